//! The integration layer of aidnav (spec 00): the aided-INS filters that
//! join a mechanization ([`aidnav_ins`]) to an error model
//! ([`aidnav_models`]) through the estimation engine
//! ([`aidnav_estimation`]), and their supervision ([`aidnav_supervisors`]).
//! One module per system, named as in the other layers:
//!
//! - [`ned`]: spec 40's 21-state closed-loop GNSS/INS filter on the WGS-84
//!   NED mechanization;
//! - [`local_level`]: spec 30's stage 1, the loosely coupled filter on the
//!   flat local-level INS;
//! - [`ned_loosely`]: the same stage 1 in an Earth frame, the WGS-84 NED INS
//!   with spec 40's error model and the GNSS receiver's correlated errors;
//! - [`ned_loop`]: the NED filter's epoch loop over a recorded log, its
//!   observers, and [`bridge`], spec 20's outage bridge as one of them;
//! - [`group`]: spec 30's stage 2, the group filters: one axis of a large
//!   group in information form, and the 3-D fusion of a formation in the
//!   paper's axis-decoupled form and as an EKF.

pub mod aiding;
pub mod bridge;
pub mod group;
pub mod local_level;
pub mod measurements;
pub mod ned;
pub mod ned_loop;
pub mod ned_loosely;
mod recording;
mod sparse;
pub mod state;
