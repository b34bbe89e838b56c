//! Stage 2, intersect: the closest hit of every ray of the batch.

use super::batch::{HitBatch, NO_HIT, RayBatch};
use crate::math::Vec2;
use crate::render_scene::{RenderScene, TraversalStack};

/// Finds the closest hit of each ray; misses get [`NO_HIT`].
pub fn intersect_closest(scene: &RenderScene, rays: &RayBatch, hits: &mut HitBatch) {
    let n = rays.len();
    hits.t.resize(n, 0.0);
    hits.slot.resize(n, NO_HIT);
    hits.barycentric.resize(n, Vec2::ZERO);
    let mut stack = TraversalStack::default();
    for i in 0..n {
        let (origin, direction) = (rays.origin[i], rays.direction[i]);
        let (slot, t) = scene
            .closest_hit(&mut stack, origin, direction, f32::INFINITY)
            .unwrap_or((NO_HIT, f32::INFINITY));
        (hits.slot[i], hits.t[i]) = (slot, t);
        if slot != NO_HIT {
            // Barycentrics only for the winner; the traversal computed them for every candidate.
            hits.barycentric[i] = scene.shape(slot as usize).barycentric(origin, direction);
        }
    }
}
