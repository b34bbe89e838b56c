//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them. The rays of one path share their origin and head for the same
//! lights, so they are traced together as packets of up to [`PACKET_SIZE`] rays.

use super::batch::{PathState, ShadowBatch};
use crate::flatten::FlatScene;
use crate::flatten::bvh::{PACKET_SIZE, Packet};
use rayon::prelude::*;

/// Traces the shadow rays and accumulates visible contributions into the paths' radiance.
/// Returns the number of shadow rays traced.
pub fn trace_shadow_rays(scene: &FlatScene, shadows: &ShadowBatch, paths: &mut PathState) -> u64 {
    let (n, per) = (paths.len(), shadows.per_path);
    (
        &mut paths.radiance,
        &shadows.count[..n],
        &shadows.origin[..n],
        shadows.direction[..n * per].par_chunks(per),
        shadows.t_max[..n * per].par_chunks(per),
        shadows.contribution[..n * per].par_chunks(per),
    )
        .into_par_iter()
        .with_min_len(64)
        .map(
            |(radiance, &count, &origin, direction, t_max, contribution)| {
                let count = count as usize;
                for first in (0..count).step_by(PACKET_SIZE) {
                    let rays = first..(first + PACKET_SIZE).min(count);
                    let packet =
                        Packet::new(origin, &direction[rays.clone()], &t_max[rays.clone()]);
                    let occluded = scene.occluded_packet(&packet);
                    for (k, c) in contribution[rays].iter().enumerate() {
                        if occluded & (1 << k) == 0 {
                            *radiance += *c;
                        }
                    }
                }
                count as u64
            },
        )
        .sum()
}
