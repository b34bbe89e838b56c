//! Render settings, passed explicitly from the CLI (or a test) to the renderer, and the one
//! place of their precedence: the caller's overrides (command-line flags) over the scene
//! file's `[render]` table ([`SceneDefaults`], which the scene loader fills) over the
//! defaults ([`RenderSettings::resolve`]). Settings import nothing from the loader.

use crate::error::{Error, Result};
use crate::filter::{FilterKind, PixelFilter};
use crate::math::rng::{DEFAULT_SEED, Sampler};

/// Largest accepted image side, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 32_768;
/// Largest accepted number of pixels (the film needs 28 bytes per pixel).
pub const MAX_PIXELS: u64 = 1 << 27;
/// Most shadow rays per diffuse hit.
pub const MAX_SHADOW_RAYS: u32 = 1024;

/// Render settings a scene file may state; `None` leaves the choice to the caller.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDefaults {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Shadow rays per diffuse hit.
    pub shadow_rays: Option<u32>,
    /// Where the random numbers come from (`sampler = "independent" | "sobol"`).
    pub sampler: Option<Sampler>,
    /// The pixel filter (`filter = "box" | "gaussian" | "blackman-harris"`).
    pub filter: Option<crate::filter::FilterKind>,
    /// The pixel filter's width in pixels (`filter_width = 1.5`).
    pub filter_width: Option<f32>,
}

impl SceneDefaults {
    /// Fields of `over` replace those of `self` where set.
    pub fn overridden_by(self, over: SceneDefaults) -> SceneDefaults {
        SceneDefaults {
            width: over.width.or(self.width),
            height: over.height.or(self.height),
            spp: over.spp.or(self.spp),
            shadow_rays: over.shadow_rays.or(self.shadow_rays),
            sampler: over.sampler.or(self.sampler),
            filter: over.filter.or(self.filter),
            filter_width: over.filter_width.or(self.filter_width),
        }
    }
}

/// Default noise threshold: a pixel's estimated error relative to the square root of its
/// brightness (Cycles' measure, see [`crate::film::Film::pixel_error`]). Five times Cycles'
/// 0.01, because a tile stops only when all its 64 pixels are below it (Cycles judges pixel
/// by pixel): in the room no tile reaches 0.02 or 0.01 by 8192 spp, while at 0.05 the first
/// tiles stop from about 2800 spp with a relative MSE of 0.0009 (docs/sampling.md).
pub const DEFAULT_NOISE_THRESHOLD: f32 = 0.05;
/// Samples every pixel takes before adaptive sampling may stop it, so that rare paths (a
/// caustic, a small light seen through glass) get a chance to show up in its error estimate.
pub const DEFAULT_MIN_SPP: u32 = 16;
/// Most samples per pixel of an adaptive render without a time budget.
pub const DEFAULT_MAX_SPP: u32 = 1024;
/// Noise threshold of a default render that is denoised: the denoiser removes the noise
/// left at this level, so the tiles stop far sooner (docs/denoising.md).
pub const DENOISED_NOISE_THRESHOLD: f32 = 0.25;
/// Most samples per pixel of a default render that is denoised: a tile that has not met the
/// threshold by then (caustics seen after a diffuse bounce) gains little from more samples
/// once denoised (docs/denoising.md).
pub const DENOISED_MAX_SPP: u32 = 64;
/// Most samples per pixel of a tile that sees a light (directly or through mirrors and glass)
/// in a default render that is denoised: that light is left out of the denoiser, so its
/// tiles keep the undenoised threshold, up to this (docs/denoising.md).
pub const DENOISED_LIGHT_MAX_SPP: u32 = 256;

/// Adaptive sampling: tiles of pixels stop taking samples once their error estimate is below
/// the threshold; the others go on, up to [`RenderSettings::spp`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    /// A tile stops when every pixel's relative error estimate is below this.
    pub noise_threshold: f32,
    /// Samples every pixel takes before its tile may stop.
    pub min_spp: u32,
    /// A render that is denoised: how its tiles stop (`None`: all by the rule above).
    pub denoised: Option<DenoisedStop>,
}

