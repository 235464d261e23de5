//! Built-in window-space scenes: the lectures' demonstrations and the default picture.
//!
//! Scenes scale with the target so that any `--size` shows the whole scene.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::error::{Error, try_reserve};
use crate::setup::Vertex;
use crate::shade::Shading;

/// A list of window-space triangles and the shading it is meant to be seen with.
#[derive(Clone, Debug)]
pub struct Scene {
    /// Triangles, drawn in order.
    pub triangles: Vec<[Vertex; 3]>,
    /// Suggested shading.
    pub shading: Shading,
}

/// The lectures' demonstrations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Demo {
    /// A few flat-shaded triangles sharing edges.
    Flat,
    /// Gouraud-shaded triangles.
    Smooth,
    /// A soup of random triangles at random depths.
    Soup,
}

/// Builds a demonstration scene for a `width x height` target.
#[must_use]
pub fn demo(which: Demo, width: u32, height: u32) -> Scene {
    match which {
        Demo::Flat => flat(width, height),
        Demo::Smooth => smooth(width, height),
        Demo::Soup => soup(width, height, 2000, 1),
    }
}

fn scaled(width: u32, height: u32) -> impl Fn(f32, f32, f32, [u8; 4]) -> Vertex {
    let (w, h) = (width as f32, height as f32);
    move |x, y, z, c| Vertex::new(x * w, y * h, z, c)
}

fn flat(width: u32, height: u32) -> Scene {
    let v = scaled(width, height);
    let palette = [
        [230, 57, 70, 255],
        [241, 250, 238, 255],
        [168, 218, 220, 255],
        [69, 123, 157, 255],
        [29, 53, 87, 255],
        [244, 162, 97, 255],
    ];
    // A strip of triangles over a shared row of vertices, then two overlapping ones.
    let top: Vec<(f32, f32)> = (0..4).map(|i| (0.1 + 0.27 * i as f32, 0.12)).collect();
    let bottom: Vec<(f32, f32)> = (0..4).map(|i| (0.05 + 0.27 * i as f32, 0.5)).collect();
    let mut triangles = Vec::new();
    for i in 0..3 {
        let c0 = palette[(2 * i) % palette.len()];
        let c1 = palette[(2 * i + 1) % palette.len()];
        triangles.push([
            v(top[i].0, top[i].1, 0.5, c0),
            v(top[i + 1].0, top[i + 1].1, 0.5, c0),
            v(bottom[i].0, bottom[i].1, 0.5, c0),
        ]);
        triangles.push([
            v(top[i + 1].0, top[i + 1].1, 0.5, c1),
            v(bottom[i + 1].0, bottom[i + 1].1, 0.5, c1),
            v(bottom[i].0, bottom[i].1, 0.5, c1),
        ]);
    }
    triangles.push([
        v(0.1, 0.6, 0.3, palette[5]),
        v(0.6, 0.95, 0.3, palette[5]),
        v(0.2, 0.95, 0.3, palette[5]),
    ]);
    triangles.push([
        v(0.3, 0.55, 0.6, palette[2]),
        v(0.95, 0.7, 0.2, palette[2]),
        v(0.5, 0.98, 0.6, palette[2]),
    ]);
    Scene { triangles, shading: Shading::Flat }
}

fn smooth(width: u32, height: u32) -> Scene {
    let v = scaled(width, height);
    let (r, g, b) = ([255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]);
    let (k, w) = ([0, 0, 0, 255], [255, 255, 255, 255]);
    let triangles = vec![
        [v(0.5, 0.05, 0.5, r), v(0.95, 0.85, 0.5, g), v(0.05, 0.85, 0.5, b)],
        [v(0.05, 0.9, 0.4, w), v(0.45, 0.55, 0.4, k), v(0.45, 0.98, 0.4, r)],
        [v(0.55, 0.55, 0.4, k), v(0.95, 0.9, 0.4, w), v(0.55, 0.98, 0.4, b)],
    ];
    Scene { triangles, shading: Shading::Smooth }
}

/// `count` random triangles (a few pixels to a fifth of the image across) with random colours
/// and depths, from a fixed `seed`; none on an image with a side of 0 (nowhere to put them).
#[must_use]
pub fn soup(width: u32, height: u32, count: usize, seed: u64) -> Scene {
    if width == 0 || height == 0 {
        return Scene { triangles: Vec::new(), shading: Shading::Smooth };
    }
    let mut rng = SmallRng::seed_from_u64(seed);
    let (w, h) = (width as f32, height as f32);
    let size = 0.2 * w.min(h);
    let triangles = (0..count)
        .map(|_| {
            let (cx, cy) = (rng.random_range(0.0..w), rng.random_range(0.0..h));
            let s = size * rng.random_range(0.05f32..1.0).powi(2);
            std::array::from_fn(|_| {
                let color = [rng.random(), rng.random(), rng.random(), 255];
                Vertex::new(
                    cx + rng.random_range(-s..s),
                    cy + rng.random_range(-s..s),
                    rng.random_range(0.0..1.0),
                    color,
                )
            })
        })
        .collect();
    Scene { triangles, shading: Shading::Smooth }
}

