//! glTF materials as wavetrace's (docs/importing.md documents the mapping): every material
//! becomes [`Material::MetallicRoughness`] with the file's factors (and
//! `KHR_materials_specular`, `_ior`, `_transmission`, `_clearcoat`, `_sheen`; a
//! `KHR_materials_pbrSpecularGlossiness` material converted), `KHR_materials_unlit` a
//! [`Material::Unlit`], its emission an [`Emitter`], its alpha mode an [`AlphaCoverage`], its
//! `KHR_materials_volume` a [`Volume`], and its textures a [`MaterialTextures`] (decoded by
//! `textures.rs`) read through one UV set.

use super::textures::{
    TextureTable, coat_normal_texture_info, film_texture_infos, info_slot, layer_texture_infos,
    raw_info_slot, raw_uv_transform, spec_gloss_diffuse_texture, texture_slot,
};
use crate::bsdf::AnisotropyMapping;
use crate::math::Rgb;
use crate::scene::{
    AlphaCoverage, AlphaMode, Emitter, Iridescence, Material, MaterialAnisotropy, MaterialTextures,
    Volume,
};
use crate::texture::Encoding;

/// Base colour of primitives without a material (Blender's importer default).
const DEFAULT_GREY: f32 = 0.8;
/// Roughness of primitives without a material (Blender's Principled BSDF default).
const DEFAULT_ROUGHNESS: f32 = 0.5;
/// F0 of dielectrics in the specular-glossiness to metallic-roughness conversion.
const DIELECTRIC_F0: f32 = 0.04;

/// The absorbing medium of `KHR_materials_volume` (`attenuationColor`, default white, and
/// `attenuationDistance`, default infinite), only where the surface bounds a volume:
/// `thicknessFactor` above 0. At its default 0 the material is thin-walled (the
/// specification's rule, and Blender's importer adds no Volume Absorption then): light crosses
/// the wall without travelling inside anything, so nothing is absorbed. The thickness itself
/// is not needed by a path tracer, which measures the path inside the object (`fix.rs` warns
/// once about thin-walled attenuation and about `thicknessTexture`).
fn volume_of(m: &gltf::Material) -> Option<Volume> {
    let volume = m.extension_value("KHR_materials_volume")?;
    if !bounds_a_volume(volume) {
        return None;
    }
    let channel = |i: usize| {
        let c = volume["attenuationColor"][i]
            .as_f64()
            .map_or(1.0, |x| x as f32);
        if c.is_finite() { c } else { 1.0 }
    };
    let distance = volume["attenuationDistance"]
        .as_f64()
        .map_or(f32::INFINITY, |d| d as f32);
    Volume::from_attenuation(Rgb::new(channel(0), channel(1), channel(2)), distance)
}

/// The film's index and thicknesses (nm) when `KHR_materials_iridescence` leaves them out.
const IRIDESCENCE_DEFAULTS: (f32, f32, f32) = (1.3, 100.0, 400.0);

/// `KHR_materials_iridescence` (factor 0 or absent: none). Values the specification does not
/// allow fall back (`fix.rs` warns once per file, naming the materials): a factor outside
/// [0, 1] is clamped, an index that is not positive and finite is the default 1.3, a negative
/// or non-finite thickness is 0 (no film there). An inverted range (minimum above maximum) is
/// used as written, as the Khronos sample viewer does: the thickness texture's green still maps
/// 0 to the minimum and 1 to the maximum.
fn iridescence_of(m: &gltf::Material) -> Option<Iridescence> {
    let film = m.extension_value("KHR_materials_iridescence")?;
    let (default_ior, default_minimum, default_maximum) = IRIDESCENCE_DEFAULTS;
    let number = |key: &str, default: f32| film[key].as_f64().map_or(default, |x| x as f32);
    let thickness = |key: &str, default: f32| {
        let t = number(key, default);
        if t.is_finite() { t.max(0.0) } else { 0.0 }
    };
    let ior = number("iridescenceIor", default_ior);
    let iridescence = Iridescence {
        factor: unit(number("iridescenceFactor", 0.0)),
        ior: if ior.is_finite() && ior > 0.0 {
            ior
        } else {
            default_ior
        },
        thickness_minimum: thickness("iridescenceThicknessMinimum", default_minimum),
        thickness_maximum: thickness("iridescenceThicknessMaximum", default_maximum),
    };
    (iridescence.factor > 0.0).then_some(iridescence)
}

