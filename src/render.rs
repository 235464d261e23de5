//! The draw call: runs `setup -> raster -> shade` over a triangle list, in submission order.

use crate::band::{self, Plan};
use crate::bin::{self, Prepared, Skipped};
use crate::error::Error;
use crate::raster::Algorithm;
use crate::sample::SampleCount;
use crate::setup::{CullMode, PixelRect, Rejection, TriangleSetup, Vertex};
use crate::shade::{self, DepthTest, FragmentOutput, Shading, TriangleColor, TriangleShader};
use crate::simd::{self, SimdLevel, SpanColor};
use crate::target::Target;

/// How to draw. `RenderOptions::default()` is: edge functions, smooth shading, no culling,
/// LESS depth test, no scissor, the tiled backend at the best SIMD level, its schedule chosen
/// per draw call.
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
    /// Reference (one triangle after another) or tiled (multithreaded, SIMD).
    pub backend: Backend,
    /// SIMD level for the tiled backend's kernels (set-up of eight triangles at once, spans,
    /// narrow triangles, multisampled spans); `None` picks the best available.
    pub simd: Option<SimdLevel>,
    /// How the tiled backend spreads the work over threads.
    pub schedule: Schedule,
}

/// How a draw call is executed. Both give bit-identical buffers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// The reference: each triangle rasterized and shaded over the whole target in turn. The
    /// oracle the tiled path is tested against.
    Reference,
    /// Set up and rendered in parallel on the current rayon pool, binned into 128 x 128
    /// tiles or in bands of rows ([`Schedule`]).
    #[default]
    Tiled,
}

/// How the tiled backend spreads a draw call over threads. Every schedule gives the same
/// buffers and counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Schedule {
    /// Bands for small triangles in spatial order, bins otherwise ([`band::plan`] decides from
    /// a sample of the triangles).
    #[default]
    Auto,
    /// Bins per 128 x 128 tile, drawn tile by tile (sort-middle, [`bin`]).
    Binned,
    /// Horizontal bands, one per thread, each running the front end over every triangle
    /// (setup for window triangles; the corner tests, and setup of those in its rows, for
    /// meshes) and drawing what falls in it (sort-first, [`band`]). Meshes with more than
    /// 2^20 vertices, shaded batch by batch, are binned whatever the schedule.
    Banded,
}

impl Schedule {
    /// Its name in lower case, as `TRIRAST_SCHEDULE` and `trirast bench` spell it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Binned => "binned",
            Self::Banded => "banded",
        }
    }

    /// The schedule [`Schedule::name`] spells `name`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Auto, Self::Binned, Self::Banded].into_iter().find(|s| s.name() == name)
    }

    /// This schedule, or for [`Schedule::Auto`] the one named by the environment variable
    /// `TRIRAST_SCHEDULE` (`binned`, `banded`) when that is set (comparisons, as
    /// `TRIRAST_SIMD` for kernels).
    #[must_use]
    pub fn or_forced(self) -> Self {
        let forced = std::env::var("TRIRAST_SCHEDULE").ok().and_then(|n| Self::from_name(&n));
        match (self, forced) {
            (Self::Auto, Some(schedule)) => schedule,
            (schedule, _) => schedule,
        }
    }
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

    /// Forces a SIMD level (for tests and comparisons); unavailable levels run scalar.
    #[must_use]
    pub fn with_simd(mut self, level: SimdLevel) -> Self {
        self.simd = Some(level);
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
    /// Triangles that reached the rasterizer (a triangle clipping cut into pieces once).
    pub rasterized: usize,
    /// The pieces of rasterized triangles beyond one each: what clipping added (each clip
    /// plane a triangle crosses can add a vertex to its fan).
    pub extra_pieces: usize,
    /// Dropped for a NaN or infinite coordinate.
    pub non_finite: usize,
    /// Dropped for zero area after snapping.
    pub degenerate: usize,
    /// Removed by culling.
    pub culled: usize,
    /// Fragments generated (covered samples, before the depth test).
    pub fragments: u64,
}

impl DrawStats {
    /// The sums of two sets of counts.
    #[must_use]
    pub fn merged(&self, other: &Self) -> Self {
        Self {
            submitted: self.submitted + other.submitted,
            rasterized: self.rasterized + other.rasterized,
            extra_pieces: self.extra_pieces + other.extra_pieces,
            non_finite: self.non_finite + other.non_finite,
            degenerate: self.degenerate + other.degenerate,
            culled: self.culled + other.culled,
            fragments: self.fragments + other.fragments,
        }
    }

    /// Counts a triangle the tiled front end skipped.
    pub fn skip(&mut self, why: Skipped) {
        self.skip_many(why, 1);
    }

    /// Counts `n` triangles skipped for the same reason.
    pub fn skip_many(&mut self, why: Skipped, n: usize) {
        match why {
            Skipped::Rejected(Rejection::NonFinite) => self.non_finite += n,
            Skipped::Rejected(Rejection::Culled) => self.culled += n,
            // Setup refuses a triangle past the range, which `draw` then clips, so these are
            // clipped pieces' (in the 3D pipeline, a degenerate leftover of the guard band).
            Skipped::Rejected(Rejection::Degenerate | Rejection::OutOfRange) => {
                self.degenerate += n;
            }
            // Set up like any other: it reached the rasterizer, which finds no sample.
            Skipped::Empty => self.rasterized += n,
        }
    }

    /// Counts a triangle that setup rejected.
    pub fn reject(&mut self, why: Rejection) {
        self.skip_many(Skipped::Rejected(why), 1);
    }
}

