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
    /// Shines from `position` into a cone about `direction`, attenuated as `cone` says.
    Spot {
        /// Position.
        position: Vec3A,
        /// Axis of the cone (unit).
        direction: Vec3A,
        /// Where and how the intensity falls off.
        cone: SpotCone,
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

    /// A spot light of on-axis intensity `intensity` W/sr.
    pub fn spot(position: Vec3A, direction: Vec3A, intensity: Rgb, cone: SpotCone) -> Self {
        DeltaLight {
            kind: DeltaKind::Spot {
                position,
                direction,
                cone,
            },
            intensity,
            // The solid angle of the cone halfway between full intensity and none.
            power: 2.0 * PI * (1.0 - 0.5 * (cone.cos_full + cone.cos_outer)) * luminance(intensity),
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

/// The angular falloff of a spot light: no light outside the cone of cosine `cos_outer`, full
/// intensity inside the cone of cosine `cos_full`, and between them a profile of the ramp
/// `x = (cos - cos_outer) / (cos_full - cos_outer)`, linear in the cosine. When the two cones
/// are one the edge is hard (Blender's Spot Blend 0), with no division by their difference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpotCone {
    /// Cosine of the angle from the axis beyond which there is no light.
    pub cos_outer: f32,
    /// Cosine of the angle from the axis within which the intensity is full.
    pub cos_full: f32,
    /// The shape of the ramp.
    pub profile: SpotProfile,
}

/// The shape of a spot light's ramp `x` in [0, 1] between its cones.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpotProfile {
    /// `x^2`: the falloff the glTF specification recommends (`KHR_lights_punctual`).
    Squared,
    /// `smoothstep(x) = x^2 (3 - 2 x)`: Cycles' spot blend.
    Smoothstep,
}

impl SpotCone {
    /// glTF's cone between the `inner` and `outer` angles (radians from the axis).
    pub fn gltf(inner: f32, outer: f32) -> Self {
        SpotCone {
            cos_outer: outer.cos(),
            cos_full: inner.cos(),
            profile: SpotProfile::Squared,
        }
    }

    /// Blender's (Cycles') cone of Spot Size `2 outer` and Spot Blend `blend` in [0, 1]: the
    /// smoothstep spans `blend` of the cosine range `[cos outer, 1]`.
    pub fn blender(outer: f32, blend: f32) -> Self {
        let cos_outer = outer.cos();
        SpotCone {
            cos_outer,
            cos_full: cos_outer + (1.0 - cos_outer) * blend,
            profile: SpotProfile::Smoothstep,
        }
    }

    /// The linear ramp at cosine `cos` from the axis: 0 at the outer cone, 1 at the full one.
    #[inline]
    fn ramp(&self, cos: f32) -> f32 {
        if self.cos_full > self.cos_outer {
            ((cos - self.cos_outer) / (self.cos_full - self.cos_outer)).clamp(0.0, 1.0)
        } else if cos >= self.cos_outer {
            1.0
        } else {
            0.0
        }
    }

    /// The fraction of the on-axis intensity sent at cosine `cos` from the axis.
    #[inline]
    pub fn attenuation(&self, cos: f32) -> f32 {
        let x = self.ramp(cos);
        match self.profile {
            SpotProfile::Squared => x * x,
            SpotProfile::Smoothstep => x * x * (3.0 - 2.0 * x),
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
                cone,
            } => {
                let (wi, distance, w) = towards(position);
                let cos = -wi.dot(direction);
                PunctualSample {
                    wi,
                    distance,
                    weight: self.intensity * (w * cone.attenuation(cos)),
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
        let cone = SpotCone::gltf(0.5, 0.5);
        let edge = 0.5f32.cos();
        assert_eq!(cone.attenuation(edge + 1e-4), 1.0);
        assert_eq!(cone.attenuation(1.0), 1.0);
        assert_eq!(cone.attenuation(edge - 1e-4), 0.0);
        // Blender's Spot Blend 0 is the same hard edge.
        assert_eq!(
            SpotCone::blender(0.5, 0.0),
            SpotCone {
                profile: SpotProfile::Smoothstep,
                ..cone
            }
        );
        // Seen from a point on the axis, 2 m away: intensity / d^2, in full.
        let light = DeltaLight {
            select_probability: 1.0,
            ..DeltaLight::spot(Vec3A::ZERO, Vec3A::NEG_Z, Rgb::ONE, cone)
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
        let cone = SpotCone::gltf(inner, outer);
        let light = DeltaLight {
            select_probability: 1.0,
            ..DeltaLight::spot(Vec3A::ZERO, Vec3A::NEG_Z, Rgb::ONE, cone)
        };
        let cos = 0.5 * (ci + co);
        let sin = (1.0 - cos * cos).sqrt();
        let s = light.sample_from(Vec3A::new(sin, 0.0, -cos));
        assert!((s.weight.x - 0.25).abs() < 1e-4, "{}", s.weight);
        assert_eq!(cone.attenuation(ci + 1e-3), 1.0);
        assert_eq!(cone.attenuation(co - 1e-3), 0.0);
        // A narrow blend keeps its own ramp (no minimum width).
        let narrow = SpotCone::gltf(0.5, 0.5001);
        let mid = 0.5 * (narrow.cos_full + narrow.cos_outer);
        assert!((narrow.attenuation(mid) - 0.25).abs() < 0.05);
    }

    #[test]
    fn a_blender_spot_follows_cycles_smoothstep_at_every_angle() {
        // Cycles 4.5 (kernel/light/spot.h): smoothstep((cos t - cos o) / ((1 - cos o) blend)),
        // o = spot_size / 2, with no further cosine. Spot Size 60 degrees, blend 0.15 and 0.5.
        for blend in [0.15f32, 0.5, 1.0] {
            let outer = 30f32.to_radians();
            let cone = SpotCone::blender(outer, blend);
            let co = outer.cos();
            for degrees in [
                0.0f32, 5.0, 10.0, 15.0, 20.0, 22.0, 24.0, 26.0, 28.0, 29.5, 31.0,
            ] {
                let cos = degrees.to_radians().cos();
                let x = ((cos - co) / ((1.0 - co) * blend)).clamp(0.0, 1.0);
                let cycles = x * x * (3.0 - 2.0 * x);
                let ours = cone.attenuation(cos);
                assert!(
                    (ours - cycles).abs() < 1e-5,
                    "blend {blend}, {degrees} deg: {ours} vs {cycles}"
                );
            }
        }
        // Blend 0.5 of a 30-degree half-angle is full from 21.1 degrees, not glTF's 15.
        let cone = SpotCone::blender(30f32.to_radians(), 0.5);
        assert!((cone.cos_full.acos().to_degrees() - 21.1).abs() < 0.01);
        assert!(cone.attenuation(21.3f32.to_radians().cos()) < 1.0);
        assert_eq!(cone.attenuation(20.9f32.to_radians().cos()), 1.0);
        // The smoothstep is half way at the ramp's middle, the glTF square a quarter.
        let mid = 0.5 * (cone.cos_full + cone.cos_outer);
        assert!((cone.attenuation(mid) - 0.5).abs() < 1e-5);
    }
}
