//! Tests of the GGX albedo tables: the generator (a deterministic quadrature), the tables
//! against a finer quadrature, the average against its definition, and the compensated white
//! conductor's furnace.

use super::*;
use crate::bsdf::microfacet::{MIN_ALPHA, masking_shadowing};
use crate::math::Vec3A;

/// Single-scattering directional albedo of a white GGX conductor (F = 1) at cosine `mu`, by
/// deterministic quadrature independent of any sampler: the integral of
/// D G2 / (4 wo.z wi.z) wi.z over wi, rewritten over normals h with dwi = 4 |wo.h| dh, and
/// taken on a midpoint grid in the coordinates (x, phi) where D(h) cos(theta_h) dh = dx dphi / 2pi,
/// i.e. tan^2 theta_h = alpha^2 x / (1 - x); x = 1 - (1 - v)^4 with v on a uniform grid, so
/// that GGX's long tail (x near 1, where wi crosses the horizon) is finely resolved. `phi`
/// covers [0, pi] (the integrand is symmetric about wo's plane).
pub(crate) fn albedo_quadrature(alpha: f32, mu: f32, nx: usize, nphi: usize) -> f64 {
    weighted_albedo_quadrature(alpha, mu, nx, nphi, false)
}

/// [`albedo_quadrature`], the integrand weighted by Schlick's `(1 - wo.h)^5` when `schlick`.
fn weighted_albedo_quadrature(alpha: f32, mu: f32, nx: usize, nphi: usize, schlick: bool) -> f64 {
    normal_quadrature(alpha, mu, (nx, nphi), |wo, h, c| {
        let wi = 2.0 * c * h - wo;
        if wi.z <= 0.0 {
            return 0.0;
        }
        // f wi.z dwi = D G2 / (4 wo.z) * 4 c dh = G2 c / (wo.z cos_theta) * (D cos_theta dh).
        let weight = if schlick {
            (1.0 - c.min(1.0) as f64).powi(5)
        } else {
            1.0
        };
        weight * (masking_shadowing(alpha, wo, wi) * c / wo.z) as f64
    })
}

/// The midpoint quadrature over GGX normals of the albedo generators (see
/// [`albedo_quadrature`]): the mean over the `nx x nphi` grid of `integrand(wo, h, wo.h)`
/// (normals facing `wo` only, `wo` at cosine `mu`) divided by `cos theta_h` and times
/// `dx / dv`. The integrand holds what one normal sends out, over `D cos(theta_h) dh`.
pub(crate) fn normal_quadrature(
    alpha: f32,
    mu: f32,
    (nx, nphi): (usize, usize),
    mut integrand: impl FnMut(Vec3A, Vec3A, f32) -> f64,
) -> f64 {
    let wo = Vec3A::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
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
            let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::PI;
            let h = Vec3A::new(
                (sin_theta * phi.cos()) as f32,
                (sin_theta * phi.sin()) as f32,
                cos_theta as f32,
            );
            let c = wo.dot(h);
            if c <= 0.0 {
                continue;
            }
            total += integrand(wo, h, c) / cos_theta * dx_dv;
        }
    }
    total / (nx * nphi) as f64
}

/// The table's node `(i, j)`: `mu = (i / 31)^2` (1e-4 for `i` = 0), `alpha = (j / 31)^2`
/// (at least [`MIN_ALPHA`]).
fn node(i: usize, j: usize) -> (f32, f32) {
    let s = i as f32 / (N_MU - 1) as f32;
    let r = j as f32 / (N_ROUGHNESS - 1) as f32;
    ((s * s).max(1e-4), (r * r).max(MIN_ALPHA))
}

/// `E_avg` of a row: `2 \int E mu dmu = 4 \int E(s^2) s^3 ds` with `s = sqrt(mu)`, for the
/// row's linear interpolant in `s` (what [`albedo`] reads), integrated exactly per cell.
fn average_of_row(row: &[f64]) -> f64 {
    let h = 1.0 / (N_MU - 1) as f64;
    (0..N_MU - 1)
        .map(|i| {
            let (s0, s1) = (i as f64 * h, (i + 1) as f64 * h);
            let (e0, e1) = (row[i], row[i + 1]);
            let quartic = s1.powi(4) - s0.powi(4);
            e0 * quartic + (e1 - e0) / h * (0.8 * (s1.powi(5) - s0.powi(5)) - s0 * quartic)
        })
        .sum()
}

