//! Point-cloud splatting with a bounding-sphere hierarchy (QSplat style): the lectures'
//! "post-triangle world".
//!
//! Pipeline: [`cloud`] (point clouds from PLY, or sampled from any mesh) -> [`tree`] (a
//! bounding-sphere tree, built in parallel) -> [`format`](mod@format) (the compact `.tsplat`
//! file, about 6 bytes per node, quantized relative to the parent) -> [`render`] (traverse,
//! cull by frustum and normal cone, stop at a projected-size threshold, draw splats through the
//! same tiles and depth buffer as triangles; incremental refinement under a budget).

pub mod cloud;
pub mod format;
pub mod render;
pub mod tree;

pub use cloud::PointCloud;
pub use tree::{SplatNode, SplatTree};
