//! The splat hierarchy and renderer: containment, every leaf at threshold 0, agreement with
//! the triangle render of the same sphere away from the silhouette, thread independence, and
//! progressive refinement converging to the full-detail frame.

use glam::{Vec3, Vec4};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use trirast::Target;
use trirast::camera::{Camera, Projection};
use trirast::pipeline::{Fragment, Pipeline};
use trirast::splat::render::{self, Progressive, SplatOptions, SplatShape};
use trirast::splat::{PointCloud, SplatTree};

fn random_cloud(rng: &mut SmallRng, n: usize, radii: bool) -> PointCloud {
    let positions: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            let c = if rng.random() { 5.0 } else { -3.0 };
            [
                c + rng.random_range(-1.0..1.0),
                rng.random_range(-2.0..2.0f32).powi(3),
                rng.random_range(-1.0..1.0),
            ]
        })
        .collect();
    let normals = positions
        .iter()
        .map(|_| {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            v.normalize_or(Vec3::Y).to_array()
        })
        .collect();
    PointCloud {
        radii: radii.then(|| (0..n).map(|_| rng.random_range(0.0..0.05)).collect()),
        colors: Some((0..n).map(|_| [rng.random(), rng.random(), rng.random()]).collect()),
        normals: Some(normals),
        positions,
        ..PointCloud::default()
    }
}

/// Points (with their splat radii) under node `i`.
fn subtree_points(tree: &SplatTree, i: usize, out: &mut Vec<usize>) {
    if tree.nodes[i].child_count == 0 {
        out.push(i);
    }
    for k in tree.children(i) {
        subtree_points(tree, k, out);
    }
}

#[test]
fn every_point_lies_in_every_ancestor_sphere() {
    let mut rng = SmallRng::seed_from_u64(1);
    for &n in &[1usize, 2, 3, 5, 17, 1000, 20_000] {
        for radii in [false, true] {
            let cloud = random_cloud(&mut rng, n, radii);
            let tree = SplatTree::build(&cloud).unwrap();
            assert_eq!(tree.leaf_count(), n, "one leaf per point");
            // Breadth-first layout: children after their parent, contiguous, at most 4.
            let mut expected_child = 1;
            for (i, node) in tree.nodes.iter().enumerate() {
                assert!(node.child_count <= 4);
                if node.child_count > 0 {
                    assert_eq!(node.first_child as usize, expected_child, "node {i}");
                    assert!(node.first_child as usize > i);
                    expected_child += node.child_count as usize;
                }
                assert!(node.cone >= 0.0 && node.cone <= std::f32::consts::PI);
            }
            assert_eq!(expected_child, tree.nodes.len());
            // Every leaf's point (a sphere of the leaf's radius) inside every ancestor.
            let step = (tree.nodes.len() / 400).max(1);
            for i in (0..tree.nodes.len()).step_by(step) {
                let node = tree.nodes[i];
                let mut leaves = Vec::new();
                subtree_points(&tree, i, &mut leaves);
                for l in leaves {
                    let leaf = tree.nodes[l];
                    let d = Vec3::from(leaf.centre).distance(Vec3::from(node.centre));
                    assert!(
                        d + leaf.radius <= node.radius * (1.0 + 1e-5) + 1e-6,
                        "leaf {l} outside node {i}"
                    );
                    // The cone covers the leaf's normal.
                    if node.cone < std::f32::consts::PI {
                        let (u, v) = (Vec3::from(node.normal), Vec3::from(leaf.normal));
                        let a = u.cross(v).length().atan2(u.dot(v));
                        assert!(
                            a <= node.cone + 1e-4,
                            "normal of leaf {l} outside cone of node {i}: n={n} angle {a} cone {} leaf {:?} node {:?}",
                            node.cone,
                            leaf.normal,
                            node.normal
                        );
                    }
                }
            }
        }
    }
    assert!(SplatTree::build(&PointCloud::default()).unwrap().nodes.is_empty());
}

