//! Sort-first drawing: the target cut into horizontal bands, one per thread; each band runs
//! the front end over every triangle, with its own rows as the clip rectangle, and draws what
//! lands in it at once, in submission order.
//!
//! Why: binning ([`crate::bin`], sort-middle) writes each set-up triangle's record (about 250
//! bytes) to memory and reads it back tile by tile. For a mesh of small triangles submitted in
//! spatial order that round trip costs more than the tiles' cache locality gives back: a grid
//! of 1,000,000 two-pixel triangles took 109 ms binned on one thread and 88 ms here. Here a
//! chunk of records is written to a buffer that stays in the cache and drawn straight away,
//! and the pixels a coherent mesh reaches next are the ones it reached last. The price: every
//! band runs the first tests (for a mesh, the corner tests; for window triangles, setup) on
//! every triangle, and triangles in random order lose the tiles' locality (1,000,000 random
//! 10-pixel triangles: no faster on one thread, slower on two). [`plan`] chooses from a
//! sample of the draw call.
//!
//! **Determinism.** Every pixel lies in one band, and a band draws its triangles in submission
//! order, so the output is the reference's whatever the bands.
//!
//! **Counts.** The reasons a triangle is skipped do not depend on the clip rectangle: the
//! front ends test zero area and culling before the rectangle, and a triangle outside the
//! rectangle counts as set up and empty, as one inside counts as set up and drawn
//! ([`DrawStats::rasterized`]). So every band counts every triangle alike, and the first
//! band's counts are the draw call's (fragments excepted: each band counts its own).

use rayon::prelude::*;

use crate::bin::{self, Coverage, Prepared, Sink};
use crate::render::{DrawStats, Schedule};
use crate::setup::PixelRect;
use crate::shade::{self, DepthTest, OfTriangle, TriangleFragments};
use crate::simd::{SimdLevel, SpanColor};
use crate::target::Target;

/// Consecutive triangles whose joint bounding box [`plan`] measures.
const RUN: usize = 16;

/// Runs of [`RUN`] triangles [`plan`] samples, spread evenly over the draw call.
const RUNS: usize = 256;

/// The largest mean pixel box of the sampled triangles for which [`plan`] bands: the
/// benchmark meshes that gain average 4 (a grid of two-pixel triangles) and 26 (the Stanford
/// bunny at 1080p); the 256 large triangles of `fill` average 1.5 million.
const SMALL_BOX: i64 = 64;

/// The largest joint pixel box of a run of [`RUN`] triangles that [`plan`] counts as local
/// (16 boxes of at most 64 pixels side by side): the grid's runs cover about 30 pixels.
const LOCAL_RUN: i64 = 1024;

/// The largest box holding every sampled triangle for which [`plan`] bands triangles that do
/// not come in spatial order: the bunny's 575,000 pixels (4.6 MB of colour and depth) banded
/// are 3-5% faster than binned; 1,000,000 random triangles over all 2,073,600 pixels of 1080p
/// are 10% slower banded on two threads (window triangles: each band sets up all of them).
const FOOTPRINT: i64 = 1 << 20;

/// Which schedule [`plan`] chose.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Plan {
    /// Bin into tiles ([`crate::bin`]).
    Binned,
    /// Draw in these bands.
    Banded(Bands),
}

/// The bands a draw call's triangles are drawn in ([`Bands::draw`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Bands {
    /// The bands' first rows (ascending, the first 0).
    starts: Vec<u32>,
    /// Triangles in the draw call.
    triangles: usize,
}

