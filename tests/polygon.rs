//! Polygon properties: triangulations tile random simple polygons (convex and not, with and
//! without holes) exactly, the 2D fill lights exactly the pixel centres inside the snapped
//! polygon (each once), mesh faces keep their winding, and twisted faces give `n - 2` triangles
//! using every corner even where a projection puts two corners on one point.
//!
//! Polygons are generated on the 1/256-pixel grid (so snapping is the identity and the
//! oracle sees exactly the vertices the rasterizer sees), often with vertices and axis-aligned
//! edges on pixel centres. Centres exactly on the boundary are *not* skipped: the oracle decides
//! them by the top-left convention, stated for a polygon as "the centre nudged right by `ε` and
//! down by `ε²` is inside". Every generated polygon is checked valid with exact integer tests
//! (simple rings, holes strictly inside the outer ring and disjoint), because earcut only
//! promises a tiling for valid input.

use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::polygon::{
    fill_polygon, fill_polygon_with, triangulate_face, triangulate_polygon, triangulate_snapped,
};
use trirast::{Algorithm, CullMode, RenderOptions, Target, fixed};

/// A fixed-point point, 1/256 pixel units.
type P = [i64; 2];

/// Target size for the fill tests: small, odd-sized, polygons overlap its borders.
const W: u32 = 47;
const H: u32 = 39;

// ---------------------------------------------------------------------------------------------
// Exact geometry.

/// Twice the signed area of `abc` (the cross product `(b - a) x (c - a)`).
fn cross(a: P, b: P, c: P) -> i128 {
    let d = |p: P, q: P, k: usize| i128::from(q[k] - p[k]);
    d(a, b, 0) * d(a, c, 1) - d(a, c, 0) * d(a, b, 1)
}

/// Twice the signed area of a ring.
fn ring_area2(ring: &[P]) -> i128 {
    (0..ring.len()).map(|i| cross([0, 0], ring[i], ring[(i + 1) % ring.len()])).sum()
}

/// Is `q`, collinear with segment `pr`, within its bounding box (so on the closed segment)?
fn on_segment(p: P, q: P, r: P) -> bool {
    q[0] >= p[0].min(r[0])
        && q[0] <= p[0].max(r[0])
        && q[1] >= p[1].min(r[1])
        && q[1] <= p[1].max(r[1])
}

/// Do the closed segments `ab` and `cd` share any point?
fn segments_touch(a: P, b: P, c: P, d: P) -> bool {
    let (d1, d2) = (cross(a, b, c).signum(), cross(a, b, d).signum());
    let (d3, d4) = (cross(c, d, a).signum(), cross(c, d, b).signum());
    if d1 * d2 < 0 && d3 * d4 < 0 {
        return true;
    }
    (d1 == 0 && on_segment(a, c, b))
        || (d2 == 0 && on_segment(a, d, b))
        || (d3 == 0 && on_segment(c, a, d))
        || (d4 == 0 && on_segment(c, b, d))
}

/// Crossing parity of the ray from the nudged sample `s + (ε, ε²)` towards +x.
///
/// An edge crosses the horizontal line `y = s.y + ε²` iff exactly one end is strictly below
/// `s.y` (integers), and it does so at `x = s.x + n / dy + O(ε²)` with
/// `n = (a.x - s.x) dy + (s.y - a.y) dx`; that is right of `s.x + ε` iff `n / dy > 0` (when
/// `n = 0`, the sample is on the edge and the crossing is `O(ε²)`, left of `s.x + ε`).
fn crosses(a: P, b: P, s: P) -> bool {
    if (a[1] > s[1]) == (b[1] > s[1]) {
        return false;
    }
    let (dx, dy) = (i128::from(b[0] - a[0]), i128::from(b[1] - a[1]));
    let n = i128::from(a[0] - s[0]) * dy + i128::from(s[1] - a[1]) * dx;
    n.signum() * dy.signum() > 0
}

/// Is `s` exactly on the edge `ab`?
fn on_edge(a: P, b: P, s: P) -> bool {
    cross(a, b, s) == 0 && on_segment(a, s, b)
}

/// Point in polygon (even-odd over all rings) for the nudged sample: the top-left convention.
fn inside(rings: &[Vec<P>], s: P) -> bool {
    let mut odd = false;
    for ring in rings {
        for i in 0..ring.len() {
            odd ^= crosses(ring[i], ring[(i + 1) % ring.len()], s);
        }
    }
    odd
}

/// Exact validity: rings of >= 3 points, no zero-length edges, no ring touching itself except
/// adjacent edges at their shared corner (without folding back), no two rings touching, every
/// hole inside the outer ring and outside every other hole.
fn is_valid(rings: &[Vec<P>]) -> bool {
    let mut edges = Vec::new();
    for (r, ring) in rings.iter().enumerate() {
        let n = ring.len();
        if n < 3 || ring_area2(ring) == 0 {
            return false;
        }
        for i in 0..n {
            let (a, b, c) = (ring[i], ring[(i + 1) % n], ring[(i + 2) % n]);
            if a == b {
                return false;
            }
            // Adjacent edges a->b, b->c: folding back onto a->b is an overlap.
            let dot = (b[0] - a[0]) * (c[0] - b[0]) + (b[1] - a[1]) * (c[1] - b[1]);
            if cross(a, b, c) == 0 && dot < 0 {
                return false;
            }
            edges.push((r, i, n, a, b));
        }
    }
    for (x, &(r1, i1, n1, a, b)) in edges.iter().enumerate() {
        for &(r2, i2, _, c, d) in &edges[x + 1..] {
            let adjacent = r1 == r2 && (i2 == i1 + 1 || (i1 == 0 && i2 == n1 - 1));
            if !adjacent && segments_touch(a, b, c, d) {
                return false;
            }
        }
    }
    // No crossings: one corner decides where a whole ring lies.
    let holes = &rings[1..];
    holes.iter().enumerate().all(|(i, h)| {
        inside(&rings[..1], h[0])
            && holes
                .iter()
                .enumerate()
                .all(|(j, g)| i == j || !inside(std::slice::from_ref(g), h[0]))
    })
}

// ---------------------------------------------------------------------------------------------
// Random valid polygons on the 1/256 grid.

