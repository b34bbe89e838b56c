//! Absorbing media (`KHR_materials_volume`): the medium inside a material and Beer-Lambert
//! transmittance along a segment. Shared by shading, next-event estimation, the connections
//! to light vertices and the light paths; the path's current medium itself lives in
//! [`super::batch::PathState`].

use crate::math::Rgb;
use crate::render_scene::RenderScene;

/// The absorption coefficient of the medium inside `material` (zero if it has none).
#[inline]
pub(super) fn material_absorption(scene: &RenderScene, material: usize) -> Rgb {
    scene
        .material_absorption
        .get(material)
        .copied()
        .unwrap_or(Rgb::ZERO)
}

/// The fraction of light left after `distance` in a medium of absorption `sigma_a`.
#[inline]
pub(super) fn transmittance(sigma_a: Rgb, distance: f32) -> Rgb {
    // A channel that absorbs nothing keeps everything, even to a directional light's
    // infinite distance (0 x infinity would be NaN).
    let channel = |s: f32| if s > 0.0 { (-s * distance).exp() } else { 1.0 };
    Rgb::new(channel(sigma_a.x), channel(sigma_a.y), channel(sigma_a.z))
}
