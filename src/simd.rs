//! SIMD kernels: spans and narrow triangles (shading), window corners and corner tests (the
//! 3D front end, eight vertices or triangles at once), and small SSE2 helpers (four floors, a
//! unit clamp, cache prefetch hints): the only module with `unsafe` and `core::arch`. Each
//! has a scalar path it is tested against.
//!
//! The shading kernels shade a 1x span, or a whole narrow triangle, of a window-space
//! triangle with flat or smooth colour: the same arithmetic as the reference per-pixel loop in
//! [`crate::shade`], lane by lane, so the output is bit-identical (tested at every level
//! against the reference):
//! - barycentric numerators are exact integers below 2^49, so stepping them in `f64` lanes
//!   (`e + k * step`) gives exactly the reference's integer values converted to `f64`;
//! - planes are evaluated as `(a0 + e1 * g1) + e2 * g2` with separate multiplies and adds (no
//!   fused multiply-add), rounding to `f32` and round-half-even to integers use the default
//!   rounding mode, as the scalar code does;
//! - clamps put the constant first (`max(0, z)`), so a `-0.0` survives as it does in
//!   `f32::clamp`.
//!
//! The level is detected once per draw call ([`SimdLevel::detect`]) and can be forced (tests,
//! comparisons) with [`crate::RenderOptions::simd`] or `TRIRAST_SIMD`.

use glam::Vec4;

use crate::bin::extent_coverage_bounds;
use crate::clip::ClipVolume;
use crate::pipeline::Viewport;
use crate::setup::{self, CullMode, PixelRect, Rejection, TriangleSetup};
use crate::shade::{DepthTest, quantize_channel};

/// Instruction set used by the span kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdLevel {
    /// Plain Rust, one pixel at a time.
    Scalar,
    /// AVX2: four pixels per step.
    Avx2,
}

impl SimdLevel {
    /// The best level this CPU supports, or the one named by the environment variable
    /// `TRIRAST_SIMD` (`scalar`, `avx2`) when that is set and available.
    #[must_use]
    pub fn detect() -> Self {
        let forced = match std::env::var("TRIRAST_SIMD").as_deref() {
            Ok("scalar") => Some(Self::Scalar),
            Ok("avx2") => Some(Self::Avx2),
            _ => None,
        };
        match forced {
            Some(level) if level.is_available() => level,
            _ if Self::Avx2.is_available() => Self::Avx2,
            _ => Self::Scalar,
        }
    }

    /// Whether this CPU can run the level.
    #[must_use]
    pub fn is_available(self) -> bool {
        match self {
            Self::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 => false,
        }
    }

    /// Every level this CPU supports, scalar first.
    #[must_use]
    pub fn available() -> Vec<Self> {
        [Self::Scalar, Self::Avx2].into_iter().filter(|l| l.is_available()).collect()
    }
}

/// Asks the CPU to start loading `value`'s cache lines: the tile loop reads triangle records
/// in bin order, scattered over the batch, and would otherwise wait on each one.
#[inline]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = std::ptr::from_ref(value).cast::<i8>();
        // Every line the value touches: a 44-byte record straddles two lines more often than
        // not, so stepping from its start alone would miss the second.
        let lines = (start as usize % 64 + size_of::<T>()).div_ceil(64);
        for line in 0..lines {
            // SAFETY: a prefetch is a hint that never faults and reads nothing observable;
            // SSE is part of the x86_64 baseline. The address may lie past `value` (within
            // its last line), which is fine for a hint: it is never dereferenced.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(line * 64)) }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// [`prefetch`] for every cache line of a slice.
#[inline]
pub fn prefetch_slice<T>(values: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = values.as_ptr().cast::<i8>();
        for line in (0..size_of_val(values)).step_by(64) {
            // SAFETY: as in `prefetch`: a hint that never faults, inside the slice.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(line)) }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = values;
}

/// `floor` of four values as integers, each first clamped to `[-2^30, 2^30]` so the
/// conversion cannot overflow; NaN gives `i32::MIN`. Rust's `as i32` saturates and handles
/// NaN for every value separately, six times a splat; on x86_64 this is three SSE2
/// instructions for all four (truncate, convert back, subtract one where truncation rounded
/// up), with the same results as the scalar path.
#[inline]
#[must_use]
pub fn floor_i32x4(v: [f32; 4]) -> [i32; 4] {
    const LIMIT: f32 = (1 << 30) as f32;
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_add_epi32, _mm_castps_si128, _mm_cmpgt_ps, _mm_cvtepi32_ps, _mm_cvttps_epi32,
            _mm_loadu_ps, _mm_max_ps, _mm_min_ps, _mm_set1_ps, _mm_storeu_si128,
        };
        let mut out = [0i32; 4];
        // SAFETY: SSE2 is part of the x86_64 baseline; the loads and the store move 16 bytes
        // from and to four-element arrays of 4-byte values.
        unsafe {
            let x = _mm_loadu_ps(v.as_ptr());
            // `min(hi, max(lo, x))`: SSE returns the second operand when either is NaN, so
            // NaN passes through to the conversion, which makes it `i32::MIN`.
            let x = _mm_min_ps(_mm_set1_ps(LIMIT), _mm_max_ps(_mm_set1_ps(-LIMIT), x));
            let t = _mm_cvttps_epi32(x);
            let above = _mm_cmpgt_ps(_mm_cvtepi32_ps(t), x);
            _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_add_epi32(t, _mm_castps_si128(above)));
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    v.map(|x| if x.is_nan() { i32::MIN } else { x.clamp(-LIMIT, LIMIT).floor() as i32 })
}

/// Four values clamped to [0, 1] (NaN to 0, `-0.0` to `0.0`), as their bits: the front of
/// the sRGB encoder ([`crate::color::linear_to_srgb8_rgb`]) for three channels at once, four
/// SSE2 instructions where the scalar clamp with its NaN test takes a dozen a channel.
#[inline]
#[must_use]
pub fn unit_clamped_bits(v: [f32; 4]) -> [u32; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_castps_si128, _mm_loadu_ps, _mm_max_ps, _mm_min_ps, _mm_set1_ps, _mm_setzero_ps,
            _mm_storeu_si128,
        };
        let mut out = [0u32; 4];
        // SAFETY: SSE2 is part of the x86_64 baseline; the load and the store move 16 bytes
        // from and to four-element arrays of 4-byte values.
        unsafe {
            // `max(x, 0)`: SSE returns the second operand when either is NaN or both are
            // zeros, so NaN and `-0.0` become `0.0`; `x` is then a number for the `min`.
            let x = _mm_max_ps(_mm_loadu_ps(v.as_ptr()), _mm_setzero_ps());
            let x = _mm_min_ps(x, _mm_set1_ps(1.0));
            _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_castps_si128(x));
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    v.map(|x| if x.is_nan() { 0u32 } else { x.clamp(0.0, 1.0).to_bits() & 0x7fff_ffff })
}

/// The colour of a span: constant, or four planes `[a0, g1, g2]` (RGBA, 0..=255 units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpanColor {
    /// Flat colour.
    Flat([u8; 4]),
    /// Gouraud planes per channel.
    Smooth([[f64; 3]; 4]),
    /// A triangle's vertex colours when its vertices share one alpha (opaque geometry): planes
    /// for red, green and blue, and the alpha. The same colours as `Smooth` with the alpha
    /// plane `[a0, 0, 0]` and `quantize(a0)` here (`a0 + f1 * 0 + f2 * 0` is `a0` for finite
    /// `f1`, `f2`), with a fourth less arithmetic and no clamps: at a covered pixel centre each
    /// value is a convex combination of the vertex values (barycentric weights in [0, 1])
    /// give or take rounding (below 1e-12), so it lies in (-0.5, 255.5), where rounding alone
    /// gives what clamping and rounding give. Planes that leave that range at a covered pixel
    /// are outside this variant's contract (the kernels' lanes outside the triangle, masked
    /// off, may hold anything).
    SmoothRgb([[f64; 3]; 3], u8),
}

