//! Meshes: each mesh's triangles in world space (the winding kept under mirroring
//! transforms), with their vertex attributes (shading normals, texture coordinates, tangents
//! for normal maps); degenerate triangles are skipped with a warning.

use super::instances::InstanceRequest;
use super::lights::validate_emitter;
use super::materials::{self, MaterialTable};
use super::{Group, Primitives, Source};
use crate::accel::alpha::{self, AlphaRecord};
use crate::error::{Error, Result};
use crate::geometry::TriangleGeom;
use crate::math::{Affine3A, Mat3A, Rgb, Vec2, Vec3, Vec3A, Vec4};
use crate::scene::{
    AlphaCoverage, Emitter, Iridescence, Material, MaterialTextures, Mesh, Name, SharedMesh,
    Transform, VertexColors, VertexTangents, Volume, mesh_of,
};
use crate::texture::TextureRef;
use rayon::prelude::*;
use std::collections::HashSet;
use std::path::Path;
use std::sync::Arc;

/// Appends every mesh of the world to `prims` (one group per mesh, its triangles described,
/// not copied: see [`MeshPrims`]), its material to `materials`.
/// Entities drawing a mesh of `instanced` (opaque, not emitting) are not flattened but
/// returned as instance requests.
pub(super) fn flatten_meshes<'w>(
    world: &'w hecs::World,
    path: &Path,
    materials: &mut MaterialTable,
    prims: &mut Primitives<'w>,
    instanced: &HashSet<*const Mesh>,
) -> Result<Vec<InstanceRequest>> {
    let mut requests = Vec::new();
    // Anisotropic meshes without texture coordinates or tangents: (count, first name).
    let mut frameless: (usize, Option<String>) = (0, None);
    let Primitives {
        groups,
        sources,
        count,
        warnings,
        alpha_records,
        ..
    } = prims;
    for (
        (entity, name),
        transform,
        (mesh, shared),
        (material, alpha, volume, iridescence),
        textures,
        (tangents, colors),
        emitter,
    ) in world
        .query::<(
            (hecs::Entity, Option<&Name>),
            Option<&Transform>,
            (Option<&Mesh>, Option<&SharedMesh>),
            (
                &Material,
                Option<&AlphaCoverage>,
                Option<&Volume>,
                Option<&Iridescence>,
            ),
            Option<&MaterialTextures>,
            (Option<&VertexTangents>, Option<&VertexColors>),
            Option<&Emitter>,
        )>()
        .iter()
    {
        let own_mesh = mesh.is_some();
        let Some(mesh) = mesh_of(mesh, shared) else {
            continue; // a sphere
        };
        let name = name.map_or("unnamed mesh", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let material = materials.index(material, textures, volume, iridescence);
        // No tangent frame for an anisotropic material: its tangents stay zero, which the
        // shade stage renders isotropic (a generated frame would point anywhere).
        let no_frame = textures.is_some_and(|t| t.anisotropy.is_some() && !t.is_normal_mapped())
            && mesh.uvs.is_empty()
            && tangents.is_none();
        if no_frame {
            frameless.0 += 1;
            frameless.1.get_or_insert_with(|| name.to_string());
        }
        let needs_tangents = textures.is_some_and(|t| t.needs_tangents()) && !no_frame;
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
                normal_mapped: needs_tangents,
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
        let tangents = needs_tangents.then_some(tangents);
        // An emitter's coverage also weighs its light samples (`flatten/lights.rs`).
        let alpha = match alpha {
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
            first: *count,
            material,
            emitter,
            emission_texture,
            alpha,
        });
        // The mesh's components, borrowed for as long as the world is: the triangles are
        // read from them when the tree and the columns are made.
        let mesh = match shared {
            Some(shared) if !own_mesh => MeshRef::Shared(shared.0.clone()),
            _ => MeshRef::Component(world.get::<&Mesh>(entity).expect("the query found it")),
        };
        let tangents = tangents.map(|_| world.get::<&VertexTangents>(entity).ok());
        let colors = colors.and_then(|_| world.get::<&VertexColors>(entity).ok());
        let (triangles, skipped) = flatten_mesh(mesh, &transform, (tangents, colors), path, name)?;
        *count += triangles.len();
        sources.push(Source::Mesh(triangles));
        if skipped > 0 {
            let kind = if emitter.is_some() { " emitting" } else { "" };
            warnings.push(format!(
                "mesh '{name}': skipped {skipped} degenerate (zero-area){kind} triangles"
            ));
        }
    }
    if let (n, Some(first)) = frameless {
        let others = if n > 1 {
            format!(" and {} more", n - 1)
        } else {
            String::new()
        };
        warnings.push(format!(
            "mesh '{first}'{others}: anisotropic material (KHR_materials_anisotropy) without \
             texture coordinates or tangents, so without a tangent frame: rendered isotropic"
        ));
    }
    Ok(requests)
}

