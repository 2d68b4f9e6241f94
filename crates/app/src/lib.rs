//! The aidnav application: [`process`] takes a recorded IMU + GNSS log
//! (and any wheel-speed or barometer stream) end to end — read, initialise,
//! filter, smooth, score, export — and [`jobs`] are the acts behind the
//! command-line tool's subcommands and the Python package, each reading its
//! inputs, running the library and writing its outputs. [`fuzzing`] holds
//! the bodies of the fuzz targets.
//!
//! The layers below (frames, INS, engine, models, integration, supervisors,
//! simulation, reproductions, I/O) know nothing of this crate; the CLI and
//! Python only call it and print or write.

pub mod fuzzing;
pub mod jobs;
pub mod process;

/// Version of aidnav written into every output.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
