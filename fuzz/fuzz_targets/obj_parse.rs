//! Fuzzes the OBJ reader against its contract (`tests/common/obj_contract.rs`, the one the
//! mutation test `tests/obj_fuzz.rs` checks on stable): `parse` never panics, the streamed
//! reader agrees with it, an error names a real line, and a mesh it accepts is consistent and
//! safe to triangulate and draw, both rasterizers agreeing on it.
//!
//! Run with a nightly toolchain: `cargo +nightly fuzz run obj_parse` (from the crate root).
#![no_main]

#[path = "../../tests/common/obj_contract.rs"]
mod obj_contract;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    obj_contract::check(data);
});
