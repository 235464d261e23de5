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
//! They are computed in `f64`: any finite `f32` positions' differences and distances are then
//! finite (in `f32`, coordinates near `f32::MAX` overflowed to NaN vertices), and the new
//! vertex lies between the edge's ends, so it is finite in `f32` too.
//!
//! Window-space triangles, which have no clip space, are clipped the same way to the
//! fixed-point range itself when a vertex lies past it (`window_fan`).

use glam::{DVec4, Vec4};

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

/// The planes a target of `width x height` pixels clips against, inside where
/// [`ClipVolume::outcode`]'s distances are `>= 0`: near `z >= 0`, far `z <= w`, `w >= MIN_W`,
/// and the guard band `|x| <= gx w`, `|y| <= gy w`.
#[derive(Clone, Copy, Debug)]
pub struct ClipVolume {
    guard: [f32; 2],
}

/// Number of clip planes.
const PLANES: usize = 7;

/// Smallest `w` allowed after clipping: keeps the perspective divide finite for vertices that
/// sit on the camera plane (w = 0) in projections without a near plane.
pub(crate) const MIN_W: f32 = 1e-12;

impl ClipVolume {
    /// The clip volume of a `width x height` target.
    #[must_use]
    pub fn for_target(width: u32, height: u32) -> Self {
        // Window x = (ndc + 1) * W / 2 stays within [W - L, L] for |ndc| <= 2L/W - 1.
        let gx = 2.0 * GUARD_BAND_PIXELS / width as f32 - 1.0;
        let gy = 2.0 * GUARD_BAND_PIXELS / height as f32 - 1.0;
        Self { guard: [gx, gy] }
    }

    /// The guard band's `[gx, gy]`: inside is `|x| <= gx w`, `|y| <= gy w` (read by the x86
    /// kernels).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) fn guard(&self) -> [f32; 2] {
        self.guard
    }

    /// Signed distance (unnormalised) of `p` from `plane`, inside `>= 0`. Written out per
    /// plane rather than as a dot product with mostly-zero coefficients: the same value for
    /// finite positions (adding products with zero changes nothing but the sign of a zero),
    /// with a fraction of the arithmetic, in the per-vertex path.
    #[inline]
    fn distance(&self, plane: usize, p: Vec4) -> f32 {
        let [gx, gy] = self.guard;
        match plane {
            0 => p.z,
            1 => p.w - p.z,
            2 => p.w - MIN_W,
            3 => p.x + gx * p.w,
            4 => gx * p.w - p.x,
            5 => p.y + gy * p.w,
            _ => gy * p.w - p.y,
        }
    }

    /// [`Self::distance`] in `f64`, for the clipped edges: finite for any finite position.
    fn distance_f64(&self, plane: usize, p: DVec4) -> f64 {
        let [gx, gy] = self.guard.map(f64::from);
        match plane {
            0 => p.z,
            1 => p.w - p.z,
            2 => p.w - f64::from(MIN_W),
            3 => p.x + gx * p.w,
            4 => gx * p.w - p.x,
            5 => p.y + gy * p.w,
            _ => gy * p.w - p.y,
        }
    }

    /// `p`, a point where an edge meets `plane`, with the coordinate the plane bounds set
    /// on it exactly. As computed, that coordinate is the difference of the edge's ends'
    /// (times `t`): where they are far larger than the guard band, it can miss the plane by
    /// more than the band is wide (a triangle over the whole view, corners at 1e30, had
    /// covered half of it), and `w` can land at or below 0 (an outside end at w = 0, `t`
    /// rounded to 1), where the divide overflows.
    fn on_plane(&self, plane: usize, mut p: DVec4) -> DVec4 {
        let [gx, gy] = self.guard.map(f64::from);
        match plane {
            0 => p.z = 0.0,
            1 => p.z = p.w,
            2 => p.w = f64::from(MIN_W),
            3 => p.x = -gx * p.w,
            4 => p.x = gx * p.w,
            5 => p.y = -gy * p.w,
            _ => p.y = gy * p.w,
        }
        p
    }

    /// Bit `i` set iff the vertex is outside plane `i`. Non-finite positions are outside
    /// everything.
    #[must_use]
    pub fn outcode(&self, p: Vec4) -> u8 {
        if !p.is_finite() {
            return (1 << PLANES) - 1;
        }
        (0..PLANES).fold(0, |code, i| code | (u8::from(self.distance(i, p) < 0.0) << i))
    }

    /// Clips a triangle; returns the convex polygon that remains (empty, or 3 to 10 vertices),
    /// in the triangle's winding, its vertices finite with `w >= MIN_W`. A triangle with a
    /// non-finite coordinate clips to nothing.
    pub fn clip<V: Varyings>(&self, tri: [ClipVertex<V>; 3]) -> Vec<ClipVertex<V>> {
        let codes = tri.map(|v| self.outcode(v.position));
        if codes[0] & codes[1] & codes[2] != 0 || !tri.iter().all(|v| v.position.is_finite()) {
            // All outside one plane, or a vertex not finite (its distances would be NaN, and
            // a NaN vertex made where its edges meet each plane).
            return Vec::new();
        }
        let mut poly = tri.to_vec();
        let crossing = codes[0] | codes[1] | codes[2];
        let mut next = Vec::with_capacity(10);
        for plane in (0..PLANES).filter(|&i| crossing & (1 << i) != 0) {
            let distance = |v: &ClipVertex<V>| self.distance_f64(plane, v.position.as_dvec4());
            clip_polygon(
                &poly,
                &mut next,
                |v| distance(v) >= 0.0,
                |inside, outside| {
                    let (p, q) = (inside.position.as_dvec4(), outside.position.as_dvec4());
                    let (di, d_o) = (distance(inside), distance(outside));
                    let t = di / (di - d_o);
                    ClipVertex {
                        position: self.on_plane(plane, p + (q - p) * t).as_vec4(),
                        varyings: V::lerp(&inside.varyings, &outside.varyings, t as f32),
                    }
                },
            );
            std::mem::swap(&mut poly, &mut next);
            if poly.is_empty() {
                break;
            }
        }
        poly
    }
}

