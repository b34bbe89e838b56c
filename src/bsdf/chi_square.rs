//! Test support: Pearson's chi-square goodness-of-fit test of a direction sampler against its
//! claimed density over the whole sphere (the pbrt / Mitsuba construction), and the
//! chi-square distribution function it needs (a regularised incomplete gamma function).

use crate::math::{Vec2, Vec3A};
use rayon::prelude::*;
use std::f64::consts::{PI, TAU};

/// Grid and sample sizes of one test.
pub struct ChiSquareSetup {
    /// Cells in theta (over [0, pi]).
    pub theta_cells: usize,
    /// Cells in phi (over [0, 2 pi)).
    pub phi_cells: usize,
    /// Simpson intervals per cell side when integrating the density (even).
    pub simpson_intervals: usize,
    /// Number of samples drawn.
    pub samples: usize,
    /// Significance level of this one test (after any correction for multiple tests).
    pub significance: f64,
}

/// Outcome of one test.
#[derive(Debug)]
pub struct ChiSquareResult {
    /// Pearson's statistic over the pooled cells.
    pub statistic: f64,
    /// Degrees of freedom (pooled cells - 1).
    pub dof: usize,
    /// Probability of a statistic at least this large if the sampler matched the density.
    pub p_value: f64,
    /// Sum over all cells of the integrated density (the sampler's probability of success).
    pub total_mass: f64,
}

fn cell_index(setup: &ChiSquareSetup, w: Vec3A) -> usize {
    let theta = (w.z as f64).clamp(-1.0, 1.0).acos();
    let mut phi = (w.y as f64).atan2(w.x as f64);
    if phi < 0.0 {
        phi += TAU;
    }
    let i = ((theta / PI * setup.theta_cells as f64) as usize).min(setup.theta_cells - 1);
    let j = ((phi / TAU * setup.phi_cells as f64) as usize).min(setup.phi_cells - 1);
    i * setup.phi_cells + j
}

/// Runs the test: `sample(u_lobe, u)` returns a unit direction or `None`, `pdf(w)` its
/// solid-angle density. Expected counts come from 2D Simpson integration of `pdf` over each
/// cell (in theta, phi with the sin(theta) Jacobian); cells expecting fewer than 5 samples are
/// pooled; observed samples in cells of zero expected count fail the test outright.
pub fn chi_square_test(
    setup: &ChiSquareSetup,
    seed: u64,
    sample: impl Fn(f32, Vec2) -> Option<Vec3A>,
    pdf: impl Fn(Vec3A) -> f32 + Sync,
) -> ChiSquareResult {
    let cells = setup.theta_cells * setup.phi_cells;
    let mut observed = vec![0.0f64; cells];
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let mut next = || {
        // SplitMix64 (Steele et al. 2014), 24-bit floats in [0, 1).
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    };
    for _ in 0..setup.samples {
        let (u_lobe, u) = (next(), Vec2::new(next(), next()));
        if let Some(w) = sample(u_lobe, u) {
            observed[cell_index(setup, w)] += 1.0;
        }
    }

    let n = setup.simpson_intervals;
    let simpson_weight = |k: usize| -> f64 {
        if k == 0 || k == n {
            1.0
        } else if k % 2 == 1 {
            4.0
        } else {
            2.0
        }
    };
    let d_theta = PI / setup.theta_cells as f64;
    let d_phi = TAU / setup.phi_cells as f64;
    let expected: Vec<f64> = (0..cells)
        .into_par_iter()
        .map(|c| {
            let (i, j) = (c / setup.phi_cells, c % setup.phi_cells);
            let mut integral = 0.0;
            for a in 0..=n {
                // Nodes stay a hair inside the cell: densities jump at the horizon, which is a
                // cell boundary, and each cell must see its own side's limit.
                let inside = (a as f64 / n as f64).clamp(1e-5, 1.0 - 1e-5);
                let theta = (i as f64 + inside) * d_theta;
                for b in 0..=n {
                    let phi = (j as f64 + b as f64 / n as f64) * d_phi;
                    let w = Vec3A::new(
                        (theta.sin() * phi.cos()) as f32,
                        (theta.sin() * phi.sin()) as f32,
                        theta.cos() as f32,
                    );
                    integral += simpson_weight(a)
                        * simpson_weight(b)
                        * pdf(w.normalize()) as f64
                        * theta.sin();
                }
            }
            let h = (d_theta / n as f64) * (d_phi / n as f64) / 9.0;
            integral * h * setup.samples as f64
        })
        .collect();
    let total_mass = expected.iter().sum::<f64>() / setup.samples as f64;

    // --- Pool cells with small expectations (sorted ascending) until the pool reaches 5.
    let mut order: Vec<usize> = (0..cells).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut statistic, mut dof) = (0.0, 0usize);
    let (mut pool_expected, mut pool_observed) = (0.0, 0.0);
    for &c in &order {
        if expected[c] == 0.0 {
            assert!(
                observed[c] == 0.0,
                "{} samples in cell {c}, where the density is 0",
                observed[c]
            );
            continue;
        }
        if expected[c] < 5.0 || pool_expected > 0.0 && pool_expected < 5.0 {
            pool_expected += expected[c];
            pool_observed += observed[c];
            continue;
        }
        statistic += (observed[c] - expected[c]).powi(2) / expected[c];
        dof += 1;
    }
    if pool_expected > 0.0 {
        statistic += (pool_observed - pool_expected).powi(2) / pool_expected;
        dof += 1;
    }
    let dof = dof.saturating_sub(1).max(1);
    let p_value = chi_square_survival(statistic, dof as f64);
    if p_value <= setup.significance {
        // Show the worst cells to make a failure diagnosable.
        let mut worst: Vec<usize> = (0..cells).filter(|&c| expected[c] >= 5.0).collect();
        worst.sort_by(|&a, &b| {
            let z = |c: usize| (observed[c] - expected[c]).powi(2) / expected[c];
            z(b).total_cmp(&z(a))
        });
        for &c in worst.iter().take(8) {
            eprintln!(
                "cell theta {} phi {}: observed {} expected {:.1}",
                c / setup.phi_cells,
                c % setup.phi_cells,
                observed[c],
                expected[c]
            );
        }
    }
    ChiSquareResult {
        statistic,
        dof,
        p_value,
        total_mass,
    }
}

