#![doc = include_str!("../../../README.md")]

pub mod fuzzing;
pub mod jobs;
pub mod process;

pub use aidnav_estimation as estimation;
pub use aidnav_frames as frames;
pub use aidnav_ins as ins;
pub use aidnav_integration as integration;
pub use aidnav_io as io;
pub use aidnav_models as models;
pub use aidnav_reproduce as reproduce;
pub use aidnav_sim as sim;
pub use aidnav_supervisors as supervisors;

/// Version of aidnav written into every output.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
