//! Instancing: `EXT_mesh_gpu_instancing` draws the node's mesh once per instance (the file
//! renders as the same scene written as one node per instance), and meshes drawn several
//! times render the same through the two-level BVH as flattened into one BVH; a model placed
//! several times by `[[model]]` tables is loaded once and renders as three copies of its file.
//! Every file is written by the test.

use crate::common::GltfDoc;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use wavetrace::math::{Quat, Vec3};
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::scene::{Mesh, SharedMesh};
use wavetrace::{Image, Instancing, RenderScene, RenderSettings, flatten_with, load_scene};

/// A torus around +Y (glTF's up) of radii 1 and 0.35 with `major x minor` quads, with
/// per-vertex normals: positions, normals and triangle indices.
pub fn torus(major: u32, minor: u32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
    let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    let tau = std::f32::consts::TAU;
    for i in 0..major {
        let a = tau * i as f32 / major as f32;
        for j in 0..minor {
            let b = tau * j as f32 / minor as f32;
            let n = [a.cos() * b.cos(), b.sin(), a.sin() * b.cos()];
            positions.push([a.cos() + 0.35 * n[0], 0.35 * n[1], a.sin() + 0.35 * n[2]]);
            normals.push(n);
            let (i1, j1) = ((i + 1) % major, (j + 1) % minor);
            let v = |i: u32, j: u32| i * minor + j;
            indices.extend([v(i, j), v(i, j1), v(i1, j), v(i1, j), v(i, j1), v(i1, j1)]);
        }
    }
    (positions, normals, indices)
}

/// Instance placements (translation, rotation, scale), in the node's space: a plain one, a
/// turned one, a non-uniformly scaled one and a mirrored one (negative determinant).
fn placements() -> Vec<(Vec3, Quat, Vec3)> {
    vec![
        (Vec3::new(-2.5, 0.0, 0.0), Quat::IDENTITY, Vec3::ONE),
        (
            Vec3::new(0.0, 0.5, 0.0),
            Quat::from_axis_angle(Vec3::new(1.0, 0.3, 0.2).normalize(), 1.1),
            Vec3::ONE,
        ),
        (
            Vec3::new(2.5, 0.0, 0.5),
            Quat::from_rotation_z(0.4),
            Vec3::new(1.2, 0.5, 0.8),
        ),
        (
            Vec3::new(0.0, 0.0, 2.8),
            Quat::from_rotation_y(0.7),
            Vec3::new(-1.0, 1.0, 1.0),
        ),
    ]
}

/// Writes the torus placed by [`placements`] under a parent node (which moves and scales
/// them all) as a glTF file: with `instanced`, one node with `EXT_mesh_gpu_instancing`
/// (rotations as normalized shorts, which the extension allows), else one node per
/// placement, all sharing the mesh.
fn write_tori(dir: &Path, name: &str, instanced: bool, segments: (u32, u32)) -> PathBuf {
    let mut doc = GltfDoc::default();
    let (positions, normals, indices) = torus(segments.0, segments.1);
    let position = doc.positions(&positions);
    let normal = doc.floats(&normals, "VEC3");
    let index = doc.push(
        indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
        None,
        json!({"componentType": 5125, "count": indices.len(), "type": "SCALAR"}),
    );
    let placements = placements();
    // The rotations as the file stores them (normalized shorts) and as the reader decodes
    // them, so both files hold the same transforms.
    let quantized: Vec<[i16; 4]> = placements
        .iter()
        .map(|(_, r, _)| r.to_array().map(|c| (c * 32767.0).round() as i16))
        .collect();
    let decoded: Vec<[f32; 4]> = quantized
        .iter()
        .map(|q| q.map(|c| (c as f32 / 32767.0).max(-1.0)))
        .collect();
    let parent = json!({"translation": [0.0, 0.2, -0.5], "scale": [0.9, 0.9, 0.9],
                        "rotation": [0.0, 0.2588190, 0.0, 0.9659258]});
    let mut nodes = vec![parent];
    if instanced {
        let t: Vec<[f32; 3]> = placements.iter().map(|p| p.0.to_array()).collect();
        let s: Vec<[f32; 3]> = placements.iter().map(|p| p.2.to_array()).collect();
        let translation = doc.floats(&t, "VEC3");
        let scale = doc.floats(&s, "VEC3");
        let rotation = doc.push(
            quantized
                .iter()
                .flatten()
                .flat_map(|c| c.to_le_bytes())
                .collect(),
            None,
            json!({"componentType": 5122, "normalized": true, "count": quantized.len(),
                   "type": "VEC4"}),
        );
        nodes.push(
            json!({"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes":
            {"TRANSLATION": translation, "ROTATION": rotation, "SCALE": scale}}}}),
        );
    } else {
        for ((t, _, s), r) in placements.iter().zip(&decoded) {
            let r = Quat::from_array(*r).normalize();
            nodes.push(json!({"mesh": 0, "translation": t.to_array(),
                              "rotation": r.to_array(), "scale": s.to_array()}));
        }
    }
    nodes[0]["children"] = json!((1..nodes.len()).collect::<Vec<_>>());
    let mut root = json!({
        "scenes": [{"nodes": [0]}],
        "nodes": nodes,
        "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal},
                                    "indices": index}]}],
    });
    if instanced {
        root["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing"]);
    }
    doc.write(dir, name, root)
}

