//! The formation's Monte Carlo: stage 1, then both stage-2 filters on the
//! same measurements, and the scores over runs.

use aidnav_estimation::EstimationError;
use aidnav_ins::local_level::LocalLevelState;
use aidnav_integration::group::{EkfFusion, OwnSolution, PaperFusion};
use aidnav_models::local_ins::Matrix6;
use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::channel_rng;
use nalgebra::Vector3;

use serde::{Deserialize, Serialize};

#[cfg(test)]
use super::Stage2Motion;
use super::network::{self, NetworkStats};
use super::simulate::{
    RATE_CHANNEL, RELATIVE_CHANNEL, StageOnePaths, relative_measurements, relative_rates,
    stage_one_on,
};
use super::{Denial, FormationResult, FormationScenario, MemberScore, Stage2OwnErrors};

/// One run's per-epoch errors, what [`finish`] combines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunErrors {
    /// `[epoch][member][solution]`: squared position error.
    pub(super) position_sq: Vec<Vec<[f64; 3]>>,
    pub(super) velocity_sq: Vec<Vec<[f64; 3]>>,
    /// `[epoch][member][solution]`: position and velocity σ (√ trace).
    pub(super) sigma: Vec<Vec<[f64; 3]>>,
    pub(super) velocity_sigma: Vec<Vec<[f64; 3]>>,
    /// `[epoch][member][solution]`: position and velocity NEES.
    pub(super) position_nees: Vec<Vec<[f64; 3]>>,
    pub(super) velocity_nees: Vec<Vec<[f64; 3]>>,
    pub(super) relative: usize,
    /// What the network did (only with `[formation.network]`).
    pub(super) network: Option<NetworkStats>,
}

/// e_iᵀ P⁻¹ e for the 3-D block at `offset` of a 6×6 covariance (Cholesky
/// solve; NaN when the block is not positive definite).
fn nees3(p: &Matrix6, offset: usize, e: &Vector3<f64>) -> f64 {
    let block = p.fixed_view::<3, 3>(offset, offset).into_owned();
    block.cholesky().map_or(f64::NAN, |c| e.dot(&c.solve(e)))
}

/// Which members' stage-1 solutions of `epoch` hold a new GNSS fix, as
/// stage 2 is to treat them: with the correlated model, a member without a
/// GNSS fix this epoch hands stage 2 a prediction of what was already fused,
/// not fused again (its INS drift is not white); the white treatment fuses
/// every solution. The same for the ideal exchange and the network's packets.
pub(super) fn own_new(sc: &FormationScenario, epoch: usize) -> Vec<bool> {
    let t = (epoch + 1) as f64 * sc.fix_interval_s;
    (0..sc.members)
        .map(|l| sc.stage2_own_errors == Stage2OwnErrors::White || !sc.denied(l, t))
        .collect()
}

impl RunErrors {
    pub(super) fn with_capacity(epochs: usize) -> Self {
        Self {
            position_sq: Vec::with_capacity(epochs),
            velocity_sq: Vec::with_capacity(epochs),
            sigma: Vec::with_capacity(epochs),
            velocity_sigma: Vec::with_capacity(epochs),
            position_nees: Vec::with_capacity(epochs),
            velocity_nees: Vec::with_capacity(epochs),
            relative: 0,
            network: None,
        }
    }

