//! IMU error models from datasheet numbers, per axis: turn-on bias,
//! bias instability (first-order Gauss–Markov), white noise (angle /
//! velocity random walk), scale-factor error, axis misalignment, vibration,
//! quantisation and saturation; and the sampling: time-stamp jitter,
//! dropped samples, rate or increment output.
//!
//! Measurement of each triad from the true vector t (angular rate or
//! specific force, body axes):
//! `m = Q(S((I + K + M) t + b₀ + b_GM(t) + n + v(t)))`, with
//! - K = diag(k), k ~ N(0, σ_k²) per axis and b₀ ~ N(0, σ_b0²) per axis,
//!   drawn once per run (turn-on),
//! - M the misalignment / non-orthogonality matrix: zero diagonal,
//!   off-diagonal elements ~ N(0, σ_M²) drawn once per run (σ_M =
//!   `misalignment_sigma_mrad`),
//! - b_GM a first-order Gauss–Markov process of stationary σ equal to the
//!   datasheet bias instability and correlation time τ (the usual
//!   approximation of the flicker floor of the Allan deviation),
//! - n white, per sample σ = N · √f_s for random walk coefficient N and
//!   sample rate f_s (the trapezoid increments then random-walk by N √t),
//! - v the vibration: a sum of sinusoidal lines ([`VibrationLine`]), each
//!   of fixed amplitude per axis and a phase per axis drawn once per run,
//! - S the saturation (clip to ± range) and Q the quantisation (round to a
//!   multiple of the LSB), applied in that order to the output (the
//!   clipping range is the largest multiple of the LSB within the range).
//!
//! With [`ImuOutput::Increments`] t is the mean of the truth over the
//! sample interval and v the exact mean of the vibration over it (see
//! [`ImuOutput`]). The time stamp written is the true sampling instant plus
//! white jitter ([`ImuSpec::time_jitter_sigma_s`]); dropped samples
//! ([`ImuSpec::drop_probability`]) are missing from the output (the error
//! processes still run through them).
//!
//! The default, [`ImuSpec::default`], is an industrial-grade MEMS IMU (the
//! class of an ADIS16465 / Xsens MTi-630 after factory calibration) with
//! every term after the scale factor off:
//!
//! | | gyro | accelerometer |
//! |---|---|---|
//! | turn-on bias σ | 10 °/h | 1 mg |
//! | bias instability (τ = 300 s) | 3 °/h | 0.05 mg |
//! | random walk | 0.2 °/√h | 0.05 m/s/√h |
//! | scale factor σ | 300 ppm | 500 ppm |
//!
//! [`ImuSpec::grade`] gives one IMU per performance class
//! ([`ImuGrade`]); σ of a turn-on error is the datasheet's ± limit / 3
//! where the datasheet gives a limit:
//!
//! | grade (example parts) | gyro turn-on / instability (τ) / ARW / SF / misalignment / range / LSB | accel turn-on / instability (τ) / VRW / SF / misalignment / range / LSB | output |
//! |---|---|---|---|
//! | consumer (Bosch BMI160, phone MEMS) | 3600 °/h (±3 °/s) / 10 °/h (100 s) / 0.42 °/√h (0.007 °/s/√Hz) / 3000 ppm / 3 mrad / 2000 °/s / 16 bit (0.061 °/s) | 13 mg (±40 mg) / 0.1 mg (100 s) / 0.106 m/s/√h (180 µg/√Hz) / 3000 ppm / 3 mrad / 8 g / 16 bit (0.24 mg) | rates |
//! | industrial (ADIS16465, MTi-630) = [`ImuSpec::default`] | 10 °/h / 3 °/h (300 s) / 0.2 °/√h / 300 ppm / – / – / – | 1 mg / 0.05 mg (300 s) / 0.05 m/s/√h / 500 ppm / – / – / – | rates |
//! | tactical (Safran STIM300, Honeywell HG1700) | 4 °/h / 0.5 °/h (1 h) / 0.15 °/√h / 150 ppm / 0.3 mrad / 400 °/s / 0.22 °/h | 0.75 mg / 0.05 mg (1 h) / 0.07 m/s/√h / 300 ppm / 0.3 mrad / 10 g / 1.9 µg | rates |
//! | navigation (ring-laser gyro, Honeywell HG9900 class; quartz pendulous accelerometers) | 0.003 °/h / 0.003 °/h (1 h) / 0.002 °/√h / 5 ppm / 0.02 mrad / 400 °/s / – | 0.025 mg / 0.005 mg (1 h) / 0.004 m/s/√h (≈ 7 µg/√Hz) / 100 ppm / 0.02 mrad / 20 g / – | increments |
//!
//! Sources: BMI160 datasheet (zero-rate offset ±3 °/s, gyro noise
//! 0.007 °/s/√Hz, zero-g offset ±40 mg, accel noise 180 µg/√Hz,
//! sensitivity and cross-axis tolerance ±1 %); published Allan deviations
//! of such parts for their bias instability (5–20 °/h, ≈ 0.1 mg); STIM300
//! datasheet (gyro ARW 0.15 °/√h, bias instability 0.5 °/h, bias
//! repeatability 4 °/h, resolution 0.22 °/h; accelerometer 0.07 m/s/√h,
//! 0.05 mg, repeatability 0.75 mg, resolution 1.9 µg); HG1700 AG58 (scale
//! factors 150 / 300 ppm); HG9900 class (0.002 °/√h, 0.003 °/h, 5 ppm,
//! 25 µg). The navigation grade leaves quantisation off: a ring-laser
//! gyro's counter keeps the residual of each pulse, so its quantisation
//! does not add up as independent per-sample rounding would. Time-stamp
//! jitter, dropped samples and vibration belong to the installation, not
//! the grade: off in every grade.
//!
//! Each process draws from its own stream ([`crate::rng::Stream`]).

