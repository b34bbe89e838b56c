//! Every scene shipped in `scenes/` loads, flattens and renders (small) without a single NaN or
//! infinite sample: the film discards and counts such samples, and the count must stay 0.

use std::path::PathBuf;
use wavetrace::{Flow, RenderSettings, flatten, load_scene, render};

#[test]
fn shipped_scenes_render_without_nan_or_infinite_samples() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    assert!(!scenes.is_empty());
    for path in &scenes {
        let scene = load_scene(path).unwrap_or_else(|e| panic!("{e}"));
        let flat = flatten(&scene.world, path).unwrap();
        let settings = RenderSettings {
            width: 48,
            height: 48,
            spp: 16,
            shadow_rays: scene.defaults.shadow_rays.unwrap_or(1),
            ..Default::default()
        };
        let (film, stats) = render(&flat, &settings, |_| Flow::Continue).unwrap();
        assert_eq!(
            stats.rejected_samples,
            0,
            "{}: {} NaN/infinite samples",
            path.display(),
            stats.rejected_samples
        );
        assert_eq!(film.min_samples(), 16, "{}", path.display());
        assert!(!stats.interrupted);
    }
}