/// Draws `triangles` into `target`; triangle `i` has id `i`.
///
/// A triangle with a vertex outside the fixed-point range ([-32768, 32768) pixels) is clipped
/// to that range and drawn as the pieces of its clipped polygon, with its id (only edges
/// with an end past the range are cut, so its neighbours still meet it edge to edge),
/// counting once, as the 3D pipeline counts a clipped triangle; NaN or infinite vertices
/// drop their triangle and are counted in the returned stats.
///
/// # Errors
/// [`Error::TargetBuffer`] when one of `target`'s buffers was replaced by one of another
/// length ([`Target::check_buffers`]).
pub fn draw(
    target: &mut Target,
    triangles: &[[Vertex; 3]],
    options: &RenderOptions,
) -> Result<DrawStats, Error> {
    target.set_schedule(None);
    target.check_buffers()?;
    let clip = match options.scissor {
        Some(s) => s.intersect(&target.rect()),
        None => Some(target.rect()),
    };
    let mut stats = DrawStats { submitted: triangles.len(), ..DrawStats::default() };
    if options.backend == Backend::Tiled {
        let tiled = match options.shading {
            Shading::Perspective => draw_tiled::<TriangleColor>,
            Shading::Flat | Shading::Smooth => draw_tiled::<SpanColor>,
        };
        return Ok(tiled(target, triangles, options, clip, stats));
    }
    let color = |color: &TriangleColor, e1, e2| FragmentOutput {
        color: color.color_at(e1, e2),
        normal: None,
    };
    let mut shade = |tri: &[Vertex; 3], setup: &TriangleSetup, id: usize| {
        let Some(clip) = clip else { return 0 };
        let (depth, shader) = TriangleShader::new(tri, setup, options.shading).into_parts();
        shade::shade_triangle(
            &mut target.band(),
            setup,
            options.algorithm,
            &clip,
            &depth,
            options.depth_test,
            id as i32,
            None,
            |_, _, e1, e2, _| Some(color(&shader, e1, e2)),
        )
    };
    for (id, tri) in triangles.iter().enumerate() {
        match TriangleSetup::new(tri, options.cull) {
            Ok(setup) => {
                stats.rasterized += 1;
                stats.fragments += shade(tri, &setup, id);
            }
            Err(Rejection::OutOfRange) => match clipped_pieces(tri, options) {
                Ok(pieces) => {
                    stats.rasterized += 1;
                    stats.extra_pieces += pieces.len() - 1;
                    for (piece, setup) in &pieces {
                        stats.fragments += shade(piece, setup, id);
                    }
                }
                Err(why) => stats.reject(why),
            },
            Err(why) => stats.reject(why),
        }
    }
    Ok(stats)
}

/// The pieces of window triangle `tri`, which setup refused as reaching past the fixed-point
/// range ([`Rejection::OutOfRange`]): its polygon clipped to the range
/// ([`crate::clip::window_fan`]) and fanned, each piece set up, in order, those setup
/// rejects left out; or, when none is left, how the triangle counts: culled when nothing
/// of it lies in the range, else as its first piece's rejection (one meeting the range only
/// along its bounds leaves degenerate pieces). Clipped here, in the front end, where setup
/// finds such a triangle: a scan of the draw call's vertices for them first read every
/// vertex once more (a fourteenth of a frame of a million small triangles). The triangle
/// counts once, as the 3D pipeline counts a clipped triangle: its first piece as the
/// triangle, the others as [`DrawStats::extra_pieces`].
fn clipped_pieces(
    tri: &[Vertex; 3],
    options: &RenderOptions,
) -> Result<Vec<([Vertex; 3], TriangleSetup)>, Rejection> {
    let perspective = options.shading == Shading::Perspective;
    let fan = crate::clip::window_fan(tri, perspective, options.shading == Shading::Flat);
    let mut first_rejection = None;
    let mut pieces = Vec::with_capacity(fan.len());
    for piece in fan {
        match TriangleSetup::new(&piece, options.cull) {
            Ok(setup) => pieces.push((piece, setup)),
            Err(why) => _ = first_rejection.get_or_insert(why),
        }
    }
    match first_rejection {
        _ if !pieces.is_empty() => Ok(pieces),
        Some(why) => Err(why),
        None => Err(Rejection::Culled),
    }
}

/// The tiled backend of [`draw`], keeping colour `C` per triangle.
fn draw_tiled<C: WindowColor>(
    target: &mut Target,
    triangles: &[[Vertex; 3]],
    options: &RenderOptions,
    clip: Option<PixelRect>,
    mut stats: DrawStats,
) -> DrawStats {
    let level = options.simd.unwrap_or_else(SimdLevel::detect);
    let multisampled = target.samples().count() > 1;
    // With the scissor off the target nothing is visible, but setup still counts.
    let visible = clip.unwrap_or(PixelRect::EMPTY);
    let coverage = bin::Coverage { clip: visible, multisampled };
    let kernel = window_kernel::<C>(level);
    // Narrow triangles set up eight at a time (`simd::narrow_eight`), at AVX-512 and AVX2.
    let eight = matches!(level, SimdLevel::Avx512 | SimdLevel::Avx2).then_some(level);
    let threads = rayon::current_num_threads();
    // Every band sets window triangles up in full: beyond two threads that costs more than
    // bands save (a coherent grid of 1,000,000 window triangles: 101 -> 77 ms banded on one
    // thread, 55 -> 53 ms on two).
    let schedule = match options.schedule.or_forced() {
        Schedule::Auto if threads > 2 => Schedule::Binned,
        schedule => schedule,
    };
    let canvas = (target.height(), target.samples().count());
    let shares = (threads, &target.balance);
    let plan = band::plan(schedule, triangles.len(), canvas, &visible, shares, |k| {
        window_bounds(&triangles[k])
    });
    target.set_schedule(Some(plan.schedule()));
    if let Plan::Banded(bands) = plan {
        let (counts, fragments) = bands.draw(
            target,
            coverage,
            options.depth_test,
            (kernel, eight),
            window_fragment,
            |range, sink: &mut bin::Sink<'_, C::Record>| {
                set_up_window::<C>(triangles, 0, range, options, level, sink);
            },
            |_| None,
        );
        stats = stats.merged(&counts);
        stats.fragments += fragments;
        return stats;
    }
    let mut pair: bin::PreparedPair<C::Record> = target.take_scratch();
    let mut fragments = 0;
    let bin_target = bin::BinTarget::of(target, options.depth_test);
    let prepare = |b, first: usize, batch: &[_], prepared: &mut bin::PreparedBatch<_>| {
        let counts = prepared.prepare_ranges(batch.len(), coverage, |range, sink| {
            set_up_window::<C>(batch, first, range, options, level, sink);
        });
        stats = stats.merged(&counts);
        // Binned here, except the first batch (see `PreparedBatch::bin`).
        if b > 0 && clip.is_some() {
            prepared.bin(bin_target);
        }
    };
    let draw = |_, prepared: &bin::PreparedBatch<C::Record>| {
        if clip.is_some() {
            let test = options.depth_test;
            fragments +=
                bin::draw_binned(target, prepared, test, kernel, window_fragment, false, eight);
        }
    };
    // Batches bounded by bytes: a perspective colour's record is 216 bytes.
    bin::pipelined(triangles, bin::batch_for::<C::Record>(), &mut pair, prepare, draw);
    stats.fragments += fragments;
    target.keep_scratch(pair);
    stats
}

