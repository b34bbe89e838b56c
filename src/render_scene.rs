//! The render scene: what the wavefront stages read, built once by [`crate::flatten()`] and
//! immutable after. World-space primitives in BVH slot order (the slot indexes every
//! per-primitive column), the material and light tables, the accelerators of [`crate::accel`],
//! and the whole query API the stages and ray-casting clients use: closest hit, occlusion,
//! shadow packets and ray batches.

use crate::accel::ClosestHitPath;
use crate::accel::alpha::{AlphaRecord, OPAQUE, alpha_covers};
use crate::accel::build::Bvh4;
use crate::accel::instances::Instances;
use crate::accel::leaf_prims::{LeafPrim, closest_in_leaf, closest_in_node};
use crate::accel::occluders::Occluders;
use crate::accel::ray_batches;
use crate::bsdf::Bsdf;
use crate::geometry::Shape;
use crate::geometry::sphere::intersect_sphere;
use crate::geometry::triangle::{OriginTerms, intersect_triangle_from};
use crate::lights::LightTable;
use crate::math::{Rgb, Vec2, Vec3, Vec3A, Vec4};
use crate::scene::Camera;
use crate::texture::{Mipmapped, SurfaceTextures, TexturedEmission};
use obvhs::aabb::Aabb;
use std::time::Duration;

// The query API's types, so that its callers need not know the accelerators' modules.
pub use crate::accel::alpha::RayKey;
pub use crate::accel::packet::{PACKET_SIZE, Packet};
pub use crate::accel::traverse::TraversalStack;
pub use crate::math::Ray;

/// Marks a primitive that emits nothing in [`RenderScene::emitter`].
pub const NO_EMITTER: u32 = u32::MAX;

/// How long [`crate::flatten()`] took (wall time), kept with the scene it made.
#[derive(Clone, Copy, Debug, Default)]
pub struct FlattenTimes {
    /// The BVH build alone: obvhs's binary tree over the primitives' boxes and its collapse
    /// into 4-wide nodes (what a ray-tracing library's build does).
    pub bvh_build: Duration,
    /// All of it: the meshes' world-space triangles, the BVH, and every per-primitive column
    /// in slot order.
    pub total: Duration,
}

/// The render-side scene: immutable, world space, shared by reference across threads.
pub struct RenderScene {
    /// Geometry per BVH slot, laid out for the traversals' leaf tests (see
    /// [`RenderScene::shape`] for the shape itself).
    pub(crate) leaf_prims: Vec<LeafPrim>,
    /// How the closest-hit query runs: which of the fast layouts it reads (chosen once, by
    /// [`ClosestHitPath::choose`]).
    pub(crate) closest_hit_path: ClosestHitPath,
    /// Per-vertex shading normals per slot (unit, world space); all zero for flat shading
    /// and for spheres.
    pub(crate) vertex_normals: Vec<[Vec3; 3]>,
    /// Texture coordinates of the three vertices per slot (zero when the mesh has none);
    /// read only for textured materials.
    pub(crate) vertex_uvs: Vec<[Vec2; 3]>,
    /// Tangents of the three vertices per slot (world space, `w` = handedness, see
    /// [`VertexTangents`]); empty unless some material has a normal map.
    pub(crate) vertex_tangents: Vec<[Vec4; 3]>,
    /// Linear RGBA colours of the three vertices per slot (white where the mesh has none,
    /// see [`VertexColors`](crate::scene::VertexColors)); empty unless some mesh has them.
    pub(crate) vertex_colors: Vec<[Vec4; 3]>,
    /// Per slot, its index into `alpha_records`, or [`OPAQUE`]; empty when
    /// every primitive is opaque.
    pub(crate) alpha_of_slot: Vec<u32>,
    /// How the alpha-tested meshes are covered.
    pub(crate) alpha_records: Vec<AlphaRecord>,
    /// Material index per slot, into `materials`.
    pub(crate) material: Vec<u32>,
    /// Light index per slot, into `lights.lights`, or [`NO_EMITTER`]; empty when no
    /// primitive emits (read through [`RenderScene::emitter_of`]).
    pub(crate) emitter: Vec<u32>,
    /// Distinct materials.
    pub(crate) materials: Vec<Bsdf>,
    /// Absorption coefficient of the medium inside each material (`KHR_materials_volume`),
    /// by material index; empty when no material absorbs.
    pub(crate) material_absorption: Vec<Rgb>,
    /// Whether some material may transmit through a rough lobe or holds an absorbing medium:
    /// the shade stage's choice of its path (`wavefront::shade::shade_hits`).
    pub(crate) transmits_or_absorbs: bool,
    /// Textures per material, looked up at the hit's texture coordinates.
    pub(crate) material_textures: Vec<SurfaceTextures>,
    /// Distinct textures, with their mipmaps.
    pub(crate) textures: Vec<Mipmapped>,
    /// Emitting primitives, punctual lights and the environment.
    pub(crate) lights: LightTable,
    /// Whether camera rays that miss everything see the environment (else black).
    pub(crate) environment_visible: bool,
    /// Per area light (as `lights.lights`), its emission texture; empty when no light has one.
    pub(crate) textured_emission: Vec<Option<TexturedEmission>>,
    /// The BVH over the primitives (slot `i` is `leaf_prims[i]`).
    pub(crate) bvh: Bvh4,
    /// The primitives that can block a shadow ray and their own tree, when some triangles
    /// bound the scene and cannot (see [`crate::accel::occluders`]); `None`: all of them can.
    pub(crate) occluders: Option<Occluders>,
    /// Per slot, the index of the primitive in flattening order (meshes in query order, their
    /// triangles in index order, then spheres), to map hits back to the input.
    pub(crate) source_index: Vec<u32>,
    /// The instanced meshes (see [`crate::accel::instances`]): their primitives have the
    /// virtual slots from `leaf_prims.len()` to `slot_count`; `None` when nothing is
    /// instanced (most scenes, which then run exactly the flat paths).
    pub(crate) instances: Option<Instances>,
    /// Number of slots: the flat part's and the instances' virtual ones.
    pub(crate) slot_count: usize,
    /// Whether some mesh has vertex colours (then `vertex_colors` is filled for the flat
    /// part, and the prototypes have theirs).
    pub(crate) has_vertex_colors: bool,
    /// The camera.
    pub(crate) camera: Camera,
    /// Things skipped while flattening (degenerate triangles, ...), for the user to see.
    pub(crate) warnings: Vec<String>,
    /// How long [`crate::flatten()`] took.
    pub(crate) times: FlattenTimes,
}

