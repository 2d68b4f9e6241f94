//! A zero-velocity update at a standstill: `z = v̂ = δv`.

use aidnav_models::ned_ins::VELOCITY;
use nalgebra::{Matrix3, SMatrix};

use super::{Linearized, Measurement, Nominal};

/// The IMU's velocity is zero, σ per axis \[m/s\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZeroVelocity {
    /// σ per axis \[m/s\].
    pub sigma_mps: f64,
}

impl<const N: usize> Measurement<3, N> for ZeroVelocity {
    const NAME: &'static str = "zero_velocity";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<3, N> {
        let mut h = SMatrix::<f64, 3, N>::zeros();
        h.fixed_view_mut::<3, 3>(0, VELOCITY)
            .copy_from(&Matrix3::identity());
        Linearized {
            z: nominal.state.velocity.raw(),
            h,
            r: Matrix3::identity() * (self.sigma_mps * self.sigma_mps),
        }
    }
}
