//! Fuzzes the TOML scene loader, the flattening that validates its output, and a tiny render
//! of whatever passes: any text must give an image or an `Err`, never a panic (the fuzz build
//! has debug assertions on, so the renderer's `debug_assert!`s on valid data are checked too).
//! Crashes become regression tests in tests/e2e/fuzz_regressions.rs.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Relative includes resolve against a directory that does not exist, so they fail fast;
    // `builtin:room` still reaches the include code path.
    let path = Path::new("/nonexistent-fuzz-dir/scene.toml");
    let Ok(scene) = wavetrace::scene::load_scene_str(path, text) else {
        return;
    };
    common::flatten_and_render(&scene, path);
});
