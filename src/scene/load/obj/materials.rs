//! MTL materials as wavetrace's (docs/importing.md documents the mapping): `Kd`/`map_Kd`,
//! `Ks`, `Ns`/`Pr`, `Pm`, `Ni` -> glTF metallic-roughness, `Ke` -> one-sided emitter,
//! `illum 3` or a mirror-like `Ks` with high `Ns` -> mirror, `d` below 1 -> glass of index
//! `Ni` (`Tr` is ignored, as Blender does). The MTL files are read by tobj (guarded against
//! its panics); `map_Kd` images are decoded once each.

use crate::math::Rgb;
use crate::scene::{Emitter, FresnelModel, Material};
use crate::texture::Texture;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Albedo of faces without a usable material (Blender's default grey).
pub(super) const DEFAULT_GREY: f32 = 0.8;
/// `Ks` at least this (every channel) and `Ns` at least [`MIRROR_MIN_NS`] read as a mirror.
const MIRROR_MIN_KS: f32 = 0.9;
/// See [`MIRROR_MIN_KS`] (Blender writes `Ns` 1000 for roughness 0).
const MIRROR_MIN_NS: f32 = 900.0;

/// How one MTL material appears in the world: the surface, its emission, its `map_Kd`.
pub(super) type ImportedMaterial = (Material, Option<Emitter>, Option<Arc<Texture>>);

/// Decoded `map_Kd` images by full path; `None` for one that could not be loaded.
pub(super) type TextureCache = HashMap<PathBuf, Option<Arc<Texture>>>;

/// Warns about the `mtllib` files that could not be read: with a default grey for every face
/// when none could, else naming each one that failed (tobj said nothing).
pub(super) fn warn_unread_libraries(
    path: &Path,
    libraries: &[(PathBuf, Option<tobj::LoadError>)],
    any_material: bool,
    warnings: &mut Vec<String>,
) {
    if !any_material {
        if let Some(e) = libraries.iter().find_map(|(_, e)| e.as_ref()) {
            let names: Vec<String> = libraries
                .iter()
                .map(|(p, _)| p.display().to_string())
                .collect();
            warnings.push(format!(
                "{}: cannot read material library {} ({e}); using a default grey material",
                path.display(),
                names.join(", ")
            ));
        }
    } else {
        for (library, e) in libraries {
            if let Some(e) = e {
                warnings.push(format!(
                    "{}: cannot read material library {} ({e}); faces using its materials \
                     get a default grey",
                    path.display(),
                    library.display()
                ));
            }
        }
    }
}

/// `tobj::load_mtl`, except that colour lines (`Ka`, `Kd`, `Ks`, `Ke`) with fewer than three
/// numbers are a parse error: tobj 4.0.5 panics on them (found by fuzzing).
pub(super) fn load_mtl_checked(path: &Path) -> tobj::MTLLoadResult {
    let bytes = std::fs::read(path).map_err(|_| tobj::LoadError::OpenFileFailed)?;
    let text = std::str::from_utf8(&bytes).map_err(|_| tobj::LoadError::ReadError)?;
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if matches!(words.next(), Some("Ka" | "Kd" | "Ks" | "Ke")) && words.count() < 3 {
            return Err(tobj::LoadError::MaterialParseError);
        }
    }
    tobj::load_mtl_buf(&mut text.as_bytes())
}

/// docs/importing.md's MTL mapping.
pub(super) fn import_material(
    m: &tobj::Material,
    dir: &Path,
    cache: &mut TextureCache,
    warnings: &mut Vec<String>,
) -> ImportedMaterial {
    let material = surface_of(m, warnings);
    let emitter = m
        .emissive
        .map(Rgb::from)
        .filter(|ke| ke.max_element() > 0.0)
        .map(|ke| Emitter {
            radiance: ke.max(Rgb::ZERO),
            two_sided: false,
        });
    let texture = diffuse_texture(m, dir, cache, warnings);
    (material, emitter, texture)
}

