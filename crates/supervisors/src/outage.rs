//! Outage bridging (spec 20, paper eqs. 10–11): while GNSS is lost, the INS
//! output is corrected with a *predicted* error, from a predictor chosen by
//! the outage's age — the relay algorithm.
//!
//! [`OutageBridge::start`] takes the history of one error estimate recorded
//! during stable GNSS and builds every predictor once:
//! - hold: the last estimate;
//! - trend: `k t + d` fitted by least squares on the last `trend_window_s`;
//! - moving average: the mean of the same window, held (the paper's "линия
//!   скользящего среднего", which smooths the fluctuations the hold
//!   carries into the outage);
//! - self-organising model: [`aidnav_estimation::gmdh`] selection on the last
//!   `model_window_s` (candidates: polynomial, the given frequencies such as
//!   the Schuler frequency, and a searched grid);
//! - combined ("modified") trend: `w(τ) · trend + (1 − w(τ)) · model` with
//!   the weight depending on the prediction length τ: `w = 1` up to T2,
//!   falling linearly to 0 at T3, 0 after — so it is the trend where the
//!   relay uses the trend, the model where the relay uses the model, and the
//!   relay is continuous at T2 and T3 (spec 20 result 4: combined trend and
//!   model identical at the end of long prediction);
//! - relay: hold until T1, trend until T2, combined trend until T3, the model
//!   until T4, and the correction reached at T4 held after it (T0 = the
//!   outage start; the paper's eq. 10 ends at T4, the longest outage the
//!   bridge is designed for, so beyond it nothing is extrapolated further);
//! - re-selected model: the paper determines the model's parameters
//!   "depending on the moment t_k". With [`BridgeConfig::reselect_ratio`]
//!   set, the model used at outage age τ is the one selected for the
//!   forecast horizon of τ's stage: the stages end at T2, r·T2, r²·T2, …
//!   up to the last horizon (T4, else the model's own `horizon_s`, else
//!   T3), so a short outage is bridged by a model selected for a short
//!   forecast and a long one by models selected for ever longer ones. All
//!   stages are selected at the outage start, from the same record (an
//!   outage brings no new data); only the external criterion's horizon
//!   differs.
//!
//! The a-priori model predictor (propagating the filter state with Φ) needs
//! the whole state and lives with the filter, not here.

use aidnav_estimation::gmdh::{GmdhConfig, GmdhError, GmdhModel, select_for_horizons};
use serde::{Deserialize, Serialize};

/// A scalar predictor of the error during an outage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Predictor {
    /// Last estimate.
    Hold,
    /// Linear trend on the last window.
    Trend,
    /// Mean of the trend's window, held.
    MovingAverage,
    /// Trend blended into the self-organising model.
    CombinedTrend,
    /// Self-organising (GMDH) model.
    Gmdh,
    /// Switched by outage age.
    Relay,
    /// Self-organising model re-selected per stage of the outage
    /// ([`BridgeConfig::reselect_ratio`]); the single model without it.
    GmdhReselected,
}

/// Switch ages of the relay, seconds after the outage starts
/// (T1 < T2 < T3 < T4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelaySchedule {
    /// Hold until T1.
    pub t1_s: f64,
    /// Trend until T2.
    pub t2_s: f64,
    /// Combined trend until T3; the model after.
    pub t3_s: f64,
    /// The model until T4; after it the relay holds the correction it
    /// reached at T4. Default none (the model for ever).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub t4_s: Option<f64>,
}

impl RelaySchedule {
    /// Weight of the trend in the combined trend at outage age `age_s`:
    /// 1 up to T2, linear to 0 at T3, 0 after.
    pub fn trend_weight(&self, age_s: f64) -> f64 {
        if age_s <= self.t2_s {
            1.0
        } else if age_s >= self.t3_s {
            0.0
        } else {
            (self.t3_s - age_s) / (self.t3_s - self.t2_s)
        }
    }

