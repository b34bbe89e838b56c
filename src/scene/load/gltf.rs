//! glTF 2.0 import (`.gltf` with external or data-URI buffers, `.glb`): the default scene's
//! node hierarchy becomes entities of the world, placed by `world_from_file` (which turns
//! glTF's +Y up into wavetrace's +Z up, see [`super::UpAxis`]).
//!
//! Each triangle primitive becomes one entity (`Name` = its node's name) with a [`Mesh`] in
//! node space and the node's world [`Transform`]; cameras become [`Camera`]s in world space;
//! `KHR_lights_punctual` lights become [`PunctualLight`]s. Every material becomes
//! [`Material::MetallicRoughness`] with the file's factors (and `KHR_materials_specular`,
//! `_ior`, `_transmission`), its textures a [`MaterialTextures`] (with `TANGENT` data as
//! [`VertexTangents`] when there is a normal map), its emission an [`Emitter`]; the README
//! documents the mapping.

use super::{Scene, SceneDefaults, UpAxis, check_mesh, gltf_check};
use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat4, Rgb, Vec2, Vec3, Vec4};
use crate::scene::{
    Camera, Emitter, Material, MaterialTextures, Mesh, Name, PunctualLight, TextureSlot, Transform,
    VertexTangents,
};
use crate::texture::{Encoding, Filter, Texture, UvTransform, Wrap};
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::Mode;
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// Extensions a file may list in `extensionsRequired`: those whose absence would change the
/// image are read; the others (unlit, specular, ...) only refine what we approximate anyway.
const SUPPORTED_REQUIRED: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_transmission",
    "KHR_texture_transform",
];

/// How one glTF material appears in the world.
struct ImportedMaterial {
    material: Material,
    emitter: Option<Emitter>,
    textures: MaterialTextures,
    /// Texture coordinate set (`TEXCOORD_n`) the textures read, if any texture is used.
    uv_set: Option<u32>,
}

/// Decoded textures by glTF texture index and how their values are encoded.
type TextureTable = HashMap<(usize, Encoding), Arc<Texture>>;

