//! The tiled, multithreaded backend against the reference, bit for bit: colour, depth, ids and
//! overdraw, for 1, 2 and 7 threads, at 1x, 4x and 8x, binned and banded, for window-space
//! scenes and the 3D pipeline.

mod common;

use glam::{Vec3, Vec4};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::pipeline::{FaceCull, Fragment, IndexBuffer, Pipeline};
use trirast::render::{Backend, Schedule};
use trirast::sample::SampleCount;
use trirast::simd::SimdLevel;
use trirast::{CullMode, DepthTest, PixelRect, RenderOptions, Shading, Target, Vertex};

/// The schedules the tiled backend can be forced to (the tests' scenes are mostly too small
/// for `Auto` to sample, so it bins them).
const SCHEDULES: [Schedule; 2] = [Schedule::Binned, Schedule::Banded];

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

fn assert_same(a: &Target, b: &Target, what: &str) {
    assert!(a.color == b.color, "{what}: colour differs");
    assert!(
        a.depth.iter().map(|d| d.to_bits()).eq(b.depth.iter().map(|d| d.to_bits())),
        "{what}: depth differs"
    );
    assert!(a.ids == b.ids, "{what}: ids differ");
    assert!(a.overdraw == b.overdraw, "{what}: overdraw differs");
    assert!(a.normals == b.normals, "{what}: normals differ");
}

/// Draws `tris` with `options` on the reference backend and with the tiled one on each of
/// `threads`, into targets made by `fresh`: the same counts and buffers. Returns the tiled
/// targets.
fn assert_tiled_matches_reference(
    fresh: impl Fn() -> Target,
    tris: &[[Vertex; 3]],
    options: &RenderOptions,
    threads: &[usize],
    what: &str,
) -> Vec<Target> {
    let mut reference = fresh();
    let ref_stats =
        trirast::draw(&mut reference, tris, &options.with_backend(Backend::Reference)).unwrap();
    threads
        .iter()
        .map(|&threads| {
            let mut tiled = fresh();
            let stats = pool(threads).install(|| trirast::draw(&mut tiled, tris, options));
            let what = format!("{what}, {threads} threads");
            assert_eq!(stats.unwrap(), ref_stats, "{what}");
            assert_same(&reference, &tiled, &what);
            tiled
        })
        .collect()
}

/// Random window-space scenes: small and large triangles, some far off screen, overlapping at
/// random depths (so the depth test and submission order matter), some exactly equal depths,
/// half of them opaque, one in forty with a non-finite coordinate (rejected, and counted).
fn scene(rng: &mut SmallRng, n: usize, w: f32, h: f32) -> Vec<[Vertex; 3]> {
    (0..n)
        .map(|_| {
            let broken = rng.random_range(0..40) == 0;
            let mut tri = scene_triangle(rng, w, h);
            if broken {
                let bad = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY][rng.random_range(0..3)];
                let v = &mut tri[rng.random_range(0..3)];
                *[&mut v.x, &mut v.y, &mut v.z, &mut v.inv_w][rng.random_range(0..4)] = bad;
            }
            tri
        })
        .collect()
}

/// One triangle of [`scene`], finite.
fn scene_triangle(rng: &mut SmallRng, w: f32, h: f32) -> [Vertex; 3] {
    let size = match rng.random_range(0..10) {
        0 => 3000.0,
        1..=3 => 200.0,
        _ => 12.0,
    };
    let (cx, cy) = (rng.random_range(-20.0..w + 20.0), rng.random_range(-20.0..h + 20.0));
    let flat_z = rng.random_range(0..4) == 0;
    let z0 = rng.random_range(0.0..1.0);
    // Half of them opaque: one alpha at every vertex takes the kernels' three-plane
    // colour without clamps.
    let alpha = rng.random::<bool>().then_some(255);
    std::array::from_fn(|_| Vertex {
        x: cx + rng.random_range(-size..size),
        y: cy + rng.random_range(-size..size),
        z: if flat_z { z0 } else { rng.random_range(0.0..1.0) },
        inv_w: rng.random_range(0.2..3.0),
        color: [rng.random(), rng.random(), rng.random(), alpha.unwrap_or(rng.random())],
    })
}

#[test]
fn window_scenes_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(606);
    let (w, h) = (211u32, 143u32);
    for round in 0..18 {
        let count = rng.random_range(50..1500);
        let tris = scene(&mut rng, count, w as f32, h as f32);
        let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][round % 3];
        let shading = [Shading::Flat, Shading::Smooth, Shading::Perspective][(round / 3) % 3];
        // Depth test and culling vary apart from the sample count (round 9 on shifts them).
        let other = round + round / 9;
        let depth_test = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always][other % 3];
        let cull = [CullMode::None, CullMode::Clockwise, CullMode::CounterClockwise][other % 3];
        let mut options = RenderOptions::default()
            .with_shading(shading)
            .with_depth_test(depth_test)
            .with_cull(cull);
        if round % 4 == 1 {
            options = options.with_scissor(PixelRect { x0: 17, y0: 9, x1: 150, y1: 120 });
        }
        // Without an overdraw buffer (every other round), large triangles take the
        // hierarchical depth test.
        let fresh = || {
            let target = Target::multisampled(w, h, samples).unwrap().with_ids();
            if round % 2 == 0 { target.with_overdraw() } else { target }
        };
        assert_every_tiled_draw_matches(fresh, &tris, &options, &format!("round {round}"));
    }
}

/// Draws `tris` with `options` on the reference backend and with the tiled one on 1, 2 and 7
/// threads at every SIMD level and schedule, into targets made by `fresh`: the same counts
/// and buffers. Returns the counts.
fn assert_every_tiled_draw_matches(
    fresh: impl Fn() -> Target,
    tris: &[[Vertex; 3]],
    options: &RenderOptions,
    what: &str,
) -> trirast::DrawStats {
    let mut reference = fresh();
    let ref_stats =
        trirast::draw(&mut reference, tris, &options.with_backend(Backend::Reference)).unwrap();
    for threads in [1, 2, 7] {
        for level in SimdLevel::available() {
            for schedule in SCHEDULES {
                let mut tiled = fresh();
                let opts = options.with_simd(level).with_schedule(schedule);
                let stats =
                    pool(threads).install(|| trirast::draw(&mut tiled, tris, &opts)).unwrap();
                let what = format!("{what}, {threads} threads, {level:?}, {schedule:?}");
                assert_eq!(stats, ref_stats, "{what}");
                assert_same(&reference, &tiled, &what);
            }
        }
    }
    ref_stats
}

/// Window scenes with corners past the fixed-point range (a quarter of the triangles, one or
/// two corners each, up to 1e12 pixels away), which `draw` clips to the range: the tiled
/// backend draws the pieces as the reference does, with the same counts, for each shading,
/// sample count, thread count, SIMD level and schedule.
#[test]
fn window_scenes_past_the_range_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(707);
    let (w, h) = (157u32, 101u32);
    for round in 0..9 {
        let count = rng.random_range(40..400);
        let mut tris = scene(&mut rng, count, w as f32, h as f32);
        for tri in &mut tris {
            if rng.random_range(0..4) != 0 {
                continue;
            }
            let corners = rng.random_range(1..3);
            for v in tri.iter_mut().take(corners) {
                let far = 10f32.powf(rng.random_range(4.6..12.0));
                let angle = rng.random_range(0.0..std::f32::consts::TAU);
                (v.x, v.y) = (v.x + far * angle.cos(), v.y + far * angle.sin());
            }
        }
        let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][round % 3];
        let shading = [Shading::Flat, Shading::Smooth, Shading::Perspective][(round / 3) % 3];
        let cull = [CullMode::None, CullMode::Clockwise][round % 2];
        let options = RenderOptions::default().with_shading(shading).with_cull(cull);
        let fresh = || Target::multisampled(w, h, samples).unwrap().with_ids().with_overdraw();
        let what = format!("round {round}");
        let stats = assert_every_tiled_draw_matches(fresh, &tris, &options, &what);
        assert!(stats.extra_pieces > 0, "round {round}: no triangle was cut");
    }
}

