//! PLY reader: ASCII, binary little endian and binary big endian.
//!
//! Parsing is done by the `ply-rs-bw` crate, driven one element at a time so that every error
//! can name its position: the crate's header parser reports the header line, ASCII elements are
//! handed to it line by line (we count the lines), and binary elements are read from a cursor
//! whose position gives the byte offset of the element that failed. Its messages are shortened
//! and completed with what was expected (the element's declared layout). Checks the crate does
//! not make are done here: duplicate element or property names (the crate would silently merge
//! them and misread the body), the types of the properties we use, non-finite positions, and
//! face indices out of range. Reservations are capped by what the rest of the file can hold, so
//! `element vertex 4000000000` in a small file allocates nothing and fails where the data ends.
//!
//! Read from the `vertex` element: `x y z`, optional normals `nx ny nz`, colours `red green
//! blue [alpha]` (also `r g b [a]` and `diffuse_red ...`; `uchar` is divided by 255, `ushort`
//! by 65535, floats are taken as they are, all clamped to [0, 1]; alpha defaults to 1) and
//! texture coordinates `u v` (or `s t`, `texture_u texture_v`, `texture_s texture_t`). From the
//! `face` element: the integer list `vertex_indices` (or `vertex_index`) of any size, each face
//! triangulated by [`crate::polygon::triangulate_face`]. Other elements and properties are
//! skipped. Vertices map one to one onto [`Mesh`] vertices.
//!
//! Binary errors are [`Error::Parse`] with `line: 0` and a message starting `byte N:`.

use std::collections::{HashMap, HashSet};
use std::io::Cursor;
use std::path::Path;

use ply_rs_bw::parser::{ParseError, Parser, Reader};
use ply_rs_bw::ply::{
    ElementDef, Encoding, Header, Property, PropertyAccess, PropertyAccessResult, PropertyType,
    ScalarType,
};

use super::Mesh;
use crate::error::Error;

/// Reads a PLY file as a [`Mesh`].
pub fn read(path: &Path) -> Result<Mesh, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse(&bytes, path)
}

/// Parses the contents of a PLY file; `path` is only used to name the file in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, Error> {
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

// Value slots of an element; the texture coordinate spellings have slots of their own so that
// the header decides which pair is used.
const X: usize = 0;
const NX: usize = 3;
const RED: usize = 6;
const ALPHA: usize = 9;
const UV: usize = 10;
const SLOTS: usize = 18;
const UV_NAMES: [[&str; 2]; 4] =
    [["u", "v"], ["s", "t"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]];
const COLOR_NAMES: [[&str; 3]; 4] = [
    ["red", "r", "diffuse_red"],
    ["green", "g", "diffuse_green"],
    ["blue", "b", "diffuse_blue"],
    ["alpha", "a", "diffuse_alpha"],
];
const INDEX_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

fn slot(name: &str) -> Option<usize> {
    Some(match name {
        "x" => X,
        "y" => X + 1,
        "z" => X + 2,
        "nx" => NX,
        "ny" => NX + 1,
        "nz" => NX + 2,
        _ => {
            if let Some(c) = COLOR_NAMES.iter().position(|names| names.contains(&name)) {
                RED + c
            } else {
                let k = UV_NAMES.as_flattened().iter().position(|n| *n == name)?;
                UV + k
            }
        }
    })
}

/// One element as the crate delivers it: the values we use, by slot, and the face indices.
struct Element {
    values: [f32; SLOTS],
    indices: Vec<i64>,
    /// The number of values in the element's lists (to check an ASCII line's length).
    list_values: usize,
}

impl PropertyAccess for Element {
    fn new() -> Self {
        let mut values = [0.0; SLOTS];
        values[ALPHA] = 1.0;
        Self { values, indices: Vec::new(), list_values: 0 }
    }

