//! The light table: every emitting primitive (sampled uniformly by area, the seed's equation
//! 16 generalised to many emitters) and every punctual light (point, spot, directional; delta
//! lights reached only by next-event estimation, see [`punctual`]), each chosen in proportion
//! to its power, and sampled four lanes at a time; a scene lit by one area light takes the
//! fast path of [`single`]. The environment light ([`environment`]), when there is one, is
//! the table's last entry, chosen by its power over the scene's bounding sphere.

pub mod environment;
mod punctual;
mod single;

pub use environment::Environment;
pub use punctual::{DeltaKind, DeltaLight, SpotCone};
use single::{SingleLight, single_light};

use crate::geometry::Shape;
use crate::geometry::triangle::TriangleGeom;
use crate::math::sampling::{
    sample_discrete, sample_triangle, sample_uniform_sphere, shifted_mod_one,
};
use crate::math::{BVec4A, Rgb, Vec2, Vec3A, Vec4, luminance, transpose4};
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

/// Light samples per shading point are taken in groups of this many lanes: one `Vec4`.
pub const LIGHT_LANES: usize = 4;

/// Four light samples seen from one shading point, lane `k` of every vector being sample
/// `k`, so that one SIMD instruction serves all four. Kept in registers from the choice of
/// the points to the shadow rays: scalar stores that vector loads read back stall.
#[derive(Clone, Copy, Debug, Default)]
pub struct LightSamples {
    /// Unit direction from the shading point toward the light, by axis.
    pub wi: [Vec4; 3],
    /// Distance to the light point; infinite for directional lights.
    pub distance: Vec4,
    /// Radiance of an area light, or the weight of a punctual light, by channel.
    pub radiance: [Vec4; 3],
    /// Incident radiance over the sample's density, per unit of `|cos|` at the receiver, is
    /// `radiance * scale`; zero when the light does not shine toward the point.
    pub scale: Vec4,
    /// Density of `wi` per solid angle (choice of the light included), for multiple
    /// importance sampling; infinite for punctual lights, which BSDF sampling never finds.
    pub pdf_solid_angle: Vec4,
}

/// The uniform numbers of four light samples, lane `k` of each vector being sample `k`'s: one
/// to choose the light, two for the point on it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LightUniforms {
    /// The choice of the light, by power.
    pub pick: Vec4,
    /// The point on the light, by coordinate.
    pub point: [Vec4; 2],
}

impl LightUniforms {
    /// Lane `k` from `lanes[k]`: (light choice, point).
    pub fn from_lanes(lanes: [(f32, Vec2); LIGHT_LANES]) -> Self {
        LightUniforms {
            pick: Vec4::from_array(lanes.map(|l| l.0)),
            point: [
                Vec4::from_array(lanes.map(|l| l.1.x)),
                Vec4::from_array(lanes.map(|l| l.1.y)),
            ],
        }
    }

    /// These numbers shifted by `(pick, point)`, modulo one: the Cranley-Patterson rotation
    /// of a lattice (see [`crate::math::sampling::Rank1Lattice`]).
    #[inline(always)]
    pub fn shifted(&self, (pick, point): (f32, Vec2)) -> Self {
        LightUniforms {
            pick: shifted_mod_one(self.pick, pick),
            point: [
                shifted_mod_one(self.point[0], point.x),
                shifted_mod_one(self.point[1], point.y),
            ],
        }
    }
}

/// Where four light samples lie, for emission textures only. Apart from [`LightSamples`]:
/// the light indices are made lane by lane, so copying them along with the samples reads
/// four scalar stores back as one vector, which stalls (7% of the shade stage).
#[derive(Clone, Copy, Debug)]
pub struct LightPoints {
    /// Index of the area light sampled (into [`LightTable::lights`]), or [`NOT_AREA_LIGHT`].
    pub area_light: [u32; LIGHT_LANES],
    /// Barycentrics `(b1, b2)` of the point on a triangle light.
    pub barycentric: [Vec4; 2],
}

impl LightSamples {
    /// `*self = samples`, field by field: the compiler copies the whole struct (144 bytes)
    /// with a call to `memcpy`, from a stack copy of the registers that hold it.
    #[inline(always)]
    pub fn overwrite(&mut self, samples: LightSamples) {
        let LightSamples {
            wi,
            distance,
            radiance,
            scale,
            pdf_solid_angle,
        } = samples;
        self.wi = wi;
        self.distance = distance;
        self.radiance = radiance;
        self.scale = scale;
        self.pdf_solid_angle = pdf_solid_angle;
    }

