//! Fixed-point window coordinates: the grid every vertex snaps to before any inside test.
//!
//! A window coordinate `x` (pixels, origin at the image's top-left corner, y down) becomes the
//! integer `round_half_even(x * 256)`: 8 sub-pixel bits, as in D3D10+ and Vulkan
//! implementations (llvmpipe, NVIDIA). `x * 256` is exact in `f32` (a power-of-two scale), so the
//! only rounding is the snap itself.
//!
//! # Range and the overflow bound
//! Vertices must lie in [-32768, 32768) pixels (the D3D "16.8" range), so a snapped coordinate
//! `X` satisfies `|X| <= 2^23`. Targets are at most 16384 x 16384 pixels, so a pixel centre
//! `256 * px + 128` lies in `[0, 2^22)`.
//! - Edge coefficients `A = Ya - Yb`, `B = Xb - Xa`: `|A|, |B| <= 2^24`.
//! - `C = -(A * Xa + B * Ya)`: `|C| <= 2 * 2^24 * 2^23 = 2^48`.
//! - `E(P) = A * X + B * Y + C` at a pixel centre: `|E| <= 2 * 2^24 * 2^22 + 2^48 < 2^49`, and
//!   relative to a vertex, `A * (X - Xa) + B * (Y - Ya)` with `|X - Xa| < 2^24`: again `< 2^49`.
//! - Twice the signed area is an edge function at the third vertex: `< 2^49`.
//!
//! So `i64` holds every edge value with 14 bits to spare, and every edge value is an integer of
//! magnitude below 2^53, hence *exact* in `f64` too: interpolation may use edge values in `f64`
//! without ever rounding them. `tests/range.rs` checks triangles at the extremes.

/// Sub-pixel bits of the snapped grid.
pub const SUBPIXEL_BITS: u32 = 8;

/// Fixed-point units per pixel (`1 << SUBPIXEL_BITS`).
pub const ONE: i32 = 1 << SUBPIXEL_BITS;

/// Half a pixel in fixed point: pixel `px` is sampled at `px * ONE + HALF`.
pub const HALF: i32 = ONE / 2;

/// Smallest accepted window coordinate, in pixels (inclusive).
pub const MIN_COORD: f32 = -32768.0;

/// Largest accepted window coordinate, in pixels (exclusive).
pub const MAX_COORD: f32 = 32768.0;

/// Largest accepted target width or height, in pixels.
pub const MAX_TARGET_SIZE: u32 = 16384;

/// Snaps a finite window coordinate in `[MIN_COORD, MAX_COORD)` to the sub-pixel grid.
///
/// Returns `None` when `x` is NaN, infinite or outside the range: such a vertex cannot be
/// represented without overflowing the edge-function bound above. Rounding is half to even,
/// which is what the GPUs we match do.
#[must_use]
pub fn snap(x: f32) -> Option<i32> {
    if !(MIN_COORD..MAX_COORD).contains(&x) {
        return None;
    }
    // In f64 (exact), adding and removing 1.5 * 2^52 rounds half to even without a libm call.
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let scaled = ((f64::from(x) * f64::from(ONE)) + MAGIC) - MAGIC;
    // 32767.999 rounds up to 2^23 = 32768 pixels, just past the range.
    if scaled >= f64::from(MAX_COORD) * f64::from(ONE) {
        return None;
    }
    Some(scaled as i32)
}

/// The largest `f32` below [`MAX_COORD`] is `MAX_COORD - 2^-9`, which scales to
/// `2^23 - 0.5` and rounds (half to even) up to `2^23`, past the range; every value below it
/// snaps inside. So [`snap`] succeeds exactly on `[MIN_COORD, SNAP_LIMIT)`.
pub(crate) const SNAP_LIMIT: f32 = MAX_COORD - 1.0 / 512.0;

/// Whether [`snap`] succeeds on `x`, as two comparisons (no rounding): a whole array of
/// coordinates can be checked at vector speed before any is snapped.
#[inline]
#[must_use]
pub fn snaps(x: f32) -> bool {
    (MIN_COORD..SNAP_LIMIT).contains(&x)
}

/// The fixed-point coordinate of the centre of pixel column (or row) `p`.
#[inline]
#[must_use]
pub fn pixel_centre(p: i32) -> i64 {
    i64::from(p) * i64::from(ONE) + i64::from(HALF)
}

/// The smallest pixel index whose centre is `>= v` (a fixed-point coordinate), for every
/// `v`: with `v = ONE q + r` (`0 <= r < ONE`), the centres `ONE p + HALF` from `q`'s on are
/// at or after `v` when `r <= HALF`, from `q + 1`'s otherwise. (`ceil((v - HALF) / ONE)`
/// overflowed at `i64::MIN`.)
#[inline]
#[must_use]
pub fn first_centre_at_or_after(v: i64) -> i64 {
    let (q, r) = (v.div_euclid(i64::from(ONE)), v.rem_euclid(i64::from(ONE)));
    q + i64::from(r > i64::from(HALF))
}

/// The largest pixel index whose centre is `<= v` (a fixed-point coordinate), for every `v`:
/// `q` (as in [`first_centre_at_or_after`]) when `r >= HALF`, else `q - 1`.
#[inline]
#[must_use]
pub fn last_centre_at_or_before(v: i64) -> i64 {
    let (q, r) = (v.div_euclid(i64::from(ONE)), v.rem_euclid(i64::from(ONE)));
    q - i64::from(r < i64::from(HALF))
}

