//! Wavefront OBJ reader.
//!
//! Hand-written rather than taken from `tobj` for two reasons that matter here: errors must name
//! the line, and triangles must be numbered in file order (tobj regroups faces by object and
//! material). Supported: `v x y z [w]` and `v x y z r g b`, `vt`, `vn`, and faces of any size
//! whose corners are `v`, `v/vt`, `v//vn` or `v/vt/vn`, with negative (relative) indices.
//! `mtllib` and `usemtl` are recorded; [`read_mesh`] resolves them through [`super::mtl`].
//! Other statements (`o`, `g`, `s`, `l`, `p`, ...) are skipped.

use std::collections::HashMap;
use std::path::Path;

use super::{Material, Mesh};
use crate::error::Error;

/// One face corner: indices (0-based) into the mesh's arrays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Corner {
    /// Index into `positions`.
    pub position: u32,
    /// Index into `texcoords`, when given.
    pub texcoord: Option<u32>,
    /// Index into `normals`, when given.
    pub normal: Option<u32>,
}

/// The contents of an OBJ file, faces in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    /// `v` positions.
    pub positions: Vec<[f32; 3]>,
    /// `w` of each `v` (1 when absent).
    pub w: Vec<f32>,
    /// Optional `v x y z r g b` colour of each position, in [0, 1].
    pub colors: Vec<Option<[f32; 3]>>,
    /// `vt` coordinates.
    pub texcoords: Vec<[f32; 2]>,
    /// `vn` normals.
    pub normals: Vec<[f32; 3]>,
    /// All face corners, face after face.
    pub corners: Vec<Corner>,
    /// `face_starts[i]..face_starts[i + 1]` are the corners of face `i`.
    pub face_starts: Vec<u32>,
    /// The 1-based line of each face.
    pub face_lines: Vec<u32>,
    /// The argument of each `mtllib` statement (one or more file names) with its line.
    pub material_libraries: Vec<(String, u32)>,
    /// Distinct `usemtl` names in order of first use, with the line of that first use.
    pub material_names: Vec<(String, u32)>,
    /// For each face, the `usemtl` in force as an index into `material_names` (`None` before the
    /// first `usemtl`).
    pub face_materials: Vec<Option<u32>>,
}

impl ObjMesh {
    /// Iterates over the faces' corner lists.
    pub fn faces(&self) -> impl Iterator<Item = &[Corner]> {
        self.face_starts.windows(2).map(|w| &self.corners[w[0] as usize..w[1] as usize])
    }

    /// Number of faces.
    #[must_use]
    pub fn face_count(&self) -> usize {
        self.face_starts.len().saturating_sub(1)
    }

    /// Number of triangles once every face is fanned.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.faces().map(|f| f.len() - 2).sum()
    }
}

/// Reads and parses an OBJ file.
pub fn read(path: &Path) -> Result<ObjMesh, Error> {
    let bytes = crate::input::read(path)?;
    parse(&bytes).map_err(|(line, message)| Error::Parse {
        path: path.to_path_buf(),
        line,
        message,
    })
}

/// Reads an OBJ file as an indexed [`Mesh`]: corners with the same (v, vt, vn) share a vertex,
/// faces are triangulated by [`crate::polygon::triangulate_face`] in file order. Materials
/// come from the `mtllib` files (see [`super::mtl::apply`]); a missing library or texture is a
/// warning in [`Mesh::warnings`].
pub fn read_mesh(path: &Path) -> Result<Mesh, Error> {
    let obj = read(path)?;
    let mut mesh = to_mesh(&obj);
    super::mtl::apply(&mut mesh, &obj, path)?;
    Ok(mesh)
}

