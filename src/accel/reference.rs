//! The plain reference path: every primitive tested one by one with its shape's own test, in
//! slot order, no tree and no layout. Slow, and obviously right; every fast path (the tree's
//! walks, the leaf layouts, packets, the occluders' tree) is tested against it.

use crate::geometry::Shape;
use crate::math::Vec3A;

/// The closest of `shapes` (in slot order) hit along `origin + t direction` within
/// `[0, t_max]`: its slot and distance; the earlier slot on a tie.
pub fn closest_hit(
    shapes: impl IntoIterator<Item = Shape>,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> Option<(u32, f32)> {
    (0u32..)
        .zip(shapes)
        .map(|(slot, shape)| (slot, shape.intersect_t(origin, direction, t_max)))
        .filter(|hit| hit.1 < f32::INFINITY)
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Whether any of `shapes` is hit along `origin + t direction` within `[0, t_max]`.
pub fn any_hit(
    shapes: impl IntoIterator<Item = Shape>,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> bool {
    shapes
        .into_iter()
        .any(|shape| shape.intersect_t(origin, direction, t_max) < f32::INFINITY)
}

/// [`closest_hit`] over a scene with instanced meshes: the flat part's `shapes` (slots from
/// 0), then every instance's prototype triangles one by one, tested on the ray carried into
/// the instance's object space (unnormalised, so distances are world distances: the
/// two-level structure's definition of a hit), with virtual slots as in [`Instances`].
pub fn closest_hit_instanced(
    shapes: impl IntoIterator<Item = Shape>,
    instances: &crate::accel::instances::Instances,
    origin: Vec3A,
    direction: Vec3A,
    t_max: f32,
) -> Option<(u32, f32)> {
    let mut best = closest_hit(shapes, origin, direction, t_max);
    for (i, instance) in instances.instances.iter().enumerate() {
        let prototype = &instances.prototypes[instance.prototype as usize];
        let o = instance.object_from_world.transform_point3a(origin);
        let d = instance.object_from_world.matrix3 * direction;
        for (s, prim) in prototype.leaf_prims.iter().enumerate() {
            let t = prim.shape().intersect_t(o, d, t_max);
            let slot = instances.first_slot[i] + s as u32;
            if t < f32::INFINITY && best.is_none_or(|(b, bt)| t < bt || (t == bt && slot < b)) {
                best = Some((slot, t));
            }
        }
    }
    best
}