/// Triangles over many tiles are binned only where they may cover a sample: long slivers
/// across a 700 x 500 target (6 x 4 tiles), some from corner to corner, and large triangles,
/// at random depths, at 1x, 4x and 8x, with and without an overdraw buffer (so with and
/// without hierarchical depth), in window space and through the 3D pipeline: the tiled
/// backend writes what the reference writes.
#[test]
fn slivers_across_many_tiles_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(707);
    let (w, h) = (700.0, 500.0);
    let tris: Vec<[Vertex; 3]> = (0..600)
        .map(|k| {
            let mut point =
                || (rng.random_range(-40.0..w + 40.0), rng.random_range(-40.0..h + 40.0));
            let (a, b) = match k % 4 {
                0 => ((-10.0, -10.0), (w + 10.0, h + 10.0)),
                1 => ((w + 10.0, -10.0), (-10.0, h + 10.0)),
                _ => (point(), point()),
            };
            // Three in four slivers: the third vertex within a few pixels of the first.
            let c = if k % 8 == 7 { point() } else { (a.0 + 3.0, a.1 - 1.25) };
            let z = rng.random_range(0.0..1.0);
            let color = [rng.random(), rng.random(), rng.random(), 255];
            [a, b, c].map(|(x, y)| Vertex::new(x, y, z, color))
        })
        .collect();
    for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
        for overdraw in [false, true] {
            let fresh = || {
                let target = Target::multisampled(w as u32, h as u32, samples).unwrap().with_ids();
                if overdraw { target.with_overdraw() } else { target }
            };
            // Binned, whatever the scene's plan would choose: the trivial reject is binning's.
            let options = RenderOptions::default()
                .with_shading(Shading::Smooth)
                .with_schedule(Schedule::Binned);
            let what = format!("{samples:?}, overdraw {overdraw}");
            for tiled in assert_tiled_matches_reference(fresh, &tris, &options, &[1, 2, 7], &what) {
                assert_eq!(tiled.last_schedule(), Some(Schedule::Binned), "{what}");
            }
        }
    }
    // Through the 3D pipeline, on the same 6 x 4 tiles, at 1x and 4x, each schedule.
    let (vertices, triangles) = clip_space_mesh(&tris, w, h);
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, f.varyings, 0.5, 1.0));
    for samples in [SampleCount::X1, SampleCount::X4] {
        let fresh = || Target::multisampled(w as u32, h as u32, samples).unwrap().with_ids();
        assert_pipeline_matches_reference_on(fresh, &[1, 2], &vertices, &triangles, &fs);
    }
}

/// Tall slivers, as the side of a finely tessellated cylinder makes them: a trapezoid (top
/// and bottom exactly horizontal, so snapping keeps its cut points on them) cut into 6000
/// triangles a tenth of a pixel wide and 850 rows tall, leaning by up to 40 pixels, across
/// seven rows of tiles. The tiled backend (which walks such boxes by columns when no span
/// kernel takes them: perspective colour, and the 3D pipeline) reaches every pixel the
/// trapezoid's two triangles cover once, and no other, at 1x; and writes what the reference
/// writes, on 1, 2 and 7 threads, binned and banded, at 1x, 4x and 8x.
#[test]
fn tall_slivers_tile_their_trapezoid_once() {
    let (w, h) = (400u32, 900u32);
    let (top, bottom) = (20.25, 870.75);
    let n = 3000;
    let at = |from: f32, to: f32, i: usize| from + (to - from) * i as f32 / n as f32;
    let t = |i| (at(100.1, 300.7, i), top);
    let b = |i| (at(60.3, 340.9, i), bottom);
    let vertex = |(x, y): (f32, f32), k: usize| {
        Vertex::new(x, y, (k % 97) as f32 / 100.0, [(k % 251) as u8, 40, 200, 255])
    };
    let tris: Vec<[Vertex; 3]> = (0..n)
        .flat_map(|i| [[t(i), b(i), b(i + 1)], [t(i), b(i + 1), t(i + 1)]])
        .enumerate()
        .map(|(k, tri)| tri.map(|p| vertex(p, k)))
        .collect();
    let trapezoid = [[t(0), b(0), b(n)], [t(0), b(n), t(n)]].map(|tri| tri.map(|p| vertex(p, 0)));
    let mut expected = Target::new(w, h).unwrap().with_overdraw();
    let reference = RenderOptions::default().with_backend(Backend::Reference);
    trirast::draw(&mut expected, &trapezoid, &reference).unwrap();
    let expected = expected.overdraw.unwrap();
    assert!(expected.iter().all(|&o| o <= 1) && expected.iter().sum::<u32>() > 150_000);

    let options = RenderOptions::default().with_shading(Shading::Perspective);
    for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
        let fresh = || Target::multisampled(w, h, samples).unwrap().with_ids().with_overdraw();
        for schedule in SCHEDULES {
            let options = options.with_schedule(schedule);
            let what = format!("{samples:?}, {schedule:?}");
            for tiled in assert_tiled_matches_reference(fresh, &tris, &options, &[1, 2, 7], &what) {
                // A multisampled pixel two slivers share is reached by both.
                if samples == SampleCount::X1 {
                    assert!(tiled.overdraw.unwrap() == expected, "{what}: not each pixel once");
                }
            }
        }
    }
    // The 3D pipeline: each pixel once, and the reference's buffers.
    let (vertices, triangles) = clip_space_mesh(&tris, w as f32, h as f32);
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, 0.5, 0.25, 1.0));
    let vs = |p: &Vec4| (*p, p.z);
    for schedule in SCHEDULES {
        let mut target = Target::new(w, h).unwrap().with_overdraw();
        let pipeline = Pipeline::default().with_cull(FaceCull::None).with_schedule(schedule);
        pool(2).install(|| pipeline.draw(&mut target, &vs, &fs, &vertices, &triangles)).unwrap();
        assert!(target.overdraw.unwrap() == expected, "3D, {schedule:?}: not each pixel once");
    }
    let fresh = || Target::new(w, h).unwrap().with_ids().with_overdraw();
    assert_pipeline_matches_reference_on(fresh, &[1, 2, 7], &vertices, &triangles, &fs);
}

/// Hierarchical depth (on at 1x without an overdraw buffer): large overlapping triangles,
/// drawn front to back (most are hidden tile by tile), back to front (each covering one lowers
/// the tiles' depth bound) and in random order, full-screen quads at one depth (ties, where
/// `Less` and `LessEqual` differ), axis-aligned rectangles (right triangles that cover all of
/// a block's part inside their box, not the block), translucent and opaque, with and without span kernels;
/// drawn twice on one target so the second draw starts from a written depth buffer, with and
/// without a scissor, at 1x, 4x and 8x. The tiled backend still writes exactly what the reference writes, and
/// counts the same fragments.
#[test]
fn hidden_tiles_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(2718);
    let (w, h) = (300u32, 200u32);
    for round in 0..18 {
        let mut tris: Vec<[Vertex; 3]> = (0..rng.random_range(20..120))
            .map(|_| {
                let opaque = rng.random_range(0..3) > 0;
                let (cx, cy) = (rng.random_range(0.0..w as f32), rng.random_range(0.0..h as f32));
                let z0: f32 = rng.random_range(0.0..1.0);
                std::array::from_fn(|_| {
                    let mut color: [u8; 4] = rng.random();
                    if opaque {
                        color[3] = 255;
                    }
                    Vertex::new(
                        cx + rng.random_range(-400.0..400.0),
                        cy + rng.random_range(-400.0..400.0),
                        (z0 + rng.random_range(-0.05..0.05)).clamp(0.0, 1.0),
                        color,
                    )
                })
            })
            .collect();
        let mean_z = |t: &[Vertex; 3]| t.iter().map(|v| v.z).sum::<f32>();
        match round % 3 {
            0 => tris.sort_by(|a, b| mean_z(a).total_cmp(&mean_z(b))),
            1 => tris.sort_by(|a, b| mean_z(b).total_cmp(&mean_z(a))),
            _ => {}
        }
        // Full-screen quads at one depth, somewhere in the list.
        let z = rng.random_range(0.2..0.8);
        let corner = |x: f32, y: f32| Vertex::new(x, y, z, [90, 120, 150, 255]);
        let (a, b, c, d) =
            (corner(-8.0, -8.0), corner(w as f32 + 8.0, -8.0), corner(-8.0, h as f32 + 8.0), {
                corner(w as f32 + 8.0, h as f32 + 8.0)
            });
        for k in 0..3 {
            let at = rng.random_range(0..=tris.len());
            tris.insert(at, if k % 2 == 0 { [a, b, c] } else { [b, d, c] });
        }
        // Axis-aligned rectangles (pairs of right triangles) at whole pixels: a triangle that
        // covers all of the part of a tile's block inside its box, but not the whole block.
        for _ in 0..6 {
            let (x0, y0) = (rng.random_range(-20..w as i32), rng.random_range(-20..h as i32));
            let (x1, y1) = (x0 + rng.random_range(20..200), y0 + rng.random_range(20..200));
            let z = rng.random_range(0.0..1.0);
            let corner = |x: i32, y: i32| Vertex::new(x as f32, y as f32, z, [40, 200, 90, 255]);
            let (a, b, c, d) = (corner(x0, y0), corner(x1, y0), corner(x0, y1), corner(x1, y1));
            let at = rng.random_range(0..=tris.len());
            tris.insert(at, [a, b, c]);
            tris.insert(at + 1, [b, d, c]);
        }
        let shading = [Shading::Flat, Shading::Smooth, Shading::Perspective][(round / 3) % 3];
        let depth_test = [DepthTest::Less, DepthTest::LessEqual][(round / 9) % 2];
        let mut options =
            RenderOptions::default().with_shading(shading).with_depth_test(depth_test);
        if round % 2 == 1 {
            // A scissor off the tile and block grid: clipped tiles, blocks and fragment counts.
            let (x0, y0) = (rng.random_range(1..100), rng.random_range(1..70));
            let (x1, y1) = (x0 + rng.random_range(30..190), y0 + rng.random_range(30..120));
            options = options.with_scissor(PixelRect { x0, y0, x1, y1 });
        }
        let samples = [SampleCount::X1, SampleCount::X4, SampleCount::X8][round % 3];
        let mut reference = Target::multisampled(w, h, samples).unwrap().with_ids();
        let reference_options = options.with_backend(Backend::Reference);
        let first = trirast::draw(&mut reference, &tris, &reference_options).unwrap();
        let second =
            trirast::draw(&mut reference, &tris[tris.len() / 2..], &reference_options).unwrap();
        for threads in [1, 2, 7] {
            // Bands take no hierarchical depth test: they draw the same scene another way.
            for (level, schedule) in SimdLevel::available()
                .into_iter()
                .flat_map(|level| SCHEDULES.map(|schedule| (level, schedule)))
            {
                let mut tiled = Target::multisampled(w, h, samples).unwrap().with_ids();
                let opts = options.with_simd(level).with_schedule(schedule);
                let stats = pool(threads).install(|| {
                    let a = trirast::draw(&mut tiled, &tris, &opts).unwrap();
                    let b = trirast::draw(&mut tiled, &tris[tris.len() / 2..], &opts).unwrap();
                    (a, b)
                });
                let what = format!("round {round}, {threads} threads, {level:?}, {schedule:?}");
                assert_eq!(stats, (first, second), "{what}");
                assert_same(&reference, &tiled, &what);
            }
        }
    }
}

