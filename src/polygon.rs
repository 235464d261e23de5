//! Polygon triangulation: faces of meshes, and exact filling of 2D polygons.

/// Triangulates one planar face given its corner positions in order; returns triangles as
/// indices into `points`, keeping the face's winding.
#[must_use]
pub fn triangulate_face(points: &[[f32; 3]]) -> Vec<[usize; 3]> {
    // Convex faces: the lectures' fan (v0, vi, vi+1).
    (1..points.len().saturating_sub(1)).map(|i| [0, i, i + 1]).collect()
}
