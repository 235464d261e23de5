//! Multisampling: the tiling, agreement, symmetry and fill-rule properties per sample, depth
//! per sample, colour once per pixel, and the linear-light resolve.

mod common;

use common::*;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::raster::{self, Algorithm, Span};
use trirast::sample::SampleCount;
use trirast::{CullMode, PixelRect, RenderOptions, Shading, Target, TriangleSetup, Vertex};

/// Covered (pixel, sample) pairs of one triangle, from both rasterizers (asserted equal).
fn sample_coverage(t: &TriangleSetup, clip: &PixelRect, samples: SampleCount) -> Vec<Vec<Span>> {
    (0..samples.count())
        .map(|s| {
            let spans = |alg| {
                let mut v = Vec::new();
                raster::rasterize_sample(alg, t, clip, samples.offset(s), |sp| v.push(sp));
                v
            };
            let (a, b) = (spans(Algorithm::EdgeFunctions), spans(Algorithm::Scanline));
            assert_eq!(a, b, "rasterizers disagree on sample {s} of {:?}", t.xy);
            assert_eq!(a, spans(Algorithm::EdgeMasks), "edge masks, sample {s} of {:?}", t.xy);
            a
        })
        .collect()
}

fn sample_point(px: i64, py: i64, samples: SampleCount, s: usize) -> P {
    let [ox, oy] = samples.offset(s);
    [centre(px) + ox, centre(py) + oy]
}

#[test]
fn tilings_cover_every_sample_exactly_once() {
    let mut rng = SmallRng::seed_from_u64(404);
    let (w, h) = (40u32, 32u32);
    let clip = PixelRect::of_target(w, h);
    for samples in [SampleCount::X4, SampleCount::X8] {
        let n = samples.count();
        let mut total = 0;
        let mut round = 0;
        while total < 30_000 {
            round += 1;
            let rect = if round % 3 == 0 {
                [-256 * 4000, -256 * 3000, 256 * 5000, 256 * 6000]
            } else {
                let x0 = coord(&mut rng, -6, 12);
                let y0 = coord(&mut rng, -6, 10);
                [x0, y0, x0 + coord(&mut rng, 8, 40), y0 + coord(&mut rng, 8, 30)]
            };
            let n_tris = rng.random_range(300..1500);
            let tris = random_tiling(&mut rng, rect, n_tris);
            total += tris.len();
            let mut count = vec![0u32; (w * h) as usize * n];
            for t in &tris {
                let Some(s) = setup(*t) else { continue };
                for (k, spans) in sample_coverage(&s, &clip, samples).iter().enumerate() {
                    for sp in spans {
                        for x in sp.x_start..sp.x_end {
                            count[(sp.y as usize * w as usize + x as usize) * n + k] += 1;
                        }
                    }
                }
            }
            for py in 0..h as i64 {
                for px in 0..w as i64 {
                    for k in 0..n {
                        let [x, y] = sample_point(px, py, samples, k);
                        let inside =
                            (rect[0]..rect[2]).contains(&x) && (rect[1]..rect[3]).contains(&y);
                        let got = count[(py as usize * w as usize + px as usize) * n + k];
                        assert_eq!(
                            got,
                            u32::from(inside),
                            "{samples:?} sample {k} of ({px}, {py})"
                        );
                    }
                }
            }
        }
    }
}

