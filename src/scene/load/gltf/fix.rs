//! Permissive reading of glTF JSON: what the glTF specification allows but `gltf-json`'s strict
//! deserialiser refuses is patched in the JSON tree before it is deserialised, and each feature
//! the importer ignores or approximates is named in one warning per file and feature.
//!
//! Patches (the file stays valid glTF; only data wavetrace does not use is dropped): a scene
//! without `nodes` gets an empty list; animations (including `KHR_animation_pointer` channels,
//! which have no `node`) are removed (`animation.rs` reads them on its own); morph targets
//! that name an accessor the file does not have are removed with a warning; application-specific
//! attributes (`_PRESSURE`, any name starting with `_`) are removed with a warning; a primitive
//! that names an accessor the file does not have is removed with a warning; a texture's image is
//! chosen among its sources (`EXT_texture_webp`, the core `source`, `KHR_texture_basisu`).

use super::check;
use super::materials::bounds_a_volume;
use crate::error::{Error, Result};
use gltf::json::Value;
use std::collections::BTreeMap;
use std::path::Path;

/// Extensions the importer reads or whose absence has a defined fallback (so a file may
/// require them): the others in `extensionsRequired` make the file an error.
pub(super) const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_texture_transform",
    "KHR_texture_basisu",
    "KHR_mesh_quantization",
    "EXT_mesh_gpu_instancing",
    "EXT_texture_webp",
    "EXT_meshopt_compression",
    "KHR_meshopt_compression",
];

/// Extensions handled or warned about by name elsewhere: not reported as unknown.
const KNOWN: &[&str] = &[
    // Used without being required, this leaves uncompressed data that the importer reads.
    "KHR_draco_mesh_compression",
    "KHR_animation_pointer",
    "KHR_materials_clearcoat",
    "KHR_materials_sheen",
    "KHR_materials_volume",
    "KHR_materials_iridescence",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
];

/// Parses the JSON of a glTF file (the JSON chunk of a GLB) into a `gltf-json` root,
/// patching what the specification allows and the deserialiser refuses; `warnings` receives
/// one line per dropped feature.
pub(super) fn parse_root(
    path: &Path,
    json: &[u8],
    in_glb: bool,
    warnings: &mut Vec<String>,
) -> Result<gltf::json::Root> {
    let mut value: Value = gltf::json::deserialize::from_slice(json)
        .map_err(|e| check::json_error(path, json, in_glb, &e))?;
    if !value.is_object() {
        return Err(Error::input(
            path,
            None,
            "invalid glTF: the JSON is not an object",
        ));
    }
    patch(path, &mut value, warnings);
    gltf::json::deserialize::from_value(value).map_err(|e| {
        // The patched tree has no lines: parse the original text again for the location.
        match gltf::json::deserialize::from_slice::<gltf::json::Root>(json) {
            Err(located) => check::json_error(path, json, in_glb, &located),
            Ok(_) => Error::input(path, None, format!("invalid glTF: {e}")),
        }
    })
}

fn array_len(v: &Value) -> usize {
    v.as_array().map_or(0, Vec::len)
}

