//! Alpha coverage end to end (glTF `alphaMode`): a MASK quad whose texture's alpha is a
//! half-plane hides the emitter behind it over exactly the covered part of the image, and its
//! shadow under a directional light has the cut-out's shape; a BLEND quad of alpha 0.3 passes
//! 0.7 of the emitter behind it; renders with alpha are the same on any thread count. Every
//! file is written by the test; each scene is a glTF with its own camera and lights, rendered
//! as it is.

use crate::common::{assert_finite, render_image, render_with_threads};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use wavetrace::{Image, RenderScene, RenderSettings, flatten, load_scene};

/// Vertical field of view of the test cameras (radians); the images are square.
const YFOV: f32 = 1.0;

/// A glTF under construction: one buffer, its views and accessors, nodes, meshes, materials.
#[derive(Default)]
struct Doc {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    nodes: Vec<Value>,
    images: Vec<(String, image::RgbaImage)>,
    lights: Vec<Value>,
}

impl Doc {
    fn accessor(&mut self, data: Vec<u8>, mut accessor: Value) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()}));
        self.bytes.extend(data);
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A quad (two triangles, front face along `normal_axis`'s positive direction) spanning
    /// `lo..hi` on the two other axes at `offset` on that axis, with texture coordinates
    /// `u` along the first other axis, and the material `material`.
    fn quad(&mut self, axis: usize, offset: f32, lo: f32, hi: f32, material: usize) {
        let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
        let corner = |s: f32, t: f32| {
            let mut p = [0.0f32; 3];
            p[axis] = offset;
            p[a] = s;
            p[b] = t;
            p
        };
        let positions = [
            corner(lo, lo),
            corner(hi, lo),
            corner(lo, hi),
            corner(hi, hi),
        ];
        let uvs = [[0.0f32, 0.5], [1.0, 0.5], [0.0, 0.5], [1.0, 0.5]];
        let min: Vec<f32> = (0..3)
            .map(|k| positions.iter().map(|p| p[k]).fold(f32::MAX, f32::min))
            .collect();
        let max: Vec<f32> = (0..3)
            .map(|k| positions.iter().map(|p| p[k]).fold(f32::MIN, f32::max))
            .collect();
        let floats = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let position = self.accessor(
            floats(positions.as_flattened()),
            json!({"componentType": 5126, "count": 4, "type": "VEC3", "min": min, "max": max}),
        );
        let uv = self.accessor(
            floats(uvs.as_flattened()),
            json!({"componentType": 5126, "count": 4, "type": "VEC2"}),
        );
        // Counter-clockwise seen from the positive side of `axis`: (a, b) is right-handed
        // with `axis`.
        let indices: Vec<u8> = [0u16, 1, 2, 2, 1, 3]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let indices = self.accessor(
            indices,
            json!({"componentType": 5123, "count": 6, "type": "SCALAR"}),
        );
        self.meshes.push(json!({"primitives": [{
            "attributes": {"POSITION": position, "TEXCOORD_0": uv},
            "indices": indices, "material": material}]}));
        self.nodes.push(json!({"mesh": self.meshes.len() - 1}));
    }

    fn material(&mut self, material: Value) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }

    /// A texture of one row whose texels have the given alpha (white colour), sampled with
    /// nearest filtering; returns its index.
    fn alpha_texture(&mut self, alpha: &[u8]) -> usize {
        let image = image::RgbaImage::from_fn(alpha.len() as u32, 1, |x, _| {
            image::Rgba([255, 255, 255, alpha[x as usize]])
        });
        self.images
            .push((format!("alpha{}.png", self.images.len()), image));
        self.images.len() - 1
    }

    /// A camera at `translation`, turned by the quaternion `rotation` (it looks along its
    /// local -z).
    fn camera(&mut self, translation: [f32; 3], rotation: [f32; 4]) {
        self.nodes
            .push(json!({"camera": 0, "translation": translation, "rotation": rotation}));
    }

    fn write(self, dir: &Path, name: &str) -> PathBuf {
        let bin = format!("{name}.bin");
        std::fs::write(dir.join(&bin), &self.bytes).unwrap();
        for (file, image) in &self.images {
            image.save(dir.join(format!("{name}-{file}"))).unwrap();
        }
        let n = self.images.len();
        let mut doc = json!({
            "asset": {"version": "2.0"},
            "scenes": [{"nodes": (0..self.nodes.len()).collect::<Vec<_>>()}],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "cameras": [{"type": "perspective",
                "perspective": {"yfov": YFOV, "znear": 0.01, "aspectRatio": 1.0}}],
            "buffers": [{"byteLength": self.bytes.len(), "uri": bin}],
            "bufferViews": self.views,
            "accessors": self.accessors,
        });
        if n > 0 {
            doc["images"] = json!(
                self.images
                    .iter()
                    .map(|(file, _)| json!({"uri": format!("{name}-{file}")}))
                    .collect::<Vec<_>>()
            );
            doc["samplers"] = json!([{"magFilter": 9728}]);
            doc["textures"] = json!(
                (0..n)
                    .map(|i| json!({"source": i, "sampler": 0}))
                    .collect::<Vec<_>>()
            );
        }
        if !self.lights.is_empty() {
            doc["extensionsUsed"] = json!(["KHR_lights_punctual"]);
            doc["extensions"] = json!({"KHR_lights_punctual": {"lights": self.lights}});
        }
        let path = dir.join(format!("{name}.gltf"));
        std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
        path
    }
}