    fn set_property(&mut self, name: &str, property: Property) -> PropertyAccessResult {
        self.list_values += list_len(&property);
        if INDEX_NAMES.contains(&name) {
            self.indices = match property {
                Property::ListChar(v) => v.into_iter().map(i64::from).collect(),
                Property::ListUChar(v) => v.into_iter().map(i64::from).collect(),
                Property::ListShort(v) => v.into_iter().map(i64::from).collect(),
                Property::ListUShort(v) => v.into_iter().map(i64::from).collect(),
                Property::ListInt(v) => v.into_iter().map(i64::from).collect(),
                Property::ListUInt(v) => v.into_iter().map(i64::from).collect(),
                _ => return PropertyAccessResult::Ignored,
            };
            return PropertyAccessResult::Set;
        }
        let Some(k) = slot(name) else {
            return PropertyAccessResult::Ignored;
        };
        let value = if (RED..=ALPHA).contains(&k) { color(&property) } else { scalar(&property) };
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

/// A colour channel in [0, 1]: `ushort` / 65535, other integers / 255, floats as they are.
#[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
fn color(p: &Property) -> Option<f32> {
    let v = match *p {
        Property::UShort(v) => f32::from(v) / 65535.0,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => scalar(p)? / 255.0,
    };
    Some(if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
}

/// Which of our attributes the `vertex` element has.
#[derive(Default)]
struct Layout {
    normals: bool,
    colors: bool,
    /// The slot of `u` of the texture coordinate pair in use.
    uv: Option<usize>,
}

/// What an element is to us.
#[derive(Clone, Copy, PartialEq)]
enum Role {
    Vertex,
    Face,
    Skip,
}

fn parse_at(bytes: &[u8]) -> Result<Mesh, Fail> {
    if !bytes.starts_with(b"ply") {
        return Err((At::Line(1), "not a PLY file: expected `ply` on the first line".into()));
    }
    let parser = Parser::<Element>::new();
    let mut reader = Reader::new(Cursor::new(bytes));
    let header = parser.read_header(&mut reader).map_err(|e| header_error(&e, &reader, bytes))?;
    let body_start = reader.get_ref().position();
    let header_bytes = &bytes[..usize::try_from(body_start).unwrap_or(bytes.len())];
    let declared = scan_header(header_bytes)?;
    let end_line = header_bytes.iter().filter(|&&b| b == b'\n').count();
    let line_of =
        |name: &str| declared.iter().find(|(n, _)| n == name).map_or(end_line, |(_, line)| *line);

    let layout = check_header(&header, &line_of, end_line)?;

    let mut body = Body { layout, ..Body::default() };
    match header.encoding {
        Encoding::Ascii => {
            read_ascii(&parser, &header, bytes, body_start, end_line + 1, &mut body)?
        }
        Encoding::BinaryLittleEndian | Encoding::BinaryBigEndian => {
            read_binary(&parser, &header, bytes, body_start, &mut body)?;
        }
    }
    body.into_mesh()
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

/// Element names and their header lines; rejects duplicate element or property names, which the
/// crate would merge (so the body would be misread).
fn scan_header(header: &[u8]) -> Result<Vec<(String, usize)>, Fail> {
    let mut elements: Vec<(String, usize)> = Vec::new();
    let mut element_lines: HashMap<String, usize> = HashMap::new();
    let mut properties = HashSet::new();
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
                properties.clear();
                elements.push((name, line));
            }
            Some("property") => {
                let name = tokens.last().unwrap_or("").to_string();
                if !properties.insert(name.clone()) {
                    let element = elements.last().map_or("", |(e, _)| e.as_str());
                    return Err((
                        At::Line(line),
                        format!("property `{name}` is declared twice in element `{element}`"),
                    ));
                }
            }
            _ => {}
        }
    }
    Ok(elements)
}

/// Checks the properties we use and decides which attributes the vertices have.
fn check_header(
    header: &Header,
    line_of: &dyn Fn(&str) -> usize,
    end_line: usize,
) -> Result<Layout, Fail> {
    let Some(vertex) = header.elements.get("vertex") else {
        return Err((At::Line(end_line), "the header declares no `vertex` element".into()));
    };
    let at = At::Line(line_of("vertex"));
    let scalar = |name: &str| {
        let property = vertex.properties.get(name);
        property.is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(_)))
    };
    for p in vertex.properties.values() {
        if slot(&p.name).is_some() && matches!(p.data_type, PropertyType::List(..)) {
            return Err((
                at,
                format!("`vertex` property `{}` must be a scalar, not a list", p.name),
            ));
        }
    }
    for name in ["x", "y", "z"] {
        if !scalar(name) {
            return Err((at, format!("element `vertex` has no property `{name}`")));
        }
    }
    let channel = |c: usize| COLOR_NAMES[c].iter().any(|n| scalar(n));
    let layout = Layout {
        normals: ["nx", "ny", "nz"].iter().all(|n| scalar(n)),
        colors: (0..3).all(channel),
        uv: UV_NAMES.iter().position(|[u, v]| scalar(u) && scalar(v)).map(|k| UV + 2 * k),
    };
    if let Some(face) = header.elements.get("face") {
        let at = At::Line(line_of("face"));
        let Some(list) = INDEX_NAMES.iter().find_map(|n| face.properties.get(*n)) else {
            return Err((
                at,
                "element `face` has no `vertex_indices` (or `vertex_index`) list".into(),
            ));
        };
        match &list.data_type {
            PropertyType::List(_, ScalarType::Float | ScalarType::Double) => {
                return Err((
                    at,
                    format!("`{}` must be a list of integers, not floats", list.name),
                ));
            }
            PropertyType::Scalar(_) => {
                return Err((at, format!("`{}` must be a list, not a scalar", list.name)));
            }
            PropertyType::List(..) => {}
        }
    }
    Ok(layout)
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

