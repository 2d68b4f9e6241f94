//! Spec 20, "outages": GNSS disappears after a stretch of stable operation;
//! the INS velocity error is compensated with predicted errors. Every
//! predictor is scored against the uncorrected autonomous INS over a short
//! and a long outage of the same runs:
//! `improvement = 1 − RMS(δV − δV̂_pred) / RMS(δV)` over the outage.
//!
//! Before the outage a Kalman filter with known statistics estimates δV from
//! GNSS velocity; its estimates are the recorded history the predictors use.
//! The truth carries the accelerometer error B + b(t) that the filter's model
//! does not contain (see [`aidnav_models::platform`]): the a-priori model is
//! exact only up to b(t), which is what limits it on long outages.
//! The a-priori model predictor propagates the filter's full state with its
//! own Φ; the others come from [`aidnav_supervisors::outage`].

use aidnav_estimation::EstimationError;
use aidnav_estimation::gmdh::{FrequencyGrid, GmdhConfig, Split};
use aidnav_frames::constants::EARTH_MEAN_RADIUS_M;
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range};
use aidnav_models::PlatformChannel;
use aidnav_models::platform::PLATFORM_G_M_S2;
use aidnav_sim::faults::{FaultSpec, SigmaRange};
use aidnav_supervisors::outage::{BridgeConfig, RelaySchedule};
use serde::{Deserialize, Serialize};

#[cfg(doc)]
use aidnav_supervisors::efficiency::AdaptiveScalarVariance;

/// Innovations averaged by the adaptive σ_KOI (eq. 15's `M[θ²]`).
const ADAPTIVE_VARIANCE_WINDOW: usize = 10;

/// Stream of the recovery faults (0 is truth and fix noise).
const CHANNEL_RECOVERY_FAULTS: u64 = 1;

/// Predictor keys, in table order (`summary.json` uses these).
pub const PREDICTORS: [&str; 8] = [
    "apriori",
    "hold",
    "moving_average",
    "trend",
    "combined_trend",
    "gmdh",
    "gmdh_reselected",
    "relay",
];

/// Scenario (TOML; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutagesScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 100 000. Default 200.
    pub runs: usize,
    /// The platform channel and its truth parameters.
    pub platform: PlatformChannel,
    /// Prior σ of δV [m/s], 1e-6 … 1e3. Default 1.
    pub initial_velocity_sigma_mps: f64,
    /// Prior σ of the tilt \[rad\], 1e-9 … 1. Default 1e-3.
    pub initial_tilt_sigma_rad: f64,
    /// GNSS lost at this time \[s\], dt_s … [`MAX_TIME_S`]. Default 3000.
    pub outage_start_s: f64,
    /// Short outage length \[s\], dt_s … long_outage_s. Default 200.
    pub short_outage_s: f64,
    /// Long outage length \[s\], dt_s … [`MAX_TIME_S`]. Default 3000.
    pub long_outage_s: f64,
    /// Predictors and relay schedule.
    pub bridge: BridgeConfig,
    /// GNSS is back for this long after the long outage \[s\] (efficiency criterion phase), dt_s … [`MAX_TIME_S`] and within
    /// [`crate::MEMORY_BUDGET_BYTES`] (see [`OutagesScenario::memory_bytes`]). Default 600.
    pub recovery_s: f64,
    /// Faults on the returning GNSS (the paper stresses bursts right after an outage).
    pub recovery_faults: Vec<FaultSpec>,
    /// σ_GNSS of the efficiency criterion (prior data) [m/s], 1e-6 … 1e3. Default: the GNSS noise σ, 0.1.
    pub efficiency_sigma_gnss_mps: f64,
    /// Anomaly level γ of the filter's limiting during recovery, 1 … 10⁴. Default 9.
    pub recovery_gamma: f64,
}