impl SpanColor {
    /// The colour at barycentric numerators `(f1, f2)`, as the reference computes it.
    #[inline]
    fn at(&self, f1: f64, f2: f64) -> [u8; 4] {
        match *self {
            Self::Flat(c) => c,
            Self::Smooth(p) => p.map(|[a0, g1, g2]| quantize_channel(a0 + f1 * g1 + f2 * g2)),
            Self::SmoothRgb(p, alpha) => {
                let [r, g, b] = p.map(|[a0, g1, g2]| quantize_channel(a0 + f1 * g1 + f2 * g2));
                [r, g, b, alpha]
            }
        }
    }
}

/// What the shading kernels write and how: a triangle's depth plane and colour, the depth
/// test, the id, and the buffers (indexed alike), shared by spans and narrow triangles.
#[derive(Debug)]
pub struct KernelTarget<'a> {
    /// Depth plane `[a0, g1, g2]`.
    pub depth_plane: [f64; 3],
    /// Colour.
    pub color: SpanColor,
    /// Depth comparison.
    pub depth_test: DepthTest,
    /// Id to write.
    pub id: i32,
    /// Depth buffer.
    pub depth: &'a mut [f32],
    /// Colour buffer.
    pub color_out: &'a mut [[u8; 4]],
    /// Id buffer.
    pub ids: Option<&'a mut [i32]>,
    /// Overdraw buffer.
    pub overdraw: Option<&'a mut [u32]>,
}

impl KernelTarget<'_> {
    /// One covered pixel `i` at barycentric numerators `(f1, f2)`: the reference loop's
    /// overdraw count, depth test and writes.
    #[inline]
    fn pixel(&mut self, i: usize, f1: f64, f2: f64) {
        if let Some(o) = self.overdraw.as_deref_mut() {
            o[i] += 1;
        }
        let [d0, d1, d2] = self.depth_plane;
        let z = ((d0 + f1 * d1 + f2 * d2) as f32).clamp(0.0, 1.0);
        if !self.depth_test.passes(z, self.depth[i]) {
            return;
        }
        self.depth[i] = z;
        self.color_out[i] = self.color.at(f1, f2);
        if let Some(ids) = self.ids.as_deref_mut() {
            ids[i] = self.id;
        }
    }

    /// Panics unless every buffer holds as many elements as `depth`; returns that number.
    fn checked_len(&self) -> usize {
        let n = self.depth.len();
        assert!(self.color_out.len() == n, "kernel buffers must have the same length");
        assert!(self.ids.as_ref().is_none_or(|s| s.len() == n), "kernel buffers differ");
        assert!(self.overdraw.as_ref().is_none_or(|s| s.len() == n), "kernel buffers differ");
        n
    }
}

/// One span to shade: the pixels of `target`'s buffers (exactly the span's), starting where
/// the barycentric numerators are `e1`, `e2`, stepping by `step1`, `step2` per pixel.
#[derive(Debug)]
pub struct SpanJob<'a> {
    /// `E1` at the first pixel.
    pub e1: i64,
    /// `E2` at the first pixel.
    pub e2: i64,
    /// `E1` step per pixel.
    pub step1: i64,
    /// `E2` step per pixel.
    pub step2: i64,
    /// The triangle's shading and the span's pixels.
    pub target: KernelTarget<'a>,
}

/// Shades a span at `level` (which must be available; otherwise the scalar kernel runs).
pub fn shade_span(level: SimdLevel, job: SpanJob<'_>) {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 support was just checked at run time.
            unsafe { x86::shade_span_avx2(job) }
        }
        _ => shade_span_scalar(job),
    }
}

/// Widest box (pixels) [`shade_narrow`] takes: two groups of four lanes, the narrow boxes of
/// [`crate::raster::edge::rasterize_narrow`].
pub const NARROW_COLUMNS: usize = crate::raster::edge::NARROW as usize;

/// A small triangle shaded whole, coverage included: its box (clipped) is at most
/// [`NARROW_COLUMNS`] pixels wide. Coverage is the edge functions' sign test at every pixel of
/// the box, as [`crate::raster::edge::rasterize_narrow`] does, so no spans are built: most
/// triangles of a dense scene cover a few pixels on each of a few rows, where a span loop
/// spends its time on row setup and mispredicted exits.
#[derive(Debug)]
pub struct NarrowJob<'a> {
    /// Biased edge values (fill rule applied: covered iff all are `>= 0`) at the centre of
    /// the box's first pixel (top left).
    pub edges: [i64; 3],
    /// Edge value steps one pixel to the right (`a * 256`).
    pub step_x: [i64; 3],
    /// Edge value steps one row down (`b * 256`).
    pub step_y: [i64; 3],
    /// Biased minus unbiased values of edges 1 and 2 (0 or -1): the barycentric numerators
    /// are `edges[1] - bias[0]` and `edges[2] - bias[1]`.
    pub bias: [i64; 2],
    /// Columns of the box, `1..=NARROW_COLUMNS`.
    pub columns: usize,
    /// Rows of the box.
    pub rows: usize,
    /// Buffer index of the box's first pixel.
    pub first: usize,
    /// Buffer elements from one row to the next.
    pub stride: usize,
    /// The triangle's shading and the buffers (the rows the box lies in, or more).
    pub target: KernelTarget<'a>,
}

impl NarrowJob<'_> {
    /// One past the last buffer element a kernel reads in four-pixel groups.
    fn group_end(&self) -> usize {
        self.first + (self.rows - 1) * self.stride + 4 * self.columns.div_ceil(4)
    }
}

/// Shades a small triangle at `level`; returns the number of covered pixels. A box whose last
/// four-pixel group would reach past the buffers (the target's last row, right edge) takes
/// the scalar kernel.
///
/// # Panics
/// If the box is empty or wider than [`NARROW_COLUMNS`], or the buffers do not hold it.
pub fn shade_narrow(level: SimdLevel, job: NarrowJob<'_>) -> u64 {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2
            if SimdLevel::Avx2.is_available() && job.group_end() <= job.target.depth.len() =>
        {
            // SAFETY: AVX2 support was just checked at run time.
            unsafe { x86::shade_narrow_avx2(job) }
        }
        _ => shade_narrow_scalar(job),
    }
}

/// [`shade_narrow`] pixel by pixel: the reference loop's coverage test and arithmetic.
///
/// # Panics
/// As [`shade_narrow`].
pub fn shade_narrow_scalar(mut job: NarrowJob<'_>) -> u64 {
    assert!((1..=NARROW_COLUMNS).contains(&job.columns) && job.rows > 0, "not a narrow box");
    let mut covered = 0;
    let mut row = job.edges;
    for r in 0..job.rows {
        let mut e = row;
        for c in 0..job.columns {
            if (e[0] | e[1] | e[2]) >= 0 {
                covered += 1;
                let (f1, f2) = ((e[1] - job.bias[0]) as f64, (e[2] - job.bias[1]) as f64);
                job.target.pixel(job.first + r * job.stride + c, f1, f2);
            }
            e = std::array::from_fn(|k| e[k] + job.step_x[k]);
        }
        row = std::array::from_fn(|k| row[k] + job.step_y[k]);
    }
    covered
}

/// The scalar kernel: the reference loop's arithmetic, specialised to plane colours.
pub fn shade_span_scalar(mut job: SpanJob<'_>) {
    let (mut e1, mut e2) = (job.e1, job.e2);
    for k in 0..job.target.depth.len() {
        job.target.pixel(k, e1 as f64, e2 as f64);
        e1 += job.step1;
        e2 += job.step2;
    }
}

