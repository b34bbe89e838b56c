//! Ray cones: the footprint of a path's rays on the surfaces they hit, which chooses the
//! mipmap level of texture lookups (Akenine-Möller et al., "Texture Level of Detail
//! Strategies for Real-Time Ray Tracing", Ray Tracing Gems, 2019). Each path carries a cone
//! (a width at its ray's origin and a spread angle); the camera gives the first (a pinhole's
//! spread is one pixel's angle, an orthographic camera's width one pixel's size); the cone
//! keeps its spread through delta bounces (mirrors and smooth glass, taken as flat) and
//! widens at non-delta ones to the angle of the sampled lobe (`1 / sqrt(pdf)`, the side of the
//! solid angle the density gives one sample), so that textures seen after a diffuse bounce
//! are read from coarse levels and those in a sharp glossy reflection from fine ones. Pure
//! math; the wavefront stages hold the cones and `wavefront/surface.rs` asks for the level.

/// The widest spread a non-delta bounce gives a cone (radians per unit distance).
pub const MAX_SPREAD: f32 = 1.0;

/// A path's ray cone: its width at the ray's origin and how fast it grows with distance.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayCone {
    /// Width (world units) at the ray's origin.
    pub width: f32,
    /// Spread angle (radians): the width grows by this per unit distance.
    pub spread: f32,
}

impl RayCone {
    /// The cone's width at distance `t` along the ray.
    #[inline(always)]
    pub fn width_at(self, t: f32) -> f32 {
        (self.width + self.spread * t).abs()
    }

    /// The cone of the next ray after a bounce at distance `t`: the width there; the spread
    /// kept after a delta bounce, widened to the sampled lobe's angle (`1 / sqrt(pdf)`,
    /// at most [`MAX_SPREAD`]) after a non-delta one.
    #[inline(always)]
    pub fn after_bounce(self, t: f32, is_delta: bool, pdf: f32) -> RayCone {
        let lobe = if is_delta || pdf.is_nan() || pdf <= 0.0 {
            0.0
        } else {
            pdf.sqrt().recip().min(MAX_SPREAD)
        };
        RayCone {
            width: self.width_at(t),
            spread: self.spread.max(lobe),
        }
    }
}

/// `log2` of the width, in the mesh's texture coordinates, of the footprint of a cone of
/// `width` meeting a triangle at `cos` (the cosine between the ray and the geometric
/// normal), the triangle's doubled areas being `world_area2` and `uv_area2`: the level of
/// detail before the texture's own size, `0.5 log2(uv / world) + log2(width / sqrt(cos))`.
/// The footprint is an ellipse `width` across and `width / cos` long; the isotropic filter
/// takes the side of a square of its area, where the paper takes its long axis
/// (`log2(width / cos)`), which at grazing angles blurred the checkerboard of
/// `tests/e2e/texture_filtering.rs` across the footprint (docs/importing.md, Texture
/// filtering). Negative infinity (level 0) where there is no footprint (zero width or no
/// texture coordinates); positive infinity (the last level) at a grazing cosine of zero.
#[inline]
pub fn log2_uv_footprint(width: f32, cos: f32, world_area2: f32, uv_area2: f32) -> f32 {
    0.5 * (uv_area2 / world_area2).log2() + width.log2() - 0.5 * cos.abs().log2()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cone_grows_with_distance_and_widens_at_rough_bounces_only() {
        let camera = RayCone {
            width: 0.0,
            spread: 0.01,
        };
        assert_eq!(camera.width_at(3.0), 0.03);
        let mirror = camera.after_bounce(3.0, true, 0.0);
        assert_eq!((mirror.width, mirror.spread), (0.03, 0.01));
        // A diffuse lobe (pdf ~ 1/pi) spreads as wide as allowed; a sharp glossy one
        // (pdf 1e6) keeps the camera's spread, which is wider.
        assert_eq!(camera.after_bounce(3.0, false, 0.3).spread, MAX_SPREAD);
        assert_eq!(camera.after_bounce(3.0, false, 1e6).spread, 0.01);
        assert_eq!(camera.after_bounce(3.0, false, 400.0).spread, 0.05);
        assert_eq!(camera.after_bounce(3.0, false, f32::NAN).spread, 0.01);
    }

    #[test]
    fn the_footprint_doubles_with_the_width_and_at_a_quarter_cosine() {
        // A unit right triangle mapped to a quarter of the texture square: 0.5 uv per world
        // unit along each axis.
        let (world, uv) = (1.0, 0.25);
        let head_on = log2_uv_footprint(0.5, 1.0, world, uv);
        assert!(
            (head_on - -2.0).abs() < 1e-6,
            "0.5 world = 0.25 uv: {head_on}"
        );
        assert!((log2_uv_footprint(1.0, 1.0, world, uv) - (head_on + 1.0)).abs() < 1e-6);
        assert!((log2_uv_footprint(0.5, 0.25, world, uv) - (head_on + 1.0)).abs() < 1e-6);
        assert_eq!(log2_uv_footprint(0.0, 1.0, world, uv), f32::NEG_INFINITY);
        assert_eq!(log2_uv_footprint(0.5, 1.0, world, 0.0), f32::NEG_INFINITY);
        assert_eq!(log2_uv_footprint(0.5, 0.0, world, uv), f32::INFINITY);
    }
}
