//! The extended-state filter pass: the 14-state Kalman filter on the
//! closed-loop launch INS, fix by fix, with the Cramér–Rao ratio δ(n) and
//! the switches it drives.

use super::*;
use aidnav_estimation::Step;
use aidnav_ins::launch::LaunchInsLanes;

/// The filter's prior covariance, fix noise R and process noise Q.
#[allow(clippy::type_complexity)]
pub(super) fn filter_matrices(
    sc: &ExtendedStateScenario,
) -> (Matrix14, SMatrix<f64, NAVIGATION, NAVIGATION>, Matrix14) {
    let mut p0 = SMatrix::<f64, STATES, STATES>::zeros();
    for i in 0..STATES {
        p0[(i, i)] = if i < NAVIGATION {
            sc.prior_navigation_variance
        } else if let Some(s) = sc.prior_instrument_sigmas.get(i - NAVIGATION) {
            s * s
        } else {
            sc.prior_instrument_variance
        };
    }
    let mut r = SMatrix::<f64, NAVIGATION, NAVIGATION>::zeros();
    let mut q = Matrix14::zeros();
    for i in 0..3 {
        r[(i, i)] = sc.position_sigma_m.powi(2);
        r[(3 + i, 3 + i)] = sc.velocity_sigma_mps.powi(2);
        q[(3 + i, 3 + i)] = sc.velocity_process_noise;
    }
    (p0, r, q)
}

impl FilterHistory {
    /// One fix: δ(n), the instrument estimates' error, σ and bound, the
    /// position error, and the smallest eigenvalue of P − bound.
    fn record(
        &mut self,
        t_fix: f64,
        delta: f64,
        instrument_error: [f64; ESTIMATED],
        p: &Matrix14,
        bound: &Matrix14,
        position_error_m: f64,
    ) {
        self.time_s.push(t_fix);
        self.delta.push(delta);
        self.instrument_error.push(instrument_error);
        self.instrument_sigma.push(std::array::from_fn(|i| {
            p[(NAVIGATION + i, NAVIGATION + i)].sqrt()
        }));
        self.instrument_bound.push(std::array::from_fn(|i| {
            bound[(NAVIGATION + i, NAVIGATION + i)].sqrt()
        }));
        self.position_error_m.push(position_error_m);
        // In the basis scaled by P's own σ, where rounding is uniform
        // (the diagonal spans fifteen orders of magnitude).
        let scale = p.diagonal().map(|v| 1.0 / v.sqrt());
        let scaled = Matrix14::from_fn(|i, j| (p[(i, j)] - bound[(i, j)]) * scale[i] * scale[j]);
        self.bound_gap.push(scaled.symmetric_eigenvalues().min());
    }
}

/// INS minus fix for one fix: the fix is the truth plus noise drawn from
/// `rng` (position and velocity per axis, in that order).
fn fix_residual(
    sc: &ExtendedStateScenario,
    ins: &LaunchIns,
    truth_r: &Vector3<f64>,
    truth_v: &Vector3<f64>,
    rng: &mut RunRng,
) -> SVector<f64, NAVIGATION> {
    let mut z = SVector::<f64, NAVIGATION>::zeros();
    for i in 0..3 {
        let (np, nv) = (standard_normal(rng), standard_normal(rng));
        let scale = sc.fix_noise_scale;
        z[i] = ins.position[i] - (truth_r[i] + scale * sc.position_sigma_m * np);
        z[3 + i] = ins.velocity[i] - (truth_v[i] + scale * sc.velocity_sigma_mps * nv);
    }
    z
}

/// Closed loop on the navigation states: the estimated position and
/// velocity errors leave the INS and the filter's state; the instrument
/// estimates stay. Returns the state after the reset.
fn feed_back_navigation(
    kf: &mut FixedKalmanFilter<STATES>,
    ins: &mut LaunchIns,
) -> Result<SVector<f64, STATES>, EstimationError> {
    let mut x = *kf.state();
    for i in 0..3 {
        ins.position[i] -= x[i];
        ins.velocity[i] -= x[3 + i];
    }
    x.rows_mut(0, NAVIGATION).fill(0.0);
    kf.set_state(x)?;
    Ok(x)
}