/// The span kernels of window triangles, at `level`, for the colours that have one.
fn window_kernel<C: WindowColor>(
    level: SimdLevel,
) -> impl Fn(&C) -> Option<(SimdLevel, &SpanColor)> + Copy + Sync {
    move |c| c.kernel().map(|k| (level, k))
}

/// The fragment stage of window triangles: the colour `C` keeps, at the pixel centre.
fn window_fragment<C: WindowColor>(
    c: &C,
    _: i32,
    _: i32,
    e1: f64,
    e2: f64,
    _: f32,
) -> Option<FragmentOutput> {
    Some(FragmentOutput { color: c.at(e1, e2), normal: None })
}

/// The tiled backend's front end for window triangles `range` of `batch` (the first of
/// which is triangle `first` of the draw call, and has that id): each set up into `sink`,
/// eight at a time in AVX-512 or AVX2 for flat and smooth colours ([`simd::window_group`]),
/// one at a time otherwise; one reaching past the fixed-point range as its clipped pieces
/// ([`clipped_pieces`]).
fn set_up_window<C: WindowColor>(
    batch: &[[Vertex; 3]],
    first: usize,
    range: std::ops::Range<usize>,
    options: &RenderOptions,
    level: SimdLevel,
    sink: &mut bin::Sink<'_, C::Record>,
) {
    // A triangle setup refused: its pieces, when it was refused for reaching past the range.
    let refused =
        |tri: &[Vertex; 3], why: Rejection, id: i32, sink: &mut bin::Sink<'_, C::Record>| {
            if why != Rejection::OutOfRange {
                return sink.skip_many(why.into(), 1);
            }
            match clipped_pieces(tri, options) {
                Ok(pieces) => {
                    for (k, (piece, setup)) in pieces.into_iter().enumerate() {
                        let inv_area2 = 1.0 / setup.area2 as f64;
                        let record = C::record(&piece, setup, inv_area2, options.shading, id);
                        if k == 0 {
                            sink.push_record(&setup, record);
                        } else {
                            sink.push_extra_record(&setup, record);
                        }
                    }
                }
                Err(why) => sink.skip_many(why.into(), 1),
            }
        };
    let set_up_one = |k: usize, sink: &mut bin::Sink<'_, C::Record>| {
        let (tri, id) = (&batch[k], (first + k) as i32);
        let setup = match TriangleSetup::new(tri, options.cull) {
            Ok(setup) => setup,
            Err(why) => return refused(tri, why, id, sink),
        };
        if sink.coverage().of(&setup).is_none() {
            return sink.skip_many(Skipped::Empty, 1);
        }
        let inv_area2 = 1.0 / setup.area2 as f64;
        let record = C::record(tri, setup, inv_area2, options.shading, id);
        sink.push_record(&setup, record);
    };
    let mut k = range.start;
    // The first records' memory; each group then asks for the next ones'.
    sink.prefetch(0, 8);
    // Flat and smooth colours eight triangles at a time where there is a kernel for it
    // (the same records; the rest, and perspective colours, one at a time).
    let mut group = simd::WindowGroup::default();
    let mut records = simd::WindowRecords::default();
    while k + 8 <= range.end && options.shading != Shading::Perspective {
        let Ok(tris) = <&[[Vertex; 3]; 8]>::try_from(&batch[k..k + 8]) else { break };
        sink.prefetch(8, 8);
        if !simd::window_group(level, tris, options.cull, &mut group) {
            break;
        }
        let id = (first + k) as i32;
        // A lane past the range takes the lane-by-lane path, which clips it.
        let past_range = group.rejected.contains(&Some(Rejection::OutOfRange));
        if !past_range
            && C::push_eight((tris, &group, id), (options.shading, level), &mut records, sink)
        {
            k += 8;
            continue;
        }
        for (l, tri) in tris.iter().enumerate() {
            let id = (first + k + l) as i32;
            let (setup, inv_area2) = match group.lane(l) {
                Ok(lane) => lane,
                Err(why) => {
                    refused(tri, why, id, sink);
                    continue;
                }
            };
            let record = C::record(tri, setup, inv_area2, options.shading, id);
            sink.push_record(&setup, record);
        }
        k += 8;
    }
    for k in k..range.end {
        if (k - range.start).is_multiple_of(8) {
            sink.prefetch(8, 8);
        }
        set_up_one(k, sink);
    }
}

/// The pixels a window triangle's box reaches (`None` for a non-finite vertex), for
/// [`band::plan`]'s sample.
fn window_bounds(tri: &[Vertex; 3]) -> Option<PixelRect> {
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    for v in tri {
        if !(v.x.is_finite() && v.y.is_finite()) {
            return None;
        }
        lo = [lo[0].min(v.x), lo[1].min(v.y)];
        hi = [hi[0].max(v.x), hi[1].max(v.y)];
    }
    // Saturating casts: a box far off the target is clipped away by the caller.
    Some(PixelRect { x0: lo[0] as i32, y0: lo[1] as i32, x1: hi[0] as i32, y1: hi[1] as i32 })
}

