//! The configuration file of `aidnav process` and its validation.

use std::path::PathBuf;

use aidnav_estimation::adaptive::DiagonalRule;
use aidnav_estimation::gmdh::GmdhConfig;
use aidnav_estimation::{Scheme, SchemeParameters};
use aidnav_frames::Vec3;
use aidnav_ins::standstill::StandstillThresholds;
use aidnav_integration::aiding::{
    BaroConfig, BaroSource, NonHolonomic, NonHolonomicSource, StandstillSource, StandstillUpdates,
    WheelSpeedConfig, WheelSpeedSource,
};
use aidnav_integration::ned::RecoveryConfig;
use aidnav_integration::state::{Augmented, BlockDynamics, StateLayout};
pub use aidnav_io::checks::CheckLevel;
use aidnav_sensors::{BaroSample, WheelSpeedSample};
use aidnav_supervisors::outage::{BridgeConfig, RelaySchedule};
use serde::{Deserialize, Deserializer, Serialize};

/// An array of exactly `N` numbers: serde's `[f64; N]` reads the first `N`
/// elements of a longer TOML array and drops the rest without a word.
fn exact_array<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    let len = v.len();
    v.try_into().map_err(|_| {
        serde::de::Error::invalid_length(len, &format!("an array of length {N}").as_str())
    })
}

/// [`exact_array`] for an optional key (set only when written).
fn exact_array_option<'de, D: Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    exact_array(d).map(Some)
}

pub use aidnav_io::formats::{BaroFormat, GnssFormat, ImuFormat, WheelSpeedFormat};

/// Where the data are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DataFiles {
    /// Directory of the files (relative: to the configuration file).
    pub dir: PathBuf,
    /// IMU file.
    pub imu: PathBuf,
    /// Its format. Default `rtklib_tagged`.
    #[serde(default)]
    pub imu_format: ImuFormat,
    /// RTKLIB time-tag file of the IMU (for `rtklib_tagged`).
    #[serde(default)]
    pub imu_tags: Option<PathBuf>,
    /// Units of a `generic_csv` IMU file whose columns are named `gx, gy,
    /// gz, ax, ay, az`: `{ gyro = "rad_s" | "deg_s", accel = "m_s2" | "g",
    /// kind = "rates" | "increments" }` (kind default `rates`); only with
    /// `imu_format = "generic_csv"`. Default none: the columns carry their
    /// units in their names (`gx_rad_s … az_m_s2`). See
    /// `aidnav_io::kfgins`.
    #[serde(default)]
    pub imu_units: Option<aidnav_io::kfgins::ImuUnits>,
    /// GNSS file.
    pub gnss: PathBuf,
    /// Its format. Default `rtklib_pos`.
    #[serde(default)]
    pub gnss_format: GnssFormat,
    /// σ of each horizontal axis and of up \[m\] for every fix of a
    /// `generic_csv` GNSS file without σ columns (its columns win when it
    /// has them); only with `gnss_format = "generic_csv"`. Default none.
    #[serde(default, deserialize_with = "exact_array_option")]
    pub gnss_sigma_m: Option<[f64; 2]>,
}

/// IMU handling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuConfig {
    /// Added to the IMU time \[s\] (a logging delay). Default 0.
    pub time_offset_s: f64,
    /// Sensor → body rotation as (roll, pitch, yaw) \[deg\], Groves'
    /// Euler_to_CTM: `f_body = C(roll, pitch, yaw) f_sensor`; body axes
    /// forward, right, down. Default [0, 0, 0] (the sensor frame is the body
    /// frame).
    #[serde(deserialize_with = "exact_array")]
    pub mounting_deg: [f64; 3],
    /// Zero-phase moving-average window \[s\] (0: none), against a
    /// vibration line in the gyros. Default 0.
    pub smoothing_s: f64,
    /// Noise terms of the filter model (`[imu.noise]`), and whether
    /// `process` tunes them first (`auto = true`).
    pub noise: NoiseConfig,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            time_offset_s: 0.0,
            mounting_deg: [0.0; 3],
            smoothing_s: 0.0,
            noise: NoiseConfig::default(),
        }
    }
}

/// The `[imu.noise]` table: the model's noise terms
/// ([`aidnav_models::ned_ins::ImuNoise`], every key of it) and `auto`.
///
/// With `auto = true`, `aidnav process` first runs the tuning of
/// [`super::tune`] (Allan deviation of the longest standstill, then the
/// noise scalars and the GNSS σ scale by maximum likelihood, starting from
/// the values written here) and filters with the fitted values. It derefs
/// to the noise terms, so `cfg.imu.noise.arw_deg_per_sqrt_h` reads them.
/// `noise = "auto"` is short for `auto = true` with the default terms.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NoiseConfig {
    /// Tune the noise before processing. Default false.
    pub auto: bool,
    /// The noise terms (with `auto`: the tuning's starting point).
    pub values: aidnav_models::ned_ins::ImuNoise,
}

impl std::ops::Deref for NoiseConfig {
    type Target = aidnav_models::ned_ins::ImuNoise;
    fn deref(&self) -> &Self::Target {
        &self.values
    }
}

impl std::ops::DerefMut for NoiseConfig {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.values
    }
}

impl Serialize for NoiseConfig {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Table<'a> {
            auto: bool,
            #[serde(flatten)]
            values: &'a aidnav_models::ned_ins::ImuNoise,
        }
        Table {
            auto: self.auto,
            values: &self.values,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for NoiseConfig {
    /// A table: `auto` (a boolean) taken out, the rest read as the noise
    /// terms (unknown keys refused); or the string `"auto"`.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        let expected = "a table of noise terms or the string \"auto\"";
        let mut table = match toml::Value::deserialize(d)? {
            toml::Value::String(w) if w == "auto" => {
                return Ok(Self {
                    auto: true,
                    values: Default::default(),
                });
            }
            toml::Value::Table(t) => t,
            other => {
                return Err(D::Error::custom(format!("{other}: expected {expected}")));
            }
        };
        let auto = match table.remove("auto") {
            None => false,
            Some(toml::Value::Boolean(b)) => b,
            Some(v) => {
                return Err(D::Error::custom(format!(
                    "auto = {v}: expected true or false"
                )));
            }
        };
        let values = aidnav_models::ned_ins::ImuNoise::deserialize(toml::Value::Table(table))
            .map_err(|e| D::Error::custom(e.message().trim()))?;
        Ok(Self { auto, values })
    }
}

