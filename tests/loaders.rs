//! Mesh loaders through `trirast::mesh::load`: meshes generated here are written in every format
//! and variant (OBJ, ASCII / binary little / big endian PLY with every attribute spelling and
//! index type, ASCII / binary STL) and read back; malformed files must give errors naming the
//! file and the line or byte offset; missing material libraries and textures are warnings; and a
//! deterministic mutation fuzz checks that the PLY and STL readers never panic (and that the
//! streamed STL reader agrees with the reference). Paths that are not regular files
//! (directories, devices, FIFOs) are refused by name, and oversized textures from their header.
//!
//! Everything is generated in code: the tests need nothing outside the repository (the real
//! models in `../shared/models` are loaded too when that directory exists).

mod common;

use std::collections::HashMap;
use std::fmt::Write as _;
use std::fs;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use common::xorshift::XorShift;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::Error;
use trirast::mesh::{self, Mesh};
use trirast::model::MaterialTextures;
use trirast::polygon::triangulate_face;
use trirast::splat::{cloud, format};
use trirast::texture::Texture;

/// A fresh scratch directory for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("loaders").join(name);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// A mesh as generated: attributes per vertex, faces of 3 or 4 corners.
struct Model {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    /// RGBA as bytes: exact in both the `uchar` and the float encodings.
    colors: Vec<[u8; 4]>,
    texcoords: Vec<[f32; 2]>,
    faces: Vec<Vec<u32>>,
}

impl Model {
    fn random(seed: u64, vertices: usize, faces: usize) -> Self {
        let mut rng = SmallRng::seed_from_u64(seed);
        let coord = |rng: &mut SmallRng| (rng.random_range(-1000..1000) as f32) / 64.0;
        let positions = (0..vertices).map(|_| [0; 3].map(|_| coord(&mut rng))).collect();
        let normals = (0..vertices).map(|_| [0; 3].map(|_| rng.random_range(-1.0..1.0))).collect();
        let colors = (0..vertices).map(|_| rng.random()).collect();
        let texcoords = (0..vertices).map(|_| [rng.random(), rng.random()]).collect();
        let faces = (0..faces)
            .map(|_| {
                let n = if rng.random_bool(0.5) { 3 } else { 4 };
                let mut face: Vec<u32> = Vec::new();
                while face.len() < n {
                    let v = rng.random_range(0..vertices as u32);
                    if !face.contains(&v) {
                        face.push(v);
                    }
                }
                face
            })
            .collect();
        Self { positions, normals, colors, texcoords, faces }
    }

    /// The triangles the loaders must produce, in order, as indices into the model's vertices.
    fn triangles(&self) -> Vec<[u32; 3]> {
        let mut out = Vec::new();
        for face in &self.faces {
            let points: Vec<[f32; 3]> = face.iter().map(|&v| self.positions[v as usize]).collect();
            for t in triangulate_face(&points) {
                out.push(t.map(|k| face[k]));
            }
        }
        out
    }

    fn color(&self, v: usize, alpha: bool) -> [f32; 4] {
        let c = self.colors[v].map(|b| f32::from(b) / 255.0);
        [c[0], c[1], c[2], if alpha { c[3] } else { 1.0 }]
    }

    fn float_color(&self, v: usize) -> [f32; 4] {
        self.colors[v].map(|b| f32::from(b) / 255.0)
    }
}

fn check_indices(mesh: &Mesh) {
    let n = mesh.positions.len();
    assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < n), "index out of range");
    for len in [
        mesh.normals.as_ref().map(Vec::len),
        mesh.texcoords.as_ref().map(Vec::len),
        mesh.colors.as_ref().map(Vec::len),
    ]
    .into_iter()
    .flatten()
    {
        assert_eq!(len, n, "attribute arrays have one entry per vertex");
    }
    if let Some(m) = &mesh.triangle_materials {
        assert_eq!(m.len(), mesh.triangles.len());
        assert!(m.iter().all(|&k| (k as usize) < mesh.materials.len()));
    }
}

// ---------------------------------------------------------------------------------------------
// PLY

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Ascii,
    Little,
    Big,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Colors {
    None,
    U8,
    U8Alpha,
    Float,
    FloatAlpha,
}

#[derive(Clone, Copy, Debug)]
struct PlyVariant {
    encoding: Encoding,
    normals: bool,
    colors: Colors,
    /// `r g b a` instead of `red green blue alpha`.
    short_color_names: bool,
    uv: Option<[&'static str; 2]>,
    index_type: &'static str,
    index_name: &'static str,
    position_type: &'static str,
    /// Extra properties and elements the reader must skip.
    extras: bool,
}

/// One value of a PLY body in the given type and encoding.
fn put(out: &mut Vec<u8>, encoding: Encoding, ty: &str, value: f64) {
    macro_rules! bin {
        ($t:ty) => {{
            let v = value as $t;
            out.extend_from_slice(&if encoding == Encoding::Big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            });
        }};
    }
    if encoding == Encoding::Ascii {
        let text = match ty {
            "float" => format!("{}", value as f32),
            "double" => format!("{value}"),
            _ => format!("{}", value as i64),
        };
        out.extend_from_slice(text.as_bytes());
        out.push(b' ');
        return;
    }
    match ty {
        "char" => bin!(i8),
        "uchar" => bin!(u8),
        "short" => bin!(i16),
        "ushort" => bin!(u16),
        "int" => bin!(i32),
        "uint" => bin!(u32),
        "float" => bin!(f32),
        "double" => bin!(f64),
        _ => unreachable!("{ty}"),
    }
}

fn end_element(out: &mut Vec<u8>, encoding: Encoding) {
    if encoding == Encoding::Ascii {
        out.pop();
        out.push(b'\n');
    }
}

