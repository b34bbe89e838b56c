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
