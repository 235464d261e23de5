//! End-to-end tests of the `trirast` binary: they run it as a user would, on OBJ files written
//! here, and check what it wrote (PNG, `.npy`) or what it said (exit status, stderr).
//!
//! Every check is a property that follows from the inputs (which triangle owns which pixel,
//! which depth a flat triangle has, which one a depth test keeps), not a stored snapshot.

use std::ffi::{OsStr, OsString};
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(test: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir = std::env::temp_dir()
            .join(format!("trirast-cli-{test}-{}-{n}-{nanos}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    fn write(&self, name: &str, contents: &str) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, contents).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}

fn trirast_in<I, S>(dir: &Path, args: I) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    trirast_with_env(dir, args, ("", ""))
}

/// [`trirast_in`] with the environment variable `name` set to `value` (none when `name` is
/// empty).
fn trirast_with_env<I, S>(dir: &Path, args: I, (name, value): (&str, &str)) -> Output
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut command = Command::new(env!("CARGO_BIN_EXE_trirast"));
    command.args(args).current_dir(dir);
    if !name.is_empty() {
        command.env(name, value);
    }
    command.output().expect("failed to start the trirast binary")
}

fn stderr_of(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Runs trirast in `dir` and asserts it succeeded without panicking; returns stderr.
fn run_ok<I, S>(dir: &Path, args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = trirast_in(dir, args);
    let err = stderr_of(&out);
    assert!(out.status.success(), "trirast failed ({}): {err}", out.status);
    assert!(!err.contains("panicked"), "trirast panicked: {err}");
    err
}

/// Runs trirast in `dir` and asserts it failed cleanly (non-zero, a message, no panic).
fn run_err<I, S>(dir: &Path, args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = trirast_in(dir, args);
    let err = stderr_of(&out);
    assert!(!out.status.success(), "trirast should have failed; stderr: {err}");
    assert!(out.status.code().is_some(), "trirast was killed by a signal: {err}");
    assert!(!err.contains("panicked"), "trirast panicked: {err}");
    assert!(!err.trim().is_empty(), "trirast failed without a message");
    err
}

/// A decoded `.npy` file: dtype descriptor, shape and raw little-endian data.
struct Npy {
    descr: String,
    shape: Vec<usize>,
    data: Vec<u8>,
}

/// Value of `key` in a numpy header dict such as
/// `{'descr': '<i4', 'fortran_order': False, 'shape': (48, 64), }`.
fn header_value<'a>(dict: &'a str, key: &str) -> &'a str {
    let pat = format!("'{key}':");
    let start = dict.find(&pat).unwrap_or_else(|| panic!("no {key} in {dict:?}")) + pat.len();
    let rest = dict[start..].trim_start();
    let end = match rest.as_bytes()[0] {
        b'\'' => rest[1..].find('\'').unwrap() + 2,
        b'(' => rest.find(')').unwrap() + 1,
        _ => rest.find([',', '}']).unwrap(),
    };
    rest[..end].trim()
}

fn read_npy(path: &Path) -> Npy {
    let bytes = fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(&bytes[..6], b"\x93NUMPY", "bad magic in {}", path.display());
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_len, text_start) = match major {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 => (u32::from_le_bytes(bytes[8..12].try_into().unwrap()) as usize, 12),
        v => panic!("unknown npy version {v}.{minor}"),
    };
    assert_eq!(minor, 0, "npy minor version");
    let data_start = text_start + header_len;
    assert_eq!(data_start % 16, 0, "npy data must start 16-byte aligned");
    let header = std::str::from_utf8(&bytes[text_start..data_start]).unwrap();
    assert!(header.ends_with('\n'), "npy header must end with a newline: {header:?}");
    let dict = header.trim();
    assert!(dict.starts_with('{') && dict.ends_with('}'), "header is not a dict: {dict:?}");
    let descr = header_value(dict, "descr").trim_matches('\'').to_string();
    assert_eq!(header_value(dict, "fortran_order"), "False");
    let shape = header_value(dict, "shape");
    let shape: Vec<usize> = shape
        .trim_matches(['(', ')'])
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    Npy { descr, shape, data: bytes[data_start..].to_vec() }
}

impl Npy {
    fn check(&self, descr: &str, height: usize, width: usize) {
        assert_eq!(self.descr, descr);
        assert_eq!(self.shape, [height, width]);
        assert_eq!(self.data.len(), height * width * 4, "data length for shape {:?}", self.shape);
    }

    fn words(&self) -> impl Iterator<Item = [u8; 4]> + '_ {
        self.data.chunks_exact(4).map(|c| c.try_into().unwrap())
    }

    fn i32s(&self) -> Vec<i32> {
        assert_eq!(self.descr, "<i4");
        self.words().map(i32::from_le_bytes).collect()
    }

    fn u32s(&self) -> Vec<u32> {
        assert_eq!(self.descr, "<u4");
        self.words().map(u32::from_le_bytes).collect()
    }

    fn f32s(&self) -> Vec<f32> {
        assert_eq!(self.descr, "<f4");
        self.words().map(f32::from_le_bytes).collect()
    }
}

/// A decoded RGBA8 PNG.
struct Image {
    width: usize,
    height: usize,
    rgba: Vec<u8>,
}

impl Image {
    fn at(&self, x: usize, y: usize) -> [u8; 4] {
        let i = 4 * (y * self.width + x);
        self.rgba[i..i + 4].try_into().unwrap()
    }

    fn distinct_colors(&self) -> usize {
        let mut c: Vec<[u8; 4]> =
            self.rgba.chunks_exact(4).map(|p| p.try_into().unwrap()).collect();
        c.sort_unstable();
        c.dedup();
        c.len()
    }
}

fn read_png(path: &Path) -> Image {
    let file = fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut reader = png::Decoder::new(std::io::BufReader::new(file)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    Image { width: info.width as usize, height: info.height as usize, rgba: buf }
}

/// Renders `obj` (window projection, `W x H`) with extra `args`, returning the PNG and the
/// three `.npy` buffers (ids, depth, overdraw).
struct Rendered {
    image: Image,
    ids: Vec<i32>,
    depth: Vec<f32>,
    overdraw: Vec<u32>,
    stderr: String,
}

const W: usize = 64;
const H: usize = 48;

fn render_obj(dir: &TempDir, obj: &str, args: &[&str]) -> Rendered {
    let input = dir.write("scene.obj", obj);
    let mut all: Vec<&OsStr> = vec![
        "render".as_ref(),
        input.as_os_str(),
        "--projection".as_ref(),
        "window".as_ref(),
        "--size".as_ref(),
        "64x48".as_ref(),
        "-o".as_ref(),
        "c.png".as_ref(),
        "--depth".as_ref(),
        "d.npy".as_ref(),
        "--ids".as_ref(),
        "i.npy".as_ref(),
        "--overdraw".as_ref(),
        "o.npy".as_ref(),
    ];
    all.extend(args.iter().map(OsStr::new));
    let stderr = run_ok(&dir.0, &all);
    let image = read_png(&dir.path("c.png"));
    assert_eq!((image.width, image.height), (W, H));
    let (ids, depth, overdraw) =
        (read_npy(&dir.path("i.npy")), read_npy(&dir.path("d.npy")), read_npy(&dir.path("o.npy")));
    ids.check("<i4", H, W);
    depth.check("<f4", H, W);
    overdraw.check("<u4", H, W);
    Rendered { image, ids: ids.i32s(), depth: depth.f32s(), overdraw: overdraw.u32s(), stderr }
}

fn idx(x: usize, y: usize) -> usize {
    y * W + x
}

const BLACK: [u8; 4] = [0, 0, 0, 255];
const WHITE: [u8; 4] = [255, 255, 255, 255];

// ---------------------------------------------------------------------------------------------
// Rendering to PNG and .npy
// ---------------------------------------------------------------------------------------------

/// Quad A: (4,4)-(28,20) at z = 0.25, two explicit triangles split along (4,4)-(28,20), the
/// first with red, green, blue vertices. Quad B: (36,24)-(60,44) at z = 0.5, one `f` with four
/// corners (fanned into triangles 2 and 3 along (36,24)-(60,44)), no colours (white).
const QUADS: &str = "\
# quad A: two triangles
v 4 4 0.25 1 0 0
v 28 4 0.25 0 1 0
v 28 20 0.25 0 0 1
v 4 20 0.25 1 1 1
f 1 2 3
f 1 3 4
# quad B: one face of four corners
v 36 24 0.5
v 60 24 0.5
v 60 44 0.5
v 36 44 0.5
f 5 6 7 8
";

/// Which side of the diagonal `a -> c` the centre of pixel (x, y) lies on, exactly (all
/// coordinates doubled so that pixel centres are integers): < 0 above-right, > 0 below-left.
fn side(a: (i64, i64), c: (i64, i64), x: usize, y: usize) -> i64 {
    let (px, py) = (2 * x as i64 + 1, 2 * y as i64 + 1);
    (c.0 - a.0) * (py - 2 * a.1) - (c.1 - a.1) * (px - 2 * a.0)
}

#[test]
fn render_writes_png_and_npy_buffers_that_match_the_mesh() {
    let dir = TempDir::new("quads");
    let r = render_obj(&dir, QUADS, &[]);
    assert!(r.stderr.contains("4 triangles"), "stderr: {}", r.stderr);

    // Every pixel: which quad contains its centre (quad edges are on integer coordinates, so no
    // centre is ever on one), and within a quad which fan triangle.
    let quads = [((4, 4), (28, 20), 0.25f32, [0, 1]), ((36, 24), (60, 44), 0.5, [2, 3])];
    let mut counted = [0usize; 4];
    for y in 0..H {
        for x in 0..W {
            let i = idx(x, y);
            let (cx, cy) = (x as f64 + 0.5, y as f64 + 0.5);
            let inside = quads.iter().find(|(a, c, _, _)| {
                (a.0 as f64) < cx && cx < c.0 as f64 && (a.1 as f64) < cy && cy < c.1 as f64
            });
            match inside {
                None => {
                    assert_eq!(r.ids[i], -1, "id at ({x}, {y})");
                    assert_eq!(r.overdraw[i], 0, "overdraw at ({x}, {y})");
                    assert_eq!(r.depth[i], 1.0, "depth at ({x}, {y})");
                    assert_eq!(r.image.at(x, y), BLACK, "colour at ({x}, {y})");
                }
                Some(&(a, c, z, [upper, lower])) => {
                    // A tiled quad: exactly one fragment per pixel, diagonal included.
                    assert_eq!(r.overdraw[i], 1, "overdraw at ({x}, {y})");
                    assert_eq!(r.depth[i], z, "depth at ({x}, {y})");
                    let s = side(a, c, x, y);
                    let id = r.ids[i];
                    match s.signum() {
                        -1 => assert_eq!(id, upper, "id at ({x}, {y})"),
                        1 => assert_eq!(id, lower, "id at ({x}, {y})"),
                        _ => assert!(id == upper || id == lower, "id {id} at ({x}, {y})"),
                    }
                    counted[id as usize] += 1;
                }
            }
        }
    }
    // Each triangle covers about half its quad (24x16 / 2 = 192, 24x20 / 2 = 240).
    for (t, (&n, expected)) in counted.iter().zip([192, 192, 240, 240]).enumerate() {
        assert!(n.abs_diff(expected) <= 24, "triangle {t} covers {n} pixels");
    }

    // Spot checks at centres clearly inside each triangle.
    for (x, y, id) in [(24, 6, 0), (6, 18, 1), (56, 26, 2), (38, 42, 3)] {
        assert_eq!(r.ids[idx(x, y)], id, "id at ({x}, {y})");
    }

    // Colours: quad B has no vertex colours, so it is white; triangle 1 is (red, blue, white)
    // and triangle 0 is (red, green, blue), smoothly interpolated.
    assert_eq!(r.image.at(50, 30), WHITE);
    let bary = |p: (f64, f64), v: [(f64, f64); 3]| -> [f64; 3] {
        let area = |a: (f64, f64), b: (f64, f64), c: (f64, f64)| {
            (b.0 - a.0) * (c.1 - a.1) - (c.0 - a.0) * (b.1 - a.1)
        };
        let total = area(v[0], v[1], v[2]);
        [area(p, v[1], v[2]) / total, area(v[0], p, v[2]) / total, area(v[0], v[1], p) / total]
    };
    let w = bary((24.5, 6.5), [(4.0, 4.0), (28.0, 4.0), (28.0, 20.0)]);
    let expected = [255.0 * w[0], 255.0 * w[1], 255.0 * w[2]];
    let got = r.image.at(24, 6);
    for c in 0..3 {
        assert!(
            (f64::from(got[c]) - expected[c]).abs() <= 1.0,
            "channel {c} at (24, 6): got {got:?}, expected about {expected:?}"
        );
    }
    assert_eq!(got[3], 255);
}

#[test]
fn npy_files_load_in_numpy() {
    let has_numpy = Command::new("python3")
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_numpy {
        eprintln!("skipping npy_files_load_in_numpy: python3 with numpy is not available");
        return;
    }
    let dir = TempDir::new("numpy");
    render_obj(&dir, QUADS, &[]);
    let script = "\
import numpy as np
i = np.load('i.npy'); d = np.load('d.npy'); o = np.load('o.npy')
for name, a in (('ids', i), ('depth', d), ('overdraw', o)):
    print(name, a.shape, a.dtype.str)
print('values', int(i[6, 24]), int(i[42, 38]), int(i[0, 0]), float(d[6, 24]), float(d[0, 0]), \
int(o.sum()), int((i >= 0).sum()))
";
    let out = Command::new("python3").args(["-c", script]).current_dir(&dir.0).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "python failed: {}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines[0], "ids (48, 64) <i4");
    assert_eq!(lines[1], "depth (48, 64) <f4");
    assert_eq!(lines[2], "overdraw (48, 64) <u4");
    // Row-major (H, W) indexing: [y, x]. Quads cover 24*16 + 24*20 = 864 pixels, once each.
    assert_eq!(lines[3], "values 0 3 -1 0.25 1.0 864 864");
}

/// A deterministic 64-bit LCG (Knuth's MMIX constants).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        self.0 >> 11
    }

    /// Uniform in `[0, n)`.
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

