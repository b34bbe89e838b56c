//! The textures of glTF materials: which textures the materials read and with which encoding
//! (colour textures sRGB, data textures linear), each image read and decoded once (PNG, JPEG
//! or WebP, from a file, a data URI or a buffer view) with its sampler's wrap and filter, and a
//! material's reference to a texture as a [`TextureSlot`] with its UV set
//! (`KHR_texture_transform` may change it). An image that cannot be read or decoded is left
//! out with one warning naming it and the materials that render without it. Materials
//! themselves are `materials.rs`'s.

use crate::math::Rgb;
use crate::scene::TextureSlot;
use crate::texture::{Encoding, Filter, MinFilter, Texture, UvTransform, Wrap};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// Decoded textures by glTF texture index and how their values are encoded.
pub(super) type TextureTable = HashMap<(usize, Encoding), Arc<Texture>>;

/// Every texture a material reads, with the encoding of its use: colour textures (base
/// colour, emission, specular colour) are sRGB, data textures (metallic-roughness, normal,
/// specular strength, anisotropy) linear.
fn texture_uses(document: &gltf::Document) -> Vec<(usize, Encoding)> {
    let mut uses = Vec::new();
    for m in document.materials() {
        let pbr = m.pbr_metallic_roughness();
        let specular = m.specular();
        let srgb = [
            pbr.base_color_texture(),
            m.emissive_texture(),
            specular.as_ref().and_then(|s| s.specular_color_texture()),
        ];
        let linear = [
            pbr.metallic_roughness_texture(),
            specular.as_ref().and_then(|s| s.specular_texture()),
        ];
        for info in srgb.into_iter().flatten() {
            uses.push((info.texture().index(), Encoding::Srgb));
        }
        for info in linear.into_iter().flatten() {
            uses.push((info.texture().index(), Encoding::Linear));
        }
        if let Some(n) = m.normal_texture() {
            uses.push((n.texture().index(), Encoding::Linear));
        }
        if let Some(index) = spec_gloss_diffuse_texture(&m) {
            uses.push((index, Encoding::Srgb));
        }
        let extension_infos = (layer_texture_infos(&m).into_iter())
            .chain(film_texture_infos(&m))
            .chain([(coat_normal_texture_info(&m), Encoding::Linear)]);
        for (info, encoding) in extension_infos {
            if let Some(index) = info.and_then(|i| i["index"].as_u64()) {
                uses.push((index as usize, encoding));
            }
        }
        let anisotropy = m.extension_value("KHR_materials_anisotropy");
        if let Some(index) = anisotropy.and_then(|e| e["anisotropyTexture"]["index"].as_u64()) {
            uses.push((index as usize, Encoding::Linear));
        }
    }
    uses.retain(|&(i, _)| i < document.textures().len());
    uses.sort_by_key(|&(i, e)| (i, e == Encoding::Linear));
    uses.dedup();
    uses
}

/// The materials that use each image, as "material 'A', material 'B'", for warnings.
fn image_users(document: &gltf::Document) -> HashMap<usize, String> {
    let mut users: HashMap<usize, Vec<String>> = HashMap::new();
    for m in document.materials() {
        let pbr = m.pbr_metallic_roughness();
        let mut textures: Vec<gltf::Texture> = [pbr.base_color_texture(), m.emissive_texture()]
            .into_iter()
            .chain([pbr.metallic_roughness_texture()])
            .flatten()
            .map(|info| info.texture())
            .collect();
        textures.extend(m.normal_texture().map(|n| n.texture()));
        textures.extend(spec_gloss_diffuse_texture(&m).and_then(|i| document.textures().nth(i)));
        let name = match m.name() {
            Some(n) => format!("material '{n}'"),
            None => format!("material {}", m.index().unwrap_or(0)),
        };
        for t in textures {
            let list = users.entry(t.source().index()).or_default();
            if !list.contains(&name) {
                list.push(name.clone());
            }
        }
    }
    users
        .into_iter()
        .map(|(image, names)| (image, names.join(", ")))
        .collect()
}

/// "image 2 ('wood.png')": an image and where it comes from, for warnings.
fn image_label(image: &gltf::Image) -> String {
    let origin = match (image.source(), image.name()) {
        (gltf::image::Source::Uri { uri, .. }, _) if !uri.starts_with("data:") => {
            format!(" ('{uri}')")
        }
        (_, Some(name)) => format!(" ('{name}')"),
        _ => String::new(),
    };
    format!("image {}{origin}", image.index())
}

/// The KTX2 file identifier (`KHR_texture_basisu` images).
const KTX2_MAGIC: &[u8] = b"\xABKTX 20\xBB";

