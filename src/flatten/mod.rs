//! The ECS -> render boundary, and the only module that reads the `hecs::World`.
//!
//! [`flatten`] validates the world once and turns it into an immutable [`FlatScene`]:
//! world-space primitives in BVH order (so the BVH's slots index every per-primitive column
//! directly, with no indirection), a material table with its textures, a light table (area
//! and punctual lights), one BVH over all primitives, and, when some triangles bound the
//! scene, a second over the primitives that can block shadow rays ([`occluders`]). The
//! renderer's hot loops then assume valid data.

pub mod bvh;
pub mod leaf_prims;
pub mod lights;
pub mod materials;
pub mod occluders;
pub mod ray_batches;
pub mod spheres;
pub mod triangles;

use crate::bsdf::microfacet::alpha_from_roughness;
use crate::bsdf::{Bsdf, FresnelModel, Layered, MetallicRoughness};
use crate::error::{Error, Result};
use crate::math::{Rgb, Vec2, Vec3, Vec3A, Vec4};
use crate::scene::{
    Camera, Emitter, Material, MaterialTextures, Mesh, Name, PunctualLight, Sphere, Transform,
    VertexTangents,
};
use crate::texture::Texture;
use lights::{AreaLight, DeltaLight, LightTable};
use materials::{SurfaceTextures, TextureInterner, TextureRef, TexturedEmission};
use obvhs::aabb::Aabb;
use rayon::prelude::*;
use spheres::SphereGeom;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};
use triangles::TriangleGeom;

/// Marks a primitive that emits nothing in [`FlatScene::emitter`].
pub const NO_EMITTER: u32 = u32::MAX;
/// Marks an unset texture in a [`materials::TextureRef`].
pub const NO_TEXTURE: u32 = u32::MAX;

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
    /// Geometry per BVH slot, laid out for the traversals' leaf tests (see
    /// [`FlatScene::shape`] for the shape itself).
    pub leaf_prims: Vec<leaf_prims::LeafPrim>,
    /// Per BVH node, its leaves' triangles for one four-wide closest-hit test, when every
    /// leaf holds one primitive (small scenes); else empty.
    pub node_triangles: Vec<leaf_prims::NodeTriangles>,
    /// Every primitive, for a closest-hit query without the tree, in the smallest scenes
    /// (at most [`leaf_prims::MAX_FLAT_PRIMITIVES`]); else `None`.
    pub flat_primitives: Option<leaf_prims::FlatPrimitives>,
    /// Per-vertex shading normals per slot (unit, world space); all zero for flat shading
    /// and for spheres.
    pub vertex_normals: Vec<[Vec3; 3]>,
    /// Texture coordinates of the three vertices per slot (zero when the mesh has none);
    /// read only for textured materials.
    pub vertex_uvs: Vec<[Vec2; 3]>,
    /// Tangents of the three vertices per slot (world space, `w` = handedness, see
    /// [`VertexTangents`]); empty unless some material has a normal map.
    pub vertex_tangents: Vec<[Vec4; 3]>,
    /// Material index per slot, into `materials`.
    pub material: Vec<u32>,
    /// Light index per slot, into `lights.lights`, or [`NO_EMITTER`].
    pub emitter: Vec<u32>,
    /// Distinct materials.
    pub materials: Vec<Bsdf>,
    /// Textures per material, looked up at the hit's texture coordinates.
    pub material_textures: Vec<SurfaceTextures>,
    /// Distinct textures.
    pub textures: Vec<Arc<Texture>>,
    /// Emitting primitives and punctual lights.
    pub lights: LightTable,
    /// Per area light (as `lights.lights`), its emission texture; empty when no light has one.
    pub textured_emission: Vec<Option<TexturedEmission>>,
    /// The BVH over the primitives (slot `i` is `leaf_prims[i]`).
    pub bvh: bvh::Bvh4,
    /// The primitives that can block a shadow ray and their own tree, when some triangles
    /// bound the scene and cannot (see [`occluders`]); `None`: all of them can.
    pub occluders: Option<occluders::Occluders>,
    /// Per slot, the index of the primitive in flattening order (meshes in query order, their
    /// triangles in index order, then spheres), to map hits back to the input.
    pub source_index: Vec<u32>,
    /// The camera.
    pub camera: Camera,
    /// Things skipped while flattening (degenerate triangles, ...), for the user to see.
    pub warnings: Vec<String>,
    /// How long [`flatten`] took.
    pub times: FlattenTimes,
}

impl FlatScene {
    /// The primitive in slot `slot`.
    #[inline(always)]
    pub fn shape(&self, slot: usize) -> Shape {
        self.leaf_prims[slot].shape()
    }

