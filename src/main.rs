//! The `wavetrace` command line: parses flags into `RenderSettings`, runs the library, prints
//! the summary, and maps errors to exit codes: 0 done, 1 failure (bad input, unwritable
//! output), 2 usage error (clap), 128 + signal number when SIGINT or SIGTERM stopped the render
//! early (the image of the samples taken so far is still written).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use signal_hook::consts::{SIGINT, SIGTERM};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicI32, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use wavetrace::film::{Image, Layer};
use wavetrace::frames::{BLENDER_CURRENT_FRAME, DEFAULT_FPS, FrameRange, frame_path};
use wavetrace::output::NamedLayer;
use wavetrace::scene::load::{
    EnvironmentOverrides, LightUnits, LoadOptions, Placement, UpAxis, dark_image_warning,
    is_model_file, load_scene_placed,
};
use wavetrace::scene::{AnimationChoice, EnvironmentSource};
use wavetrace::settings::{
    Adaptive, DENOISED_LIGHT_MAX_SPP, DENOISED_MAX_SPP, DENOISED_NOISE_THRESHOLD, DenoisedStop,
    MAX_IMAGE_SIDE, MAX_SHADOW_RAYS,
};
use wavetrace::{
    Film, Flow, RenderOverrides, RenderSettings, RenderStats, Scene, flatten, render, render_rows,
    write_image,
};

mod farm_cli;

#[derive(Parser)]
#[command(version, about = "A physically based Monte Carlo path tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file (.toml) or a model (.gltf, .glb, .obj) to a PNG or OpenEXR image.
    Render(Box<RenderArgs>),
    /// Merge the part files of one frame (`render --part K/N`), in any order, into the image
    /// the whole render would have written, byte for byte.
    Merge(MergeArgs),
    /// Render on a Slurm cluster: `wavetrace slurm SCENE [render flags] (--parts N | --frames
    /// A-B[:STEP] [--frames-per-task M]) -o OUT [--sbatch ARG]... [--wait]`. Submits a job
    /// array (one task per part, then a merge job; or one task per chunk of frames), prints
    /// the job ids; --wait blocks until the last job ends and fails if one did. Scripts, logs
    /// and parts go to the folder OUT.slurm next to OUT. See docs/farm.md.
    #[command(disable_help_flag = true)]
    Slurm(SlurmArgs),
    /// Reproduce the seed report's benchmark tables on the built-in room and print them next
    /// to the report's seconds.
    BenchSeed(BenchSeedArgs),
}

