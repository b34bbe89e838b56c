//! Denoising and auxiliary layers (`--denoise`, `--aov`, `wavetrace::denoise`): the layers of
//! the multi-layer EXR and their ranges, the usage errors, and, in builds with the `denoise`
//! feature, the denoiser's error against a reference and its determinism across threads.

use crate::common::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

fn room_toml() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml")
}

/// Renders the room at `side` x `side` into `output` with the extra flags.
fn render_room(side: u32, output: &Path, extra: &[&str]) -> Output {
    let side = side.to_string();
    wavetrace()
        .args(["render", "-q", "--width", &side, "--height", &side])
        .arg(room_toml())
        .arg("-o")
        .arg(output)
        .args(extra)
        .output()
        .expect("the binary runs")
}

/// Every channel of an EXR file's first layer, by name.
fn exr_channels(path: &Path) -> BTreeMap<String, Vec<f32>> {
    let image = exr::prelude::read_all_flat_layers_from_file(path).expect("readable EXR");
    let layer = &image.layer_data[0];
    layer
        .channel_data
        .list
        .iter()
        .map(|channel| {
            let values = match &channel.sample_data {
                exr::prelude::FlatSamples::F32(v) => v.clone(),
                other => panic!("{}: not f32: {other:?}", channel.name),
            };
            (channel.name.to_string(), values)
        })
        .collect()
}

fn triples(channels: &BTreeMap<String, Vec<f32>>, names: [&str; 3]) -> Vec<[f32; 3]> {
    let [a, b, c] = names.map(|n| &channels[n]);
    (0..a.len()).map(|i| [a[i], b[i], c[i]]).collect()
}

#[test]
fn aov_layers_are_written_beside_the_colour_and_lie_in_range() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.exr");
    let out = render_room(
        48,
        &output,
        &[
            "--spp",
            "2",
            "--no-denoise",
            "--aov",
            "albedo,normal,depth,noisy,spp",
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let channels = exr_channels(&output);
    let names: Vec<&str> = channels.keys().map(String::as_str).collect();
    for expected in [
        "B", "G", "R", "albedo.B", "albedo.G", "albedo.R", "depth.Z", "noisy.B", "noisy.G",
        "noisy.R", "normal.X", "normal.Y", "normal.Z", "spp.Y",
    ] {
        assert!(
            names.contains(&expected),
            "{expected} missing from {names:?}"
        );
    }
    let albedo = triples(&channels, ["albedo.R", "albedo.G", "albedo.B"]);
    assert!(albedo.iter().flatten().all(|a| (0.0..=1.0).contains(a)));
    // Unit normals and positive depths, but where every sample of a pixel escaped through a
    // crack between the room's polygons (zero normal, zero depth: a handful of pixels).
    let normal = triples(&channels, ["normal.X", "normal.Y", "normal.Z"]);
    let mut escaped = 0;
    for (n, &depth) in normal.iter().zip(&channels["depth.Z"]) {
        let length = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if length == 0.0 {
            escaped += 1;
            continue;
        }
        assert!((length - 1.0).abs() < 1e-4, "normal {n:?}");
        assert!(depth > 0.0 && depth.is_finite(), "depth {depth}");
    }
    assert!(
        escaped * 100 <= normal.len(),
        "{escaped} pixels without a normal"
    );
    assert!(channels["spp.Y"].iter().all(|&n| n == 2.0));
    // Without denoising the colour is the noisy layer.
    assert_eq!(channels["R"], channels["noisy.R"]);
    // The room's blue wall (C-D, albedo 0.15, 0.25, 0.8) shows in the albedo layer.
    let blue = albedo
        .iter()
        .filter(|a| {
            (a[0] - 0.15).abs() < 0.01 && (a[1] - 0.25).abs() < 0.01 && (a[2] - 0.8).abs() < 0.01
        })
        .count();
    assert!(blue > 20, "{blue} blue albedo pixels");
    // The colour is the image a render without layers writes, bit for bit.
    let plain = dir.path().join("plain.exr");
    let out = render_room(48, &plain, &["--spp", "2", "--no-denoise"]);
    assert!(out.status.success());
    let plain = exr_channels(&plain);
    assert_eq!(plain["R"], channels["R"]);
    assert_eq!(plain["B"], channels["B"]);
}

#[test]
fn the_variance_layer_comes_from_adaptive_sampling() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.exr");
    let flags = [
        "--spp",
        "8",
        "--noise-threshold",
        "0.05",
        "--min-spp",
        "4",
        "--no-denoise",
        "--aov",
        "variance,spp",
    ];
    let out = render_room(24, &output, &flags);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let channels = exr_channels(&output);
    assert!(
        channels["variance.G"]
            .iter()
            .all(|&v| v >= 0.0 && v.is_finite())
    );
    assert!(channels["variance.G"].iter().any(|&v| v > 0.0));
    assert!(channels["spp.Y"].iter().all(|&n| (4.0..=8.0).contains(&n)));
}

