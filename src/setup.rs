//! Triangle setup: snap the vertices, classify the triangle (winding, culling, degeneracy),
//! and derive the three integer edge functions with the fill rule folded in.
//!
//! Contract: `TriangleSetup::new` either rejects a triangle (a [`Rejection`] the caller counts)
//! or returns a setup whose edges (`TriangleSetup::edges`) are such that a sample point `P`
//! (fixed point) is covered iff `edge.eval(P) >= 0` for all three edges. Nothing downstream
//! knows about windings or ties.

use crate::fixed::{self, ONE};
use crate::sample::SampleCount;

/// A vertex in window space: `x`, `y` in pixels (origin at the top-left corner of the image,
/// y down), `z` in [0, 1], and `inv_w = 1/w` for perspective-correct varyings (1 when the
/// vertex did not come through a projection).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Vertex {
    /// Horizontal window coordinate, pixels.
    pub x: f32,
    /// Vertical window coordinate, pixels, growing downwards.
    pub y: f32,
    /// Depth in [0, 1]; interpolated linearly in screen space.
    pub z: f32,
    /// Reciprocal of the clip-space `w`; weights perspective-correct varyings.
    pub inv_w: f32,
    /// Vertex colour, RGBA8.
    pub color: [u8; 4],
}

// The layout the SIMD front end reads: `simd::avx2::window_group` bytes 0 to 16 (`x`, `y`,
// `z`, `inv_w`), `simd::avx2::window_records` bytes 4 to 20 (`y`, `z`, `inv_w`, `color`).
const _: () = {
    use std::mem::offset_of;
    assert!(size_of::<Vertex>() == 20 && offset_of!(Vertex, y) == 4 && offset_of!(Vertex, z) == 8);
    assert!(offset_of!(Vertex, inv_w) == 12 && offset_of!(Vertex, color) == 16);
};

impl Vertex {
    /// A vertex with `inv_w = 1` (no perspective).
    #[must_use]
    pub const fn new(x: f32, y: f32, z: f32, color: [u8; 4]) -> Self {
        Self { x, y, z, inv_w: 1.0, color }
    }
}

/// Which screen-space winding to discard. Windings are as seen on the image (y down):
/// a triangle whose vertices go clockwise on screen is `Clockwise`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CullMode {
    /// Draw both windings.
    #[default]
    None,
    /// Discard triangles that are clockwise on screen.
    Clockwise,
    /// Discard triangles that are counter-clockwise on screen.
    CounterClockwise,
}

/// Why setup produced no triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rejection {
    /// A coordinate (x, y, z or 1/w) is NaN or infinite: dropped and counted, never rasterized.
    NonFinite,
    /// A vertex lies outside [-32768, 32768) pixels; the edge functions could overflow.
    OutOfRange,
    /// Zero area after snapping: covers no sample.
    Degenerate,
    /// Removed by the cull mode.
    Culled,
}

/// The fill rule that decides samples exactly on an edge: D3D10+/Vulkan top-left, y down.
///
/// A sample on an edge belongs to the triangle iff the edge is a *top* edge (exactly horizontal,
/// the third vertex below it) or a *left* edge. With the winding normalised so that the inside
/// is `E > 0`, an edge `a -> b` has `A = Ya - Yb` and `B = Xb - Xa`; it is
/// - *left* iff `A > 0` (the edge goes up the screen, so the inside lies to its right), and
/// - *top* iff `A == 0 && B > 0` (horizontal, going right, so the inside lies below it).
///
/// Proof that shared edges are owned once: two triangles sharing the edge with the inside on
/// opposite sides see it as `a -> b` and `b -> a`, i.e. with `(A, B)` and `(-A, -B)`. Exactly
/// one of those pairs satisfies `A > 0 || (A == 0 && B > 0)` unless `A == B == 0`, which a
/// non-degenerate edge never is. So a sample exactly on the shared edge is in exactly one of
/// the two triangles; a sample at a shared vertex follows the same argument around the fan.
///
/// Because `E` is an integer at every sample, "`E >= 0` on owned edges, `E > 0` elsewhere" is
/// `E + bias >= 0` with `bias = 0` on owned edges and `-1` elsewhere: the rule is applied once,
/// here, and the inner loops test plain signs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FillRule;

