//! The walk over a glTF scene's node hierarchy that spawns the entities: each node's world
//! transform, its mesh (one entity per triangle primitive, `Name` = the node's name, the mesh
//! in node space with the node's world [`Transform`], at the node or at each of its
//! `EXT_mesh_gpu_instancing` instances), its camera and its light (`lights_cameras.rs`). A mesh
//! drawn more than once is read once and shared ([`SharedMesh`]); a deformed one is read for
//! its node. Primitives that cannot be read are skipped with one warning each; a file left
//! with nothing to render is an error.

use super::accessors::read_floats;
use super::animation::{self, Placed};
use super::check::node_location;
use super::deform::{self, Deform};
use super::lights_cameras::{spawn_camera, spawn_light};
use super::materials::ImportedMaterial;
use super::primitives::read_primitive;
use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat4, Quat, Vec3};
use crate::scene::load::shared::UpAxis;
use crate::scene::{
    Mesh, Name, PunctualLight, SharedMesh, Transform, VertexColors, VertexTangents,
};
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

/// A primitive as read, shareable between the entities that draw it.
type SharedRead = (Arc<Mesh>, Option<VertexTangents>, Option<VertexColors>);

/// A mesh and primitive index, which warnings and the read cache are keyed by.
type PrimitiveKey = (usize, usize);

/// The parts of the file the walk reads.
pub(super) struct Parts<'a> {
    pub(super) path: &'a Path,
    pub(super) document: &'a gltf::Document,
    pub(super) buffers: &'a [gltf::buffer::Data],
    /// The file's materials, by index.
    pub(super) materials: &'a [ImportedMaterial],
    /// The file's animations as JSON (`animation.rs`), when it has any: the entities of
    /// animated files record the node that placed them.
    pub(super) animations: &'a Option<serde_json::Value>,
}

/// The walk's state: the world it fills and what it has read, warned and counted.
struct NodeWalk<'a> {
    parts: &'a Parts<'a>,
    /// The material of primitives without one.
    default_material: &'a ImportedMaterial,
    warnings: &'a mut Vec<String>,
    world: hecs::World,
    /// Every node's world transform, for skins' joints.
    node_world: Vec<Option<Affine3A>>,
    /// How many times each mesh is drawn (nodes and GPU instances).
    mesh_uses: Vec<usize>,
    /// Primitives of shared meshes, read once.
    read_cache: HashMap<PrimitiveKey, SharedRead>,
    /// Skins already warned about.
    bad_skins: HashSet<usize>,
    /// One warning per bad primitive even when several nodes use its mesh.
    skip_warned: HashSet<PrimitiveKey>,
    lines_warned: HashSet<PrimitiveKey>,
    primitives_seen: usize,
    primitives_read: usize,
    lines_skipped: usize,
    /// The first skipped primitive's warning, for the error when nothing is left.
    first_skip: Option<String>,
}

/// Spawns the entities of the scene's nodes into a new world; also returns the indices of
/// the scene's root nodes (for posing animations).
pub(super) fn spawn_nodes(
    parts: &Parts,
    up: UpAxis,
    warnings: &mut Vec<String>,
) -> Result<(hecs::World, Vec<usize>)> {
    let (path, document) = (parts.path, parts.document);
    let roots = scene_roots(document, path, warnings)?;
    let root_indices = roots.iter().map(|n| n.index()).collect();
    let world_from_file = up.world_from_file();
    let node_count = document.nodes().len();
    let default_material = ImportedMaterial::blender_default();
    let mut walk = NodeWalk {
        parts,
        default_material: &default_material,
        warnings,
        world: hecs::World::new(),
        node_world: deform::node_world_transforms(
            roots.iter().cloned(),
            node_count,
            world_from_file,
        ),
        mesh_uses: mesh_uses(document),
        read_cache: HashMap::new(),
        bad_skins: HashSet::new(),
        skip_warned: HashSet::new(),
        lines_warned: HashSet::new(),
        primitives_seen: 0,
        primitives_read: 0,
        lines_skipped: 0,
        first_skip: None,
    };
    let mut stack: Vec<(gltf::Node, Affine3A, usize)> = roots
        .iter()
        .map(|n| (n.clone(), world_from_file, 0usize))
        .collect();
    stack.reverse(); // visit in document order
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
            walk.spawn_mesh(&node, &mesh, world_from_node, &name);
        }
        let camera = spawn_camera(
            &mut walk.world,
            &node,
            &name,
            world_from_node,
            path,
            walk.warnings,
        )?;
        if let Some(entity) = camera {
            animation::bind(
                &mut walk.world,
                entity,
                parts.animations,
                node.index(),
                Placed::Camera,
            );
        }
        if let Some(entity) = spawn_light(
            &mut walk.world,
            &node,
            &name,
            world_from_node,
            path,
            document,
        )? {
            animation::bind(
                &mut walk.world,
                entity,
                parts.animations,
                node.index(),
                Placed::Light,
            );
        }
        let children: Vec<_> = node.children().collect();
        for child in children.into_iter().rev() {
            stack.push((child, world_from_node, depth + 1));
        }
    }
    Ok((walk.finish()?, root_indices))
}

