//! glTF material textures end to end: the test writes a `.gltf` with its `.bin` and PNG
//! images, renders it small, and checks that each texture changes the image where it covers
//! the quad and nowhere else, with tolerances from the renders' standard errors. Also checks
//! that next-event estimation of a textured emitter is unbiased.

use crate::common::{assert_agree, assert_finite, render_image};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use wavetrace::{Image, RenderScene, RenderSettings, flatten, load_scene};

/// Little-endian binary buffer with one buffer view and accessor per attribute.
#[derive(Default)]
struct Buffer {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Buffer {
    fn push(&mut self, data: Vec<u8>, accessor: Value) -> usize {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
        self.views
            .push(json!({"buffer": 0, "byteOffset": self.bytes.len(), "byteLength": data.len()}));
        self.bytes.extend(data);
        let mut accessor = accessor;
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn floats(
        &mut self,
        v: &[f32],
        count: usize,
        kind: &str,
        minmax: Option<(Value, Value)>,
    ) -> usize {
        let data = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        let mut a = json!({"componentType": 5126, "count": count, "type": kind});
        if let Some((lo, hi)) = minmax {
            a["min"] = lo;
            a["max"] = hi;
        }
        self.push(data, a)
    }

    fn indices(&mut self, i: &[u16]) -> usize {
        let data = i.iter().flat_map(|x| x.to_le_bytes()).collect();
        self.push(
            data,
            json!({"componentType": 5123, "count": i.len(), "type": "SCALAR"}),
        )
    }
}

/// Adds a quad in glTF's z = `z` plane from (x0, -1) to (x1, 1), facing `+z` (or `-z` if
/// `down`), with UVs spanning [0, 1]^2 (v down the image: v = 0 at y = 1), as a mesh with
/// `material`. Returns the mesh index.
fn quad(
    b: &mut Buffer,
    meshes: &mut Vec<Value>,
    x0: f32,
    x1: f32,
    z: f32,
    down: bool,
    material: usize,
) -> usize {
    let p = [x0, -1.0, z, x1, -1.0, z, x1, 1.0, z, x0, 1.0, z];
    let nz = if down { -1.0 } else { 1.0 };
    let n = [0.0, 0.0, nz].repeat(4);
    let uv = [0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    let positions = b.floats(
        &p,
        4,
        "VEC3",
        Some((json!([x0, -1.0, z]), json!([x1, 1.0, z]))),
    );
    let normals = b.floats(&n, 4, "VEC3", None);
    let uvs = b.floats(&uv, 4, "VEC2", None);
    let indices = if down {
        b.indices(&[0, 2, 1, 0, 3, 2])
    } else {
        b.indices(&[0, 1, 2, 0, 2, 3])
    };
    meshes.push(json!({"primitives": [{
        "attributes": {"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs},
        "indices": indices, "material": material}]}));
    meshes.len() - 1
}

/// Writes `doc` (with `b` as `name.bin`) and the PNGs `images` into `dir`; returns the path.
fn write_gltf(
    dir: &Path,
    name: &str,
    mut doc: Value,
    b: Buffer,
    images: &[(&str, image::RgbImage)],
) -> PathBuf {
    std::fs::write(dir.join(format!("{name}.bin")), &b.bytes).unwrap();
    doc["buffers"] = json!([{"uri": format!("{name}.bin"), "byteLength": b.bytes.len()}]);
    doc["bufferViews"] = json!(b.views);
    doc["accessors"] = json!(b.accessors);
    doc["asset"] = json!({"version": "2.0"});
    for (file, img) in images {
        img.save(dir.join(file)).unwrap();
    }
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

/// An 8 x 8 image: `quadrant` (0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right) is
/// `inside`, the rest `outside`. Bilinear filtering blends them only within half a texel
/// (1/16) of the borders.
fn quadrant_image(quadrant: u32, inside: [u8; 3], outside: [u8; 3]) -> image::RgbImage {
    image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb(if (y / 4) * 2 + x / 4 == quadrant {
            inside
        } else {
            outside
        })
    })
}

fn flat(path: &Path) -> RenderScene {
    let scene = load_scene(path).expect("the test's glTF loads");
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    flatten(&scene.world, path).expect("flattens")
}

/// Mean and standard error over the pixels where `inside(u, v)` holds, from two renders with
/// different seeds (as `common::mean_and_error`, restricted to a region).
fn region_estimate(
    scene: &RenderScene,
    settings: &RenderSettings,
    uv_of_pixel: impl Fn(u32, u32) -> (f32, f32),
    inside: impl Fn(f32, f32) -> bool,
) -> ([f64; 3], [f64; 3]) {
    let render = |seed| {
        let image: Image = render_image(scene, &RenderSettings { seed, ..*settings });
        assert_finite(&image);
        image
    };
    let (a, b) = (render(settings.seed), render(settings.seed ^ 0x5EED_F00D));
    let (mut sum, mut var, mut n) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    for y in 0..settings.height {
        for x in 0..settings.width {
            let (u, v) = uv_of_pixel(x, y);
            if !inside(u, v) {
                continue;
            }
            let i = (y * settings.width + x) as usize;
            for c in 0..3 {
                let (p, q) = (a.pixels[i][c] as f64, b.pixels[i][c] as f64);
                sum[c] += (p + q) / 2.0;
                var[c] += (p - q) * (p - q) / 4.0;
            }
            n += 1.0;
        }
    }
    assert!(n > 0.0);
    (sum.map(|s| s / n), var.map(|v| v.sqrt() / n))
}

/// Sum of the channels and its standard error (the channels of one pixel are correlated, so
/// the errors add).
fn total((m, e): ([f64; 3], [f64; 3])) -> (f64, f64) {
    (m.iter().sum(), e.iter().sum())
}

const SIZE: u32 = 24;

/// Where a pixel's centre lands on the quad of [`textured_quad`]: the camera sees x, y in
/// [-0.9, 0.9], so u = (x + 1) / 2 and v = (1 - y) / 2.
fn uv_of_pixel(px: u32, py: u32) -> (f32, f32) {
    let x = ((px as f32 + 0.5) / SIZE as f32 * 2.0 - 1.0) * 0.9;
    let y = (1.0 - (py as f32 + 0.5) / SIZE as f32 * 2.0) * 0.9;
    ((x + 1.0) / 2.0, (1.0 - y) / 2.0)
}

/// The quadrant a texture coordinate is well inside of (away from the bilinear blend at the
/// quadrant borders), if any.
fn quadrant_of(u: f32, v: f32) -> Option<u32> {
    let away = |t: f32| (t - 0.5).abs() > 0.15;
    (away(u) && away(v)).then(|| (v > 0.5) as u32 * 2 + (u > 0.5) as u32)
}

/// A textured quad facing a camera, lit head-on by a directional light (irradiance 2). The
/// material is a white metal of roughness 0.5 with no dielectric specular layer; each
/// texture changes one quadrant: base colour darkens the top-left one, the metallic-roughness
/// map makes the top-right one a non-metal (so exactly Lambertian), the normal map tilts the
/// bottom-left one by 30 degrees, and the emissive map makes the bottom-right one emit.
fn textured_quad(
    dir: &Path,
    name: &str,
    base: bool,
    mr: bool,
    normal: bool,
    emissive: bool,
) -> PathBuf {
    let mut b = Buffer::default();
    let mut meshes = Vec::new();
    let mesh = quad(&mut b, &mut meshes, -1.0, 1.0, 0.0, false, 0);
    let half_fov = (0.9f32 / 2.0).atan();
    let mut material = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 1.0,
            "roughnessFactor": 0.5},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}
    });
    let mut textures = Vec::new();
    let mut texture = |file: &str| {
        textures.push(json!({"source": textures.len(), "sampler": 0}));
        (textures.len() - 1, json!({"uri": file}))
    };
    let mut images_json = Vec::new();
    if base {
        let (i, img) = texture("base.png");
        images_json.push(img);
        material["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": i});
    }
    if mr {
        let (i, img) = texture("mr.png");
        images_json.push(img);
        material["pbrMetallicRoughness"]["metallicRoughnessTexture"] = json!({"index": i});
    }
    if normal {
        let (i, img) = texture("normal.png");
        images_json.push(img);
        material["normalTexture"] = json!({"index": i, "scale": 1.0});
    }
    if emissive {
        let (i, img) = texture("emissive.png");
        images_json.push(img);
        material["emissiveTexture"] = json!({"index": i});
        material["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    }
    let doc = json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.0}]}},
        "nodes": [
            {"name": "quad", "mesh": mesh},
            {"name": "eye", "camera": 0, "translation": [0.0, 0.0, 2.0]},
            {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "cameras": [{"type": "perspective", "perspective":
            {"yfov": 2.0 * half_fov, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [material],
        "meshes": meshes,
        "images": images_json,
        "textures": textures,
        // Linear filtering, clamped: the quadrants blend only near their borders.
        "samplers": [{"magFilter": 9729, "wrapS": 33071, "wrapT": 33071}]
    });
    // Base colour: sRGB 64 (linear 0.05) top-left, white elsewhere. Metallic-roughness:
    // blue 0 (non-metal) top-right, else 1 (green 1: roughness as the factor). Normal map:
    // (sin 30, 0, cos 30) bottom-left, else flat. Emission: (255, 128, 0) bottom-right,
    // else black.
    let images = [
        ("base.png", quadrant_image(0, [64; 3], [255; 3])),
        ("mr.png", quadrant_image(1, [0, 255, 0], [0, 255, 255])),
        (
            "normal.png",
            quadrant_image(2, [191, 128, 238], [128, 128, 255]),
        ),
        ("emissive.png", quadrant_image(3, [255, 128, 0], [0, 0, 0])),
    ];
    write_gltf(dir, name, doc, b, &images)
}

#[test]
fn each_gltf_texture_changes_its_own_region_of_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: 32,
        ..Default::default()
    };
    let all = flat(&textured_quad(dir.path(), "all", true, true, true, true));
    assert_eq!(all.textures().len(), 4, "four textures, each used once");
    let estimate = |scene: &RenderScene, quadrant: u32| {
        region_estimate(scene, &settings, uv_of_pixel, |u, v| {
            quadrant_of(u, v) == Some(quadrant)
        })
    };
    // The metallic-roughness case compares files without the emissive texture: the emitting
    // quadrant (radiance about 1) outshines the sun (2 lux = 2/683 W/m^2) in the light
    // table, so nearly every shadow ray goes to it, and in the coplanar top-right quadrant
    // they all add nothing: the sun's light there has a standard error of ~20% at 32 spp and
    // the texture's effect (-40%) measured only z = -2.1. With the sun the only light, the
    // quadrant is noise-free.
    let no_emission = flat(&textured_quad(
        dir.path(),
        "no-emission",
        true,
        true,
        true,
        false,
    ));
    // Each texture against the same file without it: the difference (with - without) in the
    // texture's quadrant has the expected sign and is beyond 4 sigma; base colour and
    // metallic-roughness are exactly neutral (texel 1) elsewhere, so the other quadrants agree.
    let cases = [
        (
            "base colour",
            0,
            &all,
            textured_quad(dir.path(), "no-base", false, true, true, true),
            -1.0,
        ),
        (
            "metallic-roughness",
            1,
            &no_emission,
            textured_quad(dir.path(), "no-mr", true, false, true, false),
            -1.0,
        ),
        (
            "normal map",
            2,
            &all,
            textured_quad(dir.path(), "no-normal", true, true, false, true),
            -1.0,
        ),
    ];
    for (what, quadrant, with, without, sign) in cases {
        let all = with;
        let without = flat(&without);
        let (with_m, with_e) = total(estimate(all, quadrant));
        let (without_m, without_e) = total(estimate(&without, quadrant));
        let sigma = (with_e * with_e + without_e * without_e).sqrt();
        let z = (with_m - without_m) / sigma;
        eprintln!("{what}: {with_m:.4} with vs {without_m:.4} without (z = {z:.1})");
        assert!(
            sign * (with_m - without_m) > 4.0 * sigma && with_m != without_m,
            "{what}: {with_m} with the texture vs {without_m} without (sigma {sigma:.2e})"
        );
        if what != "normal map" {
            for other in (0..4).filter(|&q| q != quadrant) {
                assert_agree(
                    &format!("{what}, quadrant {other}"),
                    estimate(all, other),
                    estimate(&without, other),
                    4.0,
                );
            }
        }
    }
    // Where the metallic-roughness texture makes the white metal a non-metal without specular
    // layer, the quad is exactly Lambertian under the head-on sun: E / pi in each channel,
    // E = 2 lux / 683 lm/W (no texel would give that if the texture's green and blue were
    // swapped or sRGB-decoded: see also the unit test in wavefront::surface).
    let (lambertian, error) = estimate(&no_emission, 1);
    let expected = 2.0 / 683.0 / std::f64::consts::PI;
    assert_agree(
        "non-metal quadrant under the sun",
        (lambertian, error),
        ([expected; 3], [expected * 1e-5; 3]),
        4.0,
    );
    // Emission: against the file without the emissive texture and factor, the difference is
    // the texel's radiance (sRGB (255, 128, 0) = linear (1, 0.2158, 0)) in its quadrant and 0
    // elsewhere (the quad cannot light itself).
    let dark = no_emission;
    let texel = [1.0, 0.215_860_5, 0.0];
    for q in 0..4 {
        let (a, ea) = estimate(&all, q);
        let (b, eb) = estimate(&dark, q);
        let emitted = [0, 1, 2].map(|c| a[c] - b[c]);
        let error = [0, 1, 2].map(|c| (ea[c] * ea[c] + eb[c] * eb[c]).sqrt());
        let expected = if q == 3 { texel } else { [0.0; 3] };
        assert_agree(
            &format!("emission in quadrant {q}"),
            (emitted, error),
            (expected, [0.0; 3]),
            4.0,
        );
    }
}

