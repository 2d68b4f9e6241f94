//! The jobs behind the CLI's subcommands: each reads its inputs, runs the
//! library, writes its outputs and returns a report for the CLI to print.
//! The CLI itself only parses arguments and prints.

use std::path::{Path, PathBuf};

use aidnav_estimation::{Chi2Mean, EpochRecord, EstimationError, Observer, Outcome, rts_smooth};
use aidnav_io::IoError;
use aidnav_io::measurements::read_measurements;
use aidnav_io::model_file::load_model;
use aidnav_io::writers::{FilterCsvWriter, Summary, write_smoothed};
use serde::Serialize;

use crate::VERSION;

mod campaign;
mod convert;
mod process;
mod reproduce;
pub mod simulate;
mod tune;
pub mod zoo;

pub use campaign::{Campaign, Experiment, reproduce_summary};
pub use convert::{ConvertReport, convert_kfgins};
use process::process_error;
pub use process::{ProcessReport, ProcessRun, RecoveryReport, process};
pub use reproduce::{
    FormationOutcome, anomalies, anomalies_summary, consistency, consistency_summary,
    extended_state, extended_state_summary, formation, formation_network,
    formation_network_summary, formation_summary, group, group_summary, outages, outages_summary,
};
pub use tune::{TuneJob, TuneReport, tune};

/// Anything a job can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JobError {
    /// Reading or writing files.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The estimation engine (with the file that fed it). The message holds
    /// the engine's error, so it is not also returned as the source (an
    /// error chain prints each level once).
    #[error("{context}: {error}")]
    Estimation {
        /// What was being processed.
        context: String,
        /// The engine's error.
        error: EstimationError,
    },
    /// The extended-state experiment (guidance solution or filter); its
    /// message holds the experiment's error (not also a source).
    #[error("extended-state experiment: {0}")]
    ExtendedState(aidnav_reproduce::extended_state::ExtendedStateError),
    /// The outages experiment (its filter or its model selection); its
    /// message holds the experiment's error (not also a source).
    #[error("outages experiment: {0}")]
    Outages(aidnav_reproduce::outages::OutagesError),
    /// The job refuses the request (size limits and the like).
    #[error("{0}")]
    Refused(String),
    /// The job was cancelled through its [`Cancel`](aidnav_sim::Cancel)
    /// token before it finished.
    #[error("cancelled")]
    Cancelled,
}

impl From<aidnav_sim::Cancelled> for JobError {
    fn from(_: aidnav_sim::Cancelled) -> Self {
        JobError::Cancelled
    }
}

impl From<aidnav_reproduce::extended_state::ExtendedStateError> for JobError {
    fn from(e: aidnav_reproduce::extended_state::ExtendedStateError) -> Self {
        Self::ExtendedState(e)
    }
}

impl From<aidnav_reproduce::outages::OutagesError> for JobError {
    fn from(e: aidnav_reproduce::outages::OutagesError) -> Self {
        Self::Outages(e)
    }
}

/// Result alias of the jobs.
pub type JobResult<T> = Result<T, JobError>;

/// Wrap an engine error with what was being computed.
fn estimation(context: &str) -> impl FnOnce(EstimationError) -> JobError + '_ {
    move |error| JobError::Estimation {
        context: context.into(),
        error,
    }
}

/// Memory the RTS smoother may use for the stored forward pass before the job
/// refuses (two n×n matrices and two n-vectors per epoch).
pub const MAX_SMOOTHER_BYTES: usize = 4 << 30;

/// Inputs of `aidnav filter`.
#[derive(Debug, Clone)]
pub struct FilterJob {
    /// Model TOML.
    pub model: PathBuf,
    /// Measurement CSV.
    pub measurements: PathBuf,
    /// Output directory.
    pub out: PathBuf,
    /// Also run the RTS smoother.
    pub smooth: bool,
    /// Also write the full covariance per epoch.
    pub full_covariance: bool,
    /// Cap on epochs read.
    pub max_epochs: usize,
}

