//! Placing imported models: the bare-model rule (a model that does not light itself goes
//! into the hexagonal room, as its subject, on the room's stage), `[[model]]` placement (a file
//! placed several times is loaded once: its meshes shared, its world copied), a
//! framing camera for files without one, the choice of camera, and the dark-image check of
//! files rendered as they are. These read and edit the authoring world (and, for the check,
//! the finished image); rendering never comes here.

use super::shared::Scene;
use crate::error::{Error, Result};
use crate::film::Image;
use crate::math::{Affine3A, Vec3, luminance};
use crate::scene::animation::Animated;
use crate::scene::{
    AlphaCoverage, Camera, Emitter, EnvironmentLight, Iridescence, Material, MaterialTextures,
    Mesh, Name, PunctualLight, SharedMesh, Sphere, Transform, VertexColors, VertexTangents, Volume,
    mesh_of,
};
use std::path::Path;
use std::sync::Arc;

/// The room camera's eye; it looks along +x with a 90 degree (square) view, so a point
/// (x, y, z) is in view when |y| and |z| are at most x + 1. `scene_file.rs`'s tests check these against
/// the room file.
pub const ROOM_EYE: Vec3 = Vec3::new(-1.0, 0.0, 0.0);
/// The room's floor height.
pub const ROOM_FLOOR: f32 = -5.0;
/// A placed model's top stays at or below this height, 3 units under the ceiling light, so
/// that the light reaches its top and front.
pub const ROOM_STAGE_TOP: f32 = 2.0;
/// The placed model keeps inside this fraction of the room camera's half view (a margin of
/// 3% of the image on each side).
pub const ROOM_VIEW_FILL: f32 = 0.94;
/// The placed model keeps this far from the room's walls.
pub const ROOM_WALL_CLEARANCE: f32 = 0.3;
/// The room's props: a placed model's bounding box that overlaps one's takes it out of the
/// room (the model would stand inside it; the model hides it from the camera anyway).
pub const ROOM_PROPS: [&str; 3] = ["tetrahedron", "glass sphere", "mirror sphere"];
/// The nearest a placed model's front can be: where the room camera first sees the floor,
/// with the view margin (x = 5 / 0.94 - 1).
pub const ROOM_STAGE_FRONT: f32 = -ROOM_FLOOR / ROOM_VIEW_FILL + ROOM_EYE.x;
/// A model whose depth (front to back) is more than this times its width is turned a
/// quarter turn so that its long side faces the camera (a row of objects, a panel seen
/// edge-on).
pub const FLAT_TURN_RATIO: f32 = 2.0;

/// Whether an imported model lights itself: it has punctual lights, or it has surfaces that
/// show light (emitters, `KHR_materials_unlit` surfaces) and a camera (a scene set up for
/// rendering), or every surface is unlit (nothing in it needs light: it looks as it does in
/// any glTF viewer). Surfaces that show light without a camera do not count: a model whose
/// only light is its own glow (emissive decals, a lamp's bulb) or a few unlit labels would
/// render black but for them.
pub fn lights_itself(world: &hecs::World) -> bool {
    let punctual = world.query::<&PunctualLight>().iter().next().is_some();
    let has_camera = world.query::<&Camera>().iter().next().is_some();
    punctual || (has_camera && has_lights(world)) || all_unlit(world)
}

/// Whether the world has anything that shows light: an emitter of non-zero radiance, a
/// punctual light, or an unlit surface of non-black colour (it is no light source that
/// shadow rays aim at, but camera and bounce rays see its colour, so it lights its
/// neighbours as a glowing surface would).
pub fn has_lights(world: &hecs::World) -> bool {
    let emitting = world
        .query::<&Emitter>()
        .iter()
        .any(|e| e.radiance.max_element() > 0.0);
    let unlit = world
        .query::<&Material>()
        .iter()
        .any(|m| matches!(m, Material::Unlit { color } if color.max_element() > 0.0));
    emitting || unlit || world.query::<&PunctualLight>().iter().next().is_some()
}

/// Whether the world has surfaces and every one of them is unlit.
fn all_unlit(world: &hecs::World) -> bool {
    let mut query = world.query::<(
        &Material,
        Option<&Mesh>,
        Option<&SharedMesh>,
        Option<&Sphere>,
    )>();
    let mut surfaces = query
        .iter()
        .filter(|(_, mesh, shared, sphere)| mesh.is_some() || shared.is_some() || sphere.is_some())
        .map(|(material, ..)| matches!(material, Material::Unlit { .. }))
        .peekable();
    surfaces.peek().is_some() && surfaces.all(|unlit| unlit)
}

