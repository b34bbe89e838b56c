//! Meshopt-compressed geometry (`EXT_meshopt_compression`, `KHR_meshopt_compression`) loads
//! as the same file uncompressed: positions bit for bit (filter NONE), normals within the
//! octahedral filter's quantisation, the triangles of modes TRIANGLES and INDICES exactly (up to the rotation of corners that
//! TRIANGLES allows). Files are
//! written by the test with the `meshopt` crate's encoders (the library wavetrace decodes
//! with; the bitstreams are the extensions' own, fixed by their specifications), and real
//! files from gltfpack and gltf-pipeline (`tests/data/gltfpack`) render as their source or
//! are refused by name.

use crate::common::{GltfDoc, glb};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use wavetrace::math::Vec3;
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::scene::{Mesh, SharedMesh, mesh_of};

/// A 21 x 21 height field (441 vertices: more than one 256-element attribute block, not a
/// multiple of 16), its unit normals and its triangles.
fn height_field() -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<u32>) {
    let n = 21u32;
    let h = |x: f32, y: f32| 0.3 * (2.0 * x).sin() * (1.5 * y).cos();
    let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f32 * 0.1 - 1.0, j as f32 * 0.1 - 1.0);
            positions.push([x, y, h(x, y)]);
            let (dx, dy) = (
                0.6 * (2.0 * x).cos() * (1.5 * y).cos(),
                -0.45 * (2.0 * x).sin() * (1.5 * y).sin(),
            );
            let normal = Vec3::new(-dx, -dy, 1.0).normalize();
            normals.push(normal.to_array());
        }
    }
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            indices.extend([v, v + 1, v + n, v + 1, v + n + 1, v + n]);
        }
    }
    (positions, normals, indices)
}

fn le_bytes<T: Copy, const N: usize>(values: &[T], to: fn(T) -> [u8; N]) -> Vec<u8> {
    values.iter().flat_map(|&v| to(v)).collect()
}

/// The glTF around two primitives: `[positions, normals, indices]` accessors each.
fn gltf_root(primitives: [[usize; 3]; 2], extension: Option<&str>) -> Value {
    let primitive =
        |[p, n, i]: [usize; 3]| json!({"attributes": {"POSITION": p, "NORMAL": n}, "indices": i});
    let mut root = json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": primitives.map(primitive)}],
    });
    let mut used = vec!["KHR_mesh_quantization"];
    used.extend(extension);
    root["extensionsUsed"] = json!(used);
    root["extensionsRequired"] = json!(used);
    root
}

/// The uncompressed file: float positions, normals as normalized shorts (the type the
/// octahedral filter writes), the first primitive's indices as u16, the second's as u32.
fn uncompressed(dir: &Path, normals: &[[i16; 4]]) -> PathBuf {
    let (positions, _, indices) = height_field();
    let mut doc = GltfDoc::default();
    let position = doc.positions(&positions);
    let normal = doc.push(
        le_bytes(&normals.concat(), i16::to_le_bytes),
        Some(8),
        json!({"componentType": 5122, "normalized": true, "count": normals.len(),
               "type": "VEC3"}),
    );
    let short: Vec<u16> = indices.iter().map(|&i| i as u16).collect();
    let first = doc.push(
        le_bytes(&short, u16::to_le_bytes),
        None,
        json!({"componentType": 5123, "count": indices.len(), "type": "SCALAR"}),
    );
    let half = &indices[..indices.len() / 2];
    let second = doc.push(
        le_bytes(half, u32::to_le_bytes),
        None,
        json!({"componentType": 5125, "count": half.len(), "type": "SCALAR"}),
    );
    let root = gltf_root(
        [[position, normal, first], [position, normal, second]],
        None,
    );
    doc.write(dir, "plain.gltf", root)
}

