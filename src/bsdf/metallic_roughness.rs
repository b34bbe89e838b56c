//! The glTF 2.0 metallic-roughness material (specification, appendix B) with
//! `KHR_materials_specular`, `KHR_materials_ior` and `KHR_materials_transmission`:
//!
//! ```text
//! metal      = specular_brdf(alpha) * schlick(f0 = base_color, |wo.h|)
//! opaque     = (1 - specular * max3(E_spec(wo))) * base_color / pi + specular * fr * specular_brdf(alpha)
//!              with fr = schlick(f0 = min(((ior-1)/(ior+1))^2 * specular_color, 1), |wo.h|)
//!              and E_spec(wo) the specular lobe's directional albedo (per channel)
//! glass      = rough dielectric (Walter et al. 2007): F * specular_brdf + (1 - F) * base_color * specular_btdf
//!              with F the exact dielectric Fresnel of the microfacet
//! f          = metallic * metal + (1 - metallic) * ((1 - transmission) * opaque + transmission * glass)
//! specular_brdf = D G2 / (4 |wo.z| |wi.z|),  GGX D with alpha = roughness^2, height-correlated Smith G2
//! ```
//!
//! The metal and the opaque dielectric's specular lobe are single-scattering GGX times the
//! energy compensation of [`ggx_albedo`] (Blender's default "Multiscatter GGX": the energy
//! that single scattering loses to masking comes back, so a white metal reflects all light at
//! every roughness). Always on, for every file (the glTF specification's BRDF is single
//! scattering; Cycles renders Blender's and imported files with multiscatter GGX). The
//! rough glass part is compensated too, both lobes by `1 / E` of the white rough dielectric at
//! `wo` ([`super::ggx_glass_albedo`], as Cycles compensates its GGX glass), so white rough glass
//! reflects and transmits all light from either side.
//!
//! The opaque dielectric is layered as Blender's Principled BSDF is, not as the glTF
//! specification's `fresnel_mix` (which takes `1 - F` per microfacet and reflects up to 1.43
//! of the light at grazing angles over a white base): the diffuse base is scaled by one minus
//! the specular layer's directional albedo at `wo` ([`ggx_albedo::compensated_schlick_albedo`]),
//! so the pair conserves energy; like the compensation it depends on `wo` alone.
//!
//! The spec writes the transmissive dielectric as `fresnel_mix(base = specular_btdf, layer =
//! specular_brdf)`; here that pair is the physically based rough dielectric, so that
//! transmission conserves energy and reduces to the seed's smooth glass as roughness goes to 0
//! (smooth glass itself stays [`super::Bsdf::Dielectric`]). Transmission refracts (a volume
//! boundary, `+z` = outside), and `KHR_materials_specular` does not apply to it.
//!
//! `KHR_materials_anisotropy` ([`Anisotropy`]) makes every microfacet lobe (metal, specular
//! layer, rough glass) anisotropic GGX ([`Ggx::Anisotropic`]); its energy compensation reads
//! the albedo tables at the geometric mean of the two alphas, as Cycles does. Isotropic
//! surfaces run the isotropic functions, unchanged.
//!
//! The diffuse lobe carries Blender's Bump Map Correction ([`BumpShadowing`]) where a normal
//! map tilts the shading normal.
//!
//! A thin film (`KHR_materials_iridescence`, [`ThinFilm`]) replaces the Fresnel terms of the
//! metal and of the opaque dielectric's specular lobe by the film's, blended by its factor;
//! the diffuse base is then layered under the film's specular albedo estimate (Cycles': the
//! film's Fresnel term at `wo` times the compensated lobe's albedo), and the multiscatter
//! compensation keeps the film-less average Fresnel term (as Cycles' does). Sampling is
//! unchanged. Without a film (factor 0) every value is computed as before, bit for bit.
//!
//! Surfaces without transmission are two-sided: they reflect on the side `wo` is on.
//!
//! Sampling picks the diffuse lobe (cosine) or the microfacet lobe (visible normals) by their
//! approximate albedos at `wo`, then reflection or refraction about the sampled normal by the
//! Fresnel-weighted split; `pdf` is the combined density of all of that, and a sample's weight
//! is `eval * |cos| / pdf` (one-sample MIS over lobes).

