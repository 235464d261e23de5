//! The programmable 3D pipeline: vertex shader -> clip -> viewport -> setup -> raster -> shade
//! with a fragment shader.
//!
//! ```
//! use glam::{Vec3, Vec4};
//! use trirast::pipeline::{Fragment, Pipeline};
//! use trirast::Target;
//!
//! // Vertices carry a position and a colour; the colour is a perspective-correct varying.
//! let vertices = [
//!     (Vec3::new(-1.0, -1.0, -3.0), Vec3::X),
//!     (Vec3::new(1.0, -1.0, -3.0), Vec3::Y),
//!     (Vec3::new(0.0, 1.0, -3.0), Vec3::Z),
//! ];
//! let camera = trirast::camera::Camera {
//!     eye: Vec3::ZERO, target: Vec3::NEG_Z, up: Vec3::Y,
//!     projection: trirast::camera::Projection::Perspective { fov_y: 1.0 },
//!     near: 0.1, far: 10.0,
//! };
//! let mut target = Target::new(64, 64)?.with_ids();
//! let view_proj = camera.view_projection(1.0);
//! let vertex = |v: &(Vec3, Vec3)| (view_proj * v.0.extend(1.0), v.1);
//! let fragment = |f: &Fragment<Vec3>| Some(f.varyings.extend(1.0));
//! let stats = Pipeline::default().draw(&mut target, &vertex, &fragment, &vertices, &[[0, 1, 2]])?;
//! assert_eq!(stats.rasterized, 1);
//! assert_eq!(target.ids.as_ref().unwrap()[target.index(32, 32)], 0);
//! # Ok::<(), trirast::Error>(())
//! ```
//!
//! Vertices are shaded once each (in parallel), triangles in submission order. A clipped
//! triangle keeps its index as its id. Fragment shaders return linear RGBA; the pipeline
//! encodes to sRGB on write.

use std::borrow::Borrow;

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::band;
use crate::bin::{self, Prepared, Sink, Skipped};
use crate::clip::{ClipVertex, ClipVolume};
use crate::color::{linear_to_srgb8_rgb, unorm8};
use crate::error::Error;
use crate::fixed;
use crate::raster::Algorithm;
use crate::render::{Backend, DrawStats, Schedule};
use crate::sample::SampleCount;
use crate::setup::{self, CullMode, PixelRect, Rejection, TriangleSetup, Vertex};
use crate::shade::{self, DepthTest, FragmentOutput, LANES, PassedLanes, TriangleFragments};
use crate::simd::{self, Corner, CornerGroup, OUTSIDE, PerspectiveColor, SimdLevel, SpanColor};
use crate::target::Target;
use crate::varyings::Varyings;

/// Computes a vertex's clip-space position and varyings. Closures
/// `Fn(&I) -> (Vec4, V)` are vertex shaders. A shader must give the same output each time
/// it shades a vertex: the pipeline shades the vertices of triangles that need clipping
/// again, for their positions, rather than keep every vertex's.
pub trait VertexShader<I>: Sync {
    /// What the vertex passes on.
    type Varyings: Varyings;
    /// Shades one vertex.
    fn shade(&self, input: &I) -> (Vec4, Self::Varyings);
}

impl<I, V: Varyings, F: Fn(&I) -> (Vec4, V) + Sync> VertexShader<I> for F {
    type Varyings = V;
    fn shade(&self, input: &I) -> (Vec4, V) {
        self(input)
    }
}

/// One covered pixel that passed the depth test.
#[derive(Clone, Copy, Debug)]
pub struct Fragment<V> {
    /// Pixel column.
    pub x: i32,
    /// Pixel row (0 at the top).
    pub y: i32,
    /// Window depth in [0, 1].
    pub depth: f32,
    /// Perspective-correct varyings at the pixel centre.
    pub varyings: V,
    /// True when the triangle faces the camera (counter-clockwise in NDC).
    pub front_facing: bool,
    /// Index of the triangle in the draw call.
    pub primitive: u32,
}

/// Computes a fragment's linear RGBA colour, or `None` to discard it. Closures
/// `Fn(&Fragment<V>) -> Option<Vec4>` are fragment shaders.
pub trait FragmentShader<V>: Sync {
    /// Shades one fragment.
    fn shade(&self, fragment: &Fragment<V>) -> Option<Vec4>;

    /// Shades `fragments` into `out` (as many, at most [`crate::shade::LANES`]): what
    /// [`FragmentShader::shade`] gives each, bit for bit. A shader overrides it to compute
    /// several fragments side by side, where one alone would wait on a chain of square roots
    /// and divisions (the built-in Phong lighting), and says so with
    /// [`FragmentShader::shades_lanes`]; by default one after another.
    fn shade_lanes(&self, fragments: &[Fragment<V>], out: &mut [Option<Vec4>]) {
        for (fragment, out) in fragments.iter().zip(out) {
            *out = self.shade(fragment);
        }
    }

    /// Whether the pipeline should gather the fragments that pass the depth test and hand
    /// them to [`FragmentShader::shade_lanes`] several at a time. `false` by default: each
    /// fragment then goes to [`FragmentShader::shade`] as it is interpolated, without the
    /// gathering (which cost the Gouraud bunny 4.6% more instructions).
    fn shades_lanes(&self) -> bool {
        false
    }

    /// The normal to store in the target's normal buffer, if any.
    fn normal(&self, _fragment: &Fragment<V>) -> Option<Vec3> {
        None
    }

    /// Whether [`FragmentShader::shade`] may discard (return `None`). A shader that says
    /// `false` lets large triangles that cover a block of the target lower its depth bound,
    /// so later triangles behind them are skipped there (see ARCHITECTURE.md, *Hierarchical
    /// depth*); saying `false` and then discarding draws wrong pictures.
    fn may_discard(&self) -> bool {
        true
    }

    /// For the triangle `primitive` with vertex varyings `varyings`: `Some` when
    /// [`FragmentShader::shade`] gives every fragment of it the colour `InterpolatedColor`
    /// describes, and never discards there. The tiled backend may then shade the triangle in
    /// SIMD kernels, which compute that colour as the pipeline's own arithmetic does, bit for
    /// bit, without calling `shade` (it does at 1x, on targets without a normal buffer: small
    /// triangles from AVX2 on, larger ones with AVX-512). `None` by default; a shader that
    /// says `Some` and then computes something else draws wrong pictures.
    fn interpolated_color(&self, _varyings: [&V; 3], _primitive: u32) -> Option<InterpolatedColor> {
        None
    }
}

impl<V, F: Fn(&Fragment<V>) -> Option<Vec4> + Sync> FragmentShader<V> for F {
    fn shade(&self, fragment: &Fragment<V>) -> Option<Vec4> {
        self(fragment)
    }
}

/// A triangle's fragment colour as a fixed function of its vertex colours
/// ([`FragmentShader::interpolated_color`]): `weighted * scale`, where `weighted` is the
/// perspective-correct interpolation of `colors` as [`Varyings::weighted`] computes it for a
/// `Vec4` (`c0 * w0 + c1 * w1 + c2 * w2` in `f32`, left to right) and the product is
/// component-wise; with `alpha`, every fragment's alpha is that value instead.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterpolatedColor {
    /// Linear RGBA at the three vertices.
    pub colors: [Vec4; 3],
    /// Multiplies the interpolated colour (a material's albedo); [`Vec4::ONE`] for none.
    pub scale: Vec4,
    /// Every fragment's alpha, when it is not interpolated.
    pub alpha: Option<f32>,
}

impl InterpolatedColor {
    /// The colour as the kernels take it, for a triangle with the vertices' `1/w` `inv_w`
    /// and `1 / area2` `inv_area2`.
    #[inline(always)]
    fn perspective(&self, inv_w: [f32; 3], inv_area2: f64) -> PerspectiveColor {
        PerspectiveColor {
            colors: self.colors.map(|c| c.to_array()),
            scale: self.scale.to_array(),
            alpha: self.alpha,
            inv_w,
            inv_area2,
        }
    }
}

/// The fragment shader that outputs the interpolated vertex colour: linear RGBA (`Vec4`
/// varyings), or linear RGB, opaque (`Vec3`). The tiled backend shades it in SIMD kernels
/// ([`FragmentShader::interpolated_color`]), which are much faster than a closure computing
/// the same: use it for Gouraud-shaded and vertex-coloured meshes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VertexColor;

impl FragmentShader<Vec4> for VertexColor {
    fn shade(&self, f: &Fragment<Vec4>) -> Option<Vec4> {
        Some(f.varyings)
    }

    fn may_discard(&self) -> bool {
        false
    }

    fn interpolated_color(&self, v: [&Vec4; 3], _: u32) -> Option<InterpolatedColor> {
        Some(InterpolatedColor { colors: v.map(|c| *c), scale: Vec4::ONE, alpha: None })
    }
}

impl FragmentShader<Vec3> for VertexColor {
    fn shade(&self, f: &Fragment<Vec3>) -> Option<Vec4> {
        Some(f.varyings.extend(1.0))
    }

    fn may_discard(&self) -> bool {
        false
    }

    fn interpolated_color(&self, v: [&Vec3; 3], _: u32) -> Option<InterpolatedColor> {
        let colors = v.map(|c| c.extend(0.0));
        Some(InterpolatedColor { colors, scale: Vec4::ONE, alpha: Some(1.0) })
    }
}

/// Which faces to discard.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FaceCull {
    /// Keep everything.
    None,
    /// Discard triangles facing away from the camera (clockwise in NDC).
    #[default]
    Back,
    /// Discard triangles facing the camera.
    Front,
}

/// Fixed-function state of the 3D pipeline.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Pipeline {
    /// Faces to discard (default: back faces; counter-clockwise in NDC is front).
    pub cull: FaceCull,
    /// Depth comparison (default: less).
    pub depth_test: DepthTest,
    /// Coverage algorithm.
    pub algorithm: Algorithm,
    /// Reference or tiled execution (bit-identical results).
    pub backend: Backend,
    /// How the tiled backend spreads the work over threads (meshes over 2^20 vertices are
    /// binned whatever it says: each band would shade their vertices again).
    pub schedule: Schedule,
    /// The tiled backend's SIMD level (`None`: the best the CPU has, or `TRIRAST_SIMD`).
    /// Every level draws the same pixels.
    pub simd: Option<SimdLevel>,
}

impl Pipeline {
    /// Sets the cull mode.
    #[must_use]
    pub fn with_cull(mut self, cull: FaceCull) -> Self {
        self.cull = cull;
        self
    }

    /// Sets the backend.
    #[must_use]
    pub fn with_backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// Sets the tiled backend's schedule.
    #[must_use]
    pub fn with_schedule(mut self, schedule: Schedule) -> Self {
        self.schedule = schedule;
        self
    }

    /// Sets the depth test.
    #[must_use]
    pub fn with_depth_test(mut self, depth_test: DepthTest) -> Self {
        self.depth_test = depth_test;
        self
    }

