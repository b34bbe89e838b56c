//! The chunked build of large scenes, whose scratch is bounded by the chunk instead of the
//! scene: the primitives are cut into chunks of at most a given size, each chunk's tree is
//! built by [`super::build`] and collapsed on its own (its scratch freed before the next),
//! and a small top tree over the chunks joins them into one [`super::build::Bvh4`].
//!
//! What makes the chunked tree trace as fast as a whole build:
//! - The cuts are chosen top-down by the surface area heuristic, binned over the boxes'
//!   centres, each side's area weighted by its number of primitives: a chunk is a box of
//!   space that a whole build would also keep together.
//! - Large primitives (the walls and floor of a room) are kept out of the chunks and become
//!   leaves of the top tree. A whole PLOC build merges them last, so they sit near the root
//!   and every other box stays tight; in a chunk, one wall would stretch the chunk's box to
//!   the whole room, and rays from inside the room would enter every chunk.
//! - The top tree is obvhs's slowest and best build over the chunks' boxes and the large
//!   primitives (a few dozen items), collapsed like the chunks: inner nodes opened widest
//!   first, large primitives merged into leaves where the surface area cost says so.

use super::build::{
    BinaryTree, Lanes, MAX_DEPTH, Node4, PlocRun, build_bvh2_of, merged_leaf, scratch_vec,
};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use rayon::prelude::*;
use std::ops::Range;

/// Bins per axis of a top split: the top splits are few (a handful of levels), so they can
/// afford more candidate planes than a whole-scene binned build would.
const BINS: usize = 64;

/// The share of the scene's half area above which a primitive's box is large (a box 1/32
/// of the scene's size each way): the 26 walls of the 1.3M-triangle ray-set scene, none of
/// its furniture.
const LARGE_AREA: f32 = 1.0 / 1024.0;

/// The most large primitives set apart: the top tree's build (obvhs's slowest) stays a few
/// milliseconds. A scene of mostly large primitives is cut like any other.
const MAX_LARGE: usize = 4096;

/// A primitive's box with its index, while the top splits reorder the primitives (28 bytes:
/// the boxes are read once, and freed before the chunks are built).
#[derive(Clone, Copy)]
struct Boxed {
    min: [f32; 3],
    max: [f32; 3],
    index: u32,
}

impl Boxed {
    fn new(index: usize, aabb: Aabb) -> Self {
        Boxed {
            min: aabb.min.into(),
            max: aabb.max.into(),
            index: index as u32,
        }
    }

    fn centre(&self, axis: usize) -> f32 {
        (self.min[axis] + self.max[axis]) * 0.5
    }

    fn aabb(&self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }
}

/// Builds the tree over `count` primitives whose boxes `box_of` gives, in chunks of at most
/// `chunk_size` primitives; puts its nodes in `nodes` (empty before), appends its slot
/// order to `order` and returns its depth (above [`MAX_DEPTH`] for a tree too deep, which
/// is refused).
pub(super) fn build_in_chunks(
    count: usize,
    box_of: &(impl Fn(usize) -> Aabb + Sync),
    chunk_size: usize,
    (params, max_leaf_size, cubic_cells): (BvhBuildParams, u32, bool),
    nodes: &mut Vec<Node4>,
    order: &mut Vec<u32>,
) -> usize {
    let chunk_size = chunk_size.max(1);
    let mut boxed: Vec<Boxed> = (0..count)
        .into_par_iter()
        .map(|i| Boxed::new(i, box_of(i)))
        .collect();
    let (large, ranges) = cut_into_chunks(&mut boxed, chunk_size);
    let items: Vec<Aabb> = ranges
        .iter()
        .map(|(_, aabb)| *aabb)
        .chain(boxed[..large].iter().map(Boxed::aabb))
        .collect();
    // Mapped, as every vector of the build that is freed before the scene is done: glibc
    // keeps smaller freed blocks resident, beside the render scene made next.
    let mut sorted = scratch_vec(count, true);
    sorted.extend(boxed.iter().map(|b| b.index));
    drop(boxed);
    let top = build_bvh2_of(
        items.len(),
        &|i| items[i],
        PlocRun {
            params: BvhBuildParams::very_slow_build(),
            cubic_cells: false,
            mapped_scratch: false,
        },
    );
    let tree = TopTree {
        top: &top,
        chunks: &ranges,
        sorted: &sorted,
        large: &sorted[..large],
        box_of,
        params,
        max_leaf_size,
        cubic_cells,
    };
    // Mapped (see `scratch_vec`), so that growing it past the estimate moves no nodes and
    // leaves no freed copy resident.
    *nodes = scratch_vec(count / NODE_ESTIMATE_DIVISOR + 1, true);
    tree.collapse(&[0], nodes, order, MAX_DEPTH)
}

