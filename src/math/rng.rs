//! Counter-based random numbers: every number is a pure function of
//! (seed, pixel, sample index, bounce, dimension), so an image never depends on the thread
//! count, the batch size or the order in which work is scheduled.
//!
//! The dimension table below is the single place that says which number is used for what.

use super::Vec2;
use super::sobol;

/// The default seed of the CLI and of the tests.
pub const DEFAULT_SEED: u64 = 0x5EED_2026;

/// Random-number dimensions used within one bounce of a path.
///
/// The shadow rays of a bounce take the points of one lattice, shifted by the three numbers
/// of dimension `LIGHT_SAMPLES` (see [`super::sampling::Rank1Lattice`]), so any number of
/// shadow rays costs one hash.
pub mod dim {
    /// Pixel jitter of the camera ray (2 numbers, bounce 0 only).
    pub const PIXEL_JITTER: u32 = 0;
    /// Lobe choice of the BSDF sample (reflect or refract).
    pub const BSDF_LOBE: u32 = 2;
    /// Direction of the BSDF sample (2 numbers).
    pub const BSDF_DIRECTION: u32 = 3;
    /// Russian roulette.
    pub const ROULETTE: u32 = 5;
    /// The shift of the shadow rays' lattice (light choice and point on the light, 3 numbers
    /// from one hash).
    pub const LIGHT_SAMPLES: u32 = 6;
    /// Which light vertex of the pass a camera vertex connects to (an index, always from
    /// independent bits: see [`super::Sampler::index`]).
    pub const LIGHT_VERTEX: u32 = 8;
}

/// SplitMix64's finaliser: a bijective 64-bit mixer with full avalanche.
#[inline]
pub(super) fn mix64(mut z: u64) -> u64 {
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

/// 64 random bits for `dimension` of `bounce` of the path with key `key`.
#[inline]
fn bits(key: u64, bounce: u32, dimension: u32) -> u64 {
    mix64(key ^ mix64((bounce as u64) << 32 | dimension as u64))
}

/// The `width` bits of `h` starting at bit `shift`, as a number in [0, 1): every value is
/// exactly representable in an `f32` (width <= 24) and strictly below 1.
#[inline(always)]
fn unit_float(h: u64, shift: u32, width: u32) -> f32 {
    ((h >> shift) & ((1 << width) - 1)) as f32 * (1.0 / (1u64 << width) as f32)
}

/// A uniform number in [0, 1) for `dimension` of `bounce` of the path with key `key`.
#[inline]
pub fn uniform(key: u64, bounce: u32, dimension: u32) -> f32 {
    unit_float(bits(key, bounce, dimension), 40, 24)
}

/// A uniform number in [0, 1) for the alpha coverage of primitive `slot` met by ray `ray` of
/// `bounce` of the path with key `key` (ray 0: the bounce's ray; 1 + k: its shadow ray k).
/// Its own stream (a salted key), so that it is independent of the path's other numbers.
#[inline]
pub fn coverage_uniform(key: u64, bounce: u32, ray: u32, slot: u32) -> f32 {
    const ALPHA_SALT: u64 = 0xA1FA_C0DE_5EED_0001;
    unit_float(
        mix64(bits(key ^ ALPHA_SALT, bounce, ray) ^ slot as u64),
        40,
        24,
    )
}

/// Three uniform numbers from the one hash of `dimension` of `bounce`, for light samples:
/// the first (which light) with 24 bits, the other two (where on it) with 20 bits each.
#[inline]
pub fn uniform3(key: u64, bounce: u32, dimension: u32) -> (f32, Vec2) {
    let h = bits(key, bounce, dimension);
    (
        unit_float(h, 40, 24),
        Vec2::new(unit_float(h, 20, 20), unit_float(h, 0, 20)),
    )
}

/// An index uniform in `0..n` for `dimension` of `bounce` of the path with key `key`: the
/// high half of 64 random bits times `n`, uniform to within `n / 2^64` for any `n`.
#[inline]
pub fn uniform_index(key: u64, bounce: u32, dimension: u32, n: u64) -> u64 {
    ((bits(key, bounce, dimension) as u128 * n as u128) >> 64) as u64
}

/// Two uniform numbers: `dimension` and `dimension + 1`.
#[inline]
pub fn uniform2(key: u64, bounce: u32, dimension: u32) -> Vec2 {
    Vec2::new(
        uniform(key, bounce, dimension),
        uniform(key, bounce, dimension + 1),
    )
}

/// Which numbers drive the paths. Either way every number is a pure function of (seed, pixel,
/// sample index, bounce, dimension): images never depend on threads or batches.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampler {
    /// Independent uniform numbers from a counter-based hash.
    Independent,
    /// Owen-scrambled Sobol points (see [`sobol`]): the samples of a pixel are stratified in
    /// every pattern of [`dim`] (the camera jitter, the BSDF lobe and direction, roulette, the
    /// shift of the shadow rays' lattice) for the first [`SOBOL_BOUNCES`] bounces;
    /// independent numbers past them. The default.
    #[default]
    Sobol,
}

