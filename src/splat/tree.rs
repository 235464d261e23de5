//! The bounding-sphere hierarchy.
//!
//! Layout (the one the file format stores): nodes in breadth-first order, the root first, the
//! children of a node contiguous (`first_child .. first_child + child_count`), at most 4 per
//! node, leaves have none. Every node's sphere contains every input point below it; its
//! normal is the (normalised) average of its points' normals and `cone` bounds the angle
//! between it and any normal below, so a node whose whole cone faces away can be culled.
//! Built trees have single-child nodes where a node is much smaller than its parent (see
//! `with_chains`: they keep decoded `.tsplat` spheres close to their size).

/// One node of the hierarchy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SplatNode {
    /// Sphere centre.
    pub centre: [f32; 3],
    /// Sphere radius (for a leaf: the splat radius of its point).
    pub radius: f32,
    /// Unit average normal (zero when normals are unknown).
    pub normal: [f32; 3],
    /// Half-angle of the normal cone, radians, in [0, pi]; pi means "any direction".
    pub cone: f32,
    /// Average colour, sRGB-encoded RGB8.
    pub color: [u8; 3],
    /// Index of the first child (meaningless for a leaf).
    pub first_child: u32,
    /// Number of children, 0 for a leaf, at most 4.
    pub child_count: u8,
}

impl SplatNode {
    /// Indices of this node's children (empty for a leaf).
    #[must_use]
    pub fn children(&self) -> std::ops::Range<usize> {
        self.first_child as usize..self.first_child as usize + usize::from(self.child_count)
    }
}

/// A bounding-sphere tree over a point cloud.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SplatTree {
    /// Nodes in breadth-first order; `nodes[0]` is the root.
    pub nodes: Vec<SplatNode>,
    /// The smallest leaf radius, computed by [`SplatTree::new`].
    min_leaf_radius: f32,
}

impl SplatTree {
    /// A tree over `nodes` (breadth-first, as described above).
    #[must_use]
    pub fn new(nodes: Vec<SplatNode>) -> Self {
        let min_leaf_radius = nodes
            .iter()
            .filter(|n| n.child_count == 0 && n.radius.is_finite())
            .map(|n| n.radius.max(0.0))
            .reduce(f32::min)
            .unwrap_or(0.0);
        Self { nodes, min_leaf_radius }
    }

    /// The smallest splat (leaf) radius. A node's sphere contains its points' splats, so
    /// its radius less this bounds how far its points themselves spread (exactly so where
    /// spheres nest, as built trees' do): the detail a node stands for, as opposed to the
    /// size of the disk drawn for it.
    #[must_use]
    pub fn min_leaf_radius(&self) -> f32 {
        self.min_leaf_radius
    }

    /// The children of node `i`: those of its range that follow it and lie within `nodes`,
    /// as a breadth-first tree's all do. A tree made by hand ([`SplatTree::new`], or `nodes`
    /// changed) may have a range that does not; the renderer walks the tree through this, so
    /// such a range cannot send it past the nodes or round a cycle (a node listing itself had
    /// made it index past the end); the renderer also drops children that another parent's
    /// range already reached, so ranges that overlap are walked once. The encoder clips ranges
    /// its own way ([`super::format::encode`]).
    #[must_use]
    pub fn children(&self, i: usize) -> std::ops::Range<usize> {
        let children = self.nodes[i].children();
        children.start.max(i + 1)..children.end.min(self.nodes.len())
    }

    /// Number of leaves.
    #[must_use]
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().filter(|n| n.child_count == 0).count()
    }
}

use super::PointCloud;
use crate::error::{Error, try_reserve_named};

/// What a build is for, to name it in [`Error::OutOfMemory`].
#[derive(Clone, Copy)]
struct Building {
    /// Points in the cloud.
    points: usize,
}

impl Building {
    /// Reserves exactly `n` more elements in `v`, or [`Error::OutOfMemory`] naming the
    /// hierarchy, `part` of it and the bytes of the whole array asked for (`v`'s elements and
    /// the `n` more). The build's arrays are proportional to the point count, and a cloud
    /// that fits in memory may have a hierarchy that does not.
    fn reserve<T>(self, v: &mut Vec<T>, n: usize, part: &str) -> Result<(), Error> {
        try_reserve_named(v, n, || {
            format!("the splat hierarchy of {} points ({part})", self.points)
        })
    }

