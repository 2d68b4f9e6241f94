//! # aidnav-ins — inertial navigation
//!
//! Instrument error models used both to corrupt simulated sensor outputs and
//! to correct real ones, and the strapdown mechanizations: the local-level
//! flat-Earth one of spec 30's formation simulation ([`local_level`]) with its
//! loosely coupled GNSS filter ([`loosely_coupled`]); the launch-frame INS
//! of spec 10 with its twelve instrument errors ([`launch`]); the WGS-84
//! NED mechanization of spec 40 ([`ned`]).

pub mod instrument;
pub mod launch;
pub mod local_level;
pub mod ned;

pub use instrument::AxisError;
