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
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => obj::read_mesh_reporting(path, report),
        Some("ply") => ply::read_reporting(path, report),
        Some("stl") => stl::read_reporting(path, report),
        _ => Err(Error::UnsupportedFormat { path: path.to_path_buf() }),
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
    let mut buffer = Vec::new();
    let mut number = 0;
    loop {
        buffer.clear();
        if input.read_until(b'\n', &mut buffer).map_err(&io)? == 0 {
            return Ok(());
        }
        let mut text = &buffer[..];
        if number == 0 {
            text = text.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(text);
            if !text.ends_with(b"\n") && text.contains(&b'\r') {
                // This first read reached the end: the file has no LF.
                for (n, piece) in text.split(|&b| b == b'\r').enumerate() {
                    line(piece, n + 1)?;
                }
                return Ok(());
            }
        }
        number += 1;
        line(text.strip_suffix(b"\n").unwrap_or(text), number)?;
    }
}

/// The statement of an OBJ or MTL line `raw` (number `line`): the text before any `#`,
/// trimmed. Only that text need be UTF-8: exporters write names in other encodings (Latin-1)
/// into comments, and a file is not refused for them.
pub(crate) fn statement_text(raw: &[u8], line: usize) -> Result<&str, (usize, String)> {
    let raw = raw.iter().position(|&b| b == b'#').map_or(raw, |k| &raw[..k]);
    let text = std::str::from_utf8(raw).map_err(|_| (line, "not valid UTF-8".to_string()))?;
    Ok(text.trim())
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
