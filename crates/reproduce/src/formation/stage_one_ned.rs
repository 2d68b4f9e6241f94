//! Stage 1 of one member in an Earth frame (`ins_model = "ned"`): the
//! formation's flight, defined in the local tangent plane (ENU) at the
//! origin `origin_latitude_deg`, `origin_longitude_deg` on the WGS-84
//! ellipsoid, is carried onto the rotating Earth; the member's IMU measures
//! what a perfect IMU along that path measures ([`ideal_increment`]: Earth
//! rate, transport rate, Coriolis and normal gravity included) plus the same
//! instrument errors as the flat model draws; the WGS-84 NED INS and its
//! filter ([`NedLooselyCoupled`]) run on it, and the solution is returned in
//! the tangent-plane frame stage 2 and the relative sensors use.
//!
//! The random numbers are drawn in the flat model's order and frames (ENU,
//! body forward–left–up) and then turned into NED and forward–right–down,
//! so that both models see the same errors run for run.

use aidnav_estimation::EstimationError;
use aidnav_frames::earth::Geodetic;
use aidnav_frames::{Ecef, Ned, Rotation, Vec3};
use aidnav_ins::local_level::LocalLevelState;
use aidnav_ins::ned::{ImuIncrement, NedState, ideal_increment};
use aidnav_integration::group::OwnSolution;
use aidnav_integration::ned_loosely::{NedLooselyCoupled, prior_sigmas};
use aidnav_models::local_ins::Matrix6;
use aidnav_sim::rng::{RunRng, channel_rng, standard_normal};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use super::FormationScenario;
use super::simulate::{ErrorProcesses, reported_noise};

/// ENU → NED and forward–left–up → forward–right–down (each its own inverse).
const ENU_NED: Matrix3<f64> = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, -1.0);
const FLU_FRD: Matrix3<f64> = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);

/// The formation's tangent plane on the ellipsoid.
pub(super) struct EarthFrame {
    origin_ecef: Vector3<f64>,
    /// Tangent-plane ENU → ECEF.
    enu_to_ecef: Matrix3<f64>,
}

fn quaternion(m: &Matrix3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*m))
}

impl EarthFrame {
    pub(super) fn new(sc: &FormationScenario) -> Self {
        let origin = Geodetic {
            latitude_rad: sc.origin_latitude_deg.to_radians(),
            longitude_rad: sc.origin_longitude_deg.to_radians(),
            height_m: 0.0,
        };
        Self {
            origin_ecef: origin.to_ecef().raw(),
            enu_to_ecef: origin.ecef_to_ned().raw().transpose() * ENU_NED,
        }
    }

    /// Tangent-plane ENU → local NED at `p`.
    fn enu_to_ned(&self, p: &Geodetic) -> Matrix3<f64> {
        p.ecef_to_ned().raw() * self.enu_to_ecef
    }

    /// A tangent-plane state on the Earth; also the ENU → local NED rotation.
    pub(super) fn to_earth(&self, s: &LocalLevelState) -> (NedState, Matrix3<f64>) {
        let ecef = Vec3::<Ecef>::assume_in_frame(self.origin_ecef + self.enu_to_ecef * s.position);
        let position = Geodetic::from_ecef(&ecef);
        let t = self.enu_to_ned(&position);
        let c_bn = t * s.attitude.to_rotation_matrix().into_inner() * FLU_FRD;
        (
            NedState {
                position,
                velocity: Vec3::assume_in_frame(t * s.velocity),
                attitude: Rotation::assume_from_quaternion(quaternion(&c_bn)),
            },
            t,
        )
    }

    /// An Earth state in the tangent plane; also the ENU → local NED rotation.
    pub(super) fn to_tangent_plane(&self, s: &NedState) -> (LocalLevelState, Matrix3<f64>) {
        let t = self.enu_to_ned(&s.position);
        let position =
            self.enu_to_ecef.transpose() * (s.position.to_ecef().raw() - self.origin_ecef);
        let c = t.transpose() * s.attitude.matrix().raw() * FLU_FRD;
        (
            LocalLevelState {
                position,
                velocity: t.transpose() * s.velocity.raw(),
                attitude: quaternion(&c),
            },
            t,
        )
    }
}

fn gauss3(rng: &mut RunRng, sigma: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        sigma.x * standard_normal(rng),
        sigma.y * standard_normal(rng),
        sigma.z * standard_normal(rng),
    )
}

