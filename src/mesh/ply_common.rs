//! What the two PLY readers share: [`super::ply`] (meshes) and [`crate::splat::cloud`] (point
//! clouds) drive the `ply-rs-bw` crate the same way and differ only in what they keep of an
//! element's values, so the driving is here, once.
//!
//! The file is read as it is parsed, through a buffer ([`Source`]), not whole into memory
//! first: the bytes of a binary mesh had been as large as the mesh made of them, those of an
//! ASCII one nearly three times (`trirast info` on a 1 M-triangle grid: peak RSS 46.9 -> 29.1
//! MiB binary, 78.9 -> 29.1 MiB ASCII, of which the mesh is 17.2 and the process 10). The
//! crate's header parser reports the header line of a problem; the header, which the source
//! records as the crate reads it, is then scanned again for duplicate element or property
//! names (the crate would silently merge them and misread the body). ASCII elements are
//! handed to the crate line by line (we count the lines), and binary elements are read from
//! the source, whose count of bytes read gives the offset of the element that failed; the
//! crate's grammar takes digits only, so a line with non-finite values written as words (PCL
//! writes `nan` normals) is read by [`with_non_finite`] as a binary file's values. The
//! crate's messages are shortened and completed with what was expected (the element's
//! declared layout). Reservations are capped by what the rest of the file can hold, so
//! `element vertex 4000000000` in a small file allocates nothing and fails where the data
//! ends.
//!
//! A reader supplies its [`Fields`] (what it keeps of one element's properties) and a [`Sink`]
//! (what it does with each element), and words the few errors that differ between the two.

use std::collections::HashMap;
use std::io::{self, BufRead, Cursor, Read};
use std::path::Path;

use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use crate::error::Error;
use crate::input::ReadProgress;

/// Where an error is: a 1-based line (header, ASCII body) or a byte offset (binary body).
#[derive(Clone, Copy, Debug)]
pub(crate) enum At {
    /// A 1-based line of the header or of an ASCII body.
    Line(usize),
    /// The byte offset where the failing binary element starts.
    Byte(u64),
}

/// An error before it names its file: where it is, and what is wrong.
pub(crate) type Fail = (At, String);

/// Puts `path` before each of `warnings` (`path: ...`), as the warnings of reading a file read
/// (the body's own, [`Ply::read_body`]'s, know no path).
pub(crate) fn name_warnings(warnings: &mut [String], path: &Path) {
    for warning in warnings {
        *warning = format!("{}: {warning}", path.display());
    }
}

/// `fail` as [`Error::Parse`] naming `path`; a byte offset goes in the message as `byte N:`,
/// with `line: 0`.
pub(crate) fn parse_error(path: &Path, (at, message): Fail) -> Error {
    match at {
        At::Line(line) => Error::Parse { path: path.to_path_buf(), line, message },
        At::Byte(offset) => Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: format!("byte {offset}: {message}"),
        },
    }
}