#[test]
#[ignore = "generator: prints src/bsdf/ggx_albedo/table.rs (~1 min)"]
fn print_albedo_table() {
    // cargo test --release --lib print_albedo_table -- --ignored --nocapture > table.txt
    let rows: Vec<Vec<f64>> = (0..N_ROUGHNESS)
        .map(|j| {
            (0..N_MU)
                .map(|i| {
                    let (mu, alpha) = node(i, j);
                    albedo_quadrature(alpha, mu, 2000, 256)
                })
                .collect()
        })
        .collect();
    println!("/// `E(mu, r)` at `mu = (i / 31)^2` (1e-4 for `i` = 0) and `alpha = (j / 31)^2` (at");
    println!(
        "/// least `MIN_ALPHA`), rows by `j`: white single-scattering GGX's directional albedo by"
    );
    println!("/// quadrature (2000 x 256 nodes), from `tests::print_albedo_table`.");
    println!("#[rustfmt::skip]");
    println!("#[allow(clippy::excessive_precision)] // printed with 6 decimals by the generator");
    println!("const ALBEDO: [[f32; N_MU]; N_ROUGHNESS] = [");
    for row in &rows {
        let cells: Vec<String> = row.iter().map(|e| format!("{e:.6}")).collect();
        println!("    [{}],", cells.join(", "));
    }
    println!("];");
    println!();
    println!();
    println!("/// The same integral weighted by Schlick's `(1 - wo.h)^5`, on the same nodes: with");
    println!("/// [`ALBEDO`], the directional albedo of a Schlick-Fresnel GGX lobe is");
    println!("/// `f0 E + (1 - f0) E_schlick`, from `tests::print_albedo_table`.");
    println!("#[rustfmt::skip]");
    println!("#[allow(clippy::excessive_precision)]");
    println!("const SCHLICK_ALBEDO: [[f32; N_MU]; N_ROUGHNESS] = [");
    for j in 0..N_ROUGHNESS {
        let cells: Vec<String> = (0..N_MU)
            .map(|i| {
                let (mu, alpha) = node(i, j);
                format!(
                    "{:.6}",
                    weighted_albedo_quadrature(alpha, mu, 2000, 256, true)
                )
            })
            .collect();
        println!("    [{}],", cells.join(", "));
    }
    println!("];");
    println!();
    println!(
        "/// `E_avg(r) = 2 \\int E(mu) mu dmu` of each row of [`ALBEDO`] (the row's linear interpolant in `sqrt(mu)`, integrated exactly),"
    );
    println!("/// from `tests::print_albedo_table`.");
    println!("#[rustfmt::skip]");
    println!("#[allow(clippy::excessive_precision)]");
    println!("const AVERAGE_ALBEDO: [f32; N_ROUGHNESS] = [");
    let averages: Vec<String> = rows
        .iter()
        .map(|r| format!("{:.6}", average_of_row(r)))
        .collect();
    println!("    {},", averages.join(", "));
    println!("];");
}

#[test]
fn albedo_table_matches_a_finer_quadrature() {
    // Every fifth node against the full-range grid of 6000 x 720 nodes: within 2e-4. The one
    // value known in closed form first: at normal incidence with alpha = 1, D = 1 / pi, so
    // normals are cosine-distributed, those beyond 45 degrees reflect below the horizon, and
    // with G2 = 1 / (1 + Lambda(wi)) the albedo is 1 - ln 2.
    assert!((ALBEDO[N_ROUGHNESS - 1][N_MU - 1] as f64 - (1.0 - 2f64.ln())).abs() < 1e-4);
    for j in (0..N_ROUGHNESS).step_by(5) {
        for i in (0..N_MU).step_by(5) {
            let (mu, alpha) = node(i, j);
            let expected = albedo_quadrature(alpha, mu, 6000, 720);
            let table = ALBEDO[j][i] as f64;
            assert!(
                (table - expected).abs() < 2e-4,
                "mu {mu} alpha {alpha}: table {table} vs quadrature {expected}"
            );
        }
    }
}

#[test]
fn schlick_table_matches_a_finer_quadrature() {
    for j in (0..N_ROUGHNESS).step_by(6) {
        for i in (0..N_MU).step_by(6) {
            let (mu, alpha) = node(i, j);
            let expected = weighted_albedo_quadrature(alpha, mu, 6000, 720, true);
            let table = SCHLICK_ALBEDO[j][i] as f64;
            assert!(
                (table - expected).abs() < 2e-4,
                "mu {mu} alpha {alpha}: table {table} vs quadrature {expected}"
            );
        }
    }
}

#[test]
fn average_albedo_is_the_cosine_weighted_mean_of_the_albedo() {
    // 2 \int E mu dmu by the midpoint rule in mu (64 nodes, each E by quadrature): within 2e-3
    // of the table's exact integral of its interpolant; a constant row (E = 1) gives 1.
    for j in [3usize, 12, 20, 31] {
        let (_, alpha) = node(0, j);
        let n = 64;
        let mean: f64 = (0..n)
            .map(|k| {
                let mu = (k as f64 + 0.5) / n as f64;
                2.0 * mu * albedo_quadrature(alpha, mu as f32, 400, 90) / n as f64
            })
            .sum();
        let table = AVERAGE_ALBEDO[j] as f64;
        assert!(
            (table - mean).abs() < 2e-3,
            "alpha {alpha}: table {table} vs {mean}"
        );
    }
    assert!((average_of_row(&[1.0; N_MU]) - 1.0).abs() < 1e-12);
}

#[test]
fn compensation_makes_a_white_conductor_lossless_and_keeps_others_below_one() {
    // At nodes and between them: E(mu) * scale is 1 for F = 1 up to the interpolation of E
    // (the scale divides by the interpolated E itself), and for F_avg < 1 the compensated
    // albedo F_avg E + F_ms (1 - E) stays below 1.
    for (mu, alpha) in [(0.9f32, 0.49f32), (0.13, 0.9), (0.5, 0.05), (0.02, 1.0)] {
        let e = albedo(mu, alpha);
        let white = energy_compensation(Rgb::ONE, mu, alpha).x * e;
        assert!((white - 1.0).abs() < 1e-5, "mu {mu} alpha {alpha}: {white}");
        for f in [0.04f32, 0.5, 0.9] {
            let f_average = schlick_average(Rgb::splat(f));
            let scale = energy_compensation(f_average, mu, alpha).x;
            assert!(scale >= 1.0);
            assert!(
                f_average.x * e * scale <= 1.0,
                "f {f}: {}",
                f_average.x * e * scale
            );
        }
    }
}
