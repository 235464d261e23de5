//! Wavefront OBJ reader.
//!
//! Hand-written rather than taken from `tobj` for two reasons that matter here: errors must name
//! the line, and triangles must be numbered in file order (tobj regroups faces by object and
//! material). Supported: `v x y z [w]` and `v x y z [w] r g b` (the colour extension; with
//! `w`, positive, for window-space scenes drawn in perspective), `vt`, `vn`, and faces of any size
//! whose corners are `v`, `v/vt`, `v//vn` or `v/vt/vn`, with negative (relative) indices.
//! `mtllib` and `usemtl` are recorded; [`read_mesh`] resolves them through [`super::mtl`].
//! Other statements of the format (`o`, `g`, `s`, `l`, `p`, ...) are skipped; a keyword the
//! format does not have is a warning. A `\` at the end of a line continues its statement.
//!
//! Two readers share one statement parser (`Statements`):
//! - [`parse`] keeps the file as written ([`ObjMesh`]: every element and face corner), which the
//!   window projection reads and [`to_mesh`], the reference, turns into an indexed [`Mesh`];
//! - [`parse_mesh`] (what [`read_mesh`] uses) builds the same [`Mesh`] while it reads, line by
//!   line from a buffered file (see `mesh::read_lines`): a face whose corners are all read
//!   becomes triangles at once, so neither the file's bytes nor its corners are kept. A 37 MB
//!   OBJ of 1,000,000 triangles had peaked at 254 MB through the two steps, for a mesh of 18
//!   MB; now 61 MB.
//!
//! Positive indices may refer forwards, to elements later in the file. [`parse_mesh`] keeps
//! the faces from the first such one on as written (their corners in memory, as [`parse`]
//! keeps them) and turns them into triangles at the end, so that the triangles stay in file
//! order.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use super::{Material, Mesh};
use crate::error::Error;
use crate::input::ReadProgress;

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

/// An OBJ file's material statements, which [`super::mtl::apply`] resolves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialStatements {
    /// The argument of each `mtllib` statement (one or more file names) with its line.
    pub libraries: Vec<(String, u32)>,
    /// Distinct `usemtl` names in order of first use, with the line of that first use.
    pub names: Vec<(String, u32)>,
}

/// The contents of an OBJ file, faces in file order.
///
/// What [`read`] and [`parse`] return holds together: `face_starts` rises from 0 to
/// `corners.len()` by three or more corners a face, `w` and `colors` have an entry per
/// position, and every index is within its array. The functions of a mesh made or changed by
/// hand ([`ObjMesh::faces`], [`to_mesh`], [`super::window_triangles`]) panic where it does
/// not (faces of fewer than three corners give no triangles).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ObjMesh {
    /// `v` positions.
    pub positions: Vec<[f32; 3]>,
    /// `w` of each `v` (1 when absent).
    pub w: Vec<f32>,
    /// Optional `v x y z [w] r g b` colour of each position, in [0, 1].
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
    /// The `mtllib` and `usemtl` statements.
    pub materials: MaterialStatements,
    /// For each face, the `usemtl` in force as an index into `materials.names` (`None` before
    /// the first `usemtl`).
    pub face_materials: Vec<Option<u32>>,
    /// Problems that did not stop reading (statements of unknown kinds), for the user to see.
    pub warnings: Vec<String>,
}

impl ObjMesh {
    /// Iterates over the faces' corner lists.
    ///
    /// # Panics
    /// Where `face_starts` does not rise within `corners` (see [`ObjMesh`]).
    pub fn faces(&self) -> impl Iterator<Item = &[Corner]> {
        self.face_starts.windows(2).map(|w| &self.corners[w[0] as usize..w[1] as usize])
    }

    /// Number of faces.
    #[must_use]
    pub fn face_count(&self) -> usize {
        self.face_starts.len().saturating_sub(1)
    }

    /// Number of triangles once every face is fanned.
    ///
    /// # Panics
    /// As [`ObjMesh::faces`].
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        // Saturating: a face of fewer than three corners (made by hand) fans to none, where
        // a wrapped count had asked `window_triangles` for an impossible allocation.
        self.faces().map(|f| f.len().saturating_sub(2)).sum()
    }
}

/// Reads and parses an OBJ file as written (see [`parse`]).
pub fn read(path: &Path) -> Result<ObjMesh, Error> {
    let mut obj = ObjMesh { face_starts: vec![0], ..ObjMesh::default() };
    let (materials, unknown) =
        read_statements(open(path, &|_| {})?, &mut obj).map_err(|f| f.at(path))?;
    obj.materials = materials;
    obj.warnings.extend(unknown.map(|u| u.warning(path.display())));
    let colours = obj.colors.iter().flatten().copied();
    obj.warnings.extend(super::colour_warning(path.display(), colours));
    Ok(obj)
}

/// Reads an OBJ file as an indexed [`Mesh`]: corners with the same (v, vt, vn) share a vertex,
/// faces are triangulated by [`crate::polygon::triangulate_face`] in file order. Materials
/// come from the `mtllib` files (see [`super::mtl::apply`]); a missing library or texture is a
/// warning in [`Mesh::warnings`]. Read line by line (see [`parse_mesh`]).
pub fn read_mesh(path: &Path) -> Result<Mesh, Error> {
    read_mesh_reporting(path, &|_| {})
}

/// [`read_mesh`], telling `report` how many bytes of the OBJ file it has read so far.
pub(crate) fn read_mesh_reporting(path: &Path, report: &dyn Fn(u64)) -> Result<Mesh, Error> {
    let (mut mesh, materials) = built_mesh(open(path, report)?, path)?;
    super::mtl::apply(&mut mesh, &materials, path)?;
    Ok(mesh)
}

/// [`build_mesh`] of `input`, its warnings (unknown statements, colours out of range) in the
/// mesh, `path` naming the file in them and in errors.
fn built_mesh(input: impl BufRead, path: &Path) -> Result<(Mesh, MaterialStatements), Error> {
    let (mut mesh, materials, unknown) = build_mesh(input).map_err(|f| f.at(path))?;
    mesh.warnings.extend(unknown.map(|u| u.warning(path.display())));
    let colours = mesh.colors.iter().flatten().copied();
    mesh.warnings.extend(super::colour_warning(path.display(), colours));
    Ok((mesh, materials))
}