    /// Sets the tiled backend's SIMD level (which must be available; a level the CPU lacks
    /// runs scalar code).
    #[must_use]
    pub fn with_simd(mut self, level: SimdLevel) -> Self {
        self.simd = Some(level);
        self
    }

    /// Draws indexed triangles: each vertex of `vertices` through `vertex_shader` once, each
    /// triangle of `triangles` (indices into `vertices`) clipped, rasterized and shaded.
    ///
    /// An index past the end of `vertices` is an error, reported before anything is drawn,
    /// as is a buffer of `target` replaced by one of another length
    /// ([`Target::check_buffers`]). Each call makes a pass over the indices for that check
    /// (and for the ranges drawing needs): [`Pipeline::draw_indexed`] draws a mesh whose
    /// [`IndexBuffer`] has them already.
    pub fn draw<I, VS, FS>(
        &self,
        target: &mut Target,
        vertex_shader: &VS,
        fragment_shader: &FS,
        vertices: &[I],
        triangles: &[[u32; 3]],
    ) -> Result<DrawStats, Error>
    where
        I: Sync,
        VS: VertexShader<I>,
        FS: FragmentShader<VS::Varyings>,
    {
        let level = self.simd.unwrap_or_else(SimdLevel::detect);
        let ranges = chunk_ranges(level, triangles);
        let indices = Indices::new(triangles, &ranges);
        self.draw_indices(target, vertex_shader, fragment_shader, vertices, indices)
    }

    /// [`Pipeline::draw`] with the index ranges `triangles` keeps: the same pixels and
    /// errors, without a pass over the indices.
    pub fn draw_indexed<I, VS, FS>(
        &self,
        target: &mut Target,
        vertex_shader: &VS,
        fragment_shader: &FS,
        vertices: &[I],
        triangles: &IndexBuffer,
    ) -> Result<DrawStats, Error>
    where
        I: Sync,
        VS: VertexShader<I>,
        FS: FragmentShader<VS::Varyings>,
    {
        let indices = triangles.indices();
        self.draw_indices(target, vertex_shader, fragment_shader, vertices, indices)
    }

    /// [`Pipeline::draw`], given the index range of each chunk of the triangles.
    fn draw_indices<I, VS, FS>(
        &self,
        target: &mut Target,
        vertex_shader: &VS,
        fragment_shader: &FS,
        vertices: &[I],
        indices: Indices<'_>,
    ) -> Result<DrawStats, Error>
    where
        I: Sync,
        VS: VertexShader<I>,
        FS: FragmentShader<VS::Varyings>,
    {
        target.set_schedule(None);
        target.check_buffers()?;
        let triangles = indices.triangles;
        // Small meshes: every vertex shaded once, up front. Large ones: per batch of
        // triangles (below), so memory stays bounded whatever the mesh size.
        let whole = vertices.len() <= VERTEX_CACHE;
        let level = self.simd.unwrap_or_else(SimdLevel::detect);
        // The batches `bin::pipelined` will cut (given this length, it cuts the same), and
        // each one's index range, which sizes its vertex window below.
        let batch_len = bin::even_batch_len(triangles.len(), batch::<VS::Varyings>());
        let index_ranges: Vec<(u32, u32)> = if whole {
            Vec::new()
        } else {
            let end = |start: usize| (start + batch_len).min(triangles.len());
            let starts = (0..triangles.len()).step_by(batch_len);
            starts.map(|start| indices.range(level, start..end(start))).collect()
        };
        // The largest index validates them all; the first bad triangle is searched for only
        // when there is one.
        if let Some(largest) = indices.largest
            && largest as usize >= vertices.len()
            && let Some((t, &bad)) = triangles
                .iter()
                .enumerate()
                .find(|(_, t)| t.iter().any(|&i| i as usize >= vertices.len()))
        {
            return Err(Error::IndexOutOfRange {
                triangle: t,
                indices: bad,
                vertices: vertices.len(),
            });
        }
        let front = FrontEnd {
            coverage: bin::Coverage {
                clip: target.rect(),
                multisampled: target.samples().count() > 1,
            },
            samples: target.samples(),
            volume: ClipVolume::for_target(target.width(), target.height()),
            viewport: Viewport::of(target),
            cull: match self.cull {
                FaceCull::None => CullMode::None,
                // The viewport's y flip keeps the picture upright, so a triangle
                // counter-clockwise in NDC is counter-clockwise on the image too.
                FaceCull::Back => CullMode::Clockwise,
                FaceCull::Front => CullMode::CounterClockwise,
            },
        };
        let shade_vertex = |v: &I| {
            let (position, varyings) = vertex_shader.shade(v);
            front.vertex(ClipVertex { position, varyings })
        };
        // A vertex's clip-space position again, for the few triangles that are clipped.
        let position = |i: u32| vertex_shader.shade(&vertices[i as usize]).0;
        // Buffers a previous draw call on this target left: refilled, not reallocated (fresh
        // vectors had their pages faulted in and zeroed by the kernel every frame).
        let mut scratch: Scratch<VS::Varyings> = target.take_scratch();
        let Scratch { shaded, window, rows, prepared } = &mut scratch;
        // The tiled backend's corner tests read a window of corners, written in the same pass
        // as the vertices: a pass of its own read every shaded vertex back (a fortieth of a
        // frame of a grid mesh of small triangles).
        if whole && self.backend == Backend::Tiled {
            let n = vertices.len();
            if shaded.len() >= n {
                // Overwritten in place (buffers kept from a draw of a mesh at least as long):
                // faster than collecting both (grid, one thread: 71-78 against 79-81 ms), and
                // eight vertices at a time.
                shaded.truncate(n);
                window.truncate(n);
                window.resize(n, OUTSIDE);
                shaded
                    .par_chunks_mut(VERTEX_CHUNK)
                    .zip(window.par_chunks_mut(VERTEX_CHUNK))
                    .zip(vertices.par_chunks(VERTEX_CHUNK))
                    .for_each(|((shaded, corners), vertices)| {
                        let eights = shaded.chunks_exact_mut(8).zip(corners.chunks_exact_mut(8));
                        let input = vertices.chunks_exact(8);
                        let at = vertices.len() - input.remainder().len();
                        for ((s, c), v) in eights.zip(input) {
                            front.vertices(level, v, s, c, |v| vertex_shader.shade(v));
                        }
                        let ends = shaded[at..].iter_mut().zip(&mut corners[at..]);
                        for ((s, c), v) in ends.zip(&vertices[at..]) {
                            *s = shade_vertex(v);
                            *c = s.corner();
                        }
                    });
            } else {
                // Collected (there is no value to fill longer buffers with first).
                let both = |v| {
                    let s = shade_vertex(v);
                    (s, s.corner())
                };
                vertices.par_iter().map(both).unzip_into_vecs(shaded, window);
            }
        } else if whole {
            vertices.par_iter().map(shade_vertex).collect_into_vec(shaded);
        } else {
            shaded.clear();
        }
        let shaded = &*shaded;
        let want_normal = target.normals.is_some();
        // What the tile loop will bin for, so that batches are binned as they are prepared.
        let bin_target = bin::BinTarget::of(target, self.depth_test);
        // Kernels write no normals. Multisampled, they compute a pixel's colour once per
        // sample lane, where the fragment stage computes it once per pixel: the Gouraud
        // bunny at 4x was 10-15% slower with them. The span and narrow kernels' four lanes
        // a step (AVX2) pay more for their gathers and divisions than the fragment stage
        // does (the bunny on one thread: 11.3 ms through the stage, 14.2 ms through the AVX2
        // kernels), so AVX-512 only; the small kernel packs eight pixels of any triangles
        // per step at AVX2 too.
        let single = target.samples().count() == 1;
        // The small kernel takes a 4x target too (it computes a pixel's colour once,
        // `simd::shade_small_samples`), without an overdraw buffer.
        let small_samples = target.samples() == simd::SMALL_SAMPLES && target.overdraw.is_none();
        let small = (!want_normal && (single || small_samples))
            .then_some(level)
            .filter(|&l| l >= SimdLevel::Avx2 && l.is_available());
        let kernel = small.filter(|&l| single && l == SimdLevel::Avx512);
        let shade = ShaderStage { shader: fragment_shader, want_normal, kernel, small, level };
        let mut stats = DrawStats { submitted: triangles.len(), ..DrawStats::default() };
        let count = |stats: &mut DrawStats, r: &Result<_, Skipped>| match r {
            Ok(_) => stats.rasterized += 1,
            Err(why) => stats.skip(*why),
        };
        match self.backend {
            Backend::Reference => {
                for (id, tri) in triangles.iter().enumerate() {
                    let owned = (!whole).then(|| tri.map(|i| shade_vertex(&vertices[i as usize])));
                    let input = match &owned {
                        Some(v) => v.each_ref(),
                        None => tri.map(|i| &shaded[i as usize]),
                    };
                    front.prepare(
                        input,
                        || tri.map(position),
                        id,
                        |r, how| {
                            match how {
                                Count::Triangle => count(&mut stats, &r),
                                Count::Piece => stats.extra_pieces += 1,
                            }
                            let Ok(p) = r else { return };
                            stats.fragments += shade::shade_triangle(
                                &mut target.band(),
                                &p.setup,
                                self.algorithm,
                                &front.coverage.clip,
                                &p.depth,
                                self.depth_test,
                                p.id,
                                None,
                                // One fragment at a time: the definition the tiled backend's
                                // lanes are held to.
                                |x, y, e1, e2, z| shade.fragment(&p.payload, x, y, e1, e2, z),
                            );
                        },
                    );
                }
            }
            Backend::Tiled => {
                // The corner tests read corners from a window of them: for a small mesh, all
                // its vertices' (written above); for a large one, each batch's index range.
                // Small meshes may take bands instead (vertices shaded up front: each band
                // reads them; a large mesh's are shaded batch by batch).
                let threads = rayon::current_num_threads();
                let plan = if whole {
                    let corners = |k: usize| triangles[k].map(|i| window[i as usize]);
                    let clip = &front.coverage.clip;
                    band::plan(
                        self.schedule,
                        triangles.len(),
                        (target.height(), target.samples().count()),
                        clip,
                        (threads, &target.balance),
                        |k| corner_bounds(corners(k), front.cull),
                    )
                } else {
                    band::Plan::Binned
                };
                target.set_schedule(Some(plan.schedule()));
                if let band::Plan::Banded(bands) = plan {
                    // Where each chunk's triangles can reach, from their vertices' rows (one
                    // band skips nothing: no rows, every chunk unbounded).
                    if threads > 1 {
                        vertex_rows(window, rows);
                    } else {
                        rows.clear();
                    }
                    let rows = &*rows;
                    // `Bands::draw` cuts the chunks the index ranges were found for.
                    let chunk_rows = |range: std::ops::Range<usize>| {
                        debug_assert!(range.start.is_multiple_of(bin::CHUNK), "a chunk's start");
                        chunk_rows(*indices.ranges.get(range.start / bin::CHUNK)?, rows)
                    };
                    // Small triangles' kernel colours, where the stage shades in kernels.
                    let colors =
                        |v: [&_; 3], primitive| fragment_shader.interpolated_color(v, primitive);
                    let colors = small.map(|_| &colors);
                    let (counts, covered) = bands.draw(
                        target,
                        front.coverage,
                        self.depth_test,
                        (|_| None, None),
                        shade,
                        |range, sink| {
                            // The band's rows are the clip rectangle.
                            let front = FrontEnd { coverage: sink.coverage(), ..front };
                            let vertex = |i: u32| &shaded[i as usize];
                            // Shaded vertices fetched ahead where the chunk's are stored
                            // together (see `VERTICES_AHEAD`).
                            let together = indices
                                .ranges
                                .get(range.start / bin::CHUNK)
                                .is_some_and(|&(lo, hi)| hi - lo <= TOGETHER_AT_MOST);
                            let ahead = together.then_some(&shaded[..]);
                            let source = (window.as_slice(), 0, vertex, position);
                            let out = (sink, colors);
                            front.prepare_range(triangles, range, 0, source, (level, ahead), out);
                        },
                        chunk_rows,
                    );
                    stats = stats.merged(&counts);
                    stats.fragments += covered;
                    target.keep_scratch(scratch);
                    return Ok(stats);
                }
                let mut counts = DrawStats::default();
                let mut fragments = 0;
                let prepare = |b: usize, first, batch: &[_], out: &mut bin::PreparedBatch<_>| {
                    // Vertices of a large mesh: the batch's index range shaded into a scratch
                    // window when it is compact (meshes are mostly stored with locality),
                    // otherwise each corner shaded where it is used. A window of at most
                    // VERTEX_CACHE vertices: a batch (at most 1M triangles) of a mesh stored
                    // with locality spans fewer. (A small mesh's vertices were all shaded up
                    // front, and it has no batch ranges.)
                    let windowed = index_ranges
                        .get(b)
                        .copied()
                        .filter(|&(lo, hi)| !whole && (hi - lo) as usize <= VERTEX_CACHE);
                    // Only positions: most triangles of a large mesh stop at the corner
                    // tests, and the few that go on shade their three vertices again.
                    if let Some((lo, hi)) = windowed {
                        let span = &vertices[lo as usize..=hi as usize];
                        // Every element is written below.
                        window.resize(span.len(), OUTSIDE);
                        window
                            .par_chunks_mut(CORNER_BLOCK)
                            .zip(span.par_chunks(CORNER_BLOCK))
                            .for_each(|(out, input)| {
                                let mut positions = [Vec4::ZERO; CORNER_BLOCK];
                                for (p, v) in positions.iter_mut().zip(input) {
                                    *p = vertex_shader.shade(v).0;
                                }
                                let positions = &positions[..input.len()];
                                simd::window_corners(
                                    level,
                                    positions,
                                    &front.volume,
                                    &front.viewport,
                                    out,
                                );
                            });
                    }
                    let batch_counts =
                        out.prepare_ranges(batch.len(), front.coverage, |range, sink| {
                            if whole {
                                // Vertices by reference: a triangle reads its corners in place.
                                let vertex = |i: u32| &shaded[i as usize];
                                let source = (window.as_slice(), 0, vertex, position);
                                let out = (sink, None::<&fn([&_; 3], u32) -> _>);
                                // No vertices prefetched (see `VERTICES_AHEAD`).
                                let kernels = (level, None);
                                front.prepare_range(batch, range, first, source, kernels, out);
                            } else if let Some((lo, _)) = windowed {
                                // Its corner is known: inside, only depth and `1 / w` to find.
                                let vertex = |i: u32| {
                                    let (position, varyings) =
                                        vertex_shader.shade(&vertices[i as usize]);
                                    let corner = window[(i - lo) as usize];
                                    front.vertex_at(ClipVertex { position, varyings }, corner)
                                };
                                let source = (window.as_slice(), lo, vertex, position);
                                let out = (sink, None::<&fn([&_; 3], u32) -> _>);
                                // No vertices prefetched (see `VERTICES_AHEAD`).
                                let kernels = (level, None);
                                front.prepare_range(batch, range, first, source, kernels, out);
                            } else {
                                for k in range {
                                    // Shaded once: the positions are at hand for clipping.
                                    let out = batch[k]
                                        .map(|i| vertex_shader.shade(&vertices[i as usize]));
                                    let owned = out.map(|(position, varyings)| {
                                        front.vertex(ClipVertex { position, varyings })
                                    });
                                    let positions = || out.map(|(position, _)| position);
                                    let take = |p, how| sink.take_piece(p, how);
                                    front.prepare(owned.each_ref(), positions, first + k, take);
                                }
                            }
                        });
                    counts = counts.merged(&batch_counts);
                    // Binned here, except the first batch (see `PreparedBatch::bin`) and a
                    // large mesh's batches (its front end, the corner tests, is the busier
                    // side).
                    if b > 0 && whole {
                        out.bin(bin_target);
                    }
                };
                let draw = |_, prepared: &bin::PreparedBatch<_>| {
                    fragments += bin::draw_binned(
                        target,
                        prepared,
                        self.depth_test,
                        |_| None,
                        shade,
                        fragment_shader.may_discard(),
                        None,
                    );
                };
                bin::pipelined(triangles, batch_len, prepared, prepare, draw);
                stats = stats.merged(&counts);
                stats.fragments += fragments;
            }
        }
        target.keep_scratch(scratch);
        Ok(stats)
    }
}

