//! The AVX-512 shading kernels: eight pixels per step, the numerators and planes in `f64`
//! lanes of one 512-bit register, depth, colour and ids in eight 32-bit lanes, coverage and
//! the depth test in mask registers. Masked loads and stores touch only the lanes a mask
//! enables (and raise no fault for the others), so a narrow triangle's row is one group
//! whatever its width, a span's tail is one masked group, and no pixel outside the triangle
//! is read or written: the AVX2 kernels' read-blend-write of whole groups, and the scalar
//! fallbacks at the buffers' ends, are not needed here.
//!
//! The arithmetic is the AVX2 kernels' (and so the scalar code's) lane by lane: separate
//! multiplies and adds, conversions in the default rounding mode, clamps with the constant
//! first.

use std::arch::x86_64::*;

use super::{KernelTarget, NarrowJob, SpanColor, SpanJob};
use crate::shade::DepthTest;

/// Eight lanes of `(a0 + f1 * g1) + f2 * g2`.
#[inline]
#[target_feature(enable = "avx512f")]
fn plane(p: [f64; 3], f1: __m512d, f2: __m512d) -> __m512d {
    let t = _mm512_add_pd(_mm512_set1_pd(p[0]), _mm512_mul_pd(f1, _mm512_set1_pd(p[1])));
    _mm512_add_pd(t, _mm512_mul_pd(f2, _mm512_set1_pd(p[2])))
}

/// `quantize_channel` on eight lanes, as the AVX2 `quantize`: `max(v, 0)` maps NaN to 0, the
/// conversion rounds half to even.
#[inline]
#[target_feature(enable = "avx512f")]
fn quantize(v: __m512d) -> __m256i {
    let v = _mm512_min_pd(_mm512_set1_pd(255.0), _mm512_max_pd(v, _mm512_setzero_pd()));
    _mm512_cvtpd_epi32(v)
}

/// Eight lanes of RGBA8 from planes (see the AVX2 `smooth`).
#[inline]
#[target_feature(enable = "avx512f")]
fn smooth<const CLAMP: bool>(
    p: &[[f64; 3]],
    alpha: Option<u8>,
    f1: __m512d,
    f2: __m512d,
) -> __m256i {
    let channel = |p: [f64; 3]| {
        let v = plane(p, f1, f2);
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

/// The eight pixels at `at` whose bits in `cover` are set, with barycentric numerators `f1`,
/// `f2`: overdraw, depth test and writes, as `KernelTarget::pixel` does lane by lane. With
/// `SKIP_HIDDEN`, no colour is computed when no lane passes the depth test.
///
/// # Safety
/// The CPU must support AVX-512 F and VL; `at` must be at most `t.checked_len()`, and every
/// lane set in `cover` must lie below it.
#[inline]
#[target_feature(enable = "avx512f,avx512vl")]
unsafe fn group<const SKIP_HIDDEN: bool>(
    t: &mut KernelTarget<'_>,
    at: usize,
    f1: __m512d,
    f2: __m512d,
    cover: __mmask8,
    rgba: impl Fn(__m512d, __m512d) -> __m256i,
) {
    // SAFETY (every pointer access in this block): `at` is within every buffer or one past
    // its end (they all hold `checked_len()` elements), so the offset pointers stay in their
    // allocations; the masked loads and stores access only lanes set in `cover` (or in
    // `pass`, a subset), which the caller guarantees lie in the buffers, and suppress the
    // others entirely; they need no alignment. `[u8; 4]` is four bytes, one i32 lane.
    unsafe {
        if let Some(o) = t.overdraw.as_deref_mut() {
            let p = o.as_mut_ptr().add(at).cast::<i32>();
            let counts = _mm256_maskz_loadu_epi32(cover, p);
            _mm256_mask_storeu_epi32(p, cover, _mm256_add_epi32(counts, _mm256_set1_epi32(1)));
        }
        let z = _mm512_cvtpd_ps(plane(t.depth_plane, f1, f2));
        let z = _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z));
        let dp = t.depth.as_mut_ptr().add(at);
        let stored = _mm256_maskz_loadu_ps(cover, dp);
        let pass = match t.depth_test {
            DepthTest::Less => _mm256_mask_cmp_ps_mask::<_CMP_LT_OQ>(cover, z, stored),
            DepthTest::LessEqual => _mm256_mask_cmp_ps_mask::<_CMP_LE_OQ>(cover, z, stored),
            DepthTest::Always => cover,
        };
        if SKIP_HIDDEN && pass == 0 {
            return;
        }
        _mm256_mask_storeu_ps(dp, pass, z);
        let cp = t.color_out.as_mut_ptr().add(at).cast::<i32>();
        _mm256_mask_storeu_epi32(cp, pass, rgba(f1, f2));
        if let Some(ids) = t.ids.as_deref_mut() {
            _mm256_mask_storeu_epi32(ids.as_mut_ptr().add(at), pass, _mm256_set1_epi32(t.id));
        }
    }
}

