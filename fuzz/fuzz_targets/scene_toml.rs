//! Fuzzes the TOML scene loader and the flattening that follows it: any text must give a
//! scene or an `Err`, never a panic (crashes become regression tests in tests/fuzz_regressions.rs).
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    // Relative includes resolve against a directory that does not exist, so they fail fast;
    // `builtin:room` still reaches the include code path.
    let path = Path::new("/nonexistent-fuzz-dir/scene.toml");
    if let Ok(scene) = wavetrace::scene::load_scene_str(path, text) {
        let _ = wavetrace::flatten(&scene.world, path);
    }
});
