//! Coverage properties: watertight tilings, the two rasterizers agreeing with each other and
//! with an independent oracle, the fill rule's unit cases, symmetry, and the range extremes.

mod common;

use common::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::fixed;
use trirast::raster::{self, Algorithm};
use trirast::render::{Backend, Schedule};
use trirast::sample::SampleCount;
use trirast::{CullMode, PixelRect, RenderOptions, Shading, Target, TriangleSetup, Vertex};

/// Tilings of rectangles (inside the image, overlapping it, and reaching thousands of pixels
/// outside) cover every pixel centre of the half-open rectangle exactly once and nothing else.
#[test]
fn random_tilings_are_watertight() {
    let mut rng = SmallRng::seed_from_u64(0x7117);
    let (w, h) = (72u32, 56u32);
    let mut total = 0;
    let mut round = 0u64;
    while total < 120_000 {
        round += 1;
        let rect = match round % 4 {
            // Inside the image, edges on arbitrary sub-pixel positions.
            0 => {
                let x0 = coord(&mut rng, 0, 20);
                let y0 = coord(&mut rng, 0, 20);
                [x0, y0, x0 + coord(&mut rng, 10, 50), y0 + coord(&mut rng, 10, 35)]
            }
            // Edges exactly on pixel centres.
            1 => [centre(3), centre(2), centre(60), centre(50)],
            // Overlapping the image borders.
            2 => [
                -coord(&mut rng, 1, 30),
                -coord(&mut rng, 1, 30),
                coord(&mut rng, 40, 100),
                coord(&mut rng, 40, 90),
            ],
            // Reaching far outside.
            _ => [-256 * 5000, -256 * 3000, 256 * 9000, 256 * 7000],
        };
        let n = rng.random_range(500..3000);
        let tris = random_tiling(&mut rng, rect, n);
        total += tris.len();
        // Agreement on every tiling (cheap at this size).
        let count = count_coverage(&tris, w, h, true);
        for py in 0..h as i64 {
            for px in 0..w as i64 {
                let (x, y) = (centre(px), centre(py));
                let inside = (rect[0]..rect[2]).contains(&x) && (rect[1]..rect[3]).contains(&y);
                let got = count[(py * w as i64 + px) as usize];
                assert_eq!(
                    got,
                    u32::from(inside),
                    "round {round}: pixel ({px}, {py}) covered {got} times; rect {rect:?}"
                );
            }
        }
    }
    assert!(total >= 100_000);
}

/// The same property through the public draw call: the overdraw buffer is exactly 1 inside.
#[test]
fn tiling_overdraw_through_draw() {
    let mut rng = SmallRng::seed_from_u64(42);
    let rect = [centre(4) + 77, centre(3) - 31, centre(90) + 5, centre(61)];
    let tris = random_tiling(&mut rng, rect, 4000);
    let to_vertex = |p: P| Vertex::new(p[0] as f32 / 256.0, p[1] as f32 / 256.0, 0.5, [9; 4]);
    let triangles: Vec<[Vertex; 3]> = tris.iter().map(|t| t.map(to_vertex)).collect();
    for algorithm in [Algorithm::EdgeFunctions, Algorithm::Scanline] {
        let mut target = Target::new(100, 70).unwrap().with_overdraw().with_ids();
        let stats = trirast::draw(
            &mut target,
            &triangles,
            &RenderOptions::default().with_algorithm(algorithm),
        )
        .unwrap();
        assert_eq!(stats.rasterized, triangles.len());
        let overdraw = target.overdraw.as_ref().unwrap();
        for py in 0..70 {
            for px in 0..100 {
                let (x, y) = (centre(px), centre(py));
                let inside = (rect[0]..rect[2]).contains(&x) && (rect[1]..rect[3]).contains(&y);
                assert_eq!(overdraw[(py * 100 + px) as usize], u32::from(inside), "({px}, {py})");
            }
        }
        assert_eq!(stats.fragments, overdraw.iter().map(|&o| u64::from(o)).sum::<u64>());
    }
}

