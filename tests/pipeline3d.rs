//! The 3D pipeline: clipping against the analytic visible region, culling and winding,
//! auto-framing, perspective-correct varyings through clipping, and textures.

use glam::{DVec3, Vec2, Vec3, Vec4};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::Target;
use trirast::camera::{self, Camera, Projection};
use trirast::pipeline::{FaceCull, Fragment, IndexBuffer, Pipeline};
use trirast::render::Backend;
use trirast::texture::{Filter, Texture, Wrap};

const W: u32 = 160;
const H: u32 = 120;

/// A camera at the origin looking down -Z.
fn camera(near: f32) -> Camera {
    Camera {
        eye: Vec3::ZERO,
        target: Vec3::NEG_Z,
        up: Vec3::Y,
        projection: Projection::Perspective { fov_y: 1.2 },
        near,
        far: 100.0,
    }
}

/// Renders view-space triangles (no culling) and returns the id buffer and the u varying.
fn render(cam: &Camera, tris: &[[Vec3; 3]], uvs: &[[f32; 3]]) -> (Vec<i32>, Vec<f32>) {
    let mut target = Target::new(W, H).unwrap().with_ids();
    let vp = cam.view_projection(W as f32 / H as f32);
    let vertices: Vec<(Vec3, f32)> =
        tris.iter().zip(uvs).flat_map(|(t, u)| (0..3).map(move |k| (t[k], u[k]))).collect();
    let indices: Vec<[u32; 3]> =
        (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let u_buf = std::sync::Mutex::new(vec![f32::NAN; (W * H) as usize]);
    let vs = |v: &(Vec3, f32)| (vp * v.0.extend(1.0), v.1);
    let fs = |f: &Fragment<f32>| {
        u_buf.lock().unwrap()[(f.y as u32 * W + f.x as u32) as usize] = f.varyings;
        Some(Vec4::ONE)
    };
    Pipeline::default()
        .with_cull(FaceCull::None)
        .draw(&mut target, &vs, &fs, &vertices, &indices)
        .unwrap();
    (target.ids.unwrap(), u_buf.into_inner().unwrap())
}

/// Where the ray through pixel centre (px, py) meets the triangle's plane, in view space, as
/// barycentrics (b1, b2) and the hit point; `None` when parallel.
fn ray_hit(cam: &Camera, t: [Vec3; 3], px: u32, py: u32) -> Option<(f64, f64, DVec3)> {
    let Projection::Perspective { fov_y } = cam.projection else { unreachable!() };
    let tan = (f64::from(fov_y) / 2.0).tan();
    let aspect = f64::from(W) / f64::from(H);
    let ndc_x = (f64::from(px) + 0.5) / f64::from(W) * 2.0 - 1.0;
    let ndc_y = 1.0 - (f64::from(py) + 0.5) / f64::from(H) * 2.0;
    let d = DVec3::new(ndc_x * tan * aspect, ndc_y * tan, -1.0);
    let [a, b, c] = t.map(|v| v.as_dvec3());
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = -a;
    let b1 = s.dot(p) / det;
    let q = s.cross(e1);
    let b2 = d.dot(q) / det;
    let t_ray = e2.dot(q) / det;
    Some((b1, b2, d * t_ray))
}

/// The analytic verdict for a pixel: Some(true) clearly inside the visible part (in the
/// triangle, in front of the near plane, by a margin), Some(false) clearly outside, None near
/// a boundary.
fn analytic(cam: &Camera, t: [Vec3; 3], px: u32, py: u32) -> Option<bool> {
    let Some((b1, b2, hit)) = ray_hit(cam, t, px, py) else { return Some(false) };
    let b0 = 1.0 - b1 - b2;
    let margin = 2e-3;
    let near = -f64::from(cam.near);
    let depth_margin = (hit.z - near) / near.abs(); // > 0 means behind the near plane
    let far = -f64::from(cam.far);
    let far_margin = (far - hit.z) / far.abs(); // > 0 means beyond the far plane
    let behind_eye = hit.z >= 0.0;
    let worst = b0.min(b1).min(b2);
    if behind_eye || worst < -margin || depth_margin > margin || far_margin > margin {
        return Some(false);
    }
    if worst > margin && depth_margin < -margin && far_margin < -margin {
        return Some(true);
    }
    None
}

/// Renders `t` alone and checks every pixel the analytic test decides; returns how many.
fn assert_renders_the_analytic_region(cam: &Camera, t: [Vec3; 3]) -> usize {
    let (ids, _) = render(cam, &[t], &[[0.0; 3]]);
    let mut checked = 0;
    for py in 0..H {
        for px in 0..W {
            let got = ids[(py * W + px) as usize] == 0;
            if let Some(want) = analytic(cam, t, px, py) {
                let (near, far) = (cam.near, cam.far);
                assert_eq!(got, want, "pixel ({px}, {py}) of {t:?}, near {near}, far {far}");
                checked += 1;
            }
        }
    }
    checked
}

#[test]
fn near_plane_clipping_renders_exactly_the_visible_part() {
    let mut rng = SmallRng::seed_from_u64(11);
    let mut checked = 0;
    for _ in 0..40 {
        let cam = camera(rng.random_range(0.1..1.0));
        // Triangles reaching from in front of the camera to behind it, some with a vertex
        // exactly on the camera plane (w = 0).
        let mut t: [Vec3; 3] = std::array::from_fn(|_| {
            Vec3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-6.0..1.5),
            )
        });
        if rng.random() {
            t[0].z = 0.0;
        }
        checked += assert_renders_the_analytic_region(&cam, t);
    }
    assert!(checked > 40 * (W * H) as usize * 9 / 10);
}

