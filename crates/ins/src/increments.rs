//! Increments from rate samples: the trapezoid rule between two IMU
//! samples, split at any time between them (a GNSS epoch) with the rates
//! interpolated linearly.

use aidnav_frames::Vec3;
use nalgebra::Vector3;

use crate::ned::ImuIncrement;
use crate::samples::ImuSample;

/// Angular rate and specific force at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rates {
    /// Angular rate [rad/s].
    pub angular_rate: Vector3<f64>,
    /// Specific force [m/s²].
    pub specific_force: Vector3<f64>,
}

impl Rates {
    /// The rates of a sample.
    pub fn of(s: &ImuSample) -> Self {
        Self {
            angular_rate: s.angular_rate,
            specific_force: s.specific_force,
        }
    }

    /// The rates at `t` between samples `a` and `b` (linear interpolation;
    /// `t` in [a.time_s, b.time_s]).
    pub fn interpolate(a: &ImuSample, b: &ImuSample, t: f64) -> Self {
        let frac = (t - a.time_s) / (b.time_s - a.time_s);
        Self {
            angular_rate: a.angular_rate + (b.angular_rate - a.angular_rate) * frac,
            specific_force: a.specific_force + (b.specific_force - a.specific_force) * frac,
        }
    }
}

/// The trapezoid-rule increment over `dt_s` between rates `r0` and `r1`.
///
/// ```
/// use aidnav_ins::increments::{Rates, trapezoid};
/// use nalgebra::Vector3;
/// let r0 = Rates { angular_rate: Vector3::zeros(), specific_force: Vector3::new(0.0, 0.0, -9.8) };
/// let r1 = Rates { angular_rate: Vector3::new(0.0, 0.0, 0.2), ..r0 };
/// let inc = trapezoid(&r0, &r1, 0.01);
/// assert!((inc.delta_angle.z() - 0.001).abs() < 1e-15);
/// assert!((inc.delta_velocity.z() + 0.098).abs() < 1e-15);
/// ```
pub fn trapezoid(r0: &Rates, r1: &Rates, dt_s: f64) -> ImuIncrement {
    ImuIncrement {
        dt_s,
        delta_angle: Vec3::assume_in_frame((r0.angular_rate + r1.angular_rate) * (0.5 * dt_s)),
        delta_velocity: Vec3::assume_in_frame(
            (r0.specific_force + r1.specific_force) * (0.5 * dt_s),
        ),
    }
}
