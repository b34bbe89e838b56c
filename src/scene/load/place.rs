//! Placing imported models: the bare-model rule (a model without lights goes into the seed
//! room), `[[model]]` placement, a framing camera for files without one, and the choice of
//! camera. These read and edit the authoring world; rendering never comes here.

use super::{BUILTIN_ROOM, Scene, scene_file};
use crate::error::{Error, Result};
use crate::math::{Affine3A, Vec3};
use crate::scene::{
    Camera, Emitter, Material, MaterialTextures, Mesh, Name, PunctualLight, Sphere, Transform,
};
use std::path::Path;

/// Where a bare model's bottom centre lands in the seed room: the floor point (z = -5) whose
/// 3 x 3 footprint, with the whole 3-unit box in the room camera's view, keeps the largest
/// clearance from the walls and from the tetrahedron and the two spheres (a 0.1-unit grid
/// search over the hexagon; the clearance there is 0.4 units on every side).
pub const ROOM_FREE_FLOOR_CENTRE: Vec3 = Vec3::new(10.4, -0.9, -5.0);
/// A bare model is scaled so that its largest extent is this (world units).
pub const ROOM_MODEL_SIZE: f32 = 3.0;

/// Whether the world has anything that emits light (an emitter of non-zero radiance, or a
/// punctual light).
pub fn has_lights(world: &hecs::World) -> bool {
    let emitting = world
        .query::<&Emitter>()
        .iter()
        .any(|e| e.radiance.max_element() > 0.0);
    emitting || world.query::<&PunctualLight>().iter().next().is_some()
}