/// `ceil(n / d)` for `d > 0`, exact for every `n` (`i64::MIN` too, which the negation of
/// `floor(-n / d)` would overflow).
#[inline]
#[must_use]
pub fn ceil_div(n: i64, d: i64) -> i64 {
    debug_assert!(d > 0);
    n.div_euclid(d) + i64::from(n.rem_euclid(d) != 0)
}

/// `floor(n / d)` for `d > 0`.
#[inline]
#[must_use]
pub fn floor_div(n: i64, d: i64) -> i64 {
    debug_assert!(d > 0);
    n.div_euclid(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The divisions are the exact ceiling and floor, computed in `i128`, for operands of
    /// both signs, at the ends of `i64` and on and beside multiples of `d`.
    #[test]
    fn divisions_round_up_and_down_exactly() {
        let ds = [1, 2, 3, 7, 256, 1 << 40, i64::MAX - 1, i64::MAX];
        for d in ds {
            let mut ns = vec![i64::MIN, i64::MIN + 1, -1, 0, 1, i64::MAX - 1, i64::MAX];
            for k in [-5i64, -1, 0, 1, 5] {
                let m = k.saturating_mul(d);
                ns.extend([m.saturating_sub(1), m, m.saturating_add(1)]);
            }
            for n in ns {
                let (wn, wd) = (i128::from(n), i128::from(d));
                let (floor, ceil) = (wn.div_euclid(wd), -(-wn).div_euclid(wd));
                assert_eq!(i128::from(floor_div(n, d)), floor, "floor({n} / {d})");
                assert_eq!(i128::from(ceil_div(n, d)), ceil, "ceil({n} / {d})");
            }
        }
    }

    #[test]
    fn snap_rounds_half_to_even() {
        // 1/512 is half a sub-pixel step: ties go to the even neighbour.
        assert_eq!(snap(1.0 / 512.0), Some(0));
        assert_eq!(snap(3.0 / 512.0), Some(2));
        assert_eq!(snap(-1.0 / 512.0), Some(0));
        assert_eq!(snap(-3.0 / 512.0), Some(-2));
        assert_eq!(snap(0.5), Some(128));
        assert_eq!(snap(10.25), Some(2624));
    }

    #[test]
    fn snap_rejects_out_of_range_and_non_finite() {
        assert_eq!(snap(f32::NAN), None);
        assert_eq!(snap(f32::INFINITY), None);
        assert_eq!(snap(f32::NEG_INFINITY), None);
        assert_eq!(snap(32768.0), None);
        assert_eq!(snap(32767.999), None, "rounds up onto the excluded bound");
        assert_eq!(snap(-32768.0), Some(-(1 << 23)));
        assert_eq!(snap(-32768.01), None);
        // f32 holds 9 fraction bits here: 32767.990234375 * 256 is a tie, rounded to even.
        assert_eq!(snap(32767.99), Some((1 << 23) - 2));
    }

    /// `snaps` is `snap(..).is_some()`: at the ends of the range, their neighbours, ties
    /// and random values (by bit patterns, so every exponent and the non-finite ones).
    #[test]
    fn snaps_predicts_snap() {
        use rand::{Rng, SeedableRng};
        let ends = [MIN_COORD, MAX_COORD, SNAP_LIMIT, 0.0, -0.0, 32767.0 + 255.0 / 256.0];
        let mut values: Vec<f32> = ends
            .iter()
            .flat_map(|&x| [x, x.next_up(), x.next_down(), x.next_up().next_up()])
            .collect();
        let mut rng = rand::rngs::SmallRng::seed_from_u64(5);
        values.extend((0..200_000).map(|_| f32::from_bits(rng.random())));
        values.extend((0..200_000).map(|_| rng.random_range(-33000.0..33000.0f32)));
        for x in values {
            assert_eq!(snaps(x), snap(x).is_some(), "{x:e} ({:#x})", x.to_bits());
        }
    }

    /// The centre searches are exact for every `v`: against `i128` at the ends of `i64`, on
    /// and beside centres and pixel edges, and at random.
    #[test]
    fn centre_searches_are_exact_at_every_coordinate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::SmallRng::seed_from_u64(8);
        let mut vs = vec![i64::MIN, i64::MIN + 1, i64::MIN + 128, i64::MAX, i64::MAX - 127];
        for p in [-3i64, -1, 0, 1, 5, 1 << 40, -(1 << 40)] {
            for d in -2..=2 {
                vs.extend([p * 256 + 128 + d, p * 256 + d]);
            }
        }
        vs.extend((0..100_000).map(|_| rng.random::<i64>()));
        let (one, half) = (i128::from(ONE), i128::from(HALF));
        for v in vs {
            let w = i128::from(v);
            // The smallest p with one p + half >= w, the largest with one p + half <= w.
            let first = -(-(w - half)).div_euclid(one);
            let last = (w - half).div_euclid(one);
            assert_eq!(i128::from(first_centre_at_or_after(v)), first, "first at or after {v}");
            assert_eq!(i128::from(last_centre_at_or_before(v)), last, "last at or before {v}");
        }
    }

    #[test]
    fn centre_ranges() {
        assert_eq!(first_centre_at_or_after(128), 0);
        assert_eq!(first_centre_at_or_after(129), 1);
        assert_eq!(first_centre_at_or_after(127), 0);
        assert_eq!(first_centre_at_or_after(-129), -1);
        assert_eq!(last_centre_at_or_before(128), 0);
        assert_eq!(last_centre_at_or_before(127), -1);
        assert_eq!(last_centre_at_or_before(383), 0);
        assert_eq!(last_centre_at_or_before(384), 1);
    }
}