/// Initialisation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialConfig {
    /// Length of the standstill window at the start used for levelling and
    /// the gyro bias \[s\]: the log's first `static_s` seconds when they
    /// are a standstill (see `[standstill]`); otherwise the filter aligns in
    /// motion. Default 5.
    pub static_s: f64,
    /// GNSS speed above which the course gives the heading [m/s]. Default
    /// from the platform (car 2, pedestrian 0.5, aircraft 10, generic 1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heading_speed_mps: Option<f64>,
    /// Prior σ of the heading \[deg\]. Default 5 after a static start
    /// (the heading from the course as the vehicle drives off), 10 after an
    /// alignment in motion.
    pub heading_sigma_deg: f64,
    /// Prior σ of roll and pitch \[deg\]. Default 0.5 after levelling at
    /// rest; an alignment in motion takes `moving_tilt_sigma_deg`.
    pub tilt_sigma_deg: f64,
    /// Prior σ of roll and pitch after an alignment in motion \[deg\]
    /// (roll is unknown, pitch from the climb angle). Default 5.
    pub moving_tilt_sigma_deg: f64,
    /// Prior σ of the heading after an alignment in motion \[deg\]
    /// (body axis and course differ by a sideslip or crab angle). Default 10.
    pub moving_heading_sigma_deg: f64,
    /// A given initial attitude (roll, pitch, yaw) \[deg\] instead of
    /// levelling and the GNSS course; the gyro bias then starts at zero.
    /// Default none.
    #[serde(deserialize_with = "exact_array_option")]
    pub attitude_deg: Option<[f64; 3]>,
    /// A given initial NED velocity [m/s] with `attitude_deg` (default: the
    /// first fix's GNSS velocity, else at rest).
    #[serde(deserialize_with = "exact_array_option")]
    pub velocity_ned_mps: Option<[f64; 3]>,
    /// Prior σ of each position coordinate \[m\]. Default: the first fix's
    /// largest σ (× its quality factor, at least `gnss.min_position_sigma_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub position_sigma_m: Option<f64>,
    /// Prior σ of each velocity coordinate [m/s]. Default: at a standstill
    /// `standstill.max_speed_mps`; in motion the fix's velocity σ (× its
    /// quality factor), 0.5 without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_sigma_mps: Option<f64>,
}

impl Default for InitialConfig {
    fn default() -> Self {
        Self {
            static_s: 5.0,
            heading_speed_mps: None,
            heading_sigma_deg: 5.0,
            tilt_sigma_deg: 0.5,
            moving_tilt_sigma_deg: 5.0,
            moving_heading_sigma_deg: 10.0,
            attitude_deg: None,
            velocity_ned_mps: None,
            position_sigma_m: None,
            velocity_sigma_mps: None,
        }
    }
}

/// GNSS use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssConfig {
    /// Lever arm IMU → antenna in the body frame (forward, right, down) \[m\].
    /// Default [0, 0, 0].
    #[serde(deserialize_with = "exact_array")]
    pub lever_arm_m: [f64; 3],
    /// Use the velocity columns. Default true.
    pub use_velocity: bool,
    /// Floor on the position σ from the file \[m\]. Default 0.01.
    pub min_position_sigma_m: f64,
    /// Floor on the velocity σ [m/s]. Default 0.02.
    pub min_velocity_sigma_mps: f64,
    /// σ of non-fixed solutions (position and velocity) × these factors,
    /// by fix quality.
    pub quality_sigma_scale: QualitySigmaScale,
    /// Measurement policy of the GNSS updates (main run and outage scores):
    /// `accept`, `chi2_gate`, `recovering_gate`, `huber`, `rejection` or
    /// `limiting` (spec 20's detector with rejection or limiting),
    /// `adaptive_gain` (spec 20 eq. 4), `limited_adaptive_gain` (eq. 4 + 5 +
    /// 8), `developed` (eq. 9: limiting with the eq. 3 adaptive noise,
    /// guarded by the detector) or `robust`.
    ///
    /// Default `robust`: spec 20's developed update (eq. 5 detector, eq. 8
    /// limiting, eq. 3 innovation-feedback noise guarded by the detector)
    /// that *rejects* instead of limiting while a stream is re-acquired
    /// after a gap, until one fix passes the detector; with the `recovery`
    /// below. Why: a receiver's stream may carry outliers at any time and
    /// bursts when it comes back after an outage. While the stream flows,
    /// limiting bounds an outlier's pull to the gain times the gate radius
    /// (centimetres with RTK) and keeps correcting a filter that a skipped
    /// fix let drift past the gate — on the recorded drive the filter is
    /// optimistic (clean fixes have a mean NIS of 8, not 3), and every
    /// policy that rejects there locks out in manoeuvres. After a gap the
    /// gate radius is the dead-reckoning uncertainty (metres), so limiting
    /// would drag the solution towards a burst: there it rejects. The
    /// recovery ends any lock-out by design. `accept` is KF-GINS's choice
    /// (no protection).
    pub policy: PolicyName,
    /// Anomaly level γ of spec 20's detector (eq. 5: νᵀν > γ tr S) in
    /// `rejection`, `limiting`, `limited_adaptive_gain`, `developed`,
    /// `robust` and the adaptive noise's guard, 1 … 10 000. Default and
    /// range: the engine's [`SchemeParameters::anomaly_gamma`] (9).
    pub anomaly_gamma: f64,
    /// Innovations in eq. 4's sliding window (`adaptive_gain`,
    /// `limited_adaptive_gain`), 1 … 10 000. Default and range: the
    /// engine's [`SchemeParameters::adaptive_window`] (20, 5 s at 4 Hz).
    pub adaptive_window: usize,
    /// Probability of the χ²(m) quantile that `chi2_gate` and
    /// `recovering_gate` reject above, 0 < p < 1. Default and range: the
    /// engine's [`SchemeParameters::chi2_probability`] (0.999).
    pub chi2_probability: f64,
    /// Rejections in a row after which `recovering_gate` accepts again,
    /// 1 … 100 000 (fixes). Default and range: the engine's
    /// [`SchemeParameters::recovering_after`] (20, 5 s at 4 Hz).
    pub recovering_after: usize,
    /// Huber threshold k on √NIS (`huber`: R inflated by √NIS / k above
    /// k), 0.1 … 100. Default and range: the engine's
    /// [`SchemeParameters::huber_k`] (1.345).
    pub huber_k: f64,
    /// How eq. 4 compares the diagonals of M̂ and H P⁻ Hᵀ (`adaptive_gain`,
    /// `limited_adaptive_gain`): `all` (every element must exceed) or
    /// `any`. Default: the engine's
    /// [`SchemeParameters::adaptive_diagonal_rule`] (`all`).
    pub adaptive_diagonal_rule: DiagonalRule,
    /// Every GNSS σ (position and velocity, after the quality factors and
    /// the floors) × this: the receiver's σ may be optimistic or
    /// pessimistic as a whole (`aidnav tune` fits it). Default 1.
    pub sigma_scale: f64,
    /// Never lock out: when `recovery_fixes` refused (rejected or limited)
    /// fixes in a run agree with each other — the change between them
    /// matches the change the filter predicts, within the χ²(3) quantile of
    /// `recovery_probability`, or, when the filter has diverged and its
    /// prediction is off, drifts from it at a common rate (then one fix
    /// more is needed) — the position (and, from the same fix, the
    /// velocity) is reset to the latest of them, as PX4 EKF2 and ArduPilot
    /// EKF3 reset to GNSS after a timeout; a refused velocity stream resets
    /// the velocity alone. Each reset is an outcome `reset` in solution.csv
    /// and is listed in summary.json. Applies to every policy that refuses
    /// fixes (`chi2_gate`, `recovering_gate`, `rejection`, `limiting`,
    /// `limited_adaptive_gain`, `developed`, `robust`). Default true.
    pub recovery: bool,
    /// Refused fixes that must agree in a run before a reset (≥ 2).
    /// Default 21: one more than the longest short burst of spec 20 (2–20
    /// epochs), so a short burst is ridden out and never reset to; 5.25 s
    /// at 4 Hz (PX4 EKF2 resets after 7 s without a fused fix, ArduPilot
    /// EKF3 after its 10 s GPS retry time).
    pub recovery_fixes: usize,
    /// Probability of the χ²(3) quantile of the pairwise agreement test, in
    /// (0, 1). Default 0.999 (a genuine 21-fix run breaks with probability
    /// about 2 %).
    pub recovery_probability: f64,
    /// The covariance of a reset position (velocity) is `(1 +
    /// recovery_margin) R` of the fix (≥ 0). Default 1: the variance
    /// doubled, since the fix the filter resets to is one it had refused.
    pub recovery_margin: f64,
    /// Latency of the GNSS time tag: a fix stamped t is the antenna's state
    /// at t − latency (a receiver or logger that stamps its output late).
    /// Seconds (the fixes are re-timed by it; negative: stamped early), or
    /// `"estimate"`: a state of the filter, starting from 0 with the prior
    /// σ `latency_sigma_s`, observable while the vehicle moves (reported in
    /// `summary.json`'s `install` with its σ). Default 0.
    pub latency: GnssLatency,
    /// Prior σ of the estimated latency \[s\]. Default 0.3 (a logger's
    /// stamp against the receiver's measurement time: tenths of a second).
    pub latency_sigma_s: f64,
    /// Estimate the lever arm: three states of the filter starting from
    /// `lever_arm_m` with the prior σ `lever_arm_sigma_m` per axis,
    /// observable in turns and attitude changes (a straight, level drive
    /// leaves the along-track and vertical components to the prior). An
    /// axis whose σ ends above half its prior is kept at `lever_arm_m`
    /// (reported as weakly observed). Default false.
    pub estimate_lever_arm: bool,
    /// Prior σ of each axis of the estimated lever arm \[m\]. Default 1 (an
    /// antenna on a car's roof against an IMU under a seat).
    pub lever_arm_sigma_m: f64,
}

