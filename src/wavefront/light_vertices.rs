//! Caustics seen after a diffuse bounce: camera vertices connected to the light paths'
//! diffuse end points (a light vertex cache, as in VCM; BDPT's connection strategy restricted
//! to the paths `light -> (mirror | smooth glass)+ -> x1`).
//!
//! The light paths of a pass ([`super::light_paths`]) keep the first non-delta point `x1`
//! each one reaches after at least one delta bounce: a [`LightVertex`], in path order. At
//! every non-delta camera path vertex `x2` (every bounce, next to next-event estimation) the
//! shade stage picks one of the pass's `n_L` light paths uniformly with the path's own random
//! numbers (`dim::LIGHT_VERTEX`) and, if that path kept a point, makes a shadow ray
//! `x2 -> x1` whose contribution, if nothing blocks it, is
//!
//! ```text
//! beta_cam f(x2; wo, ->x1) |ns2 . w| |ng1 . w| / d^2  f(x1; ->x2, w1) |ns1 . w1| / |ng1 . w1|
//!     beta_light  weight
//! ```
//!
//! (`|ns1 . w1| / |ng1 . w1|` the adjoint correction for shading normals, as in the direct
//! connection to the camera). Choosing one of the pass's `n_L` light paths uniformly gives a
//! light path of the light tracer's distribution, so the estimator is unbiased with density
//! `p_LT` and one connection per camera vertex. Paths that kept no point contribute zero, so
//! the kept points are stored alone and a pick past them makes no ray (which `m` of the `n_L`
//! indices stand for the kept points does not matter: any assignment is a uniform choice).
//! Picking among the `m` kept points only, weighted by `m / n_L`, has the same expectation and
//! less variance, but a ray at every vertex: on the room (`m / n_L` = 6%) it took 41% more
//! rays for a relative MSE per sample only 1% lower than this pick's (docs/sampling.md,
//! section 7).
//!
//! MIS, balance heuristic, against the path tracer's BSDF-sampled path
//! `x2 -> x1 -> delta+ -> light`: `r = p_LT / p_PT` is the direct case's ratio
//! ([`super::mis::mis_ratio`]) with the camera's density of `x1` replaced by the density with
//! which `x2`'s BSDF sampling reaches `x1` per area, `p_bsdf(x2 -> x1) |ng1 . w| / d^2`
//! ([`super::mis::camera_vertex_factor`] with that solid-angle density), and the light path
//! count by the connections per camera vertex, 1. The path tracer keeps the same factor in
//! its [`super::batch::CausticState`] from `x1` through the delta bounces (the shade stage); both sides compute
//! `r` with the same functions from the same quantities, so the weights sum to one for every
//! path. Where `x1` was reached from a delta vertex there is no connection (weight 1 for the
//! path tracer, as before). Paths longer than the path tracer's depth cap are not connected
//! either, so both strategies cover the same paths. Punctual lights take weight 1: the path
//! tracer cannot hit them, so their caustics seen after a diffuse bounce, missing before,
//! come only from here.
//!
//! Russian roulette: the connection is made at `x2` before its roulette, as next-event
//! estimation is, whether or not the path survives; the ratio leaves out the path tracer's
//! survival probabilities (as it leaves out the Fresnel choices). That changes which weights
//! the two strategies get, never their sum: the weight is a function of the path alone, the
//! same on both sides, so the combination stays unbiased.
//!
//! Absorption: the segment `x2 -> x1` crosses the medium on the side of `x2` it leaves from
//! (the path's, or the object's through a transmitting surface), as the path tracer's ray
//! would.

use super::mis::{camera_vertex_factor, light_tracer_weight, mis_ratio};
use super::surface;
use crate::bsdf::Bsdf;
use crate::math::Rgb;
use crate::math::frame::Frame;
use crate::math::{Vec2, Vec3A};
use crate::render_scene::{NO_EMITTER, RenderScene};

/// A light path's first non-delta point after at least one delta bounce, and what a
/// connection to it needs.
#[derive(Clone, Copy, Debug)]
pub struct LightVertex {
    /// The point and its unit geometric normal.
    pub(super) p: Vec3A,
    pub(super) ng: Vec3A,
    /// Unit direction back toward where the light came from (the chain's last delta vertex).
    pub(super) to_light: Vec3A,
    /// The light path's throughput arriving at the point (before its BSDF).
    pub(super) throughput: Rgb,
    /// Where the material and the shading normal are looked up.
    pub(super) slot: u32,
    pub(super) material: u32,
    pub(super) barycentric: Vec2,
    /// The area light the path left (an index into the light table), or [`NO_EMITTER`] for a
    /// punctual light.
    pub(super) light: u32,
    /// Delta bounces between the light and the point.
    pub(super) delta_bounces: u32,
}

