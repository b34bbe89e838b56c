//! glTF animation playback: node translation, rotation and scale with LINEAR, STEP and
//! CUBICSPLINE samplers where the glTF specification puts them, a skin posed by an animated
//! joint, animated morph weights, bad channels skipped with a warning, and the command line's
//! `--frame`, `--frames`, `--skip-existing` and `--animation`. Every file is written by the
//! test (`+Z` up, so that file and world coordinates agree).

use crate::common::{GltfDoc, check_failure, files_in, world_vertices};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::process::Command;
use wavetrace::Scene;
use wavetrace::math::{Quat, Vec3};
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::scene::{AnimationChoice, SharedMesh, Transform};

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
const FPS: f32 = 24.0;

/// A file with one triangle on node 0 and one animation whose sampler reads `times` and
/// `output` (accessors of `doc`), animating node 0's `path` with `interpolation`.
fn animated_file(
    dir: &Path,
    name: &str,
    mut doc: GltfDoc,
    channels: Value,
    samplers: Value,
) -> PathBuf {
    let p = doc.positions(&TRIANGLE);
    doc.write(
        dir,
        name,
        json!({
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "name": "tri"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": p}}]}],
            "animations": [{"name": "Move", "channels": channels, "samplers": samplers}],
        }),
    )
}

/// One channel on node 0 and its sampler.
fn one_channel(
    dir: &Path,
    name: &str,
    path: &str,
    interpolation: &str,
    times: &[f32],
    values: &[[f32; 3]],
) -> PathBuf {
    let mut doc = GltfDoc::default();
    let t = doc.floats(&times.iter().map(|&t| [t]).collect::<Vec<_>>(), "SCALAR");
    let v = doc.floats(values, "VEC3");
    animated_file(
        dir,
        name,
        doc,
        json!([{"sampler": 0, "target": {"node": 0, "path": path}}]),
        json!([{"input": t, "output": v, "interpolation": interpolation}]),
    )
}

fn load(path: &Path) -> Scene {
    import_model(path, UpAxis::Z).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The world-space vertices after posing `scene` at `frame` (at 24 fps).
fn posed(scene: &mut Scene, frame: u32) -> (Vec<Vec3>, Vec<String>) {
    let warnings = scene
        .pose(&AnimationChoice::First, frame as f32 / FPS)
        .unwrap_or_else(|e| panic!("poses: {e}"));
    let points = world_vertices(scene).into_iter().map(|(p, _)| p).collect();
    (points, warnings)
}

fn assert_near(got: Vec3, want: Vec3) {
    assert!((got - want).length() < 1e-5, "{got} != {want}");
}

#[test]
fn linear_translation_puts_the_object_where_the_spec_says_at_frames_0_12_24() {
    let dir = tempfile::tempdir().unwrap();
    let path = one_channel(
        dir.path(),
        "move.gltf",
        "translation",
        "LINEAR",
        &[0.0, 1.0],
        &[[0.0, 0.0, 0.0], [2.0, 0.0, 4.0]],
    );
    let mut scene = load(&path);
    assert!(scene.is_animated());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for (frame, want) in [
        (0, Vec3::ZERO),
        (12, Vec3::new(1.0, 0.0, 2.0)),
        (24, Vec3::new(2.0, 0.0, 4.0)),
    ] {
        let (points, warnings) = posed(&mut scene, frame);
        assert_near(points[0], want);
        assert_near(points[1], want + Vec3::X);
        assert!(warnings.is_empty(), "{warnings:?}");
    }
    // Past the end: the last pose holds, and the warning says so.
    let (points, warnings) = posed(&mut scene, 48);
    assert_near(points[0], Vec3::new(2.0, 0.0, 4.0));
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("move.gltf") && warnings[0].contains("'Move'"),
        "{warnings:?}"
    );
    // Posing again at an earlier time gives the same world as before (no drift).
    let (again, _) = posed(&mut scene, 12);
    assert_eq!(again, posed(&mut load(&path), 12).0);
}