/// `gnss.latency`: a known latency of the GNSS time tag, or a state that
/// estimates it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GnssLatency {
    /// Known \[s\]: the fixes are re-timed by it.
    Seconds(f64),
    /// Estimated by the filter (`"estimate"`).
    Estimate,
}

impl Default for GnssLatency {
    fn default() -> Self {
        GnssLatency::Seconds(0.0)
    }
}

impl Serialize for GnssLatency {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            GnssLatency::Seconds(v) => s.serialize_f64(*v),
            GnssLatency::Estimate => s.serialize_str("estimate"),
        }
    }
}

impl<'de> Deserialize<'de> for GnssLatency {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl serde::de::Visitor<'_> for Visit {
            type Value = GnssLatency;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("seconds (a number) or \"estimate\"")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<GnssLatency, E> {
                Ok(GnssLatency::Seconds(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<GnssLatency, E> {
                Ok(GnssLatency::Seconds(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<GnssLatency, E> {
                Ok(GnssLatency::Seconds(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<GnssLatency, E> {
                match v {
                    "estimate" => Ok(GnssLatency::Estimate),
                    other => Err(E::invalid_value(serde::de::Unexpected::Str(other), &self)),
                }
            }
        }
        d.deserialize_any(Visit)
    }
}

impl ConstraintConfig {
    /// The vehicle misalignment states this section adds (None: the
    /// misalignment is known).
    pub fn misalignment_block(&self) -> Option<(Augmented, BlockDynamics)> {
        self.estimate_misalignment.then(|| {
            (
                Augmented::VehicleMisalignment,
                BlockDynamics::constant(self.misalignment_sigma_deg.to_radians()),
            )
        })
    }

    /// `misalignment_deg` in radians.
    pub fn misalignment_rad(&self) -> [f64; 3] {
        self.misalignment_deg.map(f64::to_radians)
    }
}

impl GnssConfig {
    /// The latency state this section adds (None: the latency is known).
    pub fn latency_block(&self) -> Option<(Augmented, BlockDynamics)> {
        (self.latency == GnssLatency::Estimate).then(|| {
            (
                Augmented::GnssLatency,
                BlockDynamics::constant(self.latency_sigma_s),
            )
        })
    }

    /// The lever-arm states this section adds (None: the lever arm is
    /// known).
    pub fn lever_arm_block(&self) -> Option<(Augmented, BlockDynamics)> {
        self.estimate_lever_arm.then(|| {
            (
                Augmented::LeverArm,
                BlockDynamics::constant(self.lever_arm_sigma_m),
            )
        })
    }

    /// The known latency the fixes are re-timed by \[s\] (0 when estimated).
    pub fn known_latency_s(&self) -> f64 {
        match self.latency {
            GnssLatency::Seconds(v) => v,
            GnssLatency::Estimate => 0.0,
        }
    }
}

/// What each plausibility check does when a log fails it: `error`
/// (refuse the log, the default), `warn` (a warning, and go on) or `off`.
/// Limits no sensor can exceed are not plausibility checks and always
/// refuse.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChecksConfig {
    /// The readers' checks of the IMU units: the median specific force
    /// about 1 g, a gyro at rest reading below 0.1 rad/s.
    pub units: CheckLevel,
    /// The gyro's yaw against the GNSS course while moving
    /// ([`super::check_turn_rate`]): a degree/radian mix-up.
    pub turn_rate: CheckLevel,
}

/// Vehicle constraints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConstraintConfig {
    /// Non-holonomic constraint (zero lateral and vertical body velocity)
    /// for a land vehicle. Default from the platform (car: on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub non_holonomic: Option<bool>,
    /// Its σ [m/s] (the IMU is not at the wheel contact; turns and bumps
    /// break the constraint by this much). Default 0.1.
    pub non_holonomic_sigma_mps: f64,
    /// Its rate \[Hz\]. Default 10.
    pub non_holonomic_rate_hz: f64,
    /// Not applied below this speed [m/s]. Default 1.
    pub min_speed_mps: f64,
    /// χ² gate of each constraint update: the probability of its χ²(2)
    /// quantile (1: no gate). A misaligned vehicle frame then has its
    /// updates rejected — and warned of — instead of forcing its lateral
    /// or vertical velocity into the solution. Default 0.9999 (|ν| up to
    /// about 4.3σ).
    pub non_holonomic_gate_probability: f64,
    /// The vehicle frame of the non-holonomic constraint and the wheel
    /// speed against the body frame (the IMU after `imu.mounting_deg`), as
    /// (roll, pitch, yaw) \[deg\]: `v_vehicle = R_z(yaw) R_y(pitch)
    /// R_x(roll) v_body`. A phone pitched 3° up against the car: [0, 3, 0].
    /// Default [0, 0, 0].
    #[serde(deserialize_with = "exact_array")]
    pub misalignment_deg: [f64; 3],
    /// Estimate the misalignment's pitch and yaw as filter states, starting
    /// from `misalignment_deg` (the roll stays: no vehicle constraint sees
    /// it). Needs the non-holonomic constraint or a wheel-speed source; the
    /// constraint's weight follows the misalignment's σ, so it holds the
    /// velocity only as far as the misalignment has converged. Default off.
    pub estimate_misalignment: bool,
    /// Prior σ of the estimated pitch and yaw \[deg\]. Default 5.
    pub misalignment_sigma_deg: f64,
    /// Zero-velocity and zero-angular-rate updates while a standstill is
    /// detected (`[standstill]`). Default from the platform (car and
    /// pedestrian: on).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zero_velocity: Option<bool>,
    /// σ of the zero-velocity update per axis [m/s] (a standing car rocks,
    /// a hand trembles). Default 0.05.
    pub zero_velocity_sigma_mps: f64,
    /// Floor of the σ of the zero-angular-rate update per axis \[deg/s\]
    /// (the window's own noise of the mean counts too). Default 0.1.
    pub zero_angular_rate_sigma_deg_s: f64,
    /// Rate of both standstill updates \[Hz\]. Default 1: the residual
    /// motion of a standstill (rocking, tremor) is correlated over about a
    /// second, and faster updates count the same motion again as if it were
    /// new information (on the drive, 10 Hz at σ 0.02 m/s made the 30 s
    /// outages 44 % worse; 1 Hz at 0.05 m/s made them 9 % better).
    pub zero_velocity_rate_hz: f64,
}

impl Default for ConstraintConfig {
    fn default() -> Self {
        Self {
            non_holonomic: None,
            non_holonomic_sigma_mps: 0.1,
            non_holonomic_rate_hz: 10.0,
            min_speed_mps: 1.0,
            non_holonomic_gate_probability: 0.9999,
            misalignment_deg: [0.0; 3],
            estimate_misalignment: false,
            misalignment_sigma_deg: 5.0,
            zero_velocity: None,
            zero_velocity_sigma_mps: 0.05,
            zero_angular_rate_sigma_deg_s: 0.1,
            zero_velocity_rate_hz: 1.0,
        }
    }
}

/// `[wheel_speed]`: a wheel-speed (odometer) stream as an aid source, a
/// forward-speed update at the wheel's lever arm (absent: none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WheelSpeedSection {
    /// The file, relative to `data.dir` (required).
    pub file: PathBuf,
    /// Its format. Default `generic_csv` (see `--help`).
    pub format: WheelSpeedFormat,
    /// Added to the file's time \[s\] (a logging delay).
    pub time_offset_s: f64,
    /// σ of a sample without its own, and the floor of a given σ [m/s].
    /// Default 0.1 (slip, tyre deflection and quantisation together).
    pub sigma_mps: f64,
    /// Lever arm from the IMU to the wheel's contact point (body frame:
    /// forward, right, down) \[m\]. Default 0 (a rear-axle centre behind the
    /// IMU is e.g. [-1.3, 0, 0.3]).
    #[serde(deserialize_with = "exact_array")]
    pub lever_arm_m: [f64; 3],
    /// Estimate the odometer's scale-factor error (a state of its own).
    /// Default on.
    pub scale_state: bool,
    /// Prior σ of the scale-factor error [–]. Default 0.02 (2 %: tyre
    /// radius, pressure and wear).
    pub scale_sigma: f64,
    /// Random-walk density of the scale-factor error [1/√s]. Default 1e-5
    /// (the radius changes with temperature and pressure over tens of
    /// minutes).
    pub scale_noise_per_sqrt_s: f64,
    /// χ² gate probability of each update (1: every sample accepted).
    /// Default 0.999.
    pub gate_probability: f64,
    /// Fuse at most one sample per this interval \[s\] (0: every sample).
    /// Default 0.1: the wheel's errors are correlated over tenths of a
    /// second, so faster updates count the same error again.
    pub min_interval_s: f64,
}

impl Default for WheelSpeedSection {
    fn default() -> Self {
        Self {
            file: PathBuf::new(),
            format: WheelSpeedFormat::default(),
            time_offset_s: 0.0,
            sigma_mps: 0.1,
            lever_arm_m: [0.0; 3],
            scale_state: true,
            scale_sigma: 0.02,
            scale_noise_per_sqrt_s: 1e-5,
            gate_probability: 0.999,
            min_interval_s: 0.1,
        }
    }
}

impl WheelSpeedSection {
    /// The state block this section adds to the filter (None: no scale
    /// state).
    pub fn block(&self) -> Option<(Augmented, BlockDynamics)> {
        self.scale_state.then(|| {
            (
                Augmented::WheelSpeedScale,
                BlockDynamics::random_walk(self.scale_sigma, self.scale_noise_per_sqrt_s),
            )
        })
    }

    /// The aid source of this section over its samples.
    pub fn source<'a>(&self, samples: &'a [WheelSpeedSample]) -> WheelSpeedSource<'a> {
        WheelSpeedSource::new(
            samples,
            WheelSpeedConfig {
                sigma_mps: self.sigma_mps,
                lever_arm_m: Vec3::assume_in_frame(self.lever_arm_m.into()),
                gate_probability: gate(self.gate_probability),
                min_interval_s: self.min_interval_s,
            },
        )
    }
}

/// A gate probability of the configuration: 1 is no gate.
fn gate(probability: f64) -> Option<f64> {
    (probability < 1.0).then_some(probability)
}

/// `[barometer]`: a barometric height (or pressure) stream as an aid
/// source, a height update (absent: none).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BarometerSection {
    /// The file, relative to `data.dir` (required).
    pub file: PathBuf,
    /// Its format. Default `generic_csv` (see `--help`; a pressure column
    /// becomes a height by the ISA standard atmosphere).
    pub format: BaroFormat,
    /// Added to the file's time \[s\] (a logging delay).
    pub time_offset_s: f64,
    /// σ of a sample without its own, and the floor of a given σ \[m\].
    /// Default 0.5 (a consumer MEMS barometer's noise and gusts).
    pub sigma_m: f64,
    /// Estimate the barometer's height bias against the ellipsoid (a state
    /// of its own: the ISA datum, the geoid and the weather). Default on;
    /// off, the barometer's heights must be ellipsoidal.
    pub bias_state: bool,
    /// Prior σ of the bias \[m\]. Default 100 (geoid undulation and the
    /// weather's departure from the standard atmosphere).
    pub bias_sigma_m: f64,
    /// Random-walk density of the bias [m/√s]. Default 0.05 (≈ 3 m/√h:
    /// the weather moves the pressure by about 1 hPa per hour).
    pub bias_noise_m_per_sqrt_s: f64,
    /// χ² gate probability of each update (1: every sample accepted).
    /// Default 0.999.
    pub gate_probability: f64,
    /// Fuse at most one sample per this interval \[s\] (0: every sample).
    /// Default 0.1.
    pub min_interval_s: f64,
}

impl Default for BarometerSection {
    fn default() -> Self {
        Self {
            file: PathBuf::new(),
            format: BaroFormat::default(),
            time_offset_s: 0.0,
            sigma_m: 0.5,
            bias_state: true,
            bias_sigma_m: 100.0,
            bias_noise_m_per_sqrt_s: 0.05,
            gate_probability: 0.999,
            min_interval_s: 0.1,
        }
    }
}

impl BarometerSection {
    /// The state block this section adds to the filter (None: no bias
    /// state).
    pub fn block(&self) -> Option<(Augmented, BlockDynamics)> {
        self.bias_state.then(|| {
            (
                Augmented::BaroBias,
                BlockDynamics::random_walk(self.bias_sigma_m, self.bias_noise_m_per_sqrt_s),
            )
        })
    }