/// Filter pass: from launch to the last snapshot needed (or t_B when
/// `history` is requested), the switches at the fixes `path` decided for
/// this flight. Returns, per switch case, the snapshot at its switch (None:
/// never), and the snapshots at the forced times.
#[allow(clippy::type_complexity)]
pub(super) fn filter_pass(
    sc: &ExtendedStateScenario,
    flight: &Flight<'_>,
    path: &CovariancePath,
    rng: &mut RunRng,
    forced: &[f64],
    mut history: Option<&mut FilterHistory>,
) -> Result<(Vec<Option<Snapshot>>, Vec<Option<Snapshot>>), EstimationError> {
    let (traj, errors) = (flight.traj, &flight.errors);
    let dt = traj.dt_s;
    let fix_steps = FixSteps::new(sc, dt);
    let last = traj.samples() - 1;
    let (p0, r, q) = filter_matrices(sc);
    let mut kf = FixedKalmanFilter::<STATES>::new(SVector::zeros(), p0)?;
    let mut fisher = FisherInformation::from_prior_covariance(&p0)?;
    let c = ExtendedStateModel::measurement();
    let truth_m = errors.estimated_components();
    let mut at_switch: Vec<Option<Snapshot>> = vec![None; path.switch_at.len()];
    let mut at_forced: Vec<Option<Snapshot>> = vec![None; forced.len()];
    let mut ins = LaunchIns::default();
    let mut n = 0;
    for k in 0..last {
        ins.step_with_thrust(dt, &flight.raw[k]);
        let step = k + 1;
        if !fix_steps.at(step) {
            continue;
        }
        let t_fix = step as f64 * dt;
        let fix = path.fix(n)?;
        if n > 0 {
            kf.predict(&fix.phi, &q)?;
            fisher.propagate(&fix.phi)?;
        }
        let predicted = *kf.covariance();
        let truth_r = traj.positions[step];
        let truth_v = traj.velocities[step];
        let z = fix_residual(sc, &ins, &truth_r, &truth_v, rng);
        let rec = kf.update(&z, &c, &r)?;
        fisher.add_measurement(&c, &r)?;
        let bound = fisher.cramer_rao_bound()?;
        let delta = cramer_rao_ratio(&rec.gain, &predicted, &bound, NAVIGATION);
        // Closed loop on the navigation states.
        let x = feed_back_navigation(&mut kf, &mut ins)?;
        let x_m: [f64; ESTIMATED] = std::array::from_fn(|i| x[NAVIGATION + i]);
        let snapshot = Snapshot {
            time_s: t_fix,
            fix: n,
            ins,
            estimate: x_m,
        };
        for (at, slot) in path.switch_at.iter().zip(at_switch.iter_mut()) {
            if *at == Some(n) {
                *slot = Some(snapshot);
            }
        }
        for (f, slot) in forced.iter().zip(at_forced.iter_mut()) {
            if slot.is_none() && t_fix >= *f {
                *slot = Some(snapshot);
            }
        }
        if let Some(h) = history.as_deref_mut() {
            let error = std::array::from_fn(|i| x_m[i] - truth_m[i]);
            let position_error_m = (ins.position - truth_r).norm();
            h.record(
                t_fix,
                delta,
                error,
                kf.covariance(),
                &bound,
                position_error_m,
            );
            h.forecast_sigma_m.push(path.forecast_variance[n].sqrt());
            h.forecast_reduction.push(path.forecast_reduction[n]);
            h.forecast_share.push(path.forecast_share[n]);
        } else if at_switch.iter().all(Option::is_some) && at_forced.iter().all(Option::is_some) {
            break;
        }
        n += 1;
    }
    Ok((at_switch, at_forced))
}

/// One fix of a [`CovariancePath`].
#[derive(Debug, Clone)]
pub(super) struct PathFix {
    /// Transition from the previous fix (unused at the first).
    pub(super) phi: Matrix14,
    /// Kalman gain of the fix's update.
    gain: SMatrix<f64, STATES, NAVIGATION>,
}