/// Two triangles filling clip space at depth `z` (and a margin past it), as four vertices.
fn screen_quad(z: f32) -> [Vec4; 4] {
    [[-1.2, -1.2], [1.2, -1.2], [1.2, 1.2], [-1.2, 1.2]].map(|[x, y]| Vec4::new(x, y, z, 1.0))
}

/// Clip-space positions (depth as the varying) through the 3D pipeline without culling, into
/// 300 x 200 targets with ids: the tiled backend on 1, 2 and 7 threads against the reference.
fn assert_pipeline_matches_reference<FS: trirast::pipeline::FragmentShader<f32>>(
    vertices: &[Vec4],
    triangles: &[[u32; 3]],
    fs: &FS,
) {
    let fresh = || Target::new(300, 200).unwrap().with_ids();
    assert_pipeline_matches_reference_on(fresh, &[1, 2, 7], vertices, triangles, fs);
}

/// [`assert_pipeline_matches_reference`] into targets made by `fresh`, on `threads`.
fn assert_pipeline_matches_reference_on<FS: trirast::pipeline::FragmentShader<f32>>(
    fresh: impl Fn() -> Target,
    threads: &[usize],
    vertices: &[Vec4],
    triangles: &[[u32; 3]],
    fs: &FS,
) {
    let pipeline = Pipeline::default().with_cull(FaceCull::None);
    assert_pipeline_matches_reference_with(pipeline, fresh, threads, vertices, triangles, fs);
}

/// [`assert_pipeline_matches_reference_on`] with `pipeline`'s settings (its backend and
/// schedule replaced); returns the reference's counts.
fn assert_pipeline_matches_reference_with<FS: trirast::pipeline::FragmentShader<f32>>(
    pipeline: Pipeline,
    fresh: impl Fn() -> Target,
    threads: &[usize],
    vertices: &[Vec4],
    triangles: &[[u32; 3]],
    fs: &FS,
) -> trirast::render::DrawStats {
    let vs = |p: &Vec4| (*p, p.z);
    let mut reference = fresh();
    let ref_stats = pipeline
        .with_backend(Backend::Reference)
        .draw(&mut reference, &vs, fs, vertices, triangles)
        .unwrap();
    for &threads in threads {
        for schedule in SCHEDULES {
            let mut tiled = fresh();
            let pipeline = pipeline.with_schedule(schedule);
            let stats = pool(threads)
                .install(|| pipeline.draw(&mut tiled, &vs, fs, vertices, triangles))
                .unwrap();
            let what = format!("{threads} threads, {schedule:?}");
            assert_eq!(stats, ref_stats, "{what}");
            assert_same(&reference, &tiled, &what);
        }
    }
    ref_stats
}

/// Window-space triangles on a `w x h` target as a mesh in clip space (z in [0, 1) at
/// `w = 1`), three vertices of their own per triangle, so ids number the same triangles.
fn clip_space_mesh(tris: &[[Vertex; 3]], w: f32, h: f32) -> (Vec<Vec4>, Vec<[u32; 3]>) {
    let vertices = tris
        .iter()
        .flatten()
        .map(|v| Vec4::new(v.x / w * 2.0 - 1.0, 1.0 - v.y / h * 2.0, v.z, 1.0))
        .collect();
    let triangles = (0..tris.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    (vertices, triangles)
}

/// Hierarchical depth in the 3D pipeline, whose fragment shaders may discard: a screen-filling
/// quad in front that discards half its pixels must not lower the tiles' depth bound, or the
/// triangles behind it would be skipped where it left holes.
#[test]
fn hidden_tiles_respect_discards() {
    let mut vertices: Vec<Vec4> = screen_quad(0.1).into_iter().chain(screen_quad(0.5)).collect();
    // Large triangles between and behind the quads.
    let mut rng = SmallRng::seed_from_u64(5);
    for _ in 0..60 {
        let z = rng.random_range(0.2..0.9);
        vertices.extend(
            (0..3).map(|_| {
                Vec4::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), z, 1.0)
            }),
        );
    }
    let mut triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
    triangles.extend((0..60).map(|k| [8 + 3 * k, 9 + 3 * k, 10 + 3 * k]));
    // The near quad (depth 0.1) discards a checkerboard.
    let fs = |f: &Fragment<f32>| {
        if f.varyings < 0.15 && (f.x + f.y) % 2 == 0 {
            return None;
        }
        Some(Vec4::new(f.varyings, 0.5, 1.0 - f.varyings, 1.0))
    };
    assert_pipeline_matches_reference(&vertices, &triangles, &fs);
}

/// Hierarchical depth in the 3D pipeline with a fragment shader that says it never discards
/// (so screen-filling triangles lower the blocks' depth bounds): large triangles in front of,
/// between and behind two screen-filling quads, in an order that hides many of them.
#[test]
fn hidden_tiles_with_shaders_that_never_discard() {
    struct Opaque;
    impl trirast::pipeline::FragmentShader<f32> for Opaque {
        fn shade(&self, f: &Fragment<f32>) -> Option<Vec4> {
            Some(Vec4::new(f.varyings, 1.0 - f.varyings, 0.5, 1.0))
        }
        fn may_discard(&self) -> bool {
            false
        }
    }
    let mut rng = SmallRng::seed_from_u64(11);
    let mut vertices: Vec<Vec4> = screen_quad(0.7).into_iter().chain(screen_quad(0.9)).collect();
    let mut triangles = vec![[4, 5, 6], [4, 6, 7], [0, 1, 2], [0, 2, 3]];
    for k in 0..120 {
        // Sloped: a triangle's largest depth over a block differs from its smallest.
        vertices.extend((0..3).map(|_| {
            let (x, y) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            Vec4::new(x, y, rng.random_range(0.05..0.95), 1.0)
        }));
        let at = rng.random_range(0..=triangles.len());
        triangles.insert(at, [8 + 3 * k, 9 + 3 * k, 10 + 3 * k]);
    }
    assert_pipeline_matches_reference(&vertices, &triangles, &Opaque);
}

/// Watertight tilings through the tiled backend: still exactly one fragment per pixel, and the
/// same buffers as the reference.
#[test]
fn tilings_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(17);
    let rect = [-256 * 300, 256 * 7 + 13, 256 * 500, 256 * 190 - 77];
    let tris = common::random_tiling(&mut rng, rect, 20_000);
    let vertex = |p: [i64; 2]| Vertex::new(p[0] as f32 / 256.0, p[1] as f32 / 256.0, 0.5, [200; 4]);
    let triangles: Vec<[Vertex; 3]> = tris.iter().map(|t| t.map(vertex)).collect();
    let fresh = || Target::new(300, 200).unwrap().with_ids().with_overdraw();
    let mut reference = fresh();
    trirast::draw(
        &mut reference,
        &triangles,
        &RenderOptions::default().with_backend(Backend::Reference),
    )
    .unwrap();
    for schedule in SCHEDULES {
        let mut tiled = fresh();
        let options = RenderOptions::default().with_schedule(schedule);
        pool(7).install(|| trirast::draw(&mut tiled, &triangles, &options)).unwrap();
        assert_same(&reference, &tiled, &format!("tiling, {schedule:?}"));
    }
}

