//! Polygon triangulation: faces of meshes, and exact filling of 2D polygons.
//!
//! Every entry point turns a simple polygon into triangles over its own vertices that tile it
//! (disjoint interiors, union the polygon) and are all wound like the polygon, so culling and
//! normals see one consistent face:
//! - strictly convex polygons without holes get the lectures' fan `(v0, vi, vi+1)`, which is
//!   cheap and exact;
//! - other simple polygons go to [earcut](https://github.com/georust/earcut), a maintained port
//!   of mapbox/earcut (ear clipping with hole bridging), or, above 1024 corners, where
//!   earcut's time can grow with the square of the corners, to a constrained Delaunay
//!   triangulation ([spade](https://github.com/Stoeoef/spade)), earcut taking what that
//!   cannot triangulate;
//! - a twisted face can project onto a degenerate ring (two corners on one point, the ring
//!   crossing itself) of which earcut leaves corners out, a hole in the mesh: it is projected
//!   again, along its Newell normal and then the other axes, until earcut uses every corner,
//!   and takes the fan if it never does;
//! - polygons through one point more than twice are not simple, and earcut's time on them
//!   grows with the cube of their length: faces take the fan, 2D polygons give nothing; so
//!   do polygons of more than 1024 corners whose sides cross, and of more than 16,384 that
//!   the Delaunay triangulation refuses (earcut's time on them grows with the square).
//!
//! [`fill_polygon`] is the exact 2D fill. It snaps the vertices to the rasterizer's 1/256-pixel
//! grid *first* and triangulates the snapped integers with exact predicates, so the triangles
//! tile the snapped polygon exactly (corners past the fixed-point range, which cannot be
//! snapped, are kept as they are, and the triangles reaching them clipped by `draw`). The
//! top-left rule is watertight for any tiling (a sample on an edge or vertex belongs to the
//! one triangle containing the sample nudged right by `ε` and down by `ε²`), hence: a pixel is
//! lit iff its centre is inside the snapped polygon, a centre exactly on the polygon's
//! boundary is lit iff that nudged point is inside (the top-left rule applied to the
//! polygon), and no pixel is lit twice.

use crate::error::Error;
use crate::fixed;
use crate::render::{DrawStats, RenderOptions, draw};
use crate::setup::Vertex;
use crate::shade::{DepthTest, Shading};
use crate::target::Target;
use earcut::Earcut;
use earcut::int::EarcutI32;
use std::collections::HashMap;

use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// At most this many corners of a polygon may lie on one point for earcut to see it. A simple
/// polygon has each point once, a polygon with a hole bridged to its boundary twice at the
/// bridge's ends. Earcut's time on faces that pass through points three times or more grows
/// with the cube of their length: a triangle's corners repeated 1000 times took 4.5 s (a
/// 12 KB OBJ face of 6000 corners, 26 s), a 1000-point star traversed three times 3.7 s,
/// where the same star traversed twice took 6 ms. Such a polygon is not simple, so no
/// triangulation is the right one: faces take the fan, 2D polygons are not drawn.
const MAX_CORNERS_AT_ONE_POINT: usize = 2;

/// Polygons of more corners than this are triangulated by a constrained Delaunay
/// triangulation ([spade](https://github.com/Stoeoef/spade)) rather than earcut. Earcut clips
/// one ear at a time and checks each candidate against the corners in its box: on a tight
/// spiral most of the ring lies in every candidate's box, and its time grows with the square
/// of the corners (a planar spiral face of 80,000 corners, a 5 MB OBJ, took 24 s). Spade's
/// bulk load takes `O(n log n)`. Below this, earcut's worst case is a few milliseconds, and
/// faces keep the triangles they always had.
const CDT_ABOVE_CORNERS: usize = 1024;

/// Rings of more corners than this that the constrained Delaunay triangulation refuses get no
/// triangles (faces take the fan) rather than earcut's. They are not simple: two corners on
/// one point (a pinch or a bridge), sides that touch, overlap or cross. Earcut's time on such
/// rings grows with the square of their corners (random faces of 20,000 corners took 0.7 s
/// to load, 200,000 corners 34-47 s), while a simple ring of any size takes the Delaunay
/// path in `O(n log n)`.
const EARCUT_AT_MOST_CORNERS: usize = 16_384;

/// Half the side of the square [`EarcutI32`] accepts: coordinates must lie in `[-2^19, 2^19]`.
const EARCUT_I32_HALF_RANGE: i64 = 1 << 19;

/// Triangulates one face given its corner positions in order; returns triangles as indices
/// into `points`, keeping the face's winding.
///
/// The face is projected onto the coordinate plane its Newell normal is most aligned with (so
/// the projection is as little foreshortened as possible), keeping the orientation: every
/// output triangle's normal points the same way as the face's Newell normal. A strictly convex
/// face gives exactly the fan `(0, i, i + 1)`; other faces are triangulated by earcut (above
/// 1024 corners by a constrained Delaunay triangulation where that covers every corner).
///
/// A twisted (non-planar) face can project onto a degenerate ring (two corners on one point,
/// the ring touching or crossing itself), of which earcut leaves corners out: a hole in the
/// mesh. So a twisted face keeps earcut's triangles only if there are `n - 2` of them, `n`
/// its corners but those equal to the one before them (which earcut drops, leaving nothing
/// out); otherwise it is projected onto the plane perpendicular to its Newell normal, then
/// onto the other coordinate planes, and takes the first projection earcut gives `n - 2`
/// triangles for, the fan over those `n` corners if none does. A planar face (up to rounding) projects one-to-one and
/// keeps earcut's answer, which leaves out only corners repeated or on the line through their
/// neighbours.
///
/// Degenerate input never panics: fewer than 3 points give nothing; a corner with a NaN or
/// infinite coordinate makes the face undefined, and it gives the fan from that corner, every
/// triangle of which the rasterizer drops and counts as non-finite (the fan from corner 0 drew
/// its other triangles over each other: a star of 2,000 corners with one NaN covered three
/// times its area); a zero or non-finite normal of finite corners (collinear or repeated
/// points, an overflow) gives the fan, whose triangles the rasterizer then drops and counts
/// as degenerate, or draws. So does a face passing through one point
/// more than twice (repeats next to each other counting once), which is not a simple polygon
/// and would take earcut time cubic in its length.
#[must_use]
pub fn triangulate_face(points: &[[f32; 3]]) -> Vec<[usize; 3]> {
    let n = points.len();
    if n <= 3 {
        return fan(n);
    }
    if let Some(k) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return fan_from(n, k);
    }
    let normal = newell_normal(points);
    if !normal.iter().all(|c| c.is_finite()) || normal == [0.0; 3] {
        return fan(n);
    }
    // Most aligned first (the last of equals), then the others.
    let mut axes = [0, 1, 2];
    axes.sort_by(|&a, &b| normal[b].abs().total_cmp(&normal[a].abs()).then(b.cmp(&a)));
    let along = |k: usize| -> (Vec<[f64; 2]>, bool) {
        // Axes (k+1, k+2) keep the orientation: the projected signed area is `normal[k] / 2`.
        let (u, v) = ((k + 1) % 3, (k + 2) % 3);
        let ring = points.iter().map(|p| [f64::from(p[u]), f64::from(p[v])]).collect();
        (ring, normal[k] > 0.0)
    };
    let (ring, ccw) = along(axes[0]);
    if is_strictly_convex(&ring) {
        return fan(n);
    }
    // Earcut drops a corner equal to the one before it, which leaves nothing out: the
    // triangles a whole triangulation has are those of the face without such repeats.
    let whole = (n - repeated_corners(points)).saturating_sub(2);
    let simple = most_corners_at_one_point(&ring, &[]) <= MAX_CORNERS_AT_ONE_POINT;
    let tris = if simple { triangulate_rings(&ring, &[], ccw) } else { Vec::new() };
    if tris.len() == whole || is_planar(points, normal) {
        // Earcut gives up on some self-intersecting faces; a fan still draws something sensible.
        return if tris.is_empty() { fan(n) } else { tris };
    }
    let retries = std::iter::once_with(|| (newell_plane(points, normal), true))
        .chain(axes[1..].iter().filter(|&&k| normal[k] != 0.0).map(|&k| along(k)));
    for (ring, ccw) in retries {
        if is_strictly_convex(&ring) {
            return fan(n);
        }
        if most_corners_at_one_point(&ring, &[]) <= MAX_CORNERS_AT_ONE_POINT {
            let tris = triangulate_rings(&ring, &[], ccw);
            if tris.len() == whole {
                return tris;
            }
        }
    }
    // The fan over the corners that are not repeats (a repeat's triangle has no area).
    let kept: Vec<usize> = (0..n).filter(|&i| !repeats(points, i)).collect();
    fan(kept.len()).into_iter().map(|t| t.map(|i| kept[i])).collect()
}

