//! The light table: every emitting primitive, chosen in proportion to its emitted power and
//! sampled uniformly by area (the seed's equation 16, generalised to many emitters).

use super::Shape;
use crate::math::sampling::{sample_discrete, sample_triangle, sample_uniform_sphere};
use crate::math::{Rgb, Vec2, Vec3A, luminance};

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
    /// Probability of choosing this light.
    pub select_probability: f32,
}

/// A point sampled on a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// The point, world space.
    pub point: Vec3A,
    /// Geometric normal at the point (the emitting front side).
    pub normal: Vec3A,
    /// Radiance emitted from the front side.
    pub radiance: Rgb,
    /// Whether the back face emits too.
    pub two_sided: bool,
    /// Density of the point per unit area, including the choice of the light.
    pub pdf_area: f32,
}

/// All lights with the cumulative distribution of their power.
#[derive(Clone, Debug, Default)]
pub struct LightTable {
    /// The lights.
    pub lights: Vec<AreaLight>,
    /// Running sum of the lights' power; the last entry is the total.
    pub power_cdf: Vec<f32>,
}

impl LightTable {
    /// Builds the table; `power = luminance(radiance) * area * pi` per emitting side.
    pub fn new(mut lights: Vec<AreaLight>) -> Self {
        let power = |l: &AreaLight| {
            luminance(l.radiance)
                * l.area
                * std::f32::consts::PI
                * if l.two_sided { 2.0 } else { 1.0 }
        };
        let mut total = 0.0f64;
        let power_cdf = lights
            .iter()
            .map(|l| {
                total += power(l) as f64;
                total as f32
            })
            .collect();
        for l in &mut lights {
            l.select_probability = (power(l) as f64 / total) as f32;
        }
        LightTable { lights, power_cdf }
    }

    /// Whether the scene has any light to sample.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Chooses a light with `u_pick` and a point on it with `u`.
    #[inline]
    pub fn sample(&self, u_pick: f32, u: Vec2) -> LightSample {
        let light = &self.lights[sample_discrete(&self.power_cdf, u_pick)];
        let (point, normal) = match light.shape {
            Shape::Triangle(t) => {
                let b = sample_triangle(u);
                (t.point(b), t.normal_unnormalized().normalize())
            }
            Shape::Sphere(s) => {
                let n = sample_uniform_sphere(u);
                (s.center + s.radius * n, n)
            }
        };
        LightSample {
            point,
            normal,
            radiance: light.radiance,
            two_sided: light.two_sided,
            pdf_area: light.select_probability / light.area,
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
        let light = |shape: Shape, l: f32| AreaLight {
            shape,
            radiance: Rgb::splat(l),
            two_sided: false,
            area: match shape {
                Shape::Triangle(t) => t.area(),
                Shape::Sphere(s) => s.area(),
            },
            select_probability: 0.0,
        };
        // Same power: small bright and large dim.
        let table = LightTable::new(vec![light(tri(1.0), 4.0), light(tri(2.0), 1.0)]);
        assert!((table.lights[0].select_probability - 0.5).abs() < 1e-6);
        // pdf_area integrates to 1 over all lights: sum(p_select / area * area) = 1.
        let total: f32 = table.lights.iter().map(|l| l.select_probability).sum();
        assert!((total - 1.0).abs() < 1e-6);
        let s = table.sample(0.75, Vec2::new(0.3, 0.3));
        assert!(
            (s.pdf_area - 0.5 / 2.0).abs() < 1e-6,
            "second light, area 2"
        );
        assert!((s.normal - Vec3A::Z).length() < 1e-6);
    }
}
