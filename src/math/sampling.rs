//! Warps from uniform numbers to distributions, each paired with its density.
//! They take `u` in [0,1)^n and never an RNG, so tests can integrate them exactly.

use super::{Vec2, Vec3A, Vec4};
use std::f32::consts::{FRAC_1_PI, PI};

/// Cosine-weighted direction on the +z hemisphere (Malley's method on a concentric disk).
#[inline]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3A {
    let d = sample_concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3A::new(d.x, d.y, z)
}

/// Solid-angle density of [`sample_cosine_hemisphere`] for a local direction.
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform point on the unit disk, by Shirley and Chiu's concentric map (keeps strata compact).
#[inline]
pub fn sample_concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    // The angle is pi/4 (y/x), or pi/2 - pi/4 (x/y), whose cosine and sine are the sine and
    // cosine of pi/4 (x/y): both from angles within [-pi/4, pi/4]. Which one is a coin flip,
    // so both sides are chosen by selects: a branch here mispredicted at every other hit
    // (3-4% of a room render's time sat on this polynomial).
    let steep = o.x.abs() <= o.y.abs();
    let (r, other) = if steep { (o.y, o.x) } else { (o.x, o.y) };
    let (c, s) = cos_sin_within_quarter(PI / 4.0 * (other / r));
    let (cos, sin) = if steep { (s, c) } else { (c, s) };
    r * Vec2::new(cos, sin)
}

/// `(cos x, sin x)` for `|x| <= pi/4`, from their Taylor polynomials (degrees 10 and 9:
/// truncation below 2e-9, so the error is f32 rounding, a few 1e-8). Inline, unlike libm's
/// `sincosf`, whose call was 2.7% of a room render; and the same bits on every platform,
/// which libms are not.
#[inline(always)]
fn cos_sin_within_quarter(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let sin =
        x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 + x2 / 362_880.0))));
    let cos = 1.0
        + x2 * (-0.5
            + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40_320.0 - x2 / 3_628_800.0))));
    (cos, sin)
}

/// Uniform barycentrics `(b1, b2)` on a triangle, for four samples at once (lane `k` of
/// `u[0]`, `u[1]` gives lane `k` of `b1`, `b2`); the point is `v0 + b1 e1 + b2 e2` and the
/// area density `1 / area`.
#[inline]
pub fn sample_triangle(u: [Vec4; 2]) -> [Vec4; 2] {
    // Heitz's low-distortion map: no square root, no fold discontinuity. Both halves are
    // computed and selected lane by lane: a branch on the half mispredicts every other time.
    let [x, y] = u;
    let (half_x, half_y) = (x * 0.5, y * 0.5);
    let upper = y.cmpgt(x);
    [
        Vec4::select(upper, half_x, x - half_y),
        Vec4::select(upper, y - half_x, half_y),
    ]
}

/// Uniform direction on the unit sphere; density `1 / (4 pi)`.
#[inline]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// Index `i` with probability `(cdf[i] - cdf[i-1]) / cdf.last()`, for a non-decreasing `cdf`
/// whose last entry is the total. Binary search (O(log n)) beyond 17 entries.
#[inline]
pub fn sample_discrete(cdf: &[f32], u: f32) -> usize {
    debug_assert!(!cdf.is_empty());
    let target = u * cdf[cdf.len() - 1];
    let (head, _) = cdf.split_at(cdf.len() - 1);
    if head.len() <= 16 {
        // Counting is branch-free: a binary search over a few entries mispredicts half its
        // branches (a quad light's two triangles are chosen by a coin flip).
        head.iter().map(|&c| (c <= target) as usize).sum()
    } else {
        head.partition_point(|&c| c <= target)
    }
}

/// A rank-1 lattice of `n` points in `[0, 1)^3`: point `j` is `(j g / n) mod 1` per
/// dimension, for generators `g` coprime to `n`, so that each coordinate takes every value
/// `i / n` once (stratified in each dimension) and the generators near `n / phi` and
/// `n / rho` (golden and plastic ratios) spread the points over the cube. Shifted by one
/// uniform random vector per use (Cranley-Patterson rotation), each point is uniform on the
/// cube and the estimator built on them stays unbiased, with less variance than independent
/// points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rank1Lattice {
    n: u32,
    generators: [u32; 3],
}

impl Rank1Lattice {
    /// The lattice of `n >= 1` points.
    pub fn new(n: u32) -> Self {
        assert!(n >= 1, "a lattice has at least one point");
        // The integer nearest `n * fraction` that is coprime to `n` (1 always is).
        let generator = |fraction: f64| {
            let target = (n as f64 * fraction).round() as u32;
            (0..n)
                .flat_map(|d| [target.saturating_sub(d), target + d])
                .find(|&g| g >= 1 && g < n.max(2) && gcd(g, n) == 1)
                .unwrap_or(1)
        };
        Rank1Lattice {
            n,
            generators: [
                generator(0.754_877_666_246_692_8), // 1 / plastic ratio
                1,
                generator(0.618_033_988_749_894_9), // 1 / golden ratio
            ],
        }
    }

