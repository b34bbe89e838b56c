//! Smooth dielectric interface (glass): Fresnel reflection and Snell refraction, with total
//! internal reflection. The lobe is chosen with probability equal to the Fresnel reflectance,
//! so both lobes carry weight `tint` (times the 1/eta^2 radiance scaling on refraction).

use crate::math::{Rgb, Vec3A};

use super::BsdfSample;
use super::mirror::reflect;

/// How the Fresnel reflectance is computed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FresnelModel {
    /// The exact unpolarised dielectric Fresnel equations.
    #[default]
    Exact,
    /// Schlick's approximation (the seed report's choice); it uses the cosine on the denser
    /// side, so it stays sensible beyond the critical angle, and total internal reflection is exact.
    Schlick,
}

/// Fresnel reflectance and the cosine of the transmitted direction, for light arriving with
/// cosine `cos_i` (> 0) on the side of index 1 and continuing into relative index `eta`
/// (transmitted over incident). Total internal reflection returns `(1, 0)`.
#[inline]
pub fn fresnel(cos_i: f32, eta: f32, model: FresnelModel) -> (f32, f32) {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return (1.0, 0.0);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let reflectance = match model {
        FresnelModel::Exact => {
            let r_parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
            let r_perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
            0.5 * (r_parallel * r_parallel + r_perpendicular * r_perpendicular)
        }
        FresnelModel::Schlick => {
            let r0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
            let c = 1.0 - if eta >= 1.0 { cos_i } else { cos_t };
            r0 + (1.0 - r0) * c.powi(5)
        }
    };
    (reflectance, cos_t)
}

/// Samples reflection or refraction for `wo` (local frame, `+z` = outside).
#[inline]
pub fn sample(
    ior: f32,
    model: FresnelModel,
    tint: Rgb,
    wo: Vec3A,
    u_lobe: f32,
) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let entering = wo.z > 0.0;
    let eta = if entering { ior } else { 1.0 / ior };
    let cos_o = wo.z.abs();
    let (reflectance, cos_t) = fresnel(cos_o, eta, model);
    if u_lobe < reflectance {
        return Some(BsdfSample {
            wi: reflect(wo),
            weight: tint,
            pdf: reflectance,
            is_delta: true,
        });
    }
    // Snell's law in vector form; the normal on wo's side is sign(wo.z) * z.
    let side = if entering { 1.0 } else { -1.0 };
    let wi = -wo / eta + Vec3A::new(0.0, 0.0, side * (cos_o / eta - cos_t));
    // Radiance is compressed into the denser medium: L_t = L_i / eta^2 (pbrt, Mitsuba).
    Some(BsdfSample {
        wi: wi.normalize(),
        weight: tint / (eta * eta),
        pdf: 1.0 - reflectance,
        is_delta: true,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_reflectance_is_the_classic_formula() {
        for eta in [1.33f32, 1.5, 2.4, 1.0 / 1.5] {
            let expected = ((eta - 1.0) / (eta + 1.0)).powi(2);
            for model in [FresnelModel::Exact, FresnelModel::Schlick] {
                let (f, cos_t) = fresnel(1.0, eta, model);
                assert!(
                    (f - expected).abs() < 1e-6,
                    "{model:?} eta {eta}: {f} vs {expected}"
                );
                assert!((cos_t - 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn total_internal_reflection_beyond_the_critical_angle() {
        let eta = 1.0 / 1.5; // glass to air
        let critical = (1.0f32 / 1.5).asin();
        for model in [FresnelModel::Exact, FresnelModel::Schlick] {
            let just_beyond = (critical + 0.01).cos();
            assert_eq!(fresnel(just_beyond, eta, model).0, 1.0);
            let just_before = (critical - 0.01).cos();
            assert!(fresnel(just_before, eta, model).0 < 1.0);
        }
        // Sampling from inside beyond the critical angle always reflects.
        let theta = critical + 0.05;
        let wo = Vec3A::new(theta.sin(), 0.0, -theta.cos());
        for u in [0.0, 0.5, 0.999] {
            let s = sample(1.5, FresnelModel::Exact, Rgb::ONE, wo, u).unwrap();
            assert_eq!(s.wi, reflect(wo));
        }
    }

    #[test]
    fn schlick_tracks_the_exact_equations() {
        // Schlick's error for glass stays within a few percent absolute over all angles.
        for i in 0..=90 {
            let cos_i = (i as f32).to_radians().cos();
            for eta in [1.5f32, 1.0 / 1.5] {
                let (exact, _) = fresnel(cos_i, eta, FresnelModel::Exact);
                let (schlick, _) = fresnel(cos_i, eta, FresnelModel::Schlick);
                assert!(
                    (exact - schlick).abs() < 0.05,
                    "angle {i}, eta {eta}: {exact} vs {schlick}"
                );
            }
        }
        // Exact at 45 degrees from air into glass: 0.0502 (textbook value).
        let (f45, _) = fresnel(std::f32::consts::FRAC_PI_4.cos(), 1.5, FresnelModel::Exact);
        assert!((f45 - 0.0502).abs() < 5e-4, "{f45}");
    }

    #[test]
    fn refraction_obeys_snell_and_lobe_probabilities_sum_to_one() {
        let theta_i = 0.6f32;
        let wo = Vec3A::new(theta_i.sin(), 0.0, theta_i.cos());
        let (f, _) = fresnel(theta_i.cos(), 1.5, FresnelModel::Exact);
        let r = sample(1.5, FresnelModel::Exact, Rgb::ONE, wo, f * 0.5).unwrap();
        let t = sample(1.5, FresnelModel::Exact, Rgb::ONE, wo, f + (1.0 - f) * 0.5).unwrap();
        assert!((r.pdf + t.pdf - 1.0).abs() < 1e-6);
        assert!(t.wi.z < 0.0 && (t.wi.length() - 1.0).abs() < 1e-5);
        let sin_t = (t.wi.x * t.wi.x + t.wi.y * t.wi.y).sqrt();
        assert!((theta_i.sin() - 1.5 * sin_t).abs() < 1e-5, "Snell");
        assert!(
            t.wi.x < 0.0,
            "refracted ray continues to the other side of the normal"
        );
        assert!((t.weight.x - 1.0 / 2.25).abs() < 1e-6);
        // Leaving glass scales radiance back up by eta^2.
        // and retraces the incoming direction (reversibility).
        let inside = sample(1.5, FresnelModel::Exact, Rgb::ONE, t.wi, 0.999).unwrap();
        assert!((inside.weight.x - 2.25).abs() < 1e-4);
        assert!((inside.wi - wo).length() < 1e-4);
    }
}