/// Vertices shaded at a time into a batch's window of corners: their positions (16 KB) stay
/// in the L1 cache for [`simd::window_corners`].
const CORNER_BLOCK: usize = 1024;

/// Meshes with at most this many vertices have them all shaded before any triangle; larger
/// ones are shaded batch by batch, bounding memory.
const VERTEX_CACHE: usize = 1 << 20;

/// Vertices per task of the vertex pass of a small mesh.
const VERTEX_CHUNK: usize = 4096;

/// What [`Pipeline::draw`] keeps on the target between draw calls with the same varyings.
struct Scratch<V> {
    /// A small mesh's shaded vertices.
    shaded: Vec<ShadedVertex<V>>,
    /// The corners the corner tests read (all a small mesh's, or a batch's index range).
    window: Vec<Corner>,
    /// For the banded schedule, the rows of each block of a small mesh's vertices
    /// ([`vertex_rows`]).
    rows: Vec<Option<[i32; 2]>>,
    /// The tiled backend's set-up triangles: one batch being drawn, the next being prepared.
    prepared: bin::PreparedPair<Prepared<TriangleData<V>>>,
}

impl<V> Default for Scratch<V> {
    fn default() -> Self {
        Self {
            shaded: Vec::new(),
            window: Vec::new(),
            rows: Vec::new(),
            prepared: Default::default(),
        }
    }
}

/// Triangles per batch of the binned schedule, for varyings `V` (the records' size).
fn batch<V>() -> usize {
    bin::batch_for::<Prepared<TriangleData<V>>>()
}

/// What the fragment stage needs of one (possibly clipped) triangle.
#[derive(Clone, Copy, Debug)]
struct TriangleData<V> {
    /// The vertices' varyings, as three fields rather than an array: built from three
    /// vertices, an array was copied with loads straddling the stores that had just built it,
    /// which waited for them (store forwarding failed; grid, one thread: 91 -> 89 ms).
    varyings0: V,
    varyings1: V,
    varyings2: V,
    /// The vertices' `1/w` as they come (`f32`): widened where they are used, which is exact,
    /// so records are 16 bytes smaller than with them kept as `f64` (grid, one thread: 129 ->
    /// 125 ms).
    inv_w: [f32; 3],
    inv_area2: f64,
    front_facing: bool,
    primitive: u32,
}

impl<V> TriangleData<V> {
    /// The vertices' `1/w`, as the perspective weights take them.
    #[inline(always)]
    fn inv_w_f64(&self) -> [f64; 3] {
        let [a, b, c] = self.inv_w;
        [f64::from(a), f64::from(b), f64::from(c)]
    }
}

impl<V: Varyings> TriangleData<V> {
    /// Its fragment at pixel `(x, y)` with depth `z` and perspective-correct weights `w`.
    #[inline(always)]
    fn fragment(&self, x: i32, y: i32, z: f32, w: [f32; 3]) -> Fragment<V> {
        let (a, b, c) = (&self.varyings0, &self.varyings1, &self.varyings2);
        Fragment {
            x,
            y,
            depth: z,
            varyings: V::weighted(a, b, c, w),
            front_facing: self.front_facing,
            primitive: self.primitive,
        }
    }
}

/// The pipeline's fragment stage: perspective-correct varyings, the fragment shader, sRGB
/// encoding. Copied into each draw of a batch (it holds a reference, whatever the shader).
struct ShaderStage<'a, FS> {
    shader: &'a FS,
    want_normal: bool,
    /// The level the kernels shade at, where the shader's colours allow it
    /// ([`FragmentShader::interpolated_color`]); `None`: never.
    kernel: Option<SimdLevel>,
    /// The level the small kernel ([`simd::shade_small_eight`]) shades at, on the same
    /// condition; `None`: never.
    small: Option<SimdLevel>,
    /// The level lanes of fragments are encoded at ([`simd::srgb8_lanes`]).
    level: SimdLevel,
}

impl<FS> Clone for ShaderStage<'_, FS> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<FS> Copy for ShaderStage<'_, FS> {}

