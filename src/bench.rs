//! Built-in benchmark scenes and the timing loop behind `trirast bench`.
//!
//! Every scene is generated in code (the bunny reads the Stanford bunny when [`bunny_path`]
//! finds it and otherwise generates a mesh of the same triangle count, and says which).
//! Timings are render time only: scene generation and loading are excluded.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{Vec3, Vec4};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::camera::{self, Camera, Projection};
use crate::error::Error;
use crate::mesh::Mesh;
use crate::model::{self, Lighting, MaterialTextures, ModelOptions};
use crate::pipeline::{FaceCull, Fragment, IndexBuffer, Pipeline};
use crate::render::{self, DrawStats, RenderOptions, Schedule};
use crate::sample::SampleCount;
use crate::scene;
use crate::setup::{CullMode, Vertex};
use crate::shade::Shading;
use crate::target::Target;

/// The benchmark scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BenchScene {
    /// The Stanford bunny (69,451 triangles), perspective, 1920x1080, Gouraud + depth.
    Bunny,
    /// 1,000,000 random triangles of about 10 px area, 1920x1080, Gouraud + depth.
    Soup,
    /// A 1,000,000-triangle indexed grid mesh covering 1920x1080, random vertex colours
    /// and depths, drawn by the 3D pipeline with [`crate::pipeline::VertexColor`].
    Grid,
    /// 256 large random triangles, 3840x2160, Gouraud + depth.
    Fill,
    /// A 100,000,000-triangle mesh, 1920x1080, depth + flat colour.
    Dense,
}

impl BenchScene {
    /// All scenes, in the order of the issue's table.
    pub const ALL: [Self; 5] = [Self::Bunny, Self::Soup, Self::Grid, Self::Fill, Self::Dense];

    /// The scene's name on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Bunny => "bunny",
            Self::Soup => "soup",
            Self::Grid => "grid",
            Self::Fill => "fill",
            Self::Dense => "dense",
        }
    }
}

/// What one scene measured.
#[derive(Clone, Debug)]
pub struct BenchResult {
    /// Scene name.
    pub scene: &'static str,
    /// Where the scene came from (e.g. which bunny).
    pub source: String,
    /// Triangles submitted per frame.
    pub triangles: usize,
    /// Target pixels.
    pub pixels: usize,
    /// Covered samples per frame.
    pub fragments: u64,
    /// Worker threads.
    pub threads: usize,
    /// Samples per pixel.
    pub msaa: usize,
    /// Median frame time, ms.
    pub median_ms: f64,
    /// Fastest frame time, ms.
    pub min_ms: f64,
    /// How the tiled backend spread the frames over threads (what [`Schedule::Auto`] chose,
    /// or `TRIRAST_SCHEDULE` forced).
    pub schedule: Option<Schedule>,
    /// The process's peak resident memory while the scene was built and drawn, in bytes:
    /// the scene's own data, the target's buffers and the renderer's (the issue's memory
    /// bound for the dense mesh is stated in these terms). Memory the allocator kept from
    /// scenes run before in the same process counts too. `None` where the system does not
    /// tell (it is read from Linux's `/proc`).
    pub peak_memory: Option<u64>,
}

impl BenchResult {
    /// Millions of triangles per second at the median.
    #[must_use]
    pub fn mtri_per_s(&self) -> f64 {
        self.triangles as f64 / self.median_ms / 1e3
    }

    /// Billions of fragments per second at the median.
    #[must_use]
    pub fn gfrag_per_s(&self) -> f64 {
        self.fragments as f64 / self.median_ms / 1e6
    }
}

