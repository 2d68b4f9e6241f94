//! `process` and the reproductions: the library's jobs as values.

use std::path::{Path, PathBuf};

use aidnav::app::jobs::{Campaign as RustCampaign, Experiment, ProcessRun, ScenarioOverrides};
use aidnav::app::process::{Inputs, Process, ProcessConfig};
use numpy::PyArray1;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use crate::convert::{interruptible, py_of_json, toml_of};
use crate::errors;
use crate::readers::{gnss_from_columns, imu_from_columns};

/// Add `process` and the campaigns to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ProcessResult>()?;
    m.add_class::<Campaign>()?;
    m.add_function(wrap_pyfunction!(process_log, m)?)?;
    m.add_function(wrap_pyfunction!(experiment_names, m)?)?;
    Ok(())
}

/// A configuration given as a path or a dict: its TOML text, the name it
/// has in errors, and the directory its relative paths start from.
pub(crate) struct Source {
    pub(crate) text: String,
    pub(crate) origin: PathBuf,
    base: PathBuf,
    name: String,
}

pub(crate) fn source(
    config: &Bound<'_, PyAny>,
    base: Option<PathBuf>,
    what: &str,
) -> PyResult<Source> {
    if let Ok(d) = config.cast::<PyDict>() {
        let text = toml_of(d)?;
        let origin = PathBuf::from(format!("<{what} dict>"));
        let base = match base {
            Some(b) => b,
            None => std::env::current_dir()?,
        };
        return Ok(Source {
            text,
            name: origin.display().to_string(),
            origin,
            base,
        });
    }
    let path: PathBuf = config.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{what}: a path to a TOML file or a dict, not {}",
            config
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })?;
    let text = std::fs::read_to_string(&path).map_err(|reason| {
        errors::io(aidnav::io::IoError::Read {
            path: path.clone(),
            reason,
        })
    })?;
    let base = base.unwrap_or_else(|| path.parent().unwrap_or(Path::new(".")).to_path_buf());
    let name = path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    Ok(Source {
        text,
        origin: path,
        base,
        name,
    })
}

/// A processed log (what `aidnav process` computes), before anything is
/// written.
#[pyclass(module = "aidnav._aidnav", frozen)]
pub struct ProcessResult {
    run: ProcessRun,
    config_name: String,
}

fn table<'py>(
    py: Python<'py>,
    (header, rows): (Vec<&'static str>, Vec<Vec<f64>>),
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (j, name) in header.iter().enumerate() {
        let col: Vec<f64> = rows.iter().map(|r| r[j]).collect();
        d.set_item(*name, PyArray1::from_vec(py, col))?;
    }
    Ok(d)
}

#[pymethods]
impl ProcessResult {
    /// `solution.csv`'s columns (per GNSS epoch and the rows between).
    fn solution<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.run.result;
        table(
            py,
            aidnav::app::process::export::solution_table(&r.epochs, &r.between),
        )
    }

    /// `smoothed.csv`'s columns (empty without `output.smooth`).
    fn smoothed<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        table(
            py,
            aidnav::app::process::export::smoothed_table(&self.run.result.smoothed),
        )
    }

    /// `instruments.csv`'s columns.
    fn instruments<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        table(
            py,
            aidnav::app::process::export::instruments_table(&self.run.result.epochs),
        )
    }

    /// The columns of `wheel_speed.csv` or `barometer.csv` (`source`), one
    /// row per update of that stream (empty when the configuration has no
    /// such table).
    fn aid_updates<'py>(&self, py: Python<'py>, source: &str) -> PyResult<Bound<'py, PyDict>> {
        let updates = &self.run.result.aid_updates;
        let t =
            aidnav::app::process::export::aid_updates_table(updates, source).ok_or_else(|| {
                PyValueError::new_err(format!(
                    "no per-update table for {source:?}: \"wheel_speed\" or \"barometer\""
                ))
            })?;
        table(py, t)
    }

    /// `summary.json` as a Python value (no file listed).
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = self.run.report(Vec::new(), Vec::new());
        let summary = self.run.summary(&report);
        let v = serde_json::to_value(&summary).map_err(|e| PyValueError::new_err(e.to_string()))?;
        py_of_json(py, &v)
    }

    /// Write every file `aidnav process` writes into `dir`; returns the
    /// files.
    fn write(&self, py: Python<'_>, dir: PathBuf) -> PyResult<Vec<PathBuf>> {
        let run = &self.run;
        let name = &self.config_name;
        let report = py.detach(|| run.write(&dir, name)).map_err(errors::job)?;
        Ok(report.files)
    }

    /// Whether the log was scored.
    #[getter]
    fn scored(&self) -> bool {
        self.run.scores.is_some()
    }
}

