//! Spec 10 (seed 000): a launch vehicle's strapdown INS aided by
//! radio-navigation fixes from 20 s, a 14-state filter estimating the INS
//! errors and eight instrument errors, the Cramér–Rao convergence criterion
//! δ(n) deciding when to correct the instruments, and autonomous flight to
//! t_B. Four cases at t_B, per Table 1 trajectory and threshold:
//!
//! - `free INS`: no fixes at all;
//! - `outputs only`: fixes from 20 s to the switch, position and velocity
//!   corrected, instruments not; autonomous afterwards (the paper's baseline);
//! - `proposed`: as outputs only, plus the instrument outputs corrected with
//!   the filter's estimate x̂_M from the switch on;
//! - `oracle`: instruments corrected with their true errors at the switch;
//! - `Gauss–Newton` (beyond the paper): the same fixes estimated as a batch
//!   with the nonlinear INS (module `gauss_newton`), flown with its estimate.
//!
//! The switch is decided several ways ([`SwitchKind`]): the paper's δ(n) ≤
//! δ_thr taken literally, the same armed by the scenario's `switch`, and
//! from the forecast of the position error at t_B that the filter's
//! covariance gives (see
//! [`ExtendedStateScenario::forecast_instrument_share`]).
//!
//! The INS runs at `imu_dt_s` (RK4, the same scheme as the truth, so an
//! error-free INS reproduces the truth); its position and velocity are reset
//! with the filter's estimate after every fix (closed loop on the navigation
//! states, the instruments untouched), which keeps the linear error model
//! valid. Monte Carlo is over the fix noise (and the error signs when
//! `error_signs = "random"`).

use aidnav_estimation::{EstimationError, FisherInformation, FixedKalmanFilter};
use aidnav_ins::launch::{ESTIMATED, LaunchIns, LaunchInsLanes, LaunchInstrumentErrors};
use aidnav_models::extended_state::{
    ExtendedStateModel, INSTRUMENTS, Matrix14, NAVIGATION, STATES, TransitionForm,
};
use aidnav_supervisors::convergence::{ConvergenceSwitch, SwitchRule, cramer_rao_ratio};
use nalgebra::{SMatrix, SVector, Vector3};
use serde::Serialize;

use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::{RngExt, RunRng, channel_rng, standard_normal};
use aidnav_sim::trajectory::LaunchTrajectory;

mod filter;
mod gauss_newton;
mod scenario;

pub use scenario::*;

use filter::{CovariancePath, Replay, filter_pass, replay, replay_runs};
use gauss_newton::gauss_newton;

/// What the filter pass keeps at a switch.
#[derive(Debug, Clone, Copy)]
struct Snapshot {
    /// Flight time (s).
    time_s: f64,
    /// Index of the fix (0: the first).
    fix: usize,
    ins: LaunchIns,
    estimate: [f64; ESTIMATED],
}

/// Per-epoch record of the filter pass (for the figures).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct FilterHistory {
    /// Flight time of each fix \[s\].
    pub time_s: Vec<f64>,
    /// δ(n).
    pub delta: Vec<f64>,
    /// Estimation error x̂_M − x_M of the 8 instrument errors.
    pub instrument_error: Vec<[f64; INSTRUMENTS]>,
    /// Filter σ of the 8 instrument errors.
    pub instrument_sigma: Vec<[f64; INSTRUMENTS]>,
    /// Cramér–Rao σ of the 8 instrument errors.
    pub instrument_bound: Vec<[f64; INSTRUMENTS]>,
    /// |Δx| of the closed-loop INS after each fix \[m\].
    pub position_error_m: Vec<f64>,
    /// Smallest eigenvalue of P − P_Γ after each fix, in the basis scaled by
    /// P's σ (≥ 0 up to rounding: the bound holds).
    pub bound_gap: Vec<f64>,
    /// The filter's forecast of the 3-D position error at t_B if the
    /// instruments were corrected at this fix (σ, from P carried to t_B by
    /// Φ) \[m\].
    pub forecast_sigma_m: Vec<f64>,
    /// Relative reduction of the forecast's variance achieved by this fix,
    /// per second.
    pub forecast_reduction: Vec<f64>,
    /// The instrument states' share of the forecast's variance.
    pub forecast_share: Vec<f64>,
}

/// How a switch time is decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SwitchKind {
    /// δ(n) ≤ δ_thr, armed by the scenario's `switch` rule.
    DeltaArmed,
    /// The paper's rule taken literally: the first fix with δ(n) ≤ δ_thr.
    DeltaLiteral,
    /// The forecast of the position error at t_B stops improving: its
    /// variance falls by less than the threshold per second of fusion
    /// (after the reduction has once exceeded the threshold, for
    /// `switch.confirm_epochs` fixes in a row).
    Forecast,
    /// The instrument errors' share of the forecast: the part of the
    /// predicted t_B position-error variance that the instrument states'
    /// covariance P_M contributes, over that part plus the navigation
    /// states' (P_H), has fallen to the threshold (for
    /// `switch.confirm_epochs` fixes in a row).
    ForecastShare,
}

impl SwitchKind {
    /// Number written to the CSV's `rule` column.
    pub fn code(self) -> f64 {
        match self {
            SwitchKind::DeltaArmed => 0.0,
            SwitchKind::DeltaLiteral => 1.0,
            SwitchKind::Forecast => 2.0,
            SwitchKind::ForecastShare => 3.0,
        }
    }
}

/// One switch rule with its threshold.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SwitchCase {
    /// The rule.
    pub kind: SwitchKind,
    /// δ_thr for the δ rules; the reduction per second for the forecast.
    pub threshold: f64,
}