/// Where vertices may lie: pixel centres, pixel corners, half pixels, or any 1/256 step.
#[derive(Clone, Copy, Debug)]
enum Grid {
    Centres,
    Corners,
    Halves,
    Any,
}

impl Grid {
    fn random(rng: &mut SmallRng) -> Self {
        [Self::Centres, Self::Corners, Self::Halves, Self::Any][rng.random_range(0..4)]
    }

    /// Rounds `v` pixels to the grid, in fixed point.
    fn round(self, v: f64) -> i64 {
        let (step, offset) = match self {
            Self::Centres => (256, 128),
            Self::Corners => (256, 0),
            Self::Halves => (128, 0),
            Self::Any => (1, 0),
        };
        (((v * 256.0) - offset as f64) / step as f64).round() as i64 * step + offset
    }
}

/// A star-shaped ring around `c` (pixels): sorted random angles, radii in `[r0, r1]`.
fn star(rng: &mut SmallRng, grid: Grid, c: [f64; 2], r0: f64, r1: f64, n: usize) -> Vec<P> {
    let mut angles: Vec<f64> =
        (0..n).map(|_| rng.random_range(0.0..std::f64::consts::TAU)).collect();
    angles.sort_by(f64::total_cmp);
    let mut ring: Vec<P> = angles
        .iter()
        .map(|a| {
            let r = if r1 > r0 { rng.random_range(r0..=r1) } else { r0 };
            [grid.round(c[0] + r * a.cos()), grid.round(c[1] + r * a.sin())]
        })
        .collect();
    ring.dedup();
    ring
}

/// A rectilinear comb: columns between random x breakpoints, each spanning a common band and
/// reaching up and down by random amounts (teeth on both sides); then a random symmetry of the
/// square and translation. Neighbouring columns always overlap in the band, so it is simple.
fn comb(rng: &mut SmallRng, grid: Grid, origin: [f64; 2], scale: f64) -> Vec<P> {
    let k = rng.random_range(2..12);
    let mut xs = vec![0.0];
    for _ in 0..k {
        let w = rng.random_range(0.5..3.0) * scale;
        xs.push(xs.last().unwrap() + w);
    }
    let band = rng.random_range(0.5..2.0) * scale;
    let tops: Vec<f64> = (0..k).map(|_| -rng.random_range(0.0..4.0) * scale).collect();
    let bottoms: Vec<f64> = (0..k).map(|_| band + rng.random_range(0.0..4.0) * scale).collect();
    let mut pts = Vec::new();
    for i in 0..k {
        pts.push([xs[i], tops[i]]);
        pts.push([xs[i + 1], tops[i]]);
    }
    for i in (0..k).rev() {
        pts.push([xs[i + 1], bottoms[i]]);
        pts.push([xs[i], bottoms[i]]);
    }
    let (transpose, fx, fy) = (rng.random::<bool>(), rng.random::<bool>(), rng.random::<bool>());
    let mut ring: Vec<P> = pts
        .iter()
        .map(|&[x, y]| {
            let (x, y) = if transpose { (y, x) } else { (x, y) };
            let (x, y) = (if fx { -x } else { x }, if fy { -y } else { y });
            [grid.round(origin[0] + x), grid.round(origin[1] + y)]
        })
        .collect();
    ring.dedup();
    while ring.len() > 1 && ring.first() == ring.last() {
        ring.pop();
    }
    if rng.random() {
        ring.reverse();
    }
    ring
}

/// The strictly convex hull (monotone chain, collinear points dropped) of random points.
fn convex(rng: &mut SmallRng, grid: Grid, c: [f64; 2], r: f64) -> Vec<P> {
    let n = rng.random_range(3..30);
    let mut pts: Vec<P> = (0..n)
        .map(|_| {
            let (a, d) =
                (rng.random_range(0.0..std::f64::consts::TAU), r * rng.random_range(0.3..1.0f64));
            [grid.round(c[0] + d * a.cos()), grid.round(c[1] + d * a.sin())]
        })
        .collect();
    pts.sort();
    pts.dedup();
    let mut hull: Vec<P> = Vec::new();
    for pass in 0..2 {
        let start = hull.len();
        for &p in &pts {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
        if pass == 0 {
            pts.reverse();
        }
    }
    if rng.random() {
        hull.reverse();
    }
    hull
}

/// The kinds of outer boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    Convex,
    Star,
    Comb,
    Huge,
}

/// A random valid outer ring of `kind`, mostly around the target.
fn outer(rng: &mut SmallRng, kind: Kind) -> Vec<P> {
    loop {
        let grid = Grid::random(rng);
        let c = [
            rng.random_range(-8.0..f64::from(W) + 8.0),
            rng.random_range(-8.0..f64::from(H) + 8.0),
        ];
        let r1 = rng.random_range(1.0..40.0);
        let r0 = r1 * rng.random_range(0.05..1.0);
        let n = rng.random_range(3..40);
        let ring = match kind {
            Kind::Convex => convex(rng, grid, c, r1),
            Kind::Star => star(rng, grid, c, r0, r1, n),
            Kind::Comb => {
                let scale = rng.random_range(0.3..5.0);
                comb(rng, grid, [c[0] - 20.0, c[1] - 10.0], scale)
            }
            // Spans far more than 4096 pixels: the f64 earcut path.
            Kind::Huge => {
                let r1 = r1 * 750.0;
                star(rng, grid, c, r1 * 0.2, r1, n % 10 + 3)
            }
        };
        if is_valid(std::slice::from_ref(&ring)) {
            return ring;
        }
    }
}

