//! # aidnav-supervisors — on-board decision logic
//!
//! Supervisors read the filter's outputs and matrices and decide; they do not
//! filter. This layer starts with a windowed NIS monitor (is the filter still
//! consistent with its measurements?) and the outage bridge with its relay
//! predictor and the efficiency criterion (spec 20), and the Cramér–Rao
//! convergence criterion with its switch (spec 10).

pub mod convergence;
pub mod efficiency;
pub mod nis_monitor;
pub mod outage;

pub use convergence::{ConvergenceSwitch, SwitchRule, cramer_rao_ratio};
pub use efficiency::{EfficiencyCriterion, Source};
pub use nis_monitor::{NisMonitor, NisVerdict};
pub use outage::{BridgeConfig, OutageBridge, Predictor, RelaySchedule};
