//! Shared generators and an independent coverage oracle for the property tests.
#![allow(dead_code)]

pub mod xorshift;

use rand::Rng;
use trirast::raster::{self, Algorithm, Span};
use trirast::{CullMode, PixelRect, TriangleSetup};

/// A fixed-point point (1/256 pixel units).
pub type P = [i64; 2];

/// Pixel-centre coordinate of index `p`, fixed point.
pub fn centre(p: i64) -> i64 {
    p * 256 + 128
}

/// Geometric side of `p` relative to the directed line `a -> b` (sign of the cross product).
fn side(a: P, b: P, p: P) -> i128 {
    let (ax, ay, bx, by, px, py) =
        (a[0] as i128, a[1] as i128, b[0] as i128, b[1] as i128, p[0] as i128, p[1] as i128);
    (bx - ax) * (py - ay) - (by - ay) * (px - ax)
}

/// The coverage rule stated from its definition, with no shared code and 128-bit arithmetic:
/// a sample is covered iff it is strictly on the inner side of every edge, or exactly on an
/// edge that is *top* (horizontal, third vertex below, y down) or *left* (third vertex to the
/// right of the edge's line at the third vertex's height) and on the inner side of the others.
pub fn oracle_covers(v: [P; 3], s: P) -> bool {
    if side(v[0], v[1], v[2]) == 0 {
        return false;
    }
    (0..3).all(|i| {
        let (a, b, c) = (v[i], v[(i + 1) % 3], v[(i + 2) % 3]);
        let inner = side(a, b, c).signum();
        let here = side(a, b, s).signum();
        if here != 0 {
            return here == inner;
        }
        let top = a[1] == b[1] && c[1] > a[1];
        let left = a[1] != b[1] && {
            // x of the edge line at c's height is left of c.
            let (ax, ay, bx, by, cx, cy) = (
                a[0] as i128,
                a[1] as i128,
                b[0] as i128,
                b[1] as i128,
                c[0] as i128,
                c[1] as i128,
            );
            ((cx - ax) * (by - ay) - (cy - ay) * (bx - ax)) * (by - ay).signum() > 0
        };
        top || left
    })
}

/// Sets up a triangle from fixed-point vertices (no culling).
pub fn setup(v: [P; 3]) -> Option<TriangleSetup> {
    TriangleSetup::from_snapped(v, CullMode::None).ok()
}

/// Spans from both rasterizers (and the edge functions' row-mask variant), asserted equal.
pub fn agreed_spans(t: &TriangleSetup, clip: &PixelRect) -> Vec<Span> {
    let a = raster::spans(Algorithm::EdgeFunctions, t, clip);
    let b = raster::spans(Algorithm::Scanline, t, clip);
    assert_eq!(a, b, "edge functions and scanline disagree on {:?}", t.xy);
    let c = raster::spans(Algorithm::EdgeMasks, t, clip);
    assert_eq!(a, c, "edge functions and edge masks disagree on {:?}", t.xy);
    a
}

/// A random fixed-point coordinate in `[lo, hi)` pixels, on one of several grids: pixel
/// centres, pixel edges, half-pixel steps, or any 1/256 step.
pub fn coord(rng: &mut impl Rng, lo: i64, hi: i64) -> i64 {
    let p = rng.random_range(lo..hi);
    match rng.random_range(0..4) {
        0 => centre(p),
        1 => p * 256,
        2 => p * 256 + 128 * rng.random_range(0..2),
        _ => p * 256 + rng.random_range(0..256),
    }
}

/// A random triangle of one of several kinds within roughly `[-margin, size + margin)`:
/// small, medium, huge, slivers, near-degenerate and exactly degenerate.
pub fn random_triangle(rng: &mut impl Rng, size: i64) -> [P; 3] {
    let pt = |rng: &mut dyn FnMut() -> i64| [rng(), rng()];
    match rng.random_range(0..7) {
        0 => {
            // Small: within a few pixels.
            let c = [coord(rng, -2, size + 2), coord(rng, -2, size + 2)];
            std::array::from_fn(|_| {
                [c[0] + rng.random_range(-800..800), c[1] + rng.random_range(-800..800)]
            })
        }
        1 => std::array::from_fn(|_| [coord(rng, -4, size + 4), coord(rng, -4, size + 4)]),
        2 => {
            // Huge: far outside the image, up to the range limits.
            std::array::from_fn(|_| {
                [rng.random_range(-(1 << 23)..(1 << 23)), rng.random_range(-(1 << 23)..(1 << 23))]
            })
        }
        3 => {
            // Sliver: the third vertex within a few units of the line through the first two.
            let a = [coord(rng, -8, size + 8), coord(rng, -8, size + 8)];
            let b = [coord(rng, -8, size + 8), coord(rng, -8, size + 8)];
            let t = rng.random_range(-0.5..1.5f64);
            let c = [
                a[0] + ((b[0] - a[0]) as f64 * t) as i64 + rng.random_range(-3..=3),
                a[1] + ((b[1] - a[1]) as f64 * t) as i64 + rng.random_range(-3..=3),
            ];
            [a, b, c]
        }
        4 => {
            // Exactly degenerate: collinear on an integer direction.
            let a = [coord(rng, 0, size), coord(rng, 0, size)];
            let d = [rng.random_range(-300..300), rng.random_range(-300..300)];
            let (s, t) = (rng.random_range(-5..5), rng.random_range(-5..5));
            [a, [a[0] + s * d[0], a[1] + s * d[1]], [a[0] + t * d[0], a[1] + t * d[1]]]
        }
        5 => {
            // Axis-aligned edges through pixel centres (exercises top/bottom/left/right ties).
            let x0 = centre(rng.random_range(-2..size + 2));
            let y0 = centre(rng.random_range(-2..size + 2));
            let x1 = centre(rng.random_range(-2..size + 2));
            let y1 = centre(rng.random_range(-2..size + 2));
            let mut v = [[x0, y0], [x1, y0], [x0, y1]];
            if rng.random() {
                v.swap(1, 2);
            }
            v
        }
        _ => {
            let mut r = || coord(rng, -1, size + 1);
            [pt(&mut r), pt(&mut r), pt(&mut r)]
        }
    }
}

