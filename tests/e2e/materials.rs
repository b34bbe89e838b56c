//! glTF metallic-roughness materials in scenes: the parameter sets that reduce to the seed's
//! materials render exactly as those do, a white metal sphere under uniform light loses only
//! the single-scattering GGX energy, and bad parameters are refused with a clear message.

use crate::common::*;
use std::path::Path;
use wavetrace::RenderSettings;
use wavetrace::scene::load::load_scene_str;

/// A small box lit by a ceiling light, with the floor and a sphere made of `material`.
fn box_with(material: &str) -> String {
    let materials = format!(
        "white = {{ type = \"diffuse\", albedo = [0.7, 0.7, 0.7] }}\nprobe = {material}\n\
         black = {{ type = \"diffuse\", albedo = [0, 0, 0] }}"
    );
    BoxScene {
        camera: BOX_CAMERA,
        materials: &materials,
        walls: [
            Some("probe"),
            None,
            Some("white"),
            None,
            Some("white"),
            None,
        ],
        light_half: 0.4,
        light_radiance: 5.0,
        extra_shapes: r#"
[[shape]]
type = "sphere"
material = "probe"
center = [0.2, 0.3, -0.6]
radius = 0.35
"#,
    }
    .toml()
}

#[test]
fn pbr_without_specular_renders_exactly_as_diffuse() {
    let settings = RenderSettings {
        width: 24,
        height: 24,
        spp: 4,
        ..Default::default()
    };
    let diffuse = render_image(
        &scene_from_toml(&box_with(
            r#"{ type = "diffuse", albedo = [0.8, 0.5, 0.2] }"#,
        )),
        &settings,
    );
    let pbr = render_image(
        &scene_from_toml(&box_with(
            r#"{ type = "pbr", base_color = [0.8, 0.5, 0.2], roughness = 0.5, specular = 0.0 }"#,
        )),
        &settings,
    );
    assert_eq!(diffuse.pixels, pbr.pixels);
}

#[test]
fn smooth_clear_pbr_glass_renders_exactly_as_dielectric() {
    let settings = RenderSettings {
        width: 24,
        height: 24,
        spp: 4,
        ..Default::default()
    };
    let dielectric = render_image(
        &scene_from_toml(&box_with(
            r#"{ type = "dielectric", ior = 1.4, tint = [1.0, 0.9, 0.8] }"#,
        )),
        &settings,
    );
    let pbr = render_image(
        &scene_from_toml(&box_with(
            r#"{ type = "pbr", base_color = [1.0, 0.9, 0.8], roughness = 0.0, transmission = 1.0, ior = 1.4 }"#,
        )),
        &settings,
    );
    assert_eq!(dielectric.pixels, pbr.pixels);
}

#[test]
fn out_of_range_pbr_parameters_are_refused() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/test-scene.toml");
    for (material, expected) in [
        (
            r#"{ type = "pbr", base_color = [0.5, 0.5, 0.5], roughness = 2.0 }"#,
            "roughness must lie in [0, 1]",
        ),
        (
            r#"{ type = "pbr", base_color = [1.5, 0.5, 0.5] }"#,
            "base_color components must lie in [0, 1]",
        ),
        (
            r#"{ type = "pbr", base_color = [0.5, 0.5, 0.5], transmission = 1.0, ior = 1.0 }"#,
            "ior must be at least 1",
        ),
        (
            r#"{ type = "pbr", base_color = [0.5, 0.5, 0.5], clearcoat = 1.5 }"#,
            "clearcoat must lie in [0, 1]",
        ),
        (
            r#"{ type = "pbr", base_color = [0.5, 0.5, 0.5], sheen_color = [1.2, 0.0, 0.0] }"#,
            "sheen_color components must lie in [0, 1]",
        ),
    ] {
        let error = load_scene_str(&path, &box_with(material))
            .err()
            .expect("bad material is refused")
            .to_string();
        assert!(
            error.contains(expected) && error.contains("test-scene.toml"),
            "{error}"
        );
    }
}

/// Multiscatter GGX (Blender's default): a white metal reflects all the light at every
/// roughness. Single scattering alone would reflect 0.916 (roughness 0.5) and 1 - ln 2 =
/// 0.307 (roughness 1) at normal incidence (`bsdf::ggx_albedo`'s tests).
#[test]
fn white_metal_sphere_in_a_furnace_reflects_all_light() {
    for roughness in [0.5f64, 1.0] {
        // A white metal sphere inside a uniformly emitting, non-reflecting sphere of radiance 1;
        // a narrow camera sees only the metal at normal incidence (cos > 0.9998), so the image
        // is the directional albedo at normal incidence.
        let scene = scene_from_toml(&format!(
            r#"
[camera]
eye = [0, -3, 0]
look_at = [0, 0, 0]
vfov = 0.5
[materials]
metal = {{ type = "pbr", base_color = [1, 1, 1], metallic = 1.0, roughness = {roughness} }}
black = {{ type = "diffuse", albedo = [0, 0, 0] }}
[[shape]]
type = "sphere"
material = "metal"
center = [0, 0, 0]
radius = 1
[[shape]]
type = "sphere"
material = "black"
center = [0, 0, 0]
radius = 10
emission = [1, 1, 1]
two_sided = true
"#
        ));
        let measured = estimate(
            &scene,
            &RenderSettings {
                width: 16,
                height: 16,
                spp: 64,
                ..Default::default()
            },
        );
        // The albedo table's interpolation error (< 3e-3) counts as two standard errors.
        let exact = ([1.0; 3], [1.5e-3; 3]);
        assert_agree(
            &format!("white metal, roughness {roughness}"),
            measured,
            exact,
            4.0,
        );
    }
}