impl RenderScene {
    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Things skipped while flattening (degenerate triangles, ...), for the user to see.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// How long [`crate::flatten()`] took.
    pub fn flatten_times(&self) -> FlattenTimes {
        self.times
    }

    /// Number of primitives drawn (slots, an instanced mesh's primitives once per instance).
    pub fn primitive_count(&self) -> usize {
        self.slot_count
    }

    /// Number of primitives stored (an instanced mesh's primitives once).
    pub fn stored_primitive_count(&self) -> usize {
        self.leaf_prims.len()
            + self
                .instances
                .as_ref()
                .map_or(0, |i| i.prototypes.iter().map(|p| p.leaf_prims.len()).sum())
    }

    /// Number of instances of instanced meshes (0 when nothing is instanced).
    pub fn instance_count(&self) -> usize {
        self.instances.as_ref().map_or(0, |i| i.instances.len())
    }

    /// The index in flattening order of the primitive in slot `slot` (see
    /// [`crate::flatten()`]), to map hits back to the input; `u32::MAX` for the primitives of
    /// instanced meshes.
    pub fn source_index(&self, slot: usize) -> u32 {
        self.source_index.get(slot).copied().unwrap_or(u32::MAX)
    }

    /// Depth of the BVH (a root alone has depth 1).
    pub fn bvh_depth(&self) -> usize {
        self.bvh.depth
    }

    /// The distinct materials.
    pub fn materials(&self) -> &[Bsdf] {
        &self.materials
    }

    /// The textures each material reads, by material.
    pub fn material_textures(&self) -> &[SurfaceTextures] {
        &self.material_textures
    }

    /// The distinct textures.
    pub fn textures(&self) -> &[Mipmapped] {
        &self.textures
    }

    /// Emitting primitives and punctual lights.
    pub fn lights(&self) -> &LightTable {
        &self.lights
    }

    /// Number of area lights with an emission texture.
    pub fn textured_light_count(&self) -> usize {
        self.textured_emission.iter().flatten().count()
    }

    /// Per-vertex shading normals of the primitive in slot `slot` (all zero when flat), in
    /// world space.
    #[inline(always)]
    pub fn vertex_normals(&self, slot: usize) -> [Vec3; 3] {
        match self.flat_vertex_normals(slot) {
            Some(n) => *n,
            None => self.instanced(slot).vertex_normals(slot as u32),
        }
    }

    /// [`Self::vertex_normals`] of a slot in the flat part, in place (`None` past it).
    #[inline(always)]
    pub fn flat_vertex_normals(&self, slot: usize) -> Option<&[Vec3; 3]> {
        self.vertex_normals
            .get(slot)
            .filter(|_| slot < self.leaf_prims.len())
    }

    /// The instanced part, for a slot past the flat part.
    #[inline(always)]
    fn instanced(&self, slot: usize) -> &Instances {
        debug_assert!(slot >= self.leaf_prims.len());
        self.instances.as_ref().expect("an instanced slot")
    }

