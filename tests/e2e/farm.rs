//! A frame rendered in parts (`render --part K/N`) and merged (`wavetrace merge`) writes the
//! same bytes as the frame rendered whole, with fixed and adaptive sampling and the room's
//! caustic light paths (it has a mirror and a glass sphere); the bad inputs of both commands;
//! and `wavetrace slurm` on a real Slurm cluster (`tools/slurm_local.sh`): skipped, saying so,
//! where there is none, and failing instead when `WAVETRACE_REQUIRE_SLURM=1` (CI).

use crate::common::{check_failure, files_in};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

fn room() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml")
}

/// Runs `wavetrace ARGS`.
fn run(args: &[&str]) -> Output {
    wavetrace().args(args).output().expect("wavetrace runs")
}

/// Runs `wavetrace ARGS` and panics with its stderr unless it succeeded.
fn run_ok(args: &[&str]) {
    let out = run(args);
    assert!(
        out.status.success(),
        "wavetrace {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Renders `flags` whole and in `order.len()` parts taken in `order`, merges the parts (given
/// in that order) and checks that both images are the same bytes.
fn assert_parts_merge_to_the_whole(flags: &[&str], order: &[u32], dir: &Path) {
    let room = room();
    let room = room.to_str().unwrap();
    let whole = dir.join("whole.exr");
    let merged = dir.join("merged.exr");
    let mut args = vec!["render", room, "--quiet", "-o", whole.to_str().unwrap()];
    args.extend(flags);
    run_ok(&args);
    let n = order.len();
    let mut parts = Vec::new();
    for &k in order {
        let part = dir.join(format!("part-{k}.wtpart"));
        let index = format!("{k}/{n}");
        let mut args = vec!["render", room, "--quiet", "--part", &index];
        args.extend(["-o", part.to_str().unwrap()]);
        args.extend(flags);
        run_ok(&args);
        parts.push(part.to_str().unwrap().to_string());
    }
    let mut args = vec!["merge", "--quiet", "-o", merged.to_str().unwrap()];
    args.extend(parts.iter().map(String::as_str));
    run_ok(&args);
    let (whole, merged) = (
        std::fs::read(whole).unwrap(),
        std::fs::read(merged).unwrap(),
    );
    assert!(
        whole == merged,
        "merged parts differ from the whole render ({flags:?})"
    );
}

#[test]
fn fixed_sampling_parts_merge_to_the_whole_render_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    // 60 rows: 8 tile rows, the last one 4 pixels high, shared 2 + 3 + 3.
    let flags = [
        "--width",
        "40",
        "--height",
        "60",
        "--spp",
        "32",
        "--caustic-paths",
        "1",
    ];
    assert_parts_merge_to_the_whole(&flags, &[2, 0, 1], dir.path());
}

#[test]
fn adaptive_sampling_parts_merge_to_the_whole_render_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let flags = [
        "--width",
        "48",
        "--height",
        "48",
        "--spp",
        "128",
        "--noise-threshold",
        "0.05",
        "--seed",
        "7",
    ];
    assert_parts_merge_to_the_whole(&flags, &[3, 1, 0, 2], dir.path());
}

#[test]
fn bad_part_flags_are_usage_errors_or_clear_errors_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let room = room();
    let room = room.to_str().unwrap();
    let part = dir.path().join("p.wtpart");
    let part = part.to_str().unwrap();
    let render = |extra: &[&str]| {
        let mut args = vec![
            "render", room, "-q", "-o", part, "--width", "16", "--height", "32",
        ];
        args.extend(extra);
        run(&args)
    };
    for bad in ["4/4", "0/0", "x", "1/", "-1/2"] {
        let out = render(&["--spp", "1", &format!("--part={bad}")]);
        check_failure(&out, 2, &["--part"]).unwrap();
    }
    check_failure(&render(&["--time", "1s", "--part", "0/2"]), 2, &["--time"]).unwrap();
    check_failure(&render(&["--part", "0/2"]), 1, &["--part 0/2", "--spp"]).unwrap();
    // 32 rows are 4 tile rows: not enough for 5 parts.
    check_failure(
        &render(&["--spp", "1", "--part", "0/5"]),
        1,
        &["too few for 5 parts"],
    )
    .unwrap();
    assert!(
        files_in(dir.path()).is_empty(),
        "{:?}",
        files_in(dir.path())
    );
}