/// Corners equal to the corner before them (round the ring).
fn repeated_corners(points: &[[f32; 3]]) -> usize {
    (0..points.len()).filter(|&i| repeats(points, i)).count()
}

/// Whether corner `i` equals the corner before it (round the ring), `-0.0` and `0.0` being
/// one.
fn repeats(points: &[[f32; 3]], i: usize) -> bool {
    let key = |p: &[f32; 3]| p.map(|c| (c + 0.0).to_bits());
    key(&points[i]) == key(&points[(i + points.len() - 1) % points.len()])
}

/// Whether every corner lies on the plane through the first perpendicular to `normal`, up to
/// 2^-20 of the largest coordinate (16 times the rounding of `f32` coordinates). Corners of a
/// face that flat which a projection puts on one point lie within a few times that of each
/// other: what earcut leaves out is too thin to see.
fn is_planar(points: &[[f32; 3]], normal: [f64; 3]) -> bool {
    let len = dot(normal, normal).sqrt();
    let largest = points.iter().flatten().fold(0.0f64, |m, &c| m.max(f64::from(c).abs()));
    let o = points[0].map(f64::from);
    points.iter().all(|p| {
        let d = [0, 1, 2].map(|k| f64::from(p[k]) - o[k]);
        dot(d, normal).abs() <= len * largest / f64::from(1 << 20)
    })
}

/// The face's corners in an orthonormal basis `(e1, e2)` of the plane perpendicular to its
/// Newell normal, with `e1 x e2` along the normal (so the ring is counter-clockwise): the
/// projection along the normal, which separates corners unless their difference is parallel
/// to it, where dropping a coordinate merges corners that differ only in that coordinate.
fn newell_plane(points: &[[f32; 3]], normal: [f64; 3]) -> Vec<[f64; 2]> {
    let unit = |v: [f64; 3]| {
        let len = dot(v, v).sqrt();
        v.map(|c| c / len)
    };
    let n = unit(normal);
    // The axis least aligned with the normal is far from parallel to it.
    let j = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
    let mut axis = [0.0; 3];
    axis[j] = 1.0;
    let e1 = unit(cross(n, axis));
    let e2 = cross(n, e1);
    // Relative to the first corner, for precision far from the origin.
    let o = points[0].map(f64::from);
    points
        .iter()
        .map(|p| {
            let d = [0, 1, 2].map(|k| f64::from(p[k]) - o[k]);
            [dot(d, e1), dot(d, e2)]
        })
        .collect()
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Triangulates a 2D polygon with holes: `rings[0]` is the outer boundary, the other rings are
/// holes; the result indexes the concatenation of all rings.
///
/// Triangles are wound like the outer ring. Rings must not cross or touch each other (holes
/// strictly inside the outer ring, pairwise disjoint), and each must be simple; for other input
/// the result is whatever earcut or the Delaunay triangulation (above 1024 corners, see the
/// module docs) makes of it, except that rings passing through one point more
/// than twice (repeats next to each other counting once) give no triangles. Non-finite
/// coordinates give no triangles, holes with fewer than 3 points are ignored; finite ones of
/// any magnitude triangulate as the same polygon at ordinary scale. For an exact
/// triangulation of pixel coordinates, see [`triangulate_snapped`].
#[must_use]
pub fn triangulate_polygon(rings: &[Vec<[f64; 2]>]) -> Vec<[usize; 3]> {
    let Some(outer) = rings.first() else {
        return Vec::new();
    };
    if rings.iter().flatten().any(|p| !(p[0].is_finite() && p[1].is_finite())) {
        return Vec::new();
    }
    let largest = rings.iter().flatten().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    if largest > 2f64.powi(500) || (largest > 0.0 && largest < 2f64.powi(-500)) {
        // Products of such coordinates (the area, earcut's orientation tests) overflow or
        // underflow: a square at 1e308 or at 1e-320 had given no triangles. Scaled by a power
        // of two to about 1, in two steps (one factor could be out of range), they are the
        // same polygon, exactly.
        let e = largest.log2().floor() as i32;
        let (a, b) = (2f64.powi(-e / 2), 2f64.powi(-e + e / 2));
        let scaled: Vec<Vec<[f64; 2]>> =
            rings.iter().map(|r| r.iter().map(|p| p.map(|c| c * a * b)).collect()).collect();
        return triangulate_polygon(&scaled);
    }
    let area = shoelace(outer);
    if area == 0.0 || !area.is_finite() {
        return Vec::new();
    }
    if rings.iter().skip(1).all(|h| h.len() < 3) && is_strictly_convex(outer) {
        return fan(outer.len());
    }
    let (data, holes, map) = flatten(rings, |ring| ring.len() >= 3);
    if most_corners_at_one_point(&data, &holes) > MAX_CORNERS_AT_ONE_POINT {
        return Vec::new();
    }
    let tris = triangulate_rings(&data, &holes, area > 0.0);
    tris.into_iter().map(|t| t.map(|i| map[i])).collect()
}

/// Triangulates a polygon with holes given in snapped fixed-point coordinates (1/256 pixel, as
/// [`fixed::snap`] makes them): the triangulation [`fill_polygon`] draws.
///
/// Same conventions as [`triangulate_polygon`], but every predicate is exact: coordinates are
/// integers of magnitude at most 2^23, so earcut's orientation tests are exact (in `i64` through
/// earcut's integer variant when the polygon spans at most 2^20 units, i.e. 4096 pixels, and in
/// `f64`, where such products are still exact, beyond that), and so are spade's (adaptive
/// precision) for polygons of more than 1024 corners. Holes of zero area are ignored:
/// they remove nothing.
#[must_use]
pub fn triangulate_snapped(rings: &[Vec<[i32; 2]>]) -> Vec<[usize; 3]> {
    let Some(outer) = rings.first() else {
        return Vec::new();
    };
    let area = shoelace_exact(outer);
    if area == 0 {
        return Vec::new();
    }
    let keep = |ring: &Vec<[i32; 2]>| shoelace_exact(ring) != 0;
    let as_f64 = |ring: &[[i32; 2]]| -> Vec<[f64; 2]> {
        ring.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]).collect()
    };
    if !rings.iter().skip(1).any(keep) && is_strictly_convex(&as_f64(outer)) {
        return fan(outer.len());
    }
    let (data, holes, map) = flatten(rings, keep);
    if most_corners_at_one_point(&as_f64(&data), &holes) > MAX_CORNERS_AT_ONE_POINT {
        return Vec::new();
    }
    let (mut lo, mut hi) = ([i64::MAX; 2], [i64::MIN; 2]);
    for p in &data {
        for k in 0..2 {
            lo[k] = lo[k].min(i64::from(p[k]));
            hi[k] = hi[k].max(i64::from(p[k]));
        }
    }
    if data.len() > CDT_ABOVE_CORNERS
        && let Some(tris) = large_rings(&as_f64(&data), &holes, area > 0)
    {
        // Spade's orientation tests are exact (adaptive precision), so these triangles
        // tile the snapped polygon as earcut's integer ones do.
        return tris.into_iter().map(|t| t.map(|i| map[i])).collect();
    }
    let mut flat = Vec::new();
    if (0..2).all(|k| hi[k] - lo[k] <= 2 * EARCUT_I32_HALF_RANGE) {
        // Translate into EarcutI32's square; translation changes no predicate.
        let shift = [lo[0] + EARCUT_I32_HALF_RANGE, lo[1] + EARCUT_I32_HALF_RANGE];
        let moved = data
            .iter()
            .map(|p| [(i64::from(p[0]) - shift[0]) as i32, (i64::from(p[1]) - shift[1]) as i32]);
        EarcutI32::new().earcut(moved, &holes, &mut flat);
    } else {
        // |coordinate| <= 2^23: differences, their products and sums are exact in f64.
        Earcut::new().earcut(as_f64(&data), &holes, &mut flat);
    }
    let signed = |t: [usize; 3]| -> i128 {
        let [a, b, c] = t.map(|i| data[i].map(i128::from));
        (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
    };
    let tris = orient(&flat, area > 0, |t| signed(t).signum() as f64);
    tris.into_iter().map(|t| t.map(|i| map[i])).collect()
}

