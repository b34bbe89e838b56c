//! `KHR_materials_volume`: Beer-Lambert absorption inside transmissive objects.
//!
//! A smooth glass cube of side d with attenuation colour c at distance D, inside a uniformly
//! emitting sky of radiance 1, seen head-on through a 0.001-radian camera. At normal incidence
//! every path stays on the axis, so the pixel is the slab's closed form: with Fresnel
//! reflectance F = ((ior - 1) / (ior + 1))^2 at both faces and internal transmittance
//! tau = exp(-sigma_a d), sigma_a = -ln(c) / D per channel,
//!
//! ```text
//! R = F + (1 - F)^2 F tau^2 / (1 - F^2 tau^2)      (front reflection, then the bounces inside)
//! T = (1 - F)^2 tau / (1 - F^2 tau^2)
//! ```
//!
//! and the radiance seen is R + T (1 without absorption: a furnace).
//!
//! The medium exists only where `thicknessFactor` is positive (a volume boundary); at its
//! default 0 the glass is thin-walled and absorbs nothing, whatever its attenuation.

use crate::common::*;
use crate::import::{Buffer, scratch, write_gltf};
use serde_json::{Value, json};
use wavetrace::RenderSettings;
use wavetrace::flatten;
use wavetrace::load_scene;

/// A cube of half-size `half` with outward-facing triangles (counter-clockwise seen from
/// outside), as positions and indices.
fn cube(half: f32) -> (Vec<[f32; 3]>, Vec<u16>) {
    let corners: Vec<[f32; 3]> = (0..8)
        .map(|k| [4, 2, 1].map(|bit| if k & bit != 0 { half } else { -half }))
        .collect();
    // Corner k has x, y, z = +-half by its bits 2, 1, 0; each face counter-clockwise from
    // outside.
    let faces: [[u16; 4]; 6] = [
        [0, 1, 3, 2], // x = -half
        [4, 6, 7, 5], // x = +half
        [0, 4, 5, 1], // y = -half
        [2, 3, 7, 6], // y = +half
        [0, 2, 6, 4], // z = -half
        [1, 5, 7, 3], // z = +half
    ];
    let indices = faces
        .iter()
        .flat_map(|[a, b, c, d]| [*a, *b, *c, *a, *c, *d])
        .collect();
    (corners, indices)
}

/// The scene: the glass cube (material `glass`) in a double-sided emitting sky cube (black,
/// without specular layer: it reflects nothing), and a camera on the +z axis looking down it.
fn glass_in_sky(half: f32, glass: Value) -> Value {
    let mut b = Buffer::default();
    let (corners, indices) = cube(half);
    let (glass_positions, glass_indices) = (b.vec3s(&corners), b.indices(&indices));
    let (corners, indices) = cube(10.0);
    let (sky_positions, sky_indices) = (b.vec3s(&corners), b.indices(&indices));
    b.into_doc(json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_materials_specular", "KHR_materials_transmission", "KHR_materials_volume"],
        "nodes": [
            {"name": "glass", "mesh": 0},
            {"name": "sky", "mesh": 1},
            {"name": "eye", "camera": 0, "translation": [0.0, 0.0, 5.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.001, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [glass,
            {"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0},
             "emissiveFactor": [1.0, 1.0, 1.0], "doubleSided": true,
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": glass_positions}, "indices": glass_indices, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": sky_positions}, "indices": sky_indices, "material": 1}]}
        ]
    }))
}

#[test]
fn absorption_in_a_glass_cube_matches_the_slab_closed_form() {
    let dir = scratch("volume");
    let (side, distance) = (2.0f64, 1.0f64);
    let colour = [0.8f64, 0.5, 0.2];
    let glass = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_volume": {"attenuationColor": colour, "attenuationDistance": distance,
                "thicknessFactor": side}
        }
    });
    let path = write_gltf(
        &dir,
        "absorbing.gltf",
        &glass_in_sky(side as f32 / 2.0, glass),
    );
    let scene = load_scene(&path).expect("loads");
    assert!(
        scene.warnings.iter().all(|w| !w.contains("volume")),
        "nothing about the volume is ignored: {:?}",
        scene.warnings
    );
    let flat = flatten(&scene.world, &path).unwrap();
    let got = estimate(
        &flat,
        &RenderSettings {
            width: 8,
            height: 8,
            spp: 2048,
            ..Default::default()
        },
    );
    let f = (0.5f64 / 2.5).powi(2);
    let expected = colour.map(|c| {
        let tau = (c.ln() / distance * side).exp();
        let bounce = 1.0 - f * f * tau * tau;
        f + (1.0 - f).powi(2) * (f * tau * tau + tau) / bounce
    });
    assert_agree("absorbing glass cube", got, (expected, [0.0; 3]), 4.0);
    // The test resolves the absorption to well under 1% of the brightest channel.
    assert!(got.1.iter().all(|e| *e < 0.002), "{got:?}");
}

#[test]
fn a_thin_walled_glass_cube_absorbs_nothing_and_says_so() {
    let dir = scratch("volume-thin");
    let glass = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {
            "KHR_materials_transmission": {"transmissionFactor": 1.0},
            "KHR_materials_volume": {"attenuationColor": [0.8, 0.5, 0.2], "attenuationDistance": 1.0}
        }
    });
    let path = write_gltf(&dir, "thin.gltf", &glass_in_sky(1.0, glass));
    let scene = load_scene(&path).expect("loads");
    let thin: Vec<_> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("thin-walled"))
        .collect();
    assert_eq!(
        thin.len(),
        1,
        "one warning about the thin wall: {:?}",
        scene.warnings
    );
    assert!(
        thin[0].contains("attenuation is not applied (1 material)"),
        "{thin:?}"
    );
    let flat = flatten(&scene.world, &path).unwrap();
    let got = estimate(
        &flat,
        &RenderSettings {
            width: 8,
            height: 8,
            spp: 512,
            ..Default::default()
        },
    );
    // Clear glass in a uniform sky of radiance 1 is a furnace: every channel sees 1 (the
    // absorbing cube's blue channel would see 0.08).
    eprintln!("thin-walled glass cube: {got:?}");
    // (Paths through smooth glass in the sky may all carry exactly 1, so the error estimate
    // can be 0: the bound adds a rounding allowance.)
    for c in 0..3 {
        assert!(
            (got.0[c] - 1.0).abs() <= 4.0 * got.1[c] + 1e-5,
            "channel {c}: {got:?}"
        );
    }
    assert!(got.1.iter().all(|e| *e < 0.002), "{got:?}");
}
