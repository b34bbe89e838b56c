//! Alpha coverage (glTF `alphaMode` MASK and BLEND): which surfaces a ray passes through.
//! The coverage at a point is the material's alpha factor x its base-colour texture's alpha
//! x the vertex colour's alpha; MASK keeps a hit where it reaches the cutoff, BLEND keeps it
//! with probability equal to it (stochastic transparency, unbiased in a path tracer), from a
//! hash of the path's key, the bounce, the ray and the slot, so the image does not depend on
//! the thread count. The traversals ask [`RenderScene::covers`] only for slots flagged in
//! `RenderScene::alpha_of_slot`, and only in scenes that have some (see
//! [`crate::accel::ClosestHitPath::AlphaTested`]): opaque scenes run the paths they always ran.

use crate::math::rng::coverage_uniform;
use crate::math::{Vec2, Vec3A};
use crate::render_scene::RenderScene;
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

impl RenderScene {
    /// Whether the ray `origin + t direction` of `key`, which hits the primitive in `slot`
    /// (a flagged slot: `alpha_of_slot[slot] != OPAQUE`), stops there.
    #[inline(never)]
    pub(crate) fn covers(&self, slot: u32, origin: Vec3A, direction: Vec3A, key: RayKey) -> bool {
        let record = &self.alpha_records[self.alpha_of_slot[slot as usize] as usize];
        let s = slot as usize;
        let mut alpha = record.factor;
        if record.texture.is_set() || record.vertex_alpha {
            let b = self.shape(s).barycentric(origin, direction);
            let at = |v: [f32; 3], b: Vec2| v[0] * (1.0 - b.x - b.y) + v[1] * b.x + v[2] * b.y;
            if record.vertex_alpha {
                alpha *= at(self.vertex_colors[s].map(|c| c.w), b);
            }
            if record.texture.is_set() {
                let uvs = self.vertex_uvs[s];
                let uv = uvs[0] * (1.0 - b.x - b.y) + uvs[1] * b.x + uvs[2] * b.y;
                let t = &record.texture;
                alpha *= self.textures[t.texture as usize].lookup_alpha(t.uv_transform.apply(uv));
            }
        }
        match record.mode {
            AlphaMode::Mask { cutoff } => alpha >= cutoff,
            AlphaMode::Blend => coverage_uniform(key.path, key.bounce, key.ray, slot) < alpha,
        }
    }
}
