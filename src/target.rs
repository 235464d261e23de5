//! Render targets: the buffers the shade stage writes, laid out row-major, row 0 at the top.
//!
//! Per-sample buffers (colour, depth, ids) hold `samples` consecutive values per pixel: element
//! `pixel * samples + s`, i.e. an array of shape (height, width, samples). Per-pixel buffers
//! (overdraw, normals) hold one.

use crate::color::{linear_to_srgb8, srgb_to_linear};
use crate::error::Error;
use crate::fixed::MAX_TARGET_SIZE;
use crate::sample::SampleCount;
use crate::setup::PixelRect;

/// Colour, depth and the optional id, overdraw and normal buffers of one image.
#[derive(Clone, Debug)]
pub struct Target {
    width: u32,
    height: u32,
    samples: SampleCount,
    /// RGBA8 colour per sample (sRGB-encoded where the pipeline is colour-managed).
    pub color: Vec<[u8; 4]>,
    /// Depth per sample, cleared to 1.0.
    pub depth: Vec<f32>,
    /// Per sample, the index of the triangle whose fragment was last written there (passed the
    /// depth test), -1 where none was.
    pub ids: Option<Vec<i32>>,
    /// Covered samples per pixel, counted before the depth test (fragments, at 1x).
    pub overdraw: Option<Vec<u32>>,
    /// Normal of the last written fragment (zero where none), when a pipeline provides one.
    pub normals: Option<Vec<[f32; 3]>>,
}

/// The colour a new target is cleared to: opaque black.
pub const DEFAULT_CLEAR_COLOR: [u8; 4] = [0, 0, 0, 255];

impl Target {
    /// A `width x height` target with colour and depth; both sides must be in
    /// `1..=16384` (the range the fixed-point bound is derived for).
    pub fn new(width: u32, height: u32) -> Result<Self, Error> {
        Self::multisampled(width, height, SampleCount::X1)
    }

    /// A target with `samples` samples per pixel for colour, depth and ids.
    pub fn multisampled(width: u32, height: u32, samples: SampleCount) -> Result<Self, Error> {
        if !(1..=MAX_TARGET_SIZE).contains(&width) || !(1..=MAX_TARGET_SIZE).contains(&height) {
            return Err(Error::TargetSize { width, height });
        }
        let n = width as usize * height as usize * samples.count();
        Ok(Self {
            width,
            height,
            samples,
            color: vec![DEFAULT_CLEAR_COLOR; n],
            depth: vec![1.0; n],
            ids: None,
            overdraw: None,
            normals: None,
        })
    }

    /// Adds a triangle-id buffer, cleared to -1.
    #[must_use]
    pub fn with_ids(mut self) -> Self {
        self.ids = Some(vec![-1; self.pixel_count() * self.samples.count()]);
        self
    }

    /// Adds an overdraw buffer, cleared to 0.
    #[must_use]
    pub fn with_overdraw(mut self) -> Self {
        self.overdraw = Some(vec![0; self.pixel_count()]);
        self
    }

    /// Adds a normal buffer, cleared to zero.
    #[must_use]
    pub fn with_normals(mut self) -> Self {
        self.normals = Some(vec![[0.0; 3]; self.pixel_count()]);
        self
    }

    /// Clears colour to `color`, depth to 1.0, ids to -1, overdraw and normals to 0.
    pub fn clear(&mut self, color: [u8; 4]) {
        self.color.fill(color);
        self.depth.fill(1.0);
        if let Some(ids) = &mut self.ids {
            ids.fill(-1);
        }
        if let Some(o) = &mut self.overdraw {
            o.fill(0);
        }
        if let Some(n) = &mut self.normals {
            n.fill([0.0; 3]);
        }
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// `width * height`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The whole target as a pixel rectangle.
    #[must_use]
    pub fn rect(&self) -> PixelRect {
        PixelRect::of_target(self.width, self.height)
    }

    /// Samples per pixel.
    #[must_use]
    pub fn samples(&self) -> SampleCount {
        self.samples
    }

    /// The colour image: at 1x the colour buffer itself; with multisampling, each pixel's
    /// samples averaged in linear light (colour decoded from sRGB, averaged, encoded again;
    /// alpha averaged as is).
    #[must_use]
    pub fn resolve(&self) -> Vec<[u8; 4]> {
        let n = self.samples.count();
        if n == 1 {
            return self.color.clone();
        }
        self.color
            .chunks_exact(n)
            .map(|px| {
                let mut sum = [0.0f32; 4];
                for c in px {
                    for k in 0..3 {
                        sum[k] += srgb_to_linear(c[k]);
                    }
                    sum[3] += f32::from(c[3]);
                }
                let k = n as f32;
                [
                    linear_to_srgb8(sum[0] / k),
                    linear_to_srgb8(sum[1] / k),
                    linear_to_srgb8(sum[2] / k),
                    (sum[3] / k).round() as u8,
                ]
            })
            .collect()
    }

    /// Sample `s` of every pixel of a per-sample buffer, as a per-pixel image.
    ///
    /// # Panics
    /// If `s` is not below the sample count or `buffer` is not a per-sample buffer.
    #[must_use]
    pub fn sample_plane<T: Copy>(&self, buffer: &[T], s: usize) -> Vec<T> {
        let n = self.samples.count();
        assert!(s < n && buffer.len() == self.pixel_count() * n, "not a per-sample buffer");
        buffer.iter().skip(s).step_by(n).copied().collect()
    }

    /// Index of pixel `(x, y)` in per-pixel buffers (and in per-sample ones at 1x).
    #[inline]
    #[must_use]
    pub fn index(&self, x: i32, y: i32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}