/// Accumulates the elements we use while the body is read.
#[derive(Default)]
struct Body {
    layout: Layout,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 4]>,
    texcoords: Vec<[f32; 2]>,
    corners: Vec<i64>,
    face_ends: Vec<usize>,
    face_at: Vec<At>,
}

impl Body {
    fn role(name: &str) -> Role {
        match name {
            "vertex" => Role::Vertex,
            "face" => Role::Face,
            _ => Role::Skip,
        }
    }

    fn reserve(&mut self, role: Role, count: usize) {
        match role {
            Role::Vertex => {
                self.positions.reserve(count);
                if self.layout.normals {
                    self.normals.reserve(count);
                }
                if self.layout.colors {
                    self.colors.reserve(count);
                }
                if self.layout.uv.is_some() {
                    self.texcoords.reserve(count);
                }
            }
            Role::Face => {
                self.face_ends.reserve(count);
                self.face_at.reserve(count);
            }
            Role::Skip => {}
        }
    }

    fn add(&mut self, role: Role, e: Element, index: usize, at: At) -> Result<(), Fail> {
        match role {
            Role::Vertex => {
                let v = &e.values;
                let p = [v[X], v[X + 1], v[X + 2]];
                if !p.iter().all(|c| c.is_finite()) {
                    return Err((at, format!("vertex {index}: position {p:?} is not finite")));
                }
                self.positions.push(p);
                if self.layout.normals {
                    self.normals.push([v[NX], v[NX + 1], v[NX + 2]]);
                }
                if self.layout.colors {
                    self.colors.push([v[RED], v[RED + 1], v[RED + 2], v[ALPHA]]);
                }
                if let Some(k) = self.layout.uv {
                    self.texcoords.push([v[k], v[k + 1]]);
                }
            }
            Role::Face => {
                if e.indices.len() < 3 {
                    return Err((
                        at,
                        format!(
                            "face {index} has {} vertex indices; a face needs 3 or more",
                            e.indices.len()
                        ),
                    ));
                }
                self.corners.extend_from_slice(&e.indices);
                self.face_ends.push(self.corners.len());
                self.face_at.push(at);
            }
            Role::Skip => {}
        }
        Ok(())
    }