/// A camera vertex as the connection needs it.
pub(super) struct CameraVertex<'a> {
    pub(super) p: Vec3A,
    pub(super) ng: Vec3A,
    /// Whether the path arrived on the side `ng` points to.
    pub(super) front: bool,
    pub(super) frame: Frame,
    pub(super) bsdf: &'a Bsdf,
    pub(super) wo_local: Vec3A,
    /// The path's throughput arriving at the vertex.
    pub(super) throughput: Rgb,
    /// The vertex's bounce (0: the camera ray's hit).
    pub(super) bounce: u32,
}

/// A connection's shadow ray: the light vertex it ends at, whether it leaves through the
/// camera vertex's surface, and what it adds if unoccluded (without absorption along it).
pub(super) struct Connection {
    pub(super) target: Vec3A,
    pub(super) through: bool,
    pub(super) contribution: Rgb,
}

/// The connection of camera vertex `at` to the light vertex of light path `pick` among the
/// pass's `light_vertices` (an index in `0..light_paths`; past the kept vertices, none), if
/// it can add anything. `max_depth` is the path tracer's cap.
#[inline(never)]
pub(super) fn connect(
    scene: &RenderScene,
    light_vertices: &[LightVertex],
    pick: usize,
    at: &CameraVertex<'_>,
    max_depth: u32,
) -> Option<Connection> {
    let vertex = light_vertices.get(pick)?;
    // The path tracer reaches the light at bounce `bounce + 2 + delta bounces`; it traces
    // bounces below `max_depth` only.
    if at.bounce + 2 + vertex.delta_bounces >= max_depth {
        return None;
    }
    let to_vertex = vertex.p - at.p;
    let distance_squared = to_vertex.length_squared();
    let distance = distance_squared.sqrt();
    let w = to_vertex / distance;
    // At x2: the side rule of the path tracer's BSDF sample toward w.
    let wi_local = at.frame.to_local(w);
    let through = wi_local.z * at.wo_local.z < 0.0;
    if ((at.ng.dot(w) > 0.0) == at.front) == through {
        return None;
    }
    let f2 = at.bsdf.eval(at.wo_local, wi_local);
    if f2.max_element() <= 0.0 {
        return None;
    }
    // At x1: the material seen from x2, and the side rule of the path tracer's sample there.
    let (slot, material) = (vertex.slot as usize, vertex.material as usize);
    let ng1 = vertex.ng;
    let wo1 = -w;
    let ns1 = surface::shading_normal(scene, slot, vertex.barycentric, ng1);
    let (bsdf1, ns1) =
        surface::textured_surface(scene, material, slot, vertex.barycentric, ng1, ns1, wo1);
    if bsdf1.is_black() {
        return None;
    }
    let frame1 = Frame::from_normal(ns1);
    let (wo1_local, wi1_local) = (frame1.to_local(wo1), frame1.to_local(vertex.to_light));
    let through1 = wi1_local.z * wo1_local.z < 0.0;
    if ((ng1.dot(vertex.to_light) > 0.0) == (ng1.dot(wo1) > 0.0)) == through1 {
        return None;
    }
    let f1 = bsdf1.eval(wo1_local, wi1_local);
    if f1.max_element() <= 0.0 {
        return None;
    }
    let (cos_to_x2, cos_to_light) = (ng1.dot(wo1).abs(), ng1.dot(vertex.to_light).abs());
    let weight = match scene.lights.lights.get(vertex.light as usize) {
        None => 1.0, // a punctual light: no other strategy finds these paths
        Some(light) => {
            let factor = camera_vertex_factor(
                cos_to_light,
                bsdf1.pdf(wo1_local, wi1_local),
                cos_to_x2,
                distance,
                at.bsdf.pdf(at.wo_local, wi_local),
            );
            if factor == 0.0 {
                return None; // a degenerate point: the path tracer's weight is 1 there
            }
            light_tracer_weight(mis_ratio(light, factor))
        }
    };
    let contribution = at.throughput
        * f2
        * f1
        * vertex.throughput
        * (wi_local.z.abs() * cos_to_x2 / distance_squared
            * (wi1_local.z.abs() / cos_to_light)
            * weight);
    (contribution.is_finite() && contribution.max_element() > 0.0).then_some(Connection {
        target: vertex.p,
        through,
        contribution,
    })
}

/// [`NO_EMITTER`], the light of a vertex whose path left a punctual light.
pub(super) const PUNCTUAL: u32 = NO_EMITTER;
