//! Colour spaces: shading happens in linear light, images store sRGB-encoded 8-bit values.

use std::sync::OnceLock;

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
    // A 4096-entry table is finer than the 8-bit output everywhere except the steep start of
    // the curve, where it is indexed by the square root to spend entries on the dark end.
    const N: usize = 4096;
    static TABLE: OnceLock<Vec<u8>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..N)
            .map(|i| {
                let s = i as f32 / (N - 1) as f32;
                (srgb_encode(s * s) * 255.0).round() as u8
            })
            .collect()
    });
    let l = if l.is_nan() { 0.0 } else { l.clamp(0.0, 1.0) };
    // `x + 0.5` truncated is `round(x)` for x >= 0, without a libm call in the pixel loop.
    table[(l.sqrt() * (N - 1) as f32 + 0.5) as usize]
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
}