#[test]
fn scanline_and_edge_algorithms_write_identical_files() {
    // ~200 triangles, partly off-screen, coordinates on a 1/8-pixel grid so that many vertices
    // and edges pass exactly through pixel centres (the tie cases), plus a shared-edge fan.
    let mut rng = Lcg(0x5eed_1234_abcd_0001);
    let mut obj = String::new();
    let coord = |rng: &mut Lcg, extent: u64| (rng.below((extent + 40) * 8) as f64) / 8.0 - 20.0;
    for _ in 0..200 {
        for _ in 0..3 {
            let (x, y) = (coord(&mut rng, W as u64), coord(&mut rng, H as u64));
            let z = 0.1 + rng.below(900) as f64 / 1000.0;
            let (r, g, b) = (rng.below(256), rng.below(256), rng.below(256));
            let (r, g, b) = (r as f64 / 255.0, g as f64 / 255.0, b as f64 / 255.0);
            writeln!(obj, "v {x} {y} {z} {r:.6} {g:.6} {b:.6}").unwrap();
        }
        obj.push_str("f -3 -2 -1\n");
    }
    // A fan of 12 around (32.5, 24.5), nearer than the soup (z >= 0.1): every pixel near the
    // centre is owned exactly once.
    writeln!(obj, "v 32.5 24.5 0.05").unwrap();
    for k in 0..12 {
        let a = std::f64::consts::TAU * f64::from(k) / 12.0;
        writeln!(obj, "v {:.3} {:.3} 0.05", 32.5 + 15.0 * a.cos(), 24.5 + 15.0 * a.sin()).unwrap();
    }
    let hub = 601;
    for k in 0..12 {
        writeln!(obj, "f {hub} {} {}", hub + 1 + k, hub + 1 + (k + 1) % 12).unwrap();
    }

    let mut outputs = Vec::new();
    for algorithm in ["edge", "scanline"] {
        let dir = TempDir::new(&format!("alg-{algorithm}"));
        let r = render_obj(&dir, &obj, &["--algorithm", algorithm]);
        let files: Vec<Vec<u8>> = ["i.npy", "d.npy", "o.npy", "c.png"]
            .iter()
            .map(|f| fs::read(dir.path(f)).unwrap())
            .collect();
        // Not a trivial picture: many triangles visible, the fan's hub owned once.
        let mut visible: Vec<i32> = r.ids.iter().copied().filter(|&i| i >= 0).collect();
        visible.sort_unstable();
        visible.dedup();
        assert!(visible.len() > 50, "only {} triangles visible", visible.len());
        assert!(r.overdraw.iter().any(|&o| o > 3), "soup should overlap");
        assert!((200..212).contains(&r.ids[idx(32, 24)]), "the fan is in front at its hub");
        outputs.push((files, r.stderr));
    }
    let (edge, scan) = (&outputs[0].0, &outputs[1].0);
    for (k, name) in ["ids", "depth", "overdraw", "colour png"].iter().enumerate() {
        assert!(edge[k] == scan[k], "{name} differs between edge and scanline");
    }
    // Same statistics line (rasterized / degenerate / fragments) on stderr too.
    let stats = |s: &str| s.lines().find(|l| l.contains("fragments")).unwrap_or("").to_string();
    assert_eq!(stats(&outputs[0].1), stats(&outputs[1].1));
}

// ---------------------------------------------------------------------------------------------
// Depth test, culling, flat shading
// ---------------------------------------------------------------------------------------------

/// Two overlapping triangles, both covering pixel (20, 20): first at depth `z0`, then `z1`.
fn overlapping(z0: f32, z1: f32) -> String {
    format!(
        "v 4 4 {z0} 1 0 0\nv 40 4 {z0} 1 0 0\nv 4 40 {z0} 1 0 0\nf 1 2 3\n\
         v 10 10 {z1} 0 0 1\nv 44 10 {z1} 0 0 1\nv 10 44 {z1} 0 0 1\nf 4 5 6\n"
    )
}

#[test]
fn depth_test_always_lets_the_last_triangle_win_and_less_the_nearest() {
    const RED: [u8; 4] = [255, 0, 0, 255];
    const BLUE: [u8; 4] = [0, 0, 255, 255];
    let p = idx(20, 20);
    let dir = TempDir::new("depth");
    // Nearer triangle first.
    let obj = overlapping(0.2, 0.6);
    let less = render_obj(&dir, &obj, &["--depth-test", "less"]);
    assert_eq!((less.ids[p], less.depth[p], less.image.at(20, 20)), (0, 0.2, RED));
    assert_eq!(less.overdraw[p], 2, "both fragments are counted before the depth test");
    let always = render_obj(&dir, &obj, &["--depth-test", "always"]);
    assert_eq!((always.ids[p], always.depth[p], always.image.at(20, 20)), (1, 0.6, BLUE));
    assert_eq!(always.overdraw[p], 2);
    // Nearer triangle last: both tests keep it.
    let obj = overlapping(0.6, 0.2);
    for test in ["less", "always", "less-equal"] {
        let r = render_obj(&dir, &obj, &["--depth-test", test]);
        assert_eq!((r.ids[p], r.depth[p]), (1, 0.2), "--depth-test {test}");
    }
    // Equal depths: `less` keeps the first, `less-equal` and `always` the last.
    let obj = overlapping(0.4, 0.4);
    for (test, id) in [("less", 0), ("less-equal", 1), ("always", 1)] {
        let r = render_obj(&dir, &obj, &["--depth-test", test]);
        assert_eq!(r.ids[p], id, "--depth-test {test} at equal depth");
    }
    // Pixels covered by one triangle only are unaffected by the choice.
    assert_eq!(less.ids[idx(6, 6)], 0);
    assert_eq!(always.ids[idx(6, 6)], 0);
    assert_eq!(less.ids[idx(40, 12)], 1);
    assert!(!less.stderr.contains("outside [0, 1]"), "{}", less.stderr);
    // Depths outside [0, 1] are stored clamped, and said to be.
    let r = render_obj(&dir, &overlapping(-0.5, 2.0), &[]);
    assert_eq!((r.ids[p], r.depth[p]), (0, 0.0));
    assert!(r.stderr.contains("6 vertices have z outside [0, 1]"), "{}", r.stderr);
}

