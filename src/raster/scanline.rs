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
//! edge-function rasterizer, ties included. Along a run of rows between two sloped edges the
//! bounds are carried as quotient and remainder (`EdgeWalker`, an exact DDA): two divisions
//! per edge for the run instead of two per row (the divisions were half the cost of the rows
//! of large triangles).

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
    let edges = tri.edges();
    let edge = |i: usize, j: usize| &edges[3 - i - j];
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
    walk_rows(rows(i64::from(r.y0), above), [long, upper], &r, offset, &mut emit);
    if (y_mid - i64::from(HALF)).rem_euclid(i64::from(ONE)) == 0 {
        let y = fixed::last_centre_at_or_before(y_mid);
        for y in rows(y, y) {
            walk_row(y, &[long, upper, lower], &r, offset, &mut emit);
        }
    }
    walk_rows(rows(below, i64::from(r.y1)), [long, lower], &r, offset, &mut emit);
}

/// The right-hand side of the inside test on the sample row at fixed-point `yc`: the sample
/// in column `px` is inside `e` iff `a * 256 * px >= inside_rhs`.
#[inline]
fn inside_rhs(e: &EdgeFunction, yc: i64, offset: [i64; 2]) -> i64 {
    -(e.b * yc + e.c + e.a * (i64::from(HALF) + offset[0]))
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
        let rhs = inside_rhs(e, yc, offset);
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

/// One edge's bound on a row's pixel index `px`, stepped from row to row by exact
/// incremental division: the bound is `q` with the remainder `r` carried along (`0 <= r < s`),
/// so a run of rows costs two divisions per edge instead of two per row.
#[derive(Clone, Copy, Debug)]
pub(super) struct EdgeWalker {
    /// `floor(n / s)` on the current row: a right edge's upper bound on `px`, the negated
    /// lower bound of a left edge.
    pub(super) q: i64,
    /// Remainder of the bound's division, `0 <= r < s`.
    r: i64,
    /// Divisor: `|a| * 256`.
    s: i64,
    /// Whole and fractional change of the bound per row (`0 <= dr < s`).
    dq: i64,
    dr: i64,
}

impl EdgeWalker {
    /// The bound `q` on every row (or column).
    pub(super) const fn constant(q: i64) -> Self {
        Self { q, r: 0, s: 1, dq: 0, dr: 0 }
    }

    /// `floor(n / s)` for `s > 0`, stepped by `n += d` per row.
    pub(super) fn floor_of(n: i64, s: i64, d: i64) -> Self {
        let q = fixed::floor_div(n, s);
        let dq = fixed::floor_div(d, s);
        Self { q, r: n - q * s, s, dq, dr: d - dq * s }
    }

    /// Steps to the next row: `n + d = (q + dq) * s + (r + dr)`, carried without a branch.
    #[inline]
    pub(super) fn step(&mut self) {
        self.q += self.dq;
        self.r += self.dr;
        let carry = i64::from(self.r >= self.s);
        self.q += carry;
        self.r -= carry * self.s;
    }
}

/// Emits the spans of a run of rows bounded by two edges (the long edge and a short one):
/// the per-row bounds of [`walk_row`], carried from row to row by [`EdgeWalker`]s.
fn walk_rows(
    rows: std::ops::RangeInclusive<i32>,
    active: [&EdgeFunction; 2],
    clip: &PixelRect,
    offset: [i64; 2],
    emit: &mut impl FnMut(Span),
) {
    if rows.is_empty() {
        return;
    }
    let first = *rows.start();
    // A horizontal edge decides whole rows; runs with one are rare (flat tops and bottoms):
    // row by row.
    if active.iter().any(|e| e.a == 0) {
        for y in rows {
            walk_row(y, &active, clip, offset, emit);
        }
        return;
    }
    let yc = fixed::pixel_centre(first) + offset[1];
    // Per edge: `n = -rhs` and its change per row `d`, where the sample in column `px` is
    // inside iff `a * 256 * px >= rhs` (see `walk_row`). Left edges (`a > 0`):
    // `px >= ceil(rhs / s) = -floor(n / s)`; right edges (`a < 0`): `px <= floor(n / -s)`.
    let mut lo = None;
    let mut hi = None;
    for e in active {
        let rhs = inside_rhs(e, yc, offset);
        let d = e.b * i64::from(ONE);
        let s = e.a * i64::from(ONE);
        if e.a > 0 {
            lo = Some(EdgeWalker::floor_of(-rhs, s, d));
        } else {
            hi = Some(EdgeWalker::floor_of(-rhs, -s, d));
        }
    }
    let (x0, x1) = (i64::from(clip.x0), i64::from(clip.x1));
    match (lo, hi) {
        (Some(mut lo), Some(mut hi)) => {
            for y in rows {
                let (start, end) = (x0.max(-lo.q), x1.min(hi.q));
                if start <= end {
                    emit(Span { y, x_start: start as i32, x_end: end as i32 + 1 });
                }
                lo.step();
                hi.step();
            }
        }
        // Two left or two right edges cannot bound one run of a triangle's rows; should
        // setup ever produce them, the row-by-row bounds are still exact.
        _ => {
            for y in rows {
                walk_row(y, &active, clip, offset, emit);
            }
        }
    }
}