/// In a projection without a near plane (depth `z = w / 2`: only `w >= MIN_W` bounds the
/// view in front of the eye), a triangle reaching behind the eye draws exactly the part in
/// front of it, cut by the guard band. Its edges had met the `w` plane at vertices rounded
/// onto the eye's plane (`w = 0`), whose pieces were non-finite and dropped: the whole
/// triangle went undrawn.
#[test]
fn triangles_through_the_eye_plane_draw_their_part_in_front_of_it() {
    let mut rng = SmallRng::seed_from_u64(17);
    // The analytic test's camera: its near and far planes out of the way.
    let mut cam = camera(1e-6);
    cam.far = 1e9;
    let Projection::Perspective { fov_y } = cam.projection else { unreachable!() };
    let f = 1.0 / (fov_y / 2.0).tan();
    let aspect = W as f32 / H as f32;
    let vs = |v: &Vec3| (Vec4::new(v.x * f / aspect, v.y * f, -v.z / 2.0, -v.z), ());
    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
    let (mut checked, mut drawn) = (0, 0);
    for i in 0..60 {
        let mut t: [Vec3; 3] = std::array::from_fn(|_| {
            Vec3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-6.0..1.5),
            )
        });
        match i % 3 {
            0 => t[0].z = 0.0,
            // Clip space (-s, -s, _, s), (s, -s, _, s), (0, s, _, -s): in `f32` the edges to
            // the last met the `w` plane where w is 0 (t is 1/2 exactly: MIN_W is below the
            // precision of s).
            1 => {
                let s = rng.random_range(0.5..3.0);
                let (x, y) = (s * aspect / f, s / f);
                t = [Vec3::new(-x, -y, -s), Vec3::new(x, -y, -s), Vec3::new(0.0, y, s)];
            }
            _ => {}
        }
        let mut target = Target::new(W, H).unwrap().with_ids();
        let stats = Pipeline::default()
            .with_cull(FaceCull::None)
            .draw(&mut target, &vs, &fs, &t, &[[0, 1, 2]])
            .unwrap();
        assert_eq!(stats.non_finite, 0, "{t:?}: {stats:?}");
        let ids = target.ids.unwrap();
        for py in 0..H {
            for px in 0..W {
                let got = ids[(py * W + px) as usize] == 0;
                if let Some(want) = analytic(&cam, t, px, py) {
                    assert_eq!(got, want, "pixel ({px}, {py}) of {t:?}");
                    checked += 1;
                    drawn += usize::from(want);
                }
            }
        }
    }
    assert!(checked > 60 * (W * H) as usize * 9 / 10 && drawn > 60 * (W * H) as usize / 10);
}

/// A triangle over the whole view with clip-space coordinates near `f32::MAX` covers every
/// pixel: in `f32`, the clip's differences overflowed and it had been clipped to nothing.
#[test]
fn a_huge_triangle_over_the_view_covers_every_pixel() {
    for c in [1.0e30f32, 1.7e38, 3.0e38, f32::MAX] {
        let t =
            [Vec4::new(c, 0.0, 0.5, 1.0), Vec4::new(-c, c, 0.5, 1.0), Vec4::new(0.0, -c, 0.5, 1.0)];
        let mut target = Target::new(W, H).unwrap().with_ids();
        let stats = Pipeline::default()
            .with_cull(FaceCull::None)
            .draw(
                &mut target,
                &|v: &Vec4| (*v, ()),
                &|_: &Fragment<()>| Some(Vec4::ONE),
                &t,
                &[[0, 1, 2]],
            )
            .unwrap();
        let ids = target.ids.unwrap();
        assert!(ids.iter().all(|&i| i == 0), "{c:e}: {stats:?}");
    }
}

