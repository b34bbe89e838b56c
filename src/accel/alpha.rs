//! Alpha coverage (glTF `alphaMode` MASK and BLEND): which surfaces a ray passes through.
//! The coverage at a point is the material's alpha factor x its base-colour texture's alpha
//! x the vertex colour's alpha; MASK keeps a hit where it reaches the cutoff, BLEND keeps it
//! with probability equal to it (stochastic transparency, unbiased in a path tracer), from a
//! hash of the path's key, the bounce, the ray and the slot, so the image does not depend on
//! the thread count. This module holds the records and [`alpha_covers`], the test at one
//! point; the traversals ask `RenderScene::covers` (which looks the point's alpha up) only
//! for slots flagged in `RenderScene::alpha_of_slot`, and only in scenes that have some (see
//! [`super::ClosestHitPath::AlphaTested`]): opaque scenes run the paths they always ran.

use crate::math::rng::coverage_uniform;
use crate::scene::AlphaMode;
use crate::texture::TextureRef;

/// In `RenderScene::alpha_of_slot`: the slot is opaque.
pub const OPAQUE: u32 = u32::MAX;

/// How one group of primitives (a mesh) is covered.
#[derive(Clone, Copy, Debug)]
pub struct AlphaRecord {
    /// MASK (with its cutoff) or BLEND.
    pub mode: AlphaMode,
    /// The material's alpha factor.
    pub factor: f32,
    /// The base-colour texture, when it has non-opaque texels (else unset).
    pub texture: TextureRef,
    /// Whether the vertex colours' alpha counts (the mesh has some below 1).
    pub vertex_alpha: bool,
}

/// Which ray of a path meets a surface, for the BLEND coverage's random number.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayKey {
    /// The path's random-number key.
    pub path: u64,
    /// The bounce.
    pub bounce: u32,
    /// 0 for the bounce's ray, 1 + k for its shadow ray k.
    pub ray: u32,
}

/// Whether a ray of `key` stops at the point of `slot` whose coverage is `alpha`, under
/// `mode`: at or above the cutoff (MASK), or with probability `alpha` (BLEND).
#[inline]
pub fn alpha_covers(mode: AlphaMode, alpha: f32, slot: u32, key: RayKey) -> bool {
    match mode {
        AlphaMode::Mask { cutoff } => alpha >= cutoff,
        AlphaMode::Blend => coverage_uniform(key.path, key.bounce, key.ray, slot) < alpha,
    }
}
