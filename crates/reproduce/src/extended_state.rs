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
//! - `oracle`: instruments corrected with their true errors at the switch.
//!
//! The INS runs at `imu_dt_s` (RK4, the same scheme as the truth, so an
//! error-free INS reproduces the truth); its position and velocity are reset
//! with the filter's estimate after every fix (closed loop on the navigation
//! states, the instruments untouched), which keeps the linear error model
//! valid. Monte Carlo is over the fix noise (and the error signs when
//! `error_signs = "random"`).

use aidnav_estimation::{EstimationError, FisherInformation, FixedKalmanFilter};
use aidnav_ins::launch::{ESTIMATED, LaunchIns, LaunchInstrumentErrors};
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range, non_negative, positive};
use aidnav_models::extended_state::{
    ExtendedStateModel, INSTRUMENTS, Matrix14, NAVIGATION, STATES, TransitionForm,
};
use aidnav_supervisors::convergence::{ConvergenceSwitch, SwitchRule, cramer_rao_ratio};
use nalgebra::{SMatrix, SVector, Vector3};
use serde::{Deserialize, Serialize};

use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::{RngExt, RunRng, channel_rng, standard_normal};
use aidnav_sim::trajectory::{
    LaunchProgram, LaunchTarget, LaunchTrajectory, TABLE1, TrajectoryError,
};

/// Signs of the true instrument errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorSigns {
    /// Every component positive (Table 2 as printed).
    Positive,
    /// Each component's sign drawn per run.
    Random,
}

/// Scenario (TOML; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExtendedStateScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs per trajectory, 1 … 100 000. Default 100.
    pub runs: usize,
    /// INS and truth step \[s\] (≤ 0.01 s: 100 Hz or faster). Default 0.01.
    pub imu_dt_s: f64,
    /// Interval between fixes Δt \[s\] (a whole number of steps). Default 0.15.
    pub fix_interval_s: f64,
    /// Flight time of the first fix \[s\]. Default 20.
    pub fusion_start_s: f64,
    /// σ of the fixes' position noise \[m\] (R = σ² I). Default 10.
    pub position_sigma_m: f64,
    /// σ of the fixes' velocity noise [m/s]. Default 10.
    pub velocity_sigma_mps: f64,
    /// Scale of the simulated fix noise (0: exact fixes; the filter still
    /// assumes R from the two σ above). Default 1.
    pub fix_noise_scale: f64,
    /// Prior variance of the navigation states (P_H(0) = v I6). Default 1e3.
    pub prior_navigation_variance: f64,
    /// Prior variance of the instrument states (P_M(0) = v I8). Default 1e3.
    pub prior_instrument_variance: f64,
    /// Process noise on each velocity per fix interval [(m/s)²]. The paper
    /// gives none; with 0 the filter's covariance equals the Cramér–Rao
    /// bound and δ(n) is exactly the relative reduction of tr P_M by one
    /// fix. Any Q > 0 keeps P_M above the bound, so δ(n) turns up again late
    /// in the flight (1e-4: δ never falls below 1 % on t_B = 300 s).
    /// Default 0.
    pub velocity_process_noise: f64,
    /// Φ from A: `first_order` (the paper's I + AΔt, A at the interval
    /// start) or `exact` (I + AΔ + A²Δ²/2 per INS step). Default `exact`.
    pub transition: TransitionForm,
    /// Thresholds δ_thr. Default [0.03, 0.01].
    pub thresholds: Vec<f64>,
    /// Arming of the switch (its `threshold` is replaced by each of
    /// `thresholds`). Default: δ non-increasing for 15 s, then δ ≤ δ_thr
    /// for 5 epochs. The 15 s were chosen after looking at δ(n) of the
    /// t_B = 300 s, φ = 0 flight: its early humps fall for 4 s and 11 s
    /// before the next instrument errors become observable.
    pub switch: SwitchRule,
    /// Signs of the true instrument errors. Default `positive`.
    pub error_signs: ErrorSigns,
    /// Shape of the guidance program.
    pub program: LaunchProgram,
    /// Target points. Default: Table 1.
    pub targets: Vec<LaunchTarget>,
    /// Index into `targets` of the trajectory drawn in the figures. Default 4
    /// (t_B = 400 s, φ = 30°).
    pub figure_target: usize,
    /// Forced switch times for the sweep figure: every this many seconds of
    /// fusion. Default 10.
    pub sweep_step_s: f64,
    /// Runs of the sweep. Default 20.
    pub sweep_runs: usize,
}