/// A Lambertian floor (albedo 0.5) at glTF z = 0 under a square emitter at z = 1 facing down,
/// seen by a camera between them. `textured` gives the emitter (x in [-1, 1]) an emission
/// texture that is white on its left half (x < 0) and black on the right, sampled nearest;
/// otherwise the emitter is only that left half, untextured. Both light the floor the same.
fn half_lit_floor(dir: &Path, textured: bool) -> PathBuf {
    let mut b = Buffer::default();
    let mut meshes = Vec::new();
    let floor = quad(&mut b, &mut meshes, -3.0, 3.0, 0.0, false, 0);
    let lamp = if textured {
        quad(&mut b, &mut meshes, -1.0, 1.0, 1.0, true, 1)
    } else {
        quad(&mut b, &mut meshes, -1.0, 0.0, 1.0, true, 1)
    };
    let mut lamp_material = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}},
        "emissiveFactor": [1.0, 1.0, 1.0]
    });
    if textured {
        lamp_material["emissiveTexture"] = json!({"index": 0});
    }
    let doc = json!({
        "scenes": [{"nodes": [0, 1, 2]}],
        "extensionsUsed": ["KHR_materials_specular"],
        "nodes": [
            {"name": "floor", "mesh": floor},
            {"name": "lamp", "mesh": lamp},
            {"name": "eye", "camera": 0, "translation": [0.0, 0.0, 0.9]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 1.6, "aspectRatio": 1.0, "znear": 0.01}}],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0},
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}},
            lamp_material
        ],
        "meshes": meshes,
        "images": [{"uri": "half.png"}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}]
    });
    let half = image::RgbImage::from_fn(2, 1, |x, _| {
        image::Rgb(if x == 0 { [255; 3] } else { [0; 3] })
    });
    let name = if textured {
        "textured-lamp"
    } else {
        "half-lamp"
    };
    write_gltf(dir, name, doc, b, &[("half.png", half)])
}

