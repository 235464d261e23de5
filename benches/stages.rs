//! Micro-benchmarks of the pipeline stages: triangle setup, binning, the span and narrow
//! triangle kernels (1x, 4x, 8x), eight two-pixel triangles shaded together, and the 3D
//! front end's window corners and corner tests, at every SIMD level this CPU has.
//! `cargo bench --bench stages`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::Vec4;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use trirast::bin::Bins;
use trirast::clip::ClipVolume;
use trirast::fixed;
use trirast::pipeline::Viewport;
use trirast::sample::SampleCount;
use trirast::shade::DepthTest;
use trirast::simd::{
    self, Corner, KernelTarget, NarrowJob, NarrowSamplesJob, PerspectiveColor, SampleSpanJob,
    SimdLevel, SmallEight, SmallLane, SmallShading, SpanColor, SpanJob,
};
use trirast::{CullMode, PixelRect, TriangleSetup, Vertex};

fn triangles(n: usize) -> Vec<[Vertex; 3]> {
    let mut rng = SmallRng::seed_from_u64(1);
    (0..n)
        .map(|_| {
            let (cx, cy) = (rng.random_range(0.0..1920.0f32), rng.random_range(0.0..1080.0f32));
            std::array::from_fn(|_| {
                Vertex::new(
                    cx + rng.random_range(-4.0..4.0),
                    cy + rng.random_range(-4.0..4.0),
                    rng.random_range(0.0..1.0),
                    [200; 4],
                )
            })
        })
        .collect()
}

fn setup(c: &mut Criterion) {
    let tris = triangles(10_000);
    let mut g = c.benchmark_group("setup");
    g.throughput(Throughput::Elements(tris.len() as u64));
    g.bench_function("small triangles", |b| {
        b.iter(|| {
            tris.iter().filter(|t| TriangleSetup::new(black_box(t), CullMode::None).is_ok()).count()
        })
    });
    g.finish();
}

fn binning(c: &mut Criterion) {
    let tris = triangles(16_384);
    let bounds: Vec<Option<PixelRect>> =
        tris.iter().map(|t| TriangleSetup::new(t, CullMode::None).ok().map(|s| s.bounds)).collect();
    let mut g = c.benchmark_group("bin");
    g.throughput(Throughput::Elements(bounds.len() as u64));
    g.bench_function("16k small triangles, 1080p", |b| {
        b.iter(|| Bins::build(black_box(&bounds), 1920, 1080))
    });
    g.finish();
}

/// The kernels' shading in every bench: smooth opaque colour (three planes and one alpha, as
/// for a triangle whose vertices share one alpha), LESS depth, no id or overdraw buffer.
fn smooth_target<'a>(depth: &'a mut [f32], color: &'a mut [[u8; 4]]) -> KernelTarget<'a> {
    const PLANES: [[f64; 3]; 3] = [[100.0, 1e-9, -2e-9], [50.0, 2e-9, 1e-9], [20.0, 0.0, 3e-9]];
    KernelTarget {
        depth_plane: [0.5, 1e-12, 1e-12],
        color: &SpanColor::SmoothRgb(PLANES, 255),
        depth_test: DepthTest::Less,
        id: 1,
        depth,
        color_out: color,
        ids: None,
        overdraw: None,
    }
}

/// The narrow kernels' job for triangle `s`'s box, on buffers whose rows are `stride` pixels
/// apart.
fn narrow_job<'a>(
    s: &TriangleSetup,
    stride: usize,
    depth: &'a mut [f32],
    color: &'a mut [[u8; 4]],
) -> NarrowJob<'a> {
    let (x, y) = (fixed::pixel_centre(s.bounds.x0), fixed::pixel_centre(s.bounds.y0));
    let edges = s.edges().map(|e| e.eval(x, y));
    let (e1, e2) = s.barycentric_numerators(x, y);
    NarrowJob {
        edges,
        step_x: s.edges().map(|e| e.a * 256),
        step_y: s.edges().map(|e| e.b * 256),
        bias: [edges[1] - e1, edges[2] - e2],
        columns: (s.bounds.x1 - s.bounds.x0 + 1) as usize,
        rows: (s.bounds.y1 - s.bounds.y0 + 1) as usize,
        first: 0,
        stride,
        target: smooth_target(depth, color),
    }
}

fn kernels(c: &mut Criterion) {
    let mut g = c.benchmark_group("span kernel");
    let n = 64;
    g.throughput(Throughput::Elements(n as u64));
    for level in SimdLevel::available() {
        let mut depth = vec![1.0f32; n];
        let mut color = vec![[0u8; 4]; n];
        g.bench_function(format!("{level:?}, 64 px smooth"), |b| {
            b.iter(|| {
                depth.fill(1.0);
                simd::shade_span(
                    level,
                    SpanJob {
                        e1: 1 << 30,
                        e2: 1 << 29,
                        step1: 1 << 20,
                        step2: -(1 << 19),
                        target: smooth_target(&mut depth, &mut color),
                    },
                );
            })
        });
    }
    g.finish();
}

