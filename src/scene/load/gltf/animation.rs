//! glTF 2.0 animations, read for playback ([`crate::scene::animation`] plays them).
//!
//! `gltf-json`'s strict reader refuses some valid animations (`KHR_animation_pointer`
//! channels have no `node`) and a malformed channel would refuse the whole file, so
//! `gltf_fix` removes the `animations` array before that reader runs and this module reads it
//! from the file's JSON on its own ([`read_animations`]). Each channel is checked; a bad one
//! (missing sampler or node, input and output counts that disagree, times that do not
//! increase, NaN keys, a node given by a `matrix`) is skipped with a warning naming the file,
//! the animation and the channel. `KHR_animation_pointer` channels that point at a node's
//! translation, rotation, scale or weights play like plain channels; other pointers (material,
//! camera-lens and light properties) are ignored with one warning per file.
//!
//! While the loader spawns entities it records which node placed each one ([`bind`]); at the
//! end [`attach`] turns those records into [`Animated`] components sharing one [`Rig`], or
//! removes them when the file has no animations (its world is then exactly as before).
//! [`deform`] skins and morphs a mesh again for a pose, with the loader's own deformation
//! (`deform`), from the file's buffers, which the rig keeps.

use super::accessors::read_floats;
use super::deform::{Vertices, apply_morph_targets, apply_skin, joint_matrices};
pub(crate) use super::lights_cameras::camera_at;
use crate::math::{Affine3A, Mat4, Quat, Vec3, Vec4};
use crate::scene::animation::{
    Animated, AnimatedTarget, Channel, Clip, Interpolation, Keyframes, Pose, Property, Rig, RigNode,
};
use crate::scene::{Mesh, VertexTangents};
use serde_json::Value;
use std::path::Path;
use std::sync::Arc;

/// The parsed glTF document and its buffers, kept by an animated file's [`Rig`] to deform
/// meshes again (the memory of the file's buffers stays in use while the scene lives).
pub(crate) struct GltfSource {
    pub document: gltf::Document,
    pub buffers: Vec<gltf::buffer::Data>,
}

/// The `animations` array of a glTF file's JSON (a GLB's JSON chunk), `None` when the file
/// has none or its JSON does not parse (the loader reports that).
pub(super) fn read_animations(bytes: &[u8]) -> Option<Value> {
    #[derive(serde::Deserialize)]
    struct AnimationsOnly {
        #[serde(default)]
        animations: Option<Value>,
    }
    let json = if bytes.starts_with(b"glTF") {
        gltf::binary::Glb::from_slice(bytes).ok()?.json
    } else {
        std::borrow::Cow::Borrowed(bytes)
    };
    let read: AnimationsOnly = serde_json::from_slice(&json).ok()?;
    read.animations
        .filter(|a| a.as_array().is_some_and(|a| !a.is_empty()))
}

/// What placed an entity, recorded by the loader while it spawns.
#[derive(Clone, Copy, Debug)]
pub(super) enum Placed {
    /// Primitive `primitive` of mesh `mesh`; `instance` its `EXT_mesh_gpu_instancing`
    /// instance, if the node has them; `skinned` when the loader posed it by its skin.
    Mesh {
        mesh: usize,
        primitive: usize,
        instance: Option<usize>,
        skinned: bool,
    },
    Camera,
    Light,
}

/// The record [`bind`] attaches, until [`attach`] replaces it.
struct NodeBinding {
    node: usize,
    placed: Placed,
}

/// Hook of the loader's spawn walk: records that node `node` placed `entity`, when the file
/// has animations (`animations` from [`read_animations`]).
pub(super) fn bind(
    world: &mut hecs::World,
    entity: hecs::Entity,
    animations: &Option<Value>,
    node: usize,
    placed: Placed,
) {
    if animations.is_some() {
        world
            .insert_one(entity, NodeBinding { node, placed })
            .expect("just spawned");
    }
}