/// One Sutherland-Hodgman step: the part of the convex polygon `poly` where `inside` holds,
/// written to `out` in `poly`'s winding, with `cross(a, b)` the point where the edge from
/// `a` (inside) to `b` (outside) leaves. Edges are always handed over inside end first,
/// whichever way the polygon runs along them, so that two polygons sharing an edge get
/// the same new vertex on it (bit for bit, `cross` being a function of its arguments) and
/// stay watertight.
fn clip_polygon<P: Copy>(
    poly: &[P],
    out: &mut Vec<P>,
    inside: impl Fn(&P) -> bool,
    cross: impl Fn(&P, &P) -> P,
) {
    out.clear();
    for (i, a) in poly.iter().enumerate() {
        let b = &poly[(i + 1) % poly.len()];
        let (a_in, b_in) = (inside(a), inside(b));
        if a_in {
            out.push(*a);
        }
        if a_in != b_in {
            out.push(if a_in { cross(a, b) } else { cross(b, a) });
        }
    }
}

/// The bounds `[lo, hi]` of the window coordinates [`window_fan`] clips to: the `f32` values
/// that snap into the fixed-point range.
const WINDOW_BOX: [f32; 2] = [crate::fixed::MIN_COORD, crate::fixed::MAX_COORD - 1.0 / 256.0];

const _: () = {
    // The first `f32` above the upper bound is the first that does not snap.
    assert!(crate::fixed::SNAP_LIMIT == WINDOW_BOX[1] + 1.0 / 512.0);
};

