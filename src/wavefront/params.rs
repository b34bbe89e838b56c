//! What the shade stage and its helpers need to know besides the scene: the bounce, the
//! settings that shape the estimator, and the pass's light paths for caustics.

use super::light_vertices::LightVertex;
use super::merging::LightVertexGrid;
use crate::camera::PinholeCamera;
use crate::math::rng::Sampler;

/// What shading needs to know besides the scene.
#[derive(Clone, Copy, Debug)]
pub struct ShadeParams<'a> {
    /// Index of the bounce: 0 for camera rays.
    pub bounce: u32,
    /// Shadow rays per non-delta hit; 0 disables next-event estimation.
    pub shadow_rays: u32,
    /// Whether light and BSDF samples are combined by multiple importance sampling.
    pub mis: bool,
    /// Bounces before Russian roulette may end a path.
    pub roulette_min_bounces: u32,
    /// Paths are cut (and counted) when they reach this depth.
    pub max_depth: u32,
    /// Where the random numbers come from.
    pub sampler: Sampler,
    /// With light paths for caustics in the pass: what weights the caustic paths the path
    /// tracer finds against them ([`super::light_paths`]), and the light vertices its
    /// vertices connect to ([`super::light_vertices`]).
    pub caustics: Option<CausticWeights<'a>>,
}

/// What the path tracer needs to weight the caustic paths it finds against the light paths
/// of the pass, and the light vertices its vertices connect to.
#[derive(Clone, Copy, Debug)]
pub struct CausticWeights<'a> {
    /// Light paths traced in the pass: the `n` of the balance heuristic, and the range of a
    /// camera vertex's pick among them.
    pub light_path_count: u64,
    /// The camera, for the density of its rays.
    pub camera: PinholeCamera,
    /// Whether camera vertices connect to the light vertices (caustics seen after a diffuse
    /// bounce, [`super::light_vertices`]).
    pub connections: bool,
    /// The pass's light vertices, in path order (empty without connections and merging).
    pub light_vertices: &'a [LightVertex],
    /// With merging of light vertices at camera vertices reached through a delta bounce
    /// (caustics seen behind a mirror or glass, [`super::merging`]): the pass's light vertices
    /// in their grid, which holds the pass's merge radius.
    pub merge_grid: Option<&'a LightVertexGrid>,
}
