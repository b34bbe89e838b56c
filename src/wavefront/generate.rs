//! Stage 1, generate: camera rays for a range of pixels and one sample index.

use super::batch::{PathState, RayBatch};
use crate::camera::PinholeCamera;
use crate::math::Rgb;
use crate::math::rng::{self, dim};
use rayon::prelude::*;
use std::ops::Range;

/// Starts one path per pixel of `pixels` for sample `sample_index`: resets the path state and
/// writes the camera rays (box filter: the sample is uniform inside its pixel).
pub fn generate_camera_rays(
    camera: &PinholeCamera,
    seed: u64,
    pixels: Range<u32>,
    sample_index: u32,
    paths: &mut PathState,
    rays: &mut RayBatch,
) {
    let n = pixels.len();
    paths.resize(n);
    rays.resize(n);
    (
        &mut paths.pixel,
        &mut paths.rng_key,
        &mut paths.throughput,
        &mut paths.radiance,
        &mut paths.count_emission,
        &mut rays.origin,
        &mut rays.direction,
    )
        .into_par_iter()
        .enumerate()
        .with_min_len(1024)
        .for_each(
            |(i, (pixel, key, throughput, radiance, count_emission, origin, direction))| {
                *pixel = pixels.start + i as u32;
                *key = rng::path_key(seed, *pixel, sample_index);
                *throughput = Rgb::ONE;
                *radiance = Rgb::ZERO;
                *count_emission = true;
                (*origin, *direction) =
                    camera.generate_ray(*pixel, rng::uniform2(*key, 0, dim::PIXEL_JITTER));
                // flatten refused non-finite cameras, so every camera ray is valid
                debug_assert!(origin.is_finite() && direction.is_normalized());
            },
        );
}
