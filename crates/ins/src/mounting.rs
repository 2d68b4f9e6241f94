//! The IMU's mounting: sensor frame → body frame, by Groves' Euler_to_CTM
//! convention (as the rtklibexplorer data set's upstream uses).

use nalgebra::Matrix3;

use crate::samples::ImuSample;

/// Groves' Euler_to_CTM: the coordinate transformation for (roll, pitch, yaw).
///
/// ```
/// use aidnav_ins::mounting::euler_to_ctm;
/// assert_eq!(euler_to_ctm(0.0, 0.0, 0.0), nalgebra::Matrix3::identity());
/// ```
pub fn euler_to_ctm(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Matrix3::new(
        cp * cy,
        cp * sy,
        -sp,
        -cr * sy + sr * sp * cy,
        cr * cy + sr * sp * sy,
        sr * cp,
        sr * sy + cr * sp * cy,
        -sr * cy + cr * sp * sy,
        cr * cp,
    )
}

/// Shift every sample's time by `time_offset_s` and rotate its specific
/// force and angular rate from the sensor frame into the body frame by the
/// mounting angles (roll, pitch, yaw) \[deg\].
pub fn mount(imu: &mut [ImuSample], mounting_deg: [f64; 3], time_offset_s: f64) {
    let [r, p, y] = mounting_deg.map(f64::to_radians);
    let c = euler_to_ctm(r, p, y);
    for s in imu {
        s.time_s += time_offset_s;
        s.specific_force = c * s.specific_force;
        s.angular_rate = c * s.angular_rate;
    }
}
