//! The camera of the render: the world's first (the earliest spawned), checked once.

use crate::error::{Error, Result};
use crate::scene::{Camera, Projection};
use std::path::Path;

/// The world's first camera, refused if its placement is not finite or its field of view
/// (perspective) or film height (orthographic) is out of range.
pub(super) fn first_camera(world: &hecs::World, path: &Path) -> Result<Camera> {
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
    if let Projection::Orthographic { half_height } = camera.projection {
        if !(half_height > 0.0 && half_height.is_finite()) {
            return Err(Error::input(
                path,
                Some("camera".into()),
                format!(
                    "the orthographic film's half height must be positive and finite, got {half_height}"
                ),
            ));
        }
    } else if !(camera.vfov > 0.0 && camera.vfov < std::f32::consts::PI) {
        return Err(Error::input(
            path,
            Some("camera".into()),
            format!(
                "the field of view must lie in (0, 180) degrees, got {}",
                camera.vfov.to_degrees()
            ),
        ));
    }
    Ok(camera)
}
