//! Structure-of-arrays work buffers passed between the stages. Each set is allocated once
//! per worker thread and render and reused for every bounce and batch; index `i` of every
//! buffer of a bounce refers to the same live path.

use super::aov::AovColumns;
use crate::film::FilmRegion;
use crate::lights::LightUniforms;
use crate::math::{Rgb, Vec2, Vec3A};
use crate::ray_cone::RayCone;
use std::ops::Range;

/// Rays to intersect, one per live path.
#[derive(Clone, Default)]
pub struct RayBatch {
    /// Ray origin, world space (already offset off the surface it leaves).
    pub origin: Vec<Vec3A>,
    /// Unit direction, world space.
    pub direction: Vec<Vec3A>,
}

impl RayBatch {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origin.len()
    }

    /// Whether there are no rays.
    pub fn is_empty(&self) -> bool {
        self.origin.is_empty()
    }

    /// Resizes every column to `n` (new entries are placeholders the next stage overwrites).
    pub fn resize(&mut self, n: usize) {
        self.origin.resize(n, Vec3A::ZERO);
        self.direction.resize(n, Vec3A::Z);
    }
}

/// Marks a ray that hit nothing in [`HitBatch::slot`].
pub const NO_HIT: u32 = u32::MAX;

/// Closest hits of a [`RayBatch`].
#[derive(Clone, Default)]
pub struct HitBatch {
    /// Distance along the ray.
    pub t: Vec<f32>,
    /// BVH slot of the primitive hit, or [`NO_HIT`].
    pub slot: Vec<u32>,
    /// Barycentrics `(u, v)` of a triangle hit (unused for spheres).
    pub barycentric: Vec<Vec2>,
}

/// Per-path state that lives across bounces.
#[derive(Clone, Default)]
pub struct PathState {
    /// Pixel index (row-major) the path contributes to.
    pub pixel: Vec<u32>,
    /// Random-number key of the path (see `math::rng`).
    pub rng_key: Vec<u64>,
    /// Product of BSDF weights so far.
    pub throughput: Vec<Rgb>,
    /// Radiance gathered so far.
    pub radiance: Vec<Rgb>,
    /// Whether emission found by the next hit is counted: true after the camera and after
    /// delta bounces, where next-event estimation could not have counted it.
    pub count_emission: Vec<bool>,
    /// Solid-angle density of the BSDF sample that made the current ray, when emission its
    /// next hit finds is counted with a multiple-importance weight; 0 when that emission is
    /// not counted (light sampling only). Unused while `count_emission` is true.
    pub bsdf_pdf: Vec<f32>,
    /// Whether the path continues after this bounce (set by shading).
    pub alive: Vec<bool>,
    /// Product of the radiance compressions (`1 / eta^2`) of the refractions so far, which
    /// Russian roulette divides out of the throughput.
    pub radiance_scale: Vec<f32>,
    /// Absorption coefficient of the medium the path travels in (`KHR_materials_volume`):
    /// set when it refracts into an absorbing object, zero outside.
    pub medium: Vec<Rgb>,
    /// Where the path stands toward the caustics the pass's light paths also find (always
    /// [`CausticState::None`] when no light paths are traced).
    pub caustic: Vec<CausticState>,
    /// The ray cone of the path's current ray (texture level of detail).
    pub cone: Vec<RayCone>,
    /// Auxiliary values (albedo, normal, depth) for the denoiser and `--aov`; empty columns
    /// when the render records none.
    pub aov: AovColumns,
}

impl PathState {
    /// Number of live paths.
    pub fn len(&self) -> usize {
        self.pixel.len()
    }

    /// Whether no path is live.
    pub fn is_empty(&self) -> bool {
        self.pixel.is_empty()
    }

    /// Resizes every column to `n`.
    pub fn resize(&mut self, n: usize) {
        self.pixel.resize(n, 0);
        self.rng_key.resize(n, 0);
        self.throughput.resize(n, Rgb::ZERO);
        self.radiance.resize(n, Rgb::ZERO);
        self.count_emission.resize(n, false);
        self.bsdf_pdf.resize(n, 0.0);
        self.alive.resize(n, false);
        self.radiance_scale.resize(n, 1.0);
        self.medium.resize(n, Rgb::ZERO);
        self.caustic.resize(n, CausticState::None);
        self.cone.resize(n, RayCone::default());
        if self.aov.is_active() {
            self.aov.resize(n);
        }
    }
}

/// A path's standing toward the caustic paths (`camera or non-delta vertex -> x1 (non-delta)
/// -> delta+ -> light`) that the light paths find too ([`super::light_paths`],
/// [`super::light_vertices`]), with the factor the two strategies' MIS weights need
/// ([`super::mis::camera_vertex_factor`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum CausticState {
    /// Emission the path finds is no such caustic (or no light paths are traced).
    #[default]
    None,
    /// The last vertex `x1` was non-delta and could be a light path's diffuse point.
    /// `factor` is the part of the light tracer's MIS ratio that the vertex before `x1`
    /// gives (the camera's or a connecting vertex's), with its strategy's count. Emission
    /// found straight after `x1` is no caustic (next-event estimation covers it), so the
    /// factor waits for a delta bounce.
    Pending { factor: f32 },
    /// One or more delta bounces since such an `x1`: emission found now ends a caustic path,
    /// weighted against the light paths with `factor`.
    Caustic { factor: f32 },
}

