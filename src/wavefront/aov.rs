//! Auxiliary values of each path (the denoiser's guides and the `--aov` layers): the albedo and
//! shading normal at the path's first non-specular hit, the camera ray's hit distance, and the
//! light the path finds before that hit (emitters and the environment seen directly or through
//! mirrors and glass: exactly what the shade stage adds there, which the denoiser leaves
//! alone).
//! Mirrors and smooth glass are followed as Cycles' denoising albedo and normal follow them: the
//! path goes on through its delta bounces, and their tints multiply the albedo found behind
//! them. A pass of its own between intersect and shade: it reads the hits, draws no random
//! number and changes nothing the colour estimator reads, so images are the same with or
//! without it.

use super::batch::{HitBatch, NO_HIT, PathState, RayBatch};
use super::medium::transmittance;
use super::surface;
use crate::bsdf::Bsdf;
use crate::film::AovSample;
use crate::math::Rgb;
use crate::render_scene::{NO_EMITTER, RenderScene};

/// Per-path auxiliary state, columns of [`PathState`]; all empty when the render records no
/// auxiliary values.
#[derive(Clone, Default)]
pub struct AovColumns {
    /// The values recorded so far (provisional while `pending`).
    pub sample: Vec<AovSample>,
    /// Product of the tints of the delta surfaces the path has passed.
    pub tint: Vec<Rgb>,
    /// Whether the path has not reached a non-specular surface yet.
    pub pending: Vec<bool>,
}

impl AovColumns {
    /// Whether the columns are in use (they hold one entry per live path).
    #[inline]
    pub fn is_active(&self) -> bool {
        !self.pending.is_empty()
    }

    /// Resizes every column to `n`.
    pub fn resize(&mut self, n: usize) {
        self.sample.resize(n, AovSample::default());
        self.tint.resize(n, Rgb::ONE);
        self.pending.resize(n, true);
    }

    /// Moves path `from`'s entries to `to` (compaction).
    #[inline]
    pub fn move_entry(&mut self, from: usize, to: usize) {
        self.sample[to] = self.sample[from];
        self.tint[to] = self.tint[from];
        self.pending[to] = self.pending[from];
    }
}

/// Records the auxiliary values of the paths whose rays `rays` found `hits` at bounce
/// `bounce`; at bounce 0 it first starts the columns afresh for the batch's camera paths.
pub fn record_first_surfaces(
    scene: &RenderScene,
    rays: &RayBatch,
    hits: &HitBatch,
    paths: &mut PathState,
    bounce: u32,
) {
    let cones = &paths.cone;
    let aov = &mut paths.aov;
    if bounce == 0 {
        aov.sample.clear();
        aov.tint.clear();
        aov.pending.clear();
        aov.resize(rays.len());
    }
    for i in 0..rays.len() {
        if !aov.pending[i] {
            continue;
        }
        let (origin, direction) = (rays.origin[i], rays.direction[i]);
        let sample = &mut aov.sample[i];
        if hits.slot[i] == NO_HIT {
            let seen = bounce > 0 || scene.environment_visible;
            let background = match scene.lights.environment() {
                Some(environment) if seen => environment.eval(direction),
                _ => Rgb::ZERO,
            };
            // As `shade_kernel::escaped` adds it after the camera or delta bounces: in full.
            sample.emission += paths.throughput[i] * background;
            sample.albedo = aov.tint[i] * unit_clamped(background);
            sample.normal = Rgb::ZERO;
            aov.pending[i] = false;
            continue;
        }
        let (slot, t, barycentric) = (hits.slot[i] as usize, hits.t[i], hits.barycentric[i]);
        if bounce == 0 {
            sample.depth = t;
        }
        let ng = scene
            .shape(slot)
            .surface_point(origin, direction, t, barycentric)
            .ng;
        let wo = -direction;
        let ns = surface::shading_normal(scene, slot, barycentric, ng);
        let material = scene.material_of(slot) as usize;
        let width = cones.get(i).map_or(0.0, |cone| cone.width_at(t));
        let (bsdf, ns) = surface::textured_surface_in_cone(
            scene,
            material,
            slot,
            barycentric,
            ng,
            ns,
            wo,
            width,
        );
        let facing = if ns.dot(wo) < 0.0 { -ns } else { ns };
        sample.normal = Rgb::from(facing);
        let emitter = scene.emitter_of(slot);
        if emitter != NO_EMITTER
            && (ng.dot(wo) > 0.0 || scene.lights.lights[emitter as usize].two_sided)
        {
            // As the shade stage adds it after the camera or delta bounces: in full, after
            // the absorption along the segment.
            let mut throughput = paths.throughput[i];
            if paths.medium[i] != Rgb::ZERO {
                throughput *= transmittance(paths.medium[i], t);
            }
            sample.emission += throughput * surface::emitted_radiance(scene, emitter, barycentric);
        }
        match bsdf {
            Bsdf::Mirror { tint } | Bsdf::Dielectric { tint, .. } if !bsdf.is_black() => {
                // Provisional until the path reaches a non-specular surface (it may end here).
                aov.tint[i] *= unit_clamped(tint);
                sample.albedo = aov.tint[i];
            }
            _ => {
                let albedo = if bsdf.is_black() && emitter != NO_EMITTER {
                    surface::emitted_radiance(scene, emitter, barycentric)
                } else {
                    surface_albedo(&bsdf)
                };
                sample.albedo = aov.tint[i] * unit_clamped(albedo);
                aov.pending[i] = false;
            }
        }
    }
}

/// The colour a denoiser takes for a surface's reflectance: the base colour (diffuse or
/// metallic alike), a delta surface's tint, an unlit surface's colour.
fn surface_albedo(bsdf: &Bsdf) -> Rgb {
    match *bsdf {
        Bsdf::Lambertian { albedo } => albedo,
        Bsdf::Mirror { tint } | Bsdf::Dielectric { tint, .. } => tint,
        Bsdf::MetallicRoughness(params) => params.base_color,
        Bsdf::Layered(layered) => layered.base.base_color,
        Bsdf::Unlit { color } => color,
    }
}

/// Each channel clamped to [0, 1] (NaN to 0).
#[inline]
fn unit_clamped(colour: Rgb) -> Rgb {
    let channel = |c: f32| if c > 0.0 { c.min(1.0) } else { 0.0 };
    Rgb::new(channel(colour.x), channel(colour.y), channel(colour.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn albedo_is_clamped_to_the_unit_range() {
        assert_eq!(
            unit_clamped(Rgb::new(-1.0, 0.5, 7.0)),
            Rgb::new(0.0, 0.5, 1.0)
        );
        assert_eq!(unit_clamped(Rgb::new(f32::NAN, 0.0, 1.0)).x, 0.0);
    }
}
