//! Point clouds (`trirast::splat::cloud`): PLY reading and writing, and sampling meshes.
//!
//! - PLY: clouds with every combination of attributes are written and read back bit for bit;
//!   hand-written ASCII, binary little-endian and binary big-endian files (other spellings and
//!   types, faces before and after the vertices) read as expected; malformed files give errors
//!   naming the file and the line or byte offset, and no truncation or mutation panics.
//! - Sampling: exactly `n` points, on the surface, spread by area (two triangles of areas 1 and
//!   3 get about 1/4 and 3/4 of the points) and uniformly within a triangle; normals, colours
//!   (vertex colours, texture, material, default) and radii as documented; the same seed gives
//!   the same cloud whatever the number of threads, another seed another cloud.
//!
//! Everything is generated in code; `../shared/models` is sampled too when it exists.

use std::fs;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::Error;
use trirast::color::{linear_to_srgb8, srgb_decode};
use trirast::mesh::{Material, Mesh};
use trirast::model::MaterialTextures;
use trirast::splat::cloud::{
    PointCloud, parse_ply, read_ply, sample_mesh, sample_mesh_with_textures, write_ply,
};
use trirast::splat::tree::SplatTree;
use trirast::texture::{Filter, Texture, Wrap};

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("splat_cloud").join(name);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

fn bits3(v: &[[f32; 3]]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.map(f32::to_bits)).collect()
}

/// Asserts `a` and `b` are the same cloud, comparing floats bit for bit (so -0.0 != 0.0).
fn assert_identical(a: &PointCloud, b: &PointCloud) {
    assert_eq!(bits3(&a.positions), bits3(&b.positions));
    assert_eq!(a.normals.as_deref().map(bits3), b.normals.as_deref().map(bits3));
    assert_eq!(a.colors, b.colors);
    let radii = |c: &PointCloud| c.radii.as_ref().map(|r| r.iter().map(|x| x.to_bits()).collect());
    let (ra, rb): (Option<Vec<u32>>, Option<Vec<u32>>) = (radii(a), radii(b));
    assert_eq!(ra, rb);
}

fn unit(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / l)
}

fn random_cloud(seed: u64, n: usize, normals: bool, colors: bool, radii: bool) -> PointCloud {
    let mut rng = SmallRng::seed_from_u64(seed);
    let special = [0.0, -0.0, 1e-40, -3.4e38, f32::MIN_POSITIVE, 1.0 + f32::EPSILON, 123_456.79];
    let mut positions: Vec<[f32; 3]> =
        (0..n).map(|_| std::array::from_fn(|_| rng.random_range(-1000.0f32..1000.0))).collect();
    for (i, &s) in special.iter().enumerate().take(n) {
        positions[i] = [s, -s, s * 0.5];
    }
    let normals = normals.then(|| {
        let mut v: Vec<[f32; 3]> = (0..n)
            .map(|_| unit(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0) + f32::EPSILON)))
            .collect();
        if n > 2 {
            v[0] = [0.0; 3];
            v[1] = [0.0, 0.0, -1.0];
        }
        v
    });
    let colors = colors.then(|| (0..n).map(|_| rng.random()).collect());
    let radii = radii.then(|| {
        let mut r: Vec<f32> = (0..n).map(|_| rng.random_range(0.0f32..5.0)).collect();
        if n > 0 {
            r[0] = 0.0;
        }
        r
    });
    PointCloud { positions, normals, colors, radii, ..PointCloud::default() }
}

// ------------------------------------------------------------------------------------------
// PLY round trip and hand-written files
// ------------------------------------------------------------------------------------------

#[test]
fn write_then_read_is_bit_exact_for_every_attribute_combination() {
    let dir = scratch("round_trip");
    for mask in 0..8u32 {
        for n in [0, 1, 50] {
            let cloud = random_cloud(
                u64::from(mask) * 7 + n as u64,
                n,
                mask & 1 != 0,
                mask & 2 != 0,
                mask & 4 != 0,
            );
            let path = dir.join(format!("cloud_{mask}_{n}.ply"));
            write_ply(&path, &cloud).unwrap();
            let back = read_ply(&path).unwrap();
            assert_identical(&back, &cloud);
            assert_eq!(back, cloud);
            let bytes = fs::read(&path).unwrap();
            let text = String::from_utf8_lossy(&bytes);
            assert!(text.starts_with("ply\nformat binary_little_endian 1.0\n"), "{text}");
            assert_eq!(text.contains("property float nx"), mask & 1 != 0);
            assert_eq!(text.contains("property uchar red"), mask & 2 != 0);
            assert_eq!(text.contains("property float radius"), mask & 4 != 0);
            // Header plus 12 bytes of position, 12 of normal, 3 of colour, 4 of radius.
            let record = 12 + 12 * (mask & 1) + 3 * ((mask >> 1) & 1) + 4 * ((mask >> 2) & 1);
            let header = text.find("end_header\n").unwrap() + "end_header\n".len();
            assert_eq!(bytes.len() - header, n * record as usize);
        }
    }
}

#[test]
fn sampled_cloud_round_trips() {
    let dir = scratch("sampled_round_trip");
    let cloud = sample_mesh(&tetrahedron(), &MaterialTextures::default(), 3000, 11).unwrap();
    let path = dir.join("sampled.ply");
    write_ply(&path, &cloud).unwrap();
    assert_identical(&read_ply(&path).unwrap(), &cloud);
}