/// Edge functions, scanline walking and the independent 128-bit oracle agree on 150,000 random
/// triangles of every kind, including degenerate and near-degenerate ones.
#[test]
fn rasterizers_agree_with_each_other_and_the_oracle() {
    let mut rng = SmallRng::seed_from_u64(0xC0FFEE);
    let size = 40i64;
    let clip = PixelRect::of_target(size as u32, size as u32);
    for n in 0..150_000 {
        let v = random_triangle(&mut rng, size);
        let Some(s) = setup(v) else {
            assert_eq!(area2(v), 0, "setup rejected a non-degenerate triangle {v:?}");
            continue;
        };
        let spans = agreed_spans(&s, &clip);
        // Brute force over the image, every 8th triangle (the oracle is slow).
        if n % 8 == 0 {
            let mut covered = vec![false; (size * size) as usize];
            for sp in &spans {
                for x in sp.x_start..sp.x_end {
                    covered[(sp.y as i64 * size + x as i64) as usize] = true;
                }
            }
            for py in 0..size {
                for px in 0..size {
                    let want = oracle_covers(v, [centre(px), centre(py)]);
                    assert_eq!(covered[(py * size + px) as usize], want, "{v:?} at ({px}, {py})");
                }
            }
        }
    }
}

/// The trivial accept of tiles (`raster::covers_rect`, from the four corner pixels alone) holds
/// exactly when every pixel centre of the rectangle is covered, on random triangles and
/// rectangles of every size from one pixel up, many inside the triangle, many crossing it.
#[test]
fn rectangles_are_accepted_iff_every_pixel_is_covered() {
    let mut rng = SmallRng::seed_from_u64(0xB10C);
    let size = 40i64;
    let clip = PixelRect::of_target(size as u32, size as u32);
    let (mut accepted, mut refused) = (0, 0);
    for _ in 0..30_000 {
        let v = random_triangle(&mut rng, size);
        let Some(s) = setup(v) else { continue };
        let spans = agreed_spans(&s, &clip);
        let covered = |px: i32, py: i32| {
            spans.iter().any(|sp| sp.y == py && (sp.x_start..sp.x_end).contains(&px))
        };
        for _ in 0..4 {
            let (x0, y0) = (rng.random_range(0..size as i32), rng.random_range(0..size as i32));
            let r = PixelRect {
                x0,
                y0,
                x1: (x0 + rng.random_range(0..12)).min(size as i32 - 1),
                y1: (y0 + rng.random_range(0..12)).min(size as i32 - 1),
            };
            let all = (r.y0..=r.y1).all(|py| (r.x0..=r.x1).all(|px| covered(px, py)));
            assert_eq!(raster::covers_rect(&s, &r), all, "{v:?} on {r:?}");
            if all { accepted += 1 } else { refused += 1 }
        }
    }
    assert!(accepted > 1000 && refused > 1000, "{accepted} accepted, {refused} refused");
}

/// The trivial reject of tiles (`raster::TrivialReject`, which binning uses for
/// triangles over many tiles) never rejects a rectangle one of whose pixels has a covered
/// sample, at 1x, 4x and 8x, and does reject most rectangles the triangle stays clear of
/// (those outside one edge; a rectangle off a corner, outside two, may pass).
#[test]
fn rectangles_are_rejected_only_when_no_sample_is_covered() {
    let mut rng = SmallRng::seed_from_u64(0x5EC7);
    let size = 40i64;
    for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
        let (mut rejected, mut clear) = (0, 0);
        for _ in 0..10_000 {
            let v = random_triangle(&mut rng, size);
            let Some(s) = setup(v) else { continue };
            for _ in 0..4 {
                let (x0, y0) =
                    (rng.random_range(-8..size as i32), rng.random_range(-8..size as i32));
                let r = PixelRect {
                    x0,
                    y0,
                    x1: x0 + rng.random_range(0..12),
                    y1: y0 + rng.random_range(0..12),
                };
                let any = (r.y0..=r.y1).any(|py| {
                    (r.x0..=r.x1).any(|px| {
                        (0..samples.count()).any(|k| {
                            let [ox, oy] = samples.offset(k);
                            s.covers_point(centre(px.into()) + ox, centre(py.into()) + oy)
                        })
                    })
                });
                let misses = raster::TrivialReject::new(&s, samples.reach()).misses(&r);
                assert!(!(misses && any), "{v:?} on {r:?} at {samples:?}: a sample is covered");
                clear += usize::from(!any);
                rejected += usize::from(misses);
            }
        }
        assert!(rejected * 2 > clear, "{samples:?}: {rejected} rejected of {clear} clear");
    }
}

