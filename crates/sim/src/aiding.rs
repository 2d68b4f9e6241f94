//! Aiding sensors of a land vehicle: the wheel-speed odometer and the
//! barometer.
//!
//! - Wheel speed: the forward (body-x) component of the Earth-relative
//!   velocity of the wheel point, `v_b + ω_eb × l` for its lever arm l from
//!   the IMU, times `1 + scale_error`, plus white noise.
//! - Barometer: the true ellipsoidal height of the IMU, plus a constant
//!   bias (the sensor's datum), a first-order Gauss–Markov drift and white
//!   noise.
//!
//! Sample j of each is at `start + j / rate_hz`; each noise process draws
//! from its own stream ([`crate::rng::Stream`]).

use aidnav_frames::{Body, Vec3};
use aidnav_sensors::{BaroSample, WheelSpeedSample};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{SimError, finite, non_negative, positive};
use crate::processes::{GaussMarkov, white};
use crate::rng::Stream;
use crate::truth::{TruthSample, truth_at};

/// The wheel-speed odometer.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WheelSpeedSpec {
    /// Sample rate \[Hz\] (> 0). Default 20.
    pub rate_hz: f64,
    /// The measured point from the IMU in body axes (x fwd, y right,
    /// z down) \[m\]. Default (−1.3, 0, 0.3): the middle of the rear axle
    /// (the mean of the two rear wheel speeds).
    pub lever_arm_m: [f64; 3],
    /// Scale-factor error k (dimensionless; tyre radius error): the output
    /// is `(1 + k)` times the true speed. Default 0.005.
    pub scale_error: f64,
    /// σ of the white noise \[m/s\], also the σ written. Default 0.05.
    pub noise_sigma_mps: f64,
}

impl Default for WheelSpeedSpec {
    fn default() -> Self {
        Self {
            rate_hz: 20.0,
            lever_arm_m: [-1.3, 0.0, 0.3],
            scale_error: 0.005,
            noise_sigma_mps: 0.05,
        }
    }
}

impl WheelSpeedSpec {
    /// Check every parameter (fields named as in the scenario).
    pub fn validate(&self) -> Result<(), SimError> {
        positive("wheel_speed.rate_hz", self.rate_hz)?;
        for i in 0..3 {
            finite(format!("wheel_speed.lever_arm_m[{i}]"), self.lever_arm_m[i])?;
        }
        crate::error::check(
            "wheel_speed.scale_error",
            self.scale_error,
            self.scale_error.is_finite() && self.scale_error > -1.0,
            "must be finite and > −1",
        )?;
        non_negative("wheel_speed.noise_sigma_mps", self.noise_sigma_mps)
    }
}

/// The barometric height sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BaroSpec {
    /// Sample rate \[Hz\] (> 0). Default 10.
    pub rate_hz: f64,
    /// Constant bias: barometric minus ellipsoidal height \[m\]. Default 10.
    pub bias_m: f64,
    /// σ of the Gauss–Markov drift \[m\] (weather, temperature); 0
    /// disables it. Default 0.5.
    pub drift_sigma_m: f64,
    /// Correlation time of the drift \[s\] (> 0). Default 300.
    pub drift_correlation_time_s: f64,
    /// σ of the white noise \[m\]. Default 0.3.
    pub noise_sigma_m: f64,
}

impl Default for BaroSpec {
    fn default() -> Self {
        Self {
            rate_hz: 10.0,
            bias_m: 10.0,
            drift_sigma_m: 0.5,
            drift_correlation_time_s: 300.0,
            noise_sigma_m: 0.3,
        }
    }
}

impl BaroSpec {
    /// Check every parameter (fields named as in the scenario).
    pub fn validate(&self) -> Result<(), SimError> {
        positive("baro.rate_hz", self.rate_hz)?;
        finite("baro.bias_m", self.bias_m)?;
        non_negative("baro.drift_sigma_m", self.drift_sigma_m)?;
        positive(
            "baro.drift_correlation_time_s",
            self.drift_correlation_time_s,
        )?;
        non_negative("baro.noise_sigma_m", self.noise_sigma_m)
    }

    /// The σ written with each sample \[m\]: that of the error about
    /// height + bias, `√(σ_noise² + σ_drift²)`.
    pub fn sigma_m(&self) -> f64 {
        self.noise_sigma_m.hypot(self.drift_sigma_m)
    }
}

/// The truth at `start + j / rate_hz`, j = 0, 1, … within the span.
fn epochs(truth: &[TruthSample], rate_hz: f64) -> impl Iterator<Item = (usize, TruthSample)> + '_ {
    let (t0, t1) = match (truth.first(), truth.last()) {
        (Some(a), Some(b)) => (a.time_s, b.time_s),
        _ => (0.0, -1.0),
    };
    let count = if t1 >= t0 {
        ((t1 - t0) * rate_hz + 1e-9).floor() as usize + 1
    } else {
        0
    };
    (0..count)
        .filter_map(move |j| truth_at(truth, (t0 + j as f64 / rate_hz).min(t1)).map(|s| (j, s)))
}

/// The true forward speed of the point at `lever` from the IMU \[m/s\]:
/// body x of `v_b + ω_eb × l`.
pub fn wheel_point_speed(s: &TruthSample, lever: &Vec3<Body>) -> f64 {
    s.point_velocity_body(lever).x()
}

/// The wheel-speed samples of run `run` under master seed `seed`.
pub fn simulate_wheel_speed(
    spec: &WheelSpeedSpec,
    truth: &[TruthSample],
    seed: u64,
    run: u64,
) -> Result<Vec<WheelSpeedSample>, SimError> {
    spec.validate()?;
    let lever = Vec3::<Body>::assume_in_frame(Vector3::from(spec.lever_arm_m));
    let mut rng = Stream::WheelSpeedNoise.rng(seed, run);
    Ok(epochs(truth, spec.rate_hz)
        .map(|(_, s)| WheelSpeedSample {
            time_s: s.time_s,
            speed_mps: (1.0 + spec.scale_error) * wheel_point_speed(&s, &lever)
                + white(spec.noise_sigma_mps, &mut rng),
            sigma_mps: Some(spec.noise_sigma_mps),
        })
        .collect())
}

/// The barometer samples of run `run` under master seed `seed`.
pub fn simulate_baro(
    spec: &BaroSpec,
    truth: &[TruthSample],
    seed: u64,
    run: u64,
) -> Result<Vec<BaroSample>, SimError> {
    spec.validate()?;
    let mut drift_rng = Stream::BaroDrift.rng(seed, run);
    let mut noise_rng = Stream::BaroNoise.rng(seed, run);
    let mut drift = GaussMarkov::new(
        spec.drift_sigma_m,
        spec.drift_correlation_time_s,
        &mut drift_rng,
    );
    let dt = 1.0 / spec.rate_hz;
    let sigma = spec.sigma_m();
    Ok(epochs(truth, spec.rate_hz)
        .map(|(j, s)| {
            let d = if j == 0 {
                drift.value()
            } else {
                drift.step(dt, &mut drift_rng)
            };
            BaroSample {
                time_s: s.time_s,
                height_m: s.position.height_m
                    + spec.bias_m
                    + d
                    + white(spec.noise_sigma_m, &mut noise_rng),
                sigma_m: Some(sigma),
            }
        })
        .collect())
}
