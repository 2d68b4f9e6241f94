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

use aidnav_frames::{Body, Ned, Vec3};
use aidnav_ins::ned::NedState;
use aidnav_models::ned_ins::STATES;
use nalgebra::{Matrix3, Matrix3x2, SMatrix, SVector, Vector3};

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
    /// The navigation-frame acceleration, low-passed (zero unless the
    /// layout has a GNSS latency state, whose velocity model needs it)
    /// \[m/s²\].
    pub acceleration: Vec3<Ned>,
    /// The GNSS antenna's lever arm (body frame, IMU → antenna) \[m\].
    pub antenna_lever_arm: Vec3<Body>,
    /// The rotation body → vehicle frame of the vehicle constraints
    /// (identity unless the IMU is misaligned against the vehicle):
    /// `v_vehicle = C_vb v_body`.
    pub vehicle_from_body: Matrix3<f64>,
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

/// The GNSS latency state's index and nominal value τ̂ \[s\] (None: no
/// latency state). A fix stamped t is the antenna at t − τ: predicted by
/// `x̂(t) − ẋ̂ τ̂`, so its H column is `+ẋ` (the state is τ − τ̂).
pub(crate) fn latency<const N: usize>(nominal: &Nominal<'_, N>) -> Option<(usize, f64)> {
    let i = nominal
        .layout
        .offset(crate::state::Augmented::GnssLatency)?;
    Some((i, nominal.parameters[i]))
}

/// The first index of the lever-arm block (None: the lever arm is known).
/// The block's nominal value is the filter's lever arm
/// ([`Nominal::antenna_lever_arm`]); the state is l − l̂, so an antenna
/// predicted at `r + C l̂` is `−C` in it.
pub(crate) fn lever_arm<const N: usize>(nominal: &Nominal<'_, N>) -> Option<usize> {
    nominal.layout.offset(crate::state::Augmented::LeverArm)
}

/// The vehicle misalignment block's index and the H columns of a
/// vehicle-frame velocity `v^v = C_vb u` in its two states (None: the
/// misalignment is known). `C_vb = R_z(ψ) R_y(θ) R_x(φ)` with the nominal
/// θ̂, ψ̂ the block holds; the states are θ − θ̂, ψ − ψ̂. As
/// `∂C/∂θ = [(R_z e_y)×] C` and `∂C/∂ψ = [e_z×] C`, the predicted-minus-true
/// velocity is `v^v × a` per state with `a_θ = R_z(ψ̂) e_y`, `a_ψ = e_z`:
/// these are the columns (all three rows; a measurement takes its own).
pub(crate) fn misalignment_columns<const N: usize>(
    nominal: &Nominal<'_, N>,
    vehicle_velocity: &Vector3<f64>,
) -> Option<(usize, Matrix3x2<f64>)> {
    let i = nominal
        .layout
        .offset(crate::state::Augmented::VehicleMisalignment)?;
    let yaw = nominal.parameters[i + 1];
    let a_pitch = Vector3::new(-yaw.sin(), yaw.cos(), 0.0);
    Some((
        i,
        Matrix3x2::from_columns(&[
            vehicle_velocity.cross(&a_pitch),
            vehicle_velocity.cross(&Vector3::z()),
        ]),
    ))
}

