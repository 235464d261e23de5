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
//! The driving is shared with [`crate::splat::cloud`] (in `ply_common`); this reader adds what
//! it keeps of the elements and how it makes a [`Mesh`] of them.
//!
//! Read from the `vertex` element: `x y z`, optional normals `nx ny nz`, colours `red green
//! blue [alpha]` (also `r g b [a]` and `diffuse_red ...`; `uchar` is divided by 255, `ushort`
//! by 65535, floats are taken as they are, all clamped to [0, 1], with a warning where any was
//! outside; alpha defaults to 1) and
//! texture coordinates `u v` (or `s t`, `texture_u texture_v`, `texture_s texture_t`). From the
//! `face` element: the integer list `vertex_indices` (or `vertex_index`) of any size, each face
//! triangulated by [`crate::polygon::triangulate_face`]. Other elements and properties are
//! skipped. Vertices map one to one onto [`Mesh`] vertices.
//!
//! Binary errors are [`Error::Parse`] with `line: 0` and a message starting `byte N:`.

use std::io::Read;
use std::path::Path;

use ply_rs_bw::ply::{ElementDef, Property, PropertyType, ScalarType};

use super::Mesh;
use super::ply_common::{
    At, COLOR_NAMES, Fail, Fields, NX, POSITION_NORMAL, Ply, RED, Sink, Source, X, name_warnings,
    parse_with, read_file, scalar,
};
use crate::error::Error;

/// Reads a PLY file as a [`Mesh`], from the file as it goes (not whole into memory first).
pub fn read(path: &Path) -> Result<Mesh, Error> {
    read_reporting(path, &|_| {})
}

/// [`read`], telling `report` how many bytes of the file it has read so far.
pub(crate) fn read_reporting(path: &Path, report: &dyn Fn(u64)) -> Result<Mesh, Error> {
    read_file(path, report, parse_at).map(|mesh| finished(mesh, path))
}

/// Parses the contents of a PLY file; `path` is only used to name the file in errors and
/// warnings.
pub fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, Error> {
    parse_with(bytes, bytes.len() as u64, path, parse_at).map(|mesh| finished(mesh, path))
}

/// `mesh` as read from `path`, finished: the warnings of reading it naming `path`, and its
/// colours, read as the file has them, clamped to [0, 1] (NaN as 0), with a warning naming
/// `path` where that changed any.
fn finished(mut mesh: Mesh, path: &Path) -> Mesh {
    name_warnings(&mut mesh.warnings, path);
    if let Some(colours) = &mut mesh.colors {
        mesh.warnings.extend(super::colour_warning(path.display(), colours.iter().copied()));
        let unit = |c: f32| if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
        colours.iter_mut().for_each(|c| *c = c.map(unit));
    }
    mesh
}

// Value slots of an element after the shared ones (`X`, `NX`, `RED`); the texture coordinate
// spellings have slots of their own so that the header decides which pair is used.
const ALPHA: usize = 9;
const UV: usize = 10;
const SLOTS: usize = 18;
const UV_NAMES: [[&str; 2]; 4] =
    [["u", "v"], ["s", "t"], ["texture_u", "texture_v"], ["texture_s", "texture_t"]];
const INDEX_NAMES: [&str; 2] = ["vertex_indices", "vertex_index"];

fn slot(name: &str) -> Option<usize> {
    if let Some(k) = POSITION_NORMAL.iter().position(|n| *n == name) {
        Some(X + k)
    } else if let Some(c) = COLOR_NAMES.iter().position(|names| names.contains(&name)) {
        Some(RED + c)
    } else {
        let k = UV_NAMES.as_flattened().iter().position(|n| *n == name)?;
        Some(UV + k)
    }
}

/// What we keep of one element: the values we use, by slot, and the face indices, as the
/// crate's list (converted where they are used, [`index_values`]: a copy in `i64` was a second
/// allocation per face).
struct Element {
    values: [f32; SLOTS],
    indices: Option<Property>,
}

