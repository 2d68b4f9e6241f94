//! Writers for every sensor-log format aidnav reads: what a simulator (or a
//! converter) writes so that the readers of this crate give the records
//! back. [`crate::formats`]' `write` methods call them; each writes its
//! file(s) atomically ([`crate::writers::write_atomic`]), creates the
//! parent directory when needed, and returns the paths written.
//!
//! Round trip (write, then read with this crate's reader), per format:
//!
//! | format | time | position | σ | velocity |
//! | --- | --- | --- | --- | --- |
//! | generic IMU CSV | exact | — | — | rates, force exact |
//! | RTKLIB raw CSV + `.tag` | ≈ 1 µs when the span is a whole number of ms (else stretched by up to 0.5 ms at the end) | — | — | rates, force within 2 ulp (g and deg/s on file) |
//! | KF-GINS IMU | exact on an even grid | — | — | rates to a few ulp |
//! | generic GNSS CSV | exact (GPST or UTC) | exact in degrees (1 ulp from radians) | exact | exact (one velocity σ for all axes) |
//! | RTKLIB `.pos` | 1 ms | 1e-9° and 0.1 mm | 0.1 mm | 1e-5 m/s |
//! | KF-GINS GNSS | exact | exact in degrees | exact | exact (13 columns) |
//! | NMEA GGA + RMC + GST | 10 ms, UTC | 1e-7 minute (≈ 1.7e-9°), 0.1 mm | 0.1 mm | horizontal only, ≈ 1e-5 m/s |
//! | UBX NAV-PVT | 1 ms | 1e-7°, 1 mm | 1 mm (hAcc, vAcc) | 1 mm/s |
//! | wheel speed, barometer CSV | exact | — | exact | exact |
//!
//! Numbers written in full are written with Rust's `{}` (the shortest
//! decimal that reads back as the same `f64`); angles stored in radians are
//! written in degrees, so they come back within an ulp or two of the
//! input (`to_degrees` then `to_radians`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use aidnav_sensors::{BaroSample, GnssFix, ImuSample, WheelSpeedSample};
use nalgebra::Vector3;

use crate::error::{IoError, Result};
use crate::formats::TimeSystem;
use crate::kfgins::STANDARD_GRAVITY_M_S2;
use crate::text::{GPS_EPOCH_1970_S, civil_from_days, gps_minus_utc_s, num};

/// Milliseconds in a day.
const DAY_MS: i64 = 86_400_000;
/// 2200-01-01 in seconds since 1970: the latest time the calendar formats
/// are written for (the generic reader's bound too).
const LATEST_GPST_S: f64 = 7_258_118_400.0;

/// Milliseconds in a GPS week.
const WEEK_MS: i64 = 604_800_000;

fn write_error(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Write `bytes` to `path` atomically, its directory created first.
fn put(path: &Path, bytes: &[u8]) -> Result<PathBuf> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::writers::ensure_dir(dir)?;
    }
    crate::writers::write_atomic(path, bytes)?;
    Ok(path.to_path_buf())
}

/// Times must be finite and strictly increasing; `what` names the records.
fn check_times(path: &Path, what: &str, times: impl Iterator<Item = f64>) -> Result<usize> {
    let mut previous: Option<f64> = None;
    let mut n = 0;
    for (k, t) in times.enumerate() {
        if !t.is_finite() {
            return Err(write_error(path, format!("{what} {k}: time not finite")));
        }
        if let Some(p) = previous
            && t <= p
        {
            return Err(write_error(
                path,
                format!(
                    "{what} {k}: time {} does not increase (previous {})",
                    num(t),
                    num(p)
                ),
            ));
        }
        previous = Some(t);
        n += 1;
    }
    if n == 0 {
        return Err(write_error(path, format!("no {what} to write")));
    }
    Ok(n)
}

/// Every value finite, else an error naming record `k` at `time_s`.
fn check_finite(path: &Path, what: &str, k: usize, time_s: f64, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(write_error(
            path,
            format!("{what} {k} at {}: a value is not finite", num(time_s)),
        ))
    }
}

/// GPS − UTC \[s\] for the GPST instant `gpst_s` (seconds since 1970): the
/// leap seconds of the UTC day the instant falls on, so that UTC + this
/// (what the readers add) gives `gpst_s` back.
pub(crate) fn leap_for_gpst(gpst_s: f64) -> f64 {
    let day = |s: f64| (s / 86_400.0).floor() as i64;
    let first = gps_minus_utc_s(day(gpst_s));
    let second = gps_minus_utc_s(day(gpst_s - first));
    if second == first { first } else { second }
}

/// The UTC milliseconds since 1970 of the GPST milliseconds `gpst_ms`.
fn utc_ms_of(gpst_ms: i64) -> i64 {
    gpst_ms - (leap_for_gpst(gpst_ms as f64 / 1000.0) as i64) * 1000
}

/// Date and time of day of milliseconds since 1970: (year, month, day,
/// hour, minute, millisecond of the minute).
fn calendar(ms: i64) -> (i64, i64, i64, i64, i64, i64) {
    let (y, m, d) = civil_from_days(ms.div_euclid(DAY_MS));
    let rest = ms.rem_euclid(DAY_MS);
    (y, m, d, rest / 3_600_000, rest / 60_000 % 60, rest % 60_000)
}

