//! Animation playback: the keyframe curves of imported files (glTF 2.0 animations), the node
//! hierarchy they move ([`Rig`]), and [`Scene::pose`], which poses the world at a time.
//!
//! The glTF loader attaches an [`Animated`] component to every entity a node of an animated
//! file places (meshes, cameras, punctual lights); all of them share the file's [`Rig`].
//! Posing recomputes each entity's [`Transform`] (or [`Camera`], or deformed vertices) from
//! the rig's rest data, never from the current state: posing at a time gives the same world
//! whatever was posed before, so a frame rendered alone equals the same frame of a sequence.
//!
//! What is read from the file (channels, samplers, their checks) is the loader's business
//! (`load/gltf/animation.rs`); skinning and morphing reuse the loader's own deformation.
//! Not here: material, camera-lens and light-property animation (`KHR_animation_pointer`
//! targets other than node transforms and weights), which the loader warns about.

use crate::error::{Error, Result};
use crate::math::{Affine3A, Quat, Vec3};
use crate::scene::load::Scene;
use crate::scene::load::gltf_animation::{self, GltfSource};
use crate::scene::{Camera, Mesh, SharedMesh, Transform, VertexTangents};
use std::path::PathBuf;
use std::sync::Arc;

/// Which of a file's animations plays (`--animation NAME|INDEX`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum AnimationChoice {
    /// The file's first animation (Blender's importer makes it the active one).
    #[default]
    First,
    /// The animation at this index (0-based, in file order).
    Index(usize),
    /// The animation of this name.
    Name(String),
}

impl AnimationChoice {
    /// A number is an index, anything else a name.
    pub fn parse(text: &str) -> Self {
        match text.parse::<usize>() {
            Ok(index) => AnimationChoice::Index(index),
            Err(_) => AnimationChoice::Name(text.to_string()),
        }
    }
}

impl std::fmt::Display for AnimationChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AnimationChoice::First => write!(f, "the first animation"),
            AnimationChoice::Index(i) => write!(f, "animation {i}"),
            AnimationChoice::Name(n) => write!(f, "animation '{n}'"),
        }
    }
}

/// How a curve goes from one key to the next (glTF 2.0, 3.11, `sampler.interpolation`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Straight lines; rotations by spherical linear interpolation.
    Linear,
    /// Each key's value holds until the next key.
    Step,
    /// Cubic Hermite spline through the values, with the file's in and out tangents.
    CubicSpline,
}

/// One animated property's keys: `times` in seconds (finite, strictly increasing, at least
/// one) and `width` numbers per key, three times that for [`Interpolation::CubicSpline`]
/// (in-tangent, value, out-tangent, as glTF stores them).
#[derive(Clone, Debug, PartialEq)]
pub struct Keyframes {
    /// How values between keys are found.
    pub interpolation: Interpolation,
    /// Key times in seconds.
    pub times: Vec<f32>,
    /// The keys' numbers, key after key.
    pub values: Vec<f32>,
    /// Numbers per value: 3 (translation, scale), 4 (rotation, x y z w), or the number of
    /// morph targets (weights).
    pub width: usize,
}

impl Keyframes {
    /// The numbers of key `k`'s value.
    fn value(&self, k: usize) -> &[f32] {
        let w = self.width;
        let start = match self.interpolation {
            Interpolation::CubicSpline => (3 * k + 1) * w,
            _ => k * w,
        };
        &self.values[start..start + w]
    }

