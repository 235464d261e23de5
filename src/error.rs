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
    /// An array whose size the input chose (points to sample, triangles to generate, a file
    /// to read) could not be allocated: an error to report rather than the abort of an
    /// infallible allocation. With overcommit the allocation may succeed and the system stop
    /// the process later; this is what the allocator refuses.
    #[error("not enough memory for {what}: {gib:.1} GiB", gib = *.bytes as f64 / f64::from(1 << 30))]
    OutOfMemory {
        /// What the memory was for.
        what: String,
        /// How many bytes were asked for.
        bytes: u128,
    },
    /// The buffers asked for need more memory than the system has available. Checked before
    /// they are allocated, because they are cleared as they are made: with overcommit the
    /// allocation itself succeeds, and the system stops the process once the pages are touched.
    /// Needed is rounded up and available down, to hundredths of a GiB, so the two never
    /// read the same.
    #[error(
        "{what} needs {needed:.2} GiB of memory and {available:.2} GiB is available",
        needed = (*.needed as f64 / f64::from(1 << 30) * 100.0).ceil() / 100.0,
        available = (*.available as f64 / f64::from(1 << 30) * 100.0).floor() / 100.0
    )]
    MemoryUnavailable {
        /// What the memory is for.
        what: String,
        /// Bytes needed.
        needed: u128,
        /// Bytes available.
        available: u128,
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
    /// A point cloud's attribute array whose length differs from its number of positions.
    #[error("point cloud has {len} {attribute} for {expected} positions")]
    CloudAttributeLength {
        /// The attribute (`"normals"`, `"colors"` or `"radii"`).
        attribute: &'static str,
        /// Its length.
        len: usize,
        /// The number of positions.
        expected: usize,
    },
    /// A splat hierarchy whose root sphere (the one enclosing every point) is beyond `f32`,
    /// in which `.tsplat` stores it: its points reach past about 1.7e38 on either side.
    #[error(
        "the splat hierarchy's root sphere (centre {centre:?}, radius {radius}) is beyond single \
         precision, which .tsplat stores it in: its points reach too far from one another"
    )]
    SplatExtent {
        /// The root sphere's centre, as encoded.
        centre: [f32; 3],
        /// Its radius, as encoded.
        radius: f32,
    },
    /// Points to sample over a surface so large that their splat radius (see
    /// [`crate::splat::cloud::sample_mesh`]) is beyond `f32`: a cloud written with it would be
    /// refused when read. Fewer points make larger splats, so `fewest` points would do.
    #[error(
        "{points} points over an area of {area:.3e} would need splats of radius {radius:.3e}, \
         more than an f32 holds; at least {fewest} points would fit"
    )]
    SampleRadius {
        /// Points asked for.
        points: usize,
        /// The surface's area.
        area: f64,
        /// The radius they would need.
        radius: f64,
        /// The fewest points whose radius fits.
        fewest: u64,
    },
    /// A target buffer whose length is not what the target's size and samples need (its
    /// buffers are public fields, and one was replaced).
    #[error("the target's {buffer} buffer has {len} entries where {expected} are needed")]
    TargetBuffer {
        /// The buffer (`"colour"`, `"depth"`, `"id"`, `"overdraw"` or `"normal"`).
        buffer: &'static str,
        /// Its length.
        len: usize,
        /// The length the target's size and samples need.
        expected: usize,
    },
    /// A file whose extension names no format trirast reads.
    #[error("{}: unsupported mesh format: expected .obj, .ply or .stl", path.display())]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// A malformed input file.
    #[error("{}{}: {message}", path.display(), at_line(*line))]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number; 0 in a binary file, whose message names the byte.
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
    /// An input path that names a directory, a device, a FIFO or a socket (symlinks followed),
    /// refused rather than read: reading a device or a FIFO may never end.
    #[error("{}: is {kind}, not a regular file", path.display())]
    NotRegularFile {
        /// The path as given.
        path: PathBuf,
        /// What it is, with its article (`"a directory"`, `"a character device"`, ...).
        kind: &'static str,
    },
    /// A texture larger than [`crate::texture::MAX_TEXTURE_SIDE`] a side or
    /// [`crate::texture::MAX_TEXELS`] in all, refused from its header before it is decoded.
    #[error(
        "{}: texture size {width}x{height} is not supported: each side must be at most {} \
         texels and the whole at most {} texels",
        path.display(),
        crate::texture::MAX_TEXTURE_SIDE,
        crate::texture::MAX_TEXELS
    )]
    TextureSize {
        /// The file.
        path: PathBuf,
        /// Width its header declares.
        width: u32,
        /// Height its header declares.
        height: u32,
    },
    /// Options that do not fit together.
    #[error("{0}")]
    Usage(String),
    /// A camera that forms no image ([`crate::camera::Camera::check`] says why).
    #[error("camera: {0}")]
    Camera(String),
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

