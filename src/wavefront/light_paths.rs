//! Light paths for caustics seen directly: paths `light -> (mirror | smooth glass)+ ->
//! diffuse point -> camera`, which the path tracer finds only when a BSDF sample at the
//! camera's first hit happens to pass through the delta chain onto a (small) light: rare and
//! very bright, the fireflies of scenes with glass and mirrors. Next-event estimation cannot
//! reach a light through a delta surface.
//!
//! Once per pass, before the camera paths, `light_path_count` light paths leave the lights
//! (chosen as next-event estimation chooses them, by power; area lights emit
//! cosine-distributed from a point uniform by area, point and spot lights uniformly over
//! their sphere or cone). A path follows delta bounces only; at the first non-delta surface
//! after at least one of them (the diffuse point `x1`) it is connected to the pinhole by a
//! shadow ray, and its contribution is kept for the pixel `x1` projects to. A path whose
//! first hit is non-delta stops at once (next-event estimation does direct light far
//! better), so most light paths cost one ray. The pass's splats are added in path order into
//! one buffer, and each camera sample of the pass carries its pixel's splats into the film
//! (`batch::compact_paths`): a pixel that takes no sample in the pass (adaptive sampling, an
//! interrupted pass) drops them, and each sample stays an unbiased estimate of its pixel.
//! The diffuse points are also kept, in path order, as the pass's light vertices, to which
//! the camera paths' later vertices connect ([`super::light_vertices`]: caustics seen after a
//! diffuse bounce).
//!
//! The path tracer finds the same paths (camera -> `x1`, non-delta BSDF sample, delta
//! bounces, emitter) and both count them with the balance heuristic, one camera sample per
//! pixel against `n` light paths per pass: the path tracer's weight is `1 / (1 + r)` and the
//! light tracer's `r / (1 + r)` with
//!
//! ```text
//! r = n p_LT / p_PT = n * p_light_area(y0) * (p_emit(w0) / cos_y0) * cos_x1
//!                       / (p_bsdf(w1) * p_camera_area(x1))
//! ```
//!
//! both densities taken in the measure of the path tracer's variables (`x1` by area, `w1` by
//! solid angle; through a delta chain `dA(x1) dw(w1) cos_x1 = dA(y0) dw(w0) cos_y0` in one
//! medium). The two sides compute `r` with the same functions ([`super::mis`]) from the same
//! quantities, so the weights sum to one for every path, and the sum stays unbiased even
//! where the ratio leaves out factors (the Fresnel choices, alike both
//! ways; the `n^2` of a light inside glass). Punctual lights, which no ray can hit, take
//! weight 1: their caustics come only from here. Directional and environment lights would
//! need emission from a disk over the scene and are left to the path tracer.
//!
//! Throughput along the light path: `Le cos_y0 / (p_light_area p_emit)` at the light, the
//! delta lobes' tint at each bounce (the sample's weight without the `1/eta^2` radiance
//! compression, which belongs to radiance flowing toward the camera; through a chain that
//! starts and ends in air the path tracer's compressions multiply to 1 too), absorption in
//! media, and at `x1` the BSDF toward the camera times `|ns.wi| / |ng.wi|` (the adjoint
//! shading-normal correction) times the camera's density of `x1` per area, `p_camera_area`,
//! which is the pinhole's importance for the pixel. Lights inside absorbing objects are taken
//! to start outside any medium (as cameras are).
//!
//! Determinism: light path `k` of pass `p` draws from a key of (seed, pass, k) alone; chunks
//! of paths run in parallel and their splats are added in path order.

use super::light_vertices::{self, LightVertex};
use super::medium::{material_absorption, transmittance};
use super::mis::{camera_vertex_factor, emission_density_over_cos, light_tracer_weight, mis_ratio};
use super::surface;
use crate::bsdf::Bsdf;
use crate::camera::PinholeCamera;
use crate::geometry::sphere::SphereGeom;
use crate::geometry::{Shape, SurfacePoint};
use crate::lights::{AreaLight, DeltaKind, DeltaLight};
use crate::math::frame::Frame;
use crate::math::rng::{dim, path_key, uniform, uniform2, uniform3};
use crate::math::sampling::{sample_cosine_hemisphere, sample_discrete, sample_triangle};
use crate::math::{Rgb, Vec2, Vec3A, Vec4, offset_ray_origin};
use crate::render_scene::{RayKey, RenderScene, TraversalStack};
use crate::settings::RenderSettings;
use rayon::prelude::*;
use std::f32::consts::{FRAC_1_PI, PI};

