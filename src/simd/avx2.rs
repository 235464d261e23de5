//! The AVX2 kernels: four pixels (or eight vertices, eight triangles) per step.

use std::arch::x86_64::*;

use glam::Vec4;

use super::{
    Corner, CornerGroup, CornerTests, EdgeValues, KernelTarget, NarrowBox, NarrowEight, NarrowJob,
    NarrowSamplesJob, PerspectiveColor, SampleSpanJob, SimdLevel, SmallEight, SmallLane,
    SmallShading, SpanColor, SpanJob, WindowGroup,
};
use crate::clip::MIN_W;
use crate::color::ENCODE_BUCKETS;
use crate::fixed;
use crate::render::WindowRecord;
use crate::sample::{MAX_SAMPLES, SampleCount};
use crate::setup::{CullMode, PixelRect, Vertex};
use crate::shade::DepthTest;
use crate::target::TargetBand;

/// [`super::corner_tests`] for eight triangles at once: areas in two halves of four
/// `i64` lanes (corner differences are below 2^24, so products are exact), boxes and
/// their first and last pixel centres in eight `i32` lanes (`ceil((v - 128) / 256)` is
/// `(v + 127) >> 8`, `floor((v - 128) / 256)` is `(v - 128) >> 8`, arithmetic shifts).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn corner_tests(
    group: &CornerGroup,
    cull: CullMode,
    clip: &PixelRect,
    samples: SampleCount,
) -> CornerTests {
    // Element by element: the rows were just written by 4-byte stores, which a 32-byte
    // load cannot take from the store buffer (it would wait for them to reach the cache).
    let row = |r: &[i32; 8]| _mm256_setr_epi32(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]);
    let x = [row(&group.x[0]), row(&group.x[1]), row(&group.x[2])];
    let y = [row(&group.y[0]), row(&group.y[1]), row(&group.y[2])];
    tests(x, y, cull, clip, samples)
}

/// [`super::corner_tests_indexed`]: each corner read from the window as one 8-byte
/// `[x, y]` straight into a vector (memory written long before, so no store-forwarding
/// wait), four triangles' pairs per half, then split into rows of x and of y.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn corner_tests_indexed(
    tris: &[[u32; 3]; 8],
    window: &[Corner],
    base: u32,
    (cull, clip, samples): (CullMode, &PixelRect, SampleCount),
    rows: &mut CornerGroup,
) -> CornerTests {
    let (x, y) = corner_rows(tris, window, base);
    for v in 0..3 {
        // SAFETY: eight `i32`s, 32 bytes, each; the stores need no alignment.
        unsafe {
            _mm256_storeu_si256(rows.x[v].as_mut_ptr().cast(), x[v]);
            _mm256_storeu_si256(rows.y[v].as_mut_ptr().cast(), y[v]);
        }
    }
    tests(x, y, cull, clip, samples)
}

/// The corners of eight triangles of an index buffer (`window[i - base]` for index `i`) in
/// rows: `x[v]`, `y[v]` hold corner `v`'s coordinates, lane `k` triangle `k`'s. Each corner
/// is read as one 8-byte load straight into a vector.
///
/// # Panics
/// If an index minus `base` falls outside the window.
#[inline]
#[target_feature(enable = "avx2")]
fn corner_rows(tris: &[[u32; 3]; 8], window: &[Corner], base: u32) -> ([__m256i; 3], [__m256i; 3]) {
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
    (x, y)
}

/// [`super::small_run_geometry`]: the corners' rows loaded whole, the setup's integers in
/// `i32` lanes (twice the area of a triangle whose box is at most 8 x 8 pixels, its vertices
/// within 9 * 256 units of each other, stays below 2^23; lanes outside `mask` may wrap, and
/// are dropped, as are lanes refused before their areas are used), `1 / area2` in two `f64`
/// halves, and the coverage as [`small_eight`] computes it. With a `reach` (a 4x target's,
/// [`super::small_run_samples_geometry`]), the boxes are those of the samples, the pixel
/// centres' coverage then to be replaced by the samples' ([`small_samples`]).
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn small_run_geometry(
    rows: &CornerGroup,
    (mask, reach): (u8, i32),
    clip: &PixelRect,
    eight: &mut SmallEight,
    shading: &mut SmallShading,
) -> Option<[usize; 2]> {
    // SAFETY: eight `i32`s, 32 bytes, each; the loads need no alignment.
    let row = |r: &[i32; 8]| unsafe { _mm256_loadu_si256(r.as_ptr().cast()) };
    let (x, y) = (rows.x.each_ref().map(row), rows.y.each_ref().map(row));
    let lanes = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let mask =
        _mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(i32::from(mask)), lanes), lanes);
    // The boxes, and within the clip rectangle.
    let b = eight_boxes_reaching([x[0], y[0], x[1], y[1], x[2], y[2]], clip, reach);
    let most = _mm256_set1_epi32(super::SMALL_BOX - 1);
    let large =
        _mm256_or_si256(_mm256_cmpgt_epi32(b.width, most), _mm256_cmpgt_epi32(b.height, most));
    let one = _mm256_set1_epi32(1);
    let empty =
        _mm256_or_si256(_mm256_cmpgt_epi32(one, b.columns), _mm256_cmpgt_epi32(one, b.rows));
    let refused = _mm256_and_si256(_mm256_or_si256(large, empty), mask);
    if _mm256_movemask_ps(_mm256_castsi256_ps(refused)) != 0 {
        return None;
    }
    let (rx0, ry0) = (b.px0, b.py0);
    // Columns and rows of each box (1 outside `mask`), and the largest of each.
    let columns = _mm256_blendv_epi8(one, b.columns, mask);
    let rows = _mm256_blendv_epi8(one, b.rows, mask);
    let largest = |v: __m256i| {
        let v = _mm256_max_epi32(v, _mm256_permute2x128_si256::<0x01>(v, v));
        let v = _mm256_max_epi32(v, _mm256_shuffle_epi32::<0b01_00_11_10>(v));
        let v = _mm256_max_epi32(v, _mm256_shuffle_epi32::<0b10_11_00_01>(v));
        _mm256_cvtsi256_si32(v) as usize
    };
    let span = [largest(columns), largest(rows)];
    // Twice the signed area, `(x1 - x0)(y2 - y0) - (x2 - x0)(y1 - y0)`: clockwise when
    // positive, its magnitude `area2`.
    let area = _mm256_sub_epi32(
        _mm256_mullo_epi32(_mm256_sub_epi32(x[1], x[0]), _mm256_sub_epi32(y[2], y[0])),
        _mm256_mullo_epi32(_mm256_sub_epi32(x[2], x[0]), _mm256_sub_epi32(y[1], y[0])),
    );
    let clockwise = _mm256_cmpgt_epi32(area, _mm256_setzero_si256());
    // 1 where clockwise, else -1.
    let sign = _mm256_or_si256(_mm256_xor_si256(clockwise, _mm256_set1_epi32(-1)), one);
    small_eight_rows((x, y, sign), [rx0, ry0], span, eight);
    // `1 / area2`, as `1.0 / area2 as f64`.
    let area2 = _mm256_abs_epi32(area);
    let inverse = |v: __m128i| _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_cvtepi32_pd(v));
    let put_i32 = |out: &mut [i32; 8], v: __m256i| {
        // SAFETY: eight `i32`s, 32 bytes; the store needs no alignment.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), v) }
    };
    // SAFETY: eight `f64`s, 64 bytes, in two stores of 32; they need no alignment.
    unsafe {
        let out = shading.inv_area2.as_mut_ptr();
        _mm256_storeu_pd(out, inverse(_mm256_castsi256_si128(area2)));
        _mm256_storeu_pd(out.add(4), inverse(_mm256_extracti128_si256::<1>(area2)));
    }
    put_i32(&mut shading.x0, rx0);
    put_i32(&mut shading.y0, ry0);
    // Each box's pixels (`SmallShading::set`): a row's `columns` bits in each of its `rows`
    // bytes; none outside `mask`. As `u64`s, four lanes at a time: the row's bits (below
    // 2^8) times 0x0101_0101 repeat them in the low four bytes, shifted up into the high
    // four, then cut to the rows.
    let row = _mm256_sub_epi32(_mm256_sllv_epi32(one, columns), one);
    let row = _mm256_and_si256(row, mask);
    let cells = |row: __m128i, rows: __m128i| {
        let row = _mm256_mul_epu32(_mm256_cvtepu32_epi64(row), _mm256_set1_epi64x(0x0101_0101));
        let row = _mm256_or_si256(row, _mm256_slli_epi64::<32>(row));
        let cut = _mm256_sub_epi64(
            _mm256_set1_epi64x(64),
            _mm256_slli_epi64::<3>(_mm256_cvtepu32_epi64(rows)),
        );
        _mm256_and_si256(row, _mm256_srlv_epi64(_mm256_set1_epi64x(-1), cut))
    };
    let half = |v: __m256i, high: bool| {
        if high { _mm256_extracti128_si256::<1>(v) } else { _mm256_castsi256_si128(v) }
    };
    // SAFETY: eight `u64`s, 64 bytes, in two stores of 32; they need no alignment.
    unsafe {
        let out = shading.cells.as_mut_ptr();
        _mm256_storeu_si256(out.cast(), cells(half(row, false), half(rows, false)));
        _mm256_storeu_si256(out.add(4).cast(), cells(half(row, true), half(rows, true)));
    }
    Some(span)
}

/// The corner tests on eight triangles' corners in rows (`x[v]`: corner `v`'s x).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn tests(
    x: [__m256i; 3],
    y: [__m256i; 3],
    cull: CullMode,
    clip: &PixelRect,
    samples: SampleCount,
) -> CornerTests {
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
    // For each sample position, the first and last pixels whose sample at that position
    // lies in the box, clipped: empty for every position, the box holds no sample. (Offsets
    // are below 128 and the corners at most 2^23 in magnitude: no overflow; lanes with an
    // `OUTSIDE` corner wrap, and are masked off.)
    let min3 = |a, b, c| _mm256_min_epi32(_mm256_min_epi32(a, b), c);
    let max3 = |a, b, c| _mm256_max_epi32(_mm256_max_epi32(a, b), c);
    let first = |v, o: i32| _mm256_srai_epi32::<8>(_mm256_add_epi32(v, _mm256_set1_epi32(127 - o)));
    let last = |v, o: i32| _mm256_srai_epi32::<8>(_mm256_sub_epi32(v, _mm256_set1_epi32(128 + o)));
    let (lo, hi) = ([min3(x0, x1, x2), min3(y0, y1, y2)], [max3(x0, x1, x2), max3(y0, y1, y2)]);
    let none_at = |ox: i32, oy: i32| {
        let px0 = _mm256_max_epi32(first(lo[0], ox), _mm256_set1_epi32(clip.x0));
        let px1 = _mm256_min_epi32(last(hi[0], ox), _mm256_set1_epi32(clip.x1));
        let py0 = _mm256_max_epi32(first(lo[1], oy), _mm256_set1_epi32(clip.y0));
        let py1 = _mm256_min_epi32(last(hi[1], oy), _mm256_set1_epi32(clip.y1));
        _mm256_or_si256(_mm256_cmpgt_epi32(px0, px1), _mm256_cmpgt_epi32(py0, py1))
    };
    // At 1x, the centre's test alone, with its offsets known (the dense scene's front end).
    let empty = match samples {
        SampleCount::X1 => none_at(0, 0),
        _ => samples.pattern().iter().fold(_mm256_set1_epi32(-1), |empty, &[ox, oy]| {
            _mm256_and_si256(empty, none_at(16 * ox, 16 * oy))
        }),
    };
    let empty = _mm256_movemask_ps(_mm256_castsi256_ps(empty)) as u8;
    let degenerate = zero & lanes;
    let culled = match cull {
        CullMode::None => 0,
        CullMode::Clockwise => positive,
        CullMode::CounterClockwise => negative,
    } & lanes;
    CornerTests { inside: lanes, degenerate, culled, empty: empty & lanes & !degenerate & !culled }
}

/// [`super::window_corner`] of eight positions, from their [`WindowLanes`].
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn window_corners(p: &[Vec4; 8], guard: [f32; 2], half: [f32; 2]) -> [Corner; 8] {
    let w = window_lanes(p, guard, half);
    let outside = w.planes[1..].iter().fold(w.planes[0], |a, &b| _mm256_or_ps(a, b));
    let valid = _mm256_castps_si256(_mm256_and_ps(_mm256_andnot_ps(outside, w.finite), w.snaps));
    let min = _mm256_set1_epi32(i32::MIN);
    let sx = _mm256_blendv_epi8(min, w.x, valid);
    let sy = _mm256_blendv_epi8(min, w.y, valid);
    let mut xs = [0i32; 8];
    let mut ys = [0i32; 8];
    // SAFETY: each array holds eight i32 (32 bytes); unaligned stores need no alignment.
    unsafe {
        _mm256_storeu_si256(xs.as_mut_ptr() as *mut __m256i, sx);
        _mm256_storeu_si256(ys.as_mut_ptr() as *mut __m256i, sy);
    }
    std::array::from_fn(|k| [xs[k], ys[k]])
}

/// [`super::window_vertices`] in AVX2: the lanes of [`window_corners`], each plane's test
/// a bit of the outcode.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn window_vertices(
    p: &[Vec4; 8],
    guard: [f32; 2],
    half: [f32; 2],
) -> super::WindowVertices {
    let w = window_lanes(p, guard, half);
    // Bit `i` where plane `i` has the vertex outside; every bit for a position not finite.
    let mut code = _mm256_setzero_si256();
    for (i, plane) in w.planes.iter().enumerate() {
        let bit = _mm256_and_si256(_mm256_castps_si256(*plane), _mm256_set1_epi32(1 << i));
        code = _mm256_or_si256(code, bit);
    }
    let every = _mm256_set1_epi32((1 << w.planes.len()) - 1);
    let code = _mm256_blendv_epi8(every, code, _mm256_castps_si256(w.finite));
    let inside = _mm256_cmpeq_epi32(code, _mm256_setzero_si256());
    let valid = _mm256_and_si256(inside, _mm256_castps_si256(w.snaps));
    let keep = |v: __m256i| _mm256_and_si256(v, valid);
    let keep_ps = |v: __m256| _mm256_and_ps(v, _mm256_castsi256_ps(valid));
    let mut out = super::WindowVertices::default();
    let (mut codes, mut xs, mut ys) = ([0i32; 8], [0i32; 8], [0i32; 8]);
    // SAFETY: each array holds eight 4-byte values (32 bytes); unaligned stores need no
    // alignment.
    unsafe {
        _mm256_storeu_si256(codes.as_mut_ptr().cast(), code);
        _mm256_storeu_si256(xs.as_mut_ptr().cast(), keep(w.x));
        _mm256_storeu_si256(ys.as_mut_ptr().cast(), keep(w.y));
        _mm256_storeu_ps(out.z.as_mut_ptr(), keep_ps(w.z));
        _mm256_storeu_ps(out.inv_w.as_mut_ptr(), keep_ps(w.inv_w));
    }
    out.outcode = codes.map(|c| c as u8);
    out.xy = std::array::from_fn(|k| [xs[k], ys[k]]);
    out.snapped = _mm256_movemask_ps(_mm256_castsi256_ps(valid)) as u8;
    out
}

