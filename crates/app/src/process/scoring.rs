//! Every scoring run of a log: simulated outages (coasting filter, free INS,
//! smoothed, bridged), the efficiency criterion, injected outliers under
//! every policy, bursts after outages. Each run prepares its plan
//! ([`RunPlan`]) and runs the ordinary loop; the runs go in parallel.

use aidnav_sim::Cancel;
use std::sync::Mutex;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use super::config::{BRIDGE_PREDICTORS, PolicyName};
use super::consistency::{OutageConsistency, outage_consistency};
use super::run::{Epoch, RunPlan, reset_events, run_filter};
use super::score::{
    EfficiencyScore, OutageScore, bridged_epochs, efficiency_in_windows, inject_outliers,
    is_reference, outage_windows, post_outage_bursts, score_windows, tracking_rms,
    tracking_rms_with_gnss,
};
use super::warnings::{Warning, WarningKind};
use super::{Inputs, ProcessConfig, ProcessError};

/// Outage scores of one bridging predictor.
#[derive(Debug, Clone, Serialize)]
pub struct BridgedScores {
    /// The predictor.
    pub predictor: aidnav_supervisors::outage::Predictor,
    /// Per outage length, as the coasting filter's.
    pub scores: Vec<OutageScore>,
}

/// The 3-D antenna error of the coasting filter through one outage length's
/// windows, for the drift plot (time since the first IMU sample \[s\]).
#[derive(Debug, Clone, PartialEq)]
pub struct DriftSeries {
    /// L \[s\].
    pub outage_s: f64,
    /// (time, 3-D error \[m\], floored at 1 mm) per epoch.
    pub error_m: Vec<(f64, f64)>,
    /// (time, 3σ of the 3-D position \[m\], floored at 1 mm) per epoch.
    pub three_sigma_m: Vec<(f64, f64)>,
}

/// Everything scoring measures (see [`super::Process::score`]).
#[derive(Debug, Clone, Default)]
pub struct Scores {
    /// Outage scores (filter coasting), per length.
    pub outages: Vec<OutageScore>,
    /// Outage scores of the RTS-smoothed solution (with `output.smooth`).
    pub outages_smoothed: Vec<OutageScore>,
    /// Outage scores of the free INS (raw IMU, no instrument correction).
    pub outages_free_ins: Vec<OutageScore>,
    /// Outage scores with spec 20's predictors bridging the windows (with
    /// `outage_bridge.enabled`), per predictor.
    pub outages_bridged: Vec<BridgedScores>,
    /// Spec 20's efficiency criterion in the outage windows, per length.
    pub efficiency: Vec<EfficiencyScore>,
    /// The coasting filter's covariance against its actual error in the
    /// outage windows, per length.
    pub consistency: Vec<OutageConsistency>,
    /// The same for the RTS-smoothed solution and its covariance (with
    /// `output.smooth`).
    pub consistency_smoothed: Vec<OutageConsistency>,
    /// (fraction, policy, RMS 3-D error over the reference epochs against
    /// the clean fixes; None: no reference, NaN: the run failed).
    pub anomalies: Vec<(f64, PolicyName, Option<f64>)>,
    /// (policy, RMS 3-D error over the reference epochs with GNSS) with the
    /// 30 s outages and a burst after each; and the same without bursts
    /// (None: no reference, NaN: the run failed).
    pub post_outage_bursts: Vec<(PolicyName, Option<f64>, Option<f64>)>,
    /// Resets of the recovery in each run of `anomalies` (same order).
    pub anomaly_resets: Vec<usize>,
    /// Resets of the recovery in the runs of `post_outage_bursts` (same
    /// order): with bursts, without.
    pub burst_resets: Vec<[usize; 2]>,
    /// The coasting filter's drift per outage length.
    pub drift: Vec<DriftSeries>,
    /// Runs that failed (their score is NaN), and why (kind `scoring_run`).
    pub warnings: Vec<Warning>,
}

/// Score a log: every table of [`Scores`].
pub fn score_log(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    cancel: &Cancel,
) -> Result<Scores, ProcessError> {
    let mut scores = Scores::default();
    outage_scores(cfg, inputs, cancel, &mut scores)?;
    // A policy other than the configured one may make the filter fail
    // on corrupted data (eq. 4's gain, say): that is a result of the
    // table (NaN, and a warning saying why), not a reason to stop.
    let failures = Mutex::new(Vec::new());
    let scored_or_nan = |what: String, run: Result<Option<f64>, ProcessError>| {
        run.unwrap_or_else(|e| {
            failures
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
                .push(Warning::new(
                    WarningKind::ScoringRun,
                    format!("{what}: {e}"),
                ));
            Some(f64::NAN)
        })
    };
    let anomalies = anomaly_scores(cfg, inputs, cancel, &scored_or_nan);
    scores.anomaly_resets = anomalies.iter().map(|a| a.3).collect();
    scores.anomalies = anomalies
        .into_iter()
        .map(|(f, p, rms, _)| (f, p, rms))
        .collect();
    let bursts = burst_scores(cfg, inputs, cancel, &scored_or_nan);
    scores.burst_resets = bursts.iter().map(|b| [b.1.1, b.2.1]).collect();
    scores.post_outage_bursts = bursts
        .into_iter()
        .map(|(p, burst, clean)| (p, burst.0, clean.0))
        .collect();
    scores.warnings = failures
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    Ok(scores)
}

