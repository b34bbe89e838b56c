//! Renders that stop early: SIGINT or SIGTERM (sent by the test) stops at the next batch
//! boundary and still writes a valid image of the samples taken so far; a second SIGINT quits
//! at once without an image; `--time` renders whole passes within a time budget.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const ROOM: &str = include_str!("../../scenes/room.toml");
const REQUESTED_SPP: u32 = 1_000_000;

struct Stopped {
    code: Option<i32>,
    stderr: String,
}

/// Starts a render of the seed room that would take hours (with `shadow_rays` per hit),
/// waits until it has begun rendering, sends `signals` (`kill -SIGNAL pid`) `gap` apart, and
/// waits for the process.
fn render_and_signal(
    dir: &Path,
    output: &Path,
    (size, batch, shadow_rays): (u32, u32, u32),
    signals: &[&str],
    gap: Duration,
) -> Stopped {
    let scene = dir.join("room.toml");
    std::fs::write(&scene, ROOM).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render"])
        .arg(&scene)
        .arg("-o")
        .arg(output)
        .args(["--width", &size.to_string(), "--height", &size.to_string()])
        .args(["--spp", &REQUESTED_SPP.to_string()])
        .args(["--batch-size", &batch.to_string()])
        .args(["--shadow-rays", &shadow_rays.to_string()])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut text = String::new();
    // The binary announces the render once the scene is loaded; signals sent from then on
    // must produce an image.
    while !text.contains("wavetrace: rendering") {
        assert!(
            stderr.read_line(&mut text).unwrap() > 0,
            "ended early: {text}"
        );
    }
    std::thread::sleep(Duration::from_millis(300)); // let some batches finish
    for (i, signal) in signals.iter().enumerate() {
        if i > 0 {
            // Two signals of one kind sent before the process takes the first are merged by
            // the kernel into one: wait until the first is acknowledged.
            while !text.contains("received, stopping") {
                assert!(
                    stderr.read_line(&mut text).unwrap() > 0,
                    "ended early: {text}"
                );
            }
            std::thread::sleep(gap);
        }
        let kill = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
    }
    stderr.read_to_string(&mut text).unwrap();
    let status = child.wait().unwrap();
    Stopped {
        code: status.code(),
        stderr: text,
    }
}

/// The complete samples per pixel stated in "... at WxH, N spp" or "N-M spp (...)".
fn stated_spp(stderr: &str) -> u32 {
    let line = stderr
        .lines()
        .find(|l| l.contains("the image holds"))
        .unwrap_or_else(|| panic!("no 'image holds' line: {stderr}"));
    let inside = line.split_once("so far (").unwrap().1;
    let digits: String = inside.chars().take_while(char::is_ascii_digit).collect();
    digits
        .parse()
        .unwrap_or_else(|_| panic!("no spp in: {line}"))
}

fn check_partial_image(dir: &Path, output: &Path, stopped: &Stopped, signal: &str, code: i32) {
    assert_eq!(stopped.code, Some(code), "{}", stopped.stderr);
    assert!(
        stopped
            .stderr
            .contains(&format!("stopped early by {signal}")),
        "{}",
        stopped.stderr
    );
    assert!(!stopped.stderr.contains("panicked"), "{}", stopped.stderr);
    assert!(stated_spp(&stopped.stderr) < REQUESTED_SPP);
    let image = wavetrace::output::read_exr(output).unwrap();
    assert_eq!((image.width, image.height), (32, 32));
    assert!(image.pixels.iter().all(|p| p.is_finite()));
    assert!(
        image.mean().max_element() > 0.0,
        "the lit room is not black"
    );
    // only the scene and the image: no temporary file
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert_eq!(names, ["room.exr", "room.toml"]);
}

#[test]
fn sigint_writes_the_samples_finished_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.exr");
    let stopped = render_and_signal(dir.path(), &output, (32, 256, 1), &["INT"], Duration::ZERO);
    check_partial_image(dir.path(), &output, &stopped, "SIGINT", 130);
}

#[test]
fn sigterm_writes_the_samples_finished_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.exr");
    let stopped = render_and_signal(dir.path(), &output, (32, 256, 1), &["TERM"], Duration::ZERO);
    check_partial_image(dir.path(), &output, &stopped, "SIGTERM", 143);
}

#[test]
fn a_second_sigint_quits_at_once_without_an_image() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("room.exr");
    // One round of 512x512 paths with 256 shadow rays per hit takes seconds, far longer than
    // the wait for the first signal's acknowledgement, the 5 ms gap and starting `kill`
    // twice on a busy machine, so both arrive before the render reaches a round boundary.
    let stopped = render_and_signal(
        dir.path(),
        &output,
        (512, 512 * 512, 256),
        &["INT", "INT"],
        Duration::from_millis(5),
    );
    assert_eq!(stopped.code, Some(130), "{}", stopped.stderr);
    assert!(
        stopped.stderr.contains("SIGINT again, quitting at once"),
        "{}",
        stopped.stderr
    );
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["room.toml"]);
}

#[test]
fn time_budget_renders_whole_passes_then_writes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("room.toml");
    std::fs::write(&scene, ROOM).unwrap();
    let output = dir.path().join("room.exr");
    let start = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render", "--width", "16", "--height", "16", "--time", "2s"])
        // Fixed passes: without a sample count the render would be adaptive.
        .args(["--noise-threshold", "0"])
        .arg(&scene)
        .arg("-o")
        .arg(&output)
        .output()
        .unwrap();
    let elapsed = start.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    // whole passes only: "16x16, N spp," with no "N-M spp" range
    let held = stderr
        .lines()
        .find_map(|l| l.strip_prefix("wavetrace: 16x16, "))
        .unwrap_or_else(|| panic!("no summary: {stderr}"));
    let spp: u32 = held.split(" spp,").next().unwrap().parse().unwrap();
    assert!(spp >= 2, "{stderr}");
    // the budget is 2 s; allow for process start-up and the image write, not another budget
    assert!(elapsed < Duration::from_secs(4), "{elapsed:?}: {stderr}");
    let image = wavetrace::output::read_exr(&output).unwrap();
    assert_eq!((image.width, image.height), (16, 16));
}