impl FillRule {
    /// The bias added to `C` of an edge with coefficients `(a, b)` (inside is positive).
    #[inline]
    #[must_use]
    pub fn bias(a: i64, b: i64) -> i64 {
        // Bitwise, not short-circuit: edges of random orientation mispredicted the branches.
        i64::from((a > 0) | ((a == 0) & (b > 0))) - 1
    }
}

/// An edge function `E(X, Y) = a*X + b*Y + c` over fixed-point coordinates, positive inside,
/// with the fill-rule bias already in `c`. Ranges: see [`crate::fixed`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EdgeFunction {
    /// Coefficient of X (`Ya - Yb`): stepping one fixed-point unit right adds `a`.
    pub a: i64,
    /// Coefficient of Y (`Xb - Xa`).
    pub b: i64,
    /// Constant term, including the fill-rule bias.
    pub c: i64,
}

impl EdgeFunction {
    /// The biased edge value at fixed-point `(x, y)`: the sample is on the inside of this edge
    /// (ties resolved by the fill rule) iff the result is `>= 0`.
    #[inline]
    #[must_use]
    pub fn eval(&self, x: i64, y: i64) -> i64 {
        self.a * x + self.b * y + self.c
    }

    /// The values of a triangle's three edges at fixed-point `(x, y)` (covered iff all are
    /// `>= 0`). Written out element by element, like [`widen`], for the per-triangle paths,
    /// which derive the edges once ([`TriangleSetup::edges`]) and evaluate them here.
    #[inline(always)]
    #[must_use]
    pub fn values(edges: &[Self; 3], x: i64, y: i64) -> [i64; 3] {
        let [a, b, c] = edges;
        [a.eval(x, y), b.eval(x, y), c.eval(x, y)]
    }

    /// What the three edges' values change by from one pixel to the next: `(right, down)`.
    #[inline(always)]
    #[must_use]
    pub fn pixel_steps(edges: &[Self; 3]) -> ([i64; 3], [i64; 3]) {
        let [a, b, c] = edges;
        (
            [a.a * PIXEL_STEP, b.a * PIXEL_STEP, c.a * PIXEL_STEP],
            [a.b * PIXEL_STEP, b.b * PIXEL_STEP, c.b * PIXEL_STEP],
        )
    }

    /// True iff this edge owns samples lying exactly on it (top or left edge).
    #[must_use]
    pub fn is_top_left(&self) -> bool {
        FillRule::bias(self.a, self.b) == 0
    }
}

/// Inclusive pixel rectangle `[x0, x1] x [y0, y1]`, used for bounding boxes and scissors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelRect {
    /// First column.
    pub x0: i32,
    /// First row.
    pub y0: i32,
    /// Last column (inclusive).
    pub x1: i32,
    /// Last row (inclusive).
    pub y1: i32,
}

impl PixelRect {
    /// A rectangle containing no pixel.
    pub const EMPTY: Self = Self { x0: 0, y0: 0, x1: -1, y1: -1 };

    /// The rectangle of a whole `width x height` target. A side past `i32::MAX` (no target's:
    /// they stop at [`crate::fixed::MAX_TARGET_SIZE`]) is taken as `i32::MAX`, where the
    /// subtraction had wrapped it to a negative bound.
    #[must_use]
    pub fn of_target(width: u32, height: u32) -> Self {
        let last = |side: u32| side.min(i32::MAX as u32) as i32 - 1;
        Self { x0: 0, y0: 0, x1: last(width), y1: last(height) }
    }

    /// Intersection; `None` when empty.
    #[must_use]
    pub fn intersect(&self, other: &Self) -> Option<Self> {
        let r = Self {
            x0: self.x0.max(other.x0),
            y0: self.y0.max(other.y0),
            x1: self.x1.min(other.x1),
            y1: self.y1.min(other.y1),
        };
        (r.x0 <= r.x1 && r.y0 <= r.y1).then_some(r)
    }