    /// `n` copies of `value`, or [`Error::OutOfMemory`] as for [`Building::reserve`].
    fn filled<T: Clone>(self, n: usize, value: T, part: &str) -> Result<Vec<T>, Error> {
        let mut v = Vec::new();
        self.reserve(&mut v, n, part)?;
        v.resize(n, value);
        Ok(v)
    }
}

impl SplatTree {
    /// Builds the hierarchy over `cloud`, level by level: each node's points (a contiguous
    /// range of an index array) are split at the median of their longest bounding-box axis,
    /// and each half again, into up to 4 children, until single points remain; then spheres,
    /// normals, cones and colours are computed bottom-up. O(n log n) work; the nodes of a
    /// level are split in parallel. Non-finite points are left out. An empty cloud gives an
    /// empty tree.
    ///
    /// Leaf radii come from the cloud; a cloud without radii gets one radius for all points,
    /// estimated from the spacing (three quarters of the typical radius of the nodes just
    /// above the leaves), so splats of neighbouring points overlap.
    ///
    /// # Errors
    /// [`Error::CloudAttributeLength`] when an attribute array's length is not the number of
    /// positions (the fields are public; [`PointCloud::check_lengths`]).
    /// [`Error::OutOfMemory`] when an array of the build (each proportional to the number of
    /// points: the points with their indices, node ranges, the nodes, per-node weights, the
    /// nodes again while chains are inserted and each level's list of them) cannot be allocated,
    /// naming it and its bytes. The hierarchy of a cloud that fits in memory may not, and an
    /// infallible allocation would abort the process instead. (With overcommit the system may
    /// still stop the process later; this is what the allocator refuses.)
    pub fn build(cloud: &PointCloud) -> Result<Self, Error> {
        cloud.check_lengths()?;
        let building = Building { points: cloud.len() };
        // Points travel with their indices, so partitioning reads memory in order instead of
        // chasing an index into the cloud (which made building 15 M points cache-miss bound).
        let mut index: Vec<Item> = Vec::new();
        building.reserve(&mut index, cloud.len(), "points with their indices")?;
        index.extend(
            cloud
                .positions
                .iter()
                .enumerate()
                .filter(|(_, p)| p.iter().all(|c| c.is_finite()))
                .map(|(i, p)| (*p, i as u32)),
        );
        if index.is_empty() {
            return Ok(Self::default());
        }
        // Top-down: (start, len) of each node's range in `index`, breadth first. A node's
        // children's ranges follow from its own ([`children_of`]): a level's points are
        // partitioned in place, in parallel, then the next level's ranges appended.
        let mut ranges: Vec<(u32, u32)> = Vec::new();
        building.reserve(&mut ranges, 1, "node ranges")?;
        ranges.push((0, index.len() as u32));
        let mut level_start = 0;
        while level_start < ranges.len() {
            let level_end = ranges.len();
            partition_level(&mut index, 0, &ranges[level_start..level_end]);
            // Exactly the next level: levels grow about fourfold, so the array is copied about
            // a third of its final size in all (doubling copied up to all of it), and holds
            // nothing spare.
            let next: usize =
                ranges[level_start..].iter().map(|&r| usize::from(children_of(r).count)).sum();
            building.reserve(&mut ranges, next, "node ranges")?;
            for i in level_start..level_end {
                ranges.extend_from_slice(children_of(ranges[i]).ranges());
            }
            level_start = level_end;
        }
        // Bottom-up: spheres, normals, cones, colours.
        let mut nodes: Vec<SplatNode> = Vec::new();
        building.reserve(&mut nodes, ranges.len(), "nodes")?;
        let mut next_child = 1u32;
        for &range in &ranges {
            let count = children_of(range).count;
            nodes.push(SplatNode {
                centre: [0.0; 3],
                radius: 0.0,
                normal: [0.0; 3],
                cone: std::f32::consts::PI,
                color: [0; 3],
                first_child: if count > 0 { next_child } else { 0 },
                child_count: count,
            });
            next_child += u32::from(count);
        }
        let uniform = cloud.radii.is_none();
        let mut tree = Self { nodes, min_leaf_radius: 0.0 };
        let radius_of = |i| cloud.radii.as_ref().map_or(0.0, |r: &Vec<f32>| r[i]);
        tree.fill_bottom_up(building, cloud, &index, &ranges, radius_of)?;
        if uniform {
            let radius = tree.estimate_spacing(building)?;
            tree.fill_bottom_up(building, cloud, &index, &ranges, |_| radius)?;
        }
        // The work arrays go before the chained copy of the nodes is made.
        drop((index, ranges));
        Ok(Self::new(with_chains(building, tree.nodes)?))
    }

