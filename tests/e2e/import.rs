//! Importing glTF and OBJ: the Blender exports of `assets/blender` give the objects,
//! world-space bounding boxes, materials and camera their README documents; hand-made glTF
//! files (written here) cover the edge cases; bad files give errors that name the file and the
//! problem; the bare-model rule and `[[model]]` place models in the room; punctual lights give
//! their analytic radiance.
//!
//! Axis convention under test: imported files are +Y up and come out +Z up by
//! `(x, y, z) -> (x, -z, y)`, so Blender's exports land back in Blender's own frame, where
//! the README's numbers are given.

use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use wavetrace::internals::Shape;
use wavetrace::math::{Rgb, Vec3};
use wavetrace::scene::load::{
    LightUnits, LoadOptions, ROOM_EYE, ROOM_FLOOR, ROOM_VIEW_FILL, UpAxis, bounding_box,
    has_lights, import_model, load_scene_with,
};
use wavetrace::scene::{Camera, Emitter, Material, MaterialTextures, Mesh, Name, Transform};
use wavetrace::{RenderScene, RenderSettings, Scene, flatten, load_scene, render};

fn blender_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/blender")
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// A fresh directory for files a test writes.
pub(crate) fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wavetrace-import-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Per object name: world-space bounding box, material, emitter, triangle count.
struct Object {
    lo: Vec3,
    hi: Vec3,
    material: Material,
    emitter: Option<Emitter>,
    triangles: usize,
    textured: bool,
}

fn objects(scene: &Scene) -> BTreeMap<String, Object> {
    let mut out: BTreeMap<String, Object> = BTreeMap::new();
    for (name, transform, mesh, material, emitter, texture) in scene
        .world
        .query::<(
            &Name,
            &Transform,
            &Mesh,
            &Material,
            Option<&Emitter>,
            Option<&MaterialTextures>,
        )>()
        .iter()
    {
        let world: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|&p| transform.0.transform_point3(p))
            .collect();
        let lo = world.iter().fold(Vec3::INFINITY, |a, &b| a.min(b));
        let hi = world.iter().fold(Vec3::NEG_INFINITY, |a, &b| a.max(b));
        let o = out.entry(name.0.clone()).or_insert(Object {
            lo,
            hi,
            material: *material,
            emitter: emitter.copied(),
            triangles: 0,
            textured: texture.is_some_and(|t| t.base_color.is_some()),
        });
        o.lo = o.lo.min(lo);
        o.hi = o.hi.max(hi);
        o.triangles += mesh.indices.len();
    }
    out
}

fn close(a: Vec3, b: Vec3, tolerance: f32) -> bool {
    (a - b).abs().max_element() <= tolerance
}

fn vec3(v: &Value) -> Vec3 {
    let a: Vec<f32> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect();
    Vec3::new(a[0], a[1], a[2])
}

fn cameras(scene: &Scene) -> Vec<(String, Camera)> {
    scene
        .world
        .query::<(&Camera, Option<&Name>)>()
        .iter()
        .map(|(c, n)| (n.map_or(String::new(), |n| n.0.clone()), *c))
        .collect()
}

#[test]
fn blender_gltf_export_gives_the_documented_scene() {
    let dir = blender_dir();
    let path = dir.join("primitives.glb");
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let objects = objects(&scene);
    let doc: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("primitives.objects.json")).unwrap(),
    )
    .unwrap();
    let mut meshes = 0;
    for o in doc["objects"].as_array().unwrap() {
        let name = o["name"].as_str().unwrap();
        if o["type"] != "MESH" {
            continue;
        }
        meshes += 1;
        let got = objects
            .get(name)
            .unwrap_or_else(|| panic!("object '{name}' missing"));
        let (lo, hi) = (vec3(&o["world_bbox_min"]), vec3(&o["world_bbox_max"]));
        assert!(
            close(got.lo, lo, 1e-4) && close(got.hi, hi, 1e-4),
            "{name}: bbox {}..{} expected {lo}..{hi}",
            got.lo,
            got.hi
        );
        assert_eq!(
            got.triangles,
            o["triangles"].as_u64().unwrap() as usize,
            "{name}"
        );
    }
    assert_eq!(objects.len(), meshes, "no extra objects");

    // Materials: the Principled BSDF inputs of the assets README (specularFactor is twice
    // Blender's Specular IOR Level).
    let principled = |base: [f32; 3], metallic: f32, roughness: f32, ior: f32, level: f32| {
        (Rgb::from(base), metallic, roughness, ior, 2.0 * level)
    };
    let expect = [
        (
            "Ground",
            principled([0.5, 0.5, 0.5], 0.0, 1.0, 1.5, 0.0),
            0.0,
        ),
        ("Cube", principled([0.7, 0.1, 0.1], 0.0, 1.0, 1.5, 0.0), 0.0),
        (
            "Cylinder",
            principled([0.1, 0.6, 0.2], 0.0, 1.0, 1.5, 0.0),
            0.0,
        ),
        (
            "Icosphere",
            principled([0.15, 0.25, 0.8], 0.0, 1.0, 1.5, 0.0),
            0.0,
        ),
        (
            "MirrorBall",
            principled([1.0, 1.0, 1.0], 1.0, 0.0, 1.5, 0.5),
            0.0,
        ),
        (
            "GlassBall",
            principled([1.0, 1.0, 1.0], 0.0, 0.0, 1.45, 0.5),
            1.0,
        ),
        (
            "LightPanel",
            principled([0.0, 0.0, 0.0], 0.0, 1.0, 1.5, 0.0),
            0.0,
        ),
    ];
    for (name, (base, metal, rough, eta, spec), transmitted) in expect {
        match objects[name].material {
            Material::MetallicRoughness {
                base_color,
                metallic,
                roughness,
                specular,
                specular_color,
                ior,
                transmission,
                ..
            } => assert!(
                close(base_color, base, 1e-6)
                    && (metallic, roughness, specular, transmission)
                        == (metal, rough, spec, transmitted)
                    && (ior - eta).abs() < 1e-6
                    && specular_color == Rgb::ONE,
                "{name}: {:?}",
                objects[name].material
            ),
            other => panic!("{name} is {other:?}"),
        }
        assert_eq!(
            objects[name].emitter.is_some(),
            name == "LightPanel",
            "{name}"
        );
    }
    let panel = objects["LightPanel"].emitter.unwrap();
    assert_eq!(panel.radiance, Rgb::splat(10.0));
    assert!(
        !panel.two_sided,
        "doubleSided: false emits on the front only"
    );
    // The panel's front faces down (-Z in Blender's frame).
    let flat = flatten(&with_camera(scene_world_clone(&path)), &path).unwrap();
    // Rendered as the README promises: diffuse ones exactly Lambertian, the mirror and the
    // glass exactly the seed's delta materials.
    use wavetrace::internals::Bsdf;
    let mut kinds: Vec<&str> = flat
        .materials()
        .iter()
        .map(|m| match m {
            Bsdf::Lambertian { .. } => "lambertian",
            Bsdf::Mirror { tint } if *tint == Rgb::ONE => "mirror",
            Bsdf::Dielectric { ior, .. } if (ior - 1.45).abs() < 1e-6 => "glass",
            _ => "other",
        })
        .collect();
    kinds.sort();
    kinds.dedup();
    assert_eq!(
        kinds,
        ["glass", "lambertian", "mirror"],
        "{:?}",
        flat.materials()
    );
    let light = &flat.lights().lights[0];
    match light.shape {
        Shape::Triangle(t) => assert!(t.normal_unnormalized().normalize().z < -0.999),
        _ => panic!("panel is a triangle mesh"),
    }

    // The camera: at (0, -8, 3) looking at (0, 0, 0.6), vertical fov = yfov, aspect 4:3.
    let cams = cameras(&scene);
    assert_eq!(cams.len(), 1);
    let (name, cam) = &cams[0];
    assert_eq!(name, "Camera");
    assert!(
        close(cam.eye, Vec3::new(0.0, -8.0, 3.0), 1e-4),
        "{}",
        cam.eye
    );
    let toward = (Vec3::new(0.0, 0.0, 0.6) - cam.eye).normalize();
    assert!(
        close(cam.forward, toward, 1e-4),
        "{} vs {toward}",
        cam.forward
    );
    assert!(cam.up.z > 0.9 && cam.up.dot(cam.forward).abs() < 1e-5);
    assert!((cam.vfov - 0.672_869_86).abs() < 1e-6);
    assert!((cam.aspect_ratio.unwrap() - 4.0 / 3.0).abs() < 1e-6);
}

