//! Furnace tests: closed Lambertian enclosures that emit Le and reflect with albedo a have
//! radiance Le / (1 - a) everywhere (the Neumann series of the rendering equation).

use crate::common::*;
use wavetrace::RenderSettings;

/// Checks one enclosure: every pixel is an independent estimate of the same value, so the
/// image mean's standard error is the pixel standard deviation over sqrt(pixels).
fn check_furnace(scene_toml: &str, albedo: f32, emission: f32, shadow_rays: u32, spp: u32) {
    let scene = scene_from_toml(scene_toml);
    let settings = RenderSettings {
        width: 64,
        height: 64,
        spp,
        shadow_rays,
        ..Default::default()
    };
    let image = render_image(&scene, &settings);
    assert_finite(&image);
    let expected = emission as f64 / (1.0 - albedo as f64);
    let n = image.pixels.len() as f64;
    for c in 0..3 {
        let values: Vec<f64> = image.pixels.iter().map(|p| p[c] as f64).collect();
        let mean = values.iter().sum::<f64>() / n;
        let sd = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        let error = sd / n.sqrt();
        let z = (mean - expected) / error;
        eprintln!(
            "albedo {albedo}, shadow rays {shadow_rays}: {mean:.5} vs {expected:.5} (error {error:.2e}, z {z:.2})"
        );
        assert!(
            error < 0.01 * expected,
            "the test must be able to detect a 1% bias (error {error})"
        );
        assert!(
            z.abs() < 4.0,
            "furnace mean {mean} differs from {expected} by {z:.2} standard errors"
        );
    }
}

fn sphere_enclosure(albedo: f32, emission: f32) -> String {
    format!(
        r#"
        [camera]
        eye = [0.1, 0.2, -0.1]
        look_at = [1, 0.3, 0.2]
        vfov = 100
        [materials]
        wall = {{ type = "diffuse", albedo = [{albedo}, {albedo}, {albedo}] }}
        [[shape]]
        type = "sphere"
        material = "wall"
        center = [0, 0, 0]
        radius = 2
        emission = [{emission}, {emission}, {emission}]
        two_sided = true
        "#
    )
}

/// A cube of triangles with one-sided emitters facing inward.
fn cube_enclosure(albedo: f32, emission: f32) -> String {
    let mut s = format!(
        r#"
        [camera]
        eye = [0.3, -0.2, 0.1]
        look_at = [1, 0.5, 0.3]
        vfov = 120
        [materials]
        wall = {{ type = "diffuse", albedo = [{albedo}, {albedo}, {albedo}] }}
        "#
    );
    // Each face as a quad wound to face the inside (front = counter-clockwise seen from inside).
    let faces = [
        "[[-1,-1,-1],[1,-1,-1],[1,1,-1],[-1,1,-1]]", // z = -1, faces +z
        "[[-1,-1,1],[-1,1,1],[1,1,1],[1,-1,1]]",     // z = +1, faces -z
        "[[-1,-1,-1],[-1,1,-1],[-1,1,1],[-1,-1,1]]", // x = -1, faces +x
        "[[1,-1,-1],[1,-1,1],[1,1,1],[1,1,-1]]",     // x = +1, faces -x
        "[[-1,-1,-1],[-1,-1,1],[1,-1,1],[1,-1,-1]]", // y = -1, faces +y
        "[[-1,1,-1],[1,1,-1],[1,1,1],[-1,1,1]]",     // y = +1, faces -y
    ];
    for f in faces {
        s += &format!(
            "[[shape]]\ntype = \"quad\"\nmaterial = \"wall\"\nemission = [{emission}, {emission}, {emission}]\nvertices = {f}\n"
        );
    }
    s
}

#[test]
fn closed_sphere_furnace_matches_analytic() {
    for (albedo, shadow_rays) in [(0.5, 1), (0.8, 1), (0.8, 4), (0.5, 0)] {
        check_furnace(&sphere_enclosure(albedo, 1.0), albedo, 1.0, shadow_rays, 4);
    }
}

#[test]
fn closed_one_sided_cube_furnace_matches_analytic() {
    for (albedo, shadow_rays) in [(0.7, 1), (0.7, 0)] {
        check_furnace(&cube_enclosure(albedo, 0.5), albedo, 0.5, shadow_rays, 48);
    }
}
