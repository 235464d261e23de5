//! Colour spaces: shading happens in linear light, images store sRGB-encoded 8-bit values.

use std::sync::OnceLock;

/// sRGB-encoded 8-bit value to linear light in [0, 1].
#[inline]
#[must_use]
pub fn srgb_to_linear(c: u8) -> f32 {
    srgb_decode_table()[c as usize]
}

/// [`srgb_to_linear`] of every 8-bit value, for loops that decode many.
#[must_use]
pub fn srgb_decode_table() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_decode(i as f32 / 255.0)))
}

/// The sRGB transfer function's inverse, on [0, 1].
#[must_use]
pub fn srgb_decode(c: f32) -> f32 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// The sRGB transfer function, on [0, 1].
#[must_use]
pub fn srgb_encode(l: f32) -> f32 {
    if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

/// Linear light (clamped to [0, 1]; NaN as 0) to an sRGB-encoded 8-bit value, rounded
/// exactly (as `round(255 * encode(l))` computed in `f64`).
///
/// No root or power per call: linear light is bucketed by its float bits (exponent and top
/// 8 mantissa bits, so buckets are 2^-8 of their value wide), and within one bucket the 8-bit
/// output rises by at most one step (the curve's slope times the bucket width stays below a
/// quarter of a step), so each bucket stores its first value and the bits at which the next
/// begins: a table lookup and one comparison.
#[inline]
#[must_use]
pub fn linear_to_srgb8(l: f32) -> u8 {
    // Below 2^-13 everything encodes to 0, as 2^-13 does; `-0.0` is below.
    let l = if l.is_nan() { FIRST_ENCODED } else { l.clamp(FIRST_ENCODED, 1.0) };
    encode_bits(srgb8_table(), l.to_bits())
}

/// The encoder's table ([`linear_to_srgb8`]), for the SIMD kernels' gathers.
#[inline]
pub(crate) fn srgb8_table() -> &'static [u32; ENCODE_BUCKETS] {
    ENCODE_TABLE.get_or_init(encode_table)
}

/// [`linear_to_srgb8`] of three channels: the same table lookups, after one vector clamp
/// ([`crate::simd::clamped_bits`]) that also puts them at or above 2^-13, where the table
/// starts (everything below encodes to 0, as 2^-13 does), so the bucket needs no floor.
#[inline]
#[must_use]
pub fn linear_to_srgb8_rgb(l: [f32; 3]) -> [u8; 3] {
    let table = srgb8_table();
    let [r, g, b, _] = crate::simd::clamped_bits([l[0], l[1], l[2], 1.0], FIRST_ENCODED);
    [encode_bits(table, r), encode_bits(table, g), encode_bits(table, b)]
}

/// The table lookup, for the bits of a value in [2^-13, 1]: its bucket is within the table
/// (the `min` only spares a bounds check).
#[inline]
fn encode_bits(table: &[u32; ENCODE_BUCKETS], bits: u32) -> u8 {
    let bucket = ((bits >> MANTISSA_SHIFT) as usize).wrapping_sub(FIRST_BUCKET);
    let entry = table[bucket.min(ENCODE_BUCKETS - 1)];
    (entry >> 16) as u8 + u8::from(bits & LOW_MASK >= entry & 0xffff)
}

/// Mantissa bits below the bucket index.
pub(crate) const MANTISSA_SHIFT: u32 = 15;
/// Bits within a bucket.
pub(crate) const LOW_MASK: u32 = (1 << MANTISSA_SHIFT) - 1;
/// Exponents covered: below 2^-13, linear light encodes to 0 (it is under half a step on
/// the curve's linear segment, 0.5 / (255 * 12.92) = 1.5e-4).
const EXPONENTS: usize = 13;
/// The bucket index of 2^-13, the first bucket; callers clamp everything below to 2^-13.
pub(crate) const FIRST_BUCKET: usize = (127 - EXPONENTS) << (23 - MANTISSA_SHIFT);
/// 2^-13, the start of the first bucket; every value below it encodes to 0, as it does.
pub(crate) const FIRST_ENCODED: f32 = 1.0 / (1 << EXPONENTS) as f32;
/// Buckets from 2^-13 up to and including 1.0.
pub(crate) const ENCODE_BUCKETS: usize = (EXPONENTS << (23 - MANTISSA_SHIFT)) + 1;

static ENCODE_TABLE: OnceLock<[u32; ENCODE_BUCKETS]> = OnceLock::new();

/// Per bucket: `value << 16 | threshold`, where the bucket's values encode to `value` below
/// `threshold` (the low bits of the first one that rounds higher) and to `value + 1` from it
/// on; a threshold of `1 << 15` is never reached.
fn encode_table() -> [u32; ENCODE_BUCKETS] {
    let exact = |bits: u32| (srgb_encode_f64(f64::from(f32::from_bits(bits))) * 255.0).round();
    std::array::from_fn(|k| {
        let first = ((k + FIRST_BUCKET) as u32) << MANTISSA_SHIFT;
        let value = if k == 0 { 0.0 } else { exact(first) };
        // Binary search for the first low-bits value rounding above `value` (the curve is
        // increasing); 1 << 15 when none does.
        let (mut lo, mut hi) = (0u32, 1u32 << MANTISSA_SHIFT);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if exact(first | mid) > value { hi = mid } else { lo = mid + 1 }
        }
        (value as u32) << 16 | lo
    })
}

/// [`srgb_encode`] in `f64`, the reference the 8-bit encoder rounds exactly.
fn srgb_encode_f64(l: f64) -> f64 {
    if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 }
}

/// Linear to 8-bit for an alpha channel (no transfer function).
#[inline]
#[must_use]
pub fn unorm8(a: f32) -> u8 {
    let a = if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) };
    (a * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_every_8_bit_value() {
        for c in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb_to_linear(c)), c);
        }
    }

    /// Every `f32` from 2^-13 to 1 (109 million; every 13th in a debug build) encodes to the
    /// exactly rounded value, and so do smaller ones (sampled: all encode to 0), NaN and
    /// values outside [0, 1].
    #[test]
    fn encoder_is_exactly_rounded() {
        let exact = |l: f32| (srgb_encode_f64(f64::from(l)) * 255.0).round() as u8;
        let stride = if cfg!(debug_assertions) { 13 } else { 1 };
        let first = 2f32.powi(-13).to_bits();
        let mut bits = 0;
        while bits <= 1.0f32.to_bits() {
            let l = f32::from_bits(bits);
            assert_eq!(linear_to_srgb8(l), exact(l), "{l:e} ({bits:#x})");
            bits += if bits < first { 9973 } else { stride };
        }
        // The three-channel encoder lane by lane.
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200_000 {
            let mut next = || {
                rng = rng.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                f32::from_bits((rng >> 32) as u32 % 0x4000_0000)
                    * if rng & 1 == 0 { 1.0 } else { -1.0 }
            };
            let l = [next(), next(), next()];
            assert_eq!(linear_to_srgb8_rgb(l), l.map(linear_to_srgb8), "{l:?}");
        }
        let tiny = 2f32.powi(-13);
        for l in [
            f32::NAN,
            -0.0,
            0.0,
            -1.0,
            f32::NEG_INFINITY,
            2.0,
            f32::INFINITY,
            tiny,
            tiny * 0.99,
            1e-40,
        ] {
            assert_eq!(linear_to_srgb8_rgb([l, 0.5, l]), [l, 0.5, l].map(linear_to_srgb8));
            assert_eq!(linear_to_srgb8(l), exact(if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) }));
        }
    }
}