#[derive(Args)]
struct MergeArgs {
    /// The part files (`render --part K/N -o FILE`), every part exactly once, any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image; the extension picks the format (.png: sRGB 8-bit; .exr: linear float).
    #[arg(short, long)]
    output: PathBuf,
    /// Print nothing on success but warnings.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args)]
struct SlurmArgs {
    /// SCENE, render flags and the slurm flags, in any order after SCENE (see `wavetrace help
    /// slurm`).
    #[arg(trailing_var_arg = true, allow_hyphen_values = true, num_args = 0..)]
    args: Vec<String>,
}

#[derive(Args)]
struct BenchSeedArgs {
    /// Image width (the report used 800).
    #[arg(long, default_value_t = 800)]
    width: u32,
    /// Image height (the report used 800).
    #[arg(long, default_value_t = 800)]
    height: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Only Table 1 (shadow rays) or Table 2 (samples).
    #[arg(long)]
    table: Option<u8>,
}

#[derive(Args)]
struct RenderArgs {
    /// Scene file (.toml) or model file (.gltf, .glb, .obj). A model that does not light
    /// itself (no punctual light, and no emitter with a camera of its own) is placed in the
    /// seed room, facing and filling the room's camera.
    scene: PathBuf,
    /// Place a model file in the seed room even if it has its own lights.
    #[arg(long)]
    in_room: bool,
    /// The model file's up axis: y (glTF, Blender's OBJ export; default) or z.
    #[arg(long, value_parser = ["y", "z"])]
    up: Option<String>,
    /// How a glTF file's light intensities are read: spec (candela and lux, 683 lm/W, as
    /// Blender exports by default), unitless (read as W/sr and W/m^2), raw (Blender's watts).
    #[arg(long, value_parser = ["spec", "unitless", "raw"])]
    light_units: Option<String>,
    /// Render from the camera of this name (default: the file's first camera).
    #[arg(long)]
    camera: Option<String>,
    /// Output image; the extension picks the format (.png: sRGB 8-bit; .exr: linear float).
    /// Default: the scene's name with .png, in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Image width in pixels (default: the scene's, else 800, or from the height and the
    /// camera's aspect ratio, square without one).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's, else 800, or from the width and the
    /// camera's aspect ratio, square without one).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    height: Option<u32>,
    /// Exactly this many samples in every pixel (no adaptive sampling). Default: the scene's;
    /// else adaptive sampling up to 1024 spp and 60 s; with --time: no limit but the time.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    spp: Option<u32>,
    /// Adaptive sampling: 8x8 tiles stop once every pixel's relative error estimate is below
    /// this (Cycles' error measure; default 0.05); 0 turns adaptive sampling off. With --spp,
    /// adaptive up to that many samples.
    #[arg(long, value_parser = parse_noise_threshold)]
    noise_threshold: Option<f32>,
    /// Adaptive sampling: samples every pixel takes before its tile may stop (default 16).
    #[arg(long, value_parser = clap::value_parser!(u32).range(2..))]
    min_spp: Option<u32>,
    /// Render for this long (e.g. 30s, 5m, 1h 30m), as many whole samples per pixel as fit
    /// (adaptive: until the noise threshold too), then write the image. At least one sample
    /// per pixel is always taken.
    #[arg(long, value_parser = parse_time_budget)]
    time: Option<Duration>,
    /// Random numbers: independent, or Owen-scrambled Sobol points (default: the scene's,
    /// else sobol).
    #[arg(long, value_enum)]
    sampler: Option<SamplerArg>,
    /// Shadow rays per diffuse hit for next-event estimation (default: the scene's, else 1).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=MAX_SHADOW_RAYS as i64))]
    shadow_rays: Option<u32>,
    /// Light sampling only: emitters that BSDF-sampled rays find at non-delta hits are
    /// discarded instead of being combined with the shadow rays by multiple importance sampling.
    #[arg(long)]
    no_mis: bool,
    /// Light paths per pixel and pass that find caustics seen directly (light -> mirror or
    /// glass -> diffuse surface), combined with the path tracer by multiple importance
    /// sampling (default 0.25); 0 turns them off. Only scenes with a mirror or smooth glass and
    /// an area, point or spot light trace them.
    #[arg(long, value_parser = parse_caustic_paths)]
    caustic_paths: Option<f32>,
    /// Radius, in pixels, within which the light paths' points are merged at points seen
    /// through a mirror or smooth glass (caustics behind a delta vertex; default 3; the
    /// radius shrinks with the passes, so the image converges as without it); 0 turns
    /// merging off.
    #[arg(long, value_parser = parse_merge_radius)]
    merge_radius: Option<f32>,
    /// Pixel reconstruction filter: box, gaussian or blackman-harris (default: the scene
    /// file's, else box; a model file (glTF, OBJ) takes Cycles' blackman-harris of 1.5 px).
    #[arg(long, value_enum)]
    filter: Option<FilterArg>,
    /// Pixel filter width in pixels, as Cycles means it: the box's side, the Gaussian's 4
    /// standard deviations, half the Blackman-Harris window (default: the scene file's, else
    /// 1 for the box and 1.5 for the others).
    #[arg(long, value_name = "PX", allow_negative_numbers = true, value_parser = parse_filter_width)]
    filter_width: Option<f32>,
    /// Seed of the random numbers; the same seed gives the same image on any thread count.
    #[arg(long, default_value_t = wavetrace::math::rng::DEFAULT_SEED)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    threads: Option<u16>,
    /// Exposure in stops applied before PNG encoding (EXR stays linear and unscaled).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_exposure)]
    exposure: f32,
    /// Paths traced together per wavefront batch (affects speed and memory, never the image).
    #[arg(long, default_value_t = RenderSettings::default().batch_size,
          value_parser = clap::value_parser!(u32).range(1..=1 << 24))]
    batch_size: u32,
    /// Print nothing on success but warnings: no progress bar, no summary.
    #[arg(short, long)]
    quiet: bool,
    /// Render only part K (0-based) of N of the frame, a band of rows, into -o FILE: a partial
    /// film for `wavetrace merge` (see docs/farm.md). Needs a fixed stop (--spp, or the
    /// scene's spp), not a time budget.
    #[arg(long, value_name = "K/N", conflicts_with_all = ["time", "frames"])]
    part: Option<wavetrace::farm::PartIndex>,
    /// Light the scene from infinity: an equirectangular .hdr/.exr map, or a constant colour
    /// R,G,B (replaces the scene's [environment]; a model file renders under it, not in the room).
    #[arg(long, value_name = "FILE|R,G,B", value_parser = parse_environment)]
    env: Option<EnvironmentSource>,
    /// Multiplies the environment's radiance (default: the scene's, else 1).
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    env_strength: Option<f32>,
    /// Turns the environment about +Z by this many degrees (Blender's Mapping rotation).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    env_rotation: Option<f32>,
    /// Camera rays that escape see black; the environment still lights the scene.
    #[arg(long)]
    env_hidden: bool,
    /// Denoise the image with Open Image Denoise (guided by the albedo and normal layers);
    /// the default in builds with the `denoise` feature. With no sample flags the render then
    /// stops sooner (noise threshold 0.25, at most 64 spp).
    #[arg(long, overrides_with = "no_denoise")]
    denoise: bool,
    /// Write the image as rendered, without denoising.
    #[arg(long, overrides_with = "denoise")]
    no_denoise: bool,
    /// Auxiliary layers written beside the colour in the (.exr) output, comma-separated:
    /// albedo, normal (at the first non-specular hit, mirrors and glass followed), depth,
    /// noisy (the colour before denoising), spp (samples taken), variance (of the pixel's
    /// mean; adaptive sampling only).
    #[arg(long, value_name = "LIST", value_delimiter = ',', value_enum)]
    aov: Vec<AovName>,
    /// Pose the scene's animation at this frame (time FRAME / --fps). Default: frame 1, the
    /// one Blender shows after importing a glTF file. A `#` run in -o is replaced by the
    /// zero-padded frame number.
    #[arg(long, conflicts_with = "frames")]
    frame: Option<u32>,
    /// Render the frames A to B (every STEPth): the scene is loaded once and posed for each.
    /// The last `#` run of -o becomes the zero-padded frame number (f-####.png); without
    /// one, the number is added before the extension (f.png -> f0001.png).
    #[arg(long, value_name = "A-B[:STEP]", value_parser = FrameRange::parse)]
    frames: Option<FrameRange>,
    /// Frames per second of the animation's timeline (Blender's default 24).
    #[arg(long, default_value_t = DEFAULT_FPS, value_parser = parse_fps)]
    fps: f32,
    /// The animation to play: its name, or its index in the file (default: the first).
    #[arg(long, value_name = "NAME|INDEX")]
    animation: Option<String>,
    /// Skip a frame whose output file exists already (a retried farm task goes on where the
    /// last attempt stopped).
    #[arg(long)]
    skip_existing: bool,
}