    /// These samples with the vector lanes set in `mask` taken from `other`.
    #[inline]
    fn merged(self, other: LightSamples, mask: BVec4A) -> LightSamples {
        let pick = |a: Vec4, b: Vec4| Vec4::select(mask, b, a);
        let pick3 = |a: [Vec4; 3], b: [Vec4; 3]| [0, 1, 2].map(|i| pick(a[i], b[i]));
        LightSamples {
            wi: pick3(self.wi, other.wi),
            distance: pick(self.distance, other.distance),
            radiance: pick3(self.radiance, other.radiance),
            scale: pick(self.scale, other.scale),
            pdf_solid_angle: pick(self.pdf_solid_angle, other.pdf_solid_angle),
        }
    }
}

/// [`LightPoints::area_light`] of a punctual light.
pub const NOT_AREA_LIGHT: u32 = u32::MAX;

/// All lights (area lights first, then punctual ones) with the cumulative distribution of
/// their power.
#[derive(Clone, Debug, Default)]
pub struct LightTable {
    /// The emitting primitives (indexed by `RenderScene::emitter`).
    pub lights: Vec<AreaLight>,
    /// The punctual lights.
    pub delta_lights: Vec<DeltaLight>,
    /// Running sum of the lights' power, area lights then punctual ones; the last entry is the total.
    pub power_cdf: Vec<f32>,
    /// Per area light, what its samples read, in two vectors: `[normal, pdf_area]` and
    /// `[radiance, 1 if two-sided else 0]`.
    records: Vec<[Vec4; 2]>,
    /// When every light is a one-sided triangle and they lie in a few planes: those planes.
    /// A point behind all of them gets no light (see [`LightTable::all_behind`]).
    emitting_planes: Vec<EmittingPlane>,
    /// The only light, when it is one triangle or one parallelogram.
    single: Option<SingleLight>,
    /// The light at infinity, sampled after the punctual lights (index
    /// `lights.len() + delta_lights.len()` in `power_cdf`) when its power is positive.
    environment: Option<Environment>,
    /// Probability of choosing the environment (0 when it is not sampled).
    environment_probability: f32,
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

/// Light samples seen from `p` of points `point` (by axis, lane `k` being sample `k`) on
/// lights of unit normal `normal`, area density `pdf_area`, radiance `radiance`, and
/// `two_sided` 1 where they shine both ways (else 0).
#[inline(always)]
fn samples_toward(
    p: Vec3A,
    point: [Vec4; 3],
    normal: [Vec4; 3],
    pdf_area: Vec4,
    radiance: [Vec4; 3],
    two_sided: Vec4,
) -> LightSamples {
    let [point_x, point_y, point_z] = point;
    let [normal_x, normal_y, normal_z] = normal;
    let (dx, dy, dz) = (
        point_x - Vec4::splat(p.x),
        point_y - Vec4::splat(p.y),
        point_z - Vec4::splat(p.z),
    );
    let distance_squared = dx * dx + dy * dy + dz * dz;
    let distance = distance_squared.sqrt();
    let inverse_distance = Vec4::ONE / distance;
    let wi = [
        dx * inverse_distance,
        dy * inverse_distance,
        dz * inverse_distance,
    ];
    // The cosine at the light times the distance, from the unnormalised direction, and
    // the density and its inverse as two independent divisions: none of them waits for
    // the chain of square root and division above.
    let cos_times_distance = -(normal_x * dx + normal_y * dy + normal_z * dz);
    // A one-sided light shines toward its normal; a two-sided one both ways.
    let facing = Vec4::select(
        two_sided.cmpgt(Vec4::ZERO),
        cos_times_distance.abs(),
        cos_times_distance,
    );
    let shines = facing.cmpgt(Vec4::ZERO) & distance_squared.cmpgt(Vec4::ZERO);
    let area_term = pdf_area * distance_squared * distance;
    let pdf_solid_angle = area_term / cos_times_distance.abs();
    LightSamples {
        wi,
        distance,
        radiance,
        scale: Vec4::select(shines, cos_times_distance.abs() / area_term, Vec4::ZERO),
        pdf_solid_angle,
    }
}

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
        let vertices = t.vertices();
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
    pub fn new(lights: Vec<AreaLight>, delta_lights: Vec<DeltaLight>) -> Self {
        Self::with_environment(lights, delta_lights, None, 1.0)
    }