    /// Point `j` (taken modulo `n`).
    pub fn point(&self, j: u32) -> [f32; 3] {
        let n = u64::from(self.n);
        // `i / n` for `i < n` rounds to below 1 in `f32` (for `n` below 2^24).
        self.generators
            .map(|g| ((u64::from(j) * u64::from(g)) % n) as f32 / self.n as f32)
    }
}

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// `base + shift` wrapped into `[0, 1)`, lane by lane, for `base` and `shift` in `[0, 1)`.
#[inline(always)]
pub fn shifted_mod_one(base: Vec4, shift: f32) -> Vec4 {
    let u = base + Vec4::splat(shift);
    Vec4::select(u.cmpge(Vec4::ONE), u - Vec4::ONE, u)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_points_are_stratified_in_every_dimension() {
        for n in [1, 2, 3, 4, 7, 15, 16, 64, 100, 1024] {
            let lattice = Rank1Lattice::new(n);
            for d in 0..3 {
                let mut strata: Vec<u32> = (0..n)
                    .map(|j| {
                        let x = lattice.point(j)[d];
                        assert!((0.0..1.0).contains(&x), "n {n}: {x}");
                        (x * n as f32).round() as u32
                    })
                    .collect();
                strata.sort_unstable();
                assert_eq!(strata, (0..n).collect::<Vec<_>>(), "n {n}, dimension {d}");
            }
        }
    }

    #[test]
    fn lattice_points_spread_over_the_square() {
        // The two coordinates of a point on a light: no two points closer (on the torus) than
        // half the spacing `1 / sqrt(n)` of a square grid of as many points. A lattice along
        // the diagonal (generator 1) has them `sqrt(2) / n` apart and fails from n = 9 on.
        for n in [7, 8, 15, 16, 32, 64, 100, 1024] {
            let lattice = Rank1Lattice::new(n);
            let points: Vec<Vec2> = (0..n)
                .map(|j| {
                    let [_, u, v] = lattice.point(j);
                    Vec2::new(u, v)
                })
                .collect();
            for (i, a) in points.iter().enumerate() {
                for b in &points[i + 1..] {
                    let d = (*a - *b).abs();
                    let torus = d.min(Vec2::ONE - d);
                    assert!(torus.length() > 0.5 / (n as f32).sqrt(), "n {n}: {a} {b}");
                }
            }
        }
    }

    #[test]
    fn shifted_lattices_integrate_without_bias() {
        // The mean of a lattice's points under random shifts is the integral (here of
        // x + y^2 z over the cube: 1/2 + 1/6), as for independent points; unshifted, a
        // lattice always gives the same, wrong, sum (0.516 for 4 points).
        for n in [1, 4, 15] {
            let lattice = Rank1Lattice::new(n);
            let shifts = 20_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for i in 0..shifts {
                let u =
                    |d: u32| crate::math::rng::uniform(crate::math::rng::path_key(5, i, 0), 0, d);
                let mut estimate = 0.0;
                for j in 0..n {
                    let [a, b, c] = lattice.point(j).map(Vec4::splat);
                    let (x, y, z) = (
                        shifted_mod_one(a, u(0)).x as f64,
                        shifted_mod_one(b, u(1)).x as f64,
                        shifted_mod_one(c, u(2)).x as f64,
                    );
                    estimate += (y * y * z + x) / n as f64;
                }
                sum += estimate;
                sum2 += estimate * estimate;
            }
            let mean = sum / shifts as f64;
            let error = ((sum2 / shifts as f64 - mean * mean) / shifts as f64).sqrt();
            let exact = 1.0 / 6.0 + 0.5;
            assert!(
                (mean - exact).abs() < 4.0 * error + 1e-6,
                "n {n}: {mean} +- {error}"
            );
        }
    }

    #[test]
    fn shifted_points_stay_below_one() {
        let almost = 1.0 - f32::EPSILON / 2.0;
        let u = shifted_mod_one(Vec4::new(0.0, 0.5, almost, almost), almost);
        assert!(u.cmplt(Vec4::ONE).all() && u.cmpge(Vec4::ZERO).all(), "{u}");
    }

    /// A stratified grid of `n * n` points in [0,1)^2.
    fn grid(n: usize) -> impl Iterator<Item = Vec2> {
        (0..n * n).map(move |i| {
            Vec2::new(
                ((i % n) as f32 + 0.5) / n as f32,
                ((i / n) as f32 + 0.5) / n as f32,
            )
        })
    }

    #[test]
    fn cosine_hemisphere_is_normalised_and_matches_its_pdf() {
        // Integral of pdf over the hemisphere = 1, and E[f/pdf] of f = cos gives pi (exact: cos/pdf = pi).
        let n = 400;
        let mut mean_cos = 0.0f64;
        for u in grid(n) {
            let w = sample_cosine_hemisphere(u);
            assert!((w.length() - 1.0).abs() < 1e-4 && w.z >= 0.0);
            mean_cos += w.z as f64;
        }
        mean_cos /= (n * n) as f64;
        // E[cos] under p = cos/pi equals 2/3.
        assert!((mean_cos - 2.0 / 3.0).abs() < 1e-3, "{mean_cos}");
        // Histogram check: the fraction with cos > 0.5 is 1 - 0.25 = 0.75.
        let frac = grid(n)
            .filter(|&u| sample_cosine_hemisphere(u).z > 0.5)
            .count() as f64
            / (n * n) as f64;
        assert!((frac - 0.75).abs() < 2e-3, "{frac}");
        // Numerical integral of the pdf over the hemisphere (midpoint rule in theta, phi).
        let nt = 256;
        let mut integral = 0.0f64;
        for i in 0..nt {
            let theta = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
            integral += cosine_hemisphere_pdf(theta.cos() as f32) as f64
                * theta.sin()
                * (std::f64::consts::FRAC_PI_2 / nt as f64)
                * (2.0 * std::f64::consts::PI);
        }
        assert!((integral - 1.0).abs() < 1e-3, "{integral}");
    }

    #[test]
    fn cosine_and_sine_within_a_quarter_are_accurate() {
        let n = 100_000;
        let mut worst = 0.0f64;
        for i in 0..=n {
            let x = (2.0 * i as f32 / n as f32 - 1.0) * PI / 4.0;
            let (cos, sin) = cos_sin_within_quarter(x);
            let x = x as f64;
            worst = worst
                .max((cos as f64 - x.cos()).abs())
                .max((sin as f64 - x.sin()).abs());
        }
        // One f32 ulp of 1 is 1.2e-7: at most a rounding or two off.
        assert!(worst < 1.2e-7, "{worst:e}");
    }

    #[test]
    fn triangle_samples_are_uniform() {
        // Uniform on the triangle: E[b1] = E[b2] = 1/3, and every sample inside.
        let n = 300;
        let (mut s1, mut s2) = (0.0f64, 0.0f64);
        let mut sub = 0usize; // fraction in the sub-triangle b1 > 1/2 has area 1/4
        for u in grid(n) {
            let [b1, b2] = sample_triangle([Vec4::splat(u.x), Vec4::splat(u.y)]);
            let b = Vec2::new(b1.x, b2.x);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0);
            s1 += b.x as f64;
            s2 += b.y as f64;
            sub += (b.x > 0.5) as usize;
        }
        let m = (n * n) as f64;
        assert!((s1 / m - 1.0 / 3.0).abs() < 1e-3 && (s2 / m - 1.0 / 3.0).abs() < 1e-3);
        assert!((sub as f64 / m - 0.25).abs() < 2e-3);
    }

    #[test]
    fn sphere_samples_are_uniform() {
        let n = 300;
        let m = (n * n) as f64;
        let mut mean = Vec3A::ZERO;
        let mut cap = 0usize; // z > 0.5 is a cap of area fraction 1/4
        for u in grid(n) {
            let w = sample_uniform_sphere(u);
            assert!((w.length() - 1.0).abs() < 1e-4);
            mean += w;
            cap += (w.z > 0.5) as usize;
        }
        assert!((mean / m as f32).length() < 1e-3);
        assert!((cap as f64 / m - 0.25).abs() < 2e-3);
    }

    #[test]
    fn discrete_sampling_counts_and_searches_alike() {
        // Short tables are counted, long ones searched: both give the first entry above the
        // target, with ties (zero weights) and the clamp at the end.
        for len in 1..40 {
            let cdf: Vec<f32> = (0..len)
                .map(|i: usize| (i.div_ceil(2) * 3) as f32 + 1.0)
                .collect();
            for i in 0..=200 {
                let u = i as f32 / 200.0;
                let target = u * cdf[len - 1];
                let expected = cdf.partition_point(|&c| c <= target).min(len - 1);
                assert_eq!(sample_discrete(&cdf, u), expected, "len {len}, u {u}");
            }
        }
    }

    #[test]
    fn discrete_sampling_follows_weights() {
        let cdf = [1.0, 1.0, 4.0, 8.0]; // weights 1, 0, 3, 4
        let mut counts = [0usize; 4];
        let n = 80_000;
        for i in 0..n {
            counts[sample_discrete(&cdf, (i as f32 + 0.5) / n as f32)] += 1;
        }
        assert_eq!(counts[1], 0, "zero-weight entries are never chosen");
        for (c, w) in counts.iter().zip([1.0, 0.0, 3.0, 4.0]) {
            assert!((*c as f64 / n as f64 - w / 8.0).abs() < 1e-3);
        }
    }
}
