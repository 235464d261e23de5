//! STL reader: ASCII and binary.
//!
//! Hand-written rather than taken from `stl_io`, whose reader cannot meet this crate's error
//! contract: its ASCII errors carry no line number (and it drops blank lines before parsing, so
//! one cannot be recovered), its binary reader trusts the header's triangle count, and it
//! decides ASCII vs binary by the `solid ` prefix alone, so binary files whose 80-byte header
//! starts with `solid` (common) are misread as ASCII. Both formats are simple enough that a
//! focused reader is shorter than the workarounds.
//!
//! Format detection: a file whose first word is `solid` (after a UTF-8 byte order mark, if
//! any) is ASCII unless its size is exactly `84 + 50 * count` for the little-endian triangle
//! count at byte 80, in which case it is a binary file with a text-like header. Anything else
//! is binary, and a size that disagrees with the count is an error naming byte 80, except that
//! a count of 0 in a file of whole facets (some exporters write 0) is read by the size, with a
//! warning; a file beginning `solid` is so read only when its first bytes are not text.
//!
//! ASCII: keywords are matched case-insensitively; a file may hold several `solid ... endsolid`
//! blocks; `facet normal nx ny nz` may omit the normal; an `outer loop` of more than three
//! vertices is accepted as a polygon and triangulated by [`crate::polygon::triangulate_face`].
//! Lines end at LF or CR LF, or in a file whose first line ends with a CR alone (classic Mac
//! OS), at CR (the OBJ reader takes such files too).
//!
//! **Welding.** STL stores every facet's corners separately, with a per-facet normal. The
//! [`Mesh`] produced here welds them: corners at bit-identical positions (after folding `-0.0`
//! into `0.0`) share one vertex, and `normals` is `None`. Welding restores the connectivity the
//! format throws away, which the pipeline needs to compute smooth vertex normals, and costs
//! nothing for flat shading, since the pipeline recomputes each facet normal from the positions
//! (the stored ones are often zero or inaccurate, and would only agree with the winding by
//! convention). A model that wants hard edges gets them from the pipeline's flat shading or a
//! crease angle, not from unwelded corners. Triangles keep the file's order and winding;
//! degenerate facets are kept (setup rejects zero-area triangles).
//!
//! **Streaming.** [`read`] parses the file as it reads it, through a 64 KB buffer, welding as
//! it goes, so the file is never in memory whole: the size that decides the format comes from
//! the file's metadata, and the first bytes (the header, the first word, which may follow any
//! amount of whitespace) are read ahead and then read again by the parser. `trirast info` on a
//! binary STL of 1,000,000 triangles (50 MB; a mesh of 18 MB, welded through an index of as
//! much) had peaked at 123 MB and now at 76 MB; on an ASCII one (228 MB), 279 MB and now 55 MB.
//! [`parse`] reads a file already in memory, as the reader did before: it is the reference the
//! streamed reader ([`parse_streamed`] on bytes) is tested against. The two share the ASCII
//! grammar, the decoding of a binary facet and the welding; each has its own format detection,
//! line splitting and binary framing.
//!
//! Binary errors are [`Error::Parse`] with `line: 0` and a message starting `byte N:`. The
//! vertex and triangle arrays grow fallibly: memory running out is [`Error::OutOfMemory`].

use std::collections::HashMap;
use std::io::{BufRead, BufReader, Read, Seek};
use std::path::Path;

use super::Mesh;
use crate::error::Error;

/// Bytes read from a file at a time.
const READ_BUFFER: usize = 1 << 16;

/// The first bytes format detection looks at: the triangle count at byte 80, and the bytes
/// that tell a binary file with a `solid` header from an ASCII one ([`looks_binary`]).
const HEAD: usize = 512;

/// Bytes of a binary facet: normal, three vertices (12 `f32`), attribute byte count (`u16`).
const FACET: usize = 50;

/// Reads an STL file (ASCII or binary) as a welded [`Mesh`], parsing it as it is read (see
/// the module documentation). A path that is not a regular file is refused by
/// [`crate::input::open`].
pub fn read(path: &Path) -> Result<Mesh, Error> {
    read_reporting(path, &|_| {})
}

/// [`read`], telling `report` how far into the file it has read.
pub(crate) fn read_reporting(path: &Path, report: &dyn Fn(u64)) -> Result<Mesh, Error> {
    let file = crate::input::open(path)?;
    let size = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let file = crate::input::ReadProgress::new(file, report);
    read_from(BufReader::with_capacity(READ_BUFFER, file), size, path)
}

/// Parses the contents of an STL file as [`read`] reads a file (through the same buffered
/// reader, over `bytes`); `path` is only used to name the file in errors. Gives what [`parse`]
/// gives.
pub fn parse_streamed(bytes: &[u8], path: &Path) -> Result<Mesh, Error> {
    let reader = BufReader::with_capacity(READ_BUFFER, std::io::Cursor::new(bytes));
    read_from(reader, bytes.len() as u64, path)
}

/// Parses the contents of an STL file, all in memory; `path` is only used to name the file in
/// errors. The reference [`read`] is tested against.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, Error> {
    let len = bytes.len() as u64;
    let head = &bytes[..bytes.len().min(HEAD)];
    let solid = first_word(bytes).eq_ignore_ascii_case(b"solid");
    let mesh = match format(head, len, solid) {
        Ok(Format::Ascii) => {
            parse_ascii(&mut SliceLines::new(bytes)).map_err(|f| ascii_failed(f, head, len))
        }
        Ok(Format::Binary { count, by_size }) => {
            parse_binary(&bytes[84..], count).map(|mesh| warned(mesh, (count, by_size), path))
        }
        Err(fail) => Err(fail),
    };
    mesh.map_err(|f| f.at(path))
}

