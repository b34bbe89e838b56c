//! Stage 3, shade: at each hit, add emission the path may count, make the next-event
//! estimation shadow rays, sample the BSDF for the next ray, and play Russian roulette.

use super::batch::{HitBatch, NO_HIT, PathState, RayBatch, ShadowBatch};
use super::surface;
use crate::flatten::lights::{LIGHT_LANES, LightSamples};
use crate::flatten::spheres::SphereGeom;
use crate::flatten::{FlatScene, NO_EMITTER, Shape};
use crate::math::frame::Frame;
use crate::math::rng::{self, dim};
use crate::math::{Rgb, Vec2, Vec3A, max_component, offset_ray_origin};
use crate::settings::MAX_SHADOW_RAYS;

/// Russian roulette never keeps a path with probability above this, so that paths through
/// lossless materials (glass, white mirrors) still end.
const MAX_SURVIVAL: f32 = 0.95;
/// Shadow rays stop this fraction short of the light point, so the light itself never occludes.
const SHADOW_RAY_SHORTENING: f32 = 1e-4;

/// What shading needs to know besides the scene.
#[derive(Clone, Copy, Debug)]
pub struct ShadeParams {
    /// Index of the bounce: 0 for camera rays.
    pub bounce: u32,
    /// Shadow rays per non-delta hit; 0 disables next-event estimation.
    pub shadow_rays: u32,
    /// Whether light and BSDF samples are combined by multiple importance sampling.
    pub mis: bool,
    /// Bounces before Russian roulette may end a path.
    pub roulette_min_bounces: u32,
    /// Paths are cut (and counted) when they reach this depth.
    pub max_depth: u32,
}

/// Shades every hit of the batch. Writes each path's next ray into `next_rays` (same index)
/// and its shadow rays into its chunk of `shadows`; returns how many paths hit the depth cap.
pub fn shade_hits(
    scene: &FlatScene,
    params: ShadeParams,
    rays: &RayBatch,
    hits: &HitBatch,
    paths: &mut PathState,
    next_rays: &mut RayBatch,
    shadows: &mut ShadowBatch,
) -> u64 {
    let n = paths.len();
    next_rays.resize(n);
    shadows.grow_to(n);
    let per = shadows.per_path;
    // Shadow ray j of this bounce draws dimension SHADOW_FIRST + j on every path.
    let mut salts = [0; MAX_SHADOW_RAYS as usize];
    let salts = &mut salts[..params.shadow_rays as usize];
    for (j, salt) in salts.iter_mut().enumerate() {
        *salt = rng::dimension_salt(params.bounce, dim::SHADOW_FIRST + j as u32);
    }
    let mut light_samples = LightSamples::default();
    let mut capped = 0;
    for i in 0..n {
        let hit = Hit {
            origin: rays.origin[i],
            direction: rays.direction[i],
            t: hits.t[i],
            slot: hits.slot[i],
            barycentric: hits.barycentric[i],
        };
        let mut path = PathView {
            throughput: &mut paths.throughput[i],
            radiance: &mut paths.radiance[i],
            count_emission: &mut paths.count_emission[i],
            bsdf_pdf: &mut paths.bsdf_pdf[i],
            alive: &mut paths.alive[i],
            next_origin: &mut next_rays.origin[i],
            next_direction: &mut next_rays.direction[i],
        };
        let chunk = i * per..(i + 1) * per;
        let next_event = NextEvent {
            salts,
            samples: &mut light_samples,
            shadow: ShadowView {
                count: &mut shadows.count[i],
                origin: &mut shadows.origin[i],
                direction: &mut shadows.direction[chunk.clone()],
                t_max: &mut shadows.t_max[chunk.clone()],
                contribution: &mut shadows.contribution[chunk],
            },
        };
        capped += u64::from(shade_one(
            scene,
            &params,
            paths.rng_key[i],
            hit,
            &mut path,
            next_event,
        ));
    }
    capped
}

/// The ray and what it hit.
struct Hit {
    origin: Vec3A,
    direction: Vec3A,
    t: f32,
    slot: u32,
    barycentric: Vec2,
}

/// One path's mutable state.
struct PathView<'a> {
    throughput: &'a mut Rgb,
    radiance: &'a mut Rgb,
    count_emission: &'a mut bool,
    bsdf_pdf: &'a mut f32,
    alive: &'a mut bool,
    next_origin: &'a mut Vec3A,
    next_direction: &'a mut Vec3A,
}

/// What next-event estimation at one hit works with: the random-number salts of the shadow
/// rays, scratch space for the light samples, and the path's chunk of the shadow batch.
struct NextEvent<'a> {
    salts: &'a [u64],
    samples: &'a mut LightSamples,
    shadow: ShadowView<'a>,
}

