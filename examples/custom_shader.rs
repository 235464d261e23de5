//! Drawing your own data with your own shaders, without the command line.
//!
//! Renders the Stanford bunny from `../shared/models` when it is there (a generated sphere
//! otherwise) with a vertex shader that passes world-space normals and a fragment shader that
//! shows them as colours, then writes `custom_shader.png` and the id buffer as `.npy`.
//!
//! ```sh
//! cargo run --release --example custom_shader
//! ```

use glam::{Vec3, Vec4};
use trirast::camera::{Camera, Projection, bounding_sphere};
use trirast::model::vertex_normals;
use trirast::pipeline::{Fragment, Pipeline};
use trirast::{Error, Target};

/// What each vertex hands to the fragment shader; any `Varyings` type works (tuples, arrays,
/// glam vectors, or your own struct implementing the trait).
type Normal = Vec3;

fn main() -> Result<(), Error> {
    let path = std::path::Path::new("../shared/models/stanford-bunny.obj");
    let mesh = if path.exists() {
        println!("reading {}", path.display());
        trirast::mesh::load(path)?
    } else {
        println!("{} not found: drawing a generated sphere", path.display());
        trirast::scene::sphere_mesh(4096)?
    };
    let normals =
        mesh.normals.clone().unwrap_or_else(|| vertex_normals(&mesh.positions, &mesh.triangles));

    let (width, height) = (800, 600);
    let (centre, radius) = bounding_sphere(&mesh.positions);
    let aspect = width as f32 / height as f32;
    let projection = Projection::Perspective { fov_y: 35f32.to_radians() };
    let camera = Camera::framing_sphere(centre, radius, 0.5, 0.3, aspect, projection);
    let view_proj = camera.view_projection(aspect);

    // Vertex shader: a vertex index in, clip position and a varying out.
    let vertex_shader = |&i: &u32| -> (Vec4, Normal) {
        let p = Vec3::from(mesh.positions[i as usize]);
        (view_proj * p.extend(1.0), Vec3::from(normals[i as usize]))
    };
    // Fragment shader: interpolated (perspective-correct) varyings in, linear RGBA out.
    let fragment_shader = |f: &Fragment<Normal>| -> Option<Vec4> {
        let n = f.varyings.normalize_or_zero();
        Some((n * 0.5 + Vec3::splat(0.5)).powf(2.2).extend(1.0))
    };

    let mut target = Target::new(width, height)?.with_ids();
    let vertices: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let stats = Pipeline::default().draw(
        &mut target,
        &vertex_shader,
        &fragment_shader,
        &vertices,
        &mesh.triangles,
    )?;
    println!("{} triangles drawn, {} fragments", stats.rasterized, stats.fragments);
    trirast::output::write_png("custom_shader.png".as_ref(), &target)?;
    let ids = target.ids.as_ref().expect("requested above");
    trirast::output::write_npy("custom_shader_ids.npy".as_ref(), ids, width, height)?;
    println!("wrote custom_shader.png and custom_shader_ids.npy");
    Ok(())
}