/// The patches of the module documentation, in place.
fn patch(path: &Path, root: &mut Value, warnings: &mut Vec<String>) {
    let file = path.display();
    if let Some(scenes) = root.get_mut("scenes").and_then(Value::as_array_mut) {
        for scene in scenes.iter_mut().filter_map(Value::as_object_mut) {
            scene
                .entry("nodes")
                .or_insert_with(|| Value::Array(Vec::new()));
        }
    }
    let object = root.as_object_mut().expect("checked by the caller");
    // Animation hook: the strict reader refuses valid animations (pointer channels have no
    // node) and a malformed one would refuse the file; `animation.rs` reads them from the
    // JSON instead, channel by channel, and warns about what it skips.
    object.remove("animations");
    let accessor_count = object.get("accessors").map_or(0, array_len);
    let mut app_attributes = BTreeMap::<String, usize>::new();
    let mut bad_targets = 0usize;
    if let Some(meshes) = object.get_mut("meshes").and_then(Value::as_array_mut) {
        for (m, mesh) in meshes.iter_mut().enumerate() {
            let mesh_name = match mesh.get("name").and_then(Value::as_str) {
                Some(n) => format!("mesh '{n}' (index {m})"),
                None => format!("mesh {m}"),
            };
            let Some(primitives) = mesh.get_mut("primitives").and_then(Value::as_array_mut) else {
                continue;
            };
            let mut p = 0usize;
            primitives.retain_mut(|primitive| {
                let index = p;
                p += 1;
                let Some(primitive) = primitive.as_object_mut() else {
                    return true;
                };
                let target_accessors = primitive
                    .get("targets")
                    .and_then(Value::as_array)
                    .into_iter()
                    .flatten()
                    .filter_map(Value::as_object)
                    .flat_map(|t| t.values());
                if target_accessors
                    .filter_map(Value::as_u64)
                    .any(|a| a as usize >= accessor_count)
                {
                    primitive.remove("targets");
                    bad_targets += 1;
                }
                if let Some(attributes) = primitive
                    .get_mut("attributes")
                    .and_then(Value::as_object_mut)
                {
                    attributes.retain(|name, _| {
                        let application = name.starts_with('_');
                        if application {
                            *app_attributes.entry(name.clone()).or_default() += 1;
                        }
                        !application
                    });
                }
                let named = primitive
                    .get("attributes")
                    .and_then(Value::as_object)
                    .into_iter()
                    .flat_map(|a| a.values())
                    .chain(primitive.get("indices"));
                let missing = named
                    .filter_map(Value::as_u64)
                    .find(|&a| a as usize >= accessor_count);
                if let Some(bad) = missing {
                    warnings.push(format!(
                        "{file}:{mesh_name}, primitive {index}: accessor {bad} does not exist \
                         (the file has {accessor_count}); the primitive is skipped"
                    ));
                    return false;
                }
                true
            });
        }
    }
    if !app_attributes.is_empty() {
        let names: Vec<String> = app_attributes.keys().cloned().collect();
        warnings.push(format!(
            "{file}: application-specific vertex attributes are ignored ({})",
            names.join(", ")
        ));
    }
    if bad_targets > 0 {
        warnings.push(format!(
            "{file}: morph targets that name accessors the file does not have are ignored \
             ({bad_targets} primitive{})",
            plural(bad_targets)
        ));
    }
    choose_texture_sources(root);
}

/// A texture's `source` becomes the image wavetrace can best decode: the `EXT_texture_webp`
/// image, else the core (PNG/JPEG) source, else the `KHR_texture_basisu` (KTX2) one, whose
/// decoding then fails with a warning that names the format.
fn choose_texture_sources(root: &mut Value) {
    let Some(textures) = root.get_mut("textures").and_then(Value::as_array_mut) else {
        return;
    };
    for texture in textures.iter_mut().filter_map(Value::as_object_mut) {
        let from_extension = |name: &str| {
            texture
                .get("extensions")
                .and_then(|e| e.get(name))
                .and_then(|e| e.get("source"))
                .cloned()
        };
        let chosen = from_extension("EXT_texture_webp")
            .or_else(|| texture.get("source").cloned())
            .or_else(|| from_extension("KHR_texture_basisu"));
        if let Some(source) = chosen {
            texture.insert("source".to_string(), source);
        }
    }
}

/// "s" for counts other than one.
pub(super) fn plural(n: usize) -> &'static str {
    if n == 1 { "" } else { "s" }
}

/// One warning per feature the file uses that the importer ignores or approximates (the
/// material-level ones are counted over the materials meshes use or not alike).
pub(super) fn survey(path: &Path, document: &gltf::Document, warnings: &mut Vec<String>) {
    let materials: Vec<gltf::Material> = document.materials().collect();
    survey_material_features(path, &materials, warnings);
    survey_anisotropy(path, &materials, warnings);
    let ignored = ignored_material_extensions(&materials);
    for (name, n) in &ignored {
        warn_count(
            path,
            warnings,
            &format!("{name} is ignored"),
            *n,
            "material",
        );
    }
    let primitives: Vec<gltf::Primitive> = document.meshes().flat_map(|m| m.primitives()).collect();
    warn_count(
        path,
        warnings,
        "KHR_materials_variants is ignored: the default materials are shown",
        primitives
            .iter()
            .filter(|p| p.extension_value("KHR_materials_variants").is_some())
            .count(),
        "primitive",
    );
    let file = path.display();
    for name in document.extensions_used() {
        if !SUPPORTED_REQUIRED.contains(&name)
            && !KNOWN.contains(&name)
            && !ignored.contains_key(name)
        {
            warnings.push(format!(
                "{file}: the extension {name} is not supported; ignored"
            ));
        }
    }
}

