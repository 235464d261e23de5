//! Splat rendering: traverse the hierarchy, cull, stop at a projected size, draw splats.
//!
//! A node is culled when its sphere lies outside a frustum plane, or when every normal in its
//! cone faces away from the eye (with a margin for the sphere's angular size). It is drawn as
//! a splat when it is a leaf or when the points it stands for spread over less than the
//! threshold (pixels): its projected diameter less that of the smallest splat
//! ([`SplatTree::min_leaf_radius`]), since every sphere is inflated by its points' splat radii
//! and testing the inflated size would refine nodes whose points all fall within one pixel.
//! The splat is a square or disk of the node's full projected radius around its projected
//! centre, at the depth of its centre, lit by its normal with the same light as meshes.
//! Otherwise its children are visited.
//!
//! Traversal goes level by level, each level's nodes classified in parallel chunks and
//! concatenated in index order; drawing then uses the triangles' machinery: splats binned into
//! 128 x 128 tiles ([`Bins`]) in that order, rows of tiles ([`Target::bands`]) drawn in parallel
//! with the depth test. So the image does not depend on the thread count.

use glam::{Mat3, Mat4, Vec3, Vec3A, Vec4};
use rayon::prelude::*;

use super::tree::SplatTree;
use crate::bin::{Bins, TileGrid};
use crate::camera::Camera;
use crate::color::{linear_to_srgb8_rgb, srgb_decode_table};
use crate::model::Light;
use crate::setup::PixelRect;
use crate::simd::floor_i32x4;
use crate::target::{Target, TargetBand};

/// The footprint of a splat.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SplatShape {
    /// An axis-aligned square.
    Square,
    /// A disk.
    #[default]
    Round,
}

/// How to render splats. Default: 1-pixel threshold, round splats, back-face culling, the
/// mesh renderer's head light.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub struct SplatOptions {
    /// Stop descending at nodes whose points spread over less than this many pixels on
    /// screen (0: draw every leaf); see the module documentation.
    pub threshold: f32,
    /// Splat footprint.
    pub shape: SplatShape,
    /// Cull nodes whose normal cone faces away from the eye.
    pub backface_cull: bool,
    /// Light (view space, as for meshes); `None` draws the node colours unlit.
    pub light: Option<Light>,
}

impl Default for SplatOptions {
    fn default() -> Self {
        Self {
            threshold: 1.0,
            shape: SplatShape::Round,
            backface_cull: true,
            light: Some(Light::default()),
        }
    }
}

impl SplatOptions {
    /// Sets the threshold in pixels.
    #[must_use]
    pub fn with_threshold(mut self, threshold: f32) -> Self {
        self.threshold = threshold;
        self
    }

    /// Sets the splat shape.
    #[must_use]
    pub fn with_shape(mut self, shape: SplatShape) -> Self {
        self.shape = shape;
        self
    }

    /// Sets the light (`None`: unlit).
    #[must_use]
    pub fn with_light(mut self, light: Option<Light>) -> Self {
        self.light = light;
        self
    }

    /// Turns back-face culling on or off.
    #[must_use]
    pub fn with_backface_cull(mut self, on: bool) -> Self {
        self.backface_cull = on;
        self
    }
}

/// What a splat render did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SplatStats {
    /// Nodes visited.
    pub visited: usize,
    /// Splats drawn.
    pub drawn: usize,
    /// Of those, leaves.
    pub leaves_drawn: usize,
    /// Nodes culled (frustum or normal cone).
    pub culled: usize,
    /// Leaves not drawn because their sphere reaches the camera's plane, where no projection
    /// holds (not counted in `culled`): splats whose radius is at least their depth along the
    /// view, which a user should hear of, since they leave a picture empty with nothing culled.
    pub at_eye: usize,
    /// Pixels written (passed the depth test).
    pub pixels: u64,
}

/// One splat in window space: 32 bytes, two to a cache line.
#[derive(Clone, Copy, Debug, Default)]
struct Splat {
    x: f32,
    y: f32,
    /// The squared radius (pixels) for the disk test.
    half_squared: f32,
    /// Window-space depth, clamped to [0, 1].
    depth: f32,
    color: [u8; 4],
    id: i32,
    /// The pixels it may write, on the target ([`footprint`]), as `x0, y0, x1, y1`; empty
    /// (`x0 > x1`) when off it. Target sides are at most 16384, so `u16` holds them.
    rect: [u16; 4],
}

