//! Adaptive sampling (`settings::Adaptive`): deterministic, unbiased within statistics,
//! spending fewer samples where the image is flat, and off (bit for bit) with a fixed count.

use crate::common::*;
use std::process::Command;
use wavetrace::settings::Adaptive;
use wavetrace::{Flow, RenderSettings, render};

fn adaptive(noise_threshold: f32, min_spp: u32) -> Option<Adaptive> {
    Some(Adaptive {
        noise_threshold,
        min_spp,
        denoised: None,
    })
}

/// A lit box seen through its open side: the background around it is black (no sample
/// varies there), the walls are noisy.
fn open_box() -> wavetrace::RenderScene {
    scene_from_toml(
        &BoxScene {
            camera: "eye = [0, -4.5, 0]\nlook_at = [0, 0, 0]\nvfov = 45",
            materials: r#"
white = { type = "diffuse", albedo = [0.7, 0.7, 0.7] }
red = { type = "diffuse", albedo = [0.7, 0.1, 0.1] }
black = { type = "diffuse", albedo = [0, 0, 0] }"#,
            walls: [
                Some("white"),
                Some("red"),
                Some("white"),
                Some("white"),
                Some("white"),
                None,
            ],
            light_half: 0.4,
            light_radiance: 4.0,
            extra_shapes: "",
        }
        .toml(),
    )
}

#[test]
fn adaptive_images_do_not_depend_on_threads_or_batches() {
    // The open box: its black surroundings stop at the minimum, its walls go on (in the
    // room at 0.05 no tile stops by 48 spp).
    let scene = open_box();
    let settings = RenderSettings {
        width: 48,
        height: 40,
        spp: 48,
        adaptive: adaptive(0.05, 8),
        batch_size: 700,
        ..Default::default()
    };
    let (one, s1) = render_with_threads(&scene, &settings, 1);
    let (two, s2) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 4096,
            ..settings
        },
        2,
    );
    assert_finite(&one);
    assert!(
        one == two,
        "threads or batch size changed the adaptive image"
    );
    assert_eq!(
        (s1.spp_min, s1.spp_mean, s1.spp_max, s1.samples),
        (s2.spp_min, s2.spp_mean, s2.spp_max, s2.samples)
    );
    assert!(
        s1.spp_min < s1.spp_max,
        "some tiles stop early, others go on: {} {}",
        s1.spp_min,
        s1.spp_max
    );
}

#[test]
fn adaptive_image_mean_agrees_with_the_fixed_sample_image() {
    // Adaptive stopping reads each tile's own samples, so it is biased in theory (Cycles
    // accepts that); at this threshold the bias must stay below the statistical resolution.
    let scene = room();
    let base = RenderSettings {
        width: 32,
        height: 32,
        ..Default::default()
    };
    let fixed = estimate(&scene, &RenderSettings { spp: 64, ..base });
    let adaptive_estimate = estimate(
        &scene,
        &RenderSettings {
            spp: 64,
            adaptive: adaptive(0.05, 8),
            ..base
        },
    );
    assert!(
        fixed.1.iter().zip(fixed.0).all(|(e, m)| *e < 0.01 * m),
        "the test resolves a 1% difference: {fixed:?}"
    );
    assert_agree("room, adaptive vs fixed", adaptive_estimate, fixed, 4.0);
}