#[test]
fn bad_aov_requests_are_usage_errors_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("room.exr");
    let png = dir.path().join("room.png");
    let cases: [(&Path, &[&str], &str); 3] = [
        (&exr, &["--aov", "albedo,shiny"], "shiny"),
        (&png, &["--aov", "albedo"], "OpenEXR"),
        (&exr, &["--aov", "variance"], "adaptive sampling"),
    ];
    for (output, flags, fragment) in cases {
        let out = render_room(8, output, &[&["--spp", "1"], flags].concat());
        if let Err(problem) = check_failure(&out, 2, &[fragment]) {
            panic!("{flags:?}: {problem}");
        }
    }
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?}",
        files_in(dir.path())
    );
}

#[cfg(not(feature = "denoise"))]
#[test]
fn denoise_in_a_build_without_the_denoiser_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.png");
    let out = render_room(8, &output, &["--spp", "1", "--denoise"]);
    if let Err(problem) = check_failure(&out, 2, &["--features denoise"]) {
        panic!("{problem}");
    }
    assert!(files_in(dir.path()).is_empty());
    // --no-denoise (and no flag at all) are fine.
    let out = render_room(8, &output, &["--spp", "1", "--no-denoise"]);
    assert!(out.status.success());
}

#[cfg(feature = "denoise")]
mod with_denoiser {
    use super::*;
    use crate::image_error::image_error;
    use wavetrace::RenderSettings;
    use wavetrace::film::Layer;

    /// The "done when" figure of issue 33: the room at 256 x 256 and 16 spp, denoised as the
    /// command line denoises (all but the light seen directly), has at most 0.05x the relative
    /// MSE of the noisy image against a 4096-spp reference (committed,
    /// tests/data/denoise/room-256-4096spp.exr).
    #[test]
    fn denoising_cuts_the_relative_mse_of_the_room_twenty_fold() {
        let reference = wavetrace::output::read_exr(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/denoise/room-256-4096spp.exr"),
        )
        .unwrap();
        let settings = RenderSettings {
            width: 256,
            height: 256,
            spp: 16,
            record_aovs: true,
            ..RenderSettings::default()
        };
        let scene = room();
        let (film, _) = wavetrace::render(&scene, &settings, |_| wavetrace::Flow::Continue)
            .expect("render succeeds");
        let noisy = film.resolve();
        let albedo = film.layer(Layer::Albedo).unwrap();
        let normal = film.layer(Layer::Normal).unwrap();
        let direct = film.layer(Layer::Emission).unwrap();
        let denoised = wavetrace::denoise::denoise_except(&noisy, &direct, &albedo, &normal)
            .expect("denoises");
        let noisy_error = image_error(&noisy, &reference).unwrap();
        let denoised_error = image_error(&denoised, &reference).unwrap();
        let ratio = denoised_error.relative_mse / noisy_error.relative_mse;
        eprintln!(
            "relative MSE: noisy {:.5}, denoised {:.5} ({ratio:.4}x); MSE {:.5} -> {:.5}",
            noisy_error.relative_mse,
            denoised_error.relative_mse,
            noisy_error.mse,
            denoised_error.mse
        );
        assert!(ratio <= 0.05, "{ratio}");
    }

    #[test]
    fn denoised_images_do_not_depend_on_the_thread_count() {
        let dir = tempfile::tempdir().unwrap();
        let files: Vec<Vec<u8>> = ["1", "2", "3"]
            .iter()
            .map(|threads| {
                let output = dir.path().join(format!("t{threads}.exr"));
                let flags = ["--spp", "4", "--denoise", "--threads", threads];
                let out = render_room(64, &output, &flags);
                assert!(
                    out.status.success(),
                    "{}",
                    String::from_utf8_lossy(&out.stderr)
                );
                std::fs::read(&output).unwrap()
            })
            .collect();
        assert!(files.iter().all(|f| *f == files[0]));
        // And the denoised image differs from the noisy one.
        let noisy = dir.path().join("noisy.exr");
        let out = render_room(64, &noisy, &["--spp", "4", "--no-denoise"]);
        assert!(out.status.success());
        assert_ne!(std::fs::read(&noisy).unwrap(), files[0]);
    }
}