/// Whether the render traces light paths for caustics: they are asked for, multiple
/// importance sampling is on (without it, `--no-mis`, the renderer is the seed's estimator),
/// the scene has a delta surface for them to bounce off and a light they can leave from, and
/// paths are deep enough to hold a delta bounce between the camera's hit and the light.
pub fn caustics_traced(scene: &RenderScene, settings: &RenderSettings) -> bool {
    let has_delta_surface = scene
        .materials
        .iter()
        .any(|m| matches!(m, Bsdf::Mirror { .. } | Bsdf::Dielectric { .. }) && !m.is_black());
    let has_light = !scene.lights.lights.is_empty()
        || scene
            .lights
            .delta_lights
            .iter()
            .any(|l| !matches!(l.kind, DeltaKind::Directional { .. }));
    // An orthographic camera's rays share one direction: no light path can reach its film
    // (the path tracer alone finds caustics there).
    settings.caustic_paths > 0.0
        && !scene.camera.is_orthographic()
        && settings.mis
        && settings.max_depth >= 3
        && has_delta_surface
        && has_light
}

/// Light paths in a pass of an image of `pixels` pixels (all of them, however many take a
/// sample in the pass: see `render_rows`).
pub fn light_path_count(settings: &RenderSettings, pixels: u64) -> u64 {
    (settings.caustic_paths as f64 * pixels as f64).round() as u64
}

/// Salt of the light paths' keys, apart from the camera paths'.
const LIGHT_PATH_SALT: u64 = 0x4C16_47C0_FFEE_D00D;

/// Light paths per parallel job.
const PATHS_PER_JOB: u64 = 4096;

/// Traces the pass's light paths and writes their splats, summed per pixel in path order,
/// into `splats` (one per pixel of the film, cleared first), and, with
/// `settings.caustic_connections` or merging, their diffuse end points in path order into
/// `light_vertices` (cleared first). Returns the rays traced.
pub fn trace_light_paths(
    scene: &RenderScene,
    settings: &RenderSettings,
    camera: &PinholeCamera,
    pass: u32,
    path_count: u64,
    splats: &mut Vec<Rgb>,
    light_vertices: &mut Vec<LightVertex>,
) -> u64 {
    splats.clear();
    splats.resize((settings.width * settings.height) as usize, Rgb::ZERO);
    light_vertices.clear();
    if path_count == 0 {
        return 0;
    }
    let tracer = LightTracer {
        scene,
        camera,
        seed: settings.seed,
        pass,
        light_paths: path_count as f32,
        max_delta_bounces: settings.max_depth.saturating_sub(2),
        keep_vertices: settings.caustic_connections || settings.caustic_merge_radius > 0.0,
    };
    let jobs: Vec<JobOutput> = (0..path_count.div_ceil(PATHS_PER_JOB))
        .into_par_iter()
        .map(|job| {
            let mut stack = TraversalStack::default();
            let mut out = JobOutput::default();
            let first = job * PATHS_PER_JOB;
            for k in first..(first + PATHS_PER_JOB).min(path_count) {
                if let Some(splat) = tracer.trace(&mut stack, k, &mut out) {
                    out.splats.push(splat);
                }
            }
            out
        })
        .collect();
    let mut rays = 0;
    for job in jobs {
        rays += job.rays;
        for (film_point, value) in job.splats {
            camera.splat(film_point, value, splats);
        }
        light_vertices.extend_from_slice(&job.vertices);
    }
    rays
}

/// What one job of light paths found, in path order.
#[derive(Default)]
struct JobOutput {
    /// Film position and value (for the box of 1 px) of each splat.
    splats: Vec<(Vec2, Rgb)>,
    vertices: Vec<LightVertex>,
    rays: u64,
}

