//! `aidnav process`: a recorded log, filtered, scored and written.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::*;

/// What `aidnav process` measured.
#[derive(Debug, Clone, Serialize)]
pub struct ProcessReport {
    /// IMU samples used.
    pub imu_samples: usize,
    /// GNSS epochs.
    pub gnss_epochs: usize,
    /// Policy of the GNSS updates in the main run and the outage scores.
    pub policy: crate::process::PolicyName,
    /// RMS 3-D antenna error over RTK-fixed epochs, all GNSS used \[m\].
    pub tracking_rms_m: f64,
    /// Updates by outcome in the clean run.
    pub outcomes: Vec<(String, usize)>,
    /// The recovery's resets in the clean run (see `gnss.recovery`).
    pub recovery: RecoveryReport,
    /// RMS 3-D error of the RTS-smoothed antenna positions (with `output.smooth`).
    pub tracking_smoothed_rms_m: Option<f64>,
    /// Time after the first fix at which spec 10's rule (δ non-increasing
    /// 15 s, then ≤ threshold) declares the instruments converged, for
    /// δ_thr = 3 % and 1 % (None: never).
    pub instrument_convergence_s: Vec<(f64, Option<f64>)>,
    /// Outage scores (filter coasting).
    pub outages: Vec<crate::process::OutageScore>,
    /// Outage scores of the RTS-smoothed solution (with `output.smooth`).
    pub outages_smoothed: Vec<crate::process::OutageScore>,
    /// Outage scores of the free INS (raw IMU, no instrument correction).
    pub outages_free_ins: Vec<crate::process::OutageScore>,
    /// Outage scores with spec 20's predictors bridging the windows (with
    /// `outage_bridge.enabled`), per predictor.
    pub outages_bridged: Vec<BridgedScores>,
    /// Spec 20's efficiency criterion in the outage windows, per length.
    pub efficiency: Vec<crate::process::EfficiencyScore>,
    /// Fraction of the clean run's epochs at which K_eff > 1 (the
    /// integrated solution is predicted better than GNSS).
    pub k_eff_integrated_fraction: f64,
    /// (fraction, policy, RMS 3-D error over RTK-fixed epochs against the clean fixes).
    pub anomalies: Vec<(f64, crate::process::PolicyName, f64)>,
    /// Resets of the recovery in each run of `anomalies` (same order).
    pub anomaly_resets: Vec<usize>,
    /// (policy, RMS 3-D error over the RTK-fixed epochs with GNSS) with the
    /// 30 s outages and a burst after each; and the same without bursts.
    pub post_outage_bursts: Vec<(crate::process::PolicyName, f64, f64)>,
    /// Resets of the recovery in the runs of `post_outage_bursts` (same
    /// order): with bursts, without.
    pub burst_resets: Vec<[usize; 2]>,
    /// Reader warnings.
    pub warnings: Vec<String>,
    /// Wall time \[s\]: reading, one filter pass, scoring.
    pub timing_s: [f64; 3],
    /// Files written.
    pub files: Vec<PathBuf>,
}

pub use crate::process::BridgedScores;

/// The recovery's resets of one run (`summary.json`'s `result.recovery`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct RecoveryReport {
    /// Resets.
    pub resets: usize,
    /// Each reset: its fix's time and GNSS index, and what it reset.
    pub events: Vec<crate::process::ResetEvent>,
}

/// Run `aidnav process CONFIG.toml`: read the log named in the
/// configuration (`data_dir` replaces its `data.dir`), filter it, write
/// `solution.csv` (per GNSS epoch: antenna position, NED velocity, attitude,
/// σ, NIS, update outcome), `trajectory.svg`, `outage_drift.svg` and
/// `summary.json`; with `score`, also the outage and anomaly tables.
pub fn process(
    config: &Path,
    data_dir: Option<&Path>,
    out: &Path,
    score: bool,
) -> JobResult<ProcessReport> {
    use crate::process::{Inputs, Process, export};
    use std::time::Instant;
    let (mut cfg, _) = aidnav_io::load_toml::<crate::process::ProcessConfig>(config)?;
    if let Some(d) = data_dir {
        cfg.data.dir = d.to_path_buf();
    }
    let base = config.parent().unwrap_or(Path::new("."));
    let t_read = Instant::now();
    let inputs = Inputs::load(&cfg, base).map_err(process_error)?;
    let read_s = t_read.elapsed().as_secs_f64();
    let process = Process::new(cfg, inputs).map_err(process_error)?;
    let t_run = Instant::now();
    let result = process.run().map_err(process_error)?;
    let run_s = t_run.elapsed().as_secs_f64();
    let t_score = Instant::now();
    let scores = if score {
        Some(process.score().map_err(process_error)?)
    } else {
        None
    };
    let score_s = t_score.elapsed().as_secs_f64();
    let cfg = process.config();
    aidnav_io::writers::begin_outputs(out)?;
    let (files, written) =
        export::write_files(&result, scores.as_ref(), out, cfg.output.kf_gins_text)?;
    let mut report = ProcessReport::new(
        result,
        scores.unwrap_or_default(),
        [read_s, run_s, score_s],
        files,
    );
    report.warnings.extend(written);
    if !report.tracking_rms_m.is_finite() {
        report.warnings.push(format!(
            "the RMS 3-D antenna error over RTK-fixed epochs is {} (no finite error to average)",
            report.tracking_rms_m
        ));
    }
    let path = export::write_summary(out, cfg, &report)?;
    report.files.push(path);
    Ok(report)
}

impl ProcessReport {
    /// The report of a result and its scores (empty when not scored).
    pub fn new(
        result: crate::process::ProcessResult,
        scores: crate::process::Scores,
        timing_s: [f64; 3],
        files: Vec<PathBuf>,
    ) -> Self {
        Self {
            imu_samples: result.imu_samples,
            gnss_epochs: result.gnss_epochs,
            policy: result.policy,
            tracking_rms_m: result.tracking_rms_m,
            outcomes: result.outcomes,
            recovery: RecoveryReport {
                resets: result.resets.len(),
                events: result.resets,
            },
            tracking_smoothed_rms_m: result.tracking_smoothed_rms_m,
            instrument_convergence_s: result.instrument_convergence_s,
            outages: scores.outages,
            outages_smoothed: scores.outages_smoothed,
            outages_free_ins: scores.outages_free_ins,
            outages_bridged: scores.outages_bridged,
            efficiency: scores.efficiency,
            k_eff_integrated_fraction: result.k_eff_integrated_fraction,
            anomalies: scores.anomalies,
            post_outage_bursts: scores.post_outage_bursts,
            anomaly_resets: scores.anomaly_resets,
            burst_resets: scores.burst_resets,
            warnings: result.warnings.into_iter().chain(scores.warnings).collect(),
            timing_s,
            files,
        }
    }
}

fn process_error(e: crate::process::ProcessError) -> JobError {
    match e {
        crate::process::ProcessError::Io(io) => JobError::Io(io),
        crate::process::ProcessError::Estimation(source) => estimation("GNSS/INS filter")(source),
        crate::process::ProcessError::Data(m) => JobError::Refused(m),
    }
}
