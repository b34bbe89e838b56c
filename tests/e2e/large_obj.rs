//! A large OBJ (a 750 x 750 vertex grid: about 1.1 million lines, 1.1 million triangles,
//! written here) loads and flattens through the library in bounded memory. Its time is a
//! figure for benchmarks and the closing notes, not a pass/fail limit: it is printed.
//!
//! The memory bound is stated per triangle: the process's peak resident size (VmHWM, Linux)
//! may grow by at most `BYTES_PER_TRIANGLE` per triangle plus `FIXED_BYTES` while the file is
//! loaded, flattened and its BVH built. The full 10-million-line case (a 2237 x 2237 grid,
//! 10.0 M triangles) measured by hand peaked at 4.6 GB through the binary, about 460 bytes per
//! triangle (file text, tobj's faces and vertex map, our mesh, world-space primitives, BVH),
//! before the text was borrowed and freed early and obvhs's nodes shrank to 32 bytes; this
//! test's grid then grew the peak by 302 MB, 282 bytes per triangle (docs/performance.md,
//! "Memory per triangle"), and the bound catches a return to the old figures.
//! The test runs alone in a child process (`common::run_alone`), so that no other test shares
//! the process's peak.

use crate::common::run_alone;
use std::io::Write;
use std::time::Instant;

const SIDE: usize = 750;
const BYTES_PER_TRIANGLE: u64 = 300;
const FIXED_BYTES: u64 = 64 << 20;

/// Peak resident set size of this process in bytes, from /proc/self/status.
fn peak_rss() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

#[test]
fn a_million_line_obj_loads_in_bounded_time_and_memory() {
    run_alone(
        "large_obj::a_million_line_obj_loads_in_bounded_time_and_memory",
        load_a_million_line_obj,
    );
}

fn load_a_million_line_obj() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grid.obj");
    {
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        writeln!(out, "o Grid").unwrap();
        for j in 0..SIDE {
            for i in 0..SIDE {
                let (x, y) = (i as f32 / SIDE as f32, j as f32 / SIDE as f32);
                writeln!(out, "v {x:.6} {y:.6} 0.000000").unwrap();
            }
        }
        for j in 0..SIDE - 1 {
            let row = j * SIDE + 1;
            for i in 0..SIDE - 1 {
                let a = row + i;
                writeln!(out, "f {} {} {} {}", a, a + 1, a + SIDE + 1, a + SIDE).unwrap();
            }
        }
    }
    let triangles = 2 * (SIDE - 1) * (SIDE - 1);
    let before = peak_rss();
    let start = Instant::now();
    let scene = wavetrace::load_scene(&path).expect("the grid loads");
    let flat = wavetrace::flatten(&scene.world, &path).expect("the grid flattens");
    let elapsed = start.elapsed();
    let after = peak_rss();
    // The room's own primitives come with the grid.
    assert!(
        flat.primitive_count() >= triangles,
        "{}",
        flat.primitive_count()
    );
    if let (Some(before), Some(after)) = (before, after) {
        let grown = after.saturating_sub(before);
        let bound = BYTES_PER_TRIANGLE * triangles as u64 + FIXED_BYTES;
        eprintln!(
            "{triangles} triangles: {elapsed:?}, peak grew by {} MB (bound {} MB)",
            grown >> 20,
            bound >> 20
        );
        assert!(grown <= bound, "peak grew by {grown} bytes, bound {bound}");
    }
}
