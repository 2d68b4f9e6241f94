//! Spec 30's full pipeline: M vehicles flying a 3-D formation, each with its
//! own INS and GNSS receiver (GNSS errors first-order Gauss–Markov plus
//! white) fused by the stage-1 loosely coupled filter
//! ([`aidnav_integration::local_level`]); inter-vehicle sensors measuring slant
//! range, bearing and elevation in the observer's body frame
//! ([`aidnav_models::relative_sensor`]), exchanged over the network; and the
//! stage-2 group filter in two forms:
//!
//! - **paper**: the paper's axis-decoupled fusion — each relative measurement
//!   converted to Cartesian coordinates with the observer's INS* attitude,
//!   its per-axis variance the diagonal of the converted covariance, one
//!   filter per axis ([`GroupAxisFilter`], constant-velocity model, own
//!   positions and velocities observed);
//! - **ekf**: one extended Kalman filter over all members' 3-D positions and
//!   velocities that uses range, bearing and elevation directly (their noise
//!   uncorrelated in polar form, so the cross-axis correlation of the
//!   Cartesian errors is carried exactly by the Jacobian), and the full 6×6
//!   stage-1 covariance of each member's own solution.
//!
//! Both forms add the observer's INS* attitude uncertainty to the relative
//! measurement noise (a line of sight of length D turned by ψ moves by D ψ).
//!
//! GNSS denial: the members listed in `[[formation.denial]]` lose GNSS for
//! the interval; their stage-1 INS runs free (its σ grows) while the group
//! keeps measuring them.
//!
//! The flight: the leader flies east at `speed_mps`, weaving left and right
//! (`weave_amplitude_m`, `weave_period_s`) and climbing and descending; the
//! others hold a V behind it (`spacing_m`, rotated with the leader's heading).
//! Flat, non-rotating Earth, local ENU frame (see [`aidnav_ins::local_level`]).

use aidnav_estimation::{DynKalmanFilter, EstimationError};
use aidnav_ins::local_level::{LocalLevelState, ideal_imu};
use aidnav_integration::group::GroupAxisFilter;
use aidnav_integration::local_level::LooselyCoupled;
use aidnav_io::config::{
    Invalid, Validate, all_positive, count_in_range, in_range, non_negative, positive,
};
use aidnav_models::GaussMarkov;
use aidnav_models::local_ins::{LocalInsModel, Matrix6};
use aidnav_models::relative_sensor::{Polar, RelativeSensor, wrap_angle};
use nalgebra::{DMatrix, DVector, Matrix3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::{RunRng, channel_rng, standard_normal};

/// Names of the three solutions compared per member.
pub const SOLUTIONS: [&str; 3] = ["gnss_ins", "paper", "ekf"];

/// One GNSS denial interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Denial {
    /// Members (0-based) that lose GNSS.
    pub members: Vec<usize>,
    /// Start of the denial \[s\].
    pub start_s: f64,
    /// End of the denial \[s\].
    pub end_s: f64,
}

impl Denial {
    fn denies(&self, member: usize, t: f64) -> bool {
        t >= self.start_s && t < self.end_s && self.members.contains(&member)
    }
}

/// Initial INS errors (σ).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialErrors {
    /// Position σ per axis \[m\]. Default 3.
    pub position_sigma_m: f64,
    /// Velocity σ per axis [m/s]. Default 0.2.
    pub velocity_sigma_mps: f64,
    /// Roll and pitch σ \[rad\]. Default 1e-3.
    pub tilt_sigma_rad: f64,
    /// Heading σ \[rad\]. Default 5e-3.
    pub heading_sigma_rad: f64,
}

impl Default for InitialErrors {
    fn default() -> Self {
        Self {
            position_sigma_m: 3.0,
            velocity_sigma_mps: 0.2,
            tilt_sigma_rad: 1e-3,
            heading_sigma_rad: 5e-3,
        }
    }
}