/// A black, rough, single-sided dielectric (it reflects only what is in front of it, where
/// the scenes have nothing) with the given alpha fields.
fn black(alpha: Value) -> Value {
    let mut m = json!({"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0],
        "metallicFactor": 0.0, "roughnessFactor": 1.0}});
    for (k, v) in alpha.as_object().unwrap() {
        if k == "baseColorFactor" || k == "baseColorTexture" {
            m["pbrMetallicRoughness"][k] = v.clone();
        } else {
            m[k] = v.clone();
        }
    }
    m
}

fn flat(path: &Path) -> RenderScene {
    let scene = load_scene(path).unwrap_or_else(|e| panic!("{} loads: {e}", path.display()));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    flatten(&scene.world, path).expect("flattens")
}

/// A camera on the +z axis at distance 3 from the origin looking at it, an emitting square
/// at z = -1 filling the view, and, if `cover` is given, a square of that material at z = 0
/// (x, y in [-2, 2]) filling the view, textured with `texture_alpha` if given. The cover's
/// texture coordinate `u` runs along x from -2 to 2.
fn emitter_behind(dir: &Path, name: &str, cover: Option<Value>, texture_alpha: &[u8]) -> PathBuf {
    let mut doc = Doc::default();
    let glow = doc.material(json!({"emissiveFactor": [1.0, 1.0, 1.0],
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0]}}));
    doc.quad(2, -1.0, -4.0, 4.0, glow);
    if let Some(mut cover) = cover {
        if !texture_alpha.is_empty() {
            let t = doc.alpha_texture(texture_alpha);
            cover["baseColorTexture"] = json!({"index": t});
        }
        let m = doc.material(black(cover));
        doc.quad(2, 0.0, -2.0, 2.0, m);
    }
    doc.camera([0.0, 0.0, 3.0], [0.0, 0.0, 0.0, 1.0]);
    doc.write(dir, name)
}

fn settings(spp: u32) -> RenderSettings {
    RenderSettings {
        width: 64,
        height: 64,
        spp,
        ..Default::default()
    }
}

/// The fraction of pixels brighter than half of `reference`'s mean.
fn bright_fraction(image: &Image, reference: f64) -> f64 {
    let bright = image
        .pixels
        .iter()
        .filter(|p| (p[0] + p[1] + p[2]) as f64 / 3.0 > 0.5 * reference)
        .count();
    bright as f64 / image.pixels.len() as f64
}

fn grey_mean(image: &Image) -> f64 {
    let m = crate::common::mean(image);
    (m[0] + m[1] + m[2]) / 3.0
}

#[test]
fn a_mask_cut_out_shows_the_emitter_behind_exactly_where_its_texture_is_transparent() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let settings = settings(4);
    let open = render_image(&flat(&emitter_behind(d, "open", None, &[])), &settings);
    let reference = grey_mean(&open);
    assert!(reference > 0.0);
    assert_eq!(
        bright_fraction(&open, reference),
        1.0,
        "the emitter fills the view"
    );
    // Alpha per quarter of u (x in [-2, 2]): opaque, opaque, opaque, 0.2; cutoff 0.5 keeps
    // x < 1. The view at z = 0 spans |x| <= 3 tan(YFOV / 2) (about 1.64).
    let mask = json!({"alphaMode": "MASK"});
    let path = emitter_behind(d, "mask", Some(mask), &[255, 255, 255, 51]);
    let image = render_image(&flat(&path), &settings);
    assert_finite(&image);
    let half_view = 3.0 * (YFOV as f64 / 2.0).tan();
    let expected = (half_view - 1.0) / (2.0 * half_view);
    let found = bright_fraction(&image, reference);
    eprintln!("mask cut-out: visible fraction {found:.4}, expected {expected:.4}");
    // Pixels straddling the edge go either way: one column of 64.
    assert!(
        (found - expected).abs() <= 1.0 / 64.0,
        "visible fraction {found}, expected {expected}"
    );
    // A cutoff above the surface's alpha everywhere: the surface is all cut away.
    let all_cut = json!({"alphaMode": "MASK", "alphaCutoff": 1.0,
        "baseColorFactor": [0.0, 0.0, 0.0, 0.99]});
    let path = emitter_behind(d, "all-cut", Some(all_cut), &[]);
    let image = render_image(&flat(&path), &settings);
    assert_eq!(
        bright_fraction(&image, reference),
        1.0,
        "alpha 0.99 < cutoff 1"
    );
}