/// A vertex as the corner tests see it: its snapped window position, or [`OUTSIDE`] when it
/// is outside the clip volume (or cannot be snapped). Eight bytes where a shaded vertex takes
/// forty or more: a large mesh's vertices are shaded batch by batch into a window of corners,
/// and the few triangles that pass the tests shade their vertices again.
pub type Corner = [i32; 2];

/// The corner of a vertex outside the clip volume (snapped positions are within `+-2^23`).
pub const OUTSIDE: Corner = [i32::MIN; 2];

/// The corner of a vertex at clip-space position `p`: outside if any clip plane has it
/// outside ([`ClipVolume::outcode`]), else its snapped window position
/// ([`Viewport::map_snapped`]), outside too when that fails.
#[inline]
#[must_use]
pub fn window_corner(p: Vec4, volume: &ClipVolume, viewport: &Viewport) -> Corner {
    if volume.outcode(p) != 0 {
        return OUTSIDE;
    }
    viewport.map_snapped(p).map_or(OUTSIDE, |(xy, _, _)| xy)
}

/// [`window_corner`] of every position into `out` (as long as `positions`), at `level`:
/// AVX2 takes eight vertices at a time. In a dense mesh this is most of the per-vertex work
/// (five plane tests, a division, two snaps): a quarter of the frame, scalar.
///
/// # Panics
/// If `out` is shorter than `positions`.
pub fn window_corners(
    level: SimdLevel,
    positions: &[Vec4],
    volume: &ClipVolume,
    viewport: &Viewport,
    out: &mut [Corner],
) {
    assert!(out.len() >= positions.len(), "one corner per position");
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx2 && SimdLevel::Avx2.is_available() {
        for (p, o) in positions.chunks_exact(8).zip(out.chunks_exact_mut(8)) {
            let p: &[Vec4; 8] = p.try_into().expect("chunks of eight");
            let o: &mut [Corner; 8] = o.try_into().expect("chunks of eight");
            // SAFETY: AVX2 support was just checked at run time.
            *o = unsafe { x86::window_corners_avx2(p, volume.guard(), viewport.half_size()) };
            done += 8;
        }
    }
    window_corners_scalar(&positions[done..], volume, viewport, &mut out[done..]);
}

/// [`window_corners`] one vertex at a time, through [`window_corner`].
///
/// # Panics
/// If `out` is shorter than `positions`.
pub fn window_corners_scalar(
    positions: &[Vec4],
    volume: &ClipVolume,
    viewport: &Viewport,
    out: &mut [Corner],
) {
    assert!(out.len() >= positions.len(), "one corner per position");
    for (o, &p) in out.iter_mut().zip(positions) {
        *o = window_corner(p, volume, viewport);
    }
}

/// The corners of eight triangles, structure of arrays: corner `v` of triangle `k` is
/// `(x[v][k], y[v][k])`, a snapped position or [`OUTSIDE`]. Filled by the front end as it
/// reads each triangle's corners, so the vector tests load whole rows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CornerGroup {
    /// `x` of corner `v` of each triangle.
    pub x: [[i32; 8]; 3],
    /// `y` of corner `v` of each triangle.
    pub y: [[i32; 8]; 3],
}

impl Default for CornerGroup {
    /// Every corner outside: lanes past the end of a short group take no tests.
    fn default() -> Self {
        Self { x: [[OUTSIDE[0]; 8]; 3], y: [[OUTSIDE[1]; 8]; 3] }
    }
}

impl CornerGroup {
    /// Sets triangle `k`'s corners.
    #[inline]
    pub fn set(&mut self, k: usize, corners: [Corner; 3]) {
        for (v, [x, y]) in corners.into_iter().enumerate() {
            self.x[v][k] = x;
            self.y[v][k] = y;
        }
    }

    /// Triangle `k`'s corners.
    #[must_use]
    pub fn get(&self, k: usize) -> [Corner; 3] {
        std::array::from_fn(|v| [self.x[v][k], self.y[v][k]])
    }
}

/// What the corner tests decide for eight triangles (bit `k`: triangle `k`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CornerTests {
    /// All three corners inside the clip volume: the tests below were made.
    pub inside: u8,
    /// Zero area.
    pub degenerate: u8,
    /// Nonzero area, removed by the cull mode.
    pub culled: u8,
    /// Kept by both tests above, but its box holds no pixel centre of the clip rectangle.
    pub empty: u8,
}

/// The front end's first tests for eight triangles whose corners are all inside the clip
/// volume, from their snapped corners alone: zero area and culling
/// ([`TriangleSetup::signed_area2`]), then no pixel centre in the box
/// ([`crate::bin::extent_coverage_bounds`], one sample per pixel), in that precedence.
/// Triangles with a corner [`OUTSIDE`] are not `inside` and report nothing else. In a dense
/// mesh nearly every triangle stops here; AVX2 decides eight at once.
#[must_use]
pub fn corner_tests(
    level: SimdLevel,
    group: &CornerGroup,
    cull: CullMode,
    clip: &PixelRect,
) -> CornerTests {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 support was just checked at run time.
            unsafe { x86::corner_tests_avx2(group, cull, clip) }
        }
        _ => corner_tests_scalar(group, cull, clip),
    }
}

/// [`corner_tests`] for eight consecutive triangles of an index buffer whose corners are
/// `window[i - base]` for index `i`. AVX2 reads each corner straight into a vector: filling a
/// [`CornerGroup`] first and loading its rows would read memory just written.
///
/// # Panics
/// If an index minus `base` falls outside the window.
#[must_use]
pub fn corner_tests_indexed(
    level: SimdLevel,
    tris: &[[u32; 3]; 8],
    window: &[Corner],
    base: u32,
    cull: CullMode,
    clip: &PixelRect,
) -> CornerTests {
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx2 && SimdLevel::Avx2.is_available() {
        // SAFETY: AVX2 support was just checked at run time.
        return unsafe { x86::corner_tests_indexed_avx2(tris, window, base, cull, clip) };
    }
    let mut group = CornerGroup::default();
    for (k, tri) in tris.iter().enumerate() {
        group.set(k, tri.map(|i| window[i.wrapping_sub(base) as usize]));
    }
    corner_tests(level, &group, cull, clip)
}