    /// The aid source of this section over its samples.
    pub fn source<'a>(&self, samples: &'a [BaroSample]) -> BaroSource<'a> {
        BaroSource::new(
            samples,
            BaroConfig {
                sigma_m: self.sigma_m,
                gate_probability: gate(self.gate_probability),
                min_interval_s: self.min_interval_s,
            },
        )
    }
}

/// The kind of vehicle: its preset chooses the constraints and the
/// thresholds of the keys left out of the configuration.
///
/// | preset | non-holonomic | standstill updates | heading speed | standstill: accel / gyro std |
/// | --- | --- | --- | --- | --- |
/// | `car` | on | on | 2 m/s | 0.3 m/s² / 3 °/s (engine vibration) |
/// | `pedestrian` | off | on | 0.5 m/s | 0.25 m/s² / 1 °/s |
/// | `aircraft` | off | off | 10 m/s | 0.1 m/s² / 0.5 °/s |
/// | `generic` | off | off | 1 m/s | 0.2 m/s² / 1 °/s |
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Platform {
    /// A land vehicle on wheels.
    Car,
    /// A walker carrying the sensors (in hand, on the body).
    Pedestrian,
    /// An aircraft (no constraint; it never stands still in flight).
    Aircraft,
    /// Nothing assumed (the default).
    #[default]
    Generic,
}

