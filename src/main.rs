//! The `trirast` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use trirast::camera::{self, Camera, Projection};
use trirast::mesh::{Format, Mesh};
use trirast::model::{self, Lighting, MaterialTextures, ModelOptions};
use trirast::pipeline::FaceCull;
use trirast::render::Schedule;
use trirast::sample::SampleCount;

/// mimalloc rather than glibc's malloc, which hands every large block back to the system
/// when it is freed, so each frame faulted in (and zeroed) its buffers again page by page
/// (splat frames: 250 -> 182 ms with mimalloc).
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;
use trirast::scene::{self, Demo};
use trirast::texture::{Filter, Wrap};
use trirast::{Algorithm, CullMode, DepthTest, Error, RenderOptions, Shading, Target};

/// `println!` that cannot panic. What a reader that closed the pipe early (`trirast info m.obj
/// | head -1`) did not want is dropped, as other command-line tools drop it; any other failure
/// to write (a full disk) is said once and makes the command fail once its work (a picture to
/// write) is done. `println!` panicked on both, leaving the picture unwritten.
macro_rules! say {
    ($($arg:tt)*) => {
        say(format_args!($($arg)*))
    };
}

/// `eprintln!` that cannot panic: messages that cannot be written (standard error closed or
/// full) are dropped, so that they do not stop the work they report on.
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        // Escaped like every message: a file name's control characters had reached the
        // terminal through `wrote ...`.
        let line = format!($($arg)*);
        let _ = writeln!(std::io::stderr(), "{}", printable(&line));
    }};
}

/// `text` with its control characters (but line breaks and tabs) escaped: messages quote
/// what a file holds, and an escape sequence in a malformed line had reached the terminal.
fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    let control = |c: char| c.is_control() && c != '\n' && c != '\t';
    if !text.chars().any(control) {
        return text.into();
    }
    let escaped = |c: char| if control(c) { c.escape_default().to_string() } else { c.into() };
    text.chars().map(escaped).collect::<String>().into()
}

/// [`say!`]'s line to standard output.
fn say(line: std::fmt::Arguments) {
    use std::io::Write as _;
    // Escaped as `note!` escapes (`info`'s `file:` line printed a name's control characters).
    let line = line.to_string();
    if let Err(e) = writeln!(std::io::stdout(), "{}", printable(&line))
        && e.kind() != std::io::ErrorKind::BrokenPipe
        && !STDOUT_FAILED.swap(true, std::sync::atomic::Ordering::Relaxed)
    {
        note!("trirast: error: writing to standard output: {e}");
    }
}

/// Set when standard output could not be written (see [`say!`]): the command then fails.
static STDOUT_FAILED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[derive(Parser)]
#[command(name = "trirast", version, about = "An exact software triangle rasterizer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Every command takes negative numbers as values (`--fov -30`, `--background -1,0,0`), so
/// that the value's own check explains what is wrong; clap had read them as unknown options.
#[derive(Subcommand)]
enum Command {
    /// Render a mesh (.obj, .ply, .stl), or the built-in default scene when no file is given.
    #[command(allow_negative_numbers = true)]
    Render(Box<RenderArgs>),
    /// Print a mesh's vertex, triangle and polygon counts, bounds and attributes.
    #[command(allow_negative_numbers = true)]
    Info {
        /// Mesh file.
        file: PathBuf,
    },
    /// Time the built-in benchmark scenes (bunny, soup, grid, fill, dense).
    #[command(allow_negative_numbers = true)]
    Bench {
        /// Scenes to run (default: all five).
        #[arg(value_enum)]
        scenes: Vec<SceneArg>,
        /// Worker threads, 1 to 1024 (default: all cores).
        #[arg(long, value_parser = parse_threads)]
        threads: Option<usize>,
        /// Timed frames per scene, after one warm-up frame (1 to 1,000,000).
        #[arg(long, default_value_t = 10, value_parser = parse_frames)]
        frames: usize,
        /// Samples per pixel; with 4 or 8, each scene is also timed at 1x for comparison.
        #[arg(long, value_parser = parse_msaa, default_value = "1")]
        msaa: SampleCount,
        /// Triangles in the dense scene (1 to 1,000,000,000; a sphere has at least 12).
        #[arg(long, default_value_t = trirast::bench::DENSE_TRIANGLES, value_parser = parse_dense)]
        dense_triangles: usize,
        /// Print one JSON object per scene instead of a table.
        #[arg(long)]
        json: bool,
        /// Write each scene's triangles (NumPy arrays and a JSON file) into this existing
        /// directory instead of timing it, for drawing them with another renderer
        /// (tools/llvmpipe/bench.py times Mesa's llvmpipe on them).
        #[arg(long, value_name = "DIR", conflicts_with_all = ["json", "threads", "frames", "msaa"])]
        export: Option<PathBuf>,
    },
    /// Time the splat hierarchy: build, bytes per point, ms per frame at 1920x1080, for the
    /// lectures' 130,712 / 1,017,149 / 14,835,967 points sampled from the bunny.
    #[command(allow_negative_numbers = true)]
    SplatBench {
        /// Point counts, each 1 to 2^30 (default: the three above).
        #[arg(long, value_delimiter = ',', value_parser = parse_points)]
        points: Vec<usize>,
        /// Worker threads, 1 to 1024 (default: all cores).
        #[arg(long, value_parser = parse_threads)]
        threads: Option<usize>,
        /// Timed frames per count (1 to 1,000,000).
        #[arg(long, default_value_t = 10, value_parser = parse_frames)]
        frames: usize,
    },
    /// Sample points from a mesh (area-weighted, with normals and colours) into a PLY cloud.
    #[command(allow_negative_numbers = true)]
    Sample {
        /// Mesh file (.obj, .ply, .stl).
        file: PathBuf,
        /// Number of points (1 to 2^30).
        #[arg(long, default_value_t = 1_000_000, value_parser = parse_points)]
        points: usize,
        /// Output point cloud (.ply, binary).
        #[arg(short, long, default_value = "cloud.ply")]
        output: PathBuf,
        /// Random seed, 0 to 2^64 - 1 (the same seed gives the same points).
        #[arg(long, default_value_t = 1, value_parser = parse_seed)]
        seed: u64,
    },
    /// Build the splat hierarchy of a point cloud and write it as a compact .tsplat file.
    #[command(allow_negative_numbers = true)]
    Pack {
        /// Point cloud (.ply).
        file: PathBuf,
        /// Output file.
        #[arg(short, long, default_value = "cloud.tsplat")]
        output: PathBuf,
    },
    /// Render a point cloud (.ply, or a packed .tsplat) as splats.
    #[command(allow_negative_numbers = true)]
    Splat(Box<SplatArgs>),
    /// Draw one of the lectures' 2D demonstrations.
    #[command(allow_negative_numbers = true)]
    Demo {
        /// Which demonstration.
        #[arg(value_enum, default_value_t = DemoArg::Smooth)]
        which: DemoArg,
        /// Output PNG.
        #[arg(short, long, default_value = "demo.png")]
        output: PathBuf,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "512x512", value_parser = parse_size, allow_hyphen_values = true)]
        size: (u32, u32),
        /// Coverage algorithm.
        #[arg(long, value_enum, default_value_t = AlgorithmArg::Edge)]
        algorithm: AlgorithmArg,
    },
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Mesh file. Without one, a built-in scene is drawn.
    file: Option<PathBuf>,
    /// `perspective` and `orthographic` view the model through a camera; `window` takes x, y
    /// as pixels (y down) and z as depth.
    #[arg(long, value_enum, default_value_t = ProjectionArg::Perspective)]
    projection: ProjectionArg,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "800x600", value_parser = parse_size, allow_hyphen_values = true)]
    size: (u32, u32),
    /// Output colour PNG (with --turntable, frames are named OUTPUT_000.png, ...).
    #[arg(short, long, default_value = "trirast.png")]
    output: PathBuf,
    /// PNG compression: fast (fdeflate, the default), balanced (zlib 6: files a quarter to
    /// a half smaller, encoding several times slower than drawing), best (zlib 9).
    #[arg(long, value_enum, default_value_t = PngCompressionArg::Fast)]
    png_compression: PngCompressionArg,
    /// Also write the depth buffer as a float32 .npy of shape (H, W).
    #[arg(long, value_name = "FILE")]
    depth: Option<PathBuf>,
    /// Also write triangle ids (int32 .npy, -1 where empty).
    #[arg(long, value_name = "FILE")]
    ids: Option<PathBuf>,
    /// Also write fragments per pixel, counted before the depth test (uint32 .npy).
    #[arg(long, value_name = "FILE")]
    overdraw: Option<PathBuf>,
    /// Also write world-space unit normals (float32 .npy of shape (H, W, 3); 3D only).
    #[arg(long, value_name = "FILE")]
    normals: Option<PathBuf>,
    /// Shading. Window projection: flat, smooth (default), perspective. 3D: unlit, flat,
    /// gouraud (= smooth), phong (default).
    #[arg(long, value_enum)]
    shading: Option<ShadingArg>,
    /// Coverage algorithm of the window projection (default edge); both give identical
    /// pixels. The 3D pipeline chooses per triangle.
    #[arg(long, value_enum)]
    algorithm: Option<AlgorithmArg>,
    /// Culling. Window: none (default), cw, ccw (on-screen winding). 3D: back (default),
    /// front, none; counter-clockwise faces are front faces.
    #[arg(long, value_enum)]
    cull: Option<CullArg>,
    /// Depth comparison; `always` disables the test, so the last triangle drawn wins.
    #[arg(long, value_enum, default_value_t = DepthTestArg::Less)]
    depth_test: DepthTestArg,
    /// Orbit the camera: AZIMUTH,ELEVATION in degrees around the model's bounding sphere.
    #[arg(long, value_name = "AZ,EL", value_parser = parse_vec2, allow_hyphen_values = true)]
    #[arg(conflicts_with = "eye")]
    view: Option<[f32; 2]>,
    /// Explicit eye position X,Y,Z (overrides the automatic framing; needs --target).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "target")]
    eye: Option<[f32; 3]>,
    /// Point the camera looks at, X,Y,Z.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, requires = "eye")]
    target: Option<[f32; 3]>,
    /// Camera up direction X,Y,Z, with --eye (default 0,1,0); not along the view direction.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    #[arg(requires_all = ["eye", "target"])]
    up: Option<[f32; 3]>,
    /// Vertical field of view in degrees (perspective), 1 to 170 [default: 35].
    #[arg(long, value_parser = parse_fov)]
    fov: Option<f32>,
    /// Texture filtering [default: bilinear].
    #[arg(long, value_enum)]
    filter: Option<FilterArg>,
    /// Texture wrapping [default: repeat].
    #[arg(long, value_enum)]
    wrap: Option<WrapArg>,
    /// Background colour as R,G,B (0-255).
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    background: Option<[u8; 3]>,
    /// A diffuse texture (PNG or JPEG) for a mesh with texture coordinates, replacing its
    /// materials.
    #[arg(long, value_name = "IMAGE")]
    texture: Option<PathBuf>,
    /// Samples per pixel: 1, 4 or 8 (D3D standard patterns). Default: 1 for window
    /// projection, 4 for models.
    #[arg(long, value_parser = parse_msaa)]
    msaa: Option<SampleCount>,
    /// Write --ids and --depth with every sample, shape (H, W, S), instead of sample 0.
    #[arg(long)]
    per_sample: bool,
    /// Time the render: draw N frames after a warm-up one and print median / min ms per frame
    /// and throughput (loading excluded). The image written is the last frame. N is 1 to
    /// 1,000,000.
    #[arg(long, value_name = "N", value_parser = parse_frames)]
    frames: Option<usize>,
    /// Render N frames orbiting the model (3D only), N 1 to 1,000,000. Every output is
    /// numbered: OUTPUT_000.png, ..., and --depth d.npy as d_000.npy, ... (likewise --ids,
    /// --overdraw and --normals).
    #[arg(long, value_name = "N", value_parser = parse_turntable)]
    #[arg(conflicts_with_all = ["frames", "eye"])]
    turntable: Option<u32>,
}