/// A time as whole milliseconds, the time checked to be on GPS time
/// (1980-01-06 on) and within the `i64` range.
fn gpst_ms(path: &Path, what: &str, k: usize, time_s: f64) -> Result<i64> {
    if !(GPS_EPOCH_1970_S..LATEST_GPST_S).contains(&time_s) {
        return Err(write_error(
            path,
            format!(
                "{what} {k}: time {} s is not GPST seconds since 1970 from 1980-01-06 to 2200",
                num(time_s)
            ),
        ));
    }
    Ok((time_s * 1000.0).round() as i64)
}

// ---------------------------------------------------------------- IMU ----

/// Header of the generic IMU CSV ([`crate::kfgins::read_generic_imu`]).
pub const GENERIC_IMU_HEADER: &str = "time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2";

/// Write `samples` as aidnav's generic IMU CSV: `time_s` (as given: GPST
/// seconds since 1970), rates \[rad/s\] and specific force \[m/s²\], every
/// number in its shortest exact form, so [`crate::kfgins::read_generic_imu`]
/// gives the samples back exactly. Errors: no sample, times that are not
/// finite or do not increase, a non-finite value.
pub fn write_generic_imu(path: &Path, samples: &[ImuSample]) -> Result<Vec<PathBuf>> {
    check_times(path, "IMU sample", samples.iter().map(|s| s.time_s))?;
    let mut text = String::with_capacity(120 * (samples.len() + 1));
    text.push_str(GENERIC_IMU_HEADER);
    text.push('\n');
    for (k, s) in samples.iter().enumerate() {
        let (w, f) = (s.angular_rate, s.specific_force);
        check_imu(path, k, s)?;
        let _ = writeln!(
            text,
            "{},{},{},{},{},{},{}",
            s.time_s, w.x, w.y, w.z, f.x, f.y, f.z
        );
    }
    Ok(vec![put(path, text.as_bytes())?])
}

/// The time-tag file written beside an RTKLIB raw IMU CSV: `path` with
/// `.tag` appended (`imu.csv` → `imu.csv.tag`), as `str2str` names it and
/// `[data] imu_tags` usually gives it.
pub fn tag_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_os_string();
    s.push(".tag");
    PathBuf::from(s)
}

/// Write `samples` as the rtklibexplorer raw IMU CSV (`ax ay az` \[g\],
/// `gx gy gz` \[deg/s\], logger tick \[ms\]) and its RTKLIB time-tag file
/// [`tag_path`]; returns both paths (CSV first).
///
/// The reader drops the CSV's first and last line (a logger artefact) and
/// maps ticks to GPST by the tag file's start and its last tag: the CSV
/// gets a copy of the first sample before and of the last sample after the
/// samples; the ticks are the milliseconds since the first sample, the tag
/// file's start is the first sample's time (whole seconds and fraction,
/// exact), and one tag per sample holds (its tick rounded to whole ms, the
/// byte offset of its line). Times come back to about a microsecond when
/// the log's span (last − first sample) is a whole number of milliseconds
/// (any rate on a millisecond grid); otherwise the reader's tick-to-time
/// scale (last tag / span) stretches them by up to 0.5 ms at the end. Rates
/// and specific force come back within an ulp or two (deg/s and g on file).
///
/// Errors: fewer than two samples, times that do not increase or are not
/// finite, a first time outside the tag file's 32-bit seconds, a span under
/// a millisecond, a non-finite value.
pub fn write_tagged_imu(path: &Path, samples: &[ImuSample]) -> Result<Vec<PathBuf>> {
    let n = check_times(path, "IMU sample", samples.iter().map(|s| s.time_s))?;
    if n < 2 {
        return Err(write_error(path, "1 IMU sample: need at least 2"));
    }
    let t0 = samples[0].time_s;
    if !(0.0..f64::from(u32::MAX)).contains(&t0) {
        return Err(write_error(
            path,
            format!(
                "first time {} s is outside the tag file's range (0 to 2³² s since 1970)",
                num(t0)
            ),
        ));
    }
    let ticks: Vec<f64> = samples.iter().map(|s| (s.time_s - t0) * 1000.0).collect();
    if let Some(k) = ticks.windows(2).position(|w| w[1] <= w[0]) {
        return Err(write_error(
            path,
            format!("IMU samples {k} and {}: the same millisecond tick", k + 1),
        ));
    }
    let last_tick = ticks[n - 1];
    if last_tick.round() < 1.0 || last_tick >= f64::from(u32::MAX) {
        return Err(write_error(
            path,
            format!(
                "the log spans {} ms: the tag file needs 1 ms to 49 days",
                num(last_tick)
            ),
        ));
    }
    let step = ticks[1] - ticks[0];
    let line = |s: &ImuSample, tick: f64| -> String {
        let f = s.specific_force / STANDARD_GRAVITY_M_S2;
        let w = s.angular_rate.map(f64::to_degrees);
        format!("{},{},{},{},{},{},{}\n", f.x, f.y, f.z, w.x, w.y, w.z, tick)
    };
    let mut csv = String::with_capacity(100 * (n + 2));
    let mut tags: Vec<u8> = b"TIMETAG RTKLIB aidnav".to_vec();
    tags.resize(60, 0);
    tags.extend(0u32.to_le_bytes());
    let whole = t0.floor();
    tags.extend((whole as u32).to_le_bytes());
    tags.extend((t0 - whole).to_le_bytes());
    csv.push_str(&line(&samples[0], -step));
    for (k, s) in samples.iter().enumerate() {
        check_imu(path, k, s)?;
        let offset = u32::try_from(csv.len())
            .map_err(|_| write_error(path, "CSV beyond 4 GiB: tag offsets are 32-bit"))?;
        tags.extend((ticks[k].round() as u32).to_le_bytes());
        tags.extend(offset.to_le_bytes());
        csv.push_str(&line(s, ticks[k]));
    }
    csv.push_str(&line(&samples[n - 1], last_tick + step));
    let csv_path = put(path, csv.as_bytes())?;
    let tag = put(&tag_path(path), &tags)?;
    Ok(vec![csv_path, tag])
}

