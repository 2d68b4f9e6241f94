//! Standstill detection from the IMU: a window of samples whose every axis
//! varies less than a threshold. A vehicle at rest still vibrates (an engine,
//! a hand), so the thresholds are per platform; speed evidence (GNSS, the
//! filter) is the caller's to add — a smooth, straight, constant-speed
//! motion is indistinguishable from rest for an IMU.

use nalgebra::Vector3;

use crate::samples::ImuSample;

/// √χ²₂(0.999): the horizontal speed a receiver at rest reports stays below
/// this many σ (per horizontal axis) in 999 of 1000 fixes.
pub const STILL_HORIZONTAL_SIGMAS: f64 = 3.716_922;
/// √χ²₁(0.999): the same for the vertical speed.
pub const STILL_VERTICAL_SIGMAS: f64 = 3.290_527;

/// Whether a GNSS velocity says "at rest": its horizontal speed at most
/// `max_speed_mps` or, when larger, [`STILL_HORIZONTAL_SIGMAS`] × the
/// velocity's horizontal σ (the RMS of north and east), and its vertical
/// speed at most `max_speed_mps` or [`STILL_VERTICAL_SIGMAS`] × its up σ.
/// Without a σ the bound is `max_speed_mps`. A fixed threshold alone misses
/// a standstill when the velocity's noise approaches it (at σ 0.1 m/s a
/// receiver at rest reports more than 0.2 m/s in one fix of seven).
///
/// ```
/// use aidnav_ins::standstill::gnss_says_still;
/// use nalgebra::Vector3;
/// let v = Vector3::new(0.25, 0.1, 0.05);
/// assert!(!gnss_says_still(&v, None, 0.2));
/// assert!(gnss_says_still(&v, Some(&Vector3::new(0.1, 0.1, 0.2)), 0.2));
/// assert!(!gnss_says_still(&Vector3::new(1.0, 0.0, 0.0), Some(&Vector3::repeat(0.1)), 0.2));
/// ```
pub fn gnss_says_still(
    velocity_ned: &Vector3<f64>,
    sigma_neu: Option<&Vector3<f64>>,
    max_speed_mps: f64,
) -> bool {
    let (horizontal, vertical) = match sigma_neu {
        Some(s) => (
            (STILL_HORIZONTAL_SIGMAS * (0.5 * (s.x * s.x + s.y * s.y)).sqrt()).max(max_speed_mps),
            (STILL_VERTICAL_SIGMAS * s.z).max(max_speed_mps),
        ),
        None => (max_speed_mps, max_speed_mps),
    };
    velocity_ned.xy().norm() <= horizontal && velocity_ned.z.abs() <= vertical
}

/// Largest per-axis standard deviations of a standstill window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandstillThresholds {
    /// Specific force [m/s²].
    pub accel_std_mps2: f64,
    /// Angular rate [rad/s].
    pub gyro_std_rad_s: f64,
}

/// Mean and per-axis standard deviation of a window of samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowStats {
    /// Samples in the window.
    pub samples: usize,
    /// Mean specific force [m/s²].
    pub mean_force: Vector3<f64>,
    /// Mean angular rate [rad/s].
    pub mean_rate: Vector3<f64>,
    /// Per-axis standard deviation of the specific force [m/s²].
    pub force_std: Vector3<f64>,
    /// Per-axis standard deviation of the angular rate [rad/s].
    pub rate_std: Vector3<f64>,
}

impl WindowStats {
    /// Two-pass mean and standard deviation (no allocation); None for fewer
    /// than two samples.
    ///
    /// ```
    /// use aidnav_ins::samples::ImuSample;
    /// use aidnav_ins::standstill::{StandstillThresholds, WindowStats};
    /// use nalgebra::Vector3;
    /// let rest: Vec<ImuSample> = (0..50)
    ///     .map(|k| ImuSample {
    ///         time_s: k as f64 * 0.01,
    ///         specific_force: Vector3::new(0.0, 0.0, -9.8 + if k % 2 == 0 { 0.01 } else { -0.01 }),
    ///         angular_rate: Vector3::zeros(),
    ///     })
    ///     .collect();
    /// let s = WindowStats::of(&rest).unwrap();
    /// assert!((s.force_std.z - 0.01).abs() < 1e-3);
    /// let th = StandstillThresholds { accel_std_mps2: 0.1, gyro_std_rad_s: 0.01 };
    /// assert!(s.is_still(&th));
    /// ```
    pub fn of(window: &[ImuSample]) -> Option<Self> {
        if window.len() < 2 {
            return None;
        }
        let n = window.len() as f64;
        let mean_force = window
            .iter()
            .map(|s| s.specific_force)
            .sum::<Vector3<f64>>()
            / n;
        let mean_rate = window.iter().map(|s| s.angular_rate).sum::<Vector3<f64>>() / n;
        let (mut vf, mut vw) = (Vector3::zeros(), Vector3::zeros());
        for s in window {
            let df = s.specific_force - mean_force;
            let dw = s.angular_rate - mean_rate;
            vf += df.component_mul(&df);
            vw += dw.component_mul(&dw);
        }
        Some(Self {
            samples: window.len(),
            mean_force,
            mean_rate,
            force_std: (vf / (n - 1.0)).map(f64::sqrt),
            rate_std: (vw / (n - 1.0)).map(f64::sqrt),
        })
    }

    /// Every axis below its threshold.
    pub fn is_still(&self, th: &StandstillThresholds) -> bool {
        self.force_std.max() <= th.accel_std_mps2 && self.rate_std.max() <= th.gyro_std_rad_s
    }
}

