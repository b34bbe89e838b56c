//! Permissive import of real-world glTF and OBJ files: what the glTF specification allows
//! loads; one bad element (primitive, image, face) is skipped with one warning naming the file,
//! the element and the reason; each ignored feature is named once per file; triangle strips and
//! fans give the same triangles as the list; spec-gloss materials convert to metal-rough; MTL as
//! MeshLab writes it (`Tr 1`) stays opaque. Every file is written by the test.

use crate::common::GltfDoc;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use wavetrace::math::{Rgb, Vec3};
use wavetrace::scene::load::{UpAxis, import_model};
use wavetrace::scene::{Material, MaterialTextures, Mesh, Name};

/// The unit square in z = 0 as four vertices: (0,0), (1,0), (0,1), (1,1).
const SQUARE: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [1.0, 1.0, 0.0],
];

/// One node with one mesh of the given primitives.
fn one_mesh(primitives: Value) -> Value {
    json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "n", "mesh": 0}],
        "meshes": [{"name": "m", "primitives": primitives}],
    })
}

/// Every mesh's triangles with their file-space vertices.
fn triangles(scene: &wavetrace::Scene) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for mesh in scene.world.query::<&Mesh>().iter() {
        for t in &mesh.indices {
            out.push(t.map(|i| mesh.positions[i as usize]));
        }
    }
    out
}

/// Sum of the triangles' vector areas: the projected area with its orientation.
fn vector_area(tris: &[[Vec3; 3]]) -> Vec3 {
    tris.iter()
        .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a))
        .sum()
}

fn bounds(tris: &[[Vec3; 3]]) -> (Vec3, Vec3) {
    let points = tris.iter().flatten();
    (
        points.clone().fold(Vec3::INFINITY, |a, &b| a.min(b)),
        points.fold(Vec3::NEG_INFINITY, |a, &b| a.max(b)),
    )
}

fn load(path: &Path) -> wavetrace::Scene {
    import_model(path, UpAxis::Z).unwrap_or_else(|e| panic!("{} should load: {e}", path.display()))
}

/// The warnings with the directory of the files removed from their paths.
fn local_warnings(scene: &wavetrace::Scene, dir: &Path) -> Vec<String> {
    let prefix = format!("{}/", dir.display());
    scene
        .warnings
        .iter()
        .map(|w| w.replace(&prefix, ""))
        .collect()
}

fn warnings_with(scene: &wavetrace::Scene, text: &str) -> usize {
    scene.warnings.iter().filter(|w| w.contains(text)).count()
}

#[test]
fn strips_and_fans_give_the_triangles_of_the_list() {
    let dir = tempfile::tempdir().unwrap();
    let mut shapes = Vec::new();
    for (name, mode, indices) in [
        ("list", 4, &[0u16, 1, 3, 0, 3, 2][..]),
        ("strip", 5, &[0, 1, 2, 3][..]),
        ("fan", 6, &[0, 1, 3, 2][..]),
    ] {
        let mut doc = GltfDoc::default();
        let p = doc.positions(&SQUARE);
        let i = doc.indices(indices);
        let path = doc.write(
            dir.path(),
            &format!("{name}.gltf"),
            one_mesh(json!([{"attributes": {"POSITION": p}, "indices": i, "mode": mode}])),
        );
        let scene = load(&path);
        assert!(scene.warnings.is_empty(), "{name}: {:?}", scene.warnings);
        shapes.push((name, triangles(&scene)));
    }
    let (_, list) = &shapes[0];
    for (name, tris) in &shapes {
        assert_eq!(tris.len(), list.len(), "{name}");
        assert_eq!(bounds(tris), bounds(list), "{name}");
        // Same orientation and area: every triangle faces +z, the square's area is 1.
        assert!(
            (vector_area(tris) - Vec3::Z).length() < 1e-6,
            "{name}: {}",
            vector_area(tris)
        );
        assert!(
            tris.iter()
                .all(|[a, b, c]| (*b - *a).cross(*c - *a).z > 0.0),
            "{name}: a triangle is flipped"
        );
    }
}

