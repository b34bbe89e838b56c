//! Equal-time (or equal-sample) error of a render against a reference EXR: renders the scene
//! at the reference's size for a time budget or a number of samples per pixel, once per seed,
//! and prints RMSE, MSE, relative MSE (mean of `(x - ref)^2 / (ref^2 + 0.01)` over pixels and
//! channels) and the share of the squared error in the worst 1% of pixels (see
//! `examples/common/image_error.rs`), then their means over the seeds and the MSE times the seconds
//! (inverse efficiency: lower is better, and equal for two renderers whose error falls as
//! 1/time alike).
//!
//! ```text
//! cargo run --release --features examples --example equal_time -- scenes/room.toml --reference ref.exr \
//!     (--spp 16 | --time 4s | both) [--seeds 4] [--seed S] [--sampler independent|sobol] \
//!     [--noise-threshold T [--min-spp N]] [--shadow-rays N] [--roulette-min-bounces N] \
//!     [--no-mis] [--caustic-paths N] [--no-caustic-connections] [--threads N] [--write out.exr]
//! ```
//!
//! With `--noise-threshold` the render is adaptive (8x8 tiles stop at that threshold; with
//! `--spp`, at most that many samples); the figures then give the mean samples per pixel.
//!
//! The reference should be a high-spp render of the same scene by the same renderer (same
//! reconstruction filter), with a seed none of the runs use. With several seeds, `--write`
//! writes the last one's image.

// The error measures, shared with `image_error` (each example uses part of them).
#[allow(dead_code)]
#[path = "common/image_error.rs"]
mod image_error;

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use image_error::{ImageError, image_error};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use wavetrace::math::rng::Sampler;
use wavetrace::output::read_exr;
use wavetrace::settings::{Adaptive, DEFAULT_MIN_SPP};
use wavetrace::{Flow, RenderSettings, flatten, load_scene, render, write_image};

#[derive(Clone, Copy, Debug, ValueEnum)]
enum SamplerArg {
    Independent,
    Sobol,
}

#[derive(Parser)]
struct Args {
    /// Scene file.
    scene: PathBuf,
    /// Reference image (linear EXR); the render takes its size.
    #[arg(long)]
    reference: PathBuf,
    /// Samples per pixel (with --time: at most this many).
    #[arg(long)]
    spp: Option<u32>,
    /// Time budget per render: whole passes (samples per pixel) while another one fits.
    #[arg(long, value_parser = humantime::parse_duration)]
    time: Option<Duration>,
    /// Renders, with seeds `seed`, `seed + 1`, ...
    #[arg(long, default_value_t = 1)]
    seeds: u64,
    /// First seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Random numbers.
    #[arg(long, value_enum, default_value_t = SamplerArg::Independent)]
    sampler: SamplerArg,
    /// Adaptive sampling with this noise threshold (default: fixed samples per pixel).
    #[arg(long)]
    noise_threshold: Option<f32>,
    /// Adaptive sampling's minimum samples per pixel.
    #[arg(long, default_value_t = DEFAULT_MIN_SPP)]
    min_spp: u32,
    /// Shadow rays per hit (default: the renderer's).
    #[arg(long)]
    shadow_rays: Option<u32>,
    /// Bounces before Russian roulette (default: the renderer's).
    #[arg(long)]
    roulette_min_bounces: Option<u32>,
    /// Light sampling only, no multiple importance sampling.
    #[arg(long)]
    no_mis: bool,
    /// Light paths per pixel and pass for caustics (default: the renderer's; 0: off).
    #[arg(long)]
    caustic_paths: Option<f32>,
    /// No connections of camera vertices to the light paths' diffuse points (caustics seen
    /// after a diffuse bounce); the light paths still make the caustics seen directly.
    #[arg(long)]
    no_caustic_connections: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Write the (last) render here.
    #[arg(long)]
    write: Option<PathBuf>,
}

