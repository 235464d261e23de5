//! Shading: interpolate attributes over a span, depth-test, write colour, depth, id, overdraw.
//!
//! # Interpolation
//! Every attribute is a plane over the triangle. Its plane equation is built from the edge
//! functions: with `E_1`, `E_2` the unbiased edge values opposite vertices 1 and 2 and
//! `area2 = E_i(v_i)`, the barycentric weights are `E_i / area2`, so
//! `a(P) = a_0 + E_1(P) * (a_1 - a_0) / area2 + E_2(P) * (a_2 - a_0) / area2`.
//! `E_1`, `E_2` are integers below 2^49 (see [`crate::fixed`]), exact in `f64`; the gradients
//! are `(a_i - a_0) * (1 / area2)` (one division per triangle) and the plane is evaluated in
//! `f64` in a fixed order: depth and perspective colour as `(a_0 + E_1 g_1) + E_2 g_2`
//! ([`PlaneEquation::eval`]), flat and Gouraud colour as `fma(E_2, g_2, fma(E_1, g_1, a_0))`
//! ([`SpanColor::at`]). So at a vertex that sits on a pixel centre the weights are (1, 0, 0)
//! up to two roundings (`1/area2` and the gradient), about 1e-16 relative, and the result
//! rounds back to the vertex's own `f32` depth and `u8` colour. A fast path must evaluate the
//! same expressions in the same order to stay bit-identical.
//!
//! Depth is interpolated linearly in screen space and clamped to [0, 1]. Colours are
//! interpolated in 0..=255 units and rounded half to even.

use crate::fixed;
use crate::raster::column::ColumnWalk;
use crate::raster::{self, Algorithm, Span};
use crate::sample::{MAX_SAMPLES, SampleCount};
use crate::setup::{
    BarycentricNumerators, EdgeFunction, PixelRect, TriangleSetup, Vertex, sample_bounds,
};
use crate::simd::{
    self, KernelTarget, NarrowJob, NarrowSamplesJob, SampleSpanJob, SimdLevel, SpanColor, SpanJob,
};
use crate::target::TargetBand;

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
        Self::with_inv_area2(a, 1.0 / setup.area2 as f64)
    }

    /// The plane through the values `a`, given `1 / area2` of the triangle: one division
    /// per triangle, shared by all its planes (`new` is defined through this, so both give
    /// the same bits).
    #[inline]
    #[must_use]
    pub fn with_inv_area2(a: [f64; 3], inv_area2: f64) -> Self {
        Self { a0: a[0], g1: (a[1] - a[0]) * inv_area2, g2: (a[2] - a[0]) * inv_area2 }
    }

    /// The attribute at a sample with barycentric numerators `(e1, e2)`, with separate
    /// multiplies and adds: depth and perspective colour (flat and Gouraud colour planes are
    /// evaluated fused, by [`SpanColor::at`]).
    #[inline]
    #[must_use]
    pub fn eval(&self, e1: f64, e2: f64) -> f64 {
        self.a0 + e1 * self.g1 + e2 * self.g2
    }

    /// The plane `[a0, g1, g2]` (as [`PlaneEquation::coefficients`] gives it back).
    #[inline(always)]
    #[must_use]
    pub fn from_coefficients([a0, g1, g2]: [f64; 3]) -> Self {
        Self { a0, g1, g2 }
    }

    /// `[a0, g1, g2]`, for the kernels, and for [`SpanColor`], which evaluates colour planes
    /// fused.
    #[must_use]
    pub fn coefficients(&self) -> [f64; 3] {
        [self.a0, self.g1, self.g2]
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

/// The per-triangle colour source: plain data, so that the tiled backend's records need no
/// drop when a batch's buffers are refilled (a boxed variant made clearing them a fortieth of
/// a frame of small triangles), and so that the perspective planes fit inline.
#[derive(Clone, Copy, Debug)]
enum ColorSource {
    /// Flat and affine colours, already as the span kernels take them (three planes or four
    /// decided once per triangle, not once per tile).
    Planes(SpanColor),
    /// Perspective-correct colour: `c / w` per channel over the one `1 / w` plane.
    Perspective { over_w: [PlaneEquation; 4], inv_w: PlaneEquation },
}

/// The window pipeline's per-triangle shading: a depth plane and a colour.
#[derive(Clone, Copy, Debug)]
pub struct TriangleShader {
    depth: PlaneEquation,
    color: TriangleColor,
}

/// A triangle's colour across it: what the tiled backend keeps per triangle beside the depth
/// plane it keeps anyway.
#[derive(Clone, Copy, Debug)]
pub struct TriangleColor(ColorSource);

/// The depth plane of a triangle with vertex depths `z` (`inv_area2` is `1 / area2` of its
/// setup).
#[inline(always)]
pub(crate) fn depth_plane(z: [f32; 3], inv_area2: f64) -> PlaneEquation {
    PlaneEquation::with_inv_area2([f64::from(z[0]), f64::from(z[1]), f64::from(z[2])], inv_area2)
}

/// The colour of a triangle with vertex colours `c` as the span kernels take it: flat, or
/// with `smooth`, Gouraud planes (`inv_area2` is `1 / area2` of its setup).
#[inline(always)]
fn span_color(c: [[u8; 4]; 3], inv_area2: f64, smooth: bool) -> SpanColor {
    if !smooth {
        return SpanColor::Flat(flat_color_of(c));
    }
    let plane = |k| PlaneEquation::with_inv_area2(channel(&c, k), inv_area2).coefficients();
    SpanColor::smooth([plane(0), plane(1), plane(2), plane(3)])
}

/// Channel `k` of vertex colours `c`, as the colour planes take it.
#[inline(always)]
fn channel(c: &[[u8; 4]; 3], k: usize) -> [f64; 3] {
    [f64::from(c[0][k]), f64::from(c[1][k]), f64::from(c[2][k])]
}

/// The vertex depths and colours of `v`, written out (see [`each_vertex`]).
#[inline(always)]
pub(crate) fn depths_and_colors(v: &[Vertex; 3]) -> ([f32; 3], [[u8; 4]; 3]) {
    ([v[0].z, v[1].z, v[2].z], [v[0].color, v[1].color, v[2].color])
}

/// The flat colour of a triangle: per channel, the average of the vertex colours rounded to
/// nearest (halves up), `(2 * sum + 3) / 6` in integers.
#[must_use]
pub fn flat_color(v: &[Vertex; 3]) -> [u8; 4] {
    flat_color_of([v[0].color, v[1].color, v[2].color])
}

/// [`flat_color`] of vertex colours `c`.
#[inline]
fn flat_color_of(c: [[u8; 4]; 3]) -> [u8; 4] {
    std::array::from_fn(|k| {
        let sum: u32 = c.iter().map(|p| u32::from(p[k])).sum();
        ((2 * sum + 3) / 6) as u8
    })
}

/// Converts an interpolated colour channel to `u8`: clamp to [0, 255], round half to even.
#[inline]
#[must_use]
pub fn quantize_channel(c: f64) -> u8 {
    // NaN (possible only from a 0/0 perspective division) maps to 0: `max` returns the
    // other operand when one is NaN (`clamp` would keep the NaN).
    #[allow(clippy::manual_clamp)]
    let c = c.max(0.0).min(255.0);
    // Adding 1.5 * 2^52 rounds to an integer in the current (nearest-even) rounding mode,
    // round half to even, without a libm call, and leaves that integer in the low bits of the
    // sum (its unit in the last place is 1): no subtraction or float-to-int conversion.
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    (c + MAGIC).to_bits() as u8
}

impl TriangleShader {
    /// Prepares the planes of a triangle with vertices `v` and setup `setup`. Inlined, so the
    /// planes are built where the caller keeps them (returned through the stack, they were
    /// read back with wide loads that waited on the narrow stores writing them).
    #[inline(always)]
    #[must_use]
    pub fn new(v: &[Vertex; 3], setup: &TriangleSetup, shading: Shading) -> Self {
        let inv_area2 = 1.0 / setup.area2 as f64;
        let (z, colors) = depths_and_colors(v);
        let depth = depth_plane(z, inv_area2);
        let color = match shading {
            Shading::Flat | Shading::Smooth => {
                ColorSource::Planes(span_color(colors, inv_area2, shading == Shading::Smooth))
            }
            Shading::Perspective => {
                let inv_w = each_vertex(v, |p| f64::from(p.inv_w));
                let plane = |k| PerspectivePlane::new(channel(&colors, k), inv_w, setup);
                let [r, g, b, a] = [plane(0), plane(1), plane(2), plane(3)];
                // Every channel's `1 / w` plane is the same one: kept once.
                ColorSource::Perspective {
                    over_w: [r.over_w, g.over_w, b.over_w, a.over_w],
                    inv_w: r.inv_w,
                }
            }
        };
        Self { depth, color: TriangleColor(color) }
    }

    /// The depth plane and the colour, apart.
    #[must_use]
    pub fn into_parts(self) -> (PlaneEquation, TriangleColor) {
        (self.depth, self.color)
    }

    /// What [`TriangleShader::new`] gives for flat (`smooth == false`) or smooth shading,
    /// apart, with the colour as the span kernels take it: a record of [`SpanColor`] is 24
    /// bytes smaller than one of [`TriangleColor`], whose perspective variant is larger.
    #[inline(always)]
    #[must_use]
    pub fn span_parts(
        v: &[Vertex; 3],
        setup: &TriangleSetup,
        smooth: bool,
    ) -> (PlaneEquation, SpanColor) {
        let (z, colors) = depths_and_colors(v);
        Self::span_parts_of(z, colors, 1.0 / setup.area2 as f64, smooth)
    }

    /// [`TriangleShader::span_parts`] of a triangle with vertex depths `z`, vertex colours
    /// `colors` and `1 / area2` `inv_area2`: the same planes, from what a packed record keeps.
    #[inline(always)]
    #[must_use]
    pub fn span_parts_of(
        z: [f32; 3],
        colors: [[u8; 4]; 3],
        inv_area2: f64,
        smooth: bool,
    ) -> (PlaneEquation, SpanColor) {
        (depth_plane(z, inv_area2), span_color(colors, inv_area2, smooth))
    }

    /// The depth plane.
    #[must_use]
    pub fn depth_plane(&self) -> &PlaneEquation {
        &self.depth
    }

    /// Depth at barycentric numerators `(e1, e2)`, as stored in the depth buffer.
    #[inline]
    #[must_use]
    pub fn depth_at(&self, e1: f64, e2: f64) -> f32 {
        depth_at(&self.depth, e1, e2)
    }

    /// The colour as a SIMD span kernel takes it; `None` for perspective shading, which has
    /// no kernel.
    #[must_use]
    pub fn span_color(&self) -> Option<&SpanColor> {
        self.color.span_color()
    }

    /// Colour at barycentric numerators `(e1, e2)`.
    #[inline]
    #[must_use]
    pub fn color_at(&self, e1: f64, e2: f64) -> [u8; 4] {
        self.color.color_at(e1, e2)
    }
}

/// A flat or Gouraud colour as [`TriangleShader::new`] keeps it.
impl From<SpanColor> for TriangleColor {
    fn from(color: SpanColor) -> Self {
        Self(ColorSource::Planes(color))
    }
}

impl TriangleColor {
    /// The colour as a SIMD span kernel takes it; `None` for perspective shading, which has
    /// no kernel. For the triangle's covered pixels only: an opaque triangle's colour is a
    /// [`SpanColor::SmoothRgb`], which only the narrow sample kernels clamp.
    #[inline]
    #[must_use]
    pub fn span_color(&self) -> Option<&SpanColor> {
        match &self.0 {
            ColorSource::Planes(c) => Some(c),
            ColorSource::Perspective { .. } => None,
        }
    }

    /// Colour at barycentric numerators `(e1, e2)` (each channel `quantize_channel` of its
    /// plane, which is what the kernels compute).
    #[inline]
    #[must_use]
    pub fn color_at(&self, e1: f64, e2: f64) -> [u8; 4] {
        match &self.0 {
            ColorSource::Planes(c) => c.at(e1, e2),
            // Out of line, so the common cases above inline into the pixel loop.
            ColorSource::Perspective { over_w, inv_w } => {
                perspective_color_at(over_w, inv_w, e1, e2)
            }
        }
    }
}

/// [`PerspectivePlane::eval`] per channel, quantized, with the shared `1 / w` evaluated once
/// (the same value each channel's plane would give: tested).
#[inline(never)]
fn perspective_color_at(
    over_w: &[PlaneEquation; 4],
    inv_w: &PlaneEquation,
    e1: f64,
    e2: f64,
) -> [u8; 4] {
    let w = inv_w.eval(e1, e2);
    over_w.map(|p| quantize_channel(p.eval(e1, e2) / w))
}

/// `f` of each of a triangle's vertices, written out rather than with `array::map`, which the
/// compiler left out of line: it stored the array with narrow stores that the caller's wide
/// loads then waited on (store forwarding fails), most of `TriangleShader::new`'s time.
#[inline(always)]
fn each_vertex(v: &[Vertex; 3], f: impl Fn(&Vertex) -> f64) -> [f64; 3] {
    [f(&v[0]), f(&v[1]), f(&v[2])]
}

/// What a fragment writes once it has passed the depth test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FragmentOutput {
    /// Colour, RGBA8.
    pub color: [u8; 4],
    /// Normal for the target's normal buffer, if it has one.
    pub normal: Option<[f32; 3]>,
}

