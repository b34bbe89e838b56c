//! The command line's render-farm glue: `render --part K/N` (the part's identity, its file)
//! and `wavetrace slurm` (its flags, read by hand because the render flags pass through).

use super::{Cli, RenderArgs, signal_name};
use anyhow::{Context, Result, bail};
use clap::Parser;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;
use wavetrace::farm::parts::PartHeader;
use wavetrace::farm::slurm::{self, Split, Submission};
use wavetrace::farm::{PartIndex, fnv1a64, part_rows, write_part};
use wavetrace::scene::load::LoadOptions;
use wavetrace::{Film, RenderSettings, RenderStats};

/// A render of one part of a frame (`--part K/N`).
pub struct PartRender {
    /// The part's pixel rows.
    pub rows: Range<u32>,
    header: PartHeader,
}

impl PartRender {
    /// Checks that the render stops at a fixed sample count and builds the part's identity:
    /// the program's version, the scene file's fingerprint, the load options and every
    /// resolved setting that affects the pixels (the batch size does not).
    pub fn new(
        part: PartIndex,
        args: &RenderArgs,
        options: &LoadOptions,
        settings: &RenderSettings,
        time_budget: Option<Duration>,
    ) -> Result<Self> {
        if time_budget.is_some() {
            bail!(
                "--part {part}: a part must stop at a fixed number of samples, the same on \
                 every machine; give --spp (a render without --spp and without the scene's \
                 spp stops after at most a minute)"
            );
        }
        let rows = part_rows(settings.height, part)?;
        let scene_bytes = std::fs::read(&args.scene)
            .with_context(|| format!("{}: cannot read", args.scene.display()))?;
        let scene_name = args
            .scene
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let pixel_settings = RenderSettings {
            batch_size: 0,
            ..*settings
        };
        let identity = format!(
            "wavetrace {}\nscene {scene_name}, {} bytes, fnv1a64 {:016x}\nload {options:?}\n\
             settings {pixel_settings:?}\nexposure {}\nframe {:?} at {} fps, animation {:?}",
            env!("CARGO_PKG_VERSION"),
            scene_bytes.len(),
            fnv1a64(&scene_bytes),
            args.exposure,
            args.frame,
            args.fps,
            args.animation
        );
        Ok(PartRender {
            rows,
            header: PartHeader {
                part,
                width: settings.width,
                height: settings.height,
                identity,
                exposure: args.exposure,
            },
        })
    }

    /// Writes the part's file, unless a signal stopped the render early: a part holds all of
    /// its samples or does not exist.
    pub fn finish(
        &self,
        output: &Path,
        film: &Film,
        stats: &RenderStats,
        signal: Option<i32>,
        quiet: bool,
    ) -> Result<ExitCode> {
        if let Some(signal) = signal
            && stats.interrupted
        {
            eprintln!(
                "wavetrace: stopped early by {}; part {} not written (a part must hold all its \
                 samples)",
                signal_name(signal),
                self.header.part
            );
            return Ok(ExitCode::from(128 + signal as u8));
        }
        write_part(output, &self.header, film)?;
        if !quiet {
            eprintln!(
                "wavetrace: part {} of {}x{} (rows {}..{}), {}-{} spp -> {}",
                self.header.part,
                self.header.width,
                self.header.height,
                self.rows.start,
                self.rows.end,
                stats.spp_min,
                stats.spp_max,
                output.display()
            );
            eprintln!("{}", stats.summary());
        }
        Ok(ExitCode::SUCCESS)
    }
}

const SLURM_USAGE: &str = "Usage: wavetrace slurm SCENE [render flags] (--parts N | --frames A-B[:STEP] \
     [--frames-per-task M]) -o OUT [--sbatch ARG]... [--wait]";

/// `wavetrace slurm`'s request, read from its arguments.
struct SlurmRequest {
    scene: PathBuf,
    render_flags: Vec<String>,
    split: Split,
    output: PathBuf,
    sbatch_args: Vec<String>,
    wait: bool,
}

/// Reads `wavetrace slurm`'s arguments: SCENE first, then our flags among the render flags,
/// which pass through to `wavetrace render` unchanged. A usage error is an `Err(message)`.
fn parse_slurm_args(args: &[String]) -> std::result::Result<SlurmRequest, String> {
    let mut words = args.iter();
    let scene = match words.next() {
        Some(scene) if !scene.starts_with('-') => PathBuf::from(scene),
        _ => return Err("the first argument must be the scene file".into()),
    };
    let (mut parts, mut frames, mut per_task, mut output) = (None, None, None, None);
    let (mut render_flags, mut sbatch_args, mut wait) = (Vec::new(), Vec::new(), false);
    while let Some(word) = words.next() {
        let (flag, inline) = match word.split_once('=') {
            Some((flag, value)) if flag.starts_with("--") => (flag, Some(value.to_string())),
            _ => (word.as_str(), None),
        };
        let mut value = || {
            inline
                .clone()
                .or_else(|| words.next().cloned())
                .ok_or_else(|| format!("{flag} needs a value"))
        };
        match flag {
            "--parts" => {
                let n: u32 = value()?
                    .parse()
                    .map_err(|_| "--parts needs a whole number of at least 1".to_string())?;
                if n == 0 {
                    return Err("--parts needs a whole number of at least 1".into());
                }
                parts = Some(n);
            }
            "--frames" => frames = Some(slurm::parse_frame_range(&value()?)?),
            "--frames-per-task" => {
                per_task = Some(
                    value()?
                        .parse::<u32>()
                        .ok()
                        .filter(|&m| m > 0)
                        .ok_or("--frames-per-task needs a whole number of at least 1")?,
                );
            }
            "-o" | "--output" => output = Some(PathBuf::from(value()?)),
            "--sbatch" => sbatch_args.push(value()?),
            "--wait" => wait = true,
            "--part" => {
                return Err("--part is set per task by `wavetrace slurm`; use --parts N".into());
            }
            _ => render_flags.push(word.clone()),
        }
    }
    let output = output.ok_or("-o OUT is required")?;
    let split = match (parts, frames) {
        (Some(n), None) => Split::Parts(n),
        (None, Some((first, last, step))) => Split::Frames {
            first,
            last,
            step,
            per_task: per_task.unwrap_or(1),
        },
        _ => return Err("give either --parts N or --frames A-B[:STEP]".into()),
    };
    if per_task.is_some() && parts.is_some() {
        return Err("--frames-per-task goes with --frames, not --parts".into());
    }
    Ok(SlurmRequest {
        scene,
        render_flags,
        split,
        output,
        sbatch_args,
        wait,
    })
}

