//! Casts the ray sets of `shared/tools/raysets` through wavetrace's own flattening and BVH,
//! prints Mrays/s per set (all threads and one thread) and checks the hits against Embree's
//! reference answers.
//!
//! ```text
//! cargo run --release --example cast_rays -- DIR SCENE [--repeats N] [--limit N] [--sets a,b]
//! ```
//! `DIR` is the output directory of `raysets.py gen` (+ `bench --save-ref`); `SCENE` is
//! `room`, `mesh1m` or `mesh5m`. `--limit N` casts only the first `N` rays of each set and
//! `--sets` picks sets (`primary,bounce,shadow` by default): a short run for instruction
//! counts, e.g. `valgrind --tool=callgrind --toggle-collect='*cast_closest*'` (the tracing
//! loops are the non-inlined `cast_closest` and `cast_occluded`).

use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;
use wavetrace::flatten::bvh::TraversalStack;
use wavetrace::math::{Vec3, Vec3A};
use wavetrace::scene::{Camera, Material, Mesh, Name};

/// The raw little-endian payload of a `.npy` file (v1.0 header skipped).
fn read_npy(path: &Path) -> Vec<u8> {
    let bytes =
        std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    assert_eq!(
        &bytes[..6],
        b"\x93NUMPY",
        "{} is not a .npy file",
        path.display()
    );
    let header_len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    bytes[10 + header_len..].to_vec()
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// One ray: origin, direction, t_max (t_min is always 0 in these sets).
type Ray = (Vec3A, Vec3A, f32);

fn read_rays(path: &Path, limit: usize) -> Vec<Ray> {
    f32s(&read_npy(path))
        .chunks_exact(8)
        .take(limit)
        .map(|r| {
            (
                Vec3A::new(r[0], r[1], r[2]),
                Vec3A::new(r[4], r[5], r[6]),
                r[7],
            )
        })
        .collect()
}

/// CPU time (user + system) of this process so far, in seconds, from /proc (Linux).
fn process_cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the parenthesised command name; utime and stime are fields 14 and 15 (indices 10 and 11 once the state letter is skipped), in ticks of 1/100 s.
    let rest = stat.rsplit_once(')').map_or("", |r| r.1);
    let fields: Vec<f64> = rest
        .split_whitespace()
        .filter_map(|f| f.parse().ok())
        .collect();
    fields
        .get(10)
        .zip(fields.get(11))
        .map_or(f64::NAN, |(u, s)| (u + s) / 100.0)
}

/// Median wall time and median CPU time of `repeats` runs of `f` on `threads` threads.
fn median_seconds(threads: usize, repeats: usize, f: impl Fn() + Sync + Send) -> (f64, f64) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (mut wall, mut cpu): (Vec<f64>, Vec<f64>) = (0..repeats)
        .map(|_| {
            let (t, c) = (Instant::now(), process_cpu_seconds());
            pool.install(&f);
            (t.elapsed().as_secs_f64(), process_cpu_seconds() - c)
        })
        .unzip();
    wall.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    (wall[wall.len() / 2], cpu[cpu.len() / 2])
}

/// Casts closest-hit rays; returns how many hit. Not inlined, so that profilers can select it.
#[inline(never)]
fn cast_closest(scene: &wavetrace::FlatScene, rays: &[Ray]) -> usize {
    rays.par_iter()
        .with_min_len(1024)
        .map_init(TraversalStack::default, |stack, &(o, d, t)| {
            scene.closest_hit(stack, o, d, t).is_some()
        })
        .filter(|&hit| hit)
        .count()
}

