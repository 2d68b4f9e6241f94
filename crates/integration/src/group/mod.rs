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
//! moves by D ψ). Range rates and body-frame relative velocities
//! ([`RelativeRate`]) are fused after the epoch's positions: the EKF uses
//! both; the paper's form uses the relative velocity (converted to the nav
//! frame, one scalar per axis) but not the range rate, which is the
//! projection of the 3-D relative velocity on the line of sight and cannot
//! be split into independent per-axis observations.
//!
//! The errors of a member's stage-1 solution are mostly the GNSS receiver's
//! correlated errors (minutes). With [`OwnErrorModel::White`] stage 2 takes
//! each epoch's stage-1 covariance as white measurement noise (the paper's
//! treatment), and so averages correlated errors as if they were independent.
//! With [`OwnErrorModel::GaussMarkov`] it carries per member, per axis a
//! first-order Gauss–Markov state for the correlated part of the stage-1
//! position (and, when own velocities are fused, velocity) error, and takes
//! only the rest of the stage-1 covariance as white.
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

pub use axis_information::{AxisOwnErrors, GroupAxisFilter, k_nearest, within_range};
pub use delayed::{DelayStats, DelayedFusion, EpochFusion, MemberPacket};
pub use ekf::EkfFusion;
pub use paper::PaperFusion;

use aidnav_ins::local_level::LocalLevelState;
use aidnav_models::GaussMarkov;
use aidnav_models::local_ins::Matrix6;
use aidnav_models::relative_sensor::{Polar, RelativeSensor};
use nalgebra::{Matrix3, Vector3};

/// The correlated part of each member's stage-1 errors, per nav axis, and
/// the white floor kept under it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrelatedOwnErrors {
    /// Gauss–Markov model of the stage-1 position error, per axis.
    pub position: [GaussMarkov; 3],
    /// Gauss–Markov model of the stage-1 velocity error, per axis (used
    /// when own velocities are fused).
    pub velocity: [GaussMarkov; 3],
    /// Least white σ left on an own position fix \[m\]: the white noise is
    /// the stage-1 variance minus the correlated one, but never below this.
    pub position_white_floor_m: f64,
    /// Least white σ left on an own velocity fix [m/s].
    pub velocity_white_floor_mps: f64,
}

/// How stage 2 treats the errors of each member's own (stage-1) solution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OwnErrorModel {
    /// White: each epoch's stage-1 covariance is the own fix's noise.
    White,
    /// Correlated part as Gauss–Markov states, the rest white.
    GaussMarkov(CorrelatedOwnErrors),
}

impl CorrelatedOwnErrors {
    /// The white part of an own fix's covariance `total` (position or
    /// velocity block) given the correlated variances `correlated`: the
    /// difference with its eigenvalues raised to at least `floor²`, so that
    /// it stays a covariance whatever stage 1 reports.
    fn white_part(total: &Matrix3<f64>, correlated: &Vector3<f64>, floor: f64) -> Matrix3<f64> {
        let diff = total - Matrix3::from_diagonal(correlated);
        let diff = 0.5 * (diff + diff.transpose());
        let mut eig = diff.symmetric_eigen();
        for v in eig.eigenvalues.iter_mut() {
            *v = v.max(floor * floor);
        }
        eig.recompose()
    }

    /// Stationary variances of the position states.
    fn position_variances(&self) -> Vector3<f64> {
        Vector3::from_fn(|a, _| self.position[a].sigma().powi(2))
    }

    /// Stationary variances of the velocity states.
    fn velocity_variances(&self) -> Vector3<f64> {
        Vector3::from_fn(|a, _| self.velocity[a].sigma().powi(2))
    }

    /// The white part of a stage-1 covariance (6×6, position first): each
    /// 3×3 block's white part from [`Self::white_part`], the position–
    /// velocity cross block kept (it is white-to-white).
    pub(crate) fn white_covariance(&self, stage1: &Matrix6) -> Matrix6 {
        let mut w = *stage1;
        let pp = Self::white_part(
            &stage1.fixed_view::<3, 3>(0, 0).into_owned(),
            &self.position_variances(),
            self.position_white_floor_m,
        );
        let vv = Self::white_part(
            &stage1.fixed_view::<3, 3>(3, 3).into_owned(),
            &self.velocity_variances(),
            self.velocity_white_floor_mps,
        );
        w.fixed_view_mut::<3, 3>(0, 0).copy_from(&pp);
        w.fixed_view_mut::<3, 3>(3, 3).copy_from(&vv);
        // Shrinking the diagonal blocks can leave the cross block too large;
        // scale it until the whole is positive definite.
        let mut scale = 1.0;
        while scale > 0.0 && w.cholesky().is_none() {
            scale *= 0.5;
            if scale < 1e-6 {
                scale = 0.0;
            }
            let cross = stage1.fixed_view::<3, 3>(0, 3) * scale;
            w.fixed_view_mut::<3, 3>(0, 3).copy_from(&cross);
            w.fixed_view_mut::<3, 3>(3, 0).copy_from(&cross.transpose());
        }
        w
    }
}

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
    /// How the errors of each member's own solution are modelled.
    pub own_errors: OwnErrorModel,
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

/// Motion of member `to` measured by member `from`: the range rate and/or
/// the relative velocity in `from`'s body frame
/// ([`aidnav_models::relative_sensor::range_rate`],
/// [`aidnav_models::relative_sensor::body_relative_velocity`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelativeRate {
    /// Observer (0-based member index).
    pub from: usize,
    /// Observed member.
    pub to: usize,
    /// Measured range rate Ḋ [m/s], if the sensor measures it.
    pub range_rate_mps: Option<f64>,
    /// Measured relative velocity in the observer's body frame [m/s], if
    /// the sensor measures it.
    pub body_velocity_mps: Option<Vector3<f64>>,
}

/// Covariance added to a line of sight `d` (nav frame) by the observer's
/// attitude uncertainty: δd = d × ψ.
fn attitude_covariance_on(d: &Vector3<f64>, p_psi: &Matrix3<f64>) -> Matrix3<f64> {
    let s = d.cross_matrix();
    s * p_psi * s.transpose()
}
