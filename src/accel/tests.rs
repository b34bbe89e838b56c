//! The acceleration structures against brute force over every primitive: the tree's walks,
//! the leaf layouts, packets and the build's two collapses.

use super::build::*;
use super::leaf_prims::{
    FlatPrimitives, LeafPrim, MAX_FLAT_PRIMITIVES, closest_in_leaf, closest_in_node, node_triangles,
};
use super::packet::*;
use super::traverse::*;
use crate::geometry::triangle::{OriginTerms, TriangleGeom, intersect_triangle_from};
use crate::geometry::{Shape, SphereGeom};
use crate::math::Vec3A;
use crate::math::rng::{path_key, uniform};
use obvhs::BvhBuildParams;

/// Random triangles and spheres, already in BVH order.
fn random_scene(n: u32) -> (Vec<Shape>, Bvh4) {
    let shapes = random_shapes(n);
    let (bvh, order) = build_bvh(&shapes).unwrap();
    (order.iter().map(|&i| shapes[i as usize]).collect(), bvh)
}

/// Random triangles and one sphere in seven, in a 10-unit cube.
fn random_shapes(n: u32) -> Vec<Shape> {
    let u = |i: u32, d: u32| uniform(path_key(1, i, 0), 0, d);
    (0..n)
        .map(|i| {
            let c = Vec3A::new(u(i, 0), u(i, 1), u(i, 2)) * 10.0;
            if i % 7 == 0 {
                Shape::Sphere(SphereGeom {
                    center: c,
                    radius: 0.05 + 0.3 * u(i, 3),
                })
            } else {
                let e = |d| Vec3A::new(u(i, d) - 0.5, u(i, d + 1) - 0.5, u(i, d + 2) - 0.5);
                Shape::Triangle(TriangleGeom::new(c, c + e(4), c + e(7)))
            }
        })
        .collect()
}

/// Ray `i` of a random set `set` through the scenes of [`random_scene`]: half of them
/// unbounded, half with a random length.
fn random_ray(set: u64, i: u32) -> (Vec3A, Vec3A, f32) {
    let u = |d: u32| uniform(path_key(set, i, 0), 0, d);
    let origin = Vec3A::new(u(0), u(1), u(2)) * 12.0 - Vec3A::ONE;
    let direction = (Vec3A::new(u(3), u(4), u(5)) - 0.5).normalize();
    let t_max = if i.is_multiple_of(2) {
        f32::INFINITY
    } else {
        3.0 * u(6)
    };
    (origin, direction, t_max)
}

