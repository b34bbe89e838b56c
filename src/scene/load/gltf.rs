//! glTF 2.0 import (`.gltf` with external or data-URI buffers, `.glb`): the default scene's
//! node hierarchy becomes entities of the world, placed by `world_from_file` (which turns
//! glTF's +Y up into wavetrace's +Z up, see [`super::UpAxis`]).
//!
//! Each triangle primitive becomes one entity (`Name` = its node's name) with a [`Mesh`] in
//! node space and the node's world [`Transform`]; cameras become [`Camera`]s in world space;
//! `KHR_lights_punctual` lights become [`PunctualLight`]s. Every material becomes
//! [`Material::MetallicRoughness`] with the file's factors (and `KHR_materials_specular`,
//! `_ior`, `_transmission`, `_clearcoat`, `_sheen`), its textures a [`MaterialTextures`] (with `TANGENT` data as
//! [`VertexTangents`] when there is a normal map), its emission an [`Emitter`]; the README
//! documents the mapping.

use super::{
    Scene, SceneDefaults, UpAxis, check_mesh, gltf_check, gltf_deform, gltf_fix, gltf_geometry,
    gltf_memory, gltf_meshopt,
};
use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat4, Rgb, Vec2, Vec3, Vec4};
use crate::scene::{
    AlphaCoverage, AlphaMode, Camera, Emitter, Material, MaterialTextures, Mesh, Name,
    PunctualLight, SharedMesh, SpotFalloff, TextureSlot, Transform, VertexColors, VertexTangents,
    Volume,
};
use crate::texture::{Encoding, Filter, Texture, UvTransform, Wrap};
use gltf::khr_lights_punctual::Kind as LightKind;
use gltf::mesh::Mode;
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

/// Base colour of primitives without a material (Blender's importer default).
const DEFAULT_GREY: f32 = 0.8;
/// Roughness of primitives without a material (Blender's Principled BSDF default).
const DEFAULT_ROUGHNESS: f32 = 0.5;
/// F0 of dielectrics in the specular-glossiness to metallic-roughness conversion.
const DIELECTRIC_F0: f32 = 0.04;