#[test]
fn step_holds_each_key_and_cubic_spline_follows_its_tangents() {
    let dir = tempfile::tempdir().unwrap();
    let path = one_channel(
        dir.path(),
        "step.gltf",
        "scale",
        "STEP",
        &[0.0, 1.0, 2.0],
        &[[1.0; 3], [2.0; 3], [3.0; 3]],
    );
    let mut scene = load(&path);
    assert_near(posed(&mut scene, 23).0[1], Vec3::X);
    assert_near(posed(&mut scene, 36).0[1], Vec3::X * 2.0);
    assert_near(posed(&mut scene, 48).0[1], Vec3::X * 3.0);

    // From x = 0 to x = 1 over 2 s, leaving with 1/s and arriving with 0 (in-tangent, value,
    // out-tangent per key).
    let path = one_channel(
        dir.path(),
        "cubic.gltf",
        "translation",
        "CUBICSPLINE",
        &[0.0, 2.0],
        &[
            [0.0; 3],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0; 3],
            [1.0, 0.0, 0.0],
            [0.0; 3],
        ],
    );
    let mut scene = load(&path);
    let (s, interval) = (0.25f32, 2.0f32); // frame 12 = 0.5 s
    let hermite = (-2.0 * s.powi(3) + 3.0 * s * s) + interval * (s.powi(3) - 2.0 * s * s + s);
    assert_near(posed(&mut scene, 12).0[0], Vec3::new(hermite, 0.0, 0.0));
    assert_near(posed(&mut scene, 48).0[0], Vec3::X);
}

#[test]
fn rotation_is_slerped_halfway() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let t = doc.floats(&[[0.0], [1.0]], "SCALAR");
    let quarter = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2).to_array();
    let r = doc.floats(&[Quat::IDENTITY.to_array(), quarter], "VEC4");
    let path = animated_file(
        dir.path(),
        "turn.gltf",
        doc,
        json!([{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]),
        json!([{"input": t, "output": r}]),
    );
    let mut scene = load(&path);
    let (points, _) = posed(&mut scene, 12);
    let half = std::f32::consts::FRAC_1_SQRT_2;
    assert_near(points[1], Vec3::new(half, half, 0.0));
}

#[test]
fn a_skin_follows_its_animated_joint_and_morph_weights_animate() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let p = doc.positions(&TRIANGLE);
    let joints = doc.push(
        vec![0u8; 12],
        None,
        json!({"componentType": 5121, "count": 3, "type": "VEC4"}),
    );
    let weights = doc.floats(&[[1.0, 0.0, 0.0, 0.0]; 3], "VEC4");
    let up = doc.positions(&[[0.0, 0.0, 1.0]; 3]);
    let t = doc.floats(&[[0.0], [1.0]], "SCALAR");
    let lift = doc.floats(&[[0.0; 3], [0.0, 0.0, 3.0]], "VEC3");
    let w = doc.floats(&[[0.0], [1.0]], "SCALAR");
    let path = doc.write(
        dir.path(),
        "rig.gltf",
        json!({
            "scenes": [{"nodes": [0, 1, 2]}],
            "nodes": [
                {"mesh": 0, "skin": 0},
                {"name": "joint"},
                {"mesh": 1, "translation": [10.0, 0.0, 0.0]},
            ],
            "skins": [{"joints": [1]}],
            "meshes": [
                {"primitives": [{"attributes": {"POSITION": p, "JOINTS_0": joints, "WEIGHTS_0": weights}}]},
                {"primitives": [{"attributes": {"POSITION": p}, "targets": [{"POSITION": up}]}]},
            ],
            "animations": [{"channels": [
                {"sampler": 0, "target": {"node": 1, "path": "translation"}},
                {"sampler": 1, "target": {"node": 2, "path": "weights"}},
            ], "samplers": [{"input": t, "output": lift}, {"input": t, "output": w}]}],
        }),
    );
    let mut scene = load(&path);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let (points, _) = posed(&mut scene, 12);
    let skinned: Vec<Vec3> = points.iter().copied().filter(|p| p.x < 5.0).collect();
    let morphed: Vec<Vec3> = points.iter().copied().filter(|p| p.x >= 5.0).collect();
    assert_eq!((skinned.len(), morphed.len()), (3, 3), "{points:?}");
    for (p, rest) in skinned.iter().zip(TRIANGLE) {
        assert_near(*p, Vec3::from(rest) + Vec3::new(0.0, 0.0, 1.5));
    }
    for (p, rest) in morphed.iter().zip(TRIANGLE) {
        assert_near(*p, Vec3::from(rest) + Vec3::new(10.0, 0.0, 0.5));
    }
}

