//! Spec 40: process a recorded IMU + GNSS log end to end with the NED
//! filter ([`aidnav_ins::ned_filter`]) and score it with simulated GNSS
//! outages and injected anomalies.
//!
//! Pipeline: read (RTKLIB `.pos`, raw IMU CSV + `.tag`), shift the IMU time
//! by `imu.time_offset_s`, rotate sensor → body (`imu.mounting_deg`, Groves'
//! Euler_to_CTM convention as the data set's upstream uses), smooth with a
//! zero-phase centred moving average (`imu.smoothing_s`, offline), initialise
//! (levelling and gyro bias over the first `initial.static_s` seconds at
//! rest, heading from the first GNSS course above `initial.heading_speed_mps`
//! — the car is assumed to drive straight off), then filter: IMU increments
//! by the trapezoid rule, split at every GNSS epoch so each update is made
//! at the fix's own time.

use std::path::{Path, PathBuf};

use aidnav_estimation::{
    AcceptAll, Chi2Gate, EstimationError, Huber, MeasurementPolicy, Outcome, RecoveringChi2Gate,
    adaptive::{
        AdaptiveGain, AnomalyDetector, DiagonalRule, LimitedAdaptiveGain, Limiting, Rejection,
    },
    gmdh::GmdhConfig,
    nalgebra::U3,
};
use aidnav_frames::earth::{Geodetic, earth_rate_ned};
use aidnav_ins::ned::{ImuIncrement, NedState};
use aidnav_ins::ned_filter::NedFilter;
use aidnav_io::config::{Invalid, Validate, all_positive, count_in_range, in_range, non_negative};
use aidnav_io::rtklib::{GnssFix, ImuSample, read_pos, read_tagged_imu};
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, NedErrorModel, POSITION, VELOCITY,
    Vector21,
};
use aidnav_supervisors::outage::{BridgeConfig, OutageBridge, Predictor, RelaySchedule};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

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
    /// Added to the IMU time [s] (logging delay). Default −0.125.
    pub time_offset_s: f64,
    /// Sensor → body rotation as (roll, pitch, yaw) [deg], Groves'
    /// Euler_to_CTM: `f_body = C(roll, pitch, yaw) f_sensor`. Default the
    /// data set's [180, −6.79, 185.35].
    pub mounting_deg: [f64; 3],
    /// Zero-phase moving-average window [s] (0: none). Default 0.1
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
    /// Static period at the start used for levelling and gyro bias [s]. Default 5.
    pub static_s: f64,
    /// GNSS speed above which the course gives the heading [m/s]. Default 2.
    pub heading_speed_mps: f64,
    /// Prior σ of the heading [deg]. Default 5.
    pub heading_sigma_deg: f64,
    /// Prior σ of roll and pitch [deg]. Default 0.5.
    pub tilt_sigma_deg: f64,
    /// A given initial attitude (roll, pitch, yaw) [deg] instead of
    /// levelling and the GNSS course; the gyro bias then starts at zero.
    /// Default none.
    pub attitude_deg: Option<[f64; 3]>,
    /// A given initial NED velocity [m/s] (default: at rest).
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
    /// Lever arm IMU → antenna in the body frame (forward, right, down) [m].
    /// Default the data set's [0, −0.05, 0].
    pub lever_arm_m: [f64; 3],
    /// Use the velocity columns. Default true.
    pub use_velocity: bool,
    /// Floor on the position σ from the file [m]. Default 0.01.
    pub min_position_sigma_m: f64,
    /// Floor on the velocity σ [m/s]. Default 0.02.
    pub min_velocity_sigma_mps: f64,
    /// Measurement policy of the GNSS updates (main run and outage scores):
    /// `accept`, `chi2_gate`, `recovering_gate`, `huber`, `rejection` or
    /// `limiting` (spec 20's detector with rejection or limiting). Default `accept`
    /// (as KF-GINS). Choose `huber` when the stream may hold outliers: on the
    /// recorded drive it costs about 1 cm on clean data and keeps 5–50 m
    /// outliers on 30 % of the epochs to 8 cm (the anomaly table). Also
    /// `adaptive_gain` (spec 20 eq. 4), `limited_adaptive_gain` (eq. 4 + 5 +
    /// 8) and `developed` (eq. 9: limiting with the eq. 3 adaptive noise,
    /// guarded by the detector).
    pub policy: PolicyName,
    /// Anomaly level γ of spec 20's detector (eq. 5: νᵀν > γ tr S) in
    /// `rejection`, `limiting`, `limited_adaptive_gain`, `developed` and the
    /// adaptive noise's guard. Default 9.
    pub anomaly_gamma: f64,
    /// Innovations in eq. 4's sliding window (`adaptive_gain`,
    /// `limited_adaptive_gain`). Default 20 (5 s at 4 Hz).
    pub adaptive_window: usize,
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
    /// Its rate [Hz]. Default 10.
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
            policy: PolicyName::Accept,
            anomaly_gamma: 9.0,
            adaptive_window: 20,
        }
    }
}

/// Outage scoring (spec 40's default schedule).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScoreConfig {
    /// Outage lengths L [s]. Default [10, 30, 60].
    pub outages_s: Vec<f64>,
    /// First window starts this long after the first IMU sample [s]. Default 60.
    pub lead_s: f64,
    /// GNSS between windows [s]. Default 30.
    pub gap_s: f64,
    /// Fractions of epochs given an outlier. Default [0.1, 0.3].
    pub outlier_fractions: Vec<f64>,
    /// Outlier size range [m]. Default [5, 50].
    pub outlier_m: [f64; 2],
    /// Seed of the injected outliers. Default 20261123.
    pub seed: u64,
    /// Burst after every 30 s outage: this long after GNSS returns, the
    /// fixes carry one common 5–50 m jump (a bad re-acquisition) [s]; 0: no
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
    /// History of the trend [s]. Default 30.
    pub trend_window_s: f64,
    /// History of the self-organising model [s]. Default 60.
    pub model_window_s: f64,
    /// Every n-th epoch of the model history is used. Default 2.
    pub model_decimation: usize,
    /// Relay switch ages [s] (hold, trend, combined trend, model). Default
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
    fn bridge(&self) -> BridgeConfig {
        BridgeConfig {
            trend_window_s: self.trend_window_s,
            model_window_s: self.model_window_s,
            model_decimation: self.model_decimation,
            relay: self.relay,
            gmdh: self.gmdh.clone(),
        }
    }
}