/// Whether a `KHR_materials_volume` object makes its surface a volume boundary:
/// `thicknessFactor` (default 0, thin-walled) positive and finite.
pub(super) fn bounds_a_volume(volume: &gltf::json::Value) -> bool {
    volume["thicknessFactor"]
        .as_f64()
        .is_some_and(|t| t.is_finite() && t > 0.0)
}

/// How one glTF material appears in the world.
pub(super) struct ImportedMaterial {
    pub(super) material: Material,
    pub(super) emitter: Option<Emitter>,
    pub(super) textures: MaterialTextures,
    /// Texture coordinate set (`TEXCOORD_n`) the textures read, if any texture is used.
    pub(super) uv_set: Option<u32>,
    /// `alphaMode` MASK or BLEND; `None` for OPAQUE.
    pub(super) alpha: Option<AlphaCoverage>,
    /// `KHR_materials_volume`'s absorbing medium, if it absorbs anything.
    pub(super) volume: Option<Volume>,
    /// `KHR_materials_iridescence`'s thin film, if its factor is above 0.
    pub(super) iridescence: Option<Iridescence>,
}

impl ImportedMaterial {
    /// The material of primitives without one: not glTF's default material (white metal,
    /// roughness 1, which Cycles users know as grey plastic) but what Blender's importer
    /// gives, a grey dielectric.
    pub(super) fn blender_default() -> ImportedMaterial {
        ImportedMaterial {
            material: Material::MetallicRoughness {
                base_color: Rgb::splat(DEFAULT_GREY),
                metallic: 0.0,
                roughness: DEFAULT_ROUGHNESS,
                specular: 1.0,
                specular_color: Rgb::ONE,
                ior: 1.5,
                transmission: 0.0,
                clearcoat: 0.0,
                clearcoat_roughness: 0.0,
                sheen_color: Rgb::ZERO,
                sheen_roughness: 0.0,
            },
            emitter: None,
            textures: MaterialTextures::default(),
            uv_set: None,
            alpha: None,
            volume: None,
            iridescence: None,
        }
    }
}

/// docs/importing.md's mapping from a glTF PBR material to wavetrace's.
///
/// `mapping` is the anisotropy's: Cycles' for files Blender wrote, else glTF's.
pub(super) fn import_material(
    m: &gltf::Material,
    textures: &TextureTable,
    mapping: AnisotropyMapping,
    warnings: &mut Vec<String>,
) -> ImportedMaterial {
    let spec_gloss = m.extension_value("KHR_materials_pbrSpecularGlossiness");
    let (base, metallic, roughness) = base_metallic_roughness(m, spec_gloss);
    let (mut surface, mut uv_set) = material_textures(m, spec_gloss, textures, warnings);
    surface.anisotropy = anisotropy_of(m, textures, mapping, &mut uv_set, warnings);
    let textures = surface;
    let alpha = alpha_coverage(m);
    if m.extension_value("KHR_materials_unlit").is_some() {
        // Unlit: base colour, its texture, vertex colours and alpha only; everything about
        // lighting (metal, roughness, normal map, emission) is ignored, as the extension says.
        return ImportedMaterial {
            material: Material::Unlit { color: base },
            emitter: None,
            textures: MaterialTextures {
                base_color: textures.base_color,
                ..MaterialTextures::default()
            },
            uv_set,
            alpha,
            volume: None,
            iridescence: None,
        };
    }
    ImportedMaterial {
        material: metallic_roughness(m, base, metallic, roughness),
        emitter: emitter_of(m),
        textures,
        uv_set,
        alpha,
        volume: volume_of(m),
        iridescence: iridescence_of(m),
    }
}

