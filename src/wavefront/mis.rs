//! Multiple-importance-sampling weights, every strategy pair in one place:
//!
//! - next-event estimation against BSDF sampling (Veach's power heuristic, `beta = 2`):
//!   [`power_heuristic`] for the shadow rays, [`emission_weight`] and [`environment_weight`]
//!   for what a BSDF-sampled ray finds;
//! - the path tracer against the light paths for caustics (the balance heuristic,
//!   `1 / (1 + r)` and `r / (1 + r)` with `r = n p_LT / p_PT`; the derivation is in
//!   [`super::light_paths`] and [`super::light_vertices`]): [`camera_vertex_factor`],
//!   [`mis_ratio`], [`path_tracer_weight`] and [`light_tracer_weight`]; merging of light
//!   vertices ([`super::merging`]) takes the same ratio with [`merge_vertex_factor`]. Both sides compute `r`
//!   with these functions from the same quantities, so their weights sum to one for every
//!   path.

use crate::lights::AreaLight;
use crate::math::Vec4;
use std::f32::consts::FRAC_1_PI;

/// Veach's power heuristic (beta = 2), lane by lane, for a sample from the strategy of
/// density `pdf` against one of density `other_pdf`, each already multiplied by its sample
/// count.
#[inline(always)]
pub(super) fn power_heuristic(pdf: Vec4, other_pdf: Vec4) -> Vec4 {
    let (a, b) = (pdf * pdf, other_pdf * other_pdf);
    let weight = Vec4::select((a + b).cmpgt(Vec4::ZERO), a / (a + b), Vec4::ZERO);
    Vec4::select(a.cmpeq(Vec4::INFINITY), Vec4::ONE, weight)
}

/// The MIS weight of emission that a BSDF-sampled ray (solid-angle density `bsdf_pdf` at the
/// previous vertex) found at `distance`, where the surface's cosine toward that vertex is
/// `cos_light`, against the `shadow_rays` shadow rays that could have chosen the same point
/// (area density `light_pdf_area`).
#[inline(always)]
pub(super) fn emission_weight(
    bsdf_pdf: f32,
    shadow_rays: u32,
    light_pdf_area: f32,
    distance: f32,
    cos_light: f32,
) -> f32 {
    // The density with which the shadow rays would have chosen this point, per solid angle
    // at the previous vertex.
    let light_pdf_sa = light_pdf_area * distance * distance / cos_light;
    power_heuristic(
        Vec4::splat(bsdf_pdf),
        Vec4::splat(shadow_rays as f32 * light_pdf_sa),
    )
    .x
}

/// The MIS weight of the environment's radiance that a BSDF-sampled ray (solid-angle
/// density `bsdf_pdf`) found on leaving the scene, against the `shadow_rays` shadow rays
/// that could have chosen its direction (solid-angle density `light_pdf`, choice included).
#[inline]
pub(super) fn environment_weight(bsdf_pdf: f32, shadow_rays: u32, light_pdf: f32) -> f32 {
    power_heuristic(
        Vec4::splat(bsdf_pdf),
        Vec4::splat(shadow_rays as f32 * light_pdf),
    )
    .x
}

/// The camera vertex's part of the light tracer's MIS ratio:
/// `cos_x1 / (p_bsdf(w1) * p_camera_area(x1))`, with `cos_x1 = |ng . w1|` toward the light
/// side, `bsdf_pdf` the solid-angle density of `w1` given the direction to the camera,
/// `to_camera_cos = |ng . wo|`, `distance` from the eye and `direction_density` the camera's
/// density of its ray direction. For a connection after a diffuse bounce the "camera" is the
/// previous vertex `x2`, and `direction_density` its BSDF's density of the direction to `x1`.
#[inline]
pub(super) fn camera_vertex_factor(
    cos_x1: f32,
    bsdf_pdf: f32,
    to_camera_cos: f32,
    distance: f32,
    direction_density: f32,
) -> f32 {
    let camera_area_density = direction_density * to_camera_cos / (distance * distance);
    let factor = cos_x1 / (bsdf_pdf * camera_area_density);
    if factor.is_finite() { factor } else { 0.0 }
}

/// The merging vertex's part of the light tracer's MIS ratio
/// ([`super::merging`]): `n_L pi r^2 cos_x1 / p_bsdf(w1)`, merging's density of the
/// direction `w1` at `x1` over the path tracer's, without the light's factors (which
/// [`mis_ratio`] adds). `cos_x1 = |ng . w1|`; infinite where the BSDF cannot sample `w1`.
#[inline]
pub(super) fn merge_vertex_factor(
    light_paths: f32,
    radius: f32,
    cos_x1: f32,
    bsdf_pdf: f32,
) -> f32 {
    if bsdf_pdf > 0.0 {
        light_paths * std::f32::consts::PI * radius * radius * cos_x1 / bsdf_pdf
    } else {
        f32::INFINITY
    }
}

/// The emission density over the cosine at the light, `p_emit(w0) / cos_y0`, of an area light.
#[inline]
pub(super) fn emission_density_over_cos(light: &AreaLight) -> f32 {
    if light.two_sided {
        0.5 * FRAC_1_PI
    } else {
        FRAC_1_PI
    }
}

/// `r = n p_LT / p_PT` for a path that left area light `light` and met the camera vertex of
/// factor `camera_factor`: `n` (the light paths of the pass for the direct connection to the
/// camera, 1 for a connection after a diffuse bounce) times [`camera_vertex_factor`].
#[inline]
pub(super) fn mis_ratio(light: &AreaLight, camera_factor: f32) -> f32 {
    light.pdf_area * emission_density_over_cos(light) * camera_factor
}

/// The path tracer's weight for emission from `light` found through a delta chain after the
/// camera vertex of factor `camera_factor` (as for [`mis_ratio`]).
#[inline]
pub(super) fn path_tracer_weight(light: &AreaLight, camera_factor: f32) -> f32 {
    1.0 / (1.0 + mis_ratio(light, camera_factor))
}

/// The light tracer's weight, the complement of [`path_tracer_weight`] (1 for an infinite
/// ratio: a direction the path tracer cannot sample).
#[inline]
pub(super) fn light_tracer_weight(ratio: f32) -> f32 {
    1.0 / (1.0 + 1.0 / ratio)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Shape;
    use crate::geometry::triangle::TriangleGeom;
    use crate::math::{Rgb, Vec3A};

    #[test]
    fn the_path_and_light_tracer_weights_sum_to_one() {
        let light = AreaLight {
            pdf_area: 0.37,
            ..AreaLight::new(
                Shape::Triangle(TriangleGeom::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)),
                Rgb::ONE,
                false,
            )
        };
        for light_paths in [1.0, 300.0, 65536.0] {
            for factor in [1e-6, 0.01, 1.0, 37.0, 1e6] {
                let factor = light_paths * factor;
                let path_tracer = path_tracer_weight(&light, factor);
                let light_tracer = light_tracer_weight(mis_ratio(&light, factor));
                assert!((path_tracer + light_tracer - 1.0).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn the_power_heuristic_weights_of_two_strategies_sum_to_one() {
        let a = Vec4::new(0.5, 2.0, 1e-3, 7.0);
        let b = Vec4::new(1.5, 0.25, 3.0, 7.0);
        let sum = power_heuristic(a, b) + power_heuristic(b, a);
        assert!((sum - Vec4::ONE).abs().max_element() < 1e-6, "{sum}");
    }
}
