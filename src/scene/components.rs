//! ECS components of a scene. Geometry is stored in object space; [`Transform`] places it.

pub use crate::bsdf::FresnelModel;
use crate::math::{Affine3A, Rgb, Vec2, Vec3, Vec4};
use crate::texture::{Texture, UvTransform};
use std::path::PathBuf;
use std::sync::Arc;

/// Object-to-world placement of an entity (`world_from_object`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform(pub Affine3A);

impl Default for Transform {
    fn default() -> Self {
        Transform(Affine3A::IDENTITY)
    }
}

/// Human-readable name of an entity, used in error messages and statistics.
#[derive(Clone, Debug, PartialEq)]
pub struct Name(pub String);

/// An indexed triangle mesh in object space.
///
/// A triangle's front face is the side from which `v0, v1, v2` appear counter-clockwise;
/// its geometric normal is `normalize((v1 - v0) x (v2 - v0))`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, object space.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (object space), or empty for flat shading.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates, or empty.
    pub uvs: Vec<Vec2>,
    /// Triangles as three indices into the vertex arrays.
    pub indices: Vec<[u32; 3]>,
}

/// A [`Mesh`] that several entities use (glTF nodes that share a mesh, the instances of
/// `EXT_mesh_gpu_instancing`): its data is stored once and each entity places it with its own
/// [`Transform`]. An entity has either a `Mesh` or a `SharedMesh`; everything that reads
/// meshes reads both (see [`mesh_of`]), and [`crate::flatten()`] may trace such a mesh once
/// per entity through a second-level BVH instead of copying it (see `accel::instances`).
#[derive(Clone, Debug)]
pub struct SharedMesh(pub Arc<Mesh>);

/// The mesh of an entity that has a [`Mesh`] or a [`SharedMesh`].
pub fn mesh_of<'a>(mesh: Option<&'a Mesh>, shared: Option<&'a SharedMesh>) -> Option<&'a Mesh> {
    mesh.or(shared.map(|s| &*s.0))
}

/// An analytic sphere of the given radius centred on the entity's origin. Its transform may
/// translate, rotate and scale uniformly; the outward side is the front.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Radius in object units (> 0).
    pub radius: f32,
}

/// How a surface scatters light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// Ideal diffuse reflector with the given albedo. Albedo 0 absorbs everything, which is
    /// how light sources that "reflect nothing" are written.
    Lambertian {
        /// Hemispherical reflectance, linear RGB in [0, 1].
        albedo: Rgb,
    },
    /// Perfect specular reflector; `tint` scales the reflected radiance.
    Mirror {
        /// Reflectance, linear RGB (1 = ideal mirror).
        tint: Rgb,
    },
    /// Smooth dielectric interface (glass) between the outside (vacuum/air) and an inside of
    /// refractive index `ior`; the front face (geometric normal side) is the outside.
    Dielectric {
        /// Index of refraction of the inside relative to the outside.
        ior: f32,
        /// Fresnel equations used to split reflection and refraction.
        fresnel: FresnelModel,
        /// Scales both reflected and transmitted radiance (1 = clear glass).
        tint: Rgb,
    },
    /// glTF 2.0 metallic-roughness surface with `KHR_materials_specular`, `KHR_materials_ior`
    /// and `KHR_materials_transmission` (see `bsdf::metallic_roughness` for the model), under
    /// optional `KHR_materials_clearcoat` and `KHR_materials_sheen` layers (`bsdf::layered`;
    /// with either, the exact special cases below do not apply).
    /// A non-metal with `specular` 0 and no transmission is exactly [`Material::Lambertian`];
    /// clear glass with roughness 0 is exactly [`Material::Dielectric`]; a metal with
    /// roughness 0 (and no metallic-roughness texture) is [`Material::Mirror`] tinted by the
    /// base colour (exact for white; a coloured one loses Schlick's grazing brightening).
    MetallicRoughness {
        /// Base colour, linear RGB in [0, 1]: diffuse albedo, metal reflectance at normal
        /// incidence, and transmission tint.
        base_color: Rgb,
        /// Share of the conductor, in [0, 1].
        metallic: f32,
        /// Perceptual roughness in [0, 1]; the GGX alpha is its square.
        roughness: f32,
        /// Strength of the dielectric's specular layer, in [0, 1] (glTF default 1).
        specular: f32,
        /// Tint of the dielectric's normal-incidence reflectance (glTF default white).
        specular_color: Rgb,
        /// Index of refraction of the dielectric (glTF default 1.5).
        ior: f32,
        /// Share of rough glass in the dielectric, in [0, 1] (glTF default 0).
        transmission: f32,
        /// `KHR_materials_clearcoat` strength in [0, 1]: a clear GGX dielectric layer (ior
        /// 1.5) on top (0: none, the default; see `bsdf::layered`).
        clearcoat: f32,
        /// Perceptual roughness of the clear coat in [0, 1] (default 0).
        clearcoat_roughness: f32,
        /// `KHR_materials_sheen` colour, linear RGB in [0, 1] (black: no sheen, the default).
        sheen_color: Rgb,
        /// Perceptual roughness of the sheen in [0, 1] (default 0; below 0.05 taken as 0.05).
        sheen_roughness: f32,
    },
    /// glTF `KHR_materials_unlit`: the surface shows `color` (times the base-colour texture
    /// and vertex colours) to every ray that hits it, camera and bounce rays alike, and
    /// reflects nothing; it lights nothing through next-event estimation (it is not a light
    /// source). A display convention for baked or flat-shaded assets, not physics.
    Unlit {
        /// The colour shown, linear RGB in [0, 1] (the base colour factor).
        color: Rgb,
    },
}

