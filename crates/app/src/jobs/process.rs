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
    /// Epochs of the main run whose fix is a reference
    /// (`score.reference_quality`; RTK fixed by default).
    pub reference_epochs: usize,
    /// RMS 3-D antenna error over the reference epochs, all GNSS used \[m\]
    /// (null: no reference epoch).
    pub tracking_rms_m: Option<f64>,
    /// Updates by outcome in the clean run.
    pub outcomes: Vec<(String, usize)>,
    /// How and when the filter started.
    pub start: crate::process::StartSummary,
    /// Standstill (zero-velocity + zero-angular-rate) updates in the clean run.
    pub standstill_updates: usize,
    /// What every aid source of the clean run did: per measurement stream (`name`)
    /// the measurements it passed to the filter (`fused`), of those
    /// `accepted`, `rejected`, `modified` (limited or re-weighted) and
    /// `reset`, and the samples it did not fuse (`skipped`).
    pub aid_sources: Vec<aidnav_integration::aiding::SourceStatus>,
    /// The filter's added states at the end of the clean run: per state
    /// its `name` (`gnss_latency`, `wheel_speed_scale`, `baro_bias` …),
    /// `unit`, estimate `value`, `sigma` and `prior_sigma`.
    pub install: Vec<aidnav_integration::state::AddedStateEstimate>,
    /// RMS 3-D error of the RTS-smoothed antenna positions over the
    /// reference epochs (null: not smoothed, or no reference).
    pub tracking_smoothed_rms_m: Option<Option<f64>>,
    /// The recovery's resets in the clean run (see `gnss.recovery`).
    pub recovery: RecoveryReport,
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
    /// Is the covariance honest? `consistency.outages[]`: per outage length
    /// (`outage_s`) the coasting filter's reference epochs in the windows
    /// (`epochs`), the fraction whose 3-D antenna error lies inside the
    /// filter's 99 % ellipsoid (`inside_99_fraction`, NEES ≤ `chi2_99`) and
    /// the mean position NEES (`mean_nees`, `nees_dof` = 3 for an honest
    /// covariance); `consistency.all_gnss`: the mean position NIS per degree
    /// of freedom of the main run (`mean_nis_per_dof`, 1 when honest) over
    /// its `epochs` updates; `consistency.outages_smoothed[]`: the outages'
    /// figures for the RTS-smoothed solution against the smoother's
    /// covariance (with `output.smooth`). See [`crate::process::consistency`].
    pub consistency: crate::process::Consistency,
    /// Fraction of the clean run's epochs at which K_eff > 1 (the
    /// integrated solution is predicted better than GNSS).
    pub k_eff_integrated_fraction: f64,
    /// The efficiency criterion applied per parameter (`selected.csv`):
    /// `epochs`, `position_integrated_fraction`,
    /// `velocity_integrated_fraction`, `position_switches`,
    /// `velocity_switches`. See [`crate::process::selection`].
    pub selection: crate::process::SelectionSummary,
    /// (fraction, policy, RMS 3-D error over the reference epochs against
    /// the clean fixes; null: no reference or the run failed).
    pub anomalies: Vec<(f64, crate::process::PolicyName, Option<f64>)>,
    /// (policy, RMS 3-D error over the reference epochs with GNSS) with the
    /// 30 s outages and a burst after each; and the same without bursts
    /// (null: no reference or the run failed).
    pub post_outage_bursts: Vec<(crate::process::PolicyName, Option<f64>, Option<f64>)>,
    /// Resets of the recovery in each run of `anomalies` (same order).
    pub anomaly_resets: Vec<usize>,
    /// Resets of the recovery in the runs of `post_outage_bursts` (same
    /// order): with bursts, without.
    pub burst_resets: Vec<[usize; 2]>,
    /// Every warning of the run, its scoring and its outputs: `kind`
    /// (`input`, `divergence`, `rejection_run`, `levelling_while_moving`,
    /// `implausible_units`, `scoring_run`, `output`), `message`, and the
    /// stretch it concerns (`start_s`, `end_s`, GPST s, or null). See
    /// [`crate::process::warnings`].
    pub warnings: Vec<crate::process::Warning>,
    /// The tuning made first with `[imu.noise] auto` (the run used its
    /// fitted noise and GNSS σ scale); None: the configured noise.
    pub tuning: Option<crate::process::tune::TuneResult>,
    /// Wall time \[s\]: reading (and tuning, with `auto`), one filter
    /// pass, scoring. Without scoring the filter pass's time includes
    /// writing the tables ([`ProcessRun::run_writing`]).
    pub timing_s: [f64; 3],
    /// Files written.
    pub files: Vec<PathBuf>,
}