#[test]
fn a_lines_primitive_among_triangles_is_skipped_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE);
    let i = doc.indices(&[0, 1, 3, 0, 3, 2]);
    let lines = doc.indices(&[0, 1, 1, 3]);
    let path = doc.write(
        dir.path(),
        "wires.gltf",
        one_mesh(json!([
            {"attributes": {"POSITION": p}, "indices": lines, "mode": 1},
            {"attributes": {"POSITION": p}, "indices": i},
            {"attributes": {"POSITION": p}, "mode": 0},
        ])),
    );
    let scene = load(&path);
    assert_eq!(triangles(&scene).len(), 2);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains("wires.gltf")
            && scene.warnings[0].contains("points and lines are not rendered (2 primitives"),
        "{}",
        scene.warnings[0]
    );

    // Only lines: nothing renderable is left, which is an error.
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE);
    let path = doc.write(
        dir.path(),
        "only-lines.gltf",
        one_mesh(json!([{"attributes": {"POSITION": p}, "mode": 3}])),
    );
    let e = import_model(&path, UpAxis::Z)
        .err()
        .expect("an error")
        .to_string();
    assert!(
        e.contains("only-lines.gltf") && e.contains("nothing renderable"),
        "{e}"
    );
}

#[test]
fn valid_files_the_strict_reader_refused_load() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE[..3]);
    let pressure = doc.floats(&[[0.0, 0.0]; 3], "VEC2");
    let mut gltf = one_mesh(json!([{"attributes": {"POSITION": p, "_PRESSURE": pressure}}]));
    // A second scene without nodes; an animation whose channel has no node
    // (KHR_animation_pointer).
    gltf["scenes"] = json!([{"nodes": [0]}, {"name": "empty"}]);
    gltf["scene"] = json!(0);
    gltf["extensionsUsed"] = json!(["KHR_animation_pointer"]);
    gltf["animations"] = json!([{
        "channels": [{"sampler": 0, "target": {"path": "pointer",
            "extensions": {"KHR_animation_pointer": {"pointer": "/nodes/0/translation"}}}}],
        "samplers": [{"input": pressure, "output": pressure}],
    }]);
    let path = doc.write(dir.path(), "pressure.gltf", gltf);
    let scene = load(&path);
    assert_eq!(triangles(&scene).len(), 1);
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert_eq!(
        warnings_with(
            &scene,
            "application-specific vertex attributes are ignored (_PRESSURE)"
        ),
        1
    );
    // The pointer channel plays like a translation channel, but its input is not scalar.
    assert_eq!(
        warnings_with(&scene, "channel 0: input accessor 1 is not SCALAR"),
        1
    );

    // The only scene has no nodes: an empty model, not an error.
    let mut doc = GltfDoc::default();
    doc.positions(&SQUARE);
    let path = doc.write(dir.path(), "no-nodes.gltf", json!({"scenes": [{}]}));
    let scene = load(&path);
    assert!(triangles(&scene).is_empty());

    // No scenes at all (glTF-Blender-IO's roundtrip file `00_no_scenes`): the root nodes are
    // rendered, as Blender imports them, with one warning; a child is drawn once, under its
    // parent's transform.
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE[..3]);
    let mut gltf = one_mesh(json!([{"attributes": {"POSITION": p}}]));
    gltf.as_object_mut().unwrap().remove("scenes");
    gltf["nodes"] = json!([
        {"name": "root", "mesh": 0, "children": [1]},
        {"name": "child", "mesh": 0, "translation": [0.0, 0.0, 5.0]},
        {"name": "other root", "mesh": 0, "translation": [0.0, 0.0, -5.0]},
    ]);
    let path = doc.write(dir.path(), "no-scenes.gltf", gltf);
    let scene = load(&path);
    let tris = triangles_in_world(&scene);
    let mut heights: Vec<f32> = tris.iter().map(|t| t[0].z).collect();
    heights.sort_by(f32::total_cmp);
    assert_eq!(heights, [-5.0, 0.0, 5.0]);
    assert_eq!(
        local_warnings(&scene, dir.path()),
        ["no-scenes.gltf: the file has no scene; its 2 root nodes are rendered"]
    );

    // Neither scenes nor nodes: an error that says so.
    let mut doc = GltfDoc::default();
    doc.positions(&SQUARE);
    let path = doc.write(dir.path(), "library.gltf", json!({}));
    let error = import_model(&path, UpAxis::Z)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        error.contains("library.gltf") && error.contains("no scene and no nodes"),
        "{error}"
    );
}