fn scene_world_clone(path: &Path) -> hecs::World {
    import_model(path, UpAxis::Y).unwrap().world
}

fn with_camera(mut world: hecs::World) -> hecs::World {
    if world.query::<&Camera>().iter().next().is_none() {
        world.spawn((Camera::look_at(
            Vec3::new(0.0, -10.0, 0.0),
            Vec3::ZERO,
            Vec3::Z,
            1.0,
        ),));
    }
    world
}

#[test]
fn blender_obj_export_gives_the_documented_objects() {
    let path = blender_dir().join("cube-cylinder.obj");
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let objects = objects(&scene);
    assert_eq!(objects.keys().collect::<Vec<_>>(), ["Cube", "Cylinder"]);
    let cube = &objects["Cube"];
    assert!(
        close(cube.lo, Vec3::new(-2.683013, 0.316987, 0.0), 1e-4),
        "{}",
        cube.lo
    );
    assert!(
        close(cube.hi, Vec3::new(-1.316987, 1.683013, 1.0), 1e-4),
        "{}",
        cube.hi
    );
    let cylinder = &objects["Cylinder"];
    assert!(
        close(cylinder.lo, Vec3::new(-0.5, 1.5, 0.0), 1e-4),
        "{}",
        cylinder.lo
    );
    assert!(
        close(cylinder.hi, Vec3::new(0.5, 2.5, 1.5), 1e-4),
        "{}",
        cylinder.hi
    );
    // 6 quads; 32 side quads and two 32-gon caps (30 triangles each).
    assert_eq!(cube.triangles, 12);
    assert_eq!(cylinder.triangles, 64 + 60);
    // Kd = base colour, Ns 0 = roughness 1, Ks 0 = no specular layer, Ni = IOR.
    let diffuse = |r: f32, g: f32, b: f32| Material::MetallicRoughness {
        base_color: Rgb::new(r, g, b),
        metallic: 0.0,
        roughness: 1.0,
        specular: 0.0,
        specular_color: Rgb::ZERO,
        ior: 1.5,
        transmission: 0.0,
        clearcoat: 0.0,
        clearcoat_roughness: 0.0,
        sheen_color: Rgb::ZERO,
        sheen_roughness: 0.0,
    };
    assert_eq!(cube.material, diffuse(0.7, 0.1, 0.1));
    assert_eq!(cylinder.material, diffuse(0.1, 0.6, 0.2));
    assert!(cube.emitter.is_none() && cylinder.emitter.is_none());
    // The caps triangulate to their full area: pi r^2 for a 32-gon of radius 0.5, 2 caps.
    let flat = flatten(&with_camera(scene.world), &path).unwrap();
    let cap_area: f32 = flat
        .shapes()
        .filter_map(|s| match s {
            Shape::Triangle(t) if t.normal_unnormalized().normalize().z.abs() > 0.999 => {
                let centre_x = t.v0.x;
                (centre_x > -1.0).then_some(t.area()) // the cylinder, not the cube's faces
            }
            _ => None,
        })
        .sum();
    let polygon_area = 0.5 * 32.0 * 0.25 * (2.0 * std::f32::consts::PI / 32.0).sin();
    assert!((cap_area - 2.0 * polygon_area).abs() < 1e-4, "{cap_area}");
}

