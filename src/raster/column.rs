//! Column walking: the scanline walk turned on its side, for tall thin triangles.
//!
//! A sliver (the sides of a finely tessellated cylinder, terrain seen at a grazing angle)
//! crosses hundreds of rows but covers a pixel on few of them, and a row walk pays for every
//! row, covered or not: a 40,000-triangle cylinder at 1080p spent half its frame stepping
//! rows that held nothing. Such a triangle has few columns.
//!
//! On the vertical line through the samples of column `px`, each edge's inside
//! `a * X + b * Y + c >= 0` is a half-line in `Y`: a lower bound on the row when `b > 0`, an
//! upper bound when `b < 0`. The three bounds together give the column's covered rows, one
//! run (the triangle is convex). Unlike [`super::scanline`], no split at the middle vertex is
//! needed: a bound that does not bind on a column is simply not the tightest. An edge with
//! `b == 0` (vertical) does not depend on `Y`: it bounds the columns instead, once. The
//! bounds are exact integer ceil/floor divisions, carried from column to column as quotient
//! and remainder (the scanline's exact DDA), so the pixels are exactly those of the
//! edge-function reference, fill rule and ties included.

use super::scanline::EdgeWalker;
use crate::fixed::{self, HALF, ONE};
use crate::setup::{EdgeFunction, PixelRect, TriangleSetup};

/// Covered pixels in rows `y_start..y_end` (half-open) of column `x`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ColumnSpan {
    /// Column.
    pub x: i32,
    /// First covered row.
    pub y_start: i32,
    /// One past the last covered row.
    pub y_end: i32,
}

/// Does a box of pixels have so many more rows than columns that walking its columns beats
/// walking its rows? A column costs about what a row does (a few additions and a branch);
/// short boxes stay with the row masks, tuned for the small triangles of dense meshes.
#[must_use]
pub fn is_tall(r: &PixelRect) -> bool {
    let (columns, rows) = (r.x1 - r.x0 + 1, r.y1 - r.y0 + 1);
    rows >= TALL_ROWS && rows >= 2 * columns
}

/// Fewest rows of a box [`is_tall`] accepts.
const TALL_ROWS: i32 = 16;

/// A bound farther than any row (targets are at most 16384 rows): a walker that never binds.
const UNBOUNDED: EdgeWalker = EdgeWalker::constant(1 << 40);

/// Emits the column spans of pixels of `tri` within `clip` whose sample at fixed-point
/// `offset` from the centre is covered, left to right. Same pixels as
/// [`super::rasterize_sample`], a column at a time.
pub fn rasterize(
    tri: &TriangleSetup,
    clip: &PixelRect,
    offset: [i64; 2],
    mut emit: impl FnMut(ColumnSpan),
) {
    let Some(mut walk) = ColumnWalk::new(tri, clip, offset) else { return };
    for x in walk.columns() {
        let (y_start, y_end) = walk.next_rows();
        if y_start < y_end {
            emit(ColumnSpan { x, y_start, y_end });
        }
    }
}

/// The column walk of one sample of a triangle, stepped a column at a time, so that the
/// walks of a pixel's samples can be stepped side by side (multisampling).
#[derive(Clone, Debug)]
pub struct ColumnWalk {
    /// The first column to walk: the one [`ColumnWalk::next_rows`] gives next, at the start.
    x0: i32,
    /// The last column to walk.
    x1: i32,
    /// The clip's rows.
    rows: (i64, i64),
    /// The lower bounds on the row (negated: `-q` is the bound), from edges with `b > 0`.
    lower: [EdgeWalker; 2],
    /// The upper bounds on the row, from edges with `b < 0`.
    upper: [EdgeWalker; 2],
}

