//! What every loader shares and none owns: the loaded [`Scene`], the up axis of an imported
//! file ([`UpAxis`]) and the check of an imported mesh's indices and positions. This module
//! imports no loader: the TOML scene format, the model importers and the placing of models
//! all build on it, so that the dependencies inside `scene/load/` run one way.

use crate::error::{Error, Result};
use crate::math::{Affine3A, Mat3A, Vec3A};
use crate::scene::Mesh;
use crate::settings::SceneDefaults;
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
