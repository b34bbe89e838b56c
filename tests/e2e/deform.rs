//! glTF deformations in the pose the file holds: a morph target with weight 1 (the mesh's
//! weights, then the node's overriding them) and a skinned mesh with a posed joint load as
//! the same triangles as a plain twin file holding the deformed vertices. Every file is
//! written by the test.

use crate::common::{GltfDoc, world_vertices};
use serde_json::{Value, json};
use std::path::Path;
use wavetrace::math::{Affine3A, Mat4, Quat, Vec3};
use wavetrace::scene::load::{UpAxis, import_model};

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
const NORMALS: [[f32; 3]; 3] = [[0.0, 0.0, 1.0]; 3];

/// Loads `doc` written as `name` and returns its world-space vertices and normals.
fn vertices(dir: &Path, name: &str, doc: GltfDoc, root: Value) -> Vec<(Vec3, Option<Vec3>)> {
    let path = doc.write(dir, name, root);
    let scene = import_model(&path, UpAxis::Y).unwrap_or_else(|e| panic!("{name} loads: {e}"));
    let ours: Vec<&String> = scene
        .warnings
        .iter()
        .filter(|w| w.contains("morph") || w.contains("skin"))
        .collect();
    assert!(ours.is_empty(), "{name}: {ours:?}");
    world_vertices(&scene)
}

/// A plain file with one triangle at `positions` (normals `normals`) under a node at `node`.
fn plain(
    dir: &Path,
    name: &str,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    node: Value,
) -> Vec<(Vec3, Option<Vec3>)> {
    let mut doc = GltfDoc::default();
    let p = doc.positions(positions);
    let n = doc.floats(normals, "VEC3");
    let mut node = node;
    node["mesh"] = json!(0);
    vertices(
        dir,
        name,
        doc,
        json!({"scenes": [{"nodes": [0]}], "nodes": [node],
               "meshes": [{"primitives": [{"attributes": {"POSITION": p, "NORMAL": n}}]}]}),
    )
}

fn assert_same(got: &[(Vec3, Option<Vec3>)], want: &[(Vec3, Option<Vec3>)]) {
    assert_eq!(got.len(), want.len());
    for ((p, n), (wp, wn)) in got.iter().zip(want) {
        assert!((*p - *wp).length() < 1e-5, "position {p} != {wp}");
        let (n, wn) = (n.unwrap(), wn.unwrap());
        assert!((n - wn).length() < 1e-5, "normal {n} != {wn}");
    }
}

/// A triangle with one morph target moving its vertices by `DISPLACEMENT` and tilting its
/// normals, with the mesh's weights and, optionally, the node's.
fn morphed(
    dir: &Path,
    name: &str,
    mesh_weight: f32,
    node_weight: Option<f32>,
) -> Vec<(Vec3, Option<Vec3>)> {
    let mut doc = GltfDoc::default();
    let p = doc.positions(&TRIANGLE);
    let n = doc.floats(&NORMALS, "VEC3");
    let dp = doc.positions(&DISPLACEMENT);
    let dn = doc.floats(&[[1.0, 0.0, 0.0]; 3], "VEC3");
    let mut node = json!({"mesh": 0, "translation": [5.0, 0.0, 0.0]});
    if let Some(w) = node_weight {
        node["weights"] = json!([w]);
    }
    vertices(
        dir,
        name,
        doc,
        json!({"scenes": [{"nodes": [0]}], "nodes": [node],
               "meshes": [{"weights": [mesh_weight], "primitives": [{
                   "attributes": {"POSITION": p, "NORMAL": n},
                   "targets": [{"POSITION": dp, "NORMAL": dn}]}]}]}),
    )
}

const DISPLACEMENT: [[f32; 3]; 3] = [[0.0, 0.0, 2.0], [0.5, 0.0, 0.0], [0.0, 0.0, -1.0]];

#[test]
fn a_morph_target_moves_the_vertices_by_its_weight() {
    let dir = tempfile::tempdir().unwrap();
    let node = json!({"translation": [5.0, 0.0, 0.0]});
    let shifted = |w: f32| {
        TRIANGLE
            .map(|p| p)
            .iter()
            .zip(DISPLACEMENT)
            .map(|(p, d)| [p[0] + w * d[0], p[1] + w * d[1], p[2] + w * d[2]])
            .collect::<Vec<_>>()
    };
    let tilted = |w: f32| vec![Vec3::new(w, 0.0, 1.0).normalize().to_array(); 3];
    let full = plain(
        dir.path(),
        "full.gltf",
        &shifted(1.0),
        &tilted(1.0),
        node.clone(),
    );
    assert_same(&morphed(dir.path(), "weight-1.gltf", 1.0, None), &full);
    // The node's weights override the mesh's.
    let half = plain(
        dir.path(),
        "half.gltf",
        &shifted(0.5),
        &tilted(0.5),
        node.clone(),
    );
    assert_same(
        &morphed(dir.path(), "node-half.gltf", 1.0, Some(0.5)),
        &half,
    );
    // Weight 0 is the base shape: the morph must be what moved the vertices above.
    let base = plain(dir.path(), "base.gltf", &TRIANGLE, &NORMALS, node);
    assert_same(&morphed(dir.path(), "weight-0.gltf", 0.0, None), &base);
    assert!((full[0].0 - base[0].0).length() > 1.0);
}

