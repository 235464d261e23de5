//! Point clouds: the splatting pipeline's input, read from PLY or sampled from any mesh.
//!
//! A [`PointCloud`] comes from a scanner's PLY file ([`read_ply`]) or from a triangle mesh
//! ([`sample_mesh`]), and can be saved for later runs ([`write_ply`]).
//!
//! # Reading PLY
//!
//! [`read_ply`] takes ASCII, binary little endian and binary big endian files. The header and
//! the elements are decoded by the `ply-rs-bw` crate, driven one element at a time as
//! [`crate::mesh::ply`] does, so that every error names its position: header lines and ASCII
//! elements by their 1-based line, binary elements by the byte offset where the failing
//! element starts (as [`Error::Parse`] with `line: 0` and a message starting `byte N:`).
//!
//! From the `vertex` element (required) it reads:
//!
//! - `x y z` (required; any scalar type, converted to `f32`). A non-finite position is an
//!   error naming the vertex: it would poison every bounding sphere above it.
//! - `nx ny nz` (all three, or no normals). Normals are normalised on read, so a file with
//!   scaled normals still gives unit normals; a zero normal stays zero (unknown), and so does a
//!   non-finite one (PCL writes `nan` normals for points it could not estimate). A normal that
//!   is already unit to `f32` precision is kept bit for bit, which is what makes
//!   [`write_ply`] -> [`read_ply`] exact.
//! - colours `red green blue` (also `r g b` and `diffuse_red ...`): `uchar` as it is, `ushort`
//!   scaled from 0..65535, other integers clamped to 0..255, `float`/`double` taken as 0..1
//!   (clamped) and rounded to 8 bits. `alpha` is allowed and ignored (splats are opaque).
//! - `radius`: the splat radius in world units, finite and non-negative. `scale` and `size`
//!   are deliberately not read: Gaussian-splat files store per-axis *log* scales under
//!   `scale_0..2`, and `size` means a diameter or a pixel size depending on the tool, so
//!   guessing would give wrong splats silently.
//!
//! Other properties and other elements (`face`, say) are skipped; elements after `vertex` are
//! not read at all, since a point cloud has no use for them. Duplicate element or property
//! names are errors (the crate would merge them and misread the body). Reservations are
//! capped by what the rest of the file can hold, so `element vertex 4000000000` in a small
//! file allocates nothing and fails where the data ends.

use std::io::{BufWriter, Cursor, Write};
use std::path::Path;

use glam::{DVec2, DVec3, Vec2};
use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::color::{linear_to_srgb8, srgb_decode};
use crate::error::Error;
use crate::mesh::{Mesh, unorm8};
use crate::model::MaterialTextures;
use crate::texture::{Filter, Texture, Wrap};

/// Points with optional per-point normals, colours and radii.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, when known.
    pub normals: Option<Vec<[f32; 3]>>,
    /// sRGB-encoded RGB8 colours, when known.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Splat radii, when known (world units).
    pub radii: Option<Vec<f32>>,
}

impl PointCloud {
    /// Number of points.
    #[must_use]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no points (an empty cloud renders nothing and builds an empty tree).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The axis-aligned bounding box `(min, max)` of the positions, for framing a camera; `None`
    /// for an empty cloud, which has no box to frame. NaN coordinates are ignored.
    #[must_use]
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (std::array::from_fn(|a| lo[a].min(p[a])), std::array::from_fn(|a| hi[a].max(p[a])))
        }))
    }

    /// Checks what [`write_ply`] needs: attribute arrays as long as `positions`, and finite
    /// positions (which [`read_ply`] would refuse).
    fn check(&self) -> Result<(), String> {
        let n = self.positions.len();
        let lengths = [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
            ("radii", self.radii.as_ref().map(Vec::len)),
        ];
        for (name, len) in lengths {
            if let Some(len) = len.filter(|&len| len != n) {
                return Err(format!("the cloud has {n} positions but {len} {name}"));
            }
        }
        if let Some(i) = self.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(format!("point {i}: position {:?} is not finite", self.positions[i]));
        }
        Ok(())
    }
}

// ------------------------------------------------------------------------------------------
// Reading
// ------------------------------------------------------------------------------------------