/// Fragments of one triangle shaded together at 1x (see [`FragmentStage::lanes`]): at most
/// this many.
pub const LANES: usize = 8;

/// Up to [`LANES`] fragments of one triangle that passed the depth test, lane by lane: pixel,
/// barycentric numerators at its centre, depth. Lanes `len..` hold leftovers. Kept under 256
/// bytes (the buffer index is recomputed from the pixel): each triangle's queue starts zeroed,
/// and larger, the zeroing became a `memset` call, a tenth of a frame of small triangles.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassedLanes {
    /// Lanes in use: `0..len`.
    pub len: usize,
    /// Pixel column.
    pub x: [i32; LANES],
    /// Pixel row.
    pub y: [i32; LANES],
    /// Barycentric numerator `E_1` at the pixel centre.
    pub e1: [f64; LANES],
    /// Barycentric numerator `E_2` at the pixel centre.
    pub e2: [f64; LANES],
    /// Depth (as it will be stored).
    pub z: [f32; LANES],
}

impl PassedLanes {
    /// Lane `l` as a fragment stage takes it: `(x, y, e1, e2, z)`.
    #[inline]
    #[must_use]
    pub fn lane(&self, l: usize) -> (i32, i32, f64, f64, f32) {
        (self.x[l], self.y[l], self.e1[l], self.e2[l], self.z[l])
    }

    /// Counts the covered pixel `(x, y)` at buffer index `i` (overdraw) and queues it if it
    /// passes the depth test, with barycentric numerators `f1`, `f2` at its centre: whether
    /// it was queued. The queue must have room.
    #[inline(always)]
    fn push_passing(
        &mut self,
        target: &mut TargetBand<'_>,
        depth: &PlaneEquation,
        depth_test: DepthTest,
        (i, x, y): (usize, i32, i32),
        f1: f64,
        f2: f64,
    ) -> bool {
        if let Some(o) = &mut target.overdraw {
            o[i] += 1;
        }
        let z = depth_at(depth, f1, f2);
        if !depth_test.passes(z, target.depth[i]) {
            return false;
        }
        let l = self.len;
        (self.x[l], self.y[l], self.e1[l], self.e2[l], self.z[l]) = (x, y, f1, f2, z);
        self.len += 1;
        true
    }

    /// Writes the lanes in use whose `out` is not discarded: depth, colour, lane `l`'s id
    /// `id(l)` and the normal, where the target keeps them; then empties the queue.
    #[inline(always)]
    fn write(
        &mut self,
        target: &mut TargetBand<'_>,
        out: &[Option<FragmentOutput>; LANES],
        id: impl Fn(usize) -> i32,
    ) {
        for (l, out) in out.iter().enumerate().take(self.len) {
            let Some(out) = out else { continue };
            let i = target.index(self.x[l], self.y[l]);
            target.depth[i] = self.z[l];
            target.color[i] = out.color;
            if let Some(ids) = &mut target.ids {
                ids[i] = id(l);
            }
            if let (Some(normals), Some(nrm)) = (&mut target.normals, out.normal) {
                normals[i] = nrm;
            }
        }
        self.len = 0;
    }

    /// `out[l] = fragment(lane l)` for the lanes in use, in order: the default
    /// [`FragmentStage::lanes`].
    #[inline(always)]
    pub fn each_into(
        &self,
        out: &mut [Option<FragmentOutput>; LANES],
        mut fragment: impl FnMut(i32, i32, f64, f64, f32) -> Option<FragmentOutput>,
    ) {
        for (l, out) in out.iter_mut().enumerate().take(self.len) {
            let (x, y, e1, e2, z) = self.lane(l);
            *out = fragment(x, y, e1, e2, z);
        }
    }
}

/// What a triangle's covered pixels that pass the depth test become: the output of each
/// fragment, or nothing (discarded). Closures `FnMut(x, y, e1, e2, z) -> Option<FragmentOutput>`
/// are fragment stages, taking `e1`, `e2` at the pixel centre and the depth `z`.
pub trait FragmentStage {
    /// The output of the fragment at pixel `(x, y)`.
    fn fragment(&mut self, x: i32, y: i32, e1: f64, e2: f64, z: f32) -> Option<FragmentOutput>;

    /// The outputs of `lanes`' fragments into `out[..lanes.len]`: lane by lane what
    /// [`FragmentStage::fragment`] gives, bit for bit. By default one fragment after
    /// another; a stage may override it to compute its lanes side by side.
    fn lanes(&mut self, lanes: &PassedLanes, out: &mut [Option<FragmentOutput>; LANES]) {
        lanes.each_into(out, |x, y, e1, e2, z| self.fragment(x, y, e1, e2, z));
    }

    /// Whether [`FragmentStage::lanes`] computes its lanes side by side
    /// ([`crate::pipeline::FragmentShader::shades_lanes`]), so that a multisampled target's
    /// pixels are worth queueing for it; at 1x every stage's are. `false` by default.
    fn shades_lanes(&self) -> bool {
        false
    }

    /// The triangle's colour as the kernels compute it, and their level, when the kernels
    /// may shade its fragments instead of [`FragmentStage::fragment`]: they write what it
    /// would, bit for bit (the 3D pipeline's interpolated vertex colours,
    /// [`SpanColor::Perspective`]). `None` by default.
    fn span_color(&self) -> Option<(SimdLevel, SpanColor)> {
        None
    }
}

impl<F: FnMut(i32, i32, f64, f64, f32) -> Option<FragmentOutput>> FragmentStage for F {
    #[inline(always)]
    fn fragment(&mut self, x: i32, y: i32, e1: f64, e2: f64, z: f32) -> Option<FragmentOutput> {
        self(x, y, e1, e2, z)
    }
}

/// The [`FragmentStage`] of every triangle of a draw call, given the shading data `T` each
/// triangle keeps (the tile loop's form). `Sync` closures
/// `Fn(&T, x, y, e1, e2, z) -> Option<FragmentOutput>` are such stages; the compiler needs
/// their first parameter's type written out (`|c: &TriangleColor, _, _, e1, e2, _| ..`), as it
/// infers closure signatures only from `Fn` bounds.
pub trait TriangleFragments<T>: Sync {
    /// [`FragmentStage::fragment`] for the triangle with data `t`.
    fn fragment(&self, t: &T, x: i32, y: i32, e1: f64, e2: f64, z: f32) -> Option<FragmentOutput>;

    /// [`FragmentStage::lanes`] for the triangle with data `t`, with the same contract.
    fn lanes(&self, t: &T, lanes: &PassedLanes, out: &mut [Option<FragmentOutput>; LANES]) {
        lanes.each_into(out, |x, y, e1, e2, z| self.fragment(t, x, y, e1, e2, z));
    }

    /// [`TriangleFragments::lanes`] for lanes of several triangles, lane `l`'s data
    /// `tris[l]` (`Some` for every lane in use), with the same contract.
    fn lanes_of(
        &self,
        tris: &[Option<&T>; LANES],
        lanes: &PassedLanes,
        out: &mut [Option<FragmentOutput>; LANES],
    ) {
        for (l, (out, t)) in out.iter_mut().zip(tris).enumerate().take(lanes.len) {
            debug_assert!(t.is_some(), "lane {l} in use without its triangle");
            let (x, y, e1, e2, z) = lanes.lane(l);
            *out = t.and_then(|t| self.fragment(t, x, y, e1, e2, z));
        }
    }

    /// [`FragmentStage::span_color`] for the triangle with data `t`.
    fn span_color(&self, _t: &T) -> Option<(SimdLevel, SpanColor)> {
        None
    }

    /// [`FragmentStage::shades_lanes`], for every triangle.
    fn shades_lanes(&self) -> bool {
        false
    }

    /// Whether a multisampled pixel's colour may be written after its depth, other pixels'
    /// writes between (the tiled backend's small triangles then share one queue for their
    /// colour): the stage shades lanes and never discards. `false` by default.
    fn defers_colour(&self) -> bool {
        false
    }

    /// Whether [`TriangleFragments::span_color`] may give any triangle a colour: where it
    /// cannot, the tile loops do not set triangles up for the kernels that would ask it.
    fn span_colors(&self) -> bool {
        false
    }

    /// [`TriangleFragments::span_color`] for the small kernel
    /// ([`crate::simd::shade_small_eight`]), which may shade at levels where the others do
    /// not. The same by default.
    fn small_color(&self, t: &T) -> Option<(SimdLevel, SpanColor)> {
        self.span_color(t)
    }

    /// Whether [`TriangleFragments::small_color`] may give any triangle a colour.
    fn small_colors(&self) -> bool {
        self.span_colors()
    }
}

impl<T, F> TriangleFragments<T> for F
where
    F: Fn(&T, i32, i32, f64, f64, f32) -> Option<FragmentOutput> + Sync,
{
    #[inline(always)]
    fn fragment(&self, t: &T, x: i32, y: i32, e1: f64, e2: f64, z: f32) -> Option<FragmentOutput> {
        self(t, x, y, e1, e2, z)
    }
}

/// One triangle's [`FragmentStage`]: its data and the draw call's [`TriangleFragments`].
pub(crate) struct OfTriangle<'a, T, F>(pub &'a F, pub &'a T);

impl<T, F: TriangleFragments<T>> FragmentStage for OfTriangle<'_, T, F> {
    #[inline(always)]
    fn fragment(&mut self, x: i32, y: i32, e1: f64, e2: f64, z: f32) -> Option<FragmentOutput> {
        self.0.fragment(self.1, x, y, e1, e2, z)
    }

    #[inline(always)]
    fn lanes(&mut self, lanes: &PassedLanes, out: &mut [Option<FragmentOutput>; LANES]) {
        self.0.lanes(self.1, lanes, out);
    }

    #[inline(always)]
    fn span_color(&self) -> Option<(SimdLevel, SpanColor)> {
        self.0.span_color(self.1)
    }

    #[inline(always)]
    fn shades_lanes(&self) -> bool {
        self.0.shades_lanes()
    }
}

/// Depth from a depth plane, as stored: evaluated in `f64`, rounded to `f32`, clamped to [0, 1].
#[inline]
#[must_use]
pub fn depth_at(plane: &PlaneEquation, e1: f64, e2: f64) -> f32 {
    (plane.eval(e1, e2) as f32).clamp(0.0, 1.0)
}