use std::f64::consts::TAU;

use aidnav_frames::constants::STANDARD_GRAVITY_M_S2;
use aidnav_sensors::ImuSample;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::error::{SimError, check, non_negative, positive};
use crate::processes::{GaussMarkov, white};
use crate::rng::{RngExt, RunRng, Stream};
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
/// Milliradians.
const MRAD: f64 = 1e-3;
/// Largest time-stamp jitter accepted, as a fraction of the sample
/// interval: at 0.1 two consecutive stamps swap with probability ~1e-12.
const MAX_JITTER_FRACTION: f64 = 0.1;
/// The number of vibration lines an [`ImuSpec`] holds.
pub const VIBRATION_LINES: usize = 4;

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
    /// σ of each off-diagonal element of the misalignment matrix M
    /// \[mrad\] (axis misalignment and non-orthogonality; 1 mrad couples
    /// 0.1 % of one axis's rate into another). Default 0 (off).
    pub misalignment_sigma_mrad: f64,
    /// Output resolution, one least significant bit \[rad/s\]: each output
    /// is rounded to a multiple of it. Default 0 (off).
    pub quantisation_lsb_rad_s: f64,
    /// Measurement range \[deg/s\]: outputs are clipped to ± range.
    /// Default 0 (off: unlimited).
    pub range_deg_s: f64,
}

