//! Scattering math, free of scenes and batches.
//!
//! Conventions (used everywhere in the crate):
//! - directions are in the local shading frame, where the normal is `+z`;
//! - `wo` points toward the previous path vertex and `wi` is the sampled direction, both
//!   pointing away from the surface;
//! - `eval` returns the BSDF value f (without the cosine), `pdf` the solid-angle density of
//!   `sample`, and a sample's `weight` is `f |cos wi| / pdf` (for delta lobes, the lobe's
//!   throughput factor);
//! - `eta` is the relative index of refraction across an interface, transmitted over
//!   incident side.

pub mod anisotropy;
pub mod bump_shadowing;
#[cfg(test)]
pub(crate) mod chi_square;
pub mod dielectric;
pub mod ggx_albedo;
pub mod ggx_glass_albedo;
pub mod lambert;
pub mod layered;
pub mod metallic_roughness;
pub mod microfacet;
pub mod mirror;
pub mod sheen;
pub mod thin_film;

pub use anisotropy::{Anisotropy, AnisotropyMapping};
pub use bump_shadowing::BumpShadowing;
pub use dielectric::FresnelModel;
pub use layered::Layered;
pub use metallic_roughness::MetallicRoughness;
pub use thin_film::ThinFilm;

use crate::math::{Rgb, Vec2, Vec3A, Vec4};

/// A render-side scattering model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// Ideal diffuse reflection (two-sided: it reflects on the side `wo` is on).
    Lambertian {
        /// Hemispherical reflectance.
        albedo: Rgb,
    },
    /// Perfect specular reflection.
    Mirror {
        /// Reflectance.
        tint: Rgb,
    },
    /// Smooth dielectric; `+z` is the outside.
    Dielectric {
        /// Inside over outside index of refraction.
        ior: f32,
        /// Fresnel equations in use.
        fresnel: FresnelModel,
        /// Colour filter on both lobes.
        tint: Rgb,
    },
    /// glTF metallic-roughness microfacet surface (with the specular, ior and transmission
    /// extensions). Build it with [`Bsdf::metallic_roughness`], which keeps exactly
    /// Lambertian parameter sets Lambertian.
    MetallicRoughness(MetallicRoughness),
    /// A metallic-roughness surface under `KHR_materials_clearcoat` and
    /// `KHR_materials_sheen` layers. Build it with [`Bsdf::layered`], which keeps a surface
    /// without layers [`Bsdf::MetallicRoughness`] (or Lambertian).
    Layered(Layered),
    /// `KHR_materials_unlit`: a surface that shows `color` to every ray that hits it and
    /// reflects nothing (a display convention, not a light: the shade stage adds the colour
    /// as radiance seen along the ray; it is no light source for next-event estimation).
    Unlit {
        /// The radiance shown: base colour (times texture and vertex colour), linear RGB.
        color: Rgb,
    },
}

/// A sampled direction with its path-throughput factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    /// Sampled direction, local frame.
    pub wi: Vec3A,
    /// `f |cos wi| / pdf`: what the path throughput is multiplied by.
    pub weight: Rgb,
    /// Solid-angle density of `wi` (for delta lobes, the discrete probability of the lobe).
    pub pdf: f32,
    /// Whether the sample came from a delta lobe (mirror or smooth glass).
    pub is_delta: bool,
}

impl BsdfSample {
    /// The sample of a non-delta direction `wi` from its density `pdf` and BSDF value `f`;
    /// `None` when the density is zero or NaN, or the weight is not finite.
    #[inline]
    pub(crate) fn non_delta(wi: Vec3A, f: Rgb, pdf: f32) -> Option<Self> {
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let weight = f * (wi.z.abs() / pdf);
        weight.is_finite().then_some(BsdfSample {
            wi,
            weight,
            pdf,
            is_delta: false,
        })
    }
}

impl Bsdf {
    /// The render-side model of glTF metallic-roughness parameters: [`Bsdf::Lambertian`] when
    /// they reduce to it exactly (a non-metal with `specular` 0 and no transmission).
    pub fn metallic_roughness(params: MetallicRoughness) -> Self {
        match params.as_lambertian() {
            Some(albedo) => Bsdf::Lambertian { albedo },
            None => Bsdf::MetallicRoughness(params),
        }
    }