/// Scissor rectangles clip both rasterizers identically.
#[test]
fn scissor_clips_identically() {
    let mut rng = SmallRng::seed_from_u64(5);
    for _ in 0..5_000 {
        let v = random_triangle(&mut rng, 32);
        let Some(s) = setup(v) else { continue };
        let x0 = rng.random_range(-3..30);
        let y0 = rng.random_range(-3..30);
        let clip = PixelRect {
            x0,
            y0,
            x1: x0 + rng.random_range(0..20),
            y1: y0 + rng.random_range(0..20),
        };
        for sp in agreed_spans(&s, &clip) {
            assert!(
                sp.y >= clip.y0
                    && sp.y <= clip.y1
                    && sp.x_start >= clip.x0
                    && sp.x_end <= clip.x1 + 1
            );
            for x in sp.x_start..sp.x_end {
                assert!(s.covers(x, sp.y));
            }
        }
    }
}

fn covers_px(v: [[f32; 2]; 3], px: i32, py: i32) -> bool {
    let t = v.map(|[x, y]| Vertex::new(x, y, 0.5, [255; 4]));
    let s = TriangleSetup::new(&t, CullMode::None).unwrap();
    let reference = s.covers(px, py);
    for alg in [Algorithm::EdgeFunctions, Algorithm::Scanline] {
        let spans = raster::spans(alg, &s, &PixelRect { x0: -20, y0: -20, x1: 40, y1: 40 });
        let by_spans = spans.iter().any(|sp| sp.y == py && (sp.x_start..sp.x_end).contains(&px));
        assert_eq!(by_spans, reference, "{alg:?} on {v:?} at ({px}, {py})");
    }
    // The opposite winding decides the same.
    let r = [v[0], v[2], v[1]].map(|[x, y]| Vertex::new(x, y, 0.5, [255; 4]));
    assert_eq!(TriangleSetup::new(&r, CullMode::None).unwrap().covers(px, py), reference);
    reference
}

#[test]
fn fill_rule_unit_cases() {
    // Pixel (4, 2) has its centre at (4.5, 2.5).
    // Top edge: horizontal at y = 2.5, third vertex below.
    assert!(covers_px([[0.0, 2.5], [9.0, 2.5], [4.0, 7.0]], 4, 2), "top edge is in");
    // Bottom edge: horizontal at y = 2.5, third vertex above.
    assert!(!covers_px([[0.0, 2.5], [9.0, 2.5], [4.0, -3.0]], 4, 2), "bottom edge is out");
    // Left edge: vertical at x = 4.5, triangle to its right.
    assert!(covers_px([[4.5, -2.0], [4.5, 8.0], [9.0, 3.0]], 4, 2), "left edge is in");
    // Right edge: vertical at x = 4.5, triangle to its left.
    assert!(!covers_px([[4.5, -2.0], [4.5, 8.0], [0.0, 3.0]], 4, 2), "right edge is out");
    // Sloped left and right edges through (4.5, 2.5): the line from (2.5, -1.5) to (6.5, 6.5).
    assert!(covers_px([[2.5, -1.5], [6.5, 6.5], [9.0, -1.5]], 4, 2), "sloped left edge is in");
    assert!(!covers_px([[2.5, -1.5], [6.5, 6.5], [0.0, 6.5]], 4, 2), "sloped right edge is out");
    // A sample exactly at a vertex: in iff both edges meeting there own it.
    assert!(covers_px([[4.5, 2.5], [9.0, 2.5], [4.5, 7.0]], 4, 2), "top-left corner is in");
    assert!(!covers_px([[4.5, 2.5], [0.0, 2.5], [4.5, 7.0]], 4, 2), "top-right corner is out");
    assert!(!covers_px([[4.5, 2.5], [9.0, 2.5], [4.5, -3.0]], 4, 2), "bottom-left corner is out");
}

/// Around a vertex on a pixel centre, a closed fan of triangles covers that centre exactly once,
/// whatever the number and angles of the triangles.
#[test]
fn fan_vertex_is_covered_exactly_once() {
    let mut rng = SmallRng::seed_from_u64(99);
    for _ in 0..3000 {
        let c = [centre(10), centre(10)];
        let k = rng.random_range(3..12);
        let mut angles: Vec<f64> =
            (0..k).map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect();
        angles.sort_by(f64::total_cmp);
        let ring: Vec<P> = angles
            .iter()
            .map(|a| {
                let r = rng.random_range(1.0..8.0) * 256.0;
                // Some ring points land exactly on the axes through the centre.
                let (dx, dy) = (r * a.cos(), r * a.sin());
                let mut q = |d: f64| {
                    if rng.random_range(0..4) == 0 {
                        (d / 256.0).round() as i64 * 256
                    } else {
                        d as i64
                    }
                };
                [c[0] + q(dx), c[1] + q(dy)]
            })
            .collect();
        let tris: Vec<[P; 3]> = (0..k).map(|i| [c, ring[i], ring[(i + 1) % k]]).collect();
        // Only closed fans whose triangles all keep one orientation tile a neighbourhood.
        let sign = area2(tris[0]).signum();
        if sign == 0 || tris.iter().any(|t| area2(*t).signum() != sign) {
            continue;
        }
        let n = tris.iter().filter_map(|t| setup(*t)).filter(|s| s.covers(10, 10)).count();
        assert_eq!(n, 1, "fan {tris:?}");
    }
}