    /// The primitives in slot order.
    pub fn shapes(&self) -> impl ExactSizeIterator<Item = Shape> + '_ {
        self.leaf_prims.iter().map(leaf_prims::LeafPrim::shape)
    }
}

/// How long [`flatten`] took (wall time).
#[derive(Clone, Copy, Debug, Default)]
pub struct FlattenTimes {
    /// The BVH build alone: obvhs's binary tree over the primitives' boxes and its collapse
    /// into 4-wide nodes (what a ray-tracing library's build does).
    pub bvh_build: Duration,
    /// All of it: the meshes' world-space triangles, the BVH, and every per-primitive column
    /// in slot order.
    pub total: Duration,
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
}

/// Per-primitive columns in flattening order (before BVH ordering). A vertex-attribute
/// column is left empty when no primitive of the scene has that attribute: the BVH-ordered
/// column is then all zeros, made without touching memory per primitive.
#[derive(Default)]
struct Columns {
    shapes: Vec<Shape>,
    normals: Vec<[Vec3; 3]>,
    uvs: Vec<[Vec2; 3]>,
    tangents: Vec<[Vec4; 3]>,
}

/// Which vertex attributes some primitive of the scene has (and so which [`Columns`] are filled).
#[derive(Clone, Copy)]
struct Attributes {
    normals: bool,
    uvs: bool,
    tangents: bool,
}

impl Columns {
    /// Appends a primitive without vertex attributes (a sphere).
    fn push_plain(&mut self, shape: Shape, attributes: Attributes) {
        self.shapes.push(shape);
        if attributes.normals {
            self.normals.push([Vec3::ZERO; 3]);
        }
        if attributes.uvs {
            self.uvs.push([Vec2::ZERO; 3]);
        }
        if attributes.tangents {
            self.tangents.push([Vec4::ZERO; 3]);
        }
    }

    /// The column `unordered` in BVH slot order, or zeros if the scene lacks it.
    fn ordered<T: Copy + Send + Sync + bytemuck::Zeroable>(
        unordered: &[T],
        order: &[u32],
    ) -> Vec<T> {
        if unordered.is_empty() {
            bytemuck::zeroed_vec(order.len())
        } else {
            order.par_iter().map(|&i| unordered[i as usize]).collect()
        }
    }
}

