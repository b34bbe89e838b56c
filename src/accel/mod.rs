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

pub mod build;
pub mod leaf_prims;
pub mod occluders;
pub mod packet;
pub mod ray_batches;
pub mod traverse;

#[cfg(test)]
mod tests;