#[test]
fn bad_channels_are_skipped_with_a_warning_naming_the_file_animation_and_channel() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let two = doc.floats(&[[0.0], [1.0]], "SCALAR");
    let backwards = doc.floats(&[[1.0], [0.5]], "SCALAR");
    let three = doc.floats(&[[0.0; 3], [1.0; 3], [2.0; 3]], "VEC3");
    let nan = doc.floats(&[[0.0; 3], [f32::NAN, 0.0, 0.0]], "VEC3");
    let good = doc.floats(&[[0.0; 3], [0.0, 0.0, 1.0]], "VEC3");
    let path = animated_file(
        dir.path(),
        "bad.gltf",
        doc,
        json!([
            {"sampler": 0, "target": {"node": 0, "path": "translation"}},
            {"sampler": 1, "target": {"node": 0, "path": "translation"}},
            {"sampler": 2, "target": {"node": 0, "path": "scale"}},
            {"sampler": 3, "target": {"node": 7, "path": "translation"}},
            {"sampler": 4, "target": {"node": 0, "path": "translation"}},
        ]),
        json!([
            {"input": two, "output": three},
            {"input": backwards, "output": good},
            {"input": two, "output": nan},
            {"input": two, "output": good},
            {"input": two, "output": good},
        ]),
    );
    let mut scene = load(&path);
    let expected = [
        "channel 0: the input has 2 keys but the output 9 numbers",
        "channel 1: key times do not increase",
        "channel 2: output number 3 is NaN",
        "channel 3: node 7 does not exist",
    ];
    assert_eq!(scene.warnings.len(), expected.len(), "{:?}", scene.warnings);
    for (warning, fragment) in scene.warnings.iter().zip(expected) {
        assert!(
            warning.contains("bad.gltf")
                && warning.contains("animation 'Move' (index 0)")
                && warning.contains(fragment)
                && warning.ends_with("the channel is skipped"),
            "{warning}"
        );
    }
    // The good channel still plays.
    assert_near(posed(&mut scene, 24).0[0], Vec3::Z);
    // An animation the file does not have is an error that lists those it has.
    for choice in [
        AnimationChoice::Index(1),
        AnimationChoice::Name("Run".into()),
    ] {
        let e = scene
            .pose(&choice, 0.0)
            .expect_err("no such animation")
            .to_string();
        assert!(e.contains("bad.gltf") && e.contains("'Move'"), "{e}");
    }
}

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

