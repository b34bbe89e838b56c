//! The renderer: wavefront stages over batches of paths.
//!
//! Each pass takes one sample per pixel; pixels are cut into batches; each batch runs
//! generate -> (intersect -> shade -> shadow -> compact)* until no path is left. Every stage
//! is a plain sequential function over the structure-of-arrays buffers of [`batch`]; the
//! batches are traced in parallel, one per thread at a time. A thread's batch stays in its
//! own cache from stage to stage (the shadow rays shading writes are traced right after),
//! and the threads meet only between rounds of batches, not after every stage and bounce.
//!
//! With adaptive sampling ([`crate::settings::Adaptive`]) the pixels are grouped in tiles of
//! [`TILE`] x [`TILE`]; between passes, a tile whose pixels' error estimates are all below the
//! threshold stops for good, and later passes trace only the pixels of the tiles still going.
//! The decisions read only the film, after whole passes, so the image still does not depend
//! on threads or batches.

pub mod aov;
pub mod batch;
pub mod generate;
pub mod intersect;
mod light_paths;
mod light_vertices;
mod medium;
mod merging;
mod mis;
mod next_event;
pub mod params;
pub mod shade;
mod shade_kernel;
pub mod shadow;
pub mod stats;
mod surface;

use crate::camera::PinholeCamera;
use crate::error::Result;
use crate::film::{Film, FilmRegion};
use crate::math::Rgb;
use crate::render_scene::RenderScene;
use crate::settings::{Adaptive, RenderSettings};
use batch::{HitBatch, PathState, RayBatch, ShadowBatch, compact_paths};
use light_vertices::LightVertex;
use merging::LightVertexGrid;
use params::{CausticWeights, ShadeParams};
use rayon::prelude::*;
use stats::RenderStats;
use std::ops::{Deref, DerefMut, Range};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Reported after every round of batches; the callback decides whether to go on.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Paths (samples) finished so far.
    pub samples_done: u64,
    /// Paths in the whole render (with adaptive sampling: at most, if no more tiles stop).
    pub samples_total: u64,
    /// Whether this report ends a pass (every pixel still sampled has one more sample).
    pub pass_ended: bool,
}

/// What the progress callback wants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flow {
    /// Keep rendering.
    Continue,
    /// Stop at this round's end; the film keeps the samples finished so far.
    Stop,
}

/// The work buffers of one batch, reused by every bounce (and by later batches: see
/// [`BufferPool`]).
#[derive(Default)]
struct Buffers {
    paths: PathState,
    rays: RayBatch,
    next_rays: RayBatch,
    hits: HitBatch,
    shadows: ShadowBatch,
}

/// Bytes per pixel that writing the image takes beside the film: the resolved image (f32
/// RGB) and the encoder's copy (16-bit or f32 RGB) with its output buffer.
const OUTPUT_BYTES_PER_PIXEL: u64 = 32;

/// Refuses an image whose per-pixel memory would not fit in what the process can still
/// take (see [`crate::memory`]): the film, the light paths' splats and vertices, and the
/// output. The batches' buffers do not grow with the image.
fn check_image_memory(settings: &RenderSettings, caustics_traced: bool) -> Result<()> {
    let pixels = settings.pixel_count();
    let mut bytes =
        pixels * (Film::bytes_per_pixel(settings.adaptive.is_some()) + OUTPUT_BYTES_PER_PIXEL);
    if settings.record_aovs {
        // The layers' sums, and the resolved guides and denoised image beside the output.
        bytes += pixels * (Film::aov_bytes_per_pixel() + 3 * size_of::<Rgb>() as u64);
    }
    if caustics_traced {
        bytes += pixels * size_of::<Rgb>() as u64;
        bytes += light_paths::light_path_count(settings, pixels) * size_of::<LightVertex>() as u64;
    }
    let what = format!("a {}x{} image", settings.width, settings.height);
    let needed = crate::memory::Needed {
        resident: bytes,
        address_space: bytes,
    };
    match crate::memory::shortfall(&what, needed, crate::memory::available()) {
        Some(why) => Err(crate::Error::Settings(format!(
            "{why}; render a smaller image"
        ))),
        None => Ok(()),
    }
}

