//! A GNSS antenna position fix: `z = r̂_ant − r_fix = δr + [(Ĉ l)×] φ + n`.

use aidnav_frames::earth::Geodetic;
use aidnav_models::ned_ins::NedErrorModel;
use nalgebra::Vector3;

use super::{Linearized, Measurement, Nominal, diagonal_r, on_layout};

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
        let antenna = s.position.offset_by(&arm);
        Linearized {
            z: self.fix.ned_to(&antenna).raw(),
            h: on_layout(&NedErrorModel::position_measurement(arm.as_raw())),
            r: diagonal_r(&self.sigma_ned_m),
        }
    }
}
