//! Binning: triangles sorted into 64 x 64 pixel tiles, then tiles rendered in parallel.
//!
//! Contract: `draw_binned` writes exactly what drawing the same triangles one after another
//! with [`shade::shade_triangle`] over the whole target writes, bit for bit, whatever the
//! thread count:
//! - every pixel belongs to exactly one tile, and a tile's bin lists the triangles that may
//!   touch it in submission order, so each pixel sees the same triangles in the same order;
//! - the value written at a pixel depends only on the triangle and the pixel (interpolation
//!   evaluates the plane at the pixel, never by stepping from a neighbour), so cutting a
//!   triangle into tiles changes nothing;
//! - threads take whole rows of tiles ([`Target::bands`]: disjoint slices), so no two threads
//!   write one pixel and no locks are needed.
//!
//! Memory is bounded: callers feed triangles in batches of at most [`BATCH`]; a batch is set
//! up, binned, rendered and dropped before the next (the lectures' "flush"), so bin memory
//! never grows with the scene, and no triangle is ever dropped.

use rayon::prelude::*;

use crate::raster::Algorithm;
use crate::render::DrawStats;
use crate::setup::{PixelRect, Rejection, TriangleSetup};
use crate::shade::{self, DepthTest, FragmentOutput, PlaneEquation};
use crate::simd::{SimdLevel, SpanColor};
use crate::target::Target;

/// Tile side in pixels.
pub const TILE: u32 = 64;

/// Triangles per batch: bounds the memory of set-up triangles and bins (a few tens of MB).
pub const BATCH: usize = 1 << 14;

/// A triangle ready for the back end: coverage setup, depth plane, id, and whatever the
/// fragment function needs (`payload`).
#[derive(Clone, Copy, Debug)]
pub struct Prepared<T> {
    /// Coverage.
    pub setup: TriangleSetup,
    /// Depth plane.
    pub depth: PlaneEquation,
    /// Id written to the id buffer.
    pub id: i32,
    /// Per-triangle shading data.
    pub payload: T,
}

/// Why a triangle gives the back end nothing to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skipped {
    /// Setup rejected it.
    Rejected(Rejection),
    /// It was set up but covers no sample inside the clip rectangle (most triangles of a
    /// dense mesh): shading data is never computed for it.
    Empty,
}

impl From<Rejection> for Skipped {
    fn from(r: Rejection) -> Self {
        Self::Rejected(r)
    }
}

/// Runs the front end over a batch in parallel: `prepare(k)` gives the pieces of the batch's
/// triangle `k`. Returns the prepared triangles in submission order and the counts of what
/// was skipped; skipped triangles take no memory.
///
/// `out` is cleared and refilled: callers keep it across batches, so its memory is reused
/// instead of being returned to the system and faulted in again for every batch.
pub fn prepare_batch<T, It, F>(len: usize, out: &mut Vec<Prepared<T>>, prepare: F) -> DrawStats
where
    T: Send,
    It: IntoIterator<Item = Result<Prepared<T>, Skipped>>,
    F: Fn(usize) -> It + Sync,
{
    // Fixed chunks collected in order, then joined once: no merge tree, no per-item slots.
    // Small enough that a chunk's buffer (~75 KB) comes from the allocator's arenas.
    const CHUNK: usize = 256;
    let parts: Vec<(Vec<Prepared<T>>, DrawStats)> = (0..len.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| {
            let mut out = Vec::with_capacity(CHUNK);
            let mut stats = DrawStats::default();
            for k in c * CHUNK..((c + 1) * CHUNK).min(len) {
                for piece in prepare(k) {
                    match piece {
                        Ok(p) => {
                            stats.rasterized += 1;
                            out.push(p);
                        }
                        Err(why) => stats.skip(why),
                    }
                }
            }
            (out, stats)
        })
        .collect();
    out.clear();
    let mut stats = DrawStats::default();
    for (part, counts) in parts {
        out.extend(part);
        stats = stats.merged(&counts);
    }
    stats
}

/// Per-tile lists of triangle indices, in submission order.
#[derive(Debug, Default)]
pub struct Bins {
    tiles_x: usize,
    lists: Vec<Vec<u32>>,
}

impl Bins {
    /// Bins triangles whose (sample-inclusive) pixel bounds are `bounds`; bounds reaching
    /// outside the `width x height` target are clipped to it. Chunks are binned in parallel
    /// and merged in chunk order, so lists stay in submission order.
    #[must_use]
    pub fn build(bounds: &[Option<PixelRect>], width: u32, height: u32) -> Self {
        Self::build_with(bounds.len(), |k| bounds[k], width, height)
    }