/// The same file compressed: positions ATTRIBUTES (filter NONE), normals ATTRIBUTES with the
/// OCTAHEDRAL filter, the first indices TRIANGLES, the second INDICES. `vertex_version` 0 is
/// the one `EXT_meshopt_compression` allows; `corrupt_sequence` breaks the INDICES stream.
fn compressed(dir: &Path, extension: &str, vertex_version: i32, corrupt_sequence: bool) -> PathBuf {
    let (positions, normals, indices) = height_field();
    let mut doc = GltfDoc::default();
    let encode = |data: &[u8], stride: usize| -> Vec<u8> {
        // The encoder takes elements of a fixed type: bytes grouped by the stride.
        match stride {
            12 => {
                let v: Vec<[u8; 12]> = data
                    .chunks_exact(12)
                    .map(|c| c.try_into().unwrap())
                    .collect();
                meshopt::encoding::encode_vertex_buffer_level(&v, 2, Some(vertex_version))
            }
            _ => {
                let v: Vec<[u8; 8]> = data
                    .chunks_exact(8)
                    .map(|c| c.try_into().unwrap())
                    .collect();
                meshopt::encoding::encode_vertex_buffer_level(&v, 2, Some(vertex_version))
            }
        }
        .unwrap()
    };
    let float_bytes = le_bytes(&positions.concat(), f32::to_le_bytes);
    let position = doc.push_meshopt(
        extension,
        encode(&float_bytes, 12),
        json!({"mode": "ATTRIBUTES", "byteStride": 12, "count": positions.len()}),
        float_bytes.len(),
        None,
        json!({"componentType": 5126, "count": positions.len(), "type": "VEC3",
               "min": [-1.0, -1.0, -0.3], "max": [1.0, 1.0, 0.3]}),
    );
    let unit: Vec<[f32; 4]> = normals.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect();
    let octahedral = meshopt::encoding::encode_filter_oct::<i16>(&unit, 16);
    let octahedral_bytes = le_bytes(&octahedral.concat(), i16::to_le_bytes);
    let normal = doc.push_meshopt(
        extension,
        encode(&octahedral_bytes, 8),
        json!({"mode": "ATTRIBUTES", "filter": "OCTAHEDRAL", "byteStride": 8,
               "count": normals.len()}),
        octahedral_bytes.len(),
        Some(8),
        json!({"componentType": 5122, "normalized": true, "count": normals.len(),
               "type": "VEC3"}),
    );
    let triangles = meshopt::encoding::encode_index_buffer(&indices, positions.len()).unwrap();
    let first = doc.push_meshopt(
        extension,
        triangles,
        json!({"mode": "TRIANGLES", "byteStride": 2, "count": indices.len()}),
        indices.len() * 2,
        None,
        json!({"componentType": 5123, "count": indices.len(), "type": "SCALAR"}),
    );
    let half = &indices[..indices.len() / 2];
    let mut sequence = meshopt::encoding::encode_index_sequence(half, positions.len()).unwrap();
    if corrupt_sequence {
        // A wrong header byte: no meshopt index sequence.
        sequence[0] = 0x00;
    }
    let second = doc.push_meshopt(
        extension,
        sequence,
        json!({"mode": "INDICES", "byteStride": 4, "count": half.len()}),
        half.len() * 4,
        None,
        json!({"componentType": 5125, "count": half.len(), "type": "SCALAR"}),
    );
    let root = gltf_root(
        [[position, normal, first], [position, normal, second]],
        Some(extension),
    );
    doc.write(dir, &format!("{extension}{corrupt_sequence}.gltf"), root)
}

/// The meshes of a loaded file, in entity order.
fn meshes(path: &Path) -> (Vec<Mesh>, Vec<String>) {
    let scene = import_model(path, UpAxis::Z).unwrap_or_else(|e| panic!("loads: {e}"));
    let mut meshes: Vec<(u32, Mesh)> = scene
        .world
        .query::<(hecs::Entity, Option<&Mesh>, Option<&SharedMesh>)>()
        .iter()
        .filter_map(|(e, m, s)| mesh_of(m, s).map(|m| (e.id(), m.clone())))
        .collect();
    meshes.sort_by_key(|(id, _)| *id);
    (meshes.into_iter().map(|(_, m)| m).collect(), scene.warnings)
}