/// The predictors scored, in the order of [`Epoch::bridged`].
pub const BRIDGE_PREDICTORS: [Predictor; 4] = [
    Predictor::Trend,
    Predictor::CombinedTrend,
    Predictor::Gmdh,
    Predictor::Relay,
];

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
    /// week, lat, lon [deg], h [m], vN vE vD [m/s], roll pitch yaw [deg];
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

impl Validate for ProcessConfig {
    fn validate(&self) -> Result<(), Invalid> {
        if self.data.imu_format == ImuFormat::RtklibTagged && self.data.imu_tags.is_none() {
            return Err(Invalid::new(
                "data.imu_tags",
                "(missing)",
                "the RTKLIB .tag file of the IMU CSV (imu_format = \"rtklib_tagged\")",
            ));
        }
        in_range("time_offset_s", self.imu.time_offset_s, -10.0, 10.0)
            .map_err(|e| e.within("imu"))?;
        in_range("smoothing_s", self.imu.smoothing_s, 0.0, 5.0).map_err(|e| e.within("imu"))?;
        let n = &self.imu.noise;
        all_positive(
            "imu.noise",
            &[
                ("arw_deg_per_sqrt_h", n.arw_deg_per_sqrt_h),
                ("vrw_mps_per_sqrt_h", n.vrw_mps_per_sqrt_h),
                ("gyro_bias_deg_per_h", n.gyro_bias_deg_per_h),
                ("accel_bias_mg", n.accel_bias_mg),
                ("gyro_scale_ppm", n.gyro_scale_ppm),
                ("accel_scale_ppm", n.accel_scale_ppm),
                ("correlation_s", n.correlation_s),
            ],
        )?;
        all_positive(
            "initial",
            &[
                ("static_s", self.initial.static_s),
                ("heading_speed_mps", self.initial.heading_speed_mps),
                ("heading_sigma_deg", self.initial.heading_sigma_deg),
                ("tilt_sigma_deg", self.initial.tilt_sigma_deg),
            ],
        )?;
        all_positive(
            "gnss",
            &[
                ("min_position_sigma_m", self.gnss.min_position_sigma_m),
                ("min_velocity_sigma_mps", self.gnss.min_velocity_sigma_mps),
            ],
        )?;
        in_range("anomaly_gamma", self.gnss.anomaly_gamma, 1.0, 1e4)
            .map_err(|e| e.within("gnss"))?;
        count_in_range("adaptive_window", self.gnss.adaptive_window, 1, 10_000)
            .map_err(|e| e.within("gnss"))?;
        count_in_range(
            "adaptive_noise_window",
            self.filter.adaptive_noise_window,
            1,
            10_000,
        )
        .map_err(|e| e.within("filter"))?;
        let b = &self.outage_bridge;
        all_positive(
            "outage_bridge",
            &[
                ("trend_window_s", b.trend_window_s),
                ("model_window_s", b.model_window_s),
                ("relay.t1_s", b.relay.t1_s),
            ],
        )?;
        if !(b.relay.t1_s < b.relay.t2_s && b.relay.t2_s < b.relay.t3_s && b.relay.t3_s.is_finite())
        {
            return Err(Invalid::new(
                "outage_bridge.relay",
                format!("[{}, {}, {}]", b.relay.t1_s, b.relay.t2_s, b.relay.t3_s),
                "0 < t1_s < t2_s < t3_s",
            ));
        }
        count_in_range("model_decimation", b.model_decimation, 1, 1000)
            .map_err(|e| e.within("outage_bridge"))?;
        if let Some(sg) = self.efficiency.sigma_gnss_m {
            all_positive("efficiency", &[("sigma_gnss_m", sg)])?;
        }
        let i = self.output.interval_s;
        if !(i == 0.0 || (1e-3..=3600.0).contains(&i)) {
            return Err(Invalid::new(
                "output.interval_s",
                i,
                "0 (GNSS epochs only) or 0.001 ≤ interval_s ≤ 3600",
            ));
        }
        count_in_range("outages_s", self.score.outages_s.len(), 0, 10)
            .map_err(|e| e.within("score"))?;
        for l in &self.score.outages_s {
            in_range("outages_s", *l, 1.0, 3600.0).map_err(|e| e.within("score"))?;
        }
        non_negative("lead_s", self.score.lead_s).map_err(|e| e.within("score"))?;
        non_negative("gap_s", self.score.gap_s).map_err(|e| e.within("score"))?;
        in_range(
            "post_outage_burst_s",
            self.score.post_outage_burst_s,
            0.0,
            60.0,
        )
        .map_err(|e| e.within("score"))?;
        for f in &self.score.outlier_fractions {
            in_range("outlier_fractions", *f, 0.0, 1.0).map_err(|e| e.within("score"))?;
        }
        let [lo, hi] = self.score.outlier_m;
        if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
            return Err(Invalid::new(
                "score.outlier_m",
                format!("[{lo}, {hi}]"),
                "0 ≤ low ≤ high",
            ));
        }
        Ok(())
    }
}

/// Anything processing can fail with.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// Reading the inputs.
    #[error(transparent)]
    Io(#[from] aidnav_io::IoError),
    /// The filter.
    #[error("filter: {0}")]
    Estimation(#[from] EstimationError),
    /// The data do not allow processing.
    #[error("{0}")]
    Data(String),
}

/// IMU samples (body frame) and GNSS fixes ready for the filter.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// Body-frame IMU samples, SI.
    pub imu: Vec<ImuSample>,
    /// GNSS fixes.
    pub gnss: Vec<GnssFix>,
    /// Reader warnings.
    pub warnings: Vec<String>,
}

/// Groves' Euler_to_CTM: the coordinate transformation for (roll, pitch, yaw).
pub fn euler_to_ctm(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Matrix3::new(
        cp * cy,
        cp * sy,
        -sp,
        -cr * sy + sr * sp * cy,
        cr * cy + sr * sp * sy,
        sr * cp,
        sr * sy + cr * sp * cy,
        -sr * cy + cr * sp * sy,
        cr * cp,
    )
}