/// Fills a 2D polygon with holes (`rings[0]` outer, the rest holes; window coordinates in
/// pixels, y down) with a flat `color`, painting over what is there (no depth test).
///
/// Exact: a pixel is lit iff its centre lies inside the polygon whose vertices are snapped to
/// the 1/256-pixel grid, centres exactly on its boundary follow the top-left rule, and no pixel
/// is lit twice (see the module docs for why). The rings must form a valid polygon (simple
/// rings, holes strictly inside the outer ring and disjoint from each other, after snapping);
/// other input is drawn as it is triangulated, without panicking, except that rings
/// passing through one point more than twice are not drawn ([`triangulate_snapped`]).
///
/// Rings may reach past the fixed-point range ([-32768, 32768) pixels): such a polygon is
/// triangulated over its corners in the range snapped and those past it as given (with
/// exact predicates where the polygon is simple and has no corner twice), and [`draw`]
/// clips the triangles reaching past the range to it, cutting only their edges with an end
/// past it. A pixel is then lit iff its centre is inside that polygon, as above, except
/// that a centre within a few thousandths of a pixel of an edge with an end past the range
/// may fall on the other side of it (the clip's new corners are rounded to the grid, alike
/// in the triangles sharing them). A NaN or infinite vertex makes the polygon undefined:
/// nothing is drawn and the stats report `non_finite: 1`.
///
/// # Errors
/// Those of [`draw`]: a target whose buffers were replaced by ones of other lengths.
pub fn fill_polygon(
    target: &mut Target,
    rings: &[Vec<[f32; 2]>],
    color: [u8; 4],
) -> Result<DrawStats, Error> {
    let options =
        RenderOptions::default().with_shading(Shading::Flat).with_depth_test(DepthTest::Always);
    fill_polygon_with(target, rings, color, &options)
}

/// [`fill_polygon`] with explicit render options (depth test, cull mode, scissor, algorithm):
/// the triangles are drawn at depth 0, wound like the outer ring, so a cull mode keeps or
/// discards the polygon as a whole.
pub fn fill_polygon_with(
    target: &mut Target,
    rings: &[Vec<[f32; 2]>],
    color: [u8; 4],
    options: &RenderOptions,
) -> Result<DrawStats, Error> {
    // Corners in 1/256-pixel units: snapped where they can be, as given (exact in `f64`)
    // where a coordinate lies past the range.
    let mut units: Vec<Vec<[f64; 2]>> = Vec::with_capacity(rings.len());
    let (mut non_finite, mut past_range) = (false, false);
    for ring in rings {
        let mut ring_units = Vec::with_capacity(ring.len());
        for &[x, y] in ring {
            if !(x.is_finite() && y.is_finite()) {
                non_finite = true;
                continue;
            }
            ring_units.push(match (fixed::snap(x), fixed::snap(y)) {
                (Some(sx), Some(sy)) => [f64::from(sx), f64::from(sy)],
                _ => {
                    past_range = true;
                    [x, y].map(|c| f64::from(c) * f64::from(fixed::ONE))
                }
            });
        }
        units.push(ring_units);
    }
    if non_finite {
        return Ok(DrawStats { non_finite: 1, ..DrawStats::default() });
    }
    let tris = if past_range {
        triangulate_past_range(&units)
    } else {
        // Snapped integers, exact in `f64`.
        let snapped: Vec<Vec<[i32; 2]>> =
            units.iter().map(|r| r.iter().map(|p| p.map(|c| c as i32)).collect()).collect();
        triangulate_snapped(&snapped)
    };
    // The original coordinates snap to exactly the integers that were triangulated (those
    // past the range are the triangulated values over 256, exactly).
    let all: Vec<[f32; 2]> = rings.iter().flatten().copied().collect();
    let triangles: Vec<[Vertex; 3]> =
        tris.iter().map(|t| t.map(|i| Vertex::new(all[i][0], all[i][1], 0.0, color))).collect();
    draw(target, &triangles, options)
}

/// Triangulates rings in 1/256-pixel units some of whose corners lie past the fixed-point
/// range (those in it snapped, those past it as given): the triangulation [`fill_polygon`]
/// draws there, leaving `draw` to clip the triangles that reach past the range. Such
/// coordinates go far beyond the 2^26 units within which earcut's orientation tests are
/// exact in `f64`, while spade's are exact on any `f64` (adaptive precision), so the
/// constrained Delaunay triangulation takes every polygon it can triangulate over all its
/// corners (every simple one without a corner twice), and its triangles tile the polygon
/// exactly. What it refuses goes where [`triangulate_snapped`] sends it: crossing rings of
/// more than 1024 corners and any of more than 16,384 get none, the others earcut's
/// triangles in `f64`, whose tests may round at such magnitudes (two corners on one point:
/// a pinch, or a hole bridged to the outer ring).
///
/// The winding is the outer ring's, taken exactly at its lowest corner (for a simple ring,
/// a corner of its convex hull), the `f64` area deciding only where that corner's sides are
/// collinear; holes whose corners all lie on one line are dropped, as holes of no area are
/// in the range.
fn triangulate_past_range(rings: &[Vec<[f64; 2]>]) -> Vec<[usize; 3]> {
    let Some(outer) = rings.first() else {
        return Vec::new();
    };
    let Some(ccw) = orientation(outer) else {
        return Vec::new();
    };
    let (data, holes, map) = flatten(rings, |ring| orientation(ring).is_some());
    if most_corners_at_one_point(&data, &holes) > MAX_CORNERS_AT_ONE_POINT {
        return Vec::new();
    }
    let tris = match cdt_rings(&data, &holes, ccw) {
        Ok(tris) => tris,
        Err(why) if why.leaves_nothing(data.len()) => Vec::new(),
        Err(_) => earcut_f64(&data, &holes, ccw),
    };
    tris.into_iter().map(|t| t.map(|i| map[i])).collect()
}

/// Whether `ring` runs counter-clockwise (positive area, y up), exactly for a simple ring of
/// any `f64` coordinates: the turn at its lowest (then leftmost) corner, a corner of its
/// convex hull, from the corners before and after it that differ from it. Where those
/// three are collinear (a spike), the sign of the `f64` area. `None` when every corner lies
/// on one line (no area; the area's sign alone is not exact).
fn orientation(ring: &[[f64; 2]]) -> Option<bool> {
    let point = |p: [f64; 2]| robust::Coord { x: p[0], y: p[1] };
    let (&first, rest) = ring.split_first()?;
    // Two corners that differ, then whether any third leaves their line.
    let other = rest.iter().copied().find(|&p| p != first)?;
    let flat = |p: &[f64; 2]| robust::orient2d(point(first), point(other), point(*p)) == 0.0;
    if ring.iter().all(flat) {
        return None;
    }
    let lowest = (0..ring.len())
        .min_by(|&i, &j| {
            let (a, b) = (ring[i], ring[j]);
            a[1].total_cmp(&b[1]).then(a[0].total_cmp(&b[0]))
        })
        .unwrap_or(0);
    let v = ring[lowest];
    let n = ring.len();
    let before = (1..n).map(|k| ring[(lowest + n - k) % n]).find(|&p| p != v)?;
    let after = (1..n).map(|k| ring[(lowest + k) % n]).find(|&p| p != v)?;
    let turn = robust::orient2d(point(before), point(v), point(after));
    if turn != 0.0 {
        return Some(turn > 0.0);
    }
    let area = shoelace(ring);
    (area != 0.0).then_some(area > 0.0)
}

