//! Model files (glTF, OBJ) imported as they are: the importer chosen by the extension, and
//! the file's light intensities read in the units asked for ([`LightUnits`]). No room, no
//! camera added: placing a model is `place.rs`'s, loading a scene `mod.rs`'s.

use super::shared::{Scene, UpAxis};
use super::{gltf, obj};
use crate::error::{Error, Result};
use crate::scene::PunctualLight;
use std::path::Path;

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