/// One path's chunk of the shadow batch.
struct ShadowView<'a> {
    count: &'a mut u32,
    origin: &'a mut Vec3A,
    direction: &'a mut [Vec3A],
    t_max: &'a mut [f32],
    contribution: &'a mut [Rgb],
}

/// Shades one hit. Returns whether the path was cut by the depth cap.
fn shade_one(
    scene: &FlatScene,
    params: &ShadeParams,
    key: u64,
    hit: Hit,
    path: &mut PathView,
    next_event: NextEvent,
) -> bool {
    let NextEvent {
        salts,
        samples,
        shadow,
    } = next_event;
    *shadow.count = 0;
    *path.alive = false;
    if hit.slot == NO_HIT {
        return false; // the background is black
    }
    let slot = hit.slot as usize;
    let bounce = params.bounce;

    // --- Surface: position, its rounding error, geometric and shading normals.
    let (p, p_error, ng, ns) = match scene.shapes[slot] {
        Shape::Triangle(tri) => {
            let ng = tri.normal_unnormalized().normalize();
            let [n0, n1, n2] = scene.vertex_normals[slot];
            let b = hit.barycentric;
            let ns = if n0 == crate::math::Vec3::ZERO {
                ng
            } else {
                let ns = Vec3A::from(n0 * (1.0 - b.x - b.y) + n1 * b.x + n2 * b.y).normalize_or(ng);
                if ns.dot(ng) < 0.0 { -ns } else { ns } // the geometric normal decides the sides
            };
            (tri.point(b), tri.point_error(b), ng, ns)
        }
        Shape::Sphere(sphere) => {
            let (p, n) = sphere.project(hit.origin + hit.t * hit.direction);
            (p, SphereGeom::point_error(p), n, n)
        }
    };
    let wo = -hit.direction;
    let front = ng.dot(wo) > 0.0;

    // --- Emission: in full where next-event estimation could not have found it (camera
    // rays, delta bounces, no shadow rays), else with its MIS weight against the shadow rays.
    let emitter = scene.emitter[slot];
    if emitter != NO_EMITTER && (*path.count_emission || *path.bsdf_pdf > 0.0) {
        let light = &scene.lights.lights[emitter as usize];
        if front || light.two_sided {
            let emitted = surface::emitted_radiance(scene, emitter, hit.barycentric);
            if *path.count_emission {
                *path.radiance += *path.throughput * emitted;
            } else {
                // The density with which the shadow rays would have chosen this point, per
                // solid angle at the previous vertex (the ray's origin, `t` away).
                let cos_light = ng.dot(wo).abs();
                let light_pdf_sa = light.pdf_area * hit.t * hit.t / cos_light;
                let weight =
                    power_heuristic(*path.bsdf_pdf, params.shadow_rays as f32 * light_pdf_sa);
                *path.radiance += *path.throughput * emitted * weight;
            }
        }
    }
    let material = scene.material[slot] as usize;
    let (bsdf, ns) = surface::textured_surface(scene, material, slot, hit.barycentric, ng, ns, wo);
    if bsdf.is_black() {
        return false; // e.g. a light source: it reflects nothing
    }
    let frame = Frame::from_normal(ns);
    let wo_local = frame.to_local(wo);

    // --- Next-event estimation: N shadow rays to lights chosen by power (points on area
    // lights uniform by area; punctual lights have one point).
    let next_event = params.shadow_rays > 0 && !bsdf.is_delta() && !scene.lights.is_empty();
    if next_event {
        let inv_n = 1.0 / params.shadow_rays as f32;
        // Every shadow ray leaves on the front side of the surface (lights behind it are
        // skipped below), so all share one offset origin and can be traced as a packet.
        let front_normal = if front { ng } else { -ng };
        let origin = offset_ray_origin(p, p_error, ng, front_normal);
        *shadow.origin = origin;
        // Behind every light (a ceiling above a ceiling light) all samples would be zero.
        let samples_needed = if scene.lights.all_behind(origin) {
            0
        } else {
            salts.len()
        };
        let mut uniforms = [(0.0, Vec2::ZERO); LIGHT_LANES];
        for chunk_salts in salts[..samples_needed].chunks(LIGHT_LANES) {
            let lanes = chunk_salts.len();
            for (u, &salt) in uniforms.iter_mut().zip(chunk_salts) {
                *u = rng::uniform3_salted(key, salt);
            }
            // Sampled from the offset origin, so the direction and length serve the shadow
            // ray as they are (the offset is a rounding-error bound: it moves the estimate
            // by nothing measurable).
            scene.lights.sample(origin, &uniforms[..lanes], samples);
            // The receiver's side of every lane in one vectorised pass: the direction in the
            // shading frame, and whether the light shines here from the side the shadow rays
            // leave from.
            let mut wi_local = [[0.0; LIGHT_LANES]; 3];
            let mut usable = [0.0f32; LIGHT_LANES];
            // Plain numbers out of the vectors, so that the lane loop below vectorises.
            let [s, t, n, side] = [frame.s, frame.t, frame.n, front_normal].map(|v| v.to_array());
            let [wi_x, wi_y, wi_z] = &samples.wi;
            for k in 0..LIGHT_LANES {
                let dot = |v: [f32; 3]| wi_x[k] * v[0] + wi_y[k] * v[1] + wi_z[k] * v[2];
                (wi_local[0][k], wi_local[1][k], wi_local[2][k]) = (dot(s), dot(t), dot(n));
                // `&`, not `&&`: no branch, so that the loop vectorises.
                let on_front = dot(side) > 0.0;
                usable[k] = if on_front & (samples.scale[k] > 0.0) {
                    1.0
                } else {
                    0.0
                };
            }
            let mut f = [Rgb::ZERO; LIGHT_LANES];
            let mut bsdf_pdf = [0.0; LIGHT_LANES];
            bsdf.eval_and_pdf_lanes(wo_local, &wi_local, &mut f, &mut bsdf_pdf);
            // What multiplies f and the radiance: the light's weight, the cosine, the 1/N of
            // the N samples, and the MIS weight of this light sample against the BSDF sample
            // that could have found the point (punctual lights: weight 1).
            let mut factor = [0.0; LIGHT_LANES];
            for k in 0..LIGHT_LANES {
                let mis_weight = if params.mis {
                    power_heuristic(
                        params.shadow_rays as f32 * samples.pdf_solid_angle[k],
                        bsdf_pdf[k],
                    )
                } else {
                    1.0
                };
                factor[k] = samples.scale[k] * wi_local[2][k].abs() * inv_n * mis_weight;
            }
            for k in 0..lanes {
                if usable[k] == 0.0 {
                    continue;
                }
                let contribution = *path.throughput
                    * f[k]
                    * surface::light_sample_radiance(scene, samples, k)
                    * factor[k];
                if contribution == Rgb::ZERO {
                    continue; // nothing to add: no ray to trace
                }
                let j = *shadow.count as usize;
                *shadow.count += 1;
                // Directional lights are infinitely far: nothing may block the way out.
                shadow.direction[j] = samples.wi(k);
                shadow.t_max[j] = samples.distance[k] * (1.0 - SHADOW_RAY_SHORTENING);
                shadow.contribution[j] = contribution;
            }
        }
    }

    // --- BSDF sampling for the next ray.
    let u_lobe = rng::uniform(key, bounce, dim::BSDF_LOBE);
    let Some(sample) = bsdf.sample(
        wo_local,
        u_lobe,
        rng::uniform2(key, bounce, dim::BSDF_DIRECTION),
    ) else {
        return false;
    };
    let wi = frame.to_world(sample.wi);
    let transmitted = sample.wi.z * wo_local.z < 0.0;
    if ((ng.dot(wi) > 0.0) == front) == transmitted {
        return false; // the shading normal sent the ray through the wrong side of the surface
    }
    *path.throughput *= sample.weight;
    // Emission the next hit finds counts in full where no shadow ray could have reached it:
    // after delta lobes, without shadow rays, and through the surface (shadow rays only
    // leave on the front side; rough glass transmits). Elsewhere MIS weights it, or, with
    // light sampling only, the shadow rays alone count it.
    *path.count_emission = sample.is_delta || params.shadow_rays == 0 || transmitted;
    *path.bsdf_pdf = if params.mis && !sample.is_delta {
        sample.pdf
    } else {
        0.0
    };

    // --- Russian roulette: survive with probability min(max throughput, 0.95), reweighted.
    if bounce >= params.roulette_min_bounces {
        let survival = max_component(*path.throughput).min(MAX_SURVIVAL);
        if rng::uniform(key, bounce, dim::ROULETTE) >= survival {
            return false;
        }
        *path.throughput /= survival;
    } else if *path.throughput == Rgb::ZERO {
        return false;
    }
    if bounce + 1 >= params.max_depth {
        return true;
    }
    *path.next_origin = offset_ray_origin(p, p_error, ng, wi);
    *path.next_direction = wi;
    *path.alive = true;
    false
}

/// Veach's power heuristic (beta = 2) for a sample from the strategy of density `pdf`
/// against one of density `other_pdf`, each already multiplied by its sample count.
/// Branch-free, so that lane loops vectorise it.
#[inline(always)]
fn power_heuristic(pdf: f32, other_pdf: f32) -> f32 {
    let (a, b) = (pdf * pdf, other_pdf * other_pdf);
    let weight = if a + b > 0.0 { a / (a + b) } else { 0.0 };
    if a == f32::INFINITY { 1.0 } else { weight }
}