/// How many corners of the rings in `points` (the first, then one from each start in
/// `holes`, as earcut takes them) lie on the most visited point, `-0.0` and `0.0` being one.
/// A run of equal corners next to each other (round each ring) counts once: earcut drops such
/// repeats itself, and they are common (flattened curves snapped to the grid, exporters'
/// repeated indices).
fn most_corners_at_one_point(points: &[[f64; 2]], holes: &[usize]) -> usize {
    let kept = rings_without_repeats(points, holes);
    most_at_one_point(points, kept.iter().flatten().copied())
}

/// A point's identity for the repeat tests: its bits, `-0.0` and `0.0` being one.
fn point_key(p: &[f64; 2]) -> [u64; 2] {
    p.map(|c| (c + 0.0).to_bits())
}

/// The indices of each ring's corners (the first ring, then one from each start in `holes`)
/// but those equal to the corner before them round their ring: what earcut keeps.
fn rings_without_repeats(points: &[[f64; 2]], holes: &[usize]) -> Vec<Vec<usize>> {
    let mut bounds = vec![0];
    bounds.extend_from_slice(holes);
    bounds.push(points.len());
    let key = |i: usize| point_key(&points[i]);
    let ring = |(start, end): (usize, usize)| -> Vec<usize> {
        let previous = |i: usize| if i == start { end - 1 } else { i - 1 };
        (start..end).filter(|&i| key(i) != key(previous(i))).collect()
    };
    bounds.windows(2).map(|w| ring((w[0], w[1]))).collect()
}

/// The corners of `ring` (indices into `points`, none equal to the one before it) but those
/// strictly between their two neighbours on one line, which go into `runs` under the kept
/// side they lie on (earcut leaves such corners out; the Delaunay path takes them back once
/// the rest is triangulated, [`with_straight_corners`]). Spade's bulk
/// load inserts vertices closest to their mean first, and while all it has inserted lie on one
/// line it locates each new one by a linear search: a triangle with 10,000 corners along one
/// side took 5 s. Neighbours are the ring's own, not the corners kept: the corners of a
/// straight run each lie between theirs (so all go, leaving its ends), and a ring cannot be
/// one run, as a run moves one way along its line. The test is exact ([`robust::orient2d`]
/// for the line, comparisons for between) for the coordinates [`cdt_rings`] lets through:
/// `robust` has no guard against underflow, which differences below 2^-511 would need.
fn without_straight_corners(
    points: &[[f64; 2]],
    ring: &[usize],
    runs: &mut HashMap<[usize; 2], Vec<usize>>,
) -> Vec<usize> {
    let n = ring.len();
    if n < 3 {
        return ring.to_vec();
    }
    let coord = |i: usize| robust::Coord { x: points[i][0], y: points[i][1] };
    let straight: Vec<bool> = (0..n)
        .map(|k| {
            let (a, b, c) =
                (coord(ring[(k + n - 1) % n]), coord(ring[k]), coord(ring[(k + 1) % n]));
            let between = |a: f64, b: f64, c: f64| (a < b && b < c) || (c < b && b < a);
            robust::orient2d(a, b, c) == 0.0 && (between(a.x, b.x, c.x) || between(a.y, b.y, c.y))
        })
        .collect();
    // From a kept corner round the ring, so that every run has both ends.
    let Some(first) = straight.iter().position(|&s| !s) else { return ring.to_vec() };
    let (mut from, mut between) = (ring[first], Vec::new());
    for k in (first + 1..n).chain(0..=first) {
        if straight[k] {
            between.push(ring[k]);
        } else {
            if !between.is_empty() {
                runs.insert([from, ring[k]], std::mem::take(&mut between));
            }
            from = ring[k];
        }
    }
    (0..n).filter(|&k| !straight[k]).map(|k| ring[k]).collect()
}

/// How many of the `corners` lie on the most visited point (see [`point_key`]).
fn most_at_one_point(points: &[[f64; 2]], corners: impl Iterator<Item = usize>) -> usize {
    let mut keys: Vec<[u64; 2]> = corners.map(|i| point_key(&points[i])).collect();
    keys.sort_unstable();
    keys.chunk_by(|a, b| a == b).map(<[_]>::len).max().unwrap_or(0)
}

/// The fan `(0, i, i + 1)` over `n` corners: the triangulation of a convex polygon.
fn fan(n: usize) -> Vec<[usize; 3]> {
    fan_from(n, 0)
}

/// The fan `(k, k + i, k + i + 1)` (round the ring) over `n` corners. From a corner with a
/// NaN or infinite coordinate, every triangle has that corner, so the rasterizer drops and
/// counts them all.
pub(crate) fn fan_from(n: usize, k: usize) -> Vec<[usize; 3]> {
    (1..n.saturating_sub(1)).map(|i| [k, (k + i) % n, (k + i + 1) % n]).collect()
}

/// Newell's normal, twice the vector area: exact direction for planar polygons, a least-squares
/// fit for nearly planar ones, and robust to collinear corners (unlike one cross product).
fn newell_normal(points: &[[f32; 3]]) -> [f64; 3] {
    // Relative to the first corner, for precision far from the origin.
    let o = points[0].map(f64::from);
    let rel = |p: &[f32; 3]| [0, 1, 2].map(|k| f64::from(p[k]) - o[k]);
    let mut n = [0.0; 3];
    let mut prev = rel(&points[points.len() - 1]);
    for p in points {
        let cur = rel(p);
        for (k, nk) in n.iter_mut().enumerate() {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            *nk += (prev[a] - cur[a]) * (prev[b] + cur[b]);
        }
        prev = cur;
    }
    n
}

/// Twice the signed area of a ring (positive counter-clockwise with y up).
fn shoelace(ring: &[[f64; 2]]) -> f64 {
    let Some(&last) = ring.last() else { return 0.0 };
    let mut prev = last;
    let mut sum = 0.0;
    for &p in ring {
        sum += prev[0] * p[1] - p[0] * prev[1];
        prev = p;
    }
    sum
}

/// [`shoelace`] in exact integer arithmetic.
fn shoelace_exact(ring: &[[i32; 2]]) -> i128 {
    let Some(&last) = ring.last() else { return 0 };
    let mut prev = last.map(i128::from);
    let mut sum = 0;
    for p in ring {
        let p = p.map(i128::from);
        sum += prev[0] * p[1] - p[0] * prev[1];
        prev = p;
    }
    sum
}

/// True iff the ring is a strictly convex polygon: every turn strictly the same way, and the
/// edge directions go round exactly once (which rules out star polygons such as the pentagram,
/// whose turns also all agree). Exact when the products of coordinate differences are exact.
fn is_strictly_convex(ring: &[[f64; 2]]) -> bool {
    let n = ring.len();
    if n < 3 {
        return false;
    }
    let edge = |i: usize| {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        [b[0] - a[0], b[1] - a[1]]
    };
    let mut turn_sign = 0.0;
    let mut prev = edge(n - 1);
    for i in 0..n {
        let e = edge(i);
        let cross = prev[0] * e[1] - prev[1] * e[0];
        if cross == 0.0 || cross.is_nan() {
            return false;
        }
        if turn_sign == 0.0 {
            turn_sign = cross.signum();
        } else if cross.signum() != turn_sign {
            return false;
        }
        prev = e;
    }
    // With all turns in (0, pi) one way, each full revolution of the edge direction changes
    // the sign of dx exactly twice (cyclically); more changes mean more revolutions.
    let signs: Vec<bool> =
        (0..n).map(|i| edge(i)[0]).filter(|&dx| dx != 0.0).map(|dx| dx > 0.0).collect();
    let changes = (0..signs.len()).filter(|&i| signs[i] != signs[(i + 1) % signs.len()]).count();
    changes == 2
}

