//! Which meshes are instanced (the one place that chooses between the flat BVH and the
//! two-level structure of [`crate::accel::instances`]), and the prototypes and instances of
//! those that are.
//!
//! A mesh is instanced when it is a [`SharedMesh`] drawn by at least
//! [`INSTANCE_MIN_USES`] entities that draw at least [`INSTANCE_MIN_TRIANGLES`] triangles
//! together; scenes without such repetition keep the single flat BVH and its fast paths
//! unchanged. Entities that emit or are alpha-tested are always flattened: each emitting
//! triangle is its own area light in world space (the light table's areas and densities), and
//! the coverage filter reads flat slots; instanced geometry is opaque and emits nothing.

use super::meshes::{MeshRef, flatten_mesh};
use super::{Attributes, build_tree, build_tree_of};
use crate::accel::build::Bvh4;
use crate::accel::instances::{Instance, Instances, Prototype};
use crate::accel::leaf_prims::LeafPrim;
use crate::error::{Error, Result};
use crate::geometry::Shape;
use crate::math::{Affine3A, Vec3A};
use crate::scene::{Mesh, Name, SharedMesh, VertexColors, VertexTangents};
use obvhs::Boundable;
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::sync::Arc;

/// A shared mesh is instanced when this many entities draw it...
pub const INSTANCE_MIN_USES: usize = 2;
/// ... and they draw at least this many triangles together: below, copying costs little
/// memory and keeps the flat tree's faster single-level walks.
pub const INSTANCE_MIN_TRIANGLES: usize = 100_000;

/// How [`crate::flatten_with`] treats shared meshes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Instancing {
    /// By the rule of this module ([`INSTANCE_MIN_USES`], [`INSTANCE_MIN_TRIANGLES`]).
    #[default]
    Auto,
    /// Every shared mesh drawn by two entities or more (tests: compare with `Never`).
    Always,
    /// Every mesh copied into the flat BVH.
    Never,
}

/// The shared meshes to instance, by the address of their data.
pub(super) fn choose(world: &hecs::World, instancing: Instancing) -> HashSet<*const Mesh> {
    let mut uses: HashMap<*const Mesh, (usize, usize)> = HashMap::new();
    if instancing == Instancing::Never {
        return HashSet::new();
    }
    for shared in world.query::<&SharedMesh>().iter() {
        let entry = uses.entry(Arc::as_ptr(&shared.0)).or_default();
        entry.0 += 1;
        entry.1 += shared.0.indices.len();
    }
    let min_triangles = match instancing {
        Instancing::Always => 0,
        _ => INSTANCE_MIN_TRIANGLES,
    };
    uses.into_iter()
        .filter(|(_, (n, triangles))| *n >= INSTANCE_MIN_USES && *triangles >= min_triangles)
        .map(|(mesh, _)| mesh)
        .collect()
}

/// One entity drawn as an instance, as [`super::meshes::flatten_meshes`] found it.
pub(super) struct InstanceRequest {
    pub(super) mesh: Arc<Mesh>,
    /// The entity, whose vertex tangents and colours the prototype reads (the first
    /// entity's, for all entities with its mesh and material).
    pub(super) entity: hecs::Entity,
    pub(super) world_from_object: Affine3A,
    pub(super) material: u32,
    /// Whether the material has a normal map (tangents are needed).
    pub(super) normal_mapped: bool,
}

