//! The light table: every emitting primitive (sampled uniformly by area, the seed's equation
//! 16 generalised to many emitters) and every punctual light (point, spot, directional; delta
//! lights reached only by next-event estimation), each chosen in proportion to its power.

use super::Shape;
use crate::math::sampling::{sample_discrete, sample_triangle, sample_uniform_sphere};
use crate::math::{Rgb, Vec2, Vec3A, luminance};
use std::f32::consts::PI;

/// One emitting primitive.
#[derive(Clone, Copy, Debug)]
pub struct AreaLight {
    /// Its geometry (a copy of the primitive's).
    pub shape: Shape,
    /// Emitted radiance.
    pub radiance: Rgb,
    /// Whether the back face emits too.
    pub two_sided: bool,
    /// Surface area.
    pub area: f32,
    /// Unit normal of a triangle (the side it emits from); unused for spheres.
    pub normal: Vec3A,
    /// Probability of choosing this light.
    pub select_probability: f32,
    /// Density of its sample points per unit area: `select_probability / area`.
    pub pdf_area: f32,
}

impl AreaLight {
    /// The light of `shape`, before the table sets its probability.
    pub fn new(shape: Shape, radiance: Rgb, two_sided: bool) -> Self {
        let (area, normal) = match shape {
            Shape::Triangle(t) => (t.area(), t.normal_unnormalized().normalize_or_zero()),
            Shape::Sphere(s) => (s.area(), Vec3A::ZERO),
        };
        AreaLight {
            shape,
            radiance,
            two_sided,
            area,
            normal,
            select_probability: 0.0,
            pdf_area: 0.0,
        }
    }
}

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

/// A light sample seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The point on the light (unused for directional lights).
    pub point: Vec3A,
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3A,
    /// Distance to `point`; infinite for directional lights.
    pub distance: f32,
    /// Incident radiance over the sample's density, per unit of `|cos|` at the receiver: the
    /// estimate is `f * |ns . wi| * weight`. Zero when the light does not shine toward the point.
    pub weight: Rgb,
    /// Density of `wi` per solid angle (choice of the light included), for multiple importance
    /// sampling; infinite for punctual lights, which BSDF sampling can never find.
    pub pdf_solid_angle: f32,
    /// Index of the area light sampled (into [`LightTable::lights`]), or [`NOT_AREA_LIGHT`].
    pub area_light: u32,
    /// Barycentrics of `point` on a triangle light (for its emission texture).
    pub barycentric: Vec2,
}

/// [`LightSample::area_light`] of a punctual light.
pub const NOT_AREA_LIGHT: u32 = u32::MAX;

/// All lights (area lights first, then punctual ones) with the cumulative distribution of
/// their power.
#[derive(Clone, Debug, Default)]
pub struct LightTable {
    /// The emitting primitives (indexed by `FlatScene::emitter`).
    pub lights: Vec<AreaLight>,
    /// The punctual lights.
    pub delta_lights: Vec<DeltaLight>,
    /// Running sum of the lights' power, area lights then punctual ones; the last entry is the total.
    pub power_cdf: Vec<f32>,
}

impl LightTable {
    /// Builds the table; an area light's `power = luminance(radiance) * area * pi` per
    /// emitting side.
    pub fn new(mut lights: Vec<AreaLight>, mut delta_lights: Vec<DeltaLight>) -> Self {
        let power = |l: &AreaLight| {
            luminance(l.radiance) * l.area * PI * if l.two_sided { 2.0 } else { 1.0 }
        };
        let powers: Vec<f64> = lights
            .iter()
            .map(|l| power(l) as f64)
            .chain(delta_lights.iter().map(|l| l.power as f64))
            .collect();
        let total: f64 = powers.iter().sum();
        let mut running = 0.0f64;
        let power_cdf = powers
            .iter()
            .map(|p| {
                running += p;
                running as f32
            })
            .collect();
        let probability = |p: f64| (p / total) as f32;
        for (l, &p) in lights.iter_mut().zip(&powers) {
            l.select_probability = probability(p);
            l.pdf_area = l.select_probability / l.area;
        }
        for (l, &p) in delta_lights.iter_mut().zip(&powers[lights.len()..]) {
            l.select_probability = probability(p);
        }
        LightTable {
            lights,
            delta_lights,
            power_cdf,
        }
    }

    /// Whether the scene has any light to sample.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.power_cdf.is_empty()
    }

    /// Chooses a light with `u_pick` and a point on it with `u`, as seen from `p`.
    #[inline]
    pub fn sample(&self, p: Vec3A, u_pick: f32, u: Vec2) -> LightSample {
        let index = sample_discrete(&self.power_cdf, u_pick);
        let Some(light) = self.lights.get(index) else {
            return self.delta_lights[index - self.lights.len()].sample_from(p);
        };
        let (point, normal, barycentric) = match light.shape {
            Shape::Triangle(t) => {
                let b = sample_triangle(u);
                (t.point(b), light.normal, b)
            }
            Shape::Sphere(s) => {
                let n = sample_uniform_sphere(u);
                (s.center + s.radius * n, n, Vec2::ZERO)
            }
        };
        let to_light = point - p;
        let distance_squared = to_light.length_squared();
        let distance = distance_squared.sqrt();
        let wi = to_light / distance;
        let cos_light = -normal.dot(wi);
        let shines = cos_light > 0.0 || (light.two_sided && cos_light < 0.0);
        let pdf_solid_angle = light.pdf_area * distance_squared / cos_light.abs();
        let weight = if shines && distance_squared > 0.0 {
            light.radiance * pdf_solid_angle.recip()
        } else {
            Rgb::ZERO
        };
        LightSample {
            point,
            wi,
            distance,
            weight,
            pdf_solid_angle,
            area_light: index as u32,
            barycentric,
        }
    }
}