use super::BsdfSample;
use super::anisotropy::Anisotropy;
use super::bump_shadowing::BumpShadowing;
use super::dielectric::{FresnelModel, fresnel};
use super::ggx_albedo::{self, compensated_schlick_albedo, energy_compensation};
use super::ggx_glass_albedo::glass_energy_compensation;
use super::lambert;
use super::microfacet::{
    Ggx, alpha_from_roughness, reflect_about, refract_about, refraction_half_vector,
};
use super::thin_film::ThinFilm;
use crate::math::sampling::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use crate::math::{Rgb, Vec2, Vec3A, luminance, max_component};
use std::f32::consts::FRAC_1_PI;

/// Parameters of a glTF metallic-roughness surface, linear RGB.
///
/// Scene-file syntax (see README):
/// ```toml
/// material = { type = "pbr", base_color = [0.8, 0.8, 0.8], metallic = 0.0, roughness = 0.5,
///              specular = 1.0, specular_color = [1, 1, 1], ior = 1.5, transmission = 0.0 }
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetallicRoughness {
    /// `baseColorFactor` (times the texture): diffuse albedo, metal F0 and transmission tint.
    pub base_color: Rgb,
    /// `metallicFactor` in [0, 1]: the conductor's share.
    pub metallic: f32,
    /// GGX alpha = `roughnessFactor`^2 (clamped to [`super::microfacet::MIN_ALPHA`]).
    pub alpha: f32,
    /// `KHR_materials_ior`: inside over outside index of the dielectric (default 1.5).
    pub ior: f32,
    /// `KHR_materials_specular` `specularFactor` in [0, 1]: strength of the dielectric's
    /// specular layer (0 leaves exactly the Lambertian base).
    pub specular: f32,
    /// `KHR_materials_specular` `specularColorFactor`: tints the dielectric's F0.
    pub specular_color: Rgb,
    /// `KHR_materials_transmission` `transmissionFactor` in [0, 1]: the rough glass's share
    /// of the dielectric.
    pub transmission: f32,
    /// Blender's Bump Map Correction on the diffuse lobe (none unless a normal map tilts the
    /// shading normal at this hit; set by [`super::Bsdf::with_bump_shadowing`]).
    pub bump: BumpShadowing,
    /// `KHR_materials_iridescence`: thin-film interference on the metal's and the opaque
    /// dielectric's Fresnel terms ([`ThinFilm::NONE`]: none, and exactly the code path of a
    /// surface without it).
    pub film: ThinFilm,
    /// `KHR_materials_anisotropy` ([`Anisotropy::NONE`]: isotropic).
    pub anisotropy: Anisotropy,
}

impl Default for MetallicRoughness {
    /// glTF's defaults: white, fully metallic, fully rough, ior 1.5, full specular, opaque.
    fn default() -> Self {
        MetallicRoughness {
            base_color: Rgb::ONE,
            metallic: 1.0,
            alpha: 1.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Rgb::ONE,
            transmission: 0.0,
            bump: BumpShadowing::NONE,
            film: ThinFilm::NONE,
            anisotropy: Anisotropy::NONE,
        }
    }
}

/// Schlick's Fresnel with normal-incidence reflectance `f0` (per channel) at cosine `c`.
#[inline]
fn schlick(f0: Rgb, c: f32) -> Rgb {
    let m = (1.0 - c).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (Rgb::ONE - f0) * (m2 * m2 * m)
}

/// Exact dielectric Fresnel reflectance at cosine `c` into relative index `eta`.
#[inline]
fn dielectric_reflectance(c: f32, eta: f32) -> f32 {
    fresnel(c, eta, FresnelModel::Exact).0
}