/// The 3D pipeline (clipping, culling, perspective varyings, normals) through both backends.
#[test]
fn pipeline_matches_the_reference() {
    let mut rng = SmallRng::seed_from_u64(99);
    let n = 3000;
    let vertices: Vec<(Vec3, Vec3)> = (0..n)
        .map(|_| {
            let p = Vec3::new(
                rng.random_range(-4.0..4.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-12.0..1.0),
            );
            (p, Vec3::new(rng.random(), rng.random(), rng.random()))
        })
        .collect();
    let triangles: Vec<[u32; 3]> = (0..2000)
        .map(|_| {
            let a = rng.random_range(0..n as u32);
            // Mostly nearby vertices (small triangles), some arbitrary (large, clipped).
            let near = |rng: &mut SmallRng| (a + rng.random_range(1..20)).min(n as u32 - 1);
            if rng.random_range(0..5) == 0 {
                [a, rng.random_range(0..n as u32), rng.random_range(0..n as u32)]
            } else {
                [a, near(&mut rng), near(&mut rng)]
            }
        })
        .collect();
    let camera = trirast::camera::Camera {
        eye: Vec3::ZERO,
        target: Vec3::NEG_Z,
        up: Vec3::Y,
        projection: trirast::camera::Projection::Perspective { fov_y: 1.1 },
        near: 0.5,
        far: 10.0,
    };
    let vp = camera.view_projection(160.0 / 120.0);
    let vs = |v: &(Vec3, Vec3)| (vp * v.0.extend(1.0), v.1);
    let fs = |f: &Fragment<Vec3>| {
        if f.varyings.x > 0.97 {
            return None; // discard some fragments
        }
        Some(f.varyings.extend(1.0))
    };
    struct WithNormal<F>(F);
    impl<F: Fn(&Fragment<Vec3>) -> Option<Vec4> + Sync> trirast::pipeline::FragmentShader<Vec3>
        for WithNormal<F>
    {
        fn shade(&self, f: &Fragment<Vec3>) -> Option<Vec4> {
            (self.0)(f)
        }
        fn normal(&self, f: &Fragment<Vec3>) -> Option<Vec3> {
            Some(f.varyings)
        }
    }
    let fs = WithNormal(fs);
    for samples in [SampleCount::X1, SampleCount::X4] {
        for cull in [FaceCull::None, FaceCull::Back] {
            let fresh = || {
                Target::multisampled(160, 120, samples)
                    .unwrap()
                    .with_ids()
                    .with_overdraw()
                    .with_normals()
            };
            let pipeline = Pipeline::default().with_cull(cull);
            let mut reference = fresh();
            let ref_stats = pipeline
                .with_backend(Backend::Reference)
                .draw(&mut reference, &vs, &fs, &vertices, &triangles)
                .unwrap();
            for threads in [1, 2, 7] {
                for schedule in SCHEDULES {
                    let mut tiled = fresh();
                    let pipeline = pipeline.with_schedule(schedule);
                    let stats = pool(threads)
                        .install(|| pipeline.draw(&mut tiled, &vs, &fs, &vertices, &triangles))
                        .unwrap();
                    let what = format!("{samples:?} {cull:?} {threads} threads, {schedule:?}");
                    assert_eq!(stats, ref_stats, "{what}");
                    assert_same(&reference, &tiled, &what);
                }
            }
        }
    }
}

/// A grid of `nx x ny` quads, two triangles each, in rows: vertex `(i, j)` at
/// `position(i / nx, j / ny)`.
fn grid_mesh(nx: u32, ny: u32, position: impl Fn(f32, f32) -> Vec4) -> (Vec<Vec4>, Vec<[u32; 3]>) {
    let positions = (0..=ny)
        .flat_map(|j| (0..=nx).map(move |i| (i as f32 / nx as f32, j as f32 / ny as f32)))
        .map(|(x, y)| position(x, y))
        .collect();
    let row = nx + 1;
    let triangles = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| j * row + i))
        .flat_map(|a| [[a, a + 1, a + row + 1], [a, a + row + 1, a + row]])
        .collect();
    (positions, triangles)
}

/// Meshes with more vertices than the pipeline shades up front go through per-batch windows
/// of corners (compact index ranges; triangles that pass the corner tests or need clipping
/// shade their vertices again) or per-corner shading (scattered indices); both give the
/// reference's buffers. The mesh reaches past the screen's sides (triangles with no pixel)
/// and, along one side, behind the near plane (clipped).
#[test]
fn large_meshes_shade_vertices_in_batches() {
    let (positions, triangles) = grid_mesh(1100, 1000, |x, y| {
        let z = 0.5 * x * y + 0.3 * y - 0.02;
        Vec4::new(2.4 * x - 1.2, 2.0 * y - 1.0, z, 1.0)
    });
    assert!(positions.len() > 1 << 20);
    // Also a scattered order: every 7th triangle moved to the end.
    let mut scattered: Vec<[u32; 3]> = triangles.iter().copied().step_by(7).collect();
    scattered.extend(triangles.iter().enumerate().filter(|(k, _)| k % 7 != 0).map(|(_, t)| *t));
    let vs = |p: &Vec4| (*p, p.z);
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, 0.5, 0.25, 1.0));
    for tris in [&triangles, &scattered] {
        let fresh = || Target::new(97, 61).unwrap().with_ids().with_overdraw();
        let pipeline = Pipeline::default().with_cull(FaceCull::None);
        let mut reference = fresh();
        let ref_stats = pipeline
            .with_backend(Backend::Reference)
            .draw(&mut reference, &vs, &fs, &positions, tris)
            .unwrap();
        let mut tiled = fresh();
        let stats = pool(2).install(|| pipeline.draw(&mut tiled, &vs, &fs, &positions, tris));
        assert_eq!(stats.unwrap(), ref_stats);
        assert_same(&reference, &tiled, "large mesh");
        // Kept index ranges (each batch's from its chunks' and its ends read) draw the same.
        let indexed = IndexBuffer::new(tris.clone());
        let mut kept = fresh();
        let stats =
            pool(2).install(|| pipeline.draw_indexed(&mut kept, &vs, &fs, &positions, &indexed));
        assert_eq!(stats.unwrap(), ref_stats);
        assert_same(&reference, &kept, "large mesh, kept index ranges");
        // Still a tiling: no pixel twice; only the rows behind the near plane are bare.
        let overdraw = reference.overdraw.as_ref().unwrap();
        assert!(overdraw.iter().all(|&o| o <= 1));
        let bare = overdraw.iter().filter(|&&o| o == 0).count();
        assert!(bare > 0 && bare < 97 * 3, "{bare} pixels not covered");
    }
}

/// Clipping can turn a chunk of input triangles into more pieces than triangles (prepared
/// triangles are indexed by chunk and piece): here every triangle crosses the near plane and
/// leaves through the guard band's sides, so each becomes a fan of several pieces, and the
/// tiled backend must still draw them all, in order.
#[test]
fn clipped_fans_outnumbering_their_triangles_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(17);
    // Clip-space positions: one vertex behind the near plane (z < 0), two far to the sides
    // (|x| beyond the guard band's w multiple), all with w > 0.
    let mut vertices = Vec::new();
    let triangles: Vec<[u32; 3]> = (0..900u32)
        .map(|t| {
            let w = rng.random_range(1.0..4.0f32);
            let z = |rng: &mut SmallRng, lo: f32| rng.random_range(lo..0.9) * w;
            vertices.push(Vec4::new(rng.random_range(-0.5..0.5) * w, 0.0, z(&mut rng, -2.0), w));
            vertices.push(Vec4::new(
                -800.0 * w,
                rng.random_range(-1.0..1.0) * w,
                z(&mut rng, 0.1),
                w,
            ));
            vertices.push(Vec4::new(
                800.0 * w,
                rng.random_range(-1.0..1.0) * w,
                z(&mut rng, 0.1),
                w,
            ));
            [3 * t, 3 * t + 1, 3 * t + 2]
        })
        .collect();
    let vs = |p: &Vec4| (*p, p.y);
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings * 0.5 + 0.5, 0.25, 0.75, 1.0));
    let fresh = || Target::new(96, 64).unwrap().with_ids().with_overdraw();
    let pipeline = Pipeline::default().with_cull(FaceCull::None);
    let mut reference = fresh();
    let ref_stats = pipeline
        .with_backend(Backend::Reference)
        .draw(&mut reference, &vs, &fs, &vertices, &triangles)
        .unwrap();
    // More pieces than triangles, so chunks overflow their 256 input slots; each triangle
    // counted once.
    assert!(ref_stats.rasterized + ref_stats.extra_pieces > 2 * triangles.len(), "{ref_stats:?}");
    assert_eq!(ref_stats.rasterized + ref_stats.culled + ref_stats.degenerate, triangles.len());
    for threads in [1, 2] {
        for schedule in SCHEDULES {
            let mut tiled = fresh();
            let pipeline = pipeline.with_schedule(schedule);
            let stats = pool(threads)
                .install(|| pipeline.draw(&mut tiled, &vs, &fs, &vertices, &triangles));
            assert_eq!(stats.unwrap(), ref_stats);
            assert_same(
                &reference,
                &tiled,
                &format!("clipped fans, {threads} threads, {schedule:?}"),
            );
        }
    }
}