impl Default for GyroErrors {
    fn default() -> Self {
        Self {
            turn_on_bias_sigma_deg_h: [10.0; 3],
            bias_instability_deg_h: [3.0; 3],
            bias_correlation_time_s: [300.0; 3],
            angle_random_walk_deg_sqrt_h: [0.2; 3],
            scale_factor_sigma_ppm: [300.0; 3],
            misalignment_sigma_mrad: 0.0,
            quantisation_lsb_rad_s: 0.0,
            range_deg_s: 0.0,
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
    /// σ of each off-diagonal element of the misalignment matrix M
    /// \[mrad\]. Default 0 (off).
    pub misalignment_sigma_mrad: f64,
    /// Output resolution, one least significant bit \[m/s²\]. Default 0
    /// (off).
    pub quantisation_lsb_m_s2: f64,
    /// Measurement range \[g\] (1 g = 9.80665 m/s²): outputs are clipped
    /// to ± range. Default 0 (off: unlimited).
    pub range_g: f64,
}

impl Default for AccelErrors {
    fn default() -> Self {
        Self {
            turn_on_bias_sigma_mg: [1.0; 3],
            bias_instability_mg: [0.05; 3],
            bias_correlation_time_s: [300.0; 3],
            velocity_random_walk_m_s_sqrt_h: [0.05; 3],
            scale_factor_sigma_ppm: [500.0; 3],
            misalignment_sigma_mrad: 0.0,
            quantisation_lsb_m_s2: 0.0,
            range_g: 0.0,
        }
    }
}

/// One sinusoidal vibration line (road or engine excitation sensed by
/// the IMU on top of the vehicle's motion): on axis i the accelerometer
/// adds `a_i sin(2π f t + φ_i)` and the gyro `w_i sin(2π f t + ψ_i)`, t
/// the time since the first sample and the phases φ_i, ψ_i uniform in
/// \[0, 2π) drawn once per run. A line whose amplitudes are all 0 is
/// unused. Lines above the Nyquist frequency f_s / 2 alias in
/// [`ImuOutput::Rates`] (as on a real IMU without anti-alias filter).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VibrationLine {
    /// Frequency f \[Hz\] (≥ 0).
    pub frequency_hz: f64,
    /// Accelerometer amplitude per body axis \[m/s²\] (≥ 0).
    pub accel_amplitude_m_s2: [f64; 3],
    /// Gyro amplitude per body axis \[deg/s\] (≥ 0).
    pub gyro_amplitude_deg_s: [f64; 3],
}

impl VibrationLine {
    /// Whether the line adds anything.
    fn is_used(&self) -> bool {
        self.accel_amplitude_m_s2
            .iter()
            .chain(&self.gyro_amplitude_deg_s)
            .any(|&a| a != 0.0)
    }
}

/// What one output sample's values stand for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuOutput {
    /// The rate and specific force at the sampling instant (default).
    #[default]
    Rates,
    /// The mean rate and specific force over the interval ending at the
    /// sampling instant — the angle and velocity increments of an
    /// integrating IMU divided by the interval, still written as an
    /// [`ImuSample`] of rates. Sample k (k ≥ 1) holds the trapezoid mean
    /// of truth samples k − 1 and k, `(t_{k−1} + t_k) / 2`, the vibration
    /// its exact mean over \[t_{k−1}, t_k\]; sample 0, which has no
    /// interval, holds the instantaneous values. The error terms (scale
    /// factor, misalignment, biases, noise, saturation, quantisation) apply
    /// to the mean as to a rate; the white noise keeps its per-sample
    /// σ = N √f_s, the σ of the mean of white noise of density N over
    /// 1/f_s.
    Increments,
}

/// The IMU: its sample rate, error models and sampling (axes = vehicle
/// body axes; no mounting misalignment).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuSpec {
    /// Sample rate \[Hz\] (> 0), also the rate of the truth. Default 100.
    pub rate_hz: f64,
    /// What the samples' values stand for. Default [`ImuOutput::Rates`].
    pub output: ImuOutput,
    /// σ of the time-stamp jitter \[s\]: the time written is the true
    /// sampling instant plus white noise of this σ (the values are those
    /// of the true instant). At most 0.1 / `rate_hz`, so the stamps stay
    /// in order. Default 0 (off).
    pub time_jitter_sigma_s: f64,
    /// Probability that a sample is dropped (missing from the output),
    /// independently for each sample, in \[0, 1). Default 0 (off).
    pub drop_probability: f64,
    /// Gyro errors.
    pub gyro: GyroErrors,
    /// Accelerometer errors.
    pub accel: AccelErrors,
    /// Vibration lines (at most [`VIBRATION_LINES`]; in TOML an array of
    /// up to that many tables, the rest unused). Default: none.
    #[serde(
        serialize_with = "serialize_lines",
        deserialize_with = "deserialize_lines",
        skip_serializing_if = "no_lines"
    )]
    pub vibration: [VibrationLine; VIBRATION_LINES],
}