/// Write `samples` as a KF-GINS IMU file ([`crate::kfgins::kfgins_imu_text`])
/// with its times as given (GPST seconds since 1970, the scale of the
/// other logs aidnav reads beside it; KF-GINS itself wants seconds of week:
/// [`crate::kfgins::write_kfgins_imu`] with [`crate::kfgins::gps_week_start`]).
pub fn write_kfgins_imu(path: &Path, samples: &[ImuSample]) -> Result<Vec<PathBuf>> {
    let text = crate::kfgins::kfgins_imu_text(samples, 0.0, path)?;
    Ok(vec![put(path, text.as_bytes())?])
}

// --------------------------------------------------------------- GNSS ----

/// Velocity σ written where a format needs one and the fix has none
/// \[m/s\]: the generic reader's default
/// ([`crate::generic_gnss::DEFAULT_VELOCITY_SIGMA_MPS`]).
const DEFAULT_VELOCITY_SIGMA_MPS: f64 = crate::generic_gnss::DEFAULT_VELOCITY_SIGMA_MPS;

/// Which σ columns the fixes can fill: true when every fix has finite
/// positive σ, false when none has; a mix is an error.
fn sigma_present(path: &Path, fixes: &[GnssFix]) -> Result<bool> {
    let ok = |f: &GnssFix| {
        f.position_sigma_neu
            .iter()
            .all(|s| s.is_finite() && *s > 0.0)
    };
    let count = fixes.iter().filter(|f| ok(f)).count();
    if count == fixes.len() {
        Ok(true)
    } else if count == 0 {
        Ok(false)
    } else {
        let k = fixes.iter().position(|f| !ok(f)).unwrap_or(0);
        Err(write_error(
            path,
            format!(
                "GNSS fix {k}: σ not finite or ≤ 0 while other fixes have σ (a σ column holds every row)"
            ),
        ))
    }
}

/// Position and velocity of a fix checked finite, the latitude within ±90°.
/// IMU sample `k` has a finite time, rate and specific force.
fn check_imu(path: &Path, k: usize, s: &ImuSample) -> Result<()> {
    let (w, f) = (s.angular_rate, s.specific_force);
    check_finite(
        path,
        "IMU sample",
        k,
        s.time_s,
        &[w.x, w.y, w.z, f.x, f.y, f.z],
    )
}

fn check_fix(path: &Path, k: usize, f: &GnssFix) -> Result<()> {
    let p = &f.position;
    let mut values = vec![p.latitude_rad, p.longitude_rad, p.height_m];
    values.extend(f.velocity_ned.iter().flat_map(|v| v.iter().copied()));
    check_finite(path, "GNSS fix", k, f.time_s, &values)?;
    if p.latitude_rad.to_degrees().abs() > 90.0 {
        return Err(write_error(
            path,
            format!("GNSS fix {k}: latitude beyond ±90°"),
        ));
    }
    Ok(())
}

/// ISO 8601 UTC text of the UTC instant `utc_s` (seconds since 1970), its
/// seconds written so that the reader's sum (whole minutes + seconds) is
/// `utc_s` exactly.
fn iso8601(utc_s: f64) -> String {
    let minute = (utc_s / 60.0).floor() * 60.0;
    let seconds = utc_s - minute;
    let (y, mo, d, h, mi, _) = calendar(minute as i64 * 1000);
    let sec = format!("{seconds}");
    let pad = if seconds < 10.0 { "0" } else { "" };
    format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{pad}{sec}Z")
}

/// Header names of the generic GNSS CSV as written.
fn generic_gnss_header(time: TimeSystem, sigma: bool, velocity: bool, sigma_vel: bool) -> String {
    let mut h = vec![match time {
        TimeSystem::Gpst => "gpst_s",
        TimeSystem::Utc => "utc",
    }];
    h.extend(["lat_deg", "lon_deg", "height_m"]);
    if sigma {
        h.extend(["sigma_n_m", "sigma_e_m", "sigma_u_m"]);
    }
    if velocity {
        h.extend(["vel_n_mps", "vel_e_mps", "vel_d_mps"]);
    }
    if sigma_vel {
        h.push("sigma_vel_mps");
    }
    h.extend(["quality", "satellites"]);
    h.join(",")
}

