//! Runs the `wavetrace` binary on bad inputs made here, in a temporary directory: every case
//! must end with exit code 1 (2 for a usage error), one `error:` line on stderr that names the
//! file, the place in it and the problem, no panic, and no output file created or changed.

use crate::common::{check_failure, files_in};

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// A small valid scene; the cases below replace single lines of it, so that the line numbers
/// in the expected messages can be read off here (line 1 is `[camera]`).
const GOOD: &str = "\
[camera]
eye = [0, 0, 0]
look_at = [1, 0, 0]
vfov = 60
[materials]
white = { type = \"diffuse\", albedo = [0.5, 0.5, 0.5] }
[[shape]]
type = \"sphere\"
material = \"white\"
center = [3, 0, 0]
radius = 1
";

/// `GOOD` with its 1-based line `line` replaced by `with` ("" deletes the line's content).
fn edited(line: usize, with: &str) -> String {
    GOOD.lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == line { with } else { l })
        .collect::<Vec<_>>()
        .join("\n")
        + "\n"
}

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

/// Renders `scene` (tiny, one sample) into `output` and returns what the process did.
fn render(scene: &Path, output: &Path, extra: &[&str]) -> Output {
    wavetrace()
        .args([
            "render", "-q", "--width", "4", "--height", "4", "--spp", "1",
        ])
        .arg(scene)
        .arg("-o")
        .arg(output)
        .args(extra)
        .output()
        .expect("the binary runs")
}

/// Checks the exit code, that stderr is one `error:` line containing every `fragment`, and
/// that it shows no panic.
fn assert_fails(out: &Output, code: i32, fragments: &[&str]) {
    if let Err(problem) = check_failure(out, code, fragments) {
        panic!("{problem}");
    }
}

struct Case {
    file: &'static str,
    text: String,
    expect: &'static [&'static str],
}