    /// Scores one epoch: each member's stage-1 solution and both stage-2
    /// estimates against the truth (squared errors, σ, NEES).
    pub(super) fn push_epoch(
        &mut self,
        own_e: &[OwnSolution],
        truth_e: &[LocalLevelState],
        paper: &PaperFusion,
        ekf: &EkfFusion,
    ) {
        let members = truth_e.len();
        let mut pos = Vec::with_capacity(members);
        let mut vel = Vec::with_capacity(members);
        let mut sig = Vec::with_capacity(members);
        let mut vsig = Vec::with_capacity(members);
        let mut pnees = Vec::with_capacity(members);
        let mut vnees = Vec::with_capacity(members);
        for (l, t) in truth_e.iter().enumerate() {
            let o = &own_e[l];
            let estimates = [
                (o.state.position, o.state.velocity),
                (paper.position(l), paper.velocity(l)),
                (ekf.position(l), ekf.velocity(l)),
            ];
            pos.push(estimates.map(|(p, _)| (p - t.position).norm_squared()));
            vel.push(estimates.map(|(_, v)| (v - t.velocity).norm_squared()));
            let stage1_sigma = (0..3).map(|a| o.covariance[(a, a)]).sum::<f64>().sqrt();
            sig.push([stage1_sigma, paper.position_sigma(l), ekf.position_sigma(l)]);
            let stage1_vsigma = (3..6).map(|a| o.covariance[(a, a)]).sum::<f64>().sqrt();
            vsig.push([
                stage1_vsigma,
                paper.velocity_sigma(l),
                ekf.velocity_sigma(l),
            ]);
            let covariances = [
                o.covariance,
                paper.position_velocity_covariance(l),
                ekf.position_velocity_covariance(l),
            ];
            let mut pn = [0.0; 3];
            let mut vn = [0.0; 3];
            for s in 0..3 {
                let (p, v) = estimates[s];
                pn[s] = nees3(&covariances[s], 0, &(p - t.position));
                vn[s] = nees3(&covariances[s], 3, &(v - t.velocity));
            }
            pnees.push(pn);
            vnees.push(vn);
        }
        self.position_sq.push(pos);
        self.velocity_sq.push(vel);
        self.sigma.push(sig);
        self.velocity_sigma.push(vsig);
        self.position_nees.push(pnees);
        self.velocity_nees.push(vnees);
    }
}

fn run_once(
    sc: &FormationScenario,
    run: u64,
    paths: &StageOnePaths,
) -> Result<RunErrors, EstimationError> {
    let (own, truth) = stage_one_on(sc, run, paths)?;
    match &sc.network {
        Some(net) => network::stage_two(sc, net, run, &own, &truth),
        None => ideal_stage_two(sc, run, &own, &truth),
    }
}

/// Stage 2 with the ideal exchange: every member's solution and relative
/// measurements (positions, then rates) reach both filters at the epoch they
/// are made.
fn ideal_stage_two(
    sc: &FormationScenario,
    run: u64,
    own: &[Vec<OwnSolution>],
    truth: &[Vec<LocalLevelState>],
) -> Result<RunErrors, EstimationError> {
    let mut rng = channel_rng(sc.seed, run, RELATIVE_CHANNEL);
    let mut rate_rng = channel_rng(sc.seed, run, RATE_CHANNEL);
    let mut paper = PaperFusion::new(sc.fusion_params(), &own[0])?;
    let mut ekf = EkfFusion::new(sc.fusion_params(), &own[0])?;
    let mut errors = RunErrors::with_capacity(own.len());
    for (epoch, (own_e, truth_e)) in own.iter().zip(truth).enumerate() {
        let relative = relative_measurements(sc, truth_e, &mut rng);
        errors.relative += relative.len();
        let rates = relative_rates(sc, truth_e, &mut rate_rng);
        let own_new = own_new(sc, epoch);
        paper.epoch_with_new_own(own_e, &own_new, &relative, epoch > 0)?;
        ekf.epoch_with_new_own(own_e, &own_new, &relative, epoch > 0)?;
        if !rates.is_empty() {
            paper.fuse_rates(own_e, &rates)?;
            ekf.fuse_rates(own_e, &rates)?;
        }
        errors.push_epoch(own_e, truth_e, &paper, &ekf);
    }
    Ok(errors)
}

/// Run the Monte Carlo of the formation: [`finish`] of every run
/// ([`run_range`] over `0..mc.runs`).
pub fn run(sc: &FormationScenario, mc: &MonteCarlo) -> Result<FormationResult, EstimationError> {
    finish(sc, run_range(sc, mc, 0..mc.runs)?)
}