    /// The age at which the relay evaluates its predictor: `age_s`, but
    /// no later than T4.
    pub fn frozen_age(&self, age_s: f64) -> f64 {
        match self.t4_s {
            Some(t4) if age_s > t4 => t4,
            _ => age_s,
        }
    }

    /// The predictor the relay uses at outage age `age_s` (after T4: the
    /// model's, evaluated at T4).
    pub fn choose(&self, age_s: f64) -> Predictor {
        if age_s <= self.t1_s {
            Predictor::Hold
        } else if age_s <= self.t2_s {
            Predictor::Trend
        } else if age_s <= self.t3_s {
            Predictor::CombinedTrend
        } else {
            Predictor::Gmdh
        }
    }
}

/// Windows and model selection of the bridge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BridgeConfig {
    /// History used by the trend \[s\].
    pub trend_window_s: f64,
    /// History used by the self-organising model \[s\].
    pub model_window_s: f64,
    /// Use every n-th sample of the model window for the selection (speed;
    /// the last sample is always used). Default 1.
    #[serde(default = "one")]
    pub model_decimation: usize,
    /// Relay switch ages.
    pub relay: RelaySchedule,
    /// Model selection.
    pub gmdh: GmdhConfig,
    /// Ratio r of the re-selected model's stages (see the module docs):
    /// horizons T2, r·T2, r²·T2, … up to the last. Default none: one model,
    /// selected once for `gmdh.horizon_s`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reselect_ratio: Option<f64>,
}

fn one() -> usize {
    1
}

/// Most stages the re-selected model may have (each is one GMDH selection
/// at the outage start).
pub const MAX_RESELECT_STAGES: usize = 32;

impl BridgeConfig {
    /// Forecast horizons of the re-selected model's stages \[s of outage
    /// age\], ascending; the stage of horizon h_j covers ages
    /// (h_{j−1}, h_j], the last stage every later age. Empty without
    /// [`BridgeConfig::reselect_ratio`]. Errors name the key when the ratio
    /// is not > 1 or the stages would exceed [`MAX_RESELECT_STAGES`].
    pub fn reselect_horizons(&self) -> Result<Vec<f64>, GmdhError> {
        let Some(ratio) = self.reselect_ratio else {
            return Ok(Vec::new());
        };
        if !(ratio.is_finite() && ratio > 1.0) {
            return Err(GmdhError::Config(format!(
                "reselect_ratio {ratio} must be a number > 1"
            )));
        }
        let last = self
            .relay
            .t4_s
            .or(self.gmdh.horizon_s)
            .unwrap_or(self.relay.t3_s);
        let first = self.relay.t2_s.min(last);
        if !(first > 0.0 && last.is_finite()) {
            return Err(GmdhError::Config(format!(
                "reselect_ratio: the stages from T2 = {first} s to {last} s must be positive and finite"
            )));
        }
        let mut horizons = vec![first];
        while *horizons.last().expect("one horizon") < last {
            if horizons.len() == MAX_RESELECT_STAGES {
                return Err(GmdhError::Config(format!(
                    "reselect_ratio {ratio}: more than {MAX_RESELECT_STAGES} stages from {first} s to {last} s; use a larger ratio"
                )));
            }
            let next = (horizons.last().expect("one horizon") * ratio).min(last);
            horizons.push(next);
        }
        Ok(horizons)
    }
}

