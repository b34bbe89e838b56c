//! The BVH build: obvhs's binary tree (PLOC + reinsertion) over the primitives' boxes,
//! collapsed into the 4-wide [`Bvh4`] that the traversals walk; leaves are contiguous runs
//! of slots, and `order` maps slots back to the input primitives. Large scenes are built in
//! chunks joined under a small top tree ([`super::chunks`]), so that the build's scratch is
//! bounded by the chunk, not the scene.

use crate::math::{Vec3A, Vec4};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use rayon::prelude::*;

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
/// the hexagonal room it halves the nodes a shadow packet visits (8.6 -> 4.2) and cuts those of a
/// closest-hit ray from 7.2 to 4.7.
pub(super) const MAX_LEAF_SIZE: u32 = 4;
/// Scenes with fewer primitives get one primitive per leaf: they are rooms of large,
/// overlapping triangles, where merging leaves makes every ray test most of the walls
/// (measured on the hexagonal room: 14 primitive tests per shadow ray with 4, 0.8 with 1).
const SMALL_SCENE: usize = 4096;
/// Scenes with fewer primitives get obvhs's medium build (with reinsertion passes).
const MEDIUM_SCENE: usize = 1 << 18;

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

impl Node4 {
    /// Sets lane `k`'s box.
    pub(super) fn set_lane_box(&mut self, k: usize, aabb: &Aabb) {
        for axis in 0..3 {
            self.bounds[axis][k] = aabb.min[axis];
            self.bounds[axis + 3][k] = aabb.max[axis];
        }
    }

