//! Scoring against a reference trajectory: a simulator's truth, a
//! post-processed solution — anything that gives the IMU's position (and
//! optionally its velocity and attitude) over time, independently of the
//! GNSS file.
//!
//! Where [`super::score`] can only compare with the RTK fixes inside the
//! GNSS file, a reference trajectory scores every epoch: the tracking error
//! with all GNSS, the drift through withheld windows (the same schedule as
//! `[score]`), the velocity and attitude errors, and the filter's own
//! covariance against the actual error (NEES of the 3-D position, fraction
//! inside the 99 % ellipsoid; Bar-Shalom, Li & Kirubarajan §5.4).
//!
//! The filter's IMU position is compared with the reference's (the
//! reference is *at the IMU*); its covariance is the filter's antenna
//! position covariance (equal to the IMU's when the configuration has no
//! lever arm, a few centimetres wider through the attitude σ otherwise).
//!
//! ```
//! use aidnav_app::process::reference::{ReferenceState, ReferenceTrajectory};
//! use aidnav_frames::earth::Geodetic;
//! let at = |t: f64, h: f64| ReferenceState {
//!     time_s: t,
//!     position: Geodetic { latitude_rad: 0.5, longitude_rad: 2.0, height_m: h },
//!     velocity_ned: None,
//!     attitude: None,
//! };
//! let reference = ReferenceTrajectory::new(vec![at(0.0, 10.0), at(1.0, 12.0)]).unwrap();
//! assert_eq!(reference.at(0.25).unwrap().position.height_m, 10.5);
//! assert!(reference.at(1.5).is_none());
//! ```

use aidnav_frames::earth::Geodetic;
use aidnav_frames::{Body, Ned, Rotation};
use nalgebra::Vector3;
use serde::Serialize;

use super::consistency::chi2_3_99;
use super::run::{Epoch, RunPlan, run_filter};
use super::score::periodic_windows;
use super::{Inputs, ProcessConfig, ProcessError};

/// A reference sample: the IMU's state at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceState {
    /// Time on the log's time scale (GPST s since 1970).
    pub time_s: f64,
    /// Position of the IMU (ellipsoidal height).
    pub position: Geodetic,
    /// NED velocity \[m/s\], when the reference has it.
    pub velocity_ned: Option<Vector3<f64>>,
    /// Attitude of the vehicle body (x forward, y right, z down) → NED,
    /// when the reference has it.
    pub attitude: Option<Rotation<Body, Ned>>,
}

/// A reference trajectory: strictly increasing times, interpolated
/// linearly (positions, velocities) and by slerp (attitudes).
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceTrajectory {
    samples: Vec<ReferenceState>,
}

/// Why a reference trajectory cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// Fewer than two samples.
    #[error("a reference trajectory needs at least two samples, got {0}")]
    TooShort(usize),
    /// Times not strictly increasing or not finite.
    #[error("reference sample {index}: time {time_s} s does not follow {previous_s} s")]
    NotIncreasing {
        /// Index of the sample.
        index: usize,
        /// Its time \[s\].
        time_s: f64,
        /// The time before it \[s\].
        previous_s: f64,
    },
}

impl ReferenceTrajectory {
    /// A trajectory from samples in time order.
    pub fn new(samples: Vec<ReferenceState>) -> Result<Self, ReferenceError> {
        if samples.len() < 2 {
            return Err(ReferenceError::TooShort(samples.len()));
        }
        for (i, w) in samples.windows(2).enumerate() {
            if w[1].time_s.partial_cmp(&w[0].time_s) != Some(std::cmp::Ordering::Greater)
                || !w[0].time_s.is_finite()
            {
                return Err(ReferenceError::NotIncreasing {
                    index: i + 1,
                    time_s: w[1].time_s,
                    previous_s: w[0].time_s,
                });
            }
        }
        Ok(Self { samples })
    }

