//! # aidnav-sensors — what the sensors report
//!
//! Plain records of every sample type the filters are fed, in SI units and
//! GPST seconds since 1970-01-01, as the readers of `aidnav-io` produce
//! them and the simulator writes them: no sensor knows the filter, and the
//! readers need not know the mechanization.
//!
//! Records: [`ImuSample`], [`GnssFix`], [`WheelSpeedSample`],
//! [`BaroSample`] and the raw GNSS measurements of an epoch
//! ([`RawGnssEpoch`]: pseudorange, carrier phase, Doppler per satellite and
//! signal). Every record is [`Timed`]; [`merge()`] walks any number of time-sorted
//! streams of them in time order ([`merge`](mod@merge) module).

pub mod merge;
pub mod raw_gnss;

pub use merge::{Merge, Timed, Timeline, merge};
pub use raw_gnss::{Constellation, Measured, RawGnssEpoch, RawObservation, SatelliteId};

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

/// One GNSS solution epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssFix {
    /// GPST, seconds since 1970-01-01.
    pub time_s: f64,
    /// Antenna position (height as written in the file).
    pub position: Geodetic,
    /// Solution quality (RTKLIB Q: 1 fixed, 2 float, 5 single, …).
    pub quality: u8,
    /// Number of satellites.
    pub satellites: u32,
    /// σ of north, east, up position \[m\].
    pub position_sigma_neu: Vector3<f64>,
    /// NED velocity [m/s], when the file has velocity columns.
    pub velocity_ned: Option<Vector3<f64>>,
    /// σ of north, east, up velocity [m/s], when present.
    pub velocity_sigma_neu: Option<Vector3<f64>>,
}

/// One IMU sample in the sensor frame, SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuSample {
    /// GPST, seconds since 1970-01-01.
    pub time_s: f64,
    /// Specific force [m/s²].
    pub specific_force: Vector3<f64>,
    /// Angular rate [rad/s].
    pub angular_rate: Vector3<f64>,
}

/// One wheel-speed (odometer) sample: the speed of the wheel (or of the
/// vehicle's reference point the odometer measures) along the vehicle's
/// forward axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpeedSample {
    /// GPST, seconds since 1970-01-01.
    pub time_s: f64,
    /// Forward speed \[m/s\] (negative when reversing, if the sensor knows).
    pub speed_mps: f64,
    /// σ of the speed \[m/s\] when the log gives one.
    pub sigma_mps: Option<f64>,
}

/// One barometric height sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaroSample {
    /// GPST, seconds since 1970-01-01.
    pub time_s: f64,
    /// Barometric height \[m\] (the sensor's own datum: the filter
    /// estimates its offset from the ellipsoidal height as a bias).
    pub height_m: f64,
    /// σ of the height \[m\] when the log gives one.
    pub sigma_m: Option<f64>,
}