    fn into_mesh(self) -> Result<Mesh, Fail> {
        let n = self.positions.len();
        if u32::try_from(n).is_err() {
            return Err((At::Line(1), format!("{n} vertices are more than 2^32")));
        }
        let mut mesh = Mesh { polygon_count: self.face_ends.len(), ..Mesh::default() };
        let mut start = 0;
        let mut face = Vec::new();
        let mut points = Vec::new();
        for (f, (&end, &at)) in self.face_ends.iter().zip(&self.face_at).enumerate() {
            face.clear();
            points.clear();
            for &i in &self.corners[start..end] {
                let Some(v) = u32::try_from(i).ok().filter(|&v| (v as usize) < n) else {
                    return Err((
                        at,
                        format!(
                            "face {f}: vertex index {i} is out of range (the file has {n} vertices)"
                        ),
                    ));
                };
                face.push(v);
                points.push(self.positions[v as usize]);
            }
            start = end;
            for t in crate::polygon::triangulate_face(&points) {
                if let (Some(&a), Some(&b), Some(&c)) =
                    (face.get(t[0]), face.get(t[1]), face.get(t[2]))
                {
                    mesh.triangles.push([a, b, c]);
                }
            }
        }
        mesh.normals = self.layout.normals.then_some(self.normals);
        mesh.colors = self.layout.colors.then_some(self.colors);
        mesh.texcoords = self.layout.uv.is_some().then_some(self.texcoords);
        mesh.positions = self.positions;
        Ok(mesh)
    }
}

/// Reads an ASCII body, one element per non-blank line; `first_line` is the line after
/// `end_header`.
fn read_ascii(
    parser: &Parser<Element>,
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
    for def in header.elements.values() {
        if def.properties.is_empty() {
            continue;
        }
        let role = Body::role(&def.name);
        body.reserve(role, capacity(def, header.encoding, bytes.len() as u64 - body_start));
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
            body.add(role, element, i, at)?;
        }
    }
    Ok(())
}

/// Reads a binary body element by element from a cursor, whose position names the failing byte.
fn read_binary(
    parser: &Parser<Element>,
    header: &Header,
    bytes: &[u8],
    body_start: u64,
    body: &mut Body,
) -> Result<(), Fail> {
    let mut cursor = Cursor::new(bytes);
    cursor.set_position(body_start);
    let big = header.encoding == Encoding::BinaryBigEndian;
    for def in header.elements.values() {
        if def.properties.is_empty() {
            continue;
        }
        let role = Body::role(&def.name);
        body.reserve(role, capacity(def, header.encoding, bytes.len() as u64 - body_start));
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
            body.add(role, element, i, at)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    fn err(src: &[u8]) -> String {
        parse(src, Path::new("t.ply")).unwrap_err().to_string()
    }

    #[test]
    fn reads_ascii_with_colours_and_quads() {
        let src = b"ply\nformat ascii 1.0\ncomment hi\nelement vertex 4\nproperty float x\n\
            property float y\nproperty float z\nproperty uchar red\nproperty uchar green\n\
            property uchar blue\nelement face 1\nproperty list uchar int vertex_indices\n\
            end_header\n0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 255 255 255\n\
            4 0 1 2 3\n";
        let m = parse(src, Path::new("t.ply")).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.polygon_count, 1);
        assert_eq!(m.triangles.len(), 2);
        assert_eq!(m.colors.as_ref().unwrap()[1], [0.0, 1.0, 0.0, 1.0]);
        assert!(m.normals.is_none() && m.texcoords.is_none());
    }

    #[test]
    fn errors_name_line_or_byte() {
        let head = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                    property float z\n";
        let e = err(format!("{head}end_header\n0 0 x\n").as_bytes());
        assert!(e.starts_with("t.ply:8: `vertex` 0: not a list of numbers"), "{e}");
        let e = err(format!("{head}element vertex 2\nend_header\n").as_bytes());
        assert!(e.contains("t.ply:7: element `vertex` is declared twice"), "{e}");
        let e = err(format!("{head}end_header\n").as_bytes());
        assert!(e.starts_with("t.ply:8: file ends after 0 of the 1 `vertex`"), "{e}");
        let e = err(
            b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                      property float y\nproperty float z\nend_header\n\0\0\0\0\0\0\0\0\0\0\xc0\x7f",
        );
        assert!(e.starts_with("t.ply:0: byte 115: vertex 0: position [0.0, 0.0, NaN]"), "{e}");
        let e = err(b"plx\n");
        assert!(e.starts_with("t.ply:1: not a PLY file"), "{e}");
        let e = err(b"ply\nformat ascii 1.0\nelement vertex x\n");
        assert!(e.starts_with("t.ply:3: expected a PLY header line"), "{e}");
    }
}