fn scene_cases() -> Vec<Case> {
    let case = |file, text: String, expect| Case { file, text, expect };
    vec![
        case("empty.toml", "  \n".into(), &["file is empty"]),
        case(
            "syntax.toml",
            edited(4, "vfov = = 60"),
            &["line 4, column 8", "extra `=`"],
        ),
        case(
            "unclosed.toml",
            edited(5, "[materials"),
            &["line 5, column 11", "expected `]`"],
        ),
        case(
            "wrong_type.toml",
            edited(4, "vfov = \"wide\""),
            &[
                "line 4, column 8",
                "invalid type: string \"wide\", expected f32",
            ],
        ),
        case(
            "unknown_key.toml",
            edited(4, "vfof = 60"),
            &[
                "line 4, column 1",
                "unknown field `vfof`",
                "did you mean `vfov`?",
            ],
        ),
        case(
            "unknown_table.toml",
            edited(5, "[materails]"),
            &["line 5, column 2", "did you mean `materials`?"],
        ),
        case(
            "unknown_shape_type.toml",
            edited(8, "type = \"sphre\""),
            &[
                "line 8, column 8",
                "unknown variant `sphre`",
                "did you mean `sphere`?",
            ],
        ),
        case(
            "missing_key.toml",
            edited(4, ""),
            &["line 1, column 1", "missing field `vfov`"],
        ),
        case(
            "no_camera.toml",
            GOOD.replace(
                "[camera]\neye = [0, 0, 0]\nlook_at = [1, 0, 0]\nvfov = 60\n",
                "",
            ),
            &["the scene has no [camera]"],
        ),
        case(
            "unknown_material.toml",
            edited(9, "material = \"whte\""),
            &[
                "line 9, column 12",
                "unknown material 'whte'",
                "did you mean 'white'?",
            ],
        ),
        case(
            "unknown_material_far.toml",
            edited(9, "material = \"chrome\""),
            &[
                "line 9, column 12",
                "unknown material 'chrome'",
                "known: white",
            ],
        ),
        case(
            "negative_radius.toml",
            edited(11, "radius = -1"),
            &[
                "line 7, column 1",
                "radius must be a positive number, got -1",
            ],
        ),
        case(
            "zero_radius.toml",
            edited(11, "radius = 0"),
            &[
                "line 7, column 1",
                "radius must be a positive number, got 0",
            ],
        ),
        case(
            "nan_radius.toml",
            edited(11, "radius = nan"),
            &[
                "line 7, column 1",
                "radius must be a positive number, got NaN",
            ],
        ),
        case(
            "infinite_center.toml",
            edited(10, "center = [inf, 0, 0]"),
            &["line 7, column 1", "center must be finite numbers"],
        ),
        case(
            "huge_sphere.toml",
            edited(10, "center = [3e38, 0, 0]").replace("radius = 1", "radius = 3e38"),
            &["line 7, column 1", "the sphere's bounds overflow"],
        ),
        case(
            "far_camera.toml",
            edited(2, "eye = [3e38, 0, 0]")
                .replace("look_at = [1, 0, 0]", "look_at = [-3e38, 0, 0]"),
            &["line 1, column 1", "eye and look_at are too far apart"],
        ),
        case(
            "nan_albedo.toml",
            edited(
                6,
                "white = { type = \"diffuse\", albedo = [nan, 0.5, 0.5] }",
            ),
            &[
                "line 6, column 9",
                "material 'white': albedo must be finite numbers",
            ],
        ),
        case(
            "infinite_eye.toml",
            edited(2, "eye = [0, -inf, 0]"),
            &["line 1, column 1", "camera: eye must be finite numbers"],
        ),
        case(
            "zero_fov.toml",
            edited(4, "vfov = 0"),
            &[
                "line 1, column 1",
                "vfov must lie in (0, 180) degrees, got 0",
            ],
        ),
        case(
            "absurd_width.toml",
            GOOD.to_string() + "[render]\nwidth = 1000000\n",
            &[
                "line 13, column 9",
                "width 1000000 is outside the accepted range 1..=32768",
            ],
        ),
        case(
            "absurd_pixels.toml",
            GOOD.to_string() + "[render]\nwidth = 30000\nheight = 30000\n",
            &[
                "line 14, column 10",
                "image size 30000x30000 exceeds the limit of 134217728 pixels",
            ],
        ),
        case(
            "negative_width.toml",
            GOOD.to_string() + "[render]\nwidth = -8\n",
            &[
                "line 13, column 9",
                "invalid value: integer `-8`, expected u32",
            ],
        ),
        case(
            "zero_spp.toml",
            GOOD.to_string() + "[render]\nspp = 0\n",
            &[
                "line 13, column 7",
                "spp (samples per pixel) must be at least 1, got 0",
            ],
        ),
        case(
            "zero_shadow_rays.toml",
            GOOD.to_string() + "[render]\nshadow_rays = 0\n",
            &[
                "line 13, column 15",
                "shadow_rays 0 is outside the accepted range 1..=1024",
            ],
        ),
        case(
            "missing_include.toml",
            format!("include = [\"nowhere.toml\"]\n{GOOD}"),
            &[
                "line 1, column 12",
                "included file",
                "nowhere.toml' does not exist",
            ],
        ),
        case(
            "unknown_filter.toml",
            format!("{GOOD}[render]\nfilter = \"sinc\"\n"),
            &["line 13, column 10", "unknown variant `sinc`"],
        ),
        case(
            "bad_filter_width.toml",
            format!("{GOOD}[render]\nfilter_width = 0\n"),
            &["line 13, column 16", "pixel filter width", "got 0"],
        ),
        case(
            "cycle_a.toml",
            format!("include = [\"cycle_b.toml\"]\n{GOOD}"),
            // reported in cycle_b.toml, where the include closes the cycle
            &["cycle_b.toml", "line 1, column 12", "include cycle"],
        ),
        case(
            "unknown_extension.tomll",
            GOOD.to_string(),
            &["unknown scene file extension (expected .toml, .gltf, .glb or .obj)"],
        ),
    ]
}

#[test]
fn bad_scene_files_fail_with_one_clear_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let cases = scene_cases();
    for case in &cases {
        std::fs::write(dir.path().join(case.file), &case.text).unwrap();
    }
    std::fs::write(
        dir.path().join("cycle_b.toml"),
        "include = [\"cycle_a.toml\"]\n",
    )
    .unwrap();
    let mut failures = Vec::new();
    for case in &cases {
        let scene = dir.path().join(case.file);
        let out = render(&scene, &out_dir.join("image.png"), &[]);
        let mut expect = vec![case.file];
        if case.file == "cycle_a.toml" {
            expect.clear();
        }
        expect.extend_from_slice(case.expect);
        if let Err(problem) = check_failure(&out, 1, &expect) {
            failures.push(format!("{}: {problem}", case.file));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(files_in(&out_dir).is_empty(), "{:?}", files_in(&out_dir));
}

#[test]
fn missing_unreadable_and_directory_scenes_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("image.png");
    let out = render(&dir.path().join("missing.toml"), &image, &[]);
    assert_fails(
        &out,
        1,
        &["missing.toml", "cannot read", "No such file or directory"],
    );
    let folder = dir.path().join("folder.toml");
    std::fs::create_dir(&folder).unwrap();
    let out = render(&folder, &image, &[]);
    assert_fails(&out, 1, &["folder.toml", "is a directory, not a file"]);
    let binary = dir.path().join("binary.toml");
    std::fs::write(&binary, [0xff, 0xfe, 0x00, 0x41]).unwrap();
    let out = render(&binary, &image, &[]);
    assert_fails(&out, 1, &["binary.toml", "cannot read", "valid UTF-8"]);
    assert_eq!(files_in(dir.path()), ["binary.toml", "folder.toml"]);
}