/// Surface emission: the entity is an area light of constant radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Emitter {
    /// Emitted radiance, linear RGB (W sr^-1 m^-2 per unit of the scene's scale).
    pub radiance: Rgb,
    /// Whether the back face emits too; by default only the front face does.
    pub two_sided: bool,
}

/// A texture and how the mesh's texture coordinates reach it.
#[derive(Clone, Debug, PartialEq)]
pub struct TextureSlot {
    /// The image and its sampler, shared between the entities that use it.
    pub texture: Arc<Texture>,
    /// `KHR_texture_transform` from the mesh's coordinates to the texture's.
    pub uv_transform: UvTransform,
}

impl TextureSlot {
    /// The texture at the mesh's coordinates as they are.
    pub fn new(texture: Arc<Texture>) -> Self {
        TextureSlot {
            texture,
            uv_transform: UvTransform::IDENTITY,
        }
    }
}

/// Textures that vary the entity's material over its [`Mesh`], looked up at each hit from the
/// interpolated texture coordinates (glTF material textures; MTL `map_Kd`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialTextures {
    /// Linear colour (decoded from sRGB) that multiplies the material's colour: the base
    /// colour, the Lambertian albedo, the mirror or glass tint.
    pub base_color: Option<TextureSlot>,
    /// glTF `metallicRoughnessTexture` (linear): blue multiplies `metallic`, green multiplies
    /// `roughness` (of [`Material::MetallicRoughness`]; other materials ignore it).
    pub metallic_roughness: Option<TextureSlot>,
    /// Tangent-space normal map (linear, `2 c - 1`; +x along the tangent, +y along the
    /// bitangent, +z along the interpolated normal).
    pub normal: Option<TextureSlot>,
    /// glTF `normalTexture.scale`: multiplies the map's x and y.
    pub normal_scale: f32,
    /// Linear colour (decoded from sRGB) that multiplies the [`Emitter`]'s radiance.
    pub emissive: Option<TextureSlot>,
    /// `KHR_materials_specular` `specularTexture`: its alpha (linear) multiplies `specular`.
    pub specular: Option<TextureSlot>,
    /// `KHR_materials_specular` `specularColorTexture`: linear colour (decoded from sRGB)
    /// that multiplies `specular_color`.
    pub specular_color: Option<TextureSlot>,
    /// `KHR_materials_clearcoat` `clearcoatTexture`: red (linear) multiplies `clearcoat`.
    pub clearcoat: Option<TextureSlot>,
    /// `clearcoatRoughnessTexture`: green (linear) multiplies `clearcoat_roughness`.
    pub clearcoat_roughness: Option<TextureSlot>,
    /// `clearcoatNormalTexture`: the coat's own tangent-space normal map (decoded as
    /// [`Self::normal`], in the same tangent frame).
    pub clearcoat_normal: Option<TextureSlot>,
    /// `clearcoatNormalTexture.scale`: multiplies the coat's map's x and y.
    pub clearcoat_normal_scale: f32,
    /// `KHR_materials_sheen` `sheenColorTexture`: colour (decoded from sRGB) that multiplies
    /// `sheen_color`.
    pub sheen_color: Option<TextureSlot>,
    /// `sheenRoughnessTexture`: alpha (linear) multiplies `sheen_roughness`.
    pub sheen_roughness: Option<TextureSlot>,
    /// `KHR_materials_iridescence` `iridescenceTexture`: red (linear) multiplies the factor.
    pub iridescence: Option<TextureSlot>,
    /// `iridescenceThicknessTexture`: green (linear) mixes the thickness from the minimum (0)
    /// to the maximum (1).
    pub iridescence_thickness: Option<TextureSlot>,
    /// `KHR_materials_anisotropy` of [`Material::MetallicRoughness`]: kept with the textures
    /// because, textured or not, it varies over the mesh with the tangent frame.
    pub anisotropy: Option<MaterialAnisotropy>,
}