/// Converts parsed OBJ data to an indexed [`Mesh`]. When the file has `usemtl`, `materials`
/// holds one default-coloured [`Material`] per name (preceded by an unnamed default for faces
/// before the first `usemtl`) and `triangle_materials` points into it.
#[must_use]
pub fn to_mesh(obj: &ObjMesh) -> Mesh {
    let has_uv = obj.corners.iter().any(|c| c.texcoord.is_some());
    let has_normal = obj.corners.iter().any(|c| c.normal.is_some());
    let has_color = obj.colors.iter().any(Option::is_some);
    let mut mesh = Mesh { polygon_count: obj.face_count(), ..Mesh::default() };
    let (mut normals, mut texcoords, mut colors) = (Vec::new(), Vec::new(), Vec::new());
    let mut index: HashMap<(u32, Option<u32>, Option<u32>), u32> = HashMap::new();
    let mut face_vertices = Vec::new();
    let mut face_points = Vec::new();
    let mut triangle_materials = Vec::new();
    let uses_materials = !obj.material_names.is_empty();
    let face_material = |f: usize| obj.face_materials.get(f).copied().flatten();
    let offset = u32::from((0..obj.face_count()).any(|f| face_material(f).is_none()));
    if uses_materials {
        if offset == 1 {
            mesh.materials.push(Material::default());
        }
        for (name, _) in &obj.material_names {
            mesh.materials.push(Material { name: name.clone(), ..Material::default() });
        }
    }
    for (f, face) in obj.faces().enumerate() {
        face_vertices.clear();
        face_points.clear();
        for c in face {
            let next = mesh.positions.len() as u32;
            let v = *index.entry((c.position, c.texcoord, c.normal)).or_insert_with(|| {
                let p = c.position as usize;
                mesh.positions.push(obj.positions[p]);
                if has_uv {
                    texcoords.push(c.texcoord.map_or([0.0; 2], |t| obj.texcoords[t as usize]));
                }
                if has_normal {
                    normals.push(c.normal.map_or([0.0; 3], |n| obj.normals[n as usize]));
                }
                if has_color {
                    let [r, g, b] = obj.colors[p].unwrap_or([1.0; 3]);
                    colors.push([r, g, b, 1.0]);
                }
                next
            });
            face_vertices.push(v);
            face_points.push(obj.positions[c.position as usize]);
        }
        let before = mesh.triangles.len();
        for t in crate::polygon::triangulate_face(&face_points) {
            mesh.triangles.push(t.map(|k| face_vertices[k]));
        }
        if uses_materials {
            let m = face_material(f).map_or(0, |k| k + offset);
            triangle_materials.resize(triangle_materials.len() + mesh.triangles.len() - before, m);
        }
    }
    mesh.triangle_materials = uses_materials.then_some(triangle_materials);
    mesh.normals = has_normal.then_some(normals);
    mesh.texcoords = has_uv.then_some(texcoords);
    mesh.colors = has_color.then_some(colors);
    mesh
}

/// Parses OBJ text; an error is `(line, message)`.
pub fn parse(bytes: &[u8]) -> Result<ObjMesh, (usize, String)> {
    let mut mesh = ObjMesh { face_starts: vec![0], ..ObjMesh::default() };
    let mut material: Option<u32> = None;
    let mut material_index: HashMap<String, u32> = HashMap::new();
    // Positive indices may refer forwards; they are checked once the whole file is read.
    let mut max_ref: [(u32, usize); 3] = [(0, 0); 3];
    // A UTF-8 byte-order mark (some Windows tools write one) is not part of the first line.
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    for (n, raw) in super::text_lines(bytes).enumerate() {
        let line = n + 1;
        let text = std::str::from_utf8(raw).map_err(|_| (line, "not valid UTF-8".to_string()))?;
        let text = text.split('#').next().unwrap_or("").trim();
        let mut tokens = text.split_ascii_whitespace();
        let Some(keyword) = tokens.next() else { continue };
        let args: Vec<&str> = tokens.collect();
        match keyword {
            "v" => {
                let f = floats(&args, line)?;
                let (xyz, w, color) = match f.len() {
                    3 => ([f[0], f[1], f[2]], 1.0, None),
                    4 => ([f[0], f[1], f[2]], f[3], None),
                    6 => ([f[0], f[1], f[2]], 1.0, Some([f[3], f[4], f[5]])),
                    k => {
                        return Err((
                            line,
                            format!("`v` takes x y z [w] or x y z r g b, found {k} numbers"),
                        ));
                    }
                };
                if w == 0.0 {
                    return Err((line, "`v` has w = 0".into()));
                }
                mesh.positions.push(xyz);
                mesh.w.push(w);
                mesh.colors.push(color);
            }
            "vt" => {
                let f = floats(&args, line)?;
                if !(1..=3).contains(&f.len()) {
                    return Err((line, format!("`vt` takes u [v [w]], found {} numbers", f.len())));
                }
                mesh.texcoords.push([f[0], f.get(1).copied().unwrap_or(0.0)]);
            }
            "vn" => {
                let f = floats(&args, line)?;
                if f.len() != 3 {
                    return Err((line, format!("`vn` takes x y z, found {} numbers", f.len())));
                }
                mesh.normals.push([f[0], f[1], f[2]]);
            }
            "f" => {
                if args.len() < 3 {
                    return Err((
                        line,
                        format!("a face needs 3 or more corners, found {}", args.len()),
                    ));
                }
                let counts = [mesh.positions.len(), mesh.texcoords.len(), mesh.normals.len()];
                for arg in &args {
                    let corner = parse_corner(arg, counts, line)?;
                    let refs = [Some(corner.position), corner.texcoord, corner.normal];
                    for (slot, r) in max_ref.iter_mut().zip(refs) {
                        if let Some(r) = r.filter(|&r| r >= slot.0) {
                            *slot = (r, line);
                        }
                    }
                    mesh.corners.push(corner);
                }
                let end = u32::try_from(mesh.corners.len())
                    .map_err(|_| (line, "more than 2^32 face corners".to_string()))?;
                mesh.face_starts.push(end);
                mesh.face_lines.push(line as u32);
                mesh.face_materials.push(material);
            }
            "mtllib" if !args.is_empty() => {
                mesh.material_libraries.push((args.join(" "), line as u32));
            }
            "usemtl" => {
                let name = args.join(" ");
                material = (!name.is_empty()).then(|| {
                    let next = material_index.len() as u32;
                    *material_index.entry(name.clone()).or_insert_with(|| {
                        mesh.material_names.push((name, line as u32));
                        next
                    })
                });
            }
            _ => {}
        }
    }
    let counts = [mesh.positions.len(), mesh.texcoords.len(), mesh.normals.len()];
    for (((max, line), count), what) in max_ref.iter().zip(counts).zip(["v", "vt", "vn"]) {
        if *line > 0 && *max as usize >= count {
            return Err((
                *line,
                format!(
                    "index {} refers past the last `{what}` (the file has {count})",
                    u64::from(*max) + 1
                ),
            ));
        }
    }
    Ok(mesh)
}