/// Reads the PLY file `path` with `parse`, from the file as it goes (see [`Source`]), telling
/// `report` how far it has read ([`ReadProgress`]).
///
/// # Errors
/// As [`crate::input::open`]; [`Error::Io`] when reading fails; else what `parse` returns, as
/// [`parse_error`] words it.
pub(crate) fn read_file<'a, T, P>(
    path: &Path,
    report: &'a dyn Fn(u64),
    parse: P,
) -> Result<T, Error>
where
    P: FnOnce(&mut Source<ReadProgress<'a, std::fs::File>>, u64) -> Result<T, Fail>,
{
    let file = crate::input::open(path)?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    parse_with(ReadProgress::new(file, report), len, path, parse)
}

/// Parses `len` bytes from `reader` with `parse`, naming `path` in errors: an I/O error the
/// source met as [`Error::Io`] (whatever the parser made of it), others by [`parse_error`].
pub(crate) fn parse_with<R: Read, T, P>(
    reader: R,
    len: u64,
    path: &Path,
    parse: P,
) -> Result<T, Error>
where
    P: FnOnce(&mut Source<R>, u64) -> Result<T, Fail>,
{
    let mut source = Source {
        inner: reader,
        buf: vec![0; READ_BUFFER],
        pos: 0,
        end: 0,
        base: 0,
        header: None,
        io_error: None,
    };
    parse(&mut source, len).map_err(|fail| match source.io_error.take() {
        Some(e) => Error::io(path, e),
        None => parse_error(path, fail),
    })
}

/// Bytes read at a time (at least: an element that does not fit grows the buffer).
const READ_BUFFER: usize = 1 << 16;

/// A PLY file being read: a buffered reader (as `std::io::BufReader`) that counts the bytes
/// consumed (the offset a binary element's error names), records them while the header is
/// read (its lines are quoted in errors and scanned again), and keeps the first I/O error it
/// meets, which the crate would otherwise report as a malformed file. Binary elements are read
/// from its buffer as from memory ([`Source::buffered`], [`Source::read_more`]): the crate
/// reads each value by itself, and through `Read` a binary mesh took 11-14% longer than from
/// a file read whole (from the buffer, 6-8%).
pub(crate) struct Source<R> {
    inner: R,
    buf: Vec<u8>,
    /// `buf[pos..end]` is read and not yet consumed.
    pos: usize,
    end: usize,
    /// Bytes consumed before `buf[0]`.
    base: u64,
    /// The bytes consumed, while the header is read.
    header: Option<Vec<u8>>,
    io_error: Option<io::Error>,
}

impl<R: Read> Source<R> {
    /// Bytes consumed from the start of the file.
    fn consumed(&self) -> u64 {
        self.base + self.pos as u64
    }

    /// The bytes read and not yet consumed.
    fn buffered(&self) -> &[u8] {
        &self.buf[self.pos..self.end]
    }

    /// Reads more of the file after [`Source::buffered`], which stays (moved to the front of
    /// the buffer, which doubles when they fill it), until the buffer is full: an element cut
    /// short is read again from its start, so reads that return little would make that
    /// quadratic. False at the end of the file.
    fn read_more(&mut self) -> io::Result<bool> {
        self.buf.copy_within(self.pos..self.end, 0);
        self.base += self.pos as u64;
        (self.pos, self.end) = (0, self.end - self.pos);
        if self.end == self.buf.len() {
            self.buf.resize(2 * self.buf.len().max(1), 0);
        }
        let before = self.end;
        while self.end < self.buf.len() {
            match self.inner.read(&mut self.buf[self.end..]) {
                Ok(0) => break,
                Ok(n) => self.end += n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => {
                    let kind = e.kind();
                    self.io_error.get_or_insert(e);
                    return Err(kind.into());
                }
            }
        }
        Ok(self.end > before)
    }

    /// The next segment of the rest of the file split at `\n`, as `<[u8]>::split` splits it
    /// (the last segment is empty when the file ends with `\n`), in `line`; false after the
    /// last. `ended` is set once the last has been returned.
    fn next_segment(&mut self, line: &mut Vec<u8>, ended: &mut bool) -> io::Result<bool> {
        if *ended {
            return Ok(false);
        }
        line.clear();
        self.read_until(b'\n', line)?;
        if line.last() == Some(&b'\n') {
            line.pop();
        } else {
            *ended = true;
        }
        Ok(true)
    }
}

impl<R: Read> Read for Source<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let buf = self.fill_buf()?;
        let n = buf.len().min(out.len());
        out[..n].copy_from_slice(&buf[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: Read> BufRead for Source<R> {
    #[inline]
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.pos == self.end {
            self.base += self.end as u64;
            (self.pos, self.end) = (0, 0);
            self.end = loop {
                match self.inner.read(&mut self.buf) {
                    Ok(n) => break n,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                    Err(e) => {
                        let kind = e.kind();
                        self.io_error.get_or_insert(e);
                        return Err(kind.into());
                    }
                }
            };
        }
        Ok(&self.buf[self.pos..self.end])
    }

    #[inline]
    fn consume(&mut self, amount: usize) {
        let amount = amount.min(self.end - self.pos);
        if let Some(header) = &mut self.header {
            header.extend_from_slice(&self.buf[self.pos..self.pos + amount]);
        }
        self.pos += amount;
    }
}

/// The colour property spellings both readers accept, by channel (red, green, blue, alpha).
pub(crate) const COLOR_NAMES: [[&str; 3]; 4] = [
    ["red", "r", "diffuse_red"],
    ["green", "g", "diffuse_green"],
    ["blue", "b", "diffuse_blue"],
    ["alpha", "a", "diffuse_alpha"],
];

/// The first value slots of both readers, from slot [`X`]: the position, then the normal.
pub(crate) const POSITION_NORMAL: [&str; 6] = ["x", "y", "z", "nx", "ny", "nz"];
/// The slot of `x` (then `y`, `z`) in both readers.
pub(crate) const X: usize = 0;
/// The slot of `nx` (then `ny`, `nz`) in both readers.
pub(crate) const NX: usize = 3;
/// The slot of the first colour channel in both readers, after [`POSITION_NORMAL`].
pub(crate) const RED: usize = 6;

/// What a reader keeps of one element's properties; `Default` is an element before any of
/// them is read.
pub(crate) trait Fields: Default {
    /// Takes the value of property `name`; false when the reader does not use it (or not with
    /// that type), so that it is skipped.
    fn set(&mut self, name: &str, property: Property) -> bool;
}

/// One element as the crate delivers it: the reader's [`Fields`], and how many values its
/// lists had (to check an ASCII line's length).
pub(crate) struct Row<F> {
    fields: F,
    list_values: usize,
}

impl<F: Fields> PropertyAccess for Row<F> {
    fn new() -> Self {
        Self { fields: F::default(), list_values: 0 }
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        self.list_values += list_len(&property);
        if self.fields.set(name, property) {
            PropertyAccessResult::Set
        } else {
            PropertyAccessResult::Ignored
        }
    }
}

fn list_len(p: &Property) -> usize {
    match p {
        Property::ListChar(v) => v.len(),
        Property::ListUChar(v) => v.len(),
        Property::ListShort(v) => v.len(),
        Property::ListUShort(v) => v.len(),
        Property::ListInt(v) => v.len(),
        Property::ListUInt(v) => v.len(),
        Property::ListFloat(v) => v.len(),
        Property::ListDouble(v) => v.len(),
        _ => 0,
    }
}

/// A scalar property as `f32` (`None` for a list): what both readers make of positions and
/// normals.
#[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
pub(crate) fn scalar(p: &Property) -> Option<f32> {
    Some(match *p {
        Property::Char(v) => f32::from(v),
        Property::UChar(v) => f32::from(v),
        Property::Short(v) => f32::from(v),
        Property::UShort(v) => f32::from(v),
        Property::Int(v) => v as f32,
        Property::UInt(v) => v as f32,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => return None,
    })
}

/// What a reader does with the elements of the body.
pub(crate) trait Sink {
    /// What the reader keeps of one element.
    type Fields: Fields;
    /// The last element to read, when the elements after it are of no use (they are then not
    /// read at all, so their errors go unreported); `None` reads the whole body.
    const LAST: Option<&'static str> = None;
    /// Whether the `\r`s ending an ASCII line are dropped before the crate parses it (the crate
    /// itself accepts one, not two).
    const STRIP_CR: bool = false;

    /// Starts element `def`; `capacity` is how many of its rows the rest of the file can hold,
    /// which caps any reservation.
    fn start(&mut self, def: &ElementDef, capacity: usize);

    /// Takes row `index` of the element started last, found at `at`.
    fn add(&mut self, row: Self::Fields, index: usize, at: At) -> Result<(), Fail>;
}

/// An element's declaration: its name, its header line and those of its properties.
struct Declared {
    name: String,
    line: usize,
    properties: HashMap<String, usize>,
}

/// A PLY file whose header has been read, ready for its body to be read into a [`Sink`].
pub(crate) struct Ply<F: Fields> {
    /// Bytes in the whole file.
    len: u64,
    parser: Parser<Row<F>>,
    /// The header as the crate reads it.
    pub(crate) header: Header,
    /// Where each element and its properties are declared, in header order.
    declared: Vec<Declared>,
    body_start: u64,
    /// The line of `end_header`.
    end_line: usize,
}

impl<F: Fields> Ply<F> {
    /// Reads and checks the header of the file `source` reads, `len` bytes in all.
    /// `property_twice(element, property, first_line)` words the error for a property declared
    /// twice, which each reader words its own way.
    pub(crate) fn read_header<R: Read>(
        source: &mut Source<R>,
        len: u64,
        property_twice: fn(&str, &str, usize) -> String,
    ) -> Result<Self, Fail> {
        // Checked before the crate reads a first line, which in a file of another kind may
        // be the whole file.
        let io = |e: io::Error| (At::Line(1), e.to_string());
        while source.buffered().len() < 3 && source.read_more().map_err(io)? {}
        if !source.buffered().starts_with(b"ply") {
            return Err((At::Line(1), "not a PLY file: expected `ply` on the first line".into()));
        }
        let parser = Parser::<Row<F>>::new();
        source.header = Some(Vec::new());
        let mut reader = Reader::new(&mut *source);
        let header = parser.read_header(&mut reader);
        let line = reader.line();
        let header_bytes = source.header.take().unwrap_or_default();
        let header = header.map_err(|e| header_error(&e, line, &header_bytes))?;
        let body_start = source.consumed();
        let declared = scan_header(&header_bytes, property_twice)?;
        let end_line = header_bytes.iter().filter(|&&b| b == b'\n').count();
        Ok(Self { len, parser, header, declared, body_start, end_line })
    }

    /// The header line of element `name` (that of `end_header` when there is none).
    pub(crate) fn element_line(&self, name: &str) -> usize {
        self.declared(name).map_or(self.end_line, |d| d.line)
    }

    /// The header line of property `property` of `element` (that of the element when there is
    /// no such property).
    pub(crate) fn property_line(&self, element: &str, property: &str) -> usize {
        let line = self.declared(element).and_then(|d| d.properties.get(property));
        line.copied().unwrap_or_else(|| self.element_line(element))
    }

    /// The declaration of `element` (a few lookups a file: a scan is enough).
    fn declared(&self, element: &str) -> Option<&Declared> {
        self.declared.iter().find(|d| d.name == element)
    }

    /// The `vertex` element, with the checks both readers make: it is there (else the error
    /// `missing`, at `end_header`), the properties the reader `uses` are scalars (a list is
    /// reported at `list_line(property)`), and it has `x y z`.
    pub(crate) fn vertex(
        &self,
        missing: &str,
        uses: impl Fn(&str) -> bool,
        list_line: impl Fn(&str) -> usize,
    ) -> Result<&ElementDef, Fail> {
        let Some(vertex) = self.header.elements.get("vertex") else {
            return Err((At::Line(self.end_line), missing.into()));
        };
        for p in vertex.properties.values() {
            if uses(&p.name) && matches!(p.data_type, PropertyType::List(..)) {
                return Err((
                    At::Line(list_line(&p.name)),
                    format!("`vertex` property `{}` must be a scalar, not a list", p.name),
                ));
            }
        }
        for name in ["x", "y", "z"] {
            let property = vertex.properties.get(name);
            if !property.is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(_))) {
                return Err((
                    At::Line(self.element_line("vertex")),
                    format!("element `vertex` has no property `{name}`"),
                ));
            }
        }
        Ok(vertex)
    }

    /// Reads the body from `source` (where [`Ply::read_header`] left it) into `sink`, up to
    /// [`Sink::LAST`]; elements without properties take no room in the body and are passed
    /// over.
    pub(crate) fn read_body<R: Read, S: Sink<Fields = F>>(
        &self,
        source: &mut Source<R>,
        sink: &mut S,
    ) -> Result<Option<String>, Fail> {
        let elements = self.header.elements.values();
        let last = S::LAST.and_then(|name| elements.clone().position(|d| d.name == name));
        let count = last.map_or(usize::MAX, |k| k + 1);
        let defs = elements.clone().take(count).filter(|d| !d.properties.is_empty());
        let ascii = self.header.encoding == Encoding::Ascii;
        if ascii {
            self.feed(defs, sink, self.ascii_rows(source, S::STRIP_CR))?;
        } else {
            self.feed(defs, sink, self.binary_rows(source))?;
        }
        if count < elements.len() {
            return Ok(None);
        }
        self.tail(source, ascii)
    }

    /// A warning when the file goes on after the last element the header declares (an ASCII
    /// file with more than blank lines): the header's counts are likely too small, and what
    /// they leave out would otherwise be dropped without a word.
    fn tail<R: Read>(&self, source: &mut Source<R>, ascii: bool) -> Result<Option<String>, Fail> {
        let end = source.consumed();
        let io = |e: io::Error| (At::Byte(end), e.to_string());
        let data = if ascii {
            // Only up to the first byte that is not blank is read.
            loop {
                let buf = source.fill_buf().map_err(io)?;
                if buf.is_empty() {
                    break false;
                }
                if !buf.iter().all(u8::is_ascii_whitespace) {
                    break true;
                }
                let n = buf.len();
                source.consume(n);
            }
        } else {
            !source.fill_buf().map_err(io)?.is_empty()
        };
        Ok(data.then(|| {
            let counts: Vec<String> = (self.header.elements.values())
                .map(|d| format!("{} `{}`", d.count, d.name))
                .collect();
            // The file's size may be unknown (0 from /proc) or wrong: then no count.
            let left = self.len.checked_sub(end).filter(|&n| n > 0);
            format!(
                "{} after the elements the header declares ({}) are ignored; the header's \
                 counts may be too small",
                left.map_or("the bytes".to_string(), |n| format!("{n} bytes")),
                counts.join(", ")
            )
        }))
    }

    /// How many rows of `def` the rest of the file can hold.
    fn capacity(&self, def: &ElementDef) -> usize {
        capacity(def, self.header.encoding, self.len.saturating_sub(self.body_start))
    }

    /// Hands the rows of `defs` to `sink`, each read by `read(def, index)`, which also says
    /// where the row is.
    fn feed<'h, S: Sink<Fields = F>>(
        &self,
        defs: impl Iterator<Item = &'h ElementDef>,
        sink: &mut S,
        mut read: impl FnMut(&ElementDef, usize) -> Result<(Row<F>, At), Fail>,
    ) -> Result<(), Fail> {
        for def in defs {
            sink.start(def, self.capacity(def));
            for i in 0..def.count {
                let (row, at) = read(def, i)?;
                sink.add(row.fields, i, at)?;
            }
        }
        Ok(())
    }

    /// Reads the rows of an ASCII body from `source`, one per non-blank line, counting from
    /// the line after `end_header`; `strip_cr` as [`Sink::STRIP_CR`] says.
    fn ascii_rows<'s, R: Read>(
        &'s self,
        source: &'s mut Source<R>,
        strip_cr: bool,
    ) -> impl FnMut(&ElementDef, usize) -> Result<(Row<F>, At), Fail> + 's {
        let first_line = self.end_line + 1;
        // The line the next segment is on, and whether the last one has been read.
        let (mut next_line, mut ended) = (first_line, false);
        let mut raw = Vec::new();
        let mut last_line = first_line;
        move |def: &ElementDef, i: usize| {
            let line = loop {
                let at = At::Line(next_line);
                let more =
                    source.next_segment(&mut raw, &mut ended).map_err(|e| (at, e.to_string()))?;
                if !more {
                    // `next_line` is past the last segment, the line the file ends on.
                    return Err((
                        At::Line((next_line - 1).max(last_line)),
                        format!(
                            "file ends after {i} of the {} `{}` elements the header declares",
                            def.count, def.name
                        ),
                    ));
                }
                next_line += 1;
                if !raw.iter().all(u8::is_ascii_whitespace) {
                    break next_line - 1;
                }
            };
            last_line = line;
            let at = At::Line(line);
            let text =
                std::str::from_utf8(&raw).map_err(|_| (at, "not valid UTF-8".to_string()))?;
            let text = if strip_cr { text.trim_end_matches('\r') } else { text };
            // A letter other than an exponent's: the line may hold non-finite words, which
            // the crate's grammar refuses (after parsing the line twice and formatting an
            // error naming it: PCL's clouds have them on many lines).
            let words = text.bytes().any(|b| b.is_ascii_alphabetic() && !matches!(b, b'e' | b'E'));
            let parsed = match words.then(|| with_non_finite(&self.parser, text, def)).flatten() {
                Some(row) => Ok(row),
                None => self.parser.read_ascii_element(text, def),
            };
            let row = parsed.map_err(|e| {
                let found: String = text.trim().chars().take(60).collect();
                (
                    at,
                    format!(
                        "`{}` {i}: {}; expected {}, found `{found}`",
                        def.name,
                        crate_message(&e),
                        describe(def)
                    ),
                )
            })?;
            // The crate ignores values past the declared ones; a longer line means the header
            // does not describe the data.
            let values = text.split_ascii_whitespace().count();
            let declared = def.properties.len() + row.list_values;
            if values != declared {
                return Err((
                    at,
                    format!(
                        "`{}` {i}: found {values} values, but the header declares {declared} \
                         ({})",
                        def.name,
                        describe(def)
                    ),
                ));
            }
            Ok((row, at))
        }
    }

    /// Reads the rows of a binary body from `source`, whose count of bytes read names the byte
    /// where the failing row starts.
    fn binary_rows<'s, R: Read>(
        &'s self,
        source: &'s mut Source<R>,
    ) -> impl FnMut(&ElementDef, usize) -> Result<(Row<F>, At), Fail> + 's {
        let len = self.len;
        let big = self.header.encoding == Encoding::BinaryBigEndian;
        move |def: &ElementDef, i: usize| {
            let at = At::Byte(source.consumed());
            // From the bytes buffered, as from a file in memory; an element they end inside
            // is read again once more are (reading has no effect but the row it returns).
            let row = loop {
                let mut cursor = Cursor::new(source.buffered());
                let row = if big {
                    self.parser.read_big_endian_element(&mut cursor, def)
                } else {
                    self.parser.read_little_endian_element(&mut cursor, def)
                };
                let read = usize::try_from(cursor.position()).unwrap_or(usize::MAX);
                match row {
                    Ok(row) => {
                        source.consume(read);
                        break Ok(row);
                    }
                    Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
                        match source.read_more() {
                            Ok(true) => {}
                            Ok(false) => break Err(e),
                            // Reported as the I/O error it is (see `parse_with`).
                            Err(e) => return Err((at, e.to_string())),
                        }
                    }
                    Err(e) => break Err(e),
                }
            };
            let row = row.map_err(|e| {
                let message = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    format!(
                        "file ends inside `{}` {i} of {} (the file has {} bytes); expected {}",
                        def.name,
                        def.count,
                        len,
                        describe(def)
                    )
                } else {
                    format!("`{}` {i}: {}; expected {}", def.name, crate_message(&e), describe(def))
                };
                (at, message)
            })?;
            Ok((row, at))
        }
    }
}

