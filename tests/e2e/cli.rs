//! The command line renders scene files to valid PNG and OpenEXR images of the asked size,
//! from any working directory.

use std::path::Path;
use std::process::Command;

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

fn room_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml")
}

#[test]
fn render_writes_png_and_exr_of_the_asked_size() {
    let dir = tempfile::tempdir().unwrap();
    for (name, w, h) in [("room.png", 40, 30), ("room.exr", 24, 36)] {
        let out = dir.path().join(name);
        let status = wavetrace()
            .current_dir(dir.path()) // not the repository: nothing may be read relative to it
            .args([
                "render",
                room_path().to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ])
            .args([
                "--width",
                &w.to_string(),
                "--height",
                &h.to_string(),
                "--spp",
                "2",
                "--shadow-rays",
                "2",
            ])
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "{}",
            String::from_utf8_lossy(&status.stderr)
        );
        let stderr = String::from_utf8_lossy(&status.stderr);
        assert!(
            stderr.contains("rays/s") && stderr.contains("samples/s"),
            "summary line missing: {stderr}"
        );
        if name.ends_with(".png") {
            let img = image::open(&out).unwrap().to_rgb8();
            assert_eq!((img.width(), img.height()), (w, h));
            assert!(img.pixels().any(|p| p.0 != [0, 0, 0]));
        } else {
            let img = wavetrace::output::read_exr(&out).unwrap();
            assert_eq!((img.width, img.height), (w, h));
            assert!(img.pixels.iter().all(|p| p.is_finite()) && img.mean().max_element() > 0.0);
        }
        // No temporary file is left beside the output.
        let leftovers: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
            .collect();
        assert!(leftovers.is_empty());
    }
}

#[test]
fn default_output_is_named_after_the_scene_in_the_working_directory() {
    let dir = tempfile::tempdir().unwrap();
    let status = wavetrace()
        .current_dir(dir.path())
        .args([
            "render",
            room_path().to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
            "--spp",
            "1",
            "--quiet",
        ])
        .output()
        .unwrap();
    assert!(status.status.success());
    // --quiet: nothing on success (the room gives no warnings).
    assert_eq!(String::from_utf8_lossy(&status.stderr), "");
    assert!(dir.path().join("room.png").is_file());
}