/// Every mesh's triangles (shared or not) placed by its entity's transform.
fn triangles_in_world(scene: &wavetrace::Scene) -> Vec<[Vec3; 3]> {
    use wavetrace::scene::{SharedMesh, Transform, mesh_of};
    let mut out = Vec::new();
    for (mesh, shared, transform) in scene
        .world
        .query::<(Option<&Mesh>, Option<&SharedMesh>, &Transform)>()
        .iter()
    {
        let Some(mesh) = mesh_of(mesh, shared) else {
            continue;
        };
        for t in &mesh.indices {
            out.push(t.map(|i| transform.0.transform_point3(mesh.positions[i as usize])));
        }
    }
    out
}

/// A textured triangle whose base colour image is `uri` (with `extra` merged into the texture).
fn textured(dir: &Path, name: &str, images: Value, texture: Value, required: &[&str]) -> PathBuf {
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE[..3]);
    let uv = doc.floats(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "VEC2");
    let mut gltf = one_mesh(json!([{"attributes": {"POSITION": p, "TEXCOORD_0": uv},
        "material": 0}]));
    gltf["materials"] = json!([{"name": "painted",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
    gltf["images"] = images;
    gltf["textures"] = json!([texture]);
    if !required.is_empty() {
        gltf["extensionsUsed"] = json!(required);
        gltf["extensionsRequired"] = json!(required);
    }
    doc.write(dir, name, gltf)
}

fn base_colour_texture_mean(scene: &wavetrace::Scene) -> Option<Rgb> {
    let mut query = scene.world.query::<&MaterialTextures>();
    let textures = query.iter().next()?;
    textures.base_color.as_ref().map(|s| s.texture.mean())
}

#[test]
fn missing_and_undecodable_textures_are_skipped_with_a_warning_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = textured(
        dir.path(),
        "missing.gltf",
        json!([{"uri": "nowhere.png"}]),
        json!({"source": 0}),
        &[],
    );
    let scene = load(&path);
    assert_eq!(
        triangles(&scene).len(),
        1,
        "the material renders without it"
    );
    assert_eq!(base_colour_texture_mean(&scene), None);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let w = &scene.warnings[0];
    assert!(
        w.contains("missing.gltf")
            && w.contains("image 0 ('nowhere.png')")
            && w.contains("material 'painted'"),
        "{w}"
    );

    // A KTX2 image with a PNG fallback: the PNG is used; without one, a warning names KTX2.
    let ktx2 = [b"\xABKTX 20\xBB\r\n\x1A\n".as_slice(), &[0; 64]].concat();
    std::fs::write(dir.path().join("t.ktx2"), ktx2).unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([255, 0, 0]))
        .save(dir.path().join("t.png"))
        .unwrap();
    let path = textured(
        dir.path(),
        "fallback.gltf",
        json!([{"uri": "t.ktx2"}, {"uri": "t.png"}]),
        json!({"source": 1, "extensions": {"KHR_texture_basisu": {"source": 0}}}),
        &[],
    );
    let scene = load(&path);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let mean = base_colour_texture_mean(&scene).expect("the PNG fallback");
    assert!(
        (mean - Rgb::new(1.0, 0.0, 0.0)).abs().max_element() < 1e-6,
        "{mean}"
    );
    let path = textured(
        dir.path(),
        "basisu.gltf",
        json!([{"uri": "t.ktx2"}]),
        json!({"extensions": {"KHR_texture_basisu": {"source": 0}}}),
        &["KHR_texture_basisu"],
    );
    let scene = load(&path);
    assert_eq!(base_colour_texture_mean(&scene), None);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("KTX2"), "{}", scene.warnings[0]);
}

