//! Shading: interpolate attributes over a span, depth-test, write colour, depth, id, overdraw.
//!
//! # Interpolation
//! Every attribute is a plane over the triangle. Its plane equation is built from the edge
//! functions: with `E_1`, `E_2` the unbiased edge values opposite vertices 1 and 2 and
//! `area2 = E_i(v_i)`, the barycentric weights are `E_i / area2`, so
//! `a(P) = a_0 + E_1(P) * (a_1 - a_0) / area2 + E_2(P) * (a_2 - a_0) / area2`.
//! `E_1`, `E_2` are integers below 2^49 (see [`crate::fixed`]), exact in `f64`; the plane is
//! evaluated in `f64` in exactly this order, so at a vertex that sits on a pixel centre the
//! weights are exactly (1, 0, 0) up to one rounding of `1/area2`, and the result rounds back
//! to the vertex's own `f32` depth and `u8` colour. A fast path must evaluate the same
//! expression in the same order to stay bit-identical.
//!
//! Depth is interpolated linearly in screen space and clamped to [0, 1]. Colours are
//! interpolated in 0..=255 units and rounded half to even.

use crate::fixed;
use crate::raster::Span;
use crate::setup::{TriangleSetup, Vertex};
use crate::target::Target;

/// How a triangle's colour varies across it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Shading {
    /// One colour per triangle: the average of the three vertex colours, rounded as
    /// `(2 * sum + 3) / 6` per channel.
    Flat,
    /// Gouraud: vertex colours interpolated linearly in screen space.
    #[default]
    Smooth,
    /// Vertex colours interpolated perspective-correctly, weighted by each vertex's `1/w`.
    Perspective,
}

/// The depth comparison a fragment must pass against the stored depth.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DepthTest {
    /// Pass iff the fragment is strictly nearer.
    #[default]
    Less,
    /// Pass iff the fragment is nearer or equal.
    LessEqual,
    /// Always pass (depth is still written): the last triangle drawn wins.
    Always,
}

impl DepthTest {
    /// Does a fragment at depth `z` pass against the stored `stored`?
    #[inline]
    #[must_use]
    pub fn passes(self, z: f32, stored: f32) -> bool {
        match self {
            Self::Less => z < stored,
            Self::LessEqual => z <= stored,
            Self::Always => true,
        }
    }
}

/// One attribute as a plane over the triangle: `a_0 + e1 * g1 + e2 * g2`, with `e1`, `e2` the
/// barycentric numerators of [`TriangleSetup::barycentric_numerators`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneEquation {
    a0: f64,
    g1: f64,
    g2: f64,
}

impl PlaneEquation {
    /// The plane through the values `a` at the triangle's three vertices.
    #[must_use]
    pub fn new(a: [f64; 3], setup: &TriangleSetup) -> Self {
        let area2 = setup.area2 as f64;
        Self { a0: a[0], g1: (a[1] - a[0]) / area2, g2: (a[2] - a[0]) / area2 }
    }

    /// The attribute at a sample with barycentric numerators `(e1, e2)`.
    #[inline]
    #[must_use]
    pub fn eval(&self, e1: f64, e2: f64) -> f64 {
        self.a0 + e1 * self.g1 + e2 * self.g2
    }
}

/// A perspective-correct varying: `a/w` and `1/w` are planes in screen space; their ratio is
/// the attribute.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerspectivePlane {
    over_w: PlaneEquation,
    inv_w: PlaneEquation,
}

impl PerspectivePlane {
    /// The varying taking values `a` at vertices whose reciprocal clip `w` are `inv_w`.
    #[must_use]
    pub fn new(a: [f64; 3], inv_w: [f64; 3], setup: &TriangleSetup) -> Self {
        let over_w = [a[0] * inv_w[0], a[1] * inv_w[1], a[2] * inv_w[2]];
        Self { over_w: PlaneEquation::new(over_w, setup), inv_w: PlaneEquation::new(inv_w, setup) }
    }

    /// The attribute at a sample with barycentric numerators `(e1, e2)`.
    #[inline]
    #[must_use]
    pub fn eval(&self, e1: f64, e2: f64) -> f64 {
        self.over_w.eval(e1, e2) / self.inv_w.eval(e1, e2)
    }
}

/// The per-triangle colour source.
#[derive(Clone, Copy, Debug)]
enum ColorSource {
    Flat([u8; 4]),
    Smooth([PlaneEquation; 4]),
    Perspective([PerspectivePlane; 4]),
}

/// What the shade stage needs for one triangle: its coverage setup, depth plane and colour.
#[derive(Clone, Copy, Debug)]
pub struct TriangleShader {
    depth: PlaneEquation,
    color: ColorSource,
    id: i32,
}