#[test]
fn bad_flags_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("good.toml");
    std::fs::write(&scene, GOOD).unwrap();
    let image = dir.path().join("image.png");
    for (flag, value, problem) in [
        ("--width", "0", "0 is not in 1..=32768"),
        ("--height", "40000", "40000 is not in 1..=32768"),
        ("--spp", "0", "0 is not in 1.."),
        ("--shadow-rays", "0", "0 is not in 1..=1024"),
        ("--time", "0s", "the time budget must be more than zero"),
        ("--time", "soon", "--time"),
        ("--exposure", "nan", "exposure must lie in -64..=64 stops"),
        ("--threads", "0", "0 is not in 1..=1024"),
        ("--filter", "sinc", "invalid value 'sinc'"),
        (
            "--filter-width",
            "0",
            "pixel filter width must be a number of pixels in (0, 16]",
        ),
        ("--filter-width", "-1", "got -1"),
        ("--filter-width", "nan", "got NaN"),
        ("--filter-width", "17", "got 17"),
    ] {
        let out = wavetrace()
            .args(["render", "-q"])
            .arg(&scene)
            .arg("-o")
            .arg(&image)
            .args([flag, value])
            .output()
            .unwrap();
        assert_fails(&out, 2, &[flag, problem]);
    }
    assert_eq!(files_in(dir.path()), ["good.toml"]);
}

#[test]
fn unwritable_outputs_fail_before_rendering_and_keep_existing_images() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("good.toml");
    std::fs::write(&scene, GOOD).unwrap();
    let missing_dir = dir.path().join("no-such-dir").join("image.png");
    assert_fails(
        &render(&scene, &missing_dir, &[]),
        1,
        &[
            "no-such-dir",
            "image.png",
            "output directory",
            "does not exist",
        ],
    );
    assert_fails(
        &render(&scene, &dir.path().join("image.jpg"), &[]),
        1,
        &[
            "image.jpg",
            "unknown output extension (expected .png or .exr)",
        ],
    );
    let folder = dir.path().join("folder.png");
    std::fs::create_dir(&folder).unwrap();
    assert_fails(
        &render(&scene, &folder, &[]),
        1,
        &["folder.png", "is a directory, not a file"],
    );
    // sysfs refuses new files even to root (CI runs the tests as root, where permission bits
    // on a temporary directory would not stop anything).
    let forbidden = PathBuf::from("/sys/wavetrace-test-image.png");
    assert_fails(
        &render(&scene, &forbidden, &[]),
        1,
        &[
            "wavetrace-test-image.png",
            "cannot write",
            "Permission denied",
        ],
    );
    // A failing render never touches an image that is already there.
    let existing = dir.path().join("existing.png");
    std::fs::write(&existing, b"an earlier render").unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, edited(11, "radius = 0")).unwrap();
    assert_fails(&render(&bad, &existing, &[]), 1, &["bad.toml"]);
    assert_eq!(std::fs::read(&existing).unwrap(), b"an earlier render");
    assert_eq!(
        files_in(dir.path()),
        ["bad.toml", "existing.png", "folder.png", "good.toml"]
    );
}

#[test]
fn a_good_render_replaces_the_image_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("good.toml");
    std::fs::write(&scene, GOOD).unwrap();
    for name in ["image.png", "image.exr"] {
        let image = dir.path().join(name);
        std::fs::write(&image, b"an earlier render").unwrap();
        let out = render(&scene, &image, &[]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_ne!(std::fs::read(&image).unwrap(), b"an earlier render");
    }
    let written = wavetrace::output::read_exr(&dir.path().join("image.exr")).unwrap();
    assert_eq!((written.width, written.height), (4, 4));
    // no temporary file is left beside the image
    assert_eq!(
        files_in(dir.path()),
        ["good.toml", "image.exr", "image.png"]
    );
}
