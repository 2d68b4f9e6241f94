//! Measurement models of the NED filter, one file each: a measurement is
//! what it measures (its sample), and from the filter's nominal state it
//! gives `z` (predicted minus measured), `H` (∂z/∂x over the layout's
//! states) and `R`. The filter has one update sequence for all of them
//! ([`NedFilter::fuse`](crate::ned::NedFilter::fuse)).
//!
//! Error-state convention (spec 40, [`aidnav_models::ned_ins`]): δr, δv, φ
//! are the INS minus the truth; the instrument and added states are the
//! correction the nominal value needs (truth minus nominal), so feedback
//! adds them. Either way `z ≈ H x + n`.

use aidnav_frames::{Body, Vec3};
use aidnav_ins::ned::NedState;
use aidnav_models::ned_ins::STATES;
use nalgebra::{SMatrix, SVector};

use crate::ned::InstrumentEstimate;
use crate::state::StateLayout;

mod barometer;
mod gnss_position;
mod gnss_velocity;
mod non_holonomic;
mod wheel_speed;
mod zero_angular_rate;
mod zero_velocity;

pub use barometer::Barometer;
pub use gnss_position::GnssPosition;
pub use gnss_velocity::GnssVelocity;
pub use non_holonomic::NonHolonomicConstraint;
pub use wheel_speed::WheelSpeed;
pub use zero_angular_rate::ZeroAngularRate;
pub use zero_velocity::ZeroVelocity;

/// What a measurement model sees of the filter: the nominal (INS) state
/// and everything else a predicted measurement depends on.
#[derive(Debug, Clone, Copy)]
pub struct Nominal<'a, const N: usize> {
    /// The INS's navigation state (not corrected by the estimate in open
    /// loop: there the estimate is part of `H x`).
    pub state: &'a NedState,
    /// The corrected body rate of the last IMU increment \[rad/s\].
    pub body_rate: Vec3<Body>,
    /// The GNSS antenna's lever arm (body frame, IMU → antenna) \[m\].
    pub antenna_lever_arm: Vec3<Body>,
    /// The instrument corrections in use.
    pub instruments: &'a InstrumentEstimate,
    /// Nominal values of the added states (by state index; the base 21
    /// entries are 0): each block's unit.
    pub parameters: &'a SVector<f64, N>,
    /// Where each added block sits.
    pub layout: &'a StateLayout,
}

/// A measurement linearised at the nominal state.
#[derive(Debug, Clone, PartialEq)]
pub struct Linearized<const M: usize, const N: usize> {
    /// Predicted minus measured.
    pub z: SVector<f64, M>,
    /// ∂z/∂x.
    pub h: SMatrix<f64, M, N>,
    /// Measurement noise covariance.
    pub r: SMatrix<f64, M, M>,
}

/// A measurement of `M` components for a filter of `N` states.
pub trait Measurement<const M: usize, const N: usize> {
    /// The measurement's name in records and outputs (snake_case).
    const NAME: &'static str;

    /// `z`, `H`, `R` at the nominal state.
    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<M, N>;
}

/// An H over the base 21 states, on the `N` states of a layout (the added
/// columns zero). `N ≥ 21` holds for every filter (the layout starts with
/// the base states).
pub(crate) fn on_layout<const M: usize, const N: usize>(
    h: &SMatrix<f64, M, STATES>,
) -> SMatrix<f64, M, N> {
    let mut out = SMatrix::<f64, M, N>::zeros();
    out.fixed_view_mut::<M, STATES>(0, 0).copy_from(h);
    out
}

/// A diagonal R from σ per component.
pub(crate) fn diagonal_r<const M: usize>(sigma: &SVector<f64, M>) -> SMatrix<f64, M, M> {
    SMatrix::from_diagonal(&sigma.map(|v| v * v))
}