/// Exact translations by whole pixels translate coverage; exact 90-degree rotations about a
/// pixel centre rotate it whenever no pixel centre lies exactly on an edge (ties are
/// orientation-dependent by design).
#[test]
fn symmetry_under_translation_and_rotation() {
    let mut rng = SmallRng::seed_from_u64(1234);
    let size = 48i64;
    let clip = PixelRect::of_target(size as u32, size as u32);
    let pixels = |v: [P; 3]| -> Vec<(i64, i64)> {
        let Some(s) = setup(v) else { return Vec::new() };
        let mut out: Vec<(i64, i64)> = agreed_spans(&s, &clip)
            .iter()
            .flat_map(|sp| (sp.x_start..sp.x_end).map(move |x| (x as i64, sp.y as i64)))
            .collect();
        out.sort();
        out
    };
    let mut rotated_checked = 0;
    for _ in 0..4000 {
        // Keep triangles within the middle of the image so transforms stay inside the clip.
        let v: [P; 3] = std::array::from_fn(|_| [coord(&mut rng, 14, 34), coord(&mut rng, 14, 34)]);
        let base = pixels(v);
        let (tx, ty) = (rng.random_range(-10..10), rng.random_range(-10..10));
        let moved = pixels(v.map(|[x, y]| [x + 256 * tx, y + 256 * ty]));
        let expect: Vec<_> = base.iter().map(|&(x, y)| (x + tx, y + ty)).collect();
        assert_eq!(moved, expect, "translation of {v:?}");

        let Some(s) = setup(v) else { continue };
        let on_edge = (0..size).any(|py| {
            (0..size).any(|px| {
                let (x, y) = (centre(px), centre(py));
                s.edges().iter().any(|e| e.eval(x, y) - trirast::FillRule::bias(e.a, e.b) == 0)
            })
        });
        if on_edge {
            continue;
        }
        // Rotate by 90 degrees about the centre of pixel (24, 24): (x, y) -> (c - (y - c), ...).
        let c = centre(24);
        let rot = v.map(|[x, y]| [c - (y - c), c + (x - c)]);
        let mut expect: Vec<_> =
            base.iter().map(|&(x, y)| (24 - (y - 24), 24 + (x - 24))).collect();
        expect.sort();
        assert_eq!(pixels(rot), expect, "rotation of {v:?}");
        rotated_checked += 1;
    }
    assert!(rotated_checked > 1000, "too few tie-free triangles: {rotated_checked}");
}

/// Vertices at the very ends of the fixed-point range rasterize without overflow and agree
/// with the 128-bit oracle, on the widest and tallest targets supported.
#[test]
fn range_extremes_do_not_overflow() {
    let lo = -(1i64 << 23);
    let hi = (1i64 << 23) - 1;
    let big: [[P; 3]; 4] = [
        [[lo, lo], [hi, lo], [lo, hi]],
        [[hi, hi], [lo, hi], [hi, lo]],
        [[lo, lo], [hi, hi], [lo, hi]],
        [[lo, hi], [hi, lo + 1], [hi, hi]],
    ];
    for (w, h) in [(16384u32, 4u32), (4, 16384)] {
        let clip = PixelRect::of_target(w, h);
        for v in big {
            let s = setup(v).unwrap();
            let spans = agreed_spans(&s, &clip);
            // Check rows at both ends of the target against the oracle.
            for sp in spans.iter().filter(|sp| sp.y < 2 || sp.y as u32 >= h - 2) {
                for x in [sp.x_start, sp.x_end - 1] {
                    assert!(oracle_covers(v, [centre(x as i64), centre(sp.y as i64)]));
                }
                if sp.x_start > 0 {
                    assert!(!oracle_covers(
                        v,
                        [centre(sp.x_start as i64 - 1), centre(sp.y as i64)]
                    ));
                }
                if (sp.x_end as u32) < w {
                    assert!(!oracle_covers(v, [centre(sp.x_end as i64), centre(sp.y as i64)]));
                }
            }
        }
    }
    // Through the public API, with float vertices at the extremes: the range-filling square,
    // split along either diagonal, covers every pixel of the widest and tallest targets once.
    let v = |x: f32, y: f32| Vertex::new(x, y, 0.25, [1, 2, 3, 255]);
    let (l, h) = (-32768.0, 32767.996);
    let splits = [
        [[v(l, l), v(h, l), v(h, h)], [v(l, l), v(h, h), v(l, h)]],
        [[v(l, l), v(h, l), v(l, h)], [v(h, l), v(h, h), v(l, h)]],
    ];
    for (w, ht) in [(16384u32, 2u32), (2, 16384)] {
        for quad in splits {
            let mut target = Target::new(w, ht).unwrap().with_overdraw();
            trirast::draw(&mut target, &quad, &RenderOptions::default()).unwrap();
            assert!(target.overdraw.as_ref().unwrap().iter().all(|&o| o == 1));
            assert!(target.depth.iter().all(|&z| z == 0.25));
        }
    }
}