/// The 4-wide nodes reserved for a chunked build: one per this many primitives (the 2M grid
/// has one per 6.3).
const NODE_ESTIMATE_DIVISOR: usize = 5;

/// Reorders `boxed`: first the large primitives (their number is returned; more than
/// [`MAX_LARGE`] are left with the others), then the chunks, whose ranges and boxes are
/// returned.
fn cut_into_chunks(boxed: &mut [Boxed], chunk_size: usize) -> (usize, Vec<(Range<usize>, Aabb)>) {
    let bounds = boxed
        .par_iter()
        .map(Boxed::aabb)
        .reduce(Aabb::empty, |a, b| a.union(&b));
    let limit = bounds.half_area() * LARGE_AREA;
    let mut large = partition(boxed, |b| b.aabb().half_area() > limit);
    if large > MAX_LARGE {
        large = 0;
    }
    let mut ranges = Vec::new();
    split_into_chunks(&mut boxed[large..], large, chunk_size, &mut ranges);
    (large, ranges)
}

/// The large primitives and the chunks that [`build_in_chunks`] makes of `boxes`, as the
/// primitives' indices.
#[cfg(test)]
pub(super) fn chunks_of(boxes: &[Aabb], chunk_size: usize) -> (Vec<u32>, Vec<Vec<u32>>) {
    let mut boxed: Vec<Boxed> = boxes
        .iter()
        .enumerate()
        .map(|(i, &b)| Boxed::new(i, b))
        .collect();
    let (large, ranges) = cut_into_chunks(&mut boxed, chunk_size);
    let indices = |range: Range<usize>| boxed[range].iter().map(|b| b.index).collect();
    let chunks = ranges
        .into_iter()
        .map(|(range, _)| indices(range))
        .collect();
    (indices(0..large), chunks)
}

/// Splits `boxed` (which starts at `start` in the whole list) in place until every part
/// holds at most `chunk_size`; pushes each part's range and box to `chunks`, in order.
fn split_into_chunks(
    boxed: &mut [Boxed],
    start: usize,
    chunk_size: usize,
    chunks: &mut Vec<(Range<usize>, Aabb)>,
) {
    let bins = bin(boxed);
    if boxed.len() <= chunk_size {
        chunks.push((start..start + boxed.len(), bins.bounds));
        return;
    }
    let mid = match bins.best_split() {
        Some(split) => partition(boxed, |b| bins.bin_of(b, split.axis) < split.bin),
        // Every centre is the same point: any cut is as good.
        None => boxed.len() / 2,
    };
    let (left, right) = boxed.split_at_mut(mid);
    split_into_chunks(left, start, chunk_size, chunks);
    split_into_chunks(right, start + mid, chunk_size, chunks);
}

/// Moves the boxes for which `goes_left` holds before the others; returns how many there are.
fn partition(boxed: &mut [Boxed], goes_left: impl Fn(&Boxed) -> bool) -> usize {
    let mut mid = 0;
    for k in 0..boxed.len() {
        if goes_left(&boxed[k]) {
            boxed.swap(mid, k);
            mid += 1;
        }
    }
    mid
}

/// A top split: boxes whose centre falls in a bin below `bin` on `axis` go left.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Split {
    axis: usize,
    bin: usize,
}

/// The boxes of one top node, binned by their centres along each axis.
struct Bins {
    bounds: Aabb,
    centres: Aabb,
    counts: [[u32; BINS]; 3],
    boxes: [[Aabb; BINS]; 3],
}

impl Bins {
    fn empty() -> Self {
        Bins {
            bounds: Aabb::empty(),
            centres: Aabb::empty(),
            counts: [[0; BINS]; 3],
            boxes: [[Aabb::empty(); BINS]; 3],
        }
    }

    fn bin_of(&self, b: &Boxed, axis: usize) -> usize {
        let (lo, extent) = (self.centres.min[axis], self.centres.diagonal()[axis]);
        if extent <= 0.0 {
            return 0;
        }
        (((b.centre(axis) - lo) / extent * BINS as f32) as usize).min(BINS - 1)
    }

