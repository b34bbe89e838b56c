//! glTF light units and the never-black rule.
//!
//! A point light of known intensity 2 units above a Lambertian plane (albedo 0.5) gives the
//! radiance 0.5 / pi * I / 2^2 under it, I in W/sr: the file's number is read as candela
//! (/ 683 lm/W, the default), as W/sr (`unitless`), or as Blender's watts (`raw`, / 4 pi).
//! A directional light's number is lux (/ 683), W/m^2 (`unitless`) or W/m^2 (`raw`).
//!
//! A model whose only light is a small emissive part goes into the lit room unless it also
//! brings a camera (unlit surfaces count as glow), a model whose every surface is unlit
//! renders as it is; a model rendered as it is that comes out dark gets a warning.

use crate::import::{Buffer, punctual_light_doc, render_mean, scratch, write_gltf};
use serde_json::json;
use std::f32::consts::PI;
use std::process::Command;
use wavetrace::math::Rgb;
use wavetrace::scene::Name;
use wavetrace::scene::load::{LightUnits, LoadOptions, Placement, load_scene_placed};
use wavetrace::{RenderSettings, flatten};

#[test]
fn light_intensities_are_read_in_the_asked_units() {
    let dir = scratch("units");
    let (number, height) = (5464.0f32, 2.0f32); // 683 * 8
    for (units, per_sr, per_m2) in [
        (LightUnits::Spec, number / 683.0, number / 683.0),
        (LightUnits::Unitless, number, number),
        (LightUnits::Raw, number / (4.0 * PI), number),
    ] {
        for (kind, light) in [
            ("point", json!({"type": "point", "intensity": number})),
            ("sun", json!({"type": "directional", "intensity": number})),
        ] {
            let path = write_gltf(
                &dir,
                &format!("{kind}.gltf"),
                &punctual_light_doc(light, height),
            );
            let options = LoadOptions {
                light_units: units,
                ..Default::default()
            };
            let (scene, placement) = load_scene_placed(&path, &options).unwrap();
            assert_eq!(placement, Placement::AsIs);
            let flat = flatten(&scene.world, &path).unwrap();
            let irradiance = if kind == "sun" {
                per_m2
            } else {
                per_sr / (height * height)
            };
            let expected = 0.5 / PI * irradiance;
            let got = render_mean(&flat);
            assert!(
                (got - Rgb::splat(expected)).abs().max_element() < 1e-4 * expected,
                "{units:?} {kind}: {got} vs {expected}"
            );
        }
    }
}

/// A spot 4 units above the ground and `offset` to the side lights the point the camera sees
/// at `t = atan(offset / 4)` from its axis. A file Blender wrote gets Blender's Spot Blend back
/// from its cones (`1 - inner / outer`) and Cycles' smoothstep; any other file glTF's falloff.
#[test]
fn a_blender_spot_follows_cycles_blend_and_other_spots_the_gltf_falloff() {
    let dir = scratch("spot_blend");
    let (outer, blend) = (30f32.to_radians(), 0.15f32);
    let inner = outer * (1.0 - blend); // what Blender's exporter writes
    let light = json!({"type": "spot", "intensity": 683.0,
        "spot": {"innerConeAngle": inner, "outerConeAngle": outer}});
    let smoothstep = |x: f32| {
        let x = x.clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    };
    for generator in ["Khronos glTF Blender I/O v4.5.51", "some other tool"] {
        for offset in [0.0f32, 1.5, 1.8, 2.0, 2.2] {
            let mut doc = punctual_light_doc(light.clone(), 4.0);
            doc["nodes"][2]["translation"] = json!([offset, 4.0, 0.0]);
            doc["asset"]["generator"] = json!(generator);
            let path = write_gltf(&dir, "spot.gltf", &doc);
            let scene = wavetrace::load_scene(&path).unwrap();
            let flat = flatten(&scene.world, &path).unwrap();
            let (r2, cos) = (
                16.0 + offset * offset,
                4.0 / (16.0 + offset * offset).sqrt(),
            );
            let (co, ci) = (outer.cos(), inner.cos());
            let attenuation = if generator.starts_with("Khronos glTF Blender I/O") {
                smoothstep((cos - co) / ((1.0 - co) * blend))
            } else {
                ((cos - co) / (ci - co)).clamp(0.0, 1.0).powi(2)
            };
            let expected = 0.5 / PI * attenuation * cos / r2;
            // Near the outer cone the ramp is steep and the pixels see a little around the
            // point: 1e-3 of the value (the two falloffs differ there by a factor of 2).
            let got = render_mean(&flat);
            assert!(
                (got - Rgb::splat(expected)).abs().max_element() <= 1e-3 * expected,
                "{generator}, offset {offset}: {got} against {expected}"
            );
        }
    }
}

