//! `KHR_materials_clearcoat` and `KHR_materials_sheen` layered over the glTF
//! metallic-roughness surface ([`MetallicRoughness`]), as the two specifications write them:
//!
//! ```text
//! sheen_material = sheen_color * sheen_brdf + base * (1 - max3(sheen_color) * max(E(wo), E(wi)))
//! coated         = (1 - clearcoat * Fc) * sheen_material + clearcoat * Fc * coat_brdf
//!                  Fc = 0.04 + 0.96 (1 - |wo.z|)^5     (Schlick, F0 of ior 1.5, at N.V)
//!                  coat_brdf = D G2 / (4 |wo.z| |wi.z|),  GGX alpha = clearcoatRoughness^2
//! ```
//!
//! `sheen_brdf` is [`sheen::brdf`] over [`sheen::normalization`], `E` its directional albedo
//! ([`sheen::albedo`]); the `max(E(wo), E(wi))` is the specification's
//! `min(1 - m E(VdotN), 1 - m E(LdotN))`, which keeps the sheen layer reciprocal. The coat's
//! Fresnel at N.V, not V.H, is the specification's choice: it makes the layering
//! energy-conserving (the coat takes `clearcoat Fc` of the light and reflects at most that)
//! but not reciprocal. Transmitted light (rough glass below) is scaled by the same
//! `(1 - clearcoat Fc)` and sheen factor. The layers are on the side of `wo`, as two-sided
//! surfaces are (from inside glass, the coat reflects back inside).
//!
//! The coat has its own normal: its `clearcoatNormalTexture` (Blender's Coat Normal) where it
//! has one ([`Layered::coat_normal`]), else the smooth (interpolated) normal, also where a
//! normal map tilts the base's shading normal, as the specification says of a coat without
//! its own normal texture ([`super::BumpShadowing::smooth_normal`], the same vector the
//! base's Bump Map Correction uses). Its lobe and its Fresnel `Fc` are evaluated in the frame
//! of that normal. Blender's Bump Map Correction does not apply to the coat (Cycles applies it
//! to diffuse closures only).
//!
//! Sampling picks the coat (GGX visible normals), the sheen (uniform hemisphere: the lobe
//! peaks at grazing angles, where a cosine would sample it least) or the base (its own
//! sampling) by their approximate albedos at `wo`; `pdf` is the mixture's density and a
//! sample's weight is `eval * |cos| / pdf` (one-sample MIS over lobes).

use super::metallic_roughness::MetallicRoughness;
use super::microfacet::{
    distribution, masking_shadowing, reflect_about, sample_visible_normal, visible_normal_pdf,
};
use super::{BsdfSample, sheen};
use crate::math::frame::Frame;
use crate::math::{Rgb, Vec2, Vec3, Vec3A, luminance, max_component};
use std::f32::consts::{FRAC_1_PI, TAU};

/// Normal-incidence reflectance of the coat (ior 1.5).
const COAT_F0: f32 = 0.04;
/// Density of uniform hemisphere sampling.
const UNIFORM_HEMISPHERE_PDF: f32 = 0.5 * FRAC_1_PI;

/// A metallic-roughness base under a clear coat and a sheen. Build it with
/// [`super::Bsdf::layered`], which keeps a base without layers exactly what it was.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layered {
    /// The surface under the layers.
    pub base: MetallicRoughness,
    /// `clearcoatFactor` in [0, 1]: the coat's strength.
    pub clearcoat: f32,
    /// GGX alpha of the coat = `clearcoatRoughnessFactor`^2 (clamped to
    /// [`super::microfacet::MIN_ALPHA`]).
    pub clearcoat_alpha: f32,
    /// `sheenColorFactor`, linear RGB in [0, 1] (black: no sheen).
    pub sheen_color: Rgb,
    /// `sheenRoughnessFactor` in [0, 1] (clamped to [`sheen::MIN_ROUGHNESS`] when used).
    pub sheen_roughness: f32,
    /// The coat's own normal in the shading frame, from `clearcoatNormalTexture` (set by
    /// [`super::Bsdf::with_coat_normal`]); `None`: the smooth normal.
    pub coat_normal: Option<Vec3>,
}

