//! Thin-film interference on the Fresnel term (`KHR_materials_iridescence`; Blender's
//! Principled "Thin Film Thickness" and "Thin Film IOR"): a film of index `ior` and thickness
//! `d` (nm) between the outside (index 1) and the surface below reflects
//!
//! ```text
//! R = R12 + Rs + 2 sum_{m=1..3} (Rs - T121) (R12 R23)^(m/2) S(m OPD, m phi)
//!     Rs = T121^2 R23 / (1 - R12 R23),   T121 = 1 - R12,   OPD = 2 ior d cos(theta_2)
//!     phi = pi - phi12 + phi23           (phase shifts of the two reflections, 0 or pi)
//! ```
//!
//! per polarization (the exact Fresnel reflectances `R12` of the top interface and `R23` of
//! the bottom one), averaged over the two: the Airy summation of Belcour and Barla 2017 ("A
//! Practical Extension to Microfacet Theory for the Modeling of Varying Iridescence"), whose
//! spectral integral against the CIE colour-matching functions is the Fourier transform `S`
//! of their Gaussian fits, evaluated in closed form. The result is CIE XYZ under illuminant E;
//! it is scaled by the D65 white point and converted to linear Rec.709, then clamped to
//! [0, 1]. This is the model Cycles 4.5 evaluates for the Principled BSDF's thin film
//! (`intern/cycles/kernel/closure/bsdf_util.h`, `fresnel_iridescence`), written here from
//! the paper: exact polarized Fresnel at both interfaces, three orders, films below 30 nm
//! blended toward no film by moving the film's index toward the outside's. The glTF
//! specification's sample implementation differs in details (Schlick at both interfaces, two
//! orders, no polarization); wavetrace follows Cycles, the reference its comparisons use.
//!
//! How a material uses it ([`ThinFilm`]): the film's reflectance replaces the Fresnel term of
//! the dielectric's specular lobe (over a substrate of the material's `ior`; the
//! `KHR_materials_specular` colour scales it per channel as Cycles scales it) and of the metal
//! (over a substrate whose real index per channel gives the base colour as its normal-incidence
//! reflectance, as the glTF specification does; Cycles 4.5 has no film on metals),
//! blended with the plain Fresnel term by the iridescence factor. Glass (transmission) keeps
//! its plain Fresnel.

use crate::math::{Rgb, Vec3A};
use std::f32::consts::PI;

/// Below this thickness (nm) the film's index is blended toward the outside's (1): the
/// wave-optics summation does not hold for films much thinner than a wavelength.
const THIN_LIMIT_NM: f32 = 30.0;

/// Thin-film interference on a metallic-roughness surface's Fresnel terms
/// (`KHR_materials_iridescence`). [`ThinFilm::NONE`] (factor 0) leaves the surface as it was,
/// bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinFilm {
    /// `iridescenceFactor` (times the texture's red) in [0, 1]: the blend between the plain
    /// Fresnel term (0) and the film's (1).
    pub factor: f32,
    /// `iridescenceIor`: the film's index of refraction (> 0).
    pub ior: f32,
    /// The film's thickness in nanometres (>= 0): `iridescenceThicknessMaximum` until the
    /// thickness texture mixes it with [`Self::thickness_minimum`].
    pub thickness: f32,
    /// `iridescenceThicknessMinimum` (nm): the thickness where the texture's green is 0.
    pub thickness_minimum: f32,
}

impl Default for ThinFilm {
    fn default() -> Self {
        ThinFilm::NONE
    }
}

impl ThinFilm {
    /// No film.
    pub const NONE: ThinFilm = ThinFilm {
        factor: 0.0,
        ior: 1.3,
        thickness: 400.0,
        thickness_minimum: 100.0,
    };

    /// Whether there is a film at all.
    #[inline]
    pub fn is_present(&self) -> bool {
        self.factor > 0.0
    }

