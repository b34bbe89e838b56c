//! Loaders: a file becomes a [`Scene`] (an ECS world plus the render settings the file asks
//! for). The file's extension picks the loader (`.toml`, `.gltf`/`.glb`, `.obj`); every error
//! names the file.
//!
//! Imported files (glTF, OBJ) are +Y up unless told otherwise ([`UpAxis`]) and are rotated
//! into wavetrace's +Z-up world by `(x, y, z) -> (x, -z, y)`, the inverse of what Blender's
//! exporters do: a Blender export comes back in Blender's own coordinates.

mod gltf;
mod gltf_check;
mod gltf_fix;
mod obj;
mod obj_check;
mod place;
mod scene_file;

pub use place::{ROOM_FREE_FLOOR_CENTRE, bounding_box, has_lights, place_in_room};

use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat3A, Vec3A};
use crate::scene::Mesh;
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
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
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

/// How [`load_scene_with`] treats imported model files.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Place the model in the seed room even if it has its own lights (`--in-room`).
    pub in_room: bool,
    /// Name of the camera to render from; `None` takes the file's first camera.
    pub camera: Option<String>,
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
}

impl SceneDefaults {
    /// Fields of `over` replace those of `self` where set.
    pub fn overridden_by(self, over: SceneDefaults) -> SceneDefaults {
        SceneDefaults {
            width: over.width.or(self.width),
            height: over.height.or(self.height),
            spp: over.spp.or(self.spp),
            shadow_rays: over.shadow_rays.or(self.shadow_rays),
        }
    }
}

/// The seed's hexagonal room, built into the binary so that it works from any directory.
pub const BUILTIN_ROOM: &str = include_str!("../../../scenes/room.toml");

/// Loads a scene file with the default [`LoadOptions`]; the loader is chosen by the
/// extension (`.toml`, `.gltf`, `.glb`, `.obj`).
///
/// A model file (glTF or OBJ) with no emitter and no light is a *bare model*: it is placed
/// in the seed room ([`place_in_room`]) and seen from the room's camera. A file with lights
/// renders as it is, from its first camera, or from a camera framing its bounding box when
/// it has none.
pub fn load_scene(path: &Path) -> Result<Scene> {
    load_scene_with(path, &LoadOptions::default())
}

/// [`load_scene`] with options.
pub fn load_scene_with(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let mut scene = if is_model_file(path) {
        let model = import_model(path, UpAxis::Y)?;
        if options.in_room || !has_lights(&model.world) {
            place_in_room(model, path)?
        } else {
            let mut model = model;
            place::ensure_camera(&mut model.world, path)?;
            model
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
        scene_file::load(path, &text)?
    };
    place::select_camera(&mut scene.world, options.camera.as_deref(), path)?;
    Ok(scene)
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
/// space, the file's `up` axis turned to +Z. No room, no camera added.
pub fn import_model(path: &Path, up: UpAxis) -> Result<Scene> {
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
