//! Spec 20, "anomalies": INS error estimation from GNSS velocity when a share
//! of the fixes is anomalous — every estimator of the spec on the same
//! simulated data (common random numbers), scored by the RMS error of the
//! velocity-error estimate.
//!
//! Estimators (the `summary.json` keys):
//! - `kf_known_clean`: Kalman filter, known statistics, *no* anomalies (the floor);
//! - `kf_plain`: the same filter on the anomalous data;
//! - `kf_wrong_stats`: wrong a-priori statistics — the paper's model taken at
//!   its word (no process noise for the forcing, no equivalent tilt in the
//!   prior), Q and R further scaled by the scenario — on the anomalous data;
//! - `kf_reject`: known statistics + detector (eq. 5) + rejection (eq. 6);
//! - `adaptive`: innovation-feedback adaptive filter (eq. 3) alone;
//! - `adaptive_gain`: eq. 3 with the sliding-window adaptive gain of eq. 4 (no
//!   noise statistics in the gain), no detector;
//! - `adaptive_clean`: eq. 3 alone on the fixes *without* anomalies (the
//!   paper's "adaptive beats the KF" under model error, next to `kf_known_clean`);
//! - `adaptive_reject`: eq. 3 + detector + rejection;
//! - `developed`: the developed algorithm as spec 20 defines it — eq. 3 prior,
//!   detector (eq. 5) and limiting (eq. 8) with the filter's gain, the prior
//!   during anomalies predicted from the last stable epochs;
//! - `developed_eq4`: eq. 9 as printed, with eq. 4's gain in place of the
//!   filter's ([`aidnav_estimation::adaptive::LimitedAdaptiveGain`]);
//! - `chi2_gate`, `huber`: modern baselines on the known-statistics filter;
//! - `median_kf`, `tukey53h_kf`: the classical baselines the paper lists
//!   ("медианный фильтр, процедура Тьюки 53Х"): the known-statistics filter
//!   fed the causal running median of the last `median_window` fixes, or
//!   their causal Tukey 53H smooth ([`aidnav_estimation::prefilter`]).
//!
//! Beside the mixed fault list of the scenario, a per-type table
//! ([`TypeScores`], `per_type`) runs every estimator on one anomaly type at
//! a time — single outliers, short bursts, long bursts, 10 % and 30 %
//! random rates, bursts after outages — with the same truth draws (run k's
//! stream) for every type, each type beside what the paper says of it.
//!
//! "Known statistics" means what a 3-state filter can know of the truth
//! ([`PlatformChannel::known_process_noise`],
//! [`PlatformChannel::known_initial_covariance`]): the white-noise equivalent
//! of the unmodelled forcing on δV and the constant bias as an unknown
//! equivalent tilt. The adaptive filters need no Q; they start from the same prior.
//!
//! In the adaptive variants with a detector an anomalous innovation never
//! feeds the process noise: the mean of the last `stable_window` feedback
//! terms is used instead (the spec's "P predicted from the last stable
//! window"), so `adaptive_reject` and `adaptive_limit` differ only in
//! rejecting vs limiting.

use aidnav_estimation::adaptive::{AnomalyDetector, InnovationFeedbackNoise};
use aidnav_estimation::prefilter::{RunningMedian, Tukey53H};
use aidnav_estimation::{
    EstimationError, KalmanFilter, NoiseRule, Scheme, SchemeParameters, SchemePolicy,
};
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range, probability};
use aidnav_models::{PlatformChannel, PlatformTruth};
use nalgebra::{Matrix1, Matrix3, Vector1, Vector3};
use serde::{Deserialize, Serialize};

use aidnav_sim::faults::{FaultSpec, Outage, SigmaRange, plan};
use aidnav_sim::monte_carlo::{Cancel, MonteCarlo};
use aidnav_sim::rng::{channel_rng, standard_normal};

/// One row of the experiment: which scheme (measurement policy and
/// process-noise rule, from the engine's registry), on which data, with
/// which statistics.
struct Row {
    name: &'static str,
    scheme: Scheme,
    noise: NoiseRule,
    /// Runs on the fixes without anomalies.
    clean_data: bool,
    /// Believes the scenario's wrong Q and R.
    wrong_statistics: bool,
    /// What the fixes pass through before the filter.
    prefilter: Prefilter,
}

/// A classical pre-filter of the fixes (the paper's list of methods).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Prefilter {
    /// The fixes as they are.
    None,
    /// Causal running median of the last `median_window` fixes.
    Median,
    /// Causal Tukey 53H.
    Tukey53H,
}

/// A row running `scheme` as the registry defines it.
const fn row(name: &'static str, scheme: Scheme) -> Row {
    Row {
        name,
        scheme,
        noise: scheme.noise_rule(),
        clean_data: false,
        wrong_statistics: false,
        prefilter: Prefilter::None,
    }
}

/// Eq. 3's innovation feedback without the detector's guard: every
/// innovation feeds Q.
const FEEDBACK: NoiseRule = NoiseRule::Feedback { detector: false };
/// Eq. 3's feedback guarded by eq. 5's detector.
const GUARDED_FEEDBACK: NoiseRule = NoiseRule::Feedback { detector: true };