#[test]
fn meshopt_geometry_loads_as_the_same_file_uncompressed() {
    let dir = tempfile::tempdir().unwrap();
    let (_, normals, _) = height_field();
    let unit: Vec<[f32; 4]> = normals.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect();
    // The reference holds what the octahedral filter decodes to, as shorts: the filter's
    // inverse is meshoptimizer's own decoder, so it is checked against the float normals too.
    let octahedral = meshopt::encoding::encode_filter_oct::<i16>(&unit, 16);
    let mut decoded = octahedral.clone();
    meshopt::encoding::decode_filter_oct(&mut decoded);
    let (plain, plain_warnings) = meshes(&uncompressed(dir.path(), &decoded));
    assert_eq!(plain.len(), 2);
    for (extension, version) in [
        ("EXT_meshopt_compression", 0),
        ("KHR_meshopt_compression", 0),
        ("KHR_meshopt_compression", 1),
    ] {
        let (packed, warnings) = meshes(&compressed(dir.path(), extension, version, false));
        assert_eq!(
            warnings, plain_warnings,
            "{extension}: no warning of its own"
        );
        assert_eq!(packed.len(), 2, "{extension}");
        for (p, q) in plain.iter().zip(&packed) {
            // TRIANGLES may rotate a triangle's corners, keeping its winding.
            let canonical = |t: &[u32; 3]| {
                let first = (0..3).min_by_key(|&k| t[k]).unwrap();
                [0, 1, 2].map(|k| t[(first + k) % 3])
            };
            assert!(
                q.indices
                    .iter()
                    .map(canonical)
                    .eq(p.indices.iter().map(canonical)),
                "{extension} v{version}: triangles"
            );
            assert!(
                q.positions
                    .iter()
                    .zip(&p.positions)
                    .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits)),
                "{extension} v{version}: positions bit for bit"
            );
            assert_eq!(q.normals, p.normals, "{extension} v{version}: normals");
        }
    }
    // Within the filter's 16-bit quantisation of the true normals: the loader may renormalise,
    // so compare directions.
    for (n, truth) in plain[0].normals.iter().zip(&normals) {
        let angle = n.normalize().angle_between(Vec3::from(*truth));
        assert!(angle < 1e-3, "normal off by {angle} rad");
    }
}

#[test]
fn a_view_that_does_not_decode_skips_its_primitives_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = compressed(dir.path(), "EXT_meshopt_compression", 0, true);
    let (loaded, warnings) = meshes(&path);
    // View 3 holds the second primitive's indices; the first primitive is whole.
    assert_eq!(loaded.len(), 1, "{warnings:?}");
    assert_eq!(loaded[0].indices.len(), 400 * 2);
    let file = path.display().to_string();
    let about_view: Vec<&String> = warnings.iter().filter(|w| w.contains("view 3")).collect();
    assert_eq!(about_view.len(), 1, "{warnings:?}");
    assert!(
        about_view[0].contains(&file) && about_view[0].contains("does not decode"),
        "{warnings:?}"
    );
}

#[test]
fn a_required_extension_without_compressed_views_loads() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, _, indices) = height_field();
    let mut doc = GltfDoc::default();
    let position = doc.positions(&positions);
    let index = doc.push(
        le_bytes(&indices, u32::to_le_bytes),
        None,
        json!({"componentType": 5125, "count": indices.len(), "type": "SCALAR"}),
    );
    let mut root = gltf_root(
        [[position, position, index], [position, position, index]],
        Some("KHR_meshopt_compression"),
    );
    root["meshes"][0]["primitives"][0]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("NORMAL");
    root["meshes"][0]["primitives"][1]["attributes"]
        .as_object_mut()
        .unwrap()
        .remove("NORMAL");
    let (loaded, _) = meshes(&doc.write(dir.path(), "plain.gltf", root));
    assert_eq!(loaded.len(), 2);
}

