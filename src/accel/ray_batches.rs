//! The order in which large batches of independent rays are cast, for the ray-casting
//! queries of `RenderScene` (`closest_hits`, `occlusions`: a client's view of the scene, as
//! Embree's stream calls are): the rays are cast in Morton order of their origins, so that
//! rays cast one after another start in the same part of the tree and meet the same nodes
//! and triangles while they are still in cache; the answers come back in the caller's order.
//! In a scene that outgrows the caches this is worth far more than the sort costs (see the
//! README's ray-casting figures); the answers are exactly those of the one-ray queries.

use super::traverse::TraversalStack;
use crate::math::{Ray, Vec3A};
use obvhs::aabb::Aabb;
use rayon::prelude::*;

/// Scenes whose tree and leaf records take more than this are cast in Morton order; smaller
/// ones stay in a core's cache (1-2 MiB of L2 on current CPUs) whatever the order, and the
/// sort would only cost (the room, 0.3 MiB: 20-40% slower sorted; the 1.3M-triangle scene,
/// 125 MiB: 30% faster).
pub const SORT_ABOVE_BYTES: usize = 4 << 20;

/// Rays traced one after another by a thread: large enough that the threads rarely meet,
/// small enough that both cores stay busy to the end.
const RAYS_PER_JOB: usize = 4096;

/// Answers `query` for every ray, in parallel, casting the rays in Morton order of their
/// origins within the scene's box `bounds` (`None`: in their own order); the answers are
/// returned in the order of `rays`.
pub fn in_coherent_order<T: Copy + Default + Send>(
    rays: &[Ray],
    bounds: Option<Aabb>,
    query: impl Fn(&mut TraversalStack, &Ray) -> T + Sync,
) -> Vec<T> {
    let Some(order) = bounds.and_then(|bounds| morton_order(rays, bounds)) else {
        return rays
            .par_iter()
            .with_min_len(RAYS_PER_JOB)
            .map_init(TraversalStack::default, |stack, ray| query(stack, ray))
            .collect();
    };
    // Each job gathers its rays into a buffer of its own first: a pass of independent loads,
    // which the memory system overlaps, rather than a miss at the start of every traversal.
    let mut answers = vec![T::default(); rays.len()];
    answers
        .par_chunks_mut(RAYS_PER_JOB)
        .zip(order.par_chunks(RAYS_PER_JOB))
        .for_each_init(
            || (TraversalStack::default(), Vec::with_capacity(RAYS_PER_JOB)),
            |(stack, gathered), (answers, indices)| {
                gathered.clear();
                gathered.extend(indices.iter().map(|&i| rays[i as usize]));
                for (answer, ray) in answers.iter_mut().zip(gathered.iter()) {
                    *answer = query(stack, ray);
                }
            },
        );
    let mut in_order = vec![T::default(); rays.len()];
    for (&i, answer) in order.iter().zip(answers) {
        in_order[i as usize] = answer;
    }
    in_order
}

/// The indices of `rays` sorted by the Morton code of their origins on a 1024^3 grid over
/// `bounds` (origins outside fall in its border cells; ties keep their order: the sort is
/// stable). `None` when every origin lies in one cell (a pinhole camera's rays), where the
/// order would not change.
fn morton_order(rays: &[Ray], bounds: Aabb) -> Option<Vec<u32>> {
    assert!(
        u32::try_from(rays.len()).is_ok(),
        "a ray batch is indexed by u32"
    );
    let (low, high) = (bounds.min, bounds.max);
    let scale = Vec3A::splat(1023.0) / (high - low).max(Vec3A::splat(f32::MIN_POSITIVE));
    let mut keyed: Vec<(u32, u32)> = rays
        .par_iter()
        .enumerate()
        .map(|(i, ray)| {
            // A NaN origin lands in cell 0 and is answered as the one-ray query answers it.
            let cell = ((ray.origin - low) * scale).clamp(Vec3A::ZERO, Vec3A::splat(1023.0));
            (
                morton_code(cell.x as u32, cell.y as u32, cell.z as u32),
                i as u32,
            )
        })
        .collect();
    radsort::sort_by_key(&mut keyed, |&(code, _)| code);
    let one_cell = keyed.first().map(|k| k.0) == keyed.last().map(|k| k.0);
    (!one_cell).then(|| keyed.into_iter().map(|(_, i)| i).collect())
}

/// Interleaves the low 10 bits of `x`, `y` and `z` (x lowest) into a 30-bit Morton code.
fn morton_code(x: u32, y: u32, z: u32) -> u32 {
    spread_bits(x) | spread_bits(y) << 1 | spread_bits(z) << 2
}

/// The low 10 bits of `v`, two zero bits after each.
fn spread_bits(v: u32) -> u32 {
    let mut v = v & 0x3ff;
    v = (v | v << 16) & 0x0300_00ff;
    v = (v | v << 8) & 0x0300_f00f;
    v = (v | v << 4) & 0x030c_30c3;
    (v | v << 2) & 0x0924_9249
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_codes_interleave_the_coordinates_bits() {
        assert_eq!(morton_code(1, 0, 0), 0b001);
        assert_eq!(morton_code(0, 1, 0), 0b010);
        assert_eq!(morton_code(0, 0, 1), 0b100);
        assert_eq!(morton_code(0b11, 0b01, 0b10), 0b101_011);
        assert_eq!(morton_code(1023, 1023, 1023), (1 << 30) - 1);
        // Bit 9 of z is the top bit; bits past 10 are ignored.
        assert_eq!(morton_code(0, 0, 1 << 9), 1 << 29);
        assert_eq!(morton_code(1 << 10, 0, 0), 0);
    }

    #[test]
    fn rays_from_one_point_keep_their_order() {
        let ray = Ray {
            origin: Vec3A::ONE,
            direction: Vec3A::X,
            t_max: 1.0,
        };
        let unit = Aabb::new(Vec3A::ZERO, Vec3A::splat(2.0));
        assert_eq!(morton_order(&[ray; 100], unit), None);
        assert_eq!(morton_order(&[], unit), None);
    }

    #[test]
    fn the_order_visits_every_ray_once_and_groups_nearby_origins() {
        // Origins on a line, shuffled: the order must put them back along the line, and the
        // far ends last.
        let n = 1000u32;
        let rays: Vec<Ray> = (0..n)
            .map(|i| {
                let x = ((i * 389) % n) as f32;
                Ray {
                    origin: Vec3A::new(x, 0.0, 0.0),
                    direction: Vec3A::Z,
                    t_max: 1.0,
                }
            })
            .collect();
        let line = Aabb::new(Vec3A::ZERO, Vec3A::new(n as f32, 0.0, 0.0));
        let order = morton_order(&rays, line).expect("origins in many cells");
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..n).collect::<Vec<_>>());
        let xs: Vec<f32> = order.iter().map(|&i| rays[i as usize].origin.x).collect();
        assert!(xs.windows(2).all(|w| w[0] <= w[1]), "{xs:?}");
    }
}
