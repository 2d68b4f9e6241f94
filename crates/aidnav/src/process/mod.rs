//! Spec 40: process a recorded IMU + GNSS log end to end with the NED
//! filter ([`aidnav_integration::ned`]) and score it with simulated GNSS
//! outages and injected anomalies.
//!
//! Pipeline: read (GNSS: RTKLIB `.pos`, KF-GINS text, NMEA; IMU: raw CSV +
//! `.tag`, KF-GINS increments, generic CSV), shift the IMU time
//! by `imu.time_offset_s`, rotate sensor → body (`imu.mounting_deg`, Groves'
//! Euler_to_CTM convention as the data set's upstream uses), smooth with a
//! zero-phase centred moving average (`imu.smoothing_s`, offline), initialise
//! (levelling and gyro bias over the first `initial.static_s` seconds at
//! rest, heading from the first GNSS course above `initial.heading_speed_mps`
//! — the car is assumed to drive straight off), then filter: IMU increments
//! by the trapezoid rule, split at every GNSS epoch so each update is made
//! at the fix's own time.
//!
//! Layout: [`config`] (the configuration file and its validation), this
//! module (reading and initialisation), [`run`] (one filter pass under a
//! plan: withheld windows, outliers, bridging, smoothing), [`score`] (the
//! outage, efficiency and anomaly scores of a run).

pub mod config;
pub mod run;
pub mod score;

pub use config::*;
pub use run::*;
pub use score::*;

use std::path::Path;

use aidnav_estimation::EstimationError;
use aidnav_frames::{Rotation, Vec3, earth::earth_rate_ned};
use aidnav_ins::ned::NedState;
use aidnav_io::rtklib::{GnssFix, ImuSample, read_pos, read_tagged_imu};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};

/// Anything processing can fail with.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// Reading the inputs.
    #[error(transparent)]
    Io(#[from] aidnav_io::IoError),
    /// The filter.
    #[error("filter: {0}")]
    Estimation(#[from] EstimationError),
    /// The data do not allow processing.
    #[error("{0}")]
    Data(String),
}

/// IMU samples (body frame) and GNSS fixes ready for the filter.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// Body-frame IMU samples, SI.
    pub imu: Vec<ImuSample>,
    /// GNSS fixes.
    pub gnss: Vec<GnssFix>,
    /// Reader warnings.
    pub warnings: Vec<String>,
}

/// Groves' Euler_to_CTM: the coordinate transformation for (roll, pitch, yaw).
pub fn euler_to_ctm(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sr, cr) = roll.sin_cos();
    let (sp, cp) = pitch.sin_cos();
    let (sy, cy) = yaw.sin_cos();
    Matrix3::new(
        cp * cy,
        cp * sy,
        -sp,
        -cr * sy + sr * sp * cy,
        cr * cy + sr * sp * sy,
        sr * cp,
        sr * sy + cr * sp * cy,
        -sr * cy + cr * sp * sy,
        cr * cp,
    )
}

/// Read, time-shift, rotate to the body frame and smooth.
pub fn load_inputs(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    let dir = if cfg.data.dir.is_absolute() {
        cfg.data.dir.clone()
    } else {
        base.join(&cfg.data.dir)
    };
    let imu_path = dir.join(&cfg.data.imu);
    let (mut imu, mut warnings) = match cfg.data.imu_format {
        ImuFormat::RtklibTagged => {
            let tags = cfg.data.imu_tags.as_ref().ok_or_else(|| {
                ProcessError::Data("data.imu_tags is needed for imu_format = rtklib_tagged".into())
            })?;
            read_tagged_imu(&imu_path, &dir.join(tags))?
        }
        ImuFormat::KfGins => aidnav_io::kfgins::read_kfgins_imu(&imu_path)?,
        ImuFormat::GenericCsv => aidnav_io::kfgins::read_generic_imu(&imu_path)?,
    };
    let gnss_path = dir.join(&cfg.data.gnss);
    let (gnss, w) = match cfg.data.gnss_format {
        GnssFormat::RtklibPos => read_pos(&gnss_path)?,
        GnssFormat::KfGins => aidnav_io::kfgins::read_kfgins_gnss(&gnss_path)?,
        GnssFormat::Nmea => aidnav_io::nmea::read_nmea(&gnss_path)?,
    };
    warnings.extend(w);
    let [r, p, y] = cfg.imu.mounting_deg.map(f64::to_radians);
    let c = euler_to_ctm(r, p, y);
    for s in &mut imu {
        s.time_s += cfg.imu.time_offset_s;
        s.specific_force = c * s.specific_force;
        s.angular_rate = c * s.angular_rate;
    }
    if cfg.imu.smoothing_s > 0.0 && imu.len() > 2 {
        let dt = (imu[imu.len() - 1].time_s - imu[0].time_s) / (imu.len() - 1) as f64;
        let half = ((cfg.imu.smoothing_s / dt) / 2.0).round() as usize;
        if half > 0 {
            imu = smooth(&imu, half);
        }
    }
    Ok(Inputs {
        imu,
        gnss,
        warnings,
    })
}