/// Bounds of the depth a triangle can write at the pixel centres of `rect`: [`depth_at`] at
/// any of them lies in `[lo, hi]`. A plane's extremes over a rectangle are at its corners; the
/// evaluation's four roundings move a value by less than `2^-50` of the terms' magnitudes,
/// and the bounds are widened by `2^-40` of them before the (monotonic) conversion to `f32`
/// and clamp, so they hold for the computed values, not only the exact ones. A plane that is
/// not finite there gives `(-inf, inf)`: nothing is hidden behind it, and nothing hides it.
///
/// With `reach` (fixed-point units), the bounds hold at every point within `reach` of those
/// centres on each axis: every sample, with the pattern's [`crate::sample::SampleCount::reach`].
#[must_use]
pub fn depth_bounds(
    plane: &PlaneEquation,
    setup: &TriangleSetup,
    rect: &PixelRect,
    reach: i64,
) -> (f32, f32) {
    let Some((lo, hi)) = plane_bounds(plane, setup, rect, reach) else {
        return (f32::NEG_INFINITY, f32::INFINITY);
    };
    let to_depth = |v: f64| (v as f32).clamp(0.0, 1.0);
    (to_depth(lo), to_depth(hi))
}

/// [`depth_bounds`] before the conversion to depth: bounds of `plane.eval` at the pixel
/// centres of `rect` (and within `reach` of them), as computed (`None` when not finite).
fn plane_bounds(
    plane: &PlaneEquation,
    setup: &TriangleSetup,
    rect: &PixelRect,
    reach: i64,
) -> Option<(f64, f64)> {
    let [a0, g1, g2] = plane.coefficients();
    let (mut lo, mut hi, mut scale) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for [x, y] in raster::rect_corners(rect, reach) {
        let (e1, e2) = setup.barycentric_numerators(x, y);
        let (e1, e2) = (e1 as f64, e2 as f64);
        let v = plane.eval(e1, e2);
        (lo, hi) = (lo.min(v), hi.max(v));
        scale = scale.max(a0.abs() + (e1 * g1).abs() + (e2 * g2).abs());
    }
    if !(lo <= hi && scale.is_finite()) {
        return None;
    }
    let margin = scale * 2f64.powi(-40);
    Some((lo - margin, hi + margin))
}

/// The one fragment loop every pipeline shares. For each pixel with covered samples: count
/// them (overdraw), interpolate depth at each covered sample and test it, and only if one
/// passes ask the `fragment` stage for the output, once per pixel, with `e1`, `e2` and `z` at
/// the pixel centre (`None` discards it). Then write depth to the passing samples, colour and
/// id to the passing samples, and the normal to the pixel.
///
/// Only pixels of `clip` within the band are shaded (a clip reaching past the band's columns
/// had written the pixels it wrapped to in the rows next to them). At 1x the only sample is
/// the pixel centre, and the
/// fragments that pass are handed to the stage [`LANES`] at a time, so their writes may wait
/// until then (at the latest, until the call returns). Returns
/// the number of covered samples. A `kernel` (flat or smooth colour without normals)
/// replaces `fragment` by SIMD kernels computing the same values: for narrow triangles
/// (whole, coverage included), at 1x for spans, multisampled for runs of pixels whose samples
/// are all covered.
#[allow(clippy::too_many_arguments)]
pub fn shade_triangle(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    algorithm: Algorithm,
    clip: &PixelRect,
    depth: &PlaneEquation,
    depth_test: DepthTest,
    id: i32,
    kernel: Option<(SimdLevel, &SpanColor)>,
    fragment: impl FragmentStage,
) -> u64 {
    let Some(clip) = clip.intersect(&target.rect()) else { return 0 };
    let clip = &clip;
    // Where the draw call has no kernel, the stage's own (the 3D pipeline's vertex colours).
    let own = if kernel.is_none() { fragment.span_color() } else { None };
    let kernel = kernel.or(own.as_ref().map(|(level, color)| (*level, color)));
    let samples = target.samples();
    let n = samples.count();
    if n == 1 {
        return shade_single_sample(
            target, setup, algorithm, clip, depth, depth_test, id, kernel, fragment,
        );
    }
    if algorithm == Algorithm::EdgeMasks {
        let Some(r) = samples_rect(setup, samples, clip) else { return 0 };
        // Tall boxes by columns, narrow ones too: the row masks cost every row of a sliver
        // (40,000-triangle cylinder at 4x, two threads: 134-135 -> 118-119 ms).
        if kernel.is_none() && raster::column::is_tall(&r) {
            let numerators = setup.numerators();
            let pixels =
                SamplePixels::new(setup, numerators, samples, depth, (depth_test, id), fragment);
            return sample_columns(target, clip, pixels);
        }
        let columns = r.x1 - r.x0 + 1;
        if columns <= raster::edge::NARROW {
            // The edges derived once for the sample offsets and the masks below (the
            // kernel's job starts from the vertices, `narrow_start`; offsets taken from the
            // job's steps instead cost 0.3% more instructions at 4x on the soup).
            let edges = setup.edges();
            if let Some((level, color)) = kernel.filter(|_| target.overdraw.is_none()) {
                let offsets = sample_edge_offsets(&edges, samples);
                let narrow = narrow_job(target, setup, &r, depth, (depth_test, id), color);
                return simd::shade_narrow_samples(
                    level,
                    NarrowSamplesJob { narrow, samples: n, offsets },
                );
            }
            // Each sample's row coverage as a bit mask without branches (as at 1x), then the
            // pixels with any covered sample, left to right, with their sample masks: no
            // spans, no lists of them.
            let numerators = setup.numerators_of(&edges);
            let mut pixels =
                SamplePixels::new(setup, numerators, samples, depth, (depth_test, id), fragment);
            let mut rows = SampleRows::new(&edges, samples, &r);
            if rows.columns <= 4 {
                rows.each_row((r.y1 - r.y0 + 1) as usize, |j, by_sample| {
                    sample_mask_pixels(by_sample, |px, mask| {
                        pixels.pixel(target, r.x0 + px, r.y0 + j as i32, mask);
                    });
                });
                return pixels.finish(target);
            }
            let SampleRows { mut rows, step_x, step_y, columns, .. } = rows;
            // Wider boxes: each sample's masks of a run of rows at once ([`simd::row_masks`]:
            // the bunny at 4x, one thread, 30.5-30.8 -> 28.0-28.1 ms; for boxes up to four
            // wide the vectors' setup cost more than it saved, the grid's 4% more
            // instructions).
            let level = SimdLevel::detected();
            let mut masks = [[0u8; 16]; MAX_SAMPLES];
            let mut py = r.y0;
            while py <= r.y1 {
                let len = ((r.y1 - py + 1) as usize).min(16);
                for (s, row) in rows.iter_mut().enumerate().take(n) {
                    simd::row_masks(level, *row, step_x, step_y, columns, &mut masks[s][..len]);
                    *row = std::array::from_fn(|k| row[k] + len as i64 * step_y[k]);
                }
                // Row j of the run is column j of `masks`, read across the samples.
                #[allow(clippy::needless_range_loop)]
                for j in 0..len {
                    let by_sample = (0..n).fold(0u64, |m, s| m | u64::from(masks[s][j]) << (8 * s));
                    sample_mask_pixels(by_sample, |px, mask| {
                        pixels.pixel(target, r.x0 + px, py, mask);
                    });
                    py += 1;
                }
            }
            return pixels.finish(target);
        }
    }
    let numerators = setup.numerators();
    let pixels = SamplePixels::new(setup, numerators, samples, depth, (depth_test, id), fragment);
    sample_spans(target, tiled_fallback(algorithm), clip, kernel, pixels)
}

/// The pixels any sample of which may be covered, within `clip`: the union of the sample
/// boxes (of one snapped box, found once).
#[inline(always)]
fn samples_rect(
    setup: &TriangleSetup,
    samples: SampleCount,
    clip: &PixelRect,
) -> Option<PixelRect> {
    let extent = setup.extent();
    let boxes = (0..samples.count())
        .filter_map(|s| sample_bounds(extent, samples.offset(s)).intersect(clip));
    boxes.reduce(|a, b| a.union(&b))
}

/// Each sample's edge values at the first pixel of a row of a box at most
/// [`raster::edge::NARROW`] pixels wide, stepped a row at a time.
struct SampleRows {
    rows: [[i64; 3]; MAX_SAMPLES],
    step_x: [i64; 3],
    step_y: [i64; 3],
    n: usize,
    columns: usize,
}

impl SampleRows {
    /// The rows of box `r` (the first at its top) for edges `edges` and `samples`.
    #[inline(always)]
    fn new(edges: &[EdgeFunction; 3], samples: SampleCount, r: &PixelRect) -> Self {
        let (x, y) = (fixed::pixel_centre(r.x0), fixed::pixel_centre(r.y0));
        let mut rows = [[0i64; 3]; MAX_SAMPLES];
        for (s, row) in rows.iter_mut().enumerate().take(samples.count()) {
            let [ox, oy] = samples.offset(s);
            *row = EdgeFunction::values(edges, x + ox, y + oy);
        }
        let (step_x, step_y) = EdgeFunction::pixel_steps(edges);
        let columns = (r.x1 - r.x0 + 1) as usize;
        Self { rows, step_x, step_y, n: samples.count(), columns }
    }

    /// The row's coverage, sample `s`'s mask in byte `s` (at most 8 columns and 8 samples),
    /// then a step down. In registers: an array of masks, read back bit by bit, was stored
    /// narrow and loaded wide, which store forwarding fails.
    #[inline(always)]
    fn next_row(&mut self) -> u64 {
        let (step_x, step_y) = (self.step_x, self.step_y);
        let mut by_sample = 0u64;
        for (s, row) in self.rows.iter_mut().enumerate().take(self.n) {
            let mask = raster::edge::row_coverage_within(*row, step_x, self.columns);
            by_sample |= u64::from(mask) << (8 * s);
            *row = [row[0] + step_y[0], row[1] + step_y[1], row[2] + step_y[2]];
        }
        by_sample
    }

    /// [`SampleRows::next_row`] of each of the next `rows` rows, top down: `row(j, by_sample)`.
    /// A box up to four pixels wide and [`raster::edge::NARROW`] tall whose every edge value
    /// fits in `i32` (bounded by the first row's magnitudes plus three steps right and eight
    /// down) steps its four columns side by side ([`simd::EdgeColumns`]; the same signs, so
    /// the same masks): the `i64` masks, a pixel at a time, had been a tenth of the Phong
    /// bunny's 4x frame at 800 x 600.
    #[inline(always)]
    fn each_row(&mut self, rows: usize, mut row: impl FnMut(usize, u64)) {
        let n = self.n;
        let fits = |k: usize| {
            let largest = self.rows[..n].iter().fold(0, |m, r| m.max(r[k].abs()));
            largest + 3 * self.step_x[k].abs() + 8 * self.step_y[k].abs() <= i64::from(i32::MAX)
        };
        let narrow = self.columns <= 4
            && rows <= raster::edge::NARROW as usize
            && fits(0)
            && fits(1)
            && fits(2);
        let (step_x, step_y) = (self.step_x.map(|v| v as i32), self.step_y.map(|v| v as i32));
        let mut columns = [simd::EdgeColumns::new([0; 3], [0; 3]); MAX_SAMPLES];
        if narrow {
            for (c, r) in columns.iter_mut().zip(&self.rows).take(n) {
                *c = simd::EdgeColumns::new(r.map(|v| v as i32), step_x);
            }
        }
        let keep = (1 << self.columns) - 1;
        // One call of `row` (two had it compiled out of line, a call per pixel).
        for j in 0..rows {
            let by_sample = if narrow {
                let mut by_sample = 0u64;
                for (s, c) in columns.iter_mut().enumerate().take(n) {
                    by_sample |= u64::from(c.inside() & keep) << (8 * s);
                    c.step(step_y);
                }
                by_sample
            } else {
                self.next_row()
            };
            row(j, by_sample);
        }
    }
}

