//! Primitives laid out for the single-ray traversals' leaf tests: one 40-byte record per BVH
//! slot, holding what the test reads and nothing else (a triangle's first vertex and two
//! edges, packed; no enum to match). In trees whose leaves hold one primitive each (small scenes),
//! each node also keeps its leaves' triangles transposed, so that the closest-hit traversal
//! tests them together; in the smallest scenes the closest-hit query skips the tree and
//! tests every triangle, four at a time.
//!
//! The triangle test does the same arithmetic as [`crate::geometry::triangle::intersect_triangle`],
//! so it returns the same distances bit for bit. The geometric normal `e1 x e2` is computed
//! in the test rather than stored, and the edges are packed without padding: the record was
//! 64 bytes (four aligned vectors), the largest part of a large scene's memory (see
//! docs/performance.md, "Memory per triangle"). The record is read in three unaligned
//! four-float loads, as the aligned one was (see [`TriangleLanes::new`]). The test keeps one
//! early exit, on the distance (cheap for coherent rays, whose candidates mostly lie beyond
//! a closer hit: 12% fewer instructions on the room's primary rays), and forms the other
//! conditions in vector compares before one branch: incoherent rays mispredict early exits
//! about as often as not.

use super::build::{Bvh4, Node4};
use crate::geometry::Shape;
use crate::geometry::sphere::{SphereGeom, intersect_sphere};
use crate::geometry::triangle::TriangleGeom;
use crate::math::{BVec4A, Vec3A, Vec4, transpose4};

/// `w` of a sphere record's first vector (triangles have 0).
const SPHERE_TAG: f32 = 1.0;

/// One primitive for the leaf test.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct LeafPrim {
    /// Triangle: `v0`, then 0. Sphere: centre, then [`SPHERE_TAG`].
    a: [f32; 4],
    /// Triangle: `e1 = v1 - v0`, then `e2 = v2 - v0`. Sphere: radius first, then zeros.
    edges: [f32; 6],
}

impl LeafPrim {
    /// The record of no primitive: its determinant is zero, so no ray hits it.
    const NONE: LeafPrim = LeafPrim {
        a: [0.0; 4],
        edges: [0.0; 6],
    };

    /// The record of `shape`.
    pub fn new(shape: &Shape) -> Self {
        match shape {
            Shape::Triangle(t) => LeafPrim {
                a: t.v0.extend(0.0).to_array(),
                edges: [t.e1.x, t.e1.y, t.e1.z, t.e2.x, t.e2.y, t.e2.z],
            },
            Shape::Sphere(s) => LeafPrim {
                a: s.center.extend(SPHERE_TAG).to_array(),
                edges: [s.radius, 0.0, 0.0, 0.0, 0.0, 0.0],
            },
        }
    }

    /// Whether the record holds a sphere.
    #[inline(always)]
    fn is_sphere(&self) -> bool {
        self.a[3] == SPHERE_TAG
    }

    /// `v0` (a sphere's centre) and the tag.
    #[inline(always)]
    fn first(&self) -> Vec4 {
        Vec4::from_array(self.a)
    }

    /// `e1` and `e2.x`.
    #[inline(always)]
    fn edges_head(&self) -> Vec4 {
        let e = &self.edges;
        Vec4::new(e[0], e[1], e[2], e[3])
    }

    /// `e1.z` and `e2`.
    #[inline(always)]
    fn edges_tail(&self) -> Vec4 {
        let e = &self.edges;
        Vec4::new(e[2], e[3], e[4], e[5])
    }

    /// A triangle record's `v0`, `e1` and `e2`.
    #[inline(always)]
    fn triangle(&self) -> (Vec3A, Vec3A, Vec3A) {
        let e2 = self.edges_tail();
        (
            Vec3A::from_vec4(self.first()),
            Vec3A::from_vec4(self.edges_head()),
            Vec3A::new(e2.y, e2.z, e2.w),
        )
    }