impl Default for OutagesScenario {
    fn default() -> Self {
        let schuler = (PLATFORM_G_M_S2 / EARTH_MEAN_RADIUS_M).sqrt();
        let two_pi = 2.0 * std::f64::consts::PI;
        Self {
            seed: 20261123,
            runs: 200,
            platform: PlatformChannel::default(),
            initial_velocity_sigma_mps: 1.0,
            initial_tilt_sigma_rad: 1e-3,
            outage_start_s: 3000.0,
            short_outage_s: 200.0,
            long_outage_s: 3000.0,
            bridge: BridgeConfig {
                trend_window_s: 120.0,
                model_window_s: 2400.0,
                model_decimation: 5,
                relay: RelaySchedule {
                    t1_s: 10.0,
                    t2_s: 150.0,
                    t3_s: 600.0,
                    // The longest outage the bridge is designed to cover,
                    // the model's horizon below.
                    t4_s: Some(3000.0),
                },
                gmdh: GmdhConfig {
                    frequencies: vec![schuler],
                    search: Some(FrequencyGrid {
                        min: two_pi / 20_000.0,
                        max: two_pi / 600.0,
                        count: 16,
                    }),
                    split: Split::Alternating,
                    max_units: 3,
                    // Selected for the longest outage the bridge is designed
                    // to cover (the relay's T4), not for the record it fits.
                    horizon_s: Some(3000.0),
                    ..GmdhConfig::default()
                },
                // Re-selected for horizons doubling from T2 to T4.
                reselect_ratio: Some(2.0),
            },
            recovery_s: 600.0,
            recovery_faults: vec![FaultSpec::AfterOutage {
                length: 30,
                magnitude: SigmaRange {
                    min: 5.0,
                    max: 30.0,
                },
            }],
            efficiency_sigma_gnss_mps: 0.1,
            recovery_gamma: 9.0,
        }
    }
}

/// Longest time key of the scenario (`outage_start_s`, the outage lengths,
/// `recovery_s`, the bridge windows and relay times) \[s\]: 10⁶ s ≈ 11.6 days.
pub const MAX_TIME_S: f64 = 1e6;

impl OutagesScenario {
    /// Memory the experiment holds at most \[bytes\]: one run's filter
    /// history (time and estimate per epoch before the outage) and recovery
    /// fault plan (error and loss flag per epoch), run 0's plotted example
    /// (truth, six predictions and K_eff per outage epoch; K_eff and four
    /// errors per recovery epoch) and every run's summed record. Each
    /// further thread holds one more run's history and plan.
    pub fn memory_bytes(&self) -> f64 {
        let dt = self.platform.dt_s;
        let epochs = |s: f64| (s / dt).max(1.0);
        let (start, long, recovery) = (
            epochs(self.outage_start_s),
            epochs(self.long_outage_s),
            epochs(self.recovery_s),
        );
        let f = std::mem::size_of::<f64>() as f64;
        let run = start * 2.0 * f + recovery * (f + 1.0);
        let example = long * (2.0 + PREDICTORS.len() as f64 + 1.0) * f + recovery * 5.0 * f;
        run + example + self.runs as f64 * 512.0
    }
}