impl Splat {
    /// [`Splat::rect`] as a rectangle, `None` when empty.
    fn rect(&self) -> Option<PixelRect> {
        let [x0, y0, x1, y1] = self.rect.map(i32::from);
        (x0 <= x1).then_some(PixelRect { x0, y0, x1, y1 })
    }
}

/// Everything traversal needs, derived once from the camera and target.
struct View<'a> {
    tree: &'a SplatTree,
    options: &'a SplatOptions,
    clip: Mat4,
    planes: [Vec4; 6],
    eye: Vec3,
    direction: Vec3,
    perspective: bool,
    /// Pixels per world unit at w = 1 (vertically).
    pixels_per_unit: f32,
    half_size: [f32; 2],
    screen: PixelRect,
    /// The light direction in world space (the view-space light taken back through the
    /// view's rotation).
    light_world: Vec3,
    /// sRGB decoding of node colours.
    decode: &'static [f32; 256],
}

impl<'a> View<'a> {
    /// The view of `tree` from `camera` on a `width x height` target.
    fn new(
        tree: &'a SplatTree,
        camera: &Camera,
        options: &'a SplatOptions,
        width: u32,
        height: u32,
    ) -> Self {
        let (w, h) = (width as f32, height as f32);
        let projection = camera.projection(w / h);
        let view = camera.view();
        let clip = projection * view;
        let rows = [clip.row(0), clip.row(1), clip.row(2), clip.row(3)];
        let planes = [
            rows[3] + rows[0],
            rows[3] - rows[0],
            rows[3] + rows[1],
            rows[3] - rows[1],
            rows[2],
            rows[3] - rows[2],
        ]
        .map(|p| p / p.truncate().length().max(1e-30));
        let light_dir = options.light.map_or(Vec3::Z, |l| l.direction.normalize_or(Vec3::Z));
        View {
            tree,
            options,
            clip,
            planes,
            eye: camera.eye,
            direction: (camera.target - camera.eye).normalize_or(Vec3::NEG_Z),
            perspective: matches!(camera.projection, crate::camera::Projection::Perspective { .. }),
            pixels_per_unit: projection.y_axis.y * h / 2.0,
            half_size: [w / 2.0, h / 2.0],
            screen: PixelRect::of_target(width, height),
            light_world: (Mat3::from_mat4(view).transpose() * light_dir).normalize_or(Vec3::Z),
            decode: srgb_decode_table(),
        }
    }
}

impl View<'_> {
    /// Culled, drawn, or to be refined. `parent_inside`: the parent's sphere lies inside every
    /// frustum plane, so this node's cannot lie wholly outside one (it contains at least one
    /// of the parent's points) and the plane tests are skipped.
    fn classify(&self, i: usize, parent_inside: bool) -> Visit {
        let n = &self.tree.nodes[i];
        let c = Vec3::from(n.centre);
        let r = n.radius;
        let inside = parent_inside || {
            let mut inside = true;
            for p in &self.planes {
                let d = p.truncate().dot(c) + p.w;
                if d < -r {
                    return Visit::Culled;
                }
                inside &= d >= r;
            }
            inside
        };
        let normal = Vec3::from(n.normal);
        let to_eye = if self.perspective { self.eye - c } else { -self.direction };
        let facing_dot = normal.dot(to_eye);
        // Only a node whose normal faces away can be culled: test the sign before any root,
        // division or trig.
        if self.options.backface_cull
            && n.cone < std::f32::consts::FRAC_PI_2
            && facing_dot < 0.0
            && normal != Vec3::ZERO
        {
            let dist = to_eye.length();
            if dist > r {
                let cos_facing = facing_dot / dist.max(f32::MIN_POSITIVE);
                let facing = cos_facing.clamp(-1.0, 1.0).acos();
                let margin = (r / dist).clamp(0.0, 1.0).asin();
                if facing > std::f32::consts::FRAC_PI_2 + n.cone + margin {
                    return Visit::Culled;
                }
            }
        }
        let p = self.clip * c.extend(1.0);
        let leaf = n.child_count == 0;
        if p.w <= r * 1e-3 || (self.perspective && p.w - r <= 0.0) {
            // Straddles the camera plane: no projection; refine, or drop a leaf.
            return if leaf { Visit::AtEye } else { Visit::Refine { inside } };
        }
        // One division per node: everything below scales by 1/w.
        let inv_w = 1.0 / p.w;
        let radius_px = r * self.pixels_per_unit * inv_w;
        // The size test is on the detail the node stands for (its points' spread), not on
        // the disk drawn for it, which adds a splat radius: otherwise a node whose points all
        // fall within a pixel would still be refined down to its leaves.
        let spread_px = (r - self.tree.min_leaf_radius()).max(0.0) * self.pixels_per_unit * inv_w;
        if leaf || 2.0 * spread_px < self.options.threshold {
            // Two-sided, as for meshes: a normal facing away (a scan's flipped triangle, or a
            // node kept by the conservative cone test) is lit as its visible side.
            let lit = self.shade(n.color, if facing_dot < 0.0 { -normal } else { normal });
            let (x, y) =
                ((p.x * inv_w + 1.0) * self.half_size[0], (1.0 - p.y * inv_w) * self.half_size[1]);
            let half = radius_px.max(0.5);
            let rect = footprint(x, y, half, &self.screen)
                .map_or([1, 0, 0, 0], |r| [r.x0, r.y0, r.x1, r.y1].map(|v| v as u16));
            return Visit::Draw(Splat {
                x,
                y,
                half_squared: half * half,
                depth: (p.z * inv_w).clamp(0.0, 1.0),
                color: lit,
                id: i as i32,
                rect,
            });
        }
        Visit::Refine { inside }
    }

    fn shade(&self, color: [u8; 3], normal: Vec3) -> [u8; 4] {
        let albedo = Vec3A::from(color.map(|c| self.decode[usize::from(c)]));
        let lit = match self.options.light {
            Some(light) if normal != Vec3::ZERO => {
                // The light taken into world space once per frame: the view is a rotation, so
                // `dot(R n, l) == dot(n, R^T l)` and unit normals stay unit.
                let d = light.ambient + light.diffuse * normal.dot(self.light_world).max(0.0);
                albedo * d
            }
            _ => albedo,
        };
        let [r, g, b] = linear_to_srgb8_rgb(lit.to_array());
        [r, g, b, 255]
    }
}