impl ColumnWalk {
    /// The walk over the columns of `clip` that may hold pixels of `tri` whose sample at
    /// fixed-point `offset` is covered; `None` when there are none.
    #[must_use]
    pub fn new(tri: &TriangleSetup, clip: &PixelRect, offset: [i64; 2]) -> Option<Self> {
        let mut r = tri.sample_bounds(offset).intersect(clip)?;
        // A sliver's box is as wide as the sliver's whole run across; a clip that takes a
        // few of its rows (a tile) holds a few of those columns.
        let (first, last) = strip_columns(tri, &r, offset)?;
        (r.x0, r.x1) = (r.x0.max(first), r.x1.min(last));
        if r.x0 > r.x1 {
            return None;
        }
        // Sample `(px, py)` is at `X = 256 px + HALF + ox`, `Y = 256 py + HALF + oy`; it is
        // inside `e` iff `256 * b * py >= rhs(X) = -(a * X + c + b * (HALF + oy))`.
        let one = i64::from(ONE);
        let rhs = |e: &EdgeFunction, x: i64| -(e.a * x + e.c + e.b * (i64::from(HALF) + offset[1]));
        let edges = tri.edges();
        // A vertical edge (`b == 0`) is the box's left or right side, and bounds the columns
        // as the box does but for samples exactly on it: a left one (`a > 0`) owns them (the
        // fill rule), a right one does not, so its column is left out when it holds samples.
        // Column `px` is inside iff `256 * a * (px - x0) >= rhs`, `x0` the box's first column.
        for e in edges.iter().filter(|e| e.b == 0 && e.a < 0) {
            let (x0, x1) = (i64::from(r.x0), i64::from(r.x1));
            let rhs = rhs(e, fixed::pixel_centre(r.x0) + offset[0]);
            r.x1 = (x0 + fixed::floor_div(-rhs, -e.a * one)).clamp(x0 - 1, x1) as i32;
        }
        if r.x0 > r.x1 {
            return None;
        }
        let x_first = fixed::pixel_centre(r.x0) + offset[0];
        let mut lower = [UNBOUNDED; 2];
        let mut upper = [UNBOUNDED; 2];
        let (mut lowers, mut uppers) = (0, 0);
        for e in edges.iter().filter(|e| e.b != 0) {
            // From column to column `-rhs` grows by `256 * a`. Lower bound (`b > 0`):
            // `py >= ceil(rhs / 256 b) = -floor(-rhs / 256 b)`; upper (`b < 0`):
            // `py <= floor(-rhs / -256 b)`.
            let walker = EdgeWalker::floor_of(-rhs(e, x_first), e.b.abs() * one, e.a * one);
            // The edge vectors sum to zero, so the `b`s do too: at most two of each sign.
            if e.b > 0 {
                lower[lowers] = walker;
                lowers += 1;
            } else {
                upper[uppers] = walker;
                uppers += 1;
            }
        }
        Some(Self { x0: r.x0, x1: r.x1, rows: (i64::from(r.y0), i64::from(r.y1)), lower, upper })
    }

    /// The columns the walk visits, first to last; [`ColumnWalk::next_rows`] gives them in
    /// turn.
    #[must_use]
    pub fn columns(&self) -> std::ops::RangeInclusive<i32> {
        self.x0..=self.x1
    }

    /// The covered rows `y_start..y_end` (empty when `y_start >= y_end`) of the next column
    /// of [`ColumnWalk::columns`], then a step to the column after it.
    #[inline]
    pub fn next_rows(&mut self) -> (i32, i32) {
        let (y0, y1) = self.rows;
        // A bound far from the clip (a nearly horizontal edge) may be far outside `i32`:
        // both ends are kept within `y0..=y1 + 1`.
        let lo = y0.max(-self.lower[0].q).max(-self.lower[1].q).min(y1 + 1);
        let hi = y1.min(self.upper[0].q).min(self.upper[1].q);
        self.lower.iter_mut().chain(self.upper.iter_mut()).for_each(EdgeWalker::step);
        (lo as i32, (hi + 1).max(lo) as i32)
    }
}