/// Read, time-shift, rotate to the body frame and smooth.
pub fn load_inputs(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    let dir = if cfg.data.dir.is_absolute() {
        cfg.data.dir.clone()
    } else {
        base.join(&cfg.data.dir)
    };
    let imu_path = dir.join(&cfg.data.imu);
    let (mut imu, mut warnings) = match cfg.data.imu_format {
        ImuFormat::RtklibTagged => {
            let tags = cfg.data.imu_tags.as_ref().ok_or_else(|| {
                ProcessError::Data("data.imu_tags is needed for imu_format = rtklib_tagged".into())
            })?;
            read_tagged_imu(&imu_path, &dir.join(tags))?
        }
        ImuFormat::KfGins => aidnav_io::kfgins::read_kfgins_imu(&imu_path)?,
        ImuFormat::GenericCsv => aidnav_io::kfgins::read_generic_imu(&imu_path)?,
    };
    let gnss_path = dir.join(&cfg.data.gnss);
    let (gnss, w) = match cfg.data.gnss_format {
        GnssFormat::RtklibPos => read_pos(&gnss_path)?,
        GnssFormat::KfGins => aidnav_io::kfgins::read_kfgins_gnss(&gnss_path)?,
        GnssFormat::Nmea => aidnav_io::nmea::read_nmea(&gnss_path)?,
    };
    warnings.extend(w);
    let [r, p, y] = cfg.imu.mounting_deg.map(f64::to_radians);
    let c = euler_to_ctm(r, p, y);
    for s in &mut imu {
        s.time_s += cfg.imu.time_offset_s;
        s.specific_force = c * s.specific_force;
        s.angular_rate = c * s.angular_rate;
    }
    if cfg.imu.smoothing_s > 0.0 && imu.len() > 2 {
        let dt = (imu[imu.len() - 1].time_s - imu[0].time_s) / (imu.len() - 1) as f64;
        let half = ((cfg.imu.smoothing_s / dt) / 2.0).round() as usize;
        if half > 0 {
            imu = smooth(&imu, half);
        }
    }
    Ok(Inputs {
        imu,
        gnss,
        warnings,
    })
}

/// Centred moving average over 2·half + 1 samples (shrinking at the ends).
fn smooth(imu: &[ImuSample], half: usize) -> Vec<ImuSample> {
    let n = imu.len();
    let mut out = imu.to_vec();
    let mut sum_f = Vector3::zeros();
    let mut sum_w = Vector3::zeros();
    // Prefix sums keep it O(n).
    let mut pf = Vec::with_capacity(n + 1);
    let mut pw = Vec::with_capacity(n + 1);
    pf.push(sum_f);
    pw.push(sum_w);
    for s in imu {
        sum_f += s.specific_force;
        sum_w += s.angular_rate;
        pf.push(sum_f);
        pw.push(sum_w);
    }
    for (k, o) in out.iter_mut().enumerate() {
        let lo = k.saturating_sub(half);
        let hi = (k + half + 1).min(n);
        let m = (hi - lo) as f64;
        o.specific_force = (pf[hi] - pf[lo]) / m;
        o.angular_rate = (pw[hi] - pw[lo]) / m;
    }
    out
}

/// The initial state and the starting gyro bias.
fn initialise(
    cfg: &ProcessConfig,
    inputs: &Inputs,
) -> Result<(NedState, Vector3<f64>, usize), ProcessError> {
    let imu = &inputs.imu;
    let first_fix = &inputs.gnss[0];
    let start = imu
        .iter()
        .position(|s| s.time_s >= first_fix.time_s)
        .ok_or_else(|| ProcessError::Data("no IMU sample after the first GNSS epoch".into()))?;
    let t0 = imu[start].time_s;
    let (attitude, w) = match cfg.initial.attitude_deg {
        Some([r, p, y]) => (
            UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), y.to_radians()),
            None,
        ),
        None => {
            let (attitude, w) = align(cfg, inputs, start, t0)?;
            (attitude, Some(w))
        }
    };
    // Antenna fix → IMU position.
    let fix = inputs
        .gnss
        .iter()
        .rev()
        .find(|g| g.time_s <= t0)
        .unwrap_or(first_fix);
    let arm = attitude * Vector3::from(cfg.gnss.lever_arm_m);
    let position = fix.position.offset_by(&-arm);
    let gyro_bias = w.map_or_else(Vector3::zeros, |w| {
        w - attitude.inverse() * earth_rate_ned(position.latitude_rad)
    });
    Ok((
        NedState {
            position,
            velocity: cfg
                .initial
                .velocity_ned_mps
                .map_or_else(Vector3::zeros, Vector3::from),
            attitude,
        },
        gyro_bias,
        start,
    ))
}

/// Coarse alignment: roll and pitch by levelling over the static window at
/// the start, heading from the first GNSS course above the speed threshold;
/// also the mean gyro output at rest (bias + Earth rate).
fn align(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    start: usize,
    t0: f64,
) -> Result<(UnitQuaternion<f64>, Vector3<f64>), ProcessError> {
    let window: Vec<&ImuSample> = inputs.imu[start..]
        .iter()
        .take_while(|s| s.time_s < t0 + cfg.initial.static_s)
        .collect();
    if window.len() < 10 {
        return Err(ProcessError::Data(
            "static window holds fewer than 10 IMU samples".into(),
        ));
    }
    let n = window.len() as f64;
    let f = window
        .iter()
        .map(|s| s.specific_force)
        .sum::<Vector3<f64>>()
        / n;
    let w = window.iter().map(|s| s.angular_rate).sum::<Vector3<f64>>() / n;
    let roll = (-f.y).atan2(-f.z);
    let pitch = f.x.atan2(f.y.hypot(f.z));
    let moving = inputs
        .gnss
        .iter()
        .find(|g| {
            g.velocity_ned
                .is_some_and(|v| v.xy().norm() > cfg.initial.heading_speed_mps)
        })
        .ok_or_else(|| {
            ProcessError::Data(
                "the GNSS speed never exceeds initial.heading_speed_mps: no heading (give initial.attitude_deg)".into(),
            )
        })?;
    let v = moving.velocity_ned.expect("checked");
    let yaw = v.y.atan2(v.x);
    Ok((UnitQuaternion::from_euler_angles(roll, pitch, yaw), w))
}

