//! Tests of the metallic-roughness BSDF: chi-square of `sample` against `pdf`, sample
//! weights against `eval`, reciprocity, the single-scattering GGX furnace, and the exact
//! Lambertian limit.

use super::*;
use crate::bsdf::chi_square::{ChiSquareSetup, chi_square_test};
use crate::bsdf::microfacet::masking_shadowing;
use crate::math::rng::{path_key, uniform, uniform2};
use std::f32::consts::TAU;

fn direction(theta: f32, phi: f32) -> Vec3A {
    Vec3A::new(
        theta.sin() * phi.cos(),
        theta.sin() * phi.sin(),
        theta.cos(),
    )
}

fn metal(roughness: f32) -> MetallicRoughness {
    MetallicRoughness::new(Rgb::new(0.95, 0.7, 0.4), 1.0, roughness)
}

fn plastic(roughness: f32) -> MetallicRoughness {
    MetallicRoughness::new(Rgb::new(0.6, 0.3, 0.2), 0.0, roughness)
}

fn rough_glass(roughness: f32) -> MetallicRoughness {
    MetallicRoughness {
        transmission: 1.0,
        ..MetallicRoughness::new(Rgb::new(1.0, 0.9, 0.8), 0.0, roughness)
    }
}

fn everything(roughness: f32) -> MetallicRoughness {
    MetallicRoughness {
        transmission: 0.5,
        specular: 0.7,
        specular_color: Rgb::new(1.0, 0.5, 0.8),
        ior: 1.33,
        ..MetallicRoughness::new(Rgb::new(0.5, 0.8, 0.3), 0.4, roughness)
    }
}

/// Every (material, wo) pair the sampling tests run on: roughness 0.3, 0.6 and 1 for each
/// family, at incident angles from near-normal to grazing, from both sides for glass.
fn cases() -> Vec<(String, MetallicRoughness, Vec3A)> {
    let mut cases = Vec::new();
    for roughness in [0.3f32, 0.6, 1.0] {
        for (name, m) in [
            ("metal", metal(roughness)),
            ("plastic", plastic(roughness)),
            ("glass", rough_glass(roughness)),
            ("mixture", everything(roughness)),
        ] {
            for theta in [0.15f32, 0.9, 1.45] {
                cases.push((
                    format!("{name} r {roughness} theta {theta}"),
                    m,
                    direction(theta, 0.4),
                ));
            }
            if name == "glass" || name == "mixture" {
                cases.push((
                    format!("{name} r {roughness} from inside"),
                    m,
                    direction(2.5, 1.0),
                ));
            }
        }
    }
    cases
}

#[test]
#[ignore = "slow: chi-square of 42 cases x 1M samples (~28 s)"]
fn sampling_matches_pdf_chi_square() {
    let cases = cases();
    // Sidak correction: the whole family of tests fails with probability 1 %.
    let significance = 1.0 - 0.99f64.powf(1.0 / cases.len() as f64);
    for (k, (name, m, wo)) in cases.iter().enumerate() {
        let setup = ChiSquareSetup {
            theta_cells: 20,
            phi_cells: 40,
            simpson_intervals: 40,
            samples: 1_000_000,
            significance,
        };
        let result = chi_square_test(
            &setup,
            1000 + k as u64,
            |u_lobe, u| m.sample(*wo, u_lobe, u).map(|s| s.wi),
            |wi| m.pdf(*wo, wi),
        );
        eprintln!(
            "{name}: p {:.4} stat {:.0} dof {}",
            result.p_value, result.statistic, result.dof
        );
        assert!(
            result.p_value > setup.significance,
            "{name}: {result:?} (threshold {})",
            setup.significance
        );
        // The density integrates to at most 1 (samples below the surface are lost, as in pbrt).
        assert!(result.total_mass < 1.0 + 1e-2, "{name}: {result:?}");
    }
}

#[test]
fn sample_weight_and_pdf_agree_with_eval_and_pdf() {
    for (name, m, wo) in cases() {
        for k in 0..2000u32 {
            let key = path_key(3, k, 0);
            let Some(s) = m.sample(wo, uniform(key, 0, 0), uniform2(key, 0, 1)) else {
                continue;
            };
            let pdf = m.pdf(wo, s.wi);
            assert!(
                (s.pdf - pdf).abs() <= 1e-4 * pdf,
                "{name}: {} vs {pdf}",
                s.pdf
            );
            let expected = m.eval(wo, s.wi) * s.wi.z.abs() / pdf;
            let error = (expected - s.weight).abs().max_element();
            assert!(
                error <= 1e-4 * expected.max_element().max(1e-3),
                "{name}: {expected} vs {}",
                s.weight
            );
            assert!(!s.is_delta && (s.wi.length() - 1.0).abs() < 1e-4);
        }
    }
}