    /// A per-slot attribute: from the flat part's column `flat`, or for a slot past it, from
    /// the instance that holds it.
    #[inline(always)]
    fn per_slot<T: Copy>(&self, slot: usize, flat: &[T], instanced: fn(&Instances, u32) -> T) -> T {
        if slot < self.leaf_prims.len() {
            flat[slot]
        } else {
            instanced(self.instanced(slot), slot as u32)
        }
    }

    /// Texture coordinates of the vertices of the primitive in slot `slot`.
    #[inline(always)]
    pub(crate) fn vertex_uvs(&self, slot: usize) -> [Vec2; 3] {
        self.per_slot(slot, &self.vertex_uvs, Instances::vertex_uvs)
    }

    /// Linear RGBA vertex colours of the primitive in slot `slot` (white without); only for
    /// scenes with vertex colours ([`Self::has_vertex_colors`]).
    #[inline(always)]
    pub(crate) fn vertex_colors(&self, slot: usize) -> [Vec4; 3] {
        self.per_slot(slot, &self.vertex_colors, Instances::vertex_colors)
    }

    /// Whether some mesh has vertex colours.
    #[inline(always)]
    pub(crate) fn has_vertex_colors(&self) -> bool {
        self.has_vertex_colors
    }

    /// World-space tangents of the vertices of the primitive in slot `slot`; only for scenes
    /// with normal maps.
    #[inline(always)]
    pub(crate) fn vertex_tangents(&self, slot: usize) -> [Vec4; 3] {
        self.per_slot(slot, &self.vertex_tangents, Instances::vertex_tangents)
    }

    /// Material index of the primitive in slot `slot`.
    #[inline(always)]
    pub(crate) fn material_of(&self, slot: usize) -> u32 {
        self.per_slot(slot, &self.material, Instances::material)
    }

    /// Light index of the primitive in slot `slot`, or [`NO_EMITTER`] (always for instanced
    /// meshes, which are never emitters).
    #[inline(always)]
    pub(crate) fn emitter_of(&self, slot: usize) -> u32 {
        self.emitter.get(slot).copied().unwrap_or(NO_EMITTER)
    }

    /// The primitive in slot `slot`, in world space.
    #[inline(always)]
    pub fn shape(&self, slot: usize) -> Shape {
        match self.leaf_prims.get(slot) {
            Some(prim) => prim.shape(),
            None => self.instanced(slot).shape(slot as u32),
        }
    }

