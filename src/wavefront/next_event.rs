//! Next-event estimation at one hit: shadow rays toward points on lights chosen by power
//! (points on area lights uniform by area; punctual lights have one point), each weighted by
//! the BSDF, the cosine and, with MIS, the power heuristic against the BSDF sample that could
//! have found the same point. The shadow stage then adds the unoccluded contributions.
//!
//! The light samples of a hit's shadow rays are the points of one rank-1 lattice, shifted per
//! path, four lanes to a group, and shaded four lanes at a time.

use super::batch::ShadowSlots;
use super::medium::transmittance;
use super::mis::power_heuristic;
use super::params::ShadeParams;
use super::surface;
use crate::bsdf::Bsdf;
use crate::lights::{LIGHT_LANES, LightSamples, LightUniforms};
use crate::math::frame::Frame;
use crate::math::rng::dim;
use crate::math::sampling::Rank1Lattice;
use crate::math::{Rgb, Vec2, Vec3A, Vec4, offset_ray_origin, transpose4};
use crate::render_scene::RenderScene;

/// Groups of light samples taken before any of them is shaded (see [`sample_lights`]).
pub(super) const GROUPS_PER_PASS: usize = 4;
/// Shadow rays stop this fraction short of the light point, so the light itself never occludes.
pub(super) const SHADOW_RAY_SHORTENING: f32 = 1e-4;

/// What next-event estimation at one hit works with: the lattice of the shadow rays' light
/// samples (one group per four rays) and the path's chunk of the shadow batch.
pub(super) struct NextEvent<'a> {
    pub(super) lattice: &'a [LightUniforms],
    pub(super) samples: &'a mut [LightSamples; GROUPS_PER_PASS],
    pub(super) shadow: ShadowSlots<'a>,
}

impl NextEvent<'_> {
    /// The same view, borrowed again (so that the shade stage can still add a ray after
    /// next-event estimation has written its own).
    #[inline(always)]
    pub(super) fn reborrow(&mut self) -> NextEvent<'_> {
        NextEvent {
            lattice: self.lattice,
            samples: self.samples,
            shadow: self.shadow.reborrow(),
        }
    }
}

/// The shading point as next-event estimation needs it.
#[derive(Clone, Copy)]
pub(super) struct ShadingPoint<'a> {
    /// The hit point and the bound on its rounding error.
    pub(super) p: Vec3A,
    pub(super) p_error: Vec3A,
    /// Unit geometric normal, and whether the ray arrived on its side.
    pub(super) ng: Vec3A,
    pub(super) front: bool,
    /// The origin of rays that leave on the side the path came from ([`front_origin`]),
    /// shared by the shadow rays, the caustic connection and a reflected next ray.
    pub(super) front_origin: Vec3A,
    /// The shading frame, the material (textures applied) and the direction back along the
    /// ray in that frame.
    pub(super) frame: Frame,
    pub(super) bsdf: &'a Bsdf,
    pub(super) wo_local: Vec3A,
}

/// The point `p` (rounding error `p_error`) moved off its surface (geometric normal `ng`)
/// to the side a path arrived on (`front`: the side `ng` points to): the origin of every ray
/// that leaves on that side.
#[inline(always)]
pub(super) fn front_origin(p: Vec3A, p_error: Vec3A, ng: Vec3A, front: bool) -> Vec3A {
    let front_normal = if front { ng } else { -ng };
    offset_ray_origin(p, p_error, ng, front_normal)
}

/// Absorption of the media the shadow rays cross (`Rgb::ZERO`: none): on the path's side of
/// the surface (`front`), and through it (`back`). A ray that crosses a medium reaches a light
/// only inside it (the object's own surface blocks the rest), so the whole distance counts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Media {
    pub(super) front: Rgb,
    pub(super) back: Rgb,
}

impl Media {
    /// No medium on either side.
    pub(super) const NONE: Media = Media {
        front: Rgb::ZERO,
        back: Rgb::ZERO,
    };
}

/// The light-sample uniforms of `shadow_rays` shadow rays (a rank-1 lattice), four lanes to
/// a group (lanes past the last ray repeat it), written into `lattice`; each path shifts them
/// by its own random offset.
pub(super) fn shadow_ray_lattice(shadow_rays: u32, lattice: &mut Vec<LightUniforms>) {
    lattice.clear();
    if shadow_rays > 0 {
        let points = Rank1Lattice::new(shadow_rays);
        let last = shadow_rays - 1;
        let groups = (shadow_rays as usize).div_ceil(LIGHT_LANES);
        lattice.extend((0..groups).map(|g| {
            let point = |k: usize| points.point(((g * LIGHT_LANES + k) as u32).min(last));
            LightUniforms::from_lanes(std::array::from_fn(|k| {
                let [pick, u, v] = point(k);
                (pick, Vec2::new(u, v))
            }))
        }));
    }
}