/// Renders `scene`, calling `progress` after each round of batches. Runs on the current
/// rayon pool.
pub fn render(
    scene: &RenderScene,
    settings: &RenderSettings,
    progress: impl FnMut(Progress) -> Flow,
) -> Result<(Film, RenderStats)> {
    render_rows(scene, settings, 0..settings.height, progress)
}

/// Renders only the pixel rows `rows` of the image (a part of a frame split for a render
/// farm, [`crate::farm`]): the film is the whole image's, and its pixels in `rows` hold
/// exactly what [`render`] puts there (bit for bit); the others hold no samples. The rows
/// start and end on adaptive sampling's tile rows ([`TILE`]) or at the image's bottom, so
/// that each tile is decided on pixels of one part only. Every part traces the whole pass's
/// light paths (their splats and vertices serve pixels anywhere in the image).
pub fn render_rows(
    scene: &RenderScene,
    settings: &RenderSettings,
    rows: Range<u32>,
    mut progress: impl FnMut(Progress) -> Flow,
) -> Result<(Film, RenderStats)> {
    settings.validate()?;
    if rows.is_empty()
        || rows.end > settings.height
        || !rows.start.is_multiple_of(TILE)
        || !(rows.end.is_multiple_of(TILE) || rows.end == settings.height)
    {
        return Err(crate::Error::Settings(format!(
            "rows {}..{} are not a run of whole {TILE}-pixel tile rows of a {}-row image",
            rows.start, rows.end, settings.height
        )));
    }
    let start = Instant::now();
    let camera = PinholeCamera::new(&scene.camera, settings.width, settings.height)
        .with_filter(settings.filter);
    let image_pixels = settings.width * settings.height;
    let part_pixels = rows.start * settings.width..rows.end * settings.width;
    let pixel_count = part_pixels.len() as u32;
    let caustics_traced = light_paths::caustics_traced(scene, settings);
    check_image_memory(settings, caustics_traced)?;
    let batch_size = paths_per_batch(settings, caustics_traced);
    let round_size = ROUND_PATHS.max(batch_size);
    let mut film = match settings.adaptive {
        Some(_) => Film::with_error_estimate(settings.width, settings.height),
        None => Film::new(settings.width, settings.height),
    };
    if settings.record_aovs {
        film = film.with_aovs();
    }
    let mut tiles = settings
        .adaptive
        .map(|a| ActiveTiles::new(settings.width, settings.height, a, rows.clone()));
    let mut stats = RenderStats::default();
    let mut samples_total = pixel_count as u64 * settings.spp as u64;
    let connections = caustics_traced && settings.caustic_connections;
    let spare_buffers = BufferPool {
        shadow_rays_per_path: shadow_slots_per_path(settings, connections) as usize,
        spare: Mutex::new(Vec::new()),
    };
    // The pass's light-path splats, one per pixel (empty without light paths), and its light
    // vertices (empty without connections).
    let mut splats: Vec<Rgb> = Vec::new();
    let mut light_vertices: Vec<LightVertex> = Vec::new();
    // Merging of light vertices behind delta vertices: the first pass's radius, measured
    // over the whole image (parts of a frame all find the same), and the pass's grid.
    let merge_radius = (caustics_traced && settings.caustic_merge_radius > 0.0)
        .then(|| {
            let size = (settings.width, settings.height);
            merging::base_radius(scene, &camera, size, settings.caustic_merge_radius)
        })
        .flatten();
    let mut merge_grid = LightVertexGrid::default();

    'passes: for sample_index in 0..settings.spp {
        let caustics = if caustics_traced {
            // As many light paths in every pass, however many tiles have stopped: the count
            // weights every pixel's caustics, so it may depend on nothing outside the pixel's
            // own tile, or a frame rendered in parts would not add up to the whole.
            let light_paths = light_paths::light_path_count(settings, image_pixels as u64);
            let start = Instant::now();
            stats.light_rays += light_paths::trace_light_paths(
                scene,
                settings,
                &camera,
                sample_index,
                light_paths,
                &mut splats,
                &mut light_vertices,
            );
            if let Some(base) = merge_radius {
                let radius = merging::pass_radius(base, sample_index);
                merge_grid.rebuild(&light_vertices, radius);
            }
            stats.light_time += start.elapsed();
            Some(CausticWeights {
                light_path_count: light_paths,
                camera,
                connections,
                light_vertices: &light_vertices,
                merge_grid: merge_radius.is_some().then_some(&merge_grid),
            })
        } else {
            None
        };
        let rounds = part_pixels.clone().step_by(round_size as usize);
        let last_round = rounds.len() - 1;
        for (round_number, first) in rounds.enumerate() {
            let batch = Batch {
                scene,
                camera: &camera,
                settings,
                sample_index,
                active: tiles.as_ref().map(|t| &t.pixel_active[..]),
                caustics,
                splats: &splats,
            };
            let pixels = first..(first + round_size).min(part_pixels.end);
            let round = film
                .regions_mut(pixels, batch_size as usize)
                .map_init(
                    || spare_buffers.lend(),
                    |buffers, mut region| batch.trace(&mut region, buffers),
                )
                .reduce(RenderStats::default, RenderStats::merged);
            stats = stats.merged(round);
            let pass_ended = round_number == last_round;
            if pass_ended && let Some(tiles) = &mut tiles {
                let passes_done = sample_index + 1;
                tiles.stop_converged(&film, passes_done);
                // What is left: the samples so far and the active pixels' remaining passes.
                samples_total =
                    stats.samples + tiles.active_pixels() * (settings.spp - passes_done) as u64;
            }
            if progress(Progress {
                samples_done: stats.samples,
                samples_total,
                pass_ended,
            }) == Flow::Stop
            {
                stats.interrupted = stats.samples < samples_total;
                break 'passes;
            }
        }
        if tiles.as_ref().is_some_and(|t| t.active_pixels() == 0) {
            break;
        }
    }
    film.rejected_samples = stats.rejected_samples;
    (stats.spp_min, stats.spp_mean, stats.spp_max) = film.spp_range(part_pixels);
    stats.complete_spp = match tiles {
        Some(_) => stats.spp_min,
        None => (stats.samples / pixel_count as u64) as u32,
    };
    stats.adaptive = settings.adaptive.is_some();
    stats.wall_time = start.elapsed();
    Ok((film, stats))
}