/// The flat colour of a triangle: per channel, the average of the vertex colours rounded to
/// nearest (halves up), `(2 * sum + 3) / 6` in integers.
#[must_use]
pub fn flat_color(v: &[Vertex; 3]) -> [u8; 4] {
    std::array::from_fn(|c| {
        let sum: u32 = v.iter().map(|p| u32::from(p.color[c])).sum();
        ((2 * sum + 3) / 6) as u8
    })
}

/// Converts an interpolated colour channel to `u8`: clamp to [0, 255], round half to even.
#[inline]
#[must_use]
pub fn quantize_channel(c: f64) -> u8 {
    // NaN (possible only from a 0/0 perspective division) maps to 0.
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 255.0) };
    c.round_ties_even() as u8
}

impl TriangleShader {
    /// Prepares the planes of triangle `id` with vertices `v` and setup `setup`.
    #[must_use]
    pub fn new(v: &[Vertex; 3], setup: &TriangleSetup, shading: Shading, id: i32) -> Self {
        let depth = PlaneEquation::new(v.map(|p| f64::from(p.z)), setup);
        let channel = |c: usize| v.map(|p| f64::from(p.color[c]));
        let color = match shading {
            Shading::Flat => ColorSource::Flat(flat_color(v)),
            Shading::Smooth => {
                ColorSource::Smooth(std::array::from_fn(|c| PlaneEquation::new(channel(c), setup)))
            }
            Shading::Perspective => {
                let inv_w = v.map(|p| f64::from(p.inv_w));
                ColorSource::Perspective(std::array::from_fn(|c| {
                    PerspectivePlane::new(channel(c), inv_w, setup)
                }))
            }
        };
        Self { depth, color, id }
    }

    /// Depth at barycentric numerators `(e1, e2)`, as stored in the depth buffer.
    #[inline]
    #[must_use]
    pub fn depth_at(&self, e1: f64, e2: f64) -> f32 {
        depth_at(&self.depth, e1, e2)
    }

    /// Colour at barycentric numerators `(e1, e2)`.
    #[inline]
    #[must_use]
    pub fn color_at(&self, e1: f64, e2: f64) -> [u8; 4] {
        match &self.color {
            ColorSource::Flat(c) => *c,
            ColorSource::Smooth(p) => p.map(|p| quantize_channel(p.eval(e1, e2))),
            ColorSource::Perspective(p) => p.map(|p| quantize_channel(p.eval(e1, e2))),
        }
    }

    /// Shades every pixel of `span`: overdraw count, depth test, then depth, colour and id.
    pub fn shade_span(
        &self,
        setup: &TriangleSetup,
        span: Span,
        depth_test: DepthTest,
        target: &mut Target,
    ) {
        shade_span(target, setup, span, &self.depth, depth_test, self.id, |_, e1, e2, _| {
            Some(FragmentOutput { color: self.color_at(e1, e2), normal: None })
        });
    }
}

/// What a fragment writes once it has passed the depth test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FragmentOutput {
    /// Colour, RGBA8.
    pub color: [u8; 4],
    /// Normal for the target's normal buffer, if it has one.
    pub normal: Option<[f32; 3]>,
}

/// Depth from a depth plane, as stored: evaluated in `f64`, rounded to `f32`, clamped to [0, 1].
#[inline]
#[must_use]
pub fn depth_at(plane: &PlaneEquation, e1: f64, e2: f64) -> f32 {
    (plane.eval(e1, e2) as f32).clamp(0.0, 1.0)
}

/// The one fragment loop every pipeline shares: for each pixel of `span`, count overdraw,
/// interpolate depth, test it, and only then ask `fragment(px, e1, e2, z)` for the output
/// (`None` discards it: nothing is written). Writes depth, colour, id and normal.
pub fn shade_span(
    target: &mut Target,
    setup: &TriangleSetup,
    span: Span,
    depth: &PlaneEquation,
    depth_test: DepthTest,
    id: i32,
    mut fragment: impl FnMut(i32, f64, f64, f32) -> Option<FragmentOutput>,
) {
    let y = fixed::pixel_centre(span.y);
    let row = target.index(0, span.y);
    for px in span.x_start..span.x_end {
        let i = row + px as usize;
        if let Some(o) = &mut target.overdraw {
            o[i] += 1;
        }
        let (e1, e2) = setup.barycentric_numerators(fixed::pixel_centre(px), y);
        let (e1, e2) = (e1 as f64, e2 as f64);
        let z = depth_at(depth, e1, e2);
        if !depth_test.passes(z, target.depth[i]) {
            continue;
        }
        let Some(out) = fragment(px, e1, e2, z) else { continue };
        target.depth[i] = z;
        target.color[i] = out.color;
        if let Some(ids) = &mut target.ids {
            ids[i] = id;
        }
        if let (Some(normals), Some(n)) = (&mut target.normals, out.normal) {
            normals[i] = n;
        }
    }
}
