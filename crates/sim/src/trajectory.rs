//! Trajectories for simulation. [`LaunchTrajectory`]: powered flight of a
//! launch-type vehicle in the launch frame (spec 10) from rest at the origin,
//! vertical rise, then a pitch-over to a target point reached at t_B.
//!
//! Physics: thrust only (no lift, no drag — flight out of the dense
//! atmosphere), so the specific force lies along the body X1 axis and the
//! attitude follows its direction (yaw from the course, roll 0); central
//! gravity ([`central_gravity`]). The motion stays in the vertical plane of
//! the course φ (`x = s cos φ`, `z = s sin φ`).
//!
//! Program: specific force `a(t) = a₀ (1 + (k − 1) t / t_B)` (propellant
//! burning off; k = [`LaunchProgram::accel_ratio`]); pitch 90° until
//! `vertical_s`, then `ϑ(t) = 90° + (ϑ_B − 90°) τ^p` with τ the fraction of the
//! turn elapsed. The two unknowns (a₀, ϑ_B) are solved by Newton's method on
//! the RK4-integrated flight so the vehicle is at the target at t_B.
//!
//! ```
//! use aidnav_sim::trajectory::{LaunchProgram, LaunchTarget, LaunchTrajectory, TABLE1};
//! let t = LaunchTrajectory::solve(&TABLE1[3], &LaunchProgram::default(), 0.05).unwrap();
//! assert!(t.miss_m() < 1000.0);
//! let g = 9.80665;
//! assert!(t.specific_force(0.0) > g && t.specific_force(t.target.t_b_s) < 6.0 * g);
//! ```

use aidnav_frames::launch::{LaunchAttitude, central_gravity};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Standard gravity [m/s²], the unit of the specific-force limits.
const G0: f64 = 9.806_65;

/// A target point of spec 10's Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchTarget {
    /// Time of arrival t_B \[s\].
    pub t_b_s: f64,
    /// Course φ \[deg\].
    pub course_deg: f64,
    /// Target x \[km\].
    pub x_km: f64,
    /// Target y (altitude) \[km\].
    pub y_km: f64,
    /// Target z \[km\].
    pub z_km: f64,
}

impl LaunchTarget {
    /// Target position \[m\].
    pub fn position(&self) -> Vector3<f64> {
        Vector3::new(self.x_km, self.y_km, self.z_km) * 1e3
    }
}

const fn target(t_b_s: f64, course_deg: f64, x_km: f64, y_km: f64, z_km: f64) -> LaunchTarget {
    LaunchTarget {
        t_b_s,
        course_deg,
        x_km,
        y_km,
        z_km,
    }
}

/// Spec 10's Table 1: the nine target points.
pub const TABLE1: [LaunchTarget; 9] = [
    target(300.0, 0.0, 790.0, 286.0, 0.0),
    target(300.0, 30.0, 684.0, 286.0, 395.0),
    target(300.0, 50.0, 508.0, 286.0, 605.0),
    target(400.0, 0.0, 1076.0, 356.0, 0.0),
    target(400.0, 30.0, 932.0, 356.0, 538.0),
    target(400.0, 50.0, 692.0, 356.0, 824.0),
    target(500.0, 0.0, 1360.0, 408.0, 0.0),
    target(500.0, 30.0, 1178.0, 408.0, 680.0),
    target(500.0, 50.0, 874.0, 408.0, 1042.0),
];

/// Shape of the guidance program (defaults documented per field).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LaunchProgram {
    /// Vertical rise \[s\]. Default 10.
    pub vertical_s: f64,
    /// Specific force at t_B over that at lift-off. Default 3.
    pub accel_ratio: f64,
    /// Exponent p of the pitch-over law. Default 0.5 (quick initial turn).
    pub pitch_exponent: f64,
}

impl Default for LaunchProgram {
    fn default() -> Self {
        Self {
            vertical_s: 10.0,
            accel_ratio: 3.0,
            pitch_exponent: 0.5,
        }
    }
}

/// Why no trajectory was produced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrajectoryError {
    /// Newton's method did not reach the target.
    #[error(
        "the guidance solution did not converge (miss {miss_m:.1} m after {iterations} iterations)"
    )]
    NoConvergence {
        /// Remaining miss distance \[m\].
        miss_m: f64,
        /// Iterations made.
        iterations: usize,
    },
    /// The solution needs a specific force outside about 1 g … 6 g.
    #[error(
        "the solution needs {lift_off_g:.2} g at lift-off and {final_g:.2} g at t_B (allowed 1 … 6 g)"
    )]
    Infeasible {
        /// Specific force at lift-off \[g\].
        lift_off_g: f64,
        /// Specific force at t_B \[g\].
        final_g: f64,
    },
    /// Inputs out of range.
    #[error("invalid trajectory input: {0}")]
    Invalid(String),
}