    /// Number of pixels (0 when empty).
    #[must_use]
    pub fn area(&self) -> i64 {
        let side = |a: i32, b: i32| (i64::from(b) - i64::from(a) + 1).max(0);
        // Saturating: the widest rectangle has 2^64 pixels.
        side(self.x0, self.x1).saturating_mul(side(self.y0, self.y1))
    }

    /// The smallest rectangle holding both.
    #[must_use]
    pub fn union(&self, other: &Self) -> Self {
        Self {
            x0: self.x0.min(other.x0),
            y0: self.y0.min(other.y0),
            x1: self.x1.max(other.x1),
            y1: self.y1.max(other.y1),
        }
    }
}

/// Everything the rasterizers and the shader need to know about one triangle.
///
/// Edge `i` is the edge opposite vertex `i` (from vertex `i+1` to vertex `i+2`), so its
/// unbiased value at a sample is `2 * area * barycentric_i`.
///
/// The edge functions are not stored but derived from the vertices and the winding
/// ([`TriangleSetup::edges`], a few integer operations): the tile loop reads every set-up
/// triangle back from memory, and the 72 bytes they took were more than a quarter of a window
/// triangle's record, then 192 bytes (a million small random triangles at 1x, two threads: 75
/// -> 68-69 ms; the grid mesh, drawn in bands, 45 -> 42-43 ms). Window records now keep only
/// the vertices and winding of it (`TriangleSetup::from_kept`, crate-private).
#[derive(Clone, Copy, Debug)]
pub struct TriangleSetup {
    /// Snapped vertex positions, in the caller's order (within `+-2^23`: `i32` keeps the
    /// record the tile loop reads small).
    pub xy: [[i32; 2]; 3],
    /// Twice the (absolute) area in fixed-point units squared: `E_i(v_i)` unbiased. `> 0`.
    pub area2: i64,
    /// True when the input winding is clockwise on screen (y down).
    pub clockwise: bool,
    /// Pixels whose centres may be covered: the snapped bounding box, not yet clipped.
    pub bounds: PixelRect,
}

impl TriangleSetup {
    /// Snaps and sets up a triangle; see [`Rejection`] for the ways it can produce nothing.
    ///
    /// Inlined, like [`TriangleSetup::from_snapped`]: called out of line, its result came back
    /// through the stack, written with narrow stores and read with wide loads that waited on
    /// them (store forwarding fails).
    #[inline(always)]
    pub fn new(v: &[Vertex; 3], cull: CullMode) -> Result<Self, Rejection> {
        let finite = v
            .iter()
            .all(|p| p.x.is_finite() && p.y.is_finite() && p.z.is_finite() && p.inv_w.is_finite());
        if !finite {
            return Err(Rejection::NonFinite);
        }
        let mut xy = [[0i64; 2]; 3];
        for (dst, p) in xy.iter_mut().zip(v) {
            let (Some(x), Some(y)) = (fixed::snap(p.x), fixed::snap(p.y)) else {
                return Err(Rejection::OutOfRange);
            };
            *dst = [i64::from(x), i64::from(y)];
        }
        Self::from_snapped(xy, cull)
    }

    /// Sets up a triangle from already-snapped coordinates (each within `+-2^23`, else
    /// [`Rejection::OutOfRange`]).
    #[inline(always)]
    pub fn from_snapped(xy: [[i64; 2]; 3], cull: CullMode) -> Result<Self, Rejection> {
        let signed = Self::signed_area2(xy, cull)?;
        let clockwise = signed > 0;
        let [p0, p1, p2] = xy;
        let bounds = sample_bounds(extent(xy), [0, 0]);
        let narrow = |[x, y]: [i64; 2]| [x as i32, y as i32];
        let xy = [narrow(p0), narrow(p1), narrow(p2)];
        Ok(Self { xy, area2: signed.abs(), clockwise, bounds })
    }