impl Validate for OutagesScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 100_000)?;
        super::validate_platform(&self.platform)?;
        in_range(
            "initial_velocity_sigma_mps",
            self.initial_velocity_sigma_mps,
            1e-6,
            1e3,
        )?;
        in_range(
            "initial_tilt_sigma_rad",
            self.initial_tilt_sigma_rad,
            1e-9,
            1.0,
        )?;
        let dt = self.platform.dt_s;
        let what = "the history, fault plan and plotted example of a run";
        let only = |start: f64, long: f64, recovery: f64| {
            OutagesScenario {
                outage_start_s: start,
                long_outage_s: long,
                recovery_s: recovery,
                runs: 0,
                ..self.clone()
            }
            .memory_bytes()
        };
        for (key, v, bytes) in [
            (
                "outage_start_s",
                self.outage_start_s,
                only(self.outage_start_s, 0.0, 0.0),
            ),
            (
                "long_outage_s",
                self.long_outage_s,
                only(0.0, self.long_outage_s, 0.0),
            ),
            (
                "recovery_s",
                self.recovery_s,
                only(0.0, 0.0, self.recovery_s),
            ),
        ] {
            crate::within_memory(key, v, bytes, what, &format!("{key} ≤ {MAX_TIME_S} s"))?;
        }
        let bytes = self.memory_bytes();
        crate::within_memory("runs", self.runs, bytes, what, "runs ≤ 100000")?;
        in_range("outage_start_s", self.outage_start_s, dt, MAX_TIME_S)?;
        in_range("short_outage_s", self.short_outage_s, dt, MAX_TIME_S)?;
        in_range("long_outage_s", self.long_outage_s, dt, MAX_TIME_S)?;
        if self.short_outage_s > self.long_outage_s {
            return Err(Invalid::new(
                "short_outage_s",
                self.short_outage_s,
                "short_outage_s ≤ long_outage_s",
            ));
        }
        let epochs = (self.outage_start_s + self.long_outage_s) / self.platform.dt_s;
        if epochs > 1e7 {
            return Err(Invalid::new(
                "long_outage_s",
                self.long_outage_s,
                "(outage_start_s + long_outage_s) / dt_s ≤ 10⁷ epochs",
            ));
        }
        in_range("trend_window_s", self.bridge.trend_window_s, dt, MAX_TIME_S)
            .map_err(|e| e.within("bridge"))?;
        in_range("model_window_s", self.bridge.model_window_s, dt, MAX_TIME_S)
            .map_err(|e| e.within("bridge"))?;
        if self.bridge.model_window_s > self.outage_start_s
            || self.bridge.trend_window_s > self.outage_start_s
        {
            return Err(Invalid::new(
                "bridge.model_window_s",
                self.bridge.model_window_s,
                "trend and model windows ≤ outage_start_s (the history available)",
            ));
        }
        count_in_range("model_decimation", self.bridge.model_decimation, 1, 1000)
            .map_err(|e| e.within("bridge"))?;
        let r = self.bridge.relay;
        if !(0.0 <= r.t1_s && r.t1_s <= r.t2_s && r.t2_s <= r.t3_s && r.t3_s <= MAX_TIME_S) {
            return Err(Invalid::new(
                "bridge.relay",
                format!("{}, {}, {}", r.t1_s, r.t2_s, r.t3_s),
                format!("0 ≤ t1_s ≤ t2_s ≤ t3_s ≤ {MAX_TIME_S}"),
            ));
        }
        if let Some(t4) = r.t4_s
            && !(r.t3_s < t4 && t4 <= MAX_TIME_S)
        {
            return Err(Invalid::new(
                "bridge.relay.t4_s",
                t4,
                format!("t3_s = {} < t4_s ≤ {MAX_TIME_S}", r.t3_s),
            ));
        }
        if let Err(e) = self.bridge.reselect_horizons() {
            return Err(Invalid::new(
                "bridge.reselect_ratio",
                format!("{:?}", self.bridge.reselect_ratio),
                e.to_string(),
            ));
        }
        crate::validate_gmdh("bridge.gmdh", &self.bridge.gmdh)?;
        // A harmonic above the Nyquist frequency of the fitted history
        // (sampled every dt_s · model_decimation) cannot be identified.
        let nyquist = std::f64::consts::PI / (dt * self.bridge.model_decimation as f64);
        let g = &self.bridge.gmdh;
        for (key, w) in g
            .frequencies
            .iter()
            .map(|w| ("frequencies", *w))
            .chain(g.search.map(|s| ("search.max", s.max)))
        {
            if w > nyquist {
                return Err(Invalid::new(
                    key,
                    w,
                    format!(
                        "ω ≤ π / (platform.dt_s · bridge.model_decimation) = {nyquist} rad/s (the history's Nyquist frequency)"
                    ),
                )
                .within("bridge.gmdh"));
            }
        }
        in_range("recovery_s", self.recovery_s, dt, MAX_TIME_S)?;
        crate::validate_faults("recovery_faults", &self.recovery_faults)?;
        in_range(
            "efficiency_sigma_gnss_mps",
            self.efficiency_sigma_gnss_mps,
            1e-6,
            1e3,
        )?;
        in_range("recovery_gamma", self.recovery_gamma, 1.0, 1e4)?;
        Ok(())
    }
}

/// One predictor's score over one outage length.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictorScore {
    /// Key (see [`PREDICTORS`]).
    pub name: String,
    /// RMS of δV − prediction over the outage and all runs [m/s].
    pub rms_mps: f64,
    /// 1 − RMS / RMS(uncorrected INS).
    pub improvement: f64,
    /// 1 − RMS / RMS(hold): against an INS corrected up to the outage start
    /// and free after it (a closed-loop INS reset at the outage start), the
    /// other reading of the paper's "autonomous INS".
    pub improvement_vs_reset: f64,
    /// 10th percentile of the per-run improvement.
    pub improvement_p10: f64,
    /// 90th percentile of the per-run improvement.
    pub improvement_p90: f64,
}

