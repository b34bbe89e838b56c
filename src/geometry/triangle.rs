//! Triangle geometry in the layout the intersection test wants, and the test itself.

use crate::math::{Vec2, Vec3A};

/// A world-space triangle as stored for intersection: `v0`, `e1 = v1 - v0`, `e2 = v2 - v0`.
/// The front face is the side of `e1 x e2`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TriangleGeom {
    /// First vertex.
    pub v0: Vec3A,
    /// `v1 - v0`.
    pub e1: Vec3A,
    /// `v2 - v0`.
    pub e2: Vec3A,
}

impl TriangleGeom {
    /// From three vertices.
    #[inline]
    pub fn new(v0: Vec3A, v1: Vec3A, v2: Vec3A) -> Self {
        TriangleGeom {
            v0,
            e1: v1 - v0,
            e2: v2 - v0,
        }
    }

    /// The three vertices (`v0 + e1` and `v0 + e2` as rounded, not necessarily the input's).
    #[inline]
    pub fn vertices(&self) -> [Vec3A; 3] {
        [self.v0, self.v0 + self.e1, self.v0 + self.e2]
    }

    /// Unnormalised geometric normal `e1 x e2` (length = twice the area).
    #[inline]
    pub fn normal_unnormalized(&self) -> Vec3A {
        self.e1.cross(self.e2)
    }

    /// Surface area.
    #[inline]
    pub fn area(&self) -> f32 {
        0.5 * self.normal_unnormalized().length()
    }

    /// The point with barycentrics `(u, v)`: `v0 + u e1 + v e2`.
    #[inline]
    pub fn point(&self, uv: Vec2) -> Vec3A {
        self.v0 + uv.x * self.e1 + uv.y * self.e2
    }

    /// Bound on the rounding error of [`Self::point`], per component (after pbrt's analysis,
    /// with a factor 2 of margin).
    #[inline]
    pub fn point_error(&self, uv: Vec2) -> Vec3A {
        const GAMMA_7: f32 = 7.0 * f32::EPSILON * 0.5 / (1.0 - 7.0 * f32::EPSILON * 0.5);
        2.0 * GAMMA_7 * (self.v0.abs() + (uv.x * self.e1).abs() + (uv.y * self.e2).abs())
    }
}

/// Möller-Trumbore ray-triangle test (the form with a precomputed normal, one cross product
/// per test). Two-sided. Returns `(t, u, v)` for `tmin < t <= tmax`, where the hit point is
/// `v0 + u e1 + v e2`; `None` for a miss, a parallel ray or a degenerate triangle.
#[inline(always)]
pub fn intersect_triangle(
    tri: &TriangleGeom,
    origin: Vec3A,
    direction: Vec3A,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, Vec2)> {
    intersect_triangle_from(tri, &OriginTerms::new(tri, origin), direction, tmin, tmax)
}

/// The parts of the triangle test that depend only on the ray origin, shared by all rays of
/// a packet with a common origin.
#[derive(Clone, Copy, Debug)]
pub struct OriginTerms {
    /// Geometric normal `e1 x e2`.
    pub ng: Vec3A,
    /// `v0 - origin`.
    pub c: Vec3A,
    /// `ng . c`.
    pub ng_dot_c: f32,
}

impl OriginTerms {
    /// The terms of `tri` for rays from `origin`.
    #[inline(always)]
    pub fn new(tri: &TriangleGeom, origin: Vec3A) -> Self {
        let ng = tri.e1.cross(tri.e2);
        let c = tri.v0 - origin;
        OriginTerms {
            ng,
            c,
            ng_dot_c: ng.dot(c),
        }
    }
}

