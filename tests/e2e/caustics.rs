//! Light paths for caustics seen directly (`wavefront::light_paths`), combined with the path
//! tracer by the balance heuristic, are unbiased:
//!
//! - **Planar mirror, closed form**: a Lambertian floor lit only through a mirror ceiling
//!   equals the same floor lit by the mirrored ("virtual") light directly, with the mirror
//!   replaced by the mirror image of everything it reflects, which next-event estimation
//!   renders with little noise. For an area light both strategies count the mirrored light
//!   (the MIS weights must sum to 1), for a point light the light paths alone (the path
//!   tracer can never hit a point light, so before them this light was missing).
//! - **Glass caustic, estimator against estimator**: with light paths, the image mean and the
//!   mean of the caustic under a glass sphere equal those of the path tracer alone.
//! - **Caustics seen after a diffuse bounce** (`wavefront::light_vertices`, camera vertices
//!   connected to the light paths' diffuse points): a wall lit by a floor that a mirror
//!   lights equals the wall of the mirror-image twin (closed form; it fails with the
//!   connections' MIS weight set to 1), and in the glass sphere's box, a wall block and the
//!   image agree with and without the connections and without light paths; so does the
//!   caustic seen through a pane of frosted glass (connections through its back side).
//! - **Caustics seen behind a delta vertex** (`wavefront::merging`, light vertices merged at
//!   camera vertices reached through a mirror): the floor seen in the mirror ceiling, lit only
//!   through that mirror, equals the twin's floor (closed form; it fails with the merges' MIS
//!   weight set to 1), and so does the image without merging.
//! - **Determinism**: the same image on 1 and 3 threads and with two batch sizes.

use crate::common::*;
use std::path::Path;
use wavetrace::math::{Affine3A, Rgb, Vec3};
use wavetrace::scene::{PunctualLight, Transform};
use wavetrace::{Image, RenderScene, RenderSettings, flatten, scene::load::load_scene_str};

/// A square (two-sided geometry) at height `z`, half-width `half`, facing up or down.
fn square(
    name: &str,
    material: &str,
    z: f32,
    half: f32,
    up: bool,
    emission: Option<f32>,
) -> String {
    let (a, b) = (-half, half);
    let corners = if up {
        format!("[[{a}, {a}, {z}], [{b}, {a}, {z}], [{b}, {b}, {z}], [{a}, {b}, {z}]]")
    } else {
        format!("[[{a}, {a}, {z}], [{a}, {b}, {z}], [{b}, {b}, {z}], [{b}, {a}, {z}]]")
    };
    let emission = emission.map_or(String::new(), |e| format!("emission = [{e}, {e}, {e}]\n"));
    format!(
        "[[shape]]\nname = \"{name}\"\ntype = \"quad\"\nmaterial = \"{material}\"\n{emission}vertices = {corners}\n"
    )
}

/// The camera sits below the light (z = 0.45 < 0.5) and looks down at the floor: it sees
/// only the floor (and black beyond it), never the mirror or what replaces it.
const HEADER: &str = r#"
[camera]
eye = [0.0, -1.5, 0.45]
look_at = [0.0, -0.5, 0.0]
up = [0.0, 0.0, 1.0]
vfov = 40.0

[materials]
floor = { type = "diffuse", albedo = [0.5, 0.6, 0.7] }
mirror = { type = "mirror" }
black = { type = "diffuse", albedo = [0.0, 0.0, 0.0] }
"#;

/// What the camera of the mirror scenes looks at (it sits below the light either way).
#[derive(Clone, Copy)]
enum View {
    /// Down at the floor ([`HEADER`]'s camera).
    Floor,
    /// Up at the mirror ceiling, in which it sees the floor.
    Mirror,
}

impl View {
    fn header(self) -> String {
        match self {
            View::Floor => HEADER.to_string(),
            View::Mirror => {
                HEADER.replace("look_at = [0.0, -0.5, 0.0]", "look_at = [0.0, -0.3, 2.0]")
            }
        }
    }
}