/// The switch cases every trajectory is run with: the armed δ rule per
/// threshold, then (if `literal_rule`) the literal one per threshold, then
/// the forecast rule per `forecast_reduction_per_s`, then the share rule
/// per `forecast_instrument_share`.
pub fn switch_cases(sc: &ExtendedStateScenario) -> Vec<SwitchCase> {
    let delta = |kind| {
        sc.thresholds
            .iter()
            .map(move |&threshold| SwitchCase { kind, threshold })
    };
    let mut cases: Vec<SwitchCase> = delta(SwitchKind::DeltaArmed).collect();
    if sc.literal_rule {
        cases.extend(delta(SwitchKind::DeltaLiteral));
    }
    cases.extend(
        sc.forecast_reduction_per_s
            .iter()
            .map(|&threshold| SwitchCase {
                kind: SwitchKind::Forecast,
                threshold,
            }),
    );
    cases.extend(
        sc.forecast_instrument_share
            .iter()
            .map(|&threshold| SwitchCase {
                kind: SwitchKind::ForecastShare,
                threshold,
            }),
    );
    cases
}

/// One run's numbers for one threshold.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, Serialize)]
struct ThresholdRun {
    switch_time_s: f64,
    outputs_only_m: f64,
    proposed_m: f64,
    oracle_m: f64,
    /// The Gauss–Newton estimate's |Δx(t_B)| (NaN: not computed).
    gauss_newton_m: f64,
    /// The Cramér–Rao bound's variance of the 3-D position error at t_B
    /// for a switch at this fix \[m²\].
    bound_variance: f64,
}

/// Result per (trajectory, threshold), medians over runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaseResult {
    /// t_B \[s\].
    pub t_b_s: f64,
    /// Course \[deg\].
    pub course_deg: f64,
    /// The switch rule.
    pub rule: SwitchKind,
    /// The rule's threshold: δ_thr for the δ rules, the reduction of the
    /// forecast variance per second for `forecast`.
    pub delta_threshold: f64,
    /// Switch time (flight time) \[s\], median.
    pub switch_time_s: f64,
    /// Switch time, 10 % and 90 % quantiles \[s\].
    pub switch_time_p10_p90_s: [f64; 2],
    /// Runs in which the switch never fired (these use t_B as switch time).
    pub never_switched: usize,
    /// |Δx(t_B)| of the free INS \[m\], median.
    pub error_free_ins_m: f64,
    /// Outputs only \[m\], median.
    pub error_outputs_only_m: f64,
    /// Proposed \[m\], median.
    pub error_proposed_m: f64,
    /// Oracle \[m\], median.
    pub error_oracle_m: f64,
    /// Gauss–Newton \[m\], median over the runs that computed it.
    pub error_gauss_newton_m: f64,
    /// Runs that computed the Gauss–Newton estimate.
    pub gauss_newton_runs: usize,
    /// RMS over runs of |Δx(t_B)|: proposed, Gauss–Newton, oracle \[m\].
    pub rms_proposed_gauss_newton_oracle_m: [f64; 3],
    /// The Cramér–Rao bound on that RMS for a switch at the case's switch
    /// fix: √(mean over runs of tr of the position block of
    /// Φ(t_B, t_s) P_Γ Φ(t_B, t_s)ᵀ) \[m\].
    pub bound_sigma_m: f64,
    /// Ratio outputs-only / proposed, median over runs.
    pub ratio_median: f64,
    /// 10 % quantile of the ratio.
    pub ratio_p10: f64,
    /// 90 % quantile of the ratio.
    pub ratio_p90: f64,
}

/// The forced-switch sweep of the figure trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepPoint {
    /// Forced switch time (flight time) \[s\].
    pub switch_time_s: f64,
    /// Ratio outputs-only / proposed: median, p10, p90.
    pub ratio: [f64; 3],
}

/// Everything the experiment produces.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExtendedStateResult {
    /// One per trajectory × threshold.
    pub cases: Vec<CaseResult>,
    /// Filter history of run 0 on the figure trajectory.
    pub history: FilterHistory,
    /// |Δx(t)| on the figure trajectory, run 0: time and, per threshold,
    /// (proposed, outputs only); and the free INS.
    pub error_time_s: Vec<f64>,
    /// Per threshold: |Δx(t)| proposed, run 0 \[m\].
    pub error_proposed: Vec<Vec<f64>>,
    /// Per threshold: |Δx(t)| outputs only, run 0 \[m\].
    pub error_outputs_only: Vec<Vec<f64>>,
    /// |Δx(t)| of the free INS, run 0 \[m\].
    pub error_free: Vec<f64>,
    /// Forced-switch sweep on the figure trajectory.
    pub sweep: Vec<SweepPoint>,
}

/// The truth's instrument errors when every run has the same (None: drawn
/// per run).
fn fixed_errors(sc: &ExtendedStateScenario) -> Option<LaunchInstrumentErrors> {
    match sc.error_signs {
        ErrorSigns::Positive => Some(sc.error_magnitudes.errors(&[1.0; 12])),
        ErrorSigns::Random => None,
    }
}

/// The truth's instrument errors for one run.
fn true_errors(sc: &ExtendedStateScenario, rng: &mut RunRng) -> LaunchInstrumentErrors {
    match sc.error_signs {
        ErrorSigns::Positive => sc.error_magnitudes.errors(&[1.0; 12]),
        ErrorSigns::Random => {
            let mut signs = [1.0; 12];
            for s in &mut signs {
                *s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            }
            sc.error_magnitudes.errors(&signs)
        }
    }
}