/// The formation scenario (TOML table `[formation]`; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FormationScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 10 000. Default 20.
    pub runs: usize,
    /// Members M, 1 … 50. Default 5.
    pub members: usize,
    /// Flight duration \[s\], at most 36 000. Default 600.
    pub duration_s: f64,
    /// IMU sample interval \[s\] (≤ 0.02). Default 0.01.
    pub imu_dt_s: f64,
    /// Stage-1 filter time-update interval \[s\]. Default 0.1.
    pub filter_dt_s: f64,
    /// GNSS fix, relative measurement and stage-2 interval \[s\]. Default 1.
    pub fix_interval_s: f64,
    /// Errors are scored from this time on \[s\]. Default 60.
    pub settle_s: f64,
    /// Leader ground speed [m/s]. Default 60.
    pub speed_mps: f64,
    /// Initial altitude \[m\]. Default 1000.
    pub altitude_m: f64,
    /// Lateral weave amplitude of the leader \[m\]. Default 800.
    pub weave_amplitude_m: f64,
    /// Weave period \[s\]. Default 240.
    pub weave_period_s: f64,
    /// Climb/descent amplitude \[m\]. Default 50.
    pub climb_amplitude_m: f64,
    /// Climb period \[s\]. Default 180.
    pub climb_period_s: f64,
    /// Distance between neighbours in the V \[m\]. Default 150.
    pub spacing_m: f64,
    /// Stage-2 acceleration disturbance a_R [m/s²]. Default 1.
    pub group_accel_sigma_m_s2: f64,
    /// Whether stage 2 also fuses each member's own INS* velocity (the
    /// paper's optional z_V). Default false: the INS* velocity is precise
    /// (σ ≈ 0.05 m/s) so it ties stage 2's position to its own integral and
    /// stage 2 then averages the INS* positions over minutes as if their
    /// errors were white — they are not (GNSS errors correlated over
    /// `position_correlation_s`), and stage 2 becomes overconfident and
    /// lags. See the closing note of issue 5 for the numbers.
    pub stage2_own_velocity: bool,
    /// Initial INS errors.
    pub initial: InitialErrors,
    /// IMU and GNSS errors (stage-1 model; the truth draws from the same).
    pub model: LocalInsModel,
    /// Inter-vehicle sensor.
    pub sensor: RelativeSensor,
    /// GNSS denials. Default: member 2 from 200 s to 500 s.
    pub denial: Vec<Denial>,
}

impl Default for FormationScenario {
    fn default() -> Self {
        Self {
            seed: 20261123,
            runs: 20,
            members: 5,
            duration_s: 600.0,
            imu_dt_s: 0.01,
            filter_dt_s: 0.1,
            fix_interval_s: 1.0,
            settle_s: 60.0,
            speed_mps: 60.0,
            altitude_m: 1000.0,
            weave_amplitude_m: 800.0,
            weave_period_s: 240.0,
            climb_amplitude_m: 50.0,
            climb_period_s: 180.0,
            spacing_m: 150.0,
            group_accel_sigma_m_s2: 1.0,
            stage2_own_velocity: false,
            initial: InitialErrors::default(),
            model: LocalInsModel::default(),
            sensor: RelativeSensor::default(),
            denial: vec![Denial {
                members: vec![2],
                start_s: 200.0,
                end_s: 500.0,
            }],
        }
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
        positive("speed_mps", self.speed_mps)?;
        for (k, v) in [
            ("altitude_m", self.altitude_m),
            ("weave_amplitude_m", self.weave_amplitude_m),
            ("climb_amplitude_m", self.climb_amplitude_m),
        ] {
            non_negative(k, v)?;
        }
        positive("weave_period_s", self.weave_period_s)?;
        positive("climb_period_s", self.climb_period_s)?;
        positive("spacing_m", self.spacing_m)?;
        positive("group_accel_sigma_m_s2", self.group_accel_sigma_m_s2)?;
        let i = &self.initial;
        all_positive(
            "initial",
            &[
                ("position_sigma_m", i.position_sigma_m),
                ("velocity_sigma_mps", i.velocity_sigma_mps),
                ("tilt_sigma_rad", i.tilt_sigma_rad),
                ("heading_sigma_rad", i.heading_sigma_rad),
            ],
        )?;
        let imu = &self.model.imu;
        all_positive(
            "model.imu",
            &[
                ("accel_bias_sigma_m_s2", imu.accel_bias_sigma_m_s2),
                ("accel_bias_correlation_s", imu.accel_bias_correlation_s),
                ("gyro_bias_sigma_rad_s", imu.gyro_bias_sigma_rad_s),
                ("gyro_bias_correlation_s", imu.gyro_bias_correlation_s),
                ("velocity_random_walk", imu.velocity_random_walk),
                ("angle_random_walk", imu.angle_random_walk),
            ],
        )?;
        let gnss = &self.model.gnss;
        all_positive(
            "model.gnss",
            &[
                (
                    "position_horizontal_sigma_m",
                    gnss.position_horizontal_sigma_m,
                ),
                ("position_vertical_sigma_m", gnss.position_vertical_sigma_m),
                ("position_correlation_s", gnss.position_correlation_s),
                ("position_white_sigma_m", gnss.position_white_sigma_m),
                ("velocity_sigma_mps", gnss.velocity_sigma_mps),
                ("velocity_correlation_s", gnss.velocity_correlation_s),
                ("velocity_white_sigma_mps", gnss.velocity_white_sigma_mps),
            ],
        )?;
        let s = &self.sensor;
        all_positive(
            "sensor",
            &[
                ("range_sigma_m", s.range_sigma_m),
                ("bearing_sigma_rad", s.bearing_sigma_rad),
                ("elevation_sigma_rad", s.elevation_sigma_rad),
                ("range_limit_m", s.range_limit_m),
            ],
        )?;
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
        Ok(())
    }
}

