//! Micro-benchmarks of the pipeline stages: triangle setup, binning, and the span kernels at
//! every SIMD level this CPU has. `cargo bench --bench stages`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use trirast::bin::Bins;
use trirast::shade::DepthTest;
use trirast::simd::{self, SimdLevel, SpanColor, SpanJob};
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

fn kernels(c: &mut Criterion) {
    let mut g = c.benchmark_group("span kernel");
    let n = 64;
    g.throughput(Throughput::Elements(n as u64));
    let planes = [[100.0, 1e-9, -2e-9], [50.0, 2e-9, 1e-9], [20.0, 0.0, 3e-9], [255.0, 0.0, 0.0]];
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
                        depth_plane: [0.5, 1e-12, 1e-12],
                        color: SpanColor::Smooth(planes),
                        depth_test: DepthTest::Less,
                        id: 1,
                        depth: &mut depth,
                        color_out: &mut color,
                        ids: None,
                        overdraw: None,
                    },
                );
            })
        });
    }
    g.finish();
}

criterion_group!(benches, setup, binning, kernels);
criterion_main!(benches);