    /// The samples.
    pub fn samples(&self) -> &[ReferenceState] {
        &self.samples
    }

    /// The reference at `time_s`, interpolated (None outside its span).
    /// Velocity and attitude are given only where both neighbours have
    /// them.
    pub fn at(&self, time_s: f64) -> Option<ReferenceState> {
        let s = &self.samples;
        let (first, last) = (s.first()?, s.last()?);
        if !(time_s >= first.time_s && time_s <= last.time_s) {
            return None;
        }
        let j = s
            .partition_point(|x| x.time_s <= time_s)
            .clamp(1, s.len() - 1);
        let (a, b) = (&s[j - 1], &s[j]);
        let w = (time_s - a.time_s) / (b.time_s - a.time_s);
        let lerp = |x: f64, y: f64| x + (y - x) * w;
        Some(ReferenceState {
            time_s,
            position: Geodetic {
                latitude_rad: lerp(a.position.latitude_rad, b.position.latitude_rad),
                longitude_rad: lerp(a.position.longitude_rad, b.position.longitude_rad),
                height_m: lerp(a.position.height_m, b.position.height_m),
            },
            velocity_ned: a
                .velocity_ned
                .zip(b.velocity_ned)
                .map(|(va, vb)| va + (vb - va) * w),
            attitude: a.attitude.zip(b.attitude).map(|(qa, qb)| {
                Rotation::assume_from_quaternion(qa.quaternion().slerp(&qb.quaternion(), w))
            }),
        })
    }
}

/// Drift through the withheld windows of one length, against the reference.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReferenceOutageScore {
    /// L \[s\].
    pub outage_s: f64,
    /// Windows scored (at least one epoch inside the reference).
    pub windows: usize,
    /// RMS over windows of the largest horizontal error \[m\] (None: no
    /// window).
    pub horizontal_m: Option<f64>,
    /// RMS over windows of the largest 3-D error \[m\].
    pub three_d_m: Option<f64>,
    /// Epochs in the windows whose NEES could be formed.
    pub epochs: usize,
    /// Fraction of them inside the filter's 99 % ellipsoid (0.99 when the
    /// covariance is honest).
    pub inside_99_fraction: Option<f64>,
    /// Mean NEES of the 3-D position (3 when honest).
    pub mean_nees: Option<f64>,
}

/// Every score against a reference trajectory.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReferenceScores {
    /// GNSS epochs of the run with all GNSS inside the reference's span.
    pub epochs: usize,
    /// RMS horizontal error with all GNSS \[m\].
    pub tracking_horizontal_m: Option<f64>,
    /// RMS 3-D error with all GNSS \[m\].
    pub tracking_three_d_m: Option<f64>,
    /// RMS 3-D velocity error with all GNSS \[m/s\] (None: the reference
    /// has no velocity).
    pub velocity_m_s: Option<f64>,
    /// RMS roll, pitch and yaw errors with all GNSS \[deg\], after the
    /// first `settle_s` (None: the reference has no attitude).
    pub attitude_deg: Option<[f64; 3]>,
    /// The time left out of the attitude RMS at the start (alignment) \[s\].
    pub settle_s: f64,
    /// Per outage length.
    pub outages: Vec<ReferenceOutageScore>,
}

/// Time after the first GNSS epoch left out of the attitude RMS: the
/// alignment and the first convergence of the heading \[s\].
pub const ATTITUDE_SETTLE_S: f64 = 60.0;