/// Whether no vibration line is used (serde skips the field then).
fn no_lines(lines: &[VibrationLine; VIBRATION_LINES]) -> bool {
    lines.iter().all(|l| *l == VibrationLine::default())
}

/// The lines up to the last one that is not all zero.
fn serialize_lines<S: Serializer>(
    lines: &[VibrationLine; VIBRATION_LINES],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let n = lines
        .iter()
        .rposition(|l| *l != VibrationLine::default())
        .map_or(0, |i| i + 1);
    serializer.collect_seq(&lines[..n])
}

/// Up to [`VIBRATION_LINES`] lines, the rest unused.
fn deserialize_lines<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<[VibrationLine; VIBRATION_LINES], D::Error> {
    let given = Vec::<VibrationLine>::deserialize(deserializer)?;
    if given.len() > VIBRATION_LINES {
        return Err(serde::de::Error::invalid_length(
            given.len(),
            &"at most 4 vibration lines",
        ));
    }
    let mut lines = [VibrationLine::default(); VIBRATION_LINES];
    lines[..given.len()].copy_from_slice(&given);
    Ok(lines)
}

impl Default for ImuSpec {
    fn default() -> Self {
        Self {
            rate_hz: 100.0,
            output: ImuOutput::Rates,
            time_jitter_sigma_s: 0.0,
            drop_probability: 0.0,
            gyro: GyroErrors::default(),
            accel: AccelErrors::default(),
            vibration: [VibrationLine::default(); VIBRATION_LINES],
        }
    }
}