// ---------------------------------------------------------------------------------------
// Hand-made glTF files.

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Builds one binary buffer and the accessors into it.
#[derive(Default)]
pub(crate) struct Buffer {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    fn view(&mut self, data: &[u8]) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()}));
        self.bytes.extend_from_slice(data);
        self.views.len() - 1
    }

    pub(crate) fn vec3s(&mut self, v: &[[f32; 3]]) -> usize {
        let data: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        let lo: Vec<f32> = (0..3)
            .map(|k| v.iter().map(|p| p[k]).fold(f32::INFINITY, f32::min))
            .collect();
        let hi: Vec<f32> = (0..3)
            .map(|k| v.iter().map(|p| p[k]).fold(f32::NEG_INFINITY, f32::max))
            .collect();
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": v.len(),
            "type": "VEC3", "min": lo, "max": hi}),
        );
        self.accessors.len() - 1
    }

    pub(crate) fn vec2s(&mut self, v: &[[f32; 2]]) -> usize {
        let data: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": "VEC2"}),
        );
        self.accessors.len() - 1
    }

    pub(crate) fn vec4s(&mut self, v: &[[f32; 4]]) -> usize {
        let data: Vec<u8> = v.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5126, "count": v.len(), "type": "VEC4"}),
        );
        self.accessors.len() - 1
    }

    pub(crate) fn indices(&mut self, i: &[u16]) -> usize {
        let data: Vec<u8> = i.iter().flat_map(|x| x.to_le_bytes()).collect();
        let view = self.view(&data);
        self.accessors.push(
            json!({"bufferView": view, "componentType": 5123, "count": i.len(), "type": "SCALAR"}),
        );
        self.accessors.len() - 1
    }

    /// Puts the buffer, views and accessors into `doc` (buffer as a data URI).
    /// The closed box of the furnace scenes, corners at +-10 (corner k has x, y, z = +-10 by
    /// its bits 2, 1, 0), as two triangles per face: its (positions, indices) accessors.
    pub(crate) fn furnace_box(&mut self) -> (usize, usize) {
        let corners: Vec<[f32; 3]> = (0..8)
            .map(|k| [4, 2, 1].map(|bit| if k & bit != 0 { 10.0 } else { -10.0 }))
            .collect();
        let cube = self.vec3s(&corners);
        let faces = [
            [0, 1, 3, 2],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 3, 7, 6],
            [0, 2, 6, 4],
            [1, 3, 7, 5],
        ];
        let indices: Vec<u16> = faces
            .iter()
            .flat_map(|[a, b, c, d]| [*a, *b, *c, *a, *c, *d])
            .collect();
        (cube, self.indices(&indices))
    }

    pub(crate) fn into_doc(self, mut doc: Value) -> Value {
        doc["asset"] = json!({"version": "2.0"});
        doc["buffers"] = json!([{
            "byteLength": self.bytes.len(),
            "uri": format!("data:application/octet-stream;base64,{}", base64(&self.bytes)),
        }]);
        doc["bufferViews"] = json!(self.views);
        doc["accessors"] = json!(self.accessors);
        doc
    }
}

pub(crate) fn write_gltf(dir: &Path, name: &str, doc: &Value) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string_pretty(doc).unwrap()).unwrap();
    path
}

const TRIANGLE: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

#[test]
fn data_uri_non_indexed_matrix_and_negative_scale_without_normals() {
    let mut b = Buffer::default();
    let positions = b.vec3s(&TRIANGLE);
    let doc = b.into_doc(json!({
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            // Column-major matrix: a translation by (10, 0, 0).
            {"name": "parent", "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1], "children": [1]},
            {"name": "mirrored", "mesh": 0, "scale": [-1, 1, 1], "translation": [0, 0, 5]}
        ],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": positions}}]}]
    }));
    let dir = scratch("edge");
    let path = write_gltf(&dir, "edge.gltf", &doc);
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    let objects = objects(&scene);
    let tri = &objects["mirrored"];
    assert_eq!(
        tri.triangles, 1,
        "non-indexed: one triangle from three vertices"
    );
    // glTF world: (10 - x, y, 5 + z); to +Z up: (x, -z, y).
    assert!(close(tri.lo, Vec3::new(9.0, -5.0, 0.0), 1e-6), "{}", tri.lo);
    assert!(
        close(tri.hi, Vec3::new(10.0, -5.0, 1.0), 1e-6),
        "{}",
        tri.hi
    );
    for mesh in scene.world.query::<&Mesh>().iter() {
        assert!(mesh.normals.is_empty(), "no NORMAL: flat shading");
    }
    // The mirror keeps the front on glTF's +Z side (world -Y): flatten flips the winding.
    let flat = flatten(&with_camera(scene.world), &path).unwrap();
    match flat.shape(0) {
        Shape::Triangle(t) => {
            let n = t.normal_unnormalized().normalize();
            assert!(close(n.into(), Vec3::new(0.0, -1.0, 0.0), 1e-6), "{n}");
        }
        _ => unreachable!(),
    }
    assert_eq!(flat.vertex_normals(0), [Vec3::ZERO; 3]);
}

