//! Shadow-ray packets: up to [`PACKET_SIZE`] segments from one origin walk the tree
//! together, with culling tests that skip subtrees and triangles for all of them at once.

use super::build::{Bvh4, Node4};
use super::traverse::{BOX_FAR_SCALE, BoxRay, TraversalStack, safe_inverse3};
use crate::geometry::triangle::{OriginTerms, TriangleGeom};
use crate::math::{Vec3A, Vec4};
use std::cell::Cell;

/// Trees with at least this many nodes confirm a packet's node tests ray by ray (see
/// [`Bvh4::any_hit_packet`]).
pub(super) const CONFIRMED_PACKET_NODES: usize = 1024;

/// Shadow-ray packets hold at most this many rays.
pub const PACKET_SIZE: usize = 16;

/// Up to [`PACKET_SIZE`] segments from one origin (`origin + t directions[k]`, `t` in
/// `[0, t_max[k]]`), with the bounds that let whole subtrees and primitives be skipped for
/// all of them at once.
pub struct Packet<'a> {
    /// The shared origin.
    pub origin: Vec3A,
    /// Unit directions.
    pub directions: &'a [Vec3A],
    /// Lengths of the segments.
    pub t_max: &'a [f32],
    /// Box of the segments (their origin and far ends).
    segments_min: Vec3A,
    segments_max: Vec3A,
    /// Centre of the box of far ends, relative to the origin, and its half extent.
    ends_center: Vec3A,
    ends_half: Vec3A,
    /// Smallest and largest direction component per axis.
    directions_min: Vec3A,
    directions_max: Vec3A,
    /// The longest segment's length.
    longest: f32,
}

impl<'a> Packet<'a> {
    /// The packet of the given segments.
    #[inline]
    pub fn new(origin: Vec3A, directions: &'a [Vec3A], t_max: &'a [f32]) -> Self {
        debug_assert!(directions.len() <= PACKET_SIZE && t_max.len() == directions.len());
        let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        let (mut directions_min, mut directions_max) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
        let mut longest = 0.0;
        for (&d, &t) in directions.iter().zip(t_max) {
            let end = t * d; // relative to the origin
            (lo, hi) = (lo.min(end), hi.max(end));
            (directions_min, directions_max) = (directions_min.min(d), directions_max.max(d));
            // A plain compare (`maxss`): `f32::max` also orders NaNs, which lengths never are,
            // and its longer code sat on the loop's critical path.
            longest = if t > longest { t } else { longest };
        }
        Packet {
            longest,
            directions_min,
            directions_max,
            origin,
            directions,
            t_max,
            segments_min: origin + lo.min(Vec3A::ZERO),
            segments_max: origin + hi.max(Vec3A::ZERO),
            ends_center: 0.5 * (lo + hi),
            ends_half: 0.5 * (hi - lo),
        }
    }

    /// Whether no segment can cross the plane through `origin + to_plane` with normal
    /// `normal` (any length): the origin and the whole box of far ends lie on one side of it,
    /// by more than a bound on the rounding of the test. Conservative: `false` when unsure
    /// (and for infinite segments).
    #[inline(always)]
    pub fn stays_on_one_side(&self, normal: Vec3A, to_plane: Vec3A) -> bool {
        let at_origin = -normal.dot(to_plane);
        let at_ends = at_origin + normal.dot(self.ends_center);
        let spread = normal.abs().dot(self.ends_half);
        let scale = normal
            .abs()
            .dot(to_plane.abs() + self.ends_center.abs() + self.ends_half);
        let margin = PLANE_TEST_TOLERANCE * scale;
        (at_origin > margin && at_ends - spread > margin)
            || (at_origin < -margin && at_ends + spread < -margin)
    }

    /// Whether every segment passes beside the triangle `tri` (`terms` from the packet's
    /// origin): all far ends lie, by more than a bound on the rounding of the tests, outside
    /// one of the three planes through the origin and an edge, where no ray from the origin
    /// meets the triangle. Conservative: `false` when unsure.
    ///
    /// The planes' normals are those of the ray test's barycentrics: for a ray `d` that
    /// reaches the plane (`t > 0`), `u`, `v` and `1 - u - v` have the signs of `d . ca`,
    /// `d . ab` and `d . bc` times that of `ng . c`. Shadow packets from beside a triangle
    /// pass the box tests and the plane test, and this one test spares their ray-by-ray
    /// tests.
    #[inline(always)]
    pub fn passes_beside(&self, tri: &TriangleGeom, terms: &OriginTerms) -> bool {
        let (a, e1, e2) = (terms.c, tri.e1, tri.e2);
        let ab = a.cross(e1);
        let ca = e2.cross(a);
        let bc = terms.ng - ab - ca;
        // Bounds on each normal's components (and so on their rounding): the sums of the
        // products' magnitudes.
        let abs_cross = |p: Vec3A, q: Vec3A| {
            let (p, q) = (p.abs(), q.abs());
            Vec3A::new(
                p.y * q.z + p.z * q.y,
                p.z * q.x + p.x * q.z,
                p.x * q.y + p.y * q.x,
            )
        };
        let (ab_bound, ca_bound) = (abs_cross(a, e1), abs_cross(e2, a));
        let bc_bound = abs_cross(e1, e2) + ab_bound + ca_bound;
        let reach = self.ends_center.abs() + self.ends_half;
        let side = if terms.ng_dot_c > 0.0 { 1.0 } else { -1.0 };
        let outside = |normal: Vec3A, bound: Vec3A| {
            // The largest value of `side * normal . end` over the box of far ends.
            let most = side * normal.dot(self.ends_center) + normal.abs().dot(self.ends_half);
            most < -PLANE_TEST_TOLERANCE * bound.dot(reach)
        };
        // No side at all when the origin lies in the triangle's plane: never cull.
        terms.ng_dot_c != 0.0
            && (outside(ab, ab_bound) || outside(ca, ca_bound) || outside(bc, bc_bound))
    }
}

