//! Loaders: a file becomes a [`Scene`] (an ECS world plus the render settings the file asks
//! for). The file's extension picks the loader (`.toml`, `.gltf`/`.glb`, `.obj`); every error
//! names the file.
//!
//! Imported files (glTF, OBJ) are +Y up unless told otherwise ([`UpAxis`]) and are rotated
//! into wavetrace's +Z-up world by `(x, y, z) -> (x, -z, y)`, the inverse of what Blender's
//! exporters do: a Blender export comes back in Blender's own coordinates.

mod gltf;
pub(crate) mod gltf_animation;
mod gltf_check;
mod gltf_deform;
mod gltf_fix;
mod gltf_geometry;
mod gltf_memory;
mod gltf_meshopt;
mod image_decode;
mod obj;
mod obj_read;
mod place;
mod scene_file;

pub use place::{
    DARK_IMAGE_HINT, ROOM_EYE, ROOM_FLOOR, ROOM_PROPS, ROOM_STAGE_FRONT, ROOM_STAGE_TOP,
    ROOM_VIEW_FILL, bounding_box, dark_image_warning, has_lights, lights_itself, place_in_room,
    room_stage_transform,
};

use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat3A, Vec3A};
use crate::scene::{EnvironmentLight, EnvironmentSource, Mesh, Name, PunctualLight};
use std::path::Path;

/// A loaded scene: the entities, and the render settings the file asks for (the CLI's flags
/// override them).
pub struct Scene {
    /// Entities of the scene (see [`crate::scene`]).
    pub world: hecs::World,
    /// Settings stated in the scene file.
    pub defaults: SceneDefaults,
    /// Things the loader skipped or replaced (a missing `.mtl`, an unsupported texture...),
    /// for the user to see.
    pub warnings: Vec<String>,
}

/// The up axis of an imported file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UpAxis {
    /// +Y up (glTF's convention, and Blender's OBJ export): rotated to +Z up.
    #[default]
    Y,
    /// +Z up already: used as is.
    Z,
}

impl UpAxis {
    /// The rotation from the file's frame to wavetrace's +Z-up world (exact: no rounding).
    pub fn world_from_file(self) -> Affine3A {
        match self {
            UpAxis::Y => {
                Affine3A::from_mat3(Mat3A::from_cols(Vec3A::X, Vec3A::Z, Vec3A::NEG_Y).into())
            }
            UpAxis::Z => Affine3A::IDENTITY,
        }
    }
}

/// How glTF `KHR_lights_punctual` intensities are read (OBJ files have no such lights).
///
/// The renderer's lights are radiometric: a point or spot light's intensity is W/sr, a
/// directional light's irradiance W/m^2. The glTF specification's units are photometric.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LightUnits {
    /// The specification's units, as Blender's exporter writes them in its default
    /// ("Standard") lighting mode: point and spot intensities in candela, directional in lux,
    /// turned into W/sr and W/m^2 with 683 lm/W ([`LUMENS_PER_WATT`]).
    #[default]
    Spec,
    /// The numbers read as radiometric as they are: candela as W/sr, lux as W/m^2 (Blender's
    /// "Unitless" export mode).
    Unitless,
    /// Blender's "Raw" export mode: a point or spot intensity is the lamp's power in watts
    /// (W/sr = W / 4 pi), a directional one its strength in W/m^2.
    Raw,
}

/// The luminous efficacy that turns photometric into radiometric units (lm/W): the
/// definition of the candela, and what Blender's exporter multiplies its watts by.
pub const LUMENS_PER_WATT: f32 = 683.0;

impl LightUnits {
    /// The factor from the file's number to the renderer's unit, for a point or spot light
    /// (`directional: false`, to W/sr) or a directional light (to W/m^2).
    pub fn factor(self, directional: bool) -> f32 {
        match (self, directional) {
            (LightUnits::Spec, _) => 1.0 / LUMENS_PER_WATT,
            (LightUnits::Unitless, _) | (LightUnits::Raw, true) => 1.0,
            (LightUnits::Raw, false) => 1.0 / (4.0 * std::f32::consts::PI),
        }
    }
}