/// `:line` after a file's name, nothing for line 0 (a binary file: `f.ply:0: byte 115` read
/// as a line number that does not exist).
fn at_line(line: usize) -> String {
    if line == 0 { String::new() } else { format!(":{line}") }
}

/// `n` copies of `value` in a vector, or [`Error::OutOfMemory`] naming `what` when the memory
/// cannot be had.
pub(crate) fn try_filled<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>, Error> {
    let mut v = Vec::new();
    try_reserve(&mut v, n, what)?;
    v.resize(n, value);
    Ok(v)
}

/// Reserves room for `n` more elements in `v`, or [`Error::OutOfMemory`] naming `what`.
pub(crate) fn try_reserve<T>(v: &mut Vec<T>, n: usize, what: &str) -> Result<(), Error> {
    v.try_reserve_exact(n).map_err(|_| Error::OutOfMemory {
        what: what.to_string(),
        bytes: n as u128 * size_of::<T>() as u128,
    })
}

/// Room for `n` more elements in `v`, amortised as `push` grows it, or [`Error::OutOfMemory`]
/// naming `what` with the bytes `Vec` asked for: for arrays that grow with a file read in
/// pieces (the streamed OBJ and STL readers), which no single reservation bounds.
pub(crate) fn try_grow<'v, T>(
    v: &'v mut Vec<T>,
    n: usize,
    what: &str,
) -> Result<&'v mut Vec<T>, Error> {
    if v.try_reserve(n).is_err() {
        // What `Vec` asks for: room for `n` more, at least twice its capacity.
        let elements = (v.len() as u128 + n as u128).max(2 * v.capacity() as u128);
        let bytes = elements * size_of::<T>() as u128;
        return Err(Error::OutOfMemory { what: what.to_string(), bytes });
    }
    Ok(v)
}

/// Reserves exactly `n` more elements in `v`, or [`Error::OutOfMemory`] naming what `what`
/// returns (called only then) and the bytes of the whole array asked for (`v`'s elements and
/// the `n` more). For the arrays of one job named by their part in it (the splat hierarchy's,
/// the `.tsplat` encoder's and decoder's), which `refusals` can refuse in unit tests.
pub(crate) fn try_reserve_named<T>(
    v: &mut Vec<T>,
    n: usize,
    what: impl FnOnce() -> String,
) -> Result<(), Error> {
    // Tests refuse a chosen allocation by asking for more than any allocator gives.
    #[cfg(test)]
    let ask =
        if n > v.capacity() - v.len() && refusals::refuse_this_one() { usize::MAX } else { n };
    #[cfg(not(test))]
    let ask = n;
    v.try_reserve_exact(ask).map_err(|_| Error::OutOfMemory {
        what: what(),
        bytes: (v.len() as u128 + n as u128) * size_of::<T>() as u128,
    })
}

impl Error {
    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io { path: path.into(), source }
    }
}

/// A test hook: [`try_reserve_named`] refuses the reservation the test chooses, so that a test
/// can refuse each of a job's allocations in turn and check that each is an
/// [`Error::OutOfMemory`] naming the array, not an abort.
#[cfg(test)]
pub(crate) mod refusals {
    use std::cell::Cell;

    thread_local! {
        /// Reservations that allocate to let through before one is refused (`None`: none
        /// refused). Per thread, so tests running side by side do not see each other's; the
        /// jobs tested reserve on the calling thread only.
        static REFUSE: Cell<Option<usize>> = const { Cell::new(None) };
    }

    /// Lets `k` reservations that allocate through, then refuses one; `None` refuses none.
    pub(crate) fn refuse_after(k: Option<usize>) {
        REFUSE.set(k);
    }

    /// Whether the reservation being made is the one to refuse.
    pub(super) fn refuse_this_one() -> bool {
        REFUSE.with(|r| match r.get() {
            Some(0) => {
                r.set(None);
                true
            }
            Some(k) => {
                r.set(Some(k - 1));
                false
            }
            None => false,
        })
    }
}