#[test]
fn cull_removes_the_triangles_of_the_named_screen_winding() {
    // Triangle 0 goes (2,2) -> (22,2) -> (2,22): right, then down-left: clockwise on a y-down
    // image. Triangle 1 goes (30,2) -> (30,22) -> (50,2): down, then up-right: counter-clockwise.
    let obj = "v 2 2 0.5\nv 22 2 0.5\nv 2 22 0.5\nf 1 2 3\n\
               v 30 2 0.5\nv 30 22 0.5\nv 50 2 0.5\nf 4 5 6\n";
    let (in_cw, in_ccw) = (idx(6, 6), idx(34, 6));
    let dir = TempDir::new("cull");
    for (mode, cw_id, ccw_id) in [("none", 0, 1), ("cw", -1, 1), ("ccw", 0, -1)] {
        let r = render_obj(&dir, obj, &["--cull", mode]);
        assert_eq!((r.ids[in_cw], r.ids[in_ccw]), (cw_id, ccw_id), "--cull {mode}");
        // A culled triangle produces no fragments at all.
        let culled = r.overdraw.iter().filter(|&&o| o > 0).count();
        let drawn = r.ids.iter().filter(|&&i| i >= 0).count();
        assert_eq!(culled, drawn, "--cull {mode}: overdraw only where something was drawn");
        let expected_culled = if mode == "none" { "0 culled" } else { "1 culled" };
        assert!(r.stderr.contains(expected_culled), "--cull {mode}: {}", r.stderr);
    }
}

#[test]
fn flat_shading_uses_the_rounded_average_colour() {
    // Vertex colours given as k / 255, so each converts back to exactly k.
    let colors: [[u32; 3]; 3] = [[255, 0, 200], [255, 0, 17], [254, 1, 1]];
    let mut obj = String::new();
    for ((x, y), c) in [(4, 4), (60, 10), (12, 44)].iter().zip(colors) {
        let [r, g, b] = c.map(|k| f64::from(k) / 255.0);
        writeln!(obj, "v {x} {y} 0.5 {r:.9} {g:.9} {b:.9}").unwrap();
    }
    obj.push_str("f 1 2 3\n");
    let expected: [u8; 3] = std::array::from_fn(|ch| {
        let sum: u32 = colors.iter().map(|c| c[ch]).sum();
        ((2 * sum + 3) / 6) as u8
    });
    // Sums 764, 1, 218: averages 254.67, 0.33, 72.67 round to 255, 0, 73.
    assert_eq!(expected, [255, 0, 73]);
    let dir = TempDir::new("flat");
    let r = render_obj(&dir, &obj, &["--shading", "flat"]);
    let mut covered = 0;
    for y in 0..H {
        for x in 0..W {
            if r.ids[idx(x, y)] == 0 {
                covered += 1;
                let c = r.image.at(x, y);
                assert_eq!(c, [expected[0], expected[1], expected[2], 255], "at ({x}, {y})");
            }
        }
    }
    assert!(covered > 500, "the triangle covers {covered} pixels");
    // Smooth shading of the same triangle is not one colour.
    let smooth = render_obj(&dir, &obj, &["--shading", "smooth"]);
    assert!(smooth.image.distinct_colors() > 10);
    assert_eq!(smooth.ids, r.ids, "shading does not change coverage");
}

// ---------------------------------------------------------------------------------------------
// Errors and odd input
// ---------------------------------------------------------------------------------------------

/// `render FILE -o out.png`, with `--projection PROJECTION` when one is given.
fn render_file_args(file: &Path, projection: Option<&str>) -> Vec<OsString> {
    let mut args: Vec<OsString> = vec!["render".into(), file.into(), "-o".into(), "out.png".into()];
    if let Some(p) = projection {
        args.extend(["--projection".into(), p.into()]);
    }
    args
}

/// The default projection (3D) and the window projection read OBJ files alike.
const PROJECTIONS: [Option<&str>; 2] = [None, Some("window")];

#[test]
fn malformed_obj_names_the_file_and_line() {
    let dir = TempDir::new("malformed");
    let obj = dir.write("broken.obj", "# header\nv 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n");
    for projection in PROJECTIONS {
        let err = run_err(&dir.0, render_file_args(&obj, projection));
        assert!(err.contains("broken.obj:3:"), "{projection:?}: {err}");
        assert!(err.contains("`x`"), "{projection:?}: {err}");
        assert!(!dir.path("out.png").exists(), "no image is written on error");
    }
}