/// The estimators, in table order: the single source of their names,
/// schemes, data and statistics.
const ROWS: [Row; 14] = [
    Row {
        clean_data: true,
        ..row("kf_known_clean", Scheme::Accept)
    },
    row("kf_plain", Scheme::Accept),
    Row {
        wrong_statistics: true,
        ..row("kf_wrong_stats", Scheme::Accept)
    },
    row("kf_reject", Scheme::Rejection),
    Row {
        noise: FEEDBACK,
        ..row("adaptive", Scheme::Accept)
    },
    Row {
        noise: FEEDBACK,
        clean_data: true,
        ..row("adaptive_clean", Scheme::Accept)
    },
    Row {
        noise: FEEDBACK,
        ..row("adaptive_gain", Scheme::AdaptiveGain)
    },
    Row {
        noise: GUARDED_FEEDBACK,
        ..row("adaptive_reject", Scheme::Rejection)
    },
    row("developed", Scheme::Developed),
    Row {
        noise: GUARDED_FEEDBACK,
        ..row("developed_eq4", Scheme::LimitedAdaptiveGain)
    },
    row("chi2_gate", Scheme::Chi2Gate),
    row("huber", Scheme::Huber),
    Row {
        prefilter: Prefilter::Median,
        ..row("median_kf", Scheme::Accept)
    },
    Row {
        prefilter: Prefilter::Tukey53H,
        ..row("tukey53h_kf", Scheme::Accept)
    },
];

/// Names of the estimators, in table order.
pub const ESTIMATORS: [&str; ROWS.len()] = {
    let mut names = [""; ROWS.len()];
    let mut i = 0;
    while i < ROWS.len() {
        names[i] = ROWS[i].name;
        i += 1;
    }
    names
};

/// Position of an estimator in [`ESTIMATORS`].
fn index_of(name: &str) -> usize {
    ESTIMATORS
        .iter()
        .position(|n| *n == name)
        .unwrap_or_else(|| unreachable!("{name} is in ROWS"))
}

/// Scenario (TOML; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AnomaliesScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 100 000. Default 200.
    pub runs: usize,
    /// Epochs per run (T each), 10 … 10⁶. Default 5064 (one Schuler period at T = 1 s).
    pub epochs: usize,
    /// The platform channel and its truth parameters.
    pub platform: PlatformChannel,
    /// Faults added to the GNSS velocity (10–30 % of epochs anomalous).
    pub faults: Vec<FaultSpec>,
    /// Prior σ of δV [m/s]. Default 1.
    pub initial_velocity_sigma_mps: f64,
    /// Prior σ of the tilt \[rad\]. Default 1e-3.
    pub initial_tilt_sigma_rad: f64,
    /// `kf_wrong_stats` believes the model's Q (no forcing noise) × this. Default 1.
    pub wrong_q_scale: f64,
    /// `kf_wrong_stats` believes R × this. Default 1.
    pub wrong_r_scale: f64,
    /// Anomaly level γ of eq. 5, 1 … 10 000. Default: the engine's
    /// [`SchemeParameters::anomaly_gamma`] (9).
    pub gamma: f64,
    /// Stable epochs averaged for the feedback term during anomalies, ≥ 1. Default 10.
    pub stable_window: usize,
    /// Innovations n in eq. 4's empirical covariance M̂, ≥ 1. Default 10.
    pub gain_window: usize,
    /// χ² gate probability, 0 < p < 1. Default: the engine's
    /// [`SchemeParameters::chi2_probability`] (0.999).
    pub chi2_probability: f64,
    /// Huber threshold k on √NIS, 0.1 … 100. Default: the engine's
    /// [`SchemeParameters::huber_k`] (1.345).
    pub huber_k: f64,
    /// Fixes in `median_kf`'s running median, 1 … 1001. Default 5 (a
    /// spike of up to two fixes is removed).
    pub median_window: usize,
    /// The single-outlier and burst runs drawn like the paper's Figs. 3–6.
    pub illustration: Illustration,
    /// The per-type table.
    pub per_type: PerTypeScenario,
}

/// The per-type table: every estimator on one anomaly type at a time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PerTypeScenario {
    /// Monte Carlo runs per type, 0 … 100 000 (0: no table). Default 25
    /// (the six types cost 150 runs beside the main table's 200).
    pub runs: usize,
    /// Magnitude of every anomaly, in σ of the fixes. Default 5–30.
    pub magnitude: SigmaRange,
    /// Single outliers per run. Default 20.
    pub single_outliers: usize,
    /// Short bursts (2–20 epochs) per run. Default 4.
    pub short_bursts: usize,
    /// Long bursts (50–300 epochs) per run. Default 1.
    pub long_bursts: usize,
    /// Outages per run in the after-outage type, evenly spaced. Default 4.
    pub outages: usize,
    /// Length of each outage \[epochs\]. Default 100.
    pub outage_length: usize,
    /// Burst right after each outage \[epochs\]. Default 20.
    pub burst_after_outage: usize,
}

impl Default for PerTypeScenario {
    fn default() -> Self {
        Self {
            runs: 25,
            magnitude: SigmaRange {
                min: 5.0,
                max: 30.0,
            },
            single_outliers: 20,
            short_bursts: 4,
            long_bursts: 1,
            outages: 4,
            outage_length: 100,
            burst_after_outage: 20,
        }
    }
}

/// The anomaly types of the per-type table, in its order.
pub const ANOMALY_TYPES: [&str; 6] = [
    "single_outliers",
    "short_bursts",
    "long_bursts",
    "random_10_percent",
    "random_30_percent",
    "bursts_after_outages",
];

