//! SIMD kernels: spans, multisampled spans and narrow triangles (shading), window groups
//! (the window front end's setup, eight triangles at once), window corners and corner tests
//! (the 3D front end, eight vertices or triangles at once), index ranges (the 3D pipeline's pass
//! over a mesh's indices), row masks (coverage of a run of rows of a narrow box), and small
//! SSE2 helpers (four floors, the sRGB encoder's clamp, four columns of edge values, cache
//! prefetch hints) and the buffers' clear (string stores): the only module with `unsafe`,
//! `core::arch` and inline assembly. Each has a scalar path it is tested against.
//!
//! The shading kernels shade a 1x span, or a whole narrow triangle, of a window-space
//! triangle with flat or smooth colour: the same arithmetic as the reference per-pixel loop in
//! [`crate::shade`], lane by lane, so the output is bit-identical (tested at every level
//! against the reference):
//! - barycentric numerators are exact integers below 2^49, so stepping them in `f64` lanes
//!   (`e + k * step`) gives exactly the reference's integer values converted to `f64`;
//! - depth planes are evaluated as `(a0 + e1 * g1) + e2 * g2` with separate multiplies and
//!   adds, colour planes as `fma(e2, g2, fma(e1, g1, a0))` (see [`SpanColor::at`]); rounding
//!   to `f32` and round-half-even to integers use the default rounding mode, as the scalar
//!   code does;
//! - clamps put the constant first (`max(0, z)`), so a `-0.0` survives as it does in
//!   `f32::clamp`.
//!
//! The level is detected once per draw call ([`SimdLevel::detect`]) and can be forced (tests,
//! comparisons) with [`crate::RenderOptions::simd`] or `TRIRAST_SIMD`.
// Elsewhere than x86-64 only the scalar versions exist: the level each function takes, and the
// helpers only the x86 kernels call, go unused there.
#![cfg_attr(not(target_arch = "x86_64"), allow(unused_variables, unused_mut, dead_code))]

use glam::Vec4;

use crate::clip::ClipVolume;
use crate::fixed;
use crate::pipeline::Viewport;
use crate::render::WindowRecord;
use crate::sample::{MAX_SAMPLES, SampleCount};
use crate::setup::{self, CullMode, PixelRect, Rejection, TriangleSetup, Vertex};
use crate::shade::{DepthTest, PlaneEquation, quantize_channel};

/// Instruction set used by the kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdLevel {
    /// Plain Rust, one pixel at a time.
    Scalar,
    /// AVX2 and FMA, with POPCNT, BMI1 and BMI2 (separate CPU features, found together on
    /// AVX2 processors; a CPU, or a virtual machine, that reports some without the others runs
    /// the scalar code): four pixels per step in `f64` lanes (eight in the small kernel's
    /// `f32` and `i32` ones).
    Avx2,
    /// AVX-512 (F, VL, DQ, CD, with POPCNT, BMI1 and BMI2): eight pixels per step with mask
    /// registers for the shading kernels; the front end's corner kernels and the index ranges
    /// run their AVX2 versions.
    Avx512,
}

impl SimdLevel {
    /// The best level this CPU supports, or the one named by the environment variable
    /// `TRIRAST_SIMD` (`scalar`, `avx2`, `avx512`) when that is set and available.
    #[must_use]
    pub fn detect() -> Self {
        let forced = std::env::var("TRIRAST_SIMD").ok().and_then(|n| Self::from_name(&n));
        match forced {
            Some(level) if level.is_available() => level,
            _ => Self::available().pop().unwrap_or(Self::Scalar),
        }
    }

    /// [`SimdLevel::detect`], once per process: for kernels whose output is the same at
    /// every level, called deep in the shading loops where no draw call's level is at hand
    /// ([`row_masks`]).
    #[must_use]
    pub fn detected() -> Self {
        static LEVEL: std::sync::OnceLock<SimdLevel> = std::sync::OnceLock::new();
        *LEVEL.get_or_init(Self::detect)
    }

    /// The level `TRIRAST_SIMD` names `name` (`scalar`, `avx2`, `avx512`).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "scalar" => Some(Self::Scalar),
            "avx2" => Some(Self::Avx2),
            "avx512" => Some(Self::Avx512),
            _ => None,
        }
    }

    /// The level's name, as [`Self::from_name`] reads it (and `TRIRAST_SIMD` takes it).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Scalar => "scalar",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }

    /// Whether this CPU can run the level. Every kernel call asks, so the answer is the
    /// best level, detected once, compared: the four feature tests each time were a
    /// seventieth of a frame of small triangles.
    #[inline]
    #[must_use]
    pub fn is_available(self) -> bool {
        static BEST: std::sync::OnceLock<SimdLevel> = std::sync::OnceLock::new();
        self <= *BEST.get_or_init(|| {
            [Self::Avx512, Self::Avx2].into_iter().find(|l| l.supported()).unwrap_or(Self::Scalar)
        })
    }

    /// Whether this CPU has the level's features (levels are ordered: each includes the
    /// ones below).
    fn supported(self) -> bool {
        match self {
            Self::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            Self::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
                    // Every AVX2 CPU has them; the small kernel finds and clears bits with
                    // them (grid 4.5% slower without, on one thread).
                    && std::arch::is_x86_feature_detected!("popcnt")
                    && std::arch::is_x86_feature_detected!("bmi1")
                    && std::arch::is_x86_feature_detected!("bmi2")
            }
            #[cfg(target_arch = "x86_64")]
            Self::Avx512 => {
                Self::Avx2.supported()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512cd")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Self::Avx2 | Self::Avx512 => false,
        }
    }

    /// Whether the AVX2 kernels may run: at AVX2 or above, on a CPU that has it (the levels
    /// above AVX2 use its corner kernels).
    fn has_avx2(self) -> bool {
        self >= Self::Avx2 && Self::Avx2.is_available()
    }

    /// Every level this CPU supports, scalar first.
    #[must_use]
    pub fn available() -> Vec<Self> {
        [Self::Scalar, Self::Avx2, Self::Avx512].into_iter().filter(|l| l.is_available()).collect()
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

/// Appends `record` to `out` without reading its line in first (non-temporal stores), when
/// `out` has room; otherwise an ordinary push. A batch's records fill buffers larger than
/// the caches and are read back only once the batch is binned, scattered, tile by tile:
/// with ordinary stores each record's line was first read from memory, then written back.
/// The stores are weakly ordered: [`store_fence`] must follow before another thread reads
/// the records. The value in `out` is `record`, bit for bit, whichever way it went.
#[inline]
pub fn push_streamed(out: &mut Vec<WindowRecord>, record: &WindowRecord) {
    #[cfg(target_arch = "x86_64")]
    if out.len() < out.capacity() {
        use std::arch::x86_64::{__m128i, _mm_loadu_si128, _mm_stream_si128};
        let len = out.len();
        let from = std::ptr::from_ref(record).cast::<__m128i>();
        // SAFETY: SSE2 is part of the x86_64 baseline. `len < capacity`, so element `len`
        // lies in `out`'s allocation; a record is 64 bytes aligned to 64 with no padding
        // (its layout is asserted beside it), so the four 16-byte loads read initialized
        // bytes of `record` and the four aligned streaming stores write exactly element
        // `len`, which is then initialized and may be counted by `set_len`.
        unsafe {
            let to = out.as_mut_ptr().add(len).cast::<__m128i>();
            for k in 0..4 {
                _mm_stream_si128(to.add(k), _mm_loadu_si128(from.add(k)));
            }
            out.set_len(len + 1);
        }
        return;
    }
    out.push(*record);
}

/// Makes the streaming stores of [`push_streamed`] made so far on this thread visible
/// before any store after it (such as the one that tells another thread the batch is
/// ready).
#[inline]
pub fn store_fence() {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE is part of the x86_64 baseline; a fence touches no memory.
    unsafe {
        std::arch::x86_64::_mm_sfence();
    }
}

/// A four-byte value a buffer is cleared to ([`fill_words`]). Sealed: the string store
/// writes `bits` into the buffer's memory, so it must be the value's own bytes, which holds
/// for the four types here and need not for another crate's.
pub trait Word: Copy + sealed::Sealed {
    /// The value's four bytes in memory, as one native-endian word.
    fn bits(self) -> u32;
}

/// Keeps [`Word`] to the types implemented here.
mod sealed {
    pub trait Sealed {}
    impl Sealed for u32 {}
    impl Sealed for i32 {}
    impl Sealed for f32 {}
    impl Sealed for [u8; 4] {}
}

impl Word for u32 {
    fn bits(self) -> u32 {
        self
    }
}

impl Word for i32 {
    fn bits(self) -> u32 {
        u32::from_ne_bytes(self.to_ne_bytes())
    }
}

impl Word for f32 {
    fn bits(self) -> u32 {
        self.to_bits()
    }
}

impl Word for [u8; 4] {
    fn bits(self) -> u32 {
        u32::from_ne_bytes(self)
    }
}

/// Sets every element of `buffer` to `value`, as [`slice::fill`] does, with `rep stosd`
/// where the CPU has enhanced fast strings (ERMS) and the level is not forced to scalar. The
/// string store writes whole cache lines without first reading them in, which a loop of
/// vector stores cannot ask for: a 1080p target's colour and depth (16 MB, two threads) took
/// 0.37-0.47 ms against 0.52-0.63 with `fill` and 0.53 with aligned AVX-512 stores (Xeon with
/// AVX-512), a tenth of the Stanford bunny's frame; and the lines stay cached for the draw
/// that reads them next, which non-temporal stores (0.45-0.55 ms) would have sent to memory.
/// On an AMD EPYC (Zen 4) it is no slower than `fill` (1080p: fastest 0.12 against 0.17 ms).
pub fn fill_words<T: Word>(buffer: &mut [T], value: T) {
    #[cfg(target_arch = "x86_64")]
    fill_words_with(buffer, value, fast_strings());
    #[cfg(not(target_arch = "x86_64"))]
    buffer.fill(value);
}

/// [`fill_words`], with the string store or with `fill` as `string_store` says (tests run
/// the string store on any x86_64 CPU: ERMS only makes it fast).
#[cfg(target_arch = "x86_64")]
fn fill_words_with<T: Word>(buffer: &mut [T], value: T, string_store: bool) {
    const { assert!(size_of::<T>() == 4, "a word is four bytes") };
    if string_store {
        // SAFETY: `rep stosd` stores the word in `eax` `rcx` times from `rdi` upwards (the
        // direction flag is clear on entry to inline assembly, as the ABI requires), so it
        // writes exactly the `4 * len` bytes of `buffer`, which is borrowed uniquely; each
        // element's four bytes become `value.bits()`, `value`'s own bytes (`Word` is sealed
        // to types whose `bits` are), so each element is `value`. The instruction reads no
        // memory, uses no stack and sets no flags.
        unsafe {
            std::arch::asm!(
                "rep stosd",
                inout("rcx") buffer.len() => _,
                inout("rdi") buffer.as_mut_ptr() => _,
                in("eax") value.bits(),
                options(nostack, preserves_flags),
            );
        }
        return;
    }
    buffer.fill(value);
}

/// Whether [`fill_words`] takes the string store: ERMS, at a level above scalar.
#[cfg(target_arch = "x86_64")]
fn fast_strings() -> bool {
    SimdLevel::detected() > SimdLevel::Scalar && std::arch::is_x86_feature_detected!("ermsb")
}

/// [`prefetch`] for every cache line of a slice.
#[inline]
pub fn prefetch_slice<T>(values: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = values.as_ptr().cast::<i8>();
        // Every line the slice touches, the last one included when it does not start on a
        // line (as in `prefetch`).
        let lines = (start as usize % 64 + size_of_val(values)).div_ceil(64);
        for line in 0..lines {
            // SAFETY: as in `prefetch`: a hint that never faults; the address may lie past
            // the slice (within its last line), which is fine for a hint.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(line * 64)) }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = values;
}

/// Coverage bit masks of consecutive rows of a box at most 8 pixels wide, at `level`:
/// `out[r]` has bit `x` set iff pixel `x` of row `r` is inside all three edges, for
/// `x < columns`, as [`crate::raster::edge::row_coverage_within`] gives it for each row (`e`
/// the biased edge values at the first row's first pixel, stepped by `step_x` to the right
/// and `step_y` down). The row's pixels side by side in `i64` lanes (AVX2: four a register,
/// AVX-512: eight), the signs gathered into a mask at once: a third of the bunny's coverage
/// work had been building row masks a pixel at a time. Integer arithmetic, so every level
/// gives the same masks.
#[inline]
pub fn row_masks(
    level: SimdLevel,
    e: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
    columns: usize,
    out: &mut [u8],
) {
    debug_assert!((1..=8).contains(&columns), "a narrow box");
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 support was just checked at run time.
            unsafe { avx512::row_masks(e, step_x, step_y, columns, out) }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::row_masks(e, step_x, step_y, columns, out) }
        }
        _ => row_masks_scalar(e, step_x, step_y, columns, out),
    }
}

/// [`row_masks`] a row at a time, through [`crate::raster::edge::row_coverage_within`].
pub fn row_masks_scalar(
    mut e: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
    columns: usize,
    out: &mut [u8],
) {
    for o in out.iter_mut() {
        *o = crate::raster::edge::row_coverage_within(e, step_x, columns) as u8;
        e = std::array::from_fn(|k| e[k] + step_y[k]);
    }
}

/// RGBA8 of eight lanes of linear colour, as the 3D pipeline's fragment stage writes them:
/// [`crate::color::linear_to_srgb8_rgb`] of red, green and blue, [`crate::color::unorm8`] of
/// alpha, the bytes of each `u32` low to high. From AVX2 on, the lanes transposed into one
/// register per channel and the encoder's table entries gathered eight at a time: one at a
/// time, the lookups were about a twentieth of the grid's frame. The same table and the
/// same clamps, so every level gives the same bytes.
#[inline]
#[must_use]
pub fn srgb8_lanes(level: SimdLevel, colors: &[[f32; 4]; 8]) -> [u32; 8] {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return unsafe { avx2::srgb8_lanes(colors, crate::color::srgb8_table()) };
    }
    srgb8_lanes_scalar(colors)
}

/// Blinn-Phong light with a whole specular exponent, as [`gouraud_eight`] takes it: the unit
/// direction towards the light, the intensities and the exponent.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WholeLight {
    /// Unit direction towards the light (view space).
    pub l: [f32; 3],
    /// Ambient intensity.
    pub ambient: f32,
    /// Diffuse intensity.
    pub diffuse: f32,
    /// Specular intensity.
    pub specular: f32,
    /// Specular exponent (0 to 1024).
    pub exponent: u32,
}

/// Where [`gouraud_eight`] lights vertices from: the eye's origin (positions are taken
/// relative to it), the view matrix and the normal matrix, each a column per array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EyeLanes {
    /// Subtracted from every position.
    pub origin: [f32; 3],
    /// View matrix columns (`glam::Mat4`'s `x_axis` to `w_axis`).
    pub view: [[f32; 4]; 4],
    /// Normal matrix columns (`glam::Mat3`'s).
    pub normal: [[f32; 3]; 3],
}

/// `(diffuse + ambient, specular)` of eight vertices under `light`, as `crate::model`'s
/// Gouraud lanes compute them a lane at a time: each position relative to the eye's origin
/// through the view matrix, each normal (zero without `normals`) through the normal matrix,
/// then Blinn-Phong towards the eye. `None` below AVX2, where the caller does. The same
/// operations in the same order (`glam`'s matrix products, dot products and
/// `normalize_or`, `powi`'s squarings), so the same bits: each lane had waited on its chain
/// of three square roots and divisions, which the compiler spread over SSE registers and
/// scalar ones; in AVX2 all eight lanes go at once, and so do the matrix products.
#[inline]
#[must_use]
pub(crate) fn gouraud_eight(
    level: SimdLevel,
    positions: &[[f32; 3]; 8],
    normals: Option<&[[f32; 3]; 8]>,
    eye: &EyeLanes,
    light: &WholeLight,
) -> Option<([f32; 8], [f32; 8])> {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return Some(unsafe { avx2::gouraud_eight(positions, normals, eye, light) });
    }
    let _ = (level, positions, normals, eye, light);
    None
}

/// `Light::shade_towards` of eight lanes under `light`, from their normals `n` and
/// directions to the eye `v` (each normalised here, as `crate::model`'s lanes do a lane at a
/// time): `(diffuse + ambient, specular)`, the same bits ([`gouraud_eight`]'s lighting
/// alone, for Phong's fragments). `None` below AVX2, where the caller does.
#[inline]
#[must_use]
pub(crate) fn light_eight(
    level: SimdLevel,
    n: &[[f32; 8]; 3],
    v: &[[f32; 8]; 3],
    light: &WholeLight,
) -> Option<([f32; 8], [f32; 8])> {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return Some(unsafe { avx2::light_eight(n, v, light) });
    }
    let _ = (level, n, v, light);
    None
}

/// [`srgb8_lanes`] a lane at a time.
#[must_use]
pub fn srgb8_lanes_scalar(colors: &[[f32; 4]; 8]) -> [u32; 8] {
    colors.map(|[r, g, b, a]| {
        let [r, g, b] = crate::color::linear_to_srgb8_rgb([r, g, b]);
        u32::from_le_bytes([r, g, b, crate::color::unorm8(a)])
    })
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

/// One sample's three edge values at four consecutive pixels of a row, in `i32`, for the
/// coverage of boxes up to four pixels wide (`shade`'s sample rows, where they fit): on
/// x86_64 one SSE2 register per edge, so a row's mask is two ORs and a sign mask, where the
/// scalar loop (which the compiler did not vectorise) built it bit by bit. Integer
/// arithmetic: every path gives the same masks.
#[derive(Clone, Copy)]
pub struct EdgeColumns {
    #[cfg(target_arch = "x86_64")]
    edges: [std::arch::x86_64::__m128i; 3],
    #[cfg(not(target_arch = "x86_64"))]
    edges: [[i32; 4]; 3],
}

impl EdgeColumns {
    /// The values `e[k] + c * step_x[k]` for columns `c` 0 to 3 (the caller checks they fit).
    #[inline(always)]
    #[must_use]
    pub fn new(e: [i32; 3], step_x: [i32; 3]) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::_mm_setr_epi32;
            let edges = std::array::from_fn(|k| {
                let (v, s) = (e[k], step_x[k]);
                // SAFETY: SSE2 is part of the x86_64 baseline; registers only, no memory.
                unsafe { _mm_setr_epi32(v, v + s, v + 2 * s, v + 3 * s) }
            });
            Self { edges }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let edges =
                std::array::from_fn(|k| std::array::from_fn(|c| e[k] + c as i32 * step_x[k]));
            Self { edges }
        }
    }

    /// Bit `c` set iff column `c` is inside all three edges (every value `>= 0`).
    #[inline(always)]
    #[must_use]
    pub fn inside(&self) -> u32 {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_castsi128_ps, _mm_movemask_ps, _mm_or_si128};
            let [a, b, c] = self.edges;
            // SAFETY: SSE and SSE2 are part of the x86_64 baseline; registers only.
            let signs = unsafe {
                let any = _mm_or_si128(_mm_or_si128(a, b), c);
                _mm_movemask_ps(_mm_castsi128_ps(any)) as u32
            };
            !signs & 0xF
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let [a, b, c] = &self.edges;
            (0..4).fold(0, |m, i| m | u32::from((a[i] | b[i] | c[i]) >= 0) << i)
        }
    }

    /// The same columns a row down (`step_y[k]` added to edge `k`; the caller checks the
    /// values still fit).
    #[inline(always)]
    pub fn step(&mut self, step_y: [i32; 3]) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_add_epi32, _mm_set1_epi32};
            for (edge, s) in self.edges.iter_mut().zip(step_y) {
                // SAFETY: SSE2 is part of the x86_64 baseline; registers only.
                *edge = unsafe { _mm_add_epi32(*edge, _mm_set1_epi32(s)) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        for (edge, s) in self.edges.iter_mut().zip(step_y) {
            *edge = edge.map(|v| v + s);
        }
    }
}

