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
//!   after (T0 = the outage start).
//!
//! The a-priori model predictor (propagating the filter state with Φ) needs
//! the whole state and lives with the filter, not here.

use aidnav_estimation::gmdh::{GmdhConfig, GmdhError, GmdhModel, select};
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
}

/// Switch ages of the relay, seconds after the outage starts (T1 < T2 < T3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelaySchedule {
    /// Hold until T1.
    pub t1_s: f64,
    /// Trend until T2.
    pub t2_s: f64,
    /// Combined trend until T3; the model after.
    pub t3_s: f64,
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

    /// The predictor the relay uses at outage age `age_s`.
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
}

fn one() -> usize {
    1
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
///     relay: RelaySchedule { t1_s: 1.0, t2_s: 10.0, t3_s: 30.0 },
///     gmdh: GmdhConfig::default(),
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
        let model = select(&mt, &my, &config.gmdh)?.model;
        Ok(Self {
            t0,
            last,
            mean,
            slope,
            intercept,
            model,
            relay: config.relay,
        })
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
            Predictor::Relay => self.predict(self.relay.choose(age), t),
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
            Predictor::Relay => self.predict_increment(self.relay.choose(age), t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config() -> BridgeConfig {
        BridgeConfig {
            trend_window_s: 50.0,
            model_window_s: 1000.0,
            model_decimation: 1,
            relay: RelaySchedule {
                t1_s: 10.0,
                t2_s: 100.0,
                t3_s: 300.0,
            },
            gmdh: GmdhConfig {
                frequencies: vec![2.0 * std::f64::consts::PI / 500.0],
                ..GmdhConfig::default()
            },
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
}