#[test]
fn far_plane_clipping_renders_exactly_the_part_in_front_of_it() {
    let mut rng = SmallRng::seed_from_u64(13);
    let mut checked = 0;
    for _ in 0..30 {
        let mut cam = camera(0.2);
        cam.far = rng.random_range(2.0..6.0);
        // Triangles reaching from well inside the view volume to far beyond the far plane.
        let t: [Vec3; 3] = std::array::from_fn(|_| {
            let z = rng.random_range(-14.0..-0.5f32);
            Vec3::new(rng.random_range(-0.4..0.4) * -z, rng.random_range(-0.3..0.3) * -z, z)
        });
        checked += assert_renders_the_analytic_region(&cam, t);
    }
    assert!(checked > 30 * (W * H) as usize * 9 / 10);
}

#[test]
fn a_triangle_behind_the_camera_renders_nothing() {
    let cam = camera(0.5);
    let t = [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, 2.0), Vec3::new(0.0, 1.0, 0.3)];
    let (ids, _) = render(&cam, &[t], &[[0.0; 3]]);
    assert!(ids.iter().all(|&i| i == -1));
    // Also when it straddles the camera plane but stays in front of nothing visible.
    let t = [Vec3::new(-1.0, -1.0, 2.0), Vec3::new(1.0, -1.0, -0.2), Vec3::new(0.0, 1.0, 0.0)];
    let (ids, _) = render(&cam, &[t], &[[0.0; 3]]);
    assert!(ids.iter().all(|&i| i == -1));
}

/// Varyings of a clipped triangle stay perspective-correct: u at every clearly-inside pixel
/// equals the analytic barycentric interpolation of u on the 3D triangle.
#[test]
fn clipped_varyings_are_perspective_correct() {
    let mut rng = SmallRng::seed_from_u64(12);
    let mut worst = 0.0f64;
    for _ in 0..30 {
        let cam = camera(0.3);
        let t: [Vec3; 3] = std::array::from_fn(|_| {
            Vec3::new(
                rng.random_range(-3.0..3.0),
                rng.random_range(-3.0..3.0),
                rng.random_range(-8.0..1.0),
            )
        });
        let u = [0.0, 1.0, rng.random_range(0.0..1.0)];
        let (ids, got) = render(&cam, &[t], &[u]);
        for py in 0..H {
            for px in 0..W {
                if ids[(py * W + px) as usize] != 0 || analytic(&cam, t, px, py) != Some(true) {
                    continue;
                }
                let (b1, b2, _) = ray_hit(&cam, t, px, py).unwrap();
                let want =
                    (1.0 - b1 - b2) * f64::from(u[0]) + b1 * f64::from(u[1]) + b2 * f64::from(u[2]);
                worst = worst.max((f64::from(got[(py * W + px) as usize]) - want).abs());
            }
        }
    }
    assert!(worst < 2e-3, "worst varying error {worst}");
}

/// A triangle a million pixels wide gives the same pixels as the same triangle clipped to the
/// screen beforehand (away from its edges by more than the snapping tolerance).
#[test]
fn huge_triangle_matches_the_preclipped_one() {
    let ortho = |p: [f64; 2]| Vec4::new(p[0] as f32, p[1] as f32, 0.5, 1.0);
    let huge = [[-12000.0, -0.83], [13000.0, -0.71], [0.07, 0.92]];
    // Clip against the screen square [-1, 1]^2 in f64 (Sutherland-Hodgman).
    let mut poly: Vec<[f64; 2]> = huge.to_vec();
    for (axis, sign) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)] {
        let inside = |p: &[f64; 2]| sign * p[axis] <= 1.0;
        let mut out = Vec::new();
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) {
                let t = (sign - a[axis]) / (b[axis] - a[axis]);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        poly = out;
    }
    let draw = |tris: &[[[f64; 2]; 3]]| {
        let verts: Vec<Vec4> = tris.iter().flat_map(|t| t.map(ortho)).collect();
        let idx: Vec<[u32; 3]> =
            (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let mut target = Target::new(W, H).unwrap().with_overdraw();
        let vs = |p: &Vec4| (*p, ());
        let fs = |_: &Fragment<()>| Some(Vec4::ONE);
        Pipeline::default()
            .with_cull(FaceCull::None)
            .draw(&mut target, &vs, &fs, &verts, &idx)
            .unwrap();
        target.overdraw.unwrap()
    };
    let a = draw(&[huge]);
    let fan: Vec<[[f64; 2]; 3]> =
        (1..poly.len() - 1).map(|k| [poly[0], poly[k], poly[k + 1]]).collect();
    let b = draw(&fan);
    // Distance in pixels from a pixel centre to the huge triangle's edges.
    let to_px =
        |p: [f64; 2]| [(p[0] + 1.0) * f64::from(W) / 2.0, (1.0 - p[1]) * f64::from(H) / 2.0];
    let hp = huge.map(to_px);
    let mut compared = 0;
    for py in 0..H {
        for px in 0..W {
            let c = [f64::from(px) + 0.5, f64::from(py) + 0.5];
            let near_edge = (0..3).any(|i| {
                let (p, q) = (hp[i], hp[(i + 1) % 3]);
                let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
                ((c[0] - p[0]) * dy - (c[1] - p[1]) * dx).abs() / dx.hypot(dy) < 0.02
            });
            let i = (py * W + px) as usize;
            assert!(b[i] <= 1 && a[i] <= 1, "overdraw at ({px}, {py})");
            if !near_edge {
                assert_eq!(a[i], b[i], "pixel ({px}, {py})");
                compared += 1;
            }
        }
    }
    assert!(a.iter().sum::<u32>() > 1000 && compared > (W * H) as usize * 9 / 10);
}

