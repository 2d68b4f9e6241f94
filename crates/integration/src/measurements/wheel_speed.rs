//! A wheel-speed (odometer) sample: the forward speed of the wheel point,
//! `s̃ = (1 + k) u + n` with `u = e_xᵀ C_vb (Cᵀ v + ω × l_w)`, the vehicle
//! velocity at the wheel (lever arm `l_w` from the IMU, body frame; `C_vb`
//! the body → vehicle rotation, [`Nominal::vehicle_from_body`]) and k the
//! odometer's scale-factor error. Predicted `ŝ = (1 + k̂) û`, so
//!
//! ```text
//! z = ŝ − s̃ ≈ (1 + k̂) e_xᵀ C_vb (Cᵀ δv − Cᵀ [v×] φ) − û δk,   δk = k − k̂
//! ```
//!
//! (the vehicle-velocity error of the non-holonomic constraint, its first
//! row, and its misalignment columns when the layout estimates them; the
//! lever-arm term's error through the gyro bias is left out, as for the
//! GNSS velocity).

use aidnav_frames::{Body, Vec3};
use aidnav_models::ned_ins::{ATTITUDE, VELOCITY};
use nalgebra::{Matrix1, SMatrix, Vector1};

use super::{Linearized, Measurement, Nominal, misalignment_columns};
use crate::state::Augmented;

/// One forward wheel speed with its σ and the wheel's place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpeed {
    /// Measured forward speed \[m/s\].
    pub speed_mps: f64,
    /// σ of the speed \[m/s\].
    pub sigma_mps: f64,
    /// Lever arm from the IMU to the wheel's contact point (body frame) \[m\].
    pub lever_arm_m: Vec3<Body>,
}

impl WheelSpeed {
    /// The forward speed of the wheel point the nominal state predicts,
    /// before the scale factor.
    pub fn predicted_speed<const N: usize>(&self, nominal: &Nominal<'_, N>) -> f64 {
        self.vehicle_velocity(nominal).x
    }

    /// The vehicle-frame velocity of the wheel point \[m/s\].
    fn vehicle_velocity<const N: usize>(&self, nominal: &Nominal<'_, N>) -> nalgebra::Vector3<f64> {
        let s = nominal.state;
        let body = s.attitude.matrix().transpose() * s.velocity
            + nominal.body_rate.cross(&self.lever_arm_m);
        nominal.vehicle_from_body * body.raw()
    }
}

impl<const N: usize> Measurement<1, N> for WheelSpeed {
    const NAME: &'static str = "wheel_speed";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<1, N> {
        let s = nominal.state;
        // NED → vehicle.
        let c_vn = nominal.vehicle_from_body * s.attitude.matrix().transpose().as_raw();
        let vehicle = self.vehicle_velocity(nominal);
        let u = vehicle.x;
        let scale = nominal.layout.offset(Augmented::WheelSpeedScale);
        let k = scale.map_or(0.0, |i| nominal.parameters[i]);
        let dv = c_vn.row(0).into_owned();
        let dphi = -(c_vn * s.velocity.as_raw().cross_matrix()).row(0);
        let mut h = SMatrix::<f64, 1, N>::zeros();
        for c in 0..3 {
            h[(0, VELOCITY + c)] = (1.0 + k) * dv[c];
            h[(0, ATTITUDE + c)] = (1.0 + k) * dphi[c];
        }
        if let Some(i) = scale {
            h[(0, i)] = -u;
        }
        if let Some((i, columns)) = misalignment_columns(nominal, &vehicle) {
            h[(0, i)] = (1.0 + k) * columns[(0, 0)];
            h[(0, i + 1)] = (1.0 + k) * columns[(0, 1)];
        }
        Linearized {
            z: Vector1::new((1.0 + k) * u - self.speed_mps),
            h,
            r: Matrix1::new(self.sigma_mps * self.sigma_mps),
        }
    }
}
