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

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::clip::{ClipVertex, ClipVolume};
use crate::color::{linear_to_srgb8, unorm8};
use crate::error::Error;
use crate::raster::Algorithm;
use crate::render::DrawStats;
use crate::setup::{CullMode, Rejection, TriangleSetup, Vertex};
use crate::shade::{self, DepthTest, FragmentOutput, PlaneEquation};
use crate::target::Target;
use crate::varyings::Varyings;

/// Computes a vertex's clip-space position and varyings. Closures
/// `Fn(&I) -> (Vec4, V)` are vertex shaders.
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

    /// The normal to store in the target's normal buffer, if any.
    fn normal(&self, _fragment: &Fragment<V>) -> Option<Vec3> {
        None
    }
}

impl<V, F: Fn(&Fragment<V>) -> Option<Vec4> + Sync> FragmentShader<V> for F {
    fn shade(&self, fragment: &Fragment<V>) -> Option<Vec4> {
        self(fragment)
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
}

impl Pipeline {
    /// Sets the cull mode.
    #[must_use]
    pub fn with_cull(mut self, cull: FaceCull) -> Self {
        self.cull = cull;
        self
    }

    /// Sets the depth test.
    #[must_use]
    pub fn with_depth_test(mut self, depth_test: DepthTest) -> Self {
        self.depth_test = depth_test;
        self
    }

    /// Draws indexed triangles: each vertex of `vertices` through `vertex_shader` once, each
    /// triangle of `triangles` (indices into `vertices`) clipped, rasterized and shaded.
    ///
    /// An index past the end of `vertices` is an error, reported before anything is drawn.
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
        if let Some((t, &bad)) = triangles
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
        let shaded: Vec<ClipVertex<VS::Varyings>> = vertices
            .par_iter()
            .map(|v| {
                let (position, varyings) = vertex_shader.shade(v);
                ClipVertex { position, varyings }
            })
            .collect();
        let volume = ClipVolume::for_target(target.width(), target.height());
        let viewport = Viewport::of(target);
        let cull = match self.cull {
            FaceCull::None => CullMode::None,
            // The viewport's y flip keeps the picture upright, so a triangle counter-clockwise
            // in NDC is counter-clockwise on the image too.
            FaceCull::Back => CullMode::Clockwise,
            FaceCull::Front => CullMode::CounterClockwise,
        };
        let clip_rect = target.rect();
        let mut stats = DrawStats { submitted: triangles.len(), ..DrawStats::default() };
        let mut polygon = Vec::new();
        for (id, tri) in triangles.iter().enumerate() {
            let input = tri.map(|i| shaded[i as usize]);
            polygon.clear();
            let codes = input.map(|v| volume.outcode(v.position));
            if codes == [0; 3] {
                polygon.extend(input);
            } else {
                polygon.extend(volume.clip(input));
                if polygon.is_empty() {
                    stats.culled += 1;
                    continue;
                }
            }
            let window: Vec<Vertex> = polygon.iter().map(|v| viewport.map(v.position)).collect();
            for k in 1..polygon.len() - 1 {
                let corners = [0, k, k + 1];
                let win = corners.map(|c| window[c]);
                let setup = match TriangleSetup::new(&win, cull) {
                    Ok(s) => s,
                    Err(Rejection::NonFinite) => {
                        stats.non_finite += 1;
                        continue;
                    }
                    Err(Rejection::Culled) => {
                        stats.culled += 1;
                        continue;
                    }
                    // The guard band keeps vertices in range; rounding at its edge cannot
                    // reach the limit, but if it did the piece is skipped, never overflowed.
                    Err(Rejection::Degenerate | Rejection::OutOfRange) => {
                        stats.degenerate += 1;
                        continue;
                    }
                };
                stats.rasterized += 1;
                let vary = corners.map(|c| polygon[c].varyings);
                let q = win.map(|v| f64::from(v.inv_w));
                let depth = PlaneEquation::new(win.map(|v| f64::from(v.z)), &setup);
                let inv_area2 = 1.0 / setup.area2 as f64;
                let front_facing = !setup.clockwise;
                let want_normal = target.normals.is_some();
                stats.fragments += shade::shade_triangle(
                    target,
                    &setup,
                    self.algorithm,
                    &clip_rect,
                    &depth,
                    self.depth_test,
                    id as i32,
                    |x, y, e1, e2, z| {
                        let w = perspective_weights(e1 * inv_area2, e2 * inv_area2, q);
                        let fragment = Fragment {
                            x,
                            y,
                            depth: z,
                            varyings: VS::Varyings::weighted(&vary[0], &vary[1], &vary[2], w),
                            front_facing,
                            primitive: id as u32,
                        };
                        let c = fragment_shader.shade(&fragment)?;
                        let color = [
                            linear_to_srgb8(c.x),
                            linear_to_srgb8(c.y),
                            linear_to_srgb8(c.z),
                            unorm8(c.w),
                        ];
                        let normal = if want_normal {
                            fragment_shader.normal(&fragment).map(|n| n.to_array())
                        } else {
                            None
                        };
                        Some(FragmentOutput { color, normal })
                    },
                );
            }
        }
        Ok(stats)
    }
}

/// Perspective-correct barycentric weights from screen-space ones (`l1`, `l2`; `l0` is the
/// rest) and the vertices' `1/w`.
#[inline]
fn perspective_weights(l1: f64, l2: f64, q: [f64; 3]) -> [f32; 3] {
    let w = [(1.0 - l1 - l2) * q[0], l1 * q[1], l2 * q[2]];
    let sum = w[0] + w[1] + w[2];
    if sum > 0.0 { w.map(|x| (x / sum) as f32) } else { [1.0 / 3.0; 3] }
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
        Self { half_width: target.width() as f32 / 2.0, half_height: target.height() as f32 / 2.0 }
    }

    /// Perspective divide and viewport transform.
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
