//! # aidnav-supervisors — on-board decision logic
//!
//! Supervisors read the filter's outputs and matrices and decide; they do not
//! filter. This layer starts with a windowed NIS monitor (is the filter still
//! consistent with its measurements?); the Cramér–Rao convergence criterion,
//! the efficiency criterion and the relay outage predictor arrive with their
//! issues.

pub mod nis_monitor;

pub use nis_monitor::{NisMonitor, NisVerdict};
