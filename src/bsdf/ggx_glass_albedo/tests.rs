//! Tests of the rough-glass albedo tables: the generator (a deterministic quadrature), the
//! tables against a finer quadrature, and the compensated rough glass's furnace with the
//! chi-square of its sampler.

use super::*;
use crate::bsdf::dielectric::{FresnelModel, fresnel};
use crate::bsdf::ggx_albedo::tests::normal_quadrature;
use crate::bsdf::metallic_roughness::MetallicRoughness;
use crate::bsdf::microfacet::{MIN_ALPHA, masking_shadowing, refract_about};
use crate::math::rng::{path_key, uniform, uniform2};
use crate::math::{Rgb, Vec3A};

/// Single-scattering directional albedo of the white rough dielectric (reflection plus the
/// transmitted flux) at cosine `mu` into relative index `eta`, by the midpoint quadrature of
/// `ggx_albedo::tests::albedo_quadrature` over normals (`D cos(theta_h) dh = dx dphi / 2pi`,
/// `x = 1 - (1 - v)^4`, `phi` in [0, pi] by symmetry). Per normal `h` at `c = wo.h`, Fresnel
/// `F` splits the light: `F G2(wo, wr) c / (wo.z cos theta_h)` reflected and
/// `(1 - F) G2(wo, wt) c / (wo.z cos theta_h)` transmitted (the refraction's Jacobian and the
/// BTDF's `|wi.h| / denominator^2` cancel once `1 / eta^2` is left out).
pub(crate) fn glass_albedo_quadrature(
    alpha: f32,
    mu: f32,
    eta: f32,
    nx: usize,
    nphi: usize,
) -> f64 {
    normal_quadrature(alpha, mu, (nx, nphi), |wo, h, c| {
        let f = fresnel(c, eta, FresnelModel::Exact).0;
        let reflected = 2.0 * c * h - wo;
        let mut split = 0.0f32;
        if reflected.z > 0.0 {
            split += f * masking_shadowing(alpha, wo, reflected);
        }
        if let Some(transmitted) = refract_about(wo, h, eta)
            && transmitted.z < 0.0
        {
            split += (1.0 - f) * masking_shadowing(alpha, wo, transmitted);
        }
        (split * c / wo.z) as f64
    })
}

/// The tables' node `(i, j, k)`: `mu = (i / 31)^2` (1e-4 for `i` = 0), `alpha = (j / 31)^2`
/// (at least [`MIN_ALPHA`]), `ior` with `(ior - 1) / (ior + 1) = 0.5 k / 15`.
fn node(i: usize, j: usize, k: usize) -> (f32, f32, f32) {
    let s = i as f32 / (N_MU - 1) as f32;
    let r = j as f32 / (N_ROUGHNESS - 1) as f32;
    let root = MAX_REFLECTANCE_ROOT * k as f32 / (N_IOR - 1) as f32;
    (
        (s * s).max(1e-4),
        (r * r).max(MIN_ALPHA),
        (1.0 + root) / (1.0 - root),
    )
}

/// Quadrature nodes of the tables (x, phi).
const TABLE_NODES: (usize, usize) = (1000, 128);

#[test]
#[ignore = "generator: prints src/bsdf/ggx_glass_albedo/table.rs (~4 min)"]
fn print_glass_albedo_table() {
    // cargo test --release --lib print_glass_albedo_table -- --ignored --nocapture
    for (name, leaving) in [("ENTERING", false), ("LEAVING", true)] {
        let side = if leaving {
            "from inside (`eta` = 1 / ior)"
        } else {
            "from outside (`eta` = ior)"
        };
        println!("/// `E(mu, r, ior)` {side} at `mu = (i / 31)^2` (1e-4 for `i` = 0),");
        println!(
            "/// `alpha = (j / 31)^2` (at least `MIN_ALPHA`) and `(ior - 1) / (ior + 1) = k / 30`, as"
        );
        println!("/// `[k][j][i]`: the white rough dielectric's directional albedo by quadrature");
        println!(
            "/// ({} x {} nodes), from `tests::print_glass_albedo_table`.",
            TABLE_NODES.0, TABLE_NODES.1
        );
        println!("#[rustfmt::skip]");
        println!(
            "#[allow(clippy::excessive_precision, clippy::approx_constant)] // 5 decimals, some near constants by chance"
        );
        println!("static {name}: Table = [");
        for k in 0..N_IOR {
            println!("    [");
            for j in 0..N_ROUGHNESS {
                let cells: Vec<String> = (0..N_MU)
                    .map(|i| {
                        let (mu, alpha, ior) = node(i, j, k);
                        let eta = if leaving { 1.0 / ior } else { ior };
                        let (nx, nphi) = TABLE_NODES;
                        format!("{:.5}", glass_albedo_quadrature(alpha, mu, eta, nx, nphi))
                    })
                    .collect();
                println!("        [{}],", cells.join(", "));
            }
            println!("    ],");
        }
        println!("];");
        println!();
    }
}

