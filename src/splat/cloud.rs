//! Point clouds: the splatting pipeline's input, read from PLY or sampled from any mesh.
//!
//! A [`PointCloud`] comes from a scanner's PLY file ([`read_ply`]) or from a triangle mesh
//! ([`sample_mesh`]), and can be saved for later runs ([`write_ply`]).
//!
//! # Reading PLY
//!
//! [`read_ply`] takes ASCII, binary little endian and binary big endian files. The header and
//! the elements are decoded by the `ply-rs-bw` crate, driven one element at a time as
//! [`crate::mesh::ply`] does, so that every error names its position: header lines and ASCII
//! elements by their 1-based line, binary elements by the byte offset where the failing
//! element starts (as [`Error::Parse`] with `line: 0` and a message starting `byte N:`).
//!
//! From the `vertex` element (required) it reads:
//!
//! - `x y z` (required; any scalar type, converted to `f32`). A point whose position is not
//!   finite is left out, with a warning counting such points and naming the first: it would
//!   poison every bounding sphere above it, and PCL writes `nan` positions for the invalid
//!   points of organised clouds (a depth camera's pixels without a depth).
//! - `nx ny nz` (all three, or no normals). Normals are normalised on read, so a file with
//!   scaled normals still gives unit normals; a zero normal stays zero (unknown), and so does a
//!   non-finite one (PCL writes `nan` normals for points it could not estimate). A normal that
//!   is already unit to `f32` precision is kept bit for bit, which is what makes
//!   [`write_ply`] -> [`read_ply`] exact.
//! - colours `red green blue` (also `r g b` and `diffuse_red ...`): `uchar` as it is, `ushort`
//!   scaled from 0..65535, other integers clamped to 0..255, `float`/`double` taken as 0..1
//!   (clamped) and rounded to 8 bits; a channel the clamp changed is counted in a warning
//!   ([`PointCloud::warnings`]). `alpha` is allowed and ignored (splats are opaque).
//! - `radius`: the splat radius in world units, finite and non-negative. `scale` and `size`
//!   are deliberately not read: Gaussian-splat files store per-axis *log* scales under
//!   `scale_0..2`, and `size` means a diameter or a pixel size depending on the tool, so
//!   guessing would give wrong splats silently.
//!
//! Other properties and other elements (`face`, say) are skipped; elements after `vertex` are
//! not read at all, since a point cloud has no use for them. Duplicate element or property
//! names are errors (the crate would merge them and misread the body). Reservations are
//! capped by what the rest of the file can hold, so `element vertex 4000000000` in a small
//! file allocates nothing and fails where the data ends.

use std::io::{BufWriter, Read, Write};
use std::path::Path;

use glam::{DVec2, DVec3, Vec2};
use ply_rs_bw::ply::{ElementDef, Property};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::color::{linear_to_srgb8, srgb_decode};
use crate::error::{Error, try_filled};
use crate::mesh::ply_common::{
    At, COLOR_NAMES, Fail, Fields, NX, POSITION_NORMAL, Ply, RED, Sink, Source, X, name_warnings,
    parse_with, read_file, scalar,
};
use crate::mesh::{Mesh, unorm8};
use crate::model::MaterialTextures;
use crate::texture::{Filter, Texture, Wrap};
// The unit tests drive the crate's header parser and the reservation cap themselves.
#[cfg(test)]
use {
    crate::mesh::ply_common::{Row, capacity},
    ply_rs_bw::parser::{Parser, Reader},
    ply_rs_bw::ply::Encoding,
    std::io::Cursor,
};

/// Points with optional per-point normals, colours and radii.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Positions.
    pub positions: Vec<[f32; 3]>,
    /// Unit normals, when known.
    pub normals: Option<Vec<[f32; 3]>>,
    /// sRGB-encoded RGB8 colours, when known.
    pub colors: Option<Vec<[u8; 3]>>,
    /// Splat radii, when known (world units).
    pub radii: Option<Vec<f32>>,
    /// Problems that did not stop reading it (colours out of range, clamped), for the user
    /// to see.
    pub warnings: Vec<String>,
}

