//! Multisample patterns: where inside a pixel coverage and depth are sampled.
//!
//! Positions are the D3D standard patterns, in 1/16 pixel from the pixel centre, y down. One
//! sixteenth of a pixel is 16 units of the 1/256 fixed-point grid, so every sample position is
//! on the grid and samples go through exactly the same integer edge functions and top-left
//! rule as pixel centres: a mesh that tiles a region covers every sample in it exactly once.

/// Samples per pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SampleCount {
    /// One sample, at the pixel centre (no anti-aliasing).
    #[default]
    X1,
    /// Four samples, the D3D standard rotated grid.
    X4,
    /// Eight samples, the D3D standard pattern.
    X8,
}

/// The most samples a pixel has (8x): the size of per-sample arrays.
pub const MAX_SAMPLES: usize = PATTERN_8X.len();

/// Sample offsets in 1/16 pixel: 1x.
pub const PATTERN_1X: [[i32; 2]; 1] = [[0, 0]];
/// Sample offsets in 1/16 pixel: D3D standard 4x.
pub const PATTERN_4X: [[i32; 2]; 4] = [[-2, -6], [6, -2], [-6, 2], [2, 6]];
/// Sample offsets in 1/16 pixel: D3D standard 8x.
pub const PATTERN_8X: [[i32; 2]; 8] =
    [[1, -3], [-1, 3], [5, 1], [-3, -5], [-5, 5], [-7, -1], [3, 7], [7, -7]];

impl SampleCount {
    /// From a count of 1, 4 or 8.
    #[must_use]
    pub fn from_count(n: u32) -> Option<Self> {
        match n {
            1 => Some(Self::X1),
            4 => Some(Self::X4),
            8 => Some(Self::X8),
            _ => None,
        }
    }

    /// Number of samples.
    #[must_use]
    pub fn count(self) -> usize {
        self.pattern().len()
    }

    /// Offsets in 1/16 pixel from the pixel centre, y down.
    #[must_use]
    pub fn pattern(self) -> &'static [[i32; 2]] {
        match self {
            Self::X1 => &PATTERN_1X,
            Self::X4 => &PATTERN_4X,
            Self::X8 => &PATTERN_8X,
        }
    }

    /// Offset of sample `s` in fixed-point (1/256 pixel) units.
    ///
    /// # Panics
    /// If `s` is not below [`Self::count`].
    #[must_use]
    pub fn offset(self, s: usize) -> [i64; 2] {
        self.pattern()[s].map(|v| i64::from(v) * 16)
    }

    /// How far (fixed point, on either axis) the samples lie from the pixel centre at most:
    /// 0 at 1x, 96 at 4x, 112 at 8x.
    #[must_use]
    pub fn reach(self) -> i64 {
        (0..self.count()).flat_map(|s| self.offset(s)).map(i64::abs).max().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every sample lies within `reach` of the centre on both axes, and some sample reaches it.
    #[test]
    fn reach_bounds_every_sample() {
        for (samples, reach) in
            [(SampleCount::X1, 0), (SampleCount::X4, 96), (SampleCount::X8, 112)]
        {
            assert_eq!(samples.reach(), reach);
            for s in 0..samples.count() {
                assert!(samples.offset(s).iter().all(|v| v.abs() <= reach));
            }
        }
    }

    /// The patterns are centred: their offsets sum to zero, so a pixel centre is the mean of
    /// its samples, inside a triangle that covers them all (the sample span kernel evaluates
    /// colour there without clamping).
    #[test]
    fn patterns_are_centred() {
        for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
            let sum = (0..samples.count())
                .map(|s| samples.offset(s))
                .fold([0, 0], |a, o| [a[0] + o[0], a[1] + o[1]]);
            assert_eq!(sum, [0, 0], "{samples:?}");
        }
    }
}
