//! Edge equations over the bounding box: the reference rasterizer.
//!
//! The three biased edge values are evaluated once at the first pixel centre of the clipped
//! box and then stepped: `+a * 256` per pixel to the right, `+b * 256` per row. A pixel is in
//! iff `(e0 | e1 | e2) >= 0`, i.e. no sign bit is set. Each row stops as soon as it leaves the
//! span, since a convex triangle's row coverage is contiguous.

use super::Span;
use crate::fixed;
use crate::setup::{PixelRect, TriangleSetup};

/// The edge values at the first sample of the clipped box and their steps per pixel and row.
struct Stepper {
    r: PixelRect,
    row: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
}

impl Stepper {
    /// `None` when no pixel of the box lies in `clip`.
    fn start(tri: &TriangleSetup, clip: &PixelRect, offset: [i64; 2]) -> Option<Self> {
        let r = tri.sample_bounds(offset).intersect(clip)?;
        let x0 = fixed::pixel_centre(r.x0) + offset[0];
        let y0 = fixed::pixel_centre(r.y0) + offset[1];
        let (step_x, step_y) = tri.pixel_steps();
        Some(Self { r, row: tri.edge_values(x0, y0), step_x, step_y })
    }
}

/// Emits the spans of pixels of `tri` within `clip` whose sample at fixed-point `offset` from
/// the centre is covered, top to bottom.
pub fn rasterize(
    tri: &TriangleSetup,
    clip: &PixelRect,
    offset: [i64; 2],
    mut emit: impl FnMut(Span),
) {
    let Some(Stepper { r, mut row, step_x, step_y }) = Stepper::start(tri, clip, offset) else {
        return;
    };
    for y in r.y0..=r.y1 {
        let mut e = row;
        let mut start = None;
        let mut end = r.x1 + 1;
        for x in r.x0..=r.x1 {
            if (e[0] | e[1] | e[2]) >= 0 {
                start.get_or_insert(x);
            } else if start.is_some() {
                end = x;
                break;
            }
            for k in 0..3 {
                e[k] += step_x[k];
            }
        }
        if let Some(x_start) = start {
            emit(Span { y, x_start, x_end: end });
        }
        for k in 0..3 {
            row[k] += step_y[k];
        }
    }
}

/// Widest box (pixels) [`rasterize_narrow`] handles.
pub const NARROW: i32 = 8;

/// Coverage of [`NARROW`] pixels of a row as bits (bit `x`: the pixel `x` to the right of the
/// one whose biased edge values are `e`), without branches: the sign bit of `e0 | e1 | e2` is
/// set iff a pixel is out. Always inlined: with plain `#[inline]` the grid scene was 16%
/// slower on two threads (unchanged on one).
#[inline(always)]
#[must_use]
pub fn row_coverage(e: [i64; 3], step_x: [i64; 3]) -> u32 {
    row_coverage_of::<{ NARROW as u32 }>(e, step_x)
}

/// [`row_coverage`] of the first `columns` pixels (at most [`NARROW`]; asserted in debug
/// builds only, as this runs in the narrow kernels' row loops), the rest clear. Boxes up to 4
/// pixels wide step 4 pixels, not 8 (a branch per row, the same for every row of a triangle):
/// grid, one thread, 87-89 -> 80-83 ms.
#[inline(always)]
#[must_use]
pub fn row_coverage_within(e: [i64; 3], step_x: [i64; 3], columns: usize) -> u32 {
    debug_assert!(columns <= NARROW as usize, "{columns} columns: at most {NARROW}");
    let mask = if columns <= 4 { row_coverage_of::<4>(e, step_x) } else { row_coverage(e, step_x) };
    mask & ((1 << columns) - 1)
}

/// The 8 x 8 bit matrix `m` transposed: bit `8 i + j` of the result is bit `8 j + i` of `m`.
/// With one sample's row mask ([`row_coverage_within`]) per byte, the result holds one
/// pixel's sample mask per byte: in registers, three rounds of swapping the off-diagonal
/// sub-blocks of every 2 x 2, then 4 x 4, then 8 x 8 block, instead of a gather of bits from
/// an array of masks per pixel.
#[inline(always)]
#[must_use]
pub fn transpose_bits(mut m: u64) -> u64 {
    let t = (m ^ (m >> 7)) & 0x00AA_00AA_00AA_00AA;
    m ^= t ^ (t << 7);
    let t = (m ^ (m >> 14)) & 0x0000_CCCC_0000_CCCC;
    m ^= t ^ (t << 14);
    let t = (m ^ (m >> 28)) & 0x0000_0000_F0F0_F0F0;
    m ^ t ^ (t << 28)
}

/// [`row_coverage`] of the first `N` pixels only (at most 32).
#[inline(always)]
#[must_use]
fn row_coverage_of<const N: u32>(mut e: [i64; 3], step_x: [i64; 3]) -> u32 {
    let mut mask = 0u32;
    for x in 0..N {
        let out = ((e[0] | e[1] | e[2]) >> 63) as u32 & 1;
        mask |= (out ^ 1) << x;
        e = std::array::from_fn(|k| e[k] + step_x[k]);
    }
    mask
}

/// [`rasterize`] for boxes at most [`NARROW`] pixels wide (after clipping), without
/// data-dependent branches inside a row: the row's coverage is gathered as a bit mask over a
/// fixed number of pixels and the span read off its lowest and highest bits (a convex
/// triangle's row coverage is contiguous). Small triangles spend much of their time in
/// mispredicted row-exit branches otherwise. Emits exactly what [`rasterize`] emits; boxes
/// that are too wide go to it.
pub fn rasterize_narrow(
    tri: &TriangleSetup,
    clip: &PixelRect,
    offset: [i64; 2],
    mut emit: impl FnMut(Span),
) {
    let Some(Stepper { r, mut row, step_x, step_y }) = Stepper::start(tri, clip, offset) else {
        return;
    };
    let width = r.x1 - r.x0 + 1;
    if width > NARROW {
        return rasterize(tri, clip, offset, emit);
    }
    // Only the box's own columns count.
    let columns = (1u32 << width) - 1;
    for y in r.y0..=r.y1 {
        let mask = row_coverage(row, step_x) & columns;
        if mask != 0 {
            let first = mask.trailing_zeros() as i32;
            let last = 31 - mask.leading_zeros() as i32;
            emit(Span { y, x_start: r.x0 + first, x_end: r.x0 + last + 1 });
        }
        for k in 0..3 {
            row[k] += step_y[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::transpose_bits;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// Bit `8 i + j` moves to `8 j + i`, for random matrices and every single bit; twice is
    /// the identity.
    #[test]
    fn transpose_bits_swaps_rows_and_columns() {
        let naive = |m: u64| {
            let mut t = 0u64;
            for (i, j) in (0..8).flat_map(|i| (0..8).map(move |j| (i, j))) {
                t |= (m >> (8 * i + j) & 1) << (8 * j + i);
            }
            t
        };
        let mut rng = SmallRng::seed_from_u64(5);
        let singles = (0..64).map(|b| 1u64 << b);
        for m in singles.chain((0..10_000).map(|_| rng.random::<u64>())) {
            assert_eq!(transpose_bits(m), naive(m), "{m:#x}");
            assert_eq!(transpose_bits(transpose_bits(m)), m);
        }
    }
}
