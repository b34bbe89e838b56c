//! The Sobol sampler (`math::sobol` through `rng::Sampler`): deterministic like the
//! independent one, unbiased (same image mean), and with less noise per sample.

use crate::common::*;
use wavetrace::RenderSettings;
use wavetrace::math::rng::Sampler;

fn settings() -> RenderSettings {
    RenderSettings {
        width: 48,
        height: 40,
        spp: 16,
        sampler: Sampler::Sobol,
        ..Default::default()
    }
}

#[test]
fn sobol_images_do_not_depend_on_threads_or_batches() {
    let scene = room();
    let settings = RenderSettings {
        spp: 3,
        shadow_rays: 2,
        batch_size: 700,
        ..settings()
    };
    let (one, _) = render_with_threads(&scene, &settings, 1);
    let (two, _) = render_with_threads(
        &scene,
        &RenderSettings {
            batch_size: 4096,
            ..settings
        },
        2,
    );
    assert_finite(&one);
    assert!(one == two, "threads or batch size changed the image");
    let (independent, _) = render_with_threads(
        &scene,
        &RenderSettings {
            sampler: Sampler::Independent,
            ..settings
        },
        2,
    );
    assert!(one != independent, "the sampler has an effect");
}

#[test]
fn sobol_sampler_agrees_with_the_independent_one_and_is_less_noisy() {
    // The room's image mean by both samplers (two seeds each, so each has its standard
    // error from the difference of its two images: pixels are independent either way, each
    // pixel having its own scrambles).
    let scene = room();
    let settings = RenderSettings {
        spp: 64,
        ..settings()
    };
    let sobol = estimate(&scene, &settings);
    let independent = estimate(
        &scene,
        &RenderSettings {
            sampler: Sampler::Independent,
            ..settings
        },
    );
    assert_agree("sobol vs independent", sobol, independent, 4.0);
    // Stratified camera jitter, light points and BSDF directions: less variance per
    // pixel, so a smaller standard error of the mean from as many samples.
    for c in 0..3 {
        let ratio = sobol.1[c] / independent.1[c];
        eprintln!("channel {c}: standard error ratio sobol / independent {ratio:.3}");
        assert!(ratio < 0.9, "channel {c}: {ratio}");
    }
}
