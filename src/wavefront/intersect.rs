//! Stage 2, intersect: the closest hit of every ray of the batch.

use super::batch::{HitBatch, NO_HIT, RayBatch};
use crate::math::Vec2;
use crate::render_scene::{RayKey, RenderScene, TraversalStack};

/// Finds the closest hit of each ray (ray `i` of the path of random-number key
/// `path_keys[i]`, at `bounce`: they choose BLEND coverage); misses get [`NO_HIT`].
pub fn intersect_closest(
    scene: &RenderScene,
    rays: &RayBatch,
    path_keys: &[u64],
    bounce: u32,
    hits: &mut HitBatch,
) {
    let n = rays.len();
    hits.t.resize(n, 0.0);
    hits.slot.resize(n, NO_HIT);
    hits.barycentric.resize(n, Vec2::ZERO);
    let mut stack = TraversalStack::default();
    for (i, &path) in path_keys.iter().enumerate().take(n) {
        let (origin, direction) = (rays.origin[i], rays.direction[i]);
        let key = RayKey {
            path,
            bounce,
            ray: 0,
        };
        let (slot, t) = scene
            .closest_covered_hit(&mut stack, origin, direction, f32::INFINITY, key)
            .unwrap_or((NO_HIT, f32::INFINITY));
        (hits.slot[i], hits.t[i]) = (slot, t);
        if slot != NO_HIT {
            // Barycentrics only for the winner; the traversal computed them for every candidate.
            hits.barycentric[i] = scene.shape(slot as usize).barycentric(origin, direction);
        }
    }
}
