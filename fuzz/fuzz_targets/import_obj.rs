//! Fuzzes the OBJ/MTL importer through `load_scene` (import, placement in the room, camera),
//! the flattening that validates the world, and a tiny render. The input is an OBJ file,
//! optionally followed by a line `#MTL` and the material library `model.mtl` it may name.
//! Crashes become regression tests in tests/e2e/fuzz_regressions.rs.
#![no_main]

mod common;

use libfuzzer_sys::fuzz_target;

fn split_at_marker<'a>(data: &'a [u8], marker: &[u8]) -> (&'a [u8], Option<&'a [u8]>) {
    match data.windows(marker.len()).position(|w| w == marker) {
        Some(i) => (&data[..i], Some(&data[i + marker.len()..])),
        None => (data, None),
    }
}

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = split_at_marker(data, b"\n#MTL\n");
    let path = common::scratch("obj").join("model.obj");
    let mtl_path = common::scratch("obj").join("model.mtl");
    std::fs::write(&path, obj).unwrap();
    match mtl {
        Some(mtl) => std::fs::write(&mtl_path, mtl).unwrap(),
        None => {
            let _ = std::fs::remove_file(&mtl_path);
        }
    }
    let Ok(scene) = wavetrace::load_scene(&path) else {
        return;
    };
    common::flatten_and_render(&scene, &path);
});