fn main() -> anyhow::Result<()> {
    let args = Args::parse();
    if args.spp.is_none() && args.time.is_none() {
        bail!("give --spp, --time or both");
    }
    let reference = read_exr(&args.reference)?;
    let scene = load_scene(&args.scene)?;
    let flat = flatten(&scene.world, &args.scene)?;
    let defaults = RenderSettings::default();
    let base = RenderSettings {
        width: reference.width,
        height: reference.height,
        spp: args.spp.unwrap_or(u32::MAX),
        adaptive: args.noise_threshold.map(|noise_threshold| Adaptive {
            noise_threshold,
            min_spp: args.min_spp,
            denoised: None,
        }),
        shadow_rays: args.shadow_rays.unwrap_or(defaults.shadow_rays),
        mis: !args.no_mis,
        caustic_paths: args.caustic_paths.unwrap_or(defaults.caustic_paths),
        caustic_connections: !args.no_caustic_connections,
        sampler: match args.sampler {
            SamplerArg::Independent => Sampler::Independent,
            SamplerArg::Sobol => Sampler::Sobol,
        },
        roulette_min_bounces: args
            .roulette_min_bounces
            .unwrap_or(defaults.roulette_min_bounces),
        ..defaults
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    base.validate()?;
    let pixels = base.pixel_count();
    let mut runs: Vec<(f64, f64, ImageError)> = Vec::new();
    // Rays (camera, bounce, shadow and caustic light paths) per pixel: a cost that does not
    // depend on the load.
    let mut rays_per_pixel: Vec<f64> = Vec::new();
    for seed in args.seed..args.seed + args.seeds {
        let settings = RenderSettings { seed, ..base };
        let start = Instant::now();
        let mut last_pass_end = start;
        let (film, stats) = pool.install(|| {
            render(&flat, &settings, |p| {
                let Some(budget) = args.time else {
                    return Flow::Continue;
                };
                if !p.pass_ended {
                    return Flow::Continue;
                }
                // Stop after a pass if another one as long as the last would overrun (the
                // last, not the mean: adaptive passes shorten as tiles stop).
                let now = Instant::now();
                let last_pass = now - last_pass_end;
                last_pass_end = now;
                if now - start + last_pass > budget {
                    Flow::Stop
                } else {
                    Flow::Continue
                }
            })
        })?;
        let seconds = start.elapsed().as_secs_f64();
        let image = film.resolve();
        let e = image_error(&image, &reference).context("size differs from the reference")?;
        let spp = stats.samples as f64 / pixels as f64;
        let rays = stats.total_rays() as f64 / pixels as f64;
        rays_per_pixel.push(rays);
        println!(
            "seed {seed}: {spp:.1} spp, {rays:.1} rays per pixel in {seconds:.2} s: rmse {:.5} ({:.4} of the mean), mse {:.6}, \
             relative mse {:.5}, top 1% of pixels hold {:.1}% of the squared error",
            e.rmse(),
            e.rmse() / e.reference_mean,
            e.mse,
            e.relative_mse,
            100.0 * e.top_percent_share
        );
        let (m, r) = (image.mean(), reference.mean());
        println!(
            "seed {seed}: image mean {:.5} {:.5} {:.5}, reference mean {:.5} {:.5} {:.5}",
            m.x, m.y, m.z, r.x, r.y, r.z
        );
        if let Some(path) = &args.write {
            write_image(path, &film, 0.0)?;
        }
        runs.push((seconds, spp, e));
    }
    let n = runs.len() as f64;
    let mean = |f: &dyn Fn(&(f64, f64, ImageError)) -> f64| runs.iter().map(f).sum::<f64>() / n;
    let (seconds, spp) = (mean(&|r| r.0), mean(&|r| r.1));
    let (mse, relative) = (mean(&|r| r.2.mse), mean(&|r| r.2.relative_mse));
    // The spread of the MSE over the seeds: its standard error.
    let mse_error =
        (runs.iter().map(|r| (r.2.mse - mse).powi(2)).sum::<f64>() / (n - 1.0).max(1.0) / n).sqrt();
    println!(
        "mean of {} runs: {spp:.1} spp in {seconds:.2} s: mse {mse:.6} +- {mse_error:.6}, \
         relative mse {relative:.5}, top 1% share {:.1}%; mse x seconds {:.6}, mse x spp {:.5}, \
         mse x rays per pixel {:.4}, relative mse x rays per pixel {:.3}",
        runs.len(),
        100.0 * mean(&|r| r.2.top_percent_share),
        mse * seconds,
        mse * spp,
        mse * rays_per_pixel.iter().sum::<f64>() / n,
        relative * rays_per_pixel.iter().sum::<f64>() / n
    );
    // Medians resist a run slowed by other work on the machine or struck by a rare firefly.
    let median = |f: &dyn Fn(&(f64, f64, ImageError)) -> f64| {
        let mut values: Vec<f64> = runs.iter().map(f).collect();
        values.sort_by(f64::total_cmp);
        let mid = values.len() / 2;
        if values.len() % 2 == 1 {
            values[mid]
        } else {
            0.5 * (values[mid - 1] + values[mid])
        }
    };
    println!(
        "median of {} runs: {:.1} spp in {:.2} s: rmse {:.5}, mse {:.6}, relative mse {:.5}, \
         top 1% share {:.1}%",
        runs.len(),
        median(&|r| r.1),
        median(&|r| r.0),
        median(&|r| r.2.rmse()),
        median(&|r| r.2.mse),
        median(&|r| r.2.relative_mse),
        100.0 * median(&|r| r.2.top_percent_share)
    );
    Ok(())
}
