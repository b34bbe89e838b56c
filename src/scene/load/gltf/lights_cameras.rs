//! A glTF node's camera and `KHR_lights_punctual` light as entities: a perspective or
//! orthographic camera becomes a [`Camera`] in world space (an orthographic one without a
//! usable magnification is skipped with a warning), a
//! light a [`PunctualLight`] at the node, in the file's own numbers (`LightUnits` scales them
//! afterwards, in `scene/load/model.rs`).

use super::check::{check_perspective, node_location};
use crate::error::{Error, Result};
use crate::math::{Affine3A, Rgb, Vec3};
use crate::scene::{Camera, Name, Projection, PunctualLight, SpotFalloff, Transform};
use gltf::khr_lights_punctual::Kind as LightKind;
use std::path::Path;

/// Spawns the node's camera, if it has one that can be rendered from, and returns its entity.
pub(super) fn spawn_camera(
    world: &mut hecs::World,
    node: &gltf::Node,
    name: &str,
    world_from_node: Affine3A,
    path: &Path,
    warnings: &mut Vec<String>,
) -> Result<Option<hecs::Entity>> {
    let Some(camera) = node.camera() else {
        return Ok(None);
    };
    match camera.projection() {
        gltf::camera::Projection::Perspective(p) => {
            check_perspective(&p)
                .map_err(|message| Error::input(path, Some(node_location(node)), message))?;
            Ok(Some(world.spawn((
                Name(name.to_string()),
                camera_of(&world_from_node, &p),
            ))))
        }
        gltf::camera::Projection::Orthographic(o) => {
            let Some(lens) = orthographic_lens(o.xmag(), o.ymag(), path, name, warnings) else {
                return Ok(None);
            };
            let camera = camera_at(&world_from_node, &lens);
            Ok(Some(world.spawn((Name(name.to_string()), camera))))
        }
    }
}

/// The lens of a glTF orthographic camera from its half width `xmag` and half height
/// `ymag`: the film `2 |ymag|` tall, the aspect ratio `|xmag / ymag|`. The specification
/// forbids zero and advises against negative values: a negative one is taken by its size, a
/// zero or non-finite one replaced by the other (a square film), each with a warning naming
/// the file and camera; with neither usable, `None` (the camera is skipped with a warning).
fn orthographic_lens(
    xmag: f32,
    ymag: f32,
    path: &Path,
    name: &str,
    warnings: &mut Vec<String>,
) -> Option<Camera> {
    let usable = |m: f32| (m.is_finite() && m != 0.0).then_some(m.abs());
    let mut warn = |what: &str| {
        warnings.push(format!(
            "{}: orthographic camera '{name}' (xmag {xmag}, ymag {ymag}): {what}",
            path.display()
        ))
    };
    let (x, y) = match (usable(xmag), usable(ymag)) {
        (None, None) => {
            warn("no usable magnification; skipped");
            return None;
        }
        (Some(x), None) => {
            warn("ymag is zero or not finite; xmag used for both (a square film)");
            (x, x)
        }
        (None, Some(y)) => {
            warn("xmag is zero or not finite; ymag used for both (a square film)");
            (y, y)
        }
        (Some(x), Some(y)) => (x, y),
    };
    if xmag < 0.0 || ymag < 0.0 {
        warn("a negative magnification is taken by its size");
    }
    Some(Camera {
        eye: Vec3::ZERO,
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        vfov: 0.0,
        aspect_ratio: Some(x / y),
        projection: Projection::Orthographic { half_height: y },
    })
}

/// A glTF camera (looking down its node's -Z with +Y up) in world space.
fn camera_of(world_from_node: &Affine3A, p: &gltf::camera::Perspective) -> Camera {
    let lens = Camera {
        eye: Vec3::ZERO,
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        vfov: p.yfov(),
        aspect_ratio: p.aspect_ratio(),
        projection: Projection::Perspective,
    };
    camera_at(world_from_node, &lens)
}

/// A glTF camera (looking down its node's -Z with +Y up) at `world_from_node`, with the lens
/// (field of view, aspect ratio) of `lens`; an animation's pose places its cameras with it.
pub(crate) fn camera_at(world_from_node: &Affine3A, lens: &Camera) -> Camera {
    let eye = world_from_node.transform_point3(Vec3::ZERO);
    let forward = world_from_node
        .transform_vector3(Vec3::NEG_Z)
        .normalize_or(Vec3::NEG_Z);
    let up_hint = world_from_node.transform_vector3(Vec3::Y);
    let right = forward.cross(up_hint).normalize_or(Vec3::X);
    Camera {
        eye,
        forward,
        up: right.cross(forward),
        ..*lens
    }
}

/// Spawns the node's light, if it has one, and returns its entity; its colour times intensity
/// must be finite and non-negative.
pub(super) fn spawn_light(
    world: &mut hecs::World,
    node: &gltf::Node,
    name: &str,
    world_from_node: Affine3A,
    path: &Path,
    document: &gltf::Document,
) -> Result<Option<hecs::Entity>> {
    let Some(light) = node.light() else {
        return Ok(None);
    };
    let colour = Rgb::from(light.color()) * light.intensity();
    let punctual = match light.kind() {
        LightKind::Point => PunctualLight::Point { intensity: colour },
        LightKind::Directional => PunctualLight::Directional { irradiance: colour },
        LightKind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => PunctualLight::Spot {
            intensity: colour,
            inner_cone: inner_cone_angle,
            outer_cone: outer_cone_angle,
            falloff: spot_falloff(document, inner_cone_angle, outer_cone_angle),
        },
    };
    if !colour.is_finite() || colour.min_element() < 0.0 {
        return Err(Error::input(
            path,
            Some(node_location(node)),
            "light colour and intensity must be finite and non-negative",
        ));
    }
    Ok(Some(world.spawn((
        Name(name.to_string()),
        Transform(world_from_node),
        punctual,
    ))))
}

/// Whether Blender's glTF exporter wrote the file (`asset.generator`).
fn written_by_blender(document: &gltf::Document) -> bool {
    let generator = document.as_json().asset.generator.as_deref();
    generator.is_some_and(|g| g.starts_with("Khronos glTF Blender I/O"))
}

/// The anisotropy mapping of a file's materials: Cycles' for files Blender wrote (which
/// Blender's importer renders with its Principled BSDF), else the glTF specification's.
pub(super) fn anisotropy_mapping(document: &gltf::Document) -> crate::bsdf::AnisotropyMapping {
    if written_by_blender(document) {
        crate::bsdf::AnisotropyMapping::Cycles
    } else {
        crate::bsdf::AnisotropyMapping::Gltf
    }
}

/// How a spot's intensity falls between its cones: glTF's falloff, or, in a file Blender's
/// exporter wrote (`asset.generator` "Khronos glTF Blender I/O ..."), the Spot Blend that
/// Blender's importer recovers, `1 - inner / outer` (the exporter writes
/// `inner = outer (1 - blend)`), rendered with Cycles' smoothstep.
fn spot_falloff(document: &gltf::Document, inner: f32, outer: f32) -> SpotFalloff {
    let generator = document.as_json().asset.generator.as_deref();
    if !generator.is_some_and(|g| g.starts_with("Khronos glTF Blender I/O")) || outer <= 0.0 {
        return SpotFalloff::Gltf;
    }
    SpotFalloff::Blender {
        blend: (1.0 - inner / outer).clamp(0.0, 1.0),
    }
}
