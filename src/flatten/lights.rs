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

/// Light samples per shading point are taken in groups of this many lanes.
pub const LIGHT_LANES: usize = 16;

/// Up to [`LIGHT_LANES`] light samples seen from one shading point, as structure of arrays:
/// choosing the lights and the points is scalar, but the geometry of all lanes (direction,
/// distance, density) is one pass of independent lanes that compiles to SIMD.
#[derive(Clone, Debug)]
pub struct LightSamples {
    /// Lanes in use.
    pub len: usize,
    /// Unit direction from the shading point toward the light, by axis.
    pub wi: [[f32; LIGHT_LANES]; 3],
    /// Distance to the light point; infinite for directional lights.
    pub distance: [f32; LIGHT_LANES],
    /// Radiance of an area light, or the weight of a punctual light.
    pub radiance: [Rgb; LIGHT_LANES],
    /// Incident radiance over the sample's density, per unit of `|cos|` at the receiver, is
    /// `radiance * scale`; zero when the light does not shine toward the point.
    pub scale: [f32; LIGHT_LANES],
    /// Density of `wi` per solid angle (choice of the light included), for multiple
    /// importance sampling; infinite for punctual lights, which BSDF sampling never finds.
    pub pdf_solid_angle: [f32; LIGHT_LANES],
    /// Index of the area light sampled (into [`LightTable::lights`]), or [`NOT_AREA_LIGHT`].
    pub area_light: [u32; LIGHT_LANES],
    /// Barycentrics of the point on a triangle light (for its emission texture).
    pub barycentric: [Vec2; LIGHT_LANES],
    /// Inputs of the geometry pass: the point on the light, its normal, its area density,
    /// and 1 where it emits on both sides, else 0 (numbers, not `bool`s: those keep the pass
    /// from vectorising).
    point: [[f32; LIGHT_LANES]; 3],
    normal: [[f32; LIGHT_LANES]; 3],
    pdf_area: [f32; LIGHT_LANES],
    two_sided: [f32; LIGHT_LANES],
}

impl Default for LightSamples {
    fn default() -> Self {
        const ZEROS: [f32; LIGHT_LANES] = [0.0; LIGHT_LANES];
        LightSamples {
            len: 0,
            wi: [ZEROS; 3],
            distance: ZEROS,
            radiance: [Rgb::ZERO; LIGHT_LANES],
            scale: ZEROS,
            pdf_solid_angle: ZEROS,
            area_light: [NOT_AREA_LIGHT; LIGHT_LANES],
            barycentric: [Vec2::ZERO; LIGHT_LANES],
            point: [ZEROS; 3],
            normal: [ZEROS; 3],
            pdf_area: ZEROS,
            two_sided: ZEROS,
        }
    }
}

impl LightSamples {
    /// Direction of lane `k`.
    #[inline(always)]
    pub fn wi(&self, k: usize) -> Vec3A {
        Vec3A::new(self.wi[0][k], self.wi[1][k], self.wi[2][k])
    }
}

/// What a punctual light sends toward a point: the direction to it, its distance and the
/// incident radiance over the probability of choosing the light.
struct PunctualSample {
    wi: Vec3A,
    distance: f32,
    weight: Rgb,
}

/// [`LightSamples::area_light`] of a punctual light.
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
    /// When every light is a one-sided triangle and they lie in a few planes: those planes.
    /// A point behind all of them gets no light (see [`LightTable::all_behind`]).
    emitting_planes: Vec<EmittingPlane>,
}

/// A plane of one-sided triangle lights, which emit toward `normal`: `normal . x = offset`.
#[derive(Clone, Copy, Debug)]
struct EmittingPlane {
    normal: Vec3A,
    offset: f32,
    /// The largest coordinate magnitude of the plane's lights, which scales their rounding.
    extent: f32,
}

/// [`LightTable::all_behind`] keeps at most this many planes, so that it stays a few dot
/// products per hit.
const MAX_EMITTING_PLANES: usize = 8;

