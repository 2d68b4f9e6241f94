//! Filter consistency statistics: NIS, NEES and their χ² acceptance bounds
//! (Bar-Shalom, Li & Kirubarajan, *Estimation with Applications to Tracking
//! and Navigation*, §5.4).
//!
//! For a consistent filter the NEES of an n-state estimate is χ²(n) and the NIS
//! of an m-component innovation is χ²(m). The mean of K independent samples,
//! times K, is χ²(K·n): [`mean_chi2_bounds`] gives the two-sided interval in
//! which that mean must fall.

use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector, allocator::Allocator};
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::error::{EstimationError, Matrix, Result, Step};

/// Quantile of the χ² distribution with `dof` degrees of freedom.
///
/// Returns `+∞` for `probability ≥ 1` and `0` for `probability ≤ 0` or `dof = 0`.
///
/// ```
/// let q = aidnav_estimation::chi2_quantile(1, 0.95);
/// assert!((q - 3.841458820694124).abs() < 1e-9);
/// ```
pub fn chi2_quantile(dof: usize, probability: f64) -> f64 {
    if dof == 0 || probability <= 0.0 || probability.is_nan() {
        return 0.0;
    }
    if probability >= 1.0 {
        return f64::INFINITY;
    }
    // Gates ask for the same few quantiles at every update, and the inverse
    // CDF is an iterative search (most of a gated filter's time): the last
    // few are kept per thread, the same numbers as computing them again.
    let key = (dof, probability.to_bits());
    if let Some(q) =
        RECENT_QUANTILES.with(|r| r.borrow().iter().find(|(k, _)| *k == key).map(|&(_, q)| q))
    {
        return q;
    }
    let q = match ChiSquared::new(dof as f64) {
        Ok(dist) => dist.inverse_cdf(probability),
        Err(_) => f64::NAN,
    };
    RECENT_QUANTILES.with(|r| {
        let mut r = r.borrow_mut();
        if r.len() == RECENT_QUANTILES_KEPT {
            r.remove(0);
        }
        r.push((key, q));
    });
    q
}

/// How many quantiles [`chi2_quantile`] keeps per thread.
const RECENT_QUANTILES_KEPT: usize = 16;

thread_local! {
    /// [`chi2_quantile`]'s last results: ((dof, probability's bits), quantile).
    static RECENT_QUANTILES: std::cell::RefCell<Vec<((usize, u64), f64)>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// Two-sided `confidence` bounds on the *mean* of `samples` independent χ²(`dof`) values.
///
/// ```
/// // 100 runs of a 2-state NEES: the mean must lie in about [1.62, 2.43] at 95 %.
/// let (lo, hi) = aidnav_estimation::mean_chi2_bounds(2, 100, 0.95);
/// assert!(lo > 1.6 && lo < 1.65 && hi > 2.4 && hi < 2.45);
/// ```
pub fn mean_chi2_bounds(dof: usize, samples: usize, confidence: f64) -> (f64, f64) {
    let total = dof * samples;
    let tail = 0.5 * (1.0 - confidence);
    let k = samples.max(1) as f64;
    (
        chi2_quantile(total, tail) / k,
        chi2_quantile(total, 1.0 - tail) / k,
    )
}

/// Normalised estimation error squared `(x − x̂)ᵀ P⁻¹ (x − x̂)`, by Cholesky solve.
pub fn nees<N: Dim>(
    truth: &OVector<f64, N>,
    estimate: &OVector<f64, N>,
    p: &OMatrix<f64, N, N>,
) -> Result<f64>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    let e = truth - estimate;
    let chol = Cholesky::new(p.clone()).ok_or(EstimationError::NotPositiveDefinite {
        step: Step::Update,
        matrix: Matrix::P,
    })?;
    Ok(e.dot(&chol.solve(&e)))
}

/// Running mean of a χ² statistic together with its acceptance test.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Chi2Mean {
    sum: f64,
    count: usize,
    dof_sum: usize,
}

impl Chi2Mean {
    /// Add one sample with its degrees of freedom.
    pub fn push(&mut self, value: f64, dof: usize) {
        self.sum += value;
        self.count += 1;
        self.dof_sum += dof;
    }

    /// Mean of the samples (NaN when empty).
    pub fn mean(&self) -> f64 {
        self.sum / self.count as f64
    }

    /// Mean normalised by its degrees of freedom: 1 for a consistent filter.
    pub fn mean_per_dof(&self) -> f64 {
        self.sum / self.dof_sum as f64
    }

    /// Number of samples.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Two-sided bounds on the mean at `confidence`, assuming independent samples.
    pub fn bounds(&self, confidence: f64) -> (f64, f64) {
        let tail = 0.5 * (1.0 - confidence);
        let k = self.count.max(1) as f64;
        (
            chi2_quantile(self.dof_sum, tail) / k,
            chi2_quantile(self.dof_sum, 1.0 - tail) / k,
        )
    }

    /// Whether the mean lies within the `confidence` bounds.
    pub fn is_consistent(&self, confidence: f64) -> bool {
        let (lo, hi) = self.bounds(confidence);
        let m = self.mean();
        m >= lo && m <= hi
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kept quantiles are the computed ones, before and after more
    /// distinct quantiles than are kept have pushed them out.
    #[test]
    fn kept_quantiles_are_the_computed_ones() {
        let direct = |dof: usize, p: f64| ChiSquared::new(dof as f64).unwrap().inverse_cdf(p);
        for round in 0..3 {
            for dof in 1..=2 * RECENT_QUANTILES_KEPT {
                for p in [0.95, 0.999] {
                    let q = chi2_quantile(dof, p);
                    assert_eq!(q.to_bits(), direct(dof, p).to_bits(), "{round} {dof} {p}");
                    assert_eq!(chi2_quantile(dof, p).to_bits(), q.to_bits());
                }
            }
        }
    }
}
