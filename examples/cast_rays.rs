//! Casts ray sets (`.npy` rays with Intel Embree's answers and timings, as written by the
//! `raysets.py` comparison tool that lives outside this repository) through wavetrace's own flattening and BVH,
//! prints Mrays/s per set (all threads and one thread) and checks the hits against Embree's
//! reference answers.
//!
//! ```text
//! cargo run --release --features examples --example cast_rays -- DIR SCENE [--repeats N] [--limit N] [--sets a,b]
//! ```
//! `DIR` is the output directory of `raysets.py gen` (+ `bench --save-ref`); `SCENE` is
//! `room`, `mesh1m` or `mesh5m`. `--limit N` casts only the first `N` rays of each set and
//! `--sets` picks sets (`primary,bounce,shadow` by default): a short run for instruction
//! counts, e.g. `valgrind --tool=callgrind --toggle-collect='*cast_closest*'` (the tracing
//! loops are the non-inlined `cast_closest` and `cast_occluded`).

use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;
use wavetrace::RenderScene;
use wavetrace::internals::{Ray, TraversalStack};
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

fn read_rays(path: &Path, limit: usize) -> Vec<Ray> {
    f32s(&read_npy(path))
        .chunks_exact(8)
        .take(limit)
        .map(|r| Ray {
            origin: Vec3A::new(r[0], r[1], r[2]),
            direction: Vec3A::new(r[4], r[5], r[6]),
            t_max: r[7],
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

/// The order in which a set's rays are cast.
#[derive(Clone, Copy, Debug)]
enum Order {
    /// One query per ray, in the set's order (what Embree's single-ray figures time).
    Given,
    /// The batch queries: Morton order of the origins, sort included in the time.
    Morton,
}

/// `query` of every ray, one ray after another in the set's order, on all threads.
fn in_given_order<T: Send>(
    rays: &[Ray],
    query: impl Fn(&mut TraversalStack, &Ray) -> T + Sync,
) -> Vec<T> {
    rays.par_iter()
        .with_min_len(1024)
        .map_init(TraversalStack::default, |stack, r| query(stack, r))
        .collect()
}

/// Closest hits of `rays`, in their order. Not inlined, so that profilers can select it.
#[inline(never)]
fn cast_closest(scene: &RenderScene, rays: &[Ray], order: Order) -> Vec<Option<(u32, f32)>> {
    match order {
        Order::Given => in_given_order(rays, |stack, r| {
            scene.closest_hit(stack, r.origin, r.direction, r.t_max)
        }),
        Order::Morton => scene.closest_hits(rays),
    }
}

/// Occlusion of `rays`, in their order. Not inlined (see [`cast_closest`]).
#[inline(never)]
fn cast_occluded(scene: &RenderScene, rays: &[Ray], order: Order) -> Vec<bool> {
    match order {
        Order::Given => in_given_order(rays, |stack, r| {
            scene.occluded(stack, r.origin, r.direction, r.t_max)
        }),
        Order::Morton => scene.occlusions(rays),
    }
}

/// The share of `rays` (set `set` of scene `scene_name`) on which the answers cast in
/// `order` agree with Embree's reference answers in `dir`.
fn agreement(
    scene: &RenderScene,
    dir: &Path,
    scene_name: &str,
    set: &str,
    rays: &[Ray],
    order: Order,
) -> f64 {
    let reference = |what: &str| read_npy(&dir.join(format!("ref_{scene_name}_{set}_{what}.npy")));
    let agreeing = if set == "shadow" {
        let occluded = reference("occluded");
        let ours = cast_occluded(scene, rays, order);
        ours.iter()
            .zip(&occluded)
            .filter(|(a, b)| **a == (**b != 0))
            .count()
    } else {
        let (ref_t, ref_prim) = (f32s(&reference("t")), u32s(&reference("prim")));
        let ours = cast_closest(scene, rays, order);
        ours.iter()
            .zip(ref_t.iter().zip(&ref_prim))
            .filter(|(ours, (rt, rp))| match ours {
                None => !rt.is_finite(),
                Some((slot, t)) => {
                    scene.source_index(*slot as usize) == **rp
                        || (t - **rt).abs() <= 1e-5 * rt.abs().max(1e-3)
                }
            })
            .count()
    };
    agreeing as f64 / rays.len() as f64
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
    println!(
        "{scene_name}: {triangle_count} triangles, BVH build {:.1} ms, flatten + BVH build {:.1} ms ({threads} threads), BVH depth {}",
        scene.flatten_times().bvh_build.as_secs_f64() * 1e3,
        scene.flatten_times().total.as_secs_f64() * 1e3,
        scene.bvh_depth()
    );

    println!(
        "{:<8} {:<7} {:>10} {:>16} {:>16} {:>11}",
        "set", "order", "Mrays/s", "1 thread Mrays/s", "Mrays/CPU-s", "agreement"
    );
    for set in sets.iter().map(String::as_str) {
        let rays_file = if set == "primary" {
            dir.join("rays_primary.npy")
        } else {
            dir.join(format!("rays_{scene_name}_{set}.npy"))
        };
        let rays = read_rays(&rays_file, limit);
        let n = rays.len();
        for order in [Order::Given, Order::Morton] {
            let trace = || match set {
                "shadow" => drop(std::hint::black_box(cast_occluded(&scene, &rays, order))),
                _ => drop(std::hint::black_box(cast_closest(&scene, &rays, order))),
            };
            let agreement = agreement(&scene, &dir, scene_name, set, &rays, order);
            let (all, _) = median_seconds(threads, repeats, trace);
            let (one, one_cpu) = median_seconds(1, repeats, trace);
            println!(
                "{set:<8} {:<7} {:>10.2} {:>16.2} {:>16.2} {:>10.4}%{}",
                format!("{order:?}").to_lowercase(),
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
    }
    println!(
        "(medians of {repeats} runs; load average at the end: {})",
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
}