#[test]
fn culling_follows_the_winding() {
    let ccw = [Vec3::new(-1.0, -1.0, -3.0), Vec3::new(1.0, -1.0, -3.0), Vec3::new(0.0, 1.0, -3.0)];
    let cw = [ccw[0], ccw[2], ccw[1]];
    let cam = camera(0.5);
    let vp = cam.view_projection(W as f32 / H as f32);
    for (cull, want_ccw, want_cw) in [
        (FaceCull::Back, true, false),
        (FaceCull::Front, false, true),
        (FaceCull::None, true, true),
    ] {
        for (tri, want, front) in [(ccw, want_ccw, true), (cw, want_cw, false)] {
            let mut target = Target::new(W, H).unwrap().with_ids();
            let vs = |v: &Vec3| (vp * v.extend(1.0), ());
            let fs = |f: &Fragment<()>| {
                assert_eq!(f.front_facing, front);
                Some(Vec4::ONE)
            };
            let stats = Pipeline::default()
                .with_cull(cull)
                .draw(&mut target, &vs, &fs, &tri, &[[0, 1, 2]])
                .unwrap();
            let drawn = target.ids.unwrap().contains(&0);
            assert_eq!(drawn, want, "{cull:?}, front {front}");
            assert_eq!(stats.culled, usize::from(!want));
        }
    }
}

#[test]
fn index_out_of_range_is_an_error() {
    let mut target = Target::new(8, 8).unwrap();
    let vs = |v: &Vec4| (*v, ());
    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
    let err =
        Pipeline::default().draw(&mut target, &vs, &fs, &[Vec4::ONE; 3], &[[0, 1, 3]]).unwrap_err();
    assert!(err.to_string().contains("only 3 vertices"), "{err}");
    // The same error from kept index ranges, for the first bad triangle of a larger mesh.
    let mut triangles = vec![[0, 1, 2]; 700];
    triangles[600] = [2, 3, 1];
    triangles[650] = [4, 0, 1];
    let indexed = IndexBuffer::new(triangles.clone());
    assert_eq!(indexed.largest(), Some(4));
    let pipeline = Pipeline::default();
    let plain = pipeline.draw(&mut target, &vs, &fs, &[Vec4::ONE; 3], &triangles).unwrap_err();
    let kept = pipeline.draw_indexed(&mut target, &vs, &fs, &[Vec4::ONE; 3], &indexed).unwrap_err();
    assert_eq!(plain.to_string(), kept.to_string());
    assert!(kept.to_string().contains("triangle 600"), "{kept}");
    let five = [Vec4::ONE; 5];
    pipeline.draw_indexed(&mut target, &vs, &fs, &five, &indexed).unwrap();
    assert_eq!(IndexBuffer::new(Vec::new()).largest(), None);
}

/// Auto-framing puts every vertex inside the image, for any cloud, view and aspect ratio.
#[test]
fn auto_framing_keeps_every_vertex_in_view() {
    let mut rng = SmallRng::seed_from_u64(21);
    for _ in 0..300 {
        let scale = 10f32.powf(rng.random_range(-3.0..4.0));
        // Offsets up to 100 model sizes: beyond that f32 positions themselves lose the shape.
        let offset = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ) * 100.0
            * scale;
        let stretch = Vec3::new(
            rng.random_range(0.01..1.0),
            rng.random_range(0.01..1.0),
            rng.random_range(0.01..1.0),
        );
        let points: Vec<[f32; 3]> = (0..200)
            .map(|_| {
                let p = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                (offset + p * stretch * scale).to_array()
            })
            .collect();
        let (centre, radius) = camera::bounding_sphere(&points);
        let aspect = rng.random_range(0.3..3.0);
        let projection = if rng.random() {
            Projection::Perspective { fov_y: rng.random_range(0.2..2.0) }
        } else {
            Projection::Orthographic { height: 1.0 }
        };
        let cam = Camera::framing_sphere(
            centre,
            radius,
            rng.random_range(-3.2..3.2),
            rng.random_range(-1.5..1.5),
            aspect,
            projection,
        );
        let m = cam.view_projection(aspect);
        for p in &points {
            let c = m * Vec3::from(*p).extend(1.0);
            let ndc = c.truncate() / c.w;
            assert!(c.w > 0.0);
            assert!(ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0, "{ndc:?} with {projection:?}");
            assert!((0.0..=1.0).contains(&ndc.z), "depth {}", ndc.z);
        }
    }
}