/// Runs `range` of the campaign (run k's streams depend on k alone): a
/// chunk for [`finish`] to combine with the others, computed anywhere.
pub fn run_range(
    sc: &FormationScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<Vec<RunErrors>, EstimationError> {
    let paths = StageOnePaths::new(sc);
    mc.try_run_range(range, |run, _rng| run_once(sc, run as u64, &paths))
}

/// The result from every run, in run order (the chunks of [`run_range`]
/// concatenated): the same numbers, bit for bit, as [`run`].
pub fn finish(
    sc: &FormationScenario,
    runs: Vec<RunErrors>,
) -> Result<FormationResult, EstimationError> {
    let epochs = sc.epochs();
    let time_s: Vec<f64> = (0..epochs)
        .map(|k| (k + 1) as f64 * sc.fix_interval_s)
        .collect();
    let settled: Vec<usize> = (0..epochs).filter(|&k| time_s[k] >= sc.settle_s).collect();
    let n_runs = runs.len() as f64;
    let members = (0..sc.members)
        .map(|l| {
            let mean_over = |pick: &dyn Fn(&RunErrors, usize) -> [f64; 3], root: bool| {
                let mut acc = [0.0; 3];
                for r in &runs {
                    for &k in &settled {
                        let v = pick(r, k);
                        for s in 0..3 {
                            acc[s] += v[s];
                        }
                    }
                }
                acc.map(|a| {
                    let mean = a / (n_runs * settled.len() as f64);
                    if root { mean.sqrt() } else { mean }
                })
            };
            let windows: Vec<&Denial> = sc
                .denial
                .iter()
                .filter(|d| d.members.contains(&l))
                .collect();
            let in_denial: Vec<usize> = (0..epochs)
                .filter(|&k| windows.iter().any(|d| d.denies(l, time_s[k])))
                .collect();
            let (denial_max, denial_end) = if in_denial.is_empty() {
                (None, None)
            } else {
                let mut max = [0.0; 3];
                let mut end = [0.0; 3];
                let last = *in_denial.last().expect("non-empty");
                for r in &runs {
                    for s in 0..3 {
                        let worst = in_denial
                            .iter()
                            .map(|&k| r.position_sq[k][l][s])
                            .fold(0.0, f64::max);
                        max[s] += worst.sqrt() / n_runs;
                        end[s] += r.position_sq[last][l][s] / n_runs;
                    }
                }
                (Some(max), Some(end.map(f64::sqrt)))
            };
            let in_degradation: Vec<usize> = (0..epochs)
                .filter(|&k| !sc.denied(l, time_s[k]) && sc.degradation_at(l, time_s[k]).is_some())
                .collect();
            let degradation_rms = (!in_degradation.is_empty()).then(|| {
                let mut acc = [0.0; 3];
                for r in &runs {
                    for &k in &in_degradation {
                        for (a, v) in acc.iter_mut().zip(r.position_sq[k][l]) {
                            *a += v;
                        }
                    }
                }
                acc.map(|a| (a / (n_runs * in_degradation.len() as f64)).sqrt())
            });
            MemberScore {
                member: l,
                denied: !in_denial.is_empty(),
                position_rms_m: mean_over(&|r, k| r.position_sq[k][l], true),
                velocity_rms_mps: mean_over(&|r, k| r.velocity_sq[k][l], true),
                position_sigma_m: mean_over(&|r, k| r.sigma[k][l], false),
                velocity_sigma_mps: mean_over(&|r, k| r.velocity_sigma[k][l], false),
                position_nees: mean_over(&|r, k| r.position_nees[k][l], false),
                velocity_nees: mean_over(&|r, k| r.velocity_nees[k][l], false),
                denial_max_error_m: denial_max,
                denial_end_error_m: denial_end,
                degraded: degradation_rms.is_some(),
                degradation_rms_error_m: degradation_rms,
            }
        })
        .collect();
    let error_by_epoch = (0..epochs)
        .map(|k| {
            (0..sc.members)
                .map(|l| {
                    let mut acc = [0.0; 3];
                    for r in &runs {
                        for (a, v) in acc.iter_mut().zip(r.position_sq[k][l]) {
                            *a += v;
                        }
                    }
                    acc.map(|a| (a / n_runs).sqrt())
                })
                .collect()
        })
        .collect();
    let relative_per_epoch =
        runs.iter().map(|r| r.relative as f64).sum::<f64>() / (n_runs * epochs as f64);
    let network = sc.network.as_ref().map(|_| {
        let mut total = NetworkStats::default();
        for r in &runs {
            if let Some(n) = &r.network {
                total.add(n);
            }
        }
        total
    });
    Ok(FormationResult {
        members,
        time_s,
        error_by_epoch,
        relative_per_epoch,
        network,
    })
}

#[cfg(test)]
mod tests {
    use super::super::Degradation;
    use super::*;
    use aidnav_io::config::Validate;

    /// `runs` flights of `duration_s` (30 s to settle), member 2 without
    /// GNSS from 100 s to `denial_end_s`; the rest as the default.
    fn member_2_denied_from_100_s(
        runs: usize,
        duration_s: f64,
        denial_end_s: f64,
    ) -> FormationScenario {
        FormationScenario {
            runs,
            duration_s,
            settle_s: 30.0,
            denial: vec![Denial {
                members: vec![2],
                start_s: 100.0,
                end_s: denial_end_s,
            }],
            ..FormationScenario::default()
        }
    }

    #[test]
    fn formation_truth_is_smooth_and_spaced() {
        let sc = FormationScenario::default();
        for t in [0.0, 37.0, 120.0, 333.0] {
            for l in 1..sc.members {
                let d = (sc.position(l, t) - sc.position(0, t)).norm();
                assert!(
                    d > 100.0 && d < 2.5 * sc.spacing_m,
                    "member {l} at {t}: {d}"
                );
            }
            let s = sc.truth(0, t);
            assert!((s.velocity.norm() - sc.speed_mps).abs() < 25.0);
            // Body x axis along the velocity.
            let fwd = s.attitude * Vector3::x();
            assert!(fwd.dot(&s.velocity.normalize()) > 0.999);
        }
    }

    #[test]
    fn bad_denial_is_named() {
        let sc = FormationScenario {
            denial: vec![Denial {
                members: vec![7],
                start_s: 0.0,
                end_s: 10.0,
            }],
            ..FormationScenario::default()
        };
        let e = sc.validate().unwrap_err();
        assert_eq!(e.key, "denial[0].members");
    }

    /// σ keys have physical ranges: a σ whose square underflows, or a
    /// period that makes the weave's rate overflow, is refused by name.
    #[test]
    fn sigmas_and_periods_out_of_physical_range_are_named() {
        let mut sc = FormationScenario::default();
        sc.sensor.range_sigma_m = 1e-170;
        assert_eq!(sc.validate().unwrap_err().key, "sensor.range_sigma_m");
        let sc = FormationScenario {
            weave_period_s: 1e-300,
            ..FormationScenario::default()
        };
        assert_eq!(sc.validate().unwrap_err().key, "weave_period_s");
        let mut sc = FormationScenario::default();
        sc.model.gnss.velocity_sigma_mps = f64::INFINITY;
        assert_eq!(
            sc.validate().unwrap_err().key,
            "model.gnss.velocity_sigma_mps"
        );
        assert!(FormationScenario::default().validate().is_ok());
        let mut sc = FormationScenario::default();
        sc.sensor.range_rate_sigma_mps = 0.0;
        assert_eq!(
            sc.validate().unwrap_err().key,
            "sensor.range_rate_sigma_mps"
        );
        let mut sc = FormationScenario::default();
        sc.sensor.relative_velocity_sigma_mps = f64::NAN;
        assert_eq!(
            sc.validate().unwrap_err().key,
            "sensor.relative_velocity_sigma_mps"
        );
    }

    /// The own-error model is a named TOML key; an unknown value is refused.
    #[test]
    fn stage2_own_errors_key_parses() {
        let parse = |text: &str| {
            aidnav_io::config::parse_toml::<super::super::FormationFile>(
                text,
                std::path::Path::new("test.toml"),
            )
        };
        let file = parse("[formation]\nstage2_own_errors = \"white\"\n").unwrap();
        assert_eq!(file.formation.stage2_own_errors, Stage2OwnErrors::White);
        assert_eq!(
            FormationScenario::default().stage2_own_errors,
            Stage2OwnErrors::Stage1Reported
        );
        let file = parse(
            "[formation]\nstage2_own_errors = \"stage1_reported\"\nstage2_motion = \"paper\"\n",
        )
        .unwrap();
        assert_eq!(
            file.formation.stage2_own_errors,
            Stage2OwnErrors::Stage1Reported
        );
        assert_eq!(file.formation.stage2_motion, Stage2Motion::Paper);
        assert_eq!(
            FormationScenario::default().stage2_motion,
            Stage2Motion::PiecewiseConstantAcceleration
        );
        let bad = parse("[formation]\nstage2_own_errors = \"pink\"\n");
        assert!(format!("{:#}", bad.unwrap_err()).contains("stage2_own_errors"));
        let bad = parse("[formation]\nstage2_motion = \"jerky\"\n");
        assert!(format!("{:#}", bad.unwrap_err()).contains("stage2_motion"));
    }

    /// Short flight, few runs: the group beats GNSS/INS alone for every
    /// member, and the denied member's error stays bounded inside the group
    /// while alone it drifts.
    #[test]
    fn group_fusion_beats_stand_alone_and_bounds_the_denied_member() {
        let sc = member_2_denied_from_100_s(4, 300.0, 250.0);
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        assert_eq!(r.members.len(), 5);
        for m in r.members.iter().filter(|m| !m.denied) {
            let [alone, paper, ekf] = m.position_rms_m;
            assert!(
                paper < alone && ekf < alone,
                "member {}: {:?}",
                m.member,
                m.position_rms_m
            );
        }
        let denied = &r.members[2];
        let [alone, paper, ekf] = denied.denial_max_error_m.unwrap();
        assert!(alone > 20.0, "free INS drift {alone}");
        assert!(
            paper < 10.0 && ekf < 10.0,
            "inside the group: {paper}, {ekf}"
        );
    }

    /// Short flight, few runs, member 2 denied from 100 s to 180 s: with the
    /// stage-1 errors' correlated part modelled (default), stage 2's
    /// position error stays within its σ and beats stage 1 for every member,
    /// and its velocity is far better than with the white treatment. Range
    /// rates and relative velocities reduce the EKF's velocity error
    /// further.
    ///
    /// Measured (3 runs of 240 s; paper / EKF): RMS/σ 0.72 / 0.71 (white
    /// 1.00 / 1.00 — its overconfidence builds over minutes: 1.34 at
    /// 600 s), NEES 1.5 / 1.5, velocity 0.165 / 0.168 m/s (white 0.71 /
    /// 0.72), with rates 0.142 / 0.135 m/s. Asserted: RMS/σ in 0.6 … 1.25,
    /// NEES 1 … 5, velocity below a third of white's, rates better.
    #[test]
    fn correlated_stage_one_errors_make_stage_two_consistent() {
        // The receiver-model Gauss–Markov stage 2 with the paper's motion
        // model, as measured (the default before the stage-1 reported one).
        let base = FormationScenario {
            stage2_own_errors: Stage2OwnErrors::GaussMarkov,
            stage2_motion: Stage2Motion::Paper,
            ..member_2_denied_from_100_s(3, 240.0, 180.0)
        };
        let go =
            |sc: &FormationScenario| run(sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        let gm = go(&base);
        let white = go(&FormationScenario {
            stage2_own_errors: Stage2OwnErrors::White,
            stage2_own_velocity: false,
            ..base.clone()
        });
        let mut rates_sc = base.clone();
        rates_sc.sensor.range_rate = true;
        rates_sc.sensor.relative_velocity = true;
        let rates = go(&rates_sc);
        let mean = |r: &FormationResult, f: &dyn Fn(&MemberScore) -> f64| {
            r.members.iter().map(f).sum::<f64>() / r.members.len() as f64
        };
        for s in 1..3 {
            let ratio = |r: &FormationResult| {
                mean(r, &|m| m.position_rms_m[s]) / mean(r, &|m| m.position_sigma_m[s])
            };
            let (g, w) = (ratio(&gm), ratio(&white));
            assert!((0.6..1.25).contains(&g), "solution {s}: RMS/σ {g}");
            assert!(w > g, "solution {s}: white {w} vs Gauss–Markov {g}");
            let nees = mean(&gm, &|m| m.position_nees[s]);
            assert!((1.0..5.0).contains(&nees), "solution {s}: NEES {nees}");
            let (vg, vw) = (
                mean(&gm, &|m| m.velocity_rms_mps[s]),
                mean(&white, &|m| m.velocity_rms_mps[s]),
            );
            assert!(vg < vw / 3.0, "solution {s}: velocity {vg} vs white {vw}");
            for m in gm.members.iter().filter(|m| !m.denied) {
                assert!(
                    m.position_rms_m[s] < m.position_rms_m[0],
                    "member {}: {:?}",
                    m.member,
                    m.position_rms_m
                );
            }
        }
        let (v, vr) = (
            mean(&gm, &|m| m.velocity_rms_mps[2]),
            mean(&rates, &|m| m.velocity_rms_mps[2]),
        );
        assert!(vr < v, "EKF velocity with rates {vr} vs without {v}");
    }

    /// Short flight, few runs, member 2 denied from 100 s to 180 s, the
    /// default stage 2 (each member's stage-1 error as states moved by the
    /// transition its own filter reports; the acceleration's share on the
    /// position within a step): both forms consistent in position and
    /// velocity, and no worse than stage 1 in either for any member keeping
    /// GNSS.
    ///
    /// Measured (3 runs of 240 s, mean over the members keeping GNSS; paper
    /// / EKF, stage 1 beside): position RMS/σ 0.80 / 0.80 (stage 1 0.87 in
    /// this small sample), NEES 1.7 / 1.6; velocity 0.044 / 0.043 m/s
    /// against stage 1's 0.061, RMS/σ 1.04 / 1.05, NEES 3.3 / 3.4; position
    /// 1.46 / 1.45 m against 3.53 m. Asserted: position RMS/σ 0.6 … 1.3,
    /// velocity RMS/σ 0.8 … 1.3, velocity NEES 2 … 4.5, and each member's
    /// position and velocity RMS below stage 1's.
    #[test]
    fn stage_one_reported_errors_make_stage_two_consistent_and_no_worse_than_stage_one() {
        let sc = member_2_denied_from_100_s(3, 240.0, 180.0);
        assert_eq!(sc.stage2_own_errors, Stage2OwnErrors::Stage1Reported);
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        let keeping: Vec<&MemberScore> = r.members.iter().filter(|m| !m.denied).collect();
        let mean = |f: &dyn Fn(&MemberScore) -> f64| {
            keeping.iter().map(|m| f(m)).sum::<f64>() / keeping.len() as f64
        };
        for s in 1..3 {
            let position = mean(&|m| m.position_rms_m[s]) / mean(&|m| m.position_sigma_m[s]);
            let velocity = mean(&|m| m.velocity_rms_mps[s]) / mean(&|m| m.velocity_sigma_mps[s]);
            let nees = mean(&|m| m.velocity_nees[s]);
            assert!(
                (0.6..1.3).contains(&position),
                "solution {s}: position RMS/σ {position}"
            );
            assert!(
                (0.8..1.3).contains(&velocity),
                "solution {s}: velocity RMS/σ {velocity}"
            );
            assert!(
                (2.0..4.5).contains(&nees),
                "solution {s}: velocity NEES {nees}"
            );
            for m in &keeping {
                assert!(
                    m.position_rms_m[s] < m.position_rms_m[0]
                        && m.velocity_rms_mps[s] < m.velocity_rms_mps[0],
                    "member {} solution {s}: position {:?}, velocity {:?}",
                    m.member,
                    m.position_rms_m,
                    m.velocity_rms_mps
                );
            }
        }
    }

    #[test]
    fn bad_degradation_is_named() {
        let good = Degradation {
            member: 1,
            start_s: 10.0,
            end_s: 20.0,
            sigma_scale: 5.0,
            bias_m: [10.0, 0.0, 0.0],
            reported: false,
        };
        let with = |d: Degradation| FormationScenario {
            degradation: vec![good.clone(), d],
            ..FormationScenario::default()
        };
        assert!(with(good.clone()).validate().is_ok());
        let cases = [
            (
                Degradation {
                    member: 5,
                    ..good.clone()
                },
                "degradation[1].member",
            ),
            (
                Degradation {
                    end_s: 5.0,
                    ..good.clone()
                },
                "degradation[1].end_s",
            ),
            (
                Degradation {
                    sigma_scale: 0.5,
                    ..good.clone()
                },
                "degradation[1].sigma_scale",
            ),
            (
                Degradation {
                    bias_m: [0.0, f64::NAN, 0.0],
                    ..good.clone()
                },
                "degradation[1].bias_m",
            ),
        ];
        for (d, key) in cases {
            assert_eq!(with(d).validate().unwrap_err().key, key);
        }
    }

    /// Short flight, few runs, member 2's fixes 5× noisier and biased north
    /// from 100 s to 250 s. Every variant shares its random numbers (same
    /// seed), so the comparisons are paired.
    ///
    /// Measured (4 runs; RMS of member 2 during the interval, alone / paper /
    /// EKF): no bias 26.7 / 5.12 / 5.09 m, 10 m 28.3 / 5.47 / 5.43 m, 30 m
    /// 38.9 / 7.87 / 7.76 m; 10 m reported 24.9 / 2.73 / 2.71 m.
    #[test]
    fn group_fusion_reduces_a_silent_gnss_degradation() {
        // Measured, and asserted, with the white treatment of stage 1's
        // errors (the default before the Gauss–Markov model).
        let scenario = |bias: f64, reported: bool| FormationScenario {
            stage2_own_errors: Stage2OwnErrors::White,
            stage2_motion: Stage2Motion::Paper,
            stage2_own_velocity: false,
            runs: 4,
            duration_s: 300.0,
            settle_s: 30.0,
            denial: Vec::new(),
            degradation: vec![Degradation {
                member: 2,
                start_s: 100.0,
                end_s: 250.0,
                sigma_scale: 5.0,
                bias_m: [bias, 0.0, 0.0],
                reported,
            }],
            ..FormationScenario::default()
        };
        let score = |sc: &FormationScenario| {
            let r = run(sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
            assert!(r.members.iter().all(|m| m.degraded == (m.member == 2)));
            r.members[2].degradation_rms_error_m.unwrap()
        };
        let unbiased = score(&scenario(0.0, false));
        let mut previous = unbiased[0];
        let mut silent = unbiased;
        for bias in [10.0, 30.0] {
            let [alone, paper, ekf] = score(&scenario(bias, false));
            if bias == 10.0 {
                silent = [alone, paper, ekf];
            }
            // (a) Stage 1 follows the bias: with paired noise, the squared RMS
            // grows by b² + 2 b · mean(north error) — the measured part
            // attributable to the bias is 0.93 b (10 m) and 0.94 b (30 m);
            // ±25 % leaves room for a mean north error of ±1.2 m at 10 m.
            assert!(alone > previous, "bias {bias}: {alone} ≤ {previous}");
            previous = alone;
            let from_bias = (alone * alone - unbiased[0] * unbiased[0]).sqrt();
            assert!(
                (0.75 * bias..1.25 * bias).contains(&from_bias),
                "bias {bias}: {from_bias} of the error from the bias"
            );
            // (b) The group pulls the member back: measured 5.2× (10 m) and
            // 4.9× (30 m) below stage 1, and at 0.26 b at 30 m; asserted 3×
            // and 0.4 b.
            for fused in [paper, ekf] {
                assert!(fused < alone / 3.0, "bias {bias}: {fused} vs {alone}");
            }
            if bias > 20.0 {
                assert!(paper < 0.4 * bias && ekf < 0.4 * bias, "{paper}, {ekf}");
            }
        }
        // Reported: stage 2 sees the inflated stage-1 σ and weighs the member
        // down; measured 2.0× below the silent case, asserted 1.5×.
        let reported = score(&scenario(10.0, true));
        assert!(
            reported[1] < silent[1] / 1.5 && reported[2] < silent[2] / 1.5,
            "reported {reported:?}, silent {silent:?}"
        );
    }
}
