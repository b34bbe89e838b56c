//! The second level of the two-level structure: meshes drawn several times (glTF nodes that
//! share a mesh, `EXT_mesh_gpu_instancing`) are stored once, in object space, as a
//! [`Prototype`] with its own BVH (the bottom level), and drawn by [`Instance`]s, each a
//! transform of one prototype, under a top-level BVH over the instances' world boxes.
//!
//! Rays are carried into object space by the instance's inverse transform without
//! renormalising the direction, so a distance `t` along the object-space ray is the same `t`
//! along the world-space ray: hits of every instance and of the flat part of the scene
//! compare directly. Each instance's primitives have *virtual slots* of their own after the
//! flat part's slots (instance `i`'s prototype slot `s` is `first_slot[i] + s`), so a hit is
//! still one `u32`; the render scene turns a virtual slot back into world-space geometry and
//! attributes on demand ([`Instances::shape`] and the attribute lookups), with mirroring
//! transforms (negative determinant) handled as flattening does: the winding is reversed
//! (corners 1 and 2 swapped), so the geometric normal keeps the front side.

use super::build::Bvh4;
use super::leaf_prims::{LeafPrim, closest_in_leaf};
use super::traverse::TraversalStack;
use crate::geometry::{Shape, TriangleGeom};
use crate::math::{Affine3A, Mat3A, Vec2, Vec3, Vec3A, Vec4};

/// A mesh stored once, in object space, in the slot order of its own BVH.
pub struct Prototype {
    /// The BVH over the prototype's triangles (object space).
    pub bvh: Bvh4,
    /// Triangles per slot, object space.
    pub leaf_prims: Vec<LeafPrim>,
    /// Unit shading normals of the three vertices per slot (object space), zero for flat
    /// shading; empty when the scene has no vertex normals.
    pub normals: Vec<[Vec3; 3]>,
    /// Texture coordinates per slot; empty when the scene has none.
    pub uvs: Vec<[Vec2; 3]>,
    /// Tangents per slot (object space, `w` = handedness); empty unless normal-mapped.
    pub tangents: Vec<[Vec4; 3]>,
    /// Linear RGBA vertex colours per slot; empty when the scene has none.
    pub colors: Vec<[Vec4; 3]>,
    /// Material index (into the render scene's materials) of every triangle.
    pub material: u32,
}

/// One placement of a prototype.
#[derive(Clone, Copy, Debug)]
pub struct Instance {
    /// Object to world.
    pub world_from_object: Affine3A,
    /// World to object (the inverse, computed once).
    pub object_from_world: Affine3A,
    /// The inverse transpose of the linear part, for normals.
    pub normal_matrix: Mat3A,
    /// The prototype drawn.
    pub prototype: u32,
    /// Whether the transform mirrors (negative determinant).
    pub flips: bool,
}

/// The instanced part of a scene: prototypes, instances in top-level slot order, and the
/// top-level BVH over the instances.
pub struct Instances {
    /// The distinct meshes.
    pub prototypes: Vec<Prototype>,
    /// Instances in top-level BVH slot order.
    pub instances: Vec<Instance>,
    /// Per instance, the virtual slot of its prototype's slot 0 (increasing), then one past
    /// the last virtual slot.
    pub first_slot: Vec<u32>,
    /// The top-level BVH over the instances' world-space boxes.
    pub tlas: Bvh4,
}

impl Instances {
    /// The instance and prototype slot of virtual slot `slot` (which must be an instanced one).
    #[inline]
    pub fn locate(&self, slot: u32) -> (&Instance, &Prototype, usize) {
        let i = self.first_slot.partition_point(|&first| first <= slot) - 1;
        let instance = &self.instances[i];
        let prototype = &self.prototypes[instance.prototype as usize];
        (instance, prototype, (slot - self.first_slot[i]) as usize)
    }

    /// The ray `origin + t direction` in the object space of `instance` (same `t`).
    #[inline(always)]
    fn object_ray(instance: &Instance, origin: Vec3A, direction: Vec3A) -> (Vec3A, Vec3A) {
        let m = &instance.object_from_world;
        (m.transform_point3a(origin), m.matrix3 * direction)
    }

