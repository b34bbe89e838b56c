//! The environment light: a white furnace (a lone diffuse sphere under a uniform sky has
//! radiance albedo x sky, since a convex object sees only the sky), light sampling only vs
//! BSDF sampling only vs MIS on a map with a small, very bright sun, `--env-hidden`, and bad
//! environment input refused with an error naming the file.

use crate::common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use wavetrace::{Image, RenderScene, RenderSettings, flatten, scene::load::load_scene_str};

/// A diffuse sphere of radius 1 at the origin seen from 4 m away, under `environment` (the
/// body of an `[environment]` table).
fn sphere_under(albedo: f32, environment: &str) -> String {
    format!(
        r#"
[camera]
eye = [0, -4, 0]
look_at = [0, 0, 0]
vfov = 40
[materials.grey]
type = "diffuse"
albedo = [{albedo}, {albedo}, {albedo}]
[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 1
material = "grey"
[environment]
{environment}
"#
    )
}

/// A scene from TOML text standing in `dir` (so that `file = ...` resolves there).
fn scene_in(dir: &Path, text: &str) -> RenderScene {
    let path = dir.join("scene.toml");
    let scene = load_scene_str(&path, text).expect("test scene loads");
    flatten(&scene.world, &path).expect("test scene flattens")
}

/// A fresh directory for one test's files.
fn test_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("environment-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const SIDE: u32 = 32;

/// Pixels whose centre is within `radius` pixels of the image centre (`inside`), or farther
/// than `radius` (`!inside`).
fn pixels_by_distance(radius: f32, inside: bool) -> Vec<usize> {
    let c = SIDE as f32 / 2.0;
    (0..(SIDE * SIDE) as usize)
        .filter(|&i| {
            let (x, y) = (
                (i as u32 % SIDE) as f32 + 0.5,
                (i as u32 / SIDE) as f32 + 0.5,
            );
            (((x - c).powi(2) + (y - c).powi(2)).sqrt() < radius) == inside
        })
        .collect()
}

/// Mean of the pixels `which` over two renders and its standard error (from their difference).
fn region_mean(a: &Image, b: &Image, which: &[usize]) -> ([f64; 3], [f64; 3]) {
    let n = which.len() as f64;
    let mut mean = [0.0; 3];
    let mut var = [0.0; 3];
    for &i in which {
        for c in 0..3 {
            let (x, y) = (a.pixels[i][c] as f64, b.pixels[i][c] as f64);
            mean[c] += (x + y) / 2.0 / n;
            var[c] += (x - y) * (x - y) / 4.0;
        }
    }
    (mean, var.map(|v| v.sqrt() / n))
}

fn two_renders(scene: &RenderScene, settings: &RenderSettings) -> (Image, Image) {
    let a = render_image(scene, settings);
    let b = render_image(
        scene,
        &RenderSettings {
            seed: settings.seed ^ 0x5DEE_CE66_D1CE_4E5B,
            ..*settings
        },
    );
    assert_finite(&a);
    assert_finite(&b);
    (a, b)
}

#[test]
fn white_furnace_diffuse_sphere_under_a_uniform_sky() {
    // The sphere spans about 11.4 pixels of radius: within 9 it covers the pixel, beyond 14
    // it does not touch it.
    let (sphere, sky) = (
        pixels_by_distance(9.0, true),
        pixels_by_distance(14.0, false),
    );
    for albedo in [0.5f32, 0.9] {
        let scene = scene_from_toml(&sphere_under(albedo, "color = [1, 1, 1]"));
        for (shadow_rays, mis) in [(1, true), (4, true), (1, false), (0, false)] {
            let settings = RenderSettings {
                width: SIDE,
                height: SIDE,
                spp: 32,
                shadow_rays,
                mis,
                ..Default::default()
            };
            let (a, b) = two_renders(&scene, &settings);
            // Camera rays that miss see the sky exactly.
            for &i in &sky {
                assert_eq!(a.pixels[i], [1.0; 3].into(), "sky pixel {i}");
            }
            let (mean, error) = region_mean(&a, &b, &sphere);
            let what = format!("albedo {albedo}, {shadow_rays} shadow rays, mis {mis}");
            let expected = albedo as f64;
            for c in 0..3 {
                eprintln!(
                    "{what}: {:.5} +- {:.1e} (expected {expected})",
                    mean[c], error[c]
                );
                assert!(
                    error[c] < 0.01,
                    "{what}: error {} too large to test",
                    error[c]
                );
                assert!(
                    (mean[c] - expected).abs() <= 4.0 * error[c].max(1e-6),
                    "{what}: channel {c} is {} +- {}, expected {expected}",
                    mean[c],
                    error[c]
                );
            }
        }
    }
}

/// Writes a 64 x 32 map: a dim blue-grey sky, a dark ground, and a sun of 2 x 2 texels
/// 20 000 times brighter than the sky, high in the sky toward +X.
fn write_sun_map(path: &Path) {
    let (w, h) = (64usize, 32usize);
    let mut texels = Vec::with_capacity(w * h * 3);
    for row in 0..h {
        for col in 0..w {
            let rgb = if (6..8).contains(&row) && (31..33).contains(&col) {
                [2000.0, 1800.0, 1500.0]
            } else if row < h / 2 {
                [0.08, 0.1, 0.15]
            } else {
                [0.03, 0.03, 0.02]
            };
            texels.extend(rgb);
        }
    }
    image::Rgb32FImage::from_raw(w as u32, h as u32, texels)
        .unwrap()
        .save_with_format(path, image::ImageFormat::Hdr)
        .unwrap();
}

#[test]
fn light_bsdf_and_mis_sampling_agree_under_a_sun_map() {
    let dir = test_dir("sun");
    write_sun_map(&dir.join("sun.hdr"));
    // A diffuse floor with a sphere on it, seen from above at a slant; the sky is not in view.
    let text = r#"
[camera]
eye = [-3, -3, 3]
look_at = [0, 0, 0]
vfov = 30
[materials.floor]
type = "diffuse"
albedo = [0.6, 0.6, 0.6]
[materials.ball]
type = "diffuse"
albedo = [0.8, 0.5, 0.3]
[[shape]]
type = "quad"
material = "floor"
vertices = [[-20, -20, 0], [20, -20, 0], [20, 20, 0], [-20, 20, 0]]
[[shape]]
type = "sphere"
center = [0, 0, 0.5]
radius = 0.5
material = "ball"
[environment]
file = "sun.hdr"
strength = 0.5
rotation = 30
"#;
    let scene = scene_in(&dir, text);
    let base = RenderSettings {
        width: 24,
        height: 24,
        ..Default::default()
    };
    let run = |spp, shadow_rays, mis| {
        let (a, b) = two_renders(
            &scene,
            &RenderSettings {
                spp,
                shadow_rays,
                mis,
                ..base
            },
        );
        mean_and_error(&a, &b)
    };
    let light_only = run(64, 1, false);
    let bsdf_only = run(1024, 0, false);
    let mis = run(64, 1, true);
    let mis4 = run(16, 4, true);
    for (name, (_, error)) in [("light", &light_only), ("bsdf", &bsdf_only), ("mis", &mis)] {
        eprintln!("{name}: relative error {:.3}", error[0] / light_only.0[0]);
    }
    assert_agree("mis vs light only", mis, light_only, 4.0);
    assert_agree("mis vs bsdf only", mis, bsdf_only, 4.0);
    assert_agree("light vs bsdf only", light_only, bsdf_only, 4.0);
    assert_agree("mis 4 shadow rays vs 1", mis4, mis, 4.0);
}

#[test]
fn hidden_environment_gives_a_black_background_and_the_same_lighting() {
    let (sphere, sky) = (
        pixels_by_distance(9.0, true),
        pixels_by_distance(14.0, false),
    );
    let settings = RenderSettings {
        width: SIDE,
        height: SIDE,
        spp: 8,
        ..Default::default()
    };
    let seen = scene_from_toml(&sphere_under(0.7, "color = [0.5, 0.8, 1]"));
    let hidden = scene_from_toml(&sphere_under(
        0.7,
        "color = [0.5, 0.8, 1]\nhide_from_camera = true",
    ));
    let (a, b) = (
        render_image(&seen, &settings),
        render_image(&hidden, &settings),
    );
    for &i in &sky {
        assert_eq!(a.pixels[i], [0.5, 0.8, 1.0].into());
        assert_eq!(b.pixels[i], [0.0; 3].into());
    }
    // Same seed, same paths: the sphere's pixels are the same numbers.
    for &i in &sphere {
        assert_eq!(a.pixels[i], b.pixels[i]);
    }
}

/// Runs the CLI on `scene` with `args`; returns (exit code, stderr) and whether `out` exists.
fn run_cli(scene: &Path, out: &Path, args: &[&str]) -> (Option<i32>, String, bool) {
    let output = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .args(["--width", "8", "--height", "8", "--spp", "1", "-q"])
        .args(args)
        .output()
        .unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
        out.exists(),
    )
}

#[test]
fn cli_env_flags_light_a_scene_and_hide_the_background() {
    let dir = test_dir("cli");
    let scene = dir.join("sphere.toml");
    std::fs::write(&scene, sphere_under(0.5, "color = [0, 0, 0]")).unwrap();
    let out = dir.join("out.exr");
    let (code, stderr, written) = run_cli(
        &scene,
        &out,
        &["--env", "0.25,0.5,1", "--env-strength", "2"],
    );
    assert_eq!(code, Some(0), "{stderr}");
    assert!(written);
    let image = wavetrace::output::read_exr(&out).unwrap();
    assert_eq!(image.pixels[0], [0.5, 1.0, 2.0].into());
    std::fs::remove_file(&out).unwrap();
    let (code, stderr, _) = run_cli(&scene, &out, &["--env-hidden"]);
    assert_eq!(code, Some(0), "{stderr}");
    let image = wavetrace::output::read_exr(&out).unwrap();
    assert_eq!(image.pixels[0], [0.0; 3].into());
}

#[test]
fn bad_environment_input_exits_1_naming_the_file_without_an_image() {
    let dir = test_dir("bad");
    let scene = dir.join("sphere.toml");
    std::fs::write(&scene, sphere_under(0.5, "color = [1, 1, 1]")).unwrap();
    // Not 2:1.
    image::Rgb32FImage::from_raw(4, 4, vec![1.0; 48])
        .unwrap()
        .save_with_format(dir.join("square.hdr"), image::ImageFormat::Hdr)
        .unwrap();
    // A NaN texel (EXR keeps it; HDR cannot encode one).
    let mut texels = vec![1.0f32; 8 * 4 * 3];
    texels[5] = f32::NAN;
    write_exr(&dir.join("nan.exr"), 8, 4, &texels);
    write_sun_map(&dir.join("good.hdr"));
    let cases: [(&str, Vec<&str>); 4] = [
        ("missing.hdr", vec![]),
        ("square.hdr", vec![]),
        ("nan.exr", vec![]),
        ("good.hdr", vec!["--env-strength", "-1"]),
    ];
    for (file, extra) in cases {
        let env = dir.join(file);
        let out = dir.join(format!("{file}.png"));
        let mut args = vec!["--env", env.to_str().unwrap()];
        args.extend(extra);
        let (code, stderr, written) = run_cli(&scene, &out, &args);
        assert_eq!(code, Some(1), "{file}: {stderr}");
        assert!(
            stderr.contains(file),
            "{file}: the error names the file: {stderr}"
        );
        assert!(!written, "{file}: no image written");
    }
    // In a scene file too, relative to it.
    let scene = dir.join("missing.toml");
    std::fs::write(&scene, sphere_under(0.5, "file = \"nowhere.exr\"")).unwrap();
    let (code, stderr, written) = run_cli(&scene, &dir.join("missing.png"), &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("nowhere.exr"), "{stderr}");
    assert!(!written);
}

/// A linear RGB OpenEXR file of `width x height` texels (row-major, top row first).
fn write_exr(path: &Path, width: usize, height: usize, texels: &[f32]) {
    exr::prelude::write_rgb_file(path, width, height, |x, y| {
        let i = 3 * (y * width + x);
        (texels[i], texels[i + 1], texels[i + 2])
    })
    .unwrap();
}
