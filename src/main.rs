//! The `wavetrace` command line: parses flags into `RenderSettings`, runs the library, prints
//! the summary, and maps errors to exit codes: 0 done, 1 failure (bad input, unwritable
//! output), 2 usage error (clap), 128 + signal number when SIGINT or SIGTERM stopped the render
//! early (the image of the samples taken so far is still written).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use signal_hook::consts::{SIGINT, SIGTERM};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicI32, AtomicUsize, Ordering};
use std::time::{Duration, Instant};
use wavetrace::scene::EnvironmentSource;
use wavetrace::scene::load::{
    EnvironmentOverrides, LightUnits, LoadOptions, Placement, UpAxis, dark_image_warning,
    is_model_file, load_scene_placed,
};
use wavetrace::settings::{MAX_IMAGE_SIDE, MAX_SHADOW_RAYS};
use wavetrace::{
    Film, Flow, RenderOverrides, RenderSettings, RenderStats, flatten, render, render_rows,
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
    /// else independent).
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
    #[arg(long, value_name = "K/N", conflicts_with = "time")]
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

fn run_render(args: RenderArgs) -> Result<ExitCode> {
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&args.scene));
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
        let (scene, placement) = load_scene_placed(&args.scene, &options)?;
        wavetrace::internals::trace_phase("loaded");
        // Refuse an unwritable output before spending time on the render.
        match args.part {
            Some(_) => wavetrace::farm::parts::check_part_writable(&output)?,
            None => wavetrace::output::check_writable(&output)?,
        }
        let flat = flatten(&scene.world, &args.scene)?;
        // The render reads only the render scene: the world's meshes (18 bytes a triangle
        // at least) are freed before the render allocates its film and buffers.
        drop(scene.world);
        wavetrace::internals::trace_phase("flattened");
        for warning in scene.warnings.iter().chain(flat.warnings()) {
            eprintln!("warning: {warning}");
        }
        if !args.quiet {
            eprintln!(
                "wavetrace: {} primitives, BVH built in {:.1} ms (the scene flattened in {:.1} ms)",
                flat.primitive_count(),
                flat.flatten_times().bvh_build.as_secs_f64() * 1e3,
                flat.flatten_times().total.as_secs_f64() * 1e3
            );
        }
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
        };
        let mut settings =
            RenderSettings::resolve(&scene.defaults, &overrides, flat.camera().aspect_ratio);
        if args.time.is_some() && args.spp.is_none() {
            // With a time budget and no sample count, the budget decides (and the noise
            // threshold, if adaptive).
            settings.spp = u32::MAX;
        }
        settings.validate()?;
        // A default render stops at the noise threshold, 1024 spp or a minute.
        let time_budget = match (args.time, settings.adaptive, args.spp) {
            (Some(budget), _, _) => Some(budget),
            (None, Some(_), None) if scene.defaults.spp.is_none() => Some(ADAPTIVE_TIME_CAP),
            _ => None,
        };
        let part = match args.part {
            Some(part) => Some(farm_cli::PartRender::new(part, &args, &options, &settings, time_budget)?),
            None => None,
        };
        let rows = part.as_ref().map_or(0..settings.height, |p| p.rows.clone());

        if let Some(signal) = received(&stop_signal) {
            eprintln!("wavetrace: {} before rendering; no image written", signal_name(signal));
            return Ok(ExitCode::from(128 + signal as u8));
        }
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
        if !args.quiet {
            eprintln!(
                "wavetrace: rendering {} at {}x{}, {} (Ctrl-C stops and writes the image so far)",
                args.scene.display(),
                settings.width,
                settings.height,
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
                    (Some(t), None) if settings.spp == u32::MAX => format!("for {}", humantime::format_duration(t)),
                    (Some(t), None) => format!("up to {} spp for {}", settings.spp, humantime::format_duration(t)),
                    (None, None) => format!("{} spp", settings.spp),
                }
            );
        }
        let start = Instant::now();
        let mut budget = time_budget.map(|b| TimeBudget::new(start, b));
        let (film, stats) = render_rows(&flat, &settings, rows, |p| {
            let pass_ended = p.pass_ended;
            match &budget {
                Some(b) => bar.set_position(start.elapsed().as_millis().min(b.length_ms()) as u64),
                None => {
                    bar.set_length(p.samples_total);
                    bar.set_position(p.samples_done);
                }
            }
            if received(&stop_signal).is_some() {
                return Flow::Stop;
            }
            let out_of_time = match &mut budget {
                Some(b) => pass_ended && !b.another_pass_fits(),
                None => false,
            };
            if out_of_time { Flow::Stop } else { Flow::Continue }
        })?;
        bar.finish_and_clear();

        if let Some(part) = &part {
            return part.finish(&output, &film, &stats, received(&stop_signal), args.quiet);
        }
        write_output(&output, &film, args.exposure)?;
        if placement == Placement::AsIs
            && let Some(warning) = dark_image_warning(&film.resolve(), args.exposure)
        {
            eprintln!("warning: {warning}");
        }
        if !args.quiet {
            eprintln!(
                "wavetrace: {}x{}, {}, {} shadow rays, {} threads -> {}",
                settings.width,
                settings.height,
                samples_held(&stats, settings.pixel_count()),
                settings.shadow_rays,
                rayon::current_num_threads(),
                output.display()
            );
        }
        if !args.quiet {
            eprintln!("{}", stats.summary());
        }
        Ok(match received(&stop_signal) {
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
    })
}

/// Writes the film as the output image: the render and the merge of a frame's parts end
/// here, so that both write the same bytes from the same film.
fn write_output(output: &Path, film: &Film, exposure: f32) -> Result<()> {
    write_image(output, film, exposure)?;
    Ok(())
}

/// `wavetrace merge`: the parts' film, checked whole, written as the render would.
fn run_merge(args: MergeArgs) -> Result<()> {
    wavetrace::output::check_writable(&args.output)?;
    let merged = wavetrace::farm::merge_parts(&args.parts)?;
    write_output(&args.output, &merged.film, merged.exposure)?;
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
