//! Binning: triangles sorted into 128 x 128 pixel tiles, then tiles rendered in parallel.
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
//! up while the one before is binned and rendered ([`pipelined`]), and its buffers are
//! reused two batches later (the lectures' "flush"), so bin memory never grows
//! with the scene, and no triangle is ever dropped.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::raster::{self, Algorithm};
use crate::render::DrawStats;
use crate::sample::SampleCount;
use crate::setup::{self, PixelRect, Rejection, TriangleSetup};
use crate::shade::{self, DepthTest, OfTriangle, PlaneEquation, TriangleFragments};
use crate::simd::{SimdLevel, SpanColor};
use crate::target::{Target, TargetBand};

/// Tile side in pixels: a tile's colour and depth (128 KB at 1x) stay in a 512 KB L2 cache;
/// 128 was faster than 32, 64 and 256 on every bench scene.
pub const TILE: u32 = 128;

/// Triangles per batch: bounds the memory of set-up triangles and bins (two batches are in
/// flight, [`pipelined`]: a flat or smooth window triangle's record is 64 bytes, about 64 MB
/// for both batches when every triangle makes one; a 3D triangle's is larger). Each batch
/// visits every tile it touches once more, prefetching its buffer rows and writing them
/// back, so larger batches move fewer tiles through the caches, while the records, read back
/// tile by tile in bin order, scattered over the batch, fall out of the cache either way. A
/// million small random triangles at 1x on the AMD VM, two threads: 104-144 ms with batches
/// of 64k (the slower figure when the shared L3 cache was busy: such batches relied on their
/// records staying there), 87-111 ms with 128k, 75 ms with 512k, 74 ms with one batch of a
/// million (one thread: 197 -> 145 ms; with records 192 bytes instead of 264, 256k took
/// 72-84 ms against 70-71 for 512k; with 64-byte records, 79-85 against 66, and a million
/// 65-81). The Intel VM of earlier sessions had favoured 64k at 1x (262 -> 208 ms on one
/// thread); multisampled targets, whose tiles hold four or eight times the bytes, and meshes
/// shaded batch by batch (the dense scene 0.62 s against 0.67 with 64k) took 512k there
/// already. A later session, with window records built eight at a time, measured a million
/// against 512k on the AMD VM: the soup 59.0 -> 56.3 ms on two threads and 111.3 -> 106.7 on
/// one (fastest of five and three alternated runs), at 4x 252 -> 237 ms (peak 268 -> 296
/// MB). A million small triangles are then one batch, set up by every thread at once, then
/// drawn, rather than two whose second one's set-up shares the threads with the first one's
/// tiles. Larger records keep their bound in bytes ([`BATCH_BYTES`]).
pub const BATCH: usize = 1 << 20;

/// The most bytes of records a batch holds when its records are larger than a cache line
/// (32 MiB: 512k of 64 bytes, the batches of every record type before [`BATCH`] doubled).
/// A 3D triangle's record carries its vertices' varyings and takes 100 to 300 bytes, so
/// batches of [`BATCH`] such records had made two batches in flight take 290 MB for a Phong
/// mesh of a million triangles, and a single `trirast render` of it had spent a third of
/// its 2.3 s having the system zero those pages.
pub const BATCH_BYTES: usize = 1 << 25;

/// Triangles per batch for records of type `S`: [`BATCH`] when `S` takes at most 64 bytes,
/// or as many as [`BATCH_BYTES`] holds (a triangle makes one record unless it is clipped).
#[must_use]
pub fn batch_for<S>() -> usize {
    if size_of::<S>() <= 64 { BATCH } else { (BATCH_BYTES / size_of::<S>()).clamp(1, BATCH) }
}

/// The length of the batches [`pipelined`] cuts `items` items into: as many batches as
/// batches of `max` would make, of equal length (the last one shorter by less than one item
/// per batch). A mesh just over one batch (1.1 M triangles) is cut in halves, not into 1 M
/// and 0.1 M, so the batch prepared before any is drawn, alone, is half the mesh rather
/// than nearly all of it. A `max` of 0 counts as 1, and the result is never 0 (callers cut
/// slices with it). Applied to its own result it gives it back (tested), so a caller may pass
/// either to [`pipelined`].
#[must_use]
pub fn even_batch_len(items: usize, max: usize) -> usize {
    let max = max.max(1);
    items.div_ceil(items.div_ceil(max).max(1)).max(1)
}

/// Triangles whose coverage rectangle (clipped) is at least this many pixels wide take the
/// hierarchical depth test in [`draw_binned`]: narrower ones seldom cover a tile or hide
/// behind one, and testing them made a frame of small triangles slower.
const HIDDEN_MIN_WIDTH: i32 = TILE as i32 / 2;

/// Triangles whose coverage rectangle spans more tiles than this are binned only to the tiles
/// where they may cover a sample ([`raster::TrivialReject`], on the triangle's record):
/// a long sliver's rectangle can span the whole target while its samples lie in a diagonal
/// of tiles, and binning it everywhere made every tile draw it, to no effect. A million
/// corner-to-corner slivers on a 4K target: 172 s a frame and 2.35 GB peak (bins of all 510
/// tiles each) before, 28 s and 0.76 GB now; fill 19.3 -> 16.6-17.0 ms. Smaller rectangles
/// skip the test, which reads the record (binning otherwise reads only the rectangles).
const TRIVIAL_REJECT_TILES: u32 = 4;

/// A batch whose records take more bytes than this writes its window records with
/// streaming stores ([`Sink::push_line`]): they will have left the caches before they are
/// read back. A batch that fits in a third-level cache is read back from it, as streamed
/// records would not be. Soup (a million records, 64 MB), Zen 5 VM, median of five
/// alternated runs' fastest frames: one thread 45.3 -> 43.2 ms, two 24.0 -> 23.2 ms.
const STREAM_BYTES: usize = 32 << 20;

/// How many triangles ahead of the one being drawn the tile loop prefetches.
const PREFETCH_AHEAD: usize = 4;

/// How many records ahead of the eight being drawn the tile loop prefetches, when it takes
/// them eight at a time: the next eight but one. A bin's records lie scattered over the
/// batch, each a miss to memory. With only the next eight prefetched, their loads were a
/// fifth of a soup frame on one thread (with `narrow_eight` computing nothing, loading the
/// records or not took 25.0 against 16.5 ms of 45). Sixteen ahead: one thread 45.7 -> 42.8
/// ms on a Zen 5 VM (median of five alternated runs' fastest frames), twenty-four no better;
/// on a 4x target, whose records go one at a time, [`PREFETCH_AHEAD`] of 8 or 16 gained
/// nothing.
const EIGHTS_AHEAD: usize = 16;

/// Whether the tile loop prefetches a whole tile's buffer rows before its bin of `len`
/// items, rather than each triangle's rows two triangles ahead. On a multisampled target a
/// tile holds four or eight times the bytes, and a short bin touches little of them: whole
/// tiles, the bunny at 4x took 19.3-20.1 ms, per triangle 18.2-18.5; the soup at 4x (about
/// 3,700 triangles per tile and batch) the other way round, 222-224 against 232-236 ms. At
/// 1x, whole tiles (per triangle was no faster on the soup).
fn prefetch_whole_tile(samples: SampleCount, len: usize) -> bool {
    samples.count() == 1 || len >= DENSE_BIN
}

/// A bin at least this long (a 128 x 128 tile's pixels over 8) counts as dense for
/// [`prefetch_whole_tile`]: the bunny's bins at 4x are shorter, the soup's longer.
const DENSE_BIN: usize = (TILE * TILE / 8) as usize;

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

/// A prepared triangle as a batch stores it: [`Prepared`] itself, or a packed form that
/// gives one back where it is drawn. Packing pays where records stream through memory: a
/// batch of small window triangles is read back tile by tile long after it was written, and
/// each record's cache lines are most of that traffic (see [`BATCH`]).
pub trait Record: Copy + Send + Sync {
    /// What the fragment stage reads per triangle.
    type Payload;

    /// Whether a batch whose records outgrow the caches (`STREAM_BYTES`) writes them with
    /// streaming stores (`Sink::push_line`; window records, one cache line each), and so
    /// does not prefetch their lines.
    const STREAMED: bool = false;

    /// The triangle's coverage setup.
    fn setup(&self) -> TriangleSetup;

    /// Calls `f` with the triangle as the back end draws it.
    fn with<R>(&self, f: impl FnOnce(&Prepared<Self::Payload>) -> R) -> R;

    /// The triangle itself, when the record keeps it whole: its data then outlives a call of
    /// [`Record::with`], as a queue shared by several triangles needs (see `shade_record`).
    fn kept(&self) -> Option<&Prepared<Self::Payload>> {
        None
    }

    /// Sets eight records up for the narrow kernel at once, at `level`, within `tile`, for a
    /// target with `samples` per pixel, into `out` ([`crate::simd::narrow_eight`]), returning
    /// the lanes set up (bit `l`: record `l`), which the tile loop then hands to
    /// [`crate::simd::shade_narrow_eight`] (or at 4x and 8x
    /// [`crate::simd::shade_narrow_samples_eight`]). None by default: records whose triangles
    /// take no narrow kernel, or are kept whole, are drawn one by one.
    #[inline(always)]
    fn narrow_eight(
        records: &[&Self; 8],
        tile: &PixelRect,
        (level, samples): (SimdLevel, SampleCount),
        out: &mut crate::simd::NarrowEight,
    ) -> u8 {
        let _ = (records, tile, level, samples, out);
        0
    }
}

impl<T: Copy + Send + Sync> Record for Prepared<T> {
    type Payload = T;

    #[inline(always)]
    fn setup(&self) -> TriangleSetup {
        self.setup
    }

    #[inline(always)]
    fn with<R>(&self, f: impl FnOnce(&Prepared<T>) -> R) -> R {
        f(self)
    }