    /// The curve at `seconds` into `out` (`width` numbers). Before the first key it holds the
    /// first value, after the last the last (as players do). A `rotation` (a unit quaternion)
    /// is interpolated by slerp along the shorter arc (LINEAR) and normalised.
    pub fn sample(&self, seconds: f32, rotation: bool, out: &mut [f32]) {
        let n = self.times.len();
        debug_assert!(n >= 1 && out.len() == self.width);
        let next = self.times.partition_point(|&t| t <= seconds);
        if next == 0 || next == n {
            out.copy_from_slice(self.value(if next == 0 { 0 } else { n - 1 }));
            return;
        }
        let k = next - 1;
        let interval = self.times[next] - self.times[k];
        let s = (seconds - self.times[k]) / interval;
        match self.interpolation {
            Interpolation::Step => out.copy_from_slice(self.value(k)),
            Interpolation::Linear if rotation => {
                let (a, b) = (self.value(k), self.value(next));
                let a = Quat::from_xyzw(a[0], a[1], a[2], a[3]).normalize();
                let b = Quat::from_xyzw(b[0], b[1], b[2], b[3]).normalize();
                out.copy_from_slice(&a.slerp(b, s).normalize().to_array());
            }
            Interpolation::Linear => {
                for (o, (a, b)) in out
                    .iter_mut()
                    .zip(self.value(k).iter().zip(self.value(next)))
                {
                    *o = (1.0 - s) * a + s * b;
                }
            }
            Interpolation::CubicSpline => {
                // Hermite basis (glTF 2.0, Appendix C); the tangents are per second, so they
                // are scaled by the key interval.
                let w = self.width;
                let (s2, s3) = (s * s, s * s * s);
                let h_value0 = 2.0 * s3 - 3.0 * s2 + 1.0;
                let h_out0 = interval * (s3 - 2.0 * s2 + s);
                let h_value1 = -2.0 * s3 + 3.0 * s2;
                let h_in1 = interval * (s3 - s2);
                let out_tangent0 = &self.values[(3 * k + 2) * w..(3 * k + 3) * w];
                let in_tangent1 = &self.values[3 * next * w..(3 * next + 1) * w];
                let (value0, value1) = (self.value(k), self.value(next));
                for (i, o) in out.iter_mut().enumerate() {
                    *o = h_value0 * value0[i]
                        + h_out0 * out_tangent0[i]
                        + h_value1 * value1[i]
                        + h_in1 * in_tangent1[i];
                }
                if rotation {
                    let q = Quat::from_slice(out).normalize();
                    out.copy_from_slice(&q.to_array());
                }
            }
        }
    }

    /// The time of the last key.
    pub fn end(&self) -> f32 {
        *self.times.last().expect("at least one key")
    }
}

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    /// The node's translation.
    Translation,
    /// The node's rotation (a quaternion x y z w).
    Rotation,
    /// The node's scale.
    Scale,
    /// The morph target weights of the node's mesh.
    Weights,
}

/// One animated property of one node.
#[derive(Clone, Debug)]
pub(crate) struct Channel {
    /// Index of the node in the rig.
    pub node: usize,
    pub property: Property,
    pub keys: Keyframes,
}

/// One animation of a file: its channels that could be read.
#[derive(Clone, Debug)]
pub(crate) struct Clip {
    pub name: Option<String>,
    pub channels: Vec<Channel>,
}

impl Clip {
    /// The time of the clip's last key (0 without channels).
    fn end(&self) -> f32 {
        self.channels
            .iter()
            .map(|c| c.keys.end())
            .fold(0.0, f32::max)
    }
}

/// A node of the rig: its rest transform relative to its parent, and its children.
#[derive(Clone, Debug)]
pub(crate) struct RigNode {
    /// The local transform as the loader computed it (the exact same matrix, so that an
    /// unanimated node keeps the loaded bits).
    pub rest: Affine3A,
    /// The rest translation, rotation and scale; `None` for a node given by a `matrix`,
    /// which glTF forbids to animate.
    pub trs: Option<(Vec3, Quat, Vec3)>,
    /// The default morph target weights (the node's, else its mesh's).
    pub weights: Vec<f32>,
    pub children: Vec<usize>,
}

/// An animated file's node hierarchy, its animations, and what deformation needs.
pub(crate) struct Rig {
    /// The file, for messages.
    pub path: PathBuf,
    /// The rotation from the file's up axis to the world's (applied above the roots).
    pub world_from_file: Affine3A,
    pub nodes: Vec<RigNode>,
    /// The scene's root nodes.
    pub roots: Vec<usize>,
    pub clips: Vec<Clip>,
    /// The document and buffers, read again to skin and morph meshes.
    pub source: GltfSource,
}

