//! Replays every input that ever crashed a fuzz target (`fuzz/`, see the README), so that CI
//! keeps the fixes without running the fuzzer: `fuzz_regressions/TARGET/*` go through the same
//! steps as the target (load, flatten, a tiny render), which must end in `Ok` or `Err`.

use std::path::{Path, PathBuf};
use wavetrace::{Flow, RenderSettings};

fn inputs(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fuzz_regressions")
        .join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
    files.sort();
    files
}

/// What every fuzz target does after loading: flatten, then render 3x2 pixels.
fn flatten_and_render(scene: wavetrace::Scene, path: &Path) {
    if let Ok(flat) = wavetrace::flatten(&scene.world, path) {
        let settings = RenderSettings {
            width: 3,
            height: 2,
            spp: 1,
            max_depth: 16,
            ..Default::default()
        };
        let (_, stats) = wavetrace::render(&flat, &settings, |_| Flow::Continue).unwrap();
        assert_eq!(stats.samples, 6);
    }
}

#[test]
fn scene_toml_crashes_stay_fixed() {
    let files = inputs("scene_toml");
    assert!(!files.is_empty());
    for file in files {
        let text = String::from_utf8_lossy(&std::fs::read(&file).unwrap()).into_owned();
        // as in the fuzz target: relative includes lead nowhere
        let path = Path::new("/nonexistent-fuzz-dir/scene.toml");
        if let Ok(scene) = wavetrace::scene::load_scene_str(path, &text) {
            flatten_and_render(scene, path);
        }
    }
}

/// The part of `data` before `marker` and, if the marker occurs, the part after it.
fn split_at_marker<'a>(data: &'a [u8], marker: &[u8]) -> (&'a [u8], Option<&'a [u8]>) {
    match data.windows(marker.len()).position(|w| w == marker) {
        Some(i) => (&data[..i], Some(&data[i + marker.len()..])),
        None => (data, None),
    }
}

#[test]
fn import_obj_crashes_stay_fixed() {
    for file in inputs("import_obj") {
        let data = std::fs::read(&file).unwrap();
        // as in the fuzz target: an OBJ, then optionally `#MTL` and its material library
        let (obj, mtl) = split_at_marker(&data, b"\n#MTL\n");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.obj");
        std::fs::write(&path, obj).unwrap();
        if let Some(mtl) = mtl {
            std::fs::write(dir.path().join("model.mtl"), mtl).unwrap();
        }
        if let Ok(scene) = wavetrace::load_scene(&path) {
            flatten_and_render(scene, &path);
        }
    }
}

#[test]
fn import_gltf_crashes_stay_fixed() {
    for file in inputs("import_gltf") {
        let data = std::fs::read(&file).unwrap();
        let name = if data.starts_with(b"glTF") {
            "model.glb"
        } else {
            "model.gltf"
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, &data).unwrap();
        if let Ok(scene) = wavetrace::load_scene(&path) {
            flatten_and_render(scene, &path);
        }
    }
}