/// The closest hit found by the reference path.
fn brute_force_closest(
    shapes: &[Shape],
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> Option<(u32, f32)> {
    super::reference::closest_hit(shapes.iter().copied(), origin, direction, t_max)
}

#[test]
fn closest_hit_and_any_hit_agree_with_brute_force() {
    let (shapes, bvh) = random_scene(3000);
    assert!(bvh.depth > 2 && bvh.depth <= MAX_DEPTH);
    let mut hits = 0;
    // One stack for every ray, as the renderer uses it: what a ray leaves must not matter.
    let mut stack = TraversalStack::default();
    for i in 0..4000 {
        let (origin, direction, t_max) = random_ray(2, i);
        let brute = brute_force_closest(&shapes, origin, direction, t_max);
        let found = bvh.closest_hit(&mut stack, origin, direction, t_max, |s, t| {
            shapes[s as usize].intersect_t(origin, direction, t)
        });
        assert_eq!(found.map(|h| h.1), brute.map(|h| h.1), "ray {i}");
        let occluded = bvh.any_hit(&mut stack, origin, direction, t_max, |s, t| {
            shapes[s as usize].intersect_t(origin, direction, t)
        });
        assert_eq!(occluded, brute.is_some(), "ray {i}");
        hits += brute.is_some() as u32;
    }
    assert!(
        hits > 400,
        "the test rays hit something often enough: {hits}"
    );
}

#[test]
fn leaf_records_agree_with_brute_force_in_a_scene_with_leaves_of_four() {
    // Above `SMALL_SCENE`, leaves hold up to four primitives and are tested four wide.
    let (shapes, bvh) = random_scene(6000);
    let prims: Vec<LeafPrim> = shapes.iter().map(LeafPrim::new).collect();
    let multi = (0..bvh.nodes.len())
        .filter(|&n| bvh.nodes[n].count.iter().any(|&c| c >= 2))
        .count();
    assert!(multi > 100, "leaves of several primitives: {multi}");
    let mut hits = 0;
    let mut stack = TraversalStack::default();
    for i in 0..3000 {
        let (origin, direction, t_max) = random_ray(7, i);
        let brute = brute_force_closest(&shapes, origin, direction, t_max);
        let found = bvh.closest_hit_by_leaf(&mut stack, origin, direction, t_max, |f, c, t| {
            closest_in_leaf(&prims, f, c, origin, direction, t)
        });
        assert_eq!(found.map(|h| h.1), brute.map(|h| h.1), "ray {i}");
        hits += brute.is_some() as u32;
    }
    assert!(
        hits > 300,
        "the test rays hit something often enough: {hits}"
    );
}

#[test]
fn node_triangles_agree_with_brute_force_in_a_scene_with_leaves_of_one() {
    // Below `SMALL_SCENE`, leaves hold one primitive and a node's triangles are tested
    // together (spheres one by one).
    let (shapes, bvh) = random_scene(2000);
    let prims: Vec<LeafPrim> = shapes.iter().map(LeafPrim::new).collect();
    let quads = node_triangles(&prims, &bvh);
    assert_eq!(quads.len(), bvh.nodes.len());
    let mut hits = 0;
    let mut stack = TraversalStack::default();
    for i in 0..3000 {
        let (origin, direction, t_max) = random_ray(8, i);
        let brute = brute_force_closest(&shapes, origin, direction, t_max);
        let found =
            bvh.closest_hit_by_node(&mut stack, origin, direction, t_max, |n, node, lanes, t| {
                closest_in_node(&prims, &quads[n], node, lanes, origin, direction, t)
            });
        assert_eq!(found, brute, "ray {i}");
        hits += brute.is_some() as u32;
    }
    assert!(
        hits > 300,
        "the test rays hit something often enough: {hits}"
    );
    // Trees with leaves of several primitives have none.
    let (shapes, bvh) = random_scene(6000);
    let prims: Vec<LeafPrim> = shapes.iter().map(LeafPrim::new).collect();
    assert!(node_triangles(&prims, &bvh).is_empty());
}

#[test]
fn the_parallel_collapse_makes_the_sequential_tree() {
    // Leaves of one primitive (a deep tree) and of up to four, each with subtrees cut at
    // the split and inner lanes that end above it.
    for (size, params, max_leaf_size) in [
        (3000, BvhBuildParams::very_slow_build(), 1),
        (20000, BvhBuildParams::fast_build(), MAX_LEAF_SIZE),
    ] {
        let (shapes, _) = random_scene(size);
        let bvh2 = build_bvh2(&shapes, params);
        let tree = BinaryTree {
            bvh2: &bvh2,
            max_leaf_size,
            node_cost: params.collapse_traversal_cost,
        };
        let (mut nodes, mut order) = (Vec::new(), Vec::new());
        let depth = tree.collapse(
            &[0],
            &mut nodes,
            &mut order,
            MAX_DEPTH,
            usize::MAX,
            &mut std::iter::empty(),
        );
        let (mut parallel_nodes, mut parallel_order) = (Vec::new(), Vec::new());
        let parallel_depth = tree.collapse_in_parallel(&mut parallel_nodes, &mut parallel_order);
        assert!(
            depth > PARALLEL_LEVELS + 1,
            "the tree reaches below the split"
        );
        assert_eq!(parallel_depth, depth);
        assert_eq!(parallel_order, order);
        assert!(parallel_nodes == nodes, "{size} primitives: the same nodes");
    }
}

#[test]
fn flat_primitives_agree_with_brute_force_in_a_tiny_scene() {
    // 28 primitives (the hexagonal room's count), four of them spheres: seven groups of
    // triangles, the last one partly empty.
    let (shapes, _) = random_scene(28);
    let prims: Vec<LeafPrim> = shapes.iter().map(LeafPrim::new).collect();
    let flat = FlatPrimitives::new(&prims).expect("28 primitives are few enough");
    let mut hits = 0;
    for i in 0..20_000 {
        // Every other ray aimed near a primitive, so that most of those hit one.
        let (origin, mut direction, t_max) = random_ray(9, i);
        if i % 2 == 0 {
            let target = match shapes[(i / 2) as usize % shapes.len()] {
                Shape::Triangle(t) => t.v0 + (t.e1 + t.e2) * 0.3,
                Shape::Sphere(s) => s.center + direction * s.radius,
            };
            direction = (target - origin + 0.05 * direction).normalize();
        }
        let brute = brute_force_closest(&shapes, origin, direction, t_max);
        assert_eq!(flat.closest_hit(origin, direction, t_max), brute, "ray {i}");
        hits += brute.is_some() as u32;
    }
    assert!(
        hits > 5000,
        "the test rays hit something often enough: {hits}"
    );
    let (shapes, _) = random_scene(MAX_FLAT_PRIMITIVES as u32 + 1);
    let prims: Vec<LeafPrim> = shapes.iter().map(LeafPrim::new).collect();
    assert!(FlatPrimitives::new(&prims).is_none());
}

#[test]
fn packets_agree_with_single_rays() {
    // A small tree (packet node tests alone) and a large one (confirmed ray by ray).
    for size in [1000, 20000] {
        let (shapes, bvh) = random_scene(size);
        let confirmed = bvh.nodes.len() >= CONFIRMED_PACKET_NODES;
        assert_eq!(confirmed, size > 1000, "{} nodes", bvh.nodes.len());
        packets_agree_in(&shapes, &bvh);
    }
}

/// The segments of test packet `i`: `1 + i % PACKET_SIZE` of them from `origin` toward
/// points scattered up to `spread / 2` per axis around `target` (random stream `stream`),
/// each `reach` times as long as the way to its point. Returns the directions, the
/// lengths and how many there are.
fn segments_toward(
    stream: u64,
    i: u32,
    origin: Vec3A,
    target: Vec3A,
    spread: f32,
    reach: f32,
) -> ([Vec3A; PACKET_SIZE], [f32; PACKET_SIZE], usize) {
    let n = 1 + (i as usize % PACKET_SIZE);
    let mut directions = [Vec3A::ZERO; PACKET_SIZE];
    let mut t_max = [0.0; PACKET_SIZE];
    for k in 0..n {
        let v = |d: u32| uniform(path_key(stream, i, k as u32), 0, d) - 0.5;
        let to = target + spread * Vec3A::new(v(0), v(1), v(2)) - origin;
        (directions[k], t_max[k]) = (to.normalize(), reach * to.length());
    }
    (directions, t_max, n)
}

fn packets_agree_in(shapes: &[Shape], bvh: &Bvh4) {
    let mut stack = TraversalStack::default();
    for i in 0..400 {
        let u = |d: u32| uniform(path_key(3, i, 0), 0, d);
        let origin = Vec3A::new(u(0), u(1), u(2)) * 10.0;
        // A cone of directions toward a random target, as shadow rays toward a light; some
        // packets are spread wide enough to mix direction signs.
        let target = Vec3A::new(u(3), u(4), u(5)) * 10.0;
        let spread = if i % 3 == 0 { 8.0 } else { 0.5 };
        let (directions, t_max, n) = segments_toward(4, i, origin, target, spread, 1.0);
        let packet = Packet::new(origin, &directions[..n], &t_max[..n]);
        let occluded = bvh.any_hit_packet(&mut stack, &packet, |s, open| {
            (0..n)
                .filter(|k| {
                    open & (1 << k) != 0
                        && shapes[s as usize].intersect_t(origin, directions[*k], t_max[*k])
                            < f32::INFINITY
                })
                .fold(0, |m, k| m | 1 << k)
        });
        for k in 0..n {
            let single = bvh.any_hit(&mut stack, origin, directions[k], t_max[k], |s, t| {
                shapes[s as usize].intersect_t(origin, directions[k], t)
            });
            assert_eq!(occluded & (1 << k) != 0, single, "packet {i}, ray {k}");
        }
    }
}

#[test]
fn plane_culling_never_drops_a_crossing_segment() {
    // Random planes and packets, some segments ending within a hair of the plane: every
    // packet the test culls must have the origin and all far ends strictly on one side
    // (checked in f64), and clear cases must be culled.
    let mut culled = 0;
    for i in 0..20000 {
        let u = |d: u32| uniform(path_key(5, i, 0), 0, d);
        let origin = Vec3A::new(u(0), u(1), u(2)) * 20.0 - 10.0;
        let normal = Vec3A::new(u(3) - 0.5, u(4) - 0.5, u(5) - 0.5) * 3.0;
        let on_plane = Vec3A::new(u(6), u(7), u(8)) * 20.0 - 10.0;
        // Far ends from 1e-5 to 1 away from the plane, on either side.
        let gap = 10f32.powf(-5.0 * u(12)) * if u(13) < 0.5 { -1.0 } else { 1.0 };
        let target = on_plane
            + Vec3A::new(u(9) - 0.5, u(10) - 0.5, u(11) - 0.5) * 1e-3
            + gap * normal.normalize();
        let spread = if i % 2 == 0 { 1e-3 } else { 0.1 };
        let (directions, t_max, n) = segments_toward(6, i, origin, target, spread, 1.0);
        let packet = Packet::new(origin, &directions[..n], &t_max[..n]);
        if !packet.stays_on_one_side(normal, on_plane - origin) {
            continue;
        }
        culled += 1;
        let side = |x: Vec3A| {
            let (x, p, nn) = (x.as_dvec3(), on_plane.as_dvec3(), normal.as_dvec3());
            (x - p).dot(nn).signum()
        };
        let s0 = side(origin);
        for k in 0..n {
            let end = origin + directions[k] * t_max[k];
            assert_eq!(side(end), s0, "packet {i} ray {k} crosses the plane");
        }
    }
    assert!(culled > 4000, "clear cases are culled: {culled}");
}

#[test]
fn edge_culling_never_drops_a_hit() {
    // Random triangles and packets aimed across the plane at points near an edge, from
    // 1e-6 to 1 inside or outside it: whenever the test culls a packet, the ray test
    // must miss with every ray, and clear cases must be culled.
    let mut culled = 0;
    for i in 0..20000 {
        let u = |d: u32| uniform(path_key(7, i, 0), 0, d);
        let point = |d: u32| Vec3A::new(u(d), u(d + 1), u(d + 2)) * 20.0 - 10.0;
        let tri = TriangleGeom::new(point(0), point(3), point(6));
        let origin = point(9);
        let vertices = tri.vertices();
        let edge = (i % 3) as usize;
        let (a, b) = (vertices[edge], vertices[(edge + 1) % 3]);
        let inward = (vertices[(edge + 2) % 3] - a)
            .reject_from(b - a)
            .normalize();
        let gap = 10f32.powf(-6.0 * u(12)) * if u(13) < 0.5 { -1.0 } else { 1.0 };
        let target = a + u(14) * (b - a) + gap * inward;
        let spread = if i % 2 == 0 { 1e-4 } else { 0.1 };
        // Past the plane: the segments reach it, so only the edges decide.
        let (directions, t_max, n) = segments_toward(8, i, origin, target, spread, 1.5);
        let packet = Packet::new(origin, &directions[..n], &t_max[..n]);
        let terms = OriginTerms::new(&tri, origin);
        if !packet.passes_beside(&tri, &terms) {
            continue;
        }
        culled += 1;
        for k in 0..n {
            let hit = intersect_triangle_from(&tri, &terms, directions[k], 0.0, t_max[k]);
            assert!(hit.is_none(), "packet {i} ray {k} hits the culled triangle");
        }
    }
    // About 10,000 packets aim outside; those whose spread is below their gap are clear.
    assert!(culled > 3500, "clear cases are culled: {culled}");
}

#[test]
fn negative_zero_direction_components_count_as_parallel() {
    // A ray straight up whose x and y components are -0.0 (as `-direction` of a light
    // pointing straight down gives): it must still find the triangle above it, singly,
    // by any-hit, and in a packet.
    let tri = TriangleGeom::new(
        Vec3A::new(-1.0, -1.0, 1.0),
        Vec3A::new(1.0, -1.0, 1.0),
        Vec3A::new(0.0, 1.0, 1.0),
    );
    let shapes = [Shape::Triangle(tri)];
    let (bvh, _) = build_bvh(&shapes).unwrap();
    let (origin, direction) = (Vec3A::new(0.1, 0.2, 0.0), Vec3A::new(-0.0, -0.0, 1.0));
    let intersect = |s: u32, t: f32| shapes[s as usize].intersect_t(origin, direction, t);
    assert_eq!(
        bvh.closest_hit(
            &mut TraversalStack::default(),
            origin,
            direction,
            10.0,
            intersect
        ),
        Some((0, 1.0))
    );
    assert!(bvh.any_hit(
        &mut TraversalStack::default(),
        origin,
        direction,
        10.0,
        intersect
    ));
    let directions = [direction, Vec3A::new(0.0, 0.0, 1.0)];
    let packet = Packet::new(origin, &directions, &[10.0, 10.0]);
    let occluded = bvh.any_hit_packet(&mut TraversalStack::default(), &packet, |_, open| {
        (0..2)
            .filter(|k| open & (1 << k) != 0 && intersect(0, 10.0) < f32::INFINITY)
            .fold(0, |m, k| m | 1 << k)
    });
    assert_eq!(occluded, 0b11);
}

/// The scalar form of [`safe_inverse3`], written out as the reference.
fn safe_inverse(x: f32) -> f32 {
    if x.abs() < f32::EPSILON {
        let sign = if x >= 0.0 { 1.0 } else { -1.0 };
        sign / f32::EPSILON
    } else {
        1.0 / x
    }
}

#[test]
fn box_ray_setup_matches_the_scalar_inverse_and_near_planes() {
    let values = [
        0.0,
        -0.0,
        1e-9,
        -1e-9,
        f32::EPSILON,
        -f32::EPSILON,
        0.3,
        -0.7,
        1.0,
    ];
    for &x in &values {
        for &y in &values {
            let direction = Vec3A::new(x, y, -y);
            let ray = BoxRay::new(Vec3A::ZERO, direction);
            for a in 0..3 {
                let d = direction[a];
                assert_eq!(ray.inv_direction[a].x.to_bits(), safe_inverse(d).to_bits());
                assert_eq!(ray.near[a], if d >= 0.0 { a } else { a + 3 }, "{d}");
            }
        }
    }
}

#[test]
#[ignore = "slow: stress, an 8,000-triangle chain down to the depth limit (~6 s)"]
fn a_chain_of_identical_triangles_is_refused_without_deep_recursion() {
    // Copies of one triangle make the binary tree a long chain; the collapse must give up
    // at the depth limit instead of recursing down the whole chain, which would overflow
    // this thread's small stack (200,000 copies overflowed the main thread's 8 MiB).
    let tri = Shape::Triangle(TriangleGeom::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y));
    let refused = std::thread::Builder::new()
        .stack_size(256 * 1024)
        .spawn(move || build_bvh(&vec![tri; 8_000]).is_none())
        .unwrap()
        .join()
        .unwrap();
    assert!(refused);
}

