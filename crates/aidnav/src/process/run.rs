//! One filter pass over a log under a plan and a measurement policy.

use aidnav_estimation::{EstimationError, Outcome};
use aidnav_frames::{Vec3, earth::Geodetic};
use aidnav_ins::ned::ImuIncrement;
use aidnav_integration::ned::NedFilter;
use aidnav_io::rtklib::GnssFix;
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, NedErrorModel, POSITION, VELOCITY,
    Vector21,
};
use aidnav_supervisors::outage::{BridgeConfig, OutageBridge, Predictor};
use nalgebra::{UnitQuaternion, Vector3};

use super::config::{AdaptiveNoise, BRIDGE_PREDICTORS, Feedback, PolicyName};
use super::{Inputs, ProcessConfig, ProcessError, initialise};

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
    /// Position innovation, antenna estimate minus fix (NED) \[m\] (NaN when withheld).
    pub innovation: Vector3<f64>,
    /// What the update did (None: withheld).
    pub outcome: Option<Outcome>,
    /// The instrument corrections after the epoch.
    pub instruments: aidnav_integration::ned::InstrumentEstimate,
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
    pub(crate) record_index: Option<usize>,
}

impl Epoch {
    /// The navigation part of this epoch as a row at its fix's time.
    pub fn row(&self, gnss: &[GnssFix]) -> SolutionRow {
        SolutionRow {
            time_s: gnss[self.index].time_s,
            antenna: self.antenna,
            velocity: self.velocity,
            attitude: self.attitude,
            sigma: self.sigma,
        }
    }

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

impl SolutionRow {
    /// The filter's navigation solution at `time_s`: antenna position, the
    /// solution's velocity and attitude, position σ.
    fn of(filter: &NedFilter, time_s: f64) -> Self {
        let (antenna, _) = filter.antenna();
        let solution = filter.solution();
        let s = filter.sigmas();
        Self {
            time_s,
            antenna,
            velocity: solution.velocity.raw(),
            attitude: solution.attitude.quaternion(),
            sigma: Vector3::new(s[POSITION], s[POSITION + 1], s[POSITION + 2]),
        }
    }
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
    let mut filter = NedFilter::new(model, state, &sig, Vec3::assume_in_frame(lever))?;
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
                        delta_angle: Vec3::assume_in_frame((w0 + w1) * (0.5 * dt)),
                        delta_velocity: Vec3::assume_in_frame((f0 + f1) * (0.5 * dt)),
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
                        between.push(SolutionRow::of(&filter, t));
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
                        fix = fix.offset_by(&Vec3::assume_in_frame(*o));
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
                        let v = Vec3::assume_in_frame(v);
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
                let row = SolutionRow::of(reporting, g.time_s);
                let bridged = if !bridging {
                    None
                } else if withheld(g.time_s) {
                    bridge.bridged(g.time_s, &row.antenna, &bridge_cfg)
                } else {
                    bridge.record(g.time_s, &(filter.fed_back() - fed_back_before));
                    None
                };
                let sigma_gnss = cfg.efficiency.sigma_gnss_m.unwrap_or_else(|| {
                    g.position_sigma_neu
                        .map(|v| v.max(cfg.gnss.min_position_sigma_m))
                        .norm()
                });
                epochs.push(Epoch {
                    index: next,
                    antenna: row.antenna,
                    velocity: row.velocity,
                    attitude: row.attitude,
                    sigma: row.sigma,
                    nis,
                    innovation,
                    outcome,
                    instruments: *reporting.instruments(),
                    smoothed_antenna: None,
                    convergence,
                    k_eff: aidnav_supervisors::efficiency::EfficiencyCriterion { sigma_gnss }
                        .coefficient(row.sigma.norm()),
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
                (MAX_RECORDED_EPOCHS * aidnav_integration::ned::BYTES_PER_RECORDED_EPOCH) >> 20
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
    fn record(&mut self, t: f64, fed_back: &Vector21) {
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
            out[k] = antenna.offset_by(&Vec3::assume_in_frame(-(dp + active.integral[k])));
        }
        active.last_t = t;
        Some(out)
    }
}

/// Most covariance epochs a smoothing run keeps (≈ 4 GiB; about five hours
/// at the 20 Hz covariance rate plus updates).
pub const MAX_RECORDED_EPOCHS: usize =
    (4 << 30) / aidnav_integration::ned::BYTES_PER_RECORDED_EPOCH;

#[cfg(test)]
mod tests {
    use super::super::config::OutageBridgeConfig;
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
