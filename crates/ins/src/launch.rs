//! The launch-frame INS of spec 10 (seed 000): navigation equation
//! `r̈ = Dᵀ f_B + g(r)` integrated from the measured attitude angles and
//! specific force, and the twelve slowly varying instrument errors
//! (paper's ММО): accelerometer bias and scale factor, attitude-angle offset
//! and drift, per axis.
//!
//! ```
//! use aidnav_frames::launch::LaunchAttitude;
//! use aidnav_ins::launch::LaunchInstrumentErrors;
//! use nalgebra::Vector3;
//! let e = LaunchInstrumentErrors::table2(1.0);
//! let truth = LaunchAttitude { yaw: 0.0, pitch: 1.0, roll: 0.0 };
//! let f = Vector3::new(30.0, 0.0, 0.0);
//! let (att, f_meas) = e.measure(10.0, &truth, &f);
//! assert!((att.pitch - (1.0 + 5.25e-2 + 2.33e-4 * 10.0)).abs() < 1e-15);
//! let (att_back, f_back) = e.correct(10.0, &att, &f_meas);
//! assert!((att_back.pitch - 1.0).abs() < 1e-15 && (f_back - f).norm() < 1e-12);
//! ```

use aidnav_frames::launch::{LaunchAttitude, central_gravity};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The twelve instrument errors (spec 10): `f̃ = f + Δa0 + K ⊙ f` per
/// accelerometer axis and `b̃ = b + Δb0 + ω_b t` per angle (ψ, ϑ, γ).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchInstrumentErrors {
    /// Accelerometer biases Δa0 (X1, Y1, Z1) [m/s²].
    pub accel_bias: Vector3<f64>,
    /// Accelerometer scale-factor errors K (X1, Y1, Z1).
    pub accel_scale: Vector3<f64>,
    /// Angle offsets Δb0 (ψ, ϑ, γ) \[rad\].
    pub angle_offset: Vector3<f64>,
    /// Angle drifts ω_b (ψ, ϑ, γ) [rad/s].
    pub angle_drift: Vector3<f64>,
}

/// Number of instrument errors the filter estimates (paper eq. 2).
pub const ESTIMATED: usize = 8;

impl LaunchInstrumentErrors {
    /// Table 2 of the paper, every component with the sign `sign` (±1).
    pub fn table2(sign: f64) -> Self {
        Self::table2_signed(&[sign; 12])
    }

    /// Table 2 with a sign per component, in the order bias x y z, scale
    /// x y z, offset ψ ϑ γ, drift ψ ϑ γ.
    pub fn table2_signed(signs: &[f64; 12]) -> Self {
        let v = |i: usize, value: f64| {
            Vector3::new(signs[i] * value, signs[i + 1] * value, signs[i + 2] * value)
        };
        Self {
            accel_bias: v(0, 5.01e-2),
            accel_scale: v(3, 2.46e-2),
            angle_offset: v(6, 5.25e-2),
            angle_drift: v(9, 2.33e-4),
        }
    }

    /// The errors an 8-state estimate `(Δẍ10, Δÿ10, Δz̈10, K_ẍ1, Δψ0, Δϑ0,
    /// ω_ψ, ω_ϑ)` stands for (the four unestimated ones zero).
    pub fn from_estimate(x: &[f64; ESTIMATED]) -> Self {
        Self {
            accel_bias: Vector3::new(x[0], x[1], x[2]),
            accel_scale: Vector3::new(x[3], 0.0, 0.0),
            angle_offset: Vector3::new(x[4], x[5], 0.0),
            angle_drift: Vector3::new(x[6], x[7], 0.0),
        }
    }

    /// The eight estimated components, in the filter's order.
    pub fn estimated_components(&self) -> [f64; ESTIMATED] {
        [
            self.accel_bias.x,
            self.accel_bias.y,
            self.accel_bias.z,
            self.accel_scale.x,
            self.angle_offset.x,
            self.angle_offset.y,
            self.angle_drift.x,
            self.angle_drift.y,
        ]
    }