/// What a [`Platform`] preset sets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatformPreset {
    /// The non-holonomic constraint.
    pub non_holonomic: bool,
    /// Zero-velocity and zero-angular-rate updates at standstill.
    pub zero_velocity: bool,
    /// GNSS speed above which the course gives the heading [m/s].
    pub heading_speed_mps: f64,
    /// Standstill: largest std of each accelerometer axis over the window [m/s²].
    pub standstill_accel_std_mps2: f64,
    /// Standstill: largest std of each gyro axis over the window \[deg/s\].
    pub standstill_gyro_std_deg_s: f64,
}

impl Platform {
    /// The preset's values.
    pub fn preset(self) -> PlatformPreset {
        let (non_holonomic, zero_velocity, heading_speed_mps, accel, gyro) = match self {
            // A car's engine shakes the IMU at a light: the gyro line of a
            // consumer MEMS sensor reaches a few °/s; GNSS speed decides.
            Platform::Car => (true, true, 2.0, 0.3, 3.0),
            Platform::Pedestrian => (false, true, 0.5, 0.25, 1.0),
            Platform::Aircraft => (false, false, 10.0, 0.1, 0.5),
            Platform::Generic => (false, false, 1.0, 0.2, 1.0),
        };
        PlatformPreset {
            non_holonomic,
            zero_velocity,
            heading_speed_mps,
            standstill_accel_std_mps2: accel,
            standstill_gyro_std_deg_s: gyro,
        }
    }
}

/// Standstill detection: a window of IMU samples whose every axis varies
/// less than the thresholds, while the GNSS velocity (a fix within the last
/// second; none in an outage) says "at rest": its horizontal speed below
/// `max_speed_mps` or, when the fix gives a velocity σ, below 3.7 × that σ
/// (`aidnav_ins::standstill::gnss_says_still`: a receiver at rest stays
/// below it in 999 fixes of 1000). It chooses
/// levelling at rest over an alignment in motion and drives the
/// zero-velocity updates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StandstillConfig {
    /// Window of the IMU statistics \[s\]. Default 0.5.
    pub window_s: f64,
    /// Largest speed of a standstill [m/s], raised to what the fix's own
    /// velocity σ allows at rest. Default 0.2.
    pub max_speed_mps: f64,
    /// Largest std of each accelerometer axis [m/s²]. Default from the platform.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_accel_std_mps2: Option<f64>,
    /// Largest std of each gyro axis \[deg/s\]. Default from the platform.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_gyro_std_deg_s: Option<f64>,
}

impl Default for StandstillConfig {
    fn default() -> Self {
        Self {
            window_s: 0.5,
            max_speed_mps: 0.2,
            max_accel_std_mps2: None,
            max_gyro_std_deg_s: None,
        }
    }
}

/// σ of non-fixed GNSS solutions × these factors: receivers report
/// optimistic σ for float and single solutions (RTKLIB explorer's settings
/// use 2 and 5). RTK fixed is taken as reported.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QualitySigmaScale {
    /// RTK float (RTKLIB Q 2). Default 2.
    pub float: f64,
    /// DGPS / SBAS (Q 4). Default 3.
    pub dgps: f64,
    /// Single point (Q 5) and anything else that is not fixed. Default 5.
    pub single: f64,
}

impl Default for QualitySigmaScale {
    fn default() -> Self {
        Self {
            float: 2.0,
            dgps: 3.0,
            single: 5.0,
        }
    }
}

impl QualitySigmaScale {
    /// The factor of a fix of RTKLIB quality `q` (1 fixed, and 0 — unknown,
    /// a format without a quality column — : 1).
    pub fn factor(&self, q: u8) -> f64 {
        match q {
            0 | 1 => 1.0,
            2 => self.float,
            4 => self.dgps,
            _ => self.single,
        }
    }
}

