//! Peak memory per triangle of a large OBJ, re-measured with one command (issue 21, item 5):
//! writes a grid OBJ of 2 x (SIDE - 1)^2 triangles (`v` and `f` lines; with `--attributes`
//! also `vn` and `vt`, indexed `v/vt/vn`), then loads, flattens and renders it at 64 x 64,
//! 1 sample per pixel, as `wavetrace render` does, and prints this process's peak resident
//! size (VmHWM, Linux) and that divided by the triangle count.
//!
//! ```text
//! cargo run --release --features examples --example memory_per_triangle -- /tmp/mem [SIDE] [--attributes]
//! WAVETRACE_MEMTRACE=1 cargo run --release --features examples --example memory_per_triangle -- /tmp/mem
//! ```
//!
//! SIDE defaults to 1001 (2 million triangles, 75 MB of text). With `WAVETRACE_MEMTRACE` set
//! the library prints the resident size after each phase (parse, meshes, loaded, shapes,
//! binary bvh, 4-wide bvh, leaf prims, flattened) and the peak within it; the
//! final figure is then the last phase's peak only. The file is written line by line, so
//! writing it adds little to the peak.

use std::io::Write;
use std::path::{Path, PathBuf};
use wavetrace::{RenderOverrides, RenderSettings, flatten, load_scene, render};

fn main() -> anyhow::Result<()> {
    let mut attributes = false;
    let mut positional = Vec::new();
    for arg in std::env::args().skip(1) {
        match arg.as_str() {
            "--attributes" => attributes = true,
            _ => positional.push(arg),
        }
    }
    let dir = PathBuf::from(positional.first().map_or(".", |d| d.as_str()));
    let side: usize = positional.get(1).map_or(Ok(1001), |s| s.parse())?;
    anyhow::ensure!(side >= 2, "SIDE must be at least 2");
    std::fs::create_dir_all(&dir)?;
    let name = if attributes {
        "grid-attributes.obj"
    } else {
        "grid.obj"
    };
    let path = dir.join(name);
    let triangles = write_grid(&path, side, attributes)?;
    let bytes = std::fs::metadata(&path)?.len();

    let scene = load_scene(&path)?;
    wavetrace::internals::trace_phase("loaded");
    let flat = flatten(&scene.world, &path)?;
    // As `wavetrace render` does: the world is freed before the render.
    drop(scene.world);
    wavetrace::internals::trace_phase("flattened");
    let overrides = RenderOverrides {
        width: Some(64),
        height: Some(64),
        spp: Some(1),
        ..Default::default()
    };
    let settings = RenderSettings::resolve(&scene.defaults, &overrides, None);
    render(&flat, &settings, |_| wavetrace::Flow::Continue)?;
    wavetrace::internals::trace_phase("rendered");

    let peak = peak_resident_bytes().ok_or_else(|| anyhow::anyhow!("no VmHWM (not Linux?)"))?;
    println!(
        "{}: {triangles} triangles, {:.1} MB of text{}",
        path.display(),
        bytes as f64 / 1e6,
        if attributes { ", with vn and vt" } else { "" }
    );
    println!(
        "peak resident memory {:.0} MB = {:.0} bytes per triangle",
        peak as f64 / 1e6,
        peak as f64 / triangles as f64
    );
    Ok(())
}

/// Writes a `side` x `side` vertex grid, slightly wavy, as OBJ; returns its triangle count.
fn write_grid(path: &Path, side: usize, attributes: bool) -> std::io::Result<usize> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    let coordinate = |i: usize| i as f32 / (side - 1) as f32;
    for j in 0..side {
        for i in 0..side {
            let height = 0.1 * ((i * 7 + j * 13) % 17) as f32 / 17.0;
            let (x, z) = (2.0 * coordinate(i) - 1.0, 2.0 * coordinate(j) - 1.0);
            writeln!(out, "v {x:.6} {height:.6} {z:.6}")?;
        }
    }
    if attributes {
        for _ in 0..side * side {
            writeln!(out, "vn 0 1 0")?;
        }
        for j in 0..side {
            for i in 0..side {
                writeln!(out, "vt {:.6} {:.6}", coordinate(i), coordinate(j))?;
            }
        }
    }
    let corner = |k: usize| {
        if attributes {
            format!("{k}/{k}/{k}")
        } else {
            k.to_string()
        }
    };
    for j in 0..side - 1 {
        for i in 0..side - 1 {
            let a = j * side + i + 1;
            let (b, c, d) = (a + 1, a + side, a + side + 1);
            writeln!(out, "f {} {} {}", corner(a), corner(c), corner(b))?;
            writeln!(out, "f {} {} {}", corner(b), corner(c), corner(d))?;
        }
    }
    out.flush()?;
    Ok(2 * (side - 1) * (side - 1))
}

/// This process's peak resident size (VmHWM of /proc/self/status) in bytes.
fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