/// [`read`] and [`parse_streamed`]: parses the file `reader` reads, whose size is `size` (a
/// hint: see [`detect`]), naming `path` in errors.
fn read_from<R: Read + Seek>(
    mut reader: BufReader<R>,
    size: u64,
    path: &Path,
) -> Result<Mesh, Error> {
    let (head, solid, len) = detect(&mut reader, size).map_err(|e| Error::io(path, e))?;
    let mesh = match format(&head, len, solid) {
        Ok(Format::Ascii) => {
            parse_ascii(&mut StreamLines::new(reader)).map_err(|f| ascii_failed(f, &head, len))
        }
        Ok(Format::Binary { count, by_size }) => {
            read_binary(&mut reader, count, len).map(|mesh| warned(mesh, (count, by_size), path))
        }
        Err(fail) => Err(fail),
    };
    mesh.map_err(|f| f.at(path))
}

/// Reads the start of the file: returns its first [`HEAD`] bytes (fewer in a shorter file),
/// whether its first word is `solid`, and its length, and leaves `reader` where it started.
///
/// The length is `size` (the file's metadata), except where what is read shows it wrong: a
/// file that ends within the bytes read has their length, and one that goes on past `size`
/// (files under /proc report 0) is read to the end to count it.
fn detect<R: Read + Seek>(
    reader: &mut BufReader<R>,
    size: u64,
) -> std::io::Result<(Vec<u8>, bool, u64)> {
    let mut head = Vec::with_capacity(HEAD);
    let mut word = FirstWord::default();
    let mut read = 0u64;
    let mut ended = false;
    while head.len() < HEAD || !word.done {
        let buffer = reader.fill_buf()?;
        if buffer.is_empty() {
            ended = true;
            break;
        }
        let mut used = 0;
        for &b in buffer {
            if head.len() == HEAD && word.done {
                break;
            }
            if head.len() < HEAD {
                head.push(b);
            }
            word.push(b);
            used += 1;
        }
        reader.consume(used);
        read += used as u64;
    }
    let len = if ended {
        read
    } else if read > size {
        loop {
            let n = reader.fill_buf()?.len();
            if n == 0 {
                break read;
            }
            reader.consume(n);
            read += n as u64;
        }
    } else {
        size
    };
    match i64::try_from(read) {
        // Within the buffer, as a rule: nothing is read again from the file.
        Ok(back) => reader.seek_relative(-back)?,
        Err(_) => reader.rewind()?,
    }
    Ok((head, word.is_solid(), len))
}

/// The first word of a file, read a byte at a time: after a [`BOM`] or any whitespace, up to
/// the next whitespace or six bytes (nine after a BOM), which is enough to tell whether it is
/// `solid`.
#[derive(Default)]
struct FirstWord {
    bytes: [u8; 9],
    len: usize,
    /// Whether the bytes so far decide it.
    done: bool,
}

impl FirstWord {
    fn push(&mut self, b: u8) {
        if self.done {
            return;
        }
        if b.is_ascii_whitespace() {
            self.done = self.len > 0;
            return;
        }
        self.bytes[self.len] = b;
        self.len += 1;
        let bom = BOM.starts_with(&self.bytes[..self.len.min(BOM.len())]);
        self.done = self.len == if bom { 9 } else { 6 };
    }

    fn is_solid(&self) -> bool {
        first_word(&self.bytes[..self.len]).eq_ignore_ascii_case(b"solid")
    }
}

/// What stopped a read: a malformed file, the file failing, or the memory running out.
#[derive(Debug)]
enum Fail {
    /// Where the file is malformed, and what was expected there.
    At(At, String),
    Io(std::io::Error),
    Error(Error),
}

impl Fail {
    /// The error, naming the file at `path`.
    fn at(self, path: &Path) -> Error {
        match self {
            Self::At(At::Line(line), message) => {
                Error::Parse { path: path.to_path_buf(), line, message }
            }
            Self::At(At::Byte(offset), message) => Error::Parse {
                path: path.to_path_buf(),
                line: 0,
                message: format!("byte {offset}: {message}"),
            },
            Self::Io(e) => Error::io(path, e),
            Self::Error(e) => e,
        }
    }
}

/// A 1-based line of an ASCII file, or a byte offset in a binary one.
#[derive(Clone, Copy, Debug)]
enum At {
    Line(usize),
    Byte(u64),
}

/// A malformed ASCII file at `line`.
fn on_line(line: usize, message: String) -> Fail {
    Fail::At(At::Line(line), message)
}

/// Which reader a file takes.
enum Format {
    Ascii,
    /// Binary, of `count` triangles (the size agrees); `by_size` when the header's count was
    /// 0 and `count` comes from the size.
    Binary {
        count: u32,
        by_size: bool,
    },
}

/// The format of a file of `len` bytes that starts with `head` (its first [`HEAD`] bytes) and
/// whose first word is `solid` or not; a binary file whose size disagrees with its count fails,
/// except that a count of 0 in a file of whole facets takes the count its size gives (some
/// exporters write 0 there). Bytes 80 to 83 all zero do not occur in ASCII STL, but a binary
/// file may begin `solid` too, so one that does is taken by its size only when its head has
/// bytes no ASCII STL has.
fn format(head: &[u8], len: u64, solid: bool) -> Result<Format, Fail> {
    if let Some(count) = count_from_size(head, len).filter(|_| !solid || looks_binary(head)) {
        return Ok(Format::Binary { count, by_size: true });
    }
    if solid && binary_size(head) != Some(len) {
        return Ok(Format::Ascii);
    }
    check_binary_size(head, len).map(|count| Format::Binary { count, by_size: false })
}

/// `mesh`, of `count` facets, with [`by_size_warning`] when it was read `by_size`.
fn warned(mut mesh: Mesh, (count, by_size): (u32, bool), path: &Path) -> Mesh {
    if by_size {
        mesh.warnings.push(by_size_warning(path, count));
    }
    mesh
}

/// The triangle count a binary file of `len` bytes whose header declares 0 holds: its facets
/// after the 84 bytes of header and count, when they are whole and at least one.
fn count_from_size(head: &[u8], len: u64) -> Option<u32> {
    let facets = len.checked_sub(84)?;
    let declared_zero = head.get(80..84)? == [0; 4];
    (declared_zero && facets > 0 && facets % 50 == 0).then(|| u32::try_from(facets / 50).ok())?
}

/// The warning for a file of `count` facets read by [`count_from_size`], naming the file.
fn by_size_warning(path: &Path, count: u32) -> String {
    format!(
        "{}: byte 80: the header declares 0 triangles, but the file holds {} (84 bytes + 50 \
         per triangle); read by its size",
        path.display(),
        count
    )
}

