//! The ECS -> render boundary, and the only module that reads the `hecs::World`.
//!
//! [`flatten`] validates the world once and turns it into an immutable [`FlatScene`]:
//! world-space primitives in BVH order (so the BVH's slots index every per-primitive column
//! directly, with no indirection), a material table, a light table and one BVH over all
//! primitives. The renderer's hot loops then assume valid data.

pub mod bvh;
pub mod lights;
pub mod spheres;
pub mod triangles;

use crate::bsdf::microfacet::alpha_from_roughness;
use crate::bsdf::{Bsdf, FresnelModel, MetallicRoughness};
use crate::error::{Error, Result};
use crate::math::{Mat3A, Vec3, Vec3A};
use crate::scene::{Camera, Emitter, Material, Mesh, Name, Sphere, Transform};
use lights::{AreaLight, LightTable};
use spheres::SphereGeom;
use std::path::Path;
use triangles::TriangleGeom;

/// Marks a primitive that emits nothing in [`FlatScene::emitter`].
pub const NO_EMITTER: u32 = u32::MAX;

/// The geometry of one primitive, as the intersection test reads it (64 bytes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle.
    Triangle(TriangleGeom),
    /// An analytic sphere.
    Sphere(SphereGeom),
}

/// The render-side scene: immutable, world space, shared by reference across threads.
pub struct FlatScene {
    /// Geometry per BVH slot.
    pub shapes: Vec<Shape>,
    /// Per-vertex shading normals per slot (unit, world space); all zero for flat shading
    /// and for spheres.
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Material index per slot, into `materials`.
    pub material: Vec<u32>,
    /// Light index per slot, into `lights.lights`, or [`NO_EMITTER`].
    pub emitter: Vec<u32>,
    /// Distinct materials.
    pub materials: Vec<Bsdf>,
    /// Emitting primitives.
    pub lights: LightTable,
    /// The BVH over `shapes` (slot `i` is `shapes[i]`).
    pub bvh: bvh::Bvh4,
    /// Per slot, the index of the primitive in flattening order (meshes in query order, their
    /// triangles in index order, then spheres), to map hits back to the input.
    pub source_index: Vec<u32>,
    /// The camera.
    pub camera: Camera,
    /// Things skipped while flattening (degenerate triangles, ...), for the user to see.
    pub warnings: Vec<String>,
}

/// One primitive before BVH ordering.
struct Primitive {
    shape: Shape,
    normals: [Vec3; 3],
    material: u32,
    emitter: Option<Emitter>,
}

