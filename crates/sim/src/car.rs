//! A simulated land-vehicle log with known truth: one entry point,
//! [`simulate_car`], from a [`CarScenario`] (route, IMU, GNSS, wheel speed,
//! barometer; a serde struct, the future TOML scenario) and one master seed.
//!
//! ```
//! use aidnav_sim::car::{CarScenario, simulate_car};
//! let mut scenario = CarScenario::default();
//! scenario.gnss.outages_s = vec![[200.0, 260.0]]; // 60 s without GNSS
//! let log = simulate_car(&scenario, 42).unwrap();
//! assert_eq!(log.imu.len(), log.truth.len()); // 100 Hz, 450 s
//! assert_eq!(log.imu.len(), 45_001);
//! assert_eq!(log.gnss.len(), 451 - 60); // 1 Hz, minus the outage
//! assert_eq!(log.wheel_speed.len(), 9_001); // 20 Hz
//! assert_eq!(log.baro.len(), 4_501); // 10 Hz
//! // The truth at any time, e.g. between two IMU samples.
//! let s = log.truth_at(log.truth[0].time_s + 100.005).unwrap();
//! assert!(s.speed_mps > 0.0);
//! // Same seed, same log.
//! assert_eq!(log, simulate_car(&scenario, 42).unwrap());
//! ```
//!
//! Streams: the generator of every error process is derived from
//! (seed, run, [`Stream`](crate::rng::Stream)), so each process's numbers
//! depend only on those three — switching another process on or off, or
//! adding a new one, leaves them unchanged.
//!
//! ## Limitations
//! Roll is always zero and the pitch is the road grade (no suspension
//! motion, no bank); the IMU axes are the vehicle axes (no mounting
//! misalignment); no IMU quantisation, g-sensitivity or axis
//! misalignment; the barometer sits at the IMU; the wheel speed is noisy
//! also at standstill; GNSS errors are per-axis white plus optional
//! Gauss–Markov, with no multipath or satellite geometry.

use aidnav_sensors::{BaroSample, GnssFix, ImuSample, WheelSpeedSample};
use serde::{Deserialize, Serialize};

use crate::aiding::{BaroSpec, WheelSpeedSpec, simulate_baro, simulate_wheel_speed};
use crate::error::{SimError, finite};
use crate::gnss::{GnssSpec, simulate_gnss};
use crate::ground::{CarRoute, drive};
use crate::imu::{ImuErrorDraw, ImuSpec, simulate_imu};
use crate::truth::{TruthSample, truth_at};

/// Default start time: GPST 2023-11-14 22:13:20 \[s since 1970\].
pub const DEFAULT_START_TIME_S: f64 = 1_700_000_000.0;

/// Everything a car simulation needs but the seed. The default: a 450 s,
/// 6.0 km urban drive ([`CarRoute::default`]) logged by an industrial MEMS IMU at
/// 100 Hz ([`ImuSpec::default`]), 1 Hz GNSS of σ 1.5 m horizontal, 3 m
/// vertical with the antenna on the roof ([`GnssSpec::default`]), a rear
/// axle odometer at 20 Hz ([`WheelSpeedSpec::default`]) and a 10 Hz
/// barometer ([`BaroSpec::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CarScenario {
    /// GPST of the first sample \[s since 1970-01-01\]. Default
    /// [`DEFAULT_START_TIME_S`].
    pub start_time_s: f64,
    /// The drive.
    pub route: CarRoute,
    /// The IMU (its rate is the truth's).
    pub imu: ImuSpec,
    /// The GNSS receiver.
    pub gnss: GnssSpec,
    /// The wheel-speed odometer.
    pub wheel_speed: WheelSpeedSpec,
    /// The barometer.
    pub baro: BaroSpec,
}

impl Default for CarScenario {
    fn default() -> Self {
        Self {
            start_time_s: DEFAULT_START_TIME_S,
            route: CarRoute::default(),
            imu: ImuSpec::default(),
            gnss: GnssSpec::default(),
            wheel_speed: WheelSpeedSpec::default(),
            baro: BaroSpec::default(),
        }
    }
}

