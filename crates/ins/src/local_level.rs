//! Strapdown mechanization in a local level frame over a flat, non-rotating
//! Earth: East–North–Up navigation axes, body axes forward–left–up, constant
//! gravity. This is the INS of spec 30's formation simulation: a group flies
//! tens of kilometres for minutes, where Earth rate (7e-5 rad/s, below the
//! simulated gyro bias of the INS grade used) and curvature
//! do not change what the group fusion shows. The WGS-84 NED mechanization
//! of spec 40 is the one for real data.
//!
//! One step integrates the attitude with the rotation vector ω Δt (exact for
//! a constant rate over the step), the velocity with the specific force
//! rotated by the mid-step attitude and the position with the trapezoid rule.
//! [`ideal_imu`] is its exact inverse: fed those outputs, the mechanization
//! reproduces a sampled trajectory's attitudes and velocities to rounding.
//!
//! ```
//! use aidnav_ins::local_level::{LocalLevelState, GRAVITY_ENU};
//! use nalgebra::{UnitQuaternion, Vector3};
//! // Level and at rest: the accelerometers read +g on the up axis.
//! let mut ins = LocalLevelState {
//!     position: Vector3::zeros(),
//!     velocity: Vector3::zeros(),
//!     attitude: UnitQuaternion::identity(),
//! };
//! for _ in 0..1000 {
//!     ins.step(&Vector3::zeros(), &-GRAVITY_ENU, 0.01);
//! }
//! assert!(ins.position.norm() < 1e-9);
//! ```

use aidnav_frames::constants::STANDARD_GRAVITY_M_S2;
use nalgebra::{UnitQuaternion, Vector3};

/// Gravity in the local ENU frame [m/s²] (standard gravity, down).
pub const GRAVITY_ENU: Vector3<f64> = Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_M_S2);

/// Position, velocity (local ENU) and attitude (body FLU → ENU) of one INS.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalLevelState {
    /// Position \[m\].
    pub position: Vector3<f64>,
    /// Velocity [m/s].
    pub velocity: Vector3<f64>,
    /// Rotation body → navigation frame.
    pub attitude: UnitQuaternion<f64>,
}

impl LocalLevelState {
    /// One mechanization step over `dt_s` with the body angular rate and
    /// specific force held constant over the step.
    pub fn step(&mut self, angular_rate: &Vector3<f64>, specific_force: &Vector3<f64>, dt_s: f64) {
        let half = UnitQuaternion::from_scaled_axis(angular_rate * (0.5 * dt_s));
        let f_nav = (self.attitude * half) * specific_force;
        let velocity = self.velocity + (f_nav + GRAVITY_ENU) * dt_s;
        self.position += (self.velocity + velocity) * (0.5 * dt_s);
        self.velocity = velocity;
        self.attitude *= half * half;
    }

    /// Specific force rotated to the navigation frame at the current attitude.
    pub fn specific_force_nav(&self, specific_force: &Vector3<f64>) -> Vector3<f64> {
        self.attitude * specific_force
    }
}

/// The error-free (angular rate, specific force) that carry the mechanization
/// from `from` to `to` in `dt_s`: the exact inverse of [`LocalLevelState::step`]
/// for attitude and velocity.
pub fn ideal_imu(
    from: &LocalLevelState,
    to: &LocalLevelState,
    dt_s: f64,
) -> (Vector3<f64>, Vector3<f64>) {
    let rate = (from.attitude.inverse() * to.attitude).scaled_axis() / dt_s;
    let half = UnitQuaternion::from_scaled_axis(rate * (0.5 * dt_s));
    let accel = (to.velocity - from.velocity) / dt_s - GRAVITY_ENU;
    let force = (from.attitude * half).inverse() * accel;
    (rate, force)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A climbing, turning, rolling trajectory sampled analytically.
    fn truth(t: f64) -> LocalLevelState {
        let position = Vector3::new(
            60.0 * t + 200.0 * (0.05 * t).sin(),
            300.0 * (0.03 * t).sin(),
            5.0 * t,
        );
        let velocity = Vector3::new(60.0 + 10.0 * (0.05 * t).cos(), 9.0 * (0.03 * t).cos(), 5.0);
        let attitude = UnitQuaternion::from_euler_angles(
            0.1 * (0.2 * t).sin(),
            -0.05,
            velocity.y.atan2(velocity.x),
        );
        LocalLevelState {
            position,
            velocity,
            attitude,
        }
    }

    #[test]
    fn ideal_imu_reproduces_the_trajectory() {
        let dt = 0.01;
        let mut ins = truth(0.0);
        let steps = 30_000; // 300 s
        for k in 0..steps {
            let (from, to) = (truth(k as f64 * dt), truth((k + 1) as f64 * dt));
            let (w, f) = ideal_imu(&from, &to, dt);
            ins.step(&w, &f, dt);
        }
        let end = truth(steps as f64 * dt);
        assert!((ins.velocity - end.velocity).norm() < 1e-8);
        assert!(ins.attitude.angle_to(&end.attitude) < 1e-9);
        // Trapezoid rule on an analytic path: O(dt²) per unit time.
        assert!((ins.position - end.position).norm() < 1e-3);
    }

    #[test]
    fn accelerometer_bias_integrates_twice_into_position() {
        let dt = 0.01;
        let mut ins = LocalLevelState {
            position: Vector3::zeros(),
            velocity: Vector3::zeros(),
            attitude: UnitQuaternion::identity(),
        };
        let bias = Vector3::new(1e-2, 0.0, 0.0);
        for _ in 0..10_000 {
            ins.step(&Vector3::zeros(), &(-GRAVITY_ENU + bias), dt);
        }
        // ½ b t² at t = 100 s.
        assert!((ins.position.x - 50.0).abs() < 1e-6);
    }
}