/// `wavetrace slurm`: checks the request, submits the jobs, prints their ids, and with
/// `--wait` waits for them.
pub fn run_slurm(args: Vec<String>) -> Result<ExitCode> {
    if args.iter().any(|a| a == "--help" || a == "-h") {
        println!("{SLURM_USAGE}\n\nSee `wavetrace help slurm` and docs/farm.md.");
        return Ok(ExitCode::SUCCESS);
    }
    let request = match parse_slurm_args(&args) {
        Ok(request) => request,
        Err(message) => {
            eprintln!("error: {message}\n\n{SLURM_USAGE}");
            return Ok(ExitCode::from(2));
        }
    };
    if let Some(code) = check_render_flags(&request) {
        return Ok(code);
    }
    let workdir = std::env::current_dir().context("cannot read the current directory")?;
    let absolute = |path: &Path| workdir.join(path);
    let output = absolute(&request.output);
    match request.split {
        Split::Parts(_) => wavetrace::output::check_writable(&output)?,
        Split::Frames { .. } => {
            if !output.to_string_lossy().contains('#') {
                eprintln!(
                    "error: {}: with --frames the output name needs a run of # for the frame \
                     number (e.g. shot-####.png)\n\n{SLURM_USAGE}",
                    request.output.display()
                );
                return Ok(ExitCode::from(2));
            }
        }
    }
    let mut render_flags = request.render_flags.clone();
    if !render_flags.iter().any(|f| f == "--quiet" || f == "-q") {
        render_flags.push("--quiet".into());
    }
    let submission = Submission {
        program: std::env::current_exe().context("cannot find the running wavetrace binary")?,
        scene: absolute(&request.scene),
        render_flags,
        output,
        split: request.split,
        sbatch_args: request.sbatch_args,
        workdir: workdir.clone(),
    };
    let jobs = slurm::submit(&submission)?;
    println!(
        "wavetrace: job array {} ({} tasks), logs in {}",
        jobs.array,
        submission.split.task_count(),
        submission.folder().display()
    );
    if let Some(merge) = &jobs.merge {
        println!(
            "wavetrace: merge job {merge} (after {}) -> {}",
            jobs.array,
            submission.output.display()
        );
    }
    if request.wait {
        slurm::wait(&submission, &jobs)?;
        println!("wavetrace: all jobs completed");
    }
    Ok(ExitCode::SUCCESS)
}

/// Checks the render flags as `wavetrace render` would read them, before anything is
/// submitted: a usage error prints clap's message and gives exit code 2.
fn check_render_flags(request: &SlurmRequest) -> Option<ExitCode> {
    let mut words: Vec<String> = vec!["wavetrace".into(), "render".into()];
    words.push(request.scene.to_string_lossy().into_owned());
    words.extend(request.render_flags.iter().cloned());
    words.extend(["-o".into(), "check.exr".into()]);
    if let Split::Parts(n) = request.split {
        words.extend(["--part".into(), format!("0/{n}")]);
        if !request
            .render_flags
            .iter()
            .any(|f| f == "--spp" || f.starts_with("--spp="))
        {
            eprintln!(
                "error: --parts needs --spp: a frame split in parts must stop at a fixed \
                 number of samples\n\n{SLURM_USAGE}"
            );
            return Some(ExitCode::from(2));
        }
    }
    match Cli::try_parse_from(words) {
        Ok(_) => None,
        Err(e) => {
            let _ = e.print();
            Some(ExitCode::from(2))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn words(text: &str) -> Vec<String> {
        text.split_whitespace().map(String::from).collect()
    }

    #[test]
    fn slurm_flags_are_taken_out_and_render_flags_pass_through() {
        let request = parse_slurm_args(&words(
            "room.toml --width 64 --parts 4 --spp=8 -o farm.exr --sbatch --time=5 --wait",
        ))
        .unwrap();
        assert_eq!(request.scene, PathBuf::from("room.toml"));
        assert_eq!(request.render_flags, words("--width 64 --spp=8"));
        assert_eq!(request.split, Split::Parts(4));
        assert_eq!(request.sbatch_args, ["--time=5"]);
        assert!(request.wait);
        for bad in [
            "--parts 4 -o x.exr",
            "room.toml --parts 0 -o x.exr",
            "room.toml --parts 4",
            "room.toml -o x.exr",
            "room.toml --parts 2 --frames 1-3 -o x.exr",
            "room.toml --frames 3-1 -o x.exr",
            "room.toml --parts 2 --part 0/2 -o x.exr",
        ] {
            assert!(parse_slurm_args(&words(bad)).is_err(), "{bad}");
        }
    }
}