#[test]
fn reflection_is_reciprocal() {
    for (name, m, _) in cases() {
        for k in 0..500u32 {
            let key = path_key(5, k, 0);
            let a = uniform2(key, 0, 0);
            let b = uniform2(key, 0, 2);
            let side = if uniform(key, 0, 4) < 0.5 { 1.0 } else { -1.0 };
            let wo = direction(a.x * 1.5, a.y * TAU) * Vec3A::new(1.0, 1.0, side);
            let wi = direction(b.x * 1.5, b.y * TAU) * Vec3A::new(1.0, 1.0, side);
            let (f, g) = (m.eval(wo, wi), m.eval(wi, wo));
            assert!(
                (f - g).abs().max_element() <= 1e-4 * f.max_element().max(1e-2),
                "{name}: {f} vs {g}"
            );
        }
    }
}

#[test]
fn refraction_scales_reciprocally_by_eta_squared() {
    // Radiance BTDFs are not symmetric: f(wo, wi) / eta_o^2 = f(wi, wo) / eta_i^2, with eta_o
    // the index on wo's side.
    let m = rough_glass(0.5);
    let m = MetallicRoughness {
        base_color: Rgb::ONE,
        ..m
    };
    for k in 0..500u32 {
        let key = path_key(6, k, 0);
        let a = uniform2(key, 0, 0);
        let b = uniform2(key, 0, 2);
        let wo = direction(a.x * 1.5, a.y * TAU);
        let wi = -direction(b.x * 1.5, b.y * TAU);
        let (f, g) = (m.eval(wo, wi).x, m.eval(wi, wo).x);
        // wo outside (index 1), wi inside (index ior).
        let (lhs, rhs) = (f, g / (m.ior * m.ior));
        assert!(
            (lhs - rhs).abs() <= 1e-3 * lhs.max(1e-3),
            "{wo} {wi}: {lhs} vs {rhs}"
        );
    }
}

/// Single-scattering directional albedo of a white GGX conductor (F = 1) at cosine `mu`, by
/// deterministic quadrature independent of the sampler under test: the integral of
/// D G2 / (4 wo.z wi.z) wi.z over wi, rewritten over normals h with dwi = 4 |wo.h| dh, and
/// sampled on a midpoint grid in the coordinates (x, phi) where D(h) cos(theta_h) dh = dx dphi / 2pi,
/// i.e. tan^2 theta_h = alpha^2 x / (1 - x); x = 1 - (1 - v)^4 with v on a uniform grid, so
/// that GGX's long tail (x near 1, where wi crosses the horizon) is finely resolved.
fn ggx_albedo_quadrature(alpha: f32, mu: f32) -> f64 {
    let wo = Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, mu);
    let (nx, nphi) = (6000, 720);
    let mut total = 0.0f64;
    for i in 0..nx {
        let v = (i as f64 + 0.5) / nx as f64;
        let one_minus_x = (1.0 - v).powi(4);
        let x = 1.0 - one_minus_x;
        let dx_dv = 4.0 * (1.0 - v).powi(3);
        let tan_theta = alpha as f64 * (x / one_minus_x).sqrt();
        let cos_theta = 1.0 / (1.0 + tan_theta * tan_theta).sqrt();
        let sin_theta = tan_theta * cos_theta;
        for j in 0..nphi {
            let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
            let h = Vec3A::new(
                (sin_theta * phi.cos()) as f32,
                (sin_theta * phi.sin()) as f32,
                cos_theta as f32,
            );
            let c = wo.dot(h);
            if c <= 0.0 {
                continue;
            }
            let wi = 2.0 * c * h - wo;
            if wi.z <= 0.0 {
                continue;
            }
            // f wi.z dwi = D G2 / (4 wo.z) * 4 c dh = G2 c / (wo.z cos_theta) * (D cos_theta dh).
            total += (masking_shadowing(alpha, wo, wi) * c / wo.z) as f64 / cos_theta * dx_dv;
        }
    }
    total / (nx * nphi) as f64
}