/// Performance class of an IMU, for [`ImuSpec::grade`] (the table in the
/// [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuGrade {
    /// Consumer MEMS (phones, Bosch BMI160 class): degrees per second of
    /// turn-on bias, 16-bit output.
    Consumer,
    /// Industrial MEMS (ADIS16465, Xsens MTi-630 class): [`ImuSpec::default`].
    Industrial,
    /// Tactical (Safran STIM300, Honeywell HG1700 class): sub-degree per
    /// hour bias instability.
    Tactical,
    /// Navigation (ring-laser gyros, Honeywell HG9900 class): thousandths
    /// of a degree per hour, increment output.
    Navigation,
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
            ..Self::default()
        }
    }

    /// A typical IMU of class `grade` at `rate_hz` \[Hz\]: the numbers of
    /// the table in the [module docs](self). [`ImuGrade::Industrial`] is
    /// [`ImuSpec::default`] at that rate.
    ///
    /// ```
    /// use aidnav_sim::imu::{ImuGrade, ImuSpec};
    /// assert_eq!(ImuSpec::grade(ImuGrade::Industrial, 100.0), ImuSpec::default());
    /// let c = ImuSpec::grade(ImuGrade::Consumer, 200.0);
    /// assert!(c.validate().is_ok() && c.gyro.range_deg_s == 2000.0);
    /// ```
    pub fn grade(grade: ImuGrade, rate_hz: f64) -> Self {
        /// 16-bit output over ± range: LSB = range / 2¹⁵.
        fn lsb16(range: f64) -> f64 {
            range / 32768.0
        }
        let industrial = Self {
            rate_hz,
            ..Self::default()
        };
        match grade {
            ImuGrade::Industrial => industrial,
            ImuGrade::Consumer => Self {
                gyro: GyroErrors {
                    turn_on_bias_sigma_deg_h: [3600.0; 3],
                    bias_instability_deg_h: [10.0; 3],
                    bias_correlation_time_s: [100.0; 3],
                    angle_random_walk_deg_sqrt_h: [0.42; 3],
                    scale_factor_sigma_ppm: [3000.0; 3],
                    misalignment_sigma_mrad: 3.0,
                    quantisation_lsb_rad_s: lsb16(2000f64.to_radians()),
                    range_deg_s: 2000.0,
                },
                accel: AccelErrors {
                    turn_on_bias_sigma_mg: [13.0; 3],
                    bias_instability_mg: [0.1; 3],
                    bias_correlation_time_s: [100.0; 3],
                    velocity_random_walk_m_s_sqrt_h: [0.106; 3],
                    scale_factor_sigma_ppm: [3000.0; 3],
                    misalignment_sigma_mrad: 3.0,
                    quantisation_lsb_m_s2: lsb16(8.0 * STANDARD_GRAVITY_M_S2),
                    range_g: 8.0,
                },
                ..industrial
            },
            ImuGrade::Tactical => Self {
                gyro: GyroErrors {
                    turn_on_bias_sigma_deg_h: [4.0; 3],
                    bias_instability_deg_h: [0.5; 3],
                    bias_correlation_time_s: [3600.0; 3],
                    angle_random_walk_deg_sqrt_h: [0.15; 3],
                    scale_factor_sigma_ppm: [150.0; 3],
                    misalignment_sigma_mrad: 0.3,
                    quantisation_lsb_rad_s: 0.22 * DEG_H_TO_RAD_S,
                    range_deg_s: 400.0,
                },
                accel: AccelErrors {
                    turn_on_bias_sigma_mg: [0.75; 3],
                    bias_instability_mg: [0.05; 3],
                    bias_correlation_time_s: [3600.0; 3],
                    velocity_random_walk_m_s_sqrt_h: [0.07; 3],
                    scale_factor_sigma_ppm: [300.0; 3],
                    misalignment_sigma_mrad: 0.3,
                    quantisation_lsb_m_s2: 1.9e-3 * MG_TO_M_S2,
                    range_g: 10.0,
                },
                ..industrial
            },
            ImuGrade::Navigation => Self {
                output: ImuOutput::Increments,
                gyro: GyroErrors {
                    turn_on_bias_sigma_deg_h: [0.003; 3],
                    bias_instability_deg_h: [0.003; 3],
                    bias_correlation_time_s: [3600.0; 3],
                    angle_random_walk_deg_sqrt_h: [0.002; 3],
                    scale_factor_sigma_ppm: [5.0; 3],
                    misalignment_sigma_mrad: 0.02,
                    quantisation_lsb_rad_s: 0.0,
                    range_deg_s: 400.0,
                },
                accel: AccelErrors {
                    turn_on_bias_sigma_mg: [0.025; 3],
                    bias_instability_mg: [0.005; 3],
                    bias_correlation_time_s: [3600.0; 3],
                    velocity_random_walk_m_s_sqrt_h: [0.004; 3],
                    scale_factor_sigma_ppm: [100.0; 3],
                    misalignment_sigma_mrad: 0.02,
                    quantisation_lsb_m_s2: 0.0,
                    range_g: 20.0,
                },
                ..industrial
            },
        }
    }

    /// Check every parameter (fields named as in the scenario, e.g.
    /// `imu.gyro.range_deg_s`, `imu.vibration[1].frequency_hz`).
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
        non_negative(
            "imu.gyro.misalignment_sigma_mrad",
            g.misalignment_sigma_mrad,
        )?;
        non_negative(
            "imu.accel.misalignment_sigma_mrad",
            a.misalignment_sigma_mrad,
        )?;
        non_negative("imu.gyro.quantisation_lsb_rad_s", g.quantisation_lsb_rad_s)?;
        non_negative("imu.accel.quantisation_lsb_m_s2", a.quantisation_lsb_m_s2)?;
        non_negative("imu.gyro.range_deg_s", g.range_deg_s)?;
        non_negative("imu.accel.range_g", a.range_g)?;
        let range_vs_lsb = |field: &str, range: f64, lsb: f64| {
            check(
                field,
                range,
                range == 0.0 || lsb == 0.0 || range >= lsb,
                "must be 0 (off) or at least one quantisation LSB",
            )
        };
        range_vs_lsb(
            "imu.gyro.range_deg_s",
            g.range_deg_s.to_radians(),
            g.quantisation_lsb_rad_s,
        )?;
        range_vs_lsb(
            "imu.accel.range_g",
            a.range_g * STANDARD_GRAVITY_M_S2,
            a.quantisation_lsb_m_s2,
        )?;
        non_negative("imu.time_jitter_sigma_s", self.time_jitter_sigma_s)?;
        check(
            "imu.time_jitter_sigma_s",
            self.time_jitter_sigma_s,
            self.time_jitter_sigma_s * self.rate_hz <= MAX_JITTER_FRACTION,
            "must be at most 0.1 / imu.rate_hz (time stamps in order)",
        )?;
        check(
            "imu.drop_probability",
            self.drop_probability,
            (0.0..1.0).contains(&self.drop_probability),
            "must be in [0, 1)",
        )?;
        for (l, line) in self.vibration.iter().enumerate() {
            non_negative(
                format!("imu.vibration[{l}].frequency_hz"),
                line.frequency_hz,
            )?;
            for i in 0..3 {
                non_negative(
                    format!("imu.vibration[{l}].accel_amplitude_m_s2[{i}]"),
                    line.accel_amplitude_m_s2[i],
                )?;
                non_negative(
                    format!("imu.vibration[{l}].gyro_amplitude_deg_s[{i}]"),
                    line.gyro_amplitude_deg_s[i],
                )?;
            }
        }
        Ok(())
    }
}