fn write_ply(model: &Model, v: &PlyVariant) -> Vec<u8> {
    let format = match v.encoding {
        Encoding::Ascii => "ascii",
        Encoding::Little => "binary_little_endian",
        Encoding::Big => "binary_big_endian",
    };
    let names =
        if v.short_color_names { ["r", "g", "b", "a"] } else { ["red", "green", "blue", "alpha"] };
    let (color_type, channels) = match v.colors {
        Colors::None => ("", 0),
        Colors::U8 => ("uchar", 3),
        Colors::U8Alpha => ("uchar", 4),
        Colors::Float => ("float", 3),
        Colors::FloatAlpha => ("float", 4),
    };
    let mut h = format!("ply\nformat {format} 1.0\ncomment generated by tests/loaders.rs\n");
    writeln!(h, "element vertex {}", model.positions.len()).unwrap();
    for axis in ["x", "y", "z"] {
        writeln!(h, "property {} {axis}", v.position_type).unwrap();
    }
    if v.extras {
        h.push_str("property float confidence\n");
    }
    if v.normals {
        h.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    for name in &names[..channels] {
        writeln!(h, "property {color_type} {name}").unwrap();
    }
    if let Some([s, t]) = v.uv {
        writeln!(h, "property float {s}\nproperty float {t}").unwrap();
    }
    writeln!(h, "element face {}", model.faces.len()).unwrap();
    if v.extras {
        h.push_str("property uchar flags\n");
    }
    writeln!(h, "property list uchar {} {}", v.index_type, v.index_name).unwrap();
    if v.extras {
        h.push_str("property list uchar float texcoord\nelement edge 2\nproperty int vertex1\n");
        h.push_str("property int vertex2\nobj_info skipped\n");
    }
    h.push_str("end_header\n");

    let e = v.encoding;
    let mut out = h.into_bytes();
    for i in 0..model.positions.len() {
        for c in model.positions[i] {
            put(&mut out, e, v.position_type, f64::from(c));
        }
        if v.extras {
            put(&mut out, e, "float", 0.5);
        }
        if v.normals {
            for c in model.normals[i] {
                put(&mut out, e, "float", f64::from(c));
            }
        }
        for k in 0..channels {
            let byte = model.colors[i][k];
            let value = if color_type == "uchar" {
                f64::from(byte)
            } else {
                f64::from(f32::from(byte) / 255.0)
            };
            put(&mut out, e, color_type, value);
        }
        if v.uv.is_some() {
            for c in model.texcoords[i] {
                put(&mut out, e, "float", f64::from(c));
            }
        }
        end_element(&mut out, e);
    }
    for face in &model.faces {
        if v.extras {
            put(&mut out, e, "uchar", 7.0);
        }
        put(&mut out, e, "uchar", face.len() as f64);
        for &i in face {
            put(&mut out, e, v.index_type, f64::from(i));
        }
        if v.extras {
            put(&mut out, e, "uchar", 2.0);
            put(&mut out, e, "float", 0.25);
            put(&mut out, e, "float", 0.75);
        }
        end_element(&mut out, e);
    }
    if v.extras {
        for pair in [[0.0, 1.0], [1.0, 2.0]] {
            for value in pair {
                put(&mut out, e, "int", value);
            }
            end_element(&mut out, e);
        }
    }
    out
}

fn ply_variants() -> Vec<PlyVariant> {
    let base = PlyVariant {
        encoding: Encoding::Ascii,
        normals: false,
        colors: Colors::None,
        short_color_names: false,
        uv: None,
        index_type: "int",
        index_name: "vertex_indices",
        position_type: "float",
        extras: false,
    };
    let mut variants = Vec::new();
    for encoding in [Encoding::Ascii, Encoding::Little, Encoding::Big] {
        let with = |f: &dyn Fn(&mut PlyVariant)| {
            let mut v = PlyVariant { encoding, ..base };
            f(&mut v);
            v
        };
        variants.extend([
            with(&|_| {}),
            with(&|v| v.normals = true),
            with(&|v| v.colors = Colors::U8),
            with(&|v| {
                v.colors = Colors::U8Alpha;
                v.short_color_names = true;
                v.index_type = "uchar";
            }),
            with(&|v| {
                v.colors = Colors::Float;
                v.uv = Some(["u", "v"]);
                v.index_type = "uint";
            }),
            with(&|v| {
                v.colors = Colors::FloatAlpha;
                v.uv = Some(["s", "t"]);
                v.normals = true;
                v.index_name = "vertex_index";
            }),
            with(&|v| {
                v.uv = Some(["texture_u", "texture_v"]);
                v.index_type = "ushort";
                v.position_type = "double";
            }),
            with(&|v| {
                v.normals = true;
                v.colors = Colors::U8Alpha;
                v.uv = Some(["u", "v"]);
                v.index_type = "uchar";
                v.extras = true;
            }),
        ]);
    }
    variants
}

#[test]
fn ply_round_trips_every_encoding_and_attribute() {
    let dir = scratch("ply_round_trip");
    let model = Model::random(1, 150, 220);
    let expected = model.triangles();
    for (k, variant) in ply_variants().iter().enumerate() {
        let path = dir.join(format!("v{k}.ply"));
        fs::write(&path, write_ply(&model, variant)).unwrap();
        let mesh = mesh::load(&path).unwrap_or_else(|e| panic!("{variant:?}: {e}"));
        check_indices(&mesh);
        assert_eq!(mesh.positions, model.positions, "{variant:?}");
        assert_eq!(mesh.triangles, expected, "{variant:?}");
        assert_eq!(mesh.polygon_count, model.faces.len(), "{variant:?}");
        assert_eq!(mesh.normals.as_ref(), variant.normals.then_some(&model.normals), "{variant:?}");
        let colors: Option<Vec<[f32; 4]>> = match variant.colors {
            Colors::None => None,
            Colors::U8 | Colors::U8Alpha => {
                let alpha = variant.colors == Colors::U8Alpha;
                Some((0..model.positions.len()).map(|i| model.color(i, alpha)).collect())
            }
            Colors::Float | Colors::FloatAlpha => {
                let alpha = variant.colors == Colors::FloatAlpha;
                Some(
                    (0..model.positions.len())
                        .map(|i| {
                            let mut c = model.float_color(i);
                            if !alpha {
                                c[3] = 1.0;
                            }
                            c
                        })
                        .collect(),
                )
            }
        };
        assert_eq!(mesh.colors, colors, "{variant:?}");
        assert_eq!(mesh.texcoords.as_ref(), variant.uv.map(|_| &model.texcoords), "{variant:?}");
        assert!(mesh.warnings.is_empty() && mesh.materials.is_empty());
    }
}

// ---------------------------------------------------------------------------------------------
// STL

/// The triangles of a mesh as sorted position triples (bit patterns), for order-free comparison.
fn triangle_set(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[[u32; 3]; 3]> {
    let mut set: Vec<_> =
        triangles.iter().map(|t| t.map(|i| positions[i as usize].map(f32::to_bits))).collect();
    set.sort_unstable();
    set
}

fn facet_normal(p: [[f32; 3]; 3]) -> [f32; 3] {
    let u = [0, 1, 2].map(|c| p[1][c] - p[0][c]);
    let v = [0, 1, 2].map(|c| p[2][c] - p[0][c]);
    [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
}

fn write_stl_ascii(model: &Model, shouting: bool) -> Vec<u8> {
    let kw = |s: &str| {
        if shouting { s.to_uppercase() } else { s.to_string() }
    };
    let mut s = format!("{} generated\n", kw("solid"));
    for t in model.triangles() {
        let p = t.map(|i| model.positions[i as usize]);
        let [a, b, c] = facet_normal(p);
        writeln!(s, "  {} {a:e} {b:e} {c:e}\n    {}", kw("facet normal"), kw("outer loop"))
            .unwrap();
        for [x, y, z] in p {
            writeln!(s, "      {} {x} {y} {z}", kw("vertex")).unwrap();
        }
        writeln!(s, "    {}\n  {}\n", kw("endloop"), kw("endfacet")).unwrap();
    }
    writeln!(s, "{} generated", kw("endsolid")).unwrap();
    s.into_bytes()
}

fn write_stl_binary(model: &Model, header: &[u8]) -> Vec<u8> {
    let triangles = model.triangles();
    let mut out = header.to_vec();
    out.resize(80, 0);
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for t in triangles {
        let p = t.map(|i| model.positions[i as usize]);
        for c in [facet_normal(p)].iter().chain(&p).flatten() {
            out.extend_from_slice(&c.to_le_bytes());
        }
        out.extend_from_slice(&[0, 0]);
    }
    out
}

#[test]
fn stl_round_trips_ascii_and_binary_welded() {
    let dir = scratch("stl_round_trip");
    let model = Model::random(2, 120, 200);
    let expected = triangle_set(&model.positions, &model.triangles());
    let triangles = model.triangles();
    let stl_io_triangles: Vec<stl_io::Triangle> = triangles
        .iter()
        .map(|t| {
            let p = t.map(|i| model.positions[i as usize]);
            stl_io::Triangle {
                normal: stl_io::Normal::new(facet_normal(p)),
                vertices: p.map(stl_io::Vertex::new),
            }
        })
        .collect();
    let mut by_stl_io = Vec::new();
    stl_io::write_stl(&mut by_stl_io, stl_io_triangles.iter()).unwrap();
    let files: [(&str, Vec<u8>); 5] = [
        ("ascii.stl", write_stl_ascii(&model, false)),
        ("ASCII_UPPER.STL", write_stl_ascii(&model, true)),
        ("binary.stl", write_stl_binary(&model, b"binary STL from the tests")),
        ("solid_header.stl", write_stl_binary(&model, b"solid but binary")),
        ("stl_io.stl", by_stl_io),
    ];
    for (name, bytes) in files {
        let path = dir.join(name);
        fs::write(&path, &bytes).unwrap();
        let mesh = mesh::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        // Streamed from the file: the mesh the reference makes of the bytes.
        assert_eq!(mesh, mesh::stl::parse(&bytes, &path).unwrap(), "{name}");
        check_indices(&mesh);
        assert_eq!(triangle_set(&mesh.positions, &mesh.triangles), expected, "{name}");
        assert_eq!(mesh.polygon_count, triangles.len(), "{name}");
        assert!(mesh.normals.is_none() && mesh.colors.is_none() && mesh.texcoords.is_none());
        // Welded: every position once, and exactly the positions the faces use.
        let mut used: Vec<[u32; 3]> = model
            .faces
            .iter()
            .flatten()
            .map(|&v| model.positions[v as usize].map(f32::to_bits))
            .collect();
        used.sort_unstable();
        used.dedup();
        let mut got: Vec<[u32; 3]> = mesh.positions.iter().map(|p| p.map(f32::to_bits)).collect();
        got.sort_unstable();
        assert_eq!(got, used, "{name}: positions are welded");
        // File order and winding are kept.
        for (t, e) in mesh.triangles.iter().zip(&triangles) {
            let got = t.map(|i| mesh.positions[i as usize]);
            let want = e.map(|i| model.positions[i as usize]);
            assert_eq!(got, want, "{name}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// OBJ

#[derive(Clone, Copy, Debug)]
struct ObjVariant {
    texcoords: bool,
    normals: bool,
    colors: bool,
    negative: bool,
}

fn write_obj(model: &Model, v: ObjVariant) -> Vec<u8> {
    let mut s = String::from("# generated by tests/loaders.rs\no model\n");
    for (i, [x, y, z]) in model.positions.iter().enumerate() {
        if v.colors {
            let [r, g, b, _] = model.float_color(i);
            writeln!(s, "v {x} {y} {z} {r} {g} {b}").unwrap();
        } else {
            writeln!(s, "v {x} {y} {z}").unwrap();
        }
    }
    if v.texcoords {
        for [a, b] in &model.texcoords {
            writeln!(s, "vt {a} {b}").unwrap();
        }
    }
    if v.normals {
        for [a, b, c] in &model.normals {
            writeln!(s, "vn {a} {b} {c}").unwrap();
        }
    }
    let n = model.positions.len() as i64;
    for face in &model.faces {
        s.push('f');
        for &i in face {
            let i = if v.negative { i64::from(i) - n } else { i64::from(i) + 1 };
            match (v.texcoords, v.normals) {
                (false, false) => write!(s, " {i}"),
                (true, false) => write!(s, " {i}/{i}"),
                (false, true) => write!(s, " {i}//{i}"),
                (true, true) => write!(s, " {i}/{i}/{i}"),
            }
            .unwrap();
        }
        s.push('\n');
    }
    s.into_bytes()
}

#[test]
fn obj_round_trips_with_and_without_attributes() {
    let dir = scratch("obj_round_trip");
    let model = Model::random(3, 100, 150);
    let expected = model.triangles();
    let flags = [
        (false, false, false, false),
        (true, false, false, false),
        (false, true, false, true),
        (true, true, false, false),
        (false, false, true, false),
        (true, true, true, true),
    ];
    for (k, (texcoords, normals, colors, negative)) in flags.into_iter().enumerate() {
        let variant = ObjVariant { texcoords, normals, colors, negative };
        let path = dir.join(format!("v{k}.obj"));
        fs::write(&path, write_obj(&model, variant)).unwrap();
        let mesh = mesh::load(&path).unwrap_or_else(|e| panic!("{variant:?}: {e}"));
        check_indices(&mesh);
        assert_eq!(mesh.triangles.len(), expected.len(), "{variant:?}");
        assert_eq!(mesh.polygon_count, model.faces.len());
        assert_eq!(mesh.normals.is_some(), normals);
        assert_eq!(mesh.texcoords.is_some(), texcoords);
        assert_eq!(mesh.colors.is_some(), colors);
        // OBJ vertices are (v, vt, vn) combinations in first-use order: compare corner by corner.
        for (t, e) in mesh.triangles.iter().zip(&expected) {
            for (&got, &want) in t.iter().zip(e) {
                let (got, want) = (got as usize, want as usize);
                assert_eq!(mesh.positions[got], model.positions[want], "{variant:?}");
                if let Some(n) = &mesh.normals {
                    assert_eq!(n[got], model.normals[want]);
                }
                if let Some(uv) = &mesh.texcoords {
                    assert_eq!(uv[got], model.texcoords[want]);
                }
                if let Some(c) = &mesh.colors {
                    assert_eq!(c[got], model.color(want, false));
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Materials

fn png(path: &Path) {
    image::RgbaImage::from_pixel(2, 2, image::Rgba([10, 20, 30, 255])).save(path).unwrap();
}

#[test]
fn materials_resolve_relative_paths_and_missing_files_are_warnings() {
    let dir = scratch("materials");
    fs::create_dir_all(dir.join("mats/tex")).unwrap();
    png(&dir.join("mats/tex/wood.png"));
    fs::write(dir.join("mats/broken.png"), b"not a png").unwrap();
    fs::write(
        dir.join("mats/lib.mtl"),
        "# materials\nnewmtl wood\nKd 0.5 0.25 1\nmap_Kd -s 1 1 1 -bm 0.5 tex/wood.png\n\n\
         newmtl gone\nKd 0.1 0.2 0.3\nmap_Kd missing.png\n\
         newmtl broken\nKd 1\nmap_Kd broken.png\nnewmtl unused\n",
    )
    .unwrap();
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
    let obj = format!(
        "mtllib mats/lib.mtl\n{quad}f 1/1 2/2 3/3\nusemtl wood\nf 1/1 3/3 4/4\n\
         usemtl gone\nf 1 2 3 4\nusemtl broken\nf 1 2 3\nusemtl nowhere\nf 2 3 4\nusemtl wood\n\
         f 4 3 2\n"
    );
    let path = dir.join("scene.obj");
    fs::write(&path, obj).unwrap();
    let mesh = mesh::load(&path).unwrap();
    check_indices(&mesh);
    let names: Vec<&str> = mesh.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["", "wood", "gone", "broken", "nowhere"]);
    assert_eq!(mesh.triangle_materials, Some(vec![0, 1, 2, 2, 3, 4, 1]));
    let m = &mesh.materials;
    assert_eq!(m[0], trirast::mesh::Material::default());
    assert_eq!(m[1].diffuse, [0.5, 0.25, 1.0]);
    assert_eq!(m[1].diffuse_texture.as_deref(), Some(dir.join("mats/tex/wood.png").as_path()));
    assert_eq!((m[2].diffuse, m[2].diffuse_texture.is_none()), ([0.1, 0.2, 0.3], true));
    assert_eq!((m[3].diffuse, m[3].diffuse_texture.is_none()), ([1.0; 3], true));
    assert_eq!(m[4].diffuse, trirast::mesh::Material::default().diffuse);
    let warnings = mesh.warnings.join("\n");
    for needle in [
        "missing.png of material `gone` was not found; using its diffuse colour",
        "broken.png of material `broken` cannot be decoded",
        // Each names its `map_Kd` line.
        "lib.mtl:8: texture ",
        "lib.mtl:11: texture ",
        "scene.obj:17: material `nowhere`: no material library defines it",
    ] {
        assert!(warnings.contains(needle), "{needle:?} not in warnings:\n{warnings}");
    }
    assert_eq!(mesh.warnings.len(), 3, "{warnings}");

    // A missing library: the mesh loads, with one warning (not one more per material).
    let path = dir.join("alone.obj");
    fs::write(&path, "mtllib alone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    let mesh = mesh::load(&path).unwrap();
    assert_eq!(mesh.triangle_materials, Some(vec![0]));
    assert_eq!(mesh.materials.len(), 1, "no default material when every face has one");
    let warnings = mesh.warnings.join("\n");
    assert!(warnings.contains("alone.obj:1: material library"), "{warnings}");
    assert!(warnings.contains("alone.mtl was not found"), "{warnings}");
    assert_eq!(mesh.warnings.len(), 1, "{warnings}");

    // Several libraries on one `mtllib` line, one of them missing.
    let path = dir.join("two.obj");
    let two = format!("mtllib mats/lib.mtl nothere.mtl\n{quad}usemtl wood\nf 1 2 3\n");
    fs::write(&path, two).unwrap();
    let mesh = mesh::load(&path).unwrap();
    assert_eq!(mesh.materials[0].diffuse, [0.5, 0.25, 1.0]);
    let warnings = mesh.warnings.join("\n");
    assert!(warnings.contains("two.obj:1: material library "), "{warnings}");
    assert!(warnings.contains("nothere.mtl was not found"), "{warnings}");
    assert_eq!(mesh.warnings.len(), 1, "{warnings}");

    // `usemtl` without any `mtllib`.
    let path = dir.join("nolib.obj");
    fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    let mesh = mesh::load(&path).unwrap();
    let warnings = mesh.warnings.join("\n");
    assert!(warnings.contains("nolib.obj:4: material `a`: the file has no `mtllib`"), "{warnings}");

    // No usemtl: no materials at all.
    let path = dir.join("plain.obj");
    fs::write(&path, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let mesh = mesh::load(&path).unwrap();
    assert!(mesh.materials.is_empty() && mesh.triangle_materials.is_none());
    assert!(mesh.warnings.is_empty());
}

/// A library named again, on more lines, on one line or under another spelling of its path, is
/// read where first named: its warnings are given once (they had been given once per naming,
/// and 5000 namings of a 20,000-material library took minutes) and the materials are those of
/// naming it once. The library that defines a name first still decides its material.
#[test]
fn a_library_named_again_is_read_once() {
    let dir = scratch("library_named_again");
    // `Kd 2 0 0` is clamped with a warning.
    fs::write(dir.join("red.mtl"), "newmtl a\nKd 2 0 0\nnewmtl b\nKd 0 0 1\n").unwrap();
    fs::write(dir.join("green.mtl"), "newmtl a\nKd 0 1 0\n").unwrap();
    let triangles = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 1 3 2\n";
    let load = |name: &str, libraries: &str| {
        let path = dir.join(name);
        fs::write(&path, format!("{libraries}{triangles}")).unwrap();
        let mesh = mesh::load(&path).unwrap();
        let colours: Vec<[f32; 3]> = mesh.materials.iter().map(|m| m.diffuse).collect();
        (colours, mesh.warnings)
    };
    let once = load("once.obj", "mtllib red.mtl\n");
    assert_eq!(once.0, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(once.1.len(), 1, "{:?}", once.1);
    let lines = "mtllib red.mtl\n".repeat(50);
    let one_line = format!("mtllib {}\n", ["red.mtl"; 50].join(" "));
    let spellings = "mtllib red.mtl\nmtllib ./red.mtl\nmtllib ../library_named_again/red.mtl\n";
    for (name, libraries) in
        [("lines.obj", lines.as_str()), ("one_line.obj", &one_line), ("spellings.obj", spellings)]
    {
        assert_eq!(load(name, libraries), once, "{name}");
    }

    // The first definition of `a` wins, however often either library is named after.
    let (colours, _) = load("red_first.obj", "mtllib red.mtl\nmtllib green.mtl\nmtllib red.mtl\n");
    assert_eq!(colours, [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    let (colours, _) =
        load("green_first.obj", "mtllib green.mtl red.mtl green.mtl\nmtllib red.mtl\n");
    assert_eq!(colours, [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);

    // A missing library named again is warned of once, at its first naming.
    let (colours, warnings) = load("gone.obj", "mtllib gone.mtl\nmtllib red.mtl gone.mtl\n");
    assert_eq!(colours, once.0);
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(warnings[0].contains("gone.obj:1: material library "), "{warnings:?}");
    assert!(warnings[0].contains("gone.mtl was not found"), "{warnings:?}");
    assert_eq!(warnings[1], once.1[0]);
}

// ---------------------------------------------------------------------------------------------
// Input files that are not regular files, and oversized textures

/// `f()`, or a failure if it takes more than five seconds: a reader stuck on a FIFO or a device
/// then fails the test rather than hanging it.
fn within_seconds<T: Send + 'static>(f: impl FnOnce() -> T + Send + 'static) -> T {
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || sender.send(f()));
    receiver.recv_timeout(std::time::Duration::from_secs(5)).expect("still reading after 5 s")
}

/// Makes a FIFO at `path` with `mkfifo`; false (and the case is skipped) where there is none.
fn fifo(path: &Path) -> bool {
    let made = std::process::Command::new("mkfifo").arg(path).status().is_ok_and(|s| s.success());
    if !made {
        eprintln!("mkfifo not available: skipping the FIFO case");
    }
    made
}

#[test]
fn paths_that_are_not_regular_files_are_refused_by_name() {
    let dir = scratch("not_regular");
    let refused = |path: &Path, result: Result<(), Error>, kind: &str| {
        let e = result.expect_err("not a regular file: must be refused");
        assert!(matches!(e, Error::NotRegularFile { .. }), "{e:?}");
        assert_eq!(e.to_string(), format!("{}: is {kind}, not a regular file", path.display()));
    };
    for name in ["d.obj", "d.ply", "d.stl"] {
        let path = dir.join(name);
        fs::create_dir(&path).unwrap();
        refused(&path, mesh::load(&path).map(drop), "a directory");
    }
    let path = dir.join("d.ply");
    refused(&path, cloud::read_ply(&path).map(drop), "a directory");
    refused(&path, Texture::load(&path).map(drop), "a directory");
    let path = dir.join("d.tsplat");
    fs::create_dir(&path).unwrap();
    refused(&path, format::read(&path).map(drop), "a directory");

    // A symlink is followed: to /dev/zero, it had been read until memory ran out.
    #[cfg(target_os = "linux")]
    {
        let path = dir.join("zero.obj");
        std::os::unix::fs::symlink("/dev/zero", &path).unwrap();
        let p = path.clone();
        refused(&path, within_seconds(move || mesh::load(&p).map(drop)), "a character device");
    }
    // A FIFO with no writer: opening it had blocked forever.
    let path = dir.join("pipe.stl");
    if fifo(&path) {
        let p = path.clone();
        refused(&path, within_seconds(move || mesh::load(&p).map(drop)), "a FIFO (named pipe)");
    }
}

#[test]
fn material_libraries_and_textures_that_are_not_files_are_warnings() {
    let dir = scratch("not_regular_materials");
    fs::create_dir(dir.join("dir.mtl")).unwrap();
    fs::create_dir(dir.join("dir.png")).unwrap();
    let mut libraries = vec![("dir.mtl".to_string(), "a directory")];
    let mut textures = vec![("dir.png".to_string(), "a directory")];
    if cfg!(target_os = "linux") {
        libraries.push(("/dev/zero".into(), "a character device"));
        textures.push(("/dev/zero".into(), "a character device"));
    }
    if fifo(&dir.join("pipe.mtl")) && fifo(&dir.join("pipe.png")) {
        libraries.push(("pipe.mtl".into(), "a FIFO (named pipe)"));
        textures.push(("pipe.png".into(), "a FIFO (named pipe)"));
    }
    let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl m\nf 1/1 2/1 3/1\n";
    for (k, (library, kind)) in libraries.into_iter().enumerate() {
        let path = dir.join(format!("library{k}.obj"));
        fs::write(&path, format!("mtllib {library}\n{triangle}")).unwrap();
        let p = path.clone();
        let mesh = within_seconds(move || mesh::load(&p)).unwrap();
        let expected = format!(
            "{}:1: material library {} is {kind}, not a regular file; using default materials",
            path.display(),
            dir.join(&library).display()
        );
        assert_eq!(mesh.warnings, [expected]);
    }
    for (k, (texture, kind)) in textures.into_iter().enumerate() {
        let library = dir.join(format!("texture{k}.mtl"));
        fs::write(&library, format!("newmtl m\nKd 0.5\nmap_Kd {texture}\n")).unwrap();
        let path = dir.join(format!("texture{k}.obj"));
        fs::write(&path, format!("mtllib texture{k}.mtl\n{triangle}")).unwrap();
        let p = path.clone();
        let mesh = within_seconds(move || mesh::load(&p)).unwrap();
        let expected = format!(
            "{}:3: texture {} of material `m` is {kind}, not a regular file; using its diffuse \
             colour",
            library.display(),
            dir.join(&texture).display()
        );
        assert_eq!(mesh.warnings, [expected]);
        assert_eq!(mesh.materials[0].diffuse, [0.5; 3]);
        assert_eq!(mesh.materials[0].diffuse_texture, None);
    }
}

/// A PNG whose header declares `width` x `height` RGBA texels and which holds none of them (its
/// one image data chunk is a bare zlib header): what a decompression bomb looks like before its
/// texels are decoded.
fn png_header_only(path: &Path, width: u32, height: u32) {
    let mut encoder = png::Encoder::new(fs::File::create(path).unwrap(), width, height);
    encoder.set_color(png::ColorType::Rgba);
    let mut writer = encoder.write_header().unwrap();
    writer.write_chunk(png::chunk::IDAT, &[0x78, 0x01]).unwrap();
    // Dropping the writer ends the file (IEND).
}

#[test]
fn oversized_textures_are_refused_from_their_header() {
    let dir = scratch("texture_size");
    // Over the side limit (a real image, 80 KB of texels), then over the texel limit.
    image::RgbaImage::new(20000, 1).save(dir.join("wide.png")).unwrap();
    png_header_only(&dir.join("bomb.png"), 8193, 8193);
    // PNG's largest size, whose rows the decoder refuses before it gives the size (its error
    // had said only "Memory limit exceeded").
    let most = i32::MAX as u32;
    png_header_only(&dir.join("huge.png"), most, most);
    let sizes = [("wide.png", 20000, 1), ("bomb.png", 8193, 8193), ("huge.png", most, most)];
    for (name, width, height) in sizes {
        let path = dir.join(name);
        let expected = format!(
            "{}: texture size {width}x{height} is not supported: each side must be at most 16384 \
             texels and the whole at most 67108864 texels",
            path.display()
        );
        for e in [Texture::load(&path).map(drop), Texture::dimensions(&path).map(drop)] {
            let e = e.expect_err("over the limit: must be refused");
            assert!(matches!(e, Error::TextureSize { .. }), "{e:?}");
            assert_eq!(e.to_string(), expected);
        }
    }
    // At the side limit: loaded.
    image::RgbaImage::new(16384, 1).save(dir.join("limit.png")).unwrap();
    assert_eq!(Texture::load(&dir.join("limit.png")).unwrap().width(), 16384);

    // Through a material: one warning each, the plain colour, nothing left to load when drawing.
    fs::write(
        dir.join("lib.mtl"),
        "newmtl wide\nKd 0.25\nmap_Kd wide.png\nnewmtl bomb\nmap_Kd bomb.png\n",
    )
    .unwrap();
    let path = dir.join("scene.obj");
    let obj = "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl wide\nf 1/1 2/1 3/1\n\
               usemtl bomb\nf 1/1 3/1 2/1\n";
    fs::write(&path, obj).unwrap();
    let mesh = mesh::load(&path).unwrap();
    let library = dir.join("lib.mtl");
    let expected = [("wide", "20000x1", 3), ("bomb", "8193x8193", 5)].map(|(name, size, line)| {
        format!(
            "{}:{line}: texture {} of material `{name}` is {size} texels, more than a texture may have \
             (at most 16384 a side and 67108864 in all); using its diffuse colour",
            library.display(),
            dir.join(format!("{name}.png")).display()
        )
    });
    assert_eq!(mesh.warnings, expected);
    assert_eq!(mesh.materials[0].diffuse, [0.25; 3]);
    assert!(mesh.materials.iter().all(|m| m.diffuse_texture.is_none()));
    let textures = MaterialTextures::load(&mesh);
    assert!(textures.warnings.is_empty() && textures.get(0).is_none(), "{:?}", textures.warnings);
}

// ---------------------------------------------------------------------------------------------
// Malformed files

const PLY_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n\
                        property float y\nproperty float z\nelement face 1\n\
                        property list uchar int vertex_indices\nend_header\n";

fn binary_ply_head(count: u64, encoding: &str) -> Vec<u8> {
    format!(
        "ply\nformat {encoding} 1.0\nelement vertex {count}\nproperty float x\n\
         property float y\nproperty float z\nend_header\n"
    )
    .into_bytes()
}

#[test]
fn malformed_files_name_the_file_and_position() {
    let dir = scratch("malformed");
    let huge = binary_ply_head(4_000_000_000, "binary_little_endian");
    let mut truncated = binary_ply_head(3, "binary_little_endian");
    let body = truncated.len();
    truncated.extend_from_slice(&[0; 12 * 2 + 5]);
    let mut negative_list =
        b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\n\
        property float y\nproperty float z\nelement face 1\nproperty list char int vertex_indices\n\
        end_header\n"
            .to_vec();
    let face_at = negative_list.len() + 12;
    negative_list.extend_from_slice(&[0; 12]);
    negative_list.extend_from_slice(&[0xff, 0, 0, 0, 0]);
    let mut binary_stl = vec![0; 80];
    binary_stl.extend_from_slice(&7u32.to_le_bytes());
    binary_stl.extend_from_slice(&[0; 50 * 6]);
    let mut nan_stl = vec![0; 80];
    nan_stl.extend_from_slice(&1u32.to_le_bytes());
    nan_stl.extend_from_slice(&[0; 50]);
    nan_stl[84 + 12 + 4..84 + 12 + 8].copy_from_slice(&f32::NAN.to_le_bytes());
    let stl_head = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n";
    fs::write(dir.join("bad.mtl"), "newmtl a\nKd 0.5 oops 0.5\n").unwrap();

    let cases: Vec<(&str, Vec<u8>, String)> = vec![
        (
            "not_a_number.ply",
            format!("{PLY_HEAD}0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n").into_bytes(),
            ":11: `vertex` 1: not a list of numbers; expected float x, float y, float z".into(),
        ),
        (
            "short_line.ply",
            format!("{PLY_HEAD}0 0 0\n1 0\n0 1 0\n3 0 1 2\n").into_bytes(),
            ":11: `vertex` 1: too few values; expected float x, float y, float z, found `1 0`"
                .to_string(),
        ),
        (
            "long_line.ply",
            format!("{PLY_HEAD}0 0 0\n1 0 0 1\n0 1 0\n3 0 1 2\n").into_bytes(),
            ":11: `vertex` 1: found 4 values, but the header declares 3 (float x, float y, float z)"
                .into(),
        ),
        (
            "long_list.ply",
            format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0\n").into_bytes(),
            ":13: `face` 0: found 5 values, but the header declares 4".into(),
        ),
        (
            "truncated.ply",
            format!("{PLY_HEAD}0 0 0\n\n1 0 0\n").into_bytes(),
            ":13: file ends after 2 of the 3 `vertex` elements".into(),
        ),
        (
            "bad_header.ply",
            b"ply\nformat ascii 1.0\nelement vertex three\n".to_vec(),
            ":3: expected a PLY header line".into(),
        ),
        (
            "no_end_header.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\n".to_vec(),
            ":4: file ends before `end_header`".into(),
        ),
        (
            "out_of_range.ply",
            format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n").into_bytes(),
            ":13: face 0: vertex index 3 is out of range (the file has 3 vertices)".into(),
        ),
        (
            "negative_index.ply",
            format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n").into_bytes(),
            ":13: face 0: vertex index -1 is out of range".into(),
        ),
        (
            "two_corners.ply",
            format!("{PLY_HEAD}0 0 0\n1 0 0\n0 1 0\n2 0 1\n").into_bytes(),
            ":13: face 0 has 2 vertex indices; a face needs 3 or more".into(),
        ),
        (
            "huge_count.ply",
            huge.clone(),
            format!(
                ": byte {}: file ends inside `vertex` 0 of 4000000000",
                huge.len()
            ),
        ),
        (
            "truncated_le.ply",
            truncated,
            format!(": byte {}: file ends inside `vertex` 2 of 3", body + 24),
        ),
        (
            "negative_list.ply",
            negative_list,
            format!(": byte {face_at}: `face` 0: the list's length is negative"),
        ),
        (
            "float_indices.ply",
            PLY_HEAD.replace("uchar int", "uchar float").into_bytes(),
            ":7: `vertex_indices` must be a list of integers".into(),
        ),
        (
            "no_z.ply",
            PLY_HEAD.replace("property float z\n", "").into_bytes(),
            ":3: element `vertex` has no property `z`".into(),
        ),
        (
            "duplicate.ply",
            PLY_HEAD
                .replace("property float z\n", "property float z\nproperty float y\n")
                .into_bytes(),
            ":7: property `y` is declared twice in element `vertex`".into(),
        ),
        (
            "count_mismatch.stl",
            binary_stl,
            ": byte 80: the header declares 7 triangles, which take 434 bytes".into(),
        ),
        (
            "nan.stl",
            nan_stl,
            ": byte 100: triangle 0, vertex 0: coordinate y is NaN".into(),
        ),
        (
            "huge.stl",
            format!("{stl_head}vertex 1e39 0 0\n").into_bytes(),
            ":5: vertex `1e39 0 0` is not finite in single precision".into(),
        ),
        (
            "huge.ply",
            format!("{}1e300 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", PLY_HEAD.replace("float x", "double x"))
                .into_bytes(),
            ":10: vertex 0: position [inf, 0.0, 0.0] is not finite in single precision".into(),
        ),
        (
            "short_vertex.stl",
            format!("{stl_head}vertex 1 0\n").into_bytes(),
            ":5: `vertex` takes 3 numbers, found 2".into(),
        ),
        (
            "no_endloop.stl",
            format!("{stl_head}vertex 1 0 0\nvertex 0 1 0\nendfacet\n").into_bytes(),
            ":7: expected `vertex x y z` or `endloop`, found `endfacet`".into(),
        ),
        (
            "no_endsolid.stl",
            format!("{stl_head}vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n").into_bytes(),
            ":9: file ends where `facet` or `endsolid` was expected".into(),
        ),
        (
            "bad_face.obj",
            b"v 0 0 0\nv 1 0 0\nf 1 2\n".to_vec(),
            ":3: a face needs 3 or more corners".into(),
        ),
    ];
    assert!(cases.len() >= 10);
    for (name, bytes, needle) in &cases {
        let path = dir.join(name);
        fs::write(&path, bytes).unwrap();
        let e = match mesh::load(&path) {
            Ok(_) => panic!("{name} should not load"),
            Err(e) => e.to_string(),
        };
        let expected = format!("{}{needle}", path.display());
        assert!(e.starts_with(&expected), "{name}:\n  got  {e}\n  want {expected}...");
        assert!(!e.contains('\n'), "{name}: one-line message: {e:?}");
    }

    // A material library's line that cannot be read is a warning naming it; the model loads,
    // its material with the default colour.
    let path = dir.join("uses_bad_mtl.obj");
    fs::write(&path, "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    let mesh = mesh::load(&path).unwrap();
    let want = format!(
        "{}:2: `Kd` expected a finite number, found `oops`; the line is ignored",
        dir.join("bad.mtl").display()
    );
    assert_eq!(mesh.warnings, [want]);
    assert_eq!(mesh.materials[0].diffuse, trirast::mesh::Material::default().diffuse);

    let e = mesh::load(&dir.join("model.3ds")).unwrap_err().to_string();
    assert!(e.contains("model.3ds") && e.contains("expected .obj, .ply or .stl"), "{e}");
    let e = mesh::load(&dir.join("absent.ply")).unwrap_err().to_string();
    assert!(e.contains("absent.ply"), "{e}");
}

/// A PLY header cut short on a line without `\n` is reported on that line, the file's last, by
/// both PLY readers: the crate counts one line past it (`ply\ncomment` ended "at line 3" of 2).
/// Found by the `ply_parse` fuzz target.
#[test]
fn a_header_cut_short_names_its_last_line() {
    let cases: [(&[u8], usize); 3] = [
        (b"ply\ncomment", 2),
        (b"ply\ncomment\n", 3),
        (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty short x", 4),
    ];
    for (src, line) in cases {
        let path = Path::new("t.ply");
        let expected = format!("t.ply:{line}: file ends before `end_header`");
        assert_eq!(mesh::ply::parse(src, path).unwrap_err().to_string(), expected);
        assert_eq!(cloud::parse_ply(src, path).unwrap_err().to_string(), expected);
    }
}

/// OBJ and MTL files read the same whatever their line endings: LF, CR LF, CR alone (classic
/// Mac OS, which was read as one line: "expected a number, found `v`") and CR CR LF; and an
/// error names the same line in each.
#[test]
fn obj_and_mtl_line_endings_read_alike() {
    let dir = scratch("line_endings");
    let lines = ["mtllib m.mtl", "v 0 0 0", "v 1 0 0", "v 0 1 0", "usemtl red", "f 1 2 3"];
    let mtl = ["newmtl red", "Kd 1 0 0"];
    let mut meshes = Vec::new();
    for (k, end) in ["\n", "\r\n", "\r", "\r\r\n"].into_iter().enumerate() {
        let sub = dir.join(format!("e{k}"));
        fs::create_dir_all(&sub).unwrap();
        fs::write(sub.join("m.mtl"), mtl.join(end) + end).unwrap();
        fs::write(sub.join("t.obj"), lines.join(end) + end).unwrap();
        let mesh = mesh::load(&sub.join("t.obj")).unwrap();
        assert!(mesh.warnings.is_empty(), "{end:?}: {:?}", mesh.warnings);
        meshes.push((mesh.positions, mesh.triangles, mesh.materials));
        let bad = ["v 0 0 0", "v 1 0 0", "v 0 oops 0"].join(end) + end;
        fs::write(sub.join("bad.obj"), bad).unwrap();
        let e = mesh::load(&sub.join("bad.obj")).unwrap_err().to_string();
        assert!(e.contains("bad.obj:3:"), "{end:?}: {e}");
    }
    assert!(meshes.windows(2).all(|w| w[0] == w[1]));
    assert_eq!(meshes[0].2[0].diffuse, [1.0, 0.0, 0.0]);
}

// ---------------------------------------------------------------------------------------------
// Mutation fuzz

const TOKENS: &[&[u8]] = &[
    b"4000000000",
    b"4294967295",
    b"-1",
    b"255",
    b"0",
    b"nan",
    b"1e39",
    b"\n",
    b" ",
    b"\r\n",
    b"end_header\n",
    b"element vertex 9\n",
    b"property list uint uint vertex_indices\n",
    b"property double x\n",
    b"format binary_big_endian 1.0\n",
    b"endloop\n",
    b"endsolid\n",
    b"facet normal 0 0 1\n",
    b"vertex 1 2 3\n",
    b"solid",
    b"\xff\xff\xff\xff",
    b"\x00\x00\xc0\x7f",
    // A line end of its own in STL (classic Mac OS), whitespace elsewhere.
    b"\r",
];

fn mutate(rng: &mut XorShift, seed: &[u8]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = b.len();
        let at = rng.below(len + 1);
        match rng.below(8) {
            0 if len > 0 => b[at.min(len - 1)] ^= 1 << rng.below(8),
            1 if len > 0 => b[at.min(len - 1)] = rng.next() as u8,
            2 => b.truncate(at),
            3 => {
                let end = (at + 1 + rng.below(16)).min(len);
                b.drain(at.min(end)..end);
            }
            4 => {
                let t = TOKENS[rng.below(TOKENS.len())];
                b.splice(at..at, t.iter().copied());
            }
            5 if at + 4 <= len => {
                let v = [0u32, 1, 3, 0x7fff_ffff, 0xffff_ffff, 0x8000_0000][rng.below(6)];
                b[at..at + 4].copy_from_slice(&v.to_le_bytes());
            }
            6 => {
                let end = (at + rng.below(64)).min(len);
                let chunk = b[at..end].to_vec();
                b.splice(at..at, chunk);
            }
            _ if len > 0 => {
                // Replace a digit run with a large or odd number.
                if let Some(p) = b[at.min(len - 1)..].iter().position(u8::is_ascii_digit) {
                    let p = at.min(len - 1) + p;
                    let t = TOKENS[rng.below(7)];
                    b.splice(p..p + 1, t.iter().copied());
                }
            }
            _ => {}
        }
    }
    b
}

fn fuzz(
    name: &str,
    seeds: &[Vec<u8>],
    iterations: usize,
    parse: fn(&[u8], &Path) -> Result<Mesh, trirast::Error>,
) {
    // `TRIRAST_FUZZ_ITERS` and `TRIRAST_FUZZ_SEED` override the defaults for a longer local run.
    let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
    let iterations = env("TRIRAST_FUZZ_ITERS").map_or(iterations, |n| n as usize);
    let mut rng = XorShift::new(env("TRIRAST_FUZZ_SEED").unwrap_or(0x5eed_1e55_f00d_cafe));
    let path = Path::new("fuzz.input");
    let (mut accepted, mut rejected) = (0, 0);
    for i in 0..iterations {
        let seed = &seeds[i % seeds.len()];
        let input = mutate(&mut rng, seed);
        let result = catch_unwind(AssertUnwindSafe(|| parse(&input, path)));
        match result {
            Err(_) => panic!("{name}: panic on input {i}: {:?}", input.escape_ascii().to_string()),
            Ok(Ok(mesh)) => {
                check_indices(&mesh);
                accepted += 1;
            }
            Ok(Err(e)) => {
                let text = e.to_string();
                assert!(text.starts_with("fuzz.input:"), "{text}");
                assert!(!text.contains('\n'), "{text:?}");
                rejected += 1;
            }
        }
    }
    assert!(accepted > 0 && rejected > 0, "{name}: {accepted} accepted, {rejected} rejected");
}

#[test]
fn fuzz_ply_never_panics() {
    let model = Model::random(4, 10, 8);
    let seeds: Vec<Vec<u8>> = ply_variants().iter().map(|v| write_ply(&model, v)).collect();
    fuzz("ply", &seeds, 4000, mesh::ply::parse);
}

#[test]
fn fuzz_stl_never_panics() {
    let model = Model::random(5, 8, 6);
    let seeds = vec![
        write_stl_ascii(&model, false),
        write_stl_ascii(&model, true),
        write_stl_binary(&model, b""),
        write_stl_binary(&model, b"solid header"),
    ];
    fuzz("stl", &seeds, 4000, mesh::stl::parse);
    fuzz("stl streamed", &seeds, 4000, mesh::stl::parse_streamed);
}

/// The streamed STL reader gives what the reference (the file in memory) gives, the same mesh
/// or the same error, on the fuzz test's mutated files.
#[test]
fn fuzz_stl_streamed_is_the_reference() {
    let model = Model::random(6, 8, 6);
    let seeds = [
        write_stl_ascii(&model, false),
        write_stl_ascii(&model, true),
        write_stl_binary(&model, b""),
        write_stl_binary(&model, b"solid header"),
    ];
    let mut rng = XorShift::new(0x571e_5eed);
    let path = Path::new("fuzz.stl");
    let (mut accepted, mut rejected) = (0, 0);
    for i in 0..4000 {
        let input = mutate(&mut rng, &seeds[i % seeds.len()]);
        let escaped = || input.escape_ascii().to_string();
        match (mesh::stl::parse(&input, path), mesh::stl::parse_streamed(&input, path)) {
            (Ok(reference), Ok(streamed)) => {
                assert_eq!(reference, streamed, "{}", escaped());
                accepted += 1;
            }
            (Err(reference), Err(streamed)) => {
                assert_eq!(format!("{reference:?}"), format!("{streamed:?}"), "{}", escaped());
                rejected += 1;
            }
            (reference, streamed) => panic!("{reference:?}\n{streamed:?}\n{}", escaped()),
        }
    }
    assert!(accepted > 200 && rejected > 2000, "{accepted} accepted, {rejected} rejected");
}

// ---------------------------------------------------------------------------------------------
// Real models, when present

#[test]
fn shared_models_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models");
    let Ok(entries) = fs::read_dir(&dir) else {
        eprintln!("{} not found: skipping the real models", dir.display());
        return;
    };
    let mut loaded = HashMap::new();
    for entry in entries {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "obj") {
            continue;
        }
        let mesh = mesh::load(&path).unwrap_or_else(|e| panic!("{e}"));
        check_indices(&mesh);
        assert!(!mesh.triangles.is_empty(), "{}", path.display());
        loaded.insert(path.file_name().unwrap().to_string_lossy().into_owned(), mesh);
    }
    if let Some(beetle) = loaded.get("beetle.obj") {
        // Its mtllib names a file that is not shipped: a warning, and the default material.
        assert!(beetle.warnings.iter().any(|w| w.contains("VWBugMesh002.mtl was not found")));
        assert_eq!(beetle.materials.len(), 1);
    }
    if let Some(spot) = loaded.get("spot.obj") {
        assert!(spot.texcoords.is_some());
    }
}

/// Loads `path` through `read` with a report that records what it is told: returns the result
/// and the reports.
fn reported<T>(
    path: &Path,
    read: impl FnOnce(&Path, &dyn Fn(u64)) -> Result<T, Error>,
) -> (Result<T, Error>, Vec<u64>) {
    let seen = std::cell::RefCell::new(Vec::new());
    let result = read(path, &|n| seen.borrow_mut().push(n));
    (result, seen.into_inner())
}

/// The progress a load reports (for `trirast`'s bar) rises with every report and ends at the
/// file's size, in each format, over files of many 64 KB reads; the STL reader's second read
/// of its first bytes does not count again. The mesh is the one `load` gives. A truncated
/// file reports no further than its end.
#[test]
fn loads_report_progress_to_the_end_of_the_file() {
    let dir = scratch("progress");
    let model = Model::random(7, 4000, 9000);
    let mut files = vec![
        (
            "m.obj",
            write_obj(
                &model,
                ObjVariant { texcoords: true, normals: true, colors: false, negative: false },
            ),
        ),
        ("ascii.stl", write_stl_ascii(&model, false)),
        ("binary.stl", write_stl_binary(&model, b"solid but binary")),
    ];
    // One PLY file per encoding, with indices that hold 4,000 vertices.
    let mut encodings = Vec::new();
    for variant in ply_variants() {
        if !variant.index_type.contains("char") && !encodings.contains(&variant.encoding) {
            encodings.push(variant.encoding);
            files.push((
                ["a.ply", "b.ply", "c.ply"][encodings.len() - 1],
                write_ply(&model, &variant),
            ));
        }
    }
    assert_eq!(encodings.len(), 3, "ASCII and both binary encodings");
    for (name, bytes) in &files {
        let path = dir.join(name);
        fs::write(&path, bytes).unwrap();
        let (mesh, reports) = reported(&path, mesh::load_reporting);
        assert_eq!(mesh.unwrap(), mesh::load(&path).unwrap(), "{name}");
        assert!(reports.len() > 2, "{name}: {} reports", reports.len());
        assert!(reports.windows(2).all(|w| w[0] < w[1]), "{name}: {reports:?}");
        assert_eq!(reports.last(), Some(&(bytes.len() as u64)), "{name}");
        // Cut short: an error, and no report past the bytes there are.
        let cut = &bytes[..bytes.len() * 2 / 3];
        fs::write(&path, cut).unwrap();
        let (mesh, reports) = reported(&path, mesh::load_reporting);
        assert!(mesh.is_err(), "{name}: a truncated file was read");
        assert!(reports.iter().all(|&n| n <= cut.len() as u64), "{name}");
    }
    let path = dir.join("cloud.ply");
    let cloud = cloud::PointCloud {
        positions: model.positions.clone(),
        normals: Some(model.normals.clone()),
        ..cloud::PointCloud::default()
    };
    cloud::write_ply(&path, &cloud).unwrap();
    let (read, reports) = reported(&path, cloud::read_ply_reporting);
    assert_eq!(read.unwrap(), cloud::read_ply(&path).unwrap());
    assert!(reports.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(reports.last(), Some(&fs::metadata(&path).unwrap().len()));
}