/// Side of adaptive sampling's tiles, in pixels: a tile's decision rests on 64 pixels' error
/// estimates (one pixel's, with few samples, is itself noisy), and stopping whole tiles
/// leaves no lone unconverged pixel among stopped ones.
pub const TILE: u32 = 8;

/// Adaptive sampling's state: which tiles still take samples.
struct ActiveTiles {
    width: u32,
    height: u32,
    adaptive: Adaptive,
    tiles_x: u32,
    tile_active: Vec<bool>,
    /// The same, per pixel, for the generate stage.
    pixel_active: Vec<bool>,
    active_pixels: u64,
}

impl ActiveTiles {
    /// Every tile of the pixel rows `rows` (whole tile rows) active, the others stopped.
    fn new(width: u32, height: u32, adaptive: Adaptive, rows: Range<u32>) -> Self {
        let tiles_x = width.div_ceil(TILE);
        let tiles_y = height.div_ceil(TILE);
        let tile_rows = rows.start / TILE..rows.end.div_ceil(TILE);
        let part_pixels = (rows.start * width) as usize..(rows.end * width) as usize;
        ActiveTiles {
            width,
            height,
            adaptive,
            tiles_x,
            tile_active: (0..tiles_x * tiles_y)
                .map(|tile| tile_rows.contains(&(tile / tiles_x)))
                .collect(),
            pixel_active: (0..(width * height) as usize)
                .map(|pixel| part_pixels.contains(&pixel))
                .collect(),
            active_pixels: part_pixels.len() as u64,
        }
    }

    fn active_pixels(&self) -> u64 {
        self.active_pixels
    }