/// A scene ready to draw repeatedly.
enum Prepared {
    Window {
        triangles: Vec<[Vertex; 3]>,
        options: RenderOptions,
    },
    Model {
        mesh: Box<Mesh>,
        camera: Camera,
        options: ModelOptions,
    },
    Grid {
        positions: Vec<Vec4>,
        colors: Vec<Vec3>,
        /// The vertex shader's inputs: the vertex indices (built once, not in every frame).
        vertices: Vec<u32>,
        /// The triangles with their index ranges, found once (as a GPU driver keeps a static
        /// index buffer's, which llvmpipe's figures had too), not in every frame.
        triangles: IndexBuffer,
    },
    Dense {
        positions: Vec<[f32; 3]>,
        /// As the grid's.
        triangles: IndexBuffer,
        view_proj: glam::Mat4,
    },
}

/// The Stanford bunny the bunny scene and the splat benchmark read, where one is found:
/// `stanford-bunny.obj` in the directory `TRIRAST_MODELS` names, or in a `shared/models`
/// directory beside the working directory (`../shared/models`) or beside a directory above
/// the executable (a build of this repository's, where `shared` lies beside it), so that
/// the scenes do not change with the directory the command is run from.
#[must_use]
pub fn bunny_path() -> Option<PathBuf> {
    const NAME: &str = "stanford-bunny.obj";
    if let Some(dir) = std::env::var_os("TRIRAST_MODELS") {
        return Some(Path::new(&dir).join(NAME)).filter(|p| p.is_file());
    }
    let beside_cwd = std::env::current_dir().ok().map(|d| d.join("../shared/models"));
    let exe = std::env::current_exe().ok();
    let above_exe = exe.iter().flat_map(|e| e.ancestors().skip(1)).map(|a| a.join("shared/models"));
    beside_cwd.into_iter().chain(above_exe).map(|d| d.join(NAME)).find(|p| p.is_file())
}

/// Size of the dense scene, overridable for quick runs.
pub const DENSE_TRIANGLES: usize = 100_000_000;

fn prepare(
    scene: BenchScene,
    dense_triangles: usize,
) -> Result<(Prepared, u32, u32, String), Error> {
    let mut rng = SmallRng::seed_from_u64(2024);
    Ok(match scene {
        BenchScene::Bunny => {
            let (mut mesh, source) = if let Some(path) = bunny_path() {
                (crate::mesh::load(&path)?, format!("{}", path.display()))
            } else {
                // The count it has, which is near the bunny's, not the bunny's (69,432).
                let sphere = scene::sphere_mesh(69_451)?;
                let count = sphere.triangles.len();
                (sphere, format!("generated sphere of {count} triangles (bunny not found)"))
            };
            // Normals computed once, as `trirast render` does, not in every timed frame.
            model::with_vertex_normals(&mut mesh);
            let (centre, radius) = camera::bounding_sphere(&mesh.positions);
            let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
            let camera = Camera::framing_sphere(centre, radius, 0.5, 0.35, 16.0 / 9.0, projection);
            let options = ModelOptions::default().with_lighting(Lighting::Gouraud);
            (Prepared::Model { mesh: Box::new(mesh), camera, options }, 1920, 1080, source)
        }
        BenchScene::Soup => {
            let triangles = (0..1_000_000)
                .map(|_| {
                    let c = [rng.random_range(0.0..1920.0f32), rng.random_range(0.0..1080.0f32)];
                    let angle = rng.random_range(0.0..std::f32::consts::TAU);
                    let base = rng.random_range(3.0..7.0f32);
                    let height = 20.0 / base;
                    let skew = rng.random_range(-0.5..0.5f32) * base;
                    let local = [[-base / 2.0, 0.0], [base / 2.0, 0.0], [skew, height]];
                    local.map(|[x, y]| {
                        let (s, co) = angle.sin_cos();
                        Vertex::new(
                            c[0] + x * co - y * s,
                            c[1] + x * s + y * co,
                            rng.random_range(0.0..1.0),
                            [rng.random(), rng.random(), rng.random(), 255],
                        )
                    })
                })
                .collect();
            let options = RenderOptions::default().with_shading(Shading::Smooth);
            (Prepared::Window { triangles, options }, 1920, 1080, "generated".into())
        }
        BenchScene::Fill => {
            let triangles = (0..256)
                .map(|_| {
                    let v: [Vertex; 3] = std::array::from_fn(|_| {
                        Vertex::new(
                            rng.random_range(0.0..3840.0),
                            rng.random_range(0.0..2160.0),
                            rng.random_range(0.0..1.0),
                            [rng.random(), rng.random(), rng.random(), 255],
                        )
                    });
                    // Shrunk about the centroid so the frame has about the issue's 113.5 M
                    // fragments (random corners alone give 160 M).
                    let (cx, cy) =
                        ((v[0].x + v[1].x + v[2].x) / 3.0, (v[0].y + v[1].y + v[2].y) / 3.0);
                    v.map(|p| Vertex { x: cx + (p.x - cx) * 0.84, y: cy + (p.y - cy) * 0.84, ..p })
                })
                .collect();
            let options = RenderOptions::default().with_shading(Shading::Smooth);
            (Prepared::Window { triangles, options }, 3840, 2160, "generated".into())
        }
        BenchScene::Grid => {
            let (positions, colors, triangles) = grid(1000, 500, &mut rng);
            let vertices = (0..positions.len() as u32).collect();
            let triangles = IndexBuffer::new(triangles);
            let grid = Prepared::Grid { positions, colors, vertices, triangles };
            (grid, 1920, 1080, "generated".into())
        }
        BenchScene::Dense => {
            // Depth + flat colour with the leanest shaders: positions in, no varyings, one
            // colour per triangle from its index. Nothing per vertex is stored but the mesh.
            let mesh = scene::sphere_mesh(dense_triangles)?;
            let (centre, radius) = camera::bounding_sphere(&mesh.positions);
            let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
            let camera = Camera::framing_sphere(centre, radius, 0.3, 0.2, 16.0 / 9.0, projection);
            let source = format!("generated sphere of {} triangles", mesh.triangles.len());
            let view_proj = camera.view_projection(16.0 / 9.0);
            let Mesh { positions, triangles, .. } = mesh;
            let triangles = IndexBuffer::new(triangles);
            (Prepared::Dense { positions, triangles, view_proj }, 1920, 1080, source)
        }
    })
}