/// `--aov`: the layers the output can hold besides the colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum AovName {
    /// Albedo at the first non-specular hit (albedo.R, .G, .B).
    Albedo,
    /// Shading normal there, world space (normal.X, .Y, .Z).
    Normal,
    /// Distance from the camera to the first hit (depth.Z).
    Depth,
    /// The colour before denoising (noisy.R, .G, .B).
    Noisy,
    /// Light seen directly or through mirrors and glass, the part of the colour the denoiser
    /// leaves alone (emission.R, .G, .B).
    Emission,
    /// Samples per pixel (spp.Y).
    Spp,
    /// Estimated variance of the pixel's mean (variance.R, .G, .B).
    Variance,
}

impl AovName {
    /// The layer's name in the file, its channels, and the film layer it comes from (`None`:
    /// the colour before denoising).
    fn layout(self) -> (&'static str, &'static [&'static str], Option<Layer>) {
        match self {
            AovName::Albedo => ("albedo", &["R", "G", "B"], Some(Layer::Albedo)),
            AovName::Normal => ("normal", &["X", "Y", "Z"], Some(Layer::Normal)),
            AovName::Depth => ("depth", &["Z"], Some(Layer::Depth)),
            AovName::Noisy => ("noisy", &["R", "G", "B"], None),
            AovName::Emission => ("emission", &["R", "G", "B"], Some(Layer::Emission)),
            AovName::Spp => ("spp", &["Y"], Some(Layer::Samples)),
            AovName::Variance => ("variance", &["R", "G", "B"], Some(Layer::Variance)),
        }
    }
}

fn parse_fps(text: &str) -> std::result::Result<f32, String> {
    let fps: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
        return Err(format!(
            "frames per second must lie in (0, 10000], got {text}"
        ));
    }
    Ok(fps)
}

/// `--env`: three comma-separated numbers are a colour, anything else a file.
fn parse_environment(text: &str) -> std::result::Result<EnvironmentSource, String> {
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() == 3
        && let Ok(rgb) = parts
            .iter()
            .map(|p| p.trim().parse::<f32>())
            .collect::<std::result::Result<Vec<f32>, _>>()
    {
        return Ok(EnvironmentSource::Color(wavetrace::math::Vec3::new(
            rgb[0], rgb[1], rgb[2],
        )));
    }
    Ok(EnvironmentSource::File(PathBuf::from(text)))
}

/// `--sampler`: the library's [`Sampler`](wavetrace::math::rng::Sampler), for clap.
#[derive(Clone, Copy, clap::ValueEnum)]
enum SamplerArg {
    /// Independent uniform numbers.
    Independent,
    /// Owen-scrambled Sobol points.
    Sobol,
}

impl From<SamplerArg> for wavetrace::math::rng::Sampler {
    fn from(arg: SamplerArg) -> Self {
        match arg {
            SamplerArg::Independent => Self::Independent,
            SamplerArg::Sobol => Self::Sobol,
        }
    }
}

/// `--filter`: the library's [`FilterKind`](wavetrace::FilterKind), for clap.
#[derive(Clone, Copy, clap::ValueEnum)]
enum FilterArg {
    /// Each sample uniform over a square of the width's side (1 px: inside its pixel).
    Box,
    /// A Gaussian of standard deviation width / 4.
    Gaussian,
    /// The Blackman-Harris window over [-width, width] (Cycles' default).
    BlackmanHarris,
}

impl From<FilterArg> for wavetrace::FilterKind {
    fn from(arg: FilterArg) -> Self {
        match arg {
            FilterArg::Box => Self::Box,
            FilterArg::Gaussian => Self::Gaussian,
            FilterArg::BlackmanHarris => Self::BlackmanHarris,
        }
    }
}

fn parse_filter_width(text: &str) -> std::result::Result<f32, String> {
    let width: f32 = text.parse().map_err(|e| format!("{e}"))?;
    wavetrace::PixelFilter::check_width(width)?;
    Ok(width)
}

/// Time cap of a default (adaptive, no --spp, no --time) render: a first image within a
/// minute even of a scene that does not reach the noise threshold at 1024 spp.
const ADAPTIVE_TIME_CAP: Duration = Duration::from_secs(60);

fn parse_noise_threshold(text: &str) -> std::result::Result<f32, String> {
    let threshold: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if !(threshold.is_finite() && (0.0..=1.0).contains(&threshold)) {
        return Err(format!("the noise threshold must lie in 0..=1, got {text}"));
    }
    Ok(threshold)
}

fn parse_caustic_paths(text: &str) -> std::result::Result<f32, String> {
    use wavetrace::settings::MAX_CAUSTIC_PATHS;
    let paths: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if !(0.0..=MAX_CAUSTIC_PATHS).contains(&paths) {
        return Err(format!(
            "caustic light paths per pixel must lie in 0..={MAX_CAUSTIC_PATHS}, got {text}"
        ));
    }
    Ok(paths)
}