/// Flattens the world into a [`FlatScene`]. `path` names the scene in errors.
pub fn flatten(world: &hecs::World, path: &Path) -> Result<FlatScene> {
    let mut cameras = world.query::<&Camera>();
    let camera = *cameras
        .iter()
        .next()
        .ok_or_else(|| Error::input(path, None, "the scene has no camera"))?;
    drop(cameras);

    let mut materials: Vec<Bsdf> = Vec::new();
    let mut material_index = |m: &Material| -> u32 {
        let bsdf = bsdf_of(m);
        let found = materials.iter().position(|b| *b == bsdf);
        found.unwrap_or_else(|| {
            materials.push(bsdf);
            materials.len() - 1
        }) as u32
    };

    let mut prims: Vec<Primitive> = Vec::new();
    let mut warnings = Vec::new();
    for (name, transform, mesh, material, emitter) in world
        .query::<(
            Option<&Name>,
            Option<&Transform>,
            &Mesh,
            &Material,
            Option<&Emitter>,
        )>()
        .iter()
    {
        let name = name.map_or("unnamed mesh", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let material = material_index(material);
        let emitter = validate_emitter(emitter, path, name)?;
        let skipped = flatten_mesh(mesh, &transform, path, name, |shape, normals| {
            prims.push(Primitive {
                shape,
                normals,
                material,
                emitter,
            })
        })?;
        if skipped > 0 {
            warnings.push(format!(
                "mesh '{name}': skipped {skipped} degenerate (zero-area) triangles"
            ));
        }
    }
    for (name, transform, sphere, material, emitter) in world
        .query::<(
            Option<&Name>,
            Option<&Transform>,
            &Sphere,
            &Material,
            Option<&Emitter>,
        )>()
        .iter()
    {
        let name = name.map_or("unnamed sphere", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let scale = Vec3::new(
            transform.matrix3.x_axis.length(),
            transform.matrix3.y_axis.length(),
            transform.matrix3.z_axis.length(),
        );
        if (scale.max_element() - scale.min_element()) > 1e-4 * scale.max_element() {
            return Err(Error::input(
                path,
                Some(format!("sphere '{name}'")),
                "a sphere's transform must scale uniformly",
            ));
        }
        let geom = SphereGeom {
            center: transform.translation,
            radius: sphere.radius * scale.x,
        };
        if !(geom.radius > 0.0 && geom.radius.is_finite() && geom.center.is_finite()) {
            return Err(Error::input(
                path,
                Some(format!("sphere '{name}'")),
                "radius must be positive and the centre finite",
            ));
        }
        let material = material_index(material);
        let emitter = validate_emitter(emitter, path, name)?;
        prims.push(Primitive {
            shape: Shape::Sphere(geom),
            normals: [Vec3::ZERO; 3],
            material,
            emitter,
        });
    }

    // BVH order: every per-primitive column is permuted once, so slots index them directly.
    let shapes_unordered: Vec<Shape> = prims.iter().map(|p| p.shape).collect();
    let (bvh, order) = bvh::build_bvh(&shapes_unordered).ok_or_else(|| {
        Error::input(
            path,
            None,
            format!(
                "the geometry is too degenerate for the BVH (deeper than {})",
                bvh::MAX_DEPTH
            ),
        )
    })?;
    let ordered = || order.iter().map(|&i| &prims[i as usize]);
    // Lights come from the primitives, not the slots: a pre-split triangle owns several slots
    // but is one light.
    let mut area_lights = Vec::new();
    let light_of_primitive: Vec<u32> = prims
        .iter()
        .map(|p| match p.emitter {
            Some(e) => {
                let area = match p.shape {
                    Shape::Triangle(t) => t.area(),
                    Shape::Sphere(s) => s.area(),
                };
                area_lights.push(AreaLight {
                    shape: p.shape,
                    radiance: e.radiance,
                    two_sided: e.two_sided,
                    area,
                    select_probability: 0.0,
                });
                (area_lights.len() - 1) as u32
            }
            None => NO_EMITTER,
        })
        .collect();
    let emitter = order
        .iter()
        .map(|&i| light_of_primitive[i as usize])
        .collect();
    let source_index = order.clone();
    Ok(FlatScene {
        shapes: ordered().map(|p| p.shape).collect(),
        vertex_normals: ordered().map(|p| p.normals).collect(),
        material: ordered().map(|p| p.material).collect(),
        emitter,
        materials,
        lights: LightTable::new(area_lights),
        bvh,
        source_index,
        camera,
        warnings,
    })
}

/// The render-side scattering model of a scene material.
fn bsdf_of(m: &Material) -> Bsdf {
    match *m {
        Material::Lambertian { albedo } => Bsdf::Lambertian { albedo },
        Material::Mirror { tint } => Bsdf::Mirror { tint },
        Material::Dielectric { ior, fresnel, tint } => Bsdf::Dielectric { ior, fresnel, tint },
        Material::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            specular,
            specular_color,
            ior,
            transmission,
        } => {
            if transmission == 1.0 && metallic == 0.0 && roughness == 0.0 {
                // Smooth clear glass stays the exact delta dielectric.
                return Bsdf::Dielectric {
                    ior,
                    fresnel: FresnelModel::Exact,
                    tint: base_color,
                };
            }
            Bsdf::metallic_roughness(MetallicRoughness {
                base_color,
                metallic,
                alpha: alpha_from_roughness(roughness),
                ior,
                specular,
                specular_color,
                transmission,
            })
        }
    }
}

/// Emitters that emit nothing are dropped; invalid radiance is an error.
fn validate_emitter(e: Option<&Emitter>, path: &Path, name: &str) -> Result<Option<Emitter>> {
    match e {
        Some(e) if !(e.radiance.is_finite() && e.radiance.min_element() >= 0.0) => {
            Err(Error::input(
                path,
                Some(format!("'{name}'")),
                "emitted radiance must be finite and non-negative",
            ))
        }
        Some(e) if e.radiance == Vec3::ZERO => Ok(None),
        other => Ok(other.copied()),
    }
}

/// Emits each valid world-space triangle of `mesh`; returns how many degenerate ones were skipped.
fn flatten_mesh(
    mesh: &Mesh,
    world_from_object: &crate::math::Affine3A,
    path: &Path,
    name: &str,
    mut emit: impl FnMut(Shape, [Vec3; 3]),
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
    if let Some(bad) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::input(
            path,
            at(),
            format!("vertex {bad} is not finite"),
        ));
    }
    let normal_matrix = Mat3A::from(world_from_object.matrix3).inverse().transpose();
    let flips = world_from_object.matrix3.determinant() < 0.0;
    let world: Vec<Vec3A> = mesh
        .positions
        .iter()
        .map(|&p| world_from_object.transform_point3a(p.into()))
        .collect();
    let mut skipped = 0;
    for (t, &[a, b, c]) in mesh.indices.iter().enumerate() {
        if let Some(&bad) = [a, b, c].iter().find(|&&i| i as usize >= n) {
            return Err(Error::input(
                path,
                at(),
                format!("triangle {t}: vertex index {bad} out of range ({n} vertices)"),
            ));
        }
        let [a, b, c] = if flips { [a, c, b] } else { [a, b, c] };
        let geom = TriangleGeom::new(world[a as usize], world[b as usize], world[c as usize]);
        let double_area = geom.normal_unnormalized().length();
        if !(double_area > 0.0) || !double_area.is_finite() {
            skipped += 1;
            continue;
        }
        let normals = if mesh.normals.is_empty() {
            [Vec3::ZERO; 3]
        } else {
            [a, b, c].map(|i| {
                Vec3::from(normal_matrix * Vec3A::from(mesh.normals[i as usize]))
                    .normalize_or_zero()
            })
        };
        // A shading normal that could not be normalised falls back to flat shading.
        let normals = if normals.contains(&Vec3::ZERO) {
            [Vec3::ZERO; 3]
        } else {
            normals
        };
        emit(Shape::Triangle(geom), normals);
    }
    Ok(skipped)
}