    /// Builds the table with an environment light too, whose power is
    /// [`Environment::power_estimate`] over the scene's bounding sphere of radius
    /// `scene_radius`. A black environment is kept for camera rays but never sampled.
    pub fn with_environment(
        mut lights: Vec<AreaLight>,
        mut delta_lights: Vec<DeltaLight>,
        environment: Option<Environment>,
        scene_radius: f32,
    ) -> Self {
        let environment_power = environment
            .as_ref()
            .map_or(0.0, |e| e.power_estimate(scene_radius) as f64);
        let sampled = environment_power > 0.0 && environment_power.is_finite();
        let power = |l: &AreaLight| {
            luminance(l.radiance) * l.area * PI * if l.two_sided { 2.0 } else { 1.0 }
        };
        let powers: Vec<f64> = lights
            .iter()
            .map(|l| power(l) as f64)
            .chain(delta_lights.iter().map(|l| l.power as f64))
            .chain(sampled.then_some(environment_power))
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
        let records = lights
            .iter()
            .map(|l| {
                let two_sided = if l.two_sided { 1.0 } else { 0.0 };
                [l.normal.extend(l.pdf_area), l.radiance.extend(two_sided)]
            })
            .collect();
        let environment_probability = if sampled {
            probability(environment_power)
        } else {
            0.0
        };
        // Light from infinity reaches every point from every side: neither the one-light
        // fast path nor the behind-all-lights test holds.
        let (single, emitting_planes) = if environment.is_some() {
            (None, Vec::new())
        } else {
            (
                single_light(&lights, &delta_lights),
                emitting_planes(&lights, &delta_lights),
            )
        };
        LightTable {
            single,
            records,
            emitting_planes,
            lights,
            delta_lights,
            power_cdf,
            environment,
            environment_probability,
        }
    }

    /// The environment light, if the scene has one (sampled or not).
    #[inline]
    pub fn environment(&self) -> Option<&Environment> {
        self.environment.as_ref()
    }

    /// Probability with which a light sample chooses the environment (0 if it never does).
    #[inline]
    pub fn environment_probability(&self) -> f32 {
        self.environment_probability
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

    /// Makes the samples of a parallelogram light say on which triangle they lie, which
    /// emission textures need ([`LightPoints`]): it is sampled as its two triangles again.
    pub fn locate_samples_on_triangles(&mut self) {
        self.single = self.single.filter(|light| !light.parallelogram);
    }

    /// Whether the scene has any light to sample.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.power_cdf.is_empty()
    }

    /// Four light samples as seen from `p`, and where they lie: lane `k` chooses a light
    /// with lane `k` of `uniforms.pick` and a point on it with lane `k` of `uniforms.point`
    /// (area lights: uniform by area; a table whose only light is one triangle or
    /// parallelogram needs no choice).
    #[inline(always)]
    pub fn sample(&self, p: Vec3A, uniforms: &LightUniforms) -> (LightSamples, LightPoints) {
        let u = uniforms.point;
        if let Some(light) = &self.single {
            return light.sample(p, u);
        }
        let barycentric = sample_triangle(u);
        let (b1, b2) = (barycentric[0].to_array(), barycentric[1].to_array());
        let index =
            (uniforms.pick.to_array()).map(|u_pick| sample_discrete(&self.power_cdf, u_pick));
        // Each lane's point and its light's `[normal, pdf_area]` and `[radiance, two_sided]`
        // records. A punctual lane computes harmless garbage below and is overwritten after.
        let lane = |k: usize| {
            let Some(light) = self.lights.get(index[k]) else {
                return [Vec4::ZERO; 3];
            };
            let [normal_pdf, radiance_sided] = self.records[index[k]];
            match light.shape {
                Shape::Triangle(t) => [
                    t.point(Vec2::new(b1[k], b2[k])).extend(0.0),
                    normal_pdf,
                    radiance_sided,
                ],
                Shape::Sphere(s) => {
                    let n = sample_uniform_sphere(Vec2::new(u[0][k], u[1][k]));
                    [
                        (s.center + s.radius * n).extend(0.0),
                        n.extend(normal_pdf.w),
                        radiance_sided,
                    ]
                }
            }
        };
        // Called lane by lane, not through `array::from_fn`, which the compiler left as a
        // call per lane.
        let lanes = [lane(0), lane(1), lane(2), lane(3)];
        // Lanes to vectors: row `axis` of the transposed 4 x 4 block is that axis over the lanes.
        let by_axis = |field: usize| transpose4(lanes.map(|l| l[field]));
        let [point_x, point_y, point_z, _] = by_axis(0);
        let [normal_x, normal_y, normal_z, pdf_area] = by_axis(1);
        let [red, green, blue, two_sided] = by_axis(2);
        let samples = samples_toward(
            p,
            [point_x, point_y, point_z],
            [normal_x, normal_y, normal_z],
            pdf_area,
            [red, green, blue],
            two_sided,
        );
        let points = LightPoints {
            area_light: index.map(|i| {
                if i < self.lights.len() {
                    i as u32
                } else {
                    NOT_AREA_LIGHT
                }
            }),
            barycentric,
        };
        let punctual = points.area_light.map(|light| light == NOT_AREA_LIGHT);
        if !punctual.contains(&true) {
            return (samples, points);
        }
        let lanes = (0..LIGHT_LANES).fold(0, |bits, k| bits | u32::from(punctual[k]) << k);
        let mask = BVec4A::from_array(punctual);
        let merged = samples.merged(self.punctual_samples(p, lanes, &index, u), mask);
        (merged, points)
    }

