//! The crate's one error type.

use std::path::PathBuf;

/// Everything that can go wrong in trirast, with enough context to act on.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A target side is 0 or above 16384.
    #[error("target size {width}x{height} is not supported: each side must be 1..=16384 pixels")]
    TargetSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The target's buffers could not be allocated.
    #[error("not enough memory for a {width}x{height} target with {samples} sample(s) per pixel")]
    TargetMemory {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Samples per pixel.
        samples: usize,
    },
    /// A vertex lies outside the fixed-point range.
    #[error(
        "triangle {triangle}: vertex {vertex} at ({x}, {y}) is outside the supported window \
         range [-32768, 32768) pixels"
    )]
    CoordinateOutOfRange {
        /// Triangle index in submission order.
        triangle: usize,
        /// Vertex 0, 1 or 2.
        vertex: usize,
        /// The offending x.
        x: f32,
        /// The offending y.
        y: f32,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("triangle {triangle} has indices {indices:?} but there are only {vertices} vertices")]
    IndexOutOfRange {
        /// Triangle index.
        triangle: usize,
        /// Its vertex indices.
        indices: [u32; 3],
        /// Number of vertices.
        vertices: usize,
    },
    /// A mesh attribute array whose length does not match what it describes (one entry per
    /// vertex, or one material per triangle).
    #[error("mesh has {len} {attribute} for {expected} {of}")]
    MeshAttributeLength {
        /// The attribute (`"normals"`, `"texture coordinates"`, ...).
        attribute: &'static str,
        /// Its length.
        len: usize,
        /// The length it must have.
        expected: usize,
        /// What it must match (`"vertices"` or `"triangles"`).
        of: &'static str,
    },
    /// A file whose extension names no format trirast reads.
    #[error("{}: unsupported mesh format: expected .obj, .ply or .stl", path.display())]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// A malformed input file.
    #[error("{}:{line}: {message}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What was expected.
        message: String,
    },
    /// Reading or writing a file failed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Options that do not fit together.
    #[error("{0}")]
    Usage(String),
    /// Decoding an input image failed.
    #[error("{}: cannot decode image: {message}", path.display())]
    Decode {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// Encoding an output image failed.
    #[error("{}: {message}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// What the encoder said.
        message: String,
    },
}

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}
