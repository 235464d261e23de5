//! The AVX-512 shading kernels: eight pixels per step, the numerators and planes in `f64`
//! lanes of one 512-bit register, depth, colour and ids in eight 32-bit lanes, coverage and
//! the depth test in mask registers. Masked loads and stores touch only the lanes a mask
//! enables (and raise no fault for the others), so a narrow triangle's row is one group
//! whatever its width, a span's tail is one masked group, and no pixel outside the triangle
//! is read or written: the AVX2 kernels' read-blend-write of whole groups, and the scalar
//! fallbacks at the buffers' ends, are not needed here.
//!
//! The arithmetic is the AVX2 kernels' (and so the scalar code's) lane by lane: separate
//! multiplies and adds for depth, fused multiply-adds for colour, conversions in the default
//! rounding mode, clamps with the constant first.

use std::arch::x86_64::*;

use super::{
    EdgeValues, KernelTarget, NarrowBox, NarrowEight, NarrowJob, NarrowSamplesJob,
    PerspectiveColor, SampleSpanJob, SmallEight, SmallShading, SpanColor, SpanJob, WindowGroup,
};
use crate::color::ENCODE_BUCKETS;
use crate::fixed;
use crate::render::WindowRecord;
use crate::setup::{CullMode, PixelRect, Vertex};
use crate::shade::DepthTest;
use crate::target::TargetBand;

/// [`super::row_masks`]: a row's eight pixels in one register per edge; the pixels out are
/// the negative lanes of `e0 | e1 | e2`.
///
/// # Safety
/// The CPU must support AVX-512 (F, VL, DQ).
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
pub(super) unsafe fn row_masks(
    e: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
    columns: usize,
    out: &mut [u8],
) {
    let keep = ((1u32 << columns) - 1) as u8;
    let iota = _mm512_set_epi64(7, 6, 5, 4, 3, 2, 1, 0);
    let mut v: [__m512i; 3] = std::array::from_fn(|k| {
        let across = _mm512_mullo_epi64(iota, _mm512_set1_epi64(step_x[k]));
        _mm512_add_epi64(_mm512_set1_epi64(e[k]), across)
    });
    let down: [__m512i; 3] = std::array::from_fn(|k| _mm512_set1_epi64(step_y[k]));
    for o in out.iter_mut() {
        let any = _mm512_or_si512(_mm512_or_si512(v[0], v[1]), v[2]);
        *o = !_mm512_movepi64_mask(any) & keep;
        v = std::array::from_fn(|k| _mm512_add_epi64(v[k], down[k]));
    }
}

/// Eight lanes of `(a0 + f1 * g1) + f2 * g2`: a depth plane.
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn plane(p: [f64; 3], f1: __m512d, f2: __m512d) -> __m512d {
    let t = _mm512_add_pd(_mm512_set1_pd(p[0]), _mm512_mul_pd(f1, _mm512_set1_pd(p[1])));
    _mm512_add_pd(t, _mm512_mul_pd(f2, _mm512_set1_pd(p[2])))
}

/// Eight lanes of `fma(f2, g2, fma(f1, g1, a0))`: a colour plane (see [`SpanColor::at`]).
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn color_plane(p: [f64; 3], f1: __m512d, f2: __m512d) -> __m512d {
    let t = _mm512_fmadd_pd(f1, _mm512_set1_pd(p[1]), _mm512_set1_pd(p[0]));
    _mm512_fmadd_pd(f2, _mm512_set1_pd(p[2]), t)
}

/// `quantize_channel` on eight lanes, as the AVX2 `quantize`: `max(v, 0)` maps NaN to 0, the
/// conversion rounds half to even.
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn quantize(v: __m512d) -> __m256i {
    let v = _mm512_min_pd(_mm512_set1_pd(255.0), _mm512_max_pd(v, _mm512_setzero_pd()));
    _mm512_cvtpd_epi32(v)
}

/// Eight lanes of RGBA8 from planes (see the AVX2 `smooth`).
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn smooth<const CLAMP: bool>(
    p: &[[f64; 3]],
    alpha: Option<u8>,
    f1: __m512d,
    f2: __m512d,
) -> __m256i {
    let channel = |p: [f64; 3]| {
        let v = color_plane(p, f1, f2);
        if CLAMP { quantize(v) } else { _mm512_cvtpd_epi32(v) }
    };
    let (r, g, b) = (channel(p[0]), channel(p[1]), channel(p[2]));
    let a = match alpha {
        Some(a) => _mm256_set1_epi32(i32::from(a) << 24),
        None => _mm256_slli_epi32::<24>(channel(p[3])),
    };
    _mm256_or_si256(
        _mm256_or_si256(r, _mm256_slli_epi32::<8>(g)),
        _mm256_or_si256(_mm256_slli_epi32::<16>(b), a),
    )
}

/// Eight lanes of [`PerspectiveColor::at`] (its `1 / w` and whether they are affine, `q`;
/// the sRGB encoder's `table`): the weights in `f64` lanes (three divisions of eight), the
/// colours in `f32` lanes, the encoder's lookups gathered ([`super::avx2::srgb8`]).
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx2,popcnt,bmi1,bmi2")]
fn perspective(
    p: &PerspectiveColor,
    q: ([f64; 3], bool),
    table: &[u32; ENCODE_BUCKETS],
    f1: __m512d,
    f2: __m512d,
) -> __m256i {
    // Written out, without closures or `map`: a closure here was called, not inlined, a
    // quarter of the bunny's frame.
    let w = perspective_weights(p.inv_area2, q, f1, f2);
    let r = super::avx2::srgb8(perspective_channel(p, &w, 0), table);
    let g = super::avx2::srgb8(perspective_channel(p, &w, 1), table);
    let b = super::avx2::srgb8(perspective_channel(p, &w, 2), table);
    let a = match p.alpha {
        Some(a) => _mm256_set1_epi32(i32::from(crate::color::unorm8(a)) << 24),
        None => _mm256_slli_epi32::<24>(super::avx2::unorm8(perspective_channel(p, &w, 3))),
    };
    _mm256_or_si256(
        _mm256_or_si256(r, _mm256_slli_epi32::<8>(g)),
        _mm256_or_si256(_mm256_slli_epi32::<16>(b), a),
    )
}

/// Eight lanes of `crate::pipeline::perspective_weights(f1 inv_area2, f2 inv_area2, q)`.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
fn perspective_weights(
    inv_area2: f64,
    (q, affine): ([f64; 3], bool),
    f1: __m512d,
    f2: __m512d,
) -> [__m256; 3] {
    let inv_area2 = _mm512_set1_pd(inv_area2);
    let (l1, l2) = (_mm512_mul_pd(f1, inv_area2), _mm512_mul_pd(f2, inv_area2));
    let l0 = _mm512_sub_pd(_mm512_sub_pd(_mm512_set1_pd(1.0), l1), l2);
    if affine {
        return [_mm512_cvtpd_ps(l0), _mm512_cvtpd_ps(l1), _mm512_cvtpd_ps(l2)];
    }
    let w0 = _mm512_mul_pd(l0, _mm512_set1_pd(q[0]));
    let w1 = _mm512_mul_pd(l1, _mm512_set1_pd(q[1]));
    let w2 = _mm512_mul_pd(l2, _mm512_set1_pd(q[2]));
    let sum = _mm512_add_pd(_mm512_add_pd(w0, w1), w2);
    // `sum > 0`, false for NaN: thirds elsewhere.
    let positive = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(sum, _mm512_setzero_pd());
    let third = _mm256_set1_ps(1.0 / 3.0);
    [
        _mm256_mask_blend_ps(positive, third, _mm512_cvtpd_ps(_mm512_div_pd(w0, sum))),
        _mm256_mask_blend_ps(positive, third, _mm512_cvtpd_ps(_mm512_div_pd(w1, sum))),
        _mm256_mask_blend_ps(positive, third, _mm512_cvtpd_ps(_mm512_div_pd(w2, sum))),
    ]
}

/// Channel `k` of the colour at weights `w`: `(c0 w0 + c1 w1 + c2 w2) scale`, left to right.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
fn perspective_channel(p: &PerspectiveColor, w: &[__m256; 3], k: usize) -> __m256 {
    let [c0, c1, c2] = p.colors;
    let (c0, c1, c2) = (_mm256_set1_ps(c0[k]), _mm256_set1_ps(c1[k]), _mm256_set1_ps(c2[k]));
    let t = _mm256_add_ps(_mm256_mul_ps(c0, w[0]), _mm256_mul_ps(c1, w[1]));
    let t = _mm256_add_ps(t, _mm256_mul_ps(c2, w[2]));
    _mm256_mul_ps(t, _mm256_set1_ps(p.scale[k]))
}

