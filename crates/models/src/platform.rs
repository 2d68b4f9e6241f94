//! Spec 20's test model: one horizontal channel of a platform INS, corrected
//! by GNSS velocity (seed 004, the dissertation's experiments).
//!
//! State `x = (δV, φ, ε)`: velocity error [m/s], platform tilt \[rad\], gyro
//! drift rate [rad/s]. With sampling period T:
//!
//! ```text
//! Φ = | 1      −g T   0       |
//!     | T / R   1     T       |
//!     | 0       0     1 − β T |
//! ```
//!
//! The drift is a first-order Markov process; its discrete noise variance
//! `σ_ε² (1 − (1 − βT)²)` keeps its stationary σ at `σ_ε`. The measurement is
//! INS − GNSS velocity: `H = (1, 0, 0)`.
//!
//! The accelerometer error enters the *truth* ([`PlatformTruth`]) as a forcing
//! `((B + b(t)) T, 0, 0)` that the filter's model does not contain. A constant
//! B alone is no model error at all: `(I − Φ) c = (B T, 0, 0)` has the
//! solution `c = (0, B/g, 0)`, so the truth is a model trajectory with its
//! tilt shifted by B/g, and a filter absorbs B as an initial tilt. What the
//! model cannot represent is the variation `b(t)` — here a first-order
//! Gauss–Markov process standing for manoeuvre-dependent accelerometer errors
//! (scale factor × manoeuvre acceleration, temperature), σ_b and τ_b
//! scenario parameters. [`PlatformChannel::known_process_noise`] and
//! [`PlatformChannel::known_initial_covariance`] give the statistics a 3-state
//! filter "with known statistics" can hold of these terms.

use aidnav_frames::constants::EARTH_MEAN_RADIUS_M;
use nalgebra::{Matrix1, Matrix1x3, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Gravity used by the paper's model [m/s²] (spec 20: g = 9.81).
pub const PLATFORM_G_M_S2: f64 = 9.81;

/// Parameters of the platform channel (defaults: spec 20's suggestions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlatformChannel {
    /// Sampling period T \[s\]. Default 1.
    pub dt_s: f64,
    /// Mean frequency β of the drift's random change [1/s]. Default 1/3600.
    pub beta_per_s: f64,
    /// Stationary σ of the gyro drift [rad/s]. Default 0.05 °/h.
    pub drift_sigma_rad_s: f64,
    /// Accelerometer bias B [m/s²], truth only. Default 1e-2.
    pub accel_bias_m_s2: f64,
    /// GNSS velocity noise σ [m/s]. Default 0.1.
    pub gnss_velocity_sigma_mps: f64,
    /// Stationary σ_b of the accelerometer error's variation b(t) [m/s²],
    /// truth only. Default 2e-3 (a 1e-3 scale factor under 2 m/s² of
    /// manoeuvring; 0 gives the constant-B truth).
    pub accel_bias_variation_m_s2: f64,
    /// Correlation time τ_b of b(t) \[s\], > 0. Default 300 (a manoeuvre's time scale).
    pub accel_bias_correlation_s: f64,
}

impl Default for PlatformChannel {
    fn default() -> Self {
        Self {
            dt_s: 1.0,
            beta_per_s: 1.0 / 3600.0,
            drift_sigma_rad_s: 0.05_f64.to_radians() / 3600.0,
            accel_bias_m_s2: 1e-2,
            gnss_velocity_sigma_mps: 0.1,
            accel_bias_variation_m_s2: 2e-3,
            accel_bias_correlation_s: 300.0,
        }
    }
}

impl PlatformChannel {
    /// Φ for one step.
    pub fn transition(&self) -> Matrix3<f64> {
        let t = self.dt_s;
        Matrix3::new(
            1.0,
            -PLATFORM_G_M_S2 * t,
            0.0,
            t / EARTH_MEAN_RADIUS_M,
            1.0,
            t,
            0.0,
            0.0,
            1.0 - self.beta_per_s * t,
        )
    }

    /// Q: only the drift is driven by noise.
    pub fn process_noise(&self) -> Matrix3<f64> {
        let a = 1.0 - self.beta_per_s * self.dt_s;
        Matrix3::from_diagonal(&Vector3::new(
            0.0,
            0.0,
            self.drift_sigma_rad_s.powi(2) * (1.0 - a * a),
        ))
    }

    /// Q of a filter that knows the truth's statistics as far as its three
    /// states can: the model's Q plus, on δV, the white-noise equivalent of
    /// the forcing variation, `2 σ_b² τ_b T` (the variance growth rate of
    /// ∫ b dt for lags ≫ τ_b).
    pub fn known_process_noise(&self) -> Matrix3<f64> {
        let mut q = self.process_noise();
        q[(0, 0)] = 2.0
            * self.accel_bias_variation_m_s2.powi(2)
            * self.accel_bias_correlation_s
            * self.dt_s;
        q
    }

    /// Prior covariance of a filter that knows the truth's statistics: the
    /// given σ of δV and tilt, with the constant B counted as an unknown
    /// equivalent tilt of size B/g (see the module docs), and the drift's
    /// stationary σ.
    pub fn known_initial_covariance(&self, velocity_sigma: f64, tilt_sigma: f64) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(
            velocity_sigma.powi(2),
            tilt_sigma.powi(2) + self.equivalent_tilt_rad().powi(2),
            self.drift_sigma_rad_s.powi(2),
        ))
    }

    /// The tilt B/g that absorbs a constant accelerometer bias exactly \[rad\].
    pub fn equivalent_tilt_rad(&self) -> f64 {
        self.accel_bias_m_s2 / PLATFORM_G_M_S2
    }

    /// H = (1, 0, 0) and R = σ² of the GNSS velocity.
    pub fn velocity_measurement(&self) -> (Matrix1x3<f64>, Matrix1<f64>) {
        (
            Matrix1x3::new(1.0, 0.0, 0.0),
            Matrix1::new(self.gnss_velocity_sigma_mps.powi(2)),
        )
    }

    /// Schuler period 2π √(R/g) \[s\] (≈ 84.4 min), the natural run length.
    pub fn schuler_period_s() -> f64 {
        2.0 * std::f64::consts::PI * (EARTH_MEAN_RADIUS_M / PLATFORM_G_M_S2).sqrt()
    }
}