    /// The setup [`TriangleSetup::from_snapped`] gave a triangle, from the two fields the
    /// others follow from (its snapped vertices and winding): for records that keep only
    /// those. The area and box are recomputed exactly as there, so the result is equal.
    #[inline(always)]
    #[must_use]
    pub(crate) fn from_kept(xy: [[i32; 2]; 3], clockwise: bool) -> Self {
        let wide = widen(xy);
        let bounds = sample_bounds(extent(wide), [0, 0]);
        Self { xy, area2: twice_signed_area(wide).abs(), clockwise, bounds }
    }

    /// The edge functions, inside positive whatever the input winding, fill rule applied.
    #[inline(always)]
    #[must_use]
    pub fn edges(&self) -> [EdgeFunction; 3] {
        let [p0, p1, p2] = widen(self.xy);
        let sign = if self.clockwise { 1 } else { -1 };
        let edge = |a: [i64; 2], b: [i64; 2]| {
            let ea = sign * (a[1] - b[1]);
            let eb = sign * (b[0] - a[0]);
            let c = -(ea * a[0] + eb * a[1]);
            EdgeFunction { a: ea, b: eb, c: c + FillRule::bias(ea, eb) }
        };
        [edge(p1, p2), edge(p2, p0), edge(p0, p1)]
    }

    /// Where the narrow paths start, at fixed-point `(x, y)`: the three edges' values there,
    /// their steps one pixel right and down, and edges 1 and 2's fill-rule biases (an edge's
    /// value less its bias is a barycentric numerator). The values [`EdgeFunction::values`]
    /// and [`EdgeFunction::pixel_steps`] of [`TriangleSetup::edges`] give, computed from the
    /// vertices directly: `a (x - x_v) + b (y - y_v) + bias` for an edge leaving vertex `v`
    /// forms no constant term and each bias once (the grid of two-pixel triangles, one
    /// thread: 1% fewer instructions, 1-3% faster).
    #[inline(always)]
    #[must_use]
    pub fn edges_at(&self, x: i64, y: i64) -> ([i64; 3], [i64; 3], [i64; 3], [i64; 2]) {
        // In `i32` up to the products (coordinates within 2^23, their differences within
        // 2^24): in `i64` throughout, the grid took 2% more instructions.
        let p = self.xy;
        let sign = if self.clockwise { 1 } else { -1 };
        let (mut values, mut step_x, mut step_y, mut bias) = ([0; 3], [0; 3], [0; 3], [0; 3]);
        for k in 0..3 {
            let (a, b) = (p[(k + 1) % 3], p[(k + 2) % 3]);
            let (ea, eb) = (sign * (a[1] - b[1]), sign * (b[0] - a[0]));
            bias[k] = FillRule::bias(i64::from(ea), i64::from(eb));
            let (ea, eb) = (i64::from(ea), i64::from(eb));
            values[k] = ea * (x - i64::from(a[0])) + eb * (y - i64::from(a[1])) + bias[k];
            (step_x[k], step_y[k]) = (ea * PIXEL_STEP, eb * PIXEL_STEP);
        }
        (values, step_x, step_y, [bias[1], bias[2]])
    }

    /// The checks of [`TriangleSetup::from_snapped`], on their own: twice the signed area
    /// (`> 0`: clockwise on a y-down screen), or why the triangle is rejected (a coordinate
    /// outside `+-2^23`, zero area, culled). Lets a front end drop triangles before paying
    /// for a full setup.
    pub fn signed_area2(xy: [[i64; 2]; 3], cull: CullMode) -> Result<i64, Rejection> {
        // Outside it the products below overflow (a caller's coordinates not snapped).
        let range = -(1 << 23)..=1 << 23;
        if !xy.iter().flatten().all(|v| range.contains(v)) {
            return Err(Rejection::OutOfRange);
        }
        let signed = twice_signed_area(xy);
        if signed == 0 {
            return Err(Rejection::Degenerate);
        }
        match cull {
            CullMode::Clockwise if signed > 0 => Err(Rejection::Culled),
            CullMode::CounterClockwise if signed < 0 => Err(Rejection::Culled),
            _ => Ok(signed),
        }
    }

