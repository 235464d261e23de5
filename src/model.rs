//! Rendering a [`Mesh`] with built-in shaders: unlit, flat, Gouraud and Phong lighting, vertex
//! colours, materials and textures. This is what `trirast render MODEL` runs; it is written
//! against the public [`crate::pipeline`] API like any user program.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

use crate::camera::Camera;
use crate::color::srgb_decode;
use crate::error::Error;
use crate::mesh::Mesh;
use crate::pipeline::{FaceCull, Fragment, FragmentShader, InterpolatedColor, Pipeline};
use crate::render::DrawStats;
use crate::shade::DepthTest;
use crate::simd::{self, SimdLevel};
use crate::target::Target;
use crate::texture::{Filter, Texture, Wrap};

/// Lighting models.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Lighting {
    /// Surface colour only (vertex colours, material, texture): no light.
    Unlit,
    /// One normal per face.
    Flat,
    /// Lighting evaluated per vertex and interpolated.
    Gouraud,
    /// Normals interpolated, lighting evaluated per pixel.
    #[default]
    Phong,
}

/// One directional light plus ambient, in view space (so it moves with the camera).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Direction towards the light, view space (normalised on use).
    pub direction: Vec3,
    /// Diffuse intensity.
    pub diffuse: f32,
    /// Ambient intensity.
    pub ambient: f32,
    /// Specular intensity (Blinn-Phong) for Gouraud and Phong.
    pub specular: f32,
    /// Specular exponent. Whole exponents from 0 to 1024 are computed by repeated
    /// multiplication (`powi`, within 1e-4 of `powf` relative), others by `powf`.
    pub shininess: f32,
}

impl Default for Light {
    /// A head light from slightly above and to the left of the camera.
    fn default() -> Self {
        Self {
            direction: Vec3::new(-0.35, 0.45, 1.0),
            diffuse: 0.85,
            ambient: 0.15,
            specular: 0.2,
            shininess: 32.0,
        }
    }
}

impl Light {
    /// Light reflected towards the viewer from a surface with normal `n` (view space, unit)
    /// seen along `view` (unit, from the surface to the eye): `(diffuse + ambient, specular)`.
    #[must_use]
    pub fn shade(&self, n: Vec3, view: Vec3) -> (f32, f32) {
        self.shade_towards(self.unit_direction(), n, view)
    }

    /// The direction towards the light, normalised (`+z` when it is zero or not finite).
    #[must_use]
    pub fn unit_direction(&self) -> Vec3 {
        self.direction.normalize_or(Vec3::Z)
    }

    /// [`Light::shade`] towards the unit direction `l` instead of [`Light::direction`]: with
    /// `l = self.unit_direction()`, computed once by the caller rather than once per vertex or
    /// fragment, the same result as `shade`, bit for bit.
    #[inline]
    #[must_use]
    pub fn shade_towards(&self, l: Vec3, n: Vec3, view: Vec3) -> (f32, f32) {
        let diffuse = self.ambient + self.diffuse * n.dot(l).max(0.0);
        let h = (l + view).normalize_or(Vec3::Z);
        let spec =
            if n.dot(l) > 0.0 { self.specular * self.highlight(n.dot(h).max(0.0)) } else { 0.0 };
        (diffuse, spec)
    }

    /// `c` to the power [`Light::shininess`]: by repeated multiplication for whole exponents
    /// up to 1024 (the usual ones, the default 32 among them), cheaper than `powf` and within
    /// 1e-4 of it relative, far below a step of an 8-bit colour. `powi`'s rounding is not
    /// specified across platforms, but one build computes it one way, so both backends agree.
    #[inline]
    fn highlight(&self, c: f32) -> f32 {
        match self.whole_exponent() {
            Some(k) => c.powi(k as i32),
            None => c.powf(self.shininess),
        }
    }

    /// [`Light::shininess`] when it is whole and from 0 to 1024: the exponents raised by
    /// repeated multiplication.
    #[inline]
    fn whole_exponent(&self) -> Option<u32> {
        let k = self.shininess;
        (k.fract() == 0.0 && (0.0..=1024.0).contains(&k)).then_some(k as u32)
    }

    /// The light towards unit direction `l` as [`simd::gouraud_eight`] takes it, when its
    /// exponent is whole (what [`Light::highlight`] raises by `powi`).
    fn whole(&self, l: Vec3) -> Option<simd::WholeLight> {
        self.whole_exponent().map(|exponent| simd::WholeLight {
            l: l.to_array(),
            ambient: self.ambient,
            diffuse: self.diffuse,
            specular: self.specular,
            exponent,
        })
    }

    /// [`Light::highlight`] of each lane, bit for bit: `powi` (a call per value) written out
    /// as it computes, the odd bits of the exponent from the lowest, each factor the previous
    /// one squared, multiplied into a running product that starts at 1 (held to it by
    /// `gouraud_lanes_light_as_one_vertex_at_a_time`).
    fn highlights<const N: usize>(&self, c: [f32; N]) -> [f32; N] {
        let Some(k) = self.whole_exponent() else {
            return c.map(|c| c.powf(self.shininess));
        };
        let (mut bits, mut factor, mut product) = (k, c, [1.0f32; N]);
        loop {
            if bits & 1 == 1 {
                product = std::array::from_fn(|j| product[j] * factor[j]);
            }
            bits >>= 1;
            if bits == 0 {
                return product;
            }
            factor = factor.map(|f| f * f);
        }
    }
}

/// How to render a mesh. `ModelOptions::default()` gives Phong lighting with the head light,
/// back faces culled, bilinear repeat textures.
#[derive(Clone, Debug, Default, PartialEq)]
#[non_exhaustive]
pub struct ModelOptions {
    /// Lighting model.
    pub lighting: Lighting,
    /// The light.
    pub light: Light,
    /// Faces to discard.
    pub cull: FaceCull,
    /// Depth comparison.
    pub depth_test: DepthTest,
    /// Texture filtering.
    pub filter: Filter,
    /// Texture wrapping.
    pub wrap: Wrap,
}

impl ModelOptions {
    /// Sets the lighting model.
    #[must_use]
    pub fn with_lighting(mut self, lighting: Lighting) -> Self {
        self.lighting = lighting;
        self
    }

    /// Sets the faces to discard.
    #[must_use]
    pub fn with_cull(mut self, cull: FaceCull) -> Self {
        self.cull = cull;
        self
    }
}

/// Textures of a mesh's materials, loaded once; a texture that cannot be read becomes a warning
/// and the material's plain colour.
#[derive(Clone, Debug, Default)]
pub struct MaterialTextures {
    /// Materials naming the same file share its one decoded copy (a file's materials often
    /// share one atlas: five materials of one 8192 x 8192 texture had taken 5.5 GB).
    textures: Vec<Option<Arc<Texture>>>,
    /// Problems met while loading.
    pub warnings: Vec<String>,
}

impl MaterialTextures {
    /// The loaded texture of material `material`, if it has one that could be read.
    #[must_use]
    pub fn get(&self, material: usize) -> Option<&Texture> {
        self.textures.get(material).and_then(Option::as_deref)
    }

    /// Textures already loaded: `textures[k]` is material `k`'s (`None`: none). For a texture
    /// whose loading error the caller reports itself, rather than as a warning.
    #[must_use]
    pub fn from_loaded(textures: Vec<Option<Texture>>) -> Self {
        Self {
            textures: textures.into_iter().map(|t| t.map(Arc::new)).collect(),
            warnings: Vec::new(),
        }
    }