/// The weights and the four channels of [`perspective`] at eight numerators, for the tests.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[cfg(test)]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
pub(super) unsafe fn perspective_probe(
    p: &PerspectiveColor,
    f1: [f64; 8],
    f2: [f64; 8],
) -> ([[f32; 8]; 3], [[f32; 8]; 4]) {
    // SAFETY: each load reads the lanes of its array, no more.
    let (f1, f2) = unsafe { (_mm512_loadu_pd(f1.as_ptr()), _mm512_loadu_pd(f2.as_ptr())) };
    let w = perspective_weights(p.inv_area2, p.inv_w(), f1, f2);
    let lanes = |v: __m256| {
        let mut out = [0.0f32; 8];
        // SAFETY: eight `f32` lanes into an array of eight.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), v) };
        out
    };
    (w.map(lanes), [0, 1, 2, 3].map(|k| lanes(perspective_channel(p, &w, k))))
}

/// Eight 32-bit lanes of `p`, those of `m` read and the others zero: from `p + at[0]`, or,
/// with `PAIR`, lanes 0-3 from `p + at[0]` and 4-7 from `p + at[1]` (two rows of a narrow
/// triangle).
///
/// # Safety
/// The CPU must support AVX-512 F and VL; both offsets must be within the buffer `p` points
/// into (or one past it), and every lane of `m` must lie in it.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
unsafe fn load<const PAIR: bool>(p: *const i32, at: [usize; 2], m: __mmask8) -> __m256i {
    // SAFETY: the offsets stay in the buffer (the caller's contract); masked loads read only
    // the lanes of `m`, which lie in it, and need no alignment.
    unsafe {
        if PAIR {
            let lo = _mm_maskz_loadu_epi32(m & 0xF, p.add(at[0]));
            let hi = _mm_maskz_loadu_epi32(m >> 4, p.add(at[1]));
            _mm256_inserti128_si256::<1>(_mm256_castsi128_si256(lo), hi)
        } else {
            _mm256_maskz_loadu_epi32(m, p.add(at[0]))
        }
    }
}

/// Writes the lanes of `m` of `v` where [`load`] reads them.
///
/// # Safety
/// As [`load`].
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
unsafe fn store<const PAIR: bool>(p: *mut i32, at: [usize; 2], m: __mmask8, v: __m256i) {
    // SAFETY: as in `load`: masked stores write only the lanes of `m`.
    unsafe {
        if PAIR {
            _mm_mask_storeu_epi32(p.add(at[0]), m & 0xF, _mm256_castsi256_si128(v));
            _mm_mask_storeu_epi32(p.add(at[1]), m >> 4, _mm256_extracti128_si256::<1>(v));
        } else {
            _mm256_mask_storeu_epi32(p.add(at[0]), m, v);
        }
    }
}

/// The eight pixels at `at` (see [`load`]) whose bits in `cover` are set, with barycentric
/// numerators `f1`, `f2`: overdraw, depth test and writes, as `KernelTarget::pixel` does lane
/// by lane. With `SKIP_HIDDEN`, no colour is computed when no lane passes the depth test.
/// With `at_sample`, depth is taken at those numerators instead (samples whose colour is
/// their pixel centre's).
///
/// # Safety
/// The CPU must support AVX-512 F and VL; the offsets must be at most `t.checked_len()`, and
/// every lane set in `cover` must lie below it.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
unsafe fn group<const SKIP_HIDDEN: bool, const PAIR: bool, const DEPTH: u8>(
    t: &mut KernelTarget<'_>,
    at: [usize; 2],
    f1: __m512d,
    f2: __m512d,
    cover: __mmask8,
    at_sample: Option<[__m512d; 2]>,
    rgba: impl Fn(__m512d, __m512d) -> __m256i,
) {
    // SAFETY (every access in this block): the buffers all hold `checked_len()` elements, so
    // the caller's guarantee on `at` and `cover` is `load`'s and `store`'s for each, and for
    // `pass`, a subset of `cover`; `f32` and `[u8; 4]` are four bytes, one i32 lane.
    unsafe {
        if let Some(o) = t.overdraw.as_deref_mut() {
            let p = o.as_mut_ptr().cast::<i32>();
            let counts = load::<PAIR>(p, at, cover);
            store::<PAIR>(p, at, cover, _mm256_add_epi32(counts, _mm256_set1_epi32(1)));
        }
        let [z1, z2] = at_sample.unwrap_or([f1, f2]);
        let z = _mm512_cvtpd_ps(plane(t.depth_plane, z1, z2));
        let z = _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z));
        let dp = t.depth.as_mut_ptr().cast::<i32>();
        let stored = _mm256_castsi256_ps(load::<PAIR>(dp, at, cover));
        let pass = match depth_test::<DEPTH>(t.depth_test) {
            DepthTest::Less => _mm256_mask_cmp_ps_mask::<_CMP_LT_OQ>(cover, z, stored),
            DepthTest::LessEqual => _mm256_mask_cmp_ps_mask::<_CMP_LE_OQ>(cover, z, stored),
            DepthTest::Always => cover,
        };
        if SKIP_HIDDEN && pass == 0 {
            return;
        }
        store::<PAIR>(dp, at, pass, _mm256_castps_si256(z));
        store::<PAIR>(t.color_out.as_mut_ptr().cast::<i32>(), at, pass, rgba(f1, f2));
        if let Some(ids) = t.ids.as_deref_mut() {
            store::<PAIR>(ids.as_mut_ptr(), at, pass, _mm256_set1_epi32(t.id));
        }
    }
}

/// [`group`]'s depth test: `DEPTH` names one ([`DEPTH_LESS`] and the others) for loops
/// instantiated per test, or is [`ANY_DEPTH`] for `test`, read where the group runs.
#[inline(always)]
fn depth_test<const DEPTH: u8>(test: DepthTest) -> DepthTest {
    match DEPTH {
        DEPTH_LESS => DepthTest::Less,
        DEPTH_LESS_EQUAL => DepthTest::LessEqual,
        DEPTH_ALWAYS => DepthTest::Always,
        _ => test,
    }
}

/// [`group`]'s `DEPTH` for a test read where the group runs.
const ANY_DEPTH: u8 = 0;
/// [`group`]'s `DEPTH` for [`DepthTest::Less`].
const DEPTH_LESS: u8 = 1;
/// [`group`]'s `DEPTH` for [`DepthTest::LessEqual`].
const DEPTH_LESS_EQUAL: u8 = 2;
/// [`group`]'s `DEPTH` for [`DepthTest::Always`].
const DEPTH_ALWAYS: u8 = 3;

/// The lanes `0..8` as `f64`.
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn lanes() -> __m512d {
    _mm512_setr_pd(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0)
}

/// Lane `l` of eight samples, `n` (4 or 8) per pixel: `f(pixel, sample)`, the pixel
/// `l / n` of the group and the sample `l % n`, by shifts and masks (a closure called
/// through `dyn` with a division per lane, 32 per triangle, was a twentieth of a frame of
/// small triangles at 4x).
#[inline]
#[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
fn sample_lanes(n: usize, f: impl Fn(usize, usize) -> f64) -> __m512d {
    debug_assert!(n == 4 || n == 8, "4 or 8 samples per pixel");
    let shift = n.trailing_zeros();
    let lane = |l: usize| f(l >> shift, l & (n - 1));
    _mm512_setr_pd(lane(0), lane(1), lane(2), lane(3), lane(4), lane(5), lane(6), lane(7))
}

/// [`super::shade_narrow`] in AVX-512: each row of the box is one group of eight lanes, the
/// box's columns and the triangle's coverage (the sign bits of `e0 | e1 | e2`, stepped
/// exactly in `f64` as in the AVX2 kernel) one mask. No branches on coverage or depth.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_narrow(job: &mut NarrowJob<'_>) -> u64 {
    // Packed lanes hold buffer indices in `i32` (any target's, and any band's buffers but
    // one of more than 2^31 pixels, which takes the unpacked loop).
    if let SpanColor::Perspective(p) = job.target.color
        && job.end(job.columns) <= i32::MAX as usize
    {
        // SAFETY: the CPU supports AVX-512 F, VL and DQ (this function's contract).
        return unsafe {
            if job.columns <= 4 {
                narrow_packed::<true>(job, p)
            } else {
                narrow_packed::<false>(job, p)
            }
        };
    }
    // SAFETY: the CPU supports AVX-512 F, VL and DQ (this function's contract).
    with_rgba!(*job.target.color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        narrow_rows(job, rgba)
    })
}

/// [`shade_narrow`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
unsafe fn narrow_rows(job: &mut NarrowJob<'_>, rgba: impl Fn(__m512d, __m512d) -> __m256i) -> u64 {
    job.assert_narrow();
    let box_ = NarrowBox::of(job);
    // SAFETY: the CPU supports AVX-512 F, VL and DQ (this function's contract); the box is
    // narrow (asserted above).
    unsafe { narrow_box(&box_, &mut job.target, rgba) }
}