impl MetallicRoughness {
    /// Parameters from glTF's core factors (`roughness` is perceptual; alpha = roughness^2);
    /// the extensions keep their defaults.
    pub fn new(base_color: Rgb, metallic: f32, roughness: f32) -> Self {
        MetallicRoughness {
            base_color,
            metallic,
            alpha: alpha_from_roughness(roughness),
            ..Default::default()
        }
    }

    /// The albedo if this surface is exactly Lambertian: a non-metal without specular layer
    /// or transmission (Blender's "Specular IOR Level 0").
    pub fn as_lambertian(&self) -> Option<Rgb> {
        (self.metallic == 0.0 && self.specular == 0.0 && self.transmission == 0.0)
            .then_some(self.base_color)
    }

    /// Whether it reflects and transmits nothing.
    pub fn is_black(&self) -> bool {
        self.base_color == Rgb::ZERO
            && self.transmission == 0.0
            && (self.metallic == 1.0 || self.specular == 0.0 || self.specular_color == Rgb::ZERO)
    }

    /// The GGX distribution of the microfacet lobes.
    #[inline]
    fn ggx(&self) -> Ggx {
        self.anisotropy.ggx(self.alpha)
    }

    /// The dielectric's tinted normal-incidence reflectance (KHR_materials_specular).
    #[inline]
    fn dielectric_f0(&self) -> Rgb {
        let r = (self.ior - 1.0) / (self.ior + 1.0);
        (r * r * self.specular_color).min(Rgb::ONE)
    }

    /// Weights of the opaque-dielectric, glass and metal parts.
    #[inline]
    fn shares(&self) -> (f32, f32, f32) {
        let dielectric = 1.0 - self.metallic;
        (
            dielectric * (1.0 - self.transmission),
            dielectric * self.transmission,
            self.metallic,
        )
    }

    /// Moves the pair to `wo`'s side (`wo.z > 0`) and returns the relative index seen from there.
    #[inline]
    fn to_upper(self, wo: Vec3A, wi: Vec3A) -> (Vec3A, Vec3A, f32) {
        if wo.z > 0.0 {
            (wo, wi, self.ior)
        } else {
            let flip = Vec3A::new(1.0, 1.0, -1.0);
            (wo * flip, wi * flip, 1.0 / self.ior)
        }
    }

    /// Probability of the diffuse lobe for `wo` (upper side); the rest goes to the microfacets.
    #[inline]
    fn diffuse_probability(&self, wo: Vec3A, eta: f32) -> f32 {
        let (_, glass, metal) = self.shares();
        let diffuse = self.diffuse_albedo();
        if diffuse <= 0.0 {
            return 0.0;
        }
        let (r, t) = self.microfacet_split(wo.z, eta);
        let present = metal > 0.0 || glass > 0.0 || self.specular > 0.0;
        let microfacet = if present { (r + t).max(1e-4) } else { 0.0 };
        diffuse / (diffuse + microfacet)
    }

    /// Approximate albedo (luminance) of the diffuse lobe.
    #[inline]
    fn diffuse_albedo(&self) -> f32 {
        let (opaque, _, _) = self.shares();
        opaque
            * luminance(self.base_color)
            * (1.0 - self.specular * max_component(self.dielectric_f0()))
    }

    /// Approximate directional albedo (luminance) at `wo`, for choosing among the lobes of
    /// layers over this surface.
    #[inline]
    pub(super) fn approximate_albedo(&self, wo: Vec3A) -> f32 {
        if let Some(albedo) = self.as_lambertian() {
            return luminance(albedo);
        }
        let (wo, _, eta) = self.to_upper(wo, Vec3A::Z);
        let (r, t) = self.microfacet_split(wo.z, eta);
        self.diffuse_albedo() + r + t
    }

    /// Approximate reflected and transmitted albedos of the microfacet lobe at cosine `c`.
    #[inline]
    fn microfacet_split(&self, c: f32, eta: f32) -> (f32, f32) {
        let (opaque, glass, metal) = self.shares();
        let f = dielectric_reflectance(c, eta);
        let reflected = metal * luminance(schlick(self.base_color, c))
            + opaque * self.specular * max_component(schlick(self.dielectric_f0(), c))
            + glass * f;
        let transmitted = glass * (1.0 - f) * luminance(self.base_color);
        (reflected, transmitted)
    }