/// A target keeps the tiled backend's batch buffers from one draw call to the next: a draw
/// into a target that has drawn a larger scene (more chunks of set-up triangles than the new
/// one fills) or another pipeline's triangles (another record type) gives exactly what a
/// fresh target gives.
#[test]
fn reused_targets_draw_what_fresh_ones_draw() {
    let mut rng = SmallRng::seed_from_u64(2718);
    let (w, h) = (190u32, 130u32);
    let large = scene(&mut rng, 4000, w as f32, h as f32);
    let small = scene(&mut rng, 300, w as f32, h as f32);
    let fresh = || Target::new(w, h).unwrap().with_ids().with_overdraw();
    let options = RenderOptions::default();
    let mut expected = fresh();
    trirast::draw(&mut expected, &small, &options).unwrap();

    let vertices: Vec<Vec3> = (0..600)
        .map(|_| {
            Vec3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
                rng.random_range(0.1..0.9),
            )
        })
        .collect();
    let triangles: Vec<[u32; 3]> =
        (0..400).map(|_| std::array::from_fn(|_| rng.random_range(0..600))).collect();
    let large_vertices: Vec<Vec3> = (0..5000)
        .map(|_| Vec3::new(rng.random_range(-1.5..1.5), rng.random_range(-1.5..1.5), 0.5))
        .collect();
    let large_triangles: Vec<[u32; 3]> =
        (0..3000).map(|_| std::array::from_fn(|_| rng.random_range(0..5000))).collect();
    let vs = |p: &Vec3| (p.extend(1.0), *p);
    let fs = |f: &Fragment<Vec3>| Some(f.varyings.extend(1.0));
    let pipeline = Pipeline::default().with_cull(FaceCull::None);
    let mut expected_3d = fresh();
    pipeline.draw(&mut expected_3d, &vs, &fs, &vertices, &triangles).unwrap();

    let mut reused = fresh();
    for threads in [2, 1, 7] {
        pool(threads).install(|| {
            reused.clear([0, 0, 0, 255]);
            trirast::draw(&mut reused, &large, &options).unwrap();
            reused.clear([0, 0, 0, 255]);
            trirast::draw(&mut reused, &small, &options).unwrap();
            assert_same(&expected, &reused, &format!("after a larger scene, {threads} threads"));
            reused.clear([0, 0, 0, 255]);
            pipeline.draw(&mut reused, &vs, &fs, &vertices, &triangles).unwrap();
            assert_same(&expected_3d, &reused, &format!("3D after 2D, {threads} threads"));
            // The pipeline's own buffers (shaded vertices, corners, records) reused after a
            // larger mesh: a stale vertex or record would show.
            reused.clear([0, 0, 0, 255]);
            pipeline.draw(&mut reused, &vs, &fs, &large_vertices, &large_triangles).unwrap();
            reused.clear([0, 0, 0, 255]);
            pipeline.draw(&mut reused, &vs, &fs, &vertices, &triangles).unwrap();
            assert_same(&expected_3d, &reused, &format!("3D after 3D, {threads} threads"));
            reused.clear([0, 0, 0, 255]);
            trirast::draw(&mut reused, &small, &options).unwrap();
            assert_same(&expected, &reused, &format!("2D after 3D, {threads} threads"));
        });
    }
    reused.release_scratch();
    reused.clear([0, 0, 0, 255]);
    trirast::draw(&mut reused, &small, &options).unwrap();
    assert_same(&expected, &reused, "after release_scratch");
}

/// Each vertex of a small mesh goes through the vertex shader exactly once per draw call,
/// on both backends and every thread count: on a fresh target, again on the same target
/// (whose buffers the vertex pass then overwrites in place), and after a longer mesh.
#[test]
fn vertices_are_shaded_once_per_draw() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let mut rng = SmallRng::seed_from_u64(99);
    let mesh = |n: u32, rng: &mut SmallRng| {
        let vertices: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.5))
            .collect();
        let triangles: Vec<[u32; 3]> =
            (0..n).map(|_| std::array::from_fn(|_| rng.random_range(0..n))).collect();
        (vertices, triangles)
    };
    let (small, small_tris) = mesh(300, &mut rng);
    let (large, large_tris) = mesh(9000, &mut rng);
    let calls = AtomicUsize::new(0);
    let vs = |p: &Vec3| {
        calls.fetch_add(1, Ordering::Relaxed);
        (p.extend(1.0), *p)
    };
    let fs = |f: &Fragment<Vec3>| Some(f.varyings.extend(1.0));
    for backend in [Backend::Tiled, Backend::Reference] {
        let pipeline = Pipeline::default().with_cull(FaceCull::None).with_backend(backend);
        for threads in [1, 2, 7] {
            let mut target = Target::new(64, 48).unwrap();
            for (vertices, triangles) in [
                (&small, &small_tris),
                (&small, &small_tris),
                (&large, &large_tris),
                (&small, &small_tris),
            ] {
                calls.store(0, Ordering::Relaxed);
                pool(threads).install(|| {
                    pipeline.draw(&mut target, &vs, &fs, vertices, triangles).unwrap();
                });
                let what = format!("{backend:?}, {threads} threads, {} vertices", vertices.len());
                assert_eq!(calls.load(Ordering::Relaxed), vertices.len(), "{what}");
            }
        }
    }
}

/// `n` opaque triangles piled on a `w x h` target (seeded by `seed`): each within `size` of a
/// random centre, one in 500 within 150 pixels, at one of four depths, so `Less` meets ties.
fn piled_triangles(seed: u64, n: usize, w: f32, h: f32, size: f32) -> Vec<[Vertex; 3]> {
    let mut rng = SmallRng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let (cx, cy) = (rng.random_range(0.0..w), rng.random_range(0.0..h));
            let z = f32::from(rng.random_range(0u8..4)) / 4.0;
            let size = if k % 500 == 0 { 150.0 } else { size };
            std::array::from_fn(|_| {
                let (x, y) =
                    (cx + rng.random_range(-size..size), cy + rng.random_range(-size..size));
                Vertex::new(x, y, z, [rng.random(), rng.random(), rng.random(), 255])
            })
        })
        .collect()
}

/// Draw calls longer than a batch: batches are set up while the one before is drawn, and
/// must still be drawn in submission order. Two and a half batches of small triangles piled
/// on a small target (every pixel is written by triangles of every batch), one in 500 large
/// (so hierarchical depth, on without an overdraw buffer, meets them in every batch), with
/// the `Always` test (the last writer wins) and with `Less` against ties, in window space and
/// through the 3D pipeline: the tiled backend on 1, 2 and 7 threads writes what the reference
/// writes.
#[test]
fn batches_are_drawn_in_submission_order() {
    use trirast::bin::BATCH;
    let (w, h) = (160.0, 100.0);
    // Three batches: the third refills the first one's buffers.
    let tris = piled_triangles(77, 2 * BATCH + BATCH / 2, w, h, 6.0);
    for (depth_test, overdraw) in
        [(DepthTest::Always, true), (DepthTest::Less, true), (DepthTest::Less, false)]
    {
        let options = RenderOptions::default().with_depth_test(depth_test);
        let fresh = || {
            let target = Target::new(w as u32, h as u32).unwrap().with_ids();
            if overdraw { target.with_overdraw() } else { target }
        };
        let what = format!("{depth_test:?}, overdraw {overdraw}");
        assert_tiled_matches_reference(fresh, &tris, &options, &[1, 2, 7], &what);
    }
    // Through the 3D pipeline, as a mesh in clip space small enough to have its vertices
    // shaded up front (the large-mesh path is `multisampled_batches_are_drawn_in_submission_
    // order`'s): the first 2^18 triangles' vertices, each used by every triangle of the draw
    // call that repeats its triangle (with the same depth: `Less` keeps the first, so the ids
    // tell the order).
    let distinct = 1 << 18;
    let (vertices, once) = clip_space_mesh(&tris[..distinct], w, h);
    let triangles: Vec<[u32; 3]> = (0..tris.len()).map(|t| once[t * 7 % distinct]).collect();
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, f.varyings, 0.5, 1.0));
    assert_pipeline_matches_reference(&vertices, &triangles, &fs);
}