/// The JSON and buffer 0 of a file written by [`compressed`].
fn json_and_bin(path: &Path) -> (Value, Vec<u8>) {
    let doc: Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let bin = path.with_file_name(doc["buffers"][0]["uri"].as_str().unwrap());
    (doc, std::fs::read(bin).unwrap())
}

#[test]
fn a_glb_with_an_unmarked_placeholder_buffer_loads_as_gltfpack_writes_it() {
    // gltfpack's layout: the compressed data in the BIN chunk (buffer 0), the views in a
    // buffer without uri after it, which the specification need not mark as a fallback.
    let dir = tempfile::tempdir().unwrap();
    let gltf = compressed(dir.path(), "EXT_meshopt_compression", 0, false);
    let (mut doc, bin) = json_and_bin(&gltf);
    doc["buffers"][1]
        .as_object_mut()
        .unwrap()
        .remove("extensions");
    let path = dir.path().join("packed.glb");
    std::fs::write(&path, glb(&doc, &bin)).unwrap();
    let (from_glb, warnings) = meshes(&path);
    let (from_gltf, _) = meshes(&gltf);
    assert_eq!(from_glb, from_gltf, "{warnings:?}");
}

#[test]
fn a_view_that_does_not_decode_reads_its_uncompressed_fallback_when_there_is_one() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, normals, indices) = height_field();
    let unit: Vec<[f32; 4]> = normals.iter().map(|n| [n[0], n[1], n[2], 0.0]).collect();
    let mut octahedral = meshopt::encoding::encode_filter_oct::<i16>(&unit, 16);
    meshopt::encoding::decode_filter_oct(&mut octahedral);
    let short: Vec<u16> = indices.iter().map(|&i| i as u16).collect();
    // What each view holds uncompressed, in view order (as `compressed` writes them).
    let views = [
        le_bytes(&positions.concat(), f32::to_le_bytes),
        le_bytes(&octahedral.concat(), i16::to_le_bytes),
        le_bytes(&short, u16::to_le_bytes),
        le_bytes(&indices[..indices.len() / 2], u32::to_le_bytes),
    ];
    let gltf = compressed(dir.path(), "EXT_meshopt_compression", 0, true);
    let (mut doc, _) = json_and_bin(&gltf);
    let mut fallback = vec![0u8; doc["buffers"][1]["byteLength"].as_u64().unwrap() as usize];
    for (v, data) in views.iter().enumerate() {
        let at = doc["bufferViews"][v]["byteOffset"].as_u64().unwrap() as usize;
        fallback[at..at + data.len()].copy_from_slice(data);
    }
    std::fs::write(dir.path().join("fallback.bin"), &fallback).unwrap();
    doc["buffers"][1] = json!({"byteLength": fallback.len(), "uri": "fallback.bin"});
    doc["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    let path = dir.path().join("with-fallback.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let (loaded, warnings) = meshes(&path);
    let (plain, _) = meshes(&uncompressed(dir.path(), &octahedral));
    assert_eq!(loaded.len(), 2, "{warnings:?}");
    assert_eq!(
        loaded[1], plain[1],
        "the INDICES view read from the fallback"
    );
    let about_view: Vec<&String> = warnings.iter().filter(|w| w.contains("view 3")).collect();
    assert_eq!(about_view.len(), 1, "{warnings:?}");
    assert!(about_view[0].contains("uncompressed data"), "{warnings:?}");
}