/// The samples of `imu` in `(imu[end].time_s − window_s, imu[end].time_s]`,
/// found by walking back from `end` (cost: the window's length).
pub fn window_ending_at(imu: &[ImuSample], end: usize, window_s: f64) -> &[ImuSample] {
    let Some(last) = imu.get(end) else {
        return &[];
    };
    let mut first = end;
    while first > 0 && imu[first - 1].time_s > last.time_s - window_s {
        first -= 1;
    }
    &imu[first..=end]
}

/// The stretches of `imu` that stand still: runs of consecutive,
/// non-overlapping windows of `window_s` whose statistics are still
/// ([`WindowStats::is_still`]) and for which `slow(t_first, t_last)` — the
/// caller's speed evidence over the window's sample times — holds. Each
/// stretch is a range of sample indices; longest first (ties: earliest
/// first). Cost: one pass over the samples.
///
/// ```
/// use aidnav_ins::samples::ImuSample;
/// use aidnav_ins::standstill::{StandstillThresholds, still_stretches};
/// use nalgebra::Vector3;
/// // 10 s at 100 Hz, a shake between 4 and 5 s.
/// let imu: Vec<ImuSample> = (0..1000)
///     .map(|k| {
///         let t = k as f64 * 0.01;
///         let shake = if (4.0..5.0).contains(&t) && k % 2 == 0 { 1.0 } else { 0.0 };
///         ImuSample { time_s: t, specific_force: Vector3::new(shake, 0.0, -9.8), angular_rate: Vector3::zeros() }
///     })
///     .collect();
/// let th = StandstillThresholds { accel_std_mps2: 0.1, gyro_std_rad_s: 0.01 };
/// let s = still_stretches(&imu, 0.5, &th, |_, _| true);
/// assert_eq!(s[0], 500..1000); // 5 … 10 s
/// assert_eq!(s[1], 0..400);    // 0 … 4 s
/// ```
pub fn still_stretches(
    imu: &[ImuSample],
    window_s: f64,
    thresholds: &StandstillThresholds,
    mut slow: impl FnMut(f64, f64) -> bool,
) -> Vec<std::ops::Range<usize>> {
    let mut stretches = Vec::new();
    if !(window_s.is_finite() && window_s > 0.0) {
        return stretches;
    }
    let mut current: Option<std::ops::Range<usize>> = None;
    let mut i = 0;
    while i < imu.len() {
        let t0 = imu[i].time_s;
        let mut j = i + 1;
        while j < imu.len() && imu[j].time_s < t0 + window_s {
            j += 1;
        }
        let window = &imu[i..j];
        let still = WindowStats::of(window).is_some_and(|s| s.is_still(thresholds))
            && slow(t0, window[window.len() - 1].time_s);
        current = match (still, current.take()) {
            (true, Some(r)) => Some(r.start..j),
            (true, None) => Some(i..j),
            (false, Some(r)) => {
                stretches.push(r);
                None
            }
            (false, None) => None,
        };
        i = j;
    }
    stretches.extend(current);
    stretches.sort_by(|a, b| b.len().cmp(&a.len()).then(a.start.cmp(&b.start)));
    stretches
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(force_noise: f64, rate_noise: f64, rate: f64) -> Vec<ImuSample> {
        (0..100)
            .map(|k| {
                let s = if k % 2 == 0 { 1.0 } else { -1.0 };
                ImuSample {
                    time_s: k as f64 * 0.01,
                    specific_force: Vector3::new(0.0, 0.0, -9.8) + Vector3::repeat(s * force_noise),
                    angular_rate: Vector3::new(0.0, 0.0, rate) + Vector3::repeat(s * rate_noise),
                }
            })
            .collect()
    }

    const TH: StandstillThresholds = StandstillThresholds {
        accel_std_mps2: 0.2,
        gyro_std_rad_s: 0.02,
    };

    #[test]
    fn vibration_below_the_thresholds_is_still_above_is_not() {
        assert!(
            WindowStats::of(&samples(0.05, 0.005, 0.0))
                .unwrap()
                .is_still(&TH)
        );
        assert!(
            !WindowStats::of(&samples(0.5, 0.005, 0.0))
                .unwrap()
                .is_still(&TH)
        );
        assert!(
            !WindowStats::of(&samples(0.05, 0.05, 0.0))
                .unwrap()
                .is_still(&TH)
        );
        // A steady turn has no variance but a mean rate: the std test alone
        // cannot see it (the caller adds the speed), the mean says it.
        let turn = WindowStats::of(&samples(0.05, 0.005, 0.3)).unwrap();
        assert!((turn.mean_rate.z - 0.3).abs() < 1e-3);
        // std of ±a alternating over an even count: a √(n/(n−1)).
        let s = WindowStats::of(&samples(0.05, 0.0, 0.0)).unwrap();
        assert!((s.force_std.x - 0.05 * (100.0f64 / 99.0).sqrt()).abs() < 1e-12);
        assert!(WindowStats::of(&samples(0.0, 0.0, 0.0)[..1]).is_none());
    }

    #[test]
    fn the_window_ends_at_the_sample_and_spans_the_time() {
        let imu = samples(0.0, 0.0, 0.0);
        let w = window_ending_at(&imu, 50, 0.1);
        assert_eq!(w.len(), 10);
        assert_eq!(w[9].time_s, imu[50].time_s);
        assert_eq!(window_ending_at(&imu, 3, 1.0).len(), 4);
        assert!(window_ending_at(&imu, 500, 1.0).is_empty());
    }
}
