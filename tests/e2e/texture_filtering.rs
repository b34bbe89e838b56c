//! Texture filtering end to end: a checkerboard plane that runs to the horizon, seen at a
//! grazing angle through an unlit material (each camera ray's radiance is the texture's
//! value, nothing else adds noise), rendered at a few samples per pixel with mipmaps
//! (the sampler's default, trilinear) and without (`minFilter` LINEAR), against a
//! supersampled reference (many samples, box filter, no mipmaps): the per-pixel mean of the
//! texture over each pixel's footprint. Mipmaps must cut the error by more than half.

use crate::common::{GltfDoc, assert_finite, render_image};
use serde_json::json;
use std::path::{Path, PathBuf};
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::{Image, RenderSettings, flatten};

/// A 256 x 256 checkerboard of 8-texel squares, black and white.
fn checkerboard() -> image::RgbImage {
    image::RgbImage::from_fn(256, 256, |x, y| {
        let white = (x / 8 + y / 8) % 2 == 0;
        image::Rgb(if white { [255; 3] } else { [0; 3] })
    })
}

/// The scene as a glTF (+Y up): an unlit ground plane 80 wide and 400 deep, the texture
/// repeating every 4 units, and a camera 1 unit above it looking toward the horizon.
/// `min_filter` is the sampler's `minFilter` (`None`: unspecified).
fn ground(dir: &Path, name: &str, min_filter: Option<u32>) -> PathBuf {
    checkerboard().save(dir.join("checker.png")).unwrap();
    let mut doc = GltfDoc::default();
    let (x, z0, z1) = (40.0f32, 2.0f32, -400.0f32);
    let corners = [[-x, 0.0, z0], [x, 0.0, z0], [x, 0.0, z1], [-x, 0.0, z1]];
    let positions = doc.positions(&corners);
    let uvs = doc.floats(&corners.map(|p| [p[0] / 4.0, p[2] / 4.0]), "VEC2");
    let indices = doc.indices(&[0, 1, 2, 0, 2, 3]);
    let mut sampler = json!({"magFilter": 9729});
    if let Some(filter) = min_filter {
        sampler["minFilter"] = json!(filter);
    }
    let pitch = -0.12f32; // radians below the horizontal
    let (s, c) = ((pitch / 2.0).sin(), (pitch / 2.0).cos());
    doc.write(
        dir,
        name,
        json!({
            "extensionsUsed": ["KHR_materials_unlit"],
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"mesh": 0},
                {"camera": 0, "translation": [0.0, 1.0, 0.0], "rotation": [s, 0.0, 0.0, c]}
            ],
            "cameras": [{"type": "perspective",
                "perspective": {"yfov": 0.5, "aspectRatio": 1.5, "znear": 0.01}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": positions, "TEXCOORD_0": uvs},
                "indices": indices, "material": 0}]}],
            "materials": [{"extensions": {"KHR_materials_unlit": {}},
                "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0, "sampler": 0}],
            "images": [{"uri": "checker.png"}],
            "samplers": [sampler]
        }),
    )
}

fn render(path: &Path, spp: u32, seed: u64) -> Image {
    let scene = import_model(path, UpAxis::Y).expect("the test's glTF loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let scene = flatten(&scene.world, path).expect("flattens");
    let settings = RenderSettings {
        width: 96,
        height: 64,
        spp,
        seed,
        ..RenderSettings::default()
    };
    let image = render_image(&scene, &settings);
    assert_finite(&image);
    image
}

/// Root-mean-square difference of the pixels' mean over channels, over the rows `rows`
/// (96 pixels a row).
fn rmse(a: &Image, b: &Image, rows: std::ops::Range<usize>) -> f64 {
    let pixels = rows.start * 96..rows.end * 96;
    let n = pixels.len() as f64;
    let sum: f64 = (a.pixels[pixels.clone()].iter().zip(&b.pixels[pixels]))
        .map(|(p, q)| {
            let d = (*p - *q).as_dvec3();
            (d.x + d.y + d.z) / 3.0
        })
        .map(|d| d * d)
        .sum();
    (sum / n).sqrt()
}

/// The rows where the plane lies beyond 20 units (the horizon is at row 16.6, one pixel is
/// 0.0078 rad, and the plane is 20 units away 0.05 rad below the horizon), with the sky
/// above it (black in every render): where the checkerboard is minified and aliases.
const FAR_ROWS: std::ops::Range<usize> = 0..23;

#[test]
fn mipmaps_cut_the_error_of_a_distant_checkerboard_at_few_samples() {
    let dir = std::env::temp_dir().join(format!("wavetrace-mip-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let trilinear = ground(&dir, "trilinear.gltf", None);
    let bilinear = ground(&dir, "bilinear.gltf", Some(9729));
    let reference = render(&bilinear, 1024, 7);
    let (mut with, mut without) = ([0.0; 2], [0.0; 2]);
    for seed in 1..=2 {
        let (mip, plain) = (render(&trilinear, 4, seed), render(&bilinear, 4, seed));
        for (k, rows) in [FAR_ROWS, 0..64].into_iter().enumerate() {
            with[k] += rmse(&mip, &reference, rows.clone()) / 2.0;
            without[k] += rmse(&plain, &reference, rows) / 2.0;
        }
    }
    // The blur mipmaps add, seen at many samples (the reference's own noise is at most
    // 0.5 / 32 = 0.016 a pixel).
    let converged = render(&trilinear, 1024, 7);
    let bias = [
        rmse(&converged, &reference, FAR_ROWS),
        rmse(&converged, &reference, 0..64),
    ];
    println!(
        "RMSE against the reference, far rows / whole image: 4 spp mipmaps {:.4} / {:.4}, \
         none {:.4} / {:.4}; 1024 spp mipmaps {:.4} / {:.4}",
        with[0], with[1], without[0], without[1], bias[0], bias[1]
    );
    assert!(
        with[0] < 0.5 * without[0],
        "far rows: mipmaps {:.4} vs bilinear only {:.4}",
        with[0],
        without[0]
    );
    assert!(with[1] < without[1], "whole image: {with:?} vs {without:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
