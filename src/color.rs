//! Colour spaces: shading happens in linear light, images store sRGB-encoded 8-bit values.

use std::sync::OnceLock;

use glam::Vec3A;

/// sRGB-encoded 8-bit value to linear light in [0, 1].
#[inline]
#[must_use]
pub fn srgb_to_linear(c: u8) -> f32 {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_decode(i as f32 / 255.0)))[c as usize]
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

/// Linear light (clamped to [0, 1]; NaN as 0) to an sRGB-encoded 8-bit value, rounded.
#[inline]
#[must_use]
pub fn linear_to_srgb8(l: f32) -> u8 {
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    // `x + 0.5` truncated is `round(x)` for x >= 0, without a libm call in the pixel loop.
    encode_table()[(l.sqrt() * (ENCODE_TABLE_LEN - 1) as f32 + 0.5) as usize]
}

/// Entries of the encoding table.
const ENCODE_TABLE_LEN: usize = 4096;

/// The encoding table, indexed by the square root of linear light. 4096 entries are finer
/// than the 8-bit output everywhere except the steep start of the curve, which indexing by the
/// square root spends entries on.
fn encode_table() -> &'static [u8; ENCODE_TABLE_LEN] {
    static TABLE: OnceLock<[u8; ENCODE_TABLE_LEN]> = OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let s = i as f32 / (ENCODE_TABLE_LEN - 1) as f32;
            (srgb_encode(s * s) * 255.0).round() as u8
        })
    })
}

/// [`linear_to_srgb8`] of three channels at once: the same table and the same rounding steps,
/// lane by lane, so the result is identical, but one vector square root instead of three (its
/// latency was most of a splat's shading).
#[inline]
#[must_use]
pub fn linear_to_srgb8_rgb(l: Vec3A) -> [u8; 3] {
    let table = encode_table();
    let l = Vec3A::select(l.is_nan_mask(), Vec3A::ZERO, l).clamp(Vec3A::ZERO, Vec3A::ONE);
    let i = l.sqrt() * (ENCODE_TABLE_LEN - 1) as f32 + 0.5;
    // Indices lie in [0.5, 4095.5], where floor is truncation; the mask only spares the
    // bounds checks.
    let [r, g, b, _] = crate::simd::floor_i32x4([i.x, i.y, i.z, 0.0]);
    let at = |k: i32| table[k as usize & (ENCODE_TABLE_LEN - 1)];
    [at(r), at(g), at(b)]
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

    /// The three-channel encoder is the scalar one lane by lane, on every 8-bit value's
    /// neighbourhood, the clamped ends, NaN and infinities.
    #[test]
    fn three_channel_encoder_matches_the_scalar_one() {
        let mut values = vec![f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1.0, -0.0, 2.0];
        for i in 0..=40_000 {
            values.push(i as f32 / 40_000.0);
        }
        for c in 0..=255u8 {
            let l = srgb_to_linear(c);
            values.extend([l, l.next_up(), l.next_down()]);
        }
        for w in values.windows(3) {
            let got = linear_to_srgb8_rgb(Vec3A::new(w[0], w[1], w[2]));
            assert_eq!(got, [w[0], w[1], w[2]].map(linear_to_srgb8), "{w:?}");
        }
    }
}