/// The lanes `0..8` as `f64`.
#[inline]
#[target_feature(enable = "avx512f")]
fn lanes() -> __m512d {
    _mm512_setr_pd(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0)
}

/// [`super::shade_narrow`] in AVX-512: each row of the box is one group of eight lanes, the
/// box's columns and the triangle's coverage (the sign bits of `e0 | e1 | e2`, stepped
/// exactly in `f64` as in the AVX2 kernel) one mask. No branches on coverage or depth.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
pub(super) unsafe fn shade_narrow(job: &mut NarrowJob<'_>) -> u64 {
    // SAFETY: the CPU supports AVX-512 F, VL and DQ (this function's contract).
    with_rgba!(job.target.color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        narrow_rows(job, rgba)
    })
}

/// [`shade_narrow`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F, VL and DQ.
#[inline]
#[target_feature(enable = "avx512f,avx512vl,avx512dq")]
unsafe fn narrow_rows(job: &mut NarrowJob<'_>, rgba: impl Fn(__m512d, __m512d) -> __m256i) -> u64 {
    let n = job.target.checked_len();
    assert!((1..=super::NARROW_COLUMNS).contains(&job.columns) && job.rows > 0, "not narrow");
    assert!(
        job.first + (job.rows - 1) * job.stride + job.columns <= n,
        "the box must lie in the buffers"
    );
    let offsets: [__m512d; 3] =
        std::array::from_fn(|k| _mm512_mul_pd(lanes(), _mm512_set1_pd(job.step_x[k] as f64)));
    let columns = ((1u32 << job.columns) - 1) as __mmask8;
    let bias = job.bias.map(|b| _mm512_set1_pd(b as f64));
    let mut row = job.edges.map(|e| e as f64);
    let step_y = job.step_y.map(|s| s as f64);
    let mut covered = 0u64;
    for r in 0..job.rows {
        let e: [__m512d; 3] =
            std::array::from_fn(|k| _mm512_add_pd(_mm512_set1_pd(row[k]), offsets[k]));
        let any = _mm512_or_si512(
            _mm512_or_si512(_mm512_castpd_si512(e[0]), _mm512_castpd_si512(e[1])),
            _mm512_castpd_si512(e[2]),
        );
        let cover = !_mm512_movepi64_mask(any) & columns;
        covered += u64::from(cover.count_ones());
        let (f1, f2) = (_mm512_sub_pd(e[1], bias[0]), _mm512_sub_pd(e[2], bias[1]));
        // SAFETY: the row's first pixel is in the buffers and so are its `columns` lanes, a
        // superset of `cover` (asserted above).
        unsafe {
            group::<false>(&mut job.target, job.first + r * job.stride, f1, f2, cover, &rgba)
        };
        row = std::array::from_fn(|k| row[k] + step_y[k]);
    }
    covered
}

/// [`super::shade_span`] in AVX-512: eight pixels per step, the last `n % 8` as one masked
/// group.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[target_feature(enable = "avx512f,avx512vl")]
pub(super) unsafe fn shade_span(job: &mut SpanJob<'_>) {
    // SAFETY: the CPU supports AVX-512 F and VL (this function's contract).
    with_rgba!(job.target.color, __m512d, _mm256_set1_epi32, smooth, rgba => unsafe {
        span_groups(job, rgba)
    })
}

/// [`shade_span`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX-512 F and VL.
#[inline]
#[target_feature(enable = "avx512f,avx512vl")]
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
        unsafe { group::<true>(&mut job.target, k, f1, f2, 0xFF, &rgba) };
        f1 = _mm512_add_pd(f1, step1);
        f2 = _mm512_add_pd(f2, step2);
        k += 8;
    }
    if k < n {
        let tail = ((1u32 << (n - k)) - 1) as __mmask8;
        // SAFETY: `k < n` and the lanes of `tail` are `k..n`.
        unsafe { group::<true>(&mut job.target, k, f1, f2, tail, &rgba) };
    }
}
