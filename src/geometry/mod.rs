//! Shapes: what a primitive is ([`Shape`]: a triangle or an analytic sphere), with each
//! shape's bounds and ray intersection; the geometry of each kind lives in its own file.

pub mod sphere;
pub mod triangle;

use crate::math::{Vec2, Vec3A};
use obvhs::aabb::Aabb;
pub use sphere::SphereGeom;
pub use triangle::TriangleGeom;

/// The geometry of one primitive, as the intersection test reads it (64 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle.
    Triangle(TriangleGeom),
    /// An analytic sphere.
    Sphere(SphereGeom),
}

/// A point on a primitive's surface, as shading and ray offsets use it.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    /// The point (world space).
    pub p: Vec3A,
    /// Bound on its rounding error, per component.
    pub p_error: Vec3A,
    /// Unit geometric normal (a triangle's front face is the side of `e1 x e2`; a sphere's
    /// normal points out).
    pub ng: Vec3A,
}

impl Shape {
    /// The point of a hit at distance `t` along `origin + t direction`, where the triangle
    /// test found barycentrics `barycentric` (spheres ignore them: their point is the ray's,
    /// projected onto the surface).
    #[inline(always)]
    pub fn surface_point(
        &self,
        origin: Vec3A,
        direction: Vec3A,
        t: f32,
        barycentric: Vec2,
    ) -> SurfacePoint {
        match self {
            Shape::Triangle(tri) => SurfacePoint {
                p: tri.point(barycentric),
                p_error: tri.point_error(barycentric),
                ng: tri.normal_unnormalized().normalize(),
            },
            Shape::Sphere(sphere) => {
                let (p, n) = sphere.project(origin + t * direction);
                SurfacePoint {
                    p,
                    p_error: SphereGeom::point_error(p),
                    ng: n,
                }
            }
        }
    }
}

impl Shape {
    /// The barycentrics of the hit of the ray `origin + t direction` (which hits the shape):
    /// a triangle's `(u, v)`, where the hit point is `v0 + u e1 + v e2`; zero for a sphere,
    /// which has none.
    #[inline(always)]
    pub fn barycentric(&self, origin: Vec3A, direction: Vec3A) -> Vec2 {
        match self {
            Shape::Triangle(tri) => {
                triangle::intersect_triangle(tri, origin, direction, 0.0, f32::INFINITY)
                    .map_or(Vec2::ZERO, |h| h.1)
            }
            Shape::Sphere(_) => Vec2::ZERO,
        }
    }
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
            Shape::Triangle(t) => triangle::intersect_triangle(t, origin, direction, 0.0, t_max)
                .map_or(f32::INFINITY, |h| h.0),
            Shape::Sphere(s) => {
                sphere::intersect_sphere(s, origin, direction, 0.0, t_max).unwrap_or(f32::INFINITY)
            }
        }
    }
}