/// Write `fixes` as aidnav's generic GNSS CSV
/// ([`crate::generic_gnss`]): time as `gpst_s` (GPST) or `utc` (ISO 8601,
/// GPST − the leap seconds of the date, as the reader adds them back),
/// `lat_deg, lon_deg, height_m` (ellipsoidal), `sigma_n_m, sigma_e_m,
/// sigma_u_m` when the fixes have σ (every fix finite and > 0; when none
/// has, the columns are left out and the reader needs `[data]
/// gnss_sigma_m`), `vel_n_mps, vel_e_mps, vel_d_mps` when any fix has a
/// velocity (empty cells for the others), `sigma_vel_mps` when any fix has
/// a velocity σ (one σ for every axis: the largest of the three is written,
/// exact when they are equal), `quality` (RTKLIB Q) and `satellites`.
/// Every number in its shortest exact form: the reader gives the fixes back
/// exactly, angles within an ulp (degrees on file).
///
/// Errors: no fix, times that do not increase (or before 1980-01-06 for
/// the reader's `gpst_s`/`utc`), non-finite values, σ on some fixes only.
pub fn write_generic_gnss(
    path: &Path,
    fixes: &[GnssFix],
    time: TimeSystem,
) -> Result<Vec<PathBuf>> {
    check_times(path, "GNSS fix", fixes.iter().map(|f| f.time_s))?;
    let sigma = sigma_present(path, fixes)?;
    let velocity = fixes.iter().any(|f| f.velocity_ned.is_some());
    let sigma_vel = fixes
        .iter()
        .any(|f| f.velocity_ned.is_some() && f.velocity_sigma_neu.is_some());
    let mut text = generic_gnss_header(time, sigma, velocity, sigma_vel);
    text.push('\n');
    for (k, f) in fixes.iter().enumerate() {
        check_fix(path, k, f)?;
        if f.time_s < GPS_EPOCH_1970_S {
            return Err(write_error(
                path,
                format!(
                    "GNSS fix {k}: time {} s is before GPS time began (1980-01-06)",
                    num(f.time_s)
                ),
            ));
        }
        match time {
            TimeSystem::Gpst => {
                let _ = write!(text, "{}", f.time_s);
            }
            TimeSystem::Utc => text.push_str(&iso8601(f.time_s - leap_for_gpst(f.time_s))),
        }
        let p = &f.position;
        let _ = write!(
            text,
            ",{},{},{}",
            p.latitude_rad.to_degrees(),
            p.longitude_rad.to_degrees(),
            p.height_m
        );
        if sigma {
            let s = f.position_sigma_neu;
            let _ = write!(text, ",{},{},{}", s.x, s.y, s.z);
        }
        if velocity {
            match f.velocity_ned {
                Some(v) => {
                    let _ = write!(text, ",{},{},{}", v.x, v.y, v.z);
                }
                None => text.push_str(",,,"),
            }
        }
        if sigma_vel {
            text.push(',');
            if let (Some(_), Some(s)) = (f.velocity_ned, f.velocity_sigma_neu) {
                let s = s.max();
                if !(s.is_finite() && s > 0.0) {
                    return Err(write_error(
                        path,
                        format!("GNSS fix {k}: velocity σ not finite or ≤ 0"),
                    ));
                }
                let _ = write!(text, "{s}");
            }
        }
        let _ = writeln!(text, ",{},{}", f.quality, f.satellites);
    }
    Ok(vec![put(path, text.as_bytes())?])
}

/// Smallest σ written by the fixed-decimal formats (`.pos`, NMEA GST)
/// \[m\]: their 0.1 mm resolution; a smaller σ would read as 0 (refused).
const MIN_FIXED_SIGMA_M: f64 = 1e-4;