    /// The primitives in slot order (instanced ones in world space, once per instance).
    pub fn shapes(&self) -> impl ExactSizeIterator<Item = Shape> + '_ {
        (0..self.slot_count).map(|slot| self.shape(slot))
    }

    /// Closest primitive along the ray within `[0, t_max]`: its BVH slot and distance.
    /// (BLEND coverage, if any, as for the first ray of a path of key 0.)
    #[inline]
    pub fn closest_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> Option<(u32, f32)> {
        self.closest_covered_hit(stack, origin, direction, t_max, RayKey::default())
    }

    /// [`Self::closest_hit`] for the ray `key` of a path: hits on alpha-tested primitives
    /// that do not cover the point (see [`crate::accel::alpha`]) are passed through.
    #[inline]
    pub(crate) fn closest_covered_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
        key: RayKey,
    ) -> Option<(u32, f32)> {
        let flat = self.closest_flat_hit(stack, origin, direction, t_max, key);
        match &self.instances {
            None => flat,
            Some(instances) => {
                let t_max = flat.map_or(t_max, |(_, t)| t);
                let mut inner = TraversalStack::default();
                instances
                    .closest_hit(stack, &mut inner, origin, direction, t_max)
                    .or(flat)
            }
        }
    }

    /// [`Self::closest_covered_hit`] among the flat part's primitives.
    #[inline(always)]
    fn closest_flat_hit(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
        key: RayKey,
    ) -> Option<(u32, f32)> {
        let prims = &self.leaf_prims;
        match &self.closest_hit_path {
            ClosestHitPath::Flat(flat) => flat.closest_hit(origin, direction, t_max),
            ClosestHitPath::NodeTriangles(quads) => self.bvh.closest_hit_by_node(
                stack,
                origin,
                direction,
                t_max,
                #[inline(always)]
                |index, node, lanes, t_max| {
                    let quad = &quads[index];
                    closest_in_node(prims, quad, node, lanes, origin, direction, t_max)
                },
            ),
            ClosestHitPath::Leaves => self.bvh.closest_hit_by_leaf(
                stack,
                origin,
                direction,
                t_max,
                // Inlined by force: the renderer's build otherwise called it per leaf.
                #[inline(always)]
                |first, count, t_max| {
                    closest_in_leaf(prims, first, count, origin, direction, t_max)
                },
            ),
            ClosestHitPath::AlphaTested => {
                let alpha = &self.alpha_of_slot;
                self.bvh.closest_hit_by_leaf(
                    stack,
                    origin,
                    direction,
                    t_max,
                    |first, count, t_max| {
                        let mut best = (u32::MAX, t_max);
                        for slot in first..first + count {
                            let t = prims[slot as usize].hit_t(origin, direction, best.1);
                            if t < best.1
                                && (alpha[slot as usize] == OPAQUE
                                    || self.covers(slot, origin, direction, key))
                            {
                                best = (slot, t);
                            }
                        }
                        best
                    },
                )
            }
        }
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
        self.occluded_flat(stack, origin, direction, t_max)
            || self.instances.as_ref().is_some_and(|instances| {
                let mut inner = TraversalStack::default();
                instances.occluded(stack, &mut inner, origin, direction, t_max)
            })
    }

    /// [`Self::occluded`] by the flat part's primitives.
    #[inline(always)]
    fn occluded_flat(
        &self,
        stack: &mut TraversalStack,
        origin: Vec3A,
        direction: Vec3A,
        t_max: f32,
    ) -> bool {
        let prims = &self.leaf_prims;
        if !self.alpha_of_slot.is_empty() {
            let key = RayKey::default();
            return self
                .bvh
                .any_hit(stack, origin, direction, t_max, |slot, t_max| {
                    let t = prims[slot as usize].hit_t(origin, direction, t_max);
                    let covered = t == f32::INFINITY
                        || self.alpha_of_slot[slot as usize] == OPAQUE
                        || self.covers(slot, origin, direction, key);
                    if covered { t } else { f32::INFINITY }
                });
        }
        self.bvh
            .any_hit(stack, origin, direction, t_max, |slot, t_max| {
                prims[slot as usize].hit_t(origin, direction, t_max)
            })
    }

    /// Occlusion of up to [`PACKET_SIZE`] shadow rays from one origin: bit `k` is set when
    /// segment `k` of the packet is blocked. For segments between points of the scene (see
    /// [`crate::accel::occluders`]): the triangles that bound the scene are left out.
    /// (BLEND coverage, if any, as for the shadow rays of a path of key 0.)
    #[inline]
    pub fn occluded_packet(&self, stack: &mut TraversalStack, packet: &Packet) -> u32 {
        self.occluded_covered_packet(stack, packet, RayKey::default())
    }

    /// [`Self::occluded_packet`] for the shadow rays of a path: ray `k` of the packet is ray
    /// `key.ray + k` of the bounce. Scenes with alpha-tested primitives pass each blocking
    /// candidate on a flagged slot through the coverage test; others run the opaque walk.
    #[inline]
    pub(crate) fn occluded_covered_packet(
        &self,
        stack: &mut TraversalStack,
        packet: &Packet,
        key: RayKey,
    ) -> u32 {
        let mut blocked = if self.alpha_of_slot.is_empty() {
            self.occluded_packet_walk::<false>(stack, packet, key)
        } else {
            self.occluded_packet_walk::<true>(stack, packet, key)
        };
        if let Some(instances) = &self.instances {
            // The instanced geometry has no packet walk: each ray the flat part leaves open
            // is traced alone through the two-level structure.
            let rays = (1u32 << packet.directions.len()) - 1; // at most PACKET_SIZE = 16
            let mut open = rays & !blocked;
            let mut inner = TraversalStack::default();
            while open != 0 {
                let k = open.trailing_zeros() as usize;
                open &= open - 1;
                let (d, t_max) = (packet.directions[k], packet.t_max[k]);
                if instances.occluded(stack, &mut inner, packet.origin, d, t_max) {
                    blocked |= 1 << k;
                }
            }
        }
        blocked
    }

    /// The walk of [`Self::occluded_covered_packet`], with the coverage test if `ALPHA`.
    #[inline(always)]
    fn occluded_packet_walk<const ALPHA: bool>(
        &self,
        stack: &mut TraversalStack,
        packet: &Packet,
        key: RayKey,
    ) -> u32 {
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
            if ALPHA && blocked != 0 && self.alpha_of_slot[slot as usize] != OPAQUE {
                // (No occluders' tree in these scenes: `slot` is the scene's slot.)
                let mut candidates: u32 = blocked;
                while candidates != 0 {
                    let k = candidates.trailing_zeros();
                    candidates &= candidates - 1;
                    let ray = RayKey {
                        ray: key.ray + k,
                        ..key
                    };
                    if !self.covers(slot, origin, directions[k as usize], ray) {
                        blocked &= !(1 << k);
                    }
                }
            }
            blocked
        })
    }

    /// Whether the ray `origin + t direction` of `key`, which hits the primitive in `slot`
    /// (a flagged slot: `alpha_of_slot[slot] != OPAQUE`), stops there: the alpha at the hit
    /// point (the material's factor x the texture's x the vertex colour's) as
    /// [`alpha_covers`] tests it.
    #[inline(never)]
    pub(crate) fn covers(&self, slot: u32, origin: Vec3A, direction: Vec3A, key: RayKey) -> bool {
        let record = &self.alpha_records[self.alpha_of_slot[slot as usize] as usize];
        let s = slot as usize;
        let mut alpha = record.factor;
        if record.texture.is_set() || record.vertex_alpha {
            let b = self.shape(s).barycentric(origin, direction);
            let at = |v: [f32; 3], b: Vec2| v[0] * (1.0 - b.x - b.y) + v[1] * b.x + v[2] * b.y;
            if record.vertex_alpha {
                alpha *= at(self.vertex_colors[s].map(|c| c.w), b);
            }
            if record.texture.is_set() {
                let uvs = self.vertex_uvs[s];
                let uv = uvs[0] * (1.0 - b.x - b.y) + uvs[1] * b.x + uvs[2] * b.y;
                let t = &record.texture;
                alpha *= self.textures[t.texture as usize].lookup_alpha(t.uv_transform.apply(uv));
            }
        }
        alpha_covers(record.mode, alpha, slot, key)
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
    fn sort_bounds(&self) -> Option<Aabb> {
        let footprint = std::mem::size_of_val(&self.leaf_prims[..])
            + std::mem::size_of_val(&self.bvh.nodes[..])
            + self.instances.as_ref().map_or(0, Instances::bytes);
        let bounds = match (
            self.bvh.bounds(),
            self.instances.as_ref().and_then(|i| i.tlas.bounds()),
        ) {
            (Some(a), Some(b)) => Some(a.union(&b)),
            (a, b) => a.or(b),
        };
        bounds.filter(|_| footprint > ray_batches::SORT_ABOVE_BYTES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::leaf_prims::{FlatPrimitives, node_triangles};
    use crate::accel::reference;
    use crate::geometry::TriangleGeom;
    use crate::math::rng::{path_key, uniform};
    use crate::math::{Affine3A, Vec3};
    use crate::scene::{Camera, Material, Mesh, Sphere, Transform};

    /// `triangles` random triangles of edges up to `size` and `spheres` spheres in a 10-unit
    /// cube.
    fn random_scene(triangles: u32, spheres: u32, size: f32) -> RenderScene {
        let u = |i: u32, d: u32| uniform(path_key(3, i, 0), 0, d);
        let mut world = hecs::World::new();
        world.spawn((Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Z, 1.0),));
        let mut mesh = Mesh::default();
        for i in 0..triangles {
            let c = Vec3::new(u(i, 0), u(i, 1), u(i, 2)) * 10.0;
            let e = |d| (Vec3::new(u(i, d), u(i, d + 1), u(i, d + 2)) - 0.5) * size;
            mesh.indices
                .push([0, 1, 2].map(|k| mesh.positions.len() as u32 + k));
            mesh.positions.extend([c, c + e(3), c + e(6)]);
        }
        let white = Material::Lambertian {
            albedo: Vec3::splat(0.5),
        };
        world.spawn((mesh, white));
        for i in 0..spheres {
            let centre = Vec3::new(u(i, 9), u(i, 10), u(i, 11)) * 10.0;
            world.spawn((
                Sphere { radius: 0.4 * size },
                Transform(Affine3A::from_translation(centre)),
                white,
            ));
        }
        crate::flatten(&world, std::path::Path::new(".")).expect("a valid scene")
    }

    #[test]
    fn batch_answers_are_the_one_ray_answers_in_the_callers_order() {
        // Far past the smallest scenes' flat test, so the queries walk the tree.
        let scene = random_scene(5000, 20, 1.0);
        let rays: Vec<Ray> = (0..20_000)
            .map(|i| {
                let u = |d: u32| uniform(path_key(4, i, 0), 0, d);
                Ray {
                    origin: Vec3A::new(u(0), u(1), u(2)) * 12.0 - 1.0,
                    direction: (Vec3A::new(u(3), u(4), u(5)) - 0.5).normalize(),
                    t_max: if i % 2 == 0 {
                        f32::INFINITY
                    } else {
                        4.0 * u(6)
                    },
                }
            })
            .collect();
        // The scene is too small for the public queries to sort, so the sorted path is
        // called as they would call it in a large scene, and compared with them.
        assert!(scene.sort_bounds().is_none());
        let sorted_closest =
            ray_batches::in_coherent_order(&rays, scene.bvh.bounds(), |stack, ray| {
                scene.closest_hit(stack, ray.origin, ray.direction, ray.t_max)
            });
        let sorted_occluded =
            ray_batches::in_coherent_order(&rays, scene.bvh.bounds(), |stack, ray| {
                scene.occluded(stack, ray.origin, ray.direction, ray.t_max)
            });
        let (closest, occluded) = (scene.closest_hits(&rays), scene.occlusions(&rays));
        let mut stack = TraversalStack::default();
        let mut hits = 0;
        for (i, ray) in rays.iter().enumerate() {
            let one = scene.closest_hit(&mut stack, ray.origin, ray.direction, ray.t_max);
            assert_eq!(closest[i], one, "ray {i}");
            assert_eq!(sorted_closest[i], one, "ray {i}");
            let blocked = scene.occluded(&mut stack, ray.origin, ray.direction, ray.t_max);
            assert_eq!(occluded[i], blocked, "ray {i}");
            assert_eq!(sorted_occluded[i], blocked, "ray {i}");
            hits += usize::from(one.is_some());
        }
        // Both answers must occur often for the comparison to mean something.
        assert!((4_000..16_000).contains(&hits), "{hits} hits");
    }

    /// Every closest-hit path the scene allows (the chosen one among them).
    fn allowed_paths(scene: &RenderScene) -> Vec<ClosestHitPath> {
        let prims = &scene.leaf_prims;
        let quads = node_triangles(prims, &scene.bvh);
        let mut paths = vec![ClosestHitPath::Leaves];
        if !quads.is_empty() {
            paths.push(ClosestHitPath::NodeTriangles(quads));
        }
        paths.extend(FlatPrimitives::new(prims).map(ClosestHitPath::Flat));
        paths
    }

    /// Ray `i` of random set `set`: from anywhere around the 10-unit cube, unbounded or with
    /// a random length.
    fn random_ray(set: u64, i: u32) -> (Vec3A, Vec3A, f32) {
        let u = |d: u32| uniform(path_key(set, i, 0), 0, d);
        let origin = Vec3A::new(u(0), u(1), u(2)) * 12.0 - 1.0;
        let direction = (Vec3A::new(u(3), u(4), u(5)) - 0.5).normalize();
        let t_max = if i.is_multiple_of(2) {
            f32::INFINITY
        } else {
            6.0 * u(6)
        };
        (origin, direction, t_max)
    }

    #[test]
    fn every_closest_hit_path_agrees_with_the_reference() {
        // 40 primitives allow all three paths, 2,020 (leaves of one) the two tree paths, and
        // 6,040 (leaves of up to four) the leaf path alone.
        for (triangles, spheres, size, path_count) in
            [(36, 4, 4.0, 3), (2000, 20, 1.0, 2), (6000, 40, 1.0, 1)]
        {
            let mut scene = random_scene(triangles, spheres, size);
            let paths = allowed_paths(&scene);
            assert_eq!(paths.len(), path_count, "{triangles} triangles");
            for path in paths {
                scene.closest_hit_path = path;
                let mut stack = TraversalStack::default();
                let mut hits = 0;
                for i in 0..3000 {
                    let (origin, mut direction, t_max) = random_ray(21, i);
                    if i % 2 == 0 {
                        // Aimed near a primitive, so that many rays hit one.
                        let target = match scene.shape(i as usize / 2 % scene.primitive_count()) {
                            Shape::Triangle(t) => t.v0 + (t.e1 + t.e2) * 0.3,
                            Shape::Sphere(s) => s.center,
                        };
                        direction = (target - origin + 0.05 * direction).normalize();
                    }
                    let expected = reference::closest_hit(scene.shapes(), origin, direction, t_max);
                    let found = scene.closest_hit(&mut stack, origin, direction, t_max);
                    assert_eq!(found, expected, "{triangles} triangles, ray {i}");
                    let blocked = scene.occluded(&mut stack, origin, direction, t_max);
                    assert_eq!(
                        blocked,
                        expected.is_some(),
                        "{triangles} triangles, ray {i}"
                    );
                    hits += u32::from(expected.is_some());
                }
                assert!(hits > 1000, "{triangles} triangles: only {hits} hits");
            }
        }
    }

    /// Random shadow packet `i` from the random streams `stream` and `stream + 1`: an origin
    /// in the 10-unit cube and 1 to `PACKET_SIZE` rays toward points around a common target,
    /// each ending there.
    fn random_packet(
        i: u32,
        stream: u64,
    ) -> (Vec3A, usize, [Vec3A; PACKET_SIZE], [f32; PACKET_SIZE]) {
        let u = |d: u32| uniform(path_key(stream, i, 0), 0, d);
        let origin = Vec3A::new(u(0), u(1), u(2)) * 10.0;
        let target = Vec3A::new(u(3), u(4), u(5)) * 10.0;
        let n = 1 + i as usize % PACKET_SIZE;
        let (mut directions, mut t_max) = ([Vec3A::ZERO; PACKET_SIZE], [0.0; PACKET_SIZE]);
        for k in 0..n {
            let v = |d: u32| uniform(path_key(stream + 1, i, k as u32), 0, d) - 0.5;
            let to = target + 2.0 * Vec3A::new(v(0), v(1), v(2)) - origin;
            (directions[k], t_max[k]) = (to.normalize(), to.length());
        }
        (origin, n, directions, t_max)
    }

    #[test]
    fn shadow_packets_agree_with_the_reference_over_the_shadow_tree() {
        for (triangles, spheres, size) in [(36, 4, 4.0), (2000, 20, 1.0), (6000, 40, 1.0)] {
            let scene = random_scene(triangles, spheres, size);
            // The primitives the packets are traced against (the occluders, when some
            // triangles bound the scene: `occluders` tests that choice).
            let shapes: Vec<Shape> = match &scene.occluders {
                Some(o) => o.leaf_prims.iter().map(LeafPrim::shape).collect(),
                None => scene.shapes().collect(),
            };
            let mut stack = TraversalStack::default();
            let (mut blocked, mut open) = (0, 0);
            for i in 0..400 {
                let (origin, n, directions, t_max) = random_packet(i, 22);
                let packet = Packet::new(origin, &directions[..n], &t_max[..n]);
                let occluded = scene.occluded_packet(&mut stack, &packet);
                for k in 0..n {
                    let expected =
                        reference::any_hit(shapes.iter().copied(), origin, directions[k], t_max[k]);
                    assert_eq!(
                        occluded >> k & 1 == 1,
                        expected,
                        "{triangles}: packet {i}, ray {k}"
                    );
                    if expected { blocked += 1 } else { open += 1 }
                }
            }
            assert!(
                blocked > 200 && open > 200,
                "{triangles}: {blocked} blocked, {open} open"
            );
        }
    }

    /// A scene with instanced meshes: `flat` random triangles and a few spheres in the flat
    /// part, and a shared mesh of 300 random triangles drawn by six instances (translated,
    /// turned, scaled non-uniformly, mirrored), all in the 10-unit cube.
    fn instanced_scene(flat: u32) -> RenderScene {
        let world = instanced_world(flat);
        let path = std::path::Path::new(".");
        crate::flatten_with(&world, path, crate::flatten::Instancing::Always).expect("valid")
    }

    /// The world of [`instanced_scene`].
    fn instanced_world(flat: u32) -> hecs::World {
        use crate::math::Quat;
        use crate::scene::SharedMesh;
        let mut world = hecs::World::new();
        world.spawn((Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Z, 1.0),));
        let white = Material::Lambertian {
            albedo: Vec3::splat(0.5),
        };
        let random_mesh = |set: u64, n: u32, size: f32, extent: f32| {
            let u = |i: u32, d: u32| uniform(path_key(set, i, 0), 0, d);
            let mut mesh = Mesh::default();
            for i in 0..n {
                let c = (Vec3::new(u(i, 0), u(i, 1), u(i, 2)) - 0.5) * extent;
                let e = |d| (Vec3::new(u(i, d), u(i, d + 1), u(i, d + 2)) - 0.5) * size;
                mesh.indices
                    .push([0, 1, 2].map(|k| mesh.positions.len() as u32 + k));
                mesh.positions.extend([c, c + e(3), c + e(6)]);
                // Shading normals, so that their transform is checked too.
                mesh.normals
                    .extend([9, 12, 15].map(|d| (e(d) + Vec3::splat(0.1)).normalize()));
            }
            mesh
        };
        world.spawn((random_mesh(31, flat, 1.0, 10.0), white));
        let shared = SharedMesh(std::sync::Arc::new(random_mesh(32, 300, 0.8, 3.0)));
        let placements = [
            Affine3A::from_translation(Vec3::new(2.0, 2.0, 2.0)),
            Affine3A::from_rotation_translation(
                Quat::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.9),
                Vec3::new(7.0, 3.0, 5.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(1.5, 0.4, 0.9),
                Quat::from_rotation_z(0.6),
                Vec3::new(3.0, 7.0, 7.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(-1.0, 1.0, 1.2),
                Quat::from_rotation_x(0.3),
                Vec3::new(7.0, 7.0, 2.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(0.5, 0.5, 0.5),
                Quat::IDENTITY,
                Vec3::new(5.0, 5.0, 5.0),
            ),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(-0.7, -1.1, 0.6),
                Quat::from_rotation_y(1.2),
                Vec3::new(2.0, 8.0, 8.0),
            ),
        ];
        for m in placements {
            world.spawn((shared.clone(), Transform(m), white));
        }
        for i in 0..4 {
            let u = |d: u32| uniform(path_key(33, i, 0), 0, d);
            world.spawn((
                Sphere { radius: 0.5 },
                Transform(Affine3A::from_translation(
                    Vec3::new(u(0), u(1), u(2)) * 10.0,
                )),
                white,
            ));
        }
        world
    }

    #[test]
    fn instanced_hits_and_occlusion_agree_with_the_brute_force_reference() {
        // 40 flat primitives (the flat layout), 2,004 (one per leaf), 6,004 (leaves of four):
        // every flat path combined with the instances.
        for flat in [36, 2000, 6000] {
            let scene = instanced_scene(flat);
            let instances = scene.instances.as_ref().expect("instanced");
            assert_eq!(instances.instances.len(), 6);
            assert_eq!(scene.primitive_count(), flat as usize + 4 + 6 * 300);
            let flat_shapes = || scene.leaf_prims.iter().map(LeafPrim::shape);
            let mut stack = TraversalStack::default();
            let (mut instanced_hits, mut hits) = (0, 0);
            for i in 0..4000 {
                let (origin, mut direction, t_max) = random_ray(24, i);
                if i % 2 == 0 {
                    // Aimed near a primitive (most of them instanced).
                    let slot = (i as usize * 7919) % scene.primitive_count();
                    let target = match scene.shape(slot) {
                        Shape::Triangle(t) => t.v0 + (t.e1 + t.e2) * 0.3,
                        Shape::Sphere(s) => s.center,
                    };
                    direction = (target - origin + 0.05 * direction).normalize();
                }
                let expected = reference::closest_hit_instanced(
                    flat_shapes(),
                    instances,
                    origin,
                    direction,
                    t_max,
                );
                let found = scene.closest_hit(&mut stack, origin, direction, t_max);
                assert_eq!(found, expected, "{flat} flat, ray {i}");
                let blocked = scene.occluded(&mut stack, origin, direction, t_max);
                assert_eq!(blocked, expected.is_some(), "{flat} flat, ray {i}");
                hits += u32::from(expected.is_some());
                instanced_hits +=
                    u32::from(expected.is_some_and(|(s, _)| s as usize >= scene.leaf_prims.len()));
            }
            assert!(
                hits > 1500 && instanced_hits > 500,
                "{flat}: {hits} hits, {instanced_hits} on instances"
            );
        }
    }

    #[test]
    fn instanced_shadow_packets_agree_with_the_brute_force_reference() {
        let scene = instanced_scene(2000);
        let instances = scene.instances.as_ref().expect("instanced");
        let flat_shapes = || scene.leaf_prims.iter().map(LeafPrim::shape);
        let mut stack = TraversalStack::default();
        let (mut blocked, mut open) = (0, 0);
        for i in 0..400 {
            let (origin, n, directions, t_max) = random_packet(i, 25);
            let packet = Packet::new(origin, &directions[..n], &t_max[..n]);
            let occluded = scene.occluded_packet(&mut stack, &packet);
            assert_eq!(occluded >> n, 0, "packet {i}: bits past the packet");
            for k in 0..n {
                let expected = reference::closest_hit_instanced(
                    flat_shapes(),
                    instances,
                    origin,
                    directions[k],
                    t_max[k],
                )
                .is_some();
                assert_eq!(occluded >> k & 1 == 1, expected, "packet {i}, ray {k}");
                if expected { blocked += 1 } else { open += 1 }
            }
        }
        assert!(
            blocked > 200 && open > 200,
            "{blocked} blocked, {open} open"
        );
    }

    #[test]
    fn instanced_triangles_are_the_flattened_ones_with_their_front_sides() {
        // The same world flattened into one BVH: every instanced triangle (world space, as
        // shading sees it) is a flattened triangle, with the same geometric normal (the
        // mirrored instances' winding reversed as the flattener reverses it) and the same
        // vertex normals in the same corner order (rounding aside).
        let world = instanced_world(36);
        let path = std::path::Path::new(".");
        let instanced =
            crate::flatten_with(&world, path, crate::flatten::Instancing::Always).expect("valid");
        let flat =
            crate::flatten_with(&world, path, crate::flatten::Instancing::Never).expect("valid");
        assert!(flat.instances.is_none());
        assert_eq!(flat.primitive_count(), instanced.primitive_count());
        let first_instanced = instanced.leaf_prims.len();
        let flat_triangles: Vec<(usize, TriangleGeom)> = (0..flat.primitive_count())
            .filter_map(|slot| match flat.shape(slot) {
                Shape::Triangle(t) => Some((slot, t)),
                Shape::Sphere(_) => None,
            })
            .collect();
        let close = |a: Vec3A, b: Vec3A| (a - b).length() < 1e-4;
        for slot in first_instanced..instanced.primitive_count() {
            let Shape::Triangle(t) = instanced.shape(slot) else {
                panic!("instanced spheres")
            };
            let &(twin, f) = flat_triangles
                .iter()
                .find(|(_, f)| close(f.v0, t.v0) && close(f.e1, t.e1) && close(f.e2, t.e2))
                .unwrap_or_else(|| panic!("slot {slot}: no flattened twin"));
            let n = t.normal_unnormalized().normalize();
            assert!(
                n.dot(f.normal_unnormalized().normalize()) > 0.9999,
                "slot {slot}"
            );
            let (a, b) = (instanced.vertex_normals(slot), flat.vertex_normals(twin));
            for k in 0..3 {
                assert!((a[k] - b[k]).length() < 1e-4, "slot {slot}, corner {k}");
            }
            assert_eq!(instanced.material_of(slot), flat.material_of(twin));
        }
    }
}