/// `path` through [`crate::input::open`], buffered for reading line by line, telling `report`
/// how far it has read.
fn open<'a>(
    path: &Path,
    report: &'a dyn Fn(u64),
) -> Result<BufReader<ReadProgress<'a, File>>, Error> {
    let file = crate::input::open(path)?;
    Ok(BufReader::with_capacity(1 << 16, ReadProgress::new(file, report)))
}

/// Parses OBJ text as written; an error is `(line, message)`. Warnings name their line as
/// `line:N:` and vertex colours outside [0, 1] as `OBJ text:`, where [`read`] names the file.
pub fn parse(bytes: &[u8]) -> Result<ObjMesh, (usize, String)> {
    let mut obj = ObjMesh { face_starts: vec![0], ..ObjMesh::default() };
    let (materials, unknown) = read_statements(bytes, &mut obj).map_err(|fail| match fail {
        Fail::Parse(line, message) => (line, message),
        // Not reached: a slice reads without error, and `ObjMesh` grows as usual.
        Fail::Io(e) => (0, e.to_string()),
        Fail::Error(e) => (0, e.to_string()),
    })?;
    obj.materials = materials;
    obj.warnings.extend(unknown.map(|u| u.warning("line")));
    let colours = obj.colors.iter().flatten().copied();
    obj.warnings.extend(super::colour_warning("OBJ text", colours));
    Ok(obj)
}

/// Parses OBJ text into an indexed [`Mesh`] as [`read_mesh`] reads a file, without resolving
/// the materials: the mesh [`to_mesh`] makes of [`parse`]'s result (it is the reference this
/// is tested against), and the material statements. `path` only names the file in errors.
pub fn parse_mesh(bytes: &[u8], path: &Path) -> Result<(Mesh, MaterialStatements), Error> {
    built_mesh(bytes, path)
}

/// Converts parsed OBJ data to an indexed [`Mesh`]. When the file has `usemtl`, `materials`
/// holds one default-coloured [`Material`] per name (preceded by an unnamed default for faces
/// before the first `usemtl`) and `triangle_materials` points into it.
///
/// # Panics
/// If `obj` does not hold together (see [`ObjMesh`]).
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
    let uses_materials = !obj.materials.names.is_empty();
    let face_material = |f: usize| obj.face_materials.get(f).copied().flatten();
    let offset = u32::from((0..obj.face_count()).any(|f| face_material(f).is_none()));
    if uses_materials {
        mesh.materials = materials_of(&obj.materials.names, offset);
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

/// The materials of a mesh whose file names `names` in `usemtl`: an unnamed default first
/// when `offset` is 1 (some face has no `usemtl` in force), then one per name.
fn materials_of(names: &[(String, u32)], offset: u32) -> Vec<Material> {
    let default = (offset == 1).then(Material::default);
    let named =
        names.iter().map(|(name, _)| Material { name: name.clone(), ..Material::default() });
    default.into_iter().chain(named).collect()
}

/// What stopped a read: a malformed line, or the file or the memory failing.
enum Fail {
    Parse(usize, String),
    Io(std::io::Error),
    Error(Error),
}

impl From<(usize, String)> for Fail {
    fn from((line, message): (usize, String)) -> Self {
        Self::Parse(line, message)
    }
}

impl Fail {
    /// The error, naming the file at `path`.
    fn at(self, path: &Path) -> Error {
        match self {
            Self::Parse(line, message) => Error::Parse { path: path.to_path_buf(), line, message },
            Self::Io(e) => Error::io(path, e),
            Self::Error(e) => e,
        }
    }
}

/// [`crate::error::try_grow`] for [`parse_mesh`]'s arrays, which grow with the file.
fn reserve<'v, T>(v: &'v mut Vec<T>, n: usize, what: &str) -> Result<&'v mut Vec<T>, Fail> {
    crate::error::try_grow(v, n, what).map_err(Fail::Error)
}

/// Marks an absent index (a corner without `vt` or `vn`; no vertex made yet). Element counts
/// stop at it ([`Statements::count`]), so every valid index is below it.
const NONE: u32 = u32::MAX;

/// What the statements of an OBJ file hand on, in file order: [`ObjMesh`] keeps it as
/// written, [`MeshBuilder`] makes triangles of it.
trait Elements {
    /// A `v` statement.
    fn vertex(&mut self, xyz: [f32; 3], w: f32, color: Option<[f32; 3]>) -> Result<(), Fail>;
    /// A `vt` statement.
    fn texcoord(&mut self, uv: [f32; 2]) -> Result<(), Fail>;
    /// A `vn` statement.
    fn normal(&mut self, normal: [f32; 3]) -> Result<(), Fail>;
    /// A face of three or more corners on `line`, with the `usemtl` in force. Its positive
    /// indices may refer past the elements so far; [`Statements::finish`] checks them.
    fn face(&mut self, corners: &[Corner], line: usize, material: Option<u32>) -> Result<(), Fail>;
}

impl Elements for ObjMesh {
    fn vertex(&mut self, xyz: [f32; 3], w: f32, color: Option<[f32; 3]>) -> Result<(), Fail> {
        self.positions.push(xyz);
        self.w.push(w);
        self.colors.push(color);
        Ok(())
    }

    fn texcoord(&mut self, uv: [f32; 2]) -> Result<(), Fail> {
        self.texcoords.push(uv);
        Ok(())
    }

    fn normal(&mut self, normal: [f32; 3]) -> Result<(), Fail> {
        self.normals.push(normal);
        Ok(())
    }

    fn face(&mut self, corners: &[Corner], line: usize, material: Option<u32>) -> Result<(), Fail> {
        self.corners.extend_from_slice(corners);
        let end = u32::try_from(self.corners.len())
            .map_err(|_| (line, "more than 2^32 face corners".to_string()))?;
        self.face_starts.push(end);
        self.face_lines.push(line as u32);
        self.face_materials.push(material);
        Ok(())
    }
}

/// Reads `input` line by line (see `mesh::read_lines`), each statement to `elements`;
/// returns the material statements.
fn read_statements(
    input: impl BufRead,
    elements: &mut impl Elements,
) -> Result<(MaterialStatements, Option<Unknown>), Fail> {
    let mut statements = Statements::default();
    super::read_lines(input, Fail::Io, |text, line| statements.line(text, line, elements))?;
    if !statements.continued.is_empty() {
        // The file ends on a continuation: the statement is what came before it.
        statements.line(b"", 0, elements)?;
    }
    let unknown = statements.unknown.take();
    Ok((statements.finish()?, unknown))
}

