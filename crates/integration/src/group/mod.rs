//! Spec 30's stage 2: group filters that fuse each member's own INS/GNSS
//! solution with the relative measurements between members.
//!
//! - [`GroupAxisFilter`]: one axis of a group of hundreds to thousands of
//!   vehicles, the paper's constant-velocity model with a dense covariance,
//!   updated in information form ([`aidnav_estimation::SubspaceUpdate`])
//!   from sparse observations — own position (and velocity) fixes, and
//!   relative positions to a few neighbours ([`k_nearest`], [`within_range`]).
//!   Its state is ordered `[R¹ … R^M, V¹ … V^M]` (positions first) so the
//!   observed block is contiguous; [`aidnav_models::AxisGroup`] keeps the
//!   paper's interleaved order for the small reproduction.
//! - [`PaperFusion`]: the paper's axis-decoupled 3-D fusion, three
//!   [`GroupAxisFilter`]s fed with relative measurements converted to
//!   Cartesian coordinates.
//! - [`EkfFusion`]: one extended Kalman filter over all members' 3-D
//!   positions and velocities that uses range, bearing and elevation
//!   directly.
//!
//! - [`DelayedFusion`]: either 3-D form (or any [`EpochFusion`]) fed over a
//!   network: a late [`MemberPacket`] is fused at its own epoch by rewinding
//!   to a buffered snapshot and running the epochs since again.
//!
//! Both 3-D forms take their parameters from [`FusionParams`], each member's
//! stage-1 solution as an [`OwnSolution`] and the relative measurements as
//! [`RelativeMeasurement`]s, and add the observer's attitude uncertainty to
//! the relative measurement noise (a line of sight of length D turned by ψ
//! moves by D ψ).
//!
//! ```
//! use aidnav_integration::group::GroupAxisFilter;
//! let mut f = GroupAxisFilter::new(3, 1.0, 1.0, false, &[0.0; 3], &[0.0; 3], 10.0, 5.0).unwrap();
//! f.predict();
//! f.observe_own_position(0, 2.0, 10.0).unwrap();
//! f.observe_relative(0, 1, -50.0, 0.5).unwrap(); // R¹ − R² = −50
//! f.update().unwrap();
//! assert!(f.position_sigma(1) < 10.0); // member 2 gained from member 1's fix
//! ```

mod axis_information;
mod delayed;
mod ekf;
mod paper;

pub use axis_information::{GroupAxisFilter, k_nearest, within_range};
pub use delayed::{DelayStats, DelayedFusion, EpochFusion, MemberPacket};
pub use ekf::EkfFusion;
pub use paper::PaperFusion;

use aidnav_ins::local_level::LocalLevelState;
use aidnav_models::local_ins::Matrix6;
use aidnav_models::relative_sensor::{Polar, RelativeSensor};
use nalgebra::{Matrix3, Vector3};

/// Parameters of the 3-D stage-2 filters ([`PaperFusion`], [`EkfFusion`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusionParams {
    /// Interval between stage-2 epochs (own fixes and relative
    /// measurements) \[s\].
    pub interval_s: f64,
    /// Acceleration disturbance a_R of the constant-velocity model
    /// \[m/s²\]: Q = (a_R T)² on each velocity.
    pub accel_sigma_m_s2: f64,
    /// Whether each member's own stage-1 velocity is fused too (the paper's
    /// optional z_V), not only its position.
    pub own_velocity: bool,
    /// The inter-vehicle sensor: σ of range, bearing and elevation.
    pub sensor: RelativeSensor,
    /// Initial σ of each position coordinate \[m\].
    pub initial_position_sigma_m: f64,
    /// Initial σ of each velocity coordinate \[m/s\].
    pub initial_velocity_sigma_mps: f64,
}

/// What stage 1 hands to stage 2 for one member at one epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OwnSolution {
    /// The member's INS* solution (position, velocity, attitude).
    pub state: LocalLevelState,
    /// Covariance of its position and velocity (6×6, position first).
    pub covariance: Matrix6,
    /// Covariance of its attitude error ψ \[rad²\].
    pub attitude_covariance: Matrix3<f64>,
}

/// A relative measurement of member `to` by member `from`, in `from`'s
/// body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativeMeasurement {
    /// Observer (0-based member index).
    pub from: usize,
    /// Observed member.
    pub to: usize,
    /// Range, bearing and elevation.
    pub polar: Polar,
}

/// Covariance added to a line of sight `d` (nav frame) by the observer's
/// attitude uncertainty: δd = d × ψ.
fn attitude_covariance_on(d: &Vector3<f64>, p_psi: &Matrix3<f64>) -> Matrix3<f64> {
    let s = d.cross_matrix();
    s * p_psi * s.transpose()
}