/// Concatenates the rings that pass `keep` (the first ring always), returning the points,
/// earcut's hole start indices, and the map back to indices in the concatenation of all rings.
fn flatten<T: Copy>(
    rings: &[Vec<T>],
    keep: impl Fn(&Vec<T>) -> bool,
) -> (Vec<T>, Vec<usize>, Vec<usize>) {
    let (mut data, mut holes, mut map) = (Vec::new(), Vec::new(), Vec::new());
    let mut start = 0;
    for (r, ring) in rings.iter().enumerate() {
        if r == 0 || keep(ring) {
            if r > 0 {
                holes.push(data.len());
            }
            data.extend_from_slice(ring);
            map.extend(start..start + ring.len());
        }
        start += ring.len();
    }
    (data, holes, map)
}

/// Triangulates the rings of `data` (the outer ring, then one from each start in `holes`):
/// through [`cdt_rings`] above [`CDT_ABOVE_CORNERS`] corners where it can, else earcut.
fn triangulate_rings(data: &[[f64; 2]], holes: &[usize], ccw: bool) -> Vec<[usize; 3]> {
    if data.len() > CDT_ABOVE_CORNERS
        && let Some(tris) = large_rings(data, holes, ccw)
    {
        return tris;
    }
    earcut_f64(data, holes, ccw)
}

/// The triangles of rings of more than [`CDT_ABOVE_CORNERS`] corners: [`cdt_rings`]'s, none
/// for rings whose sides cross or, above [`EARCUT_AT_MOST_CORNERS`], that it refuses at all;
/// `None` for earcut to decide.
fn large_rings(data: &[[f64; 2]], holes: &[usize], ccw: bool) -> Option<Vec<[usize; 3]>> {
    match cdt_rings(data, holes, ccw) {
        Ok(tris) => Some(tris),
        Err(why) if why.leaves_nothing(data.len()) => Some(Vec::new()),
        Err(_) => None,
    }
}

/// Why [`cdt_rings`] gave no triangulation.
#[derive(Debug, PartialEq)]
enum Refusal {
    /// Two sides cross. The rings bound no polygon, so no triangulation is the right one, and
    /// earcut's time on such a ring grows with the square of its corners (a random face of
    /// 200,000 corners took 47 s to load): above [`CDT_ABOVE_CORNERS`] there are no
    /// triangles, as for rings through one point three times (faces take the fan).
    Crossing,
    /// Any other reason (a corner twice, sides that touch or overlap, coordinates spade
    /// refuses), for earcut to decide.
    Other,
}

impl Refusal {
    /// Whether rings of `corners` corners refused for this reason get no triangles rather
    /// than earcut's: crossing ones above [`CDT_ABOVE_CORNERS`], any above
    /// [`EARCUT_AT_MOST_CORNERS`] (where earcut's time grows with the square of the corners).
    fn leaves_nothing(&self, corners: usize) -> bool {
        (*self == Self::Crossing && corners > CDT_ABOVE_CORNERS) || corners > EARCUT_AT_MOST_CORNERS
    }
}

/// The triangles inside the rings of `data` (laid out as for earcut), wound positively if
/// `ccw`, from a constrained Delaunay triangulation of the corners with the rings' sides as
/// constraints. A triangle is inside when the way to it from outside crosses the sides an odd
/// number of times; where two ways disagree the rings are not a polygon's boundary.
///
/// A corner equal to the one before it on its ring is left out, as earcut leaves it out. One
/// strictly between its neighbours on a straight side is left out of the triangulation and
/// then taken back ([`without_straight_corners`]), so it is a corner of the triangles.
/// `None`, for earcut to decide, where the result would not be a triangulation of the polygon
/// over all its other corners: two of them on one point (spade keeps one vertex per position,
/// so a bridge or a pinch would lose one), a ring left with fewer than 3, sides that cross
/// (constraints in conflict), coordinates spade refuses (magnitudes above 2^201 or non-zero
/// below 2^-142), parities that disagree (sides that overlap, which spade merges, or a corner
/// on another side), or a count other than the `n + 2h - 2` triangles every triangulation of
/// `n` corners and `h` holes has.
fn cdt_rings(data: &[[f64; 2]], holes: &[usize], ccw: bool) -> Result<Vec<[usize; 3]>, Refusal> {
    let rings = rings_without_repeats(data, holes);
    if most_at_one_point(data, rings.iter().flatten().copied()) > 1 {
        return Err(Refusal::Other);
    }
    // Refused as spade refuses them, and before the straight corners' test, which would not be
    // exact for them (see `without_straight_corners`).
    let tiny = |c: f64| c != 0.0 && c.abs() < spade::MIN_ALLOWED_VALUE;
    if rings.iter().flatten().any(|&i| data[i].iter().any(|&c| tiny(c))) {
        return Err(Refusal::Other);
    }
    // Corners strictly between their neighbours on a straight side are left out of the
    // triangulation and taken back at the end (see `with_straight_corners`): the corners
    // between the ends of each kept side, in the ring's order.
    let mut straight_runs: HashMap<[usize; 2], Vec<usize>> = HashMap::new();
    let rings: Vec<Vec<usize>> =
        rings.iter().map(|r| without_straight_corners(data, r, &mut straight_runs)).collect();
    if rings.iter().any(|r| r.len() < 3) {
        return Err(Refusal::Other);
    }
    // The corners kept, and the sides between them as spade's indices into `kept`.
    let (mut kept, mut sides) = (Vec::with_capacity(data.len()), Vec::with_capacity(data.len()));
    for ring in rings {
        let (first, last) = (kept.len(), kept.len() + ring.len() - 1);
        sides.extend((first..=last).map(|k| [k, if k == last { first } else { k + 1 }]));
        kept.extend(ring);
    }
    let n = kept.len();
    let points = kept.iter().map(|&i| Point2::new(data[i][0], data[i][1])).collect();
    let mut conflict = false;
    let cdt =
        ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(points, sides, |_| {
            conflict = true
        })
        .map_err(|_| Refusal::Other)?;
    if conflict {
        return Err(Refusal::Crossing);
    }
    if cdt.num_vertices() != n {
        return Err(Refusal::Other);
    }
    // Each face's parity, spread from the faces on the hull (the outer face is outside).
    let mut inside: Vec<Option<bool>> = vec![None; cdt.num_all_faces()];
    inside[spade::handles::OUTER_FACE.index()] = Some(false);
    let mut stack = Vec::new();
    for face in cdt.inner_faces() {
        for side in face.adjacent_edges() {
            if side.rev().face().is_outer() && inside[face.fix().index()].is_none() {
                inside[face.fix().index()] = Some(side.is_constraint_edge());
                stack.push(face.fix());
            }
        }
    }
    while let Some(fixed) = stack.pop() {
        let here = inside[fixed.index()] == Some(true);
        for side in cdt.face(fixed).adjacent_edges() {
            let across = here != side.is_constraint_edge();
            let other = side.rev().face();
            match inside[other.fix().index()] {
                None => {
                    inside[other.fix().index()] = Some(across);
                    stack.extend(other.as_inner().map(|f| f.fix()));
                }
                Some(parity) if parity != across => return Err(Refusal::Other),
                Some(_) => {}
            }
        }
    }
    let tris: Vec<[usize; 3]> = cdt
        .inner_faces()
        .filter(|face| inside[face.fix().index()] == Some(true))
        .map(|face| {
            // Spade gives each face's corners counterclockwise (positive area).
            let [a, b, c] = face.vertices().map(|v| kept[v.fix().index()]);
            if ccw { [a, b, c] } else { [a, c, b] }
        })
        .collect();
    if tris.len() + 2 != n + 2 * holes.len() {
        return Err(Refusal::Other);
    }
    with_straight_corners(tris, straight_runs).ok_or(Refusal::Other)
}