/// Above this many vertices in all, a shared mesh contributes the eight corners of its box
/// rather than its vertices to [`world_points`]: 1,000 nodes sharing a 100,000-triangle mesh
/// would otherwise make 50M points (600 MB, copied twice by the fit). The box's corners
/// enclose the mesh, so the placement stays in view; it is only less tight.
const EXACT_POINTS: usize = 4_000_000;

/// Every world-space point of the meshes (their vertices, or for shared meshes in large
/// scenes their boxes' corners, see [`EXACT_POINTS`]) and spheres (their boxes' corners).
fn world_points(world: &hecs::World) -> Vec<Vec3> {
    let mut points = Vec::new();
    let total: usize = world
        .query::<&Mesh>()
        .iter()
        .map(|m| m.positions.len())
        .sum::<usize>()
        + world
            .query::<&SharedMesh>()
            .iter()
            .map(|m| m.0.positions.len())
            .sum::<usize>();
    let boxes_for_shared = total > EXACT_POINTS;
    let mut mesh_boxes = std::collections::HashMap::<*const Mesh, Vec<Vec3>>::new();
    let mut meshes = world.query::<(Option<&Mesh>, Option<&SharedMesh>, Option<&Transform>)>();
    for (mesh, shared, transform) in meshes.iter() {
        let Some(m) = mesh_of(mesh, shared) else {
            continue;
        };
        let t = transform.copied().unwrap_or_default().0;
        if let Some(shared) = shared.filter(|_| boxes_for_shared) {
            let corners = mesh_boxes
                .entry(std::sync::Arc::as_ptr(&shared.0))
                .or_insert_with(|| {
                    let used = used_vertices(m);
                    box_of(&used).map_or_else(Vec::new, |(lo, hi)| {
                        (0..8)
                            .map(|c| {
                                let pick =
                                    |bit: u32, a: f32, b: f32| if c & bit == 0 { a } else { b };
                                Vec3::new(
                                    pick(1, lo.x, hi.x),
                                    pick(2, lo.y, hi.y),
                                    pick(4, lo.z, hi.z),
                                )
                            })
                            .collect()
                    })
                });
            points.extend(corners.iter().map(|p| t.transform_point3(*p)));
            continue;
        }
        points.extend(used_vertices(m).into_iter().map(|p| t.transform_point3(p)));
    }
    for (sphere, transform) in world.query::<(&Sphere, Option<&Transform>)>().iter() {
        let t = transform.copied().unwrap_or_default().0;
        let c = t.transform_point3(Vec3::ZERO);
        let r = sphere.radius * t.matrix3.x_axis.length();
        for corner in 0..8 {
            let sign = |bit: u32| if corner & bit == 0 { -1.0 } else { 1.0 };
            points.push(c + r * Vec3::new(sign(1), sign(2), sign(4)));
        }
    }
    points
}

/// The vertices of `mesh` that triangles use (an unused vertex is not seen), object space.
fn used_vertices(mesh: &Mesh) -> Vec<Vec3> {
    let mut used = vec![false; mesh.positions.len()];
    for tri in &mesh.indices {
        for &i in tri {
            used[i as usize] = true;
        }
    }
    mesh.positions
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(p, _)| *p)
        .collect()
}

/// World-space bounding box (min, max) of every mesh and sphere, or `None` if there is none.
pub fn bounding_box(world: &hecs::World) -> Option<(Vec3, Vec3)> {
    box_of(&world_points(world))
}

