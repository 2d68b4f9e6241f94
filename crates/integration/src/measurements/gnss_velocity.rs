//! A GNSS antenna velocity fix: `z = v̂_ant − v_fix`, with
//! `v_ant = v + Ĉ (ω × l)`; with a GNSS latency state τ the prediction is
//! `v̂_ant − â τ̂` (â the low-passed acceleration) and `z` gains `â δτ`;
//! with a lever-arm state `−Ĉ [ω×] δl`.

use aidnav_frames::{Ned, Vec3};
use aidnav_models::ned_ins::NedErrorModel;
use nalgebra::Vector3;

use super::{Linearized, Measurement, Nominal, diagonal_r, latency, lever_arm, on_layout};

/// A GNSS antenna NED velocity with σ (north, east, down) \[m/s\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssVelocity {
    /// The fix's NED velocity \[m/s\].
    pub velocity_ned_mps: Vec3<Ned>,
    /// σ north, east, down \[m/s\].
    pub sigma_ned_mps: Vector3<f64>,
}

impl<const N: usize> Measurement<3, N> for GnssVelocity {
    const NAME: &'static str = "gnss_velocity";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<3, N> {
        let s = nominal.state;
        let c = s.attitude.matrix();
        let lever_velocity = c * nominal.body_rate.cross(&nominal.antenna_lever_arm);
        let mut v_ant = s.velocity + lever_velocity;
        let mut h: nalgebra::SMatrix<f64, 3, N> = on_layout(&NedErrorModel::velocity_measurement(
            lever_velocity.as_raw(),
        ));
        if let Some((i, tau)) = latency(nominal) {
            v_ant -= nominal.acceleration * tau;
            h.column_mut(i).copy_from(&nominal.acceleration.raw());
        }
        if let Some(i) = lever_arm(nominal) {
            let w = nominal.body_rate.raw();
            h.fixed_view_mut::<3, 3>(0, i)
                .copy_from(&(-c.raw() * w.cross_matrix()));
        }
        Linearized {
            z: (v_ant - self.velocity_ned_mps).raw(),
            h,
            r: diagonal_r(&self.sigma_ned_mps),
        }
    }
}