#[test]
fn sparse_accessors_and_several_primitives_with_mapped_materials() {
    let mut b = Buffer::default();
    let positions = b.vec3s(&TRIANGLE);
    let indices = b.indices(&[0, 1, 2]);
    // Sparse: vertex 1 replaced by (2, 0, 0).
    let sparse_index = b.view(&1u16.to_le_bytes());
    let sparse_value: Vec<u8> = [2.0f32, 0.0, 0.0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    let sparse_values = b.view(&sparse_value);
    let mut doc = b.into_doc(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "parts", "mesh": 0}],
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_emissive_strength"],
        "materials": [
            {"name": "glass", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}},
             "pbrMetallicRoughness": {"roughnessFactor": 0.0}},
            {"name": "lamp", "emissiveFactor": [1.0, 0.5, 0.25], "doubleSided": true,
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
             "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.3, 0.4, 1.0], "metallicFactor": 0.0}},
            {"name": "gold mirror", "pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.8, 0.3, 1.0],
             "metallicFactor": 1.0, "roughnessFactor": 0.0}}
        ],
        "meshes": [{"name": "parts", "primitives": [
            {"attributes": {"POSITION": 2}, "indices": indices, "material": 0},
            {"attributes": {"POSITION": positions}, "material": 1},
            {"attributes": {"POSITION": positions}, "indices": indices, "material": 2}
        ]}]
    }));
    let sparse_accessor = json!({
        "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
        "min": [0.0, 0.0, 0.0], "max": [2.0, 1.0, 0.0],
        "sparse": {"count": 1,
            "indices": {"bufferView": sparse_index, "componentType": 5123},
            "values": {"bufferView": sparse_values}}
    });
    doc["accessors"]
        .as_array_mut()
        .unwrap()
        .push(sparse_accessor);
    let path = write_gltf(&scratch("sparse"), "sparse.gltf", &doc);
    let scene = import_model(&path, UpAxis::Z).expect("loads");
    let mut parts: Vec<(Mesh, Material, Option<Emitter>)> = scene
        .world
        .query::<(&Mesh, &Material, Option<&Emitter>)>()
        .iter()
        .map(|(m, mat, e)| (m.clone(), *mat, e.copied()))
        .collect();
    assert_eq!(parts.len(), 3, "one entity per primitive");
    parts.sort_by_key(|p| format!("{:?}", p.1));
    let glass = parts
        .iter()
        .find(|p| matches!(p.1, Material::MetallicRoughness { transmission, .. } if transmission == 1.0))
        .unwrap();
    assert_eq!(
        glass.0.positions[1],
        Vec3::new(2.0, 0.0, 0.0),
        "sparse value applied"
    );
    assert!(
        matches!(glass.1, Material::MetallicRoughness { ior, metallic, roughness, .. }
            if ior == 1.5 && metallic == 1.0 && roughness == 0.0),
        "default IOR 1.5, glTF's default metallic 1: {:?}",
        glass.1
    );
    let lamp = parts.iter().find(|p| p.2.is_some()).unwrap();
    let e = lamp.2.unwrap();
    assert_eq!(e.radiance, Rgb::new(4.0, 2.0, 1.0));
    assert!(e.two_sided);
    assert_eq!(
        lamp.1,
        Material::MetallicRoughness {
            base_color: Rgb::new(0.2, 0.3, 0.4),
            metallic: 0.0,
            roughness: 1.0,
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
    let gold = parts
        .iter()
        .find(|p| matches!(p.1, Material::MetallicRoughness { base_color, .. } if base_color == Rgb::new(1.0, 0.8, 0.3)))
        .unwrap();
    assert!(
        matches!(gold.1, Material::MetallicRoughness { metallic, roughness, .. } if metallic == 1.0 && roughness == 0.0)
    );
}

#[test]
fn base_colour_textures_are_decoded_sampled_and_transformed() {
    // A 2x1 PNG: sRGB 255 and 188 (linear 1 and ~0.5029) in red.
    let mut png = Vec::new();
    image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 188, 0, 0])
        .unwrap()
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut b = Buffer::default();
    let positions = b.vec3s(&TRIANGLE);
    let uvs = b.vec2s(&[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]);
    let doc = b.into_doc(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "textured", "mesh": 0}],
        "extensionsUsed": ["KHR_texture_transform"],
        "images": [{"uri": format!("data:image/png;base64,{}", base64(&png))}],
        "samplers": [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}],
        "textures": [{"source": 0, "sampler": 0}],
        "materials": [{"extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
            "pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 1.0, 1.0],
            "metallicFactor": 0.0,
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform":
                {"offset": [0.5, 0.0], "scale": [0.5, 1.0]}}}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": positions, "TEXCOORD_0": uvs},
            "material": 0}]}]
    }));
    let path = write_gltf(&scratch("texture"), "texture.gltf", &doc);
    let scene = import_model(&path, UpAxis::Y).expect("loads");
    let mesh = scene.world.query::<&Mesh>().iter().next().unwrap().clone();
    assert_eq!(
        mesh.uvs,
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]].map(wavetrace::math::Vec2::from)
    );
    let flat = flatten(&with_camera(scene.world), &path).unwrap();
    // uv' = offset + scale * uv, applied at each lookup.
    let transform = flat.material_textures()[0].base_color.uv_transform;
    assert_eq!(
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]].map(|uv| transform.apply(uv.into())),
        [[0.5, 0.0], [1.0, 0.0], [0.5, 1.0]].map(wavetrace::math::Vec2::from)
    );
    assert_eq!(flat.textures().len(), 1);
    let t = &flat.textures()[0];
    let left = t.lookup(wavetrace::math::Vec2::new(0.25, 0.5));
    let right = t.lookup(wavetrace::math::Vec2::new(0.75, 0.5));
    assert!(
        (left.x - 1.0).abs() < 1e-6 && (right.x - 0.5029).abs() < 1e-3,
        "{left} {right}"
    );
    assert_eq!(
        t.lookup(wavetrace::math::Vec2::new(0.6, 0.5)),
        right,
        "nearest filter"
    );
    assert_eq!(
        t.lookup(wavetrace::math::Vec2::new(7.0, 0.5)),
        right,
        "clamp to edge"
    );
    assert!(
        matches!(flat.materials()[0], wavetrace::internals::Bsdf::Lambertian { albedo } if albedo == Rgb::new(0.5, 1.0, 1.0))
    );
}

/// A ground quad (albedo 0.5, glTF y = 0, 100 units wide) seen straight down by a camera of
/// tiny field of view at glTF height 2, lit by one punctual light from straight above.
pub(crate) fn punctual_light_doc(light: Value, light_height: f32) -> Value {
    let mut b = Buffer::default();
    let positions = b.vec3s(&[
        [-50.0, 0.0, 50.0],
        [50.0, 0.0, 50.0],
        [50.0, 0.0, -50.0],
        [-50.0, 0.0, -50.0],
    ]);
    let indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let down = [
        -std::f32::consts::FRAC_1_SQRT_2,
        0.0,
        0.0,
        std::f32::consts::FRAC_1_SQRT_2,
    ];
    b.into_doc(json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"],
        "extensions": {"KHR_lights_punctual": {"lights": [light]}},
        "nodes": [
            {"name": "ground", "mesh": 0},
            {"name": "eye", "camera": 0, "translation": [0.0, 2.0, 0.0], "rotation": down},
            {"name": "lamp", "translation": [0.0, light_height, 0.0], "rotation": down,
             "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.001, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0},
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": positions}, "indices": indices, "material": 0}]}]
    }))
}

pub(crate) fn render_mean(flat: &RenderScene) -> Rgb {
    let settings = RenderSettings {
        width: 4,
        height: 4,
        spp: 4,
        ..Default::default()
    };
    let (film, _) = render(flat, &settings, |_| wavetrace::Flow::Continue).unwrap();
    let image = film.resolve();
    image.pixels.iter().sum::<Rgb>() / image.pixels.len() as f32
}