impl PointCloud {
    /// Number of points.
    #[must_use]
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no points (an empty cloud renders nothing and builds an empty tree).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The axis-aligned bounding box `(min, max)` of the positions, for framing a camera; `None`
    /// for an empty cloud, which has no box to frame. NaN coordinates are ignored.
    #[must_use]
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        Some(self.positions.iter().fold((first, first), |(lo, hi), p| {
            (std::array::from_fn(|a| lo[a].min(p[a])), std::array::from_fn(|a| hi[a].max(p[a])))
        }))
    }

    /// Checks that every attribute array is as long as `positions`, as the hierarchy and the
    /// writer need.
    ///
    /// # Errors
    /// [`Error::CloudAttributeLength`] naming the first that is not.
    pub fn check_lengths(&self) -> Result<(), Error> {
        let expected = self.positions.len();
        let lengths = [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
            ("radii", self.radii.as_ref().map(Vec::len)),
        ];
        for (attribute, len) in lengths {
            if let Some(len) = len.filter(|&len| len != expected) {
                return Err(Error::CloudAttributeLength { attribute, len, expected });
            }
        }
        Ok(())
    }

    /// Checks what [`write_ply`] needs: attribute arrays as long as `positions`, finite
    /// positions, and radii finite and >= 0 (which [`read_ply`] would refuse).
    fn check(&self) -> Result<(), String> {
        self.check_lengths().map_err(|e| e.to_string())?;
        if let Some(i) = self.positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(format!("point {i}: position {:?} is not finite", self.positions[i]));
        }
        let radii = self.radii.as_deref().unwrap_or_default();
        if let Some(i) = radii.iter().position(|r| !(r.is_finite() && *r >= 0.0)) {
            return Err(format!("point {i}: radius {} is not a finite number >= 0", radii[i]));
        }
        Ok(())
    }
}

// ------------------------------------------------------------------------------------------
// Reading
// ------------------------------------------------------------------------------------------

/// Reads a point cloud from a PLY file (see the [module documentation](self) for what is read).
///
/// # Errors
/// [`Error::Io`] when the file cannot be read, [`Error::NotRegularFile`] when the path is not a
/// regular file (see [`crate::input`]); [`Error::Parse`] naming the file and the line
/// (header, ASCII body) or byte offset (binary body) of the first problem.
pub fn read_ply(path: &Path) -> Result<PointCloud, Error> {
    read_ply_reporting(path, &|_| {})
}

/// [`read_ply`], telling `report` how many bytes of the file it has read so far (the furthest
/// offset reached: see [`crate::input::ReadProgress`]), for a progress bar.
///
/// # Errors
/// As [`read_ply`].
pub fn read_ply_reporting(path: &Path, report: &dyn Fn(u64)) -> Result<PointCloud, Error> {
    read_file(path, report, parse_at).map(|cloud| naming(cloud, path))
}

/// `cloud` with its warnings naming `path`.
fn naming(mut cloud: PointCloud, path: &Path) -> PointCloud {
    name_warnings(&mut cloud.warnings, path);
    cloud
}

/// Parses the contents of a PLY file as [`read_ply`] does; `path` only names the file in errors.
/// Useful when the bytes come from somewhere other than a file.
///
/// # Errors
/// [`Error::Parse`] naming `path` and the line or byte offset of the first problem.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<PointCloud, Error> {
    parse_with(bytes, bytes.len() as u64, path, parse_at).map(|cloud| naming(cloud, path))
}

// Value slots of a vertex after the shared ones (`X`, `NX`, `RED`): the radius, then per
// colour channel its value as the file has it and whether that was out of its type's range.
const RADIUS: usize = 9;
const RAW_RED: usize = 10;
const OUT_RED: usize = 13;
const SLOTS: usize = 16;

fn slot(name: &str) -> Option<usize> {
    if let Some(k) = POSITION_NORMAL.iter().position(|n| *n == name) {
        Some(X + k)
    } else if name == "radius" {
        Some(RADIUS)
    } else {
        Some(RED + COLOR_NAMES[..3].iter().position(|names| names.contains(&name))?)
    }
}

/// What we keep of one element: the values we use, by slot (colours on a 0..255 scale).
#[derive(Default)]
struct Point {
    values: [f32; SLOTS],
}

/// One element as the crate delivers it (the unit tests parse headers with it).
#[cfg(test)]
type Values = Row<Point>;

impl Fields for Point {
    fn set(&mut self, name: &str, property: Property) -> bool {
        let Some(k) = slot(name) else { return false };
        if (RED..RED + 3).contains(&k) {
            let Some((scaled, raw, outside)) = channel(&property) else { return false };
            let c = k - RED;
            self.values[k] = scaled;
            (self.values[RAW_RED + c], self.values[OUT_RED + c]) = (raw, f32::from(outside));
            return true;
        }
        scalar(&property).map(|v| self.values[k] = v).is_some()
    }
}

/// A colour channel on a 0..255 scale: `uchar` as it is, `ushort` / 257, floats * 255 (from
/// 0..1), other integers clamped (NaN as 0); with the value as the file has it, and whether
/// that lies outside its type's range (0..1 for floats, 0..255 for integers other than
/// `ushort`), which the clamp hides.
#[allow(clippy::cast_possible_truncation)]
fn channel(p: &Property) -> Option<(f32, f32, bool)> {
    let raw = scalar(p)?;
    let (v, range) = match *p {
        Property::UShort(v) => (f32::from(v) / 257.0, 0.0..=65535.0),
        Property::Float(v) => (v.clamp(0.0, 1.0) * 255.0, 0.0..=1.0),
        Property::Double(v) => ((v.clamp(0.0, 1.0) * 255.0) as f32, 0.0..=1.0),
        _ => (raw, 0.0..=255.0),
    };
    let scaled = if v.is_nan() { 0.0 } else { v.clamp(0.0, 255.0) };
    Some((scaled, raw, !range.contains(&raw)))
}