#[test]
fn merging_missing_repeated_or_foreign_parts_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let room = room();
    let room = room.to_str().unwrap();
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let render_part = |name: &str, part: &str, extra: &[&str]| {
        let out = path(name);
        let mut args = vec!["render", room, "--quiet", "--spp", "2", "--width", "16"];
        args.extend(["--height", "24", "--part", part, "-o", &out]);
        args.extend(extra);
        run_ok(&args);
        out
    };
    let a0 = render_part("a0", "0/2", &[]);
    let a1 = render_part("a1", "1/2", &[]);
    let seed = render_part("seed", "1/2", &["--seed", "5"]);
    let three = render_part("three", "1/3", &[]);
    let out = path("out.png");
    let merge = |parts: &[&str]| {
        let mut args = vec!["merge", "-o", &out];
        args.extend(parts);
        run(&args)
    };
    check_failure(
        &merge(&[&a1]),
        1,
        &["a1", "part 0 of 2 of this render missing"],
    )
    .unwrap();
    check_failure(&merge(&[&a0, &a1, &a0]), 1, &["a0", "given twice"]).unwrap();
    check_failure(
        &merge(&[&a0, &seed]),
        1,
        &["seed", "another render", "seed: 5"],
    )
    .unwrap();
    check_failure(&merge(&[&a0, &three]), 1, &["three", "3 parts"]).unwrap();
    let room_copy = path("room.toml");
    std::fs::copy(room, &room_copy).unwrap();
    check_failure(
        &merge(&[&a0, &room_copy]),
        1,
        &["room.toml", "not a wavetrace part file"],
    )
    .unwrap();
    let mut cut = std::fs::read(&a1).unwrap();
    cut.truncate(cut.len() - 100);
    std::fs::write(&a1, &cut).unwrap();
    check_failure(&merge(&[&a0, &a1]), 1, &["a1", "checksum"]).unwrap();
    check_failure(&merge(&[&a0, &path("absent")]), 1, &["absent"]).unwrap();
    assert!(!Path::new(&out).exists());
    check_failure(&run(&["merge", "-o", &out]), 2, &["PARTS"]).unwrap();
}

#[test]
fn slurm_without_sbatch_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("farm.exr");
    let room = room();
    let result = wavetrace()
        .args([
            "slurm",
            room.to_str().unwrap(),
            "--spp",
            "1",
            "--parts",
            "2",
        ])
        .args(["-o", out.to_str().unwrap()])
        .env("PATH", dir.path())
        .output()
        .unwrap();
    check_failure(&result, 1, &["sbatch not found"]).unwrap();
    let usage = run(&[
        "slurm",
        room.to_str().unwrap(),
        "--parts",
        "2",
        "-o",
        "x.exr",
    ]);
    check_failure(&usage, 2, &["--parts needs --spp"]).unwrap();
}

/// Whether a Slurm cluster is at hand (`sbatch` runs and `SLURM_CONF` is set); prints why the
/// test is skipped when not, and panics instead where `WAVETRACE_REQUIRE_SLURM=1`.
fn slurm_available(test: &str) -> bool {
    let conf = std::env::var_os("SLURM_CONF").is_some();
    let sbatch = Command::new("sbatch").arg("--version").output().is_ok();
    if conf && sbatch {
        return true;
    }
    let why = match (sbatch, conf) {
        (false, _) => "sbatch not found",
        _ => "SLURM_CONF is not set",
    };
    assert!(
        std::env::var("WAVETRACE_REQUIRE_SLURM").as_deref() != Ok("1"),
        "{test}: {why}, but WAVETRACE_REQUIRE_SLURM=1 (start tools/slurm_local.sh)"
    );
    eprintln!(
        "SKIPPED {test}: {why} (start a local cluster with `sudo tools/slurm_local.sh start` \
         and export the SLURM_CONF it prints)"
    );
    false
}

#[test]
fn slurm_parts_merge_to_the_whole_render_byte_for_byte() {
    if !slurm_available("farm::slurm_parts_merge_to_the_whole_render_byte_for_byte") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let room = room();
    let room = room.to_str().unwrap();
    let flags = ["--width", "64", "--height", "64", "--spp", "8"];
    let farm = dir.path().join("farm.exr");
    let whole = dir.path().join("whole.exr");
    let mut args = vec![
        "slurm",
        room,
        "--parts",
        "4",
        "-o",
        farm.to_str().unwrap(),
        "--wait",
    ];
    args.extend(flags);
    run_ok(&args);
    let mut args = vec!["render", room, "--quiet", "-o", whole.to_str().unwrap()];
    args.extend(flags);
    run_ok(&args);
    assert!(std::fs::read(&farm).unwrap() == std::fs::read(&whole).unwrap());
    assert!(dir.path().join("farm.exr.slurm/task-3.log").exists());
}

#[test]
fn slurm_wait_names_the_failed_task_and_its_log() {
    if !slurm_available("farm::slurm_wait_names_the_failed_task_and_its_log") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let farm = dir.path().join("farm.exr");
    // A scene that does not exist: every task fails, the merge job never runs.
    let scene = dir.path().join("gone.toml");
    let out = run(&[
        "slurm",
        scene.to_str().unwrap(),
        "--spp",
        "1",
        "--parts",
        "2",
        "-o",
        farm.to_str().unwrap(),
        "--wait",
    ]);
    check_failure(&out, 1, &["FAILED", "task-", ".log", "merge job"]).unwrap();
    assert!(!farm.exists());
}

#[test]
fn slurm_frames_write_every_frame() {
    if !slurm_available("farm::slurm_frames_write_every_frame") {
        return;
    }
    let help = run(&["render", "--help"]);
    if !String::from_utf8_lossy(&help.stdout).contains("--frames") {
        eprintln!("SKIPPED farm::slurm_frames_write_every_frame: `render` has no --frames yet");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let room = room();
    let out = dir.path().join("f-##.png");
    run_ok(&[
        "slurm",
        room.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "1",
        "--frames",
        "0-4:2",
        "--frames-per-task",
        "2",
        "-o",
        out.to_str().unwrap(),
        "--wait",
    ]);
    for frame in ["f-00.png", "f-02.png", "f-04.png"] {
        assert!(
            dir.path().join(frame).exists(),
            "{frame}: {:?}",
            files_in(dir.path())
        );
    }
}
