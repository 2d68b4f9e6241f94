//! The non-holonomic constraint of a land vehicle on its wheels: zero
//! lateral and vertical vehicle-frame velocity, `z = (v^v_y, v^v_z)` with
//! `v^v = C_vb Cᵀ v` (the vehicle frame is the body frame unless the IMU
//! is misaligned against the vehicle, [`Nominal::vehicle_from_body`]).

use aidnav_models::ned_ins::NedErrorModel;
use nalgebra::{Matrix2, Vector2};

use super::{Linearized, Measurement, Nominal, misalignment_columns, on_layout};

/// Zero lateral and vertical vehicle velocity with σ \[m/s\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonHolonomicConstraint {
    /// σ of each component \[m/s\].
    pub sigma_mps: f64,
}

impl<const N: usize> Measurement<2, N> for NonHolonomicConstraint {
    const NAME: &'static str = "non_holonomic";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<2, N> {
        let s = nominal.state;
        // Vehicle → NED: the constraint's rows are the vehicle axes.
        let c_nv = s.attitude.matrix().as_raw() * nominal.vehicle_from_body.transpose();
        let vehicle = c_nv.transpose() * s.velocity.as_raw();
        let mut h: nalgebra::SMatrix<f64, 2, N> = on_layout(
            &NedErrorModel::non_holonomic_measurement(&c_nv, s.velocity.as_raw()),
        );
        if let Some((i, columns)) = misalignment_columns(nominal, &vehicle) {
            h.fixed_view_mut::<2, 2>(0, i)
                .copy_from(&columns.fixed_rows::<2>(1));
        }
        Linearized {
            z: Vector2::new(vehicle.y, vehicle.z),
            h,
            r: Matrix2::identity() * (self.sigma_mps * self.sigma_mps),
        }
    }
}
