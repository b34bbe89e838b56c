//! The GGX (Trowbridge-Reitz) microfacet distribution: normal distribution `D`, the
//! height-correlated Smith masking-shadowing `G2`, and sampling of the visible normals
//! (the spherical-cap construction of Dupuy & Benyoub 2023, which gives the same density as
//! Heitz 2018 with fewer operations) with its density.
//!
//! The free functions are isotropic; [`Ggx`] is the distribution a lobe uses, isotropic (those
//! functions, unchanged) or anisotropic (`KHR_materials_anisotropy`: alpha along a tangent
//! direction and along the bitangent, the same formulas with the roughness stretched per axis).
//! Everything is in the local frame (`+z` = macro normal). Directions are on the upper side:
//! callers flip to `wo`'s side first. Microfacet normals `h` have `h.z > 0`.

use crate::math::{Vec2, Vec3A};
use std::f32::consts::{PI, TAU};

/// Smallest alpha used: below it the lobe is a spike that f32 cannot integrate reliably, so
/// `roughness` 0 means alpha = 1e-3 (roughness ~ 0.032), as in pbrt's "effectively smooth" limit.
pub const MIN_ALPHA: f32 = 1e-3;

/// The GGX alpha of a glTF `roughness` (perceptual): alpha = roughness^2, clamped to [`MIN_ALPHA`].
#[inline]
pub fn alpha_from_roughness(roughness: f32) -> f32 {
    (roughness * roughness).clamp(MIN_ALPHA, 1.0)
}

/// Normal distribution D(h): projected-area density of microfacet normals, so that
/// the integral of D(h) h.z over the hemisphere is 1.
#[inline]
pub fn distribution(alpha: f32, h: Vec3A) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let cos2 = h.z * h.z;
    let denominator = cos2 * (a2 - 1.0) + 1.0;
    a2 / (PI * denominator * denominator)
}

/// Smith's Lambda(w) for GGX: the masking function is 1 / (1 + Lambda).
#[inline]
pub fn lambda(alpha: f32, w: Vec3A) -> f32 {
    let cos2 = w.z * w.z;
    if cos2 == 0.0 {
        return f32::INFINITY;
    }
    let tan2 = ((1.0 - cos2) / cos2).max(0.0);
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// Smith masking G1(w) (uncorrelated with any other direction).
#[inline]
pub fn masking(alpha: f32, w: Vec3A) -> f32 {
    1.0 / (1.0 + lambda(alpha, w))
}

/// Height-correlated Smith masking-shadowing G2(wo, wi) = 1 / (1 + Lambda(wo) + Lambda(wi)).
#[inline]
pub fn masking_shadowing(alpha: f32, wo: Vec3A, wi: Vec3A) -> f32 {
    1.0 / (1.0 + lambda(alpha, wo) + lambda(alpha, wi))
}

/// Samples a microfacet normal visible from `wo` (`wo.z > 0`) with density
/// [`visible_normal_pdf`]. Spherical caps: in the stretched configuration where the
/// distribution is a unit hemisphere, the visible normals are `wo + a point uniform on the
/// spherical cap z > -wo.z`, normalised.
#[inline]
pub fn sample_visible_normal(alpha: f32, wo: Vec3A, u: Vec2) -> Vec3A {
    let wo_std = Vec3A::new(wo.x * alpha, wo.y * alpha, wo.z).normalize();
    let phi = TAU * u.x;
    let z = (1.0 - u.y) * (1.0 + wo_std.z) - wo_std.z;
    let sin_theta = (1.0 - z * z).max(0.0).sqrt();
    let cap = Vec3A::new(sin_theta * phi.cos(), sin_theta * phi.sin(), z);
    let h_std = cap + wo_std;
    Vec3A::new(h_std.x * alpha, h_std.y * alpha, h_std.z.max(0.0)).normalize_or(Vec3A::Z)
}

/// Density (solid angle of `h`) of [`sample_visible_normal`]: G1(wo) max(0, wo.h) D(h) / wo.z.
#[inline]
pub fn visible_normal_pdf(alpha: f32, wo: Vec3A, h: Vec3A) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    masking(alpha, wo) * wo.dot(h).max(0.0) * distribution(alpha, h) / wo.z
}

/// The GGX distribution of one lobe: one alpha (the free functions above), or an alpha along
/// a tangent direction and another along the bitangent. The choice is the material's, made
/// once where its parameters are set; isotropic lobes run exactly the isotropic functions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Ggx {
    /// The same alpha in every direction.
    Isotropic(f32),
    /// `alpha.x` along `tangent`, `alpha.y` along the bitangent (`+z` x tangent).
    Anisotropic {
        /// Alpha along the tangent and along the bitangent.
        alpha: Vec2,
        /// The tangent in the local frame: unit `(cos, sin)` of its angle from `+x`.
        tangent: Vec2,
    },
}

