//! The shade stage's per-hit kernel, [`shade_one`]: what one path does at one vertex, phase
//! by phase as in Mitsuba's `path.cpp` (absorption, emission, next-event estimation, the
//! connection to a light vertex, the merge of light vertices behind a delta vertex, BSDF
//! sampling, Russian roulette). The stage's loop over the batch is in [`super::shade`].

use super::batch::{CausticState, NO_HIT, ShadowSlots};
use super::light_vertices::{self, CameraVertex};
use super::medium::{material_absorption, transmittance};
use super::merging;
use super::mis::{
    camera_vertex_factor, emission_weight, environment_weight, merge_vertex_factor,
    path_tracer_weight,
};
use super::next_event::{
    self, Media, NextEvent, SHADOW_RAY_SHORTENING, ShadingPoint, sample_lights_front,
    sample_lights_through,
};
use super::params::ShadeParams;
use super::surface;
use crate::bsdf::{Bsdf, BsdfSample};
use crate::geometry::SurfacePoint;
use crate::lights::Environment;
use crate::math::frame::Frame;
use crate::math::rng::dim;
use crate::math::{Rgb, Vec2, Vec3A, max_component, offset_ray_origin};
use crate::ray_cone::RayCone;
use crate::render_scene::{NO_EMITTER, RenderScene};

/// Russian roulette never keeps a path with probability above this, so that paths through
/// lossless materials (glass, white mirrors) still end.
const MAX_SURVIVAL: f32 = 0.95;

/// The ray and what it hit.
pub(super) struct Hit {
    pub(super) origin: Vec3A,
    pub(super) direction: Vec3A,
    pub(super) t: f32,
    pub(super) slot: u32,
    pub(super) barycentric: Vec2,
}

/// One path's mutable state.
pub(super) struct PathView<'a> {
    pub(super) throughput: &'a mut Rgb,
    pub(super) radiance: &'a mut Rgb,
    pub(super) count_emission: &'a mut bool,
    pub(super) bsdf_pdf: &'a mut f32,
    pub(super) alive: &'a mut bool,
    pub(super) radiance_scale: &'a mut f32,
    pub(super) medium: &'a mut Rgb,
    pub(super) caustic: &'a mut CausticState,
    pub(super) cone: &'a mut RayCone,
    pub(super) next_origin: &'a mut Vec3A,
    pub(super) next_direction: &'a mut Vec3A,
}

