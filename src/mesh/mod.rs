//! Mesh input: file readers, the [`Mesh`] they produce, and the window-space view of an OBJ.
//!
//! Readers report errors as [`Error::Parse`] naming the file and the 1-based line (or, for
//! binary files, the byte offset). They read files through [`crate::input`], which refuses a
//! path that is not a regular file ([`Error::NotRegularFile`]).

pub mod mtl;
pub mod obj;
pub mod ply;
pub(crate) mod ply_common;
pub mod stl;

use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::setup::Vertex;

pub use obj::{Corner, MaterialStatements, ObjMesh};

/// A surface material: a diffuse colour, optionally modulated by a texture.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name from the material library (empty when unnamed).
    pub name: String,
    /// Diffuse colour (`Kd`), sRGB-encoded components in [0, 1].
    pub diffuse: [f32; 3],
    /// Diffuse texture (`map_Kd`), resolved relative to the material file.
    pub diffuse_texture: Option<PathBuf>,
    /// The material library and line whose `map_Kd` named `diffuse_texture`, when it came
    /// from one: loading checks only the texture's header, so a body that fails to decode is
    /// found when drawing, and its warning names this line.
    pub texture_statement: Option<(PathBuf, usize)>,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            name: String::new(),
            diffuse: [0.8, 0.8, 0.8],
            diffuse_texture: None,
            texture_statement: None,
        }
    }
}

/// An indexed triangle mesh with optional per-vertex attributes, as the 3D pipeline takes it.
/// Triangles keep the file's winding (counter-clockwise front) and order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (model space).
    pub positions: Vec<[f32; 3]>,
    /// Per-vertex normals, when the file has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Per-vertex texture coordinates (u right, v up), when the file has them.
    pub texcoords: Option<Vec<[f32; 2]>>,
    /// Per-vertex RGBA colours in [0, 1] (sRGB-encoded), when the file has them.
    pub colors: Option<Vec<[f32; 4]>>,
    /// Triangles as indices into the vertex arrays.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of each triangle (same length as `triangles`), when materials exist.
    pub triangle_materials: Option<Vec<u32>>,
    /// Materials referred to by `triangle_materials`.
    pub materials: Vec<Material>,
    /// Faces in the file before triangulation.
    pub polygon_count: usize,
    /// Problems that did not stop loading (a missing texture, say), for the user to see.
    pub warnings: Vec<String>,
    /// The material libraries read (an OBJ's `mtllib` files), in the order read: inputs too,
    /// for a caller that must not write over what it read.
    pub material_libraries: Vec<PathBuf>,
}

/// A mesh file's format, as [`load`] chooses its reader.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// Wavefront OBJ (`.obj`).
    Obj,
    /// Stanford PLY (`.ply`).
    Ply,
    /// STL, ASCII or binary (`.stl`).
    Stl,
}

impl Format {
    /// The format `path`'s extension names, in any case; `None` for any other.
    #[must_use]
    pub fn of(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?;
        [("obj", Self::Obj), ("ply", Self::Ply), ("stl", Self::Stl)]
            .into_iter()
            .find_map(|(name, format)| ext.eq_ignore_ascii_case(name).then_some(format))
    }
}

/// Reads a mesh file for the 3D pipeline, choosing the reader by extension.
pub fn load(path: &Path) -> Result<Mesh, Error> {
    load_reporting(path, &|_| {})
}

/// [`load`], telling `report` how many bytes of the file it has read so far (the furthest
/// offset reached: see [`crate::input::ReadProgress`]), for a progress bar; the last report
/// is the file's size when it was read to its end. A material library or texture is not
/// counted.
///
/// # Errors
/// As [`load`].
pub fn load_reporting(path: &Path, report: &dyn Fn(u64)) -> Result<Mesh, Error> {
    match Format::of(path) {
        Some(Format::Obj) => obj::read_mesh_reporting(path, report),
        Some(Format::Ply) => ply::read_reporting(path, report),
        Some(Format::Stl) => stl::read_reporting(path, report),
        None => match crate::input::open(path) {
            // A directory (or device) is named as such, not as an unknown format.
            Err(e @ Error::NotRegularFile { .. }) => Err(e),
            _ => Err(Error::UnsupportedFormat { path: path.to_path_buf() }),
        },
    }
}