    /// A node whose four lanes are unused (empty boxes, no children), to be filled in.
    pub(super) const EMPTY: Node4 = Node4 {
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
    };
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

/// Scenes with more primitives are built in chunks of at most this many (see
/// [`super::chunks`]), so that obvhs's scratch (about 144 bytes per primitive: binary
/// nodes, its two node lists, Morton codes) is bounded by the chunk instead of growing with
/// the scene: 72 MiB with 2^19, where a whole build of 2M triangles needs 275 MiB beside the
/// scene. The chunked tree traces as fast as the whole one (docs/performance.md).
const CHUNK_SIZE: usize = 1 << 19;

/// Builds the BVH over `shapes` (primitives, or the world boxes of instances). Returns it
/// with the map from BVH slots to shapes: slot `i` holds `shapes[order[i]]`. `None` if the
/// tree is deeper than [`MAX_DEPTH`] (only degenerate geometry does that).
pub fn build_bvh<T: obvhs::Boundable>(shapes: &[T]) -> Option<(Bvh4, Vec<u32>)> {
    build_bvh_of(shapes.len(), |i| shapes[i].aabb())
}

/// [`build_bvh`] over `count` primitives whose boxes `box_of` gives (by index, each asked
/// for once or a few times, from several threads): the caller needs no array of primitives
/// or boxes beside the build's own scratch.
pub fn build_bvh_of(
    count: usize,
    box_of: impl Fn(usize) -> Aabb + Sync,
) -> Option<(Bvh4, Vec<u32>)> {
    build_bvh_in_chunks_of(count, &box_of, CHUNK_SIZE)
}

/// [`build_bvh_of`] with chunks of at most `chunk_size` primitives: a scene that fits in one
/// is built whole; a larger one is cut into chunks, each built and collapsed on its own
/// (obvhs's scratch freed in between), and joined under a small top tree (see
/// [`super::chunks`]). The result is one ordinary [`Bvh4`].
pub(super) fn build_bvh_in_chunks_of(
    count: usize,
    box_of: &(impl Fn(usize) -> Aabb + Sync),
    chunk_size: usize,
) -> Option<(Bvh4, Vec<u32>)> {
    let (params, max_leaf_size) = if count < SMALL_SCENE {
        (BvhBuildParams::very_slow_build(), 1)
    } else if count < MEDIUM_SCENE {
        (BvhBuildParams::medium_build(), MAX_LEAF_SIZE)
    } else {
        let params = BvhBuildParams {
            reinsertion_batch_ratio: 0.0,
            ..BvhBuildParams::fast_build()
        };
        (params, MAX_LEAF_SIZE)
    };
    // Large scenes of small primitives: obvhs scales its Morton cells to the scene's box
    // on each axis, which for a flat box (a terrain, a floor of furniture) makes the cells
    // flat slabs and the curve's neighbours far apart; cubes keep them close (the 2M-triangle
    // grid in the room: 8% fewer instructions per ray). Smaller scenes keep obvhs's cells:
    // Cycles' export of the room traced 11% slower with cubes.
    let cubic_cells = count >= MEDIUM_SCENE;
    let mut bvh = Bvh4::default();
    let mut order = Vec::with_capacity(count);
    if count <= chunk_size.max(1) {
        let run = PlocRun {
            params,
            cubic_cells,
            mapped_scratch: false,
        };
        let bvh2 = build_bvh2_of(count, box_of, run);
        crate::memory::trace_phase("binary bvh");
        // About a third of the binary nodes with one primitive per leaf, a sixth with four
        // (room enough that the vector never grows; pages never touched cost nothing).
        bvh.nodes = Vec::with_capacity(bvh2.nodes.len() / 5 + 1);
        if count > 0 {
            let tree = BinaryTree {
                bvh2: &bvh2,
                max_leaf_size,
                node_cost: params.collapse_traversal_cost,
            };
            bvh.depth = tree.collapse_in_parallel(&mut bvh.nodes, &mut order);
        }
    } else {
        bvh.depth = super::chunks::build_in_chunks(
            count,
            box_of,
            chunk_size,
            (params, max_leaf_size, cubic_cells),
            &mut bvh.nodes,
            &mut order,
        );
        crate::memory::trace_phase("binary bvh");
    }
    bvh.leaf_lanes = bvh
        .nodes
        .par_iter()
        .map(|node| (0..4).fold(0, |m, k| m | u8::from(node.count[k] != 0) << k))
        .collect();
    (bvh.depth <= MAX_DEPTH).then_some((bvh, order))
}

/// The binary BVH with one primitive per leaf: obvhs's PLOC build and reinsertion passes,
/// the steps of its `build_bvh2` without its leaf collapse (which [`BinaryTree::collapse`]
/// replaces) and without the validation that build runs with debug assertions on: that one panics on
/// trees deeper than 96, which degenerate input can make, while [`build_bvh`] refuses such
/// trees with an error in every build.
#[cfg(test)]
pub(super) fn build_bvh2<T: obvhs::Boundable>(boxes: &[T], params: BvhBuildParams) -> Bvh2 {
    let run = PlocRun {
        params,
        cubic_cells: false,
        mapped_scratch: false,
    };
    build_bvh2_of(boxes.len(), &|i| boxes[i].aabb(), run)
}

/// [`build_bvh2`] over `count` primitives whose boxes `box_of` gives: obvhs's leaves are
/// made here from the boxes (as its `build_ploc` makes them from a slice), so no array of
/// boxes or primitives is needed beside its scratch.
pub(super) fn build_bvh2_of(
    count: usize,
    box_of: &(impl Fn(usize) -> Aabb + Sync),
    PlocRun {
        params,
        cubic_cells,
        mapped_scratch,
    }: PlocRun,
) -> Bvh2 {
    // The node array is first written by all threads: PLOC's merge loop fills it on one
    // thread, which otherwise took every page fault of its 84 MB (1.3M triangles) alone
    // (build 240 -> 215 ms there).
    let node_count = (2 * count).saturating_sub(1);
    let mut nodes = scratch_vec::<Bvh2Node>(node_count, mapped_scratch);
    nodes.par_extend((0..node_count).into_par_iter().map(|_| Bvh2Node::default()));
    let mut bvh2 = Bvh2 {
        nodes,
        // obvhs's leaves hold their primitive's index into `primitive_indices` as its place
        // there, so only the identity gives trees whose leaves can be read through it.
        primitive_indices: {
            let mut identity = scratch_vec(count, mapped_scratch);
            identity.extend(0..count as u32);
            identity
        },
        ..Bvh2::default()
    };
    if count == 0 {
        return bvh2;
    }
    let mut ploc = obvhs::ploc::PlocBuilder {
        current_nodes: scratch_vec(count, mapped_scratch),
        next_nodes: scratch_vec(count, mapped_scratch),
        mortons: scratch_vec(count, mapped_scratch),
        ..obvhs::ploc::PlocBuilder::new()
    };
    ploc.current_nodes.par_extend(
        (0..count)
            .into_par_iter()
            .map(|i| Bvh2Node::new(box_of(i), 1, i as u32)),
    );
    let total = ploc
        .current_nodes
        .par_iter()
        .map(|node| *node.aabb())
        .reduce(Aabb::empty, |a, b| a.union(&b));
    let total = if cubic_cells {
        Aabb::new(
            total.min,
            total.min + Vec3A::splat(total.diagonal().max_element()),
        )
    } else {
        total
    };
    let (precision, depth) = (params.sort_precision, params.search_depth_threshold);
    use obvhs::ploc::PlocSearchDistance as Distance;
    match params.ploc_search_distance {
        Distance::Minimum => {
            ploc.build_ploc_from_leaves::<1, false>(&mut bvh2, total, precision, depth)
        }
        Distance::VeryLow => {
            ploc.build_ploc_from_leaves::<2, false>(&mut bvh2, total, precision, depth)
        }
        Distance::Low => {
            ploc.build_ploc_from_leaves::<6, false>(&mut bvh2, total, precision, depth)
        }
        Distance::Medium => {
            ploc.build_ploc_from_leaves::<14, false>(&mut bvh2, total, precision, depth)
        }
        Distance::High => {
            ploc.build_ploc_from_leaves::<24, false>(&mut bvh2, total, precision, depth)
        }
        Distance::VeryHigh => {
            ploc.build_ploc_from_leaves::<32, false>(&mut bvh2, total, precision, depth)
        }
    }
    // Its scratch (node lists and Morton codes, about 80 bytes per primitive) is freed
    // before the collapse allocates.
    drop(ploc);
    let mut reinsertion = obvhs::bvh2::reinsertion::ReinsertionOptimizer::default();
    reinsertion.run(&mut bvh2, params.reinsertion_batch_ratio, None);
    reinsertion.run(
        &mut bvh2,
        params.reinsertion_batch_ratio * params.post_collapse_reinsertion_batch_ratio_multiplier,
        None,
    );
    bvh2
}

/// How [`build_bvh2_of`] runs obvhs's PLOC.
#[derive(Clone, Copy)]
pub(super) struct PlocRun {
    pub(super) params: BvhBuildParams,
    /// Morton codes taken in the cube from the scene box's lower corner, instead of in the
    /// box itself (see [`build_bvh_in_chunks_of`]).
    pub(super) cubic_cells: bool,
    /// The scratch allocated by [`scratch_vec`] with room enough to be mapped on its own.
    pub(super) mapped_scratch: bool,
}

/// An empty vector for `len` items; with `mapped`, with room for more than
/// [`MAPPED_SCRATCH_BYTES`]: glibc maps blocks that large on their own and unmaps them when
/// they are freed, while smaller freed blocks stay resident (its mmap threshold rises to 32
/// MiB as large blocks are freed): the chunks' scratch otherwise left 84 MiB of dead memory
/// beside the scene. Pages never touched cost address space only.
pub(super) fn scratch_vec<T>(len: usize, mapped: bool) -> Vec<T> {
    let room = if mapped {
        len.max(MAPPED_SCRATCH_BYTES / size_of::<T>() + 1)
    } else {
        len
    };
    Vec::with_capacity(room)
}

/// glibc's largest mmap threshold (`DEFAULT_MMAP_THRESHOLD_MAX` on 64-bit systems).
const MAPPED_SCRATCH_BYTES: usize = 32 << 20;

/// The binary BVH, read top-down by [`BinaryTree::collapse`], which decides its leaves on
/// the way: a subtree of at most `max_leaf_size` primitives becomes one leaf of the 4-wide
/// tree when that lowers its surface area cost (testing all its primitives against keeping
/// its nodes, each costing `node_cost` primitive tests), so that far-apart primitives stay
/// apart. Only subtrees that small can become leaves, so the decision looks at a handful of
/// nodes below the one asked about, and no pass over the whole binary tree is needed.
pub(super) struct BinaryTree<'a> {
    pub(super) bvh2: &'a Bvh2,
    pub(super) max_leaf_size: u32,
    pub(super) node_cost: f32,
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
    /// surface area cost (see [`merged_leaf`]).
    fn merged_leaf(&self, n: u32, budget: u32) -> Option<(u32, f32)> {
        let nodes = &self.bvh2.nodes;
        merged_leaf(nodes, n, budget, self.node_cost, &|n| {
            Some(nodes[n as usize].prim_count)
        })
    }