/// [`corner_tests`] lane by lane, through the front end's own functions.
#[must_use]
pub fn corner_tests_scalar(group: &CornerGroup, cull: CullMode, clip: &PixelRect) -> CornerTests {
    let mut t = CornerTests::default();
    for k in 0..8 {
        let tri = group.get(k);
        if tri.contains(&OUTSIDE) {
            continue;
        }
        t.inside |= 1 << k;
        let corners = tri.map(|p| p.map(i64::from));
        match TriangleSetup::signed_area2(corners, cull) {
            Err(Rejection::Degenerate) => t.degenerate |= 1 << k,
            Err(_) => t.culled |= 1 << k,
            Ok(_) => {
                if extent_coverage_bounds(setup::extent(corners), false, clip).is_none() {
                    t.empty |= 1 << k;
                }
            }
        }
    }
    t
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use glam::Vec4;

    use super::{Corner, CornerGroup, CornerTests, KernelTarget, NarrowJob, SpanColor, SpanJob};
    use crate::clip::MIN_W;
    use crate::fixed;
    use crate::setup::{CullMode, PixelRect};
    use crate::shade::DepthTest;

    /// [`super::corner_tests`] for eight triangles at once: areas in two halves of four
    /// `i64` lanes (corner differences are below 2^24, so products are exact), boxes and
    /// their first and last pixel centres in eight `i32` lanes (`ceil((v - 128) / 256)` is
    /// `(v + 127) >> 8`, `floor((v - 128) / 256)` is `(v - 128) >> 8`, arithmetic shifts).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn corner_tests_avx2(
        group: &CornerGroup,
        cull: CullMode,
        clip: &PixelRect,
    ) -> CornerTests {
        // Element by element: the rows were just written by 4-byte stores, which a 32-byte
        // load cannot take from the store buffer (it would wait for them to reach the cache).
        let row = |r: &[i32; 8]| _mm256_setr_epi32(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]);
        let x = [row(&group.x[0]), row(&group.x[1]), row(&group.x[2])];
        let y = [row(&group.y[0]), row(&group.y[1]), row(&group.y[2])];
        tests(x, y, cull, clip)
    }

    /// [`super::corner_tests_indexed`]: each corner read from the window as one 8-byte
    /// `[x, y]` straight into a vector (memory written long before, so no store-forwarding
    /// wait), four triangles' pairs per half, then split into rows of x and of y.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn corner_tests_indexed_avx2(
        tris: &[[u32; 3]; 8],
        window: &[Corner],
        base: u32,
        cull: CullMode,
        clip: &PixelRect,
    ) -> CornerTests {
        // A corner's 8 bytes as the low half of a vector; slice indexing checks the index.
        let corner = |k: usize, v: usize| -> __m128i {
            let c: &Corner = &window[tris[k][v].wrapping_sub(base) as usize];
            // SAFETY: `c` is a reference to 8 readable bytes; the load has no alignment
            // requirement.
            unsafe { _mm_loadl_epi64(std::ptr::from_ref(c).cast::<__m128i>()) }
        };
        let mut x = [_mm256_setzero_si256(); 3];
        let mut y = [_mm256_setzero_si256(); 3];
        for v in 0..3 {
            // [x y] pairs of triangles 0-3 and 4-7, in 32-bit lanes.
            let pairs = |first: usize| {
                let lo = _mm_unpacklo_epi64(corner(first, v), corner(first + 1, v));
                let hi = _mm_unpacklo_epi64(corner(first + 2, v), corner(first + 3, v));
                _mm256_set_m128i(hi, lo)
            };
            let (p, q) = (_mm256_castsi256_ps(pairs(0)), _mm256_castsi256_ps(pairs(4)));
            // Per 128-bit half: lanes [t0 t1 t4 t5 | t2 t3 t6 t7]; the permute restores
            // triangle order.
            let xs = _mm256_castps_si256(_mm256_shuffle_ps::<0b10_00_10_00>(p, q));
            let ys = _mm256_castps_si256(_mm256_shuffle_ps::<0b11_01_11_01>(p, q));
            x[v] = _mm256_permute4x64_epi64::<0b11_01_10_00>(xs);
            y[v] = _mm256_permute4x64_epi64::<0b11_01_10_00>(ys);
        }
        tests(x, y, cull, clip)
    }

    /// The corner tests on eight triangles' corners in rows (`x[v]`: corner `v`'s x).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn tests(x: [__m256i; 3], y: [__m256i; 3], cull: CullMode, clip: &PixelRect) -> CornerTests {
        let ([x0, x1, x2], [y0, y1, y2]) = (x, y);
        // Lanes with a corner equal to OUTSIDE take no tests.
        let (ox, oy) = (_mm256_set1_epi32(super::OUTSIDE[0]), _mm256_set1_epi32(super::OUTSIDE[1]));
        let out = |x, y| _mm256_and_si256(_mm256_cmpeq_epi32(x, ox), _mm256_cmpeq_epi32(y, oy));
        let any_outside = _mm256_or_si256(out(x0, y0), _mm256_or_si256(out(x1, y1), out(x2, y2)));
        let lanes = !(_mm256_movemask_ps(_mm256_castsi256_ps(any_outside)) as u8);
        // Signed area, twice: (x1 - x0)(y2 - y0) - (x2 - x0)(y1 - y0), as in `signed_area2`.
        let (d1x, d1y) = (_mm256_sub_epi32(x1, x0), _mm256_sub_epi32(y1, y0));
        let (d2x, d2y) = (_mm256_sub_epi32(x2, x0), _mm256_sub_epi32(y2, y0));
        let half = |v: __m256i, high: bool| {
            let h = if high { _mm256_extracti128_si256::<1>(v) } else { _mm256_castsi256_si128(v) };
            _mm256_cvtepi32_epi64(h)
        };
        let (mut zero, mut positive, mut negative) = (0u8, 0u8, 0u8);
        for (shift, high) in [(0, false), (4, true)] {
            let area = _mm256_sub_epi64(
                _mm256_mul_epi32(half(d1x, high), half(d2y, high)),
                _mm256_mul_epi32(half(d2x, high), half(d1y, high)),
            );
            let bits = |m: __m256i| (_mm256_movemask_pd(_mm256_castsi256_pd(m)) as u8) << shift;
            let z = _mm256_setzero_si256();
            zero |= bits(_mm256_cmpeq_epi64(area, z));
            positive |= bits(_mm256_cmpgt_epi64(area, z));
            negative |= bits(_mm256_cmpgt_epi64(z, area));
        }
        // The box's first and last pixel centres, clipped.
        let min3 = |a, b, c| _mm256_min_epi32(_mm256_min_epi32(a, b), c);
        let max3 = |a, b, c| _mm256_max_epi32(_mm256_max_epi32(a, b), c);
        let first = |v| _mm256_srai_epi32::<8>(_mm256_add_epi32(v, _mm256_set1_epi32(127)));
        let last = |v| _mm256_srai_epi32::<8>(_mm256_sub_epi32(v, _mm256_set1_epi32(128)));
        let px0 = _mm256_max_epi32(first(min3(x0, x1, x2)), _mm256_set1_epi32(clip.x0));
        let px1 = _mm256_min_epi32(last(max3(x0, x1, x2)), _mm256_set1_epi32(clip.x1));
        let py0 = _mm256_max_epi32(first(min3(y0, y1, y2)), _mm256_set1_epi32(clip.y0));
        let py1 = _mm256_min_epi32(last(max3(y0, y1, y2)), _mm256_set1_epi32(clip.y1));
        let empty = _mm256_or_si256(_mm256_cmpgt_epi32(px0, px1), _mm256_cmpgt_epi32(py0, py1));
        let empty = _mm256_movemask_ps(_mm256_castsi256_ps(empty)) as u8;
        let degenerate = zero & lanes;
        let culled = match cull {
            CullMode::None => 0,
            CullMode::Clockwise => positive,
            CullMode::CounterClockwise => negative,
        } & lanes;
        CornerTests {
            inside: lanes,
            degenerate,
            culled,
            empty: empty & lanes & !degenerate & !culled,
        }
    }

    /// [`super::window_corner`] of eight positions: the same `f32` operations lane by lane
    /// (distances to the clip planes, `1 / w`, the viewport, no fused multiply-adds), and the
    /// snap as a round-half-even of `x * 256` in `f32`, which is exact: `x * 256` is (a power
    /// of two scale) and, within the range, so is its rounding to an integer below 2^23.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn window_corners_avx2(
        p: &[Vec4; 8],
        guard: [f32; 2],
        half: [f32; 2],
    ) -> [Corner; 8] {
        let lane = |c: usize| {
            _mm256_setr_ps(p[0][c], p[1][c], p[2][c], p[3][c], p[4][c], p[5][c], p[6][c], p[7][c])
        };
        let (x, y, z, w) = (lane(0), lane(1), lane(2), lane(3));
        let zero = _mm256_setzero_ps();
        let lt = |a, b| _mm256_cmp_ps::<_CMP_LT_OQ>(a, b);
        let or = |a, b| _mm256_or_ps(a, b);
        let and = |a, b| _mm256_and_ps(a, b);
        // Finite: |v| < inf (false for NaN).
        let inf = _mm256_set1_ps(f32::INFINITY);
        let abs = |v| _mm256_andnot_ps(_mm256_set1_ps(-0.0), v);
        let finite = |v| lt(abs(v), inf);
        let all_finite = and(and(finite(x), finite(y)), and(finite(z), finite(w)));
        // Outside any plane: the distances of `ClipVolume::distance`, each `< 0`.
        let (gx, gy) = (_mm256_mul_ps(_mm256_set1_ps(guard[0]), w), {
            _mm256_mul_ps(_mm256_set1_ps(guard[1]), w)
        });
        let outside = or(
            or(
                or(lt(z, zero), lt(_mm256_sub_ps(w, z), zero)),
                lt(_mm256_sub_ps(w, _mm256_set1_ps(MIN_W)), zero),
            ),
            or(
                or(lt(_mm256_add_ps(x, gx), zero), lt(_mm256_sub_ps(gx, x), zero)),
                or(lt(_mm256_add_ps(y, gy), zero), lt(_mm256_sub_ps(gy, y), zero)),
            ),
        );
        // `Viewport::map`.
        let one = _mm256_set1_ps(1.0);
        let inv_w = _mm256_div_ps(one, w);
        let wx =
            _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(x, inv_w), one), _mm256_set1_ps(half[0]));
        let wy =
            _mm256_mul_ps(_mm256_sub_ps(one, _mm256_mul_ps(y, inv_w)), _mm256_set1_ps(half[1]));
        let wz = _mm256_mul_ps(z, inv_w);
        // `fixed::snap`: in [MIN_COORD, MAX_COORD), and the rounded value below 2^23.
        let snap = |v: __m256| {
            let in_range = and(
                _mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_set1_ps(fixed::MIN_COORD)),
                lt(v, _mm256_set1_ps(fixed::MAX_COORD)),
            );
            let scaled = _mm256_mul_ps(v, _mm256_set1_ps(fixed::ONE as f32));
            let rounded =
                _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(scaled);
            let limit = _mm256_set1_ps(fixed::MAX_COORD * fixed::ONE as f32);
            (and(in_range, lt(rounded, limit)), _mm256_cvtps_epi32(rounded))
        };
        let (x_ok, sx) = snap(wx);
        let (y_ok, sy) = snap(wy);
        let valid = and(
            _mm256_andnot_ps(outside, all_finite),
            and(and(x_ok, y_ok), and(finite(wz), finite(inv_w))),
        );
        let valid = _mm256_castps_si256(valid);
        let min = _mm256_set1_epi32(i32::MIN);
        let sx = _mm256_blendv_epi8(min, sx, valid);
        let sy = _mm256_blendv_epi8(min, sy, valid);
        let mut xs = [0i32; 8];
        let mut ys = [0i32; 8];
        // SAFETY: each array holds eight i32 (32 bytes); unaligned stores need no alignment.
        unsafe {
            _mm256_storeu_si256(xs.as_mut_ptr() as *mut __m256i, sx);
            _mm256_storeu_si256(ys.as_mut_ptr() as *mut __m256i, sy);
        }
        std::array::from_fn(|k| [xs[k], ys[k]])
    }

    /// Four lanes of `(a0 + f1 * g1) + f2 * g2`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn plane(p: [f64; 3], f1: __m256d, f2: __m256d) -> __m256d {
        let t = _mm256_add_pd(_mm256_set1_pd(p[0]), _mm256_mul_pd(f1, _mm256_set1_pd(p[1])));
        _mm256_add_pd(t, _mm256_mul_pd(f2, _mm256_set1_pd(p[2])))
    }

    /// `quantize_channel` on four lanes, as i32, in three instructions: `max(v, 0)` returns its
    /// second operand when `v` is NaN, which maps NaN to 0 as the scalar code does, and the
    /// conversion rounds in the default mode, half to even, as the scalar magic-number trick
    /// does.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn quantize(v: __m256d) -> __m128i {
        let v = _mm256_min_pd(_mm256_set1_pd(255.0), _mm256_max_pd(v, _mm256_setzero_pd()));
        _mm256_cvtpd_epi32(v)
    }

    /// Four lanes of RGBA8 (in `i32` lanes) from planes: red, green, blue and, when `alpha`
    /// is `None`, the fourth plane's alpha; without `CLAMP`, the values are only rounded (see
    /// [`SpanColor::SmoothRgb`]).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn smooth<const CLAMP: bool>(
        p: &[[f64; 3]],
        alpha: Option<u8>,
        f1: __m256d,
        f2: __m256d,
    ) -> __m128i {
        let channel = |p: [f64; 3]| {
            let v = plane(p, f1, f2);
            if CLAMP { quantize(v) } else { _mm256_cvtpd_epi32(v) }
        };
        let (r, g, b) = (channel(p[0]), channel(p[1]), channel(p[2]));
        let a = match alpha {
            Some(a) => _mm_set1_epi32(i32::from(a) << 24),
            None => _mm_slli_epi32::<24>(channel(p[3])),
        };
        _mm_or_si128(
            _mm_or_si128(r, _mm_slli_epi32::<8>(g)),
            _mm_or_si128(_mm_slli_epi32::<16>(b), a),
        )
    }

    /// Runs `$body` with `$rgba` bound to the colour of four lanes at barycentric numerators
    /// `(f1, f2)` as a closure, one per colour kind: each kind's loop is compiled on its own,
    /// without a match per group (and with groups small enough to inline).
    macro_rules! with_rgba {
        ($color:expr, $rgba:ident => $body:expr) => {
            match $color {
                SpanColor::Flat(c) => {
                    let flat = _mm_set1_epi32(i32::from_le_bytes(c));
                    let $rgba = move |_: __m256d, _: __m256d| flat;
                    $body
                }
                SpanColor::Smooth(p) => {
                    let $rgba = move |f1, f2| smooth::<true>(&p, None, f1, f2);
                    $body
                }
                SpanColor::SmoothRgb(p, alpha) => {
                    let $rgba = move |f1, f2| smooth::<false>(&p, Some(alpha), f1, f2);
                    $body
                }
            }
        };
    }

    /// Four lanes of `-1` (covered) or `0`, from the low four bits of an index.
    static LANE_MASKS: [[i32; 4]; 16] = {
        let mut t = [[0; 4]; 16];
        let mut bits = 0;
        while bits < 16 {
            let mut lane = 0;
            while lane < 4 {
                t[bits][lane] = if bits & (1 << lane) != 0 { -1 } else { 0 };
                lane += 1;
            }
            bits += 1;
        }
        t
    };

    /// A group of four pixels at `at` whose lanes in `cover` (each 0 or -1) are covered,
    /// with barycentric numerators `f1`, `f2`: overdraw, depth test, writes, as the scalar
    /// `KernelTarget::pixel` does lane by lane. Read-blend-write of the whole group (masked
    /// stores are microcoded and slow on AMD cores): uncovered lanes are written back as read.
    /// With `SKIP_HIDDEN`, a group where no lane passes the depth test stops there: right
    /// for long spans of large overlapping triangles (fill: twice as fast as without), wrong
    /// for the few groups of a small triangle, where the mispredicted branch costs more than
    /// the colour it saves (soup: 7% faster without).
    ///
    /// # Safety
    /// The CPU must support AVX2, and `at + 4` must not exceed `t.checked_len()`.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn group<const SKIP_HIDDEN: bool>(
        t: &mut KernelTarget<'_>,
        at: usize,
        f1: __m256d,
        f2: __m256d,
        cover: __m128i,
        rgba: impl Fn(__m256d, __m256d) -> __m128i,
    ) {
        // SAFETY (every pointer access in this block): the caller guarantees the four
        // elements at `at` lie in every buffer (they all hold `checked_len()` elements);
        // unaligned loads and stores have no alignment requirement; `[u8; 4]` is four bytes,
        // read and written as one i32 lane.
        unsafe {
            if let Some(o) = t.overdraw.as_deref_mut() {
                let p = o.as_mut_ptr().add(at) as *mut __m128i;
                // Covered lanes are -1: subtracting them counts one fragment.
                _mm_storeu_si128(p, _mm_sub_epi32(_mm_loadu_si128(p), cover));
            }
            let z = _mm256_cvtpd_ps(plane(t.depth_plane, f1, f2));
            let z = _mm_min_ps(_mm_set1_ps(1.0), _mm_max_ps(_mm_setzero_ps(), z));
            let dp = t.depth.as_mut_ptr().add(at);
            let stored = _mm_loadu_ps(dp);
            let cover_ps = _mm_castsi128_ps(cover);
            let pass = match t.depth_test {
                DepthTest::Less => _mm_and_ps(_mm_cmp_ps::<_CMP_LT_OQ>(z, stored), cover_ps),
                DepthTest::LessEqual => _mm_and_ps(_mm_cmp_ps::<_CMP_LE_OQ>(z, stored), cover_ps),
                DepthTest::Always => cover_ps,
            };
            if SKIP_HIDDEN && _mm_movemask_ps(pass) == 0 {
                return;
            }
            _mm_storeu_ps(dp, _mm_blendv_ps(stored, z, pass));
            let pass = _mm_castps_si128(pass);
            let cp = t.color_out.as_mut_ptr().add(at) as *mut __m128i;
            _mm_storeu_si128(cp, _mm_blendv_epi8(_mm_loadu_si128(cp), rgba(f1, f2), pass));
            if let Some(ids) = t.ids.as_deref_mut() {
                let ip = ids.as_mut_ptr().add(at) as *mut __m128i;
                let id = _mm_set1_epi32(t.id);
                _mm_storeu_si128(ip, _mm_blendv_epi8(_mm_loadu_si128(ip), id, pass));
            }
        }
    }

    /// The lane mask of the low four bits of `bits`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lane_mask(bits: u32) -> __m128i {
        let row = &LANE_MASKS[(bits & 0xF) as usize];
        // SAFETY: `row` is four i32 (16 bytes); unaligned loads need no alignment.
        unsafe { _mm_loadu_si128(row.as_ptr() as *const __m128i) }
    }

    /// [`super::shade_narrow`] in AVX2: each row of the box as one or two groups of four
    /// pixels. The edge values are stepped in `f64` lanes (integers below 2^49 plus steps below
    /// 2^35: exact), so coverage is the sign bit of `e0 | e1 | e2` as in the scalar test, and
    /// the barycentric numerators are the edge values minus the fill-rule biases, exactly.
    /// Lanes past the box's columns are uncovered, so their pixels (of the same band: this
    /// thread's) are written back as read. Every group of the box goes through the same
    /// steps, covered or not, without branches on coverage or depth: a small triangle has a
    /// few groups each, and mispredicted branches cost more than the work they would skip.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn shade_narrow_avx2(job: NarrowJob<'_>) -> u64 {
        // SAFETY: the CPU supports AVX2 (this function's contract).
        with_rgba!(job.target.color, rgba => unsafe { narrow_groups(job, rgba) })
    }

    /// [`shade_narrow_avx2`] for one colour kind.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn narrow_groups(
        mut job: NarrowJob<'_>,
        rgba: impl Fn(__m256d, __m256d) -> __m128i,
    ) -> u64 {
        let n = job.target.checked_len();
        assert!((1..=super::NARROW_COLUMNS).contains(&job.columns) && job.rows > 0, "not narrow");
        assert!(job.group_end() <= n, "the box's groups must lie in the buffers");
        let groups = job.columns.div_ceil(4);
        let lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
        // Edge k's offsets from the row's first pixel, for the lanes of groups 0 and 1.
        let offsets = |k: usize, g: usize| {
            let step = _mm256_set1_pd(job.step_x[k] as f64);
            _mm256_mul_pd(_mm256_add_pd(lanes, _mm256_set1_pd(4.0 * g as f64)), step)
        };
        let offsets: [[__m256d; 2]; 3] = std::array::from_fn(|k| [offsets(k, 0), offsets(k, 1)]);
        // The box's columns among each group's lanes.
        let column_bits =
            [(1u32 << job.columns.min(4)) - 1, (1u32 << (job.columns.max(4) - 4)) - 1];
        let bias = job.bias.map(|b| _mm256_set1_pd(b as f64));
        let mut row = job.edges.map(|e| e as f64);
        let step_y = job.step_y.map(|s| s as f64);
        let mut covered = 0u64;
        for r in 0..job.rows {
            for g in 0..groups {
                let e: [__m256d; 3] =
                    std::array::from_fn(|k| _mm256_add_pd(_mm256_set1_pd(row[k]), offsets[k][g]));
                let out = _mm256_movemask_pd(_mm256_or_pd(_mm256_or_pd(e[0], e[1]), e[2]));
                let bits = !(out as u32) & column_bits[g];
                covered += u64::from(bits.count_ones());
                let (f1, f2) = (_mm256_sub_pd(e[1], bias[0]), _mm256_sub_pd(e[2], bias[1]));
                let at = job.first + r * job.stride + 4 * g;
                // SAFETY: `at + 4 <= group_end() <= n` (asserted above).
                unsafe { group::<false>(&mut job.target, at, f1, f2, lane_mask(bits), &rgba) };
            }
            row = std::array::from_fn(|k| row[k] + step_y[k]);
        }
        covered
    }

    /// The AVX2 kernel: four pixels per step; the last `n % 4` pixels as the span's last four
    /// with those already shaded masked off (spans shorter than four go to the scalar
    /// kernel).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn shade_span_avx2(job: SpanJob<'_>) {
        if job.target.checked_len() < 4 {
            return super::shade_span_scalar(job);
        }
        // SAFETY: the CPU supports AVX2 (this function's contract).
        with_rgba!(job.target.color, rgba => unsafe { span_groups(job, rgba) })
    }

    /// [`shade_span_avx2`] for one colour kind, on a span of at least four pixels.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn span_groups(mut job: SpanJob<'_>, rgba: impl Fn(__m256d, __m256d) -> __m128i) {
        let n = job.target.checked_len();
        let lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
        // The numerators at pixel `first + lane`: exact integers as everywhere
        // (`(first + lane) * step` is below 2^47, the sum below 2^49).
        let at = |first: usize| {
            let k = _mm256_add_pd(lanes, _mm256_set1_pd(first as f64));
            let f = |e: i64, step: i64| {
                _mm256_add_pd(
                    _mm256_set1_pd(e as f64),
                    _mm256_mul_pd(k, _mm256_set1_pd(step as f64)),
                )
            };
            (f(job.e1, job.step1), f(job.e2, job.step2))
        };
        let (mut f1, mut f2) = at(0);
        let (step1, step2) =
            (_mm256_set1_pd(4.0 * job.step1 as f64), _mm256_set1_pd(4.0 * job.step2 as f64));
        let full = n - n % 4;
        let all = _mm_set1_epi32(-1);
        let mut k = 0;
        while k < full {
            // SAFETY: `k + 4 <= full <= n`.
            unsafe { group::<true>(&mut job.target, k, f1, f2, all, &rgba) };
            f1 = _mm256_add_pd(f1, step1);
            f2 = _mm256_add_pd(f2, step2);
            k += 4;
        }
        if full < n {
            // The last four pixels, those already shaded masked off.
            let (f1, f2) = at(n - 4);
            let done = 4 - n % 4;
            let cover = lane_mask(0xF << done);
            // SAFETY: `n - 4 + 4 = n`.
            unsafe { group::<true>(&mut job.target, n - 4, f1, f2, cover, &rgba) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// The vector floor is `f64::floor` of the clamped value for every finite and infinite
    /// input (integers, halves, values just off integers, huge, tiny, negative zero), and
    /// `i32::MIN` for NaN.
    #[test]
    fn floor_matches_scalar_floor() {
        let mut rng = SmallRng::seed_from_u64(4);
        let mut values = vec![
            0.0,
            -0.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            (1u32 << 30) as f32,
            -((1u32 << 30) as f32),
            8_388_608.5,
        ];
        for k in -300..300 {
            let x = k as f32 * 0.5;
            values.extend([x, x.next_up(), x.next_down()]);
        }
        values.extend((0..20_000).map(|_| rng.random_range(-3e9f32..3e9)));
        values.extend((0..20_000).map(|_| rng.random_range(-2000f32..2000.0)));
        let expect = |x: f32| {
            if x.is_nan() {
                i32::MIN
            } else {
                f64::from(x).clamp(-1073741824.0, 1073741824.0).floor() as i32
            }
        };
        for c in values.chunks_exact(4) {
            let v = [c[0], c[1], c[2], c[3]];
            assert_eq!(floor_i32x4(v), v.map(expect), "{v:?}");
        }
    }

    /// The corner tests agree with the front end's functions lane by lane, at every level:
    /// tiny triangles near pixel centres (corners on, beside and between centres), large
    /// ones across the whole snapped range, collinear corners, both windings, every cull
    /// mode, clip rectangles inside, at the edge of and off the triangles, partial lane sets.
    #[test]
    fn corner_tests_match_the_front_end() {
        let mut rng = SmallRng::seed_from_u64(11);
        let limit = (1 << 23) - 1;
        // Lanes found degenerate, culled, empty, kept, and with a corner outside.
        let mut seen = [0u32; 5];
        for round in 0..40_000 {
            let mut group = CornerGroup::default();
            for k in 0..8 {
                let mut tri = [[0i32; 2]; 3];
                let kind = rng.random_range(0..4);
                let base = [rng.random_range(-3000..3000), rng.random_range(-3000..3000)];
                for (v, p) in tri.iter_mut().enumerate() {
                    *p = match kind {
                        // Within a few pixels, often on a centre or a centre +- 1.
                        0 => base.map(|b| {
                            256 * (b / 256) + 128 + rng.random_range(-3..4) * [1, 64, 255][v]
                        }),
                        1 => base.map(|b| b + rng.random_range(-600..600)),
                        2 => [rng.random_range(-limit..=limit), rng.random_range(-limit..=limit)],
                        // Collinear.
                        _ => base.map(|b| b + 37 * v as i32),
                    };
                }
                // Some corners outside the clip volume (and lanes of a short group).
                if round % 5 == 0 && rng.random_range(0..3) == 0 {
                    tri[rng.random_range(0..3)] = OUTSIDE;
                }
                group.set(k, tri);
            }
            let cull = [CullMode::None, CullMode::Clockwise, CullMode::CounterClockwise][round % 3];
            let (cx, cy) = (rng.random_range(-20..20), rng.random_range(-20..20));
            let clip = PixelRect {
                x0: cx,
                y0: cy,
                x1: cx + rng.random_range(-1..40),
                y1: cy + rng.random_range(-1..40),
            };
            let expect = corner_tests_scalar(&group, cull, &clip);
            let lanes = expect.inside;
            seen[0] += expect.degenerate.count_ones();
            seen[1] += expect.culled.count_ones();
            seen[2] += expect.empty.count_ones();
            seen[3] += (lanes & !(expect.degenerate | expect.culled | expect.empty)).count_ones();
            for level in SimdLevel::available() {
                assert_eq!(corner_tests(level, &group, cull, &clip), expect, "{level:?} {group:?}");
            }
            seen[4] += (!lanes).count_ones();
        }
        // Every outcome is exercised, many times.
        assert!(seen.iter().all(|&n| n > 1000), "{seen:?}");
    }

    /// Corner tests read through indices from a window of corners give what the scalar tests
    /// give on the same corners gathered into a group: random windows (positions within a
    /// few pixels of each other, far apart, and OUTSIDE), indices offset by a base, every
    /// cull mode; an index outside the window panics at every level.
    #[test]
    fn indexed_corner_tests_match_the_group_ones() {
        let mut rng = SmallRng::seed_from_u64(21);
        for round in 0..20_000 {
            let len = rng.random_range(3..40);
            let spread = [300, 3000, 1 << 23][round % 3];
            let window: Vec<Corner> = (0..len)
                .map(|_| {
                    if rng.random_range(0..10) == 0 {
                        OUTSIDE
                    } else {
                        [rng.random_range(-spread..spread), rng.random_range(-spread..spread)]
                    }
                })
                .collect();
            let base = rng.random_range(0..1000u32);
            let tris: [[u32; 3]; 8] = std::array::from_fn(|_| {
                std::array::from_fn(|_| base + rng.random_range(0..len) as u32)
            });
            let cull = [CullMode::None, CullMode::Clockwise, CullMode::CounterClockwise][round % 3];
            let clip = PixelRect { x0: -5, y0: -3, x1: rng.random_range(0..30), y1: 20 };
            let mut group = CornerGroup::default();
            for (k, t) in tris.iter().enumerate() {
                group.set(k, t.map(|i| window[(i - base) as usize]));
            }
            let expect = corner_tests_scalar(&group, cull, &clip);
            for level in SimdLevel::available() {
                let got = corner_tests_indexed(level, &tris, &window, base, cull, &clip);
                assert_eq!(got, expect, "{level:?}, round {round}");
            }
        }
        let window = vec![[0, 0]; 5];
        let mut tris = [[0u32, 1, 2]; 8];
        tris[6][1] = 5;
        for level in SimdLevel::available() {
            let r = std::panic::catch_unwind(|| {
                corner_tests_indexed(level, &tris, &window, 0, CullMode::None, &PixelRect::EMPTY)
            });
            assert!(r.is_err(), "{level:?} read past the window");
        }
    }

    /// The vector corners against [`window_corner`] for every lane of random and special
    /// positions: inside, outside each plane, exactly on planes (`z = 0`, `z = w`, the guard
    /// band, `w = MIN_W`), `w` of zero, negative or tiny, NaN and infinities in each component,
    /// window coordinates whose snap is a tie (a 1 x 1 target: `x * 256` at half-integers), and
    /// lengths that leave a scalar tail.
    #[test]
    fn window_corners_match_scalar() {
        let mut rng = SmallRng::seed_from_u64(12);
        for (width, height) in [(1920, 1080), (1, 1), (16384, 16384), (97, 61)] {
            let volume = ClipVolume::for_target(width, height);
            let viewport = Viewport::of_size(width, height);
            let [gx, gy] = volume.guard();
            for round in 0..400 {
                let n = rng.random_range(0..70);
                let specials = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0, -0.0, 1e-30];
                let positions: Vec<Vec4> = (0..n)
                    .map(|_| {
                        let w = match rng.random_range(0..10) {
                            0 => specials[rng.random_range(0..specials.len())],
                            1 => crate::clip::MIN_W,
                            2 => -rng.random_range(0.0..2.0f32),
                            3 => 1.0,
                            _ => rng.random_range(0.01..3.0f32),
                        };
                        let mut p = Vec4::new(
                            rng.random_range(-1.5..1.5f32) * w,
                            rng.random_range(-1.5..1.5f32) * w,
                            rng.random_range(-0.2..1.2f32) * w,
                            w,
                        );
                        match rng.random_range(0..12) {
                            0 => p[rng.random_range(0..4)] = specials[rng.random_range(0..3)],
                            1 => p.z = 0.0,
                            2 => p.z = p.w,
                            3 => p.x = gx * p.w,
                            4 => p.y = -gy * p.w,
                            5 => p.x = rng.random_range(-40.0..40.0f32) * p.w,
                            // Multiples of 2^-10 with w = 1: on a 1 x 1 target, window
                            // x * 256 = m / 8 + 128, a tie whenever m = 4 mod 8.
                            6 | 7 => {
                                p = Vec4::new(
                                    rng.random_range(-1024..1024) as f32 / 1024.0,
                                    rng.random_range(-1024..1024) as f32 / 1024.0,
                                    0.5,
                                    1.0,
                                );
                            }
                            _ => {}
                        }
                        p
                    })
                    .collect();
                let run = |level: SimdLevel| {
                    let mut out = vec![[0, 0]; n];
                    window_corners(level, &positions, &volume, &viewport, &mut out);
                    out
                };
                let reference = run(SimdLevel::Scalar);
                for (k, &p) in positions.iter().enumerate() {
                    assert_eq!(reference[k], window_corner(p, &volume, &viewport));
                }
                for level in SimdLevel::available() {
                    assert_eq!(run(level), reference, "{level:?}, {width}x{height}, round {round}");
                }
            }
        }
    }

    /// Buffers of `n` pixels a kernel starts from: depth (a quarter of it 0.5, so that planes
    /// tie with it now and then), colour, ids and overdraw.
    fn random_buffers(
        rng: &mut SmallRng,
        n: usize,
    ) -> (Vec<f32>, Vec<[u8; 4]>, Vec<i32>, Vec<u32>) {
        let depth = (0..n)
            .map(|_| if rng.random_range(0..4) == 0 { 0.5 } else { rng.random_range(0.0..1.0) })
            .collect();
        let color = (0..n).map(|_| [rng.random(); 4]).collect();
        let ids = (0..n).map(|_| rng.random_range(-1..5)).collect();
        let overdraw = (0..n).map(|_| rng.random_range(0..3)).collect();
        (depth, color, ids, overdraw)
    }

    /// A random plane `[a0, g1, g2]` whose values over a span leave [0, scale] on either side.
    fn random_plane(rng: &mut SmallRng, scale: f64) -> [f64; 3] {
        [
            rng.random_range(-0.2..1.2) * scale,
            rng.random_range(-1e-6..1e-6) * scale,
            rng.random_range(-1e-6..1e-6) * scale,
        ]
    }

    /// A random flat or smooth colour (four planes, or three within [0, 255] and a constant
    /// alpha); now and then one of four planes with a NaN or infinite channel (the quantizers
    /// map NaN to 0 and clamp infinities).
    fn random_color(rng: &mut SmallRng, round: usize) -> SpanColor {
        if rng.random() {
            return SpanColor::Flat([rng.random(), rng.random(), rng.random(), rng.random()]);
        }
        if rng.random() {
            // Within its contract: values inside [0, 255] wherever the tests evaluate them
            // (numerators below 2^42), near the ends of the range.
            let plane = |rng: &mut SmallRng| {
                let a0 = [0.2, 254.8, rng.random_range(2.0..253.0)][rng.random_range(0..3)];
                let g = |rng: &mut SmallRng| rng.random_range(-0.09..0.09) / (1u64 << 42) as f64;
                [a0, g(rng), g(rng)]
            };
            return SpanColor::SmoothRgb([0; 3].map(|_| plane(rng)), rng.random());
        }
        let mut planes: [[f64; 3]; 4] = std::array::from_fn(|_| random_plane(rng, 255.0));
        if round.is_multiple_of(89) {
            planes[round % 4][0] = [f64::NAN, f64::INFINITY, -f64::INFINITY][round % 3];
        }
        SpanColor::Smooth(planes)
    }

    /// The narrow kernels against the scalar one on random boxes (1 to 8 columns, 1 to 6
    /// rows) of random edge functions (so any coverage pattern, not only triangles'), biases
    /// 0 and -1, every depth test, flat and smooth colours, with and without id and overdraw
    /// buffers, boxes whose last group ends exactly at the buffers' end or would reach past it
    /// (where the scalar kernel takes over).
    #[test]
    fn narrow_kernels_match_scalar_bit_for_bit() {
        let mut rng = SmallRng::seed_from_u64(8);
        for round in 0..20_000 {
            let columns = rng.random_range(1..=NARROW_COLUMNS);
            let rows = rng.random_range(1..=6usize);
            let stride = rng.random_range(columns..columns + 12);
            let len = rows * stride + rng.random_range(0..6);
            // Up to the last position where the box fits; its groups may not.
            let first = rng.random_range(0..=len - (rows - 1) * stride - columns);
            let edge = |rng: &mut SmallRng| rng.random_range(-(1i64 << 40)..(1 << 40));
            let step = |rng: &mut SmallRng| rng.random_range(-(1i64 << 32)..(1 << 32));
            // Small edge values near zero so boxes are partly covered.
            let near = |rng: &mut SmallRng| rng.random_range(-3000i64..3000);
            let (edges, step_x, step_y) = if round % 2 == 0 {
                let s = |rng: &mut SmallRng| rng.random_range(-700i64..700);
                (
                    [near(&mut rng), near(&mut rng), near(&mut rng)],
                    [0; 3].map(|_| s(&mut rng)),
                    [0; 3].map(|_| s(&mut rng)),
                )
            } else {
                (
                    [0; 3].map(|_| edge(&mut rng)),
                    [0; 3].map(|_| step(&mut rng)),
                    [0; 3].map(|_| step(&mut rng)),
                )
            };
            let bias = [-(rng.random::<bool>() as i64), -(rng.random::<bool>() as i64)];
            let depth_plane = random_plane(&mut rng, 1.0);
            let color = random_color(&mut rng, round);
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let extras = round % 4 < 2;
            let buffers = random_buffers(&mut rng, len);
            let run = |level: SimdLevel| {
                let (mut d, mut c, mut i, mut o) = buffers.clone();
                let covered = shade_narrow(
                    level,
                    NarrowJob {
                        edges,
                        step_x,
                        step_y,
                        bias,
                        columns,
                        rows,
                        first,
                        stride,
                        target: KernelTarget {
                            depth_plane,
                            color,
                            depth_test,
                            id: 9,
                            depth: &mut d,
                            color_out: &mut c,
                            ids: extras.then_some(&mut i[..]),
                            overdraw: extras.then_some(&mut o[..]),
                        },
                    },
                );
                (covered, d.iter().map(|z| z.to_bits()).collect::<Vec<_>>(), c, i, o)
            };
            let reference = run(SimdLevel::Scalar);
            for level in SimdLevel::available() {
                assert_eq!(run(level), reference, "{level:?}, round {round}");
            }
        }
    }

    /// Every available kernel against the scalar one on random spans: lengths 0..40 (tails),
    /// every depth test, flat and smooth colours, planes that leave [0, 1] and [0, 255]
    /// (clamping), NaN and infinite colour planes, a `-0.0` depth, and stored depths that tie.
    #[test]
    fn kernels_match_scalar_bit_for_bit() {
        let mut rng = SmallRng::seed_from_u64(1);
        for round in 0..20_000 {
            let n = rng.random_range(0..40usize);
            let mut depth_plane = random_plane(&mut rng, 1.0);
            if round % 97 == 0 {
                depth_plane = [-0.0, 0.0, 0.0];
            }
            let color = random_color(&mut rng, round);
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let e1 = rng.random_range(-(1i64 << 40)..(1 << 40));
            let e2 = rng.random_range(-(1i64 << 40)..(1 << 40));
            let step1 = rng.random_range(-(1i64 << 30)..(1 << 30));
            let step2 = rng.random_range(-(1i64 << 30)..(1 << 30));
            let buffers = random_buffers(&mut rng, n);
            let run = |level: SimdLevel| {
                let (mut d, mut c, mut i, mut o) = buffers.clone();
                shade_span(
                    level,
                    SpanJob {
                        e1,
                        e2,
                        step1,
                        step2,
                        target: KernelTarget {
                            depth_plane,
                            color,
                            depth_test,
                            id: 7,
                            depth: &mut d,
                            color_out: &mut c,
                            ids: Some(&mut i),
                            overdraw: Some(&mut o),
                        },
                    },
                );
                (d.iter().map(|z| z.to_bits()).collect::<Vec<_>>(), c, i, o)
            };
            let reference = run(SimdLevel::Scalar);
            for level in SimdLevel::available() {
                assert_eq!(run(level), reference, "{level:?}, round {round}");
            }
        }
    }
}