impl Default for ExtendedStateScenario {
    fn default() -> Self {
        Self {
            seed: 20261123,
            runs: 100,
            imu_dt_s: 0.01,
            fix_interval_s: 0.15,
            fusion_start_s: 20.0,
            position_sigma_m: 10.0,
            velocity_sigma_mps: 10.0,
            fix_noise_scale: 1.0,
            prior_navigation_variance: 1e3,
            prior_instrument_variance: 1e3,
            velocity_process_noise: 0.0,
            transition: TransitionForm::Exact,
            thresholds: vec![0.03, 0.01],
            switch: SwitchRule {
                falling_s: 15.0,
                ..SwitchRule::default()
            },
            error_signs: ErrorSigns::Positive,
            program: LaunchProgram::default(),
            targets: TABLE1.to_vec(),
            figure_target: 4,
            sweep_step_s: 10.0,
            sweep_runs: 20,
        }
    }
}

impl Validate for ExtendedStateScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 100_000)?;
        count_in_range("sweep_runs", self.sweep_runs, 1, 100_000)?;
        in_range("imu_dt_s", self.imu_dt_s, 1e-4, 0.01)?;
        in_range("fix_interval_s", self.fix_interval_s, self.imu_dt_s, 10.0)?;
        let ratio = self.fix_interval_s / self.imu_dt_s;
        if (ratio - ratio.round()).abs() > 1e-6 {
            return Err(Invalid::new(
                "fix_interval_s",
                self.fix_interval_s,
                "a whole number of imu_dt_s",
            ));
        }
        non_negative("fusion_start_s", self.fusion_start_s)?;
        positive("position_sigma_m", self.position_sigma_m)?;
        positive("velocity_sigma_mps", self.velocity_sigma_mps)?;
        in_range("fix_noise_scale", self.fix_noise_scale, 0.0, 100.0)?;
        positive("prior_navigation_variance", self.prior_navigation_variance)?;
        positive("prior_instrument_variance", self.prior_instrument_variance)?;
        non_negative("velocity_process_noise", self.velocity_process_noise)?;
        positive("sweep_step_s", self.sweep_step_s)?;
        if self.thresholds.is_empty() || self.thresholds.len() > 10 {
            return Err(Invalid::new(
                "thresholds",
                self.thresholds.len(),
                "1 … 10 thresholds",
            ));
        }
        for t in &self.thresholds {
            in_range("thresholds", *t, 1e-9, 1.0)?;
        }
        non_negative("arm_after_s", self.switch.arm_after_s).map_err(|e| e.within("switch"))?;
        non_negative("falling_s", self.switch.falling_s).map_err(|e| e.within("switch"))?;
        count_in_range("confirm_epochs", self.switch.confirm_epochs, 1, 100_000)
            .map_err(|e| e.within("switch"))?;
        count_in_range("targets", self.targets.len(), 1, 100)?;
        for (i, t) in self.targets.iter().enumerate() {
            if !(t.t_b_s > self.fusion_start_s + 10.0 && t.t_b_s <= 3600.0) {
                return Err(Invalid::new(
                    format!("targets[{i}].t_b_s"),
                    t.t_b_s,
                    "fusion_start_s + 10 < t_b_s ≤ 3600",
                ));
            }
        }
        count_in_range(
            "figure_target",
            self.figure_target,
            0,
            self.targets.len() - 1,
        )?;
        Ok(())
    }
}