/// The roll, pitch and yaw of `estimate` minus those of `reference`,
/// wrapped into (−180°, 180°] \[deg\].
pub fn euler_error_deg(
    estimate: &Rotation<Body, Ned>,
    reference: &Rotation<Body, Ned>,
) -> [f64; 3] {
    let (r1, p1, y1) = estimate.euler_angles();
    let (r0, p0, y0) = reference.euler_angles();
    let wrap = |d: f64| {
        let d = d.to_degrees() % 360.0;
        if d > 180.0 {
            d - 360.0
        } else if d <= -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    [wrap(r1 - r0), wrap(p1 - p0), wrap(y1 - y0)]
}

/// `eᵀ P⁻¹ e` by Cholesky (None: P not positive definite).
fn nees(error: &Vector3<f64>, covariance: &nalgebra::Matrix3<f64>) -> Option<f64> {
    let chol = nalgebra::Cholesky::new(*covariance)?;
    Some(error.dot(&chol.solve(error)))
}

/// Score the configured filter on `inputs` against `reference`: one run
/// with all GNSS, and one per `cfg.score.outages_s` length with its windows
/// withheld (the schedule of `[score]`: the first `lead_s` after the first
/// IMU sample, then one every length + `gap_s`). The runs go in parallel.
pub fn score_against_reference(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    reference: &ReferenceTrajectory,
) -> Result<ReferenceScores, ProcessError> {
    use rayon::prelude::*;
    let policy = cfg.gnss.policy;
    let first_imu = inputs.imu.first().map_or(f64::NAN, |s| s.time_s);
    let last_gnss = inputs.gnss.last().map_or(f64::NAN, |g| g.time_s);
    let lengths = cfg.score.outages_s.clone();
    let plans: Vec<RunPlan> = std::iter::once(Vec::new())
        .chain(lengths.iter().map(|&l| {
            periodic_windows(first_imu + cfg.score.lead_s, l, cfg.score.gap_s, last_gnss)
        }))
        .map(|windows| RunPlan {
            windows,
            ..RunPlan::default()
        })
        .collect();
    let runs: Vec<Vec<Epoch>> = plans
        .par_iter()
        .map(|plan| run_filter(cfg, inputs, plan, policy).map(|r| r.epochs))
        .collect::<Result<_, _>>()?;
    let full = &runs[0];
    let t0 = full.first().map_or(f64::NAN, |e| e.fix.time_s);
    let (mut n, mut h2, mut d2) = (0usize, 0.0, 0.0);
    let (mut nv, mut v2) = (0usize, 0.0);
    let (mut na, mut a2) = (0usize, [0.0f64; 3]);
    for e in full {
        let Some(r) = reference.at(e.fix.time_s) else {
            continue;
        };
        let d = r.position.ned_to(&e.imu_position).raw();
        n += 1;
        h2 += d.xy().norm_squared();
        d2 += d.norm_squared();
        if let Some(v) = r.velocity_ned {
            nv += 1;
            v2 += (e.velocity.raw() - v).norm_squared();
        }
        if let Some(att) = r
            .attitude
            .filter(|_| e.fix.time_s >= t0 + ATTITUDE_SETTLE_S)
        {
            na += 1;
            let err = euler_error_deg(&e.attitude, &att);
            for i in 0..3 {
                a2[i] += err[i] * err[i];
            }
        }
    }
    let rms = |sum: f64, n: usize| (n > 0).then(|| (sum / n as f64).sqrt());
    let outages = lengths
        .iter()
        .zip(&plans[1..])
        .zip(&runs[1..])
        .map(|((&length, plan), epochs)| outage_score(length, &plan.windows, epochs, reference))
        .collect();
    Ok(ReferenceScores {
        epochs: n,
        tracking_horizontal_m: rms(h2, n),
        tracking_three_d_m: rms(d2, n),
        velocity_m_s: rms(v2, nv),
        attitude_deg: (na > 0).then(|| a2.map(|s| (s / na as f64).sqrt())),
        settle_s: ATTITUDE_SETTLE_S,
        outages,
    })
}

/// The drift and the consistency of one length's windows.
fn outage_score(
    length_s: f64,
    windows: &[(f64, f64)],
    epochs: &[Epoch],
    reference: &ReferenceTrajectory,
) -> ReferenceOutageScore {
    let bound = chi2_3_99();
    let mut maxima: Vec<[f64; 2]> = Vec::new();
    let (mut n, mut inside, mut sum) = (0usize, 0usize, 0.0);
    for &(a, b) in windows {
        let mut m: Option<[f64; 2]> = None;
        for e in epochs.iter().filter(|e| (a..b).contains(&e.fix.time_s)) {
            let Some(r) = reference.at(e.fix.time_s) else {
                continue;
            };
            let d = r.position.ned_to(&e.imu_position).raw();
            let mm = m.get_or_insert([0.0; 2]);
            mm[0] = mm[0].max(d.xy().norm());
            mm[1] = mm[1].max(d.norm());
            if let Some(q) = nees(&d, &e.position_covariance) {
                n += 1;
                sum += q;
                inside += usize::from(q <= bound);
            }
        }
        maxima.extend(m);
    }
    let rms = |i: usize| {
        (!maxima.is_empty())
            .then(|| (maxima.iter().map(|m| m[i] * m[i]).sum::<f64>() / maxima.len() as f64).sqrt())
    };
    ReferenceOutageScore {
        outage_s: length_s,
        windows: maxima.len(),
        horizontal_m: rms(0),
        three_d_m: rms(1),
        epochs: n,
        inside_99_fraction: (n > 0).then(|| inside as f64 / n as f64),
        mean_nees: (n > 0).then(|| sum / n as f64),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn state(t: f64, lat: f64, yaw_deg: f64) -> ReferenceState {
        ReferenceState {
            time_s: t,
            position: Geodetic {
                latitude_rad: lat,
                longitude_rad: 0.1,
                height_m: 5.0,
            },
            velocity_ned: Some(Vector3::new(t, 0.0, 0.0)),
            attitude: Some(Rotation::from_euler_angles(0.0, 0.0, yaw_deg.to_radians())),
        }
    }

    #[test]
    fn interpolation_is_linear_and_slerps_the_attitude() {
        let r =
            ReferenceTrajectory::new(vec![state(0.0, 0.0, 10.0), state(2.0, 0.2, 30.0)]).unwrap();
        let s = r.at(0.5).unwrap();
        assert!((s.position.latitude_rad - 0.05).abs() < 1e-15);
        assert!((s.velocity_ned.unwrap().x - 0.5).abs() < 1e-15);
        let (_, _, yaw) = s.attitude.unwrap().euler_angles();
        assert!(
            (yaw.to_degrees() - 15.0).abs() < 1e-9,
            "{}",
            yaw.to_degrees()
        );
        assert_eq!(r.at(2.0).unwrap().position.latitude_rad, 0.2);
        assert!(r.at(-0.1).is_none() && r.at(2.1).is_none());
    }

    #[test]
    fn bad_references_are_refused() {
        assert_eq!(
            ReferenceTrajectory::new(vec![state(0.0, 0.0, 0.0)]),
            Err(ReferenceError::TooShort(1))
        );
        let e =
            ReferenceTrajectory::new(vec![state(1.0, 0.0, 0.0), state(1.0, 0.0, 0.0)]).unwrap_err();
        assert!(e.to_string().contains("sample 1"), "{e}");
    }

    #[test]
    fn euler_errors_wrap_around_north() {
        let a = Rotation::from_euler_angles(0.0, 0.0, 179.0f64.to_radians());
        let b = Rotation::from_euler_angles(0.0, 0.0, (-179.0f64).to_radians());
        let e = euler_error_deg(&a, &b);
        assert!((e[2] + 2.0).abs() < 1e-9, "{e:?}");
    }

    #[test]
    fn nees_matches_the_closed_form_of_a_diagonal_covariance() {
        let p = nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 9.0));
        let q = nees(&Vector3::new(1.0, 2.0, 3.0), &p).unwrap();
        assert!((q - 3.0).abs() < 1e-12);
        assert!(nees(&Vector3::x(), &nalgebra::Matrix3::zeros()).is_none());
    }
}