/// Reads and decodes one image (a file, a data URI or a buffer view; PNG, JPEG or WebP).
fn decode_image(
    image: &gltf::Image,
    base: &Path,
    buffers: &[gltf::buffer::Data],
) -> std::result::Result<image::DynamicImage, String> {
    let bytes: Vec<u8> = match image.source() {
        gltf::image::Source::View { view, .. } => {
            // `check_ranges` has checked that the view lies inside its buffer.
            let data = &buffers[view.buffer().index()].0;
            data[view.offset()..view.offset() + view.length()].to_vec()
        }
        gltf::image::Source::Uri { uri, .. } => {
            // The buffer reader resolves data URIs, percent-escapes and relative paths alike.
            gltf::buffer::Data::from_source(gltf::buffer::Source::Uri(uri), Some(base))
                .map_err(|e| match e {
                    gltf::Error::Io(e) => format!("cannot read it: {e}"),
                    other => format!("cannot read it: {other}"),
                })?
                .0
        }
    };
    if bytes.starts_with(KTX2_MAGIC) {
        return Err("KTX2 (KHR_texture_basisu) images are not supported".to_string());
    }
    crate::scene::load::image_decode::decode_image_bytes(&bytes)
}

/// A decoded image as a texture of the given encoding.
fn texture_of(image: &image::DynamicImage, encoding: Encoding) -> Option<Texture> {
    use image::DynamicImage as D;
    let (w, h) = (image.width(), image.height());
    match image {
        D::ImageLuma8(_) | D::ImageLumaA8(_) | D::ImageRgb8(_) | D::ImageRgba8(_) => {
            let channels = image.color().channel_count() as usize;
            Texture::from_bytes8(w, h, channels, image.as_bytes().to_vec(), encoding)
        }
        D::ImageRgb32F(_) | D::ImageRgba32F(_) => {
            let floats = image.to_rgb32f();
            Texture::new(
                w,
                h,
                floats
                    .pixels()
                    .map(|p| Rgb::new(p[0], p[1], p[2]))
                    .collect(),
            )
        }
        _ => {
            let wide = image.to_rgba16();
            let bytes: Vec<u8> = wide.as_raw().iter().flat_map(|v| v.to_le_bytes()).collect();
            Texture::from_bytes16(w, h, 4, &bytes, encoding)
        }
    }
}

/// Decodes the images the materials use (sRGB colour to linear where the use is colour),
/// with their samplers. An image that cannot be read or decoded is left out with one warning
/// naming it and the materials that render without it.
pub(super) fn import_textures(
    document: &gltf::Document,
    base: &Path,
    buffers: &[gltf::buffer::Data],
    path: &Path,
    warnings: &mut Vec<String>,
) -> TextureTable {
    let mut out = TextureTable::new();
    let mut images: HashMap<usize, Option<image::DynamicImage>> = HashMap::new();
    let users = image_users(document);
    let textures: Vec<gltf::Texture> = document.textures().collect();
    for (index, encoding) in texture_uses(document) {
        let texture = &textures[index];
        let image = texture.source();
        let decoded = images.entry(image.index()).or_insert_with(|| {
            let result = decode_image(&image, base, buffers).and_then(|d| {
                if d.width() == 0 || d.height() == 0 {
                    Err("the decoded image has no texels".to_string())
                } else {
                    Ok(d)
                }
            });
            result
                .map_err(|why| {
                    warnings.push(format!(
                        "{}: {}: {why}; {} render{} without it",
                        path.display(),
                        image_label(&image),
                        users.get(&image.index()).map_or("", String::as_str),
                        if users.get(&image.index()).is_some_and(|u| u.contains(", ")) {
                            ""
                        } else {
                            "s"
                        }
                    ))
                })
                .ok()
        });
        let Some(decoded) = decoded.as_ref() else {
            continue;
        };
        let Some(mut decoded) = texture_of(decoded, encoding) else {
            warnings.push(format!(
                "{}: {}: the decoded image has an inconsistent size; ignored",
                path.display(),
                image_label(&image)
            ));
            continue;
        };
        let sampler = texture.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        decoded.wrap = [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())];
        decoded.filter = match sampler.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
            _ => Filter::Linear,
        };
        decoded.min_filter = min_filter(sampler.min_filter());
        out.insert((index, encoding), Arc::new(decoded));
    }
    out
}

/// The sampler's `minFilter` (trilinear when the file does not say: what Cycles and
/// Blender's importer do with mipmapped textures).
fn min_filter(filter: Option<gltf::texture::MinFilter>) -> MinFilter {
    use gltf::texture::MinFilter as F;
    match filter {
        Some(F::Nearest) => MinFilter::Nearest,
        Some(F::Linear) => MinFilter::Linear,
        Some(F::NearestMipmapNearest) => MinFilter::NearestMipmapNearest,
        Some(F::LinearMipmapNearest) => MinFilter::LinearMipmapNearest,
        Some(F::NearestMipmapLinear) => MinFilter::NearestMipmapLinear,
        Some(F::LinearMipmapLinear) | None => MinFilter::LinearMipmapLinear,
    }
}