fn checker(n: u32) -> (Texture, Vec<[u8; 4]>) {
    let texels: Vec<[u8; 4]> = (0..n * n)
        .map(|i| {
            if (i % n + i / n).is_multiple_of(2) { [230, 40, 30, 255] } else { [20, 60, 200, 255] }
        })
        .collect();
    (Texture::from_srgba8(n, n, texels.as_flattened()), texels)
}

#[test]
fn sampling_at_texel_centres_returns_texels() {
    let mut rng = SmallRng::seed_from_u64(5);
    let (w, h) = (7u32, 5u32);
    let texels: Vec<[u8; 4]> =
        (0..w * h).map(|_| [rng.random(), rng.random(), rng.random(), rng.random()]).collect();
    let tex = Texture::from_srgba8(w, h, texels.as_flattened());
    for j in 0..h {
        for i in 0..w {
            let uv = Vec2::new((i as f32 + 0.5) / w as f32, 1.0 - (j as f32 + 0.5) / h as f32);
            let want = texels[(j * w + i) as usize];
            for filter in [Filter::Nearest, Filter::Bilinear] {
                for wrap in [Wrap::Repeat, Wrap::Clamp] {
                    let s = tex.sample(uv, filter, wrap);
                    let got = [
                        trirast::color::linear_to_srgb8(s.x),
                        trirast::color::linear_to_srgb8(s.y),
                        trirast::color::linear_to_srgb8(s.z),
                        trirast::color::unorm8(s.w),
                    ];
                    assert_eq!(got, want, "texel ({i}, {j}) {filter:?} {wrap:?}");
                }
            }
            // Repeat: one period away samples the same texel.
            let s = tex.sample(uv + Vec2::new(3.0, -2.0), Filter::Nearest, Wrap::Repeat);
            assert_eq!(s, tex.sample(uv, Filter::Nearest, Wrap::Repeat));
        }
    }
    // Clamp: far outside gives the edge texel.
    let edge = tex.sample(Vec2::new(50.0, 0.5), Filter::Bilinear, Wrap::Clamp);
    assert_eq!(edge, tex.texel(i64::from(w) - 1, i64::from(h / 2), Wrap::Clamp));
}

/// A checkerboard floor in perspective: every pixel whose analytic texture coordinate is away
/// from a cell border shows exactly that cell's colour.
#[test]
fn perspective_checkerboard_matches_the_analytic_checker() {
    let n = 8;
    let (tex, texels) = checker(n);
    let cam = camera(0.2);
    let vp = cam.view_projection(W as f32 / H as f32);
    // A floor quad receding from z = -1 to z = -20, u across, v along.
    let corners = [
        (Vec3::new(-2.0, -1.0, -1.0), Vec2::new(0.0, 0.0)),
        (Vec3::new(2.0, -1.0, -1.0), Vec2::new(1.0, 0.0)),
        (Vec3::new(2.0, -1.0, -20.0), Vec2::new(1.0, 1.0)),
        (Vec3::new(-2.0, -1.0, -20.0), Vec2::new(0.0, 1.0)),
    ];
    let mut target = Target::new(W, H).unwrap().with_ids();
    let vs = |v: &(Vec3, Vec2)| (vp * v.0.extend(1.0), v.1);
    let fs = |f: &Fragment<Vec2>| Some(tex.sample(f.varyings, Filter::Nearest, Wrap::Repeat));
    Pipeline::default()
        .with_cull(FaceCull::None)
        .draw(&mut target, &vs, &fs, &corners, &[[0, 1, 2], [0, 2, 3]])
        .unwrap();
    let tri = [corners[0].0, corners[1].0, corners[2].0];
    let mut checked = 0;
    for py in 0..H {
        for px in 0..W {
            let Some((_, _, hit)) = ray_hit(&cam, tri, px, py) else { continue };
            let u = (hit.x + 2.0) / 4.0;
            let v = (-1.0 - hit.z) / 19.0;
            if hit.z >= 0.0 || !(0.0..1.0).contains(&u) || !(0.0..1.0).contains(&v) {
                continue;
            }
            let (cu, cv) = (u * f64::from(n), v * f64::from(n));
            let border = |c: f64| (c - c.round()).abs() < 0.03;
            if border(cu) || border(cv) {
                continue;
            }
            let (i, j) = (cu.floor() as u32, n - 1 - cv.floor() as u32);
            let idx = target.index(px as i32, py as i32);
            assert!(target.ids.as_ref().unwrap()[idx] >= 0, "floor pixel ({px}, {py}) not drawn");
            assert_eq!(
                target.color[idx],
                texels[(j * n + i) as usize],
                "pixel ({px}, {py}) u {u} v {v}"
            );
            checked += 1;
        }
    }
    assert!(checked > 3000, "{checked}");
}