/// How `schedule` ([`Schedule::or_forced`]) draws `len` triangles into `clip` (on a target
/// `height` rows high) with `threads` threads, given the triangles' pixel boxes (`bounds(k)`,
/// `None` when unknown, e.g. a corner outside the view volume).
///
/// [`Schedule::Auto`] samples [`RUNS`] runs of [`RUN`] consecutive triangles and bands when
/// their boxes within `clip` are small ([`SMALL_BOX`]), and either at least three quarters of
/// the runs are local ([`LOCAL_RUN`]: the triangles come in spatial order) or all of them lie
/// in a small part of the target ([`FOOTPRINT`]). Draw calls too small to sample fully are
/// binned (the choice matters little there). Bands split the sampled triangles' rows evenly,
/// so that a model covering part of the target still gives each thread a like share.
pub fn plan(
    schedule: Schedule,
    len: usize,
    height: u32,
    clip: &PixelRect,
    threads: usize,
    bounds: impl Fn(usize) -> Option<PixelRect>,
) -> Plan {
    let schedule = schedule.or_forced();
    if schedule == Schedule::Binned {
        return Plan::Binned;
    }
    let runs = RUNS.min(len / RUN);
    let mut local_runs = 0;
    let mut area = 0;
    let mut footprint: Option<PixelRect> = None;
    let mut rows = Vec::with_capacity(RUN * runs);
    for r in 0..runs {
        let first = if runs > 1 { r * (len - RUN) / (runs - 1) } else { 0 };
        let mut joint: Option<PixelRect> = None;
        let mut known = true;
        for k in first..first + RUN {
            let Some(b) = bounds(k) else {
                known = false;
                continue;
            };
            if let Some(b) = b.intersect(clip) {
                area += b.area();
                rows.push((b.y0 + b.y1) / 2);
                joint = Some(joint.map_or(b, |j| j.union(&b)));
            }
        }
        if known && joint.is_none_or(|j| j.area() <= LOCAL_RUN) {
            local_runs += 1;
        }
        if let Some(j) = joint {
            footprint = Some(footprint.map_or(j, |f| f.union(&j)));
        }
    }
    let small = area <= SMALL_BOX * rows.len() as i64;
    let local = 4 * local_runs >= 3 * runs || footprint.is_none_or(|f| f.area() <= FOOTPRINT);
    let banded = match schedule {
        Schedule::Banded => true,
        _ => runs == RUNS && small && local,
    };
    if !banded {
        return Plan::Binned;
    }
    Plan::Banded(Bands { starts: band_starts(&mut rows, height, threads), triangles: len })
}

/// The first rows of at most `threads` bands that split `rows` (the sampled triangles' middle
/// rows) evenly, on a target `height` rows high; bands of equal height when there is no
/// sample.
fn band_starts(rows: &mut [i32], height: u32, threads: usize) -> Vec<u32> {
    let threads = threads.max(1);
    rows.sort_unstable();
    let mut starts = vec![0];
    for t in 1..threads {
        let row = match rows.len() {
            0 => (t as u64 * u64::from(height) / threads as u64) as u32,
            n => (rows[t * n / threads].max(0) as u32).min(height.saturating_sub(1)),
        };
        if row > *starts.last().unwrap_or(&0) && row < height {
            starts.push(row);
        }
    }
    starts
}

impl Bands {
    /// The bands' first rows (ascending, the first 0).
    #[must_use]
    pub fn starts(&self) -> &[u32] {
        &self.starts
    }

    /// Draws the draw call's triangles, the bands in parallel on the current rayon pool: each
    /// band gives `prepare(range, sink)` the triangles `range` a chunk at a time, with its rows
    /// (within `coverage`'s clip) as the sink's clip rectangle, and shades the pieces at once,
    /// with the span kernels `kernel(payload)` gives and the fragment stage `fragments`
    /// otherwise (as [`bin::draw_binned`]). Returns the counts (the first band's; see the
    /// module's doc) and the covered samples.
    pub fn draw<T, K, F, P>(
        &self,
        target: &mut Target,
        coverage: Coverage,
        depth_test: DepthTest,
        kernel: K,
        fragments: F,
        prepare: P,
    ) -> (DrawStats, u64)
    where
        T: Send,
        K: Fn(&T) -> Option<(SimdLevel, &SpanColor)> + Sync,
        F: TriangleFragments<T>,
        P: Fn(std::ops::Range<usize>, &mut Sink<'_, T>) + Sync,
    {
        let len = self.triangles;
        let per_band: Vec<(DrawStats, u64)> = target
            .bands_from(&self.starts)
            .into_par_iter()
            .map(|mut band| {
                let clip = coverage.clip.intersect(&band.rect()).unwrap_or(PixelRect::EMPTY);
                let coverage = Coverage { clip, ..coverage };
                let mut records: Vec<Prepared<T>> = Vec::with_capacity(bin::CHUNK);
                let mut covers = Vec::with_capacity(bin::CHUNK);
                let mut stats = DrawStats::default();
                let mut covered = 0;
                for first in (0..len).step_by(bin::CHUNK) {
                    records.clear();
                    covers.clear();
                    let mut sink = Sink::new(&mut records, &mut covers, coverage, &mut stats);
                    prepare(first..(first + bin::CHUNK).min(len), &mut sink);
                    for (p, rect) in records.iter().zip(&covers) {
                        covered += shade::shade_triangle(
                            &mut band,
                            &p.setup,
                            bin::coverage_algorithm(&p.setup),
                            rect,
                            &p.depth,
                            depth_test,
                            p.id,
                            kernel(&p.payload),
                            OfTriangle(&fragments, &p.payload),
                        );
                    }
                }
                (stats, covered)
            })
            .collect();
        debug_assert!(per_band.windows(2).all(|w| w[0].0 == w[1].0), "bands counted differently");
        let stats = per_band.first().map(|b| b.0).unwrap_or_default();
        (stats, per_band.iter().map(|b| b.1).sum())
    }
}