/// Hook at the end of the loader: reads the animations, and replaces the records of [`bind`]
/// with [`Animated`] components sharing the file's rig (which takes the document and the
/// buffers). `roots` are the scene's root nodes.
pub(super) fn attach(
    path: &Path,
    animations: Option<Value>,
    source: GltfSource,
    roots: Vec<usize>,
    world_from_file: Affine3A,
    world: &mut hecs::World,
    warnings: &mut Vec<String>,
) {
    let Some(animations) = animations else {
        return;
    };
    let clips = read_clips(
        path,
        &source.document,
        &source.buffers,
        &animations,
        warnings,
    );
    let nodes = source
        .document
        .nodes()
        .map(|node| rig_node(&node))
        .collect();
    let bindings: Vec<(hecs::Entity, usize, Placed)> = world
        .query::<(hecs::Entity, &NodeBinding)>()
        .iter()
        .map(|(e, b)| (e, b.node, b.placed))
        .collect();
    let morphed_nodes: Vec<usize> = (clips.iter())
        .flat_map(|c| c.channels.iter())
        .filter(|c| c.property == Property::Weights)
        .map(|c| c.node)
        .collect();
    let mut targets = Vec::with_capacity(bindings.len());
    for &(entity, node, placed) in &bindings {
        let target = match placed {
            Placed::Camera => AnimatedTarget::Camera,
            Placed::Light => AnimatedTarget::Object {
                node_from_object: None,
            },
            Placed::Mesh {
                mesh,
                primitive,
                instance,
                skinned,
            } => {
                let node_from_object = instance.and_then(|i| instance_transform(&source, node, i));
                if skinned || morphed_nodes.contains(&node) {
                    AnimatedTarget::Deformed {
                        mesh,
                        primitive,
                        node_from_object,
                        skinned,
                    }
                } else {
                    AnimatedTarget::Object { node_from_object }
                }
            }
        };
        targets.push((entity, node, target));
    }
    let rig = Arc::new(Rig {
        path: path.to_path_buf(),
        world_from_file,
        nodes,
        roots,
        clips,
        source,
    });
    for (entity, node, target) in targets {
        world.remove_one::<NodeBinding>(entity).expect("bound");
        let animated = Animated {
            rig: Arc::clone(&rig),
            node,
            target,
            placement: None,
        };
        world.insert_one(entity, animated).expect("bound");
    }
}

/// The local transform of GPU instance `instance` of `node`.
fn instance_transform(source: &GltfSource, node: usize, instance: usize) -> Option<Affine3A> {
    let node = source.document.nodes().nth(node)?;
    match super::nodes::instance_transforms(&node, &source.document, &source.buffers)? {
        Ok(locals) => locals.get(instance).copied(),
        Err(_) => None,
    }
}

/// A node's rest data.
fn rig_node(node: &gltf::Node) -> RigNode {
    let rest = Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix()));
    let trs = match node.transform() {
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => Some((
            Vec3::from(translation),
            Quat::from_array(rotation),
            Vec3::from(scale),
        )),
        gltf::scene::Transform::Matrix { .. } => None,
    };
    let weights = node
        .weights()
        .or_else(|| node.mesh().and_then(|m| m.weights()))
        .unwrap_or(&[])
        .to_vec();
    RigNode {
        rest,
        trs,
        weights,
        children: node.children().map(|c| c.index()).collect(),
    }
}

/// Every animation of the file, with the channels that could be read (the others warned
/// about and skipped).
fn read_clips(
    path: &Path,
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    animations: &Value,
    warnings: &mut Vec<String>,
) -> Vec<Clip> {
    let mut ignored_pointers: Vec<String> = Vec::new();
    let mut clips = Vec::new();
    for (a, animation) in animations.as_array().into_iter().flatten().enumerate() {
        let name = animation["name"].as_str().map(str::to_string);
        let label = match &name {
            Some(n) => format!("animation '{n}' (index {a})"),
            None => format!("animation {a}"),
        };
        let mut channels = Vec::new();
        let channel_values = animation["channels"].as_array().into_iter().flatten();
        for (c, channel) in channel_values.enumerate() {
            match read_channel(document, buffers, animation, channel) {
                Ok(Some(read)) => channels.push(read),
                Ok(None) => ignored_pointers.push(
                    channel["target"]["extensions"]["KHR_animation_pointer"]["pointer"]
                        .as_str()
                        .unwrap_or("?")
                        .to_string(),
                ),
                Err(why) => warnings.push(format!(
                    "{}: {label}, channel {c}: {why}; the channel is skipped",
                    path.display()
                )),
            }
        }
        clips.push(Clip { name, channels });
    }
    if !ignored_pointers.is_empty() {
        ignored_pointers.sort();
        ignored_pointers.dedup();
        let shown: Vec<&str> = ignored_pointers
            .iter()
            .take(3)
            .map(String::as_str)
            .collect();
        warnings.push(format!(
            "{}: KHR_animation_pointer channels that animate anything but a node's \
             translation, rotation, scale or weights are ignored ({}{})",
            path.display(),
            shown.join(", "),
            if ignored_pointers.len() > 3 {
                ", ..."
            } else {
                ""
            }
        ));
    }
    clips
}

