//! Sort-first drawing: the target cut into horizontal bands, one per thread; each band runs
//! the front end over every triangle, with its own rows as the clip rectangle, and draws what
//! lands in it at once, in submission order.
//!
//! Why: binning ([`crate::bin`], sort-middle) writes each set-up triangle's record (64 to about 200
//! bytes) to memory and reads it back tile by tile. For a mesh of small triangles submitted in
//! spatial order that round trip costs more than the tiles' cache locality gives back: a grid of
//! 1,000,000 two-pixel triangles took 114 ms binned on one thread and 85-90 ms here. Here a piece
//! of a chunk (`PIECE` triangles) has its records written to a buffer that stays in the
//! first-level cache and drawn straight away, and the pixels a coherent mesh reaches next are
//! the ones it reached last. The price: every band runs the first tests (for a mesh, the
//! corner tests; for window triangles, setup) on every triangle, and triangles in random order
//! lose the tiles' locality (1,000,000 random 10-pixel triangles: no faster on one thread,
//! slower on two). [`plan`] chooses from a sample of the draw call.
//!
//! **Determinism.** Every pixel lies in one band, and a band draws its triangles in submission
//! order, so the output is the reference's whatever the bands: their rows follow the times
//! earlier draw calls' bands took ([`BandBalance`]), and only decide which thread draws what.
//!
//! **Skipped chunks.** Where the caller can bound the rows a chunk of triangles reaches (a
//! mesh's vertices, all inside the clip volume, in a small range of indices), a band whose
//! rows the chunk cannot reach skips it whole: a mesh stored in spatial order had each band
//! run the front end over the others' triangles too (the grid's 1,000,000 triangles on two
//! threads: 1.7-2.5 ms of each band's 33-35). Nothing is drawn differently: no piece of those
//! triangles lies in the band.
//!
//! **Counts.** The reasons a triangle is skipped do not depend on the clip rectangle: the
//! front ends test zero area and culling before the rectangle, and a triangle outside the
//! rectangle counts as set up and empty, as one inside counts as set up and drawn
//! ([`DrawStats::rasterized`]). So any band counts a chunk as any other would, and each chunk
//! is counted by one band, its owner (`chunk_take`: the first band it can reach, or the
//! first band when that is not known), which never skips it; the draw call's counts are the
//! sum of the bands' (fragments included: each band counts its own).

use rayon::prelude::*;

use crate::bin::{self, Coverage, Record, Sink};
use crate::render::{DrawStats, Schedule};
use crate::setup::PixelRect;
use crate::shade::{self, DepthTest, TriangleFragments};
use crate::simd::{SimdLevel, SpanColor};
use crate::target::{Target, TargetBand};

/// Consecutive triangles whose joint bounding box [`plan`] measures.
const RUN: usize = 16;

/// Runs of [`RUN`] triangles [`plan`] samples, spread evenly over the draw call.
const RUNS: usize = 256;

/// Triangles [`plan`] samples, spread evenly over the draw call, for their sizes, the part
/// of the target they lie in and the rows that split them evenly.
const SPREAD: usize = 4096;

/// What a band does with a chunk of triangles ([`chunk_take`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Take {
    /// Its triangles cannot reach the band.
    Skip,
    /// Drawn, counted by another band.
    Draw,
    /// Drawn and counted: the band owns it.
    Own,
}

/// What band `band` (of bands covering pixel rows `bands`, each `[first, last]`, top to
/// bottom) does with a chunk of triangles whose pieces lie within pixel rows `rows` (`None`:
/// anywhere). The owner is the first band the rows reach, or the first band when they are
/// unknown or reach none; every band they reach draws the chunk, and so does its owner.
fn chunk_take(rows: Option<[i32; 2]>, band: usize, bands: &[[i32; 2]]) -> Take {
    let reaches = |b: &[i32; 2]| rows.is_none_or(|r| r[0] <= b[1] && b[0] <= r[1]);
    let owner = rows.and_then(|_| bands.iter().position(reaches)).unwrap_or(0);
    if band == owner {
        Take::Own
    } else if reaches(&bands[band]) {
        Take::Draw
    } else {
        Take::Skip
    }
}

/// What a triangle costs a band besides its pixels, in pixels of box, when [`plan`] splits
/// the sampled triangles' work evenly.
const TRIANGLE_COST: i64 = 2;

/// The largest mean pixel box of the sampled triangles for which [`plan`] bands: the
/// benchmark meshes that gain average 4 (a grid of two-pixel triangles) and 26 (the Stanford
/// bunny at 1080p); the 256 large triangles of `fill` average 1.5 million.
const SMALL_BOX: i64 = 64;

