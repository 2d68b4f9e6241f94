//! Readers for RTKLIB files (spec 40): solution files (`.pos`) and the raw
//! IMU CSV of the rtklibexplorer data set with its binary RTKLIB time-tag
//! file (`.csv.tag`).
//!
//! Time: GPST as seconds since 1970-01-01 (the tag file's convention; a
//! `.pos` calendar time `YYYY/MM/DD HH:MM:SS.sss` in GPST maps to the same
//! scale by a plain calendar conversion, no leap seconds; a `.pos` whose
//! column header names `UTC` gets the leap seconds of its date added).
//!
//! Validation: every error names the file, the line and the column; a
//! truncated *last* line is skipped with a warning (a logger artefact), a
//! truncated line elsewhere, a non-finite value, a σ ≤ 0, a latitude outside
//! ±90°, and time that does not increase are errors.

use std::path::Path;

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::checks::CheckLevel;
use crate::error::{IoError, Result};

pub use aidnav_sensors::{GnssFix, ImuSample};

/// Standard gravity, the unit of the data set's accelerometer columns.
const G0: f64 = 9.806_65;

pub(crate) use crate::text::days_from_civil;

use crate::text::GPS_EPOCH_1970_S;

/// A data error naming the file, line and column.
pub(crate) fn data_error(
    path: &Path,
    line: usize,
    column: &str,
    message: impl Into<String>,
) -> IoError {
    IoError::Data {
        path: path.to_path_buf(),
        line,
        column: column.to_string(),
        message: message.into(),
    }
}

/// A value checked against a physical bound ([`crate::limits`]): an error
/// naming the file, line and column when outside `[lo, hi]`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn in_range(
    path: &Path,
    line: usize,
    column: &str,
    value: f64,
    lo: f64,
    hi: f64,
    unit: &str,
    why: &str,
) -> Result<()> {
    match crate::limits::outside(value, lo, hi, unit, why) {
        Some(m) => Err(data_error(path, line, column, m)),
        None => Ok(()),
    }
}

/// The warning for a truncated last line skipped (`what`: how many fields
/// it has), as every text reader words it.
pub(crate) fn truncated_last_line(path: &Path, line: usize, what: std::fmt::Arguments) -> String {
    format!(
        "{}:{line}: truncated last line skipped ({what})",
        path.display()
    )
}

/// Check latitude, longitude and height of a position against
/// [`crate::limits`].
pub(crate) fn check_position(
    path: &Path,
    line: usize,
    lat_deg: f64,
    lon_deg: f64,
    height_m: f64,
) -> Result<()> {
    use crate::limits::*;
    in_range(
        path,
        line,
        "latitude",
        lat_deg,
        -MAX_LATITUDE_DEG,
        MAX_LATITUDE_DEG,
        "deg",
        "the poles; x/y/z ECEF files are not supported",
    )?;
    in_range(
        path,
        line,
        "longitude",
        lon_deg,
        -MAX_LONGITUDE_DEG,
        MAX_LONGITUDE_DEG,
        "deg",
        "±180° or 0–360°",
    )?;
    in_range(
        path,
        line,
        "height",
        height_m,
        MIN_HEIGHT_M,
        MAX_HEIGHT_M,
        "m",
        "below the lowest land or above 100 km",
    )
}

/// Check a rate vector against [`crate::limits::MAX_ANGULAR_RATE_RAD_S`].
pub(crate) fn check_rate(
    path: &Path,
    line: usize,
    column: &str,
    rate_rad_s: &Vector3<f64>,
    hint: &str,
) -> Result<()> {
    let w = rate_rad_s.norm();
    if w > crate::limits::MAX_ANGULAR_RATE_RAD_S {
        return Err(data_error(
            path,
            line,
            column,
            format!(
                "|ω| = {} rad/s is above {} rad/s (≈ 2 900 °/s, beyond any MEMS gyro's range){hint}",
                crate::text::num(w),
                crate::limits::MAX_ANGULAR_RATE_RAD_S
            ),
        ));
    }
    Ok(())
}

/// Check a specific force against [`crate::limits::MAX_SPECIFIC_FORCE_M_S2`].
pub(crate) fn check_force(
    path: &Path,
    line: usize,
    column: &str,
    force_m_s2: &Vector3<f64>,
) -> Result<()> {
    let f = force_m_s2.norm();
    if f > crate::limits::MAX_SPECIFIC_FORCE_M_S2 {
        return Err(data_error(
            path,
            line,
            column,
            format!(
                "|f| = {} m/s² is above {} m/s² (≈ 200 g, beyond navigation accelerometers)",
                crate::text::num(f),
                crate::limits::MAX_SPECIFIC_FORCE_M_S2
            ),
        ));
    }
    Ok(())
}

/// The median specific-force magnitude of a log must be about 1 g
/// ([`crate::limits::MEDIAN_SPECIFIC_FORCE_M_S2`]); near 1 it is in g.
pub(crate) fn check_median_force(
    path: &Path,
    line: usize,
    column: &str,
    forces: impl Iterator<Item = Vector3<f64>>,
) -> Result<()> {
    let mut norms: Vec<f64> = forces.map(|f| f.norm()).collect();
    if norms.is_empty() {
        return Ok(());
    }
    norms.sort_by(f64::total_cmp);
    let median = norms[norms.len() / 2];
    let range = crate::limits::MEDIAN_SPECIFIC_FORCE_M_S2;
    if !range.contains(&median) {
        return Err(data_error(
            path,
            line,
            column,
            format!(
                "median |f| = {} m/s², expected about 9.8 (between {} and {}){}",
                crate::text::num(median),
                range.start(),
                range.end(),
                if (0.5..2.0).contains(&median) {
                    " — is the accelerometer in g instead of m/s²?"
                } else {
                    ""
                }
            ),
        ));
    }
    Ok(())
}

