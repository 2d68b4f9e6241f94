//! The formation scenario's range checks, its flight (the leader's weaving,
//! climbing path and the V behind it) and what it gives stage 2.

use aidnav_ins::local_level::LocalLevelState;
use aidnav_integration::group::{CorrelatedOwnErrors, FusionParams, MotionModel, OwnErrorModel};
use aidnav_io::config::{Invalid, Validate, all_in_range, count_in_range, in_range};
use aidnav_models::GaussMarkov;
use nalgebra::{UnitQuaternion, Vector3};

use super::{Degradation, Denial, FormationScenario, Stage2Motion, Stage2OwnErrors};

/// Stage 2's prior σ of each position coordinate around the first stage-1
/// solution \[m\] (a few times the GNSS σ).
const STAGE2_INITIAL_POSITION_SIGMA_M: f64 = 10.0;
/// Stage 2's prior σ of each velocity coordinate \[m/s\].
const STAGE2_INITIAL_VELOCITY_SIGMA_MPS: f64 = 1.0;

impl Denial {
    pub(super) fn denies(&self, member: usize, t: f64) -> bool {
        t >= self.start_s && t < self.end_s && self.members.contains(&member)
    }
}

impl Degradation {
    pub(super) fn degrades(&self, member: usize, t: f64) -> bool {
        t >= self.start_s && t < self.end_s && self.member == member
    }

    /// The bias in the formation's ENU frame.
    pub(super) fn bias_enu(&self) -> Vector3<f64> {
        let [n, e, d] = self.bias_m;
        Vector3::new(e, n, -d)
    }
}