/// Which of our attributes the `vertex` element has.
#[derive(Clone, Copy, Default)]
struct Layout {
    normals: bool,
    colors: bool,
    radii: bool,
}

fn parse_at<R: Read>(source: &mut Source<R>, len: u64) -> Result<PointCloud, Fail> {
    let ply = Ply::<Point>::read_header(source, len, |element, property, first| {
        format!("element `{element}` has two properties `{property}` (first at line {first})")
    })?;
    let layout = check_header(&ply)?;
    // A mesh's faces say nothing about its surface's points: said, since the picture (splats
    // at the vertices only) would otherwise be taken for the mesh's.
    let faces = ply.header.elements.get("face").map_or(0, |face| face.count);
    let unused_faces = (faces > 0).then(|| {
        format!(
            "line {}: {} not used: a point cloud is the file's vertices (`trirast sample` \
             spreads points over a mesh's surface)",
            ply.element_line("face"),
            if faces == 1 { "its face is".to_string() } else { format!("its {faces} faces are") },
        )
    });
    let colours_outside = (0, f32::INFINITY, f32::NEG_INFINITY);
    let mut body = Body { layout, colours_outside, ..Body::default() };
    let tail = ply.read_body(source, &mut body)?;
    let mut cloud = body.into_cloud();
    cloud.warnings.extend(unused_faces);
    cloud.warnings.extend(tail);
    Ok(cloud)
}

/// Checks the `vertex` element: present, `x y z` there, the properties we read scalars.
fn check_header(ply: &Ply<Point>) -> Result<Layout, Fail> {
    let vertex = ply.vertex(
        "the header declares no `vertex` element: a point cloud needs one with `x y z`",
        |name| slot(name).is_some(),
        |name| ply.property_line("vertex", name),
    )?;
    let has = |name: &str| vertex.properties.get(name).is_some();
    Ok(Layout {
        normals: ["nx", "ny", "nz"].iter().all(|n| has(n)),
        colors: COLOR_NAMES[..3].iter().all(|names| names.iter().any(|n| has(n))),
        radii: has("radius"),
    })
}

/// Accumulates the vertices while the body is read.
#[derive(Default)]
struct Body {
    layout: Layout,
    /// Whether the element being read is `vertex` (the others are read past).
    vertex: bool,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[u8; 3]>,
    radii: Vec<f32>,
    /// Points with a colour channel outside its type's range, and the smallest and largest
    /// such values as the file has them.
    colours_outside: (usize, f32, f32),
    /// Vertices left out for a non-finite position, and the first of them (index, where).
    not_finite: (usize, Option<(usize, At)>),
}

impl Sink for Body {
    type Fields = Point;
    const LAST: Option<&'static str> = Some("vertex");
    const STRIP_CR: bool = true;

    fn start(&mut self, def: &ElementDef, capacity: usize) {
        self.vertex = def.name == "vertex";
        if !self.vertex {
            return;
        }
        self.positions.reserve(capacity);
        if self.layout.normals {
            self.normals.reserve(capacity);
        }
        if self.layout.colors {
            self.colors.reserve(capacity);
        }
        if self.layout.radii {
            self.radii.reserve(capacity);
        }
    }

    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
    fn add(&mut self, e: Point, index: usize, at: At) -> Result<(), Fail> {
        if !self.vertex {
            return Ok(());
        }
        let v = &e.values;
        let p = [v[X], v[X + 1], v[X + 2]];
        if !p.iter().all(|c| c.is_finite()) {
            let (count, first) = &mut self.not_finite;
            *count += 1;
            first.get_or_insert((index, at));
            return Ok(());
        }
        if self.layout.radii {
            let r = v[RADIUS];
            if !(r.is_finite() && r >= 0.0) {
                return Err((
                    at,
                    format!("vertex {index}: radius {r} is not a finite number >= 0"),
                ));
            }
            self.radii.push(r);
        }
        self.positions.push(p);
        if self.layout.normals {
            self.normals.push(unit_or_zero([v[NX], v[NX + 1], v[NX + 2]]));
        }
        if self.layout.colors {
            self.colors.push([v[RED], v[RED + 1], v[RED + 2]].map(|c| c.round() as u8));
            let outside = (0..3).filter(|&c| v[OUT_RED + c] != 0.0).map(|c| v[RAW_RED + c]);
            let (count, low, high) = &mut self.colours_outside;
            let before = *count;
            for raw in outside {
                (*low, *high) = (low.min(raw), high.max(raw));
                *count = before + 1;
            }
        }
        Ok(())
    }
}