impl<FS> ShaderStage<'_, FS> {
    /// What `fragment`, shaded to linear colour `c`, writes.
    #[inline(always)]
    fn output<V>(&self, fragment: &Fragment<V>, c: Vec4) -> FragmentOutput
    where
        FS: FragmentShader<V>,
    {
        let [r, g, b] = linear_to_srgb8_rgb([c.x, c.y, c.z]);
        FragmentOutput { color: [r, g, b, unorm8(c.w)], normal: self.normal(fragment) }
    }

    /// The normal `fragment` writes, where the target keeps normals.
    #[inline(always)]
    fn normal<V>(&self, fragment: &Fragment<V>) -> Option<[f32; 3]>
    where
        FS: FragmentShader<V>,
    {
        if self.want_normal { self.shader.normal(fragment).map(|n| n.to_array()) } else { None }
    }

    /// Lane `l` of `passed` as a fragment of `t` with perspective-correct weights `w`, shaded:
    /// the body of each loop of [`TriangleFragments::lanes`] and `lanes_of`. Its linear
    /// colour goes to `linear`, for [`ShaderStage::encode_lanes`] to encode with the others';
    /// the output's colour is left for it.
    #[inline(always)]
    fn shade_lane<V: Varyings>(
        &self,
        t: &TriangleData<V>,
        passed: &PassedLanes,
        l: usize,
        w: [f32; 3],
        linear: &mut [f32; 4],
    ) -> Option<FragmentOutput>
    where
        FS: FragmentShader<V>,
    {
        let fragment = t.fragment(passed.x[l], passed.y[l], passed.z[l], w);
        let c = self.shader.shade(&fragment)?;
        *linear = c.to_array();
        Some(FragmentOutput { color: [0; 4], normal: self.normal(&fragment) })
    }

    /// Lanes `..passed.len` of `passed` as fragments, lane `l` of triangle `tri(l)` with
    /// perspective-correct weights `w[..][l]`, shaded together
    /// ([`FragmentShader::shade_lanes`]) and encoded together: the end of
    /// [`TriangleFragments::lanes`] and `lanes_of` for a shader that
    /// [`FragmentShader::shades_lanes`].
    #[inline(always)]
    fn shade_together<'t, V: Varyings>(
        &self,
        passed: &PassedLanes,
        tri: impl Fn(usize) -> &'t TriangleData<V>,
        w: &[[f32; LANES]; 3],
        out: &mut [Option<FragmentOutput>; LANES],
    ) where
        FS: FragmentShader<V>,
    {
        let len = passed.len;
        if len == 0 {
            return;
        }
        let at = |l: usize| {
            let weights = [w[0][l], w[1][l], w[2][l]];
            tri(l).fragment(passed.x[l], passed.y[l], passed.z[l], weights)
        };
        // Lanes past `len` copy the first, and are not shaded.
        let mut fragments = [at(0); LANES];
        for (l, f) in fragments.iter_mut().enumerate().take(len).skip(1) {
            *f = at(l);
        }
        let mut colors = [None; LANES];
        self.shader.shade_lanes(&fragments[..len], &mut colors[..len]);
        let mut linear = [[0.0; 4]; LANES];
        for l in 0..len {
            out[l] = colors[l].map(|c| {
                linear[l] = c.to_array();
                FragmentOutput { color: [0; 4], normal: self.normal(&fragments[l]) }
            });
        }
        self.encode_lanes(&linear, out);
    }

    /// `t`'s colour as the kernels at `level` take it, where the shader gives one
    /// ([`FragmentShader::interpolated_color`]).
    #[inline(always)]
    fn kernel_color<V: Varyings>(
        &self,
        level: SimdLevel,
        t: &TriangleData<V>,
    ) -> Option<(SimdLevel, SpanColor)>
    where
        FS: FragmentShader<V>,
    {
        let varyings = [&t.varyings0, &t.varyings1, &t.varyings2];
        let c = self.shader.interpolated_color(varyings, t.primitive)?;
        Some((level, SpanColor::Perspective(c.perspective(t.inv_w, t.inv_area2))))
    }

    /// The colours of lanes `out` shaded (by [`ShaderStage::shade_lane`]) from their linear
    /// colours `linear`, all eight encoded at once ([`simd::srgb8_lanes`]; lanes past those
    /// in use encode leftovers, and are not read).
    #[inline(always)]
    fn encode_lanes(&self, linear: &[[f32; 4]; LANES], out: &mut [Option<FragmentOutput>; LANES]) {
        let colors = simd::srgb8_lanes(self.level, linear);
        for (out, color) in out.iter_mut().zip(colors) {
            if let Some(out) = out {
                out.color = color.to_le_bytes();
            }
        }
    }
}

impl<V, FS> TriangleFragments<TriangleData<V>> for ShaderStage<'_, FS>
where
    V: Varyings,
    FS: FragmentShader<V>,
{
    /// Always inlined: called out of line, its result went back through the stack, written
    /// field by field and read back wider, which store forwarding cannot serve (grid at 4x,
    /// two threads: 118-125 -> 110-113 ms; bunny 21.8-22.2 -> 20.9-21.2 ms).
    #[inline(always)]
    fn fragment(
        &self,
        t: &TriangleData<V>,
        x: i32,
        y: i32,
        e1: f64,
        e2: f64,
        z: f32,
    ) -> Option<FragmentOutput> {
        let w = perspective_weights(e1 * t.inv_area2, e2 * t.inv_area2, t.inv_w_f64());
        let fragment = t.fragment(x, y, z, w);
        let c = self.shader.shade(&fragment)?;
        Some(self.output(&fragment, c))
    }

    #[inline(always)]
    fn span_color(&self, t: &TriangleData<V>) -> Option<(SimdLevel, SpanColor)> {
        self.kernel_color(self.kernel?, t)
    }

    #[inline(always)]
    fn span_colors(&self) -> bool {
        self.kernel.is_some()
    }

    #[inline(always)]
    fn small_color(&self, t: &TriangleData<V>) -> Option<(SimdLevel, SpanColor)> {
        self.kernel_color(self.small?, t)
    }

    #[inline(always)]
    fn small_colors(&self) -> bool {
        self.small.is_some()
    }

    #[inline(always)]
    fn shades_lanes(&self) -> bool {
        self.shader.shades_lanes()
    }

    #[inline(always)]
    fn defers_colour(&self) -> bool {
        self.shader.shades_lanes() && !self.shader.may_discard()
    }

    /// [`TriangleFragments::fragment`] of each lane. With perspective, the weights of all
    /// lanes first: one loop of divisions, which pipeline, rather than three divisions
    /// waiting in each fragment's chain (see docs/design-log.md, `shade`). Affine triangles need
    /// no division, and compute their weights lane by lane.
    fn lanes(
        &self,
        t: &TriangleData<V>,
        passed: &PassedLanes,
        out: &mut [Option<FragmentOutput>; LANES],
    ) {
        let q = t.inv_w_f64();
        if self.shader.shades_lanes() {
            let mut w = [[0.0f32; LANES]; 3];
            let numerators = passed.e1.iter().zip(&passed.e2).take(passed.len);
            for (l, (e1, e2)) in numerators.enumerate() {
                [w[0][l], w[1][l], w[2][l]] =
                    perspective_weights(e1 * t.inv_area2, e2 * t.inv_area2, q);
            }
            return self.shade_together(passed, |_| t, &w, out);
        }
        if is_affine(q) {
            // No division: the weights are the screen-space ones, computed where they are used.
            // (One loop for both kinds, taking its weights from a closure, made the grid 7%
            // slower, so each kind has its loop around `shade_lane`.)
            let mut linear = [[0.0; 4]; LANES];
            for (l, out) in out.iter_mut().enumerate().take(passed.len) {
                let (l1, l2) = (passed.e1[l] * t.inv_area2, passed.e2[l] * t.inv_area2);
                *out = self.shade_lane(t, passed, l, affine_weights(l1, l2), &mut linear[l]);
            }
            self.encode_lanes(&linear, out);
            return;
        }
        // One array per weight, so that each load below reads exactly what one store wrote.
        // As `[[f32; 3]; LANES]`, a lane's weights were stored as 8 + 4 bytes and loaded as
        // 4 + 8, which store forwarding cannot serve: whether that stalled depended on how
        // soon the loads came, which moved with unrelated edits elsewhere (a quarter of this
        // function's time in one build: bunny 6.6 -> 7.6 ms on two threads, the same
        // instructions).
        let mut w = [[0.0f32; LANES]; 3];
        let numerators = passed.e1.iter().zip(&passed.e2).take(passed.len);
        for (l, (e1, e2)) in numerators.enumerate() {
            [w[0][l], w[1][l], w[2][l]] = divided_weights(e1 * t.inv_area2, e2 * t.inv_area2, q);
        }
        let mut linear = [[0.0; 4]; LANES];
        for (l, out) in out.iter_mut().enumerate().take(passed.len) {
            *out = self.shade_lane(t, passed, l, [w[0][l], w[1][l], w[2][l]], &mut linear[l]);
        }
        self.encode_lanes(&linear, out);
    }

    /// [`TriangleFragments::lanes`] for lanes of several triangles: each lane's triangle
    /// constants gathered first, then the weights of all lanes in one loop of fixed length
    /// (lanes past `len` compute from leftovers and zeros, and are not read), affine or
    /// divided lane by lane.
    /// The lanes in use always have their triangle; shading `Option::and_then` of it instead
    /// of `expect` made the grid 2% slower.
    fn lanes_of(
        &self,
        tris: &[Option<&TriangleData<V>>; LANES],
        passed: &PassedLanes,
        out: &mut [Option<FragmentOutput>; LANES],
    ) {
        let mut k = [[0.0f64; LANES]; 4];
        for l in 0..passed.len {
            let t = tris[l].expect("a queued lane has its triangle");
            let q = t.inv_w_f64();
            (k[0][l], k[1][l], k[2][l], k[3][l]) = (t.inv_area2, q[0], q[1], q[2]);
        }
        let mut w = [[0.0f32; LANES]; 3];
        for l in 0..LANES {
            let (l1, l2) = (passed.e1[l] * k[0][l], passed.e2[l] * k[0][l]);
            [w[0][l], w[1][l], w[2][l]] = perspective_weights(l1, l2, [k[1][l], k[2][l], k[3][l]]);
        }
        if self.shader.shades_lanes() {
            let tri = |l: usize| tris[l].expect("a queued lane has its triangle");
            return self.shade_together(passed, tri, &w, out);
        }
        let mut linear = [[0.0; 4]; LANES];
        for (l, out) in out.iter_mut().enumerate().take(passed.len) {
            let t = tris[l].expect("a queued lane has its triangle");
            *out = self.shade_lane(t, passed, l, [w[0][l], w[1][l], w[2][l]], &mut linear[l]);
        }
        self.encode_lanes(&linear, out);
    }
}

/// How a piece of a triangle counts in [`DrawStats`]: a triangle clipping cut into pieces
/// counts once, with one of them, as rasterized if any piece reaches the rasterizer (set up,
/// or holding no sample) and otherwise as its first piece's rejection; the others that
/// reach it count as extra pieces ([`DrawStats::extra_pieces`]), and rejected pieces of a
/// rasterized triangle not at all. Whether a piece holds a sample depends on the clip
/// rectangle (a band's, in the banded schedule), which these counts do not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Count {
    /// The piece the triangle is counted with.
    Triangle,
    /// Another piece of a rasterized triangle.
    Piece,
}

/// The fixed-function stages between the vertex shader and the rasterizer.
#[derive(Clone, Copy)]
struct FrontEnd {
    /// The pixels that may be drawn, and whether the target is multisampled.
    coverage: bin::Coverage,
    /// The target's sample pattern.
    samples: SampleCount,
    volume: ClipVolume,
    viewport: Viewport,
    cull: CullMode,
}

/// A vertex out of the vertex shader with what every triangle using it needs, computed once
/// per vertex rather than once per corner: its outcode and, inside the clip volume, its
/// window position snapped to the fixed-point grid.
#[derive(Clone, Copy, Debug)]
struct ShadedVertex<V> {
    /// The vertex shader's varyings. Not its position, which only clipping reads (the
    /// vertices of a triangle to clip are shaded again): the vertex pass writes these and
    /// the bands read them back from memory: 32 bytes with an RGB colour (48 with RGBA),
    /// where a position and a nested `ClipVertex` had made 64.
    varyings: V,
    outcode: u8,
    /// Snapped window `x`, `y` (valid when `outcode == 0` and `snapped`).
    xy: [i32; 2],
    /// Window depth and `1/w` (valid when `outcode == 0`).
    z: f32,
    inv_w: f32,
    /// The window position was finite and in the fixed-point range (always, inside the clip
    /// volume; kept so that a violation is a rejection, not a wrong picture).
    snapped: bool,
}