/// One pass's light tracer.
struct LightTracer<'a> {
    scene: &'a RenderScene,
    camera: &'a PinholeCamera,
    seed: u64,
    pass: u32,
    light_paths: f32,
    /// Most delta bounces before the diffuse point: the path tracer's depth cap leaves it
    /// room for the camera's hit, these bounces and the light.
    max_delta_bounces: u32,
    /// Whether the diffuse points are kept for connections from camera vertices and merges.
    keep_vertices: bool,
}

/// Where a light path starts: its ray, throughput, and the area light it left (for the MIS
/// weight; none for punctual lights).
struct Emission<'a> {
    origin: Vec3A,
    direction: Vec3A,
    throughput: Rgb,
    area_light: Option<&'a AreaLight>,
    /// Its index in the light table, or [`light_vertices::PUNCTUAL`].
    light_index: u32,
}

impl LightTracer<'_> {
    /// Light path `k`: its splat (pixel, value), if it makes one; counts its rays in
    /// `out.rays` and keeps its diffuse point in `out.vertices` (if asked to).
    fn trace(
        &self,
        stack: &mut TraversalStack,
        k: u64,
        out: &mut JobOutput,
    ) -> Option<(Vec2, Rgb)> {
        let rays = &mut out.rays;
        let scene = self.scene;
        // Paths beyond 2^32 in a pass (huge images) salt the seed with the high bits.
        let seed = self.seed ^ LIGHT_PATH_SALT ^ (k >> 32).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        let key = path_key(seed, k as u32, self.pass);
        let emission = self.emit(key)?;
        let (mut origin, mut direction) = (emission.origin, emission.direction);
        let mut throughput = emission.throughput;
        let mut medium = Rgb::ZERO;
        for bounce in 1.. {
            *rays += 1;
            let ray_key = RayKey {
                path: key,
                bounce,
                ray: 0,
            };
            let (slot, t) =
                scene.closest_covered_hit(stack, origin, direction, f32::INFINITY, ray_key)?;
            if medium != Rgb::ZERO {
                throughput *= transmittance(medium, t);
            }
            let slot = slot as usize;
            let shape = scene.shape(slot);
            let barycentric = shape.barycentric(origin, direction);
            let SurfacePoint { p, p_error, ng } =
                shape.surface_point(origin, direction, t, barycentric);
            let material = scene.material_of(slot) as usize;
            if !scene.materials[material].is_delta() {
                // The diffuse point: a caustic only after at least one delta bounce.
                if bounce == 1 {
                    return None;
                }
                if self.keep_vertices {
                    out.vertices.push(LightVertex {
                        p,
                        ng,
                        to_light: -direction,
                        throughput,
                        slot: slot as u32,
                        material: material as u32,
                        barycentric,
                        light: emission.light_index,
                        delta_bounces: bounce - 1,
                    });
                }
                let at = DiffusePoint {
                    slot,
                    material,
                    barycentric,
                    p,
                    p_error,
                    ng,
                    to_light: -direction,
                };
                return self.connect(
                    stack,
                    key,
                    bounce,
                    at,
                    throughput,
                    emission.area_light,
                    rays,
                );
            }
            if bounce > self.max_delta_bounces {
                return None;
            }
            // A delta bounce: the light travels on in the lobe's direction.
            let ns = surface::shading_normal(scene, slot, barycentric, ng);
            let wo = -direction;
            let (bsdf, ns) =
                surface::textured_surface(scene, material, slot, barycentric, ng, ns, wo);
            if bsdf.is_black() {
                return None;
            }
            let frame = Frame::from_normal(ns);
            let wo_local = frame.to_local(wo);
            let sample = bsdf.sample(
                wo_local,
                uniform(key, bounce, dim::BSDF_LOBE),
                uniform2(key, bounce, dim::BSDF_DIRECTION),
            )?;
            let wi = frame.to_world(sample.wi);
            let front = ng.dot(wo) > 0.0;
            let transmitted = sample.wi.z * wo_local.z < 0.0;
            if ((ng.dot(wi) > 0.0) == front) == transmitted {
                return None; // the shading normal sent it through the wrong side
            }
            throughput *= sample.weight / bsdf.radiance_compression(wo_local, sample.wi);
            if transmitted && scene.transmits_or_absorbs {
                medium = if front {
                    material_absorption(scene, material)
                } else {
                    Rgb::ZERO
                };
            }
            if throughput == Rgb::ZERO {
                return None;
            }
            origin = offset_ray_origin(p, p_error, ng, wi);
            direction = wi;
        }
        None
    }

    /// Chooses a light by power (as next-event estimation does) and the ray it emits;
    /// directional and environment lights emit nothing here.
    fn emit(&self, key: u64) -> Option<Emission<'_>> {
        let lights = &self.scene.lights;
        if lights.is_empty() {
            return None;
        }
        let (u_pick, u_point) = uniform3(key, 0, dim::LIGHT_SAMPLES);
        let u_direction = uniform2(key, 0, dim::BSDF_DIRECTION);
        let index = sample_discrete(&lights.power_cdf, u_pick);
        if let Some(light) = lights.lights.get(index) {
            return self.emit_area(light, index as u32, key, u_point, u_direction);
        }
        // Punctual lights follow the area lights in the table.
        let light = lights.delta_lights.get(index - lights.lights.len())?;
        emit_punctual(light, u_direction)
    }

    /// A cosine-distributed ray from a point uniform by area on `light`, on its emitting side
    /// (a two-sided light: either side, by a coin).
    fn emit_area<'a>(
        &self,
        light: &'a AreaLight,
        index: u32,
        key: u64,
        u_point: Vec2,
        u_direction: Vec2,
    ) -> Option<Emission<'a>> {
        let (p, p_error, normal, radiance) = match light.shape {
            Shape::Triangle(t) => {
                let [b1, b2] = sample_triangle([Vec4::splat(u_point.x), Vec4::splat(u_point.y)]);
                let b = Vec2::new(b1.x, b2.x);
                let radiance = surface::sampled_emitted_radiance(self.scene, index, b);
                (t.point(b), t.point_error(b), light.normal, radiance)
            }
            Shape::Sphere(s) => {
                let n = crate::math::sampling::sample_uniform_sphere(u_point);
                let (p, n) = s.project(s.center + s.radius * n);
                (p, SphereGeom::point_error(p), n, light.radiance)
            }
        };
        let side = if light.two_sided && uniform(key, 0, dim::BSDF_LOBE) < 0.5 {
            -normal
        } else {
            normal
        };
        let direction = Frame::from_normal(side).to_world(sample_cosine_hemisphere(u_direction));
        // Le cos / (p_area p_emit) with p_emit = cos / pi (or cos / 2 pi over both sides).
        let throughput = radiance / (light.pdf_area * emission_density_over_cos(light));
        (throughput.max_element() > 0.0 && direction.dot(side) > 0.0).then(|| Emission {
            origin: offset_ray_origin(p, p_error, side, direction),
            direction,
            throughput,
            area_light: Some(light),
            light_index: index,
        })
    }

    /// Connects the diffuse point `at`, reached by light with `throughput` (from
    /// `area_light`, or a punctual light), to the camera: the splat it makes, if the camera
    /// sees it.
    #[allow(clippy::too_many_arguments)]
    fn connect(
        &self,
        stack: &mut TraversalStack,
        key: u64,
        bounce: u32,
        at: DiffusePoint,
        throughput: Rgb,
        area_light: Option<&AreaLight>,
        rays: &mut u64,
    ) -> Option<(Vec2, Rgb)> {
        let scene = self.scene;
        let film_point = self.camera.film_point(at.p)?;
        let to_eye = self.camera.eye() - at.p;
        let distance = to_eye.length();
        let wo = to_eye / distance;
        let ns = surface::shading_normal(scene, at.slot, at.barycentric, at.ng);
        let (bsdf, ns) =
            surface::textured_surface(scene, at.material, at.slot, at.barycentric, at.ng, ns, wo);
        if bsdf.is_black() {
            return None;
        }
        let frame = Frame::from_normal(ns);
        let (wo_local, wi_local) = (frame.to_local(wo), frame.to_local(at.to_light));
        // The sides as the path tracer sees them: its sample toward the light must leave on
        // the side the shading frame says.
        let transmitted = wi_local.z * wo_local.z < 0.0;
        let front = at.ng.dot(wo) > 0.0;
        if ((at.ng.dot(at.to_light) > 0.0) == front) == transmitted {
            return None;
        }
        let f = bsdf.eval(wo_local, wi_local);
        if f.max_element() <= 0.0 {
            return None;
        }
        let (cos_camera, cos_light) = (at.ng.dot(wo).abs(), at.ng.dot(at.to_light).abs());
        let direction_density = self.camera.direction_density(-wo);
        let camera_area_density = direction_density * cos_camera / (distance * distance);
        let weight = match area_light {
            None => 1.0,
            Some(light) => {
                let pdf = bsdf.pdf(wo_local, wi_local);
                let factor = self.light_paths
                    * camera_vertex_factor(cos_light, pdf, cos_camera, distance, direction_density);
                if factor == 0.0 {
                    return None; // a degenerate point: the path tracer's weight is 1 there
                }
                light_tracer_weight(mis_ratio(light, factor))
            }
        };
        let value = throughput
            * f
            * (wi_local.z.abs() / cos_light)
            * (camera_area_density * weight / self.light_paths);
        if !(value.is_finite() && value.max_element() > 0.0) {
            return None;
        }
        // The camera must see the point: nothing between it and the eye.
        *rays += 1;
        let origin = offset_ray_origin(at.p, at.p_error, at.ng, wo);
        let ray_key = RayKey {
            path: key,
            bounce: bounce + 1,
            ray: 0,
        };
        let blocked = scene
            .closest_covered_hit(
                stack,
                origin,
                wo,
                (self.camera.eye() - origin).length(),
                ray_key,
            )
            .is_some();
        (!blocked).then_some((film_point, value))
    }
}