/// A random valid polygon: an outer ring of `kind` with up to `max_holes` small star-shaped
/// holes, placed where they are visible in the target when possible.
fn polygon(rng: &mut SmallRng, kind: Kind, max_holes: usize) -> Vec<Vec<P>> {
    let mut rings = vec![outer(rng, kind)];
    let want = rng.random_range(0..=max_holes);
    let (lo, hi) = bbox(&rings[0]);
    let px = |v: i64| v as f64 / 256.0;
    let range = |a: f64, b: f64, m: f64| {
        let (a2, b2) = (a.max(-2.0), b.min(m + 2.0));
        if a2 < b2 { (a2, b2) } else { (a, b) }
    };
    let (x0, x1) = range(px(lo[0]), px(hi[0]), f64::from(W));
    let (y0, y1) = range(px(lo[1]), px(hi[1]), f64::from(H));
    let mut attempts = 0;
    while rings.len() <= want && attempts < 30 {
        attempts += 1;
        let c = [rng.random_range(x0..=x1), rng.random_range(y0..=y1)];
        let r1 = rng.random_range(0.3..((x1 - x0).min(y1 - y0) / 3.0).max(0.5));
        let (grid, r0, n) =
            (Grid::random(rng), r1 * rng.random_range(0.2..1.0), rng.random_range(3..9));
        let hole = star(rng, grid, c, r0, r1, n);
        rings.push(hole);
        if !is_valid(&rings) {
            rings.pop();
        }
    }
    rings
}

