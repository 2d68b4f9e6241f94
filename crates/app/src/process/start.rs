//! Where and how the filter starts: at the first GNSS epoch that allows an
//! alignment — a standstill (levelling and the gyro bias at rest, the
//! heading from the course once the vehicle moves off) or a motion fast
//! enough for the course (heading from the course, pitch from the climb
//! angle, velocity from GNSS, larger attitude σ) — or with a given attitude.

use aidnav_frames::{Rotation, Vec3};
use aidnav_ins::alignment::{course, gyro_bias_at_rest, level, static_window};
use aidnav_ins::ned::NedState;
use aidnav_ins::standstill::{StandstillThresholds, WindowStats, gnss_says_still};
use aidnav_io::rtklib::GnssFix;
use nalgebra::{UnitQuaternion, Vector3};
use serde::Serialize;

use super::warnings::{Warning, WarningKind};
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
    /// What a user should know (a late start, a standstill only the IMU
    /// vouched for).
    pub warnings: Vec<Warning>,
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
        let until = t0 + cfg.initial.static_s;
        let imu_still =
            window.len() >= 10 && WindowStats::of(window).is_some_and(|s| s.is_still(&thresholds));
        let gnss_says = if imu_still {
            gnss_speed_evidence(gnss, k, until, cfg.standstill.max_speed_mps)
        } else {
            GnssEvidence::Moving
        };
        if gnss_says != GnssEvidence::Moving {
            let levelling = level(window);
            let moving = (k..gnss.len())
                .find_map(|j| velocity_of(gnss, j).filter(|v| v.xy().norm() > heading_speed))
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
            if gnss_says == GnssEvidence::None {
                // A vehicle cruising on a smooth road looks still to the
                // IMU; only GNSS can tell, and here it says nothing.
                s.warnings.push(Warning::during(
                    WarningKind::LevellingWhileMoving,
                    format!(
                        "levelled at {} on the IMU's word alone: the GNSS log has no velocity, and its fixes within initial.static_s = {} s (or the next one) are too coarse to confirm a standstill; if the vehicle was moving the attitude and velocity are wrong (give initial.attitude_deg, or a log with GNSS velocity)",
                        aidnav_io::text::date_time(t0),
                        cfg.initial.static_s
                    ),
                    t0,
                    until,
                ));
            }
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

/// What GNSS says about a standstill from fix `k` to `until`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum GnssEvidence {
    /// Velocities or displacements at most the standstill speed.
    Still,
    /// A velocity or displacement above it.
    Moving,
    /// Nothing to judge by: no velocity, and no second fix within the
    /// window or right after it, or fixes too coarse for the standstill
    /// speed over that time.
    None,
}

/// The GNSS speed over the fixes from `k` up to `until`: their velocities,
/// or (without velocity columns) their displacement — to the last fix in
/// the window, or to the first one after it when the window holds only
/// fix `k` (a 1 Hz log and a short window).
fn gnss_speed_evidence(gnss: &[GnssFix], k: usize, until: f64, max: f64) -> GnssEvidence {
    let mut last = None;
    let mut any_velocity = false;
    for g in gnss[k..].iter().take_while(|g| g.time_s <= until) {
        match g.velocity_ned {
            Some(v) if !gnss_says_still(&v, g.velocity_sigma_neu.as_ref(), max) => {
                return GnssEvidence::Moving;
            }
            Some(_) => any_velocity = true,
            None => last = Some(g),
        }
    }
    if any_velocity {
        return GnssEvidence::Still;
    }
    let after = gnss[k..].iter().find(|g| g.time_s > until);
    let end = match last {
        Some(l) if l.time_s > gnss[k].time_s => Some(l),
        _ => after,
    };
    // The displacement over the window, less 3 σ of each end, at most
    // `max` on average; when 3 σ alone exceed `max` over that time, the
    // fixes cannot tell a standstill from a crawl at `max`.
    match end {
        Some(l) if l.time_s > gnss[k].time_s => {
            let dt = l.time_s - gnss[k].time_s;
            let (d, noise) = displacement_and_noise(&gnss[k], l);
            if (d.norm() - noise).max(0.0) / dt > max {
                GnssEvidence::Moving
            } else if noise / dt > max {
                GnssEvidence::None
            } else {
                GnssEvidence::Still
            }
        }
        _ => GnssEvidence::None,
    }
}

