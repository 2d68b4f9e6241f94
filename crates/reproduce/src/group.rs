//! Spec 30, the paper's experiment: one coordinate axis, M = 5 vehicles in
//! formation, the axis-decoupled group filter ([`AxisGroup`]) against a single
//! vehicle. Three cases, as in the paper's table: `single` (M = 1),
//! `group_low` (low-grade relative sensors, strong disturbances) and
//! `group_high` (high-grade relative sensors, weak disturbances).
//!
//! "Mean error" is undefined in the paper, so both readings are reported,
//! each averaged over the members and over the settled part of the run
//! (epochs at or after `settle_s`): the filter's σ (√ of P's diagonal after
//! the update) and the Monte Carlo RMS of the true error. The steady-state σ
//! of the filtering Riccati equation is reported beside them.
//!
//! Truth and filter share the model: each member's initial position and
//! velocity are drawn from the prior (σ_own, `initial_velocity_sigma_mps`),
//! its velocity then walks with a_R T per step; the filter starts at zero
//! with that prior.

use aidnav_estimation::{EstimationError, KalmanFilter, steady_state_covariance};
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range};
use aidnav_models::AxisGroup;
use nalgebra::{DMatrix, DVector, Dyn};
use serde::{Deserialize, Serialize};

use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::standard_normal;

/// Case keys, in table order (`summary.json` uses these).
pub const CASES: [&str; 3] = ["single", "group_low", "group_high"];

/// Scenario (TOML; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GroupScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 1 000 000. Default 1000.
    pub runs: usize,
    /// Epochs per run (T each), 2 … 100 000. Default 31 (the paper's ≈ 30 s).
    pub epochs: usize,
    /// Averages start at this time \[s\] (the paper's filter settles in ≈ 10 s). Default 10.
    pub settle_s: f64,
    /// Prior σ of each member's velocity [m/s]. Default 10.
    pub initial_velocity_sigma_mps: f64,
    /// The single vehicle (paper: σ_own 10 m, a_R 1 m/s²).
    pub single: AxisGroup,
    /// Five vehicles, low-grade relative sensors (σ_rel 10 m, a_R 1 m/s²).
    pub group_low: AxisGroup,
    /// Five vehicles, high-grade relative sensors (σ_rel 0.5 m, a_R 0.01 m/s²).
    pub group_high: AxisGroup,
}

impl Default for GroupScenario {
    fn default() -> Self {
        let single = AxisGroup::default();
        Self {
            seed: 20261123,
            runs: 1000,
            epochs: 31,
            settle_s: 10.0,
            initial_velocity_sigma_mps: 10.0,
            single,
            group_low: AxisGroup {
                members: 5,
                relative_sigma_m: Some(10.0),
                ..single
            },
            group_high: AxisGroup {
                members: 5,
                accel_sigma_m_s2: 0.01,
                relative_sigma_m: Some(0.5),
                ..single
            },
        }
    }
}

fn validate_group(key: &str, g: &AxisGroup) -> Result<(), Invalid> {
    let inner = || -> Result<(), Invalid> {
        count_in_range("members", g.members, 1, 200)?;
        in_range("dt_s", g.dt_s, 1e-4, 100.0)?;
        crate::within("accel_sigma_m_s2", g.accel_sigma_m_s2, crate::SIGMA_RANGE)?;
        crate::within(
            "own_position_sigma_m",
            g.own_position_sigma_m,
            crate::SIGMA_RANGE,
        )?;
        if let Some(s) = g.own_velocity_sigma_mps {
            crate::within("own_velocity_sigma_mps", s, crate::SIGMA_MPS_RANGE)?;
        }
        if let Some(s) = g.relative_sigma_m {
            crate::within("relative_sigma_m", s, crate::SIGMA_RANGE)?;
        }
        Ok(())
    };
    inner().map_err(|e| e.within(key))
}