fn sample_kernels(c: &mut Criterion) {
    let mut g = c.benchmark_group("sample span kernel");
    let pixels = 64;
    g.throughput(Throughput::Elements(pixels as u64));
    for samples in [4, 8] {
        for level in SimdLevel::available() {
            let n = pixels * samples;
            let mut depth = vec![1.0f32; n];
            let mut color = vec![[0u8; 4]; n];
            let offsets = std::array::from_fn(|s| [(s as i64 - 3) << 16, (5 - s as i64) << 15]);
            g.bench_function(format!("{level:?}, 64 px at {samples}x smooth"), |b| {
                b.iter(|| {
                    depth.fill(1.0);
                    let span = SpanJob {
                        e1: 1 << 30,
                        e2: 1 << 29,
                        step1: 1 << 20,
                        step2: -(1 << 19),
                        target: smooth_target(&mut depth, &mut color),
                    };
                    simd::shade_samples(level, SampleSpanJob { span, samples, offsets });
                })
            });
        }
    }
    g.finish();
}

fn narrow(c: &mut Criterion) {
    // Triangles of about 12 pixels in a 5 x 5 and a 4 x 5 box, on a 64-pixel-wide buffer.
    let v = |p: [[f32; 2]; 3]| p.map(|[x, y]| Vertex::new(x, y, 0.3 + 0.05 * x, [9; 4]));
    let boxes = [
        ("5 x 5", v([[1.2, 0.7], [5.9, 2.1], [2.4, 5.6]])),
        ("4 x 5", v([[0.6, 0.7], [4.6, 2.1], [2.0, 5.6]])),
    ];
    let mut g = c.benchmark_group("narrow kernel");
    g.throughput(Throughput::Elements(1));
    for (name, mut tri) in boxes {
        for (k, vertex) in tri.iter_mut().enumerate() {
            vertex.color = [[9, 50, 99, 255], [99, 150, 199, 255], [199, 250, 9, 255]][k];
        }
        let s = TriangleSetup::new(&tri, CullMode::None).expect("a triangle");
        let (x, y) = (fixed::pixel_centre(s.bounds.x0), fixed::pixel_centre(s.bounds.y0));
        for level in SimdLevel::available() {
            let mut depth = vec![1.0f32; 64 * 8];
            let mut color = vec![[0u8; 4]; 64 * 8];
            g.bench_function(format!("{level:?}, {name} box smooth"), |b| {
                // The SIMD kernels have no branches on depth, so a buffer already written
                // costs them what a fresh one does (the scalar one, after the first iteration,
                // times hidden pixels: no colour written).
                b.iter(|| simd::shade_narrow(level, narrow_job(&s, 64, &mut depth, &mut color)))
            });
            // The same box at 4x and 8x, every sample of its pixels tested.
            for samples in [SampleCount::X4, SampleCount::X8] {
                let n = samples.count();
                let offsets = std::array::from_fn(|k| {
                    let [ox, oy] = if k < n { samples.offset(k) } else { [0, 0] };
                    s.edges().map(|e| e.eval(x + ox, y + oy) - e.eval(x, y))
                });
                // Rows of 8 pixels, so that the fill below stays small.
                let mut depth = vec![1.0f32; 8 * 8 * n];
                let mut color = vec![[0u8; 4]; 8 * 8 * n];
                g.bench_function(format!("{level:?}, {name} box smooth at {n}x"), |b| {
                    // A fresh buffer each time (the fill is timed too), so that every
                    // covered sample is visible and written, as a first layer is.
                    b.iter(|| {
                        depth.fill(1.0);
                        let narrow = narrow_job(&s, 8, &mut depth, &mut color);
                        simd::shade_narrow_samples(
                            level,
                            NarrowSamplesJob { narrow, samples: n, offsets },
                        )
                    })
                });
            }
        }
    }
    g.finish();
}

