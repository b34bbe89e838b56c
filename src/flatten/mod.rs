//! The ECS -> render boundary, and the only module that reads the `hecs::World`.
//!
//! [`flatten`] validates the world once and turns it into an immutable [`RenderScene`]:
//! world-space primitives in BVH order (so the BVH's slots index every per-primitive column
//! directly, with no indirection), a material table with its textures, a light table (area
//! and punctual lights), one BVH over all primitives, and, when some triangles bound the
//! scene, a second over the primitives that can block shadow rays
//! ([`crate::accel::occluders`]). The renderer's hot loops then assume valid data.

mod camera;
mod instances;
mod lights;
mod materials;
mod meshes;
mod spheres;

pub use instances::{INSTANCE_MIN_TRIANGLES, INSTANCE_MIN_USES, Instancing};

use crate::accel::ClosestHitPath;
use crate::accel::alpha::AlphaRecord;
use crate::accel::build::{self as bvh, Bvh4};
use crate::accel::leaf_prims::LeafPrim;
use crate::accel::occluders;
use crate::error::{Error, Result};
use crate::geometry::Shape;
use crate::geometry::sphere::SphereGeom;
use crate::math::{Rgb, Vec2, Vec3, Vec4};
use crate::render_scene::{FlattenTimes, NO_EMITTER, RenderScene};
use crate::scene::{Emitter, MaterialTextures, Mesh, SharedMesh, VertexColors, mesh_of};
use crate::texture::TextureRef;
use materials::MaterialTable;
use meshes::MeshPrims;
use rayon::prelude::*;
use std::path::Path;
use std::time::Instant;

/// Peak resident bytes per primitive that flattening adds to the world it reads: the BVH
/// build, then the leaf records and the per-slot columns (a 2-million-triangle OBJ adds
/// about 73 bytes per triangle, 121 with normals and texture coordinates; see
/// docs/performance.md, "Memory per triangle"). Kept with a margin.
const FLATTEN_RESIDENT_PER_PRIMITIVE: u64 = 200;
/// The same in address space, which grows faster (allocator arenas, vectors reserved before
/// they are filled, the chunked build's mapped scratch): the 2-million-triangle OBJ's
/// address space peaks at 0.51 GB (`VmPeak`).
const FLATTEN_ADDRESS_SPACE_PER_PRIMITIVE: u64 = 250;

/// Refuses a world whose render scene would not fit in the memory the process can still
/// take (see [`crate::memory`]), before anything large is built.
fn check_memory(
    world: &hecs::World,
    path: &Path,
    instanced: &std::collections::HashSet<*const Mesh>,
) -> Result<()> {
    // Flattened meshes count once per entity, instanced ones once in all (their instances
    // are a few hundred bytes each, counted as one primitive).
    let mut prototypes = std::collections::HashSet::new();
    let mut primitives = 0u64;
    for (mesh, shared) in world.query::<(Option<&Mesh>, Option<&SharedMesh>)>().iter() {
        let Some(mesh) = mesh_of(mesh, shared) else {
            continue;
        };
        let triangles = mesh.indices.len() as u64;
        let key = mesh as *const Mesh;
        primitives += if !instanced.contains(&key) {
            triangles
        } else if prototypes.insert(key) {
            triangles + 1
        } else {
            1
        };
    }
    primitives += world.query::<&crate::scene::Sphere>().iter().count() as u64;
    crate::memory::check_fits(
        path,
        &format!("its render scene ({primitives} primitives)"),
        crate::memory::Needed {
            resident: primitives.saturating_mul(FLATTEN_RESIDENT_PER_PRIMITIVE),
            address_space: primitives.saturating_mul(FLATTEN_ADDRESS_SPACE_PER_PRIMITIVE),
        },
        crate::memory::available(),
    )
}

/// Flattens the world into a [`RenderScene`]. `path` names the scene in errors.
/// The camera used is the first one (the earliest spawned).
pub fn flatten(world: &hecs::World, path: &Path) -> Result<RenderScene> {
    flatten_with(world, path, Instancing::Auto)
}