/// A scenario file for `aidnav run`: the formation under a `[formation]` table.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormationFile {
    /// The scenario.
    #[serde(default)]
    pub formation: FormationScenario,
}

impl Validate for FormationFile {
    fn validate(&self) -> Result<(), Invalid> {
        self.formation.validate().map_err(|e| e.within("formation"))
    }
}

impl FormationScenario {
    fn epochs(&self) -> usize {
        (self.duration_s / self.fix_interval_s).floor() as usize
    }

    fn imu_steps_per_fix(&self) -> usize {
        (self.fix_interval_s / self.imu_dt_s).round() as usize
    }

    fn denied(&self, member: usize, t: f64) -> bool {
        self.denial.iter().any(|d| d.denies(member, t))
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

/// Per-member result (RMS over settled epochs and runs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MemberScore {
    /// Member index.
    pub member: usize,
    /// Whether the member is denied GNSS at some time.
    pub denied: bool,
    /// 3-D position error RMS \[m\], per solution in [`SOLUTIONS`] order.
    pub position_rms_m: [f64; 3],
    /// 3-D velocity error RMS [m/s], per solution.
    pub velocity_rms_mps: [f64; 3],
    /// Filter's predicted 3-D position σ (√ trace), mean over epochs \[m\].
    pub position_sigma_m: [f64; 3],
    /// During its denial: mean over runs of the largest 3-D position error \[m\].
    pub denial_max_error_m: Option<[f64; 3]>,
    /// At the end of its denial: RMS over runs of the 3-D position error \[m\].
    pub denial_end_error_m: Option<[f64; 3]>,
}

/// The experiment's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FormationResult {
    /// Per member.
    pub members: Vec<MemberScore>,
    /// Epoch times \[s\].
    pub time_s: Vec<f64>,
    /// Per epoch, per member, per solution: RMS over runs of the 3-D position error \[m\].
    pub error_by_epoch: Vec<Vec<[f64; 3]>>,
    /// Relative measurements per epoch (mean over epochs and runs).
    pub relative_per_epoch: f64,
}

/// One run's per-epoch errors.
struct RunErrors {
    /// [epoch][member][solution] squared position error.
    position_sq: Vec<Vec<[f64; 3]>>,
    velocity_sq: Vec<Vec<[f64; 3]>>,
    sigma: Vec<Vec<[f64; 3]>>,
    relative: usize,
}

/// What stage 1 hands to stage 2 for one member at one epoch.
struct OwnSolution {
    state: LocalLevelState,
    covariance: Matrix6,
    attitude_covariance: Matrix3<f64>,
}

/// A relative measurement of member `to` by member `from`.
struct RelativeMeasurement {
    from: usize,
    to: usize,
    polar: Polar,
}

/// Truth-side IMU and GNSS error processes of one member.
struct MemberErrors {
    accel_bias: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    gnss_position: Vector3<f64>,
    gnss_velocity: Vector3<f64>,
}

fn gauss3(rng: &mut RunRng, sigma: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        sigma.x * standard_normal(rng),
        sigma.y * standard_normal(rng),
        sigma.z * standard_normal(rng),
    )
}

