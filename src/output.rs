//! Files a user can open: PNG colour images and NumPy `.npy` arrays of shape (H, W).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use npyz::WriterBuilder;

use crate::error::Error;
use crate::target::Target;

/// How hard PNG encoding works to make the file small.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PngCompression {
    /// `fdeflate`, made for PNG: about seven times faster than `Balanced` (an 800 x 600
    /// render 3 against 45 ms, a 1080p one 29 against 195 ms), its file a quarter to a half
    /// larger. The default, because encoding with `Balanced` took longer than drawing the
    /// frame, at 1080p five times as long.
    #[default]
    Fast,
    /// zlib level 6, as most tools write PNG.
    Balanced,
    /// zlib level 9: a few percent smaller than `Balanced`, for archiving.
    Best,
}

/// Writes the target's colour image (resolved, when multisampled) as an 8-bit RGBA PNG,
/// compressed with [`PngCompression::Fast`].
///
/// # Errors
/// [`Error::TargetBuffer`] when one of the target's buffers was replaced by one of another
/// length (checked before the file is made), [`Error::Io`] or [`Error::Encode`] when the
/// file cannot be written.
pub fn write_png(path: &Path, target: &Target) -> Result<(), Error> {
    write_png_with(path, target, PngCompression::default())
}

/// [`write_png`] with a choice of compression.
///
/// # Errors
/// As [`write_png`].
pub fn write_png_with(
    path: &Path,
    target: &Target,
    compression: PngCompression,
) -> Result<(), Error> {
    // The buffers are public fields: a colour buffer of another length had panicked in the
    // resolve (after the file was made).
    target.check_buffers()?;
    let file = File::create(path).map_err(|e| Error::io(path, e))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), target.width(), target.height());
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(match compression {
        PngCompression::Fast => png::Compression::Fast,
        PngCompression::Balanced => png::Compression::Balanced,
        PngCompression::Best => png::Compression::High,
    });
    let encode_err =
        |e: png::EncodingError| Error::Encode { path: path.to_path_buf(), message: e.to_string() };
    let mut writer = encoder.write_header().map_err(encode_err)?;
    writer.write_image_data(target.resolve().as_flattened()).map_err(encode_err)?;
    writer.finish().map_err(encode_err)
}

/// Writes `data` (row-major, `height * width` elements) as a little-endian `.npy` array of
/// shape (height, width) that `numpy.load` opens.
///
/// # Errors
/// As [`write_npy_shaped`].
pub fn write_npy<T>(path: &Path, data: &[T], width: u32, height: u32) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize,
{
    write_npy_shaped(path, data, &[u64::from(height), u64::from(width)])
}

/// Writes `data` (row-major, `height * width` arrays of `N` values, as [`Target::normals`]
/// holds) as a little-endian `.npy` array of shape (height, width, N).
///
/// # Errors
/// As [`write_npy_shaped`].
pub fn write_npy_arrays<T, const N: usize>(
    path: &Path,
    data: &[[T; N]],
    width: u32,
    height: u32,
) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize,
{
    write_npy_shaped(path, data.as_flattened(), &[u64::from(height), u64::from(width), N as u64])
}