#[test]
fn webp_textures_decode() {
    let dir = tempfile::tempdir().unwrap();
    let texel = [40u8, 120, 200];
    let image = image::RgbImage::from_pixel(4, 4, image::Rgb(texel));
    image.save(dir.path().join("t.webp")).unwrap();
    image::RgbImage::from_pixel(4, 4, image::Rgb([0, 0, 0]))
        .save(dir.path().join("t.png"))
        .unwrap();
    let path = textured(
        dir.path(),
        "webp.gltf",
        json!([{"uri": "t.png"}, {"uri": "t.webp"}]),
        json!({"source": 0, "extensions": {"EXT_texture_webp": {"source": 1}}}),
        &["EXT_texture_webp"],
    );
    let scene = load(&path);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let mean = base_colour_texture_mean(&scene).expect("decoded");
    // Lossless WebP: the texel comes back exactly (sRGB-decoded).
    let srgb = |c: u8| {
        let c = c as f32 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let expected = Rgb::new(srgb(texel[0]), srgb(texel[1]), srgb(texel[2]));
    assert!(
        (mean - expected).abs().max_element() < 1e-4,
        "{mean} vs {expected}"
    );
}

fn material_of(scene: &wavetrace::Scene, name: &str) -> Material {
    for (n, m) in scene.world.query::<(&Name, &Material)>().iter() {
        if n.0 == name {
            return *m;
        }
    }
    panic!("no object {name}")
}

#[test]
fn spec_gloss_converts_and_required_fallback_extensions_load() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE[..3]);
    let mut gltf = json!({
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [{"name": "gold", "mesh": 0}, {"name": "paint", "mesh": 1},
                  {"name": "flat", "mesh": 2}, {"name": "plain", "mesh": 3}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": p}, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": p}, "material": 1}]},
            {"primitives": [{"attributes": {"POSITION": p}, "material": 2}]},
            {"primitives": [{"attributes": {"POSITION": p}}]},
        ],
        "materials": [
            {"name": "gold", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                "diffuseFactor": [0, 0, 0, 1], "specularFactor": [1.0, 0.766, 0.336],
                "glossinessFactor": 0.8}}},
            {"name": "paint", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                "diffuseFactor": [0.5, 0.2, 0.1, 1], "specularFactor": [0.04, 0.04, 0.04],
                "glossinessFactor": 0.25}}},
            {"name": "flat", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1]},
             "extensions": {"KHR_materials_unlit": {}}},
        ],
    });
    let required = [
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_materials_unlit",
        "KHR_materials_variants",
    ];
    gltf["extensionsUsed"] = json!(required);
    gltf["extensionsRequired"] = json!(required);
    gltf["meshes"][2]["primitives"][0]["extensions"] =
        json!({"KHR_materials_variants": {"mappings": [{"material": 0, "variants": [0]}]}});
    let path = doc.write(dir.path(), "specgloss.gltf", gltf);
    let scene = load(&path);
    let Material::MetallicRoughness {
        base_color,
        metallic,
        roughness,
        ..
    } = material_of(&scene, "gold")
    else {
        panic!("gold")
    };
    // A black diffuse is a pure metal: its base colour is the specular colour.
    assert!(
        (base_color - Rgb::new(1.0, 0.766, 0.336))
            .abs()
            .max_element()
            < 1e-5,
        "{base_color}"
    );
    assert!((metallic - 1.0).abs() < 1e-5, "{metallic}");
    assert!((roughness - 0.2).abs() < 1e-6);
    // Specular 0.04 is glTF's dielectric: the diffuse colour is the base colour, exactly.
    let Material::MetallicRoughness {
        base_color,
        metallic,
        roughness,
        ..
    } = material_of(&scene, "paint")
    else {
        panic!("paint")
    };
    assert!(
        (base_color - Rgb::new(0.5, 0.2, 0.1)).abs().max_element() < 1e-6,
        "{base_color}"
    );
    assert_eq!(metallic, 0.0);
    assert_eq!(roughness, 0.75);
    // Unlit: its base colour shown as it is (see tests/e2e/unlit.rs), without a warning;
    // variants: the default material.
    assert_eq!(
        material_of(&scene, "flat"),
        Material::Unlit {
            color: Rgb::new(0.2, 0.4, 0.6)
        }
    );
    assert_eq!(
        warnings_with(&scene, "KHR_materials_variants is ignored"),
        1
    );
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    // No material: Blender's grey dielectric, not glTF's white metal.
    assert_eq!(
        material_of(&scene, "plain"),
        Material::MetallicRoughness {
            base_color: Rgb::splat(0.8),
            metallic: 0.0,
            roughness: 0.5,
            specular: 1.0,
            specular_color: Rgb::ONE,
            ior: 1.5,
            transmission: 0.0,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Rgb::ZERO,
            sheen_roughness: 0.0,
        }
    );
}