/// `pixel(c, mask)` for the pixels of a row with any sample covered, left to right (`c` from
/// the row's first), with their sample masks, given sample `s`'s row mask in byte `s` of
/// `by_sample`: the 8 x 8 bit transpose puts each pixel's sample mask in byte `c`.
#[inline(always)]
fn sample_mask_pixels(by_sample: u64, mut pixel: impl FnMut(i32, u32)) {
    let mut by_pixel = raster::edge::transpose_bits(by_sample);
    while by_pixel != 0 {
        let c = by_pixel.trailing_zeros() / 8;
        let mask = (by_pixel >> (8 * c)) as u32 & 0xFF;
        by_pixel &= !(0xFF << (8 * c));
        pixel(c as i32, mask);
    }
}

/// The pixels of `clip` with covered samples, a column at a time: each sample's
/// [`ColumnWalk`] stepped side by side, for tall thin triangles, whose rows are mostly empty
/// (the side of a cylinder at 4x spent most of its frame walking rows and sorting spans).
fn sample_columns<S: FragmentStage>(
    target: &mut TargetBand<'_>,
    clip: &PixelRect,
    mut pixels: SamplePixels<'_, S>,
) -> u64 {
    let (setup, n, samples) = (pixels.setup, pixels.n, target.samples());
    // Filled in place: built by `array::from_fn`, the walks of all eight samples (1.5 KB)
    // were copied out on every call.
    let mut walks: [Option<ColumnWalk>; MAX_SAMPLES] = [const { None }; MAX_SAMPLES];
    for (s, walk) in walks.iter_mut().enumerate().take(n) {
        *walk = ColumnWalk::new(setup, clip, samples.offset(s));
    }
    let columns = walks.iter().flatten().map(ColumnWalk::columns);
    let Some(all) = columns.reduce(|a, b| *a.start().min(b.start())..=*a.end().max(b.end())) else {
        return 0;
    };
    for x in all {
        let mut runs = [(0, 0); MAX_SAMPLES];
        let (mut lo, mut hi) = (i32::MAX, i32::MIN);
        for (run, walk) in runs.iter_mut().zip(&mut walks).take(n) {
            // A sample's walk is stepped once for each column of its own, in order.
            if let Some(walk) = walk.as_mut().filter(|w| w.columns().contains(&x)) {
                *run = walk.next_rows();
                if run.0 < run.1 {
                    (lo, hi) = (lo.min(run.0), hi.max(run.1));
                }
            }
        }
        for py in lo..hi {
            let mask = runs.iter().take(n).enumerate().fold(0u32, |m, (s, &(y0, y1))| {
                if (y0..y1).contains(&py) { m | (1 << s) } else { m }
            });
            if mask != 0 {
                pixels.pixel(target, x, py, mask);
            }
        }
    }
    pixels.finish(target)
}

/// The rasterizer for a box [`Algorithm::EdgeMasks`]' paths do not take: the scanline walk,
/// whose cost grows with rows, not with the box's pixels.
fn tiled_fallback(algorithm: Algorithm) -> Algorithm {
    match algorithm {
        Algorithm::EdgeMasks => Algorithm::Scanline,
        other => other,
    }
}

/// The narrow kernels' job for box `r` of a triangle (at most [`simd::NARROW_COLUMNS`]
/// wide): the edge values at the centre of its first pixel, their steps, the fill-rule
/// biases, and the band's buffers.
#[inline(always)]
fn narrow_job<'a>(
    target: &'a mut TargetBand<'_>,
    setup: &TriangleSetup,
    r: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    color: &'a SpanColor,
) -> NarrowJob<'a> {
    let (edges, step_x, step_y, bias) = narrow_start(setup, r);
    NarrowJob {
        edges,
        step_x,
        step_y,
        bias,
        columns: (r.x1 - r.x0 + 1) as usize,
        rows: (r.y1 - r.y0 + 1) as usize,
        first: target.index(r.x0, r.y0),
        stride: target.stride(),
        target: KernelTarget {
            depth_plane: depth.coefficients(),
            color,
            depth_test,
            id,
            depth: target.depth,
            color_out: target.color,
            ids: target.ids.as_deref_mut(),
            overdraw: target.overdraw.as_deref_mut(),
        },
    }
}

/// Where the narrow paths start a box `r` of a triangle: [`TriangleSetup::edges_at`] the
/// centre of its first pixel.
#[inline(always)]
fn narrow_start(setup: &TriangleSetup, r: &PixelRect) -> ([i64; 3], [i64; 3], [i64; 3], [i64; 2]) {
    setup.edges_at(fixed::pixel_centre(r.x0), fixed::pixel_centre(r.y0))
}

/// Each sample's edge values less its pixel centre's, for edges `edges`: `a ox + b oy` per
/// edge, the same at every pixel (the edge functions are linear).
#[inline(always)]
fn sample_edge_offsets(edges: &[EdgeFunction; 3], samples: SampleCount) -> [[i64; 3]; MAX_SAMPLES] {
    let mut offsets = [[0i64; 3]; MAX_SAMPLES];
    for (s, o) in offsets.iter_mut().enumerate().take(samples.count()) {
        let [ox, oy] = samples.offset(s);
        *o = edges.map(|e| e.a * ox + e.b * oy);
    }
    offsets
}

/// [`shade_triangle`] on a multisampled target, from each sample's spans: pixel by pixel over
/// each row's union of them, except the pixels every sample of which is covered (their
/// intersection) with a span kernel's colour and no overdraw buffer (it counts per pixel),
/// which go to the sample span kernel. Out of line: inlined, it slowed the narrow path above
/// (grid at 4x, 144 -> 156 ms).
#[inline(never)]
fn sample_spans<S: FragmentStage>(
    target: &mut TargetBand<'_>,
    algorithm: Algorithm,
    clip: &PixelRect,
    kernel: Option<(SimdLevel, &SpanColor)>,
    mut pixels: SamplePixels<'_, S>,
) -> u64 {
    let (setup, n, samples) = (pixels.setup, pixels.n, target.samples());
    let spans: Vec<Vec<Span>> = (0..n)
        .map(|s| {
            let mut v = Vec::new();
            raster::rasterize_sample(algorithm, setup, clip, samples.offset(s), |sp| v.push(sp));
            v
        })
        .collect();
    let Some(y0) = spans.iter().filter_map(|v| v.first()).map(|sp| sp.y).min() else {
        return pixels.finish(target);
    };
    let y1 = spans.iter().filter_map(|v| v.last()).map(|sp| sp.y).max().unwrap_or(y0);
    let sample_kernel = kernel.filter(|_| target.overdraw.is_none());
    let (depth, depth_test, id, offsets) =
        (pixels.depth, pixels.depth_test, pixels.id, pixels.offsets);
    let mut kernel_covered = 0u64;
    let (steps, _) = setup.pixel_steps();
    let mut cursor = vec![0usize; n];
    let mut row = [None::<Span>; MAX_SAMPLES];
    for y in y0..=y1 {
        let (mut lo, mut hi) = (i32::MAX, i32::MIN);
        // The pixels every sample of which is covered: the spans' intersection.
        let (mut inner_lo, mut inner_hi) = (i32::MIN, i32::MAX);
        for s in 0..n {
            row[s] = spans[s].get(cursor[s]).copied().filter(|sp| sp.y == y);
            match row[s] {
                Some(sp) => {
                    cursor[s] += 1;
                    lo = lo.min(sp.x_start);
                    hi = hi.max(sp.x_end);
                    inner_lo = inner_lo.max(sp.x_start);
                    inner_hi = inner_hi.min(sp.x_end);
                }
                None => inner_hi = i32::MIN,
            }
        }
        let mut each_pixel = |target: &mut TargetBand<'_>, from: i32, to: i32| {
            for px in from..to {
                let mask = (0..n).fold(0u32, |m, s| match row[s] {
                    Some(sp) if (sp.x_start..sp.x_end).contains(&px) => m | (1 << s),
                    _ => m,
                });
                if mask != 0 {
                    pixels.pixel(target, px, y, mask);
                }
            }
        };
        match sample_kernel {
            Some((level, color)) if inner_hi.saturating_sub(inner_lo) >= SAMPLE_KERNEL_MIN_SPAN => {
                each_pixel(target, lo, inner_lo);
                let (e1, e2) = setup
                    .barycentric_numerators(fixed::pixel_centre(inner_lo), fixed::pixel_centre(y));
                let row_start = target.index(0, y);
                let range =
                    n * (row_start + inner_lo as usize)..n * (row_start + inner_hi as usize);
                let job = SampleSpanJob {
                    span: SpanJob {
                        e1,
                        e2,
                        step1: steps[1],
                        step2: steps[2],
                        // No overdraw buffer here (it counts per pixel).
                        target: kernel_target(target, range, (depth, color, depth_test, id), false),
                    },
                    samples: n,
                    offsets,
                };
                simd::shade_samples(level, job);
                kernel_covered += (n * (inner_hi - inner_lo) as usize) as u64;
                each_pixel(target, inner_hi, hi);
            }
            _ => each_pixel(target, lo, hi),
        }
    }
    pixels.finish(target) + kernel_covered
}

/// Runs of fully covered multisampled pixels at least this long go to the sample span
/// kernel.
const SAMPLE_KERNEL_MIN_SPAN: i32 = 2;

/// The pixels of one triangle on a multisampled target, each with its mask of covered
/// samples: count them (overdraw), test depth per covered sample, and if any passes, shade
/// the pixel once and write the passing samples. A method always inlined, not a closure:
/// called from two loops (narrow triangles and spans), a closure was left out of line and
/// the spans' loop (large triangles, fill at 4x) took a fifth longer.
struct SamplePixels<'a, S> {
    setup: &'a TriangleSetup,
    /// The setup's numerators, derived once for the triangle's pixels.
    numerators: BarycentricNumerators,
    /// Samples per pixel.
    n: usize,
    /// Each sample's numerators less its pixel centre's.
    offsets: [[i64; 2]; MAX_SAMPLES],
    depth: &'a PlaneEquation,
    depth_test: DepthTest,
    id: i32,
    fragment: S,
    /// Covered samples so far.
    covered: u64,
    /// For a stage that [`FragmentStage::shades_lanes`], the pixels waiting for it; other
    /// stages shade each pixel as it comes (queued, the Gouraud bunny at 4x took 2.6% more
    /// instructions and about 5% longer) and pay nothing for the queue's arrays.
    queue: Option<SampleQueue>,
}

/// Pixels with a sample that passed the depth test, waiting to be shaded [`LANES`] at a time
/// ([`FragmentStage::lanes`]): their centres, the samples that passed and every covered
/// sample's depth. Their writes may wait, as [`LaneQueue`]'s: the triangle reaches each
/// pixel once, and [`SamplePixels::finish`] writes the last.
struct SampleQueue {
    centres: PassedLanes,
    passed: [u32; LANES],
    z: [[f32; MAX_SAMPLES]; LANES],
}

impl<'a, S: FragmentStage> SamplePixels<'a, S> {
    /// The loop's state for a triangle with barycentric numerators `numerators`, no sample
    /// covered yet.
    fn new(
        setup: &'a TriangleSetup,
        numerators: BarycentricNumerators,
        samples: SampleCount,
        depth: &'a PlaneEquation,
        (depth_test, id): (DepthTest, i32),
        fragment: S,
    ) -> Self {
        let n = samples.count();
        let mut offsets = [[0i64; 2]; MAX_SAMPLES];
        for (s, o) in offsets.iter_mut().enumerate().take(n) {
            *o = numerators.offset(samples.offset(s));
        }
        let queue = fragment.shades_lanes().then(|| SampleQueue {
            centres: PassedLanes::default(),
            passed: [0; LANES],
            z: [[0.0; MAX_SAMPLES]; LANES],
        });
        Self { setup, numerators, n, offsets, depth, depth_test, id, fragment, covered: 0, queue }
    }

