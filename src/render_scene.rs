//! The render scene: what the wavefront stages read, built once by [`crate::flatten()`] and
//! immutable after. World-space primitives in BVH slot order (the slot indexes every
//! per-primitive column), the material and light tables, the accelerators of [`crate::accel`],
//! and the whole query API the stages and ray-casting clients use: closest hit, occlusion,
//! shadow packets and ray batches.

use crate::accel::ClosestHitPath;
use crate::accel::build::Bvh4;
use crate::accel::leaf_prims::{LeafPrim, closest_in_leaf, closest_in_node};
use crate::accel::occluders::Occluders;
use crate::accel::ray_batches;
use crate::alpha::{AlphaRecord, RayKey};
use crate::bsdf::Bsdf;
use crate::flatten::FlattenTimes;
use crate::geometry::Shape;
use crate::geometry::sphere::intersect_sphere;
use crate::geometry::triangle::{OriginTerms, intersect_triangle_from};
use crate::lights::LightTable;
use crate::math::{Rgb, Vec2, Vec3, Vec3A, Vec4};
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
    pub(crate) leaf_prims: Vec<LeafPrim>,
    /// How the closest-hit query runs: which of the fast layouts it reads (chosen once, by
    /// [`ClosestHitPath::choose`]).
    pub(crate) closest_hit_path: ClosestHitPath,
    /// Per-vertex shading normals per slot (unit, world space); all zero for flat shading
    /// and for spheres.
    #[doc(hidden)]
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Texture coordinates of the three vertices per slot (zero when the mesh has none);
    /// read only for textured materials.
    pub(crate) vertex_uvs: Vec<[Vec2; 3]>,
    /// Tangents of the three vertices per slot (world space, `w` = handedness, see
    /// [`VertexTangents`]); empty unless some material has a normal map.
    pub(crate) vertex_tangents: Vec<[Vec4; 3]>,
    /// Linear RGBA colours of the three vertices per slot (white where the mesh has none,
    /// see [`VertexColors`](crate::scene::VertexColors)); empty unless some mesh has them.
    pub(crate) vertex_colors: Vec<[Vec4; 3]>,
    /// Per slot, its index into `alpha_records`, or [`crate::alpha::OPAQUE`]; empty when
    /// every primitive is opaque.
    pub(crate) alpha_of_slot: Vec<u32>,
    /// How the alpha-tested meshes are covered.
    pub(crate) alpha_records: Vec<AlphaRecord>,
    /// Material index per slot, into `materials`.
    pub(crate) material: Vec<u32>,
    /// Light index per slot, into `lights.lights`, or [`NO_EMITTER`].
    pub(crate) emitter: Vec<u32>,
    /// Distinct materials.
    #[doc(hidden)]
    pub materials: Vec<Bsdf>,
    /// Absorption coefficient of the medium inside each material (`KHR_materials_volume`),
    /// by material index; empty when no material absorbs.
    pub(crate) material_absorption: Vec<Rgb>,
    /// Textures per material, looked up at the hit's texture coordinates.
    #[doc(hidden)]
    pub material_textures: Vec<SurfaceTextures>,
    /// Distinct textures.
    #[doc(hidden)]
    pub textures: Vec<Arc<Texture>>,
    /// Emitting primitives, punctual lights and the environment.
    #[doc(hidden)]
    pub lights: LightTable,
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

    /// Number of primitives (BVH slots).
    pub fn primitive_count(&self) -> usize {
        self.leaf_prims.len()
    }

    /// The index in flattening order of the primitive in slot `slot` (see
    /// [`crate::flatten()`]), to map hits back to the input.
    pub fn source_index(&self, slot: usize) -> u32 {
        self.source_index[slot]
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
    pub fn textures(&self) -> &[Arc<Texture>] {
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

    /// Per-vertex shading normals of the primitive in slot `slot` (all zero when flat).
    pub fn vertex_normals(&self, slot: usize) -> [Vec3; 3] {
        self.vertex_normals[slot]
    }

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
    /// that do not cover the point (see [`crate::alpha`]) are passed through.
    #[inline]
    pub(crate) fn closest_covered_hit(
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
                                && (alpha[slot as usize] == crate::alpha::OPAQUE
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
        let prims = &self.leaf_prims;
        if !self.alpha_of_slot.is_empty() {
            let key = RayKey::default();
            return self
                .bvh
                .any_hit(stack, origin, direction, t_max, |slot, t_max| {
                    let t = prims[slot as usize].hit_t(origin, direction, t_max);
                    let covered = t == f32::INFINITY
                        || self.alpha_of_slot[slot as usize] == crate::alpha::OPAQUE
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
        if self.alpha_of_slot.is_empty() {
            self.occluded_packet_walk::<false>(stack, packet, key)
        } else {
            self.occluded_packet_walk::<true>(stack, packet, key)
        }
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
            if ALPHA && blocked != 0 && self.alpha_of_slot[slot as usize] != crate::alpha::OPAQUE {
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
            + std::mem::size_of_val(&self.bvh.nodes[..]);
        self.bvh
            .bounds()
            .filter(|_| footprint > ray_batches::SORT_ABOVE_BYTES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::leaf_prims::{FlatPrimitives, node_triangles};
    use crate::accel::reference;
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
                let u = |d: u32| uniform(path_key(22, i, 0), 0, d);
                let origin = Vec3A::new(u(0), u(1), u(2)) * 10.0;
                let target = Vec3A::new(u(3), u(4), u(5)) * 10.0;
                let n = 1 + i as usize % PACKET_SIZE;
                let (mut directions, mut t_max) = ([Vec3A::ZERO; PACKET_SIZE], [0.0; PACKET_SIZE]);
                for k in 0..n {
                    let v = |d: u32| uniform(path_key(23, i, k as u32), 0, d) - 0.5;
                    let to = target + 2.0 * Vec3A::new(v(0), v(1), v(2)) - origin;
                    (directions[k], t_max[k]) = (to.normalize(), to.length());
                }
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
}
