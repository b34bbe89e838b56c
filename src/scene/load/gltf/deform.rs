//! Deformations glTF applies to a mesh before it is drawn, in the pose the file holds (or,
//! called by `animation.rs`, an animated pose): morph targets blended with the node's
//! `weights` (else the mesh's), and linear-blend skinning by the joints' node transforms.
//!
//! A skinned primitive comes out in world space: the glTF specification says the skinned
//! mesh's own node transform is ignored and only the joints' transforms apply, so its entity
//! gets the identity [`crate::scene::Transform`].

use super::accessors::read_floats;
use crate::math::{Affine3A, Mat3, Mat4, Vec3, Vec4};

/// How a node deforms its mesh.
pub(super) struct Deform<'a> {
    /// Morph target weights (the node's, else the mesh's; empty: none).
    pub(super) weights: &'a [f32],
    /// The skin's joint matrices when the node has a skin that could be posed.
    pub(super) joints: Option<&'a [Affine3A]>,
    /// The node's world transform, for skinned vertices without weights.
    pub(super) world_from_node: Affine3A,
}

/// Every node's world transform (`world_from_file` times its ancestors' transforms) when the
/// node is reachable from `roots` without a cycle; `None` for the others.
pub(super) fn node_world_transforms<'a>(
    roots: impl Iterator<Item = gltf::Node<'a>>,
    node_count: usize,
    world_from_file: Affine3A,
) -> Vec<Option<Affine3A>> {
    let mut world = vec![None; node_count];
    let mut stack: Vec<(gltf::Node, Affine3A, usize)> =
        roots.map(|n| (n, world_from_file, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > node_count || node.index() >= node_count {
            continue; // a cycle: the loader reports it
        }
        let local = Affine3A::from_mat4(Mat4::from_cols_array_2d(&node.transform().matrix()));
        let here = parent * local;
        world[node.index()] = Some(here);
        stack.extend(node.children().map(|c| (c, here, depth + 1)));
    }
    world
}

/// The skinning matrix of each joint (`world_from_joint x inverse_bind`), or why the skin
/// cannot be posed.
pub(super) fn joint_matrices(
    skin: &gltf::Skin,
    node_world: &[Option<Affine3A>],
    buffers: &[gltf::buffer::Data],
) -> Result<Vec<Affine3A>, String> {
    let joints: Vec<gltf::Node> = skin.joints().collect();
    let inverse_bind: Vec<[f32; 16]> = match skin.inverse_bind_matrices() {
        Some(accessor) => read_floats::<16>(&accessor, buffers)
            .filter(|m| m.len() >= joints.len())
            .ok_or_else(|| {
                format!(
                    "its inverseBindMatrices accessor {} is not {} MAT4 floats inside its buffer",
                    accessor.index(),
                    joints.len()
                )
            })?,
        None => vec![Mat4::IDENTITY.to_cols_array(); joints.len()],
    };
    joints
        .iter()
        .zip(inverse_bind)
        .map(|(joint, ibm)| {
            let world = node_world
                .get(joint.index())
                .copied()
                .flatten()
                .ok_or_else(|| format!("joint node {} is not in the scene", joint.index()))?;
            let m = world * Affine3A::from_mat4(Mat4::from_cols_array(&ibm));
            if m.is_finite() {
                Ok(m)
            } else {
                Err(format!("joint node {} has no finite matrix", joint.index()))
            }
        })
        .collect()
}

/// One primitive's vertex attributes, deformed in place.
pub(super) struct Vertices<'a> {
    pub positions: &'a mut [Vec3],
    /// Empty when the primitive has no normals.
    pub normals: &'a mut [Vec3],
    /// Empty when the primitive's tangents are not used.
    pub tangents: &'a mut [Vec4],
}

/// Adds each morph target's displacements times its weight (glTF 2.0, 3.7.2.2); normals and
/// tangents are renormalised afterwards.
pub(super) fn apply_morph_targets(
    primitive: &gltf::Primitive,
    weights: &[f32],
    buffers: &[gltf::buffer::Data],
    v: &mut Vertices,
) -> Result<(), String> {
    let n = v.positions.len();
    let read = |accessor: gltf::Accessor, target: usize, what: &str| {
        read_floats::<3>(&accessor, buffers)
            .filter(|d| d.len() == n)
            .ok_or_else(|| {
                format!(
                    "morph target {target}: its {what} accessor {} is not {n} VEC3 values \
                     inside its buffer",
                    accessor.index()
                )
            })
    };
    for (t, (target, &w)) in primitive.morph_targets().zip(weights).enumerate() {
        if w == 0.0 {
            continue;
        }
        if !w.is_finite() {
            return Err(format!("morph target {t} has the weight {w}"));
        }
        if let Some(a) = target.positions() {
            for (p, d) in v.positions.iter_mut().zip(read(a, t, "POSITION")?) {
                *p += w * Vec3::from(d);
            }
        }
        if let Some(a) = target.normals().filter(|_| !v.normals.is_empty()) {
            for (p, d) in v.normals.iter_mut().zip(read(a, t, "NORMAL")?) {
                *p += w * Vec3::from(d);
            }
        }
        if let Some(a) = target.tangents().filter(|_| !v.tangents.is_empty()) {
            for (p, d) in v.tangents.iter_mut().zip(read(a, t, "TANGENT")?) {
                *p += w * Vec3::from(d).extend(0.0);
            }
        }
    }
    renormalise(v);
    Ok(())
}