/// A 100 x 100 grey ground with a 0.1-unit emissive triangle above it, with or without a
/// camera.
fn glowing_model(with_camera: bool) -> serde_json::Value {
    let mut b = Buffer::default();
    let ground = b.vec3s(&[
        [-50.0, 0.0, 50.0],
        [50.0, 0.0, 50.0],
        [50.0, 0.0, -50.0],
        [-50.0, 0.0, -50.0],
    ]);
    let ground_indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let glow = b.vec3s(&[[0.0, 1.0, 0.0], [0.1, 1.0, 0.0], [0.0, 1.1, 0.0]]);
    let mut nodes = vec![
        json!({"name": "ground", "mesh": 0}),
        json!({"name": "glow", "mesh": 1}),
    ];
    if with_camera {
        nodes.push(json!({"name": "eye", "camera": 0, "translation": [0.0, 3.0, 10.0]}));
    }
    let node_ids: Vec<usize> = (0..nodes.len()).collect();
    b.into_doc(json!({
        "scenes": [{"nodes": node_ids}],
        "nodes": nodes,
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}},
            {"emissiveFactor": [1.0, 1.0, 1.0]}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": ground}, "indices": ground_indices, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": glow}, "material": 1}]}
        ]
    }))
}

/// [`glowing_model`] with `KHR_materials_unlit` surfaces: the small triangle is unlit
/// (colour [1, 0.5, 0.25]) instead of emissive, and with `all_unlit` the ground is unlit too.
fn unlit_model(all_unlit: bool, with_camera: bool) -> serde_json::Value {
    let mut doc = glowing_model(with_camera);
    let unlit = |colour: [f32; 4]| {
        json!({"pbrMetallicRoughness": {"baseColorFactor": colour},
               "extensions": {"KHR_materials_unlit": {}}})
    };
    doc["extensionsUsed"] = json!(["KHR_materials_unlit"]);
    doc["materials"][1] = unlit([1.0, 0.5, 0.25, 1.0]);
    if all_unlit {
        doc["materials"][0] = unlit([0.5, 0.5, 0.5, 1.0]);
    }
    doc
}

/// Unlit surfaces show light as emitters do (camera and bounce rays see their colour): a
/// model with a few of them among lit surfaces goes into the room unless it brings a camera,
/// like a glowing one; a model whose every surface is unlit needs no light and renders as it
/// is, showing exactly its colours.
#[test]
fn unlit_surfaces_light_a_file_as_emitters_do_and_an_all_unlit_file_renders_as_it_is() {
    let dir = scratch("unlit-placement");
    let in_room = |path: &std::path::Path| {
        let (scene, placement) = load_scene_placed(path, &LoadOptions::default()).unwrap();
        let room_light = scene
            .world
            .query::<&Name>()
            .iter()
            .any(|n| n.0 == "area light");
        assert_eq!(room_light, placement == Placement::InRoom, "{path:?}");
        (scene, placement)
    };
    let part = write_gltf(&dir, "unlit-part.gltf", &unlit_model(false, false));
    assert_eq!(in_room(&part).1, Placement::InRoom);
    let staged = write_gltf(&dir, "unlit-part-camera.gltf", &unlit_model(false, true));
    assert_eq!(in_room(&staged).1, Placement::AsIs);
    for with_camera in [false, true] {
        let all = write_gltf(&dir, "unlit-all.gltf", &unlit_model(true, with_camera));
        let (scene, placement) = in_room(&all);
        assert_eq!(placement, Placement::AsIs, "camera: {with_camera}");
        // Nothing but unlit surfaces on a black background: a pixel whose whole footprint is
        // on the ground shows exactly its grey (unlit colours are shown in full, with no
        // noise), and no pixel is brighter than the surfaces' colours.
        let flat = flatten(&scene.world, &all).unwrap();
        let settings = RenderSettings {
            width: 16,
            height: 16,
            spp: 4,
            ..Default::default()
        };
        let image = crate::common::render_image(&flat, &settings);
        let grey = image
            .pixels
            .iter()
            .filter(|p| **p == Rgb::splat(0.5))
            .count();
        println!(
            "all unlit (camera: {with_camera}): {grey} of 256 pixels exactly the ground's 0.5"
        );
        assert!(grey > 0, "camera: {with_camera}");
        assert!(image.pixels.iter().all(|p| p.max_element() <= 1.0));
    }
}

