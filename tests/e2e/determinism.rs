//! The image is a function of scene, settings and seed only: not of the thread count or the
//! batch size.

use crate::common::*;
use wavetrace::RenderSettings;

#[test]
fn same_seed_same_image_any_thread_count_or_batch_size() {
    let scene = room();
    let settings = RenderSettings {
        width: 48,
        height: 40,
        spp: 3,
        shadow_rays: 2,
        batch_size: 700,
        ..Default::default()
    };
    let (one, _) = render_with_threads(&scene, &settings, 1);
    let (two, _) = render_with_threads(&scene, &settings, 2);
    let (three, _) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 4096,
            ..settings
        },
        3,
    );
    assert_finite(&one);
    assert!(
        one.pixels.iter().any(|p| p.max_element() > 0.0),
        "the render is not black"
    );
    assert!(one == two, "1 and 2 threads differ");
    assert!(one == three, "batch size changed the image");
    let (other_seed, _) = render_with_threads(
        &scene,
        &RenderSettings {
            seed: 99,
            ..settings
        },
        2,
    );
    assert!(one != other_seed, "the seed has an effect");
}