/// Reads a point cloud from a PLY file (see the [module documentation](self) for what is read).
///
/// # Errors
/// [`Error::Io`] when the file cannot be read; [`Error::Parse`] naming the file and the line
/// (header, ASCII body) or byte offset (binary body) of the first problem.
pub fn read_ply(path: &Path) -> Result<PointCloud, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_ply(&bytes, path)
}

/// Parses the contents of a PLY file as [`read_ply`] does; `path` only names the file in errors.
/// Useful when the bytes come from somewhere other than a file.
///
/// # Errors
/// [`Error::Parse`] naming `path` and the line or byte offset of the first problem.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<PointCloud, Error> {
    parse_at(bytes).map_err(|(at, message)| match at {
        At::Line(line) => Error::Parse { path: path.to_path_buf(), line, message },
        At::Byte(offset) => Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: format!("byte {offset}: {message}"),
        },
    })
}

/// Where an error is: a 1-based line (header, ASCII body) or a byte offset (binary body).
#[derive(Clone, Copy, Debug)]
enum At {
    Line(usize),
    Byte(u64),
}

type Fail = (At, String);

// Value slots of a vertex.
const X: usize = 0;
const NX: usize = 3;
const RED: usize = 6;
const RADIUS: usize = 9;
const SLOTS: usize = 10;
const COLOR_NAMES: [[&str; 3]; 3] =
    [["red", "r", "diffuse_red"], ["green", "g", "diffuse_green"], ["blue", "b", "diffuse_blue"]];

fn slot(name: &str) -> Option<usize> {
    Some(match name {
        "x" => X,
        "y" => X + 1,
        "z" => X + 2,
        "nx" => NX,
        "ny" => NX + 1,
        "nz" => NX + 2,
        "radius" => RADIUS,
        _ => RED + COLOR_NAMES.iter().position(|names| names.contains(&name))?,
    })
}

/// One element as the crate delivers it: the values we use, by slot (colours on a 0..255
/// scale), and how many list values it had (to check an ASCII line's length).
struct Values {
    values: [f32; SLOTS],
    list_values: usize,
}

