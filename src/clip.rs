//! Homogeneous clipping, before the perspective divide.
//!
//! A triangle is clipped against the near (`z >= 0`) and far (`z <= w`) planes and against a
//! guard band in x and y (`|x|, |y| <= g * w`), where `g` is chosen per target so every
//! clipped vertex lands inside the fixed-point window range of [`crate::fixed`]: the guard band
//! is what lets a triangle a million pixels wide rasterize without overflow, while triangles
//! merely crossing the screen edge are not cut (the rasterizer's scissor handles those).
//!
//! Varyings are interpolated linearly in clip space, which is perspective-correct. New
//! vertices on an edge are always computed from the edge's inside end towards its outside
//! end, so two triangles sharing a clipped edge get bit-identical vertices and stay watertight.

use glam::Vec4;

use crate::varyings::Varyings;

/// The window coordinate (pixels) the guard band keeps clipped vertices within, in both
/// directions from the image: inside the [-32768, 32768) fixed-point range with a margin.
pub const GUARD_BAND_PIXELS: f32 = 32000.0;

/// A clip-space vertex with its varyings.
#[derive(Clone, Copy, Debug)]
pub struct ClipVertex<V> {
    /// Homogeneous clip-space position.
    pub position: Vec4,
    /// Varyings to interpolate.
    pub varyings: V,
}

/// The planes a target of `width x height` pixels clips against: `dot(plane, position) >= 0`.
#[derive(Clone, Copy, Debug)]
pub struct ClipVolume {
    planes: [Vec4; 7],
}

/// Smallest `w` allowed after clipping: keeps the perspective divide finite for vertices that
/// sit on the camera plane (w = 0) in projections without a near plane.
const MIN_W: f32 = 1e-12;

impl ClipVolume {
    /// The clip volume of a `width x height` target.
    #[must_use]
    pub fn for_target(width: u32, height: u32) -> Self {
        // Window x = (ndc + 1) * W / 2 stays within [W - L, L] for |ndc| <= 2L/W - 1.
        let gx = 2.0 * GUARD_BAND_PIXELS / width as f32 - 1.0;
        let gy = 2.0 * GUARD_BAND_PIXELS / height as f32 - 1.0;
        Self {
            planes: [
                Vec4::new(0.0, 0.0, 1.0, 0.0),  // near: z >= 0
                Vec4::new(0.0, 0.0, -1.0, 1.0), // far: z <= w
                Vec4::new(0.0, 0.0, 0.0, 1.0),  // w >= MIN_W (offset below)
                Vec4::new(1.0, 0.0, 0.0, gx),   // x >= -gx w
                Vec4::new(-1.0, 0.0, 0.0, gx),  // x <= gx w
                Vec4::new(0.0, 1.0, 0.0, gy),   // y >= -gy w
                Vec4::new(0.0, -1.0, 0.0, gy),  // y <= gy w
            ],
        }
    }

    fn distance(&self, plane: usize, p: Vec4) -> f32 {
        let d = self.planes[plane].dot(p);
        if plane == 2 { d - MIN_W } else { d }
    }

    /// Bit `i` set iff the vertex is outside plane `i`. NaN positions are outside everything.
    #[must_use]
    pub fn outcode(&self, p: Vec4) -> u8 {
        (0..7).fold(0, |code, i| {
            let d = self.distance(i, p);
            if d >= 0.0 { code } else { code | (1 << i) }
        })
    }

    /// Clips a triangle; returns the convex polygon that remains (empty, or 3 to 10 vertices),
    /// in the triangle's winding.
    pub fn clip<V: Varyings>(&self, tri: [ClipVertex<V>; 3]) -> Vec<ClipVertex<V>> {
        let codes = tri.map(|v| self.outcode(v.position));
        if codes[0] & codes[1] & codes[2] != 0 {
            return Vec::new();
        }
        let mut poly = tri.to_vec();
        let crossing = codes[0] | codes[1] | codes[2];
        let mut next = Vec::with_capacity(10);
        for plane in (0..7).filter(|&i| crossing & (1 << i) != 0) {
            next.clear();
            for i in 0..poly.len() {
                let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
                let (da, db) = (self.distance(plane, a.position), self.distance(plane, b.position));
                let (a_in, b_in) = (da >= 0.0, db >= 0.0);
                if a_in {
                    next.push(a);
                }
                if a_in != b_in {
                    // From the inside end, so shared edges give identical vertices.
                    let (inside, outside, di, d_o) =
                        if a_in { (a, b, da, db) } else { (b, a, db, da) };
                    let t = di / (di - d_o);
                    next.push(ClipVertex {
                        position: inside.position + (outside.position - inside.position) * t,
                        varyings: V::lerp(&inside.varyings, &outside.varyings, t),
                    });
                }
            }
            std::mem::swap(&mut poly, &mut next);
            if poly.is_empty() {
                break;
            }
        }
        poly
    }
}