/// The instruments' raw outputs at flight time t.
fn raw_outputs(
    traj: &LaunchTrajectory,
    errors: &LaunchInstrumentErrors,
    t: f64,
) -> (aidnav_frames::launch::LaunchAttitude, Vector3<f64>) {
    errors.measure(
        t,
        &traj.attitude(t),
        &Vector3::new(traj.specific_force(t), 0.0, 0.0),
    )
}

/// How an INS flight corrects its instruments.
#[derive(Debug, Clone, Copy)]
enum Correction<'a> {
    /// Not at all: the raw outputs.
    None,
    /// With the true errors (the oracle).
    Truth,
    /// With a run's estimate.
    Estimate(&'a LaunchInstrumentErrors),
}

/// One INS of [`Flight::fly_lanes`]: its correction, its state at the
/// start and the step index it starts at.
#[derive(Debug, Clone, Copy)]
struct Lane<'a> {
    correction: Correction<'a>,
    start: LaunchIns,
    from: usize,
}

/// The raw instrument outputs at the three RK4 times of one step.
type StepOutputs = [(aidnav_frames::launch::LaunchAttitude, Vector3<f64>); 3];

/// One trajectory with one set of true instrument errors, and what every
/// INS flown on them shares: the raw instrument outputs at the three RK4
/// times of every step, and the thrust `Dᵀ f` there from the raw outputs
/// and from the outputs corrected with the true errors. None of it depends
/// on the INS state, so a run's filter pass and flights read them instead
/// of evaluating the trajectory and the error model again (with fixed
/// error signs, one `Flight` per trajectory serves every run); a flight
/// corrected with a run's estimate corrects the stored outputs. The same
/// arithmetic as [`LaunchIns::step`] on [`raw_outputs`], so the same
/// numbers.
struct Flight<'a> {
    traj: &'a LaunchTrajectory,
    errors: LaunchInstrumentErrors,
    outputs: Vec<StepOutputs>,
    raw: Vec<[Vector3<f64>; 3]>,
    truth_corrected: Vec<[Vector3<f64>; 3]>,
    /// (sine, cosine) of the raw roll output at the three RK4 times of
    /// every step. The filter estimates no roll error, so a flight
    /// corrected with an estimate flies the raw roll: its sine and cosine
    /// are these, not computed again at every step.
    roll_sin_cos: Vec<[(f64, f64); 3]>,
    /// Whether step k starts at step k − 1's last RK4 time bit for bit
    /// (`k dt` and `(k − 1) dt + dt` differ by rounding at about a quarter
    /// of the steps): then both have the same outputs, so any correction
    /// gives both the same thrust, and a flight computes it once.
    continues: Vec<bool>,
}

impl<'a> Flight<'a> {
    fn new(traj: &'a LaunchTrajectory, errors: LaunchInstrumentErrors) -> Self {
        let dt = traj.dt_s;
        let outputs: Vec<StepOutputs> = (0..traj.samples() - 1)
            .map(|k| Self::times(k, dt).map(|tau| raw_outputs(traj, &errors, tau)))
            .collect();
        let roll_sin_cos = outputs
            .iter()
            .map(|step| step.map(|(att, _)| att.roll.sin_cos()))
            .collect();
        let continues = (0..outputs.len())
            .map(|k| {
                k > 0 && Self::times(k, dt)[0].to_bits() == Self::times(k - 1, dt)[2].to_bits()
            })
            .collect();
        let mut flight = Self {
            traj,
            errors,
            outputs,
            raw: Vec::new(),
            truth_corrected: Vec::new(),
            roll_sin_cos,
            continues,
        };
        let n = flight.outputs.len();
        flight.raw = (0..n)
            .map(|k| flight.live_thrust(Correction::None, k))
            .collect();
        flight.truth_corrected = (0..n)
            .map(|k| flight.live_thrust(Correction::Truth, k))
            .collect();
        flight
    }

    /// The RK4 times of step k, as [`LaunchIns::step_thrust`] computes them.
    fn times(k: usize, dt: f64) -> [f64; 3] {
        let t = k as f64 * dt;
        [t, t + dt / 2.0, t + dt]
    }

    /// The thrust of step k (from k dt to (k + 1) dt) from the stored
    /// outputs, corrected as given.
    fn live_thrust(&self, correction: Correction<'_>, k: usize) -> [Vector3<f64>; 3] {
        let times = Self::times(k, self.traj.dt_s);
        std::array::from_fn(|i| {
            let (att, f) = &self.outputs[k][i];
            let tau = times[i];
            let (att, f) = match correction {
                Correction::None => (*att, *f),
                Correction::Truth => self.errors.correct(tau, att, f),
                Correction::Estimate(c) => return self.estimate_thrust(c, k, i, tau),
            };
            LaunchIns::thrust(&att, &f)
        })
    }

    /// The thrust at RK4 time i (`tau`) of step k corrected with an
    /// estimate: [`LaunchIns::thrust`] of the corrected outputs, with the
    /// stored sine and cosine of the roll when the correction leaves the
    /// roll as it is (always for an 8-state estimate, whose roll errors are
    /// zero: `γ − (0 + 0 t) = γ`), so the same matrix and thrust.
    fn estimate_thrust(
        &self,
        correction: &LaunchInstrumentErrors,
        k: usize,
        i: usize,
        tau: f64,
    ) -> Vector3<f64> {
        let (raw_att, raw_f) = &self.outputs[k][i];
        let (att, f) = correction.correct(tau, raw_att, raw_f);
        let roll = if att.roll.to_bits() == raw_att.roll.to_bits() {
            self.roll_sin_cos[k][i]
        } else {
            att.roll.sin_cos()
        };
        let d = aidnav_frames::launch::LaunchAttitude::orientation_from_sin_cos(
            att.yaw.sin_cos(),
            att.pitch.sin_cos(),
            roll,
        );
        d.transpose() * f
    }

