//! A GNSS antenna position fix: `z = r̂_ant − r_fix = δr + [(Ĉ l)×] φ + n`;
//! with a GNSS latency state τ (the fix is the antenna τ before its time
//! tag) the prediction is `r̂_ant − v̂_ant τ̂ + ½ â τ̂²` and `z` gains
//! `(v̂_ant − â τ̂) δτ`; with a lever-arm state `−Ĉ δl`.

use aidnav_frames::earth::Geodetic;
use aidnav_models::ned_ins::NedErrorModel;
use nalgebra::Vector3;

use crate::ned::antenna_of_solution;

use super::{Linearized, Measurement, Nominal, diagonal_r, latency, lever_arm, on_layout};

/// A GNSS antenna position with σ (north, east, down) \[m\].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssPosition {
    /// The fix.
    pub fix: Geodetic,
    /// σ north, east, down \[m\].
    pub sigma_ned_m: Vector3<f64>,
}

impl<const N: usize> Measurement<3, N> for GnssPosition {
    const NAME: &'static str = "gnss_position";

    fn linearize(&self, nominal: &Nominal<'_, N>) -> Linearized<3, N> {
        let s = nominal.state;
        let c = s.attitude.matrix();
        // The INS's own antenna: in open loop the estimate x is part of H x.
        let arm = c * nominal.antenna_lever_arm;
        let (mut antenna, v_ant) =
            antenna_of_solution(s, nominal.antenna_lever_arm, nominal.body_rate);
        let mut h: nalgebra::SMatrix<f64, 3, N> =
            on_layout(&NedErrorModel::position_measurement(arm.as_raw()));
        if let Some((i, tau)) = latency(nominal) {
            // To second order: in a turn the centripetal ½ a τ² is
            // centimetres at tenths of a second.
            let a = nominal.acceleration;
            antenna = antenna.offset_by(&(v_ant * -tau + a * (0.5 * tau * tau)));
            h.column_mut(i).copy_from(&(v_ant - a * tau).raw());
        }
        if let Some(i) = lever_arm(nominal) {
            h.fixed_view_mut::<3, 3>(0, i).copy_from(&-c.raw());
        }
        Linearized {
            z: self.fix.ned_to(&antenna).raw(),
            h,
            r: diagonal_r(&self.sigma_ned_m),
        }
    }
}