/// Turns a header error from the crate into one naming the line (the reader's `line` when the
/// error does not say), with a readable message; `bytes` are those the crate read. The crate
/// counts one line past a last line without `\n` (`ply\ncomment` "ends at line 3"), so the line
/// is capped at the one the header's bytes end on.
fn header_error(e: &ParseError, line: usize, bytes: &[u8]) -> Fail {
    let last = bytes.split(|&b| b == b'\n').count();
    let line = e.line().unwrap_or(line).clamp(1, last);
    let text = bytes.split(|&b| b == b'\n').nth(line - 1).unwrap_or(b"").trim_ascii();
    let text = super::shown_at_most(text, 80).0;
    let first = e.to_string();
    let first = first.split("\n\t").next().unwrap_or("").trim();
    let crate_line = e.line().map(|l| format!("Line {l}: ")).unwrap_or_default();
    let first = first.strip_prefix(&crate_line).unwrap_or(first);
    let message = match first {
        "Couldn't parse line." => format!(
            "expected a PLY header line (`format ascii|binary_little_endian|binary_big_endian \
             1.0`, `comment ...`, `obj_info ...`, `element NAME COUNT`, `property TYPE NAME`, \
             `property list COUNT_TYPE TYPE NAME` or `end_header`), found `{text}`"
        ),
        "Invalid element" => format!("element count too large in `{text}`"),
        "No format line found." => "the header has no `format` line".into(),
        m if m.starts_with("Unexpected end of file while reading header") => {
            "file ends before `end_header`".into()
        }
        m if m.contains("UTF-8") => "header line is not valid text".into(),
        m => format!("{m} (found `{text}`)"),
    };
    (At::Line(line), message)
}