/// What `aidnav filter` reports.
#[derive(Debug, Clone, Serialize)]
pub struct FilterReport {
    /// Epochs processed.
    pub epochs: usize,
    /// State names.
    pub states: Vec<String>,
    /// Final estimate.
    pub final_state: Vec<f64>,
    /// Final 1σ.
    pub final_sigma: Vec<f64>,
    /// Mean NIS over the updates (per degree of freedom: 1 when consistent).
    pub mean_nis_per_dof: f64,
    /// Updates by outcome.
    pub outcomes: std::collections::BTreeMap<String, usize>,
    /// Non-finite numbers written or computed, each naming its file, column
    /// and first epoch (also in `summary.json`; the CLI prints them on stderr).
    pub warnings: Vec<String>,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Accumulates the NIS and outcome counts of a run.
#[derive(Default)]
struct RunStats {
    nis: Chi2Mean,
    finite_nis: usize,
    non_finite_nis: usize,
    first_non_finite_nis: Option<usize>,
    outcomes: std::collections::BTreeMap<String, usize>,
}

impl Observer for RunStats {
    fn observe_epoch(&mut self, r: &EpochRecord) {
        if r.outcome != Outcome::Missing {
            if r.nis.is_finite() {
                self.nis.push(r.nis, r.dof);
                self.finite_nis += 1;
            } else {
                self.non_finite_nis += 1;
                self.first_non_finite_nis.get_or_insert(r.epoch);
            }
        }
        *self
            .outcomes
            .entry(r.outcome.as_str().to_string())
            .or_default() += 1;
    }
}

/// Refuse a smoothing run whose stored forward pass (two n×n matrices and
/// two n-vectors per epoch) would exceed [`MAX_SMOOTHER_BYTES`].
fn check_smoother_memory(measurements: &Path, n: usize, epochs: usize) -> JobResult<()> {
    let per_epoch = (2 * n * n + 2 * n) * std::mem::size_of::<f64>();
    if per_epoch.saturating_mul(epochs) > MAX_SMOOTHER_BYTES {
        return Err(JobError::Refused(format!(
            "{}: smoothing {epochs} epochs of {n} states needs {} MiB for the forward pass, over the {} MiB limit; split the file",
            measurements.display(),
            per_epoch.saturating_mul(epochs) >> 20,
            MAX_SMOOTHER_BYTES >> 20
        )));
    }
    Ok(())
}

/// Warnings for what a filter run produced that is not finite: the mean
/// NIS, epochs whose NIS the mean left out, the final state and σ.
fn non_finite_warnings(
    stats: &RunStats,
    epochs: usize,
    names: &[String],
    final_state: &[f64],
    final_sigma: &[f64],
) -> Vec<String> {
    let mut warnings = Vec::new();
    let mean_nis_per_dof = stats.nis.mean_per_dof();
    if !mean_nis_per_dof.is_finite() {
        warnings.push(format!(
            "mean NIS per degree of freedom is {mean_nis_per_dof} ({} of {epochs} epochs with a finite NIS)",
            stats.finite_nis
        ));
    }
    if stats.non_finite_nis > 0 {
        warnings.push(format!(
            "{} epochs with an update have a non-finite NIS (first at epoch {}); the mean NIS leaves them out",
            stats.non_finite_nis,
            stats.first_non_finite_nis.unwrap_or(0)
        ));
    }
    for (name, (x, s)) in names.iter().zip(final_state.iter().zip(final_sigma)) {
        if !x.is_finite() || !s.is_finite() {
            warnings.push(format!(
                "final state `{name}`: estimate {x}, σ {s} (not finite)"
            ));
        }
    }
    warnings
}

/// Run a linear Kalman filter from a model file over a measurement CSV.
pub fn filter(job: &FilterJob) -> JobResult<FilterReport> {
    let loaded = load_model(&job.model)?;
    let table = read_measurements(&job.measurements, &loaded.measurement_names, job.max_epochs)?;
    if job.smooth {
        check_smoother_memory(&job.measurements, loaded.model.states(), table.len())?;
    }
    aidnav_io::writers::begin_outputs(&job.out)?;
    let mut writer = FilterCsvWriter::create(
        &job.out,
        &loaded.state_names,
        &loaded.measurement_names,
        job.full_covariance,
    )?;
    let mut stats = RunStats::default();
    let mut options = loaded.options;
    options.keep_covariance = job.full_covariance;
    options.keep_forward_pass = job.smooth;
    let out = {
        let mut both = (&mut writer, &mut stats);
        loaded
            .model
            .run(table.epochs(), &options, &mut both)
            .map_err(|error| JobError::Estimation {
                context: format!(
                    "{} with {}",
                    job.model.display(),
                    job.measurements.display()
                ),
                error,
            })?
    };
    let mut warnings = writer.warnings();
    writer.finish()?;
    let mut files = vec![
        job.out.join("estimates.csv"),
        job.out.join("innovations.csv"),
    ];
    if job.full_covariance {
        files.push(job.out.join("covariance.csv"));
    }
    if job.smooth {
        let smoothed = rts_smooth(&out.forward).map_err(|error| JobError::Estimation {
            context: format!("smoothing {}", job.measurements.display()),
            error,
        })?;
        files.push(write_smoothed(
            &job.out,
            &loaded.state_names,
            &table.times,
            &smoothed,
        )?);
    }
    // `covariance.csv` and `smoothed.csv` are written only when asked: an
    // earlier run's would otherwise pass for this one's.
    warnings.extend(aidnav_io::writers::remove_stale_outputs(
        &job.out,
        &["covariance.csv", "smoothed.csv"],
        &files,
    )?);
    let mean_nis_per_dof = stats.nis.mean_per_dof();
    let final_sigma: Vec<f64> = out
        .final_covariance
        .diagonal()
        .iter()
        .map(|v| v.max(0.0).sqrt())
        .collect();
    let final_state: Vec<f64> = out.final_state.iter().copied().collect();
    warnings.extend(non_finite_warnings(
        &stats,
        out.epochs,
        &loaded.state_names,
        &final_state,
        &final_sigma,
    ));
    let report = FilterReport {
        epochs: out.epochs,
        states: loaded.state_names.clone(),
        final_state,
        final_sigma,
        mean_nis_per_dof,
        outcomes: stats.outcomes,
        warnings,
        files: files.clone(),
    };
    let mut summary = Summary::new("filter", VERSION, None, &loaded.file);
    summary.insert("model_file", job.model.display().to_string());
    summary.insert("measurement_file", job.measurements.display().to_string());
    summary.insert("smooth", job.smooth);
    summary.insert("epochs", report.epochs);
    summary.insert("final_state", &report.final_state);
    summary.insert("final_sigma", &report.final_sigma);
    summary.insert("mean_nis_per_dof", report.mean_nis_per_dof);
    summary.insert("outcomes", &report.outcomes);
    summary.insert("warnings", &report.warnings);
    let mut report = report;
    report.files.push(summary.write(&job.out)?);
    Ok(report)
}

/// Monte Carlo settings given beside a scenario (the CLI's `--runs`,
/// `--seed`, and `reproduce all`'s quick run count).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScenarioOverrides {
    /// Number of runs, replacing the scenario's.
    pub runs: Option<usize>,
    /// Master seed, replacing the scenario's.
    pub seed: Option<u64>,
    /// Cap on the scenario's own run count (applied before `runs`).
    pub max_runs: Option<usize>,
}

