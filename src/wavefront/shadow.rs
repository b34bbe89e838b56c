//! Stage 4, shadow: occlusion of every shadow ray, adding the unoccluded contributions to
//! the paths that made them.

use super::batch::{PathState, ShadowBatch};
use crate::flatten::FlatScene;
use crate::math::Rgb;
use rayon::prelude::*;

/// Traces the shadow rays and accumulates visible contributions into the paths' radiance.
/// Returns the number of shadow rays traced.
pub fn trace_shadow_rays(scene: &FlatScene, shadows: &ShadowBatch, paths: &mut PathState) -> u64 {
    let per = shadows.per_path;
    (
        &mut paths.radiance,
        shadows.origin.par_chunks(per),
        shadows.direction.par_chunks(per),
        shadows.t_max.par_chunks(per),
        shadows.contribution.par_chunks(per),
    )
        .into_par_iter()
        .with_min_len(256)
        .map(|(radiance, origin, direction, t_max, contribution)| {
            let mut traced = 0;
            for j in 0..per {
                if contribution[j] == Rgb::ZERO {
                    continue; // unused entry
                }
                traced += 1;
                if !scene.occluded(origin[j], direction[j], t_max[j]) {
                    *radiance += contribution[j];
                }
            }
            traced
        })
        .sum()
}