/// [`flatten`], with shared meshes instanced as `instancing` says (see [`Instancing`]).
pub fn flatten_with(
    world: &hecs::World,
    path: &Path,
    instancing: Instancing,
) -> Result<RenderScene> {
    let start = Instant::now();
    let camera = camera::first_camera(world, path)?;
    // Primitives in flattening order (meshes in query order, their triangles in index order,
    // then spheres), one group per entity, with the distinct materials they use.
    let mut materials = MaterialTable::default();
    let mut prims = Primitives::new(Attributes::of(world));
    let instanced = instances::choose(world, instancing);
    check_memory(world, path, &instanced)?;
    let requests = meshes::flatten_meshes(world, path, &mut materials, &mut prims, &instanced)?;
    spheres::flatten_spheres(world, path, &mut materials, &mut prims)?;
    crate::memory::trace_phase("shapes");

    // BVH order: every per-primitive column is made once in slot order (none is kept in
    // flattening order), so slots index them directly.
    let bvh_start = Instant::now();
    let (bvh, order) = build_tree_of(
        prims.count,
        |p| obvhs::Boundable::aabb(&prims.shape(p)),
        path,
    )?;
    crate::memory::trace_phase("4-wide bvh");
    // The instanced meshes: their own trees and the top-level tree over their instances.
    let instances = instances::build(
        world,
        requests,
        prims.attributes,
        order.len(),
        path,
        &mut prims.warnings,
    )?;
    let bvh_build = bvh_start.elapsed();
    let scene_bounds = match (
        bvh.bounds(),
        instances.as_ref().and_then(|i| i.tlas.bounds()),
    ) {
        (Some(a), Some(b)) => Some(a.union(&b)),
        (a, b) => a.or(b),
    };

    // Lights, and the primitives that can block shadow rays (which depend on the lights).
    let delta_lights = lights::punctual_lights(world, scene_bounds, path)?;
    let (environment, environment_visible) = lights::environment(world, path)?;
    // Shadow rays in scenes with alpha-tested primitives walk the whole tree (its slots are
    // the ones flagged for the coverage test), and so do shadow rays toward the environment,
    // which leave the scene in every direction: every primitive can block one.
    let alpha_tested = !prims.alpha_records.is_empty();
    // So do scenes with instances: the occluders' choice sees only the flat primitives' points,
    // and a triangle that bounds those may still stand between an instance and a light.
    let occluders = if alpha_tested || environment.is_some() || instances.is_some() {
        None
    } else {
        occluders::occluders_of(
            prims.count,
            prims.triangle_count(),
            |p| prims.shape(p),
            &delta_lights,
        )
    };
    let scene_radius = lights::scene_radius(scene_bounds);
    let lights = lights::scene_lights(&prims, delta_lights, environment, scene_radius);

    // Per-slot columns.
    let (material, emitter, alpha_of_slot) =
        slot_materials_lights_and_alpha(&prims.groups, &lights.first_light, &order, alpha_tested);
    // One record per slot, which also gives back the shape (see `RenderScene::shape`), made
    // in slot order from the meshes: no array of records or shapes in flattening order
    // (128 MB at 2M triangles) is alive during the build or beside this one.
    let leaf_prims = prims.column(
        &order,
        |mesh, t| LeafPrim::new(&Shape::Triangle(mesh.geometry(t))),
        |sphere| LeafPrim::new(&Shape::Sphere(*sphere)),
    );
    crate::memory::trace_phase("leaf prims");
    let attributes = prims.attributes;
    let vertex_normals = prims.column_or_zeros(
        attributes.normals,
        &order,
        MeshPrims::normals,
        [Vec3::ZERO; 3],
    );
    let vertex_uvs = prims.column_or_zeros(attributes.uvs, &order, MeshPrims::uvs, [Vec2::ZERO; 3]);
    let vertex_colors = if attributes.colors {
        prims.column(&order, MeshPrims::colors, |_| [Vec4::ONE; 3])
    } else {
        Vec::new()
    };
    let vertex_tangents = if attributes.tangents {
        prims.column(&order, MeshPrims::tangents, |_| [Vec4::ZERO; 3])
    } else {
        Vec::new()
    };
    let Primitives {
        warnings,
        alpha_records,
        ..
    } = prims;
    let slot_count = instances.as_ref().map_or(leaf_prims.len(), |i| {
        *i.first_slot.last().expect("one past the last") as usize
    });
    Ok(RenderScene {
        instances,
        slot_count,
        has_vertex_colors: attributes.colors,
        closest_hit_path: ClosestHitPath::choose(&leaf_prims, &bvh, alpha_tested),
        alpha_of_slot,
        alpha_records,
        leaf_prims,
        vertex_normals,
        vertex_uvs,
        vertex_colors,
        vertex_tangents,
        material,
        emitter,
        material_textures: materials.surface_textures(),
        transmits_or_absorbs: materials.transmits_or_absorbs(),
        material_absorption: materials.absorptions(),
        materials: materials.bsdfs(),
        textures: materials::mipmapped(materials.interner.textures, path)?,
        lights: lights.table,
        environment_visible,
        textured_emission: lights.textured_emission,
        bvh,
        occluders,
        source_index: order,
        camera,
        warnings,
        // Last: the fields above are made in the order written.
        times: FlattenTimes {
            bvh_build,
            total: start.elapsed(),
        },
    })
}