#[derive(clap::Args)]
struct SplatArgs {
    /// Point cloud: .ply (the hierarchy is built on load) or .tsplat.
    file: PathBuf,
    /// Output colour PNG.
    #[arg(short, long, default_value = "splat.png")]
    output: PathBuf,
    /// PNG compression: fast (fdeflate, the default), balanced (zlib 6: files a quarter to
    /// a half smaller, encoding several times slower than drawing), best (zlib 9).
    #[arg(long, value_enum, default_value_t = PngCompressionArg::Fast)]
    png_compression: PngCompressionArg,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "800x600", value_parser = parse_size, allow_hyphen_values = true)]
    size: (u32, u32),
    /// Stop refining at nodes whose points spread over less than this many pixels on screen
    /// (0 draws every point; a finite number, 0 or more).
    #[arg(long, default_value_t = 1.0, value_parser = parse_threshold)]
    threshold: f32,
    /// Time budget: draw coarse-to-fine levels while the next is expected to fit; the image
    /// is the finest level completed (a finite number over 0).
    #[arg(long, value_name = "MS", value_parser = parse_budget)]
    budget_ms: Option<f64>,
    /// Also write the depth buffer (float32 .npy, shape (H, W)).
    #[arg(long, value_name = "FILE")]
    depth: Option<PathBuf>,
    /// Orbit: AZIMUTH,ELEVATION in degrees.
    #[arg(long, value_name = "AZ,EL", value_parser = parse_vec2, allow_hyphen_values = true)]
    view: Option<[f32; 2]>,
    /// Splat footprint.
    #[arg(long, value_enum, default_value_t = ShapeArg::Round)]
    shape: ShapeArg,
    /// Background colour as R,G,B (0-255).
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    background: Option<[u8; 3]>,
}