/// An indexed grid of `nx x ny` quads covering NDC, with random vertex colours and depths.
fn grid(nx: u32, ny: u32, rng: &mut SmallRng) -> (Vec<Vec4>, Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let x = -1.0 + 2.0 * i as f32 / nx as f32;
            let y = -1.0 + 2.0 * j as f32 / ny as f32;
            positions.push(Vec4::new(x, y, rng.random_range(0.1..0.9), 1.0));
            colors.push(Vec3::new(rng.random(), rng.random(), rng.random()));
        }
    }
    let row = nx + 1;
    let mut triangles = Vec::with_capacity(2 * (nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            let a = j * row + i;
            triangles.push([a, a + 1, a + row + 1]);
            triangles.push([a, a + row + 1, a + row]);
        }
    }
    (positions, colors, triangles)
}

fn draw(
    prepared: &Prepared,
    target: &mut Target,
    textures: &MaterialTextures,
) -> Result<DrawStats, Error> {
    match prepared {
        Prepared::Window { triangles, options } => render::draw(target, triangles, options),
        Prepared::Model { mesh, camera, options } => {
            model::render_mesh(target, mesh, camera, options, textures)
        }
        Prepared::Dense { positions, triangles, view_proj } => {
            let vs = |p: &[f32; 3]| (*view_proj * Vec3::from(*p).extend(1.0), ());
            let fs = |f: &Fragment<()>| {
                let h = f.primitive.wrapping_mul(0x9E37_79B9);
                let c = |shift: u32| ((h >> shift) & 0xFF) as f32 / 255.0;
                Some(Vec4::new(c(0), c(8), c(16), 1.0))
            };
            let pipeline = Pipeline::default().with_cull(DENSE_CULL);
            pipeline.draw_indexed(target, &vs, &fs, positions, triangles)
        }
        Prepared::Grid { positions, colors, vertices, triangles } => {
            let vs = |&i: &u32| (positions[i as usize], colors[i as usize]);
            let fs = crate::pipeline::VertexColor;
            let pipeline = Pipeline::default().with_cull(GRID_CULL);
            pipeline.draw_indexed(target, &vs, &fs, vertices, triangles)
        }
    }
}