fn bbox(ring: &[P]) -> (P, P) {
    let mut lo = [i64::MAX; 2];
    let mut hi = [i64::MIN; 2];
    for p in ring {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    (lo, hi)
}

/// Twice the polygon's area, exactly: outer minus holes.
fn polygon_area2(rings: &[Vec<P>]) -> i128 {
    ring_area2(&rings[0]).abs() - rings[1..].iter().map(|h| ring_area2(h).abs()).sum::<i128>()
}

fn concat(rings: &[Vec<P>]) -> Vec<P> {
    rings.iter().flatten().copied().collect()
}

fn kind_of(i: usize) -> Kind {
    [Kind::Convex, Kind::Star, Kind::Comb, Kind::Star, Kind::Comb, Kind::Huge][i % 6]
}

// ---------------------------------------------------------------------------------------------
// (a) Triangles tile the polygon: total area equals the polygon's area.

/// Checks that both triangulations of `rings` tile it, and returns them (snapped, then
/// `f64`). Exact: the snapped triangulation, in integers, every triangle wound like the outer
/// ring and none empty, so the absolute areas cannot cancel: their sum is the polygon's area.
/// Floating point: the same polygon in pixels through `triangulate_polygon`, to 1e-9 of it.
fn assert_tiles(rings: &[Vec<P>]) -> (Vec<[usize; 3]>, Vec<[usize; 3]>) {
    let pts = concat(rings);
    let expected = polygon_area2(rings);
    let outer_sign = ring_area2(&rings[0]).signum();
    let snapped: Vec<Vec<[i32; 2]>> =
        rings.iter().map(|r| r.iter().map(|p| p.map(|v| v as i32)).collect()).collect();
    let tris = triangulate_snapped(&snapped);
    let mut total = 0;
    for t in &tris {
        let a = cross(pts[t[0]], pts[t[1]], pts[t[2]]);
        assert_eq!(a.signum(), outer_sign, "triangle {t:?} flipped or empty in {rings:?}");
        total += a.abs();
    }
    assert_eq!(total, expected, "exact area mismatch for {rings:?}");

    let float: Vec<Vec<[f64; 2]>> =
        rings.iter().map(|r| r.iter().map(|p| p.map(|v| v as f64 / 256.0)).collect()).collect();
    let fpts: Vec<[f64; 2]> = float.iter().flatten().copied().collect();
    let ftris = triangulate_polygon(&float);
    let mut ftotal = 0.0;
    for t in &ftris {
        let [a, b, c] = t.map(|k| fpts[k]);
        let s = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
        assert_eq!(s.signum() as i128, outer_sign, "f64 triangle {t:?} flipped in {rings:?}");
        ftotal += s.abs();
    }
    let fexpected = expected as f64 / 65536.0;
    assert!(
        (ftotal - fexpected).abs() <= 1e-9 * fexpected,
        "f64 area {ftotal} != {fexpected} for {rings:?}"
    );
    (tris, ftris)
}

#[test]
fn triangulations_add_up_to_the_polygon_area() {
    let mut rng = SmallRng::seed_from_u64(0x5eed_a4ea);
    let (mut with_holes, mut earcut_used) = (0, 0);
    for i in 0..3000 {
        let rings = polygon(&mut rng, kind_of(i), 4);
        with_holes += usize::from(rings.len() > 1);
        let (tris, _) = assert_tiles(&rings);
        earcut_used += usize::from(tris.iter().enumerate().any(|(j, t)| *t != [0, j + 1, j + 2]));
    }
    assert!(with_holes > 1000, "only {with_holes} polygons with holes");
    assert!(earcut_used > 1500, "only {earcut_used} polygons went through earcut");
}

// ---------------------------------------------------------------------------------------------
// (b) The fill lights exactly the centres inside the polygon, each once.

/// Fills `rings` and compares every pixel with the oracle; returns the number of pixel
/// centres lying exactly on the boundary (decided by the top-left convention).
fn check_fill(rings: &[Vec<P>], options: Option<&RenderOptions>) -> usize {
    let mut target = Target::new(W, H).unwrap().with_overdraw();
    let float: Vec<Vec<[f32; 2]>> =
        rings.iter().map(|r| r.iter().map(|p| p.map(|v| v as f32 / 256.0)).collect()).collect();
    let color = [10, 200, 30, 255];
    let stats = match options {
        Some(o) => fill_polygon_with(&mut target, &float, color, o),
        None => fill_polygon(&mut target, &float, color),
    }
    .unwrap();
    let overdraw = target.overdraw.as_ref().unwrap();
    let mut ties = 0;
    let mut lit = 0;
    for py in 0..H as i64 {
        let sy = py * 256 + 128;
        // Only the edges crossing this row can matter (or contain its centres).
        let row: Vec<Vec<P>> = rings
            .iter()
            .map(|r| {
                let n = r.len();
                (0..n)
                    .filter(|&i| {
                        let (a, b) = (r[i], r[(i + 1) % n]);
                        a[1].min(b[1]) <= sy && a[1].max(b[1]) >= sy
                    })
                    .flat_map(|i| [r[i], r[(i + 1) % n]])
                    .collect()
            })
            .collect();
        for px in 0..W as i64 {
            let s = [px * 256 + 128, sy];
            // Pairs of points, each pair one edge.
            let mut odd = false;
            let mut on_boundary = false;
            for pairs in &row {
                for e in pairs.chunks_exact(2) {
                    odd ^= crosses(e[0], e[1], s);
                    on_boundary |= on_edge(e[0], e[1], s);
                }
            }
            ties += usize::from(on_boundary);
            let got = overdraw[target.index(px as i32, py as i32)];
            assert!(got <= 1, "pixel ({px}, {py}) lit {got} times by {rings:?}");
            assert_eq!(got == 1, odd, "pixel ({px}, {py}) (boundary: {on_boundary}) in {rings:?}");
            if odd {
                assert_eq!(target.color[target.index(px as i32, py as i32)], color);
            }
            lit += u64::from(got);
        }
    }
    assert_eq!(stats.fragments, lit);
    ties
}

#[test]
fn fill_lights_exactly_the_centres_inside() {
    let mut rng = SmallRng::seed_from_u64(0xf111);
    let scanline = RenderOptions::default().with_algorithm(Algorithm::Scanline);
    let mut ties = 0;
    for i in 0..1500 {
        let rings = polygon(&mut rng, kind_of(i), 4);
        ties += check_fill(&rings, (i % 5 == 0).then_some(&scanline));
    }
    // The boundary cases are the point of the exercise: make sure there were plenty.
    assert!(ties > 2000, "only {ties} centres on polygon boundaries");
}

/// Polygons reaching past the fixed-point range are drawn, not refused: star-shaped rings
/// (every other one of nine corners or more holding a hole around its centre) with corners
/// from a few pixels to 1e9 pixels away light exactly the centres inside the polygon (corners
/// in the range snapped, those past it whole 1/256ths of a pixel, as given), but for centres
/// within 1/64 pixel of an edge with an end past the range, whose clipped pieces' new corners are
/// rounded; no pixel is lit twice.
#[test]
fn fill_reaches_past_the_range() {
    let mut rng = SmallRng::seed_from_u64(0xfa4);
    let (mut lit, mut near_far_edges, mut far_rounds) = (0, 0, 0);
    for round in 0..300 {
        let c = [
            rng.random_range(-10.0..f64::from(W) + 10.0),
            rng.random_range(-10.0..f64::from(H) + 10.0),
        ];
        let n = rng.random_range(3..16);
        let step = std::f64::consts::TAU / n as f64;
        // A corner at `r` pixels from the centre: the polygon's input and its exact units,
        // snapped in the range; past it, both coordinates whole 1/256ths of a pixel (as any
        // `f32` past the range is), which the fill keeps as they are.
        let corner = |angle: f64, r: f64| -> ([f32; 2], P) {
            let p = [c[0] + r * angle.cos(), c[1] + r * angle.sin()].map(|v| v as f32);
            if let [Some(x), Some(y)] = p.map(fixed::snap) {
                return (p, [i64::from(x), i64::from(y)]);
            }
            let p = p.map(|v| ((f64::from(v) * 256.0).round() / 256.0) as f32);
            (p, p.map(|v| (f64::from(v) * 256.0) as i64))
        };
        let outer: Vec<([f32; 2], P)> = (0..n)
            .map(|k| {
                let angle = (k as f64 + rng.random_range(-0.3..0.3)) * step;
                corner(angle, 10f64.powf(rng.random_range(0.9..9.0)))
            })
            .collect();
        let mut rings = vec![outer];
        if round % 2 == 0 && n >= 9 {
            // Clockwise on screen where the outer ring runs counter-clockwise: a hole within
            // three pixels of the centre, inside every side (corners past 8 pixels, gaps
            // below 1.12 radians between them). Fewer corners may leave the centre outside.
            rings.push((0..4).rev().map(|k| corner(k as f64 * 1.6, 3.0)).collect());
        }
        let input: Vec<Vec<[f32; 2]>> =
            rings.iter().map(|r| r.iter().map(|p| p.0).collect()).collect();
        let exact: Vec<Vec<P>> = rings.iter().map(|r| r.iter().map(|p| p.1).collect()).collect();
        let mut target = Target::new(W, H).unwrap().with_overdraw();
        let stats = fill_polygon(&mut target, &input, [10, 200, 30, 255]).unwrap();
        let overdraw = target.overdraw.unwrap();
        // The edges with an end past the range, in pixels.
        let past = |p: P| p.iter().any(|&u| !(-32768 * 256..32768 * 256).contains(&u));
        let far_edges: Vec<[[f64; 2]; 2]> = exact
            .iter()
            .flat_map(|r| (0..r.len()).map(move |i| (r[i], r[(i + 1) % r.len()])))
            .filter(|&(a, b)| past(a) || past(b))
            .map(|(a, b)| [a, b].map(|p| p.map(|u| u as f64 / 256.0)))
            .collect();
        let near = |s: [f64; 2]| {
            far_edges.iter().any(|[a, b]| {
                let (d, e) = ([b[0] - a[0], b[1] - a[1]], [s[0] - a[0], s[1] - a[1]]);
                let t = ((d[0] * e[0] + d[1] * e[1]) / (d[0] * d[0] + d[1] * d[1])).clamp(0.0, 1.0);
                (e[0] - t * d[0]).hypot(e[1] - t * d[1]) < 1.0 / 64.0
            })
        };
        for py in 0..H as i64 {
            for px in 0..W as i64 {
                let got = overdraw[(py * i64::from(W) + px) as usize];
                assert!(got <= 1, "pixel ({px}, {py}) lit {got} times by {input:?}");
                let s = [px * 256 + 128, py * 256 + 128];
                if near([px as f64 + 0.5, py as f64 + 0.5]) {
                    near_far_edges += 1;
                    continue;
                }
                assert_eq!(
                    got == 1,
                    inside(&exact, s),
                    "pixel ({px}, {py}), round {round}: {input:?}"
                );
                lit += usize::from(got == 1);
            }
        }
        let lit_here = overdraw.iter().map(|&o| u64::from(o)).sum::<u64>();
        assert_eq!(stats.fragments, lit_here, "round {round}");
        far_rounds += usize::from(!far_edges.is_empty());
    }
    // Most of the image is covered in most rounds; hardly any centre lies so near an edge
    // (a tenth of a percent).
    assert!(lit > 300 * (W * H) as usize / 3, "{lit}");
    assert!(near_far_edges < 300 * (W * H) as usize / 1000, "{near_far_edges}");
    assert!(far_rounds > 250, "{far_rounds}");
}

/// Corners past the range at the ends of `f32` (a square over the whole plane, cut along
/// either diagonal by the triangulation), and a keyhole ring past the range: a square hole
/// bridged to the outer ring, its two bridge corners each visited twice, which the Delaunay
/// triangulation refuses and earcut takes. Each lights exactly the centres inside, once.
#[test]
fn fill_past_the_range_at_the_ends_of_f32_and_through_a_keyhole() {
    let square = |r: f32| vec![[-r, -r], [r, -r], [r, r], [-r, r]];
    let keyhole = vec![
        [-4e4, -4e4],
        [4e4, -4e4],
        [4e4, 4e4],
        [-4e4, 4e4],
        [-4e4, 10.0],
        [10.0, 10.0],
        [10.0, 30.0],
        [30.0, 30.0],
        [30.0, 10.0],
        [10.0, 10.0],
        [-4e4, 10.0],
    ];
    let in_hole = |x: u32, y: u32| (10..30).contains(&x) && (10..30).contains(&y);
    // Each ring, and whether it has the hole.
    let cases = [
        (square(3e38), false),
        (square(f32::MAX).into_iter().rev().collect(), false),
        (keyhole, true),
    ];
    for (ring, holed) in cases {
        let inside = |x, y| !(holed && in_hole(x, y));
        let mut target = Target::new(W, H).unwrap().with_overdraw();
        let stats = fill_polygon(&mut target, std::slice::from_ref(&ring), [1, 2, 3, 255]).unwrap();
        let overdraw = target.overdraw.unwrap();
        for py in 0..H {
            for px in 0..W {
                let got = overdraw[(py * W + px) as usize];
                assert_eq!(got, u32::from(inside(px, py)), "pixel ({px}, {py}) of {ring:?}");
            }
        }
        assert_eq!(stats.fragments, overdraw.iter().map(|&o| u64::from(o)).sum::<u64>());
    }
}

#[test]
fn fill_edge_cases() {
    let mut target = Target::new(W, H).unwrap().with_overdraw();
    let square = vec![[2.0, 2.0], [10.0, 2.0], [10.0, 10.0], [2.0, 10.0]];
    // Clockwise on screen (y down): culled as a whole, or drawn as a whole.
    let cull_cw = RenderOptions::default().with_cull(CullMode::Clockwise);
    let s =
        fill_polygon_with(&mut target, std::slice::from_ref(&square), [255; 4], &cull_cw).unwrap();
    assert_eq!((s.culled, s.fragments), (2, 0));
    let cull_ccw = RenderOptions::default().with_cull(CullMode::CounterClockwise);
    let s =
        fill_polygon_with(&mut target, std::slice::from_ref(&square), [255; 4], &cull_ccw).unwrap();
    assert_eq!((s.culled, s.fragments), (0, 64));

    let mut nan = square.clone();
    nan[2][0] = f32::NAN;
    let s = fill_polygon(&mut target, &[nan], [255; 4]).unwrap();
    assert_eq!((s.non_finite, s.fragments), (1, 0));

    // Nothing to fill: no rings, too few points, zero area after snapping.
    for rings in [
        vec![],
        vec![vec![[1.0, 1.0], [5.0, 5.0]]],
        vec![vec![[1.0, 1.0], [1.001, 9.0], [1.0, 20.0]]],
    ] {
        assert_eq!(fill_polygon(&mut target, &rings, [255; 4]).unwrap().fragments, 0);
    }
}

// ---------------------------------------------------------------------------------------------
// (b2) Polygons of more than 1024 corners: the constrained Delaunay path (earcut's time on
// them can grow with the square of the corners), held to the same properties.

/// A spiral strip around `c` (pixels): `m` corners out along one arm of `turns` turns, back
/// along a second arm `width` pixels further out (less than the arms' spacing, so the strip
/// never touches itself). Earcut's worst case: every ear's box holds most of the ring.
fn spiral(grid: Grid, c: [f64; 2], reach: f64, turns: f64, m: usize, width: f64) -> Vec<P> {
    let angle = turns * std::f64::consts::TAU;
    let pitch = (reach - width) / angle;
    let arm = |offset: f64| -> Vec<P> {
        (0..m)
            .map(|i| {
                let t = angle * i as f64 / m as f64;
                let r = 1.0 + offset + pitch * t;
                [grid.round(c[0] + r * t.cos()), grid.round(c[1] + r * t.sin())]
            })
            .collect()
    };
    let mut ring = arm(0.0);
    ring.extend(arm(width).into_iter().rev());
    ring.dedup();
    ring
}

/// A large random polygon (more than 1024 corners after deduplication): a spiral strip, or a
/// star of many corners with up to four holes; with holes placed as [`polygon`] places them.
fn large_polygon(rng: &mut SmallRng, i: usize) -> Vec<Vec<P>> {
    loop {
        let grid = [Grid::Any, Grid::Halves][rng.random_range(0..2)];
        let c = [rng.random_range(15.0..32.0), rng.random_range(12.0..27.0)];
        let ring = if i.is_multiple_of(2) {
            let turns: f64 = rng.random_range(2.0..6.0);
            let reach = rng.random_range(20.0..40.0);
            let width = rng.random_range(0.3..0.8f64) * (reach / turns / 1.2).min(3.0);
            spiral(grid, c, reach, turns, rng.random_range(600..1500), width)
        } else {
            let r1 = rng.random_range(15.0..60.0);
            let (r0, n) = (r1 * rng.random_range(0.3..0.9), rng.random_range(1100..2500));
            star(rng, grid, c, r0, r1, n)
        };
        if ring.len() <= 1024 || !is_valid(std::slice::from_ref(&ring)) {
            continue;
        }
        if i.is_multiple_of(2) {
            return vec![if rng.random() { ring } else { ring.into_iter().rev().collect() }];
        }
        // Holes: small stars where they fit.
        let mut rings = vec![ring];
        for _ in 0..rng.random_range(0..=4) {
            let hc = [rng.random_range(5.0..42.0), rng.random_range(5.0..34.0)];
            let r = rng.random_range(0.5..4.0);
            let (grid, n) = (Grid::random(rng), rng.random_range(3..9));
            rings.push(star(rng, grid, hc, r * 0.3, r, n));
            if !is_valid(&rings) {
                rings.pop();
            }
        }
        return rings;
    }
}

#[test]
fn large_polygons_tile_and_fill_exactly() {
    let mut rng = SmallRng::seed_from_u64(0x1a76e);
    let mut holes = 0;
    for i in 0..12 {
        let rings = large_polygon(&mut rng, i);
        holes += rings.len() - 1;
        let pts = concat(&rings);
        let outer_sign = ring_area2(&rings[0]).signum();
        let (tris, ftris) = assert_tiles(&rings);
        // Every triangulation of n corners and h holes has n + 2h - 2 triangles.
        assert_eq!(tris.len(), pts.len() + 2 * (rings.len() - 1) - 2, "polygon {i}");
        assert_eq!(ftris.len(), tris.len(), "polygon {i}: f64 triangles");
        check_fill(&rings, None);
        // As a mesh face (a spiral's ring, on the plane z = 0 in f32): n - 2 triangles wound
        // like the face.
        if rings.len() == 1 {
            let face: Vec<[f32; 3]> = pts
                .iter()
                .map(|p| p.map(|v| (v as f64 / 256.0) as f32))
                .map(|[x, y]| [x, y, 0.0])
                .collect();
            let tris = triangulate_face(&face);
            assert_n_minus_2(&tris, face.len(), &[]);
            for t in &tris {
                assert_eq!(cross(pts[t[0]], pts[t[1]], pts[t[2]]).signum(), outer_sign);
            }
        }
    }
    assert!(holes >= 4, "only {holes} holes in the large polygons");
}

// ---------------------------------------------------------------------------------------------
// (c) Mesh faces: random 2D polygons embedded in 3D keep their winding and their area.

/// An integer quaternion's rotation matrix scaled by its squared norm: a rotation times an
/// integer, so an integer polygon embeds exactly (and stays exactly planar) in `f32`.
fn scaled_rotation(rng: &mut SmallRng) -> [[i64; 3]; 3] {
    loop {
        let [a, b, c, d] = [(); 4].map(|_| rng.random_range(-6i64..=6));
        if a * a + b * b + c * c + d * d == 0 {
            continue;
        }
        return [
            [a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c)],
            [2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b)],
            [2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d],
        ];
    }
}