/// [`narrow_rows`] for a perspective colour, whose lanes cost most (three divisions and
/// three table gathers): coverage and the depth test group by group as [`narrow_box`] does
/// them (depth, ids and overdraw written there), and the numerators of the pixels that pass
/// packed eight to a group before their colour is computed. A small triangle's box is
/// mostly uncovered: the Stanford bunny's narrow triangles at 1080p cover about a fifth of
/// their groups' lanes. Each lane's colour is the one [`perspective`] gives it unpacked.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,popcnt,bmi1,bmi2")]
unsafe fn narrow_packed<const PAIR: bool>(job: &mut NarrowJob<'_>, p: &PerspectiveColor) -> u64 {
    job.assert_narrow();
    assert!(PAIR == (job.columns <= 4), "two rows per group for boxes up to four wide");
    let end = job.end(job.columns);
    let b = NarrowBox::of(job);
    let t = &mut job.target;
    let n = t.checked_len();
    assert!(end <= n && end <= i32::MAX as usize, "the box must lie in the buffers");
    let (table, q) = (crate::color::srgb8_table(), p.inv_w());
    let (mut e, step, columns, rows_per_group) = b.groups();
    // Each lane's buffer offset from the group's first pixel (lanes 4-7 the next row's in
    // pairs): below the box's end, so within `i32`.
    let stride = b.stride as i32;
    let index = if PAIR {
        _mm256_setr_epi32(0, 1, 2, 3, stride, stride + 1, stride + 2, stride + 3)
    } else {
        _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)
    };
    let bias = [0, 1].map(|k| _mm512_set1_pd(b.values.bias(k)));
    // The passing pixels' numerators and buffer indices, packed in the lanes below
    // `waiting` (in registers: loaded back from arrays, a pack's lanes were read with loads
    // spanning several stores, which store forwarding fails).
    let (mut packed_f1, mut packed_f2) = (_mm512_setzero_pd(), _mm512_setzero_pd());
    let mut packed_at = _mm256_setzero_si256();
    let mut waiting = 0u32;
    let iota = _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 6, 7);
    let color_out = t.color_out.as_mut_ptr().cast::<i32>();
    let mut covered = 0u64;
    for r in (0..b.rows).step_by(rows_per_group) {
        // `group_edges`, written out: called here, the bunny measured 1-3% slower (the
        // compiler placed this loop's values differently).
        let any = _mm512_or_si512(
            _mm512_or_si512(_mm512_castpd_si512(e[0]), _mm512_castpd_si512(e[1])),
            _mm512_castpd_si512(e[2]),
        );
        let outside = _mm512_movepi64_mask(any);
        let (f1, f2) = (_mm512_sub_pd(e[1], bias[0]), _mm512_sub_pd(e[2], bias[1]));
        let (at, second, lanes) = b.group_at::<PAIR>(r, columns);
        let cover = !outside & lanes;
        covered += u64::from(cover.count_ones());
        // SAFETY: both rows' first pixels are in the buffers and so are their `columns`
        // lanes, a superset of `cover` (asserted above); `f32` and `i32` are four bytes.
        let pass = unsafe {
            if let Some(o) = t.overdraw.as_deref_mut() {
                let o = o.as_mut_ptr().cast::<i32>();
                let counts = load::<PAIR>(o, [at, second], cover);
                store::<PAIR>(
                    o,
                    [at, second],
                    cover,
                    _mm256_add_epi32(counts, _mm256_set1_epi32(1)),
                );
            }
            let z = _mm512_cvtpd_ps(plane(t.depth_plane, f1, f2));
            let z = _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z));
            let dp = t.depth.as_mut_ptr().cast::<i32>();
            let stored = _mm256_castsi256_ps(load::<PAIR>(dp, [at, second], cover));
            let pass = match t.depth_test {
                DepthTest::Less => _mm256_mask_cmp_ps_mask::<_CMP_LT_OQ>(cover, z, stored),
                DepthTest::LessEqual => _mm256_mask_cmp_ps_mask::<_CMP_LE_OQ>(cover, z, stored),
                DepthTest::Always => cover,
            };
            store::<PAIR>(dp, [at, second], pass, _mm256_castps_si256(z));
            if let Some(ids) = t.ids.as_deref_mut() {
                store::<PAIR>(ids.as_mut_ptr(), [at, second], pass, _mm256_set1_epi32(t.id));
            }
            pass
        };
        let at_lanes = _mm256_add_epi32(_mm256_set1_epi32(at as i32), index);
        let (f1, f2) = (_mm512_maskz_compress_pd(pass, f1), _mm512_maskz_compress_pd(pass, f2));
        let at_lanes = _mm256_maskz_compress_epi32(pass, at_lanes);
        // The new lanes moved up past the waiting ones (indices modulo 8: those that wrap
        // around are the next pack's).
        let up = _mm512_sub_epi64(iota, _mm512_set1_epi64(i64::from(waiting)));
        let above = (0xFFu32 << waiting) as __mmask8;
        packed_f1 = _mm512_mask_permutexvar_pd(packed_f1, above, up, f1);
        packed_f2 = _mm512_mask_permutexvar_pd(packed_f2, above, up, f2);
        let up32 = _mm512_cvtepi64_epi32(up);
        packed_at = _mm256_mask_permutexvar_epi32(packed_at, above, up32, at_lanes);
        waiting += pass.count_ones();
        if waiting >= 8 {
            // SAFETY: the eight packed lanes are indices of pixels of the box (below `n`).
            unsafe {
                packed_colors(p, (q, table), (packed_f1, packed_f2, packed_at), 0xFF, color_out)
            };
            // The rest of the new lanes, from the first that did not fit.
            waiting -= 8;
            packed_f1 = _mm512_permutexvar_pd(up, f1);
            packed_f2 = _mm512_permutexvar_pd(up, f2);
            packed_at = _mm256_permutexvar_epi32(up32, at_lanes);
        }
        e = std::array::from_fn(|k| _mm512_add_pd(e[k], step[k]));
    }
    if waiting > 0 {
        let m = ((1u32 << waiting) - 1) as __mmask8;
        // SAFETY: the first `waiting` packed lanes are indices of pixels of the box.
        unsafe { packed_colors(p, (q, table), (packed_f1, packed_f2, packed_at), m, color_out) };
    }
    covered
}

/// The perspective colours of the packed lanes `m` (of the first eight) written at their
/// buffer indices.
///
/// # Safety
/// The CPU must support AVX-512 F and VL; each lane of `m` must hold an index into the colour
/// buffer `out` points to.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx2,popcnt,bmi1,bmi2")]
unsafe fn packed_colors(
    p: &PerspectiveColor,
    (q, table): (([f64; 3], bool), &[u32; ENCODE_BUCKETS]),
    (f1, f2, at): (__m512d, __m512d, __m256i),
    m: __mmask8,
    out: *mut i32,
) {
    let rgba = perspective(p, q, table, f1, f2);
    // SAFETY: the scatter writes the lanes of `m` only, at indices into the buffer (the
    // caller's contract).
    unsafe { _mm256_mask_i32scatter_epi32::<4>(out.cast(), m, at, rgba) };
}

impl<V: EdgeValues> NarrowBox<V> {
    /// How groups of eight lanes cover the box: edge `k` at each lane of the first group and
    /// its step from one group to the next, the lanes within the box's columns, and the rows
    /// a group takes (boxes up to four pixels wide, most small triangles, two: lanes 0-3 the
    /// first, 4-7 the second). The loops step the edge values in their registers: stepped as
    /// one value per edge and then added to the lanes' offsets, each group's row went through
    /// memory to be broadcast (soup 47.8 -> 45.9 ms on two threads). The sums are the same:
    /// integers below 2^53, exact in `f64` whatever their order.
    #[inline]
    #[target_feature(enable = "avx512f,popcnt,bmi1,bmi2")]
    fn groups(&self) -> ([__m512d; 3], [__m512d; 3], __mmask8, usize) {
        let pair = self.columns <= 4;
        let (column, row_of_lane, rows_per_group) = if pair {
            (_mm512_setr_pd(0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0), 1.0, 2)
        } else {
            (lanes(), 0.0, 1)
        };
        let r = row_of_lane;
        let row_of_lane = _mm512_setr_pd(0.0, 0.0, 0.0, 0.0, r, r, r, r);
        let offsets: [__m512d; 3] = std::array::from_fn(|k| {
            _mm512_add_pd(
                _mm512_mul_pd(column, _mm512_set1_pd(self.values.step_x(k))),
                _mm512_mul_pd(row_of_lane, _mm512_set1_pd(self.values.step_y(k))),
            )
        });
        let edge = |k: usize| _mm512_set1_pd(self.values.edge(k));
        let first = std::array::from_fn(|k| _mm512_add_pd(edge(k), offsets[k]));
        let rows = rows_per_group as f64;
        let step = std::array::from_fn(|k| _mm512_set1_pd(rows * self.values.step_y(k)));
        let row_bits = (1u32 << self.columns) - 1;
        let columns = if pair { row_bits | row_bits << 4 } else { row_bits } as __mmask8;
        (first, step, columns, rows_per_group)
    }