/// A simulated log and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct CarLog {
    /// Master seed of the run.
    pub seed: u64,
    /// Run number under the seed (0 for [`simulate_car`]).
    pub run: u64,
    /// The truth at each IMU sample time.
    pub truth: Vec<TruthSample>,
    /// IMU samples (body axes; rad/s, m/s²), one per truth sample.
    pub imu: Vec<ImuSample>,
    /// The IMU errors drawn at turn-on (bias, scale factor).
    pub imu_errors: ImuErrorDraw,
    /// GNSS fixes of the antenna (none inside the outages).
    pub gnss: Vec<GnssFix>,
    /// Wheel-speed samples.
    pub wheel_speed: Vec<WheelSpeedSample>,
    /// Barometric height samples.
    pub baro: Vec<BaroSample>,
}

impl CarLog {
    /// The truth interpolated at `time_s` (GPST \[s\]); `None` outside the
    /// log ([`truth_at`]).
    pub fn truth_at(&self, time_s: f64) -> Option<TruthSample> {
        truth_at(&self.truth, time_s)
    }
}

/// Simulate `scenario` under master seed `seed` (run 0).
///
/// ```
/// use aidnav_sim::{CarScenario, simulate_car};
/// let log = simulate_car(&CarScenario::default(), 7).unwrap();
/// // 450 s at 100 Hz; the truth and the IMU share the sample times.
/// assert_eq!(log.imu.len(), 45_001);
/// assert!(log.imu.iter().zip(&log.truth).all(|(m, t)| m.time_s == t.time_s));
/// // A car: the velocity lies along the body x axis.
/// let s = &log.truth[10_000];
/// assert!(s.velocity_body().y().abs() < 1e-9 && s.speed_mps > 10.0);
/// // Bad parameters are errors, not panics.
/// let mut bad = CarScenario::default();
/// bad.baro.rate_hz = -10.0;
/// assert!(simulate_car(&bad, 7).is_err());
/// ```
pub fn simulate_car(scenario: &CarScenario, seed: u64) -> Result<CarLog, SimError> {
    simulate_car_run(scenario, seed, 0)
}