/// `KHR_materials_anisotropy`: a metallic-roughness material rougher along a direction of
/// the mesh's tangent frame (`bsdf::anisotropy` has the formulas).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialAnisotropy {
    /// `anisotropyStrength` in [0, 1].
    pub strength: f32,
    /// `anisotropyRotation`: radians from the tangent toward the bitangent.
    pub rotation: f32,
    /// The glTF specification's alphas or Cycles' (Blender's files).
    pub mapping: crate::bsdf::AnisotropyMapping,
    /// `anisotropyTexture` (linear): red and green the direction in tangent space
    /// (`2 c - 1`, then rotated by `rotation`), blue multiplies the strength.
    pub texture: Option<TextureSlot>,
}

impl MaterialTextures {
    /// Whether a normal map (the base's or the coat's) needs the mesh's tangents.
    pub fn is_normal_mapped(&self) -> bool {
        self.normal.is_some() || self.clearcoat_normal.is_some()
    }

    /// Whether no texture is set.
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none()
            && self.metallic_roughness.is_none()
            && self.normal.is_none()
            && self.emissive.is_none()
            && self.specular.is_none()
            && self.specular_color.is_none()
            && self.clearcoat.is_none()
            && self.clearcoat_roughness.is_none()
            && self.clearcoat_normal.is_none()
            && self.sheen_color.is_none()
            && self.sheen_roughness.is_none()
            && self.iridescence.is_none()
            && self.iridescence_thickness.is_none()
            && self.anisotropy.is_none()
    }

    /// Whether shading reads the mesh's tangent frame (a normal map or anisotropy).
    pub fn needs_tangents(&self) -> bool {
        self.is_normal_mapped() || self.anisotropy.is_some()
    }
}

/// Per-vertex tangents of the entity's [`Mesh`] (glTF `TANGENT`, object space): `xyz` is the
/// direction of increasing `u`, `w` (+-1) the handedness, so that the bitangent is
/// `cross(normal, xyz) * w`. Without it, normal maps use tangents made per triangle from the
/// texture coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexTangents(pub Vec<Vec4>);

/// The medium inside a transmissive object (`KHR_materials_volume`): light travelling through
/// it is absorbed by Beer-Lambert's law, `exp(-absorption * distance)` per channel. Only paths
/// that refract into the object through its front (outer) side enter it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Volume {
    /// Absorption coefficient sigma_a per unit length, linear RGB (>= 0, finite).
    pub absorption: Rgb,
}