#[test]
fn write_refuses_inconsistent_clouds() {
    let dir = scratch("write_refuses");
    let path = dir.join("bad.ply");
    let mut cloud = random_cloud(1, 10, true, true, true);
    cloud.colors.as_mut().unwrap().pop();
    let e = write_ply(&path, &cloud).unwrap_err();
    assert!(matches!(e, Error::Io { .. }), "{e:?}");
    let e = e.to_string();
    assert!(e.contains("bad.ply") && e.contains("has 9 colors for 10 positions"), "{e}");
    // The hierarchy refuses it too, where it had indexed past the colours.
    let refused = SplatTree::build(&cloud);
    let length = Error::CloudAttributeLength { attribute: "colors", len: 9, expected: 10 };
    assert_eq!(refused.unwrap_err().to_string(), length.to_string());
    for attribute in ["normals", "radii"] {
        let mut cloud = random_cloud(2, 10, true, true, true);
        match attribute {
            "normals" => cloud.normals = Some(Vec::new()),
            _ => cloud.radii.as_mut().unwrap().truncate(1),
        }
        let e = SplatTree::build(&cloud).unwrap_err().to_string();
        assert!(e.contains(&format!("{attribute} for 10 positions")), "{e}");
    }
    let mut cloud = random_cloud(1, 10, false, false, false);
    cloud.positions[3][1] = f32::NAN;
    let e = write_ply(&path, &cloud).unwrap_err().to_string();
    assert!(e.contains("bad.ply") && e.contains("point 3"), "{e}");
    // A radius that reading refuses is not written either.
    for r in [f32::INFINITY, f32::NAN, -1.0] {
        let mut cloud = random_cloud(1, 10, false, false, true);
        cloud.radii.as_mut().unwrap()[3] = r;
        let e = write_ply(&path, &cloud).unwrap_err().to_string();
        let want = format!("point 3: radius {r} is not a finite number >= 0");
        assert!(e.contains("bad.ply") && e.contains(&want), "{e}");
    }
    let e = write_ply(&dir.join("no/such/dir/x.ply"), &PointCloud::default()).unwrap_err();
    assert!(e.to_string().contains("x.ply"), "{e}");
}

const ASCII_FULL: &str = "ply\nformat ascii 1.0\ncomment hand written\nelement vertex 3\n\
    property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n\
    property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
    property uchar alpha\nproperty float radius\nelement face 1\n\
    property list uchar int vertex_indices\nend_header\n\
    1 2 3 0 0 2 255 128 0 255 0.5\n\
    -1 0.5 1e3 0 0 0 0 0 0 0 0\n\
    \n\
    0 0 0 3 4 0 10 20 30 40 2\n\
    3 0 1 2\n";