    /// Computes every node from its children (or, for a leaf, its point), last node first.
    fn fill_bottom_up(
        &mut self,
        building: Building,
        cloud: &PointCloud,
        index: &[Item],
        ranges: &[(u32, u32)],
        leaf_radius: impl Fn(usize) -> f32,
    ) -> Result<(), Error> {
        // Point counts per node, for weighting averages.
        let mut weight = building.filled(self.nodes.len(), 0u32, "point counts per node")?;
        for i in (0..self.nodes.len()).rev() {
            let node = self.nodes[i];
            if node.child_count == 0 {
                let p = index[ranges[i].0 as usize].1 as usize;
                let normal = cloud.normals.as_ref().map(|n| n[p]);
                self.nodes[i] = SplatNode {
                    centre: cloud.positions[p],
                    radius: leaf_radius(p).max(0.0),
                    normal: normal.unwrap_or([0.0; 3]),
                    cone: if normal.is_some() { 0.0 } else { std::f32::consts::PI },
                    color: cloud.colors.as_ref().map_or([200; 3], |c| c[p]),
                    ..node
                };
                weight[i] = 1;
                continue;
            }
            let children = self.children(i);
            let kids = &self.nodes[children.clone()];
            let ws = &weight[children];
            let (centre, radius) = bounding_sphere(kids);
            let total: u32 = ws.iter().sum();
            let mut n = [0.0f32; 3];
            let mut color = [0u64; 3];
            for (k, &w) in kids.iter().zip(ws) {
                for a in 0..3 {
                    n[a] += k.normal[a] * w as f32;
                    color[a] += u64::from(k.color[a]) * u64::from(w);
                }
            }
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            let (normal, cone) =
                if len > 1e-12 && kids.iter().all(|k| k.cone < std::f32::consts::PI) {
                    let n = n.map(|c| c / len);
                    let cone = kids
                        .iter()
                        .map(|k| angle(n, k.normal) + k.cone)
                        .fold(0.0f32, f32::max)
                        .min(std::f32::consts::PI);
                    (n, cone)
                } else {
                    ([0.0; 3], std::f32::consts::PI)
                };
            let t = u64::from(total.max(1));
            self.nodes[i] = SplatNode {
                centre,
                radius,
                normal,
                cone,
                color: color.map(|c| ((c + t / 2) / t) as u8),
                ..node
            };
            weight[i] = total;
        }
        Ok(())
    }

    /// A splat radius for clouds without radii: 3/2 of the median radius of the nodes whose
    /// children are all leaves (computed with zero leaf radii, so it measures point spacing).
    /// Such a node holds about 4 points, so its radius is about `2 / sqrt(pi * density)` and
    /// this is `3 / sqrt(pi * density)`: the radius `cloud::sample_mesh` gives, at which
    /// random disks leave about e^-9 of the surface uncovered. Disks that cover the surface
    /// are what lets traversal stop at pixel-sized nodes without holes: a pixel centre inside
    /// some point's disk is inside the disk of every node above that point.
    fn estimate_spacing(&self, building: Building) -> Result<f32, Error> {
        // Room for every such node: each inner node of a built tree (before chains) has at
        // least two children, so there are at most half as many inner nodes as nodes.
        let mut radii: Vec<f32> = Vec::new();
        building.reserve(&mut radii, self.nodes.len() / 2, "radii of the nodes above leaves")?;
        radii.extend(
            (0..self.nodes.len())
                .filter(|&i| {
                    let c = self.children(i);
                    !c.is_empty() && c.clone().all(|k| self.nodes[k].child_count == 0)
                })
                .map(|i| self.nodes[i].radius)
                .filter(|r| *r > 0.0 && r.is_finite()),
        );
        if radii.is_empty() {
            // Points that coincide in fours: a hundredth of the root (none if the root's
            // radius is infinite).
            let root = self.nodes.first().map_or(0.0, |r| r.radius);
            return Ok(if root.is_finite() { root * 0.01 } else { 0.0 });
        }
        let mid = radii.len() / 2;
        let (_, m, _) = radii.select_nth_unstable_by(mid, f32::total_cmp);
        Ok(*m * 1.5)
    }
}

/// A point and its index in the cloud.
type Item = ([f32; 3], u32);

/// Nodes of a level partitioned one after another, below which [`partition_level`] stops
/// splitting the level into parallel halves (as `with_min_len(64)` did).
const SEQUENTIAL_NODES: usize = 64;