/// Bounces whose numbers the Sobol sampler stratifies; later bounces add little to the
/// image and take independent numbers.
pub const SOBOL_BOUNCES: u32 = 8;

/// Patterns a bounce may use with the Sobol sampler: one per dimension of [`dim`], plus the
/// point on the light after `LIGHT_SAMPLES`.
const PATTERNS_PER_BOUNCE: u32 = 8;

impl Sampler {
    /// The key of one path sample. Independent: a hash of (seed, pixel, sample index). Sobol:
    /// the pixel's scramble seed (distinct for every pixel) in the high half, the sample index
    /// with its bits reversed (the form the sampler works on) in the low half.
    #[inline]
    pub fn path_key(self, seed: u64, pixel: u32, sample_index: u32) -> u64 {
        match self {
            Sampler::Independent => path_key(seed, pixel, sample_index),
            Sampler::Sobol => {
                (sobol::pixel_seed(seed, pixel) as u64) << 32 | sample_index.reverse_bits() as u64
            }
        }
    }

    /// The Sobol pattern of `dimension` of `bounce` and the path's (pixel seed, reversed
    /// sample index), or `None` past the bounces it covers.
    #[inline(always)]
    fn sobol_pattern(self, key: u64, bounce: u32, dimension: u32) -> Option<(u32, u32, u32)> {
        (self == Sampler::Sobol && bounce < SOBOL_BOUNCES).then(|| {
            debug_assert!(dimension < PATTERNS_PER_BOUNCE);
            let pattern = bounce * PATTERNS_PER_BOUNCE + dimension;
            ((key >> 32) as u32, key as u32, pattern)
        })
    }

    /// The key independent numbers use: a Sobol key is structured, so it is hashed first.
    #[inline(always)]
    fn independent_key(self, key: u64) -> u64 {
        match self {
            Sampler::Independent => key,
            Sampler::Sobol => mix64(key ^ 0xD1B5_4A32_D192_ED03),
        }
    }

    /// A uniform number in [0, 1) for `dimension` of `bounce` of the path with key `key`.
    #[inline]
    pub fn uniform(self, key: u64, bounce: u32, dimension: u32) -> f32 {
        match self.sobol_pattern(key, bounce, dimension) {
            Some((pixel, index, pattern)) => {
                sobol::sample_1d_of_reversed_index(pixel, index, pattern)
            }
            None => uniform(self.independent_key(key), bounce, dimension),
        }
    }

    /// An index uniform in `0..n` for `dimension` of `bounce`, from independent bits with
    /// either sampler (a choice among `n` things gains nothing from a stratified pattern of
    /// 24-bit numbers, which could not even reach every index of a large `n`).
    #[inline]
    pub fn index(self, key: u64, bounce: u32, dimension: u32, n: u64) -> u64 {
        uniform_index(self.independent_key(key), bounce, dimension, n)
    }