/// A rig posed at one time: every reachable node's world transform (with
/// `world_from_file`) and every node's morph weights.
pub(crate) struct Pose {
    pub world: Vec<Option<Affine3A>>,
    pub weights: Vec<Vec<f32>>,
}

impl Rig {
    /// "animation 'Walk' (index 0)" or "animation 2", for messages.
    fn clip_label(&self, index: usize) -> String {
        match &self.clips[index].name {
            Some(name) => format!("animation '{name}' (index {index})"),
            None => format!("animation {index}"),
        }
    }

    /// The clip `choice` names, or an error listing the file's animations.
    fn clip_index(&self, choice: &AnimationChoice) -> Result<usize> {
        let found = match choice {
            AnimationChoice::First => Some(0),
            AnimationChoice::Index(i) => Some(*i).filter(|&i| i < self.clips.len()),
            AnimationChoice::Name(n) => {
                (self.clips.iter()).position(|c| c.name.as_ref() == Some(n))
            }
        };
        found.filter(|&i| i < self.clips.len()).ok_or_else(|| {
            let known: Vec<String> = (0..self.clips.len()).map(|i| self.clip_label(i)).collect();
            Error::input(
                &self.path,
                None,
                format!("there is no {choice} (the file has {})", known.join(", ")),
            )
        })
    }

    /// The rig posed at `seconds` into clip `clip`.
    fn pose(&self, clip: &Clip, seconds: f32) -> Pose {
        let mut trs: Vec<Option<(Vec3, Quat, Vec3)>> = vec![None; self.nodes.len()];
        let mut weights: Vec<Vec<f32>> = self.nodes.iter().map(|n| n.weights.clone()).collect();
        let mut value = [0.0f32; 4];
        for channel in &clip.channels {
            let node = &self.nodes[channel.node];
            let Some(rest) = node.trs else {
                continue; // refused by the loader
            };
            let (t, r, s) = trs[channel.node].get_or_insert(rest);
            match channel.property {
                Property::Translation | Property::Scale => {
                    channel.keys.sample(seconds, false, &mut value[..3]);
                    let v = Vec3::from_slice(&value[..3]);
                    if channel.property == Property::Translation {
                        *t = v;
                    } else {
                        *s = v;
                    }
                }
                Property::Rotation => {
                    channel.keys.sample(seconds, true, &mut value);
                    *r = Quat::from_array(value);
                }
                Property::Weights => {
                    let w = &mut weights[channel.node];
                    w.resize(channel.keys.width, 0.0);
                    channel.keys.sample(seconds, false, w);
                }
            }
        }
        let local = |i: usize| match trs[i] {
            Some((t, r, s)) => Affine3A::from_scale_rotation_translation(s, r, t),
            None => self.nodes[i].rest,
        };
        // The same walk as the loader's: parent times local, from the roots down.
        let count = self.nodes.len();
        let mut world = vec![None; count];
        let mut stack: Vec<(usize, Affine3A, usize)> = self
            .roots
            .iter()
            .map(|&r| (r, self.world_from_file, 0))
            .collect();
        while let Some((node, parent, depth)) = stack.pop() {
            if depth > count || node >= count {
                continue; // a cycle: the loader reported it
            }
            let here = parent * local(node);
            world[node] = Some(here);
            stack.extend(
                self.nodes[node]
                    .children
                    .iter()
                    .map(|&c| (c, here, depth + 1)),
            );
        }
        Pose { world, weights }
    }
}