/// The colour the tiled backend draws a triangle with, and the record it keeps: for flat and
/// smooth shading the colour as the span kernels take it ([`SpanColor`]), rebuilt from a
/// [`WindowRecord`] where the triangle is drawn; for perspective shading a [`TriangleColor`],
/// kept whole with the setup and depth plane ([`Prepared`]). No match on the colour's kind per
/// triangle and tile (see docs/design-log.md, `render`).
trait WindowColor: Copy + Send + Sync + 'static {
    /// What a batch keeps of a triangle drawn with this colour.
    type Record: bin::Record<Payload = Self>;

    /// The record of set-up triangle `id` with vertices `v` and `1 / area2` `inv_area2`
    /// (`1.0 / setup.area2 as f64`, computed by the caller: the window groups have it).
    fn record(
        v: &[Vertex; 3],
        setup: TriangleSetup,
        inv_area2: f64,
        shading: Shading,
        id: i32,
    ) -> Self::Record;

    /// Gives window group `group` (triangles `tris`, the first with id `first_id`) to `sink`
    /// as the lane-by-lane path would, its records built eight at once in `scratch`, where a
    /// kernel builds them at `level` for this colour and the sink's target: the records of
    /// the lanes that cover a pixel, and the counts of the others (rejected or empty). False,
    /// with nothing given, where no kernel does.
    #[inline(always)]
    fn push_eight(
        (tris, group, first_id): (&[[Vertex; 3]; 8], &simd::WindowGroup, i32),
        (shading, level): (Shading, SimdLevel),
        scratch: &mut simd::WindowRecords,
        sink: &mut bin::Sink<'_, Self::Record>,
    ) -> bool {
        let _ = (tris, group, first_id, shading, level, scratch, sink);
        false
    }

    /// The colour as a span kernel takes it, if it has one.
    fn kernel(&self) -> Option<&SpanColor>;

    /// The colour at barycentric numerators `(e1, e2)`.
    fn at(&self, e1: f64, e2: f64) -> [u8; 4];
}

impl WindowColor for TriangleColor {
    type Record = Prepared<Self>;

    /// The shader computes `1 / area2` itself, the same way.
    #[inline(always)]
    fn record(
        v: &[Vertex; 3],
        setup: TriangleSetup,
        _: f64,
        shading: Shading,
        id: i32,
    ) -> Prepared<Self> {
        let (depth, payload) = TriangleShader::new(v, &setup, shading).into_parts();
        Prepared { setup, depth, id, payload }
    }

    #[inline(always)]
    fn kernel(&self) -> Option<&SpanColor> {
        self.span_color()
    }

    #[inline(always)]
    fn at(&self, e1: f64, e2: f64) -> [u8; 4] {
        self.color_at(e1, e2)
    }
}

impl WindowColor for SpanColor {
    type Record = WindowRecord;

    /// For flat and smooth shading (perspective colours have no span colour: `draw` keeps
    /// [`TriangleColor`] for them); anything but flat counts as smooth.
    #[inline(always)]
    fn record(
        v: &[Vertex; 3],
        setup: TriangleSetup,
        inv_area2: f64,
        shading: Shading,
        id: i32,
    ) -> WindowRecord {
        debug_assert_ne!(shading, Shading::Perspective, "no span colour for perspective shading");
        WindowRecord::new(v, &setup, inv_area2, shading != Shading::Flat, id)
    }

    /// At 1x, [`simd::window_records`]: the same records and coverage as [`Self::record`]
    /// and [`bin::Sink::push_record`] lane by lane.
    #[inline(always)]
    fn push_eight(
        (tris, group, first_id): (&[[Vertex; 3]; 8], &simd::WindowGroup, i32),
        (shading, level): (Shading, SimdLevel),
        scratch: &mut simd::WindowRecords,
        sink: &mut bin::Sink<'_, WindowRecord>,
    ) -> bool {
        let coverage = sink.coverage();
        let smooth = shading != Shading::Flat;
        if coverage.multisampled
            || !simd::window_records(
                level,
                tris,
                group,
                (&coverage.clip, smooth, first_id),
                scratch,
            )
        {
            return false;
        }
        for (l, rejected) in group.rejected.into_iter().enumerate() {
            match rejected {
                Some(why) => sink.skip_many(why.into(), 1),
                None if scratch.empty >> l & 1 != 0 => sink.skip_many(Skipped::Empty, 1),
                None => sink.push_line(&scratch.records[l], scratch.cover(l)),
            }
        }
        true
    }

    #[inline(always)]
    fn kernel(&self) -> Option<&SpanColor> {
        Some(self)
    }

    #[inline(always)]
    fn at(&self, e1: f64, e2: f64) -> [u8; 4] {
        SpanColor::at(self, e1, e2)
    }
}

/// What a batch keeps of a window triangle with flat or smooth colour: its snapped vertices
/// and winding, vertex depths and colours, `1 / area2` and id, in one cache line. The
/// setup's box and area, the depth plane and the colour planes are recomputed from these
/// where the triangle is drawn, by the functions that computed them at setup, so they are
/// equal. Why: the whole record (192 bytes) took three lines, written at setup and read
/// back tile by tile after the batch had left the caches; a million small triangles moved
/// 384 MB a frame through memory for it.
///
/// In C layout, as sixteen 32-bit words in this order (`xy` 0-5, `z` 6-8, `colors` 9-11,
/// `inv_area2` 12-13, `id` 14, `clockwise` and `smooth` the low two bytes of 15):
/// `simd::narrow_eight` reads eight records as a 16 x 8 matrix of words.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub struct WindowRecord {
    pub(crate) xy: [[i32; 2]; 3],
    pub(crate) z: [f32; 3],
    pub(crate) colors: [[u8; 4]; 3],
    pub(crate) inv_area2: f64,
    pub(crate) id: i32,
    pub(crate) clockwise: bool,
    pub(crate) smooth: bool,
    /// Zeros: no padding, so that the record read whole as words reads initialized bytes.
    pad: [u8; 2],
}