/// Partitions the points of every node of `level` as [`split4`] does. `index` is the part of
/// the index array from `offset` on, holding every node's range. The level is halved
/// recursively, each half on its own part of `index`, in parallel: disjoint mutable slices
/// without a vector of them (16 bytes per node of the level) nor one of their children's
/// ranges (24 bytes per node, and a heap block per inner node).
fn partition_level(index: &mut [Item], offset: u32, level: &[(u32, u32)]) {
    if level.len() <= SEQUENTIAL_NODES {
        for &(start, len) in level {
            let from = (start - offset) as usize;
            split4(&mut index[from..from + len as usize]);
        }
        return;
    }
    let (first, second) = level.split_at(level.len() / 2);
    let at = second[0].0;
    let (a, b) = index.split_at_mut((at - offset) as usize);
    rayon::join(|| partition_level(a, offset, first), || partition_level(b, at, second));
}

/// The children of a node as [`split4`] makes them: `(start, len)` ranges of the index array.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Children {
    ranges: [(u32, u32); 4],
    count: u8,
}

impl Children {
    fn push(&mut self, range: (u32, u32)) {
        self.ranges[usize::from(self.count)] = range;
        self.count += 1;
    }

    /// The children's ranges, in order.
    fn ranges(&self) -> &[(u32, u32)] {
        &self.ranges[..usize::from(self.count)]
    }
}

/// The children of the node whose points are `(start, len)` in the index array: [`split4`]
/// splits at `len / 2` and each half of two points or more at its own half, so where depends
/// on the length alone, not on the points. None for a single point (a leaf); otherwise 2
/// (two points), 3 (three) or 4.
fn children_of((start, len): (u32, u32)) -> Children {
    let mut out = Children::default();
    if len <= 1 {
        return out;
    }
    let half = len / 2;
    for (offset, part) in [(0, half), (half, len - half)] {
        if part >= 2 {
            let q = part / 2;
            out.push((start + offset, q));
            out.push((start + offset + q, part - q));
        } else {
            out.push((start + offset, part));
        }
    }
    out
}

/// Splits the points of `slice` into up to 4 groups, in place: at the median of the longest
/// axis, then each half of two points or more again; the groups are [`children_of`] its
/// range. A single point is a leaf (no groups).
fn split4(slice: &mut [Item]) {
    if slice.len() <= 1 {
        return;
    }
    let half = split2(slice);
    let (a, b) = slice.split_at_mut(half);
    for part in [a, b] {
        if part.len() >= 2 {
            split2(part);
        }
    }
}

/// Partitions `slice` at the median of the longest axis of its points' bounding box; returns
/// the size of the first part (`len / 2`).
fn split2(slice: &mut [Item]) -> usize {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for &(p, _) in slice.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let axis = (0..3).max_by(|&a, &b| (hi[a] - lo[a]).total_cmp(&(hi[b] - lo[b]))).unwrap_or(0);
    let mid = slice.len() / 2;
    // Ties broken by index: the partition, hence the tree, is the same on every run.
    slice.select_nth_unstable_by(mid, |a, b| a.0[axis].total_cmp(&b.0[axis]).then(a.1.cmp(&b.1)));
    mid
}

/// A sphere holding the spheres of `kids`: centred in their bounding box, reaching the
/// farthest. In `f64`, where nothing overflows: in `f32` the squares of distances past about
/// 1.8e19 were infinite, and so was a radius, and a box with an infinite side has a NaN
/// middle, so every node above such a child had a NaN centre. A radius past `f32::MAX` (a
/// cloud spanning about 3.4e38, near the ends of `f32`) is infinite, a sphere holding
/// everything, and the centre then comes from the children's centres alone, so it stays
/// finite; traversal refines such a node whatever the view.
fn bounding_sphere(kids: &[SplatNode]) -> ([f32; 3], f32) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for k in kids {
        let r = if k.radius.is_finite() { f64::from(k.radius) } else { 0.0 };
        for a in 0..3 {
            lo[a] = lo[a].min(f64::from(k.centre[a]) - r);
            hi[a] = hi[a].max(f64::from(k.centre[a]) + r);
        }
    }
    // Between the least and the greatest child centre on each axis (the box's lower side is
    // at most the centre of the child that sets the upper side, and the other way round), so
    // it is an `f32` as finite as theirs.
    let centre: [f32; 3] = std::array::from_fn(|a| (0.5 * lo[a] + 0.5 * hi[a]) as f32);
    // Grown by a relative 1e-6 so the rounding to `f32` never leaves a child poking out.
    let radius = kids
        .iter()
        .map(|k| distance(centre, k.centre) + f64::from(k.radius))
        .fold(0.0f64, f64::max)
        * (1.0 + 1e-6);
    (centre, radius as f32)
}