/// What an [`Animated`] entity shows of its node.
#[derive(Clone, Debug)]
pub(crate) enum AnimatedTarget {
    /// A rigid mesh or a punctual light: its [`Transform`] follows the node (times the GPU
    /// instance's transform, if it is one).
    Object { node_from_object: Option<Affine3A> },
    /// A camera: its eye and axes follow the node.
    Camera,
    /// A skinned mesh, or one whose morph weights are animated: its vertices are computed
    /// again from the file's (a skinned mesh's in world space, its `Transform` left alone).
    Deformed {
        mesh: usize,
        primitive: usize,
        node_from_object: Option<Affine3A>,
        skinned: bool,
    },
}

/// Marks an entity placed by a node of an animated file (see the module documentation).
#[derive(Clone)]
pub(crate) struct Animated {
    pub rig: Arc<Rig>,
    /// The node's index in the rig.
    pub node: usize,
    pub target: AnimatedTarget,
    /// What placed the file in a scene after loading (the room's stage, a scene file's
    /// `[[model]]` position): applied after the file's own transforms. `None` for a file
    /// rendered as it is (no multiplication, so the loaded bits are kept).
    pub placement: Option<Affine3A>,
}

impl Animated {
    /// Records that the entity's transform was premultiplied by `placement`.
    pub(crate) fn place(&mut self, placement: Affine3A) {
        self.placement = Some(match self.placement {
            Some(p) => placement * p,
            None => placement,
        });
    }

    fn placed(&self, t: Affine3A) -> Affine3A {
        match self.placement {
            Some(p) => p * t,
            None => t,
        }
    }
}

impl Scene {
    /// Whether any entity of the scene is moved by an animation.
    pub fn is_animated(&self) -> bool {
        self.world.query::<&Animated>().iter().next().is_some()
    }