const _: () = {
    use std::mem::offset_of;
    assert!(size_of::<WindowRecord>() == 64, "a window record is one cache line");
    assert!(offset_of!(WindowRecord, z) == 24 && offset_of!(WindowRecord, colors) == 36);
    assert!(offset_of!(WindowRecord, inv_area2) == 48 && offset_of!(WindowRecord, id) == 56);
    assert!(offset_of!(WindowRecord, clockwise) == 60 && offset_of!(WindowRecord, smooth) == 61);
};

impl WindowRecord {
    /// The record of triangle `id` with vertices `v`, setup `setup` and `1 / area2`
    /// `inv_area2` (as `1.0 / setup.area2 as f64`).
    #[inline(always)]
    fn new(v: &[Vertex; 3], setup: &TriangleSetup, inv_area2: f64, smooth: bool, id: i32) -> Self {
        debug_assert_eq!(inv_area2.to_bits(), (1.0 / setup.area2 as f64).to_bits(), "1 / area2");
        let (z, colors) = shade::depths_and_colors(v);
        let clockwise = setup.clockwise;
        Self { xy: setup.xy, z, colors, inv_area2, id, clockwise, smooth, pad: [0; 2] }
    }
}

impl bin::Record for WindowRecord {
    type Payload = SpanColor;
    const STREAMED: bool = true;

    #[inline(always)]
    fn narrow_eight(
        records: &[&Self; 8],
        tile: &PixelRect,
        (level, samples): (SimdLevel, SampleCount),
        out: &mut simd::NarrowEight,
    ) -> u8 {
        simd::narrow_eight(level, records, tile, samples, out)
    }

    #[inline(always)]
    fn setup(&self) -> TriangleSetup {
        TriangleSetup::from_kept(self.xy, self.clockwise)
    }

    #[inline(always)]
    fn with<R>(&self, f: impl FnOnce(&Prepared<SpanColor>) -> R) -> R {
        let (depth, payload) =
            TriangleShader::span_parts_of(self.z, self.colors, self.inv_area2, self.smooth);
        f(&Prepared { setup: self.setup(), depth, id: self.id, payload })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bin::Record;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// The banded schedule draws the reference's pixels, ids and counts whatever shares of the
    /// work its bands take ([`band::BandBalance`]: the balance moves the bands' rows after
    /// each banded draw call), on two and three threads.
    #[test]
    fn banded_draws_match_the_reference_whatever_the_shares() {
        let mut rng = SmallRng::seed_from_u64(31);
        let (w, h) = (160u32, 120u32);
        let tris: Vec<[Vertex; 3]> = (0..3000)
            .map(|_| {
                let (cx, cy) = (rng.random_range(0.0..w as f32), rng.random_range(0.0..h as f32));
                std::array::from_fn(|_| {
                    let (x, y) =
                        (cx + rng.random_range(-4.0..4.0), cy + rng.random_range(-4.0..4.0));
                    Vertex::new(x, y, rng.random_range(0.0..1.0), [rng.random(), 90, 200, 255])
                })
            })
            .collect();
        let options = RenderOptions::default().with_schedule(Schedule::Banded);
        let mut reference = Target::new(w, h).unwrap().with_ids().with_overdraw();
        let want = draw(&mut reference, &tris, &options.with_backend(Backend::Reference)).unwrap();
        for shares in [vec![0.5, 0.5], vec![0.1, 0.9], vec![0.9, 0.1], vec![0.2, 0.7, 0.1]] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(shares.len()).build().unwrap();
            let mut target = Target::new(w, h).unwrap().with_ids().with_overdraw();
            target.balance = band::BandBalance::with_shares(shares.clone());
            let got = pool.install(|| draw(&mut target, &tris, &options)).unwrap();
            assert_eq!(target.last_schedule(), Some(Schedule::Banded));
            assert_eq!(got, want, "{shares:?}");
            assert!(target.color == reference.color && target.depth == reference.depth);
            assert!(target.ids == reference.ids && target.overdraw == reference.overdraw);
        }
    }

