//! Interpolation properties: vertex values reproduced exactly at vertex pixel centres, flat
//! colours, perspective-correct varyings against the analytic values on a 3D quad, and depth
//! per sample on multisampled targets.

mod common;

use common::centre;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::shade::{PerspectivePlane, TriangleShader};
use trirast::{CullMode, PlaneEquation, RenderOptions, Shading, Target, TriangleSetup, Vertex};

fn ulps(a: f32, b: f32) -> u32 {
    (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
}

fn random_vertex(rng: &mut SmallRng, px: i64, py: i64) -> Vertex {
    Vertex {
        x: px as f32 + 0.5,
        y: py as f32 + 0.5,
        z: rng.random_range(0.0..1.0),
        inv_w: rng.random_range(0.05..4.0),
        color: [rng.random(), rng.random(), rng.random(), rng.random()],
    }
}

/// At each vertex on a pixel centre, the plane equations give back the vertex's own colour
/// (exactly) and depth (within 1 ulp), for smooth and perspective shading, on 50,000 random
/// triangles including slivers.
#[test]
fn vertex_values_are_reproduced_at_vertex_centres() {
    let mut rng = SmallRng::seed_from_u64(77);
    let mut worst = 0;
    for _ in 0..50_000 {
        let v: [Vertex; 3] = std::array::from_fn(|_| {
            let (x, y) = (rng.random_range(-200..200), rng.random_range(-200..200));
            random_vertex(&mut rng, x, y)
        });
        let Ok(setup) = TriangleSetup::new(&v, CullMode::None) else { continue };
        for shading in [Shading::Smooth, Shading::Perspective] {
            let shader = TriangleShader::new(&v, &setup, shading);
            for (i, p) in v.iter().enumerate() {
                let [x, y] = setup.xy[i].map(i64::from);
                let (e1, e2) = setup.barycentric_numerators(x, y);
                let (e1, e2) = (e1 as f64, e2 as f64);
                assert_eq!(shader.color_at(e1, e2), p.color, "{shading:?} vertex {i} of {v:?}");
                let d = ulps(shader.depth_at(e1, e2), p.z);
                worst = worst.max(d);
                assert!(d <= 1, "depth off by {d} ulps at vertex {i} of {v:?}");
            }
        }
    }
    eprintln!("worst depth error at a vertex: {worst} ulp");
}

/// The same through the whole pipeline: fans of triangles around a shared vertex on a pixel
/// centre; whichever triangle owns that centre writes exactly the shared vertex's values.
#[test]
fn shared_vertex_values_reach_the_buffers() {
    let mut rng = SmallRng::seed_from_u64(3);
    let mut checked = 0;
    for _ in 0..2_000 {
        let centre_vertex = random_vertex(&mut rng, 16, 16);
        let k = rng.random_range(3..9);
        let mut angles: Vec<f64> =
            (0..k).map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect();
        angles.sort_by(f64::total_cmp);
        let ring: Vec<Vertex> = angles
            .iter()
            .map(|a| {
                let r = rng.random_range(2.0..14.0);
                let mut p = random_vertex(&mut rng, 0, 0);
                p.x = 16.5 + (r * a.cos()) as f32;
                p.y = 16.5 + (r * a.sin()) as f32;
                p
            })
            .collect();
        let tris: Vec<[Vertex; 3]> =
            (0..k).map(|i| [centre_vertex, ring[i], ring[(i + 1) % k]]).collect();
        for shading in [Shading::Smooth, Shading::Perspective] {
            let mut target = Target::new(33, 33).unwrap().with_overdraw();
            let options = RenderOptions::default().with_shading(shading);
            trirast::draw(&mut target, &tris, &options).unwrap();
            let i = target.index(16, 16);
            // Only fans that close around the centre are guaranteed to cover it.
            if target.overdraw.as_ref().unwrap()[i] != 1 {
                continue;
            }
            assert_eq!(target.color[i], centre_vertex.color);
            assert!(ulps(target.depth[i], centre_vertex.z) <= 1);
            checked += 1;
        }
    }
    assert!(checked > 1000, "only {checked} closed fans");
}

#[test]
fn flat_colour_is_the_rounded_average() {
    let mut rng = SmallRng::seed_from_u64(8);
    for _ in 0..2_000 {
        let v: [Vertex; 3] = std::array::from_fn(|_| {
            let (x, y) = (rng.random_range(0..24), rng.random_range(0..24));
            random_vertex(&mut rng, x, y)
        });
        let mut target = Target::new(24, 24).unwrap().with_ids();
        let options = RenderOptions::default().with_shading(Shading::Flat);
        trirast::draw(&mut target, &[v], &options).unwrap();
        let expect: [u8; 4] = std::array::from_fn(|c| {
            let sum: u32 = v.iter().map(|p| u32::from(p.color[c])).sum();
            // Nearest integer to sum / 3 (never a tie: thirds).
            (f64::from(sum) / 3.0).round() as u8
        });
        for (i, id) in target.ids.unwrap().iter().enumerate() {
            if *id == 0 {
                assert_eq!(target.color[i], expect);
            }
        }
    }
}

/// A quad in 3D, seen in perspective. Camera at the origin looking along +Z, y down; a point
/// (X, Y, Z) lands at window (cx + f X / Z, cy + f Y / Z) with w = Z and depth 1 - 1/Z.
struct PerspectiveQuad {
    origin: [f64; 3],
    du: [f64; 3],
    dv: [f64; 3],
    f: f64,
    c: [f64; 2],
}

impl PerspectiveQuad {
    fn point(&self, u: f64, v: f64) -> [f64; 3] {
        std::array::from_fn(|k| self.origin[k] + u * self.du[k] + v * self.dv[k])
    }

    fn vertex(&self, u: f64, v: f64) -> Vertex {
        let [x, y, z] = self.point(u, v);
        Vertex {
            x: (self.c[0] + self.f * x / z) as f32,
            y: (self.c[1] + self.f * y / z) as f32,
            z: (1.0 - 1.0 / z) as f32,
            inv_w: (1.0 / z) as f32,
            color: [(255.0 * u) as u8, (255.0 * v) as u8, 0, 255],
        }
    }

    /// (u, v, Z) where the ray through window point (sx, sy) meets the quad's plane.
    fn analytic(&self, sx: f64, sy: f64) -> (f64, f64, f64) {
        let d = [(sx - self.c[0]) / self.f, (sy - self.c[1]) / self.f, 1.0];
        // Solve origin + u du + v dv = t d  by Cramer's rule.
        let det3 = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
            a[0] * (b[1] * c[2] - b[2] * c[1]) - b[0] * (a[1] * c[2] - a[2] * c[1])
                + c[0] * (a[1] * b[2] - a[2] * b[1])
        };
        let neg_o = self.origin.map(|x| -x);
        let m = det3(self.du, self.dv, d.map(|x| -x));
        let u = det3(neg_o, self.dv, d.map(|x| -x)) / m;
        let v = det3(self.du, neg_o, d.map(|x| -x)) / m;
        let t = det3(self.du, self.dv, neg_o) / m;
        (u, v, t)
    }
}