#[test]
fn punctual_lights_give_their_analytic_radiance() {
    // Radiance off a Lambertian plane (albedo a) lit head-on: a / pi * E, with irradiance
    // E = I / d^2 for point and spot lights (I in W/sr) and E for directional lights (W/m^2).
    // The camera sees a 0.002-unit patch under the light, so the answer is exact to ~1e-6;
    // the ground's light escapes to the black background, so nothing else adds.
    let dir = scratch("lights");
    let cases = [
        (
            "point",
            json!({"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 8.0}),
        ),
        (
            "spot",
            json!({"type": "spot", "intensity": 8.0,
            "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}),
        ),
        ("sun", json!({"type": "directional", "intensity": 3.0})),
    ];
    for (name, light) in cases {
        let path = write_gltf(
            &dir,
            &format!("{name}.gltf"),
            &punctual_light_doc(light.clone(), 2.0),
        );
        // Unitless: the file's numbers are W/sr and W/m^2 (the spec reading, / 683, is
        // tested in `light_units`).
        let unitless = LoadOptions {
            light_units: LightUnits::Unitless,
            ..Default::default()
        };
        let scene = load_scene_with(&path, &unitless).expect("loads");
        assert!(has_lights(&scene.world), "{name}");
        let flat = flatten(&scene.world, &path).unwrap();
        assert_eq!(flat.lights().delta_lights.len(), 1);
        let colour = light.get("color").map_or(Rgb::ONE, vec3);
        // The lamp is 2 units above the ground: E = 8 / 2^2 for point and spot, 3 for the sun.
        let irradiance = match name {
            "sun" => 3.0 * colour,
            _ => 8.0 / 4.0 * colour,
        };
        let expected = 0.5 / std::f32::consts::PI * irradiance;
        let got = render_mean(&flat);
        assert!(
            (got - expected).abs().max_element() < 1e-4 * expected.max_element(),
            "{name}: {got} vs {expected}"
        );
    }
    // Outside a spot's outer cone there is no light: tilt the spot 45 degrees (> 0.5 rad).
    let tilted = [-0.9238795f32, 0.0, 0.0, 0.3826834]; // -135 degrees about x
    let mut doc = punctual_light_doc(
        json!({"type": "spot", "intensity": 8.0, "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}),
        2.0,
    );
    doc["nodes"][2]["rotation"] = json!(tilted);
    let path = write_gltf(&dir, "tilted.gltf", &doc);
    let flat = flatten(&load_scene(&path).unwrap().world, &path).unwrap();
    assert_eq!(render_mean(&flat), Rgb::ZERO);
}

// ---------------------------------------------------------------------------------------
// Errors.

fn error_of(path: &Path) -> String {
    match import_model(path, UpAxis::Y) {
        Ok(_) => panic!("{} loaded but should not", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn unsupported_and_broken_files_give_errors_naming_file_and_problem() {
    let dir = scratch("errors");
    let mut b = Buffer::default();
    let positions = b.vec3s(&TRIANGLE);
    let base = b.into_doc(json!({
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "n", "mesh": 0}],
        "meshes": [{"name": "wires", "primitives": [{"attributes": {"POSITION": positions}}]}]
    }));

    for ext in ["KHR_draco_mesh_compression", "EXT_lights_image_based"] {
        let mut doc = base.clone();
        doc["extensionsUsed"] = json!([ext]);
        doc["extensionsRequired"] = json!([ext]);
        let path = write_gltf(&dir, "required.gltf", &doc);
        let e = error_of(&path);
        assert!(e.contains("required.gltf") && e.contains(ext), "{e}");
    }

    let mut lines = base.clone();
    lines["meshes"][0]["primitives"][0]["mode"] = json!(1);
    let e = error_of(&write_gltf(&dir, "lines.gltf", &lines));
    // A file of lines alone has nothing to render (lines among triangles are skipped with a
    // warning: import_robust.rs).
    assert!(
        e.contains("lines.gltf")
            && e.contains("nothing renderable")
            && e.contains("points and lines are not rendered"),
        "{e}"
    );

    let mut out_of_range = base.clone();
    let mut b = Buffer::default();
    b.vec3s(&TRIANGLE);
    let idx = b.indices(&[0, 1, 7]);
    out_of_range["buffers"] = b.into_doc(json!({}))["buffers"].clone();
    out_of_range["bufferViews"] = json!([{"buffer": 0, "byteOffset": 0, "byteLength": 36},
        {"buffer": 0, "byteOffset": 36, "byteLength": 6}]);
    out_of_range["accessors"]
        .as_array_mut()
        .unwrap()
        .push(json!(
        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}));
    out_of_range["meshes"][0]["primitives"][0]["indices"] = json!(idx);
    let e = error_of(&write_gltf(&dir, "range.gltf", &out_of_range));
    assert!(
        e.contains("range.gltf") && e.contains("out of range"),
        "{e}"
    );

    let mut overrun = base.clone();
    overrun["accessors"][0]["count"] = json!(100);
    let e = error_of(&write_gltf(&dir, "overrun.gltf", &overrun));
    assert!(
        e.contains("overrun.gltf") && e.contains("run past the end of buffer view 0"),
        "{e}"
    );

    let text = serde_json::to_string(&base).unwrap();
    let truncated = dir.join("truncated.gltf");
    std::fs::write(&truncated, &text[..text.len() / 2]).unwrap();
    let e = error_of(&truncated);
    assert!(
        e.contains("truncated.gltf") && e.contains("invalid JSON"),
        "{e}"
    );

    let mut external = base.clone();
    external["buffers"][0]["uri"] = json!("missing.bin");
    let e = error_of(&write_gltf(&dir, "external.gltf", &external));
    assert!(e.contains("external.gltf") && e.contains("buffer"), "{e}");

    let glb = dir.join("garbage.glb");
    std::fs::write(&glb, b"glTF\x02\x00\x00\x00garbage").unwrap();
    let e = error_of(&glb);
    assert!(e.contains("garbage.glb"), "{e}");

    let e = error_of(&dir.join("absent.glb"));
    assert!(
        e.contains("absent.glb") && e.contains("no such file"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// OBJ details.

#[test]
fn obj_without_mtl_warns_and_concave_faces_keep_their_area() {
    let dir = scratch("obj");
    let path = dir.join("l.obj");
    // An L-shaped face (area 3) that a fan from its first vertex would get wrong, and a
    // library that does not exist.
    std::fs::write(
        &path,
        "mtllib nowhere.mtl\no L\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nusemtl gone\nf 4 5 6 1 2 3\n",
    )
    .unwrap();
    let scene = import_model(&path, UpAxis::Z).expect("loads");
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains("nowhere.mtl"),
        "{}",
        scene.warnings[0]
    );
    let objects = objects(&scene);
    assert_eq!(
        objects["L"].material,
        Material::Lambertian {
            albedo: Rgb::splat(0.8)
        }
    );
    let flat = flatten(&with_camera(scene.world), &path).unwrap();
    let area: f32 = flat
        .shapes()
        .map(|s| match s {
            Shape::Triangle(t) => t.area(),
            _ => 0.0,
        })
        .sum();
    assert!((area - 3.0).abs() < 1e-5, "{area}");

    let bad = dir.join("bad.obj");
    std::fs::write(
        &bad,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n# comment\nf 1 2 3\nf 1 2 3 9\n",
    )
    .unwrap();
    // The face naming a missing vertex is skipped with a warning; the good one stays.
    let scene = import_model(&bad, UpAxis::Z).expect("the good face loads");
    let triangles: usize = scene
        .world
        .query::<&Mesh>()
        .iter()
        .map(|m| m.indices.len())
        .sum();
    assert_eq!(triangles, 1);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains("bad.obj")
            && scene.warnings[0].contains("line 6 names vertex 9"),
        "{:?}",
        scene.warnings
    );
}

#[test]
fn mtl_mapping_covers_mirror_glass_emitter_and_texture() {
    let dir = scratch("mtl");
    std::fs::write(
        dir.join("m.mtl"),
        "newmtl mirror\nKd 0 0 0\nKs 0.9 0.9 0.9\nNs 1000\nillum 2\n\
         newmtl polished\nKd 0.5 0.5 0.5\nillum 3\n\
         newmtl glass\nKd 1 1 1\nNi 1.33\nd 0.2\nillum 2\n\
         newmtl tr\nKd 1 1 1\nTr 0.5\n\
         newmtl lamp\nKd 0 0 0\nKe 5 4 3\n\
         newmtl brushed\nKd 0.8 0.7 0.6\nKs 0.25 0.25 0.25\nNs 250\nPm 1\nNi 1.4\n\
         newmtl satin\nKd 0.5 0.5 0.5\nKs 0.5 0.5 0.5\nNs 250\nPr 0.3\n",
    )
    .unwrap();
    let mut obj = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
    for m in [
        "mirror", "polished", "glass", "tr", "lamp", "brushed", "satin",
    ] {
        obj += &format!("o {m}\nusemtl {m}\nf 1 2 3\n");
    }
    let path = dir.join("m.obj");
    std::fs::write(&path, obj).unwrap();
    let scene = import_model(&path, UpAxis::Z).expect("loads");
    // `d` below 1 without a transparency illum is alpha in Blender: approximated by glass;
    // `Tr` alone is ignored, as Blender does (its meaning differs between exporters).
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("material 'glass': d 0.2"));
    assert!(scene.warnings[1].contains("material 'tr': Tr 0.5 is ignored"));
    let o = objects(&scene);
    assert_eq!(
        o["mirror"].material,
        Material::Mirror {
            tint: Rgb::splat(0.9)
        }
    );
    assert_eq!(o["polished"].material, Material::Mirror { tint: Rgb::ONE });
    assert!(
        matches!(o["glass"].material, Material::Dielectric { ior, .. } if (ior - 1.33).abs() < 1e-6)
    );
    assert!(
        matches!(o["tr"].material, Material::MetallicRoughness { transmission, .. }
        if transmission == 0.0)
    );
    let lamp = o["lamp"].emitter.unwrap();
    assert_eq!(lamp.radiance, Rgb::new(5.0, 4.0, 3.0));
    assert!(!lamp.two_sided);
    assert!(
        matches!(o["lamp"].material, Material::MetallicRoughness { base_color, specular, .. }
            if base_color == Rgb::ZERO && specular == 0.0)
    );
    // Ns 250 is roughness 1 - sqrt(250 / 1000) = 0.5; Pr wins over Ns; Ks = specular colour / 2.
    let pbr =
        |base: f32, metallic: f32, roughness: f32, ks: f32, ior: f32| Material::MetallicRoughness {
            base_color: if base == 0.0 {
                Rgb::new(0.8, 0.7, 0.6)
            } else {
                Rgb::splat(base)
            },
            metallic,
            roughness,
            specular: 1.0,
            specular_color: Rgb::splat(2.0 * ks),
            ior,
            transmission: 0.0,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Rgb::ZERO,
            sheen_roughness: 0.0,
        };
    assert_eq!(o["brushed"].material, pbr(0.0, 1.0, 0.5, 0.25, 1.4));
    assert_eq!(o["satin"].material, pbr(0.5, 0.0, 0.3, 0.5, 1.5));

    // map_Kd: the vase of assets/ is textured.
    let vase = import_model(&repo("assets/vase.obj"), UpAxis::Y).expect("loads");
    assert!(vase.warnings.is_empty(), "{:?}", vase.warnings);
    let v = objects(&vase);
    assert!(v["Vase"].textured && !v["Star"].textured);
    assert!(matches!(v["Star"].material, Material::Mirror { .. }));
}

// ---------------------------------------------------------------------------------------
// Placement.

#[test]
fn a_bare_model_stands_in_the_room_and_a_lit_file_keeps_its_camera() {
    let path = blender_dir().join("cube-cylinder.obj");
    let scene = load_scene(&path).expect("loads");
    let cams = cameras(&scene);
    assert_eq!(cams.len(), 1);
    assert_eq!(
        cams[0].1.eye,
        Vec3::new(-1.0, 0.0, 0.0),
        "the room's camera"
    );
    let o = objects(&scene);
    assert!(o.contains_key("floor") && o.contains_key("area light"));
    let (lo, hi) = ["Cube", "Cylinder"]
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), n| {
            (lo.min(o[*n].lo), hi.max(o[*n].hi))
        });
    assert!((lo.z - ROOM_FLOOR).abs() < 1e-4, "stands on the floor");
    // In full view of the room camera (looking along +x, 90 degrees), and large: as near as
    // the view allows, so the box reaches the view's margin.
    let d = lo.x - ROOM_EYE.x;
    assert!(hi.y.abs().max(lo.y.abs()).max(hi.z.abs()) <= ROOM_VIEW_FILL * d + 1e-4);
    assert!((-lo.z).max(hi.y.abs()).max(lo.y.abs()) >= ROOM_VIEW_FILL * d * 0.999);

    // The glTF export has an emitter: it renders as is, from its own camera.
    let glb = blender_dir().join("primitives.glb");
    let scene = load_scene(&glb).unwrap();
    assert_eq!(cameras(&scene)[0].0, "Camera");
    assert!(!objects(&scene).contains_key("floor"));
    // ... unless --in-room.
    let options = LoadOptions {
        in_room: true,
        ..Default::default()
    };
    let scene = load_scene_with(&glb, &options).unwrap();
    assert!(objects(&scene).contains_key("floor"));
    assert_eq!(cameras(&scene).len(), 1);
    // A camera that does not exist is named in the error, with the ones that do.
    let options = LoadOptions {
        camera: Some("Nope".into()),
        ..Default::default()
    };
    let e = load_scene_with(&glb, &options).err().unwrap().to_string();
    assert!(e.contains("Nope") && e.contains("Camera"), "{e}");
    let options = LoadOptions {
        camera: Some("Camera".into()),
        ..Default::default()
    };
    assert_eq!(cameras(&load_scene_with(&glb, &options).unwrap()).len(), 1);
}

#[test]
fn a_lit_file_without_camera_gets_one_that_frames_it() {
    let mut doc = punctual_light_doc(json!({"type": "point", "intensity": 1.0}), 2.0);
    doc["nodes"].as_array_mut().unwrap().remove(1);
    doc["scenes"][0]["nodes"] = json!([0, 1]);
    doc.as_object_mut().unwrap().remove("cameras");
    let path = write_gltf(&scratch("frame"), "nocam.gltf", &doc);
    let scene = load_scene(&path).unwrap();
    let cams = cameras(&scene);
    assert_eq!(cams.len(), 1);
    let (lo, hi) = bounding_box(&scene.world).unwrap();
    let centre = (lo + hi) * 0.5;
    let c = cams[0].1;
    assert!(
        close(c.forward, (centre - c.eye).normalize(), 1e-5),
        "looks at the centre"
    );
}

#[test]
fn model_tables_place_files_in_a_scene() {
    let path = repo("scenes/room-with-model.toml");
    let scene = load_scene(&path).expect("loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let o = objects(&scene);
    let (lo, hi) = ["Vase", "Star"]
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), n| {
            (lo.min(o[*n].lo), hi.max(o[*n].hi))
        });
    // fit = 2.2 scales the file's largest extent to 2.2 (before the rotation about z, which
    // leaves the height alone).
    let (file_lo, file_hi) = bounding_box(
        &import_model(&repo("assets/vase.obj"), UpAxis::Y)
            .unwrap()
            .world,
    )
    .unwrap();
    let scale = 2.2 / (file_hi - file_lo).max_element();
    assert!(
        ((hi - lo).z - scale * (file_hi - file_lo).z).abs() < 1e-4,
        "fit 2.2: {lo}..{hi}"
    );
    assert!((lo.z - -5.0).abs() < 1e-4, "anchor on the floor: {lo}");
    assert!(o.contains_key("floor") && o["Vase"].textured);

    // Position, rotation, scale and the material override, in a scene written here.
    let dir = scratch("model-table");
    std::fs::copy(blender_dir().join("cube-cylinder.obj"), dir.join("cc.obj")).unwrap();
    std::fs::copy(
        blender_dir().join("cube-cylinder.mtl"),
        dir.join("cube-cylinder.mtl"),
    )
    .unwrap();
    let toml = "[camera]\neye = [0, -10, 0]\nlook_at = [0, 0, 0]\nvfov = 40\n\
        [materials]\nchrome = { type = \"mirror\" }\n\
        [[model]]\nfile = \"cc.obj\"\nposition = [100, 0, 0]\nrotation = [0, 0, 90]\nscale = 2\nmaterial = \"chrome\"\n";
    let scene_path = dir.join("s.toml");
    std::fs::write(&scene_path, toml).unwrap();
    let scene = load_scene(&scene_path).expect("loads");
    let o = objects(&scene);
    // Cylinder: (-0.5, 1.5, 0)..(0.5, 2.5, 1.5), doubled, then turned 90 degrees about z:
    // (x, y) -> (-y, x), then moved by (100, 0, 0).
    assert!(
        close(o["Cylinder"].lo, Vec3::new(95.0, -1.0, 0.0), 1e-4),
        "{}",
        o["Cylinder"].lo
    );
    assert!(
        close(o["Cylinder"].hi, Vec3::new(97.0, 1.0, 3.0), 1e-4),
        "{}",
        o["Cylinder"].hi
    );
    assert_eq!(o["Cube"].material, Material::Mirror { tint: Rgb::ONE });

    let missing = dir.join("missing.toml");
    std::fs::write(&missing, "[camera]\neye = [0, -10, 0]\nlook_at = [0, 0, 0]\nvfov = 40\n[[model]]\nfile = \"nope.obj\"\n").unwrap();
    let e = load_scene(&missing).err().unwrap().to_string();
    assert!(
        e.contains("missing.toml") && e.contains("nope.obj") && e.contains("line 6"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// Clearcoat and sheen.

/// A quad (glTF y = 0, front +y) of `material` inside a closed box that emits radiance 1 from
/// both sides and reflects nothing, seen at 60 degrees from the quad's normal by a camera of
/// tiny field of view: each pixel is the quad's directional albedo at mu = 0.5, times 1.
fn layered_furnace_doc(material: Value) -> Value {
    let mut b = Buffer::default();
    let quad = b.vec3s(&[
        [-1.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 0.0, -1.0],
        [-1.0, 0.0, -1.0],
    ]);
    let quad_indices = b.indices(&[0, 1, 2, 0, 2, 3]);
    let (cube, cube_indices) = b.furnace_box();
    let half = 15f32.to_radians(); // -30 degrees about x: looking along (0, -0.5, -0.866)
    b.into_doc(json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_materials_specular", "KHR_materials_clearcoat", "KHR_materials_sheen"],
        "nodes": [
            {"name": "probe", "mesh": 0},
            {"name": "sky", "mesh": 1},
            {"name": "eye", "camera": 0, "translation": [0.0, 0.5, 0.75f32.sqrt()],
             "rotation": [-half.sin(), 0.0, 0.0, half.cos()]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.001, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [material,
            {"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0},
             "emissiveFactor": [1.0, 1.0, 1.0], "doubleSided": true,
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": quad}, "indices": quad_indices, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": cube}, "indices": cube_indices, "material": 1}]}
        ]
    }))
}

/// A Lambertian base of `albedo` (no specular layer) with the given extensions added.
fn layered_material(albedo: f32, extensions: Value) -> Value {
    let mut m = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [albedo, albedo, albedo, 1.0], "metallicFactor": 0.0},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}
    });
    for (k, v) in extensions.as_object().unwrap() {
        m["extensions"][k] = v.clone();
    }
    m
}

