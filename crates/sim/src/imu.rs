//! IMU error models from datasheet numbers, per axis: turn-on bias,
//! bias instability (first-order Gauss–Markov), white noise (angle /
//! velocity random walk) and scale-factor error.
//!
//! Measurement of each axis from the true value t (rate or specific force):
//! `m = (1 + k) t + b₀ + b_GM(t) + n`, with
//! - k ~ N(0, σ_k²) and b₀ ~ N(0, σ_b0²) drawn once per run (turn-on),
//! - b_GM a first-order Gauss–Markov process of stationary σ equal to the
//!   datasheet bias instability and correlation time τ (the usual
//!   approximation of the flicker floor of the Allan deviation),
//! - n white, per sample σ = N · √f_s for random walk coefficient N and
//!   sample rate f_s (the trapezoid increments then random-walk by N √t).
//!
//! The default, [`ImuSpec::default`], is an industrial-grade MEMS IMU (the
//! class of an ADIS16465 / Xsens MTi-630 after factory calibration):
//!
//! | | gyro | accelerometer |
//! |---|---|---|
//! | turn-on bias σ | 10 °/h | 1 mg |
//! | bias instability (τ = 300 s) | 3 °/h | 0.05 mg |
//! | random walk | 0.2 °/√h | 0.05 m/s/√h |
//! | scale factor σ | 300 ppm | 500 ppm |
//!
//! Each process draws from its own stream ([`crate::rng::Stream`]).

use aidnav_frames::constants::STANDARD_GRAVITY_M_S2;
use aidnav_sensors::ImuSample;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{SimError, non_negative, positive};
use crate::processes::{GaussMarkov, white};
use crate::rng::{RunRng, Stream};
use crate::truth::TruthSample;

/// Degrees per hour in rad/s.
const DEG_H_TO_RAD_S: f64 = std::f64::consts::PI / 180.0 / 3600.0;
/// °/√h in rad/√s (60 √s per √h).
const DEG_SQRT_H_TO_RAD_SQRT_S: f64 = std::f64::consts::PI / 180.0 / 60.0;
/// m/s/√h in m/s/√s.
const M_S_SQRT_H_TO_M_S_SQRT_S: f64 = 1.0 / 60.0;
/// Milli-g in m/s².
const MG_TO_M_S2: f64 = 1e-3 * STANDARD_GRAVITY_M_S2;
/// Parts per million.
const PPM: f64 = 1e-6;

/// Gyro errors per axis (x, y, z of the body), datasheet units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GyroErrors {
    /// σ of the turn-on bias \[deg/h\]. Default 10 on each axis.
    pub turn_on_bias_sigma_deg_h: [f64; 3],
    /// Bias instability, the σ of the Gauss–Markov bias \[deg/h\].
    /// Default 3.
    pub bias_instability_deg_h: [f64; 3],
    /// Correlation time of the Gauss–Markov bias \[s\] (> 0). Default 300.
    pub bias_correlation_time_s: [f64; 3],
    /// Angle random walk \[deg/√h\]. Default 0.2.
    pub angle_random_walk_deg_sqrt_h: [f64; 3],
    /// σ of the scale-factor error \[ppm\]. Default 300.
    pub scale_factor_sigma_ppm: [f64; 3],
}

impl Default for GyroErrors {
    fn default() -> Self {
        Self {
            turn_on_bias_sigma_deg_h: [10.0; 3],
            bias_instability_deg_h: [3.0; 3],
            bias_correlation_time_s: [300.0; 3],
            angle_random_walk_deg_sqrt_h: [0.2; 3],
            scale_factor_sigma_ppm: [300.0; 3],
        }
    }
}

/// Accelerometer errors per axis (x, y, z of the body), datasheet units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AccelErrors {
    /// σ of the turn-on bias \[mg\] (1 mg = 9.80665e-3 m/s²). Default 1.
    pub turn_on_bias_sigma_mg: [f64; 3],
    /// Bias instability, the σ of the Gauss–Markov bias \[mg\]. Default 0.05.
    pub bias_instability_mg: [f64; 3],
    /// Correlation time of the Gauss–Markov bias \[s\] (> 0). Default 300.
    pub bias_correlation_time_s: [f64; 3],
    /// Velocity random walk \[m/s/√h\]. Default 0.05.
    pub velocity_random_walk_m_s_sqrt_h: [f64; 3],
    /// σ of the scale-factor error \[ppm\]. Default 500.
    pub scale_factor_sigma_ppm: [f64; 3],
}