impl Validate for FormationScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 10_000)?;
        count_in_range("members", self.members, 1, 50)?;
        in_range("duration_s", self.duration_s, 1.0, 36_000.0)?;
        in_range("imu_dt_s", self.imu_dt_s, 1e-4, 0.02)?;
        in_range("filter_dt_s", self.filter_dt_s, self.imu_dt_s, 10.0)?;
        in_range(
            "fix_interval_s",
            self.fix_interval_s,
            self.filter_dt_s,
            60.0,
        )?;
        if (self.fix_interval_s / self.imu_dt_s - (self.fix_interval_s / self.imu_dt_s).round())
            .abs()
            > 1e-6
        {
            return Err(Invalid::new(
                "fix_interval_s",
                self.fix_interval_s,
                "a whole number of imu_dt_s",
            ));
        }
        in_range(
            "settle_s",
            self.settle_s,
            0.0,
            self.duration_s - self.fix_interval_s,
        )?;
        // Physical ranges, not just "> 0": a σ of 1e-170 squares to zero and
        // a period of 1e-300 overflows the weave's angular rate.
        use std::f64::consts::PI;
        all_in_range(
            "",
            &[
                ("speed_mps", self.speed_mps, 0.1, 1_000.0),
                ("altitude_m", self.altitude_m, 0.0, 50_000.0),
                ("weave_amplitude_m", self.weave_amplitude_m, 0.0, 100_000.0),
                ("climb_amplitude_m", self.climb_amplitude_m, 0.0, 10_000.0),
                ("weave_period_s", self.weave_period_s, 1.0, 1e6),
                ("climb_period_s", self.climb_period_s, 1.0, 1e6),
                ("spacing_m", self.spacing_m, 0.1, 100_000.0),
                ("origin_latitude_deg", self.origin_latitude_deg, -85.0, 85.0),
                (
                    "origin_longitude_deg",
                    self.origin_longitude_deg,
                    -180.0,
                    180.0,
                ),
                (
                    "group_accel_sigma_m_s2",
                    self.group_accel_sigma_m_s2,
                    1e-6,
                    100.0,
                ),
            ],
        )?;
        let i = &self.initial;
        all_in_range(
            "initial",
            &[
                ("position_sigma_m", i.position_sigma_m, 1e-4, 1e6),
                ("velocity_sigma_mps", i.velocity_sigma_mps, 1e-5, 1e4),
                ("tilt_sigma_rad", i.tilt_sigma_rad, 1e-7, PI),
                ("heading_sigma_rad", i.heading_sigma_rad, 1e-7, PI),
            ],
        )?;
        let imu = &self.model.imu;
        all_in_range(
            "model.imu",
            &[
                (
                    "accel_bias_sigma_m_s2",
                    imu.accel_bias_sigma_m_s2,
                    1e-8,
                    10.0,
                ),
                (
                    "accel_bias_correlation_s",
                    imu.accel_bias_correlation_s,
                    1.0,
                    1e8,
                ),
                (
                    "gyro_bias_sigma_rad_s",
                    imu.gyro_bias_sigma_rad_s,
                    1e-10,
                    0.1,
                ),
                (
                    "gyro_bias_correlation_s",
                    imu.gyro_bias_correlation_s,
                    1.0,
                    1e8,
                ),
                ("velocity_random_walk", imu.velocity_random_walk, 1e-8, 10.0),
                ("angle_random_walk", imu.angle_random_walk, 1e-9, 1.0),
            ],
        )?;
        let gnss = &self.model.gnss;
        all_in_range(
            "model.gnss",
            &[
                (
                    "position_horizontal_sigma_m",
                    gnss.position_horizontal_sigma_m,
                    1e-4,
                    1e4,
                ),
                (
                    "position_vertical_sigma_m",
                    gnss.position_vertical_sigma_m,
                    1e-4,
                    1e4,
                ),
                (
                    "position_correlation_s",
                    gnss.position_correlation_s,
                    0.01,
                    1e8,
                ),
                (
                    "position_white_sigma_m",
                    gnss.position_white_sigma_m,
                    1e-4,
                    1e4,
                ),
                ("velocity_sigma_mps", gnss.velocity_sigma_mps, 1e-5, 100.0),
                (
                    "velocity_correlation_s",
                    gnss.velocity_correlation_s,
                    0.01,
                    1e8,
                ),
                (
                    "velocity_white_sigma_mps",
                    gnss.velocity_white_sigma_mps,
                    1e-5,
                    100.0,
                ),
            ],
        )?;
        let s = &self.sensor;
        all_in_range(
            "sensor",
            &[
                ("range_sigma_m", s.range_sigma_m, 1e-4, 1e4),
                ("bearing_sigma_rad", s.bearing_sigma_rad, 1e-7, PI),
                ("elevation_sigma_rad", s.elevation_sigma_rad, 1e-7, PI),
                ("range_limit_m", s.range_limit_m, 1.0, 1e7),
                ("range_rate_sigma_mps", s.range_rate_sigma_mps, 1e-5, 100.0),
                (
                    "relative_velocity_sigma_mps",
                    s.relative_velocity_sigma_mps,
                    1e-5,
                    100.0,
                ),
            ],
        )?;
        count_in_range("denial", self.denial.len(), 0, 1_000)?;
        for (i, d) in self.denial.iter().enumerate() {
            let key = format!("denial[{i}]");
            if let Some(&m) = d.members.iter().find(|&&m| m >= self.members) {
                return Err(Invalid::new(
                    format!("{key}.members"),
                    m,
                    format!("member indices 0 … {}", self.members - 1),
                ));
            }
            if !(d.start_s >= 0.0 && d.end_s > d.start_s && d.end_s.is_finite()) {
                return Err(Invalid::new(
                    format!("{key}.end_s"),
                    d.end_s,
                    "0 ≤ start_s < end_s, finite",
                ));
            }
        }
        count_in_range("degradation", self.degradation.len(), 0, 1_000)?;
        for (i, d) in self.degradation.iter().enumerate() {
            let key = format!("degradation[{i}]");
            if d.member >= self.members {
                return Err(Invalid::new(
                    format!("{key}.member"),
                    d.member,
                    format!("a member index 0 … {}", self.members - 1),
                ));
            }
            if !(d.start_s >= 0.0 && d.end_s > d.start_s && d.end_s.is_finite()) {
                return Err(Invalid::new(
                    format!("{key}.end_s"),
                    d.end_s,
                    "0 ≤ start_s < end_s, finite",
                ));
            }
            in_range(&format!("{key}.sigma_scale"), d.sigma_scale, 1.0, 1_000.0)?;
            if let Some(&b) = d.bias_m.iter().find(|b| !b.is_finite() || b.abs() > 1e5) {
                return Err(Invalid::new(
                    format!("{key}.bias_m"),
                    b,
                    "each component within ±100000",
                ));
            }
        }
        if let Some(n) = &self.network {
            n.validate_for(self).map_err(|e| e.within("network"))?;
        }
        Ok(())
    }
}