enum Visit {
    Culled,
    /// A leaf reaching the camera's plane: not drawn.
    AtEye,
    Draw(Splat),
    /// Visit the children; `inside`: this node lies inside every frustum plane.
    Refine {
        inside: bool,
    },
}

/// Renders `tree` seen by `camera` into `target` (which the caller clears).
///
/// # Panics
/// If one of `target`'s buffers was replaced by one of another length
/// ([`Target::check_buffers`] says which): drawing would index past it.
pub fn render(
    target: &mut Target,
    tree: &SplatTree,
    camera: &Camera,
    options: &SplatOptions,
) -> SplatStats {
    if let Err(e) = target.check_buffers() {
        panic!("splat render: {e}");
    }
    if tree.nodes.is_empty() {
        return SplatStats::default();
    }
    let v = View::new(tree, camera, options, target.width(), target.height());
    // Level by level: the frontier holds one depth's nodes in ascending index order (the
    // layout is breadth-first, so children of ascending parents ascend too), so each level
    // reads the node array front to back, and the nodes to come are known in advance (they
    // are prefetched). Chunks of a level are classified in parallel and their children
    // concatenated in chunk order, so the splat order, and with it the image, does not
    // depend on the thread count.
    const PREFETCH_AHEAD: usize = 16;
    let mut stats = SplatStats::default();
    let tiles = TileGrid::of_size(target.width(), target.height());
    // Splats stay in the per-chunk parts they were produced in (never concatenated: that copy
    // was a tenth of the frame).
    let mut parts: Vec<Part> = Vec::new();
    // Frontier entries are node indices with the top bit set when the parent lies inside
    // the frustum (trees of 2^31 nodes or more go without the shortcut).
    const INSIDE: u32 = 1 << 31;
    let flag_fits = tree.nodes.len() <= INSIDE as usize;
    let mut frontier = vec![0u32];
    while !frontier.is_empty() {
        let level: Vec<(Part, Vec<u32>, SplatStats)> = frontier
            .par_chunks(CHUNK)
            .map(|chunk| {
                let (mut out, mut next, mut st) =
                    (PartBuilder::new(chunk.len(), &tiles), Vec::new(), SplatStats::default());
                for (j, &i) in chunk.iter().enumerate() {
                    // The frontier says which nodes come next: ask for them early, since a
                    // sparse level is a cache miss per node otherwise.
                    if let Some(&ahead) = chunk.get(j + PREFETCH_AHEAD) {
                        let ahead = if flag_fits { ahead & !INSIDE } else { ahead };
                        crate::simd::prefetch(&tree.nodes[ahead as usize]);
                    }
                    let parent_inside = flag_fits && i & INSIDE != 0;
                    let i = if flag_fits { i & !INSIDE } else { i } as usize;
                    st.visited += 1;
                    match v.classify(i, parent_inside) {
                        Visit::Culled => st.culled += 1,
                        Visit::AtEye => st.at_eye += 1,
                        Visit::Draw(s) => {
                            st.drawn += 1;
                            st.leaves_drawn += usize::from(tree.nodes[i].child_count == 0);
                            out.push(s);
                        }
                        Visit::Refine { inside } => {
                            let flag = if inside && flag_fits { INSIDE } else { 0 };
                            next.extend(tree.children(i).map(|k| k as u32 | flag));
                        }
                    }
                }
                (out.sorted_by_tile(), next, st)
            })
            .collect();
        // Every node of the next level comes after every node of this one, in ascending
        // order: in a breadth-first tree all do, and those of a tree made by hand that do not
        // (children shared by several parents, which had made the walk exponential: 32 nodes
        // each listing the next four took minutes and gigabytes) are dropped, so that each
        // node is visited at most once.
        let index = |k: u32| if flag_fits { k & !INSIDE } else { k } as usize;
        let mut after = frontier.last().map_or(0, |&k| index(k) + 1);
        frontier = Vec::with_capacity(level.iter().map(|p| p.1.len()).sum());
        for (part, next, st) in level {
            if !part.runs.is_empty() {
                parts.push(part);
            }
            frontier.extend(next.into_iter().filter(|&k| {
                let fresh = index(k) >= after;
                if fresh {
                    after = index(k) + 1;
                }
                fresh
            }));
            stats.visited += st.visited;
            stats.drawn += st.drawn;
            stats.leaves_drawn += st.leaves_drawn;
            stats.culled += st.culled;
            stats.at_eye += st.at_eye;
        }
    }
    stats.pixels = draw_splats(target, &parts, &tiles, options.shape);
    stats
}