impl Default for AccelErrors {
    fn default() -> Self {
        Self {
            turn_on_bias_sigma_mg: [1.0; 3],
            bias_instability_mg: [0.05; 3],
            bias_correlation_time_s: [300.0; 3],
            velocity_random_walk_m_s_sqrt_h: [0.05; 3],
            scale_factor_sigma_ppm: [500.0; 3],
        }
    }
}

/// The IMU: its sample rate and error models (axes = vehicle body axes;
/// no mounting misalignment yet).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuSpec {
    /// Sample rate \[Hz\] (> 0), also the rate of the truth. Default 100.
    pub rate_hz: f64,
    /// Gyro errors.
    pub gyro: GyroErrors,
    /// Accelerometer errors.
    pub accel: AccelErrors,
}

impl Default for ImuSpec {
    fn default() -> Self {
        Self {
            rate_hz: 100.0,
            gyro: GyroErrors::default(),
            accel: AccelErrors::default(),
        }
    }
}

impl ImuSpec {
    /// An error-free IMU at `rate_hz` \[Hz\].
    pub fn ideal(rate_hz: f64) -> Self {
        let zero = [0.0; 3];
        Self {
            rate_hz,
            gyro: GyroErrors {
                turn_on_bias_sigma_deg_h: zero,
                bias_instability_deg_h: zero,
                angle_random_walk_deg_sqrt_h: zero,
                scale_factor_sigma_ppm: zero,
                ..GyroErrors::default()
            },
            accel: AccelErrors {
                turn_on_bias_sigma_mg: zero,
                bias_instability_mg: zero,
                velocity_random_walk_m_s_sqrt_h: zero,
                scale_factor_sigma_ppm: zero,
                ..AccelErrors::default()
            },
        }
    }

    /// Check every parameter (fields named as in the scenario).
    pub fn validate(&self) -> Result<(), SimError> {
        positive("imu.rate_hz", self.rate_hz)?;
        let g = &self.gyro;
        let a = &self.accel;
        for i in 0..3 {
            let f = |name: &str| format!("imu.{name}[{i}]");
            non_negative(
                f("gyro.turn_on_bias_sigma_deg_h"),
                g.turn_on_bias_sigma_deg_h[i],
            )?;
            non_negative(
                f("gyro.bias_instability_deg_h"),
                g.bias_instability_deg_h[i],
            )?;
            positive(
                f("gyro.bias_correlation_time_s"),
                g.bias_correlation_time_s[i],
            )?;
            non_negative(
                f("gyro.angle_random_walk_deg_sqrt_h"),
                g.angle_random_walk_deg_sqrt_h[i],
            )?;
            non_negative(
                f("gyro.scale_factor_sigma_ppm"),
                g.scale_factor_sigma_ppm[i],
            )?;
            non_negative(f("accel.turn_on_bias_sigma_mg"), a.turn_on_bias_sigma_mg[i])?;
            non_negative(f("accel.bias_instability_mg"), a.bias_instability_mg[i])?;
            positive(
                f("accel.bias_correlation_time_s"),
                a.bias_correlation_time_s[i],
            )?;
            non_negative(
                f("accel.velocity_random_walk_m_s_sqrt_h"),
                a.velocity_random_walk_m_s_sqrt_h[i],
            )?;
            non_negative(
                f("accel.scale_factor_sigma_ppm"),
                a.scale_factor_sigma_ppm[i],
            )?;
        }
        Ok(())
    }
}

/// The errors drawn once per run (the truth a filter's bias and scale
/// states should converge to, apart from the Gauss–Markov part).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuErrorDraw {
    /// Gyro turn-on bias \[rad/s\].
    pub gyro_bias_rad_s: Vector3<f64>,
    /// Gyro scale-factor error (dimensionless).
    pub gyro_scale_factor: Vector3<f64>,
    /// Accelerometer turn-on bias [m/s²].
    pub accel_bias_m_s2: Vector3<f64>,
    /// Accelerometer scale-factor error (dimensionless).
    pub accel_scale_factor: Vector3<f64>,
}

/// One instrument triad's error processes, in SI units.
struct Triad {
    scale: Vector3<f64>,
    bias: Vector3<f64>,
    markov: [GaussMarkov; 3],
    noise_sigma: Vector3<f64>,
    markov_rng: RunRng,
    noise_rng: RunRng,
}

