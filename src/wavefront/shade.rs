//! Stage 3, shade: at each hit, add emission the path may count, make the next-event
//! estimation shadow rays ([`super::next_event`]) and the connection to a light vertex
//! ([`super::light_vertices`]), sample the BSDF for the next ray, and play Russian roulette.
//! This file is the stage's loop over the batch; the per-hit kernel, [`shade_one`], is in
//! [`super::shade_kernel`].

use super::batch::{HitBatch, PathState, RayBatch, ShadowBatch};
use super::next_event::{self, GROUPS_PER_PASS, NextEvent};
use super::params::ShadeParams;
use super::shade_kernel::{Hit, PathView, shade_one};
use crate::lights::LightSamples;
use crate::render_scene::RenderScene;

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
    if shadows.lattice_rays != params.shadow_rays {
        next_event::shadow_ray_lattice(params.shadow_rays, &mut shadows.lattice);
        shadows.lattice_rays = params.shadow_rays;
    }
    let mut samples = [LightSamples::default(); GROUPS_PER_PASS];
    let mut capped = 0;
    // Every column cut to the batch's length once, so that indexing them needs no bounds
    // check per path.
    let (origin, direction) = (&rays.origin[..n], &rays.direction[..n]);
    let (t, slot, barycentric) = (&hits.t[..n], &hits.slot[..n], &hits.barycentric[..n]);
    let (throughput, radiance) = (&mut paths.throughput[..n], &mut paths.radiance[..n]);
    let (count_emission, bsdf_pdf) = (&mut paths.count_emission[..n], &mut paths.bsdf_pdf[..n]);
    let (alive, radiance_scale) = (&mut paths.alive[..n], &mut paths.radiance_scale[..n]);
    let (medium, caustic, cone) = (
        &mut paths.medium[..n],
        &mut paths.caustic[..n],
        &mut paths.cone[..n],
    );
    let rng_key = &paths.rng_key[..n];
    let (next_origin, next_direction) = (&mut next_rays.origin[..n], &mut next_rays.direction[..n]);
    for i in 0..n {
        let hit = Hit {
            origin: origin[i],
            direction: direction[i],
            t: t[i],
            slot: slot[i],
            barycentric: barycentric[i],
        };
        let mut path = PathView {
            throughput: &mut throughput[i],
            radiance: &mut radiance[i],
            count_emission: &mut count_emission[i],
            bsdf_pdf: &mut bsdf_pdf[i],
            alive: &mut alive[i],
            radiance_scale: &mut radiance_scale[i],
            medium: &mut medium[i],
            caustic: &mut caustic[i],
            cone: &mut cone[i],
            next_origin: &mut next_origin[i],
            next_direction: &mut next_direction[i],
        };
        let (lattice, shadow) = shadows.lattice_and_slots(i);
        let next_event = NextEvent {
            lattice,
            samples: &mut samples,
            shadow,
        };
        capped += u64::from(shade_one::<THROUGH>(
            scene, &params, rng_key[i], hit, &mut path, next_event,
        ));
    }
    capped
}

#[cfg(test)]
mod tests {
    use crate::settings::RenderSettings;

    /// The shading path of opaque scenes (no work for transmission or media) renders the
    /// same image as the general path, bit for bit, on the hexagonal room (diffuse walls, a
    /// mirror and a smooth glass sphere, whose delta lobes need no shadow rays through them).
    #[test]
    fn the_opaque_scene_path_renders_what_the_general_path_renders() {
        let mut scene = crate::wavefront::tests::room();
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