impl Ggx {
    /// `w` in the anisotropic lobe's own frame (`+x` along the tangent).
    #[inline]
    fn to_tangent_frame(tangent: Vec2, w: Vec3A) -> Vec3A {
        Vec3A::new(
            tangent.x * w.x + tangent.y * w.y,
            tangent.x * w.y - tangent.y * w.x,
            w.z,
        )
    }

    /// Normal distribution D(h) (projected area density, as [`distribution`]).
    #[inline]
    pub fn distribution(self, h: Vec3A) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => distribution(alpha, h),
            Ggx::Anisotropic { alpha, tangent } => {
                if h.z <= 0.0 {
                    return 0.0;
                }
                let h = Self::to_tangent_frame(tangent, h);
                let (x, y) = (h.x / alpha.x, h.y / alpha.y);
                let denominator = x * x + y * y + h.z * h.z;
                1.0 / (PI * alpha.x * alpha.y * denominator * denominator)
            }
        }
    }

    /// Smith's Lambda(w): the projected roughness toward `w` replaces the single alpha.
    #[inline]
    pub fn lambda(self, w: Vec3A) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => lambda(alpha, w),
            Ggx::Anisotropic { alpha, tangent } => {
                let cos2 = w.z * w.z;
                if cos2 == 0.0 {
                    return f32::INFINITY;
                }
                let w = Self::to_tangent_frame(tangent, w);
                let (x, y) = (w.x * alpha.x, w.y * alpha.y);
                0.5 * ((1.0 + (x * x + y * y) / cos2).sqrt() - 1.0)
            }
        }
    }

    /// Height-correlated Smith masking-shadowing G2(wo, wi).
    #[inline]
    pub fn masking_shadowing(self, wo: Vec3A, wi: Vec3A) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => masking_shadowing(alpha, wo, wi),
            _ => 1.0 / (1.0 + self.lambda(wo) + self.lambda(wi)),
        }
    }

    /// Samples a microfacet normal visible from `wo` ([`sample_visible_normal`], stretched
    /// by each axis's alpha in the tangent frame).
    #[inline]
    pub fn sample_visible_normal(self, wo: Vec3A, u: Vec2) -> Vec3A {
        match self {
            Ggx::Isotropic(alpha) => sample_visible_normal(alpha, wo, u),
            Ggx::Anisotropic { alpha, tangent } => {
                let w = Self::to_tangent_frame(tangent, wo);
                let wo_std = Vec3A::new(w.x * alpha.x, w.y * alpha.y, w.z).normalize();
                let phi = TAU * u.x;
                let z = (1.0 - u.y) * (1.0 + wo_std.z) - wo_std.z;
                let sin_theta = (1.0 - z * z).max(0.0).sqrt();
                let cap = Vec3A::new(sin_theta * phi.cos(), sin_theta * phi.sin(), z);
                let h_std = cap + wo_std;
                let h = Vec3A::new(h_std.x * alpha.x, h_std.y * alpha.y, h_std.z.max(0.0))
                    .normalize_or(Vec3A::Z);
                // Back to the local frame: the inverse rotation.
                Vec3A::new(
                    tangent.x * h.x - tangent.y * h.y,
                    tangent.y * h.x + tangent.x * h.y,
                    h.z,
                )
            }
        }
    }

    /// Density of [`Ggx::sample_visible_normal`]: G1(wo) max(0, wo.h) D(h) / wo.z.
    #[inline]
    pub fn visible_normal_pdf(self, wo: Vec3A, h: Vec3A) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => visible_normal_pdf(alpha, wo, h),
            _ => {
                if wo.z <= 0.0 {
                    return 0.0;
                }
                wo.dot(h).max(0.0) * self.distribution(h) / ((1.0 + self.lambda(wo)) * wo.z)
            }
        }
    }

    /// The single alpha whose albedo table stands for this lobe in the energy compensation:
    /// the geometric mean `sqrt(alpha_x alpha_y)` for an anisotropic lobe, as Cycles' does.
    #[inline]
    pub fn equivalent_alpha(self) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => alpha,
            Ggx::Anisotropic { alpha, .. } => (alpha.x * alpha.y).sqrt(),
        }
    }

    /// The alpha whose albedo table compensates this lobe's rough glass: the smaller of an
    /// anisotropic lobe's two, whose isotropic lobe loses no more energy than the anisotropic
    /// one, so the compensated glass never gains energy (the geometric mean over-compensated
    /// the glass by 1.8% at roughness 1 from inside). Isotropic: its alpha.
    #[inline]
    pub fn glass_alpha(self) -> f32 {
        match self {
            Ggx::Isotropic(alpha) => alpha,
            Ggx::Anisotropic { alpha, .. } => alpha.x.min(alpha.y),
        }
    }
}