    /// Two uniform numbers for `dimension` of `bounce` (with the Sobol sampler, one 2-D
    /// pattern; independent: dimensions `dimension` and `dimension + 1`).
    #[inline(always)]
    pub fn uniform2(self, key: u64, bounce: u32, dimension: u32) -> Vec2 {
        match self.sobol_pattern(key, bounce, dimension) {
            Some((pixel, index, pattern)) => {
                Vec2::from_array(sobol::sample_2d_of_reversed_index(pixel, index, pattern))
            }
            None => uniform2(self.independent_key(key), bounce, dimension),
        }
    }

    /// Three uniform numbers for light samples of `bounce` (the light choice, then the point
    /// on it; with the Sobol sampler a 1-D pattern and a 2-D one).
    #[inline(always)]
    pub fn uniform3(self, key: u64, bounce: u32, dimension: u32) -> (f32, Vec2) {
        match self.sobol_pattern(key, bounce, dimension) {
            Some((pixel, index, pattern)) => (
                sobol::sample_1d_of_reversed_index(pixel, index, pattern),
                Vec2::from_array(sobol::sample_2d_of_reversed_index(
                    pixel,
                    index,
                    pattern + 1,
                )),
            ),
            None => uniform3(self.independent_key(key), bounce, dimension),
        }
    }
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

    /// Indices fall in range and every one of a few is chosen about equally often (chi-square
    /// with 6 degrees of freedom below its 0.999 quantile, 22.46).
    #[test]
    fn indices_are_uniform() {
        let (n, draws) = (7u64, 70_000u32);
        let mut counts = [0u32; 7];
        for i in 0..draws {
            let k = uniform_index(path_key(3, i, 0), 1, dim::LIGHT_VERTEX, n);
            counts[k as usize] += 1;
        }
        let expected = draws as f64 / n as f64;
        let chi2: f64 = (counts.iter())
            .map(|&c| (c as f64 - expected).powi(2) / expected)
            .sum();
        assert!(chi2 < 22.46, "{counts:?}");
        assert_eq!(uniform_index(5, 0, 0, 1), 0);
        assert_eq!(uniform_index(5, 0, 0, 0), 0);
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

    #[test]
    fn sobol_sampler_stratifies_a_pixels_samples_and_is_independent_past_its_bounces() {
        let sampler = Sampler::Sobol;
        let keys: Vec<u64> = (0..16)
            .map(|i| sampler.path_key(DEFAULT_SEED, 123, i))
            .collect();
        // 16 samples of the camera jitter: one in each 1/4 x 1/4 cell.
        let mut cells: Vec<u32> = keys
            .iter()
            .map(|&k| {
                let u = sampler.uniform2(k, 0, dim::PIXEL_JITTER);
                (u.x * 4.0) as u32 * 4 + (u.y * 4.0) as u32
            })
            .collect();
        cells.sort_unstable();
        assert_eq!(cells, (0..16).collect::<Vec<_>>());
        // Roulette of bounce 3: one number in each 1/16.
        let mut strata: Vec<u32> = keys
            .iter()
            .map(|&k| (sampler.uniform(k, 3, dim::ROULETTE) * 16.0) as u32)
            .collect();
        strata.sort_unstable();
        assert_eq!(strata, (0..16).collect::<Vec<_>>());
        // Past the covered bounces: hashed numbers, still deterministic and in range.
        let k = keys[5];
        let late = sampler.uniform(k, SOBOL_BOUNCES, dim::ROULETTE);
        assert_eq!(late, sampler.uniform(k, SOBOL_BOUNCES, dim::ROULETTE));
        assert!((0.0..1.0).contains(&late));
        // Distinct pixels and samples have distinct keys.
        assert_ne!(k, sampler.path_key(DEFAULT_SEED, 124, 5));
        // The independent sampler is the plain hash, unchanged.
        let i = Sampler::Independent;
        assert_eq!(i.path_key(9, 1, 2), path_key(9, 1, 2));
        assert_eq!(i.uniform(77, 1, 2), uniform(77, 1, 2));
    }
}
