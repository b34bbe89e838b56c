//! Loaders: a file becomes a [`Scene`] (an ECS world plus the render settings the file asks
//! for). The file's extension picks the loader (`.toml`, `.gltf`/`.glb`, `.obj`); every error
//! names the file.
//!
//! Imported files (glTF, OBJ) are +Y up unless told otherwise ([`UpAxis`]) and are rotated
//! into wavetrace's +Z-up world by `(x, y, z) -> (x, -z, y)`, the inverse of what Blender's
//! exporters do: a Blender export comes back in Blender's own coordinates.
//!
//! The files, each importing only those listed before it (and `crate::settings`, which owns
//! [`SceneDefaults`](crate::settings::SceneDefaults)):
//! - `shared.rs`: the [`Scene`], [`UpAxis`] and the imported-mesh check;
//! - `image_decode.rs`: texture images from bytes;
//! - `gltf/`, `obj/`: the model importers;
//! - `model.rs`: a model file imported as it is, its lights in the units asked for;
//! - `place.rs`: bare models placed in the hexagonal room, `[[model]]` placement, cameras;
//! - `scene_file.rs`: the TOML scene format (which places models through `place.rs`);
//! - this file: [`load_scene`] and its options, the command line's environment flags.

mod gltf;
pub(crate) use gltf::animation as gltf_animation; // posing reads the rig (scene/animation.rs)
mod image_decode;
mod model;
mod obj;
mod place;
mod scene_file;
mod shared;

pub use model::{LUMENS_PER_WATT, LightUnits, import_model, import_model_with, is_model_file};
pub use place::{
    DARK_IMAGE_HINT, ROOM_EYE, ROOM_FLOOR, ROOM_PROPS, ROOM_STAGE_FRONT, ROOM_STAGE_TOP,
    ROOM_VIEW_FILL, bounding_box, dark_image_warning, has_lights, lights_itself,
    room_stage_transform,
};
pub use scene_file::BUILTIN_ROOM;
pub use shared::{Scene, UpAxis};

use crate::error::{Error, Result};
use crate::scene::{EnvironmentLight, EnvironmentSource, Name};
use std::path::Path;

/// How [`load_scene_with`] treats imported model files.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Place the model in the hexagonal room even if it has its own lights (`--in-room`).
    pub in_room: bool,
    /// Name of the camera to render from; `None` takes the file's first camera.
    pub camera: Option<String>,
    /// The model file's up axis (`--up`).
    pub up: UpAxis,
    /// How the model file's light intensities are read (`--light-units`).
    pub light_units: LightUnits,
    /// The environment flags (`--env`, ...), which replace the file's `[environment]`
    /// field by field. A model file given an environment renders under it as it is, not in
    /// the hexagonal room (unless `in_room`).
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
    /// A model file placed in the hexagonal room.
    InRoom,
}

/// The bare-model rule: the hexagonal room with `model` as its subject, on the room's stage
/// ([`room_stage_transform`]), seen by the room's camera. The model's cameras are dropped.
pub fn place_in_room(model: Scene, path: &Path) -> Result<Scene> {
    place::place_in_room(model, scene_file::builtin_room, path)
}

/// Loads a scene file with the default [`LoadOptions`]; the loader is chosen by the
/// extension (`.toml`, `.gltf`, `.glb`, `.obj`).
///
/// A model file (glTF or OBJ) renders as it is only if it lights itself ([`lights_itself`]):
/// it has punctual lights, or it has emitters or unlit surfaces *and* a camera (a scene set up
/// for rendering), or every surface is unlit. Any other model is a *bare model* — its glow
/// alone (a few emissive decals) would leave it black — and is placed in the hexagonal room
/// ([`place_in_room`]) and seen from the room's camera. A file rendered as it is uses its
/// first camera, or a camera framing its bounding box when it has none.
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
        let model = model::import_model_with(path, options.up, options.light_units)?;
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

/// Loads a TOML scene from text; `path` names it in errors and anchors relative includes.
pub fn load_scene_str(path: &Path, text: &str) -> Result<Scene> {
    scene_file::load(path, text)
}

/// Reads a whole text file, with errors that name it.
fn read_text(path: &Path) -> Result<String> {
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