/// Writes `data` (row-major) as a little-endian `.npy` array of the given shape.
///
/// # Errors
/// [`Error::Io`] when the file cannot be written, or (kind `InvalidInput`, nothing written)
/// when the shape's element count is not `data.len()`, or when the elements are arrays (the
/// `.npy` writer takes scalars: [`write_npy_arrays`] writes arrays as a last axis).
pub fn write_npy_shaped<T>(path: &Path, data: &[T], shape: &[u64]) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize,
{
    let io = |e| Error::io(path, e);
    // Refused before the file is made: the writer panics on them once it has been truncated.
    if let npyz::DType::Array(n, _) = T::default_dtype() {
        let message = format!(
            "npy elements must be scalars, found arrays of {n}: write them with write_npy_arrays"
        );
        return Err(io(std::io::Error::new(std::io::ErrorKind::InvalidInput, message)));
    }
    // Checked: a product that wrapped to the data's length had passed with a header
    // promising 2^64 elements.
    let count = shape.iter().try_fold(1u64, |n, &side| n.checked_mul(side));
    if count != Some(data.len() as u64) {
        let message = format!("npy shape {shape:?} does not hold the {} values given", data.len());
        return Err(io(std::io::Error::new(std::io::ErrorKind::InvalidInput, message)));
    }
    let file = File::create(path).map_err(io)?;
    let mut buf = BufWriter::new(file);
    {
        let mut writer = npyz::WriteOptions::new()
            .default_dtype()
            .shape(shape)
            .writer(&mut buf)
            .begin_nd()
            .map_err(io)?;
        writer.extend(data.iter()).map_err(io)?;
        writer.finish().map_err(io)?;
    }
    buf.flush().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sample::SampleCount;

    /// Every compression writes a PNG that decodes to the resolved image, alpha included;
    /// `Fast` is the default `write_png` takes.
    #[test]
    fn every_compression_decodes_to_the_resolved_image() {
        let mut target = Target::multisampled(37, 23, SampleCount::X4).unwrap();
        for (k, c) in target.color.iter_mut().enumerate() {
            *c = [(k * 7) as u8, (k / 3) as u8, (k % 251) as u8, (k * 13 % 256) as u8];
        }
        let dir = std::env::temp_dir().join(format!("trirast-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let resolved = target.resolve();
        let mut sizes = Vec::new();
        for compression in [PngCompression::Fast, PngCompression::Balanced, PngCompression::Best] {
            let path = dir.join(format!("{compression:?}.png"));
            write_png_with(&path, &target, compression).unwrap();
            let image = image::open(&path).unwrap().into_rgba8();
            assert_eq!((image.width(), image.height()), (37, 23));
            assert_eq!(image.as_raw(), resolved.as_flattened(), "{compression:?}");
            sizes.push(std::fs::metadata(&path).unwrap().len());
        }
        let default = dir.join("default.png");
        write_png(&default, &target).unwrap();
        assert_eq!(std::fs::read(&default).unwrap(), std::fs::read(dir.join("Fast.png")).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(sizes[2] <= sizes[1], "best is no larger than balanced: {sizes:?}");
    }

    /// A colour buffer replaced by one of another length is an error naming it, and no file
    /// is made (the resolve had panicked).
    #[test]
    fn a_replaced_colour_buffer_is_an_error() {
        let path = std::env::temp_dir().join(format!("trirast-short-{}.png", std::process::id()));
        let mut target = Target::multisampled(5, 4, SampleCount::X4).unwrap();
        target.color.pop();
        let e = write_png(&path, &target).unwrap_err();
        assert!(matches!(e, Error::TargetBuffer { .. }), "{e:?}");
        assert!(!path.exists());
    }

    /// A shape that does not hold the data is an error, with no file written, also where its
    /// product overflows (it had wrapped to the data's length: 0); one that does is written.
    #[test]
    fn npy_shapes_must_hold_the_data() {
        let dir = std::env::temp_dir().join(format!("trirast-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.npy");
        let refused = |e: Error| matches!(e, Error::Io { source, .. } if source.kind() == std::io::ErrorKind::InvalidInput);
        assert!(refused(write_npy(&path, &[1.0f32; 3], 2, 2).unwrap_err()));
        assert!(refused(write_npy_shaped::<f32>(&path, &[], &[1 << 32, 1 << 32]).unwrap_err()));
        assert!(!path.exists());
        write_npy(&path, &[1.0f32; 6], 3, 2).unwrap();
        write_npy_shaped::<f32>(&path, &[], &[0, 1 << 40]).unwrap();
        // Arrays are refused as elements (the writer had panicked, the file already
        // truncated) and written as a last axis by `write_npy_arrays`.
        let arrays = [[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0]];
        let kept = std::fs::read(&path).unwrap();
        assert!(refused(write_npy(&path, &arrays, 2, 1).unwrap_err()));
        assert!(refused(write_npy_shaped(&path, &[[7u8; 4]], &[1, 1]).unwrap_err()));
        assert_eq!(std::fs::read(&path).unwrap(), kept);
        write_npy_arrays(&path, &arrays, 2, 1).unwrap();
        let npy = npyz::NpyFile::new(std::fs::File::open(&path).unwrap()).unwrap();
        assert_eq!(npy.shape(), [1, 2, 3]);
        assert_eq!(npy.into_vec::<f32>().unwrap(), arrays.as_flattened());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