    /// [`Bins::build`] with the bounds of triangle `k` given by `bound(k)`, so that no
    /// intermediate array is allocated per batch.
    #[must_use]
    pub fn build_with(
        len: usize,
        bound: impl Fn(usize) -> Option<PixelRect> + Sync,
        width: u32,
        height: u32,
    ) -> Self {
        let tiles_x = width.div_ceil(TILE) as usize;
        let tiles_y = height.div_ceil(TILE) as usize;
        let tiles = tiles_x * tiles_y;
        let chunk = len.div_ceil(rayon::current_num_threads() * 4).max(1024);
        let partial: Vec<Vec<Vec<u32>>> = (0..len.div_ceil(chunk))
            .into_par_iter()
            .map(|c| (c, (c * chunk..((c + 1) * chunk).min(len)).map(&bound)))
            .map(|(c, part)| {
                let mut lists = vec![Vec::new(); tiles];
                let target = PixelRect::of_target(width, height);
                for (k, r) in part.enumerate() {
                    let Some(r) = r.and_then(|r| r.intersect(&target)) else { continue };
                    let index = (c * chunk + k) as u32;
                    let (tx0, tx1) = (r.x0 as u32 / TILE, r.x1 as u32 / TILE);
                    let (ty0, ty1) = (r.y0 as u32 / TILE, r.y1 as u32 / TILE);
                    for ty in ty0..=ty1 {
                        for tx in tx0..=tx1 {
                            lists[ty as usize * tiles_x + tx as usize].push(index);
                        }
                    }
                }
                lists
            })
            .collect();
        let lists = (0..tiles)
            .into_par_iter()
            .map(|t| {
                let mut merged = Vec::with_capacity(partial.iter().map(|p| p[t].len()).sum());
                for p in &partial {
                    merged.extend_from_slice(&p[t]);
                }
                merged
            })
            .collect();
        Self { tiles_x, lists }
    }

    /// The triangles of tile `(tx, ty)`.
    #[must_use]
    pub fn tile(&self, tx: usize, ty: usize) -> &[u32] {
        &self.lists[ty * self.tiles_x + tx]
    }
}

/// Pixels whose centre or any sample (offsets within +-1/2 pixel) the triangle may cover,
/// clipped to `clip`.
#[must_use]
pub fn coverage_bounds(
    setup: &TriangleSetup,
    multisampled: bool,
    clip: &PixelRect,
) -> Option<PixelRect> {
    let r = if multisampled {
        let lo = setup.sample_bounds([128, 128]);
        let hi = setup.sample_bounds([-128, -128]);
        PixelRect { x0: lo.x0, y0: lo.y0, x1: hi.x1, y1: hi.y1 }
    } else {
        setup.bounds
    };
    r.intersect(clip)
}

/// The faster of the two (identical) rasterizers for a triangle: scanline spans cost a few
/// divisions per row however wide the row, edge stepping a few additions per pixel of the
/// bounding box; narrow triangles are cheaper to step.
fn coverage_algorithm(setup: &TriangleSetup) -> Algorithm {
    if setup.bounds.x1 - setup.bounds.x0 < 8 {
        Algorithm::EdgeFunctions
    } else {
        Algorithm::Scanline
    }
}

/// Renders prepared triangles through tiles on the current rayon thread pool; returns the
/// number of covered samples.
/// `fragment(payload, x, y, e1, e2, z)` shades one pixel; where `kernel(payload)` gives a span
/// kernel, it shades 1x spans instead.
#[allow(clippy::too_many_arguments)]
pub fn draw_binned<T, K, F>(
    target: &mut Target,
    prepared: &[Prepared<T>],
    depth_test: DepthTest,
    clip: &PixelRect,
    kernel: K,
    fragment: F,
) -> u64
where
    T: Sync,
    K: Fn(&T) -> Option<(SimdLevel, SpanColor)> + Sync,
    F: Fn(&T, i32, i32, f64, f64, f32) -> Option<FragmentOutput> + Sync,
{
    let multisampled = target.samples().count() > 1;
    let (width, height) = (target.width(), target.height());
    let bins = Bins::build_with(
        prepared.len(),
        |k| coverage_bounds(&prepared[k].setup, multisampled, clip),
        width,
        height,
    );
    let tiles_x = width.div_ceil(TILE) as usize;
    target
        .bands(TILE)
        .into_par_iter()
        .enumerate()
        .map(|(ty, mut band)| {
            let mut covered = 0;
            for tx in 0..tiles_x {
                let tile = PixelRect {
                    x0: (tx as u32 * TILE) as i32,
                    y0: band.rect().y0,
                    x1: ((tx as u32 + 1) * TILE).min(width) as i32 - 1,
                    y1: band.rect().y1,
                };
                let Some(tile) = tile.intersect(clip) else { continue };
                for &i in bins.tile(tx, ty) {
                    let p = &prepared[i as usize];
                    covered += shade::shade_triangle(
                        &mut band,
                        &p.setup,
                        coverage_algorithm(&p.setup),
                        &tile,
                        &p.depth,
                        depth_test,
                        p.id,
                        kernel(&p.payload),
                        |x, y, e1, e2, z| fragment(&p.payload, x, y, e1, e2, z),
                    );
                }
            }
            covered
        })
        .sum()
}