#[test]
fn reads_hand_written_ascii() {
    let dir = scratch("ascii");
    let path = dir.join("full.ply");
    fs::write(&path, ASCII_FULL).unwrap();
    let c = read_ply(&path).unwrap();
    assert_eq!(c.positions, vec![[1.0, 2.0, 3.0], [-1.0, 0.5, 1000.0], [0.0, 0.0, 0.0]]);
    // Normalised on read; a zero normal stays zero.
    assert_eq!(c.normals.unwrap(), vec![[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [0.6, 0.8, 0.0]]);
    assert_eq!(c.colors.unwrap(), vec![[255, 128, 0], [0, 0, 0], [10, 20, 30]]);
    assert_eq!(c.radii.unwrap(), vec![0.5, 0.0, 2.0]);

    // Positions only, other properties and elements ignored, CRLF line ends.
    let src = "ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\n\
               property float y\r\nproperty int z\r\nproperty float confidence\r\n\
               property float nx\r\nend_header\r\n1 2 3 0.5 9\r\n4 5 -6 0.25 9\r\n";
    let path = dir.join("plain.ply");
    fs::write(&path, src).unwrap();
    let c = read_ply(&path).unwrap();
    assert_eq!(c.positions, vec![[1.0, 2.0, 3.0], [4.0, 5.0, -6.0]]);
    assert_eq!((c.normals, c.colors, c.radii), (None, None, None));

    // `r g b` as floats in [0, 1] (clamped), faces before the vertices.
    let src = "ply\nformat ascii 1.0\nelement face 2\nproperty list uchar uint vertex_indices\n\
               element vertex 2\nproperty double x\nproperty double y\nproperty double z\n\
               property float r\nproperty float g\nproperty float b\nend_header\n\
               3 0 1 1\n4 1 1 1 1\n0 0 0 1 0.5 0\n1 1 1 -3 2 0.2\n";
    let path = dir.join("float_rgb.ply");
    fs::write(&path, src).unwrap();
    let c = read_ply(&path).unwrap();
    assert_eq!(c.positions, vec![[0.0; 3], [1.0; 3]]);
    assert_eq!(c.colors.unwrap(), vec![[255, 128, 0], [0, 255, 51]]);
}

/// Big- or little-endian writers for hand-made binary files.
struct Bin {
    big: bool,
    bytes: Vec<u8>,
}

impl Bin {
    fn new(header: &str, big: bool) -> Self {
        Self { big, bytes: header.as_bytes().to_vec() }
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        let b = if self.big { v.to_be_bytes() } else { v.to_le_bytes() };
        self.bytes.extend_from_slice(&b);
        self
    }
    fn f64(&mut self, v: f64) -> &mut Self {
        let b = if self.big { v.to_be_bytes() } else { v.to_le_bytes() };
        self.bytes.extend_from_slice(&b);
        self
    }
    fn u8(&mut self, v: u8) -> &mut Self {
        self.bytes.push(v);
        self
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        let b = if self.big { v.to_be_bytes() } else { v.to_le_bytes() };
        self.bytes.extend_from_slice(&b);
        self
    }
}

#[test]
fn reads_hand_written_binary_little_endian() {
    // Faces first (they must be read past), float colours under `r g b`, an ignored alpha.
    let header = "ply\nformat binary_little_endian 1.0\nelement face 2\n\
                  property list uchar int vertex_indices\nelement vertex 2\nproperty float x\n\
                  property float y\nproperty float z\nproperty float r\nproperty float g\n\
                  property float b\nproperty float a\nend_header\n";
    let mut b = Bin::new(header, false);
    b.u8(3).i32(0).i32(1).i32(1).u8(4).i32(0).i32(1).i32(1).i32(0);
    b.f32(1.5).f32(-2.0).f32(3.25).f32(1.0).f32(0.0).f32(0.5).f32(0.1);
    b.f32(0.0).f32(f32::MAX).f32(-0.0).f32(0.2).f32(0.4).f32(0.6).f32(1.0);
    let dir = scratch("binary_le");
    let path = dir.join("le.ply");
    fs::write(&path, &b.bytes).unwrap();
    let c = read_ply(&path).unwrap();
    assert_eq!(bits3(&c.positions), bits3(&[[1.5, -2.0, 3.25], [0.0, f32::MAX, -0.0]]));
    assert_eq!(c.colors.unwrap(), vec![[255, 0, 128], [51, 102, 153]]);
    assert_eq!((c.normals, c.radii), (None, None));
}

#[test]
fn reads_hand_written_binary_big_endian() {
    // Double positions, float normals (not unit: normalised), uchar colours, a radius, and a
    // face element after the vertices, truncated: it is not read.
    let header = "ply\nformat binary_big_endian 1.0\ncomment big\nelement vertex 2\n\
                  property double x\nproperty double y\nproperty double z\nproperty float nx\n\
                  property float ny\nproperty float nz\nproperty uchar red\n\
                  property uchar green\nproperty uchar blue\nproperty float radius\n\
                  element face 5\nproperty list uchar int vertex_indices\nend_header\n";
    let mut b = Bin::new(header, true);
    b.f64(0.1).f64(-7.0).f64(1e6).f32(0.0).f32(-3.0).f32(0.0).u8(1).u8(2).u8(3).f32(0.25);
    b.f64(2.0).f64(4.0).f64(8.0).f32(1e-30).f32(1e-30).f32(0.0).u8(250).u8(0).u8(9).f32(1e9);
    b.u8(3).i32(0);
    let dir = scratch("binary_be");
    let path = dir.join("be.ply");
    fs::write(&path, &b.bytes).unwrap();
    let c = read_ply(&path).unwrap();
    assert_eq!(c.positions, vec![[0.1f64 as f32, -7.0, 1e6], [2.0, 4.0, 8.0]]);
    let normals = c.normals.unwrap();
    assert_eq!(normals[0], [0.0, -1.0, 0.0]);
    let h = std::f32::consts::FRAC_1_SQRT_2;
    assert!((normals[1][0] - h).abs() < 1e-7 && (normals[1][1] - h).abs() < 1e-7);
    assert_eq!(normals[1][2], 0.0);
    assert_eq!(c.colors.unwrap(), vec![[1, 2, 3], [250, 0, 9]]);
    assert_eq!(c.radii.unwrap(), vec![0.25, 1e9]);
}

#[test]
fn non_finite_normals_read_as_unknown() {
    // PCL writes NaN normals for points it could not estimate one for.
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n\
                  property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
                  property float nz\nend_header\n";
    let mut b = Bin::new(header, false);
    b.f32(1.0).f32(2.0).f32(3.0).f32(f32::NAN).f32(f32::NAN).f32(f32::NAN);
    b.f32(1.0).f32(2.0).f32(3.0).f32(0.0).f32(f32::INFINITY).f32(0.0);
    let c = parse_ply(&b.bytes, Path::new("pcl.ply")).unwrap();
    assert_eq!(c.normals.unwrap(), vec![[0.0; 3]; 2]);
}

/// PCL writes the invalid points of an organised cloud (a depth camera's pixels without a
/// depth) with `nan` positions, and often `nan` normals and radii with them. Those points are
/// left out, every attribute with its point, and counted in one warning naming the first; a
/// cloud of only such points reads as empty.
#[test]
fn points_with_non_finite_positions_are_left_out() {
    let head = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
                property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
                property uchar red\nproperty uchar green\nproperty uchar blue\n\
                property float radius\nend_header\n";
    let body = "nan nan nan nan nan nan 0 0 0 nan\n\
                1 2 3 0 0 1 10 20 30 0.5\n\
                4 inf 6 0 1 0 1 1 1 -1\n\
                7 8 9 1 0 0 40 50 60 0.25\n\
                0 0 1e39 0 0 1 9 9 9 1\n";
    let path = Path::new("organised.ply");
    let c = parse_ply(format!("{head}{body}").as_bytes(), path).unwrap();
    assert_eq!(c.positions, [[1.0, 2.0, 3.0], [7.0, 8.0, 9.0]]);
    assert_eq!(c.normals.unwrap(), [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]);
    assert_eq!(c.colors.unwrap(), [[10, 20, 30], [40, 50, 60]]);
    assert_eq!(c.radii.unwrap(), [0.5, 0.25]);
    let want = "organised.ply: 3 points were left out for a position that is not finite (the \
                first: vertex 0, line 15)";
    assert_eq!(c.warnings, [want]);

    let only = "nan nan nan 0 0 1 0 0 0 1\n".repeat(5);
    let c = parse_ply(format!("{head}{only}").as_bytes(), path).unwrap();
    assert!(c.is_empty() && c.normals.unwrap().is_empty() && c.radii.unwrap().is_empty());
    assert_eq!(c.warnings.len(), 1);
}

// ------------------------------------------------------------------------------------------
// Malformed files
// ------------------------------------------------------------------------------------------

const XYZ: &str = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                   property float z\n";

fn binary_xyz(count: &str, big: bool) -> Bin {
    let format = if big { "binary_big_endian" } else { "binary_little_endian" };
    Bin::new(
        &format!(
            "ply\nformat {format} 1.0\nelement vertex {count}\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        ),
        big,
    )
}

/// Writes `bytes` to a file, reads it, and returns the error message; checks that it starts
/// with the path and `:line:` (line 0, in binary data: the path alone).
fn error_of(dir: &Path, name: &str, bytes: &[u8], line: usize) -> String {
    let path = dir.join(name);
    fs::write(&path, bytes).unwrap();
    let e = read_ply(&path).unwrap_err();
    assert!(matches!(e, Error::Parse { .. }), "{name}: {e:?}");
    let text = e.to_string();
    let at = if line == 0 { String::new() } else { format!(":{line}") };
    let prefix = format!("{}{at}: ", path.display());
    assert!(text.starts_with(&prefix), "{name}: expected `{prefix}...`, got `{text}`");
    text[prefix.len()..].to_string()
}

#[test]
fn malformed_files_name_the_file_and_line_or_byte() {
    let dir = scratch("malformed");
    let e = error_of(&dir, "not_ply.ply", b"plx\nformat ascii 1.0\n", 1);
    assert!(e.starts_with("not a PLY file"), "{e}");

    let e = error_of(&dir, "bad_count.ply", b"ply\nformat ascii 1.0\nelement vertex x\n", 3);
    assert!(e.starts_with("expected a PLY header line"), "{e}");

    let e = error_of(&dir, "no_end.ply", XYZ.as_bytes(), 7);
    assert!(e.contains("ends before `end_header`"), "{e}");

    let src = "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\n\
               end_header\n";
    let e = error_of(&dir, "no_vertex.ply", src.as_bytes(), 5);
    assert!(e.contains("no `vertex` element"), "{e}");

    let src = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
               end_header\n1 2\n";
    let e = error_of(&dir, "no_z.ply", src.as_bytes(), 3);
    assert!(e.contains("no property `z`"), "{e}");

    let src = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n\
               property list uchar float y\nproperty float z\nend_header\n1 1 2 3\n";
    let e = error_of(&dir, "list_y.ply", src.as_bytes(), 5);
    assert!(e.contains("`y` must be a scalar"), "{e}");

    let e = error_of(&dir, "dup.ply", format!("{XYZ}property float y\nend_header\n").as_bytes(), 7);
    assert!(e.contains("two properties `y` (first at line 5)"), "{e}");

    let e = error_of(&dir, "short.ply", format!("{XYZ}end_header\n1 2 3\n").as_bytes(), 9);
    assert!(e.starts_with("file ends after 1 of the 2 `vertex`"), "{e}");

    let e =
        error_of(&dir, "word.ply", format!("{XYZ}end_header\n1 2 3\n\n4 five 6\n").as_bytes(), 10);
    assert!(e.starts_with("`vertex` 1: not a list of numbers"), "{e}");

    let src = format!(
        "{XYZ}property uchar red\nproperty uchar green\nproperty uchar blue\n\
                       end_header\n1 2 3 0 0 0\n4 5 6 0 300 0\n"
    );
    let e = error_of(&dir, "big_uchar.ply", src.as_bytes(), 12);
    assert!(e.starts_with("`vertex` 1: a value does not fit its type ('300')"), "{e}");

    let e = error_of(&dir, "long.ply", format!("{XYZ}end_header\n1 2 3 4\n4 5 6\n").as_bytes(), 8);
    assert!(e.contains("found 4 values, but the header declares 3"), "{e}");

    // A point with a non-finite position is left out (PCL's invalid points) and warned of,
    // but its other values must still be well formed, and the rest of the file too.
    let src = format!("{XYZ}property float radius\nend_header\n1 2 3 1\nnan nan nan x\n");
    let e = error_of(&dir, "nan_word.ply", src.as_bytes(), 10);
    assert!(e.starts_with("`vertex` 1: not a list of numbers"), "{e}");

    let src = format!("{XYZ}property float radius\nend_header\n1 2 3 1\n4 5 6 -1\n");
    let e = error_of(&dir, "radius.ply", src.as_bytes(), 10);
    assert!(e.starts_with("vertex 1: radius -1 is not"), "{e}");

    // Absurd counts: nothing is allocated for them; the error comes where the data ends.
    let e = error_of(
        &dir,
        "absurd_ascii.ply",
        format!("{}end_header\n1 2 3\n", XYZ.replace("vertex 2", "vertex 4000000000000"))
            .as_bytes(),
        9,
    );
    assert!(e.starts_with("file ends after 1 of the 4000000000000 `vertex`"), "{e}");
}

#[test]
fn malformed_binary_files_name_the_byte() {
    let dir = scratch("malformed_binary");
    for big in [false, true] {
        let mut b = binary_xyz("2", big);
        let body = b.bytes.len();
        b.f32(1.0).f32(2.0).f32(3.0).f32(4.0).f32(f32::INFINITY).f32(6.0);
        let path = dir.join("inf.ply");
        fs::write(&path, &b.bytes).unwrap();
        let cloud = read_ply(&path).unwrap();
        assert_eq!(cloud.positions, [[1.0, 2.0, 3.0]]);
        let want = format!(
            "{}: 1 point was left out for a position that is not finite (the first: vertex 1, \
             byte {})",
            path.display(),
            body + 12
        );
        assert_eq!(cloud.warnings, [want]);

        // Truncated inside vertex 1: the error names where vertex 1 starts.
        let mut b = binary_xyz("2", big);
        let body = b.bytes.len();
        b.f32(1.0).f32(2.0).f32(3.0).f32(4.0).f32(5.0);
        let e = error_of(&dir, "truncated.ply", &b.bytes, 0);
        assert!(
            e.starts_with(&format!("byte {}: file ends inside `vertex` 1 of 2", body + 12)),
            "{e}"
        );

        // An absurd count in a small file: fails at the end of the data, allocating nothing big.
        let mut b = binary_xyz("18000000000000000000", big);
        let body = b.bytes.len();
        b.f32(1.0).f32(2.0).f32(3.0);
        let e = error_of(&dir, "absurd.ply", &b.bytes, 0);
        assert!(
            e.starts_with(&format!("byte {}: file ends inside `vertex` 1 of", body + 12)),
            "{e}"
        );
    }
    let e = read_ply(&dir.join("missing.ply")).unwrap_err();
    assert!(matches!(e, Error::Io { .. }) && e.to_string().contains("missing.ply"), "{e}");
}

#[test]
fn truncations_and_mutations_never_panic() {
    let cloud = random_cloud(5, 6, true, true, true);
    let dir = scratch("fuzz");
    let path = dir.join("base.ply");
    write_ply(&path, &cloud).unwrap();
    let base = fs::read(&path).unwrap();
    let header = base.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let name = Path::new("fuzz.ply");
    for len in 0..base.len() {
        let r = catch_unwind(|| parse_ply(&base[..len], name));
        let r = r.unwrap_or_else(|_| panic!("panic at truncation {len}"));
        // Every cut inside the header or the vertices is an error (there is nothing after).
        assert!(r.is_err(), "truncation to {len} of {} bytes was accepted", base.len());
        if len > header {
            assert!(r.unwrap_err().to_string().starts_with("fuzz.ply: byte "));
        }
    }
    let mut rng = SmallRng::seed_from_u64(99);
    let ascii = ASCII_FULL.as_bytes();
    for round in 0..3000 {
        let mut bytes = if round % 2 == 0 { base.clone() } else { ascii.to_vec() };
        for _ in 0..rng.random_range(1..4) {
            let i = rng.random_range(0..bytes.len());
            bytes[i] = match rng.random_range(0..4) {
                0 => rng.random(),
                1 => b'9',
                2 => b'\n',
                _ => b' ',
            };
        }
        let r = catch_unwind(AssertUnwindSafe(|| parse_ply(&bytes, name)));
        assert!(r.is_ok(), "panic on mutation round {round}");
    }
}

// ------------------------------------------------------------------------------------------
// Sampling
// ------------------------------------------------------------------------------------------

fn mesh(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
    let polygon_count = triangles.len();
    Mesh { positions, triangles, polygon_count, ..Mesh::default() }
}

/// An irregular tetrahedron away from the origin.
fn tetrahedron() -> Mesh {
    let o = [100.0, -50.0, 20.0];
    let p = |x: f32, y: f32, z: f32| [o[0] + 3.0 * x, o[1] + 3.0 * y, o[2] + 3.0 * z];
    mesh(
        vec![p(0.0, 0.0, 0.0), p(1.0, 0.1, 0.0), p(0.3, 1.2, 0.1), p(0.4, 0.3, 0.9)],
        vec![[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]],
    )
}

/// The unit square in z = 0, two counter-clockwise triangles seen from +z.
fn quad() -> Mesh {
    let mut m = mesh(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    m.texcoords = Some(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]);
    m
}

type V = [f64; 3];
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V, b: V) -> V {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn f64s(p: [f32; 3]) -> V {
    p.map(f64::from)
}

/// Distance from `p` to triangle `abc` (closest point by region, after Ericson).
fn distance_to_triangle(p: V, a: V, b: V, c: V) -> f64 {
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    let at = |q: V| dot(sub(p, q), sub(p, q)).sqrt();
    let lerp = |x: V, y: V, t: f64| {
        [x[0] + t * (y[0] - x[0]), x[1] + t * (y[1] - x[1]), x[2] + t * (y[2] - x[2])]
    };
    if d1 <= 0.0 && d2 <= 0.0 {
        return at(a);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return at(b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return at(lerp(a, b, d1 / (d1 - d3)));
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return at(c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return at(lerp(a, c, d2 / (d2 - d6)));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return at(lerp(b, c, (d4 - d3) / ((d4 - d3) + (d5 - d6))));
    }
    let n = cross(ab, ac);
    (dot(ap, n) / dot(n, n).sqrt()).abs()
}

/// Barycentric coordinates of `p` (on the triangle's plane) in triangle `abc`.
fn barycentric(p: V, a: V, b: V, c: V) -> V {
    let (v0, v1, v2) = (sub(b, a), sub(c, a), sub(p, a));
    let (d00, d01, d11, d20, d21) =
        (dot(v0, v0), dot(v0, v1), dot(v1, v1), dot(v2, v0), dot(v2, v1));
    let den = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / den;
    let w = (d00 * d21 - d01 * d20) / den;
    [1.0 - v - w, v, w]
}

fn assert_consistent(c: &PointCloud, n: usize) {
    assert_eq!(c.len(), n);
    assert_eq!(c.is_empty(), n == 0);
    assert_eq!(c.normals.as_ref().map(Vec::len), Some(n));
    assert_eq!(c.colors.as_ref().map(Vec::len), Some(n));
    assert_eq!(c.radii.as_ref().map(Vec::len), Some(n));
}

/// Points whose arrays cannot be allocated are an error naming them and the bytes of all four
/// arrays (12 + 12 + 3 + 4 per point), not an abort (`trirast sample --points 1073741824`
/// under an 8 GB limit aborted in `vec!`). Here the size overflows, so nothing is allocated;
/// an allocator's refusal takes the same path.
#[test]
fn sampling_points_that_cannot_be_allocated_is_an_error() {
    let n = usize::MAX / 16;
    match sample_mesh(&tetrahedron(), &MaterialTextures::default(), n, 3) {
        Err(Error::OutOfMemory { what, bytes }) => {
            assert_eq!(what, format!("{n} sampled points"));
            assert_eq!(bytes, n as u128 * 31, "the four arrays' bytes");
        }
        other => panic!("expected OutOfMemory, got {:?}", other.map(|c| c.len())),
    }
}

/// A surface so large that its splats' radius is beyond `f32` is an error saying how many
/// points would fit, before any is sampled: 3 points on a triangle of corners 3e38 (area
/// 2.2e77) had been given a radius of inf, which reading the written cloud refused. With that
/// many points the radius is finite and the cloud reads back as it was.
#[test]
fn sampling_with_a_radius_beyond_f32_is_an_error() {
    let m = mesh(vec![[3e38; 3], [-3e38; 3], [3e38, -3e38, 0.0]], vec![[0, 1, 2]]);
    let none = MaterialTextures::default();
    let fewest = match sample_mesh(&m, &none, 3, 1) {
        Err(Error::SampleRadius { points: 3, area, radius, fewest }) => {
            assert!(area.is_finite() && radius > f64::from(f32::MAX), "{area} {radius}");
            usize::try_from(fewest).unwrap()
        }
        other => panic!("expected SampleRadius, got {:?}", other.map(|c| c.radii)),
    };
    assert_eq!(fewest, 6);
    let refused = sample_mesh(&m, &none, fewest - 1, 1);
    assert!(matches!(refused, Err(Error::SampleRadius { fewest: 6, .. })));
    let cloud = sample_mesh(&m, &none, fewest, 1).unwrap();
    assert_consistent(&cloud, fewest);
    assert!(cloud.radii.as_ref().unwrap().iter().all(|r| r.is_finite()));
    let path = scratch("radius_beyond_f32").join("cloud.ply");
    write_ply(&path, &cloud).unwrap();
    assert_identical(&read_ply(&path).unwrap(), &cloud);
}

#[test]
fn samples_exactly_n_points_on_the_surface() {
    let m = tetrahedron();
    let none = MaterialTextures::default();
    for n in [1, 7, 4096, 4097, 9000] {
        let c = sample_mesh(&m, &none, n, 3).unwrap();
        assert_consistent(&c, n);
        let size = 3.0 * 1.3;
        for (i, p) in c.positions.iter().enumerate() {
            let d = m
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, cc] = t.map(|k| f64s(m.positions[k as usize]));
                    distance_to_triangle(f64s(*p), a, b, cc)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(d < 1e-5 * size, "point {i} {p:?} is {d} from the surface");
        }
    }
}

#[test]
fn triangles_get_points_in_proportion_to_their_area() {
    // Areas 1 (z = 0) and 3 (z = 5).
    let m = mesh(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 5.0],
            [3.0, 0.0, 5.0],
            [0.0, 2.0, 5.0],
        ],
        vec![[0, 1, 2], [3, 4, 5]],
    );
    let n = 40_000;
    let c = sample_mesh(&m, &MaterialTextures::default(), n, 2024).unwrap();
    let small = c.positions.iter().filter(|p| p[2] < 2.5).count() as f64 / n as f64;
    // Standard deviation sqrt(1/4 * 3/4 / 40000) ~ 0.0022: a tolerance of about 5 of them.
    assert!((small - 0.25).abs() < 0.012, "fraction on the area-1 triangle: {small}");
    // Uniform within a triangle (the sqrt trick): the corner triangle at vertex 0 with half
    // edges has a quarter of the area, and so does the one at vertex 1.
    let on_small: Vec<_> = c.positions.iter().filter(|p| p[2] < 2.5).collect();
    let k = on_small.len() as f64;
    let corner0 = on_small.iter().filter(|p| p[0] + p[1] / 2.0 < 0.5).count() as f64 / k;
    let corner1 = on_small.iter().filter(|p| p[0] > 0.5).count() as f64 / k;
    assert!(
        (corner0 - 0.25).abs() < 0.025 && (corner1 - 0.25).abs() < 0.025,
        "{corner0} {corner1}"
    );
}

#[test]
fn degenerate_and_broken_triangles_get_no_points() {
    // A zero-area sliver at z = 1 and a triangle with an index out of range, besides a real one.
    let m = mesh(
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [2.0, 2.0, 1.0],
        ],
        vec![[3, 4, 5], [0, 1, 2], [0, 1, 99], [4, 4, 3]],
    );
    let c = sample_mesh(&m, &MaterialTextures::default(), 5000, 1).unwrap();
    assert_consistent(&c, 5000);
    assert!(c.positions.iter().all(|p| p[2] == 0.0));
}