/// Columns holding every pixel of `tri` in rows `r.y0..=r.y1` whose sample at `offset` is
/// covered, a few more at most; `None` when no point of the triangle lies between those
/// rows' samples. The triangle cut to the strip between the first and last rows' samples is
/// convex, its corners the triangle's own corners within the strip and the crossings of its
/// edges with the strip's two lines: their leftmost and rightmost, computed in `f64` (within
/// a millionth of a pixel of exact) and widened by a pixel each way.
fn strip_columns(tri: &TriangleSetup, r: &PixelRect, offset: [i64; 2]) -> Option<(i32, i32)> {
    let (top, bottom) =
        (fixed::pixel_centre(r.y0) + offset[1], fixed::pixel_centre(r.y1) + offset[1]);
    let [p0, p1, p2] = tri.xy.map(|[x, y]| [f64::from(x), f64::from(y)]);
    let (mut left, mut right) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |x: f64| (left, right) = (left.min(x), right.max(x));
    let (top, bottom) = (top as f64, bottom as f64);
    for (a, b) in [(p0, p1), (p1, p2), (p2, p0)] {
        if (top..=bottom).contains(&a[1]) {
            take(a[0]);
        }
        for line in [top, bottom] {
            if (a[1].min(b[1])..=a[1].max(b[1])).contains(&line) && a[1] != b[1] {
                take(a[0] + (line - a[1]) * (b[0] - a[0]) / (b[1] - a[1]));
            }
        }
    }
    if left > right {
        return None;
    }
    // Column `px` has its sample at `256 px + HALF + ox`.
    let column = |x: f64| (x - (f64::from(HALF) + offset[0] as f64)) / f64::from(ONE);
    Some((column(left).floor() as i32 - 1, column(right).ceil() as i32 + 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::CullMode;
    use crate::raster::{Algorithm, rasterize_sample};
    use crate::setup::Vertex;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};
    use std::collections::BTreeSet;

    /// The pixels of the column walk, as a set, and checks that columns come left to right,
    /// each once, with a nonempty run inside the clip.
    fn column_pixels(
        tri: &TriangleSetup,
        clip: &PixelRect,
        offset: [i64; 2],
    ) -> BTreeSet<[i32; 2]> {
        let mut pixels = BTreeSet::new();
        let mut last = i32::MIN;
        rasterize(tri, clip, offset, |s| {
            assert!(s.x > last && s.x >= clip.x0 && s.x <= clip.x1, "{s:?} after {last}");
            assert!(s.y_start < s.y_end && s.y_start >= clip.y0 && s.y_end <= clip.y1 + 1);
            last = s.x;
            pixels.extend((s.y_start..s.y_end).map(|y| [s.x, y]));
        });
        pixels
    }

    fn reference_pixels(
        tri: &TriangleSetup,
        clip: &PixelRect,
        offset: [i64; 2],
    ) -> BTreeSet<[i32; 2]> {
        let mut pixels = BTreeSet::new();
        rasterize_sample(Algorithm::EdgeFunctions, tri, clip, offset, |s| {
            pixels.extend((s.x_start..s.x_end).map(|x| [x, s.y]));
        });
        pixels
    }

    /// Triangles reaching to the ends of the fixed-point range (the guard band), mostly
    /// slivers, seen through small clips on a 16384-pixel target: the bounds' numerators are
    /// near their largest there, and the column walk still covers the reference's pixels.
    #[test]
    fn columns_of_triangles_across_the_whole_range() {
        let mut rng = SmallRng::seed_from_u64(11);
        let mut checked = 0;
        for round in 0..4000 {
            let mut v: [Vertex; 3] = std::array::from_fn(|_| {
                let (x, y) =
                    (rng.random_range(-32767.0..32767.0), rng.random_range(-32767.0..32767.0));
                Vertex::new(x, y, 0.5, [0; 4])
            });
            if round % 2 == 0 {
                // A sliver: the third vertex within a pixel of the first edge.
                let t = rng.random_range(0.0..1.0);
                v[2].x = v[0].x + t * (v[1].x - v[0].x) + rng.random_range(-1.0..1.0);
                v[2].y = v[0].y + t * (v[1].y - v[0].y) + rng.random_range(-1.0..1.0);
            }
            let Ok(tri) = TriangleSetup::new(&v, CullMode::None) else { continue };
            // A clip the triangle crosses, where it does on the target.
            let Some(on) = tri.bounds.intersect(&PixelRect::of_target(16384, 16384)) else {
                continue;
            };
            let (x0, y0) = (rng.random_range(on.x0..=on.x1), rng.random_range(on.y0..=on.y1));
            let clip = PixelRect { x0, y0, x1: x0 + rng.random_range(0..40), y1: y0 + 60 };
            let offset = [rng.random_range(-127..128), rng.random_range(-127..128)];
            let reference = reference_pixels(&tri, &clip, offset);
            checked += usize::from(!reference.is_empty());
            assert_eq!(
                column_pixels(&tri, &clip, offset),
                reference,
                "{v:?} clip {clip:?} offset {offset:?}"
            );
        }
        assert!(checked > 200, "only {checked} clips held pixels");
    }

    /// A sliver from the top rim of a cylinder's inside seen from above: its top edge, 20/256
    /// of a pixel long, lies just above the first row's samples.
    #[test]
    fn sliver_below_a_short_top_edge() {
        let xy = [[239629, 197440], [238737, 27005], [238717, 27006]];
        let v = xy.map(|[x, y]| Vertex::new(x as f32 / 256.0, y as f32 / 256.0, 0.5, [0; 4]));
        let tri = TriangleSetup::new(&v, CullMode::None).unwrap();
        for clip in [tri.bounds, PixelRect { x0: 932, y0: 105, x1: 935, y1: 127 }] {
            let reference = reference_pixels(&tri, &clip, [0, 0]);
            assert!(!reference.is_empty());
            assert_eq!(column_pixels(&tri, &clip, [0, 0]), reference, "{clip:?}");
        }
    }

    /// Random triangles (slivers, vertical and horizontal edges, vertices on the pixel
    /// grid and off it), clips and sample offsets: the column walk covers exactly the
    /// reference's pixels.
    #[test]
    fn columns_cover_the_reference_pixels() {
        let mut rng = SmallRng::seed_from_u64(7);
        for round in 0..20_000 {
            let snap = |v: f32| if round % 3 == 0 { (v * 2.0).round() / 2.0 } else { v };
            let mut v: [Vertex; 3] = std::array::from_fn(|_| {
                Vertex::new(
                    snap(rng.random_range(-20.0..60.0)),
                    snap(rng.random_range(-20.0..90.0)),
                    0.5,
                    [0; 4],
                )
            });
            match round % 4 {
                // A sliver: the third vertex near the line through the first two.
                1 => {
                    let t = rng.random_range(0.0..1.0);
                    v[2].x = v[0].x + t * (v[1].x - v[0].x) + rng.random_range(-0.6..0.6);
                    v[2].y = v[0].y + t * (v[1].y - v[0].y) + rng.random_range(-0.6..0.6);
                }
                // A vertical edge.
                2 => v[1].x = v[0].x,
                _ => {}
            }
            let Ok(tri) = TriangleSetup::new(&v, CullMode::None) else { continue };
            let clip = match round % 5 {
                0 => PixelRect { x0: -8, y0: -8, x1: 70, y1: 100 },
                _ => {
                    let (x0, y0) = (rng.random_range(-10..50), rng.random_range(-10..80));
                    PixelRect {
                        x0,
                        y0,
                        x1: x0 + rng.random_range(0..30),
                        y1: y0 + rng.random_range(0..30),
                    }
                }
            };
            let offset = match round % 3 {
                0 => [0, 0],
                _ => [rng.random_range(-127..128), rng.random_range(-127..128)],
            };
            assert_eq!(
                column_pixels(&tri, &clip, offset),
                reference_pixels(&tri, &clip, offset),
                "{v:?} clip {clip:?} offset {offset:?}"
            );
        }
    }
}