/// Triangles past the fixed-point range are clipped to the range, not refused: squares
/// with corners far outside it (up to the end of `f32`), split along either diagonal, cover
/// every pixel of the target exactly once, at the depth their corners share, on both backends;
/// each triangle counts once, as rasterized (the pieces clipping added apart).
#[test]
fn squares_past_the_range_cover_the_target_once() {
    let v = |x: f32, y: f32| Vertex::new(x, y, 0.25, [1, 2, 3, 255]);
    for far in [32768.0, 32767.999, 40000.5, 1e6, 1e20, 3e38] {
        let (l, h) = (-far, far);
        let splits = [
            [[v(l, l), v(h, l), v(h, h)], [v(l, l), v(h, h), v(l, h)]],
            [[v(l, l), v(h, l), v(l, h)], [v(h, l), v(h, h), v(l, h)]],
        ];
        for (w, ht) in [(64u32, 48u32), (16384, 2), (2, 16384)] {
            for quad in splits {
                for backend in [Backend::Reference, Backend::Tiled] {
                    let mut target = Target::new(w, ht).unwrap().with_overdraw().with_ids();
                    let options = RenderOptions::default().with_backend(backend);
                    let stats = trirast::draw(&mut target, &quad, &options).unwrap();
                    let what = format!("corners at {far}, {w} x {ht}, {backend:?}");
                    assert!(target.overdraw.as_ref().unwrap().iter().all(|&o| o == 1), "{what}");
                    assert!(target.depth.iter().all(|&z| z == 0.25), "{what}");
                    assert!(target.ids.as_ref().unwrap().iter().all(|&id| id == 0 || id == 1));
                    assert_eq!((stats.submitted, stats.rasterized), (2, 2), "{what}");
                    assert_eq!(stats.culled + stats.degenerate + stats.non_finite, 0, "{what}");
                }
            }
        }
    }
    // Targets, unlike vertices, have a hard limit.
    assert!(Target::new(16385, 1).is_err());
    assert!(Target::new(0, 1).is_err());
    assert!(Target::new(16384, 16384).is_ok() || cfg!(target_pointer_width = "32"));
}