/// The simulated truth of the channel: the error state and the forcing's
/// variation b(t). Draws no random numbers itself: each step is given its
/// standard normal draws, so the caller owns the streams.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformTruth {
    /// Error state (δV, φ, ε).
    pub x: Vector3<f64>,
    /// Current variation b of the accelerometer error [m/s²].
    pub bias_variation: f64,
    phi: Matrix3<f64>,
    drift_step_sigma: f64,
    bias_decay: f64,
    bias_step_sigma: f64,
    bias: f64,
    dt: f64,
}

impl PlatformTruth {
    /// Start at `x0`; `n_bias` (standard normal) draws b(0) from its stationary law.
    pub fn new(channel: &PlatformChannel, x0: Vector3<f64>, n_bias: f64) -> Self {
        let decay = (-channel.dt_s / channel.accel_bias_correlation_s).exp();
        Self {
            x: x0,
            bias_variation: channel.accel_bias_variation_m_s2 * n_bias,
            phi: channel.transition(),
            drift_step_sigma: channel.process_noise()[(2, 2)].sqrt(),
            bias_decay: decay,
            bias_step_sigma: channel.accel_bias_variation_m_s2 * (1.0 - decay * decay).sqrt(),
            bias: channel.accel_bias_m_s2,
            dt: channel.dt_s,
        }
    }

    /// Advance one step T with standard normal draws for the drift and for b.
    pub fn step(&mut self, n_drift: f64, n_bias: f64) {
        let forcing = (self.bias + self.bias_variation) * self.dt;
        self.x = self.phi * self.x + Vector3::new(forcing, 0.0, self.drift_step_sigma * n_drift);
        self.bias_variation = self.bias_decay * self.bias_variation + self.bias_step_sigma * n_bias;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn free_tilt_oscillates_at_the_schuler_period() {
        // No drift, no noise: a velocity error returns to itself after one
        // Schuler period (to the discretisation's accuracy).
        let m = PlatformChannel {
            dt_s: 0.1,
            beta_per_s: 0.0,
            ..Default::default()
        };
        let phi = m.transition();
        let steps = (PlatformChannel::schuler_period_s() / m.dt_s).round() as usize;
        let mut x = Vector3::new(1.0, 0.0, 0.0);
        let mut min_dv = f64::INFINITY;
        for _ in 0..steps {
            x = phi * x;
            min_dv = min_dv.min(x[0]);
        }
        assert!(
            (min_dv + 1.0).abs() < 0.01,
            "half a period reverses δV: {min_dv}"
        );
        assert!((x[0] - 1.0).abs() < 0.01, "{}", x[0]);
        assert!((PlatformChannel::schuler_period_s() / 60.0 - 84.4).abs() < 0.1);
    }

    #[test]
    fn constant_bias_is_a_tilt_offset() {
        // With b ≡ 0 and no drift noise, the truth minus (0, B/g, 0) follows
        // the filter's model exactly.
        let m = PlatformChannel {
            accel_bias_variation_m_s2: 0.0,
            ..Default::default()
        };
        let phi = m.transition();
        let offset = Vector3::new(0.0, m.equivalent_tilt_rad(), 0.0);
        let x0 = Vector3::new(0.3, 2e-4, 1e-7);
        let mut truth = PlatformTruth::new(&m, x0, 0.0);
        let mut model = x0 - offset;
        for _ in 0..5000 {
            truth.step(0.0, 0.0);
            model = phi * model;
        }
        assert!(
            (truth.x - offset - model).norm() < 1e-9,
            "{}",
            truth.x - offset - model
        );
    }

    #[test]
    fn bias_variation_has_its_stationary_sigma_and_known_q_its_growth() {
        let m = PlatformChannel::default();
        let mut truth = PlatformTruth::new(&m, Vector3::zeros(), 0.0);
        // Deterministic pseudo-normal draws are enough for a variance check:
        // sum of 12 uniforms − 6 from a fixed LCG.
        let mut state = 12345u64;
        let mut normal = || {
            (0..12)
                .map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .sum::<f64>()
                - 6.0
        };
        let (mut sum2, mut n) = (0.0, 0.0);
        for k in 0..400_000 {
            truth.step(0.0, normal());
            if k > 3000 {
                sum2 += truth.bias_variation.powi(2);
                n += 1.0;
            }
        }
        let sigma = (sum2 / n).sqrt();
        assert!(
            (sigma / m.accel_bias_variation_m_s2 - 1.0).abs() < 0.05,
            "{sigma}"
        );
        let q = m.known_process_noise();
        assert_eq!(q[(0, 0)], 2.0 * 4e-6 * 300.0);
        assert_eq!(q[(2, 2)], m.process_noise()[(2, 2)]);
    }

    #[test]
    fn drift_noise_keeps_its_stationary_sigma() {
        let m = PlatformChannel::default();
        let a = m.transition()[(2, 2)];
        let stationary = m.process_noise()[(2, 2)] / (1.0 - a * a);
        assert!((stationary.sqrt() / m.drift_sigma_rad_s - 1.0).abs() < 1e-12);
    }
}