/// Eight clip-space positions through the front end's per-vertex arithmetic, lane by lane
/// as the scalar code computes each: [`ClipVolume::outcode`]'s plane tests,
/// [`crate::pipeline::Viewport::map`] and [`fixed::snap`] of `x` and `y`.
struct WindowLanes {
    /// Lanes outside each plane, in `ClipVolume::distance`'s order.
    planes: [__m256; 7],
    /// Lanes whose four coordinates are finite.
    finite: __m256,
    /// Lanes whose window `x` and `y` snap and whose depth and `1 / w` are finite.
    snaps: __m256,
    /// Snapped window `x` and `y` (where `snaps`).
    x: __m256i,
    y: __m256i,
    /// Window depth and `1 / w`.
    z: __m256,
    inv_w: __m256,
}

/// [`WindowLanes`] of eight positions (`guard`: the clip volume's guard band, `half`: the
/// viewport's half size): the same `f32` operations lane by lane (distances to the clip
/// planes, `1 / w`, the viewport, no fused multiply-adds), and the snap as a
/// round-half-even of `x * 256` in `f32`, which is exact: `x * 256` is (a power of two
/// scale) and, within the range, so is its rounding to an integer below 2^23.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn window_lanes(p: &[Vec4; 8], guard: [f32; 2], half: [f32; 2]) -> WindowLanes {
    let lane = |c: usize| {
        _mm256_setr_ps(p[0][c], p[1][c], p[2][c], p[3][c], p[4][c], p[5][c], p[6][c], p[7][c])
    };
    let (x, y, z, w) = (lane(0), lane(1), lane(2), lane(3));
    let zero = _mm256_setzero_ps();
    let lt = |a, b| _mm256_cmp_ps::<_CMP_LT_OQ>(a, b);
    let and = |a, b| _mm256_and_ps(a, b);
    // Finite: |v| < inf (false for NaN).
    let inf = _mm256_set1_ps(f32::INFINITY);
    let abs = |v| _mm256_andnot_ps(_mm256_set1_ps(-0.0), v);
    let finite = |v| lt(abs(v), inf);
    let all_finite = and(and(finite(x), finite(y)), and(finite(z), finite(w)));
    // Outside a plane: the distances of `ClipVolume::distance`, each `< 0`.
    let (gx, gy) = (_mm256_mul_ps(_mm256_set1_ps(guard[0]), w), {
        _mm256_mul_ps(_mm256_set1_ps(guard[1]), w)
    });
    let planes = [
        lt(z, zero),
        lt(_mm256_sub_ps(w, z), zero),
        lt(_mm256_sub_ps(w, _mm256_set1_ps(MIN_W)), zero),
        lt(_mm256_add_ps(x, gx), zero),
        lt(_mm256_sub_ps(gx, x), zero),
        lt(_mm256_add_ps(y, gy), zero),
        lt(_mm256_sub_ps(gy, y), zero),
    ];
    // `Viewport::map`.
    let one = _mm256_set1_ps(1.0);
    let inv_w = _mm256_div_ps(one, w);
    let wx = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(x, inv_w), one), _mm256_set1_ps(half[0]));
    let wy = _mm256_mul_ps(_mm256_sub_ps(one, _mm256_mul_ps(y, inv_w)), _mm256_set1_ps(half[1]));
    let wz = _mm256_mul_ps(z, inv_w);
    // `fixed::snap`: in [MIN_COORD, MAX_COORD), and the rounded value below 2^23.
    let snap = |v: __m256| {
        let in_range = and(
            _mm256_cmp_ps::<_CMP_GE_OQ>(v, _mm256_set1_ps(fixed::MIN_COORD)),
            lt(v, _mm256_set1_ps(fixed::MAX_COORD)),
        );
        let scaled = _mm256_mul_ps(v, _mm256_set1_ps(fixed::ONE as f32));
        let rounded = _mm256_round_ps::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(scaled);
        let limit = _mm256_set1_ps(fixed::MAX_COORD * fixed::ONE as f32);
        (and(in_range, lt(rounded, limit)), _mm256_cvtps_epi32(rounded))
    };
    let (x_ok, sx) = snap(wx);
    let (y_ok, sy) = snap(wy);
    let snaps = and(and(x_ok, y_ok), and(finite(wz), finite(inv_w)));
    WindowLanes { planes, finite: all_finite, snaps, x: sx, y: sy, z: wz, inv_w }
}

/// [`SpanColor::at`] for one pixel, compiled for FMA: `f64::mul_add` is one instruction
/// here, where the crate's baseline build calls a function for it.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn color_at(color: &SpanColor, f1: f64, f2: f64) -> [u8; 4] {
    color.fused_at(f1, f2)
}

/// Four lanes of `(a0 + f1 * g1) + f2 * g2`: a depth plane.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn plane(p: [f64; 3], f1: __m256d, f2: __m256d) -> __m256d {
    let t = _mm256_add_pd(_mm256_set1_pd(p[0]), _mm256_mul_pd(f1, _mm256_set1_pd(p[1])));
    _mm256_add_pd(t, _mm256_mul_pd(f2, _mm256_set1_pd(p[2])))
}

/// Four lanes of `fma(f2, g2, fma(f1, g1, a0))`: a colour plane (see [`SpanColor::at`]).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn color_plane(p: [f64; 3], f1: __m256d, f2: __m256d) -> __m256d {
    let t = _mm256_fmadd_pd(f1, _mm256_set1_pd(p[1]), _mm256_set1_pd(p[0]));
    _mm256_fmadd_pd(f2, _mm256_set1_pd(p[2]), t)
}

/// `quantize_channel` on four lanes, as i32, in three instructions: `max(v, 0)` returns its
/// second operand when `v` is NaN, which maps NaN to 0 as the scalar code does, and the
/// conversion rounds in the default mode, half to even, as the scalar magic-number trick
/// does.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn quantize(v: __m256d) -> __m128i {
    let v = _mm256_min_pd(_mm256_set1_pd(255.0), _mm256_max_pd(v, _mm256_setzero_pd()));
    _mm256_cvtpd_epi32(v)
}

/// Four lanes of RGBA8 (in `i32` lanes) from planes: red, green, blue and, when `alpha`
/// is `None`, the fourth plane's alpha; without `CLAMP`, the values are only rounded (see
/// [`SpanColor::SmoothRgb`]).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn smooth<const CLAMP: bool>(
    p: &[[f64; 3]],
    alpha: Option<u8>,
    f1: __m256d,
    f2: __m256d,
) -> __m128i {
    let channel = |p: [f64; 3]| {
        let v = color_plane(p, f1, f2);
        if CLAMP { quantize(v) } else { _mm256_cvtpd_epi32(v) }
    };
    let (r, g, b) = (channel(p[0]), channel(p[1]), channel(p[2]));
    let a = match alpha {
        Some(a) => _mm_set1_epi32(i32::from(a) << 24),
        None => _mm_slli_epi32::<24>(channel(p[3])),
    };
    _mm_or_si128(_mm_or_si128(r, _mm_slli_epi32::<8>(g)), _mm_or_si128(_mm_slli_epi32::<16>(b), a))
}

/// [`crate::color::linear_to_srgb8`] of eight lanes, in `i32` lanes: the clamp (NaN to
/// 2^-13 as `max` returns its second operand for NaN), the bucket from the bits, its table
/// entry gathered, and the one comparison of the low bits with the entry's threshold.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn srgb8(v: __m256, table: &[u32; ENCODE_BUCKETS]) -> __m256i {
    use crate::color::{FIRST_BUCKET, FIRST_ENCODED, LOW_MASK, MANTISSA_SHIFT};
    let v = _mm256_min_ps(_mm256_max_ps(v, _mm256_set1_ps(FIRST_ENCODED)), _mm256_set1_ps(1.0));
    let bits = _mm256_castps_si256(v);
    let bucket = _mm256_sub_epi32(
        _mm256_srli_epi32::<{ MANTISSA_SHIFT as i32 }>(bits),
        _mm256_set1_epi32(FIRST_BUCKET as i32),
    );
    // Within the table after the clamp; the `min` makes the gather's bound local.
    let bucket = _mm256_min_epu32(bucket, _mm256_set1_epi32(ENCODE_BUCKETS as i32 - 1));
    // SAFETY: every lane of `bucket` is below `ENCODE_BUCKETS`, an index into `table`
    // (scale 4: `u32` elements); the gather reads nothing else.
    let entry = unsafe { _mm256_i32gather_epi32::<4>(table.as_ptr().cast(), bucket) };
    let low = _mm256_and_si256(bits, _mm256_set1_epi32(LOW_MASK as i32));
    let threshold = _mm256_and_si256(entry, _mm256_set1_epi32(0xffff));
    // `value + (low >= threshold)`: `value + 1`, less one where `threshold > low` (both
    // below 2^16, so the signed comparison is the unsigned one).
    let value = _mm256_srli_epi32::<16>(entry);
    let below = _mm256_cmpgt_epi32(threshold, low);
    _mm256_add_epi32(_mm256_add_epi32(value, _mm256_set1_epi32(1)), below)
}

/// `f` of each of eight lanes, in one register (`f` a plain function: inlined, where a
/// closure called through `dyn` would be called per lane).
#[inline]
#[target_feature(enable = "avx2")]
fn lanes_i32(lanes: &[SmallLane; 8], f: fn(&SmallLane) -> i32) -> __m256i {
    _mm256_setr_epi32(
        f(&lanes[0]),
        f(&lanes[1]),
        f(&lanes[2]),
        f(&lanes[3]),
        f(&lanes[4]),
        f(&lanes[5]),
        f(&lanes[6]),
        f(&lanes[7]),
    )
}

/// [`super::small_eight`]: each lane's vertices and box assembled in registers from the
/// lanes (scalar loads: vector loads of what the caller just stored one value at a time
/// would wait for the stores), the edges as `TriangleSetup::edges_at` computes them, and
/// the `span` of each box tested by stepping the edge values, their sign bits gathered into
/// one mask per lane (rows 0 to 3 in one `i32` lane, rows 4 to 7 in another, interleaved
/// into `u64`s at the end).
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn small_eight(lanes: &[SmallLane; 8], span: [usize; 2], out: &mut SmallEight) {
    let each = |f: fn(&SmallLane) -> i32| lanes_i32(lanes, f);
    let x = [each(|l| l.xy[0][0]), each(|l| l.xy[1][0]), each(|l| l.xy[2][0])];
    let y = [each(|l| l.xy[0][1]), each(|l| l.xy[1][1]), each(|l| l.xy[2][1])];
    let sign = each(|l| if l.clockwise { 1 } else { -1 });
    let first = [each(|l| l.first[0]), each(|l| l.first[1])];
    small_eight_rows((x, y, sign), first, span, out);
}

/// [`small_eight`] from the lanes in rows: corners `x`, `y` as [`corner_rows`] gives them,
/// `sign` 1 (clockwise) or -1, and the boxes' first pixels.
#[inline]
#[target_feature(enable = "avx2")]
fn small_eight_rows(
    (x, y, sign): ([__m256i; 3], [__m256i; 3], __m256i),
    first: [__m256i; 2],
    span: [usize; 2],
    out: &mut SmallEight,
) {
    let half = _mm256_set1_epi32(fixed::HALF);
    let sx = _mm256_add_epi32(_mm256_slli_epi32::<8>(first[0]), half);
    let sy = _mm256_add_epi32(_mm256_slli_epi32::<8>(first[1]), half);
    let put = |out: &mut [i32; 8], v: __m256i| {
        // SAFETY: eight `i32`s, 32 bytes; the store needs no alignment.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), v) }
    };
    let zero = _mm256_setzero_si256();
    let mut value = [zero; 3];
    let mut step_x = [zero; 3];
    let mut step_y = [zero; 3];
    for k in 0..3 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        // `vpsignd`: negated where the sign is -1 (counter-clockwise).
        let ea = _mm256_sign_epi32(_mm256_sub_epi32(y[a], y[b]), sign);
        let eb = _mm256_sign_epi32(_mm256_sub_epi32(x[b], x[a]), sign);
        // `FillRule::bias`: 0 on owned edges (`a > 0`, or `a == 0` and `b > 0`), else -1.
        let owned = _mm256_or_si256(
            _mm256_cmpgt_epi32(ea, zero),
            _mm256_and_si256(_mm256_cmpeq_epi32(ea, zero), _mm256_cmpgt_epi32(eb, zero)),
        );
        let bias = _mm256_andnot_si256(owned, _mm256_set1_epi32(-1));
        let dx = _mm256_sub_epi32(sx, x[a]);
        let dy = _mm256_sub_epi32(sy, y[a]);
        value[k] = _mm256_add_epi32(
            _mm256_add_epi32(_mm256_mullo_epi32(ea, dx), _mm256_mullo_epi32(eb, dy)),
            bias,
        );
        step_x[k] = _mm256_slli_epi32::<8>(ea);
        step_y[k] = _mm256_slli_epi32::<8>(eb);
        put(&mut out.edges[k], value[k]);
        put(&mut out.step_x[k], step_x[k]);
        put(&mut out.step_y[k], step_y[k]);
        if k > 0 {
            put(&mut out.bias[k - 1], bias);
        }
    }
    inside_masks(value, (step_x, step_y), span, &mut out.inside);
}

/// The coverage bits of the first `span` columns and rows of eight boxes (bit `8 r + c` of
/// `out[l]`, as [`SmallEight::inside`]) from the biased edge values at their first sample
/// (`value`) and their steps.
#[inline]
#[target_feature(enable = "avx2")]
fn inside_masks(
    value: [__m256i; 3],
    (step_x, step_y): ([__m256i; 3], [__m256i; 3]),
    span: [usize; 2],
    out: &mut [u64; 8],
) {
    let zero = _mm256_setzero_si256();
    // Bit `8 r + c` of each lane (less 32 from row 4 on): the sign of `e0 | e1 | e2` there
    // (set: outside), the values stepped from pixel to pixel.
    let (columns, rows) = (span[0].min(8), span[1].min(8));
    let (mut outside, mut inside) = ([zero; 2], [zero; 2]);
    let mut row = value;
    for r in 0..rows {
        let mut v = row;
        for c in 0..columns {
            let any = _mm256_or_si256(_mm256_or_si256(v[0], v[1]), v[2]);
            let at = _mm_cvtsi32_si128((8 * (r % 4) + c) as i32);
            let o = &mut outside[r / 4];
            *o = _mm256_or_si256(*o, _mm256_sll_epi32(_mm256_srli_epi32::<31>(any), at));
            v = std::array::from_fn(|k| _mm256_add_epi32(v[k], step_x[k]));
        }
        row = std::array::from_fn(|k| _mm256_add_epi32(row[k], step_y[k]));
    }
    // The bits of the span: its columns in each of its rows.
    let row_bits = (1u32 << columns) - 1;
    for (h, inside) in inside.iter_mut().enumerate() {
        let cells = (0..rows.saturating_sub(4 * h).min(4)).fold(0, |m, r| m | row_bits << (8 * r));
        *inside = _mm256_andnot_si256(outside[h], _mm256_set1_epi32(cells as i32));
    }
    // Lanes 0, 1, 4, 5 and 2, 3, 6, 7 as `u64`s, low half first; then in order.
    let (a, b) =
        (_mm256_unpacklo_epi32(inside[0], inside[1]), _mm256_unpackhi_epi32(inside[0], inside[1]));
    let (first, last) =
        (_mm256_permute2x128_si256::<0x20>(a, b), _mm256_permute2x128_si256::<0x31>(a, b));
    // SAFETY: eight `u64`s, 64 bytes, in two stores of 32; they need no alignment.
    unsafe {
        _mm256_storeu_si256(out.as_mut_ptr().cast(), first);
        _mm256_storeu_si256(out.as_mut_ptr().add(4).cast(), last);
    }
}

