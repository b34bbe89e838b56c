//! The one BVH over all primitives (triangles and analytic spheres together).
//!
//! obvhs builds a binary BVH (PLOC + reinsertion); we collapse it into a 4-wide BVH whose
//! nodes keep their four child boxes as structure-of-arrays `Vec4`s, so one ray tests all
//! four children with a handful of SIMD instructions, and we traverse it with our own loop
//! (closest hit: near-to-far with a fixed-size stack; occlusion: stops at the first hit).
//! Leaves point at contiguous runs of primitive slots: the scene stores primitives in BVH
//! order, so there is no index indirection at trace time.

use super::leaf_prims::{closest_in_leaf, closest_in_node};
use super::spheres::intersect_sphere;
use super::triangles::{OriginTerms, TriangleGeom, intersect_triangle_from};
use super::{FlatScene, Shape};
use crate::math::{Vec3A, Vec4};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use rayon::prelude::*;
use std::cell::Cell;

/// Largest supported depth of the 4-wide tree; [`TraversalStack`] is sized for it.
pub const MAX_DEPTH: usize = 64;
/// Primitives per leaf at most, in large scenes: fewer, fuller leaves mean fewer nodes and
/// cache misses (measured on the 1.3M-triangle ray sets: 10-20% faster than 1 or 2).
/// Large scenes are built with obvhs's `fast_build` preset (PLOC with a short search)
/// without its reinsertion pass: on the 1.3M-triangle ray sets it builds about 20% faster
/// than `medium_build` for the same ray rates within noise, while `fastest_build` loses ~30%
/// on primary rays; reinsertion cost 50-90 ms there for the same primitive tests per ray and
/// ray rates within noise (2% less inner-node surface area). Small scenes use
/// `very_slow_build` (reinsertion over every node): their build time is negligible, and in
/// the seed room it halves the nodes a shadow packet visits (8.6 -> 4.2) and cuts those of a
/// closest-hit ray from 7.2 to 4.7.
const MAX_LEAF_SIZE: u32 = 4;
/// Scenes with fewer primitives get one primitive per leaf: they are rooms of large,
/// overlapping triangles, where merging leaves makes every ray test most of the walls
/// (measured on the seed room: 14 primitive tests per shadow ray with 4, 0.8 with 1).
const SMALL_SCENE: usize = 4096;
/// Widens the far distance of box tests so that rounding never drops a box the ray touches
/// (pbrt's 1 + 2 gamma(3)).
const BOX_FAR_SCALE: f32 = 1.0 + 2.0 * 3.0 * f32::EPSILON;

/// Trees with at least this many nodes confirm a packet's node tests ray by ray (see
/// [`Bvh4::any_hit_packet`]).
const CONFIRMED_PACKET_NODES: usize = 1024;

/// Shadow-ray packets hold at most this many rays.
pub const PACKET_SIZE: usize = 16;

/// A node with up to four children.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Node4 {
    /// Child boxes by axis: `[min_x, min_y, min_z, max_x, max_y, max_z]`, lane `k` = child `k`.
    /// Unused lanes hold an empty box (min = +inf, max = -inf) that no ray enters.
    pub bounds: [Vec4; 6],
    /// Inner child: index of its node. Leaf child: first primitive slot.
    pub child: [u32; 4],
    /// 0 for an inner child (or an unused lane), else the number of primitives in the leaf.
    pub count: [u32; 4],
}

/// The 4-wide BVH. An empty scene has no nodes, and every ray misses.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    /// Nodes in depth-first order; the root is node 0.
    pub nodes: Vec<Node4>,
    /// Depth of the tree (a root alone has depth 1).
    pub depth: usize,
    /// Per node, bit `k` set when lane `k` is a leaf (`count[k] > 0`), for the closest-hit
    /// traversal: one load instead of four compares per node.
    pub leaf_lanes: Vec<u8>,
}

impl Bvh4 {
    /// The box around everything in the tree; `None` for an empty tree.
    pub fn bounds(&self) -> Option<Aabb> {
        let root = self.nodes.first()?;
        let lo = Vec3A::new(
            root.bounds[0].min_element(),
            root.bounds[1].min_element(),
            root.bounds[2].min_element(),
        );
        let hi = Vec3A::new(
            root.bounds[3].max_element(),
            root.bounds[4].max_element(),
            root.bounds[5].max_element(),
        );
        Some(Aabb::new(lo, hi))
    }
}