/// Covariance added to a line of sight `d` (nav frame) by the observer's
/// attitude uncertainty: δd = d × ψ.
fn attitude_covariance_on(d: &Vector3<f64>, p_psi: &Matrix3<f64>) -> Matrix3<f64> {
    let s = d.cross_matrix();
    s * p_psi * s.transpose()
}

/// Per epoch, per member: stage-1 solutions and the truth.
type StageOne = (Vec<Vec<OwnSolution>>, Vec<Vec<LocalLevelState>>);

/// Stage 1 of every member over the whole flight: per epoch, each member's
/// INS* solution. Also returns the truth at each epoch.
fn stage_one(sc: &FormationScenario, run: u64) -> Result<StageOne, EstimationError> {
    let m = sc.members;
    let epochs = sc.epochs();
    let steps = sc.imu_steps_per_fix();
    let dt = sc.imu_dt_s;
    let model = sc.model;
    let imu = model.imu;
    let gnss = model.gnss;
    let mut out: Vec<Vec<OwnSolution>> = (0..epochs).map(|_| Vec::with_capacity(m)).collect();
    let mut truth_by_epoch: Vec<Vec<LocalLevelState>> =
        (0..epochs).map(|_| Vec::with_capacity(m)).collect();
    let gm = |tau: f64, sigma: f64, step: f64| {
        GaussMarkov::new(tau, sigma)
            .expect("validated")
            .discretise(step)
    };
    let (ba_phi, ba_q) = gm(imu.accel_bias_correlation_s, imu.accel_bias_sigma_m_s2, dt);
    let (bg_phi, bg_q) = gm(imu.gyro_bias_correlation_s, imu.gyro_bias_sigma_rad_s, dt);
    let gnss_pos_sigma = gnss.position_sigmas();
    let (ep_phi, _) = gm(gnss.position_correlation_s, 1.0, sc.fix_interval_s);
    let (ev_phi, ev_q) = gm(
        gnss.velocity_correlation_s,
        gnss.velocity_sigma_mps,
        sc.fix_interval_s,
    );
    let accel_noise = imu.velocity_random_walk / dt.sqrt();
    let gyro_noise = imu.angle_random_walk / dt.sqrt();
    let i = &sc.initial;
    let attitude_sigma = Vector3::new(i.tilt_sigma_rad, i.tilt_sigma_rad, i.heading_sigma_rad);
    for l in 0..m {
        let mut rng = channel_rng(sc.seed, run, l as u64);
        let start = sc.truth(l, 0.0);
        let psi = gauss3(&mut rng, &attitude_sigma);
        let ins0 = LocalLevelState {
            position: start.position + gauss3(&mut rng, &Vector3::repeat(i.position_sigma_m)),
            velocity: start.velocity + gauss3(&mut rng, &Vector3::repeat(i.velocity_sigma_mps)),
            attitude: UnitQuaternion::from_scaled_axis(-psi) * start.attitude,
        };
        let prior = model.prior_sigmas(i.position_sigma_m, i.velocity_sigma_mps, attitude_sigma);
        let mut lc = LooselyCoupled::new(model, ins0, &prior, sc.filter_dt_s)?;
        let mut e = MemberErrors {
            accel_bias: gauss3(&mut rng, &Vector3::repeat(imu.accel_bias_sigma_m_s2)),
            gyro_bias: gauss3(&mut rng, &Vector3::repeat(imu.gyro_bias_sigma_rad_s)),
            gnss_position: gauss3(&mut rng, &gnss_pos_sigma),
            gnss_velocity: gauss3(&mut rng, &Vector3::repeat(gnss.velocity_sigma_mps)),
        };
        let mut prev = start;
        for (epoch, (out_e, truth_e)) in out.iter_mut().zip(truth_by_epoch.iter_mut()).enumerate() {
            // Epoch k is at t = (k + 1) · fix interval.
            for s in 0..steps {
                let t = (epoch * steps + s + 1) as f64 * dt;
                let next = sc.truth(l, t);
                let (w, f) = ideal_imu(&prev, &next, dt);
                let gyro = w + e.gyro_bias + gauss3(&mut rng, &Vector3::repeat(gyro_noise));
                let accel = f + e.accel_bias + gauss3(&mut rng, &Vector3::repeat(accel_noise));
                lc.step_imu(&gyro, &accel, dt)?;
                e.accel_bias =
                    e.accel_bias * ba_phi + gauss3(&mut rng, &Vector3::repeat(ba_q.sqrt()));
                e.gyro_bias =
                    e.gyro_bias * bg_phi + gauss3(&mut rng, &Vector3::repeat(bg_q.sqrt()));
                prev = next;
            }
            let t = (epoch + 1) as f64 * sc.fix_interval_s;
            e.gnss_position = e.gnss_position * ep_phi
                + gauss3(&mut rng, &(gnss_pos_sigma * (1.0 - ep_phi * ep_phi).sqrt()));
            e.gnss_velocity =
                e.gnss_velocity * ev_phi + gauss3(&mut rng, &Vector3::repeat(ev_q.sqrt()));
            let white_p = gauss3(&mut rng, &Vector3::repeat(gnss.position_white_sigma_m));
            let white_v = gauss3(&mut rng, &Vector3::repeat(gnss.velocity_white_sigma_mps));
            if sc.denied(l, t) {
                lc.propagate()?;
            } else {
                lc.gnss_update(
                    &(prev.position + e.gnss_position + white_p),
                    &(prev.velocity + e.gnss_velocity + white_v),
                )?;
            }
            out_e.push(OwnSolution {
                state: *lc.solution(),
                covariance: lc.position_velocity_covariance(),
                attitude_covariance: lc.attitude_covariance(),
            });
            truth_e.push(prev);
        }
    }
    Ok((out, truth_by_epoch))
}