/// A mesh mixing clipped and unclipped triangles stays watertight: a fan around a pixel
/// centre whose rim alternates pairs of corners inside the fixed-point range but far out
/// (beyond 32,000 pixels) with corners past the range. Each spoke to an in-range corner is
/// shared by a triangle drawn as it is and one that is clipped, and runs through pixel
/// centres of the image (its direction a small integer step from the centre), so a clipped
/// triangle that cut it and rounded the new corner would leave such a centre uncovered or
/// cover it twice. Every pixel is covered exactly once, on both backends.
#[test]
fn meshes_of_clipped_and_unclipped_triangles_stay_watertight() {
    let mut rng = SmallRng::seed_from_u64(77);
    let (w, h) = (160u32, 120u32);
    for round in 0..40 {
        let c = [rng.random_range(4..w - 4) as f32 + 0.5, rng.random_range(4..h - 4) as f32 + 0.5];
        let big = [4e4f32, 1e7, 1e12, 3e38][round % 4];
        // Steps (long, short) from the centre, and how far past 32,000 pixels a corner lies.
        let steps: [(i32, i32); 4] =
            std::array::from_fn(|_| (rng.random_range(29..47), rng.random_range(1..4)));
        let beyond: [f32; 8] = std::array::from_fn(|_| rng.random_range(1.0..400.0));
        // A corner whole steps of (dx, dy) from the centre: in range, past 32,000 pixels along
        // the step's long axis (at least 32,160 + 1 pixels from the centre, at most 32,606).
        let far_along = |dx: i32, dy: i32, k: usize| {
            let long = dx.abs().max(dy.abs()) as f32;
            let n = ((32_160.0 + beyond[k]) / long).floor() + 1.0;
            let p = [c[0] + n * dx as f32, c[1] + n * dy as f32];
            assert!(p.iter().all(|&v| fixed::snaps(v)) && p[0].abs().max(p[1].abs()) > 32_000.0);
            p
        };
        let [(a0, a1), (b0, b1), (e0, e1), (f0, f1)] = steps;
        // In angular order (clockwise on screen): right, down, left, up, a pair in range near
        // each axis, then a corner past the range on the diagonal after it.
        let rim = [
            far_along(a0, -a1, 0),
            far_along(b0, b1, 1),
            [big, big],
            far_along(e1, e0, 2),
            far_along(-f1, f0, 3),
            [-big, big],
            far_along(-a0, a1, 4),
            far_along(-b0, -b1, 5),
            [-big, -big],
            far_along(-e1, -e0, 6),
            far_along(f1, -f0, 7),
            [big, -big],
        ];
        let v = |p: [f32; 2]| Vertex::new(p[0], p[1], 0.5, [9, 9, 9, 255]);
        let fan: Vec<[Vertex; 3]> =
            (0..rim.len()).map(|k| [v(c), v(rim[k]), v(rim[(k + 1) % rim.len()])]).collect();
        for backend in [Backend::Reference, Backend::Tiled] {
            let mut target = Target::new(w, h).unwrap().with_overdraw();
            let options = RenderOptions::default().with_backend(backend);
            trirast::draw(&mut target, &fan, &options).unwrap();
            let overdraw = target.overdraw.unwrap();
            for (i, &o) in overdraw.iter().enumerate() {
                let (px, py) = (i as u32 % w, i as u32 / w);
                assert_eq!(o, 1, "pixel ({px}, {py}), round {round}, {backend:?}: {rim:?} {c:?}");
            }
        }
    }
}

/// A clipped triangle covers the pixel centres that the exact edges of the triangle it stands
/// for cover (its corners snapped, the edges evaluated in 128-bit integers, the top-left rule
/// included: `oracle_covers`), but for centres within 1/64 pixel of one of those edges: its
/// new corners on the range's bounds are rounded to the grid, which may turn an edge by a few
/// thousandths of a pixel across the image. Random triangles with one to three corners past
/// the range (up to 1e9 pixels away), at 1x.
#[test]
fn clipped_triangles_cover_what_their_exact_edges_cover() {
    let mut rng = SmallRng::seed_from_u64(4242);
    let (w, h) = (96u32, 64u32);
    let snap = |x: f32| (f64::from(x) * 256.0).round_ties_even() as i64;
    let (mut drawn_rounds, mut near_edges) = (0, 0);
    for round in 0..300 {
        let far_corners = 1 + round % 3;
        let tri: [Vertex; 3] = std::array::from_fn(|k| {
            let (x, y) = if k < far_corners {
                // Far along a random direction, often near an axis so edges cross the image.
                let angle = rng.random_range(0.0..std::f32::consts::TAU);
                let distance = 10f32.powf(rng.random_range(4.6..9.0));
                let (cx, cy) = (rng.random_range(0.0..w as f32), rng.random_range(0.0..h as f32));
                (cx + distance * angle.cos(), cy + distance * angle.sin())
            } else {
                (rng.random_range(-30.0..w as f32 + 30.0), rng.random_range(-30.0..h as f32 + 30.0))
            };
            Vertex::new(x, y, 0.5, [255; 4])
        });
        let mut target = Target::new(w, h).unwrap().with_ids();
        let options = RenderOptions::default().with_backend(Backend::Reference);
        trirast::draw(&mut target, &[tri], &options).unwrap();
        let corners: [P; 3] = tri.map(|v| [snap(v.x), snap(v.y)]);
        // Distance in pixels from centre `s` to the nearest edge line.
        let nearest_edge = |s: P| {
            (0..3)
                .map(|i| {
                    let (a, b) = (corners[i], corners[(i + 1) % 3]);
                    let (dx, dy) = ((b[0] - a[0]) as f64, (b[1] - a[1]) as f64);
                    let cross = dx * (s[1] - a[1]) as f64 - dy * (s[0] - a[0]) as f64;
                    cross.abs() / dx.hypot(dy) / 256.0
                })
                .fold(f64::INFINITY, f64::min)
        };
        let ids = target.ids.as_ref().unwrap();
        drawn_rounds += usize::from(ids.contains(&0));
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let s = [centre(x), centre(y)];
                let drawn = ids[(y * w as i64 + x) as usize] == 0;
                if drawn != oracle_covers(corners, s) {
                    let d = nearest_edge(s);
                    assert!(d < 1.0 / 64.0, "round {round}: pixel ({x}, {y}) {d} px from an edge");
                    near_edges += 1;
                }
            }
        }
    }
    // Not passing on empty images: most triangles reach the image.
    assert!(drawn_rounds > 150, "{drawn_rounds} of 300 rounds drew a pixel");
    assert!(near_edges < 300, "{near_edges} centres near an edge differed");
}