/// Writes the shadow rays of the hit `at` on a path of weight `throughput` into its chunk
/// of the shadow batch (only rays with something to add), with their contributions: the
/// estimator of surfaces that cannot transmit, reached outside any medium (every hit of an
/// opaque scene). It does no work for lights behind the surface or for absorption; on such
/// surfaces it writes what [`sample_lights_through`] writes (tested below).
#[inline(always)]
pub(super) fn sample_lights_front(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    at: &ShadingPoint<'_>,
    throughput: Rgb,
    next_event: NextEvent,
) {
    sample_lights::<false>(scene, params, key, at, Media::NONE, throughput, next_event);
}

/// [`sample_lights_front`] for every surface: where the BSDF transmits, also shadow rays
/// toward lights behind the surface (from a second origin on its back side), and absorption
/// in `media` along every shadow ray. Out of line, so that the shade stage of opaque scenes
/// keeps the size (and the inlining) it had without it.
#[inline(never)]
pub(super) fn sample_lights_through(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    at: &ShadingPoint<'_>,
    media: Media,
    throughput: Rgb,
    next_event: NextEvent,
) {
    sample_lights::<true>(scene, params, key, at, media, throughput, next_event);
}

/// The two estimators' one body: `THROUGH` false compiles the work for lights behind the
/// surface and for media out.
#[inline(always)]
fn sample_lights<const THROUGH: bool>(
    scene: &RenderScene,
    params: &ShadeParams,
    key: u64,
    at: &ShadingPoint<'_>,
    media: Media,
    throughput: Rgb,
    next_event: NextEvent,
) {
    let NextEvent {
        lattice,
        samples,
        mut shadow,
    } = next_event;
    let ShadingPoint {
        p,
        p_error,
        ng,
        front,
        front_origin: origin,
        frame,
        bsdf,
        wo_local,
    } = *at;
    let absorbs = THROUGH && media != Media::NONE;
    let inv_n = 1.0 / params.shadow_rays as f32;
    // Shadow rays leave on the front side of the surface (the side the path came from), all
    // from one offset origin so that they are traced as a packet. Where the BSDF transmits,
    // rays toward lights behind the surface leave from a second origin on the back side
    // (without them, lights that BSDF sampling cannot hit, such as punctual ones, would be
    // lost behind rough glass); elsewhere lights behind are skipped below.
    let front_normal = if front { ng } else { -ng };
    shadow.set_front_origin(origin);
    let transmits = THROUGH && bsdf.transmits();
    if transmits {
        shadow.set_back_origin(offset_ray_origin(p, p_error, ng, -front_normal));
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
                for (k, (ray, colour)) in rays.into_iter().zip(colours).take(lanes).enumerate() {
                    let entry = if keep_front >> k & 1 == 1 {
                        count += 1;
                        ShadowSlots::front_entry(count - 1)
                    } else if keep_back >> k & 1 == 1 {
                        back_count += 1;
                        shadow.back_entry(back_count - 1)
                    } else {
                        continue;
                    };
                    let t_max = ray.w * (1.0 - SHADOW_RAY_SHORTENING);
                    shadow.write(entry, Vec3A::from_vec4(ray), t_max, colour.truncate());
                }
                continue;
            }
            // A shadow ray only where there is something to add, written without branches:
            // every lane is stored at the next free entry, which only a kept lane takes.
            let keep = (usable & lit).bitmask() & lane_mask;
            for (k, (ray, colour)) in rays.into_iter().zip(colours).take(lanes).enumerate() {
                let entry = ShadowSlots::front_entry(count);
                let t_max = ray.w * (1.0 - SHADOW_RAY_SHORTENING);
                shadow.write(entry, Vec3A::from_vec4(ray), t_max, colour.truncate());
                count += (keep >> k & 1) as usize;
            }
        }
    }
    shadow.set_counts(count, back_count);
    // Absorption in media, after the loop so that surfaces outside media do no work in it.
    // Over the shortened length: 1e-4 of the distance changes the transmittance by nothing
    // measurable.
    if absorbs {
        let (front_entries, back_entries) = shadow.entries();
        for (entry, medium) in front_entries
            .map(|e| (e, media.front))
            .chain(back_entries.map(|e| (e, media.back)))
        {
            let kept = transmittance(medium, shadow.t_max(entry));
            shadow.scale_contribution(entry, kept);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{Layered, MetallicRoughness};
    use crate::math::rng::{Sampler, path_key, uniform};
    use crate::render_scene::RenderScene;
    use crate::wavefront::batch::ShadowBatch;

    /// The shadow rays one estimator writes: the count, the origin, the back side's count,
    /// and the kept entries.
    type Written = (u32, Vec3A, u32, Vec<(Vec3A, f32, Rgb)>);

    fn written(
        through: bool,
        scene: &RenderScene,
        params: &ShadeParams,
        key: u64,
        at: &ShadingPoint<'_>,
    ) -> Written {
        let mut shadows = ShadowBatch {
            per_path: params.shadow_rays as usize,
            ..Default::default()
        };
        shadows.grow_to(1);
        shadow_ray_lattice(params.shadow_rays, &mut shadows.lattice);
        let mut samples = [LightSamples::default(); GROUPS_PER_PASS];
        let (lattice, shadow) = shadows.lattice_and_slots(0);
        let next_event = NextEvent {
            lattice,
            samples: &mut samples,
            shadow,
        };
        let throughput = Rgb::new(0.9, 0.7, 0.5);
        if through {
            sample_lights_through(scene, params, key, at, Media::NONE, throughput, next_event);
        } else {
            sample_lights_front(scene, params, key, at, throughput, next_event);
        }
        let entries = shadows
            .front_entries(0)
            .map(|e| {
                (
                    shadows.direction[e],
                    shadows.t_max[e],
                    shadows.contribution[e],
                )
            })
            .collect();
        (
            shadows.count[0],
            shadows.origin[0],
            shadows.back_count[0],
            entries,
        )
    }

    /// On surfaces that cannot transmit, outside media, the front-side estimator (the fast
    /// path of opaque scenes) writes exactly what the general one writes, bit for bit: the
    /// same shadow rays, none from the back side. Random points in the room, both sides of
    /// random surfaces, shading normals tilted off the geometric ones, every opaque model,
    /// shadow-ray counts that fill the last group of four or not, with and without MIS.
    #[test]
    fn the_front_side_estimator_is_the_general_one_on_opaque_surfaces() {
        let scene = crate::wavefront::tests::room();
        let base = MetallicRoughness::new(Rgb::new(0.9, 0.6, 0.3), 0.0, 0.4);
        let bsdfs = [
            Bsdf::Lambertian {
                albedo: Rgb::new(0.8, 0.5, 0.2),
            },
            Bsdf::metallic_roughness(base),
            Bsdf::metallic_roughness(MetallicRoughness::new(Rgb::ONE, 1.0, 0.2)),
            Bsdf::layered(Layered {
                base,
                clearcoat: 0.7,
                clearcoat_alpha: 0.05,
                sheen_color: Rgb::new(0.4, 0.3, 0.2),
                sheen_roughness: 0.5,
                coat_normal: None,
            }),
        ];
        let mut rays_kept = 0;
        for (b, bsdf) in bsdfs.iter().enumerate() {
            assert!(!bsdf.transmits());
            for (shadow_rays, mis) in [(1, true), (4, false), (7, true), (16, true)] {
                let params = ShadeParams {
                    bounce: 1,
                    shadow_rays,
                    mis,
                    roulette_min_bounces: 3,
                    max_depth: 8,
                    sampler: Sampler::Independent,
                    caustics: None,
                };
                for i in 0..300 {
                    let u = |d: u32| uniform(path_key(31, i, b as u32), 0, d);
                    let unit = |d: u32| {
                        (Vec3A::new(u(d), u(d + 1), u(d + 2)) * 2.0 - 1.0).normalize_or(Vec3A::Z)
                    };
                    let p = Vec3A::new(10.0 * u(0), 10.0 * u(1) - 5.0, 9.0 * u(2) - 4.5);
                    let ng = unit(3);
                    let ns = (ng + 0.3 * unit(6)).normalize_or(ng);
                    let wo = unit(9);
                    let frame = Frame::from_normal(ns);
                    let (p_error, front) = (Vec3A::splat(1e-6), ng.dot(wo) > 0.0);
                    let at = ShadingPoint {
                        p,
                        p_error,
                        ng,
                        front,
                        front_origin: front_origin(p, p_error, ng, front),
                        frame,
                        bsdf,
                        wo_local: frame.to_local(wo),
                    };
                    let key = path_key(37, i, b as u32);
                    let fast = written(false, &scene, &params, key, &at);
                    let general = written(true, &scene, &params, key, &at);
                    assert_eq!(fast, general, "{bsdf:?} at {p}, {shadow_rays} rays");
                    assert_eq!(general.2, 0, "no ray from the back of an opaque surface");
                    rays_kept += fast.0;
                }
            }
        }
        // Enough of the cases keep rays for the comparison to mean something.
        assert!(rays_kept > 2000, "{rays_kept}");
    }
}