    /// The render-side model of a metallic-roughness surface under layers: exactly
    /// [`Bsdf::metallic_roughness`] of the base when there is no layer (clearcoat 0, black
    /// sheen), so that surfaces without the extensions are unchanged.
    pub fn layered(layered: Layered) -> Self {
        if layered.has_layers() {
            Bsdf::Layered(layered)
        } else {
            Bsdf::metallic_roughness(layered.base)
        }
    }

    /// Whether every lobe is a delta distribution (no light sampling is possible).
    #[inline]
    pub fn is_delta(&self) -> bool {
        !matches!(
            self,
            Bsdf::Lambertian { .. } | Bsdf::MetallicRoughness(_) | Bsdf::Layered(_)
        )
    }

    /// The factor `1 / eta^2` by which a sample transmitted from `wo` (local frame) through
    /// this surface compresses radiance (part of the sample's weight: see dielectric.rs); 1
    /// for reflection and for surfaces that transmit nothing. Russian roulette divides it out,
    /// since it cancels when the path leaves the medium again.
    #[inline]
    pub fn radiance_compression(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let ior = match *self {
            Bsdf::Dielectric { ior, .. } => ior,
            Bsdf::MetallicRoughness(params) => params.ior,
            Bsdf::Layered(layered) => layered.base.ior,
            Bsdf::Lambertian { .. } | Bsdf::Mirror { .. } | Bsdf::Unlit { .. } => return 1.0,
        };
        if wo.z * wi.z >= 0.0 {
            return 1.0;
        }
        // Inside over outside when entering (wo outside, +z), its inverse when leaving.
        let eta = if wo.z > 0.0 { ior } else { 1.0 / ior };
        1.0 / (eta * eta)
    }

    /// Whether some non-delta lobe transmits (light from behind the surface reaches `wo`), so
    /// that next-event estimation must sample lights on both sides.
    #[inline]
    pub fn transmits(&self) -> bool {
        match *self {
            Bsdf::MetallicRoughness(params) => params.transmission > 0.0 && params.metallic < 1.0,
            Bsdf::Layered(layered) => {
                layered.base.transmission > 0.0 && layered.base.metallic < 1.0
            }
            Bsdf::Lambertian { .. }
            | Bsdf::Mirror { .. }
            | Bsdf::Dielectric { .. }
            | Bsdf::Unlit { .. } => false,
        }
    }

    /// Whether [`Bsdf::transmits`] may hold once textures scale the material (a
    /// metallic-roughness texture lowers `metallic`, so a metal with `transmission` may
    /// transmit where its texture is below 1).
    #[inline]
    pub fn may_transmit(&self) -> bool {
        match *self {
            Bsdf::MetallicRoughness(params) => params.transmission > 0.0,
            Bsdf::Layered(layered) => layered.base.transmission > 0.0,
            Bsdf::Lambertian { .. }
            | Bsdf::Mirror { .. }
            | Bsdf::Dielectric { .. }
            | Bsdf::Unlit { .. } => false,
        }
    }

    /// Whether the surface reflects nothing at all (a path ends on it; an unlit one shows its
    /// colour there).
    #[inline]
    pub fn is_black(&self) -> bool {
        match *self {
            Bsdf::Unlit { .. } => true,
            Bsdf::Lambertian { albedo } => albedo == Rgb::ZERO,
            Bsdf::Mirror { tint } | Bsdf::Dielectric { tint, .. } => tint == Rgb::ZERO,
            Bsdf::MetallicRoughness(params) => params.is_black(),
            Bsdf::Layered(layered) => layered.is_black(),
        }
    }

    /// The same model with its colour (albedo or tint) multiplied by `colour` (a texture).
    #[inline]
    pub fn tinted(self, colour: Rgb) -> Bsdf {
        match self {
            Bsdf::Lambertian { albedo } => Bsdf::Lambertian {
                albedo: albedo * colour,
            },
            Bsdf::Mirror { tint } => Bsdf::Mirror {
                tint: tint * colour,
            },
            Bsdf::Dielectric { ior, fresnel, tint } => Bsdf::Dielectric {
                ior,
                fresnel,
                tint: tint * colour,
            },
            Bsdf::MetallicRoughness(params) => Bsdf::MetallicRoughness(MetallicRoughness {
                base_color: params.base_color * colour,
                ..params
            }),
            Bsdf::Layered(layered) => Bsdf::Layered(Layered {
                base: MetallicRoughness {
                    base_color: layered.base.base_color * colour,
                    ..layered.base
                },
                ..layered
            }),
            Bsdf::Unlit { color } => Bsdf::Unlit {
                color: color * colour,
            },
        }
    }

