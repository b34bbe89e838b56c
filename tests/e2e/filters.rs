//! Pixel filters (filter importance sampling): a sharp edge is spread as the filter says, a
//! furnace stays exact under any filter, images stay independent of threads and batches, and
//! the command line gives model files Cycles' Blackman-Harris.

use crate::common::*;
use std::process::Command;
use wavetrace::settings::Adaptive;
use wavetrace::{FilterKind, PixelFilter, RenderSettings};

/// A two-sided emitter of radiance 1 filling the left half of the view (x < 0, at y = 1)
/// before a black void: on a 16-pixel-wide film its edge falls on the border of columns 7
/// and 8.
const EDGE: &str = r#"
[camera]
eye = [0, 0, 0]
look_at = [0, 1, 0]
vfov = 30
[materials]
black = { type = "diffuse", albedo = [0, 0, 0] }
[[shape]]
type = "quad"
material = "black"
emission = [1, 1, 1]
two_sided = true
vertices = [[-5, 1, -5], [0, 1, -5], [0, 1, 5], [-5, 1, 5]]
"#;

/// The analytic filter's mass below `offset` (pixels from the centre), by a fine midpoint
/// rule, independently of the renderer's tables.
fn mass_below(filter: PixelFilter, offset: f64) -> f64 {
    let w = filter.width as f64;
    let (radius, profile): (f64, Box<dyn Fn(f64) -> f64>) = match filter.kind {
        FilterKind::Box => (0.5 * w, Box::new(|_| 1.0)),
        FilterKind::Gaussian => (1.5 * w, Box::new(move |x| (-8.0 * x * x / (w * w)).exp())),
        FilterKind::BlackmanHarris => (
            w,
            Box::new(move |x| {
                let p = std::f64::consts::PI * (x / w + 1.0);
                0.35875 - 0.48829 * p.cos() + 0.14128 * (2.0 * p).cos() - 0.01168 * (3.0 * p).cos()
            }),
        ),
    };
    let integral = |a: f64, b: f64| {
        let n = 20_000;
        let h = (b - a) / n as f64;
        (0..n)
            .map(|i| profile(a + (i as f64 + 0.5) * h))
            .sum::<f64>()
            * h
    };
    integral(-radius, offset.clamp(-radius, radius)) / integral(-radius, radius)
}

/// The mean of column `x` of `image` (red channel).
fn column_mean(image: &wavetrace::Image, x: u32) -> f64 {
    (0..image.height)
        .map(|y| image.at(x, y).x as f64)
        .sum::<f64>()
        / image.height as f64
}

#[test]
fn a_sharp_edge_spreads_as_the_filter_says() {
    let scene = scene_from_toml(EDGE);
    let spp = 256;
    let render = |filter| {
        render_image(
            &scene,
            &RenderSettings {
                width: 16,
                height: 8,
                spp,
                filter,
                ..Default::default()
            },
        )
    };
    // The box of 1 px keeps the edge: every sample stays in its pixel.
    let sharp = render(PixelFilter::BOX);
    assert_eq!(column_mean(&sharp, 7), 1.0);
    assert_eq!(column_mean(&sharp, 8), 0.0);
    for filter in [
        PixelFilter::CYCLES,
        PixelFilter {
            kind: FilterKind::Gaussian,
            width: 1.5,
        },
        PixelFilter {
            kind: FilterKind::Box,
            width: 2.0,
        },
    ] {
        let image = render(filter);
        assert_finite(&image);
        // Each sample of column 8 (centre 8.5) sees the emitter when its offset is below
        // -0.5: a Bernoulli mean over 8 rows x spp samples.
        for (column, centre) in [(6u32, 6.5f64), (7, 7.5), (8, 8.5), (9, 9.5)] {
            let p = mass_below(filter, 8.0 - centre);
            let error = (p * (1.0 - p) / (8 * spp) as f64).sqrt().max(1e-4);
            let mean = column_mean(&image, column);
            eprintln!("{filter:?}: column {column}: {mean:.4} vs {p:.4} (error {error:.1e})");
            assert!(
                (mean - p).abs() <= 4.0 * error,
                "{filter:?}: column {column} is {mean}, the filter says {p}"
            );
        }
        assert!(column_mean(&image, 8) > 0.02, "{filter:?} softens the edge");
    }
}

