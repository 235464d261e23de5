//! Fuzzes the STL reader: the streamed reader (`parse_streamed`, what `stl::read` runs on a
//! file) must give what the in-memory reference (`parse`) gives, the same mesh or the same
//! error, and never panic; a mesh it accepts must index only its own vertices.
//!
//! Run with a nightly toolchain: `cargo +nightly fuzz run stl_parse` (from the crate root).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use trirast::mesh::stl;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("f.stl");
    let reference = stl::parse(data, path);
    let streamed = stl::parse_streamed(data, path);
    assert_eq!(format!("{reference:?}"), format!("{streamed:?}"));
    if let Ok(mesh) = reference {
        let vertices = mesh.positions.len();
        assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < vertices));
    }
});