#[test]
fn a_model_lit_only_by_its_own_glow_goes_into_the_room_unless_it_brings_a_camera() {
    let dir = scratch("glow");
    let bare = write_gltf(&dir, "glow.gltf", &glowing_model(false));
    let (scene, placement) = load_scene_placed(&bare, &LoadOptions::default()).unwrap();
    assert_eq!(placement, Placement::InRoom);
    assert!(
        scene
            .world
            .query::<&Name>()
            .iter()
            .any(|n| n.0 == "area light"),
        "lit by the room's light"
    );
    // In the room, the model is lit: its ground shows clearly (not just the glow).
    let flat = flatten(&scene.world, &bare).unwrap();
    assert!(render_mean(&flat).max_element() > 0.05);

    // With a camera, the file is a scene set up for rendering: as it is. It comes out dark
    // (one small glowing triangle), and the command line says how to light it.
    let staged = write_gltf(&dir, "glow-camera.gltf", &glowing_model(true));
    let (_, placement) = load_scene_placed(&staged, &LoadOptions::default()).unwrap();
    assert_eq!(placement, Placement::AsIs);
    let out = dir.join("glow.png");
    let run = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render",
            staged.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ])
        .args(["--width", "32", "--spp", "2", "--quiet"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: the image is dark") && stderr.contains("--in-room"),
        "{stderr}"
    );
    // --width alone on a camera without an aspect ratio... this one has 1:1: 32 x 32.
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (32, 32));
    // The room's render of the same model is not dark: no warning.
    let run = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render",
            bare.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ])
        .args(["--width", "32", "--spp", "2", "--quiet"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success() && !stderr.contains("dark"), "{stderr}");
}

#[test]
fn width_alone_without_a_camera_aspect_gives_a_square_image_and_up_is_checked() {
    // A lit file without a camera gets a framing camera with no aspect ratio.
    let dir = scratch("width");
    let mut doc = punctual_light_doc(json!({"type": "point", "intensity": 683.0}), 2.0);
    doc["nodes"].as_array_mut().unwrap().remove(1);
    doc["scenes"][0]["nodes"] = json!([0, 1]);
    doc.as_object_mut().unwrap().remove("cameras");
    let path = write_gltf(&dir, "nocam.gltf", &doc);
    for (flag, expected) in [("--width", (40, 40)), ("--height", (24, 24))] {
        let out = dir.join("w.png");
        let value = expected.0.to_string();
        let run = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
            .args([
                "render",
                path.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ])
            .args([flag, value.as_str(), "--spp", "1", "--quiet", "--up", "z"])
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let img = image::open(&out).unwrap();
        assert_eq!((img.width(), img.height()), expected, "{flag}");
    }
    // The room has a 800 x 800 [render] size: --width alone keeps its square.
    let glow = write_gltf(&dir, "glow.gltf", &glowing_model(false));
    let out = dir.join("room.png");
    let run = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render",
            glow.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ])
        .args(["--width", "20", "--spp", "1", "--quiet"])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (20, 20));
    // --up on a scene file is refused, saying where it belongs.
    let room = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml");
    let run = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render", room.to_str().unwrap(), "--up", "z", "--quiet"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("[[model]]"), "{stderr}");
}
