//! Energy compensation of single-scattering GGX ("multiscatter GGX", Blender's default
//! Principled distribution): the directional albedo `E(mu, r)` of a white GGX conductor
//! (F = 1, height-correlated Smith G2) as a table, its cosine-weighted average `E_avg(r)`, and
//! the scale that restores the energy single scattering loses (Kulla and Conty 2017, in the
//! scaling form of Turquin 2019, which Cycles 4.x applies to its GGX closures):
//!
//! ```text
//! F_ms  = F_avg E_avg / (1 - F_avg (1 - E_avg))       (per channel)
//! scale = 1 + F_ms (1 - E(wo)) / E(wo)
//! ```
//!
//! `F_avg` is the lobe's cosine-weighted average Fresnel ([`schlick_average`]). For a white
//! conductor `F_ms` = 1 and the scaled lobe's albedo is exactly 1; for any Fresnel at most 1 it
//! stays at most 1 (it becomes `F E + F_ms (1 - E)`, with `F_ms` <= 1). The scale depends on
//! `wo` only: sampling is unchanged, and the lobe is not reciprocal (as in Cycles).
//!
//! A second table holds the same integral weighted by Schlick's `(1 - wo.h)^5`, so that the
//! directional albedo of a Schlick-Fresnel lobe, `f0 E + (1 - f0) E_schlick`, is known: the
//! metallic-roughness BSDF layers its diffuse base under the specular lobe by it
//! ([`compensated_schlick_albedo`]).
//!
//! `r` is the perceptual roughness `sqrt(alpha)`. The tables (`ggx_albedo/table.rs`) are the
//! output of `tests::print_albedo_table` (a deterministic quadrature, see there; regenerate
//! with `cargo test --release --lib print_albedo_table -- --ignored --nocapture`), and the
//! tests check them against a finer quadrature.

use crate::math::Rgb;

/// Cells of the table in `sqrt(mu)` (denser toward grazing, where `E` changes fast).
const N_MU: usize = 32;
/// Cells of the table in perceptual roughness `sqrt(alpha)`, from 0 to 1.
const N_ROUGHNESS: usize = 32;

/// Row `j` and fraction of a perceptual roughness `sqrt(alpha)`.
#[inline]
fn roughness_cell(alpha: f32) -> (usize, f32) {
    let y = alpha.clamp(0.0, 1.0).sqrt() * (N_ROUGHNESS - 1) as f32;
    let j = (y as usize).min(N_ROUGHNESS - 2);
    (j, y - j as f32)
}

/// `table` at `(mu, alpha)`, bilinear.
#[inline]
fn bilinear(table: &[[f32; N_MU]; N_ROUGHNESS], mu: f32, alpha: f32) -> f32 {
    let x = mu.clamp(0.0, 1.0).sqrt() * (N_MU - 1) as f32;
    let i = (x as usize).min(N_MU - 2);
    let fx = x - i as f32;
    let (j, fy) = roughness_cell(alpha);
    let row = |j: usize| table[j][i] * (1.0 - fx) + table[j][i + 1] * fx;
    row(j) * (1.0 - fy) + row(j + 1) * fy
}

/// Single-scattering directional albedo `E(mu)` of white GGX with this `alpha` (bilinear in
/// the table).
#[inline]
pub fn albedo(mu: f32, alpha: f32) -> f32 {
    bilinear(&ALBEDO, mu, alpha)
}

/// Directional albedo at `mu` of the single-scattering GGX lobe with Schlick's Fresnel of
/// reflectance `f0`, times its [`energy_compensation`]: what the compensated lobe reflects
/// of light from `wo` (per channel), `scale (f0 E + (1 - f0) E_schlick)`.
#[inline]
pub fn compensated_schlick_albedo(f0: Rgb, mu: f32, alpha: f32) -> Rgb {
    let e = albedo(mu, alpha);
    let e_schlick = bilinear(&SCHLICK_ALBEDO, mu, alpha);
    let single = f0 * e + (Rgb::ONE - f0) * e_schlick;
    single * energy_compensation(schlick_average(f0), mu, alpha)
}

/// `E_avg = 2 \int E(mu) mu dmu` of white GGX with this `alpha` (linear in the table).
#[inline]
pub fn average_albedo(alpha: f32) -> f32 {
    let (j, fy) = roughness_cell(alpha);
    AVERAGE_ALBEDO[j] * (1.0 - fy) + AVERAGE_ALBEDO[j + 1] * fy
}

/// The cosine-weighted hemispherical average of Schlick's Fresnel with reflectance `f0`:
/// `f0 + (1 - f0) / 21`.
#[inline]
pub fn schlick_average(f0: Rgb) -> Rgb {
    f0 + (Rgb::ONE - f0) * (1.0 / 21.0)
}

/// The factor that multiplies a single-scattering GGX lobe with average Fresnel `f_average`
/// seen from a direction at cosine `mu` (module doc).
#[inline]
pub fn energy_compensation(f_average: Rgb, mu: f32, alpha: f32) -> Rgb {
    let e = albedo(mu, alpha).max(1e-3);
    let e_average = average_albedo(alpha);
    let f_ms = f_average * e_average / (Rgb::ONE - f_average * (1.0 - e_average));
    Rgb::ONE + f_ms * ((1.0 - e) / e)
}

// The tables are generated: see `tests::print_albedo_table`.
include!("ggx_albedo/table.rs");

#[cfg(test)]
pub(crate) mod tests;
