//! Stage 3, shade: at each hit, add emission the path may count, make the next-event
//! estimation shadow rays, sample the BSDF for the next ray, and play Russian roulette.

use super::batch::{HitBatch, NO_HIT, PathState, RayBatch, ShadowBatch};
use super::surface;
use crate::flatten::lights::{LIGHT_LANES, LightSamples, LightUniforms};
use crate::flatten::spheres::SphereGeom;
use crate::flatten::{FlatScene, NO_EMITTER, Shape};
use crate::math::frame::Frame;
use crate::math::rng::{Sampler, dim};
use crate::math::sampling::Rank1Lattice;
use crate::math::{Rgb, Vec2, Vec3A, Vec4, max_component, offset_ray_origin, transpose4};
use crate::settings::MAX_SHADOW_RAYS;

/// Russian roulette never keeps a path with probability above this, so that paths through
/// lossless materials (glass, white mirrors) still end.
const MAX_SURVIVAL: f32 = 0.95;
/// Groups of light samples taken before any of them is shaded (see `shade_one`).
const GROUPS_PER_PASS: usize = 4;
/// Groups of four shadow rays a hit takes at most.
const MAX_SHADOW_GROUPS: usize = (MAX_SHADOW_RAYS as usize).div_ceil(LIGHT_LANES);
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
    /// Where the random numbers come from.
    pub sampler: Sampler,
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
    // The shadow rays of a hit take the points of one lattice, four lanes to a group (lanes
    // past the last ray repeat it), shifted per path.
    let mut lattice = [LightUniforms::default(); MAX_SHADOW_GROUPS];
    let lattice = &mut lattice[..(params.shadow_rays as usize).div_ceil(LIGHT_LANES)];
    if !lattice.is_empty() {
        let points = Rank1Lattice::new(params.shadow_rays);
        let last = params.shadow_rays - 1;
        for (g, group) in lattice.iter_mut().enumerate() {
            let point = |k: usize| points.point(((g * LIGHT_LANES + k) as u32).min(last));
            *group = LightUniforms::from_lanes(std::array::from_fn(|k| {
                let [pick, u, v] = point(k);
                (pick, Vec2::new(u, v))
            }));
        }
    }
    let mut samples = [LightSamples::default(); GROUPS_PER_PASS];
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
            radiance_scale: &mut paths.radiance_scale[i],
            next_origin: &mut next_rays.origin[i],
            next_direction: &mut next_rays.direction[i],
        };
        let chunk = i * per..(i + 1) * per;
        let next_event = NextEvent {
            lattice,
            samples: &mut samples,
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
    radiance_scale: &'a mut f32,
    next_origin: &'a mut Vec3A,
    next_direction: &'a mut Vec3A,
}