    #[inline(always)]
    fn kept(&self) -> Option<&Prepared<T>> {
        Some(self)
    }
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

/// Input triangles per front-end chunk: a chunk is set up by one task into its own buffer.
pub(crate) const CHUNK: usize = 256;

/// Bits of a prepared triangle's index that number it within its chunk: room for every
/// piece a chunk's triangles can be clipped into (a clipped triangle is a fan of at most
/// 3 + 7 planes - 2 = 8 triangles, so a chunk holds at most 2048 pieces).
const PIECE_BITS: u32 = 12;

/// A batch of prepared triangles, kept as the per-chunk buffers the parallel front end wrote
/// (never joined: joining copied every record once more). Piece `k` of chunk `c`
/// has index `c << 12 | k`, so indices grow in submission order. The buffers are reused from
/// batch to batch, so their pages are faulted in once per draw call, not once per batch.
///
/// Beside each chunk's records, the pieces' coverage rectangles ([`coverage_bounds`], with the
/// clip and sample count the batch was prepared for): binning reads those 16 bytes per
/// triangle instead of each record, which by then has left the cache.
///
/// A batch may also hold its bins ([`PreparedBatch::bin`]), which [`draw_binned`] uses when
/// they were made for the target it draws into.
#[derive(Debug)]
pub struct PreparedBatch<S> {
    chunks: Vec<Vec<S>>,
    covers: Vec<Vec<PixelRect>>,
    used: usize,
    coverage: Coverage,
    /// The batch's bins and its wide triangles' samples, when binned as it was prepared, with
    /// what they were binned for.
    binned: Option<(Bins, u64, BinTarget)>,
}

impl<S> Default for PreparedBatch<S> {
    fn default() -> Self {
        Self {
            chunks: Vec::new(),
            covers: Vec::new(),
            used: 0,
            coverage: Coverage::default(),
            binned: None,
        }
    }
}

/// What a batch's triangles are prepared for: the clip rectangle and whether the samples
/// are other than the pixel centres (the two inputs of [`coverage_bounds`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coverage {
    /// The pixels that may be drawn.
    pub clip: PixelRect,
    /// Several samples per pixel.
    pub multisampled: bool,
}

impl Default for Coverage {
    /// Nothing to draw.
    fn default() -> Self {
        Self { clip: PixelRect::EMPTY, multisampled: false }
    }
}

impl Coverage {
    /// [`coverage_bounds`] with these.
    #[inline]
    #[must_use]
    pub fn of(&self, setup: &TriangleSetup) -> Option<PixelRect> {
        coverage_bounds(setup, self.multisampled, &self.clip)
    }
}

/// Where the front end puts the pieces of one triangle: prepared ones into the chunk's buffer,
/// skipped ones into the counts. Passing a sink down (rather than returning pieces) builds
/// each record once, in place, instead of moving it through `Result`s and
/// iterators, which cost a full copy per triangle even for the many that are skipped.
#[derive(Debug)]
pub struct Sink<'a, S> {
    out: &'a mut Vec<S>,
    covers: &'a mut Vec<PixelRect>,
    coverage: Coverage,
    stats: &'a mut DrawStats,
    /// Where the front end may set small triangles up as kernel lanes rather than records
    /// (the band loop's, drawn there in order with the records).
    runs: Option<&'a mut SmallRuns>,
    /// Whether window records go to memory with streaming stores ([`Sink::push_line`]).
    stream: bool,
}

/// Eight small triangles a front end set up straight into the lanes of the small-triangle
/// kernel ([`crate::simd::shade_small_eight`]; on a 4x target
/// [`crate::simd::shade_small_samples`]), without records: the coverage and shading the
/// band loop would have given that kernel for the same triangles' records (lane `l` the
/// group's `l`-th triangle; those not drawn have no pixels), drawn after the records before
/// them. Building each record and reading it back into the same lanes, a triangle at a time,
/// had taken about a third of a frame of two-pixel triangles (the benchmark grid).
#[derive(Clone, Debug)]
pub struct SmallRun {
    /// How many records come before it.
    at: usize,
    level: SimdLevel,
    coverage: crate::simd::SmallEight,
    /// Each sample's coverage, on a 4x target ([`crate::simd::shade_small_samples`]).
    samples: crate::simd::SmallSamples,
    shading: crate::simd::SmallShading,
}

impl Default for SmallRun {
    fn default() -> Self {
        Self {
            at: 0,
            level: SimdLevel::Scalar,
            coverage: Default::default(),
            samples: Default::default(),
            shading: Default::default(),
        }
    }
}

impl SmallRun {
    /// How many records come before it.
    pub(crate) fn at(&self) -> usize {
        self.at
    }
}

/// The [`SmallRun`]s of a band's piece, in order (one per group of eight triangles at most),
/// kept from one piece to the next (each is over a kilobyte: set in place, never cleared).
#[derive(Debug, Default)]
pub struct SmallRuns {
    runs: Vec<SmallRun>,
    used: usize,
}

impl SmallRuns {
    /// Forgets every run (their memory is kept).
    pub(crate) fn clear(&mut self) {
        self.used = 0;
    }

    /// The runs set since the last [`SmallRuns::clear`].
    pub(crate) fn runs(&self) -> &[SmallRun] {
        &self.runs[..self.used]
    }
}

/// A [`SmallRun`] being set: nothing counts until [`SmallRunSetter::finish`] (a front end
/// that finds a triangle it cannot take drops the run and makes records).
pub struct SmallRunSetter<'r> {
    run: &'r mut SmallRun,
    used: &'r mut usize,
    stats: &'r mut DrawStats,
}

impl SmallRunSetter<'_> {
    /// The run's coverage, each sample's on a 4x target, and shading, to be set (see
    /// [`crate::simd::small_run_geometry`], [`crate::simd::small_run_samples_geometry`]).
    #[inline(always)]
    pub fn parts(
        &mut self,
    ) -> (
        &mut crate::simd::SmallEight,
        &mut crate::simd::SmallSamples,
        &mut crate::simd::SmallShading,
    ) {
        (&mut self.run.coverage, &mut self.run.samples, &mut self.run.shading)
    }

    /// Keeps the run, for the kernel at `level`, with its `lanes` triangles counted as
    /// rasterized.
    pub fn finish(self, level: SimdLevel, lanes: usize) {
        self.run.level = level;
        self.stats.rasterized += lanes;
        *self.used += 1;
    }
}

impl<'a, S> Sink<'a, S> {
    /// A sink putting pieces into `out` and their coverage rectangles (for `coverage`) into
    /// `covers`, and counting what it skips in `stats`.
    pub(crate) fn new(
        out: &'a mut Vec<S>,
        covers: &'a mut Vec<PixelRect>,
        coverage: Coverage,
        stats: &'a mut DrawStats,
    ) -> Self {
        Self { out, covers, coverage, stats, runs: None, stream: false }
    }

    /// The same sink, taking [`SmallRun`]s into `runs` too.
    pub(crate) fn with_small_runs(self, runs: &'a mut SmallRuns) -> Self {
        Self { runs: Some(runs), ..self }
    }

    /// A new [`SmallRun`] after the records taken so far, when the sink takes them.
    #[inline]
    pub fn small_run(&mut self) -> Option<SmallRunSetter<'_>> {
        let runs = self.runs.as_deref_mut()?;
        if runs.used == runs.runs.len() {
            runs.runs.push(SmallRun::default());
        }
        let run = &mut runs.runs[runs.used];
        run.at = self.out.len();
        Some(SmallRunSetter { run, used: &mut runs.used, stats: self.stats })
    }

    /// Takes one piece, as `record`, with setup `setup`. A piece covering no sample (front
    /// ends usually drop those before computing their shading) is counted as
    /// [`Skipped::Empty`].
    #[inline]
    pub fn push_record(&mut self, setup: &TriangleSetup, record: S) {
        match self.coverage.of(setup) {
            Some(r) => self.push_covered(record, r),
            None => self.stats.skip(Skipped::Empty),
        }
    }

    /// Takes a piece of a triangle that clipping cut into several, other than the one the
    /// triangle is counted with, as `record` with setup `setup`: counted as an extra piece
    /// ([`DrawStats::extra_pieces`]), whether or not it covers a sample.
    #[inline]
    pub fn push_extra_record(&mut self, setup: &TriangleSetup, record: S) {
        self.stats.extra_pieces += 1;
        if let Some(r) = self.coverage.of(setup) {
            self.covers.push(r);
            self.out.push(record);
        }
    }

    /// Takes one piece, as `record`, whose coverage rectangle (`self.coverage().of` its
    /// setup, not empty) the caller computed.
    #[inline]
    pub(crate) fn push_covered(&mut self, record: S, cover: PixelRect) {
        self.take_cover(cover);
        self.out.push(record);
    }

    /// Counts a piece taken and keeps its coverage rectangle (not empty), for the record the
    /// caller then puts in `out`.
    #[inline]
    fn take_cover(&mut self, cover: PixelRect) {
        debug_assert!(cover.x0 <= cover.x1 && cover.y0 <= cover.y1, "an empty rectangle");
        self.stats.rasterized += 1;
        self.covers.push(cover);
    }

    /// What the batch is prepared for.
    #[must_use]
    pub fn coverage(&self) -> Coverage {
        self.coverage
    }

    /// Asks the CPU to start loading the memory the pieces after the next `skip` will be
    /// written to (up to `n` of them, within the buffer's capacity).
    #[inline]
    pub fn prefetch(&mut self, skip: usize, n: usize) {
        if self.stream {
            // The lines are written without being read: loading them would undo that.
            return;
        }
        let spare = self.out.spare_capacity_mut();
        let from = skip.min(spare.len());
        crate::simd::prefetch_slice(&spare[from..(skip + n).min(spare.len())]);
    }

    /// Counts `n` pieces skipped for the same reason at once.
    #[inline]
    pub fn skip_many(&mut self, why: Skipped, n: usize) {
        self.stats.skip_many(why, n);
    }
}

