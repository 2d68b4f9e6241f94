//! The non-holonomic constraint of a land vehicle on its wheels: zero
//! lateral and vertical body velocity, `z = (v^b_y, v^b_z)`.

use aidnav_models::ned_ins::NedErrorModel;
use nalgebra::{Matrix2, Vector2};

use super::{Linearized, Measurement, Nominal, on_layout};

/// Zero lateral and vertical body velocity with σ \[m/s\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonHolonomicConstraint {
    /// σ of each component \[m/s\].
    pub sigma_mps: f64,
}

impl<const N: usize> Measurement<2, N> for NonHolonomicConstraint {
    const NAME: &'static str = "non_holonomic";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<2, N> {
        let s = nominal.state;
        let c = s.attitude.matrix();
        let body = c.transpose() * s.velocity;
        Linearized {
            z: Vector2::new(body.y(), body.z()),
            h: on_layout(&NedErrorModel::non_holonomic_measurement(
                c.as_raw(),
                s.velocity.as_raw(),
            )),
            r: Matrix2::identity() * (self.sigma_mps * self.sigma_mps),
        }
    }
}