impl Default for GnssConfig {
    /// The scheme keys from the engine's [`SchemeParameters::default`].
    fn default() -> Self {
        let recovery = RecoveryConfig::default();
        let scheme = SchemeParameters::default();
        Self {
            lever_arm_m: [0.0; 3],
            use_velocity: true,
            min_position_sigma_m: 0.01,
            min_velocity_sigma_mps: 0.02,
            quality_sigma_scale: QualitySigmaScale::default(),
            policy: PolicyName::Robust,
            anomaly_gamma: scheme.anomaly_gamma,
            adaptive_window: scheme.adaptive_window,
            chi2_probability: scheme.chi2_probability,
            recovering_after: scheme.recovering_after,
            huber_k: scheme.huber_k,
            adaptive_diagonal_rule: scheme.adaptive_diagonal_rule,
            sigma_scale: 1.0,
            recovery: true,
            recovery_fixes: recovery.agreement.run_length,
            recovery_probability: recovery.agreement.probability,
            recovery_margin: recovery.margin,
            latency: GnssLatency::default(),
            latency_sigma_s: 0.3,
            estimate_lever_arm: false,
            lever_arm_sigma_m: 1.0,
        }
    }
}

/// Outage scoring (spec 40's default schedule).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScoreConfig {
    /// Outage lengths L \[s\]. Default [10, 30, 60].
    pub outages_s: Vec<f64>,
    /// First window starts this long after the first IMU sample \[s\]. Default 60.
    pub lead_s: f64,
    /// GNSS between windows \[s\]. Default 30.
    pub gap_s: f64,
    /// Fractions of epochs given an outlier. Default [0.1, 0.3].
    pub outlier_fractions: Vec<f64>,
    /// Outlier size range \[m\]. Default [5, 50].
    #[serde(deserialize_with = "exact_array")]
    pub outlier_m: [f64; 2],
    /// Seed of the injected outliers. Default 20261123.
    pub seed: u64,
    /// Burst after every 30 s outage: this long after GNSS returns, the
    /// fixes carry one common 5–50 m jump (a bad re-acquisition) \[s\]; 0: no
    /// burst run. Default 2.5 (10 epochs at 4 Hz).
    pub post_outage_burst_s: f64,
    /// Fix qualities that serve as the reference of every score (outage
    /// drift, consistency, efficiency, tracking, anomalies): `fixed`
    /// (RTKLIB Q = 1, NMEA GGA 4), `float` (2), `sbas` (3), `dgps` (4),
    /// `single` (5), `ppp` (6), `unknown` (0: formats without a quality
    /// column, e.g. KF-GINS text — name it to score against such a file).
    /// A log without a fix of these qualities scores "no reference" (null
    /// in `summary.json`). Default `["fixed"]`.
    pub reference_quality: Vec<FixQuality>,
}

/// Quality of a GNSS fix, named after RTKLIB's Q (the readers map their
/// formats' qualities onto it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FixQuality {
    /// Q = 0: not given by the format.
    Unknown,
    /// Q = 1: RTK fixed (cm level).
    Fixed,
    /// Q = 2: RTK float.
    Float,
    /// Q = 3: SBAS.
    Sbas,
    /// Q = 4: DGPS.
    Dgps,
    /// Q = 5: single point.
    Single,
    /// Q = 6: PPP.
    Ppp,
}

impl FixQuality {
    /// RTKLIB's Q of this quality.
    pub fn rtklib_q(self) -> u8 {
        match self {
            FixQuality::Unknown => 0,
            FixQuality::Fixed => 1,
            FixQuality::Float => 2,
            FixQuality::Sbas => 3,
            FixQuality::Dgps => 4,
            FixQuality::Single => 5,
            FixQuality::Ppp => 6,
        }
    }
}

impl Default for ScoreConfig {
    fn default() -> Self {
        Self {
            outages_s: vec![10.0, 30.0, 60.0],
            lead_s: 60.0,
            gap_s: 30.0,
            outlier_fractions: vec![0.1, 0.3],
            outlier_m: [5.0, 50.0],
            seed: 20261123,
            post_outage_burst_s: 2.5,
            reference_quality: vec![FixQuality::Fixed],
        }
    }
}

/// How the estimates reach the INS.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Feedback {
    /// Closed loop (seed 000): every estimate is fed back into the INS and
    /// the instrument corrections.
    #[default]
    Closed,
    /// Open loop (seed 004): the INS runs free, the output is corrected.
    Open,
}

/// The filter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilterConfig {
    /// `closed` (default) or `open`. Open loop cannot be smoothed.
    pub feedback: Feedback,
    /// Run spec 10's Cramér–Rao convergence measure δ(n) on the instrument
    /// states (a Fisher recursion beside the filter, +0.2 s per pass on the
    /// drive) and report when the rule declares them converged. Note that
    /// the bound assumes constant instrument errors; with Gauss–Markov
    /// instruments (Q > 0) P_M stays above it and δ rises late in a log.
    /// Default false.
    pub convergence_monitor: bool,
    /// Spec 20 eq. 3's adaptive process noise on the position updates:
    /// `off`, `hard` (the term `K_{k−1} ν_k ν_kᵀ K_{k−1}ᵀ` of each epoch, as
    /// the paper has it) or `averaged` (its mean over the last
    /// `adaptive_noise_window` normal epochs, Mohamed–Schwarz). It is added
    /// to the model's Q: replacing Q, as the paper does on its 3-state
    /// model, made the drive fail (S not positive definite — a rank-3 term
    /// per fix cannot keep 21 states' covariance positive). An
    /// anomalous ν (the eq. 5 detector with `gnss.anomaly_gamma`) feeds the
    /// mean term of the last normal epochs instead; the first fix after an
    /// outage feeds nothing (the gain of an epoch without a fix is zero).
    /// Default `off` (`developed` uses `hard` unless this says otherwise).
    pub adaptive_noise: AdaptiveNoise,
    /// Window of the averaged term and of the guard's mean. Default 10.
    pub adaptive_noise_window: usize,
}

impl Default for FilterConfig {
    fn default() -> Self {
        Self {
            feedback: Feedback::Closed,
            convergence_monitor: false,
            adaptive_noise: AdaptiveNoise::Off,
            adaptive_noise_window: 10,
        }
    }
}

/// Spec 20 eq. 3 on the NED filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AdaptiveNoise {
    /// The model's Q only.
    #[default]
    Off,
    /// Plus each epoch's K ν νᵀ Kᵀ (eq. 3's hard feedback).
    Hard,
    /// Plus its mean over the last window of normal epochs.
    Averaged,
}

/// Outage bridging (spec 20's predictors on real data). In closed loop the
/// filter's estimates are fed back and reset, so the series the predictors
/// extrapolate is the *accumulated GNSS correction* of position and
/// velocity (NED): what the INS needed, per axis, up to the outage. In an
/// outage each predictor continues it from the outage start; the bridged
/// output is the coasting filter's minus the predicted position increment
/// plus the integral of the predicted velocity increment. (Holding the last
/// estimate adds nothing in closed loop: that is the coasting filter, the
/// a-priori model predictor.)
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutageBridgeConfig {
    /// Score the bridged outputs in `aidnav process`'s outage table. Default true.
    pub enabled: bool,
    /// History of the trend \[s\]. Default 30.
    pub trend_window_s: f64,
    /// History of the self-organising model \[s\]. Default 60.
    pub model_window_s: f64,
    /// Every n-th epoch of the model history is used. Default 2.
    pub model_decimation: usize,
    /// Relay switch ages \[s\] (hold, trend, combined trend, model). Default
    /// 1 / 10 / 30 s: a car's outage of a minute is "long".
    pub relay: RelaySchedule,
    /// Model selection (candidates, split). Default polynomials up to t²
    /// (no harmonics: a minute holds no Schuler period).
    pub gmdh: GmdhConfig,
}

