//! Fuzzes the glTF importer through `load_scene` (import, placement or camera framing), the
//! flattening that validates the world, and a tiny render. An input that starts with the
//! binary magic `glTF` is read as `model.glb`, any other as `model.gltf` (JSON).
//! Crashes become regression tests in tests/fuzz_regressions.rs.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;
use wavetrace::{Flow, RenderSettings};

/// A private directory in memory for the file of one input.
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(format!("/dev/shm/wavetrace-fuzz-gltf-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") {
        "model.glb"
    } else {
        "model.gltf"
    };
    let path = scratch().join(name);
    std::fs::write(&path, data).unwrap();
    let result = wavetrace::load_scene(&path);
    let _ = std::fs::remove_file(&path);
    let Ok(scene) = result else {
        return;
    };
    let Ok(flat) = wavetrace::flatten(&scene.world, &path) else {
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
});
