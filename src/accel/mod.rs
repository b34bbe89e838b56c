//! Acceleration structures: the one BVH over all primitives (triangles and analytic spheres
//! together), its walks, and the leaf layouts and side trees that speed them up.
//!
//! obvhs builds a binary BVH (PLOC + reinsertion); [`build`] collapses it into a 4-wide BVH
//! whose nodes keep their four child boxes as structure-of-arrays `Vec4`s, so one ray tests
//! all four children with a handful of SIMD instructions, and [`traverse`] walks it with our
//! own loops (closest hit: near-to-far with a fixed-size stack; occlusion: stops at the first
//! hit); [`packet`] walks shadow rays from one origin together. Leaves point at contiguous
//! runs of primitive slots: the scene stores primitives in BVH order, so there is no index
//! indirection at trace time. [`leaf_prims`] lays the primitives out for the leaf tests,
//! [`occluders`] finds the primitives that can block shadow rays, and [`ray_batches`] casts
//! large batches of independent rays in a cache-friendly order.

pub mod alpha;
pub mod build;
mod chunks;
pub mod instances;
pub mod leaf_prims;
pub mod occluders;
pub mod packet;
pub mod ray_batches;
pub mod traverse;

#[cfg(test)]
pub mod reference;
#[cfg(test)]
mod tests;

use build::Bvh4;
use leaf_prims::{FlatPrimitives, LeafPrim, NodeTriangles, node_triangles};

/// Which layout the closest-hit query reads, chosen once when the scene is built; each is
/// tested against [`reference`] (see `render_scene`'s tests). Shadow rays have one path of
/// their own: the tree of the occluders when some triangles bound the scene ([`occluders`]),
/// else the whole tree.
#[derive(Clone, Debug)]
pub enum ClosestHitPath {
    /// No tree: every primitive, the triangles four at a time (scenes of at most
    /// [`leaf_prims::MAX_FLAT_PRIMITIVES`] primitives, where a tree does not pay).
    Flat(FlatPrimitives),
    /// The tree, with each node's leaf triangles tested together (one entry per node), when
    /// every leaf holds one primitive (small scenes).
    NodeTriangles(Vec<NodeTriangles>),
    /// The tree, leaf by leaf, leaves of two to four triangles tested four wide (large scenes).
    Leaves,
    /// The tree, primitive by primitive, with the alpha-coverage test (an any-hit filter,
    /// [`crate::RenderScene`]'s `covers`) on candidate hits of flagged slots: scenes with some
    /// alpha-tested (MASK or BLEND) primitive. The other paths never test coverage.
    AlphaTested,
}

impl ClosestHitPath {
    /// The fastest path the scene allows: `prims` are the leaf records in slot order, `bvh`
    /// the tree over them, `alpha_tested` whether some primitive has alpha coverage.
    pub fn choose(prims: &[LeafPrim], bvh: &Bvh4, alpha_tested: bool) -> Self {
        if alpha_tested {
            return ClosestHitPath::AlphaTested;
        }
        if let Some(flat) = FlatPrimitives::new(prims) {
            return ClosestHitPath::Flat(flat);
        }
        let quads = node_triangles(prims, bvh);
        if quads.is_empty() {
            ClosestHitPath::Leaves
        } else {
            ClosestHitPath::NodeTriangles(quads)
        }
    }
}
