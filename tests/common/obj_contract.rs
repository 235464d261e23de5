//! The OBJ reader's contract, checked on one input. Shared by the mutation test on stable
//! (`tests/obj_fuzz.rs`) and the cargo-fuzz target (`fuzz/fuzz_targets/obj_parse.rs`), which
//! includes this file by path: two copies of it had drifted apart, and the fuzz target failed
//! on faces the reader triangulates as designed.
//!
//! - `parse` never panics, and `parse_mesh` (the streamed reader) agrees with it;
//! - an error names a line between 1 and the number of lines + 1, with a message;
//! - an accepted mesh is consistent (every corner index in range, faces of 3+ corners, arrays
//!   of equal length), `obj::to_mesh` gives in-range indices, and `window_triangles` and `draw`
//!   on it do not panic (and both rasterizers agree).

use std::path::Path;

use trirast::mesh::{ObjMesh, obj, window_triangles};
use trirast::{Algorithm, Error, RenderOptions, Target};

/// Checks the reader's contract on one input; panics (with a description) if it is broken.
/// Returns whether the input was accepted.
pub fn check(input: &[u8]) -> bool {
    // Lines end at LF, or at CR in a file without LF (classic Mac OS).
    let end = if input.contains(&b'\n') || !input.contains(&b'\r') { b'\n' } else { b'\r' };
    let lines = input.iter().filter(|&&b| b == end).count() + 1;
    let parsed = obj::parse(input);
    same_as_streamed(input, &parsed);
    match parsed {
        Err((line, message)) => {
            assert!(
                (1..=lines + 1).contains(&line),
                "error line {line} outside 1..={} ({message})",
                lines + 1
            );
            assert!(!message.is_empty(), "empty error message at line {line}");
            false
        }
        Ok(mesh) => {
            check_mesh(&mesh, lines);
            true
        }
    }
}

/// `obj::parse_mesh`, which builds the indexed mesh as it reads, gives what `obj::to_mesh` makes
/// of `obj::parse`'s result (compared through `Debug`, so that NaN coordinates compare), or the
/// same error.
fn same_as_streamed(input: &[u8], parsed: &Result<ObjMesh, (usize, String)>) {
    let streamed = obj::parse_mesh(input, Path::new("f.obj"));
    match (parsed, streamed) {
        (Ok(obj), Ok((mut mesh, materials))) => {
            // The same warnings, one naming the file, the other the line only; but colours
            // outside [0, 1] are counted over the vertices the mesh keeps (those faces use),
            // and over every vertex as written, so the mesh may have no such warning where
            // the text has one.
            let colours = |w: &String| w.contains(" components outside [0, 1]");
            let named: Vec<String> = (obj.warnings.iter())
                .filter(|w| !colours(w))
                .map(|w| format!("f.obj{}", w.strip_prefix("line").expect("a line's warning")))
                .collect();
            let warnings = std::mem::take(&mut mesh.warnings);
            let (coloured, others): (Vec<_>, Vec<_>) = warnings.into_iter().partition(colours);
            assert_eq!(others, named, "warnings");
            if !coloured.is_empty() {
                assert!(obj.warnings.iter().any(colours), "{coloured:?}: {:?}", obj.warnings);
            }
            assert_eq!(format!("{mesh:?}"), format!("{:?}", obj::to_mesh(obj)), "streamed mesh");
            assert_eq!(materials, obj.materials, "material statements");
        }
        (Err((line, message)), Err(Error::Parse { line: l, message: m, .. })) => {
            assert_eq!((line, message), (&l, &m), "streamed error");
        }
        (parsed, streamed) => panic!("parse: {parsed:?}, parse_mesh: {streamed:?}"),
    }
}

fn check_mesh(mesh: &ObjMesh, lines: usize) {
    let n = mesh.positions.len();
    assert_eq!(mesh.w.len(), n, "one w per position");
    assert_eq!(mesh.colors.len(), n, "one colour slot per position");
    assert!(mesh.w.iter().all(|&w| w > 0.0 || w.is_nan()), "w <= 0 must be rejected");
    assert_eq!(mesh.face_starts.first(), Some(&0));
    assert_eq!(mesh.face_starts.last().map(|&s| s as usize), Some(mesh.corners.len()));
    assert!(mesh.face_starts.windows(2).all(|w| w[1] >= w[0] + 3), "faces have 3+ corners");
    assert_eq!(mesh.face_lines.len(), mesh.face_count());
    assert!(mesh.face_lines.iter().all(|&l| (1..=lines).contains(&(l as usize))));
    for c in &mesh.corners {
        assert!((c.position as usize) < n, "position {} of {n}", c.position);
        if let Some(t) = c.texcoord {
            assert!((t as usize) < mesh.texcoords.len(), "texcoord {t} out of range");
        }
        if let Some(v) = c.normal {
            assert!((v as usize) < mesh.normals.len(), "normal {v} out of range");
        }
    }
    // The indexed mesh of the 3D pipeline: every triangle index and attribute array in range.
    let indexed = obj::to_mesh(mesh);
    let vertices = indexed.positions.len();
    assert_eq!(indexed.polygon_count, mesh.face_count());
    assert!(indexed.triangles.iter().flatten().all(|&i| (i as usize) < vertices));
    assert!(indexed.normals.as_ref().is_none_or(|a| a.len() == vertices));
    assert!(indexed.texcoords.as_ref().is_none_or(|a| a.len() == vertices));
    assert!(indexed.colors.as_ref().is_none_or(|a| a.len() == vertices));
    if let Some(m) = &indexed.triangle_materials {
        assert_eq!(m.len(), indexed.triangles.len(), "one material per triangle");
        assert!(m.iter().all(|&k| (k as usize) < indexed.materials.len()), "material index");
    }
    let triangles = window_triangles(mesh);
    // A face of n corners gives at most n - 2 triangles (fewer where the triangulation leaves
    // out collinear or repeated corners), in file order: each triangle's corners are corners
    // of its face, the faces taken one after another.
    assert!(triangles.len() <= mesh.triangle_count());
    let mut k = 0;
    for face in mesh.faces() {
        let corners: Vec<[f32; 3]> =
            face.iter().map(|c| mesh.positions[c.position as usize]).collect();
        let of_face = |v: &trirast::Vertex| {
            corners.iter().any(|&[x, y, z]| same(v.x, x) && same(v.y, y) && same(v.z, z))
        };
        while k < triangles.len() && triangles[k].iter().all(of_face) {
            k += 1;
        }
    }
    assert_eq!(k, triangles.len(), "triangle {k} is not of its face, in file order");
    // An accepted mesh may still be undrawable (out-of-range vertices are an error), but
    // drawing it must not panic, and both rasterizers must agree on it.
    let draw = |algorithm| {
        let mut target = Target::new(16, 12).unwrap().with_ids().with_overdraw();
        let options = RenderOptions::default().with_algorithm(algorithm);
        let stats = trirast::draw(&mut target, &triangles, &options).ok();
        (stats, target.ids, target.overdraw, target.depth)
    };
    let (edge, scan) = (draw(Algorithm::EdgeFunctions), draw(Algorithm::Scanline));
    assert_eq!(edge.0, scan.0, "draw stats differ between rasterizers");
    assert_eq!((edge.1, edge.2), (scan.1, scan.2), "ids/overdraw differ between rasterizers");
    let bits = |d: &[f32]| d.iter().map(|z| z.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&edge.3), bits(&scan.3), "depth differs between rasterizers");
}

fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits()
}