/// The largest joint pixel box of a run of [`RUN`] triangles that [`plan`] counts as local
/// (16 boxes of at most 64 pixels side by side): the grid's runs cover about 30 pixels.
const LOCAL_RUN: i64 = 1024;

/// The most samples in the box holding every sampled triangle for which [`plan`] bands
/// triangles that do not come in spatial order: the Stanford bunny's 575,000 pixels (4.6 MB of
/// colour and depth at 1x) are 5% faster banded than binned on two threads, but at 4x, the
/// Phong bunny of `trirast render` (1080p) is 10-15% slower banded; 1,000,000 random
/// triangles over all 2,073,600 pixels of 1080p are 10-15% slower banded on two threads
/// (window triangles: each band sets up all of them).
const FOOTPRINT: i64 = 1 << 20;

/// Triangles a band prepares and draws at a time, a quarter of a chunk ([`bin::CHUNK`],
/// whose reach and owner are still decided whole): their records stay in the first-level
/// cache from the front end to the kernels.
const PIECE: usize = bin::CHUNK / 4;

/// Which schedule [`plan`] chose.
#[derive(Clone, Debug, PartialEq)]
pub enum Plan {
    /// Bin into tiles ([`crate::bin`]).
    Binned,
    /// Draw in these bands.
    Banded(Bands),
}

impl Plan {
    /// The schedule this plan carries out (what [`crate::target::Target::last_schedule`]
    /// reports).
    #[must_use]
    pub fn schedule(&self) -> Schedule {
        match self {
            Self::Binned => Schedule::Binned,
            Self::Banded(_) => Schedule::Banded,
        }
    }
}

/// The bands a draw call's triangles are drawn in ([`Bands::draw`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Bands {
    /// The bands' first rows (ascending, the first 0).
    starts: Vec<u32>,
    /// Triangles in the draw call.
    triangles: usize,
    /// Each thread's share of the sampled work the starts were found for (see
    /// [`BandBalance`]).
    shares: Vec<f64>,
}

/// Units of a whole draw call's work in which [`band_starts`] places the bands' boundaries.
const SHARE_UNIT: i64 = 1 << 12;

/// How the banded schedule shares a draw call's work among its bands, from the times its
/// bands took before.
///
/// Why: a band cannot hand rows to another band once it has started (every band walks the
/// whole draw call in order), so the frame waits for the slowest band, and on a virtual
/// machine one virtual CPU can run slower than the other for seconds at a time (the Stanford
/// bunny's two bands took 3.9 and 5.8 ms, then 4.4 and 3.6 ms in another run, where the
/// same split had taken 3.74 and 3.77 ms). The bands' rows only decide which thread draws a
/// pixel, never what it holds: every pixel lies in one band, drawn in submission order.
///
/// How: each band's share of the sampled cost is moved, after each banded draw call, a
/// quarter of the way toward shares that would have made its bands take equal times (each
/// band's share divided by its time, normalized), each clamped to half and twice an even
/// share before the shares are normalized again (so they stay near those bounds). A quarter
/// rather than half because the virtual CPUs' speeds also change from one frame to the next,
/// and shares that chase each frame slow the frames that find both CPUs fast; one comparison
/// (Xeon VM, two threads, alternated runs) favoured it: median of the runs' median frames
/// without balance, with a half step and with a quarter, grid 25.4, 22.7 and 21.1 ms, bunny
/// 6.03, 5.29 and 5.15 ms. Later runs of the quarter step confirmed the bunny's gain (5.94
/// -> 5.11 and 7.11 -> 7.00 ms) but not the grid's (22.0 -> 24.7 and 23.9 -> 24.6 ms), and
/// fastest frames did not change: see docs/design-log.md, `band`.
#[derive(Clone, Debug, Default)]
pub struct BandBalance {
    /// Each band's share, summing to 1; empty (even shares) until a banded draw call.
    shares: Vec<f64>,
}

#[cfg(test)]
impl BandBalance {
    /// Given shares, as a test forces them.
    pub(crate) fn with_shares(shares: Vec<f64>) -> Self {
        Self { shares }
    }
}

impl BandBalance {
    /// The shares of `bands` bands: the kept ones, or even shares when the kept ones are for
    /// another number of bands.
    #[must_use]
    pub fn shares(&self, bands: usize) -> Vec<f64> {
        if self.shares.len() == bands {
            self.shares.clone()
        } else {
            vec![1.0 / bands.max(1) as f64; bands.max(1)]
        }
    }