/// Clouds far out along the axes, up to the ends of `f32`: every node's centre finite, and its
/// sphere holding every point below it (in `f64`, where the distances do not overflow). The
/// spheres' arithmetic had been `f32`, whose squares of distances overflow past about 1.8e19:
/// a cloud 1e20 across had NaN centres above its leaves. Past `f32::MAX` a radius is infinite,
/// a sphere holding everything (packed as `f32::MAX`, the largest the format stores), and the
/// cloud still renders, packs and reads back.
#[test]
fn clouds_near_the_ends_of_f32_get_finite_centres_and_containing_spheres() {
    let mut rng = SmallRng::seed_from_u64(9);
    let mut clouds = Vec::new();
    for (scale, offset) in [(1e20f32, 0.0f32), (1e30, 0.0), (1e37, 0.0), (1e20, 3e38)] {
        for radii in [false, true] {
            let mut cloud = random_cloud(&mut rng, 300, radii);
            for p in &mut cloud.positions {
                *p = p.map(|c| c * scale + offset);
            }
            if let Some(r) = &mut cloud.radii {
                r.iter_mut().for_each(|r| *r *= scale);
            }
            clouds.push((cloud, true));
        }
    }
    // The corners of a cube 6e38 across, and points within: no sphere of finite `f32` radius
    // holds them.
    let mut corners = random_cloud(&mut rng, 300, false);
    for (k, p) in corners.positions.iter_mut().enumerate() {
        *p = if k < 8 {
            [0, 1, 2].map(|a| if k >> a & 1 == 1 { 3e38 } else { -3e38 })
        } else {
            p.map(|c| c * 1e37)
        };
    }
    clouds.push((corners, false));
    for (cloud, finite_root) in &clouds {
        let tree = SplatTree::build(cloud).unwrap();
        assert_eq!(tree.leaf_count(), 300);
        for (i, node) in tree.nodes.iter().enumerate() {
            assert!(node.centre.iter().all(|c| c.is_finite()), "node {i}: {:?}", node.centre);
            assert!(node.radius >= 0.0, "node {i}: radius {}", node.radius);
            let mut leaves = Vec::new();
            subtree_points(&tree, i, &mut leaves);
            for l in leaves {
                let leaf = tree.nodes[l];
                let d: f64 = (0..3)
                    .map(|a| (f64::from(leaf.centre[a]) - f64::from(node.centre[a])).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!(
                    d + f64::from(leaf.radius) <= f64::from(node.radius),
                    "leaf {l} outside node {i}"
                );
            }
        }
        assert_eq!(tree.nodes[0].radius.is_finite(), *finite_root);
        let camera = framing(cloud, 1.0);
        let mut target = Target::new(32, 32).unwrap();
        render::render(&mut target, &tree, &camera, &SplatOptions::default());
        // Packed and read back: every point kept, with a finite sphere.
        let packed = trirast::splat::format::encode(&tree).unwrap();
        let read = trirast::splat::format::decode(&packed).unwrap();
        assert_eq!(read.leaf_count(), 300);
        assert!(read.nodes.iter().all(|n| n.centre.iter().all(|c| c.is_finite())));
        let leaves = read.nodes.iter().filter(|n| n.child_count == 0);
        assert!(leaves.clone().all(|n| n.radius.is_finite()), "{:?}", leaves.collect::<Vec<_>>());
    }
}

fn framing(cloud: &PointCloud, aspect: f32) -> Camera {
    let (centre, radius) = trirast::camera::bounding_sphere(&cloud.positions);
    Camera::framing_sphere(centre, radius, 0.4, 0.3, aspect, Projection::Perspective { fov_y: 0.7 })
}

#[test]
fn threshold_zero_draws_every_leaf() {
    let mut rng = SmallRng::seed_from_u64(2);
    let cloud = random_cloud(&mut rng, 5000, false);
    let tree = SplatTree::build(&cloud).unwrap();
    let camera = framing(&cloud, 1.5);
    let mut target = Target::new(150, 100).unwrap();
    let opts = SplatOptions::default().with_threshold(0.0).with_backface_cull(false);
    let stats = render::render(&mut target, &tree, &camera, &opts);
    assert_eq!(stats.leaves_drawn, 5000);
    assert_eq!(stats.drawn, 5000);
    // A coarser threshold draws fewer, bigger splats.
    let coarse = render::render(&mut target, &tree, &camera, &opts.with_threshold(8.0));
    assert!(coarse.drawn < 5000 / 4, "{}", coarse.drawn);
}

#[test]
fn rendering_does_not_depend_on_threads_and_refinement_converges() {
    let mut rng = SmallRng::seed_from_u64(3);
    let cloud = random_cloud(&mut rng, 30_000, true);
    let tree = SplatTree::build(&cloud).unwrap();
    let camera = framing(&cloud, 1.0);
    let frame = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut t = Target::new(120, 120).unwrap().with_ids();
        pool.install(|| render::render(&mut t, &tree, &camera, &SplatOptions::default()));
        t
    };
    let (a, b) = (frame(1), frame(3));
    assert!(a.color == b.color && a.ids == b.ids);
    assert!(a.depth.iter().zip(&b.depth).all(|(x, y)| x.to_bits() == y.to_bits()));
    // Progressive steps end on the same image as a direct render.
    let mut p = Progressive::new(1.0);
    let mut t = Target::new(120, 120).unwrap().with_ids();
    let mut steps = 0;
    while p.step(&mut t, &tree, &camera, &SplatOptions::default(), [0, 0, 0, 255]).is_some() {
        steps += 1;
    }
    assert_eq!(steps, 4);
    assert!(p.is_done());
    assert!(t.color == a.color && t.ids == a.ids);
}