impl CausticState {
    /// The state after a delta bounce: a pending factor starts to count; the rest stays.
    #[inline]
    pub fn after_delta_bounce(self) -> Self {
        match self {
            CausticState::Pending { factor } => CausticState::Caustic { factor },
            other => other,
        }
    }
}

/// Shadow rays: room for a fixed number of entries per live path (`per_path`), so that each
/// path owns a contiguous chunk and the shadow stage can accumulate without synchronisation.
/// The chunk's layout has one owner, [`ShadowSlots`] (written by shading) with
/// [`ShadowBatch::front_entries`] and [`ShadowBatch::back_entries`] (read by the shadow
/// stage): the rays of one side of the surface share their origin, which lets the shadow
/// stage trace them as packets straight from the buffers.
#[derive(Default)]
pub struct ShadowBatch {
    /// Entries per path (at least 1).
    pub per_path: usize,
    /// Shadow rays each path made (at most `per_path`).
    pub count: Vec<u32>,
    /// Shared origin of each path's shadow rays, offset off the surface (one per path).
    pub origin: Vec<Vec3A>,
    /// Shadow rays through the surface each path made (0 unless its BSDF transmits).
    pub back_count: Vec<u32>,
    /// Their shared origin, offset to the back side of the surface.
    pub back_origin: Vec<Vec3A>,
    /// Unit direction toward the light point.
    pub direction: Vec<Vec3A>,
    /// Distance up to which occluders count (just short of the light).
    pub t_max: Vec<f32>,
    /// Radiance added to the path if the ray is unoccluded.
    pub contribution: Vec<Rgb>,
    /// The light-sample uniforms of the shadow rays, four to a group (the shade stage's
    /// `shadow_ray_lattice`), made once per worker and shadow-ray count: zeroing the largest
    /// lattice on the stack at every call of the shade stage cost as much as shading a dozen
    /// paths.
    pub lattice: Vec<LightUniforms>,
    /// The shadow-ray count `lattice` was made for.
    pub lattice_rays: u32,
}

impl ShadowBatch {
    /// Makes room for `paths` live paths. It only ever grows: the stages read the first
    /// `paths` entries, which shading overwrites, so shrinking and refilling the buffers at
    /// every batch and bounce would be wasted work.
    pub fn grow_to(&mut self, paths: usize) {
        if self.origin.len() < paths {
            let n = paths * self.per_path;
            self.count.resize(paths, 0);
            self.origin.resize(paths, Vec3A::ZERO);
            self.back_count.resize(paths, 0);
            self.back_origin.resize(paths, Vec3A::ZERO);
            self.direction.resize(n, Vec3A::Z);
            self.t_max.resize(n, 0.0);
            self.contribution.resize(n, Rgb::ZERO);
        }
    }

    /// Entries of path `i`'s rays from the front origin.
    #[inline(always)]
    pub fn front_entries(&self, i: usize) -> Range<usize> {
        let start = i * self.per_path;
        start..start + self.count[i] as usize
    }

    /// Entries of path `i`'s rays from the back origin.
    #[inline(always)]
    pub fn back_entries(&self, i: usize) -> Range<usize> {
        let end = (i + 1) * self.per_path;
        end - self.back_count[i] as usize..end
    }

    /// The light-sample lattice and path `i`'s chunk, to write its shadow rays into.
    #[inline(always)]
    pub fn lattice_and_slots(&mut self, i: usize) -> (&[LightUniforms], ShadowSlots<'_>) {
        let chunk = i * self.per_path..(i + 1) * self.per_path;
        let slots = ShadowSlots {
            count: &mut self.count[i],
            origin: &mut self.origin[i],
            back_count: &mut self.back_count[i],
            back_origin: &mut self.back_origin[i],
            direction: &mut self.direction[chunk.clone()],
            t_max: &mut self.t_max[chunk.clone()],
            contribution: &mut self.contribution[chunk],
        };
        (&self.lattice, slots)
    }
}

/// One path's chunk of the [`ShadowBatch`]. The rays from the front origin (the side the
/// path arrived on) are packed from the chunk's start; at a surface that transmits, the rays
/// toward lights behind it leave from a second origin on the back side and are packed from
/// the chunk's end, last first. Neither side needs to know how many rays the other takes.
pub struct ShadowSlots<'a> {
    count: &'a mut u32,
    origin: &'a mut Vec3A,
    back_count: &'a mut u32,
    back_origin: &'a mut Vec3A,
    direction: &'a mut [Vec3A],
    t_max: &'a mut [f32],
    contribution: &'a mut [Rgb],
}