/// A small render of `scene` (seed 7).
fn small_render(scene: &RenderScene, spp: u32) -> Image {
    let settings = RenderSettings {
        width: 96,
        height: 72,
        spp,
        seed: 7,
        ..Default::default()
    };
    crate::common::render_image(scene, &settings)
}

/// How far apart two renders of the same scene with the same seed are: the relative
/// difference of their means (per channel, the largest) and the fraction of pixels that
/// differ by more than 1% of the brighter one (plus a floor for black pixels).
fn difference(a: &Image, b: &Image) -> (f64, f64) {
    let (ma, mb) = (crate::common::mean(a), crate::common::mean(b));
    let mean = (0..3)
        .map(|c| (ma[c] - mb[c]).abs() / ma[c].max(mb[c]).max(1e-9))
        .fold(0.0, f64::max);
    let differing = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(x, y)| (0..3).any(|c| (x[c] - y[c]).abs() > 0.01 * x[c].max(y[c]) + 1e-4))
        .count();
    (mean, differing as f64 / a.pixels.len() as f64)
}

/// Meshes drawn by the world: plain and shared.
fn mesh_counts(world: &hecs::World) -> (usize, usize) {
    (
        world.query::<&Mesh>().iter().count(),
        world.query::<&SharedMesh>().iter().count(),
    )
}

#[test]
fn gpu_instances_render_as_the_same_scene_written_as_nodes() {
    let dir = tempfile::tempdir().unwrap();
    let instanced = write_tori(dir.path(), "instanced.gltf", true, (24, 12));
    let nodes = write_tori(dir.path(), "nodes.gltf", false, (24, 12));
    let a = load_scene(&instanced).unwrap_or_else(|e| panic!("loads: {e}"));
    let b = load_scene(&nodes).unwrap_or_else(|e| panic!("loads: {e}"));
    assert!(
        a.warnings.iter().all(|w| !w.contains("instancing")),
        "{:?}",
        a.warnings
    );
    // The room's meshes are plain; the four tori share one mesh in both files.
    let (plain, shared) = mesh_counts(&a.world);
    assert_eq!(shared, placements().len());
    assert_eq!(mesh_counts(&b.world), (plain, shared));
    let a = wavetrace::flatten(&a.world, &instanced).expect("flattens");
    let b = wavetrace::flatten(&b.world, &nodes).expect("flattens");
    assert_eq!(a.primitive_count(), b.primitive_count());
    let (ia, ib) = (small_render(&a, 8), small_render(&b, 8));
    let (mean, differing) = difference(&ia, &ib);
    eprintln!("mean differs by {mean:.2e}, {differing:.4} of the pixels differ");
    assert!(mean < 2e-4 && differing < 0.005, "{mean} {differing}");
}

#[test]
fn bad_instancing_data_skips_the_nodes_instances_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_tori(dir.path(), "bad.gltf", true, (8, 4));
    // The scale accessor reads the rotations (VEC4): a type the extension does not allow.
    let mut root: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let attributes = &mut root["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
    attributes["SCALE"] = attributes["ROTATION"].clone();
    std::fs::write(&path, root.to_string()).unwrap();
    let scene = import_model(&path, UpAxis::Y).unwrap_or_else(|e| panic!("loads: {e}"));
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("EXT_mesh_gpu_instancing") && w.contains("SCALE")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(mesh_counts(&scene.world).1, 0);
}