fn cross3(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn sub3(a: [i128; 3], b: [i128; 3]) -> [i128; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// A random polygon without holes, centred on the origin, coordinates within 2^13.
fn small_face_polygon(rng: &mut SmallRng, i: usize) -> Vec<P> {
    let mut ring = loop {
        let kind = [Kind::Convex, Kind::Star, Kind::Comb][i % 3];
        let ring = outer(rng, kind);
        let (lo, hi) = bbox(&ring);
        if (0..2).all(|k| hi[k] - lo[k] < 1 << 13) {
            break ring;
        }
    };
    let (lo, hi) = bbox(&ring);
    for p in &mut ring {
        for k in 0..2 {
            p[k] -= (lo[k] + hi[k]) / 2;
        }
    }
    ring
}

#[test]
fn faces_keep_their_winding_and_area() {
    let mut rng = SmallRng::seed_from_u64(0xface);
    let mut fans = 0;
    for i in 0..3000 {
        let ring = small_face_polygon(&mut rng, i);
        let m = scaled_rotation(&mut rng);
        let t: [i64; 3] = [(); 3].map(|_| rng.random_range(-(1 << 20)..(1 << 20)));
        let p3: Vec<[i128; 3]> = ring
            .iter()
            .map(|&[x, y]| [0, 1, 2].map(|k| i128::from(m[k][0] * x + m[k][1] * y + t[k])))
            .collect();
        let face: Vec<[f32; 3]> = p3.iter().map(|p| p.map(|v| v as f32)).collect();
        assert!(face.iter().zip(&p3).all(|(f, p)| (0..3).all(|k| f[k] as i128 == p[k])));
        // Newell normal, exactly: twice the vector area.
        let n = (0..p3.len()).fold([0i128; 3], |acc, j| {
            let c = cross3(p3[j], p3[(j + 1) % p3.len()]);
            [acc[0] + c[0], acc[1] + c[1], acc[2] + c[2]]
        });
        let tris = triangulate_face(&face);
        // Each triangle's normal along the face's (it is parallel: the face is planar), and the
        // vector areas sum to the face's exactly: so the triangles tile the face.
        let mut sum = [0i128; 3];
        for tri in &tris {
            let [a, b, c] = tri.map(|k| p3[k]);
            let tn = cross3(sub3(b, a), sub3(c, a));
            let dot: i128 = (0..3).map(|k| tn[k] * n[k]).sum();
            assert!(
                dot > 0,
                "triangle {tri:?} does not keep the winding of {ring:?} (rotation {m:?})"
            );
            for k in 0..3 {
                sum[k] += tn[k];
            }
        }
        assert_eq!(sum, n, "areas do not add up for {ring:?} (rotation {m:?})");
        if i % 3 == 0 {
            let fan: Vec<[usize; 3]> = (1..ring.len() - 1).map(|j| [0, j, j + 1]).collect();
            assert_eq!(tris, fan, "convex face {ring:?} not fanned");
            fans += 1;
        }
    }
    assert!(fans >= 1000);
}

#[test]
fn faces_under_float_rotations() {
    // Rounded to f32, the faces are only nearly planar: the areas must still add up (no
    // folded triangles) within rounding.
    let mut rng = SmallRng::seed_from_u64(0xf10a7);
    for i in 0..1500 {
        let ring = small_face_polygon(&mut rng, i);
        let q: [f64; 4] = [(); 4].map(|_| rng.random_range(-1.0..1.0));
        let len = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        let [a, b, c, d] = q.map(|v| v / len);
        let m = [
            [a * a + b * b - c * c - d * d, 2.0 * (b * c - a * d), 2.0 * (b * d + a * c)],
            [2.0 * (b * c + a * d), a * a - b * b + c * c - d * d, 2.0 * (c * d - a * b)],
            [2.0 * (b * d - a * c), 2.0 * (c * d + a * b), a * a - b * b - c * c + d * d],
        ];
        let face: Vec<[f32; 3]> = ring
            .iter()
            .map(|&[x, y]| {
                let (x, y) = (x as f64 / 256.0, y as f64 / 256.0);
                [0, 1, 2].map(|k| (m[k][0] * x + m[k][1] * y + 5.0) as f32)
            })
            .collect();
        let p: Vec<[f64; 3]> = face.iter().map(|v| v.map(f64::from)).collect();
        let fcross = |u: [f64; 3], v: [f64; 3]| {
            [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
        };
        let fsub = |u: [f64; 3], v: [f64; 3]| [u[0] - v[0], u[1] - v[1], u[2] - v[2]];
        let norm = |u: [f64; 3]| u.iter().map(|v| v * v).sum::<f64>().sqrt();
        let n = (0..p.len()).fold([0.0; 3], |acc, j| {
            let c = fcross(p[j], p[(j + 1) % p.len()]);
            [acc[0] + c[0], acc[1] + c[1], acc[2] + c[2]]
        });
        let total: f64 = triangulate_face(&face)
            .iter()
            .map(|t| {
                let tn = fcross(fsub(p[t[1]], p[t[0]]), fsub(p[t[2]], p[t[0]]));
                let dot: f64 = (0..3).map(|k| tn[k] * n[k]).sum();
                assert!(dot > -1e-5 * norm(n) * norm(n), "{t:?} flipped in {face:?}");
                norm(tn)
            })
            .sum();
        assert!(
            (total - norm(n)).abs() <= 1e-4 * norm(n),
            "area {total} != {} for {face:?}",
            norm(n)
        );
    }
}

// ---------------------------------------------------------------------------------------------
// (d) Twisted faces: a face of n corners gives n - 2 triangles bounded by its ring, even where
// projecting it along an axis puts two corners on one point.

/// Twice the vector area of a ring: the sum of its corners' cross products.
fn newell3(p: &[[i128; 3]]) -> [i128; 3] {
    (0..p.len()).fold([0; 3], |acc, j| {
        let c = cross3(p[j], p[(j + 1) % p.len()]);
        [acc[0] + c[0], acc[1] + c[1], acc[2] + c[2]]
    })
}

/// Checks that `tris` triangulate a face of `n` corners: `n - 2` triangles of three distinct
/// valid indices, using every corner.
fn assert_n_minus_2(tris: &[[usize; 3]], n: usize, face: &[[f32; 3]]) {
    assert_eq!(tris.len(), n - 2, "{tris:?} for {face:?}");
    for t in tris {
        assert!(t.iter().all(|&i| i < n), "{t:?} out of range for {face:?}");
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2], "{t:?} repeats a corner");
    }
    let mut used: Vec<usize> = tris.iter().flatten().copied().collect();
    used.sort_unstable();
    used.dedup();
    assert_eq!(used, (0..n).collect::<Vec<_>>(), "{tris:?} leaves out corners of {face:?}");
}

/// Do two distinct corners of `face` fall on one point when it is projected along the axis its
/// Newell normal is most aligned with (the last of equals)?
fn projection_merges_corners(face: &[[f32; 3]]) -> bool {
    let p: Vec<[f64; 3]> = face.iter().map(|v| v.map(f64::from)).collect();
    let n = (0..p.len()).fold([0.0f64; 3], |acc, j| {
        let (a, b) = (p[j], p[(j + 1) % p.len()]);
        [
            acc[0] + a[1] * b[2] - a[2] * b[1],
            acc[1] + a[2] * b[0] - a[0] * b[2],
            acc[2] + a[0] * b[1] - a[1] * b[0],
        ]
    });
    let k = (0..3).max_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap();
    let (u, v) = ((k + 1) % 3, (k + 2) % 3);
    (0..p.len()).any(|i| (0..i).any(|j| p[i] != p[j] && p[i][u] == p[j][u] && p[i][v] == p[j][v]))
}

#[test]
fn twisted_quad_gives_two_triangles() {
    // Along y (the normal's largest component), corners 1 and 2 fall on one point: earcut
    // alone returned the one triangle (2, 3, 0).
    let quad = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, -4.0]];
    assert!(projection_merges_corners(&quad));
    let tris = triangulate_face(&quad);
    assert_n_minus_2(&tris, 4, &quad);
    let p: Vec<[i128; 3]> = quad.iter().map(|v| v.map(|c| c as i128)).collect();
    assert_eq!(vector_area(&p, &tris), newell3(&p));
}