/// What next-event estimation at one hit works with: the lattice of the shadow rays' light
/// samples (one group per four rays) and the path's chunk of the shadow batch.
struct NextEvent<'a> {
    lattice: &'a [LightUniforms],
    samples: &'a mut [LightSamples; GROUPS_PER_PASS],
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
        lattice,
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
    let (p, p_error, ng, ns) = match scene.shape(slot) {
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
                let weight = power_heuristic(
                    Vec4::splat(*path.bsdf_pdf),
                    Vec4::splat(params.shadow_rays as f32 * light_pdf_sa),
                )
                .x;
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
        let groups_needed = if scene.lights.all_behind(origin) {
            0
        } else {
            lattice.len()
        };
        // The lattice's shift for this path: one hash for all its shadow rays.
        let shift = params.sampler.uniform3(key, bounce, dim::LIGHT_SAMPLES);
        // The shading frame and the side the shadow rays leave from, one vector per
        // coordinate, for the lanes.
        let [s, t, n, side] =
            [frame.s, frame.t, frame.n, front_normal].map(|v| v.to_array().map(Vec4::splat));
        let throughput = path.throughput.to_array().map(Vec4::splat);
        let mut count = 0;
        let rays = params.shadow_rays as usize;
        for (p, pass) in lattice[..groups_needed].chunks(GROUPS_PER_PASS).enumerate() {
            // First every group's light samples, then their shading: each group's chain of
            // square root and divisions is long, and the chains of a pass overlap only if no
            // shading code sits between them.
            for (group, samples) in pass.iter().zip(samples.iter_mut()) {
                let uniforms = group.shifted(shift);
                // Sampled from the offset origin, so the direction and length serve the
                // shadow ray as they are (the offset is a rounding-error bound: it moves the
                // estimate by nothing measurable).
                samples.overwrite(surface::texture_light_samples(
                    scene,
                    scene.lights.sample(origin, &uniforms),
                ));
            }
            for (g, samples) in samples.iter().take(pass.len()).enumerate() {
                // Lanes past the last ray repeat it; they are never kept.
                let first = (p * GROUPS_PER_PASS + g) * LIGHT_LANES;
                let lanes = (rays - first).min(LIGHT_LANES);
                let [wi_x, wi_y, wi_z] = samples.wi;
                let dot = |v: [Vec4; 3]| wi_x * v[0] + wi_y * v[1] + wi_z * v[2];
                let wi_local = [dot(s), dot(t), dot(n)];
                // Whether the light shines here from the side the shadow rays leave from.
                let usable = dot(side).cmpgt(Vec4::ZERO) & samples.scale.cmpgt(Vec4::ZERO);
                let (f, bsdf_pdf) = bsdf.eval_and_pdf_lanes(wo_local, &wi_local);
                // What multiplies f and the radiance: the light's weight, the cosine, the 1/N of
                // the N samples, and the MIS weight of this light sample against the BSDF sample
                // that could have found the point (punctual lights: weight 1).
                let mis_weight = if params.mis {
                    power_heuristic(
                        Vec4::splat(params.shadow_rays as f32) * samples.pdf_solid_angle,
                        bsdf_pdf,
                    )
                } else {
                    Vec4::ONE
                };
                let factor = samples.scale * wi_local[2].abs() * Vec4::splat(inv_n) * mis_weight;
                let channel = |c: usize| throughput[c] * f[c] * samples.radiance[c] * factor;
                let contribution = [channel(0), channel(1), channel(2)];
                let lit = contribution[0].cmpne(Vec4::ZERO)
                    | contribution[1].cmpne(Vec4::ZERO)
                    | contribution[2].cmpne(Vec4::ZERO);
                // A shadow ray only where there is something to add.
                let keep = (usable & lit).bitmask() & ((1 << lanes) - 1);
                // Back to one vector per lane, and written without branches: every lane is
                // stored at the next free entry, which only a kept lane takes.
                let rays = transpose4([wi_x, wi_y, wi_z, samples.distance]);
                let [r, g, b] = contribution;
                let colours = transpose4([r, g, b, Vec4::ZERO]);
                for (k, (ray, colour)) in rays.into_iter().zip(colours).take(lanes).enumerate() {
                    shadow.direction[count] = Vec3A::from_vec4(ray);
                    shadow.t_max[count] = ray.w * (1.0 - SHADOW_RAY_SHORTENING);
                    shadow.contribution[count] = colour.truncate();
                    count += (keep >> k & 1) as usize;
                }
            }
        }
        *shadow.count = count as u32;
    }

    // --- BSDF sampling for the next ray.
    let u_lobe = params.sampler.uniform(key, bounce, dim::BSDF_LOBE);
    let Some(sample) = bsdf.sample(
        wo_local,
        u_lobe,
        params.sampler.uniform2(key, bounce, dim::BSDF_DIRECTION),
    ) else {
        return false;
    };
    let wi = frame.to_world(sample.wi);
    let transmitted = sample.wi.z * wo_local.z < 0.0;
    if ((ng.dot(wi) > 0.0) == front) == transmitted {
        return false; // the shading normal sent the ray through the wrong side of the surface
    }
    *path.throughput *= sample.weight;
    if transmitted {
        *path.radiance_scale *= bsdf.radiance_compression(wo_local, sample.wi);
    }
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
    // The throughput without the radiance compression of refractions (as pbrt and Mitsuba
    // play it): inside glass it is 1/eta^2 = 0.44 of what it will be once the path leaves,
    // and killing 56% of the paths there multiplied the weight of every caustic path that
    // survived by 2.25.
    if bounce >= params.roulette_min_bounces {
        let survival = (max_component(*path.throughput) / *path.radiance_scale).min(MAX_SURVIVAL);
        if params.sampler.uniform(key, bounce, dim::ROULETTE) >= survival {
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

/// Veach's power heuristic (beta = 2), lane by lane, for a sample from the strategy of
/// density `pdf` against one of density `other_pdf`, each already multiplied by its sample
/// count.
#[inline(always)]
fn power_heuristic(pdf: Vec4, other_pdf: Vec4) -> Vec4 {
    let (a, b) = (pdf * pdf, other_pdf * other_pdf);
    let weight = Vec4::select((a + b).cmpgt(Vec4::ZERO), a / (a + b), Vec4::ZERO);
    Vec4::select(a.cmpeq(Vec4::INFINITY), Vec4::ONE, weight)
}