#[test]
fn textured_emitters_light_the_scene_as_their_texels_say() {
    let dir = tempfile::tempdir().unwrap();
    let textured = flat(&half_lit_floor(dir.path(), true));
    let half = flat(&half_lit_floor(dir.path(), false));
    assert_eq!(textured.textured_light_count(), 2);
    for mis in [true, false] {
        let settings = RenderSettings {
            width: 16,
            height: 16,
            spp: 32,
            mis,
            ..Default::default()
        };
        // Left and right halves of the image separately: a light that emitted its mean
        // texel everywhere would light the floor more evenly.
        for (side, left) in [("left", true), ("right", false)] {
            let inside = |px: u32, _py: u32| ((px as f32) < 8.0) == left;
            let region = |scene: &RenderScene| {
                region_estimate(
                    scene,
                    &settings,
                    |x, y| (x as f32, y as f32),
                    |x, y| inside(x as u32, y as u32),
                )
            };
            assert_agree(
                &format!("floor, {side} half, mis {mis}"),
                region(&textured),
                region(&half),
                4.0,
            );
        }
    }
}

/// The quad of [`textured_quad`] with only its normal map (of strength `scale`), made of
/// `material` (glTF `pbrMetallicRoughness` and `extensions`), placed in a TOML scene under a
/// uniform white environment of radiance 1 (a white furnace) with the same camera.
fn normal_mapped_quad_in_a_furnace(dir: &Path, name: &str, material: Value, scale: f32) -> PathBuf {
    let gltf = textured_quad(dir, name, false, false, true, false);
    let mut doc: Value = serde_json::from_str(&std::fs::read_to_string(&gltf).unwrap()).unwrap();
    let normal = doc["materials"][0]["normalTexture"].clone();
    let mut m = material;
    m["normalTexture"] = normal;
    m["normalTexture"]["scale"] = json!(scale);
    doc["materials"][0] = m;
    doc["extensionsUsed"] = json!(["KHR_materials_specular"]);
    doc["extensions"] = json!({});
    doc["scenes"] = json!([{"nodes": [0]}]);
    doc["nodes"][2] = json!({"name": "no sun"});
    std::fs::write(&gltf, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    let vfov = 2.0 * (0.45f32).atan().to_degrees();
    let toml = format!(
        r#"
[camera]
eye = [0, 0, 2]
look_at = [0, 0, 0]
up = [0, 1, 0]
vfov = {vfov}
[[model]]
file = "{name}.gltf"
up = "z"
position = [0, 0, 0]
[environment]
color = [1, 1, 1]
"#
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml).unwrap();
    path
}

/// The reflectance of a white Lambertian whose shading normal is tilted by `acos(tilt_cos)`
/// from the geometric (and smooth) normal `+z`, under a uniform sky above `+z`, with the Bump
/// Map Correction: (1 / pi) times the integral of max(0, n . wi) G1(wi) over the upper
/// hemisphere (midpoint rule in cos theta_i and phi, f64).
fn bump_corrected_lambertian_furnace(tilt_cos: f64) -> f64 {
    let tilt_sin = (1.0 - tilt_cos * tilt_cos).sqrt();
    let alpha2 = ((1.0 - tilt_cos * tilt_cos) / (tilt_cos * tilt_cos) / 8.0).min(1.0);
    let (nmu, nphi) = (2000, 720);
    let mut total = 0.0;
    for i in 0..nmu {
        let mu = (i as f64 + 0.5) / nmu as f64;
        let sin = (1.0 - mu * mu).sqrt();
        let g1 = 2.0 / (1.0 + (1.0 + alpha2 * (1.0 - mu * mu) / (mu * mu)).sqrt());
        for j in 0..nphi {
            let phi = (j as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
            let cos_n = tilt_sin * sin * phi.cos() + tilt_cos * mu;
            total += cos_n.max(0.0) * g1;
        }
    }
    total * (std::f64::consts::TAU / nphi as f64) / nmu as f64 / std::f64::consts::PI
}

/// The white furnace of a normal-mapped plane: a white Lambertian (albedo 1) quad under a
/// uniform sky of radiance 1 reflects exactly 1 where its normal is not mapped and, where the
/// map tilts the shading normal by theta, the cosine about the mapped normal times Blender's
/// Bump Map Correction `G1(alpha^2, cos theta_i)` (alpha^2 = tan^2(theta) / 8) over the sky
/// above the geometric surface (wavetrace never lets a shading normal gather light from below
/// the geometric surface, nor send paths there): [`bump_corrected_lambertian_furnace`]. Never
/// more than 1: normal maps do not make energy. A white rough metal (multiscatter GGX) is 1
/// without the map and below 1 with it.
#[test]
fn normal_maps_gain_no_energy_in_a_white_furnace() {
    let dir = tempfile::tempdir().unwrap();
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: 64,
        ..Default::default()
    };
    let lambertian = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0},
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}
    });
    let metal = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 1.0,
            "roughnessFactor": 0.5}
    });
    // The tilted texel of the map, (191, 128, 238), decoded as glTF says: x and y times the
    // strength, then normalised.
    let tilt_cosine = |scale: f64| {
        let c = [191.0, 128.0, 238.0].map(|t: f64| 2.0 * t / 255.0 - 1.0);
        let m = [c[0] * scale, c[1] * scale, c[2]];
        m[2] / (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt()
    };
    for (what, material, scale) in [
        ("lambertian", &lambertian, 1.0f32),
        ("lambertian", &lambertian, 2.0),
        ("metal", &metal, 1.0),
        ("metal", &metal, 2.0),
    ] {
        let name = format!("furnace-{what}-{scale}");
        let path = normal_mapped_quad_in_a_furnace(dir.path(), &name, material.clone(), scale);
        let scene = load_scene(&path).expect("the furnace scene loads");
        let scene = flatten(&scene.world, &path).expect("flattens");
        let estimate = |quadrant: u32| {
            region_estimate(&scene, &settings, uv_of_pixel, |u, v| {
                quadrant_of(u, v) == Some(quadrant)
            })
        };
        let (tilted, tilted_error) = estimate(2);
        let (flat_mean, flat_error) = estimate(0);
        eprintln!(
            "furnace, {what}, strength {scale}: tilted {:.4} +- {:.4}, flat {:.4} +- {:.4}",
            tilted[0], tilted_error[0], flat_mean[0], flat_error[0]
        );
        for c in 0..3 {
            assert!(
                tilted[c] <= 1.0 + 4.0 * tilted_error[c],
                "{what}, strength {scale}: the normal-mapped quadrant reflects {} of 1 (+- {})",
                tilted[c],
                tilted_error[c]
            );
        }
        if what == "lambertian" {
            // Without the correction this would be (1 + cos theta) / 2 (0.9335 and 0.8282).
            let expected = bump_corrected_lambertian_furnace(tilt_cosine(scale as f64));
            assert_agree(
                &format!("furnace, lambertian, strength {scale}, tilted"),
                (tilted, tilted_error),
                ([expected; 3], [1e-6; 3]), // (f32 rounding)
                4.0,
            );
            assert_agree(
                &format!("furnace, lambertian, strength {scale}, flat"),
                (flat_mean, flat_error),
                ([1.0; 3], [1e-6; 3]),
                4.0,
            );
        } else {
            // Multiscatter GGX: the unmapped white metal is lossless (up to the albedo
            // table's interpolation, < 3e-3).
            assert_agree(
                &format!("furnace, metal, strength {scale}, flat"),
                (flat_mean, flat_error),
                ([1.0; 3], [1.5e-3; 3]),
                4.0,
            );
        }
    }
}

