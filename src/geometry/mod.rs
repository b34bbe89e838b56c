//! Shapes: what a primitive is ([`Shape`]: a triangle or an analytic sphere), with each
//! shape's bounds and ray intersection; the geometry of each kind lives in its own file.

pub mod sphere;
pub mod triangle;

use crate::math::Vec3A;
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