/// Traversal classifies a level's frontier in chunks of this many nodes, in parallel.
const CHUNK: usize = 4096;

/// One chunk's splats, sorted by tile as they are produced (a counting sort, stable, so each
/// tile's splats keep traversal order; a splat overlapping several tiles is copied into each):
/// bins then hold [`Run`]s, a few per part, instead of every splat, and the tile loop reads
/// each run's splats front to back.
#[derive(Debug, Default)]
struct Part {
    splats: Vec<Splat>,
    runs: Vec<Run>,
}

/// The splats `start..end` of a part, all overlapping tile `tile`.
#[derive(Clone, Copy, Debug)]
struct Run {
    tile: u32,
    start: u32,
    end: u32,
}

/// A chunk's splats as traversal produces them, each with its tile.
struct PartBuilder<'a> {
    grid: &'a TileGrid,
    splats: Vec<Splat>,
    /// Each splat's tile, or [`PartBuilder::SEVERAL`] for the few across tile borders (and
    /// for splats off the target, which have none).
    keys: Vec<u32>,
    /// The first and last tile any splat overlaps (`lo > hi`: none).
    lo: u32,
    hi: u32,
}

impl<'a> PartBuilder<'a> {
    const SEVERAL: u32 = u32::MAX;

    fn new(capacity: usize, grid: &'a TileGrid) -> Self {
        let (splats, keys) = (Vec::with_capacity(capacity), Vec::with_capacity(capacity));
        Self { grid, splats, keys, lo: u32::MAX, hi: 0 }
    }

    fn push(&mut self, s: Splat) {
        let key = match s.rect() {
            Some(r) => {
                let (first, last) = self.grid.first_and_last(&r);
                (self.lo, self.hi) = (self.lo.min(first), self.hi.max(last));
                if first == last { first } else { Self::SEVERAL }
            }
            None => Self::SEVERAL,
        };
        self.splats.push(s);
        self.keys.push(key);
    }

    /// A counting sort over the tiles this chunk touches (a chunk is a stretch of one
    /// breadth-first level: nearby nodes, few tiles): count, place, then copy the splats in
    /// the order found.
    fn sorted_by_tile(self) -> Part {
        // Counting over a tile range much wider than the chunk (a large target, splats far
        // apart) would cost more than comparing.
        let counting = self.lo > self.hi || (self.hi - self.lo) as usize <= 4 * CHUNK;
        self.sorted(counting)
    }

