//! Lambertian (ideal diffuse) reflection: f = albedo / pi on the side of `wo`.

use crate::math::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use crate::math::{Rgb, Vec2, Vec3A, Vec4};
use std::f32::consts::FRAC_1_PI;

use super::BsdfSample;

/// f / albedo and the density, from the directions' z components alone: `(1 / pi, cos / pi)`
/// on the same side, zeros otherwise. Scalar, branch-free code that lane loops vectorise.
#[inline(always)]
fn eval_and_pdf(wo_z: f32, wi_z: f32) -> (f32, f32) {
    let same_side = wo_z * wi_z > 0.0;
    (
        if same_side { FRAC_1_PI } else { 0.0 },
        if same_side {
            cosine_hemisphere_pdf(wi_z.abs())
        } else {
            0.0
        },
    )
}

/// f(wo, wi): albedo / pi when both directions are on the same side.
#[inline]
pub fn eval(albedo: Rgb, wo: Vec3A, wi: Vec3A) -> Rgb {
    albedo * eval_and_pdf(wo.z, wi.z).0
}

/// Cosine-weighted density on the side of `wo`.
#[inline]
pub fn pdf(wo: Vec3A, wi: Vec3A) -> f32 {
    eval_and_pdf(wo.z, wi.z).1
}

/// [`eval`] and [`pdf`] of four directions, given by their z components (one `Vec4` lane
/// each): f by channel, and the densities. The same arithmetic as the scalar forms.
#[inline]
pub fn eval_and_pdf_lanes(albedo: Rgb, wo_z: f32, wi_z: Vec4) -> ([Vec4; 3], Vec4) {
    let same_side = (Vec4::splat(wo_z) * wi_z).cmpgt(Vec4::ZERO);
    let f_over_albedo = Vec4::select(same_side, Vec4::splat(FRAC_1_PI), Vec4::ZERO);
    let pdf = wi_z.abs().max(Vec4::ZERO) * Vec4::splat(FRAC_1_PI);
    let f = albedo.to_array().map(|a| Vec4::splat(a) * f_over_albedo);
    (f, Vec4::select(same_side, pdf, Vec4::ZERO))
}

/// Cosine-weighted sample on the side of `wo`; the weight f cos / pdf is exactly the albedo.
#[inline]
pub fn sample(albedo: Rgb, wo: Vec3A, u: Vec2) -> Option<BsdfSample> {
    if wo.z == 0.0 {
        return None;
    }
    let mut wi = sample_cosine_hemisphere(u);
    if wo.z < 0.0 {
        wi.z = -wi.z;
    }
    let pdf = cosine_hemisphere_pdf(wi.z.abs());
    (pdf > 0.0).then_some(BsdfSample {
        wi,
        weight: albedo,
        pdf,
        is_delta: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambert_is_reciprocal_energy_conserving_and_consistent() {
        let albedo = Rgb::new(0.8, 0.5, 0.2);
        let wo = Vec3A::new(0.3, -0.2, 0.93).normalize();
        // Each sample's weight equals eval * cos / pdf, and pdf agrees with `pdf`.
        let n = 64;
        for i in 0..n * n {
            let u = Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            );
            let s = sample(albedo, wo, u).unwrap();
            let expected = eval(albedo, wo, s.wi) * s.wi.z.abs() / pdf(wo, s.wi);
            assert!((expected - s.weight).abs().max_element() < 1e-4);
            assert!((s.pdf - pdf(wo, s.wi)).abs() < 1e-5);
            assert_eq!(
                eval(albedo, wo, s.wi),
                eval(albedo, s.wi, wo),
                "reciprocity"
            );
        }
        // Directional albedo by quadrature of f cos over the hemisphere equals the albedo.
        let (nt, np) = (512, 16);
        let mut integral = Rgb::ZERO;
        for i in 0..nt {
            let theta = (i as f32 + 0.5) / nt as f32 * std::f32::consts::FRAC_PI_2;
            for j in 0..np {
                let phi = (j as f32 + 0.5) / np as f32 * std::f32::consts::TAU;
                let wi = Vec3A::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                let d_omega = theta.sin()
                    * (std::f32::consts::FRAC_PI_2 / nt as f32)
                    * (std::f32::consts::TAU / np as f32);
                integral += eval(albedo, wo, wi) * wi.z * d_omega;
            }
        }
        assert!((integral - albedo).abs().max_element() < 1e-4, "{integral}");
        // Below the surface from wo's side: nothing.
        assert_eq!(eval(albedo, wo, Vec3A::new(0.0, 0.0, -1.0)), Rgb::ZERO);
        // Two-sided: from below it reflects downward.
        let s = sample(albedo, -wo, Vec2::new(0.3, 0.6)).unwrap();
        assert!(s.wi.z < 0.0);
    }
}
