//! glTF geometry beyond plain float triangles: quantized attributes (`KHR_mesh_quantization`)
//! dequantize to the vertices the floats would give, compressed geometry that cannot be decoded
//! (Draco) is refused with an error that names the codec and the way out (meshopt is decoded:
//! meshopt.rs). Every file is written by the test.

use crate::common::{GltfDoc, world_vertices};
use serde_json::json;
use std::path::{Path, PathBuf};
use wavetrace::math::Vec3;
use wavetrace::scene::load::{UpAxis, import_model};

#[test]
fn quantized_positions_and_normals_dequantize() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    // Positions as unnormalized u16 in an interleaved view (stride 8: x, y, z, padding),
    // scaled by the node's transform as gltfpack writes them; normals as normalized i8 (VEC3
    // padded to 4 bytes per the alignment rule).
    let grid: [[u16; 3]; 3] = [[0, 0, 0], [1000, 0, 0], [0, 2000, 500]];
    let data = grid
        .iter()
        .flat_map(|p| p.iter().chain(&[0u16]).flat_map(|c| c.to_le_bytes()))
        .collect();
    let position = doc.push(
        data,
        Some(8),
        json!({"componentType": 5123, "count": 3, "type": "VEC3",
               "min": [0, 0, 0], "max": [1000, 2000, 500]}),
    );
    let normal_bytes: [[i8; 3]; 3] = [[0, 0, 127], [0, -127, 0], [-128, 0, 0]];
    let data = normal_bytes
        .iter()
        .flat_map(|n| n.iter().map(|&c| c as u8).chain([0]))
        .collect();
    let normal = doc.push(
        data,
        Some(4),
        json!({"componentType": 5120, "normalized": true, "count": 3, "type": "VEC3"}),
    );
    let path = doc.write(
        dir.path(),
        "quantized.gltf",
        json!({
            "extensionsUsed": ["KHR_mesh_quantization"],
            "extensionsRequired": ["KHR_mesh_quantization"],
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0, "scale": [0.001, 0.001, 0.001], "translation": [1, 2, 3]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal}}]}],
        }),
    );
    let scene = import_model(&path, UpAxis::Z).unwrap_or_else(|e| panic!("loads: {e}"));
    assert!(
        scene.warnings.iter().all(|w| !w.contains("quantization")),
        "{:?}",
        scene.warnings
    );
    let vertices = world_vertices(&scene);
    let expected_positions =
        grid.map(|p| Vec3::new(1.0, 2.0, 3.0) + Vec3::from(p.map(f32::from)) * 0.001);
    let expected_normals = [Vec3::Z, Vec3::NEG_Y, Vec3::NEG_X];
    assert_eq!(vertices.len(), 3);
    for ((p, n), (want_p, want_n)) in vertices
        .iter()
        .zip(expected_positions.iter().zip(expected_normals))
    {
        assert!((*p - *want_p).length() < 1e-5, "{p} != {want_p}");
        assert_eq!(*n, Some(want_n));
    }
}

#[test]
fn unnormalized_integer_normals_are_refused_for_the_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let data = [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let position = doc.push(
        data,
        None,
        json!({"componentType": 5126, "count": 3, "type": "VEC3",
               "min": [0, 0, 0], "max": [1, 1, 0]}),
    );
    let normal = doc.push(
        vec![0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0],
        Some(4),
        json!({"componentType": 5120, "count": 3, "type": "VEC3"}),
    );
    let path = doc.write(
        dir.path(),
        "bad_normals.gltf",
        json!({
            "extensionsUsed": ["KHR_mesh_quantization"],
            "scenes": [{"nodes": [0]}],
            "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": position, "NORMAL": normal}}]}],
        }),
    );
    let message = import_model(&path, UpAxis::Z)
        .err()
        .expect("nothing left")
        .to_string();
    assert!(
        message.contains("NORMAL") && message.contains("not normalized"),
        "{message}"
    );
}

/// A file whose one triangle is only available through `extension`'s compressed data.
fn compressed(dir: &Path, name: &str, extension: &str, required: bool) -> PathBuf {
    let mut root = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": [extension],
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0},
            "extensions": {extension: {"bufferView": 0, "attributes": {"POSITION": 0}}}}]}],
        "buffers": [{"byteLength": 4, "uri": "data:application/octet-stream;base64,AAAAAA=="}],
        "bufferViews": [{"buffer": 0, "byteLength": 4}],
    });
    if required {
        root["extensionsRequired"] = json!([extension]);
    }
    let path = dir.join(name);
    std::fs::write(&path, root.to_string()).unwrap();
    path
}

#[test]
fn compressed_geometry_is_refused_naming_the_codec_and_the_way_out() {
    let dir = tempfile::tempdir().unwrap();
    for (extension, required, codec) in [
        ("KHR_draco_mesh_compression", true, "Draco"),
        ("KHR_draco_mesh_compression", false, "Draco"),
    ] {
        let path = compressed(
            dir.path(),
            &format!("{extension}{required}.gltf"),
            extension,
            required,
        );
        let message = import_model(&path, UpAxis::Z)
            .err()
            .unwrap_or_else(|| panic!("{extension} (required: {required}) should be refused"))
            .to_string();
        assert!(
            message.contains(codec) && message.contains(extension) && message.contains("re-export"),
            "{message}"
        );
        assert!(!message.contains("Missing data"), "{message}");
    }
}