impl Sink<'_, crate::render::WindowRecord> {
    /// [`Sink::push_covered`] for a window record: with streaming stores in a batch whose
    /// records outgrow the caches ([`STREAM_BYTES`]), so that no record's line is read
    /// before it is written ([`crate::simd::push_streamed`]).
    #[inline]
    pub(crate) fn push_line(&mut self, record: &crate::render::WindowRecord, cover: PixelRect) {
        if !self.stream {
            return self.push_covered(*record, cover);
        }
        self.take_cover(cover);
        crate::simd::push_streamed(self.out, record);
    }
}

impl<T> Sink<'_, Prepared<T>> {
    /// Takes one piece.
    #[inline]
    pub fn take(&mut self, piece: Result<Prepared<T>, Skipped>) {
        match piece {
            Ok(p) => self.push(p),
            Err(why) => self.stats.skip(why),
        }
    }

    /// Takes one piece of a triangle that clipping may have cut into several, counted as
    /// `count` says ([`crate::pipeline::Count`]).
    #[inline]
    pub(crate) fn take_piece(
        &mut self,
        piece: Result<Prepared<T>, Skipped>,
        count: crate::pipeline::Count,
    ) {
        if count == crate::pipeline::Count::Triangle {
            return self.take(piece);
        }
        match piece {
            Ok(p) => {
                let setup = p.setup;
                self.push_extra_record(&setup, p);
            }
            Err(_) => self.stats.extra_pieces += 1,
        }
    }

    /// Takes one prepared piece (as `take(Ok(piece))`, without building a `Result` of a
    /// record first); see [`Sink::push_record`].
    #[inline]
    pub fn push(&mut self, piece: Prepared<T>) {
        let setup = piece.setup;
        self.push_record(&setup, piece);
    }
}

/// Two batches of prepared triangles, for [`pipelined`]: one being filled while the other is
/// drawn.
pub type PreparedPair<S> = [PreparedBatch<S>; 2];

/// Cuts `items` into batches of at most `batch_len` (of equal length: [`even_batch_len`]) and
/// runs batch `b` (its items `batch`, the first
/// of them `items[first]`) through `prepare(b, first, batch, prepared)` (the front end,
/// filling `prepared`) and `draw(b, prepared)` (the back end), preparing batch `b + 1` while
/// batch `b` is drawn, on
/// the current rayon pool: both sides are parallel inside, and each takes up the threads the
/// other leaves idle (a coherent mesh's batch covers a strip of the target, a row or two of
/// tiles, which one thread draws while the other sets up the next batch). Batches are drawn
/// one after another, in order, so the output is what drawing them in turn gives; `prepare`
/// must not touch what `draw` writes (it writes only its batch).
pub fn pipelined<I: Sync, S: Send + Sync>(
    items: &[I],
    batch_len: usize,
    pair: &mut PreparedPair<S>,
    mut prepare: impl FnMut(usize, usize, &[I], &mut PreparedBatch<S>) + Send,
    mut draw: impl FnMut(usize, &PreparedBatch<S>) + Send,
) {
    let batch_len = even_batch_len(items.len(), batch_len);
    let batches = items.len().div_ceil(batch_len);
    let [a, b] = pair;
    let (mut filling, mut full) = (a, b);
    for k in 0..=batches {
        rayon::join(
            || {
                if k < batches {
                    let first = k * batch_len;
                    let batch = &items[first..(first + batch_len).min(items.len())];
                    prepare(k, first, batch, filling);
                }
            },
            || {
                if k > 0 {
                    draw(k - 1, full);
                }
            },
        );
        // The drawn batch's bins go now, not when its half is refilled: at most two batches'
        // bins exist at once (the one drawn, the one binned as it is prepared).
        full.binned = None;
        std::mem::swap(&mut filling, &mut full);
    }
}

impl<S: Record> PreparedBatch<S> {
    /// Runs the front end over a batch of `len` triangles in parallel: `prepare(k, sink)`
    /// gives the pieces of the batch's triangle `k` to `sink`, which keeps each piece's
    /// coverage rectangle for `coverage` (the clip and sample count it will be drawn with).
    /// Replaces the previous contents; returns the counts of what was skipped (skipped
    /// triangles take no memory).
    pub fn prepare<F>(&mut self, len: usize, coverage: Coverage, prepare: F) -> DrawStats
    where
        F: Fn(usize, &mut Sink<'_, S>) + Sync,
    {
        self.prepare_ranges(len, coverage, |range, sink| range.for_each(|k| prepare(k, sink)))
    }

    /// [`PreparedBatch::prepare`] with the triangles handed over a chunk at a time:
    /// `prepare(range, sink)` gives the pieces of the batch's triangles `range`, in order.
    pub fn prepare_ranges<F>(&mut self, len: usize, coverage: Coverage, prepare: F) -> DrawStats
    where
        F: Fn(std::ops::Range<usize>, &mut Sink<'_, S>) + Sync,
    {
        self.used = len.div_ceil(CHUNK);
        self.coverage = coverage;
        let stream = S::STREAMED && len.saturating_mul(size_of::<S>()) > STREAM_BYTES;
        self.binned = None;
        if self.chunks.len() < self.used {
            self.chunks.resize_with(self.used, || Vec::with_capacity(CHUNK));
            self.covers.resize_with(self.used, || Vec::with_capacity(CHUNK));
        }
        self.chunks[..self.used]
            .par_iter_mut()
            .zip(&mut self.covers[..self.used])
            .enumerate()
            .map(|(c, (out, covers))| {
                out.clear();
                covers.clear();
                let mut stats = DrawStats::default();
                let mut sink = Sink::new(out, covers, coverage, &mut stats);
                sink.stream = stream;
                prepare(c * CHUNK..((c + 1) * CHUNK).min(len), &mut sink);
                if stream {
                    crate::simd::store_fence();
                }
                debug_assert!(sink.out.len() <= 1 << PIECE_BITS, "more pieces than index slots");
                stats
            })
            .reduce(DrawStats::default, |a, b| a.merged(&b))
    }
}

impl<S> PreparedBatch<S> {
    /// The triangle at `index` (as listed by `PreparedBatch::indexed`).
    #[inline]
    #[must_use]
    pub fn get(&self, index: u32) -> &S {
        &self.chunks[(index >> PIECE_BITS) as usize][(index & ((1 << PIECE_BITS) - 1)) as usize]
    }

    /// The coverage rectangles of chunks `chunks` with their triangles' indices, in
    /// submission order.
    fn indexed_covers(
        &self,
        chunks: std::ops::Range<usize>,
    ) -> impl Iterator<Item = (u32, PixelRect)> {
        chunks.flat_map(move |c| {
            let base = (c as u32) << PIECE_BITS;
            self.covers[c].iter().enumerate().map(move |(k, &r)| (base | k as u32, r))
        })
    }

    /// What the batch was prepared for.
    #[must_use]
    pub fn coverage(&self) -> Coverage {
        self.coverage
    }

    /// Number of chunks in use.
    fn chunk_count(&self) -> usize {
        self.used
    }
}

/// The `TILE x TILE` tiles of a target: tile `ty * tiles_x + tx` holds the pixels
/// `TILE * tx ..` by `TILE * ty ..`. The one place tile indices are computed, for [`Bins`] and
/// for splats sorted by tile as they are produced.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TileGrid {
    tiles_x: u32,
    tiles: u32,
    screen: PixelRect,
}

impl TileGrid {
    /// The tiles of a `width x height` target.
    ///
    /// # Panics
    /// If a side is above [`crate::fixed::MAX_TARGET_SIZE`].
    pub(crate) fn of_size(width: u32, height: u32) -> Self {
        let largest = crate::fixed::MAX_TARGET_SIZE;
        assert!(
            width.max(height) <= largest,
            "a {width} x {height} target: sides are at most {largest}"
        );
        let tiles_x = width.div_ceil(TILE);
        let tiles = tiles_x * height.div_ceil(TILE);
        Self { tiles_x, tiles, screen: PixelRect::of_target(width, height) }
    }

    /// The first and last tile (in row-major order) a rectangle on the target overlaps.
    pub(crate) fn first_and_last(&self, r: &PixelRect) -> (u32, u32) {
        let t = Self::tile_of;
        (t(r.y0) * self.tiles_x + t(r.x0), t(r.y1) * self.tiles_x + t(r.x1))
    }

    /// The column (or row) of tiles holding pixel column (or row) `v`, on the target.
    fn tile_of(v: i32) -> u32 {
        v as u32 / TILE
    }

    /// How many tiles a rectangle on the target overlaps.
    fn tiles_over(&self, r: &PixelRect) -> u32 {
        let t = Self::tile_of;
        (t(r.x1) - t(r.x0) + 1) * (t(r.y1) - t(r.y0) + 1)
    }

    /// The pixels of tile `t` (on the target).
    fn tile_rect(&self, t: u32) -> PixelRect {
        let (x0, y0) = ((t % self.tiles_x * TILE) as i32, (t / self.tiles_x * TILE) as i32);
        let last = TILE as i32 - 1;
        let tile = PixelRect { x0, y0, x1: x0 + last, y1: y0 + last };
        tile.intersect(&self.screen).unwrap_or(PixelRect::EMPTY)
    }

    /// Calls `f` with every tile a rectangle on the target overlaps, in row-major order.
    pub(crate) fn each_tile(&self, r: &PixelRect, mut f: impl FnMut(u32)) {
        let t = Self::tile_of;
        for ty in t(r.y0)..=t(r.y1) {
            for tx in t(r.x0)..=t(r.x1) {
                f(ty * self.tiles_x + tx);
            }
        }
    }
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
    ///
    /// # Panics
    /// If a side is above a target's largest, 16384 (a list per tile is allocated: sides
    /// of 2^21 had asked for 6 GB, larger ones overflowed the tile count).
    #[must_use]
    pub fn build(bounds: &[Option<PixelRect>], width: u32, height: u32) -> Self {
        Self::build_with(bounds.len(), |k| bounds[k], width, height)
    }

