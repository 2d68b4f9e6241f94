//! The raw data a mechanization is fed: IMU samples and GNSS fixes, as the
//! readers of `aidnav-io` produce them (plain data, SI units, GPST seconds
//! since 1970-01-01), and the zero-phase moving average applied to the IMU
//! before filtering.

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

/// Zero-phase centred moving average over 2·half + 1 samples (shrinking at
/// the ends), by prefix sums (O(n)); offline smoothing of a whole log.
///
/// ```
/// use aidnav_ins::samples::{ImuSample, moving_average};
/// use nalgebra::Vector3;
/// let imu: Vec<ImuSample> = (0..5)
///     .map(|k| ImuSample {
///         time_s: k as f64,
///         specific_force: Vector3::new(k as f64, 0.0, -9.8),
///         angular_rate: Vector3::zeros(),
///     })
///     .collect();
/// let smooth = moving_average(&imu, 1);
/// assert_eq!(smooth[2].specific_force.x, 2.0); // (1 + 2 + 3) / 3
/// assert_eq!(smooth[0].specific_force.x, 0.5); // (0 + 1) / 2 at the end
/// ```
pub fn moving_average(imu: &[ImuSample], half: usize) -> Vec<ImuSample> {
    let mut out = imu.to_vec();
    moving_average_in_place(&mut out, half);
    out
}

/// [`moving_average`] in place: the same values, bit for bit, without a
/// second copy of the samples (the prefix sums are taken before any sample
/// is overwritten).
pub fn moving_average_in_place(imu: &mut [ImuSample], half: usize) {
    let n = imu.len();
    let mut sum_f = Vector3::zeros();
    let mut sum_w = Vector3::zeros();
    // Prefix sums keep it O(n).
    let mut pf = Vec::with_capacity(n + 1);
    let mut pw = Vec::with_capacity(n + 1);
    pf.push(sum_f);
    pw.push(sum_w);
    for s in imu.iter() {
        sum_f += s.specific_force;
        sum_w += s.angular_rate;
        pf.push(sum_f);
        pw.push(sum_w);
    }
    for (k, o) in imu.iter_mut().enumerate() {
        let lo = k.saturating_sub(half);
        let hi = (k + half + 1).min(n);
        let m = (hi - lo) as f64;
        o.specific_force = (pf[hi] - pf[lo]) / m;
        o.angular_rate = (pw[hi] - pw[lo]) / m;
    }
}