/// Loads a glTF file into a new world.
pub(super) fn load(path: &Path, up: UpAxis) -> Result<Scene> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    })?;
    if gltf_check::path_is_glb(path) || bytes.starts_with(b"glTF") {
        gltf_check::check_glb(path, &bytes)?;
    }
    let unchecked = gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| match e {
        gltf::Error::Deserialize(e) => match gltf::binary::Glb::from_slice(&bytes) {
            Ok(glb) => gltf_check::json_error(path, &glb.json, true, &e),
            Err(_) => gltf_check::json_error(path, &bytes, false, &e),
        },
        other => Error::input(path, None, format!("not a valid glTF file: {other}")),
    })?;
    for ext in unchecked.extensions_required() {
        if !SUPPORTED_REQUIRED.contains(&ext) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "the file requires the extension '{ext}', which wavetrace does not support{}",
                    if ext.contains("draco")
                        || ext.contains("meshopt")
                        || ext.contains("quantization")
                    {
                        " (export without mesh compression or quantization)"
                    } else {
                        ""
                    }
                ),
            ));
        }
    }
    let gltf_error = |e: gltf::Error| {
        Error::input(
            path,
            None,
            match e {
                gltf::Error::Validation(errors) => format!(
                    "invalid glTF: {}",
                    errors
                        .iter()
                        .map(|(p, e)| format!("{p}: {e}"))
                        .collect::<Vec<_>>()
                        .join("; ")
                ),
                other => format!("not a valid glTF file: {other}"),
            },
        )
    };
    // gltf-json 1.4.1's validation reads a primitive's POSITION accessor before checking that
    // it exists, and panics when it does not (found by fuzzing): check that first.
    let json = unchecked.document.into_json();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let named = primitive
                .attributes
                .values()
                .chain(primitive.indices.as_ref());
            if let Some(bad) = named
                .map(|a| a.value())
                .find(|&a| a >= json.accessors.len())
            {
                return Err(Error::input(
                    path,
                    Some(format!("mesh {m}, primitive {p}")),
                    format!(
                        "accessor {bad} does not exist (the file has {})",
                        json.accessors.len()
                    ),
                ));
            }
        }
    }
    let gltf = gltf::Gltf {
        document: gltf::Document::from_json(json).map_err(gltf_error)?,
        blob: unchecked.blob,
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let gltf::Gltf { document, blob } = gltf;
    let buffers = gltf_check::import_buffers(path, &document, base, blob)?;
    gltf_check::check_ranges(path, &document)?;

    let mut warnings = Vec::new();
    let textures = import_textures(&document, base, &buffers, path)?;
    let materials: Vec<ImportedMaterial> = document
        .materials()
        .map(|m| import_material(&m, &textures, &mut warnings))
        .collect();
    let default_material = ImportedMaterial {
        // glTF's default material: base colour 1, metallic 1, roughness 1.
        material: Material::MetallicRoughness {
            base_color: Rgb::ONE,
            metallic: 1.0,
            roughness: 1.0,
            specular: 1.0,
            specular_color: Rgb::ONE,
            ior: 1.5,
            transmission: 0.0,
        },
        emitter: None,
        textures: MaterialTextures::default(),
        uv_set: None,
    };

    let scene = document
        .default_scene()
        .or_else(|| document.scenes().next())
        .ok_or_else(|| Error::input(path, None, "the file has no scene"))?;
    let mut world = hecs::World::new();
    let world_from_file = up.world_from_file();
    let mut stack: Vec<(gltf::Node, Affine3A, usize)> = scene
        .nodes()
        .map(|n| (n, world_from_file, 0usize))
        .collect();
    stack.reverse(); // visit in document order
    let node_count = document.nodes().len();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > node_count {
            return Err(Error::input(
                path,
                Some(node_location(&node)),
                "the node hierarchy has a cycle",
            ));
        }
        let local = Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix()));
        let world_from_node = parent * local;
        if !world_from_node.is_finite() {
            return Err(Error::input(
                path,
                Some(node_location(&node)),
                "the transform is not finite",
            ));
        }
        let name = node
            .name()
            .map(str::to_string)
            .or_else(|| node.mesh().and_then(|m| m.name().map(str::to_string)))
            .unwrap_or_else(|| format!("node {}", node.index()));
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                let imported = primitive
                    .material()
                    .index()
                    .map_or(&default_material, |i| &materials[i]);
                let (mesh_data, tangents) =
                    read_primitive(&primitive, &mesh, imported, &buffers, path)?;
                let entity = world.spawn((
                    Name(name.clone()),
                    Transform(world_from_node),
                    mesh_data,
                    imported.material,
                ));
                if let Some(e) = imported.emitter {
                    world.insert_one(entity, e).expect("just spawned");
                }
                if !imported.textures.is_empty() {
                    world
                        .insert_one(entity, imported.textures.clone())
                        .expect("just spawned");
                }
                if let Some(t) = tangents {
                    world.insert_one(entity, t).expect("just spawned");
                }
            }
        }
        if let Some(camera) = node.camera() {
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    gltf_check::check_perspective(&p).map_err(|message| {
                        Error::input(path, Some(node_location(&node)), message)
                    })?;
                    world.spawn((Name(name.clone()), camera_of(&world_from_node, &p)));
                }
                gltf::camera::Projection::Orthographic(_) => warnings.push(format!(
                    "camera '{name}': orthographic cameras are not supported; skipped"
                )),
            }
        }
        if let Some(light) = node.light() {
            let colour = Rgb::from(light.color()) * light.intensity();
            let punctual = match light.kind() {
                LightKind::Point => PunctualLight::Point { intensity: colour },
                LightKind::Directional => PunctualLight::Directional { irradiance: colour },
                LightKind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => PunctualLight::Spot {
                    intensity: colour,
                    inner_cone: inner_cone_angle,
                    outer_cone: outer_cone_angle,
                },
            };
            if !colour.is_finite() || colour.min_element() < 0.0 {
                return Err(Error::input(
                    path,
                    Some(node_location(&node)),
                    "light colour and intensity must be finite and non-negative",
                ));
            }
            world.spawn((Name(name.clone()), Transform(world_from_node), punctual));
        }
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world_from_node, depth + 1));
        }
    }
    Ok(Scene {
        world,
        defaults: SceneDefaults::default(),
        warnings,
    })
}