/// A texture shared by two slots is decoded once per encoding its slots need: an ORM image
/// (occlusion R, roughness G, metallic B) read as occlusion and metallic-roughness stays
/// linear with its channels as stored; one image read as base colour and metallic-roughness
/// is sRGB-decoded for the colour and linear for the data, two textures in the render scene.
#[test]
fn a_texture_shared_by_two_slots_is_decoded_for_each_use() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = Buffer::default();
    let mut meshes = Vec::new();
    let orm_mesh = quad(&mut b, &mut meshes, -1.0, 0.0, 0.0, false, 0);
    let shared_mesh = quad(&mut b, &mut meshes, 0.0, 1.0, 0.0, false, 1);
    let doc = json!({
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "orm", "mesh": orm_mesh}, {"name": "shared", "mesh": shared_mesh}],
        "materials": [
            {"name": "orm", "occlusionTexture": {"index": 0},
             "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0}}},
            {"name": "shared", "pbrMetallicRoughness": {
                "baseColorTexture": {"index": 1}, "metallicRoughnessTexture": {"index": 1}}}
        ],
        "meshes": meshes,
        "images": [{"uri": "orm.png"}, {"uri": "shared.png"}],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}]
    });
    // Distinct values in every channel, so that a swapped channel or a wrong transfer
    // function shows.
    let texel = [51u8, 153, 230];
    let images = [
        (
            "orm.png",
            image::RgbImage::from_pixel(2, 2, image::Rgb(texel)),
        ),
        (
            "shared.png",
            image::RgbImage::from_pixel(2, 2, image::Rgb(texel)),
        ),
    ];
    let path = write_gltf(dir.path(), "shared", doc, b, &images);
    let scene = load_scene(&path).expect("loads");
    let occlusion_warnings = scene.warnings.iter().filter(|w| w.contains("occlusion"));
    assert_eq!(occlusion_warnings.count(), 1, "{:?}", scene.warnings);
    let flat = flatten(&scene.world, &path).expect("flattens");

    let linear = texel.map(|c| c as f32 / 255.0);
    let srgb = linear.map(|c| ((c + 0.055) / 1.055).powf(2.4));
    let uv = wavetrace::math::Vec2::splat(0.5);
    let value =
        |r: &wavetrace::internals::TextureRef| flat.textures()[r.texture as usize].lookup(uv);
    let close = |got: wavetrace::math::Rgb, want: [f32; 3]| {
        (got - wavetrace::math::Rgb::from_array(want))
            .abs()
            .max_element()
            < 1e-5
    };
    // (The bare model is placed in the room, whose materials read no texture.)
    let orm = (flat.material_textures().iter())
        .find(|t| t.metallic_roughness.is_set() && !t.base_color.is_set());
    let orm = orm.expect("the ORM material");
    assert!(
        close(value(&orm.metallic_roughness), linear),
        "ORM: linear R, G, B"
    );
    let shared = flat
        .material_textures()
        .iter()
        .find(|t| t.base_color.is_set());
    let shared = shared.expect("the shared material");
    assert!(
        close(value(&shared.base_color), srgb),
        "base colour: sRGB-decoded"
    );
    assert!(
        close(value(&shared.metallic_roughness), linear),
        "metallic-roughness: linear"
    );
    assert_ne!(
        shared.base_color.texture, shared.metallic_roughness.texture,
        "one texture per encoding"
    );
    assert_eq!(flat.textures().len(), 3);
}