/// What a failed ASCII read reports: a binary file whose header starts with `solid` but whose
/// size is wrong complains of the size, the more useful complaint.
fn ascii_failed(fail: Fail, head: &[u8], len: u64) -> Fail {
    if let Fail::At(At::Line(_), _) = fail
        && looks_binary(head)
        && let Err(Fail::At(at, message)) = check_binary_size(head, len)
    {
        return Fail::At(
            at,
            format!("{message} (it starts with `solid` but is not ASCII STL either)"),
        );
    }
    fail
}

/// The size a binary STL with this header's triangle count has.
fn binary_size(head: &[u8]) -> Option<u64> {
    let count = head.get(80..84)?;
    let count = u32::from_le_bytes([count[0], count[1], count[2], count[3]]);
    Some(84 + 50 * u64::from(count))
}

/// The first whitespace-separated word of `bytes`, without a [`BOM`] directly before it.
fn first_word(bytes: &[u8]) -> &[u8] {
    let start = bytes.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(bytes.len());
    let rest = &bytes[start..];
    let rest = rest.strip_prefix(BOM).unwrap_or(rest);
    let end = rest.iter().position(u8::is_ascii_whitespace).unwrap_or(rest.len());
    &rest[..end]
}

/// The UTF-8 byte order mark some editors write before an ASCII file's first word.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// Whether the start of the file has bytes no ASCII STL contains (after a [`BOM`]).
fn looks_binary(head: &[u8]) -> bool {
    let head = head.strip_prefix(BOM).unwrap_or(head);
    head.iter().take(HEAD).any(|&b| b == 0 || (b < 0x20 && !b.is_ascii_whitespace()) || b > 0x7e)
}

/// The triangle count of a binary file of `len` bytes starting with `head`, if its size is
/// the one the count gives.
fn check_binary_size(head: &[u8], len: u64) -> Result<u32, Fail> {
    let Some(expected) = binary_size(head) else {
        return Err(Fail::At(
            At::Byte(len),
            format!(
                "file ends after {len} bytes: a binary STL starts with an 80-byte header and a \
                 4-byte triangle count"
            ),
        ));
    };
    let count = (expected - 84) / 50;
    if expected != len {
        return Err(Fail::At(
            At::Byte(80),
            format!(
                "the header declares {count} triangle{}, which take{} {expected} bytes (84 + 50 \
                 per triangle), but the file has {len} bytes",
                if count == 1 { "" } else { "s" },
                if count == 1 { "s" } else { "" },
            ),
        ));
    }
    Ok(count as u32)
}

/// [`crate::error::try_grow`] for the mesh's arrays, which grow as the file is read.
fn reserve<'v, T>(v: &'v mut Vec<T>, n: usize, what: &str) -> Result<&'v mut Vec<T>, Fail> {
    crate::error::try_grow(v, n, what).map_err(Fail::Error)
}

/// Welds corners into shared vertices as the mesh is built.
#[derive(Default)]
struct Welder {
    mesh: Mesh,
    index: HashMap<[u32; 3], u32>,
}

impl Welder {
    /// A welder for a binary file of `count` triangles, their array allocated.
    fn for_triangles(count: u32) -> Result<Self, Fail> {
        let mut welder = Self::default();
        let triangles = &mut welder.mesh.triangles;
        crate::error::try_reserve(triangles, count as usize, "STL triangles")
            .map_err(Fail::Error)?;
        welder.mesh.polygon_count = count as usize;
        Ok(welder)
    }

    /// The vertex at `p`, made if it is the first corner there.
    fn vertex(&mut self, p: [f32; 3]) -> Result<u32, Fail> {
        // `+ 0.0` folds -0.0 into 0.0; positions are finite, so bits identify them.
        let p = p.map(|c| c + 0.0);
        if self.index.try_reserve(1).is_err() {
            // About what the map asks for: twice the buckets, an entry and a control byte each.
            let entries = 2 * (self.index.len() as u128 + 1).max(self.index.capacity() as u128);
            let bytes = entries * (size_of::<([u32; 3], u32)>() as u128 + 1);
            let what = "STL vertex index".to_string();
            return Err(Fail::Error(Error::OutOfMemory { what, bytes }));
        }
        let next = self.mesh.positions.len() as u32;
        match self.index.entry(p.map(f32::to_bits)) {
            std::collections::hash_map::Entry::Occupied(e) => Ok(*e.get()),
            std::collections::hash_map::Entry::Vacant(e) => {
                reserve(&mut self.mesh.positions, 1, "STL vertices")?.push(p);
                Ok(*e.insert(next))
            }
        }
    }

    /// Binary facet `i` (its 50 bytes) as a triangle.
    fn facet(&mut self, i: usize, facet: &[u8; FACET]) -> Result<(), Fail> {
        let mut triangle = [0; 3];
        for (k, v) in triangle.iter_mut().enumerate() {
            let mut p = [0.0f32; 3];
            for (c, out) in p.iter_mut().enumerate() {
                let at = 12 + 12 * k + 4 * c;
                *out = f32::from_le_bytes([facet[at], facet[at + 1], facet[at + 2], facet[at + 3]]);
                if !out.is_finite() {
                    let offset = 84 + 50 * i as u64 + at as u64;
                    return Err(Fail::At(
                        At::Byte(offset),
                        format!(
                            "triangle {i}, vertex {k}: coordinate {} is {out}, expected a finite \
                             number",
                            ["x", "y", "z"][c]
                        ),
                    ));
                }
            }
            *v = self.vertex(p)?;
        }
        // Room for every triangle was reserved (`for_triangles`).
        self.mesh.triangles.push(triangle);
        Ok(())
    }
}

/// The reference binary reader: the `count` facets of `body`, the file after its header and
/// count (whose size [`check_binary_size`] checked).
fn parse_binary(body: &[u8], count: u32) -> Result<Mesh, Fail> {
    let mut welder = Welder::for_triangles(count)?;
    for (i, facet) in body.as_chunks::<FACET>().0.iter().enumerate() {
        welder.facet(i, facet)?;
    }
    Ok(welder.mesh)
}

