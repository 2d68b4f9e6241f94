//! Where and how the filter starts: at the first GNSS epoch that allows an
//! alignment — a standstill (levelling and the gyro bias at rest, the
//! heading from the course once the vehicle moves off) or a motion fast
//! enough for the course (heading from the course, pitch from the climb
//! angle, velocity from GNSS, larger attitude σ) — or with a given attitude.

use aidnav_frames::{Rotation, Vec3};
use aidnav_ins::alignment::{course, gyro_bias_at_rest, level, static_window};
use aidnav_ins::ned::NedState;
use aidnav_ins::standstill::{StandstillThresholds, WindowStats};
use aidnav_io::rtklib::GnssFix;
use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

use super::{Inputs, ProcessConfig, ProcessError};

/// How the filter was started.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StartKind {
    /// `initial.attitude_deg` was given.
    Given,
    /// Levelled at a standstill; heading from the course as it moved off.
    Static,
    /// Aligned in motion from the GNSS velocity.
    Moving,
}

/// The filter's initial state and its prior σ.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// The IMU's state.
    pub state: NedState,
    /// The gyro bias found at rest (zero otherwise) [rad/s].
    pub gyro_bias: Vector3<f64>,
    /// The IMU sample the filter starts at.
    pub index: usize,
    /// How it was aligned.
    pub kind: StartKind,
    /// GNSS speed at the start [m/s] (NaN without a velocity).
    pub speed_mps: f64,
    /// Prior σ of roll and pitch \[rad\].
    pub tilt_sigma_rad: f64,
    /// Prior σ of the heading \[rad\].
    pub heading_sigma_rad: f64,
    /// Prior σ of each position coordinate \[m\].
    pub position_sigma_m: f64,
    /// Prior σ of each velocity coordinate [m/s].
    pub velocity_sigma_mps: f64,
    /// What a user should know (a late start).
    pub warnings: Vec<String>,
}

/// Find the start: the first GNSS epoch inside the IMU span at which the
/// vehicle stands still for `initial.static_s` (IMU thresholds of the
/// platform, GNSS speed below `standstill.max_speed_mps`) or moves faster
/// than the heading speed; with `initial.attitude_deg`, the first epoch.
pub fn initialise(cfg: &ProcessConfig, inputs: &Inputs) -> Result<Start, ProcessError> {
    let (imu, gnss) = (&inputs.imu, &inputs.gnss);
    let (Some(first_imu), Some(last_imu)) = (imu.first(), imu.last()) else {
        return Err(ProcessError::Data("no IMU sample".into()));
    };
    let first = gnss
        .iter()
        .position(|g| g.time_s >= first_imu.time_s)
        .ok_or_else(|| ProcessError::Data("no GNSS epoch after the first IMU sample".into()))?;
    let start_at = |k: usize| imu.iter().position(|s| s.time_s >= gnss[k].time_s);
    let any_update_after = |t0: f64| {
        gnss.iter()
            .any(|g| g.time_s > t0 && g.time_s <= last_imu.time_s)
    };
    let Some(i0) = start_at(first) else {
        return Err(ProcessError::Data(
            "no IMU sample after the first GNSS epoch".into(),
        ));
    };
    if !any_update_after(imu[i0].time_s) {
        return Err(ProcessError::Data(format!(
            "no GNSS epoch between the filter start {} and the last IMU sample {}: the run would make no update",
            aidnav_io::text::date_time(imu[i0].time_s),
            aidnav_io::text::date_time(last_imu.time_s)
        )));
    }
    if let Some([r, p, y]) = cfg.initial.attitude_deg {
        let attitude =
            UnitQuaternion::from_euler_angles(r.to_radians(), p.to_radians(), y.to_radians());
        let velocity = cfg
            .initial
            .velocity_ned_mps
            .map(Vector3::from)
            .or(gnss[first].velocity_ned)
            .unwrap_or_else(Vector3::zeros);
        return Ok(build(
            cfg,
            &gnss[first],
            i0,
            attitude,
            velocity,
            Vector3::zeros(),
            StartKind::Given,
        ));
    }
    let heading_speed = cfg.heading_speed_mps();
    let (accel, gyro) = cfg.standstill_thresholds();
    let thresholds = StandstillThresholds {
        accel_std_mps2: accel,
        gyro_std_rad_s: gyro,
    };
    for k in first..gnss.len() {
        let g = &gnss[k];
        let Some(i) = start_at(k) else { break };
        let t0 = imu[i].time_s;
        if !any_update_after(t0) {
            break;
        }
        let window = static_window(imu, i, t0, cfg.initial.static_s);
        let still = window.len() >= 10
            && WindowStats::of(window).is_some_and(|s| s.is_still(&thresholds))
            && gnss_slow(
                gnss,
                k,
                t0 + cfg.initial.static_s,
                cfg.standstill.max_speed_mps,
            );
        if still {
            let levelling = level(window);
            let moving = gnss[k..]
                .iter()
                .find_map(|f| f.velocity_ned.filter(|v| v.xy().norm() > heading_speed))
                .ok_or_else(|| {
                    ProcessError::Data(format!(
                        "the GNSS speed never exceeds initial.heading_speed_mps = {heading_speed} m/s after the standstill at {}: no heading (lower it, set platform, or give initial.attitude_deg)",
                        aidnav_io::text::date_time(t0)
                    ))
                })?;
            let attitude = levelling.attitude(course(&moving));
            let bias = gyro_bias_at_rest(
                &levelling.mean_angular_rate,
                &attitude,
                g.position.latitude_rad,
            );
            let mut s = build(
                cfg,
                g,
                i,
                attitude,
                Vector3::zeros(),
                bias,
                StartKind::Static,
            );
            late_start_warning(&mut s, gnss[first].time_s, t0);
            return Ok(s);
        }
        if let Some(v) = velocity_of(gnss, k)
            && v.xy().norm() >= heading_speed
        {
            // Roll unknown (zero, a large σ), pitch from the climb angle.
            let pitch = (-v.z).atan2(v.xy().norm());
            let attitude = UnitQuaternion::from_euler_angles(0.0, pitch, course(&v));
            let mut s = build(cfg, g, i, attitude, v, Vector3::zeros(), StartKind::Moving);
            late_start_warning(&mut s, gnss[first].time_s, t0);
            return Ok(s);
        }
    }
    Err(ProcessError::Data(format!(
        "no start found: the log never stands still for initial.static_s = {} s (each accelerometer axis' std ≤ {accel} m/s², gyro ≤ {:.3} deg/s, GNSS speed ≤ {} m/s) nor moves faster than initial.heading_speed_mps = {heading_speed} m/s; set platform, the [standstill] thresholds, or give initial.attitude_deg",
        cfg.initial.static_s,
        gyro.to_degrees(),
        cfg.standstill.max_speed_mps
    )))
}