/// The fix's velocity; without one, the displacement to the first fix
/// 1–5 s later whose displacement exceeds 3 σ of the two fixes, over its
/// time (a course from positions needs a displacement the fixes' noise
/// cannot make; None when none does).
fn velocity_of(gnss: &[GnssFix], k: usize) -> Option<Vector3<f64>> {
    gnss[k].velocity_ned.or_else(|| {
        let t = gnss[k].time_s;
        gnss[k + 1..]
            .iter()
            .take_while(|g| g.time_s <= t + 5.0)
            .filter(|g| g.time_s >= t + 1.0)
            .find_map(|next| {
                let (d, noise) = displacement_and_noise(&gnss[k], next);
                (d.norm() > noise).then(|| d / (next.time_s - t))
            })
    })
}

/// The displacement from fix `a` to fix `b` (NED) \[m\] and 3 σ of the
/// two fixes' position noise together \[m\]: a displacement within it may
/// be noise alone.
fn displacement_and_noise(a: &GnssFix, b: &GnssFix) -> (Vector3<f64>, f64) {
    (
        a.position.ned_to(&b.position).raw(),
        3.0 * (a.position_sigma_neu.norm() + b.position_sigma_neu.norm()),
    )
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
        s.warnings.push(Warning::new(
            WarningKind::Start,
            format!(
                "the filter starts at {} ({:.1} s after the first GNSS epoch, {}): no alignment was possible before",
                aidnav_io::text::date_time(t0),
                t0 - first_fix_s,
                match s.kind {
                    StartKind::Static => "at a standstill",
                    _ => "in motion",
                }
            ),
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_frames::earth::Geodetic;

    /// Fixes every `dt` s moving north at `speed`, σ `sigma` per axis,
    /// with or without a velocity.
    fn fixes(n: usize, dt: f64, speed: f64, sigma: f64, velocity: bool) -> Vec<GnssFix> {
        let origin = Geodetic {
            latitude_rad: 0.8,
            longitude_rad: 0.2,
            height_m: 100.0,
        };
        (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                GnssFix {
                    time_s: t,
                    position: origin.offset_by(&Vec3::assume_in_frame(Vector3::new(
                        speed * t,
                        0.0,
                        0.0,
                    ))),
                    quality: 5,
                    satellites: 8,
                    position_sigma_neu: Vector3::repeat(sigma),
                    velocity_ned: velocity.then(|| Vector3::new(speed, 0.0, 0.0)),
                    velocity_sigma_neu: None,
                }
            })
            .collect()
    }

    /// A still IMU and 3 m fixes without velocity (a car on a smooth road,
    /// a phone's NMEA): levelled, with the `levelling_while_moving`
    /// warning over the window; the heading from the positions once they
    /// move north at 10 m/s. With 1 cm fixes GNSS confirms the standstill:
    /// no warning.
    #[test]
    fn a_standstill_only_the_imu_vouches_for_is_levelled_with_a_warning() {
        let place = Geodetic {
            latitude_rad: 0.8,
            longitude_rad: 0.2,
            height_m: 100.0,
        };
        let g = aidnav_ins::ned::gravity_ned(&place).raw();
        let w = aidnav_frames::earth::earth_rate_ned(place.latitude_rad).raw();
        let imu: Vec<_> = (0..3000)
            .map(|k| aidnav_io::rtklib::ImuSample {
                time_s: k as f64 * 0.01,
                specific_force: -g,
                angular_rate: w,
            })
            .collect();
        let start = |sigma: f64| {
            // Still for 12 s, then north at 10 m/s.
            let gnss: Vec<GnssFix> = fixes(120, 0.25, 0.0, sigma, false)
                .into_iter()
                .map(|mut f| {
                    let north = 10.0 * (f.time_s - 12.0).max(0.0);
                    f.position =
                        place.offset_by(&Vec3::assume_in_frame(Vector3::new(north, 0.0, 0.0)));
                    f
                })
                .collect();
            let cfg: ProcessConfig =
                toml::from_str("[data]\ndir = \".\"\nimu = \"i\"\ngnss = \"g\"\n").unwrap();
            let inputs = Inputs::new(imu.clone(), gnss);
            initialise(&cfg, &inputs).unwrap()
        };
        let coarse = start(3.0);
        assert_eq!(coarse.kind, StartKind::Static);
        let w = &coarse.warnings;
        assert_eq!(w.len(), 1, "{w:?}");
        assert_eq!(w[0].kind, WarningKind::LevellingWhileMoving);
        assert_eq!((w[0].start_s, w[0].end_s), (Some(0.0), Some(5.0)));
        assert!(
            w[0].message.contains("IMU's word alone"),
            "{}",
            w[0].message
        );
        // Heading north from the positions (to a degree: the noise-free
        // synthetic positions).
        let yaw = coarse.state.attitude.quaternion().euler_angles().2;
        assert!(yaw.to_degrees().abs() < 1.0, "yaw {}", yaw.to_degrees());
        let fine = start(0.01);
        assert_eq!(fine.kind, StartKind::Static);
        assert!(fine.warnings.is_empty(), "{:?}", fine.warnings);
    }

    /// Velocities decide when present; without them the displacement
    /// does, unless 3 σ of the fixes over the time exceed the standstill
    /// speed (then GNSS cannot tell, and a levelling has only the IMU's
    /// word: the `levelling_while_moving` warning).
    #[test]
    fn gnss_evidence_of_a_standstill() {
        let max = 0.2;
        let e = |g: &[GnssFix], until: f64| gnss_speed_evidence(g, 0, until, max);
        assert_eq!(
            e(&fixes(30, 0.25, 0.0, 5.0, true), 5.0),
            GnssEvidence::Still
        );
        assert_eq!(
            e(&fixes(30, 0.25, 8.0, 5.0, true), 5.0),
            GnssEvidence::Moving
        );
        // Precise fixes without velocity: 1 cm σ over 5 s resolves 0.2 m/s.
        assert_eq!(
            e(&fixes(30, 0.25, 0.0, 0.01, false), 5.0),
            GnssEvidence::Still
        );
        assert_eq!(
            e(&fixes(30, 0.25, 8.0, 0.01, false), 5.0),
            GnssEvidence::Moving
        );
        // 3 m fixes: a car at 8 m/s still shows (40 m in 5 s against
        // 31 m of noise) …
        assert_eq!(
            e(&fixes(30, 0.25, 8.0, 3.0, false), 5.0),
            GnssEvidence::Moving
        );
        // … a walker at 1 m/s does not, nor a standstill.
        assert_eq!(
            e(&fixes(30, 0.25, 1.0, 3.0, false), 5.0),
            GnssEvidence::None
        );
        assert_eq!(
            e(&fixes(30, 0.25, 0.0, 3.0, false), 5.0),
            GnssEvidence::None
        );
        // 0.1 Hz: the window holds one fix; the next one, 10 s on, judges.
        assert_eq!(
            e(&fixes(3, 10.0, 0.0, 0.01, false), 5.0),
            GnssEvidence::Still
        );
        assert_eq!(
            e(&fixes(3, 10.0, 3.0, 0.01, false), 5.0),
            GnssEvidence::Moving
        );
        // A single fix: nothing.
        assert_eq!(e(&fixes(1, 1.0, 0.0, 0.01, false), 5.0), GnssEvidence::None);
    }
}