/// World-space bounding box (min, max) of every mesh and sphere, or `None` if there is none.
pub fn bounding_box(world: &hecs::World) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for (mesh, transform) in world.query::<(&Mesh, Option<&Transform>)>().iter() {
        let t = transform.copied().unwrap_or_default().0;
        for tri in &mesh.indices {
            for &i in tri {
                let p = t.transform_point3(mesh.positions[i as usize]);
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
    }
    for (sphere, transform) in world.query::<(&Sphere, Option<&Transform>)>().iter() {
        let t = transform.copied().unwrap_or_default().0;
        let c = t.transform_point3(Vec3::ZERO);
        let r = sphere.radius * t.matrix3.x_axis.length();
        lo = lo.min(c - r);
        hi = hi.max(c + r);
    }
    (lo.x <= hi.x).then_some((lo, hi))
}

/// The transform that scales a box (`lo`, `hi`) so that its largest extent is `size` and
/// puts its bottom centre at `anchor`.
pub(super) fn fit_transform(lo: Vec3, hi: Vec3, size: f32, anchor: Vec3) -> Affine3A {
    let extent = (hi - lo).max_element();
    let scale = if extent > 0.0 { size / extent } else { 1.0 };
    let bottom_centre = Vec3::new((lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5, lo.z);
    Affine3A::from_translation(anchor)
        * Affine3A::from_scale(Vec3::splat(scale))
        * Affine3A::from_translation(-bottom_centre)
}

/// Moves every entity of `model` except its cameras into `world`, placed by `placement`
/// (applied after the model's own transforms). `material` replaces the model's materials
/// (and drops its textures and emission).
pub(super) fn merge_model(
    world: &mut hecs::World,
    mut model: hecs::World,
    placement: Affine3A,
    material: Option<Material>,
) {
    let cameras: Vec<hecs::Entity> = model
        .query::<(hecs::Entity, &Camera)>()
        .iter()
        .map(|(e, _)| e)
        .collect();
    for e in cameras {
        model.despawn(e).expect("entity exists");
    }
    for t in model.query_mut::<&mut Transform>() {
        t.0 = placement * t.0;
    }
    let unplaced: Vec<hecs::Entity> = model
        .query::<(hecs::Entity, &Mesh)>()
        .without::<&Transform>()
        .iter()
        .map(|(e, _)| e)
        .collect();
    for e in unplaced {
        model.insert_one(e, Transform(placement)).expect("exists");
    }
    if let Some(m) = material {
        let surfaces: Vec<hecs::Entity> = model
            .query::<(hecs::Entity, &Material)>()
            .iter()
            .map(|(e, _)| e)
            .collect();
        for e in surfaces {
            model.insert_one(e, m).expect("exists");
            let _ = model.remove_one::<MaterialTextures>(e);
            let _ = model.remove_one::<Emitter>(e);
        }
    }
    let entities: Vec<hecs::Entity> = model.iter().map(|e| e.entity()).collect();
    for e in entities {
        let taken = model.take(e).expect("entity exists");
        world.spawn(taken);
    }
}

/// The bare-model rule: the seed room with `model` standing on its floor at
/// [`ROOM_FREE_FLOOR_CENTRE`], scaled to fit a `ROOM_MODEL_SIZE` (3 units) box, seen by the room's
/// camera. The model's cameras are dropped.
pub fn place_in_room(model: Scene, path: &Path) -> Result<Scene> {
    let (lo, hi) = bounding_box(&model.world)
        .ok_or_else(|| Error::input(path, None, "the file has no geometry to place"))?;
    let mut room = scene_file::load(Path::new("builtin:room"), BUILTIN_ROOM)?;
    let placement = fit_transform(lo, hi, ROOM_MODEL_SIZE, ROOM_FREE_FLOOR_CENTRE);
    merge_model(&mut room.world, model.world, placement, None);
    room.warnings.extend(model.warnings);
    Ok(room)
}

/// Adds a camera framing the world's bounding box if the world has none: from the front
/// (-y), to the right and above, with a 40 degree vertical field of view.
pub(super) fn ensure_camera(world: &mut hecs::World, path: &Path) -> Result<()> {
    if world.query::<&Camera>().iter().next().is_some() {
        return Ok(());
    }
    let (lo, hi) = bounding_box(world)
        .ok_or_else(|| Error::input(path, None, "the file has no camera and no geometry"))?;
    // In f64: a box near the f32 range still has a centre and size, and the eye's overflow
    // (a model too large for the f32 world) is then told as such.
    let (lo64, hi64) = (lo.as_dvec3(), hi.as_dvec3());
    let centre = (lo64 + hi64) * 0.5;
    let radius = ((hi64 - lo64).length() * 0.5).max(1e-3);
    let vfov = 40f32.to_radians();
    let distance = radius / (f64::from(vfov) * 0.5).sin() * 1.05;
    let direction = glam::DVec3::new(0.5, -1.0, 0.6).normalize();
    let eye = (centre + direction * distance).as_vec3();
    let centre = centre.as_vec3();
    if !(eye.is_finite() && centre.is_finite()) {
        return Err(Error::input(
            path,
            None,
            format!(
                "the file has no camera, and its bounding box {lo} .. {hi} is too large to \
                 frame with one"
            ),
        ));
    }
    // The view direction is known exactly; `look_at` would subtract eye and centre, which
    // can overflow for such large boxes.
    let forward = -direction.as_vec3();
    let right = forward.cross(Vec3::Z).normalize();
    world.spawn((
        Name("framing camera".into()),
        Camera {
            eye,
            forward,
            up: right.cross(forward),
            vfov,
            aspect_ratio: None,
        },
    ));
    Ok(())
}

/// Keeps one camera: the one named `name`, or else the first (the earliest spawned, which
/// for imported files is the first in the file). Naming a camera that does not exist is an
/// error that lists the cameras there are.
pub(super) fn select_camera(
    world: &mut hecs::World,
    name: Option<&str>,
    path: &Path,
) -> Result<()> {
    let mut cameras: Vec<(hecs::Entity, Option<String>)> = world
        .query::<(hecs::Entity, &Camera, Option<&Name>)>()
        .iter()
        .map(|(e, _, n)| (e, n.map(|n| n.0.clone())))
        .collect();
    cameras.sort_by_key(|(e, _)| e.id());
    let keep = match name {
        None => match cameras.first() {
            Some((e, _)) => *e,
            None => return Ok(()), // flatten reports the missing camera
        },
        Some(wanted) => cameras
            .iter()
            .find(|(_, n)| n.as_deref() == Some(wanted))
            .map(|(e, _)| *e)
            .ok_or_else(|| {
                let known: Vec<&str> = cameras.iter().filter_map(|(_, n)| n.as_deref()).collect();
                Error::input(
                    path,
                    None,
                    format!(
                        "no camera named '{wanted}' (cameras: {})",
                        if known.is_empty() {
                            "none".to_string()
                        } else {
                            known.join(", ")
                        }
                    ),
                )
            })?,
    };
    for (e, _) in cameras {
        if e != keep {
            world.despawn(e).expect("entity exists");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_puts_the_bottom_centre_on_the_anchor_at_the_asked_size() {
        let t = fit_transform(
            Vec3::new(-1.0, 0.0, 2.0),
            Vec3::new(1.0, 6.0, 3.0),
            3.0,
            Vec3::new(5.0, 5.0, -5.0),
        );
        assert!(
            (t.transform_point3(Vec3::new(0.0, 3.0, 2.0)) - Vec3::new(5.0, 5.0, -5.0)).length()
                < 1e-6
        );
        assert!((t.transform_vector3(Vec3::new(0.0, 6.0, 0.0)).y - 3.0).abs() < 1e-6);
    }
}
