//! Analytic spheres: geometry and a numerically robust ray-sphere test.

use crate::math::Vec3A;

/// A world-space sphere.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SphereGeom {
    /// Centre.
    pub center: Vec3A,
    /// Radius (> 0).
    pub radius: f32,
}

impl SphereGeom {
    /// Surface area.
    #[inline]
    pub fn area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }

    /// Projects a point near the surface onto it (removes most of the error of `o + t d`), and
    /// returns it with its outward normal.
    #[inline]
    pub fn project(&self, p: Vec3A) -> (Vec3A, Vec3A) {
        let n = (p - self.center).normalize();
        (self.center + self.radius * n, n)
    }

    /// Bound on the rounding error of a projected point, per component (pbrt: gamma(5) |p|,
    /// with a factor 2 of margin).
    #[inline]
    pub fn point_error(p: Vec3A) -> Vec3A {
        const GAMMA_5: f32 = 5.0 * f32::EPSILON * 0.5 / (1.0 - 5.0 * f32::EPSILON * 0.5);
        2.0 * GAMMA_5 * p.abs()
    }
}

/// Nearest intersection distance in `(tmin, tmax]`, from outside or inside.
///
/// Uses the formulation of "Precision Improvements for Ray/Sphere Intersection" (Ray Tracing
/// Gems, ch. 7): the discriminant from the distance of the centre to the ray, and the
/// smaller root from Vieta's formula, so neither root suffers from cancellation.
#[inline(always)]
pub fn intersect_sphere(
    s: &SphereGeom,
    origin: Vec3A,
    direction: Vec3A,
    tmin: f32,
    tmax: f32,
) -> Option<f32> {
    let f = origin - s.center;
    let a = direction.length_squared();
    let b = -f.dot(direction); // half of the usual -b
    let c = f.length_squared() - s.radius * s.radius;
    let l = f + (b / a) * direction; // from the centre to the closest point on the line
    let discriminant = a * (s.radius * s.radius - l.length_squared());
    if discriminant < 0.0 {
        return None;
    }
    let q = b + b.signum() * discriminant.sqrt();
    let (mut t0, mut t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q / a) };
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    if t0 > tmin && t0 <= tmax {
        Some(t0)
    } else if t1 > tmin && t1 <= tmax {
        Some(t1)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: SphereGeom = SphereGeom {
        center: Vec3A::new(0.0, 0.0, 5.0),
        radius: 1.0,
    };

    #[test]
    fn from_outside_hits_the_near_side() {
        let t = intersect_sphere(&S, Vec3A::ZERO, Vec3A::Z, 0.0, f32::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-6);
        assert!(
            intersect_sphere(&S, Vec3A::ZERO, Vec3A::Z, 0.0, 3.9).is_none(),
            "beyond tmax"
        );
    }

    #[test]
    fn from_inside_hits_the_far_side() {
        let t =
            intersect_sphere(&S, Vec3A::new(0.0, 0.0, 5.0), Vec3A::X, 0.0, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        // Just inside the surface, leaving through it: the far side, not the start point.
        let (p, n) = S.project(Vec3A::new(0.0, 0.0, 4.0));
        let inside = p - n * 1e-4;
        let t = intersect_sphere(&S, inside, Vec3A::Z, 0.0, f32::INFINITY).unwrap();
        assert!((t - 2.0).abs() < 1e-3, "{t}");
    }

    #[test]
    fn tangent_and_grazing_rays() {
        // Tangent at x = 1: touches once (the double root).
        let t =
            intersect_sphere(&S, Vec3A::new(1.0, 0.0, 0.0), Vec3A::Z, 0.0, f32::INFINITY).unwrap();
        assert!((t - 5.0).abs() < 1e-2, "{t}");
        assert!(
            intersect_sphere(
                &S,
                Vec3A::new(1.001, 0.0, 0.0),
                Vec3A::Z,
                0.0,
                f32::INFINITY
            )
            .is_none()
        );
    }

    #[test]
    fn sphere_behind_the_origin_is_missed() {
        assert!(
            intersect_sphere(&S, Vec3A::new(0.0, 0.0, 10.0), Vec3A::Z, 0.0, f32::INFINITY)
                .is_none()
        );
    }

    #[test]
    fn far_away_small_sphere_is_precise() {
        // The naive discriminant loses every digit here; the robust one does not.
        let s = SphereGeom {
            center: Vec3A::new(0.0, 0.0, 1.0e4),
            radius: 0.01,
        };
        let t = intersect_sphere(&s, Vec3A::ZERO, Vec3A::Z, 0.0, f32::INFINITY).unwrap();
        assert!((t - (1.0e4 - 0.01)).abs() < 2e-3, "{t}");
    }
}
