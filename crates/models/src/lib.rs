//! # aidnav-models — state-space models
//!
//! Each model gives Φ, Q (and H, R where it is measured) for an epoch; the
//! estimation engine runs them without knowing what they mean. This layer
//! starts with the building blocks every navigation model is made of and the
//! 3-state platform channel of spec 20; the 14-state launch-frame model, the local-level
//! INS error model and the 3-D group kinematics arrive with their issues;
//! spec 30's axis-decoupled group model is here.

pub mod constant_velocity;
pub mod extended_state;
pub mod gauss_markov;
pub mod group_axis;
pub mod local_ins;
pub mod ned_ins;
pub mod platform;
pub mod relative_sensor;

pub use constant_velocity::ConstantVelocity;
pub use gauss_markov::GaussMarkov;
pub use group_axis::AxisGroup;
pub use platform::{PlatformChannel, PlatformTruth};