/// Which epochs a run withholds and how it corrupts the others.
#[derive(Debug, Clone, Default)]
pub struct RunPlan {
    /// Withheld intervals [start, end) (GPST s).
    pub windows: Vec<(f64, f64)>,
    /// Outlier added to the position of epoch i (NED, m), by GNSS index.
    pub outliers: Vec<Option<Vector3<f64>>>,
    /// Score the free INS instead of the coasting filter: the filter keeps
    /// all GNSS, and from each window's start a copy of its INS is
    /// mechanized from the raw IMU (no instrument corrections, no updates)
    /// to the window's end; the epochs inside a window report that copy.
    pub free_ins_in_windows: bool,
    /// Keep the forward pass and add the RTS-smoothed antenna position to
    /// every epoch (not with `free_ins_in_windows`).
    pub smooth: bool,
    /// Run the Cramér–Rao convergence monitor (δ(n) per epoch).
    pub monitor: bool,
    /// Bridge the withheld windows with spec 20's predictors
    /// ([`Epoch::bridged`]; closed loop, not with `free_ins_in_windows`).
    pub bridge: bool,
}

/// Measurement policy of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PolicyName {
    /// Accept every fix (what KF-GINS does).
    Accept,
    /// χ² gate at 0.999 (a plain gate locks out on this drive).
    Chi2Gate,
    /// χ² gate at 0.999 that accepts again after 20 rejections in a row (5 s).
    RecoveringGate,
    /// Huber re-weighting, k = 1.345.
    Huber,
    /// Spec 20 eq. 5 detector (νᵀν > γ tr S, γ = 9) with eq. 6 rejection.
    Rejection,
    /// Spec 20 eq. 5 detector with eq. 8 limiting (the innovation clipped to
    /// the gate, its direction kept).
    Limiting,
    /// Spec 20 eq. 4: the gain from the empirical innovation covariance of
    /// the last `gnss.adaptive_window` epochs when it exceeds the model's.
    AdaptiveGain,
    /// Eq. 4's gain with the eq. 5 detector and eq. 8 limiting.
    LimitedAdaptiveGain,
    /// Spec 20 eq. 9, the developed algorithm: eq. 8 limiting with the eq. 3
    /// adaptive process noise (`filter.adaptive_noise`, `hard` when that is
    /// `off`), the noise fed by normal innovations only.
    Developed,
}

impl PolicyName {
    /// Every policy, in the order of the anomaly table.
    pub const ALL: [PolicyName; 9] = [
        PolicyName::Accept,
        PolicyName::Chi2Gate,
        PolicyName::RecoveringGate,
        PolicyName::Huber,
        PolicyName::Rejection,
        PolicyName::Limiting,
        PolicyName::AdaptiveGain,
        PolicyName::LimitedAdaptiveGain,
        PolicyName::Developed,
    ];

    fn policy(self, gnss: &GnssConfig) -> Box<dyn MeasurementPolicy<U3>> {
        let detector = AnomalyDetector {
            gamma: gnss.anomaly_gamma,
        };
        let window = || {
            AdaptiveGain::new(gnss.adaptive_window, DiagonalRule::All)
                .unwrap_or_else(|| unreachable!("adaptive_window ≥ 1 is validated"))
        };
        match self {
            PolicyName::Accept => Box::new(AcceptAll),
            PolicyName::Chi2Gate => Box::new(Chi2Gate { probability: 0.999 }),
            PolicyName::RecoveringGate => Box::new(RecoveringChi2Gate::new(0.999, 20)),
            PolicyName::Huber => Box::new(Huber { k: 1.345 }),
            PolicyName::Rejection => Box::new(Rejection { detector }),
            PolicyName::Limiting | PolicyName::Developed => Box::new(Limiting { detector }),
            PolicyName::AdaptiveGain => Box::new(window()),
            PolicyName::LimitedAdaptiveGain => Box::new(LimitedAdaptiveGain {
                gain: window(),
                detector,
            }),
        }
    }

    /// The name in configuration files and tables.
    pub fn name(self) -> String {
        serde_json::to_value(self)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }
}

/// One epoch of a run's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Epoch {
    /// GNSS index.
    pub index: usize,
    /// Antenna position after the epoch (updated or not).
    pub antenna: Geodetic,
    /// NED velocity.
    pub velocity: Vector3<f64>,
    /// Attitude.
    pub attitude: UnitQuaternion<f64>,
    /// σ of the position error (N, E, D).
    pub sigma: Vector3<f64>,
    /// Position NIS of the update (NaN when withheld).
    pub nis: f64,
    /// Position innovation, antenna estimate minus fix (NED) [m] (NaN when withheld).
    pub innovation: Vector3<f64>,
    /// What the update did (None: withheld).
    pub outcome: Option<Outcome>,
    /// The instrument corrections after the epoch.
    pub instruments: aidnav_ins::ned_filter::InstrumentEstimate,
    /// RTS-smoothed antenna position (runs with `RunPlan::smooth`).
    pub smoothed_antenna: Option<Geodetic>,
    /// Spec 10's δ(n) on the instrument states (runs with
    /// `RunPlan::monitor`; NaN otherwise or while the Fisher information is
    /// singular).
    pub convergence: f64,
    /// Spec 20's efficiency criterion K_eff = σ_GNSS / σ_KOI (3-D position);
    /// above 1 the integrated solution is the better source.
    pub k_eff: f64,
    /// Inside an outage window of a run with `RunPlan::bridge`: the antenna
    /// position bridged by each of [`BRIDGE_PREDICTORS`].
    pub bridged: Option<[Geodetic; 4]>,
    record_index: Option<usize>,
}

impl Epoch {
    /// This epoch with the smoothed antenna position in place of the filtered one.
    pub fn smoothed(&self) -> Option<Epoch> {
        self.smoothed_antenna
            .map(|antenna| Epoch { antenna, ..*self })
    }
}

/// The navigation solution at a time between GNSS epochs (`output.interval_s`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolutionRow {
    /// GPST, seconds since 1970.
    pub time_s: f64,
    /// Antenna position.
    pub antenna: Geodetic,
    /// NED velocity.
    pub velocity: Vector3<f64>,
    /// Attitude.
    pub attitude: UnitQuaternion<f64>,
    /// σ of the position error (N, E, D).
    pub sigma: Vector3<f64>,
}