/// How far behind the planes (relative to the coordinates' magnitude) a point must lie for
/// [`LightTable::all_behind`]: far more than the rounding of a light sample's direction,
/// so that no sample it skips could have had a positive cosine at the light.
const BEHIND_MARGIN: f32 = 1e-4;

/// The planes of `lights` if all are one-sided triangles lying in at most
/// [`MAX_EMITTING_PLANES`] planes (and there are no punctual lights), else none.
fn emitting_planes(lights: &[AreaLight], delta_lights: &[DeltaLight]) -> Vec<EmittingPlane> {
    let mut planes: Vec<EmittingPlane> = Vec::new();
    if !delta_lights.is_empty() {
        return planes;
    }
    for light in lights {
        let Shape::Triangle(t) = light.shape else {
            return Vec::new();
        };
        if light.two_sided || light.normal == Vec3A::ZERO {
            return Vec::new();
        }
        let vertices = [t.v0, t.v0 + t.e1, t.v0 + t.e2];
        let extent = vertices
            .map(|v| v.abs().max_element())
            .into_iter()
            .fold(0.0, f32::max);
        let coplanar = |plane: &EmittingPlane| {
            let tolerance = 1e-6 * plane.extent.max(extent);
            plane.normal.dot(light.normal) > 1.0 - 1e-6
                && vertices
                    .iter()
                    .all(|v| (plane.normal.dot(*v) - plane.offset).abs() <= tolerance)
        };
        if let Some(plane) = planes.iter_mut().find(|plane| coplanar(plane)) {
            plane.extent = plane.extent.max(extent);
        } else if planes.len() < MAX_EMITTING_PLANES {
            planes.push(EmittingPlane {
                normal: light.normal,
                offset: light.normal.dot(t.v0),
                extent,
            });
        } else {
            return Vec::new();
        }
    }
    planes
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
            emitting_planes: emitting_planes(&lights, &delta_lights),
            lights,
            delta_lights,
            power_cdf,
        }
    }

    /// Whether `p` lies behind every light, so that no light sample taken from it could
    /// shine on it: true only when all lights are one-sided triangles in at most eight
    /// planes and `p` is clearly behind each one. Lets shading skip the light samples of,
    /// say, a ceiling above a ceiling light, which would all come out zero.
    #[inline]
    pub fn all_behind(&self, p: Vec3A) -> bool {
        if self.emitting_planes.is_empty() {
            return false;
        }
        let magnitude = p.abs().max_element();
        self.emitting_planes.iter().all(|plane| {
            let margin = BEHIND_MARGIN * (plane.extent + magnitude);
            plane.normal.dot(p) - plane.offset < -margin
        })
    }

    /// Whether the scene has any light to sample.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.power_cdf.is_empty()
    }

    /// Fills `samples` with `uniforms.len()` (at most [`LIGHT_LANES`]) light samples as seen
    /// from `p`: lane `k` chooses a light with `uniforms[k].0` and a point on it with
    /// `uniforms[k].1` (area lights: uniform by area).
    #[inline]
    pub fn sample(&self, p: Vec3A, uniforms: &[(f32, Vec2)], samples: &mut LightSamples) {
        debug_assert!(uniforms.len() <= LIGHT_LANES);
        samples.len = uniforms.len();
        let mut punctual = 0u32;
        for (k, &(u_pick, u)) in uniforms.iter().enumerate() {
            let index = sample_discrete(&self.power_cdf, u_pick);
            let Some(light) = self.lights.get(index) else {
                punctual |= 1 << k; // done after the geometry pass, which overwrites every lane
                continue;
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
            for axis in 0..3 {
                samples.point[axis][k] = point[axis];
                samples.normal[axis][k] = normal[axis];
            }
            samples.pdf_area[k] = light.pdf_area;
            samples.two_sided[k] = if light.two_sided { 1.0 } else { 0.0 };
            samples.radiance[k] = light.radiance;
            samples.area_light[k] = index as u32;
            samples.barycentric[k] = barycentric;
        }
        area_light_geometry(p, samples);
        while punctual != 0 {
            let k = punctual.trailing_zeros() as usize;
            punctual &= punctual - 1;
            let index = sample_discrete(&self.power_cdf, uniforms[k].0);
            let s = self.delta_lights[index - self.lights.len()].sample_from(p);
            for axis in 0..3 {
                samples.wi[axis][k] = s.wi[axis];
            }
            samples.distance[k] = s.distance;
            samples.radiance[k] = s.weight;
            samples.scale[k] = 1.0;
            samples.pdf_solid_angle[k] = f32::INFINITY;
            samples.area_light[k] = NOT_AREA_LIGHT;
        }
    }
}

