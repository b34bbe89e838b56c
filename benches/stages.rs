//! Stage-level benchmarks: each wavefront stage, on one thread as the renderer runs it, on a
//! fixed, seeded batch of 65,536 paths, in the seed room and in a heavy scene (the room plus a
//! procedural mesh of over a million triangles), reported as rays (or paths) per second; plus
//! the BVH build of the heavy scene. Names are `stage/scene`. The batch is run through each
//! stage in sub-batches of the renderer's default size, whose buffers stay in cache as a
//! render's do (the whole batch's shadow rays alone take 35 MB).

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use std::hint::black_box;
use std::path::Path;
use wavetrace::internals::{
    HitBatch, PathState, PinholeCamera, RayBatch, ShadeParams, ShadowBatch, generate_camera_rays,
    intersect_closest, shade_hits, trace_shadow_rays,
};
use wavetrace::math::{Vec3, rng};
use wavetrace::scene::{Material, Mesh, Name, Transform};
use wavetrace::{RenderScene, flatten};

/// One batch: the whole 256 x 256 image, so the batch sees the scene as a render does.
const SIDE: u32 = 256;
const BATCH: u32 = SIDE * SIDE;
/// The seed benchmark's shadow-ray count.
const SHADOW_RAYS: u32 = 15;

fn room_world() -> hecs::World {
    wavetrace::scene::load::load_scene_str(
        Path::new("builtin:room"),
        wavetrace::scene::load::BUILTIN_ROOM,
    )
    .unwrap()
    .world
}

/// A bumpy sphere of `2 * rings * segments` triangles (radius modulated by a hash), so rays
/// meet a realistic mix of tiny triangles.
fn bumpy_sphere(rings: u32, segments: u32) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            let bump = 1.0
                + 0.04 * (rng::uniform(rng::path_key(7, i, j), 0, 0) - 0.5)
                + 0.1 * (5.0 * theta).sin() * (7.0 * phi).cos();
            positions.push(
                bump * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                ),
            );
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b) = (i * segments + j, i * segments + (j + 1) % segments);
            let (c, d) = (a + segments, b + segments);
            indices.push([a, c, b]);
            indices.push([b, c, d]);
        }
    }
    Mesh {
        positions,
        indices,
        ..Default::default()
    }
}

fn heavy_world() -> hecs::World {
    let mut world = room_world();
    let transform = Transform(wavetrace::math::Affine3A::from_scale_rotation_translation(
        Vec3::splat(2.0),
        Default::default(),
        Vec3::new(5.0, 0.0, -1.5),
    ));
    world.spawn((
        Name("bumpy sphere".into()),
        transform,
        bumpy_sphere(512, 1040),
        Material::Lambertian {
            albedo: Vec3::splat(0.7),
        },
    ));
    world
}

/// Paths per sub-batch: the renderer's default batch size.
const SUB_BATCH: u32 = 4096;

/// Buffers of one sub-batch after generating its camera rays and shading their hits once.
struct Prepared {
    camera_rays: RayBatch,
    camera_hits: HitBatch,
    camera_paths: PathState,
    bounce_rays: RayBatch,
    shadow_paths: PathState,
    shadows: ShadowBatch,
    params: ShadeParams<'static>,
}

/// The pixels of each sub-batch, in order.
fn sub_batch_pixels() -> impl Iterator<Item = std::ops::Range<u32>> {
    (0..BATCH)
        .step_by(SUB_BATCH as usize)
        .map(|first| first..first + SUB_BATCH)
}

/// The sub-batches of the whole batch, in pixel order.
fn prepare(scene: &RenderScene) -> Vec<Prepared> {
    let camera = PinholeCamera::new(scene.camera(), SIDE, SIDE);
    (sub_batch_pixels().map(|pixels| prepare_sub_batch(scene, &camera, pixels))).collect()
}

fn prepare_sub_batch(
    scene: &RenderScene,
    camera: &PinholeCamera,
    pixels: std::ops::Range<u32>,
) -> Prepared {
    let (mut paths, mut rays, mut hits, mut next) = (
        PathState::default(),
        RayBatch::default(),
        HitBatch::default(),
        RayBatch::default(),
    );
    let mut shadows = ShadowBatch {
        per_path: SHADOW_RAYS as usize,
        ..Default::default()
    };
    generate_camera_rays(
        camera,
        rng::DEFAULT_SEED,
        rng::Sampler::Independent,
        pixels,
        None,
        0,
        &mut paths,
        &mut rays,
    );
    intersect_closest(scene, &rays, &paths.rng_key, 0, &mut hits);
    let defaults = wavetrace::RenderSettings::default();
    let params = ShadeParams {
        bounce: 0,
        shadow_rays: SHADOW_RAYS,
        mis: true, // the renderer's default
        roulette_min_bounces: defaults.roulette_min_bounces,
        max_depth: defaults.max_depth,
        sampler: defaults.sampler,
        caustics: None,
    };
    let camera_paths = paths.clone();
    shade_hits(
        scene,
        params,
        &rays,
        &hits,
        &mut paths,
        &mut next,
        &mut shadows,
    );
    Prepared {
        camera_rays: rays,
        camera_hits: hits,
        camera_paths,
        bounce_rays: next,
        shadow_paths: paths,
        shadows,
        params,
    }
}

