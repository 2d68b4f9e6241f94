//! `aidnav tune`: the noise of a log's configuration, tuned and written.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::*;
use crate::process::tune::TuneResult;

/// Inputs of `aidnav tune`.
#[derive(Debug, Clone)]
pub struct TuneJob {
    /// The configuration file (`aidnav process`'s).
    pub config: PathBuf,
    /// Replaces the configuration's `data.dir`.
    pub data_dir: Option<PathBuf>,
    /// Output directory.
    pub out: PathBuf,
    /// Replaces `tune.max_evaluations`.
    pub max_evaluations: Option<usize>,
}

/// What `aidnav tune` found.
#[derive(Debug, Clone, Serialize)]
pub struct TuneReport {
    /// IMU samples read.
    pub imu_samples: usize,
    /// GNSS epochs read.
    pub gnss_epochs: usize,
    /// The tuning: Allan deviation, start, fitted values, likelihoods.
    pub tuning: TuneResult,
    /// Reader warnings and the tuning's notes.
    pub warnings: Vec<String>,
    /// Wall time \[s\]: reading, standstill + Allan deviation, likelihood
    /// search.
    pub timing_s: [f64; 3],
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Run `aidnav tune CONFIG.toml`: read the log the configuration names
/// (unsmoothed), tune its noise ([`crate::process::tune::tune`]) and write
/// `allan.svg`, `allan.csv` (with a standstill long enough),
/// `tuned_noise.toml` and `summary.json` (seed null: nothing random).
pub fn tune(job: &TuneJob) -> JobResult<TuneReport> {
    use crate::process::{Inputs, ProcessConfig, export};
    use std::time::Instant;
    let (mut cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&job.config)?;
    if let Some(d) = &job.data_dir {
        cfg.data.dir = d.clone();
    }
    if let Some(n) = job.max_evaluations {
        if n == 0 {
            return Err(JobError::Refused(
                "--max-evaluations must be at least 1".into(),
            ));
        }
        cfg.tune.max_evaluations = n;
    }
    let base = job.config.parent().unwrap_or(Path::new("."));
    let t_read = Instant::now();
    let inputs = Inputs::load_unsmoothed(&cfg, base).map_err(process_error)?;
    let read_s = t_read.elapsed().as_secs_f64();
    let tuning = crate::process::tune::tune(&cfg, &inputs).map_err(process_error)?;
    aidnav_io::writers::begin_outputs(&job.out)?;
    let name = job.config.file_name().map_or_else(
        || job.config.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let (files, written) = export::write_tune_files(&tuning, &job.out, &name)?;
    let mut warnings = inputs.warnings.clone();
    warnings.extend(tuning.notes.iter().cloned());
    warnings.extend(written);
    // The Allan charts are written only when the log has a standstill
    // long enough: an earlier tuning's would otherwise pass for this one's.
    warnings.extend(aidnav_io::writers::remove_stale_outputs(
        &job.out,
        &["allan.svg", "allan.csv"],
        &files,
    )?);
    let mut report = TuneReport {
        imu_samples: inputs.imu.len(),
        gnss_epochs: inputs.gnss.len(),
        timing_s: [read_s, tuning.timing_s[0], tuning.timing_s[1]],
        tuning,
        warnings,
        files,
    };
    let mut summary = Summary::new("tune", VERSION, None, &cfg);
    summary.insert("result", &report);
    report.files.push(summary.write(&job.out)?);
    Ok(report)
}