/// `process`: read (or take) a log, filter it and (with `score`) score it.
/// `config` is a TOML path or a dict (relative data paths from `base`:
/// the file's directory, or the current one for a dict); `imu` / `gnss`
/// dicts of columns replace the files the configuration names.
#[pyfunction]
#[pyo3(signature = (config, imu=None, gnss=None, base=None, score=true))]
fn process_log(
    py: Python<'_>,
    config: &Bound<'_, PyAny>,
    imu: Option<&Bound<'_, PyDict>>,
    gnss: Option<&Bound<'_, PyDict>>,
    base: Option<PathBuf>,
    score: bool,
) -> PyResult<ProcessResult> {
    let src = source(config, base, "config")?;
    let cfg: ProcessConfig = aidnav::io::parse_toml(&src.text, &src.origin).map_err(errors::io)?;
    let imu = imu
        .map(|d| imu_from_columns(d, "imu (in memory)"))
        .transpose()?;
    let gnss = gnss
        .map(|d| gnss_from_columns(d, "gnss (in memory)"))
        .transpose()?;
    let base = src.base.clone();
    let run = interruptible(py, move |cancel| -> Result<ProcessRun, PyErrState> {
        let t = std::time::Instant::now();
        let process = if imu.is_none() && gnss.is_none() {
            Process::load(cfg, &base).map_err(PyErrState::process)?
        } else {
            let dir = aidnav::app::process::data_dir(&cfg, &base);
            let mut warnings = Vec::new();
            let (imu, imu_origin) = match imu {
                Some(s) => (s, PathBuf::from("imu (in memory)")),
                None => {
                    let path = dir.join(&cfg.data.imu);
                    let (s, w) = aidnav::app::process::read_configured_imu(&cfg, &dir)
                        .map_err(PyErrState::process)?;
                    warnings.extend(w);
                    (s, path)
                }
            };
            let (gnss, gnss_origin) = match gnss {
                Some(s) => (s, PathBuf::from("gnss (in memory)")),
                None => {
                    let path = dir.join(&cfg.data.gnss);
                    let (s, w) = aidnav::app::process::read_gnss(
                        cfg.data.gnss_format,
                        &path,
                        cfg.data.gnss_sigma_m,
                    )
                    .map_err(PyErrState::process)?;
                    warnings.extend(w);
                    (s, path)
                }
            };
            let inputs =
                Inputs::from_samples(&cfg, imu, gnss, warnings, (&imu_origin, &gnss_origin))
                    .map_err(PyErrState::process)?;
            Process::from_unsmoothed(cfg, inputs).map_err(PyErrState::process)?
        };
        let read_s = t.elapsed().as_secs_f64();
        ProcessRun::run(process.with_cancel(cancel), score, read_s).map_err(PyErrState::job)
    })?
    .map_err(PyErrState::into_err)?;
    Ok(ProcessResult {
        run,
        config_name: src.name,
    })
}

/// An error made off the GIL, raised once it is back.
enum PyErrState {
    Process(aidnav::app::process::ProcessError),
    Job(aidnav::app::jobs::JobError),
}

