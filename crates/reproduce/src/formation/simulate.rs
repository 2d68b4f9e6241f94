//! Stage 1 of the formation: every member's truth-side IMU and GNSS errors,
//! its own INS/GNSS filter over the whole flight, and the relative
//! measurements between members.

use aidnav_estimation::EstimationError;
use aidnav_ins::local_level::{LocalLevelState, ideal_imu};
use aidnav_integration::group::{OwnSolution, RelativeMeasurement, RelativeRate};
use aidnav_integration::local_level::LooselyCoupled;
use aidnav_models::GaussMarkov;
use aidnav_models::local_ins::Matrix6;
use aidnav_models::relative_sensor::{Polar, body_relative_velocity, range_rate, wrap_angle};
use aidnav_sim::rng::{RunRng, channel_rng, standard_normal};
use nalgebra::{UnitQuaternion, Vector3};

use super::{FormationScenario, InsModel};

/// The random stream of the relative measurements' noise (channel of
/// [`channel_rng`]; members' stage 1 use channels 0 … M − 1).
pub(super) const RELATIVE_CHANNEL: u64 = 1_000_000;

/// The random stream of the range rates' and relative velocities' noise
/// ([`relative_rates`]; the network's draws use another).
pub(super) const RATE_CHANNEL: u64 = 2_000_000;

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

/// The fix noise a receiver reports when its errors are `k` times nominal:
/// the model's white noise plus (k² − 1) times the nominal total variance
/// (correlated and white) per axis, so that the total σ the filter assumes
/// is k times the nominal one (the correlated part keeps its state model).
pub(super) fn reported_noise(sc: &FormationScenario, k: f64) -> Matrix6 {
    let gnss = &sc.model.gnss;
    let (_, mut r) = sc.model.measurement();
    let extra = k * k - 1.0;
    let pos = gnss.position_sigmas();
    for i in 0..3 {
        r[(i, i)] += extra * (pos[i].powi(2) + gnss.position_white_sigma_m.powi(2));
        r[(3 + i, 3 + i)] +=
            extra * (gnss.velocity_sigma_mps.powi(2) + gnss.velocity_white_sigma_mps.powi(2));
    }
    r
}

/// The simulated instruments' error processes, discretised once per run:
/// both stage-1 models (flat and NED) draw the same errors from them.
pub(super) struct ErrorProcesses {
    /// Accelerometer bias Gauss–Markov: Φ and the driving σ per IMU step.
    pub(super) ba_phi: f64,
    pub(super) ba_q: f64,
    /// Gyro bias Gauss–Markov: Φ and the driving σ per IMU step.
    pub(super) bg_phi: f64,
    pub(super) bg_q: f64,
    /// Receiver position σ (north, east, down) \[m\].
    pub(super) gnss_pos_sigma: Vector3<f64>,
    /// Receiver position error's Φ per fix interval (unit σ).
    pub(super) ep_phi: f64,
    /// Receiver velocity Gauss–Markov: Φ and the driving σ per fix interval.
    pub(super) ev_phi: f64,
    pub(super) ev_q: f64,
    /// White accelerometer and gyro noise σ per IMU step.
    pub(super) accel_noise: f64,
    pub(super) gyro_noise: f64,
    /// Initial attitude σ (tilt, tilt, heading) \[rad\].
    pub(super) attitude_sigma: Vector3<f64>,
}

impl ErrorProcesses {
    pub(super) fn new(sc: &FormationScenario) -> Self {
        let dt = sc.imu_dt_s;
        let (imu, gnss) = (sc.model.imu, sc.model.gnss);
        let gm = |tau: f64, sigma: f64, step: f64| {
            GaussMarkov::new(tau, sigma)
                .expect("validated")
                .discretise(step)
        };
        let (ba_phi, ba_q) = gm(imu.accel_bias_correlation_s, imu.accel_bias_sigma_m_s2, dt);
        let (bg_phi, bg_q) = gm(imu.gyro_bias_correlation_s, imu.gyro_bias_sigma_rad_s, dt);
        let (ep_phi, _) = gm(gnss.position_correlation_s, 1.0, sc.fix_interval_s);
        let (ev_phi, ev_q) = gm(
            gnss.velocity_correlation_s,
            gnss.velocity_sigma_mps,
            sc.fix_interval_s,
        );
        let i = &sc.initial;
        Self {
            ba_phi,
            ba_q,
            bg_phi,
            bg_q,
            gnss_pos_sigma: gnss.position_sigmas(),
            ep_phi,
            ev_phi,
            ev_q,
            accel_noise: imu.velocity_random_walk / dt.sqrt(),
            gyro_noise: imu.angle_random_walk / dt.sqrt(),
            attitude_sigma: Vector3::new(i.tilt_sigma_rad, i.tilt_sigma_rad, i.heading_sigma_rad),
        }
    }
}