fn node_location(node: &gltf::Node) -> String {
    match node.name() {
        Some(n) => format!("node '{n}' (index {})", node.index()),
        None => format!("node {}", node.index()),
    }
}

/// A glTF camera (looking down its node's -Z with +Y up) in world space.
fn camera_of(world_from_node: &Affine3A, p: &gltf::camera::Perspective) -> Camera {
    let eye = world_from_node.transform_point3(Vec3::ZERO);
    let forward = world_from_node
        .transform_vector3(Vec3::NEG_Z)
        .normalize_or(Vec3::NEG_Z);
    let up_hint = world_from_node.transform_vector3(Vec3::Y);
    let right = forward.cross(up_hint).normalize_or(Vec3::X);
    Camera {
        eye,
        forward,
        up: right.cross(forward),
        vfov: p.yfov(),
        aspect_ratio: p.aspect_ratio(),
    }
}

/// Every texture a material reads, with the encoding of its use: colour textures (base
/// colour, emission) are sRGB, data textures (metallic-roughness, normal) linear.
fn texture_uses(document: &gltf::Document) -> Vec<(usize, Encoding)> {
    let mut uses = Vec::new();
    for m in document.materials() {
        let pbr = m.pbr_metallic_roughness();
        let srgb = [pbr.base_color_texture(), m.emissive_texture()];
        let linear = [pbr.metallic_roughness_texture()];
        for info in srgb.into_iter().flatten() {
            uses.push((info.texture().index(), Encoding::Srgb));
        }
        for info in linear.into_iter().flatten() {
            uses.push((info.texture().index(), Encoding::Linear));
        }
        if let Some(n) = m.normal_texture() {
            uses.push((n.texture().index(), Encoding::Linear));
        }
    }
    uses.sort_by_key(|&(i, e)| (i, e == Encoding::Linear));
    uses.dedup();
    uses
}

/// Decodes the images the materials use (sRGB colour to linear where the use is colour),
/// with their samplers.
fn import_textures(
    document: &gltf::Document,
    base: &Path,
    buffers: &[gltf::buffer::Data],
    path: &Path,
) -> Result<TextureTable> {
    let mut out = TextureTable::new();
    let mut images: HashMap<usize, gltf::image::Data> = HashMap::new();
    let textures: Vec<gltf::Texture> = document.textures().collect();
    for (index, encoding) in texture_uses(document) {
        let texture = &textures[index];
        let image = texture.source();
        if let std::collections::hash_map::Entry::Vacant(e) = images.entry(image.index()) {
            let data = gltf::image::Data::from_source(image.source(), Some(base), buffers)
                .map_err(|e| {
                    Error::input(
                        path,
                        Some(format!("image {}", image.index())),
                        format!("cannot decode: {e}"),
                    )
                })?;
            e.insert(data);
        }
        let data = &images[&image.index()];
        use gltf::image::Format as F;
        let (w, h) = (data.width, data.height);
        let (e, px) = (encoding, &data.pixels);
        let decoded = match data.format {
            F::R8 => Texture::from_bytes8(w, h, 1, px, e),
            F::R8G8 => Texture::from_bytes8(w, h, 2, px, e),
            F::R8G8B8 => Texture::from_bytes8(w, h, 3, px, e),
            F::R8G8B8A8 => Texture::from_bytes8(w, h, 4, px, e),
            F::R16 => Texture::from_bytes16(w, h, 1, px, e),
            F::R16G16 => Texture::from_bytes16(w, h, 2, px, e),
            F::R16G16B16 => Texture::from_bytes16(w, h, 3, px, e),
            F::R16G16B16A16 => Texture::from_bytes16(w, h, 4, px, e),
            F::R32G32B32FLOAT | F::R32G32B32A32FLOAT => {
                let channels = if data.format == F::R32G32B32FLOAT {
                    3
                } else {
                    4
                };
                let floats: Vec<f32> = data
                    .pixels
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect();
                Texture::new(
                    w,
                    h,
                    floats
                        .chunks_exact(channels)
                        .map(|t| Rgb::new(t[0], t[1], t[2]))
                        .collect(),
                )
            }
        };
        let mut decoded = decoded.ok_or_else(|| {
            Error::input(
                path,
                Some(format!("image {}", image.index())),
                "the decoded image has no texels or an inconsistent size",
            )
        })?;
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
        out.insert((index, encoding), Arc::new(decoded));
    }
    Ok(out)
}