impl Volume {
    /// The medium that leaves `colour` of the light after `distance` (glTF's
    /// `attenuationColor` and `attenuationDistance`): sigma_a = -ln(colour) / distance, or
    /// `None` when it absorbs nothing (white colour or infinite distance).
    pub fn from_attenuation(colour: Rgb, distance: f32) -> Option<Volume> {
        // A black channel absorbs completely within any distance: as good as the smallest
        // positive colour, which keeps the coefficient finite.
        let colour = colour.clamp(Rgb::splat(f32::MIN_POSITIVE), Rgb::ONE);
        let absorption = -Rgb::new(colour.x.ln(), colour.y.ln(), colour.z.ln()) / distance;
        (distance > 0.0 && absorption.max_element() > 0.0).then_some(Volume { absorption })
    }
}

/// `KHR_materials_iridescence` of a [`Material::MetallicRoughness`] entity: a thin film on
/// the surface whose interference colours the metal's and the opaque dielectric's Fresnel
/// terms (`bsdf::thin_film`). The loader has made every value sane (docs/importing.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iridescence {
    /// `iridescenceFactor` in [0, 1] (0: no film).
    pub factor: f32,
    /// `iridescenceIor`, the film's index of refraction (> 0).
    pub ior: f32,
    /// `iridescenceThicknessMinimum` in nanometres (>= 0): the thickness where the thickness
    /// texture's green is 0.
    pub thickness_minimum: f32,
    /// `iridescenceThicknessMaximum` in nanometres (>= 0): the thickness without a thickness
    /// texture, and where its green is 1.
    pub thickness_maximum: f32,
}

/// How the alpha of a surface covers it (glTF `alphaMode` MASK or BLEND; OPAQUE surfaces
/// have no such component). The coverage at a point is `factor` x the base-colour texture's
/// alpha x the vertex colour's alpha.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaCoverage {
    /// MASK or BLEND.
    pub mode: AlphaMode,
    /// The base colour factor's alpha, in [0, 1].
    pub factor: f32,
}

/// See [`AlphaCoverage`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// Covered where the coverage is at least `cutoff` (glTF `alphaCutoff`, default 0.5).
    Mask {
        /// The threshold.
        cutoff: f32,
    },
    /// Covered with probability equal to the coverage (stochastic transparency): a path
    /// tracer's unbiased estimate of a partly transparent surface.
    Blend,
}

/// Per-vertex colours of the entity's [`Mesh`] (glTF `COLOR_0`, OBJ `v x y z r g b`), linear
/// RGBA: they multiply the material's base colour (albedo, tint), as glTF's base colour
/// texture does. Alpha is 1 where the file gives RGB only.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexColors(pub Vec<Vec4>);

/// A punctual (delta) light at the entity's origin, shining along the entity's local `-z`
/// (glTF `KHR_lights_punctual`). Rays never hit it; it is reached only by next-event
/// estimation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualLight {
    /// Emits equally in every direction.
    Point {
        /// Radiant intensity, W/sr per colour channel (glTF's candela, read as W/sr).
        intensity: Rgb,
    },
    /// A point light restricted to a cone about `-z`, with a smooth angular falloff.
    Spot {
        /// Radiant intensity on the axis, W/sr.
        intensity: Rgb,
        /// Angle from the axis (radians) inside which the intensity is full (glTF's falloff).
        inner_cone: f32,
        /// Angle from the axis (radians) outside which there is no light.
        outer_cone: f32,
        /// How the intensity falls from the axis to the outer cone.
        falloff: SpotFalloff,
    },
    /// Parallel light travelling along `-z`, as from an infinitely distant source.
    Directional {
        /// Irradiance on a surface facing the light, W/m^2 (glTF's lux, read as W/m^2).
        irradiance: Rgb,
    },
}

