//! Next-event estimation is unbiased: the number of shadow rays, and switching it off
//! altogether (emitters found only by hitting them), change the noise but not the mean.

use crate::common::*;
use wavetrace::RenderSettings;

#[test]
fn room_mean_is_the_same_with_1_and_16_shadow_rays() {
    let scene = room();
    let base = RenderSettings {
        width: 64,
        height: 64,
        spp: 16,
        ..Default::default()
    };
    let one = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 1,
            ..base
        },
    );
    let sixteen = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 16,
            spp: 4,
            seed: 7,
            ..base
        },
    );
    assert!(
        one.1.iter().zip(one.0).all(|(e, m)| *e < 0.02 * m),
        "the test resolves a 2% difference"
    );
    assert_agree("room, 1 vs 16 shadow rays", one, sixteen, 4.0);
}

/// A box with a large ceiling light, a mirror and a glass sphere, where brute-force path
/// tracing converges in reasonable time.
fn mirror_glass_box() -> String {
    BoxScene {
        camera: "eye = [0, -3.5, 0]\nlook_at = [0, 0, 0]\nvfov = 60",
        materials: r#"
white = { type = "diffuse", albedo = [0.7, 0.7, 0.7] }
red = { type = "diffuse", albedo = [0.7, 0.1, 0.1] }
mirror = { type = "mirror", tint = [0.9, 0.9, 0.9] }
glass = { type = "dielectric", ior = 1.5 }
black = { type = "diffuse", albedo = [0, 0, 0] }"#,
        walls: [
            Some("white"),
            Some("red"),
            Some("white"),
            Some("white"),
            Some("white"),
            None,
        ],
        light_half: 0.6,
        light_radiance: 4.0,
        extra_shapes: r#"
[[shape]]
type = "sphere"
material = "glass"
center = [0.4, 0.2, -0.6]
radius = 0.35
[[shape]]
type = "sphere"
material = "mirror"
center = [-0.4, 0.4, -0.6]
radius = 0.35
"#,
    }
    .toml()
}

#[test]
fn next_event_estimation_matches_brute_force_path_tracing() {
    let scene = scene_from_toml(&mirror_glass_box());
    let base = RenderSettings {
        width: 48,
        height: 48,
        ..Default::default()
    };
    let nee = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 2,
            spp: 16,
            ..base
        },
    );
    let brute = estimate(
        &scene,
        &RenderSettings {
            shadow_rays: 0,
            spp: 64,
            ..base
        },
    );
    assert!(
        brute.1.iter().zip(brute.0).all(|(e, m)| *e < 0.02 * m),
        "the test resolves a 2% difference: {brute:?}"
    );
    assert_agree("box, NEE vs brute force", nee, brute, 4.0);
}