/// A solved launch trajectory, its truth sampled every `dt_s`.
#[derive(Debug, Clone)]
pub struct LaunchTrajectory {
    /// The target.
    pub target: LaunchTarget,
    /// The program shape.
    pub program: LaunchProgram,
    /// Specific force at lift-off [m/s²].
    pub lift_off_accel_m_s2: f64,
    /// Pitch at t_B \[rad\].
    pub final_pitch_rad: f64,
    /// Sample interval \[s\].
    pub dt_s: f64,
    /// Position at t = k dt \[m\].
    pub positions: Vec<Vector3<f64>>,
    /// Velocity at t = k dt [m/s].
    pub velocities: Vec<Vector3<f64>>,
}

/// Program parameters and the plane of flight.
#[derive(Debug, Clone, Copy)]
struct Guidance {
    t_b: f64,
    course: f64,
    program: LaunchProgram,
    a0: f64,
    pitch_end: f64,
}

impl Guidance {
    fn accel(&self, t: f64) -> f64 {
        self.a0 * (1.0 + (self.program.accel_ratio - 1.0) * t / self.t_b)
    }

    fn pitch(&self, t: f64) -> f64 {
        let v = self.program.vertical_s;
        if t <= v {
            return std::f64::consts::FRAC_PI_2;
        }
        let tau = ((t - v) / (self.t_b - v)).clamp(0.0, 1.0);
        std::f64::consts::FRAC_PI_2
            + (self.pitch_end - std::f64::consts::FRAC_PI_2) * tau.powf(self.program.pitch_exponent)
    }

    fn attitude(&self, t: f64) -> LaunchAttitude {
        LaunchAttitude {
            yaw: -self.course,
            pitch: self.pitch(t),
            roll: 0.0,
        }
    }

    /// Thrust acceleration in the launch frame.
    fn thrust(&self, t: f64) -> Vector3<f64> {
        let (s, c) = self.pitch(t).sin_cos();
        let (sf, cf) = self.course.sin_cos();
        Vector3::new(c * cf, s, c * sf) * self.accel(t)
    }

    /// RK4 from rest at the origin to t_B; calls `sample` at every step.
    fn fly(
        &self,
        dt: f64,
        mut sample: impl FnMut(&Vector3<f64>, &Vector3<f64>),
    ) -> (Vector3<f64>, Vector3<f64>) {
        let steps = (self.t_b / dt).round() as usize;
        let (mut r, mut v) = (Vector3::zeros(), Vector3::zeros());
        sample(&r, &v);
        let acc = |t: f64, r: &Vector3<f64>| self.thrust(t) + central_gravity(r);
        for k in 0..steps {
            let t = k as f64 * dt;
            let (k1r, k1v) = (v, acc(t, &r));
            let (k2r, k2v) = (
                v + k1v * (dt / 2.0),
                acc(t + dt / 2.0, &(r + k1r * (dt / 2.0))),
            );
            let (k3r, k3v) = (
                v + k2v * (dt / 2.0),
                acc(t + dt / 2.0, &(r + k2r * (dt / 2.0))),
            );
            let (k4r, k4v) = (v + k3v * dt, acc(t + dt, &(r + k3r * dt)));
            r += (k1r + 2.0 * k2r + 2.0 * k3r + k4r) * (dt / 6.0);
            v += (k1v + 2.0 * k2v + 2.0 * k3v + k4v) * (dt / 6.0);
            sample(&r, &v);
        }
        (r, v)
    }
}

/// In-plane coordinates (downrange s, altitude y) of a position.
fn in_plane(r: &Vector3<f64>, course: f64) -> (f64, f64) {
    let (sf, cf) = course.sin_cos();
    (r.x * cf + r.z * sf, r.y)
}