impl DeltaLight {
    /// The light's sample as seen from `p` (there is only one direction to it).
    #[inline]
    fn sample_from(&self, p: Vec3A) -> LightSample {
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
                LightSample {
                    point: position,
                    wi,
                    distance,
                    weight: self.intensity * w,
                    pdf_solid_angle: f32::INFINITY,
                    area_light: NOT_AREA_LIGHT,
                    barycentric: Vec2::ZERO,
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
                LightSample {
                    point: position,
                    wi,
                    distance,
                    weight: self.intensity * (w * t * t),
                    pdf_solid_angle: f32::INFINITY,
                    area_light: NOT_AREA_LIGHT,
                    barycentric: Vec2::ZERO,
                }
            }
            DeltaKind::Directional { direction } => LightSample {
                point: p - direction,
                wi: -direction,
                distance: f32::INFINITY,
                weight: self.intensity * inv_p,
                pdf_solid_angle: f32::INFINITY,
                area_light: NOT_AREA_LIGHT,
                barycentric: Vec2::ZERO,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flatten::triangles::TriangleGeom;

    #[test]
    fn lights_are_chosen_in_proportion_to_power() {
        let tri =
            |s: f32| Shape::Triangle(TriangleGeom::new(Vec3A::ZERO, Vec3A::X * s, Vec3A::Y * s));
        let light = |shape: Shape, l: f32| AreaLight::new(shape, Rgb::splat(l), false);
        // Same power: small bright and large dim.
        let table = LightTable::new(vec![light(tri(1.0), 4.0), light(tri(2.0), 1.0)], vec![]);
        assert!((table.lights[0].select_probability - 0.5).abs() < 1e-6);
        // pdf_area integrates to 1 over all lights: sum(p_select / area * area) = 1.
        let total: f32 = table.lights.iter().map(|l| l.select_probability).sum();
        assert!((total - 1.0).abs() < 1e-6);
        // Second light (area 2, radiance 1, pdf_area = 0.5 / 2) seen from a point 1 above
        // its plane: weight = L cos / (d^2 pdf_area) with cos = 1 / d.
        let p = Vec3A::new(0.6, 0.6, 1.0);
        let s = table.sample(p, 0.75, Vec2::new(0.3, 0.3));
        let d = (s.point - p).length();
        assert!(s.point.z == 0.0 && (s.distance - d).abs() < 1e-6);
        let expected = (1.0 / d) / (d * d * 0.25);
        assert!(
            (s.weight - Rgb::splat(expected)).length() < 1e-4,
            "{}",
            s.weight
        );
        // From below, the one-sided light's back faces the point: no light.
        let s = table.sample(Vec3A::new(0.6, 0.6, -1.0), 0.75, Vec2::new(0.3, 0.3));
        assert_eq!(s.weight, Rgb::ZERO);
    }

    #[test]
    fn punctual_lights_follow_the_inverse_square_law_and_the_spot_cone() {
        let point = DeltaLight::point(Vec3A::new(0.0, 0.0, 2.0), Rgb::splat(8.0));
        let spot = DeltaLight::spot(
            Vec3A::new(0.0, 0.0, 2.0),
            Vec3A::NEG_Z,
            Rgb::splat(8.0),
            0.2,
            0.4,
        );
        let table = LightTable::new(vec![], vec![point, spot]);
        let p_point = table.delta_lights[0].select_probability;
        let s = table.sample(Vec3A::ZERO, 0.0, Vec2::ZERO);
        assert!((s.weight.x - 8.0 / 4.0 / p_point).abs() < 1e-4);
        assert!((s.wi - Vec3A::Z).length() < 1e-6 && (s.distance - 2.0).abs() < 1e-6);
        // The spot: full on its axis, nothing outside the outer cone.
        let p_spot = table.delta_lights[1].select_probability;
        let s = table.sample(Vec3A::ZERO, 0.999, Vec2::ZERO);
        assert!((s.weight.x - 8.0 / 4.0 / p_spot).abs() < 1e-3);
        let s = table.sample(Vec3A::new(2.0, 0.0, 0.0), 0.999, Vec2::ZERO);
        assert_eq!(s.weight, Rgb::ZERO);
        let sun = DeltaLight::directional(Vec3A::NEG_Z, Rgb::splat(3.0), 1.0);
        let table = LightTable::new(vec![], vec![sun]);
        let s = table.sample(Vec3A::ZERO, 0.5, Vec2::ZERO);
        assert!((s.weight - Rgb::splat(3.0)).length() < 1e-6 && s.distance.is_infinite());
        assert!((s.wi - Vec3A::Z).length() < 1e-6);
    }
}