    /// [`Bins::build`] with the bounds of triangle `k` given by `bound(k)`, so that no
    /// intermediate array is allocated per batch.
    ///
    /// # Panics
    /// As [`Bins::build`].
    #[must_use]
    pub fn build_with(
        len: usize,
        bound: impl Fn(usize) -> Option<PixelRect> + Sync,
        width: u32,
        height: u32,
    ) -> Self {
        let chunk = len.div_ceil(rayon::current_num_threads() * 4).max(1024);
        let bound = &bound;
        Self::build_groups(
            len.div_ceil(chunk),
            |g| (g * chunk..((g + 1) * chunk).min(len)).map(move |k| (k as u32, bound(k))),
            |_| None,
            width,
            height,
        )
    }

    /// Bins the triangles of a prepared batch by their coverage rectangles, calling
    /// `visit(index, rectangle)` with each (in parallel, in no particular order). A triangle
    /// over more than [`TRIVIAL_REJECT_TILES`] tiles is left out of the tiles where it covers
    /// no sample (its samples within `reach` of the pixel centres).
    fn of_batch<S: Record>(
        batch: &PreparedBatch<S>,
        width: u32,
        height: u32,
        reach: i64,
        visit: impl Fn(u32, &PixelRect) + Sync,
    ) -> Self {
        let chunks = batch.chunk_count();
        let per_group = chunks.div_ceil(rayon::current_num_threads() * 4).max(4);
        Self::build_groups(
            chunks.div_ceil(per_group),
            |g| {
                let range = g * per_group..((g + 1) * per_group).min(chunks);
                batch.indexed_covers(range).map(|(i, r)| {
                    visit(i, &r);
                    (i, Some(r))
                })
            },
            |i| Some(raster::TrivialReject::new(&batch.get(i).setup(), reach)),
            width,
            height,
        )
    }