    /// Loads the diffuse textures of `mesh`'s materials, each file once.
    #[must_use]
    pub fn load(mesh: &Mesh) -> Self {
        let mut warnings = Vec::new();
        let mut loaded: HashMap<&Path, Result<Arc<Texture>, String>> = HashMap::new();
        let textures = mesh
            .materials
            .iter()
            .map(|m| {
                let path = m.diffuse_texture.as_deref()?;
                let texture = loaded.entry(path).or_insert_with(|| {
                    Texture::load(path).map(Arc::new).map_err(|e| e.to_string())
                });
                match texture {
                    Ok(t) => Some(Arc::clone(t)),
                    Err(e) => {
                        let at = m
                            .texture_statement
                            .as_ref()
                            .map_or_else(String::new, |(f, l)| format!("{}:{l}: ", f.display()));
                        warnings.push(format!(
                            "{at}the texture of material `{}` cannot be used ({e}); using its \
                             diffuse colour",
                            m.name
                        ));
                        None
                    }
                }
            })
            .collect();
        Self { textures, warnings }
    }
}

/// Area-weighted vertex normals (the sum of the adjacent faces' cross products): large faces
/// count more, and slivers, whose normals are least reliable, count least. Vertices at the
/// same position share one normal, so seams in texture coordinates (which split vertices)
/// do not show as creases. Triangles with out-of-range indices are ignored.
///
/// Positions are matched by their bits with `foldhash` (the standard library's SipHash had
/// taken 60 ms for a mesh of half a million vertices, a tenth of `trirast render` on it).
/// How slots are numbered does not matter: each slot's sum is added up in triangle order.
#[must_use]
pub fn vertex_normals(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut slot_of: HashMap<[u32; 3], u32, foldhash::fast::RandomState> =
        HashMap::with_capacity_and_hasher(positions.len(), Default::default());
    let slots: Vec<u32> = positions
        .iter()
        .map(|p| {
            let next = slot_of.len() as u32;
            *slot_of.entry(p.map(f32::to_bits)).or_insert(next)
        })
        .collect();
    let mut sum = vec![Vec3::ZERO; slot_of.len()];
    for t in triangles {
        // Triangles referring past the vertices contribute nothing (and never panic).
        if t.iter().any(|&i| i as usize >= positions.len()) {
            continue;
        }
        let [a, b, c] = t.map(|i| Vec3::from(positions[i as usize]));
        let n = (b - a).cross(c - a);
        if n.is_finite() {
            for &i in t {
                sum[slots[i as usize] as usize] += n;
            }
        }
    }
    slots.iter().map(|&s| sum[s as usize].normalize_or_zero().to_array()).collect()
}

/// Fills in `mesh.normals` with [`vertex_normals`] when the file had none, so that rendering
/// many frames (turntables, benchmarks) does not recompute them every frame.
pub fn with_vertex_normals(mesh: &mut Mesh) {
    if mesh.normals.is_none() {
        mesh.normals = Some(vertex_normals(&mesh.positions, &mesh.triangles));
    }
}

/// Per-vertex data the model shaders read, resolved once.
struct Surface<'a> {
    mesh: &'a Mesh,
    /// Vertex normals, model space (empty when no shader reads them).
    normals: std::borrow::Cow<'a, [[f32; 3]]>,
    textures: &'a MaterialTextures,
    /// Linear RGBA per vertex (white when the mesh has no colours).
    colors: Option<Vec<Vec4>>,
    /// View-space face normals (flat lighting).
    face_normals: Vec<Vec3>,
}

/// The colour (linear RGBA) [`render_mesh`] starts from where the mesh has no vertex colours:
/// white (materials and textures multiply it), or for a mesh with neither colours nor
/// materials a light clay, not pure white, so that highlights stay visible.
#[must_use]
pub fn base_albedo(mesh: &Mesh) -> Vec4 {
    if mesh.colors.is_none() && mesh.materials.is_empty() {
        Vec4::new(0.62, 0.6, 0.56, 1.0)
    } else {
        Vec4::ONE
    }
}

/// The transforms [`render_mesh`] applies: a vertex `p` goes to view space as
/// `view * (p - origin)` and to clip space as `view_proj * (p - origin)`.
#[derive(Clone, Copy, Debug)]
pub struct ModelView {
    /// The point looked at. Working relative to it keeps a model far from the world origin
    /// (scans in survey coordinates, say) in f32 precision: `p - origin` is exact for
    /// nearby values.
    pub origin: Vec3,
    /// World (relative to `origin`) to view space.
    pub view: Mat4,
    /// World (relative to `origin`) to clip space.
    pub view_proj: Mat4,
}

impl ModelView {
    /// The transforms of `camera` on a target of the given aspect ratio (width / height).
    #[must_use]
    pub fn new(camera: &Camera, aspect: f32) -> Self {
        let origin = camera.target;
        let local_camera = Camera { eye: camera.eye - origin, target: Vec3::ZERO, ..*camera };
        let view = local_camera.view();
        Self { origin, view, view_proj: camera.projection(aspect) * view }
    }
}

/// Varyings of the model shaders: view-space normal, texture coordinate, linear colour (for
/// Gouraud: already lit), view-space position.
type ModelVaryings = (Vec3, Vec2, Vec4, Vec3);

struct ModelFragment<'a> {
    surface: &'a Surface<'a>,
    options: &'a ModelOptions,
    view_to_world: Mat3,
    /// The light's unit direction.
    light_direction: Vec3,
    /// The light as [`simd::light_eight`] takes it, where its exponent is whole.
    whole_light: Option<simd::WholeLight>,
    /// The level Phong's lanes are lit at.
    level: SimdLevel,
}