/// A message quoting a file's bytes escapes their control characters: an escape sequence in a
/// malformed line had reached the terminal as it was.
#[test]
fn quoted_control_characters_are_escaped() {
    let dir = TempDir::new("control");
    dir.write("ansi.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \u{1b}[31mRED\u{7}\n");
    let err = run_err(&dir.0, ["info", "ansi.obj"]);
    assert!(err.contains("ansi.obj:4:") && err.contains(r"`\u{1b}[31mRED\u{7}`"), "{err}");
    assert!(!err.contains('\u{1b}') && !err.contains('\u{7}'), "{err:?}");
    // File names too, wherever they are printed: `info`'s `file:` line (standard output) and
    // `render`'s `wrote` line had printed them raw.
    let name = "tri\u{1b}[31m.obj";
    dir.write(name, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    let out = trirast_in(&dir.0, ["info", name]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains(r"tri\u{1b}[31m.obj"), "{text}");
    let err = run_ok(&dir.0, ["render", name, "--size", "8x8", "-o", "a\u{7}.png"]);
    assert!(err.contains(r"wrote a\u{7}.png"), "{err}");
    for printed in [&text[..], &err] {
        assert!(!printed.contains('\u{1b}') && !printed.contains('\u{7}'), "{printed:?}");
    }
}

/// Negative values reach the checks of their options, which say what is accepted; clap had
/// taken `-30` in `--fov -30` for an unknown option.
#[test]
fn negative_values_are_checked_as_values() {
    let dir = TempDir::new("negative");
    for (args, says) in [
        (&["render", "--fov", "-30"][..], "--fov takes 1 to 170 degrees"),
        (&["render", "--background", "-1,0,0"][..], "colour components are whole numbers"),
        (&["render", "--size", "-5x10"][..], "expected WIDTHxHEIGHT"),
        (&["demo", "--size", "10x10x10"][..], "found `10x10x10`"),
        (&["sample", "m.obj", "--points", "-1"][..], "--points takes 1 to"),
    ] {
        let err = run_err(&dir.0, args);
        assert!(err.contains(says) && !err.contains("unexpected argument"), "{args:?}: {err}");
    }
}

#[test]
fn face_index_past_the_end_is_an_error() {
    let dir = TempDir::new("past-end");
    let short = dir.write("short.obj", "v 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\nf 1 2 4\n");
    // The largest index that fits in 32 bits once overflowed while formatting this message.
    let huge = dir.write("huge.obj", "v 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 4294967296\n");
    for projection in PROJECTIONS {
        let err = run_err(&dir.0, render_file_args(&short, projection));
        assert!(err.contains("short.obj:5:"), "{projection:?}: {err}");
        assert!(err.contains("index 4 "), "{projection:?}: {err}");
        let err = run_err(&dir.0, render_file_args(&huge, projection));
        assert!(err.contains("huge.obj:4:"), "{projection:?}: {err}");
        assert!(err.contains("index 4294967296"), "{projection:?}: {err}");
        assert!(!dir.path("out.png").exists());
    }
}

#[test]
fn unsupported_sizes_are_rejected() {
    let dir = TempDir::new("sizes");
    for size in ["0x10", "10x0", "20000x10", "10x16385"] {
        let err = run_err(&dir.0, ["render", "--size", size, "-o", "out.png"]);
        assert!(err.contains(size), "--size {size}: {err}");
        assert!(err.contains("16384"), "--size {size} should state the limit: {err}");
    }
    for size in ["abc", "64", "64x", "x48", "-5x10", "64x48x2"] {
        // `--size=VALUE` so that "-5x10" is a value, not a flag.
        let arg = format!("--size={size}");
        let err = run_err(&dir.0, ["render", &arg, "-o", "out.png"]);
        assert!(err.contains("size"), "--size {size}: {err}");
    }
    assert!(!dir.path("out.png").exists());
    // The limit itself is accepted (one row keeps it cheap).
    run_ok(&dir.0, ["render", "--size", "16384x1", "-o", "wide.png"]);
    let img = read_png(&dir.path("wide.png"));
    assert_eq!((img.width, img.height), (16384, 1));
}

/// A vertex past the fixed-point range is clipped to the range, not refused: the
/// triangle from the origin to 40000 pixels along x and 10 down covers the image's top rows
/// (about 10 rows near the origin), with its id.
#[test]
fn vertex_outside_the_fixed_point_range_is_clipped() {
    let dir = TempDir::new("range");
    let r = render_obj(&dir, "v 0 0 0.5\nv 40000 0 0.5\nv 0 10 0.5\nf 1 2 3\n", &[]);
    assert!(r.stderr.contains("rasterized"), "{}", r.stderr);
    for y in 0..H {
        for x in 0..W {
            // Below the edge from (0, 10) to (40000, 0) or on it: not covered.
            let inside = (y as f64 + 0.5) < 10.0 - (x as f64 + 0.5) * 10.0 / 40000.0;
            assert_eq!(r.ids[y * W + x] == 0, inside, "pixel ({x}, {y})");
        }
    }
    // Just inside the range draws as before.
    let obj = dir.write("near.obj", "v -32768 0 0\nv 32767 0 0\nv 0 10 0\nf 1 2 3\n");
    let mut args = render_file_args(&obj, Some("window"));
    args.extend(["--size".into(), "8x8".into()]);
    run_ok(&dir.0, args);
}

#[test]
fn missing_file_is_an_error() {
    let dir = TempDir::new("missing");
    for projection in PROJECTIONS {
        let err = run_err(&dir.0, render_file_args(Path::new("no-such-mesh.obj"), projection));
        assert!(err.contains("no-such-mesh.obj"), "{projection:?}: {err}");
        let err = run_err(&dir.0, render_file_args(Path::new("gone.stl"), projection));
        assert!(err.contains("gone.stl"), "{projection:?}: {err}");
    }
    assert!(!dir.path("out.png").exists());
}

#[test]
fn nan_vertex_drops_its_triangle_with_a_warning() {
    let obj = "v nan 5 0.5\nv 20 5 0.5\nv 5 20 0.5\nf 1 2 3\n\
               v 30 30 0.5\nv 60 30 0.5\nv 30 45 0.5\nf 4 5 6\n";
    let dir = TempDir::new("nan");
    let r = render_obj(&dir, obj, &[]);
    assert!(r.stderr.contains("warning"), "{}", r.stderr);
    assert!(r.stderr.contains("dropped 1 triangle"), "{}", r.stderr);
    assert!(r.ids.iter().all(|&i| i == -1 || i == 1), "triangle 0 must not be drawn");
    assert_eq!(r.ids[idx(35, 33)], 1, "the finite triangle is still drawn");
}

// ---------------------------------------------------------------------------------------------
// Built-in scenes
// ---------------------------------------------------------------------------------------------

#[test]
fn render_without_a_file_draws_the_default_scene() {
    let dir = TempDir::new("default");
    // Everything at its default: writes trirast.png in the working directory.
    run_ok(&dir.0, ["render"]);
    let img = read_png(&dir.path("trirast.png"));
    assert!(img.width > 0 && img.height > 0);
    assert!(img.distinct_colors() > 100, "a shaded model has many colours");
    // An explicit size is honoured.
    run_ok(&dir.0, ["render", "--size", "96x40", "-o", "small.png"]);
    let img = read_png(&dir.path("small.png"));
    assert_eq!((img.width, img.height), (96, 40));
    assert!(img.distinct_colors() > 10);
    // The window projection's built-in scene: a colour wheel on black.
    run_ok(&dir.0, ["render", "--projection", "window", "--size", "128x96", "-o", "wheel.png"]);
    let img = read_png(&dir.path("wheel.png"));
    assert_eq!((img.width, img.height), (128, 96));
    assert!(img.distinct_colors() > 100, "a colour wheel has many colours");
    assert_eq!(img.at(0, 0), BLACK, "the corner is background");
    assert_ne!(img.at(64, 48), BLACK, "the centre is drawn");
}

#[test]
fn demos_write_pngs() {
    let dir = TempDir::new("demo");
    for which in ["flat", "smooth", "soup"] {
        let name = format!("{which}.png");
        run_ok(&dir.0, ["demo", which, "-o", &name, "--size", "128x96"]);
        let img = read_png(&dir.path(&name));
        assert_eq!((img.width, img.height), (128, 96), "demo {which}");
        assert!(img.distinct_colors() > 2, "demo {which} is not blank");
    }
    // Both algorithms draw the same demo.
    run_ok(&dir.0, ["demo", "soup", "-o", "edge.png", "--size", "128x96", "--algorithm", "edge"]);
    run_ok(
        &dir.0,
        ["demo", "soup", "-o", "scan.png", "--size", "128x96", "--algorithm", "scanline"],
    );
    assert!(read_png(&dir.path("edge.png")).rgba == read_png(&dir.path("scan.png")).rgba);
    // With no arguments at all: the smooth demo into demo.png at 512x512.
    run_ok(&dir.0, ["demo"]);
    let img = read_png(&dir.path("demo.png"));
    assert_eq!((img.width, img.height), (512, 512));
}

/// `trirast bench --json` reports each scene with the SIMD level and schedule it ran at and its
/// peak memory, and the work it measures does not depend on the level: forcing the scalar
/// kernels reports the same triangles and fragments.
#[test]
fn bench_reports_its_simd_level_and_the_same_work_at_every_level() {
    let dir = TempDir::new("bench");
    let field = |line: &str, name: &str| -> String {
        let at = line.find(&format!("\"{name}\":")).unwrap_or_else(|| panic!("{name}: {line}"));
        let rest = &line[at + name.len() + 3..];
        rest[..rest.find([',', '}']).unwrap()].trim_matches('"').to_string()
    };
    let run = |simd: Option<&str>| {
        let args = ["bench", "fill", "--frames", "1", "--threads", "2", "--json"];
        let out = trirast_with_env(&dir.0, args, simd.map_or(("", ""), |l| ("TRIRAST_SIMD", l)));
        assert!(out.status.success(), "bench failed: {}", stderr_of(&out));
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    let (default, scalar) = (run(None), run(Some("scalar")));
    assert_eq!(field(&scalar, "simd"), "Scalar");
    assert!(["Scalar", "Avx2", "Avx512"].contains(&field(&default, "simd").as_str()));
    for name in ["scene", "triangles", "pixels", "fragments", "msaa"] {
        assert_eq!(field(&default, name), field(&scalar, name), "{name}");
    }
    assert_eq!(field(&default, "triangles"), "256");
    // The fill scene's 256 large triangles are binned (too few to sample for bands).
    assert_eq!(field(&default, "schedule"), "binned");
    assert!(field(&default, "median_ms").parse::<f64>().unwrap() > 0.0);
    // Peak memory, where Linux's /proc tells it: at least the 3840 x 2160 target's colour and
    // depth (8 bytes a pixel), which the frames wrote, and less than this machine could hold.
    let peak = field(&default, "peak_memory_mb");
    if cfg!(target_os = "linux") {
        let mb: f64 = peak.parse().unwrap_or_else(|_| panic!("peak memory {peak}"));
        assert!((3840.0 * 2160.0 * 8.0 / 1e6..100_000.0).contains(&mb), "peak memory {mb} MB");
    } else {
        assert!(peak == "null" || peak.parse::<f64>().is_ok(), "peak memory {peak}");
    }
}

/// `trirast bench --export` writes the triangles it times, for another renderer to draw: the
/// fill scene's exported window triangles, drawn again through the library, give the
/// fragments `bench` counts; indexed scenes export in-range indices, normals beside positions
/// and their matrices; a missing directory is a usage error.
#[test]
fn bench_export_writes_the_scenes_it_times() {
    let dir = TempDir::new("bench-export");
    let out = dir.path("out");
    fs::create_dir(&out).unwrap();
    let args = ["bench", "fill", "bunny", "dense", "--dense-triangles", "2000", "--export"];
    let stdout = |args: Vec<&OsStr>| {
        let output = trirast_in(&dir.0, args);
        assert!(output.status.success(), "trirast failed: {}", stderr_of(&output));
        String::from_utf8(output.stdout).unwrap()
    };
    let listed = stdout(args.iter().map(OsStr::new).chain([out.as_os_str()]).collect());
    assert!(listed.contains("fill.json") && listed.contains("dense.json"), "{listed}");
    let json = |scene: &str| fs::read_to_string(out.join(format!("{scene}.json"))).unwrap();
    let npy = |name: &str| read_npy(&out.join(format!("{name}.npy")));

    // Fill: three rows (x, y, z) and three colours per triangle.
    assert!(json("fill").contains("\"width\":3840,\"height\":2160,\"kind\":\"window\""));
    // What is culled is exported: the 3D scenes cull back faces as `Pipeline` does by default.
    assert!(json("fill").contains("\"cull\":\"none\""));
    assert!(
        json("bunny").contains("\"cull\":\"back\"") && json("dense").contains("\"cull\":\"back\"")
    );
    let (positions, colors) = (npy("fill_positions"), npy("fill_colors"));
    assert_eq!((positions.descr.as_str(), positions.shape.as_slice()), ("<f4", &[768, 3][..]));
    assert_eq!((colors.descr.as_str(), colors.shape.as_slice()), ("|u1", &[768, 4][..]));
    let xyz: Vec<f32> =
        positions.data.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    let vertex = |i: usize| {
        let (p, c) = (&xyz[3 * i..3 * i + 3], &colors.data[4 * i..4 * i + 4]);
        trirast::Vertex::new(p[0], p[1], p[2], c.try_into().unwrap())
    };
    let triangles: Vec<[trirast::Vertex; 3]> =
        (0..256).map(|t| [vertex(3 * t), vertex(3 * t + 1), vertex(3 * t + 2)]).collect();
    let mut target = trirast::Target::new(3840, 2160).unwrap();
    let options = trirast::RenderOptions::default().with_shading(trirast::Shading::Smooth);
    let drawn = trirast::draw(&mut target, &triangles, &options).unwrap();
    let timed = stdout(["bench", "fill", "--frames", "1", "--json"].map(OsStr::new).to_vec());
    assert!(timed.contains(&format!("\"fragments\":{},", drawn.fragments)), "{timed}");

    // Indexed scenes: indices within the positions, one normal per position.
    for (scene, columns) in [("bunny", 3), ("dense", 3)] {
        let positions = npy(&format!("{scene}_positions"));
        let indices = npy(&format!("{scene}_indices"));
        assert_eq!(positions.shape[1], columns);
        assert_eq!((indices.descr.as_str(), indices.shape[1]), ("<u4", 3));
        assert!(indices.u32s().iter().all(|&i| (i as usize) < positions.shape[0]), "{scene}");
    }
    let timed = stdout(["bench", "bunny", "--frames", "1", "--json"].map(OsStr::new).to_vec());
    let triangles = npy("bunny_indices").shape[0];
    assert!(timed.contains(&format!("\"triangles\":{triangles},")), "{timed}");
    assert_eq!(npy("bunny_normals").shape, npy("bunny_positions").shape);
    assert!(
        json("bunny").contains("\"kind\":\"lit\"") && json("bunny").contains("\"view_proj\":[")
    );
    let dense = json("dense");
    let matrix = dense.split("\"view_proj\":[").nth(1).and_then(|m| m.split(']').next());
    assert_eq!(matrix.map(|m| m.split(',').count()), Some(16), "{dense}");
    assert!(npy("dense_indices").shape[0] > 0);

    let err = run_err(&dir.0, ["bench", "fill", "--export", "no/such/dir"]);
    assert!(err.contains("--export no/such/dir: no such directory"), "{err}");
    // A file there is not said to be missing.
    dir.write("file", "");
    let err = run_err(&dir.0, ["bench", "fill", "--export", "file"]);
    assert!(err.contains("--export file: not a directory"), "{err}");
    let err = run_err(&dir.0, ["bench", "fill", "--json", "--export", "."]);
    assert!(err.contains("--export"), "{err}");
}

/// Thread counts that cannot be honoured are usage errors, not a silent default or an abort:
/// `--threads 0` (which rayon would take as "all cores" while the table printed 0), and counts
/// too large to start (a hundred thousand threads cannot get their stacks, and a thread that
/// fails to start aborts the process), on the command line or in `RAYON_NUM_THREADS`.
#[test]
fn impossible_thread_counts_are_usage_errors() {
    let dir = TempDir::new("threads");
    for command in ["bench", "splat-bench"] {
        for threads in ["0", "100000", "many"] {
            let err = run_err(&dir.0, [command, "--threads", threads, "--frames", "1"]);
            assert!(err.contains("--threads"), "{command} --threads {threads}: {err}");
        }
    }
    let out =
        trirast_with_env(&dir.0, ["render", "-o", "out.png"], ("RAYON_NUM_THREADS", "100000"));
    let err = stderr_of(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("RAYON_NUM_THREADS=100000"), "{err}");
    assert!(!dir.path("out.png").exists(), "nothing is rendered");
    // What rayon takes as "all cores" (0, not a number) still runs, the second with a word.
    for value in ["0", "lots"] {
        let args = ["render", "--size", "64x48", "-o", "out.png"];
        let out = trirast_with_env(&dir.0, args, ("RAYON_NUM_THREADS", value));
        let err = stderr_of(&out);
        assert!(out.status.success(), "RAYON_NUM_THREADS={value}: {err}");
        assert_eq!(err.contains("not a number of threads; using all cores"), value == "lots");
    }
    // The comparison switches refuse what they do not know (they ignored it, so a comparison
    // measured the default twice) and take what they do.
    let args = ["render", "--size", "64x48", "-o", "switch.png"];
    dir.write("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    for switch in [("TRIRAST_SIMD", "avx1024"), ("TRIRAST_SCHEDULE", "tiled")] {
        let out = trirast_with_env(&dir.0, args, switch);
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(1), "{switch:?}: {err}");
        assert!(err.contains(&format!("{}={}", switch.0, switch.1)), "{err}");
        assert!(!dir.path("switch.png").exists(), "nothing is rendered");
        // A command that draws nothing runs whatever they say.
        let out = trirast_with_env(&dir.0, ["info", "tri.obj"], switch);
        assert!(out.status.success(), "info with {switch:?}: {}", stderr_of(&out));
    }
    let known = [("TRIRAST_SIMD", "scalar"), ("TRIRAST_SCHEDULE", "banded")];
    for switch in known.into_iter().chain([("TRIRAST_SCHEDULE", "auto"), ("TRIRAST_SIMD", "")]) {
        let out = trirast_with_env(&dir.0, args, switch);
        assert!(out.status.success(), "{switch:?}: {}", stderr_of(&out));
    }
}

/// Counts and angles that cannot be meant are usage errors naming the option, not an abort,
/// a panic or a silent clamp: frames and points by the billion (whose allocations aborted the
/// process, or overflowed), zero points (a panic reading the empty hierarchy's root), a dense
/// scene past a billion triangles, and a field of view that is NaN (a blank image) or out of
/// 1 to 170 degrees (clamped without a word).
#[test]
fn absurd_counts_and_angles_are_usage_errors() {
    let dir = TempDir::new("absurd");
    let huge = "18446744073709551615";
    let cases: [(&[&str], &str); 12] = [
        (&["bench", "fill", "--frames", huge], "--frames"),
        (&["sample", "mesh.obj", "--seed", "-1"], "--seed takes a whole number from 0"),
        (&["bench", "fill", "--frames", "0"], "--frames"),
        (&["bench", "dense", "--dense-triangles", "10000000000"], "--dense-triangles"),
        (&["splat-bench", "--points", "0"], "--points"),
        (&["splat-bench", "--points", huge], "--points"),
        (&["splat-bench", "--frames", huge], "--frames"),
        (&["sample", "mesh.obj", "--points", "1000000000000"], "--points"),
        (&["render", "--frames", huge, "-o", "out.png"], "--frames"),
        (&["render", "--fov", "nan", "-o", "out.png"], "--fov"),
        (&["render", "--fov", "0", "-o", "out.png"], "--fov"),
        (&["render", "--fov", "inf", "-o", "out.png"], "--fov"),
    ];
    for (args, option) in cases {
        let err = run_err(&dir.0, args);
        assert!(err.contains(option), "{args:?}: {err}");
    }
    assert!(!dir.path("out.png").exists());
    // The library's splat benchmark reports an empty cloud instead of panicking.
    assert!(trirast::bench::run_splats(0, 1).is_err());
}

/// Runs trirast in `dir` under an address-space limit of `kib` KiB (`ulimit -v`), which its
/// memory checks read, so that what they refuse does not depend on the machine's memory.
fn trirast_limited(dir: &Path, kib: u32, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_trirast"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("failed to start sh")
}

/// The benchmarks that build what a count asks for refuse, before they start, a count the
/// memory left cannot hold: `splat-bench --points 1073741824` (2^30, allowed) had grown to
/// 24 GB and been stopped by the system's out-of-memory killer without a word. Run under an
/// address-space limit of 4 GB, which the check reads, so the refusal does not depend on the
/// machine's memory.
#[test]
fn benchmarks_too_large_for_memory_are_refused_up_front() {
    let dir = TempDir::new("bench-memory");
    let cases: [(&[&str], &str); 2] = [
        (&["splat-bench", "--points", "1073741824", "--frames", "1"], "the splat benchmark of"),
        (
            &["bench", "dense", "--dense-triangles", "1000000000", "--frames", "1"],
            "the dense scene",
        ),
    ];
    for (args, what) in cases {
        let out = trirast_limited(&dir.0, 4_000_000, args);
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(what) && err.contains("GiB is available"), "{args:?}: {err}");
    }
}