#[test]
fn empty_inputs_give_empty_clouds() {
    let none = MaterialTextures::default();
    for (m, n) in [
        (quad(), 0),
        (Mesh::default(), 100),
        (mesh(vec![[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]], vec![[0, 1, 2]]), 100),
    ] {
        let c = sample_mesh(&m, &none, n, 0).unwrap();
        assert_consistent(&c, 0);
        assert_eq!(c.bounds(), None);
    }
}

#[test]
fn face_normals_follow_the_winding() {
    let none = MaterialTextures::default();
    let c = sample_mesh(&quad(), &none, 2000, 5).unwrap();
    assert!(c.normals.unwrap().iter().all(|n| *n == [0.0, 0.0, 1.0]));
    let mut back = quad();
    for t in &mut back.triangles {
        t.swap(1, 2);
    }
    let c = sample_mesh(&back, &none, 2000, 5).unwrap();
    assert!(c.normals.unwrap().iter().all(|n| *n == [0.0, 0.0, -1.0]));
    // A tilted plane x + y + z = 1.
    let m = mesh(vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], vec![[0, 1, 2]]);
    let s = 1.0 / 3.0f32.sqrt();
    for n in sample_mesh(&m, &none, 1000, 5).unwrap().normals.unwrap() {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-6, "{n:?}");
        assert!(n.iter().all(|c| (c - s).abs() < 1e-6), "{n:?}");
    }
}