/// Parse `YYYY/MM/DD HH:MM:SS.sss` or `WEEK TOW` (two tokens) to seconds;
/// an impossible date (30 February) or time of day is an error message.
fn parse_time(date: &str, time: &str) -> std::result::Result<f64, String> {
    use crate::text::excerpt;
    if let (Ok(week), Ok(tow)) = (date.parse::<u32>(), time.parse::<f64>()) {
        if !(0.0..604_800.0).contains(&tow) {
            return Err(format!(
                "time of week `{}` is outside [0, 604 800) s",
                excerpt(time)
            ));
        }
        return Ok(GPS_EPOCH_1970_S + f64::from(week) * 604_800.0 + tow);
    }
    let no_time = || {
        format!(
            "`{} {}` is no time (YYYY/MM/DD HH:MM:SS.sss or WEEK TOW)",
            excerpt(date),
            excerpt(time)
        )
    };
    let d: Vec<i64> = date
        .split(['/', '-'])
        .map(|s| s.parse().ok())
        .collect::<Option<_>>()
        .ok_or_else(no_time)?;
    let t: Vec<&str> = time.split(':').collect();
    if d.len() != 3 || t.len() != 3 {
        return Err(no_time());
    }
    let (h, mi): (i64, i64) = (
        t[0].parse().map_err(|_| no_time())?,
        t[1].parse().map_err(|_| no_time())?,
    );
    let s: f64 = t[2].parse().map_err(|_| no_time())?;
    if !(1..=9999).contains(&d[0]) || !crate::text::is_date(d[0], d[1], d[2]) {
        return Err(format!(
            "`{}` is not a calendar date (year 1–9999, month 1–12, day within the month)",
            excerpt(date)
        ));
    }
    if !(0..24).contains(&h) || !(0..60).contains(&mi) || !(0.0..61.0).contains(&s) {
        return Err(format!(
            "`{}` is not a time of day (hh 0–23, mm 0–59, ss < 61)",
            excerpt(time)
        ));
    }
    Ok(days_from_civil(d[0], d[1], d[2]) as f64 * 86_400.0 + (h * 3600 + mi * 60) as f64 + s)
}

/// Whether the `.pos` text's column header (the `%` line naming
/// `latitude(deg)`) declares UTC time (`%  UTC  latitude(deg) …`, RTKLIB's
/// `-u` / "time format: UTC" output) rather than GPST: such times are
/// converted to GPST with the leap seconds of their date. `JST` (UTC + 9 h)
/// is refused rather than read 9 hours off; no header or `GPST`: GPST.
fn pos_time_is_utc(text: &str, path: &Path) -> Result<bool> {
    for (i, l) in crate::text::lines(text).enumerate() {
        let Some(rest) = l.trim_start().strip_prefix('%') else {
            continue;
        };
        if !rest.contains("latitude(") {
            continue;
        }
        match rest.split_whitespace().next() {
            Some("UTC") => return Ok(true),
            Some("JST") => {
                return Err(data_error(
                    path,
                    i + 1,
                    "(header)",
                    "JST time stamps are not supported: output GPST or UTC from RTKLIB",
                ));
            }
            _ => return Ok(false),
        }
    }
    Ok(false)
}

/// Column names of a `.pos` line after the two time tokens.
const POS_COLUMNS: [&str; 19] = [
    "latitude",
    "longitude",
    "height",
    "Q",
    "ns",
    "sdn",
    "sde",
    "sdu",
    "sdne",
    "sdeu",
    "sdun",
    "age",
    "ratio",
    "vn",
    "ve",
    "vu",
    "sdvn",
    "sdve",
    "sdvu",
];

/// Read an RTKLIB `.pos` solution file (latitude/longitude/height form).
/// Returns the epochs and the warnings (skipped truncated last line).
///
/// ```
/// let path = std::env::temp_dir().join(format!("aidnav-doc-{}.pos", std::process::id()));
/// std::fs::write(
///     &path,
///     "% GPST latitude(deg) longitude(deg) height(m) Q ns sdn(m) sde(m) sdu(m) ...\n\
///      2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0 0.01 -0.002 0.009 0.05 0.05 0.05\n",
/// )
/// .unwrap();
/// let (fixes, warnings) = aidnav_io::rtklib::read_pos(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert!(warnings.is_empty());
/// assert_eq!((fixes.len(), fixes[0].quality, fixes[0].satellites), (1, 1, 21));
/// assert!((fixes[0].position.latitude_rad.to_degrees() - 40.0966268).abs() < 1e-9);
/// assert!(fixes[0].velocity_ned.is_some());
/// ```
pub fn read_pos(path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_pos_from(&crate::text::read_bytes(path)?, path)
}

/// [`read_pos`] on the file's bytes; `path` names the origin in messages.
pub fn read_pos_from(bytes: &[u8], path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    use crate::text::{excerpt, num};
    let text = crate::text::decode(bytes, path)?;
    let utc = pos_time_is_utc(text, path)?;
    let lines: Vec<(usize, &str)> = crate::text::lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('%'))
        .collect();
    let mut fixes: Vec<GnssFix> = Vec::with_capacity(lines.len());
    let mut warnings = Vec::new();
    // One token buffer for every line.
    let mut tokens: Vec<&str> = Vec::new();
    for (k, &(line, text)) in lines.iter().enumerate() {
        tokens.clear();
        // ASCII text without a vertical tab (the one ASCII byte Unicode
        // calls white space and `u8::is_ascii_whitespace` does not) splits
        // into the same tokens bytewise, several times faster.
        if text.is_ascii() && !text.as_bytes().contains(&0x0B) {
            tokens.extend(text.split_ascii_whitespace());
        } else {
            tokens.extend(text.split_whitespace());
        }
        let is_last = k + 1 == lines.len();
        if tokens.len() < 2 + 13 {
            if is_last {
                warnings.push(truncated_last_line(
                    path,
                    line,
                    format_args!("{} fields", tokens.len()),
                ));
                continue;
            }
            return Err(data_error(
                path,
                line,
                "(line)",
                format!(
                    "{} fields, expected at least 15 (time and 13 solution columns)",
                    tokens.len()
                ),
            ));
        }
        let mut time_s =
            parse_time(tokens[0], tokens[1]).map_err(|m| data_error(path, line, "GPST", m))?;
        if utc {
            time_s += crate::text::gps_minus_utc_s((time_s / 86_400.0).floor() as i64);
        }
        let mut values = [f64::NAN; 19];
        for (i, tok) in tokens[2..].iter().take(19).enumerate() {
            let v = crate::text::parse_f64(tok).ok_or_else(|| {
                data_error(
                    path,
                    line,
                    POS_COLUMNS[i],
                    format!("`{}` is not a number", excerpt(tok)),
                )
            })?;
            if !v.is_finite() {
                return Err(data_error(path, line, POS_COLUMNS[i], "not finite"));
            }
            values[i] = v;
        }
        check_position(path, line, values[0], values[1], values[2])?;
        for (i, name) in [(5, "sdn"), (6, "sde"), (7, "sdu")] {
            if values[i] <= 0.0 {
                return Err(data_error(
                    path,
                    line,
                    name,
                    format!("σ = {} m: a position σ must be > 0", num(values[i])),
                ));
            }
        }
        let has_velocity = tokens.len() >= 2 + 19;
        if has_velocity {
            for (i, name) in [(16, "sdvn"), (17, "sdve"), (18, "sdvu")] {
                if values[i] <= 0.0 {
                    return Err(data_error(
                        path,
                        line,
                        name,
                        format!("σ = {} m/s: a velocity σ must be > 0", num(values[i])),
                    ));
                }
            }
            let speed = Vector3::new(values[13], values[14], values[15]).norm();
            in_range(
                path,
                line,
                "vn",
                speed,
                0.0,
                crate::limits::MAX_SPEED_M_S,
                "m/s",
                "faster than any vehicle a receiver reports",
            )?;
        }
        if let Some(prev) = fixes.last()
            && time_s <= prev.time_s
        {
            return Err(data_error(
                path,
                line,
                "GPST",
                format!(
                    "time {} does not increase (previous epoch {})",
                    crate::text::date_time(time_s),
                    crate::text::date_time(prev.time_s)
                ),
            ));
        }
        fixes.push(GnssFix {
            time_s,
            position: Geodetic {
                latitude_rad: values[0].to_radians(),
                longitude_rad: values[1].to_radians(),
                height_m: values[2],
            },
            quality: values[3] as u8,
            satellites: values[4] as u32,
            position_sigma_neu: Vector3::new(values[5], values[6], values[7]),
            velocity_ned: has_velocity.then(|| Vector3::new(values[13], values[14], -values[15])),
            velocity_sigma_neu: has_velocity
                .then(|| Vector3::new(values[16], values[17], values[18])),
        });
    }
    if fixes.is_empty() {
        return Err(data_error(path, 0, "(file)", "no solution epochs"));
    }
    Ok((fixes, warnings))
}