/// How the tiles of a denoised render stop. The denoiser takes the noise of every tile but the
/// light seen directly or through mirrors and glass (`film::Layer::Emission`), which it leaves
/// alone: a tile with such a pixel stops by `light_threshold` (up to the render's sample
/// count), the others by the adaptive threshold or at `unlit_max_spp`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DenoisedStop {
    /// The threshold of the tiles that see a light.
    pub light_threshold: f32,
    /// Most samples per pixel of the tiles that see none.
    pub unlit_max_spp: u32,
}

impl Default for Adaptive {
    fn default() -> Self {
        Adaptive {
            noise_threshold: DEFAULT_NOISE_THRESHOLD,
            min_spp: DEFAULT_MIN_SPP,
            denoised: None,
        }
    }
}

/// How to render: everything the renderer needs besides the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples (paths) per pixel; with adaptive sampling, the most any pixel takes.
    pub spp: u32,
    /// Adaptive sampling, or `None` for exactly `spp` samples in every pixel.
    pub adaptive: Option<Adaptive>,
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
    /// Light paths per pixel and pass for directly seen caustics (light -> mirror or glass
    /// -> diffuse surface -> camera), combined with the path tracer by multiple importance
    /// sampling (`wavefront::light_paths`); 0 turns them off. They run only in scenes with a
    /// delta surface and an area, point or spot light.
    pub caustic_paths: f32,
    /// Whether camera path vertices connect to the light paths' diffuse end points (caustics
    /// seen after a diffuse bounce, `wavefront::light_vertices`), when light paths run. On by
    /// default; the examples and tests turn it off to compare (no flag of the command line).
    pub caustic_connections: bool,
    /// The first pass's radius, in camera pixels, within which light vertices are merged at
    /// camera vertices reached through a mirror or smooth glass (caustics seen behind a delta
    /// vertex, `wavefront::merging`; the radius shrinks with the passes, so the image still
    /// converges to the path tracer's); 0 turns merging off. Merging runs when light paths do.
    pub caustic_merge_radius: f32,
    /// The pixel reconstruction filter, by filter importance sampling ([`crate::filter`]):
    /// where each camera sample falls around its pixel. The box of 1 px (each sample inside
    /// its pixel) by default; the command line gives model files Cycles' Blackman-Harris of
    /// 1.5 px.
    pub filter: PixelFilter,
    /// Whether each sample's auxiliary values (albedo and normal at the first non-specular
    /// hit, depth) are averaged into film layers, for the denoiser and `--aov`. They never
    /// change the colour.
    pub record_aovs: bool,
}

/// Default light paths per pixel and pass for caustics: a quarter. On the room 0.25, 1 and 4
/// give the same error per sample (the directly seen caustics are smooth from 0.25 on; what is
/// left is caustics seen through diffuse bounces), so the fewest rays win (docs/sampling.md,
/// section 7).
pub const DEFAULT_CAUSTIC_PATHS: f32 = 0.25;

/// Default merge radius of the first pass, in pixels (docs/sampling.md, section 8).
pub const DEFAULT_MERGE_RADIUS: f32 = 3.0;

/// Largest merge radius, in pixels.
pub const MAX_MERGE_RADIUS: f32 = 64.0;

/// Most light paths per pixel and pass.
pub const MAX_CAUSTIC_PATHS: f32 = 64.0;

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 800,
            height: 800,
            spp: 16,
            adaptive: None,
            shadow_rays: 1,
            mis: true,
            seed: DEFAULT_SEED,
            // Stratified: it resolves the lights' edges, which held most of the squared
            // error left once merging took the caustic fireflies (docs/sampling.md, section 8).
            sampler: Sampler::Sobol,
            batch_size: 4096,
            roulette_min_bounces: 1,
            max_depth: 1024,
            caustic_paths: DEFAULT_CAUSTIC_PATHS,
            caustic_connections: true,
            caustic_merge_radius: DEFAULT_MERGE_RADIUS,
            filter: PixelFilter::BOX,
            record_aovs: false,
        }
    }
}

