//! Single-ray walks of the 4-wide BVH: closest hit (near-to-far, branch-light, with a
//! fixed-size stack) and any hit (depth-first, stops at the first hit), and the shared
//! ray/box test.

use super::build::{Bvh4, MAX_DEPTH, Node4};
use crate::math::{Vec3A, Vec4};

/// Widens the far distance of box tests so that rounding never drops a box the ray touches
/// (pbrt's 1 + 2 gamma(3)).
pub(super) const BOX_FAR_SCALE: f32 = 1.0 + 2.0 * 3.0 * f32::EPSILON;

/// Stack entries a traversal needs for a tree of depth `depth`: each level adds at most three
/// (four children pushed, one popped), and the closest-hit traversal always stores a node's
/// four keys, entered or not.
const fn stack_len(depth: usize) -> usize {
    3 * depth + 5
}

/// The stack of every traversal (closest hit, occlusion, packets), kept by the caller and
/// reused ray after ray: a fresh zeroed stack per ray cost about 6% of a closest-hit ray's
/// instructions in the hexagonal room. Deep enough for any tree the build accepts ([`MAX_DEPTH`]).
pub struct TraversalStack([u64; stack_len(MAX_DEPTH)]);

impl Default for TraversalStack {
    fn default() -> Self {
        TraversalStack([0; stack_len(MAX_DEPTH)])
    }
}

/// The closest-hit stack entry of `node` entered at distance `t` (>= 0): the distance's bits
/// (ordered like the distances; the sign of -0.0 dropped) above the complemented node index.
#[inline(always)]
fn node_key(t: f32, node: u32) -> u64 {
    u64::from(t.to_bits() & 0x7fff_ffff) << 32 | u64::from(!node)
}

/// Number of set bits of each 4-bit mask.
const LANE_COUNT: [u8; 16] = [0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4];

/// Sorts four keys, largest first, with a branch-free network of five compare-exchanges.
#[inline(always)]
fn sort4_descending(keys: &mut [u64; 4]) {
    let mut exchange = |i: usize, j: usize| {
        let (a, b) = (keys[i], keys[j]);
        (keys[i], keys[j]) = (a.max(b), a.min(b));
    };
    exchange(0, 1);
    exchange(2, 3);
    exchange(0, 2);
    exchange(1, 3);
    exchange(1, 2);
}

/// A ray prepared for box tests.
pub(super) struct BoxRay {
    origin: [Vec4; 3],
    pub(super) inv_direction: [Vec4; 3],
    /// For each axis, which of `bounds` holds the near plane (min for positive directions).
    pub(super) near: [usize; 3],
}

impl BoxRay {
    #[inline(always)]
    pub(super) fn new(origin: Vec3A, direction: Vec3A) -> Self {
        // Branch-free: a mispredicted sign test per axis cost more than these few lane ops.
        let inv = safe_inverse3(direction);
        let negative = direction.cmplt(Vec3A::ZERO).bitmask() as usize;
        BoxRay {
            origin: [
                Vec4::splat(origin.x),
                Vec4::splat(origin.y),
                Vec4::splat(origin.z),
            ],
            inv_direction: [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
            near: [
                3 * (negative & 1),
                1 + 3 * (negative >> 1 & 1),
                2 + 3 * (negative >> 2 & 1),
            ],
        }
    }

    /// Entry distances of the four children and the mask of those entered within `(0, t_max]`.
    #[inline(always)]
    pub(super) fn test(&self, node: &Node4, t_max: f32) -> (Vec4, u32) {
        let mut t_near = Vec4::ZERO;
        let mut t_far = Vec4::splat(t_max);
        for axis in 0..3 {
            let near = self.near[axis];
            let far = if near >= 3 { near - 3 } else { near + 3 };
            t_near = t_near.max((node.bounds[near] - self.origin[axis]) * self.inv_direction[axis]);
            t_far = t_far.min((node.bounds[far] - self.origin[axis]) * self.inv_direction[axis]);
        }
        (t_near, t_near.cmple(t_far * BOX_FAR_SCALE).bitmask())
    }
}

impl Bvh4 {
    /// Closest hit along `origin + t direction`, `t` in `[0, t_max]`. `intersect(slot, t_max)`
    /// returns the hit distance of a primitive or infinity. Returns the slot and distance.
    /// (Tests only: the renderer reads leaves through [`Self::closest_hit_by_leaf`].)
    #[cfg(test)]
    #[inline(always)]
    pub fn closest_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
        mut intersect: impl FnMut(u32, f32) -> f32,
    ) -> Option<(u32, f32)> {
        self.closest_hit_by_leaf(stack, origin, direction, t_max, |first, count, t_max| {
            let mut best = (u32::MAX, t_max);
            for slot in first..first + count {
                let t = intersect(slot, best.1);
                if t < best.1 {
                    best = (slot, t);
                }
            }
            best
        })
    }

    /// [`Self::closest_hit`] with a test per leaf: `leaf(first, count, t_max)` returns the
    /// closest of the primitives in slots `first..first + count` hit before `t_max`, as its
    /// slot and distance, or `(u32::MAX, t_max)`.
    #[inline(always)]
    pub fn closest_hit_by_leaf(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
        mut leaf: impl FnMut(u32, u32, f32) -> (u32, f32),
    ) -> Option<(u32, f32)> {
        let leaves = |_: usize, node: &Node4, mut lanes: u32, mut t_max: f32| {
            let mut best_slot = u32::MAX;
            while lanes != 0 {
                let k = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                let (slot, t) = leaf(node.child[k], node.count[k], t_max);
                // Selects rather than a branch: whether a leaf holds a closer hit is a coin flip.
                best_slot = if slot != u32::MAX { slot } else { best_slot };
                t_max = t;
            }
            (best_slot, t_max)
        };
        self.closest_hit_by_node(stack, origin, direction, t_max, leaves)
    }