impl Body {
    fn into_cloud(self) -> PointCloud {
        let (outside, low, high) = self.colours_outside;
        let warnings = (outside > 0).then(|| {
            let what = if outside == 1 { "point has" } else { "points have" };
            // The extremes, where not NaN (NaN has none).
            let range = match (low.is_finite(), high.is_finite()) {
                (true, true) if low < high => format!(" (from {low} to {high})"),
                (true, _) => format!(" ({low})"),
                _ => String::new(),
            };
            format!(
                "{outside} {what} colour channels outside their type's range{range}: 0 to 1 \
                 for float colours, 0 to 255 for integer ones; they are clamped to it"
            )
        });
        let skipped = match self.not_finite {
            (count, Some((index, at))) => {
                let what = if count == 1 { "point was" } else { "points were" };
                Some(format!(
                    "{count} {what} left out for a position that is not finite (the first: \
                     vertex {index}, {})",
                    at_text(at)
                ))
            }
            _ => None,
        };
        PointCloud {
            positions: self.positions,
            normals: self.layout.normals.then_some(self.normals),
            colors: self.layout.colors.then_some(self.colors),
            radii: self.layout.radii.then_some(self.radii),
            warnings: skipped.into_iter().chain(warnings).collect(),
        }
    }
}

/// Where a vertex is, for a warning: its line, or its byte offset in a binary file.
fn at_text(at: At) -> String {
    match at {
        At::Line(line) => format!("line {line}"),
        At::Byte(offset) => format!("byte {offset}"),
    }
}

/// `n` scaled to unit length; zero for a zero or non-finite `n` (an unknown normal). A normal
/// already unit to `f32` precision is returned unchanged, so that normalising is idempotent
/// and written clouds read back bit for bit.
#[allow(clippy::cast_possible_truncation)]
fn unit_or_zero(n: [f32; 3]) -> [f32; 3] {
    if !n.iter().all(|c| c.is_finite()) {
        return [0.0; 3];
    }
    // In f64 so that tiny (or huge) components neither underflow nor overflow when squared.
    let d = DVec3::from(n.map(f64::from));
    let len2 = d.length_squared();
    if len2 == 0.0 || (len2 - 1.0).abs() <= 1e-6 {
        return n;
    }
    (d / len2.sqrt()).to_array().map(|c| c as f32)
}

// ------------------------------------------------------------------------------------------
// Writing
// ------------------------------------------------------------------------------------------

/// Writes `cloud` as a binary little-endian PLY: `float x y z`, then, when the cloud has them,
/// `float nx ny nz`, `uchar red green blue` and `float radius`. Binary because clouds are
/// large and because it keeps every `f32` bit for bit: [`read_ply`] gives back exactly `cloud`
/// (normals are assumed unit, as [`PointCloud`] promises; others would be normalised on read).
///
/// # Errors
/// [`Error::Io`] when the file cannot be written, or (kind `InvalidInput`) when an attribute
/// array's length differs from the number of positions, a position is not finite or a radius
/// is not a finite number >= 0, which would give a file [`read_ply`] refuses.
pub fn write_ply(path: &Path, cloud: &PointCloud) -> Result<(), Error> {
    cloud.check().map_err(|message| {
        Error::io(path, std::io::Error::new(std::io::ErrorKind::InvalidInput, message))
    })?;
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut out = BufWriter::new(file);
    write_body(&mut out, cloud)
        .and_then(|()| out.into_inner().map(drop).map_err(std::io::IntoInnerError::into_error))
        .map_err(|e| Error::io(path, e))
}