/// A window-space vertex being clipped: position, depth, `1 / w`, and colour (times `1 / w`
/// for perspective shading, so that every value is affine in screen space), with the
/// triangle's own vertex where it is one (kept as it was, not rebuilt from these).
#[derive(Clone, Copy, Debug)]
struct WindowPoint {
    x: f64,
    y: f64,
    z: f64,
    inv_w: f64,
    color: [f64; 4],
    corner: Option<crate::setup::Vertex>,
}

impl WindowPoint {
    /// The point `t` of the way from `self` (inside) to `to` (outside).
    fn toward(&self, to: &Self, t: f64) -> Self {
        let lerp = |a: f64, b: f64| a + t * (b - a);
        Self {
            x: lerp(self.x, to.x),
            y: lerp(self.y, to.y),
            z: lerp(self.z, to.z),
            inv_w: lerp(self.inv_w, to.inv_w),
            color: std::array::from_fn(|k| lerp(self.color[k], to.color[k])),
            corner: None,
        }
    }
}

/// A window-space triangle with a vertex outside the fixed-point range (its vertices
/// finite), clipped to that range and cut into a fan in its winding: what
/// [`crate::render::draw`] draws in its place. Empty where nothing of it lies in the range.
///
/// The planes are the range's own bounds, `-32768 <= x, y <= 32768 - 1/256` ([`WINDOW_BOX`]):
/// an `f32` coordinate lies within them exactly when it snaps into the range (no `f32` lies
/// between `32768 - 1/256` and the first that does not, `32768 - 1/512`). So a triangle is
/// clipped exactly when one of its corners cannot be snapped, and an edge is cut exactly when
/// one of its ends cannot: an edge between two corners in the range is never cut, and its
/// neighbour across it, clipped or not, meets the same edge. (A band inside the range, as the
/// 3D guard band is, would have cut such an edge in a clipped triangle and not in an
/// unclipped neighbour, the rounded new corner turning the one edge away from the other.)
/// Edges the planes cut belong only to clipped triangles, and as in the homogeneous clip each
/// new vertex is computed from its edge's inside end, with the bounded coordinate set on the
/// plane exactly, so neighbours share their new vertices. New coordinates lie within the
/// planes in `f64`, so within them as `f32` too (the bounds are `f32` values, and rounding
/// keeps order).
///
/// Depth, `1 / w` and colour are affine in screen space (colour times `1 / w` with
/// `perspective`), so the new vertices' values lie on the triangle's own planes, up to the
/// rounding of colours to 8 bits at those vertices (over 16,383 pixels from any pixel
/// centre, where that moves a colour by at most half a step before its own rounding, so by one
/// step at most). With `flat`, every piece's vertices take the triangle's flat colour, so
/// each piece's flat colour is the triangle's.
pub(crate) fn window_fan(
    tri: &[crate::setup::Vertex; 3],
    perspective: bool,
    flat: bool,
) -> Vec<[crate::setup::Vertex; 3]> {
    let [lo, hi] = WINDOW_BOX.map(f64::from);
    let mut poly: Vec<WindowPoint> = tri
        .iter()
        .map(|v| {
            let weight = if perspective { f64::from(v.inv_w) } else { 1.0 };
            WindowPoint {
                x: f64::from(v.x),
                y: f64::from(v.y),
                z: f64::from(v.z),
                inv_w: f64::from(v.inv_w),
                color: v.color.map(|c| f64::from(c) * weight),
                corner: Some(*v),
            }
        })
        .collect();
    // x >= lo, x <= hi, y >= lo, y <= hi: (axis, bound, whether it is an upper bound).
    let mut next = Vec::with_capacity(7);
    for (axis, plane, upper) in [(0, lo, false), (0, hi, true), (1, lo, false), (1, hi, true)] {
        let at = |p: &WindowPoint| if axis == 0 { p.x } else { p.y };
        let inside = |p: &WindowPoint| if upper { at(p) <= plane } else { at(p) >= plane };
        clip_polygon(&poly, &mut next, inside, |from, to| {
            let mut p = from.toward(to, (plane - at(from)) / (at(to) - at(from)));
            *(if axis == 0 { &mut p.x } else { &mut p.y }) = plane;
            p
        });
        std::mem::swap(&mut poly, &mut next);
        if poly.len() < 3 {
            return Vec::new();
        }
    }
    let flat_color = flat.then(|| crate::shade::flat_color(tri));
    let vertex = |p: &WindowPoint| {
        let weight = if perspective { p.inv_w } else { 1.0 };
        if let Some(corner) = p.corner {
            return crate::setup::Vertex { color: flat_color.unwrap_or(corner.color), ..corner };
        }
        crate::setup::Vertex {
            // Within the box (new coordinates lie between their edge's ends, whose rounding
            // in `f64` the clamp absorbs).
            x: p.x.clamp(lo, hi) as f32,
            y: p.y.clamp(lo, hi) as f32,
            z: p.z as f32,
            inv_w: p.inv_w as f32,
            color: flat_color
                .unwrap_or_else(|| p.color.map(|c| crate::shade::quantize_channel(c / weight))),
        }
    };
    (1..poly.len() - 1)
        .map(|k| [vertex(&poly[0]), vertex(&poly[k]), vertex(&poly[k + 1])])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A polygon run either way round makes each new vertex from the same (inside, outside)
    /// pair, so its neighbour across the edge gets the same one.
    #[test]
    fn new_vertices_are_made_from_the_inside_end() {
        // (label, inside); a new vertex is labelled 10 * inside end + outside end.
        let poly = [(1, true), (2, false), (3, false), (4, true)];
        let cross = |a: &(u8, bool), b: &(u8, bool)| (10 * a.0 + b.0, true);
        let mut out = Vec::new();
        clip_polygon(&poly, &mut out, |p| p.1, cross);
        assert_eq!(out, [(1, true), (12, true), (43, true), (4, true)]);
        let reversed: Vec<_> = poly.iter().rev().copied().collect();
        clip_polygon(&reversed, &mut out, |p| p.1, cross);
        assert_eq!(out, [(4, true), (43, true), (12, true), (1, true)]);
        clip_polygon(&[], &mut out, |p: &(u8, bool)| p.1, cross);
        assert!(out.is_empty());
    }

    /// Two triangles sharing an edge through the near plane, wound the same way (so each runs
    /// the edge the other way round), get the same new vertex on it, bit for bit.
    #[test]
    fn triangles_sharing_a_clipped_edge_share_its_new_vertex() {
        let volume = ClipVolume::for_target(640, 480);
        let mut rng = SmallRng::seed_from_u64(5);
        let mut point = |z: std::ops::Range<f32>| {
            let w = rng.random_range(0.5..50.0f32);
            let (x, y) = (rng.random_range(-w..w), rng.random_range(-w..w));
            Vec4::new(x, y, rng.random_range(z) * w, w)
        };
        for _ in 0..2000 {
            // `a`, `c` and `d` inside, `b` in front of the near plane only.
            let [a, b, c, d] =
                [point(0.0..1.0), point(-3.0..-1e-3), point(0.0..1.0), point(0.0..1.0)];
            let vertex = |position: Vec4| ClipVertex {
                position,
                varyings: [position.x * 0.37, 1.0 / position.w],
            };
            let one = volume.clip([vertex(a), vertex(b), vertex(c)]);
            let other = volume.clip([vertex(b), vertex(a), vertex(d)]);
            // [a, ab, bc, c] and [ab, a, d, db].
            assert_eq!((one.len(), other.len()), (4, 4));
            let (p, q) = (one[1], other[0]);
            assert_eq!(
                p.position.to_array().map(f32::to_bits),
                q.position.to_array().map(f32::to_bits)
            );
            assert_eq!(p.varyings.map(f32::to_bits), q.varyings.map(f32::to_bits));
            assert_eq!(p.position.z, 0.0, "on the near plane");
        }
    }
}