/// Statements of the OBJ format this reader skips: grouping and smoothing (`o`, `g`, `s`,
/// `mg`), lines and points (`l`, `p`), free-form geometry and its attributes, and display
/// statements. Any other keyword is not OBJ (a typo such as `F`, or another format under an
/// `.obj` name: a PLY file had read as an empty mesh without a word), and is warned of.
const SKIPPED: [&[u8]; 33] = [
    b"o",
    b"g",
    b"s",
    b"mg",
    b"l",
    b"p",
    b"vp",
    b"cstype",
    b"deg",
    b"bmat",
    b"step",
    b"curv",
    b"curv2",
    b"surf",
    b"parm",
    b"trim",
    b"hole",
    b"scrv",
    b"sp",
    b"end",
    b"con",
    b"call",
    b"csh",
    b"bevel",
    b"c_interp",
    b"d_interp",
    b"lod",
    b"shadow_obj",
    b"trace_obj",
    b"ctech",
    b"stech",
    b"maplib",
    b"usemap",
];

/// The first statement of a kind the reader does not know (see [`SKIPPED`]), and how many
/// more lines held one.
struct Unknown {
    line: usize,
    keyword: String,
    more: usize,
}

impl Unknown {
    /// The warning, its line after `file`.
    fn warning(&self, file: impl std::fmt::Display) -> String {
        let more = match self.more {
            0 => String::new(),
            1 => " (and 1 more line of unknown statements)".to_string(),
            n => format!(" (and {n} more lines of unknown statements)"),
        };
        format!("{file}:{}: unknown statement `{}` ignored{more}", self.line, self.keyword)
    }
}

/// The statement parser both readers share: relative indices, the references checked at the
/// end, the materials.
#[derive(Default)]
struct Statements {
    /// `v`, `vt` and `vn` statements so far.
    counts: [usize; 3],
    /// Per kind, the largest index referred to and the last line referring to it: positive
    /// indices may refer forwards, so they are checked once the whole file is read.
    max_ref: [(u32, usize); 3],
    /// The `usemtl` in force, as an index into `materials.names`.
    material: Option<u32>,
    /// `materials.names` by name.
    material_index: HashMap<String, u32>,
    materials: MaterialStatements,
    /// The corners of the face being read.
    corners: Vec<Corner>,
    /// The statements of unknown kinds.
    unknown: Option<Unknown>,
    /// The lines of a statement continued by a `\` at their ends, joined, and the line it
    /// starts on (which errors name).
    continued: Vec<u8>,
    continued_from: usize,
}

impl Statements {
    /// One line to `elements`: its statement, or part of one continued onto the next line
    /// by a `\` at its end (outside a comment), as the OBJ format allows.
    fn line(&mut self, raw: &[u8], line: usize, elements: &mut impl Elements) -> Result<(), Fail> {
        // A CRLF line's `\r` is trimmed first, so that only lines ending in `\` leave the way.
        if raw.trim_ascii_end().ends_with(b"\\") || !self.continued.is_empty() {
            return self.continued_line(raw, line, elements);
        }
        self.statement(raw, line, elements)
    }

    /// [`Self::line`] of a line ending in `\` or continuing one (rare, and kept out of its
    /// way).
    #[cold]
    fn continued_line(
        &mut self,
        raw: &[u8],
        line: usize,
        elements: &mut impl Elements,
    ) -> Result<(), Fail> {
        if let Some(part) = raw.trim_ascii_end().strip_suffix(b"\\")
            && memchr::memchr(b'#', part).is_none()
        {
            if self.continued.is_empty() {
                self.continued_from = line;
            }
            self.continued.extend_from_slice(part);
            self.continued.push(b' ');
            return Ok(());
        }
        if self.continued.is_empty() {
            return self.statement(raw, line, elements);
        }
        let mut text = std::mem::take(&mut self.continued);
        text.extend_from_slice(raw);
        let done = self.statement(&text, self.continued_from, elements);
        text.clear();
        self.continued = text;
        done
    }

    /// One statement to `elements`; `line` is where it starts.
    fn statement(
        &mut self,
        raw: &[u8],
        line: usize,
        elements: &mut impl Elements,
    ) -> Result<(), Fail> {
        let mut tokens = super::statement_words(raw);
        let Some(keyword) = tokens.next() else { return Ok(()) };
        match keyword {
            b"v" => {
                let (f, k) = floats::<7>(tokens, line)?;
                let (xyz, w, color) = match k {
                    3 => ([f[0], f[1], f[2]], 1.0, None),
                    4 => ([f[0], f[1], f[2]], f[3], None),
                    6 => ([f[0], f[1], f[2]], 1.0, Some([f[3], f[4], f[5]])),
                    7 => ([f[0], f[1], f[2]], f[3], Some([f[4], f[5], f[6]])),
                    k => {
                        let message =
                            format!("`v` takes x y z [w] or x y z [w] r g b, found {k} numbers");
                        return Err(Fail::Parse(line, message));
                    }
                };
                // A window vertex's w is its clip-space w, positive in front of the eye: a
                // negative one had drawn colours jumping along a line and transparent pixels
                // where the interpolated 1 / w crosses zero.
                if w <= 0.0 {
                    let message = format!("`v` has w = {w}; w must be positive");
                    return Err(Fail::Parse(line, message));
                }
                if w.is_finite() && !w.recip().is_finite() {
                    // A window vertex's 1 / w: the rasterizer would drop its triangles as if
                    // the file had said `inf`.
                    let message = format!("`v` has w = {w:e}, too small for 1 / w in f32");
                    return Err(Fail::Parse(line, message));
                }
                self.count(0, line)?;
                elements.vertex(xyz, w, color)
            }
            b"vt" => {
                let (f, k) = floats::<3>(tokens, line)?;
                if !(1..=3).contains(&k) {
                    return Err(Fail::Parse(
                        line,
                        format!("`vt` takes u [v [w]], found {k} numbers"),
                    ));
                }
                self.count(1, line)?;
                elements.texcoord([f[0], if k > 1 { f[1] } else { 0.0 }])
            }
            b"vn" => {
                let (f, k) = floats::<3>(tokens, line)?;
                if k != 3 {
                    return Err(Fail::Parse(line, format!("`vn` takes x y z, found {k} numbers")));
                }
                self.count(2, line)?;
                elements.normal(f)
            }
            b"f" => {
                self.corners.clear();
                while let Some(arg) = tokens.next() {
                    match parse_corner(arg, self.counts, line) {
                        Ok(corner) => self.corners.push(corner),
                        // Too few corners is the error to give, even with a bad one.
                        Err(e) if self.corners.len() + 1 + tokens.count() >= 3 => {
                            return Err(e.into());
                        }
                        Err(_) => break,
                    }
                }
                let n = self.corners.len();
                if n < 3 {
                    let n = super::statement_words(raw).count() - 1;
                    let message = format!("a face needs 3 or more corners, found {n}");
                    return Err(Fail::Parse(line, message));
                }
                for corner in &self.corners {
                    let refs = [Some(corner.position), corner.texcoord, corner.normal];
                    for (slot, r) in self.max_ref.iter_mut().zip(refs) {
                        if let Some(r) = r.filter(|&r| r >= slot.0) {
                            *slot = (r, line);
                        }
                    }
                }
                elements.face(&self.corners, line, self.material)
            }
            b"mtllib" => {
                let args: Vec<_> = tokens.map(String::from_utf8_lossy).collect();
                if !args.is_empty() {
                    self.materials.libraries.push((args.join(" "), line as u32));
                }
                Ok(())
            }
            b"usemtl" => {
                let name = tokens.map(String::from_utf8_lossy).collect::<Vec<_>>().join(" ");
                self.material = (!name.is_empty()).then(|| {
                    let next = self.material_index.len() as u32;
                    *self.material_index.entry(name.clone()).or_insert_with(|| {
                        self.materials.names.push((name, line as u32));
                        next
                    })
                });
                Ok(())
            }
            _ if SKIPPED.contains(&keyword) => Ok(()),
            _ => {
                match &mut self.unknown {
                    Some(unknown) => unknown.more += 1,
                    None => {
                        let (keyword, cut) = super::shown_at_most(keyword, 24);
                        let mut keyword = keyword.into_owned();
                        if cut {
                            keyword.push_str("...");
                        }
                        self.unknown = Some(Unknown { line, keyword, more: 0 });
                    }
                }
                Ok(())
            }
        }
    }

