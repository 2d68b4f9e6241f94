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
//! only the rest of the stage-1 covariance as white. With
//! [`OwnErrorModel::Stage1Reported`] it carries each member's whole stage-1
//! position–velocity error (6 states) and moves it from epoch to epoch by
//! the transition stage 1 itself reports: its covariance and the
//! cross-covariance of its error with the previous epoch's
//! ([`OwnSolution::error_cross_covariance`], which the stage-1 filters track
//! through their Φ and gains), turned into `(A, Q)` by
//! [`stage1_transition`] — no second model of the receiver.
//!
//! [`MotionModel`] chooses the constant-velocity model's process noise: the
//! paper's (a_R T)² on the velocity only, or the same acceleration held over
//! the step, which also moves the position (a T² / 2) — without it a
//! velocity tied to precise position increments lags by a T / 2 whenever
//! the vehicles accelerate.
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
    /// The whole stage-1 position–velocity error as states (per member,
    /// 6), propagated from epoch to epoch with the transition and driving
    /// noise that stage 1's own covariance and error cross-covariance
    /// ([`OwnSolution::error_cross_covariance`]) give ([`stage1_transition`]):
    /// no second model of the receiver. An own fix observes `[R V] + b`
    /// with only a numerical white floor ([`STAGE1_WHITE_FRACTION`]).
    Stage1Reported,
}

/// Under [`OwnErrorModel::Stage1Reported`], the white noise left on an own
/// fix as a fraction of stage 1's σ (its covariance times the square): a
/// numerical floor that keeps the information form's R⁻¹ finite, not a
/// model of anything (stage 1's output has no white part of its own: its
/// filter averages the receiver's white noise).
pub const STAGE1_WHITE_FRACTION: f64 = 1e-2;

/// How stage 2 propagates each member's position and velocity between
/// epochs (both the constant-velocity model with a_R).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MotionModel {
    /// The paper's item 7: `R_i = R_{i−1} + V_{i−1} T`,
    /// `V_i = V_{i−1} + a_R T w`; Q = (a_R T)² on each velocity, zero on
    /// the positions — an acceleration during the step moves the velocity
    /// but not the position, so a velocity estimate tied to position
    /// increments lags by a T / 2 under acceleration a.
    #[default]
    Paper,
    /// The same acceleration held over the step (discrete white-noise
    /// acceleration): `R_i = R_{i−1} + V_{i−1} T + a T² / 2`,
    /// `V_i = V_{i−1} + a T`, a ~ N(0, a_R²); Q = a_R² [T⁴/4, T³/2; T³/2,
    /// T²] per axis, the paper's velocity variance with the position's
    /// share of the same acceleration.
    PiecewiseConstantAcceleration,
}

impl MotionModel {
    /// Per-axis process noise `(q_RR, q_RV, q_VV)` for step `t` and
    /// acceleration σ `a`.
    pub fn process_noise(self, a: f64, t: f64) -> (f64, f64, f64) {
        let qv = (a * t).powi(2);
        match self {
            Self::Paper => (0.0, 0.0, qv),
            Self::PiecewiseConstantAcceleration => (qv * t * t / 4.0, qv * t / 2.0, qv),
        }
    }
}