/// Textures are refused, before any is decoded, when loading them needs more memory than is
/// left (`LOAD_BYTES_PER_TEXEL` a texel, from their headers): a 260 KB PNG of 16384 x 4096
/// texels, within the size limits, had aborted the process under a 2 GB address space limit.
/// The files here hold only a header, so the refusal is all that can pass: one they let
/// through would fail to decode.
#[test]
fn textures_too_large_for_memory_are_refused_up_front() {
    let dir = TempDir::new("texture-memory");
    let mut encoder =
        png::Encoder::new(fs::File::create(dir.path("big.png")).unwrap(), 16384, 4096);
    encoder.set_color(png::ColorType::Rgba);
    let mut writer = encoder.write_header().unwrap();
    writer.write_chunk(png::chunk::IDAT, &[0x78, 0x01]).unwrap();
    drop(writer);
    let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n";
    dir.write("uv.obj", triangle);
    dir.write("m.mtl", "newmtl a\nmap_Kd big.png\n");
    dir.write("material.obj", &format!("mtllib m.mtl\nusemtl a\n{triangle}"));
    let cases: [&[&str]; 3] = [
        &["render", "uv.obj", "--texture", "big.png", "--size", "8x8", "-o", "a.png"],
        &["render", "material.obj", "--size", "8x8", "-o", "a.png"],
        &["sample", "material.obj", "--points", "10", "-o", "c.ply"],
    ];
    for args in cases {
        let out = trirast_limited(&dir.0, 1_500_000, args);
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        let refused = "loading the texture big.png needs 1.82 GiB of memory";
        assert!(err.contains(refused) && err.contains("GiB is available"), "{args:?}: {err}");
        assert!(!dir.path("a.png").exists() && !dir.path("c.ply").exists());
    }
}

/// Output files are checked before anything is rendered: two options naming one file (the
/// second overwrote the first, which then held an `.npy` under a `.png` name), a missing
/// directory (found only after some files were written), an output that is a directory (a
/// turntable had written beside it) and one that cannot be made are usage errors, and
/// nothing is written.
#[test]
fn clashing_or_unreachable_outputs_are_refused_before_rendering() {
    let dir = TempDir::new("outputs");
    fs::create_dir(dir.path("sub")).unwrap();
    dir.write("file.txt", "not a directory");
    let cases: [&[&str]; 10] = [
        &["render", "--size", "64x48", "-o", "a.png", "--depth", "a.png"],
        &["demo", "-o", "a.jpg"],
        &["render", "--size", "64x48", "-o", "a.png", "--ids", "d.npy", "--overdraw", "./d.npy"],
        &["render", "--size", "64x48", "-o", "a.png", "--ids", "missing/ids.npy"],
        &["render", "--size", "64x48", "-o", "missing/a.png"],
        &["render", "--size", "64x48", "-o", "a.png", "--depth", "sub"],
        &["render", "--size", "64x48", "-o", "a.png", "--ids", "sub/"],
        &["render", "--size", "64x48", "--turntable", "3", "-o", "new/"],
        &["demo", "-o", "sub"],
        &["render", "--size", "64x48", "-o", "a.png", "--depth", "file.txt/d.npy"],
    ];
    for args in cases {
        let err = run_err(&dir.0, args);
        let refused =
            ["both name", "no directory", "is not a directory", "written as", "names a directory"];
        assert!(refused.iter().any(|r| err.contains(r)), "{args:?}: {err}");
        assert!(!dir.path("a.png").exists(), "{args:?}: nothing is written");
    }
    if Path::new("/proc/self").is_dir() {
        let args = ["render", "--size", "64x48", "-o", "a.png", "--depth", "/proc/d.npy"];
        let err = run_err(&dir.0, args);
        assert!(err.contains("--depth /proc/d.npy: cannot be written"), "{err}");
        assert!(!dir.path("a.png").exists());
    }
    assert!(!dir.path("new_000.png").exists());
    run_ok(&dir.0, ["render", "--size", "64x48", "-o", "a.png", "--depth", "a.npy"]);
    assert!(dir.path("a.png").exists() && dir.path("a.npy").exists());
}