    /// The shared binning loop: group `g` (in submission order) lists `(index, bounds)`;
    /// groups are binned in parallel and merged in group order, so lists stay in submission
    /// order. An item over more than [`TRIVIAL_REJECT_TILES`] tiles is left out of the tiles
    /// whose pixels within its bounds `reject(index)` (if it gives a test) says it misses.
    pub(crate) fn build_groups<I>(
        groups: usize,
        group: impl Fn(usize) -> I + Sync,
        reject: impl Fn(u32) -> Option<raster::TrivialReject> + Sync,
        width: u32,
        height: u32,
    ) -> Self
    where
        I: Iterator<Item = (u32, Option<PixelRect>)>,
    {
        let grid = TileGrid::of_size(width, height);
        let tiles = grid.tiles as usize;
        let partial: Vec<Vec<Vec<u32>>> = (0..groups)
            .into_par_iter()
            .map(|g| {
                let mut lists = vec![Vec::new(); tiles];
                for (index, r) in group(g) {
                    let Some(r) = r.and_then(|r| r.intersect(&grid.screen)) else { continue };
                    // Most small triangles lie in one tile.
                    let (first, last) = grid.first_and_last(&r);
                    if first == last {
                        lists[first as usize].push(index);
                        continue;
                    }
                    let spans_many = grid.tiles_over(&r) > TRIVIAL_REJECT_TILES;
                    match spans_many.then(|| reject(index)).flatten() {
                        None => grid.each_tile(&r, |t| lists[t as usize].push(index)),
                        Some(reject) => grid.each_tile(&r, |t| {
                            let pixels = grid.tile_rect(t).intersect(&r);
                            if pixels.is_some_and(|p| !reject.misses(&p)) {
                                lists[t as usize].push(index);
                            }
                        }),
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
        Self { tiles_x: grid.tiles_x as usize, lists }
    }

    /// Bins items that already know their tile: `(index, tile)` in submission order, tiles
    /// of `grid`.
    pub(crate) fn of_tiles(grid: &TileGrid, items: impl Iterator<Item = (u32, u32)>) -> Self {
        let mut lists = vec![Vec::new(); grid.tiles as usize];
        for (index, tile) in items {
            lists[tile as usize].push(index);
        }
        Self { tiles_x: grid.tiles_x as usize, lists }
    }

    /// Runs `draw(band, tile, list)` for every tile with a non-empty bin, `tile` clipped to
    /// `clip`, rows of tiles in parallel (each a disjoint [`TargetBand`]); returns the sum of
    /// what `draw` returns. `draw` prefetches what it will touch ([`TargetBand::prefetch`]).
    /// The back end of both triangles and splats.
    ///
    /// # Panics
    /// If `target`'s tiles are not those the bins were made for (bins made with no tiles, as
    /// `Bins::default()`, draw nothing into any target), or as [`Target::bands`].
    pub fn draw(
        &self,
        target: &mut Target,
        clip: &PixelRect,
        draw: impl Fn(&mut TargetBand<'_>, &PixelRect, &[u32]) -> u64 + Sync,
    ) -> u64 {
        let width = target.width();
        let grid = TileGrid::of_size(width, target.height());
        // A taller target's rows of tiles had indexed past the lists, a wider one's columns
        // been left undrawn without a word.
        assert!(
            self.lists.is_empty()
                || (grid.tiles_x as usize, grid.tiles as usize) == (self.tiles_x, self.lists.len()),
            "bins of {} x {} tiles drawn into a {width} x {} target",
            self.tiles_x,
            self.lists.len() / self.tiles_x.max(1),
            target.height()
        );
        target
            .bands(TILE)
            .into_par_iter()
            .enumerate()
            .map(|(ty, mut band)| {
                let mut sum = 0;
                for tx in 0..self.tiles_x {
                    let list = self.tile(tx, ty);
                    let tile = PixelRect {
                        x0: (tx as u32 * TILE) as i32,
                        x1: ((tx as u32 + 1) * TILE).min(width) as i32 - 1,
                        ..band.rect()
                    };
                    let Some(tile) = tile.intersect(clip).filter(|_| !list.is_empty()) else {
                        continue;
                    };
                    sum += draw(&mut band, &tile, list);
                }
                sum
            })
            .sum()
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
    if multisampled {
        extent_coverage_bounds(setup.extent(), true, clip)
    } else {
        setup.bounds.intersect(clip)
    }
}

/// [`coverage_bounds`] from the snapped bounding box alone ([`setup::extent`]), so that a
/// front end can drop a triangle covering no sample before setting it up.
#[must_use]
pub fn extent_coverage_bounds(
    extent: [[i64; 2]; 2],
    multisampled: bool,
    clip: &PixelRect,
) -> Option<PixelRect> {
    let r = if multisampled {
        let lo = setup::sample_bounds(extent, [128, 128]);
        let hi = setup::sample_bounds(extent, [-128, -128]);
        PixelRect { x0: lo.x0, y0: lo.y0, x1: hi.x1, y1: hi.y1 }
    } else {
        setup::sample_bounds(extent, [0, 0])
    };
    r.intersect(clip)
}

/// Draws `record`'s triangle within `rect`: through `queue` when the target is 1x and the
/// triangle small, kept whole, without a span kernel, `shared` (not drawn with hierarchical
/// depth; asked last, as it computes the triangle's coverage rectangle) and narrow within
/// `rect` (see
/// [`shade::SharedLaneQueue`]); otherwise with `draw`, once the queue's fragments are written.
/// Returns the covered samples. The one place the band and tile loops choose between the two.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) fn shade_record<'a, S, K, F>(
    band: &mut TargetBand<'_>,
    record: &'a S,
    rect: &PixelRect,
    depth_test: DepthTest,
    shared: impl FnOnce(&Prepared<S::Payload>) -> bool,
    (kernel, fragments): (&K, &F),
    queue: &mut shade::SharedLaneQueue<'a, S::Payload>,
    draw: impl FnOnce(&mut TargetBand<'_>, &Prepared<S::Payload>) -> u64,
) -> u64
where
    S: Record,
    K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)>,
    F: TriangleFragments<S::Payload>,
{
    let small = if band.samples().count() == 1 {
        queued(record, kernel, shared).and_then(|p| {
            let at = (depth_test, p.id);
            shade::shade_small_triangle(
                band, &p.setup, rect, &p.depth, at, &p.payload, fragments, queue,
            )
        })
    } else if fragments.defers_colour() {
        // Multisampled, where the stage lets colour wait behind depth.
        let kept = record.kept().filter(|p| kernel(&p.payload).is_none() && shared(p));
        kept.and_then(|p| {
            let (at, data) = ((depth_test, p.id), &p.payload);
            shade::shade_small_triangle_samples(
                band, &p.setup, rect, &p.depth, at, data, fragments, queue,
            )
        })
    } else {
        None
    };
    if let Some(covered) = small {
        return covered;
    }
    queue.flush(band, fragments);
    record.with(|p| draw(band, p))
}

/// `record`'s triangle where it shares the lane queue (at 1x): kept whole, small
/// ([`shade::SHARED_QUEUE_AREA2`]), without a span kernel, and `shared` (asked last, as it
/// may compute the triangle's coverage rectangle). The test of [`shade_record`] and of
/// [`shade_eight`]'s small lanes.
#[inline(always)]
fn queued<'a, S, K>(
    record: &'a S,
    kernel: &K,
    shared: impl FnOnce(&Prepared<S::Payload>) -> bool,
) -> Option<&'a Prepared<S::Payload>>
where
    S: Record,
    K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)>,
{
    match record.kept() {
        Some(p)
            if p.setup.area2 <= shade::SHARED_QUEUE_AREA2
                && kernel(&p.payload).is_none()
                && shared(p) =>
        {
            Some(p)
        }
        _ => None,
    }
}

/// What the tile and band loops set up for eight records at once ([`shade_eight`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Eight {
    /// Window triangles for the narrow kernel at this level ([`Record::narrow_eight`]).
    Narrow(SimdLevel),
    /// Window triangles on a 4x or 8x target for the narrow sample kernel at this level
    /// ([`Record::narrow_eight`] with the pattern's boxes), where the target has no overdraw
    /// buffer.
    NarrowSamples(SimdLevel),
    /// The smallest triangles' coverage ([`crate::simd::small_eight`]).
    Small,
    /// Nothing (3D triangles on 8x targets): each record on its own.
    None,
}

impl Eight {
    /// The kind for a target with `samples` per pixel: window triangles at `window` (their
    /// narrow kernel's level, if any), otherwise the smallest triangles (on a 4x target,
    /// for the small kernel, [`crate::simd::shade_small_samples`], or the shared queue of a
    /// stage whose colour waits behind depth, [`shade::shade_small_lane_samples`]); nothing
    /// else beyond 1x.
    pub(crate) fn of(window: Option<SimdLevel>, samples: SampleCount) -> Self {
        match window {
            None if samples == crate::simd::SMALL_SAMPLES => Self::Small,
            Some(level) if samples.count() > 1 => Self::NarrowSamples(level),
            _ if samples.count() > 1 => Self::None,
            Some(level) => Self::Narrow(level),
            None => Self::Small,
        }
    }
}

/// The buffers [`shade_eight`] sets records up in, kept by a loop from one call to the next.
#[derive(Default)]
pub(crate) struct EightSetup {
    narrow: crate::simd::NarrowEight,
    small: crate::simd::SmallEight,
    /// Each sample's coverage of the small lanes, on a 4x target.
    samples: crate::simd::SmallSamples,
    shading: crate::simd::SmallShading,
}

/// How many of eight records [`shade_eight`] takes together as small triangles, at least: a
/// few among larger ones (the bunny's) cost more together than alone.
const SMALL_EIGHT_MIN: u32 = 4;

/// [`SMALL_EIGHT_MIN`] for the small triangles of a 4x target whose colour waits in the
/// shared queue ([`shade::shade_small_lane_samples`]): one, as each saves more than the
/// eight's setup costs (the default render, load and four frames, 1.0188 -> 1.0110 G
/// instructions against four; at 1080p 2.3217 -> 2.3085 G).
const SMALL_EIGHT_MIN_QUEUED: u32 = 1;

/// Shades up to eight records in order within `clip` (the tile, or the band's rows) with
/// `depth_test`, as [`shade_record`] would each: eight of them set up together as `kind`
/// says, where they can be (window triangles through the narrow kernel,
/// [`crate::simd::shade_narrow_eight`]; small triangles, with boxes of at most 8 x 8
/// pixels, through [`crate::simd::shade_small_eight`] where the fragment stage gives them
/// kernel colours, else queued as [`shade::shade_small_triangle`] queues them,
/// [`shade::shade_small_lane`], if they share the lane queue, and on a 4x target as
/// [`shade::shade_small_triangle_samples`] does, [`shade::shade_small_lane_samples`]), the
/// others with `one(band, queue, l)` (record `l` through `shade_record`). `one` is called
/// from this one place, so that it is inlined: from two, it was left out of line, a call
/// per record (bunny 3-5% slower on two threads).
#[inline(always)]
pub(crate) fn shade_eight<'a, S, K, F>(
    band: &mut TargetBand<'_>,
    records: &[&'a S],
    (kind, clip, depth_test): (Eight, &PixelRect, DepthTest),
    (shared, (kernel, fragments)): (impl Fn(&Prepared<S::Payload>) -> bool, (&K, &F)),
    (queue, setup): (&mut shade::SharedLaneQueue<'a, S::Payload>, &mut EightSetup),
    mut one: impl FnMut(&mut TargetBand<'_>, &mut shade::SharedLaneQueue<'a, S::Payload>, usize) -> u64,
) -> u64
where
    S: Record,
    K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)>,
    F: TriangleFragments<S::Payload>,
{
    debug_assert!(records.len() <= 8, "eight records at most");
    let mut boxes = [PixelRect::EMPTY; 8];
    let kernels = fragments.small_colors();
    let (mut lanes, queue_lanes) = match (kind, <&[&S; 8]>::try_from(records)) {
        (Eight::Narrow(level), Ok(eight)) => {
            (S::narrow_eight(eight, clip, (level, SampleCount::X1), &mut setup.narrow), 0)
        }
        // Where the kernel can count fragments (per sample; an overdraw buffer counts them
        // per pixel, which the one-by-one path does).
        (Eight::NarrowSamples(level), Ok(eight)) if band.overdraw.is_none() => {
            (S::narrow_eight(eight, clip, (level, band.samples()), &mut setup.narrow), 0)
        }
        // Multisampled, for the small kernel, or for a stage whose colour waits behind depth
        // in the shared queue.
        (Eight::Small, _)
            if band.samples().count() > 1 && !kernels && !fragments.defers_colour() =>
        {
            (0, 0)
        }
        // Fewer than eight too: a band's piece ends with them (about one record in seven of
        // the bunny's, whose pieces lose half their triangles to culling).
        (Eight::Small, _) => {
            let tests = (clip, shared, kernel, kernels);
            let target = (band.samples().count() > 1, fragments.defers_colour());
            small_lanes(records, tests, target, setup, &mut boxes)
        }
        _ => (0, 0),
    };
    let (mut covered, mut l) = (0, 0);
    while l < records.len() {
        let run = (lanes >> l).trailing_ones() as usize;
        if run == 0 {
            covered += one(band, queue, l);
            l += 1;
            continue;
        }
        if let Eight::Narrow(level) = kind {
            covered +=
                crate::simd::shade_narrow_eight(level, &setup.narrow, l..l + run, band, depth_test);
        } else if let Eight::NarrowSamples(level) = kind {
            let lanes = l..l + run;
            covered += crate::simd::shade_narrow_samples_eight(
                level,
                &setup.narrow,
                lanes,
                band,
                depth_test,
            );
        } else {
            let (kernel_lanes, n) = if kernels {
                let run = (l..l + run, &boxes, depth_test);
                shade_small_run(band, records, run, fragments, queue, setup)
            } else {
                (0, 0)
            };
            covered += n;
            let (rest, l0) = (run - kernel_lanes, l + kernel_lanes);
            // The lanes after those, which the kernel cannot shade: without kernel colours all
            // of them (which then all share the queue), else the one whose triangle has none;
            // to the queue if they share it, else on its own (the next turn's `one`, called
            // from one place).
            l = l0;
            if rest > 0 {
                if queue_lanes >> l0 & 1 == 0 {
                    lanes &= !(1 << l0);
                    continue;
                }
                l = if kernels { l0 + 1 } else { l0 + rest };
                // A loop: the closure of a `map` here was left out of line, a call per
                // triangle (no difference measured on the grid, within the noise).
                let multisampled = band.samples().count() > 1;
                for m in l0..l {
                    let p = records[m].kept().expect("a small lane keeps its triangle");
                    let id = (depth_test, p.id);
                    let (depth, t) = (&p.depth, &p.payload);
                    covered += if multisampled {
                        let lane = (&setup.small, &setup.samples, m);
                        shade::shade_small_lane_samples(
                            band, lane, &boxes[m], depth, id, t, fragments, queue,
                        )
                    } else {
                        let lane = (&setup.small, m);
                        shade::shade_small_lane(
                            band, lane, &boxes[m], depth, id, t, fragments, queue,
                        )
                    };
                }
            }
            continue;
        }
        l += run;
    }
    covered
}

/// Shades the first triangles of `run` (of `records`, with boxes `boxes`; their coverage in
/// `setup.small`) that the fragment stage gives a kernel's colour
/// ([`SpanColor::Perspective`], the 3D pipeline's interpolated vertex colours) at once with
/// [`crate::simd::shade_small_eight`] (on a 4x target [`crate::simd::shade_small_samples`]),
/// after the queue's earlier fragments: returns how many
/// and their covered pixels (none, nothing drawn, when the first has no such colour). Out of
/// line: inlined, it grew the tile loop, whose other calls the compiler then inlined
/// differently (fill, which never takes it, 4% slower on two threads).
#[inline(never)]
fn shade_small_run<'a, S: Record, F: TriangleFragments<S::Payload>>(
    band: &mut TargetBand<'_>,
    records: &[&'a S],
    (run, boxes, depth_test): (std::ops::Range<usize>, &[PixelRect; 8], DepthTest),
    fragments: &F,
    queue: &mut shade::SharedLaneQueue<'a, S::Payload>,
    setup: &mut EightSetup,
) -> (usize, u64) {
    let (mut level, mut end) = (None, run.start);
    while end < run.end {
        let Some(p) = records[end].kept() else { break };
        let Some((l, SpanColor::Perspective(c))) = fragments.small_color(&p.payload) else {
            break;
        };
        setup.shading.set(end, &boxes[end], &p.depth, &c, p.id);
        (level, end) = (Some(l), end + 1);
    }
    let Some(level) = level else { return (0, 0) };
    queue.flush(band, fragments);
    let (small, shading) = (&setup.small, &setup.shading);
    let lanes = run.start..end;
    let covered = if band.samples().count() > 1 {
        let parts = (small, &setup.samples, shading);
        crate::simd::shade_small_samples(level, parts, lanes, band, depth_test)
    } else {
        crate::simd::shade_small_eight(level, small, shading, lanes, band, depth_test)
    };
    (end - run.start, covered)
}

/// Shades `run` (see [`SmallRun`]) within `band` with `depth_test`, after the queue's earlier
/// fragments; returns its covered samples.
pub(crate) fn shade_small_run_lanes<'a, T, F: TriangleFragments<T>>(
    band: &mut TargetBand<'_>,
    run: &SmallRun,
    depth_test: DepthTest,
    (fragments, queue): (&F, &mut shade::SharedLaneQueue<'a, T>),
) -> u64 {
    queue.flush(band, fragments);
    if band.samples().count() > 1 {
        let parts = (&run.coverage, &run.samples, &run.shading);
        return crate::simd::shade_small_samples(run.level, parts, 0..8, band, depth_test);
    }
    crate::simd::shade_small_eight(run.level, &run.coverage, &run.shading, 0..8, band, depth_test)
}

/// The lanes of up to eight records that [`shade_eight`] takes together as small
/// triangles, and of those the ones that share the lane queue: kept whole, without a span
/// kernel, `shared`, with a box of at most [`crate::simd::SMALL_BOX`] pixels a side that
/// reaches `clip`, and either small enough for the queue ([`queued`]'s test) or, when
/// `kernels` (the fragment stage may give the small kernel colours,
/// [`TriangleFragments::small_colors`]), larger. Their coverage is set up in `setup` and
/// their boxes within `clip` in `boxes`; none where fewer than [`SMALL_EIGHT_MIN`] are
/// ([`SMALL_EIGHT_MIN_QUEUED`] where they share the queue on a 4x target).
/// `multisampled` (a 4x target): the boxes of their samples ([`crate::simd::samples_box`])
/// and each sample's coverage, and those share the queue when `deferred` (the stage lets
/// their colour wait behind their depth, [`TriangleFragments::defers_colour`]), whatever
/// their size.
#[inline(always)]
fn small_lanes<S: Record, K>(
    records: &[&S],
    (clip, shared, kernel, kernels): (&PixelRect, impl Fn(&Prepared<S::Payload>) -> bool, &K, bool),
    (multisampled, deferred): (bool, bool),
    setup: &mut EightSetup,
    boxes: &mut [PixelRect; 8],
) -> (u8, u8)
where
    K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)>,
{
    let mut lanes = [crate::simd::SmallLane::default(); 8];
    let (mut smallest, mut queue) = (0u8, 0u8);
    let mut span = [1, 1];
    for (l, &record) in records.iter().enumerate() {
        let Some(p) = record.kept() else { continue };
        let samples_box;
        let b = if multisampled {
            samples_box = crate::simd::samples_box(&p.setup);
            &samples_box
        } else {
            &p.setup.bounds
        };
        let fits_queue =
            if multisampled { deferred } else { p.setup.area2 <= shade::SHARED_QUEUE_AREA2 };
        // The box first, `shared` last (it may compute the coverage rectangle).
        let small = crate::simd::SMALL_BOX;
        if b.x1 - b.x0 < small
            && b.y1 - b.y0 < small
            && (fits_queue || kernels)
            && kernel(&p.payload).is_none()
            && shared(p)
            && let Some(r) = b.intersect(clip)
        {
            let (xy, clockwise) = (p.setup.xy, p.setup.clockwise);
            lanes[l] = crate::simd::SmallLane { xy, clockwise, first: [r.x0, r.y0] };
            boxes[l] = r;
            span = [span[0].max(r.x1 - r.x0 + 1), span[1].max(r.y1 - r.y0 + 1)];
            smallest |= 1 << l;
            queue |= u8::from(fits_queue) << l;
        }
    }
    let least = if multisampled && deferred { SMALL_EIGHT_MIN_QUEUED } else { SMALL_EIGHT_MIN };
    if smallest.count_ones() < least {
        return (0, 0);
    }
    let span = span.map(|s| s as usize);
    crate::simd::small_eight(SimdLevel::detected(), &lanes, span, &mut setup.small);
    if multisampled {
        let level = SimdLevel::detected();
        crate::simd::small_samples(level, &mut setup.small, span, &mut setup.samples);
    }
    (smallest, queue)
}

/// Shades prepared triangle `p` within `rect`: with the span kernel `kernel` where there is
/// one, otherwise its fragments through `fragments` (what the band and tile loops draw for
/// a triangle that does not share a lane queue).
#[inline(always)]
pub(crate) fn shade_prepared<T, F: TriangleFragments<T>>(
    band: &mut TargetBand<'_>,
    p: &Prepared<T>,
    rect: &PixelRect,
    depth_test: DepthTest,
    kernel: Option<(SimdLevel, &SpanColor)>,
    fragments: &F,
) -> u64 {
    shade::shade_triangle(
        band,
        &p.setup,
        coverage_algorithm(&p.setup),
        rect,
        &p.depth,
        depth_test,
        p.id,
        kernel,
        OfTriangle(fragments, &p.payload),
    )
}

/// The fastest of the (identical) rasterizers for a triangle: scanline spans cost a few
/// divisions per row however wide the row, edge stepping a few additions per pixel of the
/// bounding box; narrow triangles are cheaper to step, as branch-free row masks, and tall
/// thin ones to walk by columns (both [`Algorithm::EdgeMasks`]).
pub(crate) fn coverage_algorithm(setup: &TriangleSetup) -> Algorithm {
    let b = &setup.bounds;
    if b.x1 - b.x0 < crate::raster::edge::NARROW || crate::raster::column::is_tall(b) {
        Algorithm::EdgeMasks
    } else {
        Algorithm::Scanline
    }
}

/// Renders prepared triangles through tiles on the current rayon thread pool, within the clip
/// rectangle they were prepared for ([`PreparedBatch::coverage`]); returns the number of
/// covered samples. Uses the bins [`PreparedBatch::bin`] made if they were made for this
/// target and depth test, and bins the batch itself otherwise.
/// `fragments` shades the pixels of the triangle with record `payload`: one at a time
/// ([`TriangleFragments::fragment`]), or at 1x up to eight at a time
/// ([`TriangleFragments::lanes`]); `None` discards a fragment, which only `may_discard`
/// allows. Where `kernel(payload)` gives a span kernel, it shades instead 1x spans and
/// narrow triangles, and multisampled pixels whose samples are all covered. With `eight`,
/// at 1x, records are set up for the narrow kernel eight at a time at that level where
/// their kind can be ([`Record::narrow_eight`]).
///
/// Hierarchical depth (`Less` or `LessEqual`, no overdraw buffer, which counts hidden
/// fragments too; at any sample count, with depths bounded over each pixel's samples): each
/// block of a tile keeps a bound on the largest depth stored in it (`TileDepth`), and a wide
/// triangle (its clipped coverage at least half a tile wide) whose depth over a block is at
/// or behind it fails the test at every pixel there, so the block is skipped. A bound starts
/// as the block's largest depth (computed when a wide triangle first needs it) and drops to
/// a triangle's largest depth when it covers the whole block and nothing discards. Wide
/// triangles' fragments are counted once per triangle while binning, not tile by tile
/// (skipped blocks are not shaded, so shading cannot count them).
pub fn draw_binned<S, K, F>(
    target: &mut Target,
    prepared: &PreparedBatch<S>,
    depth_test: DepthTest,
    kernel: K,
    fragments: F,
    may_discard: bool,
    eight: Option<SimdLevel>,
) -> u64
where
    S: Record,
    K: Fn(&S::Payload) -> Option<(SimdLevel, &SpanColor)> + Sync,
    F: TriangleFragments<S::Payload>,
{
    let coverage = prepared.coverage();
    let clip = &coverage.clip;
    let samples = target.samples();
    let kind = Eight::of(eight, samples);
    debug_assert_eq!(coverage.multisampled, samples.count() > 1, "prepared for other samples");
    let bin_target = BinTarget::of(target, depth_test);
    let computed;
    let (bins, wide_coverage) = match &prepared.binned {
        Some((bins, wide, binned_for)) if *binned_for == bin_target => (bins, *wide),
        _ => {
            computed = bin_batch(prepared, bin_target);
            (&computed.0, computed.1)
        }
    };
    let shaded = bins.draw(target, clip, |band, tile, list| {
        let mut covered = 0;
        let mut tile_depth = TileDepth::new(depth_test, samples);
        // Small triangles' fragments share a queue, written before any other triangle is
        // drawn (hierarchical depth reads the depth buffer) and at the tile's end.
        let mut queue = shade::SharedLaneQueue::new();
        // Drawn with hierarchical depth, by the rectangle binning had (the same function of
        // the same record).
        let hidden = |setup: &TriangleSetup| {
            bin_target.hierarchical && coverage.of(setup).is_some_and(|r| bin_target.wide(&r))
        };
        let shared = |p: &Prepared<S::Payload>| !hidden(&p.setup);
        let stages = (&kernel, &fragments);
        let whole_tile = prefetch_whole_tile(samples, list.len());
        if whole_tile {
            band.prefetch(tile);
        }
        // Triangle `j` of the list, on its own.
        let mut one = |band: &mut TargetBand<'_>, queue: &mut _, j: usize| {
            if let Some(&ahead) = list.get(j + PREFETCH_AHEAD) {
                crate::simd::prefetch(prepared.get(ahead));
            }
            // Or, where the tile was not, each triangle's first rows (its record, prefetched
            // earlier, is in the cache by then; the first two are not prefetched).
            let near = list.get(j + 2).filter(|_| !whole_tile).map(|&k| prepared.get(k).setup());
            if let Some(r) = near.and_then(|setup| coverage_bounds(&setup, true, tile)) {
                band.prefetch(&PixelRect { y1: r.y1.min(r.y0 + 7), ..r });
            }
            let record = prepared.get(list[j]);
            shade_record(band, record, tile, depth_test, shared, stages, queue, |band, p| {
                let kernel = kernel(&p.payload);
                let shade = |band: &mut TargetBand<'_>, rect: &PixelRect| {
                    shade_prepared(band, p, rect, depth_test, kernel, &fragments)
                };
                if hidden(&p.setup) {
                    // Its fragments were counted while binning.
                    tile_depth.shade(band, tile, p, !may_discard, shade);
                    0
                } else {
                    shade(band, tile)
                }
            })
        };
        let mut setup = EightSetup::default();
        for &ahead in list.iter().take(EIGHTS_AHEAD).skip(8) {
            crate::simd::prefetch(prepared.get(ahead));
        }
        for (c, next) in list.chunks(8).enumerate() {
            for &ahead in list.iter().skip(8 * c + EIGHTS_AHEAD).take(8) {
                crate::simd::prefetch(prepared.get(ahead));
            }
            let mut records = [prepared.get(next[0]); 8];
            for (r, &i) in records.iter_mut().zip(next) {
                *r = prepared.get(i);
            }
            let records = &records[..next.len()];
            let stages = (shared, stages);
            let one = |band: &mut TargetBand<'_>, queue: &mut _, l| one(band, queue, 8 * c + l);
            let run = (kind, tile, depth_test);
            covered += shade_eight(band, records, run, stages, (&mut queue, &mut setup), one);
        }
        queue.flush(band, &fragments);
        covered
    });
    shaded + wide_coverage
}