    /// Fly every lane's INS from its `start` (at step index `from`) to t_B
    /// with its correction, all together ([`LaunchInsLanes`]: per INS the
    /// same numbers as [`fly`](Self::fly)); a lane joins the others at its
    /// `from`. Returns each |Δx(t_B)|, in the lanes' order.
    fn fly_lanes(&self, lanes: &[Lane<'_>]) -> Vec<f64> {
        let traj = self.traj;
        let dt = traj.dt_s;
        let last = traj.samples() - 1;
        // Joining order: by start step (stable, so ties keep their order).
        let mut order: Vec<usize> = (0..lanes.len()).collect();
        order.sort_by_key(|&i| lanes[i].from);
        let mut flying = LaunchInsLanes::with_capacity(lanes.len());
        let mut live: Vec<Option<EstimateThrust<'_, '_>>> = Vec::with_capacity(lanes.len());
        let first = order.first().map_or(last, |&i| lanes[i].from);
        for k in first..last {
            while let Some(&i) = order.get(flying.len()) {
                if lanes[i].from != k {
                    break;
                }
                flying.push(lanes[i].start);
                live.push(match lanes[i].correction {
                    Correction::Estimate(c) => Some(EstimateThrust::new(self, c)),
                    _ => None,
                });
            }
            for (j, l) in live.iter_mut().enumerate() {
                match (lanes[order[j]].correction, l) {
                    (Correction::Estimate(_), Some(l)) => flying.set_thrust(j, &l.at(k)),
                    (Correction::Truth, _) => flying.set_thrust(j, &self.truth_corrected[k]),
                    _ => flying.set_thrust(j, &self.raw[k]),
                }
            }
            flying.step(dt);
        }
        let mut out = vec![f64::NAN; lanes.len()];
        for (j, &i) in order.iter().enumerate() {
            // A lane starting at t_B (or later) does not fly.
            let ins = if j < flying.len() {
                flying.get(j)
            } else {
                lanes[i].start
            };
            out[i] = (ins.position - traj.positions[last]).norm();
        }
        out
    }

    /// Fly the INS autonomously from `start` (at step index `from`) to t_B
    /// with the instruments corrected as given; calls `each_step(k, &ins)`
    /// after every step. Returns |Δx(t_B)|.
    fn fly(
        &self,
        correction: Correction<'_>,
        start: LaunchIns,
        from: usize,
        mut each_step: impl FnMut(usize, &LaunchIns),
    ) -> f64 {
        let traj = self.traj;
        let dt = traj.dt_s;
        let mut ins = start;
        let last = traj.samples() - 1;
        let mut live = match correction {
            Correction::Estimate(c) => Some(EstimateThrust::new(self, c)),
            _ => None,
        };
        for k in from..last {
            match (correction, &mut live) {
                (Correction::Estimate(_), Some(live)) => ins.step_with_thrust(dt, &live.at(k)),
                (Correction::Truth, _) => ins.step_with_thrust(dt, &self.truth_corrected[k]),
                _ => ins.step_with_thrust(dt, &self.raw[k]),
            }
            each_step(k + 1, &ins);
        }
        (ins.position - traj.positions[last]).norm()
    }
}

/// The thrust of a flight corrected with an estimate, step after step
/// ([`Flight::live_thrust`] of `Correction::Estimate`): the last RK4
/// time's thrust is kept and used again as the next step's first when
/// that step [continues](Flight) it, so the same numbers with about a
/// quarter fewer evaluations.
struct EstimateThrust<'f, 'a> {
    flight: &'f Flight<'a>,
    correction: &'f LaunchInstrumentErrors,
    /// The step whose thrust was computed last, and that thrust.
    last: Option<(usize, [Vector3<f64>; 3])>,
}

impl<'f, 'a> EstimateThrust<'f, 'a> {
    fn new(flight: &'f Flight<'a>, correction: &'f LaunchInstrumentErrors) -> Self {
        Self {
            flight,
            correction,
            last: None,
        }
    }