/// A triangle skinned to two joints: vertex 0 follows joint 0, vertex 1 joint 1, vertex 2
/// half of each. Joint 1 is bound at (0, 1, 0) and posed rotated 90 degrees about z and
/// moved to (0, 3, 0); the skinned node's own transform must be ignored.
#[test]
fn a_skinned_mesh_follows_its_posed_joints() {
    let dir = tempfile::tempdir().unwrap();
    let root = Affine3A::from_translation(Vec3::new(0.0, 0.0, 1.0));
    let bind1 = root * Affine3A::from_translation(Vec3::new(0.0, 1.0, 0.0));
    let posed_local = Affine3A::from_rotation_translation(
        Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
        Vec3::new(0.0, 3.0, 0.0),
    );
    let posed1 = root * posed_local;
    let joints = [root * root.inverse(), posed1 * bind1.inverse()];
    let mut doc = GltfDoc::default();
    let p = doc.positions(&TRIANGLE);
    let n = doc.floats(&NORMALS, "VEC3");
    let joint_indices = doc.push(
        [[0u8, 0, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]].concat(),
        None,
        json!({"componentType": 5121, "count": 3, "type": "VEC4"}),
    );
    let weights = doc.floats(
        &[
            [1.0, 0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0],
            [0.5, 0.5, 0.0, 0.0],
        ],
        "VEC4",
    );
    let ibm = doc.floats(
        &[
            Mat4::from(root).inverse().to_cols_array(),
            Mat4::from(bind1).inverse().to_cols_array(),
        ],
        "MAT4",
    );
    let skinned = vertices(
        dir.path(),
        "skinned.gltf",
        doc,
        json!({
            "scenes": [{"nodes": [0, 1]}],
            "nodes": [
                {"mesh": 0, "skin": 0, "translation": [100.0, 0.0, 0.0]},
                {"translation": [0.0, 0.0, 1.0], "children": [2]},
                {"translation": [0.0, 3.0, 0.0],
                 "rotation": Quat::from_rotation_z(std::f32::consts::FRAC_PI_2).to_array()},
            ],
            "skins": [{"joints": [1, 2], "inverseBindMatrices": ibm}],
            "meshes": [{"primitives": [{"attributes": {
                "POSITION": p, "NORMAL": n, "JOINTS_0": joint_indices, "WEIGHTS_0": weights}}]}],
        }),
    );
    let blend = |a: &Affine3A, b: &Affine3A, w: f32| {
        Affine3A::from_mat4(Mat4::from(*a) * (1.0 - w) + Mat4::from(*b) * w)
    };
    let per_vertex = [joints[0], joints[1], blend(&joints[0], &joints[1], 0.5)];
    let expected: Vec<[f32; 3]> = TRIANGLE
        .iter()
        .zip(&per_vertex)
        .map(|(p, m)| m.transform_point3(Vec3::from(*p)).to_array())
        .collect();
    let expected_normals: Vec<[f32; 3]> = per_vertex
        .iter()
        .map(|m| {
            m.matrix3
                .inverse()
                .transpose()
                .mul_vec3(Vec3::Z)
                .normalize()
                .to_array()
        })
        .collect();
    let twin = plain(
        dir.path(),
        "twin.gltf",
        &expected,
        &expected_normals,
        json!({}),
    );
    assert_same(&skinned, &twin);
    // The pose moved vertex 1 (bound at (1, 0, 0), it follows joint 1 to (1, 4, 0)).
    assert!(
        (Vec3::from(expected[1]) - Vec3::new(1.0, 4.0, 0.0)).length() < 1e-5,
        "{:?}",
        expected[1]
    );
}

/// Khronos' SimpleMorph sample (CC0, `tests/data/khronos`): the triangle in the pose of the
/// mesh's default weights 0.5 and 0.5, the base (0.5, 0.5, 0) apex moved by half of each
/// target's (-1, 1, 0) and (1, 1, 0) to (0.5, 1.5, 0).
#[test]
fn khronos_simple_morph_loads_in_its_default_weights() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/khronos/SimpleMorph.gltf");
    let scene = import_model(&path, UpAxis::Z).unwrap_or_else(|e| panic!("loads: {e}"));
    let got: Vec<Vec3> = world_vertices(&scene).into_iter().map(|(p, _)| p).collect();
    let want = [Vec3::ZERO, Vec3::X, Vec3::new(0.5, 1.5, 0.0)];
    assert_eq!(got, want, "{:?}", scene.warnings);
    // Its animation (of the weights) is kept for playback, without a warning.
    assert!(scene.is_animated());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}