#[test]
fn vertex_normals_are_interpolated_and_normalised() {
    let mut m = mesh(vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]], vec![[0, 1, 2]]);
    let vn = [[0.0, 0.0, 1.0], unit([1.0, 0.0, 1.0]), unit([0.0, -1.0, 1.0])];
    m.normals = Some(vn.to_vec());
    let c = sample_mesh(&m, &MaterialTextures::default(), 2000, 8).unwrap();
    let [a, b, cc] = [0, 1, 2].map(|i| f64s(m.positions[i]));
    for (p, n) in c.positions.iter().zip(c.normals.unwrap()) {
        let w = barycentric(f64s(*p), a, b, cc);
        let e: V = std::array::from_fn(|k| (0..3).map(|i| w[i] * f64::from(vn[i][k])).sum());
        let l = dot(e, e).sqrt();
        for k in 0..3 {
            assert!((f64::from(n[k]) - e[k] / l).abs() < 1e-5, "{n:?} vs {e:?} at {p:?}");
        }
    }
}

#[test]
fn vertex_colours_are_interpolated_in_linear_light() {
    let mut m = mesh(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
    let vc = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 0.5]];
    m.colors = Some(vc.to_vec());
    let c = sample_mesh(&m, &MaterialTextures::default(), 3000, 9).unwrap();
    let [a, b, cc] = [0, 1, 2].map(|i| f64s(m.positions[i]));
    for (p, col) in c.positions.iter().zip(c.colors.unwrap()) {
        let w = barycentric(f64s(*p), a, b, cc);
        let expected: [u8; 3] = std::array::from_fn(|k| {
            let l: f64 = (0..3).map(|i| w[i] * f64::from(srgb_decode(vc[i][k]))).sum();
            linear_to_srgb8(l as f32)
        });
        for k in 0..3 {
            assert!(col[k].abs_diff(expected[k]) <= 1, "{col:?} vs {expected:?} at {p:?}");
        }
    }
    // One colour everywhere comes back exactly (8-bit values survive the linear round trip).
    m.colors = Some(vec![[0.2, 0.4, 0.8, 1.0]; 3]);
    let c = sample_mesh(&m, &MaterialTextures::default(), 500, 9).unwrap();
    assert!(c.colors.unwrap().iter().all(|c| *c == [51, 102, 204]));
}