/// Centred moving average over 2·half + 1 samples (shrinking at the ends).
fn smooth(imu: &[ImuSample], half: usize) -> Vec<ImuSample> {
    let n = imu.len();
    let mut out = imu.to_vec();
    let mut sum_f = Vector3::zeros();
    let mut sum_w = Vector3::zeros();
    // Prefix sums keep it O(n).
    let mut pf = Vec::with_capacity(n + 1);
    let mut pw = Vec::with_capacity(n + 1);
    pf.push(sum_f);
    pw.push(sum_w);
    for s in imu {
        sum_f += s.specific_force;
        sum_w += s.angular_rate;
        pf.push(sum_f);
        pw.push(sum_w);
    }
    for (k, o) in out.iter_mut().enumerate() {
        let lo = k.saturating_sub(half);
        let hi = (k + half + 1).min(n);
        let m = (hi - lo) as f64;
        o.specific_force = (pf[hi] - pf[lo]) / m;
        o.angular_rate = (pw[hi] - pw[lo]) / m;
    }
    out
}

/// The initial state and the starting gyro bias.
pub(crate) fn initialise(
    cfg: &ProcessConfig,
    inputs: &Inputs,
) -> Result<(NedState, Vector3<f64>, usize), ProcessError> {
    let imu = &inputs.imu;
    let first_fix = &inputs.gnss[0];
    let start = imu
        .iter()
        .position(|s| s.time_s >= first_fix.time_s)
        .ok_or_else(|| ProcessError::Data("no IMU sample after the first GNSS epoch".into()))?;
    let t0 = imu[start].time_s;
    let (attitude, w) = match cfg.initial.attitude_deg {
        Some([r, p, y]) => (
            UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), y.to_radians()),
            None,
        ),
        None => {
            let (attitude, w) = align(cfg, inputs, start, t0)?;
            (attitude, Some(w))
        }
    };
    // Antenna fix → IMU position.
    let fix = inputs
        .gnss
        .iter()
        .rev()
        .find(|g| g.time_s <= t0)
        .unwrap_or(first_fix);
    let arm = attitude * Vector3::from(cfg.gnss.lever_arm_m);
    let position = fix.position.offset_by(&Vec3::assume_in_frame(-arm));
    let gyro_bias = w.map_or_else(Vector3::zeros, |w| {
        w - attitude.inverse() * earth_rate_ned(position.latitude_rad).raw()
    });
    Ok((
        NedState {
            position,
            velocity: Vec3::assume_in_frame(
                cfg.initial
                    .velocity_ned_mps
                    .map_or_else(Vector3::zeros, Vector3::from),
            ),
            attitude: Rotation::assume_from_quaternion(attitude),
        },
        gyro_bias,
        start,
    ))
}

/// Coarse alignment: roll and pitch by levelling over the static window at
/// the start, heading from the first GNSS course above the speed threshold;
/// also the mean gyro output at rest (bias + Earth rate).
fn align(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    start: usize,
    t0: f64,
) -> Result<(UnitQuaternion<f64>, Vector3<f64>), ProcessError> {
    let window: Vec<&ImuSample> = inputs.imu[start..]
        .iter()
        .take_while(|s| s.time_s < t0 + cfg.initial.static_s)
        .collect();
    if window.len() < 10 {
        return Err(ProcessError::Data(
            "static window holds fewer than 10 IMU samples".into(),
        ));
    }
    let n = window.len() as f64;
    let f = window
        .iter()
        .map(|s| s.specific_force)
        .sum::<Vector3<f64>>()
        / n;
    let w = window.iter().map(|s| s.angular_rate).sum::<Vector3<f64>>() / n;
    let roll = (-f.y).atan2(-f.z);
    let pitch = f.x.atan2(f.y.hypot(f.z));
    let moving = inputs
        .gnss
        .iter()
        .find(|g| {
            g.velocity_ned
                .is_some_and(|v| v.xy().norm() > cfg.initial.heading_speed_mps)
        })
        .ok_or_else(|| {
            ProcessError::Data(
                "the GNSS speed never exceeds initial.heading_speed_mps: no heading (give initial.attitude_deg)".into(),
            )
        })?;
    let v = moving.velocity_ned.expect("checked");
    let yaw = v.y.atan2(v.x);
    Ok((UnitQuaternion::from_euler_angles(roll, pitch, yaw), w))
}