#[test]
fn flat_regions_stop_at_the_minimum_and_noisy_ones_go_on() {
    let scene = open_box();
    let (width, height) = (64u32, 64u32);
    let settings = RenderSettings {
        width,
        height,
        spp: 64,
        adaptive: adaptive(0.02, 8),
        ..Default::default()
    };
    let (film, _) = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap()
        .install(|| render(&scene, &settings, |_| Flow::Continue))
        .unwrap();
    // Flat pixels: the same value under two seeds at 4 spp (the black background).
    let fixed = |seed| {
        render_image(
            &scene,
            &RenderSettings {
                spp: 4,
                seed,
                adaptive: None,
                ..settings
            },
        )
    };
    let (a, b) = (fixed(1), fixed(2));
    let tile_is_flat = |tx: u32, ty: u32| {
        (ty * 8..ty * 8 + 8).all(|y| (tx * 8..tx * 8 + 8).all(|x| a.at(x, y) == b.at(x, y)))
    };
    let (mut flat, mut noisy) = (Vec::new(), Vec::new());
    for ty in 0..height / 8 {
        for tx in 0..width / 8 {
            let spp = film.pixel_samples((ty * 8 * width + tx * 8) as usize);
            if tile_is_flat(tx, ty) {
                flat.push(spp);
            } else {
                noisy.push(spp);
            }
        }
    }
    assert!(!flat.is_empty() && !noisy.is_empty(), "{flat:?} {noisy:?}");
    assert!(
        flat.iter().all(|&n| n == 8),
        "flat tiles stop at the minimum: {flat:?}"
    );
    let mean_noisy = noisy.iter().sum::<u32>() as f64 / noisy.len() as f64;
    assert!(
        mean_noisy > 16.0,
        "noisy tiles take more samples: {noisy:?}"
    );
}

#[test]
fn a_fixed_sample_count_is_unchanged_by_the_adaptive_machinery() {
    // Adaptive sampling whose threshold no tile reaches traces every pixel's samples in the
    // same order as the fixed count: the same image, bit for bit.
    let scene = room();
    let fixed = RenderSettings {
        width: 40,
        height: 24,
        spp: 6,
        ..Default::default()
    };
    let (image, stats) = render_with_threads(&scene, &fixed, 2);
    let (never_stops, _) = render_with_threads(
        &scene,
        &RenderSettings {
            adaptive: adaptive(1e-30, 2),
            ..fixed
        },
        2,
    );
    assert!(image == never_stops);
    assert!(!stats.adaptive);
    // The command line's --spp renders exactly that (the library's fixed-count image).
    let dir = std::env::temp_dir().join(format!("wavetrace-adaptive-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("fixed.exr");
    let out = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render", "--quiet", "--width", "40", "--height", "24", "--spp", "6",
        ])
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml"))
        .arg("-o")
        .arg(&exr)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let written = wavetrace::output::read_exr(&exr).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(written == image, "--spp renders the fixed-count image");
}

#[test]
fn the_summary_reports_the_spread_of_samples() {
    let dir = std::env::temp_dir().join(format!("wavetrace-summary-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render", "--width", "32", "--height", "32", "--spp", "24"])
        .args(["--noise-threshold", "0.05", "--min-spp", "4"])
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml"))
        .arg("-o")
        .arg(dir.join("a.png"))
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let summary = stderr
        .split("adaptive: spp min ")
        .nth(1)
        .unwrap_or_else(|| panic!("no spread of samples in: {stderr}"));
    let numbers: Vec<f64> = summary
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter(|t| !t.is_empty())
        .take(3)
        .map(|t| t.parse().unwrap())
        .collect();
    let (min, mean, max) = (numbers[0], numbers[1], numbers[2]);
    assert!(
        4.0 <= min && min <= mean && mean <= max && max <= 24.0,
        "{summary}"
    );
}

#[test]
fn a_time_budget_bounds_an_adaptive_render() {
    // No sample count: adaptive up to no limit but the time (or the threshold, which the room
    // does not reach at 1e-4 in 2 s).
    let dir = std::env::temp_dir().join(format!("wavetrace-adaptive-time-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let start = std::time::Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render", "--width", "16", "--height", "16", "--time", "2s"])
        .args(["--noise-threshold", "0.0001", "--min-spp", "2"])
        .arg(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml"))
        .arg("-o")
        .arg(dir.join("a.exr"))
        .output()
        .unwrap();
    let elapsed = start.elapsed();
    let written = wavetrace::output::read_exr(&dir.join("a.exr"));
    std::fs::remove_dir_all(&dir).ok();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("adaptive"), "{stderr}");
    // The budget is 2 s: allow for start-up and the write, not another budget.
    assert!(
        elapsed < std::time::Duration::from_secs(4),
        "{elapsed:?}: {stderr}"
    );
    let image = written.unwrap();
    assert_eq!((image.width, image.height), (16, 16));
}