impl ShadowSlots<'_> {
    /// The same chunk, borrowed again.
    #[inline(always)]
    pub fn reborrow(&mut self) -> ShadowSlots<'_> {
        ShadowSlots {
            count: self.count,
            origin: self.origin,
            back_count: self.back_count,
            back_origin: self.back_origin,
            direction: self.direction,
            t_max: self.t_max,
            contribution: self.contribution,
        }
    }

    /// Entries in the chunk (front and back rays together).
    #[inline(always)]
    pub fn capacity(&self) -> usize {
        self.direction.len()
    }

    /// Empties the chunk (both sides).
    #[inline(always)]
    pub fn clear(&mut self) {
        *self.count = 0;
        *self.back_count = 0;
    }

    /// Sets the shared origin of the front rays.
    #[inline(always)]
    pub fn set_front_origin(&mut self, origin: Vec3A) {
        *self.origin = origin;
    }

    /// Sets the shared origin of the back rays.
    #[inline(always)]
    pub fn set_back_origin(&mut self, origin: Vec3A) {
        *self.back_origin = origin;
    }

    /// The entry of front ray `k` (counted from 0).
    #[inline(always)]
    pub fn front_entry(k: usize) -> usize {
        k
    }

    /// The entry of back ray `k` (counted from 0).
    #[inline(always)]
    pub fn back_entry(&self, k: usize) -> usize {
        self.direction.len() - 1 - k
    }

    /// Writes a ray into `entry` (from [`Self::front_entry`] or [`Self::back_entry`]); it
    /// counts once [`Self::set_counts`] covers it.
    #[inline(always)]
    pub fn write(&mut self, entry: usize, direction: Vec3A, t_max: f32, contribution: Rgb) {
        self.direction[entry] = direction;
        self.t_max[entry] = t_max;
        self.contribution[entry] = contribution;
    }

    /// Sets how many front and back rays the chunk holds.
    #[inline(always)]
    pub fn set_counts(&mut self, front: usize, back: usize) {
        *self.count = front as u32;
        *self.back_count = back as u32;
    }

    /// Adds a front ray after those already there; returns its entry.
    #[inline(always)]
    pub fn push_front(&mut self, direction: Vec3A, t_max: f32, contribution: Rgb) -> usize {
        let entry = Self::front_entry(*self.count as usize);
        self.write(entry, direction, t_max, contribution);
        *self.count += 1;
        entry
    }

    /// Adds a back ray after those already there; returns its entry.
    #[inline(always)]
    pub fn push_back(&mut self, direction: Vec3A, t_max: f32, contribution: Rgb) -> usize {
        let entry = self.back_entry(*self.back_count as usize);
        self.write(entry, direction, t_max, contribution);
        *self.back_count += 1;
        entry
    }

    /// The entries of the front rays, then of the back rays (each side in entry order).
    #[inline(always)]
    pub fn entries(&self) -> (Range<usize>, Range<usize>) {
        let len = self.direction.len();
        (
            0..*self.count as usize,
            len - *self.back_count as usize..len,
        )
    }

    /// The distance up to which the ray in `entry` looks for occluders.
    #[inline(always)]
    pub fn t_max(&self, entry: usize) -> f32 {
        self.t_max[entry]
    }

    /// Multiplies the contribution of the ray in `entry` by `factor`.
    #[inline(always)]
    pub fn scale_contribution(&mut self, entry: usize, factor: Rgb) {
        self.contribution[entry] *= factor;
    }
}

/// Stable, order-preserving compaction after a bounce: paths still alive move to the front
/// (with their next rays, which become the current rays), and finished paths deliver their
/// radiance to the film, together with the pass's light-path splats on their pixel
/// (`splats`, one per pixel of the film, or empty without light paths): one sample of the
/// combined estimator, with its auxiliary values if they are recorded. Sequential on purpose: the film receives samples in the same order on
/// every run.
pub fn compact_paths(
    paths: &mut PathState,
    next_rays: &mut RayBatch,
    splats: &[Rgb],
    film: &mut FilmRegion,
) {
    let mut kept = 0;
    let aov = paths.aov.is_active();
    for i in 0..paths.len() {
        if !paths.alive[i] {
            let pixel = paths.pixel[i];
            let radiance = match splats.get(pixel as usize) {
                Some(splat) => paths.radiance[i] + *splat,
                None => paths.radiance[i],
            };
            film.add_sample_with_aov(pixel, radiance, paths.aov.sample.get(i));
            continue;
        }
        if aov {
            paths.aov.move_entry(i, kept);
        }
        paths.pixel[kept] = paths.pixel[i];
        paths.rng_key[kept] = paths.rng_key[i];
        paths.throughput[kept] = paths.throughput[i];
        paths.radiance[kept] = paths.radiance[i];
        paths.count_emission[kept] = paths.count_emission[i];
        paths.bsdf_pdf[kept] = paths.bsdf_pdf[i];
        paths.radiance_scale[kept] = paths.radiance_scale[i];
        paths.medium[kept] = paths.medium[i];
        paths.caustic[kept] = paths.caustic[i];
        paths.cone[kept] = paths.cone[i];
        next_rays.origin[kept] = next_rays.origin[i];
        next_rays.direction[kept] = next_rays.direction[i];
        kept += 1;
    }
    paths.resize(kept);
    next_rays.resize(kept);
}