#[test]
fn empty_and_single_primitive_scenes() {
    let (bvh, order) = build_bvh::<Shape>(&[]).unwrap();
    assert!(
        order.is_empty()
            && bvh
                .closest_hit(
                    &mut TraversalStack::default(),
                    Vec3A::ZERO,
                    Vec3A::X,
                    f32::INFINITY,
                    |_, _| 0.0
                )
                .is_none()
    );
    let one = [Shape::Sphere(SphereGeom {
        center: Vec3A::new(3.0, 0.0, 0.0),
        radius: 1.0,
    })];
    let (bvh, _) = build_bvh(&one).unwrap();
    let hit = bvh.closest_hit(
        &mut TraversalStack::default(),
        Vec3A::ZERO,
        Vec3A::X,
        f32::INFINITY,
        |s, t| one[s as usize].intersect_t(Vec3A::ZERO, Vec3A::X, t),
    );
    assert_eq!(hit, Some((0, 2.0)));
}

/// Checks the tree `bvh` over `shapes` (input order), whose slot `i` holds
/// `shapes[order[i]]`: every primitive in exactly one leaf, every node reached once and after
/// its parent (depth-first order), every lane's box around what is below it (the child
/// node's boxes, or the leaf's primitives), `leaf_lanes` and `depth` as the nodes say.
fn check_tree(bvh: &Bvh4, order: &[u32], shapes: &[Shape]) {
    use obvhs::Boundable;
    let mut sorted = order.to_vec();
    sorted.sort_unstable();
    assert!(
        sorted.iter().copied().eq(0..shapes.len() as u32),
        "a permutation"
    );
    let lane_box = |node: &Node4, k: usize| {
        let b = &node.bounds;
        obvhs::aabb::Aabb::new(
            Vec3A::new(b[0][k], b[1][k], b[2][k]),
            Vec3A::new(b[3][k], b[4][k], b[5][k]),
        )
    };
    let inside = |inner: &obvhs::aabb::Aabb, outer: &obvhs::aabb::Aabb| {
        inner.min.cmpge(outer.min).all() && inner.max.cmple(outer.max).all()
    };
    let mut slot_seen = vec![false; shapes.len()];
    let mut node_seen = vec![false; bvh.nodes.len()];
    // (node, its parent lane's box, its depth)
    let mut stack = vec![(0usize, None, 1usize)];
    let mut depth = 0;
    while let Some((n, parent_box, level)) = stack.pop() {
        assert!(!node_seen[n], "node {n} reached once");
        node_seen[n] = true;
        depth = depth.max(level);
        let node = &bvh.nodes[n];
        let lanes = (0..4).fold(0, |m, k| m | u8::from(node.count[k] != 0) << k);
        assert_eq!(bvh.leaf_lanes[n], lanes, "node {n}");
        for k in 0..4 {
            let b = lane_box(node, k);
            if node.child[k] == u32::MAX {
                assert!(
                    b.min.cmpgt(b.max).all(),
                    "an unused lane of node {n} is empty"
                );
                continue;
            }
            if let Some(parent) = &parent_box {
                assert!(
                    inside(&b, parent),
                    "node {n} lane {k} inside its parent's box"
                );
            }
            if node.count[k] == 0 {
                let child = node.child[k] as usize;
                assert!(child > n, "depth-first: node {child} after its parent {n}");
                stack.push((child, Some(b), level + 1));
            } else {
                let first = node.child[k] as usize;
                for slot in first..first + node.count[k] as usize {
                    assert!(!slot_seen[slot], "slot {slot} in one leaf");
                    slot_seen[slot] = true;
                    let prim_box = shapes[order[slot] as usize].aabb();
                    assert!(inside(&prim_box, &b), "slot {slot} inside its leaf's box");
                }
            }
        }
    }
    assert!(slot_seen.iter().all(|&s| s), "every slot in a leaf");
    assert!(node_seen.iter().all(|&s| s), "every node reached");
    assert_eq!(bvh.depth, depth);
    assert!(bvh.depth <= MAX_DEPTH);
}

