//! The draw call: runs `setup -> raster -> shade` over a triangle list, in submission order.

use crate::error::Error;
use crate::fixed;
use crate::raster::Algorithm;
use crate::setup::{CullMode, PixelRect, Rejection, TriangleSetup, Vertex};
use crate::shade::{self, DepthTest, FragmentOutput, Shading, TriangleShader};
use crate::target::Target;

/// How to draw. `RenderOptions::default()` is: edge functions, smooth shading, no culling,
/// LESS depth test, no scissor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct RenderOptions {
    /// Coverage algorithm (both give identical pixels).
    pub algorithm: Algorithm,
    /// Colour interpolation.
    pub shading: Shading,
    /// Winding to discard.
    pub cull: CullMode,
    /// Depth comparison.
    pub depth_test: DepthTest,
    /// Optional scissor rectangle (intersected with the target).
    pub scissor: Option<PixelRect>,
}

impl RenderOptions {
    /// Sets the coverage algorithm.
    #[must_use]
    pub fn with_algorithm(mut self, algorithm: Algorithm) -> Self {
        self.algorithm = algorithm;
        self
    }

    /// Sets the shading mode.
    #[must_use]
    pub fn with_shading(mut self, shading: Shading) -> Self {
        self.shading = shading;
        self
    }

    /// Sets the cull mode.
    #[must_use]
    pub fn with_cull(mut self, cull: CullMode) -> Self {
        self.cull = cull;
        self
    }

    /// Sets the depth test.
    #[must_use]
    pub fn with_depth_test(mut self, depth_test: DepthTest) -> Self {
        self.depth_test = depth_test;
        self
    }

    /// Sets a scissor rectangle.
    #[must_use]
    pub fn with_scissor(mut self, scissor: PixelRect) -> Self {
        self.scissor = Some(scissor);
        self
    }
}

/// What a draw call did with its triangles.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Triangles submitted.
    pub submitted: usize,
    /// Triangles that reached the rasterizer.
    pub rasterized: usize,
    /// Dropped for a NaN or infinite coordinate.
    pub non_finite: usize,
    /// Dropped for zero area after snapping.
    pub degenerate: usize,
    /// Removed by culling.
    pub culled: usize,
    /// Fragments generated (covered pixel centres, before the depth test).
    pub fragments: u64,
}

/// Draws `triangles` into `target`; triangle `i` has id `i`.
///
/// Vertices outside the fixed-point range are an error, reported before anything is drawn;
/// NaN or infinite vertices drop their triangle and are counted in the returned stats.
pub fn draw(
    target: &mut Target,
    triangles: &[[Vertex; 3]],
    options: &RenderOptions,
) -> Result<DrawStats, Error> {
    check_range(triangles)?;
    let clip = match options.scissor {
        Some(s) => s.intersect(&target.rect()),
        None => Some(target.rect()),
    };
    let mut stats = DrawStats { submitted: triangles.len(), ..DrawStats::default() };
    for (id, tri) in triangles.iter().enumerate() {
        let setup = match TriangleSetup::new(tri, options.cull) {
            Ok(s) => s,
            Err(Rejection::NonFinite) => {
                stats.non_finite += 1;
                continue;
            }
            Err(Rejection::Degenerate) => {
                stats.degenerate += 1;
                continue;
            }
            Err(Rejection::Culled) => {
                stats.culled += 1;
                continue;
            }
            // Cannot happen: check_range has already returned an error for such a vertex.
            Err(Rejection::OutOfRange) => continue,
        };
        stats.rasterized += 1;
        let Some(clip) = clip else { continue };
        let shader = TriangleShader::new(tri, &setup, options.shading);
        stats.fragments += shade::shade_triangle(
            target,
            &setup,
            options.algorithm,
            &clip,
            shader.depth_plane(),
            options.depth_test,
            id as i32,
            |_, _, e1, e2, _| Some(FragmentOutput { color: shader.color_at(e1, e2), normal: None }),
        );
    }
    Ok(stats)
}

/// Rejects any finite vertex outside [-32768, 32768) pixels, naming the first one.
fn check_range(triangles: &[[Vertex; 3]]) -> Result<(), Error> {
    for (triangle, tri) in triangles.iter().enumerate() {
        for (vertex, v) in tri.iter().enumerate() {
            let finite = v.x.is_finite() && v.y.is_finite();
            if finite && (fixed::snap(v.x).is_none() || fixed::snap(v.y).is_none()) {
                return Err(Error::CoordinateOutOfRange { triangle, vertex, x: v.x, y: v.y });
            }
        }
    }
    Ok(())
}