/// Per epoch, per member: stage-1 solutions and the truth.
type StageOne = (Vec<Vec<OwnSolution>>, Vec<Vec<LocalLevelState>>);

/// [`stage_one_on`] computing the paths itself (the tests').
#[cfg(test)]
pub(super) fn stage_one(sc: &FormationScenario, run: u64) -> Result<StageOne, EstimationError> {
    stage_one_on(sc, run, &StageOnePaths::new(sc))
}

/// The members' flight paths of the Earth-frame stage 1
/// ([`MemberPath`](super::stage_one_ned::MemberPath): the truth and the
/// perfect IMU, the same in every run), computed once per campaign; empty
/// for the flat model.
pub(super) struct StageOnePaths(Vec<super::stage_one_ned::MemberPath>);

impl StageOnePaths {
    /// Every member's path (none for `ins_model = "flat"`).
    pub(super) fn new(sc: &FormationScenario) -> Self {
        if sc.ins_model != InsModel::Ned {
            return Self(Vec::new());
        }
        Self(
            (0..sc.members)
                .map(|l| super::stage_one_ned::MemberPath::new(sc, l))
                .collect(),
        )
    }
}

/// Stage 1 of every member over the whole flight: per epoch, each member's
/// INS* solution (in the tangent plane, whichever `ins_model`) and the
/// truth, with the members' paths computed beforehand
/// ([`StageOnePaths::new`]).
pub(super) fn stage_one_on(
    sc: &FormationScenario,
    run: u64,
    paths: &StageOnePaths,
) -> Result<StageOne, EstimationError> {
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
    let ErrorProcesses {
        ba_phi,
        ba_q,
        bg_phi,
        bg_q,
        gnss_pos_sigma,
        ep_phi,
        ev_phi,
        ev_q,
        accel_noise,
        gyro_noise,
        attitude_sigma,
    } = ErrorProcesses::new(sc);
    let i = &sc.initial;
    for l in 0..m {
        if sc.ins_model == InsModel::Ned {
            let member = super::stage_one_ned::member(sc, run, l, &paths.0[l])?;
            for ((out_e, truth_e), (own, truth)) in
                out.iter_mut().zip(truth_by_epoch.iter_mut()).zip(member)
            {
                out_e.push(own);
                truth_e.push(truth);
            }
            continue;
        }
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
            } else if let Some(d) = sc.degradation_at(l, t) {
                let k = d.sigma_scale;
                let position = prev.position + (e.gnss_position + white_p) * k + d.bias_enu();
                let velocity = prev.velocity + (e.gnss_velocity + white_v) * k;
                if d.reported {
                    lc.gnss_update_with_noise(&position, &velocity, &reported_noise(sc, k))?;
                } else {
                    lc.gnss_update(&position, &velocity)?;
                }
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
                error_cross_covariance: Some(lc.take_error_cross_covariance()),
            });
            truth_e.push(prev);
        }
    }
    Ok((out, truth_by_epoch))
}

/// Range, bearing and elevation of every member within range of every other.
pub(super) fn relative_measurements(
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

/// Range rates and body-frame relative velocities of every member within
/// range of every other, as the sensor is configured to measure them (none
/// when both are off). Drawn from their own random stream, so turning them
/// on leaves the other measurements unchanged.
pub(super) fn relative_rates(
    sc: &FormationScenario,
    truth: &[LocalLevelState],
    rng: &mut RunRng,
) -> Vec<RelativeRate> {
    let s = &sc.sensor;
    if !s.range_rate && !s.relative_velocity {
        return Vec::new();
    }
    let mut out = Vec::new();
    for (from, a) in truth.iter().enumerate() {
        for (to, b) in truth.iter().enumerate() {
            let d = b.position - a.position;
            if to == from || d.norm() > s.range_limit_m {
                continue;
            }
            let d_dot = b.velocity - a.velocity;
            let range_rate_mps = s
                .range_rate
                .then(|| range_rate(&d, &d_dot) + s.range_rate_sigma_mps * standard_normal(rng));
            let body_velocity_mps = s.relative_velocity.then(|| {
                body_relative_velocity(&a.attitude, &d_dot)
                    + gauss3(rng, &Vector3::repeat(s.relative_velocity_sigma_mps))
            });
            out.push(RelativeRate {
                from,
                to,
                range_rate_mps,
                body_velocity_mps,
            });
        }
    }
    out
}
