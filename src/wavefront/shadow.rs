//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them. The rays of one path share their origin and head for the same
//! lights, so they are traced together as packets of up to [`PACKET_SIZE`] rays.

use super::batch::{PathState, ShadowBatch};
use crate::flatten::FlatScene;
use crate::flatten::bvh::{PACKET_SIZE, Packet};
use crate::math::{Rgb, Vec3A};
use rayon::prelude::*;

/// Traces the shadow rays and accumulates visible contributions into the paths' radiance.
/// Returns the number of shadow rays traced.
pub fn trace_shadow_rays(scene: &FlatScene, shadows: &ShadowBatch, paths: &mut PathState) -> u64 {
    let (n, per) = (paths.len(), shadows.per_path);
    (
        &mut paths.radiance,
        &shadows.origin[..n],
        shadows.direction[..n * per].par_chunks(per),
        shadows.t_max[..n * per].par_chunks(per),
        shadows.contribution[..n * per].par_chunks(per),
    )
        .into_par_iter()
        .with_min_len(64)
        .map(|(radiance, &origin, direction, t_max, contribution)| {
            let mut traced = 0;
            let mut j = 0;
            while j < per {
                // Gather the next packet of used entries (unused ones have zero contribution).
                let mut index = [0usize; PACKET_SIZE];
                let mut packet_direction = [Vec3A::ZERO; PACKET_SIZE];
                let mut packet_t_max = [0.0f32; PACKET_SIZE];
                let mut n = 0;
                while j < per && n < PACKET_SIZE {
                    if contribution[j] != Rgb::ZERO {
                        (index[n], packet_direction[n], packet_t_max[n]) =
                            (j, direction[j], t_max[j]);
                        n += 1;
                    }
                    j += 1;
                }
                if n == 0 {
                    break;
                }
                traced += n as u64;
                let packet = Packet::new(origin, &packet_direction[..n], &packet_t_max[..n]);
                let occluded = scene.occluded_packet(&packet);
                for k in 0..n {
                    if occluded & (1 << k) == 0 {
                        *radiance += contribution[index[k]];
                    }
                }
            }
            traced
        })
        .sum()
}