impl PropertyAccess for Values {
    fn new() -> Self {
        Self { values: [0.0; SLOTS], list_values: 0 }
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        self.list_values += list_len(&property);
        let Some(k) = slot(name) else {
            return PropertyAccessResult::Ignored;
        };
        let value =
            if (RED..RED + 3).contains(&k) { channel(&property) } else { scalar(&property) };
        match value {
            Some(v) => {
                self.values[k] = v;
                PropertyAccessResult::Set
            }
            None => PropertyAccessResult::Ignored,
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

#[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
fn scalar(p: &Property) -> Option<f32> {
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

/// A colour channel on a 0..255 scale: `uchar` as it is, `ushort` / 257, floats * 255 (from
/// 0..1), other integers clamped.
#[allow(clippy::cast_possible_truncation)]
fn channel(p: &Property) -> Option<f32> {
    let v = match *p {
        Property::UShort(v) => f32::from(v) / 257.0,
        Property::Float(v) => v.clamp(0.0, 1.0) * 255.0,
        Property::Double(v) => (v.clamp(0.0, 1.0) * 255.0) as f32,
        _ => scalar(p)?,
    };
    Some(if v.is_nan() { 0.0 } else { v.clamp(0.0, 255.0) })
}

/// Which of our attributes the `vertex` element has.
#[derive(Clone, Copy, Default)]
struct Layout {
    normals: bool,
    colors: bool,
    radii: bool,
}

fn parse_at(bytes: &[u8]) -> Result<PointCloud, Fail> {
    if !bytes.starts_with(b"ply") {
        return Err((At::Line(1), "not a PLY file: expected `ply` on the first line".into()));
    }
    let parser = Parser::<Values>::new();
    let mut reader = Reader::new(Cursor::new(bytes));
    let header = parser.read_header(&mut reader).map_err(|e| header_error(&e, &reader, bytes))?;
    let body_start = reader.get_ref().position();
    let header_bytes = &bytes[..usize::try_from(body_start).unwrap_or(bytes.len())];
    let declared = scan_header(header_bytes)?;
    let end_line = header_bytes.iter().filter(|&&b| b == b'\n').count();
    let layout = check_header(&header, &declared, end_line)?;

    let mut body = Body { layout, ..Body::default() };
    match header.encoding {
        Encoding::Ascii => {
            read_ascii(&parser, &header, bytes, body_start, end_line + 1, &mut body)?;
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            read_binary(&parser, &header, bytes, body_start, &mut body)?;
        }
    }
    Ok(body.into_cloud())
}

/// Turns a header error from the crate into one naming the line, with a readable message.
fn header_error(e: &ParseError, reader: &Reader<Cursor<&[u8]>>, bytes: &[u8]) -> Fail {
    let line = e.line().unwrap_or_else(|| reader.line()).max(1);
    let text = bytes.split(|&b| b == b'\n').nth(line - 1).map(String::from_utf8_lossy);
    let text = text.as_deref().unwrap_or("").trim();
    let text: String = text.chars().take(80).collect();
    let first = e.to_string();
    let first = first.split("\n\t").next().unwrap_or("").trim();
    let first = first.strip_prefix(&format!("Line {line}: ")).unwrap_or(first);
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

/// An element declared in the header, with the lines of its declaration and its properties.
struct Declared {
    name: String,
    line: usize,
    properties: Vec<(String, usize)>,
}

/// The header's elements and properties with their lines; rejects duplicate element or
/// property names, which the crate would merge (so the body would be misread).
fn scan_header(header: &[u8]) -> Result<Vec<Declared>, Fail> {
    let mut elements: Vec<Declared> = Vec::new();
    for (n, raw) in header.split(|&b| b == b'\n').enumerate() {
        let line = n + 1;
        let text = String::from_utf8_lossy(raw);
        let mut tokens = text.split_ascii_whitespace();
        match tokens.next() {
            Some("element") => {
                let name = tokens.next().unwrap_or("").to_string();
                if let Some(first) = elements.iter().find(|e| e.name == name) {
                    return Err((
                        At::Line(line),
                        format!(
                            "element `{name}` is declared twice (first at line {})",
                            first.line
                        ),
                    ));
                }
                elements.push(Declared { name, line, properties: Vec::new() });
            }
            Some("property") => {
                let name = tokens.last().unwrap_or("").to_string();
                if let Some(element) = elements.last_mut() {
                    if let Some((_, first)) = element.properties.iter().find(|(p, _)| *p == name) {
                        return Err((
                            At::Line(line),
                            format!(
                                "element `{}` has two properties `{name}` (first at line {first})",
                                element.name
                            ),
                        ));
                    }
                    element.properties.push((name, line));
                }
            }
            _ => {}
        }
    }
    Ok(elements)
}

/// Checks the `vertex` element: present, `x y z` there, the properties we read scalars.
fn check_header(header: &Header, declared: &[Declared], end_line: usize) -> Result<Layout, Fail> {
    let Some(vertex) = header.elements.get("vertex") else {
        return Err((
            At::Line(end_line),
            "the header declares no `vertex` element: a point cloud needs one with `x y z`".into(),
        ));
    };
    let element = declared.iter().find(|d| d.name == "vertex");
    let element_line = element.map_or(end_line, |d| d.line);
    let property_line = |name: &str| {
        element
            .and_then(|d| d.properties.iter().find(|(p, _)| p == name))
            .map_or(element_line, |(_, line)| *line)
    };
    for p in vertex.properties.values() {
        if slot(&p.name).is_some() && matches!(p.data_type, PropertyType::List(..)) {
            return Err((
                At::Line(property_line(&p.name)),
                format!("`vertex` property `{}` must be a scalar, not a list", p.name),
            ));
        }
    }
    let has = |name: &str| vertex.properties.get(name).is_some();
    for name in ["x", "y", "z"] {
        if !has(name) {
            return Err((
                At::Line(element_line),
                format!("element `vertex` has no property `{name}`"),
            ));
        }
    }
    Ok(Layout {
        normals: ["nx", "ny", "nz"].iter().all(|n| has(n)),
        colors: COLOR_NAMES.iter().all(|names| names.iter().any(|n| has(n))),
        radii: has("radius"),
    })
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
fn capacity(def: &ElementDef, encoding: Encoding, available: u64) -> usize {
    let fit = available / min_size(def, encoding).max(1) + 1;
    def.count.min(usize::try_from(fit).unwrap_or(usize::MAX))
}

/// Accumulates the vertices while the body is read.
#[derive(Default)]
struct Body {
    layout: Layout,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[u8; 3]>,
    radii: Vec<f32>,
}

impl Body {
    fn reserve(&mut self, count: usize) {
        self.positions.reserve(count);
        if self.layout.normals {
            self.normals.reserve(count);
        }
        if self.layout.colors {
            self.colors.reserve(count);
        }
        if self.layout.radii {
            self.radii.reserve(count);
        }
    }

    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    fn add(&mut self, e: &Values, index: usize, at: At) -> Result<(), Fail> {
        let v = &e.values;
        let p = [v[X], v[X + 1], v[X + 2]];
        if !p.iter().all(|c| c.is_finite()) {
            return Err((at, format!("vertex {index}: position {p:?} is not finite")));
        }
        if self.layout.radii {
            let r = v[RADIUS];
            if !(r.is_finite() && r >= 0.0) {
                return Err((
                    at,
                    format!("vertex {index}: radius {r} is not a finite number >= 0"),
                ));
            }
            self.radii.push(r);
        }
        self.positions.push(p);
        if self.layout.normals {
            self.normals.push(unit_or_zero([v[NX], v[NX + 1], v[NX + 2]]));
        }
        if self.layout.colors {
            self.colors.push([v[RED], v[RED + 1], v[RED + 2]].map(|c| c.round() as u8));
        }
        Ok(())
    }

    fn into_cloud(self) -> PointCloud {
        PointCloud {
            positions: self.positions,
            normals: self.layout.normals.then_some(self.normals),
            colors: self.layout.colors.then_some(self.colors),
            radii: self.layout.radii.then_some(self.radii),
        }
    }
}

/// `n` scaled to unit length; zero for a zero or non-finite `n` (an unknown normal). A normal
/// already unit to `f32` precision is returned unchanged, so that normalising is idempotent
/// and written clouds read back bit for bit.
#[allow(clippy::cast_possible_truncation)]
fn unit_or_zero(n: [f32; 3]) -> [f32; 3] {
    if !n.iter().all(|c| c.is_finite()) {
        return [0.0; 3];
    }
    // In f64 so that tiny (or huge) components neither underflow nor overflow when squared.
    let d = DVec3::from(n.map(f64::from));
    let len2 = d.length_squared();
    if len2 == 0.0 || (len2 - 1.0).abs() <= 1e-6 {
        return n;
    }
    (d / len2.sqrt()).to_array().map(|c| c as f32)
}

/// The index of the `vertex` element among the elements, and the elements before it (which
/// must be read past, as their sizes are only known by reading them).
fn vertex_position(header: &Header) -> usize {
    header.elements.values().position(|d| d.name == "vertex").unwrap_or(usize::MAX)
}

/// Reads an ASCII body up to the end of the `vertex` element, one element per non-blank line;
/// `first_line` is the line after `end_header`.
fn read_ascii(
    parser: &Parser<Values>,
    header: &Header,
    bytes: &[u8],
    body_start: u64,
    first_line: usize,
    body: &mut Body,
) -> Result<(), Fail> {
    let start = usize::try_from(body_start).unwrap_or(bytes.len());
    let mut lines = bytes[start..]
        .split(|&b| b == b'\n')
        .enumerate()
        .map(|(n, text)| (first_line + n, text))
        .filter(|(_, text)| !text.iter().all(u8::is_ascii_whitespace));
    let mut last_line = first_line;
    let vertex_at = vertex_position(header);
    for (k, def) in header.elements.values().enumerate().take(vertex_at.saturating_add(1)) {
        if def.properties.is_empty() {
            continue;
        }
        let is_vertex = k == vertex_at;
        if is_vertex {
            body.reserve(capacity(def, header.encoding, bytes.len() as u64 - body_start));
        }
        for i in 0..def.count {
            let Some((line, raw)) = lines.next() else {
                let end = bytes[start..].split(|&b| b == b'\n').count() + first_line - 1;
                return Err((
                    At::Line(end.max(last_line)),
                    format!(
                        "file ends after {i} of the {} `{}` elements the header declares",
                        def.count, def.name
                    ),
                ));
            };
            last_line = line;
            let at = At::Line(line);
            let text = std::str::from_utf8(raw).map_err(|_| (at, "not valid UTF-8".to_string()))?;
            let text = text.trim_end_matches('\r');
            let element = parser.read_ascii_element(text, def).map_err(|e| {
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
            let declared = def.properties.len() + element.list_values;
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
            if is_vertex {
                body.add(&element, i, at)?;
            }
        }
    }
    Ok(())
}

/// Reads a binary body up to the end of the `vertex` element from a cursor, whose position
/// names the byte where the failing element starts.
fn read_binary(
    parser: &Parser<Values>,
    header: &Header,
    bytes: &[u8],
    body_start: u64,
    body: &mut Body,
) -> Result<(), Fail> {
    let mut cursor = Cursor::new(bytes);
    cursor.set_position(body_start);
    let big = header.encoding == Encoding::BinaryBigEndian;
    let vertex_at = vertex_position(header);
    for (k, def) in header.elements.values().enumerate().take(vertex_at.saturating_add(1)) {
        if def.properties.is_empty() {
            continue;
        }
        let is_vertex = k == vertex_at;
        if is_vertex {
            body.reserve(capacity(def, header.encoding, bytes.len() as u64 - body_start));
        }
        for i in 0..def.count {
            let offset = cursor.position();
            let at = At::Byte(offset);
            let element = if big {
                parser.read_big_endian_element(&mut cursor, def)
            } else {
                parser.read_little_endian_element(&mut cursor, def)
            };
            let element = element.map_err(|e| {
                let message = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    format!(
                        "file ends inside `{}` {i} of {} (the file has {} bytes); expected {}",
                        def.name,
                        def.count,
                        bytes.len(),
                        describe(def)
                    )
                } else {
                    format!("`{}` {i}: {}; expected {}", def.name, crate_message(&e), describe(def))
                };
                (at, message)
            })?;
            if is_vertex {
                body.add(&element, i, at)?;
            }
        }
    }
    Ok(())
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

// ------------------------------------------------------------------------------------------
// Writing
// ------------------------------------------------------------------------------------------

/// Writes `cloud` as a binary little-endian PLY: `float x y z`, then, when the cloud has them,
/// `float nx ny nz`, `uchar red green blue` and `float radius`. Binary because clouds are
/// large and because it keeps every `f32` bit for bit: [`read_ply`] gives back exactly `cloud`
/// (normals are assumed unit, as [`PointCloud`] promises; others would be normalised on read).
///
/// # Errors
/// [`Error::Io`] when the file cannot be written, or (kind `InvalidInput`) when an attribute
/// array's length differs from the number of positions or a position is not finite, which
/// would give a file [`read_ply`] refuses.
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<(), Error> {
    cloud.check().map_err(|message| {
        Error::io(path, std::io::Error::new(std::io::ErrorKind::InvalidInput, message))
    })?;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = BufWriter::new(file);
    write_body(&mut out, cloud)
        .and_then(|()| out.into_inner().map(drop).map_err(std::io::IntoInnerError::into_error))
        .map_err(|e| Error::io(path, e))
}

fn write_body(out: &mut impl Write, cloud: &PointCloud) -> std::io::Result<()> {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment trirast point cloud\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n",
        cloud.len()
    );
    if cloud.normals.is_some() {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if cloud.colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if cloud.radii.is_some() {
        header.push_str("property float radius\n");
    }
    header.push_str("end_header\n");
    out.write_all(header.as_bytes())?;
    let mut record = Vec::with_capacity(31);
    for (i, p) in cloud.positions.iter().enumerate() {
        record.clear();
        record.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        if let Some(n) = &cloud.normals {
            record.extend(n[i].iter().flat_map(|c| c.to_le_bytes()));
        }
        if let Some(c) = &cloud.colors {
            record.extend_from_slice(&c[i]);
        }
        if let Some(r) = &cloud.radii {
            record.extend_from_slice(&r[i].to_le_bytes());
        }
        out.write_all(&record)?;
    }
    out.flush()
}

// ------------------------------------------------------------------------------------------
// Sampling
// ------------------------------------------------------------------------------------------

/// Points per chunk of [`sample_mesh`]: each chunk has its own random stream, seeded from the
/// seed and the chunk's index, so the result does not depend on how many threads run.
const CHUNK: usize = 4096;

/// Colour of points on surfaces with neither texture, vertex colours nor material (the same
/// grey the splat tree gives uncoloured points).
const DEFAULT_COLOR: [u8; 3] = [200, 200, 200];

/// Samples `n` points uniformly by area over the surface of `mesh`, with normals, colours and
/// radii, deterministically for a given `seed`.
///
/// - **Positions**: a triangle is chosen with probability proportional to its area (binary
///   search in a cumulative-area table, so the cost is O(log triangles) per point), then a point
///   uniform within it from barycentrics `(1 - sqrt(r1), sqrt(r1) (1 - r2), sqrt(r1) r2)`; the
///   square root undoes the crowding towards the first vertex that uniform `r1` would give.
///   Degenerate triangles (zero or non-finite area) and triangles with out-of-range indices
///   have probability zero.
/// - **Normals**: the mesh's vertex normals interpolated and normalised; a mesh without
///   normals gets the smooth area-weighted ones the renderer computes
///   ([`crate::model::vertex_normals`]); where they cancel out, the face normal
///   `(b - a) x (c - a)`, normalised, which faces the side from which the triangle winds
///   counter-clockwise.
/// - **Colours**: the texture of the triangle's material at the interpolated texture
///   coordinate (bilinear, repeat: what the renderer shows by default); else the vertex
///   colours, interpolated in linear light as the renderer does; else the material's diffuse
///   colour; else light grey `[200, 200, 200]`.
/// - **Radii**: all `sqrt(A / (pi n)) * 3` for total area `A`. Disks of radius
///   `sqrt(A / (pi n))` have, together, exactly the area of the surface, which would close it
///   only if they tiled it perfectly; random points cluster and leave gaps, and the uncovered
///   fraction of a surface under `n` random disks of `k` times that radius is about
///   `exp(-k^2)`. `k = 3` leaves about 0.01% in gaps (`k = 1.5` left a tenth of the surface,
///   `k = 2.5` still 0.2%: dozens of pin-holes in a 1080p render), at the price of splats that
///   overlap more.
///
/// `n = 0` or a mesh of zero total area gives an empty cloud (with empty normals, colours and
/// radii). Memory is proportional to `n`. Work is split into fixed chunks of points, each with
/// its own `SmallRng` stream seeded from `(seed, chunk index)`, and run on rayon's threads:
/// the same seed gives the same cloud whatever the number of threads (for a given version of
/// `rand`, whose `SmallRng` algorithm is not promised to stay the same).
#[must_use]
pub fn sample_mesh(mesh: &Mesh, textures: &MaterialTextures, n: usize, seed: u64) -> PointCloud {
    sample(mesh, &|k| textures.get(k), n, seed)
}

/// [`sample_mesh`] with the diffuse textures given directly: `textures[k]` is the texture of
/// material `k` (`None`, or a short slice, for materials without one). For textures built in
/// code.
#[must_use]
pub fn sample_mesh_with_textures(
    mesh: &Mesh,
    textures: &[Option<Texture>],
    n: usize,
    seed: u64,
) -> PointCloud {
    sample(mesh, &|k| textures.get(k).and_then(Option::as_ref), n, seed)
}

type TextureOf<'a> = dyn Fn(usize) -> Option<&'a Texture> + Sync + 'a;

#[allow(clippy::cast_possible_truncation, clippy::cast_precision_loss)]
fn sample(mesh: &Mesh, texture_of: &TextureOf<'_>, n: usize, seed: u64) -> PointCloud {
    // Without normals in the file, the smooth (area-weighted, welded) vertex normals the mesh
    // renderer shades with: face normals of scanned meshes include flipped slivers, whose
    // points the splat renderer's back-face culling would then drop, leaving holes.
    let smooth = mesh
        .normals
        .is_none()
        .then(|| crate::model::vertex_normals(&mesh.positions, &mesh.triangles));
    let mut sampler = Sampler::new(mesh, texture_of);
    if let Some(normals) = &smooth {
        sampler.normals = Some(normals);
    }
    let total = sampler.cumulative.last().copied().unwrap_or(0.0);
    if n == 0 || !(total > 0.0 && total.is_finite()) {
        return PointCloud {
            positions: Vec::new(),
            normals: Some(Vec::new()),
            colors: Some(Vec::new()),
            radii: Some(Vec::new()),
        };
    }
    let mut positions = vec![[0.0f32; 3]; n];
    let mut normals = vec![[0.0f32; 3]; n];
    let mut colors = vec![[0u8; 3]; n];
    positions
        .par_chunks_mut(CHUNK)
        .zip(normals.par_chunks_mut(CHUNK))
        .zip(colors.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(chunk, ((p, nn), c))| {
            let mut rng = SmallRng::seed_from_u64(chunk_seed(seed, chunk as u64));
            for ((p, nn), c) in p.iter_mut().zip(nn).zip(c) {
                (*p, *nn, *c) = sampler.point(&mut rng, total);
            }
        });
    let radius = ((total / (std::f64::consts::PI * n as f64)).sqrt() * 3.0) as f32;
    PointCloud {
        positions,
        normals: Some(normals),
        colors: Some(colors),
        radii: Some(vec![radius; n]),
    }
}

/// The seed of chunk `chunk`'s random stream: SplitMix64 mixing, so that neighbouring seeds and
/// chunks give unrelated streams.
fn chunk_seed(seed: u64, chunk: u64) -> u64 {
    fn mix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    mix(seed ^ mix(chunk))
}

/// A mesh prepared for sampling: the triangles that can be hit and their cumulative areas,
/// and the per-vertex attributes that are usable (as long as the positions).
struct Sampler<'a, 't> {
    mesh: &'a Mesh,
    texture_of: &'a TextureOf<'t>,
    /// Indices into `mesh.triangles` of the triangles with positive area.
    triangles: Vec<usize>,
    /// `cumulative[k]`: total area of `triangles[..=k]`.
    cumulative: Vec<f64>,
    normals: Option<&'a [[f32; 3]]>,
    texcoords: Option<&'a [[f32; 2]]>,
    /// Vertex colours in linear light.
    colors: Option<Vec<DVec3>>,
}

impl<'a, 't> Sampler<'a, 't> {
    fn new(mesh: &'a Mesh, texture_of: &'a TextureOf<'t>) -> Self {
        let vertices = mesh.positions.len();
        let mut triangles = Vec::new();
        let mut cumulative = Vec::new();
        let mut total = 0.0f64;
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let Some([a, b, c]) = corners(mesh, *tri) else { continue };
            let area = 0.5 * (b - a).cross(c - a).length();
            if area > 0.0 && area.is_finite() {
                total += area;
                triangles.push(t);
                cumulative.push(total);
            }
        }
        let usable = |len: usize| len == vertices;
        Self {
            mesh,
            texture_of,
            triangles,
            cumulative,
            normals: mesh.normals.as_deref().filter(|v| usable(v.len())),
            texcoords: mesh.texcoords.as_deref().filter(|v| usable(v.len())),
            colors: mesh.colors.as_ref().filter(|v| usable(v.len())).map(|c| {
                c.iter()
                    .map(|&[r, g, b, _]| {
                        DVec3::new(
                            f64::from(srgb_decode(r.clamp(0.0, 1.0))),
                            f64::from(srgb_decode(g.clamp(0.0, 1.0))),
                            f64::from(srgb_decode(b.clamp(0.0, 1.0))),
                        )
                    })
                    .collect()
            }),
        }
    }

    /// One point: position, unit normal, colour. `total` is the last cumulative area.
    #[allow(clippy::cast_possible_truncation)]
    fn point(&self, rng: &mut SmallRng, total: f64) -> ([f32; 3], [f32; 3], [u8; 3]) {
        let r = rng.random::<f64>() * total;
        // The first triangle whose cumulative area exceeds r; zero-area triangles are not in
        // the table, and rounding at the very end falls back on the last (positive) one.
        let k = self.cumulative.partition_point(|&c| c <= r).min(self.cumulative.len() - 1);
        let t = self.triangles[k];
        let tri = self.mesh.triangles[t];
        let (r1, r2) = (rng.random::<f64>(), rng.random::<f64>());
        let s = r1.sqrt();
        let w = [1.0 - s, s * (1.0 - r2), s * r2];
        let [a, b, c] = corners(self.mesh, tri).unwrap_or([DVec3::ZERO; 3]);
        let p = a * w[0] + b * w[1] + c * w[2];
        let face = (b - a).cross(c - a).normalize_or_zero();
        let normal = self
            .normals
            .map(|n| lerp3(tri.map(|i| DVec3::from(n[i as usize].map(f64::from))), w))
            .map(DVec3::normalize_or_zero)
            .filter(|n| *n != DVec3::ZERO)
            .unwrap_or(face);
        let to_f32 = |v: DVec3| v.to_array().map(|c| c as f32);
        (to_f32(p), to_f32(normal), self.color(t, tri, w))
    }

    /// The colour at barycentrics `w` of triangle `t` (see [`sample_mesh`] for the order).
    #[allow(clippy::cast_possible_truncation)]
    fn color(&self, t: usize, tri: [u32; 3], w: [f64; 3]) -> [u8; 3] {
        let mesh = self.mesh;
        let material = mesh.triangle_materials.as_ref().and_then(|m| m.get(t)).map(|&k| k as usize);
        if let (Some(texture), Some(uvs)) = (material.and_then(self.texture_of), self.texcoords) {
            let uv = tri.map(|i| DVec2::from(uvs[i as usize].map(f64::from)));
            let uv = uv[0] * w[0] + uv[1] * w[1] + uv[2] * w[2];
            let c =
                texture.sample(Vec2::new(uv.x as f32, uv.y as f32), Filter::Bilinear, Wrap::Repeat);
            return [c.x, c.y, c.z].map(linear_to_srgb8);
        }
        if let Some(colors) = &self.colors {
            let c = lerp3(tri.map(|i| colors[i as usize]), w);
            return c.to_array().map(|c| linear_to_srgb8(c as f32));
        }
        match material.and_then(|k| mesh.materials.get(k)) {
            Some(m) => m.diffuse.map(unorm8),
            None => DEFAULT_COLOR,
        }
    }
}

/// The corners of a triangle in f64, or `None` when an index is out of range.
fn corners(mesh: &Mesh, tri: [u32; 3]) -> Option<[DVec3; 3]> {
    let p = |i: u32| mesh.positions.get(i as usize).map(|p| DVec3::from(p.map(f64::from)));
    Some([p(tri[0])?, p(tri[1])?, p(tri[2])?])
}

fn lerp3(v: [DVec3; 3], w: [f64; 3]) -> DVec3 {
    v[0] * w[0] + v[1] * w[1] + v[2] * w[2]
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use super::*;

    #[test]
    fn normalising_is_idempotent() {
        let mut rng = SmallRng::seed_from_u64(1);
        for _ in 0..100_000 {
            let v: [f32; 3] = std::array::from_fn(|_| rng.random_range(-10.0..10.0));
            let n = unit_or_zero(v);
            assert_eq!(unit_or_zero(n).map(f32::to_bits), n.map(f32::to_bits), "{v:?}");
            let len = n.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt();
            assert!((len - 1.0).abs() < 1e-6, "{v:?} -> {n:?}");
        }
        assert_eq!(unit_or_zero([1e-30, 0.0, 1e-30])[0], std::f32::consts::FRAC_1_SQRT_2);
        assert_eq!(unit_or_zero([3e38, 3e38, 0.0])[1], std::f32::consts::FRAC_1_SQRT_2);
        assert_eq!(unit_or_zero([0.0, f32::NAN, 1.0]), [0.0; 3]);
    }

    #[test]
    fn chunk_seeds_differ() {
        let mut seen = HashSet::new();
        for seed in 0..64 {
            for chunk in 0..64 {
                assert!(seen.insert(chunk_seed(seed, chunk)));
            }
        }
    }

    #[test]
    fn reservations_are_capped_by_the_file_size() {
        let src = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
                    property double x\nproperty double y\nproperty double z\nend_header\n";
        let parser = Parser::<Values>::new();
        let mut reader = Reader::new(Cursor::new(&src[..]));
        let header = parser.read_header(&mut reader).unwrap();
        let def = header.elements.get("vertex").unwrap();
        assert_eq!(capacity(def, Encoding::BinaryLittleEndian, 240), 11);
        assert_eq!(capacity(def, Encoding::Ascii, 240), 41);
    }
}