/// The prototypes (one per mesh and material) and instances of `requests`, with the
/// top-level BVH; virtual slots start at `first_slot` (the flat part's slot count).
pub(super) fn build(
    world: &hecs::World,
    requests: Vec<InstanceRequest>,
    attributes: Attributes,
    first_slot: usize,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Option<Instances>> {
    if requests.is_empty() {
        return Ok(None);
    }
    let mut prototype_of: HashMap<(*const Mesh, u32), u32> = HashMap::new();
    let mut prototypes = Vec::new();
    let mut unordered = Vec::with_capacity(requests.len());
    for request in &requests {
        let key = (Arc::as_ptr(&request.mesh), request.material);
        let prototype = match prototype_of.get(&key) {
            Some(&p) => p,
            None => {
                let p = prototype(world, request, attributes, path, warnings)?;
                prototypes.push(p);
                prototype_of.insert(key, prototypes.len() as u32 - 1);
                prototypes.len() as u32 - 1
            }
        };
        let m = request.world_from_object;
        let linear = m.matrix3;
        if linear.determinant() == 0.0 || !linear.determinant().is_finite() {
            return Err(Error::input(
                path,
                Some(format!("mesh '{}'", name_of(world, request.entity))),
                "the transform is singular (zero scale)",
            ));
        }
        unordered.push(Instance {
            world_from_object: m,
            object_from_world: m.inverse(),
            normal_matrix: linear.inverse().transpose(),
            prototype,
            flips: linear.determinant() < 0.0,
        });
    }
    // Instances with empty prototypes (every triangle degenerate) are left out.
    unordered.retain(|i| !prototypes[i.prototype as usize].leaf_prims.is_empty());
    let boxes: Vec<Aabb> = unordered
        .par_iter()
        .map(|i| world_box(&prototypes[i.prototype as usize].bvh, &i.world_from_object))
        .collect();
    let (tlas, order) = build_tree(&boxes, path)?;
    let instances: Vec<Instance> = order.iter().map(|&i| unordered[i as usize]).collect();
    let mut first = Vec::with_capacity(instances.len() + 1);
    let mut next = first_slot as u64;
    for i in &instances {
        first.push(next as u32);
        next += prototypes[i.prototype as usize].leaf_prims.len() as u64;
    }
    // Virtual slots are `u32`s below the no-hit marker.
    if next >= u64::from(u32::MAX) {
        return Err(Error::input(
            path,
            None,
            format!(
                "the scene draws {next} primitives, more than wavetrace can address ({})",
                u32::MAX - 1
            ),
        ));
    }
    first.push(next as u32);
    Ok(Some(Instances {
        prototypes,
        instances,
        first_slot: first,
        tlas,
    }))
}

/// The prototype of `request`'s mesh: its triangles in object space in the slot order of
/// their own BVH, with their attributes.
fn prototype(
    world: &hecs::World,
    request: &InstanceRequest,
    attributes: Attributes,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Prototype> {
    let name = name_of(world, request.entity);
    let entity = world.entity(request.entity).expect("the entity exists");
    let (tangents, colors) = (
        entity.get::<&VertexTangents>(),
        entity.get::<&VertexColors>(),
    );
    let tangents = request.normal_mapped.then_some(tangents);
    let (triangles, skipped) = flatten_mesh(
        MeshRef::Shared(request.mesh.clone()),
        &Affine3A::IDENTITY,
        (tangents, colors),
        path,
        &name,
    )?;
    if skipped > 0 {
        warnings.push(format!(
            "mesh '{name}': skipped {skipped} degenerate (zero-area) triangles"
        ));
    }
    // The triangles' boxes and columns are made from the mesh, as for the flat part.
    let geometry = |k: usize| Shape::Triangle(triangles.geometry(triangles.triangle(k)));
    let (bvh, order) = build_tree_of(triangles.len(), |k| geometry(k).aabb(), path)?;
    // A column in slot order, or empty when the scene lacks the attribute.
    fn column<T: Send>(has: bool, order: &[u32], item: impl Fn(usize) -> T + Sync) -> Vec<T> {
        if has {
            order.par_iter().map(|&k| item(k as usize)).collect()
        } else {
            Vec::new()
        }
    }
    let t = |k: usize| triangles.triangle(k);
    Ok(Prototype {
        leaf_prims: column(true, &order, |k| LeafPrim::new(&geometry(k))),
        bvh,
        normals: column(attributes.normals, &order, |k| triangles.normals(t(k))),
        uvs: column(attributes.uvs, &order, |k| triangles.uvs(t(k))),
        tangents: column(attributes.tangents, &order, |k| triangles.tangents(t(k))),
        colors: column(attributes.colors, &order, |k| triangles.colors(t(k))),
        material: request.material,
    })
}

/// The name of `entity`, for messages.
fn name_of(world: &hecs::World, entity: hecs::Entity) -> String {
    world
        .get::<&Name>(entity)
        .map_or_else(|_| "unnamed mesh".to_string(), |n| n.0.clone())
}

/// The world box of a prototype's tree placed by `m`: its object box's eight corners
/// transformed.
fn world_box(tree: &Bvh4, m: &Affine3A) -> Aabb {
    let b = tree.bounds().expect("a prototype has triangles");
    let mut out = Aabb::INVALID;
    for corner in 0..8 {
        let pick = |bit: u32, lo: f32, hi: f32| if corner & bit == 0 { lo } else { hi };
        let p = Vec3A::new(
            pick(1, b.min.x, b.max.x),
            pick(2, b.min.y, b.max.y),
            pick(4, b.min.z, b.max.z),
        );
        out.extend(m.transform_point3a(p));
    }
    out
}