impl PyErrState {
    fn process(e: aidnav::app::process::ProcessError) -> Self {
        Self::Process(e)
    }
    fn job(e: aidnav::app::jobs::JobError) -> Self {
        Self::Job(e)
    }
    fn into_err(self) -> PyErr {
        match self {
            Self::Process(e) => errors::process(e),
            Self::Job(e) => errors::job(e),
        }
    }
}

/// The names of the reproductions.
#[pyfunction]
fn experiment_names() -> Vec<&'static str> {
    Experiment::ALL.iter().map(|e| e.name()).collect()
}

/// A reproduction's Monte Carlo campaign: its scenario (a TOML path, a
/// dict, or None for the defaults) with `runs` and `seed` overriding the
/// scenario's. `summary()` runs it whole here; `run_chunk(start, end)` runs
/// runs start..end (run k always draws stream k of the seed) and
/// `finish(chunks)` combines the chunks, in run order, into the summary the
/// whole campaign gives, bit for bit.
#[pyclass(module = "aidnav._aidnav", frozen)]
pub struct Campaign {
    campaign: RustCampaign,
}

#[pymethods]
impl Campaign {
    /// The campaign of experiment `name` (`experiment_names()`).
    /// `scenario_text` gives the scenario as TOML text instead (`origin`
    /// names it in errors).
    #[new]
    #[pyo3(signature = (name, scenario=None, runs=None, seed=None, *, scenario_text=None, origin=None))]
    fn new(
        name: &str,
        scenario: Option<&Bound<'_, PyAny>>,
        runs: Option<usize>,
        seed: Option<u64>,
        scenario_text: Option<String>,
        origin: Option<PathBuf>,
    ) -> PyResult<Self> {
        let experiment: Experiment = name.parse().map_err(errors::job)?;
        let src = match (scenario_text, scenario) {
            (Some(text), _) => Some(Source {
                text,
                origin: origin.unwrap_or_else(|| PathBuf::from("<scenario text>")),
                base: PathBuf::from("."),
                name: String::new(),
            }),
            (None, Some(s)) if !s.is_none() => Some(source(s, None, "scenario")?),
            _ => None,
        };
        let overrides = ScenarioOverrides {
            runs,
            seed,
            max_runs: None,
        };
        let campaign = RustCampaign::new(
            experiment,
            src.as_ref().map(|s| (s.text.as_str(), s.origin.as_path())),
            &overrides,
        )
        .map_err(errors::job)?;
        Ok(Self { campaign })
    }

    /// The experiment's name.
    #[getter]
    fn name(&self) -> &'static str {
        self.campaign.experiment().name()
    }

    /// Number of runs.
    #[getter]
    fn runs(&self) -> usize {
        self.campaign.runs()
    }

    /// Whether the runs can be computed in chunks (every reproduction's
    /// can).
    #[getter]
    fn splits(&self) -> bool {
        self.campaign.experiment().splits()
    }

    /// Run the whole campaign here; `summary.json` as a Python value.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let c = self.campaign.clone();
        let s = interruptible(py, move |cancel| c.with_cancel(cancel).summary())?
            .map_err(errors::job)?;
        let v = serde_json::to_value(&s).map_err(|e| PyValueError::new_err(e.to_string()))?;
        py_of_json(py, &v)
    }

    /// Runs `start..end` as bytes for `finish`.
    fn run_chunk<'py>(
        &self,
        py: Python<'py>,
        start: usize,
        end: usize,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let c = self.campaign.clone();
        let bytes = interruptible(py, move |cancel| {
            c.with_cancel(cancel).run_chunk(start..end)
        })?
        .map_err(errors::job)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// The summary of the whole campaign from its chunks in run order.
    fn finish<'py>(&self, py: Python<'py>, chunks: Vec<Vec<u8>>) -> PyResult<Bound<'py, PyAny>> {
        let c = self.campaign.clone();
        let s = py.detach(|| c.finish(&chunks)).map_err(errors::job)?;
        let v = serde_json::to_value(&s).map_err(|e| PyValueError::new_err(e.to_string()))?;
        py_of_json(py, &v)
    }
}