    /// After `passes_done` whole passes: stops the tiles whose every pixel's error estimate is
    /// below the threshold. Judged at even pass counts from the minimum on, when both halves
    /// of every active pixel's samples are equal in number.
    fn stop_converged(&mut self, film: &Film, passes_done: u32) {
        if passes_done < self.adaptive.min_spp.max(2) || !passes_done.is_multiple_of(2) {
            return;
        }
        let threshold = self.adaptive.noise_threshold;
        let (width, height, tiles_x) = (self.width, self.height, self.tiles_x);
        for (tile, active) in self.tile_active.iter_mut().enumerate() {
            if !*active {
                continue;
            }
            let (tx, ty) = (tile as u32 % tiles_x, tile as u32 / tiles_x);
            let xs = tx * TILE..((tx + 1) * TILE).min(width);
            let ys = ty * TILE..((ty + 1) * TILE).min(height);
            let pixels = || {
                let xs = xs.clone();
                ys.clone()
                    .flat_map(move |y| xs.clone().map(move |x| (y * width + x) as usize))
            };
            // A denoised render: the tiles that see a light keep the undenoised threshold
            // for it; the others stop at the denoiser's cap too.
            let (limit, at_cap) = match self.adaptive.denoised {
                Some(rule) if pixels().any(|p| film.sees_light(p)) => (rule.light_threshold, false),
                Some(rule) => (threshold, passes_done >= rule.unlit_max_spp),
                None => (threshold, false),
            };
            if at_cap || pixels().all(|p| film.pixel_error(p) < limit) {
                *active = false;
                for p in pixels() {
                    self.pixel_active[p] = false;
                }
                self.active_pixels -= (xs.len() * ys.len()) as u64;
            }
        }
    }
}

/// Work buffers not in use, so that every job of every round reuses the buffers (and the
/// memory pages) of an earlier one: there are never more than the jobs running at once.
struct BufferPool {
    shadow_rays_per_path: usize,
    spare: Mutex<Vec<Buffers>>,
}

impl BufferPool {
    /// Spare buffers, or new ones; they return to the pool when the loan is dropped.
    fn lend(&self) -> BufferLoan<'_> {
        let spare = self
            .spare
            .lock()
            .expect("no panic while holding the lock")
            .pop();
        BufferLoan {
            buffers: spare.unwrap_or_else(|| Buffers {
                shadows: ShadowBatch {
                    per_path: self.shadow_rays_per_path,
                    ..Default::default()
                },
                ..Default::default()
            }),
            pool: self,
        }
    }
}

/// Buffers lent by a [`BufferPool`].
struct BufferLoan<'a> {
    buffers: Buffers,
    pool: &'a BufferPool,
}

impl Deref for BufferLoan<'_> {
    type Target = Buffers;
    fn deref(&self) -> &Buffers {
        &self.buffers
    }
}

impl DerefMut for BufferLoan<'_> {
    fn deref_mut(&mut self) -> &mut Buffers {
        &mut self.buffers
    }
}

impl Drop for BufferLoan<'_> {
    fn drop(&mut self) {
        let buffers = std::mem::take(&mut self.buffers);
        if let Ok(mut spare) = self.pool.spare.lock() {
            spare.push(buffers);
        }
    }
}

/// Paths traced between two progress reports (a round of batches traced in parallel): short
/// enough that Ctrl-C is answered within a fraction of a second.
const ROUND_PATHS: u32 = 1 << 18;

/// One batch of paths: one sample of each pixel of a film region.
struct Batch<'a> {
    scene: &'a RenderScene,
    camera: &'a PinholeCamera,
    settings: &'a RenderSettings,
    sample_index: u32,
    /// Adaptive sampling: which pixels take this sample.
    active: Option<&'a [bool]>,
    /// The pass's light paths for caustics, if any: how the path tracer weights the caustics
    /// it finds, and their splats, which each pixel's sample carries into the film.
    caustics: Option<CausticWeights<'a>>,
    splats: &'a [Rgb],
}

