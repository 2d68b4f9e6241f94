//! A zero-angular-rate update at a standstill: the body turns with the
//! Earth only, so the corrected mean gyro output less the Earth rate in the
//! body frame is the remaining gyro bias error.

use aidnav_frames::earth::earth_rate_ned;
use aidnav_models::ned_ins::GYRO_BIAS;
use nalgebra::{Matrix3, SMatrix, Vector3};

use super::{Linearized, Measurement, Nominal, diagonal_r};

/// The mean raw gyro output of a still window and its σ per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZeroAngularRate {
    /// Raw body-frame rates averaged over the standstill \[rad/s\].
    pub mean_raw_rate_rad_s: Vector3<f64>,
    /// σ per axis \[rad/s\] (the window's noise of the mean).
    pub sigma_rad_s: Vector3<f64>,
}

impl<const N: usize> Measurement<3, N> for ZeroAngularRate {
    const NAME: &'static str = "zero_angular_rate";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<3, N> {
        let s = nominal.state;
        let inst = nominal.instruments;
        let one = Vector3::repeat(1.0);
        let corrected =
            (self.mean_raw_rate_rad_s - inst.gyro_bias).component_div(&(one + inst.gyro_scale));
        let earth_body = s.attitude.matrix().transpose() * earth_rate_ned(s.position.latitude_rad);
        // ω = (ω̃ − b)/(1 + s): ∂ω/∂b = −1/(1 + s); the error state is the
        // excess of the corrected rate, fed back as b += δb.
        let mut h = SMatrix::<f64, 3, N>::zeros();
        h.fixed_view_mut::<3, 3>(0, GYRO_BIAS)
            .copy_from(&Matrix3::from_diagonal(
                &(one + inst.gyro_scale).map(|v| 1.0 / v),
            ));
        Linearized {
            z: corrected - earth_body.raw(),
            h,
            r: diagonal_r(&self.sigma_rad_s),
        }
    }
}