    /// Pixel `(px, py)` with covered samples `mask`.
    #[inline(always)]
    fn pixel(&mut self, target: &mut TargetBand<'_>, px: i32, py: i32, mask: u32) {
        let n = self.n;
        self.covered += u64::from(mask.count_ones());
        let p = target.index(px, py);
        if let Some(o) = &mut target.overdraw {
            o[p] += mask.count_ones();
        }
        let (cx, cy) = (fixed::pixel_centre(px), fixed::pixel_centre(py));
        let (c1, c2) = self.numerators.at(cx, cy);
        let mut z = [0.0f32; MAX_SAMPLES];
        let mut passed = 0u32;
        for s in (0..n).filter(|s| mask & (1 << s) != 0) {
            let [o1, o2] = self.offsets[s];
            z[s] = depth_at(self.depth, (c1 + o1) as f64, (c2 + o2) as f64);
            if self.depth_test.passes(z[s], target.depth[p * n + s]) {
                passed |= 1 << s;
            }
        }
        if passed == 0 {
            return;
        }
        let (e1, e2) = (c1 as f64, c2 as f64);
        let z_centre = depth_at(self.depth, e1, e2);
        let Some(q) = &mut self.queue else {
            let Some(out) = self.fragment.fragment(px, py, e1, e2, z_centre) else { return };
            write_samples(target, (p, self.n, self.id), passed, &z, &out);
            return;
        };
        let l = q.centres.len;
        let c = &mut q.centres;
        (c.x[l], c.y[l], c.e1[l], c.e2[l], c.z[l]) = (px, py, e1, e2, z_centre);
        c.len += 1;
        (q.passed[l], q.z[l]) = (passed, z);
        if c.len == LANES {
            self.flush(target);
        }
    }

    /// Shades the queued pixels and writes their passing samples (depth, colour, id) and
    /// normal, where they are not discarded.
    fn flush(&mut self, target: &mut TargetBand<'_>) {
        let Some(q) = &mut self.queue else { return };
        let len = q.centres.len;
        if len == 0 {
            return;
        }
        let mut out = [None; LANES];
        self.fragment.lanes(&q.centres, &mut out);
        for (l, out) in out.iter().enumerate().take(len) {
            let Some(out) = out else { continue };
            let p = target.index(q.centres.x[l], q.centres.y[l]);
            write_samples(target, (p, self.n, self.id), q.passed[l], &q.z[l], out);
        }
        q.centres.len = 0;
    }

    /// Writes what is still queued; returns the covered samples.
    fn finish(&mut self, target: &mut TargetBand<'_>) -> u64 {
        self.flush(target);
        self.covered
    }
}

/// Writes pixel `p`'s samples `passed` (of `n`; depths `z`) with colour `out` and id `id`,
/// and its normal.
#[inline(always)]
fn write_samples(
    target: &mut TargetBand<'_>,
    (p, n, id): (usize, usize, i32),
    passed: u32,
    z: &[f32; MAX_SAMPLES],
    out: &FragmentOutput,
) {
    for s in (0..n).filter(|s| passed & (1 << s) != 0) {
        target.depth[p * n + s] = z[s];
        target.color[p * n + s] = out.color;
        if let Some(ids) = &mut target.ids {
            ids[p * n + s] = id;
        }
    }
    if let (Some(normals), Some(nrm)) = (&mut target.normals, out.normal) {
        normals[p] = nrm;
    }
}

/// Spans at least this long go to the SIMD kernel; shorter ones cost less pixel by pixel.
const KERNEL_MIN_SPAN: usize = 8;

/// [`shade_triangle`] at 1x: the sample is the pixel centre, and the barycentric numerators
/// step along the span in exact integers (so the result is the same as evaluating them at
/// each pixel). Long spans go to the span kernel when there is one; other covered pixels
/// through a [`LaneQueue`].
#[allow(clippy::too_many_arguments)]
fn shade_single_sample(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    algorithm: Algorithm,
    clip: &PixelRect,
    depth: &PlaneEquation,
    depth_test: DepthTest,
    id: i32,
    kernel: Option<(SimdLevel, &SpanColor)>,
    fragment: impl FragmentStage,
) -> u64 {
    // Covered pixels go through a `LaneQueue`: overdraw and depth test at once, the fragments
    // that pass shaded `LANES` at a time. Built where it is used: the narrow kernel takes none,
    // and zeroing one is 16 stores per triangle.
    if algorithm == Algorithm::EdgeMasks {
        let Some(r) = setup.bounds.intersect(clip) else { return 0 };
        let narrow = (r.x1 - r.x0 + 1) as usize <= simd::NARROW_COLUMNS;
        if let Some((level, color)) = kernel.filter(|_| narrow) {
            let job = narrow_job(target, setup, &r, depth, (depth_test, id), color);
            return simd::shade_narrow(level, job);
        }
        if kernel.is_none() && raster::column::is_tall(&r) {
            return shade_columns(target, setup, &r, depth, (depth_test, id), fragment);
        }
        if narrow {
            let mut queue = LaneQueue::new(fragment, id);
            let covered = narrow_pixels::<true>(target, setup, &r, |target, at, f1, f2| {
                queue.pixel(target, depth, depth_test, at, f1, f2);
            });
            queue.flush(target);
            return covered;
        }
    }
    // Boxes the masks are not for take the scanline walk.
    let algorithm = tiled_fallback(algorithm);
    let mut queue = LaneQueue::new(fragment, id);
    let mut covered = 0u64;
    let (right, _) = setup.pixel_steps();
    let step = [right[1], right[2]];
    let shade_span = |span: Span| {
        covered += span.len() as u64;
        let row = target.index(0, span.y);
        let (mut e1, mut e2) = setup
            .barycentric_numerators(fixed::pixel_centre(span.x_start), fixed::pixel_centre(span.y));
        if let Some((level, color)) = kernel.filter(|_| span.len() >= KERNEL_MIN_SPAN) {
            let range = row + span.x_start as usize..row + span.x_end as usize;
            let job = SpanJob {
                e1,
                e2,
                step1: step[0],
                step2: step[1],
                target: kernel_target(target, range, (depth, color, depth_test, id), true),
            };
            simd::shade_span(level, job);
            return;
        }
        for px in span.x_start..span.x_end {
            let (f1, f2) = (e1 as f64, e2 as f64);
            e1 += step[0];
            e2 += step[1];
            queue.pixel(target, depth, depth_test, (row + px as usize, px, span.y), f1, f2);
        }
    };
    if algorithm == Algorithm::Scanline && raster::covers_rect(setup, clip) {
        // A tile inside a large triangle: whole rows, no edge arithmetic.
        (clip.y0..=clip.y1)
            .map(|y| Span { y, x_start: clip.x0, x_end: clip.x1 + 1 })
            .for_each(shade_span);
    } else {
        raster::rasterize(algorithm, setup, clip, shade_span);
    }
    queue.flush(target);
    covered
}

/// The pixels of box `r` a triangle covers, a column at a time ([`raster::column`]), through
/// a [`LaneQueue`]: for tall thin triangles, whose rows are mostly empty.
fn shade_columns(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    r: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    fragment: impl FragmentStage,
) -> u64 {
    let mut queue = LaneQueue::new(fragment, id);
    let mut covered = 0u64;
    let (_, down) = setup.pixel_steps();
    raster::column::rasterize(setup, r, [0, 0], |run| {
        covered += (run.y_end - run.y_start) as u64;
        let (mut e1, mut e2) = setup
            .barycentric_numerators(fixed::pixel_centre(run.x), fixed::pixel_centre(run.y_start));
        for py in run.y_start..run.y_end {
            let (f1, f2) = (e1 as f64, e2 as f64);
            e1 += down[1];
            e2 += down[2];
            let at = (target.index(run.x, py), run.x, py);
            queue.pixel(target, depth, depth_test, at, f1, f2);
        }
    });
    queue.flush(target);
    covered
}

/// What a span kernel writes: the band's buffer elements `range`, the overdraw counts there
/// too with `overdraw` (1x, where they are indexed alike), and the triangle's depth plane,
/// colour, depth test and id. Always inlined: a job's parts returned through the stack were
/// read back with loads that store forwarding fails (see ARCHITECTURE.md, *Store forwarding*).
#[inline(always)]
fn kernel_target<'a>(
    target: &'a mut TargetBand<'_>,
    range: std::ops::Range<usize>,
    (depth, color, depth_test, id): (&PlaneEquation, &'a SpanColor, DepthTest, i32),
    overdraw: bool,
) -> KernelTarget<'a> {
    KernelTarget {
        depth_plane: depth.coefficients(),
        color,
        depth_test,
        id,
        depth: &mut target.depth[range.clone()],
        color_out: &mut target.color[range.clone()],
        ids: target.ids.as_deref_mut().map(|s| &mut s[range.clone()]),
        overdraw: target.overdraw.as_deref_mut().filter(|_| overdraw).map(|s| &mut s[range]),
    }
}

/// Covered pixels of one triangle: each counted (overdraw) and depth-tested as it comes, and
/// those that pass queued until [`LANES`] wait, then shaded together by the stage
/// ([`FragmentStage::lanes`]) and written. Their writes may wait: one call of
/// [`shade_triangle`] reaches each pixel at most once, so nothing it queues is tested again
/// before the queue is flushed, which happens before the call returns (hierarchical depth
/// calls it once per run of visible blocks and reads the depth buffer in between); and the
/// stage sees fragments, not the target. Shading a queue rather than each fragment as it
/// passes lets the 3D pipeline take the perspective divisions of several fragments together.
/// Every 1x path but the SIMD kernels and [`SharedLaneQueue`] goes through it, the references
/// included; the tiled-vs-reference tests hold the lanes to single fragments, and the
/// coverage and interpolation tests (independent of it) the queue.
struct LaneQueue<S> {
    passed: PassedLanes,
    stage: S,
    id: i32,
}

impl<S: FragmentStage> LaneQueue<S> {
    /// An empty queue for the fragments of triangle `id`, shaded by `stage`.
    #[inline(always)]
    fn new(stage: S, id: i32) -> Self {
        Self { passed: PassedLanes::default(), stage, id }
    }

    /// The covered pixel `(x, y)` at buffer index `i`, with barycentric numerators `f1`, `f2`
    /// at its centre.
    #[inline(always)]
    fn pixel(
        &mut self,
        target: &mut TargetBand<'_>,
        depth: &PlaneEquation,
        depth_test: DepthTest,
        (i, x, y): (usize, i32, i32),
        f1: f64,
        f2: f64,
    ) {
        let queued = self.passed.push_passing(target, depth, depth_test, (i, x, y), f1, f2);
        if queued && self.passed.len == LANES {
            self.flush(target);
        }
    }

    /// Shades and writes the queued fragments.
    fn flush(&mut self, target: &mut TargetBand<'_>) {
        if self.passed.len == 0 {
            return;
        }
        let mut out = [None; LANES];
        self.stage.lanes(&self.passed, &mut out);
        let id = self.id;
        self.passed.write(target, &out, |_| id);
    }
}