/// The same through `draw`: the overdraw buffer counts covered samples, and ids are written
/// per sample.
#[test]
fn tiling_through_draw_counts_samples() {
    let mut rng = SmallRng::seed_from_u64(7);
    let rect = [centre(2) + 40, centre(1) - 77, centre(45) + 3, centre(37) + 100];
    let tris = random_tiling(&mut rng, rect, 2000);
    let to_vertex = |p: P| Vertex::new(p[0] as f32 / 256.0, p[1] as f32 / 256.0, 0.5, [9; 4]);
    let triangles: Vec<[Vertex; 3]> = tris.iter().map(|t| t.map(to_vertex)).collect();
    for samples in [SampleCount::X4, SampleCount::X8] {
        let n = samples.count();
        let mut target = Target::multisampled(48, 40, samples).unwrap().with_overdraw().with_ids();
        let stats = trirast::draw(&mut target, &triangles, &RenderOptions::default()).unwrap();
        let overdraw = target.overdraw.as_ref().unwrap();
        let ids = target.ids.as_ref().unwrap();
        let mut inside_total = 0;
        for py in 0..40 {
            for px in 0..48 {
                let inside: Vec<bool> = (0..n)
                    .map(|k| {
                        let [x, y] = sample_point(px, py, samples, k);
                        (rect[0]..rect[2]).contains(&x) && (rect[1]..rect[3]).contains(&y)
                    })
                    .collect();
                let p = (py * 48 + px) as usize;
                let expect = inside.iter().filter(|&&b| b).count() as u32;
                assert_eq!(overdraw[p], expect, "{samples:?} ({px}, {py})");
                for (k, &is_in) in inside.iter().enumerate() {
                    assert_eq!(ids[p * n + k] >= 0, is_in, "id of sample {k} at ({px}, {py})");
                }
                inside_total += u64::from(expect);
            }
        }
        assert_eq!(stats.fragments, inside_total);
    }
}

#[test]
fn sample_coverage_matches_the_oracle() {
    let mut rng = SmallRng::seed_from_u64(17);
    let size = 24i64;
    let clip = PixelRect::of_target(size as u32, size as u32);
    for samples in [SampleCount::X4, SampleCount::X8] {
        for _ in 0..6_000 {
            let v = random_triangle(&mut rng, size);
            let Some(s) = setup(v) else { continue };
            for (k, spans) in sample_coverage(&s, &clip, samples).iter().enumerate() {
                let mut covered = vec![false; (size * size) as usize];
                for sp in spans {
                    for x in sp.x_start..sp.x_end {
                        covered[(sp.y as i64 * size + x as i64) as usize] = true;
                    }
                }
                for py in 0..size {
                    for px in 0..size {
                        let want = oracle_covers(v, sample_point(px, py, samples, k));
                        assert_eq!(
                            covered[(py * size + px) as usize],
                            want,
                            "{v:?} s{k} ({px}, {py})"
                        );
                    }
                }
            }
        }
    }
}

/// The 4x pattern is symmetric under 90-degree rotation: rotating a tie-free triangle about a
/// pixel centre maps its covered (pixel, sample) set onto the rotated triangle's.
#[test]
fn four_x_coverage_is_rotation_symmetric() {
    let mut rng = SmallRng::seed_from_u64(90);
    let samples = SampleCount::X4;
    let size = 40i64;
    let clip = PixelRect::of_target(size as u32, size as u32);
    let pattern = samples.pattern();
    // Rotation (dx, dy) -> (-dy, dx) permutes the pattern.
    let rotated_index: Vec<usize> = pattern
        .iter()
        .map(|&[dx, dy]| {
            pattern.iter().position(|&q| q == [-dy, dx]).expect("pattern is symmetric")
        })
        .collect();
    let c = centre(20);
    let mut checked = 0;
    for _ in 0..3000 {
        let v: [P; 3] = std::array::from_fn(|_| [coord(&mut rng, 10, 30), coord(&mut rng, 10, 30)]);
        let Some(s) = setup(v) else { continue };
        let ties = (0..size).any(|py| {
            (0..size).any(|px| {
                (0..4).any(|k| {
                    let [x, y] = sample_point(px, py, samples, k);
                    s.edges().iter().any(|e| e.eval(x, y) - trirast::FillRule::bias(e.a, e.b) == 0)
                })
            })
        });
        if ties {
            continue;
        }
        let rot = v.map(|[x, y]| [c - (y - c), c + (x - c)]);
        let a = sample_coverage(&s, &clip, samples);
        let b = sample_coverage(&setup(rot).unwrap(), &clip, samples);
        let set = |cov: &Vec<Vec<Span>>| {
            let mut out: Vec<(i64, i64, usize)> = Vec::new();
            for (k, spans) in cov.iter().enumerate() {
                for sp in spans {
                    out.extend((sp.x_start..sp.x_end).map(|x| (i64::from(x), i64::from(sp.y), k)));
                }
            }
            out.sort();
            out
        };
        let mut expect: Vec<_> = set(&a)
            .into_iter()
            .map(|(x, y, k)| (20 - (y - 20), 20 + (x - 20), rotated_index[k]))
            .collect();
        expect.sort();
        assert_eq!(set(&b), expect, "{v:?}");
        checked += 1;
    }
    assert!(checked > 500, "{checked}");
}