impl Validate for GroupScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 1_000_000)?;
        count_in_range("epochs", self.epochs, 2, 100_000)?;
        crate::within(
            "initial_velocity_sigma_mps",
            self.initial_velocity_sigma_mps,
            crate::SIGMA_MPS_RANGE,
        )?;
        if !(self.settle_s >= 0.0 && self.settle_s <= 1e6) {
            return Err(Invalid::new(
                "settle_s",
                self.settle_s,
                "0 ≤ settle_s, finite",
            ));
        }
        for (key, g) in CASES.iter().zip(self.cases()) {
            validate_group(key, g)?;
            // One time axis for the per-epoch table and plot.
            if g.dt_s != self.single.dt_s {
                return Err(Invalid::new(
                    format!("{key}.dt_s"),
                    g.dt_s,
                    format!("the same step as single.dt_s ({})", self.single.dt_s),
                ));
            }
            if self.settle_s >= (self.epochs - 1) as f64 * g.dt_s {
                return Err(Invalid::new(
                    "settle_s",
                    self.settle_s,
                    "settle_s < the run length (epochs − 1) · dt_s of every case",
                ));
            }
        }
        Ok(())
    }
}

impl GroupScenario {
    /// The three cases in [`CASES`] order.
    pub fn cases(&self) -> [&AxisGroup; 3] {
        [&self.single, &self.group_low, &self.group_high]
    }
}

/// One case's numbers.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CaseScore {
    /// Key (see [`CASES`]).
    pub name: String,
    /// Members.
    pub members: usize,
    /// Filter σ of position, mean over members and settled epochs \[m\].
    pub position_sigma_m: f64,
    /// Monte Carlo RMS of the position error, members × settled epochs × runs \[m\].
    pub position_rms_m: f64,
    /// Filter σ of velocity [m/s].
    pub velocity_sigma_mps: f64,
    /// Monte Carlo RMS of the velocity error [m/s].
    pub velocity_rms_mps: f64,
    /// Steady-state filtered σ of position (Riccati), mean over members \[m\].
    pub steady_position_sigma_m: f64,
    /// Steady-state filtered σ of velocity [m/s].
    pub steady_velocity_sigma_mps: f64,
    /// Per epoch: filter σ of position, mean over members \[m\].
    pub sigma_by_epoch: Vec<f64>,
    /// Per epoch: RMS position error over members and runs \[m\].
    pub rms_by_epoch: Vec<f64>,
    /// Per epoch: filter σ of velocity, mean over members [m/s].
    pub velocity_sigma_by_epoch: Vec<f64>,
    /// Per epoch: RMS velocity error over members and runs [m/s].
    pub velocity_rms_by_epoch: Vec<f64>,
}

/// Result of the experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupResult {
    /// Cases in [`CASES`] order.
    pub cases: Vec<CaseScore>,
}

impl GroupResult {
    /// The case named `name`.
    pub fn case(&self, name: &str) -> Option<&CaseScore> {
        self.cases.iter().find(|c| c.name == name)
    }
}

/// Per run: per epoch, sums over members of squared position and velocity errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunOut {
    position_sq: Vec<f64>,
    velocity_sq: Vec<f64>,
}

/// Offsets of a member's position and velocity in its (R, V) block.
const POSITION: usize = 0;
const VELOCITY: usize = 1;

/// Mean over the members of √P of the state at `offset` in each member's block.
fn mean_member_sigma(p: &DMatrix<f64>, members: usize, offset: usize) -> f64 {
    (0..members)
        .map(|l| p[(2 * l + offset, 2 * l + offset)].sqrt())
        .sum::<f64>()
        / members as f64
}

/// A case's model: what its runs and its σ pass share.
struct CaseModel {
    n: usize,
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    r_sigma: DVector<f64>,
    p0: DMatrix<f64>,
    p0_sigma: DVector<f64>,
    velocity_step: f64,
}