/// Where each element and property is declared; rejects duplicate element or property names,
/// which the crate would merge (so the body would be misread). `property_twice` words the
/// error for a property, as [`Ply::read_header`] says.
fn scan_header(
    header: &[u8],
    property_twice: fn(&str, &str, usize) -> String,
) -> Result<Vec<Declared>, Fail> {
    let mut elements: Vec<Declared> = Vec::new();
    let mut element_lines: HashMap<String, usize> = HashMap::new();
    for (n, raw) in header.split(|&b| b == b'\n').enumerate() {
        let line = n + 1;
        let text = String::from_utf8_lossy(raw);
        let mut tokens = text.split_ascii_whitespace();
        match tokens.next() {
            Some("element") => {
                let name = tokens.next().unwrap_or("").to_string();
                if let Some(first) = element_lines.insert(name.clone(), line) {
                    return Err((
                        At::Line(line),
                        format!("element `{name}` is declared twice (first at line {first})"),
                    ));
                }
                elements.push(Declared { name, line, properties: HashMap::new() });
            }
            // The crate reads any version, but the format has only 1.0: a file of another
            // need not mean what this reader would take it to.
            Some("format") => {
                let version = tokens.nth(1).unwrap_or("");
                if version.split('.').next() != Some("1") {
                    let message = format!("PLY version {version} is not supported (only 1.0)");
                    return Err((At::Line(line), message));
                }
            }
            // The crate has refused a property before any element.
            Some("property") => {
                let Some(element) = elements.last_mut() else { continue };
                let name = tokens.last().unwrap_or("").to_string();
                if let Some(&first) = element.properties.get(&name) {
                    return Err((At::Line(line), property_twice(&element.name, &name, first)));
                }
                element.properties.insert(name, line);
            }
            _ => {}
        }
    }
    Ok(elements)
}