/// The picture `trirast render` draws when given no file: a Gouraud colour wheel made of a
/// triangle fan, pierced by two triangles that intersect it in depth.
#[must_use]
pub fn default_scene(width: u32, height: u32) -> Scene {
    let v = scaled(width, height);
    let aspect = width as f32 / height as f32;
    let (cx, cy, r) = (0.5, 0.5, 0.42);
    let slices = 24;
    let hue = |t: f32| -> [u8; 4] {
        let channel = |offset: f32| {
            let a = std::f32::consts::TAU * (t + offset);
            (127.5 + 127.5 * a.cos()) as u8
        };
        [channel(0.0), channel(-1.0 / 3.0), channel(-2.0 / 3.0), 255]
    };
    let mut triangles = Vec::new();
    for i in 0..slices {
        let point = |k: usize| {
            let a = std::f32::consts::TAU * k as f32 / slices as f32;
            (cx + r * a.cos() / aspect.max(1.0), cy + r * a.sin() * aspect.min(1.0))
        };
        let (p, q) = (point(i), point(i + 1));
        triangles.push([
            v(cx, cy, 0.5, [255, 255, 255, 255]),
            v(p.0, p.1, 0.5, hue(i as f32 / slices as f32)),
            v(q.0, q.1, 0.5, hue((i + 1) as f32 / slices as f32)),
        ]);
    }
    let dark = [20, 24, 40, 255];
    let light = [235, 235, 245, 255];
    triangles.push([v(0.08, 0.15, 0.2, light), v(0.7, 0.35, 0.8, dark), v(0.2, 0.6, 0.2, light)]);
    triangles.push([v(0.92, 0.85, 0.2, dark), v(0.3, 0.65, 0.8, light), v(0.8, 0.4, 0.2, dark)]);
    Scene { triangles, shading: Shading::Smooth }
}

/// The 3D model `trirast render` draws when given no file: a trefoil knot tube, its colour
/// running through the hues along the knot, with normals and counter-clockwise outward faces.
#[must_use]
pub fn default_model() -> crate::mesh::Mesh {
    use glam::Vec3;
    let (segments, sides) = (300usize, 28usize);
    let curve = |t: f32| {
        Vec3::new(
            t.sin() + 2.0 * (2.0 * t).sin(),
            t.cos() - 2.0 * (2.0 * t).cos(),
            -(3.0 * t).sin(),
        )
    };
    let tau = std::f32::consts::TAU;
    let mut mesh = crate::mesh::Mesh::default();
    let (mut normals, mut colors) = (Vec::new(), Vec::new());
    for i in 0..segments {
        let t = tau * i as f32 / segments as f32;
        let dt = tau / segments as f32 * 0.5;
        let (p, tangent) = (curve(t), (curve(t + dt) - curve(t - dt)).normalize());
        let side = tangent.cross(Vec3::Z).normalize_or(Vec3::X);
        let up = side.cross(tangent);
        let hue = |offset: f32| 0.5 + 0.5 * (tau * (t / tau * 2.0 + offset)).cos();
        let color = [hue(0.0), hue(-1.0 / 3.0), hue(-2.0 / 3.0), 1.0];
        for j in 0..sides {
            let a = tau * j as f32 / sides as f32;
            let n = side * a.cos() + up * a.sin();
            mesh.positions.push((p + n * 0.45).to_array());
            normals.push(n.to_array());
            colors.push(color);
        }
    }
    let index = |i: usize, j: usize| ((i % segments) * sides + j % sides) as u32;
    for i in 0..segments {
        for j in 0..sides {
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
    // Choose the winding that makes faces counter-clockwise seen from outside.
    let [a, b, c] = mesh.triangles[0].map(|k| Vec3::from(mesh.positions[k as usize]));
    if (b - a).cross(c - a).dot(Vec3::from(normals[mesh.triangles[0][0] as usize])) < 0.0 {
        for t in &mut mesh.triangles {
            t.swap(1, 2);
        }
    }
    mesh.polygon_count = mesh.triangles.len() / 2;
    mesh.normals = Some(normals);
    mesh.colors = Some(colors);
    mesh
}

/// A UV sphere with about `triangles` triangles (at most 2^31, so that its vertex and
/// triangle counts, computed in `u32`, cannot wrap), counter-clockwise outside.
///
/// Errors: [`Error::OutOfMemory`] when its arrays cannot be allocated (`triangles` is the
/// caller's to choose: `trirast bench dense --dense-triangles`).
pub fn sphere_mesh(triangles: usize) -> Result<crate::mesh::Mesh, Error> {
    let triangles = triangles.min(1 << 31);
    let stacks = ((triangles as f64 / 4.0).sqrt().round() as u32).max(2);
    let slices = ((triangles as f64 / (2.0 * f64::from(stacks))).round() as u32).max(3);
    let mut mesh = crate::mesh::Mesh::default();
    let what = format!("a sphere of {triangles} triangles");
    try_reserve(&mut mesh.positions, ((stacks + 1) * (slices + 1)) as usize, &what)?;
    for j in 0..=stacks {
        let theta = std::f32::consts::PI * j as f32 / stacks as f32;
        for i in 0..=slices {
            let phi = std::f32::consts::TAU * i as f32 / slices as f32;
            mesh.positions.push([theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()]);
        }
    }
    let row = slices + 1;
    try_reserve(&mut mesh.triangles, 2 * (stacks * slices) as usize, &what)?;
    for j in 0..stacks {
        for i in 0..slices {
            let (a, b) = (j * row + i, (j + 1) * row + i);
            mesh.triangles.push([a, b, b + 1]);
            mesh.triangles.push([a, b + 1, a + 1]);
        }
    }
    mesh.polygon_count = mesh.triangles.len();
    Ok(mesh)
}