impl PerTypeScenario {
    /// The faults and outages of type `t` (index into [`ANOMALY_TYPES`])
    /// over `epochs` epochs.
    fn faults(&self, t: usize, epochs: usize) -> (Vec<FaultSpec>, Vec<Outage>) {
        let m = self.magnitude;
        let bursts = |count, min_length, max_length| FaultSpec::Bursts {
            count,
            min_length,
            max_length,
            magnitude: m,
        };
        let rate = |rate| FaultSpec::RandomRate { rate, magnitude: m };
        match t {
            0 => (
                vec![FaultSpec::SingleOutliers {
                    count: self.single_outliers,
                    magnitude: m,
                }],
                Vec::new(),
            ),
            1 => (vec![bursts(self.short_bursts, 2, 20)], Vec::new()),
            2 => (vec![bursts(self.long_bursts, 50, 300)], Vec::new()),
            3 => (vec![rate(0.1)], Vec::new()),
            4 => (vec![rate(0.3)], Vec::new()),
            _ => {
                // Evenly spaced: outage i centred at (i + 1) / (n + 1) of the run.
                let n = self.outages;
                let outages = (0..n)
                    .map(|i| Outage {
                        start: ((i + 1) * epochs / (n + 1)).saturating_sub(self.outage_length / 2),
                        length: self.outage_length,
                    })
                    .collect();
                (
                    vec![FaultSpec::AfterOutage {
                        length: self.burst_after_outage,
                        magnitude: m,
                    }],
                    outages,
                )
            }
        }
    }
}

/// The paper's illustrations (Figs. 3–6): one run with a single outlier and
/// one with a burst, placed by hand after the filters have converged.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Illustration {
    /// Epochs of each illustration run, 10 … 10⁶. Default 1500.
    pub epochs: usize,
    /// Epoch of the outlier / the burst's start. Default 1000.
    pub at_epoch: usize,
    /// Signed magnitude in units of the GNSS σ. Default 30.
    pub sigmas: f64,
    /// Burst length \[epochs\], ≥ 1. Default 20.
    pub burst_length: usize,
}

impl Default for Illustration {
    fn default() -> Self {
        Self {
            epochs: 1500,
            at_epoch: 1000,
            sigmas: 30.0,
            burst_length: 20,
        }
    }
}

impl Default for AnomaliesScenario {
    /// γ, the χ² probability and Huber's k: the engine's
    /// [`SchemeParameters::default`].
    fn default() -> Self {
        let scheme = SchemeParameters::default();
        Self {
            seed: 20261123,
            runs: 200,
            epochs: 5064,
            platform: PlatformChannel::default(),
            faults: vec![
                FaultSpec::RandomRate {
                    rate: 0.1,
                    magnitude: SigmaRange {
                        min: 5.0,
                        max: 30.0,
                    },
                },
                FaultSpec::Bursts {
                    count: 4,
                    min_length: 2,
                    max_length: 20,
                    magnitude: SigmaRange {
                        min: 5.0,
                        max: 30.0,
                    },
                },
                FaultSpec::Bursts {
                    count: 1,
                    min_length: 50,
                    max_length: 300,
                    magnitude: SigmaRange {
                        min: 5.0,
                        max: 30.0,
                    },
                },
            ],
            initial_velocity_sigma_mps: 1.0,
            initial_tilt_sigma_rad: 1e-3,
            wrong_q_scale: 1.0,
            wrong_r_scale: 1.0,
            gamma: scheme.anomaly_gamma,
            stable_window: 10,
            gain_window: 10,
            chi2_probability: scheme.chi2_probability,
            huber_k: scheme.huber_k,
            median_window: 5,
            illustration: Illustration::default(),
            per_type: PerTypeScenario::default(),
        }
    }
}

impl Validate for AnomaliesScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 100_000)?;
        count_in_range("epochs", self.epochs, 10, 1_000_000)?;
        super::validate_platform(&self.platform)?;
        crate::within(
            "initial_velocity_sigma_mps",
            self.initial_velocity_sigma_mps,
            crate::SIGMA_MPS_RANGE,
        )?;
        in_range(
            "initial_tilt_sigma_rad",
            self.initial_tilt_sigma_rad,
            1e-9,
            1.0,
        )?;
        crate::within("wrong_q_scale", self.wrong_q_scale, crate::SCALE_RANGE)?;
        crate::within("wrong_r_scale", self.wrong_r_scale, crate::SCALE_RANGE)?;
        in_range("gamma", self.gamma, 1.0, 1e4)?;
        count_in_range("stable_window", self.stable_window, 1, 10_000)?;
        count_in_range("gain_window", self.gain_window, 1, 10_000)?;
        probability("chi2_probability", self.chi2_probability)?;
        in_range("huber_k", self.huber_k, 0.1, 100.0)?;
        count_in_range("median_window", self.median_window, 1, 1001)?;
        let pt = &self.per_type;
        count_in_range("per_type.runs", pt.runs, 0, 100_000)?;
        for (key, count) in [
            ("per_type.single_outliers", pt.single_outliers),
            ("per_type.short_bursts", pt.short_bursts),
            ("per_type.long_bursts", pt.long_bursts),
            ("per_type.outages", pt.outages),
        ] {
            count_in_range(key, count, 0, 10_000)?;
        }
        count_in_range("per_type.outage_length", pt.outage_length, 1, self.epochs)?;
        count_in_range(
            "per_type.burst_after_outage",
            pt.burst_after_outage,
            1,
            self.epochs,
        )?;
        // The magnitude goes through the fault specs' own checks.
        crate::validate_faults(
            "per_type.magnitude",
            &[FaultSpec::RandomRate {
                rate: 0.1,
                magnitude: pt.magnitude,
            }],
        )?;
        let il = &self.illustration;
        count_in_range("illustration.epochs", il.epochs, 10, 1_000_000)?;
        count_in_range("illustration.at_epoch", il.at_epoch, 0, il.epochs - 1)?;
        count_in_range("illustration.burst_length", il.burst_length, 1, il.epochs)?;
        if !il.sigmas.is_finite() {
            return Err(Invalid::new(
                "illustration.sigmas",
                il.sigmas,
                "a finite number",
            ));
        }
        crate::validate_faults("faults", &self.faults)?;
        Ok(())
    }
}