/// Write `fixes` as an RTKLIB `.pos` solution file (latitude/longitude/
/// height form, RTKLIB's column widths and decimals): a header whose
/// column line names the time system (`GPST` or `UTC`: the reader converts
/// a UTC file back to GPST with the leap seconds of its date), then per
/// epoch `YYYY/MM/DD HH:MM:SS.sss` (1 ms), latitude and longitude \[deg\]
/// with 9 decimals, ellipsoidal height with 4, Q, ns, sdn sde sdu with 4
/// (at least 0.0001 m: 0 is refused by the reader), sdne sdeu sdun, age
/// and ratio as 0 (not carried by a [`GnssFix`]); epochs with a velocity
/// add `vn ve vu` \[m/s\] (up = −down) and `sdvn sdve sdvu` with 5 decimals
/// (a velocity without σ gets 0.1 m/s, the generic reader's assumption),
/// the columns rtklibexplorer's demo5 writes and [`crate::rtklib::read_pos`]
/// reads.
///
/// Errors: no fix, times that do not increase or are before 1980-01-06,
/// two fixes in one millisecond, non-finite values.
pub fn write_pos(path: &Path, fixes: &[GnssFix], time: TimeSystem) -> Result<Vec<PathBuf>> {
    check_times(path, "GNSS fix", fixes.iter().map(|f| f.time_s))?;
    let velocity = fixes.iter().any(|f| f.velocity_ned.is_some());
    let label = match time {
        TimeSystem::Gpst => "GPST",
        TimeSystem::Utc => "UTC ",
    };
    let mut text = String::with_capacity(200 * (fixes.len() + 4));
    text.push_str("% program   : aidnav\n");
    text.push_str(
        "% (lat/lon/height=WGS84/ellipsoidal,Q=1:fix,2:float,3:sbas,4:dgps,5:single,6:ppp,ns=# of satellites)\n",
    );
    let _ = write!(
        text,
        "%  {label}                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio"
    );
    if velocity {
        text.push_str("    vn(m/s)    ve(m/s)    vu(m/s)      sdvn     sdve     sdvu");
    }
    text.push('\n');
    let mut previous_ms: Option<i64> = None;
    for (k, f) in fixes.iter().enumerate() {
        check_fix(path, k, f)?;
        let mut ms = gpst_ms(path, "GNSS fix", k, f.time_s)?;
        if previous_ms == Some(ms) {
            return Err(write_error(
                path,
                format!(
                    "GNSS fixes {} and {k}: in the same millisecond (the file's resolution)",
                    k - 1
                ),
            ));
        }
        previous_ms = Some(ms);
        if time == TimeSystem::Utc {
            ms = utc_ms_of(ms);
        }
        let (y, mo, d, h, mi, msm) = calendar(ms);
        let sigma = f.position_sigma_neu.map(|s| {
            if s.is_finite() {
                s.max(MIN_FIXED_SIGMA_M)
            } else {
                f64::NAN
            }
        });
        check_finite(path, "GNSS fix", k, f.time_s, sigma.as_slice())?;
        let p = &f.position;
        let _ = write!(
            text,
            "{y:04}/{mo:02}/{d:02} {h:02}:{mi:02}:{:02}.{:03} {:14.9} {:14.9} {:10.4} {:3} {:3} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4} {:8.4} {:6.2} {:6.1}",
            msm / 1000,
            msm % 1000,
            p.latitude_rad.to_degrees(),
            p.longitude_rad.to_degrees(),
            p.height_m,
            f.quality,
            f.satellites,
            sigma.x,
            sigma.y,
            sigma.z,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0
        );
        if let Some(v) = f.velocity_ned {
            let s = f
                .velocity_sigma_neu
                .unwrap_or(Vector3::repeat(DEFAULT_VELOCITY_SIGMA_MPS))
                .map(|s| if s.is_finite() { s.max(1e-5) } else { f64::NAN });
            check_finite(path, "GNSS fix", k, f.time_s, s.as_slice())?;
            let _ = write!(
                text,
                " {:10.5} {:10.5} {:10.5} {:9.5} {:9.5} {:9.5}",
                v.x, v.y, -v.z, s.x, s.y, s.z
            );
        }
        text.push('\n');
    }
    Ok(vec![put(path, text.as_bytes())?])
}

/// Write `fixes` as a KF-GINS GNSS file with times as given (GPST seconds
/// since 1970; see [`write_kfgins_imu`]): 13 columns (`time lat lon h vN vE
/// vD σN σE σD σvN σvE σvD`, KF-GINS's velocity layout) when every fix has a
/// velocity and its σ, else the 7 of [`crate::kfgins::kfgins_gnss_text`]
/// (position and σ only). Exact numbers; quality and satellite count are
/// not in the format (read back as 0).
pub fn write_kfgins_gnss(path: &Path, fixes: &[GnssFix]) -> Result<Vec<PathBuf>> {
    check_times(path, "GNSS fix", fixes.iter().map(|f| f.time_s))?;
    let with_velocity = fixes
        .iter()
        .all(|f| f.velocity_ned.is_some() && f.velocity_sigma_neu.is_some());
    if !with_velocity {
        let text = crate::kfgins::kfgins_gnss_text(fixes, 0.0, path)?;
        return Ok(vec![put(path, text.as_bytes())?]);
    }
    let mut text = String::with_capacity(200 * fixes.len());
    for (k, f) in fixes.iter().enumerate() {
        check_fix(path, k, f)?;
        let (p, s) = (&f.position, f.position_sigma_neu);
        let v = f.velocity_ned.unwrap_or_default();
        let sv = f.velocity_sigma_neu.unwrap_or_default();
        check_finite(
            path,
            "GNSS fix",
            k,
            f.time_s,
            &[s.x, s.y, s.z, sv.x, sv.y, sv.z],
        )?;
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {} {} {} {} {} {} {}",
            f.time_s,
            p.latitude_rad.to_degrees(),
            p.longitude_rad.to_degrees(),
            p.height_m,
            v.x,
            v.y,
            v.z,
            s.x,
            s.y,
            s.z,
            sv.x,
            sv.y,
            sv.z
        );
    }
    Ok(vec![put(path, text.as_bytes())?])
}

/// An NMEA sentence `$body*CS` with its CR LF.
fn sentence(body: &str) -> String {
    let sum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{sum:02X}\r\n")
}