/// `tris` with the corners of `runs` taken back: the triangle on each kept side `[a, c]` with
/// corners between them (`runs`, in the ring's order from `a`) is cut into a fan from its
/// third corner, which is off the side's line. Each corner so taken adds one triangle, so
/// every corner is used and there are `n + 2h - 2` triangles, as in any triangulation of the
/// ring; the fan keeps the triangle's winding. `None` if a run's side is on no triangle.
fn with_straight_corners(
    tris: Vec<[usize; 3]>,
    mut runs: HashMap<[usize; 2], Vec<usize>>,
) -> Option<Vec<[usize; 3]>> {
    if runs.is_empty() {
        return Some(tris);
    }
    let mut out = Vec::with_capacity(tris.len() + runs.values().map(Vec::len).sum::<usize>());
    let mut pending = Vec::new();
    for t in tris {
        pending.push(t);
        while let Some([a, b, c]) = pending.pop() {
            let cut = [[a, b, c], [b, c, a], [c, a, b]].into_iter().find_map(|[u, v, w]| {
                let between = match runs.remove(&[u, v]) {
                    Some(run) => run,
                    None => runs.remove(&[v, u]).map(|run| run.into_iter().rev().collect())?,
                };
                Some((u, between, v, w))
            });
            let Some((u, between, v, w)) = cut else {
                out.push([a, b, c]);
                continue;
            };
            let chain: Vec<usize> = std::iter::once(u).chain(between).chain([v]).collect();
            // Last first, so that the fan comes out in the chain's order.
            pending.extend(chain.windows(2).rev().map(|p| [p[0], p[1], w]));
        }
    }
    runs.is_empty().then_some(out)
}