fn small(c: &mut Criterion) {
    // Four quads of a grid of 1.92 x 2.16-pixel quads (the bench grid's), two triangles each,
    // with Gouraud colours in perspective-free weights, as the 3D pipeline sets them up.
    let (w, h) = (1.92f32, 2.16f32);
    let corner = |i: usize, j: usize| (0.3 + w * i as f32, 0.4 + h * j as f32);
    let tris: Vec<[Vertex; 3]> = (0..4)
        .flat_map(|i| {
            let v = |(x, y): (f32, f32)| Vertex::new(x, y, 0.2 + 0.01 * x, [9; 4]);
            let (a, b, c, d) = (corner(i, 0), corner(i + 1, 0), corner(i + 1, 1), corner(i, 1));
            [[v(a), v(b), v(c)], [v(a), v(c), v(d)]]
        })
        .collect();
    let mut target = trirast::Target::new(16, 8).expect("a target");
    let mut lanes = [SmallLane::default(); 8];
    let mut shading = SmallShading::default();
    let mut span = [1, 1];
    for (l, tri) in tris.iter().enumerate() {
        let s = TriangleSetup::new(tri, CullMode::None).expect("a triangle");
        let b = s.bounds;
        span = [span[0].max((b.x1 - b.x0 + 1) as usize), span[1].max((b.y1 - b.y0 + 1) as usize)];
        lanes[l] =
            SmallLane { xy: s.xy, clockwise: s.clockwise, first: [s.bounds.x0, s.bounds.y0] };
        let depth = trirast::shade::PlaneEquation::from_coefficients([0.5, 1e-6, -1e-6]);
        let color = PerspectiveColor {
            colors: [[0.1, 0.5, 0.9, 1.0], [0.9, 0.2, 0.4, 1.0], [0.3, 0.8, 0.1, 1.0]],
            scale: [1.0; 4],
            alpha: Some(1.0),
            inv_w: [1.0; 3],
            inv_area2: 1.0 / s.area2 as f64,
        };
        shading.set(l, &s.bounds, &depth, &color, l as i32);
    }
    let mut g = c.benchmark_group("small kernel");
    g.throughput(Throughput::Elements(8));
    // The same triangles' corners as the corner tests leave them, for a small run's setup.
    let mut rows = simd::CornerGroup::default();
    for (l, lane) in lanes.iter().enumerate() {
        rows.set(l, lane.xy);
    }
    let clip = PixelRect::of_target(16, 8);
    for level in SimdLevel::available() {
        let mut eight = SmallEight::default();
        simd::small_eight(level, &lanes, span, &mut eight);
        g.bench_function(format!("{level:?}, run geometry of eight two-pixel triangles"), |b| {
            let (mut coverage, mut run) = (SmallEight::default(), SmallShading::default());
            b.iter(|| {
                let rows = black_box(&rows);
                simd::small_run_geometry(level, rows, 0xFF, &clip, &mut coverage, &mut run)
            })
        });
        g.bench_function(format!("{level:?}, eight two-pixel triangles"), |b| {
            b.iter(|| {
                let mut band = target.band();
                let (eight, shading) = (black_box(&eight), black_box(&shading));
                simd::shade_small_eight(level, eight, shading, 0..8, &mut band, DepthTest::Always)
            })
        });
    }
    g.finish();
}

fn front_end(c: &mut Criterion) {
    let mut rng = SmallRng::seed_from_u64(3);
    let positions: Vec<Vec4> = (0..1024)
        .map(|_| {
            let w = rng.random_range(0.5..2.0f32);
            Vec4::new(rng.random_range(-1.0..1.0) * w, rng.random_range(-1.0..1.0) * w, 0.5 * w, w)
        })
        .collect();
    let volume = ClipVolume::for_target(1920, 1080);
    let viewport = Viewport::of_size(1920, 1080);
    let mut window: Vec<Corner> = vec![[0, 0]; positions.len()];
    let mut g = c.benchmark_group("front end");
    g.throughput(Throughput::Elements(positions.len() as u64));
    for level in SimdLevel::available() {
        g.bench_function(format!("{level:?}, window corners of 1024 vertices"), |b| {
            b.iter(|| {
                simd::window_corners(level, black_box(&positions), &volume, &viewport, &mut window)
            })
        });
    }
    // Triangles of neighbouring vertices, as in a mesh stored with locality.
    let tris: Vec<[u32; 3]> = (0..1024u32).map(|i| [i, (i + 1) % 1024, (i + 33) % 1024]).collect();
    let clip = PixelRect::of_target(1920, 1080);
    for (level, samples) in SimdLevel::available()
        .into_iter()
        .flat_map(|l| [SampleCount::X1, SampleCount::X4].map(|s| (l, s)))
    {
        let name = format!("{level:?}, corner tests of 1024 triangles at {}x", samples.count());
        g.bench_function(name, |b| {
            b.iter(|| {
                let mut kept = 0u32;
                let mut rows = simd::CornerGroup::default();
                for eight in tris.chunks_exact(8) {
                    let eight: &[[u32; 3]; 8] = eight.try_into().expect("eight");
                    let t = simd::corner_tests_indexed(
                        level,
                        (black_box(eight), &window, 0),
                        CullMode::Clockwise,
                        &clip,
                        samples,
                        &mut rows,
                    );
                    kept += (t.inside & !(t.degenerate | t.culled | t.empty)).count_ones();
                }
                kept
            })
        });
    }
    g.finish();
}

criterion_group!(benches, setup, binning, kernels, sample_kernels, narrow, small, front_end);
criterion_main!(benches);
