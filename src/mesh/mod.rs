//! Mesh input: file readers, and the window-space view of a mesh.
//!
//! Readers report errors as [`Error::Parse`] naming the file and the 1-based line.

pub mod obj;

use std::path::Path;

use crate::error::Error;
use crate::setup::Vertex;

pub use obj::{Corner, ObjMesh};

/// Reads a mesh file, choosing the reader by extension (currently `.obj`).
pub fn load(path: &Path) -> Result<ObjMesh, Error> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("obj") => obj::read(path),
        _ => Err(Error::Parse {
            path: path.to_path_buf(),
            line: 0,
            message: "unsupported mesh format: expected a .obj file".into(),
        }),
    }
}

/// Converts a colour in [0, 1] (clamped) to `u8`, rounding to nearest.
#[must_use]
pub fn unorm8(c: f32) -> u8 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    (c * 255.0).round_ties_even() as u8
}

/// The mesh's faces as window-space triangles: `v x y z` is a position in pixels (y down) with
/// depth `z`, an optional `w` gives `1/w` for perspective-correct shading, and an optional
/// colour in [0, 1] is the vertex colour (white when absent). A face of n corners becomes the
/// fan `(c0, c_i, c_i+1)`, n - 2 triangles numbered in file order.
#[must_use]
pub fn window_triangles(mesh: &ObjMesh) -> Vec<[Vertex; 3]> {
    let vertex = |c: &Corner| {
        let i = c.position as usize;
        let [x, y, z] = mesh.positions[i];
        let color = mesh.colors.get(i).copied().flatten().map_or([255; 4], |[r, g, b]| {
            [unorm8(r), unorm8(g), unorm8(b), 255]
        });
        Vertex { x, y, z, inv_w: 1.0 / mesh.w[i], color }
    };
    let mut out = Vec::with_capacity(mesh.triangle_count());
    for face in mesh.faces() {
        let c0 = vertex(&face[0]);
        for pair in face[1..].windows(2) {
            out.push([c0, vertex(&pair[0]), vertex(&pair[1])]);
        }
    }
    out
}