/// Four values clamped to `[low, 1]` (NaN to `low`), as their bits: the front of the sRGB
/// encoder ([`crate::color::linear_to_srgb8_rgb`]) for three channels at once, four SSE2
/// instructions where the scalar clamp with its NaN test takes a dozen a channel. `low` is
/// positive, so `-0.0` becomes it too.
#[inline]
#[must_use]
pub fn clamped_bits(v: [f32; 4], low: f32) -> [u32; 4] {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{
            _mm_castps_si128, _mm_max_ps, _mm_min_ps, _mm_set_ps, _mm_set1_ps, _mm_storeu_si128,
        };
        let mut out = [0u32; 4];
        // SAFETY: SSE2 is part of the x86_64 baseline; the store moves 16 bytes to a
        // four-element array of 4-byte values.
        unsafe {
            // Assembled in a register: a load of `v`, which callers have just built with four
            // narrow stores, waited for them (store forwarding fails; the bunny, one thread:
            // about 2%).
            let v = _mm_set_ps(v[3], v[2], v[1], v[0]);
            // `max(x, low)`: SSE returns the second operand when either is NaN, so NaN
            // becomes `low`; `x` is then a number for the `min`.
            let x = _mm_max_ps(v, _mm_set1_ps(low));
            let x = _mm_min_ps(x, _mm_set1_ps(1.0));
            _mm_storeu_si128(out.as_mut_ptr().cast(), _mm_castps_si128(x));
        }
        out
    }
    #[cfg(not(target_arch = "x86_64"))]
    v.map(|x| if x.is_nan() { low } else { x.clamp(low, 1.0) }.to_bits())
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
    /// off, may hold anything). The narrow sample kernels, which evaluate colour at the
    /// centres of partly covered pixels (possibly outside the triangle), clamp it.
    SmoothRgb([[f64; 3]; 3], u8),
    /// A 3D pipeline triangle whose fragment shader is a fixed function of its
    /// perspective-correct vertex colours ([`crate::pipeline::InterpolatedColor`]).
    Perspective(PerspectiveColor),
}

/// What a 3D pipeline triangle's fragments are when its fragment shader only passes on
/// interpolated vertex colours ([`crate::pipeline::FragmentShader::interpolated_color`]): the
/// pipeline's own arithmetic, so that kernels computing it in lanes write what the shader
/// would have. At barycentric numerators `(e1, e2)`: the perspective-correct weights of
/// `(e1, e2) / area2` and `1 / w` (`f64`, as the fragment stage computes them), the colours
/// weighted in `f32` as `Varyings::weighted` weights a `Vec4` (`c0 w0 + c1 w1 + c2 w2`, left
/// to right), times `scale`, sRGB-encoded; the alpha `alpha`, or the weighted one, as 8-bit
/// linear ([`crate::color::unorm8`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerspectiveColor {
    /// Linear RGBA at the three vertices.
    pub colors: [[f32; 4]; 3],
    /// Multiplies the weighted colour, channel by channel.
    pub scale: [f32; 4],
    /// Every fragment's alpha, in place of the weighted one.
    pub alpha: Option<f32>,
    /// The vertices' `1 / w`.
    pub inv_w: [f32; 3],
    /// `1 / area2` of the triangle (as its setup has it).
    pub inv_area2: f64,
}

impl PerspectiveColor {
    /// The vertices' `1 / w` as the weights take them, and whether they are one positive
    /// value (then the weights are the screen-space ones, with no division).
    #[inline(always)]
    fn inv_w(&self) -> ([f64; 3], bool) {
        let q = self.inv_w.map(f64::from);
        (q, crate::pipeline::is_affine(q))
    }

    /// The colour at barycentric numerators `(e1, e2)`, lane by lane as the fragment stage
    /// computes it: the definition the kernels are tested against.
    #[must_use]
    pub fn at(&self, e1: f64, e2: f64) -> [u8; 4] {
        let (q, _) = self.inv_w();
        let w = crate::pipeline::perspective_weights(e1 * self.inv_area2, e2 * self.inv_area2, q);
        let [c0, c1, c2] = self.colors.map(Vec4::from_array);
        let c = (c0 * w[0] + c1 * w[1] + c2 * w[2]) * Vec4::from_array(self.scale);
        let [r, g, b] = crate::color::linear_to_srgb8_rgb([c.x, c.y, c.z]);
        [r, g, b, crate::color::unorm8(self.alpha.unwrap_or(c.w))]
    }
}

impl SpanColor {
    /// Gouraud colour from its RGBA planes: [`SpanColor::SmoothRgb`] when the alpha plane is
    /// flat (`[a0, 0, 0]`: the vertices share one alpha), else [`SpanColor::Smooth`].
    #[inline(always)]
    #[must_use]
    pub fn smooth(planes: [[f64; 3]; 4]) -> Self {
        let [r, g, b, a] = planes;
        match a {
            [a0, 0.0, 0.0] => Self::SmoothRgb([r, g, b], quantize_channel(a0)),
            _ => Self::Smooth([r, g, b, a]),
        }
    }

    /// The colour at barycentric numerators `(f1, f2)`, as the reference computes it:
    /// `quantize_channel` of each plane, evaluated with fused multiply-adds,
    /// `fma(f2, g2, fma(f1, g1, a0))`. Why fused: colour is most of a small triangle's
    /// arithmetic in the kernels, and two fused operations in place of two multiplies and
    /// two adds made the soup 4% and fill 6% faster at 1x, 9% and 6% at 4x (two threads,
    /// AVX-512). Depth keeps separate operations ([`crate::shade::depth_at`]): the 3D
    /// pipeline evaluates it per fragment in scalar code, inlined into its loops, where a
    /// fused multiply-add is a function call (grid 6% slower when tried).
    ///
    /// The crate is built for the x86_64 baseline, without FMA, where `f64::mul_add` is a
    /// call (two, through a pointer) per channel and term: so where the CPU has FMA the
    /// planes are evaluated in one function compiled for it (forced scalar fill, one
    /// thread: 191 ms before the change, 388 ms with the calls, 187 ms now).
    #[inline(always)]
    #[must_use]
    pub fn at(&self, f1: f64, f2: f64) -> [u8; 4] {
        #[cfg(target_arch = "x86_64")]
        if matches!(self, Self::Smooth(_) | Self::SmoothRgb(..)) && SimdLevel::Avx2.is_available() {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            return unsafe { avx2::color_at(self, f1, f2) };
        }
        self.fused_at(f1, f2)
    }

    /// [`SpanColor::at`]'s arithmetic, inlined into its callers (and into a function
    /// compiled for FMA, where `f64::mul_add` is one instruction).
    #[inline(always)]
    fn fused_at(&self, f1: f64, f2: f64) -> [u8; 4] {
        // Channels written out: called per pixel by the paths without a kernel
        // (multisampling, short spans). An out-of-line `at` once made fill at 4x 10% slower;
        // the one call a pixel into `avx2::color_at` does not (fill at 4x, fastest frames:
        // 73-79 ms before fusing, 71-73 ms after).
        let q = |&[a0, g1, g2]: &[f64; 3]| quantize_channel(f2.mul_add(g2, f1.mul_add(g1, a0)));
        match self {
            Self::Flat(c) => *c,
            Self::Smooth([r, g, b, a]) => [q(r), q(g), q(b), q(a)],
            Self::SmoothRgb([r, g, b], alpha) => [q(r), q(g), q(b), *alpha],
            Self::Perspective(p) => p.at(f1, f2),
        }
    }
}

/// What the shading kernels write and how: a triangle's depth plane and colour, the depth
/// test, the id, and the buffers (indexed alike), shared by spans and narrow triangles.
#[derive(Debug)]
pub struct KernelTarget<'a> {
    /// Depth plane `[a0, g1, g2]`.
    pub depth_plane: [f64; 3],
    /// Colour, read where the tile loop holds it (in the record, or rebuilt from a packed one:
    /// a copy per triangle, of up to 104 bytes, was read back with loads spanning its
    /// stores, which store forwarding fails).
    pub color: &'a SpanColor,
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

impl<'a> KernelTarget<'a> {
    /// Lane `l` of eight triangles' depth planes and ids, side by side, with colour `color`
    /// and `depth_test`, into `target`'s buffers.
    #[inline(always)]
    fn lane(
        (depth, id): (&[[f64; 8]; 3], &[i32; 8]),
        l: usize,
        color: &'a SpanColor,
        depth_test: DepthTest,
        target: &'a mut crate::target::TargetBand<'_>,
    ) -> Self {
        KernelTarget {
            depth_plane: [depth[0][l], depth[1][l], depth[2][l]],
            color,
            depth_test,
            id: id[l],
            depth: &mut *target.depth,
            color_out: &mut *target.color,
            ids: target.ids.as_deref_mut(),
            overdraw: target.overdraw.as_deref_mut(),
        }
    }
}

impl KernelTarget<'_> {
    /// One covered pixel `i` at barycentric numerators `(f1, f2)`: the reference loop's
    /// overdraw count, depth test and writes.
    #[inline]
    fn pixel(&mut self, i: usize, f1: f64, f2: f64) {
        if let Some(o) = self.overdraw.as_deref_mut() {
            o[i] += 1;
        }
        let z = self.depth_at(f1, f2);
        if !self.depth_test.passes(z, self.depth[i]) {
            return;
        }
        self.depth[i] = z;
        self.color_out[i] = self.color.at(f1, f2);
        if let Some(ids) = self.ids.as_deref_mut() {
            ids[i] = self.id;
        }
    }

    /// One pixel of a multisampled target, whose samples start at `p`, with covered samples
    /// `mask` and barycentric numerators `centre` at its centre: each covered sample's depth
    /// (at the centre's numerators plus its `offsets`) tested, and if any passes, the colour
    /// at the centre written to the passing samples, as [`crate::shade::shade_triangle`] does.
    #[inline]
    fn pixel_samples(&mut self, p: usize, mask: u32, centre: (i64, i64), offsets: &[[i64; 2]]) {
        let (c1, c2) = centre;
        let mut z = [0.0f32; MAX_SAMPLES];
        let mut passed = 0u32;
        for (s, [o1, o2]) in offsets.iter().enumerate().filter(|(s, _)| mask & (1 << s) != 0) {
            z[s] = self.depth_at((c1 + o1) as f64, (c2 + o2) as f64);
            if self.depth_test.passes(z[s], self.depth[p + s]) {
                passed |= 1 << s;
            }
        }
        if passed == 0 {
            return;
        }
        let color = self.color.at(c1 as f64, c2 as f64);
        for s in (0..offsets.len()).filter(|s| passed & (1 << s) != 0) {
            self.depth[p + s] = z[s];
            self.color_out[p + s] = color;
            if let Some(ids) = self.ids.as_deref_mut() {
                ids[p + s] = self.id;
            }
        }
    }

    /// The depth at barycentric numerators `(f1, f2)`, as stored ([`crate::shade::depth_at`]).
    #[inline(always)]
    fn depth_at(&self, f1: f64, f2: f64) -> f32 {
        crate::shade::depth_at(&PlaneEquation::from_coefficients(self.depth_plane), f1, f2)
    }

    /// [`KernelTarget::checked_len`] of buffers of `samples` elements per pixel: panics
    /// unless `samples` is 4 or 8 and there is no overdraw buffer (it counts per pixel).
    fn checked_samples(&self, samples: usize) -> usize {
        assert!(samples == 4 || samples == 8, "4 or 8 samples per pixel");
        assert!(self.overdraw.is_none(), "no overdraw buffer");
        self.checked_len()
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
///
/// # Panics
/// If the job's buffers differ in length (at every level).
pub fn shade_span(level: SimdLevel, mut job: SpanJob<'_>) {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 support was just checked at run time.
            unsafe { avx512::shade_span(&mut job) }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::shade_span(&mut job) }
        }
        _ => shade_span_scalar(job),
    }
}

/// A span of a multisampled target's pixels in which the triangle covers every sample: per
/// pixel, each sample's depth tested, and if any passes, the colour at the pixel centre
/// written to the passing samples (what [`crate::shade::shade_triangle`] does pixel by
/// pixel). Large triangles at 4x and 8x are mostly such spans. The colour is evaluated at
/// the centres, so they must lie in the triangle (a [`SpanColor::SmoothRgb`] does not clamp):
/// they do, since the standard patterns are centred (their offsets sum to zero, tested), so
/// a centre is the mean of its samples, all covered.
#[derive(Debug)]
pub struct SampleSpanJob<'a> {
    /// The numerators at the pixel centres, and the buffers, `samples` elements per pixel;
    /// there must be no overdraw buffer (it counts per pixel).
    pub span: SpanJob<'a>,
    /// Samples per pixel: 4 or 8.
    pub samples: usize,
    /// Each sample's numerators `[E_1, E_2]` less its pixel centre's (exact integers, the
    /// edge functions being linear).
    pub offsets: [[i64; 2]; MAX_SAMPLES],
}

impl SampleSpanJob<'_> {
    /// Panics unless the job is one the kernels take; returns the span's buffer elements
    /// (samples).
    fn check(&self) -> usize {
        let (n, len) = (self.samples, self.span.target.checked_samples(self.samples));
        assert!(len.is_multiple_of(n), "whole pixels");
        len
    }
}

/// Shades a span of fully covered multisampled pixels at `level` (which must be available;
/// otherwise the scalar kernel runs). At AVX-512, eight samples per step: two pixels at 4x,
/// one at 8x; at AVX2, four, of one pixel.
///
/// # Panics
/// Unless `samples` is 4 or 8, the buffers hold whole pixels alike, and there is no overdraw
/// buffer.
pub fn shade_samples(level: SimdLevel, mut job: SampleSpanJob<'_>) {
    // Each kernel checks the job (`SampleSpanJob::check`) before touching the buffers.
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 support was just checked at run time.
            unsafe { avx512::shade_samples(&mut job) }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::shade_samples(&mut job) }
        }
        _ => samples_scalar(&mut job),
    }
}

/// [`shade_samples`] pixel by pixel, sample by sample.
///
/// # Panics
/// As [`shade_samples`].
pub fn shade_samples_scalar(mut job: SampleSpanJob<'_>) {
    samples_scalar(&mut job);
}

/// [`shade_samples_scalar`] on a borrowed job.
fn samples_scalar(job: &mut SampleSpanJob<'_>) {
    let len = job.check();
    let span = &mut job.span;
    let t = &mut span.target;
    let (mut e1, mut e2) = (span.e1, span.e2);
    let every = (1u32 << job.samples) - 1;
    for p in (0..len).step_by(job.samples) {
        t.pixel_samples(p, every, (e1, e2), &job.offsets[..job.samples]);
        e1 += span.step1;
        e2 += span.step2;
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

/// One past the last buffer element of a box of `rows` rows from `first`, `stride` apart,
/// when each row is `width` elements from its first pixel; `usize::MAX` when that overflows
/// (no buffer holds it): the kernels' bounds checks rest on this, and a job is public, safe
/// to build with any values.
fn box_end(rows: usize, stride: usize, first: usize, width: usize) -> usize {
    rows.saturating_sub(1)
        .checked_mul(stride)
        .and_then(|o| o.checked_add(first))
        .and_then(|o| o.checked_add(width))
        .unwrap_or(usize::MAX)
}

impl NarrowJob<'_> {
    /// [`box_end`] of the job's box.
    fn end(&self, width: usize) -> usize {
        box_end(self.rows, self.stride, self.first, width)
    }

    /// Panics unless the box is one the narrow kernels take ([`assert_narrow`]).
    fn assert_narrow(&self) {
        assert_narrow(self.columns, self.rows);
    }

    /// One past the last buffer element a kernel reads in four-pixel groups.
    fn group_end(&self) -> usize {
        self.end(4 * self.columns.div_ceil(4))
    }
}

/// Panics unless a box of `columns` x `rows` pixels is one the narrow kernels take: 1 to
/// [`NARROW_COLUMNS`] columns, at least one row.
fn assert_narrow(columns: usize, rows: usize) {
    assert!((1..=NARROW_COLUMNS).contains(&columns) && rows > 0, "not a narrow box");
}

/// A narrow kernel's box and where its edges' values are read (`V`: a [`NarrowJob`]'s own,
/// [`JobEdges`], or a lane of a [`NarrowEight`] in place, [`LaneEdges`]).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct NarrowBox<V> {
    values: V,
    columns: usize,
    rows: usize,
    first: usize,
    stride: usize,
}

/// A narrow box's edge values at its first pixel, their steps a pixel right and a row down,
/// and the biases of edges 1 and 2, in `f64` (integers below 2^53: exact). Read one at a
/// time where they are: a [`NarrowEight`] lane's values copied into the box one by one were
/// read back by the kernel loops with wide loads spanning several of those stores, which
/// store forwarding cannot serve (a twentieth of the soup's kernel samples on one such load;
/// soup on one thread, median of six alternated runs' fastest frames, 91.7 -> 82.4 ms).
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
trait EdgeValues {
    /// Edge `k`'s value at the box's first pixel centre.
    fn edge(&self, k: usize) -> f64;
    /// Edge `k`'s step a pixel to the right.
    fn step_x(&self, k: usize) -> f64;
    /// Edge `k`'s step a row down.
    fn step_y(&self, k: usize) -> f64;
    /// Edge `k + 1`'s bias (`k` 0 or 1).
    fn bias(&self, k: usize) -> f64;
}

/// A [`NarrowJob`]'s edge values, in `f64`.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct JobEdges {
    edges: [f64; 3],
    step_x: [f64; 3],
    step_y: [f64; 3],
    bias: [f64; 2],
}

impl EdgeValues for JobEdges {
    #[inline(always)]
    fn edge(&self, k: usize) -> f64 {
        self.edges[k]
    }
    #[inline(always)]
    fn step_x(&self, k: usize) -> f64 {
        self.step_x[k]
    }
    #[inline(always)]
    fn step_y(&self, k: usize) -> f64 {
        self.step_y[k]
    }
    #[inline(always)]
    fn bias(&self, k: usize) -> f64 {
        self.bias[k]
    }
}

/// Lane `lane` of a [`NarrowEight`]'s edge values, read in place.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct LaneEdges<'a> {
    eight: &'a NarrowEight,
    lane: usize,
}

impl EdgeValues for LaneEdges<'_> {
    #[inline(always)]
    fn edge(&self, k: usize) -> f64 {
        self.eight.edges[k][self.lane]
    }
    #[inline(always)]
    fn step_x(&self, k: usize) -> f64 {
        self.eight.step_x[k][self.lane]
    }
    #[inline(always)]
    fn step_y(&self, k: usize) -> f64 {
        self.eight.step_y[k][self.lane]
    }
    #[inline(always)]
    fn bias(&self, k: usize) -> f64 {
        self.eight.bias[k][self.lane]
    }
}

#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
impl NarrowBox<JobEdges> {
    /// `job`'s box.
    #[inline(always)]
    fn of(job: &NarrowJob<'_>) -> Self {
        Self {
            values: JobEdges {
                edges: job.edges.map(|e| e as f64),
                step_x: job.step_x.map(|s| s as f64),
                step_y: job.step_y.map(|s| s as f64),
                bias: job.bias.map(|b| b as f64),
            },
            columns: job.columns,
            rows: job.rows,
            first: job.first,
            stride: job.stride,
        }
    }
}

#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
impl<'a> NarrowBox<LaneEdges<'a>> {
    /// Lane `l`'s box of `eight`, in `target`, its values read in place (without a
    /// [`NarrowJob`], whose `i64` values would be converted from these and back). Panics
    /// unless it is narrow.
    #[inline(always)]
    fn of_lane(eight: &'a NarrowEight, l: usize, target: &crate::target::TargetBand<'_>) -> Self {
        let (columns, rows) = (eight.columns[l], eight.rows[l]);
        assert!((1..=NARROW_COLUMNS as i32).contains(&columns) && rows > 0, "not a narrow box");
        Self {
            values: LaneEdges { eight, lane: l },
            columns: columns as usize,
            rows: rows as usize,
            first: target.index(eight.x0[l], eight.y0[l]),
            stride: target.stride(),
        }
    }
}