/// Lane `i` (below 8) of `v`.
#[inline]
#[target_feature(enable = "avx2")]
fn lane_of(v: __m256i, i: usize) -> i32 {
    _mm256_cvtsi256_si32(_mm256_permutevar8x32_epi32(v, _mm256_set1_epi32(i as i32)))
}

/// An edge's change from the pixel centres to sample `s` of [`super::SMALL_SAMPLES`], lane by
/// lane, from its steps over a pixel (`super::sample_offsets`).
#[inline]
#[target_feature(enable = "avx2")]
fn sample_offset(step_x: __m256i, step_y: __m256i, s: usize) -> __m256i {
    let [ox, oy] = super::SMALL_SAMPLES.offset(s).map(|v| _mm256_set1_epi32(v as i32));
    _mm256_add_epi32(
        _mm256_mullo_epi32(_mm256_srai_epi32::<8>(step_x), ox),
        _mm256_mullo_epi32(_mm256_srai_epi32::<8>(step_y), oy),
    )
}

/// [`super::small_samples`]: each sample's edge values at the boxes' first pixels, those at
/// the centre plus the sample's offsets (`(step >> 8) o`), through [`inside_masks`].
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn small_samples(
    eight: &mut SmallEight,
    span: [usize; 2],
    out: &mut super::SmallSamples,
) {
    let load = |v: &[i32; 8]| {
        // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
        unsafe { _mm256_loadu_si256(v.as_ptr().cast()) }
    };
    let value = eight.edges.each_ref().map(load);
    let step_x = eight.step_x.each_ref().map(load);
    let step_y = eight.step_y.each_ref().map(load);
    for (s, inside) in out.inside.iter_mut().enumerate() {
        let at = std::array::from_fn(|k| {
            _mm256_add_epi32(value[k], sample_offset(step_x[k], step_y[k], s))
        });
        inside_masks(at, (step_x, step_y), span, inside);
    }
    for l in 0..8 {
        eight.inside[l] = out.inside.iter().fold(0, |m, s| m | s[l]);
    }
}

/// [`super::shade_small_eight`] in AVX2. The covered pixels of the lanes are listed in drawing
/// order (lane by lane, each box row by row, left to right) as `l << 6 | bit`, `bit` the
/// pixel's [`super::SmallEight::inside`] bit; each group of eight listed pixels then takes its
/// triangles' values from registers of all eight lanes (`vpermd`, `vpermps`; an `f64` value
/// as its two words), and computes numerators, depth and colour side by side. Without
/// scatters or conflict detection, the depth test and the depth, id and overdraw writes go
/// lane by lane in listed order, which is the reference's: a pixel two triangles of a group
/// share is tested against the earlier one's write. The colours of the lanes that passed are
/// written after, in the same order, so the later one's stays.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT, BMI1 and BMI2 (the AVX2 level's features).
#[target_feature(enable = "avx2,fma,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_small_eight(
    eight: &SmallEight,
    s: &SmallShading,
    lanes: std::ops::Range<usize>,
    target: &mut TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let stride = target.stride();
    // 64 entries a lane at most, and a group's worth after the last, zeroed. Left
    // uninitialized (to zero it was a twentieth of the grid's frame at AVX-512): only the
    // entries listed and those eight are read.
    let mut entries = [std::mem::MaybeUninit::<i32>::uninit(); 8 * 64 + 8];
    let mut listed = 0;
    let mut drawn = 0;
    for l in lanes {
        assert!(l < 8, "eight lanes");
        let mut cells = eight.inside[l] & s.cells[l];
        drawn |= i32::from(cells != 0) << l;
        while cells != 0 {
            entries[listed].write((l as i32) << 6 | cells.trailing_zeros() as i32);
            listed += 1;
            cells &= cells - 1;
        }
    }
    // SAFETY: `listed <= 8 * 64`: eight entries from it are within `entries`.
    unsafe { _mm256_storeu_si256(entries.as_mut_ptr().add(listed).cast(), _mm256_setzero_si256()) };
    let lanes = SmallEdges::of(eight, s, target, drawn);
    // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
    let ids_v = unsafe { _mm256_loadu_si256(s.id.as_ptr().cast()) };
    let depth = s.depth.each_ref().map(|v| WordPairs::of(v));
    let table = crate::color::srgb8_table();
    let columns = columns_of(&s.color_rows);
    let stride_v = _mm256_set1_epi32(stride as i32);
    assert!(target.depth.len() <= i32::MAX as usize, "buffers indexed in `i32`");
    let mut g = 0;
    while g < listed {
        let count = (listed - g).min(8);
        // SAFETY: `g < listed <= 8 * 64`: eight entries from `g` are within `entries`, and
        // initialized (listed, or the zeros after them).
        let e = unsafe { _mm256_loadu_si256(entries.as_ptr().add(g).cast()) };
        g += count;
        let tri = _mm256_srli_epi32::<6>(e);
        let (at, centre) = lanes.at(tri, e, stride_v);
        // Exact in `f64`.
        let (f1, f2) = (f64_halves(centre[0]), f64_halves(centre[1]));
        let picks = [WordPick::of(tri, 0), WordPick::of(tri, 1)];
        let half_z = |h: usize| {
            let c = |k: usize| depth[k].pick(&picks[h]);
            let z = _mm256_add_pd(
                _mm256_add_pd(c(0), _mm256_mul_pd(f1[h], c(1))),
                _mm256_mul_pd(f2[h], c(2)),
            );
            _mm256_cvtpd_ps(z)
        };
        let z = _mm256_set_m128(half_z(1), half_z(0));
        let z = _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z));
        let (mut at_lanes, mut z_lanes, mut id_lanes) = ([0i32; 8], [0f32; 8], [0i32; 8]);
        // SAFETY: each array holds eight four-byte lanes, 32 bytes; the stores need no
        // alignment.
        unsafe {
            _mm256_storeu_si256(at_lanes.as_mut_ptr().cast(), at);
            _mm256_storeu_ps(z_lanes.as_mut_ptr(), z);
            _mm256_storeu_si256(
                id_lanes.as_mut_ptr().cast(),
                _mm256_permutevar8x32_epi32(ids_v, tri),
            );
        }
        // The reference loop's writes, pixel by pixel in listed order (indexing checks that
        // each pixel lies in the buffers: a negative index wraps to one that does not).
        let mut pass = 0u32;
        for i in 0..count {
            let p = at_lanes[i] as u32 as usize;
            if let Some(o) = target.overdraw.as_deref_mut() {
                o[p] += 1;
            }
            if depth_test.passes(z_lanes[i], target.depth[p]) {
                target.depth[p] = z_lanes[i];
                if let Some(ids) = target.ids.as_deref_mut() {
                    ids[p] = id_lanes[i];
                }
                pass |= 1 << i;
            }
        }
        if pass == 0 {
            continue;
        }
        let rgba = small_colors::<1>(s, (table, &columns), tri, &picks, (f1, f2), pass);
        let mut rgba_lanes = [0u32; 8];
        // SAFETY: eight `u32`s, 32 bytes; the store needs no alignment.
        unsafe { _mm256_storeu_si256(rgba_lanes.as_mut_ptr().cast(), rgba) };
        while pass != 0 {
            let i = pass.trailing_zeros() as usize;
            pass &= pass - 1;
            target.color[at_lanes[i] as u32 as usize] = rgba_lanes[i].to_le_bytes();
        }
    }
    listed as u64
}

/// [`super::shade_small_samples`] in AVX2: [`shade_small_eight`]'s groups of eight listed
/// pixels, each listed as `l << 10 | mask << 6 | bit` (`mask` its covered samples), each
/// sample's depth computed side by side at the centre's numerators plus the lane's
/// [`super::sample_offsets`] (`i32` sums below 2^26, exact in `f64`), the colour at the
/// centre. The depth tests and the depth and id writes go pixel by pixel in listed order,
/// then the colours of the pixels that passed, in the same order: a sample two triangles of
/// a group share is tested against the earlier one's write, and keeps the later colour.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT, BMI1 and BMI2 (the AVX2 level's features).
#[target_feature(enable = "avx2,fma,popcnt,bmi1,bmi2")]
pub(super) unsafe fn shade_small_samples(
    eight: &SmallEight,
    samples: &super::SmallSamples,
    s: &SmallShading,
    lanes: std::ops::Range<usize>,
    target: &mut TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    const N: usize = 4;
    let stride = target.stride();
    // As in `shade_small_eight`: only the entries listed and the eight after them are read.
    let mut entries = [std::mem::MaybeUninit::<i32>::uninit(); 8 * 64 + 8];
    let mut listed = 0;
    let mut drawn = 0;
    let mut covered = 0u64;
    let inside = &samples.inside;
    for l in lanes {
        assert!(l < 8, "eight lanes");
        let mut cells = eight.inside[l] & s.cells[l];
        drawn |= i32::from(cells != 0) << l;
        while cells != 0 {
            let bit = cells.trailing_zeros();
            let mask = (inside[0][l] >> bit & 1)
                | (inside[1][l] >> bit & 1) << 1
                | (inside[2][l] >> bit & 1) << 2
                | (inside[3][l] >> bit & 1) << 3;
            covered += u64::from(mask.count_ones());
            entries[listed].write((l as i32) << 10 | (mask as i32) << 6 | bit as i32);
            listed += 1;
            cells &= cells - 1;
        }
    }
    // SAFETY: `listed <= 8 * 64`: eight entries from it are within `entries`.
    unsafe { _mm256_storeu_si256(entries.as_mut_ptr().add(listed).cast(), _mm256_setzero_si256()) };
    let lanes = SmallEdges::of(eight, s, target, drawn);
    let (step_x, step_y) = (lanes.step_x, lanes.step_y);
    // Each sample's numerator offsets, lane by lane (`sample_offsets`): `(step >> 8) o`.
    let offsets: [[__m256i; 2]; N] =
        std::array::from_fn(|n| std::array::from_fn(|k| sample_offset(step_x[k], step_y[k], n)));
    // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
    let ids_v = unsafe { _mm256_loadu_si256(s.id.as_ptr().cast()) };
    let depth = s.depth.each_ref().map(|v| WordPairs::of(v));
    let table = crate::color::srgb8_table();
    let columns = columns_of(&s.color_rows);
    let stride_v = _mm256_set1_epi32(stride as i32);
    assert!(target.depth.len() <= i32::MAX as usize, "buffers indexed in `i32`");
    let mut g = 0;
    while g < listed {
        let count = (listed - g).min(8);
        // SAFETY: `g < listed <= 8 * 64`: eight entries from `g` are within `entries`, and
        // initialized (listed, or the zeros after them).
        let e = unsafe { _mm256_loadu_si256(entries.as_ptr().add(g).cast()) };
        g += count;
        let tri = _mm256_srli_epi32::<10>(e);
        let mask = _mm256_and_si256(_mm256_srli_epi32::<6>(e), _mm256_set1_epi32(15));
        let (at, centre) = lanes.at(tri, e, stride_v);
        let pick = |v: __m256i| _mm256_permutevar8x32_epi32(v, tri);
        let picks = [WordPick::of(tri, 0), WordPick::of(tri, 1)];
        let c: [[__m256d; 3]; 2] =
            std::array::from_fn(|h| std::array::from_fn(|k| depth[k].pick(&picks[h])));
        // Sample `n`'s depth, as `crate::shade::depth_at` computes it.
        let z: [__m256; N] = std::array::from_fn(|n| {
            let f1 = f64_halves(_mm256_add_epi32(centre[0], pick(offsets[n][0])));
            let f2 = f64_halves(_mm256_add_epi32(centre[1], pick(offsets[n][1])));
            let half_z = |h: usize| {
                let z = _mm256_add_pd(
                    _mm256_add_pd(c[h][0], _mm256_mul_pd(f1[h], c[h][1])),
                    _mm256_mul_pd(f2[h], c[h][2]),
                );
                _mm256_cvtpd_ps(z)
            };
            let z = _mm256_set_m128(half_z(1), half_z(0));
            _mm256_min_ps(_mm256_set1_ps(1.0), _mm256_max_ps(_mm256_setzero_ps(), z))
        });
        // Transposed: pixel `i`'s four samples side by side at `4 i` of `by_pixel` (`u[j]`
        // holds pixels `j` and `j + 4`).
        let (t0, t1) = (_mm256_unpacklo_ps(z[0], z[1]), _mm256_unpackhi_ps(z[0], z[1]));
        let (t2, t3) = (_mm256_unpacklo_ps(z[2], z[3]), _mm256_unpackhi_ps(z[2], z[3]));
        let u = [
            _mm256_shuffle_ps::<0x44>(t0, t2),
            _mm256_shuffle_ps::<0xEE>(t0, t2),
            _mm256_shuffle_ps::<0x44>(t1, t3),
            _mm256_shuffle_ps::<0xEE>(t1, t3),
        ];
        let mut by_pixel = [0f32; 32];
        // SAFETY: four stores of eight `f32`s into the 32 of `by_pixel`; stores need no
        // alignment.
        unsafe {
            let out = by_pixel.as_mut_ptr();
            _mm256_storeu_ps(out, _mm256_permute2f128_ps::<0x20>(u[0], u[1]));
            _mm256_storeu_ps(out.add(8), _mm256_permute2f128_ps::<0x20>(u[2], u[3]));
            _mm256_storeu_ps(out.add(16), _mm256_permute2f128_ps::<0x31>(u[0], u[1]));
            _mm256_storeu_ps(out.add(24), _mm256_permute2f128_ps::<0x31>(u[2], u[3]));
        }
        let (mut at_lanes, mut mask_lanes) = ([0i32; 8], [0i32; 8]);
        // SAFETY: each array holds eight four-byte lanes, 32 bytes; the stores need no
        // alignment.
        unsafe {
            _mm256_storeu_si256(at_lanes.as_mut_ptr().cast(), at);
            _mm256_storeu_si256(mask_lanes.as_mut_ptr().cast(), mask);
        }
        let id_lanes = pick(ids_v);
        // The pixel loop's tests and writes, pixel by pixel in listed order, a pixel's four
        // samples at once (the slices check that they lie in the buffers).
        let mut passed = [_mm_setzero_si128(); 8];
        let mut pass = 0u32;
        for i in 0..count {
            let p = N * at_lanes[i] as u32 as usize;
            let depth = &mut target.depth[p..p + N];
            // SAFETY: four `f32`s of `by_pixel` (at most 28 + 4) and of `depth` (its length);
            // unaligned loads and stores need no alignment.
            let ok = unsafe {
                let z = _mm_loadu_ps(by_pixel.as_ptr().add(4 * i));
                let stored = _mm_loadu_ps(depth.as_ptr());
                let covered = _mm_castsi128_ps(lane_mask(mask_lanes[i] as u32));
                let ok = match depth_test {
                    DepthTest::Less => _mm_and_ps(_mm_cmp_ps::<_CMP_LT_OQ>(z, stored), covered),
                    DepthTest::LessEqual => {
                        _mm_and_ps(_mm_cmp_ps::<_CMP_LE_OQ>(z, stored), covered)
                    }
                    DepthTest::Always => covered,
                };
                if _mm_movemask_ps(ok) == 0 {
                    continue;
                }
                _mm_storeu_ps(depth.as_mut_ptr(), _mm_blendv_ps(stored, z, ok));
                _mm_castps_si128(ok)
            };
            if let Some(ids) = target.ids.as_deref_mut() {
                let ids = &mut ids[p..p + N];
                let id = _mm_set1_epi32(lane_of(id_lanes, i));
                // SAFETY: four `i32`s of `ids` (its length); unaligned loads and stores need
                // no alignment.
                unsafe {
                    let old = _mm_loadu_si128(ids.as_ptr().cast());
                    _mm_storeu_si128(ids.as_mut_ptr().cast(), _mm_blendv_epi8(old, id, ok));
                }
            }
            passed[i] = ok;
            pass |= 1 << i;
        }
        if pass == 0 {
            continue;
        }
        let (f1, f2) = (f64_halves(centre[0]), f64_halves(centre[1]));
        let rgba = small_colors::<4>(s, (table, &columns), tri, &picks, (f1, f2), pass);
        while pass != 0 {
            let i = pass.trailing_zeros() as usize;
            pass &= pass - 1;
            let p = N * at_lanes[i] as u32 as usize;
            let colors = &mut target.color[p..p + N];
            let rgba = _mm_set1_epi32(lane_of(rgba, i));
            // SAFETY: four four-byte colours of `colors` (its length); unaligned loads and
            // stores need no alignment.
            unsafe {
                let old = _mm_loadu_si128(colors.as_ptr().cast());
                let new = _mm_blendv_epi8(old, rgba, passed[i]);
                _mm_storeu_si128(colors.as_mut_ptr().cast(), new);
            }
        }
    }
    covered
}