    /// A window record, built per triangle or from a window group, draws as the whole record
    /// did: the same setup, depth plane and colour to the bit (`TriangleSetup::new`,
    /// `TriangleShader::span_parts`), flat and smooth, with one alpha and with three, for
    /// random triangles small and large.
    #[test]
    fn window_records_rebuild_the_whole_record() {
        let mut rng = SmallRng::seed_from_u64(21);
        let mut checked = 0;
        for round in 0..2_000 {
            let spread = [4.0, 60.0, 3000.0][round % 3];
            let vertex = |rng: &mut SmallRng| {
                let alpha = if round % 2 == 0 { 255 } else { rng.random() };
                Vertex::new(
                    rng.random_range(-spread..spread) + 500.0,
                    rng.random_range(-spread..spread) + 400.0,
                    rng.random_range(0.0..1.0),
                    [rng.random(), rng.random(), rng.random(), alpha],
                )
            };
            let tris: [[Vertex; 3]; 8] =
                std::array::from_fn(|_| [vertex(&mut rng), vertex(&mut rng), vertex(&mut rng)]);
            let mut group = simd::WindowGroup::default();
            let grouped =
                simd::window_group(SimdLevel::detect(), &tris, CullMode::None, &mut group);
            for (k, v) in tris.iter().enumerate() {
                let Ok(setup) = TriangleSetup::new(v, CullMode::None) else { continue };
                for shading in [Shading::Flat, Shading::Smooth] {
                    let smooth = shading == Shading::Smooth;
                    let (depth, color) = TriangleShader::span_parts(v, &setup, smooth);
                    let want = format!("{setup:?} {depth:?} {color:?} 7");
                    let shown = |r: &WindowRecord| {
                        r.with(|p| format!("{:?} {:?} {:?} {}", p.setup, p.depth, p.payload, p.id))
                    };
                    let one = SpanColor::record(v, setup, 1.0 / setup.area2 as f64, shading, 7);
                    assert_eq!(shown(&one), want, "round {round}, triangle {k}");
                    if grouped {
                        let (lane, inv_area2) = group.lane(k).unwrap();
                        let from_group = SpanColor::record(v, lane, inv_area2, shading, 7);
                        assert_eq!(shown(&from_group), want, "round {round}, lane {k}");
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked > 20_000, "{checked} records checked");
    }

    /// The records a window group builds eight at a time ([`simd::window_records`], from
    /// AVX2 on) are, lane by lane, the per-triangle front end's: the same record to the bit
    /// (`WindowRecord::new` from `TriangleSetup::new`), the same coverage rectangle within the
    /// clip (`bin::coverage_bounds` at 1x), and the same lanes kept, empty or rejected.
    /// Random triangles of a few pixels to hundreds, both windings, every cull mode, flat and
    /// smooth, vertices on pixel centres (degenerate and empty boxes), non-finite and out of
    /// range coordinates, clip rectangles that cut them or miss them.
    #[test]
    fn window_groups_build_each_lanes_record() {
        let mut rng = SmallRng::seed_from_u64(77);
        let (mut kept, mut empty, mut rejected) = (0, 0, 0);
        // One for every round, as the front end keeps one: a lane left as an earlier round
        // wrote it would show.
        let mut out = simd::WindowRecords::default();
        let fields = |r: &WindowRecord| {
            let z = r.z.map(f32::to_bits);
            (r.xy, z, r.colors, r.inv_area2.to_bits(), r.id, r.clockwise, r.smooth, r.pad)
        };
        for round in 0..8_000 {
            let spread = [2.0, 6.0, 40.0, 400.0][round % 4];
            let centre = [rng.random_range(-50.0..250.0), rng.random_range(-50.0..250.0)];
            let vertex = |rng: &mut SmallRng| {
                let mut c = |k: usize| match rng.random_range(0..120) {
                    0 => f32::NAN,
                    1 => f32::INFINITY,
                    2 => 40_000.0,
                    3..=12 => rng.random_range(0..8) as f32 + 0.5,
                    _ => centre[k] + rng.random_range(-spread..spread),
                };
                let (x, y) = (c(0), c(1));
                let z = if rng.random_range(0..30) == 0 { f32::NAN } else { rng.random() };
                Vertex::new(x, y, z, [rng.random(), rng.random(), rng.random(), rng.random()])
            };
            let tris: [[Vertex; 3]; 8] =
                std::array::from_fn(|_| [vertex(&mut rng), vertex(&mut rng), vertex(&mut rng)]);
            let cull = [CullMode::None, CullMode::Clockwise, CullMode::CounterClockwise][round % 3];
            let x0 = rng.random_range(-20..120);
            let y0 = rng.random_range(-20..120);
            let clip = PixelRect {
                x0,
                y0,
                x1: x0 + rng.random_range(0..200),
                y1: y0 + rng.random_range(0..200),
            };
            let smooth = rng.random();
            let first_id = rng.random_range(0..1 << 20);
            for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
                if !level.is_available() {
                    continue;
                }
                let mut group = simd::WindowGroup::default();
                assert!(simd::window_group(level, &tris, cull, &mut group));
                let args = (&clip, smooth, first_id);
                assert!(simd::window_records(level, &tris, &group, args, &mut out));
                for (l, v) in tris.iter().enumerate() {
                    let bit = 1u8 << l;
                    let Ok(setup) = TriangleSetup::new(v, cull) else {
                        assert!(group.rejected[l].is_some(), "round {round}, lane {l}");
                        rejected += 1;
                        continue;
                    };
                    assert!(group.rejected[l].is_none(), "round {round}, lane {l}");
                    let Some(cover) = bin::coverage_bounds(&setup, false, &clip) else {
                        assert_eq!(out.empty & bit, bit, "round {round}, lane {l}");
                        empty += 1;
                        continue;
                    };
                    assert_eq!(out.empty & bit, 0, "round {round}, lane {l}");
                    assert_eq!(out.cover(l), cover, "round {round}, lane {l}");
                    let id = first_id + l as i32;
                    let want = WindowRecord::new(v, &setup, 1.0 / setup.area2 as f64, smooth, id);
                    assert_eq!(fields(&out.records[l]), fields(&want), "round {round}, lane {l}");
                    kept += 1;
                }
            }
        }
        if SimdLevel::Avx2.is_available() {
            assert!(kept > 8_000 && empty > 2_000 && rejected > 2_000, "{kept} {empty} {rejected}");
        }
    }

    /// Eight window records set up at once for the narrow kernel (AVX-512 and AVX2) are, lane
    /// by lane, what the tile loop derives from each record alone, bit for bit: the box within the
    /// tile (`TriangleSetup::from_kept`), `edges_at` the centre of its first pixel, the depth
    /// plane and the colour (`span_parts_of`: flat, smooth with one alpha, smooth); and
    /// exactly the lanes that the kernel takes alone are set up (narrow before clipping,
    /// reaching the tile). At 4x and 8x the box is the extent widened by the pattern's reach
    /// (the same box of each sample's box at the corner offsets), which holds every pixel
    /// of each sample's box, and its lanes are narrow at the pixel centres too. Random
    /// triangles of one to a dozen pixels and larger, both windings, far out in the
    /// fixed-point range, flat and smooth, one alpha and three, finite, NaN and infinite
    /// depths, random tiles around them.
    #[test]
    fn eight_records_set_up_as_each_alone() {
        for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
            if level.is_available() {
                eight_records_set_up_at(level);
            }
        }
    }

    /// Eight random window records around `centre` (within `spread` on each axis), ids
    /// from `round`, depths from `depth`, one in `one_alpha` with three alphas, one in four
    /// flat; `None` where one of them is rejected by setup.
    fn random_records(
        rng: &mut SmallRng,
        round: usize,
        (centre, spread, one_alpha): ([f32; 2], [f32; 2], u32),
        depth: impl Fn(&mut SmallRng) -> f32,
    ) -> Option<[WindowRecord; 8]> {
        let records: Vec<WindowRecord> = (0..8)
            .filter_map(|k| {
                let alpha = if rng.random_range(0..one_alpha) > 0 { Some(255) } else { None };
                let v: [Vertex; 3] = std::array::from_fn(|_| {
                    let a = alpha.unwrap_or_else(|| rng.random());
                    Vertex::new(
                        centre[0] + rng.random_range(-spread[0]..spread[0]),
                        centre[1] + rng.random_range(-spread[1]..spread[1]),
                        depth(rng),
                        [rng.random(), rng.random(), rng.random(), a],
                    )
                });
                let setup = TriangleSetup::new(&v, CullMode::None).ok()?;
                let smooth = rng.random_range(0..4) > 0;
                let inv_area2 = 1.0 / setup.area2 as f64;
                Some(WindowRecord::new(&v, &setup, inv_area2, smooth, (round * 8 + k) as i32))
            })
            .collect();
        records.try_into().ok()
    }

    fn eight_records_set_up_at(level: SimdLevel) {
        let mut rng = SmallRng::seed_from_u64(22);
        let (mut lanes_set_up, mut lanes_left, mut kinds) = (0, 0, [0; 3]);
        for round in 0..20_000 {
            let far = round % 7 == 0;
            let (cx, cy) = if far {
                let edge = |rng: &mut SmallRng| rng.random_range(32_700.0..32_750.0f32);
                let sign = |rng: &mut SmallRng| if rng.random() { 1.0 } else { -1.0 };
                (edge(&mut rng) * sign(&mut rng), edge(&mut rng) * sign(&mut rng))
            } else {
                (rng.random_range(0.0..2000.0f32), rng.random_range(0.0..2000.0f32))
            };
            let spread = [1.0, 3.0, 5.0, 7.0, 30.0][round % 5];
            let depth = |rng: &mut SmallRng| match rng.random_range(0..40) {
                0 => f32::NAN,
                1 => f32::INFINITY,
                2 => -1e30,
                _ => rng.random_range(-0.5..1.5),
            };
            let around = ([cx, cy], [spread; 2], 4);
            let Some(records) = random_records(&mut rng, round, around, depth) else { continue };
            // A tile around the triangles, often cutting their boxes.
            let (tx, ty) = (cx.floor() as i32, cy.floor() as i32);
            let tile = PixelRect {
                x0: tx - rng.random_range(-4..40),
                y0: ty - rng.random_range(-4..40),
                x1: tx + rng.random_range(-4..40),
                y1: ty + rng.random_range(-4..40),
            };
            let mut eight = simd::NarrowEight::default();
            let refs = std::array::from_fn(|l| &records[l]);
            let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][round % 3];
            let lanes = simd::narrow_eight(level, &refs, &tile, samples, &mut eight);
            for (l, record) in records.iter().enumerate() {
                let setup = record.setup();
                let (depth, color) = TriangleShader::span_parts_of(
                    record.z,
                    record.colors,
                    record.inv_area2,
                    record.smooth,
                );
                // The box of the samples at the pattern's corner offsets.
                let reach = samples.reach();
                let (first, last) =
                    (setup.sample_bounds([reach; 2]), setup.sample_bounds([-reach; 2]));
                let b = PixelRect { x1: last.x1, y1: last.y1, ..first };
                let narrow = b.x1 - b.x0 < crate::raster::edge::NARROW;
                let Some(r) = b.intersect(&tile).filter(|_| narrow) else {
                    assert_eq!(lanes >> l & 1, 0, "round {round}, lane {l}: {record:?} {tile:?}");
                    lanes_left += 1;
                    continue;
                };
                assert_eq!(lanes >> l & 1, 1, "round {round}, lane {l}: {record:?} {tile:?}");
                lanes_set_up += 1;
                // Each sample's pixels within the tile lie in the box, and a lane narrow with
                // its samples is narrow at the centres.
                for s in 0..samples.count() {
                    if let Some(own) = setup.sample_bounds(samples.offset(s)).intersect(&tile) {
                        assert_eq!(own.union(&r), r, "round {round}, lane {l}, sample {s}");
                    }
                }
                let centres = setup.bounds;
                assert!(centres.x1 - centres.x0 < crate::raster::edge::NARROW, "round {round}");
                let (x, y) = (crate::fixed::pixel_centre(r.x0), crate::fixed::pixel_centre(r.y0));
                let (edges, step_x, step_y, bias) = setup.edges_at(x, y);
                let bits = |v: [f64; 3]| v.map(f64::to_bits);
                let lane = |rows: &[[f64; 8]; 3]| bits([rows[0][l], rows[1][l], rows[2][l]]);
                let what = format!("{level:?}, round {round}, lane {l}: {record:?} {tile:?}");
                assert_eq!(
                    [eight.x0[l], eight.y0[l], eight.columns[l], eight.rows[l], eight.id[l]],
                    [r.x0, r.y0, r.x1 - r.x0 + 1, r.y1 - r.y0 + 1, record.id],
                    "{what}"
                );
                assert_eq!(lane(&eight.edges), bits(edges.map(|e| e as f64)), "{what}");
                assert_eq!(lane(&eight.step_x), bits(step_x.map(|e| e as f64)), "{what}");
                assert_eq!(lane(&eight.step_y), bits(step_y.map(|e| e as f64)), "{what}");
                let want_bias = bias.map(|b| (b as f64).to_bits());
                assert_eq!([eight.bias[0][l], eight.bias[1][l]].map(f64::to_bits), want_bias);
                assert_eq!(lane(&eight.depth), bits(depth.coefficients()), "{what}");
                // The colour as the kernel takes it: the kind, and its planes or value.
                let (smooth, one_alpha) = (eight.smooth >> l & 1, eight.one_alpha >> l & 1);
                let planes = |n: usize| &eight.color[..n];
                match color {
                    SpanColor::Flat(c) => {
                        assert_eq!((smooth, eight.flat[l].to_le_bytes()), (0, c), "{what}");
                    }
                    SpanColor::SmoothRgb(want, alpha) => {
                        assert_eq!((smooth, one_alpha), (1, 1), "{what}");
                        for (c, (got, want)) in planes(3).iter().zip(want).enumerate() {
                            assert_eq!(lane(got), bits(want), "{what}, channel {c}");
                        }
                        assert_eq!(eight.alpha[l], i32::from(alpha), "{what}");
                    }
                    SpanColor::Smooth(want) => {
                        assert_eq!((smooth, one_alpha), (1, 0), "{what}");
                        for (c, (got, want)) in planes(4).iter().zip(want).enumerate() {
                            assert_eq!(lane(got), bits(want), "{what}, channel {c}");
                        }
                    }
                    SpanColor::Perspective(_) => unreachable!("a window record's colour"),
                }
                kinds[usize::from(smooth * (1 + one_alpha))] += 1;
            }
        }
        assert!(lanes_set_up > 10_000 && lanes_left > 10_000, "{lanes_set_up} {lanes_left}");
        assert!(kinds.iter().all(|&k| k > 1_000), "flat, smooth, smooth, one alpha: {kinds:?}");
    }