/// "file: what (n units)", when `n` is not zero.
fn warn_count(path: &Path, warnings: &mut Vec<String>, what: &str, n: usize, unit: &str) {
    if n > 0 {
        let file = path.display();
        warnings.push(format!("{file}: {what} ({n} {unit}{})", plural(n)));
    }
}

/// The warnings about material features that are read only in part: occlusion maps, the
/// textures of clearcoat and sheen, clearcoat over emission, thin-walled volumes' attenuation
/// and volumes' thickness textures.
fn survey_material_features(path: &Path, materials: &[gltf::Material], warnings: &mut Vec<String>) {
    iridescence_checks(path, materials, warnings);
    let mut count = |what: &str, n: usize| warn_count(path, warnings, what, n, "material");
    count(
        "occlusion maps are ignored",
        materials
            .iter()
            .filter(|m| m.occlusion_texture().is_some())
            .count(),
    );
    let with_keys = |extension: &str, keys: &[&str]| {
        materials
            .iter()
            .filter(|m| {
                m.extension_value(extension)
                    .is_some_and(|e| keys.iter().any(|k| e.get(*k).is_some()))
            })
            .count()
    };
    count(
        "KHR_materials_clearcoat does not darken emission (the specification scales it by \
         1 - clearcoat * Fresnel)",
        materials
            .iter()
            .filter(|m| {
                m.emissive_factor().iter().any(|&e| e > 0.0)
                    && m.extension_value("KHR_materials_clearcoat")
                        .and_then(|e| e["clearcoatFactor"].as_f64())
                        .is_some_and(|c| c > 0.0)
            })
            .count(),
    );
    count(
        "KHR_materials_transmission textures (transmissionTexture) are ignored: the factor \
         applies everywhere",
        with_keys("KHR_materials_transmission", &["transmissionTexture"]),
    );
    let volumes = || {
        materials
            .iter()
            .filter_map(|m| m.extension_value("KHR_materials_volume"))
    };
    count(
        "KHR_materials_volume without thicknessFactor is thin-walled (the specification's \
         default): its attenuation is not applied",
        volumes()
            .filter(|v| {
                !bounds_a_volume(v)
                    && v["attenuationColor"]
                        .as_array()
                        .is_some_and(|c| c.iter().any(|x| x.as_f64().is_some_and(|x| x < 1.0)))
            })
            .count(),
    );
    count(
        "KHR_materials_volume thicknessTexture is ignored: the path tracer measures the \
         distance travelled inside the object",
        volumes()
            .filter(|v| bounds_a_volume(v) && v.get("thicknessTexture").is_some())
            .count(),
    );
}

/// One warning for the `KHR_materials_iridescence` values the specification does not allow,
/// naming the materials (the loader's fallbacks, `gltf/materials.rs`): an inverted thickness
/// range (used as written), a negative thickness (0), an index that is not positive (1.3).
fn iridescence_checks(path: &Path, materials: &[gltf::Material], warnings: &mut Vec<String>) {
    let mut bad = Vec::new();
    for (i, m) in materials.iter().enumerate() {
        let Some(film) = m.extension_value("KHR_materials_iridescence") else {
            continue;
        };
        let number = |key: &str| film[key].as_f64();
        let (minimum, maximum) = (
            number("iridescenceThicknessMinimum").unwrap_or(100.0),
            number("iridescenceThicknessMaximum").unwrap_or(400.0),
        );
        let mut problems = Vec::new();
        if minimum > maximum {
            problems.push("thickness minimum above maximum (used as written)");
        }
        if minimum < 0.0 || maximum < 0.0 {
            problems.push("negative thickness (taken as 0)");
        }
        if number("iridescenceIor").is_some_and(|ior| ior <= 0.0) {
            problems.push("iridescenceIor not positive (taken as 1.3)");
        }
        if !problems.is_empty() {
            let name = m
                .name()
                .map_or_else(|| format!("#{i}"), |n| format!("'{n}'"));
            bad.push(format!("{name}: {}", problems.join(", ")));
        }
    }
    if !bad.is_empty() {
        warnings.push(format!(
            "{}: KHR_materials_iridescence values out of range in {} material{}: {}",
            path.display(),
            bad.len(),
            plural(bad.len()),
            bad.join("; ")
        ));
    }
}

