//! Vertex colours end to end: glTF `COLOR_0` (float RGB and normalized unsigned byte RGBA) and
//! OBJ `v x y z r g b` multiply the base colour. Each coloured model is rendered in the seed
//! room against the same model without colours whose base colour is the product (estimator
//! against estimator), and against the same model without colours and the base colour alone,
//! which must differ (so the comparison can fail). Every file is written by the test.

use crate::common::{assert_agree, estimate};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use wavetrace::{RenderScene, RenderSettings, flatten, load_scene};

/// Three unit squares in the planes x = 0, y = 0 and z = 0 (so that some of them face the
/// room camera however the model is turned), as vertices and triangles.
fn three_squares() -> (Vec<[f32; 3]>, Vec<[u16; 3]>) {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        let base = positions.len() as u16;
        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let mut p = [0.0f32; 3];
            p[(axis + 1) % 3] = u;
            p[(axis + 2) % 3] = v;
            positions.push(p);
        }
        triangles.push([base, base + 1, base + 2]);
        triangles.push([base + 2, base + 1, base + 3]);
    }
    (positions, triangles)
}

/// How the test writes `COLOR_0`.
#[derive(Clone, Copy)]
enum Colour {
    None,
    /// The same float RGB at every vertex.
    FloatRgb([f32; 3]),
    /// The same normalized unsigned-byte RGBA at every vertex.
    ByteRgba([u8; 4]),
}

/// Writes `<name>.gltf` and `<name>.bin`: [`three_squares`], double-sided, with a dielectric
/// material of base colour `base` and roughness 1, and vertex colours `colour`.
fn write_gltf(dir: &Path, name: &str, base: [f32; 3], colour: Colour) -> PathBuf {
    let (positions, triangles) = three_squares();
    let n = positions.len();
    let mut bytes: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut push = |data: Vec<u8>, mut accessor: Value| {
        while !bytes.len().is_multiple_of(4) {
            bytes.push(0);
        }
        views.push(json!({"buffer": 0, "byteOffset": bytes.len(), "byteLength": data.len()}));
        bytes.extend(data);
        accessor["bufferView"] = json!(views.len() - 1);
        accessors.push(accessor);
        accessors.len() - 1
    };
    let position = push(
        positions
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect(),
        json!({"componentType": 5126, "count": n, "type": "VEC3",
               "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]}),
    );
    let indices = push(
        triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect(),
        json!({"componentType": 5123, "count": triangles.len() * 3, "type": "SCALAR"}),
    );
    let mut attributes = json!({"POSITION": position});
    match colour {
        Colour::None => {}
        Colour::FloatRgb(c) => {
            let data = (0..n)
                .flat_map(|_| c)
                .flat_map(|x| x.to_le_bytes())
                .collect();
            attributes["COLOR_0"] = json!(push(
                data,
                json!({"componentType": 5126, "count": n, "type": "VEC3"})
            ));
        }
        Colour::ByteRgba(c) => {
            let data = (0..n).flat_map(|_| c).collect();
            attributes["COLOR_0"] = json!(push(
                data,
                json!({"componentType": 5121, "normalized": true, "count": n, "type": "VEC4"})
            ));
        }
    }
    let bin = format!("{name}.bin");
    let doc = json!({
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "squares", "mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": indices, "material": 0}]}],
        "materials": [{"doubleSided": true, "pbrMetallicRoughness": {
            "baseColorFactor": [base[0], base[1], base[2], 1.0],
            "metallicFactor": 0.0, "roughnessFactor": 1.0}}],
        "buffers": [{"byteLength": bytes.len(), "uri": bin}],
        "bufferViews": views,
        "accessors": accessors,
    });
    std::fs::write(dir.join(&bin), &bytes).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// The model placed in the seed room, flattened; the load must not warn.
fn placed(path: &Path) -> RenderScene {
    let scene = load_scene(path).unwrap_or_else(|e| panic!("{} loads: {e}", path.display()));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    flatten(&scene.world, path).expect("flattens")
}

fn settings() -> RenderSettings {
    RenderSettings {
        width: 48,
        height: 48,
        spp: 16,
        seed: 7,
        ..Default::default()
    }
}

/// Asserts that `coloured` renders as `product` (within 4 standard errors) and that `plain`
/// does not (beyond 6).
fn assert_colour_multiplies(coloured: &Path, product: &Path, plain: &Path) {
    let settings = settings();
    let with_colours = estimate(&placed(coloured), &settings);
    assert_agree(
        "vertex colour x base colour vs their product as base colour",
        with_colours,
        estimate(&placed(product), &settings),
        4.0,
    );
    let (m, e) = with_colours;
    let (p, ep) = estimate(&placed(plain), &settings);
    let z = (0..3)
        .map(|c| ((m[c] - p[c]) / (e[c] * e[c] + ep[c] * ep[c]).sqrt()).abs())
        .fold(0.0, f64::max);
    eprintln!("vertex colours against none: {z:.1} sigma apart");
    assert!(
        z > 6.0,
        "the colours change the image by only {z:.1} sigma ({m:?} vs {p:?})"
    );
}

#[test]
fn gltf_float_and_byte_vertex_colours_multiply_the_base_colour() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = [0.9, 0.8, 0.7];
    let times = |c: [f32; 3]| [0, 1, 2].map(|k| base[k] * c[k]);
    let plain = write_gltf(d, "plain", base, Colour::None);

    let float = [0.2, 0.5, 1.0];
    assert_colour_multiplies(
        &write_gltf(d, "float", base, Colour::FloatRgb(float)),
        &write_gltf(d, "float-product", times(float), Colour::None),
        &plain,
    );

    // Normalized bytes: c / 255 (the alpha byte is coverage, not colour).
    let bytes = [255, 51, 128, 200];
    let as_float = [0, 1, 2].map(|k| bytes[k] as f32 / 255.0);
    assert_colour_multiplies(
        &write_gltf(d, "bytes", base, Colour::ByteRgba(bytes)),
        &write_gltf(d, "bytes-product", times(as_float), Colour::None),
        &plain,
    );
}

/// Writes `<name>.obj` ([`three_squares`], with `v x y z r g b` when `colour` is given) and
/// `<name>.mtl` with `Kd` = `kd`.
fn write_obj(dir: &Path, name: &str, kd: [f32; 3], colour: Option<[f32; 3]>) -> PathBuf {
    let (positions, triangles) = three_squares();
    let mut text = format!("mtllib {name}.mtl\nusemtl m\n");
    for p in positions {
        text += &format!("v {} {} {}", p[0], p[1], p[2]);
        if let Some(c) = colour {
            text += &format!(" {} {} {}", c[0], c[1], c[2]);
        }
        text += "\n";
    }
    for t in triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(dir.join(format!("{name}.obj")), text).unwrap();
    let mtl = format!("newmtl m\nKd {} {} {}\n", kd[0], kd[1], kd[2]);
    std::fs::write(dir.join(format!("{name}.mtl")), mtl).unwrap();
    dir.join(format!("{name}.obj"))
}

#[test]
fn obj_vertex_colours_multiply_the_diffuse_colour() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let kd = [0.9, 0.8, 0.7];
    let colour = [0.25, 1.0, 0.5];
    assert_colour_multiplies(
        &write_obj(d, "coloured", kd, Some(colour)),
        &write_obj(d, "product", [0, 1, 2].map(|k| kd[k] * colour[k]), None),
        &write_obj(d, "plain", kd, None),
    );
}
