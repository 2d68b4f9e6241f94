//! Result writers: CSV observers for filter runs and `summary.json`.

use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use aidnav_estimation::{EpochRecord, Observer, SmoothedEpoch, nalgebra::Dyn};
use serde::Serialize;

use crate::error::{IoError, Result};

fn write_err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Create `dir` (and parents) if needed.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| write_err(dir, e))
}

fn csv_writer(path: &Path) -> Result<csv::Writer<BufWriter<File>>> {
    let f = File::create(path).map_err(|e| write_err(path, e))?;
    Ok(csv::Writer::from_writer(BufWriter::new(f)))
}

/// Writes a filter run as it happens:
/// `estimates.csv` (epoch, time, each state, each σ),
/// `innovations.csv` (epoch, time, each innovation and its σ, NIS, dof, outcome)
/// and, when asked, `covariance.csv` (upper triangle of P per epoch).
/// Errors are kept and returned by [`finish`](Self::finish): an observer cannot fail mid-run.
pub struct FilterCsvWriter {
    estimates: (PathBuf, csv::Writer<BufWriter<File>>),
    innovations: (PathBuf, csv::Writer<BufWriter<File>>),
    covariance: Option<(PathBuf, csv::Writer<BufWriter<File>>)>,
    states: Vec<String>,
    measurements: Vec<String>,
    error: Option<IoError>,
    row: Vec<String>,
}

impl FilterCsvWriter {
    /// Open the files in `dir`; names label the columns.
    pub fn create(
        dir: &Path,
        states: &[String],
        measurements: &[String],
        full_covariance: bool,
    ) -> Result<Self> {
        ensure_dir(dir)?;
        let est = dir.join("estimates.csv");
        let inn = dir.join("innovations.csv");
        let cov = dir.join("covariance.csv");
        Ok(Self {
            estimates: (est.clone(), csv_writer(&est)?),
            innovations: (inn.clone(), csv_writer(&inn)?),
            covariance: if full_covariance {
                Some((cov.clone(), csv_writer(&cov)?))
            } else {
                None
            },
            states: states.to_vec(),
            measurements: measurements.to_vec(),
            error: None,
            row: Vec::new(),
        })
    }

    fn keep(&mut self, r: std::result::Result<(), (PathBuf, csv::Error)>) {
        if let Err((p, e)) = r
            && self.error.is_none()
        {
            self.error = Some(write_err(&p, e));
        }
    }

    /// Flush and report the first error of the run, if any.
    pub fn finish(mut self) -> Result<()> {
        if let Some(e) = self.error.take() {
            return Err(e);
        }
        let (p, w) = &mut self.estimates;
        w.flush().map_err(|e| write_err(p, e))?;
        let (p, w) = &mut self.innovations;
        w.flush().map_err(|e| write_err(p, e))?;
        if let Some((p, w)) = &mut self.covariance {
            w.flush().map_err(|e| write_err(p, e))?;
        }
        Ok(())
    }
}

fn fmt(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v}")
    }
}

impl Observer for FilterCsvWriter {
    fn observe_init(&mut self, _states: usize, _measurements: usize) {
        let mut h = vec!["epoch".to_string(), "time".to_string()];
        h.extend(self.states.iter().cloned());
        h.extend(self.states.iter().map(|s| format!("sigma_{s}")));
        let (p, w) = &mut self.estimates;
        let r = w.write_record(&h).map_err(|e| (p.clone(), e));
        self.keep(r);
        let mut h = vec!["epoch".to_string(), "time".to_string()];
        h.extend(self.measurements.iter().map(|s| format!("innovation_{s}")));
        h.extend(
            self.measurements
                .iter()
                .map(|s| format!("sigma_innovation_{s}")),
        );
        h.extend(["nis", "dof", "outcome"].map(String::from));
        let (p, w) = &mut self.innovations;
        let r = w.write_record(&h).map_err(|e| (p.clone(), e));
        self.keep(r);
        if self.covariance.is_some() {
            let mut h = vec!["epoch".to_string(), "time".to_string()];
            for i in 0..self.states.len() {
                for j in i..self.states.len() {
                    h.push(format!("P_{}_{}", self.states[i], self.states[j]));
                }
            }
            if let Some((p, w)) = &mut self.covariance {
                let r = w.write_record(&h).map_err(|e| (p.clone(), e));
                self.keep(r);
            }
        }
    }