fn parse_merge_radius(text: &str) -> std::result::Result<f32, String> {
    use wavetrace::settings::MAX_MERGE_RADIUS;
    let radius: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if !(0.0..=MAX_MERGE_RADIUS).contains(&radius) {
        return Err(format!(
            "the merge radius must lie in 0..={MAX_MERGE_RADIUS} pixels, got {text}"
        ));
    }
    Ok(radius)
}

fn parse_time_budget(text: &str) -> std::result::Result<Duration, String> {
    let budget = humantime::parse_duration(text).map_err(|e| e.to_string())?;
    if budget.is_zero() {
        return Err("the time budget must be more than zero".into());
    }
    Ok(budget)
}

fn parse_exposure(text: &str) -> std::result::Result<f32, String> {
    let stops: f32 = text.parse().map_err(|e| format!("{e}"))?;
    if !(-64.0..=64.0).contains(&stops) {
        return Err(format!("exposure must lie in -64..=64 stops, got {text}"));
    }
    Ok(stops)
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => run_render(*args),
        Command::Merge(args) => run_merge(args).map(|()| ExitCode::SUCCESS),
        Command::Slurm(args) => farm_cli::run_slurm(args.args),
        Command::BenchSeed(args) => run_bench_seed(args).map(|()| ExitCode::SUCCESS),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes on one line, leaving out a cause whose text its parent already
/// shows (our I/O errors print the operating system's reason themselves).
fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line += ": ";
        }
        line += &text;
    }
    line
}

/// Watches for SIGINT and SIGTERM. The first one is acknowledged on stderr and recorded in
/// the returned cell (the render polls it after every round); a second one ends the process
/// at once, removing the temporary file of an image write in progress (the output file
/// itself is only ever renamed into place).
fn watch_stop_signals(output: &Path) -> Result<Arc<AtomicI32>> {
    let temporary = wavetrace::output::temporary_path(output);
    let received = Arc::new(AtomicI32::new(0));
    // Deliveries are counted inside the handler: the iterator below reports a signal that
    // arrived twice before its thread woke up only once, which would lose a quick double Ctrl-C.
    let deliveries = Arc::new(AtomicUsize::new(0));
    for signal in [SIGINT, SIGTERM] {
        let (received, deliveries) = (Arc::clone(&received), Arc::clone(&deliveries));
        // SAFETY: the action only stores to and increments atomics, which is signal-safe.
        unsafe {
            signal_hook::low_level::register(signal, move || {
                received.store(signal, Ordering::SeqCst);
                deliveries.fetch_add(1, Ordering::SeqCst);
            })
        }
        .context("cannot install the SIGINT/SIGTERM handler")?;
    }
    // Registered after the counting actions, so they have run whenever this thread wakes.
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])
        .context("cannot install the SIGINT/SIGTERM handler")?;
    std::thread::spawn(move || {
        for signal in signals.forever() {
            let name = signal_name(signal);
            if deliveries.load(Ordering::SeqCst) < 2 {
                // Said at once: the render stops only at the end of its current round.
                eprintln!("\nwavetrace: {name} received, stopping ({name} again quits at once)");
                continue;
            }
            eprintln!("\nwavetrace: {name} again, quitting at once");
            let _ = std::fs::remove_file(&temporary);
            std::process::exit(128 + signal);
        }
    });
    Ok(received)
}

fn signal_name(signal: i32) -> &'static str {
    match signal {
        SIGINT => "SIGINT",
        SIGTERM => "SIGTERM",
        _ => "signal",
    }
}

/// A usage error found after parsing: printed as clap prints its own, exit code 2.
fn usage_error(message: String) -> ! {
    use clap::CommandFactory;
    Cli::command()
        .error(clap::error::ErrorKind::ArgumentConflict, message)
        .exit()
}

/// Whether to denoise: `--denoise`/`--no-denoise`, else whether the build can. `--denoise` in
/// a build without the denoiser is a usage error.
fn denoise_wanted(args: &RenderArgs) -> bool {
    if args.denoise && !wavetrace::denoise::AVAILABLE {
        usage_error(
            "--denoise: this build has no denoiser; build with `cargo build --release \
             --features denoise` (run tools/setup_oidn.sh first unless the system has Open \
             Image Denoise 2)"
                .into(),
        );
    }
    !args.no_denoise && wavetrace::denoise::AVAILABLE
}

/// Refuses `--aov` with a PNG output (it holds no layers) before anything is rendered.
fn check_aov_output(args: &RenderArgs, output: &Path) {
    let exr = output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if !args.aov.is_empty() && !exr {
        usage_error(format!(
            "--aov: {} cannot hold layers; write an OpenEXR file (-o NAME.exr)",
            output.display()
        ));
    }
}

/// A default render that is denoised (no sample flag, no sample count in the scene) stops
/// at the denoiser's looser threshold and cap, unless a time budget decides.
fn tune_for_denoiser(args: &RenderArgs, scene_spp: Option<u32>, settings: &mut RenderSettings) {
    let sample_flags = args.spp.is_some()
        || args.noise_threshold.is_some()
        || args.min_spp.is_some()
        || args.time.is_some();
    if sample_flags || scene_spp.is_some() {
        return;
    }
    if let Some(adaptive) = &mut settings.adaptive {
        *adaptive = Adaptive {
            noise_threshold: DENOISED_NOISE_THRESHOLD,
            denoised: Some(DenoisedStop {
                light_threshold: adaptive.noise_threshold,
                unlit_max_spp: DENOISED_MAX_SPP,
            }),
            ..*adaptive
        };
        settings.spp = DENOISED_LIGHT_MAX_SPP;
    }
}