impl ModelFragment<'_> {
    fn albedo(&self, f: &Fragment<ModelVaryings>) -> Vec4 {
        let (_, uv, color, _) = f.varyings;
        self.albedo_at(uv, color, f.primitive)
    }

    /// The surface colour at texture coordinate `uv` with interpolated colour `color`, on
    /// triangle `primitive`. Inlined for meshes without materials (the colour as it is); a
    /// call per fragment to find that out was a twentieth of the bunny's frame.
    #[inline]
    fn albedo_at(&self, uv: Vec2, color: Vec4, primitive: u32) -> Vec4 {
        match &self.surface.mesh.triangle_materials {
            None => color,
            Some(materials) => self.material_albedo(uv, color, materials[primitive as usize]),
        }
    }

    /// What material `material` multiplies a colour by: its texture where the mesh has
    /// coordinates for it, else its diffuse colour; one for an index past the list (the colour
    /// as it is, which a product with one gives bit for bit). The one definition the fragment
    /// shader ([`ModelFragment::material_albedo`]) and the kernels' constant
    /// ([`ColorFragment::interpolated_color`]) share.
    fn material_factor(&self, material: u32) -> MaterialFactor<'_> {
        let mesh = self.surface.mesh;
        let k = material as usize;
        let Some(m) = mesh.materials.get(k) else { return MaterialFactor::Constant(Vec4::ONE) };
        match self.surface.textures.get(k) {
            Some(t) if mesh.texcoords.is_some() => MaterialFactor::Texture(t),
            _ => MaterialFactor::Constant(Vec3::from(m.diffuse.map(srgb_decode)).extend(1.0)),
        }
    }

    /// [`ModelFragment::albedo_at`] on a triangle with material index `material`.
    #[inline(never)]
    fn material_albedo(&self, uv: Vec2, color: Vec4, material: u32) -> Vec4 {
        match self.material_factor(material) {
            MaterialFactor::Texture(t) => {
                color * t.sample(uv, self.options.filter, self.options.wrap)
            }
            MaterialFactor::Constant(c) => color * c,
        }
    }

    /// Phong's colours of `fragments` (at most [`GOURAUD_LANES`]) into `out`, as
    /// [`FragmentShader::shade`] computes each: their normals and directions to the eye lit
    /// side by side ([`simd::light_eight`] where the exponent is whole, else
    /// [`GouraudLanes::shade`], both bit for bit `Light::shade_towards` of the normalised
    /// vectors), the albedo lane by lane. A fragment alone waited on its chain of three
    /// square roots, three divisions and the highlight's powers. A back face's normal is
    /// negated before it is normalised rather than after, which gives the same bits but for
    /// a zero normal's signs of zero: its diffuse term may then differ in the sign of a zero,
    /// which the specular term, `+0` there, takes away in the sum.
    fn phong_lanes(&self, fragments: &[Fragment<ModelVaryings>], out: &mut [Option<Vec4>]) {
        let mut lanes = GouraudLanes::default();
        for (j, f) in fragments.iter().enumerate() {
            let n = if f.front_facing { f.varyings.0 } else { -f.varyings.0 };
            lanes.set(j, n, -f.varyings.3);
        }
        let light = &self.options.light;
        let lit = self
            .whole_light
            .as_ref()
            .and_then(|w| simd::light_eight(self.level, &lanes.n, &lanes.v, w));
        let (d, s) = lit.unwrap_or_else(|| lanes.shade(light, self.light_direction));
        for (j, (f, out)) in fragments.iter().zip(out).enumerate() {
            let albedo = self.albedo(f);
            *out = Some((albedo.truncate() * d[j] + Vec3::splat(s[j])).extend(albedo.w));
        }
    }

    fn normal_at(&self, f: &Fragment<ModelVaryings>) -> Vec3 {
        let n = match self.options.lighting {
            Lighting::Flat => self.surface.face_normals[f.primitive as usize],
            _ => f.varyings.0.normalize_or_zero(),
        };
        // Two-sided: a back face seen through a hole is lit as its visible side.
        if f.front_facing { n } else { -n }
    }
}

impl FragmentShader<ModelVaryings> for ModelFragment<'_> {
    fn shade(&self, f: &Fragment<ModelVaryings>) -> Option<Vec4> {
        let albedo = self.albedo(f);
        let lit = match self.options.lighting {
            Lighting::Unlit | Lighting::Gouraud => albedo,
            Lighting::Flat | Lighting::Phong => {
                let view = (-f.varyings.3).normalize_or(Vec3::Z);
                let (d, s) =
                    self.options.light.shade_towards(self.light_direction, self.normal_at(f), view);
                (albedo.truncate() * d + Vec3::splat(s)).extend(albedo.w)
            }
        };
        Some(lit)
    }

    /// Phong's lanes lit side by side ([`ModelFragment::phong_lanes`]), other lighting one
    /// fragment at a time.
    fn shade_lanes(&self, fragments: &[Fragment<ModelVaryings>], out: &mut [Option<Vec4>]) {
        if self.options.lighting == Lighting::Phong && fragments.len() <= GOURAUD_LANES {
            return self.phong_lanes(fragments, out);
        }
        for (f, out) in fragments.iter().zip(out) {
            *out = self.shade(f);
        }
    }

    fn shades_lanes(&self) -> bool {
        self.options.lighting == Lighting::Phong
    }

    fn normal(&self, f: &Fragment<ModelVaryings>) -> Option<Vec3> {
        Some((self.view_to_world * self.normal_at(f)).normalize_or_zero())
    }

    fn may_discard(&self) -> bool {
        false
    }
}

/// The varyings of the lighting models that read no normal or position per pixel (unlit and
/// Gouraud, without a normal buffer): texture coordinate and (lit) colour. Half of
/// [`ModelVaryings`]: each fragment interpolates 6 values instead of 12, and each triangle's
/// record drops three normals and positions (the Stanford bunny, Gouraud, two threads: about
/// 3% faster).
type SurfaceVaryings = (Vec2, Vec4);

/// [`ModelFragment`] for [`SurfaceVaryings`].
struct SurfaceFragment<'a>(ModelFragment<'a>);

impl FragmentShader<SurfaceVaryings> for SurfaceFragment<'_> {
    fn shade(&self, f: &Fragment<SurfaceVaryings>) -> Option<Vec4> {
        let (uv, color) = f.varyings;
        Some(self.0.albedo_at(uv, color, f.primitive))
    }

    fn may_discard(&self) -> bool {
        false
    }
}

/// [`SurfaceVaryings`] without the texture coordinate, for meshes that have none (the
/// coordinate would be zero at every vertex, and materials read it only from a mesh with
/// texture coordinates): four values per fragment instead of six (the Stanford bunny,
/// Gouraud, two threads, eight alternated runs: 5.74-5.97 -> 5.42-5.73 ms, the fastest frame
/// of each).
struct ColorFragment<'a>(ModelFragment<'a>);

/// What a material multiplies a colour by ([`ModelFragment::material_factor`]).
enum MaterialFactor<'a> {
    /// Its texture, sampled at the fragment's coordinates.
    Texture(&'a Texture),
    /// A constant.
    Constant(Vec4),
}

impl FragmentShader<Vec4> for ColorFragment<'_> {
    fn shade(&self, f: &Fragment<Vec4>) -> Option<Vec4> {
        Some(self.0.albedo_at(Vec2::ZERO, f.varyings, f.primitive))
    }

    fn may_discard(&self) -> bool {
        false
    }

    /// The lit vertex colours times the triangle's material colour (a constant: this shader
    /// is only drawn without texture coordinates). Inlined into the front end's small runs,
    /// which call it per triangle (a call, it was a twenty-fifth of the bunny's frame).
    #[inline]
    fn interpolated_color(&self, v: [&Vec4; 3], primitive: u32) -> Option<InterpolatedColor> {
        let scale = match &self.0.surface.mesh.triangle_materials {
            None => Vec4::ONE,
            Some(materials) => match self.0.material_factor(materials[primitive as usize]) {
                MaterialFactor::Constant(c) => c,
                MaterialFactor::Texture(_) => return None,
            },
        };
        Some(InterpolatedColor { colors: v.map(|c| *c), scale, alpha: None })
    }
}