use crate::process::BridgedScores;
use crate::process::{Warning, WarningKind};

impl ProcessReport {
    /// The warnings `aidnav process --strict` fails on
    /// ([`WarningKind::fails_strict`]: all but the readers' notes and the
    /// comparison tables' failed runs).
    pub fn strict_failures(&self) -> impl Iterator<Item = &Warning> {
        self.warnings.iter().filter(|w| w.kind.fails_strict())
    }
}

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
/// `summary.json`; with `score`, also the outage and anomaly tables. With
/// `[imu.noise] auto` the noise is tuned first ([`crate::process::tune`];
/// `allan.svg`, `allan.csv`, `tuned_noise.toml` too, `result.tuning` in
/// `summary.json`) and the run uses the fitted values.
pub fn process(
    config: &Path,
    data_dir: Option<&Path>,
    out: &Path,
    score: bool,
) -> JobResult<ProcessReport> {
    use std::time::Instant;
    let (mut cfg, _) = aidnav_io::load_toml::<crate::process::ProcessConfig>(config)?;
    if let Some(d) = data_dir {
        cfg.data.dir = d.to_path_buf();
    }
    let base = config.parent().unwrap_or(Path::new("."));
    let t_read = Instant::now();
    let process = crate::process::Process::load(cfg, base).map_err(process_error)?;
    let read_s = t_read.elapsed().as_secs_f64();
    let name = config.file_name().map_or_else(
        || config.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    if score {
        ProcessRun::run(process, score, read_s)?.write(out, &name)
    } else {
        ProcessRun::run_writing(process, read_s, out, &name)
    }
}

/// A processed log: the [`crate::process::Process`] (configuration and
/// inputs), its result and scores, before anything is written. What
/// `aidnav process` and the Python package's `process` share.
#[derive(Debug, Clone)]
pub struct ProcessRun {
    /// The log and its configuration (tuned with `[imu.noise] auto`).
    pub process: crate::process::Process,
    /// The filter pass over the whole log.
    pub result: crate::process::ProcessResult,
    /// Its scores (None: not scored).
    pub scores: Option<crate::process::Scores>,
    /// Wall time \[s\]: reading (and tuning), one filter pass, scoring.
    pub timing_s: [f64; 3],
}

impl ProcessRun {
    /// Filter (and with `score`, score) a log; `read_s` is the time its
    /// reading took, for the report.
    pub fn run(process: crate::process::Process, score: bool, read_s: f64) -> JobResult<Self> {
        use std::time::Instant;
        let t_run = Instant::now();
        let result = aidnav_sim::Cancel::catch(|| process.run())?.map_err(process_error)?;
        let run_s = t_run.elapsed().as_secs_f64();
        let t_score = Instant::now();
        let scores = if score {
            Some(aidnav_sim::Cancel::catch(|| process.score())?.map_err(process_error)?)
        } else {
            None
        };
        let score_s = t_score.elapsed().as_secs_f64();
        Ok(Self {
            process,
            result,
            scores,
            timing_s: [read_s, run_s, score_s],
        })
    }

    /// [`run`](Self::run) without scoring, then [`write`](Self::write),
    /// the forward tables and charts written on other threads while this
    /// one smooths the log and writes `smoothed.csv`
    /// ([`Process::run_forward`](crate::process::Process::run_forward)):
    /// the same files and report. The run's time (`timing_s[1]`) then
    /// includes the writing. When smoothing fails, its error is returned
    /// and the forward files stay written, without `summary.json` (as a
    /// run that fails leaves its outputs).
    pub fn run_writing(
        process: crate::process::Process,
        read_s: f64,
        out: &Path,
        config_name: &str,
    ) -> JobResult<ProcessReport> {
        use crate::process::export;
        use std::time::Instant;
        let t_run = Instant::now();
        let navresult = process.config().output.kf_gins_text;
        let (mut result, smoothing) =
            aidnav_sim::Cancel::catch(|| process.run_forward())?.map_err(process_error)?;
        // The smoother's worker finishes recording before the writers
        // below take the second core (it caught up at a quarter of a core
        // beside them).
        if let Some(s) = &smoothing {
            s.catch_up();
        }
        // Before any thread writes: the directory, no stale summary.json.
        aidnav_io::writers::begin_outputs(out)?;
        let (forward, smoothed) = std::thread::scope(|s| {
            let forward = s.spawn(|| export::write_forward_files(&result, None, out, navresult));
            let smoothed = smoothing
                .map(|smoothing| -> JobResult<_> {
                    let smoothed = smoothing.finish(&result).map_err(process_error)?;
                    let table = export::write_smoothed_file(smoothed.epochs(), out);
                    Ok((smoothed, table))
                })
                .transpose();
            // A panic on the other thread is re-raised here, as it would
            // have been on this one.
            let forward = forward
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (forward, smoothed)
        });
        // The errors in the order of a run written after it: smoothing's,
        // then the forward tables', then smoothed.csv's.
        let (smoothed, table) = match smoothed? {
            Some((smoothed, table)) => (Some(smoothed), Some(table)),
            None => (None, None),
        };
        let forward = forward?;
        let table = table.transpose()?.flatten();
        if let Some(smoothed) = smoothed {
            smoothed.apply_to(&mut result);
        }
        let run_s = t_run.elapsed().as_secs_f64();
        let (files, written) = forward.with_smoothed(table);
        let run = Self {
            process,
            result,
            scores: None,
            timing_s: [read_s, run_s, 0.0],
        };
        run.finish_writing(out, config_name, files, written)
    }

    /// The report `summary.json` holds under `result`, with `files` listed
    /// and the writers' warnings (kind `output`) added.
    pub fn report(&self, files: Vec<PathBuf>, written: Vec<String>) -> ProcessReport {
        let mut report = ProcessReport::new(
            report_fields(&self.result),
            self.scores.clone().unwrap_or_default(),
            self.timing_s,
            files,
        );
        report.warnings.extend(
            written
                .into_iter()
                .map(|w| Warning::new(WarningKind::Output, w)),
        );
        report.tuning = self.process.tuning().cloned();
        if let Some(t) = &report.tuning {
            report.warnings.extend(
                t.notes
                    .iter()
                    .map(|n| Warning::new(WarningKind::Input, n.clone())),
            );
        }
        if let Some(rms) = report.tracking_rms_m.filter(|v| !v.is_finite()) {
            report.warnings.push(Warning::new(
                WarningKind::Divergence,
                format!(
                    "the RMS 3-D antenna error over the reference epochs is {rms} (no finite error to average)"
                ),
            ));
        }
        report
    }

    /// `summary.json` as a value: the configuration as used and `report`
    /// under `result`.
    pub fn summary(&self, report: &ProcessReport) -> Summary {
        crate::process::export::summary(self.process.config(), report)
    }

    /// Write every file `aidnav process` writes into `out` (`config_name`
    /// names the configuration in `tuned_noise.toml`) and return the report.
    pub fn write(&self, out: &Path, config_name: &str) -> JobResult<ProcessReport> {
        use crate::process::export;
        let cfg = self.process.config();
        // write_files creates `out` and removes a stale summary.json first.
        let (files, written) = export::write_files(
            &self.result,
            self.scores.as_ref(),
            out,
            cfg.output.kf_gins_text,
        )?;
        self.finish_writing(out, config_name, files, written)
    }

    /// [`write`](Self::write) after the tables and charts (`files`, with
    /// their warnings `written`): the tuning's files, the removal of the
    /// optional files an earlier run left ([`export::OPTIONAL_FILES`](crate::process::export::OPTIONAL_FILES),
    /// noted as warnings), the report and `summary.json`.
    fn finish_writing(
        &self,
        out: &Path,
        config_name: &str,
        mut files: Vec<PathBuf>,
        mut written: Vec<String>,
    ) -> JobResult<ProcessReport> {
        use crate::process::export;
        let cfg = self.process.config();
        if let Some(t) = self.process.tuning() {
            let (f, w) = export::write_tune_files(t, out, config_name)?;
            files.extend(f);
            written.extend(w);
        }
        written.extend(aidnav_io::writers::remove_stale_outputs(
            out,
            &export::OPTIONAL_FILES,
            &files,
        )?);
        let mut report = self.report(files, written);
        let path = export::write_summary(out, cfg, &report)?;
        report.files.push(path);
        Ok(report)
    }
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
            reference_epochs: result.reference_epochs,
            tracking_rms_m: result.tracking_rms_m,
            outcomes: result.outcomes,
            start: result.start,
            standstill_updates: result.standstill_updates,
            aid_sources: result.aid_sources,
            install: result.install,
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
            consistency: crate::process::Consistency {
                outages: scores.consistency,
                outages_smoothed: scores.consistency_smoothed,
                all_gnss: result.nis,
                ..crate::process::Consistency::default()
            },
            k_eff_integrated_fraction: result.k_eff_integrated_fraction,
            selection: result.selection,
            anomalies: scores.anomalies,
            post_outage_bursts: scores.post_outage_bursts,
            tuning: None,
            anomaly_resets: scores.anomaly_resets,
            burst_resets: scores.burst_resets,
            warnings: result.warnings.into_iter().chain(scores.warnings).collect(),
            timing_s,
            files,
        }
    }
}