    /// Sorted by counting over the touched tile range, or by comparison of `(tile, index)`
    /// pairs; both give the same part.
    fn sorted(self, counting: bool) -> Part {
        debug_assert!(self.splats.len() <= CHUNK);
        let (grid, lo, hi) = (self.grid, self.lo, self.hi);
        if lo > hi {
            return Part::default();
        }
        if !counting {
            let mut pairs: Vec<(u32, u16)> = Vec::with_capacity(self.splats.len());
            for (k, (s, &key)) in self.splats.iter().zip(&self.keys).enumerate() {
                if key != Self::SEVERAL {
                    pairs.push((key, k as u16));
                } else if let Some(r) = s.rect() {
                    grid.each_tile(&r, |t| pairs.push((t, k as u16)));
                }
            }
            pairs.sort_unstable();
            let mut runs: Vec<Run> = Vec::new();
            for (i, &(tile, _)) in pairs.iter().enumerate() {
                match runs.last_mut() {
                    Some(run) if run.tile == tile => run.end += 1,
                    _ => runs.push(Run { tile, start: i as u32, end: i as u32 + 1 }),
                }
            }
            let splats = pairs.iter().map(|&(_, k)| self.splats[usize::from(k)]).collect();
            return Part { splats, runs };
        }
        let mut starts = vec![0u32; (hi - lo + 2) as usize];
        for (s, &key) in self.splats.iter().zip(&self.keys) {
            if key != Self::SEVERAL {
                starts[(key - lo + 1) as usize] += 1;
            } else if let Some(r) = s.rect() {
                grid.each_tile(&r, |t| starts[(t - lo + 1) as usize] += 1);
            }
        }
        let mut runs = Vec::new();
        for t in 0..starts.len() - 1 {
            let (start, count) = (starts[t], starts[t + 1]);
            if count > 0 {
                runs.push(Run { tile: lo + t as u32, start, end: start + count });
            }
            starts[t + 1] = start + count;
        }
        let mut order = vec![0u16; starts[starts.len() - 1] as usize];
        for (k, (s, &key)) in self.splats.iter().zip(&self.keys).enumerate() {
            let mut put = |t: u32| {
                let at = &mut starts[(t - lo) as usize];
                order[*at as usize] = k as u16;
                *at += 1;
            };
            if key != Self::SEVERAL {
                put(key);
            } else if let Some(r) = s.rect() {
                grid.each_tile(&r, put);
            }
        }
        Part { splats: order.iter().map(|&k| self.splats[usize::from(k)]).collect(), runs }
    }
}

/// Draws splats through the triangles' tiles: runs binned into 128 x 128 tiles in part order,
/// rows of tiles drawn in parallel, each tile's runs in order; returns pixels written. Per
/// tile, that is every splat overlapping it in traversal order, as if binned one by one.
fn draw_splats(target: &mut Target, parts: &[Part], grid: &TileGrid, shape: SplatShape) -> u64 {
    let (width, height) = (target.width(), target.height());
    // Run `k` of all parts in order is `runs[k]`, as (part, run).
    let runs: Vec<(u32, u32)> = parts
        .iter()
        .enumerate()
        .flat_map(|(p, part)| (0..part.runs.len() as u32).map(move |k| (p as u32, k)))
        .collect();
    let bins = Bins::of_tiles(
        grid,
        runs.iter()
            .enumerate()
            .map(|(k, &(p, r))| (k as u32, parts[p as usize].runs[r as usize].tile)),
    );
    bins.draw(target, &PixelRect::of_target(width, height), |band, tile, list| {
        // Bins of runs of splats, short however many splats they hold: always whole tiles.
        band.prefetch(tile);
        let mut sum = 0;
        let plain = plain(band);
        for &k in list {
            let (p, r) = runs[k as usize];
            let part = &parts[p as usize];
            let run = part.runs[r as usize];
            for s in &part.splats[run.start as usize..run.end as usize] {
                sum += draw_splat(band, s, shape, tile, plain);
            }
        }
        sum
    })
}

/// The pixels a splat centred at `(x, y)` with half-size `half` may write, within `clip`:
/// those whose centres lie in its square, and the pixel containing its centre.
fn footprint(x: f32, y: f32, half: f32, clip: &PixelRect) -> Option<PixelRect> {
    if !x.is_finite() || !y.is_finite() || !half.is_finite() {
        return None;
    }
    // Far-off splats clamp in the conversion and are then clipped away. `ceil(t)` is
    // `-floor(-t)`, negation being exact.
    let (lo_x, lo_y) = (x - half - 0.5, y - half - 0.5);
    let [hx, hy, nx0, ny0] = floor_i32x4([x, y, -lo_x, -lo_y]);
    let [x1, y1, _, _] = floor_i32x4([x + half - 0.5, y + half - 0.5, 0.0, 0.0]);
    PixelRect { x0: (-nx0).min(hx), x1: x1.max(hx), y0: (-ny0).min(hy), y1: y1.max(hy) }
        .intersect(clip)
}