    /// The same model with Blender's Bump Map Correction on its diffuse lobe, for a hit whose
    /// normal map turned the smooth normal `smooth` into the shading normal `mapped` (unit,
    /// world space): a Lambertian surface becomes the equal metallic-roughness one (metallic
    /// and specular 0) that carries the term; mirrors, glass and unlit surfaces have no diffuse
    /// lobe and are unchanged, as is everything when the normals agree.
    #[inline]
    pub fn with_bump_shadowing(self, mapped: Vec3A, smooth: Vec3A) -> Bsdf {
        let bump = BumpShadowing::new(mapped, smooth);
        if bump == BumpShadowing::NONE {
            return self;
        }
        match self {
            Bsdf::Lambertian { albedo } => Bsdf::MetallicRoughness(MetallicRoughness {
                base_color: albedo,
                metallic: 0.0,
                specular: 0.0,
                transmission: 0.0,
                bump,
                ..Default::default()
            }),
            other => other.with_base(|params| MetallicRoughness { bump, ..params }),
        }
    }

    /// The same model with the coat's own normal `coat` (unit, world space; a
    /// `clearcoatNormalTexture`'s) for a hit whose shading normal is `shading` (the local
    /// frame's `+z`); only [`Bsdf::Layered`] has a coat, other models are returned as they are.
    #[inline]
    pub fn with_coat_normal(self, coat: Vec3A, shading: Vec3A) -> Bsdf {
        match self {
            Bsdf::Layered(layered) => Bsdf::Layered(Layered {
                coat_normal: Some(crate::math::Vec3::from(
                    crate::math::frame::Frame::from_normal(shading).to_local(coat),
                )),
                ..layered
            }),
            other => other,
        }
    }

    /// The same model with `metallic` scaled by `metallic_scale` and the perceptual roughness
    /// by `roughness_scale` (a glTF metallic-roughness texture's blue and green); only
    /// [`Bsdf::MetallicRoughness`] has these parameters.
    #[inline]
    pub fn with_metallic_roughness_scaled(self, metallic_scale: f32, roughness_scale: f32) -> Bsdf {
        self.with_base(|params| MetallicRoughness {
            metallic: params.metallic * metallic_scale,
            // alpha = roughness^2, so it scales by the square; the clamp to MIN_ALPHA
            // commutes with the scale because the scale is at most 1.
            alpha: (params.alpha * roughness_scale * roughness_scale)
                .clamp(microfacet::MIN_ALPHA, 1.0),
            ..params
        })
    }

    /// The same model with `change` applied to its metallic-roughness parameters (those of
    /// [`Bsdf::MetallicRoughness`], or the base of [`Bsdf::Layered`]); other models have none
    /// and are returned as they are.
    #[inline]
    fn with_base(self, change: impl Fn(MetallicRoughness) -> MetallicRoughness) -> Bsdf {
        match self {
            Bsdf::MetallicRoughness(params) => Bsdf::MetallicRoughness(change(params)),
            Bsdf::Layered(layered) => Bsdf::Layered(Layered {
                base: change(layered.base),
                ..layered
            }),
            other => other,
        }
    }

    /// The anisotropy of its metallic-roughness parameters, if it has any
    /// ([`Bsdf::MetallicRoughness`] or the base of [`Bsdf::Layered`]).
    #[inline]
    pub fn anisotropy(&self) -> Option<Anisotropy> {
        let anisotropy = match self {
            Bsdf::MetallicRoughness(params) => params.anisotropy,
            Bsdf::Layered(layered) => layered.base.anisotropy,
            _ => return None,
        };
        (!anisotropy.is_none()).then_some(anisotropy)
    }

    /// The same model with `anisotropy` on its metallic-roughness parameters (the shade
    /// stage's, turned into a hit's shading frame).
    #[inline]
    pub fn with_anisotropy(self, anisotropy: Anisotropy) -> Bsdf {
        self.with_base(|params| MetallicRoughness {
            anisotropy,
            ..params
        })
    }