#[test]
fn texture_colours_come_from_the_texture() {
    // 2x1: red on the left, blue on the right; the quad's uv is its xy.
    let texture = Texture::from_srgba8(2, 1, &[255, 0, 0, 255, 0, 0, 255, 255]);
    let mut m = quad();
    m.materials = vec![Material { diffuse: [0.0, 1.0, 0.0], ..Material::default() }];
    m.triangle_materials = Some(vec![0, 0]);
    let c = sample_mesh_with_textures(&m, &[Some(texture.clone())], 4000, 12).unwrap();
    let colors = c.colors.unwrap();
    let mut near_centre = 0;
    for (p, col) in c.positions.iter().zip(&colors) {
        let t = texture.sample(glam::Vec2::new(p[0], p[1]), Filter::Bilinear, Wrap::Repeat);
        let expected = [t.x, t.y, t.z].map(linear_to_srgb8);
        for k in 0..3 {
            assert!(col[k].abs_diff(expected[k]) <= 1, "{col:?} vs {expected:?} at {p:?}");
        }
        assert_eq!(col[1], 0, "no green from the material at {p:?}");
        if p[0] > 0.05 && p[0] < 0.45 {
            assert!(col[0] > col[2], "left half is red: {col:?} at {p:?}");
        }
        if p[0] > 0.55 && p[0] < 0.95 {
            assert!(col[2] > col[0], "right half is blue: {col:?} at {p:?}");
        }
        if (p[0] - 0.25).abs() < 0.005 {
            near_centre += 1;
            assert!(col[0] >= 250 && col[2] <= 30, "red texel centre: {col:?} at {p:?}");
        }
    }
    assert!(near_centre > 0);
    // Without texture coordinates, the material colour.
    m.texcoords = None;
    let c = sample_mesh_with_textures(&m, &[Some(texture)], 100, 12).unwrap();
    assert!(c.colors.unwrap().iter().all(|c| *c == [0, 255, 0]));
}