/// Relative rounding bound of [`Packet::stays_on_one_side`]: a few dozen ulps of the sums
/// it forms, far below the gaps it is meant for (shadow rays stop 1e-4 short of the light).
const PLANE_TEST_TOLERANCE: f32 = 64.0 * f32::EPSILON;

impl Bvh4 {
    /// Occlusion of a packet: bit `k` of the result is set when segment `k` is blocked.
    /// `intersect(slot, rays)` returns which of the rays in the bit set `rays` primitive
    /// `slot` blocks.
    ///
    /// Nodes are tested once for the whole packet: against the box of all segments, and with
    /// interval arithmetic: on each axis where all directions have the same sign, the
    /// packet's inverse directions span `[lo, hi]`, which bounds every ray's slab distances
    /// from below (entry) and above (exit). The tests are conservative, and leaves test every
    /// ray exactly, so the answer is the same as tracing the rays one by one. Packets spread
    /// over more than one axis sign are traced one ray at a time.
    pub fn any_hit_packet(
        &self,
        stack: &mut TraversalStack,
        packet: &Packet,
        mut intersect: impl FnMut(u32, u32) -> u32,
    ) -> u32 {
        let Packet {
            origin,
            directions,
            t_max,
            ..
        } = *packet;
        let n = directions.len();
        if self.nodes.is_empty() || n == 0 {
            return 0;
        }
        let all = if n == 32 { u32::MAX } else { (1u32 << n) - 1 };
        // Which axes keep one sign, and the interval of inverse directions on them: on
        // either side of zero `safe_inverse3` never increases, so the interval's ends are the
        // inverses of the extreme components (exactly what inverting every ray would give).
        let (d_min, d_max) = (packet.directions_min, packet.directions_max);
        let positive = d_min.cmpge(Vec3A::ZERO).bitmask();
        let negative = d_max.cmplt(Vec3A::ZERO).bitmask();
        let (lo, hi) = (safe_inverse3(d_max), safe_inverse3(d_min));
        let mut axes = [(0usize, 0usize, Vec4::ZERO, Vec4::ZERO, Vec4::ZERO); 3];
        let mut constrained = 0;
        // Branch-free (the signs vary from packet to packet): every axis is written at the
        // end of the list, which grows only over the axes that keep one sign.
        for axis in 0..3 {
            let is_positive = (positive >> axis & 1) as usize;
            let keeps_sign = ((positive | negative) >> axis & 1) as usize;
            axes[constrained] = (
                axis + 3 * (1 - is_positive),
                axis + 3 * is_positive,
                Vec4::splat(lo[axis]),
                Vec4::splat(hi[axis]),
                Vec4::splat(origin[axis]),
            );
            constrained += keeps_sign;
        }
        if constrained < 2 {
            let mut occluded = 0;
            for k in 0..n {
                if self.any_hit(stack, origin, directions[k], t_max[k], |slot, _| {
                    if intersect(slot, 1 << k) != 0 {
                        0.0
                    } else {
                        f32::INFINITY
                    }
                }) {
                    occluded |= 1 << k;
                }
            }
            return occluded;
        }
        let axes = &axes[..constrained];
        let packet_t_max = Vec4::splat(packet.longest * BOX_FAR_SCALE);
        let box_min = packet.segments_min.to_array().map(Vec4::splat);
        let box_max = packet.segments_max.to_array().map(Vec4::splat);
        let occluded = Cell::new(0u32);
        // The rays prepared once for the ray-by-ray confirmation below. Small trees skip it:
        // there the subtrees it could cut are small too (in the hexagonal room it cost 5% more
        // instructions per path and saved nothing).
        let box_rays: Option<[BoxRay; PACKET_SIZE]> = (self.nodes.len() >= CONFIRMED_PACKET_NODES)
            .then(|| std::array::from_fn(|k| BoxRay::new(origin, directions[k.min(n - 1)])));
        let enter = |node: &Node4| {
            let (mut t_near, mut t_far) = (Vec4::ZERO, packet_t_max);
            for &(near, far, lo, hi, o) in axes {
                let (dn, df) = (node.bounds[near] - o, node.bounds[far] - o);
                t_near = t_near.max((dn * lo).min(dn * hi));
                t_far = t_far.min((df * lo).max(df * hi));
            }
            let mut overlap = t_near.cmple(t_far * BOX_FAR_SCALE);
            for axis in 0..3 {
                overlap &= node.bounds[axis].cmple(box_max[axis])
                    & node.bounds[axis + 3].cmpge(box_min[axis]);
            }
            // The packet bounds are loose when its rays spread wide (a large light seen from
            // nearby), and such packets walked, and tested, much of a large mesh (the stage
            // benchmark's heavy scene: 21.7 s -> 0.31 s). So a child passes only if one of
            // the rays still open enters it, tested ray by ray until every candidate is
            // confirmed; in a coherent packet the first ray usually confirms them all.
            let candidates = overlap.bitmask();
            let Some(box_rays) = &box_rays else {
                return candidates;
            };
            let mut entered = 0;
            let mut open = all & !occluded.get();
            while candidates & !entered != 0 && open != 0 {
                let k = open.trailing_zeros() as usize;
                open &= open - 1;
                entered |= box_rays[k].test(node, t_max[k]).1;
            }
            entered & candidates
        };
        self.walk_until(stack, enter, |slot| {
            let blocked = occluded.get() | intersect(slot, all & !occluded.get());
            occluded.set(blocked);
            blocked == all
        });
        occluded.get()
    }
}