impl Triad {
    /// Corrupt one true vector, after advancing the Gauss–Markov biases by
    /// `dt_s` (0 at the first sample: the initial draw applies).
    fn measure(&mut self, truth: Vector3<f64>, dt_s: f64) -> Vector3<f64> {
        Vector3::from_fn(|i, _| {
            let gm = if dt_s > 0.0 {
                self.markov[i].step(dt_s, &mut self.markov_rng)
            } else {
                self.markov[i].value()
            };
            (1.0 + self.scale[i]) * truth[i]
                + self.bias[i]
                + gm
                + white(self.noise_sigma[i], &mut self.noise_rng)
        })
    }
}

/// Per-axis draws of N(0, σ²) from one stream.
fn draw3(sigma: Vector3<f64>, rng: &mut RunRng) -> Vector3<f64> {
    Vector3::from_fn(|i, _| white(sigma[i], rng))
}

/// The IMU samples (one per truth sample, body axes, rad/s and m/s²) and
/// the turn-on errors drawn, for run `run` of master seed `seed`.
pub fn simulate_imu(
    spec: &ImuSpec,
    truth: &[TruthSample],
    seed: u64,
    run: u64,
) -> Result<(Vec<ImuSample>, ImuErrorDraw), SimError> {
    spec.validate()?;
    let sqrt_rate = spec.rate_hz.sqrt();
    let (g, a) = (&spec.gyro, &spec.accel);
    let v = |x: [f64; 3], unit: f64| Vector3::from(x) * unit;
    let triad = |scale_sigma: Vector3<f64>,
                 bias_sigma: Vector3<f64>,
                 gm_sigma: Vector3<f64>,
                 tau: [f64; 3],
                 noise_sigma: Vector3<f64>,
                 streams: [Stream; 4]| {
        let mut scale_rng = streams[0].rng(seed, run);
        let mut bias_rng = streams[1].rng(seed, run);
        let mut markov_rng = streams[2].rng(seed, run);
        let scale = draw3(scale_sigma, &mut scale_rng);
        let bias = draw3(bias_sigma, &mut bias_rng);
        let markov =
            std::array::from_fn(|i| GaussMarkov::new(gm_sigma[i], tau[i], &mut markov_rng));
        Triad {
            scale,
            bias,
            markov,
            noise_sigma,
            markov_rng,
            noise_rng: streams[3].rng(seed, run),
        }
    };
    let mut gyro = triad(
        v(g.scale_factor_sigma_ppm, PPM),
        v(g.turn_on_bias_sigma_deg_h, DEG_H_TO_RAD_S),
        v(g.bias_instability_deg_h, DEG_H_TO_RAD_S),
        g.bias_correlation_time_s,
        v(
            g.angle_random_walk_deg_sqrt_h,
            DEG_SQRT_H_TO_RAD_SQRT_S * sqrt_rate,
        ),
        [
            Stream::GyroScaleFactor,
            Stream::GyroTurnOnBias,
            Stream::GyroBiasInstability,
            Stream::GyroNoise,
        ],
    );
    let mut accel = triad(
        v(a.scale_factor_sigma_ppm, PPM),
        v(a.turn_on_bias_sigma_mg, MG_TO_M_S2),
        v(a.bias_instability_mg, MG_TO_M_S2),
        a.bias_correlation_time_s,
        v(
            a.velocity_random_walk_m_s_sqrt_h,
            M_S_SQRT_H_TO_M_S_SQRT_S * sqrt_rate,
        ),
        [
            Stream::AccelScaleFactor,
            Stream::AccelTurnOnBias,
            Stream::AccelBiasInstability,
            Stream::AccelNoise,
        ],
    );
    let draw = ImuErrorDraw {
        gyro_bias_rad_s: gyro.bias,
        gyro_scale_factor: gyro.scale,
        accel_bias_m_s2: accel.bias,
        accel_scale_factor: accel.scale,
    };
    let mut previous_time = None;
    let samples = truth
        .iter()
        .map(|s| {
            let dt = previous_time.map_or(0.0, |t0| s.time_s - t0);
            previous_time = Some(s.time_s);
            ImuSample {
                time_s: s.time_s,
                specific_force: accel.measure(s.specific_force_body.raw(), dt),
                angular_rate: gyro.measure(s.angular_rate_body.raw(), dt),
            }
        })
        .collect();
    Ok((samples, draw))
}