/// An output that is the command's input, or another output reached by another path, is
/// refused before anything is written: `pack c.ply -o c.ply` replaced the cloud it read,
/// `render --texture t.png -o t.png` the texture, and `--ids x.npy --depth ../dir/x.npy` wrote
/// one file twice.
#[test]
fn outputs_that_are_inputs_or_each_other_are_refused() {
    let dir = TempDir::new("inputs");
    let cloud = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                 property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    let quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
                f 1/1 2/2 3/3 4/4\n";
    let with_material = format!("mtllib m.mtl\nusemtl tex\n{quad}");
    let files = [
        ("c.ply", cloud),
        ("m.obj", quad),
        ("q.obj", &with_material),
        ("m.mtl", "newmtl tex\nmap_Kd tex.png\n"),
    ];
    for (name, text) in files {
        dir.write(name, text);
    }
    run_ok(&dir.0, ["render", "--size", "8x8", "-o", "t.png"]);
    for copy in ["t_001.png", "tex.png"] {
        fs::copy(dir.path("t.png"), dir.path(copy)).unwrap();
    }
    run_ok(&dir.0, ["pack", "c.ply", "-o", "c.tsplat"]);
    let here = dir.0.file_name().unwrap().to_str().unwrap().to_string();
    let round_trip = format!("../{here}/x.npy");
    let inputs = ["c.tsplat", "m.obj", "t.png", "t_001.png", "tex.png", "m.mtl"];
    let cases: [(&[&str], &str); 9] = [
        (&["pack", "c.tsplat", "-o", "c.tsplat"], "is the input"),
        (&["pack", "c.tsplat", "-o", "./c.tsplat"], "is the input"),
        (&["sample", "m.obj", "-o", "./m.obj"], "is the input"),
        (
            &["render", "m.obj", "--texture", "t.png", "--size", "8x8", "-o", "t.png"],
            "is the input",
        ),
        (&["render", "--size", "8x8", "--ids", "x.npy", "--depth", &round_trip], "both name"),
        (&["sample", "m.obj", "-o", "m.png"], "written as .ply"),
        // A material's texture, and a turntable's numbered frames.
        (&["render", "q.obj", "--size", "8x8", "-o", "tex.png"], "is the input"),
        (
            &["render", "m.obj", "--texture", "t_001.png", "--turntable", "2", "-o", "t.png"],
            "is the input",
        ),
        (&["render", "q.obj", "--size", "8x8", "-o", "m.mtl"], "written as .png"),
    ];
    for (args, refused) in cases {
        let before = inputs.map(|f| fs::read(dir.path(f)).unwrap());
        let err = run_err(&dir.0, args);
        assert!(err.contains(refused), "{args:?}: {err}");
        let after = inputs.map(|f| fs::read(dir.path(f)).unwrap());
        assert!(before == after, "{args:?}: an input was written");
        assert!(!dir.path("x.npy").exists(), "{args:?}: nothing is written");
    }
    // A material library is an input too, whatever its name (`--depth lib.npy` had replaced
    // an `.obj`'s `mtllib lib.npy`).
    for (library, args) in [
        ("lib.npy", &["render", "l.obj", "--size", "8x8", "-o", "l.png", "--depth", "lib.npy"][..]),
        ("lib.ply", &["sample", "l.obj", "-o", "lib.ply"][..]),
    ] {
        let mtl = "newmtl tex\nKd 1 0 0\n";
        dir.write(library, mtl);
        dir.write("l.obj", &format!("mtllib {library}\nusemtl tex\n{quad}"));
        let err = run_err(&dir.0, args);
        assert!(err.contains(&format!("is the input {library}")), "{err}");
        assert_eq!(fs::read_to_string(dir.path(library)).unwrap(), mtl, "{args:?}");
        assert!(!dir.path("l.png").exists(), "{args:?}: nothing is written");
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(dir.path("c.tsplat"), dir.path("link.tsplat")).unwrap();
        fs::hard_link(dir.path("c.tsplat"), dir.path("hard.tsplat")).unwrap();
        for output in ["link.tsplat", "hard.tsplat"] {
            let err = run_err(&dir.0, ["pack", "c.tsplat", "-o", output]);
            assert!(err.contains("is the input"), "{output}: {err}");
        }
        // Two outputs that are two names of one file (the ids had replaced the depth).
        fs::write(dir.path("d.npy"), "").unwrap();
        fs::hard_link(dir.path("d.npy"), dir.path("hard.npy")).unwrap();
        let args =
            ["render", "--size", "8x8", "-o", "h.png", "--depth", "d.npy", "--ids", "hard.npy"];
        assert!(run_err(&dir.0, args).contains("both name"));
        assert!(!dir.path("h.png").exists());
        // An output through a link to a file not yet made is written where the link leads,
        // and the link stays (checking it could be written had replaced the link by an
        // empty file beside a stray one).
        std::os::unix::fs::symlink("made.png", dir.path("dangling.png")).unwrap();
        run_ok(&dir.0, ["render", "--size", "8x8", "-o", "dangling.png"]);
        let link = fs::symlink_metadata(dir.path("dangling.png")).unwrap();
        assert!(link.file_type().is_symlink());
        assert_eq!(read_png(&dir.path("made.png")).width, 8);
        // A link to a file not yet made names the file it leads to, as another output may
        // (the depth had been written over the picture), also through a second link.
        std::os::unix::fs::symlink("later.npy", dir.path("first.png")).unwrap();
        std::os::unix::fs::symlink("first.png", dir.path("second.png")).unwrap();
        for link in ["first.png", "second.png"] {
            let args = ["render", "--size", "8x8", "-o", link, "--depth", "later.npy"];
            assert!(run_err(&dir.0, args).contains("both name"), "{link}");
            assert!(!dir.path("later.npy").exists(), "{link}");
        }
    }
    // Accepted: the same name in another directory; a turntable whose frames are not the
    // texture it reads (t.png itself is not written: its frames are t_000.png, t_001.png).
    fs::create_dir(dir.path("sub")).unwrap();
    run_ok(&dir.0, ["pack", "c.tsplat", "-o", "sub/c.tsplat"]);
    let turntable = ["render", "m.obj", "--texture", "t.png", "--size", "8x8", "--turntable", "2"];
    run_ok(&dir.0, [&turntable[..], &["-o", "t.png"]].concat());
    assert!(dir.path("t_000.png").exists() && dir.path("sub/c.tsplat").exists());
}