/// A 6×6 position–velocity covariance turned by `r` (3×3) in both blocks.
fn rotate6(p: &Matrix6, r: &Matrix3<f64>) -> Matrix6 {
    let mut big = Matrix6::zeros();
    big.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
    big.fixed_view_mut::<3, 3>(3, 3).copy_from(r);
    let out = big * p * big.transpose();
    (out + out.transpose()) * 0.5
}

/// A 6×6 cross-covariance E[e_k e_jᵀ] of position–velocity errors turned
/// by `r_k` on the left and `r_j` on the right (each in both blocks).
fn rotate6_between(c: &Matrix6, r_k: &Matrix3<f64>, r_j: &Matrix3<f64>) -> Matrix6 {
    let block = |r: &Matrix3<f64>| {
        let mut big = Matrix6::zeros();
        big.fixed_view_mut::<3, 3>(0, 0).copy_from(r);
        big.fixed_view_mut::<3, 3>(3, 3).copy_from(r);
        big
    };
    block(r_k) * c * block(r_j).transpose()
}

/// What stage 1 of one member takes from the formation's flight alone: the
/// truth in the tangent plane and on the Earth and what a perfect IMU
/// measures along it. The same in every run, so computed once per campaign
/// ([`MemberPath::new`]) and read by every run's [`member`]: the same
/// numbers as computing them in each run.
pub(super) struct MemberPath {
    /// The truth at t = 0, on the Earth, and the ENU → NED rotation there.
    start: (LocalLevelState, NedState, Matrix3<f64>),
    /// Per IMU step, the perfect IMU's increment ([`ideal_increment`]).
    ideal: Vec<ImuIncrement>,
    /// Per epoch, the truth at the epoch, on the Earth, and the ENU → NED
    /// rotation there.
    epochs: Vec<(LocalLevelState, NedState, Matrix3<f64>)>,
}

impl MemberPath {
    /// The path of member `l` over the flight.
    pub(super) fn new(sc: &FormationScenario, l: usize) -> Self {
        let frame = EarthFrame::new(sc);
        let (epochs, steps, dt) = (sc.epochs(), sc.imu_steps_per_fix(), sc.imu_dt_s);
        let start = sc.truth(l, 0.0);
        let (start_e, t0) = frame.to_earth(&start);
        let mut ideal = Vec::with_capacity(epochs * steps);
        let mut at_epochs = Vec::with_capacity(epochs);
        let mut prev = start;
        let mut prev_e = start_e;
        let mut previous: Option<ImuIncrement> = None;
        for epoch in 0..epochs {
            for s in 0..steps {
                let t = (epoch * steps + s + 1) as f64 * dt;
                let next = sc.truth(l, t);
                let (next_e, _) = frame.to_earth(&next);
                let increment = ideal_increment(previous.as_ref(), &prev_e, &next_e, dt);
                ideal.push(increment);
                previous = Some(increment);
                prev = next;
                prev_e = next_e;
            }
            let (_, t_true) = frame.to_earth(&prev);
            at_epochs.push((prev, prev_e, t_true));
        }
        Self {
            start: (start, start_e, t0),
            ideal,
            epochs: at_epochs,
        }
    }
}

