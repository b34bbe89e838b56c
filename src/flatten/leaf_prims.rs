//! Primitives laid out for the single-ray traversals' leaf tests: one 64-byte, cache-line
//! aligned record per BVH slot, holding what the test reads and nothing else (a triangle's
//! normal precomputed; no enum to match).
//!
//! The triangle test does the same arithmetic as [`super::triangles::intersect_triangle`],
//! so it returns the same distances bit for bit, but forms all its conditions before one
//! branch: incoherent rays mispredict early exits about as often as not.

use super::Shape;
use super::spheres::{SphereGeom, intersect_sphere};
use crate::math::{Vec3A, Vec4};

/// `w` of a sphere record's first vector (triangles have 0).
const SPHERE_TAG: f32 = 1.0;

/// One primitive for the leaf test.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct LeafPrim {
    /// Triangle: `v0`, `w` = 0. Sphere: centre, `w` = [`SPHERE_TAG`].
    a: Vec4,
    /// Triangle: `e1 = v1 - v0`. Sphere: radius in `x`.
    b: Vec4,
    /// Triangle: `e2 = v2 - v0`.
    c: Vec4,
    /// Triangle: the geometric normal `e1 x e2`.
    d: Vec4,
}

impl LeafPrim {
    /// The record of `shape`.
    pub fn new(shape: &Shape) -> Self {
        match shape {
            Shape::Triangle(t) => LeafPrim {
                a: t.v0.extend(0.0),
                b: t.e1.extend(0.0),
                c: t.e2.extend(0.0),
                d: t.e1.cross(t.e2).extend(0.0),
            },
            Shape::Sphere(s) => LeafPrim {
                a: s.center.extend(SPHERE_TAG),
                b: Vec4::new(s.radius, 0.0, 0.0, 0.0),
                c: Vec4::ZERO,
                d: Vec4::ZERO,
            },
        }
    }

    /// Hit distance in `(0, t_max]`, or infinity.
    #[inline(always)]
    pub fn hit_t(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> f32 {
        if self.a.w == SPHERE_TAG {
            return self.sphere_t(origin, direction, t_max);
        }
        let (v0, e1, e2, ng) = (
            Vec3A::from_vec4(self.a),
            Vec3A::from_vec4(self.b),
            Vec3A::from_vec4(self.c),
            Vec3A::from_vec4(self.d),
        );
        let c = v0 - origin;
        let det = ng.dot(direction);
        let inv_det = 1.0 / det;
        let t = ng.dot(c) * inv_det;
        if !(t > 0.0 && t <= t_max) {
            return f32::INFINITY;
        }
        let r = direction.cross(c);
        let u = -r.dot(e2) * inv_det;
        let v = r.dot(e1) * inv_det;
        // All six conditions in two vector compares, so that the test has no branch
        // (`det != 0` as `|det| > 0`: a NaN determinant fails `t > 0` in both forms).
        let within = Vec4::new(0.0, 0.0, u + v, t).cmple(Vec4::new(u, v, 1.0, t_max));
        let positive = Vec4::ZERO.cmplt(Vec4::new(t, det.abs(), 1.0, 1.0));
        let hit = (within & positive).all();
        if hit { t } else { f32::INFINITY }
    }

    #[cold]
    #[inline(never)]
    fn sphere_t(&self, origin: Vec3A, direction: Vec3A, t_max: f32) -> f32 {
        let sphere = SphereGeom {
            center: Vec3A::from_vec4(self.a),
            radius: self.b.x,
        };
        intersect_sphere(&sphere, origin, direction, 0.0, t_max).unwrap_or(f32::INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flatten::triangles::TriangleGeom;
    use crate::math::rng::{path_key, uniform};

    /// The record gives the same distance as the shape's own test, bit for bit, on random
    /// rays (many of them near edges, parallel or ending near the surface).
    #[test]
    fn records_agree_with_the_shape_tests_exactly() {
        let mut hits = 0;
        for i in 0..20_000 {
            let u = |d: u32| uniform(path_key(11, i, 0), 0, d);
            let p = |d: u32| Vec3A::new(u(d), u(d + 1), u(d + 2)) * 2.0 - 1.0;
            let shape = if i % 5 == 0 {
                Shape::Sphere(SphereGeom {
                    center: p(0),
                    radius: 0.1 + u(3),
                })
            } else if i % 5 == 1 {
                // Degenerate: all three vertices on a line.
                let a = p(0);
                Shape::Triangle(TriangleGeom::new(a, a + p(3), a + 2.0 * p(3)))
            } else {
                Shape::Triangle(TriangleGeom::new(p(0), p(3), p(6)))
            };
            let origin = p(9) * 2.0;
            // Aimed at a point near the shape (inside or just outside a triangle's edges, or
            // of a sphere's outline), so that about half the rays hit.
            let target = match shape {
                Shape::Triangle(t) => {
                    t.v0 + (1.4 * u(12) - 0.2) * t.e1 + (1.4 * u(13) - 0.2) * t.e2
                }
                Shape::Sphere(s) => s.center + 1.2 * s.radius * (p(12) - 0.5),
            };
            let direction = if i % 7 == 0 {
                Vec3A::new(0.0, 0.0, 1.0) // axis-parallel
            } else {
                (target - origin).normalize_or(Vec3A::X)
            };
            let t_max = if i % 2 == 0 {
                f32::INFINITY
            } else {
                3.0 * u(15)
            };
            let expected = shape.intersect_t(origin, direction, t_max);
            let got = LeafPrim::new(&shape).hit_t(origin, direction, t_max);
            assert_eq!(got.to_bits(), expected.to_bits(), "case {i}: {shape:?}");
            hits += (got < f32::INFINITY) as u32;
        }
        assert!(hits > 2000, "enough cases hit: {hits}");
    }

    #[test]
    fn records_are_one_cache_line() {
        assert_eq!(std::mem::size_of::<LeafPrim>(), 64);
        assert_eq!(std::mem::align_of::<LeafPrim>(), 64);
    }
}
