//! Meshes: each mesh's triangles in world space (the winding kept under mirroring
//! transforms), with their vertex attributes (shading normals, texture coordinates, tangents
//! for normal maps); degenerate triangles are skipped with a warning.

use super::instances::InstanceRequest;
use super::lights::validate_emitter;
use super::materials::{self, MaterialTable};
use super::{Attributes, Columns, Group, Primitives};
use crate::accel::leaf_prims::LeafPrim;
use crate::alpha::{self, AlphaRecord};
use crate::error::{Error, Result};
use crate::geometry::{Shape, TriangleGeom};
use crate::math::{Rgb, Vec2, Vec3, Vec3A, Vec4};
use crate::scene::{
    AlphaCoverage, Emitter, Material, MaterialTextures, Mesh, Name, SharedMesh, Transform,
    VertexColors, VertexTangents, Volume, mesh_of,
};
use crate::texture::TextureRef;
use rayon::prelude::*;
use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

/// Appends every mesh of the world to `prims` (one group per mesh), its material to
/// `materials`.
/// Entities drawing a mesh of `instanced` (opaque, not emitting) are not flattened but
/// returned as instance requests.
pub(super) fn flatten_meshes(
    world: &hecs::World,
    path: &Path,
    materials: &mut MaterialTable,
    prims: &mut Primitives,
    instanced: &HashSet<*const Mesh>,
) -> Result<Vec<InstanceRequest>> {
    let mut requests = Vec::new();
    let Primitives {
        groups,
        columns,
        warnings,
        attributes,
        alpha_records,
    } = prims;
    let attributes = *attributes;
    for (
        (entity, name),
        transform,
        (mesh, shared),
        (material, alpha, volume),
        textures,
        (tangents, colors),
        emitter,
    ) in world
        .query::<(
            (hecs::Entity, Option<&Name>),
            Option<&Transform>,
            (Option<&Mesh>, Option<&SharedMesh>),
            (&Material, Option<&AlphaCoverage>, Option<&Volume>),
            Option<&MaterialTextures>,
            (Option<&VertexTangents>, Option<&VertexColors>),
            Option<&Emitter>,
        )>()
        .iter()
    {
        let Some(mesh) = mesh_of(mesh, shared) else {
            continue; // a sphere
        };
        let name = name.map_or("unnamed mesh", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let material = materials.index(material, textures, volume);
        let mut emitter = validate_emitter(emitter, path, name)?;
        if let Some(shared) = shared
            && instanced.contains(&Arc::as_ptr(&shared.0))
            && emitter.is_none()
            && alpha.is_none()
        {
            requests.push(InstanceRequest {
                mesh: shared.0.clone(),
                entity,
                world_from_object: transform,
                material,
                normal_mapped: textures.is_some_and(|t| t.normal.is_some()),
            });
            continue;
        }
        let emission_texture = textures
            .and_then(|t| t.emissive.as_ref())
            .filter(|_| emitter.is_some() && !mesh.uvs.is_empty())
            .map(|slot| (materials.interner.intern(Some(slot)), slot.texture.mean()));
        if emission_texture.is_some_and(|(_, mean)| mean == Rgb::ZERO) {
            emitter = None; // a black emission texture: nothing is emitted
        }
        let tangents = textures.and_then(|t| t.normal.as_ref()).map(|_| tangents);
        let alpha = match alpha {
            // Light sampling would still pick the cut-out parts of an emitter.
            Some(_) if emitter.is_some() => {
                warnings.push(format!(
                    "mesh '{name}': alpha coverage of an emitting surface is ignored; it is \
                     rendered opaque"
                ));
                alpha::OPAQUE
            }
            Some(coverage) => {
                let texture = textures
                    .and_then(|t| t.base_color.as_ref())
                    .filter(|slot| slot.texture.has_alpha() && !mesh.uvs.is_empty())
                    .map_or_else(TextureRef::default, |slot| {
                        materials.interner.intern(Some(slot))
                    });
                let vertex_alpha = colors.is_some_and(|c| c.0.iter().any(|c| c.w < 1.0));
                alpha_records.push(AlphaRecord {
                    mode: coverage.mode,
                    factor: coverage.factor,
                    texture,
                    vertex_alpha,
                });
                alpha_records.len() as u32 - 1
            }
            None => alpha::OPAQUE,
        };
        groups.push(Group {
            first: columns.leaf_prims.len(),
            material,
            emitter,
            emission_texture,
            alpha,
        });
        let vertex_attributes = (tangents, colors);
        let skipped = flatten_mesh(
            mesh,
            &transform,
            vertex_attributes,
            path,
            name,
            attributes,
            columns,
        )?;
        if skipped > 0 {
            let kind = if emitter.is_some() { " emitting" } else { "" };
            warnings.push(format!(
                "mesh '{name}': skipped {skipped} degenerate (zero-area){kind} triangles"
            ));
        }
    }
    Ok(requests)
}

/// Appends the valid world-space triangles of `mesh` to `columns` (the vertex attributes
/// that `attributes` asks for, zero where the mesh has none); returns how many degenerate
/// triangles were skipped. `tangents` is `Some` for normal-mapped meshes: `Some(Some(_))`
/// with the file's tangents, `Some(None)` to make them per triangle. `colors` are the mesh's
/// vertex colours, if it has any.
pub(super) fn flatten_mesh(
    mesh: &Mesh,
    world_from_object: &crate::math::Affine3A,
    (tangents, colors): (Option<Option<&VertexTangents>>, Option<&VertexColors>),
    path: &Path,
    name: &str,
    attributes: Attributes,
    columns: &mut Columns,
) -> Result<usize> {
    let at = || Some(format!("mesh '{name}'"));
    let n = mesh.positions.len();
    if !mesh.normals.is_empty() && mesh.normals.len() != n {
        return Err(Error::input(
            path,
            at(),
            format!("{} normals for {n} positions", mesh.normals.len()),
        ));
    }
    if !mesh.uvs.is_empty() && mesh.uvs.len() != n {
        return Err(Error::input(
            path,
            at(),
            format!("{} texture coordinates for {n} positions", mesh.uvs.len()),
        ));
    }
    if let Some(VertexColors(c)) = colors
        && c.len() != n
    {
        return Err(Error::input(
            path,
            at(),
            format!("{} vertex colours for {n} positions", c.len()),
        ));
    }
    if let Some(bad) = mesh.positions.par_iter().position_first(|p| !p.is_finite()) {
        return Err(Error::input(
            path,
            at(),
            format!("vertex {bad} is not finite"),
        ));
    }
    let normal_matrix = world_from_object.matrix3.inverse().transpose();
    let flips = world_from_object.matrix3.determinant() < 0.0;
    let world: Vec<Vec3A> = mesh
        .positions
        .par_iter()
        .map(|&p| world_from_object.transform_point3a(p.into()))
        .collect();
    if let Some(bad) = world.par_iter().position_first(|p| !p.is_finite()) {
        return Err(Error::input(
            path,
            at(),
            format!(
                "vertex {bad} {} overflows when transformed to world space",
                mesh.positions[bad]
            ),
        ));
    }
    // Vertex indices in the winding that keeps the front face under mirroring transforms.
    let corners = |t: usize| {
        let [a, b, c] = mesh.indices[t];
        if flips { [a, c, b] } else { [a, b, c] }
    };
    let geometry = |t: usize| {
        let p = corners(t).map(|i| world[i as usize]);
        TriangleGeom::new(p[0], p[1], p[2])
    };
    // Whether the triangle is kept (else: an index out of range, an area overflowing f32 or
    // a zero area; the slow path below tells these apart).
    let kept = |t: usize| {
        corners(t).iter().all(|&i| (i as usize) < n) && {
            let double_area = geometry(t).normal_unnormalized().length();
            double_area > 0.0 && double_area.is_finite()
        }
    };

    // --- Which triangles are kept: in the common case all, found by one parallel count.
    let count = mesh.indices.len();
    let kept_count = (0..count).into_par_iter().filter(|&t| kept(t)).count();
    let kept_triangles: Option<Vec<u32>> = if kept_count == count {
        None
    } else {
        for (t, &[a, b, c]) in mesh.indices.iter().enumerate() {
            if let Some(&bad) = [a, b, c].iter().find(|&&i| i as usize >= n) {
                return Err(Error::input(
                    path,
                    at(),
                    format!("triangle {t}: vertex index {bad} out of range ({n} vertices)"),
                ));
            }
            if !geometry(t).normal_unnormalized().length().is_finite() {
                // Finite vertices, but far enough apart (~1e19) that the area overflows f32:
                // the triangle cannot be intersected or sampled, and skipping it would change
                // the image.
                let p = corners(t).map(|i| Vec3::from(world[i as usize]));
                return Err(Error::input(
                    path,
                    at(),
                    format!(
                        "triangle {t}: its area (and normal) overflows f32; the vertices {}, {}, {} \
                         are too far apart (scale the model down)",
                        p[0], p[1], p[2]
                    ),
                ));
            }
        }
        Some(
            (0..count as u32)
                .into_par_iter()
                .filter(|&t| kept(t as usize))
                .collect(),
        )
    };
    // Appends `attribute(t)` for every kept triangle `t` to `column`.
    fn extend<T: Send>(
        column: &mut Vec<T>,
        kept_triangles: &Option<Vec<u32>>,
        count: usize,
        attribute: impl Fn(usize) -> T + Sync + Send,
    ) {
        match kept_triangles {
            None => column.par_extend((0..count).into_par_iter().map(attribute)),
            Some(kept) => column.par_extend(kept.par_iter().map(|&t| attribute(t as usize))),
        }
    }

    // --- Geometry and vertex attributes of the kept triangles, written in place.
    extend(&mut columns.leaf_prims, &kept_triangles, count, |t| {
        LeafPrim::new(&Shape::Triangle(geometry(t)))
    });
    let normals = |t: usize| {
        if mesh.normals.is_empty() {
            return [Vec3::ZERO; 3];
        }
        let normals = corners(t).map(|i| {
            Vec3::from(normal_matrix * Vec3A::from(mesh.normals[i as usize])).normalize_or_zero()
        });
        // A shading normal that could not be normalised falls back to flat shading.
        if normals.contains(&Vec3::ZERO) {
            return [Vec3::ZERO; 3];
        }
        // Each turned to the triangle's side before they are interpolated: a vertex shared by
        // faces that face opposite ways (a two-sided sheet) has a normal of either sign.
        let facing = geometry(t).normal_unnormalized();
        normals.map(|n| {
            if Vec3A::from(n).dot(facing) < 0.0 {
                -n
            } else {
                n
            }
        })
    };
    let uvs = |t: usize| {
        if mesh.uvs.is_empty() {
            [Vec2::ZERO; 3]
        } else {
            corners(t).map(|i| mesh.uvs[i as usize])
        }
    };
    if attributes.normals {
        extend(&mut columns.normals, &kept_triangles, count, normals);
    }
    if attributes.uvs {
        extend(&mut columns.uvs, &kept_triangles, count, uvs);
    }
    if attributes.colors {
        // Linear RGB; the alpha channel is coverage, not colour.
        let colors = |t: usize| match colors {
            Some(VertexColors(c)) => corners(t).map(|i| c[i as usize]),
            None => [Vec4::ONE; 3],
        };
        extend(&mut columns.colors, &kept_triangles, count, colors);
    }
    if attributes.tangents {
        // Tangents: the file's (the linear part carries them; a mirroring transform flips
        // the handedness), else one per triangle from the UVs.
        let tangents = |t: usize| match tangents {
            None => [Vec4::ZERO; 3],
            Some(Some(VertexTangents(tangents)))
                if tangents.len() == n && normals(t)[0] != Vec3::ZERO =>
            {
                corners(t).map(|i| {
                    let t = tangents[i as usize];
                    let xyz = world_from_object.matrix3 * Vec3A::from(t.truncate());
                    let w = if (t.w < 0.0) != flips { -1.0 } else { 1.0 };
                    xyz.normalize_or_zero().extend(w)
                })
            }
            Some(_) => {
                let p = corners(t).map(|i| world[i as usize]);
                let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                [materials::triangle_tangent(p, uvs(t), n); 3]
            }
        };
        extend(&mut columns.tangents, &kept_triangles, count, tangents);
    }
    Ok(count - kept_count)
}
