//! Textures: images decoded to linear RGBA, sampled with nearest or bilinear filtering.
//!
//! Texture coordinates follow OBJ: `u` to the right, `v` up, so `v = 1` is the image's top
//! row. Texel `(i, j)` (row `j` from the top) has its centre at
//! `u = (i + 0.5) / W`, `v = 1 - (j + 0.5) / H`; sampling there returns that texel.

use std::io::BufReader;
use std::path::Path;

use glam::{Vec2, Vec4};
use image::ImageDecoder as _;

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

/// The largest texture side, in texels, as in Direct3D 11 and 12; [`MAX_TEXELS`] bounds the
/// area further, so a 16384 x 16384 (or 16384 x 8192) texture is refused while 16384 x 4096
/// loads.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

/// The most texels a texture may have: 2^26 (8192 x 8192), 1 GiB kept as linear `Vec4`
/// texels (so that sampling does no decoding), and up to [`LOAD_BYTES_PER_TEXEL`] times the
/// texels while it loads: 1.8 GiB. An 11000 x 11000 PNG of 494 KB had taken 2.9 GB.
pub const MAX_TEXELS: u64 = 1 << 26;

/// Bytes a texel of [`Texture::load`] takes at its peak, rounded up from what was measured
/// (the largest resident set of `trirast render --texture` of a 4096 x 4096 PNG, less the
/// same render without it): 20.5 for RGBA8, 21.5 for grey, 26.4 for 16-bit RGB and 28.3 for
/// 16-bit RGBA, whose decoded image (8 bytes a texel) and RGBA8 copy (4) come before the 16
/// of the texels kept.
pub const LOAD_BYTES_PER_TEXEL: u64 = 29;

impl Texture {
    /// Reads a PNG or JPEG file (sRGB-encoded). The format is taken from the file's first bytes,
    /// else from its extension.
    ///
    /// # Errors
    /// [`Error::NotRegularFile`] or [`Error::Io`] when the file cannot be opened;
    /// [`Error::TextureSize`] when its header declares more than [`MAX_TEXTURE_SIDE`] a side or
    /// [`MAX_TEXELS`] in all (before any texel is decoded); [`Error::Decode`] when it cannot be
    /// decoded; [`Error::OutOfMemory`] when the allocator refuses its texels.
    pub fn load(path: &Path) -> Result<Self, Error> {
        let decoder = decoder(path)?;
        let img = image::DynamicImage::from_decoder(decoder).map_err(|e| decode_error(path, e))?;
        // `into_rgba8` reuses an RGBA8 image's buffer (`to_rgba8` copied it).
        let rgba = img.into_rgba8();
        let (width, height) = rgba.dimensions();
        // The largest array, by far: asked for fallibly (a 16384 x 4096 texture under a 2 GB
        // address space limit had aborted the process here).
        let mut texels = Vec::new();
        let what = || format!("the texels of {}", path.display());
        crate::error::try_reserve_named(&mut texels, rgba.as_raw().len() / 4, what)?;
        texels.extend(rgba.as_raw().chunks_exact(4).map(linear_texel));
        Ok(Self { width, height, texels })
    }

    /// The most memory [`Texture::load`] takes for the texture in `path`, from its header:
    /// [`LOAD_BYTES_PER_TEXEL`] a texel.
    ///
    /// # Errors
    /// As [`Texture::dimensions`].
    pub fn load_bytes(path: &Path) -> Result<u128, Error> {
        let (width, height) = Self::dimensions(path)?;
        Ok(u128::from(width) * u128::from(height) * u128::from(LOAD_BYTES_PER_TEXEL))
    }

    /// The size of the texture in `path` (width, height), as [`Texture::load`] would find it,
    /// read from the header only.
    ///
    /// # Errors
    /// As [`Texture::load`], except for problems past the header.
    pub fn dimensions(path: &Path) -> Result<(u32, u32), Error> {
        decoder(path).map(|d| d.dimensions())
    }