/// Runs `frame` once to warm up (caches, the thread pool, the target's kept buffers) and then
/// `frames` more times, timing each: returns what the last frame returned (its counts) and
/// the times in ms, fastest first (empty when `frames` is 0). The one timing loop of
/// `trirast bench`, `splat-bench` and `render --frames`.
pub fn time_frames<T>(
    frames: usize,
    mut frame: impl FnMut() -> Result<T, Error>,
) -> Result<(T, Vec<f64>), Error> {
    let mut stats = frame()?;
    let mut times = Vec::new();
    for _ in 0..frames {
        let start = Instant::now();
        stats = frame()?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok((stats, times))
}

/// Renders `scene` `frames` times (0 is taken as 1) after one warm-up frame and reports the
/// timings.
pub fn run(
    scene: BenchScene,
    frames: usize,
    threads: usize,
    msaa: SampleCount,
    dense_triangles: usize,
) -> Result<BenchResult, Error> {
    peak_memory::reset();
    let (prepared, width, height, source) = prepare(scene, dense_triangles)?;
    let textures = match &prepared {
        Prepared::Model { mesh, .. } => MaterialTextures::load(mesh),
        _ => MaterialTextures::default(),
    };
    let mut target = Target::multisampled(width, height, msaa)?;
    let (stats, times) = time_frames(frames.max(1), || {
        target.clear([0, 0, 0, 255]);
        draw(&prepared, &mut target, &textures)
    })?;
    Ok(BenchResult {
        scene: scene.name(),
        source,
        triangles: stats.submitted,
        pixels: width as usize * height as usize,
        fragments: stats.fragments,
        threads,
        msaa: msaa.count(),
        median_ms: times[times.len() / 2],
        min_ms: times[0],
        schedule: target.last_schedule(),
        peak_memory: peak_memory::read(),
    })
}

/// The process's peak resident set, from Linux's `/proc/self`: reset before a scene, read
/// after it. Elsewhere (or where `/proc` is not readable) there is no figure.
mod peak_memory {
    /// Lowers the recorded peak to the current resident set (`clear_refs` value 5). A
    /// failure leaves the peak of the whole run so far, which still bounds the scene's.
    pub(super) fn reset() {
        let _ = std::fs::write("/proc/self/clear_refs", "5");
    }

    /// The peak resident set since the last [`reset`], in bytes (`VmHWM`).
    pub(super) fn read() -> Option<u64> {
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let line = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?;
        let kb: u64 = line.trim().strip_suffix("kB")?.trim().parse().ok()?;
        Some(kb * 1024)
    }
}

/// The grid culls nothing: every one of its triangles is drawn.
const GRID_CULL: FaceCull = FaceCull::None;
/// The dense sphere is closed: its back faces are culled.
const DENSE_CULL: FaceCull = FaceCull::Back;

/// A cull mode as `export` names it.
fn cull_name(cull: FaceCull) -> &'static str {
    match cull {
        FaceCull::None => "none",
        FaceCull::Back => "back",
        FaceCull::Front => "front",
    }
}

