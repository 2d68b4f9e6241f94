//! Efficiency criterion of integrated processing (spec 20, paper eqs. 12–16):
//! `K_eff = σ_GNSS / σ_KOI` per navigation parameter. K_eff > 1: navigate on
//! INS + filter (КОИ); K_eff < 1: GNSS alone; K_eff ≈ 1: no difference.
//!
//! σ_GNSS is prior data (flight tests, or a stable stretch); σ_KOI is √P_kk of
//! the filter in flight, the predicted σ during an outage. For a scalar
//! channel whose input-noise statistics are unknown, [`AdaptiveScalarVariance`]
//! gives P from the innovations (eqs. 14–16).

use serde::{Deserialize, Serialize};

/// Which source the criterion selects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Source {
    /// GNSS alone.
    Gnss,
    /// INS corrected by the filter (integrated processing, КОИ).
    Integrated,
}

/// `K_eff = σ_GNSS / σ_KOI` and the source it selects.
///
/// ```
/// use aidnav_supervisors::efficiency::{EfficiencyCriterion, Source};
/// let c = EfficiencyCriterion { sigma_gnss: 0.1 };
/// assert_eq!(c.select(0.05), (Source::Integrated, 2.0));
/// assert_eq!(c.select(0.2).0, Source::Gnss);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EfficiencyCriterion {
    /// σ of the GNSS error of this parameter (prior data).
    pub sigma_gnss: f64,
}

impl EfficiencyCriterion {
    /// `K_eff` for the filter's σ of this parameter.
    pub fn coefficient(&self, sigma_integrated: f64) -> f64 {
        self.sigma_gnss / sigma_integrated
    }

    /// The selected source and `K_eff` (integrated when K_eff > 1).
    pub fn select(&self, sigma_integrated: f64) -> (Source, f64) {
        let k = self.coefficient(sigma_integrated);
        (
            if k > 1.0 {
                Source::Integrated
            } else {
                Source::Gnss
            },
            k,
        )
    }
}

/// How the prior variance is formed from the innovations θ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum VarianceFeedback {
    /// Eq. 15: `p⁻ = a² p + k² M[θ²]`, M over the last `window` innovations.
    MeanSquare {
        /// Innovations averaged, ≥ 1.
        window: usize,
    },
    /// Eq. 16, hard feedback: `p⁻ = a² p + k² θ²`.
    Hard,
}

/// Scalar filter variance without input-noise statistics (eqs. 14–16): the
/// prior variance is fed back from the innovations; by eq. 14 the gain is
/// zero while `M[θ²] − r < 0` (the estimation error is below the noise).
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveScalarVariance {
    a: f64,
    r: f64,
    p: f64,
    gain: f64,
    feedback: VarianceFeedback,
    squares: Vec<f64>,
    next: usize,
}

impl AdaptiveScalarVariance {
    /// Transition a (Φ_ii), measurement variance r > 0, initial variance p0 ≥ 0.
    pub fn new(a: f64, r: f64, p0: f64, feedback: VarianceFeedback) -> Option<Self> {
        let window = match feedback {
            VarianceFeedback::MeanSquare { window } => window,
            VarianceFeedback::Hard => 1,
        };
        (a.is_finite() && r > 0.0 && p0 >= 0.0 && window >= 1).then(|| Self {
            a,
            r,
            p: p0,
            gain: p0 / (p0 + r),
            feedback,
            squares: Vec::with_capacity(window),
            next: 0,
        })
    }

    /// One epoch with innovation θ: returns (prior variance, gain). The
    /// posterior variance is then [`variance`](Self::variance).
    pub fn step(&mut self, theta: f64) -> (f64, f64) {
        let theta2 = theta * theta;
        let mean_square = match self.feedback {
            VarianceFeedback::Hard => theta2,
            VarianceFeedback::MeanSquare { window } => {
                if self.squares.len() < window {
                    self.squares.push(theta2);
                } else {
                    self.squares[self.next] = theta2;
                }
                self.next = (self.next + 1) % window;
                self.squares.iter().sum::<f64>() / self.squares.len() as f64
            }
        };
        let prior = self.a * self.a * self.p + self.gain * self.gain * mean_square;
        // Eq. 14: with M[θ²] − r < 0 the error is below the noise: no update.
        self.gain = if mean_square - self.r < 0.0 {
            0.0
        } else {
            prior / (prior + self.r)
        };
        self.p = (1.0 - self.gain) * prior;
        (prior, self.gain)
    }

    /// Posterior variance after the last step.
    pub fn variance(&self) -> f64 {
        self.p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_is_zero_while_innovations_are_below_the_noise() {
        let mut v =
            AdaptiveScalarVariance::new(1.0, 1.0, 1.0, VarianceFeedback::MeanSquare { window: 4 })
                .unwrap();
        for _ in 0..4 {
            let (_, k) = v.step(0.5);
            assert_eq!(k, 0.0);
        }
    }

    #[test]
    fn large_innovations_raise_the_variance_and_the_gain() {
        let mut v = AdaptiveScalarVariance::new(1.0, 1.0, 0.1, VarianceFeedback::Hard).unwrap();
        v.step(3.0);
        let p_small = v.variance();
        let (prior, k) = v.step(10.0);
        assert!(prior > p_small);
        assert!(k > 0.5, "{k}");
        // p = (1 − k) p⁻ = r k for the scalar filter.
        assert!((v.variance() - k * 1.0).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(AdaptiveScalarVariance::new(1.0, 0.0, 1.0, VarianceFeedback::Hard).is_none());
        assert!(
            AdaptiveScalarVariance::new(1.0, 1.0, 1.0, VarianceFeedback::MeanSquare { window: 0 })
                .is_none()
        );
    }
}