/// Stage 1 of member `l` over the flight: per epoch, its INS* solution (in
/// the tangent plane) and the truth; `path` is the member's
/// [`MemberPath`].
pub(super) fn member(
    sc: &FormationScenario,
    run: u64,
    l: usize,
    path: &MemberPath,
) -> Result<Vec<(OwnSolution, LocalLevelState)>, EstimationError> {
    let frame = EarthFrame::new(sc);
    let epochs = sc.epochs();
    let steps = sc.imu_steps_per_fix();
    let dt = sc.imu_dt_s;
    let model = sc.model;
    let imu = model.imu;
    let gnss = model.gnss;
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
    let mut rng = channel_rng(sc.seed, run, l as u64);
    let (_, start_e, t0) = path.start;
    // The flat model's draws (ENU), turned into the local NED.
    let psi = t0 * gauss3(&mut rng, &attitude_sigma);
    let dp0 = t0 * gauss3(&mut rng, &Vector3::repeat(i.position_sigma_m));
    let dv0 = t0 * gauss3(&mut rng, &Vector3::repeat(i.velocity_sigma_mps));
    let ins0 = NedState {
        position: start_e.position.offset_by(&Vec3::assume_in_frame(dp0)),
        velocity: start_e.velocity + Vec3::assume_in_frame(dv0),
        attitude: Rotation::<Ned, Ned>::from_rotation_vector(Vec3::assume_in_frame(-psi))
            * start_e.attitude,
    };
    // Tilt about N and E, heading about D: the flat model's σ in its order.
    let prior = prior_sigmas(
        &model,
        i.position_sigma_m,
        i.velocity_sigma_mps,
        ENU_NED * attitude_sigma,
    );
    let mut lc = NedLooselyCoupled::new(model, ins0, &prior, sc.filter_dt_s)?;
    // NED → ENU rotation at the error cross-covariance's reference epoch.
    let mut back_previous = frame.to_tangent_plane(lc.solution()).1.transpose();
    let mut accel_bias = gauss3(&mut rng, &Vector3::repeat(imu.accel_bias_sigma_m_s2));
    let mut gyro_bias = gauss3(&mut rng, &Vector3::repeat(imu.gyro_bias_sigma_rad_s));
    let mut gnss_position = gauss3(&mut rng, &gnss_pos_sigma);
    let mut gnss_velocity = gauss3(&mut rng, &Vector3::repeat(gnss.velocity_sigma_mps));
    let mut out = Vec::with_capacity(epochs);
    for epoch in 0..epochs {
        for s in 0..steps {
            let ideal = &path.ideal[epoch * steps + s];
            // Draw as the flat model does (body forward–left–up), then turn.
            let gyro_err = gyro_bias + gauss3(&mut rng, &Vector3::repeat(gyro_noise));
            let accel_err = accel_bias + gauss3(&mut rng, &Vector3::repeat(accel_noise));
            let raw = ImuIncrement {
                dt_s: dt,
                delta_angle: Vec3::assume_in_frame(
                    ideal.delta_angle.raw() + FLU_FRD * gyro_err * dt,
                ),
                delta_velocity: Vec3::assume_in_frame(
                    ideal.delta_velocity.raw() + FLU_FRD * accel_err * dt,
                ),
            };
            lc.step_increment(&raw)?;
            accel_bias = accel_bias * ba_phi + gauss3(&mut rng, &Vector3::repeat(ba_q.sqrt()));
            gyro_bias = gyro_bias * bg_phi + gauss3(&mut rng, &Vector3::repeat(bg_q.sqrt()));
        }
        let (prev, prev_e, t_true) = path.epochs[epoch];
        let t = (epoch + 1) as f64 * sc.fix_interval_s;
        gnss_position = gnss_position * ep_phi
            + gauss3(&mut rng, &(gnss_pos_sigma * (1.0 - ep_phi * ep_phi).sqrt()));
        gnss_velocity = gnss_velocity * ev_phi + gauss3(&mut rng, &Vector3::repeat(ev_q.sqrt()));
        let white_p = gauss3(&mut rng, &Vector3::repeat(gnss.position_white_sigma_m));
        let white_v = gauss3(&mut rng, &Vector3::repeat(gnss.velocity_white_sigma_mps));
        let fix = |position_err_enu: Vector3<f64>, bias_ned: Vector3<f64>, velocity_err_enu| {
            (
                prev_e
                    .position
                    .offset_by(&Vec3::assume_in_frame(t_true * position_err_enu + bias_ned)),
                prev_e.velocity + Vec3::assume_in_frame(t_true * velocity_err_enu),
            )
        };
        if sc.denied(l, t) {
            lc.propagate()?;
        } else if let Some(d) = sc.degradation_at(l, t) {
            let k = d.sigma_scale;
            let (position, velocity) = fix(
                (gnss_position + white_p) * k,
                Vector3::from(d.bias_m),
                (gnss_velocity + white_v) * k,
            );
            if d.reported {
                lc.gnss_update_with_noise(&position, &velocity, &reported_noise(sc, k))?;
            } else {
                lc.gnss_update(&position, &velocity)?;
            }
        } else {
            let (position, velocity) = fix(
                gnss_position + white_p,
                Vector3::zeros(),
                gnss_velocity + white_v,
            );
            lc.gnss_update(&position, &velocity)?;
        }
        let (state, t_ins) = frame.to_tangent_plane(lc.solution());
        let back = t_ins.transpose();
        out.push((
            OwnSolution {
                state,
                covariance: rotate6(&lc.position_velocity_covariance(), &back),
                attitude_covariance: {
                    let a = back * lc.attitude_covariance() * t_ins;
                    (a + a.transpose()) * 0.5
                },
                error_cross_covariance: Some(rotate6_between(
                    &lc.take_error_cross_covariance(),
                    &back,
                    &std::mem::replace(&mut back_previous, back),
                )),
            },
            prev,
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::{Denial, InsModel};
    use super::*;

    /// The tangent plane and the Earth frame map onto each other exactly.
    #[test]
    fn tangent_plane_round_trips_through_the_earth() {
        let sc = FormationScenario {
            origin_latitude_deg: -33.0,
            origin_longitude_deg: 151.0,
            ..FormationScenario::default()
        };
        let frame = EarthFrame::new(&sc);
        for (l, t) in [(0, 0.0), (3, 250.0), (4, 599.0)] {
            let s = sc.truth(l, t);
            let (e, _) = frame.to_earth(&s);
            let (back, _) = frame.to_tangent_plane(&e);
            assert!((back.position - s.position).norm() < 1e-6);
            assert!((back.velocity - s.velocity).norm() < 1e-9);
            assert!(back.attitude.angle_to(&s.attitude) < 1e-9);
            // Height above the ellipsoid: the altitude plus the plane's
            // rise over the curved Earth (≈ d²/2R).
            let d = s.position.xy().norm();
            let rise = d * d / (2.0 * 6.371e6);
            assert!((e.position.height_m - s.position.z - rise).abs() < 0.05 * rise + 0.01);
        }
    }

    /// Stage 1 with the Earth-frame model on a short flight (two members),
    /// 12 runs of member 1 with a GNSS gap from 60 s to 90 s: its errors agree with its
    /// own σ (NEES per axis, position and velocity, close to 1), and the flat
    /// model, given the same random numbers, agrees with it closely.
    #[test]
    fn ned_stage_one_is_consistent_and_agrees_with_the_flat_model_on_a_short_flight() {
        let base = FormationScenario {
            members: 2,
            duration_s: 120.0,
            settle_s: 20.0,
            denial: vec![Denial {
                members: vec![1],
                start_s: 60.0,
                end_s: 90.0,
            }],
            ..FormationScenario::default()
        };
        let runs = 12;
        let l = 1;
        let mut nees = [0.0; 2];
        let mut count = 0.0;
        let mut sq = [[0.0; 2]; 2]; // [model][position, velocity]
        for (m, ins_model) in [InsModel::Ned, InsModel::Flat].into_iter().enumerate() {
            let sc = FormationScenario {
                ins_model,
                ..base.clone()
            };
            for run in 0..runs {
                let (own, truth) = super::super::simulate::stage_one(&sc, run).unwrap();
                for (k, (own_e, truth_e)) in own.iter().zip(&truth).enumerate() {
                    if ((k + 1) as f64) < sc.settle_s {
                        continue;
                    }
                    let o = &own_e[l];
                    let ep = o.state.position - truth_e[l].position;
                    let ev = o.state.velocity - truth_e[l].velocity;
                    sq[m][0] += ep.norm_squared();
                    sq[m][1] += ev.norm_squared();
                    if ins_model == InsModel::Ned {
                        let p = o.covariance.fixed_view::<3, 3>(0, 0).into_owned();
                        let v = o.covariance.fixed_view::<3, 3>(3, 3).into_owned();
                        nees[0] += ep.dot(&(p.cholesky().unwrap().solve(&ep))) / 3.0;
                        nees[1] += ev.dot(&(v.cholesky().unwrap().solve(&ev))) / 3.0;
                        count += 1.0;
                    }
                }
            }
        }
        let nees = nees.map(|n| n / count);
        // 12 runs × 100 epochs, strongly correlated in time (the receiver's
        // τ = 300 s): a wide band.
        for (name, n) in ["position", "velocity"].iter().zip(nees) {
            assert!((0.4..2.0).contains(&n), "{name} NEES {n}");
        }
        for (q, (ned, flat)) in sq[0].iter().zip(&sq[1]).enumerate() {
            let (ned, flat) = (ned.sqrt(), flat.sqrt());
            assert!(
                (ned / flat - 1.0).abs() < 0.1,
                "quantity {q}: ned {ned}, flat {flat}"
            );
        }
    }

    /// The origin must be on the ellipsoid away from the poles (the NED
    /// frame is singular there); a bad key is named.
    #[test]
    fn origin_out_of_range_is_named() {
        use aidnav_io::config::Validate;
        for (lat, lon, key) in [
            (89.0, 0.0, "origin_latitude_deg"),
            (f64::NAN, 0.0, "origin_latitude_deg"),
            (10.0, 181.0, "origin_longitude_deg"),
        ] {
            let sc = FormationScenario {
                origin_latitude_deg: lat,
                origin_longitude_deg: lon,
                ..FormationScenario::default()
            };
            assert_eq!(sc.validate().unwrap_err().key, key);
        }
        let flat = FormationScenario {
            ins_model: InsModel::Flat,
            ..FormationScenario::default()
        };
        assert!(flat.validate().is_ok());
    }
}
