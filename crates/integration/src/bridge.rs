//! Spec 20's outage bridging around the NED filter: the history of the
//! accumulated GNSS corrections and, in an outage, the antenna position each
//! predictor gives ([`BridgeState`]); [`BridgeObserver`] runs it as an
//! observer of the epoch loop ([`crate::ned_loop`]).

use aidnav_frames::Vec3;
use aidnav_frames::earth::Geodetic;
use aidnav_models::ned_ins::{POSITION, VELOCITY, Vector21};
use aidnav_supervisors::outage::{BridgeConfig, OutageBridge, Predictor};
use nalgebra::Vector3;

use crate::ned::FilterView;
use crate::ned_loop::{EpochObserver, FixRecord};

/// The predictors bridged, in the order of [`BridgeState::bridged`]'s output.
pub const BRIDGE_PREDICTORS: [Predictor; 4] = [
    Predictor::Trend,
    Predictor::CombinedTrend,
    Predictor::Gmdh,
    Predictor::Relay,
];

/// The history of the accumulated GNSS corrections and, in an outage, the
/// predictors built from it.
#[derive(Debug, Default)]
pub struct BridgeState {
    times: Vec<f64>,
    /// Accumulated GNSS correction at each time: position (NED, m),
    /// velocity (NED, m/s).
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
    pub fn record(&mut self, t: f64, fed_back: &Vector21) {
        self.active = None;
        for (c, h) in self.history.iter_mut().enumerate() {
            let i = if c < 3 {
                POSITION + c
            } else {
                VELOCITY + c - 3
            };
            let total = h.last().copied().unwrap_or(0.0);
            h.push(total + fed_back[i]);
        }
        self.times.push(t);
    }

    /// Whether an outage is being bridged.
    pub fn in_outage(&self) -> bool {
        self.active.is_some()
    }

    /// An epoch inside an outage: the antenna position each of
    /// [`BRIDGE_PREDICTORS`] gives (None when the predictors could not be
    /// built).
    pub fn bridged(
        &mut self,
        t: f64,
        antenna: &Geodetic,
        cfg: &BridgeConfig,
    ) -> Option<[Geodetic; 4]> {
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
            out[k] = antenna.offset_by(&Vec3::assume_in_frame(-(dp + active.integral[k])));
        }
        active.last_t = t;
        Some(out)
    }
}

/// The bridge as an observer of the epoch loop: records the corrections of
/// every epoch with GNSS, bridges every withheld one; one entry per fix
/// epoch in [`BridgeObserver::bridged`].
#[derive(Debug)]
pub struct BridgeObserver {
    state: BridgeState,
    cfg: BridgeConfig,
    fed_back_before: Vector21,
    /// Per fix epoch, in loop order: the bridged antenna positions (None
    /// outside outages or when the predictors could not be built).
    pub bridged: Vec<Option<[Geodetic; 4]>>,
}

impl BridgeObserver {
    /// A bridge with an empty history.
    pub fn new(cfg: BridgeConfig) -> Self {
        Self {
            state: BridgeState::default(),
            cfg,
            fed_back_before: Vector21::zeros(),
            bridged: Vec::new(),
        }
    }
}

impl EpochObserver for BridgeObserver {
    fn before_update(&mut self, filter: &dyn FilterView) {
        self.fed_back_before = filter.base_fed_back();
    }

    fn fix(&mut self, filter: &dyn FilterView, record: &FixRecord) {
        let bridged = if record.withheld {
            self.state
                .bridged(record.row.time_s, &record.row.antenna, &self.cfg)
        } else {
            self.state.record(
                record.row.time_s,
                &(filter.base_fed_back() - self.fed_back_before),
            );
            None
        };
        self.bridged.push(bridged);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_estimation::gmdh::GmdhConfig;
    use aidnav_supervisors::outage::RelaySchedule;

    /// A history whose velocity correction grows linearly (the INS kept
    /// needing a = 0.01 m/s² of north correction) is bridged, by the trend,
    /// with the position correction a τ²/2 — exactly, since the line fits
    /// the history exactly and the trapezoid rule is exact for it; the relay
    /// holds (no correction) up to T1, then follows the trend's increment.
    #[test]
    fn bridge_integrates_the_extrapolated_velocity_correction() {
        let cfg = BridgeConfig {
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
            reselect_ratio: None,
        };
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
            let north = |g: &Geodetic| antenna.ned_to(g).x();
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
        assert!(!state.in_outage());
    }
}