/// Small triangles share a queue of fragments, their writes waiting for its flush: a pixel an
/// earlier triangle in the queue covers must see that triangle's depth. Tiny triangles piled
/// on a 12 x 8 target (most within 4 pixels of area, so consecutive ones overlap), one in 50
/// a sliver of the same area too long for the narrow path (some cut narrow by the target's
/// edge), each nearer than those well before it but in random order among its neighbours,
/// with `Less`: through the 3D pipeline, some discarded (whose depth
/// must not be written), and in window space with perspective colours (the kernels take flat
/// and smooth ones). Then slivers of that area over half a tile long among small triangles
/// on a 256 x 16 target, where hierarchical depth draws the slivers (and counts their
/// fragments while binning). Banded and binned, the tiled backend on 1, 2 and 7 threads
/// writes what the reference writes and counts what it counts.
#[test]
fn small_triangles_sharing_a_queue_keep_their_order() {
    // Triangle `k`'s first vertex and depth, as a sliver `length` long of area 2.4 pixels.
    let sliver = |t: &[Vertex; 3], length: f32| {
        let (x, y, thick) = (t[0].x, t[0].y, 4.8 / length);
        let v = |x: f32, y: f32| Vertex { x, y, ..t[0] };
        [v(x - length / 2.0, y), v(x + length / 2.0, y + 0.7), v(x + length / 2.0, y + 0.7 + thick)]
    };
    let fs = |f: &Fragment<f32>| {
        (!f.primitive.is_multiple_of(7))
            .then(|| Vec4::new(f.varyings, (f.primitive % 256) as f32 / 255.0, 0.5, 1.0))
    };
    let (w, h) = (12.0, 8.0);
    let mut tris = piled_triangles(79, 20_000, w, h, 1.2);
    for t in tris.iter_mut().step_by(50) {
        *t = sliver(t, 16.0);
    }
    // Depths that come forward over the draw, shuffled among neighbours: with the four depths
    // of `piled_triangles` every pixel soon holds the nearest, and nothing passes `Less`.
    let n = tris.len() as f32;
    for (k, t) in tris.iter_mut().enumerate() {
        let z = 0.9 * (1.0 - k as f32 / n) + (k * 7919 % 100) as f32 / 1000.0;
        t.iter_mut().for_each(|v| v.z = z);
    }
    let (vertices, triangles) = clip_space_mesh(&tris, w, h);
    let fresh = || Target::new(w as u32, h as u32).unwrap().with_ids();
    assert_pipeline_matches_reference_on(fresh, &[1, 2, 7], &vertices, &triangles, &fs);
    let perspective = RenderOptions::default().with_shading(Shading::Perspective);
    for schedule in SCHEDULES {
        let options = perspective.with_schedule(schedule);
        let what = format!("window, {schedule:?}");
        assert_tiled_matches_reference(fresh, &tris, &options, &[1, 2, 7], &what);
    }
    let (w, h) = (256.0, 16.0);
    let mut tris = piled_triangles(80, 4000, w, h, 1.2);
    for t in tris.iter_mut().step_by(10) {
        *t = sliver(t, 100.0);
    }
    let (vertices, triangles) = clip_space_mesh(&tris, w, h);
    let fresh = || Target::new(w as u32, h as u32).unwrap().with_ids();
    assert_pipeline_matches_reference_on(fresh, &[1, 2, 7], &vertices, &triangles, &fs);
}

/// Multisampled draw calls longer than a batch: one and a half batches of small triangles
/// piled on a small 4x target, one in 500 large, with `Always` and an overdraw buffer and with
/// `Less` and hierarchical depth, binned (on 1 and 2 threads) and banded, in window space and
/// through the 3D pipeline (a mesh shaded batch by batch and one shaded up front): the tiled
/// backend writes what the reference writes, every sample.
#[test]
fn multisampled_batches_are_drawn_in_submission_order() {
    use trirast::bin::BATCH;
    let (w, h) = (160.0, 100.0);
    let tris = piled_triangles(78, BATCH + BATCH / 2, w, h, 3.0);
    let fresh = |overdraw: bool| {
        let target = Target::multisampled(w as u32, h as u32, SampleCount::X4).unwrap().with_ids();
        if overdraw { target.with_overdraw() } else { target }
    };
    for (depth_test, overdraw) in [(DepthTest::Always, true), (DepthTest::Less, false)] {
        let options = RenderOptions::default().with_depth_test(depth_test);
        let mut reference = fresh(overdraw);
        let ref_stats =
            trirast::draw(&mut reference, &tris, &options.with_backend(Backend::Reference))
                .unwrap();
        // Binned (the second batch binned as it is prepared) and banded.
        for (threads, schedule) in
            [(1, Schedule::Binned), (2, Schedule::Binned), (2, Schedule::Banded)]
        {
            let mut tiled = fresh(overdraw);
            let options = options.with_schedule(schedule);
            let stats = pool(threads).install(|| trirast::draw(&mut tiled, &tris, &options));
            let what = format!("{depth_test:?}, {threads} threads, {schedule:?}");
            assert_eq!(stats.unwrap(), ref_stats, "{what}");
            assert_eq!(tiled.last_schedule(), Some(schedule), "{what}");
            assert_same(&reference, &tiled, &what);
        }
    }
    // Through the 3D pipeline: as a mesh of 2.4 M vertices (shaded batch by batch), and as one
    // small enough to be shaded up front (repeated triangles sharing the first 2^18
    // triangles' vertices, as in `batches_are_drawn_in_submission_order`).
    let (vertices, triangles) = clip_space_mesh(&tris, w, h);
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, f.varyings, 0.5, 1.0));
    assert_pipeline_matches_reference_on(|| fresh(false), &[1, 2], &vertices, &triangles, &fs);
    let distinct = 1 << 18;
    let (vertices, once) = clip_space_mesh(&tris[..distinct], w, h);
    let triangles: Vec<[u32; 3]> = (0..tris.len()).map(|t| once[t * 7 % distinct]).collect();
    assert_pipeline_matches_reference_on(|| fresh(false), &[2], &vertices, &triangles, &fs);
}

/// Hierarchical depth bounds a triangle's depth over a block's samples, not only its pixel
/// centres: behind a flat triangle at 0.5 covering the target (so every block's bound drops
/// to 0.5), a steep triangle whose depth at the pixel centres of the block at x 64..128 never
/// goes below 0.501 still passes at the samples left of those centres (0.4995 at 4x). The
/// tiled backend writes exactly those samples, as the reference does.
#[test]
fn hierarchical_depth_bounds_cover_the_samples() {
    let slope = 0.004; // depth per pixel, along x
    let z = |x: f32| 0.501 + slope * (x - 64.5);
    // One triangle over the whole 160 x 100 target, its depth `z(x)`.
    let cover = |z: &dyn Fn(f32) -> f32| {
        let v = |x: f32, y: f32| Vertex::new(x, y, z(x), [200, 100, 50, 255]);
        [v(-10.0, -10.0), v(250.0, -10.0), v(-10.0, 400.0)]
    };
    let tris = [cover(&|_| 0.5), cover(&z)];
    for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
        let options = RenderOptions::default().with_shading(Shading::Smooth);
        let fresh = || Target::multisampled(160, 100, samples).unwrap().with_ids();
        let mut reference = fresh();
        trirast::draw(&mut reference, &tris, &options.with_backend(Backend::Reference)).unwrap();
        let mut tiled = fresh();
        trirast::draw(&mut tiled, &tris, &options).unwrap();
        assert_same(&reference, &tiled, &format!("{samples:?}"));
        if samples != SampleCount::X1 {
            // Not vacuous: the steep triangle owns samples in the block at 64..128.
            let n = samples.count();
            let ids = reference.ids.as_ref().unwrap();
            let won = (64..128).any(|x| {
                let p = reference.index(x, 50);
                ids[p * n..(p + 1) * n].contains(&1)
            });
            assert!(won, "{samples:?}: the steep triangle is hidden everywhere in the block");
        }
    }
}

