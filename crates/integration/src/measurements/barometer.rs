//! A barometric height: `h̃ = h + b + n` (b the barometer's bias against
//! the ellipsoidal height, a state when the layout has one). Predicted
//! `ĥ + b̂`, so with δr_D = D̂ − D = −(ĥ − h):
//!
//! ```text
//! z = ĥ + b̂ − h̃ = −δr_D − δb,   δb = b − b̂
//! ```

use aidnav_models::ned_ins::POSITION;
use nalgebra::{Matrix1, SMatrix, Vector1};

use super::{Linearized, Measurement, Nominal};
use crate::state::Augmented;

/// One barometric height with its σ, taken at the IMU.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Barometer {
    /// Measured height \[m\].
    pub height_m: f64,
    /// σ of the height \[m\].
    pub sigma_m: f64,
}

impl<const N: usize> Measurement<1, N> for Barometer {
    const NAME: &'static str = "barometer";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<1, N> {
        let bias = nominal.layout.offset(Augmented::BaroBias);
        let b = bias.map_or(0.0, |i| nominal.parameters[i]);
        let mut h = SMatrix::<f64, 1, N>::zeros();
        h[(0, POSITION + 2)] = -1.0;
        if let Some(i) = bias {
            h[(0, i)] = -1.0;
        }
        Linearized {
            z: Vector1::new(nominal.state.position.height_m + b - self.height_m),
            h,
            r: Matrix1::new(self.sigma_m * self.sigma_m),
        }
    }
}