/// Transition `(A, Q)` of a stage-1 error process from one epoch to the
/// next: with `previous` = Cov(e_{k−1}), `cross` = E[e_k e_{k−1}ᵀ] and
/// `current` = Cov(e_k), the best linear predictor e_k = A e_{k−1} + w has
/// A = C P_{k−1}⁻¹ (Cholesky solve) and Cov(w) = Q = P_k − A C ᵀ,
/// symmetrised with its eigenvalues raised to ≥ 0. `None` when `previous`
/// is not positive definite or a result is not finite.
pub fn stage1_transition(
    previous: &Matrix6,
    cross: &Matrix6,
    current: &Matrix6,
) -> Option<(Matrix6, Matrix6)> {
    let chol = previous.cholesky()?;
    // A Pₖ₋₁ = C  ⇔  Pₖ₋₁ Aᵀ = Cᵀ.
    let a = chol.solve(&cross.transpose()).transpose();
    let q = current - a * cross.transpose();
    let q = 0.5 * (q + q.transpose());
    let mut eig = q.symmetric_eigen();
    for v in eig.eigenvalues.iter_mut() {
        *v = v.max(0.0);
    }
    let q = eig.recompose();
    let q = 0.5 * (q + q.transpose());
    (a.iter().chain(q.iter()).all(|v| v.is_finite())).then_some((a, q))
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
    /// How positions and velocities are propagated between epochs.
    pub motion: MotionModel,
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
    /// `E[e_k e_{k−1}ᵀ]`: cross-covariance (6×6, position first) of this
    /// solution's position–velocity error with the member's previous
    /// epoch's, when stage 1 tracks it (needed by
    /// [`OwnErrorModel::Stage1Reported`]).
    pub error_cross_covariance: Option<Matrix6>,
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

/// Under [`OwnErrorModel::Stage1Reported`]: each member's last stage-1
/// covariance, which turns the next solution's error cross-covariance into
/// a transition ([`stage1_transition`]).
#[derive(Debug, Clone)]
pub(crate) struct Stage1Errors {
    last: Vec<Matrix6>,
}

impl Stage1Errors {
    pub(crate) fn new(first: &[OwnSolution]) -> Self {
        Self {
            last: first.iter().map(|o| o.covariance).collect(),
        }
    }

    /// This epoch's `(A, Q)` per member, from its solution where it is
    /// available (`own[l]`), and the covariances recorded for the next
    /// epoch. A member whose solution did not arrive (a lost packet) keeps
    /// its error (A = I, Q = 0: one epoch's change of a slowly varying
    /// error is neglected) and its last covariance; a solution without a
    /// cross-covariance (or with one that gives no transition) starts a
    /// fresh error of its covariance (A = 0, Q = P: the white treatment).
    pub(crate) fn step(&mut self, own: &[Option<&OwnSolution>]) -> Vec<(Matrix6, Matrix6)> {
        own.iter()
            .zip(self.last.iter_mut())
            .map(|(o, last)| match o {
                None => (Matrix6::identity(), Matrix6::zeros()),
                Some(o) => {
                    let t = o
                        .error_cross_covariance
                        .and_then(|c| stage1_transition(last, &c, &o.covariance))
                        .unwrap_or((Matrix6::zeros(), o.covariance));
                    *last = o.covariance;
                    t
                }
            })
            .collect()
    }
}

/// Covariance added to a line of sight `d` (nav frame) by the observer's
/// attitude uncertainty: δd = d × ψ.
fn attitude_covariance_on(d: &Vector3<f64>, p_psi: &Matrix3<f64>) -> Matrix3<f64> {
    let s = d.cross_matrix();
    s * p_psi * s.transpose()
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_models::local_ins::Matrix6;

    /// A 6-state first-order process e_k = F e_{k−1} + w: the transition
    /// from Cov(e_{k−1}), E[e_k e_{k−1}ᵀ] = F P and Cov(e_k) = F P Fᵀ + Q is
    /// F and Q again; a cross-covariance larger than the covariances allow
    /// gives a Q raised to ≥ 0, not a negative one.
    #[test]
    fn stage1_transition_recovers_a_first_order_process() {
        let f = Matrix6::from_fn(|i, j| {
            if i == j {
                0.9 - 0.02 * i as f64
            } else {
                0.03 * (i as f64 - j as f64).sin()
            }
        });
        let l = Matrix6::from_fn(|i, j| {
            if j <= i {
                1.0 + 0.1 * (i + 2 * j) as f64
            } else {
                0.0
            }
        });
        let p = l * l.transpose();
        let q_true =
            Matrix6::from_diagonal(&nalgebra::Vector6::new(0.2, 0.2, 0.5, 1e-3, 1e-3, 2e-3));
        let current = f * p * f.transpose() + q_true;
        let (a, q) = stage1_transition(&p, &(f * p), &current).unwrap();
        assert!((a - f).amax() < 1e-9, "A {a}");
        assert!((q - q_true).amax() < 1e-9, "Q {q}");
        // Perfectly correlated (Q = 0) and then some: Q clamped at 0.
        let (_, q) = stage1_transition(&p, &(f * p * 1.01), &(f * p * f.transpose())).unwrap();
        assert!(q.symmetric_eigenvalues().min() >= -1e-9);
        assert!(stage1_transition(&Matrix6::zeros(), &p, &p).is_none());
    }
}