/// Range, bearing and elevation of every member within range of every other.
fn relative_measurements(
    sc: &FormationScenario,
    truth: &[LocalLevelState],
    rng: &mut RunRng,
) -> Vec<RelativeMeasurement> {
    let s = &sc.sensor;
    let mut out = Vec::new();
    for (from, a) in truth.iter().enumerate() {
        for (to, b) in truth.iter().enumerate() {
            let d = b.position - a.position;
            if to == from || d.norm() > s.range_limit_m {
                continue;
            }
            let p = Polar::from_cartesian(&(a.attitude.inverse() * d));
            out.push(RelativeMeasurement {
                from,
                to,
                polar: Polar {
                    range_m: p.range_m + s.range_sigma_m * standard_normal(rng),
                    bearing_rad: wrap_angle(
                        p.bearing_rad + s.bearing_sigma_rad * standard_normal(rng),
                    ),
                    elevation_rad: p.elevation_rad + s.elevation_sigma_rad * standard_normal(rng),
                },
            });
        }
    }
    out
}

/// Stage 2, paper form: three axis filters.
struct PaperFusion {
    axes: Vec<GroupAxisFilter>,
}

impl PaperFusion {
    fn new(sc: &FormationScenario, first: &[OwnSolution]) -> Result<Self, EstimationError> {
        let m = sc.members;
        let axes = (0..3)
            .map(|a| {
                let p: Vec<f64> = first.iter().map(|o| o.state.position[a]).collect();
                let v: Vec<f64> = first.iter().map(|o| o.state.velocity[a]).collect();
                GroupAxisFilter::new(
                    m,
                    sc.fix_interval_s,
                    sc.group_accel_sigma_m_s2,
                    sc.stage2_own_velocity,
                    &p,
                    &v,
                    10.0,
                    1.0,
                )
            })
            .collect::<Result<_, _>>()?;
        Ok(Self { axes })
    }

    fn epoch(
        &mut self,
        sc: &FormationScenario,
        own: &[OwnSolution],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        for (a, f) in self.axes.iter_mut().enumerate() {
            if predict {
                f.predict();
            }
            for (l, o) in own.iter().enumerate() {
                f.observe_own_position(l, o.state.position[a], o.covariance[(a, a)].sqrt())?;
                if sc.stage2_own_velocity {
                    f.observe_own_velocity(
                        l,
                        o.state.velocity[a],
                        o.covariance[(3 + a, 3 + a)].sqrt(),
                    )?;
                }
            }
            for r in relative {
                let observer = &own[r.from];
                let c = observer.state.attitude.to_rotation_matrix().into_inner();
                // Line of sight to `to` in the nav frame: d = R^to − R^from.
                let d = c * r.polar.to_cartesian();
                let cov = c * sc.sensor.converted_covariance(&r.polar) * c.transpose()
                    + attitude_covariance_on(&d, &observer.attitude_covariance);
                // The paper's z^{lk} = R^l − R^k with l the observer.
                f.observe_relative(r.from, r.to, -d[a], cov[(a, a)].sqrt())?;
            }
            f.update()?;
        }
        Ok(())
    }

