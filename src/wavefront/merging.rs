//! Caustics seen behind a delta vertex: vertex merging (progressive photon mapping of the
//! pass's light vertices, VCM's merging restricted to the paths no connection reaches).
//!
//! A camera path that reaches a non-delta point `x` through a mirror or smooth glass (camera
//! -> mirror -> floor, or wall -> mirror -> floor) cannot connect `x`'s caustic to anything:
//! the light tracer's connection to the camera and a connection from the vertex before `x`
//! both need a straight segment to `x`. Before merging, only the path tracer found these
//! paths (`x`, a BSDF sample through glass onto a small light): the fireflies that held over
//! 80% of the room's squared error (docs/sampling.md, section 7).
//!
//! At such an `x` (a non-delta vertex after a delta bounce, never the camera's first hit) the
//! shade stage adds the density estimate of the pass's light vertices ([`LightVertex`]: light
//! -> delta+ -> `y`) within radius `r` of `x`:
//!
//! ```text
//! beta_cam  sum_{|y - x| < r}  f(x; wo, w_y) |ns . w_y| / |ng . w_y|  beta_y  weight_y
//!     / (n_L pi r^2)
//! ```
//!
//! with `w_y` the direction the light arrived from at `y`, `n_L` the pass's light paths and the
//! BSDF taken at `x` (the camera's point). The light vertices lie in a hash grid of cells
//! `2r` wide ([`LightVertexGrid`], rebuilt every pass), so that the 8 cells around `x` hold
//! every vertex within `r`.
//!
//! MIS, balance heuristic, against the path tracer's BSDF sample at `x` that passes the delta
//! chain and hits the light: in the path tracer's variables (`x` fixed by the camera prefix,
//! `w1` by solid angle at `x`) merging samples `w1` with density `n_L pi r^2 p_LT(x, w1)`,
//! `p_LT(x, w1) = p_light_area(y0) (p_emit(w0) / cos_y0) cos_x1` (the light path's density
//! carried through the delta chain, as in [`super::light_paths`]), so
//! `r_merge = n_L pi r^2 p_light_area (p_emit / cos_y0) cos_x1 / p_bsdf(w1)`:
//! [`super::mis::merge_vertex_factor`] and [`super::mis::mis_ratio`]. The path tracer keeps
//! the same factor in its [`super::batch::CausticState`] from `x` on, so the two weights sum
//! to one for every path. Punctual lights take weight 1 (no ray hits them).
//!
//! Bias and consistency: merging blurs the caustic over `r`; the radius shrinks with the pass
//! as progressive photon mapping's does (Knaus and Zwicker, alpha = 2/3:
//! `r_i = r_0 i^(-1/6)`), so the bias vanishes as samples grow and the estimator converges to
//! the same image as the path tracer alone. `r_0` is `RenderSettings::caustic_merge_radius` camera pixels (3 by default) at
//! the median distance of the camera's first hits ([`base_radius`]): the number of light
//! vertices per merge then depends neither on the resolution nor on the scene's scale.
//!
//! Determinism: the grid holds the vertices in path order within each cell, and a merge adds
//! them in that order; nothing depends on the thread count.

use super::light_vertices::{CameraVertex, LightVertex};
use super::mis::{light_tracer_weight, merge_vertex_factor, mis_ratio};
use crate::camera::PinholeCamera;
use crate::math::{Rgb, Vec2, Vec3A};
use crate::render_scene::{RenderScene, TraversalStack};
use std::f32::consts::PI;

/// Progressive photon mapping's alpha (the share of the light vertices a pass keeps in the
/// radius's shrinking): 2/3, asymptotically the best balance of bias and variance.
const ALPHA: f32 = 2.0 / 3.0;

/// The merge radius of pass `pass` (0-based) for first-pass radius `base`:
/// `base (pass + 1)^((alpha - 1) / 2)`.
pub fn pass_radius(base: f32, pass: u32) -> f32 {
    base * ((pass + 1) as f32).powf(0.5 * (ALPHA - 1.0))
}

/// Camera rays of the probe that measures the scene's distance from the camera, per side.
const PROBE_SIDE: u32 = 16;

