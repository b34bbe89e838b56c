//! Next-event estimation is unbiased: the number of shadow rays, and switching it off
//! altogether (emitters found only by hitting them), change the noise but not the mean.

mod common;
use common::*;
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
const BOX: &str = r#"
[camera]
eye = [0, -3.5, 0]
look_at = [0, 0, 0]
vfov = 60
[materials]
white = { type = "diffuse", albedo = [0.7, 0.7, 0.7] }
red = { type = "diffuse", albedo = [0.7, 0.1, 0.1] }
mirror = { type = "mirror", tint = [0.9, 0.9, 0.9] }
glass = { type = "dielectric", ior = 1.5 }
black = { type = "diffuse", albedo = [0, 0, 0] }
[[shape]]
type = "quad"
material = "white"
vertices = [[-1,-1,-1],[1,-1,-1],[1,1,-1],[-1,1,-1]]
[[shape]]
type = "quad"
material = "red"
vertices = [[-1,-1,-1],[-1,1,-1],[-1,1,1],[-1,-1,1]]
[[shape]]
type = "quad"
material = "white"
vertices = [[-1,1,-1],[1,1,-1],[1,1,1],[-1,1,1]]
[[shape]]
type = "quad"
material = "white"
vertices = [[1,-1,-1],[1,-1,1],[1,1,1],[1,1,-1]]
[[shape]]
type = "quad"
material = "white"
vertices = [[-1,-1,1],[-1,1,1],[1,1,1],[1,-1,1]]
[[shape]]
type = "quad"
material = "black"
emission = [4, 4, 4]
vertices = [[-0.6,-0.6,0.99],[-0.6,0.6,0.99],[0.6,0.6,0.99],[0.6,-0.6,0.99]]
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
"#;

#[test]
fn next_event_estimation_matches_brute_force_path_tracing() {
    let scene = scene_from_toml(BOX);
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