fn case_model(g: &AxisGroup, sc: &GroupScenario) -> CaseModel {
    let n = g.states();
    let phi = g.transition();
    let q = g.process_noise();
    let (h, r) = g.measurement();
    let r_sigma = r.diagonal().map(f64::sqrt);
    let p0 = DMatrix::from_diagonal(&DVector::from_fn(n, |i, _| {
        if i % 2 == 0 {
            g.own_position_sigma_m.powi(2)
        } else {
            sc.initial_velocity_sigma_mps.powi(2)
        }
    }));
    let p0_sigma = p0.diagonal().map(f64::sqrt);
    let velocity_step = g.accel_sigma_m_s2 * g.dt_s;
    CaseModel {
        n,
        phi,
        q,
        h,
        r,
        r_sigma,
        p0,
        p0_sigma,
        velocity_step,
    }
}

/// Runs `range` of one case.
fn case_runs(
    g: &AxisGroup,
    sc: &GroupScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<Vec<RunOut>, EstimationError> {
    let CaseModel {
        n,
        phi,
        q,
        h,
        r,
        r_sigma,
        p0,
        p0_sigma,
        velocity_step,
    } = case_model(g, sc);
    let _ = &r;
    mc.try_run_range(range, |_, rng| -> Result<RunOut, EstimationError> {
        let mut x = DVector::from_fn(n, |i, _| p0_sigma[i] * standard_normal(rng));
        let mut kf = KalmanFilter::<Dyn>::new(DVector::zeros(n), p0.clone())?;
        let mut out = RunOut {
            position_sq: Vec::with_capacity(sc.epochs),
            velocity_sq: Vec::with_capacity(sc.epochs),
        };
        for e in 0..sc.epochs {
            if e > 0 {
                x = &phi * &x;
                for l in 0..g.members {
                    x[2 * l + 1] += velocity_step * standard_normal(rng);
                }
                kf.predict(&phi, &q).map_err(|err| err.at_epoch(e))?;
            }
            let noise = DVector::from_fn(h.nrows(), |i, _| r_sigma[i] * standard_normal(rng));
            let z = &h * &x + noise;
            kf.update(&z, &h, &r).map_err(|err| err.at_epoch(e))?;
            let err = kf.state() - &x;
            out.position_sq
                .push((0..g.members).map(|l| err[2 * l].powi(2)).sum());
            out.velocity_sq
                .push((0..g.members).map(|l| err[2 * l + 1].powi(2)).sum());
        }
        Ok(out)
    })
}

/// A case's score from its runs (in run order).
fn case_score(
    name: &str,
    g: &AxisGroup,
    sc: &GroupScenario,
    per_run: &[RunOut],
) -> Result<CaseScore, EstimationError> {
    let CaseModel {
        n,
        phi,
        q,
        h,
        r,
        p0,
        ..
    } = case_model(g, sc);
    // The filter's σ does not depend on the data: one pass gives it.
    let mut sigma_filter = KalmanFilter::<Dyn>::new(DVector::zeros(n), p0.clone())?;
    let mut sigma_by_epoch = Vec::with_capacity(sc.epochs);
    let mut velocity_sigma_by_epoch = Vec::with_capacity(sc.epochs);
    for e in 0..sc.epochs {
        if e > 0 {
            sigma_filter
                .predict(&phi, &q)
                .map_err(|err| err.at_epoch(e))?;
        }
        let z = &h * sigma_filter.state();
        sigma_filter
            .update(&z, &h, &r)
            .map_err(|err| err.at_epoch(e))?;
        let p = sigma_filter.covariance();
        sigma_by_epoch.push(mean_member_sigma(p, g.members, POSITION));
        velocity_sigma_by_epoch.push(mean_member_sigma(p, g.members, VELOCITY));
    }
    let settled: Vec<usize> = (0..sc.epochs)
        .filter(|&e| e as f64 * g.dt_s >= sc.settle_s)
        .collect();
    let count = (settled.len() * g.members * per_run.len()) as f64;
    let rms = |pick: fn(&RunOut) -> &Vec<f64>| {
        (per_run
            .iter()
            .map(|r| settled.iter().map(|&e| pick(r)[e]).sum::<f64>())
            .sum::<f64>()
            / count)
            .sqrt()
    };
    let mean_over_settled =
        |v: &[f64]| settled.iter().map(|&e| v[e]).sum::<f64>() / settled.len() as f64;
    let ss = steady_state_covariance(&phi, &h, &q, &r)?;
    let rms_by_epoch_of = |pick: fn(&RunOut) -> &Vec<f64>| -> Vec<f64> {
        (0..sc.epochs)
            .map(|e| {
                (per_run.iter().map(|r| pick(r)[e]).sum::<f64>()
                    / (g.members * per_run.len()) as f64)
                    .sqrt()
            })
            .collect()
    };
    Ok(CaseScore {
        name: name.to_string(),
        members: g.members,
        position_sigma_m: mean_over_settled(&sigma_by_epoch),
        position_rms_m: rms(|r| &r.position_sq),
        velocity_sigma_mps: mean_over_settled(&velocity_sigma_by_epoch),
        velocity_rms_mps: rms(|r| &r.velocity_sq),
        steady_position_sigma_m: mean_member_sigma(&ss.filtered, g.members, POSITION),
        steady_velocity_sigma_mps: mean_member_sigma(&ss.filtered, g.members, VELOCITY),
        sigma_by_epoch,
        rms_by_epoch: rms_by_epoch_of(|r| &r.position_sq),
        velocity_sigma_by_epoch,
        velocity_rms_by_epoch: rms_by_epoch_of(|r| &r.velocity_sq),
    })
}

/// Run the three cases (each on the streams of the same seed):
/// [`finish`] of every run ([`run_range`] over `0..mc.runs`).
pub fn run(sc: &GroupScenario, mc: &MonteCarlo) -> Result<GroupResult, EstimationError> {
    finish(sc, run_range(sc, mc, 0..mc.runs)?)
}

/// Runs `range` of every case, in [`CASES`] order: a chunk for [`finish`]
/// to combine with the others (run k draws stream k of the seed whatever
/// the range), computed anywhere.
pub fn run_range(
    sc: &GroupScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<GroupRuns, EstimationError> {
    let cases = sc
        .cases()
        .iter()
        .map(|g| case_runs(g, sc, mc, range.clone()))
        .collect::<Result<_, _>>()?;
    Ok(GroupRuns { cases })
}

/// The runs of a range of the campaign, per case.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct GroupRuns {
    cases: Vec<Vec<RunOut>>,
}

impl crate::Chunk for GroupRuns {
    fn runs(&self) -> usize {
        self.cases.first().map_or(0, Vec::len)
    }

    fn append(&mut self, other: Self) {
        if self.cases.is_empty() {
            *self = other;
            return;
        }
        for (mine, theirs) in self.cases.iter_mut().zip(other.cases) {
            mine.extend(theirs);
        }
    }
}

/// The result from every run, in run order (the chunks of [`run_range`]
/// joined): the same numbers, bit for bit, as [`run`].
pub fn finish(sc: &GroupScenario, runs: GroupRuns) -> Result<GroupResult, EstimationError> {
    let cases = CASES
        .iter()
        .zip(sc.cases())
        .zip(&runs.cases)
        .map(|((name, g), per_run)| case_score(name, g, sc, per_run))
        .collect::<Result<_, _>>()?;
    Ok(GroupResult { cases })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steady_state_of_the_single_vehicle_is_about_six_metres() {
        // Spec 30: the single vehicle's steady-state position σ is ≈ 6.0 m;
        // the filter over a long run reaches the Riccati solution.
        let sc = GroupScenario {
            runs: 1,
            epochs: 400,
            ..GroupScenario::default()
        };
        let r = run(&sc, &MonteCarlo::new(1, 1).quiet()).unwrap();
        let single = r.case("single").unwrap();
        assert!(
            (single.steady_position_sigma_m - 6.0).abs() < 0.1,
            "{}",
            single.steady_position_sigma_m
        );
        let last = *single.sigma_by_epoch.last().unwrap();
        assert!(
            (last - single.steady_position_sigma_m).abs() < 1e-9,
            "{last}"
        );
    }

    #[test]
    fn reduced_run_group_beats_the_single_vehicle_in_both_grades() {
        let sc = GroupScenario {
            runs: 200,
            ..GroupScenario::default()
        };
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        let single = r.case("single").unwrap();
        for name in ["group_low", "group_high"] {
            let g = r.case(name).unwrap();
            assert!(g.position_rms_m < single.position_rms_m, "{name}");
            assert!(g.velocity_rms_mps < single.velocity_rms_mps, "{name}");
            assert!(g.position_sigma_m < single.position_sigma_m, "{name}");
        }
        // The Monte Carlo agrees with the filter's σ (same model): within
        // the sampling error of 200 runs × 5 members × 21 epochs (a few %).
        for c in &r.cases {
            assert!(
                (c.position_rms_m / c.position_sigma_m - 1.0).abs() < 0.1,
                "{}",
                c.name
            );
        }
    }

    /// Issue 16 item 4: the high-grade case's slow settling comes from the
    /// group's common mode (the mean position and velocity of the five),
    /// which only the own fixes observe — not from the relative sensors.
    /// Making the relative measurements 500× more precise leaves the
    /// settled σ unchanged (measured 1.907 → 1.906 m), while a velocity
    /// prior of 0.1 m/s instead of 10 m/s brings it from 1.91 m to 1.10 m
    /// and the velocity σ from 0.18 to 0.05 m/s. The filter's σ is
    /// deterministic (one run suffices); the Monte Carlo RMS of the velocity
    /// follows it per epoch.
    #[test]
    fn high_grade_settling_is_set_by_the_common_mode_not_the_relative_sensors() {
        let high = |sc: GroupScenario| {
            let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
            r.case("group_high").unwrap().clone()
        };
        let base = GroupScenario {
            runs: 1,
            ..GroupScenario::default()
        };
        let default = high(base.clone());
        let mut exact = base.clone();
        exact.group_high.relative_sigma_m = Some(0.001);
        let exact = high(exact);
        let known_velocity = high(GroupScenario {
            initial_velocity_sigma_mps: 0.1,
            ..base
        });
        assert!(
            (exact.position_sigma_m / default.position_sigma_m - 1.0).abs() < 0.01,
            "{} vs {}",
            exact.position_sigma_m,
            default.position_sigma_m
        );
        assert!(
            known_velocity.position_sigma_m < 0.7 * default.position_sigma_m,
            "{} vs {}",
            known_velocity.position_sigma_m,
            default.position_sigma_m
        );
        assert!(known_velocity.velocity_sigma_mps < 0.5 * default.velocity_sigma_mps);
        // Either way the settled σ stays above the steady state (0.94 m).
        assert!(known_velocity.position_sigma_m > known_velocity.steady_position_sigma_m);
        // Velocity per epoch: Monte Carlo against the filter's σ (300 runs).
        let sc = GroupScenario {
            runs: 300,
            ..GroupScenario::default()
        };
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        for c in &r.cases {
            assert_eq!(c.velocity_rms_by_epoch.len(), sc.epochs);
            let last = sc.epochs - 1;
            let ratio = c.velocity_rms_by_epoch[last] / c.velocity_sigma_by_epoch[last];
            // 300 runs × 5 members (× 1 for single): a 95 % band of ±8 % (±17 %).
            assert!((0.8..1.2).contains(&ratio), "{}: {ratio}", c.name);
        }
    }
}