    /// Where the group starting at row `r` reads and writes: its first row's first pixel,
    /// its second row's (`PAIR`: boxes up to four wide, two rows a group) or the same, and
    /// its lanes within the box's `columns` (a last row of its own leaves the upper lanes
    /// masked off, at the same address).
    #[inline(always)]
    fn group_at<const PAIR: bool>(&self, r: usize, columns: __mmask8) -> (usize, usize, __mmask8) {
        let at = self.first + r * self.stride;
        if !PAIR {
            (at, at, columns)
        } else if r + 1 < self.rows {
            (at, at + self.stride, columns)
        } else {
            (at, at, columns & 0xF)
        }
    }
}

/// A group's edge values `e` (edge `k` at each lane's pixel): the lanes outside an edge (the
/// sign bits of `e0 | e1 | e2`) and the barycentric numerators (edges 1 and 2 less their
/// `bias`).
#[inline]
#[target_feature(enable = "avx512f,avx512dq,popcnt,bmi1,bmi2")]
fn group_edges(e: &[__m512d; 3], bias: &[__m512d; 2]) -> (__mmask8, __m512d, __m512d) {
    let any = _mm512_or_si512(
        _mm512_or_si512(_mm512_castpd_si512(e[0]), _mm512_castpd_si512(e[1])),
        _mm512_castpd_si512(e[2]),
    );
    (_mm512_movepi64_mask(any), _mm512_sub_pd(e[1], bias[0]), _mm512_sub_pd(e[2], bias[1]))
}

/// The narrow kernel's loop over box `b` into `t`: each row of the box one group of eight
/// lanes (two rows for boxes up to four wide), coverage the sign bits of `e0 | e1 | e2`.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ; `b` must be narrow (1 to 8 columns, a row or
/// more).
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
unsafe fn narrow_box(
    b: &NarrowBox<impl EdgeValues>,
    t: &mut KernelTarget<'_>,
    rgba: impl Fn(__m512d, __m512d) -> __m256i,
) -> u64 {
    debug_assert!((1..=8).contains(&b.columns) && b.rows > 0, "a narrow box");
    let n = t.checked_len();
    // Checked arithmetic (an overflow is `usize::MAX`, past any buffer): the offsets below
    // stay in the buffers only if this holds.
    let end = super::box_end(b.rows, b.stride, b.first, b.columns);
    assert!(end <= n, "the box must lie in the buffers");
    // A loop for each kind of group and depth test, with no choice between them inside:
    // with the choices in the loop, how the compiler placed the loop's values moved with
    // unrelated edits elsewhere (the soup 3-5% slower or faster), the depth test reloaded
    // from the stack. With the depth test a constant too, the soup went 50.8 -> 48.9 ms on
    // two threads, 95.5 -> 92.1 ms on one. (The same for the packed perspective loop made
    // the soup, which does not run it, 7% slower again, and the bunny no faster.)
    // SAFETY: the box is narrow and lies in the buffers (asserted above).
    unsafe {
        match (b.columns <= 4, t.depth_test) {
            (true, DepthTest::Less) => narrow_groups::<true, DEPTH_LESS>(b, t, rgba),
            (true, DepthTest::LessEqual) => narrow_groups::<true, DEPTH_LESS_EQUAL>(b, t, rgba),
            (true, DepthTest::Always) => narrow_groups::<true, DEPTH_ALWAYS>(b, t, rgba),
            (false, DepthTest::Less) => narrow_groups::<false, DEPTH_LESS>(b, t, rgba),
            (false, DepthTest::LessEqual) => narrow_groups::<false, DEPTH_LESS_EQUAL>(b, t, rgba),
            (false, DepthTest::Always) => narrow_groups::<false, DEPTH_ALWAYS>(b, t, rgba),
        }
    }
}

/// [`narrow_box`]'s groups: two rows of up to four pixels each (`PAIR`), or one of up to
/// eight.
///
/// # Safety
/// As [`narrow_box`], whose assertions it relies on; `PAIR` when the box is at most four
/// wide.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
unsafe fn narrow_groups<const PAIR: bool, const DEPTH: u8>(
    b: &NarrowBox<impl EdgeValues>,
    t: &mut KernelTarget<'_>,
    rgba: impl Fn(__m512d, __m512d) -> __m256i,
) -> u64 {
    debug_assert_eq!(PAIR, b.columns <= 4, "two rows per group for boxes up to four wide");
    let (mut e, step, columns, rows_per_group) = b.groups();
    let bias = [0, 1].map(|k| _mm512_set1_pd(b.values.bias(k)));
    let mut covered = 0u64;
    for r in (0..b.rows).step_by(rows_per_group) {
        let (outside, f1, f2) = group_edges(&e, &bias);
        let (at, second, lanes) = b.group_at::<PAIR>(r, columns);
        let cover = !outside & lanes;
        covered += u64::from(cover.count_ones());
        // SAFETY: both rows' first pixels are in the buffers and so are their `columns`
        // lanes, a superset of `cover` (asserted by `narrow_box`).
        unsafe { group::<false, PAIR, DEPTH>(t, [at, second], f1, f2, cover, None, &rgba) };
        e = std::array::from_fn(|k| _mm512_add_pd(e[k], step[k]));
    }
    covered
}

/// Eight rows of sixteen 32-bit words as sixteen registers of eight: word `i` of row `l` in
/// lane `l` of the `i`-th.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
fn transposed(r: [__m512i; 8]) -> [__m256i; 16] {
    // Per 128-bit lane j of rows 0-3: words 4j + i side by side in `b[i]`; of rows 4-7 in
    // `c[i]`.
    let quad = |r: &[__m512i]| {
        let (a0, a1) = (_mm512_unpacklo_epi32(r[0], r[1]), _mm512_unpackhi_epi32(r[0], r[1]));
        let (a2, a3) = (_mm512_unpacklo_epi32(r[2], r[3]), _mm512_unpackhi_epi32(r[2], r[3]));
        [
            _mm512_unpacklo_epi64(a0, a2),
            _mm512_unpackhi_epi64(a0, a2),
            _mm512_unpacklo_epi64(a1, a3),
            _mm512_unpackhi_epi64(a1, a3),
        ]
    };
    let (b, c) = (quad(&r[..4]), quad(&r[4..]));
    let mut word = [_mm256_setzero_si256(); 16];
    for i in 0..4 {
        // [b lane 0, c lane 0, b lane 1, c lane 1]: words i and 4 + i of all eight rows;
        // lanes 2 and 3 the same for words 8 + i and 12 + i.
        let lo = _mm512_shuffle_i32x4::<0b01_00_01_00>(b[i], c[i]);
        let lo = _mm512_shuffle_i32x4::<0b11_01_10_00>(lo, lo);
        let hi = _mm512_shuffle_i32x4::<0b11_10_11_10>(b[i], c[i]);
        let hi = _mm512_shuffle_i32x4::<0b11_01_10_00>(hi, hi);
        word[i] = _mm512_castsi512_si256(lo);
        word[4 + i] = _mm512_extracti64x4_epi64::<1>(lo);
        word[8 + i] = _mm512_castsi512_si256(hi);
        word[12 + i] = _mm512_extracti64x4_epi64::<1>(hi);
    }
    word
}