/// The transitions of a flight's filter: Φ from each fix to the next (the
/// first: identity, unused) and from the last fix to t_B.
fn fix_transitions(sc: &ExtendedStateScenario, flight: &Flight<'_>) -> (Vec<Matrix14>, Matrix14) {
    let (traj, errors) = (flight.traj, &flight.errors);
    let dt = traj.dt_s;
    let fix_steps = FixSteps::new(sc, dt);
    let last = traj.samples() - 1;
    let first_order = |t0: f64, span: f64| {
        let (att, f) = raw_outputs(traj, errors, t0);
        let a = ExtendedStateModel::continuous(t0, &att, &f);
        ExtendedStateModel::transition(&a, span, TransitionForm::FirstOrder)
    };
    let mut phis = Vec::new();
    let mut phi = Matrix14::identity();
    let mut last_fix_s = f64::NAN;
    for k in 0..last {
        let t = k as f64 * dt;
        if k >= fix_steps.start && sc.transition == TransitionForm::Exact {
            let (att, f) = raw_outputs(traj, errors, t + dt / 2.0);
            let a = ExtendedStateModel::continuous(t + dt / 2.0, &att, &f);
            phi = ExtendedStateModel::transition(&a, dt, TransitionForm::Exact) * phi;
        }
        let step = k + 1;
        if !fix_steps.at(step) {
            continue;
        }
        let t_fix = step as f64 * dt;
        if !phis.is_empty() && sc.transition == TransitionForm::FirstOrder {
            phi = first_order(t_fix - sc.fix_interval_s, sc.fix_interval_s);
        }
        phis.push(phi);
        phi = Matrix14::identity();
        last_fix_s = t_fix;
    }
    let t_b = last as f64 * dt;
    if sc.transition == TransitionForm::FirstOrder && t_b > last_fix_s {
        phi = first_order(last_fix_s, t_b - last_fix_s);
    }
    (phis, phi)
}

/// [`fix_transitions`] for the tests.
#[cfg(test)]
pub(super) fn fix_transitions_for_tests(
    sc: &ExtendedStateScenario,
    flight: &Flight<'_>,
) -> (Vec<Matrix14>, Matrix14) {
    fix_transitions(sc, flight)
}

/// What the filter pass does not take from the run. Q, R and H are fixed
/// and Φ is built from the true instrument outputs, the same in every run
/// when the error signs are fixed; so are the covariance, the gains, the
/// Fisher information, δ(n), the forecast of the position error at t_B
/// and the fixes at which the switches fire. One filter pass computes them
/// per flight ([`CovariancePath::new`]); a run then replays only its state
/// ([`replay`]): `x⁻ = Φ x`, `x = x⁻ + K (z − H x⁻)`, the feedback into its
/// INS. The same operations on the same numbers as [`filter_pass`], so the
/// same results.
pub(super) struct CovariancePath {
    pub(super) fixes: Vec<PathFix>,
    /// Per switch case ([`switch_cases`]), the fix at which it fires (None:
    /// never).
    pub(super) switch_at: Vec<Option<usize>>,
    /// δ(n) per fix.
    pub(super) delta: Vec<f64>,
    /// Per fix, the filter's predicted variance of the 3-D position error
    /// at t_B if the instruments were corrected there (tr of the position
    /// block of Φ(t_B, t_n) P(n) Φ(t_B, t_n)ᵀ) \[m²\].
    pub(super) forecast_variance: Vec<f64>,
    /// The same from the Cramér–Rao bound P_Γ(n) \[m²\].
    pub(super) bound_variance: Vec<f64>,
    /// Per fix, the relative reduction of `forecast_variance` that the fix
    /// achieved, per second of fusion (0 at the first fix).
    pub(super) forecast_reduction: Vec<f64>,
    /// Per fix, the instrument states' share of the forecast variance:
    /// `V_M / (V_M + V_H)`, V_M from P_M and V_H from P_H alone.
    pub(super) forecast_share: Vec<f64>,
    /// The error that ended the path before t_B (a run needing a later fix
    /// meets it as [`filter_pass`] would).
    pub(super) error: Option<EstimationError>,
}