/// A texture reference's slot and UV set (`KHR_texture_transform` may override the set).
pub(super) fn texture_slot(
    textures: &TextureTable,
    index: usize,
    encoding: Encoding,
    tex_coord: u32,
    transform: Option<(UvTransform, Option<u32>)>,
) -> Option<(TextureSlot, u32)> {
    let texture = textures.get(&(index, encoding))?.clone();
    let (uv_transform, set) = transform.unwrap_or((UvTransform::IDENTITY, None));
    Some((
        TextureSlot {
            texture,
            uv_transform,
        },
        set.unwrap_or(tex_coord),
    ))
}

/// [`texture_slot`] for a typed `texture::Info`.
pub(super) fn info_slot(
    textures: &TextureTable,
    info: Option<gltf::texture::Info>,
    encoding: Encoding,
) -> Option<(TextureSlot, u32)> {
    let info = info?;
    let transform = info.texture_transform().map(|t| {
        (
            UvTransform::from_offset_rotation_scale(t.offset(), t.rotation(), t.scale()),
            t.tex_coord(),
        )
    });
    texture_slot(
        textures,
        info.texture().index(),
        encoding,
        info.tex_coord(),
        transform,
    )
}

/// `KHR_texture_transform` from its raw JSON (normal maps have no typed accessor for it).
pub(super) fn raw_uv_transform(t: &gltf::json::Value) -> (UvTransform, Option<u32>) {
    let pair = |key: &str, default: f32| -> [f32; 2] {
        let v = |i: usize| t[key][i].as_f64().map_or(default, |x| x as f32);
        [v(0), v(1)]
    };
    let rotation = t["rotation"].as_f64().unwrap_or(0.0) as f32;
    (
        UvTransform::from_offset_rotation_scale(pair("offset", 0.0), rotation, pair("scale", 1.0)),
        t["texCoord"].as_u64().map(|c| c as u32),
    )
}

/// The textures of `KHR_materials_clearcoat` and `_sheen` a material names (raw JSON: the
/// `gltf` crate reads neither extension), with the encodings of their uses: clearcoat (red,
/// linear), clearcoat roughness (green, linear), sheen colour (sRGB), sheen roughness (alpha).
pub(super) fn layer_texture_infos<'m>(
    m: &'m gltf::Material,
) -> [(Option<&'m gltf::json::Value>, Encoding); 4] {
    let info = |extension: &str, key: &str| m.extension_value(extension).and_then(|e| e.get(key));
    [
        (
            info("KHR_materials_clearcoat", "clearcoatTexture"),
            Encoding::Linear,
        ),
        (
            info("KHR_materials_clearcoat", "clearcoatRoughnessTexture"),
            Encoding::Linear,
        ),
        (
            info("KHR_materials_sheen", "sheenColorTexture"),
            Encoding::Srgb,
        ),
        (
            info("KHR_materials_sheen", "sheenRoughnessTexture"),
            Encoding::Linear,
        ),
    ]
}

/// The texture info of `KHR_materials_clearcoat`'s `clearcoatNormalTexture` (linear).
pub(super) fn coat_normal_texture_info<'m>(m: &'m gltf::Material) -> Option<&'m gltf::json::Value> {
    m.extension_value("KHR_materials_clearcoat")
        .and_then(|e| e.get("clearcoatNormalTexture"))
}

/// The texture infos of `KHR_materials_iridescence` (factor, thickness), both linear.
pub(super) fn film_texture_infos<'m>(
    m: &'m gltf::Material,
) -> [(Option<&'m gltf::json::Value>, Encoding); 2] {
    let info = |key: &str| {
        m.extension_value("KHR_materials_iridescence")
            .and_then(|e| e.get(key))
    };
    [
        (info("iridescenceTexture"), Encoding::Linear),
        (info("iridescenceThicknessTexture"), Encoding::Linear),
    ]
}

/// [`texture_slot`] for a texture info read from raw JSON (`index`, `texCoord`,
/// `KHR_texture_transform`).
pub(super) fn raw_info_slot(
    textures: &TextureTable,
    info: Option<&gltf::json::Value>,
    encoding: Encoding,
) -> Option<(TextureSlot, u32)> {
    let info = info?;
    let index = info["index"].as_u64()? as usize;
    let tex_coord = info["texCoord"].as_u64().unwrap_or(0) as u32;
    let transform = info["extensions"]
        .get("KHR_texture_transform")
        .map(raw_uv_transform);
    texture_slot(textures, index, encoding, tex_coord, transform)
}

/// The texture index of a `KHR_materials_pbrSpecularGlossiness` diffuse texture.
pub(super) fn spec_gloss_diffuse_texture(m: &gltf::Material) -> Option<usize> {
    let sg = m.extension_value("KHR_materials_pbrSpecularGlossiness")?;
    sg["diffuseTexture"]["index"].as_u64().map(|i| i as usize)
}