#[derive(Clone, Copy, ValueEnum)]
enum ShapeArg {
    Round,
    Square,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ProjectionArg {
    Perspective,
    Orthographic,
    Window,
}

#[derive(Clone, Copy, ValueEnum)]
enum SceneArg {
    Bunny,
    Soup,
    Grid,
    Fill,
    Dense,
}

#[derive(Clone, Copy, ValueEnum)]
enum DemoArg {
    Flat,
    Smooth,
    Soup,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ShadingArg {
    Flat,
    Smooth,
    Perspective,
    Unlit,
    Gouraud,
    Phong,
}

#[derive(Clone, Copy, ValueEnum)]
enum AlgorithmArg {
    Edge,
    Scanline,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum CullArg {
    None,
    Cw,
    Ccw,
    Back,
    Front,
}

#[derive(Clone, Copy, ValueEnum)]
enum DepthTestArg {
    Less,
    LessEqual,
    Always,
}

#[derive(Clone, Copy, ValueEnum)]
enum PngCompressionArg {
    Fast,
    Balanced,
    Best,
}

impl From<PngCompressionArg> for trirast::output::PngCompression {
    fn from(c: PngCompressionArg) -> Self {
        match c {
            PngCompressionArg::Fast => Self::Fast,
            PngCompressionArg::Balanced => Self::Balanced,
            PngCompressionArg::Best => Self::Best,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum FilterArg {
    Nearest,
    Bilinear,
}

#[derive(Clone, Copy, ValueEnum)]
enum WrapArg {
    Repeat,
    Clamp,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, e.g. 640x480, found `{s}`"))?;
    let side = |t: &str| {
        let message = || format!("expected WIDTHxHEIGHT in whole pixels, found `{s}`");
        t.trim().parse::<u32>().map_err(|_| message())
    };
    Ok((side(w)?, side(h)?))
}

/// The most worker threads `--threads` and `RAYON_NUM_THREADS` may ask for. Far more than
/// the work splits into usefully, and few enough to start: a hundred thousand threads cannot
/// get their stacks, and a thread that fails to start aborts the process.
const MAX_THREADS: usize = 1024;

fn parse_threads(s: &str) -> Result<usize, String> {
    parse_count(s, "--threads", MAX_THREADS)
}

/// The most frames a timing run may ask for: each one's time is kept for the median, and a
/// count far past what a benchmark needs is a typo, not a plan (a billion frames asked for
/// gigabytes of timings up front, and aborted when they could not be had).
const MAX_FRAMES: usize = 1_000_000;

fn parse_frames(s: &str) -> Result<usize, String> {
    parse_count(s, "--frames", MAX_FRAMES)
}

fn parse_turntable(s: &str) -> Result<u32, String> {
    // MAX_FRAMES fits in u32.
    parse_count(s, "--turntable", MAX_FRAMES).map(|n| n as u32)
}

/// The most points `sample` and `splat-bench` take: 2^30 points are about 40 GB of cloud and
/// hierarchy. Counts far past it are typos, whose allocations aborted the process (capacity
/// overflow) instead of reporting an error.
const MAX_POINTS: usize = 1 << 30;

fn parse_points(s: &str) -> Result<usize, String> {
    parse_count(s, "--points", MAX_POINTS)
}

/// The largest dense scene: a billion triangles are 12 GB of indices and 6 GB of positions,
/// past which generating the mesh aborted the process when memory ran out.
const MAX_DENSE_TRIANGLES: usize = 1_000_000_000;

fn parse_dense(s: &str) -> Result<usize, String> {
    parse_count(s, "--dense-triangles", MAX_DENSE_TRIANGLES)
}

/// `n what`, `what` taking an `s` unless `n` is 1 ("1 points" had been printed).
fn counted(n: usize, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}

/// `--seed`: a whole number that fits 64 bits (the parser's own message, "invalid digit
/// found in string" for `-1`, named neither the option nor the range).
fn parse_seed(s: &str) -> Result<u64, String> {
    s.parse()
        .map_err(|_| format!("--seed takes a whole number from 0 to {}, found `{s}`", u64::MAX))
}

/// A whole number from 1 to `max` for option `name`.
fn parse_count(s: &str, name: &str, max: usize) -> Result<usize, String> {
    s.parse::<usize>()
        .ok()
        .filter(|n| (1..=max).contains(n))
        .ok_or_else(|| format!("{name} takes 1 to {max}, found `{s}`"))
}

/// The thread count `RAYON_NUM_THREADS` asks the global pool for, checked before the pool
/// starts, whatever the command: rayon reads it (0 or not a number means all cores), but a
/// count too large to start aborts the process.
fn check_rayon_threads() -> Result<(), Error> {
    // The second is rayon's older name for the first, still read.
    for name in ["RAYON_NUM_THREADS", "RAYON_RS_NUM_CPUS"] {
        let Some(value) = std::env::var_os(name) else { continue };
        // Rayon takes a value it cannot read (and empty) as unset: every core. Other programs
        // share the variable, so that is a warning, not an error.
        let text = value.to_str().unwrap_or("?");
        match text.parse::<usize>() {
            _ if text.is_empty() => {}
            Ok(n) if n > MAX_THREADS => {
                return Err(usage(format!(
                    "{name}={n}: at most {MAX_THREADS} worker threads (0 or unset: all cores)"
                )));
            }
            Ok(_) => {}
            Err(_) => note!(
                "trirast: warning: {name}={}: not a number of threads; using all cores",
                value.to_string_lossy()
            ),
        }
    }
    Ok(())
}

/// The comparison switches `TRIRAST_SIMD` and `TRIRAST_SCHEDULE`, checked as the commands
/// that draw start: a value the library does not know (it ignored them in silence, so a
/// comparison could measure the default against itself) is an error, and a SIMD level this
/// CPU lacks a warning naming the level used instead.
fn check_switches() -> Result<(), Error> {
    use trirast::simd::SimdLevel;
    if let Some(value) = std::env::var_os("TRIRAST_SIMD") {
        // Empty: as unset, the best level.
        let name = value.to_str().unwrap_or("?");
        let named =
            if name.is_empty() { Some(SimdLevel::detect()) } else { SimdLevel::from_name(name) };
        let Some(level) = named else {
            let value = value.to_string_lossy();
            return Err(usage(format!("TRIRAST_SIMD={value}: scalar, avx2 or avx512")));
        };
        if !level.is_available() {
            note!(
                "trirast: warning: TRIRAST_SIMD={}: this CPU lacks it; using {}",
                value.to_string_lossy(),
                SimdLevel::detect().name()
            );
        }
    }
    if let Some(value) = std::env::var_os("TRIRAST_SCHEDULE")
        && !value.to_str().is_some_and(|n| n.is_empty() || Schedule::from_name(n).is_some())
    {
        let value = value.to_string_lossy();
        return Err(usage(format!("TRIRAST_SCHEDULE={value}: auto, binned or banded")));
    }
    Ok(())
}

fn parse_msaa(s: &str) -> Result<SampleCount, String> {
    s.parse::<u32>()
        .ok()
        .and_then(SampleCount::from_count)
        .ok_or_else(|| format!("--msaa takes 1, 4 or 8, found `{s}`"))
}

fn parse_floats<const N: usize>(s: &str) -> Result<[f32; N], String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != N {
        return Err(format!("expected {N} comma-separated numbers, found `{s}`"));
    }
    let mut out = [0.0; N];
    for (o, p) in out.iter_mut().zip(parts) {
        *o = p.trim().parse::<f32>().map_err(|_| format!("`{p}` is not a number"))?;
        if !o.is_finite() {
            return Err(format!("`{p}` is not a finite number"));
        }
    }
    Ok(out)
}

/// A field of view in degrees, 1 to 170: NaN drew nothing and other values were clamped
/// without a word.
fn parse_fov(s: &str) -> Result<f32, String> {
    s.trim()
        .parse::<f32>()
        .ok()
        .filter(|f| (1.0..=170.0).contains(f))
        .ok_or_else(|| format!("--fov takes 1 to 170 degrees, found `{s}`"))
}

/// A splat threshold in pixels: NaN and negative values were taken as 0 (every point), and
/// infinity drew a single splat, without a word.
fn parse_threshold(s: &str) -> Result<f32, String> {
    s.trim().parse::<f32>().ok().filter(|t| t.is_finite() && *t >= 0.0).ok_or_else(|| {
        format!("--threshold takes a finite number of pixels, 0 or more, found `{s}`")
    })
}

/// A time budget in ms: NaN meant no budget, and 0 or less the coarsest level, silently.
fn parse_budget(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|b| b.is_finite() && *b > 0.0)
        .ok_or_else(|| format!("--budget-ms takes a finite number of ms over 0, found `{s}`"))
}

fn parse_vec2(s: &str) -> Result<[f32; 2], String> {
    parse_floats::<2>(s)
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    parse_floats::<3>(s)
}

fn parse_rgb(s: &str) -> Result<[u8; 3], String> {
    let f = parse_floats::<3>(s)?;
    // Whole numbers only: `0.5,0.5,0.5` (a colour in 0-1) became black in silence.
    if f.iter().any(|&c| !(0.0..=255.0).contains(&c) || c.fract() != 0.0) {
        return Err(format!("colour components are whole numbers 0-255, found `{s}`"));
    }
    Ok(f.map(|c| c as u8))
}

impl From<AlgorithmArg> for Algorithm {
    fn from(a: AlgorithmArg) -> Self {
        match a {
            AlgorithmArg::Edge => Algorithm::EdgeFunctions,
            AlgorithmArg::Scanline => Algorithm::Scanline,
        }
    }
}

impl From<DepthTestArg> for DepthTest {
    fn from(d: DepthTestArg) -> Self {
        match d {
            DepthTestArg::Less => DepthTest::Less,
            DepthTestArg::LessEqual => DepthTest::LessEqual,
            DepthTestArg::Always => DepthTest::Always,
        }
    }
}

/// Refuses, before anything is allocated, a target whose buffers need more memory than is
/// `available` (see [`Error::MemoryUnavailable`]): colour and depth (8 bytes a sample),
/// `per_sample` and `per_pixel` bytes of the other buffers asked for, and 8 bytes a pixel for
/// the PNG (the resolved colour, and the compressed image the encoder holds beside it). Sizes
/// outside the supported range are left to [`Target`] to refuse.
fn check_target_memory(
    (width, height): (u32, u32),
    samples: SampleCount,
    per_sample: u128,
    per_pixel: u128,
    available: Option<u128>,
) -> Result<(), Error> {
    let sides = 1..=trirast::fixed::MAX_TARGET_SIZE;
    if !(sides.contains(&width) && sides.contains(&height)) {
        return Ok(());
    }
    let count = samples.count() as u128;
    let needed =
        u128::from(width) * u128::from(height) * (count * (8 + per_sample) + per_pixel + 8);
    let what = || format!("a {width}x{height} target with {count} sample(s) per pixel");
    within(what, needed, available)
}

/// The textures `mesh`'s materials name.
fn material_textures(mesh: &trirast::mesh::Mesh) -> impl Iterator<Item = &Path> {
    mesh.materials.iter().filter_map(|m| m.diffuse_texture.as_deref())
}

/// The files reading `mesh` read besides its own: its material libraries and their textures,
/// which no output may write over (an output named as an `.obj`'s `mtllib` had replaced it).
fn files_read(mesh: &trirast::mesh::Mesh) -> Vec<&Path> {
    let libraries = mesh.material_libraries.iter().map(PathBuf::as_path);
    libraries.chain(material_textures(mesh)).collect()
}

/// Refuses, before any is decoded, textures whose loading needs more memory than the system
/// can give ([`trirast::texture::LOAD_BYTES_PER_TEXEL`] a texel, each file once, as if all
/// loaded at once): four PNGs of 16384 x 4096 texels, 260 KB each, had grown past 4 GB and
/// aborted. Textures whose headers cannot be read are left to the loader to report.
fn check_texture_memory<'p>(paths: impl IntoIterator<Item = &'p Path>) -> Result<(), Error> {
    let mut files: Vec<&Path> = paths.into_iter().collect();
    files.sort_unstable();
    files.dedup();
    let needed: u128 =
        files.iter().filter_map(|&p| trirast::texture::Texture::load_bytes(p).ok()).sum();
    let what = || match files[..] {
        [one] => format!("loading the texture {}", one.display()),
        _ => format!("loading {} textures", files.len()),
    };
    check_memory(what, needed)
}

/// Refuses, before it starts, work that needs `needed` bytes more than the system can give
/// ([`memory_available`]): `sample --points 1073741824` had grown past 15 GB on a 24 GB
/// machine before it was stopped.
fn check_memory(what: impl FnOnce() -> String, needed: u128) -> Result<(), Error> {
    within(what, needed, memory_available())
}

/// [`Error::MemoryUnavailable`] naming `what` if `needed` bytes are more than `available`
/// (nothing is refused where the system does not say).
fn within(
    what: impl FnOnce() -> String,
    needed: u128,
    available: Option<u128>,
) -> Result<(), Error> {
    match available {
        Some(available) if needed > available => {
            Err(Error::MemoryUnavailable { what: what(), needed, available })
        }
        _ => Ok(()),
    }
}

/// Peak bytes a point of building a splat hierarchy takes beyond its cloud, rounded up from
/// what was measured (`trirast splat` of clouds of 1 and 2 million points: 192).
const BUILD_BYTES_PER_POINT: u128 = 200;

/// Peak bytes a point of writing a `.tsplat` file takes beyond its hierarchy, rounded up from
/// what was measured (`trirast pack`, 1 and 2 million points: 114).
const ENCODE_BYTES_PER_POINT: u128 = 120;

/// Peak bytes a triangle of `bench dense` takes (its sphere's vertices and indices), rounded
/// up from what was measured (10 and 40 million triangles: 17.5): a billion triangles had
/// grown past 4 GB unchecked.
const DENSE_BYTES_PER_TRIANGLE: u128 = 20;

/// Peak bytes a point of `splat-bench` takes (the sampled cloud, its hierarchy and the
/// build's scratch), rounded up from what was measured (1 and 4 million points: 287):
/// `--points 1073741824` had been stopped by the system's out-of-memory killer at 24 GB.
const SPLAT_BENCH_BYTES_PER_POINT: u128 = 300;

/// Bytes this process can still have without being stopped or pushing others out: Linux's
/// estimate of allocatable memory (`MemAvailable`, reclaimable caches included) plus free
/// swap, less where a control group above the process sets a lower limit, or the process's
/// address space limit (`ulimit -v`) leaves less room. `None` where the system does not say
/// (not Linux), and then nothing is refused up front.
fn memory_available() -> Option<u128> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let mut available = meminfo_available(&meminfo)?;
    for room in [cgroup_room(), address_space_room()].into_iter().flatten() {
        available = available.min(room);
    }
    Some(available)
}

/// The room the address space limit leaves: `Max address space` of `/proc/self/limits` less
/// `VmSize` of `/proc/self/status`; `None` where it is unlimited or cannot be read.
fn address_space_room() -> Option<u128> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    address_space_room_of(&limits, &status)
}

/// [`address_space_room`] of the two files' texts.
fn address_space_room_of(limits: &str, status: &str) -> Option<u128> {
    let soft = limits.lines().find_map(|l| l.strip_prefix("Max address space"))?;
    let limit: u128 = soft.split_whitespace().next()?.parse().ok()?;
    let size = status.lines().find_map(|l| l.strip_prefix("VmSize:"))?;
    let kib: u128 = size.trim().strip_suffix("kB")?.trim().parse().ok()?;
    Some(limit.saturating_sub(kib * 1024))
}

/// `MemAvailable` plus `SwapFree` of a `/proc/meminfo` text, in bytes.
fn meminfo_available(meminfo: &str) -> Option<u128> {
    let field = |name: &str| {
        meminfo.lines().find_map(|line| {
            let kib = line.strip_prefix(name)?.strip_prefix(':')?.trim().strip_suffix("kB")?;
            kib.trim().parse::<u128>().ok().map(|kib| kib * 1024)
        })
    };
    Some(field("MemAvailable")? + field("SwapFree").unwrap_or(0))
}

/// The value of `name` in a cgroup `memory.stat` text (`name value` lines).
fn memory_stat(stat: &str, name: &str) -> Option<u128> {
    stat.lines().find_map(|line| line.strip_prefix(name)?.strip_prefix(' ')?.trim().parse().ok())
}

/// The least room a memory control group above this process leaves it, from the process's
/// group up to the root, cgroup v2 or v1 (its `memory` controller, possibly mounted with
/// others); `None` where none sets a limit that can be read. A group's room is its limit
/// less its usage, the inactive file cache (which the kernel reclaims before it stops a
/// process) not counted as used.
fn cgroup_room() -> Option<u128> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    // v1: the line of the controllers that include `memory`, mounted under their names.
    let v1 = groups.lines().find_map(|line| {
        let (_, rest) = line.split_once(':')?;
        let (controllers, path) = rest.split_once(':')?;
        let root = format!("/sys/fs/cgroup/{controllers}");
        controllers.split(',').any(|c| c == "memory").then_some((path, root))
    });
    // v2: one line `0::/path`, `memory.max` reading "max" where no limit is set. v1: no
    // limit reads as a huge number.
    let (own, root, limit, usage, inactive) = match v1 {
        Some((own, root)) => {
            (own, root, "memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        }
        None => {
            let own = groups.lines().find_map(|line| line.strip_prefix("0::"))?;
            (own, "/sys/fs/cgroup".to_string(), "memory.max", "memory.current", "inactive_file")
        }
    };
    let root = PathBuf::from(root);
    let mut dir = root.join(own.trim_start_matches('/'));
    let read = |dir: &Path, file| std::fs::read_to_string(dir.join(file)).ok();
    let mut least: Option<u128> = None;
    loop {
        if let (Some(max), Some(current)) = (read(&dir, limit), read(&dir, usage))
            && let (Ok(max), Ok(current)) = (max.trim().parse::<u128>(), current.trim().parse())
        {
            let cache = read(&dir, "memory.stat").and_then(|s| memory_stat(&s, inactive));
            let used: u128 = current - cache.unwrap_or(0).min(current);
            let room = max.saturating_sub(used);
            least = Some(least.map_or(room, |l: u128| l.min(room)));
        }
        if !dir.pop() || !dir.starts_with(&root) {
            return least;
        }
    }
}

/// Warns where the framing's single-precision arithmetic cannot follow the model: squares of
/// distances overflow past about 1.8e19 (a cloud with one point at 1e20 drew nothing; a star
/// scaled by 1e20 framed as one flat wedge) and underflow below about 1e-19 (a model 1e-25
/// across was framed as a unit sphere, a dot too small to draw). `what` names a position.
fn warn_of_scale(positions: &[[f32; 3]], what: &str) {
    let finite = positions.iter().flatten().filter(|c| c.is_finite());
    let reach = finite.clone().fold(0.0f32, |m, c| m.max(c.abs()));
    if reach > 1e18 {
        note!(
            "trirast: warning: a {what} lies {reach:.1e} units along an axis; past about 1e19 \
             the view's single-precision arithmetic overflows and the picture may be wrong"
        );
        return;
    }
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in positions.iter().filter(|p| p.iter().all(|c| c.is_finite())) {
        for k in 0..3 {
            (lo[k], hi[k]) = (lo[k].min(p[k]), hi[k].max(p[k]));
        }
    }
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max);
    if extent > 0.0 && extent < 1e-18 {
        note!(
            "trirast: warning: the model spans {extent:.1e} units; below about 1e-19 the \
             view's single-precision arithmetic underflows and it may not be framed"
        );
    }
}

/// A mistake in what the command was given that clap cannot see and the library has no error
/// for: a value that does not fit the projection, an input with nothing to sample, a file's
/// triangle out of the window range (said with the file's name).
fn usage(message: String) -> Error {
    Error::Usage(message)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // The switches choose how triangles are drawn: a command that draws none runs whatever
    // they say (`info` of a model had failed on a mistyped level).
    let draws = !matches!(
        cli.command,
        Command::Info { .. } | Command::Pack { .. } | Command::Sample { .. }
    );
    let result = check_rayon_threads()
        .and_then(|()| if draws { check_switches() } else { Ok(()) })
        .and_then(|()| match cli.command {
            Command::Render(args) => render(&args),
            Command::Info { file } => info(&file),
            Command::Sample { file, points, output, seed } => sample(&file, points, &output, seed),
            Command::SplatBench { points, threads, frames } => {
                splat_bench(&points, threads, frames)
            }
            Command::Pack { file, output } => pack(&file, &output),
            Command::Splat(args) => splat(&args),
            Command::Bench { scenes, dense_triangles, export: Some(dir), .. } => {
                export(&scenes, dense_triangles, &dir)
            }
            Command::Bench {
                scenes,
                threads,
                frames,
                msaa,
                dense_triangles,
                json,
                export: None,
            } => bench(&scenes, threads, frames, msaa, dense_triangles, json),
            Command::Demo { which, output, size, algorithm } => {
                demo(which, &output, size, algorithm)
            }
        });
    match result {
        Ok(()) if STDOUT_FAILED.load(std::sync::atomic::Ordering::Relaxed) => ExitCode::FAILURE,
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            note!("trirast: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn render(args: &RenderArgs) -> Result<(), Error> {
    if args.per_sample && args.ids.is_none() && args.depth.is_none() {
        // It changes only those two files: alone it had been accepted and did nothing.
        return Err(usage("--per-sample shapes the --ids and --depth files: give one".into()));
    }
    let outputs = [
        ("--output", Some(args.output.as_path()), Written::Png),
        ("--depth", args.depth.as_deref(), Written::Npy),
        ("--ids", args.ids.as_deref(), Written::Npy),
        ("--overdraw", args.overdraw.as_deref(), Written::Npy),
        ("--normals", args.normals.as_deref(), Written::Npy),
    ];
    let inputs: Vec<&Path> = args.file.iter().chain(&args.texture).map(PathBuf::as_path).collect();
    check_outputs(&outputs, &inputs, args.turntable)?;
    let (width, height) = args.size;
    let window = args.projection == ProjectionArg::Window;
    let default_msaa = if window { SampleCount::X1 } else { SampleCount::X4 };
    let samples = args.msaa.unwrap_or(default_msaa);
    let per_sample = if args.ids.is_some() { 4 } else { 0 };
    let per_pixel =
        if args.overdraw.is_some() { 4 } else { 0 } + if args.normals.is_some() { 12 } else { 0 };
    check_target_memory(args.size, samples, per_sample, per_pixel, memory_available())?;
    let mut target = Target::multisampled(width, height, samples)?;
    if args.ids.is_some() {
        target = target.try_with_ids()?;
    }
    if args.overdraw.is_some() {
        target = target.try_with_overdraw()?;
    }
    if args.normals.is_some() {
        target = target.try_with_normals()?;
    }
    if window {
        render_window(args, &mut target)?;
        return write_outputs(args, &target, None);
    }
    if args.projection == ProjectionArg::Orthographic && args.fov.is_some() {
        return Err(usage("--fov is for the perspective projection".into()));
    }
    if args.algorithm.is_some() {
        return Err(usage(
            "--algorithm is for --projection window: the 3D pipeline chooses the coverage \
             algorithm per triangle (every one gives the same pixels)"
                .into(),
        ));
    }
    let mut mesh = match &args.file {
        Some(path) => reading(path, |report| trirast::mesh::load_reporting(path, report))?,
        None => scene::default_model(),
    };
    // A texture asked for by name that cannot be read is an error (naming it), not a warning
    // and a plain-colour image as for a material's.
    let mut texture = None;
    if let Some(path) = &args.texture {
        if mesh.texcoords.is_none() {
            note!("trirast: warning: the mesh has no texture coordinates; --texture ignored");
        } else {
            check_texture_memory([path.as_path()])?;
            texture = Some(trirast::texture::Texture::load(path)?);
            mesh.materials = vec![trirast::mesh::Material {
                name: "texture".into(),
                diffuse: [1.0; 3],
                diffuse_texture: Some(path.clone()),
                texture_statement: None,
            }];
            mesh.triangle_materials = Some(vec![0; mesh.triangles.len()]);
        }
    }
    // The materials' libraries and textures are inputs too, known once the mesh is read.
    check_not_inputs(&outputs, &files_read(&mesh), args.turntable)?;
    warn_about(&mesh);
    if mesh.positions.is_empty() {
        note!("trirast: warning: the file has no faces: nothing to draw");
    }
    // The camera's up with --eye and --target (Y, unless --up says otherwise).
    let up = Vec3::from(args.up.unwrap_or([0.0, 1.0, 0.0]));
    // The length of an --up of 1e38 overflowed, and it was called zero: such an up is scaled
    // by its largest component (others are left as given, so that their pictures keep their
    // bits).
    let up = if up.length().is_finite() { up } else { up / up.abs().max_element() };
    if let (Some(eye), Some(look)) = (args.eye, args.target) {
        if eye == look {
            return Err(usage("--eye and --target must differ".into()));
        }
        // The camera works in single precision: a view that overflows it (an --eye at 1e38)
        // was reported as an --up along the view.
        let view = Vec3::from(look) - Vec3::from(eye);
        if !view.is_finite() || !view.length().is_finite() {
            return Err(usage(
                "--eye and --target are too far apart for single precision (about 1.8e19 at \
                 most: the square of their distance must stay below 3.4e38)"
                    .into(),
            ));
        }
        // An up direction along the view (or zero) leaves the image's roll undefined; the
        // camera fell back to another up without a word.
        // Directions found at any scale: an --eye 1e-30 from the --target had made the view
        // NaN, which passed this test, and the camera then looked along -Z.
        let along = match (camera::direction(view), camera::direction(up)) {
            (Some(view), Some(up)) => up.cross(view).length() < 1e-3,
            _ => true,
        };
        if along {
            let which = if args.up.is_some() { "--up" } else { "the default --up 0,1,0" };
            return Err(usage(format!(
                "{which} is zero or along the view from --eye to --target: give another --up"
            )));
        }
    }
    model::with_vertex_normals(&mut mesh);
    let textures = match texture {
        Some(t) => MaterialTextures::from_loaded(vec![Some(t)]),
        None => {
            check_texture_memory(material_textures(&mesh))?;
            MaterialTextures::load(&mesh)
        }
    };
    print_warnings(&textures.warnings);
    let textured = mesh.texcoords.is_some()
        && (0..mesh.materials.len().max(1)).any(|k| textures.get(k).is_some());
    if !textured {
        // Accepted and ignored, they had said nothing.
        let given = [("--filter", args.filter.is_some()), ("--wrap", args.wrap.is_some())];
        for (option, _) in given.into_iter().filter(|&(_, given)| given) {
            note!("trirast: warning: {option} ignored: nothing is drawn with a texture");
        }
    }
    let options = model_options(args)?;
    let background = args.background.unwrap_or([38, 42, 52]);
    let clear = [background[0], background[1], background[2], 255];
    let (centre, radius) = camera::bounding_sphere(&mesh.positions);
    if args.eye.is_none() {
        warn_of_scale(&mesh.positions, "vertex");
    }
    let [az, el] = args.view.unwrap_or([30.0, 20.0]);
    let camera_at = |azimuth: f32| -> Camera {
        let projection = match args.projection {
            ProjectionArg::Orthographic => Projection::Orthographic { height: 2.0 * radius },
            _ => Projection::Perspective { fov_y: args.fov.unwrap_or(35.0).to_radians() },
        };
        let mut cam = Camera::framing_sphere(
            centre,
            radius,
            azimuth.to_radians(),
            el.to_radians(),
            width as f32 / height as f32,
            projection,
        );
        if let (Some(eye), Some(look)) = (args.eye, args.target) {
            let (eye, look) = (Vec3::from(eye), Vec3::from(look));
            let distance = eye.distance(centre);
            cam.eye = eye;
            cam.target = look;
            cam.up = up;
            cam.near = (distance - radius * 1.5).max(radius * 1e-3);
            cam.far = distance + radius * 1.5;
        }
        cam
    };
    // Refused in the model's terms: the camera's own values (an eye at infinity, near and far
    // planes the user never gave) had said nothing of what to change.
    if let Err(e) = camera_at(az).check() {
        let model =
            args.file.as_ref().map_or("the default model".into(), |f| f.display().to_string());
        let point = |p: Vec3| format!("[{:e}, {:e}, {:e}]", p.x, p.y, p.z);
        return Err(usage(match args.eye {
            Some(eye) => format!(
                "--eye {} is {:e} from the centre of {model}, whose bounding sphere's radius is \
                 {radius:e}: too far for single precision to separate the depths of its near \
                 and far sides; bring the eye closer ({e})",
                point(Vec3::from(eye)),
                Vec3::from(eye).distance(centre),
            ),
            None => format!(
                "{model} is too large to frame in single precision: its bounding sphere has \
                 radius {radius:e} about {} ({e})",
                point(centre)
            ),
        }));
    }
    match args.turntable {
        None => {
            let camera = camera_at(az);
            draw_timed(&mut target, args.frames, clear, |t| {
                model::render_mesh(t, &mesh, &camera, &options, &textures)
            })?;
            write_outputs(args, &target, None)
        }
        Some(frames) => {
            let bar = ProgressBar::new(u64::from(frames)).with_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} frames, {eta} left")
                    .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            for k in 0..frames {
                target.clear(clear);
                let azimuth = az + 360.0 * k as f32 / frames as f32;
                model::render_mesh(&mut target, &mesh, &camera_at(azimuth), &options, &textures)?;
                write_outputs(args, &target, Some(k))?;
                bar.inc(1);
            }
            bar.finish();
            // Named as the files are (the progress bar alone left them to be guessed).
            let last = frame_path(&args.output, frames - 1, frames);
            let first = frame_path(&args.output, 0, frames);
            if frames == 1 {
                note!("wrote {}", first.display());
            } else {
                note!("wrote {frames} frames, {} to {}", first.display(), last.display());
            }
            Ok(())
        }
    }
}

fn model_options(args: &RenderArgs) -> Result<ModelOptions, Error> {
    let mut options = ModelOptions::default();
    options.lighting = match args.shading {
        None | Some(ShadingArg::Phong) => Lighting::Phong,
        Some(ShadingArg::Unlit) => Lighting::Unlit,
        Some(ShadingArg::Flat) => Lighting::Flat,
        Some(ShadingArg::Gouraud | ShadingArg::Smooth) => Lighting::Gouraud,
        Some(ShadingArg::Perspective) => {
            return Err(usage(
                "--shading perspective is for --projection window; 3D varyings are always \
                 perspective-correct"
                    .into(),
            ));
        }
    };
    options.cull = match args.cull {
        None | Some(CullArg::Back) => FaceCull::Back,
        Some(CullArg::Front) => FaceCull::Front,
        Some(CullArg::None) => FaceCull::None,
        Some(CullArg::Cw | CullArg::Ccw) => {
            return Err(usage(
                "--cull cw|ccw is for --projection window; use back|front|none".into(),
            ));
        }
    };
    options.depth_test = args.depth_test.into();
    options.filter = match args.filter.unwrap_or(FilterArg::Bilinear) {
        FilterArg::Nearest => Filter::Nearest,
        FilterArg::Bilinear => Filter::Bilinear,
    };
    options.wrap = match args.wrap.unwrap_or(WrapArg::Repeat) {
        WrapArg::Repeat => Wrap::Repeat,
        WrapArg::Clamp => Wrap::Clamp,
    };
    Ok(options)
}

fn render_window(args: &RenderArgs, target: &mut Target) -> Result<(), Error> {
    // Options of the camera and of textures (the window projection has neither) were
    // ignored in silence; refused before the file is read.
    let camera_or_texture = [
        ("--normals", args.normals.is_some()),
        ("--turntable", args.turntable.is_some()),
        ("--view", args.view.is_some()),
        ("--eye", args.eye.is_some()),
        ("--fov", args.fov.is_some()),
        ("--texture", args.texture.is_some()),
        ("--filter", args.filter.is_some()),
        ("--wrap", args.wrap.is_some()),
    ];
    if let Some((option, _)) = camera_or_texture.iter().find(|(_, given)| *given) {
        return Err(usage(format!("{option} needs a 3D projection")));
    }
    let (width, height) = args.size;
    let (triangles, default_shading) = match &args.file {
        Some(path) => {
            let is_obj = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
            if !is_obj {
                return Err(usage(format!(
                    "{}: --projection window reads .obj files (`v x y z [w] [r g b]`)",
                    path.display()
                )));
            }
            let obj = trirast::mesh::obj::read(path)?;
            print_warnings(&obj.warnings);
            // Window depth is stored clamped to [0, 1]; a scene outside it had been drawn
            // with its depths flattened without a word.
            let outside = |z: f32| z.is_finite() && !(0.0..=1.0).contains(&z);
            let outside = obj.positions.iter().filter(|p| outside(p[2])).count();
            if outside > 0 {
                let what = if outside == 1 { "vertex has" } else { "vertices have" };
                note!(
                    "trirast: warning: {}: {outside} {what} z outside [0, 1]: depths are \
                     clamped to it",
                    path.display()
                );
            }
            let triangles = trirast::mesh::window_triangles(&obj);
            if triangles.is_empty() {
                note!("trirast: warning: {} has no faces: nothing to draw", path.display());
            }
            (triangles, Shading::Smooth)
        }
        None => {
            let s = scene::default_scene(width, height);
            (s.triangles, s.shading)
        }
    };
    let shading = match args.shading {
        None => default_shading,
        Some(ShadingArg::Flat) => Shading::Flat,
        Some(ShadingArg::Smooth | ShadingArg::Gouraud) => Shading::Smooth,
        Some(ShadingArg::Perspective) => Shading::Perspective,
        Some(ShadingArg::Unlit | ShadingArg::Phong) => {
            return Err(usage(
                "--projection window shades vertex colours: use flat, smooth or perspective".into(),
            ));
        }
    };
    let cull = match args.cull {
        None | Some(CullArg::None) => CullMode::None,
        Some(CullArg::Cw) => CullMode::Clockwise,
        Some(CullArg::Ccw) => CullMode::CounterClockwise,
        Some(CullArg::Back | CullArg::Front) => {
            return Err(usage(
                "--projection window has no camera to face: use --cull none, cw or ccw".into(),
            ));
        }
    };
    let clear =
        args.background.map_or(trirast::target::DEFAULT_CLEAR_COLOR, |[r, g, b]| [r, g, b, 255]);
    let options = RenderOptions::default()
        .with_algorithm(args.algorithm.unwrap_or(AlgorithmArg::Edge).into())
        .with_shading(shading)
        .with_cull(cull)
        .with_depth_test(args.depth_test.into());
    draw_timed(target, args.frames, clear, |t| trirast::draw(t, &triangles, &options))
}

/// `out.png` -> `out_007.png`: frame `k` of `total`, numbered with at least three digits and
/// as many as the last frame needs, so that the names sort in frame order.
fn frame_path(output: &Path, k: u32, total: u32) -> PathBuf {
    // The name's own bytes, whatever their encoding: names that are not UTF-8 had all
    // become `frame_000...`, so that two outputs wrote one file.
    let mut name = output.file_stem().unwrap_or("frame".as_ref()).to_os_string();
    let digits = total.saturating_sub(1).max(1).ilog10() as usize + 1;
    name.push(format!("_{k:0width$}.", width = digits.max(3)));
    name.push(output.extension().unwrap_or("png".as_ref()));
    output.with_file_name(name)
}

/// What a command writes to a file, for [`check_outputs`].
#[derive(Clone, Copy, PartialEq)]
enum Written {
    /// A PNG image.
    Png,
    /// A NumPy array.
    Npy,
    /// A PLY point cloud.
    Ply,
    /// A packed splat hierarchy.
    Tsplat,
}

impl Written {
    /// The extension of the format.
    fn extension(self) -> &'static str {
        match self {
            Self::Png => "png",
            Self::Npy => "npy",
            Self::Ply => "ply",
            Self::Tsplat => "tsplat",
        }
    }
}

/// Extensions of formats that readers recognise by name: a file named with one but holding
/// another format would be read as that one by whatever opens it.
const KNOWN_FORMATS: [&str; 18] = [
    "png", "npy", "jpg", "jpeg", "bmp", "gif", "tif", "tiff", "webp", "tga", "exr", "hdr", "ppm",
    "ply", "obj", "stl", "mtl", "tsplat",
];

/// Checks the files a command will write before it does any work: an output that is one of
/// the command's `inputs` (`pack c.ply -o c.ply` replaced the cloud it read, `render --texture
/// t.png -o t.png` the texture), two options naming one file (the second silently overwrote
/// the first, and "wrote" named a PNG holding an `.npy`), a directory that does not exist
/// (found only after rendering, with some files already written), and a name that says
/// another format (a `.jpg` held PNG bytes). Files are compared where they lead
/// ([`resolved`]), so `x.npy` and `../dir/x.npy` or a link to it are one file.
fn check_outputs(
    outputs: &[(&str, Option<&Path>, Written)],
    inputs: &[&Path],
    frames: Option<u32>,
) -> Result<(), Error> {
    check_not_inputs(outputs, inputs, frames)?;
    let named: Vec<(&str, &Path, Written)> =
        outputs.iter().filter_map(|&(option, path, kind)| Some((option, path?, kind))).collect();
    let outputs: Vec<PathBuf> = named.iter().map(|&(_, p, _)| resolved(p)).collect();
    for (k, &(option, path, kind)) in named.iter().enumerate() {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let ext = ext.as_deref().unwrap_or("");
        if KNOWN_FORMATS.contains(&ext) && ext != kind.extension() {
            let format = kind.extension();
            return Err(usage(format!("{option} {}: it is written as .{format}", path.display())));
        }
        if let Some(j) = (0..k).find(|&j| one_file(&outputs[j], &outputs[k])) {
            let first = named[j].0;
            return Err(usage(format!("{first} and {option} both name {}", path.display())));
        }
        let dir = path.parent().filter(|d| !d.as_os_str().is_empty());
        if let Some(dir) = dir.filter(|d| !d.is_dir()) {
            let exists = dir.exists();
            let (path, dir) = (path.display(), dir.display());
            return Err(usage(if exists {
                format!("{option} {path}: {dir} is not a directory")
            } else {
                format!("{option} {path}: there is no directory {dir}")
            }));
        }
        let first = frames.map_or_else(|| path.to_path_buf(), |total| frame_path(path, 0, total));
        can_write(option, path, &first)?;
    }
    Ok(())
}

/// The part of [`check_outputs`] that needs the inputs: an output that would write over one
/// of them. Checked again once a mesh names the files it read (material libraries, textures),
/// without probing the outputs a second time.
fn check_not_inputs(
    outputs: &[(&str, Option<&Path>, Written)],
    inputs: &[&Path],
    frames: Option<u32>,
) -> Result<(), Error> {
    for &(option, path, _) in outputs {
        let Some(path) = path else { continue };
        if let Some(input) = inputs.iter().find(|&&input| writes(path, frames, input)) {
            return Err(usage(format!(
                "{option} {} is the input {}: writing it would destroy what is read",
                path.display(),
                input.display()
            )));
        }
    }
    Ok(())
}

/// Whether the file `path` names (`first`, the first frame's name for a turntable) can be
/// written, found out before the work: a directory (`-o out/`, which a turntable had turned
/// into `out_000.png` beside it) or a place that refuses files (`/proc`, a read-only
/// directory) had been reported only once the picture was drawn, with some outputs already
/// written. The file is opened as it will be written, without truncating it; one made by
/// this is removed again. A device or FIFO is not opened (a FIFO would wait for a reader).
fn can_write(option: &str, path: &Path, first: &Path) -> Result<(), Error> {
    let names_a_directory = path.as_os_str().as_encoded_bytes().ends_with(b"/");
    if names_a_directory || path.is_dir() || first.is_dir() {
        let message = format!("{option} {} names a directory: give a file name", path.display());
        return Err(usage(message));
    }
    let existing = std::fs::metadata(first).ok();
    if existing.as_ref().is_some_and(|m| !m.is_file()) {
        return Ok(());
    }
    let opened = std::fs::OpenOptions::new().write(true).create(true).truncate(false).open(first);
    match opened {
        Ok(_) if existing.is_none() => {
            // The file made, where the name leads: through a dangling link, the link's
            // target (removing the name had removed the link and left the new file).
            let made = std::fs::canonicalize(first).unwrap_or_else(|_| first.to_path_buf());
            let _ = std::fs::remove_file(made);
            Ok(())
        }
        Ok(_) => Ok(()),
        Err(e) => Err(usage(format!("{option} {}: cannot be written: {e}", first.display()))),
    }
}

/// Whether writing `output` (or, for a turntable of `frames`, its numbered files
/// `stem_000.ext`...) would write over `input`: the same file where they lead ([`resolved`]),
/// or, on Unix, two names (hard links) of one file.
fn writes(output: &Path, frames: Option<u32>, input: &Path) -> bool {
    let input_at = resolved(input);
    let Some(total) = frames else {
        return one_file(&resolved(output), &input_at);
    };
    // Only the frame whose number the input's name (where it leads) carries can be it.
    let stem = input_at.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let number = &stem[stem.trim_end_matches(|c: char| c.is_ascii_digit()).len()..];
    number
        .parse::<u32>()
        .is_ok_and(|k| k < total && writes(&frame_path(output, k, total), None, input))
}

/// Whether two [`resolved`] paths name one file: the same path or, on Unix, two names (hard
/// links) of one existing file.
fn one_file(a: &Path, b: &Path) -> bool {
    if a == b {
        return true;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt as _;
        if let (Ok(a), Ok(b)) = (std::fs::metadata(a), std::fs::metadata(b)) {
            return (a.dev(), a.ino()) == (b.dev(), b.ino());
        }
    }
    false
}

/// Where `path` leads: the file itself with links and `..` resolved when it exists, else its
/// directory resolved and its name (the name as given where the directory is missing, which
/// [`check_outputs`] reports anyway). A link to a file not yet made leads where it points
/// (`-o link.png --depth d.npy`, the link to `d.npy`, had been accepted and the depth written
/// over the picture), through at most 40 links, as the system follows them.
fn resolved(path: &Path) -> PathBuf {
    resolved_within(path, 40)
}

/// [`resolved`], following at most `links` more links.
fn resolved_within(path: &Path, links: u32) -> PathBuf {
    if let Ok(p) = std::fs::canonicalize(path) {
        return p;
    }
    if links > 0
        && let Ok(target) = std::fs::read_link(path)
    {
        // Relative to the link's directory (an absolute target replaces it).
        let dir = path.parent().unwrap_or(Path::new(""));
        return resolved_within(&dir.join(target), links - 1);
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    match (std::fs::canonicalize(dir), path.file_name()) {
        (Ok(dir), Some(name)) => dir.join(name),
        _ => path.to_path_buf(),
    }
}

/// Writes the PNG and the requested buffers; a turntable `frame` numbers every file name.
fn write_outputs(args: &RenderArgs, target: &Target, frame: Option<u32>) -> Result<(), Error> {
    let (width, height) = (target.width(), target.height());
    let total = args.turntable.unwrap_or(1);
    let named = |p: &PathBuf| frame.map_or_else(|| p.clone(), |k| frame_path(p, k, total));
    let png = named(&args.output);
    trirast::output::write_png_with(&png, target, args.png_compression.into())?;
    if let Some(p) = &args.depth {
        write_sampled(&named(p), &target.depth, target, args.per_sample)?;
    }
    if let (Some(p), Some(ids)) = (&args.ids, &target.ids) {
        write_sampled(&named(p), ids, target, args.per_sample)?;
    }
    if let (Some(p), Some(o)) = (&args.overdraw, &target.overdraw) {
        trirast::output::write_npy(&named(p), o, width, height)?;
    }
    if let (Some(p), Some(n)) = (&args.normals, &target.normals) {
        trirast::output::write_npy_arrays(&named(p), n, width, height)?;
    }
    if frame.is_none() {
        note!("wrote {}", png.display());
    }
    Ok(())
}

/// Writes a per-sample buffer: every sample as (H, W, S), or sample 0 as (H, W).
fn write_sampled<T>(path: &Path, buffer: &[T], target: &Target, all: bool) -> Result<(), Error>
where
    T: npyz::Serialize + npyz::AutoSerialize + Copy,
{
    let (width, height) = (target.width(), target.height());
    if all {
        let shape = [u64::from(height), u64::from(width), target.samples().count() as u64];
        trirast::output::write_npy_shaped(path, buffer, &shape)
    } else {
        trirast::output::write_npy(path, &target.sample_plane(buffer, 0), width, height)
    }
}

/// The scenes named on the command line, or all five.
fn bench_scenes(scenes: &[SceneArg]) -> Vec<trirast::bench::BenchScene> {
    use trirast::bench::BenchScene;
    if scenes.is_empty() {
        return BenchScene::ALL.to_vec();
    }
    scenes
        .iter()
        .map(|s| match s {
            SceneArg::Bunny => BenchScene::Bunny,
            SceneArg::Soup => BenchScene::Soup,
            SceneArg::Grid => BenchScene::Grid,
            SceneArg::Fill => BenchScene::Fill,
            SceneArg::Dense => BenchScene::Dense,
        })
        .collect()
}

/// `trirast bench --export DIR`: the scenes' triangles written out, not timed.
fn export(scenes: &[SceneArg], dense_triangles: usize, dir: &Path) -> Result<(), Error> {
    if !dir.is_dir() {
        let why = if dir.exists() { "not a directory" } else { "no such directory" };
        return Err(usage(format!("--export {}: {why}", dir.display())));
    }
    for scene in bench_scenes(scenes) {
        let json = trirast::bench::export(scene, dense_triangles, dir)?;
        say!("{}: {}", scene.name(), json.display());
    }
    Ok(())
}

/// Bytes as megabytes (10^6), as the bench tables print memory.
fn megabytes(bytes: u64) -> f64 {
    bytes as f64 / 1e6
}

fn bench(
    scenes: &[SceneArg],
    threads: Option<usize>,
    frames: usize,
    msaa: SampleCount,
    dense_triangles: usize,
    json: bool,
) -> Result<(), Error> {
    use trirast::bench;
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| usage(format!("cannot start {threads} threads: {e}")))?;
    let scenes = bench_scenes(scenes);
    if scenes.contains(&trirast::bench::BenchScene::Dense) {
        let needed = dense_triangles as u128 * DENSE_BYTES_PER_TRIANGLE;
        check_memory(|| format!("the dense scene of {dense_triangles} triangles"), needed)?;
    }
    // What the kernels run on, so that figures from different machines can be told apart.
    let simd = trirast::simd::SimdLevel::detect();
    if !json {
        say!(
            "SIMD level: {simd:?} (TRIRAST_SIMD=scalar|avx2|avx512 forces one; \
             TRIRAST_SCHEDULE=binned|banded forces a schedule)"
        );
        say!(
            "{:<6} {:>11} {:>10} {:>12} {:>4} {:>4} {:>10} {:>10} {:>9} {:>9} {:>8}  schedule",
            "scene",
            "triangles",
            "pixels",
            "fragments",
            "thr",
            "msaa",
            "median ms",
            "min ms",
            "Mtri/s",
            "Gfrag/s",
            "peak MB"
        );
    }
    for scene in scenes {
        let mut counts = vec![msaa];
        if msaa != SampleCount::X1 {
            counts.insert(0, SampleCount::X1);
        }
        let mut baseline = None;
        for samples in counts {
            let r =
                pool.install(|| bench::run(scene, frames, threads, samples, dense_triangles))?;
            if json {
                say!(
                    "{{\"scene\":\"{}\",\"source\":{},\"triangles\":{},\"pixels\":{},\"fragments\":{},\"threads\":{},\"msaa\":{},\"simd\":\"{simd:?}\",\"median_ms\":{:.3},\"min_ms\":{:.3},\"mtri_per_s\":{:.2},\"gfrag_per_s\":{:.3},\"peak_memory_mb\":{},\"schedule\":{}}}",
                    r.scene,
                    bench::json_string(&r.source),
                    r.triangles,
                    r.pixels,
                    r.fragments,
                    r.threads,
                    r.msaa,
                    r.median_ms,
                    r.min_ms,
                    r.mtri_per_s(),
                    r.gfrag_per_s(),
                    r.peak_memory.map_or("null".into(), |b| format!("{:.1}", megabytes(b))),
                    r.schedule.map_or("null".into(), |s| format!("\"{}\"", s.name()))
                );
            } else {
                let cost = match baseline {
                    Some(b) if r.msaa > 1 => format!("  ({:.2}x the 1x time)", r.median_ms / b),
                    _ => String::new(),
                };
                say!(
                    "{:<6} {:>11} {:>10} {:>12} {:>4} {:>4} {:>10.2} {:>10.2} {:>9.1} {:>9.3} {:>8}  {:<6}{cost}",
                    r.scene,
                    r.triangles,
                    r.pixels,
                    r.fragments,
                    r.threads,
                    r.msaa,
                    r.median_ms,
                    r.min_ms,
                    r.mtri_per_s(),
                    r.gfrag_per_s(),
                    r.peak_memory.map_or("-".into(), |b| format!("{:.0}", megabytes(b))),
                    r.schedule.map_or("-", Schedule::name)
                );
                if r.source != "generated" && r.msaa == 1 {
                    say!("       ({})", r.source);
                }
            }
            baseline.get_or_insert(r.median_ms);
        }
    }
    Ok(())
}

fn splat_bench(points: &[usize], threads: Option<usize>, frames: usize) -> Result<(), Error> {
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| usage(format!("cannot start {threads} threads: {e}")))?;
    let counts =
        if points.is_empty() { trirast::bench::SPLAT_COUNTS.to_vec() } else { points.to_vec() };
    // The largest count, refused before any is timed.
    let most = counts.iter().copied().max().unwrap_or(0);
    check_memory(
        || format!("the splat benchmark of {most} points"),
        most as u128 * SPLAT_BENCH_BYTES_PER_POINT,
    )?;
    say!(
        "{:>10} {:>10} {:>10} {:>12} {:>8} {:>8} {:>10} {:>9} {:>4}",
        "points",
        "nodes",
        "build ms",
        "bytes",
        "B/node",
        "B/point",
        "median ms",
        "splats",
        "thr"
    );
    let mut source = None;
    for n in counts {
        let r = pool.install(|| trirast::bench::run_splats(n, frames))?;
        source.get_or_insert(r.source.clone());
        say!(
            "{:>10} {:>10} {:>10.0} {:>12} {:>8.2} {:>8.2} {:>10.2} {:>9} {:>4}",
            r.points,
            r.nodes,
            r.build_ms,
            r.bytes,
            r.bytes as f64 / r.nodes as f64,
            r.bytes as f64 / r.points as f64,
            r.median_ms,
            r.splats,
            threads
        );
    }
    if let Some(source) = source {
        say!("points sampled from {source}");
    }
    Ok(())
}