/// A texture reference's slot and UV set (`KHR_texture_transform` may override the set).
fn texture_slot(
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
fn info_slot(
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
fn raw_uv_transform(t: &gltf::json::Value) -> (UvTransform, Option<u32>) {
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

/// The README's mapping from glTF PBR materials to wavetrace's.
fn import_material(
    m: &gltf::Material,
    textures: &TextureTable,
    warnings: &mut Vec<String>,
) -> ImportedMaterial {
    let name = m.name().unwrap_or("unnamed");
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _alpha] = pbr.base_color_factor();
    let base = Rgb::new(r, g, b).clamp(Rgb::ZERO, Rgb::ONE);
    // glTF 2.0 metallic-roughness as the specification defines it; `flatten` resolves the
    // exact special cases (Lambertian, smooth glass, mirror) from these values.
    let unit = |x: f32| {
        if x.is_finite() {
            x.clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let specular = m.specular();
    let material = Material::MetallicRoughness {
        base_color: base,
        metallic: unit(pbr.metallic_factor()),
        roughness: unit(pbr.roughness_factor()),
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
    };
    let strength = m.emissive_strength().unwrap_or(1.0);
    let radiance = Rgb::from(m.emissive_factor()) * strength;
    let emitter = (radiance.max_element() > 0.0).then_some(Emitter {
        radiance,
        two_sided: m.double_sided(),
    });
    // Textures: one set of texture coordinates per mesh, so all of a material's textures
    // must read the same `TEXCOORD_n`.
    let normal = m.normal_texture();
    let slots = [
        info_slot(textures, pbr.base_color_texture(), Encoding::Srgb),
        info_slot(textures, pbr.metallic_roughness_texture(), Encoding::Linear),
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
    ];
    let uv_set = slots.iter().flatten().map(|(_, set)| *set).next();
    let [base_color, metallic_roughness, normal_map, emissive] = slots.map(|slot| {
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
    ImportedMaterial {
        material,
        emitter,
        textures: MaterialTextures {
            base_color,
            metallic_roughness,
            normal: normal_map,
            normal_scale: normal.map_or(1.0, |n| n.scale()),
            emissive,
        },
        uv_set,
    }
}

/// Reads one primitive's triangles into a [`Mesh`] in node space.
fn read_primitive(
    primitive: &gltf::Primitive,
    mesh: &gltf::Mesh,
    material: &ImportedMaterial,
    buffers: &[gltf::buffer::Data],
    path: &Path,
) -> Result<(Mesh, Option<VertexTangents>)> {
    let mesh_name = match mesh.name() {
        Some(n) => format!("mesh '{n}' (index {})", mesh.index()),
        None => format!("mesh {}", mesh.index()),
    };
    let at = || Some(format!("{mesh_name}, primitive {}", primitive.index()));
    if primitive.mode() != Mode::Triangles {
        return Err(Error::input(
            path,
            at(),
            format!(
                "primitive mode {:?} is not supported (only triangles are)",
                primitive.mode()
            ),
        ));
    }
    // gltf 1.4.1's readers panic (`unreachable!`) on component types the specification
    // forbids, and its validation does not catch them (found by fuzzing): check them here.
    {
        use gltf::Semantic;
        use gltf::accessor::{DataType, Dimensions};
        let texture_set = material.uv_set;
        let tangents = material
            .textures
            .normal
            .as_ref()
            .and_then(|_| primitive.get(&Semantic::Tangents));
        let expected: [(Option<gltf::Accessor>, &str, &[DataType], Dimensions); 5] = [
            (
                primitive.get(&Semantic::Positions),
                "POSITION",
                &[DataType::F32],
                Dimensions::Vec3,
            ),
            (
                primitive.get(&Semantic::Normals),
                "NORMAL",
                &[DataType::F32],
                Dimensions::Vec3,
            ),
            (
                texture_set.and_then(|set| primitive.get(&Semantic::TexCoords(set))),
                "TEXCOORD",
                &[DataType::F32, DataType::U8, DataType::U16],
                Dimensions::Vec2,
            ),
            (tangents, "TANGENT", &[DataType::F32], Dimensions::Vec4),
            (
                primitive.indices(),
                "indices",
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
            ),
        ];
        for (accessor, what, types, dimensions) in expected {
            if let Some(a) = accessor
                && (!types.contains(&a.data_type()) || a.dimensions() != dimensions)
            {
                return Err(Error::input(
                    path,
                    at(),
                    format!(
                        "{what} accessor {} holds {:?} {:?}, which glTF does not allow there",
                        a.index(),
                        a.dimensions(),
                        a.data_type()
                    ),
                ));
            }
        }
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| {
            Error::input(
                path,
                at(),
                "POSITION is missing, or its accessor lies outside its buffer",
            )
        })?
        .map(Vec3::from)
        .collect();
    let n = positions.len();
    let normals: Vec<Vec3> = reader
        .read_normals()
        .map(|it| it.map(Vec3::from).collect())
        .unwrap_or_default();
    let uvs: Vec<Vec2> = match material.uv_set {
        Some(set) => reader
            .read_tex_coords(set)
            .map(|it| it.into_f32().map(Vec2::from).collect())
            .unwrap_or_default(),
        None => Vec::new(),
    };
    let tangents: Vec<Vec4> = match material.textures.normal {
        Some(_) => reader
            .read_tangents()
            .map(|it| it.map(Vec4::from).collect())
            .unwrap_or_default(),
        None => Vec::new(),
    };
    let flat: Vec<u32> = match (primitive.indices(), reader.read_indices()) {
        (_, Some(indices)) => indices.into_u32().collect(),
        (None, None) => (0..n as u32).collect(), // non-indexed: consecutive triples
        (Some(_), None) => {
            return Err(Error::input(
                path,
                at(),
                "the indices accessor lies outside its buffer",
            ));
        }
    };
    if !flat.len().is_multiple_of(3) {
        return Err(Error::input(
            path,
            at(),
            format!(
                "{} indices do not make whole triangles (not a multiple of 3)",
                flat.len()
            ),
        ));
    }
    let mesh = Mesh {
        positions,
        normals: if normals.len() == n {
            normals
        } else {
            Vec::new()
        },
        uvs: if uvs.len() == n { uvs } else { Vec::new() },
        indices: flat.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
    };
    check_mesh(path, &mesh_name, &mesh)?;
    // Tangents are only of use with vertex normals to orthogonalise against.
    let tangents =
        (tangents.len() == n && mesh.normals.len() == n && tangents.iter().all(|t| t.is_finite()))
            .then_some(VertexTangents(tangents));
    Ok((mesh, tangents))
}
