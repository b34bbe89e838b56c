//! One glTF primitive read into a [`Mesh`]: its component types checked (the `gltf` crate's
//! readers panic on those the specification forbids), its attributes read (any component
//! type, through `accessors.rs`), morphed and skinned (`deform.rs`), its strips and fans
//! turned into triangle lists, and its tangents and vertex colours kept when they are usable.
//! Which primitives are read, and how often, is `nodes.rs`'s business.

use super::accessors::{check_attribute, read_floats};
use super::deform::{self, Deform};
use super::materials::ImportedMaterial;
use crate::error::{Error, Result};
use crate::math::{Vec2, Vec3, Vec4};
use crate::scene::load::shared::check_mesh;
use crate::scene::{Mesh, VertexColors, VertexTangents};
use gltf::Semantic;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use std::path::Path;

/// A primitive as read: its mesh, and its tangents and colours if it has them.
pub(super) type ReadPrimitive = (Mesh, Option<VertexTangents>, Option<VertexColors>);

/// Reads one primitive's triangles into a [`Mesh`], morphed, in node space (in world space
/// when `deform` skins it); `None` for points and lines, which are not rendered.
pub(super) fn read_primitive(
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
    let location = format!("{mesh_name}, primitive {}", primitive.index());
    let at = || Some(location.clone());
    if matches!(
        primitive.mode(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
    ) {
        return Ok(None);
    }
    check_component_types(primitive, material).map_err(|why| Error::input(path, at(), why))?;
    let mut vertices = read_attributes(primitive, material, buffers).ok_or_else(|| {
        Error::input(
            path,
            at(),
            "POSITION is missing, or its accessor lies outside its buffer",
        )
    })?;
    vertices
        .deform(primitive, deform, buffers)
        .map_err(|message| Error::input(path, at(), message))?;
    let n = vertices.positions.len();
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
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
    let RawVertices {
        positions,
        normals,
        uvs,
        tangents,
    } = vertices;
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
    Ok(Some(with_tangents_and_colors(mesh, tangents, colors)))
}

/// Checks the component types and shapes of the attributes and indices the primitive will be
/// read with: gltf 1.4.1's readers panic (`unreachable!`) on component types the
/// specification forbids, and its validation does not catch them (found by fuzzing).
fn check_component_types(
    primitive: &gltf::Primitive,
    material: &ImportedMaterial,
) -> std::result::Result<(), String> {
    let texture_set = material.uv_set;
    let tangents = (material.textures.needs_tangents())
        .then(|| primitive.get(&Semantic::Tangents))
        .flatten();
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
            return Err(format!(
                "COLOR_0 accessor {} holds {:?} {:?}{}, which glTF does not allow there",
                a.index(),
                a.dimensions(),
                a.data_type(),
                if normalized_int {
                    " (not normalized)"
                } else {
                    ""
                }
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
            if let Some(message) = wrong_shape.or_else(|| check_attribute(&a, what)) {
                return Err(message);
            }
        }
    }
    if let Some(a) = primitive.indices()
        && (![DataType::U8, DataType::U16, DataType::U32].contains(&a.data_type())
            || a.dimensions() != Dimensions::Scalar)
    {
        return Err(format!(
            "indices accessor {} holds {:?} {:?}, which glTF does not allow there",
            a.index(),
            a.dimensions(),
            a.data_type()
        ));
    }
    Ok(())
}

/// A primitive's vertex attributes as read; an attribute whose count differs from the
/// positions' is dropped when the mesh is made.
struct RawVertices {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    /// Read only when the material has a normal map.
    tangents: Vec<Vec4>,
}

/// Reads the attributes (here rather than by the `gltf` reader, which takes only floats for
/// positions, normals and tangents: `KHR_mesh_quantization` allows integers); `None` when
/// POSITION is missing or lies outside its buffer.
fn read_attributes(
    primitive: &gltf::Primitive,
    material: &ImportedMaterial,
    buffers: &[gltf::buffer::Data],
) -> Option<RawVertices> {
    let attribute = |semantic: Semantic| primitive.get(&semantic);
    let positions: Vec<Vec3> = attribute(Semantic::Positions)
        .and_then(|a| read_floats::<3>(&a, buffers))?
        .into_iter()
        .map(Vec3::from)
        .collect();
    let normals: Vec<Vec3> = attribute(Semantic::Normals)
        .and_then(|a| read_floats::<3>(&a, buffers))
        .map(|v| v.into_iter().map(Vec3::from).collect())
        .unwrap_or_default();
    let uvs: Vec<Vec2> = material
        .uv_set
        .and_then(|set| attribute(Semantic::TexCoords(set)))
        .and_then(|a| read_floats::<2>(&a, buffers))
        .map(|v| v.into_iter().map(Vec2::from).collect())
        .unwrap_or_default();
    let tangents: Vec<Vec4> = if material.textures.needs_tangents() {
        attribute(Semantic::Tangents)
            .and_then(|a| read_floats::<4>(&a, buffers))
            .map(|v| v.into_iter().map(Vec4::from).collect())
            .unwrap_or_default()
    } else {
        Vec::new()
    };
    Some(RawVertices {
        positions,
        normals,
        uvs,
        tangents,
    })
}

impl RawVertices {
    /// Applies the node's morph targets, then its skin (see `deform.rs`).
    fn deform(
        &mut self,
        primitive: &gltf::Primitive,
        deform: &Deform,
        buffers: &[gltf::buffer::Data],
    ) -> std::result::Result<(), String> {
        let n = self.positions.len();
        let mut vertices = deform::Vertices {
            positions: &mut self.positions,
            normals: if self.normals.len() == n {
                &mut self.normals
            } else {
                &mut []
            },
            tangents: if self.tangents.len() == n {
                &mut self.tangents
            } else {
                &mut []
            },
        };
        deform::apply_morph_targets(primitive, deform.weights, buffers, &mut vertices).and_then(
            |()| match deform.joints {
                Some(joints) => deform::apply_skin(
                    primitive,
                    joints,
                    deform.world_from_node,
                    buffers,
                    &mut vertices,
                ),
                None => Ok(()),
            },
        )
    }
}

/// The mesh with its tangents (only of use with vertex normals to orthogonalise against) and
/// its vertex colours, when each has one finite value per vertex.
fn with_tangents_and_colors(mesh: Mesh, tangents: Vec<Vec4>, colors: Vec<Vec4>) -> ReadPrimitive {
    let n = mesh.positions.len();
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
    (mesh, tangents, colors)
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
