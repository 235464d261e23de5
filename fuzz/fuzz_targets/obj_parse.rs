//! Fuzzes the OBJ reader: `parse` must never panic, an error must name a real line, a mesh it
//! accepts must be safe to turn into triangles and draw, and the streamed reader
//! (`parse_mesh`) must give the mesh `to_mesh` makes of it, or the same error.
//!
//! Run with a nightly toolchain: `cargo +nightly fuzz run obj_parse` (from the crate root).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use trirast::mesh::{obj, window_triangles};
use trirast::{Error, RenderOptions, Target};

fuzz_target!(|data: &[u8]| {
    // Lines end at LF, or at CR in a file without LF.
    let end = if data.contains(&b'\n') || !data.contains(&b'\r') { b'\n' } else { b'\r' };
    let lines = data.iter().filter(|&&b| b == end).count() + 1;
    let parsed = obj::parse(data);
    match (&parsed, obj::parse_mesh(data, Path::new("f.obj"))) {
        (Ok(obj), Ok((mut mesh, _))) => {
            // `to_mesh` makes no warnings; `parse_mesh` names the file in each of its own
            // (unknown statements, colours out of range), which `tests/obj_fuzz.rs` holds to
            // `parse`'s one by one.
            let warnings = std::mem::take(&mut mesh.warnings);
            assert!(warnings.iter().all(|w| w.starts_with("f.obj")), "{warnings:?}");
            assert_eq!(format!("{mesh:?}"), format!("{:?}", obj::to_mesh(obj)));
        }
        (Err((line, message)), Err(Error::Parse { line: l, message: m, .. })) => {
            assert_eq!((line, message), (&l, &m));
        }
        (parsed, streamed) => panic!("parse: {parsed:?}, parse_mesh: {streamed:?}"),
    }
    match parsed {
        Err((line, message)) => {
            assert!((1..=lines).contains(&line), "error line {line} of {lines}: {message}");
            assert!(!message.is_empty());
        }
        Ok(mesh) => {
            for c in &mesh.corners {
                assert!((c.position as usize) < mesh.positions.len());
                assert!(c.texcoord.is_none_or(|t| (t as usize) < mesh.texcoords.len()));
                assert!(c.normal.is_none_or(|n| (n as usize) < mesh.normals.len()));
            }
            let indexed = obj::to_mesh(&mesh);
            let vertices = indexed.positions.len();
            assert!(indexed.triangles.iter().flatten().all(|&i| (i as usize) < vertices));
            let triangles = window_triangles(&mesh);
            // A face of n corners gives at most n - 2 triangles: fewer where its polygon is not
            // simple (a bow-tie quad) or the triangulation leaves out collinear or repeated
            // corners, as `tests/obj_fuzz.rs` asserts too.
            assert!(triangles.len() <= mesh.triangle_count());
            // Drawing may refuse out-of-range vertices, but must not panic.
            let mut target = Target::new(16, 16).unwrap().with_ids().with_overdraw();
            let _ = trirast::draw(&mut target, &triangles, &RenderOptions::default());
        }
    }
});
