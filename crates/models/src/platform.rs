//! Spec 20's test model: one horizontal channel of a platform INS, corrected
//! by GNSS velocity (seed 004, the dissertation's experiments).
//!
//! State `x = (δV, φ, ε)`: velocity error [m/s], platform tilt [rad], gyro
//! drift rate [rad/s]. With sampling period T:
//!
//! ```text
//! Φ = | 1      −g T   0       |
//!     | T / R   1     T       |
//!     | 0       0     1 − β T |
//! ```
//!
//! The drift is a first-order Markov process; its discrete noise variance
//! `σ_ε² (1 − (1 − βT)²)` keeps its stationary σ at `σ_ε`. The accelerometer
//! bias B enters the *truth* as a constant forcing `(B T, 0, 0)` that the
//! filter's model does not contain (the model error the adaptive filters are
//! for). The measurement is INS − GNSS velocity: `H = (1, 0, 0)`.

use aidnav_frames::constants::EARTH_MEAN_RADIUS_M;
use nalgebra::{Matrix1, Matrix1x3, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Gravity used by the paper's model [m/s²] (spec 20: g = 9.81).
pub const PLATFORM_G_M_S2: f64 = 9.81;

/// Parameters of the platform channel (defaults: spec 20's suggestions).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlatformChannel {
    /// Sampling period T [s]. Default 1.
    pub dt_s: f64,
    /// Mean frequency β of the drift's random change [1/s]. Default 1/3600.
    pub beta_per_s: f64,
    /// Stationary σ of the gyro drift [rad/s]. Default 0.05 °/h.
    pub drift_sigma_rad_s: f64,
    /// Accelerometer bias B [m/s²], truth only. Default 1e-2.
    pub accel_bias_m_s2: f64,
    /// GNSS velocity noise σ [m/s]. Default 0.1.
    pub gnss_velocity_sigma_mps: f64,
}

impl Default for PlatformChannel {
    fn default() -> Self {
        Self {
            dt_s: 1.0,
            beta_per_s: 1.0 / 3600.0,
            drift_sigma_rad_s: 0.05_f64.to_radians() / 3600.0,
            accel_bias_m_s2: 1e-2,
            gnss_velocity_sigma_mps: 0.1,
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

    /// The truth's constant forcing per step from the accelerometer bias: (B T, 0, 0).
    pub fn bias_forcing(&self) -> Vector3<f64> {
        Vector3::new(self.accel_bias_m_s2 * self.dt_s, 0.0, 0.0)
    }

    /// H = (1, 0, 0) and R = σ² of the GNSS velocity.
    pub fn velocity_measurement(&self) -> (Matrix1x3<f64>, Matrix1<f64>) {
        (
            Matrix1x3::new(1.0, 0.0, 0.0),
            Matrix1::new(self.gnss_velocity_sigma_mps.powi(2)),
        )
    }

    /// Schuler period 2π √(R/g) [s] (≈ 84.4 min), the natural run length.
    pub fn schuler_period_s() -> f64 {
        2.0 * std::f64::consts::PI * (EARTH_MEAN_RADIUS_M / PLATFORM_G_M_S2).sqrt()
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
    fn drift_noise_keeps_its_stationary_sigma() {
        let m = PlatformChannel::default();
        let a = m.transition()[(2, 2)];
        let stationary = m.process_noise()[(2, 2)] / (1.0 - a * a);
        assert!((stationary.sqrt() / m.drift_sigma_rad_s - 1.0).abs() < 1e-12);
    }
}