/// The distance between two points, in `f64`: their difference's squares do not overflow.
fn distance(a: [f32; 3], b: [f32; 3]) -> f64 {
    let d = [0, 1, 2].map(|k| f64::from(a[k]) - f64::from(b[k]));
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

/// Angle between two vectors, as `atan2(|a x b|, a . b)`: accurate near 0 and pi, where
/// `acos` of a rounded dot product is not (acos(1 - 2^-24) is already 3e-4).
fn angle(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt().atan2(d)
}

/// A node whose parent's sphere is more than this many times its own gets single-child nodes
/// above it ([`with_chains`]).
const CHAIN_RATIO: f32 = 4.0;

/// How many single-child nodes go above a node whose parent is `ratio` times its size: radii
/// doubling from the node's up to below the parent's.
fn chain_length(ratio: f32) -> u8 {
    if ratio.is_nan() || ratio <= CHAIN_RATIO {
        return 0;
    }
    (ratio.log2().ceil() as u8).saturating_sub(1).clamp(1, 40)
}

/// `nodes` (breadth-first) with single-child nodes inserted above every node (of non-zero
/// radius) whose parent's sphere is more than [`CHAIN_RATIO`] times its own (isolated points
/// or clumps under a large parent): [`chain_length`] of them, centred on the node, their
/// radii doubling from the node's towards the parent's, each with the node's normal, cone
/// and colour.
///
/// Why: `.tsplat` quantizes a child's sphere against its parent's decoded one (centres in
/// steps of a sixth of the parent's radius), so a decoded sphere is its own size plus about
/// a quarter of its parent's; a node much smaller than its parent decodes many times too big,
/// and so does everything below it, a leaf being drawn whatever its size: blobs. With every
/// step at most 4x (usually 2x in a built tree), decoded sizes stay within a small factor.
/// The inserted spheres contain every point below them, as the invariant asks.
///
/// Its arrays (the chain lengths, the new nodes, each level's work list) are allocated
/// fallibly, as [`SplatTree::build`]'s are.
fn with_chains(building: Building, nodes: Vec<SplatNode>) -> Result<Vec<SplatNode>, Error> {
    let mut chain = building.filled(nodes.len(), 0u8, "chain lengths")?;
    for n in &nodes {
        for k in n.children() {
            if nodes[k].radius > 0.0 {
                chain[k] = chain_length(n.radius / nodes[k].radius);
            }
        }
    }
    let extra: usize = chain.iter().map(|&c| usize::from(c)).sum();
    if extra == 0 {
        return Ok(nodes);
    }
    // Level by level over (node, chain nodes still to emit above it).
    let mut out: Vec<SplatNode> = Vec::new();
    building.reserve(&mut out, nodes.len() + extra, "nodes with chains")?;
    let mut level = vec![(0usize, 0u8)];
    while !level.is_empty() {
        let entries = level
            .iter()
            .map(|&(i, pending)| if pending > 0 { 1 } else { usize::from(nodes[i].child_count) })
            .sum();
        let mut next = Vec::new();
        building.reserve(&mut next, entries, "a level of nodes with chains")?;
        let mut next_first = (out.len() + level.len()) as u32;
        for &(i, pending) in &level {
            let n = nodes[i];
            if pending > 0 {
                let radius = n.radius * (1u64 << pending.min(60)) as f32;
                out.push(SplatNode { radius, first_child: next_first, child_count: 1, ..n });
                next.push((i, pending - 1));
                next_first += 1;
            } else {
                let first_child = if n.child_count > 0 { next_first } else { 0 };
                out.push(SplatNode { first_child, ..n });
                next.extend(n.children().map(|k| (k, chain[k])));
                next_first += u32::from(n.child_count);
            }
        }
        level = next;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use rand::rngs::SmallRng;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::error::refusals::refuse_after;

    /// The ranges [`children_of`] gives are the groups [`split4`] leaves: consecutive, covering
    /// the node's range, half of it on each side of `len / 2`, each half split at its own half.
    #[test]
    fn children_cover_the_range_split_at_halves() {
        for len in 0..200u32 {
            let c = children_of((1000, len));
            let lens: Vec<u32> = c.ranges().iter().map(|r| r.1).collect();
            let expected: Vec<u32> = match len {
                0 | 1 => vec![],
                2 => vec![1, 1],
                3 => vec![1, 1, 1],
                _ => {
                    let (a, b) = (len / 2, len - len / 2);
                    vec![a / 2, a - a / 2, b / 2, b - b / 2]
                }
            };
            assert_eq!(lens, expected, "{len}");
            let mut at = 1000;
            for &(start, l) in c.ranges() {
                assert_eq!(start, at);
                at += l;
            }
        }
    }

    /// Each of the build's reservations, refused in turn as an allocator refuses a request
    /// too large for it, is an [`Error::OutOfMemory`] naming the hierarchy, the array and its
    /// bytes, not an abort (`trirast splat-bench --points 60000000` under `ulimit -v 4000000`
    /// sampled its points, then aborted building). Once none is refused the tree is the
    /// usual one. The cloud has no radii (so the spacing is estimated) and a few points far
    /// from a clump (so chains are inserted): every array the build has is asked for.
    #[test]
    fn every_refused_reservation_is_an_error_naming_the_array() {
        let mut rng = SmallRng::seed_from_u64(4);
        let n = 3000;
        let positions: Vec<[f32; 3]> = (0..n)
            .map(|i| {
                let spread = if i % 500 == 0 { 100.0 } else { 1.0 };
                std::array::from_fn(|_| rng.random_range(-spread..spread))
            })
            .collect();
        let cloud = PointCloud { positions, ..PointCloud::default() };
        let whole = SplatTree::build(&cloud).unwrap();
        assert!(whole.nodes.iter().any(|n| n.child_count == 1), "no chains");
        // Per array, in the order first refused: refusals, and the largest request's bytes.
        let mut parts: Vec<(String, usize, u128)> = Vec::new();
        for k in 0.. {
            refuse_after(Some(k));
            let built = SplatTree::build(&cloud);
            refuse_after(None);
            let (what, bytes) = match built {
                Ok(tree) => {
                    assert!(tree == whole, "refusing allocation {k} and after");
                    break;
                }
                Err(Error::OutOfMemory { what, bytes }) => (what, bytes),
                Err(e) => panic!("allocation {k}: {e}"),
            };
            let part = what
                .strip_prefix(&format!("the splat hierarchy of {n} points ("))
                .and_then(|w| w.strip_suffix(')'))
                .unwrap_or_else(|| panic!("allocation {k}: {what}"));
            match parts.iter_mut().find(|p| p.0 == part) {
                Some(p) => (p.1, p.2) = (p.1 + 1, p.2.max(bytes)),
                None => parts.push((part.to_string(), 1, bytes)),
            }
        }
        // Built trees have no single-child nodes but the chains.
        let nodes = whole.nodes.iter().filter(|n| n.child_count != 1).count();
        let bytes = |count: usize, size: usize| (count * size) as u128;
        let all = [
            ("points with their indices", 1, bytes(n, size_of::<Item>())),
            // The root's, then one per level but the last, which has no children.
            ("node ranges", levels_of(n), bytes(nodes, 8)),
            ("nodes", 1, bytes(nodes, size_of::<SplatNode>())),
            ("point counts per node", 2, bytes(nodes, 4)),
            ("radii of the nodes above leaves", 1, bytes(nodes / 2, 4)),
            ("chain lengths", 1, bytes(nodes, 1)),
            ("nodes with chains", 1, bytes(whole.nodes.len(), size_of::<SplatNode>())),
        ];
        for (k, (part, refusals, most)) in all.iter().enumerate() {
            assert_eq!(parts[k], (part.to_string(), *refusals, *most), "{part}");
        }
        // Then one per level of the tree with chains but the last.
        let last = &parts[all.len()..];
        assert_eq!(last.len(), 1, "{parts:?}");
        assert_eq!(last[0].0, "a level of nodes with chains");
        assert_eq!(last[0].1, depth(&whole) - 1);
    }

    /// Levels of the tree over `n` points before chains are inserted.
    fn levels_of(n: usize) -> usize {
        let mut level = vec![(0, n as u32)];
        let mut levels = 0;
        while !level.is_empty() {
            levels += 1;
            level = level.iter().flat_map(|&r| children_of(r).ranges().to_vec()).collect();
        }
        levels
    }

    /// Levels of `tree`.
    fn depth(tree: &SplatTree) -> usize {
        let mut level = vec![0];
        let mut levels = 0;
        while !level.is_empty() {
            levels += 1;
            level = level.iter().flat_map(|&i| tree.children(i)).collect();
        }
        levels
    }
}