/// Counts, per pixel of a `w x h` image, the triangles covering its centre (via spans).
pub fn count_coverage(tris: &[[P; 3]], w: u32, h: u32, check_agreement: bool) -> Vec<u32> {
    let clip = PixelRect::of_target(w, h);
    let mut count = vec![0u32; (w * h) as usize];
    for &t in tris {
        let Some(s) = setup(t) else { continue };
        let spans = if check_agreement {
            agreed_spans(&s, &clip)
        } else {
            raster::spans(Algorithm::EdgeFunctions, &s, &clip)
        };
        for sp in spans {
            for x in sp.x_start..sp.x_end {
                count[(sp.y as u32 * w + x as u32) as usize] += 1;
            }
        }
    }
    count
}

/// Twice the signed area (y down: > 0 clockwise on screen).
pub fn area2(v: [P; 3]) -> i128 {
    side(v[0], v[1], v[2])
}

/// A random triangulation of the rectangle `[x0, x1) x [y0, y1)` (fixed point), built by
/// repeatedly splitting a random triangle at a random interior point (snapped to pixel
/// centres, pixel edges or any 1/256 step) and flipping random interior edges of convex quads.
/// Every step keeps all triangles with the same non-zero orientation, so they always tile the
/// rectangle exactly.
pub fn random_tiling(rng: &mut impl Rng, rect: [i64; 4], n: usize) -> Vec<[P; 3]> {
    let [x0, y0, x1, y1] = rect;
    let mut tris = vec![[[x0, y0], [x1, y0], [x1, y1]], [[x0, y0], [x1, y1], [x0, y1]]];
    let mut attempts = 0;
    while tris.len() < n && attempts < 50 * n {
        attempts += 1;
        let i = rng.random_range(0..tris.len());
        if rng.random_range(0..3) == 0 {
            flip_edge(&mut tris, i, rng.random_range(0..3));
            continue;
        }
        let t = tris[i];
        // A random point inside, snapped to one of the grids.
        let (a, b) = (rng.random_range(0.0..1.0f64), rng.random_range(0.0..1.0f64));
        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
        let f = |k: usize| {
            t[0][k] as f64 + a * (t[1][k] - t[0][k]) as f64 + b * (t[2][k] - t[0][k]) as f64
        };
        let grid = match rng.random_range(0..3) {
            0 => 1,
            1 => 128,
            _ => 256,
        };
        let snap = |v: f64, off: i64| ((v - off as f64) / grid as f64).round() as i64 * grid + off;
        let off = if grid == 256 && rng.random() { 128 } else { 0 };
        let p = [snap(f(0), off), snap(f(1), off)];
        let parts = [[t[0], t[1], p], [t[1], t[2], p], [t[2], t[0], p]];
        let sign = area2(t).signum();
        if parts.iter().all(|q| area2(*q).signum() == sign) {
            tris.swap_remove(i);
            tris.extend(parts);
        }
    }
    tris
}

/// Flips edge `k` of triangle `i` with its neighbour when the quad they form is convex.
fn flip_edge(tris: &mut [[P; 3]], i: usize, k: usize) {
    let t = tris[i];
    let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
    // The neighbour has the edge reversed: b -> a.
    let Some(j) = (0..tris.len())
        .find(|&j| j != i && (0..3).any(|m| tris[j][m] == b && tris[j][(m + 1) % 3] == a))
    else {
        return;
    };
    let m = (0..3).find(|&m| tris[j][m] == b).unwrap();
    let d = tris[j][(m + 2) % 3];
    let (new1, new2) = ([c, a, d], [d, b, c]);
    let sign = area2(t).signum();
    if area2(new1).signum() == sign && area2(new2).signum() == sign {
        tris[i] = new1;
        tris[j] = new2;
    }
}