    /// Pixels whose sample at fixed-point `offset` from the centre may be covered (the
    /// bounding box, for that sample position).
    #[must_use]
    pub fn sample_bounds(&self, offset: [i64; 2]) -> PixelRect {
        sample_bounds(self.extent(), offset)
    }

    /// The snapped bounding box in fixed point: `[[x_min, y_min], [x_max, y_max]]`.
    #[must_use]
    #[inline]
    pub fn extent(&self) -> [[i64; 2]; 2] {
        extent(widen(self.xy))
    }

    /// Does the triangle cover the centre of pixel `(px, py)`? The definition every
    /// rasterizer must agree with.
    #[inline]
    #[must_use]
    pub fn covers(&self, px: i32, py: i32) -> bool {
        self.covers_point(fixed::pixel_centre(px), fixed::pixel_centre(py))
    }

    /// Does the triangle cover the fixed-point sample `(x, y)`?
    #[inline]
    #[must_use]
    pub fn covers_point(&self, x: i64, y: i64) -> bool {
        let [e0, e1, e2] = self.edges();
        (e0.eval(x, y) | e1.eval(x, y) | e2.eval(x, y)) >= 0
    }

    /// The three biased edge values at fixed-point `(x, y)` (covered iff all are `>= 0`).
    #[inline(always)]
    #[must_use]
    pub fn edge_values(&self, x: i64, y: i64) -> [i64; 3] {
        EdgeFunction::values(&self.edges(), x, y)
    }

    /// What the three edge values change by from one pixel to the next: `(right, down)`.
    #[inline(always)]
    #[must_use]
    pub fn pixel_steps(&self) -> ([i64; 3], [i64; 3]) {
        EdgeFunction::pixel_steps(&self.edges())
    }

    /// Unbiased edge values `(E_1, E_2)` at fixed-point `(x, y)`, computed relative to vertex 0
    /// (which lies on both edges) so that they are exact integers below 2^49: `E_i / area2`
    /// is the barycentric weight of vertex `i`. For points within the fixed-point range
    /// (`+-2^23`, where every pixel of a target lies), as the products must stay in `i64`.
    #[inline]
    #[must_use]
    pub fn barycentric_numerators(&self, x: i64, y: i64) -> (i64, i64) {
        self.numerators().at(x, y)
    }

    /// What the barycentric numerators change by from a point to the point `offset`
    /// (fixed point) away: exact, the edge functions being linear (a sample's numerators are
    /// its pixel centre's plus its offset's).
    #[inline]
    #[must_use]
    pub fn numerator_offset(&self, offset: [i64; 2]) -> [i64; 2] {
        self.numerators().offset(offset)
    }

    /// The barycentric numerators as a function of the sample position, derived once: for
    /// loops over many samples, since the setup derives its edges on every call.
    #[inline(always)]
    #[must_use]
    pub fn numerators(&self) -> BarycentricNumerators {
        self.numerators_of(&self.edges())
    }

    /// [`TriangleSetup::numerators`] from the triangle's edges, already derived.
    #[inline(always)]
    #[must_use]
    pub fn numerators_of(&self, edges: &[EdgeFunction; 3]) -> BarycentricNumerators {
        let [_, e1, e2] = edges;
        BarycentricNumerators {
            origin: [i64::from(self.xy[0][0]), i64::from(self.xy[0][1])],
            e1: [e1.a, e1.b],
            e2: [e2.a, e2.b],
        }
    }
}

/// A triangle's barycentric numerators `(E_1, E_2)`: the coefficients of edges 1 and 2 and
/// vertex 0, which lies on both ([`TriangleSetup::numerators`]).
#[derive(Clone, Copy, Debug)]
pub struct BarycentricNumerators {
    origin: [i64; 2],
    e1: [i64; 2],
    e2: [i64; 2],
}