    /// Probability of reflecting (rather than refracting) about a normal at cosine `c` to `wo`.
    #[inline]
    fn reflect_probability(&self, c: f32, eta: f32) -> f32 {
        let (r, t) = self.microfacet_split(c, eta);
        if t <= 0.0 { 1.0 } else { r / (r + t) }
    }

    /// The opaque dielectric's specular albedo at cosine `mu` under the thin film, given the
    /// film-less one `plain` ([`compensated_schlick_albedo`]): the film's Fresnel term at
    /// `mu` times the compensated lobe's albedo without Fresnel (`E(mu)` times the
    /// compensation), Cycles' estimate for thin films (exact for a smooth surface; a rough
    /// one averages the Fresnel term over the microfacets around `mu`), blended with `plain`
    /// by the factor as the lobe's Fresnel term is.
    #[inline(never)]
    fn film_layer_albedo(&self, plain: Rgb, f0: Rgb, mu: f32) -> Rgb {
        let fresnel = self.film.over_dielectric(Rgb::ZERO, f0, self.ior, mu);
        let alpha = self.ggx().equivalent_alpha(); // of the albedo tables
        let lobe = ggx_albedo::albedo(mu, alpha)
            * energy_compensation(ggx_albedo::schlick_average(f0), mu, alpha);
        // over_dielectric blended the film with zero: add the plain share back.
        fresnel * lobe + plain * (1.0 - self.film.factor)
    }

    /// BSDF value f(wo, wi).
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> Rgb {
        if let Some(albedo) = self.as_lambertian() {
            return lambert::eval(albedo, wo, wi) * self.bump.factor(wi);
        }
        if wo.z == 0.0 || wi.z == 0.0 {
            return Rgb::ZERO;
        }
        let bump = self.bump.factor(wi); // of the unflipped pair: it compares wi with Ns
        let (wo, wi, eta) = self.to_upper(wo, wi);
        let (opaque, glass, metal) = self.shares();
        if wi.z > 0.0 {
            // --- Reflection: every part contributes.
            let h = (wo + wi).normalize();
            let c = wo.dot(h);
            let ggx = self.ggx();
            let alpha = ggx.equivalent_alpha(); // of the albedo tables
            let specular_brdf =
                ggx.distribution(h) * ggx.masking_shadowing(wo, wi) / (4.0 * wo.z * wi.z);
            let mut f = Rgb::ZERO;
            if metal > 0.0 {
                let compensation =
                    energy_compensation(ggx_albedo::schlick_average(self.base_color), wo.z, alpha);
                let mut fresnel = schlick(self.base_color, c);
                if self.film.is_present() {
                    fresnel = self.film.over_conductor(fresnel, self.base_color, c);
                }
                f += metal * specular_brdf * fresnel * compensation;
            }
            if opaque > 0.0 {
                // Blender's layering: the diffuse base gets what the compensated specular
                // layer does not reflect of the light from wo (its directional albedo).
                let f0 = self.dielectric_f0();
                let mut layer = compensated_schlick_albedo(f0, wo.z, alpha);
                if self.film.is_present() {
                    layer = self.film_layer_albedo(layer, f0, wo.z);
                }
                let base = (1.0 - self.specular * max_component(layer)).max(0.0)
                    * (FRAC_1_PI * bump)
                    * self.base_color;
                let compensation =
                    energy_compensation(ggx_albedo::schlick_average(f0), wo.z, alpha);
                let mut fr = schlick(f0, c);
                if self.film.is_present() {
                    fr = self.film.over_dielectric(fr, f0, self.ior, c);
                }
                f += opaque * (base + self.specular * specular_brdf * fr * compensation);
            }
            if glass > 0.0 {
                let compensation = glass_energy_compensation(wo.z, ggx.glass_alpha(), eta);
                f += Rgb::splat(
                    glass * specular_brdf * dielectric_reflectance(c, eta) * compensation,
                );
            }
            f
        } else {
            // --- Transmission: only the glass part, through a microfacet facing both directions.
            if glass <= 0.0 {
                return Rgb::ZERO;
            }
            let h = refraction_half_vector(wo, wi, eta);
            let (c_o, c_i) = (wo.dot(h), wi.dot(h));
            if c_o <= 0.0 || c_i >= 0.0 {
                return Rgb::ZERO;
            }
            let denominator = c_i + c_o / eta;
            let ggx = self.ggx();
            let btdf = ggx.distribution(h)
                * ggx.masking_shadowing(wo, wi)
                * (1.0 - dielectric_reflectance(c_o, eta))
                * (c_i * c_o / (wi.z * wo.z * denominator * denominator)).abs()
                / (eta * eta); // radiance is compressed into the denser side, as in dielectric.rs
            glass * btdf * glass_energy_compensation(wo.z, ggx.glass_alpha(), eta) * self.base_color
        }
    }