    /// Angle errors (yaw, pitch, roll) at time t: offset plus drift.
    fn angle_error(&self, t: f64) -> Vector3<f64> {
        self.angle_offset + self.angle_drift * t
    }

    /// Instrument outputs for the true attitude and specific force at time t.
    pub fn measure(
        &self,
        t: f64,
        attitude: &LaunchAttitude,
        force: &Vector3<f64>,
    ) -> (LaunchAttitude, Vector3<f64>) {
        let angle = self.angle_error(t);
        (
            LaunchAttitude {
                yaw: attitude.yaw + angle[0],
                pitch: attitude.pitch + angle[1],
                roll: attitude.roll + angle[2],
            },
            force + self.accel_bias + self.accel_scale.component_mul(force),
        )
    }

    /// Correct instrument outputs with these errors (the inverse of
    /// [`measure`](Self::measure)).
    pub fn correct(
        &self,
        t: f64,
        attitude: &LaunchAttitude,
        force: &Vector3<f64>,
    ) -> (LaunchAttitude, Vector3<f64>) {
        let angle = self.angle_error(t);
        (
            LaunchAttitude {
                yaw: attitude.yaw - angle[0],
                pitch: attitude.pitch - angle[1],
                roll: attitude.roll - angle[2],
            },
            (force - self.accel_bias).component_div(&(Vector3::repeat(1.0) + self.accel_scale)),
        )
    }
}

/// Position and velocity of the launch-frame INS.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LaunchIns {
    /// Position in the launch frame \[m\].
    pub position: Vector3<f64>,
    /// Velocity [m/s].
    pub velocity: Vector3<f64>,
}

impl LaunchIns {
    /// One RK4 step of `r̈ = Dᵀ f_B + g(r)` from t to t + dt, with
    /// `sensed(τ)` the attitude and body specific force the INS uses at τ
    /// (instrument outputs, corrected or not).
    pub fn step(
        &mut self,
        t: f64,
        dt: f64,
        sensed: impl Fn(f64) -> (LaunchAttitude, Vector3<f64>),
    ) {
        self.step_with_thrust(dt, &Self::step_thrust(t, dt, sensed));
    }

    /// The non-gravitational acceleration `Dᵀ f_B` in the launch frame from
    /// a sensed attitude and body specific force.
    pub fn thrust(attitude: &LaunchAttitude, force: &Vector3<f64>) -> Vector3<f64> {
        attitude.orientation().transpose() * force
    }

    /// The thrust at the three RK4 times of the step from t to t + dt
    /// (t, t + dt/2, t + dt), as [`step`](Self::step) evaluates it. It does
    /// not depend on the INS state: a caller flying many INS through the
    /// same sensed outputs computes it once per step.
    pub fn step_thrust(
        t: f64,
        dt: f64,
        sensed: impl Fn(f64) -> (LaunchAttitude, Vector3<f64>),
    ) -> [Vector3<f64>; 3] {
        let thrust = |tau: f64| {
            let (att, f) = sensed(tau);
            Self::thrust(&att, &f)
        };
        [thrust(t), thrust(t + dt / 2.0), thrust(t + dt)]
    }

    /// [`step`](Self::step) with the thrust of
    /// [`step_thrust`](Self::step_thrust) given: the same arithmetic.
    pub fn step_with_thrust(&mut self, dt: f64, thrust: &[Vector3<f64>; 3]) {
        Self::step_many(std::array::from_mut(self), dt, [thrust]);
    }