fn scalar_size(t: &ScalarType) -> u64 {
    match t {
        ScalarType::Char | ScalarType::UChar => 1,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    }
}

/// The fewest bytes an element can take in the body.
fn min_size(def: &ElementDef, encoding: Encoding) -> u64 {
    if encoding == Encoding::Ascii {
        // Each value is at least one character and a separator (space or newline).
        return 2 * def.properties.len() as u64;
    }
    def.properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) | PropertyType::List(t, _) => scalar_size(t),
        })
        .sum()
}

/// How many elements of `def` can fit in `available` bytes: caps reservations, so that a header
/// declaring billions of elements allocates nothing before the body runs out.
pub(crate) fn capacity(def: &ElementDef, encoding: Encoding, available: u64) -> usize {
    let fit = available / min_size(def, encoding).max(1) + 1;
    def.count.min(usize::try_from(fit).unwrap_or(usize::MAX))
}

/// Row `text` of `def` when its only values the crate's grammar refuses are non-finite ones
/// written as words (`nan`, `inf`, `-Infinity`, in any case: PCL writes `nan` normals) at
/// `float` or `double` properties of an element without lists: parsed with `0` in place of
/// each word (the separators as they were, so the grammar sees the line otherwise as
/// written), then given those values, as a binary file's would be. `None` otherwise (the
/// crate's error stands).
fn with_non_finite<F: Fields>(
    parser: &Parser<Row<F>>,
    text: &str,
    def: &ElementDef,
) -> Option<Row<F>> {
    if def.properties.values().any(|p| matches!(p.data_type, PropertyType::List(..))) {
        return None;
    }
    let mut words = Vec::new();
    let mut zeroed = String::with_capacity(text.len());
    let mut copied = 0;
    for (i, token) in text.split_ascii_whitespace().enumerate() {
        if token.bytes().any(|b| b.is_ascii_digit()) {
            continue;
        }
        let Some(v) = token.parse::<f64>().ok().filter(|v| !v.is_finite()) else { continue };
        let (name, p) = def.properties.get_index(i)?;
        let property = match p.data_type {
            PropertyType::Scalar(ScalarType::Float) => Property::Float(v as f32),
            PropertyType::Scalar(ScalarType::Double) => Property::Double(v),
            _ => return None,
        };
        words.push((name, property));
        // `token` is a slice of `text`: its offset is the distance between their starts.
        let at = token.as_ptr() as usize - text.as_ptr() as usize;
        zeroed.push_str(&text[copied..at]);
        zeroed.push('0');
        copied = at + token.len();
    }
    if words.is_empty() {
        return None;
    }
    zeroed.push_str(&text[copied..]);
    let mut row = parser.read_ascii_element(&zeroed, def).ok()?;
    for (name, property) in words {
        row.set_property(name, property);
    }
    Some(row)
}

