//! Fuzzes the MTL reader: `mtl::parse` must never panic, an error (or a warning of an ignored
//! line) must name a real line with a message, and every `Kd` colour it accepts is in [0, 1].
//!
//! Run (from `fuzz/`): `RUSTC_BOOTSTRAP=1 cargo fuzz run -O mtl_parse -- -timeout=10`, or with
//! a nightly toolchain `cargo +nightly fuzz run -O mtl_parse`.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use trirast::mesh::mtl;

fuzz_target!(|data: &[u8]| {
    match mtl::parse(data, Path::new(".")) {
        Err((line, message)) => {
            // Lines end at LF, or at CR in a file without LF.
            let end = if data.contains(&b'\n') || !data.contains(&b'\r') { b'\n' } else { b'\r' };
            let lines = data.iter().filter(|&&b| b == end).count() + 1;
            assert!((1..=lines).contains(&line), "error line {line} of {lines}: {message}");
            assert!(!message.is_empty());
        }
        Ok(lib) => {
            let end = if data.contains(&b'\n') || !data.contains(&b'\r') { b'\n' } else { b'\r' };
            let lines = data.iter().filter(|&&b| b == end).count() + 1;
            for w in &lib.warnings {
                let line = w.strip_prefix("line ").and_then(|w| w.split_once(':'));
                if let Some((line, _)) = line {
                    let line: usize = line.parse().expect("a line number");
                    assert!((1..=lines).contains(&line), "warning line {line} of {lines}: {w}");
                }
            }
            for m in &lib.materials {
                assert!(m.diffuse.iter().all(|c| (0.0..=1.0).contains(c)), "{m:?}");
            }
        }
    }
});