/// A chevron (concave at corner 1) with a step up at its notch: along z, corners 1 and 2 fall
/// on one point and earcut alone left out corner 1. The fan from corner 0 folds (its triangle
/// (0, 2, 3) faces down); the face's projection along its normal does not.
#[test]
fn stepped_chevron_is_not_fanned() {
    let face =
        [[0.0, 0.0, 0.0], [2.0, 1.0, 0.0], [2.0, 1.0, 1.0], [4.0, 0.0, 0.0], [2.0, 3.0, 0.0]];
    assert!(projection_merges_corners(&face));
    assert_unfolded(&face, &triangulate_face(&face));
    // With a corner repeated next to itself (which earcut drops), the same.
    for at in 0..face.len() {
        let mut repeated = face.to_vec();
        repeated.insert(at, face[at]);
        assert_unfolded(&repeated, &triangulate_face(&repeated));
    }
}

/// Checks that `tris` are one triangle fewer than the face's distinct corners (a corner equal
/// to the one before it not counted), none degenerate or facing against the face's normal.
fn assert_unfolded(face: &[[f32; 3]], tris: &[[usize; 3]]) {
    let p: Vec<[i128; 3]> = face.iter().map(|v| v.map(|c| c as i128)).collect();
    let distinct = (0..p.len()).filter(|&i| p[i] != p[(i + p.len() - 1) % p.len()]).count();
    assert_eq!(tris.len(), distinct - 2, "{tris:?} for {face:?}");
    let n = newell3(&p);
    for t in tris {
        let c = cross3(sub3(p[t[1]], p[t[0]]), sub3(p[t[2]], p[t[0]]));
        let dot: i128 = (0..3).map(|k| c[k] * n[k]).sum();
        assert!(dot > 0, "{t:?} folds against the face's normal {n:?}: {tris:?} for {face:?}");
    }
}