/// The geometry pass of [`LightTable::sample`] over all lanes, area lights or not (unused
/// lanes compute harmless garbage): no branches, no calls, so that it vectorises.
#[inline(always)]
fn area_light_geometry(p: Vec3A, s: &mut LightSamples) {
    let [point_x, point_y, point_z] = &s.point;
    let [normal_x, normal_y, normal_z] = &s.normal;
    let [wi_x, wi_y, wi_z] = &mut s.wi;
    for k in 0..LIGHT_LANES {
        let (dx, dy, dz) = (point_x[k] - p.x, point_y[k] - p.y, point_z[k] - p.z);
        let distance_squared = dx * dx + dy * dy + dz * dz;
        let distance = distance_squared.sqrt();
        let inverse_distance = 1.0 / distance;
        (wi_x[k], wi_y[k], wi_z[k]) = (
            dx * inverse_distance,
            dy * inverse_distance,
            dz * inverse_distance,
        );
        let cos_light = -(normal_x[k] * wi_x[k] + normal_y[k] * wi_y[k] + normal_z[k] * wi_z[k]);
        // A one-sided light shines toward its normal; a two-sided one both ways.
        let facing = if s.two_sided[k] > 0.0 {
            cos_light.abs()
        } else {
            cos_light
        };
        let pdf_solid_angle = s.pdf_area[k] * distance_squared / cos_light.abs();
        s.distance[k] = distance;
        s.pdf_solid_angle[k] = pdf_solid_angle;
        s.scale[k] = if facing > 0.0 && distance_squared > 0.0 {
            1.0 / pdf_solid_angle
        } else {
            0.0
        };
    }
}

impl DeltaLight {
    /// The light's sample as seen from `p` (there is only one direction to it).
    #[inline]
    fn sample_from(&self, p: Vec3A) -> PunctualSample {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flatten::triangles::TriangleGeom;
    use crate::math::rng::{path_key, uniform};

    /// One light sample seen from `p`: its point, direction, distance and weight.
    fn sample_one(table: &LightTable, p: Vec3A, u_pick: f32, u: Vec2) -> (Vec3A, Vec3A, f32, Rgb) {
        let mut s = LightSamples::default();
        table.sample(p, &[(u_pick, u)], &mut s);
        let wi = s.wi(0);
        (
            p + s.distance[0] * wi,
            wi,
            s.distance[0],
            s.radiance[0] * s.scale[0],
        )
    }

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
        let (point, _, distance, weight) = sample_one(&table, p, 0.75, Vec2::new(0.3, 0.3));
        let d = (point - p).length();
        assert!(point.z.abs() < 1e-6 && (distance - d).abs() < 1e-6);
        let expected = (1.0 / d) / (d * d * 0.25);
        assert!((weight - Rgb::splat(expected)).length() < 1e-4, "{weight}");
        // From below, the one-sided light's back faces the point: no light.
        let below = Vec3A::new(0.6, 0.6, -1.0);
        let (_, _, _, weight) = sample_one(&table, below, 0.75, Vec2::new(0.3, 0.3));
        assert_eq!(weight, Rgb::ZERO);
    }