#[test]
fn glass_table_matches_a_finer_quadrature() {
    // Nodes of both tables (every fifth in angle and roughness) against 4000 x 512 quadrature
    // nodes, within 2e-3, from mu = 0.017 (node 4) on: closer to grazing, the table's
    // quadrature does not resolve the nearly smooth surfaces (mu 1e-4, alpha 0.004: 0.562
    // against 0.511), which only directions within a degree of the horizon read. Points
    // between nodes (the trilinear interpolant) within 1e-2.
    for (leaving, k) in [(false, 0), (false, 6), (true, 6), (true, 15), (false, 15)] {
        for j in (1..N_ROUGHNESS).step_by(5) {
            for i in (4..N_MU).step_by(5) {
                let (mu, alpha, ior) = node(i, j, k);
                let eta = if leaving { 1.0 / ior } else { ior };
                let fine = glass_albedo_quadrature(alpha, mu, eta, 4000, 512);
                let table = glass_albedo(mu, alpha, eta) as f64;
                assert!(
                    (table - fine).abs() < 2e-3,
                    "node mu {mu} alpha {alpha} eta {eta}: {table} vs {fine}"
                );
            }
        }
    }
    for (mu, roughness, ior) in [
        (0.3f32, 0.45f32, 1.45f32),
        (0.7, 0.8, 1.33),
        (0.1, 0.25, 1.6),
    ] {
        let alpha = roughness * roughness;
        for eta in [ior, 1.0 / ior] {
            let fine = glass_albedo_quadrature(alpha, mu, eta, 2000, 256);
            let table = glass_albedo(mu, alpha, eta) as f64;
            assert!(
                (table - fine).abs() < 1e-2,
                "mu {mu} alpha {alpha} eta {eta}: {table} vs {fine}"
            );
        }
    }
}

/// White rough glass (transmission 1, base colour 1, metallic 0) of this roughness and ior.
fn white_glass(roughness: f32, ior: f32) -> MetallicRoughness {
    MetallicRoughness {
        transmission: 1.0,
        ior,
        ..MetallicRoughness::new(Rgb::ONE, 0.0, roughness)
    }
}

/// Mean and standard error of the flux the sampler of `m` carries from `wo` (red channel):
/// the sample weights, the transmitted ones times `eta^2` (refraction's radiance scaling is
/// not energy).
fn sampled_flux(m: &MetallicRoughness, wo: Vec3A, n: u32, seed: u32) -> (f64, f64) {
    let eta = if wo.z > 0.0 { m.ior } else { 1.0 / m.ior };
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for k in 0..n {
        let key = path_key(17, k, seed);
        if let Some(s) = m.sample(wo, uniform(key, 0, 0), uniform2(key, 0, 1)) {
            let scale = if s.wi.z * wo.z < 0.0 { eta * eta } else { 1.0 };
            let w = (s.weight.x * scale) as f64;
            sum += w;
            sum2 += w * w;
        }
    }
    let mean = sum / n as f64;
    (mean, ((sum2 / n as f64 - mean * mean) / n as f64).sqrt())
}

#[test]
fn rough_glass_furnace_is_one_at_every_roughness_from_both_sides() {
    // Multiscatter glass: reflection plus transmitted flux is 1 seen from outside and from
    // inside (where total internal reflection sends more of it back). Single scattering alone
    // carries E (the quadrature, printed). Tolerance: 4 standard errors plus the tables'
    // interpolation between nodes (ior 1.45 lies between them; below 1e-2, see above).
    for (k, roughness) in [0.1f32, 0.3, 0.5, 0.7, 1.0].into_iter().enumerate() {
        for ior in [1.5f32, 1.45] {
            let m = white_glass(roughness, ior);
            for mu in [1.0f32, 0.5, 0.2, 0.05] {
                for side in [1.0f32, -1.0] {
                    let wo = Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, side * mu);
                    let (mean, standard_error) = sampled_flux(&m, wo, 100_000, k as u32);
                    let eta = if side > 0.0 { ior } else { 1.0 / ior };
                    let single = glass_albedo_quadrature(m.alpha, mu, eta, 1000, 128);
                    eprintln!(
                        "roughness {roughness} ior {ior} mu {mu} side {side}: furnace \
                         {mean:.5} +- {standard_error:.5} (single scattering {single:.4})"
                    );
                    assert!(
                        (mean - 1.0).abs() < 4.0 * standard_error + 1e-2,
                        "roughness {roughness} ior {ior} mu {mu} side {side}: {mean} +- \
                         {standard_error}"
                    );
                }
            }
        }
    }
}