/// Writes the render: the colour (denoised if asked and possible, else as rendered, with a
/// warning) and the `--aov` layers beside it.
fn write_output(args: &RenderArgs, output: &Path, film: &Film, denoise: bool) -> Result<Image> {
    let noisy = film.resolve();
    let mut color = None;
    if denoise {
        let guides = (
            film.layer(Layer::Albedo),
            film.layer(Layer::Normal),
            film.layer(Layer::Emission),
        );
        if let (Some(albedo), Some(normal), Some(direct)) = guides {
            let start = Instant::now();
            match wavetrace::denoise::denoise_except(&noisy, &direct, &albedo, &normal) {
                Ok(image) => {
                    if !args.quiet {
                        eprintln!(
                            "wavetrace: denoised (Open Image Denoise) in {:.2} s",
                            start.elapsed().as_secs_f64()
                        );
                    }
                    color = Some(image);
                }
                Err(e) => eprintln!("warning: {e}; the image is written as rendered (noisy)"),
            }
        }
    }
    let color = color.unwrap_or_else(|| noisy.clone());
    if args.aov.is_empty() {
        write_image(output, &color, args.exposure)?;
        return Ok(color);
    }
    let mut layers = Vec::new();
    for name in &args.aov {
        let (layer_name, channels, source) = name.layout();
        let image = match source {
            None => noisy.clone(),
            Some(layer) => film.layer(layer).ok_or_else(|| {
                anyhow::anyhow!("--aov {layer_name}: the render kept no such layer")
            })?,
        };
        layers.push(NamedLayer {
            name: layer_name,
            channels,
            image,
        });
    }
    wavetrace::output::write_exr_layers(output, &color, &layers)?;
    Ok(color)
}

/// `wavetrace merge`: the parts' film, checked whole, written as the render writes it.
fn run_merge(args: MergeArgs) -> Result<()> {
    wavetrace::output::check_writable(&args.output)?;
    let merged = wavetrace::farm::merge_parts(&args.parts)?;
    write_image(&args.output, &merged.film, merged.exposure)?;
    if !args.quiet {
        eprintln!(
            "wavetrace: merged {} parts of {}x{} -> {}",
            args.parts.len(),
            merged.film.width,
            merged.film.height,
            args.output.display()
        );
    }
    Ok(())
}

fn run_render(args: RenderArgs) -> Result<ExitCode> {
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&args.scene));
    // Usage errors of the denoiser's flags, before anything is loaded.
    denoise_wanted(&args);
    check_aov_output(&args, &output);
    let stop_signal = watch_stop_signals(&output)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.map_or(0, usize::from))
        .build()
        .context("cannot start worker threads")?;
    pool.install(|| {
        if (args.up.is_some() || args.light_units.is_some()) && !is_model_file(&args.scene) {
            anyhow::bail!(
                "{}: --up and --light-units apply to model files; a scene file states them \
                 per [[model]] (up = \"z\", light_units = \"unitless\")",
                args.scene.display()
            );
        }
        let options = LoadOptions {
            in_room: args.in_room,
            camera: args.camera.clone(),
            up: match args.up.as_deref() {
                Some("z") => UpAxis::Z,
                _ => UpAxis::Y,
            },
            light_units: match args.light_units.as_deref() {
                Some("unitless") => LightUnits::Unitless,
                Some("raw") => LightUnits::Raw,
                _ => LightUnits::Spec,
            },
            environment: EnvironmentOverrides {
                source: args.env.clone(),
                strength: args.env_strength,
                rotation_degrees: args.env_rotation,
                hidden: args.env_hidden,
            },
        };
        let (mut scene, placement) = load_scene_placed(&args.scene, &options)?;
        wavetrace::internals::trace_phase("loaded");
        render_frames(
            &args,
            &options,
            &mut scene,
            placement,
            &output,
            &stop_signal,
        )
    })
}

