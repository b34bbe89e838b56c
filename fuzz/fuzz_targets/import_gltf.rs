//! Fuzzes the glTF importer through `load_scene` (import, placement or camera framing), the
//! flattening that validates the world, and a tiny render. An input that starts with the
//! binary magic `glTF` is read as `model.glb`, any other as `model.gltf` (JSON).
//! Crashes become regression tests in tests/e2e/fuzz_regressions.rs.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let name = if data.starts_with(b"glTF") {
        "model.glb"
    } else {
        "model.gltf"
    };
    let path = common::scratch("gltf").join(name);
    std::fs::write(&path, data).unwrap();
    let result = wavetrace::load_scene(&path);
    let _ = std::fs::remove_file(&path);
    let Ok(scene) = result else {
        return;
    };
    common::flatten_and_render(&scene, &path);
});