/// Builds the BVH over `shapes`. Returns it with the map from BVH slots to shapes: slot `i`
/// holds `shapes[order[i]]`. `None` if the tree is deeper than [`MAX_DEPTH`] (only
/// degenerate geometry does that).
pub fn build_bvh(shapes: &[Shape]) -> Option<(Bvh4, Vec<u32>)> {
    let (params, max_leaf_size) = if shapes.len() < SMALL_SCENE {
        (BvhBuildParams::very_slow_build(), 1)
    } else {
        let params = BvhBuildParams {
            reinsertion_batch_ratio: 0.0,
            ..BvhBuildParams::fast_build()
        };
        (params, MAX_LEAF_SIZE)
    };
    let bvh2 = build_bvh2(shapes, params);
    let mut bvh = Bvh4 {
        // About a third of the binary nodes with one primitive per leaf, a sixth with four
        // (room enough that the vector never grows; pages never touched cost nothing).
        nodes: Vec::with_capacity(bvh2.nodes.len() / 5 + 1),
        depth: 0,
        leaf_lanes: Vec::new(),
    };
    let mut order = Vec::with_capacity(shapes.len());
    if !shapes.is_empty() {
        let tree = BinaryTree {
            bvh2: &bvh2,
            max_leaf_size,
            node_cost: params.collapse_traversal_cost,
        };
        bvh.depth = tree.collapse_in_parallel(&mut bvh.nodes, &mut order);
        bvh.leaf_lanes = bvh
            .nodes
            .par_iter()
            .map(|node| (0..4).fold(0, |m, k| m | u8::from(node.count[k] != 0) << k))
            .collect();
    }
    (bvh.depth <= MAX_DEPTH).then_some((bvh, order))
}

/// The binary BVH with one primitive per leaf: obvhs's PLOC build and reinsertion passes,
/// the steps of its `build_bvh2` without its leaf collapse (which [`BinaryTree::collapse`]
/// replaces) and without the validation that build runs with debug assertions on: that one panics on
/// trees deeper than 96, which degenerate input can make, while [`build_bvh`] refuses such
/// trees with an error in every build.
fn build_bvh2(shapes: &[Shape], params: BvhBuildParams) -> Bvh2 {
    let indices = (0..shapes.len() as u32).collect();
    // The node array is first written by all threads: PLOC's merge loop fills it on one
    // thread, which otherwise took every page fault of its 84 MB (1.3M triangles) alone
    // (build 240 -> 215 ms there).
    let node_count = (2 * shapes.len()).saturating_sub(1);
    let mut bvh2 = Bvh2 {
        nodes: (0..node_count)
            .into_par_iter()
            .map(|_| Bvh2Node::default())
            .collect(),
        ..Bvh2::default()
    };
    obvhs::ploc::PlocBuilder::with_capacity(shapes.len()).build_with_bvh(
        &mut bvh2,
        params.ploc_search_distance,
        shapes,
        indices,
        params.sort_precision,
        params.search_depth_threshold,
    );
    let mut reinsertion = obvhs::bvh2::reinsertion::ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh2, params.reinsertion_batch_ratio, None);
    reinsertion.run(
        &mut bvh2,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    bvh2
}

/// The binary BVH, read top-down by [`BinaryTree::collapse`], which decides its leaves on
/// the way: a subtree of at most `max_leaf_size` primitives becomes one leaf of the 4-wide
/// tree when that lowers its surface area cost (testing all its primitives against keeping
/// its nodes, each costing `node_cost` primitive tests), so that far-apart primitives stay
/// apart. Only subtrees that small can become leaves, so the decision looks at a handful of
/// nodes below the one asked about, and no pass over the whole binary tree is needed.
struct BinaryTree<'a> {
    bvh2: &'a Bvh2,
    max_leaf_size: u32,
    node_cost: f32,
}