/// Anything the experiment can fail with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExtendedStateError {
    /// A target could not be reached by the guidance program.
    #[error("target t_B = {t_b_s} s, course {course_deg}°: {source}")]
    Trajectory {
        /// t_B of the target.
        t_b_s: f64,
        /// Course.
        course_deg: f64,
        /// Why.
        source: TrajectoryError,
    },
    /// The filter.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}

/// What the filter pass keeps at a switch.
#[derive(Debug, Clone, Copy)]
struct Snapshot {
    /// Flight time [s].
    time_s: f64,
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
}

/// One run's numbers for one threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ThresholdRun {
    switch_time_s: f64,
    outputs_only_m: f64,
    proposed_m: f64,
    oracle_m: f64,
}

/// Result per (trajectory, threshold), medians over runs.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaseResult {
    /// t_B \[s\].
    pub t_b_s: f64,
    /// Course \[deg\].
    pub course_deg: f64,
    /// δ_thr.
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

/// The truth's instrument errors for one run.
fn true_errors(sc: &ExtendedStateScenario, rng: &mut RunRng) -> LaunchInstrumentErrors {
    match sc.error_signs {
        ErrorSigns::Positive => LaunchInstrumentErrors::table2(1.0),
        ErrorSigns::Random => {
            let mut signs = [1.0; 12];
            for s in &mut signs {
                *s = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            }
            LaunchInstrumentErrors::table2_signed(&signs)
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

/// Fly the INS autonomously from `start` (at step index `from`) to t_B with
/// the instruments corrected by `correction` (None: uncorrected); calls
/// `each_step(k, &ins)` after every step.
fn fly(
    traj: &LaunchTrajectory,
    errors: &LaunchInstrumentErrors,
    correction: Option<&LaunchInstrumentErrors>,
    start: LaunchIns,
    from: usize,
    mut each_step: impl FnMut(usize, &LaunchIns),
) -> f64 {
    let dt = traj.dt_s;
    let mut ins = start;
    let last = traj.samples() - 1;
    for k in from..last {
        ins.step(k as f64 * dt, dt, |tau| {
            let (att, f) = raw_outputs(traj, errors, tau);
            match correction {
                Some(c) => c.correct(tau, &att, &f),
                None => (att, f),
            }
        });
        each_step(k + 1, &ins);
    }
    (ins.position - traj.positions[last]).norm()
}

/// Filter pass: from launch to the last snapshot needed (or t_B when
/// `history` is requested). Returns, per threshold, the snapshot at its
/// switch (None: never), and the snapshots at the forced times.
#[allow(clippy::type_complexity)]
fn filter_pass(
    sc: &ExtendedStateScenario,
    traj: &LaunchTrajectory,
    errors: &LaunchInstrumentErrors,
    rng: &mut RunRng,
    forced: &[f64],
    mut history: Option<&mut FilterHistory>,
) -> Result<(Vec<Option<Snapshot>>, Vec<Option<Snapshot>>), EstimationError> {
    let dt = traj.dt_s;
    let per_fix = (sc.fix_interval_s / dt).round() as usize;
    let start_step = (sc.fusion_start_s / dt).round() as usize;
    let last = traj.samples() - 1;
    let mut p0 = SMatrix::<f64, STATES, STATES>::zeros();
    for i in 0..STATES {
        p0[(i, i)] = if i < NAVIGATION {
            sc.prior_navigation_variance
        } else {
            sc.prior_instrument_variance
        };
    }
    let mut kf = FixedKalmanFilter::<STATES>::new(SVector::zeros(), p0)?;
    let mut fisher = FisherInformation::from_prior_covariance(&p0)?;
    let c = ExtendedStateModel::measurement();
    let mut r = SMatrix::<f64, NAVIGATION, NAVIGATION>::zeros();
    let mut q = Matrix14::zeros();
    for i in 0..3 {
        r[(i, i)] = sc.position_sigma_m.powi(2);
        r[(3 + i, 3 + i)] = sc.velocity_sigma_mps.powi(2);
        q[(3 + i, 3 + i)] = sc.velocity_process_noise;
    }
    let truth_m = errors.estimated_components();
    let mut switches: Vec<ConvergenceSwitch> = sc
        .thresholds
        .iter()
        .map(|&threshold| {
            ConvergenceSwitch::new(SwitchRule {
                threshold,
                ..sc.switch
            })
        })
        .collect();
    let mut at_switch: Vec<Option<Snapshot>> = vec![None; switches.len()];
    let mut at_forced: Vec<Option<Snapshot>> = vec![None; forced.len()];
    let mut ins = LaunchIns::default();
    let mut phi = Matrix14::identity();
    let mut first_fix = true;
    for k in 0..last {
        let t = k as f64 * dt;
        if k >= start_step && sc.transition == TransitionForm::Exact {
            let (att, f) = raw_outputs(traj, errors, t + dt / 2.0);
            let a = ExtendedStateModel::continuous(t + dt / 2.0, &att, &f);
            phi = ExtendedStateModel::transition(&a, dt, TransitionForm::Exact) * phi;
        }
        ins.step(t, dt, |tau| raw_outputs(traj, errors, tau));
        let step = k + 1;
        if step < start_step || !(step - start_step).is_multiple_of(per_fix) {
            continue;
        }
        let t_fix = step as f64 * dt;
        if !first_fix {
            if sc.transition == TransitionForm::FirstOrder {
                let t0 = t_fix - sc.fix_interval_s;
                let (att, f) = raw_outputs(traj, errors, t0);
                let a = ExtendedStateModel::continuous(t0, &att, &f);
                phi = ExtendedStateModel::transition(
                    &a,
                    sc.fix_interval_s,
                    TransitionForm::FirstOrder,
                );
            }
            kf.predict(&phi, &q)?;
            fisher.propagate(&phi)?;
        }
        first_fix = false;
        phi = Matrix14::identity();
        let predicted = *kf.covariance();
        let truth_r = traj.positions[step];
        let truth_v = traj.velocities[step];
        let mut z = SVector::<f64, NAVIGATION>::zeros();
        for i in 0..3 {
            let (np, nv) = (standard_normal(rng), standard_normal(rng));
            let scale = sc.fix_noise_scale;
            z[i] = ins.position[i] - (truth_r[i] + scale * sc.position_sigma_m * np);
            z[3 + i] = ins.velocity[i] - (truth_v[i] + scale * sc.velocity_sigma_mps * nv);
        }
        let rec = kf.update(&z, &c, &r)?;
        fisher.add_measurement(&c, &r)?;
        let bound = fisher.cramer_rao_bound()?;
        let delta = cramer_rao_ratio(&rec.gain, &predicted, &bound, NAVIGATION);
        // Closed loop on the navigation states.
        let mut x = *kf.state();
        for i in 0..3 {
            ins.position[i] -= x[i];
            ins.velocity[i] -= x[3 + i];
        }
        x.rows_mut(0, NAVIGATION).fill(0.0);
        kf.set_state(x)?;
        let x_m: [f64; ESTIMATED] = std::array::from_fn(|i| x[NAVIGATION + i]);
        let snapshot = Snapshot {
            time_s: t_fix,
            ins,
            estimate: x_m,
        };
        let fusion_s = t_fix - sc.fusion_start_s;
        for (s, slot) in switches.iter_mut().zip(at_switch.iter_mut()) {
            if s.observe(fusion_s, delta) {
                *slot = Some(snapshot);
            }
        }
        for (f, slot) in forced.iter().zip(at_forced.iter_mut()) {
            if slot.is_none() && t_fix >= *f {
                *slot = Some(snapshot);
            }
        }
        if let Some(h) = history.as_deref_mut() {
            let p = kf.covariance();
            h.time_s.push(t_fix);
            h.delta.push(delta);
            h.instrument_error
                .push(std::array::from_fn(|i| x_m[i] - truth_m[i]));
            h.instrument_sigma.push(std::array::from_fn(|i| {
                p[(NAVIGATION + i, NAVIGATION + i)].sqrt()
            }));
            h.instrument_bound.push(std::array::from_fn(|i| {
                bound[(NAVIGATION + i, NAVIGATION + i)].sqrt()
            }));
            h.position_error_m.push((ins.position - truth_r).norm());
            // In the basis scaled by P's own σ, where rounding is uniform
            // (the diagonal spans fifteen orders of magnitude).
            let scale = p.diagonal().map(|v| 1.0 / v.sqrt());
            let scaled =
                Matrix14::from_fn(|i, j| (p[(i, j)] - bound[(i, j)]) * scale[i] * scale[j]);
            h.bound_gap.push(scaled.symmetric_eigenvalues().min());
        } else if at_switch.iter().all(Option::is_some) && at_forced.iter().all(Option::is_some) {
            break;
        }
    }
    Ok((at_switch, at_forced))
}

/// Ratio and errors of the three switched cases from one snapshot.
fn branches(
    traj: &LaunchTrajectory,
    errors: &LaunchInstrumentErrors,
    snapshot: &Snapshot,
) -> ThresholdRun {
    let from = (snapshot.time_s / traj.dt_s).round() as usize;
    let estimated = LaunchInstrumentErrors::from_estimate(&snapshot.estimate);
    ThresholdRun {
        switch_time_s: snapshot.time_s,
        outputs_only_m: fly(traj, errors, None, snapshot.ins, from, |_, _| {}),
        proposed_m: fly(
            traj,
            errors,
            Some(&estimated),
            snapshot.ins,
            from,
            |_, _| {},
        ),
        oracle_m: fly(traj, errors, Some(errors), snapshot.ins, from, |_, _| {}),
    }
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
            LaunchTrajectory::solve(t, &sc.program, sc.imu_dt_s).map_err(|source| {
                ExtendedStateError::Trajectory {
                    t_b_s: t.t_b_s,
                    course_deg: t.course_deg,
                    source,
                }
            })
        })
        .collect()
}

/// Run the experiment.
pub fn run(
    sc: &ExtendedStateScenario,
    mc: &MonteCarlo,
) -> Result<ExtendedStateResult, ExtendedStateError> {
    let trajs = trajectories(sc)?;
    let mut cases = Vec::new();
    for (ti, traj) in trajs.iter().enumerate() {
        let per_run = mc.try_run(|run, _| {
            let mut rng = channel_rng(sc.seed, run as u64, ti as u64);
            let errors = true_errors(sc, &mut rng);
            let free = fly(traj, &errors, None, LaunchIns::default(), 0, |_, _| {});
            let (switches, _) = filter_pass(sc, traj, &errors, &mut rng, &[], None)?;
            let t_b = traj.target.t_b_s;
            let out: Vec<(ThresholdRun, bool)> = switches
                .iter()
                .map(|s| match s {
                    Some(s) => (branches(traj, &errors, s), false),
                    None => (
                        ThresholdRun {
                            switch_time_s: t_b,
                            outputs_only_m: f64::NAN,
                            proposed_m: f64::NAN,
                            oracle_m: f64::NAN,
                        },
                        true,
                    ),
                })
                .collect();
            Ok::<_, EstimationError>((free, out))
        })?;
        let free = sorted(per_run.iter().map(|r| r.0).collect());
        for (k, &threshold) in sc.thresholds.iter().enumerate() {
            let runs: Vec<ThresholdRun> = per_run.iter().map(|r| r.1[k].0).collect();
            let never = per_run.iter().filter(|r| r.1[k].1).count();
            let ok: Vec<&ThresholdRun> = runs.iter().filter(|r| r.proposed_m.is_finite()).collect();
            let pick = |f: fn(&ThresholdRun) -> f64| sorted(ok.iter().map(|r| f(r)).collect());
            let ratio = pick(|r| r.outputs_only_m / r.proposed_m);
            let switch = sorted(runs.iter().map(|r| r.switch_time_s).collect());
            cases.push(CaseResult {
                t_b_s: traj.target.t_b_s,
                course_deg: traj.target.course_deg,
                delta_threshold: threshold,
                switch_time_s: quantile(&switch, 0.5),
                switch_time_p10_p90_s: [quantile(&switch, 0.1), quantile(&switch, 0.9)],
                never_switched: never,
                error_free_ins_m: quantile(&free, 0.5),
                error_outputs_only_m: quantile(&pick(|r| r.outputs_only_m), 0.5),
                error_proposed_m: quantile(&pick(|r| r.proposed_m), 0.5),
                error_oracle_m: quantile(&pick(|r| r.oracle_m), 0.5),
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
    let errors = true_errors(sc, &mut rng);
    let mut history = FilterHistory::default();
    let (switches, _) = filter_pass(sc, traj, &errors, &mut rng, &[], Some(&mut history))?;
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
    fly(traj, &errors, None, LaunchIns::default(), 0, |k, ins| {
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
            fly(traj, &errors, Some(&estimated), s.ins, from, |k, ins| {
                record(&mut p, k, ins)
            });
            let mut o = Vec::new();
            fly(traj, &errors, None, s.ins, from, |k, ins| {
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
    // Sweep of forced switch times.
    let t_b = traj.target.t_b_s;
    let mut forced = Vec::new();
    let mut t = sc.fusion_start_s + sc.sweep_step_s;
    while t < t_b - 1.0 {
        forced.push(t);
        t += sc.sweep_step_s;
    }
    let sweep_mc = MonteCarlo::new(sc.sweep_runs, sc.seed).quiet();
    let sweep_runs = sweep_mc.try_run(|run, _| {
        let mut rng = channel_rng(sc.seed, run as u64, 1000 + ti);
        let errors = true_errors(sc, &mut rng);
        let (_, at) = filter_pass(sc, traj, &errors, &mut rng, &forced, None)?;
        Ok::<_, EstimationError>(
            at.iter()
                .map(|s| {
                    s.map_or(f64::NAN, |s| {
                        let b = branches(traj, &errors, &s);
                        b.outputs_only_m / b.proposed_m
                    })
                })
                .collect::<Vec<f64>>(),
        )
    })?;
    let sweep = forced
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
        .collect();
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

#[cfg(test)]
mod tests {
    use super::*;

    fn quick(targets: Vec<LaunchTarget>) -> ExtendedStateScenario {
        ExtendedStateScenario {
            runs: 4,
            targets,
            figure_target: 0,
            sweep_runs: 2,
            sweep_step_s: 60.0,
            ..ExtendedStateScenario::default()
        }
    }

    /// The 14-state linear model against the nonlinear INS: small instrument
    /// errors (1 % of Table 2) propagated for 100 s from launch through
    /// both give the same position and velocity errors within 1 %.
    #[test]
    fn linear_error_model_matches_the_nonlinear_ins() {
        let traj = LaunchTrajectory::solve(&TABLE1[0], &LaunchProgram::default(), 0.01).unwrap();
        let mut errors = LaunchInstrumentErrors::table2(1.0);
        errors.accel_bias *= 0.01;
        errors.accel_scale *= 0.01;
        errors.angle_offset *= 0.01;
        errors.angle_drift *= 0.01;
        let steps = 10_000; // 100 s
        let mut x = SVector::<f64, STATES>::zeros();
        let m = errors.estimated_components();
        for i in 0..ESTIMATED {
            x[NAVIGATION + i] = m[i];
        }
        let mut ins = LaunchIns::default();
        for k in 0..steps {
            let t = k as f64 * 0.01;
            let (att, f) = raw_outputs(&traj, &errors, t + 0.005);
            let a = ExtendedStateModel::continuous(t + 0.005, &att, &f);
            x = ExtendedStateModel::transition(&a, 0.01, TransitionForm::Exact) * x;
            ins.step(t, 0.01, |tau| raw_outputs(&traj, &errors, tau));
        }
        let dr = ins.position - traj.positions[steps];
        let dv = ins.velocity - traj.velocities[steps];
        let lr = Vector3::new(x[0], x[1], x[2]);
        let lv = Vector3::new(x[3], x[4], x[5]);
        assert!((dr - lr).norm() < 0.01 * dr.norm(), "{dr} vs {lr}");
        assert!((dv - lv).norm() < 0.01 * dv.norm(), "{dv} vs {lv}");
        assert!(dr.norm() > 10.0); // the comparison is not vacuous
    }

    /// Noise-free fixes: the filter recovers the eight instrument errors
    /// within 5 % (errors at 0.1 % of Table 2, where the neglected
    /// second-order attitude term f Δb²/2 is below 1 % of the accelerometer
    /// bias; at full size it is as large as the bias itself).
    #[test]
    fn noise_free_fixes_recover_the_instrument_errors() {
        let sc = quick(vec![TABLE1[0]]);
        let traj = LaunchTrajectory::solve(&TABLE1[0], &sc.program, sc.imu_dt_s).unwrap();
        let mut errors = LaunchInstrumentErrors::table2(1.0);
        errors.accel_bias *= 0.001;
        errors.accel_scale *= 0.001;
        errors.angle_offset *= 0.001;
        errors.angle_drift *= 0.001;
        let mut history = FilterHistory::default();
        let mut rng = channel_rng(1, 0, 0);
        let exact = ExtendedStateScenario {
            fix_noise_scale: 0.0,
            ..sc.clone()
        };
        filter_pass(&exact, &traj, &errors, &mut rng, &[], Some(&mut history)).unwrap();
        let last = history.instrument_error.last().unwrap();
        let truth = errors.estimated_components();
        for i in 0..ESTIMATED {
            assert!(
                last[i].abs() < 0.05 * truth[i].abs(),
                "component {i}: error {} of {}",
                last[i],
                truth[i]
            );
        }
    }

    /// With Q = 0 the filter covariance never drops below the Cramér–Rao
    /// bound (P − P_Γ ⪰ 0 up to rounding), with Q > 0 it stays above it;
    /// and δ(n) falls after the transient.
    #[test]
    fn covariance_respects_the_bound_and_delta_falls() {
        for q in [0.0, 1e-4] {
            let sc = ExtendedStateScenario {
                velocity_process_noise: q,
                ..quick(vec![TABLE1[0]])
            };
            let traj = LaunchTrajectory::solve(&TABLE1[0], &sc.program, sc.imu_dt_s).unwrap();
            let errors = LaunchInstrumentErrors::table2(1.0);
            let mut history = FilterHistory::default();
            let mut rng = channel_rng(2, 0, 0);
            filter_pass(&sc, &traj, &errors, &mut rng, &[], Some(&mut history)).unwrap();
            let worst = history
                .bound_gap
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            // With Q = 0, P and P_Γ are equal in exact arithmetic; in σ-scaled
            // coordinates their computed difference is rounding of the order
            // of 1e-5 (median here; F's condition number is ~1e15), so the
            // tolerance is 1e-3 — far below a real violation (order 1).
            assert!(worst > -1e-3, "Q = {q}: P − P_Γ has eigenvalue {worst:e}");
            if q == 0.0 {
                // δ after 100 s of fusion is below its value at 60 s and
                // below half its transient peak.
                let at = |s: f64| {
                    let k = history.time_s.iter().position(|&t| t >= s).unwrap();
                    history.delta[k]
                };
                let peak = history.delta.iter().copied().fold(0.0, f64::max);
                assert!(at(200.0) < at(80.0) && at(200.0) < 0.5 * peak);
            }
        }
    }

    /// Reduced run of the reproduction: every trajectory, both thresholds,
    /// the proposed correction beats outputs-only in the median.
    #[test]
    fn reduced_reproduction_improves_every_case() {
        let sc = quick(TABLE1.to_vec());
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        assert_eq!(r.cases.len(), 18);
        for c in &r.cases {
            assert_eq!(c.never_switched, 0, "{c:?}");
            assert!(c.ratio_median > 1.0, "{c:?}");
            assert!(c.error_oracle_m < c.error_proposed_m, "{c:?}");
            assert!(c.error_outputs_only_m < c.error_free_ins_m, "{c:?}");
        }
    }
}