/// One estimator's score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimatorScore {
    /// Key (see [`ESTIMATORS`]).
    pub name: String,
    /// RMS of the δV estimation error over all runs and epochs [m/s].
    pub rms_mps: f64,
    /// 10th percentile of the per-run RMS [m/s].
    pub p10_mps: f64,
    /// 90th percentile of the per-run RMS [m/s].
    pub p90_mps: f64,
    /// 1 − RMS / RMS(kf_plain).
    pub improvement_vs_kf: f64,
    /// 1 − RMS / RMS(kf_reject).
    pub improvement_vs_kf_reject: f64,
}

/// One run kept for plotting: truth and estimates of δV and tilt per epoch.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ExampleRun {
    /// True δV per epoch [m/s].
    pub truth: Vec<f64>,
    /// True tilt per epoch \[rad\].
    pub tilt: Vec<f64>,
    /// Whether the fix at each epoch was anomalous.
    pub anomalous: Vec<bool>,
    /// δV estimates per estimator (order of [`ESTIMATORS`]).
    pub estimates: Vec<Vec<f64>>,
    /// Tilt estimates per estimator (order of [`ESTIMATORS`]).
    pub tilt_estimates: Vec<Vec<f64>>,
}

/// Result of the experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AnomaliesResult {
    /// Scores in the order of [`ESTIMATORS`].
    pub scores: Vec<EstimatorScore>,
    /// Mean fraction of anomalous epochs.
    pub anomaly_fraction: f64,
    /// Run 0, for plots.
    #[serde(skip)]
    pub example: ExampleRun,
    /// The single-outlier illustration run (Figs. 3–4).
    #[serde(skip)]
    pub outlier: ExampleRun,
    /// The burst illustration run (Figs. 5–6).
    #[serde(skip)]
    pub burst: ExampleRun,
    /// One row per anomaly type ([`ANOMALY_TYPES`]; empty with
    /// `per_type.runs = 0`).
    pub per_type: Vec<TypeScores>,
}

/// Every estimator on one anomaly type.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TypeScores {
    /// The type (see [`ANOMALY_TYPES`]).
    pub anomaly_type: String,
    /// What the paper says of it.
    pub paper: String,
    /// Monte Carlo runs.
    pub runs: usize,
    /// Mean fraction of anomalous epochs.
    pub anomaly_fraction: f64,
    /// Mean fraction of epochs lost to outages (scored too: the estimators
    /// predict through them).
    pub lost_fraction: f64,
    /// RMS of the δV estimate per estimator \[m/s\] (order of [`ESTIMATORS`]).
    pub rms_mps: Vec<EstimatorRms>,
}

/// One estimator's RMS in a [`TypeScores`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimatorRms {
    /// Key (see [`ESTIMATORS`]).
    pub name: String,
    /// RMS of the δV estimation error over all runs and epochs \[m/s\].
    pub rms_mps: f64,
    /// 1 − RMS / RMS(kf_plain).
    pub improvement_vs_kf: f64,
}

/// Streams: truth noise and fix noise (0), faults (1), the per-type
/// table's faults (2 + type).
const CHANNEL_FAULTS: u64 = 1;
/// First stream of the per-type table's faults.
const CHANNEL_PER_TYPE: u64 = 2;

/// A pre-filter's state.
#[derive(Debug, Clone)]
enum PrefilterState {
    None,
    Median(RunningMedian),
    Tukey(Tukey53H),
}

impl PrefilterState {
    fn new(kind: Prefilter, median_window: usize) -> Self {
        match kind {
            Prefilter::None => Self::None,
            Prefilter::Median => Self::Median(
                RunningMedian::new(median_window)
                    .unwrap_or_else(|| unreachable!("median_window ≥ 1 is validated")),
            ),
            Prefilter::Tukey53H => Self::Tukey(Tukey53H::new()),
        }
    }

    /// The fix the filter sees (None: a gap, which restarts the window).
    fn pass(&mut self, z: Option<f64>) -> Option<f64> {
        match (self, z) {
            (Self::None, z) => z,
            (Self::Median(m), Some(z)) => Some(m.filter(z)),
            (Self::Tukey(t), Some(z)) => Some(t.filter(z)),
            (Self::Median(m), None) => {
                m.clear();
                None
            }
            (Self::Tukey(t), None) => {
                t.clear();
                None
            }
        }
    }
}