/// The GNSS speed over the fixes from `k` up to `until` is below `max`:
/// their velocities, or (without velocity columns) their displacement.
fn gnss_slow(gnss: &[GnssFix], k: usize, until: f64, max: f64) -> bool {
    let window = gnss[k..].iter().take_while(|g| g.time_s <= until);
    let mut last = None;
    for g in window {
        match g.velocity_ned {
            Some(v) if v.norm() > max => return false,
            Some(_) => {}
            None => last = Some(g),
        }
    }
    // Without velocities: the displacement over the window, less 3 σ of
    // each end, at most `max` on average.
    match last {
        Some(l) if l.time_s > gnss[k].time_s => {
            let d = gnss[k].position.ned_to(&l.position).norm();
            let noise = 3.0 * (gnss[k].position_sigma_neu.norm() + l.position_sigma_neu.norm());
            (d - noise).max(0.0) / (l.time_s - gnss[k].time_s) <= max
        }
        _ => true,
    }
}

/// The fix's velocity, else the displacement to the next fix over its time.
fn velocity_of(gnss: &[GnssFix], k: usize) -> Option<Vector3<f64>> {
    gnss[k].velocity_ned.or_else(|| {
        let next = gnss.get(k + 1)?;
        let dt = next.time_s - gnss[k].time_s;
        (dt > 0.0 && dt <= 2.0).then(|| gnss[k].position.ned_to(&next.position).raw() / dt)
    })
}

/// The start at fix `g` (antenna) and IMU sample `index`.
fn build(
    cfg: &ProcessConfig,
    g: &GnssFix,
    index: usize,
    attitude: UnitQuaternion<f64>,
    velocity: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    kind: StartKind,
) -> Start {
    let i = &cfg.initial;
    let (tilt, heading) = match kind {
        StartKind::Moving => (i.moving_tilt_sigma_deg, i.moving_heading_sigma_deg),
        StartKind::Static | StartKind::Given => (i.tilt_sigma_deg, i.heading_sigma_deg),
    };
    // As the loop uses the fix: × the quality factor, floored, × the scale.
    let scale = cfg.gnss.sigma_scale;
    let quality = cfg.gnss.quality_sigma_scale.factor(g.quality);
    let position_sigma_m = i.position_sigma_m.unwrap_or_else(|| {
        (g.position_sigma_neu.max() * quality).max(cfg.gnss.min_position_sigma_m) * scale
    });
    let velocity_sigma_mps = i.velocity_sigma_mps.unwrap_or_else(|| match kind {
        StartKind::Static => cfg
            .standstill
            .max_speed_mps
            .max(cfg.gnss.min_velocity_sigma_mps),
        StartKind::Moving | StartKind::Given => g.velocity_sigma_neu.map_or(0.5, |s| {
            (s.max() * quality).max(cfg.gnss.min_velocity_sigma_mps) * scale
        }),
    });
    // The antenna fix → the IMU's position.
    let arm = attitude * Vector3::from(cfg.gnss.lever_arm_m);
    Start {
        state: NedState {
            position: g.position.offset_by(&Vec3::assume_in_frame(-arm)),
            velocity: Vec3::assume_in_frame(velocity),
            attitude: Rotation::assume_from_quaternion(attitude),
        },
        gyro_bias,
        index,
        kind,
        speed_mps: g.velocity_ned.map_or(f64::NAN, |v| v.norm()),
        tilt_sigma_rad: tilt.to_radians(),
        heading_sigma_rad: heading.to_radians(),
        position_sigma_m,
        velocity_sigma_mps,
        warnings: Vec::new(),
    }
}

fn late_start_warning(s: &mut Start, first_fix_s: f64, t0: f64) {
    if t0 - first_fix_s > 1.0 {
        s.warnings.push(format!(
            "the filter starts at {} ({:.1} s after the first GNSS epoch, {}): no alignment was possible before",
            aidnav_io::text::date_time(t0),
            t0 - first_fix_s,
            match s.kind {
                StartKind::Static => "at a standstill",
                _ => "in motion",
            }
        ));
    }
}