/// Renders `mesh` seen by `camera` into `target` (which the caller clears).
///
/// # Errors
/// A per-vertex attribute or material list whose length does not match the vertices or
/// triangles, a camera that forms no image ([`Camera::check`]), or what
/// [`crate::pipeline::Pipeline::draw`] refuses (an index past the vertices).
pub fn render_mesh(
    target: &mut Target,
    mesh: &Mesh,
    camera: &Camera,
    options: &ModelOptions,
    textures: &MaterialTextures,
) -> Result<DrawStats, Error> {
    check_mesh(mesh)?;
    camera.check()?;
    let aspect = target.width() as f32 / target.height() as f32;
    let ModelView { origin, view, view_proj } = ModelView::new(camera, aspect);
    let normal_matrix = Mat3::from_mat4(view).inverse().transpose();
    // Vertex normals, where something reads them: the lighting per vertex or per pixel, or
    // the normal buffer (flat lighting writes face normals there). Borrowed when the mesh
    // has them (callers drawing many frames should fill them once, see
    // `with_vertex_normals`); computed here otherwise; empty when nothing reads them.
    let lighting = options.lighting;
    let read_normals = matches!(lighting, Lighting::Gouraud | Lighting::Phong)
        || (target.normals.is_some() && lighting != Lighting::Flat);
    let normals: std::borrow::Cow<'_, [[f32; 3]]> = match &mesh.normals {
        _ if !read_normals => std::borrow::Cow::Borrowed(&[]),
        Some(n) => std::borrow::Cow::Borrowed(n),
        None => std::borrow::Cow::Owned(vertex_normals(&mesh.positions, &mesh.triangles)),
    };
    let colors = mesh.colors.as_ref().map(|c| {
        c.iter()
            .map(|&[r, g, b, a]| Vec4::new(srgb_decode(r), srgb_decode(g), srgb_decode(b), a))
            .collect()
    });
    // Only flat lighting reads face normals.
    let face_normals = if options.lighting == Lighting::Flat {
        face_normals(mesh, &view, origin)
    } else {
        Vec::new()
    };
    let surface = Surface { mesh, normals, textures, colors, face_normals };

    let light = options.light;
    let light_direction = light.unit_direction();
    let base_albedo = base_albedo(mesh);
    // Gouraud's lit colours, every vertex's at once (see `gouraud_colors`).
    let lit = if lighting == Lighting::Gouraud {
        let albedo = |i: usize| surface.colors.as_ref().map_or(base_albedo, |c| c[i]);
        let eye = EyeSpace { origin, view, normal_matrix };
        let level = SimdLevel::detected();
        gouraud_colors(level, &mesh.positions, &surface.normals, albedo, &eye, &light)
    } else {
        Vec::new()
    };
    // Relative to the origin (see `ModelView`).
    let local = |i: usize| (Vec3::from(mesh.positions[i]) - origin).extend(1.0);
    // Gouraud: lit per vertex; texture and material still modulate per pixel.
    let color = |i: usize| match lit.get(i) {
        Some(&lit) => lit,
        None => surface.colors.as_ref().map_or(base_albedo, |c| c[i]),
    };
    let uv = |i: usize| mesh.texcoords.as_ref().map_or(Vec2::ZERO, |t| Vec2::from(t[i]));
    let vertex = |&i: &u32| -> (Vec4, ModelVaryings) {
        let i = i as usize;
        let p = local(i);
        let view_pos = (view * p).truncate();
        let n = surface
            .normals
            .get(i)
            .map_or(Vec3::ZERO, |&n| (normal_matrix * Vec3::from(n)).normalize_or_zero());
        (view_proj * p, (n, uv(i), color(i), view_pos))
    };
    let fragment = ModelFragment {
        surface: &surface,
        options,
        view_to_world: Mat3::from_mat4(view).transpose(),
        light_direction,
        whole_light: light.whole(light_direction),
        level: SimdLevel::detected(),
    };
    let indices: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let pipeline = Pipeline::default().with_cull(options.cull).with_depth_test(options.depth_test);
    // What the fragment shader reads decides what is interpolated.
    let per_pixel_normals = matches!(lighting, Lighting::Flat | Lighting::Phong);
    if per_pixel_normals || target.normals.is_some() {
        return pipeline.draw(target, &vertex, &fragment, &indices, &mesh.triangles);
    }
    if mesh.texcoords.is_none() {
        // Only what the shader reads (the full vertex, called from three places, was not
        // inlined, and its normal's normalisation not left out).
        let color_vertex = |&i: &u32| (view_proj * local(i as usize), color(i as usize));
        let fragment = ColorFragment(fragment);
        return pipeline.draw(target, &color_vertex, &fragment, &indices, &mesh.triangles);
    }
    let surface_vertex = |&i: &u32| {
        let i = i as usize;
        (view_proj * local(i), (uv(i), color(i)))
    };
    let fragment = SurfaceFragment(fragment);
    pipeline.draw(target, &surface_vertex, &fragment, &indices, &mesh.triangles)
}

/// The view transforms Gouraud lighting needs: positions go to view space as
/// `view * (p - origin)`, normals as `normal_matrix * n`.
struct EyeSpace {
    origin: Vec3,
    view: Mat4,
    normal_matrix: Mat3,
}

/// Vertices lit side by side: each vertex alone waited on its chain of square roots and
/// divisions (three normalisations, then the highlight's powers), a third of a Gouraud frame
/// at a small size.
const GOURAUD_LANES: usize = 8;

/// Gouraud's lit colour of every vertex: `albedo(i).rgb * diffuse + specular` (alpha kept),
/// with [`Light::shade_towards`] at the vertex's view-space normal (`normals[i]`, zero when
/// there are none) and direction to the eye. The same operations as one vertex at a time,
/// lane by lane (tested bit for bit at every level), in arrays of [`GOURAUD_LANES`] that the
/// compiler vectorises; from AVX2 on (`level`), eight vertices at a time through
/// [`simd::gouraud_eight`] where the light's exponent is whole ([`Light::whole`]): the
/// Stanford bunny's 35,947 vertices, fastest of 20 frames, 0.52 -> 0.36 ms on one thread
/// and 0.29 -> 0.20 ms on two with the light alone in AVX2, then 0.31 and 0.18 ms with the
/// matrix products in AVX2 too.
fn gouraud_colors(
    level: SimdLevel,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    albedo: impl Fn(usize) -> Vec4 + Sync,
    eye: &EyeSpace,
    light: &Light,
) -> Vec<Vec4> {
    use rayon::prelude::*;
    const CHUNK: usize = 4096;
    let l = light.unit_direction();
    let whole = light.whole(l);
    let lanes_eye = simd::EyeLanes {
        origin: eye.origin.to_array(),
        view: eye.view.to_cols_array_2d(),
        normal: eye.normal_matrix.to_cols_array_2d(),
    };
    let mut out = vec![Vec4::ZERO; positions.len()];
    out.par_chunks_mut(CHUNK).enumerate().for_each(|(c, out)| {
        for (k, out) in out.chunks_mut(GOURAUD_LANES).enumerate() {
            let first = c * CHUNK + k * GOURAUD_LANES;
            let range = first..first + GOURAUD_LANES;
            // Eight side by side in SIMD where they can be (every vertex's normal or none).
            let eight = whole.as_ref().zip(positions.get(range.clone())).and_then(|(w, p)| {
                let p = p.try_into().ok()?;
                let n = match normals.get(range.clone()) {
                    Some(n) => Some(n.try_into().ok()?),
                    None if normals.is_empty() => None,
                    None => return None,
                };
                simd::gouraud_eight(level, p, n, &lanes_eye, w)
            });
            let (d, s) = eight.unwrap_or_else(|| {
                let mut lanes = GouraudLanes::default();
                for (j, _) in out.iter().enumerate() {
                    let i = first + j;
                    let p = (Vec3::from(positions[i]) - eye.origin).extend(1.0);
                    let view_pos = (eye.view * p).truncate();
                    let n =
                        normals.get(i).map_or(Vec3::ZERO, |&n| eye.normal_matrix * Vec3::from(n));
                    lanes.set(j, n, -view_pos);
                }
                lanes.shade(light, l)
            });
            for (j, out) in out.iter_mut().enumerate() {
                let color = albedo(first + j);
                *out = (color.truncate() * d[j] + Vec3::splat(s[j])).extend(color.w);
            }
        }
    });
    out
}

/// [`GOURAUD_LANES`] vertices' view-space normals and directions to the eye, a component per
/// array.
#[derive(Default)]
struct GouraudLanes {
    n: [[f32; GOURAUD_LANES]; 3],
    v: [[f32; GOURAUD_LANES]; 3],
}

impl GouraudLanes {
    fn set(&mut self, j: usize, n: Vec3, v: Vec3) {
        for k in 0..3 {
            (self.n[k][j], self.v[k][j]) = (n[k], v[k]);
        }
    }

