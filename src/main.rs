//! The `wavetrace` command line: parses flags into `RenderSettings`, runs the library, prints
//! the summary, and maps errors to exit codes (1 for failures, 2 for usage errors).

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use wavetrace::{Flow, RenderSettings, flatten, load_scene, render, write_image};

#[derive(Parser)]
#[command(version, about = "A physically based Monte Carlo path tracer")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene file to a PNG or OpenEXR image.
    Render(RenderArgs),
    /// Reproduce the seed report's benchmark tables on the built-in room and print them next
    /// to the report's seconds.
    BenchSeed(BenchSeedArgs),
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
    /// Scene file (.toml).
    scene: PathBuf,
    /// Output image; the extension picks the format (.png: sRGB 8-bit; .exr: linear float).
    /// Default: the scene's name with .png, in the current directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Image width in pixels (default: the scene's, else 800).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (default: the scene's, else 800).
    #[arg(long)]
    height: Option<u32>,
    /// Samples per pixel (default: the scene's, else 16).
    #[arg(long)]
    spp: Option<u32>,
    /// Shadow rays per diffuse hit for next-event estimation (default: the scene's, else 1).
    #[arg(long)]
    shadow_rays: Option<u32>,
    /// Light sampling only: emitters that BSDF-sampled rays find at non-delta hits are
    /// discarded instead of being combined with the shadow rays by multiple importance sampling.
    #[arg(long)]
    no_mis: bool,
    /// Seed of the random numbers; the same seed gives the same image on any thread count.
    #[arg(long, default_value_t = wavetrace::math::rng::DEFAULT_SEED)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Exposure in stops applied before PNG encoding (EXR stays linear and unscaled).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    exposure: f32,
    /// Paths traced together per wavefront batch (affects speed and memory, never the image).
    #[arg(long, default_value_t = RenderSettings::default().batch_size)]
    batch_size: u32,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => run_render(args),
        Command::BenchSeed(args) => run_bench_seed(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run_render(args: RenderArgs) -> Result<()> {
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&args.scene));
    // Refuse a bad output name before spending time on the render.
    wavetrace::output::ImageFormat::from_path(&output)?;
    let threads = args.threads.unwrap_or(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start worker threads")?;
    pool.install(|| {
        let scene = load_scene(&args.scene)?;
        let flat = flatten(&scene.world, &args.scene)?;
        for warning in &flat.warnings {
            eprintln!("warning: {warning}");
        }
        let defaults = RenderSettings::default();
        let settings = RenderSettings {
            width: args
                .width
                .or(scene.defaults.width)
                .unwrap_or(defaults.width),
            height: args
                .height
                .or(scene.defaults.height)
                .unwrap_or(defaults.height),
            spp: args.spp.or(scene.defaults.spp).unwrap_or(defaults.spp),
            shadow_rays: args
                .shadow_rays
                .or(scene.defaults.shadow_rays)
                .unwrap_or(defaults.shadow_rays),
            mis: !args.no_mis,
            seed: args.seed,
            batch_size: args.batch_size,
            ..defaults
        };
        if settings.shadow_rays == 0 {
            anyhow::bail!("--shadow-rays must be at least 1");
        }
        settings.validate()?;

        let bar = if args.quiet {
            ProgressBar::hidden()
        } else {
            ProgressBar::new(settings.pixel_count() * settings.spp as u64)
        };
        bar.set_style(
            ProgressStyle::with_template(
                "{spinner} [{elapsed_precise}] {wide_bar} {percent}% (ETA {eta})",
            )
            .expect("valid template"),
        );
        let (film, stats) = render(&flat, &settings, |p| {
            bar.set_position(p.samples_done);
            Flow::Continue
        })?;
        bar.finish_and_clear();
        write_image(&output, &film.resolve(), args.exposure)?;
        eprintln!(
            "wavetrace: {}x{}, {} spp, {} shadow rays, {} threads -> {}",
            settings.width,
            settings.height,
            settings.spp,
            settings.shadow_rays,
            rayon::current_num_threads(),
            output.display()
        );
        eprintln!("{}", stats.summary());
        Ok(())
    })
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

/// `scenes/room.toml` -> `room.png` in the current directory.
fn default_output(scene: &Path) -> PathBuf {
    let stem = scene
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "render".into());
    PathBuf::from(format!("{stem}.png"))
}
