//! Files a user can open: PNG colour images and NumPy `.npy` arrays of shape (H, W).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use npyz::WriterBuilder;

use crate::error::Error;
use crate::target::Target;

/// Writes the target's colour image (resolved, when multisampled) as an 8-bit RGBA PNG.
pub fn write_png(path: &Path, target: &Target) -> Result<(), Error> {
    let file = File::create(path).map_err(|e| Error::io(path, e))?;
    let mut encoder = png::Encoder::new(BufWriter::new(file), target.width(), target.height());
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let encode_err =
        |e: png::EncodingError| Error::Encode { path: path.to_path_buf(), message: e.to_string() };
    let mut writer = encoder.write_header().map_err(encode_err)?;
    writer.write_image_data(target.resolve().as_flattened()).map_err(encode_err)?;
    writer.finish().map_err(encode_err)
}

/// Writes `data` (row-major, `height * width` elements) as a little-endian `.npy` array of
/// shape (height, width) that `numpy.load` opens.
pub fn write_npy<T>(path: &Path, data: &[T], width: u32, height: u32) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize,
{
    write_npy_shaped(path, data, &[u64::from(height), u64::from(width)])
}

/// Writes `data` (row-major) as a little-endian `.npy` array of the given shape.
///
/// # Panics
/// If the shape's element count differs from `data.len()`.
pub fn write_npy_shaped<T>(path: &Path, data: &[T], shape: &[u64]) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize,
{
    assert_eq!(shape.iter().product::<u64>(), data.len() as u64, "npy shape and data disagree");
    let io = |e| Error::io(path, e);
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