/// The header and tags of an RTKLIB time-tag file.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeTags {
    /// Start time, GPST seconds since 1970.
    pub start_s: f64,
    /// (ms since start, byte offset) pairs.
    pub tags: Vec<(u32, u32)>,
}

/// Read an RTKLIB `TIMETAG` file.
pub fn read_time_tags(path: &Path) -> Result<TimeTags> {
    read_time_tags_from(&crate::text::read_bytes(path)?, path)
}

/// [`read_time_tags`] on the file's bytes; `path` names the origin in
/// messages. Tags whose milliseconds decrease, or a last tag at 0 ms (every
/// sample would map to one instant), are errors.
pub fn read_time_tags_from(bytes: &[u8], path: &Path) -> Result<TimeTags> {
    let bad = |m: &str| data_error(path, 0, "(binary header)", m.to_string());
    if bytes.len() < 76 || !bytes.starts_with(b"TIMETAG") {
        return Err(bad("not an RTKLIB time-tag file (no TIMETAG header)"));
    }
    let u32_at =
        |o: usize| u32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
    let seconds = f64::from(u32_at(64));
    let mut frac = [0u8; 8];
    frac.copy_from_slice(&bytes[68..76]);
    let fraction = f64::from_le_bytes(frac);
    if !(0.0..1.0).contains(&fraction) {
        return Err(bad("start-time fraction outside [0, 1)"));
    }
    let body = &bytes[76..];
    if !body.len().is_multiple_of(8) {
        return Err(bad("tag records are not whole (u32, u32) pairs"));
    }
    let tags: Vec<(u32, u32)> = body
        .chunks_exact(8)
        .map(|c| {
            (
                u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                u32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            )
        })
        .collect();
    if let Some(k) = tags.windows(2).position(|w| w[1].0 < w[0].0) {
        return Err(data_error(
            path,
            0,
            "(tags)",
            format!(
                "tag {} (byte {}) at {} ms is before the previous tag's {} ms: the milliseconds must not decrease",
                k + 1,
                76 + 8 * (k + 1),
                tags[k + 1].0,
                tags[k].0
            ),
        ));
    }
    if tags.last().is_some_and(|&(ms, _)| ms == 0) {
        return Err(data_error(
            path,
            0,
            "(tags)",
            "the last tag is at 0 ms: the log would span no time (every sample at one instant); a degenerate tag file",
        ));
    }
    Ok(TimeTags {
        start_s: seconds + fraction,
        tags,
    })
}

/// Column names of the raw IMU CSV.
const IMU_COLUMNS: [&str; 7] = [
    "ax [g]",
    "ay [g]",
    "az [g]",
    "gx [deg/s]",
    "gy [deg/s]",
    "gz [deg/s]",
    "tick [ms]",
];

/// Read the data set's raw IMU CSV (accelerometer in g, gyro in deg/s,
/// logger tick in ms) with its time-tag file, dropping the first and the
/// last line as upstream does, and mapping ticks to GPST by the tag file's
/// start and last tag (the README's formula). Returns samples in SI units
/// (sensor frame) and warnings.
///
/// ```
/// let dir = std::env::temp_dir();
/// let csv = dir.join(format!("aidnav-doc-{}.csv", std::process::id()));
/// let tag = dir.join(format!("aidnav-doc-{}.csv.tag", std::process::id()));
/// // The binary tag file: "TIMETAG" header padded to 60 bytes, time-zone
/// // u32, start seconds u32, start fraction f64, then (ms, offset) pairs.
/// let mut t = b"TIMETAG RTKLIB demo5".to_vec();
/// t.resize(60, 0);
/// t.extend(0u32.to_le_bytes());
/// t.extend(1_750_000_000u32.to_le_bytes());
/// t.extend(0.5f64.to_le_bytes());
/// for (ms, offset) in [(0u32, 0u32), (20, 100)] {
///     t.extend(ms.to_le_bytes());
///     t.extend(offset.to_le_bytes());
/// }
/// std::fs::write(&tag, &t).unwrap();
/// // ax ay az [g], gx gy gz [deg/s], tick [ms]; first and last line dropped
/// // (ticks 10 to 30: the 20 ms of the last tag).
/// std::fs::write(&csv, "0,0,1,0,0,0,0\n0,0,1,0,0,0,10\n0,0,1,0,0,0,20\n0,0,1,0,0,0,30\n0,0,1,0,0,0,40\n")
///     .unwrap();
/// let (imu, _warnings) = aidnav_io::rtklib::read_tagged_imu(&csv, &tag).unwrap();
/// std::fs::remove_file(&csv).unwrap();
/// std::fs::remove_file(&tag).unwrap();
/// assert!(!imu.is_empty());
/// assert!(imu.iter().all(|s| (s.specific_force.z - 9.806_65).abs() < 1e-9));
/// assert!(imu.windows(2).all(|w| w[1].time_s > w[0].time_s));
/// ```
pub fn read_tagged_imu(csv_path: &Path, tag_path: &Path) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_tagged_imu_from(
        &crate::text::read_bytes(csv_path)?,
        csv_path,
        &crate::text::read_bytes(tag_path)?,
        tag_path,
    )
}