    /// The samples of the punctual lights and the environment that the lanes set in `lanes`
    /// chose (`index`, counted after the area lights; the environment's direction from lane
    /// `k` of `u`); other lanes are zero. Apart, and off the common path, so that the
    /// samples of area lights never leave registers.
    #[cold]
    #[inline(never)]
    fn punctual_samples(
        &self,
        p: Vec3A,
        mut lanes: u32,
        index: &[usize; LIGHT_LANES],
        u: [Vec4; 2],
    ) -> LightSamples {
        let mut wi = [[0.0; LIGHT_LANES]; 3];
        let mut radiance = [[0.0; LIGHT_LANES]; 3];
        let mut distance = [0.0; LIGHT_LANES];
        let mut scale = [1.0; LIGHT_LANES];
        let mut pdf_solid_angle = [f32::INFINITY; LIGHT_LANES];
        while lanes != 0 {
            let k = lanes.trailing_zeros() as usize;
            lanes &= lanes - 1;
            let Some(light) = self.delta_lights.get(index[k] - self.lights.len()) else {
                // The environment: a direction by its own density, at infinity.
                let environment = self.environment.as_ref().expect("sampled environment");
                let s = environment.sample(Vec2::new(u[0][k], u[1][k]));
                let pdf = self.environment_probability * s.pdf;
                for axis in 0..3 {
                    wi[axis][k] = s.direction[axis];
                    radiance[axis][k] = s.radiance[axis];
                }
                distance[k] = f32::INFINITY;
                // A zero density (a pole of the map, measure zero) drops the sample.
                scale[k] = if pdf > 0.0 { 1.0 / pdf } else { 0.0 };
                pdf_solid_angle[k] = pdf;
                continue;
            };
            let s = light.sample_from(p);
            for axis in 0..3 {
                wi[axis][k] = s.wi[axis];
                radiance[axis][k] = s.weight[axis];
            }
            distance[k] = s.distance;
        }
        LightSamples {
            wi: wi.map(Vec4::from_array),
            distance: Vec4::from_array(distance),
            radiance: radiance.map(Vec4::from_array),
            scale: Vec4::from_array(scale),
            pdf_solid_angle: Vec4::from_array(pdf_solid_angle),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sphere::SphereGeom;
    use crate::geometry::triangle::TriangleGeom;
    use crate::math::rng::{path_key, uniform};

    /// One light sample seen from `p`: its point, direction, distance and weight.
    fn sample_one(table: &LightTable, p: Vec3A, u_pick: f32, u: Vec2) -> (Vec3A, Vec3A, f32, Rgb) {
        let (s, _) = table.sample(p, &LightUniforms::from_lanes([(u_pick, u); LIGHT_LANES]));
        let wi = Vec3A::from_array(s.wi.map(|axis| axis.x));
        let radiance = Rgb::from_array(s.radiance.map(|channel| channel.x));
        (
            p + s.distance.x * wi,
            wi,
            s.distance.x,
            radiance * s.scale.x,
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
        // The hexagonal room's light: a quad at z = 4.99 facing down, its two triangles coplanar.
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
            for group in 0..4 {
                let uniforms = std::array::from_fn(|k| {
                    let d = 10 + 3 * (4 * group + k as u32);
                    (u(d), Vec2::new(u(d + 1), u(d + 2)))
                });
                let (samples, _) = table.sample(p, &LightUniforms::from_lanes(uniforms));
                assert_eq!(samples.scale, Vec4::ZERO, "{p}");
            }
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

    /// Lanes of one group that choose different kinds of light (two triangles, a sphere, a
    /// point light) get what each would get alone.
    #[test]
    fn lanes_of_mixed_lights_match_single_samples() {
        let area = |shape: Shape| AreaLight::new(shape, Rgb::new(1.0, 2.0, 3.0), false);
        let tri = |z: f32| {
            Shape::Triangle(TriangleGeom::new(
                Vec3A::new(-1.0, -1.0, z),
                Vec3A::new(1.0, -1.0, z),
                Vec3A::new(0.0, 1.0, z),
            ))
        };
        let ball = Shape::Sphere(SphereGeom {
            center: Vec3A::new(3.0, 0.0, 2.0),
            radius: 0.5,
        });
        let point = DeltaLight::point(Vec3A::new(-2.0, 1.0, 3.0), Rgb::new(5.0, 4.0, 3.0));
        let mut flipped = area(tri(3.0));
        flipped.two_sided = true;
        let table = LightTable::new(vec![area(tri(2.0)), flipped, area(ball)], vec![point]);
        let p = Vec3A::new(0.2, -0.1, 0.0);
        for i in 0..200 {
            let u = |d: u32| uniform(path_key(9, i, 0), 0, d);
            let uniforms: [(f32, Vec2); LIGHT_LANES] = std::array::from_fn(|k| {
                (
                    u(3 * k as u32),
                    Vec2::new(u(3 * k as u32 + 1), u(3 * k as u32 + 2)),
                )
            });
            let (group, group_points) = table.sample(p, &LightUniforms::from_lanes(uniforms));
            for (k, &one) in uniforms.iter().enumerate() {
                let (alone, alone_points) =
                    table.sample(p, &LightUniforms::from_lanes([one; LIGHT_LANES]));
                let lane = |s: &LightSamples| {
                    let mut values = s.wi.map(|v| v[k]).to_vec();
                    values.extend(s.radiance.map(|v| v[k]));
                    values.extend([s.distance[k], s.scale[k], s.pdf_solid_angle[k]]);
                    values.into_iter().map(f32::to_bits).collect::<Vec<_>>()
                };
                assert_eq!(lane(&group), lane(&alone), "case {i}, lane {k}");
                assert_eq!(group_points.area_light[k], alone_points.area_light[0]);
            }
        }
    }

    /// A quad light of two triangles at z = 2 facing down, split along either diagonal.
    fn quad_light(split: usize, radiance: [Rgb; 2]) -> Vec<AreaLight> {
        let v = [[-1.0, -0.5], [1.5, -0.5], [1.5, 1.0], [-1.0, 1.0]]
            .map(|[x, y]| Vec3A::new(x, y, 2.0));
        let (a, b, c, d) = (
            v[split],
            v[split + 1],
            v[(split + 2) % 4],
            v[(split + 3) % 4],
        );
        // Counter-clockwise seen from below: the front faces -z.
        let triangles = [TriangleGeom::new(a, c, b), TriangleGeom::new(a, d, c)];
        let light = |k: usize| AreaLight::new(Shape::Triangle(triangles[k]), radiance[k], false);
        vec![light(0), light(1)]
    }

    /// The mean of `radiance * scale * cos` at `p` (normal +z) over an `n x n` grid of sample
    /// coordinates: the irradiance, estimated.
    fn irradiance(table: &LightTable, p: Vec3A, n: u32) -> Rgb {
        let mut sum = Rgb::ZERO;
        for i in 0..n * n {
            let u = |k: u32| (k as f32 + 0.5) / n as f32;
            // The choice among lights from a Kronecker sequence, independent of the grid.
            let pick = (i as f32 * 0.618_034).fract();
            let uniforms = [(pick, Vec2::new(u(i % n), u(i / n))); LIGHT_LANES];
            let (s, _) = table.sample(p, &LightUniforms::from_lanes(uniforms));
            let cos = s.wi[2].x.max(0.0);
            sum += Rgb::from_array(s.radiance.map(|c| c.x)) * s.scale.x * cos;
        }
        sum / (n * n) as f32
    }

    #[test]
    fn a_quad_light_is_sampled_as_one_parallelogram_with_the_same_density() {
        let white = [Rgb::ONE; 2];
        for split in [0, 1] {
            let table = LightTable::new(quad_light(split, white), vec![]);
            let single = table.single.expect("the quad is one parallelogram");
            assert!(single.parallelogram);
            // The density per area is the triangles' own, which MIS reads where rays hit them.
            assert!((single.pdf_area.x - table.lights[1].pdf_area).abs() < 1e-7);
            let edge = |k: usize| Vec3A::from_array(single.edges[k].map(|axis| axis.x));
            let area = edge(0).cross(edge(1)).length();
            assert!((area - 3.75).abs() < 1e-5, "{area}");
            // The irradiance below it, estimated on a fine grid both ways, is one integral.
            let mut apart = table.clone();
            apart.locate_samples_on_triangles();
            assert!(apart.single.is_none());
            for p in [Vec3A::new(0.25, 0.25, 0.0), Vec3A::new(2.0, -1.0, 1.0)] {
                let (one, two) = (irradiance(&table, p, 128), irradiance(&apart, p, 128));
                assert!(
                    (one - two).abs().max_element() < 2e-3 * two.x,
                    "{one} {two} at {p}"
                );
                assert!(two.x > 0.05, "{two}");
            }
        }
        // Not one parallelogram: different radiance, a trapezoid, a flipped half, a second
        // light; one triangle alone is sampled as the lanes would sample it.
        let rejected = |lights: Vec<AreaLight>, delta: Vec<DeltaLight>| {
            LightTable::new(lights, delta).single.is_none()
        };
        assert!(rejected(quad_light(0, [Rgb::ONE, Rgb::splat(2.0)]), vec![]));
        let mut trapezoid = quad_light(0, white);
        let Shape::Triangle(t) = &mut trapezoid[1].shape else {
            unreachable!()
        };
        t.e1.x += 0.1;
        assert!(rejected(trapezoid, vec![]));
        let mut flipped = quad_light(0, white);
        let Shape::Triangle(t) = flipped[1].shape else {
            unreachable!()
        };
        let [a, b, c] = t.vertices();
        flipped[1] = AreaLight::new(Shape::Triangle(TriangleGeom::new(a, c, b)), Rgb::ONE, false);
        assert!(rejected(flipped, vec![]));
        let sun = DeltaLight::directional(Vec3A::NEG_Z, Rgb::ONE, 1.0);
        assert!(rejected(quad_light(0, white), vec![sun]));
        let one = LightTable::new(quad_light(0, white)[..1].to_vec(), vec![]);
        assert!(one.single.is_some_and(|s| !s.parallelogram));
        let mut lanes = one.clone();
        lanes.single = None;
        for i in 0..100 {
            let u = |d: u32| uniform(path_key(12, i, 0), 0, d);
            let uniforms = std::array::from_fn(|k| (u(3 * k as u32), Vec2::new(u(1), u(2))));
            let p = Vec3A::new(u(20), u(21), u(22) - 0.5);
            let bits = |s: LightSamples| {
                let mut v = s.wi.to_vec();
                v.extend(s.radiance);
                v.extend([s.distance, s.scale, s.pdf_solid_angle]);
                v.iter()
                    .flat_map(|x| x.to_array().map(f32::to_bits))
                    .collect::<Vec<_>>()
            };
            assert_eq!(
                bits(one.sample(p, &LightUniforms::from_lanes(uniforms)).0),
                bits(lanes.sample(p, &LightUniforms::from_lanes(uniforms)).0)
            );
        }
    }

    #[test]
    fn punctual_lights_follow_the_inverse_square_law_and_the_spot_cone() {
        let point = DeltaLight::point(Vec3A::new(0.0, 0.0, 2.0), Rgb::splat(8.0));
        let spot = DeltaLight::spot(
            Vec3A::new(0.0, 0.0, 2.0),
            Vec3A::NEG_Z,
            Rgb::splat(8.0),
            SpotCone::gltf(0.2, 0.4),
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