/// Renders `path` at 8x8, 1 spp, with `args`, in `dir`.
fn render(dir: &Path, path: &Path, args: &[&str]) -> std::process::Output {
    wavetrace()
        .current_dir(dir)
        .args([
            "render",
            path.to_str().unwrap(),
            "--width",
            "8",
            "--height",
            "8",
        ])
        .args(["--spp", "1"])
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn frames_write_numbered_images_and_skip_existing_ones() {
    let dir = tempfile::tempdir().unwrap();
    let path = one_channel(
        dir.path(),
        "move.gltf",
        "translation",
        "LINEAR",
        &[0.0, 0.5],
        &[[0.0; 3], [0.0, 0.0, 0.5]],
    );
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    let out = render(
        dir.path(),
        &path,
        &["--frames", "0-24", "-o", "frames/f-####.png"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let names = files_in(&frames);
    let want: Vec<String> = (0..=24).map(|f| format!("f-{f:04}.png")).collect();
    assert_eq!(names, want);
    assert_eq!(stderr.matches("-> frames/f-").count(), 25, "{stderr}");
    // The animation ends at frame 12: said once, not for every later frame.
    assert_eq!(stderr.matches("ends at").count(), 1, "{stderr}");

    // A frame of the sequence equals the same frame rendered alone.
    let alone = render(dir.path(), &path, &["--frame", "7", "-o", "alone.png"]);
    assert!(alone.status.success());
    let read = |p: PathBuf| std::fs::read(p).unwrap();
    assert_eq!(
        read(dir.path().join("alone.png")),
        read(frames.join("f-0007.png"))
    );

    // A retried task renders only the missing frames.
    std::fs::remove_file(frames.join("f-0003.png")).unwrap();
    let out = render(
        dir.path(),
        &path,
        &[
            "--frames",
            "0-24:3",
            "-o",
            "frames/f-####.png",
            "--skip-existing",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert_eq!(stderr.matches("skipped").count(), 8, "{stderr}");
    assert!(stderr.contains("frame 3: 8x8"), "{stderr}");
    assert_eq!(files_in(&frames).len(), 25);

    // Without a `#`, the number goes before the extension.
    let out = render(dir.path(), &path, &["--frames", "2-3", "-o", "plain.png"]);
    assert!(out.status.success());
    assert!(dir.path().join("plain0002.png").is_file());
    assert!(dir.path().join("plain0003.png").is_file());

    // Without --frame: frame 1, as Blender shows the file after importing it.
    let default = render(dir.path(), &path, &["-o", "default.png"]);
    assert!(default.status.success());
    assert_eq!(
        read(dir.path().join("default.png")),
        read(frames.join("f-0001.png"))
    );
}

#[test]
fn bad_frame_flags_are_usage_errors_and_unknown_animations_fail() {
    let dir = tempfile::tempdir().unwrap();
    let path = one_channel(
        dir.path(),
        "move.gltf",
        "translation",
        "LINEAR",
        &[0.0, 1.0],
        &[[0.0; 3], [1.0; 3]],
    );
    for bad in ["5-2", "1-5:0", "abc", "1-x"] {
        let out = render(dir.path(), &path, &["--frames", bad, "-o", "f-##.png"]);
        check_failure(&out, 2, &["--frames"]).unwrap_or_else(|e| panic!("{bad}: {e}"));
    }
    for bad in [["--fps", "0"], ["--fps", "nan"]] {
        let out = render(dir.path(), &path, &bad);
        check_failure(&out, 2, &["--fps"]).unwrap();
    }
    let out = render(dir.path(), &path, &["--frame", "1", "--frames", "1-2"]);
    check_failure(&out, 2, &["--frame"]).unwrap();
    for (choice, fragment) in [("Run", "'Run'"), ("3", "animation 3")] {
        let out = render(dir.path(), &path, &["--animation", choice, "-o", "x.png"]);
        check_failure(&out, 1, &["move.gltf", fragment, "'Move'"]).unwrap();
    }
    // Nothing was written.
    assert_eq!(files_in(dir.path()), ["move.gltf", "move.gltf.bin"]);
}

#[test]
fn a_model_placed_by_a_scene_file_moves_under_its_placement() {
    let dir = tempfile::tempdir().unwrap();
    one_channel(
        dir.path(),
        "move.gltf",
        "translation",
        "LINEAR",
        &[0.0, 1.0],
        &[[0.0; 3], [2.0, 0.0, 0.0]],
    );
    // Placed twice: each copy keeps its own placement (a 90 degree turn about z, then
    // a shift).
    let toml = "include = [\"builtin:room\"]\n\
        [[model]]\nfile = \"move.gltf\"\nup = \"z\"\nposition = [1.0, 2.0, 3.0]\n\
        rotation = [0.0, 0.0, 90.0]\n\
        [[model]]\nfile = \"move.gltf\"\nup = \"z\"\nposition = [-4.0, 0.0, 0.0]\n";
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    let mut scene = wavetrace::load_scene(&path).unwrap_or_else(|e| panic!("loads: {e}"));
    assert!(scene.is_animated());
    // A model placed twice stores its mesh once (`SharedMesh`).
    let origins = |scene: &mut Scene| {
        let mut points = Vec::new();
        let mut query = scene.world.query::<(&SharedMesh, &Transform)>();
        for (mesh, transform) in query.iter() {
            points.extend(
                mesh.0
                    .positions
                    .iter()
                    .map(|p| transform.0.transform_point3(*p)),
            );
        }
        let mut found: Vec<Vec3> = points
            .into_iter()
            .filter(|p| {
                [Vec3::new(1.0, 2.0, 3.0), Vec3::new(-4.0, 0.0, 0.0)]
                    .iter()
                    .any(|o| (*p - *o).length() < 2.5 && (p.z - o.z).abs() < 1e-4)
            })
            .collect();
        found.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        found
    };
    let rest = origins(&mut scene);
    assert_eq!(rest.len(), 6, "{rest:?}");
    scene.pose(&AnimationChoice::First, 0.5).unwrap();
    let moved = origins(&mut scene);
    // Copy one is turned: its +x motion of 1 is +y in the world; copy two moves along +x.
    assert!(
        moved
            .iter()
            .any(|p| (*p - Vec3::new(1.0, 3.0, 3.0)).length() < 1e-4),
        "{moved:?}"
    );
    assert!(
        moved
            .iter()
            .any(|p| (*p - Vec3::new(-3.0, 0.0, 0.0)).length() < 1e-4),
        "{moved:?}"
    );
}