/// A factor clamped to [0, 1]; a factor that is not finite is 0.
fn unit(x: f32) -> f32 {
    if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// `alphaMode` MASK or BLEND, with the base colour factor's alpha; `None` for OPAQUE.
fn alpha_coverage(m: &gltf::Material) -> Option<AlphaCoverage> {
    let alpha_factor = m.pbr_metallic_roughness().base_color_factor()[3];
    let factor = if alpha_factor.is_finite() {
        alpha_factor.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let mode = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => return None,
        gltf::material::AlphaMode::Mask => AlphaMode::Mask {
            cutoff: m.alpha_cutoff().filter(|c| c.is_finite()).unwrap_or(0.5),
        },
        gltf::material::AlphaMode::Blend => AlphaMode::Blend,
    };
    Some(AlphaCoverage { mode, factor })
}

/// Base colour, metallic and roughness: the metallic-roughness factors, or a
/// specular-glossiness material's converted ([`metallic_from_specular`]).
fn base_metallic_roughness(
    m: &gltf::Material,
    spec_gloss: Option<&gltf::json::Value>,
) -> (Rgb, f32, f32) {
    let pbr = m.pbr_metallic_roughness();
    let Some(sg) = spec_gloss else {
        let [r, g, b, _] = pbr.base_color_factor();
        let base = Rgb::new(r, g, b).clamp(Rgb::ZERO, Rgb::ONE);
        return (
            base,
            unit(pbr.metallic_factor()),
            unit(pbr.roughness_factor()),
        );
    };
    let factor =
        |key: &str, default: f32, i: usize| sg[key][i].as_f64().map_or(default, |x| x as f32);
    let diffuse = Rgb::new(
        factor("diffuseFactor", 1.0, 0),
        factor("diffuseFactor", 1.0, 1),
        factor("diffuseFactor", 1.0, 2),
    );
    let specular = Rgb::new(
        factor("specularFactor", 1.0, 0),
        factor("specularFactor", 1.0, 1),
        factor("specularFactor", 1.0, 2),
    );
    let glossiness = sg["glossinessFactor"].as_f64().map_or(1.0, |x| x as f32);
    let (base, metallic) = metallic_from_specular(
        diffuse.clamp(Rgb::ZERO, Rgb::ONE),
        specular.clamp(Rgb::ZERO, Rgb::ONE),
    );
    (base, metallic, 1.0 - unit(glossiness))
}

/// glTF 2.0 metallic-roughness as the specification defines it, with the factors of
/// `KHR_materials_specular`, `_ior`, `_transmission`, `_clearcoat` and `_sheen`; `flatten`
/// resolves the exact special cases (Lambertian, smooth glass, mirror) from these values.
fn metallic_roughness(m: &gltf::Material, base: Rgb, metallic: f32, roughness: f32) -> Material {
    let specular = m.specular();
    Material::MetallicRoughness {
        base_color: base,
        metallic,
        roughness,
        specular: specular.as_ref().map_or(1.0, |s| unit(s.specular_factor())),
        specular_color: specular
            .as_ref()
            .map_or(Rgb::ONE, |s| Rgb::from(s.specular_color_factor()))
            .max(Rgb::ZERO),
        // Blender omits KHR_materials_ior at glTF's default 1.5.
        ior: m
            .ior()
            .filter(|i| i.is_finite() && *i >= 1.0)
            .unwrap_or(1.5),
        transmission: unit(m.transmission().map_or(0.0, |t| t.transmission_factor())),
        clearcoat: unit(extension_number(
            m,
            "KHR_materials_clearcoat",
            "clearcoatFactor",
        )),
        clearcoat_roughness: unit(extension_number(
            m,
            "KHR_materials_clearcoat",
            "clearcoatRoughnessFactor",
        )),
        sheen_color: match m.extension_value("KHR_materials_sheen") {
            Some(sheen) => {
                let channel = |i: usize| {
                    unit(
                        sheen["sheenColorFactor"][i]
                            .as_f64()
                            .map_or(0.0, |x| x as f32),
                    )
                };
                Rgb::new(channel(0), channel(1), channel(2))
            }
            None => Rgb::ZERO,
        },
        sheen_roughness: unit(extension_number(
            m,
            "KHR_materials_sheen",
            "sheenRoughnessFactor",
        )),
    }
}

/// The emission (`emissiveFactor` times `KHR_materials_emissive_strength`), if any.
fn emitter_of(m: &gltf::Material) -> Option<Emitter> {
    let strength = m.emissive_strength().unwrap_or(1.0);
    let radiance = Rgb::from(m.emissive_factor()) * strength;
    (radiance.max_element() > 0.0).then_some(Emitter {
        radiance,
        two_sided: m.double_sided(),
    })
}

/// The material's textures and the UV set they read. A mesh has one set of texture
/// coordinates, so all of a material's textures must read the same `TEXCOORD_n`: a texture
/// reading another is ignored with a warning.
fn material_textures(
    m: &gltf::Material,
    spec_gloss: Option<&gltf::json::Value>,
    textures: &TextureTable,
    warnings: &mut Vec<String>,
) -> (MaterialTextures, Option<u32>) {
    let name = m.name().unwrap_or("unnamed");
    let pbr = m.pbr_metallic_roughness();
    let normal = m.normal_texture();
    let specular = m.specular();
    let [clearcoat, clearcoat_roughness, sheen_color, sheen_roughness] = layer_texture_infos(m);
    let [iridescence, iridescence_thickness] = film_texture_infos(m);
    let coat_normal = coat_normal_texture_info(m);
    let (base_color_slot, metallic_roughness_slot) = match spec_gloss {
        // The diffuse texture stands for the base colour; the specular-glossiness texture
        // has no metallic-roughness equivalent texel by texel (warned once per file).
        Some(sg) => (
            spec_gloss_diffuse_texture(m).and_then(|index| {
                let tex_coord = sg["diffuseTexture"]["texCoord"].as_u64().unwrap_or(0) as u32;
                let transform = sg["diffuseTexture"]["extensions"]
                    .get("KHR_texture_transform")
                    .map(raw_uv_transform);
                texture_slot(textures, index, Encoding::Srgb, tex_coord, transform)
            }),
            None,
        ),
        None => (
            info_slot(textures, pbr.base_color_texture(), Encoding::Srgb),
            info_slot(textures, pbr.metallic_roughness_texture(), Encoding::Linear),
        ),
    };
    let slots = [
        base_color_slot,
        metallic_roughness_slot,
        normal.as_ref().and_then(|n| {
            texture_slot(
                textures,
                n.texture().index(),
                Encoding::Linear,
                n.tex_coord(),
                n.extension_value("KHR_texture_transform")
                    .map(raw_uv_transform),
            )
        }),
        info_slot(textures, m.emissive_texture(), Encoding::Srgb),
        specular
            .as_ref()
            .and_then(|s| info_slot(textures, s.specular_texture(), Encoding::Linear)),
        specular
            .as_ref()
            .and_then(|s| info_slot(textures, s.specular_color_texture(), Encoding::Srgb)),
        raw_info_slot(textures, clearcoat.0, clearcoat.1),
        raw_info_slot(textures, clearcoat_roughness.0, clearcoat_roughness.1),
        raw_info_slot(textures, sheen_color.0, sheen_color.1),
        raw_info_slot(textures, sheen_roughness.0, sheen_roughness.1),
        raw_info_slot(textures, iridescence.0, iridescence.1),
        raw_info_slot(textures, iridescence_thickness.0, iridescence_thickness.1),
        raw_info_slot(textures, coat_normal, Encoding::Linear),
    ];
    let uv_set = slots.iter().flatten().map(|(_, set)| *set).next();
    let [
        base_color,
        metallic_roughness,
        normal_map,
        emissive,
        specular_map,
        specular_color_map,
        clearcoat_map,
        clearcoat_roughness_map,
        sheen_color_map,
        sheen_roughness_map,
        iridescence_map,
        iridescence_thickness_map,
        coat_normal_map,
    ] = slots.map(|slot| {
        let (slot, set) = slot?;
        if Some(set) != uv_set {
            warnings.push(format!(
                "material '{name}': a texture reads TEXCOORD_{set} while another reads \
                 TEXCOORD_{}; only one set is supported, the texture is ignored",
                uv_set.unwrap_or(0)
            ));
            return None;
        }
        Some(slot)
    });
    let textures = MaterialTextures {
        base_color,
        metallic_roughness,
        normal: normal_map,
        normal_scale: normal.map_or(1.0, |n| n.scale()),
        emissive,
        specular: specular_map,
        specular_color: specular_color_map,
        clearcoat: clearcoat_map,
        clearcoat_roughness: clearcoat_roughness_map,
        sheen_color: sheen_color_map,
        sheen_roughness: sheen_roughness_map,
        iridescence: iridescence_map,
        iridescence_thickness: iridescence_thickness_map,
        clearcoat_normal: coat_normal_map,
        clearcoat_normal_scale: coat_normal
            .and_then(|info| info["scale"].as_f64())
            .map_or(1.0, |s| s as f32),
        anisotropy: None,
    };
    (textures, uv_set)
}

/// `KHR_materials_anisotropy`: strength (clamped to [0, 1]; `fix.rs` warns), rotation and
/// texture, which must read the material's UV set (else it is ignored with a warning, as
/// other textures are) and sets it if no other texture does. Without any texture the set is
/// `TEXCOORD_0`, whose coordinates give the tangent frame where the file has no `TANGENT`.
/// `None` without the extension.
fn anisotropy_of(
    m: &gltf::Material,
    textures: &TextureTable,
    mapping: AnisotropyMapping,
    uv_set: &mut Option<u32>,
    warnings: &mut Vec<String>,
) -> Option<MaterialAnisotropy> {
    let extension = m.extension_value("KHR_materials_anisotropy")?;
    let rotation = extension["anisotropyRotation"].as_f64().unwrap_or(0.0) as f32;
    let texture = raw_info_slot(
        textures,
        extension.get("anisotropyTexture"),
        Encoding::Linear,
    )
    .and_then(|(slot, set)| {
        if uv_set.is_some_and(|s| s != set) {
            warnings.push(format!(
                "material '{}': the anisotropy texture reads TEXCOORD_{set} while another \
                     reads TEXCOORD_{}; only one set is supported, the texture is ignored",
                m.name().unwrap_or("unnamed"),
                uv_set.unwrap_or(0)
            ));
            return None;
        }
        *uv_set = Some(set);
        Some(slot)
    });
    uv_set.get_or_insert(0);
    Some(MaterialAnisotropy {
        strength: unit(extension_number(
            m,
            "KHR_materials_anisotropy",
            "anisotropyStrength",
        )),
        rotation: if rotation.is_finite() { rotation } else { 0.0 },
        mapping,
        texture,
    })
}

/// A number of a material extension (glTF's default 0 when absent; callers clamp it).
fn extension_number(m: &gltf::Material, extension: &str, key: &str) -> f32 {
    m.extension_value(extension)
        .and_then(|e| e[key].as_f64())
        .map_or(0.0, |x| x as f32)
}

/// Perceived brightness of a colour (the weights of the conversion's reference).
fn perceived_brightness(c: Rgb) -> f32 {
    (0.299 * c.x * c.x + 0.587 * c.y * c.y + 0.114 * c.z * c.z).sqrt()
}

/// Base colour and metallic from specular-glossiness diffuse and specular colours: the
/// conversion of the Khronos glTF sample viewer and Babylon.js (documented in
/// docs/importing.md). Metallic solves, in perceived brightness, diffuse
/// `(1 - max(specular)) / (1 - F0) * (1 - metallic)` and specular `F0 (1 - m) + base m` for the
/// same base; the base colour blends the colours that each equation gives by metallic squared.
/// Exact for pure dielectrics (specular 0.04) and pure metals (black diffuse).
fn metallic_from_specular(diffuse: Rgb, specular: Rgb) -> (Rgb, f32) {
    const EPSILON: f32 = 1e-6;
    let one_minus_specular = 1.0 - specular.max_element();
    let (d, s) = (
        perceived_brightness(diffuse),
        perceived_brightness(specular),
    );
    let metallic = if s < DIELECTRIC_F0 {
        0.0
    } else {
        let a = DIELECTRIC_F0;
        let b = d * one_minus_specular / (1.0 - a) + s - 2.0 * a;
        let c = a - s;
        let discriminant = (b * b - 4.0 * a * c).max(0.0);
        ((-b + discriminant.sqrt()) / (2.0 * a)).clamp(0.0, 1.0)
    };
    let from_diffuse =
        diffuse * (one_minus_specular / (1.0 - DIELECTRIC_F0) / (1.0 - metallic).max(EPSILON));
    let from_specular =
        (specular - Rgb::splat(DIELECTRIC_F0 * (1.0 - metallic))) * (1.0 / metallic.max(EPSILON));
    let t = metallic * metallic;
    let base = from_diffuse * (1.0 - t) + from_specular * t;
    (base.clamp(Rgb::ZERO, Rgb::ONE), metallic)
}
