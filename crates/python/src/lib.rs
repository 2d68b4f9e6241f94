//! aidnav's Python extension module, `aidnav._aidnav`: thin bindings over
//! the library. The Python package (`python/aidnav`) wraps it with
//! DataFrames, Dask and the type stubs; nothing here navigates: every call
//! converts its arguments, calls the library with the GIL released, and
//! converts the answer back.
//!
//! Built by maturin (`pip install ./python`), which turns on the
//! `extension-module` feature; a plain `cargo build` links libpython so the
//! workspace's checks build it too.

use pyo3::prelude::*;

mod convert;
mod engine;
mod errors;
mod jobs;
mod readers;
mod simulate;

/// The module `aidnav._aidnav`.
#[pymodule]
fn _aidnav(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", aidnav::VERSION)?;
    errors::register(m)?;
    engine::register(m)?;
    readers::register(m)?;
    jobs::register(m)?;
    simulate::register(m)?;
    m.add_function(wrap_pyfunction!(convert::running_calls, m)?)?;
    Ok(())
}
