//! Input files: every file trirast reads (meshes, material libraries, point clouds, `.tsplat`
//! files, textures) is opened here, and only if it is a regular file.
//!
//! A path that names a device, a FIFO or a directory, directly or through a symlink, is refused
//! before it is read: `mtllib /dev/zero` had grown past 8 GB, and `mtllib /dev/stdin` or a FIFO
//! waited forever for a writer.

use std::fs::{File, FileType};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::error::Error;

/// Opens `path` for reading if it is a regular file (symlinks followed).
///
/// The type is checked before opening, since opening a FIFO blocks until it has a writer, and
/// again on the open file, so that what is read is what was checked. (A path replaced by a
/// FIFO between the two would still block the open: a race only with someone swapping files
/// under the command.)
///
/// # Errors
/// [`Error::NotRegularFile`] naming what the path is, or [`Error::Io`].
pub fn open(path: &Path) -> Result<File, Error> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    regular(path, meta.file_type())?;
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    regular(path, meta.file_type())?;
    Ok(file)
}

/// Reads the whole of `path` if it is a regular file (see [`open`]).
///
/// # Errors
/// As [`open`], or [`Error::Io`] when reading fails.
pub fn read(path: &Path) -> Result<Vec<u8>, Error> {
    let mut file = open(path)?;
    // The size is a hint only (files under /proc report 0).
    let size = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut bytes = Vec::new();
    let what = format!("reading {}", path.display());
    crate::error::try_reserve(&mut bytes, usize::try_from(size).unwrap_or(0), &what)?;
    file.read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    Ok(bytes)
}

/// A reader that tells `report` how far into its input it has read: the furthest offset
/// reached, after each read that moves it past the last one reported. The streamed mesh and
/// point cloud readers read through it, so that a long load can show progress (`trirast
/// render` of a large file). The offset, not a count of bytes read: bytes read again after a
/// seek back (the STL reader may go back to its first bytes) do not count twice.
pub struct ReadProgress<'a, R> {
    inner: R,
    offset: u64,
    furthest: u64,
    report: &'a dyn Fn(u64),
}

impl<'a, R> ReadProgress<'a, R> {
    /// Reads `inner` from its start, reporting to `report`.
    pub fn new(inner: R, report: &'a dyn Fn(u64)) -> Self {
        Self { inner, offset: 0, furthest: 0, report }
    }
}

impl<R: Read> Read for ReadProgress<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.offset += n as u64;
        if self.offset > self.furthest {
            self.furthest = self.offset;
            (self.report)(self.furthest);
        }
        Ok(n)
    }
}

impl<R: Seek> Seek for ReadProgress<'_, R> {
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
        self.offset = self.inner.seek(to)?;
        Ok(self.offset)
    }
}

/// `Ok` for a regular file, else [`Error::NotRegularFile`] saying what it is.
fn regular(path: &Path, file_type: FileType) -> Result<(), Error> {
    if file_type.is_file() {
        return Ok(());
    }
    Err(Error::NotRegularFile { path: path.to_path_buf(), kind: kind(file_type) })
}

/// What a file that is not regular is, with its article, for messages.
fn kind(file_type: FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if file_type.is_char_device() {
            return "a character device";
        }
        if file_type.is_block_device() {
            return "a block device";
        }
        if file_type.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if file_type.is_socket() {
            return "a socket";
        }
    }
    if file_type.is_dir() { "a directory" } else { "a special file" }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_directory_is_refused_by_name() {
        let dir = std::env::temp_dir();
        let e = read(&dir).unwrap_err();
        assert!(matches!(e, Error::NotRegularFile { .. }), "{e:?}");
        assert_eq!(e.to_string(), format!("{}: is a directory, not a regular file", dir.display()));
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn devices_are_refused_before_reading() {
        // Reading /dev/zero would never end.
        let e = read(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(e.to_string(), "/dev/zero: is a character device, not a regular file");
        assert!(open(Path::new("/dev/null")).is_err());
    }

    /// Progress is the furthest offset reached: a read after a seek back reports nothing until
    /// it passes it, and reads that return nothing report nothing.
    #[test]
    fn progress_is_the_furthest_offset() {
        let seen = std::cell::RefCell::new(Vec::new());
        let report = |n| seen.borrow_mut().push(n);
        let mut r = ReadProgress::new(std::io::Cursor::new(vec![7u8; 100]), &report);
        let mut buf = [0; 40];
        assert_eq!(r.read(&mut buf).unwrap(), 40);
        r.seek(SeekFrom::Start(10)).unwrap();
        assert_eq!(r.read(&mut buf).unwrap(), 40);
        assert_eq!(r.read(&mut buf).unwrap(), 40);
        r.seek(SeekFrom::Current(-5)).unwrap();
        assert_eq!(r.read(&mut buf).unwrap(), 15);
        assert_eq!(r.read(&mut buf).unwrap(), 0);
        assert_eq!(seen.into_inner(), [40, 50, 90, 100]);
    }
}