/// What binning a batch depends on besides the batch: the target's size and samples per
/// pixel, and whether it is drawn with hierarchical depth (a depth test, no overdraw buffer),
/// whose wide triangles' samples binning counts. Plain values, so the side preparing a batch
/// can bin it while the other side draws into the target.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BinTarget {
    width: u32,
    height: u32,
    samples: SampleCount,
    hierarchical: bool,
}

impl BinTarget {
    /// Whether a triangle with (clipped) coverage rectangle `r` takes the hierarchical depth
    /// test: binning and the tile loop ask this of the same rectangle.
    fn wide(&self, r: &PixelRect) -> bool {
        self.hierarchical && r.x1 - r.x0 + 1 >= HIDDEN_MIN_WIDTH
    }

    /// What `target`, drawn with `depth_test`, bins for.
    #[must_use]
    pub fn of(target: &Target, depth_test: DepthTest) -> Self {
        Self {
            width: target.width(),
            height: target.height(),
            samples: target.samples(),
            hierarchical: depth_test != DepthTest::Always && target.overdraw.is_none(),
        }
    }
}

/// Bins a prepared batch for `to`, counting the samples of the wide triangles (whose
/// fragments hierarchical depth may leave unshaded) as it goes.
fn bin_batch<S: Record>(prepared: &PreparedBatch<S>, to: BinTarget) -> (Bins, u64) {
    let BinTarget { width, height, samples, .. } = to;
    // Counted while binning (a pass of its own was a twentieth of a frame of small
    // triangles, waiting on memory).
    let wide_coverage = AtomicU64::new(0);
    let bins = Bins::of_batch(prepared, width, height, samples.reach(), |i, r| {
        if to.wide(r) {
            let setup = prepared.get(i).setup();
            wide_coverage.fetch_add(coverage_count(&setup, r, samples), Ordering::Relaxed);
        }
    });
    (bins, wide_coverage.into_inner())
}