/// When fixes arrive, in IMU steps: at the end of step `start` (the fusion
/// start), then every `per_fix` steps (the fix interval).
#[derive(Debug, Clone, Copy)]
struct FixSteps {
    per_fix: usize,
    start: usize,
}

impl FixSteps {
    /// The scenario's fix times in steps of `dt` (rounded to the nearest).
    fn new(sc: &ExtendedStateScenario, dt: f64) -> Self {
        Self {
            per_fix: (sc.fix_interval_s / dt).round() as usize,
            start: (sc.fusion_start_s / dt).round() as usize,
        }
    }

    /// Whether a fix arrives at the end of IMU step `step`.
    fn at(self, step: usize) -> bool {
        step >= self.start && (step - self.start).is_multiple_of(self.per_fix)
    }
}

/// A switch for each case ([`switch_cases`]); the forecast rule's input is
/// the per-second reduction, the δ rules' δ(n).
fn case_switches(sc: &ExtendedStateScenario) -> Vec<(SwitchKind, ConvergenceSwitch)> {
    switch_cases(sc)
        .iter()
        .map(|case| {
            let rule = match case.kind {
                SwitchKind::DeltaArmed => SwitchRule {
                    threshold: case.threshold,
                    ..sc.switch
                },
                SwitchKind::DeltaLiteral => SwitchRule {
                    threshold: case.threshold,
                    arm_after_s: 0.0,
                    require_rise: false,
                    falling_s: 0.0,
                    confirm_epochs: 1,
                },
                // Not in the transient of the diffuse prior (the reduction
                // first rises above the threshold), confirmed as the δ rule.
                SwitchKind::ForecastShare => SwitchRule {
                    threshold: case.threshold,
                    arm_after_s: 0.0,
                    require_rise: false,
                    falling_s: 0.0,
                    confirm_epochs: sc.switch.confirm_epochs,
                },
                SwitchKind::Forecast => SwitchRule {
                    threshold: case.threshold,
                    arm_after_s: 0.0,
                    require_rise: true,
                    falling_s: 0.0,
                    confirm_epochs: sc.switch.confirm_epochs,
                },
            };
            (case.kind, ConvergenceSwitch::new(rule))
        })
        .collect()
}

impl CovariancePath {
    /// Fix `n`, or the error that ended the path before it: a run needing
    /// that fix fails as the shared pass did.
    fn fix(&self, n: usize) -> Result<&PathFix, EstimationError> {
        self.fixes.get(n).ok_or_else(|| {
            self.error
                .clone()
                .expect("a path shorter than the flight ended in an error")
        })
    }

    /// The filter pass of `flight` without a state: every fix to t_B.
    pub(super) fn new(sc: &ExtendedStateScenario, flight: &Flight<'_>) -> Self {
        let mut path = Self {
            fixes: Vec::new(),
            switch_at: vec![None; switch_cases(sc).len()],
            delta: Vec::new(),
            forecast_variance: Vec::new(),
            bound_variance: Vec::new(),
            forecast_reduction: Vec::new(),
            forecast_share: Vec::new(),
            error: None,
        };
        if let Err(e) = path.compute(sc, flight) {
            path.error = Some(e);
        }
        path
    }