/// A triangle with a NaN or infinite clip-space coordinate is dropped and counted once as
/// non-finite, whichever coordinate it is and on both backends; the finite triangle beside it
/// is still drawn. (Clipped, a NaN vertex made a fan of pieces, each counted: "dropped 2".)
#[test]
fn non_finite_vertices_drop_their_triangle_once() {
    use trirast::render::Backend;
    let good = [Vec4::new(-0.5, -0.5, 0.5, 1.0), Vec4::new(0.5, -0.5, 0.5, 1.0)];
    let third = Vec4::new(0.0, 0.5, 0.5, 1.0);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for k in 0..4 {
            let mut p = third;
            p[k] = bad;
            let vertices = [good[0], good[1], p, third];
            let triangles = [[0, 1, 2], [0, 1, 3]];
            for backend in [Backend::Reference, Backend::Tiled] {
                let mut target = Target::new(W, H).unwrap().with_ids();
                let pipeline = Pipeline::default().with_cull(FaceCull::None).with_backend(backend);
                let vs = |v: &Vec4| (*v, ());
                let fs = |_: &Fragment<()>| Some(Vec4::ONE);
                let stats = pipeline.draw(&mut target, &vs, &fs, &vertices, &triangles).unwrap();
                let what = format!("{bad} at coordinate {k}, {backend:?}");
                assert_eq!((stats.non_finite, stats.rasterized), (1, 1), "{what}: {stats:?}");
                let ids = target.ids.as_ref().unwrap();
                assert!(ids.iter().all(|&i| i == -1 || i == 1), "{what}: triangle 0 drawn");
                assert!(ids.contains(&1), "{what}: the finite triangle is drawn");
            }
        }
    }
}

/// A finite triangle with coordinates near `f32::MAX` crossing the clip volume is drawn as
/// the same triangle scaled by a power of two (which changes no ratio the pipeline uses),
/// where the clip's overflows in `f32` had made it a fan of non-finite pieces, drawn as
/// nothing and each counted, or (a triangle over the whole view) nothing, counted as culled.
#[test]
fn huge_finite_triangles_are_clipped_as_their_scaled_copies() {
    use trirast::render::Backend;
    let huge = [
        Vec4::new(0.0, 0.0, 0.5, 1.0),
        Vec4::new(3e38, 3e38, -3e38, 3e38),
        Vec4::new(-3e38, 0.0, 3e38, 3e38),
    ];
    // Largest magnitude 3e38, in [2^127, 2^128): scaled by 2^(100 - 127).
    let scale = 2f32.powi(-27);
    let scaled = huge.map(|p| p * scale);
    for backend in [Backend::Reference, Backend::Tiled] {
        let draw = |vertices: &[Vec4; 3]| {
            let mut target = Target::new(W, H).unwrap().with_ids();
            let pipeline = Pipeline::default().with_cull(FaceCull::None).with_backend(backend);
            let vs = |v: &Vec4| (*v, ());
            let fs = |_: &Fragment<()>| Some(Vec4::ONE);
            let stats = pipeline.draw(&mut target, &vs, &fs, vertices, &[[0, 1, 2]]).unwrap();
            (stats, target)
        };
        let ((stats, target), (_, reference)) = (draw(&huge), draw(&scaled));
        // Rasterized counts the clipped fan's pieces.
        assert!(stats.non_finite == 0 && stats.rasterized > 0, "{backend:?}: {stats:?}");
        assert!(target.ids.as_ref().unwrap().contains(&0), "{backend:?}: nothing drawn");
        assert_eq!(target.ids, reference.ids, "{backend:?}");
        assert_eq!(target.depth, reference.depth, "{backend:?}");
    }
}