impl Default for Element {
    fn default() -> Self {
        let mut values = [0.0; SLOTS];
        values[ALPHA] = 1.0;
        Self { values, indices: None }
    }
}

impl Fields for Element {
    fn set(&mut self, name: &str, property: Property) -> bool {
        if INDEX_NAMES.contains(&name) {
            let integers = matches!(
                property,
                Property::ListChar(_)
                    | Property::ListUChar(_)
                    | Property::ListShort(_)
                    | Property::ListUShort(_)
                    | Property::ListInt(_)
                    | Property::ListUInt(_)
            );
            if integers {
                self.indices = Some(property);
            }
            return integers;
        }
        let Some(k) = slot(name) else { return false };
        let value = if (RED..=ALPHA).contains(&k) { color(&property) } else { scalar(&property) };
        value.map(|v| self.values[k] = v).is_some()
    }
}

/// The values of an integer list `p` as `i64`, in `out` (cleared first); none for another
/// property.
fn index_values(p: Option<&Property>, out: &mut Vec<i64>) {
    out.clear();
    match p {
        Some(Property::ListChar(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        Some(Property::ListUChar(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        Some(Property::ListShort(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        Some(Property::ListUShort(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        Some(Property::ListInt(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        Some(Property::ListUInt(v)) => out.extend(v.iter().map(|&i| i64::from(i))),
        _ => {}
    }
}

/// A colour channel, 1 for full: `ushort` / 65535, other integers / 255, floats as they are
/// (clamped once the file is read: [`clamped_colours`]).
#[allow(clippy::cast_precision_loss, clippy::cast_possible_truncation)]
fn color(p: &Property) -> Option<f32> {
    Some(match *p {
        Property::UShort(v) => f32::from(v) / 65535.0,
        Property::Float(v) => v,
        Property::Double(v) => v as f32,
        _ => scalar(p)? / 255.0,
    })
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
#[derive(Clone, Copy, Default, PartialEq)]
enum Role {
    Vertex,
    Face,
    #[default]
    Skip,
}

fn parse_at<R: Read>(source: &mut Source<R>, len: u64) -> Result<Mesh, Fail> {
    let ply = Ply::<Element>::read_header(source, len, |element, property, _| {
        format!("property `{property}` is declared twice in element `{element}`")
    })?;
    let layout = check_header(&ply)?;
    let mut body = Body { layout, ..Body::default() };
    let tail = ply.read_body(source, &mut body)?;
    let mut mesh = body.into_mesh()?;
    mesh.warnings.extend(tail);
    Ok(mesh)
}

/// Checks the properties we use and decides which attributes the vertices have.
fn check_header(ply: &Ply<Element>) -> Result<Layout, Fail> {
    let vertex = ply.vertex(
        "the header declares no `vertex` element",
        |name| slot(name).is_some(),
        |_| ply.element_line("vertex"),
    )?;
    let scalar = |name: &str| {
        let property = vertex.properties.get(name);
        property.is_some_and(|p| matches!(p.data_type, PropertyType::Scalar(_)))
    };
    let channel = |c: usize| COLOR_NAMES[c].iter().any(|n| scalar(n));
    let layout = Layout {
        normals: ["nx", "ny", "nz"].iter().all(|n| scalar(n)),
        colors: (0..3).all(channel),
        uv: UV_NAMES.iter().position(|[u, v]| scalar(u) && scalar(v)).map(|k| UV + 2 * k),
    };
    if let Some(face) = ply.header.elements.get("face") {
        let at = At::Line(ply.element_line("face"));
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

/// Accumulates the elements we use while the body is read.
///
/// Faces read after the vertices (the usual order) are checked and triangulated as they come,
/// so that only the triangles are kept: their corners (`i64`), ends and positions in the file
/// had taken 48 bytes a triangle beside its 12 (`trirast info` on a binary PLY of 1 M
/// triangles: 127 MB peak). An index out of range is reported once the body has been read,
/// so that a malformed element further on comes first, as when every face was checked at the
/// end. Faces declared before the vertices are kept whole and triangulated at the end.
#[derive(Default)]
struct Body {
    layout: Layout,
    /// What the element being read is to us.
    role: Role,
    /// Whether the `vertex` element has been read: every element is read whole before the
    /// next one starts.
    vertices_read: bool,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 4]>,
    texcoords: Vec<[f32; 2]>,
    triangles: Vec<[u32; 3]>,
    /// Faces read.
    faces: usize,
    /// The first face with an index out of range, once the vertices are known.
    bad_face: Option<Fail>,
    /// Faces read before the vertices: their corners, where each ends in `corners`, and where
    /// each is in the file.
    corners: Vec<i64>,
    face_ends: Vec<usize>,
    face_at: Vec<At>,
    /// Scratch for one face: its indices, vertex indices and corner positions.
    scratch: Face,
}

/// The reusable buffers one face is triangulated with.
#[derive(Default)]
struct Face {
    indices: Vec<i64>,
    vertices: Vec<u32>,
    points: Vec<[f32; 3]>,
}

impl Sink for Body {
    type Fields = Element;

    fn start(&mut self, def: &ElementDef, capacity: usize) {
        self.role = match def.name.as_str() {
            "vertex" => Role::Vertex,
            "face" => Role::Face,
            _ => Role::Skip,
        };
        match self.role {
            Role::Vertex => {
                self.vertices_read = true;
                self.positions.reserve(capacity);
                if self.layout.normals {
                    self.normals.reserve(capacity);
                }
                if self.layout.colors {
                    self.colors.reserve(capacity);
                }
                if self.layout.uv.is_some() {
                    self.texcoords.reserve(capacity);
                }
            }
            // At least a triangle per face, exactly one for a triangle mesh.
            Role::Face if self.vertices_read => self.triangles.reserve(capacity),
            Role::Face => {
                self.face_ends.reserve(capacity);
                self.face_at.reserve(capacity);
            }
            Role::Skip => {}
        }
    }

    fn add(&mut self, e: Element, index: usize, at: At) -> Result<(), Fail> {
        match self.role {
            Role::Vertex => {
                let v = &e.values;
                let p = [v[X], v[X + 1], v[X + 2]];
                if !p.iter().all(|c| c.is_finite()) {
                    // A `double` past `f32`'s range reads as infinite too.
                    let message = format!(
                        "vertex {index}: position {p:?} is not finite in single precision \
                         (infinite or NaN as written, or a magnitude past about 3.4e38)"
                    );
                    return Err((at, message));
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
                let mut indices = std::mem::take(&mut self.scratch.indices);
                index_values(e.indices.as_ref(), &mut indices);
                if indices.len() < 3 {
                    return Err((
                        at,
                        format!(
                            "face {index} has {} vertex indices; a face needs 3 or more",
                            indices.len()
                        ),
                    ));
                }
                self.faces += 1;
                if !self.vertices_read {
                    self.corners.extend_from_slice(&indices);
                    self.face_ends.push(self.corners.len());
                    self.face_at.push(at);
                } else if self.bad_face.is_none()
                    && let Err(fail) = self.triangulate(&indices, index, at)
                {
                    self.bad_face = Some(fail);
                }
                self.scratch.indices = indices;
            }
            Role::Skip => {}
        }
        Ok(())
    }
}

impl Body {
    /// Appends the triangles of face `f`, whose corners are `indices` and which is at `at`,
    /// or names its first index out of range.
    fn triangulate(&mut self, indices: &[i64], f: usize, at: At) -> Result<(), Fail> {
        let n = self.positions.len();
        let Face { vertices, points, .. } = &mut self.scratch;
        vertices.clear();
        points.clear();
        for &i in indices {
            let Some(v) = u32::try_from(i).ok().filter(|&v| (v as usize) < n) else {
                return Err((
                    at,
                    format!(
                        "face {f}: vertex index {i} is out of range (the file has {n} vertices)"
                    ),
                ));
            };
            vertices.push(v);
            points.push(self.positions[v as usize]);
        }
        for t in crate::polygon::triangulate_face(points) {
            if let (Some(&a), Some(&b), Some(&c)) =
                (vertices.get(t[0]), vertices.get(t[1]), vertices.get(t[2]))
            {
                self.triangles.push([a, b, c]);
            }
        }
        Ok(())
    }

    fn into_mesh(mut self) -> Result<Mesh, Fail> {
        let n = self.positions.len();
        if u32::try_from(n).is_err() {
            return Err((At::Line(1), format!("{n} vertices are more than 2^32")));
        }
        if let Some(fail) = self.bad_face.take() {
            return Err(fail);
        }
        // Faces declared before the vertices.
        let (corners, face_ends, face_at) = (
            std::mem::take(&mut self.corners),
            std::mem::take(&mut self.face_ends),
            std::mem::take(&mut self.face_at),
        );
        let mut start = 0;
        for (f, (&end, &at)) in face_ends.iter().zip(&face_at).enumerate() {
            self.triangulate(&corners[start..end], f, at)?;
            start = end;
        }
        Ok(Mesh {
            polygon_count: self.faces,
            triangles: self.triangles,
            normals: self.layout.normals.then_some(self.normals),
            colors: self.layout.colors.then_some(self.colors),
            texcoords: self.layout.uv.is_some().then_some(self.texcoords),
            positions: self.positions,
            ..Mesh::default()
        })
    }
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

    /// Data after the elements the header declares is named in a warning (the counts are
    /// likely wrong, and the rest of the model would be dropped without a word), ASCII or
    /// binary; blank lines after an ASCII body are not data.
    #[test]
    fn data_after_the_declared_elements_is_warned_of() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                    property float y\nproperty float z\nelement face 1\n\
                    property list uchar int vertex_indices\nend_header\n";
        let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
        for blank in ["", "\n", "\r\n \t\n\n"] {
            let m = parse(format!("{head}{body}{blank}").as_bytes(), Path::new("t.ply")).unwrap();
            assert_eq!((m.triangles.len(), m.warnings.len()), (1, 0), "{blank:?}");
        }
        let m = parse(format!("{head}{body}\n3 0 2 1\n").as_bytes(), Path::new("t.ply")).unwrap();
        assert_eq!(m.triangles.len(), 1);
        let want = "t.ply: 9 bytes after the elements the header declares (3 `vertex`, 1 \
                    `face`) are ignored; the header's counts may be too small";
        assert_eq!(m.warnings, [want]);
        // A file whose size is not known (0, as files under /proc give) has no count.
        let src = format!("{head}{body}3 0 2 1\n");
        let m = parse_with(src.as_bytes(), 0, Path::new("t.ply"), parse_at).unwrap();
        assert!(m.warnings[0].starts_with("the bytes after the elements"), "{:?}", m.warnings);
        let binary = |extra: &[u8]| {
            let mut src = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\n\
                            property float x\nproperty float y\nproperty float z\nend_header\n"
                .to_vec();
            src.extend_from_slice(&[0; 12]);
            src.extend_from_slice(extra);
            parse(&src, Path::new("b.ply")).unwrap().warnings
        };
        assert_eq!(binary(b""), Vec::<String>::new());
        let want = "b.ply: 2 bytes after the elements the header declares (1 `vertex`) are \
                    ignored; the header's counts may be too small";
        assert_eq!(binary(b"\n\n"), [want]);
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
        assert!(e.starts_with("t.ply: byte 115: vertex 0: position [0.0, 0.0, NaN]"), "{e}");
        // The same NaN written as a word in an ASCII file.
        let e = err(format!("{head}end_header\n0 0 nan\n").as_bytes());
        assert!(e.starts_with("t.ply:8: vertex 0: position [0.0, 0.0, NaN]"), "{e}");
        // Words are read only at `float` and `double` properties of elements without lists.
        let face = "element face 1\nproperty list uchar int vertex_indices\n";
        let e = err(format!("{head}{face}end_header\n0 0 1\n3 0 nan 0\n").as_bytes());
        assert!(e.starts_with("t.ply:11: `face` 0: not a list of numbers"), "{e}");
        let e = err(format!("{head}property int k\nend_header\n0 0 1 nan\n").as_bytes());
        assert!(e.starts_with("t.ply:9: `vertex` 0: not a list of numbers"), "{e}");
        let e = err(b"ply\nformat ascii 2.0\nelement vertex 0\nend_header\n");
        assert!(e.starts_with("t.ply:2: PLY version 2.0 is not supported"), "{e}");
        let e = err(b"plx\n");
        assert!(e.starts_with("t.ply:1: not a PLY file"), "{e}");
        let e = err(b"ply\nformat ascii 1.0\nelement vertex x\n");
        assert!(e.starts_with("t.ply:3: expected a PLY header line"), "{e}");
    }

    /// A square of two triangles and a quad over 5 vertices, with faces declared `first` or
    /// after the vertices, and `tail` after the last face.
    fn faces_and_vertices(first: bool, faces: &str, tail: &str) -> Vec<u8> {
        let vertex = "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n";
        let face = "element face 3\nproperty list uchar int vertex_indices\n";
        let vertices = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 0\n";
        let (header, body) = if first {
            (format!("{face}{vertex}"), format!("{faces}{vertices}"))
        } else {
            (format!("{vertex}{face}"), format!("{vertices}{faces}"))
        };
        format!("ply\nformat ascii 1.0\n{header}end_header\n{body}{tail}").into_bytes()
    }

    /// Faces after the vertices are triangulated as they are read, faces before them at the
    /// end: the same mesh either way.
    #[test]
    fn faces_before_the_vertices_give_the_same_mesh() {
        let faces = "3 0 1 2\n3 0 2 3\n4 1 4 2 0\n";
        let read = |first| parse(&faces_and_vertices(first, faces, ""), Path::new("t.ply"));
        let (after, before) = (read(false).unwrap(), read(true).unwrap());
        assert_eq!(after.triangles.len(), 4);
        assert_eq!(after.polygon_count, 3);
        assert_eq!(after, before);
    }

    /// An index out of range names its face and line once the body has been read, so that a
    /// malformed element further on is reported first (as when every face was checked after
    /// the body), whichever element comes first.
    #[test]
    fn an_index_out_of_range_is_reported_after_the_body() {
        let faces = "3 0 1 2\n3 0 2 5\n4 1 4 2 0\n";
        for first in [false, true] {
            // `end_header` is line 9: face 1 is line 11 when faces come first, else 16.
            let line = if first { 11 } else { 16 };
            let e = err(&faces_and_vertices(first, faces, ""));
            let expected =
                format!("t.ply:{line}: face 1: vertex index 5 is out of range (the file has 5 ");
            assert!(e.starts_with(&expected), "{first}: {e}");
        }
        // A face with too many values after the bad one is the error (faces come last here).
        let e = err(&faces_and_vertices(false, "3 0 1 2\n3 0 2 5\n3 1 4 2 0\n", ""));
        assert!(e.starts_with("t.ply:17: `face` 2: found 5 values"), "{e}");
    }

    /// A file of another kind is refused from its first bytes: the crate reads a whole first
    /// line before it refuses one, which in a binary file may be all of it (here it never
    /// ends).
    #[test]
    fn a_file_of_another_kind_is_refused_from_its_first_bytes() {
        let endless = std::io::repeat(b'x');
        let e = parse_with(endless, u64::MAX, Path::new("t.ply"), parse_at).unwrap_err();
        assert_eq!(e.to_string(), "t.ply:1: not a PLY file: expected `ply` on the first line");
    }

    /// Hands out its bytes a few at a time (1 to 13 a read), then, if `fail`, an I/O error.
    struct Trickle<'a> {
        rest: &'a [u8],
        reads: usize,
        fail: bool,
    }

    impl std::io::Read for Trickle<'_> {
        fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
            if self.rest.is_empty() && self.fail {
                return Err(std::io::Error::other("the disk is on fire"));
            }
            self.reads += 1;
            let n = (1 + self.reads % 13).min(out.len()).min(self.rest.len());
            out[..n].copy_from_slice(&self.rest[..n]);
            self.rest = &self.rest[n..];
            Ok(n)
        }
    }

    /// `src` parsed as it trickles in, a few bytes a read (`fail`: then an I/O error).
    fn trickled(src: &[u8], fail: bool) -> Result<Mesh, Error> {
        let reader = Trickle { rest: src, reads: 0, fail };
        parse_with(reader, src.len() as u64, Path::new("t.ply"), parse_at)
    }

    /// A binary file whose second face has `corners` corners on a circle: with 20,000, 80 KB,
    /// more than the reader's buffer holds at first.
    fn big_face(format: &str, corners: u32) -> Vec<u8> {
        let mut src = format!(
            "ply\nformat {format} 1.0\nelement vertex {corners}\nproperty float x\n\
             property float y\nproperty float z\nelement face 2\n\
             property list uint int vertex_indices\nend_header\n"
        )
        .into_bytes();
        let big = format.contains("big");
        let mut put = |v: [u8; 4]| src.extend(if big { v } else { [v[3], v[2], v[1], v[0]] });
        for k in 0..corners {
            let a = f64::from(k) * std::f64::consts::TAU / f64::from(corners);
            for c in [a.cos() as f32, a.sin() as f32, 0.0] {
                put(c.to_be_bytes());
            }
        }
        for face in [vec![0, 1, 2], (0..corners).collect()] {
            put(u32::try_from(face.len()).unwrap().to_be_bytes());
            for i in face {
                put(i.to_be_bytes());
            }
        }
        src
    }

    /// The file is read through a buffer, not whole: what is parsed does not depend on how
    /// the reads fall (a few bytes each here, so every element is met cut short and read
    /// again), an element larger than the buffer is read whole, a file ending inside one
    /// names the byte where it starts, and an I/O error is reported as one.
    #[test]
    fn reading_does_not_depend_on_how_the_file_arrives() {
        let n = 20_000;
        for format in ["binary_little_endian", "binary_big_endian"] {
            let src = big_face(format, n);
            let whole = parse(&src, Path::new("t.ply")).unwrap();
            assert_eq!((whole.polygon_count, whole.triangles.len()), (2, n as usize - 1));
            assert_eq!(trickled(&src, false).unwrap(), whole);
            // Cut inside the big face, which starts after the first (4 + 12 bytes).
            let start = src.len() - 4 - 4 * n as usize;
            let cut = &src[..src.len() - 5];
            let e = trickled(cut, false).unwrap_err().to_string();
            let expected = format!(
                "t.ply: byte {start}: file ends inside `face` 1 of 2 (the file has {} bytes)",
                cut.len()
            );
            assert!(e.starts_with(&expected), "{e}");
            assert_eq!(e, parse(cut, Path::new("t.ply")).unwrap_err().to_string());
            let e = trickled(cut, true).unwrap_err();
            assert!(matches!(e, Error::Io { .. }), "{e:?}");
            assert_eq!(e.to_string(), "t.ply: the disk is on fire");
        }
        let src = faces_and_vertices(false, "3 0 1 2\n3 0 2 3\n4 1 4 2 0\n", "");
        assert_eq!(trickled(&src, false).unwrap(), parse(&src, Path::new("t.ply")).unwrap());
        for cut in [5, 60, src.len() - 3] {
            let e = trickled(&src[..cut], false).unwrap_err().to_string();
            assert_eq!(e, parse(&src[..cut], Path::new("t.ply")).unwrap_err().to_string());
            let e = trickled(&src[..cut], true).unwrap_err().to_string();
            assert_eq!(e, "t.ply: the disk is on fire", "cut at {cut}");
        }
    }
}