/// What the caller (the command line, a test) sets; `None` leaves the choice to the scene file
/// and then to the defaults. The flags that scene files do not set are plain overrides too.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RenderOverrides {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Shadow rays per diffuse hit.
    pub shadow_rays: Option<u32>,
    /// Whether MIS combines light and BSDF samples.
    pub mis: Option<bool>,
    /// Seed of every random number.
    pub seed: Option<u64>,
    /// Paths per wavefront batch.
    pub batch_size: Option<u32>,
    /// Where the random numbers come from.
    pub sampler: Option<Sampler>,
    /// Adaptive sampling's threshold; 0 turns adaptive sampling off.
    pub noise_threshold: Option<f32>,
    /// Adaptive sampling's minimum samples per pixel.
    pub min_spp: Option<u32>,
    /// Light paths per pixel and pass for caustics; 0 turns them off.
    pub caustic_paths: Option<f32>,
    /// The first pass's merge radius in pixels; 0 turns merging off.
    pub merge_radius: Option<f32>,
    /// The pixel filter's shape.
    pub filter: Option<FilterKind>,
    /// The pixel filter's width in pixels.
    pub filter_width: Option<f32>,
}

impl RenderSettings {
    /// The settings of a render: each one from `overrides` if set, else from the scene file's
    /// `[render]` table (`scene`), else the default. The image size comes whole from one
    /// place: the overrides if they give a side, else the scene file. A missing side follows
    /// the camera's aspect ratio (`aspect`, width / height), else the scene file's image's,
    /// else the image is square, never the other side of the scene's size; with neither side
    /// given, the larger side is the default's.
    ///
    /// Sampling is adaptive unless a sample count is given (by a flag or the scene file) or the
    /// noise threshold is 0: a first render without options comes out clean, and `--spp N`
    /// keeps exactly N samples in every pixel. A sample count together with a noise threshold
    /// is adaptive up to that count.
    ///
    /// The pixel filter's shape comes from the overrides, else the scene, else the box; its
    /// width from the same level as the shape or a higher one, else the shape's default (so
    /// `--filter gaussian` over a scene's `filter = "box", filter_width = 2` is the Gaussian
    /// of its default 1.5 px).
    pub fn resolve(
        scene: &SceneDefaults,
        overrides: &RenderOverrides,
        aspect: Option<f32>,
    ) -> RenderSettings {
        let defaults = RenderSettings::default();
        let scene_aspect = match (scene.width, scene.height) {
            (Some(w), Some(h)) => Some(w as f32 / h as f32),
            _ => None,
        };
        let (width, height) = if overrides.width.is_some() || overrides.height.is_some() {
            image_size(
                overrides.width,
                overrides.height,
                aspect.or(scene_aspect),
                (defaults.width, defaults.height),
            )
        } else {
            image_size(
                scene.width,
                scene.height,
                aspect,
                (defaults.width, defaults.height),
            )
        };
        let fixed_spp = overrides.spp.or(scene.spp);
        let adaptive = match overrides.noise_threshold {
            Some(0.0) => None,
            None if fixed_spp.is_some() => None,
            threshold => Some(Adaptive {
                noise_threshold: threshold.unwrap_or(DEFAULT_NOISE_THRESHOLD),
                min_spp: overrides.min_spp.unwrap_or(DEFAULT_MIN_SPP),
                denoised: None,
            }),
        };
        let spp = match (fixed_spp, adaptive) {
            (Some(spp), _) => spp,
            (None, Some(_)) => DEFAULT_MAX_SPP,
            (None, None) => defaults.spp,
        };
        RenderSettings {
            width,
            height,
            spp,
            adaptive,
            shadow_rays: (overrides.shadow_rays)
                .or(scene.shadow_rays)
                .unwrap_or(defaults.shadow_rays),
            mis: overrides.mis.unwrap_or(defaults.mis),
            seed: overrides.seed.unwrap_or(defaults.seed),
            batch_size: overrides.batch_size.unwrap_or(defaults.batch_size),
            sampler: (overrides.sampler)
                .or(scene.sampler)
                .unwrap_or(defaults.sampler),
            caustic_paths: overrides.caustic_paths.unwrap_or(defaults.caustic_paths),
            caustic_merge_radius: (overrides.merge_radius).unwrap_or(defaults.caustic_merge_radius),
            filter: resolve_filter(scene, overrides),
            ..defaults
        }
    }

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
        if let Some(a) = self.adaptive {
            if !(a.noise_threshold.is_finite() && a.noise_threshold > 0.0) {
                return bad(format!(
                    "noise threshold must be a positive number, got {}",
                    a.noise_threshold
                ));
            }
            if a.min_spp == 0 {
                return bad("minimum samples per pixel must be at least 1".into());
            }
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
        if !(0.0..=MAX_CAUSTIC_PATHS).contains(&self.caustic_paths) {
            return bad(format!(
                "caustic light paths per pixel must lie in 0..={MAX_CAUSTIC_PATHS}, got {}",
                self.caustic_paths
            ));
        }
        if !(0.0..=MAX_MERGE_RADIUS).contains(&self.caustic_merge_radius) {
            return bad(format!(
                "the merge radius must lie in 0..={MAX_MERGE_RADIUS} pixels, got {}",
                self.caustic_merge_radius
            ));
        }
        if let Err(message) = PixelFilter::check_width(self.filter.width) {
            return bad(message);
        }
        Ok(())
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }
}