/// Options are honoured or refused, never silently ignored: `--frames` times window
/// projection too (its image the same as one untimed frame's, on the same background), and
/// `--turntable` refuses the window projection, `--frames` and `--eye` (its frames would all
/// be one view); `--view` refuses `--eye`; a `--texture` that cannot be read is an error
/// naming it; the window projection refuses the camera's and textures' options (`--view`,
/// `--eye`, `--fov`, `--texture`, `--filter`, `--wrap`, which it ignored), orthographic
/// `--fov`; `--background` takes whole numbers (`0.5,0.5,0.5` was black); `--up` needs `--eye`
/// and must not lie along the view; splat thresholds and
/// budgets must be numbers that mean something; turntable frames are numbered so that their
/// names sort.
#[test]
fn options_are_honoured_or_refused() {
    let dir = TempDir::new("options");
    dir.write("uv.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n");
    let window = ["render", "--projection", "window", "--size", "64x48", "--background", "9,8,7"];
    run_ok(&dir.0, [&window[..], &["-o", "once.png"]].concat());
    let out = trirast_in(&dir.0, [&window[..], &["-o", "timed.png", "--frames", "3"]].concat());
    assert!(out.status.success(), "{}", stderr_of(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("3 frames"));
    let (once, timed) = (read_png(&dir.path("once.png")), read_png(&dir.path("timed.png")));
    assert!(once.rgba == timed.rgba, "timing changes the image");

    let refused: [(&[&str], &str); 15] = [
        (&["render", "--projection", "window", "--turntable", "3"], "--turntable"),
        (&["render", "--projection", "window", "--view", "10,10"], "--view"),
        (&["render", "--projection", "window", "--eye", "1,1,1", "--target", "0,0,0"], "--eye"),
        (&["render", "--projection", "window", "--fov", "50"], "--fov"),
        (&["render", "--projection", "orthographic", "--fov", "50"], "--fov"),
        (&["render", "--projection", "window", "--texture", "t.png"], "--texture"),
        (&["render", "--projection", "window", "--filter", "nearest"], "--filter"),
        (&["render", "--projection", "window", "--wrap", "clamp"], "--wrap"),
        (&["render", "--background", "0.5,0.5,0.5"], "whole numbers"),
        (&["render", "--turntable", "3", "--frames", "2"], "--frames"),
        (&["render", "--turntable", "3", "--eye", "1,1,1", "--target", "0,0,0"], "--eye"),
        (&["render", "--view", "10,10", "--eye", "1,1,1", "--target", "0,0,0"], "--eye"),
        (&["render", "uv.obj", "--texture", "no-such.png"], "no-such.png"),
        (&["render", "--per-sample", "--overdraw", "o.npy"], "--per-sample"),
        // The 3D pipeline chooses its coverage algorithm per triangle (it had been ignored).
        (&["render", "--algorithm", "scanline"], "--algorithm is for --projection window"),
    ];
    for (args, named) in refused {
        let err = run_err(&dir.0, [args, &["--size", "32x24", "-o", "x.png"]].concat());
        assert!(err.contains(named), "{args:?}: {err}");
    }
    assert!(!dir.path("x.png").exists());
    // Texture options where nothing is textured are said to be ignored.
    let err = run_ok(&dir.0, ["render", "--size", "16x12", "--filter", "nearest", "-o", "f.png"]);
    assert!(err.contains("--filter ignored: nothing is drawn with a texture"), "{err}");
    assert!(!err.contains("--wrap"), "{err}");
    for bad in ["nan", "-1", "inf"]
        .map(|v| format!("--threshold={v}"))
        .into_iter()
        .chain(["nan", "0", "-5"].map(|v| format!("--budget-ms={v}")))
    {
        let err = run_err(&dir.0, ["splat", "cloud.ply", &bad]);
        let option = bad.split('=').next().unwrap();
        assert!(err.contains(option), "{bad}: {err}");
    }
    // `--up` needs an explicit camera (it was ignored without one), and must not lie along
    // the view (the camera fell back to another up without a word).
    let above =
        ["render", "--size", "16x12", "-o", "up.png", "--eye", "0,5,0", "--target", "0,0,0"];
    assert!(run_err(&dir.0, ["render", "--up", "0,0,1"]).contains("--eye"));
    assert!(run_err(&dir.0, above).contains("--up"));
    assert!(run_err(&dir.0, [&above[..], &["--up", "0,-2,0"]].concat()).contains("--up"));
    run_ok(&dir.0, [&above[..], &["--up", "0,0,1"]].concat());
    // Single precision: an --up whose length overflows is still a direction, an --eye whose
    // distance to --target overflows is refused (both were reported as an --up along the
    // view).
    run_ok(&dir.0, [&above[..], &["--up", "1e38,0,1e38"]].concat());
    let far = ["render", "--size", "16x12", "--eye", "1e38,1e38,1e38", "--target", "0,0,0"];
    assert!(run_err(&dir.0, far).contains("too far apart"));
    // An --eye a hair from its --target still has a direction (its length squared underflows:
    // the check passed a NaN view and the camera looked along -Z); one too far from the model
    // for its near and far planes to differ, and a model too large to frame, are refused in
    // their own terms, not the camera's values.
    let near = |eye: &'static str| ["render", "--size", "16x12", "--eye", eye, "--target", "0,0,0"];
    assert!(run_err(&dir.0, near("0,1e-30,0")).contains("--up"));
    run_ok(&dir.0, [&near("0,0,1e-30")[..], &["-o", "hair.png"]].concat());
    let err = run_err(&dir.0, near("1e10,0,0"));
    assert!(err.contains("--eye") && err.contains("too far for single precision"), "{err}");
    dir.write("huge.obj", "v 1e38 0 0\nv -1e38 0 0\nv 0 1e38 0\nf 1 2 3\n");
    let err = run_err(&dir.0, ["render", "huge.obj", "--size", "16x12", "-o", "huge.png"]);
    assert!(err.contains("huge.obj is too large to frame"), "{err}");
    let err = run_ok(&dir.0, ["render", "--size", "16x12", "--turntable", "3", "-o", "t.png"]);
    assert!(err.contains("wrote 3 frames") && err.contains("t_002.png"), "{err}");
    for k in 0..3 {
        assert!(dir.path(&format!("t_{k:03}.png")).exists(), "frame {k}");
    }
}

/// `sample` never writes a cloud that reading refuses: a surface whose splats' radius is
/// beyond f32 (3 points on a triangle of corners 3e38) had written a radius of inf, which
/// `splat` then refused; now an error names the file and the points that would fit, and
/// writes nothing. That many points give a cloud that `pack` reads.
#[test]
fn sample_refuses_a_radius_beyond_f32() {
    let dir = TempDir::new("huge_sample");
    dir.write("huge.obj", "v 3e38 3e38 3e38\nv -3e38 -3e38 -3e38\nv 3e38 -3e38 0\nf 1 2 3\n");
    let err = run_err(&dir.0, ["sample", "huge.obj", "--points", "3", "-o", "huge.ply"]);
    let want = "huge.obj: 3 points over an area of 2.205e77 would need splats of radius 4.588e38";
    assert!(err.contains(want) && err.contains("at least 6 points would fit"), "{err}");
    assert!(!dir.path("huge.ply").exists());
    run_ok(&dir.0, ["sample", "huge.obj", "--points", "6", "-o", "huge.ply"]);
    run_ok(&dir.0, ["pack", "huge.ply", "-o", "huge.tsplat"]);
}

/// Nothing to draw or sample is said, not passed over: an empty mesh renders with a warning
/// (3D and window), sampling it is an error (its empty cloud was refused by everything that
/// reads one), and so is packing an empty cloud; an `--output` image not named `.png` is
/// refused (it held PNG bytes).
#[test]
fn empty_inputs_and_misnamed_outputs_are_reported() {
    let dir = TempDir::new("empty");
    dir.write("empty.obj", "");
    for projection in [None, Some("window")] {
        let err = run_ok(&dir.0, render_file_args(&dir.path("empty.obj"), projection));
        assert!(err.contains("warning") && err.contains("nothing to draw"), "{err}");
    }
    let err = run_err(&dir.0, ["sample", "empty.obj", "-o", "cloud.ply"]);
    assert!(err.contains("empty.obj") && err.contains("no surface"), "{err}");
    assert!(!dir.path("cloud.ply").exists());
    let header = "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
                  property float z\nend_header\n";
    dir.write("zero.ply", header);
    let err = run_err(&dir.0, ["pack", "zero.ply", "-o", "zero.tsplat"]);
    assert!(err.contains("zero.ply") && err.contains("empty"), "{err}");
    assert!(!dir.path("zero.tsplat").exists());

    for name in ["x.jpg", "x.npy"] {
        let err = run_err(&dir.0, ["render", "--size", "16x12", "-o", name]);
        assert!(err.contains(".png"), "{name}: {err}");
    }
    run_ok(&dir.0, ["render", "--size", "16x12", "-o", "x.PNG"]);
}

/// A texture whose header reads but whose pixels do not decode is found out only when the
/// textures are loaded: `sample`, like `render`, says so (it used to fall back to plain colour
/// in silence), naming the material.
#[test]
fn sample_warns_about_a_texture_that_does_not_decode() {
    let dir = TempDir::new("undecodable-texture");
    let png = dir.path("t.png");
    image::RgbaImage::from_fn(64, 64, |x, y| image::Rgba([(x * 4) as u8, (y * 4) as u8, 7, 255]))
        .save(&png)
        .unwrap();
    // Cut inside the pixel data: the header (what loading the mesh checks) stays whole.
    let bytes = fs::read(&png).unwrap();
    fs::write(&png, &bytes[..bytes.len() - 40]).unwrap();
    dir.write("m.mtl", "newmtl tex\nKd 1 1 1\nmap_Kd t.png\n");
    dir.write(
        "q.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl tex\n\
         f 1/1 2/2 3/3\n",
    );
    let render = run_ok(&dir.0, ["render", "q.obj", "--size", "16x16", "-o", "r.png"]);
    let sample = run_ok(&dir.0, ["sample", "q.obj", "--points", "10", "-o", "s.ply"]);
    for (command, err) in [("render", render), ("sample", sample)] {
        assert!(err.contains("warning") && err.contains("t.png"), "{command}: {err}");
        assert!(err.contains("material `tex`"), "{command}: the warning names it: {err}");
        let line = "m.mtl:3: the texture of material `tex` cannot be used";
        assert!(err.contains(line), "{command}: and its `map_Kd` line: {err}");
        // In the words of the warnings for textures missing when the library is read.
        assert!(err.contains("; using its diffuse colour"), "{command}: {err}");
    }
}

/// A cloud reaching past what the splat view's single-precision arithmetic holds is drawn
/// with a warning saying so (one point at 1e20 beside a unit cluster drew nothing, silently),
/// which `pack` gives too, and a size the target refuses is reported before the hierarchy is
/// built.
#[test]
fn splat_warns_about_points_too_far_and_checks_the_size_first() {
    let dir = TempDir::new("far-cloud");
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n",
    );
    dir.write("near.ply", &format!("{ply}1 1 1\n"));
    ply.push_str("1e20 0 0\n");
    dir.write("far.ply", &ply);
    let err = run_ok(&dir.0, ["splat", "far.ply", "--size", "32x32", "-o", "far.png"]);
    assert!(err.contains("warning") && err.contains("1.0e20"), "{err}");
    let err = run_ok(&dir.0, ["splat", "near.ply", "--size", "32x32", "-o", "near.png"]);
    assert!(!err.contains("warning"), "{err}");
    // `pack` says so too, before the cloud is drawn from its file.
    let err = run_ok(&dir.0, ["pack", "far.ply", "-o", "far.tsplat"]);
    assert!(err.contains("warning") && err.contains("1.0e20"), "{err}");
    let err = run_ok(&dir.0, ["pack", "near.ply", "-o", "near.tsplat"]);
    assert!(!err.contains("warning"), "{err}");
    let err = run_err(&dir.0, ["splat", "near.ply", "--size", "0x32", "-o", "zero.png"]);
    assert!(err.contains("0x32") && !err.contains("hierarchy"), "{err}");
    // A mesh is named as one, with what to do (it had been refused for its first line, as
    // a PLY file).
    dir.write("mesh.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    for (command, output) in [("splat", "mesh.png"), ("pack", "mesh.tsplat")] {
        let err = run_err(&dir.0, [command, "mesh.obj", "-o", output]);
        assert!(err.contains("mesh.obj: a mesh, not a point cloud"), "{err}");
        assert!(err.contains("trirast sample mesh.obj"), "{err}");
    }
}