    /// [`Self::closest_hit_by_leaf`] with one test per node: `leaves(index, node, lanes,
    /// t_max)` returns the closest of the primitives in the leaf lanes `lanes` (bit `k` for
    /// lane `k`) of node `index` hit before `t_max`, as its slot and distance, or
    /// `(u32::MAX, t_max)`.
    ///
    /// Near-to-far traversal with few branches, because incoherent (bounce) rays mispredict
    /// most data-dependent ones: every entered inner child becomes one `u64` key (its entry
    /// distance above its node index), a sorting network orders the four keys (lanes not
    /// entered are 0 and sort last), all four are stored above the stack top, and the top
    /// moves up by the number entered, so the nearest child is popped next. The node index
    /// is stored complemented so that children at equal distance are visited in the same
    /// order as by a stable sort (the later lane first).
    #[inline(always)]
    pub fn closest_hit_by_node(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        mut t_max: f32,
        mut leaves: impl FnMut(usize, &Node4, u32, f32) -> (u32, f32),
    ) -> Option<(u32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let stack = &mut stack.0;
        let ray = BoxRay::new(origin, direction);
        stack[0] = node_key(0.0, 0);
        let mut top = 1;
        let mut best_slot = u32::MAX;
        while top > 0 {
            top -= 1;
            let key = stack[top];
            if f32::from_bits((key >> 32) as u32) > t_max {
                continue; // a closer hit was found after this node was pushed
            }
            let index = !(key as u32) as usize;
            let node = &self.nodes[index];
            let (t_near, entered) = ray.test(node, t_max);
            let t_near = t_near.to_array();
            let leaf_lanes = u32::from(self.leaf_lanes[index]);
            let entered_leaves = entered & leaf_lanes;
            if entered_leaves != 0 {
                let (slot, t) = leaves(index, node, entered_leaves, t_max);
                best_slot = if slot != u32::MAX { slot } else { best_slot };
                t_max = t;
            }
            let inner = entered & !leaf_lanes;
            if inner & inner.wrapping_sub(1) == 0 {
                // At most one inner child entered (most nodes): no sort; its key is stored
                // either way and kept if it was entered.
                let k = (inner.trailing_zeros() & 3) as usize;
                stack[top] = node_key(t_near[k], node.child[k]);
                top += inner as usize >> k;
                continue;
            }
            let mut keys: [u64; 4] = std::array::from_fn(|k| {
                let key = node_key(t_near[k], node.child[k]);
                if inner & (1 << k) != 0 { key } else { 0 }
            });
            sort4_descending(&mut keys);
            stack[top..top + 4].copy_from_slice(&keys);
            top += LANE_COUNT[inner as usize] as usize; // no popcnt in baseline x86-64
        }
        (best_slot != u32::MAX).then_some((best_slot, t_max))
    }

    /// Whether any primitive is hit within `[0, t_max]`; stops at the first one found.
    /// `intersect` returns infinity for a miss.
    #[inline(always)]
    pub fn any_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
        mut intersect: impl FnMut(u32, f32) -> f32,
    ) -> bool {
        let ray = BoxRay::new(origin, direction);
        self.walk_until(
            stack,
            |node| ray.test(node, t_max).1,
            |slot| intersect(slot, t_max) < f32::INFINITY,
        )
    }

    /// Depth-first walk of every node whose lanes `enter(node)` selects, calling `leaf(slot)`
    /// on the primitives of entered leaves until it returns true. Returns whether it did.
    /// Shared by the single-ray and the packet any-hit queries.
    #[inline(always)]
    pub(super) fn walk_until(
        &self,
        stack: &mut TraversalStack,
        mut enter: impl FnMut(&Node4) -> u32,
        mut leaf: impl FnMut(u32) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let stack = &mut stack.0;
        stack[0] = 0;
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            let mut mask = enter(node);
            while mask != 0 {
                let k = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let count = node.count[k];
                if count == 0 {
                    stack[top] = u64::from(node.child[k]);
                    top += 1;
                    self.touch(node.child[k]);
                    continue;
                }
                for slot in node.child[k]..node.child[k] + count {
                    if leaf(slot) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Loads both cache lines of node `index` now, as a prefetch would (in safe code: the
    /// `black_box` keeps the load), so that the misses of the nodes a walk pushes overlap the
    /// work done before it pops them: single shadow rays in the 1.3M-triangle scene +10%
    /// (median of 16 alternating pairs, 12 of them faster); the renderer's packets and small
    /// trees, whose nodes stay in cache, within noise.
    #[inline(always)]
    fn touch(&self, index: u32) {
        let node = &self.nodes[index as usize];
        std::hint::black_box(node.bounds[0].x + node.bounds[5].w);
    }
}

/// `1 / v` per component, with a large finite stand-in (`±1 / EPSILON`) for `1 / 0` that keeps
/// `0 * inf` NaNs out of box tests. Its sign follows `x >= 0`, as the traversals' choice of
/// near planes does: `-0.0` counts as positive (taking its sign bit sent such rays' slabs the
/// wrong way round).
#[inline(always)]
pub(super) fn safe_inverse3(v: Vec3A) -> Vec3A {
    let tiny = v.abs().cmplt(Vec3A::splat(f32::EPSILON));
    let stand_in = Vec3A::select(
        v.cmpge(Vec3A::ZERO),
        Vec3A::splat(f32::EPSILON),
        Vec3A::splat(-f32::EPSILON),
    );
    Vec3A::select(tiny, stand_in, v).recip()
}
