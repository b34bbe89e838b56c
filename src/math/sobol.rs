//! Owen-scrambled Sobol points, padded in 1-D and 2-D patterns (the scheme of Burley,
//! "Practical Hash-based Owen Scrambling", JCGT 2020): the low-discrepancy sampler.
//!
//! Each pattern (say, the camera jitter, or the BSDF direction of the first bounce) takes the
//! first one or two dimensions of the Sobol sequence, which form a (0,2)-sequence in base 2:
//! the first `2^k` samples of a pixel put exactly one point in every elementary interval of
//! area `2^-k`. Every pattern of every pixel shuffles the sample index and scrambles each
//! coordinate with its own hash-based nested uniform (Owen) scramble, so that
//! - each point is uniform on the square (estimates stay unbiased),
//! - the patterns are independent of each other (padding: no correlation between the
//!   dimensions of a path, which a higher-dimensional Sobol sequence would need its direction
//!   numbers for),
//! - and the stratification of every prefix of `2^k` samples survives: the shuffle maps
//!   indices `0..2^k` onto an aligned block of `2^k` indices, itself a (0,k,2)-net.
//!
//! Every number is a pure function of (pixel seed, sample index, pattern), as the
//! independent sampler's are: images do not depend on thread counts or batch sizes.

/// Direction numbers of the Sobol sequence's second dimension (primitive polynomial `x + 1`,
/// all initial `m` = 1: its generator matrix is Pascal's triangle modulo 2), as 32-bit
/// fractions, entry `k` for bit `k` of the index.
const SECOND_DIMENSION: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
};

/// The second dimension's generator matrix times the index, one table per byte of the
/// index (the product over GF(2) is the XOR of the four bytes' products), each entry with
/// its bits reversed: the form the scramble below works on. 4 KiB, built at compile time.
const SECOND_DIMENSION_REVERSED_BY_BYTE: [[u32; 256]; 4] = {
    let mut tables = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            let mut y = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if value >> bit & 1 == 1 {
                    y ^= SECOND_DIMENSION[byte * 8 + bit];
                }
                bit += 1;
            }
            tables[byte][value] = y.reverse_bits();
            value += 1;
        }
        byte += 1;
    }
    tables
};

/// Point `index` of the Sobol sequence's first two dimensions, as 32-bit fractions (the
/// definition; the samplers below compute the same products from tables).
#[inline]
pub fn sobol_2d(index: u32) -> [u32; 2] {
    let mut y = 0;
    let mut bits = index;
    while bits != 0 {
        let k = bits.trailing_zeros();
        y ^= SECOND_DIMENSION[k as usize];
        bits &= bits - 1;
    }
    // The first dimension is van der Corput's radical inverse.
    [index.reverse_bits(), y]
}

/// The second Sobol dimension of `index` with its bits reversed, from the byte tables.
#[inline(always)]
fn second_dimension_reversed(index: u32) -> u32 {
    let [b0, b1, b2, b3] = index.to_le_bytes();
    let t = &SECOND_DIMENSION_REVERSED_BY_BYTE;
    t[0][b0 as usize] ^ t[1][b1 as usize] ^ t[2][b2 as usize] ^ t[3][b3 as usize]
}

/// Laine and Karras's permutation with Burley's constants: every step (adding, multiplying,
/// xor with an even multiple) carries information only from lower to higher bits, so bit
/// `k` of the result depends on the seed and bits `0..=k` of `v` alone.
#[inline(always)]
fn laine_karras(mut v: u32, seed: u32) -> u32 {
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^ v.wrapping_mul(0x53a2_2864)
}

/// A hash-based nested uniform scramble of the 32-bit fraction `x`: each bit is flipped or
/// not depending on the seed and on the bits above it only (the more significant digits), as
/// Owen scrambling does; so intervals of `2^-k` are permuted among themselves at every
/// level. The bits are reversed around [`laine_karras`] (which spreads information upward).
#[inline]
pub fn nested_uniform_scramble(x: u32, seed: u32) -> u32 {
    laine_karras(x.reverse_bits(), seed).reverse_bits()
}

use super::rng::mix64;