/// A run's output: one [`Epoch`] per GNSS epoch, and the rows between them
/// at `output.interval_s` (none when it is 0).
#[derive(Debug, Clone, Default)]
pub struct Run {
    /// Per GNSS epoch.
    pub epochs: Vec<Epoch>,
    /// Between GNSS epochs.
    pub between: Vec<SolutionRow>,
}

/// Run the filter over the whole log under a plan and a policy: one
/// [`Epoch`] per GNSS epoch.
pub fn run_filter(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    plan: &RunPlan,
    policy: PolicyName,
) -> Result<Vec<Epoch>, ProcessError> {
    run_filter_rows(cfg, inputs, plan, policy, 0.0).map(|r| r.epochs)
}

/// [`run_filter`], also writing a [`SolutionRow`] every `interval_s` (at
/// the first IMU sample at or after each multiple; 0: none) between the
/// GNSS epochs — through real GNSS outages too.
pub fn run_filter_rows(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    plan: &RunPlan,
    policy: PolicyName,
    interval_s: f64,
) -> Result<Run, ProcessError> {
    let (state, gyro_bias, start) = initialise(cfg, inputs)?;
    let model = NedErrorModel {
        noise: cfg.imu.noise,
    };
    let [sg, sa, kg, ka] = model.noise.instrument_sigmas();
    let mut sig = Vector21::zeros();
    let tilt = cfg.initial.tilt_sigma_deg.to_radians();
    for i in 0..3 {
        sig[POSITION + i] = 0.1;
        sig[VELOCITY + i] = 0.05;
        sig[ATTITUDE + i] = if i == 2 {
            cfg.initial.heading_sigma_deg.to_radians()
        } else {
            tilt
        };
        sig[GYRO_BIAS + i] = sg;
        sig[ACCEL_BIAS + i] = sa;
        sig[GYRO_SCALE + i] = kg;
        sig[ACCEL_SCALE + i] = ka;
    }
    let lever = Vector3::from(cfg.gnss.lever_arm_m);
    let mut filter = NedFilter::new(model, state, &sig, lever)?;
    filter.set_gyro_bias(gyro_bias);
    filter.set_open_loop(cfg.filter.feedback == Feedback::Open);
    let smooth =
        plan.smooth && !plan.free_ins_in_windows && cfg.filter.feedback == Feedback::Closed;
    if smooth {
        filter.start_recording(MAX_RECORDED_EPOCHS);
    }
    if plan.monitor {
        filter.start_convergence_monitor()?;
    }
    let adaptive = match (cfg.filter.adaptive_noise, policy) {
        (AdaptiveNoise::Off, PolicyName::Developed) | (AdaptiveNoise::Hard, _) => Some(false),
        (AdaptiveNoise::Averaged, _) => Some(true),
        (AdaptiveNoise::Off, _) => None,
    };
    if let Some(average) = adaptive {
        filter.set_adaptive_noise(
            Some(cfg.gnss.anomaly_gamma),
            cfg.filter.adaptive_noise_window,
            average,
        );
    }
    let mut position_policy = policy.policy(&cfg.gnss);
    let mut velocity_policy = policy.policy(&cfg.gnss);
    let bridging =
        plan.bridge && !plan.free_ins_in_windows && cfg.filter.feedback == Feedback::Closed;
    let bridge_cfg = cfg.outage_bridge.bridge();
    let mut bridge = BridgeState::default();
    let imu = &inputs.imu;
    let gnss = &inputs.gnss;
    let mut next = gnss
        .iter()
        .position(|g| g.time_s > imu[start].time_s)
        .unwrap_or(gnss.len());
    let mut epochs = Vec::with_capacity(gnss.len());
    let span = imu[imu.len() - 1].time_s - imu[start].time_s;
    let mut between = Vec::with_capacity(if interval_s > 0.0 {
        // Bounded: one row per IMU sample at most.
        ((span / interval_s) as usize).min(imu.len()) + 1
    } else {
        0
    });
    let mut next_row = imu[start].time_s + interval_s;
    let in_window = |t: f64| plan.windows.iter().any(|&(a, b)| t >= a && t < b);
    let free = plan.free_ins_in_windows;
    let withheld = |t: f64| !free && in_window(t);
    // The free INS of the current window (free mode only).
    let mut free_ins: Option<NedFilter> = None;
    let nhc = &cfg.constraints;
    let nhc_interval = 1.0 / nhc.non_holonomic_rate_hz;
    let mut next_nhc = imu[start].time_s + nhc_interval;
    // The time of the IMU sample being processed, for the error message.
    let mut now = imu[start].time_s;
    let pass = (|| -> Result<(), EstimationError> {
        for k in start + 1..imu.len() {
            let (a, b) = (&imu[k - 1], &imu[k]);
            now = b.time_s;
            let mut t = a.time_s;
            let (mut w0, mut f0) = (a.angular_rate, a.specific_force);
            let dt_total = b.time_s - a.time_s;
            loop {
                let split = next < gnss.len() && gnss[next].time_s <= b.time_s;
                let t_end = if split { gnss[next].time_s } else { b.time_s };
                let frac = (t_end - a.time_s) / dt_total;
                let w1 = a.angular_rate + (b.angular_rate - a.angular_rate) * frac;
                let f1 = a.specific_force + (b.specific_force - a.specific_force) * frac;
                let dt = t_end - t;
                if dt > 0.0 {
                    let inc = ImuIncrement {
                        dt_s: dt,
                        delta_angle: (w0 + w1) * (0.5 * dt),
                        delta_velocity: (f0 + f1) * (0.5 * dt),
                    };
                    if free && in_window(t_end) {
                        free_ins
                            .get_or_insert_with(|| filter.clone())
                            .coast_uncorrected(&inc);
                    } else if free {
                        free_ins = None;
                    }
                    filter.propagate(&inc)?;
                }
                t = t_end;
                w0 = w1;
                f0 = f1;
                if interval_s > 0.0 && t >= next_row {
                    while next_row <= t {
                        next_row += interval_s;
                    }
                    if !split {
                        let (antenna, _) = filter.antenna();
                        let sg = filter.sigmas();
                        let solution = filter.solution();
                        between.push(SolutionRow {
                            time_s: t,
                            antenna,
                            velocity: solution.velocity,
                            attitude: solution.attitude,
                            sigma: Vector3::new(sg[POSITION], sg[POSITION + 1], sg[POSITION + 2]),
                        });
                    }
                }
                if nhc.non_holonomic && t >= next_nhc {
                    next_nhc += nhc_interval;
                    if filter.state().velocity.norm() > nhc.min_speed_mps {
                        filter.update_non_holonomic(nhc.non_holonomic_sigma_mps)?;
                    }
                }
                if !split {
                    break;
                }
                let g = &gnss[next];
                let (mut nis, mut outcome) = (f64::NAN, None);
                let mut innovation = Vector3::repeat(f64::NAN);
                let mut convergence = f64::NAN;
                if plan.monitor {
                    filter.begin_epoch()?;
                }
                let fed_back_before = *filter.fed_back();
                if !withheld(g.time_s) {
                    let mut fix = g.position;
                    if let Some(Some(o)) = plan.outliers.get(next) {
                        fix = fix.offset_by(o);
                    }
                    let s = g.position_sigma_neu;
                    let sigma =
                        Vector3::new(s.x, s.y, s.z).map(|v| v.max(cfg.gnss.min_position_sigma_m));
                    let rec =
                        filter.update_position_with(&fix, &sigma, position_policy.as_mut())?;
                    nis = rec.nis;
                    outcome = Some(rec.outcome);
                    innovation = rec.residual;
                    if cfg.gnss.use_velocity
                        && let (Some(v), Some(sv)) = (g.velocity_ned, g.velocity_sigma_neu)
                    {
                        let sv = sv.map(|x| x.max(cfg.gnss.min_velocity_sigma_mps));
                        filter.update_velocity_with(&v, &sv, velocity_policy.as_mut())?;
                    }
                } else {
                    filter.position_fix_missing()?;
                }
                if plan.monitor {
                    convergence = filter.instrument_convergence().unwrap_or(f64::NAN);
                }
                let reporting = match &free_ins {
                    Some(f) if in_window(g.time_s) => f,
                    _ => &filter,
                };
                let (antenna, _) = reporting.antenna();
                let s = reporting.sigmas();
                let st = &reporting.solution();
                let bridged = if !bridging {
                    None
                } else if withheld(g.time_s) {
                    bridge.bridged(g.time_s, &antenna, &bridge_cfg)
                } else {
                    bridge.record(g.time_s, &(filter.fed_back() - fed_back_before));
                    None
                };
                let sigma = Vector3::new(s[POSITION], s[POSITION + 1], s[POSITION + 2]);
                let sigma_gnss = cfg.efficiency.sigma_gnss_m.unwrap_or_else(|| {
                    g.position_sigma_neu
                        .map(|v| v.max(cfg.gnss.min_position_sigma_m))
                        .norm()
                });
                epochs.push(Epoch {
                    index: next,
                    antenna,
                    velocity: st.velocity,
                    attitude: st.attitude,
                    sigma,
                    nis,
                    innovation,
                    outcome,
                    instruments: *reporting.instruments(),
                    smoothed_antenna: None,
                    convergence,
                    k_eff: aidnav_supervisors::efficiency::EfficiencyCriterion { sigma_gnss }
                        .coefficient(sigma.norm()),
                    bridged,
                    record_index: filter.recorded_epoch(),
                });
                next += 1;
            }
        }
        Ok(())
    })();
    pass.map_err(|e| {
        ProcessError::Data(format!(
            "the filter failed {:.2} s after the first IMU sample (t = {now:.3} s): {e}",
            now - imu[0].time_s
        ))
    })?;
    if smooth {
        let states = filter.smoothed_states()?.ok_or_else(|| {
            ProcessError::Data(format!(
                "the log is too long to smooth: more than {MAX_RECORDED_EPOCHS} covariance epochs ({} MB)",
                (MAX_RECORDED_EPOCHS * aidnav_ins::ned_filter::BYTES_PER_RECORDED_EPOCH) >> 20
            ))
        })?;
        for e in &mut epochs {
            e.smoothed_antenna = e.record_index.map(|i| filter.antenna_of(&states[i]));
        }
    }
    Ok(Run { epochs, between })
}