    /// The thrust of step k.
    fn at(&mut self, k: usize) -> [Vector3<f64>; 3] {
        let flight = self.flight;
        let times = Flight::times(k, flight.traj.dt_s);
        let first = match self.last {
            Some((j, thrust)) if j + 1 == k && flight.continues[k] => thrust[2],
            _ => flight.estimate_thrust(self.correction, k, 0, times[0]),
        };
        let thrust = [
            first,
            flight.estimate_thrust(self.correction, k, 1, times[1]),
            flight.estimate_thrust(self.correction, k, 2, times[2]),
        ];
        self.last = Some((k, thrust));
        thrust
    }
}

/// Ratio and errors of the three switched cases from each snapshot: the
/// outputs-only, proposed and oracle flights from its switch, every INS of
/// every snapshot flown together ([`Flight::fly_lanes`]).
fn branches_of(flight: &Flight<'_>, snapshots: &[&Snapshot]) -> Vec<ThresholdRun> {
    let from = |s: &Snapshot| (s.time_s / flight.traj.dt_s).round() as usize;
    let estimated: Vec<LaunchInstrumentErrors> = snapshots
        .iter()
        .map(|s| LaunchInstrumentErrors::from_estimate(&s.estimate))
        .collect();
    // Per snapshot: outputs only, oracle, then proposed (unless the
    // estimate is zero — the literal rule's switch at the first fix, where
    // P_HM = 0 leaves x̂_M at 0 — which corrects nothing: the outputs-only
    // flight, bit for bit ((f − 0)/(1 + 0) = f, b − 0 − 0·t = b)).
    let mut lanes = Vec::with_capacity(3 * snapshots.len());
    // Per snapshot, its outputs-only lane (the oracle's is the next) and
    // its proposed lane.
    let mut per_snapshot = Vec::with_capacity(snapshots.len());
    for (s, e) in snapshots.iter().zip(&estimated) {
        let lane = |correction| Lane {
            correction,
            start: s.ins,
            from: from(s),
        };
        let outputs_only = lanes.len();
        lanes.push(lane(Correction::None));
        lanes.push(lane(Correction::Truth));
        let proposed = if s.estimate == [0.0; ESTIMATED] {
            outputs_only
        } else {
            lanes.push(lane(Correction::Estimate(e)));
            lanes.len() - 1
        };
        per_snapshot.push((outputs_only, proposed));
    }
    let errors = flight.fly_lanes(&lanes);
    snapshots
        .iter()
        .zip(per_snapshot)
        .map(|(s, (outputs_only, proposed))| ThresholdRun {
            switch_time_s: s.time_s,
            outputs_only_m: errors[outputs_only],
            proposed_m: errors[proposed],
            oracle_m: errors[outputs_only + 1],
            gauss_newton_m: f64::NAN,
            bound_variance: f64::NAN,
        })
        .collect()
}

/// The outputs-only / proposed ratio from each snapshot (the sweep's: no
/// oracle flight; None: NaN), every INS flown together; the same numbers as
/// [`branches_of`]' ratio.
fn branch_ratios(flight: &Flight<'_>, snapshots: &[Option<Snapshot>]) -> Vec<f64> {
    let estimated: Vec<Option<LaunchInstrumentErrors>> = snapshots
        .iter()
        .map(|s| {
            s.filter(|s| s.estimate != [0.0; ESTIMATED])
                .map(|s| LaunchInstrumentErrors::from_estimate(&s.estimate))
        })
        .collect();
    let mut lanes = Vec::with_capacity(2 * snapshots.len());
    // Per snapshot, its outputs-only lane and its proposed lane.
    let mut pairs = Vec::with_capacity(snapshots.len());
    for (s, e) in snapshots.iter().zip(&estimated) {
        let Some(s) = s else {
            pairs.push(None);
            continue;
        };
        let from = (s.time_s / flight.traj.dt_s).round() as usize;
        let outputs_only = lanes.len();
        lanes.push(Lane {
            correction: Correction::None,
            start: s.ins,
            from,
        });
        // A zero estimate: proposed is the outputs-only flight (see
        // `branches_of`), the same division, so NaN, not 1, for an error
        // of 0 or ∞.
        let proposed = match e {
            Some(e) => {
                lanes.push(Lane {
                    correction: Correction::Estimate(e),
                    start: s.ins,
                    from,
                });
                outputs_only + 1
            }
            None => outputs_only,
        };
        pairs.push(Some((outputs_only, proposed)));
    }
    let errors = flight.fly_lanes(&lanes);
    pairs
        .iter()
        .map(|p| p.map_or(f64::NAN, |(o, p)| errors[o] / errors[p]))
        .collect()
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = v.fold((0.0, 0usize), |(s, c), x| (s + x * x, c + 1));
    (sum / count as f64).sqrt()
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

fn sorted(mut v: Vec<f64>) -> Vec<f64> {
    v.sort_by(f64::total_cmp);
    v
}

/// Solve every target's trajectory.
pub fn trajectories(
    sc: &ExtendedStateScenario,
) -> Result<Vec<LaunchTrajectory>, ExtendedStateError> {
    sc.targets
        .iter()
        .map(|t| {
            LaunchTrajectory::solve(t, &sc.program, sc.imu_dt_s).map_err(|reason| {
                ExtendedStateError::Trajectory {
                    t_b_s: t.t_b_s,
                    course_deg: t.course_deg,
                    reason,
                }
            })
        })
        .collect()
}

/// One run on one trajectory: the free INS's error and, per threshold,
/// the run's numbers and whether it never switched.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, Serialize)]
pub struct RunRecord {
    free: f64,
    thresholds: Vec<(ThresholdRun, bool)>,
}

/// The runs of a range of the campaign, per trajectory.
#[derive(Debug, Clone, PartialEq, Default, serde::Deserialize, Serialize)]
pub struct ExtendedStateRuns {
    trajectories: Vec<Vec<RunRecord>>,
}

impl crate::Chunk for ExtendedStateRuns {
    fn runs(&self) -> usize {
        self.trajectories.first().map_or(0, Vec::len)
    }

    fn append(&mut self, other: Self) {
        if self.trajectories.is_empty() {
            *self = other;
            return;
        }
        for (mine, theirs) in self.trajectories.iter_mut().zip(other.trajectories) {
            mine.extend(theirs);
        }
    }
}

/// Run the experiment: [`finish`] of every run ([`run_range`] over
/// `0..mc.runs`).
pub fn run(
    sc: &ExtendedStateScenario,
    mc: &MonteCarlo,
) -> Result<ExtendedStateResult, ExtendedStateError> {
    // The trajectories solved once for both.
    let trajs = trajectories(sc)?;
    let runs = runs_on(sc, mc, 0..mc.runs, &trajs)?;
    finish_on(sc, runs, &trajs)
}

/// Runs `range` on every trajectory (run k's streams depend on k alone):
/// a chunk for [`finish`] to combine with the others, computed anywhere.
pub fn run_range(
    sc: &ExtendedStateScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<ExtendedStateRuns, ExtendedStateError> {
    runs_on(sc, mc, range, &trajectories(sc)?)
}

/// Runs a worker thread takes together when they share one [`Flight`]
/// (fixed error signs): their filter replays and their branches' INS are
/// flown together ([`replay_runs`], [`Flight::fly_lanes`]), so more INS
/// overlap; few enough that the batches still spread over the threads.
const RUN_BATCH: usize = 4;

/// [`run_range`] on the scenario's solved trajectories.
fn runs_on(
    sc: &ExtendedStateScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
    trajs: &[LaunchTrajectory],
) -> Result<ExtendedStateRuns, ExtendedStateError> {
    let mut trajectories = Vec::with_capacity(trajs.len());
    // With fixed error signs every run flies the same errors: their
    // preparation is made once per trajectory, and runs go in batches. That
    // preparation is serial, so the next trajectory's is made while this
    // one's runs fly (rayon::join: on another thread when one is idle).
    let fixed = fixed_errors(sc);
    let mut next = match (fixed, trajs.first()) {
        (Some(e), Some(traj)) if !range.is_empty() => Some(Prepared::new(sc, traj, e)),
        _ => None,
    };
    for (ti, traj) in trajs.iter().enumerate() {
        let per_run = match (fixed, next.take()) {
            (Some(e), Some(prepared)) => {
                let shared = prepared.shared(sc, ti);
                let (per_run, following) = rayon::join(
                    || mc.try_run_batches(range.clone(), RUN_BATCH, |runs| shared.runs(runs)),
                    || trajs.get(ti + 1).map(|t| Prepared::new(sc, t, e)),
                );
                next = following;
                per_run?
            }
            (Some(_), None) => Vec::new(),
            (None, _) => mc.try_run_range(range.clone(), |run, _| {
                let mut rng = channel_rng(sc.seed, run as u64, ti as u64);
                let prepared = Prepared::new(sc, traj, true_errors(sc, &mut rng));
                let shared = prepared.shared(sc, ti);
                let replayed = replay(sc, &prepared.flight, &prepared.path, &mut rng, &[])?;
                shared
                    .finish_runs(&[run], &[replayed])
                    .pop()
                    .expect("one run")
            })?,
        };
        trajectories.push(per_run);
    }
    Ok(ExtendedStateRuns { trajectories })
}

/// What every run on one trajectory with one set of true errors needs
/// before it flies: the thrust tables, the free INS's |Δx(t_B)| and the
/// filter's covariance path.
struct Prepared<'a> {
    flight: Flight<'a>,
    free: f64,
    path: CovariancePath,
}

impl<'a> Prepared<'a> {
    fn new(
        sc: &ExtendedStateScenario,
        traj: &'a LaunchTrajectory,
        errors: LaunchInstrumentErrors,
    ) -> Self {
        let flight = Flight::new(traj, errors);
        let free = flight.fly(Correction::None, LaunchIns::default(), 0, |_, _| {});
        let path = CovariancePath::new(sc, &flight);
        Self { flight, free, path }
    }

    /// The runs' view of it on trajectory `ti`.
    fn shared<'s>(&'s self, sc: &'s ExtendedStateScenario, ti: usize) -> Shared<'s, 'a> {
        Shared {
            sc,
            ti,
            flight: &self.flight,
            free: self.free,
            path: &self.path,
        }
    }
}

/// What the runs on one trajectory with one set of true errors share.
struct Shared<'s, 'a> {
    sc: &'s ExtendedStateScenario,
    /// Index of the trajectory (its channel of the runs' streams).
    ti: usize,
    flight: &'s Flight<'a>,
    /// The free INS's |Δx(t_B)|.
    free: f64,
    path: &'s CovariancePath,
}

impl Shared<'_, '_> {
    /// Runs `runs` on the shared flight, replayed and flown together; if a
    /// replay fails, each run again alone, so that each run gets its own
    /// result or error.
    fn runs(&self, runs: std::ops::Range<usize>) -> Vec<Result<RunRecord, EstimationError>> {
        let stream = |run: usize| channel_rng(self.sc.seed, run as u64, self.ti as u64);
        let mut rngs: Vec<RunRng> = runs.clone().map(stream).collect();
        let run_list: Vec<usize> = runs.collect();
        match replay_runs(self.sc, self.flight, self.path, &mut rngs, &[]) {
            Ok(replayed) => self.finish_runs(&run_list, &replayed),
            Err(_) => run_list
                .iter()
                .map(|&run| {
                    let replayed = replay(self.sc, self.flight, self.path, &mut stream(run), &[])?;
                    self.finish_runs(&[run], &[replayed])
                        .pop()
                        .expect("one run")
                })
                .collect(),
        }
    }