/// Bands on targets with fewer rows than threads (one band per row at most), a target one
/// pixel high, and scissors off the target or of one row, at 1x and 4x: the reference's
/// buffers and counts.
#[test]
fn bands_on_few_rows_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(8);
    for (w, h) in [(1u32, 1u32), (5, 2), (40, 1), (3, 9)] {
        let tris = scene(&mut rng, 300, w as f32, h as f32);
        let scissors = [None, Some(PixelRect { x0: 0, y0: h as i32, x1: 3, y1: h as i32 + 4 }), {
            Some(PixelRect { x0: 0, y0: h as i32 / 2, x1: w as i32 - 1, y1: h as i32 / 2 })
        }];
        for scissor in scissors {
            let mut options = RenderOptions::default();
            if let Some(s) = scissor {
                options = options.with_scissor(s);
            }
            for samples in [SampleCount::X1, SampleCount::X4] {
                let fresh = || Target::multisampled(w, h, samples).unwrap().with_ids();
                let fresh = || fresh().with_overdraw();
                let mut reference = fresh();
                let reference_options = options.with_backend(Backend::Reference);
                let ref_stats = trirast::draw(&mut reference, &tris, &reference_options).unwrap();
                for threads in [2, 7] {
                    let mut banded = fresh();
                    let opts = options.with_schedule(Schedule::Banded);
                    let stats =
                        pool(threads).install(|| trirast::draw(&mut banded, &tris, &opts)).unwrap();
                    let what = format!("{w}x{h}, {samples:?}, {scissor:?}, {threads} threads");
                    assert_eq!(stats, ref_stats, "{what}");
                    assert_same(&reference, &banded, &what);
                }
            }
        }
    }
}

/// Meshes in spatial order drawn in bands, which skip the chunks of triangles that cannot
/// reach their rows (and each chunk counted by one band): the reference's buffers and counts
/// at 1x and 4x, on 2, 3 and 7 threads (binned too), for a grid in row order and in reverse row order,
/// with uneven depths, every other row of quads turned back-facing (culled), and part of a
/// row behind the eye (clipped: chunks with a vertex outside are never skipped).
#[test]
fn bands_skipping_chunks_out_of_reach_match_the_reference() {
    let (positions, triangles) = grid_mesh(90, 60, |x, y| {
        let (cx, cy) = (2.2 * x - 1.1, 2.1 * y - 1.05);
        if y < 0.1 && x < 0.3 {
            // Behind the eye along part of the top edge: the triangles there are clipped, and
            // their pieces' projections reach rows far from the vertices inside.
            return Vec4::new(cx * 0.4, cy * 0.4, -0.1, -0.4);
        }
        Vec4::new(cx, cy, 0.2 + 0.6 * (x * 7.0 + y * 3.0).sin().abs(), 1.0)
    });
    // Every other row of quads (90 quads, 180 triangles a row) wound the other way.
    let turned: Vec<[u32; 3]> = triangles
        .iter()
        .enumerate()
        .map(|(k, &[a, b, c])| if (k / 180) % 2 == 1 { [a, c, b] } else { [a, b, c] })
        .collect();
    let reversed: Vec<[u32; 3]> = turned.iter().rev().copied().collect();
    let fs = |f: &Fragment<f32>| Some(Vec4::new(f.varyings, 0.5, 0.25, 1.0));
    for (tris, order) in [(&turned, "rows"), (&reversed, "reversed rows")] {
        for samples in [SampleCount::X1, SampleCount::X4] {
            let fresh = || Target::multisampled(150, 101, samples).unwrap().with_ids();
            let fresh = || fresh().with_overdraw();
            let pipeline = Pipeline::default().with_cull(FaceCull::Back);
            let threads = [2, 3, 7];
            let stats = assert_pipeline_matches_reference_with(
                pipeline, fresh, &threads, &positions, tris, &fs,
            );
            assert!(stats.culled > 0 && stats.rasterized > 0, "{order}, {samples:?}: {stats:?}");
        }
    }
}

/// `Target::last_schedule` says what the tiled backend did: `Auto` bands a grid mesh of small
/// triangles in spatial order and bins the same triangles shuffled (as `band::plan` decides),
/// forced schedules are reported as given, and the reference backend and a failed draw call
/// report none.
#[test]
fn last_schedule_reports_the_schedule_used() {
    let (positions, grid) =
        grid_mesh(400, 200, |x, y| Vec4::new(2.0 * x - 1.0, 2.0 * y - 1.0, 0.5, 1.0));
    let mut shuffled = grid.clone();
    let mut rng = SmallRng::seed_from_u64(5);
    for k in (1..shuffled.len()).rev() {
        shuffled.swap(k, rng.random_range(0..=k));
    }
    let vs = |p: &Vec4| (*p, ());
    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
    let mut target = Target::new(1920, 1080).unwrap();
    assert_eq!(target.last_schedule(), None, "before any draw call");
    let pipeline = Pipeline::default().with_cull(FaceCull::None);
    let mut schedule_of = |pipeline: Pipeline, triangles: &[[u32; 3]]| {
        pool(2).install(|| pipeline.draw(&mut target, &vs, &fs, &positions, triangles)).unwrap();
        target.last_schedule()
    };
    assert_eq!(schedule_of(pipeline, &grid), Some(Schedule::Banded), "grid");
    assert_eq!(schedule_of(pipeline, &shuffled), Some(Schedule::Binned), "shuffled grid");
    for forced in SCHEDULES {
        let pipeline = pipeline.with_schedule(forced);
        assert_eq!(schedule_of(pipeline, &shuffled), Some(forced), "{forced:?}");
    }
    let reference = pipeline.with_backend(Backend::Reference);
    assert_eq!(schedule_of(reference, &grid[..100]), None, "reference backend");

    // Window triangles: the same, through `draw`; a failed call reports none.
    let tris = scene(&mut rng, 300, 1920.0, 1080.0);
    for forced in SCHEDULES {
        trirast::draw(&mut target, &tris, &RenderOptions::default().with_schedule(forced)).unwrap();
        assert_eq!(target.last_schedule(), Some(forced), "window, {forced:?}");
    }
    // A depth buffer of another length: refused before drawing.
    let depth = std::mem::take(&mut target.depth);
    assert!(trirast::draw(&mut target, &tris, &RenderOptions::default()).is_err());
    assert_eq!(target.last_schedule(), None, "failed draw call");
    target.depth = depth;
}

/// A shader whose colour is the interpolated vertex colour times a tint, with a constant alpha,
/// counting its calls. It says so through `interpolated_color`, except for every thirteenth
/// triangle (so that the kernels' runs of triangles meet ones they must leave to the shader,
/// while some groups of eight the front end sets up have none).
struct Tinted(std::sync::atomic::AtomicUsize);

const TINT: Vec4 = Vec4::new(0.9, 0.5, 1.25, 7.0);

impl trirast::pipeline::FragmentShader<Vec4> for Tinted {
    fn shade(&self, f: &Fragment<Vec4>) -> Option<Vec4> {
        self.0.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let c = f.varyings * TINT;
        Some(Vec4::new(c.x, c.y, c.z, 0.5))
    }

    fn may_discard(&self) -> bool {
        false
    }

    fn interpolated_color(
        &self,
        v: [&Vec4; 3],
        primitive: u32,
    ) -> Option<trirast::pipeline::InterpolatedColor> {
        if primitive % 13 == 3 {
            return None;
        }
        let colors = v.map(|c| *c);
        Some(trirast::pipeline::InterpolatedColor { colors, scale: TINT, alpha: Some(0.5) })
    }
}

/// Shaders whose colour is a fixed function of the vertex colours, which the tiled backend
/// shades in the SIMD kernels (`FragmentShader::interpolated_color`): `VertexColor` on `Vec4`
/// and `Vec3` colours and a tinted shader with a constant alpha, on a perspective scene (`w`
/// from 0.3 to 4, triangles crossing the near plane and the sides, slivers, two-pixel
/// triangles, ones of hundreds of pixels; colours a little outside [0, 1]), into targets with
/// ids and overdraw at 1x and 4x: the reference's buffers and counts at every SIMD level, on
/// 1, 2 and 7 threads, binned and banded; and at 1x with AVX-512 (the one level that takes
/// them) the kernels did shade, calling the shader for few of the fragments the reference
/// shaded.
#[test]
fn vertex_colours_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(41);
    let (mut positions, mut colors, mut triangles) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..1500u32 {
        let size = [0.01, 0.05, 0.3, 1.5][k as usize % 4];
        let (cx, cy) = (rng.random_range(-1.2..1.2f32), rng.random_range(-1.2..1.2f32));
        for _ in 0..3 {
            let w = rng.random_range(0.3..4.0f32);
            let (x, y) = (cx + rng.random_range(-size..size), cy + rng.random_range(-size..size));
            // Now and then in front of the near plane (z < 0): clipped.
            let z = rng.random_range(-0.05..1.0f32);
            positions.push(Vec4::new(x * w, y * w, z * w, w));
            colors.push(Vec4::from_array(std::array::from_fn(|_| rng.random_range(-0.1..1.1))));
        }
        triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
    }
    let mesh = (&positions[..], &colors[..], &triangles[..]);
    for samples in [SampleCount::X1, SampleCount::X4] {
        let fresh = || {
            let t = Target::multisampled(320, 240, samples).unwrap().with_ids();
            if samples == SampleCount::X1 { t.with_overdraw() } else { t }
        };
        let pipeline = Pipeline::default().with_cull(FaceCull::None);
        // Most of these triangles are larger than the small kernel's boxes: only AVX-512's
        // span and narrow kernels take them.
        let kernels: &[_] = if samples == SampleCount::X1 { &[SimdLevel::Avx512] } else { &[] };
        let what = format!("{samples:?}");
        let stats = assert_vertex_colours_match(mesh, pipeline, fresh, kernels, &what);
        assert!(stats[0].fragments > 50_000, "{:?}", stats[0]);
    }
}

