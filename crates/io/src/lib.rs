//! # aidnav-io — files in, files out
//!
//! - [`config`]: TOML scenario and model files onto serde structs; every error
//!   names the file, the line, the key and, for a value out of range, the
//!   allowed range.
//! - [`model_file`]: the linear-model file of `aidnav filter`.
//! - [`measurements`]: the measurement CSV of `aidnav filter` (empty cell = missing).
//! - [`writers`]: CSV observers for filter runs, `summary.json`.
//! - [`plot`]: SVG line charts.
//! - [`kfgins`]: KF-GINS IMU and GNSS text files, aidnav's generic IMU CSV.
//! - [`rtklib`]: RTKLIB `.pos` solutions and the raw IMU CSV with its `.tag` time tags.
//! - [`nmea`]: NMEA 0183 GNSS logs.
//! - [`ubx`]: u-blox UBX binary logs (NAV-PVT).
//! - [`generic_gnss`]: aidnav's generic GNSS CSV (named columns, several time,
//!   position, σ and velocity forms).
//! - [`generic_aiding`]: aidnav's generic wheel-speed and barometer CSVs.
//! - [`formats`]: the format registry, one enum per stream kind, each
//!   format's reader one `read` arm and its writer one `write` arm.
//! - [`log_writers`]: writers for every format the readers take (what a
//!   simulator writes its logs through), with each format's round-trip
//!   resolution.
//! - [`reference`](mod@reference): the reference (truth) trajectory CSV.
//! - [`text`]: UTF-8 decoding with line and byte, BOM, line splitting, excerpts.
//! - [`limits`]: the physical bounds every reader checks values against.
//!
//! Every reader has an in-memory entry point (`…_from(bytes, origin)`) beside
//! the `&Path` one, which is a thin wrapper reading the file.

pub mod checks;
pub mod config;
pub mod error;
pub mod formats;
pub mod generic_aiding;
pub mod generic_gnss;
pub mod kfgins;
pub mod limits;
pub mod log_writers;
pub mod measurements;
pub mod model_file;
mod named_csv;
pub mod nmea;
pub mod plot;
pub mod reference;
pub mod rtklib;
pub mod text;
pub mod ubx;
pub mod writers;

/// Marsaglia's xorshift64 from `seed` (nonzero): the tests' reproducible
/// stream of 64-bit words, without a random-number crate.
#[cfg(test)]
pub(crate) fn xorshift(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    }
}

pub use config::{Invalid, Validate, load_toml, parse_toml};
pub use error::{IoError, Result};