/// Flattens the world into a [`FlatScene`]. `path` names the scene in errors.
/// The camera used is the first one (the earliest spawned).
pub fn flatten(world: &hecs::World, path: &Path) -> Result<FlatScene> {
    let start = Instant::now();
    let camera = world
        .query::<(hecs::Entity, &Camera)>()
        .iter()
        .min_by_key(|(e, _)| e.id())
        .map(|(_, c)| *c)
        .ok_or_else(|| Error::input(path, None, "the scene has no camera"))?;
    if !(camera.eye.is_finite() && camera.forward.is_finite() && camera.up.is_finite()) {
        return Err(Error::input(
            path,
            Some("camera".into()),
            "the camera's position or orientation is not finite",
        ));
    }
    if !(camera.vfov > 0.0 && camera.vfov < std::f32::consts::PI) {
        return Err(Error::input(
            path,
            Some("camera".into()),
            format!(
                "the field of view must lie in (0, 180) degrees, got {}",
                camera.vfov.to_degrees()
            ),
        ));
    }

    let mut materials: Vec<(Bsdf, SurfaceTextures)> = Vec::new();
    let mut interner = TextureInterner::default();
    let mut material_index =
        |m: &Material, textures: Option<&MaterialTextures>, interner: &mut TextureInterner| {
            let surface = interner.surface(textures);
            let bsdf = bsdf_of(m, surface.metallic_roughness.is_set());
            let found = materials.iter().position(|b| *b == (bsdf, surface));
            found.unwrap_or_else(|| {
                materials.push((bsdf, surface));
                materials.len() - 1
            }) as u32
        };
    let normal_mapped = world
        .query::<&MaterialTextures>()
        .iter()
        .any(|t| t.normal.is_some());
    let attributes = Attributes {
        normals: world.query::<&Mesh>().iter().any(|m| !m.normals.is_empty()),
        uvs: world.query::<&Mesh>().iter().any(|m| !m.uvs.is_empty()),
        tangents: normal_mapped,
    };

    let mut groups: Vec<Group> = Vec::new();
    let mut columns = Columns::default();
    let mut warnings = Vec::new();
    for (name, transform, mesh, material, textures, tangents, emitter) in world
        .query::<(
            Option<&Name>,
            Option<&Transform>,
            &Mesh,
            &Material,
            Option<&MaterialTextures>,
            Option<&VertexTangents>,
            Option<&Emitter>,
        )>()
        .iter()
    {
        let name = name.map_or("unnamed mesh", |n| n.0.as_str());
        let transform = transform.copied().unwrap_or_default().0;
        let material = material_index(material, textures, &mut interner);
        let mut emitter = validate_emitter(emitter, path, name)?;
        let emission_texture = textures
            .and_then(|t| t.emissive.as_ref())
            .filter(|_| emitter.is_some() && !mesh.uvs.is_empty())
            .map(|slot| (interner.intern(Some(slot)), slot.texture.mean()));
        if emission_texture.is_some_and(|(_, mean)| mean == Rgb::ZERO) {
            emitter = None; // a black emission texture: nothing is emitted
        }
        let tangents = textures.and_then(|t| t.normal.as_ref()).map(|_| tangents);
        groups.push(Group {
            first: columns.shapes.len(),
            material,
            emitter,
            emission_texture,
        });
        let skipped = flatten_mesh(
            mesh,
            &transform,
            tangents,
            path,
            name,
            attributes,
            &mut columns,
        )?;
        if skipped > 0 {
            let kind = if emitter.is_some() { " emitting" } else { "" };
            warnings.push(format!(
                "mesh '{name}': skipped {skipped} degenerate (zero-area){kind} triangles"
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
        // The bounds too must be finite: the BVH builder cannot order infinite boxes.
        let reach = geom.center.abs().max_element() + geom.radius;
        if !(geom.radius > 0.0 && reach.is_finite()) {
            return Err(Error::input(
                path,
                Some(format!("sphere '{name}'")),
                "radius must be positive and the sphere's bounds finite",
            ));
        }
        let material = material_index(material, None, &mut interner);
        let emitter = validate_emitter(emitter, path, name)?;
        groups.push(Group {
            first: columns.shapes.len(),
            material,
            emitter,
            emission_texture: None,
        });
        columns.push_plain(Shape::Sphere(geom), attributes);
    }

    // BVH order: every per-primitive column is permuted once, so slots index them directly.
    let bvh_start = Instant::now();
    let built = bvh::build_bvh(&columns.shapes);
    let bvh_build = bvh_start.elapsed();
    let (bvh, order) = built.ok_or_else(|| {
        Error::input(
            path,
            None,
            format!(
                "the geometry is too degenerate for the BVH (deeper than {})",
                bvh::MAX_DEPTH
            ),
        )
    })?;
    let delta_lights = punctual_lights(world, bvh.bounds(), path)?;
    // Lights come from the primitives, not the slots: light `first_light[g] + k` is the
    // `k`-th primitive of group `g`.
    let mut area_lights = Vec::new();
    let mut textured_emission = Vec::new();
    let mut first_light = Vec::with_capacity(groups.len());
    for (g, group) in groups.iter().enumerate() {
        let Some(emitter) = group.emitter else {
            first_light.push(NO_EMITTER);
            continue;
        };
        first_light.push(area_lights.len() as u32);
        let end = groups
            .get(g + 1)
            .map_or(columns.shapes.len(), |next| next.first);
        for prim in group.first..end {
            let mut radiance = emitter.radiance;
            // A textured emitter is chosen by its mean radiance; shading applies the texel.
            textured_emission.push(group.emission_texture.map(|(texture, mean)| {
                radiance *= mean;
                TexturedEmission {
                    texture,
                    radiance: emitter.radiance,
                    inverse_mean: materials::inverse_or_zero(mean),
                    uvs: columns.uvs[prim],
                }
            }));
            let shape = columns.shapes[prim];
            area_lights.push(AreaLight::new(shape, radiance, emitter.two_sided));
        }
    }
    let occluders = occluders::occluders(&columns.shapes, &delta_lights);
    let mut lights = LightTable::new(area_lights, delta_lights);
    let textured_emission = if textured_emission.iter().any(Option::is_some) {
        lights.locate_samples_on_triangles();
        textured_emission
    } else {
        Vec::new()
    };
    let group_of = |prim: u32| groups.partition_point(|g| g.first <= prim as usize) - 1;
    let (material, emitter) = order
        .par_iter()
        .map(|&prim| {
            let g = group_of(prim);
            let light = match first_light[g] {
                NO_EMITTER => NO_EMITTER,
                first => first + prim - groups[g].first as u32,
            };
            (groups[g].material, light)
        })
        .unzip();
    // One record per slot, which also gives back the shape (see `FlatScene::shape`): a
    // second array of the shapes cost 84 MB and 20 ms at 1.3M triangles.
    let leaf_prims: Vec<leaf_prims::LeafPrim> = order
        .par_iter()
        .map(|&i| leaf_prims::LeafPrim::new(&columns.shapes[i as usize]))
        .collect();
    Ok(FlatScene {
        node_triangles: leaf_prims::node_triangles(&leaf_prims, &bvh),
        flat_primitives: leaf_prims::FlatPrimitives::new(&leaf_prims),
        leaf_prims,
        vertex_normals: Columns::ordered(&columns.normals, &order),
        vertex_uvs: Columns::ordered(&columns.uvs, &order),
        vertex_tangents: if normal_mapped {
            Columns::ordered(&columns.tangents, &order)
        } else {
            Vec::new()
        },
        material,
        emitter,
        material_textures: materials.iter().map(|m| m.1).collect(),
        materials: materials.iter().map(|m| m.0).collect(),
        textures: interner.textures,
        lights,
        textured_emission,
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

/// Punctual lights in world space. A directional light's power is taken over the disk that
/// the scene's bounding sphere casts, so that it is chosen in proportion to what it delivers.
fn punctual_lights(
    world: &hecs::World,
    scene_bounds: Option<Aabb>,
    path: &Path,
) -> Result<Vec<DeltaLight>> {
    let scene_radius = scene_bounds.map_or(1.0, |b| ((b.max - b.min).length() * 0.5).max(1e-3));
    let mut out = Vec::new();
    for (name, transform, light) in world
        .query::<(Option<&Name>, Option<&Transform>, &PunctualLight)>()
        .iter()
    {
        let name = name.map_or("unnamed light", |n| n.0.as_str());
        let t = transform.copied().unwrap_or_default().0;
        let position = t.transform_point3a(Vec3A::ZERO);
        let direction = t.transform_vector3a(Vec3A::NEG_Z).normalize_or_zero();
        let bad = |m: &str| {
            Err(Error::input(
                path,
                Some(format!("light '{name}'")),
                m.to_string(),
            ))
        };
        if !position.is_finite() || direction == Vec3A::ZERO {
            return bad("the light's transform is degenerate");
        }
        let delta = match *light {
            PunctualLight::Point { intensity } => DeltaLight::point(position, intensity),
            PunctualLight::Spot {
                intensity,
                inner_cone,
                outer_cone,
            } => {
                if !(0.0 <= inner_cone
                    && inner_cone < outer_cone
                    && outer_cone <= std::f32::consts::FRAC_PI_2)
                {
                    return bad("spot cone angles must satisfy 0 <= inner < outer <= pi/2");
                }
                DeltaLight::spot(position, direction, intensity, inner_cone, outer_cone)
            }
            PunctualLight::Directional { irradiance } => {
                DeltaLight::directional(direction, irradiance, scene_radius)
            }
        };
        if !(delta.intensity.is_finite() && delta.intensity.min_element() >= 0.0) {
            return bad("the light's intensity must be finite and non-negative");
        }
        if delta.intensity.max_element() > 0.0 {
            out.push(delta);
        }
    }
    Ok(out)
}

/// The render-side scattering model of a scene material; `mr_textured` says whether a
/// metallic-roughness texture varies it (which rules out the mirror special case).
fn bsdf_of(m: &Material, mr_textured: bool) -> Bsdf {
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
            clearcoat,
            clearcoat_roughness,
            sheen_color,
            sheen_roughness,
        } => {
            let base = MetallicRoughness {
                base_color,
                metallic,
                alpha: alpha_from_roughness(roughness),
                ior,
                specular,
                specular_color,
                transmission,
            };
            let layered = Layered {
                base,
                clearcoat,
                clearcoat_alpha: alpha_from_roughness(clearcoat_roughness),
                sheen_color,
                sheen_roughness,
            };
            if layered.has_layers() {
                return Bsdf::layered(layered);
            }
            if transmission == 1.0 && metallic == 0.0 && roughness == 0.0 {
                // Smooth clear glass stays the exact delta dielectric.
                return Bsdf::Dielectric {
                    ior,
                    fresnel: FresnelModel::Exact,
                    tint: base_color,
                };
            }
            if metallic == 1.0 && roughness == 0.0 && !mr_textured {
                // A smooth metal is the perfect mirror (the alpha -> 0 limit; for a coloured
                // metal, Schlick's brightening toward grazing angles is left out).
                return Bsdf::Mirror { tint: base_color };
            }
            Bsdf::metallic_roughness(base)
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

/// Appends the valid world-space triangles of `mesh` to `columns` (the vertex attributes
/// that `attributes` asks for, zero where the mesh has none); returns how many degenerate
/// triangles were skipped. `tangents` is `Some` for normal-mapped meshes: `Some(Some(_))`
/// with the file's tangents, `Some(None)` to make them per triangle.
fn flatten_mesh(
    mesh: &Mesh,
    world_from_object: &crate::math::Affine3A,
    tangents: Option<Option<&VertexTangents>>,
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
    extend(&mut columns.shapes, &kept_triangles, count, |t| {
        Shape::Triangle(geometry(t))
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
            [Vec3::ZERO; 3]
        } else {
            normals
        }
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