impl<S: Record> PreparedBatch<S> {
    /// Bins the batch for `to` as part of preparing it, so that [`draw_binned`] finds its bins
    /// made (it bins a batch that was not binned, or was binned for another target, itself).
    /// In [`pipelined`] this moves binning from the side drawing to the side preparing: a
    /// coherent mesh's batch covers a strip of bands that few threads draw, while the side
    /// preparing has time to spare (grid on two threads: 78 -> 72 ms). The first batch is
    /// better left to [`draw_binned`]: nothing is drawn beside its preparation.
    pub fn bin(&mut self, to: BinTarget) {
        self.binned = None;
        let (bins, wide) = bin_batch(self, to);
        self.binned = Some((bins, wide, to));
    }
}

/// Side of the blocks of a tile whose depth bounds [`TileDepth`] keeps (64 in tiles of 128:
/// fill 26.6 ms; 32: 28.1 ms; 16: 38.6 ms, each block's bound costing a pass over it; one
/// bound per tile: 28.6 ms).
const DEPTH_BLOCK: i32 = 64;

/// Blocks per row of a tile.
const DEPTH_BLOCKS: usize = (TILE as i32 / DEPTH_BLOCK) as usize;
const _: () = assert!(TILE as i32 % DEPTH_BLOCK == 0, "blocks must tile a tile");

/// A tile's hierarchical depth: per block of [`DEPTH_BLOCK`] pixels square, a bound on the
/// largest depth stored in it, once a wide triangle needs it.
struct TileDepth {
    test: DepthTest,
    samples: SampleCount,
    max: [Option<f32>; DEPTH_BLOCKS * DEPTH_BLOCKS],
}

impl TileDepth {
    fn new(test: DepthTest, samples: SampleCount) -> Self {
        Self { test, samples, max: [None; DEPTH_BLOCKS * DEPTH_BLOCKS] }
    }

    /// Shades a wide triangle into `tile` with `shade(band, clip)`, except in the blocks where
    /// its depth is at or behind the bound (there every pixel fails the test); lowers a block's
    /// bound when the triangle covers the whole block and `never_discards`. Each row of blocks
    /// is shaded as runs of adjacent blocks, so a triangle hidden nowhere is shaded in a few
    /// calls, not one per block. Out of line: the loop over small triangles stays as small as
    /// it was.
    #[inline(never)]
    fn shade<T>(
        &mut self,
        band: &mut TargetBand<'_>,
        tile: &PixelRect,
        p: &Prepared<T>,
        never_discards: bool,
        mut shade: impl FnMut(&mut TargetBand<'_>, &PixelRect) -> u64,
    ) {
        let multisampled = self.samples.count() > 1;
        let Some(r) = coverage_bounds(&p.setup, multisampled, tile) else { return };
        let reach = self.samples.reach();
        // Blocks are aligned to the unclipped tile.
        let origin = |v: i32| v - v % TILE as i32;
        let (ox, oy) = (origin(tile.x0), origin(tile.y0));
        // Block `(bx, by)` within the tile, and within the triangle's box.
        let block = |bx: i32, by: i32| {
            let x0 = ox + bx * DEPTH_BLOCK;
            let y0 = oy + by * DEPTH_BLOCK;
            let b = PixelRect { x0, y0, x1: x0 + DEPTH_BLOCK - 1, y1: y0 + DEPTH_BLOCK - 1 };
            let whole = b.intersect(tile)?;
            Some((whole, whole.intersect(&r)?))
        };
        let (bx0, bx1) = ((r.x0 - ox) / DEPTH_BLOCK, (r.x1 - ox) / DEPTH_BLOCK);
        for by in (r.y0 - oy) / DEPTH_BLOCK..=(r.y1 - oy) / DEPTH_BLOCK {
            // The run of visible blocks being gathered, as a rectangle.
            let mut run: Option<PixelRect> = None;
            for bx in bx0..=bx1 + 1 {
                let visible = if bx > bx1 {
                    None
                } else {
                    block(bx, by).and_then(|(whole, b)| {
                        let slot = by as usize * DEPTH_BLOCKS + bx as usize;
                        self.visible(band, p, (&whole, &b, reach), never_discards, slot)
                    })
                };
                match (visible, &mut run) {
                    (Some(b), Some(run)) => run.x1 = b.x1,
                    (Some(b), None) => run = Some(b),
                    (None, Some(done)) => {
                        shade(band, done);
                        run = None;
                    }
                    (None, None) => {}
                }
            }
        }
    }

    /// The pixels `b` of a block (`whole` within the tile, bound `slot`, samples within `reach`
    /// of the centres) that lie in the triangle's box, when the triangle may pass the depth
    /// test there; `None` when it is
    /// hidden. Lowers the block's bound as [`TileDepth::shade`] says, ahead of the shading
    /// (which follows before any other triangle is drawn).
    fn visible<T>(
        &mut self,
        band: &TargetBand<'_>,
        p: &Prepared<T>,
        (whole, b, reach): (&PixelRect, &PixelRect, i64),
        never_discards: bool,
        slot: usize,
    ) -> Option<PixelRect> {
        let (near, far) = shade::depth_bounds(&p.depth, &p.setup, b, reach);
        let slot = &mut self.max[slot];
        let max = *slot.get_or_insert_with(|| band.max_depth(whole));
        let hidden = match self.test {
            DepthTest::Less => near >= max,
            DepthTest::LessEqual => near > max,
            DepthTest::Always => false,
        };
        if hidden {
            return None;
        }
        if never_discards && crate::raster::covers_rect_within(&p.setup, whole, reach) {
            // Every pixel of the block will hold at most the triangle's depth there.
            *slot = Some(max.min(far));
        }
        Some(*b)
    }
}

/// Samples of the pixels of `rect` a triangle covers, without shading them.
fn coverage_count(setup: &TriangleSetup, rect: &PixelRect, samples: SampleCount) -> u64 {
    let n = samples.count();
    if crate::raster::covers_rect_within(setup, rect, samples.reach()) {
        return rect.area() as u64 * n as u64;
    }
    let mut covered = 0;
    for s in 0..n {
        let offset = samples.offset(s);
        crate::raster::rasterize_sample(Algorithm::Scanline, setup, rect, offset, |span| {
            covered += span.len() as u64;
        });
    }
    covered
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    /// Bins of a target larger than any target can be are refused with a message, where
    /// sides of 2^21 had asked for 6 GB and larger ones overflowed the tile count.
    #[test]
    #[should_panic(expected = "sides are at most 16384")]
    fn bins_of_an_impossible_target_are_refused() {
        let _ = Bins::build(&[], 1 << 21, 1 << 21);
    }

    /// Bins draw into a target with their own tiles, which may be another size within the
    /// same tiles; a target of other tiles is refused by a panic naming both (a taller one
    /// had indexed past the lists, a wider one been left undrawn); default bins draw nothing.
    #[test]
    fn bins_draw_only_into_targets_of_their_tiles() {
        let one = [Some(PixelRect { x0: 0, y0: 0, x1: 3, y1: 3 })];
        let bins = Bins::build(&one, 200, 100);
        let drawn = |bins: &Bins, width: u32, height: u32| {
            let mut target = Target::new(width, height).unwrap();
            let clip = target.rect();
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                bins.draw(&mut target, &clip, |_, _, list| list.len() as u64)
            }))
            .map_err(|e| *e.downcast::<String>().unwrap())
        };
        assert_eq!(drawn(&bins, 200, 100), Ok(1));
        assert_eq!(drawn(&bins, 129, 128), Ok(1));
        for (width, height) in [(200, 129), (257, 100), (128, 100)] {
            let message = drawn(&bins, width, height).unwrap_err();
            let want = format!("bins of 2 x 1 tiles drawn into a {width} x {height} target");
            assert_eq!(message, want);
        }
        assert_eq!(drawn(&Bins::default(), 300, 300), Ok(0));
    }

    /// Batches of records up to 64 bytes (window records, zero-sized ones) take [`BATCH`]
    /// triangles; larger records fewer, their bytes at most [`BATCH_BYTES`] and within a
    /// record of it; never none.
    #[test]
    fn batches_hold_a_bounded_number_of_bytes() {
        assert_eq!(batch_for::<()>(), BATCH);
        assert_eq!(batch_for::<[u8; 64]>(), BATCH);
        assert_eq!(batch_for::<crate::render::WindowRecord>(), BATCH);
        fn bytes<S>() -> (usize, usize) {
            (batch_for::<S>(), batch_for::<S>() * size_of::<S>())
        }
        for (n, b) in [bytes::<[u8; 65]>(), bytes::<[u8; 272]>(), bytes::<[u64; 1000]>()] {
            assert!(n < BATCH && b <= BATCH_BYTES && b + b / n > BATCH_BYTES, "{n} {b}");
        }
        assert_eq!(batch_for::<[u8; BATCH_BYTES + 1]>(), 1);
    }

    /// `pipelined` hands each draw the batch prepared for it, draws every batch once and in
    /// order, whatever the count (none, one, several) and the thread count.
    #[test]
    fn pipelined_draws_every_batch_in_order() {
        // The batch lengths: as many batches as of `max` items, none longer, the last
        // shorter than the others by less than the batch count, none empty.
        for n in 0..600 {
            for max in 1..70 {
                let len = even_batch_len(n, max);
                assert_eq!(even_batch_len(n, len), len, "{n} items, max {max}");
                let batches = n.div_ceil(len);
                assert!(len <= max && batches == n.div_ceil(max), "{n} items, max {max}");
                if n > 0 {
                    let last = n - (batches - 1) * len;
                    assert!(last >= 1 && len - last < batches, "{n} items, max {max}");
                }
            }
        }
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            for batches in [0usize, 1, 2, 7] {
                let drawn = Mutex::new(Vec::new());
                let mut pair = PreparedPair::<Prepared<()>>::default();
                // As many batches as batches of 10 would make, of equal length but the last.
                let items: Vec<usize> = (0..(10 * batches).saturating_sub(3)).collect();
                let len = even_batch_len(items.len(), 10);
                pool.install(|| {
                    pipelined(
                        &items,
                        10,
                        &mut pair,
                        // Batch `b` is prepared as `b + 1` chunks (of nothing): its mark.
                        |b, first, batch, prepared| {
                            assert_eq!((first, batch[0]), (len * b, len * b), "batch {b}");
                            assert!(batch.len() == len || b + 1 == batches, "batch {b}");
                            prepared.prepare_ranges(b * CHUNK + 1, Coverage::default(), |_, _| {});
                        },
                        |b, batch| {
                            assert_eq!(batch.chunk_count(), b + 1, "batch {b} drawn from another");
                            drawn.lock().unwrap().push(b);
                        },
                    );
                });
                let drawn = drawn.into_inner().unwrap();
                assert_eq!(drawn, (0..batches).collect::<Vec<_>>(), "{threads} threads");
            }
        }
    }
}

