//! Tests of the thin-film Fresnel term against closed forms: no film is the plain exact
//! Fresnel term, and the Airy summation's spectral integral equals the analytic two-interface
//! reflectance integrated over the colour-matching functions.

use super::*;
use crate::bsdf::dielectric::{FresnelModel, fresnel};

/// A film of zero thickness is no film: the exact (polarized, averaged) Fresnel reflectance of
/// the substrate, grey, whatever the film's index.
#[test]
fn thickness_zero_is_the_plain_fresnel_term() {
    for substrate in [1.33f32, 1.5, 2.4] {
        for film_ior in [1.1f32, 1.3, 2.0] {
            for cos in [1.0f32, 0.8, 0.5, 0.2, 0.05] {
                let plain = fresnel(cos, substrate, FresnelModel::Exact).0;
                let film = reflectance(cos, film_ior, substrate, 0.0);
                let error = (film - Rgb::splat(plain)).abs().max_element();
                assert!(
                    error < 2e-3,
                    "substrate {substrate} film {film_ior} cos {cos}: {film} vs {plain}"
                );
            }
        }
    }
}

/// The monochromatic reflectance of a film (index `n2`, optical path difference `opd` in m)
/// between index 1 and `n3` at normal incidence, from the two interfaces' amplitudes:
/// `|r12 + r23 e^(i delta)|^2 / |1 + r12 r23 e^(i delta)|^2`, `delta = 2 pi nu opd`.
fn airy_normal_incidence(n2: f64, n3: f64, opd: f64, nu: f64) -> f64 {
    let r12 = (1.0 - n2) / (1.0 + n2);
    let r23 = (n2 - n3) / (n2 + n3);
    let delta = 2.0 * std::f64::consts::PI * nu * opd;
    let (c, s) = (delta.cos(), delta.sin());
    let numerator = (r12 + r23 * c).powi(2) + (r23 * s).powi(2);
    let denominator = (1.0 + r12 * r23 * c).powi(2) + (r12 * r23 * s).powi(2);
    numerator / denominator
}

/// The colour-matching functions whose Fourier transforms `sensitivity` evaluates, as
/// Gaussians in wavenumber `nu` (1/m): a lobe `A cos(mu phase) exp(-var phase^2)` is the
/// transform of `A / (sqrt(2 pi) sigma) exp(-(nu - mu)^2 / (2 sigma^2))` with
/// `sigma^2 = 2 var`.
fn colour_matching(nu: f64) -> [f64; 3] {
    let lobe = |amplitude: f64, mean: f64, variance: f64| {
        let sigma = (2.0 * variance).sqrt();
        let a = amplitude * (2.0 * std::f64::consts::PI * variance).sqrt();
        a / ((2.0 * std::f64::consts::PI).sqrt() * sigma)
            * (-(nu - mean).powi(2) / (2.0 * sigma * sigma)).exp()
    };
    let x_second = {
        let sigma = (2.0 * 4.5282e9f64).sqrt();
        1.64408e-8 / ((2.0 * std::f64::consts::PI).sqrt() * sigma)
            * (-(nu - 2.2399e6).powi(2) / (2.0 * sigma * sigma)).exp()
    };
    [
        lobe(5.4856e-13, 1.6810e6, 4.3278e9) + x_second,
        lobe(4.4201e-13, 1.7953e6, 9.3046e9),
        lobe(5.2481e-13, 2.2084e6, 6.6121e9),
    ]
}

/// The analytic reflectance integrated over the colour-matching functions (midpoint rule over
/// the wavenumbers where they are not negligible), normalised as `sensitivity` is.
fn integrated_xyz(n2: f64, n3: f64, thickness_nm: f64) -> [f64; 3] {
    let opd = 2.0 * n2 * thickness_nm * 1e-9;
    let (from, to, steps) = (0.6e6f64, 3.4e6f64, 40_000);
    let step = (to - from) / steps as f64;
    let mut xyz = [0.0f64; 3];
    for k in 0..steps {
        let nu = from + (k as f64 + 0.5) * step;
        let r = airy_normal_incidence(n2, n3, opd, nu);
        for (sum, cmf) in xyz.iter_mut().zip(colour_matching(nu)) {
            *sum += r * cmf * step;
        }
    }
    xyz.map(|v| v / 1.0685e-7)
}

/// Quarter-wave films at 550 nm (an anti-reflection coating below the substrate's index and a
/// high-index film above it) and a thicker one: the Airy summation, truncated after three
/// orders, gives the analytic reflectance's spectral integral.
#[test]
fn the_airy_sum_integrates_the_two_interface_reflectance() {
    for (n2, n3, thickness) in [
        (1.3f64, 1.5f64, 550.0 / (4.0 * 1.3)),
        (2.0, 1.5, 550.0 / (4.0 * 2.0)),
        (1.6, 1.33, 380.0),
        (1.3, 1.5, 800.0),
    ] {
        // The reference is the analytic form: at the quarter wave's own wavelength it is the
        // textbook minimum ((n1 n3 - n2^2) / (n1 n3 + n2^2))^2.
        let quarter = 550.0 / (4.0 * n2);
        let at_550 = airy_normal_incidence(n2, n3, 2.0 * n2 * quarter * 1e-9, 1.0 / 550e-9);
        let textbook = ((n3 - n2 * n2) / (n3 + n2 * n2)).powi(2);
        assert!((at_550 - textbook).abs() < 1e-12, "{at_550} {textbook}");

        let expected = integrated_xyz(n2, n3, thickness);
        let got = reflectance_xyz(1.0, n2 as f32, n3 as f32, thickness as f32);
        eprintln!("film {n2} over {n3}, {thickness:.1} nm: {got} vs {expected:?}");
        for (g, e) in got.to_array().iter().zip(expected) {
            assert!((*g as f64 - e).abs() < 1e-3, "{got} vs {expected:?}");
        }
    }
}

/// The quarter-wave anti-reflection film reflects less than the bare substrate, the
/// high-index one more (their luminance), as thin-film optics says.
#[test]
fn a_quarter_wave_film_lowers_or_raises_the_reflectance_by_its_index() {
    let bare = fresnel(1.0, 1.5, FresnelModel::Exact).0;
    let luminance = |c: Rgb| crate::math::luminance(c);
    let coated = luminance(reflectance(1.0, 1.3, 1.5, 550.0 / (4.0 * 1.3)));
    let high = luminance(reflectance(1.0, 2.0, 1.5, 550.0 / 8.0));
    assert!(coated < 0.5 * bare, "{coated} vs {bare}");
    assert!(high > 2.0 * bare, "{high} vs {bare}");
}

/// Every input gives a reflectance in [0, 1], never NaN: grazing and normal incidence, total
/// internal reflection in the film (index below 1), thin and thick films.
#[test]
fn the_reflectance_is_bounded_and_finite() {
    for film_ior in [0.5f32, 1.0, 1.3, 2.5] {
        for substrate in [1.0f32, 1.5, 399.0] {
            for thickness in [0.0f32, 10.0, 100.0, 450.0, 5000.0] {
                for k in 0..=20 {
                    let cos = k as f32 / 20.0;
                    let r = reflectance(cos, film_ior, substrate, thickness);
                    assert!(
                        r.is_finite() && r.min_element() >= 0.0 && r.max_element() <= 1.0,
                        "{film_ior} {substrate} {thickness} {cos}: {r}"
                    );
                }
            }
        }
    }
}