/// The errors drawn once per run (the truth a filter's bias, scale and
/// misalignment states should converge to, apart from the Gauss–Markov
/// part).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuErrorDraw {
    /// Gyro turn-on bias \[rad/s\].
    pub gyro_bias_rad_s: Vector3<f64>,
    /// Gyro scale-factor error (dimensionless).
    pub gyro_scale_factor: Vector3<f64>,
    /// Accelerometer turn-on bias \[m/s²\].
    pub accel_bias_m_s2: Vector3<f64>,
    /// Accelerometer scale-factor error (dimensionless).
    pub accel_scale_factor: Vector3<f64>,
    /// Gyro misalignment matrix M (zero diagonal, dimensionless; zero
    /// when off): the gyro measures `(I + diag(k) + M) ω + …`.
    pub gyro_misalignment: Matrix3<f64>,
    /// Accelerometer misalignment matrix M (zero diagonal, dimensionless;
    /// zero when off).
    pub accel_misalignment: Matrix3<f64>,
}

/// Saturation then quantisation of one triad's output.
#[derive(Debug, Clone, Copy)]
struct Limits {
    /// The LSB (0 = off).
    lsb: f64,
    /// The clipping range (0 = off), a multiple of the LSB if that is on.
    range: f64,
}

impl Limits {
    fn new(lsb: f64, range: f64) -> Self {
        let range = if lsb > 0.0 {
            (range / lsb).floor() * lsb
        } else {
            range
        };
        Self { lsb, range }
    }

    fn apply(&self, x: f64) -> f64 {
        let mut x = x;
        if self.range > 0.0 {
            x = x.clamp(-self.range, self.range);
        }
        if self.lsb > 0.0 {
            x = (x / self.lsb).round() * self.lsb;
        }
        x
    }
}