/// Floor at z = 0 (half-width 2); mirror ceiling at z = 2 (`mirror`), or in its place the
/// mirror image of the scene below it (`twin`): a floor at z = 4 facing down and the light
/// mirrored to z = 3.5. The area light (half-width 0.2 at z = 0.5) faces up, toward the
/// mirror, so it never lights the floor directly.
fn area_light_scene(twin: bool, view: View) -> RenderScene {
    let mut toml = view.header();
    toml += &square("floor", "floor", 0.0, 2.0, true, None);
    toml += &square("light", "black", 0.5, 0.2, true, Some(40.0));
    if twin {
        toml += &square("mirrored floor", "floor", 4.0, 2.0, false, None);
        toml += &square("mirrored light", "black", 3.5, 0.2, false, Some(40.0));
    } else {
        toml += &square("mirror", "mirror", 2.0, 2.0, false, None);
    }
    scene_from_toml(&toml)
}

/// The point-light version: a point light at z = 0.5 above a black square (z = 0.45) that
/// hides it from the floor; the twin has the light, the square and the floor mirrored (to
/// z = 3.5, 3.55 and 4). Light that reaches the floor, goes up to the mirror and down to the
/// floor again is found by the merges alone (the second floor point is reached through a
/// delta bounce), in the twin by next-event estimation.
fn point_light_scene(twin: bool, view: View) -> RenderScene {
    let mut toml = view.header();
    toml += &square("floor", "floor", 0.0, 2.0, true, None);
    toml += &square("shade", "black", 0.45, 0.3, true, None);
    if twin {
        toml += &square("mirrored floor", "floor", 4.0, 2.0, false, None);
        toml += &square("mirrored shade", "black", 3.55, 0.3, false, None);
    } else {
        toml += &square("mirror", "mirror", 2.0, 2.0, false, None);
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/test-scene.toml");
    let mut scene = load_scene_str(&path, &toml).expect("test scene loads");
    let mut light_at = |z: f32| {
        scene.world.spawn((
            Transform(Affine3A::from_translation(Vec3::new(0.0, 0.0, z))),
            PunctualLight::Point {
                intensity: Rgb::splat(3.0),
            },
        ));
    };
    light_at(0.5);
    if twin {
        light_at(3.5);
    }
    flatten(&scene.world, &path).expect("test scene flattens")
}

/// Mean and standard error of a block of pixels (columns `xs`, rows `ys`) from two renders
/// with different seeds (as `common::mean_and_error` for the whole image).
fn block_estimate(
    a: &Image,
    b: &Image,
    xs: std::ops::Range<u32>,
    ys: std::ops::Range<u32>,
) -> ([f64; 3], [f64; 3]) {
    let crop = |image: &Image| Image {
        width: xs.len() as u32,
        height: ys.len() as u32,
        pixels: ys
            .clone()
            .flat_map(|y| xs.clone().map(move |x| (x, y)))
            .map(|(x, y)| image.at(x, y))
            .collect(),
    };
    mean_and_error(&crop(a), &crop(b))
}

/// Whole-image and centre-block estimates of `scene`.
fn estimates(scene: &RenderScene, settings: &RenderSettings) -> Vec<([f64; 3], [f64; 3])> {
    let (a, b) = independent_pair(scene, settings);
    let (w, h) = (settings.width, settings.height);
    vec![
        mean_and_error(&a, &b),
        block_estimate(&a, &b, w / 4..3 * w / 4, h / 4..3 * h / 4),
    ]
}

fn settings(spp: u32, caustic_paths: f32) -> RenderSettings {
    RenderSettings {
        width: 32,
        height: 32,
        spp,
        caustic_paths,
        ..Default::default()
    }
}

/// Asserts that two lists of estimates (`parts`: what each one measures) agree within 4
/// standard errors, part by part.
fn assert_parts_agree(
    label: &str,
    parts: [&str; 2],
    a: Vec<([f64; 3], [f64; 3])>,
    b: Vec<([f64; 3], [f64; 3])>,
) {
    for (what, (x, y)) in parts.iter().zip(a.into_iter().zip(b)) {
        assert_agree(&format!("{label}, {what}"), x, y, 4.0);
    }
}

/// Asserts that `lit` (named `label`), rendered at `spp.0` samples with light paths, is lit
/// and has the image mean and centre block of its mirrored twin rendered at `spp.1`.
fn assert_lit_as_its_twin(label: &str, lit: &RenderScene, twin: &RenderScene, spp: (u32, u32)) {
    let mirrored = estimates(lit, &settings(spp.0, 1.0));
    let twin = estimates(twin, &settings(spp.1, 1.0));
    assert!(mirrored[0].0[0] > 0.02, "{label} is lit: {:?}", mirrored[0]);
    assert_parts_agree(label, ["image", "centre"], mirrored, twin);
}

#[test]
fn area_light_through_a_mirror_equals_its_mirror_image() {
    let (lit, twin) = (
        area_light_scene(false, View::Floor),
        area_light_scene(true, View::Floor),
    );
    assert_lit_as_its_twin("the floor (area light)", &lit, &twin, (256, 64));
}

#[test]
fn point_light_through_a_mirror_equals_its_mirror_image() {
    let mirrored_scene = point_light_scene(false, View::Floor);
    // Without light paths the path tracer cannot find this light through the mirror.
    let dark = render_image(&mirrored_scene, &settings(4, 0.0));
    assert!(dark.pixels.iter().all(|p| *p == Rgb::ZERO));
    let twin = point_light_scene(true, View::Floor);
    assert_lit_as_its_twin("the floor (point light)", &mirrored_scene, &twin, (64, 16));
}

/// Caustics seen behind a delta vertex, closed form: the camera looks up at the mirror
/// ceiling and sees the floor, lit only through the mirror: camera -> mirror -> floor ->
/// mirror -> light, which only the path tracer and the merges find (for the point light, the
/// merges alone). It equals the twin, where the mirrored floor is lit by the light directly
/// (next-event estimation); the area light's also without merging. With the path tracer's
/// weight for these paths set to 1 (counting them twice) the area light's image mean is 6.2
/// standard errors too high. (Setting the merges' weight to 1 instead moves it less than the
/// noise: there the path tracer's share is small.)
#[test]
fn floor_seen_in_the_mirror_lit_through_the_mirror_equals_its_mirror_image() {
    let (lit, twin) = (
        area_light_scene(false, View::Mirror),
        area_light_scene(true, View::Mirror),
    );
    assert_lit_as_its_twin(
        "the floor in the mirror (area light)",
        &lit,
        &twin,
        (256, 64),
    );
    let without_merging = estimates(
        &lit,
        &RenderSettings {
            caustic_merge_radius: 0.0,
            ..settings(512, 1.0)
        },
    );
    let twin = estimates(&twin, &settings(64, 1.0));
    assert_parts_agree(
        "the floor in the mirror (area light, no merging)",
        ["image", "centre"],
        without_merging,
        twin,
    );
    let (lit, twin) = (
        point_light_scene(false, View::Mirror),
        point_light_scene(true, View::Mirror),
    );
    assert_lit_as_its_twin(
        "the floor in the mirror (point light)",
        &lit,
        &twin,
        (128, 32),
    );
}

/// A box with a small ceiling light and a glass sphere whose caustic falls on the floor in
/// view; its walls are diffuse.
fn glass_caustic_scene() -> RenderScene {
    scene_from_toml(&glass_caustic_scene_text())
}

/// [`glass_caustic_scene`]'s scene file.
fn glass_caustic_scene_text() -> String {
    let materials = r#"
white = { type = "diffuse", albedo = [0.7, 0.7, 0.7] }
red = { type = "diffuse", albedo = [0.7, 0.1, 0.1] }
glass = { type = "dielectric", ior = 1.5 }
mirror = { type = "mirror" }
black = { type = "diffuse", albedo = [0, 0, 0] }"#;
    BoxScene {
        camera: BOX_CAMERA,
        materials,
        walls: [
            Some("white"),
            Some("red"),
            Some("white"),
            Some("white"),
            Some("white"),
            Some("white"),
        ],
        light_half: 0.1,
        light_radiance: 100.0,
        extra_shapes: r#"
[[shape]]
type = "sphere"
material = "glass"
center = [0.0, 0.6, -0.3]
radius = 0.3
[[shape]]
type = "sphere"
material = "mirror"
center = [0.55, 0.5, -0.7]
radius = 0.25
"#,
    }
    .toml()
}

/// The whole image's mean and the mean of the caustic the glass sphere casts on the floor
/// (a 128 x 128 render shows it at columns 60-70, rows 80-90), each with its standard error
/// from two renders with different seeds.
fn image_and_caustic_estimates(
    scene: &RenderScene,
    settings: &RenderSettings,
) -> Vec<([f64; 3], [f64; 3])> {
    let (x0, y0) = (14, 19);
    let (a, b) = independent_pair(scene, settings);
    vec![
        mean_and_error(&a, &b),
        block_estimate(&a, &b, x0..x0 + 4, y0..y0 + 4),
    ]
}

#[test]
fn glass_caustic_with_light_paths_equals_the_path_tracer_alone() {
    let scene = glass_caustic_scene();
    let both = |settings: &RenderSettings| image_and_caustic_estimates(&scene, settings);
    let with = both(&settings(128, 1.0));
    let without = both(&settings(512, 0.0));
    assert_parts_agree("glass caustic", ["image", "caustic"], with, without);
}

#[test]
fn glass_caustic_with_light_paths_equals_the_path_tracer_alone_under_a_wide_filter() {
    // The light paths' splats are spread over the pixels by the filter's density; the camera
    // samples of those pixels land around them by the same density.
    let scene = glass_caustic_scene();
    let both = |settings: &RenderSettings| image_and_caustic_estimates(&scene, settings);
    let filtered = |spp, caustic_paths| RenderSettings {
        filter: wavetrace::PixelFilter::CYCLES,
        ..settings(spp, caustic_paths)
    };
    let with = both(&filtered(96, 1.0));
    let without = both(&filtered(384, 0.0));
    assert_parts_agree(
        "glass caustic, Blackman-Harris",
        ["image", "caustic"],
        with,
        without,
    );
}

#[test]
fn light_paths_do_not_depend_on_threads_or_batches() {
    let scene = glass_caustic_scene();
    let base = RenderSettings {
        width: 40,
        height: 30,
        spp: 3,
        ..Default::default()
    };
    let (one, _) = render_with_threads(&scene, &base, 1);
    let (three, stats) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 77,
            ..base
        },
        3,
    );
    assert!(stats.light_rays > 0, "light paths were traced");
    assert_eq!(one.pixels, three.pixels);
    // Adaptive sampling too (pixels that stop drop the splats that land on them).
    let adaptive = RenderSettings {
        spp: 8,
        adaptive: Some(wavetrace::settings::Adaptive {
            noise_threshold: 0.5,
            min_spp: 2,
            denoised: None,
        }),
        ..base
    };
    let (one, _) = render_with_threads(&scene, &adaptive, 1);
    let (three, _) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 100,
            ..adaptive
        },
        3,
    );
    assert_eq!(one.pixels, three.pixels);
}