    /// `light.shade_towards(l, n.normalize_or_zero(), v.normalize_or(Vec3::Z))` lane by lane:
    /// glam's operations in its order (a dot product `(x x + y y) + z z`, `1 / length` and a
    /// fallback where that is not finite and positive), the highlight as [`Light::highlight`].
    fn shade(&self, light: &Light, l: Vec3) -> (Lanes, Lanes) {
        let n = normalized(&self.n, Vec3::ZERO);
        let v = normalized(&self.v, Vec3::Z);
        let mut to_h = [[0.0; GOURAUD_LANES]; 3];
        for k in 0..3 {
            for j in 0..GOURAUD_LANES {
                to_h[k][j] = l[k] + v[k][j];
            }
        }
        let h = normalized(&to_h, Vec3::Z);
        let (mut diffuse, mut n_h) = ([0.0; GOURAUD_LANES], [0.0; GOURAUD_LANES]);
        for j in 0..GOURAUD_LANES {
            let n_l = (n[0][j] * l.x + n[1][j] * l.y) + n[2][j] * l.z;
            diffuse[j] = light.ambient + light.diffuse * n_l.max(0.0);
            n_h[j] = ((n[0][j] * h[0][j] + n[1][j] * h[1][j]) + n[2][j] * h[2][j]).max(0.0);
        }
        let highlight = light.highlights(n_h);
        let mut specular = [0.0; GOURAUD_LANES];
        for j in 0..GOURAUD_LANES {
            let n_l = (n[0][j] * l.x + n[1][j] * l.y) + n[2][j] * l.z;
            specular[j] = if n_l > 0.0 { light.specular * highlight[j] } else { 0.0 };
        }
        (diffuse, specular)
    }
}

/// [`GOURAUD_LANES`] values of one kind.
type Lanes = [f32; GOURAUD_LANES];

/// `Vec3::normalize_or(fallback)` lane by lane, in glam's operations: `1 / length`, with the
/// length the root of `(x x + y y) + z z`, and the fallback where that is not finite and
/// positive.
#[inline(always)]
fn normalized(x: &[Lanes; 3], fallback: Vec3) -> [Lanes; 3] {
    let mut out = [[0.0; GOURAUD_LANES]; 3];
    for j in 0..GOURAUD_LANES {
        let d = (x[0][j] * x[0][j] + x[1][j] * x[1][j]) + x[2][j] * x[2][j];
        let rcp = 1.0 / d.sqrt();
        let ok = rcp.is_finite() && rcp > 0.0;
        for k in 0..3 {
            out[k][j] = if ok { x[k][j] * rcp } else { fallback[k] };
        }
    }
    out
}

/// The errors the shaders would otherwise meet as out-of-bounds reads: a per-vertex array
/// shorter or longer than the positions, a material list not one per triangle. The loaders
/// never build such a mesh; a program filling [`Mesh`] itself may. An index past the
/// vertices is the pipeline's error to report (`Pipeline::draw` checks every index).
fn check_mesh(mesh: &Mesh) -> Result<(), Error> {
    let vertices = mesh.positions.len();
    let per_vertex = [
        ("normals", mesh.normals.as_ref().map(Vec::len)),
        ("texture coordinates", mesh.texcoords.as_ref().map(Vec::len)),
        ("colours", mesh.colors.as_ref().map(Vec::len)),
    ];
    for (attribute, len) in per_vertex {
        if let Some(len) = len.filter(|&len| len != vertices) {
            let of = "vertices";
            return Err(Error::MeshAttributeLength { attribute, len, expected: vertices, of });
        }
    }
    let triangles = mesh.triangles.len();
    if let Some(len) = mesh.triangle_materials.as_ref().map(Vec::len).filter(|&n| n != triangles) {
        let (attribute, of) = ("triangle materials", "triangles");
        return Err(Error::MeshAttributeLength { attribute, len, expected: triangles, of });
    }
    Ok(())
}