/// Every predictor, built at the outage start from the recorded history.
///
/// A correction that grew linearly (0.1 per second) up to the outage is
/// continued by the trend; the relay holds (adds nothing) before T1.
///
/// ```
/// use aidnav_estimation::gmdh::GmdhConfig;
/// use aidnav_supervisors::outage::{BridgeConfig, OutageBridge, Predictor, RelaySchedule};
///
/// let times: Vec<f64> = (0..120).map(|k| k as f64 * 0.5).collect();
/// let history: Vec<f64> = times.iter().map(|t| 0.1 * t).collect();
/// let cfg = BridgeConfig {
///     trend_window_s: 30.0,
///     model_window_s: 60.0,
///     model_decimation: 2,
///     relay: RelaySchedule { t1_s: 1.0, t2_s: 10.0, t3_s: 30.0, t4_s: None },
///     gmdh: GmdhConfig::default(),
///     reselect_ratio: None,
/// };
/// let bridge = OutageBridge::start(&times, &history, &cfg).unwrap();
/// let t = times[times.len() - 1] + 5.0;
/// assert!((bridge.predict_increment(Predictor::Trend, t) - 0.5).abs() < 1e-9);
/// assert_eq!(bridge.predict_increment(Predictor::Relay, times[times.len() - 1] + 0.5), 0.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct OutageBridge {
    t0: f64,
    last: f64,
    mean: f64,
    slope: f64,
    intercept: f64,
    model: GmdhModel,
    /// The re-selected models: (stage horizon \[s of age\], model).
    stages: Vec<(f64, GmdhModel)>,
    relay: RelaySchedule,
}