/// The streamed binary reader: `count` facets from `reader` (at the start of a file of `len`
/// bytes, whose size [`check_binary_size`] checked), a facet at a time. A file that ends
/// before `len` bytes or goes on past them (it changed while being read) fails.
fn read_binary(reader: &mut impl BufRead, count: u32, len: u64) -> Result<Mesh, Fail> {
    let mut fill = |buffer: &mut [u8], at: u64| {
        reader.read_exact(buffer).map_err(|e| match e.kind() {
            std::io::ErrorKind::UnexpectedEof => Fail::At(
                At::Byte(at),
                format!("the file ends before its stated size of {len} bytes"),
            ),
            _ => Fail::Io(e),
        })
    };
    fill(&mut [0; 84], 0)?;
    let mut welder = Welder::for_triangles(count)?;
    let mut facet = [0; FACET];
    for i in 0..count as usize {
        fill(&mut facet, 84 + 50 * i as u64)?;
        welder.facet(i, &facet)?;
    }
    if !reader.fill_buf().map_err(Fail::Io)?.is_empty() {
        let message = format!("the file goes on past its stated size of {len} bytes");
        return Err(Fail::At(At::Byte(len), message));
    }
    Ok(welder.mesh)
}

/// The non-blank lines of an ASCII STL.
trait Lines {
    /// The next non-blank line: its 1-based number and text, or at the end of the file the
    /// number of the last line (counting the empty one after a final LF) and `None`. Fails on
    /// a line that is not UTF-8.
    fn line(&mut self) -> Result<(usize, Option<&str>), Fail>;
}

/// How a file's lines end, decided at its first line end: a CR alone there (classic Mac OS)
/// makes every CR a line end; an LF or a CR LF makes every LF one, a CR elsewhere staying
/// whitespace, as it always was (so no file of LF lines reads differently for a stray CR).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LineEnds {
    Unknown,
    Lf,
    Cr,
}

impl LineEnds {
    /// Where the first line end of `bytes` under this rule is.
    fn find(self, bytes: &[u8]) -> Option<usize> {
        match self {
            Self::Lf => memchr::memchr(b'\n', bytes),
            Self::Cr => memchr::memchr(b'\r', bytes),
            Self::Unknown => memchr::memchr2(b'\n', b'\r', bytes),
        }
    }

    /// The rule a first line end decides: `end` the byte found, `next` the one after it
    /// (`None` at the end of the file).
    fn decided(end: u8, next: Option<u8>) -> Self {
        if end == b'\r' && next != Some(b'\n') { Self::Cr } else { Self::Lf }
    }
}

/// The reference's lines: split from the file in memory, ended as [`LineEnds`] says.
struct SliceLines<'a> {
    /// The rest of the file after the last line returned; `None` after the last.
    rest: Option<&'a [u8]>,
    ends: LineEnds,
    /// The last line number seen (for end-of-file errors).
    last: usize,
}

impl<'a> SliceLines<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { rest: Some(bytes), ends: LineEnds::Unknown, last: 0 }
    }

    /// The next line, without its line end (a CR before an LF stays, as whitespace).
    fn next_piece(&mut self) -> Option<&'a [u8]> {
        let rest = self.rest?;
        let Some(mut k) = self.ends.find(rest) else {
            self.rest = None;
            return Some(rest);
        };
        if self.ends == LineEnds::Unknown {
            self.ends = LineEnds::decided(rest[k], rest.get(k + 1).copied());
            if self.ends == LineEnds::Lf && rest[k] == b'\r' {
                k += 1;
            }
        }
        self.rest = Some(&rest[k + 1..]);
        Some(&rest[..k])
    }
}

impl Lines for SliceLines<'_> {
    fn line(&mut self) -> Result<(usize, Option<&str>), Fail> {
        while let Some(raw) = self.next_piece() {
            self.last += 1;
            let line = self.last;
            let text = std::str::from_utf8(raw)
                .map_err(|_| on_line(line, "not valid UTF-8".to_string()))?;
            if text.split_ascii_whitespace().next().is_some() {
                return Ok((line, Some(text)));
            }
        }
        Ok((self.last, None))
    }
}

/// The streamed reader's lines: read one at a time from a buffered file, ended as
/// [`SliceLines`] ends them.
struct StreamLines<R> {
    reader: R,
    /// The current line, without its line end.
    text: Vec<u8>,
    ends: LineEnds,
    /// The last line number read.
    last: usize,
    /// Whether the last line (the one after the last line end, perhaps empty) is read.
    ended: bool,
}

impl<R: BufRead> StreamLines<R> {
    fn new(reader: R) -> Self {
        Self { reader, text: Vec::new(), ends: LineEnds::Unknown, last: 0, ended: false }
    }

    /// Reads the next line into `text`; true if it was the last (no line end after it).
    fn next_piece(&mut self) -> std::io::Result<bool> {
        self.text.clear();
        loop {
            let buf = fill(&mut self.reader)?;
            if buf.is_empty() {
                return Ok(true);
            }
            let Some(k) = self.ends.find(buf) else {
                let n = buf.len();
                self.text.extend_from_slice(buf);
                self.reader.consume(n);
                continue;
            };
            let end = buf[k];
            self.text.extend_from_slice(&buf[..k]);
            self.reader.consume(k + 1);
            if self.ends == LineEnds::Unknown {
                // The byte after a CR may begin the next fill.
                let next =
                    if end == b'\r' { fill(&mut self.reader)?.first().copied() } else { None };
                self.ends = LineEnds::decided(end, next);
                if self.ends == LineEnds::Lf && end == b'\r' {
                    self.text.push(b'\r');
                    self.reader.consume(1);
                }
            }
            return Ok(false);
        }
    }
}

/// `reader`'s buffer, filled if it is empty (retried when interrupted, as `read_until` does).
fn fill<R: BufRead>(reader: &mut R) -> std::io::Result<&[u8]> {
    loop {
        match reader.fill_buf() {
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
            // Asked again (it returns the same bytes, read no more): the borrow cannot be
            // returned from inside the loop.
            Ok(_) => break,
        }
    }
    reader.fill_buf()
}