    /// Counts a `v` (`kind` 0), `vt` (1) or `vn` (2) statement; at most [`NONE`] of a kind,
    /// as the mesh's `u32` indices reach them.
    fn count(&mut self, kind: usize, line: usize) -> Result<(), Fail> {
        if self.counts[kind] >= NONE as usize {
            let what = ["v", "vt", "vn"][kind];
            return Err(Fail::Parse(line, format!("more than {NONE} `{what}` statements")));
        }
        self.counts[kind] += 1;
        Ok(())
    }

    /// The material statements, once every index referred to is checked against the file's
    /// elements.
    fn finish(self) -> Result<MaterialStatements, Fail> {
        for (((max, line), count), what) in
            self.max_ref.iter().zip(self.counts).zip(["v", "vt", "vn"])
        {
            if *line > 0 && *max as usize >= count {
                let message = format!(
                    "index {} refers past the last `{what}` (the file has {count})",
                    u64::from(*max) + 1
                );
                return Err(Fail::Parse(*line, message));
            }
        }
        Ok(self.materials)
    }
}

/// Parses every token as a number, keeping the first `N`: returns them and how many there
/// were (the statements' messages count them all).
fn floats<'a, const N: usize>(
    tokens: impl Iterator<Item = &'a [u8]>,
    line: usize,
) -> Result<([f32; N], usize), Fail> {
    let mut values = [0.0; N];
    let mut count = 0;
    for a in tokens {
        let x = number(a).ok_or_else(|| {
            let a = super::shown(a);
            Fail::Parse(line, format!("expected a number, found `{a}`"))
        })?;
        if let Some(slot) = values.get_mut(count) {
            *slot = x;
        }
        count += 1;
    }
    Ok((values, count))
}

/// Parses `v`, `v/vt`, `v//vn` or `v/vt/vn`; `counts` are the element counts so far (for
/// negative indices).
fn parse_corner(arg: &[u8], counts: [usize; 3], line: usize) -> Result<Corner, (usize, String)> {
    match plain_corner(arg) {
        Some(corner) => Ok(corner),
        None => parse_any_corner(&super::shown(arg), counts, line),
    }
}