    /// The runs' records from their replays: per switch case the branches
    /// from its snapshot (every run's flown together) and, in the first
    /// `gauss_newton_runs` runs, the Gauss–Newton estimate.
    fn finish_runs(
        &self,
        runs: &[usize],
        replayed: &[Replay],
    ) -> Vec<Result<RunRecord, EstimationError>> {
        let sc = self.sc;
        let gauss_newton_runs = sc.gauss_newton_runs.min(sc.runs);
        let t_b = self.flight.traj.target.t_b_s;
        // Cases switching at the same fix (the literal rule's thresholds)
        // share one snapshot, so one result: per run and case, the first
        // case with its switch.
        let same: Vec<Vec<Option<usize>>> = replayed
            .iter()
            .map(|r| {
                r.at_switch
                    .iter()
                    .enumerate()
                    .map(|(k, s)| {
                        r.at_switch[..k]
                            .iter()
                            .position(|p| p.is_some_and(|p| s.is_some_and(|s| p.fix == s.fix)))
                    })
                    .collect()
            })
            .collect();
        let flown: Vec<&Snapshot> = replayed
            .iter()
            .zip(&same)
            .flat_map(|(r, same)| {
                r.at_switch
                    .iter()
                    .zip(same)
                    .filter_map(|(s, same)| s.as_ref().filter(|_| same.is_none()))
            })
            .collect();
        let mut flown = branches_of(self.flight, &flown).into_iter();
        // Each run's share of the flights, taken before any run can stop
        // at an error.
        let flown: Vec<Vec<ThresholdRun>> = replayed
            .iter()
            .zip(&same)
            .map(|(r, same)| {
                let count = r
                    .at_switch
                    .iter()
                    .zip(same)
                    .filter(|(s, same)| s.is_some() && same.is_none())
                    .count();
                flown.by_ref().take(count).collect()
            })
            .collect();
        runs.iter()
            .zip(replayed)
            .zip(&same)
            .zip(flown)
            .map(|(((&run, replayed), same), flown)| {
                let mut flown = flown.into_iter();
                let mut out: Vec<(ThresholdRun, bool)> = Vec::with_capacity(same.len());
                for (s, same) in replayed.at_switch.iter().zip(same) {
                    if let Some(j) = *same {
                        out.push(out[j]);
                        continue;
                    }
                    out.push(match s {
                        Some(s) => {
                            let mut b = flown.next().expect("one flight per distinct switch");
                            b.bound_variance = self.path.bound_variance[s.fix];
                            // At the first fix the batch has nothing to add.
                            if run < gauss_newton_runs && s.fix > 0 {
                                b.gauss_newton_m = gauss_newton(
                                    sc,
                                    self.flight,
                                    &replayed.ins_at_first_fix,
                                    &replayed.fixes[..=s.fix],
                                    &s.estimate,
                                    sc.gauss_newton_iterations,
                                    false,
                                )?
                                .error_m;
                            }
                            (b, false)
                        }
                        None => (
                            ThresholdRun {
                                switch_time_s: t_b,
                                outputs_only_m: f64::NAN,
                                proposed_m: f64::NAN,
                                oracle_m: f64::NAN,
                                gauss_newton_m: f64::NAN,
                                bound_variance: f64::NAN,
                            },
                            true,
                        ),
                    });
                }
                Ok(RunRecord {
                    free: self.free,
                    thresholds: out,
                })
            })
            .collect()
    }
}

/// The result from every run, in run order (the chunks of [`run_range`]
/// joined), with run 0's figures and the forced-switch sweep: the same
/// numbers, bit for bit, as [`run`].
pub fn finish(
    sc: &ExtendedStateScenario,
    runs: ExtendedStateRuns,
) -> Result<ExtendedStateResult, ExtendedStateError> {
    finish_on(sc, runs, &trajectories(sc)?)
}

/// [`finish`] on the scenario's solved trajectories.
fn finish_on(
    sc: &ExtendedStateScenario,
    runs: ExtendedStateRuns,
    trajs: &[LaunchTrajectory],
) -> Result<ExtendedStateResult, ExtendedStateError> {
    let switch_cases = switch_cases(sc);
    let mut cases = Vec::new();
    for (traj, per_run) in trajs.iter().zip(&runs.trajectories) {
        let free = sorted(per_run.iter().map(|r| r.free).collect());
        for (k, case) in switch_cases.iter().enumerate() {
            let runs: Vec<ThresholdRun> = per_run.iter().map(|r| r.thresholds[k].0).collect();
            let never = per_run.iter().filter(|r| r.thresholds[k].1).count();
            let ok: Vec<&ThresholdRun> = runs.iter().filter(|r| r.proposed_m.is_finite()).collect();
            let pick = |f: fn(&ThresholdRun) -> f64| sorted(ok.iter().map(|r| f(r)).collect());
            let ratio = pick(|r| r.outputs_only_m / r.proposed_m);
            let switch = sorted(runs.iter().map(|r| r.switch_time_s).collect());
            let gauss: Vec<f64> = ok
                .iter()
                .map(|r| r.gauss_newton_m)
                .filter(|e| e.is_finite())
                .collect();
            let bound_variance = ok.iter().map(|r| r.bound_variance).sum::<f64>() / ok.len() as f64;
            cases.push(CaseResult {
                t_b_s: traj.target.t_b_s,
                course_deg: traj.target.course_deg,
                rule: case.kind,
                delta_threshold: case.threshold,
                switch_time_s: quantile(&switch, 0.5),
                switch_time_p10_p90_s: [quantile(&switch, 0.1), quantile(&switch, 0.9)],
                never_switched: never,
                error_free_ins_m: quantile(&free, 0.5),
                error_outputs_only_m: quantile(&pick(|r| r.outputs_only_m), 0.5),
                error_proposed_m: quantile(&pick(|r| r.proposed_m), 0.5),
                error_oracle_m: quantile(&pick(|r| r.oracle_m), 0.5),
                error_gauss_newton_m: quantile(&sorted(gauss.clone()), 0.5),
                gauss_newton_runs: gauss.len(),
                rms_proposed_gauss_newton_oracle_m: [
                    rms(ok.iter().map(|r| r.proposed_m)),
                    rms(gauss.iter().copied()),
                    rms(ok.iter().map(|r| r.oracle_m)),
                ],
                bound_sigma_m: bound_variance.sqrt(),
                ratio_median: quantile(&ratio, 0.5),
                ratio_p10: quantile(&ratio, 0.1),
                ratio_p90: quantile(&ratio, 0.9),
            });
        }
    }
    let figure = figures(sc, &trajs[sc.figure_target])?;
    Ok(ExtendedStateResult { cases, ..figure })
}

/// Run 0's history and error curves, and the forced-switch sweep, on one trajectory.
fn figures(
    sc: &ExtendedStateScenario,
    traj: &LaunchTrajectory,
) -> Result<ExtendedStateResult, ExtendedStateError> {
    let ti = sc.figure_target as u64;
    let mut rng = channel_rng(sc.seed, 0, ti);
    let flight = Flight::new(traj, true_errors(sc, &mut rng));
    let path = CovariancePath::new(sc, &flight);
    let mut history = FilterHistory::default();
    let (switches, _) = filter_pass(sc, &flight, &path, &mut rng, &[], Some(&mut history))?;
    // |Δx(t)| every second: before the switch the closed-loop INS (run again
    // to record it), after it the autonomous branches.
    let stride = (1.0 / traj.dt_s).round().max(1.0) as usize;
    let last = traj.samples() - 1;
    let error_time_s: Vec<f64> = (0..=last)
        .step_by(stride)
        .map(|k| k as f64 * traj.dt_s)
        .collect();
    let record = |v: &mut Vec<f64>, k: usize, ins: &LaunchIns| {
        if k.is_multiple_of(stride) {
            v.push((ins.position - traj.positions[k]).norm());
        }
    };
    let mut error_free = vec![0.0];
    flight.fly(Correction::None, LaunchIns::default(), 0, |k, ins| {
        record(&mut error_free, k, ins)
    });
    // Before its switch each curve is the closed-loop INS (in `history`).
    let mut error_proposed = Vec::new();
    let mut error_outputs_only = Vec::new();
    for s in &switches {
        let mut proposed = Vec::new();
        let mut outputs = Vec::new();
        if let Some(s) = s {
            let from = (s.time_s / traj.dt_s).round() as usize;
            let before: Vec<f64> = error_time_s
                .iter()
                .take_while(|&&t| t < s.time_s)
                .map(|_| f64::NAN)
                .collect();
            proposed.extend(before.iter().copied());
            outputs.extend(before.iter().copied());
            let estimated = LaunchInstrumentErrors::from_estimate(&s.estimate);
            let mut p = Vec::new();
            flight.fly(Correction::Estimate(&estimated), s.ins, from, |k, ins| {
                record(&mut p, k, ins)
            });
            let mut o = Vec::new();
            flight.fly(Correction::None, s.ins, from, |k, ins| {
                record(&mut o, k, ins)
            });
            proposed.extend(p);
            outputs.extend(o);
        }
        proposed.resize(error_time_s.len(), f64::NAN);
        outputs.resize(error_time_s.len(), f64::NAN);
        error_proposed.push(proposed);
        error_outputs_only.push(outputs);
    }
    let sweep = forced_switch_sweep(sc, traj, ti)?;
    Ok(ExtendedStateResult {
        cases: Vec::new(),
        history,
        error_time_s,
        error_proposed,
        error_outputs_only,
        error_free,
        sweep,
    })
}

/// The forced-switch sweep: the outputs-only / proposed error ratio (median,
/// 10 % and 90 % over `sweep_runs`) for switch times every `sweep_step_s`
/// from the fusion start to t_B on trajectory `ti`.
fn forced_switch_sweep(
    sc: &ExtendedStateScenario,
    traj: &LaunchTrajectory,
    ti: u64,
) -> Result<Vec<SweepPoint>, ExtendedStateError> {
    let t_b = traj.target.t_b_s;
    let mut forced = Vec::new();
    let mut t = sc.fusion_start_s + sc.sweep_step_s;
    while t < t_b - 1.0 {
        forced.push(t);
        t += sc.sweep_step_s;
    }
    let sweep_mc = MonteCarlo::new(sc.sweep_runs, sc.seed).quiet();
    let fixed = fixed_errors(sc).map(|e| {
        let flight = Flight::new(traj, e);
        let path = CovariancePath::new(sc, &flight);
        (flight, path)
    });
    let sweep_runs = sweep_mc.try_run(|run, _| {
        let mut rng = channel_rng(sc.seed, run as u64, 1000 + ti);
        let (own, own_path);
        let (flight, path) = match &fixed {
            Some((flight, path)) => (flight, path),
            None => {
                own = Flight::new(traj, true_errors(sc, &mut rng));
                own_path = CovariancePath::new(sc, &own);
                (&own, &own_path)
            }
        };
        let at = replay(sc, flight, path, &mut rng, &forced)?.at_forced;
        Ok::<_, EstimationError>(branch_ratios(flight, &at))
    })?;
    Ok(forced
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let v = sorted(
                sweep_runs
                    .iter()
                    .map(|r| r[i])
                    .filter(|x| x.is_finite())
                    .collect(),
            );
            SweepPoint {
                switch_time_s: t,
                ratio: [quantile(&v, 0.5), quantile(&v, 0.1), quantile(&v, 0.9)],
            }
        })
        .collect())
}

#[cfg(test)]
mod tests;
