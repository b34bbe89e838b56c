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
    /// between the inner and outer cone (`attenuation = clamp((cos - cos_outer) / (cos_inner - cos_outer))^2`),
    /// or a hard edge when the two cones are one (Blender's Spot Blend 0).
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

/// The square root of a spot light's attenuation at cosine `cos` from its axis: glTF's
/// linear ramp from the outer cone (0) to the inner cone (1), or, when the cones coincide,
/// 1 inside and 0 outside (a hard edge, with no division by their zero difference).
#[inline]
pub(crate) fn spot_falloff(cos: f32, cos_inner: f32, cos_outer: f32) -> f32 {
    if cos_inner > cos_outer {
        ((cos - cos_outer) / (cos_inner - cos_outer)).clamp(0.0, 1.0)
    } else if cos >= cos_outer {
        1.0
    } else {
        0.0
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
                let t = spot_falloff(cos, cos_inner, cos_outer);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spot_with_equal_cones_has_a_hard_edge() {
        let edge = 0.5f32.cos();
        assert_eq!(spot_falloff(edge + 1e-4, edge, edge), 1.0);
        assert_eq!(spot_falloff(1.0, edge, edge), 1.0);
        assert_eq!(spot_falloff(edge - 1e-4, edge, edge), 0.0);
        // Seen from a point on the axis, 2 m away: intensity / d^2, in full.
        let light = DeltaLight {
            select_probability: 1.0,
            ..DeltaLight::spot(Vec3A::ZERO, Vec3A::NEG_Z, Rgb::ONE, 0.5, 0.5)
        };
        let s = light.sample_from(Vec3A::new(0.0, 0.0, -2.0));
        assert!((s.weight - Rgb::splat(0.25)).abs().max_element() < 1e-6);
        // Just outside the cone: nothing.
        let outside = Vec3A::new(0.51f32.sin(), 0.0, -0.51f32.cos());
        assert_eq!(light.sample_from(outside).weight, Rgb::ZERO);
        // Power: the cone's solid angle times the intensity.
        let expected = 2.0 * PI * (1.0 - edge);
        assert!((light.power - expected).abs() < 1e-5 * expected);
    }

    #[test]
    fn a_spot_keeps_gltf_falloff_between_its_cones() {
        let (inner, outer) = (0.3f32, 0.6f32);
        let (ci, co) = (inner.cos(), outer.cos());
        // Halfway in cosine: (1/2)^2 of the intensity, as glTF's formula squared.
        let light = DeltaLight {
            select_probability: 1.0,
            ..DeltaLight::spot(Vec3A::ZERO, Vec3A::NEG_Z, Rgb::ONE, inner, outer)
        };
        let cos = 0.5 * (ci + co);
        let sin = (1.0 - cos * cos).sqrt();
        let s = light.sample_from(Vec3A::new(sin, 0.0, -cos));
        assert!((s.weight.x - 0.25).abs() < 1e-4, "{}", s.weight);
        assert_eq!(spot_falloff(ci + 1e-3, ci, co), 1.0);
        assert_eq!(spot_falloff(co - 1e-3, ci, co), 0.0);
        // A narrow blend keeps its own ramp (no minimum width).
        let narrow = (0.5f32.cos(), 0.5001f32.cos());
        let mid = 0.5 * (narrow.0 + narrow.1);
        assert!((spot_falloff(mid, narrow.0, narrow.1) - 0.5).abs() < 0.05);
    }
}