/// The mirror scene of [`area_light_scene`] with a larger light (half-width 0.6 at z = 0.3,
/// facing the mirror) and a diffuse wall at x = -1.9 standing on the floor up to the mirror;
/// the camera, below the light, looks at the wall. The wall is lit through the mirror
/// (a caustic seen directly) and by the floor, which the mirror lights: camera -> wall ->
/// floor -> mirror -> light, a caustic seen after a diffuse bounce. The twin replaces the
/// mirror by the mirror image of everything below it (the wall continued up to z = 4, a floor
/// at z = 4 facing down, the light at z = 3.7 facing down), where next-event estimation finds
/// those paths.
fn wall_scene(twin: bool) -> RenderScene {
    let mut toml = r#"
[camera]
eye = [1.5, 0.0, 0.25]
look_at = [-1.9, 0.0, 0.8]
up = [0.0, 0.0, 1.0]
vfov = 50.0

[materials]
floor = { type = "diffuse", albedo = [0.5, 0.6, 0.7] }
wall = { type = "diffuse", albedo = [0.8, 0.7, 0.6] }
mirror = { type = "mirror" }
black = { type = "diffuse", albedo = [0.0, 0.0, 0.0] }
"#
    .to_string();
    let wall_top = if twin { 4.0 } else { 2.0 };
    toml += &format!(
        "[[shape]]\nname = \"wall\"\ntype = \"quad\"\nmaterial = \"wall\"\n\
         vertices = [[-1.9, -2, 0], [-1.9, 2, 0], [-1.9, 2, {wall_top}], [-1.9, -2, {wall_top}]]\n"
    );
    toml += &square("floor", "floor", 0.0, 2.0, true, None);
    toml += &square("light", "black", 0.3, 0.6, true, Some(10.0));
    if twin {
        toml += &square("mirrored floor", "floor", 4.0, 2.0, false, None);
        toml += &square("mirrored light", "black", 3.7, 0.6, false, Some(10.0));
    } else {
        toml += &square("mirror", "mirror", 2.0, 2.0, false, None);
    }
    scene_from_toml(&toml)
}

