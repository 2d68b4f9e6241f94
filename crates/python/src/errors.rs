//! The library's errors as Python exceptions, messages unchanged (they name
//! the file, line, column or key).

use aidnav::app::jobs::JobError;
use aidnav::app::process::ProcessError;
use aidnav::estimation::EstimationError;
use aidnav::io::IoError;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    aidnav,
    AidnavError,
    PyException,
    "Base class of aidnav's errors; the message names the file, line, column or key."
);
create_exception!(
    aidnav,
    ConfigError,
    AidnavError,
    "A configuration or scenario (TOML file or dict) is malformed or holds a value out of range: `path:line: key: message`."
);
create_exception!(
    aidnav,
    DataError,
    AidnavError,
    "A data file (or in-memory data) cannot be read or holds a bad value: `path:line: column `name`: message`."
);
create_exception!(
    aidnav,
    FilterError,
    AidnavError,
    "The estimation engine refused a step (a matrix not finite, not symmetric, not positive definite, of the wrong shape), naming the step, the matrix and the epoch."
);

/// Add the exception classes to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("AidnavError", py.get_type::<AidnavError>())?;
    m.add("ConfigError", py.get_type::<ConfigError>())?;
    m.add("DataError", py.get_type::<DataError>())?;
    m.add("FilterError", py.get_type::<FilterError>())?;
    Ok(())
}

/// An I/O error as the exception of its kind.
pub fn io(e: IoError) -> PyErr {
    let message = e.to_string();
    match e {
        IoError::Config { .. } => ConfigError::new_err(message),
        _ => DataError::new_err(message),
    }
}

/// An engine error.
pub fn estimation(e: EstimationError) -> PyErr {
    FilterError::new_err(e.to_string())
}

/// A processing error.
pub fn process(e: ProcessError) -> PyErr {
    match e {
        ProcessError::Io(e) => io(e),
        ProcessError::Estimation(_) => FilterError::new_err(e.to_string()),
        ProcessError::Data(m) => DataError::new_err(m),
    }
}

/// A job's error.
pub fn job(e: JobError) -> PyErr {
    match e {
        JobError::Io(e) => io(e),
        JobError::Estimation { .. } => FilterError::new_err(e.to_string()),
        JobError::Cancelled => pyo3::exceptions::PyKeyboardInterrupt::new_err("aidnav: cancelled"),
        other => AidnavError::new_err(other.to_string()),
    }
}