/// Linear-blend skinning (glTF 2.0, 3.7.3): each vertex moves by the weighted sum of its
/// joints' matrices, from all `JOINTS_n`/`WEIGHTS_n` sets; the weights are normalised to sum
/// to 1. A vertex whose weights are all zero keeps `fallback` (its node's transform).
/// Positions, normals and tangents end in world space.
pub(super) fn apply_skin(
    primitive: &gltf::Primitive,
    joints: &[Affine3A],
    fallback: Affine3A,
    buffers: &[gltf::buffer::Data],
    v: &mut Vertices,
) -> Result<(), String> {
    use gltf::Semantic;
    let n = v.positions.len();
    let mut influences: Vec<Vec<([f32; 4], [f32; 4])>> = Vec::new();
    for set in 0.. {
        let (Some(j), Some(w)) = (
            primitive.get(&Semantic::Joints(set)),
            primitive.get(&Semantic::Weights(set)),
        ) else {
            break;
        };
        let indices = read_floats::<4>(&j, buffers)
            .filter(|x| x.len() == n && !j.normalized())
            .ok_or_else(|| {
                format!(
                    "JOINTS_{set} accessor {} is not {n} unsigned integer VEC4 values inside \
                     its buffer",
                    j.index()
                )
            })?;
        let weights = read_floats::<4>(&w, buffers)
            .filter(|x| x.len() == n)
            .ok_or_else(|| {
                format!(
                    "WEIGHTS_{set} accessor {} is not {n} VEC4 values inside its buffer",
                    w.index()
                )
            })?;
        influences.push(indices.into_iter().zip(weights).collect());
    }
    if influences.is_empty() {
        return Err("the node has a skin but the primitive has no JOINTS_0 and WEIGHTS_0".into());
    }
    for i in 0..n {
        let mut linear = Mat3::ZERO;
        let mut translation = Vec3::ZERO;
        let mut total = 0.0;
        for set in &influences {
            let (indices, weights) = set[i];
            for (&joint, &weight) in indices.iter().zip(&weights) {
                if weight == 0.0 {
                    continue;
                }
                let m = joints.get(joint as usize).ok_or_else(|| {
                    format!(
                        "vertex {i} names joint {joint}, but the skin has {}",
                        joints.len()
                    )
                })?;
                if !(weight.is_finite() && weight > 0.0) {
                    return Err(format!("vertex {i} has the joint weight {weight}"));
                }
                linear += Mat3::from(m.matrix3) * weight;
                translation += Vec3::from(m.translation) * weight;
                total += weight;
            }
        }
        let m = if total > 0.0 {
            Affine3A::from_mat3_translation(linear * (1.0 / total), translation / total)
        } else {
            fallback
        };
        transform_vertex(&m, i, v);
    }
    Ok(())
}

/// Moves vertex `i` by `m`: the position as a point, the normal by the inverse transpose,
/// the tangent as a direction (its handedness flips with a mirroring matrix).
fn transform_vertex(m: &Affine3A, i: usize, v: &mut Vertices) {
    v.positions[i] = m.transform_point3(v.positions[i]);
    let linear = Mat3::from(m.matrix3);
    if let Some(normal) = v.normals.get_mut(i) {
        let transformed = linear.inverse().transpose() * *normal;
        *normal = transformed.try_normalize().unwrap_or(*normal);
    }
    if let Some(tangent) = v.tangents.get_mut(i) {
        let direction = linear * tangent.truncate();
        let handedness = if linear.determinant() < 0.0 {
            -tangent.w
        } else {
            tangent.w
        };
        *tangent = direction
            .try_normalize()
            .unwrap_or(tangent.truncate())
            .extend(handedness);
    }
}

/// Normals and tangent directions back to unit length after displacement (left as they
/// are where the displacement cancelled them).
fn renormalise(v: &mut Vertices) {
    for normal in v.normals.iter_mut() {
        *normal = normal.try_normalize().unwrap_or(*normal);
    }
    for tangent in v.tangents.iter_mut() {
        let w = tangent.w;
        *tangent = tangent
            .truncate()
            .try_normalize()
            .unwrap_or(tangent.truncate())
            .extend(w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vertex_moves_by_the_blend_of_its_joints_and_normals_by_the_inverse_transpose() {
        let mut positions = [Vec3::new(1.0, 0.0, 0.0)];
        let mut normals = [Vec3::new(1.0, 1.0, 0.0).normalize()];
        let mut tangents = [Vec4::new(1.0, -1.0, 0.0, 1.0)];
        let mut v = Vertices {
            positions: &mut positions,
            normals: &mut normals,
            tangents: &mut tangents,
        };
        // Non-uniform scale: x doubled; the normal of the plane x - y = const leans to y.
        let m = Affine3A::from_scale(Vec3::new(2.0, 1.0, 1.0));
        transform_vertex(&m, 0, &mut v);
        assert_eq!(positions[0], Vec3::new(2.0, 0.0, 0.0));
        let expected = Vec3::new(0.5, 1.0, 0.0).normalize();
        assert!((normals[0] - expected).length() < 1e-6, "{}", normals[0]);
        // The tangent stays perpendicular to the normal.
        assert!(normals[0].dot(tangents[0].truncate()).abs() < 1e-6);
        assert_eq!(tangents[0].w, 1.0);
        let mirror = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        let mut v = Vertices {
            positions: &mut positions,
            normals: &mut normals,
            tangents: &mut tangents,
        };
        transform_vertex(&mirror, 0, &mut v);
        assert_eq!(tangents[0].w, -1.0, "a mirror flips the bitangent's sign");
    }
}