impl ScenarioOverrides {
    /// Apply to a scenario: the cap first, then the explicit values.
    pub fn apply<S: aidnav_reproduce::MonteCarloScenario>(&self, s: &mut S) {
        if let Some(cap) = self.max_runs {
            let runs = s.runs_mut();
            *runs = (*runs).min(cap);
        }
        if let Some(r) = self.runs {
            *s.runs_mut() = r;
        }
        if let Some(seed) = self.seed {
            *s.seed_mut() = seed;
        }
    }
}

/// The scenario of an experiment — from its TOML file, or the defaults
/// without one — with the overrides applied, then validated (an override
/// out of range is refused with the key, the value and what is allowed).
pub fn load_scenario<S>(path: Option<&Path>, overrides: &ScenarioOverrides) -> JobResult<S>
where
    S: Default
        + serde::de::DeserializeOwned
        + aidnav_io::Validate
        + aidnav_reproduce::MonteCarloScenario,
{
    let mut s = match path {
        Some(p) => aidnav_io::load_toml::<S>(p)?.0,
        None => S::default(),
    };
    overrides.apply(&mut s);
    validated(s)
}

/// A formation scenario file (`aidnav run`), with the overrides applied to
/// its `[formation]` table, validated.
pub fn load_formation_file(
    path: &Path,
    overrides: &ScenarioOverrides,
) -> JobResult<aidnav_reproduce::formation::FormationFile> {
    let mut file = aidnav_io::load_toml::<aidnav_reproduce::formation::FormationFile>(path)?.0;
    overrides.apply(&mut file.formation);
    validated(file)
}

/// `value` if it validates, else the refusal naming the key.
fn validated<T: aidnav_io::Validate>(value: T) -> JobResult<T> {
    value.validate().map_err(|inv| {
        JobError::Refused(format!(
            "{}: {} is out of range: allowed {}",
            inv.key, inv.value, inv.allowed
        ))
    })?;
    Ok(value)
}