/// Simulate run `run` of `scenario` under master seed `seed` (Monte Carlo:
/// the same truth, independent errors per run).
pub fn simulate_car_run(scenario: &CarScenario, seed: u64, run: u64) -> Result<CarLog, SimError> {
    finite("start_time_s", scenario.start_time_s)?;
    scenario.imu.validate()?;
    scenario.gnss.validate()?;
    scenario.wheel_speed.validate()?;
    scenario.baro.validate()?;
    let truth = drive(&scenario.route, scenario.imu.rate_hz, scenario.start_time_s)?;
    let (imu, imu_errors) = simulate_imu(&scenario.imu, &truth, seed, run)?;
    let gnss = simulate_gnss(&scenario.gnss, &truth, seed, run)?;
    let wheel_speed = simulate_wheel_speed(&scenario.wheel_speed, &truth, seed, run)?;
    let baro = simulate_baro(&scenario.baro, &truth, seed, run)?;
    Ok(CarLog {
        seed,
        run,
        truth,
        imu,
        imu_errors,
        gnss,
        wheel_speed,
        baro,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_frames::{Body, Vec3};
    use aidnav_ins::increments::{Rates, trapezoid};
    use aidnav_ins::ned::NedMechanization;
    use nalgebra::Vector3;

    /// Mechanize `imu[from..=to]` through the loop's trapezoid increments
    /// from the true state at `from`; (position, velocity, attitude) error
    /// against the truth at `to` [m, m/s, rad].
    fn mechanize(log: &CarLog, from: usize, to: usize) -> (f64, f64, f64) {
        let mut ins = NedMechanization::new(log.truth[from].nav_state());
        for k in from + 1..=to {
            let (a, b) = (&log.imu[k - 1], &log.imu[k]);
            ins.update(&trapezoid(
                &Rates::of(a),
                &Rates::of(b),
                b.time_s - a.time_s,
            ));
        }
        let (s, t) = (ins.state(), &log.truth[to]);
        (
            t.position.ned_to(&s.position).norm(),
            (s.velocity - t.velocity_ned).norm(),
            s.attitude.angle_to(&t.attitude),
        )
    }

    fn ideal_scenario() -> CarScenario {
        CarScenario {
            imu: ImuSpec::ideal(100.0),
            ..CarScenario::default()
        }
    }

    /// The brief asked for "within a few decimetres after 120 s of driving
    /// with turns"; asserted 1 cm. Measured 120 s from the first move
    /// (t = 20 s: accelerate, cruise over the hill, a right turn, stop, a
    /// left turn): 0.54 mm, 4.4 µm/s, 2.8e-10 rad; the whole 450 s drive:
    /// 2.2 mm, 9.7 µm/s, 8.0e-10 rad. The residual is the trapezoid rule on
    /// the rates (O(Δt²) per step), the mechanization's first-order frame
    /// rotation and the rounding of the GPST sample times (2.4e-7 s).
    const CONSISTENCY_LIMIT_M: f64 = 0.01;

    #[test]
    fn error_free_imu_reproduces_the_truth_through_the_mechanization() {
        let log = simulate_car(&ideal_scenario(), 0).unwrap();
        let start = 20 * 100;
        let (dp, dv, da) = mechanize(&log, start, start + 120 * 100);
        eprintln!("120 s: position {dp:.2e} m, velocity {dv:.2e} m/s, attitude {da:.2e} rad");
        assert!(dp < CONSISTENCY_LIMIT_M, "position {dp} m");
        assert!(dv < 1e-3, "velocity {dv} m/s");
        assert!(da < 1e-6, "attitude {da} rad");
        let (dp, dv, da) = mechanize(&log, 0, log.imu.len() - 1);
        eprintln!("whole drive: position {dp:.2e} m, velocity {dv:.2e} m/s, attitude {da:.2e} rad");
        assert!(dp < CONSISTENCY_LIMIT_M, "position {dp} m");
    }

    #[test]
    fn the_default_drive_is_a_car_drive() {
        let scenario = ideal_scenario();
        let log = simulate_car(&scenario, 0).unwrap();
        assert_eq!(log.truth[0].position, scenario.route.start_position());
        let last = log.truth.last().unwrap();
        let duration = last.time_s - log.truth[0].time_s;
        let (mut max_lat, mut max_dh, mut max_speed) = (0.0f64, 0.0f64, 0.0f64);
        for s in &log.truth {
            // No sideslip, no vertical body velocity (non-holonomic).
            let vb = s.velocity_body();
            assert!(vb.y().abs() < 1e-12 && vb.z().abs() < 1e-12, "{vb}");
            assert!((vb.x() - s.speed_mps).abs() < 1e-12);
            let f = s.specific_force_body;
            max_lat = max_lat.max(f.y().abs());
            max_dh = max_dh.max(s.position.height_m - log.truth[0].position.height_m);
            max_speed = max_speed.max(s.speed_mps);
        }
        eprintln!(
            "duration {duration} s, distance {:.0} m, max lateral {max_lat:.2} m/s², \
             max climb {max_dh:.2} m, max speed {max_speed} m/s",
            last.distance_m
        );
        assert!((300.0..=600.0).contains(&duration), "{duration}");
        assert!(max_lat < 3.0, "lateral {max_lat} m/s²");
        assert!(max_dh > 5.0, "hill {max_dh} m");
        assert_eq!(last.speed_mps, 0.0);
        // The hills come back down.
        assert!((last.position.height_m - log.truth[0].position.height_m).abs() < 1e-6);
    }

    #[test]
    fn same_seed_same_log_bit_for_bit_other_seed_other_log() {
        let scenario = CarScenario {
            gnss: GnssSpec {
                position_markov_sigma_neu_m: [0.5; 3],
                ..GnssSpec::default()
            },
            ..CarScenario::default()
        };
        let a = simulate_car(&scenario, 7).unwrap();
        let b = simulate_car(&scenario, 7).unwrap();
        let bits = |log: &CarLog| -> Vec<u64> {
            let mut v = Vec::new();
            for s in &log.imu {
                v.extend(
                    s.angular_rate
                        .iter()
                        .chain(&s.specific_force)
                        .map(|x| x.to_bits()),
                );
            }
            for f in &log.gnss {
                v.push(f.position.latitude_rad.to_bits());
                v.push(f.position.height_m.to_bits());
                v.extend(f.velocity_ned.unwrap().iter().map(|x| x.to_bits()));
            }
            v.extend(log.wheel_speed.iter().map(|w| w.speed_mps.to_bits()));
            v.extend(log.baro.iter().map(|w| w.height_m.to_bits()));
            v
        };
        assert_eq!(bits(&a), bits(&b));
        assert_eq!(a, b);
        let c = simulate_car(&scenario, 8).unwrap();
        assert_eq!(a.truth, c.truth);
        assert_ne!(a.imu[1000], c.imu[1000]);
        assert_ne!(a.gnss[10].position, c.gnss[10].position);
        assert_ne!(a.wheel_speed[10], c.wheel_speed[10]);
        assert_ne!(a.baro[10], c.baro[10]);
        assert_ne!(a.imu_errors, c.imu_errors);
        let run1 = simulate_car_run(&scenario, 7, 1).unwrap();
        assert_ne!(a.imu[1000], run1.imu[1000]);
    }

    #[test]
    fn streams_are_independent() {
        let base = simulate_car(&CarScenario::default(), 3).unwrap();
        // Switch the GNSS Gauss–Markov error and the baro drift off, add an
        // outage: the IMU, the wheel speed and the GNSS velocity are unchanged.
        let mut other = CarScenario::default();
        other.gnss.position_markov_sigma_neu_m = [1.0; 3];
        other.gnss.outages_s = vec![[100.0, 160.0]];
        other.baro.drift_sigma_m = 0.0;
        other.imu.accel.scale_factor_sigma_ppm = [0.0; 3];
        let log = simulate_car(&other, 3).unwrap();
        assert_eq!(base.wheel_speed, log.wheel_speed);
        assert_eq!(
            base.imu.iter().map(|s| s.angular_rate).collect::<Vec<_>>(),
            log.imu.iter().map(|s| s.angular_rate).collect::<Vec<_>>()
        );
        let by_time = |t: f64| base.gnss.iter().find(|f| f.time_s == t).unwrap();
        for f in &log.gnss {
            assert_eq!(f.velocity_ned, by_time(f.time_s).velocity_ned);
        }
    }

    #[test]
    fn outage_windows_have_no_fixes() {
        let mut scenario = CarScenario::default();
        scenario.gnss.outages_s = vec![[100.0, 160.0], [300.5, 301.5]];
        let t0 = scenario.start_time_s;
        let log = simulate_car(&scenario, 1).unwrap();
        let full = simulate_car(&CarScenario::default(), 1).unwrap();
        for f in &log.gnss {
            let t = f.time_s - t0;
            assert!(
                !(100.0..160.0).contains(&t) && !(300.5..301.5).contains(&t),
                "{t}"
            );
        }
        let rel: Vec<f64> = log.gnss.iter().map(|f| f.time_s - t0).collect();
        assert!(rel.contains(&99.0) && rel.contains(&160.0) && !rel.contains(&301.0));
        assert_eq!(log.gnss.len(), full.gnss.len() - 61);
        // The fixes outside the windows are those of the run without outages.
        for f in &log.gnss {
            assert!(full.gnss.contains(f));
        }
    }

    #[test]
    fn noise_free_wheel_speed_is_the_forward_speed_times_one_plus_k() {
        let mut scenario = ideal_scenario();
        scenario.wheel_speed.noise_sigma_mps = 0.0;
        scenario.wheel_speed.scale_error = 0.02;
        // At the IMU: exactly the truth speed × (1 + k).
        scenario.wheel_speed.lever_arm_m = [0.0; 3];
        let log = simulate_car(&scenario, 0).unwrap();
        for w in &log.wheel_speed {
            let s = log.truth_at(w.time_s).unwrap();
            assert!(
                (w.speed_mps - 1.02 * s.speed_mps).abs() < 1e-12,
                "{} {} {} {}",
                w.time_s - log.truth[0].time_s,
                w.speed_mps,
                s.speed_mps,
                s.velocity_body()
            );
            assert_eq!(w.sigma_mps, Some(0.0));
        }
        // The rear-left wheel: faster than the IMU point in right turns
        // (the outer wheel) by ω_z · 0.8 m, and by ω_y · 0.3 m over the
        // hills (up to 5.5 mm/s).
        scenario.wheel_speed.lever_arm_m = [-1.3, -0.8, 0.3];
        let log = simulate_car(&scenario, 0).unwrap();
        let lever = Vec3::<Body>::new(-1.3, -0.8, 0.3);
        let mut max_diff = 0.0f64;
        for w in &log.wheel_speed {
            let s = log.truth_at(w.time_s).unwrap();
            let expect = 1.02 * s.point_velocity_body(&lever).x();
            assert!((w.speed_mps - expect).abs() < 1e-12);
            let w_eb = s.earth_relative_rate_body();
            let turn_term = 1.02 * (s.speed_mps + 0.8 * w_eb.z());
            let hill_term = 1.02 * 0.3 * w_eb.y().abs();
            assert!(
                (w.speed_mps - turn_term).abs() <= hill_term + 1e-9,
                "{} {}",
                w.speed_mps,
                turn_term
            );
            max_diff = max_diff.max((w.speed_mps - 1.02 * s.speed_mps).abs());
        }
        // 12 °/s × 0.8 m ≈ 0.17 m/s in the turns.
        assert!(max_diff > 0.15, "{max_diff}");
    }

    #[test]
    fn noise_free_baro_is_height_plus_bias() {
        let mut scenario = ideal_scenario();
        scenario.baro.drift_sigma_m = 0.0;
        scenario.baro.noise_sigma_m = 0.0;
        scenario.baro.bias_m = -12.5;
        let log = simulate_car(&scenario, 0).unwrap();
        for b in &log.baro {
            let s = log.truth_at(b.time_s).unwrap();
            assert!((b.height_m - (s.position.height_m - 12.5)).abs() < 1e-12);
        }
        // Drift and noise: the error about height + bias has the σ written.
        let log = simulate_car(&CarScenario::default(), 5).unwrap();
        let sigma = log.baro[0].sigma_m.unwrap();
        let rms = (log
            .baro
            .iter()
            .map(|b| {
                (b.height_m - log.truth_at(b.time_s).unwrap().position.height_m - 10.0).powi(2)
            })
            .sum::<f64>()
            / log.baro.len() as f64)
            .sqrt();
        eprintln!("baro: σ written {sigma:.3} m, rms error {rms:.3} m");
        assert!(rms < 3.0 * sigma, "{rms} {sigma}");
    }

    #[test]
    fn noise_free_gnss_is_the_antenna() {
        let mut scenario = ideal_scenario();
        scenario.gnss = GnssSpec {
            lever_arm_m: [-0.5, 0.3, -1.0],
            ..GnssSpec::ideal()
        };
        let lever = Vec3::<Body>::new(-0.5, 0.3, -1.0);
        let log = simulate_car(&scenario, 0).unwrap();
        assert_eq!(log.gnss.len(), log.truth.len() / 100 + 1);
        for f in &log.gnss {
            let s = log.truth_at(f.time_s).unwrap();
            let d = s.point_position(&lever).ned_to(&f.position).norm();
            assert!(d < 1e-6, "{d}");
            let v = (s.attitude * s.point_velocity_body(&lever)).raw();
            assert!((f.velocity_ned.unwrap() - v).norm() < 1e-12);
            assert_eq!((f.quality, f.satellites), (1, 10));
        }
        // With noise: the σ written and the scatter agree.
        let log = simulate_car(&CarScenario::default(), 9).unwrap();
        let lever = Vec3::<Body>::new(-0.5, 0.0, -1.0);
        let mut sum = Vector3::<f64>::zeros();
        for f in &log.gnss {
            let s = log.truth_at(f.time_s).unwrap();
            let e = s.point_position(&lever).ned_to(&f.position).raw();
            sum += e.component_mul(&e);
        }
        let rms = (sum / log.gnss.len() as f64).map(f64::sqrt);
        eprintln!("gnss rms N E D {:.2} {:.2} {:.2} m", rms.x, rms.y, rms.z);
        let sigma = log.gnss[0].position_sigma_neu;
        for i in 0..3 {
            assert!((rms[i] / sigma[i] - 1.0).abs() < 0.15, "{rms} {sigma}");
        }
    }

    /// The gyro and accelerometer white noise has the per-sample σ of
    /// the random walk coefficients: N · √f_s.
    #[test]
    fn imu_white_noise_matches_the_random_walk_coefficients() {
        let mut scenario = ideal_scenario();
        scenario.imu.gyro.angle_random_walk_deg_sqrt_h = [0.2; 3];
        scenario.imu.accel.velocity_random_walk_m_s_sqrt_h = [0.05; 3];
        let log = simulate_car(&scenario, 11).unwrap();
        let (mut g2, mut a2) = (0.0, 0.0);
        for (m, t) in log.imu.iter().zip(&log.truth) {
            g2 += (m.angular_rate - t.angular_rate_body.raw()).norm_squared();
            a2 += (m.specific_force - t.specific_force_body.raw()).norm_squared();
        }
        let n = 3.0 * log.imu.len() as f64;
        let gyro = (g2 / n).sqrt();
        let accel = (a2 / n).sqrt();
        let gyro_expect = 0.2f64.to_radians() / 60.0 * 10.0;
        let accel_expect = 0.05 / 60.0 * 10.0;
        assert!(
            (gyro / gyro_expect - 1.0).abs() < 0.02,
            "{gyro} {gyro_expect}"
        );
        assert!(
            (accel / accel_expect - 1.0).abs() < 0.02,
            "{accel} {accel_expect}"
        );
    }

    /// The default IMU's errors are what its doc says: turn-on errors of
    /// the datasheet σ, applied.
    #[test]
    fn turn_on_errors_are_drawn_and_applied() {
        let mut scenario = ideal_scenario();
        scenario.imu.gyro.turn_on_bias_sigma_deg_h = [10.0; 3];
        scenario.imu.accel.scale_factor_sigma_ppm = [500.0; 3];
        let log = simulate_car(&scenario, 2).unwrap();
        let e = log.imu_errors;
        assert!(e.gyro_bias_rad_s.norm() > 0.0 && e.gyro_bias_rad_s.amax() < 5e-4);
        assert!(e.accel_scale_factor.norm() > 0.0 && e.accel_scale_factor.amax() < 3e-3);
        for (m, t) in log.imu.iter().zip(&log.truth) {
            let w = t.angular_rate_body.raw() + e.gyro_bias_rad_s;
            assert!((m.angular_rate - w).norm() < 1e-15);
            let f = t
                .specific_force_body
                .raw()
                .component_mul(&(e.accel_scale_factor.add_scalar(1.0)));
            assert!((m.specific_force - f).norm() < 1e-12);
        }
    }

    #[test]
    fn bad_parameters_are_errors_not_panics() {
        let cases: Vec<(CarScenario, &str)> = vec![
            (
                CarScenario {
                    gnss: GnssSpec {
                        rate_hz: 0.0,
                        ..GnssSpec::default()
                    },
                    ..CarScenario::default()
                },
                "gnss.rate_hz",
            ),
            (
                CarScenario {
                    gnss: GnssSpec {
                        outages_s: vec![[10.0, 5.0]],
                        ..GnssSpec::default()
                    },
                    ..CarScenario::default()
                },
                "gnss.outages_s[0][1]",
            ),
            (
                CarScenario {
                    wheel_speed: WheelSpeedSpec {
                        noise_sigma_mps: -1.0,
                        ..WheelSpeedSpec::default()
                    },
                    ..CarScenario::default()
                },
                "wheel_speed.noise_sigma_mps",
            ),
            (
                CarScenario {
                    baro: BaroSpec {
                        drift_correlation_time_s: f64::NAN,
                        ..BaroSpec::default()
                    },
                    ..CarScenario::default()
                },
                "baro.drift_correlation_time_s",
            ),
            (
                CarScenario {
                    start_time_s: f64::INFINITY,
                    ..CarScenario::default()
                },
                "start_time_s",
            ),
        ];
        for (scenario, field) in cases {
            let err = simulate_car(&scenario, 0).unwrap_err();
            assert!(err.to_string().contains(field), "{err} / {field}");
        }
        let mut s = CarScenario::default();
        s.imu.gyro.bias_correlation_time_s[1] = 0.0;
        let err = simulate_car(&s, 0).unwrap_err();
        assert!(
            err.to_string()
                .contains("imu.gyro.bias_correlation_time_s[1]"),
            "{err}"
        );
    }
}

#[cfg(test)]
mod scenario_file_tests {
    use super::*;
    use crate::ground::Segment;

    /// A scenario as the future `aidnav simulate` will read it: every
    /// section optional, unknown keys rejected.
    const SCENARIO: &str = r#"
start_time_s = 1700000000.0

[route]
start_latitude_deg = 48.1
start_heading_deg = 90.0
segments = [
    { kind = "cruise", duration_s = 10.0 },
    { kind = "accelerate", speed_mps = 15.0, accel_mps2 = 1.5 },
    { kind = "turn", angle_deg = -45.0, rate_deg_s = 8.0 },
    { kind = "stop", duration_s = 5.0, decel_mps2 = 2.0 },
]
hills = [{ start_m = 20.0, length_m = 300.0, max_pitch_deg = 3.0 }]

[imu.gyro]
bias_instability_deg_h = [1.0, 1.0, 2.0]

[gnss]
rate_hz = 5.0
outages_s = [[20.0, 30.0]]

[baro]
bias_m = -3.0
"#;

    #[test]
    fn a_toml_scenario_maps_onto_the_structs_with_defaults() {
        let s: CarScenario = toml::from_str(SCENARIO).unwrap();
        assert_eq!(s.route.start_latitude_deg, 48.1);
        assert_eq!(s.route.start_longitude_deg, 114.3); // default
        assert_eq!(
            s.route.segments[2],
            Segment::Turn {
                angle_deg: -45.0,
                rate_deg_s: 8.0
            }
        );
        assert_eq!(s.imu.gyro.bias_instability_deg_h, [1.0, 1.0, 2.0]);
        assert_eq!(s.imu.gyro.angle_random_walk_deg_sqrt_h, [0.2; 3]); // default
        assert_eq!(s.gnss.outages_s, vec![[20.0, 30.0]]);
        assert_eq!(s.wheel_speed, WheelSpeedSpec::default());
        let log = simulate_car(&s, 1).unwrap();
        let t0 = s.start_time_s;
        assert!(
            log.gnss
                .iter()
                .all(|f| !(20.0..30.0).contains(&(f.time_s - t0)))
        );
        // The default scenario round-trips.
        let text = toml::to_string(&CarScenario::default()).unwrap();
        assert_eq!(
            toml::from_str::<CarScenario>(&text).unwrap(),
            CarScenario::default()
        );
        // Unknown keys are errors.
        assert!(toml::from_str::<CarScenario>("[gnss]\nrate = 1.0\n").is_err());
        assert!(
            toml::from_str::<CarScenario>("[route]\nsegments = [{ kind = \"fly\" }]\n").is_err()
        );
    }
}