/// Among triangles within the range, one past it keeps its id, its flat colour (every piece
/// takes the triangle's, not its own corners' average) and its place in the order; one
/// wholly outside the range counts as culled, one with a NaN corner as non-finite;
/// both backends agree.
#[test]
fn a_clipped_triangle_keeps_its_id_colour_and_count() {
    let v = |x: f32, y: f32, z: f32, color: [u8; 4]| Vertex::new(x, y, z, color);
    let red = [255, 0, 0, 255];
    let tris = [
        [v(2.0, 2.0, 0.5, red), v(30.0, 2.0, 0.5, red), v(2.0, 30.0, 0.5, red)],
        // Past the range, nearer, the rows below y = 20: drawn over triangle 0 there.
        [
            v(-1e7, 20.0, 0.25, [10, 200, 30, 255]),
            v(1e7, 20.0, 0.25, [250, 20, 90, 255]),
            v(20.0, 1e7, 0.25, [40, 40, 255, 255]),
        ],
        [v(1e7, 0.0, 0.1, red), v(2e7, 0.0, 0.1, red), v(1e7, 1e7, 0.1, red)],
        [v(f32::NAN, 0.0, 0.1, red), v(1e9, 0.0, 0.1, red), v(0.0, 40.0, 0.1, red)],
    ];
    let flat = trirast::shade::flat_color(&tris[1]);
    let mut targets = [Backend::Reference, Backend::Tiled].map(|backend| {
        let mut target = Target::new(48, 40).unwrap().with_ids().with_overdraw();
        let options = RenderOptions::default().with_shading(Shading::Flat).with_backend(backend);
        let stats = trirast::draw(&mut target, &tris, &options).unwrap();
        assert_eq!(stats.submitted, 4);
        assert_eq!((stats.rasterized, stats.culled, stats.non_finite), (2, 1, 1), "{stats:?}");
        (stats, target)
    });
    let [(ref_stats, reference), (stats, tiled)] = &mut targets;
    assert_eq!(ref_stats, stats);
    assert!(reference.color == tiled.color && reference.ids == tiled.ids);
    let ids = reference.ids.as_ref().unwrap();
    assert!(ids.contains(&0) && ids.contains(&1) && !ids.iter().any(|&id| id > 1));
    for (p, &id) in ids.iter().enumerate() {
        if id == 1 {
            assert_eq!(reference.color[p], flat, "pixel {p}");
            assert_eq!(reference.depth[p], 0.25);
        }
    }
}