#[test]
fn clearcoat_and_sheen_from_gltf_render_their_closed_form_albedos() {
    // At mu = 0.5 a smooth coat reflects Fc = 0.04 + 0.96 * 0.5^5 = 0.07 over a black base
    // (the coat's single-scattering albedo at alpha 1e-3 is 1 - O(1e-6)); over a white base the
    // furnace stays at exactly 1; a sheen over a black base reflects sheen_color * E(0.5, r)
    // (the table the unit tests check against quadrature and Monte Carlo).
    let dir = scratch("layers");
    let fc = 0.04 + 0.96 * 0.5f64.powi(5);
    let sheen = Rgb::new(1.0, 0.5, 0.25);
    let e = wavetrace::internals::sheen_albedo(0.5, 0.6) as f64;
    let cases = [
        (
            "coat over black",
            layered_material(
                0.0,
                json!({"KHR_materials_clearcoat": {"clearcoatFactor": 1.0}}),
            ),
            [fc; 3],
        ),
        (
            "half coat over black",
            layered_material(
                0.0,
                json!({"KHR_materials_clearcoat": {"clearcoatFactor": 0.5}}),
            ),
            [0.5 * fc; 3],
        ),
        (
            "coat over white",
            layered_material(
                1.0,
                json!({"KHR_materials_clearcoat": {"clearcoatFactor": 1.0}}),
            ),
            [1.0; 3],
        ),
        (
            "sheen over black",
            layered_material(
                0.0,
                json!({"KHR_materials_sheen": {"sheenColorFactor": [1.0, 0.5, 0.25], "sheenRoughnessFactor": 0.6}}),
            ),
            sheen.to_array().map(|c| c as f64 * e),
        ),
    ];
    let settings = RenderSettings {
        width: 8,
        height: 8,
        spp: 256,
        ..Default::default()
    };
    for (name, material, expected) in cases {
        let path = write_gltf(&dir, "furnace.gltf", &layered_furnace_doc(material));
        let scene = load_scene(&path).expect("loads");
        assert!(
            scene
                .warnings
                .iter()
                .all(|w| !w.contains("clearcoat") && !w.contains("sheen")),
            "{name}: {:?}",
            scene.warnings
        );
        let flat = flatten(&scene.world, &path).unwrap();
        let (mean, error) = crate::common::estimate(&flat, &settings);
        for c in 0..3 {
            eprintln!(
                "{name}: {:.5} +- {:.1e} vs {:.5}",
                mean[c], error[c], expected[c]
            );
            assert!(
                error[c] < 0.005 * expected[c],
                "{name}: error {error:?} too large to detect 1 %"
            );
            assert!(
                (mean[c] - expected[c]).abs() < 4.0 * error[c] + 1e-4 * expected[c],
                "{name}: {mean:?} +- {error:?} vs {expected:?}"
            );
        }
    }
    // The coat's normal map and the sheen colour texture are read (no warning).
    let material = layered_material(
        0.5,
        json!({"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatNormalTexture": {"index": 0}},
               "KHR_materials_sheen": {"sheenColorFactor": [1.0, 1.0, 1.0], "sheenColorTexture": {"index": 0}}}),
    );
    let path = write_gltf(&dir, "textured.gltf", &layered_furnace_doc(material));
    let warnings = load_scene(&path).expect("loads").warnings;
    let count = |what: &str| warnings.iter().filter(|w| w.contains(what)).count();
    assert_eq!(count("clearcoat"), 0, "{warnings:?}");
    assert_eq!(count("sheen"), 0, "{warnings:?}");
}

