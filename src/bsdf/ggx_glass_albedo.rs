//! Energy compensation of the rough dielectric ("multiscatter GGX glass", as Cycles 4.x
//! compensates its GGX glass closure): the directional albedo `E(mu, r, eta)` of a white
//! single-scattering rough dielectric, reflection plus transmission, as two tables (light
//! arriving from outside, `eta` = ior; from inside, `eta` = 1 / ior), and the scale `1 / E`
//! that multiplies both lobes.
//!
//! A dielectric loses energy only to single scattering's masking (Fresnel splits the light, it
//! absorbs nothing), so the lost part is `1 - E` and the scaled pair's albedo is exactly 1 (the
//! rough-glass furnace). `E` counts flux: the transmitted part without the `1 / eta^2` by
//! which radiance is compressed into the denser side, which the BTDF keeps on top. The scale
//! depends on `wo` only: sampling is unchanged, and the pair is not reciprocal (as in Cycles).
//!
//! Axes: `sqrt(mu)` ([`N_MU`] nodes), the perceptual roughness `sqrt(alpha)` ([`N_ROUGHNESS`]),
//! and `(ior - 1) / (ior + 1)` from 0 to 0.5 ([`N_IOR`]: ior 1 to 3; 1.5 is a node), trilinear. The tables
//! (`ggx_glass_albedo/table.rs`) are the output of `tests::print_glass_albedo_table` (a
//! deterministic quadrature; regenerate with `cargo test --release --lib
//! print_glass_albedo_table -- --ignored --nocapture`), and the tests check them against a
//! finer quadrature and the compensated sampler's furnace.

/// Nodes in `sqrt(mu)`.
const N_MU: usize = 32;
/// Nodes in the perceptual roughness `sqrt(alpha)`.
const N_ROUGHNESS: usize = 32;
/// Nodes in `(ior - 1) / (ior + 1)`.
const N_IOR: usize = 16;
/// The largest `(ior - 1) / (ior + 1)` of the tables (ior 3); larger indices read the edge.
const MAX_REFLECTANCE_ROOT: f32 = 0.5;

/// Cell index and fraction of `t` in [0, 1] on an axis of `n` nodes.
#[inline]
fn cell(t: f32, n: usize) -> (usize, f32) {
    let x = t.clamp(0.0, 1.0) * (n - 1) as f32;
    let i = (x as usize).min(n - 2);
    (i, x - i as f32)
}

/// The three axes' coordinates in [0, 1] of `(mu, alpha, ior)`, `ior` >= 1.
#[inline]
fn coordinates(mu: f32, alpha: f32, ior: f32) -> [f32; 3] {
    [
        mu.clamp(0.0, 1.0).sqrt(),
        alpha.clamp(0.0, 1.0).sqrt(),
        (ior - 1.0) / (ior + 1.0) / MAX_REFLECTANCE_ROOT,
    ]
}

/// `table` at the coordinates, trilinear.
#[inline]
fn trilinear(table: &Table, [s, r, x]: [f32; 3]) -> f32 {
    let (i, fi) = cell(s, N_MU);
    let (j, fj) = cell(r, N_ROUGHNESS);
    let (k, fk) = cell(x, N_IOR);
    let along_mu = |k: usize, j: usize| table[k][j][i] * (1.0 - fi) + table[k][j][i + 1] * fi;
    let plane = |k: usize| along_mu(k, j) * (1.0 - fj) + along_mu(k, j + 1) * fj;
    plane(k) * (1.0 - fk) + plane(k + 1) * fk
}

/// A table as `[ior][roughness][mu]`.
type Table = [[[f32; N_MU]; N_ROUGHNESS]; N_IOR];

/// Single-scattering directional albedo (reflection plus transmitted flux) of the white rough
/// dielectric seen from cosine `mu` on the side whose relative index is `eta` (inside over
/// outside from outside: the ior; from inside: 1 / ior).
#[inline]
pub fn glass_albedo(mu: f32, alpha: f32, eta: f32) -> f32 {
    if eta >= 1.0 {
        trilinear(&ENTERING, coordinates(mu, alpha, eta))
    } else {
        trilinear(&LEAVING, coordinates(mu, alpha, 1.0 / eta))
    }
}

/// The factor `1 / E` that multiplies the rough dielectric's reflection and transmission seen
/// from `wo` at cosine `mu` (module doc).
#[inline]
pub fn glass_energy_compensation(mu: f32, alpha: f32, eta: f32) -> f32 {
    1.0 / glass_albedo(mu, alpha, eta).max(1e-2)
}

// The tables are generated: see `tests::print_glass_albedo_table`.
include!("ggx_glass_albedo/table.rs");

#[cfg(test)]
pub(crate) mod tests;