impl FormationScenario {
    /// Stage 2's parameters: the fix interval, a_R, whether own velocities
    /// are fused, the inter-vehicle sensor, the prior σ (10 m, 1 m/s), and
    /// the own-error model: with `stage2_own_errors = "gauss_markov"` the
    /// receiver's correlated position and velocity errors (σ, τ of
    /// `model.gnss`) and its white σ as the least white noise; with
    /// `"stage1_reported"` the transition each member's stage 1 reports;
    /// and the motion model (`stage2_motion`).
    pub fn fusion_params(&self) -> FusionParams {
        let gnss = &self.model.gnss;
        let gm = |tau: f64, sigma: f64| GaussMarkov::new(tau, sigma).expect("validated");
        let own_errors = match self.stage2_own_errors {
            Stage2OwnErrors::White => OwnErrorModel::White,
            Stage2OwnErrors::Stage1Reported => OwnErrorModel::Stage1Reported,
            Stage2OwnErrors::GaussMarkov => {
                let p = gnss.position_sigmas();
                OwnErrorModel::GaussMarkov(CorrelatedOwnErrors {
                    position: [0, 1, 2].map(|a| gm(gnss.position_correlation_s, p[a])),
                    velocity: [0, 1, 2]
                        .map(|_| gm(gnss.velocity_correlation_s, gnss.velocity_sigma_mps)),
                    position_white_floor_m: gnss.position_white_sigma_m,
                    velocity_white_floor_mps: gnss.velocity_white_sigma_mps,
                })
            }
        };
        FusionParams {
            own_errors,
            motion: match self.stage2_motion {
                Stage2Motion::Paper => MotionModel::Paper,
                Stage2Motion::PiecewiseConstantAcceleration => {
                    MotionModel::PiecewiseConstantAcceleration
                }
            },
            interval_s: self.fix_interval_s,
            accel_sigma_m_s2: self.group_accel_sigma_m_s2,
            own_velocity: self.stage2_own_velocity,
            sensor: self.sensor,
            initial_position_sigma_m: STAGE2_INITIAL_POSITION_SIGMA_M,
            initial_velocity_sigma_mps: STAGE2_INITIAL_VELOCITY_SIGMA_MPS,
        }
    }

    pub(super) fn epochs(&self) -> usize {
        (self.duration_s / self.fix_interval_s).floor() as usize
    }

    pub(super) fn imu_steps_per_fix(&self) -> usize {
        (self.fix_interval_s / self.imu_dt_s).round() as usize
    }

    pub(super) fn denied(&self, member: usize, t: f64) -> bool {
        self.denial.iter().any(|d| d.denies(member, t))
    }

    /// The degradation of member l's fixes at t, if any (the first listed).
    pub(super) fn degradation_at(&self, member: usize, t: f64) -> Option<&Degradation> {
        self.degradation.iter().find(|d| d.degrades(member, t))
    }

    /// Leader position.
    fn leader(&self, t: f64) -> Vector3<f64> {
        let w = std::f64::consts::TAU / self.weave_period_s;
        let c = std::f64::consts::TAU / self.climb_period_s;
        Vector3::new(
            self.speed_mps * t,
            self.weave_amplitude_m * (w * t).sin(),
            self.altitude_m + self.climb_amplitude_m * (c * t).sin(),
        )
    }

    /// Leader heading (from its horizontal velocity).
    fn leader_heading(&self, t: f64) -> f64 {
        let w = std::f64::consts::TAU / self.weave_period_s;
        (self.weave_amplitude_m * w * (w * t).cos()).atan2(self.speed_mps)
    }

    /// Offset of member l in the leader's heading frame (forward, left, up):
    /// the leader at the apex, the others alternating right/left behind it.
    fn offset(&self, l: usize) -> Vector3<f64> {
        if l == 0 {
            return Vector3::zeros();
        }
        let rank = l.div_ceil(2) as f64;
        let side = if l % 2 == 1 { -1.0 } else { 1.0 };
        let s = self.spacing_m * std::f64::consts::FRAC_1_SQRT_2;
        Vector3::new(-rank * s, side * rank * s, 10.0 * rank * side)
    }

    /// True position of member l.
    pub fn position(&self, l: usize, t: f64) -> Vector3<f64> {
        let (s, c) = self.leader_heading(t).sin_cos();
        let o = self.offset(l);
        self.leader(t) + Vector3::new(c * o.x - s * o.y, s * o.x + c * o.y, o.z)
    }

    /// True position, velocity and attitude of member l (velocity and
    /// acceleration by central differences of the analytic path; attitude
    /// along the velocity, banked for a coordinated turn).
    pub fn truth(&self, l: usize, t: f64) -> LocalLevelState {
        let h = 1e-3;
        let velocity = (self.position(l, t + h) - self.position(l, t - h)) / (2.0 * h);
        let h2 = 1e-2;
        let accel = (self.position(l, t + h2) - 2.0 * self.position(l, t)
            + self.position(l, t - h2))
            / (h2 * h2);
        let yaw = velocity.y.atan2(velocity.x);
        let pitch = velocity.z.atan2(velocity.xy().norm());
        let left = Vector3::new(-yaw.sin(), yaw.cos(), 0.0);
        let g = aidnav_ins::local_level::GRAVITY_ENU.z.abs();
        let roll = -(accel.dot(&left) / g).atan();
        LocalLevelState {
            position: self.position(l, t),
            velocity,
            attitude: UnitQuaternion::from_euler_angles(roll, -pitch, yaw),
        }
    }
}