/// For each 4x sample position: a sample exactly on a left or top edge is in, exactly on a
/// right or bottom edge is out.
#[test]
fn edges_through_each_four_x_sample() {
    let samples = SampleCount::X4;
    for k in 0..4 {
        // Pixel (5, 5); its sample k in fixed point.
        let [sx, sy] = sample_point(5, 5, samples, k);
        let covers = |v: [P; 3]| {
            let t = setup(v).unwrap();
            let cov = sample_coverage(&t, &PixelRect::of_target(12, 12), samples);
            cov[k].iter().any(|sp| sp.y == 5 && (sp.x_start..sp.x_end).contains(&5))
        };
        let d = 256 * 3;
        // Vertical edge through the sample: triangle to its right (left edge) / left (right edge).
        assert!(covers([[sx, sy - d], [sx, sy + d], [sx + d, sy]]), "left edge, sample {k}");
        assert!(!covers([[sx, sy - d], [sx, sy + d], [sx - d, sy]]), "right edge, sample {k}");
        // Horizontal edge through the sample: triangle below (top edge) / above (bottom edge).
        assert!(covers([[sx - d, sy], [sx + d, sy], [sx, sy + d]]), "top edge, sample {k}");
        assert!(!covers([[sx - d, sy], [sx + d, sy], [sx, sy - d]]), "bottom edge, sample {k}");
        // A sloped left edge through the sample.
        assert!(
            covers([[sx - 256, sy - 512], [sx + 256, sy + 512], [sx + d, sy - d]]),
            "sloped left {k}"
        );
        assert!(
            !covers([[sx - 256, sy - 512], [sx + 256, sy + 512], [sx - d, sy + d]]),
            "sloped right {k}"
        );
    }
}

/// Depth is evaluated at each sample; colour once per pixel at its centre; the resolve
/// averages in linear light.
#[test]
fn depth_per_sample_colour_per_pixel_and_resolve() {
    let mut rng = SmallRng::seed_from_u64(3);
    for _ in 0..200 {
        let v: [Vertex; 3] = std::array::from_fn(|_| Vertex {
            x: rng.random_range(-4.0..20.0),
            y: rng.random_range(-4.0..20.0),
            z: rng.random_range(0.0..1.0),
            inv_w: 1.0,
            color: [rng.random(), rng.random(), rng.random(), 255],
        });
        let Ok(s) = TriangleSetup::new(&v, CullMode::None) else { continue };
        let samples = SampleCount::X8;
        let mut target = Target::multisampled(16, 16, samples).unwrap().with_ids();
        trirast::draw(&mut target, &[v], &RenderOptions::default().with_shading(Shading::Smooth))
            .unwrap();
        let shader = trirast::shade::TriangleShader::new(&v, &s, Shading::Smooth);
        for py in 0..16 {
            for px in 0..16 {
                let p = target.index(px, py);
                let (e1, e2) = s.barycentric_numerators(centre(px.into()), centre(py.into()));
                let centre_colour = shader.color_at(e1 as f64, e2 as f64);
                for k in 0..8 {
                    let [x, y] = sample_point(px.into(), py.into(), samples, k);
                    if !s.covers_point(x, y) {
                        assert_eq!(target.ids.as_ref().unwrap()[p * 8 + k], -1);
                        continue;
                    }
                    let (e1, e2) = s.barycentric_numerators(x, y);
                    assert_eq!(target.depth[p * 8 + k], shader.depth_at(e1 as f64, e2 as f64));
                    assert_eq!(target.color[p * 8 + k], centre_colour);
                }
            }
        }
    }
    // Resolve: half the samples white, half black -> linear 0.5 -> sRGB 188.
    let mut target = Target::multisampled(1, 1, SampleCount::X4).unwrap();
    target.color = vec![[255, 255, 255, 255], [0, 0, 0, 255], [255, 255, 255, 255], [0, 0, 0, 255]];
    assert_eq!(target.resolve(), vec![[188, 188, 188, 255]]);
}
