//! Next-event estimation at one hit: shadow rays toward points on lights chosen by power
//! (points on area lights uniform by area; punctual lights have one point), each weighted by
//! the BSDF, the cosine and, with MIS, the power heuristic against the BSDF sample that could
//! have found the same point. The shadow stage then adds the unoccluded contributions.
//!
//! The light samples of a hit's shadow rays are the points of one rank-1 lattice, shifted per
//! path, four lanes to a group, and shaded four lanes at a time.

use super::shade::{ShadeParams, transmittance};
use super::surface;
use crate::bsdf::Bsdf;
use crate::lights::{LIGHT_LANES, LightSamples, LightUniforms};
use crate::math::frame::Frame;
use crate::math::rng::dim;
use crate::math::sampling::Rank1Lattice;
use crate::math::{Rgb, Vec2, Vec3A, Vec4, offset_ray_origin, transpose4};
use crate::render_scene::RenderScene;
use crate::settings::MAX_SHADOW_RAYS;

/// Groups of light samples taken before any of them is shaded (see [`sample_lights`]).
pub(super) const GROUPS_PER_PASS: usize = 4;
/// Groups of four shadow rays a hit takes at most.
pub(super) const MAX_SHADOW_GROUPS: usize = (MAX_SHADOW_RAYS as usize).div_ceil(LIGHT_LANES);
/// Shadow rays stop this fraction short of the light point, so the light itself never occludes.
const SHADOW_RAY_SHORTENING: f32 = 1e-4;

/// What next-event estimation at one hit works with: the lattice of the shadow rays' light
/// samples (one group per four rays) and the path's chunk of the shadow batch.
pub(super) struct NextEvent<'a> {
    pub(super) lattice: &'a [LightUniforms],
    pub(super) samples: &'a mut [LightSamples; GROUPS_PER_PASS],
    pub(super) shadow: ShadowView<'a>,
}

/// One path's chunk of the shadow batch.
pub(super) struct ShadowView<'a> {
    pub(super) count: &'a mut u32,
    pub(super) origin: &'a mut Vec3A,
    pub(super) back_count: &'a mut u32,
    pub(super) back_origin: &'a mut Vec3A,
    pub(super) direction: &'a mut [Vec3A],
    pub(super) t_max: &'a mut [f32],
    pub(super) contribution: &'a mut [Rgb],
}

/// The shading point as next-event estimation needs it.
#[derive(Clone, Copy)]
pub(super) struct ShadingPoint {
    /// The hit point and the bound on its rounding error.
    pub(super) p: Vec3A,
    pub(super) p_error: Vec3A,
    /// Unit geometric normal, and whether the ray arrived on its side.
    pub(super) ng: Vec3A,
    pub(super) front: bool,
    /// The shading frame, the material (textures applied) and the direction back along the
    /// ray in that frame.
    pub(super) frame: Frame,
    pub(super) bsdf: Bsdf,
    pub(super) wo_local: Vec3A,
    /// Absorption of the medium the shadow rays cross on the path's side of the surface,
    /// and through it (`Rgb::ZERO`: none). A ray that crosses a medium reaches a light only
    /// inside it (the object's own surface blocks the rest), so the whole distance counts.
    pub(super) front_medium: Rgb,
    pub(super) back_medium: Rgb,
}

/// The light-sample uniforms of `shadow_rays` shadow rays (a rank-1 lattice), four lanes to
/// a group (lanes past the last ray repeat it), written into the front of `lattice`; each path
/// shifts them by its own random offset.
pub(super) fn shadow_ray_lattice(
    shadow_rays: u32,
    lattice: &mut [LightUniforms; MAX_SHADOW_GROUPS],
) -> &[LightUniforms] {
    let lattice = &mut lattice[..(shadow_rays as usize).div_ceil(LIGHT_LANES)];
    if !lattice.is_empty() {
        let points = Rank1Lattice::new(shadow_rays);
        let last = shadow_rays - 1;
        for (g, group) in lattice.iter_mut().enumerate() {
            let point = |k: usize| points.point(((g * LIGHT_LANES + k) as u32).min(last));
            *group = LightUniforms::from_lanes(std::array::from_fn(|k| {
                let [pick, u, v] = point(k);
                (pick, Vec2::new(u, v))
            }));
        }
    }
    lattice
}

