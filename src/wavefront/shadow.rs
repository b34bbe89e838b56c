//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them. The rays of one path share their origin and head for the same
//! lights, so they are traced together as packets of up to [`PACKET_SIZE`] rays.

use super::batch::{PathState, ShadowBatch};
use crate::math::Vec3A;
use crate::render_scene::{PACKET_SIZE, Packet, RenderScene, TraversalStack};

/// Traces the shadow rays and accumulates visible contributions into the paths' radiance.
/// Returns the number of shadow rays traced.
pub fn trace_shadow_rays(scene: &RenderScene, shadows: &ShadowBatch, paths: &mut PathState) -> u64 {
    let per = shadows.per_path;
    let mut traced = 0;
    let mut stack = TraversalStack::default();
    for (i, radiance) in paths.radiance.iter_mut().enumerate() {
        let count = shadows.count[i] as usize;
        let chunk = i * per..i * per + count;
        trace_packets(
            scene,
            &mut stack,
            shadows,
            shadows.origin[i],
            chunk,
            radiance,
        );
        traced += count as u64;
        // Rays through a transmitting surface, from its back side (none on opaque surfaces).
        let back = shadows.back_count[i] as usize;
        if back > 0 {
            let chunk = (i + 1) * per - back..(i + 1) * per;
            trace_packets(
                scene,
                &mut stack,
                shadows,
                shadows.back_origin[i],
                chunk,
                radiance,
            );
            traced += back as u64;
        }
    }
    traced
}

/// Traces the rays `chunk` of the batch, all from `origin`, as packets, and adds the
/// contributions of the unoccluded ones to `radiance`.
#[inline(always)]
fn trace_packets(
    scene: &RenderScene,
    stack: &mut TraversalStack,
    shadows: &ShadowBatch,
    origin: Vec3A,
    chunk: std::ops::Range<usize>,
    radiance: &mut crate::math::Rgb,
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
        let occluded = scene.occluded_packet(stack, &packet);
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