#[test]
fn material_and_default_colours() {
    let mut m = quad();
    m.materials = vec![
        Material { diffuse: [1.0, 0.5, 0.0], ..Material::default() },
        Material { diffuse: [0.2, 0.2, 1.0], ..Material::default() },
    ];
    m.triangle_materials = Some(vec![1, 0]);
    let textures = MaterialTextures::load(&m);
    let c = sample_mesh(&m, &textures, 2000, 4).unwrap();
    for (p, col) in c.positions.iter().zip(c.colors.unwrap()) {
        // Triangle 0 is below the diagonal y = x.
        let expected = if p[1] < p[0] { [51, 51, 255] } else { [255, 128, 0] };
        if (p[1] - p[0]).abs() > 1e-6 {
            assert_eq!(col, expected, "at {p:?}");
        }
    }
    let c = sample_mesh(&quad(), &MaterialTextures::default(), 100, 4).unwrap();
    assert!(c.colors.unwrap().iter().all(|c| *c == [200, 200, 200]));
}

#[test]
fn radii_make_disks_cover_the_area_one_and_a_half_times_over() {
    let c = sample_mesh(&tetrahedron(), &MaterialTextures::default(), 1234, 0).unwrap();
    let m = tetrahedron();
    let area: f64 = m
        .triangles
        .iter()
        .map(|t| {
            let [a, b, cc] = t.map(|k| f64s(m.positions[k as usize]));
            let n = cross(sub(b, a), sub(cc, a));
            0.5 * dot(n, n).sqrt()
        })
        .sum();
    let expected = (area / (std::f64::consts::PI * 1234.0)).sqrt() * 3.0;
    for r in c.radii.unwrap() {
        assert!((f64::from(r) - expected).abs() < 1e-6 * expected, "{r} vs {expected}");
    }
}