impl BinaryTree<'_> {
    /// The number of primitives of the leaf that binary node `n` becomes, or 0 if it stays
    /// an inner node.
    fn leaf_size(&self, n: u32) -> u32 {
        let node = &self.bvh2.nodes[n as usize];
        if node.is_leaf() {
            return node.prim_count;
        }
        self.merged_leaf(n, self.max_leaf_size)
            .map_or(0, |(size, _)| size)
    }

    /// If the subtree of `n` becomes one leaf of at most `budget` primitives: its size and
    /// surface area cost. Each level down leaves the sibling at least one primitive of the
    /// budget, so at most `2^budget` nodes are read.
    fn merged_leaf(&self, n: u32, budget: u32) -> Option<(u32, f32)> {
        let node = &self.bvh2.nodes[n as usize];
        let area = node.aabb().half_area();
        if node.is_leaf() {
            let size = node.prim_count;
            return (size <= budget).then_some((size, area * size as f32));
        }
        if budget < 2 {
            return None;
        }
        let (left_size, left_cost) = self.merged_leaf(node.first_index, budget - 1)?;
        let (right_size, right_cost) =
            self.merged_leaf(node.first_index + 1, budget - left_size)?;
        let size = left_size + right_size;
        let merged_cost = area * size as f32;
        (merged_cost <= area * self.node_cost + left_cost + right_cost)
            .then_some((size, merged_cost))
    }

    /// The binary nodes that make the lanes of the 4-wide node over the binary nodes
    /// `children`, expanded until there are four or only leaves remain, each with its leaf
    /// size (0: an inner lane).
    fn lanes(&self, children: &[u32]) -> Lanes {
        let bvh2 = &self.bvh2.nodes;
        let with_size = |n: u32| (n, self.leaf_size(n));
        let mut lanes = Lanes::default();
        children.iter().for_each(|&n| lanes.push(with_size(n)));
        while lanes.len < 4 {
            // Open the inner child with the largest surface: it is the most likely to be entered.
            let widest = lanes
                .as_slice()
                .iter()
                .enumerate()
                .filter(|(_, (_, leaf_size))| *leaf_size == 0)
                .max_by(|a, b| {
                    let area = |n: u32| bvh2[n as usize].aabb().half_area();
                    area(a.1.0).total_cmp(&area(b.1.0))
                });
            let Some((k, &(n, _))) = widest else { break };
            let first = bvh2[n as usize].first_index;
            lanes.replace_with_two(k, with_size(first), with_size(first + 1));
        }
        lanes
    }

    /// The two children of the inner binary node `n`.
    fn children(&self, n: u32) -> [u32; 2] {
        let first = self.bvh2.nodes[n as usize].first_index;
        [first, first + 1]
    }

    /// The whole tree collapsed into `nodes` and `order` (see [`Self::collapse`]), the
    /// subtrees below its top [`PARALLEL_LEVELS`] levels each on its own, in parallel, then
    /// spliced in where the sequential collapse would have put them: the same nodes in the
    /// same order. Returns the depth.
    fn collapse_in_parallel(&self, nodes: &mut Vec<Node4>, order: &mut Vec<u32>) -> usize {
        let mut roots = Vec::new();
        self.subtrees_below(&[0], PARALLEL_LEVELS, MAX_DEPTH, &mut roots);
        let subtrees: Vec<Collapsed> = roots
            .par_iter()
            .map(|&(children, levels_left)| {
                let mut subtree = Collapsed::default();
                subtree.depth = self.collapse(
                    &children,
                    &mut subtree.nodes,
                    &mut subtree.order,
                    levels_left,
                    usize::MAX,
                    &mut std::iter::empty(),
                );
                subtree
            })
            .collect();
        let mut subtrees = subtrees.into_iter();
        self.collapse(
            &[0],
            nodes,
            order,
            MAX_DEPTH,
            PARALLEL_LEVELS,
            &mut subtrees,
        )
    }

    /// Collects, in depth-first order, the binary children of every inner lane `levels`
    /// levels of the 4-wide tree below the node over `children`, with the levels left there.
    fn subtrees_below(
        &self,
        children: &[u32],
        levels: usize,
        levels_left: usize,
        roots: &mut Vec<([u32; 2], usize)>,
    ) {
        for &(n, leaf_size) in self.lanes(children).as_slice() {
            match (leaf_size, levels) {
                (0, 1) => roots.push((self.children(n), levels_left - 1)),
                (0, _) => {
                    self.subtrees_below(&self.children(n), levels - 1, levels_left - 1, roots)
                }
                _ => {}
            }
        }
    }

    /// Appends the 4-wide node made of the binary nodes `children` (see [`Self::lanes`])
    /// and, recursively, its subtrees; appends the primitives of its leaves to `order`, so
    /// that every leaf is a contiguous run of slots. Below `split` levels, the subtrees are
    /// taken ready-made from `subtrees`, in depth-first order (see
    /// [`Self::collapse_in_parallel`]). Returns the subtree's depth, or stops with a depth
    /// above [`MAX_DEPTH`] when `levels_left` runs out: such a tree is refused anyway, and on
    /// degenerate input (many identical triangles) the binary tree can be a chain as long as
    /// the input, which would overflow the stack.
    fn collapse(
        &self,
        children: &[u32],
        nodes: &mut Vec<Node4>,
        order: &mut Vec<u32>,
        levels_left: usize,
        split: usize,
        subtrees: &mut impl Iterator<Item = Collapsed>,
    ) -> usize {
        if split == 0 {
            let subtree = subtrees
                .next()
                .expect("one subtree per inner lane at the split");
            return subtree.splice_into(nodes, order);
        }
        if levels_left == 0 {
            return MAX_DEPTH + 1;
        }
        let bvh2 = &self.bvh2.nodes;
        let lanes = self.lanes(children);
        let index = nodes.len();
        nodes.push(Node4 {
            bounds: [
                Vec4::INFINITY,
                Vec4::INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::NEG_INFINITY,
            ],
            child: [u32::MAX; 4],
            count: [0; 4],
        });
        let mut depth = 1;
        for (k, &(n, leaf_size)) in lanes.as_slice().iter().enumerate() {
            let aabb = bvh2[n as usize].aabb();
            for axis in 0..3 {
                nodes[index].bounds[axis][k] = aabb.min[axis];
                nodes[index].bounds[axis + 3][k] = aabb.max[axis];
            }
            if leaf_size > 0 {
                nodes[index].child[k] = order.len() as u32;
                nodes[index].count[k] = leaf_size;
                self.append_primitives(n, order);
            } else {
                nodes[index].child[k] = nodes.len() as u32;
                let below = self.collapse(
                    &self.children(n),
                    nodes,
                    order,
                    levels_left - 1,
                    split - 1,
                    subtrees,
                );
                depth = depth.max(1 + below);
            }
        }
        depth
    }

    /// Appends the primitives below binary node `n` (a small subtree) to `order`.
    fn append_primitives(&self, n: u32, order: &mut Vec<u32>) {
        let node = &self.bvh2.nodes[n as usize];
        if node.is_leaf() {
            let first = node.first_index as usize;
            order.extend_from_slice(
                &self.bvh2.primitive_indices[first..first + node.prim_count as usize],
            );
        } else {
            self.append_primitives(node.first_index, order);
            self.append_primitives(node.first_index + 1, order);
        }
    }
}