/// Largest relative difference between the logger's tick clock and the tag
/// file's time accepted: a crystal is off by parts per million, so 10 %
/// means the tag file does not belong to the log.
const MAX_TICK_SCALE_ERROR: f64 = 0.1;

/// Bytes of an IMU CSV from which [`read_tagged_imu_from`] splits and
/// parses the file in two halves on two threads (about a minute of a
/// 100 Hz log; below it a thread costs more than it saves).
const PARALLEL_IMU_BYTES: usize = 256 * 1024;

/// Where [`read_tagged_imu_from`] cuts a large text in two: just after the
/// first line terminator at or after the middle byte (after both bytes of
/// a CR LF), so that the lines of the two parts are the lines of the
/// whole. None when no terminator follows the middle or nothing follows it.
fn line_boundary_near_middle(text: &str) -> Option<usize> {
    let bytes = text.as_bytes();
    let middle = bytes.len() / 2;
    let at = middle + memchr::memchr2(b'\n', b'\r', &bytes[middle..])?;
    let end = if bytes[at..].starts_with(b"\r\n") {
        at + 2
    } else {
        at + 1
    };
    (end < bytes.len()).then_some(end)
}

/// Parsed IMU lines: each line's sample (SI, body of the sensor) with its
/// tick \[ms\] in place of the time (the tick-to-time scale needs the last
/// line), and its |f| \[g\] (the median check's).
#[derive(Debug, Default)]
struct ParsedImu {
    samples: Vec<ImuSample>,
    norms: Vec<f64>,
}

/// Parse `lines[range]` of an IMU CSV (index i is line i + 1) into a
/// [`ParsedImu`] with room for `capacity` lines: the lines up to the first
/// error, and that error. The tick of the range's first line is checked
/// against nothing (the caller checks it against the line before).
fn parse_imu_lines(
    lines: &[&str],
    range: std::ops::Range<usize>,
    csv_path: &Path,
    capacity: usize,
) -> (ParsedImu, Option<IoError>) {
    let mut parsed = ParsedImu {
        samples: Vec::with_capacity(capacity),
        norms: Vec::with_capacity(capacity),
    };
    for i in range {
        let previous = parsed.samples.last().map(|s| (i, s.time_s));
        match parse_imu_line(lines[i], i + 1, csv_path, previous) {
            Ok((sample, norm)) => {
                parsed.samples.push(sample);
                parsed.norms.push(norm);
            }
            Err(e) => return (parsed, Some(e)),
        }
    }
    (parsed, None)
}

/// Parse line number `line` of an IMU CSV (text `l`), checked in this
/// order: 7 fields, each a finite number, the gyro's rate, |f| ≤ 16 g, the
/// tick increasing from `previous` (the line before when known: its number
/// and tick). The sample holds the tick as its time; with it |f| \[g\].
fn parse_imu_line(
    l: &str,
    line: usize,
    csv_path: &Path,
    previous: Option<(usize, f64)>,
) -> Result<(ImuSample, f64)> {
    use crate::text::num;
    let v = match plain_imu_fields(l) {
        Some(v) => v,
        None => imu_fields(l, line, csv_path)?,
    };
    let angular_rate = Vector3::new(v[3], v[4], v[5]).map(f64::to_radians);
    check_rate(
        csv_path,
        line,
        "gx [deg/s]",
        &angular_rate,
        " — are the gyro columns scaled (milli-degrees/s)?",
    )?;
    // Units that cannot be right: a specific force in m/s² where g was
    // expected, or a rate in rad/s that saturates no MEMS gyro.
    let f_norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if f_norm > 16.0 {
        return Err(data_error(
            csv_path,
            line,
            "ax [g]",
            format!(
                "|f| = {} g: more than 16 g — are the accelerometer columns in m/s² instead of g?",
                num(f_norm)
            ),
        ));
    }
    if let Some((prev_line, prev_tick)) = previous {
        check_tick(csv_path, line, v[6], prev_line, prev_tick)?;
    }
    let sample = ImuSample {
        time_s: v[6],
        specific_force: Vector3::new(v[0], v[1], v[2]) * G0,
        angular_rate,
    };
    Ok((sample, f_norm))
}

/// The seven values of an IMU line made of plain decimals only (exactly
/// seven comma-separated fields, each [`crate::text::parse_plain_decimal`]:
/// no space, no exponent): what [`imu_fields`] gives for it, bit for bit,
/// in one pass over the bytes (no trimming, splitting or second scan of a
/// field). None for any other line.
fn plain_imu_fields(l: &str) -> Option<[f64; 7]> {
    let bytes = l.as_bytes();
    let mut v = [0.0; 7];
    let mut i = 0;
    for (k, slot) in v.iter_mut().enumerate() {
        let (x, len) = crate::text::plain_decimal_prefix(&bytes[i..])?;
        *slot = x;
        i += len;
        if k < 6 {
            if bytes.get(i) != Some(&b',') {
                return None;
            }
            i += 1;
        }
    }
    (i == bytes.len()).then_some(v)
}

/// The seven values of IMU line number `line` (text `l`), checked in this
/// order: 7 fields, each a finite number.
fn imu_fields(l: &str, line: usize, csv_path: &Path) -> Result<[f64; 7]> {
    use crate::text::excerpt;
    // The fields in place (no Vec per line), counted for the message.
    let mut fields = [""; 7];
    let mut count = 0;
    for f in l.trim().split(',') {
        if let Some(slot) = fields.get_mut(count) {
            *slot = f;
        }
        count += 1;
    }
    if count != 7 {
        return Err(data_error(
            csv_path,
            line,
            "(line)",
            format!("{count} fields, expected 7 (ax ay az [g], gx gy gz [deg/s], tick [ms])"),
        ));
    }
    let mut v = [0.0; 7];
    for (k, f) in fields.iter().enumerate() {
        v[k] = crate::text::parse_f64(f.trim()).ok_or_else(|| {
            data_error(
                csv_path,
                line,
                IMU_COLUMNS[k],
                format!("`{}` is not a number", excerpt(f)),
            )
        })?;
        if !v[k].is_finite() {
            return Err(data_error(csv_path, line, IMU_COLUMNS[k], "not finite"));
        }
    }
    Ok(v)
}