/// (L, free INS?, the windows of L)
type OutagePlan = (f64, bool, Vec<(f64, f64)>);

/// One outage plan's results: everything [`Scores`] takes from its run,
/// computed as soon as the run ends so that its epochs are freed then (a
/// run's epochs, kept for all six plans until the last finished, were a
/// quarter of a scored run's peak memory).
struct PlanScores {
    /// Free INS in the windows?
    free: bool,
    /// The outage score of the run.
    score: OutageScore,
    /// Score and consistency of the smoothed solution (with `output.smooth`).
    smoothed: Option<(OutageScore, OutageConsistency)>,
    /// Per bridging predictor, the bridged score (coasting runs).
    bridged: Vec<OutageScore>,
    /// The efficiency criterion (coasting runs).
    efficiency: Option<EfficiencyScore>,
    /// The consistency of the coasting filter (coasting runs).
    consistency: Option<OutageConsistency>,
    /// The drift series (coasting runs).
    drift: Option<DriftSeries>,
}

/// What a scoring run reports: its score (None: no reference) or why it failed.
type ScoredOrNan<'a> = dyn Fn(String, Result<Option<f64>, ProcessError>) -> Option<f64> + Sync + 'a;

/// The outage tables and the drift series.
fn outage_scores(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    cancel: &Cancel,
    scores: &mut Scores,
) -> Result<(), ProcessError> {
    let first = inputs.imu[0].time_s;
    let last = inputs.gnss[inputs.gnss.len() - 1].time_s;
    let reference = &cfg.score.reference_quality;
    let plans: Vec<OutagePlan> = cfg
        .score
        .outages_s
        .iter()
        .flat_map(|&l| {
            let windows = outage_windows(&cfg.score, first, last, l);
            [(l, false, windows.clone()), (l, true, windows)]
        })
        .collect();
    let bridges = if cfg.outage_bridge.enabled {
        BRIDGE_PREDICTORS.len()
    } else {
        0
    };
    // One smoothed run at a time: the smoother's storage of a pass is the
    // largest allocation of a run, and two at once would double the peak.
    // (The lock is held only around `run_filter`, which starts no rayon
    // work, so a worker waiting for it cannot block the holder.)
    let smoothing = Mutex::new(());
    let scored: Vec<PlanScores> = plans
        .par_iter()
        .map(|(l, free, windows)| {
            let (l, free) = (*l, *free);
            let plan = RunPlan {
                windows: windows.clone(),
                free_ins_in_windows: free,
                smooth: cfg.output.smooth,
                bridge: cfg.outage_bridge.enabled,
                cancel: cancel.clone(),
                ..RunPlan::default()
            };
            // (A free-INS run is never smoothed.)
            let epochs = if cfg.output.smooth && !free {
                let _one_at_a_time = smoothing
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                run_filter(cfg, inputs, &plan, cfg.gnss.policy)?.epochs
            } else {
                run_filter(cfg, inputs, &plan, cfg.gnss.policy)?.epochs
            };
            let score = score_windows(&epochs, windows, l, reference);
            if free {
                return Ok(PlanScores {
                    free,
                    score,
                    smoothed: None,
                    bridged: Vec::new(),
                    efficiency: None,
                    consistency: None,
                    drift: None,
                });
            }
            let smoothed: Vec<Epoch> = epochs.iter().filter_map(|e| e.smoothed()).collect();
            let smoothed = (!smoothed.is_empty()).then(|| {
                (
                    score_windows(&smoothed, windows, l, reference),
                    outage_consistency(&smoothed, windows, l, reference),
                )
            });
            let bridged = (0..bridges)
                .map(|k| score_windows(&bridged_epochs(&epochs, k), windows, l, reference))
                .collect();
            Ok(PlanScores {
                free,
                score,
                smoothed,
                bridged,
                efficiency: Some(efficiency_in_windows(&epochs, windows, l, reference)),
                consistency: Some(outage_consistency(&epochs, windows, l, reference)),
                drift: Some(DriftSeries {
                    outage_s: l,
                    error_m: epochs
                        .iter()
                        .filter(|e| is_reference(&e.fix, reference))
                        .map(|e| {
                            (
                                e.fix.time_s - first,
                                e.fix.position.ned_to(&e.antenna).norm().max(1e-3),
                            )
                        })
                        .collect(),
                    three_sigma_m: epochs
                        .iter()
                        .map(|e| (e.fix.time_s - first, (3.0 * e.sigma.norm()).max(1e-3)))
                        .collect(),
                }),
            })
        })
        .collect::<Result<_, ProcessError>>()?;
    if cfg.outage_bridge.enabled {
        scores.outages_bridged = BRIDGE_PREDICTORS
            .iter()
            .map(|&predictor| BridgedScores {
                predictor,
                scores: Vec::new(),
            })
            .collect();
    }
    for plan in scored {
        if plan.free {
            scores.outages_free_ins.push(plan.score);
            continue;
        }
        for (b, score) in scores.outages_bridged.iter_mut().zip(plan.bridged) {
            b.scores.push(score);
        }
        scores.efficiency.extend(plan.efficiency);
        scores.consistency.extend(plan.consistency);
        scores.drift.extend(plan.drift);
        if let Some((score, consistency)) = plan.smoothed {
            scores.outages_smoothed.push(score);
            scores.consistency_smoothed.push(consistency);
        }
        scores.outages.push(plan.score);
    }
    Ok(())
}