#[cfg(test)]
mod binned_tests {
    use super::*;
    use crate::sample::SampleCount;
    use crate::setup::{CullMode, Vertex};
    use crate::shade::{FragmentOutput, Shading, TriangleColor, TriangleShader};
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// `triangles` set up for `coverage`, smooth colour, ids by index.
    fn prepared_batch(
        triangles: &[[Vertex; 3]],
        coverage: Coverage,
    ) -> PreparedBatch<Prepared<TriangleColor>> {
        let mut batch = PreparedBatch::default();
        batch.prepare(triangles.len(), coverage, |k, sink| {
            let tri = &triangles[k];
            let Ok(setup) = TriangleSetup::new(tri, CullMode::None) else { return };
            let (depth, payload) = TriangleShader::new(tri, &setup, Shading::Smooth).into_parts();
            sink.push(Prepared { setup, depth, id: k as i32, payload });
        });
        batch
    }

    /// Triangles over many tiles are binned to every tile where they cover a sample, and
    /// long slivers to few others: random slivers across a 1000 x 700 target (8 x 6 tiles)
    /// and large random triangles, at 1x and 4x, each pair of triangle and tile checked by
    /// rasterizing the triangle's samples there.
    #[test]
    fn triangles_over_many_tiles_are_binned_where_they_cover_samples() {
        let mut rng = SmallRng::seed_from_u64(8);
        let (w, h) = (1000u32, 700u32);
        let triangles: Vec<[Vertex; 3]> = (0..300)
            .map(|k| {
                let mut point =
                    || (rng.random_range(-50.0..1050.0), rng.random_range(-50.0..750.0));
                let (a, b) = (point(), point());
                // Every other triangle a sliver: its third vertex within 3 pixels of the first.
                let c = if k % 2 == 0 { (a.0 + 2.5, a.1 - 1.5) } else { point() };
                [a, b, c].map(|(x, y)| Vertex::new(x, y, 0.5, [255; 4]))
            })
            .collect();
        for samples in [SampleCount::X1, SampleCount::X4] {
            let target = Target::multisampled(w, h, samples).unwrap();
            let coverage = Coverage { clip: target.rect(), multisampled: samples.count() > 1 };
            let mut batch = prepared_batch(&triangles, coverage);
            batch.bin(BinTarget::of(&target, DepthTest::Less));
            let bins = &batch.binned.as_ref().unwrap().0;
            let grid = TileGrid::of_size(w, h);
            // Tiles a sliver is binned to without covering a sample there: only where the
            // trivial reject is conservative (its triangle's corners near the tile's).
            let (mut covered, mut needless) = (0, 0);
            for (i, _) in batch.indexed_covers(0..batch.chunk_count()) {
                let p = batch.get(i);
                for t in 0..grid.tiles {
                    let tile = grid.tile_rect(t);
                    let mut covers = false;
                    for s in 0..samples.count() {
                        let offset = samples.offset(s);
                        let edge = Algorithm::EdgeFunctions;
                        raster::rasterize_sample(edge, &p.setup, &tile, offset, |_| covers = true);
                    }
                    let (tx, ty) = ((t % grid.tiles_x) as usize, (t / grid.tiles_x) as usize);
                    let listed = bins.tile(tx, ty).contains(&i);
                    assert!(listed || !covers, "{i} not binned to tile {t}, at {samples:?}");
                    if p.id % 2 == 0 {
                        covered += usize::from(covers);
                        needless += usize::from(listed && !covers);
                    }
                }
            }
            assert!(needless * 4 < covered, "{samples:?}: {needless} needless, {covered} covered");
        }
    }

    /// A batch binned while it was prepared draws what binning in `draw_binned` draws, and a
    /// batch binned for another target (here, one without the overdraw buffer, so with
    /// hierarchical depth and its wide triangles counted while binning) is binned again, not
    /// drawn with the wrong bins and counts.
    #[test]
    fn batches_binned_ahead_draw_what_binning_later_draws() {
        let mut rng = SmallRng::seed_from_u64(3);
        let triangles: Vec<[Vertex; 3]> = (0..3000)
            .map(|k| {
                // Mostly small, every tenth wide enough for hierarchical depth.
                let size = if k % 10 == 0 { 150.0 } else { 8.0 };
                let (cx, cy) = (rng.random_range(0.0..300.0), rng.random_range(0.0..200.0));
                std::array::from_fn(|_| {
                    let color = [rng.random(), rng.random(), rng.random(), 255];
                    let (dx, dy) = (rng.random_range(-size..size), rng.random_range(-size..size));
                    Vertex::new(cx + dx, cy + dy, rng.random_range(0.0..1.0), color)
                })
            })
            .collect();
        let draw = |bin_for: Option<&Target>, with_overdraw: bool| {
            let mut target = Target::new(300, 200).unwrap().with_ids();
            if with_overdraw {
                target = target.with_overdraw();
            }
            let coverage = Coverage { clip: target.rect(), multisampled: false };
            let mut batch = prepared_batch(&triangles, coverage);
            if let Some(other) = bin_for {
                batch.bin(BinTarget::of(other, DepthTest::Less));
                // Bins stored, for `other`: reused exactly when it is this target.
                let stored = batch.binned.as_ref().map(|b| b.2);
                assert_eq!(stored, Some(BinTarget::of(other, DepthTest::Less)));
            }
            let level = SimdLevel::detect();
            let fragments = draw_binned(
                &mut target,
                &batch,
                DepthTest::Less,
                |c| c.span_color().map(|s| (level, s)),
                |c: &TriangleColor, _, _, e1, e2, _| {
                    Some(FragmentOutput { color: c.color_at(e1, e2), normal: None })
                },
                false,
                None,
            );
            (fragments, target.color, target.depth, target.ids, target.overdraw)
        };
        for with_overdraw in [false, true] {
            let later = draw(None, with_overdraw);
            let mut same = Target::new(300, 200).unwrap();
            if with_overdraw {
                same = same.with_overdraw();
            }
            assert!(later == draw(Some(&same), with_overdraw), "binned ahead, {with_overdraw}");
            // Binned for a target that differs in its overdraw buffer (so in hierarchical
            // depth), or in its size: binned again.
            let other = Target::new(300, 200).unwrap();
            let other = if with_overdraw { other } else { other.with_overdraw() };
            assert!(later == draw(Some(&other), with_overdraw), "binned for another target");
            let smaller = Target::new(200, 100).unwrap();
            let smaller = if with_overdraw { smaller.with_overdraw() } else { smaller };
            assert!(later == draw(Some(&smaller), with_overdraw), "binned for another size");
        }
    }
}
