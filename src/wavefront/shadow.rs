//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them. The rays of one path share their origin and head for the same
//! lights, so they are traced together as packets of up to [`PACKET_SIZE`] rays.

use super::batch::{PathState, ShadowBatch};
use crate::math::{Rgb, Vec3A};
use crate::render_scene::{PACKET_SIZE, Packet, RayKey, RenderScene, TraversalStack};

/// Traces the shadow rays (made at `bounce`) and accumulates visible contributions into the
/// paths' radiance. Returns the number of shadow rays traced.
pub fn trace_shadow_rays(
    scene: &RenderScene,
    shadows: &ShadowBatch,
    bounce: u32,
    paths: &mut PathState,
) -> u64 {
    // Chosen once per scene, as the shade stage chooses: where no material transmits, no
    // path has rays from a back side.
    if scene.transmits_or_absorbs {
        trace_all::<true>(scene, shadows, bounce, paths)
    } else {
        trace_all::<false>(scene, shadows, bounce, paths)
    }
}

/// [`trace_shadow_rays`] with the rays from back sides (`THROUGH`) or without.
#[inline(always)]
fn trace_all<const THROUGH: bool>(
    scene: &RenderScene,
    shadows: &ShadowBatch,
    bounce: u32,
    paths: &mut PathState,
) -> u64 {
    let mut traced = 0;
    let mut stack = TraversalStack::default();
    let PathState {
        radiance: path_radiance,
        rng_key,
        ..
    } = paths;
    for (i, radiance) in path_radiance.iter_mut().enumerate() {
        // The coverage test of alpha-tested primitives takes one number per ray: the ray's
        // place in the path's chunk (1-based; back-side rays count on past the front ones).
        let key = |first_ray: usize| RayKey {
            path: rng_key[i],
            bounce,
            ray: 1 + first_ray as u32,
        };
        let front = shadows.front_entries(i);
        traced += front.len() as u64;
        let origin = shadows.origin[i];
        trace_packets(scene, &mut stack, shadows, origin, front, key(0), radiance);
        // Rays through a transmitting surface, from its back side (none on opaque surfaces).
        if THROUGH {
            let back = shadows.back_entries(i);
            if !back.is_empty() {
                traced += back.len() as u64;
                let (origin, key) = (shadows.back_origin[i], key(shadows.per_path));
                trace_packets(scene, &mut stack, shadows, origin, back, key, radiance);
            }
        }
    }
    traced
}

/// Traces the rays `chunk` of the batch, all from `origin`, as packets, and adds the
/// contributions of the unoccluded ones to `radiance`. `key` numbers the chunk's first ray
/// for the coverage test; the others follow it.
#[inline(always)]
fn trace_packets(
    scene: &RenderScene,
    stack: &mut TraversalStack,
    shadows: &ShadowBatch,
    origin: Vec3A,
    chunk: std::ops::Range<usize>,
    key: RayKey,
    radiance: &mut Rgb,
) {
    let count = chunk.len();
    let (direction, t_max) = (
        &shadows.direction[chunk.clone()],
        &shadows.t_max[chunk.clone()],
    );
    let contribution = &shadows.contribution[chunk];
    for first in (0..count).step_by(PACKET_SIZE) {
        let rays = first..(first + PACKET_SIZE).min(count);
        let packet = Packet::new(origin, &direction[rays.clone()], &t_max[rays.clone()]);
        let key = RayKey {
            ray: key.ray + first as u32,
            ..key
        };
        let occluded = scene.occluded_covered_packet(stack, &packet, key);
        // Summed in a local, in the same order: adding into the path's entry in memory
        // made every addition wait for the store of the one before.
        let mut sum = *radiance;
        for (k, c) in contribution[rays].iter().enumerate() {
            if occluded & (1 << k) == 0 {
                sum += *c;
            }
        }
        *radiance = sum;
    }
}