/// A step whose splats are all leaves is the last: the threshold only decides where inner
/// nodes stop refining, so finer levels would draw that image again. A tree of one node under
/// `trirast splat --budget-ms` had stopped there saying "budget reached".
#[test]
fn progressive_refinement_ends_at_a_level_of_single_points() {
    let cloud = PointCloud { positions: vec![[0.0; 3]], ..PointCloud::default() };
    let tree = SplatTree::build(&cloud).unwrap();
    let camera = front_camera();
    let options = SplatOptions::default();
    let mut p = Progressive::new(1.0);
    let mut t = Target::new(32, 32).unwrap();
    let (level, stats) = p.step(&mut t, &tree, &camera, &options, [0, 0, 0, 255]).unwrap();
    assert_eq!(level, 64.0);
    assert_eq!((stats.drawn, stats.leaves_drawn), (1, 1));
    assert!(p.is_done() && p.next_threshold().is_none());
    assert!(p.step(&mut t, &tree, &camera, &options, [0, 0, 0, 255]).is_none());
    let mut direct = Target::new(32, 32).unwrap();
    direct.clear([0, 0, 0, 255]);
    render::render(&mut direct, &tree, &camera, &options);
    assert!(t.color == direct.color);
}

/// Splats drawn into colour and depth alone take a row-slice loop; with id and overdraw
/// buffers, a per-pixel one. Both write the same colour and depth, for both shapes, and the
/// overdraw counts every pixel that was written (a written pixel was covered).
#[test]
fn id_and_overdraw_buffers_do_not_change_the_image() {
    let mut rng = SmallRng::seed_from_u64(6);
    let cloud = random_cloud(&mut rng, 20_000, true);
    let tree = SplatTree::build(&cloud).unwrap();
    let camera = framing(&cloud, 1.25);
    for shape in [SplatShape::Round, SplatShape::Square] {
        for threshold in [0.0, 1.0, 6.0] {
            let opts = SplatOptions::default().with_shape(shape).with_threshold(threshold);
            let mut plain = Target::new(150, 120).unwrap();
            let mut full = Target::new(150, 120).unwrap().with_ids().with_overdraw();
            let a = render::render(&mut plain, &tree, &camera, &opts);
            let b = render::render(&mut full, &tree, &camera, &opts);
            assert_eq!(a, b, "{shape:?} {threshold}");
            assert!(a.pixels > 1000, "{shape:?} {threshold}: {a:?}");
            assert!(plain.color == full.color, "{shape:?} {threshold}");
            assert!(plain.depth.iter().zip(&full.depth).all(|(x, y)| x.to_bits() == y.to_bits()));
            let overdraw = full.overdraw.as_ref().unwrap();
            let ids = full.ids.as_ref().unwrap();
            assert!(ids.iter().zip(overdraw).all(|(&id, &o)| id < 0 || o > 0));
        }
    }
}

