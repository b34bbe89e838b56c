//! What every fuzz target shares: a private scratch directory for the files of one input, and
//! the path after loading (flatten, then a tiny render), which must end in `Err` or an image.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use wavetrace::scene::Scene;
use wavetrace::{Flow, RenderSettings};

/// A private directory in memory, `/dev/shm/wavetrace-fuzz-TARGET-PID`, made once (the
/// scene target reads its input from memory and has no use for it).
#[allow(dead_code)]
pub fn scratch(target: &str) -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(format!(
            "/dev/shm/wavetrace-fuzz-{target}-{}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

/// Flattens a loaded scene (named `path` in errors) and renders a 3x2 image of it.
pub fn flatten_and_render(scene: &Scene, path: &Path) {
    let Ok(flat) = wavetrace::flatten(&scene.world, path) else {
        return;
    };
    let settings = RenderSettings {
        width: 3,
        height: 2,
        spp: 1,
        max_depth: 16,
        ..Default::default()
    };
    let _ = wavetrace::render(&flat, &settings, |_| Flow::Continue);
}