#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
impl<V: EdgeValues> NarrowBox<V> {
    /// Panics unless the box is one the narrow kernels take ([`assert_narrow`]).
    fn assert_narrow(&self) {
        assert_narrow(self.columns, self.rows);
    }

    /// One past the last buffer element a kernel reads in four-pixel groups.
    fn group_end(&self) -> usize {
        box_end(self.rows, self.stride, self.first, 4 * self.columns.div_ceil(4))
    }
}

/// Eight window triangles set up for the narrow kernel at once ([`narrow_eight`]), lane `l`
/// for the `l`-th record: what a [`NarrowJob`] holds for one, side by side, one 64-byte row
/// per value. Values are as the job's, in `f64` (integers below 2^53, exact); the colour is
/// the [`SpanColor`] the record's own setup gives: [`SpanColor::Flat`] (not `smooth`),
/// [`SpanColor::SmoothRgb`] (`smooth` and `one_alpha`) or [`SpanColor::Smooth`].
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub struct NarrowEight {
    /// [`NarrowJob::edges`].
    pub edges: [[f64; 8]; 3],
    /// [`NarrowJob::step_x`].
    pub step_x: [[f64; 8]; 3],
    /// [`NarrowJob::step_y`].
    pub step_y: [[f64; 8]; 3],
    /// [`NarrowJob::bias`].
    pub bias: [[f64; 8]; 2],
    /// [`KernelTarget::depth_plane`], coefficient by coefficient.
    pub depth: [[f64; 8]; 3],
    /// The red, green, blue and alpha planes, coefficient by coefficient.
    pub color: [[[f64; 8]; 3]; 4],
    /// The alpha shared by the vertices (of `one_alpha` lanes).
    pub alpha: [i32; 8],
    /// The flat colour, RGBA8 low byte first (of lanes not `smooth`).
    pub flat: [u32; 8],
    /// The lanes with Gouraud colour.
    pub smooth: u8,
    /// The box's first pixel (column, row).
    pub x0: [i32; 8],
    /// See `x0`.
    pub y0: [i32; 8],
    /// [`NarrowJob::columns`].
    pub columns: [i32; 8],
    /// [`NarrowJob::rows`].
    pub rows: [i32; 8],
    /// [`KernelTarget::id`].
    pub id: [i32; 8],
    /// The lanes whose vertices share one alpha.
    pub one_alpha: u8,
}

impl NarrowEight {
    /// What the kernels write for lane `l`, with colour `color` and `depth_test`, into
    /// `target`'s buffers.
    #[inline(always)]
    fn kernel_target<'a>(
        &self,
        l: usize,
        color: &'a SpanColor,
        depth_test: DepthTest,
        target: &'a mut crate::target::TargetBand<'_>,
    ) -> KernelTarget<'a> {
        KernelTarget::lane((&self.depth, &self.id), l, color, depth_test, target)
    }

    /// Lane `l` as the [`NarrowJob`] it stands for, with colour `color` (its
    /// [`NarrowEight::color`]). Panics unless its box is narrow.
    fn job<'a>(
        &self,
        l: usize,
        color: &'a SpanColor,
        depth_test: DepthTest,
        target: &'a mut crate::target::TargetBand<'_>,
    ) -> NarrowJob<'a> {
        let b = NarrowBox::of_lane(self, l, target);
        let v = &b.values;
        // Integers below 2^53 in `f64`: the conversions back are exact.
        NarrowJob {
            edges: [0, 1, 2].map(|k| v.edge(k) as i64),
            step_x: [0, 1, 2].map(|k| v.step_x(k) as i64),
            step_y: [0, 1, 2].map(|k| v.step_y(k) as i64),
            bias: [0, 1].map(|k| v.bias(k) as i64),
            columns: b.columns,
            rows: b.rows,
            first: b.first,
            stride: b.stride,
            target: self.kernel_target(l, color, depth_test, target),
        }
    }

    /// Lane `l`'s colour as the span kernels take it.
    #[inline(always)]
    pub fn color(&self, l: usize) -> SpanColor {
        let lane3 = |v: &[[f64; 8]; 3]| [v[0][l], v[1][l], v[2][l]];
        let planes = [lane3(&self.color[0]), lane3(&self.color[1]), lane3(&self.color[2])];
        if self.smooth >> l & 1 == 0 {
            SpanColor::Flat(self.flat[l].to_le_bytes())
        } else if self.one_alpha >> l & 1 == 1 {
            SpanColor::SmoothRgb(planes, self.alpha[l] as u8)
        } else {
            let [r, g, b] = planes;
            SpanColor::Smooth([r, g, b, lane3(&self.color[3])])
        }
    }
}

/// Sets up eight window records (`records`) for the narrow kernel within `tile` at `level`
/// into `out`, as the tile loop would one by one (`TriangleSetup::from_kept`, the box
/// within the tile, [`TriangleSetup::edges_at`] its first pixel's centre,
/// [`crate::shade::TriangleShader::span_parts_of`]): returns the lanes set up (bit `l`),
/// those whose triangle's box is at most [`NARROW_COLUMNS`] wide and reaches the tile. Only
/// AVX-512 and AVX2 have this path (none at the scalar level: the records are then drawn one
/// by one). The
/// records, one cache line each, are transposed in registers and set up side by side: one
/// by one, the setup and the calls around it (rebuilding the record's setup and planes, the
/// job, the dispatch) took more of a frame of small triangles than the kernel's loop.
///
/// On a target with `samples` per pixel, the box is that of the pixels any of whose samples
/// may be covered: the snapped extent widened by the pattern's reach on every side. Its
/// width before clipping decides narrowness, so a lane set up is narrow at the pixel centres
/// too (the multisampled path of [`crate::shade::shade_triangle`] takes it by row masks), and
/// its box holds every pixel that path's box of the samples holds ([`shade_narrow_samples_eight`]
/// draws the lanes).
#[inline]
pub fn narrow_eight(
    level: SimdLevel,
    records: &[&WindowRecord; 8],
    tile: &PixelRect,
    samples: SampleCount,
    out: &mut NarrowEight,
) -> u8 {
    // At most 112 (8x): a cast that cannot truncate.
    let reach = samples.reach() as i32;
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx512 && level.is_available() {
        // SAFETY: AVX-512 support was just checked at run time.
        return unsafe { avx512::narrow_eight(records, tile, reach, out) };
    }
    narrow_eight_below(level, records, tile, reach, out)
}

/// [`narrow_eight`] at the levels below AVX-512. Out of line: the tile and band loops inline
/// the dispatch, and inlined there too this path made the soup at AVX-512 about 2% slower.
#[inline(never)]
fn narrow_eight_below(
    level: SimdLevel,
    records: &[&WindowRecord; 8],
    tile: &PixelRect,
    reach: i32,
    out: &mut NarrowEight,
) -> u8 {
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx2 && level.is_available() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return unsafe { avx2::narrow_eight(records, tile, reach, out) };
    }
    let _ = (level, records, tile, reach, out);
    0
}

/// Shades lanes `lanes` of `eight` (set up by [`narrow_eight`] at `level`, in that order)
/// into `target` with `depth_test`, as [`shade_narrow`] shades each; returns the number of
/// covered pixels. At AVX-512 and AVX2 the lanes go through the level's narrow kernel loop,
/// read in place (at AVX2, a lane whose last groups would reach past the buffers as below);
/// below, each becomes the [`NarrowJob`] it stands for.
///
/// # Panics
/// If `lanes` reaches past 8, a lane's box is not narrow, or the buffers do not hold it.
#[inline]
pub fn shade_narrow_eight(
    level: SimdLevel,
    eight: &NarrowEight,
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx512 && level.is_available() {
        // SAFETY: AVX-512 support was just checked at run time.
        return unsafe { avx512::shade_narrow_eight(eight, lanes, target, depth_test) };
    }
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: the AVX2 level's features were just checked at run time.
        return unsafe { avx2::shade_narrow_eight(eight, lanes, target, depth_test) };
    }
    lanes.map(|l| narrow_lane_job(level, eight, l, target, depth_test)).sum()
}

/// Lane `l` of `eight` as the [`NarrowJob`] it stands for, through [`shade_narrow`] at
/// `level`: below AVX2, and at AVX2 where the lane's last groups would reach past the
/// buffers. Out of line and cold: at AVX2 few lanes take it (below AVX2 every lane does,
/// on the reference path, which is not timed).
#[cold]
#[inline(never)]
fn narrow_lane_job(
    level: SimdLevel,
    eight: &NarrowEight,
    l: usize,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let color = eight.color(l);
    shade_narrow(level, eight.job(l, &color, depth_test, target))
}

/// Shades lanes `lanes` of `eight` (set up by [`narrow_eight`] at `level` for the target's
/// samples per pixel, in that order) into multisampled `target` with `depth_test`, each as
/// the [`NarrowSamplesJob`] it stands for through [`shade_narrow_samples`]: its
/// [`NarrowJob`], and its samples' edge offsets from the steps (`a = step_x / 256`, exactly).
/// Returns the number of covered samples. Set up one by one, a small triangle's record at
/// 4x was rebuilt into a setup and planes, its box of samples found sample by sample and
/// its job built from the setup, around a kernel that does four times 1x's work.
///
/// # Panics
/// If `lanes` reaches past 8, a lane's box is not narrow or not in the buffers, the target
/// has one sample per pixel, or it has an overdraw buffer (which counts per pixel).
pub fn shade_narrow_samples_eight(
    level: SimdLevel,
    eight: &NarrowEight,
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let samples = target.samples();
    let n = samples.count();
    assert!(n > 1, "a multisampled target");
    let one = i64::from(fixed::ONE);
    let mut covered = 0;
    for l in lanes {
        let color = eight.color(l);
        let narrow = eight.job(l, &color, depth_test, target);
        let mut offsets = [[0i64; 3]; MAX_SAMPLES];
        for (s, o) in offsets.iter_mut().enumerate().take(n) {
            let [ox, oy] = samples.offset(s);
            // `a ox + b oy`, as `shade_triangle` derives them from the edges: the steps are
            // `256 a` and `256 b`, so the sum divides exactly.
            *o = std::array::from_fn(|k| (narrow.step_x[k] * ox + narrow.step_y[k] * oy) / one);
        }
        covered += shade_narrow_samples(level, NarrowSamplesJob { narrow, samples: n, offsets });
    }
    covered
}

/// Eight small triangles' coverage at once ([`small_eight`]), lane `l` for the `l`-th: the
/// values [`TriangleSetup::edges_at`] gives at the centre of its box's first pixel, and the
/// box's pixels inside all three edges. For boxes of at most [`SMALL_BOX`] x [`SMALL_BOX`]
/// pixels (before clipping): the vertices then lie within 9 * 256 of each other and of every
/// pixel centre of the box on each axis, so the edges' coefficients are below 2^12 and their
/// values within the box, even stepped seven rows and seven columns from the first pixel,
/// below 2^25: `i32` lanes hold them exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SmallEight {
    /// Biased edge values at the first pixel's centre.
    pub edges: [[i32; 8]; 3],
    /// Steps one pixel right.
    pub step_x: [[i32; 8]; 3],
    /// Steps one row down.
    pub step_y: [[i32; 8]; 3],
    /// Edges 1 and 2's fill-rule biases (0 or -1).
    pub bias: [[i32; 8]; 2],
    /// Bit `8 r + c`: the pixel `c` columns right of the first and `r` rows down is inside
    /// (for `c` and `r` within the span [`small_eight`] was given, else 0; the caller keeps
    /// those within its box).
    pub inside: [u64; 8],
}

impl SmallEight {
    /// Lane `l`'s barycentric numerators (edges 1 and 2, their fill-rule biases taken off)
    /// at the centre of pixel `bit` (`8 r + c`) of its box: exact in `i32` within the box.
    #[inline(always)]
    #[must_use]
    pub fn numerators(&self, l: usize, bit: u32) -> [i32; 2] {
        let (c, r) = ((bit & 7) as i32, (bit >> 3) as i32);
        let at = |k: usize| {
            let v = self.edges[k][l] + r * self.step_y[k][l] + c * self.step_x[k][l];
            v - self.bias[k - 1][l]
        };
        [at(1), at(2)]
    }

    /// Lane `l`'s barycentric numerators' change from a pixel centre to each sample of
    /// [`SMALL_SAMPLES`] (`sample_offsets` of edges 1 and 2).
    #[inline(always)]
    #[must_use]
    pub fn sample_numerator_offsets(&self, l: usize) -> [[i64; 2]; 4] {
        std::array::from_fn(|s| {
            let o = sample_offsets(self, l, s);
            [i64::from(o[1]), i64::from(o[2])]
        })
    }
}

/// The widest and tallest box (pixels, before clipping) of a triangle [`small_eight`] takes.
pub const SMALL_BOX: i32 = 8;

/// What [`small_eight`] needs of one triangle: its snapped vertices, winding, and the first
/// pixel of its box.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SmallLane {
    /// Snapped vertices.
    pub xy: [[i32; 2]; 3],
    /// Clockwise on screen (see [`TriangleSetup::clockwise`]).
    pub clockwise: bool,
    /// The box's first pixel (column, row).
    pub first: [i32; 2],
}

/// The coverage of eight small triangles `lanes` into `out` (see [`SmallEight`]), the first
/// `span[0]` columns of the first `span[1]` rows of each box (the largest box's, 1 to
/// [`SMALL_BOX`] each), side by side in `i32` lanes from AVX2 on: one at a time, deriving
/// each small triangle's edges and row masks had been about a fifth of a frame of two-pixel
/// triangles (the grid, one thread: doing it twice added 17 ms to 72). Integer arithmetic,
/// the same at every level. Each lane's box must be at most [`SMALL_BOX`] x [`SMALL_BOX`]
/// pixels before clipping, and `first` within it.
///
/// # Panics
/// If `span` is outside those bounds.
#[inline]
pub fn small_eight(
    level: SimdLevel,
    lanes: &[SmallLane; 8],
    span: [usize; 2],
    out: &mut SmallEight,
) {
    let limit = 1..=SMALL_BOX as usize;
    assert!(limit.contains(&span[0]) && limit.contains(&span[1]), "a span within a small box");
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return unsafe { avx2::small_eight(lanes, span, out) };
    }
    small_eight_scalar(lanes, span, out);
}

/// [`small_eight`] a triangle at a time: [`TriangleSetup::edges_at`] and
/// [`crate::raster::edge::row_coverage_within`] on each row, as the narrow path computes
/// them.
pub fn small_eight_scalar(lanes: &[SmallLane; 8], span: [usize; 2], out: &mut SmallEight) {
    for (l, lane) in lanes.iter().enumerate() {
        let setup = TriangleSetup::from_kept(lane.xy, lane.clockwise);
        let (x, y) = (fixed::pixel_centre(lane.first[0]), fixed::pixel_centre(lane.first[1]));
        let (edges, step_x, step_y, bias) = setup.edges_at(x, y);
        let mut row = edges;
        let mut inside = 0;
        let (columns, rows) = (span[0].min(SMALL_BOX as usize), span[1].min(SMALL_BOX as usize));
        for r in 0..rows {
            let mask = crate::raster::edge::row_coverage_within(row, step_x, columns);
            inside |= u64::from(mask) << (8 * r);
            row = std::array::from_fn(|k| row[k] + step_y[k]);
        }
        out.inside[l] = inside;
        for k in 0..3 {
            out.edges[k][l] = edges[k] as i32;
            out.step_x[k][l] = step_x[k] as i32;
            out.step_y[k][l] = step_y[k] as i32;
        }
        out.bias[0][l] = bias[0] as i32;
        out.bias[1][l] = bias[1] as i32;
    }
}

/// What [`shade_small_eight`] needs of eight small triangles beside their coverage
/// ([`SmallEight`]), lane `l` for the `l`-th, side by side as the kernel reads them: the
/// pixels of each box, its depth plane, its colour ([`PerspectiveColor`], the only kind the
/// 3D pipeline's small triangles have a kernel for) and its id. Set lane by lane with
/// [`SmallShading::set`].
#[derive(Clone, Copy, Debug, Default)]
pub struct SmallShading {
    /// The box's first pixel (column, row).
    x0: [i32; 8],
    y0: [i32; 8],
    /// The box's pixels, numbered as [`SmallEight::inside`] numbers them (bit `8 r + c`).
    cells: [u64; 8],
    /// Depth plane `[a0, g1, g2]`, coefficient by coefficient.
    depth: [[f64; 8]; 3],
    inv_area2: [f64; 8],
    /// The vertices' `1 / w`, vertex by vertex.
    inv_w: [[f64; 8]; 3],
    /// -1 where the `1 / w` are affine ([`crate::pipeline::is_affine`]), else 0.
    affine: [i32; 8],
    /// Lane `l`'s colours and scale in a row: channel `ch` of vertex `k` at `4 k + ch`, of
    /// the scale at `12 + ch`. Each set at once (a lane's sixteen values one by one had been
    /// most of the stores setting a lane), the rows transposed where the kernel reads them.
    color_rows: [[f32; 16]; 8],
    /// The 8-bit alpha every fragment gets ([`PerspectiveColor::alpha`]), or -1 for the
    /// weighted one.
    alpha: [i32; 8],
    id: [i32; 8],
}

impl SmallShading {
    /// Lane `l`: the triangle with id `id`, depth plane `depth` and colour `color`, whose
    /// box (within the clip rectangle, at most [`SMALL_BOX`] pixels a side) is `rect`.
    #[inline(always)]
    pub fn set(
        &mut self,
        l: usize,
        rect: &PixelRect,
        depth: &PlaneEquation,
        color: &PerspectiveColor,
        id: i32,
    ) {
        self.set_box(l, rect);
        self.inv_area2[l] = color.inv_area2;
        self.set_shading(l, depth, color, id);
    }

    /// Lane `l`'s `1 / area2`, as set.
    #[inline(always)]
    #[must_use]
    pub fn inv_area2(&self, l: usize) -> f64 {
        self.inv_area2[l]
    }

    /// Lane `l`'s box (see [`SmallShading::set`]).
    #[inline(always)]
    fn set_box(&mut self, l: usize, rect: &PixelRect) {
        let small = |a: i32, b: i32| (b - a).clamp(0, SMALL_BOX - 1) as u32 + 1;
        debug_assert!(small(rect.x0, rect.x1) == (rect.x1 - rect.x0 + 1) as u32, "a small box");
        debug_assert!(small(rect.y0, rect.y1) == (rect.y1 - rect.y0 + 1) as u32, "a small box");
        self.cells[l] = box_cells(small(rect.x0, rect.x1), small(rect.y0, rect.y1));
        (self.x0[l], self.y0[l]) = (rect.x0, rect.y0);
    }

    /// Lane `l`'s depth plane, `1 / w`, colour and id (see [`SmallShading::set`]); after
    /// [`small_run_geometry`], which set its box and `1 / area2` (`color.inv_area2` is not
    /// stored again).
    #[inline(always)]
    pub fn set_shading(
        &mut self,
        l: usize,
        depth: &PlaneEquation,
        color: &PerspectiveColor,
        id: i32,
    ) {
        let [a0, g1, g2] = depth.coefficients();
        (self.depth[0][l], self.depth[1][l], self.depth[2][l]) = (a0, g1, g2);
        let (q, affine) = color.inv_w();
        (self.inv_w[0][l], self.inv_w[1][l], self.inv_w[2][l]) = (q[0], q[1], q[2]);
        self.affine[l] = -i32::from(affine);
        let [[r0, g0, b0, a0], [r1, g1, b1, a1], [r2, g2, b2, a2]] = color.colors;
        let [sr, sg, sb, sa] = color.scale;
        self.color_rows[l] = [r0, g0, b0, a0, r1, g1, b1, a1, r2, g2, b2, a2, sr, sg, sb, sa];
        self.alpha[l] = color.alpha.map_or(-1, |a| i32::from(crate::color::unorm8(a)));
        self.id[l] = id;
    }