// ---------------------------------------------------------------------------------------
// Iridescence (thin film).

/// A smooth black dielectric (IOR 1.5) under a thin film: at mu = 0.5 it reflects the film's
/// Fresnel term at cosine 0.5 (the smooth lobe's albedo is 1 - O(1e-6)), in colour, and with
/// factor 0.5 the mean of that and Schlick's 0.07; the furnace box is the clearcoat test's.
#[test]
fn iridescence_from_gltf_renders_the_thin_film_reflectance() {
    let dir = scratch("iridescence");
    let film = |factor: f32| {
        json!({
            "name": "film",
            "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 0.0},
            "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": factor,
                "iridescenceIor": 2.0, "iridescenceThicknessMaximum": 300.0}}
        })
    };
    let full = wavetrace::internals::thin_film_reflectance(0.5, 2.0, 1.5, 300.0);
    let schlick = 0.04 + 0.96 * 0.5f64.powi(5);
    let cases = [
        ("film", film(1.0), full.to_array().map(|c| c as f64)),
        (
            "half film",
            film(0.5),
            full.to_array().map(|c| 0.5 * (c as f64 + schlick)),
        ),
    ];
    // The film is coloured at this thickness: the case can tell channels apart.
    assert!(full.max_element() - full.min_element() > 0.05, "{full}");
    let settings = RenderSettings {
        width: 8,
        height: 8,
        spp: 64,
        ..Default::default()
    };
    for (name, material, expected) in cases {
        let mut doc = layered_furnace_doc(material);
        doc["extensionsUsed"] = json!(["KHR_materials_iridescence"]);
        let path = write_gltf(&dir, "furnace.gltf", &doc);
        let scene = load_scene(&path).expect("loads");
        assert!(
            scene.warnings.iter().all(|w| !w.contains("iridescence")),
            "{name}: {:?}",
            scene.warnings
        );
        let flat = flatten(&scene.world, &path).unwrap();
        let (mean, error) = crate::common::estimate(&flat, &settings);
        for c in 0..3 {
            eprintln!(
                "{name}: {:.5} +- {:.1e} vs {:.5}",
                mean[c], error[c], expected[c]
            );
            assert!(
                (mean[c] - expected[c]).abs() < 4.0 * error[c] + 1e-3 * expected[c],
                "{name}: {mean:?} +- {error:?} vs {expected:?}"
            );
        }
    }
}