/// The history of the accumulated GNSS corrections and, in an outage, the
/// predictors built from it (see [`OutageBridgeConfig`]).
#[derive(Debug, Default)]
struct BridgeState {
    /// Accumulated GNSS correction: position (NED, m), velocity (NED, m/s).
    total: [f64; 6],
    times: Vec<f64>,
    history: [Vec<f64>; 6],
    active: Option<ActiveBridge>,
}

/// The predictors of the current outage and the running integral of each
/// one's predicted velocity increment.
#[derive(Debug)]
struct ActiveBridge {
    /// Per channel (None: too little history to build the predictors).
    channels: Option<Vec<OutageBridge>>,
    last_t: f64,
    last_dv: [Vector3<f64>; 4],
    integral: [Vector3<f64>; 4],
}

impl BridgeState {
    /// An epoch with GNSS: add its corrections (the estimate fed back by
    /// its updates) to the history; any outage is over.
    fn record(&mut self, t: f64, fed_back: &Vector21) {
        self.active = None;
        for (c, h) in self.history.iter_mut().enumerate() {
            let i = if c < 3 {
                POSITION + c
            } else {
                VELOCITY + c - 3
            };
            self.total[c] += fed_back[i];
            h.push(self.total[c]);
        }
        self.times.push(t);
    }