    /// The same model with its clearcoat, the coat's roughness, sheen colour and sheen
    /// roughness multiplied by these (the `KHR_materials_clearcoat` and `_sheen` textures);
    /// only [`Bsdf::Layered`] has layers, other models are returned as they are.
    pub fn with_layers_scaled(
        self,
        clearcoat: f32,
        clearcoat_roughness: f32,
        sheen_color: Rgb,
        sheen_roughness: f32,
    ) -> Bsdf {
        match self {
            Bsdf::Layered(layered) => Bsdf::Layered(Layered {
                clearcoat: layered.clearcoat * clearcoat,
                clearcoat_alpha: (layered.clearcoat_alpha
                    * clearcoat_roughness
                    * clearcoat_roughness)
                    .max(microfacet::MIN_ALPHA),
                sheen_color: layered.sheen_color * sheen_color,
                sheen_roughness: layered.sheen_roughness * sheen_roughness,
                ..layered
            }),
            other => other,
        }
    }

    /// The same model with the dielectric's `specular` scaled by `specular_scale` and its
    /// `specular_color` by `color_scale` (`KHR_materials_specular` textures); only
    /// [`Bsdf::MetallicRoughness`] and [`Bsdf::Layered`] have these parameters.
    #[inline]
    pub fn with_specular_scaled(self, specular_scale: f32, color_scale: Rgb) -> Bsdf {
        self.with_base(|params| MetallicRoughness {
            specular: params.specular * specular_scale,
            specular_color: params.specular_color * color_scale,
            ..params
        })
    }

    /// The same model with its thin film's factor scaled by `factor_scale` and its thickness
    /// mixed from minimum to maximum by `thickness_mix` (the `KHR_materials_iridescence`
    /// textures); models without a metallic-roughness base are returned as they are.
    #[inline]
    pub fn with_film_scaled(self, factor_scale: f32, thickness_mix: f32) -> Bsdf {
        self.with_base(|params| MetallicRoughness {
            film: params.film.scaled(factor_scale, thickness_mix),
            ..params
        })
    }

    /// BSDF value for a pair of directions (zero for delta lobes).
    #[inline]
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> Rgb {
        match *self {
            Bsdf::Lambertian { albedo } => lambert::eval(albedo, wo, wi),
            Bsdf::MetallicRoughness(params) => params.eval(wo, wi),
            Bsdf::Layered(layered) => layered.eval(wo, wi),
            Bsdf::Mirror { .. } | Bsdf::Dielectric { .. } | Bsdf::Unlit { .. } => Rgb::ZERO,
        }
    }