/// [`half_lit_floor`]'s lamp made partly transparent: `lamp` (the whole square, x in
/// [-1, 1], or its left half) with `alpha_mode` and base colour alpha `alpha_factor`, and,
/// with `alpha_texture`, a base-colour texture opaque on its left half and clear on its right
/// (sampled nearest); its emission scaled by `emission`.
fn alpha_lamp_floor(
    dir: &Path,
    name: &str,
    whole_lamp: bool,
    alpha_mode: &str,
    (alpha_factor, alpha_texture, emission): (f32, bool, f32),
) -> PathBuf {
    let source = half_lit_floor(dir, whole_lamp);
    let mut doc: Value = serde_json::from_str(&std::fs::read_to_string(&source).unwrap()).unwrap();
    let lamp = &mut doc["materials"][1];
    lamp.as_object_mut().unwrap().remove("emissiveTexture");
    lamp["emissiveFactor"] = json!([emission, emission, emission]);
    lamp["alphaMode"] = json!(alpha_mode);
    lamp["pbrMetallicRoughness"]["baseColorFactor"] = json!([0.0, 0.0, 0.0, alpha_factor]);
    if alpha_texture {
        let coverage = image::RgbaImage::from_fn(2, 1, |x, _| {
            image::Rgba([0, 0, 0, if x == 0 { 255 } else { 0 }])
        });
        coverage.save(dir.join("coverage.png")).unwrap();
        lamp["pbrMetallicRoughness"]["baseColorTexture"] = json!({"index": 0});
        doc["images"] = json!([{"uri": "coverage.png"}]);
    }
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&doc).unwrap()).unwrap();
    path
}