/// Whether `band` has one sample per pixel and only colour and depth: [`draw_splat`]'s fast
/// paths.
fn plain(band: &TargetBand<'_>) -> bool {
    band.samples().count() == 1 && band.overdraw.is_none() && band.ids.is_none()
}

/// Pixels whose centres lie in the splat's square (or disk) get it, where it passes LESS; so
/// does the pixel containing the splat's centre, so that a splat smaller than a pixel still
/// covers one (otherwise sub-pixel splats between pixel centres would leave holes).
///
/// `plain`: [`plain`]`(band)`, a fact of the band the caller decides once per tile.
fn draw_splat(
    band: &mut TargetBand<'_>,
    s: &Splat,
    shape: SplatShape,
    clip: &PixelRect,
    plain: bool,
) -> u64 {
    let [x0, y0, x1, y1] = s.rect;
    if plain && x0 == x1 && y0 == y1 {
        // Most splats at a 1-pixel threshold: the footprint is the pixel containing the
        // centre, which a splat always covers (the run's tile holds it).
        let i = band.index(i32::from(x0), i32::from(y0));
        if s.depth < band.depth[i] {
            band.depth[i] = s.depth;
            band.color[i] = s.color;
            return 1;
        }
        return 0;
    }
    let Some(r) = s.rect().and_then(|r| r.intersect(clip)) else { return 0 };
    // The pixel containing the centre (inside the footprint, so not far off).
    let [hx, hy, _, _] = floor_i32x4([s.x, s.y, 0.0, 0.0]);
    let n = band.samples().count();
    let z = s.depth;
    let round = shape == SplatShape::Round;
    let covers = |px: i32, py: i32| {
        let (dx, dy) = (px as f32 + 0.5 - s.x, py as f32 + 0.5 - s.y);
        !round || dx * dx + dy * dy <= s.half_squared || (px == hx && py == hy)
    };
    let mut written = 0;
    if plain {
        // The common case, one sample and colour plus depth only: a row's pixels are
        // contiguous, so the loop runs over row slices.
        let len = (r.x1 - r.x0 + 1) as usize;
        for py in r.y0..=r.y1 {
            let row = band.index(r.x0, py);
            let depth = &mut band.depth[row..row + len];
            let color = &mut band.color[row..row + len];
            for (k, (d, c)) in depth.iter_mut().zip(color).enumerate() {
                if z < *d && covers(r.x0 + k as i32, py) {
                    *d = z;
                    *c = s.color;
                    written += 1;
                }
            }
        }
        return written;
    }
    for py in r.y0..=r.y1 {
        for px in r.x0..=r.x1 {
            if !covers(px, py) {
                continue;
            }
            let p = band.index(px, py);
            if let Some(o) = band.overdraw.as_deref_mut() {
                o[p] += n as u32;
            }
            for k in p * n..(p + 1) * n {
                if z < band.depth[k] {
                    band.depth[k] = z;
                    band.color[k] = s.color;
                    if let Some(ids) = band.ids.as_deref_mut() {
                        ids[k] = s.id;
                    }
                    written += 1;
                }
            }
        }
    }
    written
}

/// Incremental refinement: each step renders a complete frame one level finer (thresholds
/// 64, 16, 4 and 1 times the final one), so a viewer shows a coarse image at once and the
/// full-detail image after the last step. A step whose splats are all leaves (single points)
/// is the last: the threshold only decides where inner nodes stop refining, so every finer
/// level would draw the same image (a tree of one node, or a cloud seen up close).
#[derive(Clone, Debug)]
pub struct Progressive {
    thresholds: Vec<f32>,
    next: usize,
}

impl Progressive {
    /// Levels ending at `final_threshold` pixels (0 ends by drawing every leaf).
    #[must_use]
    pub fn new(final_threshold: f32) -> Self {
        let base = if final_threshold > 0.0 { final_threshold } else { 0.5 };
        let mut thresholds: Vec<f32> = [64.0, 16.0, 4.0].iter().map(|k| base * k).collect();
        thresholds.push(final_threshold.max(0.0));
        Self { thresholds, next: 0 }
    }