    /// The reference loop's view of `target` for lane `l`, whose colour (see
    /// [`SmallShading::color`]) is `color`.
    fn kernel_target<'a>(
        &self,
        l: usize,
        color: &'a SpanColor,
        depth_test: DepthTest,
        target: &'a mut crate::target::TargetBand<'_>,
    ) -> KernelTarget<'a> {
        KernelTarget::lane((&self.depth, &self.id), l, color, depth_test, target)
    }

    /// Lane `l`'s colour as [`SmallShading::set`] was given it (a fixed alpha as `byte /
    /// 255`, whose 8-bit value is that byte).
    fn color(&self, l: usize) -> PerspectiveColor {
        PerspectiveColor {
            colors: std::array::from_fn(|k| {
                std::array::from_fn(|ch| self.color_rows[l][4 * k + ch])
            }),
            scale: std::array::from_fn(|ch| self.color_rows[l][12 + ch]),
            alpha: (self.alpha[l] >= 0).then(|| self.alpha[l] as f32 / 255.0),
            inv_w: std::array::from_fn(|k| self.inv_w[k][l] as f32),
            inv_area2: self.inv_area2[l],
        }
    }
}

/// Sets up eight small triangles' coverage (`eight`, as [`small_eight`] computes it) and boxes
/// and `1 / area2` (in `shading`, as [`SmallShading::set`] sets them) straight from their
/// corners (`rows`, as [`corner_tests_indexed`] leaves them), for the lanes of `mask`, whose
/// corners must be inside the clip volume, with nonzero area: the front end's small runs
/// (`bin::SmallRun`), set up without a `TriangleSetup` or a record. The other lanes get no
/// pixels (their `cells` are 0). Returns the span of the boxes within `clip` (the largest's
/// columns and rows), or `None`, with nothing meaningful set, when a lane of `mask` has a box
/// over [`SMALL_BOX`] pixels a side, or none within `clip` (or, in the scalar version, zero
/// area).
pub fn small_run_geometry(
    level: SimdLevel,
    rows: &CornerGroup,
    mask: u8,
    clip: &PixelRect,
    eight: &mut SmallEight,
    shading: &mut SmallShading,
) -> Option<[usize; 2]> {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 support was just checked at run time.
        return unsafe { avx2::small_run_geometry(rows, (mask, 0), clip, eight, shading) };
    }
    small_run_geometry_scalar(rows, mask, clip, eight, shading)
}

/// [`small_run_geometry`] lane by lane, through setup's functions and [`small_eight_scalar`].
pub fn small_run_geometry_scalar(
    rows: &CornerGroup,
    mask: u8,
    clip: &PixelRect,
    eight: &mut SmallEight,
    shading: &mut SmallShading,
) -> Option<[usize; 2]> {
    lanes_geometry_scalar(rows, mask, clip, false, eight, shading)
}

/// [`small_run_geometry_scalar`], the boxes those of the samples where `multisampled`
/// ([`samples_box`]).
fn lanes_geometry_scalar(
    rows: &CornerGroup,
    mask: u8,
    clip: &PixelRect,
    multisampled: bool,
    eight: &mut SmallEight,
    shading: &mut SmallShading,
) -> Option<[usize; 2]> {
    let mut lanes = [SmallLane::default(); 8];
    let mut span = [1, 1];
    for (l, lane) in lanes.iter_mut().enumerate() {
        let xy = rows.get(l);
        if mask & (1 << l) == 0 {
            shading.cells[l] = 0;
            continue;
        }
        let setup = TriangleSetup::from_snapped(setup::widen(xy), CullMode::None).ok()?;
        let b = if multisampled { samples_box(&setup) } else { setup.bounds };
        if b.x1 - b.x0 >= SMALL_BOX || b.y1 - b.y0 >= SMALL_BOX {
            return None;
        }
        let rect = b.intersect(clip)?;
        *lane = SmallLane { xy, clockwise: setup.clockwise, first: [rect.x0, rect.y0] };
        shading.set_box(l, &rect);
        shading.inv_area2[l] = 1.0 / setup.area2 as f64;
        let (columns, rows) = ((rect.x1 - rect.x0 + 1) as usize, (rect.y1 - rect.y0 + 1) as usize);
        span = [span[0].max(columns), span[1].max(rows)];
    }
    small_eight_scalar(&lanes, span, eight);
    Some(span)
}

/// Shades lanes `lanes` of eight small triangles, in that order (their coverage from
/// [`small_eight`], the rest set in `shading`), into `target` with `depth_test`: each
/// covered pixel of each box as [`KernelTarget`]'s reference loop does (overdraw, depth test,
/// depth, [`PerspectiveColor::at`], id); returns the number of covered pixels. What the 3D
/// pipeline's small triangles (boxes of at most 8 x 8 pixels: the grid's two-pixel ones, most
/// of the bunny's) take in place of the fragment stage (its lanes, or the narrow kernel).
///
/// From AVX2 on, the covered pixels of all the lanes are packed eight to a group, whatever
/// triangle each belongs to, and a group's arithmetic is done at once. At AVX-512 its
/// buffers are gathered and scattered: the pixels of one triangle are distinct, and where two
/// triangles of a group share a pixel the group ends before the later one's (`vpconflictd`),
/// so each depth test sees every earlier write, as in the reference order. AVX2, without
/// scatters, tests depth and writes depth, ids and overdraw lane by lane in that order, then
/// the colours of the lanes that passed, in the same order.
///
/// # Panics
/// If a covered pixel of a box does not lie in the buffers.
#[inline]
pub fn shade_small_eight(
    level: SimdLevel,
    eight: &SmallEight,
    shading: &SmallShading,
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    #[cfg(target_arch = "x86_64")]
    if level == SimdLevel::Avx512 && level.is_available() {
        // SAFETY: AVX-512 support (F, VL, DQ, CD, with POPCNT and BMI) was just checked at run
        // time.
        return unsafe { avx512::shade_small_eight(eight, shading, lanes, target, depth_test) };
    }
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: the AVX2 level's features (AVX2, FMA, POPCNT, BMI1, BMI2) were just checked
        // at run time.
        return unsafe { avx2::shade_small_eight(eight, shading, lanes, target, depth_test) };
    }
    shade_small_eight_scalar(eight, shading, lanes, target, depth_test)
}

/// [`shade_small_eight`] one pixel at a time, through `KernelTarget::pixel`: the
/// definition the AVX2 and AVX-512 kernels are tested against.
#[inline(never)]
pub fn shade_small_eight_scalar(
    eight: &SmallEight,
    shading: &SmallShading,
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let (mut covered, stride) = (0, target.stride());
    for l in lanes {
        let mut inside = eight.inside[l] & shading.cells[l];
        if inside == 0 {
            // Nothing of its box is read (a lane a small run does not draw has none).
            continue;
        }
        let (x0, y0) = (shading.x0[l], shading.y0[l]);
        let first = target.index(x0, y0);
        let color = SpanColor::Perspective(shading.color(l));
        let mut t = shading.kernel_target(l, &color, depth_test, target);
        covered += u64::from(inside.count_ones());
        while inside != 0 {
            let bit = inside.trailing_zeros();
            inside &= inside - 1;
            let (c, r) = ((bit & 7) as usize, (bit >> 3) as usize);
            let [f1, f2] = eight.numerators(l, bit).map(f64::from);
            t.pixel(first + r * stride + c, f1, f2);
        }
    }
    covered
}

/// The pixels of a box of `columns` x `rows` (each 1 to 8), numbered as
/// [`SmallEight::inside`] numbers them (bit `8 r + c`): a row's bits repeated in every byte,
/// cut to `rows` bytes.
#[inline(always)]
pub(crate) fn box_cells(columns: u32, rows: u32) -> u64 {
    debug_assert!((1..=8).contains(&columns) && (1..=8).contains(&rows), "a small box");
    let row = ((1u64 << columns) - 1) * 0x0101_0101_0101_0101;
    row & (u64::MAX >> (64 - 8 * rows))
}

/// Samples per pixel of the multisampled small kernel ([`shade_small_samples`]): the 4x
/// pattern, the CLI's default for meshes.
pub const SMALL_SAMPLES: SampleCount = SampleCount::X4;

/// Each sample's coverage of eight small triangles' boxes on a 4x target: `inside[s][l]` bit
/// `8 r + c` is set where sample `s` of that pixel of lane `l`'s box is covered (numbered as
/// [`SmallEight::inside`], which then holds the pixels with any sample covered).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SmallSamples {
    /// Sample by sample, lane by lane.
    pub inside: [[u64; 8]; 4],
}

impl SmallSamples {
    /// The covered samples of pixel `bit` (`8 r + c`) of lane `l`'s box, bit `s` for
    /// sample `s`.
    #[inline(always)]
    #[must_use]
    pub fn mask(&self, l: usize, bit: u32) -> u32 {
        (0..self.inside.len()).fold(0, |m, s| m | ((self.inside[s][l] >> bit) as u32 & 1) << s)
    }
}

/// Each edge's change (edges 1 and 2's: the barycentric numerators') from lane `l`'s pixel
/// centres to sample `s` of [`SMALL_SAMPLES`]: `A ox + B oy`, the edge's coefficients being its steps
/// over a pixel (`256 A`, `256 B`, exact multiples) over 256. Below 2^12 * 2 * 112 in
/// magnitude for a small triangle.
#[inline(always)]
fn sample_offsets(eight: &SmallEight, l: usize, s: usize) -> [i32; 3] {
    let [ox, oy] = SMALL_SAMPLES.offset(s).map(|v| v as i32);
    std::array::from_fn(|k| (eight.step_x[k][l] >> 8) * ox + (eight.step_y[k][l] >> 8) * oy)
}

/// Each sample's coverage (`out`) of the first `span` columns and rows of eight small
/// triangles' boxes, from their edges at the boxes' first pixel centres (`eight`, as
/// [`small_eight`] sets them), and the pixels with any covered sample into `eight.inside`.
/// The edge values at a sample are those at its pixel centre plus `A ox + B oy`: exact,
/// as the edge functions are linear, and the same row masks as the pixel loop's
/// ([`crate::raster::edge::row_coverage_within`] at the sample's offset). Integer arithmetic,
/// the same at every level.
pub fn small_samples(
    level: SimdLevel,
    eight: &mut SmallEight,
    span: [usize; 2],
    out: &mut SmallSamples,
) {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 support was just checked at run time.
        return unsafe { avx2::small_samples(eight, span, out) };
    }
    small_samples_scalar(eight, span, out);
}

/// [`small_samples`] a lane and a sample at a time.
pub fn small_samples_scalar(eight: &mut SmallEight, span: [usize; 2], out: &mut SmallSamples) {
    let (columns, rows) = (span[0].min(SMALL_BOX as usize), span[1].min(SMALL_BOX as usize));
    for l in 0..8 {
        let step_x = std::array::from_fn(|k| i64::from(eight.step_x[k][l]));
        let step_y: [i64; 3] = std::array::from_fn(|k| i64::from(eight.step_y[k][l]));
        let mut any = 0;
        for (s, inside) in out.inside.iter_mut().enumerate() {
            let o = sample_offsets(eight, l, s);
            let mut row: [i64; 3] = std::array::from_fn(|k| i64::from(eight.edges[k][l] + o[k]));
            let mut mask = 0;
            for r in 0..rows {
                let bits = crate::raster::edge::row_coverage_within(row, step_x, columns);
                mask |= u64::from(bits) << (8 * r);
                row = std::array::from_fn(|k| row[k] + step_y[k]);
            }
            inside[l] = mask;
            any |= mask;
        }
        eight.inside[l] = any;
    }
}

/// The pixels any of whose [`SMALL_SAMPLES`] the snapped box of `setup` holds: the union of
/// the sample boxes, as [`crate::shade::shade_triangle`] takes them (before clipping). Each
/// side of a sample's box moves against its offset, so the union takes each side from the
/// sample farthest that way: on both axes the 4x pattern reaches its `reach` each way, so
/// two boxes give it (`samples_box_is_the_union_of_the_sample_boxes`): the default render,
/// load and four frames, 1.0110 -> 0.9872 G instructions against the four and their union.
#[must_use]
pub fn samples_box(setup: &TriangleSetup) -> PixelRect {
    let (extent, reach) = (setup.extent(), SMALL_SAMPLES.reach());
    let first = setup::sample_bounds(extent, [reach, reach]);
    let last = setup::sample_bounds(extent, [-reach, -reach]);
    PixelRect { x0: first.x0, y0: first.y0, x1: last.x1, y1: last.y1 }
}

/// [`small_run_geometry`] for a 4x target ([`SMALL_SAMPLES`]): each lane's box the pixels any
/// of whose samples its snapped box holds (the union of the sample boxes, as
/// [`crate::shade::shade_triangle`] takes them), at most [`SMALL_BOX`] pixels a side before
/// clipping, and each sample's coverage in `samples` ([`small_samples`]). From AVX2 on, the
/// boxes of the extents widened by the pattern's reach, the same as the union, since the 4x
/// pattern reaches as far each way on both axes (tested against the scalar version).
pub fn small_run_samples_geometry(
    level: SimdLevel,
    rows: &CornerGroup,
    mask: u8,
    clip: &PixelRect,
    (eight, samples, shading): (&mut SmallEight, &mut SmallSamples, &mut SmallShading),
) -> Option<[usize; 2]> {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        let reach = SMALL_SAMPLES.reach() as i32;
        // SAFETY: AVX2 support was just checked at run time.
        let span = unsafe { avx2::small_run_geometry(rows, (mask, reach), clip, eight, shading) };
        small_samples(level, eight, span?, samples);
        return span;
    }
    small_run_samples_geometry_scalar(rows, mask, clip, (eight, samples, shading))
}

/// [`small_run_samples_geometry`] lane by lane, through setup's functions and the scalar
/// coverage.
pub fn small_run_samples_geometry_scalar(
    rows: &CornerGroup,
    mask: u8,
    clip: &PixelRect,
    (eight, samples, shading): (&mut SmallEight, &mut SmallSamples, &mut SmallShading),
) -> Option<[usize; 2]> {
    let span = lanes_geometry_scalar(rows, mask, clip, true, eight, shading)?;
    small_samples_scalar(eight, span, samples);
    Some(span)
}

/// [`shade_small_eight`] on a 4x target ([`SMALL_SAMPLES`], no overdraw buffer): the pixels of
/// each box with any covered sample (`samples`, [`small_samples`]) as the pixel loop draws
/// them ([`KernelTarget`]'s multisampled pixel: each covered sample's depth tested, and where
/// one passes, the colour at the pixel centre written to those that passed). Returns the
/// number of covered samples. From AVX2 on, eight listed pixels a group whatever triangle
/// each belongs to (their four samples' depths and the centre's colour side by side), the
/// depth tests and writes pixel by pixel in listed order.
///
/// # Panics
/// If the target is not 4x, has an overdraw buffer, or a covered pixel of a box does not lie
/// in the buffers.
#[inline]
pub fn shade_small_samples(
    level: SimdLevel,
    (eight, samples, shading): (&SmallEight, &SmallSamples, &SmallShading),
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    assert!(target.samples() == SMALL_SAMPLES, "a 4x target");
    assert!(target.overdraw.is_none(), "no overdraw buffer");
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: the AVX2 level's features (AVX2, FMA, POPCNT, BMI1, BMI2) were just checked
        // at run time.
        return unsafe {
            avx2::shade_small_samples(eight, samples, shading, lanes, target, depth_test)
        };
    }
    shade_small_samples_scalar((eight, samples, shading), lanes, target, depth_test)
}

/// [`shade_small_samples`] one pixel at a time, through [`KernelTarget`]'s multisampled pixel.
pub fn shade_small_samples_scalar(
    (eight, samples, shading): (&SmallEight, &SmallSamples, &SmallShading),
    lanes: std::ops::Range<usize>,
    target: &mut crate::target::TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let n = SMALL_SAMPLES.count();
    assert!(target.samples() == SMALL_SAMPLES, "a 4x target");
    let (mut covered, stride) = (0, target.stride());
    for l in lanes {
        let mut any = eight.inside[l] & shading.cells[l];
        if any == 0 {
            continue;
        }
        let first = target.index(shading.x0[l], shading.y0[l]);
        let offsets = eight.sample_numerator_offsets(l);
        let color = SpanColor::Perspective(shading.color(l));
        let mut t = shading.kernel_target(l, &color, depth_test, target);
        while any != 0 {
            let bit = any.trailing_zeros();
            any &= any - 1;
            let mask = samples.mask(l, bit);
            let (c, r) = ((bit & 7) as usize, (bit >> 3) as usize);
            let [f1, f2] = eight.numerators(l, bit).map(i64::from);
            t.pixel_samples(n * (first + r * stride + c), mask, (f1, f2), &offsets);
            covered += u64::from(mask.count_ones());
        }
    }
    covered
}

/// Shades a small triangle at `level`; returns the number of covered pixels. At AVX2, a box
/// whose last four-pixel group would reach past the buffers (the target's last row, right
/// edge) takes the scalar kernel; AVX-512 masks its loads and stores to the box.
///
/// # Panics
/// If the box is empty or wider than [`NARROW_COLUMNS`], or the buffers do not hold it.
pub fn shade_narrow(level: SimdLevel, mut job: NarrowJob<'_>) -> u64 {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 support was just checked at run time.
            unsafe { avx512::shade_narrow(&mut job) }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2
            if SimdLevel::Avx2.is_available() && job.group_end() <= job.target.depth.len() =>
        {
            // SAFETY: the AVX2 level's features were just checked at run time.
            unsafe { avx2::shade_narrow(&mut job) }
        }
        _ => shade_narrow_scalar(job),
    }
}

/// [`shade_narrow`] pixel by pixel: the reference loop's coverage test and arithmetic.
///
/// # Panics
/// As [`shade_narrow`].
pub fn shade_narrow_scalar(mut job: NarrowJob<'_>) -> u64 {
    job.assert_narrow();
    // Up front, as the AVX-512 kernel checks: pixel by pixel, a box of `usize::MAX` rows with
    // nothing covered had run without end, and one whose offsets wrap had written a pixel
    // outside it.
    let n = job.target.checked_len();
    assert!(job.end(job.columns) <= n, "the box must lie in the buffers");
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

/// A small triangle on a multisampled target shaded whole, coverage included, as
/// [`NarrowJob`] at 1x: each sample's edge values are its pixel centre's plus a constant
/// offset, so the coverage of every sample of the box is a sign test, and the covered samples
/// take [`SampleSpanJob`]'s arithmetic (depth at the sample, colour at the pixel centre).
/// Most triangles of a scene of small triangles at 4x are such boxes, and pixel by pixel each
/// partly covered pixel was a loop over its samples.
#[derive(Debug)]
pub struct NarrowSamplesJob<'a> {
    /// The box and the triangle's edge values at its pixel centres, as at 1x; `first` and
    /// `stride` count pixels, and the buffers hold `samples` elements per pixel (a pixel's
    /// samples side by side). There must be no overdraw buffer (it counts per pixel).
    pub narrow: NarrowJob<'a>,
    /// Samples per pixel: 4 or 8.
    pub samples: usize,
    /// Each sample's edge values less its pixel centre's (exact integers, the edge functions
    /// being linear); those of edges 1 and 2 are its barycentric numerators' offsets. As
    /// setup gives them, edge values over the box stay below 2^49 in magnitude, exact in the
    /// kernels' `f64` lanes; jobs far outside that give unspecified values within the box
    /// (and may panic on overflow in debug builds), never a write outside it.
    pub offsets: [[i64; 3]; MAX_SAMPLES],
}