/// A run's RMS and its recovery resets (NaN and 0 when it failed).
type RmsResets = (Option<f64>, usize);

/// Injected outliers under every policy: (fraction, policy, RMS, resets).
fn anomaly_scores(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    cancel: &Cancel,
    scored_or_nan: &ScoredOrNan<'_>,
) -> Vec<(f64, PolicyName, Option<f64>, usize)> {
    let policies = PolicyName::ALL;
    let mut cases: Vec<(f64, PolicyName)> = policies.iter().map(|&p| (0.0, p)).collect();
    for &f in &cfg.score.outlier_fractions {
        cases.extend(policies.iter().map(|&p| (f, p)));
    }
    cases
        .par_iter()
        .map(|&(f, p)| {
            let plan = RunPlan {
                outliers: inject_outliers(
                    inputs.gnss.len(),
                    f,
                    cfg.score.outlier_m,
                    cfg.score.seed,
                ),
                cancel: cancel.clone(),
                ..RunPlan::default()
            };
            let (run, resets) =
                rms_and_resets(run_filter(cfg, inputs, &plan, p).map(|r| r.epochs), |e| {
                    tracking_rms(e, &cfg.score.reference_quality)
                });
            let what = format!("{:.0} % outliers, {}", 100.0 * f, p.name());
            (f, p, scored_or_nan(what, run), resets)
        })
        .collect()
}

/// A run's score by `score` and its count of recovery resets (0 when it failed).
fn rms_and_resets(
    run: Result<Vec<Epoch>, ProcessError>,
    score: impl Fn(&[Epoch]) -> Option<f64>,
) -> (Result<Option<f64>, ProcessError>, usize) {
    match run {
        Ok(epochs) => (Ok(score(&epochs)), reset_events(&epochs).len()),
        Err(e) => (Err(e), 0),
    }
}

/// 30 s outages with a burst after each, and without, under every policy:
/// (policy, (RMS, resets) with bursts, without).
fn burst_scores(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    cancel: &Cancel,
    scored_or_nan: &ScoredOrNan<'_>,
) -> Vec<(PolicyName, RmsResets, RmsResets)> {
    // (Written so that a NaN length scores nothing, as `> 0` is false.)
    let scheduled = cfg.score.post_outage_burst_s > 0.0;
    if !scheduled {
        return Vec::new();
    }
    let first = inputs.imu[0].time_s;
    let last = inputs.gnss[inputs.gnss.len() - 1].time_s;
    let windows = outage_windows(&cfg.score, first, last, 30.0);
    let bursts = post_outage_bursts(
        &inputs.gnss,
        &windows,
        cfg.score.post_outage_burst_s,
        cfg.score.outlier_m,
        cfg.score.seed,
    );
    PolicyName::ALL
        .par_iter()
        .map(|&p| {
            let run = |outliers: Vec<Option<Vector3<f64>>>, what: &str| {
                let plan = RunPlan {
                    windows: windows.clone(),
                    outliers,
                    cancel: cancel.clone(),
                    ..RunPlan::default()
                };
                let (run, resets) =
                    rms_and_resets(run_filter(cfg, inputs, &plan, p).map(|r| r.epochs), |e| {
                        tracking_rms_with_gnss(e, &cfg.score.reference_quality)
                    });
                (
                    scored_or_nan(format!("30 s outages {what}, {}", p.name()), run),
                    resets,
                )
            };
            (
                p,
                run(bursts.clone(), "with bursts"),
                run(Vec::new(), "without bursts"),
            )
        })
        .collect()
}