/// A triangle drawn by three `EXT_mesh_gpu_instancing` instances whose translations and
/// rotations are the decoded output of the EXPONENTIAL and QUATERNION filters: with
/// `compress`, stored compressed with those filters; else as the plain decoded values.
fn instanced(dir: &Path, compress: bool) -> PathBuf {
    let translations: Vec<[f32; 3]> = vec![[0.0, 0.0, 0.0], [1.5, -0.25, 3.0], [-2.0, 0.5, 0.125]];
    let rotations: Vec<[f32; 4]> = vec![
        [0.0, 0.0, 0.0, 1.0],
        [0.0, 0.6, 0.0, 0.8],
        [0.5, -0.5, 0.5, 0.5],
    ];
    let exp = meshopt::encoding::encode_filter_exp(
        &translations,
        15,
        meshopt::EncodeExpMode::SharedVector,
    );
    let quat = meshopt::encoding::encode_filter_quat(&rotations, 12);
    let (mut exp_decoded, mut quat_decoded) = (exp.clone(), quat.clone());
    meshopt::encoding::decode_filter_exp(&mut exp_decoded);
    meshopt::encoding::decode_filter_quat(&mut quat_decoded);
    let mut doc = GltfDoc::default();
    let position = doc.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let extension = "EXT_meshopt_compression";
    let (translation, rotation) = if compress {
        let t = doc.push_meshopt(
            extension,
            meshopt::encoding::encode_vertex_buffer(&exp).unwrap(),
            json!({"mode": "ATTRIBUTES", "filter": "EXPONENTIAL", "byteStride": 12, "count": 3}),
            36,
            None,
            json!({"componentType": 5126, "count": 3, "type": "VEC3"}),
        );
        let r = doc.push_meshopt(
            extension,
            meshopt::encoding::encode_vertex_buffer(&quat).unwrap(),
            json!({"mode": "ATTRIBUTES", "filter": "QUATERNION", "byteStride": 8, "count": 3}),
            24,
            None,
            json!({"componentType": 5122, "normalized": true, "count": 3, "type": "VEC4"}),
        );
        (t, r)
    } else {
        let t = doc.push(
            le_bytes(&exp_decoded.concat(), u32::to_le_bytes),
            None,
            json!({"componentType": 5126, "count": 3, "type": "VEC3"}),
        );
        let r = doc.push(
            le_bytes(&quat_decoded.concat(), i16::to_le_bytes),
            None,
            json!({"componentType": 5122, "normalized": true, "count": 3, "type": "VEC4"}),
        );
        (t, r)
    };
    let mut used = vec!["EXT_mesh_gpu_instancing"];
    if compress {
        used.push(extension);
    }
    let root = json!({
        "extensionsUsed": used,
        "extensionsRequired": used,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes":
            {"TRANSLATION": translation, "ROTATION": rotation}}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": position}}]}],
    });
    doc.write(dir, &format!("instanced{compress}.gltf"), root)
}

#[test]
fn compressed_instance_transforms_decode_through_the_exponential_and_quaternion_filters() {
    let dir = tempfile::tempdir().unwrap();
    let transforms = |path: &Path| -> Vec<[f32; 12]> {
        let scene = import_model(path, UpAxis::Z).unwrap_or_else(|e| panic!("loads: {e}"));
        let mut t: Vec<(u32, [f32; 12])> = scene
            .world
            .query::<(hecs::Entity, &wavetrace::scene::Transform)>()
            .iter()
            .map(|(e, t)| (e.id(), t.0.to_cols_array()))
            .collect();
        t.sort_by_key(|(id, _)| *id);
        t.into_iter().map(|(_, t)| t).collect()
    };
    let (packed, plain) = (
        transforms(&instanced(dir.path(), true)),
        transforms(&instanced(dir.path(), false)),
    );
    assert_eq!(packed.len(), 3);
    assert_eq!(packed, plain);
    // And near the transforms encoded (15-bit mantissas, 12-bit quaternion components).
    assert!((packed[1][9] - 1.5).abs() < 1e-3 && (packed[2][11] - 0.125).abs() < 1e-3);
}