/// Renders the frames the flags ask for (one image without --frames), each to its file: the
/// scene loaded once, posed for each frame, then flattened (the BVH built) and rendered.
fn render_frames(
    args: &RenderArgs,
    options: &LoadOptions,
    scene: &mut Scene,
    placement: Placement,
    output: &Path,
    stop_signal: &AtomicI32,
) -> Result<ExitCode> {
    let animated = scene.is_animated();
    let choice = args
        .animation
        .as_deref()
        .map_or(AnimationChoice::First, AnimationChoice::parse);
    if !animated && args.animation.is_some() {
        anyhow::bail!(
            "{}: --animation: the scene has no animations",
            args.scene.display()
        );
    }
    // (frame, its output file); `None` for a render without --frame or --frames.
    let frames: Vec<(Option<u32>, PathBuf)> = match (args.frames, args.frame) {
        (Some(range), _) => (range.frames())
            .map(|f| (Some(f), frame_path(output, f, true)))
            .collect(),
        (None, Some(f)) => vec![(Some(f), frame_path(output, f, false))],
        (None, None) => vec![(None, output.to_path_buf())],
    };
    let sequence = args.frames.is_some();
    let mut said = HashSet::new();
    if !animated && (args.frame.is_some() || sequence) {
        say_once(
            &mut said,
            format!(
                "{}: the scene has no animation; every frame is the same image",
                args.scene.display()
            ),
        );
    }
    let count = frames.len();
    for (i, (frame, frame_output)) in frames.into_iter().enumerate() {
        if args.skip_existing && frame_output.exists() {
            if !args.quiet {
                eprintln!(
                    "wavetrace: frame {} -> {} exists; skipped",
                    frame.unwrap_or(BLENDER_CURRENT_FRAME),
                    frame_output.display()
                );
            }
            continue;
        }
        if let Some(signal) = received(stop_signal) {
            eprintln!(
                "wavetrace: {} before rendering; no image written",
                signal_name(signal)
            );
            return Ok(ExitCode::from(128 + signal as u8));
        }
        if animated {
            // Frame F is at F / fps seconds, as on Blender's timeline.
            let frame = frame.unwrap_or(BLENDER_CURRENT_FRAME);
            let seconds = (f64::from(frame) / f64::from(args.fps)) as f32;
            for warning in scene.pose(&choice, seconds)? {
                say_once(&mut said, warning);
            }
        }
        let job = FrameJob {
            output: &frame_output,
            frame: frame.filter(|_| sequence),
            release_world: i + 1 == count,
            options,
        };
        let code = render_frame(args, scene, placement, &job, stop_signal, &mut said)?;
        if code != ExitCode::SUCCESS {
            return Ok(code);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints a warning unless it was printed before (a sequence says each thing once).
fn say_once(said: &mut HashSet<String>, warning: String) {
    if !said.contains(&warning) {
        eprintln!("warning: {warning}");
        said.insert(warning);
    }
}

/// One image of [`render_frames`].
struct FrameJob<'a> {
    output: &'a Path,
    /// The frame number of a sequence (whose frames print one summary line each).
    frame: Option<u32>,
    /// Whether the world may be freed once flattened (the last frame).
    release_world: bool,
    /// How the scene was loaded (a part file records it, so that merge can check its parts
    /// come from one render).
    options: &'a LoadOptions,
}

fn render_frame(
    args: &RenderArgs,
    scene: &mut Scene,
    placement: Placement,
    job: &FrameJob,
    stop_signal: &AtomicI32,
    said: &mut HashSet<String>,
) -> Result<ExitCode> {
    let output = job.output;
    // Verbose output for a single image; a sequence prints one line per frame.
    let verbose = !args.quiet && job.frame.is_none();
    // Refuse an unwritable output before spending time on the render.
    match args.part {
        Some(_) => wavetrace::farm::parts::check_part_writable(output)?,
        None => wavetrace::output::check_writable(output)?,
    }
    let flat = flatten(&scene.world, &args.scene)?;
    if job.release_world {
        // The render reads only the render scene: the world's meshes (18 bytes a triangle
        // at least) are freed before the render allocates its film and buffers.
        scene.world = hecs::World::new();
    }
    wavetrace::internals::trace_phase("flattened");
    for warning in scene.warnings.iter().chain(flat.warnings()) {
        say_once(said, warning.clone());
    }
    if verbose {
        eprintln!(
            "wavetrace: {} primitives, BVH built in {:.1} ms (the scene flattened in {:.1} ms)",
            flat.primitive_count(),
            flat.flatten_times().bvh_build.as_secs_f64() * 1e3,
            flat.flatten_times().total.as_secs_f64() * 1e3
        );
    }
    let denoise = denoise_wanted(args);
    let (settings, time_budget) = frame_settings(args, scene, placement, &flat, denoise)?;
    let part = match args.part {
        Some(part) if denoise => anyhow::bail!(
            "--part {part}: merged parts are written as rendered; denoising them is not \
             supported yet, so give --no-denoise"
        ),
        Some(part) => Some(farm_cli::PartRender::new(
            part,
            args,
            job.options,
            &settings,
            time_budget,
        )?),
        None => None,
    };
    let rows = part.as_ref().map_or(0..settings.height, |p| p.rows.clone());

    if let Some(signal) = received(stop_signal) {
        eprintln!(
            "wavetrace: {} before rendering; no image written",
            signal_name(signal)
        );
        return Ok(ExitCode::from(128 + signal as u8));
    }
    let (film, stats) = render_with_progress(
        args,
        &flat,
        (&settings, rows),
        time_budget,
        stop_signal,
        verbose,
    )?;
    if let Some(part) = &part {
        return part.finish(output, &film, &stats, received(stop_signal), args.quiet);
    }

    let written = if denoise || !args.aov.is_empty() {
        write_output(args, output, &film, denoise)?
    } else {
        write_image(output, &film, args.exposure)?;
        film.resolve()
    };
    if placement == Placement::AsIs
        && let Some(warning) = dark_image_warning(&written, args.exposure)
    {
        say_once(said, warning);
    }
    if !args.quiet {
        eprintln!(
            "wavetrace: {}{}x{}, {}, {} shadow rays, {} threads{} -> {}",
            job.frame.map_or(String::new(), |f| format!("frame {f}: ")),
            settings.width,
            settings.height,
            samples_held(&stats, settings.pixel_count()),
            settings.shadow_rays,
            rayon::current_num_threads(),
            job.frame.map_or(String::new(), |_| format!(
                ", {:.2} s",
                stats.wall_time.as_secs_f64()
            )),
            output.display()
        );
    }
    if verbose {
        eprintln!("{}", stats.summary());
    }
    Ok(match received(stop_signal) {
        Some(signal) if stats.interrupted => {
            eprintln!(
                "wavetrace: stopped early by {}; the image holds the samples finished so far ({})",
                signal_name(signal),
                samples_held(&stats, settings.pixel_count())
            );
            ExitCode::from(128 + signal as u8)
        }
        _ => ExitCode::SUCCESS,
    })
}

/// The settings of one frame (flags over the scene file's `[render]` over the defaults) and
/// its time budget: a default render stops at the noise threshold, 1024 spp or a minute.
fn frame_settings(
    args: &RenderArgs,
    scene: &Scene,
    placement: Placement,
    flat: &wavetrace::RenderScene,
    denoise: bool,
) -> Result<(RenderSettings, Option<Duration>)> {
    let overrides = RenderOverrides {
        width: args.width,
        height: args.height,
        spp: args.spp,
        shadow_rays: args.shadow_rays,
        mis: Some(!args.no_mis),
        seed: Some(args.seed),
        batch_size: Some(args.batch_size),
        sampler: args.sampler.map(Into::into),
        noise_threshold: args.noise_threshold,
        min_spp: args.min_spp,
        caustic_paths: args.caustic_paths,
        merge_radius: args.merge_radius,
        filter: args.filter.map(Into::into),
        filter_width: args.filter_width,
    };
    // A model file (often a Blender export) is reconstructed as Cycles does by default:
    // Blackman-Harris of 1.5 px. Scene files keep the box of 1 px (docs/light-transport.md).
    let mut scene_defaults = scene.defaults;
    if placement != Placement::SceneFile {
        scene_defaults
            .filter
            .get_or_insert(wavetrace::FilterKind::BlackmanHarris);
    }
    let mut settings =
        RenderSettings::resolve(&scene_defaults, &overrides, flat.camera().aspect_ratio);
    if args.time.is_some() && args.spp.is_none() {
        // With a time budget and no sample count, the budget decides (and the noise
        // threshold, if adaptive).
        settings.spp = u32::MAX;
    }
    if denoise {
        tune_for_denoiser(args, scene.defaults.spp, &mut settings);
    }
    settings.record_aovs = denoise
        || args.aov.iter().any(|a| {
            matches!(
                a,
                AovName::Albedo | AovName::Normal | AovName::Depth | AovName::Emission
            )
        });
    if args.aov.contains(&AovName::Variance) && settings.adaptive.is_none() {
        usage_error(
            "--aov variance: the variance is estimated by adaptive sampling, which this \
             render does not use (drop --spp, or give --noise-threshold)"
                .into(),
        );
    }
    settings.validate()?;
    let time_budget = match (args.time, settings.adaptive, args.spp) {
        (Some(budget), _, _) => Some(budget),
        (None, Some(_), None) if scene.defaults.spp.is_none() => Some(ADAPTIVE_TIME_CAP),
        _ => None,
    };
    Ok((settings, time_budget))
}

/// Renders `flat` with a progress bar (hidden with --quiet), stopping at a signal or at the
/// end of the time budget.
fn render_with_progress(
    args: &RenderArgs,
    flat: &wavetrace::RenderScene,
    (settings, rows): (&RenderSettings, std::ops::Range<u32>),
    time_budget: Option<Duration>,
    stop_signal: &AtomicI32,
    verbose: bool,
) -> Result<(wavetrace::Film, RenderStats)> {
    let bar = match (args.quiet, time_budget) {
        (true, _) => ProgressBar::hidden(),
        (false, Some(budget)) => ProgressBar::new(budget.as_millis() as u64),
        (false, None) => ProgressBar::new(settings.pixel_count() * settings.spp as u64),
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {wide_bar} {percent}% (ETA {eta})",
        )
        .expect("valid template"),
    );
    if verbose {
        eprintln!(
            "wavetrace: rendering {} at {}x{}, {} (Ctrl-C stops and writes the image so far)",
            args.scene.display(),
            settings.width,
            settings.height,
            describe_sampling(settings, time_budget)
        );
    }
    let start = Instant::now();
    let mut budget = time_budget.map(|b| TimeBudget::new(start, b));
    let rendered = render_rows(flat, settings, rows, |p| {
        let pass_ended = p.pass_ended;
        match &budget {
            Some(b) => bar.set_position(start.elapsed().as_millis().min(b.length_ms()) as u64),
            None => {
                bar.set_length(p.samples_total);
                bar.set_position(p.samples_done);
            }
        }
        if received(stop_signal).is_some() {
            return Flow::Stop;
        }
        let out_of_time = match &mut budget {
            Some(b) => pass_ended && !b.another_pass_fits(),
            None => false,
        };
        if out_of_time {
            Flow::Stop
        } else {
            Flow::Continue
        }
    });
    bar.finish_and_clear();
    Ok(rendered?)
}

/// "16 spp", "adaptive (noise threshold 0.05, 16-1024 spp) for up to 1m", ...: how the
/// render samples, for its opening line.
fn describe_sampling(settings: &RenderSettings, time_budget: Option<Duration>) -> String {
    match (time_budget, settings.adaptive) {
        (Some(t), Some(a)) if settings.spp == u32::MAX => format!(
            "adaptive (noise threshold {}, at least {} spp) for up to {}",
            a.noise_threshold,
            a.min_spp,
            humantime::format_duration(t)
        ),
        (Some(t), Some(a)) => format!(
            "adaptive (noise threshold {}, {}-{} spp) for up to {}",
            a.noise_threshold,
            a.min_spp,
            settings.spp,
            humantime::format_duration(t)
        ),
        (None, Some(a)) => format!(
            "adaptive (noise threshold {}, {}-{} spp)",
            a.noise_threshold, a.min_spp, settings.spp
        ),
        (Some(t), None) if settings.spp == u32::MAX => {
            format!("for {}", humantime::format_duration(t))
        }
        (Some(t), None) => format!(
            "up to {} spp for {}",
            settings.spp,
            humantime::format_duration(t)
        ),
        (None, None) => format!("{} spp", settings.spp),
    }
}

/// The seed report's tables: (samples per pixel, shadow rays, seconds in the report).
const SEED_TABLE_1: [(u32, u32, f64); 4] = [
    (50, 1, 84.4),
    (50, 2, 107.0),
    (50, 8, 236.1),
    (50, 15, 384.8),
];
const SEED_TABLE_2: [(u32, u32, f64); 4] = [
    (1, 15, 10.44),
    (5, 15, 56.98),
    (25, 15, 282.21),
    (75, 15, 726.71),
];

fn run_bench_seed(args: BenchSeedArgs) -> Result<()> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    pool.install(|| {
        let room_path = Path::new("builtin:room");
        let scene = wavetrace::scene::load::load_scene_str(
            room_path,
            wavetrace::scene::load::BUILTIN_ROOM,
        )?;
        let flat = flatten(&scene.world, room_path)?;
        let threads = rayon::current_num_threads();
        println!(
            "seed room, {}x{}, {threads} threads (the report: 800x800, 1 thread)",
            args.width, args.height
        );
        for (number, table) in [(1, SEED_TABLE_1), (2, SEED_TABLE_2)] {
            if args.table.is_some_and(|t| t != number) {
                continue;
            }
            println!(
                "\nTable {number}: {}",
                if number == 1 {
                    "shadow rays at 50 samples per pixel"
                } else {
                    "samples per pixel at 15 shadow rays"
                }
            );
            println!(
                "{:>5} {:>12} {:>12} {:>12} {:>10} {:>10}",
                "spp", "shadow rays", "report (s)", "wavetrace (s)", "speed-up", "Mrays/s"
            );
            for (spp, shadow_rays, report_seconds) in table {
                let settings = RenderSettings {
                    width: args.width,
                    height: args.height,
                    spp,
                    shadow_rays,
                    ..RenderSettings::default()
                };
                let (_, stats) = render(&flat, &settings, |_| Flow::Continue)?;
                let seconds = stats.wall_time.as_secs_f64();
                // The report's times are for 800x800: scale them when another size is asked for.
                let scaled = report_seconds * settings.pixel_count() as f64 / (800.0 * 800.0);
                println!(
                    "{spp:>5} {shadow_rays:>12} {scaled:>12.2} {seconds:>12.2} {:>9.1}x {:>10.1}",
                    scaled / seconds,
                    stats.total_rays() as f64 / seconds / 1e6
                );
            }
        }
        Ok(())
    })
}