/// Material extensions wavetrace neither reads nor knows to be harmless, with the number of
/// materials that use each.
/// One warning for the materials whose `anisotropyStrength` lies outside [0, 1] (or is not
/// a number): clamped (`gltf/materials.rs`), the first one named.
fn survey_anisotropy(path: &Path, materials: &[gltf::Material], warnings: &mut Vec<String>) {
    let out_of_range: Vec<&gltf::Material> = materials
        .iter()
        .filter(|m| {
            m.extension_value("KHR_materials_anisotropy")
                .and_then(|e| e.get("anisotropyStrength"))
                .is_some_and(|s| !s.as_f64().is_some_and(|s| (0.0..=1.0).contains(&s)))
        })
        .collect();
    if let Some(first) = out_of_range.first() {
        let name = first.name().unwrap_or("unnamed");
        warn_count(
            path,
            warnings,
            &format!(
                "KHR_materials_anisotropy anisotropyStrength outside [0, 1] is clamped \
                 (material '{name}')"
            ),
            out_of_range.len(),
            "material",
        );
    }
}

fn ignored_material_extensions(materials: &[gltf::Material]) -> BTreeMap<String, usize> {
    let handled = [
        "KHR_materials_clearcoat",
        "KHR_materials_sheen",
        "KHR_materials_emissive_strength",
        "KHR_materials_ior",
        "KHR_materials_specular",
        "KHR_materials_transmission",
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_materials_unlit",
        "KHR_materials_variants",
        "KHR_materials_volume",
        "KHR_materials_iridescence",
        "KHR_materials_anisotropy",
    ];
    let mut ignored = BTreeMap::<String, usize>::new();
    for m in materials {
        for name in m.extensions().into_iter().flat_map(|e| e.keys()) {
            if !handled.contains(&name.as_str()) {
                *ignored.entry(name.clone()).or_default() += 1;
            }
        }
    }
    ignored
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(json: &str) -> (gltf::json::Root, Vec<String>) {
        let mut warnings = Vec::new();
        let root =
            parse_root(Path::new("m.gltf"), json.as_bytes(), false, &mut warnings).expect("parses");
        (root, warnings)
    }

    #[test]
    fn scenes_without_nodes_and_application_attributes_parse() {
        let (root, warnings) = parse(
            r#"{"asset": {"version": "2.0"}, "scenes": [{}],
                "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3"}],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "_PRESSURE": 0}}]}]}"#,
        );
        assert!(root.scenes[0].nodes.is_empty());
        assert_eq!(root.meshes[0].primitives[0].attributes.len(), 1);
        assert_eq!(
            warnings,
            ["m.gltf: application-specific vertex attributes are ignored (_PRESSURE)"]
        );
    }

    #[test]
    fn animations_are_left_to_the_animation_reader() {
        let (root, warnings) = parse(
            r#"{"asset": {"version": "2.0"},
                "animations": [{"channels": [{"sampler": 0, "target": {"path": "pointer",
                  "extensions": {"KHR_animation_pointer": {"pointer": "/materials/0"}}}}],
                  "samplers": [{"input": 0, "output": 0}]}, {"channels": [], "samplers": []}]}"#,
        );
        assert!(root.animations.is_empty());
        assert!(warnings.is_empty(), "{warnings:?}");
    }

    #[test]
    fn primitives_with_missing_accessors_are_dropped_alone() {
        let (root, warnings) = parse(
            r#"{"asset": {"version": "2.0"},
                "accessors": [{"componentType": 5126, "count": 3, "type": "VEC3"}],
                "meshes": [{"name": "m", "primitives": [{"attributes": {"POSITION": 7}},
                  {"attributes": {"POSITION": 0}}]}]}"#,
        );
        assert_eq!(root.meshes[0].primitives.len(), 1);
        assert_eq!(warnings.len(), 1);
        assert!(
            warnings[0].contains("mesh 'm' (index 0), primitive 0: accessor 7 does not exist"),
            "{warnings:?}"
        );
    }

    #[test]
    fn webp_sources_win_and_basisu_is_the_last_resort() {
        let (root, _) = parse(
            r#"{"asset": {"version": "2.0"}, "images": [{"uri": "a.png"}, {"uri": "b.webp"},
                  {"uri": "c.ktx2"}],
                "textures": [
                  {"source": 0, "extensions": {"EXT_texture_webp": {"source": 1}}},
                  {"source": 0, "extensions": {"KHR_texture_basisu": {"source": 2}}},
                  {"extensions": {"KHR_texture_basisu": {"source": 2}}}]}"#,
        );
        let sources: Vec<usize> = root.textures.iter().map(|t| t.source.value()).collect();
        assert_eq!(sources, [1, 0, 2]);
    }
}