/// The closest hit through `bvh` (slot order `order`) as (input index, distance).
fn closest_through(
    bvh: &Bvh4,
    order: &[u32],
    shapes: &[Shape],
    (origin, direction, t_max): (Vec3A, Vec3A, f32),
) -> Option<(u32, f32)> {
    bvh.closest_hit(
        &mut TraversalStack::default(),
        origin,
        direction,
        t_max,
        |s, t| shapes[order[s as usize] as usize].intersect_t(origin, direction, t),
    )
    .map(|(slot, t)| (order[slot as usize], t))
}

#[test]
fn chunked_builds_find_the_hits_of_the_whole_build_and_of_brute_force() {
    // Leaves of one (a small scene) and of up to four, each cut into several chunks; and a
    // flat grid (the centres' box has no height, so one Morton axis is constant).
    let grid: Vec<Shape> = (0..5000u32)
        .map(|i| {
            let (x, y) = ((i / 2 % 50) as f32, (i / 2 / 50) as f32);
            let v = |dx: f32, dy: f32| Vec3A::new(x + dx, y + dy, 0.0) * 0.2;
            if i % 2 == 0 {
                Shape::Triangle(TriangleGeom::new(v(0.0, 0.0), v(1.0, 0.0), v(0.0, 1.0)))
            } else {
                Shape::Triangle(TriangleGeom::new(v(1.0, 0.0), v(1.0, 1.0), v(0.0, 1.0)))
            }
        })
        .collect();
    for (name, shapes, chunk_size) in [
        ("3000 random", random_shapes(3000), 500),
        ("9000 random", random_shapes(9000), 1000),
        ("5000 in a plane", grid, 700),
    ] {
        let box_of = |i: usize| obvhs::Boundable::aabb(&shapes[i]);
        let (whole, whole_order) =
            build_bvh_in_chunks_of(shapes.len(), &box_of, usize::MAX).unwrap();
        let (chunked, order) = build_bvh_in_chunks_of(shapes.len(), &box_of, chunk_size).unwrap();
        check_tree(&whole, &whole_order, &shapes);
        check_tree(&chunked, &order, &shapes);
        assert!(
            chunked.nodes != whole.nodes,
            "{name}: the chunked tree is another tree"
        );
        let mut hits = 0;
        for i in 0..3000 {
            let mut ray = random_ray(11, i);
            if name.contains("plane") {
                // From above the plane, down through it.
                ray.0.z += 1.0;
                ray.1.z = -ray.1.z.abs() - 0.1;
                ray.1 = ray.1.normalize();
            }
            let brute = brute_force_closest(&shapes, ray.0, ray.1, ray.2);
            let chunked_hit = closest_through(&chunked, &order, &shapes, ray);
            assert_eq!(chunked_hit, brute, "{name}, ray {i}");
            assert_eq!(closest_through(&whole, &whole_order, &shapes, ray), brute);
            hits += brute.is_some() as u32;
        }
        assert!(hits > 300, "{name}: the test rays hit often enough: {hits}");
    }
}