/// How many times each mesh is drawn (nodes and GPU instances): a mesh drawn more than once
/// is read once and shared ([`SharedMesh`]).
fn mesh_uses(document: &gltf::Document) -> Vec<usize> {
    let mut mesh_uses = vec![0usize; document.meshes().len()];
    for node in document.nodes() {
        if let Some(mesh) = node.mesh() {
            mesh_uses[mesh.index()] += instance_count(&node, document).unwrap_or(1);
        }
    }
    mesh_uses
}

impl NodeWalk<'_> {
    /// Spawns one entity per triangle primitive of `mesh` and placement of `node`.
    fn spawn_mesh(
        &mut self,
        node: &gltf::Node,
        mesh: &gltf::Mesh,
        world_from_node: Affine3A,
        name: &str,
    ) {
        let joints = self.joint_matrices(node);
        let deform = Deform {
            weights: node.weights().or(mesh.weights()).unwrap_or(&[]),
            joints: joints.as_deref(),
            world_from_node,
        };
        // A deformed mesh is this node's own: read for it, never shared.
        let deformed = deform.joints.is_some() || deform.weights.iter().any(|&w| w != 0.0);
        let placements = self.placements(node, world_from_node, deform.joints.is_some());
        let shared = !deformed && (self.mesh_uses[mesh.index()] >= 2 || placements.len() >= 2);
        let (materials, default_material) = (self.parts.materials, self.default_material);
        for primitive in mesh.primitives() {
            let imported = primitive
                .material()
                .index()
                .map_or(default_material, |i| &materials[i]);
            self.primitives_seen += 1;
            let Some(read) = self.read_once(&primitive, mesh, imported, &deform, deformed, shared)
            else {
                continue;
            };
            self.primitives_read += 1;
            let entities =
                spawn_primitive(&mut self.world, name, imported, read, &placements, shared);
            if self.parts.animations.is_some() {
                let instanced =
                    deform.joints.is_none() && node.extension_value(GPU_INSTANCING).is_some();
                for (instance, entity) in entities.into_iter().enumerate() {
                    let placed = Placed::Mesh {
                        mesh: mesh.index(),
                        primitive: primitive.index(),
                        instance: instanced.then_some(instance),
                        skinned: deform.joints.is_some(),
                    };
                    animation::bind(
                        &mut self.world,
                        entity,
                        self.parts.animations,
                        node.index(),
                        placed,
                    );
                }
            }
        }
    }

    /// The node's skin posed, or `None` (with one warning per skin) when it cannot be: its
    /// meshes are then shown unposed.
    fn joint_matrices(&mut self, node: &gltf::Node) -> Option<Vec<Affine3A>> {
        let skin = node.skin()?;
        deform::joint_matrices(&skin, &self.node_world, self.parts.buffers)
            .map_err(|why| {
                if self.bad_skins.insert(skin.index()) {
                    self.warnings.push(format!(
                        "{}: skin {}: {why}; its meshes are shown unposed",
                        self.parts.path.display(),
                        skin.index()
                    ));
                }
            })
            .ok()
    }

    /// Where the node's mesh is drawn: at the node, or at each of its GPU instances.
    fn placements(
        &mut self,
        node: &gltf::Node,
        world_from_node: Affine3A,
        skinned: bool,
    ) -> Vec<Affine3A> {
        let parts = self.parts;
        match instance_transforms(node, parts.document, parts.buffers) {
            // A skinned mesh's vertices come out in world space (see `deform.rs`).
            _ if skinned => vec![Affine3A::IDENTITY],
            None => vec![world_from_node],
            Some(Ok(local)) => local.iter().map(|t| world_from_node * *t).collect(),
            Some(Err(message)) => {
                self.warnings.push(format!(
                    "{}: {}: EXT_mesh_gpu_instancing: {message}; the node's instances \
                         are skipped",
                    parts.path.display(),
                    node_location(node)
                ));
                Vec::new()
            }
        }
    }

    /// The primitive read (or taken from the cache when its mesh is shared), or `None` when it
    /// is skipped: points and lines are counted, errors warned once per primitive.
    fn read_once(
        &mut self,
        primitive: &gltf::Primitive,
        mesh: &gltf::Mesh,
        imported: &ImportedMaterial,
        deform: &Deform,
        deformed: bool,
        shared: bool,
    ) -> Option<SharedRead> {
        let key = (mesh.index(), primitive.index());
        if let Some(read) = self.read_cache.get(&key).filter(|_| !deformed) {
            return Some(read.clone());
        }
        let parts = self.parts;
        match read_primitive(primitive, mesh, imported, deform, parts.buffers, parts.path) {
            Ok(Some((m, t, c))) => {
                let read = (Arc::new(m), t, c);
                if shared {
                    self.read_cache.insert(key, read.clone());
                }
                Some(read)
            }
            Ok(None) => {
                if self.lines_warned.insert(key) {
                    self.lines_skipped += 1;
                }
                None
            }
            Err(e) => {
                if self.skip_warned.insert(key) {
                    let message = format!("{e}; the primitive is skipped");
                    self.first_skip.get_or_insert_with(|| message.clone());
                    self.warnings.push(message);
                }
                None
            }
        }
    }

    /// The world, once the lines and points skipped are told; an error when the file had
    /// primitives but none could be read and it has no lights either.
    fn finish(self) -> Result<hecs::World> {
        crate::memory::trace_phase("meshes");
        let path = self.parts.path;
        let lines_skipped = self.lines_skipped;
        if lines_skipped > 0 {
            self.warnings.push(format!(
                "{}: points and lines are not rendered ({lines_skipped} primitive{} skipped)",
                path.display(),
                super::fix::plural(lines_skipped)
            ));
        }
        let document = self.parts.document;
        let dropped_before = document.meshes().any(|m| m.primitives().next().is_none());
        if self.primitives_read == 0 && (self.primitives_seen > 0 || dropped_before) {
            let has_lights = self.world.query::<&PunctualLight>().iter().next().is_some();
            if !has_lights {
                let why = self
                    .first_skip
                    .or_else(|| {
                        self.warnings
                            .iter()
                            .find(|w| w.contains("skipped"))
                            .cloned()
                    })
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
        Ok(self.world)
    }
}

/// Spawns the entities of one read primitive, one per placement (returned in placement
/// order). A mesh used once stays a plain `Mesh` (the common case, which every reader of the
/// world knows); a shared one is stored once.
fn spawn_primitive(
    world: &mut hecs::World,
    name: &str,
    imported: &ImportedMaterial,
    (mesh_data, tangents, colors): SharedRead,
    placements: &[Affine3A],
    shared: bool,
) -> Vec<hecs::Entity> {
    let mut entities = Vec::with_capacity(placements.len());
    let (mut plain, shared_data) = if shared {
        (None, Some(mesh_data))
    } else {
        (Some(Arc::unwrap_or_clone(mesh_data)), None)
    };
    for world_from_object in placements {
        let entity = world.spawn((
            Name(name.to_string()),
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
        if let Some(i) = imported.iridescence {
            world.insert_one(entity, i).expect("just spawned");
        }
        entities.push(entity);
    }
    entities
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
pub(super) fn instance_transforms(
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
            Some(a) => Some(read_floats::<3>(a, buffers).ok_or(outside("TRANSLATION"))?),
            None => None,
        };
        let rotations = match &rotation {
            Some(a) => Some(read_floats::<4>(a, buffers).ok_or(outside("ROTATION"))?),
            None => None,
        };
        let scales = match &scale {
            Some(a) => Some(read_floats::<3>(a, buffers).ok_or(outside("SCALE"))?),
            None => None,
        };
        let mut transforms = Vec::with_capacity(count);
        for i in 0..count {
            let t = translations
                .as_ref()
                .map_or(Vec3::ZERO, |v| Vec3::from(v[i]));
            let r = rotations
                .as_ref()
                .map_or(Quat::IDENTITY, |v| Quat::from_array(v[i]));
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