impl NarrowSamplesJob<'_> {
    /// Panics unless the job is one the kernels take.
    fn check(&self) {
        let (job, n) = (&self.narrow, self.samples);
        let len = job.target.checked_samples(n);
        job.assert_narrow();
        // Checked arithmetic: the kernels' offsets stay in the buffers only if this holds.
        assert!(job.end(job.columns).checked_mul(n).is_some_and(|e| e <= len), "box outside");
    }
}

/// Shades a small triangle on a multisampled target at `level` (which must be available;
/// otherwise the scalar kernel runs); returns the number of covered samples. AVX-512 takes
/// eight samples per step (two pixels at 4x, one at 8x), AVX2 four (one pixel at 4x).
///
/// # Panics
/// Unless `samples` is 4 or 8, the box is not empty and at most [`NARROW_COLUMNS`] wide, the
/// buffers hold it, and there is no overdraw buffer.
pub fn shade_narrow_samples(level: SimdLevel, mut job: NarrowSamplesJob<'_>) -> u64 {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 support was just checked at run time.
            unsafe { avx512::shade_narrow_samples(&mut job) }
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::shade_narrow_samples(&mut job) }
        }
        _ => narrow_samples_scalar(&mut job),
    }
}

/// [`shade_narrow_samples`] pixel by pixel, sample by sample: the arithmetic of
/// [`crate::shade::shade_triangle`]'s multisampled pixels.
///
/// # Panics
/// As [`shade_narrow_samples`].
pub fn shade_narrow_samples_scalar(mut job: NarrowSamplesJob<'_>) -> u64 {
    narrow_samples_scalar(&mut job)
}

/// [`shade_narrow_samples_scalar`] on a borrowed job.
fn narrow_samples_scalar(job: &mut NarrowSamplesJob<'_>) -> u64 {
    job.check();
    let (n, offsets) = (job.samples, job.offsets);
    let numerators = offsets.map(|[_, o1, o2]| [o1, o2]);
    let job = &mut job.narrow;
    let t = &mut job.target;
    let mut covered = 0;
    let mut row = job.edges;
    for r in 0..job.rows {
        let mut e = row;
        for c in 0..job.columns {
            let mask = (0..n).fold(0u32, |m, s| {
                let o = offsets[s];
                m | u32::from(((e[0] + o[0]) | (e[1] + o[1]) | (e[2] + o[2])) >= 0) << s
            });
            covered += u64::from(mask.count_ones());
            let centre = (e[1] - job.bias[0], e[2] - job.bias[1]);
            t.pixel_samples(n * (job.first + r * job.stride + c), mask, centre, &numerators[..n]);
            e = std::array::from_fn(|k| e[k] + job.step_x[k]);
        }
        row = std::array::from_fn(|k| row[k] + job.step_y[k]);
    }
    covered
}

/// The scalar kernel: the reference loop's arithmetic, specialised to plane colours.
///
/// # Panics
/// As [`shade_span`].
pub fn shade_span_scalar(mut job: SpanJob<'_>) {
    span_scalar(&mut job);
}

/// [`shade_span_scalar`] on a borrowed job: the kernels hand each other jobs by reference,
/// since a job moved into a kernel that is not inlined is copied, and that copy (wide loads
/// of fields just written by narrow stores) was a twelfth of a frame of small triangles.
fn span_scalar(job: &mut SpanJob<'_>) {
    let (mut e1, mut e2) = (job.e1, job.e2);
    // As the vector kernels: buffers of one length (a longer colour buffer had been drawn
    // without a word here, and refused by them).
    for k in 0..job.target.checked_len() {
        job.target.pixel(k, e1 as f64, e2 as f64);
        e1 += job.step1;
        e2 += job.step2;
    }
}

/// Eight window triangles set up side by side, as a structure of arrays: lane `k` holds what
/// [`TriangleSetup::new`] gives triangle `k` and, when that is set up, `1 / area2` as the
/// per-triangle front end computes it (`1.0 / area2 as f64`, from which the draw computes
/// the planes). Read a lane with [`WindowGroup::lane`].
#[derive(Clone, Copy, Debug, Default)]
pub struct WindowGroup {
    /// Why each lane's triangle was not set up (`None`: it was).
    pub rejected: [Option<Rejection>; 8],
    /// Snapped vertex x, `[vertex][lane]`.
    pub x: [[i32; 8]; 3],
    /// Snapped vertex y, `[vertex][lane]`.
    pub y: [[i32; 8]; 3],
    /// Twice the area.
    pub area2: [i64; 8],
    /// Bit `k`: lane `k` is clockwise.
    pub clockwise: u8,
    /// Pixel bounds, `[x0, y0, x1, y1][lane]`.
    pub bounds: [[i32; 8]; 4],
    /// `1 / area2`.
    pub inv_area2: [f64; 8],
}

impl WindowGroup {
    /// Lane `k`: the triangle's setup and `1 / area2`, or why it was not set up.
    ///
    /// # Panics
    /// If `k` is 8 or more.
    #[inline(always)]
    pub fn lane(&self, k: usize) -> Result<(TriangleSetup, f64), Rejection> {
        if let Some(why) = self.rejected[k] {
            return Err(why);
        }
        let setup = TriangleSetup {
            xy: [
                [self.x[0][k], self.y[0][k]],
                [self.x[1][k], self.y[1][k]],
                [self.x[2][k], self.y[2][k]],
            ],
            area2: self.area2[k],
            clockwise: self.clockwise >> k & 1 != 0,
            bounds: PixelRect {
                x0: self.bounds[0][k],
                y0: self.bounds[1][k],
                x1: self.bounds[2][k],
                y1: self.bounds[3][k],
            },
        };
        Ok((setup, self.inv_area2[k]))
    }
}

/// Eight window triangles' records and coverage rectangles at 1x, as the lane-by-lane path
/// makes them from a [`WindowGroup`] (`WindowRecord`'s constructor from
/// [`WindowGroup::lane`], and [`crate::bin::coverage_bounds`]); built by [`window_records`].
/// Only the lanes the group set up mean anything.
#[derive(Clone, Copy, Debug, Default)]
pub struct WindowRecords {
    /// Lane `l`'s record.
    pub records: [WindowRecord; 8],
    /// The coverage rectangles, `[x0, y0, x1, y1][lane]`.
    cover: [[i32; 8]; 4],
    /// Lanes whose rectangle holds no pixel of the clip (bit `l` for lane `l`).
    pub empty: u8,
}

impl WindowRecords {
    /// Lane `l`'s coverage rectangle (meaningful where it is not `empty`).
    #[inline(always)]
    #[must_use]
    pub fn cover(&self, l: usize) -> PixelRect {
        let c = &self.cover;
        PixelRect { x0: c[0][l], y0: c[1][l], x1: c[2][l], y1: c[3][l] }
    }
}

/// The records of window group `group` (triangles `tris`, the first with id `first_id`, drawn
/// with smooth colour when `smooth`) and their coverage within `clip` on a 1x target, into
/// `out`: at AVX2 and AVX-512 (the AVX2 kernel at both; only measured at AVX2), eight
/// records built in registers (the group's integers and each vertex's depth and colour
/// transposed into whole records, written as two 32-byte stores each; the caller copies each
/// kept one into the batch whole). False at the scalar level, where the front end builds them
/// one by one. Why: one by one, each record had been written field by field, sixteen scalar
/// stores into a cache line the batch's buffer had not yet brought in, behind a
/// `TriangleSetup` rebuilt per lane; that was the largest part of the window front end.
#[inline]
pub fn window_records(
    level: SimdLevel,
    tris: &[[Vertex; 3]; 8],
    group: &WindowGroup,
    (clip, smooth, first_id): (&PixelRect, bool, i32),
    out: &mut WindowRecords,
) -> bool {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 support was just checked at run time.
        unsafe { avx2::window_records(tris, group, (clip, smooth, first_id), out) };
        return true;
    }
    let _ = (level, tris, group, clip, smooth, first_id, out);
    false
}

/// Each lane's [`rejection`] from the window groups' four tests as bit masks (bit `l` for
/// lane `l`): finite, in range, degenerate, culled. A group whose lanes are all set up (the
/// usual one) skips the per-lane reasons.
fn rejections([finite, in_range, degenerate, culled]: [u8; 4]) -> [Option<Rejection>; 8] {
    if finite & in_range & !degenerate & !culled == u8::MAX {
        return [None; 8];
    }
    std::array::from_fn(|l| {
        let bit = |m: u8| m >> l & 1 != 0;
        rejection(bit(finite), bit(in_range), bit(degenerate), bit(culled))
    })
}

/// Why a triangle was not set up, from the window groups' tests, in the per-triangle front
/// end's order (`None`: it was).
fn rejection(finite: bool, in_range: bool, degenerate: bool, culled: bool) -> Option<Rejection> {
    if !finite {
        Some(Rejection::NonFinite)
    } else if !in_range {
        Some(Rejection::OutOfRange)
    } else if degenerate {
        Some(Rejection::Degenerate)
    } else if culled {
        Some(Rejection::Culled)
    } else {
        None
    }
}

/// Sets up eight window triangles side by side into `out` at `level` (AVX-512: eight lanes
/// of `i64` and `f64`; AVX2: two halves of four `f64` lanes, where setup's integers are
/// exact); returns `false`, with `out` untouched, at the scalar level, where the caller sets
/// them up one by one: that per-triangle front end is what the kernels are tested against.
pub fn window_group(
    level: SimdLevel,
    tris: &[[Vertex; 3]; 8],
    cull: CullMode,
    out: &mut WindowGroup,
) -> bool {
    match level {
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx512 if SimdLevel::Avx512.is_available() => {
            // SAFETY: AVX-512 F, VL and DQ support was just checked at run time.
            unsafe { avx512::window_group(tris, cull, out) };
            true
        }
        #[cfg(target_arch = "x86_64")]
        SimdLevel::Avx2 if SimdLevel::Avx2.is_available() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::window_group(tris, cull, out) };
            true
        }
        _ => false,
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
    if level.has_avx2() {
        for (p, o) in positions.chunks_exact(8).zip(out.chunks_exact_mut(8)) {
            let p: &[Vec4; 8] = p.try_into().expect("chunks of eight");
            let o: &mut [Corner; 8] = o.try_into().expect("chunks of eight");
            // SAFETY: AVX2 and FMA support was just checked at run time.
            *o = unsafe { avx2::window_corners(p, volume.guard(), viewport.half_size()) };
            done += 8;
        }
    }
    window_corners_scalar(&positions[done..], volume, viewport, &mut out[done..]);
}

/// What the 3D pipeline's front end keeps of eight vertices at clip-space positions: each
/// one's outcode ([`ClipVolume::outcode`]) and, for those inside the clip volume whose
/// window position snaps ([`Viewport::map_snapped`]), the snapped position, window depth and
/// `1 / w`, with its bit of `snapped` set; zeros elsewhere.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct WindowVertices {
    /// Bit `i` set where plane `i` has the vertex outside.
    pub outcode: [u8; 8],
    /// Snapped window positions.
    pub xy: [[i32; 2]; 8],
    /// Window depths.
    pub z: [f32; 8],
    /// `1 / w`.
    pub inv_w: [f32; 8],
    /// The lanes inside whose position snapped.
    pub snapped: u8,
}

/// [`WindowVertices`] of eight positions in AVX2 (the arithmetic of [`window_corners`], the
/// plane tests kept apart), `None` below it, where the front end takes one vertex at a
/// time: the per-vertex work of a mesh shaded up front (a grid of 500,000 vertices: 4.8 ms
/// of its frame on one thread).
#[inline]
#[must_use]
pub(crate) fn window_vertices(
    level: SimdLevel,
    positions: &[Vec4; 8],
    volume: &ClipVolume,
    viewport: &Viewport,
) -> Option<WindowVertices> {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return Some(unsafe {
            avx2::window_vertices(positions, volume.guard(), viewport.half_size())
        });
    }
    let _ = (level, positions, volume, viewport);
    None
}

/// The smallest and largest of `values` (`(u32::MAX, 0)` when empty), at `level`: the 3D
/// pipeline's pass over a mesh's indices, which validates them and sizes each batch's vertex
/// window. Without SSE4.1 (not in the x86_64 baseline) the compiler has no unsigned 32-bit
/// min and max and emulated them: 225 ms a frame over the dense scene's 300 million indices,
/// where AVX2's `vpminud`/`vpmaxud` keep up with memory.
#[must_use]
pub fn index_range(level: SimdLevel, values: &[u32]) -> (u32, u32) {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return unsafe { avx2::index_range(values) };
    }
    index_range_scalar(values)
}

/// [`index_range`] one value at a time.
#[must_use]
pub fn index_range_scalar(values: &[u32]) -> (u32, u32) {
    values.iter().fold((u32::MAX, 0), |(lo, hi), &i| (lo.min(i), hi.max(i)))
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
    /// Kept by both tests above, but its box holds no sample of the clip rectangle's pixels
    /// ([`setup::holds_no_sample`]).
    pub empty: u8,
}

/// The front end's first tests for eight triangles whose corners are all inside the clip
/// volume, from their snapped corners alone: zero area and culling
/// ([`TriangleSetup::signed_area2`]), then no sample of `samples` in the box
/// ([`setup::holds_no_sample`]: one box test per sample position), in that precedence.
/// Triangles with a corner [`OUTSIDE`] are not `inside` and report nothing else. In a dense
/// mesh nearly every triangle stops here; AVX2 decides eight at once.
#[must_use]
pub fn corner_tests(
    level: SimdLevel,
    group: &CornerGroup,
    cull: CullMode,
    clip: &PixelRect,
    samples: SampleCount,
) -> CornerTests {
    match level {
        #[cfg(target_arch = "x86_64")]
        _ if level.has_avx2() => {
            // SAFETY: AVX2 and FMA support was just checked at run time.
            unsafe { avx2::corner_tests(group, cull, clip, samples) }
        }
        _ => corner_tests_scalar(group, cull, clip, samples),
    }
}

/// [`corner_tests`] for eight consecutive triangles of an index buffer whose corners are
/// `window[i - base]` for index `i`, which it also leaves in `rows` (for
/// [`small_run_geometry`]). AVX2 reads each corner straight into a vector: filling a
/// [`CornerGroup`] first and loading its rows would read memory just written.
///
/// # Panics
/// If an index minus `base` falls outside the window.
#[must_use]
pub fn corner_tests_indexed(
    level: SimdLevel,
    (tris, window, base): (&[[u32; 3]; 8], &[Corner], u32),
    cull: CullMode,
    clip: &PixelRect,
    samples: SampleCount,
    rows: &mut CornerGroup,
) -> CornerTests {
    #[cfg(target_arch = "x86_64")]
    if level.has_avx2() {
        // SAFETY: AVX2 and FMA support was just checked at run time.
        return unsafe {
            avx2::corner_tests_indexed(tris, window, base, (cull, clip, samples), rows)
        };
    }
    for (k, tri) in tris.iter().enumerate() {
        rows.set(k, tri.map(|i| window[i.wrapping_sub(base) as usize]));
    }
    corner_tests(level, rows, cull, clip, samples)
}

/// [`corner_tests`] lane by lane, through the front end's own functions.
#[must_use]
pub fn corner_tests_scalar(
    group: &CornerGroup,
    cull: CullMode,
    clip: &PixelRect,
    samples: SampleCount,
) -> CornerTests {
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
                if setup::holds_no_sample(setup::extent(corners), samples, clip) {
                    t.empty |= 1 << k;
                }
            }
        }
    }
    t
}