impl LaunchTrajectory {
    /// Solve the program for `target` and sample the flight every `dt_s`.
    pub fn solve(
        target: &LaunchTarget,
        program: &LaunchProgram,
        dt_s: f64,
    ) -> Result<Self, TrajectoryError> {
        let invalid = |m: &str| Err(TrajectoryError::Invalid(m.to_string()));
        if !(target.t_b_s > program.vertical_s + 1.0 && target.t_b_s <= 3600.0) {
            return invalid("t_b_s must exceed vertical_s + 1 s and be at most 3600 s");
        }
        if !(program.vertical_s >= 0.0 && program.accel_ratio >= 1.0 && program.accel_ratio <= 10.0)
        {
            return invalid("vertical_s ≥ 0 and 1 ≤ accel_ratio ≤ 10");
        }
        if !(program.pitch_exponent > 0.0 && program.pitch_exponent <= 5.0) {
            return invalid("0 < pitch_exponent ≤ 5");
        }
        if !(dt_s > 0.0 && dt_s <= 1.0) {
            return invalid("0 < dt_s ≤ 1");
        }
        let course = target.course_deg.to_radians();
        let goal = target.position();
        let (goal_s, goal_y) = in_plane(&goal, course);
        let mut g = Guidance {
            t_b: target.t_b_s,
            course,
            program: *program,
            a0: 2.0 * G0,
            pitch_end: 0.0,
        };
        let coarse = 0.1_f64.min(dt_s.max(0.01));
        let miss = |g: &Guidance| {
            let (r, _) = g.fly(coarse, |_, _| {});
            let (s, y) = in_plane(&r, course);
            (s - goal_s, y - goal_y)
        };
        let mut iterations = 0;
        let mut f = miss(&g);
        while f.0.hypot(f.1) > 1.0 {
            iterations += 1;
            if iterations > 40 || !(g.a0.is_finite() && g.pitch_end.is_finite()) {
                return Err(TrajectoryError::NoConvergence {
                    miss_m: f.0.hypot(f.1),
                    iterations,
                });
            }
            let (ha, hp) = (1e-3, 1e-5);
            let fa = miss(&Guidance { a0: g.a0 + ha, ..g });
            let fp = miss(&Guidance {
                pitch_end: g.pitch_end + hp,
                ..g
            });
            let j = nalgebra::Matrix2::new(
                (fa.0 - f.0) / ha,
                (fp.0 - f.0) / hp,
                (fa.1 - f.1) / ha,
                (fp.1 - f.1) / hp,
            );
            let Some(step) = j.lu().solve(&nalgebra::Vector2::new(f.0, f.1)) else {
                return Err(TrajectoryError::NoConvergence {
                    miss_m: f.0.hypot(f.1),
                    iterations,
                });
            };
            // Damped step: never more than 1 g or 10° at once.
            g.a0 -= step.x.clamp(-G0, G0);
            g.pitch_end -= step.y.clamp(-0.17, 0.17);
            f = miss(&g);
        }
        let lift_off_g = g.accel(0.0) / G0;
        let final_g = g.accel(g.t_b) / G0;
        if !(0.95..=6.05).contains(&lift_off_g) || !(0.95..=6.05).contains(&final_g) {
            return Err(TrajectoryError::Infeasible {
                lift_off_g,
                final_g,
            });
        }
        let steps = (target.t_b_s / dt_s).round() as usize;
        let mut positions = Vec::with_capacity(steps + 1);
        let mut velocities = Vec::with_capacity(steps + 1);
        g.fly(dt_s, |r, v| {
            positions.push(*r);
            velocities.push(*v);
        });
        Ok(Self {
            target: *target,
            program: *program,
            lift_off_accel_m_s2: g.a0,
            final_pitch_rad: g.pitch_end,
            dt_s,
            positions,
            velocities,
        })
    }

    fn guidance(&self) -> Guidance {
        Guidance {
            t_b: self.target.t_b_s,
            course: self.target.course_deg.to_radians(),
            program: self.program,
            a0: self.lift_off_accel_m_s2,
            pitch_end: self.final_pitch_rad,
        }
    }

    /// Specific force along body X1 at time t [m/s²] (the accelerometer x output).
    pub fn specific_force(&self, t: f64) -> f64 {
        self.guidance().accel(t)
    }

    /// True attitude at time t.
    pub fn attitude(&self, t: f64) -> LaunchAttitude {
        self.guidance().attitude(t)
    }

    /// Number of samples (steps + 1).
    pub fn samples(&self) -> usize {
        self.positions.len()
    }

    /// Distance from the target at t_B \[m\].
    pub fn miss_m(&self) -> f64 {
        (self.positions[self.positions.len() - 1] - self.target.position()).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_table1_target_is_reached_within_a_kilometre() {
        for t in &TABLE1 {
            let traj = LaunchTrajectory::solve(t, &LaunchProgram::default(), 0.01).unwrap();
            assert!(traj.miss_m() < 1000.0, "{t:?}: miss {}", traj.miss_m());
            let n = traj.samples();
            assert_eq!(n, (t.t_b_s / 0.01).round() as usize + 1);
            for k in [0, n / 3, n - 1] {
                let tt = k as f64 * 0.01;
                let f = traj.specific_force(tt) / G0;
                assert!((0.95..=6.05).contains(&f), "{t:?} at {tt}: {f} g");
            }
            // Starts at rest at the origin.
            assert_eq!(traj.positions[0], Vector3::zeros());
            // Stays in the plane of the course.
            let c = t.course_deg.to_radians();
            let last = traj.positions[n - 1];
            assert!((last.z * c.cos() - last.x * c.sin()).abs() < 1.0);
        }
    }

    #[test]
    fn impossible_targets_are_errors() {
        let far = LaunchTarget {
            x_km: 5000.0,
            ..TABLE1[0]
        };
        assert!(LaunchTrajectory::solve(&far, &LaunchProgram::default(), 0.05).is_err());
    }
}