    /// Eight window records shaded together (`simd::shade_narrow_eight`: at AVX-512 lane by
    /// lane from registers of all eight, at AVX2 each lane's box read in place, or its job
    /// where the box's last groups would reach past the buffers) write what the scalar level
    /// writes, each lane the `NarrowJob` it stands for, in order: triangles crowding a few
    /// pixels, boxes of one pixel to more than eight rows, one to eight columns, clipped by a
    /// band that does not start at row 0, flat and Gouraud colours with one alpha and three,
    /// depths in and out of [0, 1], every depth test, with and without ids and overdraw, runs
    /// of lanes starting anywhere.
    #[test]
    fn eight_records_shade_as_each_alone() {
        for level in [SimdLevel::Avx2, SimdLevel::Avx512] {
            if level.is_available() {
                eight_records_shade_at(level);
            }
        }
    }

    /// [`eight_records_shade_as_each_alone`] at `level`.
    fn eight_records_shade_at(level: SimdLevel) {
        let mut rng = SmallRng::seed_from_u64(23);
        let (mut covered, mut wide, mut past) = (0, 0, 0);
        let (width, height) = (24, 20);
        let band_rows = [0, 3];
        let clip = PixelRect { x0: 0, y0: 3, x1: width - 1, y1: height - 1 };
        for round in 0..20_000 {
            let spread = [1.5, 3.0, 4.5, 6.0][round % 4];
            let (cx, cy) = (rng.random_range(4.0..20.0f32), rng.random_range(2.0..18.0f32));
            let around = ([cx, cy], [spread, 1.5 * spread], 3);
            let depth = |rng: &mut SmallRng| rng.random_range(-0.2..1.2);
            let Some(records) = random_records(&mut rng, round, around, depth) else { continue };
            let mut eight = simd::NarrowEight::default();
            let refs = std::array::from_fn(|l| &records[l]);
            let lanes = simd::narrow_eight(level, &refs, &clip, SampleCount::X1, &mut eight);
            // The longest run of lanes set up from a random start.
            let start = rng.random_range(0..8);
            let run = start..start + (lanes >> start).trailing_ones() as usize;
            if run.is_empty() {
                continue;
            }
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let mut want =
                Target::random_depths(width as u32, height as u32, round % 2 == 0, &mut rng);
            let mut got = want.clone();
            let shade = |level, target: &mut Target| {
                let mut bands = target.bands_from(&band_rows);
                simd::shade_narrow_eight(level, &eight, run.clone(), &mut bands[1], depth_test)
            };
            let (n, m) = (shade(SimdLevel::Scalar, &mut want), shade(level, &mut got));
            let what = format!("{level:?}, round {round}, lanes {run:?}");
            assert_eq!(m, n, "{what}");
            let bits = |t: &Target| t.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
            assert!(bits(&want) == bits(&got) && want.color == got.color, "{what}");
            assert!(want.ids == got.ids && want.overdraw == got.overdraw, "{what}");
            covered += n;
            // Boxes whose last four-pixel group would reach past the buffers' end (the last
            // row's right edge): AVX2 takes those lanes' jobs, whose scalar fallback applies.
            let groups_past = |l: usize| {
                let right = eight.x0[l] + 4 * ((eight.columns[l] + 3) / 4);
                eight.y0[l] + eight.rows[l] == height && right > width
            };
            past += run.clone().filter(|&l| groups_past(l)).count();
            wide += run.filter(|&l| eight.columns[l] > 4).count();
        }
        assert!(covered > 200_000 && wide > 10_000, "{covered} covered, {wide} lanes over 4 wide");
        assert!(past > 100, "{past} lanes reaching past the buffers");
    }

