//! `aidnav.simulate` and the zoo's entries: a scenario (path or dict)
//! simulated, its streams and truth as columns; or simulated, processed
//! and scored (one zoo row, what a Dask worker computes).

use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use aidnav::app::jobs::simulate::{Simulation, planted_installation, simulation_of_text};
use aidnav::app::jobs::zoo::score_simulation;
use aidnav::sim::scenario::{SimLog, simulate};

use crate::convert::{interruptible, py_of_json};
use crate::errors;
use crate::jobs::source;
use crate::readers::{gnss_columns, imu_columns};

/// Register the functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(simulate_log, m)?)?;
    m.add_function(wrap_pyfunction!(zoo_entry, m)?)?;
    Ok(())
}

fn load(scenario: &Bound<'_, PyAny>, seed: Option<u64>) -> PyResult<Simulation> {
    let src = source(scenario, None, "scenario")?;
    simulation_of_text(&src.text, &src.origin, seed).map_err(errors::job)
}

/// A named column: its name and how a row gives its value.
type Column<'a, T> = (&'a str, &'a dyn Fn(&T) -> f64);

/// Columns of named values.
fn columns<'py, T>(
    py: Python<'py>,
    rows: &[T],
    cols: &[Column<'_, T>],
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (name, f) in cols {
        d.set_item(*name, PyArray1::from_vec(py, rows.iter().map(f).collect()))?;
    }
    Ok(d)
}

/// Simulate `scenario` (a TOML path or a dict; `seed` replaces its seed):
/// a dict with `imu`, `gnss`, `wheel_speed`, `barometer` and `truth` as
/// columns of arrays, `installation` (the planted values), `scenario` (the
/// resolved scenario's TOML), `seed` and `version`.
#[pyfunction]
#[pyo3(signature = (scenario, seed=None))]
fn simulate_log<'py>(
    py: Python<'py>,
    scenario: &Bound<'py, PyAny>,
    seed: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let sim = load(scenario, seed)?;
    let s = sim.scenario.clone();
    let log: SimLog = interruptible(py, move |_| simulate(&s, s.seed, 0))?
        .map_err(|e| pyo3::exceptions::PyValueError::new_err(format!("scenario: {e}")))?;
    let d = PyDict::new(py);
    d.set_item("imu", imu_columns(py, &log.imu)?)?;
    let gnss = gnss_columns(py, &log.gnss)?;
    d.set_item("gnss", gnss)?;
    d.set_item(
        "wheel_speed",
        columns(
            py,
            &log.wheel_speed,
            &[("time_s", &|w| w.time_s), ("speed_mps", &|w| w.speed_mps)],
        )?,
    )?;
    d.set_item(
        "barometer",
        columns(
            py,
            &log.baro,
            &[("time_s", &|b| b.time_s), ("height_m", &|b| b.height_m)],
        )?,
    )?;
    type T = aidnav::sim::truth::TruthSample;
    let euler = |t: &T, k: usize| {
        let (r, p, y) = t.attitude.euler_angles();
        [r, p, y][k].to_degrees()
    };
    d.set_item(
        "truth",
        columns(
            py,
            &log.truth,
            &[
                ("time_s", &|t: &T| t.time_s),
                ("latitude_deg", &|t: &T| {
                    t.position.latitude_rad.to_degrees()
                }),
                ("longitude_deg", &|t: &T| {
                    t.position.longitude_rad.to_degrees()
                }),
                ("height_m", &|t: &T| t.position.height_m),
                ("velocity_north_m_s", &|t: &T| t.velocity_ned.x()),
                ("velocity_east_m_s", &|t: &T| t.velocity_ned.y()),
                ("velocity_down_m_s", &|t: &T| t.velocity_ned.z()),
                ("roll_deg", &|t: &T| euler(t, 0)),
                ("pitch_deg", &|t: &T| euler(t, 1)),
                ("yaw_deg", &|t: &T| euler(t, 2)),
            ],
        )?,
    )?;
    d.set_item(
        "installation",
        py_of_json(py, &planted_installation(&sim.scenario))?,
    )?;
    d.set_item("scenario", sim.to_toml())?;
    d.set_item("seed", sim.scenario.seed)?;
    d.set_item("version", aidnav::VERSION)?;
    Ok(d)
}

/// One zoo row: `scenario` (a TOML path or a dict; `seed` replaces its
/// seed) simulated into a temporary directory (removed after), processed
/// with its new-user configuration and with the matched noise model, and
/// scored against its truth — the entry of `aidnav zoo`'s summary.json.
#[pyfunction]
#[pyo3(signature = (scenario, seed=None))]
fn zoo_entry<'py>(
    py: Python<'py>,
    scenario: &Bound<'py, PyAny>,
    seed: Option<u64>,
) -> PyResult<Bound<'py, PyAny>> {
    let src = source(scenario, None, "scenario")?;
    let origin = src.origin.clone();
    let sim = simulation_of_text(&src.text, &origin, seed).map_err(errors::job)?;
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    let dir = std::env::temp_dir().join(format!(
        "aidnav-zoo-{}-{call}-{}-{}",
        std::process::id(),
        sim.scenario.name,
        sim.scenario.seed
    ));
    let entry = interruptible(py, move |_| {
        let r = score_simulation(&sim, &origin, &dir);
        let _ = std::fs::remove_dir_all(&dir);
        r
    })?
    .map_err(errors::job)?;
    let json = serde_json::to_value(&entry)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    py_of_json(py, &json)
}
