//! trirast: an exact software triangle rasterizer.
//!
//! The pipeline, one module per stage, data flowing one way:
//! [`setup`] (snap to 1/256 pixel, integer edge functions with the top-left rule, plane
//! equations) -> [`raster`] (coverage as spans; two rasterizers that agree exactly) ->
//! [`shade`] (interpolation, depth test, writes into a [`Target`]). [`render::draw`] runs the
//! stages over a triangle list; [`mesh`] reads input files and [`output`] writes images.
//!
//! ```
//! use trirast::{draw, RenderOptions, Target, Vertex};
//! let mut target = Target::new(64, 64)?.with_ids();
//! let red = [255, 0, 0, 255];
//! let tri = [
//!     Vertex::new(4.0, 4.0, 0.5, red),
//!     Vertex::new(60.0, 8.0, 0.5, red),
//!     Vertex::new(10.0, 60.0, 0.5, red),
//! ];
//! let stats = draw(&mut target, &[tri], &RenderOptions::default())?;
//! assert_eq!(stats.rasterized, 1);
//! assert_eq!(target.ids.as_ref().unwrap()[target.index(10, 10)], 0);
//! # Ok::<(), trirast::Error>(())
//! ```
#![warn(missing_docs)]

pub mod band;
pub mod bench;
pub mod bin;
pub mod camera;
pub mod clip;
pub mod color;
pub mod error;
pub mod fixed;
pub mod input;
pub mod mesh;
pub mod model;
pub mod output;
pub mod pipeline;
pub mod polygon;
pub mod raster;
pub mod render;
pub mod sample;
pub mod scene;
pub mod setup;
pub mod shade;
pub mod simd;
pub mod splat;
pub mod target;
pub mod texture;
pub mod varyings;

pub use error::Error;
pub use raster::{Algorithm, Span};
pub use render::{DrawStats, RenderOptions, draw};
pub use setup::{CullMode, EdgeFunction, FillRule, PixelRect, TriangleSetup, Vertex};
pub use shade::{DepthTest, PlaneEquation, Shading};
pub use target::Target;
