//! Stage 1, generate: camera rays for a range of pixels and one sample index.

use super::batch::{CausticState, PathState, RayBatch};
use crate::camera::PinholeCamera;
use crate::math::Rgb;
use crate::math::rng::{Sampler, dim};
use std::ops::Range;

/// Starts one path per pixel of `pixels` for sample `sample_index` (numbers from `sampler`): resets the path state and
/// writes the camera rays (each sample placed around its pixel by the camera's pixel filter). With
/// `active` (a flag per pixel of the film: adaptive sampling), only the active pixels.
#[allow(clippy::too_many_arguments)]
pub fn generate_camera_rays(
    camera: &PinholeCamera,
    seed: u64,
    sampler: Sampler,
    pixels: Range<u32>,
    active: Option<&[bool]>,
    sample_index: u32,
    paths: &mut PathState,
    rays: &mut RayBatch,
) {
    let is_active = |p: &u32| active.is_none_or(|a| a[*p as usize]);
    let n = pixels.clone().filter(is_active).count();
    let cone = camera.ray_cone();
    paths.resize(n);
    rays.resize(n);
    for (i, pixel) in pixels.filter(is_active).enumerate() {
        let key = sampler.path_key(seed, pixel, sample_index);
        paths.pixel[i] = pixel;
        paths.rng_key[i] = key;
        paths.throughput[i] = Rgb::ONE;
        paths.radiance[i] = Rgb::ZERO;
        paths.count_emission[i] = true;
        paths.radiance_scale[i] = 1.0;
        paths.medium[i] = Rgb::ZERO; // cameras are outside every object
        paths.caustic[i] = CausticState::None;
        paths.cone[i] = cone;
        let (origin, direction) =
            camera.generate_ray(pixel, sampler.uniform2(key, 0, dim::PIXEL_JITTER));
        // flatten refused non-finite cameras, so every camera ray is valid
        debug_assert!(origin.is_finite() && direction.is_normalized());
        (rays.origin[i], rays.direction[i]) = (origin, direction);
    }
}
