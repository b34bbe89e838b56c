//! Stage 3, shade: at each hit, add emission the path may count, make the next-event
//! estimation shadow rays ([`super::next_event`]), sample the BSDF for the next ray, and play
//! Russian roulette.

use super::batch::{HitBatch, NO_HIT, PathState, RayBatch, ShadowBatch};
use super::light_paths::{self, CausticWeights};
use super::light_vertices::{self, CameraVertex};
use super::next_event::{
    self, GROUPS_PER_PASS, Media, NextEvent, SHADOW_RAY_SHORTENING, ShadingPoint, ShadowView,
};
use super::surface;
use crate::bsdf::Bsdf;
use crate::geometry::SurfacePoint;
use crate::lights::{Environment, LightSamples};
use crate::math::frame::Frame;
use crate::math::rng::{Sampler, dim};
use crate::math::{Rgb, Vec2, Vec3A, max_component, offset_ray_origin};
use crate::render_scene::{NO_EMITTER, RenderScene};

/// Russian roulette never keeps a path with probability above this, so that paths through
/// lossless materials (glass, white mirrors) still end.
const MAX_SURVIVAL: f32 = 0.95;

/// What shading needs to know besides the scene.
#[derive(Clone, Copy, Debug)]
pub struct ShadeParams<'a> {
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
    /// With light paths for caustics in the pass: what weights the caustic paths the path
    /// tracer finds against them ([`super::light_paths`]), and the light vertices its
    /// vertices connect to ([`super::light_vertices`]).
    pub caustics: Option<CausticWeights<'a>>,
}

/// Shades every hit of the batch. Writes each path's next ray into `next_rays` (same index)
/// and its shadow rays into its chunk of `shadows`; returns how many paths hit the depth cap.
pub fn shade_hits(
    scene: &RenderScene,
    params: ShadeParams,
    rays: &RayBatch,
    hits: &HitBatch,
    paths: &mut PathState,
    next_rays: &mut RayBatch,
    shadows: &mut ShadowBatch,
) -> u64 {
    // The one place that chooses the shading path, once per scene: where no material can
    // transmit through a rough lobe or holds a medium (every opaque scene, glass spheres
    // included: smooth glass has no lobe for shadow rays), the plain path, which does no
    // work for lights behind surfaces or for media; elsewhere the general one, which
    // chooses per hit (see `shade_one`). Both give the same image on such scenes (tested
    // below).
    if scene.transmits_or_absorbs {
        shade_batch::<true>(scene, params, rays, hits, paths, next_rays, shadows)
    } else {
        shade_batch::<false>(scene, params, rays, hits, paths, next_rays, shadows)
    }
}