#[test]
fn each_ignored_feature_is_named_once_per_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut doc = GltfDoc::default();
    let p = doc.positions(&SQUARE[..3]);
    let colours = doc.positions(&[[1.0, 0.0, 0.0]; 3]);
    let mut primitives = Vec::new();
    let mut materials = Vec::new();
    for k in 0..3 {
        primitives.push(json!({"attributes": {"POSITION": p, "COLOR_0": colours},
            "material": k}));
        materials.push(json!({"name": format!("m{k}"), "alphaMode": "BLEND",
            "occlusionTexture": {"index": 0},
            "extensions": {"KHR_materials_volume": {"thicknessFactor": 1,
                "thicknessTexture": {"index": 0}}}}));
    }
    let mut gltf = one_mesh(json!(primitives));
    gltf["materials"] = json!(materials);
    gltf["images"] = json!([{"uri": "ao.png"}]);
    gltf["textures"] = json!([{"source": 0}]);
    gltf["extensionsUsed"] = json!(["KHR_materials_volume", "EXT_lights_ies"]);
    let path = doc.write(dir.path(), "features.gltf", gltf);
    let scene = load(&path);
    let warnings = local_warnings(&scene, dir.path());
    for expected in [
        "features.gltf: occlusion maps are ignored (3 materials)",
        "features.gltf: KHR_materials_volume thicknessTexture is ignored: the path tracer \
         measures the distance travelled inside the object (3 materials)",
        "features.gltf: the extension EXT_lights_ies is not supported; ignored",
    ] {
        assert_eq!(
            warnings.iter().filter(|w| *w == expected).count(),
            1,
            "{expected}\n{warnings:?}"
        );
    }
    assert_eq!(scene.warnings.len(), 3, "{:?}", scene.warnings);
}

// ---------------------------------------------------------------------------------------
// OBJ.