impl BarycentricNumerators {
    /// The numerators at fixed-point `(x, y)` ([`TriangleSetup::barycentric_numerators`]).
    #[inline(always)]
    #[must_use]
    pub fn at(&self, x: i64, y: i64) -> (i64, i64) {
        let (dx, dy) = (x - self.origin[0], y - self.origin[1]);
        (self.e1[0] * dx + self.e1[1] * dy, self.e2[0] * dx + self.e2[1] * dy)
    }

    /// What they change by over `offset` ([`TriangleSetup::numerator_offset`]).
    #[inline(always)]
    #[must_use]
    pub fn offset(&self, [ox, oy]: [i64; 2]) -> [i64; 2] {
        [self.e1[0] * ox + self.e1[1] * oy, self.e2[0] * ox + self.e2[1] * oy]
    }
}

/// Three points' coordinates as `i64`. Written out rather than with `array::map`, which the
/// compiler left out of line in the hot loops that call this: each call stored the result
/// with narrow stores that the wide loads reading it back then waited on (store forwarding
/// fails). The same holds for the other small arrays the per-triangle paths build.
#[inline]
#[must_use]
pub fn widen(xy: [[i32; 2]; 3]) -> [[i64; 2]; 3] {
    let wide = |[x, y]: [i32; 2]| [i64::from(x), i64::from(y)];
    [wide(xy[0]), wide(xy[1]), wide(xy[2])]
}

/// Twice the signed area of snapped points (`> 0`: clockwise on a y-down screen), exact.
#[inline(always)]
fn twice_signed_area(xy: [[i64; 2]; 3]) -> i64 {
    let [p0, p1, p2] = xy;
    (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1])
}

/// The bounding box of snapped points: `[[x_min, y_min], [x_max, y_max]]`.
#[inline]
#[must_use]
pub fn extent(xy: [[i64; 2]; 3]) -> [[i64; 2]; 2] {
    let [p0, p1, p2] = xy;
    let min = |k: usize| p0[k].min(p1[k]).min(p2[k]);
    let max = |k: usize| p0[k].max(p1[k]).max(p2[k]);
    [[min(0), min(1)], [max(0), max(1)]]
}

/// Pixels `p` whose sample position `256 p + 128 + offset` lies within `extent` on both axes,
/// `i32::MIN` and `i32::MAX` left out (no target reaches them): empty when those pixels lie
/// wholly beyond `i32`'s range.
#[inline]
#[must_use]
pub fn sample_bounds(extent: [[i64; 2]; 2], offset: [i64; 2]) -> PixelRect {
    let [[x0, y0], [x1, y1]] = extent;
    let [ox, oy] = offset;
    // Saturated, and clamped within `i32`: an offset of `i64::MAX` had overflowed (a debug
    // panic, a wrapped box in release). Real offsets are under a pixel. A first pixel past
    // `i32::MAX` becomes `i32::MAX` with the last at most `i32::MAX - 1`, an empty box, and
    // likewise below.
    let first = |v: i64| v.clamp(i64::from(i32::MIN) + 1, i32::MAX.into()) as i32;
    let last = |v: i64| v.clamp(i32::MIN.into(), i64::from(i32::MAX) - 1) as i32;
    PixelRect {
        x0: first(fixed::first_centre_at_or_after(x0.saturating_sub(ox))),
        y0: first(fixed::first_centre_at_or_after(y0.saturating_sub(oy))),
        x1: last(fixed::last_centre_at_or_before(x1.saturating_sub(ox))),
        y1: last(fixed::last_centre_at_or_before(y1.saturating_sub(oy))),
    }
}

/// Whether no sample position of `samples` lies in the snapped box `extent` at a pixel of
/// `clip`: then a triangle with that box covers no sample (each sample's pixels are those
/// of [`sample_bounds`] at its offset). At 1x, "no pixel centre of `clip` in the box".
#[must_use]
pub fn holds_no_sample(extent: [[i64; 2]; 2], samples: SampleCount, clip: &PixelRect) -> bool {
    (0..samples.count()).all(|s| sample_bounds(extent, samples.offset(s)).intersect(clip).is_none())
}