/// Least-squares line through (t, y).
fn line(t: &[f64], y: &[f64]) -> (f64, f64) {
    let n = t.len() as f64;
    let (mt, my) = (t.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (a, b) in t.iter().zip(y) {
        sxy += (a - mt) * (b - my);
        sxx += (a - mt) * (a - mt);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (slope, my - slope * mt)
}

impl OutageBridge {
    /// Build the predictors from `times` / `estimates` (oldest first) recorded
    /// up to the outage start `times.last()`.
    pub fn start(
        times: &[f64],
        estimates: &[f64],
        config: &BridgeConfig,
    ) -> Result<Self, GmdhError> {
        let (Some(&t0), Some(&last)) = (times.last(), estimates.last()) else {
            return Err(GmdhError::TooFewSamples {
                samples: 0,
                needed: 6,
            });
        };
        let from = |w: f64| times.partition_point(|&t| t < t0 - w);
        let k = from(config.trend_window_s).min(times.len().saturating_sub(2));
        let (slope, intercept) = line(&times[k..], &estimates[k..]);
        let mean = estimates[k..].iter().sum::<f64>() / (times.len() - k) as f64;
        let m = from(config.model_window_s);
        let step = config.model_decimation.max(1);
        // Every step-th sample counted back from the last, so the model always
        // sees the sample at the outage start.
        let n = times.len();
        let keep: Vec<usize> = (m..n)
            .filter(|i| (n - 1 - i).is_multiple_of(step))
            .collect();
        let mt: Vec<f64> = keep.iter().map(|&i| times[i]).collect();
        let my: Vec<f64> = keep.iter().map(|&i| estimates[i]).collect();
        // One selection per horizon, the fits shared (select_for_horizons).
        let stage_horizons = config.reselect_horizons()?;
        let horizons: Vec<Option<f64>> = std::iter::once(config.gmdh.horizon_s)
            .chain(stage_horizons.iter().copied().map(Some))
            .collect();
        let mut selections = select_for_horizons(&mt, &my, &config.gmdh, &horizons)?
            .into_iter()
            .map(|s| s.model);
        let model = selections.next().expect("the single model's selection");
        let stages = stage_horizons.into_iter().zip(selections).collect();
        Ok(Self {
            t0,
            last,
            mean,
            slope,
            intercept,
            model,
            stages,
            relay: config.relay,
        })
    }

    /// The re-selected models with the horizon each was selected for
    /// (empty without [`BridgeConfig::reselect_ratio`]).
    pub fn stages(&self) -> &[(f64, GmdhModel)] {
        &self.stages
    }

    /// The model in use at outage age `age_s`: its stage's re-selected
    /// model, or the single model.
    fn model_at(&self, age_s: f64) -> &GmdhModel {
        if self.stages.is_empty() {
            return &self.model;
        }
        let j = self
            .stages
            .partition_point(|(horizon, _)| *horizon < age_s)
            .min(self.stages.len() - 1);
        &self.stages[j].1
    }

    /// The selected self-organising model.
    pub fn model(&self) -> &GmdhModel {
        &self.model
    }

    /// Prediction of `predictor` at time `t` (≥ the outage start).
    pub fn predict(&self, predictor: Predictor, t: f64) -> f64 {
        let age = t - self.t0;
        match predictor {
            Predictor::Hold => self.last,
            Predictor::MovingAverage => self.mean,
            Predictor::Trend => self.slope * t + self.intercept,
            Predictor::Gmdh => self.model.predict(t),
            Predictor::CombinedTrend => {
                let w = self.relay.trend_weight(age);
                w * (self.slope * t + self.intercept) + (1.0 - w) * self.model.predict(t)
            }
            Predictor::Relay => {
                let age = self.relay.frozen_age(age);
                self.predict(self.relay.choose(age), self.t0 + age)
            }
            Predictor::GmdhReselected => self.model_at(age).predict(t),
        }
    }

    /// The change each predictor foresees since the outage start, every
    /// component anchored at its own value there (the trend's line and the
    /// model do not pass exactly through the last estimate): for correcting
    /// a navigation output that was right at the outage start. Hold and
    /// moving average (flat): 0;
    /// trend and model: `f(t) − f(T0)`; combined trend: the weighted
    /// increments; relay: the increment of the predictor it uses at that age.
    pub fn predict_increment(&self, predictor: Predictor, t: f64) -> f64 {
        let age = t - self.t0;
        let trend = || self.slope * (t - self.t0);
        let model = || self.model.predict(t) - self.model.predict(self.t0);
        match predictor {
            Predictor::Hold | Predictor::MovingAverage => 0.0,
            Predictor::Trend => trend(),
            Predictor::Gmdh => model(),
            Predictor::CombinedTrend => {
                let w = self.relay.trend_weight(age);
                w * trend() + (1.0 - w) * model()
            }
            Predictor::Relay => {
                let age = self.relay.frozen_age(age);
                self.predict_increment(self.relay.choose(age), self.t0 + age)
            }
            Predictor::GmdhReselected => {
                let model = self.model_at(age);
                model.predict(t) - model.predict(self.t0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_estimation::gmdh::select;

    fn config() -> BridgeConfig {
        BridgeConfig {
            trend_window_s: 50.0,
            model_window_s: 1000.0,
            model_decimation: 1,
            relay: RelaySchedule {
                t1_s: 10.0,
                t2_s: 100.0,
                t3_s: 300.0,
                t4_s: None,
            },
            gmdh: GmdhConfig {
                frequencies: vec![2.0 * std::f64::consts::PI / 500.0],
                ..GmdhConfig::default()
            },
            reselect_ratio: None,
        }
    }

    #[test]
    fn predictors_on_a_known_signal() {
        let w = 2.0 * std::f64::consts::PI / 500.0;
        let f = |t: f64| 3.0 * (w * t).sin() + 0.5;
        let t: Vec<f64> = (0..1000).map(f64::from).collect();
        let y: Vec<f64> = t.iter().map(|&t| f(t)).collect();
        let b = OutageBridge::start(&t, &y, &config()).unwrap();
        assert_eq!(b.predict(Predictor::Hold, 1500.0), f(999.0));
        // The moving average: the mean of the last 50 s (t = 949 … 999,
        // 51 samples), against the closed form of the sine's mean there.
        let mean = (949..=999).map(|t| f(f64::from(t))).sum::<f64>() / 51.0;
        assert!((b.predict(Predictor::MovingAverage, 1500.0) - mean).abs() < 1e-12);
        assert_eq!(b.predict_increment(Predictor::MovingAverage, 1500.0), 0.0);
        // The model knows the signal: exact far beyond the window.
        assert!((b.predict(Predictor::Gmdh, 1700.0) - f(1700.0)).abs() < 1e-6);
        // The trend follows the local slope: good shortly after, bad later.
        // (curvature over the 50 s window biases the line by ≈ f″ W² / 6 ≈ 0.06)
        assert!((b.predict(Predictor::Trend, 1005.0) - f(1005.0)).abs() < 0.1);
        assert!((b.predict(Predictor::Trend, 1400.0) - f(1400.0)).abs() > 1.0);
        // Combined: trend at the start, model after the blend.
        assert_eq!(
            b.predict(Predictor::CombinedTrend, 999.0),
            b.predict(Predictor::Trend, 999.0)
        );
        assert_eq!(
            b.predict(Predictor::CombinedTrend, 1300.0),
            b.predict(Predictor::Gmdh, 1300.0)
        );
        // The relay is continuous where it hands over to and from the
        // combined trend (T2, T3); only the hold → trend switch at T1 jumps.
        for switch in [100.0, 300.0] {
            let before = b.predict(Predictor::Relay, 999.0 + switch - 1e-6);
            let after = b.predict(Predictor::Relay, 999.0 + switch + 1e-6);
            assert!(
                (before - after).abs() < 1e-4,
                "T = {switch}: {before} vs {after}"
            );
        }
        // Increments: zero at the start for every predictor, and the same
        // change as the predictor itself.
        for p in [
            Predictor::Hold,
            Predictor::Trend,
            Predictor::CombinedTrend,
            Predictor::Gmdh,
            Predictor::Relay,
        ] {
            assert_eq!(b.predict_increment(p, 999.0), 0.0, "{p:?}");
        }
        for p in [Predictor::Trend, Predictor::Gmdh] {
            let change = b.predict(p, 1100.0) - b.predict(p, 999.0);
            assert!((b.predict_increment(p, 1100.0) - change).abs() < 1e-12);
        }
        assert_eq!(
            b.predict_increment(Predictor::Relay, 1199.0),
            b.predict_increment(Predictor::CombinedTrend, 1199.0)
        );
        // Relay: follows its schedule.
        for (age, p) in [
            (5.0, Predictor::Hold),
            (50.0, Predictor::Trend),
            (200.0, Predictor::CombinedTrend),
            (400.0, Predictor::Gmdh),
        ] {
            assert_eq!(
                b.predict(Predictor::Relay, 999.0 + age),
                b.predict(p, 999.0 + age),
                "age {age}"
            );
        }
    }

    #[test]
    fn reselection_stages_double_from_t2_to_t4() {
        let mut cfg = config();
        assert!(cfg.reselect_horizons().unwrap().is_empty());
        cfg.relay.t4_s = Some(1000.0);
        cfg.reselect_ratio = Some(2.0);
        assert_eq!(
            cfg.reselect_horizons().unwrap(),
            vec![100.0, 200.0, 400.0, 800.0, 1000.0]
        );
        // Without T4 the stages end at the model's horizon, else at T3.
        cfg.relay.t4_s = None;
        assert_eq!(cfg.reselect_horizons().unwrap(), vec![100.0, 200.0, 300.0]);
        cfg.gmdh.horizon_s = Some(500.0);
        assert_eq!(
            cfg.reselect_horizons().unwrap(),
            vec![100.0, 200.0, 400.0, 500.0]
        );
        for bad in [1.0, 0.5, f64::NAN] {
            cfg.reselect_ratio = Some(bad);
            let e = cfg.reselect_horizons().unwrap_err().to_string();
            assert!(e.contains("reselect_ratio"), "{e}");
        }
        cfg.reselect_ratio = Some(1.0001);
        let e = cfg.reselect_horizons().unwrap_err().to_string();
        assert!(e.contains("more than 32 stages"), "{e}");
    }

    /// Each stage's model is the one a selection for that stage's horizon
    /// gives on its own; the stage is chosen by the outage's age.
    #[test]
    fn the_reselected_model_is_the_stage_horizons_selection() {
        // A slow harmonic the record holds less than a period of, a line and
        // noise-like wiggles: the structure chosen depends on the horizon.
        let t: Vec<f64> = (0..1000).map(f64::from).collect();
        let y: Vec<f64> = t
            .iter()
            .map(|&t| 2.0 * (t / 700.0).sin() + 0.001 * t + 0.05 * (1.3 * t).sin())
            .collect();
        let mut cfg = config();
        cfg.relay.t4_s = Some(800.0);
        cfg.reselect_ratio = Some(2.0);
        cfg.gmdh.search = Some(aidnav_estimation::gmdh::FrequencyGrid {
            min: 1e-3,
            max: 0.05,
            count: 12,
        });
        cfg.gmdh.max_units = 3;
        let b = OutageBridge::start(&t, &y, &cfg).unwrap();
        let horizons = cfg.reselect_horizons().unwrap();
        assert_eq!(b.stages().len(), horizons.len());
        assert!(
            b.stages()
                .iter()
                .any(|(_, m)| m.units != b.stages()[0].1.units),
            "the horizons select different structures"
        );
        let t0 = 999.0;
        for (j, h) in horizons.iter().enumerate() {
            let alone = select(
                &t,
                &y,
                &GmdhConfig {
                    horizon_s: Some(*h),
                    ..cfg.gmdh.clone()
                },
            )
            .unwrap()
            .model;
            assert_eq!(b.stages()[j], (*h, alone.clone()));
            // An age inside this stage (just below its horizon) uses it.
            let t_in = t0 + h - 1.0;
            assert_eq!(
                b.predict(Predictor::GmdhReselected, t_in),
                alone.predict(t_in)
            );
            assert_eq!(
                b.predict_increment(Predictor::GmdhReselected, t_in),
                alone.predict(t_in) - alone.predict(t0)
            );
        }
        // Beyond the last horizon the last stage's model goes on.
        let last = &b.stages().last().unwrap().1;
        assert_eq!(
            b.predict(Predictor::GmdhReselected, t0 + 5000.0),
            last.predict(t0 + 5000.0)
        );
        // Without re-selection it is the single model.
        let single = OutageBridge::start(&t, &y, &config()).unwrap();
        assert!(single.stages().is_empty());
        assert_eq!(
            single.predict(Predictor::GmdhReselected, t0 + 123.0),
            single.predict(Predictor::Gmdh, t0 + 123.0)
        );
    }

    #[test]
    fn after_t4_the_relay_holds_its_correction() {
        let w = 2.0 * std::f64::consts::PI / 500.0;
        let t: Vec<f64> = (0..1000).map(f64::from).collect();
        let y: Vec<f64> = t.iter().map(|&t| 3.0 * (w * t).sin() + 0.5).collect();
        let mut cfg = config();
        let free = OutageBridge::start(&t, &y, &cfg).unwrap();
        cfg.relay.t4_s = Some(400.0);
        let b = OutageBridge::start(&t, &y, &cfg).unwrap();
        let t0 = 999.0;
        // Up to T4 nothing changes; after it the value at T4 is held.
        for age in [5.0, 50.0, 200.0, 350.0, 400.0] {
            assert_eq!(
                b.predict(Predictor::Relay, t0 + age),
                free.predict(Predictor::Relay, t0 + age)
            );
        }
        let at_t4 = b.predict(Predictor::Relay, t0 + 400.0);
        let inc_t4 = b.predict_increment(Predictor::Relay, t0 + 400.0);
        for age in [400.5, 450.0, 1000.0] {
            assert_eq!(b.predict(Predictor::Relay, t0 + age), at_t4);
            assert_eq!(b.predict_increment(Predictor::Relay, t0 + age), inc_t4);
        }
        assert!((free.predict(Predictor::Relay, t0 + 450.0) - at_t4).abs() > 0.1);
    }
}