/// The crate's message without its debugging detail.
fn crate_message(e: &ParseError) -> String {
    let text = e.to_string();
    let mut parts = text.split("\n\t");
    let first = parts.next().unwrap_or("").trim();
    let value = parts.find_map(|p| p.strip_prefix("Value: "));
    let first = match first {
        "Couldn't parse element line." => "not a list of numbers",
        "Parse error." => "a value does not fit its type",
        m if m.starts_with("Expected element of type") => "too few values",
        m if m.starts_with("Couldn't parse element at index") => {
            "a list value does not fit its type"
        }
        // A signed count type (`list char ...`) holding a negative count.
        m if m.starts_with("List length cannot be negative") => "the list's length is negative",
        m => m.trim_end_matches('.'),
    };
    match value {
        Some(v) => format!("{first} ({})", v.trim()),
        None => first.to_string(),
    }
}

/// An element's declared layout, as `float x, float y, list uchar int vertex_indices`.
fn describe(def: &ElementDef) -> String {
    let name = |t: &ScalarType| match t {
        ScalarType::Char => "char",
        ScalarType::UChar => "uchar",
        ScalarType::Short => "short",
        ScalarType::UShort => "ushort",
        ScalarType::Int => "int",
        ScalarType::UInt => "uint",
        ScalarType::Float => "float",
        ScalarType::Double => "double",
    };
    let parts: Vec<String> = def
        .properties
        .values()
        .map(|p| match &p.data_type {
            PropertyType::Scalar(t) => format!("{} {}", name(t), p.name),
            PropertyType::List(c, t) => format!("list {} {} {}", name(c), name(t), p.name),
        })
        .collect();
    parts.join(", ")
}
