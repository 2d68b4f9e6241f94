//! The configuration file of `aidnav process` and its validation.

use std::path::PathBuf;

use aidnav_estimation::gmdh::GmdhConfig;
use aidnav_estimation::{Scheme, SchemeParameters};
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

/// Format of the IMU file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuFormat {
    /// Raw CSV (g, deg/s, tick ms) with an RTKLIB `.tag` file (`imu_tags`).
    #[default]
    RtklibTagged,
    /// KF-GINS text: time, angle and velocity increments, body frame.
    KfGins,
    /// aidnav's generic CSV (see `aidnav_io::kfgins`).
    GenericCsv,
}

/// Format of the GNSS file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GnssFormat {
    /// RTKLIB `.pos` (latitude/longitude/height).
    #[default]
    RtklibPos,
    /// KF-GINS text: time, lat, lon, h, σN σE σD [, velocity and σ].
    KfGins,
    /// NMEA 0183: GGA + RMC (+ GST for σ), see `aidnav_io::nmea`.
    Nmea,
}

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
    /// GNSS file.
    pub gnss: PathBuf,
    /// Its format. Default `rtklib_pos`.
    #[serde(default)]
    pub gnss_format: GnssFormat,
}

/// IMU handling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuConfig {
    /// Added to the IMU time \[s\] (logging delay). Default −0.125.
    pub time_offset_s: f64,
    /// Sensor → body rotation as (roll, pitch, yaw) \[deg\], Groves'
    /// Euler_to_CTM: `f_body = C(roll, pitch, yaw) f_sensor`. Default the
    /// data set's [180, −6.79, 185.35].
    #[serde(deserialize_with = "exact_array")]
    pub mounting_deg: [f64; 3],
    /// Zero-phase moving-average window \[s\] (0: none). Default 0.1
    /// (the data set's gyros carry a strong vibration line).
    pub smoothing_s: f64,
    /// Noise terms of the filter model.
    pub noise: aidnav_models::ned_ins::ImuNoise,
}

impl Default for ImuConfig {
    fn default() -> Self {
        Self {
            time_offset_s: -0.125,
            mounting_deg: [180.0, -6.79, 185.35],
            smoothing_s: 0.1,
            noise: aidnav_models::ned_ins::ImuNoise::default(),
        }
    }
}

/// Initialisation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialConfig {
    /// Static period at the start used for levelling and gyro bias \[s\]. Default 5.
    pub static_s: f64,
    /// GNSS speed above which the course gives the heading [m/s]. Default 2.
    pub heading_speed_mps: f64,
    /// Prior σ of the heading \[deg\]. Default 5.
    pub heading_sigma_deg: f64,
    /// Prior σ of roll and pitch \[deg\]. Default 0.5.
    pub tilt_sigma_deg: f64,
    /// A given initial attitude (roll, pitch, yaw) \[deg\] instead of
    /// levelling and the GNSS course; the gyro bias then starts at zero.
    /// Default none.
    #[serde(deserialize_with = "exact_array_option")]
    pub attitude_deg: Option<[f64; 3]>,
    /// A given initial NED velocity [m/s] (default: at rest).
    #[serde(deserialize_with = "exact_array_option")]
    pub velocity_ned_mps: Option<[f64; 3]>,
}

impl Default for InitialConfig {
    fn default() -> Self {
        Self {
            static_s: 5.0,
            heading_speed_mps: 2.0,
            heading_sigma_deg: 5.0,
            tilt_sigma_deg: 0.5,
            attitude_deg: None,
            velocity_ned_mps: None,
        }
    }
}

/// GNSS use.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssConfig {
    /// Lever arm IMU → antenna in the body frame (forward, right, down) \[m\].
    /// Default the data set's [0, −0.05, 0].
    #[serde(deserialize_with = "exact_array")]
    pub lever_arm_m: [f64; 3],
    /// Use the velocity columns. Default true.
    pub use_velocity: bool,
    /// Floor on the position σ from the file \[m\]. Default 0.01.
    pub min_position_sigma_m: f64,
    /// Floor on the velocity σ [m/s]. Default 0.02.
    pub min_velocity_sigma_mps: f64,
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
    /// `robust` and the adaptive noise's guard. Default 9.
    pub anomaly_gamma: f64,
    /// Innovations in eq. 4's sliding window (`adaptive_gain`,
    /// `limited_adaptive_gain`). Default 20 (5 s at 4 Hz).
    pub adaptive_window: usize,
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
}

/// Vehicle constraints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConstraintConfig {
    /// Non-holonomic constraint (zero lateral and vertical body velocity)
    /// for a land vehicle. Default false.
    pub non_holonomic: bool,
    /// Its σ [m/s] (the IMU is not at the wheel contact; turns and bumps
    /// break the constraint by this much). Default 0.1.
    pub non_holonomic_sigma_mps: f64,
    /// Its rate \[Hz\]. Default 10.
    pub non_holonomic_rate_hz: f64,
    /// Not applied below this speed [m/s]. Default 1.
    pub min_speed_mps: f64,
}

impl Default for ConstraintConfig {
    fn default() -> Self {
        Self {
            non_holonomic: false,
            non_holonomic_sigma_mps: 0.1,
            non_holonomic_rate_hz: 10.0,
            min_speed_mps: 1.0,
        }
    }
}

impl Default for GnssConfig {
    fn default() -> Self {
        Self {
            lever_arm_m: [0.0, -0.05, 0.0],
            use_velocity: true,
            min_position_sigma_m: 0.01,
            min_velocity_sigma_mps: 0.02,
            policy: PolicyName::Robust,
            anomaly_gamma: 9.0,
            adaptive_window: 20,
            recovery: true,
            recovery_fixes: 21,
            recovery_probability: 0.999,
            recovery_margin: 1.0,
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
    /// Outputs.
    #[serde(default)]
    pub output: OutputConfig,
}

/// Measurement policy of a run: a scheme of the engine's registry
/// ([`Scheme`]; its serde names are the configuration's).
pub type PolicyName = Scheme;

impl GnssConfig {
    /// The registry's tuning constants for the GNSS updates: χ² gates at
    /// 0.999 (the recovering one accepts again after 20 rejections, 5 s at
    /// 4 Hz), Huber k = 1.345, and this table's γ and eq. 4 window.
    pub fn scheme_parameters(&self) -> SchemeParameters {
        SchemeParameters {
            chi2_probability: 0.999,
            recovering_after: 20,
            huber_k: 1.345,
            anomaly_gamma: self.anomaly_gamma,
            adaptive_window: self.adaptive_window,
        }
    }
}

impl GnssConfig {
    /// The filter's reset recovery (None when `recovery` is off).
    pub fn recovery_config(&self) -> Option<aidnav_integration::ned::RecoveryConfig> {
        self.recovery
            .then_some(aidnav_integration::ned::RecoveryConfig {
                agreement: aidnav_estimation::recovery::AgreementConfig {
                    run_length: self.recovery_fixes,
                    probability: self.recovery_probability,
                },
                margin: self.recovery_margin,
            })
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