/// Warnings shown at most, of one list: a file can make one per line (50,000 `usemtl` names
/// without a library made as many lines).
const SHOWN_WARNINGS: usize = 20;

/// The first [`SHOWN_WARNINGS`] of `warnings`, and how many more there are.
fn shown(warnings: &[String]) -> (&[String], usize) {
    let n = warnings.len().min(SHOWN_WARNINGS);
    (&warnings[..n], warnings.len() - n)
}

/// Prints [`shown`] warnings to stderr, then how many more there are.
fn print_warnings(warnings: &[String]) {
    let (first, more) = shown(warnings);
    for w in first {
        note!("trirast: warning: {w}");
    }
    if more > 0 {
        note!("trirast: warning: ... and {more} more warning(s), not shown");
    }
}

/// Prints what loading left to say about a mesh: the reader's warnings, and a hint when a
/// file has vertices but no faces (a point cloud given to a mesh command).
fn warn_about(mesh: &Mesh) {
    print_warnings(&mesh.warnings);
    if mesh.triangles.is_empty() && !mesh.positions.is_empty() {
        note!(
            "trirast: warning: the file has {} vertices but no faces; for a point cloud use \
             `trirast splat`",
            mesh.positions.len()
        );
    }
}

/// Files at least this large show a progress bar while they are read: a million-triangle OBJ
/// (37 MB) reads in about 0.2 s, so smaller ones would only flash one.
const READ_PROGRESS_BYTES: u64 = 64 << 20;