/// Fixed-point units per pixel, as `i64`, for stepping edge functions by whole pixels.
pub const PIXEL_STEP: i64 = ONE as i64;

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [[f32; 2]; 3]) -> [Vertex; 3] {
        p.map(|[x, y]| Vertex::new(x, y, 0.5, [255; 4]))
    }

    /// A target's rectangle ends at its last pixel, is empty for a side of zero, and stays
    /// within `i32` for sides past it.
    #[test]
    fn target_rectangles() {
        let r = PixelRect::of_target(1920, 1080);
        assert_eq!((r.x0, r.y0, r.x1, r.y1), (0, 0, 1919, 1079));
        assert!(PixelRect::of_target(0, 5).intersect(&r).is_none());
        let huge = PixelRect::of_target(u32::MAX, 1 << 31);
        assert_eq!((huge.x1, huge.y1), (i32::MAX - 1, i32::MAX - 1));
        assert_eq!(huge.intersect(&r), Some(r));
    }

    /// `edges_at` gives what the edge functions give: their values at a point, their pixel
    /// steps and edges 1 and 2's biases, for random triangles of both windings (up to the
    /// guard band's `2^23` fixed-point units), axis-aligned edges among them (where the
    /// fill rule's ties lie), and points anywhere within reach.
    #[test]
    fn edges_at_is_the_edge_functions() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = |range: i32| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % (2 * range as u64 + 1)) as i32 - range
        };
        let mut checked = 0;
        for round in 0..50_000 {
            let range = [64, 4096, 1 << 16, 1 << 23][round % 4];
            let mut xy: [[i32; 2]; 3] = std::array::from_fn(|_| [next(range), next(range)]);
            if round % 3 == 0 {
                // An axis-aligned edge.
                let k = (round / 3) % 2;
                xy[1][k] = xy[0][k];
            }
            let Ok(setup) = TriangleSetup::from_snapped(widen(xy), CullMode::None) else {
                continue;
            };
            let (x, y) = (i64::from(next(range)), i64::from(next(range)));
            let edges = setup.edges();
            let (step_x, step_y) = EdgeFunction::pixel_steps(&edges);
            let bias = [1, 2].map(|k| FillRule::bias(edges[k].a, edges[k].b));
            let want = (EdgeFunction::values(&edges, x, y), step_x, step_y, bias);
            assert_eq!(setup.edges_at(x, y), want, "{xy:?} at ({x}, {y})");
            checked += 1;
        }
        assert!(checked > 45_000, "{checked} triangles set up");
    }

    #[test]
    fn both_windings_cover_the_same_pixels() {
        let cw =
            TriangleSetup::new(&tri([[1.0, 1.0], [9.0, 2.0], [3.0, 8.0]]), CullMode::None).unwrap();
        let ccw =
            TriangleSetup::new(&tri([[1.0, 1.0], [3.0, 8.0], [9.0, 2.0]]), CullMode::None).unwrap();
        assert!(cw.clockwise && !ccw.clockwise);
        for y in 0..10 {
            for x in 0..10 {
                assert_eq!(cw.covers(x, y), ccw.covers(x, y), "pixel {x},{y}");
            }
        }
    }

    #[test]
    fn culling_and_degenerate() {
        let cw = tri([[1.0, 1.0], [9.0, 2.0], [3.0, 8.0]]);
        assert_eq!(TriangleSetup::new(&cw, CullMode::Clockwise).err(), Some(Rejection::Culled));
        assert!(TriangleSetup::new(&cw, CullMode::CounterClockwise).is_ok());
        let line = tri([[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]]);
        assert_eq!(TriangleSetup::new(&line, CullMode::None).err(), Some(Rejection::Degenerate));
        let mut nan = cw;
        nan[1].z = f32::NAN;
        assert_eq!(TriangleSetup::new(&nan, CullMode::None).err(), Some(Rejection::NonFinite));
        let far = tri([[0.0, 0.0], [40000.0, 0.0], [0.0, 10.0]]);
        assert_eq!(TriangleSetup::new(&far, CullMode::None).err(), Some(Rejection::OutOfRange));
        // Snapped coordinates given directly: outside +-2^23 the area's products overflowed.
        let edge = 1 << 23;
        let within = [[-edge, -edge], [edge, -edge], [-edge, edge]];
        assert!(TriangleSetup::from_snapped(within, CullMode::None).is_ok());
        for far in [[[1 << 40, 0], [0, 1 << 40], [0, 0]], [[0, 0], [edge + 1, 0], [0, 1]]] {
            let refused = TriangleSetup::from_snapped(far, CullMode::None);
            assert_eq!(refused.err(), Some(Rejection::OutOfRange), "{far:?}");
        }
    }

    #[test]
    fn edge_value_at_opposite_vertex_is_twice_the_area() {
        let s = TriangleSetup::new(&tri([[1.5, 1.0], [9.25, 2.0], [3.0, 8.75]]), CullMode::None)
            .unwrap();
        for i in 0..3 {
            let [x, y] = s.xy[i].map(i64::from);
            let e = s.edges()[i];
            let unbiased = e.eval(x, y) - FillRule::bias(e.a, e.b);
            assert_eq!(unbiased, s.area2);
        }
        let [x1, y1] = s.xy[1].map(i64::from);
        assert_eq!(s.barycentric_numerators(x1, y1), (s.area2, 0));
        let [x2, y2] = s.xy[2].map(i64::from);
        assert_eq!(s.barycentric_numerators(x2, y2), (0, s.area2));
    }

    /// `holds_no_sample` against every sample of every pixel of the clip: small boxes on and
    /// beside sample positions, at 1x, 4x and 8x.
    #[test]
    fn holds_no_sample_matches_the_samples_in_the_box() {
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let mut rng = SmallRng::seed_from_u64(33);
        let clip = PixelRect { x0: 2, y0: 1, x1: 6, y1: 5 };
        for round in 0..20_000 {
            let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][round % 3];
            // On, or one unit beside, sample positions of pixels around the clip.
            let mut corner = || {
                256 * rng.random_range(0..9)
                    + 128
                    + 16 * rng.random_range(-8..8)
                    + rng.random_range(-1..2)
            };
            let (x0, y0) = (corner(), corner());
            let extent = [[x0, y0], [x0 + rng.random_range(0..300), y0 + rng.random_range(0..300)]];
            let inside = |x: i64, y: i64| {
                (extent[0][0]..=extent[1][0]).contains(&x)
                    && (extent[0][1]..=extent[1][1]).contains(&y)
            };
            let any = (clip.y0..=clip.y1).any(|py| {
                (clip.x0..=clip.x1).any(|px| {
                    (0..samples.count()).any(|s| {
                        let [ox, oy] = samples.offset(s);
                        inside(256 * i64::from(px) + 128 + ox, 256 * i64::from(py) + 128 + oy)
                    })
                })
            });
            assert_eq!(holds_no_sample(extent, samples, &clip), !any, "{extent:?} {samples:?}");
        }
    }

    /// A setup rebuilt from its vertices and winding is the setup: random snapped triangles
    /// of both windings, small and large, anywhere in the fixed-point range.
    #[test]
    fn setups_rebuilt_from_what_records_keep_are_equal() {
        use rand::rngs::SmallRng;
        use rand::{Rng, SeedableRng};
        let mut rng = SmallRng::seed_from_u64(34);
        let limit = 1i64 << 23;
        for round in 0..20_000 {
            let spread = [1 << 10, 1 << 16, limit][round % 3];
            let (cx, cy) = (rng.random_range(-limit..limit), rng.random_range(-limit..limit));
            let mut point = || {
                let d = |c: i64, rng: &mut SmallRng| {
                    (c + rng.random_range(-spread..=spread)).clamp(-limit, limit)
                };
                [d(cx, &mut rng), d(cy, &mut rng)]
            };
            let xy = [point(), point(), point()];
            let Ok(setup) = TriangleSetup::from_snapped(xy, CullMode::None) else { continue };
            let kept = TriangleSetup::from_kept(setup.xy, setup.clockwise);
            assert_eq!(format!("{kept:?}"), format!("{setup:?}"), "round {round}");
        }
    }
}
