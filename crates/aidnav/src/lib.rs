#![doc = include_str!("../../../README.md")]

pub use aidnav_app as app;
pub use aidnav_estimation as estimation;
pub use aidnav_frames as frames;
pub use aidnav_ins as ins;
pub use aidnav_integration as integration;
pub use aidnav_io as io;
pub use aidnav_models as models;
pub use aidnav_reproduce as reproduce;
pub use aidnav_sensors as sensors;
pub use aidnav_sim as sim;
pub use aidnav_supervisors as supervisors;

/// Version of aidnav written into every output.
pub use aidnav_app::VERSION;