    /// A texture from sRGB-encoded RGBA8 texels, rows from the top.
    ///
    /// # Panics
    /// If `data.len() != 4 * width * height` or a side is 0.
    #[must_use]
    pub fn from_srgba8(width: u32, height: u32, data: &[u8]) -> Self {
        assert!(width > 0 && height > 0, "empty texture");
        // Checked: a product that wrapped (2^31 x 2^31) had matched empty data.
        let size = (width as usize).checked_mul(height as usize).and_then(|n| n.checked_mul(4));
        assert_eq!(Some(data.len()), size, "texel data size");
        let texels = data.chunks_exact(4).map(linear_texel).collect();
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

/// An sRGB-encoded RGBA8 texel in linear light.
fn linear_texel(c: &[u8]) -> Vec4 {
    Vec4::new(
        srgb_to_linear(c[0]),
        srgb_to_linear(c[1]),
        srgb_to_linear(c[2]),
        f32::from(c[3]) / 255.0,
    )
}

/// A decoder for the image in `path`, its header read and its size within the limits.
fn decoder(path: &Path) -> Result<impl image::ImageDecoder, Error> {
    let mut reader = image::ImageReader::new(BufReader::new(crate::input::open(path)?));
    if let Ok(format) = image::ImageFormat::from_path(path) {
        reader.set_format(format);
    }
    let reader = reader.with_guessed_format().map_err(|e| Error::io(path, e))?;
    let decoder = reader.into_decoder().map_err(|e| match (&e, png_size(path)) {
        // The PNG decoder refuses a header whose rows alone pass its memory limit before it
        // gives the size (2^31 - 1 a side had said only "Memory limit exceeded").
        (image::ImageError::Limits(_), Some((width, height))) => {
            Error::TextureSize { path: path.to_path_buf(), width, height }
        }
        _ => decode_error(path, e),
    })?;
    let (width, height) = decoder.dimensions();
    if width.max(height) > MAX_TEXTURE_SIDE || u64::from(width) * u64::from(height) > MAX_TEXELS {
        return Err(Error::TextureSize { path: path.to_path_buf(), width, height });
    }
    Ok(decoder)
}

/// The width and height a PNG file's header declares (its first chunk, `IHDR`, after the
/// signature), if `path` starts as a PNG file does.
fn png_size(path: &Path) -> Option<(u32, u32)> {
    use std::io::Read as _;
    let mut head = [0; 24];
    crate::input::open(path).ok()?.read_exact(&mut head).ok()?;
    let png = head.starts_with(b"\x89PNG\r\n\x1a\n") && &head[12..16] == b"IHDR";
    let word = |at: usize| u32::from_be_bytes([head[at], head[at + 1], head[at + 2], head[at + 3]]);
    png.then(|| (word(16), word(20)))
}

/// An image error as [`Error::Decode`], naming the file, on one line (the JPEG decoder's
/// messages span several, which broke the warning they end up in).
fn decode_error(path: &Path, e: image::ImageError) -> Error {
    let text = e.to_string();
    let message = text.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>();
    Error::Decode { path: path.to_path_buf(), message: message.join("; ") }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::refusals::refuse_after;

    /// Texels the allocator refuses are an error naming the file, not an abort; let through,
    /// the same file loads with the texels `from_srgba8` gives.
    #[test]
    fn refused_texels_are_an_error() {
        let path = std::env::temp_dir().join(format!("trirast-texels-{}.png", std::process::id()));
        let data: Vec<u8> = (0..4 * 3 * 2).map(|k| (k * 37 % 256) as u8).collect();
        image::RgbaImage::from_raw(3, 2, data.clone()).unwrap().save(&path).unwrap();
        refuse_after(Some(0));
        let refused = Texture::load(&path);
        refuse_after(None);
        let loaded = Texture::load(&path);
        std::fs::remove_file(&path).unwrap();
        match refused {
            Err(Error::OutOfMemory { what, bytes }) => {
                assert_eq!(what, format!("the texels of {}", path.display()));
                assert_eq!(bytes, 6 * 16);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(loaded.unwrap(), Texture::from_srgba8(3, 2, &data));
    }
}