/// A [`LaneQueue`] shared by consecutive small triangles at 1x: each lane keeps its
/// triangle's data and id, and the queue is flushed when full, not when a triangle ends (a
/// grid of two-pixel triangles flushed two fragments at a time: grid at 1x, two threads, the
/// fastest of 20 frames, 41.7 -> 39.5 ms). Writes still wait until the flush, so a pixel an
/// earlier triangle has queued is a conflict: its depth test would read the depth from before
/// that fragment. Such a pixel flushes the queue first. Every queued pixel sets one of 64
/// bits (a hash of its index): in `current` while its triangle is drawn, folded into
/// `earlier` when the next small triangle starts. A pixel whose bit is set in `earlier` is
/// checked against the lanes themselves, so a collision costs a comparison, not a flush (a
/// triangle never reaches a pixel twice, so its own lanes need no check). On a multisampled
/// target only the colour waits ([`shade_small_triangle_samples`]), so there is no conflict:
/// the bits are not used there.
pub(crate) struct SharedLaneQueue<'a, T> {
    passed: PassedLanes,
    /// Lane `l`'s triangle: its shading data and id (`Some` for the lanes in use).
    tris: [Option<&'a T>; LANES],
    ids: [i32; LANES],
    earlier: u64,
    current: u64,
    /// On a multisampled target, each lane's samples that passed the depth test (whose
    /// depth and id are already written: see [`shade_small_triangle_samples`]).
    masks: [u32; LANES],
}

/// Triangles at most this large (twice the area in fixed-point units: 4 pixels) take a
/// [`SharedLaneQueue`]. Larger ones fill their own lanes, and paid more for the shared
/// queue's bookkeeping per pixel than they saved (bunny at 1x, about 10 pixels a triangle:
/// 3-4% slower with every narrow triangle in it).
pub(crate) const SHARED_QUEUE_AREA2: i64 = 8 << (2 * fixed::SUBPIXEL_BITS);

impl<'a, T> SharedLaneQueue<'a, T> {
    /// An empty queue.
    pub(crate) fn new() -> Self {
        Self {
            passed: PassedLanes::default(),
            tris: [None; LANES],
            ids: [0; LANES],
            earlier: 0,
            current: 0,
            masks: [0; LANES],
        }
    }

    /// The bit of `earlier` or `current` buffer index `i` sets: its low six bits mixed with
    /// the two groups of six above them, so that one column's pixels on nearby rows, whose
    /// indices differ by a multiple of 64 when the width is a multiple of 64 (as 1920 is),
    /// take different bits.
    #[inline(always)]
    fn bit(i: usize) -> u64 {
        1 << ((i ^ (i >> 6) ^ (i >> 12)) & 63)
    }

    /// [`LaneQueue::pixel`] for triangle `t` (id `id`), flushing first on a conflict.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn pixel<F: TriangleFragments<T>>(
        &mut self,
        target: &mut TargetBand<'_>,
        depth: &PlaneEquation,
        depth_test: DepthTest,
        (i, x, y): (usize, i32, i32),
        f1: f64,
        f2: f64,
        (t, id, stage): (&'a T, i32, &F),
    ) {
        let bit = Self::bit(i);
        if self.earlier & bit != 0 {
            let p = &self.passed;
            if (0..p.len).any(|l| p.x[l] == x && p.y[l] == y) {
                self.flush(target, stage);
            }
        }
        let l = self.passed.len;
        if self.passed.push_passing(target, depth, depth_test, (i, x, y), f1, f2) {
            (self.tris[l], self.ids[l]) = (Some(t), id);
            self.current |= bit;
            if self.passed.len == LANES {
                self.flush(target, stage);
            }
        }
    }

    /// Shades and writes the queued fragments; the caller's draw must end with one.
    pub(crate) fn flush<F: TriangleFragments<T>>(
        &mut self,
        target: &mut TargetBand<'_>,
        stage: &F,
    ) {
        // Empty, no lane has set a bit since the last flush.
        if self.passed.len == 0 {
            return;
        }
        (self.earlier, self.current) = (0, 0);
        let mut out = [None; LANES];
        stage.lanes_of(&self.tris, &self.passed, &mut out);
        let n = target.samples().count();
        if n == 1 {
            let ids = &self.ids;
            self.passed.write(target, &out, |l| ids[l]);
            return;
        }
        // Multisampled: depth and ids were written as the samples passed; the colour (and
        // normal) now, in the lanes' order, which is the triangles'.
        for (l, out) in out.iter().enumerate().take(self.passed.len) {
            let Some(out) = out else { continue };
            let p = target.index(self.passed.x[l], self.passed.y[l]);
            let mask = self.masks[l];
            for s in (0..n).filter(|s| mask & (1 << s) != 0) {
                target.color[p * n + s] = out.color;
            }
            if let (Some(normals), Some(nrm)) = (&mut target.normals, out.normal) {
                normals[p] = nrm;
            }
        }
        self.passed.len = 0;
    }

    /// Queues the multisampled pixel `(x, y)` of triangle `t` (id `id`), with barycentric
    /// numerators `e1`, `e2` and depth `z` at its centre, whose samples `mask` passed the
    /// depth test and have had their depth and id written.
    #[inline(always)]
    fn sample_pixel<F: TriangleFragments<T>>(
        &mut self,
        target: &mut TargetBand<'_>,
        (x, y, e1, e2, z): (i32, i32, f64, f64, f32),
        mask: u32,
        (t, id, stage): (&'a T, i32, &F),
    ) {
        let l = self.passed.len;
        let q = &mut self.passed;
        (q.x[l], q.y[l], q.e1[l], q.e2[l], q.z[l]) = (x, y, e1, e2, z);
        q.len += 1;
        (self.tris[l], self.ids[l], self.masks[l]) = (Some(t), id, mask);
        if self.passed.len == LANES {
            self.flush(target, stage);
        }
    }
}

/// [`shade_triangle`] on a multisampled target for a small triangle whose stage
/// [`TriangleFragments::defers_colour`] (it shades lanes and never discards), with shading
/// data `t`: each covered sample's depth is tested and, where it passes, written at once
/// with the id, and the pixel queued in `queue` for its colour (shared with earlier
/// triangles; the caller flushes it before anything else writes colour, and at the end).
/// Writing depth first and colour later gives the reference's buffers: depth and ids are
/// written in the same order, and so is the colour (the queue's order is the triangles'),
/// which no test reads. A lone triangle of the 800 x 600 bunny (about a pixel) had filled a
/// lane or two of its own queue. `None`, with nothing done, when the box of its samples
/// within `clip` is wider or taller than [`raster::edge::NARROW`] pixels: the caller draws
/// it, after flushing the queue.
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade_small_triangle_samples<'a, T, F: TriangleFragments<T>>(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    clip: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    t: &'a T,
    stage: &F,
    queue: &mut SharedLaneQueue<'a, T>,
) -> Option<u64> {
    let samples = target.samples();
    let n = samples.count();
    debug_assert!(n > 1, "a multisampled target");
    let Some(r) = samples_rect(setup, samples, clip) else { return Some(0) };
    let narrow = raster::edge::NARROW;
    if r.x1 - r.x0 + 1 > narrow || r.y1 - r.y0 + 1 > narrow {
        return None;
    }
    let edges = setup.edges();
    let numerators = setup.numerators_of(&edges);
    let mut offsets = [[0i64; 2]; MAX_SAMPLES];
    for (s, o) in offsets.iter_mut().enumerate().take(n) {
        *o = numerators.offset(samples.offset(s));
    }
    let mut rows = SampleRows::new(&edges, samples, &r);
    let mut covered = 0u64;
    rows.each_row((r.y1 - r.y0 + 1) as usize, |j, by_sample| {
        let py = r.y0 + j as i32;
        sample_mask_pixels(by_sample, |c, mask| {
            let px = r.x0 + c;
            let centre = numerators.at(fixed::pixel_centre(px), fixed::pixel_centre(py));
            let pixel = SmallSamplePixel { at: (px, py), mask, centre, offsets: &offsets[..n] };
            covered +=
                queue_sample_pixel(target, pixel, depth, (depth_test, id), (t, stage), queue);
        });
    });
    Some(covered)
}

/// A pixel of a small triangle on a multisampled target, as [`queue_sample_pixel`] takes it.
struct SmallSamplePixel<'o> {
    /// Column and row.
    at: (i32, i32),
    /// The covered samples.
    mask: u32,
    /// The barycentric numerators at its centre.
    centre: (i64, i64),
    /// Each sample's offset from `centre`, one per sample of the target.
    offsets: &'o [[i64; 2]],
}

/// One pixel of a small triangle on a multisampled target, for
/// [`shade_small_triangle_samples`] and [`shade_small_lane_samples`]: its covered samples
/// tested, their depth and id written where they pass, and the pixel queued for its colour
/// if any did; returns the covered samples.
#[inline(always)]
fn queue_sample_pixel<'a, T, F: TriangleFragments<T>>(
    target: &mut TargetBand<'_>,
    pixel: SmallSamplePixel<'_>,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    (t, stage): (&'a T, &F),
    queue: &mut SharedLaneQueue<'a, T>,
) -> u64 {
    let SmallSamplePixel { at: (px, py), mask, centre: (c1, c2), offsets } = pixel;
    let n = offsets.len();
    let p = target.index(px, py);
    if let Some(o) = &mut target.overdraw {
        o[p] += mask.count_ones();
    }
    // Every sample's depth tested and written back, its own where it fails or is not
    // covered: no branch on the masks, which these triangles' edges make unpredictable.
    let mut passed = 0u32;
    let depths = &mut target.depth[p * n..p * n + n];
    for (s, stored) in depths.iter_mut().enumerate() {
        let [o1, o2] = offsets[s];
        let z = depth_at(depth, (c1 + o1) as f64, (c2 + o2) as f64);
        let pass = mask >> s & 1 != 0 && depth_test.passes(z, *stored);
        *stored = if pass { z } else { *stored };
        passed |= u32::from(pass) << s;
    }
    if passed != 0 {
        // Ids only where a sample passed: a hidden pixel's ids stay unread.
        if let Some(ids) = &mut target.ids {
            for (s, stored) in ids[p * n..p * n + n].iter_mut().enumerate() {
                *stored = if passed >> s & 1 != 0 { id } else { *stored };
            }
        }
        let (e1, e2) = (c1 as f64, c2 as f64);
        let centre = (px, py, e1, e2, depth_at(depth, e1, e2));
        queue.sample_pixel(target, centre, passed, (t, id, stage));
    }
    u64::from(mask.count_ones())
}

/// [`shade_small_triangle_samples`] of lane `l` of `eight` on a [`simd::SMALL_SAMPLES`]
/// target, its samples' coverage `samples` ([`simd::small_eight`] and
/// [`simd::small_samples`]: the edges and each sample's coverage of a box of at most 8 x 8
/// pixels, computed with seven others), whose samples' box within the clip rectangle is `r`:
/// the same samples tested in the same order, the same pixels queued. Alone, each triangle
/// had set up its own edges, sample box and rows (the default render, the Phong bunny at
/// 4x, load and four frames: 1.359 -> 1.015 G instructions; fastest frames on two threads
/// 20.1 -> 16.1 ms).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn shade_small_lane_samples<'a, T, F: TriangleFragments<T>>(
    target: &mut TargetBand<'_>,
    (eight, samples, l): (&simd::SmallEight, &simd::SmallSamples, usize),
    r: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    t: &'a T,
    stage: &F,
    queue: &mut SharedLaneQueue<'a, T>,
) -> u64 {
    debug_assert_eq!(target.samples(), simd::SMALL_SAMPLES, "a 4x target");
    let small = simd::SMALL_BOX;
    debug_assert!(r.x1 - r.x0 < small && r.y1 - r.y0 < small, "a box of at most 8 x 8 pixels");
    // The box's pixels (the coverage bits run on over the widest box of the eight).
    let cells = simd::box_cells((r.x1 - r.x0 + 1) as u32, (r.y1 - r.y0 + 1) as u32);
    let mut inside = eight.inside[l] & cells;
    let offsets = eight.sample_numerator_offsets(l);
    let mut covered = 0u64;
    while inside != 0 {
        let bit = inside.trailing_zeros();
        inside &= inside - 1;
        let [c1, c2] = eight.numerators(l, bit).map(i64::from);
        let at = (r.x0 + (bit & 7) as i32, r.y0 + (bit >> 3) as i32);
        let (mask, centre) = (samples.mask(l, bit), (c1, c2));
        let pixel = SmallSamplePixel { at, mask, centre, offsets: &offsets };
        covered += queue_sample_pixel(target, pixel, depth, (depth_test, id), (t, stage), queue);
    }
    covered
}