/// The state of one estimator through a run.
struct Estimator {
    kf: KalmanFilter<nalgebra::Const<3>>,
    /// Eq. 3's feedback term (previous gain, ring of the last stable
    /// terms), used when the row's noise rule is feedback.
    noise: InnovationFeedbackNoise<nalgebra::U3, nalgebra::U1>,
    adaptive: bool,
    /// The scheme's measurement policy (its eq. 4 window, if any, lives here).
    policy: SchemePolicy<nalgebra::U1>,
    /// What the fixes pass through first.
    prefilter: PrefilterState,
}

#[derive(Clone, Copy)]
struct Setup {
    phi: Matrix3<f64>,
    q: Matrix3<f64>,
    h: nalgebra::Matrix1x3<f64>,
    r: Matrix1<f64>,
    p0: Matrix3<f64>,
}

impl Estimator {
    fn new(row: &Row, p0: Matrix3<f64>, sc: &AnomaliesScenario) -> Result<Self, EstimationError> {
        let parameters = SchemeParameters {
            chi2_probability: sc.chi2_probability,
            huber_k: sc.huber_k,
            anomaly_gamma: sc.gamma,
            adaptive_window: sc.gain_window,
            ..SchemeParameters::default()
        };
        Ok(Self {
            kf: KalmanFilter::new(Vector3::zeros(), p0)?,
            noise: InnovationFeedbackNoise::new(
                nalgebra::Matrix3x1::zeros(),
                (row.noise == GUARDED_FEEDBACK).then_some(AnomalyDetector { gamma: sc.gamma }),
                sc.stable_window,
            )
            .unwrap_or_else(|| unreachable!("stable_window ≥ 1 is validated")),
            adaptive: row.noise != NoiseRule::Fixed,
            policy: row.scheme.policy(&parameters),
            prefilter: PrefilterState::new(row.prefilter, sc.median_window),
        })
    }

    /// One epoch: predict, then update with `z` when present (after the
    /// pre-filter).
    fn step(&mut self, s: &Setup, z: Option<f64>, first: bool) -> Result<(), EstimationError> {
        let z = self.prefilter.pass(z);
        if !first {
            if self.adaptive {
                self.kf.predict_state(&s.phi)?;
                let q = match z {
                    Some(z) => {
                        let innov = self.kf.innovation(&Vector1::new(z), &s.h, &s.r)?;
                        self.noise.process_noise(&innov.residual, &innov.s)
                    }
                    None => self.noise.stable_mean(),
                };
                self.kf.predict_covariance(&s.phi, &q)?;
            } else {
                self.kf.predict(&s.phi, &s.q)?;
            }
        }
        let Some(z) = z else { return Ok(()) };
        let rec = self
            .kf
            .update_with(&Vector1::new(z), &s.h, &s.r, &mut self.policy)?;
        self.noise.record_gain(&rec.gain);
        Ok(())
    }
}

/// One run's output, what [`finish`] combines: per-estimator sum of
/// squared δV errors, the count of anomalous epochs, and (run 0) the
/// example traces.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunOut {
    sq: Vec<f64>,
    anomalous_epochs: usize,
    lost_epochs: usize,
    example: Option<ExampleRun>,
}

/// The known-statistics and the wrong-statistics set-ups of a scenario.
fn setups(sc: &AnomaliesScenario) -> (Setup, Setup) {
    let (h, r) = sc.platform.velocity_measurement();
    let setup = Setup {
        phi: sc.platform.transition(),
        q: sc.platform.known_process_noise(),
        h,
        r,
        p0: sc
            .platform
            .known_initial_covariance(sc.initial_velocity_sigma_mps, sc.initial_tilt_sigma_rad),
    };
    let wrong = Setup {
        q: sc.platform.process_noise() * sc.wrong_q_scale,
        r: setup.r * sc.wrong_r_scale,
        p0: Matrix3::from_diagonal(&Vector3::new(
            sc.initial_velocity_sigma_mps.powi(2),
            sc.initial_tilt_sigma_rad.powi(2),
            sc.platform.drift_sigma_rad_s.powi(2),
        )),
        ..setup
    };
    (setup, wrong)
}

/// One run of every estimator over `epochs` epochs with the faults of `faults`.
fn one_run(
    sc: &AnomaliesScenario,
    (setup, wrong): (&Setup, &Setup),
    faults: &aidnav_sim::faults::FaultPlan,
    epochs: usize,
    rng: &mut aidnav_sim::rng::RunRng,
    keep: bool,
) -> Result<RunOut, EstimationError> {
    let sigma = sc.platform.gnss_velocity_sigma_mps;
    let mut truth = initial_truth(
        &sc.platform,
        sc.initial_velocity_sigma_mps,
        sc.initial_tilt_sigma_rad,
        rng,
    );
    let mut est: Vec<Estimator> = ROWS
        .iter()
        .map(|row| {
            let s = if row.wrong_statistics { wrong } else { setup };
            Estimator::new(row, s.p0, sc)
        })
        .collect::<Result<_, _>>()?;
    let mut sq = vec![0.0; ESTIMATORS.len()];
    let mut example = ExampleRun::default();
    if keep {
        example.estimates = vec![Vec::with_capacity(epochs); ESTIMATORS.len()];
        example.tilt_estimates = vec![Vec::with_capacity(epochs); ESTIMATORS.len()];
    }
    for e in 0..epochs {
        if e > 0 {
            truth.step(standard_normal(rng), standard_normal(rng));
        }
        let x = truth.x;
        let clean = x[0] + sigma * standard_normal(rng);
        let faulty = clean + faults.error[e];
        let lost = faults.lost[e];
        for (i, (es, row)) in est.iter_mut().zip(&ROWS).enumerate() {
            let z = if row.clean_data { clean } else { faulty };
            let s = if row.wrong_statistics { wrong } else { setup };
            es.step(s, (!lost).then_some(z), e == 0)
                .map_err(|err| err.at_epoch(e))?;
            sq[i] += (es.kf.state()[0] - x[0]).powi(2);
            if keep {
                example.estimates[i].push(es.kf.state()[0]);
                example.tilt_estimates[i].push(es.kf.state()[1]);
            }
        }
        if keep {
            example.truth.push(x[0]);
            example.tilt.push(x[1]);
            example.anomalous.push(faults.is_anomalous(e));
        }
    }
    Ok(RunOut {
        sq,
        anomalous_epochs: faults.error.iter().filter(|v| **v != 0.0).count(),
        lost_epochs: faults.lost.iter().filter(|l| **l).count(),
        example: keep.then_some(example),
    })
}

