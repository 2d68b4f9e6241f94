//! Random processes of the sensor error models: the first-order
//! Gauss–Markov process (bias instability, slowly wandering GNSS and
//! barometer errors), discretised exactly.

use crate::rng::standard_normal;

/// A first-order Gauss–Markov process `ẋ = −x/τ + w`, stationary with
/// standard deviation σ, sampled exactly at any interval Δt:
/// `x_{k+1} = φ x_k + σ √(1 − φ²) n_k`, `φ = exp(−Δt/τ)`, `n_k ~ N(0, 1)`.
/// It starts from a draw of its stationary distribution, `x_0 ~ N(0, σ²)`.
///
/// ```
/// use aidnav_sim::processes::GaussMarkov;
/// use aidnav_sim::rng::run_rng;
/// let mut rng = run_rng(7, 0);
/// let mut gm = GaussMarkov::new(2.0, 100.0, &mut rng);
/// let x: Vec<f64> = (0..20_000).map(|_| gm.step(1.0, &mut rng)).collect();
/// let var = x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
/// assert!((var.sqrt() - 2.0).abs() < 0.4); // stationary σ (correlated samples)
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussMarkov {
    sigma: f64,
    correlation_time_s: f64,
    value: f64,
}

impl GaussMarkov {
    /// A process of stationary σ `sigma` (unit of the modelled quantity)
    /// and correlation time τ `correlation_time_s` \[s\], its initial value
    /// drawn from `rng`. σ = 0 gives the zero process (and draws nothing).
    pub fn new<R: rand::Rng + ?Sized>(sigma: f64, correlation_time_s: f64, rng: &mut R) -> Self {
        let value = if sigma > 0.0 {
            sigma * standard_normal(rng)
        } else {
            0.0
        };
        Self {
            sigma,
            correlation_time_s,
            value,
        }
    }

    /// The current value (unit of σ).
    pub fn value(&self) -> f64 {
        self.value
    }

    /// Advance by `dt_s` \[s\] and return the new value (unit of σ).
    pub fn step<R: rand::Rng + ?Sized>(&mut self, dt_s: f64, rng: &mut R) -> f64 {
        if self.sigma > 0.0 {
            let phi = (-dt_s / self.correlation_time_s).exp();
            self.value =
                phi * self.value + self.sigma * (1.0 - phi * phi).sqrt() * standard_normal(rng);
        }
        self.value
    }
}

/// `sigma · n`, `n ~ N(0, 1)`, drawing nothing when σ = 0 (so a disabled
/// process leaves its stream untouched and costs nothing).
pub(crate) fn white<R: rand::Rng + ?Sized>(sigma: f64, rng: &mut R) -> f64 {
    if sigma > 0.0 {
        sigma * standard_normal(rng)
    } else {
        0.0
    }
}