/// `n` small integer corners of a twisted face: axis-parallel edges and diagonals, hence
/// corners merged by a projection, are common. No three corners collinear (nor two equal), and
/// not planar: every corner is needed, and none can be dropped without leaving area out.
fn twisted_corners(rng: &mut SmallRng, n: usize) -> Vec<[i128; 3]> {
    loop {
        let p: Vec<[i128; 3]> =
            (0..n).map(|_| [(); 3].map(|_| rng.random_range(-2i128..=2))).collect();
        let collinear = (0..n).any(|a| {
            (0..a).any(|b| (0..b).any(|c| cross3(sub3(p[b], p[a]), sub3(p[c], p[a])) == [0; 3]))
        });
        let normal = cross3(sub3(p[1], p[0]), sub3(p[2], p[0]));
        let planar =
            p.iter().all(|&q| (0..3).map(|k| normal[k] * (q[k] - p[0][k])).sum::<i128>() == 0);
        if !collinear && !planar && newell3(&p) != [0; 3] {
            return p;
        }
    }
}

/// The sum of twice the triangles' vector areas (corners `p`): the face's Newell vector when
/// they are bounded by its ring.
fn vector_area(p: &[[i128; 3]], tris: &[[usize; 3]]) -> [i128; 3] {
    tris.iter().fold([0; 3], |acc, t| {
        let c = cross3(sub3(p[t[1]], p[t[0]]), sub3(p[t[2]], p[t[0]]));
        [acc[0] + c[0], acc[1] + c[1], acc[2] + c[2]]
    })
}