    /// The boxes `band::plan` samples from window triangles: a grid of two-pixel triangles is
    /// banded; a non-finite vertex makes a triangle's box unknown.
    #[test]
    fn window_bounds_band_a_grid() {
        let (cols, rows) = (1000, 500);
        let v = |i: u32, j: u32| Vertex::new(i as f32 * 1.92, j as f32 * 2.16, 0.5, [9; 4]);
        let tri = |k: usize| {
            let (i, j) = ((k / 2) as u32 % cols, (k / 2) as u32 / cols);
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i, j + 1), v(i + 1, j + 1));
            if k.is_multiple_of(2) { [a, b, d] } else { [a, d, c] }
        };
        let screen = PixelRect::of_target(1920, 1080);
        let len = 2 * (cols * rows) as usize;
        let even = band::BandBalance::default();
        let plan = band::plan(Schedule::Auto, len, (1080, 1), &screen, (2, &even), |k| {
            window_bounds(&tri(k))
        });
        assert!(matches!(plan, Plan::Banded(_)), "{plan:?}");
        let [a, b, d] = tri(0);
        assert_eq!(window_bounds(&[a, b, d]), Some(PixelRect { x0: 0, y0: 0, x1: 1, y1: 2 }));
        let nan = Vertex::new(f32::NAN, 1.0, 0.5, [9; 4]);
        assert_eq!(window_bounds(&[a, nan, d]), None);
    }
}