    fn best_split(&self) -> Option<Split> {
        let mut best: Option<(f32, Split)> = None;
        for axis in 0..3 {
            let mut left_cost = [0.0f32; BINS];
            let (mut count, mut aabb) = (0u64, Aabb::empty());
            for bin in 0..BINS - 1 {
                count += u64::from(self.counts[axis][bin]);
                aabb = aabb.union(&self.boxes[axis][bin]);
                left_cost[bin + 1] = if count > 0 {
                    aabb.half_area() * count as f32
                } else {
                    f32::INFINITY
                };
            }
            let (mut count, mut aabb) = (0u64, Aabb::empty());
            for bin in (1..BINS).rev() {
                count += u64::from(self.counts[axis][bin]);
                aabb = aabb.union(&self.boxes[axis][bin]);
                if count == 0 {
                    continue;
                }
                let cost = left_cost[bin] + aabb.half_area() * count as f32;
                if cost.is_finite() && best.is_none_or(|(lowest, _)| cost < lowest) {
                    best = Some((cost, Split { axis, bin }));
                }
            }
        }
        best.map(|(_, split)| split)
    }
}

fn bin(boxed: &[Boxed]) -> Bins {
    let (bounds, centres) = boxed
        .par_iter()
        .fold(
            || (Aabb::empty(), Aabb::empty()),
            |(bounds, centres), b| {
                let centre = (b.aabb().min + b.aabb().max) * 0.5;
                (
                    bounds.union(&b.aabb()),
                    centres.union(&Aabb::new(centre, centre)),
                )
            },
        )
        .reduce(
            || (Aabb::empty(), Aabb::empty()),
            |a, b| (a.0.union(&b.0), a.1.union(&b.1)),
        );
    let mut bins = Bins {
        bounds,
        centres,
        ..Bins::empty()
    };
    let (counts, boxes) = boxed
        .par_chunks(1 << 14)
        .map(|part| {
            let mut partial = Bins {
                centres,
                ..Bins::empty()
            };
            for b in part {
                for axis in 0..3 {
                    let k = partial.bin_of(b, axis);
                    partial.counts[axis][k] += 1;
                    partial.boxes[axis][k] = partial.boxes[axis][k].union(&b.aabb());
                }
            }
            (partial.counts, partial.boxes)
        })
        .reduce(
            || ([[0; BINS]; 3], [[Aabb::empty(); BINS]; 3]),
            |(mut counts, mut boxes), (other_counts, other_boxes)| {
                for axis in 0..3 {
                    for k in 0..BINS {
                        counts[axis][k] += other_counts[axis][k];
                        boxes[axis][k] = boxes[axis][k].union(&other_boxes[axis][k]);
                    }
                }
                (counts, boxes)
            },
        );
    (bins.counts, bins.boxes) = (counts, boxes);
    bins
}

/// Builds the tree of one chunk (the primitives `indices`) and appends it to `nodes` and
/// `order` (its root first, its slots naming the primitives by their index in the scene),
/// as a whole build's collapse appends a subtree; returns its depth. Each chunk is built
/// where the top tree's collapse reaches it, so that no chunk's nodes wait beside the
/// others' to be copied in, and its binary tree (mapped scratch) is unmapped before the next.
/// The 2M-triangle grid builds faster this way than with the parallel collapse and copies
/// (docs/performance.md, "Memory per triangle").
fn append_chunk(
    indices: &[u32],
    box_of: &(impl Fn(usize) -> Aabb + Sync),
    (params, max_leaf_size, cubic_cells): (BvhBuildParams, u32, bool),
    nodes: &mut Vec<Node4>,
    order: &mut Vec<u32>,
) -> usize {
    let bvh2 = build_bvh2_of(
        indices.len(),
        &|k| box_of(indices[k] as usize),
        PlocRun {
            params,
            cubic_cells,
            mapped_scratch: true,
        },
    );
    let tree = BinaryTree {
        bvh2: &bvh2,
        max_leaf_size,
        node_cost: params.collapse_traversal_cost,
    };
    let first_slot = order.len();
    // Sequentially, straight into `nodes` and `order`: the parallel collapse's vectors per
    // subtree, freed once copied in, stayed resident in the allocator's arenas (with the
    // other blocks below, 31 MiB beside the 2M grid's render scene, 16 bytes per triangle).
    let depth = tree.collapse(
        &[0],
        nodes,
        order,
        MAX_DEPTH,
        usize::MAX,
        &mut std::iter::empty(),
    );
    order[first_slot..]
        .par_iter_mut()
        .for_each(|i| *i = indices[*i as usize]);
    depth
}

