//! Truth of a simulated trajectory: the navigation state of the IMU point
//! at each IMU sample time, with the specific force and angular rate a
//! perfect IMU measures there, and its interpolation at any time
//! ([`truth_at`]).
//!
//! The inertial quantities are exact in the sense of the NED mechanization
//! of `aidnav-ins` (`aidnav_ins::ned`): WGS-84 radii, normal gravity with
//! height ([`aidnav_ins::ned::gravity_ned`]), Earth rate, transport rate and
//! Coriolis term; integrating the error-free samples through the trapezoid
//! increments the filter loop builds reproduces the trajectory (test in
//! [`crate::car`]: 0.5 mm after 120 s of urban driving, 2.2 mm after
//! the whole 450 s drive).

use aidnav_frames::earth::{Geodetic, earth_rate_ned};
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_ins::ned::NedState;
use aidnav_sensors::ImuSample;

/// The true state at one instant (all of the IMU point, body = vehicle
/// frame: x forward, y right, z down).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// GPST, seconds since 1970-01-01 \[s\].
    pub time_s: f64,
    /// Position of the IMU (ellipsoidal height) \[rad, rad, m\].
    pub position: Geodetic,
    /// NED velocity \[m/s\].
    pub velocity_ned: Vec3<Ned>,
    /// Attitude, body → NED.
    pub attitude: Rotation<Body, Ned>,
    /// Angular rate of the body relative to inertial space, in body axes,
    /// ω_ib^b \[rad/s\] (what a perfect gyro triad measures).
    pub angular_rate_body: Vec3<Body>,
    /// Specific force in body axes, f^b [m/s²] (what a perfect accelerometer
    /// triad measures).
    pub specific_force_body: Vec3<Body>,
    /// Forward speed, the body-x velocity \[m/s\] (≥ 0 for a car).
    pub speed_mps: f64,
    /// Distance driven from the start \[m\].
    pub distance_m: f64,
}

impl TruthSample {
    /// The navigation state of the NED mechanization (position, velocity,
    /// attitude) — e.g. the true start of an INS.
    pub fn nav_state(&self) -> NedState {
        NedState {
            position: self.position,
            velocity: self.velocity_ned,
            attitude: self.attitude,
        }
    }

    /// Velocity in body axes \[m/s\] (for a car without sideslip:
    /// (speed, 0, 0)).
    pub fn velocity_body(&self) -> Vec3<Body> {
        self.attitude.inverse() * self.velocity_ned
    }

    /// Angular rate of the body relative to the Earth in body axes,
    /// ω_eb^b = ω_ib^b − C_nb ω_ie^n \[rad/s\].
    pub fn earth_relative_rate_body(&self) -> Vec3<Body> {
        self.angular_rate_body
            - self.attitude.inverse() * earth_rate_ned(self.position.latitude_rad)
    }

    /// Earth-relative velocity of a point fixed to the body at `lever_arm`
    /// \[m\] (body axes, from the IMU) in body axes:
    /// `v_b + ω_eb × l` \[m/s\].
    pub fn point_velocity_body(&self, lever_arm: &Vec3<Body>) -> Vec3<Body> {
        self.velocity_body() + self.earth_relative_rate_body().cross(lever_arm)
    }

    /// Position of a point fixed to the body at `lever_arm` \[m\] (body axes,
    /// from the IMU).
    pub fn point_position(&self, lever_arm: &Vec3<Body>) -> Geodetic {
        self.position.offset_by(&(self.attitude * *lever_arm))
    }

    /// What a perfect IMU aligned with the body reports at this instant.
    pub fn ideal_imu(&self) -> ImuSample {
        ImuSample {
            time_s: self.time_s,
            specific_force: self.specific_force_body.raw(),
            angular_rate: self.angular_rate_body.raw(),
        }
    }
}

/// Times within this of a sample's time are that sample \[s\]: GPST
/// times near 1.7e9 s are spaced 2.4e-7 s apart, so a sensor epoch computed
/// as `start + j / rate` can miss the IMU sample time it means by an ulp
/// or two.
pub const SNAP_S: f64 = 1e-6;

/// The truth at `time_s` (GPST \[s\]) from samples in increasing time:
/// the sample itself within [`SNAP_S`] of its time, else position,
/// velocity, rates, speed and distance interpolated linearly, attitude by
/// spherical linear interpolation. `None` outside the samples' span (or
/// for an empty slice). At 100 Hz the linear position is within
/// `a Δt² / 8` ≈ 40 µm of the path for 3 m/s² of acceleration.
///
/// ```
/// use aidnav_sim::car::{CarScenario, simulate_car};
/// use aidnav_sim::truth::truth_at;
/// let log = simulate_car(&CarScenario::default(), 1).unwrap();
/// let t = log.truth[100].time_s + 0.004;
/// let s = truth_at(&log.truth, t).unwrap();
/// assert!((s.time_s - t).abs() < 1e-6);
/// assert_eq!(truth_at(&log.truth, log.truth[100].time_s + 1e-7), Some(log.truth[100]));
/// assert!(truth_at(&log.truth, log.truth[0].time_s - 1.0).is_none());
/// ```
pub fn truth_at(truth: &[TruthSample], time_s: f64) -> Option<TruthSample> {
    let (first, last) = (truth.first()?, truth.last()?);
    if !(time_s >= first.time_s - SNAP_S && time_s <= last.time_s + SNAP_S) {
        return None;
    }
    let j = truth.partition_point(|s| s.time_s <= time_s);
    let near = |i: usize| truth.get(i).filter(|s| (s.time_s - time_s).abs() <= SNAP_S);
    if let Some(s) = j.checked_sub(1).and_then(near).or_else(|| near(j)) {
        return Some(*s);
    }
    let (a, b) = (&truth[j - 1], &truth[j]);
    let w = (time_s - a.time_s) / (b.time_s - a.time_s);
    let lerp = |x: f64, y: f64| x + (y - x) * w;
    Some(TruthSample {
        time_s,
        position: Geodetic {
            latitude_rad: lerp(a.position.latitude_rad, b.position.latitude_rad),
            longitude_rad: lerp(a.position.longitude_rad, b.position.longitude_rad),
            height_m: lerp(a.position.height_m, b.position.height_m),
        },
        velocity_ned: a.velocity_ned + (b.velocity_ned - a.velocity_ned) * w,
        attitude: Rotation::assume_from_quaternion(
            a.attitude.quaternion().slerp(&b.attitude.quaternion(), w),
        ),
        angular_rate_body: a.angular_rate_body + (b.angular_rate_body - a.angular_rate_body) * w,
        specific_force_body: a.specific_force_body
            + (b.specific_force_body - a.specific_force_body) * w,
        speed_mps: lerp(a.speed_mps, b.speed_mps),
        distance_m: lerp(a.distance_m, b.distance_m),
    })
}