    /// The closest instanced triangle hit within `(0, t_max)`: its virtual slot and distance.
    /// `stack` walks the top level, `inner` the prototypes' trees.
    #[inline]
    pub fn closest_hit(
        &self,
        stack: &mut TraversalStack,
        inner: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> Option<(u32, f32)> {
        self.tlas
            .closest_hit_by_leaf(stack, origin, direction, t_max, |first, count, t_max| {
                let mut best = (u32::MAX, t_max);
                for i in first..first + count {
                    let instance = &self.instances[i as usize];
                    let prototype = &self.prototypes[instance.prototype as usize];
                    let (o, d) = Self::object_ray(instance, origin, direction);
                    let prims = &prototype.leaf_prims;
                    let hit = prototype.bvh.closest_hit_by_leaf(
                        inner,
                        o,
                        d,
                        best.1,
                        #[inline(always)]
                        |first, count, t_max| closest_in_leaf(prims, first, count, o, d, t_max),
                    );
                    if let Some((slot, t)) = hit {
                        best = (self.first_slot[i as usize] + slot, t);
                    }
                }
                best
            })
    }

    /// Whether some instanced triangle is hit within `(0, t_max]`.
    #[inline]
    pub fn occluded(
        &self,
        stack: &mut TraversalStack,
        inner: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> bool {
        self.tlas
            .any_hit(stack, origin, direction, t_max, |i, t_max| {
                let instance = &self.instances[i as usize];
                let prototype = &self.prototypes[instance.prototype as usize];
                let (o, d) = Self::object_ray(instance, origin, direction);
                let prims = &prototype.leaf_prims;
                let blocked = prototype.bvh.any_hit(inner, o, d, t_max, |slot, t_max| {
                    prims[slot as usize].hit_t(o, d, t_max)
                });
                if blocked { 0.0 } else { f32::INFINITY }
            })
    }

    /// The world-space triangle of virtual slot `slot`, with the corners in the order that
    /// keeps its front side (corners 1 and 2 swapped under a mirroring transform, as
    /// flattening does).
    #[inline]
    pub fn shape(&self, slot: u32) -> Shape {
        let (instance, prototype, s) = self.locate(slot);
        let Shape::Triangle(t) = prototype.leaf_prims[s].shape() else {
            unreachable!("prototypes hold triangles only")
        };
        let m = &instance.world_from_object;
        let (e1, e2) = (m.matrix3 * t.e1, m.matrix3 * t.e2);
        let (e1, e2) = if instance.flips { (e2, e1) } else { (e1, e2) };
        Shape::Triangle(TriangleGeom {
            v0: m.transform_point3a(t.v0),
            e1,
            e2,
        })
    }

    /// Per-vertex values in the corner order of [`Self::shape`].
    #[inline(always)]
    fn corners<T: Copy>(instance: &Instance, v: [T; 3]) -> [T; 3] {
        if instance.flips {
            [v[0], v[2], v[1]]
        } else {
            v
        }
    }

    /// World-space unit shading normals of the vertices of `slot` (all zero when flat).
    #[inline]
    pub fn vertex_normals(&self, slot: u32) -> [Vec3; 3] {
        let (instance, prototype, s) = self.locate(slot);
        let Some(n) = prototype.normals.get(s) else {
            return [Vec3::ZERO; 3];
        };
        if n[0] == Vec3::ZERO {
            return [Vec3::ZERO; 3];
        }
        let world =
            n.map(|n| Vec3::from(instance.normal_matrix * Vec3A::from(n)).normalize_or_zero());
        if world.contains(&Vec3::ZERO) {
            return [Vec3::ZERO; 3];
        }
        Self::corners(instance, world)
    }

    /// Texture coordinates of the vertices of `slot`.
    #[inline]
    pub fn vertex_uvs(&self, slot: u32) -> [Vec2; 3] {
        let (instance, prototype, s) = self.locate(slot);
        prototype
            .uvs
            .get(s)
            .map_or([Vec2::ZERO; 3], |uv| Self::corners(instance, *uv))
    }

    /// Linear RGBA colours of the vertices of `slot` (white without).
    #[inline]
    pub fn vertex_colors(&self, slot: u32) -> [Vec4; 3] {
        let (instance, prototype, s) = self.locate(slot);
        prototype
            .colors
            .get(s)
            .map_or([Vec4::ONE; 3], |c| Self::corners(instance, *c))
    }

    /// World-space tangents of the vertices of `slot` (the linear part carries them; a
    /// mirroring transform flips the handedness).
    #[inline]
    pub fn vertex_tangents(&self, slot: u32) -> [Vec4; 3] {
        let (instance, prototype, s) = self.locate(slot);
        let Some(t) = prototype.tangents.get(s) else {
            return [Vec4::ZERO; 3];
        };
        let world = t.map(|t| {
            if t == Vec4::ZERO {
                return t;
            }
            let xyz = instance.world_from_object.matrix3 * Vec3A::from(t.truncate());
            let w = if (t.w < 0.0) != instance.flips {
                -1.0
            } else {
                1.0
            };
            xyz.normalize_or_zero().extend(w)
        });
        Self::corners(instance, world)
    }

    /// The material of `slot`.
    #[inline]
    pub fn material(&self, slot: u32) -> u32 {
        self.locate(slot).1.material
    }

    /// Bytes held (prototypes, instances and the top-level tree), for the statistics.
    pub fn bytes(&self) -> usize {
        let prototypes: usize = self
            .prototypes
            .iter()
            .map(|p| {
                std::mem::size_of_val(&p.bvh.nodes[..])
                    + std::mem::size_of_val(&p.leaf_prims[..])
                    + std::mem::size_of_val(&p.normals[..])
                    + std::mem::size_of_val(&p.uvs[..])
                    + std::mem::size_of_val(&p.tangents[..])
                    + std::mem::size_of_val(&p.colors[..])
            })
            .sum();
        prototypes
            + std::mem::size_of_val(&self.instances[..])
            + std::mem::size_of_val(&self.tlas.nodes[..])
    }
}