    /// True once the final level has been drawn, or a level whose splats were all leaves
    /// (whose image the final level would only draw again).
    #[must_use]
    pub fn is_done(&self) -> bool {
        self.next >= self.thresholds.len()
    }

    /// Threshold of the next step, if any.
    #[must_use]
    pub fn next_threshold(&self) -> Option<f32> {
        self.thresholds.get(self.next).copied()
    }

    /// Skips the next level without drawing it.
    pub fn skip(&mut self) {
        self.next += 1;
    }

    /// Clears `target` to `clear` and renders the next level; `None` when already done. When
    /// every splat drawn is a leaf (`stats.drawn == stats.leaves_drawn`: no node stood for
    /// several points), that image is the final one and the levels left are dropped.
    pub fn step(
        &mut self,
        target: &mut Target,
        tree: &SplatTree,
        camera: &Camera,
        options: &SplatOptions,
        clear: [u8; 4],
    ) -> Option<(f32, SplatStats)> {
        let threshold = self.next_threshold()?;
        self.next += 1;
        target.clear(clear);
        let stats = render(target, tree, camera, &options.with_threshold(threshold));
        if stats.drawn == stats.leaves_drawn {
            self.next = self.thresholds.len();
        }
        Some((threshold, stats))
    }
}

#[cfg(test)]
mod tests {
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::camera::Projection;
    use crate::splat::PointCloud;

    /// What a classification decides, without the `inside` hint it passes down.
    fn decision(v: &Visit) -> String {
        match v {
            Visit::Culled => "culled".into(),
            Visit::AtEye => "at the eye".into(),
            Visit::Draw(s) => format!("{s:?}"),
            Visit::Refine { .. } => "refine".into(),
        }
    }

    /// Binning (splats sorted by tile per part, runs in bins) draws exactly what drawing
    /// every splat over the whole target in traversal order draws. The cloud is a flat
    /// square facing an orthographic camera, so every splat has the same depth and the first
    /// one drawn keeps each pixel (depth LESS): any reordering shows. Splats straddle tile
    /// borders (the target is several tiles wide, splats several pixels across).
    #[test]
    fn binned_drawing_matches_drawing_in_traversal_order() {
        let mut rng = SmallRng::seed_from_u64(8);
        let n = 30_000;
        let positions: Vec<[f32; 3]> = (0..n)
            .map(|_| [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), 0.0])
            .collect();
        let colors = Some((0..n).map(|_| [rng.random(), rng.random(), rng.random()]).collect());
        let cloud = PointCloud {
            normals: Some(vec![[0.0, 0.0, 1.0]; n]),
            positions,
            colors,
            radii: Some((0..n).map(|_| rng.random_range(0.002..0.03)).collect()),
            ..PointCloud::default()
        };
        let tree = SplatTree::build(&cloud).unwrap();
        let camera = Camera {
            eye: Vec3::new(0.0, 0.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            projection: Projection::Orthographic { height: 2.2 },
            near: 0.5,
            far: 4.0,
        };
        for (threshold, shape) in [(0.0, SplatShape::Round), (3.0, SplatShape::Square)] {
            let options = SplatOptions::default().with_threshold(threshold).with_shape(shape);
            let mut binned = Target::new(300, 200).unwrap().with_ids();
            render(&mut binned, &tree, &camera, &options);
            // The oracle: the same traversal, one splat at a time onto one band.
            let mut ordered = Target::new(300, 200).unwrap().with_ids();
            let view = View::new(&tree, &camera, &options, 300, 200);
            let mut frontier = vec![0usize];
            let mut drawn = 0;
            while !frontier.is_empty() {
                let mut next = Vec::new();
                for &i in &frontier {
                    match view.classify(i, false) {
                        Visit::Culled | Visit::AtEye => {}
                        Visit::Draw(s) => {
                            let mut band = ordered.band();
                            let (all, plain) = (band.rect(), plain(&band));
                            drawn += usize::from(draw_splat(&mut band, &s, shape, &all, plain) > 0);
                        }
                        Visit::Refine { .. } => next.extend(tree.children(i)),
                    }
                }
                frontier = next;
            }
            assert!(drawn > 1000, "{drawn}");
            assert!(binned.ids == ordered.ids, "threshold {threshold}");
            assert!(binned.color == ordered.color);
        }
    }