/// The node and property a channel's target names: `target.node` and `target.path`, or a
/// `KHR_animation_pointer` to `/nodes/N/translation|rotation|scale|weights`. `Ok(None)`
/// for another pointer.
fn channel_target(channel: &Value) -> Result<Option<(u64, Property)>, String> {
    let target = &channel["target"];
    let property = |name: &str| match name {
        "translation" => Some(Property::Translation),
        "rotation" => Some(Property::Rotation),
        "scale" => Some(Property::Scale),
        "weights" => Some(Property::Weights),
        _ => None,
    };
    match target["path"].as_str() {
        Some("pointer") => {
            let pointer = target["extensions"]["KHR_animation_pointer"]["pointer"]
                .as_str()
                .ok_or("a pointer channel without a KHR_animation_pointer pointer")?;
            let parts: Vec<&str> = pointer.split('/').collect();
            Ok(match parts.as_slice() {
                ["", "nodes", node, name] => node.parse::<u64>().ok().zip(property(name)),
                _ => None,
            })
        }
        Some(name) => {
            let property = property(name).ok_or_else(|| format!("unknown target path '{name}'"))?;
            let node = target["node"].as_u64().ok_or("the target has no node")?;
            Ok(Some((node, property)))
        }
        None => Err("the target has no path".into()),
    }
}

/// One channel read and checked; `Ok(None)` for a pointer channel this module ignores.
fn read_channel(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    animation: &Value,
    channel: &Value,
) -> Result<Option<Channel>, String> {
    let Some((node_index, property)) = channel_target(channel)? else {
        return Ok(None);
    };
    let node = usize::try_from(node_index)
        .ok()
        .and_then(|i| document.nodes().nth(i))
        .ok_or_else(|| format!("node {node_index} does not exist"))?;
    if property != Property::Weights
        && matches!(node.transform(), gltf::scene::Transform::Matrix { .. })
    {
        return Err(format!(
            "node {node_index} has a matrix, which glTF does not allow to animate"
        ));
    }
    let sampler_index = channel["sampler"]
        .as_u64()
        .ok_or("the channel has no sampler")?;
    let sampler = &animation["samplers"][sampler_index as usize];
    if !sampler.is_object() {
        return Err(format!("sampler {sampler_index} does not exist"));
    }
    let interpolation = match sampler["interpolation"].as_str().unwrap_or("LINEAR") {
        "LINEAR" => Interpolation::Linear,
        "STEP" => Interpolation::Step,
        "CUBICSPLINE" => Interpolation::CubicSpline,
        other => return Err(format!("unknown interpolation '{other}'")),
    };
    let accessor = |key: &str| {
        sampler[key]
            .as_u64()
            .and_then(|i| document.accessors().nth(i as usize))
            .ok_or_else(|| format!("sampler {sampler_index}: its {key} accessor does not exist"))
    };
    let input = accessor("input")?;
    let times: Vec<f32> = read_floats::<1>(&input, buffers)
        .ok_or_else(|| {
            format!(
                "input accessor {} is not SCALAR numbers inside its buffer",
                input.index()
            )
        })?
        .into_iter()
        .map(|[t]| t)
        .collect();
    if times.is_empty() {
        return Err("the input has no keys".into());
    }
    if let Some(k) = times.iter().position(|t| !t.is_finite()) {
        return Err(format!("key time {k} is {}", times[k]));
    }
    if let Some(k) = times.windows(2).position(|w| w[1] <= w[0]) {
        return Err(format!(
            "key times do not increase ({} then {} at key {})",
            times[k],
            times[k + 1],
            k + 1
        ));
    }
    let output = accessor("output")?;
    let width = match property {
        Property::Translation | Property::Scale => 3,
        Property::Rotation => 4,
        Property::Weights => {
            let targets = (node.mesh().and_then(|m| m.primitives().next()))
                .map_or(0, |p| p.morph_targets().len());
            if targets == 0 {
                return Err(format!("node {node_index} has no mesh with morph targets"));
            }
            targets
        }
    };
    let values = read_output(&output, buffers, property).ok_or_else(|| {
        format!(
            "output accessor {} does not hold {} values inside its buffer",
            output.index(),
            match property {
                Property::Translation | Property::Scale => "VEC3",
                Property::Rotation => "VEC4",
                Property::Weights => "SCALAR",
            }
        )
    })?;
    let per_key = width
        * match interpolation {
            Interpolation::CubicSpline => 3,
            _ => 1,
        };
    if values.len() != times.len() * per_key {
        return Err(format!(
            "the input has {} keys but the output {} numbers ({per_key} per key expected)",
            times.len(),
            values.len()
        ));
    }
    if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
        return Err(format!("output number {bad} is {}", values[bad]));
    }
    Ok(Some(Channel {
        node: node.index(),
        property,
        keys: Keyframes {
            interpolation,
            times,
            values,
            width,
        },
    }))
}