/// `(d)ddmm.mmmmmmm` and hemisphere of an angle \[deg\] (7 decimals of
/// minutes).
fn nmea_angle(deg: f64, degree_digits: usize, positive: char, negative: char) -> String {
    const PER_DEGREE: i64 = 600_000_000; // 1e-7 minute units
    let units = (deg.abs() * PER_DEGREE as f64).round() as i64;
    let (d, rest) = (units / PER_DEGREE, units % PER_DEGREE);
    let hemisphere = if deg < 0.0 && units > 0 {
        negative
    } else {
        positive
    };
    format!(
        "{d:0degree_digits$}{:02}.{:07},{hemisphere}",
        rest / 10_000_000,
        rest % 10_000_000
    )
}

/// GGA fix quality of RTKLIB's Q: 1 → 4 (RTK fixed), 2 → 5 (float), 3
/// (SBAS) and 4 (DGPS) → 2 (DGPS), anything else → 1 (single: GGA has no
/// "unknown", and quality 0 would be skipped as no fix).
fn gga_quality(q: u8) -> u8 {
    match q {
        1 => 4,
        2 => 5,
        3 | 4 => 2,
        _ => 1,
    }
}

/// Write `fixes` as an NMEA 0183 log (talker `GN`), always in UTC whatever
/// [`TimeSystem`] the other files use (NMEA has no GPST): per epoch a GGA
/// (position, quality, satellites), an RMC (date, speed over ground in
/// knots and course, status `A`; empty speed and course without a
/// velocity) and a GST (σ latitude, longitude, altitude).
///
/// What [`crate::nmea::read_nmea`] gives back:
/// - time: hhmmss.ss UTC (GPST − the leap seconds of the date, which the
///   reader adds back), so 10 ms resolution; fixes must be at least 10 ms
///   apart; each epoch's RMC precedes its GGA (as u-blox receivers order
///   them: the reader dates a GGA by the last RMC);
/// - position: latitude and longitude with 7 decimals of minutes (≈ 1.7e-9°,
///   0.2 mm), the height with 4 decimals in GGA's altitude field with a
///   geoid separation of **0**, so altitude + separation is the ellipsoidal
///   height (the altitude field is then not a height above mean sea level);
/// - quality: RTKLIB's Q mapped to GGA's and back (1, 2, 4, 5 unchanged; 3
///   reads back as 4; 0 and 6 as 5); satellites at most 99 (two digits);
/// - σ: GST's σ with 4 decimals (at least 0.0001 m); without GST the reader
///   would assume σ by quality, so GST is always written;
/// - velocity: horizontal only (speed 5 decimals of a knot, course 5
///   decimals of a degree, ≈ 1e-5 m/s); the vertical velocity and the
///   velocity σ are not in NMEA (the reader sets 0 with σ 0.1 / 0.1 / 10
///   m/s).
///
/// Errors: no fix, times that do not increase, before 1980-01-06 or after
/// 2079 (two-digit years), two fixes in one 10 ms step, non-finite values.
pub fn write_nmea(path: &Path, fixes: &[GnssFix]) -> Result<Vec<PathBuf>> {
    check_times(path, "GNSS fix", fixes.iter().map(|f| f.time_s))?;
    let mut text = String::with_capacity(250 * fixes.len());
    let mut previous_cs: Option<i64> = None;
    for (k, f) in fixes.iter().enumerate() {
        check_fix(path, k, f)?;
        gpst_ms(path, "GNSS fix", k, f.time_s)?;
        let leap = leap_for_gpst(f.time_s);
        let utc_cs = ((f.time_s - leap) * 100.0).round() as i64;
        if previous_cs == Some(utc_cs) {
            return Err(write_error(
                path,
                format!(
                    "GNSS fixes {} and {k}: in the same 10 ms (NMEA's time resolution)",
                    k - 1
                ),
            ));
        }
        previous_cs = Some(utc_cs);
        let (y, mo, d, h, mi, msm) = calendar(utc_cs * 10);
        if !(1980..2080).contains(&y) {
            return Err(write_error(
                path,
                format!("GNSS fix {k}: year {y} outside NMEA's two-digit years 1980–2079"),
            ));
        }
        let tod = format!("{h:02}{mi:02}{:02}.{:02}", msm / 1000, msm % 1000 / 10);
        let p = &f.position;
        let lat = nmea_angle(p.latitude_rad.to_degrees(), 2, 'N', 'S');
        let mut lon_deg = p.longitude_rad.to_degrees();
        if lon_deg > 180.0 {
            lon_deg -= 360.0;
        }
        let lon = nmea_angle(lon_deg, 3, 'E', 'W');
        check_finite(
            path,
            "GNSS fix",
            k,
            f.time_s,
            f.position_sigma_neu.as_slice(),
        )?;
        let sigma = f.position_sigma_neu.map(|s| s.max(MIN_FIXED_SIGMA_M));
        let gga = sentence(&format!(
            "GNGGA,{tod},{lat},{lon},{},{:02},,{:.4},M,0.0,M,,",
            gga_quality(f.quality),
            f.satellites.min(99),
            p.height_m
        ));
        let (speed, course) = match f.velocity_ned {
            Some(v) => {
                let knots = v.x.hypot(v.y) * 3600.0 / 1852.0;
                let mut course = v.y.atan2(v.x).to_degrees();
                if course < 0.0 {
                    course += 360.0;
                }
                let mut course = format!("{course:.5}");
                if course == "360.00000" {
                    course = "0.00000".into();
                }
                (format!("{knots:.5}"), course)
            }
            None => (String::new(), String::new()),
        };
        let rmc = sentence(&format!(
            "GNRMC,{tod},A,{lat},{lon},{speed},{course},{d:02}{mo:02}{:02},,,A",
            y % 100
        ));
        let gst = sentence(&format!(
            "GNGST,{tod},{:.4},{:.4},{:.4},0.0,{:.4},{:.4},{:.4}",
            sigma.norm(),
            sigma.x.max(sigma.y),
            sigma.x.min(sigma.y),
            sigma.x,
            sigma.y,
            sigma.z
        ));
        text.push_str(&rmc);
        text.push_str(&gga);
        text.push_str(&gst);
    }
    Ok(vec![put(path, text.as_bytes())?])
}