/// Levels at the top of the 4-wide tree collapsed sequentially; the subtrees below them are
/// collapsed in parallel. PLOC's trees are uneven at the top: the 1.3M-triangle scene has 4
/// subtrees below 3 levels (one of them most of the tree) and 56 below 5. Collapse time
/// there on two threads: 92-97 ms sequential, 65-70 ms with 5 levels (of which about 18 ms
/// splice the subtrees in), 83-95 ms with 8 (2,098 subtrees). The collapse waits on memory
/// (the binary nodes it reads are scattered over 84 MB), so two threads do not halve it.
const PARALLEL_LEVELS: usize = 5;

/// A subtree collapsed on its own: node indices count from its root, slots from its first
/// primitive.
#[derive(Default)]
struct Collapsed {
    nodes: Vec<Node4>,
    order: Vec<u32>,
    depth: usize,
}

impl Collapsed {
    /// Appends the subtree to `nodes` and `order`, its inner children and leaves moved past
    /// the nodes and slots already there. Returns its depth.
    fn splice_into(self, nodes: &mut Vec<Node4>, order: &mut Vec<u32>) -> usize {
        let (node_offset, slot_offset) = (nodes.len() as u32, order.len() as u32);
        nodes.extend(self.nodes.into_iter().map(|mut node| {
            for k in 0..4 {
                if node.count[k] > 0 {
                    node.child[k] += slot_offset;
                } else if node.child[k] != u32::MAX {
                    node.child[k] += node_offset; // an inner child (unused lanes keep MAX)
                }
            }
            node
        }));
        order.extend_from_slice(&self.order);
        self.depth
    }
}

