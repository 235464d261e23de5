//! Fuzzes the `.tsplat` decoder: `format::decode` must never panic, an error must name a byte
//! of the input, and a tree it accepts must be breadth-first with its children in range.
//! Encoding is lossy (docs/tsplat.md), so `encode(decode(x)) == x` is not promised and not
//! checked; what is: re-encoding an accepted tree gives a file that decodes, to a tree with the
//! same structure (child counts and first children), the same colours and root centre, normals
//! within rounding of the first (or zero with them), cones at least as wide, and (when its
//! spheres are finite) spheres that contain every sphere of their subtree in the first tree.
//!
//! The input is decoded as it is, then with its checksum recomputed, so that the checks after
//! the checksum are reached (a random input almost never has the right one).
//!
//! Run (from `fuzz/`): `RUSTC_BOOTSTRAP=1 cargo fuzz run -O tsplat_decode -- -timeout=10`, or
//! with a nightly toolchain `cargo +nightly fuzz run -O tsplat_decode`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use trirast::splat::format::{self, FormatError, HEADER_BYTES};
use trirast::splat::{SplatNode, SplatTree};

/// CRC-32 (IEEE), bit by bit, of every byte but the checksum field (48..52).
fn checksum(b: &[u8]) -> u32 {
    let mut c = !0u32;
    for &byte in b[..48].iter().chain(&b[52..]) {
        c ^= u32::from(byte);
        for _ in 0..8 {
            c = if c & 1 != 0 { 0xEDB8_8320 ^ (c >> 1) } else { c >> 1 };
        }
    }
    !c
}

fn check_error(e: &FormatError, len: usize) {
    assert!(e.offset <= len, "{e} in {len} bytes");
    assert!(e.to_string().starts_with(&format!("byte {}: ", e.offset)));
}

fn f64s(v: [f32; 3]) -> [f64; 3] {
    v.map(f64::from)
}

fn distance(a: [f32; 3], b: [f32; 3]) -> f64 {
    let (a, b) = (f64s(a), f64s(b));
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

fn angle(a: [f32; 3], b: [f32; 3]) -> f64 {
    let (a, b) = (f64s(a), f64s(b));
    let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let len = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    (dot / (len(a) * len(b))).clamp(-1.0, 1.0).acos()
}

/// Every node's children follow it, in range; returns each node's parent.
fn check_structure(tree: &SplatTree) -> Vec<usize> {
    let n = tree.nodes.len();
    let mut parent = vec![usize::MAX; n];
    for (i, node) in tree.nodes.iter().enumerate() {
        assert!(node.child_count <= 4);
        if node.child_count > 0 {
            assert!(node.first_child as usize > i && node.children().end <= n, "{node:?}");
        }
        for c in node.children() {
            assert_eq!(parent[c], usize::MAX, "node {c} has two parents");
            parent[c] = i;
        }
    }
    assert!(parent.iter().skip(1).all(|&p| p != usize::MAX));
    parent
}

fn finite(node: &SplatNode) -> bool {
    node.centre.iter().chain([&node.radius]).all(|v| v.is_finite() && v.abs() < 1e30)
}

fuzz_target!(|data: &[u8]| {
    if let Err(e) = format::decode(data) {
        check_error(&e, data.len());
    }
    let mut fixed = data.to_vec();
    if fixed.len() >= HEADER_BYTES {
        let crc = checksum(&fixed);
        fixed[48..52].copy_from_slice(&crc.to_le_bytes());
    }
    let tree = match format::decode(&fixed) {
        Ok(tree) => tree,
        Err(e) => return check_error(&e, fixed.len()),
    };
    let parent = check_structure(&tree);
    let bytes = format::encode(&tree).expect("encoding a decoded tree");
    assert_eq!(bytes.len(), HEADER_BYTES + 6 * tree.nodes.len());
    let again = format::decode(&bytes).unwrap_or_else(|e| panic!("re-encoded file: {e}"));
    assert_eq!(again.nodes.len(), tree.nodes.len());
    for (a, b) in tree.nodes.iter().zip(&again.nodes) {
        assert_eq!(
            (a.child_count, a.first_child, a.color),
            (b.child_count, b.first_child, b.color)
        );
        if a.normal == [0.0; 3] || b.normal == [0.0; 3] {
            assert_eq!(a.normal, b.normal);
        } else {
            assert!(angle(a.normal, b.normal) < 1e-5, "{:?} -> {:?}", a.normal, b.normal);
        }
        assert!(b.cone >= a.cone, "cone {} -> {}", a.cone, b.cone);
    }
    if let (Some(a), Some(b)) = (tree.nodes.first(), again.nodes.first()) {
        assert_eq!(a.centre, b.centre);
    }
    // Containment: each re-decoded sphere holds the first tree's spheres of its subtree.
    if tree.nodes.iter().all(finite) {
        for (i, node) in tree.nodes.iter().enumerate() {
            let mut k = i;
            loop {
                let outer = &again.nodes[k];
                let need = distance(node.centre, outer.centre) + f64::from(node.radius);
                let slack = 1e-9 * f64::from(outer.radius).max(1e-30);
                assert!(need <= f64::from(outer.radius) + slack, "node {i} outside node {k}");
                if k == 0 {
                    break;
                }
                k = parent[k];
            }
        }
    }
});