/// Out-of-range iridescence values load with their fallbacks and one warning for the file
/// that names each material: an inverted thickness range (used as written), a negative
/// thickness (0), a film index of 0 (1.3); the image has no NaN.
#[test]
fn bad_iridescence_values_warn_once_and_fall_back() {
    let dir = scratch("iridescence_bad");
    let material = json!({
        "name": "inverted",
        "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.5},
        "extensions": {"KHR_materials_iridescence": {"iridescenceFactor": 1.0,
            "iridescenceIor": 0.0, "iridescenceThicknessMinimum": 500.0,
            "iridescenceThicknessMaximum": -20.0}}
    });
    let mut doc = layered_furnace_doc(material);
    doc["extensionsUsed"] = json!(["KHR_materials_iridescence"]);
    let path = write_gltf(&dir, "bad.gltf", &doc);
    let scene = load_scene(&path).expect("loads");
    let warnings: Vec<_> = (scene.warnings.iter())
        .filter(|w| w.contains("iridescence"))
        .collect();
    assert_eq!(warnings.len(), 1, "{:?}", scene.warnings);
    for part in [
        "'inverted'",
        "minimum above maximum",
        "negative",
        "not positive",
    ] {
        assert!(warnings[0].contains(part), "{part}: {}", warnings[0]);
    }
    let film = (scene.world.query::<&wavetrace::scene::Iridescence>().iter())
        .copied()
        .next()
        .expect("the film is kept");
    assert_eq!(
        (film.ior, film.thickness_minimum, film.thickness_maximum),
        (1.3, 500.0, 0.0)
    );
    let flat = flatten(&scene.world, &path).unwrap();
    let settings = RenderSettings {
        width: 8,
        height: 8,
        spp: 16,
        ..Default::default()
    };
    let (mean, _) = crate::common::estimate(&flat, &settings);
    assert!(mean.iter().all(|m| m.is_finite() && *m > 0.0), "{mean:?}");
}