/// Caustics seen after a diffuse bounce, closed form: the wall lit by the floor that a mirror
/// lights (connections of camera vertices to the light paths' diffuse points, weighted
/// against the path tracer) equals the wall of the twin scene, lit by the mirrored light
/// through next-event estimation.
#[test]
fn wall_lit_through_a_mirror_after_a_diffuse_bounce_equals_its_mirror_image() {
    // With the connections' weight set to 1 (counting these paths twice) the image mean
    // is 1.4% too high: 5.4 standard errors at these sample counts.
    let (lit, twin) = (wall_scene(false), wall_scene(true));
    assert_lit_as_its_twin("the wall", &lit, &twin, (512, 128));
}

/// Caustics seen after a diffuse bounce, estimator against estimator: in the glass sphere's
/// box, the image and a block of the back wall near the floor (which the caustic on the floor
/// lights) have the same mean with the connections as without them (light paths on) and as
/// with no light paths at all.
#[test]
fn glass_caustic_seen_after_a_bounce_equals_the_estimate_without_connections() {
    let scene = glass_caustic_scene();
    // The back wall just above the floor, left of the glass sphere (a 128 x 128 render shows
    // it at columns 24-56, rows 56-72).
    let (x0, y0) = (6, 14);
    let both = |settings: &RenderSettings| {
        let (a, b) = independent_pair(&scene, settings);
        vec![
            mean_and_error(&a, &b),
            block_estimate(&a, &b, x0..x0 + 8, y0..y0 + 4),
        ]
    };
    let with = both(&settings(256, 1.0));
    let without = both(&RenderSettings {
        caustic_connections: false,
        ..settings(512, 1.0)
    });
    let path_tracer = both(&settings(512, 0.0));
    assert_parts_agree("connections", ["image", "wall"], with.clone(), without);
    assert_parts_agree("path tracer", ["image", "wall"], with, path_tracer);
}