/// Up to four binary nodes that become the lanes of one 4-wide node, each with its leaf size
/// (no allocation per node).
#[derive(Default)]
struct Lanes {
    items: [(u32, u32); 4],
    len: usize,
}

impl Lanes {
    fn as_slice(&self) -> &[(u32, u32)] {
        &self.items[..self.len]
    }

    fn push(&mut self, item: (u32, u32)) {
        self.items[self.len] = item;
        self.len += 1;
    }

    /// Replaces lane `k` by `a` and `b` (in that order); needs room for one more.
    fn replace_with_two(&mut self, k: usize, a: (u32, u32), b: (u32, u32)) {
        self.items.copy_within(k + 1..self.len, k + 2);
        (self.items[k], self.items[k + 1]) = (a, b);
        self.len += 1;
    }
}

/// Stack entries a traversal needs for a tree of depth `depth`: each level adds at most three
/// (four children pushed, one popped), and the closest-hit traversal always stores a node's
/// four keys, entered or not.
const fn stack_len(depth: usize) -> usize {
    3 * depth + 5
}

/// The stack of every traversal (closest hit, occlusion, packets), kept by the caller and
/// reused ray after ray: a fresh zeroed stack per ray cost about 6% of a closest-hit ray's
/// instructions in the seed room. Deep enough for any tree the build accepts ([`MAX_DEPTH`]).
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
struct BoxRay {
    origin: [Vec4; 3],
    inv_direction: [Vec4; 3],
    /// For each axis, which of `bounds` holds the near plane (min for positive directions).
    near: [usize; 3],
}