/// The first non-delta surface a light path meets after its delta bounces.
struct DiffusePoint {
    slot: usize,
    material: usize,
    barycentric: Vec2,
    p: Vec3A,
    p_error: Vec3A,
    ng: Vec3A,
    /// Unit direction back toward where the light came from.
    to_light: Vec3A,
}

/// A ray from a point or spot light, uniform over its sphere or cone, with the throughput
/// `I(w) / (p_choice p(w))`; none for directional lights.
fn emit_punctual(light: &DeltaLight, u: Vec2) -> Option<Emission<'static>> {
    let (origin, direction, density, falloff) = match light.kind {
        DeltaKind::Point { position } => (
            position,
            crate::math::sampling::sample_uniform_sphere(u),
            0.25 * FRAC_1_PI,
            1.0,
        ),
        DeltaKind::Spot {
            position,
            direction: axis,
            cone,
        } => {
            // Uniform in the outer cone: cos theta uniform in [cos_outer, 1].
            let cos = 1.0 - u.x * (1.0 - cone.cos_outer);
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let phi = 2.0 * PI * u.y;
            let local = Vec3A::new(sin * phi.cos(), sin * phi.sin(), cos);
            let solid_angle = 2.0 * PI * (1.0 - cone.cos_outer);
            (
                position,
                Frame::from_normal(axis).to_world(local),
                1.0 / solid_angle,
                cone.attenuation(cos),
            )
        }
        DeltaKind::Directional { .. } => return None,
    };
    let throughput = light.intensity * (falloff / (light.select_probability * density));
    (throughput.max_element() > 0.0).then_some(Emission {
        origin,
        direction,
        throughput,
        area_light: None,
        light_index: light_vertices::PUNCTUAL,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Scenes without a mirror or smooth glass trace no light paths, and their images do not
    /// change at all.
    #[test]
    fn scenes_without_delta_surfaces_render_as_before() {
        let mut scene = crate::wavefront::tests::room();
        let settings = RenderSettings {
            width: 24,
            height: 20,
            spp: 2,
            ..RenderSettings::default()
        };
        assert!(caustics_traced(&scene, &settings));
        for m in &mut scene.materials {
            if m.is_delta() {
                *m = Bsdf::Lambertian {
                    albedo: Rgb::splat(0.5),
                };
            }
        }
        assert!(!caustics_traced(&scene, &settings));
        let render = |caustic_paths| {
            let settings = RenderSettings {
                caustic_paths,
                ..settings
            };
            let (film, stats) =
                crate::render(&scene, &settings, |_| crate::Flow::Continue).unwrap();
            assert_eq!(stats.light_rays, 0);
            film.resolve().pixels
        };
        assert_eq!(render(1.0), render(0.0));
    }
}