/// The 12 triangles of a box's six faces, from `lo` to `hi`: the walls of a room.
fn room_walls(lo: Vec3A, hi: Vec3A) -> Vec<Shape> {
    let corner = |i: usize| {
        Vec3A::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    };
    let faces = [
        [0, 1, 3, 2],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 3, 7, 5],
    ];
    faces
        .iter()
        .flat_map(|f| {
            [
                TriangleGeom::new(corner(f[0]), corner(f[1]), corner(f[2])),
                TriangleGeom::new(corner(f[0]), corner(f[2]), corner(f[3])),
            ]
        })
        .map(Shape::Triangle)
        .collect()
}

#[test]
fn chunked_builds_keep_large_primitives_out_of_the_chunks() {
    // A room around small shapes (in 0..10, the room -20..30): the walls become leaves of
    // the top tree, so no chunk's box reaches from wall to wall, and the hits are brute
    // force's.
    let mut shapes = random_shapes(6000);
    let walls = room_walls(Vec3A::splat(-20.0), Vec3A::splat(30.0));
    shapes.extend(walls.iter().copied());
    let box_of = |i: usize| obvhs::Boundable::aabb(&shapes[i]);
    let boxes: Vec<_> = (0..shapes.len()).map(box_of).collect();
    let (mut large, chunks) = super::chunks::chunks_of(&boxes, 1000);
    large.sort_unstable();
    assert!(
        large.iter().copied().eq(6000..6012),
        "the walls, and only they, are large"
    );
    assert!(chunks.len() >= 6 && chunks.iter().all(|c| c.len() <= 1000));
    let (bvh, order) = build_bvh_in_chunks_of(shapes.len(), &box_of, 1000).unwrap();
    check_tree(&bvh, &order, &shapes);
    let is_wall = |slot: u32| order[slot as usize] as usize >= shapes.len() - walls.len();
    // Every leaf with a wall holds only walls, and every lane without walls below it (a
    // chunk's subtree) lies inside the room, away from the walls.
    fn walls_below(bvh: &Bvh4, node: usize, is_wall: &dyn Fn(u32) -> bool) -> usize {
        let mut total = 0;
        for k in 0..4 {
            let (child, count) = (bvh.nodes[node].child[k], bvh.nodes[node].count[k]);
            let walls = match (count, child) {
                (0, u32::MAX) => continue,
                (0, _) => walls_below(bvh, child as usize, is_wall),
                _ => {
                    let walls = (child..child + count).filter(|&s| is_wall(s)).count();
                    assert!(walls == 0 || walls == count as usize, "walls apart");
                    walls
                }
            };
            if walls == 0 {
                let bounds = &bvh.nodes[node].bounds;
                for axis in 0..3 {
                    assert!(bounds[axis][k] > -0.6 && bounds[axis + 3][k] < 10.6);
                }
            }
            total += walls;
        }
        total
    }
    let walls_found = walls_below(&bvh, 0, &is_wall);
    assert_eq!(walls_found, walls.len());
    for i in 0..3000 {
        let ray = random_ray(12, i);
        let brute = brute_force_closest(&shapes, ray.0, ray.1, ray.2);
        assert_eq!(
            closest_through(&bvh, &order, &shapes, ray),
            brute,
            "ray {i}"
        );
    }
}