/// [`parse_corner`] of any spelling, with its errors.
fn parse_any_corner(arg: &str, counts: [usize; 3], line: usize) -> Result<Corner, (usize, String)> {
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

/// [`parse_corner`] of a corner whose indices are all plain positive numbers of up to nine
/// digits (nearly every corner), in one pass over its bytes; `None` for anything else (signs,
/// zero, a missing position, a fourth index, other characters), which the general parse
/// takes, with its errors. Splitting on `/` and the general integer parse had been a tenth
/// of loading the Stanford bunny.
fn plain_corner(bytes: &[u8]) -> Option<Corner> {
    let mut fields = [None; 3];
    let (mut k, mut value, mut digits) = (0, 0u32, 0);
    for &b in bytes {
        let digit = b.wrapping_sub(b'0');
        if digit < 10 {
            if digits == 9 {
                return None;
            }
            (value, digits) = (value * 10 + u32::from(digit), digits + 1);
        } else if b == b'/' && k < 2 {
            if digits > 0 {
                fields[k] = Some(value.checked_sub(1)?);
            }
            (k, value, digits) = (k + 1, 0, 0);
        } else {
            return None;
        }
    }
    if digits > 0 {
        fields[k] = Some(value.checked_sub(1)?);
    }
    let [position, texcoord, normal] = fields;
    Some(Corner { position: position?, texcoord, normal })
}

/// `token` as an `f32`: the value `str::parse` gives, or `None` where it fails. Nearly every
/// OBJ number is a plain decimal of a few digits (`-0.037830`): its digits as an integer
/// `m` up to `2^24` and `10^k` up to `10^10` are both exact in `f32`, so `m / 10^k` is
/// rounded once, as the parse rounds (Clinger's fast path), and the sign is exact. Anything
/// else (more digits, an exponent, `inf`) goes to `str::parse`, which had been an eighth of
/// loading the Stanford bunny: over 200 instructions a number.
fn number(token: &[u8]) -> Option<f32> {
    const POWERS: [f32; 11] = [1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10];
    let (negative, digits) = match token {
        [b'-', rest @ ..] => (true, rest),
        [b'+', rest @ ..] => (false, rest),
        _ => (false, token),
    };
    // Up to 19 digits, `m` cannot overflow; the bounds are checked once, after.
    let (mut m, mut n, mut point) = (0u64, 0usize, None);
    for &b in digits {
        let digit = b.wrapping_sub(b'0');
        if digit < 10 {
            m = m.wrapping_mul(10).wrapping_add(u64::from(digit));
            n += 1;
        } else if b == b'.' && point.is_none() {
            point = Some(n);
        } else {
            return parse_number(token);
        }
    }
    let k = n - point.unwrap_or(n);
    if n == 0 || n > 19 || m > 1 << 24 || k >= POWERS.len() {
        return parse_number(token);
    }
    let x = m as f32 / POWERS[k];
    Some(if negative { -x } else { x })
}

/// `str::parse` of `token`, for [`number`]'s other spellings.
fn parse_number(token: &[u8]) -> Option<f32> {
    std::str::from_utf8(token).ok()?.parse().ok()
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

/// Builds [`parse_mesh`]'s indexed [`Mesh`] while the file is read: the same mesh as
/// [`to_mesh`] (vertices in order of first use, one per distinct (v, vt, vn), the same
/// triangles, attributes and materials), but what [`to_mesh`] learns from the whole file (is
/// there a texture coordinate, a normal, a colour, a `usemtl`?) is settled when the first one
/// appears, filling in the defaults for what came before.
#[derive(Default)]
struct MeshBuilder {
    mesh: Mesh,
    /// The file's `v`, `vt` and `vn` so far.
    positions: Vec<[f32; 3]>,
    texcoords: Vec<[f32; 2]>,
    normals: Vec<[f32; 3]>,
    /// The `v` colours (white where absent), from the first `v` with one.
    colors: Option<Vec<[f32; 3]>>,
    /// Per `v`, the vertex first made of it ([`NONE`] until then)...
    first_vertex: Vec<u32>,
    /// ...and that vertex's `vt` and `vn` ([`NONE`] when absent), from the first corner
    /// with either. Most files give each `v` one vertex, so the other keys are few.
    first_key: Option<Vec<[u32; 2]>>,
    /// The vertices made of other (v, vt, vn).
    other_vertices: HashMap<[u32; 3], u32>,
    /// Per triangle, the `usemtl` in force ([`NONE`] for none), from the first face with one.
    materials: Option<Vec<u32>>,
    /// Whether some face has no `usemtl` in force: the materials then start with a default.
    face_without_material: bool,
    /// The faces from the first one referring forwards on, as written, made into triangles
    /// once the file is read.
    deferred: Option<ObjMesh>,
    /// The current face's vertices and positions.
    face_vertices: Vec<u32>,
    face_points: Vec<[f32; 3]>,
}

impl Elements for MeshBuilder {
    fn vertex(&mut self, xyz: [f32; 3], _w: f32, color: Option<[f32; 3]>) -> Result<(), Fail> {
        let k = self.positions.len();
        if color.is_some() && self.colors.is_none() {
            self.colors =
                Some(crate::error::try_filled(k, [1.0; 3], "OBJ colours").map_err(Fail::Error)?);
            let vertices = self.mesh.positions.len();
            let white = crate::error::try_filled(vertices, [1.0; 4], "OBJ vertex colours");
            self.mesh.colors = Some(white.map_err(Fail::Error)?);
        }
        reserve(&mut self.positions, 1, "OBJ positions")?.push(xyz);
        reserve(&mut self.first_vertex, 1, "OBJ vertex indices")?.push(NONE);
        if let Some(keys) = &mut self.first_key {
            reserve(keys, 1, "OBJ vertices")?.push([NONE; 2]);
        }
        if let Some(colors) = &mut self.colors {
            reserve(colors, 1, "OBJ colours")?.push(color.unwrap_or([1.0; 3]));
        }
        Ok(())
    }

    fn texcoord(&mut self, uv: [f32; 2]) -> Result<(), Fail> {
        reserve(&mut self.texcoords, 1, "OBJ texture coordinates")?.push(uv);
        Ok(())
    }

    fn normal(&mut self, normal: [f32; 3]) -> Result<(), Fail> {
        reserve(&mut self.normals, 1, "OBJ normals")?.push(normal);
        Ok(())
    }

    fn face(&mut self, corners: &[Corner], line: usize, material: Option<u32>) -> Result<(), Fail> {
        if self.deferred.is_none() {
            let read = |i: Option<u32>, count: usize| i.is_none_or(|i| (i as usize) < count);
            let all_read = corners.iter().all(|c| {
                read(Some(c.position), self.positions.len())
                    && read(c.texcoord, self.texcoords.len())
                    && read(c.normal, self.normals.len())
            });
            if all_read {
                return self.triangulate(corners, line, material);
            }
            self.deferred = Some(ObjMesh { face_starts: vec![0], ..ObjMesh::default() });
        }
        match &mut self.deferred {
            Some(deferred) => deferred.face(corners, line, material),
            None => Ok(()),
        }
    }
}

impl MeshBuilder {
    /// The face's triangles, in order, with their vertices and material.
    fn triangulate(
        &mut self,
        corners: &[Corner],
        line: usize,
        material: Option<u32>,
    ) -> Result<(), Fail> {
        self.face_vertices.clear();
        for c in corners {
            let v = self.vertex_of(c, line)?;
            self.face_vertices.push(v);
        }
        let before = self.mesh.triangles.len();
        let triangles = reserve(&mut self.mesh.triangles, 1, "OBJ triangles")?;
        if let [a, b, c] = self.face_vertices[..] {
            // `triangulate_face`'s answer for three corners, without its `Vec`.
            triangles.push([a, b, c]);
        } else {
            self.face_points.clear();
            let positions = corners.iter().map(|c| self.positions[c.position as usize]);
            self.face_points.extend(positions);
            for t in crate::polygon::triangulate_face(&self.face_points) {
                reserve(triangles, 1, "OBJ triangles")?.push(t.map(|k| self.face_vertices[k]));
            }
        }
        let after = self.mesh.triangles.len();
        self.face_without_material |= material.is_none();
        if material.is_some() && self.materials.is_none() {
            let none = crate::error::try_filled(before, NONE, "OBJ triangle materials");
            self.materials = Some(none.map_err(Fail::Error)?);
        }
        if let Some(materials) = &mut self.materials {
            reserve(materials, after - before, "OBJ triangle materials")?;
            materials.resize(after, material.unwrap_or(NONE));
        }
        self.mesh.polygon_count += 1;
        Ok(())
    }

    /// The vertex of corner `c` (whose indices are all read), made if it is the first use of
    /// its (v, vt, vn). `line` names the face in errors.
    fn vertex_of(&mut self, c: &Corner, line: usize) -> Result<u32, Fail> {
        let p = c.position as usize;
        let key = [c.texcoord.unwrap_or(NONE), c.normal.unwrap_or(NONE)];
        if key != [NONE; 2] && self.first_key.is_none() {
            let keys = crate::error::try_filled(self.positions.len(), [NONE; 2], "OBJ vertices");
            self.first_key = Some(keys.map_err(Fail::Error)?);
        }
        let first = self.first_vertex[p];
        if first == NONE {
            let v = self.new_vertex(c, line)?;
            self.first_vertex[p] = v;
            if let Some(keys) = &mut self.first_key {
                keys[p] = key;
            }
            return Ok(v);
        }
        if self.first_key.as_ref().map_or([NONE; 2], |keys| keys[p]) == key {
            return Ok(first);
        }
        let triple = [c.position, key[0], key[1]];
        if let Some(&v) = self.other_vertices.get(&triple) {
            return Ok(v);
        }
        let v = self.new_vertex(c, line)?;
        self.other_vertices.insert(triple, v);
        Ok(v)
    }

    /// A new vertex for corner `c`, with its attributes (the defaults where it has none).
    fn new_vertex(&mut self, c: &Corner, line: usize) -> Result<u32, Fail> {
        let mesh = &mut self.mesh;
        let next = mesh.positions.len();
        let v = match u32::try_from(next) {
            Ok(v) if v < NONE => v,
            _ => {
                let message = format!("more than {NONE} vertices (distinct v/vt/vn corners)");
                return Err(Fail::Parse(line, message));
            }
        };
        let p = c.position as usize;
        reserve(&mut mesh.positions, 1, "OBJ vertices")?.push(self.positions[p]);
        push_attribute(
            &mut mesh.texcoords,
            c.texcoord,
            &self.texcoords,
            next,
            "OBJ texture coordinates",
        )?;
        push_attribute(&mut mesh.normals, c.normal, &self.normals, next, "OBJ normals")?;
        if let (Some(colors), Some(raw)) = (&mut mesh.colors, &self.colors) {
            let [r, g, b] = raw[p];
            reserve(colors, 1, "OBJ vertex colours")?.push([r, g, b, 1.0]);
        }
        Ok(v)
    }

    /// The mesh, once the file is read (its indices checked): the deferred faces made into
    /// triangles, the materials numbered as [`to_mesh`] numbers them.
    fn finish(mut self, names: &[(String, u32)]) -> Result<Mesh, Fail> {
        if let Some(deferred) = self.deferred.take() {
            let faces = deferred.faces().zip(&deferred.face_lines).zip(&deferred.face_materials);
            for ((face, &line), &material) in faces {
                self.triangulate(face, line as usize, material)?;
            }
        }
        let mut mesh = self.mesh;
        if !names.is_empty() {
            let offset = u32::from(self.face_without_material);
            mesh.materials = materials_of(names, offset);
            let materials = match self.materials {
                Some(mut m) => {
                    m.iter_mut().for_each(|k| *k = if *k == NONE { 0 } else { *k + offset });
                    m
                }
                None => crate::error::try_filled(mesh.triangles.len(), 0, "OBJ triangle materials")
                    .map_err(Fail::Error)?,
            };
            mesh.triangle_materials = Some(materials);
        }
        Ok(mesh)
    }
}

/// A new vertex's attribute from `raw` at `index` (zero when absent) onto `out`, which is made
/// at the first vertex with one, zero for the `next` vertices before it.
fn push_attribute<T: Copy + Default>(
    out: &mut Option<Vec<T>>,
    index: Option<u32>,
    raw: &[T],
    next: usize,
    what: &str,
) -> Result<(), Fail> {
    if index.is_some() && out.is_none() {
        *out = Some(crate::error::try_filled(next, T::default(), what).map_err(Fail::Error)?);
    }
    if let Some(out) = out {
        let value = index.map_or(T::default(), |i| raw[i as usize]);
        reserve(out, 1, what)?.push(value);
    }
    Ok(())
}

/// [`parse_mesh`] on any buffered input.
fn build_mesh(input: impl BufRead) -> Result<(Mesh, MaterialStatements, Option<Unknown>), Fail> {
    let mut builder = MeshBuilder::default();
    let (materials, unknown) = read_statements(input, &mut builder)?;
    Ok((builder.finish(&materials.names)?, materials, unknown))
}

#[cfg(test)]
mod tests {
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

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

    /// The one-pass corner parse agrees with the general one wherever it answers, and
    /// answers for the plain forms: random strings of digits, `/`, signs and letters.
    #[test]
    fn plain_corners_parse_as_the_general_parse() {
        let mut rng = SmallRng::seed_from_u64(3);
        let alphabet = b"0123456789//+-x";
        let mut answered = 0;
        for round in 0..200_000 {
            let len = rng.random_range(1..14);
            let bytes: Vec<u8> =
                (0..len).map(|_| alphabet[rng.random_range(0..alphabet.len())]).collect();
            let text = String::from_utf8(bytes).unwrap();
            let general = parse_any_corner(&text, [5; 3], 1).map_err(|_| ());
            if let Some(plain) = plain_corner(text.as_bytes()) {
                assert_eq!(Ok(plain), general, "{text:?} in round {round}");
                answered += 1;
            }
            if text.bytes().all(|b| b.is_ascii_digit()) && text.len() <= 9 && general.is_ok() {
                assert!(plain_corner(text.as_bytes()).is_some(), "{text:?} is plain");
            }
        }
        assert!(answered > 1000, "{answered}");
        let plain = |s: &str| plain_corner(s.as_bytes());
        assert_eq!(
            plain("3/1/2"),
            Some(Corner { position: 2, texcoord: Some(0), normal: Some(1) })
        );
        assert_eq!(plain("3//2"), Some(Corner { position: 2, texcoord: None, normal: Some(1) }));
        assert_eq!(plain("3/"), Some(Corner { position: 2, texcoord: None, normal: None }));
        for general_only in ["", "/1", "0", "1/0", "-1", "+1", "1/2/3/4", "1234567890", "1 "] {
            assert_eq!(plain(general_only), None, "{general_only:?}");
        }
    }

    /// The fast path of [`number`] gives `str::parse`'s bits on every spelling it takes, and
    /// the others reach the parse: random decimals of 1 to 12 digits (a rounding case needs
    /// more than `f32`'s 24 bits), with signs, leading zeros, points anywhere, exponents and
    /// stray characters.
    #[test]
    fn numbers_parse_as_str_parse() {
        let mut rng = SmallRng::seed_from_u64(11);
        let alphabet = b"0123456789012345678901234567890123456789..-+eE x";
        for round in 0..400_000 {
            let len = rng.random_range(1..14);
            let mut bytes: Vec<u8> =
                (0..len).map(|_| alphabet[rng.random_range(0..alphabet.len())]).collect();
            if round % 2 == 0 {
                // Mostly well-formed: an optional sign, digits, one point.
                bytes.retain(u8::is_ascii_digit);
                if !bytes.is_empty() {
                    let at = rng.random_range(0..=bytes.len());
                    bytes.insert(at, b'.');
                }
                if rng.random_bool(0.5) {
                    bytes.insert(0, b'-');
                }
            }
            let text = String::from_utf8(bytes).unwrap();
            let want = text.parse::<f32>().ok().map(f32::to_bits);
            assert_eq!(number(text.as_bytes()).map(f32::to_bits), want, "{text:?}");
        }
        for (text, want) in [("-0.0", Some(-0.0f32)), ("16777217", Some(16_777_216.0)), ("x", None)]
        {
            assert_eq!(number(text.as_bytes()).map(f32::to_bits), want.map(f32::to_bits));
        }
        assert!(number(b"nan").unwrap().is_nan());
    }

    /// A statement of a kind OBJ does not have is a warning naming its line and how many more
    /// there were (a PLY file under an `.obj` name read as an empty mesh without a word); the
    /// OBJ statements this reader skips are not.
    #[test]
    fn unknown_statements_are_warned_of() {
        let text = b"ply\nformat ascii 1.0\nv 0 0 0\nv 1 0 0\nv 0 1 0\nF 1 2 3\nf 1 2 3\n";
        let (mesh, _) = parse_mesh(text, Path::new("m.obj")).unwrap();
        let want = "m.obj:1: unknown statement `ply` ignored (and 2 more lines of unknown \
                    statements)";
        assert_eq!(mesh.warnings, [want]);
        assert_eq!(mesh.triangles.len(), 1);
        assert_eq!(parse(text).unwrap().warnings, [want.replace("m.obj", "line")]);
        let long = format!("v 0 0 0\n{}\n", "x".repeat(100));
        let (mesh, _) = parse_mesh(long.as_bytes(), Path::new("m.obj")).unwrap();
        assert_eq!(
            mesh.warnings,
            [format!("m.obj:2: unknown statement `{}...` ignored", "x".repeat(24))]
        );
        // Cut by characters and bytes before they are escaped: no `\xNN` is cut through.
        let bytes = [b"v 0 0 0\nab".as_slice(), &[0xff; 30], b"\n"].concat();
        let (mesh, _) = parse_mesh(&bytes, Path::new("m.obj")).unwrap();
        let shown = format!("ab{}...", "\\xff".repeat(22));
        assert_eq!(mesh.warnings, [format!("m.obj:2: unknown statement `{shown}` ignored")]);
        let skipped = b"o a\ng b\ns 1\nl 1 2\np 1\nmaplib x\nusemap x\ncstype bezier\nv 0 0 0\n";
        assert!(parse_mesh(skipped, Path::new("m.obj")).unwrap().0.warnings.is_empty());
    }

    /// A `\\` at the end of a line continues its statement on the next (the OBJ format's
    /// continuation, which had been read as an index `\\`); errors name the statement's first
    /// line; a comment's `\\` continues nothing.
    #[test]
    fn statements_continue_past_a_backslash() {
        let text = b"v 0 0 \\\n  0\nv 1 0 0\nv 0 1 0 # c \\\nf 1 \\\r\n2 \\\n 3\n";
        let obj = parse(text).unwrap();
        assert_eq!(obj.positions, [[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        assert_eq!(obj.corners.iter().map(|c| c.position).collect::<Vec<_>>(), [0, 1, 2]);
        let (mesh, _) = parse_mesh(text, Path::new("m.obj")).unwrap();
        assert_eq!(mesh.triangles, [[0, 1, 2]]);
        assert_eq!(parse(b"v 0 0 0\nv 1 \\\nx 0\n").unwrap_err().0, 2);
        let unfinished = parse(b"v 0 0 0\nv 1 0 \\").unwrap_err();
        assert_eq!(
            unfinished,
            (2, "`v` takes x y z [w] or x y z [w] r g b, found 2 numbers".into())
        );
    }

    /// A comment need not be UTF-8 (a Latin-1 name after `#`), and corners spelled with
    /// leading zeros, `+` and relative indices resolve as before; so do nine and ten digits
    /// (one-pass and general parse).
    #[test]
    fn comments_and_index_spellings() {
        let src = b"# made by Jos\xe9\nv 0 0 0 # caf\xe9\nv 1 0 0\nv 0 1 0\n\
                    f 001 +2 3\nf 1 2 -1\n";
        let m = parse(src).unwrap();
        let faces: Vec<Vec<u32>> =
            m.faces().map(|f| f.iter().map(|c| c.position).collect()).collect();
        assert_eq!(faces, [[0, 1, 2], [0, 1, 2]]);
        for s in ["1", "007", "999999999", "1000000000", "4294967295", "+12"] {
            let want = u32::try_from(s.parse::<i64>().unwrap() - 1).unwrap();
            assert_eq!(parse_corner(s.as_bytes(), [0; 3], 1).unwrap().position, want, "{s}");
        }
    }

    /// Names need not be UTF-8 (exporters write Latin-1): their other bytes are replaced, in
    /// the OBJ and in its library alike, so the material is still found; `o caf\xe9` had
    /// refused the file.
    #[test]
    fn names_that_are_not_utf8_are_read() {
        let dir = std::env::temp_dir().join(format!("trirast-latin1-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("caf\u{e9}.mtl"), b"newmtl caf\xe9 au lait\nKd 0 0.5 1\n").unwrap();
        let obj = b"mtllib caf\xc3\xa9.mtl\no caf\xe9\ng \xff\xfe\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
                    usemtl caf\xe9 au lait\nf 1 2 3\n\xff\n";
        let path = dir.join("m.obj");
        std::fs::write(&path, obj).unwrap();
        let mesh = read_mesh(&path).unwrap();
        assert_eq!(mesh.triangles.len(), 1);
        assert_eq!(mesh.materials[0].name, "caf\u{fffd} au lait");
        assert_eq!(mesh.materials[0].diffuse, [0.0, 0.5, 1.0]);
        // A message names the byte, where a name has it replaced.
        let unknown = format!("{}:9: unknown statement `\\xff` ignored", path.display());
        assert_eq!(mesh.warnings, [unknown]);
        std::fs::remove_dir_all(&dir).unwrap();
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
            (b"v 0 0 0 0\n", 1, "w = 0; w must be positive"),
            (b"v 0 0 0 1\nv 0 0 0 -1 1 0 0\n", 2, "w = -1; w must be positive"),
            (b"v 0 0 0 -0\n", 1, "w = -0; w must be positive"),
            (b"vn 0 0\n", 1, "`vn` takes"),
            (b"v 0 0 0 # caf\xe9\nf 1 1 \xe9\n", 2, "found `\\xe9`"),
            (b"v 0 0 \xe9\n", 1, "found `\\xe9`"),
            (b"v 0 0 0\nf 1 1 99999999999\n", 2, "too large"),
            (b"v 0 0 0\nf 1 1 00\n", 2, "index 0"),
        ];
        for (src, line, needle) in cases {
            let (l, msg) = parse(src).unwrap_err();
            assert_eq!(l, *line, "{msg}");
            assert!(msg.contains(needle), "{msg:?} should contain {needle:?}");
        }
    }

    /// A random OBJ text reaching every path of the streamed builder: colours, texture
    /// coordinates and normals that first appear after vertices were made, one position with
    /// several (vt, vn), relative and forward indices, faces of 3 to 6 corners (some concave),
    /// `usemtl` before, between and after faces, comments and blank lines.
    fn random_obj(rng: &mut SmallRng) -> Vec<u8> {
        let mut text = String::new();
        let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
        let forward = rng.random_bool(0.3);
        for _ in 0..rng.random_range(0..60) {
            match rng.random_range(0..10) {
                0..=2 => {
                    let [x, y, z]: [f32; 3] = std::array::from_fn(|_| rng.random_range(-9.0..9.0));
                    text += &match rng.random_range(0..6) {
                        0 => format!("v {x} {y} {z} 0.5 0.25 1\n"),
                        1 => format!("v {x} {y} {z} 2\n"),
                        _ => format!("v {x} {y} {z}\n"),
                    };
                    v += 1;
                }
                3 => {
                    text += &format!("vt {} {}\n", rng.random::<f32>(), rng.random::<f32>());
                    vt += 1;
                }
                4 => {
                    text += "vn 0 0.6 0.8\n";
                    vn += 1;
                }
                5 => text += &format!("usemtl m{}\n", rng.random_range(0..3)),
                6 => text += "# comment\n\n",
                _ if v > 0 || forward => {
                    let n = rng.random_range(3..7);
                    text += "f";
                    for _ in 0..n {
                        // Up to two past the last element when referring forwards.
                        let reach = |count: i64, rng: &mut SmallRng| {
                            let last = if forward { count + 2 } else { count };
                            match rng.random_range(0..4) {
                                0 if count > 0 => -rng.random_range(1..=count),
                                _ => rng.random_range(1..=last.max(1)),
                            }
                        };
                        let p = reach(v, rng);
                        text += &match rng.random_range(0..4) {
                            0 if vt > 0 => format!(" {p}/{}", reach(vt, rng)),
                            1 if vn > 0 => format!(" {p}//{}", reach(vn, rng)),
                            2 if vt > 0 && vn > 0 => {
                                format!(" {p}/{}/{}", reach(vt, rng), reach(vn, rng))
                            }
                            _ => format!(" {p}"),
                        };
                    }
                    text += "\n";
                }
                _ => {}
            }
        }
        // Forward references resolved at the end (or left dangling: an error both ways).
        if forward {
            for _ in 0..3 {
                text += "v 1 2 3\nvt 0.5 0.5\nvn 1 0 0\n";
            }
        }
        text.into_bytes()
    }

    /// The streamed reader builds exactly the mesh `to_mesh` makes of `parse`'s result, and
    /// fails with the same error, on random files (LF, CRLF, and CR with a byte-order mark);
    /// reading a file from disk gives the same mesh and materials.
    #[test]
    fn streamed_mesh_is_the_reference_mesh() {
        let mut rng = SmallRng::seed_from_u64(7);
        let path = Path::new("r.obj");
        let (mut accepted, mut deferred) = (0, 0);
        for round in 0..3000 {
            let mut bytes = random_obj(&mut rng);
            if round % 3 == 1 {
                bytes = String::from_utf8(bytes).unwrap().replace('\n', "\r\n").into_bytes();
            } else if round % 3 == 2 {
                bytes = [&b"\xEF\xBB\xBF"[..], &bytes].concat();
                bytes.iter_mut().filter(|b| **b == b'\n').for_each(|b| *b = b'\r');
            }
            let streamed = parse_mesh(&bytes, path);
            match parse(&bytes) {
                Ok(obj) => {
                    let (mesh, materials) = streamed.unwrap();
                    assert_eq!(mesh, to_mesh(&obj), "{}", String::from_utf8_lossy(&bytes));
                    assert_eq!(materials, obj.materials);
                    accepted += 1;
                    // Faces referring past the `v`s before them (counted on LF files).
                    if round % 3 == 0 {
                        let lines: Vec<&[u8]> = bytes.split(|&b| b == b'\n').collect();
                        let forward = obj.faces().zip(&obj.face_lines).any(|(face, &line)| {
                            let before = &lines[..line as usize - 1];
                            let v = before.iter().filter(|l| l.starts_with(b"v ")).count();
                            face.iter().any(|c| c.position as usize >= v)
                        });
                        deferred += usize::from(forward);
                    }
                }
                Err((line, message)) => match streamed {
                    Err(Error::Parse { line: l, message: m, .. }) => {
                        assert_eq!((l, m), (line, message));
                    }
                    other => panic!("{other:?} where parse failed at {line}: {message}"),
                },
            }
        }
        assert!(accepted > 1000 && deferred > 50, "{accepted} accepted, {deferred} deferred");
        // From a file, through the buffered reader.
        let dir = std::env::temp_dir().join(format!("trirast-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("m.obj");
        let bytes = loop {
            let bytes = random_obj(&mut rng);
            if parse(&bytes).is_ok_and(|obj| obj.face_count() > 5) {
                break bytes;
            }
        };
        std::fs::write(&file, &bytes).unwrap();
        let mut mesh = to_mesh(&parse(&bytes).unwrap());
        super::super::mtl::apply(&mut mesh, &parse(&bytes).unwrap().materials, &file).unwrap();
        assert_eq!(read_mesh(&file).unwrap(), mesh);
        assert_eq!(read(&file).unwrap(), parse(&bytes).unwrap());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