    fn compute(
        &mut self,
        sc: &ExtendedStateScenario,
        flight: &Flight<'_>,
    ) -> Result<(), EstimationError> {
        let (phis, tail) = fix_transitions(sc, flight);
        // Position rows of Φ(t_B, t_n), from the last fix backwards.
        let mut weights = vec![SMatrix::<f64, 3, STATES>::zeros(); phis.len()];
        let mut w: SMatrix<f64, 3, STATES> = tail.fixed_rows::<3>(0).into_owned();
        for n in (0..phis.len()).rev() {
            weights[n] = w;
            w *= phis[n];
        }
        let (p0, r, q) = filter_matrices(sc);
        let mut kf = FixedKalmanFilter::<STATES>::new(SVector::zeros(), p0)?;
        let mut fisher = FisherInformation::from_prior_covariance(&p0)?;
        let c = ExtendedStateModel::measurement();
        let mut switches = case_switches(sc);
        let z = SVector::<f64, NAVIGATION>::zeros();
        let dt = flight.traj.dt_s;
        let fix_steps = FixSteps::new(sc, dt);
        for (n, (phi, w)) in phis.iter().zip(&weights).enumerate() {
            let t_fix = (fix_steps.start + n * fix_steps.per_fix) as f64 * dt;
            if n > 0 {
                kf.predict(phi, &q)?;
                fisher.propagate(phi)?;
            }
            let predicted = *kf.covariance();
            // The gain does not depend on z: the state is the run's.
            let rec = kf.update(&z, &c, &r)?;
            fisher.add_measurement(&c, &r)?;
            let bound = fisher.cramer_rao_bound()?;
            let delta = cramer_rao_ratio(&rec.gain, &predicted, &bound, NAVIGATION);
            let forecast = (w * kf.covariance() * w.transpose()).trace();
            let reduction = match self.forecast_variance.last() {
                Some(&before) => (before - forecast) / forecast / sc.fix_interval_s,
                None => 0.0,
            };
            self.delta.push(delta);
            self.forecast_variance.push(forecast);
            self.bound_variance
                .push((w * bound * w.transpose()).trace());
            self.forecast_reduction.push(reduction);
            let p = kf.covariance();
            let (wh, wm) = (
                w.fixed_columns::<NAVIGATION>(0),
                w.fixed_columns::<INSTRUMENTS>(NAVIGATION),
            );
            let nav = (wh * p.fixed_view::<NAVIGATION, NAVIGATION>(0, 0) * wh.transpose()).trace();
            let inst = (wm
                * p.fixed_view::<INSTRUMENTS, INSTRUMENTS>(NAVIGATION, NAVIGATION)
                * wm.transpose())
            .trace();
            let share = inst / (inst + nav);
            self.forecast_share.push(share);
            self.fixes.push(PathFix {
                phi: *phi,
                gain: rec.gain,
            });
            let fusion_s = t_fix - sc.fusion_start_s;
            for ((kind, s), at) in switches.iter_mut().zip(self.switch_at.iter_mut()) {
                let input = match kind {
                    SwitchKind::Forecast => reduction,
                    SwitchKind::ForecastShare => share,
                    _ => delta,
                };
                // The forecast has no reduction at the first fix.
                if *kind == SwitchKind::Forecast && n == 0 {
                    continue;
                }
                if s.observe(fusion_s, input) {
                    *at = Some(n);
                }
            }
        }
        Ok(())
    }
}

/// One fix as a run received it.
#[derive(Debug, Clone, Copy)]
pub(super) struct Fix {
    /// Step index of the fix.
    pub(super) step: usize,
    /// Fixed position and velocity (truth plus noise).
    pub(super) measured: SVector<f64, NAVIGATION>,
}

/// What [`replay`] returns.
pub(super) struct Replay {
    /// Per switch case, the snapshot at its switch (None: never).
    pub(super) at_switch: Vec<Option<Snapshot>>,
    /// The snapshots at the forced times.
    pub(super) at_forced: Vec<Option<Snapshot>>,
    /// The fixes received, up to the last snapshot.
    pub(super) fixes: Vec<Fix>,
    /// The INS at the first fix, before its update.
    pub(super) ins_at_first_fix: LaunchIns,
}

/// [`filter_pass`] of one run on a shared [`CovariancePath`] (no history):
/// the snapshots at the switches and at the forced times, and the fixes.
pub(super) fn replay(
    sc: &ExtendedStateScenario,
    flight: &Flight<'_>,
    path: &CovariancePath,
    rng: &mut RunRng,
    forced: &[f64],
) -> Result<Replay, EstimationError> {
    let mut out = replay_runs(sc, flight, path, std::slice::from_mut(rng), forced)?;
    Ok(out.pop().expect("one replay per stream"))
}