impl<V> ShadedVertex<V> {
    /// The vertex as the corner tests see it ([`simd::window_corner`]).
    fn corner(&self) -> Corner {
        if self.outcode == 0 && self.snapped { self.xy } else { OUTSIDE }
    }
}

impl FrontEnd {
    /// Eight vertices through `shade` (the vertex shader) and then, at `level`, their
    /// outcodes, viewport and snap together ([`simd::window_vertices`]; one at a time,
    /// [`FrontEnd::vertex`], below AVX2), into `out` with their corners in `corners`.
    #[inline]
    fn vertices<I, V: Varyings>(
        &self,
        level: SimdLevel,
        input: &[I],
        out: &mut [ShadedVertex<V>],
        corners: &mut [Corner],
        shade: impl Fn(&I) -> (Vec4, V),
    ) {
        let mut positions = [Vec4::ZERO; 8];
        for ((p, s), v) in positions.iter_mut().zip(out.iter_mut()).zip(input) {
            let (position, varyings) = shade(v);
            *p = position;
            s.varyings = varyings;
        }
        let Some(w) = simd::window_vertices(level, &positions, &self.volume, &self.viewport) else {
            for ((s, c), &position) in out.iter_mut().zip(corners).zip(&positions) {
                *s = self.vertex(ClipVertex { position, varyings: s.varyings });
                *c = s.corner();
            }
            return;
        };
        for (k, (s, c)) in out.iter_mut().zip(corners).enumerate() {
            (s.outcode, s.xy, s.z, s.inv_w) = (w.outcode[k], w.xy[k], w.z[k], w.inv_w[k]);
            s.snapped = w.snapped & (1 << k) != 0;
            *c = s.corner();
        }
    }

    /// [`FrontEnd::vertex`] of a vertex whose window corner ([`simd::window_corner`] of its
    /// position) is `corner`: a corner other than `OUTSIDE` says the outcode is 0 and the
    /// snap succeeded, with that result, so only depth and `1 / w` are computed (the dense
    /// scene's triangles that pass the corner tests shade their vertices again; their
    /// outcodes and snaps had been 5% of its samples).
    #[inline]
    fn vertex_at<V: Varyings>(&self, clip: ClipVertex<V>, corner: Corner) -> ShadedVertex<V> {
        if corner == OUTSIDE {
            return self.vertex(clip);
        }
        let Vertex { z, inv_w, .. } = self.viewport.map(clip.position);
        debug_assert!(
            {
                let full = self.vertex(clip);
                (full.outcode, full.xy, full.z.to_bits(), full.inv_w.to_bits())
                    == (0, corner, z.to_bits(), inv_w.to_bits())
            },
            "a corner that is not the vertex's own"
        );
        let varyings = clip.varyings;
        ShadedVertex { varyings, outcode: 0, xy: corner, z, inv_w, snapped: true }
    }

    /// Outcode, viewport and snap of one shaded vertex.
    fn vertex<V: Varyings>(&self, clip: ClipVertex<V>) -> ShadedVertex<V> {
        let outcode = self.volume.outcode(clip.position);
        let mut v = ShadedVertex {
            varyings: clip.varyings,
            outcode,
            xy: [0; 2],
            z: 0.0,
            inv_w: 0.0,
            snapped: false,
        };
        if outcode == 0
            && let Some((xy, z, inv_w)) = self.viewport.map_snapped(clip.position)
        {
            (v.xy, v.z, v.inv_w, v.snapped) = (xy, z, inv_w, true);
        }
        v
    }

