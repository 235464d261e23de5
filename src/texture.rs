//! Textures: images decoded to linear RGBA, sampled with nearest or bilinear filtering.
//!
//! Texture coordinates follow OBJ: `u` to the right, `v` up, so `v = 1` is the image's top
//! row. Texel `(i, j)` (row `j` from the top) has its centre at
//! `u = (i + 0.5) / W`, `v = 1 - (j + 0.5) / H`; sampling there returns that texel.

use std::path::Path;

use glam::{Vec2, Vec4};

use crate::color::srgb_to_linear;
use crate::error::Error;

/// How texels are combined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// The texel containing the sample point.
    Nearest,
    /// Weighted average of the four nearest texel centres.
    #[default]
    Bilinear,
}

/// What happens outside [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The texture tiles.
    #[default]
    Repeat,
    /// Edge texels extend outwards.
    Clamp,
}

/// An RGBA texture in linear light.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Vec<Vec4>,
}

impl Texture {
    /// Reads a PNG or JPEG file (sRGB-encoded).
    pub fn load(path: &Path) -> Result<Self, Error> {
        let img = image::open(path)
            .map_err(|e| Error::Decode { path: path.to_path_buf(), message: e.to_string() })?;
        let rgba = img.to_rgba8();
        Ok(Self::from_srgba8(rgba.width(), rgba.height(), rgba.as_raw()))
    }

    /// A texture from sRGB-encoded RGBA8 texels, rows from the top.
    ///
    /// # Panics
    /// If `data.len() != 4 * width * height` or a side is 0.
    #[must_use]
    pub fn from_srgba8(width: u32, height: u32, data: &[u8]) -> Self {
        assert!(width > 0 && height > 0, "empty texture");
        assert_eq!(data.len(), 4 * width as usize * height as usize, "texel data size");
        let texels = data
            .chunks_exact(4)
            .map(|c| {
                Vec4::new(
                    srgb_to_linear(c[0]),
                    srgb_to_linear(c[1]),
                    srgb_to_linear(c[2]),
                    f32::from(c[3]) / 255.0,
                )
            })
            .collect();
        Self { width, height, texels }
    }

    /// Width in texels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in texels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Texel at column `i`, row `j` (from the top), with `wrap` applied to out-of-range indices.
    #[must_use]
    pub fn texel(&self, i: i64, j: i64, wrap: Wrap) -> Vec4 {
        let fix = |k: i64, n: u32| match wrap {
            Wrap::Repeat => k.rem_euclid(i64::from(n)) as usize,
            Wrap::Clamp => k.clamp(0, i64::from(n) - 1) as usize,
        };
        self.texels[fix(j, self.height) * self.width as usize + fix(i, self.width)]
    }

    /// Samples at `uv`. Non-finite coordinates sample texel (0, 0).
    #[must_use]
    pub fn sample(&self, uv: Vec2, filter: Filter, wrap: Wrap) -> Vec4 {
        let uv = if uv.is_finite() { uv } else { Vec2::ZERO };
        // Texel space: x right, y down from the top row; texel centres at integers + 0.5.
        let x = f64::from(uv.x) * f64::from(self.width);
        let y = (1.0 - f64::from(uv.y)) * f64::from(self.height);
        // Far outside [0, 1], repeat makes only the fraction matter; clamp only the edge.
        let (x, y) = (x.clamp(-1e9, 1e9), y.clamp(-1e9, 1e9));
        match filter {
            Filter::Nearest => self.texel(x.floor() as i64, y.floor() as i64, wrap),
            Filter::Bilinear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (i, j) = (x.floor(), y.floor());
                let (fx, fy) = ((x - i) as f32, (y - j) as f32);
                let (i, j) = (i as i64, j as i64);
                let top = self.texel(i, j, wrap).lerp(self.texel(i + 1, j, wrap), fx);
                let bottom = self.texel(i, j + 1, wrap).lerp(self.texel(i + 1, j + 1, wrap), fx);
                top.lerp(bottom, fy)
            }
        }
    }
}