    fn observe_epoch(&mut self, rec: &EpochRecord) {
        let row = &mut self.row;
        row.clear();
        row.push(rec.epoch.to_string());
        row.push(format!("{}", rec.time));
        row.extend(rec.state.iter().map(|&v| fmt(v)));
        row.extend(rec.sigma.iter().map(|&v| fmt(v)));
        let (p, w) = &mut self.estimates;
        let r1 = w.write_record(&*row).map_err(|e| (p.clone(), e));
        row.clear();
        row.push(rec.epoch.to_string());
        row.push(format!("{}", rec.time));
        row.extend(rec.innovation.iter().map(|&v| fmt(v)));
        row.extend(rec.innovation_sigma.iter().map(|&v| fmt(v)));
        row.push(fmt(rec.nis));
        row.push(rec.dof.to_string());
        row.push(rec.outcome.as_str().to_string());
        let (p, w) = &mut self.innovations;
        let r2 = w.write_record(&*row).map_err(|e| (p.clone(), e));
        let mut r3 = Ok(());
        if let (Some((p, w)), Some(cov)) = (&mut self.covariance, &rec.covariance) {
            row.clear();
            row.push(rec.epoch.to_string());
            row.push(format!("{}", rec.time));
            for i in 0..cov.nrows() {
                for j in i..cov.ncols() {
                    row.push(fmt(cov[(i, j)]));
                }
            }
            r3 = w.write_record(&*row).map_err(|e| (p.clone(), e));
        }
        self.keep(r1);
        self.keep(r2);
        self.keep(r3);
    }
}

/// Write `smoothed.csv`: epoch, time, smoothed states and their σ.
pub fn write_smoothed(
    dir: &Path,
    states: &[String],
    times: &[f64],
    smoothed: &[SmoothedEpoch<Dyn>],
) -> Result<PathBuf> {
    let path = dir.join("smoothed.csv");
    let mut w = csv_writer(&path)?;
    let mut h = vec!["epoch".to_string(), "time".to_string()];
    h.extend(states.iter().cloned());
    h.extend(states.iter().map(|s| format!("sigma_{s}")));
    w.write_record(&h).map_err(|e| write_err(&path, e))?;
    for (k, (t, s)) in times.iter().zip(smoothed).enumerate() {
        let mut row = vec![k.to_string(), format!("{t}")];
        row.extend(s.x.iter().map(|&v| fmt(v)));
        row.extend(s.p.diagonal().iter().map(|&v| fmt(v.max(0.0).sqrt())));
        w.write_record(&row).map_err(|e| write_err(&path, e))?;
    }
    w.flush().map_err(|e| write_err(&path, e))?;
    Ok(path)
}

/// Write a CSV with a header and numeric rows (NaN written as an empty cell).
pub fn write_table(
    path: &Path,
    header: &[&str],
    rows: impl IntoIterator<Item = Vec<f64>>,
) -> Result<()> {
    let mut w = csv_writer(path)?;
    w.write_record(header).map_err(|e| write_err(path, e))?;
    for row in rows {
        if row.len() != header.len() {
            return Err(write_err(
                path,
                format!("row of {} values for {} columns", row.len(), header.len()),
            ));
        }
        w.write_record(row.iter().map(|&v| {
            if v.is_nan() {
                String::new()
            } else {
                format!("{v}")
            }
        }))
        .map_err(|e| write_err(path, e))?;
    }
    w.flush().map_err(|e| write_err(path, e))
}

/// `summary.json`: the tool, its version, the command, the seed, the full
/// scenario echoed back, and the results as further top-level keys.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Always `"aidnav"`.
    pub tool: &'static str,
    /// Version of aidnav that wrote it.
    pub aidnav_version: String,
    /// The subcommand, e.g. `"filter"` or `"reproduce consistency"`.
    pub command: String,
    /// Master seed (null when the command draws no random numbers).
    pub seed: Option<u64>,
    /// The full scenario or model, as parsed (defaults filled in).
    pub scenario: serde_json::Value,
    /// Result keys, flattened to the top level.
    #[serde(flatten)]
    pub results: serde_json::Map<String, serde_json::Value>,
}

impl Summary {
    /// A summary for `command` of aidnav `version`.
    pub fn new(
        command: impl Into<String>,
        version: impl Into<String>,
        seed: Option<u64>,
        scenario: &impl Serialize,
    ) -> Self {
        Self {
            tool: "aidnav",
            aidnav_version: version.into(),
            command: command.into(),
            seed,
            scenario: serde_json::to_value(scenario).unwrap_or(serde_json::Value::Null),
            results: serde_json::Map::new(),
        }
    }

    /// Add a result under `key`.
    pub fn insert(&mut self, key: &str, value: impl Serialize) {
        let v = serde_json::to_value(value).unwrap_or(serde_json::Value::Null);
        self.results.insert(key.to_string(), v);
    }

    /// Write `dir/summary.json` (pretty-printed).
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        ensure_dir(dir)?;
        let path = dir.join("summary.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| write_err(&path, e))?;
        std::fs::write(&path, text + "\n").map_err(|e| write_err(&path, e))?;
        Ok(path)
    }
}