    /// [`FrontEnd::prepare`] for triangles `range` of `batch` (whose first has id
    /// `first_id`); vertex `i`'s corner is `corners[i - base]`, and `vertex(i)` gives it as
    /// setup needs it. Triangles inside the clip volume take the corner tests eight at a time
    /// ([`simd::corner_tests_indexed`]; multisampled, each sample position's box test): in a
    /// dense mesh nearly all stop there, counted, before their vertices are read; those that
    /// pass go straight to setup (as `setup_inside` would after the same tests), and those
    /// needing clipping through `prepare`. `ahead`: the shaded vertices `vertex` reads, to
    /// prefetch [`VERTICES_AHEAD`] triangles ahead.
    fn prepare_range<V: Varyings, R: Borrow<ShadedVertex<V>>, C>(
        &self,
        batch: &[[u32; 3]],
        range: std::ops::Range<usize>,
        first_id: usize,
        (corners, base, vertex, position): (
            &[Corner],
            u32,
            impl Fn(u32) -> R,
            impl Fn(u32) -> Vec4,
        ),
        (level, ahead): (SimdLevel, Option<&[ShadedVertex<V>]>),
        (sink, colors): (&mut Sink<'_, Prepared<TriangleData<V>>>, Option<&C>),
    ) where
        C: Fn([&V; 3], u32) -> Option<InterpolatedColor>,
    {
        let vertices = |k: usize| batch[k].map(&vertex);
        // A whole group's corners, as the corner tests leave them.
        let mut rows = CornerGroup::default();
        for start in range.clone().step_by(8) {
            let len = (range.end - start).min(8);
            if let Some(shaded) = ahead {
                for t in [start + VERTICES_AHEAD, start + VERTICES_AHEAD + 4] {
                    for v in
                        batch.get(t).into_iter().flatten().filter_map(|&i| shaded.get(i as usize))
                    {
                        simd::prefetch(v);
                    }
                }
            }
            // A whole group: its corner tests leave `rows`, and it may be a small run.
            let whole = <&[[u32; 3]; 8]>::try_from(&batch[start..start + len]).ok();
            let t = if let Some(eight) = whole {
                let (clip, group) = (&self.coverage.clip, (eight, corners, base));
                simd::corner_tests_indexed(level, group, self.cull, clip, self.samples, &mut rows)
            } else {
                let mut group = CornerGroup::default();
                for j in 0..len {
                    group.set(j, batch[start + j].map(|i| corners[(i - base) as usize]));
                }
                let clip = &self.coverage.clip;
                simd::corner_tests(level, &group, self.cull, clip, self.samples)
            };
            let count = |bits: u8| bits.count_ones() as usize;
            sink.skip_many(Skipped::Rejected(Rejection::Degenerate), count(t.degenerate));
            sink.skip_many(Skipped::Rejected(Rejection::Culled), count(t.culled));
            sink.skip_many(Skipped::Empty, count(t.empty));
            // Those that passed the tests, and those with a corner outside (to be clipped).
            let live = ((1u32 << len) - 1) as u8;
            let mut rest = (!(t.degenerate | t.culled | t.empty)) & live;
            // Small triangles inside the clip volume, straight into kernel lanes (`colors`
            // come only with kernels, which shade at the front end's level).
            if let Some(colors) = colors
                && rest != 0
                && rest & !t.inside == 0
                && let Some(eight) = whole
                && let Some(mut run) = sink.small_run()
            {
                let (source, lanes) = ((eight, &rows, &vertex), (start, rest, first_id));
                if self.small_run(source, lanes, (colors, level), &mut run) {
                    run.finish(level, rest.count_ones() as usize);
                    continue;
                }
            }
            // The records after these ones' start loading (see `Sink::prefetch`); nothing to
            // do when none passes (most of a dense mesh's groups).
            if rest != 0 {
                sink.prefetch(count(rest), 8);
            }
            while rest != 0 {
                let j = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let k = start + j;
                if t.inside & (1 << j) != 0 {
                    // Passed the corner tests: straight to setup.
                    let owned = vertices(k);
                    let tri = each_ref(&owned);
                    let xy = snapped(tri);
                    match TriangleSetup::from_snapped(xy, self.cull) {
                        Ok(setup) => sink.push(self.finish_passed(setup, tri, first_id + k)),
                        Err(why) => sink.skip_many(why.into(), 1),
                    }
                } else {
                    let positions = || batch[k].map(&position);
                    let take = |p, how| sink.take_piece(p, how);
                    self.prepare(each_ref(&vertices(k)), positions, first_id + k, take);
                }
            }
        }
    }

    /// Sets up triangles `start + j` for each bit `j` of `rest` as the lanes of `run`, with
    /// the colours `colors` gives: what [`FrontEnd::prepare_range`] and the band loop's small
    /// lanes would compute for them, without setups or records (the boxes, `1 / area2` and
    /// coverage eight at a time, [`simd::small_run_geometry`]). `eight` is the group of
    /// eight from `start` (the batch's first has id `first_id`), whose corners the tests left
    /// in `rows`; those of `rest` passed them, inside the clip volume. False, with `run` to
    /// be dropped, when one has a box over [`simd::SMALL_BOX`] pixels a side or no such
    /// colour.
    #[inline]
    fn small_run<V: Varyings, R: Borrow<ShadedVertex<V>>>(
        &self,
        (eight, rows, vertex): (&[[u32; 3]; 8], &CornerGroup, impl Fn(u32) -> R),
        (start, rest, first_id): (usize, u8, usize),
        (colors, level): (impl Fn([&V; 3], u32) -> Option<InterpolatedColor>, SimdLevel),
        run: &mut bin::SmallRunSetter<'_>,
    ) -> bool {
        // The first lane's colour before the geometry: a shader that gives none (Phong) would
        // have it computed and dropped (6% of the CLI's default render, the bunny at 4x).
        let first = rest.trailing_zeros() as usize;
        let owned = eight.get(first).map(|t| t.map(&vertex));
        let probe = owned.as_ref().map(each_ref).and_then(|[a, b, c]| {
            colors([&a.varyings, &b.varyings, &c.varyings], (first_id + start + first) as u32)
        });
        if probe.is_none() {
            return false;
        }
        let (coverage, samples, shading) = run.parts();
        let clip = &self.coverage.clip;
        let geometry = if self.samples.count() > 1 {
            let parts = (coverage, samples, shading);
            simd::small_run_samples_geometry(level, rows, rest, clip, parts)
        } else {
            simd::small_run_geometry(level, rows, rest, clip, coverage, shading)
        };
        if geometry.is_none() {
            return false;
        }
        let (_, _, shading) = run.parts();
        let mut bits = rest;
        while bits != 0 {
            let j = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let owned = eight[j].map(&vertex);
            let [a, b, c] = each_ref(&owned);
            let id = first_id + start + j;
            let varyings = [&a.varyings, &b.varyings, &c.varyings];
            let Some(color) = colors(varyings, id as u32) else { return false };
            let inv_area2 = shading.inv_area2(j);
            let depth = shade::depth_plane([a.z, b.z, c.z], inv_area2);
            let color = color.perspective([a.inv_w, b.inv_w, c.inv_w], inv_area2);
            shading.set_shading(j, &depth, &color, id as i32);
        }
        true
    }

    /// Clip, viewport and setup of triangle `id`: its pieces (the triangle, nothing, or a
    /// clipped fan) go to `emit(piece, count)`, the triangle counted once (see [`Count`]).
    /// `positions` gives the vertices' clip-space positions, asked for only when the
    /// triangle is clipped.
    fn prepare<V: Varyings>(
        &self,
        input: [&ShadedVertex<V>; 3],
        positions: impl FnOnce() -> [Vec4; 3],
        id: usize,
        mut emit: impl FnMut(Result<Prepared<TriangleData<V>>, Skipped>, Count),
    ) {
        if input.iter().all(|v| v.outcode == 0) {
            emit(self.setup_inside(input, id), Count::Triangle);
            return;
        }
        // Rejected before clipping so that a triangle with a NaN or infinite coordinate is
        // counted as non-finite: the clip returns no polygon for it, which counts as culled.
        let positions = positions();
        if !positions.iter().all(|p| p.is_finite()) {
            emit(Err(Skipped::Rejected(Rejection::NonFinite)), Count::Triangle);
            return;
        }
        // Coordinates past 2^100 are scaled down by a power of two (exact): the same
        // triangle, since the projection, depth and perspective weights are ratios of them
        // (only the `w >= MIN_W` plane, a constant, moves with the scale). Unscaled, the
        // clip's pieces would be finite (it works in `f64`), but `1 / w` near `f32::MAX`
        // is subnormal in the viewport's `f32`, and the pieces' depths lost precision.
        let scale = fitting_scale(&positions);
        let polygon = self.volume.clip(std::array::from_fn(|k| ClipVertex {
            position: positions[k] * scale,
            varyings: input[k].varyings,
        }));
        if polygon.is_empty() {
            // Entirely outside the view volume: counted with the culled.
            emit(Err(Skipped::Rejected(Rejection::Culled)), Count::Triangle);
            return;
        }
        // The triangle counts once: as rasterized when a piece is set up or merely holds no
        // sample (which also depends on the clip rectangle, a band's or the target's: the
        // count must not), with the first such piece; otherwise with its first rejection.
        let pieces: Vec<_> = (1..polygon.len() - 1)
            .map(|k| self.setup([polygon[0], polygon[k], polygon[k + 1]], id))
            .collect();
        let reaches = |p: &Result<_, Skipped>| matches!(p, Ok(_) | Err(Skipped::Empty));
        let Some(first) = pieces.iter().position(reaches) else {
            if let Some(Err(why)) = pieces.into_iter().next() {
                emit(Err(why), Count::Triangle);
            }
            return;
        };
        for (k, piece) in pieces.into_iter().enumerate().filter(|(_, p)| reaches(p)) {
            emit(piece, if k == first { Count::Triangle } else { Count::Piece });
        }
    }

    /// Setup of a triangle inside the clip volume, from its vertices' snapped positions: the
    /// same result as [`FrontEnd::setup`] (which snaps the same window coordinates).
    fn setup_inside<V: Varyings>(
        &self,
        tri: [&ShadedVertex<V>; 3],
        id: usize,
    ) -> Result<Prepared<TriangleData<V>>, Skipped> {
        if !tri.iter().all(|v| v.snapped) {
            return Err(Skipped::Rejected(Rejection::NonFinite));
        }
        self.corner_tests(snapped(tri))?;
        self.setup_passed(tri, id)
    }

    /// Zero area, culling and "covers no sample", from the snapped corners alone: most
    /// triangles of a dense mesh stop here, before they are set up. The tests
    /// of [`simd::corner_tests`], one triangle at a time (the reference backend's).
    fn corner_tests(&self, xy: [[i64; 2]; 3]) -> Result<(), Skipped> {
        TriangleSetup::signed_area2(xy, self.cull)?;
        let bin::Coverage { clip, multisampled } = self.coverage;
        debug_assert_eq!(multisampled, self.samples.count() > 1, "coverage for other samples");
        if setup::holds_no_sample(setup::extent(xy), self.samples, &clip) {
            return Err(Skipped::Empty);
        }
        Ok(())
    }

    /// Setup and planes of a snapped triangle inside the clip volume that passed the corner
    /// tests (zero area, culling, no sample in the box).
    fn setup_passed<V: Varyings>(
        &self,
        tri: [&ShadedVertex<V>; 3],
        id: usize,
    ) -> Result<Prepared<TriangleData<V>>, Skipped> {
        let xy = snapped(tri);
        let setup = TriangleSetup::from_snapped(xy, self.cull)?;
        Ok(self.finish_passed(setup, tri, id))
    }

    /// [`FrontEnd::finish`] for a triangle inside the clip volume. Inlined into the loops that
    /// call it, so that the record is built in the batch buffer rather than returned and
    /// copied.
    #[inline]
    fn finish_passed<V: Varyings>(
        &self,
        setup: TriangleSetup,
        tri: [&ShadedVertex<V>; 3],
        id: usize,
    ) -> Prepared<TriangleData<V>> {
        let [a, b, c] = tri;
        let varyings = [&a.varyings, &b.varyings, &c.varyings];
        self.finish(setup, varyings, [[a.z, a.inv_w], [b.z, b.inv_w], [c.z, c.inv_w]], id)
    }

    fn setup<V: Varyings>(
        &self,
        tri: [ClipVertex<V>; 3],
        id: usize,
    ) -> Result<Prepared<TriangleData<V>>, Skipped> {
        let win = tri.map(|v| self.viewport.map(v.position));
        let setup = TriangleSetup::new(&win, self.cull)?;
        if self.coverage.of(&setup).is_none() {
            return Err(Skipped::Empty);
        }
        let varyings = [&tri[0].varyings, &tri[1].varyings, &tri[2].varyings];
        Ok(self.finish(setup, varyings, win.map(|v| [v.z, v.inv_w]), id))
    }

    /// Planes and payload of a set-up triangle that covers a sample (callers have checked);
    /// `z_inv_w` holds each vertex's window depth and `1/w`.
    fn finish<V: Varyings>(
        &self,
        setup: TriangleSetup,
        [v0, v1, v2]: [&V; 3],
        z_inv_w: [[f32; 2]; 3],
        id: usize,
    ) -> Prepared<TriangleData<V>> {
        let inv_area2 = 1.0 / setup.area2 as f64;
        let [a, b, c] = z_inv_w;
        let depth = shade::depth_plane([a[0], b[0], c[0]], inv_area2);
        let payload = TriangleData {
            varyings0: *v0,
            varyings1: *v1,
            varyings2: *v2,
            inv_w: [a[1], b[1], c[1]],
            inv_area2,
            front_facing: !setup.clockwise,
            primitive: id as u32,
        };
        Prepared { setup, depth, id: id as i32, payload }
    }
}

/// Vertices per block of [`vertex_rows`].
const ROW_BLOCK: usize = 256;

/// The most blocks of vertices a chunk's indices may span for [`chunk_rows`] to bound its
/// rows: a mesh in spatial order (the benchmark grid's rows of 1,001 vertices) spans a few;
/// a scattered one is not worth the blocks' reading.
const CHUNK_ROW_BLOCKS: usize = 8;

/// The band loop's front end prefetches the shaded vertices of two triangles this far ahead
/// (the 1st and 5th of the group of eight that many ahead), where a chunk's vertices are
/// stored together ([`TOGETHER_AT_MOST`]). The grid (1M two-pixel triangles of an indexed
/// mesh, its rows in order) read each triangle's depth, `1 / w` and colour from vertices the
/// hardware had not fetched: 5% of its frame (Intel Xeon VM, two threads, median of eight
/// alternated runs' fastest frames, 18.1 -> 17.1 ms). A mesh stored without locality lost as
/// much: the Stanford bunny's chunks span most of its vertices, and prefetching them cost
/// 8% (3.6 -> 3.9 ms), whether to the first- or second-level cache, so they are not.
const VERTICES_AHEAD: usize = 32;

/// The largest span of vertex indices (last less first) of a chunk whose vertices the band
/// loop prefetches ([`VERTICES_AHEAD`]): 16 chunks' worth, 128 KB of shaded vertices.
const TOGETHER_AT_MOST: u32 = 4096;

/// The snapped `y` range (fixed point) of each block of [`ROW_BLOCK`] corners of `window`,
/// or `None` where one is [`OUTSIDE`] (its triangles may be clipped, and a clipped piece can
/// reach rows its corners do not), into `out`, in parallel.
fn vertex_rows(window: &[Corner], out: &mut Vec<Option<[i32; 2]>>) {
    window
        .par_chunks(ROW_BLOCK)
        .map(|block| {
            // A snapped corner lies within the fixed-point range, far from `i32::MIN`, so the
            // least `y` is `i32::MIN` exactly when a corner is `OUTSIDE`: one pass of minima
            // and maxima with no branch per corner (a fold stopping at the first `OUTSIDE`
            // took 0.50 ms of the grid's 21 ms frame on two threads, this 0.36 ms).
            let [lo, hi] =
                block.iter().fold([i32::MAX, i32::MIN], |[lo, hi], c| [lo.min(c[1]), hi.max(c[1])]);
            (lo != OUTSIDE[1]).then_some([lo, hi])
        })
        .collect_into_vec(out);
}

/// The pixel rows the pieces of triangles whose indices lie in `lo..=hi` can reach, from
/// `rows` (their vertices' blocks, [`vertex_rows`]): `None` when a vertex may lie outside the
/// clip volume or the indices span more than [`CHUNK_ROW_BLOCKS`] blocks. A piece of a
/// triangle whose vertices are all inside lies within their snapped box, and a sample of
/// pixel row `p` lies within half a pixel of `256 p + 128`: rows `(y0 >> 8) - 1` to
/// `(y1 >> 8) + 1` hold every sample between `y0` and `y1`.
fn chunk_rows((lo, hi): (u32, u32), rows: &[Option<[i32; 2]>]) -> Option<[i32; 2]> {
    let (first, last) = (lo as usize / ROW_BLOCK, hi as usize / ROW_BLOCK);
    if lo > hi || last - first >= CHUNK_ROW_BLOCKS {
        return None;
    }
    let [y0, y1] = rows.get(first..=last)?.iter().try_fold([i32::MAX, i32::MIN], |acc, r| {
        r.map(|[lo, hi]| [acc[0].min(lo), acc[1].max(hi)])
    })?;
    Some([(y0 >> 8) - 1, (y1 >> 8) + 1])
}

/// A mesh's triangles, as indices into its vertices, with the smallest and largest index of
/// each chunk of 256 triangles (the front end's chunks). The largest index validates the
/// triangles, a batch's range sizes a large mesh's window of shaded vertices, and a chunk's
/// lets a band skip it. [`Pipeline::draw`] finds them in a pass over the indices on every
/// call; a mesh drawn frame after frame keeps them here ([`Pipeline::draw_indexed`]), as GPU
/// drivers keep an index buffer's range (Mesa's min/max cache), and reads its indices once a
/// frame rather than twice: the pass was 50 of the dense scene's 600 ms on two threads.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct IndexBuffer {
    triangles: Vec<[u32; 3]>,
    /// Each chunk's (smallest, largest) index.
    ranges: Vec<(u32, u32)>,
    /// The largest of them all (`None` without triangles), kept: every draw validates with it.
    largest: Option<u32>,
}