/// One instrument triad's error processes, in SI units.
struct Triad {
    scale: Vector3<f64>,
    bias: Vector3<f64>,
    misalignment: Option<Matrix3<f64>>,
    markov: [GaussMarkov; 3],
    noise_sigma: Vector3<f64>,
    limits: Limits,
    markov_rng: RunRng,
    noise_rng: RunRng,
}

impl Triad {
    /// Corrupt one true vector, after advancing the Gauss–Markov biases by
    /// `dt_s` (0 at the first sample: the initial draw applies); `extra`
    /// (vibration) is added before saturation and quantisation.
    fn measure(
        &mut self,
        truth: Vector3<f64>,
        dt_s: f64,
        extra: Option<Vector3<f64>>,
    ) -> Vector3<f64> {
        let coupled = self.misalignment.map(|m| m * truth);
        let mut out = Vector3::from_fn(|i, _| {
            let gm = if dt_s > 0.0 {
                self.markov[i].step(dt_s, &mut self.markov_rng)
            } else {
                self.markov[i].value()
            };
            let mut scaled = (1.0 + self.scale[i]) * truth[i];
            if let Some(c) = coupled {
                scaled += c[i];
            }
            scaled + self.bias[i] + gm + white(self.noise_sigma[i], &mut self.noise_rng)
        });
        if let Some(e) = extra {
            out += e;
        }
        if self.limits.lsb > 0.0 || self.limits.range > 0.0 {
            out = out.map(|x| self.limits.apply(x));
        }
        out
    }
}

/// Per-axis draws of N(0, σ²) from one stream.
fn draw3(sigma: Vector3<f64>, rng: &mut RunRng) -> Vector3<f64> {
    Vector3::from_fn(|i, _| white(sigma[i], rng))
}

/// The misalignment matrix of σ `sigma` \[rad\]: off-diagonal elements
/// drawn row-major from `stream`; `None` when σ = 0.
fn misalignment(sigma: f64, stream: Stream, seed: u64, run: u64) -> Option<Matrix3<f64>> {
    (sigma > 0.0).then(|| {
        let mut rng = stream.rng(seed, run);
        let mut m = Matrix3::zeros();
        for r in 0..3 {
            for c in 0..3 {
                if r != c {
                    m[(r, c)] = white(sigma, &mut rng);
                }
            }
        }
        m
    })
}

/// Amplitudes and phases \[rad\] per axis of one instrument's line.
type Sinusoid = [Vector3<f64>; 2];

/// The vibration lines in SI units with their drawn phases.
struct Vibration {
    /// Per line: ω \[rad/s\], accel amplitudes \[m/s²\] and phases, gyro
    /// amplitudes \[rad/s\] and phases.
    lines: Vec<(f64, Sinusoid, Sinusoid)>,
}

impl Vibration {
    /// `None` when no line is used. Phases are drawn for every line slot
    /// in order, so enabling one line leaves the others' phases unchanged.
    fn new(spec: &ImuSpec, seed: u64, run: u64) -> Option<Self> {
        if !spec.vibration.iter().any(VibrationLine::is_used) {
            return None;
        }
        let mut rng = Stream::ImuVibrationPhase.rng(seed, run);
        let mut lines = Vec::new();
        for line in &spec.vibration {
            let mut phases = [0.0; 6];
            for p in &mut phases {
                *p = TAU * rng.random::<f64>();
            }
            if line.is_used() {
                let accel = [
                    Vector3::from(line.accel_amplitude_m_s2),
                    Vector3::new(phases[0], phases[1], phases[2]),
                ];
                let gyro = [
                    Vector3::from(line.gyro_amplitude_deg_s).map(f64::to_radians),
                    Vector3::new(phases[3], phases[4], phases[5]),
                ];
                lines.push((TAU * line.frequency_hz, accel, gyro));
            }
        }
        Some(Self { lines })
    }