#[test]
fn emitters_with_alpha_emit_as_much_as_they_cover() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A lamp whose right half is cut out (MASK) or clear (BLEND) lights the floor as the
    // lamp of its left half alone; a half-transparent lamp (BLEND, alpha 0.5) as an opaque
    // one of half its emission (Cycles' mix of transparent and emission: emission x alpha).
    let half = flat(&half_lit_floor(d, false));
    let pairs = [
        (
            "mask",
            alpha_lamp_floor(d, "mask", true, "MASK", (1.0, true, 1.0)),
            &half,
        ),
        (
            "blend",
            alpha_lamp_floor(d, "blend", true, "BLEND", (1.0, true, 1.0)),
            &half,
        ),
    ];
    let dimmed = flat(&alpha_lamp_floor(
        d,
        "dim",
        false,
        "OPAQUE",
        (1.0, false, 0.5),
    ));
    let translucent = alpha_lamp_floor(d, "translucent", false, "BLEND", (0.5, false, 1.0));
    let cases = pairs
        .into_iter()
        .chain([("blend 0.5", translucent, &dimmed)]);
    for (what, path, expected) in cases {
        let lamp = flat(&path);
        for mis in [true, false] {
            let settings = RenderSettings {
                width: 16,
                height: 16,
                spp: 32,
                mis,
                ..Default::default()
            };
            for (side, left) in [("left", true), ("right", false)] {
                let region = |scene: &RenderScene| {
                    region_estimate(
                        scene,
                        &settings,
                        |x, y| (x as f32, y as f32),
                        |x, _| (x < 8.0) == left,
                    )
                };
                assert_agree(
                    &format!("{what}: floor, {side} half, mis {mis}"),
                    region(&lamp),
                    region(expected),
                    4.0,
                );
            }
        }
    }
}