    /// Moves the shares after a draw call whose bands, given `used`, took `times` (seconds):
    /// a quarter of the way toward each band's share over its time, normalized (see
    /// [`BandBalance`]). Unchanged unless the times and shares are all positive and finite.
    pub fn update(&mut self, used: &[f64], times: &[f64]) {
        let n = used.len();
        let positive = |v: &[f64]| v.iter().all(|x| x.is_finite() && *x > 0.0);
        if n < 2 || times.len() != n || !positive(times) || !positive(used) {
            return;
        }
        let speeds: Vec<f64> = used.iter().zip(times).map(|(s, t)| s / t).collect();
        let total: f64 = speeds.iter().sum();
        let even = 1.0 / n as f64;
        let moved: Vec<f64> = used
            .iter()
            .zip(&speeds)
            .map(|(s, v)| (0.75 * s + 0.25 * v / total).clamp(0.5 * even, 2.0 * even))
            .collect();
        let sum: f64 = moved.iter().sum();
        let shares: Vec<f64> = moved.iter().map(|s| s / sum).collect();
        if positive(&shares) {
            self.shares = shares;
        }
    }
}

/// How `schedule` ([`Schedule::or_forced`]) draws `len` triangles into `clip` (on a target
/// `height` rows high with `samples` per pixel) with `threads` threads, given the triangles'
/// pixel boxes (`bounds(k)`: `None` when unknown, e.g. a corner outside the view volume or a
/// non-finite vertex; a box outside `clip` for a triangle with no pixels, e.g. culled).
///
/// [`Schedule::Auto`] samples 256 runs of 16 consecutive triangles and 4096 triangles spread
/// evenly, and bands when at least three quarters of the runs have every box known
/// (triangles to clip would be clipped by every band), the spread triangles' boxes within
/// `clip` are small on average (at most 64 pixels; some lie within `clip`), and either three
/// quarters of the runs are local (a joint box of at most 1024 pixels: the triangles come in
/// spatial order) or all the spread boxes lie within 2^20 of the target's samples. Draw calls
/// too small to sample fully are binned (the choice matters little there). The bands split
/// the spread triangles' work (a triangle's cost plus its box) in the shares `shares` gives
/// `threads` bands (even ones until the target's bands have been timed, [`BandBalance`]), so
/// that a model covering part of the target still gives each thread its share.
///
/// The thread count only sets the number of bands: every band repeats the front end's first
/// tests on the chunks it cannot rule out (the corner tests, a few nanoseconds a triangle;
/// [`Bands::draw`] skips a mesh's chunks whose rows miss the band), which is small beside
/// what bands save on two threads, the only count measured here.
///
/// The samples are taken in parallel on the current rayon pool, so `bounds` is called from
/// its threads (hence `Sync`).
///
/// # Panics
/// If `height` is past [`crate::fixed::MAX_TARGET_SIZE`], which no target has: the bands'
/// rows are found from a sum per row (a height of `u32::MAX` had aborted, refused 68 GB).
pub fn plan(
    schedule: Schedule,
    len: usize,
    (height, samples): (u32, usize),
    clip: &PixelRect,
    (threads, shares): (usize, &BandBalance),
    bounds: impl Fn(usize) -> Option<PixelRect> + Sync,
) -> Plan {
    assert!(height <= crate::fixed::MAX_TARGET_SIZE, "a target's height, not {height}");
    let schedule = schedule.or_forced();
    if schedule == Schedule::Binned {
        return Plan::Binned;
    }
    // Both samples in parallel: read from memory scattered over the draw call, they took
    // 0.13 ms of the Stanford bunny's 4.3 ms frame at 1080p on two threads one after the
    // other (the plan with `band_starts` now 0.10 ms).
    let runs = RUNS.min(len / RUN);
    let (known_runs, local_runs) = (0..runs)
        .into_par_iter()
        .map(|r| {
            // In `u64`: `r * len` may pass `usize::MAX` on 32-bit targets.
            let first = if runs > 1 {
                (r as u64 * (len - RUN) as u64 / (runs - 1) as u64) as usize
            } else {
                0
            };
            let mut joint: Option<PixelRect> = None;
            for k in first..first + RUN {
                let b = bounds(k)?;
                if let Some(b) = b.intersect(clip) {
                    joint = Some(joint.map_or(b, |j| j.union(&b)));
                }
            }
            Some(joint.is_none_or(|j| j.area() <= LOCAL_RUN))
        })
        .fold(
            || (0, 0),
            |(known, local), run| match run {
                Some(is_local) => (known + 1, local + usize::from(is_local)),
                None => (known, local),
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    // Where the work lies: triangles spread evenly over the draw call (runs are too few
    // places to split the rows by).
    let spread = SPREAD.min(len);
    let boxes: Vec<Option<PixelRect>> = (0..spread)
        .into_par_iter()
        .map(|i| {
            let k = (i as u64 * len as u64 / spread as u64) as usize;
            bounds(k).and_then(|b| b.intersect(clip))
        })
        .collect();
    let mut area = 0;
    let mut footprint: Option<PixelRect> = None;
    let mut rows = Vec::with_capacity(spread);
    for b in boxes.into_iter().flatten() {
        area += b.area();
        rows.push(((b.y0 + b.y1) / 2, TRIANGLE_COST + b.area()));
        footprint = Some(footprint.map_or(b, |f| f.union(&b)));
    }
    let small = area <= SMALL_BOX * rows.len() as i64;
    // Mostly triangles to clip (their corners unknown): every band would clip them all.
    let known = 4 * known_runs >= 3 * runs;
    let local = 4 * local_runs >= 3 * runs
        || footprint.is_none_or(|f| f.area().saturating_mul(samples as i64) <= FOOTPRINT);
    let banded = match schedule {
        Schedule::Banded => true,
        // Nothing sampled in `clip` (a scissor off the target, a model off screen): no pixels
        // to gain on, and every band would set every triangle up.
        _ => runs == RUNS && !rows.is_empty() && known && small && local,
    };
    if !banded {
        return Plan::Binned;
    }
    let shares = shares.shares(threads);
    Plan::Banded(Bands { starts: band_starts(&rows, height, &shares), triangles: len, shares })
}

/// The first rows of at most `shares.len()` bands that split the sampled triangles' work
/// in those shares (`rows`: each one's middle row, within the target, and cost, at least 1),
/// on a target `height` rows high; bands of those shares of the height when there is no
/// sample.
///
/// Band `t` starts at the row of the first triangle, in order of rows and then of costs,
/// with the shares of the bands before it of the total cost before it (the shares summed in
/// units of 1/4096, [`share_boundaries`]). Found from each row's sum and largest cost rather
/// than by sorting the triangles (0.04 ms of the bunny's frame): within a row, the last
/// triangle in that order is the costliest, so a band starts at a row exactly when the cost
/// before that triangle reaches its share (`band_starts_as_sorted`).
fn band_starts(rows: &[(i32, i64)], height: u32, shares: &[f64]) -> Vec<u32> {
    let boundaries = share_boundaries(shares);
    let mut starts = vec![0];
    let last = height.saturating_sub(1);
    if rows.is_empty() {
        let part = |b: i64| (b as u64 * u64::from(height) / SHARE_UNIT as u64) as u32;
        for row in boundaries.iter().map(|&b| part(b).min(last)) {
            if row > *starts.last().unwrap_or(&0) {
                starts.push(row);
            }
        }
        return starts;
    }
    // Each row's cost and largest cost (none: 0).
    let mut per_row = vec![(0i64, 0i64); last as usize + 1];
    for &(row, cost) in rows {
        debug_assert!((0..=last as i32).contains(&row) && cost > 0, "a row of the target");
        let r = &mut per_row[(row.max(0) as u32).min(last) as usize];
        *r = (r.0 + cost, r.1.max(cost));
    }
    let total: i64 = per_row.iter().map(|r| r.0).sum();
    let (mut t, mut before) = (0, 0i64);
    for (row, &(sum, largest)) in per_row.iter().enumerate().filter(|r| r.1.1 > 0) {
        // The row's triangles, cheapest first, were each checked with the cost before them:
        // the last check was before the costliest.
        let checked = before + sum - largest;
        while t < boundaries.len() && checked * SHARE_UNIT >= boundaries[t] * total {
            if row as u32 > *starts.last().unwrap_or(&0) {
                starts.push(row as u32);
            }
            t += 1;
        }
        before += sum;
    }
    starts
}

/// Where bands `1..` of bands with `shares` (summing to 1) start, in units of 1/4096 of the
/// whole ([`SHARE_UNIT`]): the rounded sums of the shares before each. Integers, so that
/// [`band_starts`] compares exactly (even shares of two, four or eight bands are exact).
fn share_boundaries(shares: &[f64]) -> Vec<i64> {
    let mut before = 0.0;
    let mut boundaries = Vec::with_capacity(shares.len().saturating_sub(1));
    for share in shares.iter().take(shares.len().saturating_sub(1)) {
        before += share;
        boundaries.push(((before * SHARE_UNIT as f64).round() as i64).clamp(0, SHARE_UNIT));
    }
    boundaries
}

impl Bands {
    /// Draws the draw call's triangles, the bands in parallel on the current rayon pool: each
    /// band gives `prepare(range, sink)` the triangles `range` a chunk at a time, with its rows
    /// (within `coverage`'s clip) as the sink's clip rectangle, and shades the pieces at once,
    /// with the span kernels `kernel(payload)` gives and the fragment stage `fragments`
    /// otherwise, and with `eight` records set up eight at a time at that level where they
    /// can be (as [`bin::draw_binned`]). `rows(range)` bounds the pixel rows the pieces of
    /// the chunk of triangles `range` lie in, where the caller knows (`None` otherwise): a
    /// band those rows miss skips the chunk (see the module's doc). Returns the counts and the
    /// covered samples; each band's time goes to the target's [`BandBalance`] for the next
    /// draw call's bands.
    #[allow(clippy::too_many_arguments)]
    pub fn draw<S, K, F, P, R>(
        &self,
        target: &mut Target,
        coverage: Coverage,
        depth_test: DepthTest,
        (kernel, eight): (K, Option<SimdLevel>),
        fragments: F,
        prepare: P,
        rows: R,
    ) -> (DrawStats, u64)
    where
        S: Record,
        K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)> + Sync,
        F: TriangleFragments<S::Payload>,
        P: Fn(std::ops::Range<usize>, &mut Sink<'_, S>) + Sync,
        R: Fn(std::ops::Range<usize>) -> Option<[i32; 2]> + Sync,
    {
        let len = self.triangles;
        let kind = bin::Eight::of(eight, target.samples());
        let bands = target.bands_from(&self.starts);
        let band_rows: Vec<[i32; 2]> = bands.iter().map(|b| [b.rect().y0, b.rect().y1]).collect();
        let per_band: Vec<(DrawStats, u64, f64)> = bands
            .into_par_iter()
            .enumerate()
            .map(|(b, mut band)| {
                let started = std::time::Instant::now();
                let clip = coverage.clip.intersect(&band.rect()).unwrap_or(PixelRect::EMPTY);
                let coverage = Coverage { clip, ..coverage };
                let mut records: Vec<S> = Vec::with_capacity(PIECE);
                let mut covers = Vec::with_capacity(PIECE);
                let mut setup = bin::EightSetup::default();
                let mut runs = bin::SmallRuns::default();
                let (mut stats, mut uncounted) = (DrawStats::default(), DrawStats::default());
                let mut covered = 0;
                for first in (0..len).step_by(bin::CHUNK) {
                    let range = first..(first + bin::CHUNK).min(len);
                    let counts = match chunk_take(rows(range.clone()), b, &band_rows) {
                        Take::Skip => continue,
                        Take::Draw => &mut uncounted,
                        Take::Own => &mut stats,
                    };
                    // A piece at a time: a chunk's records (40 KB for the grid's 256
                    // triangles) had left the first-level cache before they were drawn.
                    for first in range.clone().step_by(PIECE) {
                        let range = first..(first + PIECE).min(range.end);
                        records.clear();
                        covers.clear();
                        runs.clear();
                        let mut sink = Sink::new(&mut records, &mut covers, coverage, &mut *counts)
                            .with_small_runs(&mut runs);
                        prepare(range, &mut sink);
                        // Small triangles' fragments share a queue (see `bin::shade_record`).
                        let mut queue = shade::SharedLaneQueue::new();
                        let stages = (&kernel, &fragments);
                        let multisampled = band.samples().count() > 1;
                        let one = |band: &mut TargetBand<'_>, queue: &mut _, k: usize| {
                            // Multisampled, the rows of the triangle two ahead: their depth
                            // (four times the bytes of 1x) missed the cache, triangle after
                            // triangle (the 800 x 600 Phong bunny of `trirast render`).
                            if multisampled
                                && let Some(r) =
                                    covers.get(k + 2).and_then(|r| r.intersect(&band.rect()))
                            {
                                band.prefetch(&PixelRect { y1: r.y1.min(r.y0 + 7), ..r });
                            }
                            let (record, rect) = (&records[k], &covers[k]);
                            bin::shade_record(
                                band,
                                record,
                                rect,
                                depth_test,
                                |_| true,
                                stages,
                                queue,
                                |band, p| {
                                    let kernel = kernel(&p.payload);
                                    bin::shade_prepared(
                                        band, p, rect, depth_test, kernel, &fragments,
                                    )
                                },
                            )
                        };
                        // The records before each small run the front end set up (see
                        // `bin::SmallRun`), then the run; the records after the last.
                        let mut from = 0;
                        for r in 0..=runs.runs().len() {
                            let run = runs.runs().get(r);
                            let to = run.map_or(records.len(), |run| run.at());
                            // Eight at a time where the records allow (as `bin::draw_binned`).
                            for (c, next) in records[from..to].chunks(8).enumerate() {
                                let mut refs = [&next[0]; 8];
                                for (r, record) in refs.iter_mut().zip(next) {
                                    *r = record;
                                }
                                let refs = &refs[..next.len()];
                                let stages = (|_: &_| true, stages);
                                let one = |band: &mut TargetBand<'_>, queue: &mut _, l| {
                                    one(band, queue, from + 8 * c + l)
                                };
                                let run = (kind, &clip, depth_test);
                                let setup = (&mut queue, &mut setup);
                                covered +=
                                    bin::shade_eight(&mut band, refs, run, stages, setup, one);
                            }
                            if let Some(run) = run {
                                let stage = (&fragments, &mut queue);
                                covered +=
                                    bin::shade_small_run_lanes(&mut band, run, depth_test, stage);
                            }
                            from = to;
                        }
                        queue.flush(&mut band, &fragments);
                    }
                }
                (stats, covered, started.elapsed().as_secs_f64())
            })
            .collect();
        // A band for every share (no two boundaries fell in one row, so band `b` had share
        // `b`): the shares for the next draw call.
        if per_band.len() == self.shares.len() {
            let times: Vec<f64> = per_band.iter().map(|b| b.2).collect();
            target.balance.update(&self.shares, &times);
        }
        let stats = per_band.iter().fold(DrawStats::default(), |a, b| a.merged(&b.0));
        (stats, per_band.iter().map(|b| b.1).sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The starts of [`band_starts`], by sorting the triangles and walking them in order:
    /// the definition the per-row sums are held to.
    fn band_starts_sorted(rows: &mut [(i32, i64)], height: u32, shares: &[f64]) -> Vec<u32> {
        let boundaries = share_boundaries(shares);
        let mut starts = vec![0];
        rows.sort_unstable();
        let total: i64 = rows.iter().map(|r| r.1).sum();
        let (mut t, mut before) = (0, 0i64);
        for &(row, cost) in rows.iter() {
            while t < boundaries.len() && before * SHARE_UNIT >= boundaries[t] * total {
                let row = (row.max(0) as u32).min(height.saturating_sub(1));
                if row > *starts.last().unwrap_or(&0) {
                    starts.push(row);
                }
                t += 1;
            }
            before += cost;
        }
        starts
    }

    /// Each chunk is owned by one band, the first its rows reach (the first band when they
    /// reach none or are unknown); every band they reach draws it, and the others skip it
    /// (random bands and rows, rows off the target on either side, unknown rows).
    #[test]
    fn chunks_are_owned_by_one_band_and_drawn_where_they_reach() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(4);
        for _ in 0..2000 {
            let height = rng.random_range(2..200);
            let mut cuts: Vec<i32> =
                (0..rng.random_range(0..8)).map(|_| rng.random_range(1..height)).collect();
            cuts.sort_unstable();
            cuts.dedup();
            let firsts: Vec<i32> = std::iter::once(0).chain(cuts).collect();
            let bands: Vec<[i32; 2]> = firsts
                .iter()
                .zip(firsts.iter().skip(1).map(|&f| f - 1).chain([height - 1]))
                .map(|(&a, b)| [a, b])
                .collect();
            let rows = rng.random_bool(0.8).then(|| {
                let a = rng.random_range(-50..height + 50);
                [a, a + rng.random_range(0..30)]
            });
            let takes: Vec<Take> = (0..bands.len()).map(|b| chunk_take(rows, b, &bands)).collect();
            // The bands holding a row the chunk reaches, found row by row.
            let reached: Vec<bool> = bands
                .iter()
                .map(|b| rows.is_none_or(|[a, z]| (b[0]..=b[1]).any(|row| a <= row && row <= z)))
                .collect();
            let owner = takes.iter().position(|t| *t == Take::Own).expect("an owner");
            match reached.iter().position(|&r| r) {
                Some(first) if rows.is_some() => assert_eq!(owner, first, "{bands:?} {rows:?}"),
                _ => assert_eq!(owner, 0, "{bands:?} {rows:?}"),
            }
            for (b, take) in takes.iter().enumerate() {
                let drawn = *take != Take::Skip;
                assert_eq!(drawn, reached[b] || b == owner, "band {b} of {bands:?}, {rows:?}");
            }
            assert_eq!(takes.iter().filter(|t| **t == Take::Own).count(), 1);
            // Every band a row of the chunk lies in draws it.
            if let Some([a, z]) = rows {
                for row in a.max(0)..=z.min(height - 1) {
                    let b = bands.iter().position(|b| b[0] <= row && row <= b[1]).unwrap();
                    assert_ne!(takes[b], Take::Skip, "row {row} in band {b}");
                }
            }
        }
    }

    /// A band that took longer gives work to the others, until their times are equal: with
    /// times proportional to the shares over each band's speed, the shares approach the
    /// speeds' (kept within about half and twice an even share); equal times keep the
    /// shares; times that are not all positive and finite leave them; shares kept for
    /// another number of bands give even shares.
    #[test]
    fn balance_moves_work_from_slower_bands() {
        let mut balance = BandBalance::default();
        assert_eq!(balance.shares(2), [0.5, 0.5]);
        balance.update(&[0.5, 0.5], &[0.01, 0.01]);
        assert_eq!(balance.shares(2), [0.5, 0.5]);
        let run = |balance: &mut BandBalance, speeds: &[f64], frames: usize| {
            for _ in 0..frames {
                let shares = balance.shares(speeds.len());
                let times: Vec<f64> = shares.iter().zip(speeds).map(|(s, v)| s / v).collect();
                balance.update(&shares, &times);
            }
            balance.shares(speeds.len())
        };
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3);
        let shares = run(&mut balance, &[1.0, 2.0], 60);
        assert!(close(&shares, &[1.0 / 3.0, 2.0 / 3.0]), "{shares:?}");
        let shares = run(&mut balance, &[1.0, 1.0, 2.0], 80);
        assert!(close(&shares, &[0.25, 0.25, 0.5]), "{shares:?}");
        // One band ten times slower: held near half an even share.
        let shares = run(&mut balance, &[1.0, 10.0], 60);
        assert!((0.2..0.26).contains(&shares[0]), "{shares:?}");
        for s in [balance.shares(2), balance.shares(3)] {
            assert!((s.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{s:?}");
        }
        assert_eq!(balance.shares(3), [1.0 / 3.0; 3]);
        let kept = balance.shares(2);
        for bad in [[0.0, 0.01], [f64::NAN, 0.01], [f64::INFINITY, 0.01], [-1.0, 0.01]] {
            balance.update(&kept, &bad);
            assert_eq!(balance.shares(2), kept, "times {bad:?}");
            balance.update(&bad, &[0.01, 0.01]);
            assert_eq!(balance.shares(2), kept, "used {bad:?}");
        }
    }

    /// Uneven shares move the bands' boundary: a quarter of the grid's work above it.
    #[test]
    fn shares_place_the_band_starts() {
        for (first, row) in [(0.25, 270), (0.5, 540), (0.75, 810)] {
            let balance = BandBalance::with_shares(vec![first, 1.0 - first]);
            let p = plan(
                Schedule::Banded,
                1_000_000,
                (1080, 1),
                &SCREEN,
                (2, &balance),
                grid(1000, 500),
            );
            let starts = rows_of(&p).unwrap();
            assert!(starts[0] == 0 && starts[1].abs_diff(row) <= 3, "{first}: {starts:?}");
        }
    }

    /// Band starts from each row's sum and largest cost are those of walking the sorted
    /// triangles: random rows (few rows with many triangles each, or many with few), costs
    /// (some one very costly triangle) and thread counts.
    #[test]
    fn band_starts_as_sorted() {
        use rand::{Rng, SeedableRng, rngs::SmallRng};
        let mut rng = SmallRng::seed_from_u64(5);
        for round in 0..2000 {
            let height = rng.random_range(1..200);
            let len = rng.random_range(1..300);
            let spread = if round % 2 == 0 { height } else { rng.random_range(1..=height.min(4)) };
            let mut rows: Vec<(i32, i64)> = (0..len)
                .map(|_| {
                    let cost =
                        if rng.random_ratio(1, 50) { 10_000 } else { rng.random_range(1..40) };
                    (rng.random_range(0..spread) as i32, cost)
                })
                .collect();
            // Even shares, or uneven ones as `BandBalance` moves them.
            let threads = rng.random_range(1..9);
            let mut shares: Vec<f64> = (0..threads).map(|_| rng.random_range(0.5..2.0)).collect();
            if round % 3 == 0 {
                shares.fill(1.0);
            }
            let sum: f64 = shares.iter().sum();
            shares.iter_mut().for_each(|s| *s /= sum);
            let got = band_starts(&rows, height, &shares);
            assert!(got[0] == 0 && got.windows(2).all(|w| w[0] < w[1]), "{round}: {got:?}");
            assert!(got.len() <= threads && got.iter().all(|&s| s < height), "{round}: {got:?}");
            assert_eq!(got, band_starts_sorted(&mut rows, height, &shares), "{round}");
            // With no sample: the shares of the height, the same checks.
            let none = band_starts(&[], height, &shares);
            assert!(none[0] == 0 && none.windows(2).all(|w| w[0] < w[1]), "{round}: {none:?}");
            assert!(none.len() <= threads && none.iter().all(|&s| s < height), "{none:?}");
        }
    }

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
            Plan::Banded(bands) => Some(&bands.starts),
            Plan::Binned => None,
        }
    }

    /// A height no target has is refused as documented, not taken as a per-row array's length
    /// (`u32::MAX` rows had aborted the process); the largest target's is planned.
    #[test]
    fn heights_past_any_target_panic() {
        let at = |height| {
            std::panic::catch_unwind(|| {
                let balance = BandBalance::default();
                plan(Schedule::Banded, 5000, (height, 1), &SCREEN, (2, &balance), grid(100, 50))
            })
        };
        assert!(at(u32::MAX).is_err());
        assert!(at(crate::fixed::MAX_TARGET_SIZE + 1).is_err());
        assert!(rows_of(&at(crate::fixed::MAX_TARGET_SIZE).unwrap()).is_some());
    }

    /// Small triangles in spatial order, or anywhere in a small part of the target, are
    /// banded; small triangles scattered over the target, large ones and draw calls too small
    /// to sample are binned; `Binned` and `Banded` are obeyed whatever the triangles.
    #[test]
    fn plans_band_small_triangles_that_stay_together() {
        let auto = |len, bounds: &(dyn Fn(usize) -> Option<PixelRect> + Sync)| {
            plan(Schedule::Auto, len, (1080, 1), &SCREEN, (2, &BandBalance::default()), bounds)
        };
        assert!(rows_of(&auto(1_000_000, &grid(1000, 500))).is_some(), "grid");
        // The same small boxes, scattered: binned; gathered in 900 x 900 pixels: banded at 1x,
        // binned at 4x (four times the samples); larger boxes gathered as closely: binned.
        assert_eq!(auto(1_000_000, &scattered(4)), Plan::Binned, "scattered");
        let gathered = |side: i32| {
            move |k| {
                scattered(side)(k).map(|b| {
                    let (x0, y0) = (b.x0 * 900 / 1900, b.y0 * 900 / 1060);
                    PixelRect { x0, y0, x1: x0 + side - 1, y1: y0 + side - 1 }
                })
            }
        };
        assert!(rows_of(&auto(1_000_000, &gathered(4))).is_some(), "gathered");
        let at_4x = plan(
            Schedule::Auto,
            1_000_000,
            (1080, 4),
            &SCREEN,
            (2, &BandBalance::default()),
            gathered(4),
        );
        assert_eq!(at_4x, Plan::Binned, "gathered, 4x");
        assert_eq!(auto(1_000_000, &gathered(15)), Plan::Binned, "gathered, large");
        // Large triangles in order (a coarse grid), and a grid too short to sample.
        assert_eq!(auto(20_000, &grid(100, 100)), Plan::Binned, "large");
        assert_eq!(auto(RUN * RUNS - 1, &grid(1000, 500)), Plan::Binned, "too few");
        // Unknown boxes (corners outside the view volume) are not local.
        assert_eq!(auto(1_000_000, &|_| None), Plan::Binned, "unknown");
        for len in [0, 1, 100, 1_000_000] {
            let forced =
                |s| plan(s, len, (1080, 1), &SCREEN, (2, &BandBalance::default()), grid(1000, 500));
            assert_eq!(forced(Schedule::Binned), Plan::Binned, "{len}");
            assert!(rows_of(&forced(Schedule::Banded)).is_some(), "{len}");
        }
    }

    /// Bands split the sampled triangles evenly: equal rows for a grid over the whole target,
    /// the rows of a model's triangles where it covers part of it; at most one band per
    /// thread, ascending from row 0, each with at least one row.
    #[test]
    fn bands_share_the_triangles_evenly() {
        let bands = |threads, bounds: &(dyn Fn(usize) -> Option<PixelRect> + Sync)| {
            let p = plan(
                Schedule::Banded,
                1_000_000,
                (1080, 1),
                &SCREEN,
                (threads, &BandBalance::default()),
                bounds,
            );
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
            (3, 1),
            &PixelRect { y1: 2, ..SCREEN },
            (7, &BandBalance::default()),
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
        let nowhere = plan(
            Schedule::Banded,
            1_000_000,
            (1080, 1),
            &SCREEN,
            (2, &BandBalance::default()),
            |_| Some(PixelRect { x0: -9, y0: -9, x1: -5, y1: -5 }),
        );
        assert_eq!(rows_of(&nowhere), Some(&[0, 540][..]));
    }
}