impl<R: BufRead> Lines for StreamLines<R> {
    fn line(&mut self) -> Result<(usize, Option<&str>), Fail> {
        loop {
            if self.ended {
                return Ok((self.last, None));
            }
            self.ended = self.next_piece().map_err(Fail::Io)?;
            self.last += 1;
            // A blank line is ASCII, hence UTF-8: only the others need checking.
            if !self.text.iter().all(u8::is_ascii_whitespace) {
                break;
            }
        }
        let line = self.last;
        let text = std::str::from_utf8(&self.text)
            .map_err(|_| on_line(line, "not valid UTF-8".to_string()))?;
        Ok((line, Some(text)))
    }
}

/// The next non-blank line's number and tokens, or the last line's number and `None` at the
/// end of the file.
fn next_tokens(lines: &mut impl Lines) -> Result<(usize, Option<Vec<&str>>), Fail> {
    let (line, text) = lines.line()?;
    Ok((line, text.map(|t| t.split_ascii_whitespace().collect())))
}

/// The next non-blank line, where `what` is expected.
fn require<'l>(lines: &'l mut impl Lines, what: &str) -> Result<(usize, Vec<&'l str>), Fail> {
    match next_tokens(lines)? {
        (line, Some(tokens)) => Ok((line, tokens)),
        (line, None) => Err(on_line(line, format!("file ends where {what} was expected"))),
    }
}

/// The next line, which must start with `keyword`.
fn expect<'l>(
    lines: &'l mut impl Lines,
    keyword: &str,
    what: &str,
) -> Result<(usize, Vec<&'l str>), Fail> {
    let (line, tokens) = require(lines, what)?;
    if !tokens[0].eq_ignore_ascii_case(keyword) {
        return Err(on_line(line, format!("expected {what}, found `{}`", tokens.join(" "))));
    }
    Ok((line, tokens))
}

fn numbers(tokens: &[&str], line: usize, what: &str) -> Result<[f32; 3], Fail> {
    if tokens.len() != 3 {
        return Err(on_line(line, format!("`{what}` takes 3 numbers, found {}", tokens.len())));
    }
    let mut out = [0.0; 3];
    for (o, t) in out.iter_mut().zip(tokens) {
        *o = t.parse().map_err(|_| on_line(line, format!("expected a number, found `{t}`")))?;
    }
    Ok(out)
}

