//! The render scene: what the wavefront stages read, built once by [`crate::flatten()`] and
//! immutable after. World-space primitives in BVH slot order (the slot indexes every
//! per-primitive column), the material and light tables, the accelerators of [`crate::accel`],
//! and the whole query API the stages and ray-casting clients use: closest hit, occlusion,
//! shadow packets and ray batches.

use crate::accel::build::Bvh4;
use crate::accel::leaf_prims::{
    FlatPrimitives, LeafPrim, NodeTriangles, closest_in_leaf, closest_in_node,
};
use crate::accel::occluders::Occluders;
use crate::accel::ray_batches;
use crate::bsdf::Bsdf;
use crate::flatten::FlattenTimes;
use crate::geometry::Shape;
use crate::geometry::sphere::intersect_sphere;
use crate::geometry::triangle::{OriginTerms, intersect_triangle_from};
use crate::lights::LightTable;
use crate::math::{Vec2, Vec3, Vec3A, Vec4};
use crate::scene::Camera;
use crate::texture::{SurfaceTextures, Texture, TexturedEmission};
use obvhs::aabb::Aabb;
use std::sync::Arc;

// The query API's types, so that its callers need not know the accelerators' modules.
pub use crate::accel::packet::{PACKET_SIZE, Packet};
pub use crate::accel::ray_batches::Ray;
pub use crate::accel::traverse::TraversalStack;

/// Marks a primitive that emits nothing in [`RenderScene::emitter`].
pub const NO_EMITTER: u32 = u32::MAX;

/// The render-side scene: immutable, world space, shared by reference across threads.
pub struct RenderScene {
    /// Geometry per BVH slot, laid out for the traversals' leaf tests (see
    /// [`RenderScene::shape`] for the shape itself).
    pub leaf_prims: Vec<LeafPrim>,
    /// Per BVH node, its leaves' triangles for one four-wide closest-hit test, when every
    /// leaf holds one primitive (small scenes); else empty.
    pub node_triangles: Vec<NodeTriangles>,
    /// Every primitive, for a closest-hit query without the tree, in the smallest scenes
    /// (at most [`crate::accel::leaf_prims::MAX_FLAT_PRIMITIVES`]); else `None`.
    pub flat_primitives: Option<FlatPrimitives>,
    /// Per-vertex shading normals per slot (unit, world space); all zero for flat shading
    /// and for spheres.
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Texture coordinates of the three vertices per slot (zero when the mesh has none);
    /// read only for textured materials.
    pub vertex_uvs: Vec<[Vec2; 3]>,
    /// Tangents of the three vertices per slot (world space, `w` = handedness, see
    /// [`VertexTangents`]); empty unless some material has a normal map.
    pub vertex_tangents: Vec<[Vec4; 3]>,
    /// Material index per slot, into `materials`.
    pub material: Vec<u32>,
    /// Light index per slot, into `lights.lights`, or [`NO_EMITTER`].
    pub emitter: Vec<u32>,
    /// Distinct materials.
    pub materials: Vec<Bsdf>,
    /// Textures per material, looked up at the hit's texture coordinates.
    pub material_textures: Vec<SurfaceTextures>,
    /// Distinct textures.
    pub textures: Vec<Arc<Texture>>,
    /// Emitting primitives and punctual lights.
    pub lights: LightTable,
    /// Per area light (as `lights.lights`), its emission texture; empty when no light has one.
    pub textured_emission: Vec<Option<TexturedEmission>>,
    /// The BVH over the primitives (slot `i` is `leaf_prims[i]`).
    pub bvh: Bvh4,
    /// The primitives that can block a shadow ray and their own tree, when some triangles
    /// bound the scene and cannot (see [`crate::accel::occluders`]); `None`: all of them can.
    pub occluders: Option<Occluders>,
    /// Per slot, the index of the primitive in flattening order (meshes in query order, their
    /// triangles in index order, then spheres), to map hits back to the input.
    pub source_index: Vec<u32>,
    /// The camera.
    pub camera: Camera,
    /// Things skipped while flattening (degenerate triangles, ...), for the user to see.
    pub warnings: Vec<String>,
    /// How long [`crate::flatten()`] took.
    pub times: FlattenTimes,
}

impl RenderScene {
    /// The primitive in slot `slot`.
    #[inline(always)]
    pub fn shape(&self, slot: usize) -> Shape {
        self.leaf_prims[slot].shape()
    }

    /// The primitives in slot order.
    pub fn shapes(&self) -> impl ExactSizeIterator<Item = Shape> + '_ {
        self.leaf_prims.iter().map(LeafPrim::shape)
    }

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
    /// [`crate::accel::occluders`]): the triangles that bound the scene are left out.
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

    /// The closest hit of every ray, as [`RenderScene::closest_hit`] gives it (slot and
    /// distance, `None` for a miss), in the order of `rays`.
    pub fn closest_hits(&self, rays: &[Ray]) -> Vec<Option<(u32, f32)>> {
        ray_batches::in_coherent_order(rays, self.sort_bounds(), |stack, ray| {
            self.closest_hit(stack, ray.origin, ray.direction, ray.t_max)
        })
    }

    /// Whether anything blocks each ray before its `t_max`, as [`RenderScene::occluded`]
    /// tells it, in the order of `rays`.
    pub fn occlusions(&self, rays: &[Ray]) -> Vec<bool> {
        ray_batches::in_coherent_order(rays, self.sort_bounds(), |stack, ray| {
            self.occluded(stack, ray.origin, ray.direction, ray.t_max)
        })
    }

    /// The box over which batches are sorted, or `None` when the scene is too small for
    /// sorting to pay (or empty).
    pub(crate) fn sort_bounds(&self) -> Option<Aabb> {
        let footprint = std::mem::size_of_val(&self.leaf_prims[..])
            + std::mem::size_of_val(&self.bvh.nodes[..]);
        self.bvh
            .bounds()
            .filter(|_| footprint > ray_batches::SORT_ABOVE_BYTES)
    }
}