fn floats(args: &[&str], line: usize) -> Result<Vec<f32>, (usize, String)> {
    args.iter()
        .map(|a| a.parse::<f32>().map_err(|_| (line, format!("expected a number, found `{a}`"))))
        .collect()
}

/// Parses `v`, `v/vt`, `v//vn` or `v/vt/vn`; `counts` are the element counts so far (for
/// negative indices).
fn parse_corner(arg: &str, counts: [usize; 3], line: usize) -> Result<Corner, (usize, String)> {
    let mut parts = arg.split('/');
    let mut index = |k: usize, required: bool| -> Result<Option<u32>, (usize, String)> {
        match parts.next() {
            None | Some("") if !required => Ok(None),
            None | Some("") => Err((line, format!("face corner `{arg}` has no vertex index"))),
            Some(s) => resolve(s, counts[k], line).map(Some),
        }
    };
    let position = index(0, true)?.unwrap_or(0);
    let texcoord = index(1, false)?;
    let normal = index(2, false)?;
    if parts.next().is_some() {
        return Err((line, format!("face corner `{arg}` has more than three indices")));
    }
    Ok(Corner { position, texcoord, normal })
}

/// 1-based or negative (relative) OBJ index to 0-based.
fn resolve(s: &str, count: usize, line: usize) -> Result<u32, (usize, String)> {
    let i: i64 = s.parse().map_err(|_| (line, format!("expected an index, found `{s}`")))?;
    let zero_based = match i {
        0 => return Err((line, "index 0 is invalid: OBJ indices start at 1".into())),
        i if i > 0 => i - 1,
        i => count as i64 + i,
    };
    if zero_based < 0 {
        return Err((line, format!("relative index {i} reaches before the first element")));
    }
    u32::try_from(zero_based).map_err(|_| (line, format!("index {i} is too large")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_corner_forms_and_negative_indices() {
        let src = b"v 0 0 0\nv 1 0 0 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
                    f 1 2 3\nf 1/1 2/1 3/1\nf 1//1 2//1 3//1\nf -3/1/1 -2/1/1 -1/1/1 # c\n";
        let m = parse(src).unwrap();
        assert_eq!(m.face_count(), 4);
        assert_eq!(m.colors[1], Some([1.0, 0.0, 0.0]));
        let last: Vec<_> = m.faces().last().unwrap().to_vec();
        assert_eq!(last[0], Corner { position: 0, texcoord: Some(0), normal: Some(0) });
        assert_eq!(last[2].position, 2);
    }

    #[test]
    fn errors_name_the_line() {
        let cases: &[(&[u8], usize, &str)] = &[
            (b"v 0 0\n", 1, "found 2 numbers"),
            (b"v 0 0 0\nv 1 x 0\n", 2, "found `x`"),
            (b"v 0 0 0\nf 1 2\n", 2, "3 or more"),
            (b"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 4\n", 5, "past the last `v`"),
            (b"v 0 0 0\nf 0 1 1\n", 2, "index 0"),
            (b"v 0 0 0\nf -2 1 1\n", 2, "before the first"),
            (b"v 0 0 0\nf 1/2 1 1\n", 2, "past the last `vt`"),
            (b"v 0 0 0\nf 1/1/1/1 1 1\n", 2, "more than three"),
            (b"v 0 0 0\nf /1 1 1\n", 2, "no vertex index"),
            (b"v 0 0 0 0\n", 1, "w = 0"),
            (b"vn 0 0\n", 1, "`vn` takes"),
            (b"v 0 0 0\n\xff\n", 2, "UTF-8"),
        ];
        for (src, line, needle) in cases {
            let (l, msg) = parse(src).unwrap_err();
            assert_eq!(l, *line, "{msg}");
            assert!(msg.contains(needle), "{msg:?} should contain {needle:?}");
        }
    }
}