/// Calls `line(text, number)` for each line of a text file read from `input` (numbered from
/// 1), one line in memory at a time. Lines end at LF (a CR before it is left to the caller's
/// whitespace trimming), or at CR in a file without LF (classic Mac OS), which had been read as
/// one line: "expected a number, found `v`" on line 1. Such a file is in memory whole, since
/// only its end shows it has no LF. A UTF-8 byte-order mark (some Windows tools write one) is
/// not part of the first line. `io` wraps a read error.
pub(crate) fn read_lines<E>(
    mut input: impl std::io::BufRead,
    io: impl Fn(std::io::Error) -> E,
    mut line: impl FnMut(&[u8], usize) -> Result<(), E>,
) -> Result<(), E> {
    // Lines are handed on from `input`'s buffer where they lie whole in it; only one split
    // across two fills is put together in `carry`. Copying every line out (`read_until`) and
    // its byte-at-a-time search for LF had been a sixth of loading an OBJ.
    let mut carry = Vec::new();
    let mut number = 0;
    loop {
        let chunk = match input.fill_buf() {
            Ok(chunk) => chunk,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(io(e)),
        };
        if chunk.is_empty() {
            break;
        }
        let filled = chunk.len();
        let mut rest = chunk;
        while let Some(k) = memchr::memchr(b'\n', rest) {
            let text = if carry.is_empty() {
                &rest[..k]
            } else {
                carry.extend_from_slice(&rest[..k]);
                &carry[..]
            };
            number += 1;
            line(if number == 1 { without_bom(text) } else { text }, number)?;
            carry.clear();
            rest = &rest[k + 1..];
        }
        carry.extend_from_slice(rest);
        input.consume(filled);
    }
    if number == 0 && !carry.is_empty() {
        // The file has no LF: lines end at CR, if any.
        for (n, piece) in without_bom(&carry).split(|&b| b == b'\r').enumerate() {
            line(piece, n + 1)?;
        }
    } else if !carry.is_empty() {
        line(&carry, number + 1)?;
    }
    Ok(())
}

/// The first line without a UTF-8 byte-order mark.
fn without_bom(text: &[u8]) -> &[u8] {
    text.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(text)
}

/// `bytes` as a message quotes them: UTF-8 as it is, each other byte as `\xNN`, so a message
/// says which byte it was (`\xff`, where U+FFFD would not), escaped as the command line
/// escapes control characters (`\u{1b}`).
pub(crate) fn shown(bytes: &[u8]) -> std::borrow::Cow<'_, str> {
    shown_at_most(bytes, usize::MAX).0
}

/// [`shown`] of the first `n` characters and other bytes of `bytes`, and whether there were
/// more: cut before escaping, so that no `\xNN` is cut through.
pub(crate) fn shown_at_most(bytes: &[u8], n: usize) -> (std::borrow::Cow<'_, str>, bool) {
    if let Ok(text) = std::str::from_utf8(bytes) {
        return match text.char_indices().nth(n) {
            Some((cut, _)) => (text[..cut].into(), true),
            None => (text.into(), false),
        };
    }
    let (mut out, mut left) = (String::with_capacity(bytes.len() + 8), n);
    for chunk in bytes.utf8_chunks() {
        for c in chunk.valid().chars() {
            if left == 0 {
                return (out.into(), true);
            }
            out.push(c);
            left -= 1;
        }
        for b in chunk.invalid() {
            if left == 0 {
                return (out.into(), true);
            }
            out.push_str(&format!("\\x{b:02x}"));
            left -= 1;
        }
    }
    (out.into(), false)
}

/// The statement of an MTL line `raw`: the text before any `#`, trimmed, bytes that are not
/// UTF-8 replaced (U+FFFD). Exporters write names in other encodings (Latin-1); a name so
/// read still matches the OBJ's `usemtl`, whose words are converted the same way.
pub(crate) fn statement_text(raw: &[u8]) -> std::borrow::Cow<'_, str> {
    let raw = memchr::memchr(b'#', raw).map_or(raw, |k| &raw[..k]);
    match String::from_utf8_lossy(raw) {
        std::borrow::Cow::Borrowed(text) => std::borrow::Cow::Borrowed(text.trim()),
        std::borrow::Cow::Owned(text) => std::borrow::Cow::Owned(text.trim().to_string()),
    }
}

/// The words of an OBJ line `raw`: its bytes split at ASCII whitespace, up to any `#`. Words
/// stay bytes, whatever their encoding: names (`o`, `usemtl`, `mtllib`) are made text with
/// their bytes that are not UTF-8 replaced, and a number or index that is not ASCII is an
/// error naming it; making text of every line (`str::from_utf8`, then trimmed and split) had
/// been a third of loading an OBJ, and `o caf\xe9` (Latin-1) had been refused.
pub(crate) fn statement_words(raw: &[u8]) -> Words<'_> {
    Words { rest: raw }
}