#[test]
fn perspective_correct_varyings_match_the_analytic_quad() {
    let quad = PerspectiveQuad {
        // A floor-like quad receding from Z = 1.2 to Z = 9.
        origin: [-1.0, 0.6, 1.2],
        du: [2.2, 0.0, 0.0],
        dv: [0.3, -0.5, 7.8],
        f: 120.0,
        c: [100.0, 80.0],
    };
    let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    let v = corners.map(|(u, v)| quad.vertex(u, v));
    let tris = [[v[0], v[1], v[2]], [v[0], v[2], v[3]]];
    let (mut checked, mut worst, mut worst_linear) = (0, 0.0f64, 0.0f64);
    for (t, tri) in tris.iter().enumerate() {
        let setup = TriangleSetup::new(tri, CullMode::None).unwrap();
        let [u3, v3] = [0, 1].map(|k| {
            let (a, b, c) = (corners[[0, 0][t]], corners[[1, 2][t]], corners[[2, 3][t]]);
            [[a.0, b.0, c.0], [a.1, b.1, c.1]][k]
        });
        let inv_w = tri.map(|p| f64::from(p.inv_w));
        let pu = PerspectivePlane::new(u3, inv_w, &setup);
        let pv = PerspectivePlane::new(v3, inv_w, &setup);
        let linear_u = PlaneEquation::new(u3, &setup);
        let shader = TriangleShader::new(tri, &setup, Shading::Smooth);
        for py in 0..160 {
            for px in 0..200 {
                if !setup.covers(px, py) {
                    continue;
                }
                let (x, y) = (centre(px.into()), centre(py.into()));
                let (e1, e2) = setup.barycentric_numerators(x, y);
                let (e1, e2) = (e1 as f64, e2 as f64);
                let (au, av, az) = quad.analytic(f64::from(px) + 0.5, f64::from(py) + 0.5);
                let err = (pu.eval(e1, e2) - au).abs().max((pv.eval(e1, e2) - av).abs());
                worst = worst.max(err);
                worst_linear = worst_linear.max((linear_u.eval(e1, e2) - au).abs());
                // Depth (1 - 1/Z) is affine in screen space: linear interpolation is exact.
                let dz = (f64::from(shader.depth_at(e1, e2)) - (1.0 - 1.0 / az)).abs();
                assert!(dz < 2e-5, "depth off by {dz} at ({px}, {py})");
                checked += 1;
            }
        }
    }
    eprintln!(
        "{checked} pixels: perspective error {worst:.2e}, screen-linear error {worst_linear:.2e}"
    );
    assert!(checked > 5000);
    // Vertex snapping (at most 1/512 pixel) bounds the error well below this.
    assert!(worst < 5e-4, "perspective-correct u, v off by {worst}");
    // And the scene is perspective enough that screen-linear interpolation fails clearly.
    assert!(worst_linear > 0.05, "{worst_linear}");

    // Through the pipeline: colour channels carry 255 u and 255 v.
    let mut target = Target::new(200, 160).unwrap().with_ids();
    let tris = [[v[0], v[1], v[2]], [v[0], v[2], v[3]]];
    let mut tris_c = tris;
    for t in &mut tris_c {
        for p in t.iter_mut() {
            // Exact corner colours: u, v in {0, 1}.
            p.color = [
                if p.color[0] > 0 { 255 } else { 0 },
                if p.color[1] > 0 { 255 } else { 0 },
                0,
                255,
            ];
        }
    }
    let options = RenderOptions::default().with_shading(Shading::Perspective);
    trirast::draw(&mut target, &tris_c, &options).unwrap();
    for py in 0..160 {
        for px in 0..200 {
            let i = target.index(px, py);
            if target.ids.as_ref().unwrap()[i] < 0 {
                continue;
            }
            let (au, av, _) = quad.analytic(f64::from(px) + 0.5, f64::from(py) + 0.5);
            let [r, g, ..] = target.color[i];
            assert!((f64::from(r) - 255.0 * au).abs() <= 0.6, "r {r} vs u {au}");
            assert!((f64::from(g) - 255.0 * av).abs() <= 0.6, "g {g} vs v {av}");
        }
    }
}