/// The tick of line `line` must increase from that of `prev_line`.
fn check_tick(
    csv_path: &Path,
    line: usize,
    tick: f64,
    prev_line: usize,
    prev_tick: f64,
) -> Result<()> {
    use crate::text::num;
    if tick <= prev_tick {
        return Err(data_error(
            csv_path,
            line,
            "tick [ms]",
            format!(
                "tick {} does not increase (line {prev_line}: {})",
                num(tick),
                num(prev_tick)
            ),
        ));
    }
    Ok(())
}

/// [`read_tagged_imu`] on the CSV's and the tag file's bytes; the paths name
/// the origins in messages.
pub fn read_tagged_imu_from(
    csv: &[u8],
    csv_path: &Path,
    tag: &[u8],
    tag_path: &Path,
) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_tagged_imu_checked_from(csv, csv_path, tag, tag_path, CheckLevel::Error)
}

/// [`read_tagged_imu_from`] with the plausibility check of the units (the
/// median specific force about 1 g) acting as `unit_checks` says.
pub fn read_tagged_imu_checked_from(
    csv: &[u8],
    csv_path: &Path,
    tag: &[u8],
    tag_path: &Path,
    unit_checks: CheckLevel,
) -> Result<(Vec<ImuSample>, Vec<String>)> {
    use crate::text::num;
    let tags = read_time_tags_from(tag, tag_path)?;
    let last_tag_ms = tags
        .tags
        .last()
        .map(|&(ms, _)| ms)
        .ok_or_else(|| data_error(tag_path, 0, "(tags)", "no time tags"))?;
    let text = crate::text::decode(csv, csv_path)?;
    // A large file is cut at a line boundary near its middle; each part is
    // split into lines and parsed on its own thread. The second part's
    // lines are numbered from 1 until the first part's count is known
    // (its error, if any, is made again below with the line's number).
    // Each part stops at its first error; the error reported is the first
    // in file order, as a parse from the top finds it: the first part's,
    // else the tick of the second part's first line against the first
    // part's last (the last check of that line), else the second part's.
    let boundary = if text.len() >= PARALLEL_IMU_BYTES {
        line_boundary_near_middle(text)
    } else {
        None
    };
    // The first part is parsed from its second line (the file's first is
    // not parsed), the whole file's body from line 2 to the last but one.
    let body_start = 1;
    let (lines, (mut parsed, first_error), second) = match boundary {
        Some(cut) => std::thread::scope(|s| {
            let second = s.spawn(|| {
                let lines: Vec<&str> = crate::text::lines(&text[cut..]).collect();
                // The file's last line is not parsed.
                let body = 0..lines.len().saturating_sub(1);
                let parsed = parse_imu_lines(&lines, body.clone(), csv_path, body.len());
                (lines, parsed)
            });
            let lines: Vec<&str> = crate::text::lines(&text[..cut]).collect();
            // Room for about as many lines again: the second part is
            // appended without a copy of the first.
            let first = parse_imu_lines(&lines, body_start..lines.len(), csv_path, 2 * lines.len());
            let second = second
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (lines, first, Some(second))
        }),
        None => {
            let lines: Vec<&str> = crate::text::lines(text).collect();
            let body = body_start..lines.len().saturating_sub(1);
            let first = parse_imu_lines(&lines, body.clone(), csv_path, body.len());
            (lines, first, None)
        }
    };
    let line_count = lines.len() + second.as_ref().map_or(0, |(l, _)| l.len());
    let mut warnings = Vec::new();
    if line_count < 4 {
        return Err(data_error(
            csv_path,
            0,
            "(file)",
            format!("{line_count} lines: too short for an IMU log"),
        ));
    }
    warnings.push(format!(
        "{}: first and last line dropped (logger artefact, as upstream)",
        csv_path.display()
    ));
    if let Some(e) = first_error {
        return Err(e);
    }
    let (rest, second_error) = match second {
        Some((rest_lines, (rest, error))) => {
            // The second part's error again, numbered in the file: the
            // line's number and the line before's (as the parse from the
            // top passes it) are offset by the first part's lines.
            let error = error.map(|_| {
                let j = rest.samples.len();
                let previous = j
                    .checked_sub(1)
                    .map(|p| (lines.len() + j, rest.samples[p].time_s));
                parse_imu_line(rest_lines[j], lines.len() + j + 1, csv_path, previous)
                    .err()
                    .unwrap_or_else(|| {
                        data_error(csv_path, lines.len() + j + 1, "(line)", "unreadable line")
                    })
            });
            (rest, error)
        }
        None => (ParsedImu::default(), None),
    };
    if let (Some(last), Some(next)) = (parsed.samples.last(), rest.samples.first()) {
        // The second part's first line is the line after the first part's last.
        let line = body_start + parsed.samples.len() + 1;
        check_tick(csv_path, line, next.time_s, line - 1, last.time_s)?;
    }
    if let Some(e) = second_error {
        return Err(e);
    }
    parsed.samples.extend_from_slice(&rest.samples);
    parsed.norms.extend_from_slice(&rest.norms);
    let ParsedImu {
        mut samples,
        mut norms,
    } = parsed;
    // Units that cannot be right: a road vehicle's specific force has a
    // median magnitude of about 1 g; a median near 9.8 means the columns are
    // in m/s², not g.
    // The element a full sort puts in the middle (the order is total).
    let middle = norms.len() / 2;
    let median = *norms.select_nth_unstable_by(middle, f64::total_cmp).1;
    if !(0.5..=2.0).contains(&median) {
        let implausible = data_error(
            csv_path,
            body_start + 1,
            "ax [g]",
            format!(
                "median |f| = {median:.3} in the file's unit, expected ≈ 1 g{}",
                if (5.0..15.0).contains(&median) {
                    " — are the accelerometer columns in m/s² instead of g?"
                } else {
                    ""
                }
            ),
        );
        unit_checks.apply(Err(implausible), &mut warnings)?;
    }
    // The samples hold their ticks as times until here.
    let first_tick = samples[0].time_s;
    let last_tick = samples[samples.len() - 1].time_s;
    let scale = (f64::from(last_tag_ms) / 1000.0) / ((last_tick - first_tick) / 1000.0);
    if !scale.is_finite() || (scale - 1.0).abs() > MAX_TICK_SCALE_ERROR {
        return Err(data_error(
            tag_path,
            0,
            "(tags)",
            format!(
                "the last tag ({last_tag_ms} ms) against the CSV's ticks ({} ms) gives a tick-to-time scale of {}: more than {} % from 1, the tag file does not fit the log",
                num(last_tick - first_tick),
                num(scale),
                MAX_TICK_SCALE_ERROR * 100.0
            ),
        ));
    }
    if !(0.99..=1.01).contains(&scale) {
        warnings.push(format!(
            "{}: tick-to-time scale {scale:.6} is far from 1",
            tag_path.display()
        ));
    }
    for s in &mut samples {
        let tick = s.time_s;
        s.time_s = tags.start_s + (tick - first_tick) / 1000.0 * scale;
    }
    Ok((samples, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/rtklibexplorer-gnss-imu/drive_0708")
    }

    #[test]
    fn calendar_time_matches_the_gps_week_form() {
        // 2025/07/08 19:34:18.499 GPST is GPS week 2374, TOW 243 258.499.
        let a = parse_time("2025/07/08", "19:34:18.499").unwrap();
        let b = parse_time("2374", "243258.499").unwrap();
        assert!((a - b).abs() < 1e-6, "{a} {b}");
        assert!(parse_time("2025/13/08", "19:34:18").is_err());
    }

    #[test]
    fn reads_the_recorded_drive() {
        // The data set lives beside the repository (../shared, as in CI).
        let dir = data();
        let (fixes, warnings) = read_pos(&dir.join("gnss_1934_sf.pos")).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(fixes.len(), 2197);
        assert_eq!(fixes.iter().filter(|f| f.quality == 1).count(), 2189);
        assert!((fixes[0].position.latitude_rad.to_degrees() - 40.0966268).abs() < 1e-9);
        let (imu, _) =
            read_tagged_imu(&dir.join("imu_1934.csv"), &dir.join("imu_1934.csv.tag")).unwrap();
        assert_eq!(imu.len(), 54_858);
        // README: IMU start 19:34:21.854 GPST, end 19:43:30.585.
        let start = parse_time("2025/07/08", "19:34:21.854").unwrap();
        let end = parse_time("2025/07/08", "19:43:30.585").unwrap();
        assert!(
            (imu[0].time_s - start).abs() < 2e-3,
            "{}",
            imu[0].time_s - start
        );
        assert!((imu[imu.len() - 1].time_s - end).abs() < 2e-3);
        // At rest the sensor z axis reads about +1 g.
        assert!((imu[0].specific_force.z / G0 - 1.0).abs() < 0.05);
    }

    #[test]
    fn malformed_files_name_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.pos");
        let good = "2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0 0.01 -0.002 0.009 0.05 0.05 0.05";
        let next = good.replace("18.499", "18.749");
        // Truncated last line: warning.
        std::fs::write(
            &p,
            format!("% header\n{good}\n{next}\n2025/07/08 19:34:19.0 40.1"),
        )
        .unwrap();
        let (f, w) = read_pos(&p).unwrap();
        assert_eq!(f.len(), 2);
        assert!(w[0].contains(":4: truncated last line"), "{w:?}");
        // Truncated line in the middle: error.
        std::fs::write(&p, format!("2025/07/08 19:34:19.0 40.1\n{good}\n")).unwrap();
        let e = read_pos(&p).unwrap_err().to_string();
        assert!(e.contains("x.pos:1: column `(line)`"), "{e}");
        // Time going backwards.
        std::fs::write(&p, format!("{next}\n{good}\n")).unwrap();
        let e = read_pos(&p).unwrap_err().to_string();
        assert!(
            e.contains(":2: column `GPST`: time") && e.contains("does not increase"),
            "{e}"
        );
        // σ = 0.
        std::fs::write(
            &p,
            format!("{}\n", good.replace("0.0099 0.0099 0.01", "0.0099 0 0.01")),
        )
        .unwrap();
        let e = read_pos(&p).unwrap_err().to_string();
        assert!(e.contains("column `sde`: σ = 0"), "{e}");
        // NaN.
        std::fs::write(&p, format!("{}\n", good.replace("1601.474", "NaN"))).unwrap();
        let e = read_pos(&p).unwrap_err().to_string();
        assert!(e.contains("column `height`"), "{e}");
        // IMU in m/s² instead of g.
        let csv = dir.path().join("i.csv");
        let tag = dir.path().join("i.csv.tag");
        let mut t = b"TIMETAG RTKLIB demo5".to_vec();
        t.resize(60, 0);
        t.extend(0u32.to_le_bytes());
        t.extend(1_750_000_000u32.to_le_bytes());
        t.extend(0.5f64.to_le_bytes());
        for (ms, off) in [(0u32, 0u32), (30, 100)] {
            t.extend(ms.to_le_bytes());
            t.extend(off.to_le_bytes());
        }
        std::fs::write(&tag, &t).unwrap();
        std::fs::write(
            &csv,
            "0,0,9.8,0,0,0,0\n0,0,9.81,0,0,0,10\n0,0,9.81,0,0,0,20\n0,0,9.8,0,0,0,30\n0,0,9.8,0,0,0,40\n",
        )
        .unwrap();
        let e = read_tagged_imu(&csv, &tag).unwrap_err().to_string();
        assert!(
            e.contains("i.csv:2: column `ax [g]`") && e.contains("m/s²"),
            "{e}"
        );
        std::fs::write(
            &csv,
            "0,0,1,0,0,0,0\n0,0,1,0,0,0,10\n0,0,1,0,0,0,10\n0,0,1,0,0,0,30\n0,0,1,0,0,0,40\n",
        )
        .unwrap();
        let e = read_tagged_imu(&csv, &tag).unwrap_err().to_string();
        assert!(e.contains("i.csv:3: column `tick [ms]`"), "{e}");
    }

    const GOOD: &str = "2025/07/08 19:34:18.499 40.0966268 -105.1474483 1601.474 1 21 0.0099 0.0099 0.01 0 0 0 0 0 0.01 -0.002 0.009 0.05 0.05 0.05";

    fn pos(text: &str) -> Result<(Vec<GnssFix>, Vec<String>)> {
        read_pos_from(text.as_bytes(), Path::new("x.pos"))
    }

    /// A tag file with the given (ms, offset) records.
    fn tag_bytes(records: &[(u32, u32)]) -> Vec<u8> {
        let mut t = b"TIMETAG RTKLIB demo5".to_vec();
        t.resize(60, 0);
        t.extend(0u32.to_le_bytes());
        t.extend(1_750_000_000u32.to_le_bytes());
        t.extend(0.5f64.to_le_bytes());
        for (ms, off) in records {
            t.extend(ms.to_le_bytes());
            t.extend(off.to_le_bytes());
        }
        t
    }

    fn imu(csv: &str, tags: &[(u32, u32)]) -> Result<(Vec<ImuSample>, Vec<String>)> {
        read_tagged_imu_from(
            csv.as_bytes(),
            Path::new("i.csv"),
            &tag_bytes(tags),
            Path::new("i.csv.tag"),
        )
    }

    const IMU_CSV: &str =
        "0,0,1,0,0,0,0\n0,0,1,0,0,0,10\n0,0,1,0,0,0,20\n0,0,1,0,0,0,30\n0,0,1,0,0,0,40\n";

    #[test]
    fn impossible_calendar_dates_are_errors() {
        // 2025/02/30 used to be read as 2025-03-02.
        let e = pos(&GOOD.replace("2025/07/08", "2025/02/30"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("x.pos:1: column `GPST`: `2025/02/30` is not a calendar date"),
            "{e}"
        );
        assert!(pos(&GOOD.replace("2025/07/08", "2024/02/29")).is_ok());
        assert!(pos(&GOOD.replace("2025/07/08", "2025/04/31")).is_err());
    }

    #[test]
    fn a_degenerate_tag_file_is_an_error() {
        // Last tag at 0 ms: every sample would map to one instant.
        let e = imu(IMU_CSV, &[(0, 0), (0, 100)]).unwrap_err().to_string();
        assert!(
            e.contains("i.csv.tag:0: column `(tags)`") && e.contains("degenerate"),
            "{e}"
        );
        // Decreasing milliseconds.
        let e = imu(IMU_CSV, &[(10, 0), (5, 50), (20, 100)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("must not decrease"), "{e}");
        // A tag file that does not fit the log's ticks.
        let e = imu(IMU_CSV, &[(0, 0), (2000, 100)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not fit the log"), "{e}");
        assert!(imu(IMU_CSV, &[(0, 0), (20, 100)]).is_ok());
    }

    /// A file large enough to be parsed in two halves reports the error a
    /// parse from the top finds (every line of `parse_imu_lines` over the
    /// whole body at once): the first in file order, whichever half holds
    /// it, and a tick that does not increase across the halves' boundary.
    #[test]
    fn a_file_parsed_in_halves_reports_the_first_error_in_file_order() {
        // About twice the bytes from which the file is cut in two.
        let n = PARALLEL_IMU_BYTES / 16 + 11;
        let line = |k: usize| format!("0.01,0.02,1.0,0.1,-0.2,0.3,{}", 1000 + 10 * k);
        let good: Vec<String> = (0..n).map(line).collect();
        let tags = [(0, 0), (10 * (n as u32 - 3), 100)];
        let whole = |lines: &[String]| lines.join("\n") + "\n";
        let text = whole(&good);
        assert!(text.len() >= 2 * PARALLEL_IMU_BYTES);
        let cut = line_boundary_near_middle(&text).unwrap();
        let (samples, _) = imu(&whole(&good), &tags).unwrap();
        assert_eq!(samples.len(), n - 2);
        let from_the_top = |lines: &[String]| {
            let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
            parse_imu_lines(&refs, 1..refs.len() - 1, Path::new("i.csv"), 0)
                .1
                .map(|e| e.to_string())
        };
        // The second part starts at line `boundary`. The spoiled lines keep
        // their length, so the cut stays where it is.
        let boundary = crate::text::lines(&text[..cut]).count() + 1;
        let bad_tick = |lines: &mut Vec<String>, at: usize| {
            let (head, tick) = lines[at - 1].rsplit_once(',').unwrap();
            lines[at - 1] = format!("{head},{:0>w$}", 5, w = tick.len());
        };
        let bad_field = |lines: &mut Vec<String>, at: usize| {
            lines[at - 1] = lines[at - 1].replacen("0.02", "0.0x", 1);
        };
        type Spoil = fn(&mut Vec<String>, usize);
        let cases: [&[(usize, Spoil)]; 6] = [
            &[(boundary, bad_tick)],
            &[(boundary, bad_field)],
            &[(boundary - 1, bad_field)],
            &[(boundary + 5, bad_field), (boundary - 3, bad_tick)],
            &[(n - 3, bad_field), (boundary, bad_tick)],
            &[(boundary + 1, bad_tick), (boundary + 2, bad_field)],
        ];
        for spoils in cases {
            let mut lines = good.clone();
            for (at, spoil) in spoils {
                spoil(&mut lines, *at);
            }
            assert_eq!(line_boundary_near_middle(&whole(&lines)), Some(cut));
            let expected = from_the_top(&lines).expect("an error");
            let e = imu(&whole(&lines), &tags).unwrap_err().to_string();
            assert_eq!(e, expected);
        }
        // The boundary tick names both lines.
        let mut lines = good.clone();
        bad_tick(&mut lines, boundary);
        let e = imu(&whole(&lines), &tags).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "i.csv:{boundary}: column `tick [ms]`: tick 5 does not increase (line {}:",
                boundary - 1
            )),
            "{e}"
        );
    }

    /// The plain-decimal path of an IMU line gives what the general one
    /// gives, bit for bit, and declines every line it does not fully read
    /// (spaces, exponents, signs, field counts, stray bytes).
    #[test]
    fn plain_imu_lines_read_as_the_general_parse_reads_them() {
        let mut next = crate::xorshift(0x2545_F491_4F6C_DD1D);
        let pieces = [
            "0.119",
            "-0.671",
            "261906",
            "+1.5",
            "1e3",
            " 0.1",
            "0.1 ",
            "",
            "-",
            ".5",
            "7.",
            "1.2.3",
            "x",
            "nan",
            "inf",
            "0000000000000001",
            "123456789012345",
            "-0",
        ];
        let mut lines: Vec<String> = vec![
            "0.119,0.027,1.013,-0.671,3.082,0.198,261906".into(),
            "0.119,0.027,1.013,-0.671,3.082,0.198,261906,".into(),
            "0.119,0.027,1.013,-0.671,3.082,0.198".into(),
            " 0.119,0.027,1.013,-0.671,3.082,0.198,261906\t".into(),
            "0.119,0.027,1.013,-0.671,3.082,0.198,261906\r".into(),
        ];
        for _ in 0..20_000 {
            let r = next();
            let fields = 6 + (r % 3) as usize;
            let line: Vec<String> = (0..fields)
                .map(|_| {
                    let r = next();
                    if r.is_multiple_of(4) {
                        pieces[(r >> 8) as usize % pieces.len()].to_string()
                    } else {
                        let digits = 1 + (r >> 8) % 15;
                        let mut s = if r & 0x10 != 0 {
                            "-".to_string()
                        } else {
                            String::new()
                        };
                        let point = (r >> 16) % (digits + 1);
                        for d in 0..digits {
                            if d == point && d > 0 {
                                s.push('.');
                            }
                            s.push(char::from(b'0' + (next() % 10) as u8));
                        }
                        s
                    }
                })
                .collect();
            lines.push(line.join(","));
        }
        let path = Path::new("imu.csv");
        let mut plain = 0;
        for l in &lines {
            let general = imu_fields(l, 1, path);
            if let Some(v) = plain_imu_fields(l) {
                plain += 1;
                let general = general.unwrap_or_else(|e| panic!("`{l}`: {e}"));
                assert_eq!(v.map(f64::to_bits), general.map(f64::to_bits), "`{l}`");
            }
            let plain_shape = !l.contains(['e', 'E', ' ', '\t', '\r', 'n', 'i', 'x'])
                && l.split(',').count() == 7
                && l.split(',').all(|f| {
                    let b = f.strip_prefix(['-', '+']).unwrap_or(f);
                    let digits = b.bytes().filter(u8::is_ascii_digit).count();
                    (1..=15).contains(&digits) && b.matches('.').count() <= 1
                });
            assert_eq!(plain_imu_fields(l).is_some(), plain_shape, "`{l}`");
        }
        assert!(plain > 1_000, "{plain} plain lines");
    }

    /// Cutting a text where [`line_boundary_near_middle`] says keeps its
    /// lines: those of the two parts are those of the whole, whatever the
    /// terminators (LF, CR LF, lone CR, empty lines).
    #[test]
    fn the_cut_near_the_middle_keeps_the_lines() {
        let mut next = crate::xorshift(0x1234_5678_9ABC_DEF1);
        let mut cut_somewhere = 0;
        for _ in 0..5_000 {
            let len = (next() % 40) as usize;
            let text: String = (0..len)
                .map(|_| match next() % 6 {
                    0 => '\n',
                    1 => '\r',
                    2 => 'x',
                    3 => ',',
                    _ => '1',
                })
                .collect();
            let whole: Vec<&str> = crate::text::lines(&text).collect();
            if let Some(cut) = line_boundary_near_middle(&text) {
                cut_somewhere += 1;
                assert!(cut >= text.len() / 2 && cut < text.len());
                let parts: Vec<&str> = crate::text::lines(&text[..cut])
                    .chain(crate::text::lines(&text[cut..]))
                    .collect();
                assert_eq!(parts, whole, "{text:?} cut at {cut}");
            }
        }
        assert!(cut_somewhere > 1_000);
    }

    /// The `.pos` reader's bytewise split of ASCII lines gives the tokens
    /// `split_whitespace` gives, whatever ASCII byte separates them (but
    /// the vertical tab, which goes to `split_whitespace`).
    #[test]
    fn ascii_pos_lines_split_as_split_whitespace_splits_them() {
        for c in (0u8..128).filter(|&c| c != 0x0B) {
            let c = char::from(c);
            let line = format!("{c}2025/07/08 {c}{c}19:34:18.499{c}40.1 {c}");
            assert_eq!(
                line.split_ascii_whitespace().collect::<Vec<_>>(),
                line.split_whitespace().collect::<Vec<_>>(),
                "{c:?}"
            );
        }
        let line = "1\u{b}2";
        assert_ne!(
            line.split_ascii_whitespace().count(),
            line.split_whitespace().count()
        );
    }

    #[test]
    fn a_scaled_gyro_is_refused_at_its_line() {
        // Gyro ×1000 (milli-degrees/s): 20 000 °/s ≈ 349 rad/s.
        let csv = IMU_CSV.replace("0,0,1,0,0,0,20", "0,0,1,0,0,20000,20");
        let e = imu(&csv, &[(0, 0), (20, 100)]).unwrap_err().to_string();
        assert!(
            e.starts_with("i.csv:3: column `gx [deg/s]`: |ω| = 349"),
            "{e}"
        );
    }

    #[test]
    fn impossible_positions_name_line_and_column() {
        let e = pos(&format!(
            "{GOOD}\n{}",
            GOOD.replace(
                "18.499 40.0966268 -105.1474483 1601.474",
                "19.0 40.0966268 -105.1474483 160147.4"
            )
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("x.pos:2: column `height`: 160147.4 m is outside"),
            "{e}"
        );
        let e = pos(&GOOD.replace("0.01 -0.002 0.009", "5000 -0.002 0.009"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("column `vn`"), "{e}");
    }

    #[test]
    fn bom_cr_only_and_invalid_utf8() {
        let next = GOOD.replace("18.499", "18.749");
        let (f, _) = pos(&format!("\u{FEFF}% header\r{GOOD}\r{next}\r")).unwrap();
        assert_eq!(f.len(), 2);
        let mut bytes = format!("{GOOD}\n").into_bytes();
        bytes.extend(b"2025/07/08 \xFF");
        let e = read_pos_from(&bytes, Path::new("x.pos"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!(
                "x.pos:2: column `(text)`: invalid UTF-8 at byte {}",
                GOOD.len() + 12
            )),
            "{e}"
        );
        let e = imu(
            "\u{FEFF}0,0,1,0,0,0,0\r0,0,1,0,0,0,10\r0,0,1,0,0,0,20\r0,0,1,0,0,0,30\r0,0,1,0,0,0,40",
            &[(0, 0), (20, 100)],
        );
        assert_eq!(e.unwrap().0.len(), 3);
    }

    #[test]
    fn large_numbers_and_long_tokens_stay_short() {
        let huge = format!("-1{}", "0".repeat(308));
        let e = pos(&GOOD.replace("0.0099 0.0099 0.01", &format!("{huge} 0.0099 0.01")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("σ = -1e308 m"), "{e}");
        let long = "x".repeat(5000);
        let e = pos(&GOOD.replace("1601.474", &long))
            .unwrap_err()
            .to_string();
        assert!(e.len() < 200 && e.contains('…'), "{e}");
    }
}