/// A sampler's output as plain numbers.
fn read_output(
    output: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    property: Property,
) -> Option<Vec<f32>> {
    Some(match property {
        Property::Translation | Property::Scale => read_floats::<3>(output, buffers)?
            .into_iter()
            .flatten()
            .collect(),
        Property::Rotation => read_floats::<4>(output, buffers)?
            .into_iter()
            .flatten()
            .collect(),
        Property::Weights => read_floats::<1>(output, buffers)?
            .into_iter()
            .flatten()
            .collect(),
    })
}

/// Which primitive [`deform`] computes again.
pub(crate) struct DeformTarget {
    pub node: usize,
    pub mesh: usize,
    pub primitive: usize,
    pub skinned: bool,
}

/// Computes `mesh`'s positions and normals (and `tangents`) again from the file's vertices
/// for `pose`: morphed by the node's weights, then skinned by the joints' posed transforms
/// (in world space, as the loader does) when `target.skinned`.
pub(crate) fn deform(
    rig: &Rig,
    pose: &Pose,
    target: &DeformTarget,
    mesh: &mut Mesh,
    tangents: Option<&mut VertexTangents>,
) -> Result<(), String> {
    let GltfSource { document, buffers } = &rig.source;
    let primitive = (document.meshes().nth(target.mesh))
        .and_then(|m| m.primitives().nth(target.primitive))
        .ok_or("the primitive is not in the file")?;
    let n = mesh.positions.len();
    let read3 = |semantic: gltf::Semantic| {
        primitive
            .get(&semantic)
            .and_then(|a| read_floats::<3>(&a, buffers))
            .filter(|v| v.len() == n)
            .map(|v| v.into_iter().map(Vec3::from).collect::<Vec<Vec3>>())
    };
    mesh.positions = read3(gltf::Semantic::Positions).ok_or("its POSITION cannot be read")?;
    if !mesh.normals.is_empty() {
        mesh.normals = read3(gltf::Semantic::Normals).ok_or("its NORMAL cannot be read")?;
    }
    let mut no_tangents = VertexTangents::default();
    let tangents = match tangents {
        Some(t) => {
            t.0 = (primitive.get(&gltf::Semantic::Tangents))
                .and_then(|a| read_floats::<4>(&a, buffers))
                .filter(|v| v.len() == n)
                .ok_or("its TANGENT cannot be read")?
                .into_iter()
                .map(Vec4::from)
                .collect();
            t
        }
        None => &mut no_tangents,
    };
    let mut vertices = Vertices {
        positions: &mut mesh.positions,
        normals: &mut mesh.normals,
        tangents: &mut tangents.0,
    };
    apply_morph_targets(
        &primitive,
        &pose.weights[target.node],
        buffers,
        &mut vertices,
    )?;
    if target.skinned {
        let node = document.nodes().nth(target.node).ok_or("no node")?;
        let skin = node.skin().ok_or("the node has no skin")?;
        let joints = joint_matrices(&skin, &pose.world, buffers)?;
        let fallback = pose.world[target.node].ok_or("the node is not in the scene")?;
        apply_skin(&primitive, &joints, fallback, buffers, &mut vertices)?;
    }
    Ok(())
}