    /// Poses every animated file of the scene at `seconds` into the animation `choice`
    /// names: node transforms, skins and morph weights, cameras and lights. A time past the
    /// animation's end holds its last pose (as players do), with a warning in the returned
    /// list (worded the same for every such time, so a sequence can say it once). A choice
    /// that names no animation of a file is an error that lists the file's animations.
    pub fn pose(&mut self, choice: &AnimationChoice, seconds: f32) -> Result<Vec<String>> {
        let mut rigs: Vec<Arc<Rig>> = Vec::new();
        for animated in self.world.query::<&Animated>().iter() {
            if !rigs.iter().any(|r| Arc::ptr_eq(r, &animated.rig)) {
                rigs.push(Arc::clone(&animated.rig));
            }
        }
        let mut warnings = Vec::new();
        let mut poses = Vec::with_capacity(rigs.len());
        for rig in &rigs {
            let index = rig.clip_index(choice)?;
            let clip = &rig.clips[index];
            let end = clip.end();
            if seconds > end {
                warnings.push(format!(
                    "{}: {} ends at {end} s; later frames hold its last pose",
                    rig.path.display(),
                    rig.clip_label(index)
                ));
            }
            poses.push(rig.pose(clip, seconds));
        }
        type Parts<'a> = (
            &'a Animated,
            Option<&'a mut Transform>,
            Option<&'a mut Camera>,
            Option<&'a mut Mesh>,
            Option<&'a mut SharedMesh>,
            Option<&'a mut VertexTangents>,
        );
        for (animated, transform, camera, mesh, shared, tangents) in self.world.query_mut::<Parts>()
        {
            let r = (rigs.iter())
                .position(|r| Arc::ptr_eq(r, &animated.rig))
                .expect("collected above");
            let pose = &poses[r];
            let Some(world_from_node) = pose.world[animated.node] else {
                continue; // not in the scene
            };
            let with_local = |local: Option<Affine3A>| match local {
                Some(l) => world_from_node * l,
                None => world_from_node,
            };
            match &animated.target {
                AnimatedTarget::Object { node_from_object } => {
                    if let Some(t) = transform {
                        t.0 = animated.placed(with_local(*node_from_object));
                    }
                }
                AnimatedTarget::Camera => {
                    if let Some(c) = camera {
                        *c = gltf_animation::camera_at(&animated.placed(world_from_node), c);
                    }
                }
                AnimatedTarget::Deformed {
                    mesh: mesh_index,
                    primitive,
                    node_from_object,
                    skinned,
                } => {
                    let target = gltf_animation::DeformTarget {
                        node: animated.node,
                        mesh: *mesh_index,
                        primitive: *primitive,
                        skinned: *skinned,
                    };
                    let deformed = match (mesh, shared) {
                        (Some(m), _) => {
                            gltf_animation::deform(&animated.rig, pose, &target, m, tangents)
                        }
                        (None, Some(s)) => {
                            let m = Arc::make_mut(&mut s.0);
                            gltf_animation::deform(&animated.rig, pose, &target, m, tangents)
                        }
                        (None, None) => Ok(()),
                    };
                    if let Err(why) = deformed {
                        warnings.push(format!(
                            "{}: mesh {mesh_index}, primitive {primitive}: {why}; it keeps its \
                             previous pose",
                            animated.rig.path.display()
                        ));
                    }
                    if let (false, Some(t)) = (*skinned, transform) {
                        t.0 = animated.placed(with_local(*node_from_object));
                    }
                }
            }
        }
        Ok(warnings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(
        interpolation: Interpolation,
        times: &[f32],
        values: &[f32],
        width: usize,
    ) -> Keyframes {
        Keyframes {
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
            width,
        }
    }

    fn at(k: &Keyframes, t: f32, rotation: bool) -> Vec<f32> {
        let mut out = vec![0.0; k.width];
        k.sample(t, rotation, &mut out);
        out
    }

    #[test]
    fn linear_and_step_hold_the_ends_and_interpolate_between() {
        let k = keys(Interpolation::Linear, &[1.0, 3.0], &[0.0, 10.0], 1);
        assert_eq!(at(&k, 0.0, false), [0.0]);
        assert_eq!(at(&k, 2.0, false), [5.0]);
        assert_eq!(at(&k, 9.0, false), [10.0]);
        let k = keys(Interpolation::Step, &[0.0, 1.0, 2.0], &[1.0, 2.0, 3.0], 1);
        assert_eq!(at(&k, 0.99, false), [1.0]);
        assert_eq!(at(&k, 1.0, false), [2.0]);
        assert_eq!(at(&k, 1.5, false), [2.0]);
    }

    #[test]
    fn rotation_slerps_along_the_shorter_arc() {
        let a = Quat::IDENTITY;
        // The same rotation as a 90 degree turn about z, stored with the opposite sign.
        let b = -Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let values: Vec<f32> = a.to_array().into_iter().chain(b.to_array()).collect();
        let k = keys(Interpolation::Linear, &[0.0, 1.0], &values, 4);
        let q = Quat::from_slice(&at(&k, 0.5, true));
        let want = Quat::from_rotation_z(std::f32::consts::FRAC_PI_4);
        assert!(q.dot(want).abs() > 1.0 - 1e-6, "{q}");
        assert!((q.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn cubic_spline_follows_the_hermite_curve_with_tangents_scaled_by_the_interval() {
        // From 0 to 1 over 2 s, out-tangent 1/s at the start, in-tangent 0 at the end.
        let k = keys(
            Interpolation::CubicSpline,
            &[0.0, 2.0],
            &[0.0, 0.0, 1.0, 0.0, 1.0, 0.0],
            1,
        );
        let s: f32 = 0.5;
        let want = (-2.0 * s.powi(3) + 3.0 * s * s) + 2.0 * (s.powi(3) - 2.0 * s * s + s);
        assert!((at(&k, 1.0, false)[0] - want).abs() < 1e-6);
        assert_eq!(at(&k, 2.0, false), [1.0]);
        assert_eq!(at(&k, -1.0, false), [0.0]);
    }

    #[test]
    fn choices_parse_numbers_as_indices() {
        assert_eq!(AnimationChoice::parse("2"), AnimationChoice::Index(2));
        assert_eq!(
            AnimationChoice::parse("Walk"),
            AnimationChoice::Name("Walk".into())
        );
    }
}