/// View-space unit normals of the triangles; zero for one with an index past the vertices
/// (computed before `Pipeline::draw`, which reports that index as an error).
fn face_normals(mesh: &Mesh, view: &Mat4, origin: Vec3) -> Vec<Vec3> {
    let point = |i: u32| mesh.positions.get(i as usize).map(|&p| Vec3::from(p) - origin);
    mesh.triangles
        .iter()
        .map(|t| match t.map(point) {
            [Some(a), Some(b), Some(c)] => {
                let [a, b, c] = [a, b, c].map(|p| view.transform_point3(p));
                (b - a).cross(c - a).normalize_or_zero()
            }
            _ => Vec3::ZERO,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Vertex normals: vertices at one position (a texture seam splits them) share the
    /// normal of the welded mesh, bit for bit; renumbering the vertices gives each the same
    /// bits (the slots' numbering does not matter); a triangle past the vertices is ignored;
    /// a lone triangle's corners get its unit normal, and area weighting lets a large face
    /// outweigh a small one.
    #[test]
    fn vertex_normals_weld_positions_and_ignore_numbering() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(5);
        for _ in 0..50 {
            let n = rng.random_range(3..60);
            let welded: Vec<[f32; 3]> =
                (0..n).map(|_| std::array::from_fn(|_| rng.random_range(-3.0..3.0))).collect();
            let triangles: Vec<[u32; 3]> = (0..rng.random_range(1..120))
                .map(|_| std::array::from_fn(|_| rng.random_range(0..n as u32)))
                .collect();
            // Split: every corner its own vertex, at its position.
            let split_positions: Vec<[f32; 3]> =
                triangles.iter().flatten().map(|&i| welded[i as usize]).collect();
            let split_triangles: Vec<[u32; 3]> =
                (0..triangles.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
            let want = vertex_normals(&welded, &triangles);
            let got = vertex_normals(&split_positions, &split_triangles);
            for (corner, &i) in triangles.iter().flatten().enumerate() {
                assert_eq!(got[corner].map(f32::to_bits), want[i as usize].map(f32::to_bits));
            }
            // Renumbered: vertex k becomes perm[k].
            let mut perm: Vec<u32> = (0..n as u32).collect();
            for k in (1..n).rev() {
                perm.swap(k, rng.random_range(0..=k));
            }
            let mut renumbered = vec![[0.0; 3]; n];
            for (k, &p) in perm.iter().enumerate() {
                renumbered[p as usize] = welded[k];
            }
            let mut tris: Vec<[u32; 3]> =
                triangles.iter().map(|t| t.map(|i| perm[i as usize])).collect();
            tris.push([0, 1, n as u32]);
            let again = vertex_normals(&renumbered, &tris);
            for k in 0..n {
                assert_eq!(again[perm[k] as usize].map(f32::to_bits), want[k].map(f32::to_bits));
            }
        }
        let lone =
            vertex_normals(&[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]], &[[0, 1, 2]]);
        assert_eq!(lone, vec![[0.0, 0.0, 1.0]; 3]);
        // Two faces at vertex 0: a large one facing +z, a small one facing +x.
        let positions =
            [[0.0, 0.0, 0.0], [4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let n = vertex_normals(&positions, &[[0, 1, 2], [0, 3, 4]]);
        assert!(n[0][2] > 0.99 && n[0][0] > 0.0 && n[0][0] < 0.1, "{:?}", n[0]);
    }

    /// Materials naming one file share one decoded texture, and one that cannot be read
    /// warns for each material naming it.
    #[test]
    fn materials_share_a_texture_file() {
        let dir = std::env::temp_dir().join(format!("trirast-model-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (png, missing) = (dir.join("atlas.png"), dir.join("missing.png"));
        image::RgbaImage::from_pixel(4, 2, image::Rgba([10, 20, 30, 255])).save(&png).unwrap();
        let material = |name: &str, path: &Path| crate::mesh::Material {
            name: name.into(),
            diffuse_texture: Some(path.to_path_buf()),
            ..Default::default()
        };
        let mesh = Mesh {
            materials: vec![
                material("a", &png),
                material("b", &missing),
                crate::mesh::Material::default(),
                material("c", &png),
                material("d", &missing),
            ],
            ..Default::default()
        };
        let textures = MaterialTextures::load(&mesh);
        std::fs::remove_dir_all(&dir).unwrap();
        let shared = |k: usize| textures.textures[k].as_ref().expect("loaded");
        assert!(Arc::ptr_eq(shared(0), shared(3)), "one copy of the shared file");
        assert_eq!(textures.get(0).map(|t| (t.width(), t.height())), Some((4, 2)));
        assert!([1, 2, 4].iter().all(|&k| textures.get(k).is_none()));
        assert_eq!(textures.warnings.len(), 2, "{:?}", textures.warnings);
        assert!(
            textures.warnings[1].starts_with("the texture of material `d`"),
            "{:?}",
            textures.warnings
        );
    }

    /// Gouraud's colours lit side by side are those of one vertex at a time, bit for bit, at
    /// every SIMD level: random positions (some at the eye), normals (some zero, some
    /// missing), albedos, lights with whole exponents (0, 1, the default 32, 1024) and others
    /// (`powf`).
    #[test]
    fn gouraud_lanes_light_as_one_vertex_at_a_time() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(17);
        for round in 0..200 {
            let len = rng.random_range(0..40);
            let value = |rng: &mut SmallRng| rng.random_range(-2.0..2.0f32);
            let positions: Vec<[f32; 3]> =
                (0..len)
                    .map(|k| {
                        if k % 7 == 3 { [0.0; 3] } else { std::array::from_fn(|_| value(&mut rng)) }
                    })
                    .collect();
            let normals: Vec<[f32; 3]> = match round % 5 {
                0 => Vec::new(),
                _ => (0..len)
                    .map(|k| {
                        if k % 5 == 1 { [0.0; 3] } else { std::array::from_fn(|_| value(&mut rng)) }
                    })
                    .collect(),
            };
            let albedos: Vec<Vec4> =
                (0..len).map(|_| Vec4::from_array(std::array::from_fn(|_| rng.random()))).collect();
            let shininess = [0.0, 1.0, 32.0, 1024.0, 7.5, 2000.0][round % 6];
            let light = Light {
                direction: Vec3::new(value(&mut rng), value(&mut rng), value(&mut rng)),
                shininess,
                // A negative zero tells `max(-0.0, 0.0)`'s two answers apart (zero normals).
                ambient: if round % 4 == 0 { -0.0 } else { Light::default().ambient },
                ..Light::default()
            };
            let eye = EyeSpace {
                origin: Vec3::new(value(&mut rng), value(&mut rng), value(&mut rng)),
                view: Mat4::from_rotation_y(value(&mut rng)) * Mat4::from_translation(Vec3::Z),
                normal_matrix: Mat3::from_rotation_x(value(&mut rng)),
            };
            for level in SimdLevel::available() {
                let lanes =
                    gouraud_colors(level, &positions, &normals, |i| albedos[i], &eye, &light);
                for (i, lit) in lanes.iter().enumerate() {
                    let p = (Vec3::from(positions[i]) - eye.origin).extend(1.0);
                    let view_pos = (eye.view * p).truncate();
                    let n = normals.get(i).map_or(Vec3::ZERO, |&n| {
                        (eye.normal_matrix * Vec3::from(n)).normalize_or_zero()
                    });
                    let l = light.unit_direction();
                    let (d, s) = light.shade_towards(l, n, (-view_pos).normalize_or(Vec3::Z));
                    let color = albedos[i];
                    let one = (color.truncate() * d + Vec3::splat(s)).extend(color.w);
                    assert_eq!(
                        lit.to_array().map(f32::to_bits),
                        one.to_array().map(f32::to_bits),
                        "{round} {i} {level:?}"
                    );
                }
            }
        }
    }

    /// Phong's lanes ([`ModelFragment::shade_lanes`]) shade as one fragment at a time, bit
    /// for bit, at every level: random interpolated normals (zero, tiny, huge and NaN ones
    /// among them), view positions (zero among them) and colours, front and back faces, one
    /// to eight lanes, whole exponents and others, a negative zero ambient.
    #[test]
    fn phong_lanes_shade_as_one_fragment_at_a_time() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(23);
        let mesh = Mesh::default();
        let textures = MaterialTextures::default();
        for round in 0..400 {
            let value = |rng: &mut SmallRng| rng.random_range(-2.0..2.0f32);
            let vector = |rng: &mut SmallRng, k: usize| match k % 9 {
                1 => Vec3::ZERO,
                4 => Vec3::new(value(rng), value(rng), value(rng)) * 1e-30,
                6 => Vec3::new(value(rng), value(rng), value(rng)) * 1e30,
                7 if round % 2 == 0 => Vec3::new(f32::NAN, value(rng), 0.0),
                _ => Vec3::new(value(rng), value(rng), value(rng)),
            };
            let len = rng.random_range(1..=GOURAUD_LANES);
            let fragments: Vec<Fragment<ModelVaryings>> = (0..len)
                .map(|k| Fragment {
                    x: k as i32,
                    y: 0,
                    depth: 0.5,
                    varyings: (
                        vector(&mut rng, k + round),
                        Vec2::ZERO,
                        Vec4::from_array(std::array::from_fn(|_| rng.random())),
                        vector(&mut rng, k * 2 + round),
                    ),
                    front_facing: rng.random(),
                    primitive: k as u32,
                })
                .collect();
            let light = Light {
                direction: Vec3::new(value(&mut rng), value(&mut rng), value(&mut rng)),
                shininess: [0.0, 1.0, 32.0, 1024.0, 7.5, 2000.0][round % 6],
                ambient: if round % 4 == 0 { -0.0 } else { Light::default().ambient },
                ..Light::default()
            };
            let options = ModelOptions { lighting: Lighting::Phong, light, ..Default::default() };
            let surface = Surface {
                mesh: &mesh,
                normals: std::borrow::Cow::Borrowed(&[]),
                textures: &textures,
                colors: None,
                face_normals: Vec::new(),
            };
            let light_direction = light.unit_direction();
            for level in SimdLevel::available() {
                let fragment = ModelFragment {
                    surface: &surface,
                    options: &options,
                    view_to_world: Mat3::IDENTITY,
                    light_direction,
                    whole_light: light.whole(light_direction),
                    level,
                };
                let mut lanes = [None; GOURAUD_LANES];
                fragment.shade_lanes(&fragments, &mut lanes[..len]);
                for (k, (f, lane)) in fragments.iter().zip(&lanes).enumerate() {
                    let bits = |c: Option<Vec4>| c.map(|c| c.to_array().map(f32::to_bits));
                    assert_eq!(bits(*lane), bits(fragment.shade(f)), "{round} {k} {level:?}");
                }
            }
        }
    }

    use crate::camera::{self, Projection};
    use crate::mesh::Material;

    /// The specular power: for whole exponents within 1e-4 of `powf` relative (rounding
    /// grows with the number of squarings), other exponents exactly `powf`.
    #[test]
    fn highlights_follow_powf() {
        for shininess in [0.0, 1.0, 2.0, 7.0, 32.0, 100.0, 1024.0, 0.5, 2.5, 1e4, -2.0, f32::NAN] {
            let light = Light { shininess, ..Light::default() };
            for k in 0..=1000 {
                let c = k as f32 / 1000.0;
                let (got, want) = (light.highlight(c), c.powf(shininess));
                let whole = shininess.fract() == 0.0 && (0.0..=1024.0).contains(&shininess);
                if whole {
                    let tolerance = 1e-4 * want.abs() + f32::MIN_POSITIVE;
                    assert!((got - want).abs() <= tolerance, "{c}^{shininess}: {got} {want}");
                } else {
                    assert_eq!(got.to_bits(), want.to_bits(), "{c}^{shininess}");
                }
            }
        }
    }

    /// A mesh whose arrays do not match (built by a program, not a loader) is an error
    /// naming the array, and an index past the vertices is one naming the triangle, for every
    /// lighting model (flat lighting reads the positions through the indices before the
    /// pipeline does), never a panic.
    #[test]
    fn mismatched_meshes_are_errors() {
        let good = crate::scene::sphere_mesh(200).unwrap();
        let camera = Camera::framing_sphere(
            Vec3::ZERO,
            1.0,
            0.4,
            0.3,
            1.0,
            Projection::Perspective { fov_y: 1.0 },
        );
        let (n, t) = (good.positions.len(), good.triangles.len());
        type Breaks = Box<dyn Fn(&mut Mesh)>;
        let broken: [(&str, Breaks); 5] = [
            ("normals", Box::new(move |m| m.normals = Some(vec![[0.0, 0.0, 1.0]; n - 1]))),
            ("texture coordinates", Box::new(move |m| m.texcoords = Some(vec![[0.0; 2]; n + 1]))),
            ("colours", Box::new(|m| m.colors = Some(Vec::new()))),
            ("triangle materials", Box::new(move |m| m.triangle_materials = Some(vec![0; t - 1]))),
            ("index", Box::new(|m| m.triangles[7][1] = 1 << 30)),
        ];
        for (what, breaks) in &broken {
            for lighting in [Lighting::Unlit, Lighting::Flat, Lighting::Gouraud, Lighting::Phong] {
                let mut mesh = good.clone();
                breaks(&mut mesh);
                let mut target = Target::new(32, 32).unwrap();
                let options = ModelOptions::default().with_lighting(lighting);
                let textures = MaterialTextures::default();
                let err =
                    render_mesh(&mut target, &mesh, &camera, &options, &textures).expect_err(what);
                let message = err.to_string();
                let named = if *what == "index" {
                    message.contains("triangle 7")
                } else {
                    message.contains(what)
                };
                assert!(named, "{what}, {lighting:?}: {message}");
            }
        }
        let mut target = Target::new(32, 32).unwrap();
        let options = ModelOptions::default();
        render_mesh(&mut target, &good, &camera, &options, &MaterialTextures::default()).unwrap();
        // A camera that forms no image is an error too, where it had drawn nothing.
        let blind = Camera { projection: Projection::Perspective { fov_y: f32::NAN }, ..camera };
        let err = render_mesh(&mut target, &good, &blind, &options, &MaterialTextures::default());
        assert!(matches!(err, Err(Error::Camera(_))), "{err:?}");
    }

    /// A triangle's material colours it: unlit, each pixel of a sphere whose triangles
    /// alternate between a red and a blue material is the colour of the material of the
    /// triangle its id names, for every triangle drawn (no texture, no vertex colours).
    #[test]
    fn materials_colour_their_triangles() {
        let mut mesh = crate::scene::sphere_mesh(500).unwrap();
        mesh.materials = vec![
            Material { diffuse: [1.0, 0.0, 0.0], ..Material::default() },
            Material { diffuse: [0.0, 0.0, 1.0], ..Material::default() },
        ];
        mesh.triangle_materials = Some((0..mesh.triangles.len() as u32).map(|t| t % 2).collect());
        let (centre, radius) = camera::bounding_sphere(&mesh.positions);
        let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
        let camera = Camera::framing_sphere(centre, radius, 0.4, 0.3, 1.5, projection);
        let options = ModelOptions::default().with_lighting(Lighting::Unlit);
        let mut target = Target::new(96, 64).unwrap().with_ids();
        let textures = MaterialTextures::default();
        let stats = render_mesh(&mut target, &mesh, &camera, &options, &textures).unwrap();
        assert!(stats.fragments > 1000, "the sphere is drawn");
        let ids = target.ids.as_ref().unwrap();
        let mut seen = [0; 2];
        for (&id, color) in ids.iter().zip(&target.color).filter(|(id, _)| **id >= 0) {
            let want = if id % 2 == 0 { [255, 0, 0, 255] } else { [0, 0, 255, 255] };
            assert_eq!(*color, want, "triangle {id}");
            seen[id as usize % 2] += 1;
        }
        assert!(seen.iter().all(|&n| n > 100), "both materials drawn: {seen:?}");
    }

    /// Draws `mesh` unlit and Gouraud without and with a normal buffer (which takes the full
    /// varyings) and asserts the same colour, depth and ids: what is interpolated must not
    /// change the picture.
    fn assert_draws_as_with_full_varyings(mesh: &Mesh, textures: &MaterialTextures) {
        let (centre, radius) = camera::bounding_sphere(&mesh.positions);
        let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
        let camera = Camera::framing_sphere(centre, radius, 0.4, 0.3, 1.5, projection);
        for lighting in [Lighting::Unlit, Lighting::Gouraud] {
            let options = ModelOptions::default().with_lighting(lighting);
            let draw = |target: Target| {
                let mut target = target.with_ids();
                let stats = render_mesh(&mut target, mesh, &camera, &options, textures).unwrap();
                assert!(stats.fragments > 1000, "{lighting:?}: the sphere is drawn");
                target
            };
            let lean = draw(Target::new(96, 64).unwrap());
            let full = draw(Target::new(96, 64).unwrap().with_normals());
            assert_eq!(lean.color, full.color, "{lighting:?}");
            assert_eq!(lean.depth, full.depth, "{lighting:?}");
            assert_eq!(lean.ids, full.ids, "{lighting:?}");
        }
    }

    /// A sphere of `triangles` with vertex colours (alpha `alpha`) and vertex normals.
    fn coloured_sphere(triangles: usize, alpha: f32) -> Mesh {
        let mut mesh = crate::scene::sphere_mesh(triangles).unwrap();
        let n = mesh.positions.len();
        let wave = |i: usize, k: f32| (i as f32 * k).sin() * 0.5 + 0.5;
        mesh.colors =
            Some((0..n).map(|i| [wave(i, 0.3), wave(i, 0.7), wave(i, 1.1), alpha]).collect());
        with_vertex_normals(&mut mesh);
        mesh
    }

    /// Phong draws through the pipeline with its lanes ([`FragmentShader::shades_lanes`]),
    /// and on multisampled targets with its small triangles' colour waiting behind their
    /// depth in a shared queue ([`crate::shade::shade_small_triangle_samples`], at 4x also
    /// eight at a time, [`crate::shade::shade_small_lane_samples`]), what it draws one
    /// fragment at a time: colour, depth, ids, normals and overdraw, at 1x, 4x and 8x, the
    /// reference and both schedules, every level, with `Less` and with `Always` (where the
    /// last triangle drawn wins, so colour written out of order shows). The mesh is two
    /// overlapping spheres, one of large triangles after one of small ones, with back faces
    /// drawn, seen close enough for perspective.
    #[test]
    fn phong_lanes_draw_as_one_fragment_at_a_time() {
        use crate::render::{Backend, Schedule};
        use crate::sample::SampleCount;
        use crate::shade::DepthTest;
        /// The same shader, without lanes.
        struct OneByOne<'a>(&'a ModelFragment<'a>);
        impl FragmentShader<ModelVaryings> for OneByOne<'_> {
            fn shade(&self, f: &Fragment<ModelVaryings>) -> Option<Vec4> {
                self.0.shade(f)
            }
            fn normal(&self, f: &Fragment<ModelVaryings>) -> Option<Vec3> {
                self.0.normal(f)
            }
        }
        let mut mesh = coloured_sphere(3000, 0.8);
        let large = coloured_sphere(120, 1.0);
        let base = mesh.positions.len() as u32;
        let shifted = large.positions.iter().map(|p| [p[0] + 0.5, p[1] * 0.8, p[2] + 0.3]);
        mesh.positions.extend(shifted);
        mesh.normals.as_mut().unwrap().extend(large.normals.as_ref().unwrap());
        mesh.colors.as_mut().unwrap().extend(large.colors.as_ref().unwrap());
        mesh.triangles.extend(large.triangles.iter().map(|t| t.map(|i| i + base)));
        let (centre, radius) = camera::bounding_sphere(&mesh.positions);
        let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
        let camera = Camera::framing_sphere(centre, radius, 0.4, 0.3, 1.2, projection);
        let (width, height) = (200, 150);
        let ModelView { origin, view, view_proj } =
            ModelView::new(&camera, width as f32 / height as f32);
        let normal_matrix = Mat3::from_mat4(view).inverse().transpose();
        let textures = MaterialTextures::default();
        let normals = mesh.normals.clone().unwrap();
        let colors: Vec<Vec4> =
            mesh.colors.as_ref().unwrap().iter().map(|&c| Vec4::from(c)).collect();
        let surface = Surface {
            mesh: &mesh,
            normals: std::borrow::Cow::Borrowed(&normals),
            textures: &textures,
            colors: Some(colors.clone()),
            face_normals: Vec::new(),
        };
        let options = ModelOptions::default();
        assert_eq!(options.lighting, Lighting::Phong);
        let light_direction = options.light.unit_direction();
        let vertex = |&i: &u32| -> (Vec4, ModelVaryings) {
            let i = i as usize;
            let p = (Vec3::from(mesh.positions[i]) - origin).extend(1.0);
            let n = (normal_matrix * Vec3::from(normals[i])).normalize_or_zero();
            (view_proj * p, (n, Vec2::ZERO, colors[i], (view * p).truncate()))
        };
        let indices: Vec<u32> = (0..mesh.positions.len() as u32).collect();
        let backends = [
            (Backend::Reference, Schedule::Auto),
            (Backend::Tiled, Schedule::Binned),
            (Backend::Tiled, Schedule::Banded),
        ];
        for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
            for (backend, schedule) in backends {
                for depth_test in [DepthTest::Less, DepthTest::Always] {
                    for level in SimdLevel::available() {
                        let fragment = ModelFragment {
                            surface: &surface,
                            options: &options,
                            view_to_world: Mat3::from_mat4(view).transpose(),
                            light_direction,
                            whole_light: options.light.whole(light_direction),
                            level,
                        };
                        let pipeline = Pipeline::default()
                            .with_cull(FaceCull::None)
                            .with_backend(backend)
                            .with_schedule(schedule)
                            .with_depth_test(depth_test)
                            .with_simd(level);
                        let draw = |shader: &dyn Fn(&mut Target) -> DrawStats| {
                            let mut target = Target::multisampled(width, height, samples)
                                .unwrap()
                                .with_ids()
                                .with_normals()
                                .with_overdraw();
                            let stats = shader(&mut target);
                            assert!(stats.fragments > 10_000, "the spheres are drawn");
                            target
                        };
                        let triangles = &mesh.triangles;
                        let lanes = draw(&|t| {
                            pipeline.draw(t, &vertex, &fragment, &indices, triangles).unwrap()
                        });
                        let one = OneByOne(&fragment);
                        let single = draw(&|t| {
                            pipeline.draw(t, &vertex, &one, &indices, triangles).unwrap()
                        });
                        let case = format!(
                            "{samples:?} {backend:?} {schedule:?} {depth_test:?} {level:?}"
                        );
                        assert_eq!(lanes.color, single.color, "{case}");
                        let bits =
                            |t: &Target| t.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
                        assert_eq!(bits(&lanes), bits(&single), "{case}");
                        assert_eq!(lanes.ids, single.ids, "{case}");
                        assert_eq!(lanes.overdraw, single.overdraw, "{case}");
                        let normal_bits = |t: &Target| {
                            let n = t.normals.as_ref().unwrap();
                            n.iter().flat_map(|n| n.map(f32::to_bits)).collect::<Vec<_>>()
                        };
                        assert_eq!(normal_bits(&lanes), normal_bits(&single), "{case}");
                    }
                }
            }
        }
    }

    /// Unlit and Gouraud lighting interpolate only the texture coordinate and colour when the
    /// target has no normal buffer ([`SurfaceVaryings`]), on a sphere with vertex colours,
    /// texture coordinates and a textured material on half its triangles.
    #[test]
    fn surface_varyings_draw_what_the_full_ones_draw() {
        let mut mesh = coloured_sphere(3000, 1.0);
        let n = mesh.positions.len();
        let wave = |i: usize, k: f32| (i as f32 * k).sin() * 0.5 + 0.5;
        mesh.texcoords = Some((0..n).map(|i| [wave(i, 0.13), wave(i, 0.29)]).collect());
        mesh.materials = vec![Material::default(), Material::default()];
        mesh.triangle_materials = Some((0..mesh.triangles.len() as u32).map(|t| t % 2).collect());
        let texels: Vec<u8> = (0..4 * 8 * 8).map(|k| (k * 37 % 251) as u8).collect();
        let textures = MaterialTextures {
            textures: vec![None, Some(Arc::new(Texture::from_srgba8(8, 8, &texels)))],
            warnings: Vec::new(),
        };
        assert_draws_as_with_full_varyings(&mesh, &textures);
    }

    /// Without texture coordinates, unlit and Gouraud lighting interpolate the colour alone
    /// ([`ColorFragment`], shaded in the SIMD kernels at 1x), alpha included: the same bits
    /// as the full varyings (the fragment stage), without materials, with plain ones, with a
    /// textured one (which, without coordinates, takes its diffuse colour), and with an index
    /// past the materials (the colour as it is).
    #[test]
    fn color_varyings_draw_what_the_full_ones_draw() {
        let mesh = coloured_sphere(3000, 0.8);
        assert!(mesh.texcoords.is_none());
        assert_draws_as_with_full_varyings(&mesh, &MaterialTextures::default());
        let mut with_materials = mesh;
        let red = Material { diffuse: [0.9, 0.2, 0.1], ..Material::default() };
        with_materials.materials = vec![Material::default(), red.clone(), red];
        let count = with_materials.triangles.len() as u32;
        with_materials.triangle_materials = Some((0..count).map(|t| t % 4).collect());
        let texels: Vec<u8> = (0..4 * 8 * 8).map(|k| (k * 37 % 251) as u8).collect();
        let textures = MaterialTextures {
            textures: vec![None, None, Some(Arc::new(Texture::from_srgba8(8, 8, &texels)))],
            warnings: Vec::new(),
        };
        assert_draws_as_with_full_varyings(&with_materials, &MaterialTextures::default());
        assert_draws_as_with_full_varyings(&with_materials, &textures);
    }
}