/// Reflects `wo` about the microfacet normal `h`.
#[inline]
pub fn reflect_about(wo: Vec3A, h: Vec3A) -> Vec3A {
    2.0 * wo.dot(h) * h - wo
}

/// Refracts `wo` through the microfacet with normal `h` (on `wo`'s side, `wo.h > 0`) into a
/// medium of relative index `eta` (transmitted over incident). `None` on total internal reflection.
#[inline]
pub fn refract_about(wo: Vec3A, h: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = wo.dot(h);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-wo / eta + (cos_i / eta - cos_t) * h).normalize())
}

/// Generalised half vector of a refraction pair (Walter et al. 2007), on the `+z` side:
/// `wo` in the medium of index 1, `wi` in the medium of relative index `eta`.
#[inline]
pub fn refraction_half_vector(wo: Vec3A, wi: Vec3A, eta: f32) -> Vec3A {
    let h = (wo + eta * wi).normalize_or(Vec3A::Z);
    if h.z < 0.0 { -h } else { h }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn direction(theta: f32, phi: f32) -> Vec3A {
        Vec3A::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        )
    }

    #[test]
    fn distribution_projects_to_unit_area() {
        // The integral of D(h) cos(theta_h) over the hemisphere is 1 (midpoint rule in theta, phi;
        // D is isotropic so phi is exact). Fine theta steps so that alpha 0.04 is resolved.
        for alpha in [0.04f32, 0.25, 0.6, 1.0] {
            let n = 200_000;
            let d_theta = std::f64::consts::FRAC_PI_2 / n as f64;
            let mut total = 0.0f64;
            for i in 0..n {
                let theta = (i as f64 + 0.5) * d_theta;
                let h = direction(theta as f32, 0.0);
                total += distribution(alpha, h) as f64
                    * theta.cos()
                    * theta.sin()
                    * d_theta
                    * std::f64::consts::TAU;
            }
            assert!((total - 1.0).abs() < 1e-3, "alpha {alpha}: {total}");
        }
    }

    #[test]
    fn visible_normals_are_normalised_and_sampled_on_the_visible_side() {
        // The visible-normal density integrates to 1 over h, and samples face wo.
        for alpha in [0.1f32, 0.5, 1.0] {
            for theta_o in [0.0f32, 0.7, 1.4] {
                let wo = direction(theta_o, 0.3);
                let (nt, np) = (2000, 400);
                let mut total = 0.0f64;
                for i in 0..nt {
                    let theta = (i as f32 + 0.5) / nt as f32 * std::f32::consts::FRAC_PI_2;
                    for j in 0..np {
                        let phi = (j as f32 + 0.5) / np as f32 * TAU;
                        let h = direction(theta, phi);
                        total += (visible_normal_pdf(alpha, wo, h) * theta.sin()) as f64;
                    }
                }
                total *= (std::f32::consts::FRAC_PI_2 / nt as f32 * TAU / np as f32) as f64;
                // alpha 0.1 puts a spike of width ~0.1 rad on a 8e-4 rad grid: 1 % is ample.
                assert!(
                    (total - 1.0).abs() < 1e-2,
                    "alpha {alpha} theta {theta_o}: {total}"
                );
                for k in 0..64 {
                    let u = Vec2::new((k % 8) as f32 / 8.0 + 0.05, (k / 8) as f32 / 8.0 + 0.05);
                    let h = sample_visible_normal(alpha, wo, u);
                    assert!((h.length() - 1.0).abs() < 1e-5 && h.z >= 0.0);
                    assert!(wo.dot(h) >= -1e-6, "backfacing sample {h:?}");
                }
            }
        }
    }

    #[test]
    fn refraction_about_a_normal_obeys_snell_and_the_half_vector_inverts_it() {
        let h = direction(0.3, 1.0);
        let wo = direction(0.9, 2.5);
        let eta = 1.5;
        let wi = refract_about(wo, h, eta).unwrap();
        let sin_o = wo.cross(h).length();
        let sin_i = wi.cross(h).length();
        assert!((sin_o - eta * sin_i).abs() < 1e-5);
        assert!((refraction_half_vector(wo, wi, eta) - h).length() < 1e-4);
        // From the dense side beyond the critical angle: total internal reflection.
        assert!(refract_about(direction(1.2, 0.0), Vec3A::Z, 1.0 / 1.5).is_none());
    }
}
