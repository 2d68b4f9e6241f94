//! Coarse alignment at rest: roll and pitch by levelling the mean specific
//! force over a static window, the mean gyro output (bias + Earth rate), and
//! the gyro bias that leaves once the Earth rate is removed.

use aidnav_frames::earth::earth_rate_ned;
use nalgebra::{UnitQuaternion, Vector3};

use crate::samples::ImuSample;

/// What a static window says about the attitude and the gyros.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levelling {
    /// Roll from the mean specific force \[rad\].
    pub roll_rad: f64,
    /// Pitch from the mean specific force \[rad\].
    pub pitch_rad: f64,
    /// Mean angular rate over the window (gyro bias + Earth rate) \[rad/s\].
    pub mean_angular_rate: Vector3<f64>,
}

/// The samples from `imu[start]` that are earlier than `t0 + static_s`.
pub fn static_window(imu: &[ImuSample], start: usize, t0: f64, static_s: f64) -> &[ImuSample] {
    let n = imu[start..]
        .iter()
        .take_while(|s| s.time_s < t0 + static_s)
        .count();
    &imu[start..start + n]
}

/// Level over a static window (body frame: x forward, y right, z down;
/// at rest the specific force is −g in the body frame).
///
/// ```
/// use aidnav_ins::alignment::level;
/// use aidnav_ins::samples::ImuSample;
/// use nalgebra::Vector3;
/// let rest = vec![
///     ImuSample {
///         time_s: 0.0,
///         specific_force: Vector3::new(0.0, 0.0, -9.8),
///         angular_rate: Vector3::new(1e-4, 0.0, 0.0),
///     };
///     10
/// ];
/// let l = level(&rest);
/// assert!(l.roll_rad.abs() < 1e-12 && l.pitch_rad.abs() < 1e-12);
/// assert!((l.mean_angular_rate.x - 1e-4).abs() < 1e-16);
/// ```
pub fn level(window: &[ImuSample]) -> Levelling {
    let n = window.len() as f64;
    let f = window
        .iter()
        .map(|s| s.specific_force)
        .sum::<Vector3<f64>>()
        / n;
    let w = window.iter().map(|s| s.angular_rate).sum::<Vector3<f64>>() / n;
    Levelling {
        roll_rad: (-f.y).atan2(-f.z),
        pitch_rad: f.x.atan2(f.y.hypot(f.z)),
        mean_angular_rate: w,
    }
}

impl Levelling {
    /// The attitude with this roll and pitch and the given heading.
    pub fn attitude(&self, yaw_rad: f64) -> UnitQuaternion<f64> {
        UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, yaw_rad)
    }
}

/// Heading \[rad\] of a NED velocity (the course over ground).
pub fn course(velocity_ned: &Vector3<f64>) -> f64 {
    velocity_ned.y.atan2(velocity_ned.x)
}

/// The gyro bias at rest: the mean gyro output less the Earth rate at the
/// latitude, seen in the body frame of `attitude` (body → NED).
pub fn gyro_bias_at_rest(
    mean_angular_rate: &Vector3<f64>,
    attitude: &UnitQuaternion<f64>,
    latitude_rad: f64,
) -> Vector3<f64> {
    mean_angular_rate - attitude.inverse() * earth_rate_ned(latitude_rad).raw()
}
