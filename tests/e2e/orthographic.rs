//! Orthographic cameras from glTF: the film spans `2 xmag` x `2 ymag` world units, so an
//! unlit quad of known size covers a known block of pixels; bad magnifications warn (naming
//! the file and camera) and fall back.

use crate::common::{GltfDoc, assert_finite, render_image};
use serde_json::json;
use std::path::{Path, PathBuf};
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::scene::{Camera, Projection};
use wavetrace::{RenderSettings, flatten};

/// A white unlit unit quad (x, y in [-0.5, 0.5], z = 0, facing +z) and a camera 5 units in
/// front of it looking at it (glTF cameras look down -z), orthographic with `xmag`, `ymag`.
fn quad_and_camera(dir: &Path, name: &str, xmag: f32, ymag: f32) -> PathBuf {
    let mut doc = GltfDoc::default();
    let corners = [
        [-0.5, -0.5, 0.0],
        [0.5, -0.5, 0.0],
        [0.5, 0.5, 0.0],
        [-0.5, 0.5, 0.0],
    ];
    let positions = doc.positions(&corners);
    let indices = doc.indices(&[0, 1, 2, 0, 2, 3]);
    doc.write(
        dir,
        name,
        json!({
            "extensionsUsed": ["KHR_materials_unlit"],
            "scene": 0,
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [{"mesh": 0}, {"name": "top", "camera": 0, "translation": [0.0, 0.0, 5.0]}],
            "cameras": [{"type": "orthographic",
                "orthographic": {"xmag": xmag, "ymag": ymag, "znear": 0.01, "zfar": 100.0}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": positions},
                "indices": indices, "material": 0}]}],
            "materials": [{"extensions": {"KHR_materials_unlit": {}}}]
        }),
    )
}

fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wavetrace-ortho-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn camera_of(scene: &wavetrace::Scene) -> Option<Camera> {
    scene.world.query::<&Camera>().iter().next().copied()
}

#[test]
fn an_orthographic_film_covers_its_magnification_in_world_units() {
    let dir = scratch("extent");
    // A film 4 x 2 units on 128 x 64 pixels: 32 pixels a unit, the unit quad 32 x 32 pixels
    // (columns 48..80, rows 16..48), whatever its distance.
    let path = quad_and_camera(&dir, "ortho.gltf", 2.0, 1.0);
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let camera = camera_of(&scene).expect("the orthographic camera is kept");
    assert_eq!(
        camera.projection,
        Projection::Orthographic { half_height: 1.0 }
    );
    assert_eq!(camera.aspect_ratio, Some(2.0));
    let flat = flatten(&scene.world, &path).unwrap();
    let settings = RenderSettings {
        width: 128,
        height: 64,
        spp: 4,
        ..RenderSettings::default()
    };
    let image = render_image(&flat, &settings);
    assert_finite(&image);
    for (k, p) in image.pixels.iter().enumerate() {
        let (x, y) = (k % 128, k / 128);
        let inside = (48..80).contains(&x) && (16..48).contains(&y);
        let expected = if inside { 1.0 } else { 0.0 };
        assert!(
            (p.x - expected).abs() < 1e-6,
            "pixel ({x}, {y}) is {p}, expected {expected}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_orthographic_magnifications_warn_and_fall_back() {
    let dir = scratch("bad");
    // ymag 0: xmag serves for both (a square film), with a warning naming file and camera.
    let path = quad_and_camera(&dir, "zero_y.gltf", -1.5, 0.0);
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    let camera = camera_of(&scene).expect("kept with xmag");
    assert_eq!(
        camera.projection,
        Projection::Orthographic { half_height: 1.5 }
    );
    assert_eq!(camera.aspect_ratio, Some(1.0));
    let text = scene.warnings.join("\n");
    assert!(
        text.contains("zero_y.gltf") && text.contains("'top'") && text.contains("ymag is zero"),
        "{text}"
    );
    assert!(text.contains("negative magnification"), "{text}");
    // Neither usable: the camera is skipped, with a warning.
    let path = quad_and_camera(&dir, "zero.gltf", 0.0, 0.0);
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    assert!(camera_of(&scene).is_none());
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("zero.gltf") && w.contains("'top'") && w.contains("skipped")),
        "{:?}",
        scene.warnings
    );
    let _ = std::fs::remove_dir_all(&dir);
}