/// The absorbing medium of `KHR_materials_volume` (`attenuationColor`, default white, and
/// `attenuationDistance`, default infinite); its `thickness` is not needed by a path tracer,
/// which measures the path inside the object (gltf_fix warns once).
fn volume_of(m: &gltf::Material) -> Option<Volume> {
    let volume = m.extension_value("KHR_materials_volume")?;
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

/// How one glTF material appears in the world.
struct ImportedMaterial {
    material: Material,
    emitter: Option<Emitter>,
    textures: MaterialTextures,
    /// Texture coordinate set (`TEXCOORD_n`) the textures read, if any texture is used.
    uv_set: Option<u32>,
    /// `alphaMode` MASK or BLEND; `None` for OPAQUE.
    alpha: Option<AlphaCoverage>,
    /// `KHR_materials_volume`'s absorbing medium, if it absorbs anything.
    volume: Option<Volume>,
}

/// Decoded textures by glTF texture index and how their values are encoded.
type TextureTable = HashMap<(usize, Encoding), Arc<Texture>>;

/// Loads a glTF file into a new world.
pub(super) fn load(path: &Path, up: UpAxis) -> Result<Scene> {
    // Running out of memory while loading is refused with an error, not an allocation abort:
    // the file, its buffers and its meshes are each checked before they are read.
    gltf_memory::check_file(path)?;
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    })?;
    let mut warnings = Vec::new();
    let (json, blob) = if gltf_check::path_is_glb(path) || bytes.starts_with(b"glTF") {
        gltf_check::check_glb(path, &bytes)?;
        let glb = gltf::binary::Glb::from_slice(&bytes)
            .map_err(|e| Error::input(path, None, format!("not a valid glTF file: {e}")))?;
        let json = gltf_fix::parse_root(path, &glb.json, true, &mut warnings)?;
        (json, glb.bin.map(|b| b.into_owned()))
    } else {
        (
            gltf_fix::parse_root(path, &bytes, false, &mut warnings)?,
            None,
        )
    };
    // The BIN chunk was copied out: the file's bytes are not kept while the buffers load.
    drop(bytes);
    crate::memory::trace_phase("read");
    for ext in &json.extensions_required {
        if let Some(message) = gltf_geometry::compression_message(ext) {
            return Err(Error::input(path, None, message));
        }
        if !gltf_fix::SUPPORTED_REQUIRED.contains(&ext.as_str()) {
            return Err(Error::input(
                path,
                None,
                format!(
                    "the file requires the extension '{ext}', which wavetrace does not support"
                ),
            ));
        }
    }
    if let Some(message) = gltf_geometry::draco_without_fallback(&json) {
        return Err(Error::input(path, None, message));
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
    // it exists, and panics when it does not (found by fuzzing): `gltf_fix` drops such
    // primitives before validation.
    // Checked above: gltf-json's validation refuses required extensions it does not know
    // itself, even those with a fallback.
    let mut json = json;
    json.extensions_required.clear();
    let meshopt = gltf_meshopt::uses_meshopt(&json);
    let placeholders = if meshopt {
        gltf_meshopt::placeholder_buffers(&json, blob.is_some())
    } else {
        Vec::new()
    };
    let document = gltf::Document::from_json(json).map_err(gltf_error)?;
    let base = path.parent().unwrap_or(Path::new("."));
    gltf_memory::check_buffers(path, &document, base, &placeholders)?;
    let mut buffers = gltf_check::import_buffers(path, &document, base, blob, &placeholders)?;
    let document = if meshopt {
        // Compressed views become views of decoded buffers; the document is made again from
        // the changed JSON.
        let mut json = document.into_json();
        gltf_meshopt::decode_views(path, &mut json, &mut buffers, &placeholders, &mut warnings);
        gltf::Document::from_json(json).map_err(gltf_error)?
    } else {
        document
    };
    gltf_check::check_ranges(path, &document)?;
    crate::memory::trace_phase("buffers");
    gltf_memory::check_meshes(path, &document)?;

    gltf_fix::survey(path, &document, &mut warnings);
    let textures = import_textures(&document, base, &buffers, path, &mut warnings);
    let materials: Vec<ImportedMaterial> = document
        .materials()
        .map(|m| import_material(&m, &textures, &mut warnings))
        .collect();
    let default_material = ImportedMaterial {
        // Not glTF's default material (white metal, roughness 1, which Cycles users know as
        // grey plastic) but what Blender's importer gives: a grey dielectric.
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
    };

    let roots = scene_roots(&document, path, &mut warnings)?;
    let mut world = hecs::World::new();
    let world_from_file = up.world_from_file();
    let mut stack: Vec<(gltf::Node, Affine3A, usize)> = roots
        .iter()
        .map(|n| (n.clone(), world_from_file, 0usize))
        .collect();
    stack.reverse(); // visit in document order
    let node_count = document.nodes().len();
    let node_world =
        gltf_deform::node_world_transforms(roots.iter().cloned(), node_count, world_from_file);
    let mut bad_skins = HashSet::new();
    // One warning per bad primitive even when several nodes use its mesh.
    let (mut skip_warned, mut lines_warned) = (HashSet::new(), HashSet::new());
    let (mut primitives_seen, mut primitives_read, mut lines_skipped) = (0usize, 0usize, 0usize);
    let mut first_skip: Option<String> = None;
    // How many times each mesh is drawn (nodes and GPU instances): a mesh drawn more than
    // once is read once and shared ([`SharedMesh`]).
    let mut mesh_uses = vec![0usize; document.meshes().len()];
    for node in document.nodes() {
        if let Some(mesh) = node.mesh() {
            mesh_uses[mesh.index()] += instance_count(&node, &document).unwrap_or(1);
        }
    }
    type Read = (Arc<Mesh>, Option<VertexTangents>, Option<VertexColors>);
    let mut read_cache: HashMap<(usize, usize), Read> = HashMap::new();
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
            let joints = node.skin().and_then(|skin| {
                gltf_deform::joint_matrices(&skin, &node_world, &buffers)
                    .map_err(|why| {
                        if bad_skins.insert(skin.index()) {
                            warnings.push(format!(
                                "{}: skin {}: {why}; its meshes are shown unposed",
                                path.display(),
                                skin.index()
                            ));
                        }
                    })
                    .ok()
            });
            let deform = Deform {
                weights: node.weights().or(mesh.weights()).unwrap_or(&[]),
                joints: joints.as_deref(),
                world_from_node,
            };
            // A deformed mesh is this node's own: read for it, never shared.
            let deformed = deform.joints.is_some() || deform.weights.iter().any(|&w| w != 0.0);
            // Where the mesh is drawn: at the node, or at each of its GPU instances.
            let placements: Vec<Affine3A> = match instance_transforms(&node, &document, &buffers) {
                // A skinned mesh's vertices come out in world space (see `gltf_deform`).
                _ if deform.joints.is_some() => vec![Affine3A::IDENTITY],
                None => vec![world_from_node],
                Some(Ok(local)) => local.iter().map(|t| world_from_node * *t).collect(),
                Some(Err(message)) => {
                    warnings.push(format!(
                        "{}: {}: EXT_mesh_gpu_instancing: {message}; the node's instances \
                             are skipped",
                        path.display(),
                        node_location(&node)
                    ));
                    Vec::new()
                }
            };
            let shared = !deformed && (mesh_uses[mesh.index()] >= 2 || placements.len() >= 2);
            for primitive in mesh.primitives() {
                let imported = primitive
                    .material()
                    .index()
                    .map_or(&default_material, |i| &materials[i]);
                primitives_seen += 1;
                let key = (mesh.index(), primitive.index());
                let (mesh_data, tangents, colors) = match read_cache.get(&key).filter(|_| !deformed)
                {
                    Some(read) => read.clone(),
                    None => {
                        match read_primitive(&primitive, &mesh, imported, &deform, &buffers, path) {
                            Ok(Some((m, t, c))) => {
                                let read = (Arc::new(m), t, c);
                                if shared {
                                    read_cache.insert(key, read.clone());
                                }
                                read
                            }
                            Ok(None) => {
                                if lines_warned.insert(key) {
                                    lines_skipped += 1;
                                }
                                continue;
                            }
                            Err(e) => {
                                if skip_warned.insert(key) {
                                    let message = format!("{e}; the primitive is skipped");
                                    first_skip.get_or_insert_with(|| message.clone());
                                    warnings.push(message);
                                }
                                continue;
                            }
                        }
                    }
                };
                primitives_read += 1;
                // A mesh used once stays a plain `Mesh` (the common case, which every reader
                // of the world knows); a shared one is stored once.
                let (mut plain, shared_data) = if shared {
                    (None, Some(mesh_data))
                } else {
                    (Some(Arc::unwrap_or_clone(mesh_data)), None)
                };
                for world_from_object in &placements {
                    let entity = world.spawn((
                        Name(name.clone()),
                        Transform(*world_from_object),
                        imported.material,
                    ));
                    match plain.take() {
                        Some(m) => world.insert_one(entity, m),
                        None => {
                            let data = shared_data.clone().expect("a shared mesh");
                            world.insert_one(entity, SharedMesh(data))
                        }
                    }
                    .expect("just spawned");
                    if let Some(e) = imported.emitter {
                        world.insert_one(entity, e).expect("just spawned");
                    }
                    if !imported.textures.is_empty() {
                        world
                            .insert_one(entity, imported.textures.clone())
                            .expect("just spawned");
                    }
                    if let Some(t) = &tangents {
                        world.insert_one(entity, t.clone()).expect("just spawned");
                    }
                    if let Some(c) = &colors {
                        world.insert_one(entity, c.clone()).expect("just spawned");
                    }
                    if let Some(a) = imported.alpha {
                        world.insert_one(entity, a).expect("just spawned");
                    }
                    if let Some(v) = imported.volume {
                        world.insert_one(entity, v).expect("just spawned");
                    }
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
                    falloff: spot_falloff(&document, inner_cone_angle, outer_cone_angle),
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
    crate::memory::trace_phase("meshes");
    if lines_skipped > 0 {
        warnings.push(format!(
            "{}: points and lines are not rendered ({lines_skipped} primitive{} skipped)",
            path.display(),
            gltf_fix::plural(lines_skipped)
        ));
    }
    let dropped_before = document.meshes().any(|m| m.primitives().next().is_none());
    if primitives_read == 0 && (primitives_seen > 0 || dropped_before) {
        let has_lights = world.query::<&PunctualLight>().iter().next().is_some();
        if !has_lights {
            let why = first_skip
                .or_else(|| warnings.iter().find(|w| w.contains("skipped")).cloned())
                .unwrap_or_else(|| "only points and lines".to_string());
            let prefix = format!("{}:", path.display());
            let why = why.strip_prefix(&prefix).unwrap_or(&why).trim_start();
            return Err(Error::input(
                path,
                None,
                format!("nothing renderable is left in the file: {why}"),
            ));
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

/// How a spot's intensity falls between its cones: glTF's falloff, or, in a file Blender's
/// exporter wrote (`asset.generator` "Khronos glTF Blender I/O ..."), the Spot Blend that
/// Blender's importer recovers, `1 - inner / outer` (the exporter writes
/// `inner = outer (1 - blend)`), rendered with Cycles' smoothstep.
fn spot_falloff(document: &gltf::Document, inner: f32, outer: f32) -> SpotFalloff {
    let generator = document.as_json().asset.generator.as_deref();
    if !generator.is_some_and(|g| g.starts_with("Khronos glTF Blender I/O")) || outer <= 0.0 {
        return SpotFalloff::Gltf;
    }
    SpotFalloff::Blender {
        blend: (1.0 - inner / outer).clamp(0.0, 1.0),
    }
}

/// Every texture a material reads, with the encoding of its use: colour textures (base
/// colour, emission, specular colour) are sRGB, data textures (metallic-roughness, normal,
/// specular strength) linear.
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

/// The root nodes to render: the default scene's (or the first scene's). A file without
/// scenes is a library of nodes that the specification leaves to the application to show;
/// as Blender's importer does, its root nodes (those no node has as a child) are rendered,
/// with a warning. A file with neither scenes nor nodes has nothing to render.
fn scene_roots<'a>(
    document: &'a gltf::Document,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Vec<gltf::Node<'a>>> {
    if let Some(scene) = document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        return Ok(scene.nodes().collect());
    }
    let mut is_child = vec![false; document.nodes().len()];
    for child in document.nodes().flat_map(|n| n.children()) {
        is_child[child.index()] = true;
    }
    let roots: Vec<gltf::Node> = document.nodes().filter(|n| !is_child[n.index()]).collect();
    if roots.is_empty() {
        return Err(Error::input(
            path,
            None,
            "the file has no scene and no nodes: nothing to render",
        ));
    }
    warnings.push(format!(
        "{}: the file has no scene; its {} root node{} rendered",
        path.display(),
        roots.len(),
        if roots.len() == 1 { " is" } else { "s are" }
    ));
    Ok(roots)
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
    super::image_decode::decode_image_bytes(&bytes)
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
fn import_textures(
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
        out.insert((index, encoding), Arc::new(decoded));
    }
    out
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
    let [r, g, b, alpha_factor] = pbr.base_color_factor();
    let alpha_factor = if alpha_factor.is_finite() {
        alpha_factor.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let alpha = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => None,
        gltf::material::AlphaMode::Mask => Some(AlphaMode::Mask {
            cutoff: m.alpha_cutoff().filter(|c| c.is_finite()).unwrap_or(0.5),
        }),
        gltf::material::AlphaMode::Blend => Some(AlphaMode::Blend),
    }
    .map(|mode| AlphaCoverage {
        mode,
        factor: alpha_factor,
    });
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
    let spec_gloss = m.extension_value("KHR_materials_pbrSpecularGlossiness");
    let (base, metallic, roughness) = match spec_gloss {
        Some(sg) => {
            let factor = |key: &str, default: f32, i: usize| {
                sg[key][i].as_f64().map_or(default, |x| x as f32)
            };
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
        None => (
            base,
            unit(pbr.metallic_factor()),
            unit(pbr.roughness_factor()),
        ),
    };
    let material = Material::MetallicRoughness {
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
    ];
    let uv_set = slots.iter().flatten().map(|(_, set)| *set).next();
    let [
        base_color,
        metallic_roughness,
        normal_map,
        emissive,
        specular_map,
        specular_color_map,
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
    if m.extension_value("KHR_materials_unlit").is_some() {
        // Unlit: base colour, its texture, vertex colours and alpha only; everything about
        // lighting (metal, roughness, normal map, emission) is ignored, as the extension says.
        return ImportedMaterial {
            material: Material::Unlit { color: base },
            emitter: None,
            textures: MaterialTextures {
                base_color,
                ..MaterialTextures::default()
            },
            uv_set,
            alpha,
            volume: None,
        };
    }
    ImportedMaterial {
        material,
        emitter,
        textures: MaterialTextures {
            base_color,
            metallic_roughness,
            normal: normal_map,
            normal_scale: normal.map_or(1.0, |n| n.scale()),
            emissive,
            specular: specular_map,
            specular_color: specular_color_map,
        },
        uv_set,
        alpha,
        volume: volume_of(m),
    }
}

/// A number of a material extension (glTF's default 0 when absent; callers clamp it).
fn extension_number(m: &gltf::Material, extension: &str, key: &str) -> f32 {
    m.extension_value(extension)
        .and_then(|e| e[key].as_f64())
        .map_or(0.0, |x| x as f32)
}

/// The texture index of a `KHR_materials_pbrSpecularGlossiness` diffuse texture.
fn spec_gloss_diffuse_texture(m: &gltf::Material) -> Option<usize> {
    let sg = m.extension_value("KHR_materials_pbrSpecularGlossiness")?;
    sg["diffuseTexture"]["index"].as_u64().map(|i| i as usize)
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

/// The extension `EXT_mesh_gpu_instancing` of a node, if it has one.
const GPU_INSTANCING: &str = "EXT_mesh_gpu_instancing";

/// The number of GPU instances of `node` (the count of its first instancing accessor), or
/// `None` when it has none (or a malformed extension, which [`instance_transforms`] reports).
fn instance_count(node: &gltf::Node, document: &gltf::Document) -> Option<usize> {
    let attributes = node
        .extension_value(GPU_INSTANCING)?
        .get("attributes")?
        .as_object()?;
    attributes
        .values()
        .filter_map(|index| document.accessors().nth(index.as_u64()? as usize))
        .map(|a| a.count())
        .next()
}

/// The GPU instances of `node` (`EXT_mesh_gpu_instancing`) as transforms in node space
/// (translation x rotation x scale of each instance; an attribute that is missing is the
/// identity's), `None` when the node has no instances, or why they cannot be read. The
/// accessor types are those the extension allows: floats, normalized bytes and shorts for
/// rotations, and with `KHR_mesh_quantization` bytes and shorts (normalized or not) for
/// translations and scales.
fn instance_transforms(
    node: &gltf::Node,
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Option<std::result::Result<Vec<Affine3A>, String>> {
    use gltf::accessor::DataType::{F32, I8, I16, U8, U16};
    let extension = node.extension_value(GPU_INSTANCING)?;
    Some((|| {
        let attributes = extension
            .get("attributes")
            .and_then(|a| a.as_object())
            .ok_or("no attributes")?;
        let accessor = |semantic: &str, dimensions: usize, types: &[gltf::accessor::DataType]| {
            let Some(index) = attributes.get(semantic) else {
                return Ok(None);
            };
            let accessor = index
                .as_u64()
                .and_then(|i| document.accessors().nth(i as usize))
                .ok_or_else(|| format!("{semantic}: no accessor {index}"))?;
            let data_type = accessor.data_type();
            let normalized_only = semantic == "ROTATION" && data_type != F32;
            if accessor.dimensions().multiplicity() != dimensions
                || !types.contains(&data_type)
                || (normalized_only && !accessor.normalized())
            {
                return Err(format!(
                    "{semantic} accessor {} holds {:?} {data_type:?}{}, which the extension \
                     does not allow",
                    accessor.index(),
                    accessor.dimensions(),
                    if accessor.normalized() {
                        " (normalized)"
                    } else {
                        ""
                    }
                ));
            }
            Ok(Some(accessor))
        };
        let translation = accessor("TRANSLATION", 3, &[F32, I8, U8, I16, U16])?;
        let rotation = accessor("ROTATION", 4, &[F32, I8, I16])?;
        let scale = accessor("SCALE", 3, &[F32, I8, U8, I16, U16])?;
        let counts: Vec<usize> = [&translation, &rotation, &scale]
            .iter()
            .filter_map(|a| a.as_ref().map(|a| a.count()))
            .collect();
        let Some(&count) = counts.first() else {
            return Err("no TRANSLATION, ROTATION or SCALE attribute".to_string());
        };
        if counts.iter().any(|&c| c != count) {
            return Err(format!("the attributes have different counts {counts:?}"));
        }
        let outside = |semantic: &str| format!("{semantic}: the data lies outside its buffer");
        let translations = match &translation {
            Some(a) => {
                Some(gltf_geometry::read_floats::<3>(a, buffers).ok_or(outside("TRANSLATION"))?)
            }
            None => None,
        };
        let rotations = match &rotation {
            Some(a) => {
                Some(gltf_geometry::read_floats::<4>(a, buffers).ok_or(outside("ROTATION"))?)
            }
            None => None,
        };
        let scales = match &scale {
            Some(a) => Some(gltf_geometry::read_floats::<3>(a, buffers).ok_or(outside("SCALE"))?),
            None => None,
        };
        let mut transforms = Vec::with_capacity(count);
        for i in 0..count {
            let t = translations
                .as_ref()
                .map_or(Vec3::ZERO, |v| Vec3::from(v[i]));
            let r = rotations.as_ref().map_or(crate::math::Quat::IDENTITY, |v| {
                crate::math::Quat::from_array(v[i])
            });
            let s = scales.as_ref().map_or(Vec3::ONE, |v| Vec3::from(v[i]));
            let r = r.normalize();
            let transform = Affine3A::from_scale_rotation_translation(s, r, t);
            if !transform.is_finite() {
                return Err(format!("instance {i}: the transform is not finite"));
            }
            transforms.push(transform);
        }
        Ok(transforms)
    })())
}

/// How a node deforms its mesh (see [`gltf_deform`]).
struct Deform<'a> {
    /// Morph target weights (the node's, else the mesh's; empty: none).
    weights: &'a [f32],
    /// The skin's joint matrices when the node has a skin that could be posed.
    joints: Option<&'a [Affine3A]>,
    /// The node's world transform, for skinned vertices without weights.
    world_from_node: Affine3A,
}

/// A primitive as read: its mesh, and its tangents and colours if it has them.
type ReadPrimitive = (Mesh, Option<VertexTangents>, Option<VertexColors>);

/// Reads one primitive's triangles into a [`Mesh`], morphed, in node space (in world space
/// when `deform` skins it).
fn read_primitive(
    primitive: &gltf::Primitive,
    mesh: &gltf::Mesh,
    material: &ImportedMaterial,
    deform: &Deform,
    buffers: &[gltf::buffer::Data],
    path: &Path,
) -> Result<Option<ReadPrimitive>> {
    let mesh_name = match mesh.name() {
        Some(n) => format!("mesh '{n}' (index {})", mesh.index()),
        None => format!("mesh {}", mesh.index()),
    };
    let at = || Some(format!("{mesh_name}, primitive {}", primitive.index()));
    if matches!(
        primitive.mode(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
    ) {
        return Ok(None);
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
        let attributes: [(Option<gltf::Accessor>, &str, Dimensions); 4] = [
            (
                primitive.get(&Semantic::Positions),
                "POSITION",
                Dimensions::Vec3,
            ),
            (
                primitive.get(&Semantic::Normals),
                "NORMAL",
                Dimensions::Vec3,
            ),
            (
                texture_set.and_then(|set| primitive.get(&Semantic::TexCoords(set))),
                "TEXCOORD",
                Dimensions::Vec2,
            ),
            (tangents, "TANGENT", Dimensions::Vec4),
        ];
        if let Some(a) = primitive.get(&Semantic::Colors(0)) {
            let normalized_int = matches!(a.data_type(), DataType::U8 | DataType::U16);
            let type_ok = a.data_type() == DataType::F32 || (normalized_int && a.normalized());
            if !type_ok || !matches!(a.dimensions(), Dimensions::Vec3 | Dimensions::Vec4) {
                return Err(Error::input(
                    path,
                    at(),
                    format!(
                        "COLOR_0 accessor {} holds {:?} {:?}{}, which glTF does not allow there",
                        a.index(),
                        a.dimensions(),
                        a.data_type(),
                        if normalized_int {
                            " (not normalized)"
                        } else {
                            ""
                        }
                    ),
                ));
            }
        }
        for (accessor, what, dimensions) in attributes {
            if let Some(a) = accessor {
                let wrong_shape = (a.dimensions() != dimensions).then(|| {
                    format!(
                        "{what} accessor {} holds {:?} {:?}, which glTF does not allow there",
                        a.index(),
                        a.dimensions(),
                        a.data_type()
                    )
                });
                if let Some(message) =
                    wrong_shape.or_else(|| gltf_geometry::check_attribute(&a, what))
                {
                    return Err(Error::input(path, at(), message));
                }
            }
        }
        if let Some(a) = primitive.indices()
            && (![DataType::U8, DataType::U16, DataType::U32].contains(&a.data_type())
                || a.dimensions() != Dimensions::Scalar)
        {
            return Err(Error::input(
                path,
                at(),
                format!(
                    "indices accessor {} holds {:?} {:?}, which glTF does not allow there",
                    a.index(),
                    a.dimensions(),
                    a.data_type()
                ),
            ));
        }
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    // Attributes are read here rather than by the `gltf` reader, which takes only floats for
    // positions, normals and tangents: `KHR_mesh_quantization` allows integers.
    let attribute = |semantic: gltf::Semantic| primitive.get(&semantic);
    let mut positions: Vec<Vec3> = attribute(gltf::Semantic::Positions)
        .and_then(|a| gltf_geometry::read_floats::<3>(&a, buffers))
        .ok_or_else(|| {
            Error::input(
                path,
                at(),
                "POSITION is missing, or its accessor lies outside its buffer",
            )
        })?
        .into_iter()
        .map(Vec3::from)
        .collect();
    let n = positions.len();
    let mut normals: Vec<Vec3> = attribute(gltf::Semantic::Normals)
        .and_then(|a| gltf_geometry::read_floats::<3>(&a, buffers))
        .map(|v| v.into_iter().map(Vec3::from).collect())
        .unwrap_or_default();
    let uvs: Vec<Vec2> = material
        .uv_set
        .and_then(|set| attribute(gltf::Semantic::TexCoords(set)))
        .and_then(|a| gltf_geometry::read_floats::<2>(&a, buffers))
        .map(|v| v.into_iter().map(Vec2::from).collect())
        .unwrap_or_default();
    let mut tangents: Vec<Vec4> = match material.textures.normal {
        Some(_) => attribute(gltf::Semantic::Tangents)
            .and_then(|a| gltf_geometry::read_floats::<4>(&a, buffers))
            .map(|v| v.into_iter().map(Vec4::from).collect())
            .unwrap_or_default(),
        None => Vec::new(),
    };
    {
        let mut vertices = gltf_deform::Vertices {
            positions: &mut positions,
            normals: if normals.len() == n {
                &mut normals
            } else {
                &mut []
            },
            tangents: if tangents.len() == n {
                &mut tangents
            } else {
                &mut []
            },
        };
        gltf_deform::apply_morph_targets(primitive, deform.weights, buffers, &mut vertices)
            .and_then(|()| match deform.joints {
                Some(joints) => gltf_deform::apply_skin(
                    primitive,
                    joints,
                    deform.world_from_node,
                    buffers,
                    &mut vertices,
                ),
                None => Ok(()),
            })
            .map_err(|message| Error::input(path, at(), message))?;
    }
    let colors: Vec<Vec4> = reader
        .read_colors(0)
        .map(|it| it.into_rgba_f32().map(Vec4::from).collect())
        .unwrap_or_default();
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
    let flat = match primitive.mode() {
        Mode::TriangleStrip => strip_to_list(&flat),
        Mode::TriangleFan => fan_to_list(&flat),
        _ => flat,
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
    // Colours outside [0, 1] (float accessors may hold anything) are clamped: a colour above
    // 1 would make the surface reflect more light than it receives.
    let colors = (colors.len() == n && colors.iter().all(|c| c.is_finite())).then(|| {
        VertexColors(
            colors
                .into_iter()
                .map(|c| c.clamp(Vec4::ZERO, Vec4::ONE))
                .collect(),
        )
    });
    Ok(Some((mesh, tangents, colors)))
}

/// A triangle strip's triangles as a list, each with the strip's alternating winding
/// turned into one orientation (glTF 2.0, 3.7.2.1: triangle i is (i, i+1+i%2, i+2-i%2)).
fn strip_to_list(strip: &[u32]) -> Vec<u32> {
    (0..strip.len().saturating_sub(2))
        .flat_map(|i| [strip[i], strip[i + 1 + i % 2], strip[i + 2 - i % 2]])
        .collect()
}

/// A triangle fan's triangles as a list: (0, i+1, i+2), the winding of glTF's (i+1, i+2, 0).
fn fan_to_list(fan: &[u32]) -> Vec<u32> {
    (0..fan.len().saturating_sub(2))
        .flat_map(|i| [fan[0], fan[i + 1], fan[i + 2]])
        .collect()
}