/// Shades one hit. Returns whether the path was cut by the depth cap. Without `THROUGH`
/// (scenes where nothing transmits or absorbs) the path's medium stays zero and every hit
/// takes the front-side light estimator.
#[inline(always)]
pub(super) fn shade_one<const THROUGH: bool>(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    hit: Hit,
    path: &mut PathView,
    mut next_event: NextEvent,
) -> bool {
    next_event.shadow.clear();
    *path.alive = false;
    if hit.slot == NO_HIT {
        if let Some(environment) = scene.lights.environment() {
            escaped(scene, environment, params, &hit, path);
        }
        return false; // without an environment the background is black
    }
    let slot = hit.slot as usize;
    let bounce = params.bounce;

    // --- Absorption: Beer-Lambert along the segment that reached the hit.
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
            let weight = match (*path.count_emission, *path.caustic) {
                // A caustic path (camera or non-delta vertex, non-delta x1, delta bounces,
                // light) that the light paths find too is weighted against them.
                (true, CausticState::Caustic { factor }) if factor > 0.0 => {
                    path_tracer_weight(light, factor)
                }
                (true, _) => 1.0,
                (false, _) => {
                    let cos_light = ng.dot(wo).abs();
                    let (pdf, rays) = (*path.bsdf_pdf, params.shadow_rays);
                    emission_weight(pdf, rays, light.pdf_area, hit.t, cos_light)
                }
            };
            *path.radiance += *path.throughput * emitted * weight;
        }
    }

    // --- Material: textures applied; a surface that reflects nothing ends the path.
    let material = scene.material_of(slot) as usize;
    let width = path.cone.width_at(hit.t);
    // Borrowed from the scene where nothing varies it over the surface (the common case).
    let textured;
    let (bsdf, ns) = match surface::uniform_material(scene, material) {
        Some(bsdf) => (bsdf, ns),
        None => {
            let b = hit.barycentric;
            textured =
                surface::textured_surface_in_cone(scene, material, slot, b, ng, ns, wo, width);
            (&textured.0, textured.1)
        }
    };
    if bsdf.is_black() {
        if let Bsdf::Unlit { color } = *bsdf {
            // KHR_materials_unlit shows its colour to whatever ray hits it, in full (it is
            // no light: no shadow ray could have found it).
            *path.radiance += *path.throughput * color;
        }
        return false; // e.g. a light source: it reflects nothing
    }
    let frame = Frame::from_normal(ns);
    let wo_local = frame.to_local(wo);
    // The medium behind the surface: the object's when the path arrived from outside.
    let medium_behind = |front: bool| {
        if front {
            material_absorption(scene, material)
        } else {
            Rgb::ZERO
        }
    };

    // The shading point, for next-event estimation and the caustic connection. Made in
    // each branch: one made before the branches would be stored to memory for the
    // out-of-line call, at every hit.
    let front_origin = next_event::front_origin(p, p_error, ng, front);
    let at = || ShadingPoint {
        p,
        p_error,
        ng,
        front,
        front_origin,
        frame,
        bsdf,
        wo_local,
    };

    // --- Next-event estimation: shadow rays toward lights chosen by power.
    if params.shadow_rays > 0 && !bsdf.is_delta() && !scene.lights.is_empty() {
        let throughput = *path.throughput;
        let next_event = next_event.reborrow();
        // The per-hit choice of the estimator: a surface that cannot transmit, reached outside
        // any medium, takes the front-side one, which pays nothing for transmission and
        // media; the others the general one.
        if THROUGH && (bsdf.transmits() || *path.medium != Rgb::ZERO) {
            // Shadow rays on the path's side travel in its medium; through the surface, in
            // the object's (entering) or outside (leaving).
            let media = Media {
                front: *path.medium,
                back: medium_behind(front),
            };
            sample_lights_through(scene, params, key, &at(), media, throughput, next_event);
        } else {
            sample_lights_front(scene, params, key, &at(), throughput, next_event);
        }
    }

    // --- Caustic connection: one more shadow ray, to one of the pass's light vertices.
    if let Some(caustics) = &params.caustics
        && caustics.connections
        && !caustics.light_vertices.is_empty()
        && !bsdf.is_delta()
    {
        let media = Media {
            front: *path.medium,
            back: medium_behind(front),
        };
        let throughput = *path.throughput;
        let shadow = &mut next_event.shadow;
        let (key, at) = ((key, bounce), at());
        connect_light_vertex::<THROUGH>(scene, params, key, &at, throughput, media, shadow);
    }

    // --- Caustic merge: at a point reached through a delta bounce (the camera's first hit
    // excepted), the pass's light vertices nearby. With light paths MIS is on, so a zero
    // `bsdf_pdf` after the first hit means the last bounce was delta.
    if let Some(caustics) = &params.caustics
        && let Some(grid) = caustics.merge_grid
        && bounce > 0
        && *path.bsdf_pdf == 0.0
        && !bsdf.is_delta()
    {
        let at = camera_vertex(&at(), *path.throughput, bounce);
        let pass = (grid, caustics.light_vertices, caustics.light_path_count);
        *path.radiance += merging::merge(scene, pass, &at, params.max_depth);
    }

    // --- BSDF sampling for the next ray.
    let Some(sample) = bsdf.sample_drawing(
        wo_local,
        || params.sampler.uniform(key, bounce, dim::BSDF_LOBE),
        || params.sampler.uniform2(key, bounce, dim::BSDF_DIRECTION),
    ) else {
        return false;
    };
    let wi = frame.to_world(sample.wi);
    let transmitted = sample.wi.z * wo_local.z < 0.0;
    if ((ng.dot(wi) > 0.0) == front) == transmitted {
        return false; // the shading normal sent the ray through the wrong side of the surface
    }
    let cos_ng = [ng.dot(wi), ng.dot(wo)];
    *path.caustic = caustic_state_after(params, bounce, path, &sample, &hit, cos_ng);
    *path.throughput *= sample.weight;
    *path.cone = path.cone.after_bounce(hit.t, sample.is_delta, sample.pdf);
    if transmitted {
        *path.radiance_scale *= bsdf.radiance_compression(wo_local, sample.wi);
        // Into the object through its front side, out of it through its back side.
        if THROUGH {
            *path.medium = medium_behind(front);
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

    // --- Next ray, unless the depth cap cuts the path.
    if bounce + 1 >= params.max_depth {
        return true;
    }
    // A reflected ray leaves from the shadow rays' origin (the offset depends only on the
    // side of `ng` the ray leaves on).
    *path.next_origin = if (ng.dot(wi) < 0.0) != front {
        front_origin
    } else {
        offset_ray_origin(p, p_error, ng, wi)
    };
    *path.next_direction = wi;
    *path.alive = true;
    false
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
        environment_weight(
            *path.bsdf_pdf,
            params.shadow_rays,
            scene.lights.environment_probability() * environment.pdf(hit.direction),
        )
    } else {
        return; // light sampling only: the shadow rays counted it
    };
    *path.radiance += *path.throughput * environment.eval(hit.direction) * weight;
}