/// A bijective 32-bit mixer (Wellons's `lowbias32`): distinct inputs give distinct seeds.
#[inline]
fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x21f0_aaad);
    x ^= x >> 15;
    x = x.wrapping_mul(0x735a_2d97);
    x ^ (x >> 15)
}

/// The three seeds of one pattern: the index shuffle and each coordinate's scramble.
#[inline]
fn pattern_seeds(pixel_seed: u32, pattern: u32) -> [u32; 3] {
    // One 64-bit mix for the three (this runs for every number a path takes).
    let h = mix64(((pixel_seed as u64) << 32 | pattern as u64) ^ 0x6A09_E667_F3BC_C909);
    let (low, high) = (h as u32, (h >> 32) as u32);
    [
        low,
        high,
        (low ^ high.rotate_left(16)).wrapping_mul(0x9e37_79b9),
    ]
}

/// A 32-bit fraction as an `f32` in [0, 1): its top 24 bits, exact and below 1.
#[inline(always)]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The seed of one pixel's patterns, distinct for every pixel of an image (a bijection of
/// the pixel index for a given render seed).
#[inline]
pub fn pixel_seed(seed: u64, pixel: u32) -> u32 {
    let s = (seed ^ (seed >> 32)) as u32;
    mix32(pixel ^ mix32(s ^ 0x68e3_1da4))
}

/// The 2-D point of sample `index` of `pattern` for the pixel of seed `pixel_seed`, in
/// [0, 1)^2.
#[inline]
pub fn sample_2d(pixel_seed: u32, index: u32, pattern: u32) -> [f32; 2] {
    sample_2d_of_reversed_index(pixel_seed, index.reverse_bits(), pattern)
}

/// [`sample_2d`] of the index whose bits reversed are `index_reversed` (the form a path
/// keeps, which saves a reversal per number).
#[inline]
pub fn sample_2d_of_reversed_index(pixel_seed: u32, index_reversed: u32, pattern: u32) -> [f32; 2] {
    let [shuffle, scramble_x, scramble_y] = pattern_seeds(pixel_seed, pattern);
    // The shuffled index is `nested_uniform_scramble(index, shuffle)`: kept bit-reversed,
    // it is also the first dimension (van der Corput's inverse reverses the bits).
    let shuffled_reversed = laine_karras(index_reversed, shuffle);
    let shuffled = shuffled_reversed.reverse_bits();
    // Each coordinate scrambled in reversed form, reversed once at the end.
    let x = laine_karras(shuffled, scramble_x).reverse_bits();
    let y = laine_karras(second_dimension_reversed(shuffled), scramble_y).reverse_bits();
    [to_unit(x), to_unit(y)]
}

/// The 1-D number of sample `index` of `pattern` for the pixel of seed `pixel_seed`, in
/// [0, 1): a scrambled van der Corput sequence, so every `2^k` samples fill every interval
/// of `2^-k` once.
#[inline]
pub fn sample_1d(pixel_seed: u32, index: u32, pattern: u32) -> f32 {
    sample_1d_of_reversed_index(pixel_seed, index.reverse_bits(), pattern)
}