    /// Solid-angle density with which [`Self::sample`] returns `wi`.
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if self.as_lambertian().is_some() {
            return lambert::pdf(wo, wi);
        }
        if wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let (wo, wi, eta) = self.to_upper(wo, wi);
        let p_diffuse = self.diffuse_probability(wo, eta);
        if wi.z > 0.0 {
            let h = (wo + wi).normalize();
            let c = wo.dot(h);
            let microfacet = self.ggx().visible_normal_pdf(wo, h) / (4.0 * c);
            p_diffuse * cosine_hemisphere_pdf(wi.z)
                + (1.0 - p_diffuse) * self.reflect_probability(c, eta) * microfacet
        } else {
            if self.shares().1 <= 0.0 {
                return 0.0;
            }
            let h = refraction_half_vector(wo, wi, eta);
            let (c_o, c_i) = (wo.dot(h), wi.dot(h));
            if c_o <= 0.0 || c_i >= 0.0 {
                return 0.0;
            }
            let denominator = c_i + c_o / eta;
            let jacobian = c_i.abs() / (denominator * denominator);
            (1.0 - p_diffuse)
                * (1.0 - self.reflect_probability(c_o, eta))
                * self.ggx().visible_normal_pdf(wo, h)
                * jacobian
        }
    }

    /// Samples `wi`: `u_lobe` picks the lobe (diffuse, then reflection or refraction), `u`
    /// the direction.
    pub fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if let Some(albedo) = self.as_lambertian() {
            let sample = lambert::sample(albedo, wo, u)?;
            let bump = self.bump.factor(sample.wi);
            return Some(BsdfSample {
                weight: sample.weight * bump,
                ..sample
            });
        }
        if wo.z == 0.0 {
            return None;
        }
        let (wo_up, _, eta) = self.to_upper(wo, Vec3A::Z);
        let p_diffuse = self.diffuse_probability(wo_up, eta);
        let wi_up = if u_lobe < p_diffuse {
            sample_cosine_hemisphere(u)
        } else {
            let u_split = ((u_lobe - p_diffuse) / (1.0 - p_diffuse)).min(1.0);
            let h = self.ggx().sample_visible_normal(wo_up, u);
            let c = wo_up.dot(h);
            if c <= 0.0 {
                return None;
            }
            if u_split < self.reflect_probability(c, eta) {
                let wi = reflect_about(wo_up, h);
                if wi.z <= 0.0 {
                    return None;
                }
                wi
            } else {
                let wi = refract_about(wo_up, h, eta)?;
                if wi.z >= 0.0 {
                    return None;
                }
                wi
            }
        };
        let wi = if wo.z > 0.0 {
            wi_up
        } else {
            wi_up * Vec3A::new(1.0, 1.0, -1.0)
        };
        let pdf = self.pdf(wo, wi);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        BsdfSample::non_delta(wi, self.eval(wo, wi), pdf)
    }
}

#[cfg(test)]
mod tests;