    fn position(&self, l: usize) -> Vector3<f64> {
        Vector3::new(
            self.axes[0].position(l),
            self.axes[1].position(l),
            self.axes[2].position(l),
        )
    }

    fn velocity(&self, l: usize) -> Vector3<f64> {
        Vector3::new(
            self.axes[0].velocity(l),
            self.axes[1].velocity(l),
            self.axes[2].velocity(l),
        )
    }

    fn position_sigma(&self, l: usize) -> f64 {
        self.axes
            .iter()
            .map(|f| f.position_sigma(l).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// Stage 2, EKF form: state [R¹ V¹ … R^M V^M], 3-D each.
struct EkfFusion {
    kf: DynKalmanFilter,
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
}

impl EkfFusion {
    fn new(sc: &FormationScenario, first: &[OwnSolution]) -> Result<Self, EstimationError> {
        let m = sc.members;
        let n = 6 * m;
        let mut x = DVector::zeros(n);
        let mut p0 = DVector::zeros(n);
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::zeros(n, n);
        let qv = (sc.group_accel_sigma_m_s2 * sc.fix_interval_s).powi(2);
        for (l, o) in first.iter().enumerate() {
            for a in 0..3 {
                x[6 * l + a] = o.state.position[a];
                x[6 * l + 3 + a] = o.state.velocity[a];
                p0[6 * l + a] = 100.0;
                p0[6 * l + 3 + a] = 1.0;
                phi[(6 * l + a, 6 * l + 3 + a)] = sc.fix_interval_s;
                q[(6 * l + 3 + a, 6 * l + 3 + a)] = qv;
            }
        }
        Ok(Self {
            kf: DynKalmanFilter::new(x, DMatrix::from_diagonal(&p0))?,
            phi,
            q,
        })
    }

    fn epoch(
        &mut self,
        sc: &FormationScenario,
        own: &[OwnSolution],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        let n = self.kf.dim();
        if predict {
            self.kf.predict(&self.phi, &self.q)?;
        }
        // Own solution: position (and velocity) with its stage-1 covariance block.
        let k = if sc.stage2_own_velocity { 6 } else { 3 };
        for (l, o) in own.iter().enumerate() {
            let mut h = DMatrix::zeros(k, n);
            for i in 0..k {
                h[(i, 6 * l + i)] = 1.0;
            }
            let z = DVector::from_iterator(
                k,
                o.state
                    .position
                    .iter()
                    .chain(o.state.velocity.iter())
                    .take(k)
                    .copied(),
            );
            let r = DMatrix::from_fn(k, k, |i, j| o.covariance[(i, j)]);
            self.kf.update(&z, &h, &r)?;
        }
        for meas in relative {
            let observer = &own[meas.from];
            let c = observer.state.attitude.to_rotation_matrix().into_inner();
            let x = self.kf.state();
            let d = Vector3::new(
                x[6 * meas.to] - x[6 * meas.from],
                x[6 * meas.to + 1] - x[6 * meas.from + 1],
                x[6 * meas.to + 2] - x[6 * meas.from + 2],
            );
            let body = c.transpose() * d;
            let predicted = Polar::from_cartesian(&body);
            let jp = Polar::polar_jacobian(&body);
            let jd = jp * c.transpose(); // ∂h/∂d
            let mut h = DMatrix::zeros(3, n);
            for i in 0..3 {
                for j in 0..3 {
                    h[(i, 6 * meas.to + j)] = jd[(i, j)];
                    h[(i, 6 * meas.from + j)] = -jd[(i, j)];
                }
            }
            let r3 = sc.sensor.polar_covariance()
                + jd * attitude_covariance_on(&d, &observer.attitude_covariance) * jd.transpose();
            let nu = Vector3::new(
                meas.polar.range_m - predicted.range_m,
                wrap_angle(meas.polar.bearing_rad - predicted.bearing_rad),
                meas.polar.elevation_rad - predicted.elevation_rad,
            );
            // Linearised about x̂: z_eff − H x̂ = ν.
            let hx = &h * x;
            let z = DVector::from_fn(3, |i, _| nu[i] + hx[i]);
            let r = DMatrix::from_fn(3, 3, |i, j| r3[(i, j)]);
            self.kf.update(&z, &h, &r)?;
        }
        Ok(())
    }

    fn position(&self, l: usize) -> Vector3<f64> {
        let x = self.kf.state();
        Vector3::new(x[6 * l], x[6 * l + 1], x[6 * l + 2])
    }

    fn velocity(&self, l: usize) -> Vector3<f64> {
        let x = self.kf.state();
        Vector3::new(x[6 * l + 3], x[6 * l + 4], x[6 * l + 5])
    }

    fn position_sigma(&self, l: usize) -> f64 {
        let p = self.kf.covariance();
        (0..3)
            .map(|a| p[(6 * l + a, 6 * l + a)])
            .sum::<f64>()
            .sqrt()
    }
}

fn run_once(sc: &FormationScenario, run: u64) -> Result<RunErrors, EstimationError> {
    let (own, truth) = stage_one(sc, run)?;
    let mut rng = channel_rng(sc.seed, run, 1_000_000);
    let mut paper = PaperFusion::new(sc, &own[0])?;
    let mut ekf = EkfFusion::new(sc, &own[0])?;
    let mut errors = RunErrors {
        position_sq: Vec::with_capacity(own.len()),
        velocity_sq: Vec::with_capacity(own.len()),
        sigma: Vec::with_capacity(own.len()),
        relative: 0,
    };
    for (epoch, (own_e, truth_e)) in own.iter().zip(&truth).enumerate() {
        let relative = relative_measurements(sc, truth_e, &mut rng);
        errors.relative += relative.len();
        paper.epoch(sc, own_e, &relative, epoch > 0)?;
        ekf.epoch(sc, own_e, &relative, epoch > 0)?;
        let mut pos = Vec::with_capacity(sc.members);
        let mut vel = Vec::with_capacity(sc.members);
        let mut sig = Vec::with_capacity(sc.members);
        for (l, t) in truth_e.iter().enumerate() {
            let o = &own_e[l];
            let estimates = [
                (o.state.position, o.state.velocity),
                (paper.position(l), paper.velocity(l)),
                (ekf.position(l), ekf.velocity(l)),
            ];
            pos.push(estimates.map(|(p, _)| (p - t.position).norm_squared()));
            vel.push(estimates.map(|(_, v)| (v - t.velocity).norm_squared()));
            let stage1_sigma = (0..3).map(|a| o.covariance[(a, a)]).sum::<f64>().sqrt();
            sig.push([stage1_sigma, paper.position_sigma(l), ekf.position_sigma(l)]);
        }
        errors.position_sq.push(pos);
        errors.velocity_sq.push(vel);
        errors.sigma.push(sig);
    }
    Ok(errors)
}

/// Run the Monte Carlo of the formation.
pub fn run(sc: &FormationScenario, mc: &MonteCarlo) -> Result<FormationResult, EstimationError> {
    let runs = mc.try_run(|run, _rng| run_once(sc, run as u64))?;
    let epochs = sc.epochs();
    let time_s: Vec<f64> = (0..epochs)
        .map(|k| (k + 1) as f64 * sc.fix_interval_s)
        .collect();
    let settled: Vec<usize> = (0..epochs).filter(|&k| time_s[k] >= sc.settle_s).collect();
    let n_runs = runs.len() as f64;
    let members = (0..sc.members)
        .map(|l| {
            let mean_over = |pick: &dyn Fn(&RunErrors, usize) -> [f64; 3], root: bool| {
                let mut acc = [0.0; 3];
                for r in &runs {
                    for &k in &settled {
                        let v = pick(r, k);
                        for s in 0..3 {
                            acc[s] += v[s];
                        }
                    }
                }
                acc.map(|a| {
                    let mean = a / (n_runs * settled.len() as f64);
                    if root { mean.sqrt() } else { mean }
                })
            };
            let windows: Vec<&Denial> = sc
                .denial
                .iter()
                .filter(|d| d.members.contains(&l))
                .collect();
            let in_denial: Vec<usize> = (0..epochs)
                .filter(|&k| windows.iter().any(|d| d.denies(l, time_s[k])))
                .collect();
            let (denial_max, denial_end) = if in_denial.is_empty() {
                (None, None)
            } else {
                let mut max = [0.0; 3];
                let mut end = [0.0; 3];
                let last = *in_denial.last().expect("non-empty");
                for r in &runs {
                    for s in 0..3 {
                        let worst = in_denial
                            .iter()
                            .map(|&k| r.position_sq[k][l][s])
                            .fold(0.0, f64::max);
                        max[s] += worst.sqrt() / n_runs;
                        end[s] += r.position_sq[last][l][s] / n_runs;
                    }
                }
                (Some(max), Some(end.map(f64::sqrt)))
            };
            MemberScore {
                member: l,
                denied: !in_denial.is_empty(),
                position_rms_m: mean_over(&|r, k| r.position_sq[k][l], true),
                velocity_rms_mps: mean_over(&|r, k| r.velocity_sq[k][l], true),
                position_sigma_m: mean_over(&|r, k| r.sigma[k][l], false),
                denial_max_error_m: denial_max,
                denial_end_error_m: denial_end,
            }
        })
        .collect();
    let error_by_epoch = (0..epochs)
        .map(|k| {
            (0..sc.members)
                .map(|l| {
                    let mut acc = [0.0; 3];
                    for r in &runs {
                        for (a, v) in acc.iter_mut().zip(r.position_sq[k][l]) {
                            *a += v;
                        }
                    }
                    acc.map(|a| (a / n_runs).sqrt())
                })
                .collect()
        })
        .collect();
    let relative_per_epoch =
        runs.iter().map(|r| r.relative as f64).sum::<f64>() / (n_runs * epochs as f64);
    Ok(FormationResult {
        members,
        time_s,
        error_by_epoch,
        relative_per_epoch,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formation_truth_is_smooth_and_spaced() {
        let sc = FormationScenario::default();
        for t in [0.0, 37.0, 120.0, 333.0] {
            for l in 1..sc.members {
                let d = (sc.position(l, t) - sc.position(0, t)).norm();
                assert!(
                    d > 100.0 && d < 2.5 * sc.spacing_m,
                    "member {l} at {t}: {d}"
                );
            }
            let s = sc.truth(0, t);
            assert!((s.velocity.norm() - sc.speed_mps).abs() < 25.0);
            // Body x axis along the velocity.
            let fwd = s.attitude * Vector3::x();
            assert!(fwd.dot(&s.velocity.normalize()) > 0.999);
        }
    }

    #[test]
    fn bad_denial_is_named() {
        let sc = FormationScenario {
            denial: vec![Denial {
                members: vec![7],
                start_s: 0.0,
                end_s: 10.0,
            }],
            ..FormationScenario::default()
        };
        let e = sc.validate().unwrap_err();
        assert_eq!(e.key, "denial[0].members");
    }

    /// Short flight, few runs: the group beats GNSS/INS alone for every
    /// member, and the denied member's error stays bounded inside the group
    /// while alone it drifts.
    #[test]
    fn group_fusion_beats_stand_alone_and_bounds_the_denied_member() {
        let sc = FormationScenario {
            runs: 4,
            duration_s: 300.0,
            settle_s: 30.0,
            denial: vec![Denial {
                members: vec![2],
                start_s: 100.0,
                end_s: 250.0,
            }],
            ..FormationScenario::default()
        };
        let r = run(&sc, &MonteCarlo::new(sc.runs, sc.seed).quiet()).unwrap();
        assert_eq!(r.members.len(), 5);
        for m in r.members.iter().filter(|m| !m.denied) {
            let [alone, paper, ekf] = m.position_rms_m;
            assert!(
                paper < alone && ekf < alone,
                "member {}: {:?}",
                m.member,
                m.position_rms_m
            );
        }
        let denied = &r.members[2];
        let [alone, paper, ekf] = denied.denial_max_error_m.unwrap();
        assert!(alone > 20.0, "free INS drift {alone}");
        assert!(
            paper < 10.0 && ekf < 10.0,
            "inside the group: {paper}, {ekf}"
        );
    }
}