/// How [`load_scene_with`] treats imported model files.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Place the model in the seed room even if it has its own lights (`--in-room`).
    pub in_room: bool,
    /// Name of the camera to render from; `None` takes the file's first camera.
    pub camera: Option<String>,
    /// The model file's up axis (`--up`).
    pub up: UpAxis,
    /// How the model file's light intensities are read (`--light-units`).
    pub light_units: LightUnits,
    /// The environment flags (`--env`, ...), which replace the file's `[environment]`
    /// field by field. A model file given an environment renders under it as it is, not in
    /// the seed room (unless `in_room`).
    pub environment: EnvironmentOverrides,
}

/// The command line's environment settings; `None` keeps the scene's.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct EnvironmentOverrides {
    /// `--env FILE|R,G,B`.
    pub source: Option<EnvironmentSource>,
    /// `--env-strength`.
    pub strength: Option<f32>,
    /// `--env-rotation` (degrees about +Z).
    pub rotation_degrees: Option<f32>,
    /// `--env-hidden`: camera rays that escape see black.
    pub hidden: bool,
}

impl EnvironmentOverrides {
    /// Whether any flag was given.
    pub fn any(&self) -> bool {
        self.source.is_some()
            || self.strength.is_some()
            || self.rotation_degrees.is_some()
            || self.hidden
    }

    /// Applies the flags to the world's environment (adding one if `--env` names a source).
    /// A flag that modifies an environment the scene lacks is an error. Values are checked
    /// by `flatten`, which loads the file.
    pub fn apply(&self, world: &mut hecs::World, path: &Path) -> Result<()> {
        if !self.any() {
            return Ok(());
        }
        let existing = (world.query::<(hecs::Entity, &EnvironmentLight)>().iter())
            .map(|(entity, light)| (entity, light.clone()))
            .next();
        let base = match (existing, &self.source) {
            (Some((entity, light)), _) => {
                world.despawn(entity).expect("entity just queried");
                light
            }
            (None, Some(source)) => EnvironmentLight {
                source: source.clone(),
                strength: 1.0,
                rotation_degrees: 0.0,
                visible_to_camera: true,
            },
            (None, None) => {
                return Err(Error::input(
                    path,
                    None,
                    "--env-strength, --env-rotation and --env-hidden need an environment: \
                     give --env FILE|R,G,B or an [environment] table in the scene",
                ));
            }
        };
        let light = EnvironmentLight {
            source: self.source.clone().unwrap_or(base.source),
            strength: self.strength.unwrap_or(base.strength),
            rotation_degrees: self.rotation_degrees.unwrap_or(base.rotation_degrees),
            visible_to_camera: base.visible_to_camera && !self.hidden,
        };
        world.spawn((Name("environment".into()), light));
        Ok(())
    }
}

/// What [`load_scene_placed`] did with the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// A scene file, loaded as written.
    SceneFile,
    /// A model file that lights itself, rendered as it is.
    AsIs,
    /// A model file placed in the seed room.
    InRoom,
}

/// Render settings a scene file may state; `None` leaves the choice to the caller.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDefaults {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Shadow rays per diffuse hit.
    pub shadow_rays: Option<u32>,
    /// Where the random numbers come from (`sampler = "independent" | "sobol"`).
    pub sampler: Option<crate::math::rng::Sampler>,
}

impl SceneDefaults {
    /// Fields of `over` replace those of `self` where set.
    pub fn overridden_by(self, over: SceneDefaults) -> SceneDefaults {
        SceneDefaults {
            width: over.width.or(self.width),
            height: over.height.or(self.height),
            spp: over.spp.or(self.spp),
            shadow_rays: over.shadow_rays.or(self.shadow_rays),
            sampler: over.sampler.or(self.sampler),
        }
    }
}

/// The seed's hexagonal room, built into the binary so that it works from any directory.
pub const BUILTIN_ROOM: &str = include_str!("../../../scenes/room.toml");

/// Loads a scene file with the default [`LoadOptions`]; the loader is chosen by the
/// extension (`.toml`, `.gltf`, `.glb`, `.obj`).
///
/// A model file (glTF or OBJ) renders as it is only if it lights itself ([`lights_itself`]):
/// it has punctual lights, or it has emitters or unlit surfaces *and* a camera (a scene set up
/// for rendering), or every surface is unlit. Any other model is a *bare model* — its glow
/// alone (a few emissive decals) would leave it black — and is placed in the seed room ([`place_in_room`]) and seen from the room's
/// camera. A file rendered as it is uses its first camera, or a camera framing its bounding
/// box when it has none.
pub fn load_scene(path: &Path) -> Result<Scene> {
    load_scene_with(path, &LoadOptions::default())
}