/// Runs `$body` with `$rgba` bound to the colour of a vector of lanes at barycentric
/// numerators `(f1, f2)` (of type `$lanes`) as a closure, one per colour kind: each kind's
/// loop is compiled on its own, without a match per group (and with groups small enough to
/// inline). `$flat` broadcasts a colour's bits; `$smooth::<CLAMP>(planes, alpha, f1, f2)`
/// evaluates planes (red, green, blue, and alpha when `alpha` is `None`). A
/// [`SpanColor::SmoothRgb`] is not clamped unless the call starts with `clamped`: kernels
/// that evaluate colour where the triangle may not cover (partly covered pixels' centres)
/// must ask for it.
#[cfg(target_arch = "x86_64")]
macro_rules! with_rgba {
    (@ $clamp_rgb:literal, $color:expr, $lanes:ty, $flat:expr, $smooth:ident, $rgba:ident =>
        $body:expr) => {
        match $color {
            SpanColor::Flat(c) => {
                let flat = $flat(i32::from_le_bytes(c));
                let $rgba = move |_: $lanes, _: $lanes| flat;
                $body
            }
            SpanColor::Smooth(p) => {
                let $rgba = move |f1, f2| $smooth::<true>(&p, None, f1, f2);
                $body
            }
            SpanColor::SmoothRgb(p, alpha) => {
                let $rgba = move |f1, f2| $smooth::<$clamp_rgb>(&p, Some(alpha), f1, f2);
                $body
            }
            // Each kernel module's `perspective`: the sRGB encoder's clamps make any lane
            // safe, inside the triangle or not.
            SpanColor::Perspective(p) => {
                let (table, (q, affine)) = (crate::color::srgb8_table(), p.inv_w());
                let $rgba = move |f1, f2| perspective(&p, (q, affine), table, f1, f2);
                $body
            }
        }
    };
    (clamped $color:expr, $lanes:ty, $flat:expr, $smooth:ident, $rgba:ident => $body:expr) => {
        with_rgba!(@ true, $color, $lanes, $flat, $smooth, $rgba => $body)
    };
    ($color:expr, $lanes:ty, $flat:expr, $smooth:ident, $rgba:ident => $body:expr) => {
        with_rgba!(@ false, $color, $lanes, $flat, $smooth, $rgba => $body)
    };
}

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    /// A record pushed with streaming stores is the record, field for field, and so is one
    /// pushed when the vector has no room (an ordinary push, which grows it); the records
    /// before it stay as they were.
    #[test]
    fn streamed_records_are_the_records_pushed() {
        let record = |k: i32| {
            let mut r = WindowRecord::default();
            r.xy = [[k, -k], [3 * k, 7], [-1, k << 8]];
            r.z = [0.25, k as f32, -0.0];
            r.colors = [[k as u8, 1, 2, 3], [4; 4], [255, 0, (k * 7) as u8, 9]];
            r.inv_area2 = 1.0 / f64::from(k + 1);
            r.id = k;
            (r.clockwise, r.smooth) = (k % 2 == 0, k % 3 == 0);
            r
        };
        // Room for five: the other seven go through an ordinary push.
        let mut streamed = Vec::with_capacity(5);
        for k in 0..12 {
            push_streamed(&mut streamed, &record(k));
        }
        store_fence();
        assert_eq!(streamed.len(), 12);
        for (k, r) in streamed.iter().enumerate() {
            // `Debug` prints each float as the shortest text that reads back to its bits.
            assert_eq!(format!("{r:?}"), format!("{:?}", record(k as i32)), "record {k}");
        }
    }

    /// The string store fills exactly the slice it is given, as `fill` does: every length
    /// from 0 to 67 at every start within a line's first words, for each kind of word, the
    /// words around it left as they were.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn string_store_fills_as_fill_does() {
        fn check<T: Word + PartialEq + std::fmt::Debug>(around: T, value: T) {
            for start in 0..5 {
                for len in 0..68 {
                    let mut strings = vec![around; 80];
                    let mut plain = strings.clone();
                    fill_words_with(&mut strings[start..start + len], value, true);
                    plain[start..start + len].fill(value);
                    assert_eq!(strings, plain, "start {start}, length {len}");
                }
            }
        }
        check(7u32, 0xDEAD_BEEF);
        check(-5i32, -1);
        check(0.5f32, 1.0);
        check([1u8, 2, 3, 4], [0, 0, 0, 255]);
    }

    /// [`samples_box`] is the union of the four sample positions' boxes, for random snapped
    /// boxes (degenerate, sub-pixel and large, at negative and positive coordinates).
    #[test]
    fn samples_box_is_the_union_of_the_sample_boxes() {
        let mut rng = SmallRng::seed_from_u64(5);
        for round in 0..20_000 {
            let size = [0, 1, 40, 300, 5000][round % 5];
            let mut corner = || {
                let x0 = rng.random_range(-4000..4000);
                [x0, x0 + rng.random_range(0..=size)]
            };
            let ([x0, x1], [y0, y1]) = (corner(), corner());
            let setup = TriangleSetup::from_kept([[x0, y0], [x1, y0], [x0, y1]], true);
            let extent = setup.extent();
            let union = (0..SMALL_SAMPLES.count())
                .map(|s| setup::sample_bounds(extent, SMALL_SAMPLES.offset(s)))
                .reduce(|a, b| a.union(&b))
                .unwrap();
            assert_eq!(samples_box(&setup), union, "{extent:?}");
        }
    }

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
        // Lanes found degenerate, culled, empty, kept, with a corner outside, and decided
        // otherwise by sample positions than by the centre.
        let mut seen = [0u32; 6];
        for round in 0..40_000 {
            let mut group = CornerGroup::default();
            for k in 0..8 {
                let mut tri = [[0i32; 2]; 3];
                let kind = rng.random_range(0..5);
                let base = [rng.random_range(-3000..3000), rng.random_range(-3000..3000)];
                for (v, p) in tri.iter_mut().enumerate() {
                    *p = match kind {
                        // Within a few pixels, often on a centre or a centre +- 1.
                        0 => base.map(|b| {
                            256 * (b / 256) + 128 + rng.random_range(-3..4) * [1, 64, 255][v]
                        }),
                        // Under a pixel, on or beside sample positions (multiples of 16 from
                        // a centre, +- 1): where each position's box test decides.
                        4 => base.map(|b| {
                            256 * (b / 256)
                                + 128
                                + 16 * rng.random_range(-8..8)
                                + rng.random_range(-1..2)
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
            let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][(round / 3) % 3];
            let expect = corner_tests_scalar(&group, cull, &clip, samples);
            // Lanes the sample positions decide otherwise than the centre alone.
            let centre = corner_tests_scalar(&group, cull, &clip, SampleCount::X1);
            seen[5] += (expect.empty ^ centre.empty).count_ones();
            let lanes = expect.inside;
            seen[0] += expect.degenerate.count_ones();
            seen[1] += expect.culled.count_ones();
            seen[2] += expect.empty.count_ones();
            seen[3] += (lanes & !(expect.degenerate | expect.culled | expect.empty)).count_ones();
            for level in SimdLevel::available() {
                let got = corner_tests(level, &group, cull, &clip, samples);
                assert_eq!(got, expect, "{level:?} {samples:?} {group:?}");
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
            let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][(round / 3) % 3];
            let expect = corner_tests_scalar(&group, cull, &clip, samples);
            for level in SimdLevel::available() {
                let mut rows = CornerGroup::default();
                let group_of = (&tris, &window[..], base);
                let got = corner_tests_indexed(level, group_of, cull, &clip, samples, &mut rows);
                assert_eq!(got, expect, "{level:?}, {samples:?}, round {round}");
                assert_eq!(rows, group, "{level:?}, {samples:?}, round {round}");
            }
        }
        let window = [[0, 0]; 5];
        let mut tris = [[0u32, 1, 2]; 8];
        tris[6][1] = 5;
        for level in SimdLevel::available() {
            let r = std::panic::catch_unwind(|| {
                let clip = PixelRect::EMPTY;
                let mut rows = CornerGroup::default();
                let group_of = (&tris, &window[..], 0);
                let x1 = SampleCount::X1;
                corner_tests_indexed(level, group_of, CullMode::None, &clip, x1, &mut rows)
            });
            assert!(r.is_err(), "{level:?} read past the window");
        }
    }

    /// The vector corners against [`window_corner`], and the vertices eight at a time against
    /// the outcode and snap of each ([`window_vertices`]), for every lane of random and special
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
                // Eight at a time with their outcodes, depths and `1 / w`, as the 3D front end
                // keeps each vertex.
                for eight in positions.chunks_exact(8) {
                    let eight: &[Vec4; 8] = eight.try_into().expect("eight positions");
                    let mut want = WindowVertices::default();
                    for (k, &p) in eight.iter().enumerate() {
                        want.outcode[k] = volume.outcode(p);
                        if want.outcode[k] == 0
                            && let Some((xy, z, inv_w)) = viewport.map_snapped(p)
                        {
                            (want.xy[k], want.z[k], want.inv_w[k]) = (xy, z, inv_w);
                            want.snapped |= 1 << k;
                        }
                    }
                    let bits =
                        |w: WindowVertices| (w.z.map(f32::to_bits), w.inv_w.map(f32::to_bits));
                    for level in SimdLevel::available() {
                        let Some(got) = window_vertices(level, eight, &volume, &viewport) else {
                            continue;
                        };
                        let at = format!("{level:?}, {width}x{height}, round {round}");
                        assert_eq!(
                            (got.outcode, got.xy, got.snapped),
                            (want.outcode, want.xy, want.snapped),
                            "{at}"
                        );
                        assert_eq!(bits(got), bits(want), "{at}");
                    }
                }
            }
        }
    }

    /// Buffers of `n` pixels a kernel starts from: depth (an eighth each 0, 1 and 0.5, so that
    /// clamped and in-range planes tie with it), colour, ids and overdraw.
    fn random_buffers(
        rng: &mut SmallRng,
        n: usize,
    ) -> (Vec<f32>, Vec<[u8; 4]>, Vec<i32>, Vec<u32>) {
        let depth = (0..n)
            .map(|_| match rng.random_range(0..8) {
                // Ties with clamped depths (the random planes leave [0, 1]), and a cleared
                // buffer.
                0 => 0.0,
                1 => 1.0,
                2 => 0.5,
                _ => rng.random_range(0.0..1.0),
            })
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

    /// A random colour: a quarter of them a 3D pipeline triangle's vertex colours
    /// ([`random_perspective`]), the rest flat or smooth (four planes, or three within
    /// [0, 255] and a constant alpha); now and then one of four planes with a NaN or infinite
    /// channel (the quantizers map NaN to 0 and clamp infinities).
    fn random_color(rng: &mut SmallRng, round: usize) -> SpanColor {
        if rng.random_range(0..4) == 0 {
            return SpanColor::Perspective(random_perspective(rng, round));
        }
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

    /// A random [`PerspectiveColor`]: colours in [0, 1] or a little outside it (NaN and
    /// infinities now and then), a scale of ones or a random one, a constant alpha or none,
    /// `1 / w` equal (affine weights), random, or summing to zero or less somewhere (thirds),
    /// `1 / area2` of a small triangle or a large one.
    fn random_perspective(rng: &mut SmallRng, round: usize) -> PerspectiveColor {
        let value = |rng: &mut SmallRng| rng.random_range(-0.1..1.1f32);
        let mut colors: [[f32; 4]; 3] =
            std::array::from_fn(|_| std::array::from_fn(|_| value(rng)));
        if round.is_multiple_of(53) {
            colors[round % 3][round % 4] = [f32::NAN, f32::INFINITY, -f32::INFINITY][round % 3];
        }
        let scale = if rng.random() { [1.0; 4] } else { std::array::from_fn(|_| rng.random()) };
        let alpha = rng.random::<bool>().then(|| value(rng));
        let q = rng.random_range(0.01..10.0f32);
        let inv_w = match rng.random_range(0..4) {
            0 => [q; 3],
            1 => [q, -q, rng.random_range(-1.0..1.0)],
            _ => std::array::from_fn(|_| rng.random_range(0.01..10.0)),
        };
        let area2 = [rng.random_range(1..1 << 12), rng.random_range(1..1u64 << 40)][round % 2];
        PerspectiveColor { colors, scale, alpha, inv_w, inv_area2: 1.0 / area2 as f64 }
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
                            color: &color,
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

    /// What a kernel writes into `depth` and `color_out`, for the tests that ask only whether
    /// a job is refused: a flat colour, depth 0.5 tested `Less`, no ids or overdraw.
    fn refusal_target<'a>(depth: &'a mut [f32], color_out: &'a mut [[u8; 4]]) -> KernelTarget<'a> {
        KernelTarget {
            depth_plane: [0.5, 0.0, 0.0],
            color: &SpanColor::Flat([1, 2, 3, 4]),
            depth_test: DepthTest::Less,
            id: 0,
            depth,
            color_out,
            ids: None,
            overdraw: None,
        }
    }

    /// A narrow job whose box the buffers do not hold (a job is public and safe to build)
    /// panics at every level before anything is written, as documented: rows past the end,
    /// strides and offsets that overflow, and what the scalar kernel (which AVX2 hands such
    /// boxes) had done: walked `usize::MAX` uncovered rows without end, and written a pixel
    /// outside a box whose offsets wrap.
    #[test]
    fn narrow_jobs_past_the_buffers_panic_at_every_level() {
        // (edges, step_y, columns, rows, first, stride), in buffers of 64 pixels; zero edges
        // and steps cover every pixel of the box.
        let boxes = [
            // Nothing covered, rows without end.
            ([-1, 0, 0], [0; 3], 1, usize::MAX, 0, 4),
            // Every pixel covered, its second row's offset wrapping to the buffers' start.
            ([0; 3], [256, 0, 0], 1, 2, usize::MAX - 3, 4),
            // One row past the end (16 rows of 4 fit).
            ([0; 3], [0; 3], 1, 17, 0, 4),
            // A stride whose second row overflows, or lies past the end.
            ([0; 3], [0; 3], 2, 3, 0, 1usize << 63),
            ([0; 3], [0; 3], 2, 2, 5, usize::MAX / 2 + 1),
            ([0; 3], [0; 3], 2, 2, 50, 40),
        ];
        for (edges, step_y, columns, rows, first, stride) in boxes {
            for level in SimdLevel::available() {
                let (mut d, mut c) = (vec![1.0f32; 64], vec![[0u8; 4]; 64]);
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    let target = refusal_target(&mut d, &mut c);
                    let (step_x, bias) = ([0; 3], [0; 2]);
                    let job = NarrowJob {
                        edges,
                        step_x,
                        step_y,
                        bias,
                        columns,
                        rows,
                        first,
                        stride,
                        target,
                    };
                    shade_narrow(level, job)
                }));
                assert!(result.is_err(), "{level:?}, {rows} rows from {first}: not refused");
                assert_eq!(c, vec![[0u8; 4]; 64], "{level:?}: written before refusing");
            }
        }
    }

    /// The sample span kernels give the scalar one's buffers bit for bit: 4x and 8x, spans
    /// of 0 to 19 pixels, random sample offsets, every depth test and colour kind, with and
    /// without ids.
    #[test]
    fn sample_kernels_match_scalar_bit_for_bit() {
        let mut rng = SmallRng::seed_from_u64(44);
        for round in 0..10_000 {
            let samples = if round % 2 == 0 { 4 } else { 8 };
            let len = samples * rng.random_range(0..20usize);
            let depth_plane = random_plane(&mut rng, 1.0);
            let color = random_color(&mut rng, round);
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let mut numerator = |bits: u32| rng.random_range(-(1i64 << bits)..(1 << bits));
            let (e1, e2, step1, step2) =
                (numerator(40), numerator(40), numerator(30), numerator(30));
            let offsets: [[i64; 2]; MAX_SAMPLES] =
                std::array::from_fn(|_| [numerator(29), numerator(29)]);
            let with_ids = (round / 3) % 3 != 0;
            let buffers = random_buffers(&mut rng, len);
            let run = |level: SimdLevel| {
                let (mut d, mut c, mut i, _) = buffers.clone();
                let job = SampleSpanJob {
                    span: SpanJob {
                        e1,
                        e2,
                        step1,
                        step2,
                        target: KernelTarget {
                            depth_plane,
                            color: &color,
                            depth_test,
                            id: 7,
                            depth: &mut d,
                            color_out: &mut c,
                            ids: with_ids.then_some(&mut i),
                            overdraw: None,
                        },
                    },
                    samples,
                    offsets,
                };
                if level == SimdLevel::Scalar {
                    shade_samples_scalar(job);
                } else {
                    shade_samples(level, job);
                }
                (d.iter().map(|z| z.to_bits()).collect::<Vec<_>>(), c, i)
            };
            let reference = run(SimdLevel::Scalar);
            for level in SimdLevel::available() {
                assert_eq!(run(level), reference, "{level:?}, round {round}");
            }
        }
    }

    /// The narrow sample kernels against the scalar one on random boxes (1 to 8 columns, 1 to
    /// 5 rows) of random edge functions and sample offsets (any coverage pattern), 4x and 8x,
    /// biases 0 and -1, every depth test and colour kind (and opaque colours whose planes
    /// leave [0, 255] outside the triangle, where partly covered pixels' centres may lie),
    /// with and without ids, boxes that end at the buffers' end.
    #[test]
    fn narrow_sample_kernels_match_scalar_bit_for_bit() {
        let mut rng = SmallRng::seed_from_u64(21);
        for round in 0..20_000 {
            let samples = if round % 2 == 0 { 4 } else { 8 };
            let columns = rng.random_range(1..=NARROW_COLUMNS);
            let rows = rng.random_range(1..=5usize);
            let stride = rng.random_range(columns..columns + 6);
            let pixels = (rows - 1) * stride + columns + rng.random_range(0..3);
            let first = rng.random_range(0..=pixels - (rows - 1) * stride - columns);
            let small = round % 4 != 3;
            let mut value = |bits: u32, small_bits: u32| {
                let b = if small { small_bits } else { bits };
                rng.random_range(-(1i64 << b)..(1 << b))
            };
            let edges = [0; 3].map(|_| value(40, 11));
            let step_x = [0; 3].map(|_| value(32, 10));
            let step_y = [0; 3].map(|_| value(32, 10));
            let offsets: [[i64; 3]; MAX_SAMPLES] =
                std::array::from_fn(|_| [0; 3].map(|_| value(30, 9)));
            let bias = [-(rng.random::<bool>() as i64), -(rng.random::<bool>() as i64)];
            let depth_plane = random_plane(&mut rng, 1.0);
            let color = if round % 5 == 0 {
                let plane = |rng: &mut SmallRng| {
                    let g = |rng: &mut SmallRng| rng.random_range(-1.0..1.0) / 4096.0;
                    [rng.random_range(-300.0..600.0), g(rng), g(rng)]
                };
                SpanColor::SmoothRgb([0; 3].map(|_| plane(&mut rng)), rng.random())
            } else {
                random_color(&mut rng, round)
            };
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let with_ids = (round / 3) % 3 != 0;
            let buffers = random_buffers(&mut rng, pixels * samples);
            let run = |level: SimdLevel| {
                let (mut d, mut c, mut i, _) = buffers.clone();
                let job = NarrowSamplesJob {
                    narrow: NarrowJob {
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
                            color: &color,
                            depth_test,
                            id: 5,
                            depth: &mut d,
                            color_out: &mut c,
                            ids: with_ids.then_some(&mut i),
                            overdraw: None,
                        },
                    },
                    samples,
                    offsets,
                };
                let covered = if level == SimdLevel::Scalar {
                    shade_narrow_samples_scalar(job)
                } else {
                    shade_narrow_samples(level, job)
                };
                (covered, d.iter().map(|z| z.to_bits()).collect::<Vec<_>>(), c, i)
            };
            let reference = run(SimdLevel::Scalar);
            for level in SimdLevel::available() {
                assert_eq!(run(level), reference, "{level:?}, round {round}");
            }
        }
    }

    /// Sample span jobs the kernels do not take (an overdraw buffer, a sample count other
    /// than 4 or 8, buffers holding part of a pixel) panic at every level.
    #[test]
    fn sample_jobs_outside_the_contract_panic() {
        for level in SimdLevel::available() {
            for (samples, len, overdraw) in [(4, 8, true), (2, 8, false), (8, 12, false)] {
                let shade = || {
                    let color = SpanColor::Flat([1, 2, 3, 4]);
                    let (mut d, mut c, mut o) = (vec![1.0; len], vec![[0; 4]; len], vec![0; len]);
                    let job = SampleSpanJob {
                        span: SpanJob {
                            e1: 0,
                            e2: 0,
                            step1: 0,
                            step2: 0,
                            target: KernelTarget {
                                depth_plane: [0.5, 0.0, 0.0],
                                color: &color,
                                depth_test: DepthTest::Less,
                                id: 0,
                                depth: &mut d,
                                color_out: &mut c,
                                ids: None,
                                overdraw: overdraw.then_some(&mut o),
                            },
                        },
                        samples,
                        offsets: [[0; 2]; MAX_SAMPLES],
                    };
                    shade_samples(level, job);
                };
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(shade));
                assert!(outcome.is_err(), "{level:?}: {samples} samples, {len}, {overdraw}");
            }
        }
    }

    /// Narrow sample jobs the kernels do not take (an overdraw buffer, a sample count other
    /// than 4 or 8, a box with no column or row or too wide, a box reaching past the buffers,
    /// a stride so large its offsets overflow) panic at every level, before touching the
    /// buffers.
    #[test]
    fn narrow_sample_jobs_outside_the_contract_panic() {
        let ok = (4, 2, 2, 3, false);
        let cases = [
            (4, 2, 2, 3, true),
            (2, 2, 2, 3, false),
            (4, 0, 2, 3, false),
            (4, 2, 0, 3, false),
            (4, NARROW_COLUMNS + 1, 1, 9, false),
            (4, 3, 2, 4, false),
            (8, 2, 2, 3, false),
            (4, 1, 3, usize::MAX / 2, false),
        ];
        for level in SimdLevel::available() {
            for case @ (samples, columns, rows, stride, overdraw) in [ok].into_iter().chain(cases) {
                // Six pixels of four samples.
                let len = 24;
                let shade = || {
                    let color = SpanColor::Flat([1, 2, 3, 4]);
                    let (mut d, mut c, mut o) = (vec![1.0; len], vec![[0; 4]; len], vec![0; len]);
                    let job = NarrowSamplesJob {
                        narrow: NarrowJob {
                            edges: [0; 3],
                            step_x: [0; 3],
                            step_y: [0; 3],
                            bias: [0; 2],
                            columns,
                            rows,
                            first: 0,
                            stride,
                            target: KernelTarget {
                                depth_plane: [0.5, 0.0, 0.0],
                                color: &color,
                                depth_test: DepthTest::Less,
                                id: 0,
                                depth: &mut d,
                                color_out: &mut c,
                                ids: None,
                                overdraw: overdraw.then_some(&mut o),
                            },
                        },
                        samples,
                        offsets: [[0; 3]; MAX_SAMPLES],
                    };
                    shade_narrow_samples(level, job)
                };
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(shade));
                if case == ok {
                    // The box of 2 x 2 pixels, every sample covered.
                    assert_eq!(outcome.ok(), Some(16), "{level:?}");
                } else {
                    assert!(outcome.is_err(), "{level:?}: {case:?}");
                }
            }
        }
    }

    /// A random window vertex for the group setup test: ordinary, at or past the ends of the
    /// snapping range, non-finite in one coordinate, or on a coarse grid (axis-aligned edges,
    /// ties, repeated vertices, collinear triangles).
    fn group_vertex(rng: &mut SmallRng) -> Vertex {
        let coordinate = |rng: &mut SmallRng| match rng.random_range(0..40) {
            0 => crate::fixed::MIN_COORD,
            1 => crate::fixed::SNAP_LIMIT,
            2 => crate::fixed::MAX_COORD,
            3 => -32768.01,
            4 => rng.random_range(-32768.0..32767.0),
            5..=14 => rng.random_range(0..4) as f32 * 2.0 + 0.5,
            _ => rng.random_range(-30.0..330.0),
        };
        let mut v = Vertex {
            x: coordinate(rng),
            y: coordinate(rng),
            z: rng.random_range(-0.5..1.5),
            inv_w: rng.random_range(0.1..4.0),
            color: [rng.random(), rng.random(), rng.random(), 200],
        };
        if rng.random_range(0..4) == 0 {
            v.color[3] = rng.random();
        }
        if rng.random_range(0..60) == 0 {
            let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][rng.random_range(0..3)];
            match rng.random_range(0..4) {
                0 => v.x = bad,
                1 => v.y = bad,
                2 => v.z = bad,
                _ => v.inv_w = bad,
            }
        }
        v
    }

    /// The eight-triangle window setup gives, lane by lane, what the per-triangle front end
    /// gives (`TriangleSetup::new`, `1.0 / area2 as f64`): the same rejection, or the same
    /// setup and `1 / area2` to the bit, for every cull mode, on triangles of every kind (see
    /// `group_vertex`).
    #[test]
    fn window_groups_match_the_front_end() {
        let mut rng = SmallRng::seed_from_u64(2024);
        let mut kinds = std::collections::HashMap::new();
        for round in 0..20_000 {
            let cull = [CullMode::None, CullMode::Clockwise, CullMode::CounterClockwise][round % 3];
            let tris: [[Vertex; 3]; 8] =
                std::array::from_fn(|_| std::array::from_fn(|_| group_vertex(&mut rng)));
            for level in SimdLevel::available() {
                let mut group = WindowGroup::default();
                if !window_group(level, &tris, cull, &mut group) {
                    continue;
                }
                for (k, v) in tris.iter().enumerate() {
                    let want = TriangleSetup::new(v, cull).map(|setup| {
                        let inv_area2 = 1.0 / setup.area2 as f64;
                        format!("{setup:?} {:x}", inv_area2.to_bits())
                    });
                    let got = group
                        .lane(k)
                        .map(|(setup, inv_area2)| format!("{setup:?} {:x}", inv_area2.to_bits()));
                    assert_eq!(got, want, "{level:?}, round {round}, lane {k}: {v:?}");
                    *kinds
                        .entry(format!("{want:?}").chars().take(12).collect::<String>())
                        .or_insert(0) += 1;
                }
            }
        }
        // Every outcome occurred (when a kernel ran).
        if SimdLevel::Avx512.is_available() {
            for why in
                ["Err(NonFinit", "Err(OutOfRan", "Err(Degenera", "Err(Culled)", "Ok(\"Triangle"]
            {
                assert!(kinds.get(why).is_some_and(|&n| n > 20), "{why}: {kinds:?}");
            }
        }
    }

    /// Row masks are the scalar ones at every level: random triangles' edges (up to the
    /// fixed-point range's edge values, near 2^49), every width from 1 to 8 and runs of 0 to
    /// 16 rows, and edges whose values sit at 0 and -1 (the fill rule's tie) along a row.
    #[test]
    fn row_masks_agree_at_every_level() {
        let mut rng = SmallRng::seed_from_u64(40);
        for round in 0..20_000 {
            let scale = [1i64 << 12, 1 << 24, 1 << 40, 1 << 49][round % 4];
            let step = |rng: &mut SmallRng| rng.random_range(-scale / 64..=scale / 64);
            let mut e: [i64; 3] = std::array::from_fn(|_| rng.random_range(-scale..=scale));
            let step_x: [i64; 3] = std::array::from_fn(|_| step(&mut rng));
            let step_y: [i64; 3] = std::array::from_fn(|_| step(&mut rng));
            if round % 5 == 0 {
                // An edge through a pixel centre (value 0) or just off it (-1).
                let k = rng.random_range(0..3);
                e[k] = -rng.random_range(0..=1) - step_x[k] * rng.random_range(0..8);
            }
            let columns = 1 + round % 8;
            let len = rng.random_range(0..=16);
            let mut want = [0u8; 16];
            row_masks_scalar(e, step_x, step_y, columns, &mut want[..len]);
            for (r, &m) in want[..len].iter().enumerate() {
                let row: [i64; 3] = std::array::from_fn(|k| e[k] + r as i64 * step_y[k]);
                let expected = crate::raster::edge::row_coverage_within(row, step_x, columns);
                assert_eq!(u32::from(m), expected, "round {round}, row {r}");
            }
            for level in SimdLevel::available() {
                let mut got = [0xAAu8; 16];
                row_masks(level, e, step_x, step_y, columns, &mut got[..len]);
                assert_eq!(got[..len], want[..len], "{level:?}, round {round}");
                assert!(got[len..].iter().all(|&b| b == 0xAA), "{level:?} wrote past its rows");
            }
        }
    }

    /// Every level finds the smallest and largest index the scalar fold finds: lengths
    /// around the vector blocks (tails of every size), the extremes (0 and `u32::MAX`) placed
    /// anywhere, and the empty slice.
    #[test]
    fn index_ranges_agree_at_every_level() {
        let mut rng = SmallRng::seed_from_u64(21);
        for len in (0..100).chain([1000, 4099]) {
            for _ in 0..20 {
                let mut v: Vec<u32> =
                    (0..len).map(|_| rng.random_range(1000..2_000_000_000)).collect();
                if len > 0 && rng.random_bool(0.5) {
                    let k = rng.random_range(0..len);
                    v[k] = if rng.random_bool(0.5) { 0 } else { u32::MAX };
                }
                let want = (
                    v.iter().copied().min().unwrap_or(u32::MAX),
                    v.iter().copied().max().unwrap_or(0),
                );
                assert_eq!(index_range_scalar(&v), want);
                for level in SimdLevel::available() {
                    assert_eq!(index_range(level, &v), want, "{level:?}, {len} values");
                }
            }
        }
    }

    /// A span job whose buffers differ in length panics at every level, longer or shorter,
    /// before writing anything (the scalar kernel had drawn a longer colour buffer's span,
    /// which the vector kernels refuse).
    #[test]
    fn span_jobs_of_buffers_of_other_lengths_panic() {
        for level in SimdLevel::available() {
            for (depth_len, color_len, ids_len) in [(9, 10, 9), (9, 8, 9), (9, 9, 10), (9, 9, 3)] {
                let (mut depth, mut color) = (vec![1.0f32; depth_len], vec![[0u8; 4]; color_len]);
                let mut ids = vec![-1; ids_len];
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    let target = KernelTarget {
                        id: 7,
                        ids: Some(&mut ids),
                        ..refusal_target(&mut depth, &mut color)
                    };
                    shade_span(level, SpanJob { e1: 0, e2: 0, step1: 0, step2: 0, target });
                }));
                let lengths = (depth_len, color_len, ids_len);
                assert!(outcome.is_err(), "{level:?}: {lengths:?}");
                assert!(depth.iter().all(|&d| d == 1.0), "{level:?}: {lengths:?} wrote depth");
            }
        }
    }

    /// Colour planes are fused at every level, as `SpanColor::at` defines them: for planes
    /// and numerators where fused and separate multiply-adds quantize differently (values
    /// within rounding of a half), every span and narrow kernel, at 1x and 4x, writes the
    /// fused colour, for four planes (clamped) and three (rounded only, except at 4x).
    /// Random planes seldom meet such a value, so the tests above would not see a kernel
    /// that kept separate operations.
    #[test]
    fn colour_planes_are_fused_at_every_level() {
        fn target<'a>(
            color: &'a SpanColor,
            depth: &'a mut [f32],
            color_out: &'a mut [[u8; 4]],
        ) -> KernelTarget<'a> {
            let (depth_plane, depth_test) = ([0.5, 0.0, 0.0], DepthTest::Always);
            KernelTarget {
                depth_plane,
                color,
                depth_test,
                id: 0,
                depth,
                color_out,
                ids: None,
                overdraw: None,
            }
        }
        // Every pixel at numerators `(f1, f2)`: a span, and a 5 x 3 box wholly covered.
        fn span(e1: i64, e2: i64, target: KernelTarget<'_>) -> SpanJob<'_> {
            SpanJob { e1, e2, step1: 0, step2: 0, target }
        }
        fn narrow(f1: i64, f2: i64, target: KernelTarget<'_>) -> NarrowJob<'_> {
            let (step_x, step_y, bias) = ([0; 3], [0; 3], [0; 2]);
            let (columns, rows, first, stride) = (5, 3, 1, 6);
            let edges = [1, f1, f2];
            NarrowJob { edges, step_x, step_y, bias, columns, rows, first, stride, target }
        }
        let mut rng = SmallRng::seed_from_u64(31);
        let (mut found, mut tries) = (0, 0);
        while found < 300 {
            tries += 1;
            assert!(tries < 100_000, "only {found} planes found where fusing matters");
            let (f1, f2) = (rng.random_range(0..1i64 << 40), rng.random_range(0..1i64 << 40));
            let (x1, x2) = (f1 as f64, f2 as f64);
            let g = |rng: &mut SmallRng| rng.random_range(-1e-10..1e-10);
            let (g1, g2) = (g(&mut rng), g(&mut rng));
            // A value a few rounding errors from a half.
            let a0 = rng.random_range(1..254) as f64 + 0.5 - (x1 * g1 + x2 * g2);
            let fused = quantize_channel(x2.mul_add(g2, x1.mul_add(g1, a0)));
            if fused == quantize_channel(a0 + x1 * g1 + x2 * g2) {
                continue;
            }
            found += 1;
            let plane = [a0, g1, g2];
            let (four, three) =
                (SpanColor::Smooth([plane; 4]), SpanColor::SmoothRgb([plane; 3], 7));
            for (color, want) in [(four, [fused; 4]), (three, [fused, fused, fused, 7])] {
                assert_eq!(color.at(x1, x2), want);
                for level in SimdLevel::available() {
                    let (mut depth, mut out) = (vec![1.0f32; 24], vec![[0u8; 4]; 24]);
                    shade_span(level, span(f1, f2, target(&color, &mut depth, &mut out)));
                    assert!(out.iter().all(|&c| c == want), "{level:?} span: {out:?}, {want:?}");
                    let (mut depth, mut out) = (vec![1.0f32; 24], vec![[0u8; 4]; 24]);
                    let job = narrow(f1, f2, target(&color, &mut depth, &mut out));
                    assert_eq!(shade_narrow(level, job), 15);
                    let drawn = out.iter().filter(|&&c| c == want).count();
                    assert_eq!(drawn, 15, "{level:?} narrow: {out:?}, {want:?}");
                    // At 4x, samples at the pixel centres: a span of six pixels, and the box.
                    let (mut depth, mut out) = (vec![1.0f32; 24], vec![[0u8; 4]; 24]);
                    let job = span(f1, f2, target(&color, &mut depth, &mut out));
                    let offsets = [[0; 2]; MAX_SAMPLES];
                    shade_samples(level, SampleSpanJob { span: job, samples: 4, offsets });
                    assert!(out.iter().all(|&c| c == want), "{level:?} 4x span: {out:?}");
                    let (mut depth, mut out) = (vec![1.0f32; 96], vec![[0u8; 4]; 96]);
                    let job = narrow(f1, f2, target(&color, &mut depth, &mut out));
                    let offsets = [[0; 3]; MAX_SAMPLES];
                    let job = NarrowSamplesJob { narrow: job, samples: 4, offsets };
                    assert_eq!(shade_narrow_samples(level, job), 60);
                    let drawn = out.iter().filter(|&&c| c == want).count();
                    assert_eq!(drawn, 60, "{level:?} 4x narrow: {out:?}, {want:?}");
                }
            }
        }
    }

    /// The kernels' perspective weights and colour channels, lane by lane, are the fragment
    /// stage's: `perspective_weights` of the scaled numerators, the colours weighted left to
    /// right and scaled, bit for bit (NaN as NaN), on random colours (see
    /// [`random_perspective`]) at numerators up to 2^42, near zero, and at the vertices.
    #[test]
    fn perspective_lanes_match_the_fragment_stage() {
        let same = |a: f32, b: f32| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        let mut rng = SmallRng::seed_from_u64(61);
        for round in 0..20_000 {
            let p = random_perspective(&mut rng, round);
            let area2 = (1.0 / p.inv_area2).round();
            let numerator = |rng: &mut SmallRng| match rng.random_range(0..4) {
                0 => rng.random_range(-(1i64 << 42)..1 << 42) as f64,
                1 => rng.random_range(-300..300) as f64,
                2 => [0.0, area2][rng.random_range(0..2)],
                _ => rng.random_range(-area2..2.0 * area2).round(),
            };
            let f1: [f64; 8] = std::array::from_fn(|_| numerator(&mut rng));
            let f2: [f64; 8] = std::array::from_fn(|_| numerator(&mut rng));
            let q = p.inv_w.map(f64::from);
            let want = |l: usize| {
                let w = crate::pipeline::perspective_weights(
                    f1[l] * p.inv_area2,
                    f2[l] * p.inv_area2,
                    q,
                );
                let [c0, c1, c2] = p.colors.map(Vec4::from_array);
                (w, (c0 * w[0] + c1 * w[1] + c2 * w[2]) * Vec4::from_array(p.scale))
            };
            let check = |l: usize, w: [f32; 3], c: [f32; 4], level: &str| {
                let (ww, wc) = want(l);
                let ok = (0..3).all(|k| same(w[k], ww[k])) && (0..4).all(|k| same(c[k], wc[k]));
                assert!(
                    ok,
                    "{level} lane {l}: {w:?} {c:?}, want {ww:?} {wc:?} ({p:?} at {}, {})",
                    f1[l], f2[l]
                );
            };
            #[cfg(target_arch = "x86_64")]
            {
                if SimdLevel::Avx512.is_available() {
                    // SAFETY: AVX-512 support was just checked.
                    let (w, c) = unsafe { avx512::perspective_probe(&p, f1, f2) };
                    (0..8).for_each(|l| check(l, w.map(|w| w[l]), c.map(|c| c[l]), "AVX-512"));
                }
                if SimdLevel::Avx2.is_available() {
                    for half in 0..2 {
                        let part = |f: [f64; 8]| std::array::from_fn(|l| f[4 * half + l]);
                        // SAFETY: AVX2 support was just checked.
                        let (w, c) = unsafe { avx2::perspective_probe(&p, part(f1), part(f2)) };
                        for l in 0..4 {
                            check(4 * half + l, w.map(|w| w[l]), c.map(|c| c[l]), "AVX2");
                        }
                    }
                }
            }
            // Unused where there is no x86_64 kernel to check.
            let _ = (check, round);
        }
    }

    /// The kernels' sRGB and alpha encoders are `linear_to_srgb8` and `unorm8` for every
    /// kind of value: every bucket's first value and its neighbours (where the table's
    /// thresholds lie), values around 2^-13 and 1, zeros, subnormals, infinities, NaN, and
    /// random bit patterns.
    #[test]
    fn encoders_match_scalar() {
        #[cfg(target_arch = "x86_64")]
        if SimdLevel::Avx2.is_available() {
            let mut values: Vec<f32> = vec![0.0, -0.0, 1e-40, -1e-40, 1.0, f32::NAN, -f32::NAN];
            values.extend([f32::INFINITY, f32::NEG_INFINITY, f32::MAX, f32::MIN_POSITIVE]);
            for bucket in 1..=127u32 << 8 {
                let first = bucket << 15;
                for b in [first.wrapping_sub(1), first, first + 1, first + (1 << 14)] {
                    values.push(f32::from_bits(b));
                }
            }
            // Each table bucket's threshold and the value below it.
            for (k, entry) in crate::color::srgb8_table().iter().enumerate() {
                let first =
                    ((k + crate::color::FIRST_BUCKET) as u32) << crate::color::MANTISSA_SHIFT;
                let t = (entry & 0xffff).min(crate::color::LOW_MASK);
                values.extend([first | t, first | t.saturating_sub(1)].map(f32::from_bits));
            }
            let mut rng = SmallRng::seed_from_u64(62);
            values.extend((0..200_000).map(|_| f32::from_bits(rng.random())));
            values.extend((0..200_000).map(|_| rng.random_range(-0.1..1.1f32)));
            for chunk in values.chunks(16) {
                let v: [f32; 16] = std::array::from_fn(|l| chunk.get(l).copied().unwrap_or(0.5));
                let want = |l: usize| {
                    let (s, a) = (crate::color::linear_to_srgb8(v[l]), crate::color::unorm8(v[l]));
                    (u32::from(s), u32::from(a))
                };
                for half in 0..2 {
                    let part = std::array::from_fn(|l| v[8 * half + l]);
                    // SAFETY: AVX2 support was just checked.
                    let (srgb, alpha) = unsafe { avx2::encode_probe(part) };
                    for l in 0..8 {
                        let k = 8 * half + l;
                        assert_eq!((srgb[l], alpha[l]), want(k), "AVX2: {}", v[k]);
                    }
                }
            }
        }
    }

    /// Eight small triangles' coverage at every level is the scalar one's (`edges_at` and
    /// the row masks of each): boxes of 1 to 8 pixels a side before clipping, both
    /// windings, slivers, vertices on pixel centres and edges through them (fill-rule ties),
    /// near the ends of the fixed-point range, first pixels anywhere in the box, spans of
    /// every size (larger and smaller than the boxes).
    #[test]
    fn small_eights_match_scalar() {
        let mut rng = SmallRng::seed_from_u64(64);
        let mut checked = 0;
        for round in 0..20_000 {
            let lanes: [SmallLane; 8] = std::array::from_fn(|_| {
                loop {
                    let coordinate = |rng: &mut SmallRng| small_origin(rng, round, 20_000);
                    let origin = [coordinate(&mut rng), coordinate(&mut rng)];
                    // Snapped positions on a coarse grid some rounds, for exact ties; boxes
                    // up to 4 or 8 pixels a side.
                    let step = if round % 3 == 0 { 128 } else { 1 };
                    let reach = if round % 2 == 0 { 5 * 256 } else { 9 * 256 };
                    let mut v = || {
                        let d = |rng: &mut SmallRng| rng.random_range(0..reach / step) * step;
                        [origin[0] + d(&mut rng), origin[1] + d(&mut rng)]
                    };
                    let xy = [v(), v(), v()];
                    let clockwise = rng.random();
                    let setup = TriangleSetup::from_kept(xy, clockwise);
                    let b = setup.bounds;
                    let small = SMALL_BOX;
                    if b.x0 > b.x1 || b.y0 > b.y1 || b.x1 - b.x0 >= small || b.y1 - b.y0 >= small {
                        continue;
                    }
                    let first = [rng.random_range(b.x0..=b.x1), rng.random_range(b.y0..=b.y1)];
                    break SmallLane { xy, clockwise, first };
                }
            });
            let span = [rng.random_range(1..=8), rng.random_range(1..=8)];
            let mut want = SmallEight::default();
            small_eight_scalar(&lanes, span, &mut want);
            for level in SimdLevel::available() {
                let mut got = SmallEight::default();
                small_eight(level, &lanes, span, &mut got);
                assert_eq!(got, want, "{level:?}: {lanes:?}, {span:?}");
            }
            checked += want.inside.iter().filter(|&&m| m != 0).count();
        }
        assert!(checked > 30_000, "{checked} lanes with pixels inside");
    }

    /// A snapped coordinate where the small-triangle tests put a box: every fourth round
    /// near either end of the snapped range (within 2^23, with a box's 9 * 256 units
    /// beyond), else a whole pixel within `spread` pixels of 0.
    fn small_origin(rng: &mut SmallRng, round: usize, spread: i32) -> i32 {
        if round.is_multiple_of(4) {
            let sign = if rng.random() { 1 } else { -1 };
            sign * ((1 << 23) - rng.random_range(2560..4096))
        } else {
            rng.random_range(-spread..spread) * 256
        }
    }

    /// Small runs set up from their corners ([`small_run_geometry`], from the rows
    /// [`corner_tests_indexed`] leaves) at every level as lane by lane
    /// ([`small_run_geometry_scalar`]: setup's functions and [`small_eight_scalar`]): groups
    /// of eight from a window of corners (indices offset by a base), random masks of
    /// lanes (the others with `OUTSIDE` corners, zero areas or large boxes, which must change
    /// nothing), boxes of up to 8 or 10 pixels a side (refused past 8 by both), both windings,
    /// vertices on a coarse grid some rounds (fill-rule ties), near the ends of the fixed-point
    /// range, clip rectangles cutting the boxes or missing them: the same verdict, span,
    /// coverage of the lanes of the mask and boxes, `1 / area2` to the bit, and no pixels
    /// elsewhere.
    #[test]
    fn small_runs_set_up_as_scalar() {
        let mut rng = SmallRng::seed_from_u64(68);
        let (mut runs, mut refused) = (0, 0);
        for round in 0..20_000 {
            let base = rng.random_range(0..1000u32);
            let mut window = Vec::new();
            let mut tris = [[0u32; 3]; 8];
            let mut mask = 0u8;
            let origin = |rng: &mut SmallRng| small_origin(rng, round, 200);
            let start = [origin(&mut rng), origin(&mut rng)];
            for (l, tri) in tris.iter_mut().enumerate() {
                let step = if round % 3 == 0 { 128 } else { 1 };
                let reach = match rng.random_range(0..32) {
                    0 => 11 * 256,
                    1..16 => 9 * 256,
                    _ => 5 * 256,
                };
                let o = [
                    start[0] + rng.random_range(-8..8) * 256,
                    start[1] + rng.random_range(-8..8) * 256,
                ];
                let mut corner = || {
                    let d = |rng: &mut SmallRng| rng.random_range(0..reach / step) * step;
                    [o[0] + d(&mut rng), o[1] + d(&mut rng)]
                };
                let mut xy = [corner(), corner(), corner()];
                let kind = rng.random_range(0..10);
                if kind == 0 {
                    xy[1] = OUTSIDE;
                }
                for (v, c) in xy.iter().enumerate() {
                    tri[v] = base + window.len() as u32;
                    window.push(*c);
                }
                let area = || TriangleSetup::signed_area2(setup::widen(xy), CullMode::None);
                if kind != 0 && area().is_ok() && rng.random_range(0..6) != 0 {
                    mask |= 1 << l;
                }
            }
            // Clip rectangles around the boxes, every eighth round cutting some and missing
            // others.
            let c = [start[0] >> 8, start[1] >> 8];
            let cut = round % 8 == 0;
            let mut end = |near: std::ops::Range<i32>, far: i32| {
                if cut { rng.random_range(near) } else { far }
            };
            let clip = PixelRect {
                x0: c[0] + end(-12..4, -30),
                y0: c[1] + end(-12..4, -30),
                x1: c[0] + end(-4..20, 30),
                y1: c[1] + end(-4..20, 30),
            };
            let mut want = (SmallEight::default(), SmallShading::default());
            let mut group = CornerGroup::default();
            for (k, t) in tris.iter().enumerate() {
                group.set(k, t.map(|i| window[(i - base) as usize]));
            }
            let verdict = small_run_geometry_scalar(&group, mask, &clip, &mut want.0, &mut want.1);
            for level in SimdLevel::available() {
                // The rows as the corner tests leave them at this level.
                let mut rows = CornerGroup::default();
                let (tested, x1) = ((&tris, &window[..], base), SampleCount::X1);
                let _ = corner_tests_indexed(level, tested, CullMode::None, &clip, x1, &mut rows);
                let mut got = (SmallEight::default(), SmallShading::default());
                let v = small_run_geometry(level, &rows, mask, &clip, &mut got.0, &mut got.1);
                let what = format!("{level:?}: round {round}, mask {mask:#b}, {clip:?}");
                assert_eq!(v, verdict, "{what}");
                if verdict.is_none() {
                    continue;
                }
                for l in 0..8 {
                    let (g, w) = (&got, &want);
                    assert_eq!(g.1.cells[l], w.1.cells[l], "{what}, lane {l}");
                    if mask & (1 << l) == 0 {
                        assert_eq!(g.1.cells[l], 0, "{what}, lane {l}");
                        continue;
                    }
                    assert_eq!(g.0.inside[l], w.0.inside[l], "{what}, lane {l}");
                    for k in 0..3 {
                        assert_eq!(g.0.edges[k][l], w.0.edges[k][l], "{what}, lane {l}");
                        assert_eq!(g.0.step_x[k][l], w.0.step_x[k][l], "{what}, lane {l}");
                        assert_eq!(g.0.step_y[k][l], w.0.step_y[k][l], "{what}, lane {l}");
                    }
                    for b in 0..2 {
                        assert_eq!(g.0.bias[b][l], w.0.bias[b][l], "{what}, lane {l}");
                    }
                    assert_eq!([g.1.x0[l], g.1.y0[l]], [w.1.x0[l], w.1.y0[l]], "{what}, lane {l}");
                    let bits = |s: &SmallShading| s.inv_area2[l].to_bits();
                    assert_eq!(bits(&g.1), bits(&w.1), "{what}, lane {l}");
                }
            }
            match verdict {
                Some(_) => runs += 1,
                None => refused += 1,
            }
        }
        assert!(runs > 3000 && refused > 3000, "{runs} runs set up, {refused} refused");
    }

    /// The 4x small kernel and its set-up: runs of random triangles crowding a few pixels (so
    /// that a group's triangles share pixels and samples), their boxes up to 8 pixels a side
    /// with the samples' reach, some cut by the clip rectangle (a band's rows, with the rows
    /// above it in the buffers), some refused as too large. Each sample's coverage is the
    /// setup's own test at that sample, and every covered sample of the triangle within the
    /// clip lies in its box; the kernel at every level gives the scalar loop's buffers and
    /// count bit for bit, on random depths, with and without ids, every depth test.
    #[test]
    fn small_sample_runs_cover_and_shade_as_scalar() {
        let mut rng = SmallRng::seed_from_u64(71);
        let (mut covered, mut refused) = (0, 0);
        let (width, height) = (18, 16);
        let clip = PixelRect { x0: 0, y0: 4, x1: width - 1, y1: height - 1 };
        for round in 0..6_000 {
            let spot = [rng.random_range(0..width), rng.random_range(1..height)];
            let reach = if round % 4 == 0 { 7 * 256 } else { 3 * 256 };
            let mut group = CornerGroup::default();
            let mut mask = 0u8;
            for l in 0..8 {
                let mut corner = || {
                    let d =
                        |rng: &mut SmallRng, at: i32| at * 256 + rng.random_range(-reach..reach);
                    [d(&mut rng, spot[0]), d(&mut rng, spot[1])]
                };
                let xy = [corner(), corner(), corner()];
                group.set(l, xy);
                let area = TriangleSetup::signed_area2(setup::widen(xy), CullMode::None);
                if area.is_ok() && rng.random_range(0..8) != 0 {
                    mask |= 1 << l;
                }
            }
            let mut parts =
                (SmallEight::default(), SmallSamples::default(), SmallShading::default());
            let (e, s, sh) = (&mut parts.0, &mut parts.1, &mut parts.2);
            let verdict = small_run_samples_geometry_scalar(&group, mask, &clip, (e, s, sh));
            // Each level's set-up is the scalar one (the lanes it sets).
            for level in SimdLevel::available() {
                let mut got =
                    (SmallEight::default(), SmallSamples::default(), SmallShading::default());
                let (e, s, sh) = (&mut got.0, &mut got.1, &mut got.2);
                let v = small_run_samples_geometry(level, &group, mask, &clip, (e, s, sh));
                let what = format!("{level:?}, round {round}");
                assert_eq!(v, verdict, "{what}");
                if v.is_none() {
                    continue;
                }
                let (g, w) = (&got, &parts);
                for l in (0..8).filter(|l| mask & (1 << l) != 0) {
                    assert_eq!(g.0.inside[l], w.0.inside[l], "{what}, lane {l}");
                    for k in 0..3 {
                        assert_eq!(g.0.edges[k][l], w.0.edges[k][l], "{what}, lane {l}");
                        assert_eq!(g.0.step_x[k][l], w.0.step_x[k][l], "{what}, lane {l}");
                        assert_eq!(g.0.step_y[k][l], w.0.step_y[k][l], "{what}, lane {l}");
                    }
                    assert_eq!([g.0.bias[0][l], g.0.bias[1][l]], [w.0.bias[0][l], w.0.bias[1][l]]);
                    assert!((0..4).all(|s| g.1.inside[s][l] == w.1.inside[s][l]), "{what}");
                    assert_eq!([g.2.x0[l], g.2.y0[l]], [w.2.x0[l], w.2.y0[l]], "{what}");
                    assert_eq!(g.2.inv_area2[l].to_bits(), w.2.inv_area2[l].to_bits(), "{what}");
                }
                assert_eq!(g.2.cells, w.2.cells, "{what}");
            }
            if verdict.is_none() {
                refused += 1;
                continue;
            }
            let (eight, samples, shading) = &mut parts;
            for l in (0..8).filter(|l| mask & (1 << l) != 0) {
                let setup = TriangleSetup::from_snapped(setup::widen(group.get(l)), CullMode::None)
                    .unwrap();
                let (x0, y0) = (shading.x0[l], shading.y0[l]);
                let mut in_box = 0;
                for s in 0..4 {
                    let [ox, oy] = SMALL_SAMPLES.offset(s);
                    for bit in (0..64).filter(|b| shading.cells[l] >> b & 1 != 0) {
                        let (px, py) = (x0 + bit % 8, y0 + bit / 8);
                        let (x, y) = (fixed::pixel_centre(px) + ox, fixed::pixel_centre(py) + oy);
                        let inside = samples.inside[s][l] >> bit & 1 != 0;
                        assert_eq!(inside, setup.covers_point(x, y), "round {round}, lane {l}");
                        in_box += u32::from(inside);
                    }
                    let all = (clip.y0..=clip.y1)
                        .flat_map(|py| (clip.x0..=clip.x1).map(move |px| (px, py)))
                        .filter(|&(px, py)| {
                            let (x, y) = (fixed::pixel_centre(px), fixed::pixel_centre(py));
                            setup.covers_point(x + ox, y + oy)
                        })
                        .count();
                    in_box -= all as u32;
                }
                assert_eq!(in_box, 0, "round {round}, lane {l}: a covered sample outside the box");
                let any = samples.inside.iter().fold(0, |m, s| m | s[l]);
                assert_eq!(eight.inside[l] & shading.cells[l], any & shading.cells[l]);
                let depth = PlaneEquation::from_coefficients([
                    rng.random_range(-0.2..1.2),
                    rng.random_range(-1e-5..1e-5),
                    rng.random_range(-1e-5..1e-5),
                ]);
                let color = random_perspective(&mut rng, round + l);
                shading.set_shading(l, &depth, &color, 100 + l as i32);
            }
            let start = rng.random_range(0..8);
            let run = start..rng.random_range(start + 1..=8);
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let mut want =
                crate::target::Target::multisampled(width as u32, height as u32, SMALL_SAMPLES)
                    .unwrap();
            if round % 2 == 0 {
                want = want.with_ids();
            }
            for d in &mut want.depth {
                *d = rng.random_range(0.0..1.0);
            }
            let before = want.clone();
            let parts = (&*eight, &*samples, &*shading);
            let n = {
                let mut bands = want.bands_from(&[0, 4]);
                shade_small_samples_scalar(parts, run.clone(), &mut bands[1], depth_test)
            };
            for level in SimdLevel::available() {
                let mut got = before.clone();
                let mut bands = got.bands_from(&[0, 4]);
                let m = shade_small_samples(level, parts, run.clone(), &mut bands[1], depth_test);
                let what = format!("{level:?}, round {round}");
                assert_eq!(m, n, "{what}");
                let bits = |t: &crate::target::Target| {
                    t.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>()
                };
                assert!(bits(&want) == bits(&got) && want.color == got.color, "{what}");
                assert!(want.ids == got.ids, "{what}");
            }
            assert!(want.depth != before.depth || n == 0 || depth_test != DepthTest::Always);
            covered += n;
        }
        assert!(covered > 50_000 && refused > 500, "{covered} covered, {refused} refused");
    }

    /// Eight small triangles shaded together at AVX2 and AVX-512 are shaded as one pixel at
    /// a time (`shade_small_eight_scalar`: `KernelTarget::pixel` of each covered pixel, in
    /// order): runs of random lanes whose boxes (up to 4 or 8 pixels a side) crowd a few
    /// pixels (so the triangles of a group share pixels, which ends AVX-512's groups early and
    /// has AVX2's later lane tested against the earlier one's write), random colours
    /// ([`random_perspective`]: affine and divided weights, thirds, constant and weighted
    /// alpha, NaN and infinities), depth planes reaching outside [0, 1], every depth test,
    /// stored depths in [0, 1], with and without id and overdraw buffers, in a band that does
    /// not start at row 0, boxes clipped to it.
    #[test]
    fn small_eights_shade_as_scalar() {
        let mut rng = SmallRng::seed_from_u64(66);
        let (mut covered, mut shared) = (0, 0);
        for round in 0..20_000 {
            let (width, height) = (16, 14);
            let band_rows = [0, 4];
            let small = if round % 2 == 0 { 4 } else { SMALL_BOX };
            let clip = PixelRect { x0: 0, y0: 4, x1: width - 1, y1: height - 1 };
            let spot = [rng.random_range(0..width - 2), rng.random_range(2..height - 2)];
            let mut lanes = [SmallLane::default(); 8];
            let mut boxes = [PixelRect::EMPTY; 8];
            for l in 0..8 {
                (lanes[l], boxes[l]) = loop {
                    let mut v = || {
                        let d = |rng: &mut SmallRng, at: i32| {
                            at * 256 + rng.random_range(-small / 2 * 256..(small / 2 + 1) * 256)
                        };
                        [d(&mut rng, spot[0]), d(&mut rng, spot[1])]
                    };
                    let xy = [v(), v(), v()];
                    let clockwise = rng.random();
                    let setup = TriangleSetup::from_kept(xy, clockwise);
                    let b = setup.bounds;
                    if b.x0 > b.x1 || b.y0 > b.y1 || b.x1 - b.x0 >= small || b.y1 - b.y0 >= small {
                        continue;
                    }
                    let Some(r) = b.intersect(&clip) else { continue };
                    break (SmallLane { xy, clockwise, first: [r.x0, r.y0] }, r);
                };
            }
            let mut eight = SmallEight::default();
            let span = boxes.iter().fold([1, 1], |s: [usize; 2], r| {
                [s[0].max((r.x1 - r.x0 + 1) as usize), s[1].max((r.y1 - r.y0 + 1) as usize)]
            });
            small_eight_scalar(&lanes, span, &mut eight);
            let mut shading = SmallShading::default();
            for (l, rect) in boxes.iter().enumerate() {
                let depth = PlaneEquation::from_coefficients([
                    rng.random_range(-0.2..1.2),
                    rng.random_range(-1e-5..1e-5),
                    rng.random_range(-1e-5..1e-5),
                ]);
                let color = random_perspective(&mut rng, round + l);
                shading.set(l, rect, &depth, &color, 100 + l as i32);
            }
            let start = rng.random_range(0..8);
            let run = start..rng.random_range(start + 1..=8);
            let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][round % 3];
            let (w, h) = (width as u32, height as u32);
            let mut want = crate::target::Target::random_depths(w, h, round % 2 == 0, &mut rng);
            let before = want.clone();
            let n = {
                let mut bands = want.bands_from(&band_rows);
                shade_small_eight_scalar(&eight, &shading, run.clone(), &mut bands[1], depth_test)
            };
            for level in SimdLevel::available() {
                let mut got = before.clone();
                let mut bands = got.bands_from(&band_rows);
                let m = shade_small_eight(
                    level,
                    &eight,
                    &shading,
                    run.clone(),
                    &mut bands[1],
                    depth_test,
                );
                let what = format!("{level:?}, round {round}");
                assert_eq!(m, n, "{what}");
                let bits = |t: &crate::target::Target| {
                    t.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>()
                };
                assert!(bits(&want) == bits(&got) && want.color == got.color, "{what}");
                assert!(want.ids == got.ids && want.overdraw == got.overdraw, "{what}");
            }
            covered += n;
            // Pixels covered by more than one lane of the run.
            let mut seen = std::collections::HashSet::new();
            for l in run {
                let cells = eight.inside[l] & shading.cells[l];
                for b in (0..64).filter(|b| cells >> b & 1 != 0) {
                    shared += usize::from(!seen.insert((boxes[l].x0 + b % 8, boxes[l].y0 + b / 8)));
                }
            }
        }
        assert!(covered > 30_000 && shared > 3_000, "{covered} covered, {shared} shared");
    }

    /// A small triangle's box reaching outside the band, above it or below, or so far below
    /// that its pixels' `i32` indices would wrap back into the buffers (a caller's error:
    /// boxes are clipped to it), panics at every level rather than reading or writing past
    /// the buffers or elsewhere in them: the SIMD kernels check each box's first pixel
    /// against the band, the AVX-512 one each group's indices before it gathers or scatters,
    /// the AVX2 one each pixel as it writes it, colours last (so here no colour is written;
    /// the scalar loop writes the pixels before the first outside).
    #[test]
    fn small_eights_outside_the_buffers_panic() {
        let mut eight = SmallEight::default();
        // The box's first column on its two rows: the first row lies above the band.
        eight.inside[0] = 0x101;
        let mut shading = SmallShading::default();
        let depth = PlaneEquation::from_coefficients([0.5, 0.0, 0.0]);
        let color = random_perspective(&mut SmallRng::seed_from_u64(67), 1);
        // The third's first pixel lies 2^30 rows below the band: 2^32 pixels, so its index,
        // computed in `i32`, would wrap back to the band's first pixel.
        let far = 4 + (1 << 30);
        for rect in [
            PixelRect { x0: 0, y0: 3, x1: 0, y1: 4 },
            PixelRect { x0: 0, y0: 9, x1: 0, y1: 10 },
            PixelRect { x0: 0, y0: far, x1: 0, y1: far + 1 },
        ] {
            shading.set(0, &rect, &depth, &color, 1);
            for level in SimdLevel::available() {
                let mut target = crate::target::Target::new(4, 10).unwrap();
                let before = target.clone();
                let drawn = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    let mut bands = target.bands_from(&[0, 4]);
                    shade_small_eight(level, &eight, &shading, 0..1, &mut bands[1], DepthTest::Less)
                }));
                assert!(drawn.is_err(), "{level:?}, {rect:?}: drawn");
                if level != SimdLevel::Scalar {
                    assert!(target.color == before.color, "{level:?}, {rect:?}: written");
                }
            }
        }
    }

    /// Eight lanes' colours encode at every level as lane by lane: each channel in its byte,
    /// each lane in its place (the AVX2 transpose), for channels drawn from special values
    /// (NaN, infinities, zeros, 2^-13, 1 and their neighbours) and random ones in and out of
    /// [0, 1]. The encoders themselves are checked value by value above.
    #[test]
    fn srgb8_lanes_match_scalar() {
        let first = crate::color::FIRST_ENCODED;
        let special = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            first,
            f32::from_bits(first.to_bits() - 1),
            1.0,
            f32::from_bits(1.0f32.to_bits() + 1),
            f32::from_bits(1.0f32.to_bits() - 1),
        ];
        let mut rng = SmallRng::seed_from_u64(63);
        for round in 0..50_000 {
            let colors: [[f32; 4]; 8] = std::array::from_fn(|_| {
                std::array::from_fn(|_| match rng.random_range(0..4) {
                    0 if round % 2 == 0 => special[rng.random_range(0..special.len())],
                    1 => f32::from_bits(rng.random()),
                    _ => rng.random_range(-0.1..1.1),
                })
            });
            let want = srgb8_lanes_scalar(&colors);
            for (l, c) in colors.iter().enumerate() {
                let [r, g, b] = crate::color::linear_to_srgb8_rgb([c[0], c[1], c[2]]);
                let a = crate::color::unorm8(c[3]);
                assert_eq!(want[l].to_le_bytes(), [r, g, b, a], "{c:?}");
            }
            for level in SimdLevel::available() {
                assert_eq!(srgb8_lanes(level, &colors), want, "{level:?}: {colors:?}");
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
                            color: &color,
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