/// How a spot light's intensity falls off toward its outer cone.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SpotFalloff {
    /// glTF's recommended falloff: the square of a ramp linear in the cosine, 0 at the outer
    /// cone and 1 at the inner one.
    Gltf,
    /// Blender's Spot Blend as Cycles renders it: a smoothstep in the cosine from the outer cone
    /// (0) over `blend` (in [0, 1]) of the cosine range `[cos outer, 1]`; the inner cone is
    /// not used.
    Blender {
        /// Blender's Spot Blend.
        blend: f32,
    },
}

/// The light at infinity around the scene (Blender's world, Mitsuba's `envmap`): at most one
/// entity carries it. Described here; `flatten` loads the file and checks the values.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentLight {
    /// A constant colour or an equirectangular image.
    pub source: EnvironmentSource,
    /// Multiplies the radiance (>= 0).
    pub strength: f32,
    /// Degrees about +Z (Blender's Mapping node rotation in front of the Environment Texture).
    pub rotation_degrees: f32,
    /// Whether camera rays that escape see it (false: black background, lighting unchanged).
    pub visible_to_camera: bool,
}

/// Where an [`EnvironmentLight`]'s radiance comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum EnvironmentSource {
    /// The same radiance from every direction.
    Color(Rgb),
    /// A Radiance `.hdr` or OpenEXR `.exr` latitude-longitude map (path as resolved by the
    /// loader: relative to the scene file, or as given on the command line).
    File(PathBuf),
}

/// How a camera projects the scene onto its film.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Projection {
    /// Rays from the eye through the film, spanning the vertical field of view `vfov`.
    #[default]
    Perspective,
    /// Parallel rays along `forward` from a film through the eye, `2 half_height` world
    /// units tall (glTF's `ymag` is the half height); its width follows the image's aspect
    /// ratio. `vfov` is unused.
    Orthographic {
        /// Half the film's height, world units.
        half_height: f32,
    },
}

/// A camera in world space: a pinhole, or orthographic ([`Projection`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection.
    pub eye: Vec3,
    /// Viewing direction (unit).
    pub forward: Vec3,
    /// Up direction of the image (unit, orthogonal to `forward`).
    pub up: Vec3,
    /// Vertical field of view in radians.
    pub vfov: f32,
    /// Width / height the camera was made for, if it dictates one.
    pub aspect_ratio: Option<f32>,
    /// Perspective or orthographic.
    pub projection: Projection,
}

impl Camera {
    /// A camera at `eye` looking at `target`, with `up` projected to be orthogonal.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, vfov: f32) -> Self {
        let forward = (target - eye).normalize();
        let right = forward.cross(up).normalize();
        Camera {
            eye,
            forward,
            up: right.cross(forward),
            vfov,
            aspect_ratio: None,
            projection: Projection::Perspective,
        }
    }

    /// Whether the camera is orthographic.
    pub fn is_orthographic(&self) -> bool {
        matches!(self.projection, Projection::Orthographic { .. })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn volume_from_attenuation_is_beer_lambert() {
        // What is left after `distance` is the attenuation colour.
        let v = Volume::from_attenuation(Rgb::new(0.8, 0.5, 1.0), 2.0).unwrap();
        let left = (-v.absorption * 2.0).to_array().map(f32::exp);
        for (l, c) in left.iter().zip([0.8, 0.5, 1.0]) {
            assert!((l - c).abs() < 1e-6, "{left:?}");
        }
        // Nothing absorbed: white, an infinite or a non-positive distance (glTF's defaults
        // and invalid values).
        assert_eq!(Volume::from_attenuation(Rgb::ONE, 1.0), None);
        assert_eq!(
            Volume::from_attenuation(Rgb::splat(0.5), f32::INFINITY),
            None
        );
        assert_eq!(Volume::from_attenuation(Rgb::splat(0.5), 0.0), None);
        // A black channel absorbs everything within the distance, with a finite coefficient.
        let black = Volume::from_attenuation(Rgb::ZERO, 1.0).unwrap();
        assert!(black.absorption.is_finite() && black.absorption.min_element() > 80.0);
    }
}