#[test]
fn two_level_structure_renders_as_the_flattened_scene() {
    // The instanced file (turned, non-uniformly scaled and mirrored instances of a shared
    // torus) traced through the two-level structure and copied into the flat BVH: the same
    // image with the same seed but for rounding (the rays meet the tori in object space).
    let dir = tempfile::tempdir().unwrap();
    let path = write_tori(dir.path(), "tori.gltf", true, (48, 24));
    let scene = load_scene(&path).unwrap_or_else(|e| panic!("loads: {e}"));
    let instanced = flatten_with(&scene.world, &path, Instancing::Always).expect("flattens");
    let flat = flatten_with(&scene.world, &path, Instancing::Never).expect("flattens");
    assert_eq!(instanced.instance_count(), placements().len());
    assert_eq!(flat.instance_count(), 0);
    assert_eq!(instanced.primitive_count(), flat.primitive_count());
    assert!(instanced.stored_primitive_count() < flat.stored_primitive_count());
    let (a, b) = (small_render(&instanced, 8), small_render(&flat, 8));
    crate::common::assert_finite(&a);
    let (mean, differing) = difference(&a, &b);
    eprintln!("mean differs by {mean:.2e}, {differing:.4} of the pixels differ");
    assert!(mean < 2e-4 && differing < 0.005, "{mean} {differing}");
    // The tori must be in view for the comparison to mean something: without them the
    // image changes.
    let mut empty = scene.world;
    let tori: Vec<hecs::Entity> = empty
        .query::<(hecs::Entity, &SharedMesh)>()
        .iter()
        .map(|(e, _)| e)
        .collect();
    for e in tori {
        empty.despawn(e).unwrap();
    }
    let without = wavetrace::flatten(&empty, &path).expect("flattens");
    let (mean, differing) = difference(&a, &small_render(&without, 8));
    assert!(mean > 0.01 && differing > 0.1, "{mean} {differing}");
}

/// Adds a torus of `major` x `minor` quads to `doc`: its position, normal and index accessors.
fn push_torus(doc: &mut GltfDoc, major: u32, minor: u32) -> (usize, usize, usize) {
    let (positions, normals, indices) = torus(major, minor);
    let position = doc.positions(&positions);
    let normal = doc.floats(&normals, "VEC3");
    let index = doc.push(
        indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
        None,
        json!({"componentType": 5125, "count": indices.len(), "type": "SCALAR"}),
    );
    (position, normal, index)
}

#[test]
fn a_thousand_instances_render_as_their_flattened_twin() {
    // 1,000 nodes (a 10 x 10 x 10 grid, each turned, some mirrored and squashed) sharing one
    // torus of 192 triangles: the 1,000-instance case at a size the flat BVH holds.
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let (position, normal, index) = push_torus(&mut doc, 12, 8);
    let mut nodes = Vec::new();
    for k in 0..1000 {
        let (x, y, z) = (k % 10, k / 10 % 10, k / 100);
        let r = Quat::from_axis_angle(Vec3::new(1.0, 0.5, 0.2).normalize(), 0.37 * k as f32);
        let s = match k % 3 {
            0 => [1.0, 1.0, 1.0],
            1 => [-1.0, 1.0, 1.0],
            _ => [1.2, 0.6, 0.9],
        };
        nodes.push(
            json!({"mesh": 0, "translation": [3.0 * x as f32, 3.0 * y as f32,
                          3.0 * z as f32], "rotation": r.to_array(), "scale": s}),
        );
    }
    let path = doc.write(
        dir.path(),
        "grid.gltf",
        json!({
            "scenes": [{"nodes": (0..1000).collect::<Vec<_>>()}],
            "nodes": nodes,
            "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal},
                                        "indices": index}]}],
        }),
    );
    let scene = load_scene(&path).unwrap_or_else(|e| panic!("loads: {e}"));
    let instanced = flatten_with(&scene.world, &path, Instancing::Always).expect("flattens");
    let flat = flatten_with(&scene.world, &path, Instancing::Never).expect("flattens");
    assert_eq!(instanced.instance_count(), 1000);
    assert_eq!(instanced.primitive_count(), flat.primitive_count());
    // With 1,000 small tori nearly touching, a path that meets an edge where the rounding of
    // the object-space test and of the world-space one disagree goes elsewhere from there on
    // (measured: about 4% of the one-sample paths); such paths differ like independent
    // samples, not by a bias (seeds 1, 2, 3, 7: z from -2.4 to 1.7, of both signs). So: few pixels differ at one sample, and at 8 samples the means
    // agree within the spread of the differing pixels.
    let (a1, b1) = (small_render(&instanced, 1), small_render(&flat, 1));
    let (_, differing) = difference(&a1, &b1);
    let (a, b) = (small_render(&instanced, 8), small_render(&flat, 8));
    let (ma, mb) = (crate::common::mean(&a), crate::common::mean(&b));
    let n = a.pixels.len() as f64;
    for c in 0..3 {
        let spread = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| ((x[c] - y[c]) as f64).powi(2))
            .sum::<f64>()
            .sqrt()
            / n;
        let z = (ma[c] - mb[c]) / spread;
        eprintln!(
            "1,000 instances: channel {c}: {:.5} vs {:.5}, z = {z:.2}; {differing:.4} of the \
             one-sample pixels differ",
            ma[c], mb[c]
        );
        assert!(z.abs() < 4.0, "channel {c}: z = {z}");
        assert!((ma[c] - mb[c]).abs() < 5e-3 * mb[c], "channel {c}");
    }
    assert!(differing < 0.08, "{differing} of the pixels differ");
}