/// On multisampled targets, each triangle drawn alone writes, at every sample it covers, the
/// depth plane evaluated at that sample's exact numerators and the colour at its pixel
/// centre, and leaves every other sample cleared: checked from the setup, the plane and the
/// sample pattern, independently of the fragment loop (whose per-pixel path and span kernels
/// both backends share, so holding one backend to the other cannot catch a wrong sample
/// position). Large and small triangles, all three shadings, both backends, 4x and 8x.
#[test]
fn multisampled_depth_is_the_plane_at_each_sample() {
    use trirast::render::Backend;
    use trirast::sample::SampleCount;
    let mut rng = SmallRng::seed_from_u64(808);
    let (w, h) = (90u32, 70u32);
    for round in 0..60 {
        let samples = [SampleCount::X4, SampleCount::X8][round % 2];
        let shading = [Shading::Flat, Shading::Smooth, Shading::Perspective][(round / 2) % 3];
        let size = [3.0, 20.0, 80.0][(round / 6) % 3];
        let (cx, cy) = (rng.random_range(0.0..w as f32), rng.random_range(0.0..h as f32));
        let v: [Vertex; 3] = std::array::from_fn(|_| Vertex {
            x: cx + rng.random_range(-size..size),
            y: cy + rng.random_range(-size..size),
            z: rng.random_range(0.0..0.99),
            inv_w: rng.random_range(0.2..3.0),
            color: [rng.random(), rng.random(), rng.random(), 255],
        });
        let Ok(setup) = TriangleSetup::new(&v, CullMode::None) else { continue };
        let shader = TriangleShader::new(&v, &setup, shading);
        let depth = PlaneEquation::new(v.map(|p| f64::from(p.z)), &setup);
        let n = samples.count();
        for backend in [Backend::Reference, Backend::Tiled] {
            let mut target = Target::multisampled(w, h, samples).unwrap();
            let options = RenderOptions::default().with_shading(shading).with_backend(backend);
            trirast::draw(&mut target, &[v], &options).unwrap();
            for (py, px) in (0..h as i32).flat_map(|y| (0..w as i32).map(move |x| (y, x))) {
                let (x, y) = (centre(px as i64), centre(py as i64));
                let (c1, c2) = setup.barycentric_numerators(x, y);
                let color = shader.color_at(c1 as f64, c2 as f64);
                for s in 0..n {
                    let [ox, oy] = samples.offset(s);
                    let i = (py as usize * w as usize + px as usize) * n + s;
                    let what = format!("round {round}, {backend:?}, pixel ({px}, {py}) sample {s}");
                    if setup.covers_point(x + ox, y + oy) {
                        let (e1, e2) = setup.barycentric_numerators(x + ox, y + oy);
                        let z = trirast::shade::depth_at(&depth, e1 as f64, e2 as f64);
                        assert_eq!(target.depth[i].to_bits(), z.to_bits(), "{what}");
                        assert_eq!(target.color[i], color, "{what}");
                    } else {
                        assert_eq!(target.depth[i], 1.0, "{what}");
                    }
                }
            }
        }
    }
}
