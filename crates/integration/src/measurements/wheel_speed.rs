//! A wheel-speed (odometer) sample: the forward speed of the wheel point,
//! `s̃ = (1 + k) u + n` with `u = e_xᵀ (Cᵀ v + ω × l_w)`, the body velocity at
//! the wheel (lever arm `l_w` from the IMU, body frame) and k the
//! odometer's scale-factor error. Predicted `ŝ = (1 + k̂) û`, so
//!
//! ```text
//! z = ŝ − s̃ ≈ (1 + k̂) e_xᵀ (Cᵀ δv − Cᵀ [v×] φ) − û δk,   δk = k − k̂
//! ```
//!
//! (the body-velocity error of the non-holonomic constraint, its first
//! row; the lever-arm term's error through the gyro bias is left out, as
//! for the GNSS velocity).

use aidnav_frames::{Body, Vec3};
use aidnav_models::ned_ins::{ATTITUDE, VELOCITY};
use nalgebra::{Matrix1, SMatrix, Vector1};

use super::{Linearized, Measurement, Nominal};
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
        let s = nominal.state;
        let body = s.attitude.matrix().transpose() * s.velocity;
        body.x() + nominal.body_rate.cross(&self.lever_arm_m).x()
    }
}

impl<const N: usize> Measurement<1, N> for WheelSpeed {
    const NAME: &'static str = "wheel_speed";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<1, N> {
        let s = nominal.state;
        let ct = s.attitude.matrix().transpose();
        let u = self.predicted_speed(nominal);
        let scale = nominal.layout.offset(Augmented::WheelSpeedScale);
        let k = scale.map_or(0.0, |i| nominal.parameters[i]);
        let dv = ct.as_raw().row(0).into_owned();
        let dphi = -(ct.as_raw() * s.velocity.as_raw().cross_matrix()).row(0);
        let mut h = SMatrix::<f64, 1, N>::zeros();
        for c in 0..3 {
            h[(0, VELOCITY + c)] = (1.0 + k) * dv[c];
            h[(0, ATTITUDE + c)] = (1.0 + k) * dphi[c];
        }
        if let Some(i) = scale {
            h[(0, i)] = -u;
        }
        Linearized {
            z: Vector1::new((1.0 + k) * u - self.speed_mps),
            h,
            r: Matrix1::new(self.sigma_mps * self.sigma_mps),
        }
    }
}
