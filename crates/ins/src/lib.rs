//! # aidnav-ins — inertial navigation
//!
//! Instrument error models used both to corrupt simulated sensor outputs and
//! to correct real ones, and the strapdown mechanizations: the local-level
//! flat-Earth one of spec 30's formation simulation ([`local_level`]); the
//! launch-frame INS of spec 10 with its twelve instrument errors
//! ([`launch`]); the WGS-84 NED mechanization of spec 40 ([`ned`]), frame-typed
//! (`Vec3<Ned>` velocity, `Rotation<Body, Ned>` attitude, `Vec3<Body>`
//! increments). The GNSS/INS filters built on them are in `aidnav-integration`
//! (`local_level`, `ned`).

pub mod instrument;
pub mod launch;
pub mod local_level;
pub mod ned;

pub use instrument::AxisError;