    /// Both ways of sorting a chunk by tile give the same part: on a 16384 x 16384 grid,
    /// splats scattered over it (some across tile borders, some off it) and bunched in a
    /// corner.
    #[test]
    fn counting_and_comparison_sorts_agree() {
        let mut rng = SmallRng::seed_from_u64(9);
        let screen = PixelRect::of_target(16384, 16384);
        let grid = TileGrid::of_size(16384, 16384);
        for spread in [16384.0, 300.0] {
            let mut a = PartBuilder::new(CHUNK, &grid);
            let mut b = PartBuilder::new(CHUNK, &grid);
            for k in 0..3000 {
                let (x, y) = (rng.random_range(-50.0..spread), rng.random_range(-50.0..spread));
                let half = rng.random_range(0.5..90.0);
                let rect = footprint(x, y, half, &screen)
                    .map_or([1, 0, 0, 0], |r| [r.x0, r.y0, r.x1, r.y1].map(|v| v as u16));
                let s = Splat {
                    x,
                    y,
                    half_squared: half * half,
                    depth: 0.5,
                    color: [0; 4],
                    id: k,
                    rect,
                };
                a.push(s);
                b.push(s);
            }
            let (a, b) = (a.sorted(true), b.sorted(false));
            assert!(a.runs.len() > 10 && a.splats.len() > 3000, "{}", a.runs.len());
            assert_eq!(format!("{:?}", a.runs), format!("{:?}", b.runs));
            assert!(a.splats.iter().zip(&b.splats).all(|(s, t)| s.id == t.id));
        }
    }

    /// The frustum shortcut changes no decision: under every parent that lies inside all
    /// planes, each child classifies the same with the plane tests skipped as with them, on
    /// a sphere cut by the image's sides and by the far plane.
    #[test]
    fn skipping_plane_tests_under_an_inside_parent_changes_nothing() {
        let mut rng = SmallRng::seed_from_u64(5);
        let positions: Vec<[f32; 3]> = (0..20_000)
            .map(|_| {
                let v = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                v.normalize_or(Vec3::X).to_array()
            })
            .collect();
        let cloud =
            PointCloud { normals: Some(positions.clone()), positions, ..PointCloud::default() };
        let tree = SplatTree::build(&cloud).unwrap();
        let camera = Camera {
            eye: Vec3::new(0.0, 0.0, 2.2),
            target: Vec3::new(0.8, 0.0, 0.0),
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y: 0.7 },
            near: 0.5,
            far: 2.6,
        };
        let options = SplatOptions::default().with_threshold(0.0);
        let view = View::new(&tree, &camera, &options, 160, 120);
        let (mut checked, mut culled) = (0, 0);
        for i in 0..tree.nodes.len() {
            if let Visit::Refine { inside: true } = view.classify(i, false) {
                for k in tree.children(i) {
                    let full = view.classify(k, false);
                    culled += usize::from(matches!(full, Visit::Culled));
                    assert_eq!(decision(&view.classify(k, true)), decision(&full), "node {k}");
                    checked += 1;
                }
            }
        }
        let outside = (0..tree.nodes.len())
            .filter(|&i| matches!(view.classify(i, false), Visit::Culled))
            .count();
        assert!(checked > 1000 && outside > 1000, "{checked} checked, {outside} culled");
        // Under an inside parent, only back faces are culled.
        assert!(culled < checked);
    }

    /// Leaves whose sphere reaches the camera's plane are counted as such, not as culled, and
    /// only they: a row of points along the view axis, the nearest ones closer to the eye than
    /// their radius.
    #[test]
    fn leaves_at_the_eye_are_counted() {
        let n = 40;
        let cloud = PointCloud {
            positions: (0..n).map(|k| [0.0, 0.0, -0.25 * k as f32]).collect(),
            radii: Some(vec![0.6; n]),
            ..PointCloud::default()
        };
        let tree = SplatTree::build(&cloud).unwrap();
        let camera = Camera {
            eye: Vec3::ZERO,
            target: Vec3::NEG_Z,
            up: Vec3::Y,
            projection: Projection::Perspective { fov_y: 0.8 },
            near: 0.01,
            far: 100.0,
        };
        let options = SplatOptions::default().with_threshold(0.0);
        let mut target = Target::new(64, 48).unwrap();
        let stats = render(&mut target, &tree, &camera, &options);
        // Depths 0, 0.25 and 0.5 are within 0.6 of the eye's plane; 0.75 on are not.
        assert_eq!(stats.at_eye, 3, "{stats:?}");
        assert_eq!(stats.leaves_drawn, n - 3, "{stats:?}");
        assert_eq!(stats.culled, 0, "{stats:?}");
    }
}
