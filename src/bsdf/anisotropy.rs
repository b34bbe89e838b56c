//! `KHR_materials_anisotropy` on the metallic-roughness BSDF: the strength and tangent
//! direction of a material's anisotropic roughness, and the two alphas they make of the
//! isotropic alpha, by the glTF specification's mapping or by Cycles' Principled BSDF
//! (docs/importing.md, "Anisotropy", says which files get which):
//!
//! ```text
//! glTF:    alpha_t = mix(alpha, 1, strength^2),  alpha_b = alpha
//! Cycles:  aspect = sqrt(1 - 0.9 strength),  alpha_t = alpha / aspect,  alpha_b = alpha aspect
//! ```
//!
//! (`t` along the anisotropy direction, `b` across it; both clamped to
//! [`super::microfacet::MIN_ALPHA`], 1.) A material holds the direction in its tangent space
//! (`anisotropyRotation`); the shade stage turns it into the shading frame of each hit
//! (`wavefront::surface`), or makes the hit isotropic where the tangent frame degenerates.

use super::microfacet::{Ggx, MIN_ALPHA};
use crate::math::Vec2;

/// Which formula turns strength and alpha into the two alphas (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnisotropyMapping {
    /// The glTF specification's: rougher along the direction, unchanged across it.
    Gltf,
    /// Cycles' Principled BSDF (Blender's importer passes the strength through as
    /// "Anisotropic"): rougher along, smoother across, the product of the alphas kept.
    Cycles,
}

/// The anisotropy of a metallic-roughness surface; [`Anisotropy::NONE`] for isotropic ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anisotropy {
    /// `anisotropyStrength` (times the texture's blue) in [0, 1]; 0 is isotropic.
    pub strength: f32,
    /// The formula of the two alphas.
    pub mapping: AnisotropyMapping,
    /// Unit `(cos, sin)` of the direction: in the material, from the tangent toward the
    /// bitangent (`anisotropyRotation`); at a hit, from the local frame's `+x` toward `+y`.
    pub direction: Vec2,
}

impl Anisotropy {
    /// Isotropic.
    pub const NONE: Anisotropy = Anisotropy {
        strength: 0.0,
        mapping: AnisotropyMapping::Gltf,
        direction: Vec2::X,
    };

    /// Whether the roughness is the same in every direction.
    #[inline]
    pub fn is_none(&self) -> bool {
        self.strength == 0.0
    }

    /// Alpha along and across the direction for the isotropic `alpha` (module doc).
    #[inline]
    pub fn alphas(&self, alpha: f32) -> Vec2 {
        let s = self.strength;
        let (along, across) = match self.mapping {
            AnisotropyMapping::Gltf => (alpha + (1.0 - alpha) * s * s, alpha),
            AnisotropyMapping::Cycles => {
                let aspect = (1.0 - 0.9 * s).sqrt();
                (alpha / aspect, alpha * aspect)
            }
        };
        Vec2::new(along, across).clamp(Vec2::splat(MIN_ALPHA), Vec2::ONE)
    }

    /// The GGX distribution of a lobe with isotropic `alpha` under this anisotropy.
    #[inline]
    pub fn ggx(&self, alpha: f32) -> Ggx {
        if self.is_none() {
            Ggx::Isotropic(alpha)
        } else {
            Ggx::Anisotropic {
                alpha: self.alphas(alpha),
                tangent: self.direction,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mappings_follow_their_formulas() {
        let gltf = Anisotropy {
            strength: 0.5,
            ..Anisotropy::NONE
        };
        let a = gltf.alphas(0.2);
        assert!((a.x - (0.2 + 0.8 * 0.25)).abs() < 1e-6 && a.y == 0.2);
        let cycles = Anisotropy {
            mapping: AnisotropyMapping::Cycles,
            ..gltf
        };
        let a = cycles.alphas(0.2);
        let aspect = 0.55f32.sqrt();
        assert!((a.x - 0.2 / aspect).abs() < 1e-6 && (a.y - 0.2 * aspect).abs() < 1e-6);
        // Cycles keeps the product (the albedo table's alpha) while neither alpha clamps.
        assert!((a.x * a.y - 0.04).abs() < 1e-6);
        // Full strength, full roughness: clamped to 1.
        let full = Anisotropy {
            strength: 1.0,
            ..cycles
        };
        assert_eq!(full.alphas(1.0).x, 1.0);
        assert_eq!(Anisotropy::NONE.ggx(0.3), Ggx::Isotropic(0.3));
    }
}