/// Writes the shadow rays of the hit `at` on a path of weight `throughput` into its chunk
/// of the shadow batch (only rays with something to add), with their contributions.
#[inline(always)]
pub(super) fn sample_lights(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    at: &ShadingPoint,
    throughput: Rgb,
    next_event: NextEvent,
) {
    let NextEvent {
        lattice,
        samples,
        shadow,
    } = next_event;
    let ShadingPoint {
        p,
        p_error,
        ng,
        front,
        frame,
        bsdf,
        wo_local,
        front_medium,
        back_medium,
    } = *at;
    let absorbs = front_medium != Rgb::ZERO || back_medium != Rgb::ZERO;
    let inv_n = 1.0 / params.shadow_rays as f32;
    // Shadow rays leave on the front side of the surface (the side the path came from), all
    // from one offset origin so that they are traced as a packet. Where the BSDF transmits,
    // rays toward lights behind the surface leave from a second origin on the back side
    // (without them, lights that BSDF sampling cannot hit, such as punctual ones, would be
    // lost behind rough glass); elsewhere lights behind are skipped below.
    let front_normal = if front { ng } else { -ng };
    let origin = offset_ray_origin(p, p_error, ng, front_normal);
    *shadow.origin = origin;
    let transmits = bsdf.transmits();
    if transmits {
        *shadow.back_origin = offset_ray_origin(p, p_error, ng, -front_normal);
    }
    let mut back_count = 0;
    // Behind every light (a ceiling above a ceiling light) all samples would be zero.
    let groups_needed = if scene.lights.all_behind(origin) {
        0
    } else {
        lattice.len()
    };
    // The lattice's shift for this path: one hash for all its shadow rays.
    let shift = params
        .sampler
        .uniform3(key, params.bounce, dim::LIGHT_SAMPLES);
    // The shading frame and the side the shadow rays leave from, one vector per
    // coordinate, for the lanes.
    let [s, t, n, side] =
        [frame.s, frame.t, frame.n, front_normal].map(|v| v.to_array().map(Vec4::splat));
    let throughput = throughput.to_array().map(Vec4::splat);
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
            let lane_mask = (1 << lanes) - 1;
            // Back to one vector per lane.
            let rays = transpose4([wi_x, wi_y, wi_z, samples.distance]);
            let [r, g, b] = contribution;
            let colours = transpose4([r, g, b, Vec4::ZERO]);
            if transmits {
                // Lights on either side. A ray counts where the shading frame agrees with the
                // geometry on whether it crosses the surface (as BSDF sampling requires).
                let crosses = (wi_local[2] * Vec4::splat(wo_local.z)).cmplt(Vec4::ZERO);
                let behind = dot(side).cmplt(Vec4::ZERO) & samples.scale.cmpgt(Vec4::ZERO);
                let keep_front = (usable & lit & !crosses).bitmask() & lane_mask;
                let keep_back = (behind & lit & crosses).bitmask() & lane_mask;
                let last = shadow.direction.len() - 1;
                for (k, (ray, colour)) in rays.into_iter().zip(colours).take(lanes).enumerate() {
                    let entry = if keep_front >> k & 1 == 1 {
                        count += 1;
                        count - 1
                    } else if keep_back >> k & 1 == 1 {
                        back_count += 1;
                        last + 1 - back_count
                    } else {
                        continue;
                    };
                    shadow.direction[entry] = Vec3A::from_vec4(ray);
                    shadow.t_max[entry] = ray.w * (1.0 - SHADOW_RAY_SHORTENING);
                    shadow.contribution[entry] = colour.truncate();
                }
                continue;
            }
            // A shadow ray only where there is something to add, written without branches:
            // every lane is stored at the next free entry, which only a kept lane takes.
            let keep = (usable & lit).bitmask() & lane_mask;
            for (k, (ray, colour)) in rays.into_iter().zip(colours).take(lanes).enumerate() {
                shadow.direction[count] = Vec3A::from_vec4(ray);
                shadow.t_max[count] = ray.w * (1.0 - SHADOW_RAY_SHORTENING);
                shadow.contribution[count] = colour.truncate();
                count += (keep >> k & 1) as usize;
            }
        }
    }
    *shadow.count = count as u32;
    *shadow.back_count = back_count as u32;
    // Absorption in media, after the loop so that surfaces outside media do no work in it.
    // Over the shortened length: 1e-4 of the distance changes the transmittance by nothing
    // measurable.
    if absorbs {
        let back = shadow.direction.len() - back_count;
        for (entry, medium) in (0..count)
            .map(|e| (e, front_medium))
            .chain((back..shadow.direction.len()).map(|e| (e, back_medium)))
        {
            shadow.contribution[entry] *= transmittance(medium, shadow.t_max[entry]);
        }
    }
}

/// The MIS weight of emission that a BSDF-sampled ray (solid-angle density `bsdf_pdf` at the
/// previous vertex) found at `distance`, where the surface's cosine toward that vertex is
/// `cos_light`, against the `shadow_rays` shadow rays that could have chosen the same point
/// (area density `light_pdf_area`).
#[inline(always)]
pub(super) fn emission_weight(
    bsdf_pdf: f32,
    shadow_rays: u32,
    light_pdf_area: f32,
    distance: f32,
    cos_light: f32,
) -> f32 {
    // The density with which the shadow rays would have chosen this point, per solid angle
    // at the previous vertex.
    let light_pdf_sa = light_pdf_area * distance * distance / cos_light;
    power_heuristic(
        Vec4::splat(bsdf_pdf),
        Vec4::splat(shadow_rays as f32 * light_pdf_sa),
    )
    .x
}

/// The MIS weight of the environment's radiance that a BSDF-sampled ray (solid-angle
/// density `bsdf_pdf`) found on leaving the scene, against the `shadow_rays` shadow rays
/// that could have chosen its direction (solid-angle density `light_pdf`, choice included).
#[inline]
pub(super) fn environment_weight(bsdf_pdf: f32, shadow_rays: u32, light_pdf: f32) -> f32 {
    power_heuristic(
        Vec4::splat(bsdf_pdf),
        Vec4::splat(shadow_rays as f32 * light_pdf),
    )
    .x
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