/// A diagonal R from σ per component.
pub(crate) fn diagonal_r<const M: usize>(sigma: &SVector<f64, M>) -> SMatrix<f64, M, M> {
    SMatrix::from_diagonal(&sigma.map(|v| v * v))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::state::{Augmented, BlockDynamics};
    use aidnav_frames::earth::Geodetic;
    use aidnav_frames::{Rotation, Vec3};
    use nalgebra::Vector3;

    /// A car turning at 10 m/s with 2 m/s² of centripetal acceleration,
    /// the antenna 1 m up and 0.5 m behind.
    fn turning() -> (NedState, Vec3<Body>, Vec3<Ned>) {
        let state = NedState {
            position: Geodetic {
                latitude_rad: 0.6,
                longitude_rad: 2.0,
                height_m: 30.0,
            },
            velocity: Vec3::new(6.0, 8.0, 0.0),
            attitude: Rotation::from_euler_angles(0.02, -0.01, 0.93),
        };
        (state, Vec3::new(0.0, 0.0, 0.2), Vec3::new(-1.6, 1.2, 0.05))
    }

    /// z at a nominal latency τ̂ (state 21 of a 22-state layout).
    fn z_at<const M: usize, Meas: Measurement<M, 22>>(meas: &Meas, tau: f64) -> Linearized<M, 22> {
        let (state, rate, acceleration) = turning();
        let layout = StateLayout::base().with(Augmented::GnssLatency, BlockDynamics::constant(0.3));
        let mut parameters = SVector::<f64, 22>::zeros();
        parameters[21] = tau;
        let instruments = InstrumentEstimate::default();
        meas.linearize(&Nominal {
            state: &state,
            body_rate: rate,
            acceleration,
            antenna_lever_arm: Vec3::new(-0.5, 0.0, -1.0),
            vehicle_from_body: Matrix3::identity(),
            instruments: &instruments,
            parameters: &parameters,
            layout: &layout,
        })
    }

    /// The latency columns of the GNSS position and velocity H against a
    /// central finite difference of z in the nominal latency: the state is
    /// τ − τ̂, so ∂z/∂τ̂ = −H[:, τ]; and the position is predicted back by
    /// v τ̂ − ½ a τ̂².
    #[test]
    fn latency_columns_are_the_derivatives_of_the_prediction() {
        let (state, _, acceleration) = turning();
        let fix = state.position.offset_by(&Vec3::new(0.3, -0.2, 0.1));
        let position = GnssPosition {
            fix,
            sigma_ned_m: Vector3::repeat(0.02),
        };
        let velocity = GnssVelocity {
            velocity_ned_mps: Vec3::new(6.1, 7.9, 0.0),
            sigma_ned_mps: Vector3::repeat(0.05),
        };
        let (tau, d) = (0.2, 1e-4);
        let lin = z_at(&position, tau);
        let fd = (z_at(&position, tau + d).z - z_at(&position, tau - d).z) / (2.0 * d);
        for r in 0..3 {
            assert!(
                (fd[r] + lin.h[(r, 21)]).abs() < 1e-4,
                "{fd} vs {}",
                lin.h.column(21)
            );
        }
        // 0.2 s back at ~10 m/s: about 2 m, minus the turn's ½ a τ².
        let shift = z_at(&position, 0.0).z - lin.z;
        assert!((shift.norm() - 2.0).abs() < 0.1, "{shift}");
        let lin = z_at(&velocity, tau);
        let fd = (z_at(&velocity, tau + d).z - z_at(&velocity, tau - d).z) / (2.0 * d);
        for r in 0..3 {
            assert!((fd[r] + lin.h[(r, 21)]).abs() < 1e-9);
            assert!((lin.h[(r, 21)] - acceleration.raw()[r]).abs() < 1e-12);
        }
        // Without the state the models are the plain ones.
        let base = StateLayout::base();
        assert_eq!(base.offset(Augmented::GnssLatency), None);
    }

    /// z at a nominal lever arm l̂ (states 21–23 of a 24-state layout).
    fn z_at_arm<const M: usize, Meas: Measurement<M, 24>>(
        meas: &Meas,
        arm: Vector3<f64>,
    ) -> Linearized<M, 24> {
        let (state, rate, acceleration) = turning();
        let layout = StateLayout::base().with(Augmented::LeverArm, BlockDynamics::constant(1.0));
        let mut parameters = SVector::<f64, 24>::zeros();
        parameters.fixed_rows_mut::<3>(21).copy_from(&arm);
        let instruments = InstrumentEstimate::default();
        meas.linearize(&Nominal {
            state: &state,
            body_rate: rate,
            acceleration,
            antenna_lever_arm: Vec3::assume_in_frame(arm),
            vehicle_from_body: Matrix3::identity(),
            instruments: &instruments,
            parameters: &parameters,
            layout: &layout,
        })
    }

    /// The lever-arm columns of the GNSS position and velocity H against
    /// a central finite difference of z in the nominal lever arm (the
    /// state is l − l̂, so ∂z/∂l̂ = −H[:, l]).
    #[test]
    fn lever_arm_columns_are_the_derivatives_of_the_prediction() {
        let (state, _, _) = turning();
        let position = GnssPosition {
            fix: state.position.offset_by(&Vec3::new(0.3, -0.2, 0.1)),
            sigma_ned_m: Vector3::repeat(0.02),
        };
        let velocity = GnssVelocity {
            velocity_ned_mps: Vec3::new(6.1, 7.9, 0.0),
            sigma_ned_mps: Vector3::repeat(0.05),
        };
        let (arm, d) = (Vector3::new(-0.5, 0.2, -1.0), 1e-4);
        for axis in 0..3 {
            let step = Vector3::ith(axis, d);
            let lin = z_at_arm(&position, arm);
            let fd =
                (z_at_arm(&position, arm + step).z - z_at_arm(&position, arm - step).z) / (2.0 * d);
            for r in 0..3 {
                // Metres on the ellipsoid: the offset's curvature is ~1e-6.
                assert!(
                    (fd[r] + lin.h[(r, 21 + axis)]).abs() < 1e-5,
                    "{fd} vs {}",
                    lin.h
                );
            }
            let lin = z_at_arm(&velocity, arm);
            let fd =
                (z_at_arm(&velocity, arm + step).z - z_at_arm(&velocity, arm - step).z) / (2.0 * d);
            for r in 0..3 {
                assert!(
                    (fd[r] + lin.h[(r, 21 + axis)]).abs() < 1e-9,
                    "{fd} vs {}",
                    lin.h
                );
            }
        }
        // The position column of a forward arm is the heading's direction.
        let lin = z_at_arm(&position, arm);
        let heading = state.attitude.matrix().raw().column(0).into_owned();
        assert!((lin.h.fixed_view::<3, 1>(0, 21) + heading).norm() < 1e-12);
    }

    /// z at a nominal vehicle misalignment (pitch, yaw; states 21–22 of a
    /// 23-state layout), the roll 0.02 rad.
    fn z_at_misalignment<const M: usize, Meas: Measurement<M, 23>>(
        meas: &Meas,
        pitch: f64,
        yaw: f64,
    ) -> Linearized<M, 23> {
        let (state, rate, acceleration) = turning();
        let layout =
            StateLayout::base().with(Augmented::VehicleMisalignment, BlockDynamics::constant(0.1));
        let mut parameters = SVector::<f64, 23>::zeros();
        parameters[21] = pitch;
        parameters[22] = yaw;
        let instruments = InstrumentEstimate::default();
        meas.linearize(&Nominal {
            state: &state,
            body_rate: rate,
            acceleration,
            antenna_lever_arm: Vec3::zeros(),
            vehicle_from_body: nalgebra::Rotation3::from_euler_angles(0.02, pitch, yaw)
                .into_inner(),
            instruments: &instruments,
            parameters: &parameters,
            layout: &layout,
        })
    }

    /// The misalignment columns of the non-holonomic and wheel-speed H
    /// against a central finite difference of z in the nominal pitch and
    /// yaw (the states are truth − nominal, so ∂z/∂θ̂ = −H[:, θ]); and the
    /// constraint's z is the vehicle-frame velocity.
    #[test]
    fn misalignment_columns_are_the_derivatives_of_the_prediction() {
        let constraint = NonHolonomicConstraint { sigma_mps: 0.1 };
        let wheel = WheelSpeed {
            speed_mps: 10.0,
            sigma_mps: 0.1,
            lever_arm_m: Vec3::new(-1.3, 0.2, 0.3),
        };
        let (pitch, yaw, d) = (0.05, -0.08, 1e-6);
        for state in 0..2 {
            let at = |dx: f64| {
                if state == 0 {
                    (pitch + dx, yaw)
                } else {
                    (pitch, yaw + dx)
                }
            };
            let (pp, yp) = at(d);
            let (pm, ym) = at(-d);
            let lin = z_at_misalignment(&constraint, pitch, yaw);
            let fd = (z_at_misalignment(&constraint, pp, yp).z
                - z_at_misalignment(&constraint, pm, ym).z)
                / (2.0 * d);
            for r in 0..2 {
                assert!(
                    (fd[r] + lin.h[(r, 21 + state)]).abs() < 1e-6,
                    "{fd} vs {}",
                    lin.h
                );
            }
            let lin = z_at_misalignment(&wheel, pitch, yaw);
            let fd = (z_at_misalignment(&wheel, pp, yp).z - z_at_misalignment(&wheel, pm, ym).z)
                / (2.0 * d);
            assert!(
                (fd[0] + lin.h[(0, 21 + state)]).abs() < 1e-6,
                "{fd} vs {}",
                lin.h
            );
        }
        // The constraint's z: the velocity in the vehicle frame.
        let (state, _, _) = turning();
        let c_vb = nalgebra::Rotation3::from_euler_angles(0.02, pitch, yaw).into_inner();
        let vehicle = c_vb * (state.attitude.matrix().transpose() * state.velocity).raw();
        let lin = z_at_misalignment(&constraint, pitch, yaw);
        assert!((lin.z - vehicle.fixed_rows::<2>(1)).norm() < 1e-12);
        // A 3° pitch at 10 m/s: the vertical row moves by ~0.52 m/s.
        let level = z_at_misalignment(&constraint, 0.0, yaw).z;
        let pitched = z_at_misalignment(&constraint, 3f64.to_radians(), yaw).z;
        assert!(
            ((pitched - level).y.abs() - 0.52).abs() < 0.01,
            "{pitched} {level}"
        );
    }
}