/// The connection of the camera vertex `at` (reached with `throughput` at `bounce`, its two
/// sides in `media`) to one of the pass's light vertices, picked with the path's own numbers
/// (`key`): caustics seen after this bounce ([`super::light_vertices`]). Writes one more
/// shadow ray into the path's slots, from the side it leaves: after the front rays of
/// next-event estimation, or before its back rays.
#[inline(always)]
fn connect_light_vertex<const THROUGH: bool>(
    scene: &RenderScene,
    params: &ShadeParams,
    (key, bounce): (u64, u32),
    at: &ShadingPoint<'_>,
    throughput: Rgb,
    media: Media,
    shadow: &mut ShadowSlots,
) {
    let Some(caustics) = &params.caustics else {
        return;
    };
    let slots = caustics.light_path_count;
    let pick = params.sampler.index(key, bounce, dim::LIGHT_VERTEX, slots) as usize;
    let camera_vertex = camera_vertex(at, throughput, bounce);
    let vertices = caustics.light_vertices;
    let Some(connection) =
        light_vertices::connect(scene, vertices, pick, &camera_vertex, params.max_depth)
    else {
        return;
    };
    let (origin, medium) = if !connection.through {
        shadow.set_front_origin(at.front_origin);
        (at.front_origin, media.front)
    } else if THROUGH {
        let back_normal = if at.front { -at.ng } else { at.ng };
        let origin = offset_ray_origin(at.p, at.p_error, at.ng, back_normal);
        shadow.set_back_origin(origin);
        (origin, media.back)
    } else {
        return; // nothing transmits in this scene
    };
    let to_vertex = connection.target - origin;
    let distance = to_vertex.length();
    let t_max = distance * (1.0 - SHADOW_RAY_SHORTENING);
    let contribution = if THROUGH && medium != Rgb::ZERO {
        connection.contribution * transmittance(medium, t_max)
    } else {
        connection.contribution
    };
    let direction = to_vertex / distance;
    if connection.through {
        shadow.push_back(direction, t_max, contribution);
    } else {
        shadow.push_front(direction, t_max, contribution);
    }
}

/// The shading point `at`, reached with `throughput` at `bounce`, as a connection or a merge
/// needs it.
#[inline(always)]
fn camera_vertex<'a>(at: &ShadingPoint<'a>, throughput: Rgb, bounce: u32) -> CameraVertex<'a> {
    CameraVertex {
        p: at.p,
        ng: at.ng,
        front: at.front,
        frame: at.frame,
        bsdf: at.bsdf,
        wo_local: at.wo_local,
        throughput,
        bounce,
    }
}

/// The path's [`CausticState`] after this vertex's BSDF `sample` (unchanged without light
/// paths). A delta bounce lets a pending factor count. A non-delta vertex becomes the new
/// candidate for a light path's diffuse point `x1`, with the part of the MIS ratio the vertex
/// before it gives (with its strategy's count): the camera connects to the pass's `n` light
/// paths, a non-delta vertex to one light vertex (`path.bsdf_pdf`, still the density of that
/// vertex's sample, is 0 after a delta vertex or without MIS: then nothing connects to `x1`);
/// after a delta vertex the merge at `x1` itself shares the path ([`super::merging`]).
/// `cos_ng` are `ng . wi` and `ng . wo` at this vertex, reached by `hit` at `bounce`.
#[inline(always)]
fn caustic_state_after(
    params: &ShadeParams,
    bounce: u32,
    path: &PathView,
    sample: &BsdfSample,
    hit: &Hit,
    cos_ng: [f32; 2],
) -> CausticState {
    let Some(caustics) = &params.caustics else {
        return *path.caustic;
    };
    let [cos_x1, to_previous_cos] = cos_ng.map(f32::abs);
    let previous_pdf = *path.bsdf_pdf;
    if sample.is_delta {
        path.caustic.after_delta_bounce()
    } else if bounce == 0 {
        let camera_density = caustics.camera.direction_density(hit.direction);
        let factor =
            camera_vertex_factor(cos_x1, sample.pdf, to_previous_cos, hit.t, camera_density);
        CausticState::Pending {
            factor: caustics.light_path_count as f32 * factor,
        }
    } else if caustics.connections && previous_pdf > 0.0 {
        let factor = camera_vertex_factor(cos_x1, sample.pdf, to_previous_cos, hit.t, previous_pdf);
        CausticState::Pending { factor }
    } else if let Some(grid) = caustics.merge_grid
        && previous_pdf == 0.0
    {
        // Reached through a delta bounce: the merge at this vertex shares the caustic.
        let (paths, radius) = (caustics.light_path_count as f32, grid.radius());
        let factor = merge_vertex_factor(paths, radius, cos_x1, sample.pdf);
        CausticState::Pending { factor }
    } else {
        CausticState::None
    }
}