    /// An epoch inside an outage: the antenna position each predictor
    /// gives (None when the predictors could not be built).
    fn bridged(&mut self, t: f64, antenna: &Geodetic, cfg: &BridgeConfig) -> Option<[Geodetic; 4]> {
        let (times, history) = (&self.times, &self.history);
        let active = self.active.get_or_insert_with(|| {
            let channels = history
                .iter()
                .map(|h| OutageBridge::start(times, h, cfg).ok())
                .collect::<Option<Vec<_>>>();
            ActiveBridge {
                channels,
                last_t: times.last().copied().unwrap_or(t),
                last_dv: [Vector3::zeros(); 4],
                integral: [Vector3::zeros(); 4],
            }
        });
        let channels = active.channels.as_ref()?;
        let increment = |p: Predictor, c: usize| channels[c].predict_increment(p, t);
        let mut out = [*antenna; 4];
        for (k, &p) in BRIDGE_PREDICTORS.iter().enumerate() {
            let dp = Vector3::new(increment(p, 0), increment(p, 1), increment(p, 2));
            let dv = Vector3::new(increment(p, 3), increment(p, 4), increment(p, 5));
            // Trapezoid over the epochs: the predicted velocity error
            // integrates into position.
            active.integral[k] += (active.last_dv[k] + dv) * (0.5 * (t - active.last_t));
            active.last_dv[k] = dv;
            out[k] = antenna.offset_by(&-(dp + active.integral[k]));
        }
        active.last_t = t;
        Some(out)
    }
}

/// Most covariance epochs a smoothing run keeps (≈ 4 GiB; about five hours
/// at the 20 Hz covariance rate plus updates).
pub const MAX_RECORDED_EPOCHS: usize = (4 << 30) / aidnav_ins::ned_filter::BYTES_PER_RECORDED_EPOCH;

/// The default outage schedule for length L.
pub fn outage_windows(
    cfg: &ScoreConfig,
    first_imu_s: f64,
    last_gnss_s: f64,
    length_s: f64,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for k in 0.. {
        let a = first_imu_s + cfg.lead_s + k as f64 * (length_s + cfg.gap_s);
        let b = a + length_s;
        if b >= last_gnss_s {
            break;
        }
        out.push((a, b));
    }
    out
}

/// Per outage length: RMS over windows of the maximum drift.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageScore {
    /// L [s].
    pub outage_s: f64,
    /// Windows scored.
    pub windows: usize,
    /// RMS over windows of the max horizontal drift [m].
    pub horizontal_m: f64,
    /// … vertical [m].
    pub vertical_m: f64,
    /// … 3-D [m].
    pub three_d_m: f64,
}

/// Score a run's epochs inside windows against the withheld RTK-fixed fixes.
pub fn score_windows(
    gnss: &[GnssFix],
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
) -> OutageScore {
    let mut maxima: Vec<[f64; 3]> = Vec::new();
    for &(a, b) in windows {
        let mut m = [0.0f64; 3];
        let mut any = false;
        for e in epochs {
            let g = &gnss[e.index];
            if g.time_s < a || g.time_s >= b || !is_reference(g) {
                continue;
            }
            let d = g.position.ned_to(&e.antenna);
            m[0] = m[0].max(d.xy().norm());
            m[1] = m[1].max(d.z.abs());
            m[2] = m[2].max(d.norm());
            any = true;
        }
        if any {
            maxima.push(m);
        }
    }
    let rms = |i: usize| {
        (maxima.iter().map(|m| m[i] * m[i]).sum::<f64>() / maxima.len().max(1) as f64).sqrt()
    };
    OutageScore {
        outage_s: length_s,
        windows: maxima.len(),
        horizontal_m: rms(0),
        vertical_m: rms(1),
        three_d_m: rms(2),
    }
}

/// The outage-window epochs with each epoch's antenna replaced by the
/// position bridged by predictor `k` of [`BRIDGE_PREDICTORS`] (epochs
/// without a bridge keep the coasting filter's).
pub fn bridged_epochs(epochs: &[Epoch], k: usize) -> Vec<Epoch> {
    epochs
        .iter()
        .map(|e| Epoch {
            antenna: e.bridged.map_or(e.antenna, |b| b[k]),
            ..*e
        })
        .collect()
}

/// Spec 20's efficiency criterion in the outage windows of one length:
/// how long after GNSS is lost the filter still predicts itself better than
/// GNSS (K_eff > 1), and how long its actual 3-D error stays below σ_GNSS.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EfficiencyScore {
    /// L [s].
    pub outage_s: f64,
    /// Windows scored.
    pub windows: usize,
    /// Mean σ_GNSS over the windows' epochs [m].
    pub sigma_gnss_m: f64,
    /// Mean over windows of the outage age at which K_eff first falls below
    /// 1 (windows where it never does count as L) [s].
    pub predicted_crossing_s: f64,
    /// Windows where it fell below 1.
    pub predicted_crossed: usize,
    /// Mean over windows of the age at which the actual 3-D error against
    /// the RTK-fixed reference first exceeds σ_GNSS (censored at L) [s].
    pub actual_crossing_s: f64,
    /// Windows where it did.
    pub actual_crossed: usize,
}

/// The efficiency criterion of a run with outage windows (see [`EfficiencyScore`]).
pub fn efficiency_in_windows(
    gnss: &[GnssFix],
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
) -> EfficiencyScore {
    let (mut n, mut sigma_sum, mut sigma_n) = (0usize, 0.0, 0usize);
    let (mut predicted, mut actual) = ((0.0, 0usize), (0.0, 0usize));
    for &(a, b) in windows {
        let inside: Vec<&Epoch> = epochs
            .iter()
            .filter(|e| (a..b).contains(&gnss[e.index].time_s))
            .collect();
        if inside.is_empty() {
            continue;
        }
        n += 1;
        let age = |e: &Epoch| gnss[e.index].time_s - a;
        let sigma_gnss = |e: &Epoch| e.k_eff * e.sigma.norm();
        for e in &inside {
            sigma_sum += sigma_gnss(e);
            sigma_n += 1;
        }
        let first = |hit: &dyn Fn(&Epoch) -> bool| inside.iter().find(|e| hit(e)).map(|e| age(e));
        for (acc, crossing) in [
            (&mut predicted, first(&|e| e.k_eff < 1.0)),
            (
                &mut actual,
                first(&|e| {
                    is_reference(&gnss[e.index])
                        && gnss[e.index].position.ned_to(&e.antenna).norm() > sigma_gnss(e)
                }),
            ),
        ] {
            acc.0 += crossing.unwrap_or(length_s);
            acc.1 += usize::from(crossing.is_some());
        }
    }
    let mean = |x: f64| x / n.max(1) as f64;
    EfficiencyScore {
        outage_s: length_s,
        windows: n,
        sigma_gnss_m: sigma_sum / sigma_n.max(1) as f64,
        predicted_crossing_s: mean(predicted.0),
        predicted_crossed: predicted.1,
        actual_crossing_s: mean(actual.0),
        actual_crossed: actual.1,
    }
}