/// Which rays of a sub-batch an intersect benchmark casts.
type RaysOf = fn(&Prepared) -> (&RayBatch, &Vec<u64>);

/// How many of something the sub-batches of `batch` have together.
fn total(batch: &[Prepared], count: impl Fn(&Prepared) -> usize) -> u64 {
    batch.iter().map(count).sum::<usize>() as u64
}

fn stages(c: &mut Criterion) {
    let room = flatten(&room_world(), Path::new("builtin:room")).unwrap();
    let heavy = flatten(&heavy_world(), Path::new("heavy")).unwrap();
    for (name, scene) in [("seed_room", &room), ("heavy", &heavy)] {
        let batch = prepare(scene);
        let camera = PinholeCamera::new(scene.camera(), SIDE, SIDE);

        let mut g = c.benchmark_group("generate");
        g.throughput(Throughput::Elements(BATCH as u64));
        g.bench_function(name, |b| {
            let (mut paths, mut rays) = (PathState::default(), RayBatch::default());
            b.iter(|| {
                for pixels in sub_batch_pixels() {
                    generate_camera_rays(
                        &camera,
                        rng::DEFAULT_SEED,
                        rng::Sampler::Independent,
                        pixels,
                        None,
                        0,
                        &mut paths,
                        &mut rays,
                    );
                }
            })
        });
        g.finish();

        let mut g = c.benchmark_group("intersect");
        g.sample_size(20);
        let rays: [(&str, RaysOf, u32); 2] = [
            ("camera", |p| (&p.camera_rays, &p.camera_paths.rng_key), 0),
            ("bounce", |p| (&p.bounce_rays, &p.shadow_paths.rng_key), 1),
        ];
        for (kind, rays, bounce) in rays {
            g.throughput(Throughput::Elements(total(&batch, |p| rays(p).0.len())));
            g.bench_function(format!("{name}_{kind}"), |b| {
                let mut hits = HitBatch::default();
                b.iter(|| {
                    for p in &batch {
                        let (rays, keys) = rays(p);
                        intersect_closest(scene, rays, keys, bounce, &mut hits);
                    }
                })
            });
        }
        g.finish();

        let mut g = c.benchmark_group("shade");
        g.sample_size(20);
        g.throughput(Throughput::Elements(total(&batch, |p| {
            p.camera_paths.len()
        })));
        g.bench_function(name, |b| {
            let (mut next, mut shadows) = (
                RayBatch::default(),
                ShadowBatch {
                    per_path: SHADOW_RAYS as usize,
                    ..Default::default()
                },
            );
            b.iter_batched_ref(
                || {
                    batch
                        .iter()
                        .map(|p| p.camera_paths.clone())
                        .collect::<Vec<_>>()
                },
                |paths| {
                    for (p, paths) in batch.iter().zip(paths) {
                        black_box(shade_hits(
                            scene,
                            p.params,
                            &p.camera_rays,
                            &p.camera_hits,
                            paths,
                            &mut next,
                            &mut shadows,
                        ));
                    }
                },
                BatchSize::LargeInput,
            )
        });
        g.finish();

        let mut g = c.benchmark_group("shadow");
        g.sample_size(20);
        let traced = |p: &Prepared| p.shadows.count[..p.shadow_paths.len()].iter().sum::<u32>();
        g.throughput(Throughput::Elements(total(&batch, |p| traced(p) as usize)));
        g.bench_function(name, |b| {
            b.iter_batched_ref(
                || {
                    batch
                        .iter()
                        .map(|p| p.shadow_paths.clone())
                        .collect::<Vec<_>>()
                },
                |paths| {
                    for (p, paths) in batch.iter().zip(paths) {
                        black_box(trace_shadow_rays(scene, &p.shadows, 0, paths));
                    }
                },
                BatchSize::LargeInput,
            )
        });
        g.finish();
    }

    let mut g = c.benchmark_group("bvh_build");
    g.sample_size(10);
    let world = heavy_world();
    let triangles: u64 = world
        .query::<&Mesh>()
        .iter()
        .map(|m| m.indices.len() as u64)
        .sum();
    g.throughput(Throughput::Elements(triangles));
    g.bench_function("heavy", |b| {
        b.iter(|| black_box(flatten(&world, Path::new("heavy")).unwrap().bvh_depth()))
    });
    g.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);