/// The top tree: a binary tree over the chunks and the large primitives (its leaves: items
/// `0..chunks` are the chunks, the rest the large primitives, in `large`'s order).
struct TopTree<'a, F> {
    top: &'a Bvh2,
    /// Per chunk, its range of `sorted`.
    chunks: &'a [(Range<usize>, Aabb)],
    /// The primitives' indices, the large ones first, then the chunks'.
    sorted: &'a [u32],
    large: &'a [u32],
    /// The primitives' boxes, for the chunks' builds.
    box_of: &'a F,
    params: BvhBuildParams,
    max_leaf_size: u32,
    cubic_cells: bool,
}

/// A lane's content in [`TopTree::lanes`]: a chunk's root.
const CHUNK_LANE: u32 = u32::MAX;

impl<F: Fn(usize) -> Aabb + Sync> TopTree<'_, F> {
    /// The item of top node `n` if it is a leaf.
    fn item(&self, n: u32) -> Option<usize> {
        let node = &self.top.nodes[n as usize];
        node.is_leaf()
            .then(|| self.top.primitive_indices[node.first_index as usize] as usize)
    }

    /// What top node `n` becomes as a lane: [`CHUNK_LANE`] for a chunk, the number of
    /// primitives of the leaf it becomes when it holds only large primitives that one leaf
    /// tests more cheaply than nodes would (as [`BinaryTree`] decides), else 0 (inner).
    fn lane_kind(&self, n: u32) -> u32 {
        match self.item(n) {
            Some(item) if item < self.chunks.len() => CHUNK_LANE,
            // Only large primitives merge: a chunk below makes the subtree unmergeable.
            _ => merged_leaf(
                &self.top.nodes,
                n,
                self.max_leaf_size,
                self.params.collapse_traversal_cost,
                &|n| {
                    (self.item(n))
                        .filter(|&item| item >= self.chunks.len())
                        .map(|_| 1)
                },
            )
            .map_or(0, |(size, _)| size),
        }
    }

    /// Appends the large primitives below top node `n` to `order`.
    fn append_large(&self, n: u32, order: &mut Vec<u32>) {
        let node = &self.top.nodes[n as usize];
        match self.item(n) {
            Some(item) => order.push(self.large[item - self.chunks.len()]),
            None => {
                self.append_large(node.first_index, order);
                self.append_large(node.first_index + 1, order);
            }
        }
    }

    /// Appends the 4-wide node over the top tree's nodes `children` (inner ones opened,
    /// widest first, until there are four lanes), then what is below each lane: a top inner
    /// node recursively, a chunk built and appended whole (its root node is the lane's child)
    /// or a leaf of large primitives. Returns the depth below and including the node, or stops
    /// with a depth above [`MAX_DEPTH`] when `levels_left` runs out.
    fn collapse(
        &self,
        children: &[u32],
        nodes: &mut Vec<Node4>,
        order: &mut Vec<u32>,
        levels_left: usize,
    ) -> usize {
        if levels_left == 0 {
            return MAX_DEPTH + 1;
        }
        let top = &self.top.nodes;
        let lanes = Lanes::widest_first(top, children, |n| self.lane_kind(n));
        let index = nodes.len();
        nodes.push(Node4::EMPTY);
        let mut depth = 1;
        for (k, &(n, kind)) in lanes.as_slice().iter().enumerate() {
            let node = &top[n as usize];
            nodes[index].set_lane_box(k, node.aabb());
            let below = match kind {
                CHUNK_LANE => {
                    nodes[index].child[k] = nodes.len() as u32;
                    let chunk = self.item(n).expect("a chunk is a leaf of the top tree");
                    let indices = &self.sorted[self.chunks[chunk].0.clone()];
                    let build = (self.params, self.max_leaf_size, self.cubic_cells);
                    append_chunk(indices, self.box_of, build, nodes, order)
                }
                0 => {
                    nodes[index].child[k] = nodes.len() as u32;
                    let first = node.first_index;
                    self.collapse(&[first, first + 1], nodes, order, levels_left - 1)
                }
                size => {
                    nodes[index].child[k] = order.len() as u32;
                    nodes[index].count[k] = size;
                    self.append_large(n, order);
                    0
                }
            };
            depth = depth.max(1 + below);
            if depth > MAX_DEPTH {
                return depth;
            }
        }
        depth
    }
}