#[test]
fn a_blend_surface_of_alpha_0_3_passes_0_7_of_the_light_behind_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let settings = settings(16);
    let open = render_image(&flat(&emitter_behind(d, "open", None, &[])), &settings);
    let reference = grey_mean(&open);
    let blend = json!({"alphaMode": "BLEND", "baseColorFactor": [0.0, 0.0, 0.0, 0.3]});
    let scene = flat(&emitter_behind(d, "blend", Some(blend), &[]));
    let image = render_image(&scene, &settings);
    assert_finite(&image);
    // Every sample is the emitter's radiance (passed through) or 0 (stopped by the black
    // surface): a Bernoulli(0.7) estimate over 64 x 64 x 16 samples.
    let samples = (64 * 64 * 16) as f64;
    let ratio = grey_mean(&image) / reference;
    let sigma = (0.7f64 * 0.3 / samples).sqrt();
    let z = (ratio - 0.7) / sigma;
    eprintln!("blend: transmitted {ratio:.5}, expected 0.7 (z = {z:.2})");
    assert!(
        z.abs() < 4.5,
        "transmitted {ratio}, expected 0.7 ({z:.2} sigma)"
    );

    // The same on one thread and on three.
    let one = render_with_threads(&scene, &settings, 1).0;
    let three = render_with_threads(&scene, &settings, 3).0;
    assert!(
        one.pixels == three.pixels,
        "the image depends on the thread count"
    );
}

#[test]
fn a_mask_cut_out_casts_a_shadow_of_its_shape() {
    // A floor at y = -1 (facing up), a directional light shining down, a horizontal MASK
    // square at y = 0 over x, z in [-1, 1] shifted by 0.1 along z, its texture opaque for
    // u < 0.5 (z < 0.1) and transparent beyond; the camera at y = -0.5 looks straight down
    // at the floor from under the square, so the image shows the floor only.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let down = [
        -std::f32::consts::FRAC_1_SQRT_2,
        0.0,
        0.0,
        std::f32::consts::FRAC_1_SQRT_2,
    ];
    let write = |name: &str, with_cover: bool| {
        let mut doc = Doc::default();
        let floor = doc.material(json!({"pbrMetallicRoughness": {
            "baseColorFactor": [0.8, 0.8, 0.8, 1.0], "metallicFactor": 0.0,
            "roughnessFactor": 1.0}}));
        // Axis 1 (y): the quad's axes are z then x, right-handed with y, so it faces +y.
        doc.quad(1, -1.0, -5.0, 5.0, floor);
        if with_cover {
            let t = doc.alpha_texture(&[255, 0]);
            let cover = doc.material(black(json!({"alphaMode": "MASK",
                "baseColorTexture": {"index": t}, "doubleSided": true})));
            // On axis 1 the quad's `u` runs along z.
            doc.quad(1, 0.0, -1.0, 1.0, cover);
            let last = doc.nodes.len() - 1;
            doc.nodes[last]["translation"] = json!([0.0, 0.0, 0.1]);
        }
        doc.lights
            .push(json!({"type": "directional", "intensity": 1.0}));
        doc.nodes.push(json!({"rotation": down,
            "extensions": {"KHR_lights_punctual": {"light": 0}}}));
        doc.camera([0.0, -0.5, 0.0], down);
        doc.write(d, name)
    };
    let settings = settings(4);
    let lit = render_image(&flat(&write("lit", false)), &settings);
    let reference = grey_mean(&lit);
    assert!(reference > 0.0);
    assert_eq!(
        bright_fraction(&lit, reference),
        1.0,
        "the light reaches all the floor"
    );
    let image = render_image(&flat(&write("shadowed", true)), &settings);
    assert_finite(&image);
    // The view on the floor spans |z| <= 0.5 tan(YFOV / 2); the shadow covers z < 0.1.
    let half_view = 0.5 * (YFOV as f64 / 2.0).tan();
    let expected = (half_view - 0.1) / (2.0 * half_view);
    let found = bright_fraction(&image, reference);
    eprintln!("mask shadow: lit fraction {found:.4}, expected {expected:.4}");
    assert!(
        (found - expected).abs() <= 1.0 / 64.0,
        "lit fraction {found}, expected {expected}"
    );
}