/// What both small kernels ([`shade_small_eight`], [`shade_small_samples`]) read of their
/// lanes: each box's first pixel ([`box_starts`]), and edges 1 and 2's biased values at its
/// centre, steps and fill-rule biases.
#[derive(Clone, Copy)]
struct SmallEdges {
    first: __m256i,
    edges: [__m256i; 2],
    step_x: [__m256i; 2],
    step_y: [__m256i; 2],
    bias: [__m256i; 2],
}

impl SmallEdges {
    /// The lanes of `eight` and `s` within `target`, those of `drawn` (a bit per lane) to be
    /// drawn.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn of(eight: &SmallEight, s: &SmallShading, target: &TargetBand<'_>, drawn: i32) -> Self {
        let load = |v: &[i32; 8]| {
            // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
            unsafe { _mm256_loadu_si256(v.as_ptr().cast()) }
        };
        Self {
            // Each box's first pixel, `target.index` in `i32` lanes (each pixel's index is
            // checked before it is read or written, too).
            first: box_starts(s, target, drawn),
            edges: [load(&eight.edges[1]), load(&eight.edges[2])],
            step_x: [load(&eight.step_x[1]), load(&eight.step_x[2])],
            step_y: [load(&eight.step_y[1]), load(&eight.step_y[2])],
            bias: [load(&eight.bias[0]), load(&eight.bias[1])],
        }
    }

    /// Eight listed pixels, of lanes `tri`, at bits `8 r + c` (the low six bits of `entries`):
    /// their indices (`stride` a row) and barycentric numerators at their centres, `E_k + r
    /// step_y + c step_x - bias` in `i32` (below 2^25 within the box, as `SmallEight` says).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn at(&self, tri: __m256i, entries: __m256i, stride: __m256i) -> (__m256i, [__m256i; 2]) {
        let column = _mm256_and_si256(entries, _mm256_set1_epi32(7));
        let row = _mm256_and_si256(_mm256_srli_epi32::<3>(entries), _mm256_set1_epi32(7));
        let pick = |v: __m256i| _mm256_permutevar8x32_epi32(v, tri);
        let at = _mm256_add_epi32(
            _mm256_add_epi32(pick(self.first), column),
            _mm256_mullo_epi32(row, stride),
        );
        let numerators = std::array::from_fn(|k| {
            let v = _mm256_add_epi32(
                pick(self.edges[k]),
                _mm256_mullo_epi32(row, pick(self.step_y[k])),
            );
            let v = _mm256_add_epi32(v, _mm256_mullo_epi32(column, pick(self.step_x[k])));
            _mm256_sub_epi32(v, pick(self.bias[k]))
        });
        (at, numerators)
    }
}

/// Each box's first pixel, `target.index` in `i32` lanes, for the small kernels at AVX2 and
/// AVX-512.
///
/// # Panics
/// If the first pixel of a box of `drawn` (a bit per lane) lies outside the band: its pixels'
/// indices, computed in `i32`, could then wrap back into the buffers (the kernels check
/// every index against them, but such a one would pass).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn box_starts(s: &SmallShading, target: &TargetBand<'_>, drawn: i32) -> __m256i {
    let load = |v: &[i32; 8]| {
        // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
        unsafe { _mm256_loadu_si256(v.as_ptr().cast()) }
    };
    let rect = target.rect();
    let (row, column) = (
        _mm256_sub_epi32(load(&s.y0), _mm256_set1_epi32(rect.y0)),
        _mm256_sub_epi32(load(&s.x0), _mm256_set1_epi32(rect.x0)),
    );
    // Unsigned `v <= last` as `min(v, last) == v`.
    let within =
        |v: __m256i, last: i32| _mm256_cmpeq_epi32(_mm256_min_epu32(v, _mm256_set1_epi32(last)), v);
    let band = _mm256_and_si256(within(row, rect.y1 - rect.y0), within(column, rect.x1 - rect.x0));
    let band = _mm256_movemask_ps(_mm256_castsi256_ps(band));
    assert!(band & drawn == drawn, "the boxes must lie in the band");
    let stride = _mm256_set1_epi32(target.stride() as i32);
    _mm256_add_epi32(_mm256_mullo_epi32(row, stride), load(&s.x0))
}

/// Eight `f64` lanes kept as their sixteen words in two registers, lanes 0-3 and 4-7, for
/// [`WordPairs::pick`]: AVX2 permutes words across a register, not `f64`s across two.
#[derive(Clone, Copy)]
struct WordPairs([__m256i; 2]);

/// Which lanes of [`WordPairs`] four `f64` lanes take: each lane's word indices within its
/// register, and whether it is in the upper one.
#[derive(Clone, Copy)]
struct WordPick {
    words: __m256i,
    upper: __m256d,
}

impl WordPairs {
    #[inline]
    #[target_feature(enable = "avx2")]
    fn of(v: &[f64; 8]) -> Self {
        // SAFETY: eight `f64`s, 64 bytes, in two loads of 32; they need no alignment.
        unsafe {
            let p = v.as_ptr();
            Self([_mm256_loadu_si256(p.cast()), _mm256_loadu_si256(p.add(4).cast())])
        }
    }

    /// The four `f64` lanes `pick` names.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn pick(&self, pick: &WordPick) -> __m256d {
        let lo = _mm256_castsi256_pd(_mm256_permutevar8x32_epi32(self.0[0], pick.words));
        let hi = _mm256_castsi256_pd(_mm256_permutevar8x32_epi32(self.0[1], pick.words));
        _mm256_blendv_pd(lo, hi, pick.upper)
    }
}

impl WordPick {
    /// Lanes `4 h..4 h + 4` of `tri` (each below 8).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn of(tri: __m256i, h: usize) -> Self {
        let spread = if h == 0 {
            _mm256_setr_epi32(0, 0, 1, 1, 2, 2, 3, 3)
        } else {
            _mm256_setr_epi32(4, 4, 5, 5, 6, 6, 7, 7)
        };
        let t = _mm256_permutevar8x32_epi32(tri, spread);
        let words = _mm256_or_si256(
            _mm256_and_si256(_mm256_slli_epi32::<1>(t), _mm256_set1_epi32(7)),
            _mm256_setr_epi32(0, 1, 0, 1, 0, 1, 0, 1),
        );
        let upper = _mm256_castsi256_pd(_mm256_cmpgt_epi32(t, _mm256_set1_epi32(3)));
        Self { words, upper }
    }
}

/// The colours of a group of [`shade_small_eight`] at barycentric numerators `f1`, `f2` (two
/// halves of four), lane `i` of triangle `tri[i]`, as [`perspective`] computes one
/// triangle's (the lanes of `pass` matter; the others compute from leftovers). One copy per
/// kernel (`SAMPLES`, the kernel's samples per pixel, is not read), so that each has one
/// caller and is inlined there: called from both kernels, the compiler left it out of line,
/// its vectors passed through memory (the grid at 1x 22 -> 40 ms on two threads).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn small_colors<const SAMPLES: usize>(
    s: &SmallShading,
    (table, columns): (&[u32; ENCODE_BUCKETS], &[__m256; 16]),
    tri: __m256i,
    picks: &[WordPick; 2],
    (f1, f2): ([__m256d; 2], [__m256d; 2]),
    pass: u32,
) -> __m256i {
    let load = |v: &[i32; 8]| {
        // SAFETY: eight `i32`s, 32 bytes; the load needs no alignment.
        _mm256_permutevar8x32_epi32(unsafe { _mm256_loadu_si256(v.as_ptr().cast()) }, tri)
    };
    let lanes_ps = |column: usize| _mm256_permutevar8x32_ps(columns[column], tri);
    let both = |h: [__m128; 2]| _mm256_set_m128(h[1], h[0]);
    // `crate::pipeline::perspective_weights`, lane by lane affine or divided.
    let inv_area2 = WordPairs::of(&s.inv_area2);
    let l: [[__m256d; 3]; 2] = std::array::from_fn(|h| {
        let a = inv_area2.pick(&picks[h]);
        let (l1, l2) = (_mm256_mul_pd(f1[h], a), _mm256_mul_pd(f2[h], a));
        [_mm256_sub_pd(_mm256_sub_pd(_mm256_set1_pd(1.0), l1), l2), l1, l2]
    });
    let mut w: [__m256; 3] =
        std::array::from_fn(|k| both([_mm256_cvtpd_ps(l[0][k]), _mm256_cvtpd_ps(l[1][k])]));
    let affine = load(&s.affine);
    if pass & !(_mm256_movemask_ps(_mm256_castsi256_ps(affine)) as u32) != 0 {
        let inv_w = s.inv_w.each_ref().map(|v| WordPairs::of(v));
        // `sum > 0`, false for NaN: thirds elsewhere (as `perspective_weights`).
        let third = _mm256_set1_pd(1.0 / 3.0);
        let divided: [[__m128; 3]; 2] = std::array::from_fn(|h| {
            let q: [__m256d; 3] =
                std::array::from_fn(|k| _mm256_mul_pd(l[h][k], inv_w[k].pick(&picks[h])));
            let sum = _mm256_add_pd(_mm256_add_pd(q[0], q[1]), q[2]);
            let positive = _mm256_cmp_pd::<_CMP_GT_OQ>(sum, _mm256_setzero_pd());
            q.map(|v| _mm256_cvtpd_ps(_mm256_blendv_pd(third, _mm256_div_pd(v, sum), positive)))
        });
        let affine = _mm256_castsi256_ps(affine);
        w = std::array::from_fn(|k| {
            _mm256_blendv_ps(both([divided[0][k], divided[1][k]]), w[k], affine)
        });
    }
    // Channel `ch`: `(c0 w0 + c1 w1 + c2 w2) scale`, left to right.
    let channel = |ch: usize| {
        let c = |k: usize| lanes_ps(4 * k + ch);
        let t = _mm256_add_ps(_mm256_mul_ps(c(0), w[0]), _mm256_mul_ps(c(1), w[1]));
        let t = _mm256_add_ps(t, _mm256_mul_ps(c(2), w[2]));
        _mm256_mul_ps(t, lanes_ps(12 + ch))
    };
    let r = srgb8(channel(0), table);
    let g = srgb8(channel(1), table);
    let b = srgb8(channel(2), table);
    let fixed = load(&s.alpha);
    let weighted = _mm256_cmpgt_epi32(_mm256_setzero_si256(), fixed);
    let alpha = if pass & _mm256_movemask_ps(_mm256_castsi256_ps(weighted)) as u32 == 0 {
        fixed
    } else {
        _mm256_blendv_epi8(fixed, unorm8(channel(3)), weighted)
    };
    _mm256_or_si256(
        _mm256_or_si256(r, _mm256_slli_epi32::<8>(g)),
        _mm256_or_si256(_mm256_slli_epi32::<16>(b), _mm256_slli_epi32::<24>(alpha)),
    )
}

/// The sixteen columns of eight rows of sixteen `f32`: lane `l` of column `c` is `rows[l][c]`.
/// Two 8 x 8 transposes: pairs of rows interleaved, then pairs of pairs, each 128-bit half
/// then holding four rows of one column, which the last permutes put side by side.
#[inline]
#[target_feature(enable = "avx2")]
fn columns_of(rows: &[[f32; 16]; 8]) -> [__m256; 16] {
    let mut out = [_mm256_setzero_ps(); 16];
    for half in 0..2 {
        // SAFETY: each load reads eight `f32`s (32 bytes) of one row; it needs no alignment.
        let r: [__m256; 8] =
            std::array::from_fn(|l| unsafe { _mm256_loadu_ps(rows[l].as_ptr().add(8 * half)) });
        // `t[2p]`, `t[2p + 1]`: rows `2p` and `2p + 1` interleaved, low and high words of
        // each half.
        let t: [__m256; 8] = std::array::from_fn(|k| {
            let (a, b) = (r[k & !1], r[k | 1]);
            if k % 2 == 0 { _mm256_unpacklo_ps(a, b) } else { _mm256_unpackhi_ps(a, b) }
        });
        // `u[4h + i]`: rows `4h..4h + 4` of column `i` in the lower half, `4 + i` in the upper.
        let u: [__m256; 8] = std::array::from_fn(|k| {
            let (h, i) = (k / 4, k % 4);
            let (a, b) = (t[4 * h + i / 2], t[4 * h + 2 + i / 2]);
            if i % 2 == 0 {
                _mm256_shuffle_ps::<0x44>(a, b)
            } else {
                _mm256_shuffle_ps::<0xEE>(a, b)
            }
        });
        for i in 0..4 {
            out[8 * half + i] = _mm256_permute2f128_ps::<0x20>(u[i], u[4 + i]);
            out[8 * half + 4 + i] = _mm256_permute2f128_ps::<0x31>(u[i], u[4 + i]);
        }
    }
    out
}

/// [`super::srgb8_lanes`]: the eight colours transposed into a register per channel (each
/// pair of lanes `l`, `l + 4` loaded into one register, then unpacked and shuffled), red,
/// green and blue through [`srgb8`], alpha through [`unorm8`].
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn srgb8_lanes(
    colors: &[[f32; 4]; 8],
    table: &[u32; ENCODE_BUCKETS],
) -> [u32; 8] {
    let pair = |l: usize| {
        // SAFETY: lanes `l` and `l + 4` (`l < 4`) are four `f32`s each, in `colors`; the
        // loads need no alignment.
        unsafe {
            let lo = _mm_loadu_ps(colors[l].as_ptr());
            let hi = _mm_loadu_ps(colors[l + 4].as_ptr());
            _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(lo), hi)
        }
    };
    let (c04, c15, c26, c37) = (pair(0), pair(1), pair(2), pair(3));
    // Per 128-bit half: [r0 r1 g0 g1], [b0 b1 a0 a1], [r2 r3 g2 g3], [b2 b3 a2 a3] (lanes 4-7
    // in the upper halves).
    let (rg01, ba01) = (_mm256_unpacklo_ps(c04, c15), _mm256_unpackhi_ps(c04, c15));
    let (rg23, ba23) = (_mm256_unpacklo_ps(c26, c37), _mm256_unpackhi_ps(c26, c37));
    let r = _mm256_shuffle_ps::<0x44>(rg01, rg23);
    let g = _mm256_shuffle_ps::<0xEE>(rg01, rg23);
    let b = _mm256_shuffle_ps::<0x44>(ba01, ba23);
    let a = _mm256_shuffle_ps::<0xEE>(ba01, ba23);
    let rgba = _mm256_or_si256(
        _mm256_or_si256(srgb8(r, table), _mm256_slli_epi32::<8>(srgb8(g, table))),
        _mm256_or_si256(
            _mm256_slli_epi32::<16>(srgb8(b, table)),
            _mm256_slli_epi32::<24>(unorm8(a)),
        ),
    );
    let mut out = [0u32; 8];
    // SAFETY: `out` holds eight `u32`s, 32 bytes; the store needs no alignment.
    unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), rgba) };
    out
}