/// [`intersect_triangle`] with the origin's terms computed beforehand.
#[inline(always)]
pub fn intersect_triangle_from(
    tri: &TriangleGeom,
    terms: &OriginTerms,
    direction: Vec3A,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, Vec2)> {
    let det = terms.ng.dot(direction);
    if det == 0.0 {
        return None; // parallel to the plane, or degenerate
    }
    let inv_det = 1.0 / det;
    // Distance first: most candidates (walls behind the segment's end, triangles behind the
    // origin) are rejected here, before the barycentric tests.
    let t = terms.ng_dot_c * inv_det;
    if !(t > tmin && t <= tmax) {
        return None;
    }
    let r = direction.cross(terms.c);
    let u = -r.dot(tri.e2) * inv_det;
    let v = r.dot(tri.e1) * inv_det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then_some((t, Vec2::new(u, v)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> TriangleGeom {
        TriangleGeom::new(
            Vec3A::new(0.0, 0.0, 0.0),
            Vec3A::new(1.0, 0.0, 0.0),
            Vec3A::new(0.0, 1.0, 0.0),
        )
    }

    #[test]
    fn hits_front_and_back_faces_with_correct_barycentrics() {
        let t = tri();
        let (d, uv) = intersect_triangle(
            &t,
            Vec3A::new(0.25, 0.5, 2.0),
            -Vec3A::Z,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert!((d - 2.0).abs() < 1e-6 && (uv - Vec2::new(0.25, 0.5)).length() < 1e-6);
        assert!((t.point(uv) - Vec3A::new(0.25, 0.5, 0.0)).length() < 1e-6);
        // Back face: two-sided.
        let (d, _) = intersect_triangle(
            &t,
            Vec3A::new(0.25, 0.5, -3.0),
            Vec3A::Z,
            0.0,
            f32::INFINITY,
        )
        .unwrap();
        assert!((d - 3.0).abs() < 1e-6);
        // Behind the origin, and beyond tmax: no hit.
        assert!(
            intersect_triangle(&t, Vec3A::new(0.25, 0.5, 2.0), Vec3A::Z, 0.0, f32::INFINITY)
                .is_none()
        );
        assert!(intersect_triangle(&t, Vec3A::new(0.25, 0.5, 2.0), -Vec3A::Z, 0.0, 1.9).is_none());
    }

    #[test]
    fn edges_and_vertices_are_hit_and_outside_is_missed() {
        let t = tri();
        for p in [
            (0.5, 0.0),
            (0.0, 0.5),
            (0.5, 0.5),
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
        ] {
            let o = Vec3A::new(p.0, p.1, 1.0);
            assert!(
                intersect_triangle(&t, o, -Vec3A::Z, 0.0, 10.0).is_some(),
                "edge point {p:?}"
            );
        }
        for p in [(0.51, 0.51), (-0.01, 0.5), (0.5, -0.01), (1.01, 0.0)] {
            let o = Vec3A::new(p.0, p.1, 1.0);
            assert!(
                intersect_triangle(&t, o, -Vec3A::Z, 0.0, 10.0).is_none(),
                "outside point {p:?}"
            );
        }
        // Two triangles sharing the diagonal of a quad: a ray through the diagonal hits one.
        let a = TriangleGeom::new(Vec3A::ZERO, Vec3A::X, Vec3A::new(1.0, 1.0, 0.0));
        let b = TriangleGeom::new(Vec3A::ZERO, Vec3A::new(1.0, 1.0, 0.0), Vec3A::Y);
        for i in 1..100 {
            let s = i as f32 / 100.0;
            let o = Vec3A::new(s, s, 1.0);
            let hit = intersect_triangle(&a, o, -Vec3A::Z, 0.0, 10.0).or(intersect_triangle(
                &b,
                o,
                -Vec3A::Z,
                0.0,
                10.0,
            ));
            assert!(hit.is_some(), "gap on the shared edge at {s}");
        }
    }

    #[test]
    fn parallel_rays_and_degenerate_triangles_miss() {
        let t = tri();
        assert!(intersect_triangle(&t, Vec3A::new(-1.0, 0.2, 0.0), Vec3A::X, 0.0, 10.0).is_none());
        assert!(intersect_triangle(&t, Vec3A::new(-1.0, 0.2, 1e-3), Vec3A::X, 0.0, 10.0).is_none());
        let flat = TriangleGeom::new(Vec3A::ZERO, Vec3A::X, 2.0 * Vec3A::X);
        assert!(
            intersect_triangle(&flat, Vec3A::new(0.5, 0.0, 1.0), -Vec3A::Z, 0.0, 10.0).is_none()
        );
    }
}
