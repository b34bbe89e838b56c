//! `KHR_materials_unlit` end to end: an unlit surface shows its base colour to the camera
//! exactly, whatever lights the scene, reflects nothing, and is no light source for
//! next-event estimation. The test writes its `.gltf` and `.bin` into a temporary directory.

use crate::common::{assert_finite, render_image};
use serde_json::json;
use std::path::{Path, PathBuf};
use wavetrace::{RenderSettings, flatten, load_scene};

const SIZE: u32 = 16;
const UNLIT: [f32; 3] = [0.2, 0.5, 0.8];

/// Two quads side by side in the z = 0 plane, facing a camera at z = 2 that sees x, y in
/// [-0.9, 0.9]: x in [-1, 0] unlit of colour [`UNLIT`], x in [0, 1] a white Lambertian
/// (non-metal, no specular layer); a head-on sun of irradiance 2 W/m^2 lights both.
fn unlit_and_white(dir: &Path) -> PathBuf {
    let quad = |x0: f32, x1: f32| [x0, -1.0, 0.0, x1, -1.0, 0.0, x1, 1.0, 0.0, x0, 1.0, 0.0f32];
    let mut bytes: Vec<u8> = Vec::new();
    for v in quad(-1.0, 0.0).iter().chain(&quad(0.0, 1.0)) {
        bytes.extend(v.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bytes.extend(i.to_le_bytes());
    }
    std::fs::write(dir.join("unlit.bin"), &bytes).unwrap();
    let position = |view: usize, x0: f32, x1: f32| {
        json!({"bufferView": view, "componentType": 5126, "count": 4, "type": "VEC3",
               "min": [x0, -1.0, 0.0], "max": [x1, 1.0, 0.0]})
    };
    let doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular", "KHR_materials_unlit"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": 2.0 * 683.0}]}},
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"name": "unlit", "mesh": 0},
            {"name": "white", "mesh": 1},
            {"name": "eye", "camera": 0, "translation": [0.0, 0.0, 2.0]},
            {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "cameras": [{"type": "perspective", "perspective":
            {"yfov": 2.0 * (0.45f32).atan(), "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [UNLIT[0], UNLIT[1], UNLIT[2], 1.0]},
             "extensions": {"KHR_materials_unlit": {}}},
            {"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0},
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}
        ],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 1}, "indices": 2, "material": 1}]}
        ],
        "buffers": [{"uri": "unlit.bin", "byteLength": bytes.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12}
        ],
        "accessors": [
            position(0, -1.0, 0.0),
            position(1, 0.0, 1.0),
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    let path = dir.join("unlit.gltf");
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

#[test]
fn an_unlit_quad_shows_its_base_colour_exactly_and_is_no_light() {
    let dir = tempfile::tempdir().unwrap();
    let path = unlit_and_white(dir.path());
    let scene = load_scene(&path).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let scene = flatten(&scene.world, &path).expect("flattens");
    // Not in the light table: next-event estimation never aims at it.
    assert!(
        scene.lights().lights.is_empty(),
        "the unlit quad became an area light"
    );
    // Where a pixel's whole footprint (and one pixel more) is on one quad, the unlit one shows
    // exactly its colour, with no noise and nothing of the sun, which it would otherwise
    // reflect; the white one shows E / pi under the head-on sun (it cannot see the coplanar
    // unlit quad), also without noise.
    let x_of = |px: u32| ((px as f32 + 0.5) / SIZE as f32 * 2.0 - 1.0) * 0.9;
    let margin = 2.0 * 0.9 / SIZE as f32;
    for seed in [1, 2] {
        let settings = RenderSettings {
            width: SIZE,
            height: SIZE,
            spp: 16,
            seed,
            ..Default::default()
        };
        let image = render_image(&scene, &settings);
        assert_finite(&image);
        let (mut unlit, mut white) = (0, 0);
        for py in 0..SIZE {
            for px in 0..SIZE {
                let p = image.pixels[(py * SIZE + px) as usize].to_array();
                let x = x_of(px);
                if x < -margin {
                    unlit += 1;
                    for c in 0..3 {
                        assert!(
                            (p[c] - UNLIT[c]).abs() <= 1e-6 * UNLIT[c],
                            "pixel ({px}, {py}) channel {c}: {} for the unlit {}",
                            p[c],
                            UNLIT[c]
                        );
                    }
                } else if x > margin {
                    white += 1;
                    let expected = 2.0 / std::f32::consts::PI;
                    for value in p {
                        assert!(
                            (value - expected).abs() <= 1e-5 * expected,
                            "pixel ({px}, {py}): {value} on the white quad for {expected}"
                        );
                    }
                }
            }
        }
        assert!(unlit >= 80 && white >= 80, "{unlit} and {white} pixels");
    }
}
