//! # aidnav-supervisors — on-board decision logic
//!
//! Supervisors read the filter's outputs and matrices and decide; they do not
//! filter. This layer starts with a windowed NIS monitor (is the filter still
//! consistent with its measurements?) and the outage bridge with its relay
//! predictor and the efficiency criterion (spec 20); the Cramér–Rao
//! convergence criterion arrives with its issue.

pub mod efficiency;
pub mod nis_monitor;
pub mod outage;

pub use efficiency::{EfficiencyCriterion, Source};
pub use nis_monitor::{NisMonitor, NisVerdict};
pub use outage::{BridgeConfig, OutageBridge, Predictor, RelaySchedule};