/// Casts occlusion rays; returns how many are blocked. Not inlined (see [`cast_closest`]).
#[inline(never)]
fn cast_occluded(scene: &wavetrace::FlatScene, rays: &[Ray]) -> usize {
    rays.par_iter()
        .with_min_len(1024)
        .map_init(TraversalStack::default, |stack, &(o, d, t)| {
            scene.occluded(stack, o, d, t)
        })
        .filter(|&blocked| blocked)
        .count()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: cast_rays DIR SCENE [--repeats N]");
        std::process::exit(2);
    }
    let dir = PathBuf::from(&args[1]);
    let scene_name = &args[2];
    let repeats = args
        .iter()
        .position(|a| a == "--repeats")
        .map_or(5, |i| args[i + 1].parse().expect("--repeats N"));
    let limit = args
        .iter()
        .position(|a| a == "--limit")
        .map_or(usize::MAX, |i| args[i + 1].parse().expect("--limit N"));
    let sets: Vec<String> = args
        .iter()
        .position(|a| a == "--sets")
        .map_or("primary,bounce,shadow", |i| args[i + 1].as_str())
        .split(',')
        .map(str::to_string)
        .collect();
    let threads = rayon::current_num_threads();

    // --- The scene through the project's own path: ECS world -> flatten (BVH build included).
    let vertices: Vec<Vec3> = f32s(&read_npy(
        &dir.join(format!("scene_{scene_name}_vertices.npy")),
    ))
    .chunks_exact(3)
    .map(|v| Vec3::new(v[0], v[1], v[2]))
    .collect();
    let indices: Vec<[u32; 3]> = u32s(&read_npy(
        &dir.join(format!("scene_{scene_name}_indices.npy")),
    ))
    .chunks_exact(3)
    .map(|t| [t[0], t[1], t[2]])
    .collect();
    let triangle_count = indices.len();
    let mut world = hecs::World::new();
    world.spawn((
        Name("camera".into()),
        Camera::look_at(Vec3::new(-1.0, 0.0, 0.0), Vec3::ZERO, Vec3::Z, 1.5),
    ));
    world.spawn((
        Name(scene_name.clone()),
        Mesh {
            positions: vertices,
            indices,
            ..Default::default()
        },
        Material::Lambertian {
            albedo: Vec3::splat(0.5),
        },
    ));
    let scene = wavetrace::flatten(&world, &dir).expect("flatten");
    let source = &scene.source_index;
    println!(
        "{scene_name}: {triangle_count} triangles, BVH build {:.1} ms, flatten + BVH build {:.1} ms ({threads} threads), BVH depth {}",
        scene.times.bvh_build.as_secs_f64() * 1e3,
        scene.times.total.as_secs_f64() * 1e3,
        scene.bvh.depth
    );

    println!(
        "{:<8} {:>10} {:>16} {:>16} {:>11}",
        "set", "Mrays/s", "1 thread Mrays/s", "Mrays/CPU-s", "agreement"
    );
    for set in sets.iter().map(String::as_str) {
        let rays_file = if set == "primary" {
            dir.join("rays_primary.npy")
        } else {
            dir.join(format!("rays_{scene_name}_{set}.npy"))
        };
        let rays = read_rays(&rays_file, limit);
        let n = rays.len();
        let (agreement, trace): (f64, Box<dyn Fn() + Sync + Send>) = if set == "shadow" {
            let reference = read_npy(&dir.join(format!("ref_{scene_name}_shadow_occluded.npy")));
            let ours: Vec<bool> = rays
                .par_iter()
                .map_init(TraversalStack::default, |stack, &(o, d, t)| {
                    scene.occluded(stack, o, d, t)
                })
                .collect();
            let agree = ours
                .iter()
                .zip(&reference)
                .filter(|(a, b)| **a == (**b != 0))
                .count();
            let scene = &scene;
            let rays = &rays;
            (
                agree as f64 / n as f64,
                Box::new(move || {
                    std::hint::black_box(cast_occluded(scene, rays));
                }),
            )
        } else {
            let ref_t = f32s(&read_npy(
                &dir.join(format!("ref_{scene_name}_{set}_t.npy")),
            ));
            let ref_prim = u32s(&read_npy(
                &dir.join(format!("ref_{scene_name}_{set}_prim.npy")),
            ));
            let ours: Vec<Option<(u32, f32)>> = rays
                .par_iter()
                .map_init(TraversalStack::default, |stack, &(o, d, t)| {
                    scene.closest_hit(stack, o, d, t)
                })
                .collect();
            let agree = ours
                .iter()
                .zip(ref_t.iter().zip(&ref_prim))
                .filter(|(ours, (rt, rp))| match ours {
                    None => !rt.is_finite(),
                    Some((slot, t)) => {
                        source[*slot as usize] == **rp
                            || (t - **rt).abs() <= 1e-5 * rt.abs().max(1e-3)
                    }
                })
                .count();
            let scene = &scene;
            let rays = &rays;
            (
                agree as f64 / n as f64,
                Box::new(move || {
                    std::hint::black_box(cast_closest(scene, rays));
                }),
            )
        };
        let (all, _) = median_seconds(threads, repeats, &trace);
        let (one, one_cpu) = median_seconds(1, repeats, &trace);
        println!(
            "{set:<8} {:>10.2} {:>16.2} {:>16.2} {:>10.4}%{}",
            n as f64 / all / 1e6,
            n as f64 / one / 1e6,
            n as f64 / one_cpu / 1e6,
            100.0 * agreement,
            if agreement >= 0.9999 {
                ""
            } else {
                "  BELOW 99.99%"
            }
        );
    }
    println!(
        "(medians of {repeats} runs; load average at the end: {})",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