/// [`super::narrow_eight`]: the eight records loaded as one 512-bit register each (sixteen
/// 32-bit words, see [`WindowRecord`]), transposed into one 256-bit register per word, and
/// set up side by side: the box from the snapped vertices and clipped to `tile`
/// ([`crate::setup::sample_bounds`]' centres, by shifts), the edges at its first pixel's
/// centre ([`crate::setup::TriangleSetup::edges_at`], in `f64` lanes: products of integers
/// below 2^25, exact), the depth and colour planes (`(a_i - a0) * inv_area2`, the
/// operations of [`crate::shade::PlaneEquation::with_inv_area2`]).
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx2,popcnt,bmi1,bmi2")]
pub(super) unsafe fn narrow_eight(
    records: &[&WindowRecord; 8],
    tile: &PixelRect,
    reach: i32,
    out: &mut NarrowEight,
) -> u8 {
    // SAFETY: a record is 64 bytes, aligned to 64 (`repr(C, align(64))`, no padding: its
    // layout is asserted beside it), so each load reads one whole initialized record.
    let r: [__m512i; 8] = std::array::from_fn(|l| unsafe {
        _mm512_load_si512(std::ptr::from_ref(records[l]).cast::<__m512i>())
    });
    let word = transposed(r);
    let [x0, y0, x1, y1, x2, y2] = [word[0], word[1], word[2], word[3], word[4], word[5]];
    let inv_area2 = _mm512_castsi512_pd(_mm512_or_si512(
        _mm512_cvtepu32_epi64(word[12]),
        _mm512_slli_epi64::<32>(_mm512_cvtepu32_epi64(word[13])),
    ));
    let half = _mm256_set1_epi32(fixed::HALF);
    let super::avx2::EightBoxes { width, px0, py0, columns, rows, .. } =
        super::avx2::eight_boxes_reaching([x0, y0, x1, y1, x2, y2], tile, reach);
    // Narrow before clipping, as `bin::coverage_algorithm` asks of the kernel's triangles.
    let narrow = _mm256_cmpgt_epi32_mask(_mm256_set1_epi32(crate::raster::edge::NARROW), width);
    let reaches = _mm256_cmpgt_epi32_mask(columns, _mm256_setzero_si256())
        & _mm256_cmpgt_epi32_mask(rows, _mm256_setzero_si256());
    let flags = word[15];
    out.smooth = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(0xFF00));
    let alpha = _mm256_srli_epi32::<24>(word[9]);
    out.one_alpha = _mm256_cmpeq_epi32_mask(alpha, _mm256_srli_epi32::<24>(word[10]))
        & _mm256_cmpeq_epi32_mask(alpha, _mm256_srli_epi32::<24>(word[11]));
    let lanes = narrow & reaches;
    // The edges, each leaving vertex `k + 1` for vertex `k + 2`, inside positive: negated
    // for counter-clockwise triangles.
    let clockwise = _mm256_test_epi32_mask(flags, _mm256_set1_epi32(0xFF));
    let oriented = |d: __m256i| _mm256_mask_sub_epi32(d, !clockwise, _mm256_setzero_si256(), d);
    let xs = [x0, x1, x2];
    let ys = [y0, y1, y2];
    let sample = |p: __m256i| _mm256_add_epi32(_mm256_slli_epi32::<8>(p), half);
    let (sx, sy) = (sample(px0), sample(py0));
    let f64s = |v: __m256i| _mm512_cvtepi32_pd(v);
    let put = |out: &mut [f64; 8], v: __m512d| {
        // SAFETY: eight `f64`s, 64 bytes; the store needs no alignment.
        unsafe { _mm512_storeu_pd(out.as_mut_ptr(), v) }
    };
    let step = _mm512_set1_pd(f64::from(fixed::ONE));
    for k in 0..3 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let ea = oriented(_mm256_sub_epi32(ys[a], ys[b]));
        let eb = oriented(_mm256_sub_epi32(xs[b], xs[a]));
        // `FillRule::bias`: 0 on owned edges (`a > 0`, or `a == 0` and `b > 0`), else -1.
        let zero = _mm256_setzero_si256();
        let owned = _mm256_cmpgt_epi32_mask(ea, zero)
            | (_mm256_cmpeq_epi32_mask(ea, zero) & _mm256_cmpgt_epi32_mask(eb, zero));
        let bias = _mm256_mask_mov_epi32(_mm256_set1_epi32(-1), owned, zero);
        let (ea, eb) = (f64s(ea), f64s(eb));
        let dx = f64s(_mm256_sub_epi32(sx, xs[a]));
        let dy = f64s(_mm256_sub_epi32(sy, ys[a]));
        let value =
            _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(ea, dx), _mm512_mul_pd(eb, dy)), f64s(bias));
        put(&mut out.edges[k], value);
        put(&mut out.step_x[k], _mm512_mul_pd(ea, step));
        put(&mut out.step_y[k], _mm512_mul_pd(eb, step));
        if k > 0 {
            put(&mut out.bias[k - 1], f64s(bias));
        }
    }
    let plane = |a: [__m512d; 3], out: &mut [[f64; 8]; 3]| {
        let g = |v: __m512d| _mm512_mul_pd(_mm512_sub_pd(v, a[0]), inv_area2);
        put(&mut out[0], a[0]);
        put(&mut out[1], g(a[1]));
        put(&mut out[2], g(a[2]));
    };
    let z = |w: __m256i| _mm512_cvtps_pd(_mm256_castsi256_ps(w));
    plane([z(word[6]), z(word[7]), z(word[8])], &mut out.depth);
    let colors = [word[9], word[10], word[11]];
    for ch in 0..4 {
        let channel = |k: usize| f64s(super::avx2::channel(colors[k], ch));
        plane([channel(0), channel(1), channel(2)], &mut out.color[ch]);
    }
    let flat = super::avx2::flat_colors(colors);
    super::avx2::put_lanes(out, (alpha, flat), [px0, py0, columns, rows, word[14]]);
    lanes
}

/// [`super::shade_narrow_eight`]: each lane of `lanes` through the narrow kernel's loop, its
/// values broadcast from `eight`.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_narrow_eight(
    eight: &NarrowEight,
    lanes: std::ops::Range<usize>,
    target: &mut TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let mut covered = 0;
    for l in lanes {
        let box_ = NarrowBox::of_lane(eight, l, target);
        let color = eight.color(l);
        let mut t = eight.kernel_target(l, &color, depth_test, target);
        // SAFETY: the CPU supports AVX-512 F, VL and DQ (this function's contract); the box
        // is narrow (`of_lane` asserts it).
        covered += with_rgba!(color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
            narrow_box(&box_, &mut t, rgba)
        });
    }
    covered
}

/// [`super::shade_span`] in AVX-512: eight pixels per step, the last `n % 8` as one masked
/// group.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_span(job: &mut SpanJob<'_>) {
    // SAFETY: the CPU supports AVX-512 F and VL (this function's contract).
    with_rgba!(*job.target.color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        span_groups(job, rgba)
    })
}

/// [`shade_span`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
unsafe fn span_groups(job: &mut SpanJob<'_>, rgba: impl Fn(__m512d, __m512d) -> __m256i) {
    let n = job.target.checked_len();
    // The numerators at pixel `lane`, then stepped by eight pixels: exact integers as
    // everywhere (below 2^49).
    let start = |e: i64, step: i64| {
        _mm512_add_pd(_mm512_set1_pd(e as f64), _mm512_mul_pd(lanes(), _mm512_set1_pd(step as f64)))
    };
    let (mut f1, mut f2) = (start(job.e1, job.step1), start(job.e2, job.step2));
    let (step1, step2) =
        (_mm512_set1_pd(8.0 * job.step1 as f64), _mm512_set1_pd(8.0 * job.step2 as f64));
    let mut k = 0;
    while k + 8 <= n {
        // SAFETY: `k + 8 <= n`.
        unsafe {
            group::<true, false, ANY_DEPTH>(&mut job.target, [k, k], f1, f2, 0xFF, None, &rgba)
        };
        f1 = _mm512_add_pd(f1, step1);
        f2 = _mm512_add_pd(f2, step2);
        k += 8;
    }
    if k < n {
        let tail = ((1u32 << (n - k)) - 1) as __mmask8;
        // SAFETY: `k < n` and the lanes of `tail` are `k..n`.
        unsafe {
            group::<true, false, ANY_DEPTH>(&mut job.target, [k, k], f1, f2, tail, None, &rgba)
        };
    }
}

/// [`super::shade_samples`] in AVX-512: eight samples per step (lane `l`: sample `l % n` of
/// pixel `l / n`, whose buffer elements are contiguous), the colour at each lane's pixel
/// centre, depth at its sample; the last pixel at 4x as one masked group.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_samples(job: &mut SampleSpanJob<'_>) {
    // SAFETY: the CPU supports AVX-512 F and VL (this function's contract).
    with_rgba!(*job.span.target.color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        sample_groups(job, rgba)
    })
}