/// Exact counts of clipped triangles, in both backends and both schedules: one corner past
/// one bound makes a quadrilateral, two pieces (one rasterized triangle, one extra piece;
/// every pixel centre of the target lit once); a triangle meeting the range only along its
/// bound leaves pieces of zero area and counts as degenerate; one wholly past it counts as
/// culled.
#[test]
fn clipped_triangles_count_their_pieces_exactly() {
    let v = |x: f32, y: f32| Vertex::new(x, y, 0.5, [200, 100, 50, 255]);
    // The last `f32` that snaps: the range's bound, where the clip sets new corners.
    let bound = 32768.0 - 1.0 / 256.0;
    let tris = [
        // Its far corner past x's bound, its edges to it crossing the plane once each.
        [v(0.0, 0.0), v(0.0, 40.0), v(1e6, 20.0)],
        // Only its left edge, on the bound, within the range.
        [v(bound, 0.0), v(bound, 100.0), v(1e6, 50.0)],
        // Wholly past the range.
        [v(4e4, 0.0), v(5e4, 0.0), v(4e4, 1e4)],
    ];
    for backend in [Backend::Reference, Backend::Tiled] {
        for schedule in [Schedule::Binned, Schedule::Banded] {
            let mut target = Target::new(40, 40).unwrap().with_overdraw();
            let options = RenderOptions::default().with_backend(backend).with_schedule(schedule);
            let stats = trirast::draw(&mut target, &tris, &options).unwrap();
            let what = format!("{backend:?}, {schedule:?}: {stats:?}");
            assert_eq!(stats.submitted, 3, "{what}");
            assert_eq!((stats.rasterized, stats.extra_pieces), (1, 1), "{what}");
            assert_eq!((stats.degenerate, stats.culled, stats.non_finite), (1, 1, 0), "{what}");
            // Within the target the first triangle's edges to its far corner stay within
            // 0.001 of its top and bottom rows' outer sides: every pixel centre, once.
            let overdraw = target.overdraw.unwrap();
            assert!(overdraw.iter().all(|&n| n == 1), "{what}");
            assert_eq!(stats.fragments, 40 * 40, "{what}");
        }
    }
}

#[test]
fn non_finite_vertices_are_dropped_and_counted() {
    let v = |x: f32, y: f32| Vertex::new(x, y, 0.5, [255; 4]);
    let mut target = Target::new(8, 8).unwrap().with_overdraw();
    let tris = [
        [v(0.0, 0.0), v(f32::NAN, 0.0), v(0.0, 5.0)],
        [v(0.0, 0.0), v(8.0, f32::INFINITY), v(0.0, 5.0)],
        [v(0.0, 0.0), v(8.0, 0.0), v(0.0, 8.0)],
    ];
    let stats = trirast::draw(&mut target, &tris, &RenderOptions::default()).unwrap();
    assert_eq!(stats.non_finite, 2);
    assert_eq!(stats.rasterized, 1);
    let drawn: u32 = target.overdraw.unwrap().iter().sum();
    assert_eq!(u64::from(drawn), stats.fragments);
}

/// The public rectangle tests answer rightly for rectangles reaching to `i32`'s ends and for
/// any reach (they had overflowed their edge functions: a debug panic, a wrong answer in
/// release): no triangle covers the whole plane, none misses it, a big one covers a square
/// inside it, a small one misses a far rectangle; a sample's box for an offset past any
/// target is off every target.
#[test]
fn rectangle_tests_take_any_rectangle() {
    let red = [255, 0, 0, 255];
    let huge = Vertex::new;
    let big = TriangleSetup::new(
        &[
            huge(-32000.0, -32000.0, 0.5, red),
            huge(32000.0, -32000.0, 0.5, red),
            huge(0.0, 32000.0, 0.5, red),
        ],
        CullMode::None,
    )
    .unwrap();
    let small = TriangleSetup::new(
        &[huge(2.0, 2.0, 0.5, red), huge(9.0, 2.0, 0.5, red), huge(2.0, 9.0, 0.5, red)],
        CullMode::None,
    )
    .unwrap();
    let all = PixelRect { x0: i32::MIN, y0: i32::MIN, x1: i32::MAX, y1: i32::MAX };
    let inner = PixelRect { x0: -100, y0: -100, x1: 100, y1: 100 };
    for reach in [0, 96, i64::MAX, i64::MIN] {
        for tri in [&big, &small] {
            // No triangle covers the whole plane; the big one covers the inner square.
            assert!(!raster::covers_rect_within(tri, &all, reach));
            let reject = raster::TrivialReject::new(tri, reach);
            assert!(!reject.misses(&all), "{reach}");
        }
        let far = PixelRect { x0: i32::MAX - 10, y0: 0, x1: i32::MAX, y1: 10 };
        assert!(raster::TrivialReject::new(&small, reach.clamp(0, 1 << 20)).misses(&far));
    }
    assert!(raster::covers_rect(&big, &inner));
    assert!(!raster::covers_rect(&small, &inner));
    // Offsets past any target move the box off every target.
    for offset in [[i64::MAX, i64::MIN], [i64::MIN, i64::MAX], [i64::MIN, 0]] {
        let b = small.sample_bounds(offset);
        assert!(b.intersect(&inner).is_none(), "{b:?}");
    }
    assert_eq!(small.sample_bounds([0, 0]), small.bounds);
}
