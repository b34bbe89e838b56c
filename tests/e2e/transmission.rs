//! Next-event estimation through rough transmission: light behind a rough glass surface
//! reaches the camera through shadow rays that leave from the surface's back side.
//!
//! Punctual lights (point, spot, sun) cannot be found by BSDF sampling, so before shadow rays
//! went through transmitting surfaces they were lost behind rough glass. Here a single rough
//! glass interface (a plane, glass below, air above) is seen head-on by a camera above it, with
//! the light straight below: the camera sees Walter et al.'s BTDF at normal incidence, where
//! h = n, G = 1 and the half-vector Jacobian is exact, so the pixel radiance is
//! `4 (1 - F0) D(n) E` with D(n) = 1 / (pi alpha^2), F0 = ((ior - 1) / (ior + 1))^2 and E the
//! irradiance at the plane (radiance leaving the denser side is divided by ior^2, which with
//! the Jacobian (ior c_i - c_o)^-2 = 4 gives the 4), times the multiscatter compensation
//! `1 / E` of the rough glass seen from the camera's side. An area light behind the glass is
//! compared with BSDF sampling alone, which finds it unaided.

use crate::common::*;
use crate::import::{render_mean, scratch, write_gltf};
use serde_json::json;
use std::f32::consts::{FRAC_1_SQRT_2, PI};
use wavetrace::RenderSettings;
use wavetrace::flatten;
use wavetrace::internals::glass_energy_compensation;
use wavetrace::math::Rgb;
use wavetrace::scene::load::{LightUnits, LoadOptions, load_scene_with};

/// Perceptual roughness of the glass.
const ROUGHNESS: f32 = 0.5;

#[test]
fn punctual_lights_shine_through_rough_glass() {
    let dir = scratch("transmission");
    let alpha = ROUGHNESS * ROUGHNESS;
    let f0 = (0.5f32 / 2.5).powi(2);
    // Times multiscatter glass's energy compensation at normal incidence from outside (the
    // tables' 1 / E, checked against their quadrature by `bsdf::ggx_glass_albedo`'s tests).
    let btdf = 4.0 * (1.0 - f0) / (PI * alpha * alpha) * glass_energy_compensation(1.0, alpha, 1.5);
    let cases = [
        (
            "point",
            json!({"type": "point", "intensity": 8.0}),
            8.0 / 4.0,
        ),
        (
            "spot",
            json!({"type": "spot", "intensity": 8.0,
                "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}),
            8.0 / 4.0,
        ),
        ("sun", json!({"type": "directional", "intensity": 3.0}), 3.0),
    ];
    for (name, light, irradiance) in cases {
        // The seed's lit-plane document, turned into rough glass with the lamp 2 units below
        // it, pointing up.
        let mut doc = crate::import::punctual_light_doc(light, -2.0);
        doc["nodes"][2]["rotation"] = json!([FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2]);
        doc["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_materials_transmission"]);
        doc["materials"] = json!([{
            "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                "metallicFactor": 0.0, "roughnessFactor": ROUGHNESS},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}}
        }]);
        let path = write_gltf(&dir, &format!("{name}.gltf"), &doc);
        let unitless = LoadOptions {
            light_units: LightUnits::Unitless,
            ..Default::default()
        };
        let scene = load_scene_with(&path, &unitless).expect("loads");
        let flat = flatten(&scene.world, &path).unwrap();
        let expected = btdf * irradiance;
        let got = render_mean(&flat);
        eprintln!(
            "{name} behind rough glass: {got} vs closed form {expected:.5} (max rel. error {:.1e})",
            (got - Rgb::splat(expected)).abs().max_element() / expected
        );
        // The camera's 0.001-radian view sees the light within 1e-3 of normal incidence.
        assert!(
            (got - Rgb::splat(expected)).abs().max_element() < 1e-3 * expected,
            "{name}: {got} vs {expected}"
        );
    }
}

#[test]
fn an_area_light_behind_rough_glass_agrees_with_bsdf_sampling() {
    // A rough glass plane at z = 0 (outside up), a camera above it looking down, a square
    // light below it shining up, and nothing else: with MIS and with light sampling only,
    // the image mean must match BSDF sampling alone.
    let text = format!(
        r#"
[camera]
eye = [0, 0, 1.5]
look_at = [0, 0.001, 0]
vfov = 60
[materials]
glass = {{ type = "pbr", base_color = [1, 1, 1], roughness = {ROUGHNESS}, transmission = 1.0 }}
black = {{ type = "diffuse", albedo = [0, 0, 0] }}
[[shape]]
type = "quad"
material = "glass"
vertices = [[-2,-2,0],[2,-2,0],[2,2,0],[-2,2,0]]
[[shape]]
type = "quad"
material = "black"
emission = [1, 1, 1]
vertices = [[-0.4,-0.4,-0.7],[0.4,-0.4,-0.7],[0.4,0.4,-0.7],[-0.4,0.4,-0.7]]
"#
    );
    let scene = scene_from_toml(&text);
    let base = RenderSettings {
        width: 24,
        height: 24,
        ..Default::default()
    };
    let bsdf_only = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 0,
            spp: 2048,
            seed: 5,
            ..base
        },
    );
    let mis = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 2,
            spp: 256,
            ..base
        },
    );
    let light_only = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 2,
            mis: false,
            spp: 512,
            seed: 7,
            ..base
        },
    );
    assert!(
        bsdf_only.0[0] > 0.01,
        "the light shows through: {bsdf_only:?}"
    );
    assert_agree("MIS vs BSDF sampling", mis, bsdf_only, 4.0);
    assert_agree(
        "light sampling vs BSDF sampling",
        light_only,
        bsdf_only,
        4.0,
    );
}