/// The pixel filter: the shape from the highest level that names one, the width from that
/// level or a higher one, else the shape's default width.
fn resolve_filter(scene: &SceneDefaults, overrides: &RenderOverrides) -> PixelFilter {
    let (kind, width) = match (overrides.filter, scene.filter) {
        (Some(kind), _) => (kind, overrides.filter_width),
        (None, Some(kind)) => (kind, overrides.filter_width.or(scene.filter_width)),
        (None, None) => (
            FilterKind::Box,
            overrides.filter_width.or(scene.filter_width),
        ),
    };
    PixelFilter {
        kind,
        width: width.unwrap_or(kind.default_width()),
    }
}

/// The image size: what is given; a missing side follows the aspect ratio (width / height)
/// when there is one, else the image is square; with neither side given the larger side is
/// the default's.
fn image_size(
    width: Option<u32>,
    height: Option<u32>,
    aspect: Option<f32>,
    default: (u32, u32),
) -> (u32, u32) {
    let aspect = aspect.filter(|a| a.is_finite() && *a > 0.0);
    let side = |x: f32| (x.round() as u32).max(1);
    match (width, height, aspect) {
        (Some(w), Some(h), _) => (w, h),
        (Some(w), None, Some(a)) => (w, side(w as f32 / a)),
        (None, Some(h), Some(a)) => (side(h as f32 * a), h),
        (None, None, Some(a)) if a >= 1.0 => (default.0, side(default.0 as f32 / a)),
        (None, None, Some(a)) => (side(default.1 as f32 * a), default.1),
        (Some(w), None, None) => (w, w),
        (None, Some(h), None) => (h, h),
        (None, None, None) => default,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(width: Option<u32>, spp: Option<u32>, shadow_rays: Option<u32>) -> SceneDefaults {
        SceneDefaults {
            width,
            height: width,
            spp,
            shadow_rays,
            ..SceneDefaults::default()
        }
    }

    #[test]
    fn overrides_beat_the_scene_which_beats_the_defaults() {
        let defaults = RenderSettings::default();
        let none = RenderOverrides::default();
        // Nothing set anywhere: the defaults, sampled adaptively up to the default maximum.
        assert_eq!(
            RenderSettings::resolve(&SceneDefaults::default(), &none, None),
            RenderSettings {
                spp: DEFAULT_MAX_SPP,
                adaptive: Some(Adaptive::default()),
                ..defaults
            }
        );
        // The scene's [render] table over the defaults.
        let room = scene(Some(300), Some(5), Some(7));
        let from_scene = RenderSettings::resolve(&room, &none, None);
        assert_eq!(
            (
                from_scene.width,
                from_scene.height,
                from_scene.spp,
                from_scene.shadow_rays
            ),
            (300, 300, 5, 7)
        );
        assert_eq!(from_scene.seed, defaults.seed);
        assert_eq!(
            from_scene.adaptive, None,
            "the scene's sample count is kept exactly"
        );
        // Flags over the scene, field by field: the unset ones still come from the scene.
        let flags = RenderOverrides {
            width: Some(64),
            height: Some(48),
            spp: Some(2),
            mis: Some(false),
            seed: Some(9),
            batch_size: Some(100),
            ..RenderOverrides::default()
        };
        let settings = RenderSettings::resolve(&room, &flags, None);
        assert_eq!(
            (
                settings.width,
                settings.height,
                settings.spp,
                settings.shadow_rays
            ),
            (64, 48, 2, 7)
        );
        assert_eq!(
            (settings.mis, settings.seed, settings.batch_size),
            (false, 9, 100)
        );
        assert_eq!(settings.max_depth, defaults.max_depth);
        assert_eq!(settings.adaptive, None, "--spp is kept exactly");
    }

    #[test]
    fn sampling_is_adaptive_without_a_sample_count_or_with_a_threshold() {
        let resolve = |spp, noise_threshold| {
            let flags = RenderOverrides {
                spp,
                noise_threshold,
                min_spp: Some(4),
                ..RenderOverrides::default()
            };
            let s = RenderSettings::resolve(&SceneDefaults::default(), &flags, None);
            (s.spp, s.adaptive.map(|a| (a.noise_threshold, a.min_spp)))
        };
        assert_eq!(resolve(None, None), (DEFAULT_MAX_SPP, Some((0.05, 4))));
        assert_eq!(resolve(Some(64), None), (64, None));
        assert_eq!(resolve(Some(64), Some(0.05)), (64, Some((0.05, 4))));
        assert_eq!(
            resolve(None, Some(0.0)),
            (RenderSettings::default().spp, None)
        );
        let bad = RenderSettings {
            adaptive: Some(Adaptive {
                noise_threshold: -1.0,
                min_spp: 1,
                denoised: None,
            }),
            ..RenderSettings::default()
        };
        assert!(bad.validate().is_err());
    }

    #[test]
    fn the_filter_comes_whole_from_the_highest_level_that_names_it() {
        let resolve = |scene: SceneDefaults, flags: RenderOverrides| {
            RenderSettings::resolve(&scene, &flags, None).filter
        };
        let none = RenderOverrides::default();
        assert_eq!(resolve(SceneDefaults::default(), none), PixelFilter::BOX);
        let scene = SceneDefaults {
            filter: Some(FilterKind::Box),
            filter_width: Some(2.0),
            ..SceneDefaults::default()
        };
        assert_eq!(resolve(scene, none).width, 2.0);
        let gaussian = RenderOverrides {
            filter: Some(FilterKind::Gaussian),
            ..RenderOverrides::default()
        };
        assert_eq!(
            resolve(scene, gaussian),
            PixelFilter {
                kind: FilterKind::Gaussian,
                width: 1.5
            }
        );
        let wide = RenderOverrides {
            filter_width: Some(3.0),
            ..RenderOverrides::default()
        };
        assert_eq!(resolve(scene, wide).width, 3.0);
        assert_eq!(
            resolve(SceneDefaults::default(), wide).kind,
            FilterKind::Box
        );
        for width in [0.0, -1.0, f32::NAN, 17.0] {
            let settings = RenderSettings {
                filter: PixelFilter {
                    kind: FilterKind::Gaussian,
                    width,
                },
                ..RenderSettings::default()
            };
            assert!(settings.validate().is_err(), "{width}");
        }
    }

    #[test]
    fn a_missing_side_follows_the_cameras_aspect_ratio() {
        let wide = Some(2.0);
        let only_width = RenderOverrides {
            width: Some(400),
            ..RenderOverrides::default()
        };
        let scene_none = SceneDefaults::default();
        let s = RenderSettings::resolve(&scene_none, &only_width, wide);
        assert_eq!((s.width, s.height), (400, 200));
        // Neither side: the larger one is the default's.
        let s = RenderSettings::resolve(&scene_none, &RenderOverrides::default(), wide);
        assert_eq!((s.width, s.height), (800, 400));
        let s = RenderSettings::resolve(&scene_none, &RenderOverrides::default(), Some(0.5));
        assert_eq!((s.width, s.height), (400, 800));
        // A flag's lone width never takes the other side from the scene file: it keeps the
        // camera's aspect ratio, else the scene's image's, else the image is square.
        let tall_scene = SceneDefaults {
            height: Some(100),
            ..SceneDefaults::default()
        };
        let s = RenderSettings::resolve(&tall_scene, &only_width, wide);
        assert_eq!((s.width, s.height), (400, 200));
        let s = RenderSettings::resolve(&tall_scene, &only_width, None);
        assert_eq!((s.width, s.height), (400, 400));
        let scene_4_by_3 = SceneDefaults {
            width: Some(800),
            height: Some(600),
            ..SceneDefaults::default()
        };
        let s = RenderSettings::resolve(&scene_4_by_3, &only_width, None);
        assert_eq!((s.width, s.height), (400, 300));
    }
}