/// The surface: glass for a see-through material, a mirror for `illum 3` or a mirror-like
/// `Ks` and `Ns`, else metallic-roughness ([`metallic_roughness`]).
fn surface_of(m: &tobj::Material, warnings: &mut Vec<String>) -> Material {
    let rgb = |c: Option<[f32; 3]>| c.map(Rgb::from);
    let kd = rgb(m.diffuse).unwrap_or(Rgb::splat(DEFAULT_GREY));
    let ks = rgb(m.specular).unwrap_or(Rgb::ZERO);
    let ns = m.shininess.unwrap_or(0.0);
    let illum = m
        .illumination_model
        .unwrap_or(if ks == Rgb::ZERO { 1 } else { 2 });
    // Blender's rules: `d` (dissolve) alone says how see-through a surface is; `Tr` is
    // ignored, since exporters disagree on it (MeshLab writes `Tr 1` for opaque surfaces,
    // others `Tr 1` for invisible ones); `illum` does not make a surface transparent.
    let dissolve = m.dissolve.filter(|d| d.is_finite()).unwrap_or(1.0);
    if let Some(tr) = m
        .unknown_param
        .get("Tr")
        .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
        .filter(|&tr| tr > 0.0 && tr < 1.0 && m.dissolve.is_none())
    {
        warnings.push(format!(
            "material '{}': Tr {tr} is ignored (exporters disagree on whether Tr is \
             transparency or opacity; write d for see-through surfaces)",
            m.name
        ));
    }
    let transparent = dissolve < 1.0;
    if transparent && !matches!(illum, 4 | 6 | 7 | 9) {
        warnings.push(format!(
            "material '{}': d {dissolve} (a partly see-through surface) is approximated by \
             clear glass",
            m.name
        ));
    }
    if transparent {
        Material::Dielectric {
            ior: m.optical_density.filter(|&n| n > 0.0).unwrap_or(1.5),
            fresnel: FresnelModel::Exact,
            tint: Rgb::ONE,
        }
    } else if illum == 3 || (ks.min_element() >= MIRROR_MIN_KS && ns >= MIRROR_MIN_NS) {
        let tint = if ks.max_element() > 0.0 { ks } else { Rgb::ONE };
        Material::Mirror {
            tint: clamped(m, tint, "Ks", warnings),
        }
    } else {
        metallic_roughness(m, kd, ks, ns, warnings)
    }
}

/// A colour clamped to [0, 1], with a warning when it was outside.
fn clamped(m: &tobj::Material, c: Rgb, what: &str, warnings: &mut Vec<String>) -> Rgb {
    if c.min_element() < 0.0 || c.max_element() > 1.0 {
        warnings.push(format!(
            "material '{}': {what} {c} clamped to [0, 1]",
            m.name
        ));
    }
    c.clamp(Rgb::ZERO, Rgb::ONE)
}

/// An opaque material as glTF metallic-roughness: the PBR extension of MTL (`Pr`, `Pm`) where
/// present; else roughness from the Phong exponent, inverting Blender's export
/// `Ns = 1000 (1 - roughness)^2`.
fn metallic_roughness(
    m: &tobj::Material,
    kd: Rgb,
    ks: Rgb,
    ns: f32,
    warnings: &mut Vec<String>,
) -> Material {
    let param = |key: &str| {
        m.unknown_param
            .get(key)
            .and_then(|v| v.split_whitespace().next()?.parse::<f32>().ok())
            .filter(|x| x.is_finite())
    };
    let roughness = param("Pr")
        .unwrap_or_else(|| 1.0 - (ns.max(0.0) / 1000.0).sqrt())
        .clamp(0.0, 1.0);
    let metallic = param("Pm").unwrap_or(0.0).clamp(0.0, 1.0);
    // Blender writes Ks = Specular IOR Level (x tint), where level 0.5 is glTF's default
    // specular layer: Ks 0 is no layer (exactly Lambertian), else specular colour 2 Ks.
    let ks = clamped(m, ks, "Ks", warnings);
    Material::MetallicRoughness {
        base_color: clamped(m, kd, "Kd", warnings),
        metallic,
        roughness,
        specular: if ks == Rgb::ZERO { 0.0 } else { 1.0 },
        specular_color: 2.0 * ks,
        ior: m
            .optical_density
            .filter(|&n| n.is_finite() && n >= 1.0)
            .unwrap_or(1.5),
        transmission: 0.0,
        clearcoat: 0.0,
        clearcoat_roughness: 0.0,
        sheen_color: Rgb::ZERO,
        sheen_roughness: 0.0,
    }
}