/// The ASCII grammar, on the lines of either reader.
fn parse_ascii(lines: &mut impl Lines) -> Result<Mesh, Fail> {
    let mut welder = Welder::default();
    let mut corners = Vec::new();
    let mut points = Vec::new();
    // The first line, after a byte order mark if the file has one.
    let (line, tokens) = require(lines, "`solid`")?;
    if !tokens[0].trim_start_matches('\u{feff}').eq_ignore_ascii_case("solid") {
        return Err(on_line(line, format!("expected `solid`, found `{}`", tokens.join(" "))));
    }
    loop {
        let (line, tokens) = require(lines, "`facet` or `endsolid`")?;
        let keyword = tokens[0];
        if keyword.eq_ignore_ascii_case("endsolid") {
            match next_tokens(lines)? {
                (_, None) => break,
                (_, Some(t)) if t[0].eq_ignore_ascii_case("solid") => continue,
                (line, Some(t)) => {
                    return Err(on_line(
                        line,
                        format!("expected `solid` or the end of the file, found `{}`", t.join(" ")),
                    ));
                }
            }
        }
        if !keyword.eq_ignore_ascii_case("facet") {
            return Err(on_line(
                line,
                format!(
                    "expected `facet normal nx ny nz` or `endsolid`, found `{}`",
                    tokens.join(" ")
                ),
            ));
        }
        if tokens.len() > 1 {
            if !tokens[1].eq_ignore_ascii_case("normal") {
                return Err(on_line(
                    line,
                    format!("expected `facet normal nx ny nz`, found `{}`", tokens.join(" ")),
                ));
            }
            // The normal is checked for syntax but not kept (see the module documentation).
            numbers(&tokens[2..], line, "facet normal")?;
        }
        let (line, tokens) = expect(lines, "outer", "`outer loop`")?;
        if tokens.len() != 2 || !tokens[1].eq_ignore_ascii_case("loop") {
            return Err(on_line(
                line,
                format!("expected `outer loop`, found `{}`", tokens.join(" ")),
            ));
        }
        corners.clear();
        points.clear();
        loop {
            let (line, tokens) = require(lines, "`vertex x y z` or `endloop`")?;
            if tokens[0].eq_ignore_ascii_case("endloop") {
                if points.len() < 3 {
                    return Err(on_line(
                        line,
                        format!("a facet needs 3 or more vertices, found {}", points.len()),
                    ));
                }
                break;
            }
            if !tokens[0].eq_ignore_ascii_case("vertex") {
                return Err(on_line(
                    line,
                    format!("expected `vertex x y z` or `endloop`, found `{}`", tokens.join(" ")),
                ));
            }
            let p = numbers(&tokens[1..], line, "vertex")?;
            if !p.iter().all(|c| c.is_finite()) {
                // As written: a value past `f32`'s range (`1e39`) had been shown as `inf`.
                return Err(on_line(
                    line,
                    format!(
                        "vertex `{}` is not finite in single precision (largest magnitude about \
                         3.4e38)",
                        tokens[1..].join(" ")
                    ),
                ));
            }
            points.push(p);
            corners.push(welder.vertex(p)?);
        }
        expect(lines, "endfacet", "`endfacet`")?;
        welder.mesh.polygon_count += 1;
        let triangles = reserve(&mut welder.mesh.triangles, 1, "STL triangles")?;
        if let [a, b, c] = corners[..] {
            triangles.push([a, b, c]);
        } else {
            for t in crate::polygon::triangulate_face(&points) {
                if let (Some(&a), Some(&b), Some(&c)) =
                    (corners.get(t[0]), corners.get(t[1]), corners.get(t[2]))
                {
                    reserve(triangles, 1, "STL triangles")?.push([a, b, c]);
                }
            }
        }
    }
    Ok(welder.mesh)
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;

    const CUBE_CORNER: &str = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n\
        vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n\
        facet normal 0 0 1\nouter loop\nvertex 1 0 0\nvertex 1 1 0\nvertex 0 1 -0\nendloop\n\
        endfacet\nendsolid t\n";

    /// `bytes` through the streamed reader, with a buffer of `capacity` bytes and `size` for
    /// the size the file's metadata gives.
    fn streamed(bytes: &[u8], capacity: usize, size: u64) -> Result<Mesh, Error> {
        let reader = BufReader::with_capacity(capacity, Cursor::new(bytes));
        read_from(reader, size, Path::new("t.stl"))
    }

    /// Both readers on `bytes`, which must agree (with several buffer sizes); the outcome.
    fn both(bytes: &[u8]) -> Result<Mesh, Error> {
        let reference = parse(bytes, Path::new("t.stl"));
        for capacity in [1, 7, 100, READ_BUFFER] {
            let streamed = streamed(bytes, capacity, bytes.len() as u64);
            assert!(same(&reference, &streamed), "{reference:?}\n{streamed:?}");
        }
        reference
    }

    /// The same mesh, or the same error.
    fn same(a: &Result<Mesh, Error>, b: &Result<Mesh, Error>) -> bool {
        match (a, b) {
            (Ok(a), Ok(b)) => a == b,
            (Err(a), Err(b)) => format!("{a:?}") == format!("{b:?}"),
            _ => false,
        }
    }

    #[test]
    fn ascii_welds_shared_corners() {
        let m = both(CUBE_CORNER.as_bytes()).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        assert_eq!(m.polygon_count, 2);
        assert!(m.normals.is_none());
    }

    #[test]
    fn binary_with_solid_header_is_binary() {
        let mut b = b"solid binary".to_vec();
        b.resize(80, b' ');
        b.extend_from_slice(&1u32.to_le_bytes());
        for v in [[0.0f32; 3], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            for c in v {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0, 0]);
        let m = both(&b).unwrap();
        assert_eq!(m.triangles.len(), 1);
        b.push(0);
        let e = both(&b).unwrap_err().to_string();
        assert!(
            e.starts_with("t.stl: byte 80: the header declares 1 triangle, which takes"),
            "{e}"
        );
        assert!(e.contains("not ASCII STL either"), "{e}");
    }

    /// A binary file whose header declares 0 triangles but that holds whole facets is read
    /// by its size, with a warning (some exporters write 0 there), whether its header begins
    /// `solid` or not; other mismatches, and a size that is not whole facets, still fail.
    #[test]
    fn a_zero_count_is_read_by_the_size() {
        let facets = |header: &[u8], count: u32, n: usize| {
            let mut b = header.to_vec();
            b.resize(80, b' ');
            b.extend_from_slice(&count.to_le_bytes());
            for k in 0..n {
                let x = k as f32;
                for v in [[0.0f32, 0.0, 1.0], [x, 0.0, 0.0], [x + 1.0, 0.0, 0.0], [x, 1.0, 0.0]] {
                    v.iter().for_each(|c| b.extend_from_slice(&c.to_le_bytes()));
                }
                b.extend_from_slice(&[0, 0]);
            }
            b
        };
        for header in [&b"exported"[..], b"solid part"] {
            let mut m = both(&facets(header, 0, 3)).unwrap();
            let warnings = std::mem::take(&mut m.warnings);
            assert_eq!(m, both(&facets(header, 3, 3)).unwrap());
            assert_eq!(m.triangles.len(), 3);
            let want = "t.stl: byte 80: the header declares 0 triangles, but the file holds 3 (84 \
                        bytes + 50 per triangle); read by its size";
            assert_eq!(warnings, [want]);
            for (count, n, extra) in [(1, 3, 0), (4, 3, 0), (0, 3, 1), (0, 3, 49)] {
                let mut b = facets(header, count, n);
                b.extend(std::iter::repeat_n(0, extra));
                let e = both(&b).unwrap_err().to_string();
                assert!(e.contains("byte 80: the header declares"), "{count} {n} {extra}: {e}");
            }
        }
    }

    #[test]
    fn ascii_errors_name_the_line() {
        let cases: &[(&str, &str)] = &[
            ("solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0\n", "4: `vertex` takes 3"),
            (
                "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\n",
                "5: a facet needs 3",
            ),
            ("solid\nfacet normal 0 0 1\nouter loop\n\n", "5: file ends where `vertex"),
            ("solid\nfacet normal 0 0 1\nouter loop\n\n  ", "5: file ends where `vertex"),
            (
                "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 q\n",
                "4: expected a number, found `q`",
            ),
            (
                "solid x\nfacet\n outer loop\n vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
                 endloop\nendsolid\n",
                "8: expected `endfacet`",
            ),
            ("solid x\nendsolid x\njunk\n", "3: expected `solid` or the end"),
            ("solid x\nloop\n", "2: expected `facet normal"),
        ];
        for (src, needle) in cases {
            let e = both(src.as_bytes()).unwrap_err().to_string();
            assert!(
                e.starts_with(&format!("t.stl:{needle}")),
                "{e:?} should start with {needle:?}"
            );
        }
        // A byte no ASCII STL has, in the first 512: the complaint is the binary size.
        let e = both(b"\n\n  solid x\n\xff\n").unwrap_err().to_string();
        assert!(e.starts_with("t.stl: byte 14: file ends after 14 bytes"), "{e}");
        assert!(e.ends_with("(it starts with `solid` but is not ASCII STL either)"), "{e}");
        let e = both(&[b"solid x", &[b'\n'; 600][..], b"\xff\n"].concat()).unwrap_err();
        assert_eq!(e.to_string(), "t.stl:601: not valid UTF-8");
    }

    /// Lines end at LF, CR LF or a CR alone (classic Mac OS files), as the first line end
    /// decides, in both readers whatever their buffer (a CR LF split across two fills is one
    /// line end): the same mesh, and errors name the same lines. In a file of LF lines a CR
    /// elsewhere stays whitespace, as it was.
    #[test]
    fn lines_end_at_lf_cr_lf_or_cr() {
        let lf = both(CUBE_CORNER.as_bytes()).unwrap();
        for end in ["\r\n", "\r"] {
            let text = CUBE_CORNER.replace('\n', end);
            assert_eq!(both(text.as_bytes()).unwrap(), lf, "{end:?}");
            let e = both(format!("solid x{end}{end}facet{end}vertex{end}").as_bytes()).unwrap_err();
            assert!(e.to_string().starts_with("t.stl:4: expected `outer loop`"), "{end:?}: {e}");
        }
        let stray = CUBE_CORNER.replace("vertex 1 1 0", "vertex 1\r1\r 0");
        assert_eq!(both(stray.as_bytes()).unwrap(), lf);
        let stray = CUBE_CORNER.replace('\n', "\r\n").replace("vertex 1 1 0", "vertex 1\r1 0");
        assert_eq!(both(stray.as_bytes()).unwrap(), lf);
        // A file of CR lines: an LF is whitespace in it, and its first line decided so.
        let e = both(b"solid x\r\rfacet\n\rvertex\r").unwrap_err();
        assert!(e.to_string().starts_with("t.stl:4: expected `outer loop`"), "{e}");
    }

    #[test]
    fn ascii_after_a_byte_order_mark() {
        // Editors on Windows may begin a text file with a UTF-8 byte order mark; such a file
        // had been read as binary ("the header declares 1818521189 triangles").
        for pad in ["", "\n  "] {
            let ascii = format!("{pad}\u{feff}{CUBE_CORNER}");
            let m = both(ascii.as_bytes()).unwrap();
            assert_eq!(m.triangles.len(), 2, "{pad:?}");
        }
        // The mark alone, before whitespace, is no `solid`: binary, as any other first word.
        let e = both(format!("\u{feff} {CUBE_CORNER}").as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("t.stl: byte 80: the header declares"), "{e}");
    }

    /// Whitespace before the first word, past the buffer and the head: the first word is
    /// still found, and the lines are numbered from the start.
    #[test]
    fn first_word_after_long_whitespace() {
        let pad = " \n\t\r".repeat(300);
        let ascii = format!("{pad}{CUBE_CORNER}");
        let m = both(ascii.as_bytes()).unwrap();
        assert_eq!(m.triangles.len(), 2);
        let e = both(format!("{pad}solid\nfacet\nvertex\n").as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("t.stl:303: expected `outer loop`"), "{e}");
        // Not `solid`: binary, counted from the whitespace at byte 80.
        let e = both(format!("{pad}solidx").as_bytes()).unwrap_err();
        assert!(e.to_string().starts_with("t.stl: byte 80: the header declares"), "{e}");
        for empty in ["", " ", "\n\n"] {
            let e = both(empty.as_bytes()).unwrap_err().to_string();
            let len = empty.len();
            assert!(e.starts_with(&format!("t.stl: byte {len}: file ends after {len} bytes")));
        }
    }

    /// The size the metadata gives is corrected by what is read: a file that ends within the
    /// head has the length read (a small file under /sys), one that goes on past the size is
    /// counted (files under /proc report 0). A larger binary file that is shorter or longer
    /// than its stated size fails at the byte where that shows.
    #[test]
    fn wrong_sizes() {
        let mut rng = SmallRng::seed_from_u64(3);
        for _ in 0..300 {
            let bytes = random_stl(&mut rng);
            let reference = parse(&bytes, Path::new("t.stl"));
            let capacity = rng.random_range(1..1000);
            assert!(same(&reference, &streamed(&bytes, capacity, 0)));
            if bytes.len() < HEAD {
                let size = rng.random_range(0..100_000);
                assert!(same(&reference, &streamed(&bytes, capacity, size)));
            }
        }
        let header = |count: u32| {
            let mut b = b"solid but binary".to_vec();
            b.resize(80, b' ');
            b.extend_from_slice(&count.to_le_bytes());
            b
        };
        let mut b = header(20);
        b.resize(84 + 50 * 20, 0);
        let len = b.len() as u64;
        assert_eq!(both(&b).unwrap().triangles.len(), 20);
        b.truncate(84 + 50 * 15 + 7);
        let e = streamed(&b, 64, len).unwrap_err().to_string();
        assert_eq!(e, "t.stl: byte 834: the file ends before its stated size of 1084 bytes");
        b.resize(len as usize + 3, 0);
        let e = streamed(&b, 64, len).unwrap_err().to_string();
        assert_eq!(e, "t.stl: byte 1084: the file goes on past its stated size of 1084 bytes");
    }

    /// A random number as an ASCII STL writes it: mostly few distinct values (so corners
    /// weld, `-0` among them), sometimes long, exponent, non-finite or not a number.
    fn number(rng: &mut SmallRng) -> String {
        match rng.random_range(0..400) {
            0 => "nan".into(),
            1 => "-inf".into(),
            2 => "1e39".into(),
            3 => "x".into(),
            4 => format!("{:e}", rng.random::<f32>()),
            5..=59 => format!("{}", rng.random_range(-1.0f32..1.0)),
            60..=99 => "-0".into(),
            _ => format!("{}", rng.random_range(-2..3)),
        }
    }

    /// A keyword in a random case.
    fn keyword(rng: &mut SmallRng, k: &str) -> String {
        match rng.random_range(0..6) {
            0 => k.to_uppercase(),
            1 => k.chars().map(|c| if rng.random() { c.to_ascii_uppercase() } else { c }).collect(),
            _ => k.to_string(),
        }
    }

    /// A random ASCII STL, usually well formed: several solids, facets with and without a
    /// normal, polygons, blank and indented lines, CRLF, leading whitespace, no final LF.
    fn random_ascii(rng: &mut SmallRng) -> Vec<u8> {
        let mut s = String::new();
        if rng.random_bool(0.1) {
            s += &" \n".repeat(rng.random_range(0..400));
        }
        let eol = if rng.random_bool(0.2) { "\r\n" } else { "\n" };
        for _ in 0..rng.random_range(1..3) {
            s += &format!("{} name{eol}", keyword(rng, "solid"));
            for _ in 0..rng.random_range(0..10) {
                s += &keyword(rng, "facet");
                if rng.random_bool(0.8) {
                    s += &format!(" {} 0 0 1", keyword(rng, "normal"));
                }
                s += &format!("{eol}  {} {}{eol}", keyword(rng, "outer"), keyword(rng, "loop"));
                let n = [3, 3, 3, 3, 3, 4, 5, 6, 2][rng.random_range(0..9)];
                for _ in 0..n {
                    let [x, y, z] = [(); 3].map(|()| number(rng));
                    s += &format!("    {} {x} {y} {z}{eol}", keyword(rng, "vertex"));
                }
                s +=
                    &format!("  {}{eol}{}{eol}", keyword(rng, "endloop"), keyword(rng, "endfacet"));
                if rng.random_bool(0.1) {
                    s += &format!("{eol} \t{eol}");
                }
            }
            s += &format!("{} name{eol}", keyword(rng, "endsolid"));
        }
        if rng.random_bool(0.2) {
            s.truncate(s.trim_end().len());
        }
        s.into_bytes()
    }

    /// A random binary STL: a `solid` header or another, coordinates welding, the odd
    /// non-finite one, a count that is sometimes wrong, sometimes cut short or lengthened.
    fn random_binary(rng: &mut SmallRng) -> Vec<u8> {
        let mut b = match rng.random_range(0..3) {
            0 => b"solid binary".to_vec(),
            1 => (0..80).map(|_| rng.random()).collect(),
            _ => Vec::new(),
        };
        b.resize(80, b' ');
        let count = rng.random_range(0..30u32);
        let declared = if rng.random_bool(0.1) { rng.random_range(0..40) } else { count };
        b.extend_from_slice(&declared.to_le_bytes());
        for _ in 0..count {
            for k in 0..12 {
                let c = match rng.random_range(0..200) {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    _ if k < 3 => rng.random(),
                    _ => [0.0, -0.0, 1.0, 0.5, -2.0][rng.random_range(0..5)],
                };
                b.extend_from_slice(&c.to_le_bytes());
            }
            b.extend_from_slice(&[0, 0]);
        }
        match rng.random_range(0..10) {
            0 => b.truncate(rng.random_range(0..=b.len())),
            1 => b.extend((0..rng.random_range(1..60)).map(|_| rng.random::<u8>())),
            _ => {}
        }
        b
    }

    fn random_stl(rng: &mut SmallRng) -> Vec<u8> {
        if rng.random_bool(0.5) { random_ascii(rng) } else { random_binary(rng) }
    }

    /// A few random edits: flipped and replaced bytes, cuts, deletions, insertions of
    /// keywords, numbers and line ends, a rewritten triangle count.
    fn mutate(rng: &mut SmallRng, mut b: Vec<u8>) -> Vec<u8> {
        const TOKENS: &[&[u8]] = &[
            b"solid",
            b"endsolid",
            b"facet",
            b"normal",
            b"outer loop",
            b"vertex",
            b"endloop",
            b"endfacet",
            b"\n",
            b"\r\n",
            b" ",
            b"nan",
            b"1e39",
            b"-0",
            b"\xff",
            b"\0",
        ];
        for _ in 0..rng.random_range(1..4) {
            let len = b.len();
            let at = rng.random_range(0..=len);
            match rng.random_range(0..7) {
                0 if at < len => b[at] ^= 1 << rng.random_range(0..8),
                1 if at < len => b[at] = rng.random(),
                2 => b.truncate(at),
                3 => {
                    let end = (at + rng.random_range(1..20)).min(len);
                    b.drain(at..end);
                }
                4 => {
                    let t = TOKENS[rng.random_range(0..TOKENS.len())];
                    b.splice(at..at, t.iter().copied());
                }
                5 if len >= 84 => {
                    let count = (len as u32).saturating_sub(84) / 50 + rng.random_range(0..2);
                    b[80..84].copy_from_slice(&count.to_le_bytes());
                }
                _ => {}
            }
        }
        b
    }

    /// The streamed reader gives what the reference gives, mesh or error, on random and
    /// mutated files, through buffers of 1 byte to 64 KB.
    #[test]
    fn streamed_is_the_reference() {
        let mut rng = SmallRng::seed_from_u64(11);
        let mut seen = HashMap::new();
        for round in 0..6000 {
            let mut bytes = random_stl(&mut rng);
            if round % 2 == 1 {
                bytes = mutate(&mut rng, bytes);
            }
            let reference = parse(&bytes, Path::new("t.stl"));
            let capacity = [1, 2, 3, 50, 64, 511, 4096, READ_BUFFER][rng.random_range(0..8)];
            let streamed = streamed(&bytes, capacity, bytes.len() as u64);
            assert!(
                same(&reference, &streamed),
                "{reference:?}\n{streamed:?}\n{:?}",
                bytes.escape_ascii().to_string()
            );
            let what = match &reference {
                Ok(m) if m.triangles.len() > m.polygon_count => "polygons",
                Ok(m) if m.positions.len() < 3 * m.triangles.len() => "welded",
                Ok(_) => "accepted",
                Err(Error::Parse { line: 0, message, .. }) if message.contains("either") => {
                    "solid header, wrong size"
                }
                Err(Error::Parse { line: 0, .. }) => "binary error",
                Err(_) => "ASCII error",
            };
            *seen.entry(what).or_insert(0) += 1;
        }
        for what in [
            "polygons",
            "welded",
            "accepted",
            "solid header, wrong size",
            "binary error",
            "ASCII error",
        ] {
            assert!(seen.get(what).is_some_and(|&n| n > 50), "{seen:?}");
        }
    }

    /// [`read`] from files on disk gives what [`parse`] gives on their bytes.
    #[test]
    fn read_from_disk_is_the_reference() {
        let dir = std::env::temp_dir().join(format!("trirast-stl-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut rng = SmallRng::seed_from_u64(5);
        for i in 0..40 {
            let bytes = random_stl(&mut rng);
            let file = dir.join(format!("{i}.stl"));
            std::fs::write(&file, &bytes).unwrap();
            let reference = parse(&bytes, &file);
            let read = read(&file);
            assert!(same(&reference, &read), "{reference:?}\n{read:?}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