impl BoxRay {
    #[inline(always)]
    fn new(origin: Vec3A, direction: Vec3A) -> Self {
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
    fn test(&self, node: &Node4, t_max: f32) -> (Vec4, u32) {
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
    fn walk_until(
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
        // there the subtrees it could cut are small too (in the seed room it cost 5% more
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

/// `1 / v` per component, with a large finite stand-in (`±1 / EPSILON`) for `1 / 0` that keeps
/// `0 * inf` NaNs out of box tests. Its sign follows `x >= 0`, as the traversals' choice of
/// near planes does: `-0.0` counts as positive (taking its sign bit sent such rays' slabs the
/// wrong way round).
#[inline(always)]
fn safe_inverse3(v: Vec3A) -> Vec3A {
    let tiny = v.abs().cmplt(Vec3A::splat(f32::EPSILON));
    let stand_in = Vec3A::select(
        v.cmpge(Vec3A::ZERO),
        Vec3A::splat(f32::EPSILON),
        Vec3A::splat(-f32::EPSILON),
    );
    Vec3A::select(tiny, stand_in, v).recip()
}

/// The builder reads each primitive's box straight from its shape (no array of boxes).
impl obvhs::Boundable for Shape {
    /// World-space bounding box.
    fn aabb(&self) -> Aabb {
        match self {
            Shape::Triangle(t) => {
                let (v1, v2) = (t.v0 + t.e1, t.v0 + t.e2);
                Aabb::new(t.v0.min(v1).min(v2), t.v0.max(v1).max(v2))
            }
            Shape::Sphere(s) => Aabb::new(
                s.center - Vec3A::splat(s.radius),
                s.center + Vec3A::splat(s.radius),
            ),
        }
    }
}

impl Shape {
    /// Hit distance in `[0, t_max]`, or infinity.
    #[inline(always)]
    pub fn intersect_t(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> f32 {
        match self {
            Shape::Triangle(t) => {
                super::triangles::intersect_triangle(t, origin, direction, 0.0, t_max)
                    .map_or(f32::INFINITY, |h| h.0)
            }
            Shape::Sphere(s) => super::spheres::intersect_sphere(s, origin, direction, 0.0, t_max)
                .unwrap_or(f32::INFINITY),
        }
    }
}

impl FlatScene {
    /// Closest primitive along the ray within `[0, t_max]`: its BVH slot and distance.
    #[inline]
    pub fn closest_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> Option<(u32, f32)> {
        let prims = &self.leaf_prims;
        if let Some(flat) = &self.flat_primitives {
            return flat.closest_hit(origin, direction, t_max);
        }
        if !self.node_triangles.is_empty() {
            let quads = &self.node_triangles;
            return self.bvh.closest_hit_by_node(
                stack,
                origin,
                direction,
                t_max,
                #[inline(always)]
                |index, node, lanes, t_max| {
                    let quad = &quads[index];
                    closest_in_node(prims, quad, node, lanes, origin, direction, t_max)
                },
            );
        }
        self.bvh.closest_hit_by_leaf(
            stack,
            origin,
            direction,
            t_max,
            // Inlined by force: the renderer's build otherwise called it per leaf.
            #[inline(always)]
            |first, count, t_max| closest_in_leaf(prims, first, count, origin, direction, t_max),
        )
    }

    /// Whether anything blocks the segment from `origin` to `origin + t_max direction`.
    #[inline]
    pub fn occluded(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> bool {
        let prims = &self.leaf_prims;
        self.bvh
            .any_hit(stack, origin, direction, t_max, |slot, t_max| {
                prims[slot as usize].hit_t(origin, direction, t_max)
            })
    }

    /// Occlusion of up to [`PACKET_SIZE`] shadow rays from one origin: bit `k` is set when
    /// segment `k` of the packet is blocked. For segments between points of the scene (see
    /// [`super::occluders`]): the triangles that bound the scene are left out.
    #[inline]
    pub fn occluded_packet(&self, stack: &mut TraversalStack, packet: &Packet) -> u32 {
        let (bvh, prims) = match &self.occluders {
            Some(o) => (&o.bvh, &o.leaf_prims),
            None => (&self.bvh, &self.leaf_prims),
        };
        let Packet {
            origin,
            directions,
            t_max,
            ..
        } = *packet;
        bvh.any_hit_packet(stack, packet, |slot, mut open| {
            let mut blocked = 0;
            match &prims[slot as usize].shape() {
                Shape::Triangle(tri) => {
                    let terms = OriginTerms::new(tri, origin);
                    if packet.stays_on_one_side(terms.ng, terms.c)
                        || packet.passes_beside(tri, &terms)
                    {
                        return 0; // no segment reaches the plane, or every one passes beside
                    }
                    while open != 0 {
                        let k = open.trailing_zeros() as usize;
                        open &= open - 1;
                        if intersect_triangle_from(tri, &terms, directions[k], 0.0, t_max[k])
                            .is_some()
                        {
                            blocked |= 1 << k;
                        }
                    }
                }
                Shape::Sphere(sphere) => {
                    while open != 0 {
                        let k = open.trailing_zeros() as usize;
                        open &= open - 1;
                        if intersect_sphere(sphere, origin, directions[k], 0.0, t_max[k]).is_some()
                        {
                            blocked |= 1 << k;
                        }
                    }
                }
            }
            blocked
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flatten::leaf_prims::{
        FlatPrimitives, LeafPrim, MAX_FLAT_PRIMITIVES, node_triangles,
    };
    use crate::flatten::spheres::SphereGeom;
    use crate::flatten::triangles::TriangleGeom;
    use crate::math::rng::{path_key, uniform};

    /// Random triangles and spheres, already in BVH order.
    fn random_scene(n: u32) -> (Vec<Shape>, Bvh4) {
        let u = |i: u32, d: u32| uniform(path_key(1, i, 0), 0, d);
        let shapes: Vec<Shape> = (0..n)
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
            .collect();
        let (bvh, order) = build_bvh(&shapes).unwrap();
        (order.iter().map(|&i| shapes[i as usize]).collect(), bvh)
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

    /// The closest hit found by testing every shape.
    fn brute_force_closest(
        shapes: &[Shape],
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> Option<(u32, f32)> {
        (0..shapes.len() as u32)
            .map(|s| (s, shapes[s as usize].intersect_t(origin, direction, t_max)))
            .filter(|h| h.1 < f32::INFINITY)
            .min_by(|a, b| a.1.total_cmp(&b.1))
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
            let found = bvh.closest_hit_by_node(
                &mut stack,
                origin,
                direction,
                t_max,
                |n, node, lanes, t| {
                    closest_in_node(&prims, &quads[n], node, lanes, origin, direction, t)
                },
            );
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
            let parallel_depth =
                tree.collapse_in_parallel(&mut parallel_nodes, &mut parallel_order);
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
        // 28 primitives (the seed room's count), four of them spheres: seven groups of
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
        let (bvh, order) = build_bvh(&[]).unwrap();
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
}
