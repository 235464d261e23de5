//! Scanline edge walking: the lectures' algorithm, made exact.
//!
//! Vertices are sorted by y and the triangle split at the middle vertex: rows above it lie
//! between the long edge (top to bottom) and the upper short edge, rows below it between the
//! long edge and the lower short edge; a row exactly through the middle vertex is bounded by
//! all three. Leaving out the third edge elsewhere is exact, not an approximation: above the
//! middle vertex the two active half-planes cut out a sub-triangle of the original that meets
//! the lower short edge only at the middle vertex, so there that edge's value is a positive
//! integer and passes its test whatever its fill-rule bias (and symmetrically below).
//!
//! Each active edge bounds the row's pixel index `px` through its biased edge function
//! `a * (256 * px + 128) + (b * Y + c) >= 0`: a lower bound `ceil(..)` when `a > 0` (a left
//! edge), an upper bound `floor(..)` when `a < 0` (a right edge), and all-or-nothing for a
//! horizontal edge. The divisions are exact integer ceil/floor, so the spans are those of the
//! edge-function rasterizer, ties included.

use super::Span;
use crate::fixed::{self, HALF, ONE};
use crate::setup::{EdgeFunction, PixelRect, TriangleSetup};

/// Emits the spans of pixels of `tri` within `clip` whose sample at fixed-point `offset` from
/// the centre is covered, top to bottom.
pub fn rasterize(
    tri: &TriangleSetup,
    clip: &PixelRect,
    offset: [i64; 2],
    mut emit: impl FnMut(Span),
) {
    let Some(r) = tri.sample_bounds(offset).intersect(clip) else {
        return;
    };
    let oy = offset[1];
    let mut order = [0usize, 1, 2];
    order.sort_by_key(|&i| tri.xy[i][1]);
    let [top, mid, bot] = order;
    // The edge joining vertices i and j is the one opposite the third vertex.
    let edge = |i: usize, j: usize| &tri.edges[3 - i - j];
    let long = edge(top, bot);
    let upper = edge(top, mid);
    let lower = edge(mid, bot);
    // Compare sample rows with the middle vertex in "pixel centre" coordinates.
    let y_mid = i64::from(tri.xy[mid][1]) - oy;

    let rows = |first: i64, last: i64| {
        (first.max(i64::from(r.y0)) as i32)..=(last.min(i64::from(r.y1)) as i32)
    };
    let above = fixed::last_centre_at_or_before(y_mid - 1);
    let below = fixed::first_centre_at_or_after(y_mid + 1);
    for y in rows(i64::from(r.y0), above) {
        walk_row(y, &[long, upper], &r, offset, &mut emit);
    }
    if (y_mid - i64::from(HALF)).rem_euclid(i64::from(ONE)) == 0 {
        let y = fixed::last_centre_at_or_before(y_mid);
        for y in rows(y, y) {
            walk_row(y, &[long, upper, lower], &r, offset, &mut emit);
        }
    }
    for y in rows(below, i64::from(r.y1)) {
        walk_row(y, &[long, lower], &r, offset, &mut emit);
    }
}

/// Intersects the row's clip range with the bound each active edge puts on `px`.
fn walk_row(
    y: i32,
    active: &[&EdgeFunction],
    clip: &PixelRect,
    offset: [i64; 2],
    emit: &mut impl FnMut(Span),
) {
    let yc = fixed::pixel_centre(y) + offset[1];
    let (mut lo, mut hi) = (i64::from(clip.x0), i64::from(clip.x1));
    for e in active {
        // Need a * 256 * px >= rhs.
        let rhs = -(e.b * yc + e.c + e.a * (i64::from(HALF) + offset[0]));
        let step = e.a * i64::from(ONE);
        if e.a > 0 {
            lo = lo.max(fixed::ceil_div(rhs, step));
        } else if e.a < 0 {
            hi = hi.min(fixed::floor_div(-rhs, -step));
        } else if rhs > 0 {
            return; // a horizontal edge with the whole row outside it
        }
    }
    if lo <= hi {
        emit(Span { y, x_start: lo as i32, x_end: hi as i32 + 1 });
    }
}