/// Writes `scene`'s input into `dir` as NumPy arrays beside a JSON file describing the scene
/// (`NAME.json`, returned), so that another renderer can draw the same triangles:
/// `tools/llvmpipe/bench.py` times Mesa's llvmpipe on them. Arrays are `NAME_WHAT.npy`:
/// - `window` (soup, fill): positions (3n, 3) in pixels and depth, colours (3n, 4) `u8`, three
///   rows per triangle;
/// - `lit` (bunny): positions (v, 3), normals (v, 3), indices (n, 3) `u32`, with the
///   [`ModelView`](model::ModelView) matrices (column-major), light and colour in the JSON;
/// - `grid`: clip-space positions (v, 4), linear colours (v, 3), indices;
/// - `dense`: positions (v, 3), indices, the view-projection matrix in the JSON.
pub fn export(
    scene: BenchScene,
    dense_triangles: usize,
    dir: &Path,
) -> Result<std::path::PathBuf, Error> {
    use crate::output::write_npy_shaped;
    let (prepared, width, height, source) = prepare(scene, dense_triangles)?;
    let name = scene.name();
    let array = |what: &str| dir.join(format!("{name}_{what}.npy"));
    let rows = |n: usize| n as u64;
    let matrix = |m: &glam::Mat4| format!("{:?}", m.to_cols_array());
    let vec3 = |v: Vec3| format!("{:?}", v.to_array());
    let extra = match &prepared {
        Prepared::Window { triangles, options } => {
            let corners = triangles.as_flattened();
            let positions: Vec<f32> = corners.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
            let colors: Vec<u8> = corners.iter().flat_map(|v| v.color).collect();
            write_npy_shaped(&array("positions"), &positions, &[rows(corners.len()), 3])?;
            write_npy_shaped(&array("colors"), &colors, &[rows(corners.len()), 4])?;
            let cull = match options.cull {
                CullMode::None => "none",
                CullMode::Clockwise => "cw",
                CullMode::CounterClockwise => "ccw",
            };
            format!("\"kind\":\"window\",\"cull\":\"{cull}\"")
        }
        Prepared::Model { mesh, camera, options } => {
            let view = model::ModelView::new(camera, width as f32 / height as f32);
            let normals = mesh.normals.as_deref().expect("normals computed by `prepare`");
            let v = rows(mesh.positions.len());
            write_npy_shaped(&array("positions"), mesh.positions.as_flattened(), &[v, 3])?;
            write_npy_shaped(&array("normals"), normals.as_flattened(), &[v, 3])?;
            let indices = mesh.triangles.as_flattened();
            write_npy_shaped(&array("indices"), indices, &[rows(mesh.triangles.len()), 3])?;
            let light = &options.light;
            format!(
                "\"kind\":\"lit\",\"cull\":\"{}\",\"origin\":{},\"view\":{},\"view_proj\":{},\
                 \"albedo\":{:?},\"light\":{{\"direction\":{},\"diffuse\":{:?},\"ambient\":{:?},\
                 \"specular\":{:?},\"shininess\":{:?}}}",
                cull_name(options.cull),
                vec3(view.origin),
                matrix(&view.view),
                matrix(&view.view_proj),
                model::base_albedo(mesh).to_array(),
                vec3(light.direction),
                light.diffuse,
                light.ambient,
                light.specular,
                light.shininess,
            )
        }
        Prepared::Grid { positions, colors, triangles, .. } => {
            let (v, triangles) = (rows(positions.len()), triangles.triangles());
            let flat: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
            write_npy_shaped(&array("positions"), &flat, &[v, 4])?;
            let flat: Vec<f32> = colors.iter().flat_map(|c| c.to_array()).collect();
            write_npy_shaped(&array("colors"), &flat, &[v, 3])?;
            write_npy_shaped(
                &array("indices"),
                triangles.as_flattened(),
                &[rows(triangles.len()), 3],
            )?;
            format!("\"kind\":\"grid\",\"cull\":\"{}\"", cull_name(GRID_CULL))
        }
        Prepared::Dense { positions, triangles, view_proj } => {
            let triangles = triangles.triangles();
            write_npy_shaped(
                &array("positions"),
                positions.as_flattened(),
                &[rows(positions.len()), 3],
            )?;
            write_npy_shaped(
                &array("indices"),
                triangles.as_flattened(),
                &[rows(triangles.len()), 3],
            )?;
            let cull = cull_name(DENSE_CULL);
            format!("\"kind\":\"dense\",\"cull\":\"{cull}\",\"view_proj\":{}", matrix(view_proj))
        }
    };
    let json = dir.join(format!("{name}.json"));
    let text = format!(
        "{{\"scene\":\"{name}\",\"source\":{},\"width\":{width},\"height\":{height},{extra}}}\n",
        json_string(&source)
    );
    std::fs::write(&json, text).map_err(|e| Error::io(&json, e))?;
    Ok(json)
}

