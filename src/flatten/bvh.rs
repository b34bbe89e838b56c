//! The one BVH over all primitives (triangles and analytic spheres together), built with
//! obvhs as a compressed 8-wide BVH, and the two queries the renderer asks of it.

use super::{FlatScene, Shape};
use crate::math::Vec3A;
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use std::time::Duration;

/// Builds the BVH over `shapes` and returns it with the permutation into BVH order:
/// slot `i` of the BVH holds `shapes[order[i]]`.
pub fn build_bvh(shapes: &[Shape]) -> (CwBvh, Vec<u32>) {
    let aabbs: Vec<Aabb> = shapes.iter().map(Shape::aabb).collect();
    // medium_build: about Embree's build time with faster traversal (obvhs docs); measured in benches/.
    let bvh = obvhs::cwbvh::builder::build_cwbvh(
        &aabbs,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let order = bvh.primitive_indices.clone();
    (bvh, order)
}

impl Shape {
    /// World-space bounding box.
    pub fn aabb(&self) -> Aabb {
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

    /// Hit distance in `[tmin, tmax]`, or infinity.
    #[inline(always)]
    pub fn intersect_t(&self, ray: &Ray) -> f32 {
        match self {
            Shape::Triangle(t) => super::triangles::intersect_triangle(
                t,
                ray.origin,
                ray.direction,
                ray.tmin,
                ray.tmax,
            )
            .map_or(f32::INFINITY, |h| h.0),
            Shape::Sphere(s) => {
                super::spheres::intersect_sphere(s, ray.origin, ray.direction, ray.tmin, ray.tmax)
                    .unwrap_or(f32::INFINITY)
            }
        }
    }
}

impl FlatScene {
    /// Closest primitive along the ray within `(0, tmax]`: its BVH slot and distance.
    #[inline]
    pub fn closest_hit(&self, origin: Vec3A, direction: Vec3A, tmax: f32) -> Option<(u32, f32)> {
        let ray = Ray::new(origin, direction, 0.0, tmax);
        let mut hit = RayHit::none();
        let shapes = &self.shapes;
        self.bvh
            .ray_traverse(ray, &mut hit, |ray, slot| shapes[slot].intersect_t(ray))
            .then_some((hit.primitive_id, hit.t))
    }

    /// Whether anything blocks the segment from `origin` to `origin + tmax direction`.
    #[inline]
    pub fn occluded(&self, origin: Vec3A, direction: Vec3A, tmax: f32) -> bool {
        let ray = Ray::new(origin, direction, 0.0, tmax);
        let shapes = &self.shapes;
        !self
            .bvh
            .ray_traverse_miss(ray, |ray, slot| shapes[slot].intersect_t(ray))
    }
}