/// A scene file placing `files` (one per placement) by three `[[model]]` tables: turned,
/// moved and scaled differently, the last with a material override, under an environment
/// light and the seed room's camera.
fn three_placements(dir: &Path, name: &str, files: [&str; 3]) -> PathBuf {
    let tables = [
        "position = [1.2, -1.2, 0.6]\nrotation = [0, 0, 30]",
        "position = [1.8, 0.0, 0.5]\nrotation = [20, 0, -40]\nscale = 0.8",
        "position = [1.2, 1.2, 0.6]\nscale = [1.0, 0.6, 1.2]\nmaterial = \"red\"",
    ];
    let mut toml = String::from(
        "[camera]\neye = [-1, 0, 0.6]\nlook_at = [1.5, 0, 0.5]\nvfov = 70\n\
         [environment]\ncolor = [1, 1, 1]\n\
         [materials]\nred = { type = \"diffuse\", albedo = [0.8, 0.1, 0.1] }\n",
    );
    for (file, table) in files.iter().zip(tables) {
        toml += &format!("[[model]]\nfile = \"{file}\"\n{table}\n");
    }
    let path = dir.join(name);
    std::fs::write(&path, toml).unwrap();
    path
}

#[test]
fn a_model_placed_three_times_is_loaded_once_and_renders_as_three_copies() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let (position, normal, index) = push_torus(&mut doc, 48, 24);
    // An application-specific attribute: ignored with one warning per loaded file.
    doc.write(
        dir.path(),
        "torus.gltf",
        json!({
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal,
                                                       "_TEMPERATURE": position},
                                        "indices": index}]}],
        }),
    );
    for copy in ["copy1.gltf", "copy2.gltf", "copy3.gltf"] {
        std::fs::copy(dir.path().join("torus.gltf"), dir.path().join(copy)).unwrap();
    }
    let shared_path = three_placements(dir.path(), "shared.toml", ["torus.gltf"; 3]);
    let copies_path = three_placements(
        dir.path(),
        "copies.toml",
        ["copy1.gltf", "copy2.gltf", "copy3.gltf"],
    );
    let shared = load_scene(&shared_path).unwrap_or_else(|e| panic!("loads: {e}"));
    let copies = load_scene(&copies_path).unwrap_or_else(|e| panic!("loads: {e}"));

    // Loaded once: one mesh behind the three placements, and the file's warning given once.
    let meshes: Vec<Arc<Mesh>> = shared
        .world
        .query::<&SharedMesh>()
        .iter()
        .map(|s| s.0.clone())
        .collect();
    assert_eq!(meshes.len(), 3);
    assert!(meshes.iter().all(|m| Arc::ptr_eq(m, &meshes[0])));
    assert_eq!(meshes[0].indices.len(), torus(48, 24).2.len() / 3);
    let about = |warnings: &[String]| {
        warnings
            .iter()
            .filter(|w| w.contains("application-specific"))
            .count()
    };
    assert_eq!(about(&shared.warnings), 1, "{:?}", shared.warnings);
    assert_eq!(about(&copies.warnings), 3, "{:?}", copies.warnings);
    assert_eq!(mesh_counts(&copies.world), (3, 0));

    let reference = wavetrace::flatten(&copies.world, &copies_path).expect("flattens");
    let image = small_render(&reference, 8);
    for instancing in [Instancing::Auto, Instancing::Always] {
        let scene = flatten_with(&shared.world, &shared_path, instancing).expect("flattens");
        assert_eq!(scene.primitive_count(), reference.primitive_count());
        let render = small_render(&scene, 8);
        if instancing == Instancing::Auto {
            // Below INSTANCE_MIN_TRIANGLES the shared mesh is copied: the very same scene.
            assert!(render == image, "Auto: not the image of the three copies");
            continue;
        }
        // The two-level walk gives the same hits up to rounding (as the tests above).
        let (mean, differing) = difference(&render, &image);
        eprintln!("{instancing:?}: mean differs by {mean:.2e}, {differing:.4} of the pixels");
        assert!(mean < 2e-4 && differing < 0.005, "{mean} {differing}");
    }
    // The render is not black: the tori and their override are in view.
    let m = crate::common::mean(&image);
    assert!(m[0] > m[2] && m[2] > 0.01, "{m:?}");
}