/// [`shade_samples`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,popcnt,bmi1,bmi2")]
unsafe fn sample_groups(job: &mut SampleSpanJob<'_>, rgba: impl Fn(__m512d, __m512d) -> __m256i) {
    let n = job.check();
    let samples = job.samples;
    let pixels_per_group = 8 / samples;
    // Each lane's pixel within the group, and its sample's offset.
    let pixel = sample_lanes(samples, |p, _| p as f64);
    let offset = |k: usize| sample_lanes(samples, |_, s| job.offsets[s][k] as f64);
    let at_sample = [offset(0), offset(1)];
    let span = &mut job.span;
    let start = |e: i64, step: i64| {
        _mm512_add_pd(_mm512_set1_pd(e as f64), _mm512_mul_pd(pixel, _mm512_set1_pd(step as f64)))
    };
    let (mut f1, mut f2) = (start(span.e1, span.step1), start(span.e2, span.step2));
    let group_steps = pixels_per_group as f64;
    let (step1, step2) = (
        _mm512_set1_pd(group_steps * span.step1 as f64),
        _mm512_set1_pd(group_steps * span.step2 as f64),
    );
    let mut k = 0;
    while k < n {
        let lanes = if k + 8 <= n { 0xFF } else { ((1u32 << (n - k)) - 1) as __mmask8 };
        let z = [_mm512_add_pd(f1, at_sample[0]), _mm512_add_pd(f2, at_sample[1])];
        // SAFETY: `k < n`, and the lanes of `lanes` are `k..min(k + 8, n)`.
        unsafe {
            group::<true, false, ANY_DEPTH>(&mut span.target, [k, k], f1, f2, lanes, Some(z), &rgba)
        };
        f1 = _mm512_add_pd(f1, step1);
        f2 = _mm512_add_pd(f2, step2);
        k += 8;
    }
}

/// [`super::shade_narrow_samples`] in AVX-512: each row of the box in groups of eight samples
/// (lane `l`: sample `l % n` of the group's pixel `l / n`, contiguous in the buffers), their
/// coverage the sign bits of `e0 | e1 | e2` stepped exactly in `f64` as in [`narrow_rows`],
/// then [`sample_groups`]' depth per sample and colour per pixel centre. No branches on
/// coverage or depth, as in [`narrow_rows`]: a small triangle has a few groups, and a
/// mispredicted branch costs more than the work it skips (soup at 4x, two threads: skipping
/// uncovered groups 2% slower, hidden ones 7%).
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_narrow_samples(job: &mut NarrowSamplesJob<'_>) -> u64 {
    // A partly covered pixel's centre may lie outside the triangle, where a `SmoothRgb`'s
    // planes may leave [0, 255]: clamped, as the scalar `SpanColor::at` does.
    let color = *job.narrow.target.color;
    // SAFETY: the CPU supports this kernel's features (this function's contract).
    with_rgba!(clamped color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        narrow_sample_groups(job, rgba)
    })
}

/// [`shade_narrow_samples`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
unsafe fn narrow_sample_groups(
    job: &mut NarrowSamplesJob<'_>,
    rgba: impl Fn(__m512d, __m512d) -> __m256i,
) -> u64 {
    // The box lies in the buffers, `samples` elements per pixel (checked).
    job.check();
    let (n, offsets) = (job.samples, job.offsets);
    let job = &mut job.narrow;
    let pixels_per_group = 8 / n;
    let pixel = sample_lanes(n, |p, _| p as f64);
    // Each lane's edge values less the group's first pixel centre's: its pixel's columns
    // and its sample's offset.
    let at_lane: [__m512d; 3] = std::array::from_fn(|k| {
        let sample = sample_lanes(n, |_, s| offsets[s][k] as f64);
        _mm512_add_pd(_mm512_mul_pd(pixel, _mm512_set1_pd(job.step_x[k] as f64)), sample)
    });
    // The numerators at each lane's pixel centre less the group's first one's.
    let centre = [1, 2].map(|k| _mm512_mul_pd(pixel, _mm512_set1_pd(job.step_x[k] as f64)));
    // Each lane's edge values and the numerators at its pixel's centre, stepped a group
    // right and a row down in their registers (as `NarrowBox::groups`; integers below 2^53,
    // exact in any order).
    let group_step = job.step_x.map(|s| _mm512_set1_pd((pixels_per_group as i64 * s) as f64));
    let row_step = job.step_y.map(|s| _mm512_set1_pd(s as f64));
    let bias = job.bias.map(|b| _mm512_set1_pd(b as f64));
    let edges = job.edges.map(|e| _mm512_set1_pd(e as f64));
    let mut row: [__m512d; 3] = std::array::from_fn(|k| _mm512_add_pd(edges[k], at_lane[k]));
    let mut row_centre =
        [1, 2].map(|k| _mm512_add_pd(_mm512_sub_pd(edges[k], bias[k - 1]), centre[k - 1]));
    let mut covered = 0u64;
    for r in 0..job.rows {
        let (mut e, mut f) = (row, row_centre);
        for c in (0..job.columns).step_by(pixels_per_group) {
            let lanes = if c + pixels_per_group <= job.columns {
                0xFF
            } else {
                ((1u32 << ((job.columns - c) * n)) - 1) as __mmask8
            };
            let any = _mm512_or_si512(
                _mm512_or_si512(_mm512_castpd_si512(e[0]), _mm512_castpd_si512(e[1])),
                _mm512_castpd_si512(e[2]),
            );
            let cover = !_mm512_movepi64_mask(any) & lanes;
            covered += u64::from(cover.count_ones());
            let z = [_mm512_sub_pd(e[1], bias[0]), _mm512_sub_pd(e[2], bias[1])];
            let [f1, f2] = f;
            let at = n * (job.first + r * job.stride + c);
            // SAFETY: the group's first sample is in the box, so in the buffers, and so
            // are its `lanes` (the box's pixels), a superset of `cover` (checked above).
            unsafe {
                group::<false, false, ANY_DEPTH>(
                    &mut job.target,
                    [at, at],
                    f1,
                    f2,
                    cover,
                    Some(z),
                    &rgba,
                )
            };
            e = std::array::from_fn(|k| _mm512_add_pd(e[k], group_step[k]));
            f = [1, 2].map(|k| _mm512_add_pd(f[k - 1], group_step[k]));
        }
        row = std::array::from_fn(|k| _mm512_add_pd(row[k], row_step[k]));
        row_centre = [1, 2].map(|k| _mm512_add_pd(row_centre[k - 1], row_step[k]));
    }
    covered
}

/// [`super::window_group`] in AVX-512: the per-triangle front end's arithmetic lane by lane.
/// Snapping rounds `x * 256` (exact in `f64`) half to even, as `fixed::snap` does; areas are
/// `i64` lanes (exact, below 2^49), converted to `f64` (rounding to nearest, as `as f64`) for
/// `1 / area2`; pixel bounds are arithmetic shifts (floor divisions by 256).
/// Lanes whose triangle is rejected compute garbage that is never read.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,popcnt,bmi1,bmi2")]
pub(super) unsafe fn window_group(tris: &[[Vertex; 3]; 8], cull: CullMode, out: &mut WindowGroup) {
    let zero = _mm512_setzero_si512();
    let mut finite: __mmask8 = 0xFF;
    let mut in_range: __mmask8 = 0xFF;
    let mut xs = [zero; 3];
    let mut ys = [zero; 3];
    // Each triangle's three vertices, fifteen words (`Vertex` is `repr(C)`, its layout
    // asserted beside it), one row each: word `5 v + f` is field `f` (`x`, `y`, `z`, `inv_w`,
    // then the colour) of vertex `v`. Built lane by lane from 96 scalar loads, they were a
    // third of this function's samples.
    let rows: [__m512i; 8] = std::array::from_fn(|t| {
        // SAFETY: the fifteen words of the mask are the triangle's sixty bytes; the sixteenth
        // is masked off, so nothing past the triangle is read (nor can fault).
        unsafe { _mm512_maskz_loadu_epi32(0x7FFF, tris[t].as_ptr().cast()) }
    });
    let word = transposed(rows);
    for v in 0..3 {
        let field = |f: usize| _mm256_castsi256_ps(word[5 * v + f]);
        let (x, y, zv, w) = (field(0), field(1), field(2), field(3));
        // Finite iff `v - v` is 0 (NaN for NaN and infinities).
        for f in [x, y, zv, w] {
            finite &= _mm256_cmp_ps_mask::<_CMP_EQ_OQ>(_mm256_sub_ps(f, f), _mm256_setzero_ps());
        }
        // Exactly where `fixed::snap` succeeds.
        for f in [x, y] {
            in_range &= _mm256_cmp_ps_mask::<_CMP_GE_OQ>(f, _mm256_set1_ps(fixed::MIN_COORD))
                & _mm256_cmp_ps_mask::<_CMP_LT_OQ>(f, _mm256_set1_ps(fixed::SNAP_LIMIT));
        }
        let snap = |f: __m256| {
            let scaled = _mm512_mul_pd(_mm512_cvtps_pd(f), _mm512_set1_pd(f64::from(fixed::ONE)));
            _mm512_cvt_roundpd_epi64::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(scaled)
        };
        (xs[v], ys[v]) = (snap(x), snap(y));
    }
    // Snapped coordinates in range are within `+-2^23`, so their differences fit in 32 bits
    // and `vpmuldq`'s product of each lane's low halves is exact (one micro-op, where
    // `vpmullq` takes three and three times as long). Lanes out of range are rejected.
    let mul = |a: __m512i, b: __m512i| _mm512_mul_epi32(a, b);
    let sub = |a: __m512i, b: __m512i| _mm512_sub_epi64(a, b);
    let signed =
        sub(mul(sub(xs[1], xs[0]), sub(ys[2], ys[0])), mul(sub(xs[2], xs[0]), sub(ys[1], ys[0])));
    let degenerate = _mm512_cmpeq_epi64_mask(signed, zero);
    let clockwise = _mm512_cmpgt_epi64_mask(signed, zero);
    let culled = match cull {
        CullMode::None => 0,
        CullMode::Clockwise => clockwise,
        CullMode::CounterClockwise => _mm512_cmplt_epi64_mask(signed, zero),
    };
    let area2 = _mm512_abs_epi64(signed);
    let min = |v: [__m512i; 3]| _mm512_min_epi64(_mm512_min_epi64(v[0], v[1]), v[2]);
    let max = |v: [__m512i; 3]| _mm512_max_epi64(_mm512_max_epi64(v[0], v[1]), v[2]);
    let half = i64::from(fixed::HALF);
    // `first_centre_at_or_after(v) = ceil((v - 128) / 256)` and
    // `last_centre_at_or_before(v) = floor((v - 128) / 256)`.
    let first =
        |v: __m512i| _mm512_srai_epi64::<8>(_mm512_add_epi64(v, _mm512_set1_epi64(255 - half)));
    let last = |v: __m512i| _mm512_srai_epi64::<8>(_mm512_sub_epi64(v, _mm512_set1_epi64(half)));
    let bounds = [first(min(xs)), first(min(ys)), last(max(xs)), last(max(ys))];
    let inv_area2 = _mm512_div_pd(_mm512_set1_pd(1.0), _mm512_cvtepi64_pd(area2));
    // SAFETY (the stores below): each destination is an array of eight 64-bit or 32-bit
    // elements, 64 or 32 bytes, written whole by one unaligned store.
    unsafe {
        for v in 0..3 {
            _mm256_storeu_si256(out.x[v].as_mut_ptr().cast(), _mm512_cvtepi64_epi32(xs[v]));
            _mm256_storeu_si256(out.y[v].as_mut_ptr().cast(), _mm512_cvtepi64_epi32(ys[v]));
        }
        _mm512_storeu_si512(out.area2.as_mut_ptr().cast(), area2);
        for (dst, b) in out.bounds.iter_mut().zip(bounds) {
            _mm256_storeu_si256(dst.as_mut_ptr().cast(), _mm512_cvtepi64_epi32(b));
        }
        _mm512_storeu_pd(out.inv_area2.as_mut_ptr(), inv_area2);
    }
    out.clockwise = clockwise;
    out.rejected = super::rejections([finite, in_range, degenerate, culled]);
}

