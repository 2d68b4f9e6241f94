//! # aidnav-ins — inertial navigation
//!
//! Instrument error models used both to corrupt simulated sensor outputs and
//! to correct real ones. The strapdown mechanizations (launch frame of spec
//! 10, NED/WGS-84 of spec 40) arrive with their issues.

pub mod instrument;

pub use instrument::AxisError;
