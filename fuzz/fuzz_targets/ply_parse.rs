//! Fuzzes the two PLY readers on the same input: the mesh reader (`mesh::ply::parse`) and the
//! point-cloud reader (`splat::cloud::parse_ply`) must never panic, and an error must be an
//! `Error::Parse` naming the file and a real line (or, in a binary body, a byte of the input).
//! A mesh it accepts has finite positions, triangles that index only its vertices, and one
//! normal, colour and texture coordinate per vertex when it has them; a cloud has finite
//! positions, one normal (unit or zero), colour and radius (finite, >= 0) per point when it has
//! them, and when both accept they read the same positions.
//!
//! Run (from `fuzz/`): `RUSTC_BOOTSTRAP=1 cargo fuzz run -O ply_parse -- -timeout=10`, or with
//! a nightly toolchain `cargo +nightly fuzz run -O ply_parse`.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use trirast::Error;
use trirast::mesh::ply;
use trirast::splat::cloud;

/// Checks that `e` names `f.ply` and a line of `data` (or a byte of it, in a binary body).
fn check_error(e: &Error, data: &[u8]) {
    let Error::Parse { path, line, message } = e else { panic!("not a parse error: {e:?}") };
    assert_eq!(path, Path::new("f.ply"));
    assert!(!message.is_empty());
    let lines = data.iter().filter(|&&b| b == b'\n').count() + 1;
    if *line == 0 {
        let byte = message.strip_prefix("byte ").and_then(|m| m.split(':').next());
        let byte: usize = byte.and_then(|b| b.parse().ok()).unwrap_or_else(|| panic!("{e}"));
        assert!(byte <= data.len(), "{e}");
    } else {
        assert!(*line <= lines, "line {line} of {lines}: {e}");
    }
}

fuzz_target!(|data: &[u8]| {
    let path = Path::new("f.ply");
    let mesh = ply::parse(data, path);
    match &mesh {
        Err(e) => check_error(e, data),
        Ok(mesh) => {
            let n = mesh.positions.len();
            assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()));
            assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n));
            assert!(mesh.normals.as_ref().is_none_or(|v| v.len() == n));
            assert!(mesh.texcoords.as_ref().is_none_or(|v| v.len() == n));
            assert!(mesh.colors.as_ref().is_none_or(|v| v.len() == n));
            assert!(mesh.triangle_materials.is_none() && mesh.materials.is_empty());
        }
    }
    let points = cloud::parse_ply(data, path);
    match &points {
        Err(e) => check_error(e, data),
        Ok(points) => {
            let n = points.len();
            assert!(points.positions.iter().flatten().all(|c| c.is_finite()));
            assert!(points.colors.as_ref().is_none_or(|v| v.len() == n));
            assert!(points.radii.as_ref().is_none_or(|v| v.len() == n));
            assert!(points.radii.iter().flatten().all(|r| r.is_finite() && *r >= 0.0));
            let normals = points.normals.as_deref().unwrap_or_default();
            assert!(points.normals.is_none() || normals.len() == n);
            for v in normals {
                let len = v.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt();
                assert!(len == 0.0 || (len - 1.0).abs() < 1e-5, "normal {v:?}");
            }
        }
    }
    if let (Ok(mesh), Ok(points)) = (&mesh, &points) {
        assert_eq!(mesh.positions, points.positions);
    }
});