/// [`statement_words`]' iterator.
pub(crate) struct Words<'a> {
    /// What is left of the line; empty from its `#` on.
    rest: &'a [u8],
}

impl<'a> Iterator for Words<'a> {
    type Item = &'a [u8];

    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.rest.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.rest[start..];
        let end = rest.iter().position(|&b| b.is_ascii_whitespace() || b == b'#');
        let end = end.unwrap_or(rest.len());
        self.rest = if rest.get(end) == Some(&b'#') { &[] } else { &rest[end..] };
        (end > 0).then_some(&rest[..end])
    }
}

/// The warning for a file whose vertex colours have components outside [0, 1] (NaN
/// among them), which are drawn clamped (NaN as 0), or `None`: a PLY file with `float`
/// colours from 0 to 255 had been drawn white without a word.
pub(crate) fn colour_warning<const N: usize>(
    file: impl std::fmt::Display,
    colours: impl IntoIterator<Item = [f32; N]>,
) -> Option<String> {
    let (mut outside, mut low, mut high) = (0usize, 0.0f32, 1.0f32);
    for colour in colours {
        if colour.iter().any(|c| !(0.0..=1.0).contains(c)) {
            outside += 1;
            low = colour.iter().fold(low, |m, &c| m.min(c));
            high = colour.iter().fold(high, |m, &c| m.max(c));
        }
    }
    if outside == 0 {
        return None;
    }
    let what = if outside == 1 { "vertex colour has" } else { "vertex colours have" };
    // The extremes beyond the range (NaN has none).
    let range = match (low < 0.0, high > 1.0) {
        (true, true) => format!(" (from {low} to {high})"),
        (true, false) => format!(" (down to {low})"),
        (false, true) => format!(" (up to {high})"),
        (false, false) => String::new(),
    };
    Some(format!(
        "{file}: {outside} {what} components outside [0, 1]{range}; they are drawn clamped to it"
    ))
}

/// Converts a colour in [0, 1] (clamped) to `u8`, rounding to nearest.
#[must_use]
pub fn unorm8(c: f32) -> u8 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (c * 255.0).round_ties_even() as u8
}

/// The mesh's faces as window-space triangles: `v x y z` is a position in pixels (y down) with
/// depth `z`, an optional `w` gives `1/w` for perspective-correct shading, and an optional
/// colour in [0, 1] is the vertex colour (white when absent). Faces are polygons in the
/// window's x-y plane ([`crate::polygon::triangulate_polygon`], wound like the face): a
/// strictly convex face of n corners becomes the fan `(c0, c_i, c_i+1)`, a concave one its
/// triangulation (the fan drew a dart over its notch, twice over part of it). Triangles are
/// numbered in file order, face by face. A face that does not triangulate (zero area, a
/// corner on one point three times) is fanned, for the rasterizer to count or draw as before;
/// one with a NaN or infinite corner becomes the fan from that corner, all of which the
/// rasterizer drops and counts.
///
/// # Panics
/// If `mesh` does not hold together (see [`ObjMesh`]).
#[must_use]
pub fn window_triangles(mesh: &ObjMesh) -> Vec<[Vertex; 3]> {
    let vertex = |c: &Corner| {
        let i = c.position as usize;
        let [x, y, z] = mesh.positions[i];
        let color = mesh
            .colors
            .get(i)
            .copied()
            .flatten()
            .map_or([255; 4], |[r, g, b]| [unorm8(r), unorm8(g), unorm8(b), 255]);
        Vertex { x, y, z, inv_w: 1.0 / mesh.w[i], color }
    };
    let mut out = Vec::with_capacity(mesh.triangle_count());
    for face in mesh.faces() {
        if face.len() == 3 {
            out.push([vertex(&face[0]), vertex(&face[1]), vertex(&face[2])]);
            continue;
        }
        let corners: Vec<Vertex> = face.iter().map(vertex).collect();
        out.extend(window_face(&corners).into_iter().map(|t| t.map(|i| corners[i])));
    }
    out
}