/// [`shade_hits`] with the work for transmission and media compiled in (`THROUGH`) or out.
#[inline(always)]
fn shade_batch<const THROUGH: bool>(
    scene: &RenderScene,
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
    if shadows.lattice_rays != params.shadow_rays {
        next_event::shadow_ray_lattice(params.shadow_rays, &mut shadows.lattice);
        shadows.lattice_rays = params.shadow_rays;
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
            medium: &mut paths.medium[i],
            caustic_factor: &mut paths.caustic_factor[i],
            next_origin: &mut next_rays.origin[i],
            next_direction: &mut next_rays.direction[i],
        };
        let chunk = i * per..(i + 1) * per;
        let next_event = NextEvent {
            lattice: &shadows.lattice,
            samples: &mut samples,
            shadow: ShadowView {
                count: &mut shadows.count[i],
                origin: &mut shadows.origin[i],
                back_count: &mut shadows.back_count[i],
                back_origin: &mut shadows.back_origin[i],
                direction: &mut shadows.direction[chunk.clone()],
                t_max: &mut shadows.t_max[chunk.clone()],
                contribution: &mut shadows.contribution[chunk],
            },
        };
        capped += u64::from(shade_one::<THROUGH>(
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
    medium: &'a mut Rgb,
    caustic_factor: &'a mut f32,
    next_origin: &'a mut Vec3A,
    next_direction: &'a mut Vec3A,
}

/// A ray that left the scene: the environment's radiance, in full where next-event
/// estimation could not have chosen the direction, else with its MIS weight against the
/// shadow rays; camera rays see nothing when the environment is hidden from the camera.
#[cold]
fn escaped(
    scene: &RenderScene,
    environment: &Environment,
    params: &ShadeParams,
    hit: &Hit,
    path: &mut PathView,
) {
    if params.bounce == 0 && !scene.environment_visible {
        return;
    }
    let weight = if *path.count_emission {
        1.0
    } else if *path.bsdf_pdf > 0.0 {
        next_event::environment_weight(
            *path.bsdf_pdf,
            params.shadow_rays,
            scene.lights.environment_probability() * environment.pdf(hit.direction),
        )
    } else {
        return; // light sampling only: the shadow rays counted it
    };
    *path.radiance += *path.throughput * environment.eval(hit.direction) * weight;
}

/// The absorption coefficient of the medium inside `material` (zero if it has none).
#[inline]
pub(super) fn material_absorption(scene: &RenderScene, material: usize) -> Rgb {
    scene
        .material_absorption
        .get(material)
        .copied()
        .unwrap_or(Rgb::ZERO)
}

/// The fraction of light left after `distance` in a medium of absorption `sigma_a`.
#[inline]
pub(super) fn transmittance(sigma_a: Rgb, distance: f32) -> Rgb {
    // A channel that absorbs nothing keeps everything, even to a directional light's
    // infinite distance (0 x infinity would be NaN).
    let channel = |s: f32| if s > 0.0 { (-s * distance).exp() } else { 1.0 };
    Rgb::new(channel(sigma_a.x), channel(sigma_a.y), channel(sigma_a.z))
}

/// Shades one hit. Returns whether the path was cut by the depth cap. Without `THROUGH`
/// (scenes where nothing transmits or absorbs) the path's medium stays zero and every hit
/// takes the front-side light estimator.
#[inline(always)]
fn shade_one<const THROUGH: bool>(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    hit: Hit,
    path: &mut PathView,
    mut next_event: NextEvent,
) -> bool {
    *next_event.shadow.count = 0;
    *next_event.shadow.back_count = 0;
    *path.alive = false;
    if hit.slot == NO_HIT {
        if let Some(environment) = scene.lights.environment() {
            escaped(scene, environment, params, &hit, path);
        }
        return false; // without an environment the background is black
    }
    let slot = hit.slot as usize;
    let bounce = params.bounce;
    // Beer-Lambert absorption along the segment that reached the hit.
    if THROUGH && *path.medium != Rgb::ZERO {
        *path.throughput *= transmittance(*path.medium, hit.t);
    }

    // --- Surface: position, its rounding error, geometric and shading normals.
    let SurfacePoint { p, p_error, ng } =
        scene
            .shape(slot)
            .surface_point(hit.origin, hit.direction, hit.t, hit.barycentric);
    let ns = surface::shading_normal(scene, slot, hit.barycentric, ng);
    let wo = -hit.direction;
    let front = ng.dot(wo) > 0.0;

    // --- Emission: in full where next-event estimation could not have found it (camera
    // rays, delta bounces, no shadow rays), else with its MIS weight against the shadow rays.
    let emitter = scene.emitter_of(slot);
    if emitter != NO_EMITTER && (*path.count_emission || *path.bsdf_pdf > 0.0) {
        let light = &scene.lights.lights[emitter as usize];
        if front || light.two_sided {
            let emitted = surface::emitted_radiance(scene, emitter, hit.barycentric);
            if *path.count_emission {
                // A caustic path (camera or non-delta vertex, non-delta x1, delta bounces,
                // light) that the light paths find too: weighted against them. (Without
                // shadow rays emission after a non-delta bounce counts here too; its factor
                // is still pending, negative.)
                let weight = if params.caustics.is_some() && *path.caustic_factor > 0.0 {
                    light_paths::path_tracer_weight(light, *path.caustic_factor)
                } else {
                    1.0
                };
                *path.radiance += *path.throughput * emitted * weight;
            } else {
                let weight = next_event::emission_weight(
                    *path.bsdf_pdf,
                    params.shadow_rays,
                    light.pdf_area,
                    hit.t,
                    ng.dot(wo).abs(),
                );
                *path.radiance += *path.throughput * emitted * weight;
            }
        }
    }
    let material = scene.material_of(slot) as usize;
    let (bsdf, ns) = surface::textured_surface(scene, material, slot, hit.barycentric, ng, ns, wo);
    if bsdf.is_black() {
        if let Bsdf::Unlit { color } = bsdf {
            // KHR_materials_unlit shows its colour to whatever ray hits it, in full (it is
            // no light: no shadow ray could have found it).
            *path.radiance += *path.throughput * color;
        }
        return false; // e.g. a light source: it reflects nothing
    }
    let frame = Frame::from_normal(ns);
    let wo_local = frame.to_local(wo);

    // --- Next-event estimation: shadow rays toward lights chosen by power.
    if params.shadow_rays > 0 && !bsdf.is_delta() && !scene.lights.is_empty() {
        // Built in each branch: a shading point made before the branch would be stored to
        // memory for the out-of-line call, at every hit.
        let at = || ShadingPoint {
            p,
            p_error,
            ng,
            front,
            frame,
            bsdf,
            wo_local,
        };
        let throughput = *path.throughput;
        // The per-hit choice of the estimator: a surface that cannot transmit, reached outside
        // any medium, takes the front-side one, which pays nothing for transmission and
        // media; the others the general one.
        if THROUGH && (bsdf.transmits() || *path.medium != Rgb::ZERO) {
            // Shadow rays on the path's side travel in its medium; through the surface, in
            // the object's (entering) or outside (leaving).
            let media = Media {
                front: *path.medium,
                back: if front {
                    material_absorption(scene, material)
                } else {
                    Rgb::ZERO
                },
            };
            next_event::sample_lights_through(
                scene,
                params,
                key,
                &at(),
                media,
                throughput,
                next_event.reborrow(),
            );
        } else {
            next_event::sample_lights_front(
                scene,
                params,
                key,
                &at(),
                throughput,
                next_event.reborrow(),
            );
        }
    }

    // --- Connection to one of the pass's light vertices: caustics seen after this bounce.
    if let Some(caustics) = &params.caustics
        && caustics.connections
        && !caustics.light_vertices.is_empty()
        && !bsdf.is_delta()
    {
        let slots = caustics.light_path_count;
        let pick = params.sampler.index(key, bounce, dim::LIGHT_VERTEX, slots) as usize;
        let at = CameraVertex {
            p,
            ng,
            front,
            frame,
            bsdf,
            wo_local,
            throughput: *path.throughput,
            bounce,
        };
        if let Some(connection) =
            light_vertices::connect(scene, caustics, pick, &at, params.max_depth)
        {
            // One more shadow ray, from the side it leaves: after the front rays of
            // next-event estimation, or before its back rays at the chunk's end.
            let shadow = &mut next_event.shadow;
            let front_normal = if front { ng } else { -ng };
            let added = if !connection.through {
                *shadow.origin = offset_ray_origin(p, p_error, ng, front_normal);
                *shadow.count += 1;
                Some((*shadow.origin, *shadow.count as usize - 1, *path.medium))
            } else if THROUGH {
                *shadow.back_origin = offset_ray_origin(p, p_error, ng, -front_normal);
                *shadow.back_count += 1;
                let medium = if front {
                    material_absorption(scene, material)
                } else {
                    Rgb::ZERO
                };
                let entry = shadow.direction.len() - *shadow.back_count as usize;
                Some((*shadow.back_origin, entry, medium))
            } else {
                None // nothing transmits in this scene
            };
            if let Some((origin, entry, medium)) = added {
                let to_vertex = connection.target - origin;
                let distance = to_vertex.length();
                let t_max = distance * (1.0 - SHADOW_RAY_SHORTENING);
                shadow.direction[entry] = to_vertex / distance;
                shadow.t_max[entry] = t_max;
                shadow.contribution[entry] = if THROUGH && medium != Rgb::ZERO {
                    connection.contribution * transmittance(medium, t_max)
                } else {
                    connection.contribution
                };
            }
        }
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
    if let Some(caustics) = &params.caustics {
        *path.caustic_factor = if sample.is_delta {
            // A delta bounce after x1: the light paths can end here, the factor counts.
            path.caustic_factor.abs()
        } else if bounce == 0 {
            // This vertex as the light paths' diffuse point x1: the previous vertex's part of
            // the MIS ratio (with the count of its strategy), pending (negative) until a delta
            // bounce follows, and kept through the delta bounces. The camera connects to the
            // pass's n light paths; a non-delta vertex before x1 connects to one light vertex;
            // after a delta vertex nothing connects to x1.
            -(caustics.light_path_count as f32)
                * light_paths::camera_vertex_factor(
                    ng.dot(wi).abs(),
                    sample.pdf,
                    ng.dot(wo).abs(),
                    hit.t,
                    caustics.camera.direction_density(hit.direction),
                )
        } else if caustics.connections && *path.bsdf_pdf > 0.0 {
            // `bsdf_pdf` still holds the density of the previous (non-delta) vertex's sample.
            -light_paths::camera_vertex_factor(
                ng.dot(wi).abs(),
                sample.pdf,
                ng.dot(wo).abs(),
                hit.t,
                *path.bsdf_pdf,
            )
        } else {
            0.0
        };
    }
    *path.throughput *= sample.weight;
    if transmitted {
        *path.radiance_scale *= bsdf.radiance_compression(wo_local, sample.wi);
        // Into the object through its front side, out of it through its back side.
        if THROUGH {
            *path.medium = if front {
                material_absorption(scene, material)
            } else {
                Rgb::ZERO
            };
        }
    }
    // Emission the next hit finds counts in full where no shadow ray could have reached it:
    // after delta lobes and without shadow rays. Elsewhere, through a rough transmitting
    // surface as well (its shadow rays reach lights on both sides), MIS weights it, or,
    // with light sampling only, the shadow rays alone count it.
    *path.count_emission = sample.is_delta || params.shadow_rays == 0;
    *path.bsdf_pdf = if params.mis && !sample.is_delta {
        sample.pdf
    } else {
        0.0
    };

    // --- Russian roulette: survive with probability min(sqrt(max throughput), 0.95),
    // reweighted. The throughput without the radiance compression of refractions (as pbrt
    // and Mitsuba play it): inside glass it is 1/eta^2 = 0.44 of what it will be once the
    // path leaves, and killing 56% of the paths there multiplied the weight of every caustic
    // path that survived by 2.25. The square root (as Cycles) keeps more paths at the first
    // bounces, whose survivors would otherwise carry weights of 1/0.8 and more each: on the
    // room it lowers the relative MSE per sample by 16% for 15% more rays, and by 10% at
    // equal time (docs/sampling.md, section 2).
    if bounce >= params.roulette_min_bounces {
        let kept = max_component(*path.throughput) / *path.radiance_scale;
        let survival = kept.sqrt().min(MAX_SURVIVAL);
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

#[cfg(test)]
mod tests {
    use crate::settings::RenderSettings;

    /// The shading path of opaque scenes (no work for transmission or media) renders the
    /// same image as the general path, bit for bit, on the seed room (diffuse walls, a
    /// mirror and a smooth glass sphere, whose delta lobes need no shadow rays through them).
    #[test]
    fn the_opaque_scene_path_renders_what_the_general_path_renders() {
        let mut scene = crate::wavefront::next_event::tests::room();
        assert!(!scene.transmits_or_absorbs, "the room is opaque");
        let settings = RenderSettings {
            width: 40,
            height: 30,
            spp: 3,
            shadow_rays: 5,
            ..RenderSettings::default()
        };
        let plain = {
            let (film, _) = crate::render(&scene, &settings, |_| crate::Flow::Continue).unwrap();
            film.resolve().pixels
        };
        scene.transmits_or_absorbs = true;
        let general = {
            let (film, _) = crate::render(&scene, &settings, |_| crate::Flow::Continue).unwrap();
            film.resolve().pixels
        };
        assert!(plain.iter().any(|p| p.max_element() > 0.0));
        assert_eq!(plain, general);
    }
}