/// The first pass's merge radius: `pixels` pixel footprints at the median distance of the
/// camera's first hits (a `PROBE_SIDE`-square grid of pixel-centre rays over the whole image;
/// the footprint is the distance between two neighbouring pixels' rays there). `None` when no
/// probe ray hits anything (nothing to merge on).
pub fn base_radius(
    scene: &RenderScene,
    camera: &PinholeCamera,
    (width, height): (u32, u32),
    pixels: f32,
) -> Option<f32> {
    let mut stack = TraversalStack::default();
    let mut footprints = Vec::with_capacity((PROBE_SIDE * PROBE_SIDE) as usize);
    let centre = Vec2::splat(0.5);
    for j in 0..PROBE_SIDE {
        for i in 0..PROBE_SIDE {
            let x = ((i as f32 + 0.5) / PROBE_SIDE as f32 * width as f32) as u32;
            let y = ((j as f32 + 0.5) / PROBE_SIDE as f32 * height as f32) as u32;
            let x = x.min(width.saturating_sub(2));
            let pixel = y.min(height - 1) * width + x;
            let (origin, direction) = camera.generate_ray(pixel, centre);
            let (next_origin, next_direction) = camera.generate_ray(pixel + 1, centre);
            if let Some((_, t)) = scene.closest_hit(&mut stack, origin, direction, f32::INFINITY) {
                let apart = (origin + t * direction) - (next_origin + t * next_direction);
                footprints.push(apart.length());
            }
        }
    }
    footprints.retain(|f| f.is_finite() && *f > 0.0);
    if footprints.is_empty() {
        return None;
    }
    let middle = footprints.len() / 2;
    let (_, median, _) = footprints.select_nth_unstable_by(middle, f32::total_cmp);
    Some(pixels * *median)
}

/// The pass's light vertices in a hash grid of cells twice the merge radius wide, in path
/// order within each bucket. Allocated once per render and rebuilt every pass.
#[derive(Debug, Default)]
pub struct LightVertexGrid {
    radius: f32,
    inverse_cell: f32,
    bucket_mask: usize,
    /// Where each bucket's vertices start in `order` (one more entry than buckets).
    bucket_start: Vec<u32>,
    /// Vertex indices, bucket by bucket.
    order: Vec<u32>,
}

impl LightVertexGrid {
    /// Files `vertices` for merges within `radius`.
    pub fn rebuild(&mut self, vertices: &[LightVertex], radius: f32) {
        self.radius = radius;
        self.inverse_cell = 0.5 / radius;
        let buckets = (2 * vertices.len()).next_power_of_two().max(1);
        self.bucket_mask = buckets - 1;
        self.bucket_start.clear();
        self.bucket_start.resize(buckets + 1, 0);
        for v in vertices {
            let bucket = self.bucket(self.cell(v.p));
            self.bucket_start[bucket + 1] += 1;
        }
        for b in 0..buckets {
            self.bucket_start[b + 1] += self.bucket_start[b];
        }
        // Counting sort, stable: each bucket keeps its vertices in path order.
        self.order.clear();
        self.order.resize(vertices.len(), 0);
        let mut next: Vec<u32> = self.bucket_start[..buckets].to_vec();
        for (index, v) in vertices.iter().enumerate() {
            let bucket = self.bucket(self.cell(v.p));
            self.order[next[bucket] as usize] = index as u32;
            next[bucket] += 1;
        }
    }

    /// The merge radius of the pass.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    fn cell(&self, p: Vec3A) -> [i32; 3] {
        let c = (p * self.inverse_cell).floor();
        // Saturating casts: points far outside any sane scene share the border cells.
        [c.x as i32, c.y as i32, c.z as i32]
    }

    fn bucket(&self, [x, y, z]: [i32; 3]) -> usize {
        let h = (x as u32).wrapping_mul(73_856_093)
            ^ (y as u32).wrapping_mul(19_349_663)
            ^ (z as u32).wrapping_mul(83_492_791);
        h as usize & self.bucket_mask
    }

    /// Calls `visit` with the index of every vertex that may lie within the radius of `p`
    /// (and others of the same buckets), each once, bucket by bucket in path order.
    fn for_each_candidate(&self, p: Vec3A, mut visit: impl FnMut(usize)) {
        if self.order.is_empty() {
            return;
        }
        let scaled = p * self.inverse_cell;
        let base = scaled.floor();
        // Cells are 2r wide: the sphere of radius r around p touches p's cell and, per axis,
        // the neighbour on the side of p's nearer face.
        let step = (scaled - base).cmplt(Vec3A::splat(0.5));
        let [bx, by, bz] = [base.x as i32, base.y as i32, base.z as i32];
        let other = |b: i32, lower: bool| if lower { b - 1 } else { b + 1 };
        let (ox, oy, oz) = (
            other(bx, step.test(0)),
            other(by, step.test(1)),
            other(bz, step.test(2)),
        );
        let mut seen = [usize::MAX; 8];
        for k in 0..8 {
            let cell = [
                if k & 1 == 0 { bx } else { ox },
                if k & 2 == 0 { by } else { oy },
                if k & 4 == 0 { bz } else { oz },
            ];
            let bucket = self.bucket(cell);
            // Two cells may share a bucket: its vertices are visited once.
            if seen[..k].contains(&bucket) {
                continue;
            }
            seen[k] = bucket;
            let range = self.bucket_start[bucket] as usize..self.bucket_start[bucket + 1] as usize;
            for &index in &self.order[range] {
                visit(index as usize);
            }
        }
    }
}