/// The fields of a result that [`ProcessReport::new`] reads, cloned; the
/// per-epoch tables (epochs, rows, smoothed and selected epochs, the fix
/// track: megabytes on a long log) left empty.
fn report_fields(result: &crate::process::ProcessResult) -> crate::process::ProcessResult {
    let r = result;
    crate::process::ProcessResult {
        imu_samples: r.imu_samples,
        gnss_epochs: r.gnss_epochs,
        policy: r.policy,
        epochs: Vec::new(),
        between: Vec::new(),
        smoothed: Vec::new(),
        fix_track: Vec::new(),
        first_fix_time_s: r.first_fix_time_s,
        outcomes: r.outcomes.clone(),
        resets: r.resets.clone(),
        reference_epochs: r.reference_epochs,
        tracking_rms_m: r.tracking_rms_m,
        tracking_smoothed_rms_m: r.tracking_smoothed_rms_m,
        nis: r.nis.clone(),
        instrument_convergence_s: r.instrument_convergence_s.clone(),
        k_eff_integrated_fraction: r.k_eff_integrated_fraction,
        selected: Vec::new(),
        selection: r.selection,
        start: r.start,
        standstill_updates: r.standstill_updates,
        aid_sources: r.aid_sources.clone(),
        aid_updates: Vec::new(),
        install: r.install.clone(),
        warnings: r.warnings.clone(),
    }
}

pub(super) fn process_error(e: crate::process::ProcessError) -> JobError {
    match e {
        crate::process::ProcessError::Io(io) => JobError::Io(io),
        crate::process::ProcessError::Estimation(source) => estimation("GNSS/INS filter")(source),
        crate::process::ProcessError::Data(m) => JobError::Refused(m),
    }
}