/// A dense sampling of a sphere, splatted, covers the pixels the triangle render of that
/// sphere covers, except within 2 pixels of the silhouette (splats are disks around sample
/// points, so the outline is ragged by up to a splat radius).
#[test]
fn splat_sphere_covers_what_the_triangle_sphere_covers() {
    let (w, h) = (160u32, 120u32);
    let camera = front_camera();
    // Triangles: a fine UV sphere.
    let mesh = trirast::scene::sphere_mesh(40_000).unwrap();
    let vp = camera.view_projection(w as f32 / h as f32);
    let mut tri_target = Target::new(w, h).unwrap().with_ids();
    let vs = |p: &[f32; 3]| (vp * Vec3::from(*p).extend(1.0), ());
    let fs = |_: &Fragment<()>| Some(Vec4::ONE);
    Pipeline::default().draw(&mut tri_target, &vs, &fs, &mesh.positions, &mesh.triangles).unwrap();
    // Splats: 200,000 random points on the unit sphere, outward normals.
    let mut rng = SmallRng::seed_from_u64(4);
    let positions: Vec<[f32; 3]> = (0..200_000)
        .map(|_| {
            loop {
                let v = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let l = v.length();
                if l > 0.1 && l <= 1.0 {
                    break (v / l).to_array();
                }
            }
        })
        .collect();
    let cloud = PointCloud { normals: Some(positions.clone()), positions, ..PointCloud::default() };
    let tree = SplatTree::build(&cloud).unwrap();
    let mut splat_target = Target::new(w, h).unwrap().with_ids();
    let stats = render::render(&mut splat_target, &tree, &camera, &SplatOptions::default());
    // About 30 points per pixel: traversal must stop well above the leaves (the threshold
    // tests the points' spread, not the inflated splat), yet leave no holes (below).
    assert!(stats.leaves_drawn * 4 < stats.drawn, "{stats:?}");
    let covered = |t: &Target, x: i64, y: i64| {
        (0..w as i64).contains(&x)
            && (0..h as i64).contains(&y)
            && t.ids.as_ref().unwrap()[(y * w as i64 + x) as usize] >= 0
    };
    let mut differ = 0;
    let mut inside = 0;
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let a = covered(&tri_target, x, y);
            inside += usize::from(a);
            if a == covered(&splat_target, x, y) {
                continue;
            }
            differ += 1;
            // Within 2 px of the triangle render's silhouette.
            let near_edge =
                (-2..=2).any(|dy| (-2..=2).any(|dx| covered(&tri_target, x + dx, y + dy) != a));
            assert!(near_edge, "pixel ({x}, {y}) differs away from the silhouette");
        }
    }
    assert!(inside > 3000, "{inside}");
    assert!(differ < inside / 10, "{differ} of {inside}");
}

/// A perspective camera 4 units in front of the origin, looking at it.
fn front_camera() -> Camera {
    Camera {
        eye: Vec3::new(0.0, 0.0, 4.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        projection: Projection::Perspective { fov_y: 0.8 },
        near: 1.0,
        far: 10.0,
    }
}

/// A tree made by hand whose child ranges point back at a node itself, before it or past
/// the nodes is drawn without them (the walk keeps only children after their parent and
/// within the nodes), where the renderer had indexed past the end; one whose ranges overlap
/// is drawn visiting each node once.
#[test]
fn hand_made_trees_with_bad_child_ranges_render() {
    use trirast::splat::SplatNode;
    let node = |first_child, child_count| SplatNode {
        centre: [0.0; 3],
        radius: 1.0,
        normal: [0.0; 3],
        cone: std::f32::consts::PI,
        color: [200, 100, 50],
        first_child,
        child_count,
    };
    let projection = Projection::Perspective { fov_y: 0.7 };
    let camera = Camera::framing_sphere(Vec3::ZERO, 1.0, 0.4, 0.3, 1.0, projection);
    let options = SplatOptions::default().with_threshold(0.0);
    for nodes in [
        vec![node(5, 4)],
        vec![node(0, 2)],
        vec![node(1, 2), node(0, 1)],
        vec![node(1, 4), node(u32::MAX, 4), node(0, 0)],
    ] {
        let tree = SplatTree::new(nodes.clone());
        let mut target = Target::new(32, 32).unwrap();
        render::render(&mut target, &tree, &camera, &options);
        for i in 0..nodes.len() {
            let children = tree.children(i);
            assert!(children.is_empty() || (children.start > i && children.end <= nodes.len()));
        }
    }
    // Children shared by several parents (each node listing the next four): each node is
    // visited once, where the walk had visited them along every path, 4.2 M visits for 24
    // nodes and effectively without end for 64.
    let mut nodes: Vec<SplatNode> = (0..64).map(|i| node(i + 1, 4)).collect();
    nodes.extend((0..4).map(|_| node(0, 0)));
    let tree = SplatTree::new(nodes);
    let mut target = Target::new(32, 32).unwrap();
    let stats = render::render(&mut target, &tree, &camera, &options);
    assert!(stats.visited <= tree.nodes.len() && stats.drawn > 0, "{stats:?}");
}