impl IndexBuffer {
    /// Finds the index range of each chunk of `triangles` (in parallel).
    #[must_use]
    pub fn new(triangles: Vec<[u32; 3]>) -> Self {
        let ranges = chunk_ranges(SimdLevel::detect(), &triangles);
        let largest = Indices::new(&triangles, &ranges).largest;
        Self { triangles, ranges, largest }
    }

    /// The triangles.
    #[must_use]
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.triangles
    }

    /// The triangles, without the ranges.
    #[must_use]
    pub fn into_triangles(self) -> Vec<[u32; 3]> {
        self.triangles
    }

    /// The largest index (`None` without triangles): vertex arrays longer than it can be drawn
    /// with these triangles.
    #[must_use]
    pub fn largest(&self) -> Option<u32> {
        self.largest
    }

    fn indices(&self) -> Indices<'_> {
        Indices { triangles: &self.triangles, ranges: &self.ranges, largest: self.largest }
    }
}

impl From<Vec<[u32; 3]>> for IndexBuffer {
    fn from(triangles: Vec<[u32; 3]>) -> Self {
        Self::new(triangles)
    }
}

/// Triangles and each chunk's index range, as one draw reads them.
#[derive(Clone, Copy)]
struct Indices<'a> {
    triangles: &'a [[u32; 3]],
    ranges: &'a [(u32, u32)],
    /// The largest index (`None` without triangles).
    largest: Option<u32>,
}

impl<'a> Indices<'a> {
    /// `triangles` with their chunks' `ranges`, whose largest index it finds.
    fn new(triangles: &'a [[u32; 3]], ranges: &'a [(u32, u32)]) -> Self {
        let largest = ranges.iter().map(|r| r.1).max();
        Self { triangles, ranges, largest }
    }

    /// The smallest and largest index of triangles `range` (`(u32::MAX, 0)` when empty): the
    /// chunks it holds whole from their ranges, the rest (under a chunk at each end) read.
    fn range(&self, level: SimdLevel, range: std::ops::Range<usize>) -> (u32, u32) {
        let (first, last) = (range.start.div_ceil(bin::CHUNK), range.end / bin::CHUNK);
        let read =
            |r: std::ops::Range<usize>| simd::index_range(level, self.triangles[r].as_flattened());
        if first >= last {
            return read(range);
        }
        let ends = [read(range.start..first * bin::CHUNK), read(last * bin::CHUNK..range.end)];
        self.ranges[first..last]
            .iter()
            .chain(&ends)
            .fold((u32::MAX, 0), |a, b| (a.0.min(b.0), a.1.max(b.1)))
    }
}

/// The index range of each chunk of [`bin::CHUNK`] triangles, in parallel (a serial pass
/// over the indices was a tenth of a dense mesh's frame on two threads).
fn chunk_ranges(level: SimdLevel, triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    let mut ranges = Vec::new();
    let chunks = triangles.par_chunks(bin::CHUNK);
    chunks.map(|c| simd::index_range(level, c.as_flattened())).collect_into_vec(&mut ranges);
    ranges
}

/// The pixels a triangle's snapped corners reach (`None` when one is outside the clip
/// volume, none when it is culled), for [`band::plan`]'s sample.
fn corner_bounds(corners: [Corner; 3], cull: CullMode) -> Option<PixelRect> {
    if corners.contains(&OUTSIDE) {
        return None;
    }
    let xy = corners.map(|c| c.map(i64::from));
    if TriangleSetup::signed_area2(xy, cull).is_err() {
        // Culled or of zero area: no pixels to draw.
        return Some(PixelRect::EMPTY);
    }
    Some(setup::sample_bounds(setup::extent(xy), [0, 0]))
}

/// The snapped window positions of three vertices, as `i64` for setup.
#[inline]
fn snapped<V>(tri: [&ShadedVertex<V>; 3]) -> [[i64; 2]; 3] {
    setup::widen([tri[0].xy, tri[1].xy, tri[2].xy])
}

/// Three borrowed vertices as references.
fn each_ref<V, R: Borrow<ShadedVertex<V>>>(v: &[R; 3]) -> [&ShadedVertex<V>; 3] {
    [v[0].borrow(), v[1].borrow(), v[2].borrow()]
}

/// Perspective-correct barycentric weights from screen-space ones (`l1`, `l2`; `l0` is the
/// rest) and the vertices' `1/w`. When the three `1/w` are one positive value (an orthographic
/// camera, a mesh given in clip space with `w = 1`), perspective-correct weights are the
/// screen-space ones: returned as they are, without the division per fragment (a twentieth of
/// a frame of a flat grid), differing from what the division would give by rounding only.
#[inline]
pub(crate) fn perspective_weights(l1: f64, l2: f64, q: [f64; 3]) -> [f32; 3] {
    if is_affine(q) { affine_weights(l1, l2) } else { divided_weights(l1, l2, q) }
}

/// [`perspective_weights`] for `1/w` that are not [`is_affine`]: `l_i q_i / sum(l_j q_j)`,
/// thirds for a degenerate sum.
#[inline]
fn divided_weights(l1: f64, l2: f64, q: [f64; 3]) -> [f32; 3] {
    let l0 = 1.0 - l1 - l2;
    let w = [l0 * q[0], l1 * q[1], l2 * q[2]];
    let sum = w[0] + w[1] + w[2];
    if sum > 0.0 {
        [(w[0] / sum) as f32, (w[1] / sum) as f32, (w[2] / sum) as f32]
    } else {
        [1.0 / 3.0; 3]
    }
}

/// Whether the three `1/w` are one positive value, where [`perspective_weights`] are the
/// screen-space ones.
#[inline]
pub(crate) fn is_affine(q: [f64; 3]) -> bool {
    q[0] > 0.0 && q[0] == q[1] && q[1] == q[2]
}

/// The screen-space weights (`l0` the rest), as [`perspective_weights`] gives them for
/// [`is_affine`] `1/w`.
#[inline]
fn affine_weights(l1: f64, l2: f64) -> [f32; 3] {
    [(1.0 - l1 - l2) as f32, l1 as f32, l2 as f32]
}

/// Maps clip space to window space: NDC [-1, 1]^2 x [0, 1] to pixels, row 0 at the top.
#[derive(Clone, Copy, Debug)]
pub struct Viewport {
    half_width: f32,
    half_height: f32,
}

impl Viewport {
    /// The viewport covering the whole target.
    #[must_use]
    pub fn of(target: &Target) -> Self {
        Self::of_size(target.width(), target.height())
    }

    /// The viewport covering a whole `width x height` target.
    #[must_use]
    pub fn of_size(width: u32, height: u32) -> Self {
        Self { half_width: width as f32 / 2.0, half_height: height as f32 / 2.0 }
    }

    /// `[half width, half height]` in pixels (read by the x86 kernels).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) fn half_size(&self) -> [f32; 2] {
        [self.half_width, self.half_height]
    }

    /// [`Viewport::map`] with the position snapped to the fixed-point grid: `(xy, z, 1/w)`, or
    /// `None` when the position cannot be snapped ([`fixed::snap`]) or depth or `1/w` is not
    /// finite.
    #[inline]
    #[must_use]
    pub fn map_snapped(&self, p: Vec4) -> Option<([i32; 2], f32, f32)> {
        let w = self.map(p);
        match (fixed::snap(w.x), fixed::snap(w.y), w.z.is_finite() && w.inv_w.is_finite()) {
            (Some(x), Some(y), true) => Some(([x, y], w.z, w.inv_w)),
            _ => None,
        }
    }

    /// Perspective divide and viewport transform.
    #[inline]
    #[must_use]
    pub fn map(&self, p: Vec4) -> Vertex {
        let inv_w = 1.0 / p.w;
        Vertex {
            x: (p.x * inv_w + 1.0) * self.half_width,
            y: (1.0 - p.y * inv_w) * self.half_height,
            z: p.z * inv_w,
            inv_w,
            color: [255; 4],
        }
    }
}

