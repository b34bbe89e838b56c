//! Blender's *Bump Map Correction* (Cycles, on by default in Blender 4.5): a shadowing term on
//! the diffuse lobe of a surface whose shading normal `N` (normal-mapped) differs from the
//! smooth normal `Ns` (interpolated), from Conty Estevez, Lecocq and Stein 2019, "A
//! Microfacet-Based Shadowing Function to Solve the Bump Terminator Problem":
//!
//! ```text
//! factor(wi) = G1(alpha^2, |Ns . wi|) = 2 / (1 + sqrt(1 + alpha^2 tan^2(theta_i)))
//! alpha^2    = min(tan^2(d) / 8, 1),   d = angle(N, Ns),   theta_i = angle(Ns, wi)
//! ```
//!
//! It darkens light arriving at grazing angles to the smooth surface, where a mapped normal
//! tilted toward the light would otherwise make the terminator a hard edge. It depends on the
//! light direction `wi` only, so the lobe's sampling is unchanged; the factor multiplies the
//! diffuse lobe's value, hence both light samples and BSDF samples (weights `f cos / pdf`), and
//! is 1 where `N` = `Ns` (no map, or a mapped normal refused).

use crate::math::frame::Frame;
use crate::math::{Vec3, Vec3A};

/// The term's parameters at one shading point: the smooth normal in the local frame of the
/// mapped normal, and `alpha^2` (0: no correction).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BumpShadowing {
    /// `Ns` in the shading frame (`+z` = the mapped normal `N`).
    pub smooth_normal: Vec3,
    /// `min(tan^2(d) / 8, 1)`; 0 turns the term off.
    pub alpha2: f32,
}

impl Default for BumpShadowing {
    /// No correction.
    fn default() -> Self {
        BumpShadowing::NONE
    }
}

impl BumpShadowing {
    /// No correction (the shading normal is the smooth one).
    pub const NONE: BumpShadowing = BumpShadowing {
        smooth_normal: Vec3::Z,
        alpha2: 0.0,
    };

    /// The term where the shading normal `mapped` (unit, world space) replaces the smooth
    /// normal `smooth` (unit, world space); the local frame is `Frame::from_normal(mapped)`,
    /// the one the BSDF is evaluated in.
    pub fn new(mapped: Vec3A, smooth: Vec3A) -> Self {
        let local = Frame::from_normal(mapped).to_local(smooth);
        let cos2 = (local.z * local.z).min(1.0);
        if cos2 >= 1.0 || cos2 <= 0.0 {
            return BumpShadowing::NONE; // equal normals, or a degenerate (perpendicular) pair
        }
        let tan2 = (1.0 - cos2) / cos2;
        BumpShadowing {
            smooth_normal: Vec3::from(local),
            alpha2: (0.125 * tan2).min(1.0),
        }
    }

    /// The factor on the diffuse lobe for light direction `wi` (local frame).
    #[inline]
    pub fn factor(&self, wi: Vec3A) -> f32 {
        if self.alpha2 == 0.0 {
            return 1.0;
        }
        let c = Vec3A::from(self.smooth_normal).dot(wi).abs().max(1e-6);
        let c2 = (c * c).min(1.0);
        let tan2 = (1.0 - c2) / c2;
        2.0 / (1.0 + (1.0 + self.alpha2 * tan2).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_normals_change_nothing_and_a_tilt_darkens_grazing_light_only() {
        let n = Vec3A::new(0.2, -0.3, 0.9).normalize();
        assert_eq!(BumpShadowing::new(n, n), BumpShadowing::NONE);
        assert_eq!(BumpShadowing::NONE.factor(Vec3A::new(1.0, 0.0, 0.0)), 1.0);
        // N tilted 30 degrees from Ns = +z in the xz plane: alpha^2 = tan^2(30 deg) / 8 = 1/24.
        let d = 30f32.to_radians();
        let mapped = Vec3A::new(d.sin(), 0.0, d.cos());
        let term = BumpShadowing::new(mapped, Vec3A::Z);
        assert!((term.alpha2 - 1.0 / 24.0).abs() < 1e-6, "{}", term.alpha2);
        let frame = Frame::from_normal(mapped);
        // Light along Ns: no shadowing. Light 60 degrees from Ns: tan^2 = 3,
        // G1 = 2 / (1 + sqrt(1 + 3 / 24)) = 0.97092.
        assert!((term.factor(frame.to_local(Vec3A::Z)) - 1.0).abs() < 1e-6);
        let sixty = 60f32.to_radians();
        let wi = frame.to_local(Vec3A::new(sixty.sin(), 0.0, sixty.cos()));
        let expected = 2.0 / (1.0 + (1.0f32 + 3.0 / 24.0).sqrt());
        assert!(
            (term.factor(wi) - expected).abs() < 1e-5,
            "{}",
            term.factor(wi)
        );
        // Steep tilts saturate at alpha^2 = 1.
        let steep = Vec3A::new(0.95, 0.0, 0.1).normalize();
        assert_eq!(BumpShadowing::new(steep, Vec3A::Z).alpha2, 1.0);
    }
}
