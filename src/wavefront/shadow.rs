//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them. The rays of one path share their origin and head for the same
//! lights, so they are traced together as packets of up to [`PACKET_SIZE`] rays.

use super::batch::{PathState, ShadowBatch};
use crate::alpha::RayKey;
use crate::render_scene::{PACKET_SIZE, Packet, RenderScene, TraversalStack};

/// Traces the shadow rays (made at `bounce`) and accumulates visible contributions into the
/// paths' radiance. Returns the number of shadow rays traced.
pub fn trace_shadow_rays(
    scene: &RenderScene,
    shadows: &ShadowBatch,
    bounce: u32,
    paths: &mut PathState,
) -> u64 {
    let per = shadows.per_path;
    let mut traced = 0;
    let mut stack = TraversalStack::default();
    let PathState {
        radiance: path_radiance,
        rng_key,
        ..
    } = paths;
    for (i, radiance) in path_radiance.iter_mut().enumerate() {
        let count = shadows.count[i] as usize;
        let chunk = i * per..i * per + count;
        let (direction, t_max) = (
            &shadows.direction[chunk.clone()],
            &shadows.t_max[chunk.clone()],
        );
        let contribution = &shadows.contribution[chunk];
        for first in (0..count).step_by(PACKET_SIZE) {
            let rays = first..(first + PACKET_SIZE).min(count);
            let packet = Packet::new(
                shadows.origin[i],
                &direction[rays.clone()],
                &t_max[rays.clone()],
            );
            let key = RayKey {
                path: rng_key[i],
                bounce,
                ray: 1 + first as u32,
            };
            let occluded = scene.occluded_covered_packet(&mut stack, &packet, key);
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
        traced += count as u64;
    }
    traced
}