/// One run (run 0 of the scenario's seed) of every estimator with the given
/// faults instead of the scenario's, over `epochs` epochs: the paper's
/// illustrations (Figs. 3–6: a single outlier, a burst).
pub fn illustrate(
    sc: &AnomaliesScenario,
    faults: &[FaultSpec],
    epochs: usize,
) -> Result<ExampleRun, EstimationError> {
    let (setup, wrong) = setups(sc);
    let mut fault_rng = channel_rng(sc.seed, 0, CHANNEL_FAULTS);
    let plan = plan(
        faults,
        &[],
        epochs,
        sc.platform.gnss_velocity_sigma_mps,
        &mut fault_rng,
    );
    let mut rng = aidnav_sim::rng::run_rng(sc.seed, 0);
    let out = one_run(sc, (&setup, &wrong), &plan, epochs, &mut rng, true)?;
    Ok(out.example.unwrap_or_default())
}

/// Run the experiment: [`finish`] of every run ([`run_range`] over
/// `0..mc.runs`).
pub fn run(sc: &AnomaliesScenario, mc: &MonteCarlo) -> Result<AnomaliesResult, EstimationError> {
    finish_cancellable(sc, run_range(sc, mc, 0..mc.runs)?, &mc.cancel)
}

/// Runs `range` of the campaign (run k draws stream k of the seed and
/// its faults channel k, whatever the range): a chunk of the campaign, for
/// [`finish`] to combine with the others. Chunks may be computed anywhere;
/// their runs are the ones [`run`] computes.
pub fn run_range(
    sc: &AnomaliesScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<Vec<RunOut>, EstimationError> {
    let (setup, wrong) = setups(sc);
    let sigma = sc.platform.gnss_velocity_sigma_mps;
    mc.try_run_range(range, |k, rng| -> Result<RunOut, EstimationError> {
        let mut fault_rng = channel_rng(sc.seed, k as u64, CHANNEL_FAULTS);
        let faults = plan(&sc.faults, &[], sc.epochs, sigma, &mut fault_rng);
        one_run(sc, (&setup, &wrong), &faults, sc.epochs, rng, k == 0)
    })
}

/// The experiment's result from its runs, in run order (the chunks of
/// [`run_range`] concatenated): the same numbers, bit for bit, as [`run`]
/// with as many runs.
pub fn finish(
    sc: &AnomaliesScenario,
    per_run: Vec<RunOut>,
) -> Result<AnomaliesResult, EstimationError> {
    finish_cancellable(sc, per_run, &Cancel::default())
}

/// [`finish`] whose per-type campaign (the runs it computes itself) stops
/// when `cancel` is set, unwinding with [`Cancelled`](aidnav_sim::Cancelled) as
/// the main campaign's runs do.
pub fn finish_cancellable(
    sc: &AnomaliesScenario,
    per_run: Vec<RunOut>,
    cancel: &Cancel,
) -> Result<AnomaliesResult, EstimationError> {
    let n = sc.epochs as f64;
    let rms = rms_per_estimator(&per_run, sc.epochs);
    let scores = (0..ESTIMATORS.len())
        .map(|i| {
            let mut per: Vec<f64> = per_run.iter().map(|r| (r.sq[i] / n).sqrt()).collect();
            per.sort_by(f64::total_cmp);
            EstimatorScore {
                name: ESTIMATORS[i].to_string(),
                rms_mps: rms[i],
                p10_mps: percentile(&per, 0.1),
                p90_mps: percentile(&per, 0.9),
                improvement_vs_kf: 1.0 - rms[i] / rms[index_of("kf_plain")],
                improvement_vs_kf_reject: 1.0 - rms[i] / rms[index_of("kf_reject")],
            }
        })
        .collect();
    let anomaly_fraction = epoch_fraction(&per_run, sc.epochs, |r| r.anomalous_epochs);
    let example = per_run
        .into_iter()
        .find_map(|r| r.example)
        .unwrap_or_default();
    let il = sc.illustration;
    let fixed = |length| FaultSpec::Fixed {
        start: il.at_epoch,
        length,
        sigmas: il.sigmas,
    };
    Ok(AnomaliesResult {
        scores,
        anomaly_fraction,
        example,
        outlier: illustrate(sc, &[fixed(1)], il.epochs)?,
        burst: illustrate(sc, &[fixed(il.burst_length)], il.epochs)?,
        per_type: per_type(sc, cancel)?,
    })
}

/// RMS of each estimator's δV error over every run and epoch (order of
/// [`ESTIMATORS`]).
fn rms_per_estimator(per_run: &[RunOut], epochs: usize) -> Vec<f64> {
    let total = (per_run.len() * epochs) as f64;
    (0..ESTIMATORS.len())
        .map(|i| (per_run.iter().map(|r| r.sq[i]).sum::<f64>() / total).sqrt())
        .collect()
}

/// The fraction of all runs' epochs that `count` counts in each run.
fn epoch_fraction(per_run: &[RunOut], epochs: usize, count: fn(&RunOut) -> usize) -> f64 {
    per_run.iter().map(count).sum::<usize>() as f64 / (per_run.len() * epochs) as f64
}

/// The per-type table: for each of [`ANOMALY_TYPES`], `per_type.runs` runs
/// of every estimator; run k draws stream k of the seed for the truth (the
/// same truth for every type and as run k of the main table) and stream
/// `CHANNEL_PER_TYPE + type` of run k for the faults. Computed whole by
/// [`finish`] (not in [`run_range`]'s chunks: it is a fixed, small campaign).
fn per_type(sc: &AnomaliesScenario, cancel: &Cancel) -> Result<Vec<TypeScores>, EstimationError> {
    let pt = &sc.per_type;
    if pt.runs == 0 {
        return Ok(Vec::new());
    }
    let (setup, wrong) = setups(sc);
    let sigma = sc.platform.gnss_velocity_sigma_mps;
    let kf = index_of("kf_plain");
    let mut table = Vec::with_capacity(ANOMALY_TYPES.len());
    for (t, name) in ANOMALY_TYPES.iter().enumerate() {
        // No bar of its own: a few seconds beside the main campaign's.
        let campaign = MonteCarlo::new(pt.runs, sc.seed)
            .quiet()
            .with_cancel(cancel.clone());
        let (specs, outages) = pt.faults(t, sc.epochs);
        let per_run = campaign.try_run(|k, rng| -> Result<RunOut, EstimationError> {
            let mut fault_rng = channel_rng(sc.seed, k as u64, CHANNEL_PER_TYPE + t as u64);
            let faults = plan(&specs, &outages, sc.epochs, sigma, &mut fault_rng);
            one_run(sc, (&setup, &wrong), &faults, sc.epochs, rng, false)
        })?;
        let rms = rms_per_estimator(&per_run, sc.epochs);
        table.push(TypeScores {
            anomaly_type: (*name).to_string(),
            paper: crate::published::ANOMALY_TYPE_STATEMENTS[t].to_string(),
            runs: pt.runs,
            anomaly_fraction: epoch_fraction(&per_run, sc.epochs, |r| r.anomalous_epochs),
            lost_fraction: epoch_fraction(&per_run, sc.epochs, |r| r.lost_epochs),
            rms_mps: ESTIMATORS
                .iter()
                .zip(&rms)
                .map(|(n, &v)| EstimatorRms {
                    name: (*n).to_string(),
                    rms_mps: v,
                    improvement_vs_kf: 1.0 - v / rms[kf],
                })
                .collect(),
        });
    }
    Ok(table)
}

/// The truth at epoch 0: δV, tilt and drift drawn from their priors, b(0)
/// from its stationary law (four draws from `rng`, in that order).
pub(crate) fn initial_truth(
    platform: &PlatformChannel,
    velocity_sigma: f64,
    tilt_sigma: f64,
    rng: &mut aidnav_sim::rng::RunRng,
) -> PlatformTruth {
    let x0 = Vector3::new(
        velocity_sigma * standard_normal(rng),
        tilt_sigma * standard_normal(rng),
        platform.drift_sigma_rad_s * standard_normal(rng),
    );
    PlatformTruth::new(platform, x0, standard_normal(rng))
}

/// Linear-interpolated percentile of sorted values.
pub fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = p * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The per-type table: six types in order, each with the anomalous
    /// and lost fractions its faults make, and what the paper says of them
    /// where it holds on the measured numbers.
    #[test]
    fn the_per_type_table_runs_one_type_at_a_time() {
        let sc = AnomaliesScenario {
            runs: 2,
            epochs: 3000,
            per_type: PerTypeScenario {
                runs: 6,
                ..PerTypeScenario::default()
            },
            ..Default::default()
        };
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        let names: Vec<&str> = r.per_type.iter().map(|t| t.anomaly_type.as_str()).collect();
        assert_eq!(names, ANOMALY_TYPES);
        let t = |name: &str| r.per_type.iter().find(|t| t.anomaly_type == name).unwrap();
        let rms = |name: &str, est: &str| {
            t(name)
                .rms_mps
                .iter()
                .find(|e| e.name == est)
                .unwrap()
                .rms_mps
        };
        // 20 single outliers in 3000 epochs (two may fall together).
        let single = t("single_outliers").anomaly_fraction;
        assert!(
            single > 18.0 / 3000.0 && single <= 20.0 / 3000.0,
            "{single}"
        );
        for (name, rate) in [("random_10_percent", 0.1), ("random_30_percent", 0.3)] {
            let f = t(name).anomaly_fraction;
            assert!((f - rate).abs() < 0.02, "{name} {f}");
        }
        // Four outages of 100 epochs, and a 20-epoch burst after each.
        let after = t("bursts_after_outages");
        assert!((after.lost_fraction - 400.0 / 3000.0).abs() < 1e-12);
        assert!((after.anomaly_fraction - 80.0 / 3000.0).abs() < 1e-12);
        assert!(r.per_type.iter().take(5).all(|t| t.lost_fraction == 0.0));
        // The paper: limiting beats rejection on long sequences of
        // anomalies, and after an outage.
        assert!(rms("long_bursts", "developed") < rms("long_bursts", "kf_reject"));
        assert!(
            rms("bursts_after_outages", "developed") < rms("bursts_after_outages", "kf_reject")
        );
        // The running median removes isolated outliers before the filter.
        assert!(rms("single_outliers", "median_kf") < rms("single_outliers", "kf_plain"));
        assert!(rms("random_10_percent", "median_kf") < rms("random_10_percent", "kf_plain"));
        // Improvements are against kf_plain.
        let kf = rms("random_30_percent", "kf_plain");
        let e = t("random_30_percent")
            .rms_mps
            .iter()
            .find(|e| e.name == "developed")
            .unwrap();
        assert!((e.improvement_vs_kf - (1.0 - e.rms_mps / kf)).abs() < 1e-15);
        // `per_type.runs = 0`: no table.
        let none = AnomaliesScenario {
            per_type: PerTypeScenario {
                runs: 0,
                ..PerTypeScenario::default()
            },
            ..sc
        };
        assert!(
            run(&none, &MonteCarlo::new(none.runs, none.seed).quiet())
                .unwrap()
                .per_type
                .is_empty()
        );
    }

    /// The per-type table's own campaign stops when the caller's token is
    /// set, as the main campaign does: finishing the main runs with a set
    /// token unwinds with `Cancelled` instead of computing the table.
    #[test]
    fn the_per_type_campaign_honours_the_cancel_token() {
        let sc = AnomaliesScenario {
            runs: 2,
            per_type: PerTypeScenario {
                runs: 2,
                ..PerTypeScenario::default()
            },
            ..AnomaliesScenario::default()
        };
        let mc = MonteCarlo::new(sc.runs, sc.seed).quiet();
        let per_run = run_range(&sc, &mc, 0..sc.runs).unwrap();
        let cancel = Cancel::new();
        cancel.cancel();
        let r = Cancel::catch(|| finish_cancellable(&sc, per_run.clone(), &cancel));
        assert!(matches!(r, Err(aidnav_sim::Cancelled)));
        // Not set: the same table as `finish`.
        let whole = finish(&sc, per_run.clone()).unwrap();
        let again = finish_cancellable(&sc, per_run, &Cancel::new()).unwrap();
        assert_eq!(whole.per_type.len(), again.per_type.len());
        assert!(!whole.per_type.is_empty());
    }

    /// The scenario's new keys are range-checked by name.
    #[test]
    fn per_type_keys_are_validated() {
        let sc = AnomaliesScenario {
            median_window: 0,
            ..Default::default()
        };
        assert!(sc.validate().unwrap_err().key == "median_window");
        let mut sc = AnomaliesScenario::default();
        sc.per_type.outage_length = sc.epochs + 1;
        assert!(sc.validate().unwrap_err().key == "per_type.outage_length");
        let mut sc = AnomaliesScenario::default();
        sc.per_type.magnitude.max = f64::INFINITY;
        assert!(
            sc.validate()
                .unwrap_err()
                .key
                .starts_with("per_type.magnitude")
        );
    }

    #[test]
    fn reduced_run_orders_the_estimators() {
        let sc = AnomaliesScenario {
            runs: 8,
            epochs: 2000,
            ..Default::default()
        };
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        let rms = |name: &str| r.scores.iter().find(|s| s.name == name).unwrap().rms_mps;
        assert!(
            r.anomaly_fraction > 0.1 && r.anomaly_fraction < 0.3,
            "{}",
            r.anomaly_fraction
        );
        // Anomalies hurt the plain filter badly.
        assert!(rms("kf_plain") > 5.0 * rms("kf_known_clean"));
        // Spec 20's ordering "developed ≤ adaptive ≤ KF", as far as it holds
        // here (measured, not assumed; see the issue-3 closing note):
        // - developed (eq. 3 + 5 + 8) beats every KF and adaptive variant on
        //   the anomalous data;
        assert!(rms("developed") < rms("kf_plain"));
        assert!(rms("developed") < rms("kf_reject"));
        assert!(rms("developed") < rms("adaptive"));
        assert!(rms("developed") < rms("adaptive_reject"));
        // - adaptive ≤ KF holds where the paper's argument is, model error
        //   without anomalies: eq. 3 follows the unmodelled b(t) better than
        //   the best 3-state KF;
        assert!(rms("adaptive_clean") < rms("kf_known_clean"));
        // - but not under anomalies: eq. 3 without a detector turns every
        //   anomalous innovation into process noise.
        assert!(rms("adaptive") > rms("kf_plain"));
        // Rejection works in its good runs and locks out in others (the
        // filter's P stays small while the truth walks out of the gate).
        let score = |name: &str| r.scores.iter().find(|s| s.name == name).unwrap();
        assert!(score("kf_reject").p10_mps < score("kf_plain").p10_mps);
        assert!(score("kf_reject").p90_mps > 1.5 * score("kf_reject").p10_mps);
    }
}