    /// [`step_with_thrust`](Self::step_with_thrust) of `N` independent INS
    /// at once, each with its own thrust: per INS the same operations in
    /// the same order, so the same numbers. Stepped stage by stage, so the
    /// processor overlaps the INS' gravity evaluations (a square root and a
    /// division each, on a chain of four per step) instead of waiting on
    /// one chain.
    pub fn step_many<const N: usize>(
        ins: &mut [LaunchIns; N],
        dt: f64,
        thrust: [&[Vector3<f64>; 3]; N],
    ) {
        let r: [Vector3<f64>; N] = std::array::from_fn(|i| ins[i].position);
        let v: [Vector3<f64>; N] = std::array::from_fn(|i| ins[i].velocity);
        let k1r = v;
        let k1v: [Vector3<f64>; N] = std::array::from_fn(|i| thrust[i][0] + central_gravity(&r[i]));
        let k2r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k1v[i] * (dt / 2.0));
        let k2v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][1] + central_gravity(&(r[i] + k1r[i] * (dt / 2.0))));
        let k3r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k2v[i] * (dt / 2.0));
        let k3v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][1] + central_gravity(&(r[i] + k2r[i] * (dt / 2.0))));
        let k4r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k3v[i] * dt);
        let k4v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][2] + central_gravity(&(r[i] + k3r[i] * dt)));
        for i in 0..N {
            ins[i].position += (k1r[i] + 2.0 * k2r[i] + 2.0 * k3r[i] + k4r[i]) * (dt / 6.0);
            ins[i].velocity += (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]) * (dt / 6.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One RK4 step written out for a single INS (the form `step_with_thrust`
    /// had before `step_many`): the reference the stage-by-stage form must
    /// match bit for bit.
    fn reference_step(ins: &mut LaunchIns, dt: f64, thrust: &[Vector3<f64>; 3]) {
        let [a0, a_half, a1] = *thrust;
        let (r, v) = (ins.position, ins.velocity);
        let (k1r, k1v) = (v, a0 + central_gravity(&r));
        let (k2r, k2v) = (
            v + k1v * (dt / 2.0),
            a_half + central_gravity(&(r + k1r * (dt / 2.0))),
        );
        let (k3r, k3v) = (
            v + k2v * (dt / 2.0),
            a_half + central_gravity(&(r + k2r * (dt / 2.0))),
        );
        let (k4r, k4v) = (v + k3v * dt, a1 + central_gravity(&(r + k3r * dt)));
        ins.position += (k1r + 2.0 * k2r + 2.0 * k3r + k4r) * (dt / 6.0);
        ins.velocity += (k1v + 2.0 * k2v + 2.0 * k3v + k4v) * (dt / 6.0);
    }

    #[test]
    fn stepping_together_is_stepping_each_alone_bit_for_bit() {
        let start = [
            LaunchIns::default(),
            LaunchIns {
                position: Vector3::new(1.0e3, 2.5e4, -3.0e2),
                velocity: Vector3::new(900.0, 750.0, -12.0),
            },
            LaunchIns {
                position: Vector3::new(-4.0e2, 1.2e5, 7.0e3),
                velocity: Vector3::new(2.1e3, 1.1e3, 40.0),
            },
        ];
        let thrust = |i: usize, k: usize| -> [Vector3<f64>; 3] {
            std::array::from_fn(|j| {
                let s = (i * 7 + k * 3 + j) as f64;
                Vector3::new(20.0 + s.sin(), 30.0 + s.cos(), 0.1 * s.sin())
            })
        };
        let (mut together, mut alone, mut reference) = (start, start, start);
        for k in 0..500 {
            let t: [[Vector3<f64>; 3]; 3] = std::array::from_fn(|i| thrust(i, k));
            LaunchIns::step_many(&mut together, 0.01, [&t[0], &t[1], &t[2]]);
            for i in 0..3 {
                alone[i].step_with_thrust(0.01, &t[i]);
                reference_step(&mut reference[i], 0.01, &t[i]);
            }
        }
        for i in 0..3 {
            assert_eq!(together[i], alone[i]);
            assert_eq!(together[i], reference[i]);
        }
    }
}
