//! Running out of memory is bad input: a scene whose render scene would not fit in what the
//! process may take is refused with one clear error and exit code 1, nothing written, where
//! it used to end in an allocation abort (exit 134) with a backtrace.

use crate::common::{GltfDoc, check_failure};
use serde_json::json;
use std::path::Path;
use std::process::Command;

/// Side of the vertex grid of the one mesh's data: 2 x 223^2 = 99,458 triangles.
const SIDE: usize = 224;
/// How many distinct meshes draw that data (distinct meshes, so that nothing is shared):
/// about 10 million triangles, some 4.5 GB of address space to flatten.
const MESHES: usize = 100;

#[test]
fn a_scene_too_large_for_the_address_space_is_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let positions: Vec<[f32; 3]> = (0..SIDE * SIDE)
        .map(|k| [(k % SIDE) as f32, (k / SIDE) as f32, 0.0])
        .collect();
    let position = doc.positions(&positions);
    let indices: Vec<u8> = (0..SIDE - 1)
        .flat_map(|j| (0..SIDE - 1).map(move |i| (j * SIDE + i) as u32))
        .flat_map(|a| {
            [
                a,
                a + 1,
                a + SIDE as u32 + 1,
                a,
                a + SIDE as u32 + 1,
                a + SIDE as u32,
            ]
        })
        .flat_map(u32::to_le_bytes)
        .collect();
    let count = indices.len() / 4;
    let index = doc.push(
        indices,
        None,
        json!({"componentType": 5125, "count": count, "type": "SCALAR"}),
    );
    let primitive = json!({"attributes": {"POSITION": position}, "indices": index});
    let path = doc.write(
        dir.path(),
        "many.gltf",
        json!({
            "scenes": [{"nodes": (0..MESHES).collect::<Vec<_>>()}],
            "nodes": (0..MESHES).map(|m| json!({"mesh": m, "translation": [0.0, 0.0, m as f32]}))
                .collect::<Vec<_>>(),
            "meshes": (0..MESHES).map(|_| json!({"primitives": [primitive]})).collect::<Vec<_>>(),
        }),
    );
    let output = dir.path().join("many.png");
    // 2 GiB of address space: the world (about 0.2 GB of meshes) loads, its render scene
    // cannot be built.
    let out = render_limited(2 << 20, &path, &output);
    if let Err(e) = check_failure(&out, 1, &["many.gltf", "does not fit in memory", "GiB"]) {
        panic!("{e}");
    }
    assert!(!output.exists(), "no image is written");
    // many.gltf and many.bin only: no temporary image either.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

/// An OBJ too large for the memory left is refused with a clear error. 2 million faces over
/// three vertices (16 MB of text) under `ulimit -v` 400 MiB used to end in an allocation
/// abort in the parse (exit 134: tobj's face list of 218 MB); the streaming reader takes
/// 24 MB for them and flattening refuses the render scene. 6 million faces under 64 MiB (the
/// process starts in about 20): the reader's columns (72 MB of triangles) cannot grow, and
/// the loader refuses the file (its size, or a growth of the columns) with the same error,
/// not an abort.
#[test]
fn an_obj_too_large_to_parse_is_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("many-faces.png");
    for (faces, limit_mib, what) in [
        (2_000_000, 400, "its render scene ("),
        (6_000_000, 64, "reading"),
    ] {
        let path = dir.path().join("many-faces.obj");
        let mut text = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        text.push_str(&"f 1 2 3\n".repeat(faces));
        std::fs::write(&path, text).unwrap();
        let out = render_limited(limit_mib << 10, &path, &output);
        let expected = ["many-faces.obj", "does not fit in memory", what];
        if let Err(e) = check_failure(&out, 1, &expected) {
            panic!("{faces} faces, ulimit -v {limit_mib} MiB: {e}");
        }
        assert!(!output.exists(), "no image is written");
    }
}

/// Runs `wavetrace render` on `scene` under an address-space limit of `limit_kib` (`ulimit
/// -v`), writing to `output`.
fn render_limited(limit_kib: u64, scene: &Path, output: &Path) -> std::process::Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {limit_kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_wavetrace"))
        .args([
            "render", "--quiet", "--spp", "1", "--width", "8", "--height", "8", "-o",
        ])
        .arg(output)
        .arg(scene)
        .output()
        .unwrap()
}