/// Velocity σ of each axis written for a fix without a velocity (velocity
/// 0) in UBX, whose NAV-PVT always holds one \[m/s\]: practically
/// unobserved.
pub const UBX_NO_VELOCITY_SIGMA_MPS: f64 = 100.0;

/// A value rounded to an integer of the field's type, saturated.
fn round_i32(v: f64) -> i32 {
    v.round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

/// An accuracy field \[mm or mm/s\]: rounded, at least 1 (0 is refused).
fn accuracy(v: f64) -> u32 {
    v.round().clamp(1.0, f64::from(u32::MAX)) as u32
}

/// Write `fixes` as a u-blox UBX log of NAV-PVT messages (92-byte payload,
/// u-blox 8 on, Fletcher checksums), one per fix:
/// - `iTOW`: GPST time of week, whole ms (the time's resolution); UTC
///   date and time (`validDate`, `validTime`, `fullyResolved` set): GPST −
///   the leap seconds of the date, `nano` the milliseconds (the reader
///   takes the GPS week from them);
/// - `lat`, `lon` in 1e-7°, `height` (ellipsoidal) in mm; `hMSL` = `height`
///   (a geoid separation of 0: no geoid model here);
/// - fixType 3 (3-D), gnssFixOK, and the quality as flags: Q 1 → carrSoln
///   fixed, 2 → float (both with diffSoln), 3 and 4 → diffSoln (reads back
///   4), else none (reads back 5); `numSV` (at most 255);
/// - `hAcc` = √(σN² + σE²) and `vAcc` = σU in mm (at least 1): the reader
///   takes hAcc/√2 for each horizontal axis, so equal north and east σ come
///   back to 1 mm;
/// - `velN, velE, velD` in mm/s, `gSpeed`, `headMot`, and `sAcc` =
///   √(σvN² + σvE²) (read back as sAcc/√2 on every axis; a velocity without
///   σ gets 0.1 m/s). A fix without a velocity is written with velocity 0
///   and σ [`UBX_NO_VELOCITY_SIGMA_MPS`] — NAV-PVT always carries one, and
///   the reader always returns it.
///
/// [`TimeSystem`] does not apply: `iTOW` is GPST and the date fields UTC,
/// as a receiver writes them.
///
/// Errors: no fix, times that do not increase or are before 1980-01-06,
/// two fixes in one millisecond, non-finite values.
pub fn write_ubx(path: &Path, fixes: &[GnssFix]) -> Result<Vec<PathBuf>> {
    use crate::ubx::{NAV_PVT, NAV_PVT_LEN, frame::encode};
    check_times(path, "GNSS fix", fixes.iter().map(|f| f.time_s))?;
    let mut bytes = Vec::with_capacity(100 * fixes.len());
    let mut previous_ms: Option<i64> = None;
    for (k, f) in fixes.iter().enumerate() {
        check_fix(path, k, f)?;
        let ms = gpst_ms(path, "GNSS fix", k, f.time_s)?;
        if previous_ms == Some(ms) {
            return Err(write_error(
                path,
                format!(
                    "GNSS fixes {} and {k}: in the same millisecond (iTOW's resolution)",
                    k - 1
                ),
            ));
        }
        previous_ms = Some(ms);
        let since_gps = ms - (GPS_EPOCH_1970_S as i64) * 1000;
        let itow = since_gps.rem_euclid(WEEK_MS) as u32;
        let (y, mo, d, h, mi, msm) = calendar(utc_ms_of(ms));
        let s = f.position_sigma_neu;
        check_finite(path, "GNSS fix", k, f.time_s, s.as_slice())?;
        let (v, sv) = match f.velocity_ned {
            Some(v) => (
                v,
                f.velocity_sigma_neu
                    .unwrap_or(Vector3::repeat(DEFAULT_VELOCITY_SIGMA_MPS)),
            ),
            None => (Vector3::zeros(), Vector3::repeat(UBX_NO_VELOCITY_SIGMA_MPS)),
        };
        check_finite(path, "GNSS fix", k, f.time_s, sv.as_slice())?;
        let flags: u8 = 0x01
            | match f.quality {
                1 => 0x80 | 0x02,
                2 => 0x40 | 0x02,
                3 | 4 => 0x02,
                _ => 0,
            };
        let p = &f.position;
        let mut lon_deg = p.longitude_rad.to_degrees();
        if lon_deg > 180.0 {
            lon_deg -= 360.0;
        }
        let height_mm = round_i32(p.height_m * 1000.0);
        let mut heading = v.y.atan2(v.x).to_degrees();
        if heading < 0.0 {
            heading += 360.0;
        }
        let mut pl = vec![0u8; NAV_PVT_LEN];
        let mut put_at = |o: usize, b: &[u8]| pl[o..o + b.len()].copy_from_slice(b);
        put_at(0, &itow.to_le_bytes());
        put_at(4, &(y as u16).to_le_bytes());
        put_at(
            6,
            &[
                mo as u8,
                d as u8,
                h as u8,
                mi as u8,
                (msm / 1000) as u8,
                0x07,
            ],
        );
        put_at(12, &1_000_000u32.to_le_bytes()); // tAcc: 1 ms [ns]
        put_at(16, &((msm % 1000) as i32 * 1_000_000).to_le_bytes());
        put_at(20, &[3, flags, 0, f.satellites.min(255) as u8]);
        put_at(24, &round_i32(lon_deg * 1e7).to_le_bytes());
        put_at(
            28,
            &round_i32(p.latitude_rad.to_degrees() * 1e7).to_le_bytes(),
        );
        put_at(32, &height_mm.to_le_bytes());
        put_at(36, &height_mm.to_le_bytes());
        put_at(40, &accuracy(s.x.hypot(s.y) * 1000.0).to_le_bytes());
        put_at(44, &accuracy(s.z * 1000.0).to_le_bytes());
        for (i, c) in v.iter().enumerate() {
            put_at(48 + 4 * i, &round_i32(c * 1000.0).to_le_bytes());
        }
        put_at(60, &round_i32(v.x.hypot(v.y) * 1000.0).to_le_bytes());
        put_at(64, &round_i32(heading * 1e5).to_le_bytes());
        put_at(68, &accuracy(sv.x.hypot(sv.y) * 1000.0).to_le_bytes());
        put_at(72, &18_000_000u32.to_le_bytes()); // headAcc: 180° [1e-5 deg]
        put_at(76, &100u16.to_le_bytes()); // pDOP 1.00
        bytes.extend(encode(NAV_PVT.0, NAV_PVT.1, &pl));
    }
    Ok(vec![put(path, &bytes)?])
}

// ------------------------------------------------ wheel speed, barometer ----

/// Write `samples` as aidnav's generic wheel-speed CSV
/// ([`crate::generic_aiding`]): `time_s` (as given), `speed_mps`, and
/// `sigma_mps` when any sample has a σ (empty cells for the others); exact
/// numbers. Errors: no sample, times that do not increase, non-finite
/// values.
pub fn write_wheel_speed(path: &Path, samples: &[WheelSpeedSample]) -> Result<Vec<PathBuf>> {
    let rows: Vec<(f64, f64, Option<f64>)> = samples
        .iter()
        .map(|s| (s.time_s, s.speed_mps, s.sigma_mps))
        .collect();
    scalar_csv(path, "wheel-speed sample", "speed_mps", "sigma_mps", &rows)
}

/// Write `samples` as aidnav's generic barometer CSV
/// ([`crate::generic_aiding`]): `time_s` (as given), `height_m`, and
/// `sigma_m` when any sample has a σ (empty cells for the others); exact
/// numbers. Errors: no sample, times that do not increase, non-finite
/// values.
pub fn write_baro(path: &Path, samples: &[BaroSample]) -> Result<Vec<PathBuf>> {
    let rows: Vec<(f64, f64, Option<f64>)> = samples
        .iter()
        .map(|s| (s.time_s, s.height_m, s.sigma_m))
        .collect();
    scalar_csv(path, "barometer sample", "height_m", "sigma_m", &rows)
}

/// A `time_s, value[, σ]` CSV.
fn scalar_csv(
    path: &Path,
    what: &str,
    value: &str,
    sigma: &str,
    rows: &[(f64, f64, Option<f64>)],
) -> Result<Vec<PathBuf>> {
    check_times(path, what, rows.iter().map(|r| r.0))?;
    let with_sigma = rows.iter().any(|r| r.2.is_some());
    let mut text = String::with_capacity(40 * (rows.len() + 1));
    text.push_str("time_s,");
    text.push_str(value);
    if with_sigma {
        text.push(',');
        text.push_str(sigma);
    }
    text.push('\n');
    for (k, &(t, v, s)) in rows.iter().enumerate() {
        check_finite(path, what, k, t, &[v, s.unwrap_or(1.0)])?;
        let _ = write!(text, "{t},{v}");
        if with_sigma {
            text.push(',');
            if let Some(s) = s {
                let _ = write!(text, "{s}");
            }
        }
        text.push('\n');
    }
    Ok(vec![put(path, text.as_bytes())?])
}