    /// Solid-angle density with which `sample` returns `wi` (zero for delta lobes).
    #[inline]
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        match *self {
            Bsdf::Lambertian { .. } => lambert::pdf(wo, wi),
            Bsdf::MetallicRoughness(params) => params.pdf(wo, wi),
            Bsdf::Layered(layered) => layered.pdf(wo, wi),
            Bsdf::Mirror { .. } | Bsdf::Dielectric { .. } | Bsdf::Unlit { .. } => 0.0,
        }
    }

    /// [`Bsdf::eval`] and [`Bsdf::pdf`] of four directions at once, given by axis (one
    /// `Vec4` lane per direction): f by channel, and the densities. Lambertian surfaces, the
    /// common case, take all lanes in a few vector instructions; the others go lane by lane.
    #[inline]
    pub fn eval_and_pdf_lanes(&self, wo: Vec3A, wi: &[Vec4; 3]) -> ([Vec4; 3], Vec4) {
        if let Bsdf::Lambertian { albedo } = *self {
            return lambert::eval_and_pdf_lanes(albedo, wo.z, wi[2]);
        }
        let (mut f, mut pdf) = ([[0.0; 4]; 3], [0.0; 4]);
        for k in 0..4 {
            let wi = Vec3A::new(wi[0][k], wi[1][k], wi[2][k]);
            let value = self.eval(wo, wi);
            for (channel, v) in f.iter_mut().zip(value.to_array()) {
                channel[k] = v;
            }
            pdf[k] = self.pdf(wo, wi);
        }
        (f.map(Vec4::from_array), Vec4::from_array(pdf))
    }

    /// Samples `wi` from `u_lobe` (lobe choice) and `u` (direction).
    #[inline]
    pub fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2) -> Option<BsdfSample> {
        self.sample_drawing(wo, || u_lobe, || u)
    }

    /// [`Bsdf::sample`] with its random numbers drawn only when the model uses them: a
    /// Lambertian surface takes no lobe number, a smooth dielectric no direction, a mirror
    /// neither (each number of the Sobol sampler costs a hash and a scramble).
    #[inline(always)]
    pub fn sample_drawing(
        &self,
        wo: Vec3A,
        u_lobe: impl FnOnce() -> f32,
        u: impl FnOnce() -> Vec2,
    ) -> Option<BsdfSample> {
        match *self {
            Bsdf::Lambertian { albedo } => lambert::sample(albedo, wo, u()),
            Bsdf::Mirror { tint } => mirror::sample(tint, wo),
            Bsdf::Dielectric { ior, fresnel, tint } => {
                dielectric::sample(ior, fresnel, tint, wo, u_lobe())
            }
            Bsdf::MetallicRoughness(params) => params.sample(wo, u_lobe(), u()),
            Bsdf::Layered(layered) => layered.sample(wo, u_lobe(), u()),
            Bsdf::Unlit { .. } => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::rng::{path_key, uniform};

    /// An unlit surface reflects nothing in any direction (no sample, no value, no density,
    /// no light sampling: the shade stage ends the path there and shows its colour), and
    /// textures and vertex colours tint its colour.
    #[test]
    fn unlit_reflects_nothing_and_is_tinted() {
        let unlit = Bsdf::Unlit {
            color: Rgb::new(0.2, 0.5, 0.8),
        };
        let (wo, wi) = (Vec3A::new(0.3, 0.0, 0.954), Vec3A::new(-0.5, 0.1, 0.86));
        assert!(unlit.is_black() && unlit.is_delta());
        assert_eq!(unlit.eval(wo, wi), Rgb::ZERO);
        assert_eq!(unlit.pdf(wo, wi), 0.0);
        assert_eq!(unlit.sample(wo, 0.5, Vec2::splat(0.5)), None);
        assert_eq!(
            unlit.tinted(Rgb::new(0.5, 1.0, 0.0)),
            Bsdf::Unlit {
                color: Rgb::new(0.1, 0.5, 0.0)
            }
        );
        assert_eq!(unlit.with_metallic_roughness_scaled(0.0, 0.0), unlit);
    }

    /// Four directions at a time give what `eval` and `pdf` give one by one, bit for bit, on
    /// the Lambertian lane path and the generic one, for directions on both sides.
    #[test]
    fn lanes_agree_with_eval_and_pdf() {
        let bsdfs = [
            Bsdf::Lambertian {
                albedo: Rgb::new(0.8, 0.5, 0.2),
            },
            Bsdf::metallic_roughness(MetallicRoughness::new(Rgb::new(0.9, 0.6, 0.3), 1.0, 0.4)),
            Bsdf::Mirror { tint: Rgb::ONE },
            Bsdf::layered(Layered {
                base: MetallicRoughness::new(Rgb::new(0.2, 0.3, 0.4), 0.0, 0.7),
                clearcoat: 0.8,
                clearcoat_alpha: 0.05,
                sheen_color: Rgb::new(0.9, 0.5, 0.7),
                sheen_roughness: 0.4,
                coat_normal: None,
            }),
        ];
        for (b, bsdf) in bsdfs.iter().enumerate() {
            for i in 0..500 {
                let u = |d: u32| uniform(path_key(21, i, b as u32), 0, d);
                let direction = |d: u32| {
                    (Vec3A::new(u(d), u(d + 1), u(d + 2)) * 2.0 - 1.0).normalize_or(Vec3A::Z)
                };
                let wo = direction(0);
                let wi: [Vec3A; 4] = std::array::from_fn(|k| direction(3 + 3 * k as u32));
                let by_axis = [0, 1, 2].map(|a| Vec4::from_array(wi.map(|w| w[a])));
                let (f, pdf) = bsdf.eval_and_pdf_lanes(wo, &by_axis);
                for (k, &w) in wi.iter().enumerate() {
                    let expected = bsdf.eval(wo, w);
                    let lane = Rgb::new(f[0][k], f[1][k], f[2][k]);
                    assert_eq!(
                        lane.to_array().map(f32::to_bits),
                        expected.to_array().map(f32::to_bits)
                    );
                    assert_eq!(
                        pdf[k].to_bits(),
                        bsdf.pdf(wo, w).to_bits(),
                        "{bsdf:?} {wo} {w}"
                    );
                }
            }
        }
    }

    /// `transmits` is true exactly for the models whose `eval` is non-zero for some pair of
    /// directions on opposite sides (next-event estimation relies on it to send shadow rays
    /// through the surface): every variant, layers over glass included.
    #[test]
    fn transmits_exactly_when_eval_crosses_the_surface() {
        let glass = MetallicRoughness {
            transmission: 0.7,
            ..MetallicRoughness::new(Rgb::new(0.9, 0.8, 0.7), 0.2, 0.5)
        };
        let layers = |base| {
            Bsdf::layered(Layered {
                base,
                clearcoat: 0.8,
                clearcoat_alpha: 0.05,
                sheen_color: Rgb::new(0.5, 0.4, 0.3),
                sheen_roughness: 0.4,
                coat_normal: None,
            })
        };
        let opaque = MetallicRoughness::new(Rgb::new(0.9, 0.8, 0.7), 0.3, 0.5);
        let cases = [
            (Bsdf::Lambertian { albedo: Rgb::ONE }, false),
            (Bsdf::Mirror { tint: Rgb::ONE }, false),
            (
                Bsdf::Dielectric {
                    ior: 1.5,
                    fresnel: FresnelModel::Exact,
                    tint: Rgb::ONE,
                },
                false, // delta only: no lobe for shadow rays
            ),
            (Bsdf::metallic_roughness(opaque), false),
            (Bsdf::metallic_roughness(glass), true),
            (
                Bsdf::metallic_roughness(MetallicRoughness {
                    metallic: 1.0,
                    ..glass
                }),
                false,
            ),
            (layers(opaque), false),
            (layers(glass), true),
        ];
        for (b, (bsdf, transmits)) in cases.iter().enumerate() {
            assert_eq!(bsdf.transmits(), *transmits, "{bsdf:?}");
            // Every scaling a texture may make keeps `transmits` within `may_transmit`.
            for scale in [1.0, 0.5, 0.0] {
                let scaled = bsdf.with_metallic_roughness_scaled(scale, scale);
                assert!(
                    !scaled.transmits() || bsdf.may_transmit(),
                    "{bsdf:?} {scale}"
                );
            }
            let crossing = (0..2000).any(|i| {
                let u = |d: u32| uniform(path_key(23, i, b as u32), 0, d);
                let wo = (Vec3A::new(u(0), u(1), u(2)) * 2.0 - 1.0).normalize_or(Vec3A::Z);
                let wi = (Vec3A::new(u(3), u(4), u(5)) * 2.0 - 1.0).normalize_or(Vec3A::Z);
                wo.z * wi.z < 0.0 && bsdf.eval(wo, wi) != Rgb::ZERO
            });
            assert_eq!(crossing, *transmits, "{bsdf:?}");
        }
    }

    #[test]
    fn radiance_compression_matches_the_refracted_weight_and_cancels_on_leaving() {
        let glass = Bsdf::Dielectric {
            ior: 1.5,
            fresnel: FresnelModel::Exact,
            tint: Rgb::ONE,
        };
        let outside = Vec3A::new(0.0, 0.6, 0.8);
        // A refracted sample (u_lobe 0.99 > reflectance) carries weight tint / eta^2.
        let entering = glass.sample(outside, 0.99, Vec2::ZERO).unwrap();
        assert!(entering.wi.z < 0.0);
        let scale = glass.radiance_compression(outside, entering.wi);
        assert!((scale - 1.0 / 2.25).abs() < 1e-6 && (entering.weight.x - scale).abs() < 1e-6);
        // Leaving from inside: eta^2, so that a path in and out is not scaled at all.
        let inside = Vec3A::new(0.0, 0.6, -0.8);
        let leaving = glass.sample(inside, 0.99, Vec2::ZERO).unwrap();
        assert!(leaving.wi.z > 0.0);
        let out_scale = glass.radiance_compression(inside, leaving.wi);
        assert!((out_scale - leaving.weight.x).abs() < 1e-5, "{out_scale}");
        assert!((scale * out_scale - 1.0).abs() < 1e-6, "{out_scale}");
        // Reflection and surfaces that transmit nothing compress nothing.
        let reflected = Vec3A::new(0.0, -0.6, 0.8);
        assert_eq!(glass.radiance_compression(outside, reflected), 1.0);
        let wall = Bsdf::Lambertian { albedo: Rgb::ONE };
        assert_eq!(wall.radiance_compression(outside, -reflected), 1.0);
    }
}