impl Default for OutageBridgeConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            trend_window_s: 30.0,
            model_window_s: 60.0,
            model_decimation: 2,
            relay: RelaySchedule {
                t1_s: 1.0,
                t2_s: 10.0,
                t3_s: 30.0,
                t4_s: None,
            },
            gmdh: GmdhConfig::default(),
        }
    }
}

impl OutageBridgeConfig {
    pub(crate) fn bridge(&self) -> BridgeConfig {
        BridgeConfig {
            trend_window_s: self.trend_window_s,
            model_window_s: self.model_window_s,
            model_decimation: self.model_decimation,
            relay: self.relay,
            gmdh: self.gmdh.clone(),
            reselect_ratio: None,
        }
    }
}

/// The predictors scored, in the order of \[`Epoch::bridged`\].
pub use aidnav_integration::bridge::BRIDGE_PREDICTORS;

/// Spec 20's efficiency criterion K_eff = σ_GNSS / σ_KOI on the 3-D antenna
/// position.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EfficiencyConfig {
    /// σ_GNSS, prior data [m, 3-D]. Default none: each fix's own σ (with
    /// the `gnss` floors) — in an outage the withheld fix's.
    pub sigma_gnss_m: Option<f64>,
    /// σ_GNSS of velocity [m/s, 3-D] for the selected output
    /// (`selected.csv`). Default none: each fix's velocity σ (with the
    /// `gnss` floor).
    pub sigma_gnss_velocity_mps: Option<f64>,
}

/// Self-tuning of the noise (`aidnav tune`, `[imu.noise] auto = true`):
/// see [`super::tune`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TuneConfig {
    /// Shortest standstill for an Allan deviation \[s\]: 10 s of samples
    /// give the white noise at τ up to about 1 s from ten or more clusters;
    /// a shorter record shows little beyond the shortest cluster times (the
    /// configured noise is then the starting point). A MEMS bias
    /// instability needs minutes; from a shorter record it is an upper
    /// bound. Default 10.
    pub min_static_s: f64,
    /// Most filter passes of the likelihood search (each one pass over the
    /// log; the first simplex's 6 are made whatever this says). Default 250 (the drive converges in about 140, the walk in
    /// about 220).
    pub max_evaluations: usize,
    /// Each fitted factor stays within [1/this, this] of its starting
    /// value. Default 100.
    pub max_factor: f64,
    /// First step of the search, as a factor on each value. Default 2.
    pub initial_factor: f64,
    /// Stop when the log-likelihood over the simplex spans less than this
    /// and every factor is settled to 5 %. Default 0.05.
    pub tolerance: f64,
    /// What the search maximises: `coasting` (default) or `innovations`;
    /// see [`TuneObjective`].
    pub objective: TuneObjective,
    /// Length of the windows the `coasting` objective withholds \[s\].
    /// Default: the longest of `score.outages_s` (tune for the outages
    /// that are scored).
    pub outage_s: Option<f64>,
    /// GNSS between two withheld windows \[s\]. Default `score.gap_s`.
    pub gap_s: Option<f64>,
}

/// The likelihood the noise search maximises.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TuneObjective {
    /// The GNSS innovations of a pass with every fix: the one-step
    /// predictions at the GNSS rate. Fits the noise that makes tracking
    /// consistent; on the recorded logs it coasts worse than the
    /// configured noise.
    Innovations,
    /// The predictive likelihood of every fix in a pass that withholds
    /// windows of `tune.outage_s` every `tune.outage_s + tune.gap_s`
    /// (from `score.lead_s` plus half a period on, so they fall between
    /// the score's windows of the same length): the updates' innovations
    /// between the windows and, inside them, each withheld fix's position
    /// against the coasting filter's antenna position and covariance. Fits
    /// the noise whose covariance is honest over an outage as well as at
    /// the GNSS rate.
    Coasting,
}

impl ProcessConfig {
    /// `tune.outage_s`, or the longest of `score.outages_s` (None: neither).
    pub fn tune_outage_s(&self) -> Option<f64> {
        self.tune.outage_s.or_else(|| {
            self.score
                .outages_s
                .iter()
                .copied()
                .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))
        })
    }

    /// `tune.gap_s`, or `score.gap_s`.
    pub fn tune_gap_s(&self) -> f64 {
        self.tune.gap_s.unwrap_or(self.score.gap_s)
    }
}

impl Default for TuneConfig {
    fn default() -> Self {
        Self {
            min_static_s: 10.0,
            max_evaluations: 250,
            max_factor: 100.0,
            initial_factor: 2.0,
            tolerance: 0.05,
            objective: TuneObjective::Coasting,
            outage_s: None,
            gap_s: None,
        }
    }
}

/// Outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputConfig {
    /// Also run the Rauch–Tung–Striebel smoother (post-processing) and
    /// write smoothed.csv and the smoothed scores. Default true.
    pub smooth: bool,
    /// Also write navresult.txt in KF-GINS's layout (GPS week, seconds of
    /// week, lat, lon \[deg\], h \[m\], vN vE vD [m/s], roll pitch yaw \[deg\];
    /// antenna position; the rows of solution.csv). Default false.
    pub kf_gins_text: bool,
    /// Also write solution rows between the GNSS epochs, every this many
    /// seconds (at the first IMU sample at or after each multiple; 0.01:
    /// every sample of a 100 Hz IMU), so real GNSS outages have rows too
    /// (outcome 0, no NIS). 0: one row per GNSS epoch only. Default 0.
    pub interval_s: f64,
}

impl Default for OutputConfig {
    fn default() -> Self {
        Self {
            smooth: true,
            kf_gins_text: false,
            interval_s: 0.0,
        }
    }
}