/// Schlick's Fresnel of the coat at cosine `c`.
#[inline]
fn coat_fresnel(c: f32) -> f32 {
    let m = (1.0 - c).clamp(0.0, 1.0);
    let m2 = m * m;
    COAT_F0 + (1.0 - COAT_F0) * (m2 * m2 * m)
}

/// Uniform direction on the upper hemisphere.
#[inline]
fn sample_uniform_hemisphere(u: Vec2) -> Vec3A {
    let z = u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u.y;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// What `wo` decides: the coat's share, the sheen's albedo scaling, and the lobe choice.
struct AtWo {
    /// `clearcoat * Fc(|wo.z|)`.
    coat: f32,
    /// `E(|wo.z|)` of the sheen lobe (0 without sheen).
    sheen_albedo: f32,
    /// Probabilities of the coat and sheen lobes (the rest goes to the base).
    p_coat: f32,
    p_sheen: f32,
}

impl Layered {
    /// Whether there is a layer at all.
    #[inline]
    pub fn has_layers(&self) -> bool {
        self.clearcoat > 0.0 || self.has_sheen()
    }

    #[inline]
    fn has_sheen(&self) -> bool {
        max_component(self.sheen_color) > 0.0
    }

    /// Whether it reflects and transmits nothing.
    pub fn is_black(&self) -> bool {
        self.base.is_black() && !self.has_layers()
    }

    /// The sheen's albedo at cosine `mu` (0 without sheen).
    #[inline]
    fn sheen_albedo(&self, mu: f32) -> f32 {
        if self.has_sheen() {
            sheen::albedo(mu, self.sheen_roughness)
        } else {
            0.0
        }
    }

    /// The coat's frame: the smooth normal where a normal map tilts the base's shading
    /// normal (the specification's coat without `clearcoatNormalTexture` is not normal-mapped),
    /// `None` where it is the shading frame itself.
    #[inline]
    fn coat_frame(&self) -> Option<Frame> {
        let n = self.coat_normal.unwrap_or(self.base.bump.smooth_normal);
        (n != Vec3::Z).then(|| Frame::from_normal(Vec3A::from(n)))
    }

    /// `w` (shading frame) in the coat's frame.
    #[inline]
    fn in_coat_frame(frame: &Option<Frame>, w: Vec3A) -> Vec3A {
        match frame {
            Some(frame) => frame.to_local(w),
            None => w,
        }
    }

    #[inline]
    fn at_wo(&self, wo: Vec3A) -> AtWo {
        let mu = Self::in_coat_frame(&self.coat_frame(), wo).z.abs();
        let coat = self.clearcoat * coat_fresnel(mu);
        let sheen_albedo = self.sheen_albedo(mu);
        let sheen_max = max_component(self.sheen_color);
        let under = 1.0 - coat;
        let w_coat = coat;
        let w_sheen = under * luminance(self.sheen_color) * sheen_albedo.min(1.0);
        let w_base =
            under * (1.0 - sheen_max * sheen_albedo).max(0.0) * self.base.approximate_albedo(wo);
        let total = w_coat + w_sheen + w_base;
        let (p_coat, p_sheen) = if total > 0.0 {
            (w_coat / total, w_sheen / total)
        } else {
            (0.0, 0.0)
        };
        AtWo {
            coat,
            sheen_albedo,
            p_coat,
            p_sheen,
        }
    }

    /// Moves the pair to `wo`'s side (`wo.z > 0`).
    #[inline]
    fn to_upper(wo: Vec3A, wi: Vec3A) -> (Vec3A, Vec3A) {
        if wo.z > 0.0 {
            (wo, wi)
        } else {
            let flip = Vec3A::new(1.0, 1.0, -1.0);
            (wo * flip, wi * flip)
        }
    }

    /// BSDF value f(wo, wi).
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> Rgb {
        if wo.z == 0.0 || wi.z == 0.0 {
            return Rgb::ZERO;
        }
        let (wo_up, wi_up) = Self::to_upper(wo, wi);
        let at = self.at_wo(wo);
        let base = self.base.eval(wo, wi);
        // --- Sheen over the base.
        let under = if self.has_sheen() {
            let sheen_i = self.sheen_albedo(wi_up.z.abs());
            let scaling =
                (1.0 - max_component(self.sheen_color) * at.sheen_albedo.max(sheen_i)).max(0.0);
            let lobe = if wi_up.z > 0.0 {
                let alpha_g = sheen::alpha_of(self.sheen_roughness);
                sheen::brdf(alpha_g, wo_up, wi_up) / sheen::normalization(at.sheen_albedo, sheen_i)
            } else {
                0.0
            };
            self.sheen_color * lobe + base * scaling
        } else {
            base
        };
        // --- The coat over both, in its own frame.
        if self.clearcoat > 0.0 {
            let frame = self.coat_frame();
            let (wo_c, wi_c) = Self::to_upper(
                Self::in_coat_frame(&frame, wo),
                Self::in_coat_frame(&frame, wi),
            );
            let coat = if wi_c.z > 0.0 && wo_c.z > 0.0 {
                let h = (wo_c + wi_c).normalize();
                distribution(self.clearcoat_alpha, h)
                    * masking_shadowing(self.clearcoat_alpha, wo_c, wi_c)
                    / (4.0 * wo_c.z * wi_c.z)
            } else {
                0.0
            };
            under * (1.0 - at.coat) + Rgb::splat(at.coat * coat)
        } else {
            under
        }
    }

    /// Solid-angle density with which [`Self::sample`] returns `wi`.
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if wo.z == 0.0 || wi.z == 0.0 {
            return 0.0;
        }
        let (_, wi_up) = Self::to_upper(wo, wi);
        let at = self.at_wo(wo);
        let p_base = (1.0 - at.p_coat - at.p_sheen).max(0.0);
        let mut pdf = if p_base > 0.0 {
            p_base * self.base.pdf(wo, wi)
        } else {
            0.0
        };
        if at.p_coat > 0.0 {
            let frame = self.coat_frame();
            let (wo_c, wi_c) = Self::to_upper(
                Self::in_coat_frame(&frame, wo),
                Self::in_coat_frame(&frame, wi),
            );
            if wi_c.z > 0.0 && wo_c.z > 0.0 {
                let h = (wo_c + wi_c).normalize();
                let c = wo_c.dot(h);
                if c > 0.0 {
                    pdf +=
                        at.p_coat * visible_normal_pdf(self.clearcoat_alpha, wo_c, h) / (4.0 * c);
                }
            }
        }
        if wi_up.z > 0.0 {
            pdf += at.p_sheen * UNIFORM_HEMISPHERE_PDF;
        }
        pdf
    }

    /// Samples `wi`: `u_lobe` picks the lobe (coat, sheen, or the base, which reuses the rest
    /// of `u_lobe` for its own choice), `u` the direction.
    pub fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let at = self.at_wo(wo);
        let flip = |w: Vec3A| {
            if wo.z > 0.0 {
                w
            } else {
                w * Vec3A::new(1.0, 1.0, -1.0)
            }
        };
        let wi = if u_lobe < at.p_coat {
            let frame = self.coat_frame();
            let wo_c = Self::in_coat_frame(&frame, wo);
            let side = if wo_c.z > 0.0 { 1.0 } else { -1.0 };
            let wo_c = wo_c * Vec3A::new(1.0, 1.0, side);
            if wo_c.z <= 0.0 {
                return None;
            }
            let h = sample_visible_normal(self.clearcoat_alpha, wo_c, u);
            let wi_c = reflect_about(wo_c, h);
            if wo_c.dot(h) <= 0.0 || wi_c.z <= 0.0 {
                return None;
            }
            let wi_c = wi_c * Vec3A::new(1.0, 1.0, side);
            match frame {
                Some(frame) => frame.to_world(wi_c),
                None => wi_c,
            }
        } else if u_lobe < at.p_coat + at.p_sheen {
            flip(sample_uniform_hemisphere(u))
        } else {
            let p_base = 1.0 - at.p_coat - at.p_sheen;
            if p_base <= 0.0 {
                return None;
            }
            let u_base =
                ((u_lobe - at.p_coat - at.p_sheen) / p_base).clamp(0.0, 1.0 - f32::EPSILON);
            self.base.sample(wo, u_base, u)?.wi
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