/// Runs earcut in `f64` and winds the triangles counter-clockwise (y up) iff `ccw`.
fn earcut_f64(data: &[[f64; 2]], holes: &[usize], ccw: bool) -> Vec<[usize; 3]> {
    let mut flat = Vec::new();
    Earcut::new().earcut(data.iter().copied(), holes, &mut flat);
    orient(&flat, ccw, |[a, b, c]| {
        let (a, b, c) = (data[a], data[b], data[c]);
        (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
    })
}

/// Groups earcut's flat index list into triangles and reverses them all if their winding
/// (earcut emits one winding whatever the input's) is not the requested one. The winding is
/// judged by the summed signed area, so slivers with noisy signs cannot mislead it.
fn orient(
    flat: &[usize],
    positive: bool,
    signed_area: impl Fn([usize; 3]) -> f64,
) -> Vec<[usize; 3]> {
    let tris: Vec<[usize; 3]> = flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let total: f64 = tris.iter().map(|&t| signed_area(t)).sum();
    if (total > 0.0) == positive {
        tris
    } else {
        tris.into_iter().map(|[a, b, c]| [a, c, b]).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn convexity() {
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(is_strictly_convex(&square));
        let mut cw = square;
        cw.reverse();
        assert!(is_strictly_convex(&cw));
        // A collinear corner is not strictly convex.
        assert!(!is_strictly_convex(&[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 1.0]]));
        // The pentagram turns the same way at every corner but winds twice.
        let star: Vec<[f64; 2]> = (0..5)
            .map(|i| {
                let a = f64::from(i * 2) * std::f64::consts::TAU / 5.0;
                [a.cos(), a.sin()]
            })
            .collect();
        assert!(!is_strictly_convex(&star));
        let dart = [[0.0, 0.0], [4.0, 0.0], [2.0, 1.0], [2.0, 4.0]];
        assert!(!is_strictly_convex(&dart));
    }

    #[test]
    fn concave_face_keeps_winding() {
        // An L in the plane x = 1, counter-clockwise seen from +x.
        let l: Vec<[f32; 3]> =
            [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]]
                .iter()
                .map(|&[y, z]| [1.0, y, z])
                .collect();
        for face in [l.clone(), l.iter().rev().copied().collect()] {
            let n = newell_normal(&face);
            let tris = triangulate_face(&face);
            assert_eq!(tris.len(), 4);
            for t in tris {
                let [a, b, c] = t.map(|i| face[i].map(f64::from));
                let nx = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]);
                assert!(nx * n[0] > 0.0, "{t:?} flips the winding");
            }
        }
    }

    /// Planar concave faces keep earcut's triangles: these are the ones `triangulate_face`
    /// gave before twisted faces were retried, for the faces in the plane z = 0, reversed, and
    /// tilted into the plane z = x + 2y (projected along y there).
    #[test]
    fn planar_concave_faces_triangulate_as_before() {
        let l = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]];
        let arrow =
            [[0.0, 1.0], [3.0, 1.0], [3.0, 0.0], [5.0, 2.0], [3.0, 4.0], [3.0, 3.0], [0.0, 3.0]];
        // An L with a corner halfway along an edge.
        let l7 =
            [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0], [1.0, 1.0], [1.0, 2.0], [0.0, 2.0]];
        let u =
            [[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [2.0, 3.0], [2.0, 1.0], [1.0, 1.0], [1.0, 3.0]];
        let u: Vec<[f32; 2]> = u.into_iter().chain([[0.0, 3.0]]).collect();
        // The triangles for the face in the plane z = 0, reversed, and tilted.
        let check = |ring: &[[f32; 2]], flat: &[_], reversed: &[_], tilted: &[[usize; 3]]| {
            let face: Vec<[f32; 3]> = ring.iter().map(|&[x, y]| [x, y, 0.0]).collect();
            assert_eq!(triangulate_face(&face), flat);
            let face: Vec<[f32; 3]> = face.into_iter().rev().collect();
            assert_eq!(triangulate_face(&face), reversed);
            let face: Vec<[f32; 3]> = ring.iter().map(|&[x, y]| [x, y, x + 2.0 * y]).collect();
            assert!(is_planar(&face, newell_normal(&face)));
            assert_eq!(triangulate_face(&face), tilted);
        };
        check(
            &l,
            &[[4, 5, 0], [0, 1, 2], [0, 2, 3], [0, 3, 4]],
            &[[1, 5, 0], [5, 3, 4], [5, 2, 3], [5, 1, 2]],
            &[[0, 4, 5], [0, 3, 4], [0, 2, 3], [0, 1, 2]],
        );
        check(
            &arrow,
            &[[5, 6, 0], [5, 0, 1], [1, 2, 3], [3, 4, 5], [3, 5, 1]],
            &[[1, 6, 0], [1, 5, 6], [5, 3, 4], [3, 1, 2], [3, 5, 1]],
            &[[1, 6, 0], [1, 5, 6], [5, 3, 4], [3, 1, 2], [3, 5, 1]],
        );
        check(
            &l7,
            &[[5, 6, 0], [1, 2, 3], [1, 3, 4], [4, 5, 0], [4, 0, 1]],
            &[[1, 6, 0], [5, 3, 4], [5, 2, 3], [2, 6, 1], [2, 5, 6]],
            &[[1, 6, 0], [6, 4, 5], [4, 2, 3], [4, 1, 2], [4, 6, 1]],
        );
        check(
            &u,
            &[[6, 7, 0], [1, 2, 3], [1, 3, 4], [1, 4, 5], [5, 6, 0], [5, 0, 1]],
            &[[1, 7, 0], [6, 4, 5], [6, 3, 4], [6, 2, 3], [2, 7, 1], [2, 6, 7]],
            &[[0, 6, 7], [0, 5, 6], [0, 4, 5], [4, 2, 3], [4, 1, 2], [4, 0, 1]],
        );
    }

    #[test]
    fn planarity() {
        let quad = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [0.0, 1.0, -4.0]];
        assert!(!is_planar(&quad, newell_normal(&quad)));
        // A square rotated 30 degrees about x and rounded to f32 is planar up to rounding.
        let (s, c) = 30f64.to_radians().sin_cos();
        let square: Vec<[f32; 3]> = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
            .iter()
            .map(|&[x, y]: &[f64; 2]| [x as f32, (y * c + 100.0) as f32, (y * s) as f32])
            .collect();
        assert!(is_planar(&square, newell_normal(&square)));
        let mut bent = square.clone();
        bent[2][0] += 0.01;
        bent[2][2] += 0.01;
        assert!(!is_planar(&bent, newell_normal(&bent)));
    }

    #[test]
    fn degenerate_faces_do_not_panic() {
        assert!(triangulate_face(&[]).is_empty());
        assert!(triangulate_face(&[[0.0; 3], [1.0; 3]]).is_empty());
        assert_eq!(triangulate_face(&[[0.0; 3], [1.0; 3], [2.0; 3]]), vec![[0, 1, 2]]);
        let line = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [3.0, 3.0, 3.0]];
        assert_eq!(triangulate_face(&line), fan(4));
        // A non-finite corner: every triangle has it, so the rasterizer drops them all.
        let nan = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [f32::NAN, 1.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(triangulate_face(&nan), [[2, 3, 0], [2, 0, 1]]);
        let inf = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [f32::INFINITY, 1.0, 0.0], [0.0, 1.0, 0.0]];
        assert_eq!(triangulate_face(&inf), [[2, 3, 0], [2, 0, 1]]);
        let mut star: Vec<[f32; 3]> = (0..2000)
            .map(|i| {
                let (a, r) = (i as f32 * std::f32::consts::TAU / 2000.0, [1.0, 0.3][i % 2]);
                [r * a.cos(), r * a.sin(), 0.0]
            })
            .collect();
        star[700][1] = f32::NAN;
        let tris = triangulate_face(&star);
        assert_eq!(tris.len(), 1998);
        assert!(tris.iter().all(|t| t.contains(&700)));
    }

    /// Polygons through one point three times or more take earcut time cubic in their length
    /// (a 12 KB OBJ face hung for 26 s): faces take the fan, 2D polygons give nothing. Twice
    /// (a hole bridged to the boundary, a polygon traversed twice) still goes to earcut.
    #[test]
    fn polygons_through_one_point_thrice_skip_earcut() {
        // A triangle's corners 500 times over (earcut alone: half a second, 500 triangles).
        let tri = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let face: Vec<[f32; 3]> = (0..1500).map(|i| tri[i % 3]).collect();
        assert_eq!(triangulate_face(&face), fan(1500));
        let ring: Vec<[f64; 2]> = face.iter().map(|p| [f64::from(p[0]), f64::from(p[1])]).collect();
        assert!(triangulate_polygon(&[ring]).is_empty());
        let snapped: Vec<[i32; 2]> =
            (0..1500).map(|i| [[0, 0], [256, 0], [0, 256]][i % 3]).collect();
        assert!(triangulate_snapped(&[snapped]).is_empty());
        // A point visited three times by otherwise distinct corners: `-0.0` is `0.0`.
        let thrice = [[0.0, 0.0], [4.0, 1.0], [-0.0, 0.0], [4.0, 3.0], [0.0, -0.0], [4.0, 5.0]];
        assert_eq!(most_corners_at_one_point(&thrice, &[]), 3);
        // Repeats next to each other (round the ring, and per ring) count once: earcut drops
        // them itself. An L of area 3 with a corner three times over and the first corner
        // repeated at the end still goes to earcut and tiles.
        let l = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [2.0, 1.0], [2.0, 1.0], [1.0, 1.0]];
        let l: Vec<[f64; 2]> = l.into_iter().chain([[1.0, 2.0], [0.0, 2.0], [0.0, 0.0]]).collect();
        assert_eq!(most_corners_at_one_point(&l, &[]), 1);
        assert_eq!(most_corners_at_one_point(&[l.clone(), l.clone()].concat(), &[l.len()]), 2);
        let face: Vec<[f32; 3]> = l.iter().map(|p| [p[0] as f32, p[1] as f32, 0.0]).collect();
        let tris = triangulate_face(&face);
        assert_ne!(tris, fan(l.len()), "earcut, not the fan");
        let twice_area = |t: &[usize; 3]| {
            let [a, b, c] = t.map(|i| l[i]);
            (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        };
        assert_eq!(tris.iter().map(twice_area).sum::<f64>(), 6.0);
        let snapped: Vec<[i32; 2]> = l.iter().map(|p| p.map(|c| (c * 256.0) as i32)).collect();
        assert_eq!(triangulate_snapped(&[snapped]).len(), 4);
        assert_eq!(triangulate_polygon(&[l]).len(), 4);

        // A square with a square hole, bridged: the bridge's ends are visited twice. Earcut
        // tiles it: the triangles' areas sum to the polygon's.
        let keyhole = [
            [0.0, 0.0],
            [4.0, 0.0],
            [4.0, 4.0],
            [2.0, 3.0],
            [3.0, 3.0],
            [3.0, 1.0],
            [1.0, 1.0],
            [1.0, 3.0],
            [2.0, 3.0],
            [0.0, 4.0],
        ];
        assert_eq!(most_corners_at_one_point(&keyhole, &[]), 2);
        let face: Vec<[f32; 3]> = keyhole.iter().map(|p| [p[0] as f32, p[1] as f32, 0.0]).collect();
        let tris = triangulate_face(&face);
        assert_ne!(tris, fan(keyhole.len()), "earcut, not the fan");
        let area = |t: &[usize; 3]| {
            let [a, b, c] = t.map(|i| keyhole[i]);
            ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2.0
        };
        let sum: f64 = tris.iter().map(area).sum();
        assert_eq!(2.0 * sum, shoelace(&keyhole));
        // The square, less the hole and the notch the bridge cuts from the top edge.
        assert_eq!(sum, 16.0 - 4.0 - 2.0);
    }

    #[test]
    fn holes_are_indexed_in_the_concatenation() {
        let outer = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        let tiny = vec![[1.0, 1.0], [2.0, 2.0]];
        let hole = vec![[4.0, 4.0], [4.0, 6.0], [6.0, 6.0], [6.0, 4.0]];
        let tris = triangulate_polygon(&[outer, tiny, hole]);
        assert_eq!(tris.len(), 8);
        assert!(tris.iter().flatten().all(|&i| i != 4 && i != 5 && i < 10));
    }

    /// A ring of `n` corners zigzagging along the x axis (a comb of `n / 2` teeth), simple and
    /// far from convex.
    fn comb(n: usize) -> Vec<[f64; 2]> {
        let half = n / 2;
        let top = (0..half).map(|i| [i as f64, if i % 2 == 0 { 1.0 } else { 3.0 }]);
        // No three corners on a line (those the Delaunay path leaves out).
        let bottom = (0..half).rev().map(|i| [i as f64, [0.0, -0.25, -0.75][i % 3]]);
        top.chain(bottom).collect()
    }

    fn area2(data: &[[f64; 2]], tris: &[[usize; 3]]) -> f64 {
        tris.iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| data[i]);
                (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
            })
            .sum()
    }

    /// The Delaunay path takes what it can triangulate over every corner, skips repeats as
    /// earcut does, and hands everything else back for earcut to decide.
    #[test]
    fn large_rings_that_are_not_simple_skip_earcut() {
        let face = |ring: &[[f64; 2]]| -> Vec<[f32; 3]> {
            ring.iter().map(|p| [p[0] as f32, p[1] as f32, 0.0]).collect()
        };
        // Sides that cross: a comb with two far corners swapped.
        let mut crossed = comb(2000);
        crossed.swap(10, 1990);
        assert_eq!(cdt_rings(&crossed, &[], true), Err(Refusal::Crossing));
        assert!(triangulate_polygon(&[crossed.clone()]).is_empty());
        assert_eq!(triangulate_face(&face(&crossed)), fan(crossed.len()));
        let snapped: Vec<[i32; 2]> = crossed.iter().map(|p| p.map(|v| (v * 4.0) as i32)).collect();
        assert!(triangulate_snapped(&[snapped]).is_empty());
        // A pinch (one corner twice), which spade refuses: earcut's up to its bound, the fan
        // above it.
        for (n, earcut) in [(4000, true), (EARCUT_AT_MOST_CORNERS + 2, false)] {
            let mut pinched = comb(n);
            pinched.insert(n / 4, pinched[3 * n / 4 + 1]);
            assert_eq!(cdt_rings(&pinched, &[], true), Err(Refusal::Other));
            let tris = triangulate_polygon(&[pinched.clone()]);
            assert_eq!(!tris.is_empty(), earcut, "{n}");
            let drawn = triangulate_face(&face(&pinched));
            assert_eq!(drawn == fan(pinched.len()), !earcut, "{n}");
        }
    }

    /// Corners strictly between their neighbours on a straight side are left out of the
    /// Delaunay triangulation (spade located each by a linear search while all it had lay on
    /// one line: 10,000 along one side took 5 s) and taken back as fans: every corner is
    /// used, the triangles are wound as asked and tile the polygon, and a corner where the
    /// ring turns back along its side (a spike) is not taken for a straight one.
    #[test]
    fn straight_sides_are_triangulated_through_every_corner() {
        let tiles = |data: &[[f64; 2]], holes: &[usize], ccw: bool, area: f64| {
            let tris = cdt_rings(data, holes, ccw).expect("a simple polygon");
            assert_eq!(tris.len() + 2, data.len() + 2 * holes.len());
            for t in &tris {
                assert_eq!(area2(data, &[*t]) > 0.0, ccw, "{t:?}");
            }
            assert_eq!(area2(data, &tris).abs(), area);
            let mut used: Vec<usize> = tris.iter().flatten().copied().collect();
            used.sort_unstable();
            used.dedup();
            assert_eq!(used.len(), data.len());
        };
        let n = 20_000;
        let mut ring: Vec<[f64; 2]> = (0..=n).map(|k| [k as f64 / 64.0, 0.0]).collect();
        ring.push([n as f64 / 128.0, 40.0]);
        for ccw in [true, false] {
            tiles(&ring, &[], ccw, 40.0 * n as f64 / 64.0);
        }
        // Straight runs on every side of a square and of its hole, one wrapping round the
        // outer ring's start (steps of powers of two: exact corners, exact areas).
        let side = |from: [f64; 2], to: [f64; 2], m: usize| {
            (0..m).map(move |k| {
                let t = k as f64 / m as f64;
                [from[0] + (to[0] - from[0]) * t, from[1] + (to[1] - from[1]) * t]
            })
        };
        let [a, b, c, d] = [[0.0, 0.0], [64.0, 0.0], [64.0, 64.0], [0.0, 64.0]];
        let mut data: Vec<[f64; 2]> = side(a, b, 512)
            .chain(side(b, c, 256))
            .chain(side(c, d, 4))
            .chain(side(d, a, 64))
            .collect();
        data.rotate_left(40);
        let outer = data.len();
        let hole = side([8.0, 8.0], [8.0, 16.0], 64).chain(side([8.0, 16.0], [16.0, 8.0], 2));
        data.extend(hole.chain(side([16.0, 8.0], [8.0, 8.0], 8)));
        tiles(&data, &[outer], true, 2.0 * (64.0 * 64.0 - 32.0));
        // A spike: the ring goes out along a line and back; its tip is no straight corner.
        let spike = [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [1.0, 0.0], [0.0, 3.0]];
        let mut runs = HashMap::new();
        assert_eq!(without_straight_corners(&spike, &[0, 1, 2, 3, 4], &mut runs), [0, 2, 3, 4]);
        assert_eq!(runs, HashMap::from([([0, 2], vec![1])]));
    }

    #[test]
    fn delaunay_path_takes_simple_rings_and_refuses_the_rest() {
        let ring = comb(2000);
        let expected = shoelace(&ring);
        for ccw in [true, false] {
            let tris = cdt_rings(&ring, &[], ccw).expect("a simple ring");
            assert_eq!(tris.len(), ring.len() - 2);
            // Every triangle wound as asked, so the areas cannot cancel: they tile.
            for t in &tris {
                assert_eq!(area2(&ring, &[*t]) > 0.0, ccw, "{t:?}");
            }
            assert_eq!(area2(&ring, &tris).abs(), expected.abs());
        }
        // Triangles of the outer ring less a hole's: n + 2h - 2 of them.
        let mut data = ring.clone();
        data.extend([[10.2, 0.5], [10.6, 0.5], [10.4, 0.8]]);
        let tris = cdt_rings(&data, &[ring.len()], true).expect("a ring with a hole");
        assert_eq!(tris.len(), data.len());
        let hole = shoelace(&data[ring.len()..]).abs();
        assert!((area2(&data, &tris) - (expected.abs() - hole)).abs() < 1e-9);
        // Repeats next to each other are left out, wherever they sit in the ring.
        let mut repeated = ring.clone();
        repeated.insert(7, ring[6]);
        repeated.push(ring[0]);
        let tris = cdt_rings(&repeated, &[], true).expect("repeats skipped");
        assert_eq!(tris.len(), ring.len() - 2);
        let mut used: Vec<usize> = tris.iter().flatten().copied().collect();
        used.sort_unstable();
        used.dedup();
        assert_eq!(used.len(), ring.len());
        assert!(!used.contains(&7));
        assert!(!(used.contains(&0) && used.contains(&(ring.len() + 1))));
        // Refused: a corner visited twice (a bridge), sides that cross, a hole outside the
        // ring, a ring of fewer than three distinct corners, coordinates spade refuses.
        let mut pinched = ring.clone();
        pinched.insert(500, ring[1500]);
        assert_eq!(cdt_rings(&pinched, &[], true), Err(Refusal::Other));
        let mut crossed = ring.clone();
        crossed.swap(10, 1990);
        assert_eq!(cdt_rings(&crossed, &[], true), Err(Refusal::Crossing));
        // A corner of the top touching a side of the bottom at that side's midpoint.
        let mut touching = ring.clone();
        touching[500] = [499.5, -0.5];
        assert_eq!(cdt_rings(&touching, &[], true), Err(Refusal::Other));
        let mut outside = ring.clone();
        outside.extend([[10.0, 20.0], [11.0, 20.0], [10.5, 21.0]]);
        assert_eq!(
            cdt_rings(&outside, &[ring.len()], true).ok(),
            None,
            "{:?}",
            cdt_rings(&outside, &[ring.len()], true)
        );
        assert_eq!(
            cdt_rings(&[[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]], &[], true).ok(),
            None,
            "{:?}",
            cdt_rings(&[[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]], &[], true)
        );
        let mut huge = ring.clone();
        huge[3] = [1e300, 0.0];
        assert_eq!(cdt_rings(&huge, &[], true).ok(), None, "{:?}", cdt_rings(&huge, &[], true));
        // Random rings (crossing themselves everywhere, on a coarse grid: many collinear and
        // repeated corners) are refused or triangulated, never a panic.
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::SmallRng::seed_from_u64(0xcd7);
        for side in [34usize, 40, 100_000] {
            for _ in 0..20 {
                // Distinct corners, for spade to see them.
                let (mut seen, mut random) = (std::collections::HashSet::new(), Vec::new());
                while random.len() < 1100 {
                    let cell = [rng.random_range(0..side), rng.random_range(0..side)];
                    if seen.insert(cell) {
                        random.push(cell.map(|v| v as f64));
                    }
                }
                if let Ok(tris) = cdt_rings(&random, &[], true) {
                    assert_eq!(tris.len(), random.len() - 2);
                }
                let _ = triangulate_polygon(&[random]);
            }
        }
        // Above the threshold, rings go this way, the faces' and the snapped fill's too, and
        // refused ones still go to earcut.
        assert_eq!(triangulate_rings(&ring, &[], true), cdt_rings(&ring, &[], true).unwrap());
        let face: Vec<[f32; 3]> = ring.iter().map(|p| [p[0] as f32, p[1] as f32, 0.0]).collect();
        assert_eq!(triangulate_face(&face), cdt_rings(&ring, &[], shoelace(&ring) > 0.0).unwrap());
        let snapped: Vec<[i32; 2]> = ring.iter().map(|p| p.map(|v| (v * 4.0) as i32)).collect();
        let exact: Vec<[f64; 2]> = snapped.iter().map(|p| p.map(f64::from)).collect();
        assert_eq!(
            triangulate_snapped(&[snapped]),
            cdt_rings(&exact, &[], shoelace(&ring) > 0.0).unwrap()
        );
        assert_eq!(triangulate_rings(&pinched, &[], true), earcut_f64(&pinched, &[], true));
    }
}