fn obj(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn twisted_and_non_planar_polygons_are_triangulated_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    // A good triangle, two bow-tie quads (twisted), a non-planar pentagon.
    let text = "v 0 0 0\nv 2 2 0\nv 2 0 0\nv 0 2 0\n\
                v 0 0 1\nv 1 0 1.2\nv 1.3 1 0.4\nv 0.5 1.6 1.5\nv -0.3 1 0.2\n\
                f 1 3 2\nf 1 2 3 4\nf 1 2 3 4\nf 5 6 7 8 9\n";
    let path = obj(dir.path(), "scan.obj", text);
    let scene = load(&path);
    assert_eq!(triangles(&scene).len(), 1 + 2 + 2 + 3);
    let fan = scene
        .warnings
        .iter()
        .filter(|w| w.contains("triangulated as a fan"))
        .collect::<Vec<_>>();
    assert_eq!(fan.len(), 1, "{:?}", scene.warnings);
    assert!(
        fan[0].contains("scan.obj") && fan[0].contains("first, line 11"),
        "{}",
        fan[0]
    );
    assert!(scene.warnings.len() <= 1, "{:?}", scene.warnings);
}

#[test]
fn lines_short_faces_continuations_and_usemtl_without_library() {
    let dir = tempfile::tempdir().unwrap();
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nusemtl paint\n\
                f 1 2 \\\n  3\nl 1 2 3\nl 2 4\nf 2 4\n";
    let path = obj(dir.path(), "wires.obj", text);
    let scene = load(&path);
    // `l 1 2 3` is a polyline, not a triangle: the only triangle is the continued face.
    let tris = triangles(&scene);
    assert_eq!(tris.len(), 1);
    assert_eq!(
        tris[0],
        [Vec3::ZERO, Vec3::X, Vec3::Y],
        "the continued face reads 1 2 3"
    );
    let expected = [
        "wires.obj: line elements (l) are not rendered (2, first at line 8)",
        "wires.obj: faces with fewer than 3 vertices are skipped (1, first at line 10)",
        "wires.obj: line 5: usemtl names a material but the file loads no material library \
         (mtllib); using a default grey",
    ];
    assert_eq!(local_warnings(&scene, dir.path()), expected);
}

#[test]
fn mtl_as_meshlab_writes_it_and_texture_names_with_spaces() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([0, 255, 0]))
        .save(dir.path().join("fuze uv.png"))
        .unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl meshlab\nKa 0.2 0.2 0.2\nKd 0.6 0.5 0.4\nKs 0 0 0\nTr 1\nillum 2\nNs 0\n\
         newmtl textured\nKd 1 1 1\nmap_Kd -o 0 0 fuze uv.png\n\
         newmtl ambiguous\nKd 0.5 0.5 0.5\nTr 0.5\n\
         newmtl glass\nKd 1 1 1\nd 0.3\nillum 4\nNi 1.4\n",
    )
    .unwrap();
    let mut text =
        String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n");
    for m in ["meshlab", "textured", "ambiguous", "glass"] {
        text += &format!("o {m}\nusemtl {m}\nf 1/1 2/2 3/3\n");
    }
    let path = obj(dir.path(), "m.obj", &text);
    let scene = load(&path);
    // `Tr 1` with `illum 2` is opaque (Blender ignores Tr): the diffuse colour, no glass.
    assert!(matches!(material_of(&scene, "meshlab"),
        Material::MetallicRoughness { base_color, transmission, .. }
            if base_color == Rgb::new(0.6, 0.5, 0.4) && transmission == 0.0));
    assert!(matches!(
        material_of(&scene, "ambiguous"),
        Material::MetallicRoughness { .. }
    ));
    assert!(matches!(material_of(&scene, "glass"),
        Material::Dielectric { ior, .. } if ior == 1.4));
    let mut textured = None;
    for (n, t) in scene.world.query::<(&Name, &MaterialTextures)>().iter() {
        if n.0 == "textured" {
            textured = t.base_color.as_ref().map(|s| s.texture.mean());
        }
    }
    let mean = textured.expect("'fuze uv.png' is loaded");
    assert!((mean - Rgb::new(0.0, 1.0, 0.0)).abs().max_element() < 1e-6);
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert_eq!(
        warnings_with(&scene, "material 'ambiguous': Tr 0.5 is ignored"),
        1
    );
    assert_eq!(warnings_with(&scene, "map_Kd options -o are ignored"), 1);
}