#[test]
fn twisted_faces_give_n_minus_2_triangles() {
    let mut rng = SmallRng::seed_from_u64(0x7_415_7ed);
    let mut merged = [0; 7];
    for i in 0..6000 {
        let n = 4 + i % 3;
        let p = twisted_corners(&mut rng, n);
        let face: Vec<[f32; 3]> = p.iter().map(|v| v.map(|c| c as f32)).collect();
        merged[n] += usize::from(projection_merges_corners(&face));
        let tris = triangulate_face(&face);
        assert_n_minus_2(&tris, n, &face);
        // Bounded by the face's ring: the triangles' vector areas add up to the face's.
        assert_eq!(vector_area(&p, &tris), newell3(&p), "{tris:?} not bounded by {face:?}");
    }
    // The point of the exercise: many faces whose axis projection merges corners.
    assert!(merged[4..].iter().all(|&m| m > 100), "only {merged:?} merged projections");

    // The same faces with a corner repeated next to itself: earcut drops the repeat, which
    // leaves nothing out, so they keep earcut's triangles (the fan of a concave face folds).
    for i in 0..3000 {
        let n = 4 + i % 3;
        let p = twisted_corners(&mut rng, n);
        let mut face: Vec<[f32; 3]> = p.iter().map(|v| v.map(|c| c as f32)).collect();
        let at = rng.random_range(0..n);
        face.insert(at, face[at]);
        let tris = triangulate_face(&face);
        assert_eq!(tris.len(), n - 2, "{tris:?} for {face:?}");
        // Each corner of the face once or as its repeat, each triangle's three corners apart.
        let key = |i: usize| face[i].map(f32::to_bits);
        for t in &tris {
            assert!(key(t[0]) != key(t[1]) && key(t[1]) != key(t[2]) && key(t[0]) != key(t[2]));
        }
        let used: std::collections::BTreeSet<_> = tris.iter().flatten().map(|&i| key(i)).collect();
        assert_eq!(used.len(), n, "{tris:?} leaves a corner of {face:?} out");
        let q: Vec<[i128; 3]> = face.iter().map(|v| v.map(|c| c as i128)).collect();
        assert_eq!(vector_area(&q, &tris), newell3(&p), "{tris:?} not bounded by {face:?}");
    }

    // Random float corners, one made to differ from another in a single coordinate.
    for i in 0..3000 {
        let n = 4 + i % 3;
        let mut face: Vec<[f32; 3]> =
            (0..n).map(|_| [(); 3].map(|_| rng.random_range(-1.0f32..1.0))).collect();
        let (a, b) = (rng.random_range(0..n), rng.random_range(1..n));
        let (b, k) = ((a + b) % n, rng.random_range(0..3));
        face[b] = face[a];
        face[b][k] = rng.random_range(-1.0..1.0);
        let tris = triangulate_face(&face);
        assert_n_minus_2(&tris, n, &face);
    }
}

/// Polygons at coordinates whose products overflow or underflow (corners near 1e308, or
/// subnormal near 1e-320) triangulate as their copies at ordinary scale, where the area had
/// come out infinite or zero and they had given no triangles: the same polygon scaled by
/// powers of two, holes and earcut included.
#[test]
fn polygons_at_extreme_scales_triangulate_as_at_ordinary_ones() {
    let mut rng = SmallRng::seed_from_u64(0xe87e);
    for i in 0..200 {
        let rings = polygon(&mut rng, kind_of(i), 4);
        let float: Vec<Vec<[f64; 2]>> =
            rings.iter().map(|r| r.iter().map(|p| p.map(|v| v as f64)).collect()).collect();
        let want = triangulate_polygon(&float);
        assert!(!want.is_empty(), "{rings:?}");
        // 2^-1060 (subnormal) from its bits: `powi` is not exact there, and in debug builds
        // gave 0 (through 1 / 2^1060), so the test failed there alone.
        let tiny = f64::from_bits(1 << (1074 - 1060));
        for scale in [2f64.powi(1000), tiny, 2f64.powi(600), 2f64.powi(-600)] {
            let scaled: Vec<Vec<[f64; 2]>> =
                float.iter().map(|r| r.iter().map(|p| p.map(|c| c * scale)).collect()).collect();
            // The corners scale exactly: integers below 2^24 times a power of two, normal or
            // (the smallest) subnormal with room for their bits.
            assert!(
                scaled
                    .iter()
                    .flatten()
                    .flatten()
                    .zip(float.iter().flatten().flatten())
                    .all(|(s, f)| s / scale == *f)
            );
            assert_eq!(triangulate_polygon(&scaled), want, "scale {scale:e}: {rings:?}");
        }
    }
}