#[test]
fn a_furnace_stays_exact_under_any_filter() {
    // A closed sphere of albedo 0.5 emitting 0.5: radiance 1 everywhere.
    let scene = scene_from_toml(
        r#"
[camera]
eye = [0.1, 0.2, -0.1]
look_at = [1, 0.3, 0.2]
vfov = 100
[materials]
wall = { type = "diffuse", albedo = [0.5, 0.5, 0.5] }
[[shape]]
type = "sphere"
material = "wall"
center = [0, 0, 0]
radius = 2
emission = [0.5, 0.5, 0.5]
two_sided = true
"#,
    );
    for filter in [
        PixelFilter::CYCLES,
        PixelFilter {
            kind: FilterKind::Gaussian,
            width: 3.0,
        },
    ] {
        let image = render_image(
            &scene,
            &RenderSettings {
                width: 48,
                height: 48,
                spp: 8,
                filter,
                ..Default::default()
            },
        );
        assert_finite(&image);
        let values: Vec<f64> = image.pixels.iter().map(|p| p.x as f64).collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let error = sd / n.sqrt();
        eprintln!("{filter:?}: furnace mean {mean:.5} (error {error:.1e})");
        assert!(error < 0.01, "the test detects a 1% bias");
        assert!((mean - 1.0).abs() < 4.0 * error, "{filter:?}: {mean}");
    }
}

#[test]
fn filtered_images_do_not_depend_on_threads_or_batches() {
    let scene = room();
    let base = RenderSettings {
        width: 40,
        height: 32,
        spp: 3,
        filter: PixelFilter::CYCLES,
        caustic_paths: 1.0,
        ..Default::default()
    };
    let (one, stats) = render_with_threads(&scene, &base, 1);
    let (three, _) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 333,
            ..base
        },
        3,
    );
    assert!(stats.light_rays > 0, "light paths were traced");
    assert!(
        one == three,
        "threads or batches changed the filtered image"
    );
    let adaptive = RenderSettings {
        spp: 6,
        adaptive: Some(Adaptive {
            noise_threshold: 0.5,
            min_spp: 2,
            denoised: None,
        }),
        sampler: wavetrace::math::rng::Sampler::Sobol,
        ..base
    };
    let (one, _) = render_with_threads(&scene, &adaptive, 1);
    let (two, _) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 100,
            ..adaptive
        },
        2,
    );
    assert!(
        one == two,
        "adaptive Sobol with a filter changed with threads"
    );
    let (boxed, _) = render_with_threads(
        &scene,
        &RenderSettings {
            filter: PixelFilter::BOX,
            ..base
        },
        2,
    );
    assert!(boxed != one, "the filter has an effect");
}

/// Renders `model` through the binary at a tiny size with `extra` flags; the EXR's bytes.
fn render_model(model: &str, extra: &[&str]) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("image.exr");
    let out = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "render", "-q", model, "--width", "24", "--height", "16", "--spp", "2",
        ])
        .args(extra)
        .arg("-o")
        .arg(&image)
        .output()
        .expect("the binary runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::read(&image).unwrap()
}

#[test]
fn model_files_take_cycles_filter_and_scene_files_the_box() {
    let model = "assets/suzanne.glb";
    let default = render_model(model, &[]);
    assert_eq!(
        default,
        render_model(
            model,
            &["--filter", "blackman-harris", "--filter-width", "1.5"]
        )
    );
    assert_ne!(default, render_model(model, &["--filter", "box"]));
    let scene = "scenes/room.toml";
    assert_eq!(
        render_model(scene, &[]),
        render_model(scene, &["--filter", "box", "--filter-width", "1"])
    );
}
