//! Coverage: which pixel centres a set-up triangle covers, as horizontal [`Span`]s.
//!
//! Two independent rasterizers produce the same spans for every triangle, and the tests hold
//! them to it:
//! - [`edge`]: edge functions over the bounding box, stepped incrementally (the reference the
//!   fast paths are tested against);
//! - [`scanline`]: the classic edge walker, vertices sorted by y and split at the middle one,
//!   span ends from exact integer ceil/floor rules.
//!
//! A triangle is convex, so its covered centres on one row are contiguous: a span per row
//! describes coverage completely. Spans come out top to bottom, never empty, clipped to the
//! caller's rectangle.

pub mod column;
pub mod edge;
pub mod scanline;

use crate::fixed;
use crate::setup::{EdgeFunction, PixelRect, TriangleSetup};

/// Covered pixels `x_start..x_end` (half-open) on row `y`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Span {
    /// Row.
    pub y: i32,
    /// First covered column.
    pub x_start: i32,
    /// One past the last covered column.
    pub x_end: i32,
}

impl Span {
    /// Number of pixels in the span (always > 0 for spans a rasterizer emits).
    #[must_use]
    pub fn len(&self) -> usize {
        (self.x_end - self.x_start) as usize
    }

    /// True for a span with no pixels (rasterizers never emit one).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.x_end <= self.x_start
    }
}

/// Which coverage algorithm to run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Algorithm {
    /// Edge equations over the bounding box.
    #[default]
    EdgeFunctions,
    /// Scanline edge walking.
    Scanline,
    /// Edge equations over the bounding box as per-row bit masks, without branches inside a
    /// row (the fast path for narrow triangles; as spans, boxes wider than [`edge::NARROW`]
    /// pixels fall back to [`Algorithm::EdgeFunctions`]). The tiled backend's choice for
    /// narrow and for tall boxes: `shade::shade_triangle` walks a tall box by columns
    /// ([`column`](mod@column)) when no SIMD span kernel takes it, and other wide
    /// boxes by scanline.
    EdgeMasks,
}

/// Calls `emit` with every span of `tri` inside `clip` (pixel centres), top to bottom.
pub fn rasterize(
    algorithm: Algorithm,
    tri: &TriangleSetup,
    clip: &PixelRect,
    emit: impl FnMut(Span),
) {
    rasterize_sample(algorithm, tri, clip, [0, 0], emit);
}

/// Like [`rasterize`], for the sample at fixed-point `offset` from each pixel centre: a span
/// holds the pixels whose sample there is covered.
pub fn rasterize_sample(
    algorithm: Algorithm,
    tri: &TriangleSetup,
    clip: &PixelRect,
    offset: [i64; 2],
    emit: impl FnMut(Span),
) {
    match algorithm {
        Algorithm::EdgeFunctions => edge::rasterize(tri, clip, offset, emit),
        Algorithm::Scanline => scanline::rasterize(tri, clip, offset, emit),
        Algorithm::EdgeMasks => edge::rasterize_narrow(tri, clip, offset, emit),
    }
}

/// Does the triangle cover the centre of every pixel of `rect`? True iff it covers the four
/// corner pixels' centres: each edge's inside is a half-plane (its edge function is linear),
/// so their intersection is convex and holds every point between covered corners. The
/// trivial accept of hierarchical rasterizers: a tile inside a large triangle needs no edge
/// arithmetic per row.
#[must_use]
pub fn covers_rect(tri: &TriangleSetup, rect: &PixelRect) -> bool {
    covers_rect_within(tri, rect, 0)
}

/// Does the triangle cover every point within `reach` (fixed point, on either axis) of the
/// pixel centres of `rect`, so every sample of its pixels when `reach` is the sample pattern's
/// ([`crate::sample::SampleCount::reach`])? The covered set is convex, so the four outermost
/// points decide.
#[must_use]
pub fn covers_rect_within(tri: &TriangleSetup, rect: &PixelRect, reach: i64) -> bool {
    rect_corners(rect, reach).iter().all(|&[x, y]| tri.covers_point(x, y))
}

/// The trivial reject of hierarchical rasterizers for one triangle, its edges derived once
/// for the many rectangles it is asked about (binning asks it of every tile a large
/// triangle's box spans).
#[derive(Clone, Copy, Debug)]
pub struct TrivialReject {
    edges: [EdgeFunction; 3],
    reach: i64,
}

impl TrivialReject {
    /// The test for `tri`'s samples within `reach` (fixed point, on either axis) of the pixel
    /// centres: the sample pattern's ([`crate::sample::SampleCount::reach`]).
    #[must_use]
    pub fn new(tri: &TriangleSetup, reach: i64) -> Self {
        Self { edges: tri.edges(), reach }
    }

    /// Does the triangle miss every point within the reach of the pixel centres of `rect`,
    /// so every sample of its pixels? True when one edge is negative at the four corners of
    /// those points' rectangle: its edge function is linear, so it is negative over all of
    /// it. `false` does not promise a covered sample (a rectangle off a corner of the
    /// triangle, outside two edges but wholly outside neither, passes), nor does it for a
    /// rectangle wholly past [`CORNER_LIMIT`], whose corners [`rect_corners`] clamps.
    #[must_use]
    pub fn misses(&self, rect: &PixelRect) -> bool {
        let corners = rect_corners(rect, self.reach);
        self.edges.iter().any(|e| corners.iter().all(|&[x, y]| e.eval(x, y) < 0))
    }
}

/// The four corners (fixed point) of the pixel centres of `rect` pushed out by `reach` on
/// each axis: any point within `reach` of a centre of `rect` lies in their rectangle.
///
/// Coordinates are clamped to [`CORNER_LIMIT`], four times the vertex range, so that edge
/// functions evaluated at the corners cannot overflow (`i32::MIN` pixels had). No triangle
/// reaches past the limit, so a triangle covers the clamped rectangle exactly when it covers
/// the one asked about; a rectangle wholly past it collapses onto the limit, where
/// [`TrivialReject::misses`] may no longer find one edge to reject it by.
#[must_use]
pub fn rect_corners(rect: &PixelRect, reach: i64) -> [[i64; 2]; 4] {
    let limit = |v: i64| v.clamp(-CORNER_LIMIT, CORNER_LIMIT);
    let [x0, y0] = [rect.x0, rect.y0].map(|v| limit(fixed::pixel_centre(v).saturating_sub(reach)));
    let [x1, y1] = [rect.x1, rect.y1].map(|v| limit(fixed::pixel_centre(v).saturating_add(reach)));
    [[x0, y0], [x1, y0], [x0, y1], [x1, y1]]
}

/// The largest magnitude of a corner from [`rect_corners`] (fixed point): four times the
/// vertex range (2^23, [`fixed::MAX_COORD`] pixels), so edge values at it stay below 2^51.
pub const CORNER_LIMIT: i64 = 1 << 25;

/// Collects the spans of one triangle (convenient for tests and tools).
#[must_use]
pub fn spans(algorithm: Algorithm, tri: &TriangleSetup, clip: &PixelRect) -> Vec<Span> {
    let mut out = Vec::new();
    rasterize(algorithm, tri, clip, |s| out.push(s));
    out
}