#[test]
fn compressed_views_are_decoded_even_when_extensions_used_forgets_them() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = compressed(dir.path(), "KHR_meshopt_compression", 1, false);
    let (mut doc, _) = json_and_bin(&gltf);
    doc["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    doc["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    let path = dir.path().join("unlisted.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    assert_eq!(meshes(&path).0, meshes(&gltf).0);
}

/// Renders two files with the same settings and seed and checks that they agree: image
/// means to within 1.5% per channel and every lit 20 x 15 block to within 5%.
fn assert_render_alike(source: &str, packed: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let settings = wavetrace::RenderSettings {
        width: 80,
        height: 60,
        spp: 64,
        seed: 1,
        ..Default::default()
    };
    let image = |path: PathBuf| {
        let scene = wavetrace::load_scene(&path).expect("loads");
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        let flat = wavetrace::flatten(&scene.world, &path).expect("flattens");
        crate::common::render_image(&flat, &settings)
    };
    let source = image(root.join(source));
    let packed = image(root.join(packed));
    let (a, b) = (crate::common::mean(&source), crate::common::mean(&packed));
    for c in 0..3 {
        assert!(
            (b[c] / a[c] - 1.0).abs() < 0.015,
            "channel {c}: {} vs {}",
            b[c],
            a[c]
        );
    }
    let block = |image: &wavetrace::Image, bx: usize, by: usize| {
        let mut sum = 0.0f64;
        for y in by * 15..(by + 1) * 15 {
            for x in bx * 20..(bx + 1) * 20 {
                let p = image.pixels[y * 80 + x];
                sum += f64::from(p[0] + p[1] + p[2]);
            }
        }
        sum
    };
    let mut lit = 0;
    for by in 0..4 {
        for bx in 0..4 {
            let (s, p) = (block(&source, bx, by), block(&packed, bx, by));
            if s > 1.0 {
                lit += 1;
                assert!((p / s - 1.0).abs() < 0.05, "block ({bx}, {by}): {p} vs {s}");
            }
        }
    }
    assert!(lit >= 8, "only {lit} lit blocks");
}

/// A real gltfpack file (`tests/data/gltfpack/README.md`: the Blender export
/// `assets/blender/primitives.glb` through `gltfpack -cc`: meshes merged, meshopt
/// compression with its filters, quantized positions, normals and texture coordinates)
/// renders as its source (measured: means within 0.2-0.5%, blocks within 2.4% at 64 spp; the
/// quantization moves vertices by up to 1/65535 of the mesh's extent and turns normals by
/// up to about 1 degree, which shifts the reflections in the mirror and glass balls).
#[test]
fn a_gltfpack_export_renders_as_its_source() {
    assert_render_alike(
        "assets/blender/primitives.glb",
        "tests/data/gltfpack/primitives-meshopt.glb",
    );
}

/// gltfpack's instancing (`-mi`: 27 nodes sharing a torus become one node with 27
/// `EXT_mesh_gpu_instancing` instances, quantized and meshopt-compressed) renders as the
/// 27 nodes (measured: means within 0.03%, blocks within 0.6%).
#[test]
fn a_gltfpack_instanced_export_renders_as_its_nodes() {
    assert_render_alike(
        "tests/data/gltfpack/torus-grid.gltf",
        "tests/data/gltfpack/torus-grid-instanced.glb",
    );
}

/// A real Draco file (`gltf-pipeline -d` of the same export) is refused with an error that
/// names Draco and says how to re-export, exit 1, nothing written.
#[test]
fn a_gltf_pipeline_draco_export_is_refused_naming_draco() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("draco.png");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render", "--quiet", "--spp", "1", "--width", "8", "--height", "8", "-o",
        ])
        .arg(&output)
        .arg(root.join("tests/data/gltfpack/primitives-draco.glb"))
        .output()
        .unwrap();
    let expected = [
        "primitives-draco.glb",
        "KHR_draco_mesh_compression",
        "re-export",
    ];
    if let Err(e) = crate::common::check_failure(&out, 1, &expected) {
        panic!("{e}");
    }
    assert!(!output.exists(), "no image is written");
}