/// [`load_scene`] with options.
pub fn load_scene_with(path: &Path, options: &LoadOptions) -> Result<Scene> {
    load_scene_placed(path, options).map(|(scene, _)| scene)
}

/// [`load_scene_with`], also telling how the file was placed.
pub fn load_scene_placed(path: &Path, options: &LoadOptions) -> Result<(Scene, Placement)> {
    let (mut scene, placement) = if is_model_file(path) {
        let model = import_model_with(path, options.up, options.light_units)?;
        let under_environment = options.environment.source.is_some();
        if options.in_room || !(lights_itself(&model.world) || under_environment) {
            (place_in_room(model, path)?, Placement::InRoom)
        } else {
            let mut model = model;
            place::ensure_camera(&mut model.world, path)?;
            (model, Placement::AsIs)
        }
    } else {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if ext.as_deref() != Some("toml") {
            return Err(Error::input(
                path,
                None,
                "unknown scene file extension (expected .toml, .gltf, .glb or .obj)",
            ));
        }
        let text = read_text(path)?;
        (scene_file::load(path, &text)?, Placement::SceneFile)
    };
    place::select_camera(&mut scene.world, options.camera.as_deref(), path)?;
    options.environment.apply(&mut scene.world, path)?;
    Ok((scene, placement))
}

/// Whether the extension names a model format ([`import_model`] reads it).
pub fn is_model_file(path: &Path) -> bool {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    matches!(ext.as_deref(), Some("gltf" | "glb" | "obj"))
}

/// Imports a glTF or OBJ file as it is: its entities (cameras and lights included) in world
/// space, the file's `up` axis turned to +Z, light intensities read in the specification's
/// units ([`LightUnits::Spec`]). No room, no camera added.
pub fn import_model(path: &Path, up: UpAxis) -> Result<Scene> {
    import_model_with(path, up, LightUnits::default())
}

/// [`import_model`] with the light intensities read as `units` say.
pub fn import_model_with(path: &Path, up: UpAxis, units: LightUnits) -> Result<Scene> {
    let mut scene = import_file(path, up)?;
    for light in scene.world.query_mut::<&mut PunctualLight>() {
        match light {
            PunctualLight::Point { intensity } | PunctualLight::Spot { intensity, .. } => {
                *intensity *= units.factor(false)
            }
            PunctualLight::Directional { irradiance } => *irradiance *= units.factor(true),
        }
    }
    Ok(scene)
}

/// The loader chosen by the extension; lights in the file's own numbers.
fn import_file(path: &Path, up: UpAxis) -> Result<Scene> {
    if !path.is_file() {
        return Err(Error::input(path, None, "no such file"));
    }
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("gltf" | "glb") => gltf::load(path, up),
        Some("obj") => obj::load(path, up),
        _ => Err(Error::input(
            path,
            None,
            "unknown model file extension (expected .gltf, .glb or .obj)",
        )),
    }
}

/// Checks an imported mesh's index ranges and attribute counts, naming it on failure.
pub(crate) fn check_mesh(path: &Path, name: &str, mesh: &Mesh) -> Result<()> {
    let n = mesh.positions.len();
    for (t, tri) in mesh.indices.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(Error::input(
                path,
                Some(name.to_string()),
                format!("triangle {t}: vertex index {bad} out of range ({n} vertices)"),
            ));
        }
    }
    if let Some(bad) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(Error::input(
            path,
            Some(name.to_string()),
            format!("vertex {bad} is not finite"),
        ));
    }
    Ok(())
}

/// Loads a TOML scene from text; `path` names it in errors and anchors relative includes.
pub fn load_scene_str(path: &Path, text: &str) -> Result<Scene> {
    scene_file::load(path, text)
}

/// Reads a whole text file, with errors that name it.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    if path.is_dir() {
        return Err(Error::input(path, None, "is a directory, not a file"));
    }
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        action: "cannot read",
        source,
    })?;
    if text.trim().is_empty() {
        return Err(Error::input(path, None, "file is empty"));
    }
    Ok(text)
}