/// The power of two that brings the largest magnitude of `positions` (finite) to 2^100 when
/// it is larger, else 1.
fn fitting_scale(positions: &[Vec4; 3]) -> f32 {
    let largest = positions.iter().map(|p| p.abs().max_element()).fold(0.0f32, f32::max);
    let exponent = ((largest.to_bits() >> 23) & 0xff) as i32 - 127;
    // 2^(100 - exponent), built from its bits: exact, and a normal number for any finite
    // `largest` at or above 2^100.
    f32::from_bits(((127 + 100 - exponent.max(100)) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A shaded vertex with an RGB colour takes 32 bytes (48 with RGBA), not the 64 its
    /// position and a nested `ClipVertex` made it: the band loops read one per corner from
    /// memory.
    #[test]
    fn shaded_vertices_are_packed() {
        assert_eq!(std::mem::size_of::<ShadedVertex<Vec3>>(), 32);
        assert_eq!(std::mem::size_of::<ShadedVertex<Vec4>>(), 48);
    }

    /// Each block's rows are the least and greatest `y` of its corners, or `None` when one
    /// is `OUTSIDE`, for corners anywhere in the fixed-point range.
    #[test]
    fn vertex_rows_are_each_blocks_y_range() {
        let mut rng = SmallRng::seed_from_u64(13);
        for round in 0..50 {
            let n = rng.random_range(1..6 * ROW_BLOCK);
            let outside = [0.0, 0.001, 0.3][round % 3];
            let window: Vec<Corner> = (0..n)
                .map(|_| {
                    let y = rng.random_range(-(1 << 23)..=1 << 23);
                    if rng.random_bool(outside) { OUTSIDE } else { [0, y] }
                })
                .collect();
            let mut rows = Vec::new();
            vertex_rows(&window, &mut rows);
            let blocks: Vec<_> = window.chunks(ROW_BLOCK).collect();
            assert_eq!(rows.len(), blocks.len());
            for (block, row) in blocks.iter().zip(&rows) {
                let want = if block.contains(&OUTSIDE) {
                    None
                } else {
                    let ys = block.iter().map(|c| c[1]);
                    Some([ys.clone().min().unwrap(), ys.max().unwrap()])
                };
                assert_eq!(*row, want);
            }
        }
    }

    /// A range of triangles' smallest and largest index from kept chunk ranges and its ends
    /// read is what reading them all gives: ranges within one chunk, across chunk edges, on
    /// them, empty, and the whole.
    #[test]
    fn kept_index_ranges_give_every_range() {
        let mut rng = SmallRng::seed_from_u64(5);
        for len in [0, 1, 255, 256, 257, 1000, 3000] {
            let triangles: Vec<[u32; 3]> =
                (0..len).map(|_| std::array::from_fn(|_| rng.random_range(0..100_000))).collect();
            let buffer = IndexBuffer::new(triangles.clone());
            let indices = buffer.indices();
            let mut ranges = vec![0..len, 0..0, len..len];
            for _ in 0..200 {
                let a = rng.random_range(0..=len);
                ranges.push(a..rng.random_range(a..=len));
            }
            for edge in (0..=len).step_by(bin::CHUNK) {
                ranges.push(edge..len);
                ranges.push(0..edge);
            }
            for range in ranges {
                let want = simd::index_range_scalar(triangles[range.clone()].as_flattened());
                for level in SimdLevel::available() {
                    assert_eq!(indices.range(level, range.clone()), want, "{len}: {range:?}");
                }
            }
            let largest = triangles.as_flattened().iter().max().copied();
            assert_eq!(buffer.largest(), largest);
        }
    }

    /// `chunk_rows` bounds the rows of every pixel any sample of a chunk's triangles may
    /// cover (`bin::coverage_bounds`, multisampled: the widest reach), is `None` when a
    /// vertex of the blocks it reads lies outside the clip volume or the indices spread over
    /// too many blocks, and otherwise bounds chunks of nearby vertices (random corners, some
    /// outside; chunks of triangles on nearby indices, some spread out).
    #[test]
    fn chunk_rows_hold_every_sample_their_triangles_reach() {
        let mut rng = SmallRng::seed_from_u64(12);
        let everywhere = PixelRect { x0: -10_000, y0: -10_000, x1: 10_000, y1: 10_000 };
        let (mut bounded, mut unknown) = (0, 0);
        for round in 0..400 {
            let n = rng.random_range(3..12 * ROW_BLOCK);
            let outside = if round % 4 == 0 { 0.01 } else { 0.0 };
            // Rows within a few pixels of one another, at any sub-pixel position.
            let base = rng.random_range(-2000..2000) * 256;
            let window: Vec<Corner> = (0..n)
                .map(|_| {
                    let c = [rng.random_range(-5000..5000), base + rng.random_range(0..2048)];
                    if rng.random_bool(outside) { OUTSIDE } else { c }
                })
                .collect();
            let mut rows = Vec::new();
            vertex_rows(&window, &mut rows);
            let spread = if round % 3 == 0 { n } else { 40.min(n) };
            let start = rng.random_range(0..n - spread.min(n - 1));
            let chunk: Vec<[u32; 3]> = (0..rng.random_range(1..300))
                .map(|_| std::array::from_fn(|_| (start + rng.random_range(0..spread)) as u32))
                .collect();
            let indices = chunk.as_flattened();
            let (lo, hi) = (*indices.iter().min().unwrap(), *indices.iter().max().unwrap());
            let blocks = lo as usize / ROW_BLOCK..=hi as usize / ROW_BLOCK;
            let any_outside = window
                [blocks.start() * ROW_BLOCK..((blocks.end() + 1) * ROW_BLOCK).min(n)]
                .contains(&OUTSIDE);
            let r = chunk_rows((lo, hi), &rows);
            if any_outside || blocks.end() - blocks.start() >= CHUNK_ROW_BLOCKS {
                assert_eq!(r, None, "round {round}");
                unknown += 1;
                continue;
            }
            let [r0, r1] = r.expect("nearby vertices inside: bounded");
            bounded += 1;
            for t in &chunk {
                let xy = t.map(|i| window[i as usize].map(i64::from));
                let Ok(setup) = TriangleSetup::from_snapped(xy, CullMode::None) else { continue };
                if let Some(b) = bin::coverage_bounds(&setup, true, &everywhere) {
                    assert!(r0 <= b.y0 && b.y1 <= r1, "round {round}: {b:?} in {r0}..={r1}");
                }
            }
        }
        assert!(bounded > 100 && unknown > 20, "{bounded} bounded, {unknown} unknown");
    }

    /// The boxes `band::plan` samples from the corners: a grid mesh of two-pixel triangles
    /// (as the vertex stage snaps them) is banded; a culled or degenerate triangle has no
    /// pixels, one with a corner outside the clip volume is unknown.
    #[test]
    fn corner_bounds_band_a_grid_mesh() {
        let (cols, rows) = (1000, 500);
        let corner = |i: i32, j: i32| [i * 1920 * 256 / cols, j * 1080 * 256 / rows];
        let tri = |k: usize| {
            let (i, j) = ((k / 2) as i32 % cols, (k / 2) as i32 / cols);
            let (a, b, c, d) =
                (corner(i, j), corner(i + 1, j), corner(i, j + 1), corner(i + 1, j + 1));
            if k.is_multiple_of(2) { [a, b, d] } else { [a, d, c] }
        };
        let screen = PixelRect::of_target(1920, 1080);
        let len = 2 * (cols * rows) as usize;
        let even = band::BandBalance::default();
        let plan = band::plan(Schedule::Auto, len, (1080, 1), &screen, (2, &even), |k| {
            corner_bounds(tri(k), CullMode::None)
        });
        assert!(matches!(plan, band::Plan::Banded(_)), "{plan:?}");
        // Both windings of the first quad: one culled, the other kept; zero area; outside.
        let [a, b, d] = tri(0);
        let kept = corner_bounds([a, b, d], CullMode::Clockwise);
        let culled = corner_bounds([a, d, b], CullMode::Clockwise);
        assert!(kept.is_some_and(|r| r.area() > 0) != culled.is_some_and(|r| r.area() > 0));
        assert_eq!(corner_bounds([a, a, d], CullMode::None), Some(PixelRect::EMPTY));
        assert_eq!(corner_bounds([a, OUTSIDE, d], CullMode::None), None);
        assert_eq!(
            corner_bounds([a, b, d], CullMode::None),
            Some(PixelRect { x0: 0, y0: 0, x1: 1, y1: 1 })
        );
    }

    /// The tiled backend shades the fragments that pass the depth test lanes at a time; the
    /// reference one at a time. Lane by lane they are the same, bit for bit: perspective and
    /// affine triangles, fragments discarded or kept, with and without a normal buffer, and
    /// every field of each fragment reaching the shader.
    #[test]
    fn lanes_shade_as_single_fragments() {
        struct Everything;
        impl FragmentShader<Vec3> for Everything {
            fn shade(&self, f: &Fragment<Vec3>) -> Option<Vec4> {
                // Discards some fragments; each channel of the colour (in [-0.1, 1.1), so that
                // the 8-bit output keeps the differences and the clamps are reached) depends
                // on a field of the fragment.
                let v = f.varyings;
                let keep = v.x.fract() < 0.8 && (f.front_facing || f.x % 3 != 0);
                keep.then(|| {
                    let spread = |c: f32| c.fract() * 1.2 - 0.1;
                    Vec4::new(
                        spread(v.x + 0.01 * f.x as f32),
                        spread(v.y + 0.01 * f.y as f32),
                        spread(v.z + 0.05 * f.primitive as f32),
                        spread(f.depth),
                    )
                })
            }
            fn normal(&self, f: &Fragment<Vec3>) -> Option<Vec3> {
                Some(f.varyings.normalize_or_zero())
            }
        }
        let mut rng = SmallRng::seed_from_u64(11);
        // Every level encodes the lanes' colours as the single fragment does.
        let levels = SimdLevel::available();
        for round in 0..2000 {
            let level = levels[round as usize % levels.len()];
            let q0 = rng.random_range(0.01..10.0f32);
            let inv_w = if round % 3 == 0 {
                [q0; 3]
            } else {
                [q0, rng.random_range(0.01..10.0), rng.random_range(0.01..10.0)]
            };
            let area2 = rng.random_range(1.0..1e9f64).round();
            let mut varyings = || Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let triangle = TriangleData {
                varyings0: varyings(),
                varyings1: varyings(),
                varyings2: varyings(),
                inv_w,
                inv_area2: 1.0 / area2,
                front_facing: round % 2 == 0,
                primitive: round,
            };
            let mut passed =
                PassedLanes { len: rng.random_range(1..=LANES), ..PassedLanes::default() };
            for l in 0..LANES {
                passed.x[l] = rng.random_range(0..4000);
                passed.y[l] = rng.random_range(0..4000);
                passed.e1[l] = (rng.random_range(0.0..1.0) * area2).round();
                passed.e2[l] = (rng.random_range(0.0..1.0) * area2).round();
                passed.z[l] = rng.random();
            }
            for want_normal in [false, true] {
                let stage = ShaderStage {
                    shader: &Everything,
                    want_normal,
                    kernel: None,
                    small: None,
                    level,
                };
                let mut lanes = [None; LANES];
                stage.lanes(&triangle, &passed, &mut lanes);
                for (l, got) in lanes.iter().enumerate().take(passed.len) {
                    let (x, y, e1, e2, z) = passed.lane(l);
                    let one = stage.fragment(&triangle, x, y, e1, e2, z);
                    assert_eq!(*got, one, "round {round}, lane {l}");
                }
            }
        }
    }

    /// Weights are `l_i q_i / sum(l_j q_j)` to f32 rounding, whether or not the three `1/w`
    /// are equal (then they are the screen-space weights, returned without a division), and
    /// sum to one; a degenerate sum gives thirds.
    #[test]
    fn perspective_weights_follow_their_definition() {
        let mut rng = SmallRng::seed_from_u64(5);
        for round in 0..100_000 {
            let (l1, l2) = (rng.random_range(0.0..1.0f64), rng.random_range(0.0..1.0f64));
            let (l1, l2) = if l1 + l2 > 1.0 { (1.0 - l1, 1.0 - l2) } else { (l1, l2) };
            let q0 = rng.random_range(0.01..100.0f64);
            let q = if round % 2 == 0 {
                [q0; 3]
            } else {
                [q0, rng.random_range(0.01..100.0), rng.random_range(0.01..100.0)]
            };
            let l = [1.0 - l1 - l2, l1, l2];
            let sum: f64 = (0..3).map(|i| l[i] * q[i]).sum();
            let w = perspective_weights(l1, l2, q);
            if round % 2 == 0 {
                // Equal `1/w`: the screen-space weights themselves.
                assert_eq!(w, l.map(|x| x as f32), "{q:?}");
            }
            for i in 0..3 {
                let want = l[i] * q[i] / sum;
                assert!((f64::from(w[i]) - want).abs() <= 1e-6, "{l:?} {q:?}: {w:?}");
            }
            assert!((w.iter().map(|&x| f64::from(x)).sum::<f64>() - 1.0).abs() < 1e-6);
        }
        assert_eq!(perspective_weights(0.5, 0.5, [0.0; 3]), [1.0 / 3.0; 3]);
        assert_eq!(perspective_weights(0.2, 0.3, [f64::NAN; 3]), [1.0 / 3.0; 3]);
    }
}