/// The triangles of one window-space face (see [`window_triangles`]), as corner indices.
fn window_face(corners: &[Vertex]) -> Vec<[usize; 3]> {
    use crate::polygon::{fan_from, triangulate_polygon};
    let n = corners.len();
    if let Some(k) = corners.iter().position(|c| !(c.x.is_finite() && c.y.is_finite())) {
        return fan_from(n, k);
    }
    let ring: Vec<[f64; 2]> = corners.iter().map(|c| [f64::from(c.x), f64::from(c.y)]).collect();
    let tris = triangulate_polygon(&[ring]);
    if tris.is_empty() { fan_from(n, 0) } else { tris }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// Faces of fewer than three corners in a mesh made by hand give no triangles and count
    /// none, where the count had wrapped (and asked for an impossible allocation).
    #[test]
    fn hand_made_faces_of_fewer_than_three_corners_give_no_triangles() {
        let corner = |position| Corner { position, texcoord: None, normal: None };
        let obj = ObjMesh {
            positions: vec![[0.0; 3], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0]],
            w: vec![1.0; 3],
            colors: vec![None; 3],
            corners: [0, 1, 2, 0, 1, 0].map(corner).to_vec(),
            face_starts: vec![0, 0, 3, 5, 6],
            ..ObjMesh::default()
        };
        assert_eq!((obj.face_count(), obj.triangle_count()), (4, 1));
        assert_eq!(window_triangles(&obj).len(), 1);
    }

    /// The format is the extension's in any case, and nothing else names one: not a name
    /// without an extension, nor one that ends in a format's name.
    #[test]
    fn formats_are_named_by_the_extension_in_any_case() {
        let of = |name: &str| Format::of(Path::new(name));
        assert_eq!(of("bunny.obj"), Some(Format::Obj));
        assert_eq!(of("dir.v2/BUNNY.OBJ"), Some(Format::Obj));
        assert_eq!(of("scan.Ply"), Some(Format::Ply));
        assert_eq!(of("part.sTl"), Some(Format::Stl));
        for other in ["obj", "bunny", "bunny.objx", "bunny.pobj", "cloud.tsplat", ".obj/x", "x."] {
            assert_eq!(of(other), None, "{other}");
        }
    }

    /// Vertex colours outside [0, 1] are a warning naming the file, the count and the range,
    /// from each reader that has colours; colours within it are not.
    #[test]
    fn colours_outside_the_unit_range_are_warned_of() {
        let dir = std::env::temp_dir().join(format!("trirast-colours-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ply = |colours: [&str; 3]| {
            let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                        property float y\nproperty float z\nproperty float red\n\
                        property float green\nproperty float blue\nelement face 1\n\
                        property list uchar int vertex_indices\nend_header\n";
            let [a, b, c] = colours;
            format!("{head}0 0 0 {a}\n1 0 0 {b}\n0 1 0 {c}\n3 0 1 2\n")
        };
        let obj = |colours: [&str; 3]| {
            let [a, b, c] = colours;
            format!("v 0 0 0 {a}\nv 1 0 0 {b}\nv 0 1 0 {c}\nf 1 2 3\n")
        };
        let within = ["0 0.5 1", "1 1 1", "0 0 0"];
        let outside = ["255 0 0", "0 128 0", "0.5 -0.25 NaN"];
        for (ext, text) in [("ply", ply as fn([&str; 3]) -> String), ("obj", obj)] {
            let file = dir.join(format!("m.{ext}"));
            std::fs::write(&file, text(within)).unwrap();
            assert_eq!(load(&file).unwrap().warnings, Vec::<String>::new());
            std::fs::write(&file, text(outside)).unwrap();
            let want = format!(
                "{}: 3 vertex colours have components outside [0, 1] (from -0.25 to 255); they \
                 are drawn clamped to it",
                file.display()
            );
            assert_eq!(load(&file).unwrap().warnings, std::slice::from_ref(&want));
            if ext == "obj" {
                assert_eq!(obj::read(&file).unwrap().warnings, std::slice::from_ref(&want));
                let bytes = text(outside).into_bytes();
                assert_eq!(obj::parse_mesh(&bytes, &file).unwrap().0.warnings, [want]);
            }
        }
        let file = dir.join("one.obj");
        std::fs::write(&file, obj(["2 0 0", "1 1 1", "NaN 0 0"])).unwrap();
        let warnings = load(&file).unwrap().warnings;
        assert!(warnings[0].ends_with(": 2 vertex colours have components outside [0, 1] (up to 2); they are drawn clamped to it"), "{warnings:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Lines are the same whatever the reader's buffer size, so for lines split across two
    /// fills: LF and CRLF endings, a last line without LF, a byte-order mark, and files
    /// without LF, whose lines end at CR.
    #[test]
    fn lines_do_not_depend_on_the_buffer() {
        fn lines(bytes: &[u8], capacity: usize) -> Vec<(Vec<u8>, usize)> {
            let mut out = Vec::new();
            let input = std::io::BufReader::with_capacity(capacity, bytes);
            let push = |text: &[u8], n| {
                out.push((text.to_vec(), n));
                Ok::<_, std::io::Error>(())
            };
            read_lines(input, |e| e, push).unwrap();
            out
        }
        let mut rng = SmallRng::seed_from_u64(5);
        for round in 0..2000 {
            let len = rng.random_range(0..60);
            let alphabet = if round % 3 == 0 { &b"ab \r"[..] } else { &b"ab #\r\n\n"[..] };
            let mut bytes: Vec<u8> =
                (0..len).map(|_| alphabet[rng.random_range(0..alphabet.len())]).collect();
            if round % 5 == 0 {
                bytes.splice(0..0, *b"\xEF\xBB\xBF");
            }
            // One fill holds the whole file: the lines as split by hand.
            let whole = lines(&bytes, 1 << 16);
            let body = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
            let separator = if body.contains(&b'\n') { b'\n' } else { b'\r' };
            let mut want: Vec<Vec<u8>> =
                body.split(|&b| b == separator).map(<[u8]>::to_vec).collect();
            if separator == b'\n' && body.ends_with(b"\n") || bytes.is_empty() {
                want.pop();
            }
            let want: Vec<_> = want.into_iter().zip(1..).collect();
            assert_eq!(whole, want, "{bytes:?}");
            for capacity in [1, 2, 3, 7] {
                assert_eq!(lines(&bytes, capacity), whole, "{bytes:?} in fills of {capacity}");
            }
        }
    }

    /// `v x y z w r g b` gives a window vertex both its `1 / w` and its colour (`w` and the
    /// colour had excluded each other, so `--shading perspective` changed nothing of a
    /// coloured scene); `w` alone leaves it white, the colour alone sets `w` to 1.
    #[test]
    fn window_vertices_take_w_and_colour_together() {
        let text = b"v 0 0 0.5 2 1 0 0\nv 10 0 0.5 4\nv 0 10 0.5 0 0 1\nf 1 2 3\n";
        let [a, b, c] = window_triangles(&obj::parse(text).unwrap())[0];
        assert_eq!((a.inv_w, a.color), (0.5, [255, 0, 0, 255]));
        assert_eq!((b.inv_w, b.color), (0.25, [255; 4]));
        assert_eq!((c.inv_w, c.color), (1.0, [0, 0, 255, 255]));
        let err = obj::parse(b"v 0 0 0 1e-39\n").unwrap_err();
        assert_eq!(err, (1, "`v` has w = 1e-39, too small for 1 / w in f32".into()));
        let err = obj::parse(b"v 0 0 0 1 2 3 4 5\n").unwrap_err();
        assert_eq!(err, (1, "`v` takes x y z [w] or x y z [w] r g b, found 8 numbers".into()));
    }

    /// A concave face is drawn as its polygon: its triangles tile the dart (each wound like
    /// the face, their areas adding up to its area), where the fan covered the notch too. A
    /// NaN corner is in every triangle of its face, so the rasterizer drops them all.
    #[test]
    fn window_faces_are_triangulated_as_polygons() {
        let dart = b"v 100 100 0.5\nv 500 400 0.5\nv 900 100 0.5\nv 500 900 0.5\nf 1 2 3 4\n";
        let mesh = obj::parse(dart).unwrap();
        let tris = window_triangles(&mesh);
        assert_eq!(tris.len(), 2);
        let area2 = |[a, b, c]: [Vertex; 3]| (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        // Twice the face's signed area (shoelace) is 400,000.
        assert!(tris.iter().all(|&t| area2(t) > 0.0));
        assert_eq!(tris.iter().map(|&t| area2(t)).sum::<f32>(), 400_000.0);
        // A convex face is the fan from its first corner, as ever.
        let square = b"v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nf 1 2 3 4\n";
        let tris = window_triangles(&obj::parse(square).unwrap());
        let corners: Vec<[f32; 2]> = tris.iter().flatten().map(|v| [v.x, v.y]).collect();
        assert_eq!(corners, [[0., 0.], [4., 0.], [4., 4.], [0., 0.], [4., 4.], [0., 4.]]);
        let nan = b"v 100 100 0.5\nv 500 400 0.5\nv nan 100 0.5\nv 500 900 0.5\nf 1 2 3 4\n";
        let tris = window_triangles(&obj::parse(nan).unwrap());
        assert_eq!(tris.len(), 2);
        assert!(tris.iter().all(|t| t.iter().any(|v| v.x.is_nan())));
    }
}