    /// The film scaled by its textures: the factor by `factor_scale` (`iridescenceTexture`'s
    /// red), the thickness mixed between the minimum and maximum by `thickness_mix`
    /// (`iridescenceThicknessTexture`'s green; 1 without a texture).
    #[inline]
    pub fn scaled(self, factor_scale: f32, thickness_mix: f32) -> ThinFilm {
        ThinFilm {
            factor: self.factor * factor_scale,
            thickness: self.thickness_minimum
                + (self.thickness - self.thickness_minimum) * thickness_mix,
            ..self
        }
    }

    /// The dielectric specular lobe's Fresnel term at `cos` = `wo.h`, given its plain
    /// (Schlick) term `plain`, its tinted normal-incidence reflectance `f0` and the
    /// substrate's index `ior`: the film over the substrate, each channel scaled toward
    /// `f0 / F0(ior)` as far as the film's reflectance lies below 1 (Cycles' tint scaling),
    /// blended with `plain` by the factor.
    #[inline]
    pub fn over_dielectric(&self, plain: Rgb, f0: Rgb, ior: f32, cos: f32) -> Rgb {
        let mut film = reflectance(cos, self.ior, ior, self.thickness);
        let r = (ior - 1.0) / (ior + 1.0);
        let f0_real = r * r;
        if f0_real > 1e-5 {
            let tint = f0 / f0_real;
            let s = ((film - Rgb::ONE) / (f0_real - 1.0)).clamp(Rgb::ZERO, Rgb::ONE);
            film *= Rgb::ONE + (tint - Rgb::ONE) * s;
        }
        plain + (film - plain) * self.factor
    }

    /// The metal's Fresnel term at `cos`, given its plain term `plain` and its base colour:
    /// per channel, the film over a substrate whose real index has the base colour as its
    /// normal-incidence reflectance, blended with `plain` by the factor.
    #[inline]
    pub fn over_conductor(&self, plain: Rgb, base_color: Rgb, cos: f32) -> Rgb {
        let ior_of = |f0: f32| {
            let s = f0.clamp(0.0, 0.9999).sqrt();
            (1.0 + s) / (1.0 - s)
        };
        let channels = base_color.to_array().map(ior_of);
        let film = if channels[0] == channels[1] && channels[1] == channels[2] {
            reflectance(cos, self.ior, channels[0], self.thickness)
        } else {
            Rgb::new(
                reflectance(cos, self.ior, channels[0], self.thickness).x,
                reflectance(cos, self.ior, channels[1], self.thickness).y,
                reflectance(cos, self.ior, channels[2], self.thickness).z,
            )
        };
        plain + (film - plain) * self.factor
    }
}

/// The Fourier transform of the CIE XYZ colour-matching functions (Belcour and Barla's
/// Gaussian fits) at optical path difference `opd` (nm) with phase shift `shift`, normalised
/// so that a constant spectrum gives Y = 1.
#[inline]
fn sensitivity(opd: f32, shift: f32) -> Vec3A {
    const AMPLITUDE: [f32; 3] = [5.4856e-13, 4.4201e-13, 5.2481e-13];
    const MEAN: [f32; 3] = [1.6810e6, 1.7953e6, 2.2084e6];
    const VARIANCE: [f32; 3] = [4.3278e9, 9.3046e9, 6.6121e9];
    const NORMALISATION: f32 = 1.0685e-7;
    let phase = 2.0 * PI * opd * 1e-9;
    let lobe = |k: usize| {
        AMPLITUDE[k]
            * (2.0 * PI * VARIANCE[k]).sqrt()
            * (MEAN[k] * phase + shift).cos()
            * (-phase * phase * VARIANCE[k]).exp()
    };
    // X has a second, short-wavelength lobe.
    let x_second =
        1.64408e-8 * (2.2399e6 * phase + shift).cos() * (-4.5282e9 * phase * phase).exp();
    Vec3A::new(lobe(0) + x_second, lobe(1), lobe(2)) / NORMALISATION
}