/// [`super::shade_small_eight`] in AVX-512. The covered pixels of the lanes are listed in
/// drawing order (lane by lane, each box row by row, left to right), as `l << 6 | bit` with
/// `bit` the pixel's [`super::SmallEight::inside`] bit, one compress and store per two rows
/// that have any; then each group of eight listed pixels takes its triangles' values from
/// registers of all eight lanes (`vpermd`, `vpermpd`), and its buffers through gathers and
/// scatters.
///
/// # Safety
/// The CPU must support AVX-512 F, VL, DQ and CD.
#[target_feature(enable = "avx512f,avx512vl,avx512dq,avx512cd,avx2,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_small_eight(
    eight: &SmallEight,
    s: &SmallShading,
    lanes: std::ops::Range<usize>,
    target: &mut TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let n = target.depth.len();
    assert!(target.color.len() == n && n <= i32::MAX as usize, "buffers of one length");
    assert!(target.ids.as_ref().is_none_or(|b| b.len() == n), "buffers of one length");
    assert!(target.overdraw.as_ref().is_none_or(|b| b.len() == n), "buffers of one length");
    let stride = target.stride();
    // 64 entries a lane at most, each two rows' stored as sixteen. Left uninitialized (to
    // zero it was a twentieth of the grid's frame): only the entries listed are read, by
    // masked loads.
    let mut entries = [std::mem::MaybeUninit::<i32>::uninit(); 8 * 64 + 16];
    let mut listed = 0;
    let bits = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let mut drawn = 0;
    for l in lanes {
        assert!(l < 8, "eight lanes");
        let mut cells = eight.inside[l] & s.cells[l];
        drawn |= i32::from(cells != 0) << l;
        while cells != 0 {
            // The two rows of the first pixel left.
            let pair = cells.trailing_zeros() & !15;
            let two = (cells >> pair) as u16;
            cells &= !(0xFFFF << pair);
            let tagged = _mm512_or_si512(bits, _mm512_set1_epi32((l as i32) << 6 | pair as i32));
            // Compressed in a register and stored whole: a compressing store to memory is
            // microcoded on AMD's Zen 4, and took over half of this function's time.
            let packed = _mm512_maskz_compress_epi32(two, tagged);
            // SAFETY: sixteen entries from `listed`, which is below 64 l + pair: within
            // `entries`.
            unsafe { _mm512_storeu_si512(entries.as_mut_ptr().add(listed).cast(), packed) };
            listed += two.count_ones() as usize;
        }
    }
    let load = |v: &[i32; 8]| {
        // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
        unsafe { _mm256_loadu_si256(v.as_ptr().cast()) }
    };
    let load_pd = |v: &[f64; 8]| {
        // SAFETY: eight `f64`s, 64 bytes; the load needs no alignment.
        unsafe { _mm512_loadu_pd(v.as_ptr()) }
    };
    // Each box's first pixel, `target.index` in `i32` lanes (each pixel's index is checked
    // before it is read or written, too).
    let first = super::avx2::box_starts(s, target, drawn);
    let edges = [load(&eight.edges[1]), load(&eight.edges[2])];
    let step_x = [load(&eight.step_x[1]), load(&eight.step_x[2])];
    let step_y = [load(&eight.step_y[1]), load(&eight.step_y[2])];
    let bias = [load(&eight.bias[0]), load(&eight.bias[1])];
    let ids_v = load(&s.id);
    let depth = s.depth.each_ref().map(load_pd);
    let table = crate::color::srgb8_table();
    let columns = columns_of(&s.color_rows);
    let stride_v = _mm256_set1_epi32(stride as i32);
    let depth_out = target.depth.as_mut_ptr();
    let color_out = target.color.as_mut_ptr().cast::<i32>();
    let mut g = 0;
    while g < listed {
        let active = (0xFFu32 >> 8usize.saturating_sub(listed - g)) as __mmask8;
        // SAFETY: `g < listed <= 8 * 64`: eight entries from `g` are within `entries`, and
        // those of `active` (below `listed`) are initialized; the others are not read.
        let e = unsafe { _mm256_maskz_loadu_epi32(active, entries.as_ptr().add(g).cast()) };
        let tri = _mm256_srli_epi32::<6>(e);
        let column = _mm256_and_si256(e, _mm256_set1_epi32(7));
        let row = _mm256_and_si256(_mm256_srli_epi32::<3>(e), _mm256_set1_epi32(7));
        let at = _mm256_add_epi32(
            _mm256_add_epi32(_mm256_permutexvar_epi32(tri, first), column),
            _mm256_mullo_epi32(row, stride_v),
        );
        // The group ends before its first pixel that an earlier one shares.
        let shared = _mm256_maskz_conflict_epi32(active, at);
        let clash = _mm256_test_epi32_mask(shared, shared);
        let active =
            if clash == 0 { active } else { active & ((1u8 << clash.trailing_zeros()) - 1) };
        g += active.count_ones() as usize;
        let inside = _mm256_mask_cmplt_epu32_mask(active, at, _mm256_set1_epi32(n as i32));
        assert!(inside == active, "the boxes must lie in the buffers");
        // `E_k + r step_y + c step_x - bias` in `i32` (below 2^25 within the box, as
        // `SmallEight` says), exact in `f64`.
        let numerator = |k: usize| {
            let v = _mm256_add_epi32(
                _mm256_permutexvar_epi32(tri, edges[k]),
                _mm256_mullo_epi32(row, _mm256_permutexvar_epi32(tri, step_y[k])),
            );
            let v = _mm256_add_epi32(
                v,
                _mm256_mullo_epi32(column, _mm256_permutexvar_epi32(tri, step_x[k])),
            );
            _mm512_cvtepi32_pd(_mm256_sub_epi32(v, _mm256_permutexvar_epi32(tri, bias[k])))
        };
        let (f1, f2) = (numerator(0), numerator(1));
        let tri64 = _mm512_cvtepu32_epi64(tri);
        let coefficient = |k: usize| _mm512_permutexvar_pd(tri64, depth[k]);
        let z = _mm512_add_pd(
            _mm512_add_pd(coefficient(0), _mm512_mul_pd(f1, coefficient(1))),
            _mm512_mul_pd(f2, coefficient(2)),
        );
        let z = _mm512_cvtpd_ps(z);
        let z = _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z));
        // SAFETY (every gather and scatter below): each lane of `active` holds an index below
        // `n` (asserted above), the length of every buffer, and no two share one; `f32`,
        // `i32` and `[u8; 4]` are four bytes.
        let pass = unsafe {
            if let Some(o) = target.overdraw.as_deref_mut() {
                let o = o.as_mut_ptr().cast::<i32>();
                let counts =
                    _mm256_mmask_i32gather_epi32::<4>(_mm256_setzero_si256(), active, at, o);
                let counts = _mm256_add_epi32(counts, _mm256_set1_epi32(1));
                _mm256_mask_i32scatter_epi32::<4>(o, active, at, counts);
            }
            let stored = _mm256_mmask_i32gather_ps::<4>(_mm256_setzero_ps(), active, at, depth_out);
            let pass = match depth_test {
                DepthTest::Less => _mm256_mask_cmp_ps_mask::<_CMP_LT_OQ>(active, z, stored),
                DepthTest::LessEqual => _mm256_mask_cmp_ps_mask::<_CMP_LE_OQ>(active, z, stored),
                DepthTest::Always => active,
            };
            _mm256_mask_i32scatter_ps::<4>(depth_out, pass, at, z);
            if let Some(ids) = target.ids.as_deref_mut() {
                let id = _mm256_permutexvar_epi32(tri, ids_v);
                _mm256_mask_i32scatter_epi32::<4>(ids.as_mut_ptr(), pass, at, id);
            }
            pass
        };
        if pass == 0 {
            continue;
        }
        let rgba = small_colors(s, (table, &columns), tri, (f1, f2), pass);
        // SAFETY: as above.
        unsafe { _mm256_mask_i32scatter_epi32::<4>(color_out, pass, at, rgba) };
    }
    listed as u64
}