/// A mesh's triangle as [`flatten_mesh`] found it, or in the object space of an instance's
/// prototype: the mesh's components and what to do with them, not copies. The tree's boxes
/// and every per-slot column are read from it when they are made (so a 2-million-triangle
/// scene holds no array of shapes or records in flattening order: 128 MB), each computed
/// the same way every time, bit for bit.
pub(super) struct MeshPrims<'w> {
    mesh: MeshRef<'w>,
    world_from_object: Affine3A,
    /// The inverse transpose of the linear part, for normals.
    normal_matrix: Mat3A,
    /// Whether the transform mirrors (the corners are then taken in the other winding).
    flips: bool,
    /// The kept triangles' indices in the mesh, or `None` when every triangle is kept.
    kept: Option<Vec<u32>>,
    /// `Some` for normal-mapped meshes: `Some(Some(_))` with the file's tangents,
    /// `Some(None)` to make them per triangle.
    tangents: Option<Option<hecs::Ref<'w, VertexTangents>>>,
    colors: Option<hecs::Ref<'w, VertexColors>>,
}

/// A mesh component borrowed from the world, or a mesh shared between entities.
pub(super) enum MeshRef<'w> {
    Component(hecs::Ref<'w, Mesh>),
    Shared(Arc<Mesh>),
}

impl std::ops::Deref for MeshRef<'_> {
    type Target = Mesh;
    fn deref(&self) -> &Mesh {
        match self {
            MeshRef::Component(mesh) => mesh,
            MeshRef::Shared(mesh) => mesh,
        }
    }
}