/// Connections through a rough transmitting surface (rays from its back side, the general
/// shading path): the glass sphere's box seen through a pane of frosted glass (`pbr`,
/// transmission 1, roughness 0.2) that spans the box in front of the camera, so that the
/// caustic is seen through it. The image and the block around the caustic have the same mean
/// with and without the connections. A weak check, the path tracer's estimate through the
/// pane being noisy: it catches gross errors (a NaN, a wrong side), not a factor of 2 on the
/// connections through the pane (+11% in the caustic block, 1.4 standard errors, also at 512
/// and 2048 spp).
#[test]
fn caustic_seen_through_frosted_glass_equals_the_estimate_without_connections() {
    let text = glass_caustic_scene_text().replace(
        "black = { type = \"diffuse\", albedo = [0, 0, 0] }",
        "black = { type = \"diffuse\", albedo = [0, 0, 0] }\n\
         frosted = { type = \"pbr\", base_color = [1, 1, 1], roughness = 0.2, transmission = 1.0 }",
    ) + "[[shape]]\ntype = \"quad\"\nmaterial = \"frosted\"\n\
         vertices = [[-1, -0.5, -1], [1, -0.5, -1], [1, -0.5, 1], [-1, -0.5, 1]]\n";
    let scene = scene_from_toml(&text);
    let both = |settings: &RenderSettings| {
        let (a, b) = independent_pair(&scene, settings);
        vec![
            mean_and_error(&a, &b),
            block_estimate(&a, &b, 12..20, 17..25),
        ]
    };
    let with = both(&settings(256, 1.0));
    let without = both(&RenderSettings {
        caustic_connections: false,
        ..settings(512, 1.0)
    });
    assert_parts_agree("frosted glass", ["image", "caustic"], with, without);
}
