//! Fuzzes the OBJ/MTL importer through `load_scene` (import, placement in the room, camera),
//! the flattening that validates the world, and a tiny render. The input is an OBJ file,
//! optionally followed by a line `#MTL` and the material library `model.mtl` it may name.
//! Crashes become regression tests in tests/fuzz_regressions.rs.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;
use wavetrace::{Flow, RenderSettings};

/// A private directory in memory for the files of one input.
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(format!("/dev/shm/wavetrace-fuzz-obj-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    })
}

fn split_at_marker<'a>(data: &'a [u8], marker: &[u8]) -> (&'a [u8], Option<&'a [u8]>) {
    match data.windows(marker.len()).position(|w| w == marker) {
        Some(i) => (&data[..i], Some(&data[i + marker.len()..])),
        None => (data, None),
    }
}

fuzz_target!(|data: &[u8]| {
    let (obj, mtl) = split_at_marker(data, b"\n#MTL\n");
    let path = scratch().join("model.obj");
    let mtl_path = scratch().join("model.mtl");
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