/// The colours of a group of [`shade_small_eight`] at barycentric numerators `f1`, `f2`, lane
/// `i` of triangle `tri[i]`, as [`perspective`] computes one triangle's (the lanes of `pass`
/// matter; the others compute from leftovers).
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx2,popcnt,bmi1,bmi2")]
fn small_colors(
    s: &SmallShading,
    (table, columns): (&[u32; ENCODE_BUCKETS], &[__m256; 16]),
    tri: __m256i,
    (f1, f2): (__m512d, __m512d),
    pass: __mmask8,
) -> __m256i {
    let tri64 = _mm512_cvtepu32_epi64(tri);
    let lanes_pd = |v: &[f64; 8]| {
        // SAFETY: eight `f64`s, 64 bytes; the load needs no alignment.
        _mm512_permutexvar_pd(tri64, unsafe { _mm512_loadu_pd(v.as_ptr()) })
    };
    let lanes_ps = |column: usize| _mm256_permutexvar_ps(tri, columns[column]);
    let lanes_i32 = |v: &[i32; 8]| {
        // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
        _mm256_permutexvar_epi32(tri, unsafe { _mm256_loadu_si256(v.as_ptr().cast()) })
    };
    // `crate::pipeline::perspective_weights`, lane by lane affine or divided.
    let inv_area2 = lanes_pd(&s.inv_area2);
    let (l1, l2) = (_mm512_mul_pd(f1, inv_area2), _mm512_mul_pd(f2, inv_area2));
    let l0 = _mm512_sub_pd(_mm512_sub_pd(_mm512_set1_pd(1.0), l1), l2);
    let mut w = [_mm512_cvtpd_ps(l0), _mm512_cvtpd_ps(l1), _mm512_cvtpd_ps(l2)];
    let affine = lanes_i32(&s.affine);
    let affine = _mm256_test_epi32_mask(affine, affine);
    if pass & !affine != 0 {
        let w0 = _mm512_mul_pd(l0, lanes_pd(&s.inv_w[0]));
        let w1 = _mm512_mul_pd(l1, lanes_pd(&s.inv_w[1]));
        let w2 = _mm512_mul_pd(l2, lanes_pd(&s.inv_w[2]));
        let sum = _mm512_add_pd(_mm512_add_pd(w0, w1), w2);
        // `sum > 0`, false for NaN: thirds elsewhere.
        let positive = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(sum, _mm512_setzero_pd());
        let third = _mm256_set1_ps(1.0 / 3.0);
        let divided = |v: __m512d| {
            _mm256_mask_blend_ps(positive, third, _mm512_cvtpd_ps(_mm512_div_pd(v, sum)))
        };
        w = [
            _mm256_mask_blend_ps(affine, divided(w0), w[0]),
            _mm256_mask_blend_ps(affine, divided(w1), w[1]),
            _mm256_mask_blend_ps(affine, divided(w2), w[2]),
        ];
    }
    // Channel `ch`: `(c0 w0 + c1 w1 + c2 w2) scale`, left to right.
    let channel = |ch: usize| {
        let c = |k: usize| lanes_ps(4 * k + ch);
        let t = _mm256_add_ps(_mm256_mul_ps(c(0), w[0]), _mm256_mul_ps(c(1), w[1]));
        let t = _mm256_add_ps(t, _mm256_mul_ps(c(2), w[2]));
        _mm256_mul_ps(t, lanes_ps(12 + ch))
    };
    let r = super::avx2::srgb8(channel(0), table);
    let g = super::avx2::srgb8(channel(1), table);
    let b = super::avx2::srgb8(channel(2), table);
    let fixed = lanes_i32(&s.alpha);
    let weighted = _mm256_mask_cmplt_epi32_mask(pass, fixed, _mm256_setzero_si256());
    let alpha = if weighted == 0 {
        fixed
    } else {
        _mm256_mask_blend_epi32(weighted, fixed, super::avx2::unorm8(channel(3)))
    };
    _mm256_or_si256(
        _mm256_or_si256(r, _mm256_slli_epi32::<8>(g)),
        _mm256_or_si256(_mm256_slli_epi32::<16>(b), _mm256_slli_epi32::<24>(alpha)),
    )
}

/// The sixteen columns of eight rows of sixteen `f32`: lane `l` of column `c` is `rows[l][c]`.
/// Pairs of rows interleaved, then pairs of pairs, each 128-bit lane then holding four rows of
/// one column, which the last shuffles put side by side (as `narrow_eight` transposes words).
#[inline]
#[target_feature(enable = "avx512f,avx512dq,popcnt,bmi1,bmi2")]
fn columns_of(rows: &[[f32; 16]; 8]) -> [__m256; 16] {
    // SAFETY: each load reads one row, sixteen `f32`s (64 bytes); it needs no alignment.
    let r: [__m512; 8] = std::array::from_fn(|l| unsafe { _mm512_loadu_ps(rows[l].as_ptr()) });
    // `t[2p]`, `t[2p + 1]`: rows `2p` and `2p + 1` interleaved, low and high halves of each
    // 128-bit lane.
    let t: [__m512d; 8] = std::array::from_fn(|k| {
        let (a, b) = (r[k & !1], r[k | 1]);
        let v = if k % 2 == 0 { _mm512_unpacklo_ps(a, b) } else { _mm512_unpackhi_ps(a, b) };
        _mm512_castps_pd(v)
    });
    // `u[4h + i]`: in 128-bit lane `j`, rows `4h..4h + 4` of column `4j + i`.
    let u: [__m512; 8] = std::array::from_fn(|k| {
        let (h, i) = (k / 4, k % 4);
        let (a, b) = (t[4 * h + i / 2], t[4 * h + 2 + i / 2]);
        let v = if i % 2 == 0 { _mm512_unpacklo_pd(a, b) } else { _mm512_unpackhi_pd(a, b) };
        _mm512_castpd_ps(v)
    });
    let mut out = [_mm256_setzero_ps(); 16];
    for i in 0..4 {
        let (a, b) = (u[i], u[4 + i]);
        // [a.0, b.0, a.1, b.1]: columns `i` and `4 + i`; then columns `8 + i` and `12 + i`.
        let lo = _mm512_shuffle_f32x4::<0b01_00_01_00>(a, b);
        let lo = _mm512_shuffle_f32x4::<0b11_01_10_00>(lo, lo);
        let hi = _mm512_shuffle_f32x4::<0b11_10_11_10>(a, b);
        let hi = _mm512_shuffle_f32x4::<0b11_01_10_00>(hi, hi);
        out[i] = _mm512_castps512_ps256(lo);
        out[4 + i] = _mm512_extractf32x8_ps::<1>(lo);
        out[8 + i] = _mm512_castps512_ps256(hi);
        out[12 + i] = _mm512_extractf32x8_ps::<1>(hi);
    }
    out
}
