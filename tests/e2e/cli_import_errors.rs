//! Runs the `wavetrace` binary on broken glTF and OBJ files made here, in a temporary
//! directory, both as the scene itself and placed by a `[[model]]` table of a TOML scene:
//! every error case must end with exit code 1, one `error:` line on stderr that names the file,
//! the place in it (glTF buffer, view, accessor, mesh or node; OBJ line) and the problem, no
//! panic, and no output file. The warning cases (degenerate triangles, zero-area emitters, a
//! missing `.mtl`) must render, say so on stderr, and write an image without NaN.

use crate::common::{check_failure, files_in, glb};

use serde_json::{Value, json};
use std::path::Path;
use std::process::{Command, Output};

fn wavetrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wavetrace"))
}

/// Renders `scene` (tiny, one sample) into `output`.
fn render(scene: &Path, output: &Path) -> Output {
    wavetrace()
        .args([
            "render", "-q", "--width", "4", "--height", "4", "--spp", "1",
        ])
        .arg(scene)
        .arg("-o")
        .arg(output)
        .output()
        .expect("the binary runs")
}

// ---------------------------------------------------------------------------------------
// glTF files made here: one triangle mesh 'Wedge' on node 'Thing', buffer in `NAME.bin`.

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// A glTF document with one indexed mesh and its binary buffer (positions, then u16 indices),
/// the buffer stored in the file `bin_name`.
fn gltf_doc(positions: &[[f32; 3]], indices: &[u16], bin_name: &str) -> (Value, Vec<u8>) {
    let mut bin: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let positions_length = bin.len();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    // glTF requires POSITION's min and max (f32::min/max skip NaN)
    let bound = |pick: fn(f32, f32) -> f32| -> Vec<f32> {
        (0..3)
            .map(|k| positions.iter().map(|p| p[k]).reduce(pick).unwrap())
            .collect()
    };
    let doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "Thing", "mesh": 0}],
        "meshes": [{"name": "Wedge", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": positions.len(), "type": "VEC3",
             "min": bound(f32::min), "max": bound(f32::max)},
            {"bufferView": 1, "componentType": 5123, "count": indices.len(), "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions_length},
            {"buffer": 0, "byteOffset": positions_length, "byteLength": 2 * indices.len()}
        ],
        "buffers": [{"byteLength": bin.len(), "uri": bin_name}]
    });
    (doc, bin)
}

/// Adds an emissive material to the mesh and a perspective camera node 'Cam' (index 1), so
/// that the file renders as it is (not in the room) from its own camera.
fn lit_with_camera(doc: &mut Value, yfov: f32) {
    doc["materials"] = json!([{"name": "Lamp", "emissiveFactor": [1.0, 1.0, 1.0]}]);
    doc["meshes"][0]["primitives"][0]["material"] = json!(0);
    doc["cameras"] = json!([{"type": "perspective", "perspective": {"yfov": yfov, "znear": 0.1}}]);
    doc["nodes"]
        .as_array_mut()
        .unwrap()
        .push(json!({"name": "Cam", "camera": 0, "translation": [0.3, 0.3, 3.0]}));
    doc["scenes"][0]["nodes"] = json!([0, 1]);
}

/// A file to write: name and bytes.
type File = (String, Vec<u8>);

/// A broken input: the files to write (the first is rendered) and what stderr must say.
struct Case {
    files: Vec<File>,
    expect: Vec<&'static str>,
}

fn gltf_files(name: &str, doc: &Value, bin: &[u8]) -> Vec<File> {
    vec![
        (name.to_string(), serde_json::to_vec_pretty(doc).unwrap()),
        (
            doc["buffers"][0]["uri"].as_str().unwrap().into(),
            bin.to_vec(),
        ),
    ]
}