/// [`shade_triangle`] at 1x without a span kernel, for a small triangle (see
/// [`SHARED_QUEUE_AREA2`]) with shading data `t`, its fragments going through `queue`
/// (whose lanes may already hold earlier triangles'; the caller flushes it at the end).
/// `None`, with nothing done, when its box within `clip` is wider than the narrow path takes
/// (a sliver): the caller draws it, after flushing the queue.
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade_small_triangle<'a, T, F: TriangleFragments<T>>(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    clip: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    t: &'a T,
    stage: &F,
    queue: &mut SharedLaneQueue<'a, T>,
) -> Option<u64> {
    debug_assert_eq!(target.samples().count(), 1, "a shared queue at 1x only");
    let Some(r) = setup.bounds.intersect(clip) else { return Some(0) };
    if r.x1 - r.x0 + 1 > raster::edge::NARROW {
        return None;
    }
    // The lanes queued so far are now an earlier triangle's.
    (queue.earlier, queue.current) = (queue.earlier | queue.current, 0);
    Some(narrow_pixels::<false>(target, setup, &r, |target, at, f1, f2| {
        queue.pixel(target, depth, depth_test, at, f1, f2, (t, id, stage));
    }))
}

/// [`shade_small_triangle`] of lane `l` of `eight` ([`simd::small_eight`]: the edges and
/// the inside pixels of a box of at most 8 x 8 pixels, computed with seven others), whose
/// box within the clip rectangle is `r`: the same fragments in the same order, the same
/// queue.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn shade_small_lane<'a, T, F: TriangleFragments<T>>(
    target: &mut TargetBand<'_>,
    (eight, l): (&simd::SmallEight, usize),
    r: &PixelRect,
    depth: &PlaneEquation,
    (depth_test, id): (DepthTest, i32),
    t: &'a T,
    stage: &F,
    queue: &mut SharedLaneQueue<'a, T>,
) -> u64 {
    debug_assert_eq!(target.samples().count(), 1, "a shared queue at 1x only");
    let small = simd::SMALL_BOX;
    debug_assert!(r.x1 - r.x0 < small && r.y1 - r.y0 < small, "a box of at most 8 x 8 pixels");
    // The lanes queued so far are now an earlier triangle's.
    (queue.earlier, queue.current) = (queue.earlier | queue.current, 0);
    let columns = (r.x1 - r.x0 + 1) as u32;
    let wide = |v: &[[i32; 8]; 3]| [i64::from(v[0][l]), i64::from(v[1][l]), i64::from(v[2][l])];
    let (step_x, step_y) = (wide(&eight.step_x), wide(&eight.step_y));
    let bias = [i64::from(eight.bias[0][l]), i64::from(eight.bias[1][l])];
    let mut row = wide(&eight.edges);
    let mut pixel = |target: &mut TargetBand<'_>, at, f1, f2| {
        queue.pixel(target, depth, depth_test, at, f1, f2, (t, id, stage));
    };
    let mut covered = 0;
    for (n, py) in (r.y0..=r.y1).enumerate() {
        let mask = (eight.inside[l] >> (8 * n)) as u32 & ((1 << columns) - 1);
        covered += row_pixels(target, &mut pixel, mask, (&row, step_x, bias), (r.x0, py));
        row = std::array::from_fn(|k| row[k] + step_y[k]);
    }
    covered
}