/// The signal received so far, if any.
fn received(stop_signal: &AtomicI32) -> Option<i32> {
    match stop_signal.load(Ordering::SeqCst) {
        0 => None,
        signal => Some(signal),
    }
}

/// "16 spp", or for a render stopped inside a pass "3-4 spp (4 in 1200 of 6400 pixels)":
/// the film averages each pixel over its own sample count, so every pixel is an unbiased
/// estimate, but the pixels of the unfinished pass hold one sample more. Adaptive: "16-1024
/// spp (mean 87.5)".
fn samples_held(stats: &RenderStats, pixel_count: u64) -> String {
    if stats.adaptive {
        return format!(
            "{}-{} spp (mean {:.1}, adaptive)",
            stats.spp_min, stats.spp_max, stats.spp_mean
        );
    }
    let extra = stats.samples % pixel_count;
    if extra == 0 {
        format!("{} spp", stats.complete_spp)
    } else {
        format!(
            "{}-{} spp ({} in {extra} of {pixel_count} pixels)",
            stats.complete_spp,
            stats.complete_spp + 1,
            stats.complete_spp + 1
        )
    }
}

/// `--time`: passes (one sample per pixel each) go on while the next one is expected to end
/// within the budget, judged by the slowest pass so far. The first pass is always taken.
struct TimeBudget {
    start: Instant,
    length: Duration,
    last_pass_end: Instant,
    slowest_pass: Duration,
}

impl TimeBudget {
    fn new(start: Instant, length: Duration) -> Self {
        TimeBudget {
            start,
            length,
            last_pass_end: start,
            slowest_pass: Duration::ZERO,
        }
    }

    fn length_ms(&self) -> u128 {
        self.length.as_millis()
    }

    /// Called whenever a pass has just ended.
    fn another_pass_fits(&mut self) -> bool {
        let now = Instant::now();
        self.slowest_pass = self.slowest_pass.max(now - self.last_pass_end);
        self.last_pass_end = now;
        now + self.slowest_pass <= self.start + self.length
    }
}

/// `scenes/room.toml` -> `room.png` in the current directory.
fn default_output(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    PathBuf::from(format!("{stem}.png"))
}
