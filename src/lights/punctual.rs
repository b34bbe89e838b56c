//! Punctual lights (point, spot, directional): delta lights, reached only by next-event
//! estimation, each with one point (or direction) to sample.

use super::*;

/// A punctual light: a point, spot or directional light of zero size. Rays never hit it.
#[derive(Clone, Copy, Debug)]
pub struct DeltaLight {
    /// Where it is and which way it shines.
    pub kind: DeltaKind,
    /// Radiant intensity (W/sr) of point and spot lights; irradiance (W/m^2) of directional ones.
    pub intensity: Rgb,
    /// Emitted power (luminance-weighted), for the choice among lights.
    pub power: f32,
    /// Probability of choosing this light.
    pub select_probability: f32,
}

/// Geometry of a [`DeltaLight`], world space.
#[derive(Clone, Copy, Debug)]
pub enum DeltaKind {
    /// Shines equally in every direction from `position`.
    Point {
        /// Position.
        position: Vec3A,
    },
    /// Shines from `position` into a cone about `direction`, with glTF's smooth falloff
    /// between the inner and outer cone (`attenuation = clamp((cos - cos_outer) / (cos_inner - cos_outer))^2`).
    Spot {
        /// Position.
        position: Vec3A,
        /// Axis of the cone (unit).
        direction: Vec3A,
        /// Cosine of the inner cone angle.
        cos_inner: f32,
        /// Cosine of the outer cone angle.
        cos_outer: f32,
    },
    /// Parallel light travelling along `direction` (unit).
    Directional {
        /// Direction the light travels in.
        direction: Vec3A,
    },
}

impl DeltaLight {
    /// A point light of intensity `intensity` W/sr.
    pub fn point(position: Vec3A, intensity: Rgb) -> Self {
        DeltaLight {
            kind: DeltaKind::Point { position },
            intensity,
            power: 4.0 * PI * luminance(intensity),
            select_probability: 0.0,
        }
    }

    /// A spot light; cone angles in radians from the axis.
    pub fn spot(position: Vec3A, direction: Vec3A, intensity: Rgb, inner: f32, outer: f32) -> Self {
        let (cos_inner, cos_outer) = (inner.cos(), outer.cos());
        DeltaLight {
            kind: DeltaKind::Spot {
                position,
                direction,
                cos_inner,
                cos_outer,
            },
            intensity,
            // The solid angle of the cone halfway between the inner and outer angles.
            power: 2.0 * PI * (1.0 - 0.5 * (cos_inner + cos_outer)) * luminance(intensity),
            select_probability: 0.0,
        }
    }

    /// A directional light of irradiance `irradiance` W/m^2; its power is what falls on the
    /// disk of radius `scene_radius` (the scene's bounding sphere) facing it.
    pub fn directional(direction: Vec3A, irradiance: Rgb, scene_radius: f32) -> Self {
        DeltaLight {
            kind: DeltaKind::Directional { direction },
            intensity: irradiance,
            power: PI * scene_radius * scene_radius * luminance(irradiance),
            select_probability: 0.0,
        }
    }
}

/// What a punctual light sends toward a point: the direction to it, its distance and the
/// incident radiance over the probability of choosing the light.
pub(super) struct PunctualSample {
    pub(super) wi: Vec3A,
    pub(super) distance: f32,
    pub(super) weight: Rgb,
}

impl DeltaLight {
    /// The light's sample as seen from `p` (there is only one direction to it).
    #[inline]
    pub(super) fn sample_from(&self, p: Vec3A) -> PunctualSample {
        let inv_p = 1.0 / self.select_probability;
        let towards = |position: Vec3A| {
            let to_light = position - p;
            let d2 = to_light.length_squared();
            let d = d2.sqrt();
            (to_light / d, d, if d2 > 0.0 { inv_p / d2 } else { 0.0 })
        };
        match self.kind {
            DeltaKind::Point { position } => {
                let (wi, distance, w) = towards(position);
                PunctualSample {
                    wi,
                    distance,
                    weight: self.intensity * w,
                }
            }
            DeltaKind::Spot {
                position,
                direction,
                cos_inner,
                cos_outer,
            } => {
                let (wi, distance, w) = towards(position);
                let cos = -wi.dot(direction);
                let t = ((cos - cos_outer) / (cos_inner - cos_outer).max(1e-3)).clamp(0.0, 1.0);
                PunctualSample {
                    wi,
                    distance,
                    weight: self.intensity * (w * t * t),
                }
            }
            DeltaKind::Directional { direction } => PunctualSample {
                wi: -direction,
                distance: f32::INFINITY,
                weight: self.intensity * inv_p,
            },
        }
    }
}