/// Scores for one outage length.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageScores {
    /// Outage length \[s\].
    pub length_s: f64,
    /// RMS of the uncorrected INS velocity error over the outage [m/s].
    pub uncorrected_rms_mps: f64,
    /// Per predictor, in [`PREDICTORS`] order.
    pub predictors: Vec<PredictorScore>,
}

/// Run 0's long outage, for plots: truth and each predictor.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct OutageExample {
    /// Times \[s\] from the outage start.
    pub age_s: Vec<f64>,
    /// True δV.
    pub truth: Vec<f64>,
    /// Per predictor (order of [`PREDICTORS`]).
    pub predictions: Vec<Vec<f64>>,
}

/// Navigation error after the outage by source (spec 20 Fig. 10).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EfficiencyScores {
    /// Recovery phase length \[s\].
    pub length_s: f64,
    /// RMS velocity error navigating on GNSS alone [m/s].
    pub rms_always_gnss_mps: f64,
    /// RMS velocity error navigating on INS + filter [m/s].
    pub rms_always_integrated_mps: f64,
    /// RMS velocity error with the source chosen per epoch by K_eff [m/s].
    pub rms_selected_mps: f64,
    /// Fraction of recovery epochs on which K_eff chose INS + filter.
    pub fraction_integrated: f64,
    /// As `rms_selected_mps`, with σ_KOI from the innovation-fed variance of
    /// eqs. 14–15 ([`AdaptiveScalarVariance`], 10-epoch window) instead of the filter's P.
    pub rms_selected_adaptive_mps: f64,
    /// Fraction of recovery epochs on which that selection chose INS + filter.
    pub fraction_integrated_adaptive: f64,
    /// As `rms_selected_mps`, with σ_KOI = √P⁻, the filter's σ *before* it
    /// fuses the epoch's fix. (With the posterior P and R = σ_GNSS², K_eff > 1
    /// at every fused epoch: P⁺ = P⁻R / (P⁻ + R) < R, so that selection
    /// can only ever choose INS + filter.)
    pub rms_selected_predicted_mps: f64,
    /// Fraction of recovery epochs on which that selection chose INS + filter.
    pub fraction_integrated_predicted: f64,
}

/// Run 0's K_eff from the outage start to the end of recovery.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct EfficiencyExample {
    /// Time since the outage started \[s\].
    pub age_s: Vec<f64>,
    /// K_eff = σ_GNSS / σ_KOI.
    pub k_eff: Vec<f64>,
    /// GNSS velocity error at each recovery epoch (the last
    /// `gnss_error.len()` entries of `age_s`) [m/s].
    pub gnss_error: Vec<f64>,
    /// INS + filter error (estimate − truth) at each recovery epoch [m/s].
    pub integrated_error: Vec<f64>,
    /// Error of the source chosen by K_eff with σ_KOI = √P⁻ [m/s].
    pub selected_error: Vec<f64>,
}

/// Result of the experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutagesResult {
    /// Short outage.
    pub short: OutageScores,
    /// Long outage.
    pub long: OutageScores,
    /// After the long outage: GNSS alone vs INS + filter vs K_eff selection.
    pub efficiency: EfficiencyScores,
    /// Run 0, for plots.
    #[serde(skip)]
    pub example: OutageExample,
    /// Run 0's K_eff, for plots.
    #[serde(skip)]
    pub efficiency_example: EfficiencyExample,
}

/// What can stop the experiment.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutagesError {
    /// The filter before the outage.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
    /// The self-organising model selection at the outage start.
    ///
    /// The cause is part of the message and deliberately not also returned
    /// by `Error::source`, so a printer walking the chain shows it once.
    #[error("model selection at the outage start: {0}")]
    Model(aidnav_estimation::gmdh::GmdhError),
    /// A quantity the scenario's bounds keep valid was not (σ² of the GNSS
    /// velocity, the filter's variance): an error, never a panic.
    #[error("{0} is not a positive finite variance")]
    Variance(&'static str),
}

impl From<aidnav_estimation::gmdh::GmdhError> for OutagesError {
    fn from(error: aidnav_estimation::gmdh::GmdhError) -> Self {
        OutagesError::Model(error)
    }
}