/// Checks `mesh` and finds its valid triangles under `world_from_object`; returns them
/// described (see [`MeshPrims`]) with how many degenerate triangles were skipped.
/// `tangents` is `Some` for normal-mapped meshes: `Some(Some(_))` with the file's tangents,
/// `Some(None)` to make them per triangle. `colors` are the mesh's vertex colours, if it has
/// any.
pub(super) fn flatten_mesh<'w>(
    mesh: MeshRef<'w>,
    world_from_object: &Affine3A,
    (tangents, colors): (
        Option<Option<hecs::Ref<'w, VertexTangents>>>,
        Option<hecs::Ref<'w, VertexColors>>,
    ),
    path: &Path,
    name: &str,
) -> Result<(MeshPrims<'w>, usize)> {
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
    if let Some(VertexColors(c)) = colors.as_deref()
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
    if let Some(bad) = (mesh.positions.par_iter())
        .position_first(|&p| !world_from_object.transform_point3a(p.into()).is_finite())
    {
        return Err(Error::input(
            path,
            at(),
            format!(
                "vertex {bad} {} overflows when transformed to world space",
                mesh.positions[bad]
            ),
        ));
    }
    let mut prims = MeshPrims {
        mesh,
        world_from_object: *world_from_object,
        normal_matrix: world_from_object.matrix3.inverse().transpose(),
        flips: world_from_object.matrix3.determinant() < 0.0,
        kept: None,
        tangents,
        colors,
    };
    let mesh = &*prims.mesh;
    // Whether the triangle is kept (else: an index out of range, an area overflowing f32 or
    // a zero area; the slow path below tells these apart).
    let kept = |t: usize| {
        prims.corners(t).iter().all(|&i| (i as usize) < n) && {
            let double_area = prims.geometry(t).normal_unnormalized().length();
            double_area > 0.0 && double_area.is_finite()
        }
    };

    // --- Which triangles are kept: in the common case all, found by one parallel count.
    let count = mesh.indices.len();
    let kept_count = (0..count).into_par_iter().filter(|&t| kept(t)).count();
    if kept_count == count {
        return Ok((prims, 0));
    }
    for (t, &[a, b, c]) in mesh.indices.iter().enumerate() {
        if let Some(&bad) = [a, b, c].iter().find(|&&i| i as usize >= n) {
            return Err(Error::input(
                path,
                at(),
                format!("triangle {t}: vertex index {bad} out of range ({n} vertices)"),
            ));
        }
        if !prims.geometry(t).normal_unnormalized().length().is_finite() {
            // Finite vertices, but far enough apart (~1e19) that the area overflows f32:
            // the triangle cannot be intersected or sampled, and skipping it would change
            // the image.
            let p = prims.corners(t).map(|i| Vec3::from(prims.world_point(i)));
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
    let kept_triangles = (0..count as u32)
        .into_par_iter()
        .filter(|&t| kept(t as usize))
        .collect();
    prims.kept = Some(kept_triangles);
    Ok((prims, count - kept_count))
}

impl MeshPrims<'_> {
    /// How many triangles are kept.
    pub(super) fn len(&self) -> usize {
        self.kept
            .as_ref()
            .map_or(self.mesh.indices.len(), |kept| kept.len())
    }

    /// The mesh's index of kept triangle `k`.
    #[inline]
    pub(super) fn triangle(&self, k: usize) -> usize {
        self.kept.as_ref().map_or(k, |kept| kept[k] as usize)
    }

    /// Vertex indices of triangle `t` in the winding that keeps the front face under
    /// mirroring transforms.
    #[inline]
    fn corners(&self, t: usize) -> [u32; 3] {
        let [a, b, c] = self.mesh.indices[t];
        if self.flips { [a, c, b] } else { [a, b, c] }
    }

    /// Vertex `i` in world space.
    #[inline]
    fn world_point(&self, i: u32) -> Vec3A {
        (self.world_from_object).transform_point3a(self.mesh.positions[i as usize].into())
    }

    /// Triangle `t` in world space.
    #[inline]
    pub(super) fn geometry(&self, t: usize) -> TriangleGeom {
        let p = self.corners(t).map(|i| self.world_point(i));
        TriangleGeom::new(p[0], p[1], p[2])
    }

    /// The shading normals of triangle `t` in world space (zero for flat shading).
    pub(super) fn normals(&self, t: usize) -> [Vec3; 3] {
        let mesh = &*self.mesh;
        if mesh.normals.is_empty() {
            return [Vec3::ZERO; 3];
        }
        // Each turned to the triangle's side before they are interpolated: a vertex shared by
        // faces that face opposite ways (a two-sided sheet) has a normal of either sign. The
        // side is taken in object space, as instanced prototypes (made there) take it: a
        // shearing transform does not keep the sign of a dot product.
        let [a, b, c] = mesh.indices[t];
        let p = |i: u32| Vec3A::from(mesh.positions[i as usize]);
        let facing = (p(b) - p(a)).cross(p(c) - p(a));
        let normals = self.corners(t).map(|i| {
            let n = Vec3A::from(mesh.normals[i as usize]);
            let n = if n.dot(facing) < 0.0 { -n } else { n };
            Vec3::from(self.normal_matrix * n).normalize_or_zero()
        });
        // A shading normal that could not be normalised falls back to flat shading.
        if normals.contains(&Vec3::ZERO) {
            return [Vec3::ZERO; 3];
        }
        normals
    }

    /// The texture coordinates of triangle `t` (zero without).
    pub(super) fn uvs(&self, t: usize) -> [Vec2; 3] {
        if self.mesh.uvs.is_empty() {
            [Vec2::ZERO; 3]
        } else {
            self.corners(t).map(|i| self.mesh.uvs[i as usize])
        }
    }

    /// The linear RGBA vertex colours of triangle `t` (white without); the alpha channel is
    /// coverage, not colour.
    pub(super) fn colors(&self, t: usize) -> [Vec4; 3] {
        match self.colors.as_deref() {
            Some(VertexColors(c)) => self.corners(t).map(|i| c[i as usize]),
            None => [Vec4::ONE; 3],
        }
    }

    /// The tangents of triangle `t` in world space: the file's (the linear part carries
    /// them; a mirroring transform flips the handedness), else one per triangle from the
    /// UVs; zero for meshes without a normal map.
    pub(super) fn tangents(&self, t: usize) -> [Vec4; 3] {
        match &self.tangents {
            None => [Vec4::ZERO; 3],
            Some(Some(tangents))
                if tangents.0.len() == self.mesh.positions.len()
                    && self.normals(t)[0] != Vec3::ZERO =>
            {
                self.corners(t).map(|i| {
                    let t = tangents.0[i as usize];
                    let xyz = self.world_from_object.matrix3 * Vec3A::from(t.truncate());
                    let w = if (t.w < 0.0) != self.flips { -1.0 } else { 1.0 };
                    xyz.normalize_or_zero().extend(w)
                })
            }
            Some(_) => {
                let p = self.corners(t).map(|i| self.world_point(i));
                let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
                [materials::triangle_tangent(p, self.uvs(t), n); 3]
            }
        }
    }
}