    /// The binary nodes that make the lanes of the 4-wide node over the binary nodes
    /// `children`, expanded until there are four or only leaves remain, each with its leaf
    /// size (0: an inner lane).
    fn lanes(&self, children: &[u32]) -> Lanes {
        Lanes::widest_first(&self.bvh2.nodes, children, |n| self.leaf_size(n))
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
    pub(super) fn collapse_in_parallel(
        &self,
        nodes: &mut Vec<Node4>,
        order: &mut Vec<u32>,
    ) -> usize {
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
    pub(super) fn collapse(
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
        nodes.push(Node4::EMPTY);
        let mut depth = 1;
        for (k, &(n, leaf_size)) in lanes.as_slice().iter().enumerate() {
            nodes[index].set_lane_box(k, bvh2[n as usize].aabb());
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

/// If the subtree of binary node `n` of `nodes` becomes one leaf of at most `budget`
/// primitives: its size and surface area cost. It does when testing all its primitives
/// costs no more than keeping its nodes, each costing `node_cost` primitive tests.
/// `leaf_size(n)` is the number of primitives of leaf node `n`, or `None` for a leaf that
/// cannot be merged. Each level down leaves the sibling at least one primitive of the
/// budget, so at most `2^budget` nodes are read.
pub(super) fn merged_leaf(
    nodes: &[Bvh2Node],
    n: u32,
    budget: u32,
    node_cost: f32,
    leaf_size: &impl Fn(u32) -> Option<u32>,
) -> Option<(u32, f32)> {
    let node = &nodes[n as usize];
    let area = node.aabb().half_area();
    if node.is_leaf() {
        let size = leaf_size(n)?;
        return (size <= budget).then_some((size, area * size as f32));
    }
    if budget < 2 {
        return None;
    }
    let below = |child: u32, budget: u32| merged_leaf(nodes, child, budget, node_cost, leaf_size);
    let (left_size, left_cost) = below(node.first_index, budget - 1)?;
    let (right_size, right_cost) = below(node.first_index + 1, budget - left_size)?;
    let size = left_size + right_size;
    let merged_cost = area * size as f32;
    (merged_cost <= area * node_cost + left_cost + right_cost).then_some((size, merged_cost))
}

/// Levels at the top of the 4-wide tree collapsed sequentially; the subtrees below them are
/// collapsed in parallel. PLOC's trees are uneven at the top: the 1.3M-triangle scene has 4
/// subtrees below 3 levels (one of them most of the tree) and 56 below 5. Collapse time
/// there on two threads: 92-97 ms sequential, 65-70 ms with 5 levels (of which about 18 ms
/// splice the subtrees in), 83-95 ms with 8 (2,098 subtrees). The collapse waits on memory
/// (the binary nodes it reads are scattered over 84 MB), so two threads do not halve it.
pub(super) const PARALLEL_LEVELS: usize = 5;

/// A subtree collapsed on its own: node indices count from its root, slots from its first
/// primitive.
#[derive(Default)]
pub(super) struct Collapsed {
    pub(super) nodes: Vec<Node4>,
    pub(super) order: Vec<u32>,
    pub(super) depth: usize,
}

impl Collapsed {
    /// Appends the subtree to `nodes` and `order`, its inner children and leaves moved past
    /// the nodes and slots already there. Returns its depth.
    pub(super) fn splice_into(self, nodes: &mut Vec<Node4>, order: &mut Vec<u32>) -> usize {
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

/// Up to four binary nodes that become the lanes of one 4-wide node, each with what it
/// becomes there (a leaf's size, or 0 for an inner node; see [`Lanes::widest_first`]), with
/// no allocation per node.
#[derive(Default)]
pub(super) struct Lanes {
    items: [(u32, u32); 4],
    len: usize,
}

impl Lanes {
    /// The lanes over the binary nodes `children` of `nodes`, each with `kind(n)` (0: an
    /// inner node, which may be opened), the inner ones opened widest first until there are
    /// four lanes or none is left: the widest is the most likely to be entered.
    pub(super) fn widest_first(
        nodes: &[Bvh2Node],
        children: &[u32],
        kind: impl Fn(u32) -> u32,
    ) -> Lanes {
        let mut lanes = Lanes::default();
        children.iter().for_each(|&n| lanes.push((n, kind(n))));
        while lanes.len < 4 {
            let widest = lanes
                .as_slice()
                .iter()
                .enumerate()
                .filter(|(_, (_, kind))| *kind == 0)
                .max_by(|a, b| {
                    let area = |n: u32| nodes[n as usize].aabb().half_area();
                    area(a.1.0).total_cmp(&area(b.1.0))
                });
            let Some((k, &(n, _))) = widest else { break };
            let first = nodes[n as usize].first_index;
            lanes.replace_with_two(k, (first, kind(first)), (first + 1, kind(first + 1)));
        }
        lanes
    }

    pub(super) fn as_slice(&self) -> &[(u32, u32)] {
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