/// Whether a fix serves as the reference of the scores: RTK fixed (Q = 1),
/// or of unknown quality (Q = 0, formats without a quality column).
fn is_reference(g: &GnssFix) -> bool {
    g.quality == 1 || g.quality == 0
}

/// RMS 3-D error over all RTK-fixed epochs against the clean fixes.
pub fn tracking_rms(gnss: &[GnssFix], epochs: &[Epoch]) -> f64 {
    let (sum, n) =
        epochs
            .iter()
            .filter(|e| is_reference(&gnss[e.index]))
            .fold((0.0, 0usize), |(s, n), e| {
                (
                    s + gnss[e.index].position.ned_to(&e.antenna).norm_squared(),
                    n + 1,
                )
            });
    (sum / n.max(1) as f64).sqrt()
}

/// Flight times (since the first epoch) at which spec 10's switch rule —
/// δ(n) non-increasing for `falling_s`, then ≤ threshold for 5 epochs —
/// declares the instrument errors converged, per threshold (None: never).
pub fn convergence_times(
    gnss: &[GnssFix],
    epochs: &[Epoch],
    thresholds: &[f64],
    falling_s: f64,
) -> Vec<Option<f64>> {
    use aidnav_supervisors::convergence::{ConvergenceSwitch, SwitchRule};
    let Some(t0) = epochs.first().map(|e| gnss[e.index].time_s) else {
        return vec![None; thresholds.len()];
    };
    thresholds
        .iter()
        .map(|&threshold| {
            let mut switch = ConvergenceSwitch::new(SwitchRule {
                threshold,
                falling_s,
                ..SwitchRule::default()
            });
            epochs
                .iter()
                .filter(|e| e.convergence.is_finite())
                .find_map(|e| {
                    let t = gnss[e.index].time_s - t0;
                    switch.observe(t, e.convergence).then_some(t)
                })
        })
        .collect()
}

/// RMS 3-D error over the RTK-fixed epochs where GNSS was used (not
/// withheld), against the clean fixes.
pub fn tracking_rms_with_gnss(gnss: &[GnssFix], epochs: &[Epoch]) -> f64 {
    let used: Vec<Epoch> = epochs
        .iter()
        .filter(|e| e.outcome.is_some())
        .copied()
        .collect();
    tracking_rms(gnss, &used)
}

/// One common jump per window for the fixes in [end, end + burst_s) after
/// each window (seeded), by GNSS index.
pub fn post_outage_bursts(
    gnss: &[GnssFix],
    windows: &[(f64, f64)],
    burst_s: f64,
    range_m: [f64; 2],
    seed: u64,
) -> Vec<Option<Vector3<f64>>> {
    let jumps = inject_outliers(windows.len(), 1.0, range_m, seed);
    gnss.iter()
        .map(|g| {
            windows
                .iter()
                .zip(&jumps)
                .find(|((_, end), _)| g.time_s >= *end && g.time_s < end + burst_s)
                .and_then(|(_, j)| *j)
        })
        .collect()
}

/// Outliers for a fraction of the epochs (seeded).
pub fn inject_outliers(
    n: usize,
    fraction: f64,
    range_m: [f64; 2],
    seed: u64,
) -> Vec<Option<Vector3<f64>>> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            if rng.random_bool(fraction) {
                let size = rng.random_range(range_m[0]..=range_m[1]);
                let dir = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                Some(dir.normalize() * size)
            } else {
                None
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A history whose velocity correction grows linearly (the INS kept
    /// needing a = 0.01 m/s² of north correction) is bridged, by the trend,
    /// with the position correction a τ²/2 — exactly, since the line fits
    /// the history exactly and the trapezoid rule is exact for it; the relay
    /// holds (no correction) up to T1, then follows the trend's increment.
    #[test]
    fn bridge_integrates_the_extrapolated_velocity_correction() {
        let cfg = OutageBridgeConfig::default().bridge();
        let (a, dt) = (0.01, 0.25);
        let mut state = BridgeState::default();
        for k in 0..400 {
            let mut fed_back = Vector21::zeros();
            if k > 0 {
                fed_back[VELOCITY] = a * dt;
            }
            state.record(k as f64 * dt, &fed_back);
        }
        let t0 = 399.0 * dt;
        let antenna = Geodetic {
            latitude_rad: 0.5,
            longitude_rad: 0.2,
            height_m: 30.0,
        };
        for k in 1..=120 {
            let tau = k as f64 * dt;
            let bridged = state.bridged(t0 + tau, &antenna, &cfg).unwrap();
            let north = |g: &Geodetic| antenna.ned_to(g).x;
            let trend = north(&bridged[0]);
            assert!(
                (trend + 0.5 * a * tau * tau).abs() < 1e-6,
                "τ = {tau}: {trend}"
            );
            let relay = north(&bridged[3]);
            if tau <= cfg.relay.t1_s {
                assert_eq!(relay, 0.0, "τ = {tau}");
            } else if tau <= cfg.relay.t2_s {
                // From T1 the relay's velocity increment is the trend's; its
                // integral lacks the trend's first T1 seconds, less half a
                // step's worth at the switch (the trapezoid spans the jump).
                let lacking = 0.5 * a * cfg.relay.t1_s * cfg.relay.t1_s;
                let d = relay - trend;
                assert!(
                    d >= lacking - 1e-6 && d <= lacking + 0.5 * a * cfg.relay.t1_s * dt + 1e-6,
                    "τ = {tau}: {d} vs {lacking}"
                );
            }
        }
        // GNSS is back: the outage is over, the next one starts afresh.
        state.record(t0 + 31.0, &Vector21::zeros());
        assert!(state.active.is_none());
    }

    #[test]
    fn policy_names_are_the_configuration_names() {
        let names: Vec<String> = PolicyName::ALL.iter().map(|p| p.name()).collect();
        assert_eq!(names[0], "accept");
        assert_eq!(names[8], "developed");
        for n in &names {
            let p: PolicyName =
                serde_json::from_value(serde_json::Value::String(n.clone())).unwrap();
            assert_eq!(&p.name(), n);
        }
    }
}
