//! Render settings, passed explicitly from the CLI (or a test) to the renderer.

use crate::error::{Error, Result};
use crate::math::rng::{DEFAULT_SEED, Sampler};

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
/// Largest accepted number of pixels (the film needs 28 bytes per pixel).
pub const MAX_PIXELS: u64 = 1 << 27;
/// Most shadow rays per diffuse hit.
pub const MAX_SHADOW_RAYS: u32 = 1024;

/// How to render: everything the renderer needs besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples (paths) per pixel.
    pub spp: u32,
    /// Shadow rays per diffuse hit for next-event estimation. 0 turns next-event estimation
    /// off: emitters then count only when paths hit them (brute-force path tracing).
    pub shadow_rays: u32,
    /// Whether next-event estimation and BSDF sampling are combined by multiple importance
    /// sampling (power heuristic). Off, emitters reached by BSDF-sampled rays from non-delta
    /// vertices are discarded and only the shadow rays count them (light sampling only: the
    /// seed's estimator, bit for bit). Without shadow rays it has no effect.
    pub mis: bool,
    /// Seed of every random number.
    pub seed: u64,
    /// Independent random numbers, or Owen-scrambled Sobol points (stratified per pixel).
    pub sampler: Sampler,
    /// Paths traced together through the wavefront stages, one batch per thread at a time
    /// (fewer when many shadow rays per hit would make the shadow buffers large). Only speed
    /// and memory depend on it, never the image.
    pub batch_size: u32,
    /// Bounces before Russian roulette may end a path: 1 lets it play from the second hit
    /// on, as pbrt-v4 and Cycles do (the seed played it from the first).
    pub roulette_min_bounces: u32,
    /// Safety cap on path depth; paths cut there are counted in the statistics. It is high
    /// enough that Russian roulette practically always ends paths first.
    pub max_depth: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 800,
            height: 800,
            spp: 16,
            shadow_rays: 1,
            mis: true,
            seed: DEFAULT_SEED,
            sampler: Sampler::Independent,
            batch_size: 4096,
            roulette_min_bounces: 1,
            max_depth: 1024,
        }
    }
}

impl RenderSettings {
    /// Checks the settings before anything is allocated.
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Settings(m));
        if self.width == 0
            || self.height == 0
            || self.width > MAX_IMAGE_SIDE
            || self.height > MAX_IMAGE_SIDE
        {
            return bad(format!(
                "image size {}x{} is outside 1..={MAX_IMAGE_SIDE} per side",
                self.width, self.height
            ));
        }
        if self.pixel_count() > MAX_PIXELS {
            return bad(format!(
                "image size {}x{} exceeds the limit of {MAX_PIXELS} pixels",
                self.width, self.height
            ));
        }
        if self.spp == 0 {
            return bad("samples per pixel must be at least 1".into());
        }
        if self.shadow_rays > MAX_SHADOW_RAYS {
            return bad(format!(
                "{} shadow rays per hit is more than the limit of {MAX_SHADOW_RAYS}",
                self.shadow_rays
            ));
        }
        if self.batch_size == 0 {
            return bad("batch size must be at least 1".into());
        }
        if self.max_depth == 0 {
            return bad("maximum depth must be at least 1".into());
        }
        Ok(())
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }
}