/// Reflection at an interface into relative index `eta` at incident cosine `cos_i` (> 0):
/// the s and p reflectances, their phase shifts (0 or pi) and the transmitted cosine, or
/// `None` at total internal reflection.
#[inline]
fn interface(cos_i: f32, eta: f32) -> Option<([f32; 2], [f32; 2], f32)> {
    let cos_t2 = 1.0 - (1.0 - cos_i * cos_i) / (eta * eta);
    if cos_t2 <= 0.0 {
        return None;
    }
    let cos_t = cos_t2.sqrt();
    let r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let phase = |r: f32| if r < 0.0 { PI } else { 0.0 };
    Some(([r_s * r_s, r_p * r_p], [phase(r_s), phase(r_p)], cos_t))
}

/// The Airy sum of one polarization (module doc), in XYZ.
#[inline]
fn airy_sum(r12: f32, r23: f32, opd: f32, phi: f32) -> Vec3A {
    if r23 >= 1.0 {
        return Vec3A::ONE;
    }
    let t121 = 1.0 - r12;
    let r123 = r12 * r23;
    let amplitude = r123.sqrt();
    let rs = t121 * t121 * r23 / (1.0 - r123);
    let mut sum = Vec3A::splat(r12 + rs);
    let mut cm = rs - t121;
    for m in 1..=3 {
        cm *= amplitude;
        let order = m as f32;
        sum += 2.0 * cm * sensitivity(order * opd, order * phi);
    }
    sum
}

/// The film's reflectance in CIE XYZ (illuminant E), averaged over polarizations: a film of
/// index `film_ior` and thickness `thickness` (nm) over a substrate of index `substrate_ior`,
/// lit from the outside (index 1) at cosine `cos`. Total internal reflection gives 1.
pub(crate) fn reflectance_xyz(
    cos: f32,
    film_ior: f32,
    substrate_ior: f32,
    thickness: f32,
) -> Vec3A {
    let thickness = thickness.max(0.0);
    let film_ior = if thickness < THIN_LIMIT_NM {
        let x = thickness / THIN_LIMIT_NM;
        1.0 + (film_ior - 1.0) * (x * x * (3.0 - 2.0 * x))
    } else {
        film_ior
    };
    let cos = cos.clamp(0.0, 1.0);
    let Some((r12, phi12, cos_film)) = interface(cos, film_ior) else {
        return Vec3A::ONE;
    };
    let Some((r23, phi23, _)) = interface(cos_film, substrate_ior / film_ior) else {
        return Vec3A::ONE;
    };
    let opd = 2.0 * film_ior * thickness * cos_film;
    let s = airy_sum(r12[0], r23[0], opd, PI - phi12[0] + phi23[0]);
    let p = airy_sum(r12[1], r23[1], opd, PI - phi12[1] + phi23[1]);
    0.5 * (s + p)
}

/// The D65 white point in CIE XYZ (Y = 1): the chromatic adaptation from illuminant E that
/// Cycles applies as a scale.
const WHITE_D65: Vec3A = Vec3A::new(0.95047, 1.0, 1.08883);

/// CIE XYZ (D65) to linear Rec.709 RGB (sRGB primaries).
#[inline]
fn xyz_to_rgb(xyz: Vec3A) -> Rgb {
    Rgb::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
}

/// The film's reflectance (see [`reflectance_xyz`]) in linear Rec.709 RGB, clamped to [0, 1].
#[inline]
pub fn reflectance(cos: f32, film_ior: f32, substrate_ior: f32, thickness: f32) -> Rgb {
    let xyz = reflectance_xyz(cos, film_ior, substrate_ior, thickness);
    xyz_to_rgb(xyz * WHITE_D65).clamp(Rgb::ZERO, Rgb::ONE)
}

#[cfg(test)]
mod tests;