/// The configuration file of `aidnav process`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProcessConfig {
    /// The kind of vehicle: chooses the constraints and thresholds left
    /// out of the file ([`Platform`]). Default `generic`.
    #[serde(default)]
    pub platform: Platform,
    /// Input files.
    pub data: DataFiles,
    /// IMU handling.
    #[serde(default)]
    pub imu: ImuConfig,
    /// Initialisation.
    #[serde(default)]
    pub initial: InitialConfig,
    /// GNSS use.
    #[serde(default)]
    pub gnss: GnssConfig,
    /// Vehicle constraints.
    #[serde(default)]
    pub constraints: ConstraintConfig,
    /// Standstill detection.
    #[serde(default)]
    pub standstill: StandstillConfig,
    /// The filter.
    #[serde(default)]
    pub filter: FilterConfig,
    /// Outage bridging by spec 20's predictors.
    #[serde(default)]
    pub outage_bridge: OutageBridgeConfig,
    /// Spec 20's efficiency criterion.
    #[serde(default)]
    pub efficiency: EfficiencyConfig,
    /// Scoring.
    #[serde(default)]
    pub score: ScoreConfig,
    /// Self-tuning of the noise.
    #[serde(default)]
    pub tune: TuneConfig,
    /// Outputs.
    #[serde(default)]
    pub output: OutputConfig,
    /// What the plausibility checks do when a log fails them.
    #[serde(default)]
    pub checks: ChecksConfig,
    /// A wheel-speed (odometer) stream (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wheel_speed: Option<WheelSpeedSection>,
    /// A barometer stream (absent: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub barometer: Option<BarometerSection>,
}

impl ProcessConfig {
    /// The filter's state layout: the base 21 states and the blocks the
    /// aid-source sections add (in the order GNSS latency, lever arm,
    /// wheel speed, barometer).
    pub fn state_layout(&self) -> StateLayout {
        let blocks = [
            self.gnss.latency_block(),
            self.gnss.lever_arm_block(),
            self.constraints.misalignment_block(),
            self.wheel_speed.as_ref().and_then(WheelSpeedSection::block),
            self.barometer.as_ref().and_then(BarometerSection::block),
        ];
        blocks
            .into_iter()
            .flatten()
            .fold(StateLayout::base(), |layout, (kind, dynamics)| {
                layout.with(kind, dynamics)
            })
    }

    /// The non-holonomic constraint's source (None: off).
    pub fn non_holonomic_source(&self) -> Option<NonHolonomicSource> {
        let nhc = &self.constraints;
        self.non_holonomic().then(|| {
            NonHolonomicSource::new(NonHolonomic {
                rate_hz: nhc.non_holonomic_rate_hz,
                sigma_mps: nhc.non_holonomic_sigma_mps,
                min_speed_mps: nhc.min_speed_mps,
                gate_probability: (nhc.non_holonomic_gate_probability < 1.0)
                    .then_some(nhc.non_holonomic_gate_probability),
            })
        })
    }

    /// The standstill updates' source (None: off).
    pub fn standstill_source(&self) -> Option<StandstillSource> {
        let nhc = &self.constraints;
        self.zero_velocity().then(|| {
            let (accel, gyro) = self.standstill_thresholds();
            StandstillSource::new(StandstillUpdates {
                rate_hz: nhc.zero_velocity_rate_hz,
                window_s: self.standstill.window_s,
                max_speed_mps: self.standstill.max_speed_mps,
                thresholds: StandstillThresholds {
                    accel_std_mps2: accel,
                    gyro_std_rad_s: gyro,
                },
                velocity_sigma_mps: nhc.zero_velocity_sigma_mps,
                angular_rate_sigma_rad_s: nhc.zero_angular_rate_sigma_deg_s.to_radians(),
            })
        })
    }

    /// Whether the non-holonomic constraint is applied (the key, else the platform).
    pub fn non_holonomic(&self) -> bool {
        self.constraints
            .non_holonomic
            .unwrap_or(self.platform.preset().non_holonomic)
    }

    /// Whether the standstill updates are applied (the key, else the platform).
    pub fn zero_velocity(&self) -> bool {
        self.constraints
            .zero_velocity
            .unwrap_or(self.platform.preset().zero_velocity)
    }

    /// GNSS speed above which the course gives the heading (the key, else
    /// the platform) [m/s].
    pub fn heading_speed_mps(&self) -> f64 {
        self.initial
            .heading_speed_mps
            .unwrap_or(self.platform.preset().heading_speed_mps)
    }

    /// Standstill thresholds: (accelerometer std [m/s²], gyro std [rad/s]),
    /// the keys, else the platform's.
    pub fn standstill_thresholds(&self) -> (f64, f64) {
        let p = self.platform.preset();
        (
            self.standstill
                .max_accel_std_mps2
                .unwrap_or(p.standstill_accel_std_mps2),
            self.standstill
                .max_gyro_std_deg_s
                .unwrap_or(p.standstill_gyro_std_deg_s)
                .to_radians(),
        )
    }

    /// Every key that a preset decides and the file left out, set to the
    /// platform's value (what `--print-config` writes and `summary.json`
    /// echoes).
    pub fn resolved(&self) -> Self {
        let mut c = self.clone();
        let p = self.platform.preset();
        c.constraints.non_holonomic = Some(self.non_holonomic());
        c.constraints.zero_velocity = Some(self.zero_velocity());
        c.initial.heading_speed_mps = Some(self.heading_speed_mps());
        c.standstill.max_accel_std_mps2 = Some(
            self.standstill
                .max_accel_std_mps2
                .unwrap_or(p.standstill_accel_std_mps2),
        );
        c.standstill.max_gyro_std_deg_s = Some(
            self.standstill
                .max_gyro_std_deg_s
                .unwrap_or(p.standstill_gyro_std_deg_s),
        );
        c.tune.outage_s = self.tune_outage_s();
        c.tune.gap_s = Some(self.tune_gap_s());
        c
    }
}

/// Measurement policy of a run: a scheme of the engine's registry
/// ([`Scheme`]; its serde names are the configuration's).
pub type PolicyName = Scheme;

impl GnssConfig {
    /// The registry's tuning constants for the GNSS updates, from this
    /// table's scheme keys (every field named, so a parameter the engine
    /// adds must be given a key here).
    pub fn scheme_parameters(&self) -> SchemeParameters {
        SchemeParameters {
            chi2_probability: self.chi2_probability,
            recovering_after: self.recovering_after,
            huber_k: self.huber_k,
            anomaly_gamma: self.anomaly_gamma,
            adaptive_window: self.adaptive_window,
            adaptive_diagonal_rule: self.adaptive_diagonal_rule,
        }
    }
}

impl GnssConfig {
    /// The filter's reset recovery (None when `recovery` is off).
    pub fn recovery_config(&self) -> Option<RecoveryConfig> {
        self.recovery.then(|| self.recovery_parameters())
    }

    /// The recovery's parameters from this table's keys, whether or not
    /// `recovery` is on.
    pub fn recovery_parameters(&self) -> RecoveryConfig {
        RecoveryConfig {
            agreement: aidnav_estimation::recovery::AgreementConfig {
                run_length: self.recovery_fixes,
                probability: self.recovery_probability,
            },
            margin: self.recovery_margin,
        }
    }
}

/// The name a unit enum value has in configuration files and
/// `summary.json` (its serde name, e.g. `combined_trend`).
pub fn config_name<T: Serialize>(value: &T) -> String {
    serde_json::to_value(value)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default()
}