#[test]
fn same_seed_same_cloud_whatever_the_threads() {
    let m = tetrahedron();
    let none = MaterialTextures::default();
    let n = 3 * 4096 + 5;
    let run = |threads: usize, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| sample_mesh(&m, &none, n, seed).unwrap())
    };
    let one = run(1, 42);
    assert_identical(&one, &run(2, 42));
    assert_identical(&one, &run(3, 42));
    assert_identical(&one, &sample_mesh(&m, &none, n, 42).unwrap());
    let other = run(2, 43);
    let same = one.positions.iter().zip(&other.positions).filter(|(a, b)| a == b).count();
    assert!(same < 10, "{same} of {n} points equal with another seed");
    // A shorter run is a prefix of a longer one with the same seed (fixed chunks).
    let short = sample_mesh(&m, &none, 5000, 42).unwrap();
    assert_eq!(short.positions[..], one.positions[..5000]);
}

#[test]
fn len_and_bounds() {
    let c = PointCloud {
        positions: vec![[1.0, -2.0, 3.0], [-4.0, 5.0, 0.5], [0.0, 0.0, 9.0]],
        ..PointCloud::default()
    };
    assert_eq!((c.len(), c.is_empty()), (3, false));
    assert_eq!(c.bounds(), Some(([-4.0, -2.0, 0.5], [1.0, 5.0, 9.0])));
    let empty = PointCloud::default();
    assert_eq!((empty.len(), empty.is_empty(), empty.bounds()), (0, true, None));
}

#[test]
fn samples_shared_models_when_present() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models");
    for name in ["bunny-small.obj", "spot.obj"] {
        let path = dir.join(name);
        if !path.exists() {
            continue;
        }
        let m = trirast::mesh::load(&path).unwrap();
        let textures = MaterialTextures::load(&m);
        let c = sample_mesh(&m, &textures, 20_000, 7).unwrap();
        assert_consistent(&c, 20_000);
        let (lo, hi) = c.bounds().unwrap();
        let mesh_cloud = PointCloud { positions: m.positions.clone(), ..PointCloud::default() };
        let (mlo, mhi) = mesh_cloud.bounds().unwrap();
        for k in 0..3 {
            let eps = 1e-5 * (mhi[k] - mlo[k]).abs().max(1.0);
            assert!(lo[k] >= mlo[k] - eps && hi[k] <= mhi[k] + eps, "{name}: axis {k}");
        }
        for n in c.normals.unwrap() {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-5, "{name}: normal {n:?}");
        }
    }
}

/// Colour channels outside their type's range (floats beyond 0..1, such as colours written
/// from 0 to 255 as floats; integers beyond 0..255) are clamped as before, and now a warning
/// naming the file says how many points and how far; a cloud within range has none.
#[test]
fn clamped_colour_channels_are_warned_of() {
    let ply = |types: &str, rows: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
             property float z\nproperty {types} red\nproperty {types} green\n\
             property {types} blue\nend_header\n{rows}"
        )
    };
    let name = Path::new("c.ply");
    let within = ply("float", "0 0 0 0 0.5 1\n1 0 0 1 1 1\n0 1 0 0 0 0\n");
    assert!(parse_ply(within.as_bytes(), name).unwrap().warnings.is_empty());
    let floats = ply("float", "0 0 0 255 128 0\n1 0 0 1 1 1\n0 1 0 -0.5 0 NaN\n");
    let cloud = parse_ply(floats.as_bytes(), name).unwrap();
    assert_eq!(cloud.colors.as_ref().unwrap(), &[[255, 255, 0], [255; 3], [0; 3]]);
    let want = "c.ply: 2 points have colour channels outside their type's range (from -0.5 to \
                255): 0 to 1 for float colours, 0 to 255 for integer ones; they are clamped to it";
    assert_eq!(cloud.warnings, [want]);
    let integers = ply("int", "0 0 0 300 0 0\n1 0 0 255 255 255\n0 1 0 0 0 0\n");
    let cloud = parse_ply(integers.as_bytes(), name).unwrap();
    assert_eq!(cloud.colors.as_ref().unwrap()[0], [255, 0, 0]);
    assert!(
        cloud.warnings[0]
            .starts_with("c.ply: 1 point has colour channels outside their type's range (300)"),
        "{:?}",
        cloud.warnings
    );
    let uchar = ply("uchar", "0 0 0 255 0 0\n1 0 0 255 255 255\n0 1 0 0 0 0\n");
    assert!(parse_ply(uchar.as_bytes(), name).unwrap().warnings.is_empty());
}