fn write_body(out: &mut impl Write, cloud: &PointCloud) -> std::io::Result<()> {
    let mut header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment trirast point cloud\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n",
        cloud.len()
    );
    if cloud.normals.is_some() {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    if cloud.colors.is_some() {
        header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    if cloud.radii.is_some() {
        header.push_str("property float radius\n");
    }
    header.push_str("end_header\n");
    out.write_all(header.as_bytes())?;
    let mut record = Vec::with_capacity(31);
    for (i, p) in cloud.positions.iter().enumerate() {
        record.clear();
        record.extend(p.iter().flat_map(|c| c.to_le_bytes()));
        if let Some(n) = &cloud.normals {
            record.extend(n[i].iter().flat_map(|c| c.to_le_bytes()));
        }
        if let Some(c) = &cloud.colors {
            record.extend_from_slice(&c[i]);
        }
        if let Some(r) = &cloud.radii {
            record.extend_from_slice(&r[i].to_le_bytes());
        }
        out.write_all(&record)?;
    }
    out.flush()
}

// ------------------------------------------------------------------------------------------
// Sampling
// ------------------------------------------------------------------------------------------

/// Points per chunk of [`sample_mesh`]: each chunk has its own random stream, seeded from the
/// seed and the chunk's index, so the result does not depend on how many threads run.
const CHUNK: usize = 4096;

/// Colour of points on surfaces with neither texture, vertex colours nor material (the same
/// grey the splat tree gives uncoloured points).
const DEFAULT_COLOR: [u8; 3] = [200, 200, 200];

/// Samples `n` points uniformly by area over the surface of `mesh`, with normals, colours and
/// radii, deterministically for a given `seed`.
///
/// - **Positions**: a triangle is chosen with probability proportional to its area (binary
///   search in a cumulative-area table, so the cost is O(log triangles) per point), then a point
///   uniform within it from barycentrics `(1 - sqrt(r1), sqrt(r1) (1 - r2), sqrt(r1) r2)`; the
///   square root undoes the crowding towards the first vertex that uniform `r1` would give.
///   Degenerate triangles (zero or non-finite area) and triangles with out-of-range indices
///   have probability zero.
/// - **Normals**: the mesh's vertex normals interpolated and normalised; a mesh without
///   normals gets the smooth area-weighted ones the renderer computes
///   ([`crate::model::vertex_normals`]); where they cancel out, the face normal
///   `(b - a) x (c - a)`, normalised, which faces the side from which the triangle winds
///   counter-clockwise.
/// - **Colours**: the texture of the triangle's material at the interpolated texture
///   coordinate (bilinear, repeat: what the renderer shows by default); else the vertex
///   colours, interpolated in linear light as the renderer does; else the material's diffuse
///   colour; else light grey `[200, 200, 200]`.
/// - **Radii**: all `sqrt(A / (pi n)) * 3` for total area `A`. Disks of radius
///   `sqrt(A / (pi n))` have, together, exactly the area of the surface, which would close it
///   only if they tiled it perfectly; random points cluster and leave gaps, and the uncovered
///   fraction of a surface under `n` random disks of `k` times that radius is about
///   `exp(-k^2)`. `k = 3` leaves about 0.01% in gaps (`k = 1.5` left a tenth of the surface,
///   `k = 2.5` still 0.2%: dozens of pin-holes in a 1080p render), at the price of splats that
///   overlap more.
///
/// `n = 0` or a mesh of zero total area gives an empty cloud (with empty normals, colours and
/// radii). Memory is proportional to `n`. Work is split into fixed chunks of points, each with
/// its own `SmallRng` stream seeded from `(seed, chunk index)`, and run on rayon's threads:
/// the same seed gives the same cloud whatever the number of threads (for a given version of
/// `rand`, whose `SmallRng` algorithm is not promised to stay the same).
///
/// Errors: [`Error::OutOfMemory`] when the `n` points' arrays cannot be allocated;
/// [`Error::SampleRadius`] when the radius is beyond `f32` (a surface of coordinates near
/// `f32::MAX` and few points), before any point is sampled.
pub fn sample_mesh(
    mesh: &Mesh,
    textures: &MaterialTextures,
    n: usize,
    seed: u64,
) -> Result<PointCloud, Error> {
    sample(mesh, &|k| textures.get(k), n, seed)
}

/// [`sample_mesh`] with the diffuse textures given directly: `textures[k]` is the texture of
/// material `k` (`None`, or a short slice, for materials without one). For textures built in
/// code.
pub fn sample_mesh_with_textures(
    mesh: &Mesh,
    textures: &[Option<Texture>],
    n: usize,
    seed: u64,
) -> Result<PointCloud, Error> {
    sample(mesh, &|k| textures.get(k).and_then(Option::as_ref), n, seed)
}

type TextureOf<'a> = dyn Fn(usize) -> Option<&'a Texture> + Sync + 'a;

#[allow(clippy::cast_possible_truncation, clippy::cast_precision_loss, clippy::cast_sign_loss)]
fn sample(
    mesh: &Mesh,
    texture_of: &TextureOf<'_>,
    n: usize,
    seed: u64,
) -> Result<PointCloud, Error> {
    // Without normals in the file, the smooth (area-weighted, welded) vertex normals the mesh
    // renderer shades with: face normals of scanned meshes include flipped slivers, whose
    // points the splat renderer's back-face culling would then drop, leaving holes.
    let smooth = mesh
        .normals
        .is_none()
        .then(|| crate::model::vertex_normals(&mesh.positions, &mesh.triangles));
    let mut sampler = Sampler::new(mesh, texture_of);
    if let Some(normals) = &smooth {
        sampler.normals = Some(normals);
    }
    let total = sampler.cumulative.last().copied().unwrap_or(0.0);
    if n == 0 || !(total > 0.0 && total.is_finite()) {
        return Ok(PointCloud {
            positions: Vec::new(),
            normals: Some(Vec::new()),
            colors: Some(Vec::new()),
            radii: Some(Vec::new()),
            warnings: Vec::new(),
        });
    }
    // The area and radius are in f64, which holds the area of any triangle of finite f32
    // corners; the radius may not fit f32 (3 points on a triangle of corners 3e38 had written
    // a radius of inf, which reading the cloud refuses).
    let radius_of = |n: f64| (total / (std::f64::consts::PI * n)).sqrt() * 3.0;
    let radius = radius_of(n as f64) as f32;
    if radius.is_infinite() {
        // 3 sqrt(A / (pi n)) <= f32::MAX from n = 9 A / (pi f32::MAX^2) on; then up past any
        // rounding of the cast.
        let max = f64::from(f32::MAX);
        let mut fewest = (9.0 * total / (std::f64::consts::PI * max * max)).ceil() as u64;
        while (radius_of(fewest as f64) as f32).is_infinite() {
            fewest += 1;
        }
        return Err(Error::SampleRadius {
            points: n,
            area: total,
            radius: radius_of(n as f64),
            fewest,
        });
    }
    // The error names the bytes of all four arrays, whichever could not be had.
    let what = format!("{n} sampled points");
    let all = |e: Error| match e {
        Error::OutOfMemory { what, .. } => Error::OutOfMemory { what, bytes: n as u128 * 31 },
        e => e,
    };
    let mut positions = try_filled(n, [0.0f32; 3], &what).map_err(all)?;
    let mut normals = try_filled(n, [0.0f32; 3], &what).map_err(all)?;
    let mut colors = try_filled(n, [0u8; 3], &what).map_err(all)?;
    positions
        .par_chunks_mut(CHUNK)
        .zip(normals.par_chunks_mut(CHUNK))
        .zip(colors.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(chunk, ((p, nn), c))| {
            let mut rng = SmallRng::seed_from_u64(chunk_seed(seed, chunk as u64));
            for ((p, nn), c) in p.iter_mut().zip(nn).zip(c) {
                (*p, *nn, *c) = sampler.point(&mut rng, total);
            }
        });
    Ok(PointCloud {
        positions,
        normals: Some(normals),
        colors: Some(colors),
        radii: Some(try_filled(n, radius, &what).map_err(all)?),
        warnings: Vec::new(),
    })
}

/// The seed of chunk `chunk`'s random stream: SplitMix64 mixing, so that neighbouring seeds and
/// chunks give unrelated streams.
fn chunk_seed(seed: u64, chunk: u64) -> u64 {
    fn mix(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    mix(seed ^ mix(chunk))
}

/// A mesh prepared for sampling: the triangles that can be hit and their cumulative areas,
/// and the per-vertex attributes that are usable (as long as the positions).
struct Sampler<'a, 't> {
    mesh: &'a Mesh,
    texture_of: &'a TextureOf<'t>,
    /// Indices into `mesh.triangles` of the triangles with positive area.
    triangles: Vec<usize>,
    /// `cumulative[k]`: total area of `triangles[..=k]`.
    cumulative: Vec<f64>,
    normals: Option<&'a [[f32; 3]]>,
    texcoords: Option<&'a [[f32; 2]]>,
    /// Vertex colours in linear light.
    colors: Option<Vec<DVec3>>,
}

impl<'a, 't> Sampler<'a, 't> {
    fn new(mesh: &'a Mesh, texture_of: &'a TextureOf<'t>) -> Self {
        let vertices = mesh.positions.len();
        let mut triangles = Vec::new();
        let mut cumulative = Vec::new();
        let mut total = 0.0f64;
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let Some([a, b, c]) = corners(mesh, *tri) else { continue };
            let area = 0.5 * (b - a).cross(c - a).length();
            if area > 0.0 && area.is_finite() {
                total += area;
                triangles.push(t);
                cumulative.push(total);
            }
        }
        let usable = |len: usize| len == vertices;
        Self {
            mesh,
            texture_of,
            triangles,
            cumulative,
            normals: mesh.normals.as_deref().filter(|v| usable(v.len())),
            texcoords: mesh.texcoords.as_deref().filter(|v| usable(v.len())),
            colors: mesh.colors.as_ref().filter(|v| usable(v.len())).map(|c| {
                c.iter()
                    .map(|&[r, g, b, _]| {
                        DVec3::new(
                            f64::from(srgb_decode(r.clamp(0.0, 1.0))),
                            f64::from(srgb_decode(g.clamp(0.0, 1.0))),
                            f64::from(srgb_decode(b.clamp(0.0, 1.0))),
                        )
                    })
                    .collect()
            }),
        }
    }

    /// One point: position, unit normal, colour. `total` is the last cumulative area.
    #[allow(clippy::cast_possible_truncation)]
    fn point(&self, rng: &mut SmallRng, total: f64) -> ([f32; 3], [f32; 3], [u8; 3]) {
        let r = rng.random::<f64>() * total;
        // The first triangle whose cumulative area exceeds r; zero-area triangles are not in
        // the table, and rounding at the very end falls back on the last (positive) one.
        let k = self.cumulative.partition_point(|&c| c <= r).min(self.cumulative.len() - 1);
        let t = self.triangles[k];
        let tri = self.mesh.triangles[t];
        let (r1, r2) = (rng.random::<f64>(), rng.random::<f64>());
        let s = r1.sqrt();
        let w = [1.0 - s, s * (1.0 - r2), s * r2];
        let [a, b, c] = corners(self.mesh, tri).unwrap_or([DVec3::ZERO; 3]);
        let p = a * w[0] + b * w[1] + c * w[2];
        let face = (b - a).cross(c - a).normalize_or_zero();
        let normal = self
            .normals
            .map(|n| lerp3(tri.map(|i| DVec3::from(n[i as usize].map(f64::from))), w))
            .map(DVec3::normalize_or_zero)
            .filter(|n| *n != DVec3::ZERO)
            .unwrap_or(face);
        let to_f32 = |v: DVec3| v.to_array().map(|c| c as f32);
        (to_f32(p), to_f32(normal), self.color(t, tri, w))
    }

    /// The colour at barycentrics `w` of triangle `t` (see [`sample_mesh`] for the order).
    #[allow(clippy::cast_possible_truncation)]
    fn color(&self, t: usize, tri: [u32; 3], w: [f64; 3]) -> [u8; 3] {
        let mesh = self.mesh;
        let material = mesh.triangle_materials.as_ref().and_then(|m| m.get(t)).map(|&k| k as usize);
        if let (Some(texture), Some(uvs)) = (material.and_then(self.texture_of), self.texcoords) {
            let uv = tri.map(|i| DVec2::from(uvs[i as usize].map(f64::from)));
            let uv = uv[0] * w[0] + uv[1] * w[1] + uv[2] * w[2];
            let c =
                texture.sample(Vec2::new(uv.x as f32, uv.y as f32), Filter::Bilinear, Wrap::Repeat);
            return [c.x, c.y, c.z].map(linear_to_srgb8);
        }
        if let Some(colors) = &self.colors {
            let c = lerp3(tri.map(|i| colors[i as usize]), w);
            return c.to_array().map(|c| linear_to_srgb8(c as f32));
        }
        match material.and_then(|k| mesh.materials.get(k)) {
            Some(m) => m.diffuse.map(unorm8),
            None => DEFAULT_COLOR,
        }
    }
}

/// The corners of a triangle in f64, or `None` when an index is out of range.
fn corners(mesh: &Mesh, tri: [u32; 3]) -> Option<[DVec3; 3]> {
    let p = |i: u32| mesh.positions.get(i as usize).map(|p| DVec3::from(p.map(f64::from)));
    Some([p(tri[0])?, p(tri[1])?, p(tri[2])?])
}

fn lerp3(v: [DVec3; 3], w: [f64; 3]) -> DVec3 {
    v[0] * w[0] + v[1] * w[1] + v[2] * w[2]
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use super::*;

    /// Non-finite values written as words in an ASCII file (PCL writes `nan` normals) read as
    /// the same values do from a binary one; where a binary file's would be an error (a
    /// position) or cannot be (an integer property), the ASCII line is one too.
    #[test]
    fn ascii_non_finite_words_read_as_binary_values() {
        let header = |format: &str, count: usize| {
            format!(
                "ply\nformat {format} 1.0\nelement vertex {count}\nproperty float x\n\
                 property float y\nproperty float z\nproperty double nx\nproperty float ny\n\
                 property float nz\nproperty uchar red\nproperty uchar green\n\
                 property uchar blue\nend_header\n"
            )
        };
        let rows: [([f32; 3], [f64; 3], &str); 4] = [
            // A word left as the zero it is parsed as would give a unit normal.
            ([1.0, 2.0, 3.0], [f64::NAN, 0.0, 1.0], "1 2 3\tnan 0  1 1 2 3"),
            ([1.0, 2.0, 3.0], [f64::NAN, f64::NAN, f64::NAN], "1 2 3 nan NaN NAN 4 5 6"),
            (
                [0.5, 0.0, -1.0],
                [f64::INFINITY, 0.0, f64::NEG_INFINITY],
                "0.5 0 -1 inf 0 -Infinity 7 8 9",
            ),
            ([0.0, 1e-3, 2.0], [0.0, 3.0, 4.0], "0 1e-3 2 0 3 4 10 11 12"),
        ];
        let mut ascii = header("ascii", rows.len());
        let mut binary = header("binary_little_endian", rows.len()).into_bytes();
        for (k, (p, n, line)) in rows.iter().enumerate() {
            ascii += line;
            ascii += "\n";
            p.iter().for_each(|v| binary.extend(v.to_le_bytes()));
            binary.extend(n[0].to_le_bytes());
            binary.extend((n[1] as f32).to_le_bytes());
            binary.extend((n[2] as f32).to_le_bytes());
            binary.extend([3 * k as u8 + 1, 3 * k as u8 + 2, 3 * k as u8 + 3]);
        }
        let path = Path::new("c.ply");
        let from_ascii = parse_ply(ascii.as_bytes(), path).unwrap();
        assert_eq!(from_ascii, parse_ply(&binary, path).unwrap());
        assert_eq!(from_ascii.normals.as_ref().unwrap()[..3], [[0.0; 3]; 3], "unknown normals");
        // A `nan` position is read as a binary file's NaN: the point is left out.
        let text = header("ascii", 1) + "nan 2 3 0 0 1 1 2 3\n";
        let cloud = parse_ply(text.as_bytes(), path).unwrap();
        assert!(cloud.is_empty() && cloud.warnings[0].contains("(the first: vertex 0, line 14)"));
        for bad in ["1 2 3 0 0 1 nan 2 3", "1 2 3 0 0 1 1 2 3 nan"] {
            let text = header("ascii", 1) + bad + "\n";
            let e = parse_ply(text.as_bytes(), path).unwrap_err().to_string();
            assert!(e.starts_with("c.ply:14:"), "{bad}: {e}");
        }
    }

    /// Points after the declared ones are named in a warning, as a mesh's are; elements after
    /// the vertices (faces, which a cloud does not read) are not data left over.
    #[test]
    fn points_after_the_declared_ones_are_warned_of() {
        let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
                    property float y\nproperty float z\n";
        let points = "0 0 0\n1 0 0\n";
        let read = |src: String| parse_ply(src.as_bytes(), Path::new("c.ply")).unwrap();
        let cloud = read(format!("{head}end_header\n{points}2 0 0\n"));
        assert_eq!(cloud.len(), 2);
        let want = "c.ply: 6 bytes after the elements the header declares (2 `vertex`) are \
                    ignored; the header's counts may be too small";
        assert_eq!(cloud.warnings, [want]);
        let faces = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let cloud = read(format!("{head}{faces}{points}3 0 1 0\n"));
        // The faces are read past without a word about trailing bytes, but said unused.
        assert_eq!(cloud.len(), 2);
        let want = "c.ply: line 7: its face is not used: a point cloud is the file's vertices \
                    (`trirast sample` spreads points over a mesh's surface)";
        assert_eq!(cloud.warnings, [want]);
        let faces = "element face 0\nproperty list uchar int vertex_indices\nend_header\n";
        assert!(read(format!("{head}{faces}{points}")).warnings.is_empty());
    }

    #[test]
    fn normalising_is_idempotent() {
        let mut rng = SmallRng::seed_from_u64(1);
        for _ in 0..100_000 {
            let v: [f32; 3] = std::array::from_fn(|_| rng.random_range(-10.0..10.0));
            let n = unit_or_zero(v);
            assert_eq!(unit_or_zero(n).map(f32::to_bits), n.map(f32::to_bits), "{v:?}");
            let len = n.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt();
            assert!((len - 1.0).abs() < 1e-6, "{v:?} -> {n:?}");
        }
        assert_eq!(unit_or_zero([1e-30, 0.0, 1e-30])[0], std::f32::consts::FRAC_1_SQRT_2);
        assert_eq!(unit_or_zero([3e38, 3e38, 0.0])[1], std::f32::consts::FRAC_1_SQRT_2);
        assert_eq!(unit_or_zero([0.0, f32::NAN, 1.0]), [0.0; 3]);
    }

    #[test]
    fn chunk_seeds_differ() {
        let mut seen = HashSet::new();
        for seed in 0..64 {
            for chunk in 0..64 {
                assert!(seen.insert(chunk_seed(seed, chunk)));
            }
        }
    }

    #[test]
    fn reservations_are_capped_by_the_file_size() {
        let src = b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n\
                    property double x\nproperty double y\nproperty double z\nend_header\n";
        let parser = Parser::<Values>::new();
        let mut reader = Reader::new(Cursor::new(&src[..]));
        let header = parser.read_header(&mut reader).unwrap();
        let def = header.elements.get("vertex").unwrap();
        assert_eq!(capacity(def, Encoding::BinaryLittleEndian, 240), 11);
        assert_eq!(capacity(def, Encoding::Ascii, 240), 41);
    }
}