impl Batch<'_> {
    /// Runs generate -> (intersect -> shade -> shadow -> compact)* until no path is left;
    /// finished paths go to `film`. Returns the batch's counts and stage times.
    fn trace(&self, film: &mut FilmRegion, b: &mut Buffers) -> RenderStats {
        let settings = self.settings;
        let mut stats = RenderStats::default();
        // 1. generate: one camera ray per pixel of the batch
        timed(&mut stats.stage_time[0], || {
            generate::generate_camera_rays(
                self.camera,
                settings.seed,
                settings.sampler,
                film.pixels(),
                self.active,
                self.sample_index,
                &mut b.paths,
                &mut b.rays,
            )
        });
        stats.camera_rays = b.rays.len() as u64;
        stats.samples = b.rays.len() as u64;
        for bounce in 0.. {
            if b.paths.is_empty() {
                break;
            }
            if bounce > 0 {
                stats.bounce_rays += b.rays.len() as u64;
            }
            // 2. intersect: closest hit of every ray
            timed(&mut stats.stage_time[1], || {
                let keys = &b.paths.rng_key;
                intersect::intersect_closest(self.scene, &b.rays, keys, bounce, &mut b.hits)
            });
            if settings.record_aovs {
                aov::record_first_surfaces(self.scene, &b.rays, &b.hits, &mut b.paths, bounce);
            }
            // 3. shade: emission, shadow rays, next rays, Russian roulette
            let params = ShadeParams {
                bounce,
                shadow_rays: settings.shadow_rays,
                mis: settings.mis,
                roulette_min_bounces: settings.roulette_min_bounces,
                max_depth: settings.max_depth,
                sampler: settings.sampler,
                caustics: self.caustics,
            };
            stats.capped_paths += timed(&mut stats.stage_time[2], || {
                shade::shade_hits(
                    self.scene,
                    params,
                    &b.rays,
                    &b.hits,
                    &mut b.paths,
                    &mut b.next_rays,
                    &mut b.shadows,
                )
            });
            // 4. shadow: occlusion, then unoccluded light is added to its path
            stats.shadow_rays += timed(&mut stats.stage_time[3], || {
                shadow::trace_shadow_rays(self.scene, &b.shadows, bounce, &mut b.paths)
            });
            // finished paths go to the film; survivors continue with their next rays
            timed(&mut stats.stage_time[4], || {
                compact_paths(&mut b.paths, &mut b.next_rays, self.splats, film)
            });
            std::mem::swap(&mut b.rays, &mut b.next_rays);
        }
        stats.rejected_samples = film.rejected_samples;
        stats
    }
}

/// Most shadow-ray slots a batch holds (32 bytes each, 4 MiB in all): the default 4,096
/// paths with up to 32 shadow rays per hit, fewer paths with more.
const MAX_SHADOW_SLOTS: u32 = 1 << 17;

/// Shadow-ray slots per path: the shadow rays of next-event estimation, and one more for the
/// connection to a light vertex where camera vertices make one.
fn shadow_slots_per_path(settings: &RenderSettings, connections: bool) -> u32 {
    settings.shadow_rays.max(1) + u32::from(connections)
}

/// Paths per batch: the settings' batch size, cut to the image and to the shadow-ray budget,
/// so that memory stays bounded whatever the number of shadow rays (the image never depends
/// on the batch size).
fn paths_per_batch(settings: &RenderSettings, caustics_traced: bool) -> u32 {
    let connections = caustics_traced && settings.caustic_connections;
    settings
        .batch_size
        .min(settings.width * settings.height)
        .min((MAX_SHADOW_SLOTS / shadow_slots_per_path(settings, connections)).max(1))
}

/// Runs `f`, adding its duration to `total`.
fn timed<T>(total: &mut Duration, f: impl FnOnce() -> T) -> T {
    let t = Instant::now();
    let r = f();
    *total += t.elapsed();
    r
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The room of `scenes/room.toml` (one area light, walls on every side, a mirror and a
    /// glass sphere), for the stages' tests.
    pub(crate) fn room() -> RenderScene {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml");
        let scene = crate::scene::load::load_scene(&path).expect("the room loads");
        crate::flatten::flatten(&scene.world, &path).expect("the room flattens")
    }

    #[test]
    fn many_shadow_rays_shrink_the_batch_to_the_memory_budget() {
        let settings = |shadow_rays, width| RenderSettings {
            shadow_rays,
            width,
            height: width,
            ..RenderSettings::default()
        };
        // The seed's 15 shadow rays keep the full default batch; the image can cut it.
        assert_eq!(paths_per_batch(&settings(15, 800), false), 4096);
        assert_eq!(paths_per_batch(&settings(15, 50), false), 2500);
        // The most shadow rays: the shadow buffers stay within the budget.
        let most = settings(crate::settings::MAX_SHADOW_RAYS, 800);
        let paths = paths_per_batch(&most, true);
        assert!(
            paths >= 1 && paths * (most.shadow_rays + 1) <= MAX_SHADOW_SLOTS,
            "{paths}"
        );
    }
}