    #[test]
    fn points_behind_all_lights_get_no_light_from_any_sample() {
        // The seed room's light: a quad at z = 4.99 facing down, its two triangles coplanar.
        let [a, b, c, d] =
            [[4.0, 1.0], [6.0, 1.0], [6.0, -1.0], [4.0, -1.0]].map(|[x, y]| Vec3A::new(x, y, 4.99));
        let light = |p: [Vec3A; 3]| {
            AreaLight::new(
                Shape::Triangle(TriangleGeom::new(p[0], p[1], p[2])),
                Rgb::ONE,
                false,
            )
        };
        let quad = vec![light([a, b, c]), light([a, c, d])];
        let table = LightTable::new(quad.clone(), vec![]);
        assert_eq!(table.emitting_planes.len(), 1);
        let mut samples = LightSamples::default();
        let mut behind = 0;
        for i in 0..2000 {
            let u = |d: u32| uniform(path_key(5, i, 0), 0, d);
            // Points around the light's plane, down to a hair's breadth from it.
            let height = 4.99 + (u(0) - 0.5) * 10f32.powf(-4.0 * u(1));
            let p = Vec3A::new(20.0 * u(2) - 5.0, 20.0 * u(3) - 10.0, height);
            if !table.all_behind(p) {
                assert!(height < 4.99 + 1e-2, "{p} is clearly behind the light");
                continue;
            }
            behind += 1;
            assert!(height > 4.99, "{p} is in front of the light");
            let uniforms: Vec<_> = (0..LIGHT_LANES as u32)
                .map(|k| (u(10 + 3 * k), Vec2::new(u(11 + 3 * k), u(12 + 3 * k))))
                .collect();
            table.sample(p, &uniforms, &mut samples);
            assert!(
                samples.scale.iter().all(|&s| s == 0.0),
                "{p}: {:?}",
                samples.scale
            );
        }
        assert!(behind > 500, "{behind}");
        // Lights the test cannot reason about: none is ever skipped.
        let two_sided = AreaLight::new(quad[0].shape, Rgb::ONE, true);
        let sun = DeltaLight::directional(Vec3A::NEG_Z, Rgb::ONE, 1.0);
        let above = Vec3A::new(5.0, 0.0, 6.0);
        assert!(table.all_behind(above));
        assert!(!LightTable::new(vec![two_sided], vec![]).all_behind(above));
        assert!(!LightTable::new(quad, vec![sun]).all_behind(above));
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
        let (_, wi, distance, weight) = sample_one(&table, Vec3A::ZERO, 0.0, Vec2::ZERO);
        assert!((weight.x - 8.0 / 4.0 / p_point).abs() < 1e-4);
        assert!((wi - Vec3A::Z).length() < 1e-6 && (distance - 2.0).abs() < 1e-6);
        // The spot: full on its axis, nothing outside the outer cone.
        let p_spot = table.delta_lights[1].select_probability;
        let (_, _, _, weight) = sample_one(&table, Vec3A::ZERO, 0.999, Vec2::ZERO);
        assert!((weight.x - 8.0 / 4.0 / p_spot).abs() < 1e-3);
        let aside = Vec3A::new(2.0, 0.0, 0.0);
        let (_, _, _, weight) = sample_one(&table, aside, 0.999, Vec2::ZERO);
        assert_eq!(weight, Rgb::ZERO);
        let sun = DeltaLight::directional(Vec3A::NEG_Z, Rgb::splat(3.0), 1.0);
        let table = LightTable::new(vec![], vec![sun]);
        let (_, wi, distance, weight) = sample_one(&table, Vec3A::ZERO, 0.5, Vec2::ZERO);
        assert!((weight - Rgb::splat(3.0)).length() < 1e-6 && distance.is_infinite());
        assert!((wi - Vec3A::Z).length() < 1e-6);
    }
}