/// The primitives of one entity (a mesh's triangles or a sphere), which share its material
/// and emitter.
struct Group {
    /// Index of the group's first primitive in flattening order; the group runs up to the
    /// next group's first.
    first: usize,
    material: u32,
    emitter: Option<Emitter>,
    /// The emitter's texture and the texture's mean.
    emission_texture: Option<(TextureRef, Rgb)>,
    /// Index into [`Primitives::alpha_records`], or [`crate::accel::alpha::OPAQUE`].
    alpha: u32,
}

/// Which vertex attributes some primitive of the scene has (and so which per-slot columns are
/// made).
#[derive(Clone, Copy)]
struct Attributes {
    normals: bool,
    uvs: bool,
    tangents: bool,
    /// Vertex colours (some mesh has [`VertexColors`]).
    colors: bool,
}

/// Where a group's primitives come from.
enum Source<'w> {
    /// A mesh's kept triangles.
    Mesh(MeshPrims<'w>),
    /// One sphere, in world space.
    Sphere(SphereGeom),
}

/// The primitives in flattening order, as the entities are read: described, not copied (see
/// [`MeshPrims`]); the tree's boxes and the per-slot columns are made from them.
struct Primitives<'w> {
    /// One group per entity, in order.
    groups: Vec<Group>,
    /// Per group, its primitives.
    sources: Vec<Source<'w>>,
    /// The number of primitives of all groups.
    count: usize,
    /// Things skipped (degenerate triangles, ...), for the user to see.
    warnings: Vec<String>,
    /// Which vertex attributes the scene has.
    attributes: Attributes,
    /// How the alpha-tested groups are covered.
    alpha_records: Vec<AlphaRecord>,
}

impl<'w> Primitives<'w> {
    fn new(attributes: Attributes) -> Self {
        Primitives {
            groups: Vec::new(),
            sources: Vec::new(),
            count: 0,
            warnings: Vec::new(),
            attributes,
            alpha_records: Vec::new(),
        }
    }

    /// The source of primitive `prim` and, for a mesh, the mesh's index of its triangle.
    #[inline]
    fn locate(&self, prim: usize) -> (&Source<'w>, usize) {
        // Groups whose triangles were all skipped share their `first` with the next group.
        let g = self.groups.partition_point(|g| g.first <= prim) - 1;
        let source = &self.sources[g];
        match source {
            Source::Mesh(mesh) => (source, mesh.triangle(prim - self.groups[g].first)),
            Source::Sphere(_) => (source, 0),
        }
    }

    /// The world-space shape of primitive `prim`.
    #[inline]
    fn shape(&self, prim: usize) -> Shape {
        match self.locate(prim) {
            (Source::Mesh(mesh), t) => Shape::Triangle(mesh.geometry(t)),
            (Source::Sphere(sphere), _) => Shape::Sphere(*sphere),
        }
    }

    /// The vertex colours' alpha of primitive `prim` (1 for a sphere or without colours).
    fn vertex_alphas(&self, prim: usize) -> [f32; 3] {
        match self.locate(prim) {
            (Source::Mesh(mesh), t) => mesh.colors(t).map(|c| c.w),
            (Source::Sphere(_), _) => [1.0; 3],
        }
    }

    /// The texture coordinates of primitive `prim` (zero for a sphere).
    fn uvs(&self, prim: usize) -> [Vec2; 3] {
        match self.locate(prim) {
            (Source::Mesh(mesh), t) => mesh.uvs(t),
            (Source::Sphere(_), _) => [Vec2::ZERO; 3],
        }
    }

    /// How many of the primitives are triangles.
    fn triangle_count(&self) -> usize {
        let spheres = (self.sources.iter())
            .filter(|s| matches!(s, Source::Sphere(_)))
            .count();
        self.count - spheres
    }