/// Draws the mesh `(positions, colors, triangles)` with `pipeline` into targets `fresh`
/// makes, with `VertexColor` on `Vec4` and `Vec3` colours and the tinted shader: the
/// reference's buffers and counts at every SIMD level, on 1, 2 and 7 threads, binned and
/// banded. At the levels `kernels` (where the SIMD kernels take these shaders and triangles),
/// the tinted shader is called for under a quarter of the fragments the reference shaded.
/// Returns the reference's counts, shader by shader.
fn assert_vertex_colours_match(
    (positions, colors, triangles): (&[Vec4], &[Vec4], &[[u32; 3]]),
    pipeline: Pipeline,
    fresh: impl Fn() -> Target + Sync,
    kernels: &[SimdLevel],
    what: &str,
) -> [trirast::render::DrawStats; 3] {
    let indices: Vec<u32> = (0..positions.len() as u32).collect();
    let vs4 = |&i: &u32| (positions[i as usize], colors[i as usize]);
    let vs3 = |&i: &u32| (positions[i as usize], colors[i as usize].truncate());
    let draw = |backend: Backend, schedule, level: Option<SimdLevel>, shader: &Tinted| {
        let mut targets = [fresh(), fresh(), fresh()];
        let p = pipeline.with_backend(backend).with_schedule(schedule);
        let p = level.map_or(p, |l| p.with_simd(l));
        let vc = trirast::pipeline::VertexColor;
        let stats = [
            p.draw(&mut targets[0], &vs4, &vc, &indices, triangles).unwrap(),
            p.draw(&mut targets[1], &vs3, &vc, &indices, triangles).unwrap(),
            p.draw(&mut targets[2], &vs4, shader, &indices, triangles).unwrap(),
        ];
        (targets, stats)
    };
    let counted = Tinted(0.into());
    let (reference, ref_stats) = draw(Backend::Reference, Schedule::Auto, None, &counted);
    let reference_calls = counted.0.into_inner();
    for level in SimdLevel::available() {
        for threads in [1, 2, 7] {
            for schedule in SCHEDULES {
                let counted = Tinted(0.into());
                let (tiled, stats) =
                    pool(threads).install(|| draw(Backend::Tiled, schedule, Some(level), &counted));
                let what = format!("{what}, {level:?}, {threads} threads, {schedule:?}");
                assert_eq!(stats, ref_stats, "{what}");
                for (k, (a, b)) in reference.iter().zip(&tiled).enumerate() {
                    assert_same(a, b, &format!("{what}, shader {k}"));
                }
                let calls = counted.0.into_inner();
                if kernels.contains(&level) {
                    assert!(4 * calls < reference_calls, "{what}: {calls} of {reference_calls}");
                }
            }
        }
    }
    ref_stats
}

/// Small triangles with interpolated vertex colours, which the tiled backend shades eight
/// triangles at a time in one SIMD kernel at AVX2 and AVX-512 (`simd::shade_small_eight`): two
/// grids of two-pixel triangles over a small target, one in perspective (`w` from 0.5 to 2)
/// and one affine across it at other depths, then random triangles in boxes of up to about
/// 5 and 10 pixels a side (those of the shared lane queue, those of the kernel alone, and
/// larger ones, in runs together), each drawn twice in a row (so the triangles of a
/// kernel's group share pixels), with `VertexColor` on `Vec4` and
/// `Vec3` colours and a tinted shader with a constant alpha, every depth test, into targets
/// with and without ids and overdraw: the reference's buffers and counts at every SIMD
/// level, on 1, 2 and 7 threads, binned and banded; at AVX2 and AVX-512 the shader was
/// called for few of the fragments the reference shaded.
#[test]
fn tiny_vertex_coloured_triangles_match_the_reference() {
    let mut rng = SmallRng::seed_from_u64(43);
    let (mut positions, mut colors, mut triangles) = (Vec::new(), Vec::<Vec4>::new(), Vec::new());
    let color =
        |rng: &mut SmallRng| Vec4::from_array(std::array::from_fn(|_| rng.random_range(-0.1..1.1)));
    let (nx, ny) = (40u32, 30u32);
    for layer in 0..2 {
        let first = positions.len() as u32;
        for j in 0..=ny {
            for i in 0..=nx {
                let (x, y) = (-1.0 + 2.0 * i as f32 / nx as f32, -1.0 + 2.0 * j as f32 / ny as f32);
                let z = rng.random_range(0.1..0.9f32);
                let w = if layer == 0 { 0.5 + 0.75 * (x + 1.0) } else { 1.0 };
                positions.push(Vec4::new(x * w, y * w, z * w, w));
                colors.push(color(&mut rng));
            }
        }
        for j in 0..ny {
            for i in 0..nx {
                let a = first + j * (nx + 1) + i;
                triangles.push([a, a + 1, a + nx + 2]);
                triangles.push([a, a + nx + 2, a + nx + 1]);
            }
        }
    }
    // One triangle alone first: the pairs below then start at odd ids, and some straddle the
    // front end's groups of eight (a pair's first in a group the shader declines, its second
    // set up straight into kernel lanes).
    let lone = positions.len() as u32;
    positions
        .extend([(0.0, 0.0), (0.05, 0.0), (0.0, 0.05)].map(|(x, y)| Vec4::new(x, y, 0.5, 1.0)));
    colors.extend((0..3).map(|_| color(&mut rng)));
    triangles.push([lone, lone + 1, lone + 2]);
    for k in 0..2000 {
        let (cx, cy) = (rng.random_range(-1.0..1.0f32), rng.random_range(-1.0..1.0f32));
        let r = if k % 3 == 0 { 0.09 } else { 0.04 };
        let corners: [Vec4; 3] = std::array::from_fn(|_| {
            let (x, y) = (cx + rng.random_range(-r..r), cy + rng.random_range(-r..r));
            Vec4::new(x, y, rng.random_range(0.0..1.0), 1.0)
        });
        for _ in 0..2 {
            let first = positions.len() as u32;
            positions.extend(corners);
            colors.extend((0..3).map(|_| color(&mut rng)));
            triangles.push([first, first + 1, first + 2]);
        }
    }
    let mesh = (&positions[..], &colors[..], &triangles[..]);
    let tests = [DepthTest::Less, DepthTest::LessEqual, DepthTest::Always];
    for samples in [SampleCount::X1, SampleCount::X4] {
        for (k, depth_test) in tests.into_iter().enumerate() {
            // At 4x an overdraw buffer keeps the triangles off the small kernel: ids alone.
            let fresh = || {
                let t = Target::multisampled(96, 72, samples).unwrap();
                match k {
                    0 => t.with_ids().with_overdraw(),
                    1 => t.with_ids(),
                    _ => t,
                }
            };
            let pipeline =
                Pipeline::default().with_cull(FaceCull::None).with_depth_test(depth_test);
            let what = format!("{samples:?}, {depth_test:?}");
            let kernels: &[_] = match (samples, k) {
                (SampleCount::X4, 0) => &[],
                _ => &[SimdLevel::Avx2, SimdLevel::Avx512],
            };
            let stats = assert_vertex_colours_match(mesh, pipeline, fresh, kernels, &what);
            assert!(stats[0].fragments > 10_000, "{:?}", stats[0]);
        }
    }
}

/// The random soup of an image with a side of 0 is empty, where sampling its positions had
/// panicked; the other demos stay degenerate triangles, as before.
#[test]
fn demo_scenes_of_an_empty_image_do_not_panic() {
    use trirast::scene::{Demo, demo, soup};
    for (w, h) in [(0, 10), (10, 0), (0, 0)] {
        assert!(soup(w, h, 5, 1).triangles.is_empty());
        for which in [Demo::Flat, Demo::Smooth, Demo::Soup] {
            let _ = demo(which, w, h);
        }
    }
}