fn box_of(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let lo = points.iter().fold(Vec3::INFINITY, |a, p| a.min(*p));
    let hi = points.iter().fold(Vec3::NEG_INFINITY, |a, p| a.max(*p));
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

/// The room's stage: where a model given in world space (+Z up, its front facing -Y, as
/// glTF's +Z front comes out of the axis conversion) stands in the hexagonal room as its subject.
///
/// 1. It is turned about the vertical so that its front faces the room camera (-Y to -X),
///    unless it is more than [`FLAT_TURN_RATIO`] times deeper than wide: then it keeps its
///    orientation, its long side (its right, glTF -X) facing the camera.
/// 2. It stands on the floor, centred across the view, and is scaled as large as it can be
///    while every vertex stays in the room camera's view (within [`ROOM_VIEW_FILL`]), inside
///    the room's walls (with [`ROOM_WALL_CLEARANCE`]) and below [`ROOM_STAGE_TOP`]; at that
///    scale it comes as near the camera as the view allows.
///
/// Returns `None` for a world without geometry.
pub fn room_stage_transform(world: &hecs::World) -> Option<Affine3A> {
    let points = world_points(world);
    let (lo, hi) = box_of(&points)?;
    // A quarter turn about z, -Y to -X, exact (no rounding, which would give a degenerate
    // triangle an area).
    let front_to_camera = Affine3A::from_mat3(glam::Mat3::from_cols(Vec3::NEG_Y, Vec3::X, Vec3::Z));
    let (depth, width) = ((hi - lo).y, (hi - lo).x);
    let turn = if depth > FLAT_TURN_RATIO * width {
        Affine3A::IDENTITY
    } else {
        front_to_camera
    };
    let oriented: Vec<Vec3> = points.iter().map(|p| turn.transform_point3(*p)).collect();
    let (lo, hi) = box_of(&oriented)?;
    let centre_y = (lo.y + hi.y) * 0.5;
    // Offsets of every point from the box's front-bottom-centre, at unit scale.
    let offsets: Vec<Vec3> = oriented
        .iter()
        .map(|p| Vec3::new(p.x - lo.x, p.y - centre_y, p.z - lo.z))
        .collect();
    let k = ROOM_VIEW_FILL;
    // For scale s, the front x must be at least `nearest(s)` (every point in view) and at
    // most `farthest(s)` (every point inside the walls: |y| <= 6, x <= 13 - |y| / 2).
    let nearest = |s: f32| {
        offsets.iter().fold(f32::NEG_INFINITY, |a, o| {
            let (y, z) = (s * o.y, ROOM_FLOOR + s * o.z);
            a.max(y.abs().max(z.abs()) / k + ROOM_EYE.x - s * o.x)
        })
    };
    let farthest = |s: f32| {
        offsets.iter().fold(f32::INFINITY, |a, o| {
            a.min(13.0 - ROOM_WALL_CLEARANCE - 0.5 * (s * o.y).abs() - s * o.x)
        })
    };
    let size = hi - lo;
    let half_room = 6.0 - ROOM_WALL_CLEARANCE;
    let mut top: f32 = 1e6;
    if size.z > 0.0 {
        top = top.min((ROOM_STAGE_TOP - ROOM_FLOOR) / size.z);
    }
    if size.y > 0.0 {
        top = top.min(2.0 * half_room / size.y);
    }
    if size.x > 0.0 {
        top = top.min(13.0 / size.x);
    }
    if top >= 1e6 {
        top = 1.0; // a single point: any scale
    }
    let fits = |s: f32| nearest(s) <= farthest(s);
    let scale = if fits(top) {
        top
    } else {
        // Bisection: `nearest` grows with s and `farthest` shrinks, so the fitting scales
        // are an interval from 0.
        let (mut ok, mut bad) = (0.0f32, top);
        for _ in 0..40 {
            let mid = 0.5 * (ok + bad);
            if fits(mid) { ok = mid } else { bad = mid }
        }
        ok
    };
    let front = nearest(scale);
    Some(
        Affine3A::from_translation(Vec3::new(front, 0.0, ROOM_FLOOR))
            * Affine3A::from_scale(Vec3::splat(scale))
            * Affine3A::from_translation(-Vec3::new(lo.x, centre_y, lo.z))
            * turn,
    )
}

/// Removes the room props ([`ROOM_PROPS`], by name) whose bounding boxes overlap the box
/// (`lo`, `hi`).
pub(super) fn clear_props(world: &mut hecs::World, lo: Vec3, hi: Vec3) {
    let props: Vec<hecs::Entity> = world
        .query::<(hecs::Entity, &Name)>()
        .iter()
        .filter(|(_, n)| ROOM_PROPS.contains(&n.0.as_str()))
        .map(|(e, _)| e)
        .collect();
    for e in props {
        let mut single = hecs::World::new();
        let entity = world.entity(e).expect("exists");
        if let (Some(mesh), t) = (entity.get::<&Mesh>(), entity.get::<&Transform>()) {
            single.spawn(((*mesh).clone(), t.map(|t| *t).unwrap_or_default()));
        }
        if let (Some(sphere), t) = (entity.get::<&Sphere>(), entity.get::<&Transform>()) {
            single.spawn((*sphere, t.map(|t| *t).unwrap_or_default()));
        }
        if let Some((plo, phi)) = bounding_box(&single)
            && plo.cmple(hi).all()
            && phi.cmpge(lo).all()
        {
            world.despawn(e).expect("exists");
        }
    }
}

/// Turns every [`Mesh`] of `model` into a [`SharedMesh`], so that copies of the model
/// ([`copy_model`]) store each mesh once.
pub(super) fn share_meshes(model: &mut hecs::World) {
    let plain: Vec<hecs::Entity> = model
        .query::<(hecs::Entity, &Mesh)>()
        .iter()
        .map(|(e, _)| e)
        .collect();
    for e in plain {
        let mesh = model.remove_one::<Mesh>(e).expect("queried");
        model
            .insert_one(e, SharedMesh(Arc::new(mesh)))
            .expect("exists");
    }
}

/// A copy of every entity of `model`, component by component ([`SharedMesh`] data is
/// shared, not copied).
///
/// A new component type must be added to the list here, or a model placed twice would lose
/// it: debug builds (the tests) assert that every component was copied.
pub(super) fn copy_model(model: &hecs::World) -> hecs::World {
    let mut copy = hecs::World::new();
    for entity in model.iter() {
        let mut builder = hecs::EntityBuilder::new();
        let mut copied = 0usize;
        macro_rules! copy_components {
            ($($component:ty),* $(,)?) => {$(
                if let Some(c) = entity.get::<&$component>() {
                    builder.add((*c).clone());
                    copied += 1;
                }
            )*};
        }
        copy_components!(
            Name,
            Transform,
            Mesh,
            SharedMesh,
            Sphere,
            Material,
            Emitter,
            MaterialTextures,
            VertexTangents,
            VertexColors,
            Volume,
            Iridescence,
            AlphaCoverage,
            PunctualLight,
            Camera,
            EnvironmentLight,
            Animated,
        );
        debug_assert_eq!(
            copied,
            entity.component_types().count(),
            "copy_model does not know a component type of the model's entities"
        );
        copy.spawn(builder.build());
    }
    copy
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
    // Posing recomputes the transforms: it must know the placement too.
    for animated in model.query_mut::<&mut Animated>() {
        animated.place(placement);
    }
    let unplaced: Vec<hecs::Entity> = model
        .query::<(hecs::Entity, hecs::Or<&Mesh, &SharedMesh>)>()
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

/// Places `model` on the room's stage ([`room_stage_transform`]) in `world` (the room), taking
/// out the props its box overlaps. The model's cameras are dropped.
pub(super) fn stage_model(
    world: &mut hecs::World,
    model: hecs::World,
    material: Option<Material>,
    path: &Path,
) -> Result<()> {
    let placement = room_stage_transform(&model)
        .ok_or_else(|| Error::input(path, None, "the file has no geometry to place"))?;
    let (lo, hi) = bounding_box(&model).expect("has geometry");
    let corners = (0..8).map(|c| {
        let pick = |bit: u32, a: f32, b: f32| if c & bit == 0 { a } else { b };
        placement.transform_point3(Vec3::new(
            pick(1, lo.x, hi.x),
            pick(2, lo.y, hi.y),
            pick(4, lo.z, hi.z),
        ))
    });
    let placed: Vec<Vec3> = corners.collect();
    let (plo, phi) = box_of(&placed).expect("eight corners");
    clear_props(world, plo, phi);
    merge_model(world, model, placement, material);
    Ok(())
}

/// The bare-model rule: the room that `room` builds with `model` as its subject, on the
/// room's stage ([`room_stage_transform`]), seen by the room's camera. The model's cameras are
/// dropped. The room is taken as a builder, not loaded here, so that placing depends on no
/// scene format (the hexagonal room is a TOML scene, and the TOML format places models).
pub(super) fn place_in_room(
    model: Scene,
    room: impl FnOnce() -> Result<Scene>,
    path: &Path,
) -> Result<Scene> {
    if bounding_box(&model.world).is_none() {
        return Err(Error::input(
            path,
            None,
            "the file has no geometry to place",
        ));
    }
    let mut room = room()?;
    stage_model(&mut room.world, model.world, None, path)?;
    room.warnings.extend(model.warnings);
    Ok(room)
}

/// What to do about a dark image of a model rendered as it is: said by
/// [`dark_image_warning`].
pub const DARK_IMAGE_HINT: &str = "render it with --in-room to light it with the seed room, \
     or under a sky with --env assets/sky.hdr (or --env 1,1,1 for a uniform white sky)";

/// A pixel is lit when its luminance (after the exposure) reaches this: about a 15% grey
/// once sRGB-encoded.
const LIT_PIXEL: f32 = 0.02;
/// An image with fewer lit pixels than this fraction is dark.
const LIT_FRACTION: f64 = 0.10;

/// A warning if a model file rendered as it is came out dark: fewer than 10% of the pixels
/// reach a 15% grey (sRGB) at the given exposure (stops).
pub fn dark_image_warning(image: &Image, exposure: f32) -> Option<String> {
    let gain = exposure.exp2();
    let lit = image
        .pixels
        .iter()
        .filter(|p| luminance(**p) * gain >= LIT_PIXEL)
        .count();
    let fraction = lit as f64 / image.pixels.len().max(1) as f64;
    (fraction < LIT_FRACTION).then(|| {
        format!(
            "the image is dark: the file's own lights light only {:.1}% of it; {DARK_IMAGE_HINT}",
            fraction * 100.0
        )
    })
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
            projection: crate::scene::Projection::Perspective,
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
    use crate::math::{Rgb, Vec4};

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

    #[test]
    fn copies_share_the_meshes_and_keep_every_component() {
        let mut model = unit_cube_world(Vec3::ONE);
        let cube = model
            .query::<(hecs::Entity, &Mesh)>()
            .iter()
            .next()
            .unwrap()
            .0;
        model
            .insert(
                cube,
                (
                    Name("cube".into()),
                    Transform::default(),
                    VertexColors(vec![Vec4::ONE; 8]),
                    MaterialTextures::default(),
                ),
            )
            .unwrap();
        model.spawn((
            Name("lamp".into()),
            PunctualLight::Point {
                intensity: Rgb::ONE,
            },
        ));
        share_meshes(&mut model);
        assert_eq!(model.query::<&Mesh>().iter().count(), 0);
        let copy = copy_model(&model);
        assert_eq!(copy.len(), model.len());
        let kinds = |w: &hecs::World| -> Vec<usize> {
            w.iter().map(|e| e.component_types().count()).collect()
        };
        assert_eq!(kinds(&copy), kinds(&model));
        let shared = |w: &hecs::World| w.query::<&SharedMesh>().iter().next().unwrap().0.clone();
        assert!(Arc::ptr_eq(&shared(&copy), &shared(&model)));
    }

    fn unit_cube_world(size: Vec3) -> hecs::World {
        let mut world = hecs::World::new();
        let corners: Vec<Vec3> = (0..8)
            .map(|c| {
                size * Vec3::new(
                    (c & 1) as f32 - 0.5,
                    ((c >> 1) & 1) as f32 - 0.5,
                    ((c >> 2) & 1) as f32 - 0.5,
                )
            })
            .collect();
        world.spawn((Mesh {
            positions: corners,
            normals: vec![],
            uvs: vec![],
            indices: vec![[0, 1, 2], [3, 4, 5], [5, 6, 7]],
        },));
        world
    }

    #[test]
    fn the_stage_keeps_a_box_in_view_on_the_floor_and_turns_its_front_to_the_camera() {
        for size in [
            Vec3::ONE,
            Vec3::new(10.0, 1.0, 1.0), // wide
            Vec3::new(1.0, 10.0, 1.0), // deep: turned
            Vec3::new(0.1, 0.1, 5.0),  // a pole
        ] {
            let world = unit_cube_world(size);
            let t = room_stage_transform(&world).unwrap();
            let placed: Vec<Vec3> = world_points(&world)
                .iter()
                .map(|p| t.transform_point3(*p))
                .collect();
            let (lo, hi) = box_of(&placed).unwrap();
            assert!((lo.z - ROOM_FLOOR).abs() < 1e-4, "{size}: on the floor");
            assert!(hi.z <= ROOM_STAGE_TOP + 1e-4, "{size}");
            for p in &placed {
                let d = p.x - ROOM_EYE.x;
                assert!(
                    p.y.abs().max(p.z.abs()) <= ROOM_VIEW_FILL * d * (1.0 + 1e-5),
                    "{p}"
                );
                assert!(p.x <= 13.0 - 0.5 * p.y.abs() && p.y.abs() < 6.0, "{p}");
            }
            // The front (-y in the model) faces the camera (-x), unless the model was turned.
            let front = t.transform_vector3(-Vec3::Y).normalize();
            if size.y > FLAT_TURN_RATIO * size.x {
                assert!((front - -Vec3::Y).length() < 1e-5, "{size}: {front}");
                let width = (hi - lo).y;
                assert!(
                    width > 4.0 * (hi - lo).x,
                    "{size}: the long side faces the camera"
                );
            } else {
                assert!((front - -Vec3::X).length() < 1e-5, "{size}: {front}");
            }
            // Largest: one of the limits is reached (view, walls, or the top).
            let touches_view = placed.iter().any(|p| {
                let d = p.x - ROOM_EYE.x;
                p.y.abs().max(p.z.abs()) >= ROOM_VIEW_FILL * d * (1.0 - 1e-3)
            });
            assert!(touches_view, "{size}: as near as the view allows");
        }
    }
}