mod simulate;

pub use simulate::{RunOut, finish, run, run_range};

#[cfg(test)]
mod validation_tests {
    use super::*;
    use aidnav_io::config::parse_toml;
    use std::path::Path;

    /// The error of loading `text` as a scenario file `s.toml`.
    fn load_error(text: &str) -> String {
        parse_toml::<OutagesScenario>(text, Path::new("s.toml"))
            .unwrap_err()
            .to_string()
    }

    /// The `[bridge]` table's required keys (defaults), lines 1–5.
    const BRIDGE: &str = "[bridge]\ntrend_window_s = 120\nmodel_window_s = 2400\n\
                          model_decimation = 5\nrelay = { t1_s = 10, t2_s = 150, t3_s = 600 }\n";

    #[test]
    fn the_default_scenario_is_valid() {
        assert_eq!(OutagesScenario::default().validate(), Ok(()));
    }

    /// `examples/outages_regularity_only.toml` (the README's "regularity
    /// alone" row) is the default scenario without the GMDH horizon.
    #[test]
    fn the_regularity_only_example_differs_from_the_default_only_in_the_horizon() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/outages_regularity_only.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let sc = parse_toml::<OutagesScenario>(&text, &path).unwrap();
        assert_eq!(sc.validate(), Ok(()));
        assert_eq!(sc.bridge.gmdh.horizon_s, None);
        let mut default = OutagesScenario::default();
        default.bridge.gmdh.horizon_s = None;
        assert_eq!(sc, default);
    }

    #[test]
    fn an_underflowing_gnss_sigma_is_refused_at_load() {
        let e = load_error("runs = 2\n[platform]\ngnss_velocity_sigma_mps = 1e-170\n");
        assert!(
            e.starts_with("s.toml:3: platform.gnss_velocity_sigma_mps:"),
            "{e}"
        );
        assert!(e.contains("0.000001"), "{e}");
    }

    #[test]
    fn the_smallest_allowed_gnss_sigma_runs_without_panic() {
        let mut sc = OutagesScenario {
            runs: 1,
            outage_start_s: 2400.0,
            short_outage_s: 10.0,
            long_outage_s: 20.0,
            recovery_s: 20.0,
            ..Default::default()
        };
        sc.platform.gnss_velocity_sigma_mps = 1e-6;
        sc.efficiency_sigma_gnss_mps = 1e-6;
        assert_eq!(sc.validate(), Ok(()));
        let mc = aidnav_sim::monte_carlo::MonteCarlo::new(1, 1).quiet();
        assert!(run(&sc, &mc).is_ok());
    }

    #[test]
    fn a_huge_recovery_names_the_key_and_the_memory_it_would_need() {
        let e = load_error("recovery_s = 6e8\n");
        assert!(e.starts_with("s.toml:1: recovery_s:"), "{e}");
        assert!(e.contains("GB") && e.contains("at most"), "{e}");
    }

    #[test]
    fn a_huge_gmdh_frequency_is_refused_at_load() {
        let e = load_error(&format!("{BRIDGE}[bridge.gmdh]\nfrequencies = [1e308]\n"));
        assert!(e.starts_with("s.toml:7: bridge.gmdh.frequencies:"), "{e}");
        // Above the history's Nyquist frequency though below the GMDH bound.
        let e = load_error(&format!("{BRIDGE}[bridge.gmdh]\nfrequencies = [1.0]\n"));
        assert!(e.starts_with("s.toml:7: bridge.gmdh.frequencies:"), "{e}");
        assert!(e.contains("Nyquist"), "{e}");
    }

    #[test]
    fn a_huge_gmdh_degree_or_grid_is_refused_at_load() {
        let e = load_error(&format!("{BRIDGE}[bridge.gmdh]\nmax_degree = 2147483648\n"));
        assert!(e.starts_with("s.toml:7: bridge.gmdh.max_degree:"), "{e}");
        let e = load_error(&format!(
            "{BRIDGE}[bridge.gmdh.search]\nmin = 0.0003\nmax = 0.01\ncount = 4294967296\n"
        ));
        assert!(e.contains("bridge.gmdh.search.count:"), "{e}");
        assert!(e.contains("GB"), "{e}");
    }
}