    /// A per-slot column: `of_triangle(mesh, t)` of each slot's triangle, `of_sphere` of
    /// each sphere, in the slot order `order`.
    fn column<T: Send>(
        &self,
        order: &[u32],
        of_triangle: impl Fn(&MeshPrims<'w>, usize) -> T + Sync,
        of_sphere: impl Fn(&SphereGeom) -> T + Sync,
    ) -> Vec<T> {
        order
            .par_iter()
            .map(|&prim| match self.locate(prim as usize) {
                (Source::Mesh(mesh), t) => of_triangle(mesh, t),
                (Source::Sphere(sphere), _) => of_sphere(sphere),
            })
            .collect()
    }

    /// A vertex-attribute column in slot order (spheres get `none`), or zeros made without
    /// touching memory per slot when no primitive of the scene has the attribute (`has`).
    fn column_or_zeros<T: Copy + Send + Sync + bytemuck::Zeroable>(
        &self,
        has: bool,
        order: &[u32],
        of_triangle: impl Fn(&MeshPrims<'w>, usize) -> T + Sync,
        none: T,
    ) -> Vec<T> {
        if has {
            self.column(order, of_triangle, |_| none)
        } else {
            bytemuck::zeroed_vec(order.len())
        }
    }
}

impl Attributes {
    /// The attributes of the world's meshes (tangents: when some material has a normal map).
    fn of(world: &hecs::World) -> Self {
        let normal_mapped = world
            .query::<&MaterialTextures>()
            .iter()
            .any(|t| t.needs_tangents());
        Attributes {
            normals: any_mesh(world, |m| !m.normals.is_empty()),
            uvs: any_mesh(world, |m| !m.uvs.is_empty()),
            tangents: normal_mapped,
            colors: world.query::<&VertexColors>().iter().next().is_some(),
        }
    }
}

/// Whether some mesh of the world ([`Mesh`] or [`SharedMesh`]) satisfies `test`.
fn any_mesh(world: &hecs::World, test: impl Fn(&Mesh) -> bool) -> bool {
    world.query::<&Mesh>().iter().any(&test)
        || world.query::<&SharedMesh>().iter().any(|s| test(&s.0))
}

/// The BVH over `items` (primitives or instance boxes) and the map from slots to items, or an
/// error for geometry too degenerate for it.
fn build_tree<T: obvhs::Boundable>(items: &[T], path: &Path) -> Result<(Bvh4, Vec<u32>)> {
    build_tree_of(items.len(), |i| items[i].aabb(), path)
}

/// [`build_tree`] over `count` primitives whose boxes `box_of` gives.
fn build_tree_of(
    count: usize,
    box_of: impl Fn(usize) -> obvhs::aabb::Aabb + Sync,
    path: &Path,
) -> Result<(Bvh4, Vec<u32>)> {
    bvh::build_bvh_of(count, box_of).ok_or_else(|| {
        Error::input(
            path,
            None,
            format!(
                "the geometry is too degenerate for the BVH (deeper than {})",
                bvh::MAX_DEPTH
            ),
        )
    })
}

/// Per slot (BVH order `order`), the material index, the light index (or [`NO_EMITTER`];
/// none at all when no primitive emits) and, if `alpha_tested`, the alpha record (or [`crate::accel::alpha::OPAQUE`]) of its primitive.
fn slot_materials_lights_and_alpha(
    groups: &[Group],
    first_light: &[u32],
    order: &[u32],
    alpha_tested: bool,
) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let group_of = |prim: u32| groups.partition_point(|g| g.first <= prim as usize) - 1;
    let material = order
        .par_iter()
        .map(|&prim| groups[group_of(prim)].material)
        .collect();
    // Empty when nothing emits (`RenderScene::emitter_of` reads a missing entry as
    // `NO_EMITTER`): 4 bytes per primitive that most large scenes do not need.
    let emitter = if first_light.iter().all(|&first| first == NO_EMITTER) {
        Vec::new()
    } else {
        order
            .par_iter()
            .map(|&prim| {
                let g = group_of(prim);
                match first_light[g] {
                    NO_EMITTER => NO_EMITTER,
                    first => first + prim - groups[g].first as u32,
                }
            })
            .collect()
    };
    let alpha = if alpha_tested {
        order
            .par_iter()
            .map(|&p| groups[group_of(p)].alpha)
            .collect()
    } else {
        Vec::new()
    };
    (material, emitter, alpha)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_normals_are_turned_to_their_triangles_side() {
        use crate::math::Vec3;
        use crate::scene::{Camera, Material, Mesh};
        // A two-sided square: the second triangle is the first with the opposite winding,
        // on the same vertices, whose normals point one way (+z) for both.
        let mut world = hecs::World::new();
        world.spawn((Camera::look_at(Vec3::Z, Vec3::ZERO, Vec3::Y, 1.0),));
        let mesh = Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z, Vec3::Z, (Vec3::Z + Vec3::X).normalize()],
            uvs: Vec::new(),
            indices: vec![[0, 1, 2], [0, 2, 1]],
        };
        let albedo = Vec3::splat(0.5);
        world.spawn((mesh, Material::Lambertian { albedo }));
        let scene = flatten(&world, Path::new(".")).unwrap();
        let mut sides = Vec::new();
        for slot in 0..2 {
            let facing = scene.vertex_normals(slot)[0].z.signum();
            for normal in scene.vertex_normals(slot) {
                assert_eq!(normal.z.signum(), facing, "slot {slot}: {normal}");
            }
            sides.push(facing);
        }
        sides.sort_by(f32::total_cmp);
        assert_eq!(sides, [-1.0, 1.0]);
    }
}