/// [`srgb8`] of four lanes, with a gather of four (for the AVX2 kernels' four lanes; the
/// AVX-512 kernels' eight take [`srgb8`]: as two of these, the bunny was 8% slower).
#[inline]
#[target_feature(enable = "avx2")]
fn srgb8_x4(v: __m128, table: &[u32; ENCODE_BUCKETS]) -> __m128i {
    use crate::color::{FIRST_BUCKET, FIRST_ENCODED, LOW_MASK, MANTISSA_SHIFT};
    let v = _mm_min_ps(_mm_max_ps(v, _mm_set1_ps(FIRST_ENCODED)), _mm_set1_ps(1.0));
    let bits = _mm_castps_si128(v);
    let bucket = _mm_sub_epi32(
        _mm_srli_epi32::<{ MANTISSA_SHIFT as i32 }>(bits),
        _mm_set1_epi32(FIRST_BUCKET as i32),
    );
    let bucket = _mm_min_epu32(bucket, _mm_set1_epi32(ENCODE_BUCKETS as i32 - 1));
    // SAFETY: every lane of `bucket` is below `ENCODE_BUCKETS`, an index into `table`.
    let entry = unsafe { _mm_i32gather_epi32::<4>(table.as_ptr().cast(), bucket) };
    let low = _mm_and_si128(bits, _mm_set1_epi32(LOW_MASK as i32));
    let threshold = _mm_and_si128(entry, _mm_set1_epi32(0xffff));
    let value = _mm_srli_epi32::<16>(entry);
    let below = _mm_cmpgt_epi32(threshold, low);
    _mm_add_epi32(_mm_add_epi32(value, _mm_set1_epi32(1)), below)
}

/// [`crate::color::unorm8`] of eight lanes, in `i32` lanes: `max` maps NaN to 0 (and
/// `-0.0` to `0.0`, which gives the same 0), `* 255 + 0.5` as two roundings, truncated.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn unorm8(v: __m256) -> __m256i {
    let v = _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(1.0));
    let v = _mm256_add_ps(_mm256_mul_ps(v, _mm256_set1_ps(255.0)), _mm256_set1_ps(0.5));
    _mm256_cvttps_epi32(v)
}

/// Four lanes of [`PerspectiveColor::at`], as the AVX-512 `perspective` computes eight:
/// weights in `f64`, colours in `f32`, the encoder's lookups gathered four at a time
/// ([`srgb8_x4`]).
#[inline]
#[target_feature(enable = "avx2,fma")]
fn perspective(
    p: &PerspectiveColor,
    q: ([f64; 3], bool),
    table: &[u32; ENCODE_BUCKETS],
    f1: __m256d,
    f2: __m256d,
) -> __m128i {
    // Written out, without closures or `map` (see the AVX-512 `perspective`).
    let w = perspective_weights(p.inv_area2, q, f1, f2);
    let r = srgb8_x4(perspective_channel(p, &w, 0), table);
    let g = srgb8_x4(perspective_channel(p, &w, 1), table);
    let b = srgb8_x4(perspective_channel(p, &w, 2), table);
    let a = match p.alpha {
        Some(a) => _mm_set1_epi32(i32::from(crate::color::unorm8(a)) << 24),
        None => {
            let a = unorm8(_mm256_castps128_ps256(perspective_channel(p, &w, 3)));
            _mm_slli_epi32::<24>(_mm256_castsi256_si128(a))
        }
    };
    _mm_or_si128(_mm_or_si128(r, _mm_slli_epi32::<8>(g)), _mm_or_si128(_mm_slli_epi32::<16>(b), a))
}

/// Four lanes of `crate::pipeline::perspective_weights(f1 inv_area2, f2 inv_area2, q)`.
#[inline]
#[target_feature(enable = "avx2")]
fn perspective_weights(
    inv_area2: f64,
    (q, affine): ([f64; 3], bool),
    f1: __m256d,
    f2: __m256d,
) -> [__m128; 3] {
    let inv_area2 = _mm256_set1_pd(inv_area2);
    let (l1, l2) = (_mm256_mul_pd(f1, inv_area2), _mm256_mul_pd(f2, inv_area2));
    let l0 = _mm256_sub_pd(_mm256_sub_pd(_mm256_set1_pd(1.0), l1), l2);
    if affine {
        return [_mm256_cvtpd_ps(l0), _mm256_cvtpd_ps(l1), _mm256_cvtpd_ps(l2)];
    }
    let w0 = _mm256_mul_pd(l0, _mm256_set1_pd(q[0]));
    let w1 = _mm256_mul_pd(l1, _mm256_set1_pd(q[1]));
    let w2 = _mm256_mul_pd(l2, _mm256_set1_pd(q[2]));
    let sum = _mm256_add_pd(_mm256_add_pd(w0, w1), w2);
    // `sum > 0`, false for NaN: thirds elsewhere (1/3 in `f64` narrows to the `f32` third).
    let positive = _mm256_cmp_pd::<_CMP_GT_OQ>(sum, _mm256_setzero_pd());
    let third = _mm256_set1_pd(1.0 / 3.0);
    [
        _mm256_cvtpd_ps(_mm256_blendv_pd(third, _mm256_div_pd(w0, sum), positive)),
        _mm256_cvtpd_ps(_mm256_blendv_pd(third, _mm256_div_pd(w1, sum), positive)),
        _mm256_cvtpd_ps(_mm256_blendv_pd(third, _mm256_div_pd(w2, sum), positive)),
    ]
}

/// Channel `k` of the colour at weights `w`: `(c0 w0 + c1 w1 + c2 w2) scale`, left to right.
#[inline]
#[target_feature(enable = "avx2")]
fn perspective_channel(p: &PerspectiveColor, w: &[__m128; 3], k: usize) -> __m128 {
    let [c0, c1, c2] = p.colors;
    let (c0, c1, c2) = (_mm_set1_ps(c0[k]), _mm_set1_ps(c1[k]), _mm_set1_ps(c2[k]));
    let t = _mm_add_ps(_mm_mul_ps(c0, w[0]), _mm_mul_ps(c1, w[1]));
    let t = _mm_add_ps(t, _mm_mul_ps(c2, w[2]));
    _mm_mul_ps(t, _mm_set1_ps(p.scale[k]))
}

/// The weights and the four channels of [`perspective`] at four numerators, for the tests.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(test)]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn perspective_probe(
    p: &PerspectiveColor,
    f1: [f64; 4],
    f2: [f64; 4],
) -> ([[f32; 4]; 3], [[f32; 4]; 4]) {
    // SAFETY: each load reads the lanes of its array, no more.
    let (f1, f2) = unsafe { (_mm256_loadu_pd(f1.as_ptr()), _mm256_loadu_pd(f2.as_ptr())) };
    let w = perspective_weights(p.inv_area2, p.inv_w(), f1, f2);
    let lanes = |v: __m128| {
        let mut out = [0.0f32; 4];
        // SAFETY: four `f32` lanes into an array of four.
        unsafe { _mm_storeu_ps(out.as_mut_ptr(), v) };
        out
    };
    (w.map(lanes), [0, 1, 2, 3].map(|k| lanes(perspective_channel(p, &w, k))))
}

/// [`srgb8`] (and [`srgb8_x4`], asserted to agree with it) and [`unorm8`] of eight values,
/// for the tests.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(test)]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn encode_probe(v: [f32; 8]) -> ([u32; 8], [u32; 8]) {
    let table = crate::color::srgb8_table();
    let lanes = |x: __m256i| {
        let mut out = [0u32; 8];
        // SAFETY: eight `u32` lanes into an array of eight.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), x) };
        out
    };
    // SAFETY: eight `f32` from an array of eight.
    let v = unsafe { _mm256_loadu_ps(v.as_ptr()) };
    let (lo, hi) = (_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
    let x4 = _mm256_set_m128i(srgb8_x4(hi, table), srgb8_x4(lo, table));
    let eight = srgb8(v, table);
    assert_eq!(lanes(x4), lanes(eight), "four and eight lanes");
    (lanes(eight), lanes(unorm8(v)))
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
/// the colour it saves (soup: 7% faster without). With `at_sample`, depth is taken at those
/// numerators instead (samples whose colour is their pixel centre's).
///
/// # Safety
/// The CPU must support AVX2 and FMA, and `at + 4` must not exceed `t.checked_len()`.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn group<const SKIP_HIDDEN: bool>(
    t: &mut KernelTarget<'_>,
    at: usize,
    f1: __m256d,
    f2: __m256d,
    cover: __m128i,
    at_sample: Option<[__m256d; 2]>,
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
        let [z1, z2] = at_sample.unwrap_or([f1, f2]);
        let z = _mm256_cvtpd_ps(plane(t.depth_plane, z1, z2));
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
#[target_feature(enable = "avx2,fma")]
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
/// thread's) are written back as read. A box up to four wide takes one group per row, a
/// wider one one group from each row's first covered pixel and a second only where the
/// row's pixels reach past it ([`wide_rows`]). Groups go through the same steps, covered or
/// not, without branches on depth: a small triangle has a few groups each, and mispredicted
/// branches cost more than the work they would skip.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1 (the AVX2 level's features).
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
pub(super) unsafe fn shade_narrow(job: &mut NarrowJob<'_>) -> u64 {
    // SAFETY: the CPU has the AVX2 level's features (this function's contract).
    unsafe { shade_narrow_box(&NarrowBox::of(job), &mut job.target) }
}

/// [`super::shade_narrow_eight`] in AVX2: each lane of `lanes` through [`narrow_groups`],
/// its values read in place from `eight`, all in one function (as the AVX-512 version); a
/// lane whose last groups would reach past the buffers as its [`NarrowJob`]
/// (`narrow_lane_job`). Against a call of [`shade_narrow_box`] per lane from `simd`'s loop,
/// the soup took 132 -> 124 ms on one thread and 71 -> 68 ms on two (fastest of four
/// alternated runs).
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1 (the AVX2 level's features).
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
pub(super) unsafe fn shade_narrow_eight(
    eight: &NarrowEight,
    lanes: std::ops::Range<usize>,
    target: &mut TargetBand<'_>,
    depth_test: DepthTest,
) -> u64 {
    let mut covered = 0;
    for l in lanes {
        let box_ = NarrowBox::of_lane(eight, l, target);
        if box_.group_end() > target.depth.len() {
            covered += super::narrow_lane_job(SimdLevel::Avx2, eight, l, target, depth_test);
            continue;
        }
        let color = eight.color(l);
        let mut t = eight.kernel_target(l, &color, depth_test, target);
        // SAFETY: the CPU has the AVX2 level's features (this function's contract).
        covered += with_rgba!(color, __m256d, _mm_set1_epi32, smooth, rgba => unsafe {
            narrow_groups(&box_, &mut t, rgba)
        });
    }
    covered
}

/// [`shade_narrow`] of box `b` into `t`.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1 (the AVX2 level's features).
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
unsafe fn shade_narrow_box(b: &NarrowBox<impl EdgeValues>, t: &mut KernelTarget<'_>) -> u64 {
    // SAFETY: the CPU has the AVX2 level's features (this function's contract).
    with_rgba!(*t.color, __m256d, _mm_set1_epi32, smooth, rgba => unsafe {
        narrow_groups(b, t, rgba)
    })
}

/// [`shade_narrow`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1.
#[inline]
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
unsafe fn narrow_groups(
    job: &NarrowBox<impl EdgeValues>,
    target: &mut KernelTarget<'_>,
    rgba: impl Fn(__m256d, __m256d) -> __m128i,
) -> u64 {
    let n = target.checked_len();
    job.assert_narrow();
    assert!(job.group_end() <= n, "the box's groups must lie in the buffers");
    let lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
    // Edge k's offsets from the row's first pixel, for the lanes of groups 0 and 1.
    let offsets = |k: usize, g: usize| {
        let step = _mm256_set1_pd(job.values.step_x(k));
        _mm256_mul_pd(_mm256_add_pd(lanes, _mm256_set1_pd(4.0 * g as f64)), step)
    };
    let offsets: [[__m256d; 2]; 3] = std::array::from_fn(|k| [offsets(k, 0), offsets(k, 1)]);
    let bias = [0, 1].map(|k| _mm256_set1_pd(job.values.bias(k)));
    // Each group's edge values, stepped a row down in their registers (as the AVX-512
    // kernel's `NarrowBox::groups`; integers below 2^53, exact in any order).
    let mut row: [[__m256d; 2]; 3] = std::array::from_fn(|k| {
        let edge = _mm256_set1_pd(job.values.edge(k));
        offsets[k].map(|o| _mm256_add_pd(edge, o))
    });
    let step_y = [0, 1, 2].map(|k| _mm256_set1_pd(job.values.step_y(k)));
    if job.columns > 4 {
        // SAFETY: the CPU has the features (this function's contract); the box's groups
        // lie in the buffers (asserted above).
        return unsafe { wide_rows(job, target, (row, bias, step_y), &rgba) };
    }
    // A box up to four wide: one group a row.
    let columns = (1u32 << job.columns) - 1;
    let mut covered = 0u64;
    for r in 0..job.rows {
        let e: [__m256d; 3] = std::array::from_fn(|k| row[k][0]);
        let out = _mm256_movemask_pd(_mm256_or_pd(_mm256_or_pd(e[0], e[1]), e[2]));
        let bits = !(out as u32) & columns;
        covered += u64::from(bits.count_ones());
        let (f1, f2) = (_mm256_sub_pd(e[1], bias[0]), _mm256_sub_pd(e[2], bias[1]));
        let at = job.first + r * job.stride;
        // SAFETY: `at + 4 <= group_end() <= n` (asserted above).
        unsafe { group::<false>(target, at, f1, f2, lane_mask(bits), None, &rgba) };
        row = std::array::from_fn(|k| row[k].map(|e| _mm256_add_pd(e, step_y[k])));
    }
    covered
}

/// [`narrow_groups`] for boxes of five to eight columns: each row's group of four starts at
/// its first covered pixel (at most at column 4, so that it stays within the box's two
/// groups), and a second group (columns 4 to 7, the first group's pixels masked off) runs
/// only when the row's pixels reach past the first. A triangle's pixels on a row are
/// consecutive (its inside is convex), so a row of the soup's triangles, one to four pixels,
/// mostly takes one group where the box's two had taken two: their groups per triangle 7.6
/// -> 5.1. The edge values at the group's first column `c` are the row's plus `c step_x`,
/// exact integers below 2^53 in `f64`, as stepped. The pixels of the row are written by the
/// first group before the second reads them (where the two groups overlap, the second
/// writes back what the first wrote).
///
/// `row` holds each edge's values at the first row's columns 0-3 and 4-7, `bias` and `step_y`
/// the box's, broadcast.
///
/// # Safety
/// The CPU must support AVX2, FMA, POPCNT and BMI1; the box's two groups per row must lie in
/// the buffers.
#[inline]
#[target_feature(enable = "avx2,fma,popcnt,bmi1")]
unsafe fn wide_rows(
    job: &NarrowBox<impl EdgeValues>,
    target: &mut KernelTarget<'_>,
    (mut row, bias, step_y): ([[__m256d; 2]; 3], [__m256d; 2], [__m256d; 3]),
    rgba: &impl Fn(__m256d, __m256d) -> __m128i,
) -> u64 {
    let step_x = [0, 1, 2].map(|k| _mm256_set1_pd(job.values.step_x(k)));
    let columns = (1u32 << job.columns) - 1;
    let mut covered = 0u64;
    for r in 0..job.rows {
        let out = |g: usize| {
            _mm256_movemask_pd(_mm256_or_pd(_mm256_or_pd(row[0][g], row[1][g]), row[2][g])) as u32
        };
        let bits = !(out(0) | out(1) << 4) & columns;
        covered += u64::from(bits.count_ones());
        let c = bits.trailing_zeros().min(4);
        let at = job.first + r * job.stride;
        let shift = _mm256_set1_pd(f64::from(c));
        let e: [__m256d; 3] = std::array::from_fn(|k| _mm256_fmadd_pd(shift, step_x[k], row[k][0]));
        let (f1, f2) = (_mm256_sub_pd(e[1], bias[0]), _mm256_sub_pd(e[2], bias[1]));
        // SAFETY: `c <= 4`: the group ends within the row's two (the caller's contract).
        unsafe {
            group::<false>(target, at + c as usize, f1, f2, lane_mask(bits >> c), None, rgba)
        };
        let rest = bits & !(0xF << c);
        if rest != 0 {
            let (f1, f2) = (_mm256_sub_pd(row[1][1], bias[0]), _mm256_sub_pd(row[2][1], bias[1]));
            // SAFETY: the row's second group (the caller's contract).
            unsafe { group::<false>(target, at + 4, f1, f2, lane_mask(rest >> 4), None, rgba) };
        }
        row = std::array::from_fn(|k| row[k].map(|e| _mm256_add_pd(e, step_y[k])));
    }
    covered
}

/// The AVX2 kernel: four pixels per step; the last `n % 4` pixels as the span's last four
/// with those already shaded masked off (spans shorter than four go to the scalar
/// kernel).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn shade_span(job: &mut SpanJob<'_>) {
    if job.target.checked_len() < 4 {
        return super::span_scalar(job);
    }
    // SAFETY: the CPU supports AVX2 and FMA (this function's contract).
    with_rgba!(*job.target.color, __m256d, _mm_set1_epi32, smooth, rgba => unsafe {
        span_groups(job, rgba)
    })
}

/// [`shade_span`] for one colour kind, on a span of at least four pixels.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn span_groups(job: &mut SpanJob<'_>, rgba: impl Fn(__m256d, __m256d) -> __m128i) {
    let n = job.target.checked_len();
    let lanes = _mm256_set_pd(3.0, 2.0, 1.0, 0.0);
    // The numerators at pixel `first + lane`: exact integers as everywhere
    // (`(first + lane) * step` is below 2^47, the sum below 2^49).
    let at = |first: usize| {
        let k = _mm256_add_pd(lanes, _mm256_set1_pd(first as f64));
        let f = |e: i64, step: i64| {
            _mm256_add_pd(_mm256_set1_pd(e as f64), _mm256_mul_pd(k, _mm256_set1_pd(step as f64)))
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
        unsafe { group::<true>(&mut job.target, k, f1, f2, all, None, &rgba) };
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
        unsafe { group::<true>(&mut job.target, n - 4, f1, f2, cover, None, &rgba) };
    }
}

/// [`super::shade_samples`] in AVX2: four samples per step, all of one pixel (two steps a
/// pixel at 8x), the colour at its centre, depth at each sample. Spans hold whole pixels, so
/// every group is whole.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn shade_samples(job: &mut SampleSpanJob<'_>) {
    // SAFETY: the CPU supports AVX2 and FMA (this function's contract).
    with_rgba!(*job.span.target.color, __m256d, _mm_set1_epi32, smooth, rgba => unsafe {
        sample_groups(job, rgba)
    })
}

