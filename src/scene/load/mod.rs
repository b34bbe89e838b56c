//! Loaders: a file becomes a [`Scene`] (an ECS world plus the render settings the file asks
//! for). The file's extension picks the loader; every error names the file.

mod scene_file;

use crate::error::{Error, Result};
use std::path::Path;

/// A loaded scene: the entities, and the render settings the file asks for (the CLI's flags
/// override them).
pub struct Scene {
    /// Entities of the scene (see [`crate::scene`]).
    pub world: hecs::World,
    /// Settings stated in the scene file.
    pub defaults: SceneDefaults,
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

/// Loads a scene file; the loader is chosen by the extension (`.toml`).
pub fn load_scene(path: &Path) -> Result<Scene> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("toml") => {
            let text = read_text(path)?;
            scene_file::load(path, &text)
        }
        _ => Err(Error::input(
            path,
            None,
            "unknown scene file extension (expected .toml)",
        )),
    }
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