/// A glTF whose meshes would not fit once read from their accessors is refused before they
/// are read: 100 meshes of one million triangles each over 4 MB of data (one accessor of
/// byte indices, distinct meshes, so each is read), 2.4 GB to read, under `ulimit -v` 1 GiB.
/// The world alone (1.2 GB of triangles) used to end in an allocation abort.
#[test]
fn a_gltf_too_large_to_read_its_meshes_is_refused_with_a_clear_error() {
    const TRIANGLES: usize = 1_000_000;
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let position = doc.positions(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let indices: Vec<u8> = [0u8, 1, 2].repeat(TRIANGLES);
    let index = doc.push(
        indices,
        None,
        json!({"componentType": 5121, "count": 3 * TRIANGLES, "type": "SCALAR"}),
    );
    let primitive = json!({"attributes": {"POSITION": position}, "indices": index});
    let path = doc.write(
        dir.path(),
        "wide.gltf",
        json!({
            "scenes": [{"nodes": (0..MESHES).collect::<Vec<_>>()}],
            "nodes": (0..MESHES).map(|m| json!({"mesh": m})).collect::<Vec<_>>(),
            "meshes": (0..MESHES).map(|_| json!({"primitives": [primitive]})).collect::<Vec<_>>(),
        }),
    );
    let output = dir.path().join("wide.png");
    let out = render_limited(1 << 20, &path, &output);
    let expected = [
        "wide.gltf",
        "does not fit in memory",
        "reading its meshes (100000000 triangles)",
        "ulimit -v",
    ];
    if let Err(e) = check_failure(&out, 1, &expected) {
        panic!("{e}");
    }
    assert!(!output.exists(), "no image is written");
}

/// A glTF whose buffers, or a GLB whose bytes, would not fit are refused before they are
/// read: a 3 GiB buffer file and a 3 GiB `.glb` (sparse files: nothing is written to disk)
/// under `ulimit -v` 1 GiB, where reading them used to end in an allocation abort.
#[test]
fn a_gltf_with_buffers_too_large_to_read_is_refused_with_a_clear_error() {
    const SIZE: u64 = 3 << 30;
    let dir = tempfile::tempdir().unwrap();
    let sparse = |name: &str| {
        let file = std::fs::File::create(dir.path().join(name)).unwrap();
        file.set_len(SIZE).unwrap();
    };
    sparse("big.bin");
    let doc = json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": SIZE, "uri": "big.bin"}],
        "scenes": [{"nodes": []}],
    });
    let gltf = dir.path().join("big.gltf");
    std::fs::write(&gltf, doc.to_string()).unwrap();
    sparse("big.glb");
    let glb = dir.path().join("big.glb");
    for (scene, what) in [
        (&gltf, "loading its buffers (3221.2 MB)"),
        (&glb, "reading the file (3221.2 MB)"),
    ] {
        let output = dir.path().join("big.png");
        let out = render_limited(1 << 20, scene, &output);
        let name = scene.file_name().unwrap().to_str().unwrap();
        if let Err(e) = check_failure(&out, 1, &[name, "does not fit in memory", what]) {
            panic!("{e}");
        }
        assert!(!output.exists(), "no image is written");
    }
}

/// A texture whose texels would not fit is left out with one warning, and the rest renders:
/// an 8192 x 8192 16-bit grey PNG (128 MB decoded, 1 MB on disk) becomes 1 GiB of linear
/// float texels, more than `ulimit -v` 1 GiB leaves; the OBJ's material renders with its
/// `Kd`. The same image in 8 bits is kept as its bytes (64 MB) and fits.
#[test]
fn a_texture_too_large_to_decode_is_skipped_with_a_warning() {
    const SIDE: u32 = 8192;
    let dir = tempfile::tempdir().unwrap();
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(SIDE, SIDE)
        .save(dir.path().join("huge16.png"))
        .unwrap();
    image::GrayImage::new(SIDE, SIDE)
        .save(dir.path().join("huge8.png"))
        .unwrap();
    for bits in [16, 8] {
        std::fs::write(
            dir.path().join("huge.mtl"),
            format!("newmtl wall\nKd 0.5 0.5 0.5\nmap_Kd huge{bits}.png\n"),
        )
        .unwrap();
        let path = dir.path().join("huge.obj");
        std::fs::write(
            &path,
            "mtllib huge.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl wall\nf 1 2 3\n",
        )
        .unwrap();
        let output = dir.path().join(format!("huge-texture-{bits}.png"));
        let out = render_limited(1 << 20, &path, &output);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stderr}");
        assert!(output.exists(), "the image is written");
        let skipped = [
            "huge16.png",
            "does not fit in memory",
            "decoding its 8192 x 8192 texels",
            "using Kd alone",
        ];
        for expected in skipped {
            assert_eq!(
                stderr.contains(expected),
                bits == 16,
                "'{expected}' with {bits} bits: {stderr}"
            );
        }
    }
}

/// An image whose film and output would not fit is refused before the render starts: the
/// room at 11000 x 11000 (121M pixels, under the pixel limit) under `ulimit -v` 1.5 GB used
/// to end in an allocation abort with a backtrace ("memory allocation of 2904000000 bytes
/// failed", exit 134) when the film was made.
#[test]
fn an_image_too_large_for_the_memory_left_is_refused_with_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("huge.png");
    let room = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/room.toml");
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 1500000 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_wavetrace"))
        .args(["render", "--quiet", "--spp", "1", "--width", "11000"])
        .args(["--height", "11000", "-o"])
        .arg(&output)
        .arg(&room)
        .output()
        .unwrap();
    let expected = ["11000x11000 image", "does not fit in memory", "GiB"];
    if let Err(e) = check_failure(&out, 1, &expected) {
        panic!("{e}");
    }
    assert!(!output.exists(), "no image is written");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