    /// (accel, gyro) vibration at time `t_s` since the first sample, or
    /// their mean over \[`t_s` − `interval_s`, `t_s`\] if `interval_s` > 0.
    fn at(&self, t_s: f64, interval_s: f64) -> (Vector3<f64>, Vector3<f64>) {
        let mut sum = (Vector3::zeros(), Vector3::zeros());
        for (omega, accel, gyro) in &self.lines {
            let value = |[amp, phase]: &Sinusoid| {
                Vector3::from_fn(|i, _| {
                    let x1 = omega * t_s + phase[i];
                    let wt = omega * interval_s;
                    if interval_s > 0.0 && wt != 0.0 {
                        // Mean of sin over [x1 − ωΔ, x1]: (cos(x1 − ωΔ) − cos x1) / (ωΔ).
                        amp[i] * ((x1 - wt).cos() - x1.cos()) / wt
                    } else {
                        amp[i] * x1.sin()
                    }
                })
            };
            sum.0 += value(accel);
            sum.1 += value(gyro);
        }
        sum
    }
}

/// The IMU samples (body axes, rad/s and m/s²; one per truth sample
/// unless samples are dropped) and the turn-on errors drawn, for run
/// `run` of master seed `seed`.
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
                 misalignment: Option<Matrix3<f64>>,
                 limits: Limits,
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
            misalignment,
            markov,
            noise_sigma,
            limits,
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
        misalignment(
            g.misalignment_sigma_mrad * MRAD,
            Stream::GyroMisalignment,
            seed,
            run,
        ),
        Limits::new(g.quantisation_lsb_rad_s, g.range_deg_s.to_radians()),
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
        misalignment(
            a.misalignment_sigma_mrad * MRAD,
            Stream::AccelMisalignment,
            seed,
            run,
        ),
        Limits::new(a.quantisation_lsb_m_s2, a.range_g * STANDARD_GRAVITY_M_S2),
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
        gyro_misalignment: gyro.misalignment.unwrap_or_default(),
        accel_misalignment: accel.misalignment.unwrap_or_default(),
    };
    let vibration = Vibration::new(spec, seed, run);
    let mut jitter_rng =
        (spec.time_jitter_sigma_s > 0.0).then(|| Stream::ImuTimeJitter.rng(seed, run));
    let mut drop_rng = (spec.drop_probability > 0.0).then(|| Stream::ImuDropout.rng(seed, run));
    let increments = spec.output == ImuOutput::Increments;
    let t0 = truth.first().map_or(0.0, |s| s.time_s);
    let mut samples = Vec::with_capacity(truth.len());
    for (k, s) in truth.iter().enumerate() {
        let previous = k.checked_sub(1).map(|j| &truth[j]);
        let dt = previous.map_or(0.0, |p| s.time_s - p.time_s);
        let (f, w) = match previous {
            Some(p) if increments => (
                0.5 * (p.specific_force_body.raw() + s.specific_force_body.raw()),
                0.5 * (p.angular_rate_body.raw() + s.angular_rate_body.raw()),
            ),
            _ => (s.specific_force_body.raw(), s.angular_rate_body.raw()),
        };
        let (vib_f, vib_w) = match &vibration {
            Some(vib) => {
                let (vf, vw) = vib.at(s.time_s - t0, if increments { dt } else { 0.0 });
                (Some(vf), Some(vw))
            }
            None => (None, None),
        };
        let sample = ImuSample {
            time_s: match &mut jitter_rng {
                Some(rng) => s.time_s + white(spec.time_jitter_sigma_s, rng),
                None => s.time_s,
            },
            specific_force: accel.measure(f, dt, vib_f),
            angular_rate: gyro.measure(w, dt, vib_w),
        };
        let dropped = drop_rng
            .as_mut()
            .is_some_and(|rng| rng.random::<f64>() < spec.drop_probability);
        if !dropped {
            samples.push(sample);
        }
    }
    Ok((samples, draw))
}
