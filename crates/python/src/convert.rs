//! numpy ↔ nalgebra, Python values ↔ JSON/TOML, and running a long call
//! off the GIL so Ctrl-C still reaches Python.

use aidnav::sim::Cancel;
use nalgebra::{DMatrix, DVector};
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

/// A 2-D array as a matrix (any memory layout).
pub fn matrix(a: &PyReadonlyArray2<'_, f64>) -> DMatrix<f64> {
    let v = a.as_array();
    let (r, c) = v.dim();
    match v.as_slice() {
        Some(s) => DMatrix::from_row_slice(r, c, s),
        None => DMatrix::from_fn(r, c, |i, j| v[[i, j]]),
    }
}

/// A 1-D array as a vector.
pub fn vector(a: &PyReadonlyArray1<'_, f64>) -> DVector<f64> {
    let v = a.as_array();
    match v.as_slice() {
        Some(s) => DVector::from_column_slice(s),
        None => DVector::from_iterator(v.len(), v.iter().copied()),
    }
}

/// A vector as a 1-D array.
pub fn to_array1<'py>(py: Python<'py>, v: &DVector<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v.as_slice())
}

/// A matrix as a 2-D array (row-major).
pub fn to_array2<'py>(py: Python<'py>, m: &DMatrix<f64>) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let t = m.transpose();
    PyArray1::from_slice(py, t.as_slice()).reshape([m.nrows(), m.ncols()])
}

/// A Python value (dict, list, tuple, str, bool, int, float, path-like) as
/// JSON; `key` names it in errors.
pub fn json_of(v: &Bound<'_, PyAny>, key: &str) -> PyResult<serde_json::Value> {
    use serde_json::Value;
    if v.is_none() {
        return Err(PyValueError::new_err(format!(
            "{key}: None has no TOML form: leave the key out for its default"
        )));
    }
    if v.is_instance_of::<PyBool>() {
        return Ok(Value::Bool(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        return Ok(Value::from(v.extract::<i64>()?));
    }
    if v.is_instance_of::<PyFloat>() {
        let f: f64 = v.extract()?;
        return serde_json::Number::from_f64(f)
            .map(Value::Number)
            .ok_or_else(|| PyValueError::new_err(format!("{key}: {f} is not a finite number")));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut map = serde_json::Map::new();
        for (k, val) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| PyTypeError::new_err(format!("{key}: keys must be strings")))?;
            let sub = if key.is_empty() {
                k.clone()
            } else {
                format!("{key}.{k}")
            };
            map.insert(k, json_of(&val, &sub)?);
        }
        return Ok(Value::Object(map));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for (i, item) in v.try_iter()?.enumerate() {
            out.push(json_of(&item?, &format!("{key}[{i}]"))?);
        }
        return Ok(Value::Array(out));
    }
    // numpy scalars and arrays, os.PathLike.
    if let Ok(item) = v.call_method0("tolist") {
        return json_of(&item, key);
    }
    if let Ok(p) = v.call_method0("__fspath__") {
        return json_of(&p, key);
    }
    Err(PyTypeError::new_err(format!(
        "{key}: a {} has no TOML form",
        v.get_type().name()?
    )))
}

/// A Python dict as TOML text (for the library's TOML loader, so a dict is
/// checked exactly as a file is).
pub fn toml_of(d: &Bound<'_, PyDict>) -> PyResult<String> {
    let value = json_of(d.as_any(), "")?;
    toml::to_string(&value).map_err(|e| PyValueError::new_err(format!("not a TOML table: {e}")))
}

/// JSON as a Python object, through the `json` module (the summaries).
pub fn py_of_json<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(v).map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// How often a waiting call looks for Ctrl-C.
const SIGNAL_POLL: std::time::Duration = std::time::Duration::from_millis(50);

/// How long a call interrupted by Ctrl-C waits for its cancelled work to
/// stop before raising anyway (work that does not look at the token, a
/// file being read, goes on in the background).
const CANCEL_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// Work threads of [`interruptible`] still running (`_running_calls()`).
static RUNNING: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// Number of long Rust calls whose work is still running, cancelled ones
/// included (0 once an interrupted call's work has stopped).
#[pyfunction]
#[pyo3(name = "_running_calls")]
pub fn running_calls() -> usize {
    RUNNING.load(std::sync::atomic::Ordering::SeqCst)
}

/// Counts a work thread while it lives.
struct Running;

impl Running {
    fn start() -> Self {
        RUNNING.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Running
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        RUNNING.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

/// Run `work(cancel)` on a thread of its own with the GIL released,
/// looking for signals every 50 ms. On Ctrl-C (any exception a signal
/// handler raises) the token `cancel` is set — the library's Monte Carlo
/// loops and filter passes look at it between runs and IMU samples and
/// stop — the call waits for the work to stop (at most 2 s) and raises.
/// A panic in the work becomes a `RuntimeError`.
pub fn interruptible<T, F>(py: Python<'_>, work: F) -> PyResult<T>
where
    T: Send + 'static,
    F: FnOnce(Cancel) -> T + Send + 'static,
{
    let cancel = Cancel::new();
    let token = cancel.clone();
    let (tx, rx) = std::sync::mpsc::channel();
    let running = Running::start();
    std::thread::Builder::new()
        .name("aidnav".into())
        .spawn(move || {
            let _running = running;
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(token)));
            let _ = tx.send(r);
        })
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start a thread: {e}")))?;
    let mut rx = rx;
    loop {
        let (got, back) = py.detach(move || (rx.recv_timeout(SIGNAL_POLL), rx));
        rx = back;
        match got {
            Ok(Ok(v)) => return Ok(v),
            Ok(Err(panic)) => {
                let what = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_string()))
                    .unwrap_or_else(|| "unknown".into());
                return Err(PyRuntimeError::new_err(format!(
                    "aidnav panicked (a bug, please report): {what}"
                )));
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if let Err(interrupt) = py.check_signals() {
                    cancel.cancel();
                    // The work stops within a run or an IMU sample; its
                    // result (an error saying it was cancelled) is dropped.
                    let _ = py.detach(move || rx.recv_timeout(CANCEL_WAIT));
                    return Err(interrupt);
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(PyKeyboardInterrupt::new_err(
                    "aidnav: the work thread ended",
                ));
            }
        }
    }
}