/// P(X >= x) for a chi-square variable with `dof` degrees of freedom: Q(dof/2, x/2).
pub fn chi_square_survival(x: f64, dof: f64) -> f64 {
    regularized_gamma_q(0.5 * dof, 0.5 * x)
}

/// ln Gamma(z) for z > 0: shift up to z >= 15, then Stirling's series (error < 1e-13).
fn ln_gamma(mut z: f64) -> f64 {
    let mut shift = 0.0;
    while z < 15.0 {
        shift -= z.ln();
        z += 1.0;
    }
    let z2 = z * z;
    shift + (z - 0.5) * z.ln() - z + 0.5 * TAU.ln() + 1.0 / (12.0 * z) - 1.0 / (360.0 * z * z2)
        + 1.0 / (1260.0 * z * z2 * z2)
        - 1.0 / (1680.0 * z * z2 * z2 * z2)
}

/// The regularised upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a):
/// the power series of P for x < a + 1, otherwise a continued fraction (modified Lentz).
pub fn regularized_gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefactor = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // P(a, x) = x^a e^-x / Gamma(a + 1) * sum_n x^n / ((a + 1) ... (a + n)).
        let (mut term, mut sum, mut denominator) = (1.0 / a, 1.0 / a, a);
        for _ in 0..100_000 {
            denominator += 1.0;
            term *= x / denominator;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * log_prefactor.exp()
    } else {
        // Q(a, x) = x^a e^-x / Gamma(a) * 1 / (x + 1 - a - 1 (1 - a) / (x + 3 - a - ...)).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut fraction = d;
        for i in 1..100_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            fraction *= delta;
            if (delta - 1.0).abs() < 1e-15 {
                break;
            }
        }
        fraction * log_prefactor.exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_survival_matches_tabulated_quantiles() {
        // Upper 5 % and 1 % points from standard tables.
        for (dof, x05, x01) in [
            (1.0, 3.841, 6.635),
            (10.0, 18.307, 23.209),
            (100.0, 124.342, 135.807),
        ] {
            assert!(
                (chi_square_survival(x05, dof) - 0.05).abs() < 2e-4,
                "dof {dof}"
            );
            assert!(
                (chi_square_survival(x01, dof) - 0.01).abs() < 1e-4,
                "dof {dof}"
            );
        }
        // dof 2 is an exponential: Q = exp(-x / 2).
        assert!((chi_square_survival(3.0, 2.0) - (-1.5f64).exp()).abs() < 1e-12);
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-12);
    }
}