#[test]
fn leaves_made_by_hand_give_obvhs_own_tree() {
    // `build_bvh2_of` makes PLOC's leaves from a box function instead of letting obvhs read
    // a slice: the binary tree must be the one obvhs's `build_with_bvh` makes, node for node
    // (with and without reinsertion), or the records made afterwards would not match it.
    for (size, params) in [
        (3000, BvhBuildParams::very_slow_build()),
        (20000, BvhBuildParams::fast_build()),
    ] {
        let shapes = random_shapes(size);
        let ours = build_bvh2(&shapes, params);
        let mut theirs = obvhs::bvh2::Bvh2::default();
        obvhs::ploc::PlocBuilder::with_capacity(shapes.len()).build_with_bvh(
            &mut theirs,
            params.ploc_search_distance,
            &shapes,
            (0..size).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        let mut reinsertion = obvhs::bvh2::reinsertion::ReinsertionOptimizer::default();
        reinsertion.run(&mut theirs, params.reinsertion_batch_ratio, None);
        reinsertion.run(
            &mut theirs,
            params.reinsertion_batch_ratio
                * params.post_collapse_reinsertion_batch_ratio_multiplier,
            None,
        );
        assert_eq!(ours.nodes.len(), theirs.nodes.len());
        let bytes =
            |nodes: &[obvhs::bvh2::node::Bvh2Node]| bytemuck::cast_slice::<_, u8>(nodes).to_vec();
        assert!(
            bytes(&ours.nodes) == bytes(&theirs.nodes),
            "{size}: the same nodes"
        );
        assert_eq!(ours.primitive_indices, theirs.primitive_indices);
    }
}
