//! First-order Gauss–Markov process, the workhorse of instrument and GNSS
//! error models: `ẋ = −x/τ + w`, stationary variance σ².
//! Exact discretisation: `φ = e^{−T/τ}`, `q = σ² (1 − e^{−2T/τ})`, so the
//! stationary variance is preserved at any step (Gelb, *Applied Optimal
//! Estimation*, Table 3.8-1).

/// A first-order Gauss–Markov process.
///
/// ```
/// use aidnav_models::GaussMarkov;
/// let gm = GaussMarkov::new(100.0, 0.02).unwrap();
/// let (phi, q) = gm.discretise(1.0);
/// // Stationary: φ² σ² + q = σ².
/// assert!((phi * phi * 0.02f64.powi(2) + q - 0.02f64.powi(2)).abs() < 1e-18);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussMarkov {
    tau_s: f64,
    sigma: f64,
}

impl GaussMarkov {
    /// Correlation time `tau_s` > 0 \[s\] and stationary σ ≥ 0 (in the unit of x).
    pub fn new(tau_s: f64, sigma: f64) -> Option<Self> {
        (tau_s.is_finite() && tau_s > 0.0 && sigma.is_finite() && sigma >= 0.0)
            .then_some(Self { tau_s, sigma })
    }

    /// Correlation time \[s\].
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }

    /// Stationary σ.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// (φ, q) for a step of `dt_s` seconds.
    pub fn discretise(&self, dt_s: f64) -> (f64, f64) {
        let phi = (-dt_s / self.tau_s).exp();
        // 1 − e^{−2T/τ} via exp_m1 keeps precision for T ≪ τ.
        let q = self.sigma * self.sigma * -(-2.0 * dt_s / self.tau_s).exp_m1();
        (phi, q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_steps_match_the_continuous_model() {
        // For T ≪ τ: φ ≈ 1 − T/τ and q ≈ 2σ²T/τ (white-noise PSD 2σ²/τ).
        let gm = GaussMarkov::new(3600.0, 0.1).unwrap();
        let (phi, q) = gm.discretise(0.01);
        // The neglected second-order term is (T/τ)²/2 ≈ 3.9e-12.
        assert!((phi - (1.0 - 0.01 / 3600.0)).abs() < 5e-12);
        assert!((q / (2.0 * 0.01 * 0.01 / 3600.0) - 1.0).abs() < 1e-5);
    }
}