/// [`sample_1d`] of the index whose bits reversed are `index_reversed`.
#[inline]
pub fn sample_1d_of_reversed_index(pixel_seed: u32, index_reversed: u32, pattern: u32) -> f32 {
    let [shuffle, scramble, _] = pattern_seeds(pixel_seed, pattern);
    // As in `sample_2d`: the radical inverse of the shuffled index, reversed, is the
    // reversed index through the shuffle's permutation.
    let shuffled = laine_karras(index_reversed, shuffle).reverse_bits();
    to_unit(laine_karras(shuffled, scramble).reverse_bits())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Whether `points` (2^m of them) put exactly one point in each elementary interval
    /// `2^-a x 2^-(m-a)` for every `a` in `0..=m`: a (0,m,2)-net in base 2.
    fn is_net(points: &[[f32; 2]]) -> bool {
        let m = points.len().trailing_zeros();
        assert_eq!(points.len(), 1 << m);
        (0..=m).all(|a| {
            let b = m - a;
            let mut seen = vec![false; points.len()];
            points.iter().all(|&[x, y]| {
                let i = (x * (1u64 << a) as f32) as usize;
                let j = (y * (1u64 << b) as f32) as usize;
                !std::mem::replace(&mut seen[i << b | j], true)
            })
        })
    }

    #[test]
    fn first_two_dimensions_are_a_zero_two_sequence() {
        // Every aligned block of 2^m points of the unscrambled sequence is a (0,m,2)-net.
        for m in 0..=10 {
            for block in [0u32, 1, 5, 1000] {
                let points: Vec<[f32; 2]> = (0..1u32 << m)
                    .map(|i| sobol_2d(block * (1 << m) + i).map(to_unit))
                    .collect();
                assert!(is_net(&points), "m {m}, block {block}");
            }
        }
        // Known first points: (0, 0), (1/2, 1/2), (1/4, 3/4), (3/4, 1/4).
        let first: Vec<[f32; 2]> = (0..4).map(|i| sobol_2d(i).map(to_unit)).collect();
        assert_eq!(first, [[0.0, 0.0], [0.5, 0.5], [0.25, 0.75], [0.75, 0.25]]);
    }

    #[test]
    fn scrambled_and_shuffled_prefixes_stay_nets() {
        // A pixel's first 2^m samples of any pattern, for every m: the property the
        // renderer relies on at any power-of-two sample count.
        for pixel in [0, 1, 77, 65_535] {
            let seed = pixel_seed(0x5EED, pixel);
            for pattern in [0, 3, 12] {
                for m in 0..=10 {
                    let points: Vec<[f32; 2]> = (0..1u32 << m)
                        .map(|i| sample_2d(seed, i, pattern))
                        .collect();
                    assert!(is_net(&points), "pixel {pixel} pattern {pattern} m {m}");
                    // In 1-D: one number in each interval of 2^-m.
                    let mut strata: Vec<u32> = (0..1u32 << m)
                        .map(|i| (sample_1d(seed, i, pattern) * (1u64 << m) as f32) as u32)
                        .collect();
                    strata.sort_unstable();
                    assert_eq!(strata, (0..1u32 << m).collect::<Vec<_>>());
                }
            }
        }
    }

    #[test]
    fn scramble_is_a_nested_permutation() {
        // Values sharing their top k bits keep sharing them, and the map is a bijection.
        for seed in [0, 1, 0xdead_beef] {
            let mut images: Vec<u32> = (0..1u32 << 12)
                .map(|x| nested_uniform_scramble(x << 20, seed) >> 20)
                .collect();
            for k in 1..12 {
                for x in (0..1u32 << 12).step_by(7) {
                    let y = x ^ 1; // differs in the lowest of the 12 bits only
                    let (a, b) = (
                        nested_uniform_scramble(x << 20, seed),
                        nested_uniform_scramble(y << 20, seed),
                    );
                    assert_eq!(a >> (32 - k), b >> (32 - k), "seed {seed} k {k} x {x}");
                }
            }
            images.sort_unstable();
            images.dedup();
            assert_eq!(images.len(), 1 << 12, "seed {seed}");
        }
    }

    #[test]
    fn fast_samples_match_their_definition() {
        // sample_2d is the Sobol point of the shuffled index, each coordinate scrambled.
        for (index, pattern) in [(0, 0), (1, 5), (77, 2), (65_535, 9), (u32::MAX, 3)] {
            let pixel = pixel_seed(1, index);
            let [shuffle, scramble_x, scramble_y] = pattern_seeds(pixel, pattern);
            let [x, y] = sobol_2d(nested_uniform_scramble(index, shuffle));
            let expected = [
                to_unit(nested_uniform_scramble(x, scramble_x)),
                to_unit(nested_uniform_scramble(y, scramble_y)),
            ];
            assert_eq!(sample_2d(pixel, index, pattern), expected);
            assert_eq!(sample_1d(pixel, index, pattern), expected[0]);
            let shuffled = nested_uniform_scramble(index, shuffle);
            assert_eq!(second_dimension_reversed(shuffled), y.reverse_bits());
        }
    }

    #[test]
    fn pixel_seeds_are_distinct() {
        let mut seeds: Vec<u32> = (0..1 << 20).map(|p| pixel_seed(42, p)).collect();
        seeds.sort_unstable();
        seeds.dedup();
        assert_eq!(seeds.len(), 1 << 20);
    }

    #[test]
    fn same_inputs_same_numbers_in_range() {
        for index in 0..2000 {
            let p = sample_2d(pixel_seed(7, 3), index, 5);
            assert_eq!(p, sample_2d(pixel_seed(7, 3), index, 5));
            assert!(p.iter().all(|x| (0.0..1.0).contains(x)), "{p:?}");
            let u = sample_1d(pixel_seed(7, 3), index, 5);
            assert!((0.0..1.0).contains(&u));
        }
    }

    /// Mean and standard error over `pixels` pixels of the `n`-sample estimate of the integral
    /// of `f` over the unit square, from pattern `pattern`.
    fn estimates(
        pixels: u32,
        n: u32,
        pattern: u32,
        f: impl Fn(f64, f64) -> f64,
    ) -> (f64, f64, f64) {
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for pixel in 0..pixels {
            let seed = pixel_seed(11, pixel);
            let estimate = (0..n)
                .map(|i| {
                    let [x, y] = sample_2d(seed, i, pattern);
                    f(x as f64, y as f64)
                })
                .sum::<f64>()
                / n as f64;
            sum += estimate;
            sum2 += estimate * estimate;
        }
        let mean = sum / pixels as f64;
        let variance = (sum2 / pixels as f64 - mean * mean).max(0.0);
        (mean, (variance / pixels as f64).sqrt(), variance)
    }

    #[test]
    fn scrambled_points_integrate_without_bias_and_with_less_variance() {
        // x y + y^2 + sin(3x) over the square: 1/4 + 1/3 + (1 - cos 3) / 3.
        let f = |x: f64, y: f64| x * y + y * y + (3.0 * x).sin();
        let exact = 0.25 + 1.0 / 3.0 + (1.0 - 3f64.cos()) / 3.0;
        for (n, pattern) in [(1, 0), (7, 2), (16, 9)] {
            let (mean, error, _) = estimates(20_000, n, pattern, f);
            assert!(
                (mean - exact).abs() < 4.0 * error + 1e-7,
                "n {n}: {mean} +- {error} vs {exact}"
            );
        }
        // With 64 samples the variance of a smooth integrand falls about as n^-3 instead of
        // independent sampling's n^-1: far below the independent variance Var[f] / 64.
        let (_, _, variance) = estimates(2_000, 64, 4, f);
        let (m1, m2) = (0..200 * 200).fold((0.0, 0.0), |(a, b), i| {
            let (x, y) = (
                (i % 200) as f64 / 200.0 + 0.0025,
                (i / 200) as f64 / 200.0 + 0.0025,
            );
            let v = f(x, y);
            (a + v / 40_000.0, b + v * v / 40_000.0)
        });
        let independent = (m2 - m1 * m1) / 64.0;
        assert!(
            variance < independent / 20.0,
            "{variance:e} vs independent {independent:e}"
        );
    }

    #[test]
    fn patterns_are_uncorrelated() {
        // The same sample index in two patterns: no correlation between their coordinates
        // (the shuffle decorrelates them), over a pixel's 1024 samples and many pixels.
        let n = 200 * 1024;
        let mut covariance = [0.0f64; 2];
        for pixel in 0..200 {
            let seed = pixel_seed(3, pixel);
            for i in 0..1024 {
                let [a, b] = sample_2d(seed, i, 0);
                let [c, d] = sample_2d(seed, i, 1);
                let e = sample_1d(seed, i, 2);
                covariance[0] += (a as f64 - 0.5) * (c as f64 - 0.5);
                covariance[1] +=
                    (b as f64 - 0.5) * (e as f64 - 0.5) + (d as f64 - 0.5) * (a as f64 - 0.5);
            }
        }
        // Standard error of a mean product: (1/12) / sqrt(n); at most two products are summed.
        for c in covariance {
            assert!(
                (c / n as f64).abs() < 4.0 * 2f64.sqrt() / 12.0 / (n as f64).sqrt(),
                "{c}"
            );
        }
    }
}