/// Element `k` of the offsets of samples `first..first + 4`, modulo `n` (4 or 8: a mask, not
/// a division per lane), as four lanes. Written out: the closures it replaces were compiled
/// out of line and called per lane.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn offset_lanes<const K: usize>(
    offsets: &[[i64; K]; MAX_SAMPLES],
    first: usize,
    n: usize,
    k: usize,
) -> __m256d {
    debug_assert!(n == 4 || n == 8, "4 or 8 samples per pixel");
    let m = n - 1;
    _mm256_setr_pd(
        offsets[first & m][k] as f64,
        offsets[(first + 1) & m][k] as f64,
        offsets[(first + 2) & m][k] as f64,
        offsets[(first + 3) & m][k] as f64,
    )
}

/// [`shade_samples`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn sample_groups(job: &mut SampleSpanJob<'_>, rgba: impl Fn(__m256d, __m256d) -> __m128i) {
    let n = job.check();
    let samples = job.samples;
    // The offsets of samples 0-3 and, at 8x, 4-7.
    let o = &job.offsets;
    let half = |first| [offset_lanes(o, first, samples, 0), offset_lanes(o, first, samples, 1)];
    let halves = [half(0), half(4)];
    let span = &mut job.span;
    let (mut e1, mut e2) = (span.e1, span.e2);
    let all = _mm_set1_epi32(-1);
    for pixel in (0..n).step_by(samples) {
        // The centre's numerators in every lane: exact integers (below 2^49), as each
        // sample's, their sum with an offset.
        let (f1, f2) = (_mm256_set1_pd(e1 as f64), _mm256_set1_pd(e2 as f64));
        for (k, [o1, o2]) in halves.iter().enumerate().take(samples / 4) {
            let z = [_mm256_add_pd(f1, *o1), _mm256_add_pd(f2, *o2)];
            // SAFETY: the pixel's samples `pixel..pixel + samples` lie below `n` (spans hold
            // whole pixels), and `4 * k + 4 <= samples`.
            unsafe { group::<true>(&mut span.target, pixel + 4 * k, f1, f2, all, Some(z), &rgba) };
        }
        e1 += span.step1;
        e2 += span.step2;
    }
}

/// [`super::shade_narrow_samples`] in AVX2: each pixel of the box as one group of four
/// samples at 4x, two at 8x (a pixel's samples are contiguous, so a group lies in the
/// buffers whenever its pixel does), coverage the sign bits of the edge values stepped
/// exactly in `f64`, then [`sample_groups`]' arithmetic. No branch on coverage, as in
/// [`narrow_groups`]: skipping the groups with no covered sample made the soup at 4x 10%
/// slower (257-262 -> 287-299 ms, two threads).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn shade_narrow_samples(job: &mut NarrowSamplesJob<'_>) -> u64 {
    // A partly covered pixel's centre may lie outside the triangle, where a `SmoothRgb`'s
    // planes may leave [0, 255]: clamped, as the scalar `SpanColor::at` does.
    let color = *job.narrow.target.color;
    // SAFETY: the CPU supports this kernel's features (this function's contract).
    with_rgba!(clamped color, __m256d, _mm_set1_epi32, smooth, rgba => unsafe {
        narrow_sample_groups(job, rgba)
    })
}

/// [`shade_narrow_samples`] for one colour kind.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[inline]
#[target_feature(enable = "avx2,fma")]
unsafe fn narrow_sample_groups(
    job: &mut NarrowSamplesJob<'_>,
    rgba: impl Fn(__m256d, __m256d) -> __m128i,
) -> u64 {
    // The box lies in the buffers, `samples` elements per pixel (checked).
    job.check();
    let n = job.samples;
    // Edge k's offsets for samples 0-3 and, at 8x, 4-7.
    let o = &job.offsets;
    let half = |first| [0, 1, 2].map(|k| offset_lanes(o, first, n, k));
    let halves = [half(0), half(4)];
    let job = &mut job.narrow;
    let bias = job.bias.map(|b| b as f64);
    let mut row = job.edges.map(|e| e as f64);
    let mut covered = 0u64;
    for r in 0..job.rows {
        let mut e = row;
        for c in 0..job.columns {
            // The centre's numerators in every lane (exact integers, as each sample's).
            let f1 = _mm256_set1_pd(e[1] - bias[0]);
            let f2 = _mm256_set1_pd(e[2] - bias[1]);
            for (h, offsets) in halves.iter().enumerate().take(n / 4) {
                let at: [__m256d; 3] =
                    std::array::from_fn(|k| _mm256_add_pd(_mm256_set1_pd(e[k]), offsets[k]));
                let out = _mm256_movemask_pd(_mm256_or_pd(_mm256_or_pd(at[0], at[1]), at[2]));
                let bits = !(out as u32) & 0xF;
                covered += u64::from(bits.count_ones());
                let z = [
                    _mm256_sub_pd(at[1], _mm256_set1_pd(bias[0])),
                    _mm256_sub_pd(at[2], _mm256_set1_pd(bias[1])),
                ];
                let first = n * (job.first + r * job.stride + c) + 4 * h;
                // SAFETY: the pixel is in the box, so its `n` samples lie in the buffers
                // (checked), and this group's are its samples `4h..4h + 4` (`4h + 4 <= n`).
                unsafe {
                    group::<false>(&mut job.target, first, f1, f2, lane_mask(bits), Some(z), &rgba)
                };
            }
            e = std::array::from_fn(|k| e[k] + job.step_x[k] as f64);
        }
        row = std::array::from_fn(|k| row[k] + job.step_y[k] as f64);
    }
    covered
}

/// [`super::row_masks`]: a row's first four pixels in one register per edge, the next four
/// in a second when the box is wider; the sign bits of `e0 | e1 | e2` are the pixels out.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn row_masks(
    e: [i64; 3],
    step_x: [i64; 3],
    step_y: [i64; 3],
    columns: usize,
    out: &mut [u8],
) {
    let keep = ((1u32 << columns) - 1) as u8;
    let s = step_x;
    let mut lo: [__m256i; 3] = std::array::from_fn(|k| {
        _mm256_set_epi64x(e[k] + 3 * s[k], e[k] + 2 * s[k], e[k] + s[k], e[k])
    });
    let down: [__m256i; 3] = std::array::from_fn(|k| _mm256_set1_epi64x(step_y[k]));
    let outside = |v: &[__m256i; 3]| {
        let any = _mm256_or_si256(_mm256_or_si256(v[0], v[1]), v[2]);
        _mm256_movemask_pd(_mm256_castsi256_pd(any)) as u32
    };
    if columns <= 4 {
        for o in out.iter_mut() {
            *o = !(outside(&lo) as u8) & keep;
            lo = std::array::from_fn(|k| _mm256_add_epi64(lo[k], down[k]));
        }
    } else {
        let mut hi: [__m256i; 3] =
            std::array::from_fn(|k| _mm256_add_epi64(lo[k], _mm256_set1_epi64x(4 * s[k])));
        for o in out.iter_mut() {
            *o = !((outside(&lo) | outside(&hi) << 4) as u8) & keep;
            lo = std::array::from_fn(|k| _mm256_add_epi64(lo[k], down[k]));
            hi = std::array::from_fn(|k| _mm256_add_epi64(hi[k], down[k]));
        }
    }
}

/// [`super::index_range`]: 32 values a step in four pairs of accumulators (eight lanes each),
/// so that the loop waits on loads rather than on the latency of one min and one max chain;
/// the last `len % 32` values one at a time.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn index_range(values: &[u32]) -> (u32, u32) {
    let blocks = values.chunks_exact(32);
    let (tail_lo, tail_hi) = super::index_range_scalar(blocks.remainder());
    let mut lo = [_mm256_set1_epi32(-1); 4];
    let mut hi = [_mm256_setzero_si256(); 4];
    for block in blocks {
        for k in 0..4 {
            // SAFETY: `block` holds 32 values, so lanes `8k .. 8k + 8` lie within it; the
            // load is unaligned.
            let v = unsafe { _mm256_loadu_si256(block.as_ptr().add(8 * k).cast()) };
            lo[k] = _mm256_min_epu32(lo[k], v);
            hi[k] = _mm256_max_epu32(hi[k], v);
        }
    }
    let lo = _mm256_min_epu32(_mm256_min_epu32(lo[0], lo[1]), _mm256_min_epu32(lo[2], lo[3]));
    let hi = _mm256_max_epu32(_mm256_max_epu32(hi[0], hi[1]), _mm256_max_epu32(hi[2], hi[3]));
    let (mut l, mut h) = ([0u32; 8], [0u32; 8]);
    // SAFETY: each store writes 32 bytes to an eight-element array of 4-byte values.
    unsafe {
        _mm256_storeu_si256(l.as_mut_ptr().cast(), lo);
        _mm256_storeu_si256(h.as_mut_ptr().cast(), hi);
    }
    (l.into_iter().fold(tail_lo, u32::min), h.into_iter().fold(tail_hi, u32::max))
}

/// `i64` lanes of `v`, whose lanes hold integers below 2^51 in magnitude: adding 1.5 * 2^52
/// puts the integer in the low bits of the sum (one unit in the last place is 1), and
/// subtracting the bits of 1.5 * 2^52 leaves it, sign included.
#[inline]
#[target_feature(enable = "avx2,fma")]
fn exact_i64(v: __m256d) -> __m256i {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    let bits = _mm256_castpd_si256(_mm256_add_pd(v, _mm256_set1_pd(MAGIC)));
    _mm256_sub_epi64(bits, _mm256_castpd_si256(_mm256_set1_pd(MAGIC)))
}

