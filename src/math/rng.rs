//! Counter-based random numbers: every number is a pure function of
//! (seed, pixel, sample index, bounce, dimension), so an image never depends on the thread
//! count, the batch size or the order in which work is scheduled.
//!
//! The dimension table below is the single place that says which number is used for what.

use super::Vec2;

/// The default seed of the CLI and of the tests.
pub const DEFAULT_SEED: u64 = 0x5EED_2026;

/// Random-number dimensions used within one bounce of a path.
///
/// Shadow ray `j` of a bounce uses `SHADOW_FIRST + 3 j` (light choice) and the two after it
/// (point on the light), so any number of shadow rays fits without overlapping.
pub mod dim {
    /// Pixel jitter of the camera ray (2 numbers, bounce 0 only).
    pub const PIXEL_JITTER: u32 = 0;
    /// Lobe choice of the BSDF sample (reflect or refract).
    pub const BSDF_LOBE: u32 = 2;
    /// Direction of the BSDF sample (2 numbers).
    pub const BSDF_DIRECTION: u32 = 3;
    /// Russian roulette.
    pub const ROULETTE: u32 = 5;
    /// First dimension of the shadow rays: light choice, then 2 numbers for the point.
    pub const SHADOW_FIRST: u32 = 6;
    /// Dimensions consumed by each shadow ray.
    pub const PER_SHADOW_RAY: u32 = 3;
}

/// SplitMix64's finaliser: a bijective 64-bit mixer with full avalanche.
#[inline]
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The key of one path sample: hashes (seed, pixel, sample index) once, so that each random
/// number afterwards costs a single mix.
#[inline]
pub fn path_key(seed: u64, pixel: u32, sample_index: u32) -> u64 {
    let h = mix64(seed ^ 0x9E37_79B9_7F4A_7C15);
    mix64(h ^ ((pixel as u64) << 32 | sample_index as u64))
}

/// A uniform number in [0, 1) for `dimension` of `bounce` of the path with key `key`.
#[inline]
pub fn uniform(key: u64, bounce: u32, dimension: u32) -> f32 {
    let h = mix64(key ^ mix64((bounce as u64) << 32 | dimension as u64));
    // 24 high bits: every value is exactly representable and strictly below 1.
    (h >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Two uniform numbers: `dimension` and `dimension + 1`.
#[inline]
pub fn uniform2(key: u64, bounce: u32, dimension: u32) -> Vec2 {
    Vec2::new(
        uniform(key, bounce, dimension),
        uniform(key, bounce, dimension + 1),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_inputs_same_numbers_and_range() {
        let k = path_key(DEFAULT_SEED, 17, 3);
        assert_eq!(
            uniform(k, 2, 5),
            uniform(path_key(DEFAULT_SEED, 17, 3), 2, 5)
        );
        assert_ne!(k, path_key(DEFAULT_SEED, 17, 4));
        assert_ne!(k, path_key(DEFAULT_SEED + 1, 17, 3));
        for d in 0..1000 {
            let u = uniform(k, d / 10, d);
            assert!((0.0..1.0).contains(&u));
        }
    }

    #[test]
    fn moments_and_correlation_match_uniform() {
        // Mean 1/2, variance 1/12, and no correlation between neighbouring dimensions or pixels.
        let n = 200_000;
        let (mut s, mut s2, mut sxy) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let k = path_key(7, i, 0);
            let a = uniform(k, 0, 0) as f64;
            let b = uniform(path_key(7, i + 1, 0), 0, 0) as f64;
            let c = uniform(k, 0, 1) as f64;
            s += a;
            s2 += a * a;
            sxy += (a - 0.5) * (b - 0.5) + (a - 0.5) * (c - 0.5);
        }
        let n = n as f64;
        let mean = s / n;
        let var = s2 / n - mean * mean;
        // Standard errors: mean sqrt(1/12/n) ~ 6.5e-4; covariance ~ 1/12/sqrt(n) ~ 1.9e-4 each.
        assert!(
            (mean - 0.5).abs() < 4.0 * (1.0 / 12.0 / n).sqrt(),
            "mean {mean}"
        );
        assert!((var - 1.0 / 12.0).abs() < 2e-3, "variance {var}");
        assert!(
            (sxy / n).abs() < 4.0 * 2f64.sqrt() / 12.0 / n.sqrt(),
            "covariance {}",
            sxy / n
        );
    }
}