#[test]
fn white_metal_loses_only_the_single_scattering_ggx_energy() {
    // Single-scattering albedo of white GGX: GGX's long tail sends normals beyond 45 degrees
    // (6 % of them for alpha 0.25 at normal incidence) and their reflections below the
    // horizon, and G2 masks some of the rest. The quadrature gives, for mu = 1, 0.5, 0.2:
    // roughness 0.1: 0.9999, 0.9997, 0.9986; roughness 0.5: 0.916, 0.857, 0.848;
    // roughness 1.0: 0.307, 0.451, 0.642. Loose bands around them check the quadrature itself.
    let white = |roughness| MetallicRoughness::new(Rgb::ONE, 1.0, roughness);
    // One value is known in closed form: at normal incidence with alpha = 1, D = 1 / pi, so
    // normals are cosine-distributed, those beyond 45 degrees reflect below the horizon, and
    // with G2 = 1 / (1 + Lambda(wi)) the albedo is the integral of u / (1 + u) over [0, 1],
    // i.e. 1 - ln 2 = 0.30685.
    let exact = ggx_albedo_quadrature(1.0, 1.0);
    assert!((exact - (1.0 - 2f64.ln())).abs() < 1e-4, "{exact}");
    let bands = [(0.1f32, 0.99, 1.0), (0.5, 0.8, 0.95), (1.0, 0.25, 0.7)];
    for (roughness, low, high) in bands {
        let m = white(roughness);
        for mu in [1.0f32, 0.5, 0.2] {
            let expected = ggx_albedo_quadrature(m.alpha, mu);
            assert!(
                (low..=high).contains(&expected),
                "roughness {roughness} mu {mu}: quadrature {expected}"
            );
            // Monte Carlo with the sampler: mean of the weights, and its standard error.
            let wo = Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, mu);
            let n = 400_000u32;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for k in 0..n {
                let key = path_key(11, k, (roughness * 10.0) as u32);
                if let Some(s) = m.sample(wo, uniform(key, 0, 0), uniform2(key, 0, 1)) {
                    let w = s.weight.x as f64;
                    sum += w;
                    sum2 += w * w;
                }
            }
            let mean = sum / n as f64;
            let standard_error = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            eprintln!(
                "roughness {roughness} mu {mu}: quadrature {expected:.5}, sampler {mean:.5} +- {standard_error:.5}"
            );
            // 4 sigma plus the quadrature's own error (< 1e-4 on this grid).
            assert!(
                (mean - expected).abs() < 4.0 * standard_error + 1e-4,
                "roughness {roughness} mu {mu}: {mean} +- {standard_error} vs {expected}"
            );
        }
    }
}

#[test]
fn no_specular_layer_is_exactly_lambertian() {
    let albedo = Rgb::new(0.8, 0.5, 0.2);
    let m = MetallicRoughness {
        specular: 0.0,
        ..MetallicRoughness::new(albedo, 0.0, 0.5)
    };
    assert_eq!(m.as_lambertian(), Some(albedo));
    for k in 0..1000u32 {
        let key = path_key(9, k, 0);
        let wo = direction(uniform(key, 0, 0) * 1.5, uniform(key, 0, 1) * TAU);
        let wi = direction(uniform(key, 0, 2) * 3.0, uniform(key, 0, 3) * TAU);
        assert_eq!(m.eval(wo, wi), lambert::eval(albedo, wo, wi));
        assert_eq!(m.pdf(wo, wi), lambert::pdf(wo, wi));
        let (u_lobe, u) = (uniform(key, 0, 4), uniform2(key, 0, 5));
        assert_eq!(m.sample(wo, u_lobe, u), lambert::sample(albedo, wo, u));
    }
}

#[test]
fn energy_is_conserved_for_every_family() {
    // Directional albedo (MC over the sampler, per channel) never exceeds 1 beyond 4 sigma,
    // once refraction's radiance scaling 1/eta^2 is undone (it is not energy).
    for (name, m, wo) in cases() {
        let eta = if wo.z > 0.0 { m.ior } else { 1.0 / m.ior };
        let n = 20_000u32;
        let (mut sum, mut sum2) = (Rgb::ZERO, Rgb::ZERO);
        for k in 0..n {
            let key = path_key(13, k, 0);
            if let Some(s) = m.sample(wo, uniform(key, 0, 0), uniform2(key, 0, 1)) {
                let energy = if s.wi.z * wo.z < 0.0 {
                    s.weight * eta * eta
                } else {
                    s.weight
                };
                sum += energy;
                sum2 += energy * energy;
            }
        }
        let mean = sum / n as f32;
        let standard_error = ((sum2 / n as f32 - mean * mean) / n as f32).max(Rgb::ZERO);
        let bound = Rgb::ONE
            + 4.0
                * Rgb::new(
                    standard_error.x.sqrt(),
                    standard_error.y.sqrt(),
                    standard_error.z.sqrt(),
                );
        assert!(mean.cmple(bound).all(), "{name}: albedo {mean}");
    }
}
