//! The `trirast` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};
use trirast::scene::{self, Demo};
use trirast::{Algorithm, CullMode, DepthTest, Error, RenderOptions, Shading, Target, Vertex};

#[derive(Parser)]
#[command(name = "trirast", version, about = "An exact software triangle rasterizer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a mesh file, or the built-in default scene when no file is given.
    Render(RenderArgs),
    /// Draw one of the lectures' demonstrations.
    Demo {
        /// Which demonstration.
        #[arg(value_enum, default_value_t = DemoArg::Smooth)]
        which: DemoArg,
        /// Output PNG.
        #[arg(short, long, default_value = "demo.png")]
        output: PathBuf,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "512x512", value_parser = parse_size)]
        size: (u32, u32),
        /// Coverage algorithm.
        #[arg(long, value_enum, default_value_t = AlgorithmArg::Edge)]
        algorithm: AlgorithmArg,
    },
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Mesh file (.obj). Without one, the built-in default scene is drawn.
    file: Option<PathBuf>,
    /// How vertex positions map to the image. `window`: x, y are pixels (y down), z is depth.
    #[arg(long, value_enum, default_value_t = ProjectionArg::Window)]
    projection: ProjectionArg,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    size: (u32, u32),
    /// Output colour PNG.
    #[arg(short, long, default_value = "trirast.png")]
    output: PathBuf,
    /// Also write the depth buffer as a float32 .npy of shape (H, W).
    #[arg(long, value_name = "FILE")]
    depth: Option<PathBuf>,
    /// Also write triangle ids (int32 .npy, -1 where empty).
    #[arg(long, value_name = "FILE")]
    ids: Option<PathBuf>,
    /// Also write fragments per pixel, counted before the depth test (uint32 .npy).
    #[arg(long, value_name = "FILE")]
    overdraw: Option<PathBuf>,
    /// Colour interpolation (default: smooth).
    #[arg(long, value_enum)]
    shading: Option<ShadingArg>,
    /// Coverage algorithm; both give identical pixels.
    #[arg(long, value_enum, default_value_t = AlgorithmArg::Edge)]
    algorithm: AlgorithmArg,
    /// Discard triangles of this on-screen winding (y down).
    #[arg(long, value_enum, default_value_t = CullArg::None)]
    cull: CullArg,
    /// Depth comparison; `always` disables the test, so the last triangle drawn wins.
    #[arg(long, value_enum, default_value_t = DepthTestArg::Less)]
    depth_test: DepthTestArg,
}

#[derive(Clone, Copy, ValueEnum)]
enum ProjectionArg {
    Window,
}

#[derive(Clone, Copy, ValueEnum)]
enum DemoArg {
    Flat,
    Smooth,
    Soup,
}

#[derive(Clone, Copy, ValueEnum)]
enum ShadingArg {
    Flat,
    Smooth,
    Perspective,
}

#[derive(Clone, Copy, ValueEnum)]
enum AlgorithmArg {
    Edge,
    Scanline,
}

#[derive(Clone, Copy, ValueEnum)]
enum CullArg {
    None,
    Cw,
    Ccw,
}

#[derive(Clone, Copy, ValueEnum)]
enum DepthTestArg {
    Less,
    LessEqual,
    Always,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, e.g. 640x480, found `{s}`"))?;
    let side = |t: &str| t.trim().parse::<u32>().map_err(|_| format!("`{t}` is not a size"));
    Ok((side(w)?, side(h)?))
}

impl From<AlgorithmArg> for Algorithm {
    fn from(a: AlgorithmArg) -> Self {
        match a {
            AlgorithmArg::Edge => Algorithm::EdgeFunctions,
            AlgorithmArg::Scanline => Algorithm::Scanline,
        }
    }
}

impl From<ShadingArg> for Shading {
    fn from(s: ShadingArg) -> Self {
        match s {
            ShadingArg::Flat => Shading::Flat,
            ShadingArg::Smooth => Shading::Smooth,
            ShadingArg::Perspective => Shading::Perspective,
        }
    }
}

impl From<CullArg> for CullMode {
    fn from(c: CullArg) -> Self {
        match c {
            CullArg::None => CullMode::None,
            CullArg::Cw => CullMode::Clockwise,
            CullArg::Ccw => CullMode::CounterClockwise,
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => render(&args),
        Command::Demo { which, output, size, algorithm } => demo(which, &output, size, algorithm),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("trirast: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn render(args: &RenderArgs) -> Result<(), Error> {
    let (width, height) = args.size;
    let mut target = Target::new(width, height)?;
    if args.ids.is_some() {
        target = target.with_ids();
    }
    if args.overdraw.is_some() {
        target = target.with_overdraw();
    }
    let (triangles, default_shading) = match (&args.file, args.projection) {
        (Some(path), ProjectionArg::Window) => {
            let mesh = trirast::mesh::obj::read(path)?;
            (trirast::mesh::window_triangles(&mesh), Shading::Smooth)
        }
        (None, _) => {
            let s = scene::default_scene(width, height);
            (s.triangles, s.shading)
        }
    };
    let options = RenderOptions::default()
        .with_algorithm(args.algorithm.into())
        .with_shading(args.shading.map_or(default_shading, Shading::from))
        .with_cull(args.cull.into())
        .with_depth_test(args.depth_test.into());
    draw_and_report(&mut target, &triangles, &options)?;
    trirast::output::write_png(&args.output, &target)?;
    if let Some(p) = &args.depth {
        trirast::output::write_npy(p, &target.depth, width, height)?;
    }
    if let (Some(p), Some(ids)) = (&args.ids, &target.ids) {
        trirast::output::write_npy(p, ids, width, height)?;
    }
    if let (Some(p), Some(o)) = (&args.overdraw, &target.overdraw) {
        trirast::output::write_npy(p, o, width, height)?;
    }
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

fn demo(which: DemoArg, output: &Path, size: (u32, u32), algorithm: AlgorithmArg) -> Result<(), Error> {
    let which = match which {
        DemoArg::Flat => Demo::Flat,
        DemoArg::Smooth => Demo::Smooth,
        DemoArg::Soup => Demo::Soup,
    };
    let mut target = Target::new(size.0, size.1)?;
    let s = scene::demo(which, size.0, size.1);
    let options = RenderOptions::default().with_shading(s.shading).with_algorithm(algorithm.into());
    draw_and_report(&mut target, &s.triangles, &options)?;
    trirast::output::write_png(output, &target)?;
    eprintln!("wrote {}", output.display());
    Ok(())
}

fn draw_and_report(
    target: &mut Target,
    triangles: &[[Vertex; 3]],
    options: &RenderOptions,
) -> Result<(), Error> {
    let stats = trirast::draw(target, triangles, options)?;
    if stats.non_finite > 0 {
        eprintln!(
            "trirast: warning: dropped {} triangle(s) with NaN or infinite coordinates",
            stats.non_finite
        );
    }
    eprintln!(
        "{} triangles: {} rasterized, {} culled, {} degenerate; {} fragments",
        stats.submitted, stats.rasterized, stats.culled, stats.degenerate, stats.fragments
    );
    Ok(())
}