    /// The primitive this record holds.
    #[inline(always)]
    pub fn shape(&self) -> Shape {
        if self.is_sphere() {
            return Shape::Sphere(self.sphere());
        }
        let (v0, e1, e2) = self.triangle();
        Shape::Triangle(TriangleGeom { v0, e1, e2 })
    }

    /// Hit distance in `(0, t_max]`, or infinity.
    #[inline(always)]
    pub fn hit_t(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> f32 {
        if self.is_sphere() {
            return self.sphere_t(origin, direction, t_max);
        }
        let (v0, e1, e2) = self.triangle();
        // As `TriangleGeom::normal_unnormalized`, so the same bits.
        let ng = e1.cross(e2);
        let c = v0 - origin;
        let det = ng.dot(direction);
        let inv_det = 1.0 / det;
        let t = ng.dot(c) * inv_det;
        if !(t > 0.0 && t <= t_max) {
            return f32::INFINITY;
        }
        let r = direction.cross(c);
        let u = -r.dot(e2) * inv_det;
        let v = r.dot(e1) * inv_det;
        // The six conditions in two vector compares and one branch (`det != 0` as
        // `|det| > 0`: a NaN determinant fails `t > 0` in both forms).
        let within = Vec4::new(0.0, 0.0, u + v, t).cmple(Vec4::new(u, v, 1.0, t_max));
        let positive = Vec4::ZERO.cmplt(Vec4::new(t, det.abs(), 1.0, 1.0));
        let hit = (within & positive).all();
        if hit { t } else { f32::INFINITY }
    }

    #[cold]
    #[inline(never)]
    fn sphere_t(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> f32 {
        intersect_sphere(&self.sphere(), origin, direction, 0.0, t_max).unwrap_or(f32::INFINITY)
    }

    /// The sphere of a sphere record.
    #[inline(always)]
    fn sphere(&self) -> SphereGeom {
        SphereGeom {
            center: Vec3A::from_vec4(self.first()),
            radius: self.edges[0],
        }
    }
}

/// The closest primitive of the leaf `prims[first..first + count]` hit within `(0, t_max)`:
/// its slot and distance, or `(u32::MAX, t_max)`. Ties go to the earlier slot, as when the
/// primitives are tested one by one in slot order. Leaves of two to four triangles are
/// tested at once, four lanes wide (lanes past the leaf repeat its last triangle).
#[inline(always)]
pub fn closest_in_leaf(
    prims: &[LeafPrim],
    first: u32,
    count: u32,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> (u32, f32) {
    if count == 1 {
        let t = prims[first as usize].hit_t(origin, direction, t_max);
        // Selects rather than a branch: whether a candidate is closer is a coin flip.
        return if t < t_max {
            (first, t)
        } else {
            (u32::MAX, t_max)
        };
    }
    let last = first + count - 1;
    let lane = |k: u32| &prims[(first + k).min(last) as usize];
    match closest_of_four(
        [lane(0), lane(1), lane(2), lane(3)],
        origin,
        direction,
        t_max,
    ) {
        Some((lane, t)) if lane < 4 => (first + lane, t),
        Some(_) => (u32::MAX, t_max),
        None => one_by_one(prims, first, count, origin, direction, t_max),
    }
}

/// [`closest_in_leaf`] testing the primitives one at a time (leaves with a sphere).
#[cold]
#[inline(never)]
fn one_by_one(
    prims: &[LeafPrim],
    first: u32,
    count: u32,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> (u32, f32) {
    let mut best = (u32::MAX, t_max);
    for slot in first..first + count {
        let t = prims[slot as usize].hit_t(origin, direction, best.1);
        if t < best.1 {
            best = (slot, t);
        }
    }
    best
}

/// [`LeafPrim::hit_t`] on four triangles at once (the same arithmetic in the same order, so
/// the same distances): the lowest lane among those at the smallest distance below `t_max`,
/// with that distance; lane 32 when nothing is hit. `None` when a record is a sphere (left
/// to the one-by-one test).
#[inline(always)]
fn closest_of_four(
    quad: [&LeafPrim; 4],
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> Option<(u32, f32)> {
    if quad.iter().any(|p| p.is_sphere()) {
        return None;
    }
    let lanes = TriangleLanes::new(quad);
    Some(lanes.closest(BVec4A::splat(true), origin, direction, t_max))
}

/// Four triangles as structure-of-arrays lanes: each vector by axis, lane `k` = triangle `k`,
/// with their geometric normals. All-zero lanes (no triangle) have a zero determinant, which
/// no ray hits.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct TriangleLanes {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    ng: [Vec4; 3],
}

impl TriangleLanes {
    /// The triangle records `quad` in lanes 0 to 3.
    #[inline(always)]
    fn new(quad: [&LeafPrim; 4]) -> Self {
        // Each four-float load's 4 x 4 block transposed: one of its floats over the four
        // lanes per row (`e2` is the tail load's last three rows).
        let [v0x, v0y, v0z, _] = transpose4(quad.map(LeafPrim::first));
        let [e1x, e1y, e1z, _] = transpose4(quad.map(LeafPrim::edges_head));
        let [_, e2x, e2y, e2z] = transpose4(quad.map(LeafPrim::edges_tail));
        let (e1, e2) = ([e1x, e1y, e1z], [e2x, e2y, e2z]);
        // `e1 x e2` lane by lane, as glam's `cross` forms each component
        // (`a.y b.z - b.y a.z`), so the same bits as `LeafPrim::hit_t`'s.
        let ng = [
            e1[1] * e2[2] - e2[1] * e1[2],
            e1[2] * e2[0] - e2[2] * e1[0],
            e1[0] * e2[1] - e2[0] * e1[1],
        ];
        TriangleLanes {
            v0: [v0x, v0y, v0z],
            e1,
            e2,
            ng,
        }
    }

    /// The closest of the lanes in `lanes` hit within `(0, t_max]`, as in [`closest_of_four`].
    #[inline(always)]
    fn closest(&self, lanes: BVec4A, origin: Vec3A, direction: Vec3A, t_max: f32) -> (u32, f32) {
        let t = self.hit_distances(lanes, origin, direction, t_max);
        let nearest = t.min_element();
        // No lane below `t_max`: an empty mask, whose trailing zeros (32) say so.
        let closer = t.cmpeq(Vec4::splat(nearest)) & t.cmplt(Vec4::splat(t_max));
        (closer.bitmask().trailing_zeros(), nearest)
    }

    /// The hit distance of each lane in `lanes` within `(0, t_max]`; infinity elsewhere.
    #[inline(always)]
    fn hit_distances(&self, lanes: BVec4A, origin: Vec3A, direction: Vec3A, t_max: f32) -> Vec4 {
        let ([v0x, v0y, v0z], [e1x, e1y, e1z], [e2x, e2y, e2z], [ngx, ngy, ngz]) =
            (self.v0, self.e1, self.e2, self.ng);
        let (dx, dy, dz) = (
            Vec4::splat(direction.x),
            Vec4::splat(direction.y),
            Vec4::splat(direction.z),
        );
        let (cx, cy, cz) = (
            v0x - Vec4::splat(origin.x),
            v0y - Vec4::splat(origin.y),
            v0z - Vec4::splat(origin.z),
        );
        // Dot products as `(x + y) + z` and cross products as `a.y b.z - b.y a.z`, like glam's.
        let det = ngx * dx + ngy * dy + ngz * dz;
        let inv_det = Vec4::ONE / det;
        let t = (ngx * cx + ngy * cy + ngz * cz) * inv_det;
        let (rx, ry, rz) = (dy * cz - cy * dz, dz * cx - cz * dx, dx * cy - cx * dy);
        let u = -(rx * e2x + ry * e2y + rz * e2z) * inv_det;
        let v = (rx * e1x + ry * e1y + rz * e1z) * inv_det;
        let hit = lanes
            & det.abs().cmpgt(Vec4::ZERO)
            & t.cmpgt(Vec4::ZERO)
            & t.cmple(Vec4::splat(t_max))
            & u.cmpge(Vec4::ZERO)
            & v.cmpge(Vec4::ZERO)
            & (u + v).cmple(Vec4::ONE);
        Vec4::select(hit, t, Vec4::INFINITY)
    }
}

/// Per node of a tree whose leaves hold one primitive each (small scenes): the triangles of
/// its leaf lanes, transposed for one four-wide test, and which lanes they are. A node's
/// leaves are then tested together instead of one by one, each test a branch that
/// incoherent rays mispredict.
#[derive(Clone, Copy, Debug)]
pub struct NodeTriangles {
    lanes: TriangleLanes,
    /// Bit `k` set when lane `k` is a leaf holding one triangle.
    mask: u32,
}

/// The [`NodeTriangles`] of every node of `bvh`, over the records `prims` in slot order; empty
/// when some leaf holds more than one primitive (those are tested four wide by
/// [`closest_in_leaf`]).
pub fn node_triangles(prims: &[LeafPrim], bvh: &Bvh4) -> Vec<NodeTriangles> {
    if bvh.nodes.iter().any(|n| n.count.iter().any(|&c| c > 1)) {
        return Vec::new();
    }
    let node_triangles = |node: &Node4| {
        let triangle = |k: usize| {
            let prim = (node.count[k] == 1).then(|| &prims[node.child[k] as usize]);
            prim.filter(|p| !p.is_sphere())
        };
        let quad = [0, 1, 2, 3].map(triangle);
        NodeTriangles {
            lanes: TriangleLanes::new(quad.map(|p| p.unwrap_or(&LeafPrim::NONE))),
            mask: (0..4).fold(0, |mask, k| mask | u32::from(quad[k].is_some()) << k),
        }
    };
    bvh.nodes.iter().map(node_triangles).collect()
}

/// The closest primitive, hit within `(0, t_max)`, of the leaf lanes `lanes` of a node whose
/// leaves hold one primitive each (`quad` is its [`NodeTriangles`]): its slot and distance,
/// or `(u32::MAX, t_max)`. The triangles in one four-wide test, other primitives (spheres)
/// one by one.
#[inline(always)]
pub fn closest_in_node(
    prims: &[LeafPrim],
    quad: &NodeTriangles,
    node: &Node4,
    lanes: u32,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> (u32, f32) {
    let triangles = lanes & quad.mask;
    let selected = BVec4A::new(
        triangles & 1 != 0,
        triangles & 2 != 0,
        triangles & 4 != 0,
        triangles & 8 != 0,
    );
    let (lane, t) = quad.lanes.closest(selected, origin, direction, t_max);
    // Selects rather than a branch: whether a lane was hit is a coin flip.
    let mut best = if lane < 4 {
        (node.child[lane as usize], t)
    } else {
        (u32::MAX, t_max)
    };
    let mut others = lanes & !quad.mask;
    while others != 0 {
        let k = others.trailing_zeros() as usize;
        others &= others - 1;
        let t = prims[node.child[k] as usize].hit_t(origin, direction, best.1);
        if t < best.1 {
            best = (node.child[k], t);
        }
    }
    best
}

/// Scenes of at most this many primitives skip the tree in the closest-hit query (see
/// [`FlatPrimitives`]). Measured render times against the tree's: -8% in the hexagonal room (28
/// primitives), -2% with 40 (the room and a cube), +3% with 64 (the room and three cubes).
pub const MAX_FLAT_PRIMITIVES: usize = 48;

/// Every primitive of a scene too small for a tree to pay, for the closest-hit query: the
/// triangles transposed four to a group, and the spheres. All are tested, without the box
/// tests and the branches per node that incoherent rays mispredict.
#[derive(Clone, Debug)]
pub struct FlatPrimitives {
    /// Four triangles and their slots (as floats, exact below 2^24, so that they ride in the
    /// same selects as the distances); lanes past the last triangle hold [`LeafPrim::NONE`],
    /// which no ray hits.
    triangles: Vec<(TriangleLanes, Vec4)>,
    /// The spheres and their slots.
    spheres: Vec<(SphereGeom, u32)>,
}

impl FlatPrimitives {
    /// The primitives `prims` (in slot order), or `None` when there are more than
    /// [`MAX_FLAT_PRIMITIVES`].
    pub fn new(prims: &[LeafPrim]) -> Option<Self> {
        if prims.len() > MAX_FLAT_PRIMITIVES {
            return None;
        }
        let (spheres, triangles): (Vec<u32>, Vec<u32>) =
            (0..prims.len() as u32).partition(|&slot| prims[slot as usize].is_sphere());
        let group = |slots: &[u32]| {
            let slot = |k: usize| slots.get(k).map_or(f32::INFINITY, |&s| s as f32);
            let prim = |k: usize| {
                slots
                    .get(k)
                    .map_or(&LeafPrim::NONE, |&s| &prims[s as usize])
            };
            (
                TriangleLanes::new([prim(0), prim(1), prim(2), prim(3)]),
                Vec4::new(slot(0), slot(1), slot(2), slot(3)),
            )
        };
        Some(FlatPrimitives {
            triangles: triangles.chunks(4).map(group).collect(),
            spheres: spheres
                .into_iter()
                .map(|slot| (prims[slot as usize].sphere(), slot))
                .collect(),
        })
    }

    /// The closest primitive hit within `(0, t_max)`: its slot and distance. Of equally
    /// close primitives, the triangle of the lowest slot wins, and triangles win over spheres.
    #[inline(always)]
    pub fn closest_hit(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> Option<(u32, f32)> {
        // Per lane, the nearest distance so far and its slot: a strict `<` keeps the earlier
        // (lower) slot of equally close triangles, and the lowest slot of the lanes at the
        // nearest distance wins, as if the triangles were tested one by one in slot order.
        let (mut nearest, mut nearest_slot) = (Vec4::INFINITY, Vec4::INFINITY);
        for (lanes, slots) in &self.triangles {
            let t = lanes.hit_distances(BVec4A::splat(true), origin, direction, t_max);
            let closer = t.cmplt(nearest);
            nearest = Vec4::select(closer, t, nearest);
            nearest_slot = Vec4::select(closer, *slots, nearest_slot);
        }
        let t = nearest.min_element();
        let mut best = (u32::MAX, t_max);
        if t < t_max {
            let at_nearest = nearest.cmpeq(Vec4::splat(t));
            let slot = Vec4::select(at_nearest, nearest_slot, Vec4::INFINITY).min_element();
            best = (slot as u32, t);
        }
        // Inlined (unlike the leaf test's sphere test): every ray meets every sphere here.
        for (sphere, slot) in &self.spheres {
            if let Some(t) = intersect_sphere(sphere, origin, direction, 0.0, best.1) {
                best = (*slot, t);
            }
        }
        (best.0 != u32::MAX).then_some(best)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle::TriangleGeom;
    use crate::math::rng::{path_key, uniform};

    /// The record gives the same distance as the shape's own test, bit for bit, on random
    /// rays (many of them near edges, parallel or ending near the surface).
    #[test]
    fn records_agree_with_the_shape_tests_exactly() {
        let mut hits = 0;
        for i in 0..20_000 {
            let u = |d: u32| uniform(path_key(11, i, 0), 0, d);
            let p = |d: u32| Vec3A::new(u(d), u(d + 1), u(d + 2)) * 2.0 - 1.0;
            let shape = if i % 5 == 0 {
                Shape::Sphere(SphereGeom {
                    center: p(0),
                    radius: 0.1 + u(3),
                })
            } else if i % 5 == 1 {
                // Degenerate: all three vertices on a line.
                let a = p(0);
                Shape::Triangle(TriangleGeom::new(a, a + p(3), a + 2.0 * p(3)))
            } else {
                Shape::Triangle(TriangleGeom::new(p(0), p(3), p(6)))
            };
            let origin = p(9) * 2.0;
            // Aimed at a point near the shape (inside or just outside a triangle's edges, or
            // of a sphere's outline), so that about half the rays hit.
            let target = match shape {
                Shape::Triangle(t) => {
                    t.v0 + (1.4 * u(12) - 0.2) * t.e1 + (1.4 * u(13) - 0.2) * t.e2
                }
                Shape::Sphere(s) => s.center + 1.2 * s.radius * (p(12) - 0.5),
            };
            let direction = if i % 7 == 0 {
                Vec3A::new(0.0, 0.0, 1.0) // axis-parallel
            } else {
                (target - origin).normalize_or(Vec3A::X)
            };
            let t_max = if i % 2 == 0 {
                f32::INFINITY
            } else {
                3.0 * u(15)
            };
            let expected = shape.intersect_t(origin, direction, t_max);
            let got = LeafPrim::new(&shape).hit_t(origin, direction, t_max);
            assert_eq!(got.to_bits(), expected.to_bits(), "case {i}: {shape:?}");
            hits += (got < f32::INFINITY) as u32;
        }
        assert!(hits > 2000, "enough cases hit: {hits}");
    }

    /// Leaves of one to four primitives (some with a sphere, some with two copies of one
    /// triangle, so that distances tie): the four-wide test finds the same slot and distance
    /// as testing the primitives one by one in slot order.
    #[test]
    fn leaves_agree_with_one_by_one_tests() {
        let mut hits = 0;
        for i in 0..20_000 {
            let u = |d: u32| uniform(path_key(12, i, 0), 0, d);
            let p = |d: u32| Vec3A::new(u(d), u(d + 1), u(d + 2)) * 2.0 - 1.0;
            let count = 1 + i % 4;
            let mut shapes: Vec<Shape> = (0..count)
                .map(|k| {
                    let q = |d: u32| p(d + 20 * k);
                    Shape::Triangle(TriangleGeom::new(q(0), q(3), q(6)))
                })
                .collect();
            if i % 9 == 0 {
                shapes[(i / 9 % count) as usize] = Shape::Sphere(SphereGeom {
                    center: p(90),
                    radius: 0.5,
                });
            }
            if i % 5 == 0 && count >= 2 {
                shapes[count as usize - 1] = shapes[0];
            }
            // Padding records around the leaf, which must not be read as part of it.
            let far = Shape::Triangle(TriangleGeom::new(
                Vec3A::splat(-0.1),
                Vec3A::new(0.1, 0.0, 0.0),
                Vec3A::new(0.0, 0.1, 0.0),
            ));
            let mut prims = vec![LeafPrim::new(&far); 3];
            prims.extend(shapes.iter().map(LeafPrim::new));
            prims.push(LeafPrim::new(&far));
            let origin = p(100) * 3.0;
            let direction = (p(103) * 0.5 - origin).normalize();
            let t_max = if i % 3 == 0 {
                2.0 * u(106)
            } else {
                f32::INFINITY
            };
            let mut expected = (u32::MAX, t_max);
            for slot in 3..3 + count {
                let t = prims[slot as usize].hit_t(origin, direction, expected.1);
                if t < expected.1 {
                    expected = (slot, t);
                }
            }
            let got = closest_in_leaf(&prims, 3, count, origin, direction, t_max);
            assert_eq!(got.0, expected.0, "case {i}");
            assert_eq!(got.1.to_bits(), expected.1.to_bits(), "case {i}");
            hits += (got.0 != u32::MAX) as u32;
        }
        assert!(hits > 3000, "enough leaves are hit: {hits}");
    }

    #[test]
    fn records_are_ten_floats() {
        assert_eq!(std::mem::size_of::<LeafPrim>(), 40);
    }
}