/// The radiance the pass's `vertices` (filed in `grid`, made by `light_paths` light paths)
/// near `at` (a camera vertex reached through a delta bounce, at bounce 1 or later) send along
/// the camera path, its throughput included, with each one's MIS weight against the path
/// tracer.
/// `max_depth` is the path tracer's cap: light vertices whose paths it could not trace are
/// left out, so both strategies cover the same paths.
#[inline(never)]
pub(super) fn merge(
    scene: &RenderScene,
    (grid, vertices, light_paths): (&LightVertexGrid, &[LightVertex], u64),
    at: &CameraVertex<'_>,
    max_depth: u32,
) -> Rgb {
    let radius = grid.radius();
    let radius_squared = radius * radius;
    let light_paths = light_paths as f32;
    let mut sum = Rgb::ZERO;
    grid.for_each_candidate(at.p, |index| {
        let vertex = &vertices[index];
        // The path tracer reaches the light at bounce `bounce + 1 + delta bounces`.
        if (vertex.p - at.p).length_squared() >= radius_squared
            || at.bounce + 1 + vertex.delta_bounces >= max_depth
        {
            return;
        }
        let w = vertex.to_light;
        let wi_local = at.frame.to_local(w);
        // The side rule of the path tracer's BSDF sample toward w.
        let through = wi_local.z * at.wo_local.z < 0.0;
        if ((at.ng.dot(w) > 0.0) == at.front) == through {
            return;
        }
        let f = at.bsdf.eval(at.wo_local, wi_local);
        let cos_ng = at.ng.dot(w).abs();
        if f.max_element() <= 0.0 || cos_ng <= 0.0 {
            return;
        }
        let weight = match scene.lights.lights.get(vertex.light as usize) {
            None => 1.0, // a punctual light: the path tracer cannot hit it
            Some(light) => {
                let pdf = at.bsdf.pdf(at.wo_local, wi_local);
                let factor = merge_vertex_factor(light_paths, radius, cos_ng, pdf);
                light_tracer_weight(mis_ratio(light, factor))
            }
        };
        sum += f * vertex.throughput * (wi_local.z.abs() / cos_ng * weight);
    });
    let value = at.throughput * sum / (light_paths * PI * radius_squared);
    if value.is_finite() { value } else { Rgb::ZERO }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec2;

    fn vertex_at(p: Vec3A) -> LightVertex {
        LightVertex {
            p,
            ng: Vec3A::Z,
            to_light: Vec3A::Z,
            throughput: Rgb::ONE,
            slot: 0,
            material: 0,
            barycentric: Vec2::ZERO,
            light: 0,
            delta_bounces: 1,
        }
    }

    /// Every vertex within the radius of a query point is visited exactly once, whatever the
    /// hash collisions, on a cloud of points around cell borders.
    #[test]
    fn the_grid_finds_every_vertex_within_the_radius_once() {
        let mut state = 0x1234_5678_u32;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let vertices: Vec<LightVertex> = (0..2000)
            .map(|_| vertex_at(Vec3A::new(next(), next(), next()) * 2.0 - 1.0))
            .collect();
        let mut grid = LightVertexGrid::default();
        for radius in [0.01, 0.1, 0.3] {
            grid.rebuild(&vertices, radius);
            for _ in 0..200 {
                let p = Vec3A::new(next(), next(), next()) * 2.0 - 1.0;
                let mut visits = vec![0u32; vertices.len()];
                grid.for_each_candidate(p, |i| visits[i] += 1);
                for (v, visits) in vertices.iter().zip(&visits) {
                    assert!(*visits <= 1, "visited twice");
                    if (v.p - p).length() < radius {
                        assert_eq!(*visits, 1, "missed a vertex at {}", (v.p - p).length());
                    }
                }
            }
        }
    }

    #[test]
    fn the_radius_shrinks_as_progressive_photon_mapping_says() {
        assert_eq!(pass_radius(2.0, 0), 2.0);
        let r = pass_radius(2.0, 63);
        assert!((r - 2.0 * 64f32.powf(-1.0 / 6.0)).abs() < 1e-6, "{r}");
        // Its square shrinks slower than 1/i: the vertices per merge still grow.
        assert!(r * r * 64.0 > 2.0 * 2.0 * 10.0);
    }

    #[test]
    fn an_empty_grid_finds_nothing() {
        let mut grid = LightVertexGrid::default();
        grid.rebuild(&[], 0.1);
        grid.for_each_candidate(Vec3A::ZERO, |_| panic!("no vertex"));
    }
}