/// [`replay`] of several runs, each with its own stream of fix noise
/// (`rngs`), their INS flown together ([`LaunchInsLanes`]): per run the
/// same operations, so the same numbers. The error of any run ends all
/// (the caller replays them one by one to find whose).
pub(super) fn replay_runs(
    sc: &ExtendedStateScenario,
    flight: &Flight<'_>,
    path: &CovariancePath,
    rngs: &mut [RunRng],
    forced: &[f64],
) -> Result<Vec<Replay>, EstimationError> {
    let traj = flight.traj;
    let dt = traj.dt_s;
    let fix_steps = FixSteps::new(sc, dt);
    let last = traj.samples() - 1;
    let c = ExtendedStateModel::measurement();
    let mut outs: Vec<Replay> = rngs
        .iter()
        .map(|_| Replay {
            at_switch: vec![None; path.switch_at.len()],
            at_forced: vec![None; forced.len()],
            fixes: Vec::new(),
            ins_at_first_fix: LaunchIns::default(),
        })
        .collect();
    let mut lanes = LaunchInsLanes::with_capacity(rngs.len());
    for _ in 0..rngs.len() {
        lanes.push(LaunchIns::default());
    }
    let mut xs = vec![SVector::<f64, STATES>::zeros(); rngs.len()];
    let mut n = 0;
    for k in 0..last {
        for i in 0..lanes.len() {
            lanes.set_thrust(i, &flight.raw[k]);
        }
        lanes.step(dt);
        let step = k + 1;
        if !fix_steps.at(step) {
            continue;
        }
        let t_fix = step as f64 * dt;
        // The shared pass failed here; so would this run's.
        let fix = path.fix(n)?;
        for (i, ((out, x), rng)) in outs
            .iter_mut()
            .zip(&mut xs)
            .zip(rngs.iter_mut())
            .enumerate()
        {
            let mut ins = lanes.get(i);
            if n > 0 {
                // KalmanFilter::predict_state.
                *x = fix.phi * *x;
                check_finite(x, Step::Predict)?;
            } else {
                out.ins_at_first_fix = ins;
            }
            let truth_r = traj.positions[step];
            let truth_v = traj.velocities[step];
            let z = fix_residual(sc, &ins, &truth_r, &truth_v, rng);
            let mut measured = SVector::<f64, NAVIGATION>::zeros();
            for i in 0..3 {
                measured[i] = ins.position[i] - z[i];
                measured[3 + i] = ins.velocity[i] - z[3 + i];
            }
            out.fixes.push(Fix { step, measured });
            // KalmanFilter::update: ν = z − H x, x += K ν.
            let residual = z - c * *x;
            *x += fix.gain * residual;
            check_finite(x, Step::Update)?;
            // Closed loop on the navigation states (feed_back_navigation).
            for i in 0..3 {
                ins.position[i] -= x[i];
                ins.velocity[i] -= x[3 + i];
            }
            x.rows_mut(0, NAVIGATION).fill(0.0);
            lanes.set(i, ins);
            let snapshot = Snapshot {
                time_s: t_fix,
                fix: n,
                ins,
                estimate: std::array::from_fn(|i| x[NAVIGATION + i]),
            };
            for (at, slot) in path.switch_at.iter().zip(out.at_switch.iter_mut()) {
                if *at == Some(n) {
                    *slot = Some(snapshot);
                }
            }
            for (f, slot) in forced.iter().zip(out.at_forced.iter_mut()) {
                if slot.is_none() && t_fix >= *f {
                    *slot = Some(snapshot);
                }
            }
        }
        n += 1;
        // Every run has its snapshots at the same fixes (the path's and
        // the forced times'), so all are done together.
        if outs.iter().all(|out| {
            out.at_switch.iter().all(Option::is_some) && out.at_forced.iter().all(Option::is_some)
        }) {
            break;
        }
    }
    Ok(outs)
}

/// The engine's check of a state after a step.
fn check_finite(x: &SVector<f64, STATES>, step: Step) -> Result<(), EstimationError> {
    if x.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EstimationError::NonFinite {
            step,
            matrix: aidnav_estimation::Matrix::X,
        })
    }
}