/// The 3D pipeline covers exactly the samples the window-space path covers, given the same
/// triangles in clip space with `w = 1` (target sides powers of two, vertices on the 1/256
/// grid: the viewport maps them back exactly). Pixel-sized and sub-pixel triangles, at 1x, 4x
/// and 8x, with and without culling, on the reference backend and on the tiled one binned and
/// banded, for a small mesh and for one over 2^20 vertices (shaded per batch, corners in a
/// window). The pipeline's front end drops triangles that cover no sample from their corners
/// alone, before setup; the window path's setup is separate code, so a rejection too many
/// shows as a missing id here (the two backends share the front end).
#[test]
fn pipeline_covers_the_samples_window_triangles_cover() {
    use trirast::render::{Backend, RenderOptions, Schedule};
    use trirast::sample::SampleCount;
    use trirast::{CullMode, DepthTest, Vertex};
    let (w, h) = (64u32, 32u32);
    let mut rng = SmallRng::seed_from_u64(31);
    let snap = |v: f32| (v * 256.0).round() / 256.0;
    let window: Vec<[[f32; 2]; 3]> = (0..12_000)
        .map(|_| {
            let c =
                [rng.random_range(-2.0..w as f32 + 2.0), rng.random_range(-2.0..h as f32 + 2.0)];
            let size = if rng.random_bool(0.7) { 0.3 } else { 1.5 };
            std::array::from_fn(|_| {
                let jitter = [rng.random_range(-size..size), rng.random_range(-size..size)];
                [snap(c[0] + jitter[0]), snap(c[1] + jitter[1])]
            })
        })
        .collect();
    let triangles: Vec<[Vertex; 3]> =
        window.iter().map(|t| t.map(|[x, y]| Vertex::new(x, y, 0.5, [255; 4]))).collect();
    let clip = |[x, y]: [f32; 2]| {
        Vec4::new(x / (w as f32 / 2.0) - 1.0, 1.0 - y / (h as f32 / 2.0), 0.5, 1.0)
    };
    let small: Vec<Vec4> = window.iter().flat_map(|t| t.map(clip)).collect();
    // Past 2^20 vertices the pipeline shades per batch; the padding is never referenced.
    let mut large = small.clone();
    large.resize((1 << 20) + 1000, Vec4::new(0.0, 0.0, 0.5, 1.0));
    let indices: Vec<[u32; 3]> =
        (0..window.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    // Back faces are clockwise on the image (the viewport's y flip keeps windings).
    let culls = [(FaceCull::None, CullMode::None), (FaceCull::Back, CullMode::Clockwise)];
    let runs = [
        (Backend::Reference, Schedule::Auto),
        (Backend::Tiled, Schedule::Binned),
        (Backend::Tiled, Schedule::Banded),
    ];
    for samples in [SampleCount::X1, SampleCount::X4, SampleCount::X8] {
        for (face_cull, cull) in culls {
            let mut want = Target::multisampled(w, h, samples).unwrap().with_ids();
            let options =
                RenderOptions::default().with_depth_test(DepthTest::Always).with_cull(cull);
            trirast::draw(&mut want, &triangles, &options).unwrap();
            let want = want.ids.unwrap();
            let written = want.iter().filter(|&&i| i >= 0).count();
            assert!(written > want.len() / 3, "{samples:?} {cull:?}: a sparse test");
            for (vertices, mesh) in [(&small, "small"), (&large, "large")] {
                for (backend, schedule) in runs {
                    let mut target = Target::multisampled(w, h, samples).unwrap().with_ids();
                    let vs = |v: &Vec4| (*v, ());
                    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
                    Pipeline::default()
                        .with_cull(face_cull)
                        .with_depth_test(DepthTest::Always)
                        .with_backend(backend)
                        .with_schedule(schedule)
                        .draw(&mut target, &vs, &fs, vertices, &indices)
                        .unwrap();
                    let got = target.ids.unwrap();
                    let differ = got.iter().zip(&want).filter(|(a, b)| a != b).count();
                    let what =
                        format!("{samples:?}, {cull:?}, {mesh} mesh, {backend:?} {schedule:?}");
                    assert_eq!(differ, 0, "{what}: samples differ");
                }
            }
        }
    }
}

/// A target buffer replaced by one of another length (they are public fields) is an error
/// from both draw calls and every backend, where drawing had indexed past it; one of the
/// right length is drawn into as before.
#[test]
fn replaced_target_buffers_of_another_length_are_errors() {
    use trirast::render::{Backend, RenderOptions};
    use trirast::{Error, Vertex};
    let fresh = || Target::new(16, 16).unwrap().with_ids().with_overdraw().with_normals();
    type Break = fn(&mut Target);
    let breaks: [(&str, Break); 6] = [
        ("colour", |t| t.color.truncate(10)),
        ("depth", |t| t.depth.push(1.0)),
        ("id", |t| t.ids = Some(Vec::new())),
        ("overdraw", |t| t.overdraw = Some(vec![0; 16 * 16 * 4])),
        ("normal", |t| t.normals = Some(Vec::new())),
        ("none", |_| {}),
    ];
    let v = |x: f32, y: f32| Vertex::new(x, y, 0.5, [255; 4]);
    let triangles = [[v(0.0, 0.0), v(16.0, 0.0), v(0.0, 16.0)]];
    let vs = |v: &Vec4| (*v, ());
    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
    let corners = [Vec4::new(-1.0, -1.0, 0.5, 1.0), Vec4::new(1.0, -1.0, 0.5, 1.0), Vec4::Y];
    for (buffer, break_it) in breaks {
        for backend in [Backend::Reference, Backend::Tiled] {
            let mut target = fresh();
            break_it(&mut target);
            let options = RenderOptions::default().with_backend(backend);
            let drawn = trirast::draw(&mut target, &triangles, &options);
            let piped = Pipeline::default().with_backend(backend).draw(
                &mut target,
                &vs,
                &fs,
                &corners,
                &[[0, 1, 2]],
            );
            for result in [drawn.map(|_| ()), piped.map(|_| ())] {
                match (buffer, result) {
                    ("none", result) => result.unwrap(),
                    (_, Err(Error::TargetBuffer { buffer: b, .. })) => assert_eq!(b, buffer),
                    (_, other) => panic!("{buffer}: {other:?}"),
                }
            }
        }
    }
}

/// A floor mesh (`y = -1`) whose shared edges cross the eye plane, the near plane, the far
/// plane and the guard band, of cells from centimetres to a hundred kilometres: its visible
/// part is covered exactly once, as one unclipped plane would be. Each shared edge is
/// clipped from both its triangles, so the new vertices on it must be the same bits on
/// both sides, or the mesh would leak or double-cover along it.
#[test]
fn a_mesh_clipped_on_every_plane_stays_watertight() {
    let xs = [-1e5, -300.0, -7.0, -1.3, -0.01, 0.9, 11.0, 500.0, 1e5];
    let zs = [5.0, 2.0, 0.3, 0.0, -0.05, -0.7, -3.0, -40.0, -99.9, -900.0, -1e5];
    let at = |i: usize, j: usize| Vec3::new(xs[i], -1.0, zs[j]);
    let mut tris = Vec::new();
    for i in 0..xs.len() - 1 {
        for j in 0..zs.len() - 1 {
            let [a, b, c, d] = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            // Diagonals alternating, so vertices meet four or eight triangles.
            if (i + j) % 2 == 0 {
                tris.extend([[a, b, c], [a, c, d]]);
            } else {
                tris.extend([[a, b, d], [b, c, d]]);
            }
        }
    }
    // Whether the ray through a pixel centre meets the floor in the view volume: the floor
    // reaches past the far plane and the sides of the view, so only depth bounds it.
    let floor_visible = |cam: &Camera, px, py| {
        let plane = [Vec3::new(0.0, -1.0, 0.0), Vec3::X - Vec3::Y, Vec3::NEG_Y + Vec3::NEG_Z];
        let Some((_, _, hit)) = ray_hit(cam, plane, px, py) else { return Some(false) };
        let depth = -hit.z;
        let (near, far) = (f64::from(cam.near), f64::from(cam.far));
        let margin = 2e-3;
        if depth < near * (1.0 - margin) || depth > far * (1.0 + margin) {
            Some(false)
        } else if depth > near * (1.0 + margin) && depth < far * (1.0 - margin) {
            Some(true)
        } else {
            None
        }
    };
    let vertices: Vec<Vec3> = tris.iter().flatten().copied().collect();
    let indices: Vec<[u32; 3]> =
        (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    for near in [0.05, 0.5] {
        let cam = camera(near);
        let vp = cam.view_projection(W as f32 / H as f32);
        for backend in [Backend::Reference, Backend::Tiled] {
            let mut target = Target::new(W, H).unwrap().with_overdraw();
            let vs = |v: &Vec3| (vp * v.extend(1.0), ());
            let fs = |_: &Fragment<()>| Some(Vec4::ONE);
            Pipeline::default()
                .with_cull(FaceCull::None)
                .with_backend(backend)
                .draw(&mut target, &vs, &fs, &vertices, &indices)
                .unwrap();
            let overdraw = target.overdraw.unwrap();
            let (mut inside, mut outside) = (0, 0);
            for py in 0..H {
                for px in 0..W {
                    let got = overdraw[(py * W + px) as usize];
                    assert!(got <= 1, "pixel ({px}, {py}) covered {got} times, {backend:?}");
                    match floor_visible(&cam, px, py) {
                        Some(true) => {
                            assert_eq!(got, 1, "({px}, {py}) left open, {backend:?}, near {near}");
                            inside += 1;
                        }
                        Some(false) => {
                            assert_eq!(got, 0, "({px}, {py}) drawn, {backend:?}, near {near}");
                            outside += 1;
                        }
                        None => {}
                    }
                }
            }
            // The floor fills the lower part of the view up to the horizon.
            assert!(
                inside > (W * H / 3) as usize && outside > (W * H / 4) as usize,
                "{inside} {outside}"
            );
        }
    }
}
