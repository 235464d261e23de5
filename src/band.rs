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
    let (mut known_runs, mut local_runs) = (0, 0);
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
        if known {
            known_runs += 1;
            local_runs += usize::from(joint.is_none_or(|j| j.area() <= LOCAL_RUN));
        }
        if let Some(j) = joint {
            footprint = Some(footprint.map_or(j, |f| f.union(&j)));
        }
    }
    let small = area <= SMALL_BOX * rows.len() as i64;
    // Mostly triangles to clip (their corners unknown): every band would clip them all.
    let known = 4 * known_runs >= 3 * runs;
    let local = 4 * local_runs >= 3 * runs || footprint.is_none_or(|f| f.area() <= FOOTPRINT);
    let banded = match schedule {
        Schedule::Banded => true,
        _ => runs == RUNS && known && small && local,
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

#[cfg(test)]
mod tests {
    use super::*;

    const SCREEN: PixelRect = PixelRect { x0: 0, y0: 0, x1: 1919, y1: 1079 };

    /// A grid of `cols x rows` quads of two triangles each over the screen, row by row: the
    /// pixel box of triangle `k`.
    fn grid(cols: i32, rows: i32) -> impl Fn(usize) -> Option<PixelRect> {
        move |k| {
            let quad = k as i32 / 2;
            let (i, j) = (quad % cols, quad / cols);
            let (x0, y0) = (i * 1920 / cols, j * 1080 / rows);
            let (x1, y1) = ((i + 1) * 1920 / cols, (j + 1) * 1080 / rows);
            Some(PixelRect { x0, y0, x1, y1 })
        }
    }

    /// Boxes of `side` pixels scattered over the screen (a multiplicative hash of the index).
    fn scattered(side: i32) -> impl Fn(usize) -> Option<PixelRect> {
        move |k| {
            let h = (k as u32).wrapping_mul(0x9E37_79B9);
            let (x0, y0) = ((h % 1900) as i32, ((h >> 16) % 1060) as i32);
            Some(PixelRect { x0, y0, x1: x0 + side - 1, y1: y0 + side - 1 })
        }
    }

    fn rows_of(plan: &Plan) -> Option<&[u32]> {
        match plan {
            Plan::Banded(bands) => Some(bands.starts()),
            Plan::Binned => None,
        }
    }

    /// Small triangles in spatial order, or anywhere in a small part of the target, are
    /// banded; small triangles scattered over the target, large ones and draw calls too small
    /// to sample are binned; `Binned` and `Banded` are obeyed whatever the triangles.
    #[test]
    fn plans_band_small_triangles_that_stay_together() {
        let auto = |len, bounds: &dyn Fn(usize) -> Option<PixelRect>| {
            plan(Schedule::Auto, len, 1080, &SCREEN, 2, bounds)
        };
        assert!(rows_of(&auto(1_000_000, &grid(1000, 500))).is_some(), "grid");
        // The same small boxes, scattered: binned; gathered in a corner of the target: banded.
        assert_eq!(auto(1_000_000, &scattered(4)), Plan::Binned, "scattered");
        let corner = |k| scattered(4)(k).map(|b| PixelRect { x0: b.x0 / 4, x1: b.x0 / 4 + 3, ..b });
        let corner = |k| corner(k).map(|b| PixelRect { y0: b.y0 / 4, y1: b.y0 / 4 + 3, ..b });
        assert!(rows_of(&auto(1_000_000, &corner)).is_some(), "gathered");
        // Larger boxes gathered as closely: binned.
        let large = |k| {
            scattered(15)(k).map(|b| {
                let (x0, y0) = (b.x0 * 900 / 1900, b.y0 * 900 / 1060);
                PixelRect { x0, y0, x1: x0 + 14, y1: y0 + 14 }
            })
        };
        assert_eq!(auto(1_000_000, &large), Plan::Binned, "gathered, large");
        // Large triangles in order (a coarse grid), and a grid too short to sample.
        assert_eq!(auto(20_000, &grid(100, 100)), Plan::Binned, "large");
        assert_eq!(auto(RUN * RUNS - 1, &grid(1000, 500)), Plan::Binned, "too few");
        // Unknown boxes (corners outside the view volume) are not local.
        assert_eq!(auto(1_000_000, &|_| None), Plan::Binned, "unknown");
        for len in [0, 1, 100, 1_000_000] {
            let forced = |s| plan(s, len, 1080, &SCREEN, 2, grid(1000, 500));
            assert_eq!(forced(Schedule::Binned), Plan::Binned, "{len}");
            assert!(rows_of(&forced(Schedule::Banded)).is_some(), "{len}");
        }
    }

    /// Bands split the sampled triangles evenly: equal rows for a grid over the whole target,
    /// the rows of a model's triangles where it covers part of it; at most one band per
    /// thread, ascending from row 0, each with at least one row.
    #[test]
    fn bands_share_the_triangles_evenly() {
        let bands = |threads, bounds: &dyn Fn(usize) -> Option<PixelRect>| {
            let p = plan(Schedule::Banded, 1_000_000, 1080, &SCREEN, threads, bounds);
            rows_of(&p).unwrap().to_vec()
        };
        for threads in [1, 2, 3, 7] {
            let starts = bands(threads, &grid(1000, 500));
            assert_eq!(starts.len(), threads, "{starts:?}");
            for (t, &s) in starts.iter().enumerate() {
                let even = (t * 1080 / threads) as i64;
                assert!((i64::from(s) - even).abs() <= 8, "{threads} threads: {starts:?}");
            }
        }
        // A model in rows 100..=316 of the target: its rows are split, not the target's.
        let model = |k| {
            grid(1000, 500)(k).map(|b| PixelRect { y0: 100 + b.y0 / 5, y1: 100 + b.y1 / 5, ..b })
        };
        let starts = bands(2, &model);
        assert!(starts[0] == 0 && (203..=213).contains(&starts[1]), "{starts:?}");
        // More threads than rows: fewer bands, none empty.
        let short = plan(
            Schedule::Banded,
            1_000_000,
            3,
            &PixelRect { y1: 2, ..SCREEN },
            7,
            grid(1000, 500),
        );
        let starts = rows_of(&short).unwrap();
        assert!(
            starts[0] == 0
                && starts.windows(2).all(|w| w[0] < w[1])
                && starts.iter().all(|&s| s < 3),
            "{starts:?}"
        );
        // Nothing visible: bands of equal height.
        let nowhere = plan(Schedule::Banded, 1_000_000, 1080, &SCREEN, 2, |_| {
            Some(PixelRect { x0: -9, y0: -9, x1: -5, y1: -5 })
        });
        assert_eq!(rows_of(&nowhere), Some(&[0, 540][..]));
    }
}