/// The `map_Kd` texture, loaded once per file (a file that cannot be loaded is warned about
/// once per material naming it, and the material uses `Kd` alone).
fn diffuse_texture(
    m: &tobj::Material,
    dir: &Path,
    cache: &mut TextureCache,
    warnings: &mut Vec<String>,
) -> Option<Arc<Texture>> {
    let file = m.diffuse_texture.as_ref()?;
    let (file, options) = texture_file_name(file);
    if !options.is_empty() {
        warnings.push(format!(
            "material '{}': map_Kd options {} are ignored",
            m.name,
            options.join(" ")
        ));
    }
    let full = dir.join(file);
    cache
        .entry(full.clone())
        .or_insert_with(|| match load_texture(&full) {
            Ok(t) => Some(Arc::new(t)),
            Err(e) => {
                warnings.push(format!(
                    "material '{}': cannot load map_Kd '{}': {e}; using Kd alone",
                    m.name,
                    full.display()
                ));
                None
            }
        })
        .clone()
}

/// The file name of a texture statement's arguments (`-o 0 0 0 fuze uv.jpg` -> `fuze uv.jpg`:
/// names may hold spaces) and the options before it, which are not supported.
fn texture_file_name(arguments: &str) -> (&str, Vec<&str>) {
    // MTL texture options and how many values each takes.
    const OPTIONS: &[(&str, usize)] = &[
        ("-blendu", 1),
        ("-blendv", 1),
        ("-bm", 1),
        ("-boost", 1),
        ("-cc", 1),
        ("-clamp", 1),
        ("-imfchan", 1),
        ("-mm", 2),
        ("-o", 3),
        ("-s", 3),
        ("-t", 3),
        ("-texres", 1),
        ("-type", 1),
    ];
    let mut rest = arguments.trim();
    let mut options = Vec::new();
    while let Some((flag, count)) = OPTIONS.iter().find(|(flag, _)| {
        rest.strip_prefix(flag)
            .is_some_and(|r| r.starts_with(char::is_whitespace))
    }) {
        options.push(*flag);
        rest = rest[flag.len()..].trim_start();
        // -o, -s and -t take one to three numbers: only the numbers are values.
        for _ in 0..*count {
            let word_end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            let word = &rest[..word_end];
            if *count == 3 && word.parse::<f32>().is_err() {
                break;
            }
            rest = rest[word_end..].trim_start();
        }
    }
    (rest, options)
}

/// Reads an image file as an sRGB colour texture (repeat, bilinear).
fn load_texture(path: &Path) -> std::result::Result<Texture, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    let image = crate::scene::load::image_decode::decode_image_bytes(&bytes)?;
    drop(bytes);
    let (width, height) = (image.width(), image.height());
    // Grey and RGB bytes become the texture as they are; others are made RGB (an alpha
    // channel is not the OBJ material's: that is `map_d`).
    let (channels, texels) = match image {
        image::DynamicImage::ImageLuma8(grey) => (1, grey.into_raw()),
        other => (3, other.into_rgb8().into_raw()),
    };
    Texture::from_srgb8(width, height, channels, texels)
        .ok_or_else(|| "the image is empty".to_string())
}