/// `s` as a JSON string, quotes included.
#[must_use]
pub fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            // Every control character, not only those JSON requires: the CLI escapes any left
            // in what it prints, which would not be JSON.
            c if c.is_control() => out.push_str(&format!("\\u{:04x}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The point counts of the lectures' splatting figures.
pub const SPLAT_COUNTS: [usize; 3] = [130_712, 1_017_149, 14_835_967];

/// What the splat benchmark measured for one point count.
#[derive(Clone, Debug)]
pub struct SplatBenchResult {
    /// Points sampled.
    pub points: usize,
    /// Hierarchy nodes.
    pub nodes: usize,
    /// Time to build the hierarchy, ms.
    pub build_ms: f64,
    /// Size of the `.tsplat` encoding, bytes.
    pub bytes: usize,
    /// Median frame time at 1920x1080, ms (decoded tree, 1-pixel threshold).
    pub median_ms: f64,
    /// Fastest frame, ms.
    pub min_ms: f64,
    /// Splats drawn per frame.
    pub splats: usize,
    /// Where the points came from.
    pub source: String,
}

/// Samples `points` points from the bunny (or a generated sphere), builds, encodes, decodes and
/// renders the hierarchy `frames` times (0 is taken as 1) at 1920x1080. No points is an error.
pub fn run_splats(points: usize, frames: usize) -> Result<SplatBenchResult, Error> {
    use crate::splat::render::{self as splat_render, SplatOptions};
    use crate::splat::{SplatTree, cloud, format};
    let (mesh, source) = if let Some(path) = bunny_path() {
        (crate::mesh::load(&path)?, format!("{}", path.display()))
    } else {
        (scene::sphere_mesh(69_451)?, "generated sphere (bunny not found)".to_string())
    };
    let cloud = cloud::sample_mesh(&mesh, &MaterialTextures::load(&mesh), points, 7)?;
    let start = Instant::now();
    let tree = SplatTree::build(&cloud)?;
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let bytes = format::encode(&tree)?;
    let tree = format::decode(&bytes).map_err(|e| {
        e.into_error("the encoded hierarchy", |e| Error::Usage(format!("decoding: {e}")))
    })?;
    let Some(root) = tree.nodes.first() else {
        return Err(Error::Usage(format!("no points to time: {points} sampled")));
    };
    let (centre, radius) = (Vec3::from(root.centre), root.radius);
    let projection = Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y };
    let camera = Camera::framing_sphere(centre, radius, 0.5, 0.35, 16.0 / 9.0, projection);
    let mut target = Target::new(1920, 1080)?;
    let (splats, times) = time_frames(frames.max(1), || {
        target.clear([0, 0, 0, 255]);
        Ok(splat_render::render(&mut target, &tree, &camera, &SplatOptions::default()).drawn)
    })?;
    Ok(SplatBenchResult {
        points: cloud.positions.len(),
        nodes: tree.nodes.len(),
        build_ms,
        bytes: bytes.len(),
        median_ms: times[times.len() / 2],
        min_ms: times[0],
        splats,
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quotes, backslashes and every control character (C0, DEL and C1) come out as JSON
    /// escapes, so the string holds no control character for the CLI to escape again.
    #[test]
    fn json_strings_escape_every_control_character() {
        let s = json_string("a\"b\\c\u{1b}[31m\u{7f}\u{85}é\n");
        assert_eq!(s, r#""a\"b\\c\u001b[31m\u007f\u0085é\u000a""#);
        assert!(!s.chars().any(char::is_control), "{s}");
    }
}
