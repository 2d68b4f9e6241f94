//! # aidnav-ins — inertial navigation
//!
//! Instrument error models used both to corrupt simulated sensor outputs and
//! to correct real ones, and the strapdown mechanizations: the local-level
//! flat-Earth one of spec 30's formation simulation ([`local_level`]) with its
//! loosely coupled GNSS filter (in `aidnav-integration`); the launch-frame INS
//! of spec 10 with its twelve instrument errors ([`launch`]); the WGS-84
//! NED mechanization of spec 40 ([`ned`]), frame-typed (`Vec3<Ned>`
//! velocity, `Rotation<Body, Ned>` attitude, `Vec3<Body>` increments), with
//! what feeds it: the raw samples ([`samples`]), the IMU mounting
//! ([`mounting`]), the coarse alignment at rest ([`alignment`]), standstill
//! detection ([`standstill`]) and the trapezoid increments ([`increments`]).

pub mod alignment;
pub mod increments;
pub mod instrument;
pub mod launch;
pub mod local_level;
pub mod mounting;
pub mod ned;
pub mod samples;
pub mod standstill;

pub use instrument::AxisError;