/// Calls `pixel(target, (i, x, y), f1, f2)` for each pixel of box `r` (at most
/// [`raster::edge::NARROW`] wide) triangle `setup` covers, row by row, left to
/// right, with its buffer index and barycentric numerators; returns how many. Row coverage is
/// a bit mask without branches (as `rasterize_narrow`): with `SIMD_MASKS`, those of a run of
/// rows at once from [`simd::row_masks`], else row by row in scalar code.
///
/// The SIMD masks pay for their setup once a triangle has a few pixels a row: one drawn
/// alone (the bunny's, about 10 pixels) takes them (the bunny's frame 4.5% fewer
/// instructions; one thread, fastest frames of three alternated runs 10.6-11.6 -> 10.0-11.3
/// ms); the smallest
/// triangles, which share a queue ([`shade_small_triangle`], the grid's two-pixel ones),
/// took 5% more instructions with them and keep the scalar masks.
#[inline(always)]
fn narrow_pixels<const SIMD_MASKS: bool>(
    target: &mut TargetBand<'_>,
    setup: &TriangleSetup,
    r: &PixelRect,
    mut pixel: impl FnMut(&mut TargetBand<'_>, (usize, i32, i32), f64, f64),
) -> u64 {
    let columns = (r.x1 - r.x0 + 1) as usize;
    let (edges, step_x, step_y, bias) = narrow_start(setup, r);
    let mut covered = 0u64;
    let mut row = edges;
    if !SIMD_MASKS {
        for py in r.y0..=r.y1 {
            let mask = raster::edge::row_coverage_within(row, step_x, columns);
            covered += row_pixels(target, &mut pixel, mask, (&row, step_x, bias), (r.x0, py));
            row = std::array::from_fn(|k| row[k] + step_y[k]);
        }
        return covered;
    }
    let mut masks = [0u8; 16];
    let mut py = r.y0;
    while py <= r.y1 {
        let run = &mut masks[..((r.y1 - py + 1) as usize).min(16)];
        simd::row_masks(SimdLevel::detected(), row, step_x, step_y, columns, run);
        for &mask in run.iter() {
            let mask = u32::from(mask);
            covered += row_pixels(target, &mut pixel, mask, (&row, step_x, bias), (r.x0, py));
            row = std::array::from_fn(|k| row[k] + step_y[k]);
            py += 1;
        }
    }
    covered
}

/// [`narrow_pixels`]' calls for the pixels `mask` covers on row `py` (bit `c`: pixel
/// `x0 + c`), whose first pixel has biased edge values `row`; returns how many.
#[inline(always)]
fn row_pixels(
    target: &mut TargetBand<'_>,
    pixel: &mut impl FnMut(&mut TargetBand<'_>, (usize, i32, i32), f64, f64),
    mut mask: u32,
    (row, step_x, bias): (&[i64; 3], [i64; 3], [i64; 2]),
    (x0, py): (i32, i32),
) -> u64 {
    let covered = u64::from(mask.count_ones());
    let first = target.index(x0, py);
    while mask != 0 {
        let c = mask.trailing_zeros();
        mask &= mask - 1;
        let f1 = (row[1] - bias[0] + i64::from(c) * step_x[1]) as f64;
        let f2 = (row[2] - bias[1] + i64::from(c) * step_x[2]) as f64;
        pixel(target, (first + c as usize, x0 + c as i32, py), f1, f2);
    }
    covered
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clip reaching past the band's columns shades only the band's pixels, as the same
    /// clip cut to the band does (it had written the pixels its columns wrapped to, at the
    /// right of the rows above), for every algorithm, sample count and kernel.
    #[test]
    fn clips_past_the_band_shade_only_the_band() {
        let corners = [[-6.0f32, 17.0], [3.0, 17.0], [-5.0, 30.0]];
        let v = corners.map(|[x, y]| Vertex::new(x, y, 0.5, [9, 8, 7, 255]));
        let setup = TriangleSetup::new(&v, crate::CullMode::None).unwrap();
        let depth = PlaneEquation::from_coefficients([0.5, 0.0, 0.0]);
        let color = SpanColor::Flat([1, 2, 3, 4]);
        let wide = PixelRect { x0: -8, y0: 16, x1: 70, y1: 31 };
        let cut = PixelRect { x0: 0, y0: 16, x1: 3, y1: 31 };
        for samples in [SampleCount::X1, SampleCount::X4] {
            for algorithm in [Algorithm::EdgeFunctions, Algorithm::Scanline, Algorithm::EdgeMasks] {
                for kernel in [None, Some(SimdLevel::Scalar), Some(SimdLevel::detect())] {
                    let shaded = |clip: &PixelRect| {
                        let mut target =
                            crate::Target::multisampled(64, 64, samples).unwrap().with_ids();
                        let fragment = |_: i32, _: i32, _: f64, _: f64, _: f32| {
                            Some(FragmentOutput { color: [5; 4], normal: None })
                        };
                        let kernel = kernel.map(|level| (level, &color));
                        let n = shade_triangle(
                            &mut target.band(),
                            &setup,
                            algorithm,
                            clip,
                            &depth,
                            DepthTest::Less,
                            1,
                            kernel,
                            fragment,
                        );
                        (n, target.ids.unwrap(), target.color)
                    };
                    let what = format!("{samples:?} {algorithm:?} {kernel:?}");
                    let (n, ids, color) = shaded(&wide);
                    assert!(n > 0, "{what}");
                    assert_eq!((n, ids, color), shaded(&cut), "{what}");
                }
            }
        }
    }

    /// The colour a triangle keeps gives, per channel, `quantize_channel` of the plane the
    /// definition names: the plane's coefficients with fused multiply-adds for smooth colours
    /// (four planes, or three and an alpha; see `SpanColor::at`), `PerspectivePlane::eval`
    /// for perspective ones (whose shared `1 / w` plane is evaluated once), at random
    /// numerators, for random triangles.
    #[test]
    fn triangle_colours_follow_their_planes() {
        let mut rng = SmallRng::seed_from_u64(12);
        for round in 0..2000 {
            let alpha = (round % 2 == 0).then_some(200);
            let v: [Vertex; 3] = std::array::from_fn(|_| Vertex {
                x: rng.random_range(-50.0..50.0),
                y: rng.random_range(-50.0..50.0),
                z: 0.5,
                inv_w: rng.random_range(0.1..4.0),
                color: [rng.random(), rng.random(), rng.random(), alpha.unwrap_or(rng.random())],
            });
            let Ok(setup) = TriangleSetup::new(&v, crate::CullMode::None) else { continue };
            let channel = |c: usize| v.map(|p| f64::from(p.color[c]));
            let inv_w = v.map(|p| f64::from(p.inv_w));
            let smooth = TriangleShader::new(&v, &setup, Shading::Smooth);
            let perspective = TriangleShader::new(&v, &setup, Shading::Perspective);
            for _ in 0..8 {
                let e1 = rng.random_range(-1e5..1e5f64).round();
                let e2 = rng.random_range(-1e5..1e5f64).round();
                let want: [u8; 4] = std::array::from_fn(|c| {
                    let [a0, g1, g2] = PlaneEquation::new(channel(c), &setup).coefficients();
                    quantize_channel(e2.mul_add(g2, e1.mul_add(g1, a0)))
                });
                assert_eq!(smooth.color_at(e1, e2), want);
                let want: [u8; 4] = std::array::from_fn(|c| {
                    quantize_channel(PerspectivePlane::new(channel(c), inv_w, &setup).eval(e1, e2))
                });
                assert_eq!(perspective.color_at(e1, e2), want);
            }
        }
    }
    use crate::sample::SampleCount;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// `SampleRows::each_row` gives the `i64` row masks of `next_row` (each sample's
    /// `row_coverage_within`), whichever way it steps: random small triangles anywhere in the
    /// fixed-point range whose sample boxes are 1 to 8 pixels wide and tall, at 4x and 8x,
    /// some cut by a clip rectangle; and large triangles clipped to such a box, whose edge
    /// values there do not fit in `i32`, so the `i64` steps take over.
    #[test]
    fn sample_rows_match_the_i64_masks() {
        let mut rng = SmallRng::seed_from_u64(47);
        let (mut narrow, mut wide) = (0, 0);
        for round in 0..20_000 {
            let samples = [SampleCount::X4, SampleCount::X8][round % 2];
            // Vertices within the fixed-point range, [-32768, 32768) pixels, as setup asks.
            let far = [0.0, 5000.0, 16000.0][round % 3];
            let (cx, cy) = (rng.random_range(-far..=far), rng.random_range(-far..=far));
            let large = round % 7 == 0;
            let size = if large {
                rng.random_range(2000.0..16000.0)
            } else {
                rng.random_range(0.3..9.0f32)
            };
            let xy: [[i64; 2]; 3] = std::array::from_fn(|_| {
                let x = cx + rng.random_range(0.0..size);
                let y = cy + rng.random_range(0.0..size);
                [(x * 256.0).round() as i64, (y * 256.0).round() as i64]
            });
            let Ok(setup) = TriangleSetup::from_snapped(xy, crate::CullMode::None) else {
                continue;
            };
            let mut clip = PixelRect::of_target(1, 1);
            (clip.x0, clip.y0, clip.x1, clip.y1) = (-40000, -40000, 40000, 40000);
            if large {
                // A box of up to 8 x 8 pixels somewhere in the triangle's box.
                let (x0, y0) =
                    (cx as i32 + rng.random_range(0..2000), cy as i32 + rng.random_range(0..2000));
                (clip.x0, clip.y0) = (x0, y0);
                (clip.x1, clip.y1) = (x0 + rng.random_range(0..8), y0 + rng.random_range(0..8));
            } else if round % 5 == 0 {
                clip.x0 = (cx as i32) + rng.random_range(0..4);
            }
            let Some(r) = samples_rect(&setup, samples, &clip) else { continue };
            let (columns, rows) = (r.x1 - r.x0 + 1, (r.y1 - r.y0 + 1) as usize);
            if columns > raster::edge::NARROW || rows > raster::edge::NARROW as usize {
                continue;
            }
            let edges = setup.edges();
            let mut reference = SampleRows::new(&edges, samples, &r);
            let want: Vec<u64> = (0..rows).map(|_| reference.next_row()).collect();
            let mut got = vec![0; rows];
            SampleRows::new(&edges, samples, &r).each_row(rows, |j, m| got[j] = m);
            assert_eq!(got, want, "{xy:?} {samples:?} {r:?}");
            let huge = reference.rows.iter().flatten().any(|v| v.abs() > i64::from(i32::MAX));
            if huge {
                wide += 1
            } else if columns <= 4 {
                narrow += 1
            }
        }
        assert!(narrow > 2000 && wide > 200, "both ways taken: {narrow}, {wide}");
    }

    /// `depth_bounds` holds every pixel's depth over random rectangles of random triangles
    /// (small to the edge of the fixed-point range, slivers, steep, flat and nearly flat depth
    /// whose steps are as small as its rounding errors, some beyond
    /// [0, 1] so the clamp matters), and, with half a pixel's reach, every 8x sample; it is
    /// tight: within two `f32` steps on one pixel. A NaN plane hides nothing.
    #[test]
    fn depth_bounds_hold_every_pixel() {
        let mut rng = SmallRng::seed_from_u64(31);
        let mut checked = 0;
        while checked < 1200 {
            // Up to the edge of the fixed-point range (numerators near 2^49), and slivers.
            let scale = [4.0, 60.0, 2000.0, 32000.0][checked % 4];
            let mut tri: [Vertex; 3] = std::array::from_fn(|_| {
                Vertex::new(
                    rng.random_range(-scale..scale),
                    rng.random_range(-scale..scale),
                    rng.random_range(-0.2..1.2),
                    [0; 4],
                )
            });
            if checked % 5 == 0 {
                tri[2].x = tri[0].x + rng.random_range(-2.0..2.0);
                tri[2].y = tri[0].y + rng.random_range(-2.0..2.0);
            }

            let Ok(setup) = TriangleSetup::new(&tri, crate::setup::CullMode::None) else {
                continue;
            };
            checked += 1;
            let mut values = tri.map(|v| f64::from(v.z));
            if checked % 3 == 0 {
                // Nearly flat: steps of the plane as small as its rounding errors.
                let tiny = |rng: &mut SmallRng| values[0] * 1e-15 * rng.random_range(-4.0..4.0);
                values = [values[0], values[0] + tiny(&mut rng), values[0] + tiny(&mut rng)];
            }
            let plane = PlaneEquation::new(values, &setup);
            // Near a vertex, where the far corners' numerators are largest.
            let mut near = |v: f32| v as i32 + rng.random_range(-40..40);
            let (x0, y0) = (near(tri[0].x), near(tri[0].y));
            let rect = PixelRect {
                x0,
                y0,
                x1: x0 + rng.random_range(0..24),
                y1: y0 + rng.random_range(0..24),
            };
            let (lo, hi) = depth_bounds(&plane, &setup, &rect, 0);
            let (lo64, hi64) = plane_bounds(&plane, &setup, &rect, 0).unwrap();
            let samples = depth_bounds(&plane, &setup, &rect, SampleCount::X8.reach());
            assert!(lo <= hi);
            for y in rect.y0..=rect.y1 {
                for x in rect.x0..=rect.x1 {
                    let (e1, e2) = setup
                        .barycentric_numerators(fixed::pixel_centre(x), fixed::pixel_centre(y));
                    let (e1, e2) = (e1 as f64, e2 as f64);
                    // The computed values themselves, not only their rounding to `f32` (which
                    // hides most rounding errors of the plane).
                    let v = plane.eval(e1, e2);
                    assert!(lo64 <= v && v <= hi64, "{v} outside [{lo64}, {hi64}] at ({x}, {y})");
                    let z = depth_at(&plane, e1, e2);
                    assert!(lo <= z && z <= hi, "{z} outside [{lo}, {hi}] at ({x}, {y})");
                    // Every sample of the pixel at 8x, within half a pixel of its centre.
                    for s in 0..SampleCount::X8.count() {
                        let [ox, oy] = SampleCount::X8.offset(s);
                        let (cx, cy) = (fixed::pixel_centre(x) + ox, fixed::pixel_centre(y) + oy);
                        let (e1, e2) = setup.barycentric_numerators(cx, cy);
                        let z = depth_at(&plane, e1 as f64, e2 as f64);
                        let (lo, hi) = samples;
                        assert!(lo <= z && z <= hi, "sample {s}: {z} outside [{lo}, {hi}]");
                    }
                }
            }
            let one = PixelRect { x1: rect.x0, y1: rect.y0, ..rect };
            let (e1, e2) = setup
                .barycentric_numerators(fixed::pixel_centre(one.x0), fixed::pixel_centre(one.y0));
            let z = depth_at(&plane, e1 as f64, e2 as f64);
            let (lo, hi) = depth_bounds(&plane, &setup, &one, 0);
            assert!(lo <= z && z <= hi && hi - lo <= 2.0 * f32::EPSILON, "{lo} {z} {hi}");
        }
        let tri = [(0.0, 0.0), (9.0, 0.0), (0.0, 9.0)].map(|(x, y)| Vertex::new(x, y, 0.5, [0; 4]));
        let setup = TriangleSetup::new(&tri, crate::setup::CullMode::None).unwrap();
        let nan = PlaneEquation::new([f64::NAN, 0.5, 0.5], &setup);
        let rect = PixelRect { x0: 0, y0: 0, x1: 4, y1: 4 };
        assert_eq!(depth_bounds(&nan, &setup, &rect, 0), (f32::NEG_INFINITY, f32::INFINITY));
    }

    /// The quantizer rounds half to even after clamping, as `f64::round_ties_even` would, for
    /// every half and quarter step over the range and beyond it, NaN and infinities.
    #[test]
    fn quantize_clamps_and_rounds_half_to_even() {
        let expect =
            |c: f64| if c.is_nan() { 0 } else { c.clamp(0.0, 255.0).round_ties_even() as u8 };
        let mut values = vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, 1e300, -1e300];
        for k in -400..1500 {
            let c = f64::from(k) * 0.25;
            values.extend([c, c.next_up(), c.next_down()]);
        }
        for c in values {
            assert_eq!(quantize_channel(c), expect(c), "{c}");
        }
    }

    /// Small triangles (boxes up to 8 pixels wide) on 4x and 8x targets with random buffers,
    /// shaded through a span kernel's colour at every SIMD level, leave the buffers and the
    /// count of the per-pixel loop given a fragment stage computing the same colour: the
    /// narrow sample kernels against the loop they replace. Flat and smooth colours, opaque
    /// ones (whose planes the kernels clamp where partly covered pixels' centres lie outside
    /// the triangle), every depth test, with and without ids.
    #[test]
    fn narrow_sample_kernels_match_the_pixel_loop() {
        let mut rng = SmallRng::seed_from_u64(2111);
        let (w, h) = (20u32, 16u32);
        let mut kernel_runs = 0;
        for round in 0..3000 {
            let samples = [SampleCount::X4, SampleCount::X8][round % 2];
            let shading = [Shading::Flat, Shading::Smooth][(round / 2) % 2];
            let opaque = round % 3 != 0;
            let (cx, cy) = (rng.random_range(0.0..w as f32), rng.random_range(0.0..h as f32));
            let size = [1.5, 3.0, 4.5][round % 3];
            let v: [Vertex; 3] = std::array::from_fn(|_| Vertex {
                x: cx + rng.random_range(-size..size),
                y: cy + rng.random_range(-size..size),
                z: rng.random_range(0.0..1.0),
                inv_w: 1.0,
                color: [
                    rng.random(),
                    rng.random(),
                    rng.random(),
                    if opaque { 255 } else { rng.random() },
                ],
            });
            let Ok(setup) = TriangleSetup::new(&v, crate::CullMode::None) else { continue };
            let shader = TriangleShader::new(&v, &setup, shading);
            let Some(color) = shader.span_color() else { continue };
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let mut start = crate::Target::multisampled(w, h, samples).unwrap();
            if round % 4 != 0 {
                start = start.with_ids();
            }
            for z in &mut start.depth {
                *z = [0.0, 1.0, rng.random_range(0.0..1.0)][rng.random_range(0..3)];
            }
            for c in &mut start.color {
                *c = [rng.random(); 4];
            }
            let clip = start.rect();
            let run = |level: Option<SimdLevel>| {
                let mut target = start.clone();
                let fragment = |_, _, e1, e2, _| {
                    Some(FragmentOutput { color: shader.color_at(e1, e2), normal: None })
                };
                let covered = shade_triangle(
                    &mut target.band(),
                    &setup,
                    Algorithm::EdgeMasks,
                    &clip,
                    &shader.depth,
                    depth_test,
                    7,
                    level.map(|l| (l, color)),
                    fragment,
                );
                (covered, target.depth.iter().map(|z| z.to_bits()).collect::<Vec<_>>(), target)
            };
            let (covered, depth, target) = run(None);
            // The box the narrow path takes: the union of the sample boxes.
            let boxes = (0..samples.count()).map(|s| setup.sample_bounds(samples.offset(s)));
            let r = boxes.reduce(|a, b| a.union(&b)).unwrap();
            kernel_runs += usize::from(covered > 0 && r.x1 - r.x0 < 8);
            for level in SimdLevel::available() {
                let (k_covered, k_depth, k_target) = run(Some(level));
                let what = format!("{level:?}, round {round}");
                assert_eq!(k_covered, covered, "{what}");
                assert_eq!(k_depth, depth, "{what}");
                assert_eq!(k_target.color, target.color, "{what}");
                assert_eq!(k_target.ids, target.ids, "{what}");
            }
        }
        assert!(kernel_runs > 1000, "{kernel_runs} narrow triangles covered a sample");
    }
}