fn gltf_cases() -> Vec<Case> {
    let (doc, bin) = gltf_doc(&TRIANGLE, &[0, 1, 2], "wedge.bin");
    let case = |files: Vec<File>, expect: &[&'static str]| Case {
        files,
        expect: expect.to_vec(),
    };
    let edited = |name: &str, edit: &dyn Fn(&mut Value)| {
        let mut doc = doc.clone();
        edit(&mut doc);
        gltf_files(name, &doc, &bin)
    };
    let good_glb = glb(&doc, &bin);
    let text = serde_json::to_string(&doc).unwrap();
    let (nan_doc, nan_bin) = gltf_doc(
        &[[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[0, 1, 2],
        "nan.bin",
    );
    let (mut huge_doc, huge_bin) = gltf_doc(
        &[[-3e38, -3e38, 0.0], [3e38, -3e38, 0.0], [0.0, 3e38, 0.0]],
        &[0, 1, 2],
        "huge.bin",
    );
    lit_with_camera(&mut huge_doc, 0.8);
    vec![
        case(
            vec![(
                "truncated.glb".into(),
                good_glb[..good_glb.len() / 2].to_vec(),
            )],
            &["truncated: the GLB header gives a length of"],
        ),
        case(
            vec![("wrong_magic.glb".into(), [b"gLTF", &good_glb[4..]].concat())],
            &[
                "not a binary glTF file",
                "\"gLTF\" instead of the magic \"glTF\"",
            ],
        ),
        case(
            vec![("bad_json.gltf".into(), text[..text.len() - 30].into())],
            &["line 1, column", "invalid JSON: EOF while parsing"],
        ),
        case(
            vec![(
                "nan_matrix.gltf".into(),
                text.replace(
                    "\"name\":\"Thing\"",
                    "\"name\":\"Thing\",\"matrix\":[NaN,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1]",
                )
                .into(),
            )],
            &[
                "line 1, column",
                "invalid JSON: a number is not finite (JSON has no NaN or infinity)",
            ],
        ),
        case(
            edited("overflowing_matrix.gltf", &|d| {
                d["nodes"][0]["matrix"] =
                    json!([1e39, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]);
            }),
            &["node 'Thing' (index 0)", "the transform is not finite"],
        ),
        case(
            vec![
                edited("missing_bin.gltf", &|d| {
                    d["buffers"][0]["uri"] = json!("gone.bin")
                })[0]
                    .clone(),
            ], // only the .gltf is written
            &["buffer 0", "cannot load", "gone.bin", "No such file"],
        ),
        case(
            vec![
                gltf_files("short_bin.gltf", &doc, &bin)[0].clone(),
                ("wedge.bin".into(), bin[..10].to_vec()),
            ],
            &[
                "buffer 0",
                "wedge.bin",
                "holds 10 bytes, less than the buffer's byteLength 44",
            ],
        ),
        case(
            edited("short_buffer.gltf", &|d| {
                d["buffers"][0]["byteLength"] = json!(30)
            }),
            &[
                "buffer view 0",
                "bytes 0..36 lie outside buffer 0 (30 bytes)",
            ],
        ),
        case(
            edited("accessor_overrun.gltf", &|d| {
                d["accessors"][0]["count"] = json!(100)
            }),
            &[
                "accessor 0 (POSITION of mesh 'Wedge', primitive 0)",
                "100 elements of 12 bytes (stride 12) from offset 0 run past the end of buffer \
                 view 0 (36 bytes)",
            ],
        ),
        case(
            edited("accessor_missing.gltf", &|d| {
                d["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7)
            }),
            &[
                "nothing renderable is left",
                "mesh 'Wedge' (index 0), primitive 0",
                "accessor 7 does not exist (the file has 2)",
            ],
        ),
        case(
            gltf_files(
                "index_range.gltf",
                &gltf_doc(&TRIANGLE, &[0, 1, 5], "i.bin").0,
                &{ gltf_doc(&TRIANGLE, &[0, 1, 5], "i.bin").1 },
            ),
            &[
                "mesh 'Wedge'",
                "triangle 0: vertex index 5 out of range (3 vertices)",
            ],
        ),
        case(
            edited("required_extension.gltf", &|d| {
                d["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                d["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            }),
            &[
                "the geometry is compressed with Draco (KHR_draco_mesh_compression), which \
                 wavetrace cannot decode; re-export",
            ],
        ),
        case(
            gltf_files("nan_position.gltf", &nan_doc, &nan_bin),
            &["mesh 'Wedge'", "vertex 1 is not finite"],
        ),
        case(
            edited("zero_yfov.gltf", &|d| lit_with_camera(d, 0.0)),
            &[
                "node 'Cam' (index 1)",
                "yfov must lie in (0, pi) radians, got 0",
            ],
        ),
        case(
            edited("negative_yfov.gltf", &|d| lit_with_camera(d, -0.5)),
            &[
                "node 'Cam' (index 1)",
                "yfov must lie in (0, pi) radians, got -0.5",
            ],
        ),
        case(
            gltf_files("huge_triangle.gltf", &huge_doc, &huge_bin),
            &[
                "mesh 'Thing'",
                "triangle 0: its area (and normal) overflows f32",
            ],
        ),
    ]
}

// ---------------------------------------------------------------------------------------
// OBJ files made here.

const OBJ_VERTICES: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

fn obj_cases() -> Vec<Case> {
    let case = |name: &str, text: String, expect: &[&'static str]| Case {
        files: vec![(name.to_string(), text.into_bytes())],
        expect: expect.to_vec(),
    };
    vec![
        case(
            "bad_number.obj",
            "v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n".into(),
            &["line 2", "vertex: 'x' is not a number"],
        ),
        case(
            "nan_vertex.obj",
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            &["line 2", "vertex (NaN, 0, 0) is not finite"],
        ),
        case(
            "overflowing_vertex.obj",
            "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n".into(),
            &["line 2", "vertex (inf, 0, 0) is not finite"],
        ),
    ]
}

#[test]
fn broken_models_fail_with_one_clear_message_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let mut failures = Vec::new();
    for (k, case) in gltf_cases().into_iter().chain(obj_cases()).enumerate() {
        // each case in its own folder, as its files share names
        let case_dir = dir.path().join(format!("case{k}"));
        std::fs::create_dir(&case_dir).unwrap();
        for (name, bytes) in &case.files {
            std::fs::write(case_dir.join(name), bytes).unwrap();
        }
        let name = &case.files[0].0;
        // The model as the scene, and placed by a scene file (errors still name the model).
        let scene = case_dir.join("scene.toml");
        std::fs::write(
            &scene,
            format!(
                "include = [\"builtin:room\"]\n[[model]]\nfile = \"{name}\"\nposition = [0, 0, 0]\n"
            ),
        )
        .unwrap();
        for input in [case_dir.join(name), scene] {
            let out = render(&input, &out_dir.join("image.png"));
            // Overflowing triangles are found when flattening the whole scene, which names
            // the scene file and the mesh.
            let named = if input.ends_with("scene.toml") && name == "huge_triangle.gltf" {
                "scene.toml"
            } else {
                name.as_str()
            };
            let mut expect = vec![named];
            expect.extend_from_slice(&case.expect);
            if let Err(problem) = check_failure(&out, 1, &expect) {
                failures.push(format!("{}: {problem}", input.display()));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(files_in(&out_dir).is_empty(), "{:?}", files_in(&out_dir));
}

/// Renders `files[0]` to EXR, expecting success with the warning `warning` on stderr and an
/// image without NaN or infinite pixels.
fn assert_renders_with_warning(files: &[(&str, &str)], warning: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let image = dir.path().join("image.exr");
    let out = render(&dir.path().join(files[0].0), &image);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    let warnings: Vec<&str> = stderr
        .lines()
        .filter(|l| l.starts_with("warning: "))
        .collect();
    assert_eq!(warnings.len(), 1, "{stderr}");
    for fragment in warning {
        assert!(
            warnings[0].contains(fragment),
            "'{fragment}' missing in: {stderr}"
        );
    }
    assert!(!stderr.contains("NaN/infinite samples"), "{stderr}");
    let written = wavetrace::output::read_exr(&image).unwrap();
    assert_eq!(written.pixels.len(), 16);
    assert!(written.pixels.iter().all(|p| p.is_finite()), "{stderr}");
}

/// A face with a bad index is skipped with one warning naming its line and the reason, and
/// the rest of the file renders (the whole file used to be refused).
#[test]
fn faces_with_bad_indices_are_skipped_with_a_warning() {
    let cases: [(&str, &[&str]); 6] = [
        (
            "f 0 1 2",
            &[
                "line 4",
                "vertex index 0 in '0' is invalid (OBJ indices count from 1",
            ],
        ),
        (
            "f 1 2 5",
            &["line 4", "names vertex 5, and the file has 3 vertices"],
        ),
        (
            "f -1 -2 -4",
            &[
                "line 4",
                "relative vertex index -4 in '-4' reaches before the first vertex",
            ],
        ),
        (
            "vt 0 0\nf 1/1 2/1 3/-2147483648",
            &["line 5", "relative texture coordinate index -2147483648"],
        ),
        (
            "f 1 2 three",
            &["line 4", "face: 'three' in 'three' is not an index"],
        ),
        (
            "vt 0 0\nf 1/1/1 2/1/1 3/1/1",
            &["line 5", "normal indices past the file's last are ignored"],
        ),
    ];
    for (face, warning) in cases {
        let text = format!("{OBJ_VERTICES}{face}\nf 1 2 3\n");
        assert_renders_with_warning(&[("faces.obj", &text)], warning);
    }
}

#[test]
fn degenerate_triangles_and_a_missing_mtl_render_with_a_warning() {
    // A bare model with one zero-area triangle (collinear vertices): placed in the room.
    assert_renders_with_warning(
        &[(
            "flat.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\n",
        )],
        &[
            "mesh 'unnamed_object'",
            "skipped 1 degenerate (zero-area) triangles",
        ],
    );
    // A lit file whose emitter has a zero-area triangle besides a good one.
    assert_renders_with_warning(
        &[
            (
                "lamp.obj",
                "mtllib lamp.mtl\no Lamp\nusemtl lamp\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\n\
                 f 1 2 3\nf 1 2 4\n",
            ),
            ("lamp.mtl", "newmtl lamp\nKd 0.5 0.5 0.5\nKe 4 4 4\n"),
        ],
        &[
            "mesh 'Lamp'",
            "skipped 1 degenerate (zero-area) emitting triangles",
        ],
    );
    // A material library that does not exist: the default grey material.
    assert_renders_with_warning(
        &[(
            "nomtl.obj",
            "mtllib nowhere.mtl\nusemtl gone\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )],
        &[
            "nomtl.obj",
            "cannot read material library",
            "nowhere.mtl",
            "default grey",
        ],
    );
}