/// `read(report)`, with a bar over `path`'s bytes fed by `report` while it runs (drawn on a
/// terminal only, as every bar is, and only for files of [`READ_PROGRESS_BYTES`] or more),
/// cleared when it returns: reading a mesh of tens of millions of triangles takes seconds.
fn reading<T>(
    path: &Path,
    read: impl FnOnce(&dyn Fn(u64)) -> Result<T, Error>,
) -> Result<T, Error> {
    let size = std::fs::metadata(path).map_or(0, |m| m.len());
    if size < READ_PROGRESS_BYTES {
        return read(&|_| {});
    }
    let name =
        path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into());
    let bar = ProgressBar::new(size)
        .with_style(
            ProgressStyle::with_template(
                "reading {msg} {bar:30} {bytes}/{total_bytes}, {eta} left",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        )
        .with_message(name);
    let result = read(&|n| bar.set_position(n));
    bar.finish_and_clear();
    result
}

/// Work on at least this many points or nodes shows a spinner while it runs: building the
/// hierarchy of two million points takes about 1.6 s, of fifteen million about 8 s, and
/// packing it as long again.
const WORK_PROGRESS_ITEMS: usize = 1 << 20;

/// `work()`, with a spinner saying `message` and the time so far while it runs, when `items`
/// (what it works on) reach [`WORK_PROGRESS_ITEMS`] (drawn on a terminal only, as every bar
/// is), cleared when it returns.
fn working<T>(items: usize, message: impl FnOnce() -> String, work: impl FnOnce() -> T) -> T {
    if items < WORK_PROGRESS_ITEMS {
        return work();
    }
    let spinner = ProgressBar::new_spinner()
        .with_style(
            ProgressStyle::with_template("{spinner} {msg}, {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        )
        .with_message(message());
    spinner.enable_steady_tick(std::time::Duration::from_millis(100));
    let result = work();
    spinner.finish_and_clear();
    result
}

fn sample(file: &Path, points: usize, output: &Path, seed: u64) -> Result<(), Error> {
    check_outputs(&[("--output", Some(output), Written::Ply)], &[file], None)?;
    let mesh = reading(file, |report| trirast::mesh::load_reporting(file, report))?;
    check_not_inputs(&[("--output", Some(output), Written::Ply)], &files_read(&mesh), None)?;
    warn_about(&mesh);
    check_texture_memory(material_textures(&mesh))?;
    let textures = MaterialTextures::load(&mesh);
    print_warnings(&textures.warnings);
    // The cloud: position, normal, colour and radius a point.
    let needed = points as u128 * (12 + 12 + 3 + 4);
    check_memory(|| format!("a cloud of {points} points"), needed)?;
    let start = std::time::Instant::now();
    let cloud =
        trirast::splat::cloud::sample_mesh(&mesh, &textures, points, seed).map_err(|e| {
            match e {
                // The library's error has no file; what is too large is this one's surface.
                Error::SampleRadius { .. } => usage(format!("{}: {e}", file.display())),
                e => e,
            }
        })?;
    if cloud.positions.is_empty() {
        // An empty cloud written here was refused by every command that reads one.
        return Err(usage(format!(
            "{}: no surface to sample (no triangle of finite, non-zero area)",
            file.display()
        )));
    }
    trirast::splat::cloud::write_ply(output, &cloud)?;
    note!(
        "sampled {} in {:.0} ms; wrote {}",
        counted(cloud.positions.len(), "point"),
        start.elapsed().as_secs_f64() * 1e3,
        output.display()
    );
    Ok(())
}

/// The splat hierarchy of a `.tsplat` file, or built from a PLY cloud; an empty cloud is an
/// error (nothing could draw it, so nothing should pack it).
fn load_splats(file: &Path) -> Result<trirast::splat::SplatTree, Error> {
    let is = |ext: &str| file.extension().is_some_and(|e| e.eq_ignore_ascii_case(ext));
    // A mesh had been read as a PLY file and refused for its first line.
    if is("obj") || is("stl") {
        return Err(usage(format!(
            "{}: a mesh, not a point cloud (.ply or .tsplat): sample one from it first (`trirast \
             sample {} -o cloud.ply`)",
            file.display(),
            file.display()
        )));
    }
    let tree = if is("tsplat") {
        trirast::splat::format::read(file)?
    } else {
        let cloud =
            reading(file, |report| trirast::splat::cloud::read_ply_reporting(file, report))?;
        print_warnings(&cloud.warnings);
        let points = cloud.positions.len();
        let needed = points as u128 * BUILD_BYTES_PER_POINT;
        check_memory(|| format!("the hierarchy of {points} points"), needed)?;
        let start = std::time::Instant::now();
        let message = || format!("building the hierarchy of {}", counted(points, "point"));
        let tree = working(points, message, || trirast::splat::SplatTree::build(&cloud))?;
        note!(
            "built the hierarchy of {} ({}) in {:.0} ms",
            counted(cloud.positions.len(), "point"),
            counted(tree.nodes.len(), "node"),
            start.elapsed().as_secs_f64() * 1e3
        );
        tree
    };
    if tree.nodes.is_empty() {
        return Err(usage(format!("{}: the point cloud is empty", file.display())));
    }
    Ok(tree)
}

/// Warns of splats the view could not draw because they reach the camera's plane (the view
/// frames the points' centres, as `render` frames a mesh): splats larger than the cloud (a few
/// points sampled from a mesh, or radii given in other units) had given an empty picture without
/// a word but "N nodes culled". The renderer counts them, so the rule is its own.
fn warn_of_splats_at_the_eye(
    tree: &trirast::splat::SplatTree,
    camera: &Camera,
    stats: &trirast::splat::render::SplatStats,
) {
    let reaching = stats.at_eye;
    if reaching > 0 {
        let leaves = tree.nodes.iter().filter(|n| n.child_count == 0);
        let largest = leaves.map(|n| n.radius).fold(0.0f32, f32::max);
        let distance = (camera.target - camera.eye).length();
        let verb = if reaching == 1 { "reaches" } else { "reach" };
        note!(
            "trirast: warning: {reaching} of {} {verb} the camera's plane and cannot be drawn \
             (the largest splat radius is {largest:.3e}; the camera is {distance:.3e} from the \
             points' centre)",
            counted(tree.leaf_count(), "splat"),
        );
    }
}

/// The points of a splat hierarchy: its leaves' centres.
fn leaf_centres(tree: &trirast::splat::SplatTree) -> Vec<[f32; 3]> {
    tree.nodes.iter().filter(|n| n.child_count == 0).map(|n| n.centre).collect()
}

fn pack(file: &Path, output: &Path) -> Result<(), Error> {
    check_outputs(&[("--output", Some(output), Written::Tsplat)], &[file], None)?;
    let tree = load_splats(file)?;
    // Said where the cloud is packed, as `splat` says it again where it is drawn.
    warn_of_scale(&leaf_centres(&tree), "point");
    let points = tree.leaf_count();
    let needed = points as u128 * ENCODE_BYTES_PER_POINT;
    check_memory(|| format!("packing {points} points"), needed)?;
    let nodes = tree.nodes.len();
    let message = || format!("packing {} into {}", counted(nodes, "node"), output.display());
    working(nodes, message, || trirast::splat::format::write(output, &tree))?;
    let bytes = std::fs::metadata(output).map_err(|e| Error::io(output, e))?.len();
    note!(
        "wrote {}: {}, {}, {} bytes ({:.2} bytes per node, {:.2} per point)",
        output.display(),
        counted(tree.nodes.len(), "node"),
        counted(tree.leaf_count(), "point"),
        bytes,
        bytes as f64 / tree.nodes.len().max(1) as f64,
        bytes as f64 / tree.leaf_count().max(1) as f64
    );
    Ok(())
}

fn splat(args: &SplatArgs) -> Result<(), Error> {
    use trirast::splat::render::{Progressive, SplatOptions, SplatShape};
    let outputs = [
        ("--output", Some(args.output.as_path()), Written::Png),
        ("--depth", args.depth.as_deref(), Written::Npy),
    ];
    check_outputs(&outputs, &[&args.file], None)?;
    // The target first: a size it refuses is reported before the hierarchy is built.
    // Per pixel beside the target: the scratch target each level is drawn into.
    check_target_memory(args.size, SampleCount::X1, 0, 8, memory_available())?;
    let (width, height) = args.size;
    let mut target = Target::new(width, height)?;
    let tree = load_splats(&args.file)?;
    // Framed like `trirast render` frames a mesh: by the points' bounding box, so a cloud
    // sampled from a mesh appears exactly where the mesh does.
    let leaves = leaf_centres(&tree);
    let (centre, radius) = camera::bounding_sphere(&leaves);
    warn_of_scale(&leaves, "point");
    let [az, el] = args.view.unwrap_or([30.0, 20.0]);
    let camera = Camera::framing_sphere(
        centre,
        radius,
        az.to_radians(),
        el.to_radians(),
        width as f32 / height as f32,
        Projection::Perspective { fov_y: camera::DEFAULT_FOV_Y },
    );
    let shape = match args.shape {
        ShapeArg::Round => SplatShape::Round,
        ShapeArg::Square => SplatShape::Square,
    };
    let options = SplatOptions::default().with_shape(shape);
    let background = args.background.unwrap_or([38, 42, 52]);
    let clear = [background[0], background[1], background[2], 255];
    let threshold = args.threshold;
    let start = std::time::Instant::now();
    let mut progressive = Progressive::new(threshold);
    if args.budget_ms.is_none() {
        // No budget: straight to the final level.
        while progressive.next_threshold().is_some_and(|t| t != threshold) {
            progressive.skip();
        }
    }
    let mut last_ms = 0.0;
    let mut finest = None;
    // Scratch target so that a level being drawn never replaces a finished one.
    let mut scratch = target.clone();
    while let Some(next) = progressive.next_threshold() {
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        if let (Some(budget), Some(_)) = (args.budget_ms, &finest) {
            // Each level costs about 4x the previous one (about 4x more splats).
            if elapsed + 4.0 * last_ms > budget {
                break;
            }
        }
        let t = std::time::Instant::now();
        let Some((_, stats)) = progressive.step(&mut scratch, &tree, &camera, &options, clear)
        else {
            break;
        };
        last_ms = t.elapsed().as_secs_f64() * 1e3;
        std::mem::swap(&mut target, &mut scratch);
        finest = Some((next, stats, last_ms));
    }
    if let Some((level, stats, ms)) = finest {
        // A level of single points is the final image whatever its threshold (a tree of one
        // node reported "budget reached" though nothing was left to refine).
        let note = if level == threshold {
            ""
        } else if progressive.is_done() {
            " (every splat a single point: nothing left to refine)"
        } else {
            " (coarser than --threshold: budget reached)"
        };
        note!(
            "level {} px: {} ({} of them single points), {} culled, {ms:.1} ms{note}",
            // `--threshold 1e30` had printed its thirty-one digits (and 1e-30 its 31 decimals).
            if level == 0.0 || (1e-3..1e6).contains(&level) {
                level.to_string()
            } else {
                format!("{level:e}")
            },
            counted(stats.drawn, "splat"),
            stats.leaves_drawn,
            counted(stats.culled, "node"),
        );
        warn_of_splats_at_the_eye(&tree, &camera, &stats);
    }
    trirast::output::write_png_with(&args.output, &target, args.png_compression.into())?;
    if let Some(p) = &args.depth {
        trirast::output::write_npy(p, &target.depth, width, height)?;
    }
    note!("wrote {}", args.output.display());
    Ok(())
}

fn info(path: &Path) -> Result<(), Error> {
    let mesh: Mesh = reading(path, |report| trirast::mesh::load_reporting(path, report))?;
    let finite = mesh.positions.iter().filter(|p| p.iter().all(|c| c.is_finite()));
    let (lo, hi) =
        finite.clone().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), p| {
            (std::array::from_fn(|k| lo[k].min(p[k])), std::array::from_fn(|k| hi[k].max(p[k])))
        });
    warn_about(&mesh);
    say!("file:       {}", path.display());
    // What a vertex is differs by format, and the count is not the file's `v` lines for OBJ.
    let vertices = match Format::of(path) {
        Some(Format::Obj) => " (distinct corners the faces use: unused `v` lines are left out)",
        Some(Format::Stl) => " (facet corners, welded)",
        Some(Format::Ply) | None => "",
    };
    say!("vertices:   {}{vertices}", mesh.positions.len());
    say!("triangles:  {}", mesh.triangles.len());
    say!("polygons:   {}", mesh.polygon_count);
    if lo[0] <= hi[0] {
        // The framing's sphere (the box's centre, the farthest vertex from it) with its true
        // radius: in `f64`, which neither a single point (the framing's fallback of 1) nor
        // coordinates near `f32::MAX` (an infinite centre or distance) change.
        let c: [f64; 3] = std::array::from_fn(|k| (f64::from(lo[k]) + f64::from(hi[k])) / 2.0);
        let centre = c.map(|v| v as f32);
        let radius = finite
            .clone()
            .map(|p| (0..3).map(|k| (f64::from(p[k]) - c[k]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max);
        say!("bounds:     min {lo:?} max {hi:?}");
        // Shown in single precision, as the bounds are, where it fits.
        let shown = radius as f32;
        let radius = if shown.is_finite() { shown.to_string() } else { radius.to_string() };
        say!("sphere:     centre {centre:?} radius {radius}");
        let non_finite = mesh.positions.len() - finite.count();
        if non_finite > 0 {
            let what = if non_finite == 1 { "vertex" } else { "vertices" };
            say!("non-finite: {non_finite} {what} (NaN or infinite; not drawn)");
        }
    } else {
        // Not the empty fold's infinities, nor the unit sphere framing falls back to.
        say!("bounds:     none (no finite vertex)");
    }
    let yes = |b: bool| if b { "yes" } else { "no" };
    say!("normals:    {}", yes(mesh.normals.is_some()));
    say!("texcoords:  {}", yes(mesh.texcoords.is_some()));
    say!("colours:    {}", yes(mesh.colors.is_some()));
    say!("materials:  {}", mesh.materials.len());
    for m in &mesh.materials {
        let texture = m.diffuse_texture.as_ref().map(|t| t.display().to_string());
        say!(
            "  {:?}: diffuse {:?}, texture {}",
            m.name,
            m.diffuse,
            texture.unwrap_or("none".into())
        );
    }
    let (first, more) = shown(&mesh.warnings);
    for w in first {
        say!("warning:    {w}");
    }
    if more > 0 {
        say!("warning:    ... and {more} more, not shown");
    }
    Ok(())
}

fn demo(
    which: DemoArg,
    output: &Path,
    size: (u32, u32),
    algorithm: AlgorithmArg,
) -> Result<(), Error> {
    let which = match which {
        DemoArg::Flat => Demo::Flat,
        DemoArg::Smooth => Demo::Smooth,
        DemoArg::Soup => Demo::Soup,
    };
    check_outputs(&[("--output", Some(output), Written::Png)], &[], None)?;
    check_target_memory(size, SampleCount::X1, 0, 0, memory_available())?;
    let mut target = Target::new(size.0, size.1)?;
    let s = scene::demo(which, size.0, size.1);
    let options = RenderOptions::default().with_shading(s.shading).with_algorithm(algorithm.into());
    let clear = trirast::target::DEFAULT_CLEAR_COLOR;
    draw_timed(&mut target, None, clear, |t| trirast::draw(t, &s.triangles, &options))?;
    trirast::output::write_png(output, &target)?;
    note!("wrote {}", output.display());
    Ok(())
}

/// Draws a frame with `draw` on a target cleared to `clear`, or with `frames = Some(n)` one
/// untimed frame and `n` timed ones, then reports the last frame's counts and, when timed, the
/// median and fastest frame times with the throughput (`trirast render --frames`).
fn draw_timed(
    target: &mut Target,
    frames: Option<usize>,
    clear: [u8; 4],
    mut draw: impl FnMut(&mut Target) -> Result<trirast::DrawStats, Error>,
) -> Result<(), Error> {
    let (stats, times) = trirast::bench::time_frames(frames.unwrap_or(0), || {
        target.clear(clear);
        draw(target)
    })?;
    report(&stats);
    if let (Some(fastest), Some(&median)) = (times.first(), times.get(times.len() / 2)) {
        say!(
            "{}, {}: median {median:.2} ms, min {fastest:.2} ms per frame; \
             {:.1} Mtri/s, {:.3} G frag/s{}",
            counted(times.len(), "frame"),
            counted(rayon::current_num_threads(), "thread"),
            stats.submitted as f64 / median / 1e3,
            stats.fragments as f64 / median / 1e6,
            target.last_schedule().map_or(String::new(), |s| format!("; {}", s.name()))
        );
    }
    Ok(())
}

fn report(stats: &trirast::DrawStats) {
    if stats.non_finite > 0 {
        note!(
            "trirast: warning: dropped {} triangle(s) whose coordinates are NaN or infinite, \
             in the file or after the camera's transform (single precision: about 3.4e38 at \
             most)",
            stats.non_finite
        );
    }
    // Clipping can cut a triangle into several (three of them into seven, say): each is
    // counted once, and the pieces it added are said.
    let clipped = match stats.extra_pieces {
        0 => String::new(),
        1 => " (clipping added a piece)".to_string(),
        n => format!(" (clipping added {n} pieces)"),
    };
    let fragments = if stats.fragments == 1 { "fragment" } else { "fragments" };
    note!(
        "{}: {} rasterized{clipped}, {} culled or clipped away, {} degenerate; {} {fragments}",
        counted(stats.submitted, "triangle"),
        stats.rasterized,
        stats.culled,
        stats.degenerate,
        stats.fragments
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A target is refused up front exactly when its buffers need more than is available,
    /// counting the buffers asked for; no figure from the system, no refusal.
    #[test]
    fn targets_are_refused_only_past_the_memory_available() {
        let size = (1000, 500);
        // Colour and depth at 4x, ids at 4x, overdraw and normals, the resolved colour.
        let needed = 1000 * 500 * (4 * (8 + 4) + 16 + 8);
        let check = |available| check_target_memory(size, SampleCount::X4, 4, 16, available);
        assert!(check(Some(needed)).is_ok());
        assert!(check(None).is_ok());
        let Err(Error::MemoryUnavailable { what, needed: n, available }) = check(Some(needed - 1))
        else {
            panic!("one byte short is not refused");
        };
        assert_eq!((n, available), (needed, needed - 1));
        assert_eq!(what, "a 1000x500 target with 4 sample(s) per pixel");
        // Sizes out of range are for `Target` to name.
        assert!(check_target_memory((0, 500), SampleCount::X1, 0, 0, Some(0)).is_ok());
        assert!(check_target_memory((16385, 1), SampleCount::X1, 0, 0, Some(0)).is_ok());
        // 16384 x 16384 at 8x: 16 GiB of colour and depth, 2 GiB for the PNG. Needed is
        // rounded up and available down, so the two never read the same.
        let big = check_target_memory((16384, 16384), SampleCount::X8, 0, 0, Some((18 << 30) - 1));
        assert_eq!(
            big.unwrap_err().to_string(),
            "a 16384x16384 target with 8 sample(s) per pixel needs 18.00 GiB of memory and \
             17.99 GiB is available"
        );
    }

    /// `/proc/meminfo`'s fields are read by name, in kibibytes; swap counts when present.
    #[test]
    fn meminfo_is_read() {
        let text = "MemTotal:       24000000 kB\nMemFree:   100 kB\nMemAvailable:   2000 kB\n\
                    SwapTotal:  9 kB\nSwapFree:   300 kB\n";
        assert_eq!(meminfo_available(text), Some(2300 * 1024));
        assert_eq!(meminfo_available("MemAvailable: 5 kB\n"), Some(5 * 1024));
        assert_eq!(meminfo_available("MemTotal: 5 kB\nMemAvailableX: 7 kB\n"), None);
        assert_eq!(meminfo_available("MemAvailable: many kB\n"), None);
        // On Linux the live figure is read at all, and work no machine has memory for is
        // refused by it.
        if cfg!(target_os = "linux") {
            assert!(memory_available().is_some());
            let refused = check_memory(|| "a cloud".into(), u128::MAX).unwrap_err().to_string();
            assert!(refused.starts_with("a cloud needs"), "{refused}");
            assert!(check_memory(|| "a cloud".into(), 1).is_ok());
        }
        let limits = "Max cpu time              unlimited            unlimited            seconds\n\
                      Max address space         6000000000           unlimited            bytes\n";
        let status = "Name:\ttrirast\nVmPeak:\t  9 kB\nVmSize:\t  1000 kB\n";
        assert_eq!(address_space_room_of(limits, status), Some(6_000_000_000 - 1_024_000));
        let unlimited = limits.replace("6000000000 ", "unlimited  ");
        assert_eq!(address_space_room_of(&unlimited, status), None);
        let stat = "cache 5\ninactive_file 300\ntotal_inactive_file 7\n";
        assert_eq!(memory_stat(stat, "inactive_file"), Some(300));
        assert_eq!(memory_stat(stat, "total_inactive_file"), Some(7));
        assert_eq!(memory_stat(stat, "active_file"), None);
    }

    /// Turntable frame names sort in frame order: three digits up to 1,000 frames, as many as
    /// the last frame needs beyond.
    #[test]
    fn frame_names_sort_in_frame_order() {
        let name = |k, total| frame_path(Path::new("out/t.png"), k, total);
        assert_eq!(name(7, 1), Path::new("out/t_007.png"));
        assert_eq!(name(999, 1000), Path::new("out/t_999.png"));
        assert_eq!(name(7, 1001), Path::new("out/t_0007.png"));
        for total in [1, 9, 10, 999, 1000, 1001, 123_456] {
            let names: Vec<PathBuf> = (0..total.min(2000)).map(|k| name(k, total)).collect();
            assert!(names.is_sorted(), "{total} frames");
        }
    }
}