/// [`super::window_group`] in AVX2: two halves of four triangles, in `f64` lanes. The
/// integer arithmetic of setup is exact there: snapped coordinates are within 2^23, their
/// differences within 2^24, every product within 2^48 and every sum within 2^49, all below
/// 2^53; pixel bounds are floors of exact quotients by 256. The snap rounds the exact
/// `x * 256` half to even, as `fixed::snap` does.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn window_group(tris: &[[Vertex; 3]; 8], cull: CullMode, out: &mut WindowGroup) {
    let mut clockwise = 0u8;
    // Per test, a bit per lane: finite, in range, degenerate, culled.
    let mut flags = [0u8; 4];
    for half in 0..2 {
        let four = &tris[4 * half..4 * half + 4];
        let zero = _mm256_setzero_pd();
        let mut finite = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
        let mut in_range = finite;
        let (mut xs, mut ys) = ([zero; 3], [zero; 3]);
        for v in 0..3 {
            // `[x, y, z, inv_w]` of vertex `v` of each of the four triangles, transposed into
            // a register per field.
            let head = |t: usize| {
                // SAFETY: the first sixteen bytes of a 20-byte `repr(C)` vertex, its four
                // `f32`s (its layout is asserted beside it); no alignment needed.
                unsafe { _mm_loadu_ps(std::ptr::from_ref(&four[t][v]).cast::<f32>()) }
            };
            let (r0, r1, r2, r3) = (head(0), head(1), head(2), head(3));
            let (xy01, zw01) = (_mm_unpacklo_ps(r0, r1), _mm_unpackhi_ps(r0, r1));
            let (xy23, zw23) = (_mm_unpacklo_ps(r2, r3), _mm_unpackhi_ps(r2, r3));
            let [x, y, z, w] = [
                _mm_movelh_ps(xy01, xy23),
                _mm_movehl_ps(xy23, xy01),
                _mm_movelh_ps(zw01, zw23),
                _mm_movehl_ps(zw23, zw01),
            ]
            .map(|f| _mm256_cvtps_pd(f));
            // Finite iff `v - v` is 0 (NaN for NaN and infinities; exact in `f64`).
            for f in [x, y, z, w] {
                finite =
                    _mm256_and_pd(finite, _mm256_cmp_pd::<_CMP_EQ_OQ>(_mm256_sub_pd(f, f), zero));
            }
            for f in [x, y] {
                let lo =
                    _mm256_cmp_pd::<_CMP_GE_OQ>(f, _mm256_set1_pd(f64::from(fixed::MIN_COORD)));
                let hi =
                    _mm256_cmp_pd::<_CMP_LT_OQ>(f, _mm256_set1_pd(f64::from(fixed::SNAP_LIMIT)));
                in_range = _mm256_and_pd(in_range, _mm256_and_pd(lo, hi));
            }
            let snap = |f: __m256d| {
                let scaled = _mm256_mul_pd(f, _mm256_set1_pd(f64::from(fixed::ONE)));
                _mm256_round_pd::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(scaled)
            };
            (xs[v], ys[v]) = (snap(x), snap(y));
        }
        let (sub, mul) = (|a, b| _mm256_sub_pd(a, b), |a, b| _mm256_mul_pd(a, b));
        let signed = sub(
            mul(sub(xs[1], xs[0]), sub(ys[2], ys[0])),
            mul(sub(xs[2], xs[0]), sub(ys[1], ys[0])),
        );
        let degenerate = _mm256_cmp_pd::<_CMP_EQ_OQ>(signed, zero);
        let cw = _mm256_cmp_pd::<_CMP_GT_OQ>(signed, zero);
        let culled = match cull {
            CullMode::None => zero,
            CullMode::Clockwise => cw,
            CullMode::CounterClockwise => _mm256_cmp_pd::<_CMP_LT_OQ>(signed, zero),
        };
        let area2 = _mm256_andnot_pd(_mm256_set1_pd(-0.0), signed);
        let min = |v: [__m256d; 3]| _mm256_min_pd(_mm256_min_pd(v[0], v[1]), v[2]);
        let max = |v: [__m256d; 3]| _mm256_max_pd(_mm256_max_pd(v[0], v[1]), v[2]);
        let half_px = f64::from(fixed::HALF);
        let scale = _mm256_set1_pd(1.0 / f64::from(fixed::ONE));
        // `first_centre_at_or_after(v) = floor((v + 127) / 256)`,
        // `last_centre_at_or_before(v) = floor((v - 128) / 256)`: exact quotients.
        let first =
            |v| _mm256_floor_pd(mul(_mm256_add_pd(v, _mm256_set1_pd(255.0 - half_px)), scale));
        let last = |v| _mm256_floor_pd(mul(sub(v, _mm256_set1_pd(half_px)), scale));
        let bounds = [first(min(xs)), first(min(ys)), last(max(xs)), last(max(ys))];
        let inv_area2 = _mm256_div_pd(_mm256_set1_pd(1.0), area2);
        let at = 4 * half;
        // SAFETY (the stores below): each writes four elements, from `at` (0 or 4), of an
        // array of eight: `i32` lanes as 16 bytes, `i64` and `f64` lanes as 32.
        unsafe {
            let store_i32 = |dst: &mut [i32; 8], v: __m256d| {
                _mm_storeu_si128(dst.as_mut_ptr().add(at).cast(), _mm256_cvtpd_epi32(v));
            };
            for v in 0..3 {
                store_i32(&mut out.x[v], xs[v]);
                store_i32(&mut out.y[v], ys[v]);
            }
            _mm256_storeu_si256(out.area2.as_mut_ptr().add(at).cast(), exact_i64(area2));
            for (dst, b) in out.bounds.iter_mut().zip(bounds) {
                store_i32(dst, b);
            }
            _mm256_storeu_pd(out.inv_area2.as_mut_ptr().add(at), inv_area2);
        }
        let bits = |m: __m256d| _mm256_movemask_pd(m) as u8;
        clockwise |= bits(cw) << at;
        for (flag, m) in flags.iter_mut().zip([finite, in_range, degenerate, culled]) {
            *flag |= bits(m) << at;
        }
    }
    out.clockwise = clockwise;
    out.rejected = super::rejections(flags);
}

/// [`super::window_records`] in AVX2: the record's sixteen words as eight lanes each (the
/// group's rows loaded as halves of four, as AVX2's [`window_group`] stores them, so that each
/// load takes one store's bytes; each vertex's depth and colour from its last sixteen bytes,
/// four triangles' transposed per half), then transposed into whole records ([`transpose8`],
/// its own inverse) and stored as two aligned 32-byte halves each.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn window_records(
    tris: &[[Vertex; 3]; 8],
    group: &super::WindowGroup,
    (clip, smooth, first_id): (&PixelRect, bool, i32),
    out: &mut super::WindowRecords,
) {
    // Loaded in the halves of four that AVX2's `window_group` stores (a load within one
    // store takes its bytes from it; AVX-512's stores each row whole, which contains both).
    // SAFETY: eight `i32`s, two loads of sixteen bytes within them; no alignment needed.
    let row =
        |r: &[i32; 8]| unsafe { _mm256_loadu2_m128i(r.as_ptr().add(4).cast(), r.as_ptr().cast()) };
    // `[y, z, inv_w, color]` of vertex `v` of triangles `k` and `k + 4`, one per half.
    let tail = |k: usize, v: usize| {
        let at = |t: usize| {
            let p = std::ptr::from_ref(&tris[t][v]).cast::<u8>();
            // SAFETY: bytes 4 to 20 of a 20-byte `repr(C)` vertex (its layout is asserted
            // beside it): `y`, `z`, `inv_w` and `color`.
            unsafe { p.add(4).cast::<__m128i>() }
        };
        // SAFETY: two reads of sixteen bytes of a vertex (above); no alignment needed.
        unsafe { _mm256_loadu2_m128i(at(k + 4), at(k)) }
    };
    let zero = _mm256_setzero_si256();
    let (mut z, mut color) = ([zero; 3], [zero; 3]);
    for v in 0..3 {
        let r = [tail(0, v), tail(1, v), tail(2, v), tail(3, v)];
        // Per half: `[y_a y_b z_a z_b]` and `[w_a w_b c_a c_b]` of two triangles, then the
        // depths and colours of four side by side.
        let (yz01, wc01) = (_mm256_unpacklo_epi32(r[0], r[1]), _mm256_unpackhi_epi32(r[0], r[1]));
        let (yz23, wc23) = (_mm256_unpacklo_epi32(r[2], r[3]), _mm256_unpackhi_epi32(r[2], r[3]));
        z[v] = _mm256_unpackhi_epi64(yz01, yz23);
        color[v] = _mm256_unpackhi_epi64(wc01, wc23);
    }
    // `1 / area2`: its low and high words, each lane's.
    let (lo, hi) = {
        let p = group.inv_area2.as_ptr();
        // SAFETY: eight `f64`s, 64 bytes, in two loads of 32; no alignment needed.
        let (a, b) = unsafe { (_mm256_loadu_si256(p.cast()), _mm256_loadu_si256(p.add(4).cast())) };
        let split = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
        let (a, b) = (_mm256_permutevar8x32_epi32(a, split), _mm256_permutevar8x32_epi32(b, split));
        (_mm256_permute2x128_si256::<0x20>(a, b), _mm256_permute2x128_si256::<0x31>(a, b))
    };
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let id = _mm256_add_epi32(_mm256_set1_epi32(first_id), lanes);
    // `clockwise` (0 or 1) in the low byte, `smooth` in the next, the padding zero.
    let cw = _mm256_srlv_epi32(_mm256_set1_epi32(i32::from(group.clockwise)), lanes);
    let cw = _mm256_and_si256(cw, _mm256_set1_epi32(1));
    let flags = _mm256_or_si256(cw, _mm256_set1_epi32(i32::from(smooth) << 8));
    let (x, y) = (group.x.each_ref().map(row), group.y.each_ref().map(row));
    let words = [
        [x[0], y[0], x[1], y[1], x[2], y[2], z[0], z[1]],
        [z[2], color[0], color[1], color[2], lo, hi, id, flags],
    ];
    let halves = words.map(|w| transpose8(&w));
    for (l, record) in out.records.iter_mut().enumerate() {
        let p = std::ptr::from_mut(record).cast::<__m256i>();
        // SAFETY: a record is 64 bytes aligned to 64 (`repr(C, align(64))`, its layout
        // asserted beside it): two aligned 32-byte stores fill it. Every byte written is
        // valid for its field: the `bool`s are 0 or 1, the padding zero.
        unsafe {
            _mm256_store_si256(p, halves[0][l]);
            _mm256_store_si256(p.add(1), halves[1][l]);
        }
    }
    // Coverage at 1x: the box within the clip (`PixelRect::intersect`).
    let b = group.bounds.each_ref().map(row);
    let cover = [
        _mm256_max_epi32(b[0], _mm256_set1_epi32(clip.x0)),
        _mm256_max_epi32(b[1], _mm256_set1_epi32(clip.y0)),
        _mm256_min_epi32(b[2], _mm256_set1_epi32(clip.x1)),
        _mm256_min_epi32(b[3], _mm256_set1_epi32(clip.y1)),
    ];
    for (dst, v) in out.cover.iter_mut().zip(cover) {
        // SAFETY: eight `i32`s, 32 bytes; the store needs no alignment.
        unsafe { _mm256_storeu_si256(dst.as_mut_ptr().cast(), v) };
    }
    let empty = _mm256_or_si256(
        _mm256_cmpgt_epi32(cover[0], cover[2]),
        _mm256_cmpgt_epi32(cover[1], cover[3]),
    );
    out.empty = bits_of(empty);
}

/// Words `0..8` of eight rows (`r[l]` the row of record `l`) as eight registers, register
/// `i` word `i` of every row: an 8 x 8 transpose of 32-bit words.
#[inline]
#[target_feature(enable = "avx2")]
fn transpose8(r: &[__m256i; 8]) -> [__m256i; 8] {
    // Pairs of rows interleaved: words 0-1 and 4-5 of rows l, l + 1 (`lo`), 2-3 and 6-7
    // (`hi`).
    let lo: [__m256i; 4] = std::array::from_fn(|k| _mm256_unpacklo_epi32(r[2 * k], r[2 * k + 1]));
    let hi: [__m256i; 4] = std::array::from_fn(|k| _mm256_unpackhi_epi32(r[2 * k], r[2 * k + 1]));
    // Quads: word j of rows 0-3 in `a[j]`, of rows 4-7 in `b[j]`, with word j + 4 in each
    // register's upper half.
    let a = [
        _mm256_unpacklo_epi64(lo[0], lo[1]),
        _mm256_unpackhi_epi64(lo[0], lo[1]),
        _mm256_unpacklo_epi64(hi[0], hi[1]),
        _mm256_unpackhi_epi64(hi[0], hi[1]),
    ];
    let b = [
        _mm256_unpacklo_epi64(lo[2], lo[3]),
        _mm256_unpackhi_epi64(lo[2], lo[3]),
        _mm256_unpacklo_epi64(hi[2], hi[3]),
        _mm256_unpackhi_epi64(hi[2], hi[3]),
    ];
    let mut out = [_mm256_setzero_si256(); 8];
    for j in 0..4 {
        out[j] = _mm256_permute2x128_si256::<0x20>(a[j], b[j]);
        out[j + 4] = _mm256_permute2x128_si256::<0x31>(a[j], b[j]);
    }
    out
}

/// The lanes of a comparison's result (all ones or zero per 32-bit lane) as bits.
#[inline]
#[target_feature(enable = "avx2")]
fn bits_of(v: __m256i) -> u8 {
    _mm256_movemask_ps(_mm256_castsi256_ps(v)) as u8
}

/// Lanes 0-3 and 4-7 of eight `f64`s, `f(0)` and `f(1)`.
#[inline(always)]
fn halves(f: impl Fn(usize) -> __m256d) -> [__m256d; 2] {
    [f(0), f(1)]
}

/// Eight `i32` lanes as `f64`: lanes 0-3 and 4-7.
#[inline]
#[target_feature(enable = "avx2")]
fn f64_halves(v: __m256i) -> [__m256d; 2] {
    [
        _mm256_cvtepi32_pd(_mm256_castsi256_si128(v)),
        _mm256_cvtepi32_pd(_mm256_extracti128_si256::<1>(v)),
    ]
}

