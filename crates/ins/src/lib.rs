//! # aidnav-ins — inertial navigation
//!
//! Instrument error models used both to corrupt simulated sensor outputs and
//! to correct real ones, and the strapdown mechanizations: the local-level
//! flat-Earth one of spec 30's formation simulation ([`local_level`]) with its
//! loosely coupled GNSS filter ([`loosely_coupled`]); the launch-frame INS
//! of spec 10 with its twelve instrument errors ([`launch`]); NED/WGS-84 of
//! spec 40 arrives with its issue.

pub mod instrument;
pub mod launch;
pub mod local_level;
pub mod loosely_coupled;

pub use instrument::AxisError;