/// `info` prints a mesh's counts and bounds and the warnings `render` prints (a missing
/// material library), and says there are no bounds rather than printing infinities when no
/// face uses a vertex (an OBJ's mesh vertices are those its faces use).
#[test]
fn info_reports_counts_bounds_and_warnings() {
    let dir = TempDir::new("info");
    dir.write(
        "quad.obj",
        "mtllib gone.mtl\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nv 9 9 9\nf 1 2 3 4\n",
    );
    let out = trirast_in(&dir.0, ["info", "quad.obj"]);
    let (text, err) = (String::from_utf8_lossy(&out.stdout), stderr_of(&out));
    assert!(out.status.success(), "{err}");
    for line in [
        // Five `v` lines, one of them unused: the count says what it counts.
        "vertices:   4 (distinct corners the faces use: unused `v` lines are left out)",
        "triangles:  2",
        "polygons:   1",
        "min [0.0, 0.0, 0.0] max [2.0, 1.0, 0.0]",
    ] {
        assert!(text.contains(line), "{line:?} in {text}");
    }
    assert!(err.contains("gone.mtl was not found"), "{err}");
    // One finite point: its sphere has radius 0 (not the framing's 1); a NaN vertex is
    // counted.
    dir.write("point.obj", "v 1 2 3\nv nan 0 0\nf 1 1 2\n");
    let out = trirast_in(&dir.0, ["info", "point.obj"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("centre [1.0, 2.0, 3.0] radius 0\n"), "{text}");
    assert!(text.contains("non-finite: 1 vertex (NaN"), "{text}");
    // A radius past single precision is shown, not `inf`.
    dir.write("far.obj", "v 3e38 3e38 3e38\nv -3e38 -3e38 -3e38\nv 3e38 0 0\nf 1 2 3\n");
    let out = trirast_in(&dir.0, ["info", "far.obj"]);
    let text = String::from_utf8_lossy(&out.stdout);
    let radius = text.lines().find_map(|l| l.split_once(" radius ")).map(|(_, r)| r);
    let radius: f64 = radius.expect("a radius").parse().unwrap();
    assert!((radius / (3e38 * 3f64.sqrt()) - 1.0).abs() < 1e-6, "{text}");
    dir.write("off.obj", "v 3e38 0 0\nv 2e38 0 0\nv 3e38 1 0\nf 1 2 3\n");
    let out = trirast_in(&dir.0, ["info", "off.obj"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("centre [2.5e38, 0.5, 0.0] radius 500000"), "{text}");
    // A directory is named as one, not as a file of an unknown format.
    fs::create_dir(dir.path("models")).unwrap();
    let err = run_err(&dir.0, ["info", "models"]);
    assert!(err.contains("models: is a directory, not a regular file"), "{err}");
    dir.write("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
    let out = trirast_in(&dir.0, ["info", "points.obj"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && text.contains("vertices:   0"), "{text}");
    assert!(text.contains("bounds:     none") && !text.contains("inf"), "{text}");
}

/// Output that cannot be written is not a panic: a full standard output is an error that
/// says so, a full standard error (warnings, "wrote ...") does not stop the picture being
/// written, and a reader closing the pipe ends the command quietly.
#[test]
fn unwritable_standard_streams_are_not_panics() {
    use std::process::Stdio;
    let dir = TempDir::new("streams");
    let obj = "mtllib gone.mtl\nv 0 0 0\nv 20 0 0\nv 0 20 0\nf 1 2 3\n";
    dir.write("tri.obj", obj);
    let run = |args: &[&str], stdout: Stdio, stderr: Stdio| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_trirast"));
        command.args(args).current_dir(&dir.0).stdout(stdout).stderr(stderr);
        command.output().expect("failed to start the trirast binary")
    };
    if Path::new("/dev/full").exists() {
        let full = || Stdio::from(fs::File::create("/dev/full").unwrap());
        let out = run(&["info", "tri.obj"], full(), Stdio::piped());
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("writing to standard output") && !err.contains("panicked"), "{err}");
        let out = run(&["render", "tri.obj", "-o", "t.png"], Stdio::null(), full());
        assert!(out.status.success(), "{}", out.status);
        assert!(dir.path("t.png").exists());
        // The timings could not be printed: the picture is still written, and the command
        // fails once it is.
        let args = ["render", "tri.obj", "-o", "f.png", "--frames", "2"];
        let out = run(&args, full(), Stdio::piped());
        let err = stderr_of(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert_eq!(err.matches("writing to standard output").count(), 1, "{err}");
        assert!(dir.path("f.png").exists());
    }
    // The pipe is closed before the command writes, or it writes into the pipe's buffer:
    // either way it succeeds without a word, and its picture is written.
    for args in [&["info", "tri.obj"][..], &["render", "tri.obj", "-o", "p.png", "--frames", "2"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_trirast"))
            .args(args)
            .current_dir(&dir.0)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "{args:?}: {}: {}", out.status, stderr_of(&out));
        assert!(!stderr_of(&out).contains("panicked"));
    }
    assert!(dir.path("p.png").exists());
}

/// Splats that reach the camera's plane cannot be drawn; the view frames the points' centres,
/// so splats larger than the cloud had given an empty picture with no word but "culled".
#[test]
fn splat_says_when_splats_reach_the_camera() {
    let dir = TempDir::new("huge-splats");
    let header = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
                  property float z\nproperty float radius\nend_header\n";
    let points = |radius: f32| {
        let corners = ["0 0 0", "1 0 0", "0 1 0", "0 0 1"];
        corners.map(|c| format!("{c} {radius}\n")).concat()
    };
    dir.write("huge.ply", &format!("{header}{}", points(10.0)));
    dir.write("fine.ply", &format!("{header}{}", points(0.05)));
    let args = |file| ["splat", file, "--size", "32x24", "-o", "s.png"];
    let err = run_ok(&dir.0, args("huge.ply"));
    assert!(err.contains("4 of 4 splats reach the camera's plane"), "{err}");
    let err = run_ok(&dir.0, args("fine.ply"));
    assert!(!err.contains("camera's plane"), "{err}");
}

/// A huge or tiny `--threshold` is said in exponent form, not as thirty-odd digits.
#[test]
fn splat_says_a_huge_threshold_briefly() {
    let dir = TempDir::new("huge-threshold");
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    dir.write("c.ply", header);
    let thresholds = [
        ("1e30", "level 1e30 px"),
        ("2.5", "level 2.5 px"),
        ("1e-30", "level 1e-30 px"),
        ("0", "level 0 px"),
    ];
    for (threshold, said) in thresholds {
        let args = ["splat", "c.ply", "--size", "32x24", "--threshold", threshold, "-o", "s.png"];
        let err = run_ok(&dir.0, args);
        assert!(err.contains(said), "{err}");
    }
}

/// Names of outputs that are not UTF-8 keep their bytes in a turntable's numbered files (two
/// such names had both become `frame_000.npy`, ..., one array written over the other). Linux
/// only: its file systems take any bytes but `/` and NUL in a name, where macOS's refuse some.
#[cfg(target_os = "linux")]
#[test]
fn turntable_numbers_names_that_are_not_utf8() {
    use std::os::unix::ffi::{OsStrExt as _, OsStringExt as _};
    let dir = TempDir::new("non-utf8");
    let name = |bytes: &[u8]| OsString::from_vec(bytes.to_vec());
    let args = [
        OsString::from("render"),
        "--size".into(),
        "8x8".into(),
        "--turntable".into(),
        "2".into(),
        "-o".into(),
        name(b"\xfe.png"),
        "--depth".into(),
        name(b"\xff.npy"),
        "--ids".into(),
        name(b"\xfd.npy"),
    ];
    run_ok(&dir.0, &args);
    let made = |bytes: &[u8]| dir.0.join(std::ffi::OsStr::from_bytes(bytes));
    for k in [b"_000", b"_001"] {
        assert_eq!(read_png(&made(&[b"\xfe", &k[..], b".png"].concat())).width, 8);
        read_npy(&made(&[b"\xff", &k[..], b".npy"].concat())).check("<f4", 8, 8);
        read_npy(&made(&[b"\xfd", &k[..], b".npy"].concat())).check("<i4", 8, 8);
    }
}

/// A budget that stops refinement at a level of single points says so, not that the budget
/// was reached: there was nothing left to refine (a one-point cloud said "budget reached").
#[test]
fn splat_budget_on_a_single_point_says_nothing_was_left_to_refine() {
    let dir = TempDir::new("one-point");
    dir.write(
        "one.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         property float z\nend_header\n0 0 0\n",
    );
    let args = ["splat", "one.ply", "--size", "32x32", "--budget-ms", "0.001", "-o", "o.png"];
    let err = run_ok(&dir.0, args);
    assert!(err.contains("nothing left to refine") && !err.contains("budget"), "{err}");
}

/// A file that makes a warning per line shows the first twenty and how many more: one with
/// thirty `usemtl` names and no material library.
#[test]
fn warnings_are_capped() {
    let dir = TempDir::new("warnings");
    let faces: String = (0..30).map(|i| format!("usemtl m{i}\nf 1 2 3\n")).collect();
    dir.write("w.obj", &format!("v 0 0 0\nv 1 0 0\nv 0 1 0\n{faces}"));
    let err = run_ok(&dir.0, ["render", "w.obj", "--size", "16x16", "-o", "w.png"]);
    let warnings: Vec<&str> = err.lines().filter(|l| l.starts_with("trirast: warning:")).collect();
    assert_eq!(warnings.len(), 21, "{err}");
    assert!(warnings[0].contains("material `m0`"), "{err}");
    assert!(warnings[19].contains("material `m19`"), "{err}");
    assert_eq!(warnings[20], "trirast: warning: ... and 10 more warning(s), not shown");
    let out = trirast_in(&dir.0, ["info", "w.obj"]);
    let info = String::from_utf8_lossy(&out.stdout);
    assert_eq!(info.lines().filter(|l| l.starts_with("warning:")).count(), 21, "{info}");
    assert!(info.contains("warning:    ... and 10 more, not shown"), "{info}");
}

/// The statistics line counts each triangle once and says how many pieces clipping added:
/// three triangles at the eye are cut into seven pieces at 800 x 600, four more than the
/// triangles (a smaller target's guard band leaves them whole). Each of the seven had been
/// counted as a rasterized triangle.
#[test]
fn statistics_count_clipped_triangles_once() {
    let dir = TempDir::new("pieces");
    dir.write(
        "e.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 -1\nv 1 0 -1\nf 1 2 3\nf 1 4 5\nf 2 3 4\n",
    );
    let view = ["--eye", "0.5,0.5,0", "--target", "0.3,0.3,-5", "--cull", "none"];
    let err = run_ok(
        &dir.0,
        [&["render", "e.obj", "--size", "800x600", "-o", "e.png"][..], &view].concat(),
    );
    let line = err.lines().find(|l| l.contains("fragments")).unwrap_or_default();
    let rasterized: usize =
        line.split(": ").nth(1).and_then(|s| s.split(' ').next()?.parse().ok()).unwrap();
    assert!(line.starts_with("3 triangles: 3 rasterized") && rasterized == 3, "{line}");
    assert!(line.contains("(clipping added 4 pieces)"), "{line}");
    let err = run_ok(&dir.0, ["render", "e.obj", "--size", "32x32", "-o", "f.png"]);
    assert!(!err.contains("clipping added"), "{err}");
}

/// Models past the framing's single-precision range say so: a triangle 1e20 units out (its
/// distances' squares overflow) and one 1e-25 across (they underflow: it was framed as a unit
/// sphere and drew nothing); the same triangle at 1e3 does not.
#[test]
fn models_beyond_single_precision_framing_are_warned_of() {
    let dir = TempDir::new("scale");
    for (scale, warned) in [
        ("1e20", Some("1.0e20 units along an axis")),
        ("1e-25", Some("spans 1.0e-25 units")),
        ("1e3", None),
    ] {
        let obj = format!("v 0 0 0\nv {scale} 0 0\nv 0 {scale} 0\nf 1 2 3\n");
        dir.write("s.obj", &obj);
        let err = run_ok(&dir.0, ["render", "s.obj", "--size", "16x16", "-o", "s.png"]);
        let warning = err.lines().find(|l| l.starts_with("trirast: warning:"));
        match warned {
            Some(needle) => assert!(warning.is_some_and(|w| w.contains(needle)), "{scale}: {err}"),
            None => assert_eq!(warning, None, "{scale}: {err}"),
        }
    }
}