/// [`super::narrow_eight`] in AVX2, as the AVX-512 version computes it: the eight records
/// loaded as two 256-bit registers each and transposed as two 8 x 8 matrices of words, the
/// integers side by side in eight `i32` lanes, the `f64` values in two registers of four
/// lanes (integers exact there, the planes `(a_i - a0) * inv_area2` as
/// [`crate::shade::PlaneEquation::with_inv_area2`] computes them).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn narrow_eight(
    records: &[&WindowRecord; 8],
    tile: &PixelRect,
    reach: i32,
    out: &mut NarrowEight,
) -> u8 {
    let row = |l: usize, half: usize| {
        // SAFETY: a record is 64 bytes aligned to 64 (`repr(C, align(64))`, no padding: its
        // layout is asserted beside it), so each 32-byte half is an aligned, initialized load.
        unsafe { _mm256_load_si256(std::ptr::from_ref(records[l]).cast::<__m256i>().add(half)) }
    };
    let low = transpose8(&std::array::from_fn(|l| row(l, 0)));
    let high = transpose8(&std::array::from_fn(|l| row(l, 1)));
    let word = |i: usize| if i < 8 { low[i] } else { high[i - 8] };
    let [x0, y0, x1, y1, x2, y2] = [word(0), word(1), word(2), word(3), word(4), word(5)];
    // `1 / area2`: words 12 (low) and 13 (high) of each record as one `f64`.
    let (ia, ib) =
        (_mm256_unpacklo_epi32(word(12), word(13)), _mm256_unpackhi_epi32(word(12), word(13)));
    let inv_area2 = [
        _mm256_castsi256_pd(_mm256_permute2x128_si256::<0x20>(ia, ib)),
        _mm256_castsi256_pd(_mm256_permute2x128_si256::<0x31>(ia, ib)),
    ];
    let half = _mm256_set1_epi32(fixed::HALF);
    let EightBoxes { width, px0, py0, columns, rows, .. } =
        eight_boxes_reaching([x0, y0, x1, y1, x2, y2], tile, reach);
    let zero = _mm256_setzero_si256();
    // Narrow before clipping, as `bin::coverage_algorithm` asks of the kernel's triangles.
    let narrow = bits_of(_mm256_cmpgt_epi32(_mm256_set1_epi32(crate::raster::edge::NARROW), width));
    let reaches = bits_of(_mm256_and_si256(
        _mm256_cmpgt_epi32(columns, zero),
        _mm256_cmpgt_epi32(rows, zero),
    ));
    let flags = word(15);
    let set = |v: __m256i, m: i32| {
        _mm256_xor_si256(
            _mm256_cmpeq_epi32(_mm256_and_si256(v, _mm256_set1_epi32(m)), zero),
            _mm256_set1_epi32(-1),
        )
    };
    out.smooth = bits_of(set(flags, 0xFF00));
    let alpha = _mm256_srli_epi32::<24>(word(9));
    out.one_alpha = bits_of(_mm256_and_si256(
        _mm256_cmpeq_epi32(alpha, _mm256_srli_epi32::<24>(word(10))),
        _mm256_cmpeq_epi32(alpha, _mm256_srli_epi32::<24>(word(11))),
    ));
    let lanes = narrow & reaches;
    // The edges, each leaving vertex `k + 1` for vertex `k + 2`, inside positive: negated
    // for counter-clockwise triangles.
    let clockwise = set(flags, 0xFF);
    let oriented = |d: __m256i| _mm256_blendv_epi8(_mm256_sub_epi32(zero, d), d, clockwise);
    let xs = [x0, x1, x2];
    let ys = [y0, y1, y2];
    let sample = |p: __m256i| _mm256_add_epi32(_mm256_slli_epi32::<8>(p), half);
    let (sx, sy) = (sample(px0), sample(py0));
    let put = |out: &mut [f64; 8], v: [__m256d; 2]| {
        // SAFETY: two groups of four `f64`s, 64 bytes; the stores need no alignment.
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), v[0]);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), v[1]);
        }
    };
    let step = _mm256_set1_pd(f64::from(fixed::ONE));
    for k in 0..3 {
        let (a, b) = ((k + 1) % 3, (k + 2) % 3);
        let ea = oriented(_mm256_sub_epi32(ys[a], ys[b]));
        let eb = oriented(_mm256_sub_epi32(xs[b], xs[a]));
        // `FillRule::bias`: 0 on owned edges (`a > 0`, or `a == 0` and `b > 0`), else -1.
        let owned = _mm256_or_si256(
            _mm256_cmpgt_epi32(ea, zero),
            _mm256_and_si256(_mm256_cmpeq_epi32(ea, zero), _mm256_cmpgt_epi32(eb, zero)),
        );
        let bias = f64_halves(_mm256_xor_si256(owned, _mm256_set1_epi32(-1)));
        let (ea, eb) = (f64_halves(ea), f64_halves(eb));
        let dx = f64_halves(_mm256_sub_epi32(sx, xs[a]));
        let dy = f64_halves(_mm256_sub_epi32(sy, ys[a]));
        let value = halves(|h| {
            let products = _mm256_add_pd(_mm256_mul_pd(ea[h], dx[h]), _mm256_mul_pd(eb[h], dy[h]));
            _mm256_add_pd(products, bias[h])
        });
        put(&mut out.edges[k], value);
        put(&mut out.step_x[k], halves(|h| _mm256_mul_pd(ea[h], step)));
        put(&mut out.step_y[k], halves(|h| _mm256_mul_pd(eb[h], step)));
        if k > 0 {
            put(&mut out.bias[k - 1], bias);
        }
    }
    let plane = |a: [[__m256d; 2]; 3], out: &mut [[f64; 8]; 3]| {
        let g =
            |v: [__m256d; 2]| halves(|h| _mm256_mul_pd(_mm256_sub_pd(v[h], a[0][h]), inv_area2[h]));
        put(&mut out[0], a[0]);
        put(&mut out[1], g(a[1]));
        put(&mut out[2], g(a[2]));
    };
    let z = |w: __m256i| {
        let w = _mm256_castsi256_ps(w);
        [_mm256_cvtps_pd(_mm256_castps256_ps128(w)), _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(w))]
    };
    plane([z(word(6)), z(word(7)), z(word(8))], &mut out.depth);
    let colors = [word(9), word(10), word(11)];
    for ch in 0..4 {
        let [c0, c1, c2] = [channel(colors[0], ch), channel(colors[1], ch), channel(colors[2], ch)];
        plane([f64_halves(c0), f64_halves(c1), f64_halves(c2)], &mut out.color[ch]);
    }
    put_lanes(out, (alpha, flat_colors(colors)), [px0, py0, columns, rows, word(14)]);
    lanes
}

/// Eight triangles' pixel boxes ([`eight_boxes_reaching`]).
pub(super) struct EightBoxes {
    /// The box's last column less its first, before clipping.
    pub width: __m256i,
    /// The box's last row less its first, before clipping.
    pub height: __m256i,
    /// The first column within the tile.
    pub px0: __m256i,
    /// The first row within the tile.
    pub py0: __m256i,
    /// Columns within the tile (none or fewer where the box misses it).
    pub columns: __m256i,
    /// Rows within the tile.
    pub rows: __m256i,
}

/// The boxes of eight triangles, their snapped vertices `[x0, y0, x1, y1, x2, y2]` in
/// `i32` lanes, with the extents widened by `reach` on every side, within `tile`: the pixels
/// any of whose samples lies in the extent, for a pattern reaching `reach` from the centre
/// each way on both axes; with `reach` 0, those whose centre `256 p + 128` does
/// ([`crate::setup::sample_bounds`] at the centre: arithmetic shifts floor, `+ 255` makes
/// the first one a ceiling).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn eight_boxes_reaching(v: [__m256i; 6], tile: &PixelRect, reach: i32) -> EightBoxes {
    let [x0, y0, x1, y1, x2, y2] = v;
    let (half, reach) = (_mm256_set1_epi32(fixed::HALF), _mm256_set1_epi32(reach));
    let min = |a, b, c| _mm256_sub_epi32(_mm256_min_epi32(_mm256_min_epi32(a, b), c), reach);
    let max = |a, b, c| _mm256_add_epi32(_mm256_max_epi32(_mm256_max_epi32(a, b), c), reach);
    let first = |v| {
        _mm256_srai_epi32::<8>(_mm256_add_epi32(_mm256_sub_epi32(v, half), _mm256_set1_epi32(255)))
    };
    let last = |v| _mm256_srai_epi32::<8>(_mm256_sub_epi32(v, half));
    let (bx0, by0) = (first(min(x0, x1, x2)), first(min(y0, y1, y2)));
    let (bx1, by1) = (last(max(x0, x1, x2)), last(max(y0, y1, y2)));
    let px0 = _mm256_max_epi32(bx0, _mm256_set1_epi32(tile.x0));
    let py0 = _mm256_max_epi32(by0, _mm256_set1_epi32(tile.y0));
    let px1 = _mm256_min_epi32(bx1, _mm256_set1_epi32(tile.x1));
    let py1 = _mm256_min_epi32(by1, _mm256_set1_epi32(tile.y1));
    let one = _mm256_set1_epi32(1);
    EightBoxes {
        width: _mm256_sub_epi32(bx1, bx0),
        height: _mm256_sub_epi32(by1, by0),
        px0,
        py0,
        columns: _mm256_add_epi32(_mm256_sub_epi32(px1, px0), one),
        rows: _mm256_add_epi32(_mm256_sub_epi32(py1, py0), one),
    }
}

/// Channel `ch` of eight RGBA8 words (low byte first).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn channel(w: __m256i, ch: usize) -> __m256i {
    let shifted = _mm256_srlv_epi32(w, _mm256_set1_epi32(8 * ch as i32));
    _mm256_and_si256(shifted, _mm256_set1_epi32(0xFF))
}

/// Eight triangles' flat colours from their vertices' RGBA8 words `c`: `flat_color`'s
/// `(2 * sum + 3) / 6` per channel, the division as a multiply and shift, exact for
/// numerators up to 1533 (43691 / 2^18 exceeds 1/6 by less than 1.3e-6, which lifts no
/// quotient to the next integer).
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn flat_colors(c: [__m256i; 3]) -> __m256i {
    let mut flat = _mm256_setzero_si256();
    for ch in 0..4 {
        let [c0, c1, c2] = [channel(c[0], ch), channel(c[1], ch), channel(c[2], ch)];
        let sum = _mm256_add_epi32(_mm256_add_epi32(c0, c1), c2);
        let twice = _mm256_add_epi32(_mm256_add_epi32(sum, sum), _mm256_set1_epi32(3));
        let mean = _mm256_srli_epi32::<18>(_mm256_mullo_epi32(twice, _mm256_set1_epi32(43691)));
        flat = _mm256_or_si256(flat, _mm256_sllv_epi32(mean, _mm256_set1_epi32(8 * ch as i32)));
    }
    flat
}

/// Stores a [`NarrowEight`]'s integer lanes: the shared alpha and flat colour, then the box
/// (first column, first row, columns, rows) and the id.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn put_lanes(
    out: &mut NarrowEight,
    (alpha, flat): (__m256i, __m256i),
    ints: [__m256i; 5],
) {
    let [x0, y0, columns, rows, id] = ints;
    let targets =
        [&mut out.alpha, &mut out.x0, &mut out.y0, &mut out.columns, &mut out.rows, &mut out.id];
    for (out, v) in targets.into_iter().zip([alpha, x0, y0, columns, rows, id]) {
        // SAFETY: eight `i32`s, 32 bytes; the store needs no alignment.
        unsafe { _mm256_storeu_si256(out.as_mut_ptr().cast(), v) }
    }
    // SAFETY: eight `u32`s, 32 bytes; the store needs no alignment.
    unsafe { _mm256_storeu_si256(out.flat.as_mut_ptr().cast(), flat) };
}

/// [`super::gouraud_eight`] in AVX2: the positions and normals read a component at a time
/// into lanes, then `glam`'s matrix products written out in its order.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn gouraud_eight(
    positions: &[[f32; 3]; 8],
    normals: Option<&[[f32; 3]; 8]>,
    eye: &super::EyeLanes,
    light: &super::WholeLight,
) -> ([f32; 8], [f32; 8]) {
    let lane = |a: &[[f32; 3]; 8], c: usize| {
        _mm256_setr_ps(a[0][c], a[1][c], a[2][c], a[3][c], a[4][c], a[5][c], a[6][c], a[7][c])
    };
    let splat = |v: f32| _mm256_set1_ps(v);
    // `Mat4 * (p - origin).extend(1.0)`: `((x_axis p.x + y_axis p.y) + z_axis p.z) + w_axis`,
    // the last term `w_axis * 1.0`, exact.
    let rel: [__m256; 3] =
        std::array::from_fn(|c| _mm256_sub_ps(lane(positions, c), splat(eye.origin[c])));
    let view = &eye.view;
    let to_eye: [__m256; 3] = std::array::from_fn(|k| {
        let xy = _mm256_add_ps(
            _mm256_mul_ps(splat(view[0][k]), rel[0]),
            _mm256_mul_ps(splat(view[1][k]), rel[1]),
        );
        let xyz = _mm256_add_ps(xy, _mm256_mul_ps(splat(view[2][k]), rel[2]));
        // The view position negated: towards the eye.
        _mm256_xor_ps(_mm256_add_ps(xyz, splat(view[3][k])), splat(-0.0))
    });
    // `Mat3 * n`: `(x_axis n.x + y_axis n.y) + z_axis n.z`; zero without normals.
    let m = &eye.normal;
    let n: [__m256; 3] = match normals {
        Some(normals) => {
            let n: [__m256; 3] = std::array::from_fn(|c| lane(normals, c));
            std::array::from_fn(|k| {
                let xy = _mm256_add_ps(
                    _mm256_mul_ps(splat(m[0][k]), n[0]),
                    _mm256_mul_ps(splat(m[1][k]), n[1]),
                );
                _mm256_add_ps(xy, _mm256_mul_ps(splat(m[2][k]), n[2]))
            })
        }
        None => [_mm256_setzero_ps(); 3],
    };
    stored(light_lanes(n, to_eye, light))
}

/// [`super::light_eight`] in AVX2.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn light_eight(
    n: &[[f32; 8]; 3],
    v: &[[f32; 8]; 3],
    light: &super::WholeLight,
) -> ([f32; 8], [f32; 8]) {
    // SAFETY: each load reads the eight `f32` of one array.
    let load = |a: &[f32; 8]| unsafe { _mm256_loadu_ps(a.as_ptr()) };
    stored(light_lanes(n.each_ref().map(load), v.each_ref().map(load), light))
}

/// Diffuse and specular lanes as arrays.
#[inline]
#[target_feature(enable = "avx2")]
fn stored((diffuse, specular): (__m256, __m256)) -> ([f32; 8], [f32; 8]) {
    let (mut d, mut s) = ([0.0f32; 8], [0.0f32; 8]);
    // SAFETY: each store writes the eight `f32` of one array.
    unsafe {
        _mm256_storeu_ps(d.as_mut_ptr(), diffuse);
        _mm256_storeu_ps(s.as_mut_ptr(), specular);
    }
    (d, s)
}

/// `Light::shade_towards` of eight lanes, from their normals `n` and directions to the eye
/// `v` (not normalised): `(diffuse + ambient, specular)`.
#[inline]
#[target_feature(enable = "avx2")]
fn light_lanes(n: [__m256; 3], v: [__m256; 3], light: &super::WholeLight) -> (__m256, __m256) {
    let zero = _mm256_setzero_ps();
    let n = unit_or(n, [0.0; 3]);
    let v = unit_or(v, [0.0, 0.0, 1.0]);
    let l = light.l.map(|c| _mm256_set1_ps(c));
    let h = unit_or(std::array::from_fn(|k| _mm256_add_ps(l[k], v[k])), [0.0, 0.0, 1.0]);
    let n_l = dot3(&n, &l);
    let diffuse = _mm256_add_ps(
        _mm256_set1_ps(light.ambient),
        // `max` returns its second operand for NaN, as `f32::max(NaN, 0)` gives 0.
        _mm256_mul_ps(_mm256_set1_ps(light.diffuse), _mm256_max_ps(n_l, zero)),
    );
    let n_h = _mm256_max_ps(dot3(&n, &h), zero);
    // `powi`'s steps: the odd bits of the exponent from the lowest, each factor the one
    // before squared, into a product that starts at 1.
    let (mut bits, mut factor, mut product) = (light.exponent, n_h, _mm256_set1_ps(1.0));
    loop {
        if bits & 1 == 1 {
            product = _mm256_mul_ps(product, factor);
        }
        bits >>= 1;
        if bits == 0 {
            break;
        }
        factor = _mm256_mul_ps(factor, factor);
    }
    let lit = _mm256_cmp_ps::<_CMP_GT_OQ>(n_l, zero);
    (diffuse, _mm256_and_ps(lit, _mm256_mul_ps(_mm256_set1_ps(light.specular), product)))
}

/// `(x x + y y) + z z` lane by lane: `glam`'s `Vec3::dot` order.
#[inline]
#[target_feature(enable = "avx2")]
fn dot3(a: &[__m256; 3], b: &[__m256; 3]) -> __m256 {
    let xy = _mm256_add_ps(_mm256_mul_ps(a[0], b[0]), _mm256_mul_ps(a[1], b[1]));
    _mm256_add_ps(xy, _mm256_mul_ps(a[2], b[2]))
}

/// `Vec3::normalize_or(fallback)` lane by lane: `x * (1 / length)` where `1 / length` is
/// finite and positive, `fallback` elsewhere.
#[inline]
#[target_feature(enable = "avx2")]
fn unit_or(x: [__m256; 3], fallback: [f32; 3]) -> [__m256; 3] {
    let rcp = _mm256_div_ps(_mm256_set1_ps(1.0), _mm256_sqrt_ps(dot3(&x, &x)));
    // Ordered comparisons: false for NaN.
    let ok = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GT_OQ>(rcp, _mm256_setzero_ps()),
        _mm256_cmp_ps::<_CMP_LT_OQ>(rcp, _mm256_set1_ps(f32::INFINITY)),
    );
    std::array::from_fn(|k| {
        _mm256_blendv_ps(_mm256_set1_ps(fallback[k]), _mm256_mul_ps(x[k], rcp), ok)
    })
}
