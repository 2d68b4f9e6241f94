//! Readers for RTKLIB files (spec 40): solution files (`.pos`) and the raw
//! IMU CSV of the rtklibexplorer data set with its binary RTKLIB time-tag
//! file (`.csv.tag`).
//!
//! Time: GPST as seconds since 1970-01-01 (the tag file's convention; a
//! `.pos` calendar time `YYYY/MM/DD HH:MM:SS.sss` in GPST maps to the same
//! scale by a plain calendar conversion, no leap seconds).
//!
//! Validation: every error names the file, the line and the column; a
//! truncated *last* line is skipped with a warning (a logger artefact), a
//! truncated line elsewhere, a non-finite value, a σ ≤ 0, a latitude outside
//! ±90°, and time that does not increase are errors.

use std::path::Path;

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::error::{IoError, Result};

pub use aidnav_ins::samples::{GnssFix, ImuSample};

/// Standard gravity, the unit of the data set's accelerometer columns.
const G0: f64 = 9.806_65;

/// Days from 1970-01-01 to a proleptic Gregorian date (Howard Hinnant's
/// algorithm).
pub(crate) fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// GPS week 0 began 1980-01-06.
const GPS_EPOCH_1970_S: f64 = 315_964_800.0;

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

/// The whole file as text, or a read error naming it.
pub(crate) fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Parse `YYYY/MM/DD HH:MM:SS.sss` or `WEEK TOW` (two tokens) to seconds.
fn parse_time(date: &str, time: &str) -> Option<f64> {
    if let (Ok(week), Ok(tow)) = (date.parse::<u32>(), time.parse::<f64>()) {
        return Some(GPS_EPOCH_1970_S + f64::from(week) * 604_800.0 + tow);
    }
    let d: Vec<i64> = date
        .split(['/', '-'])
        .map(|s| s.parse().ok())
        .collect::<Option<_>>()?;
    let t: Vec<&str> = time.split(':').collect();
    if d.len() != 3 || t.len() != 3 {
        return None;
    }
    let (h, mi): (i64, i64) = (t[0].parse().ok()?, t[1].parse().ok()?);
    let s: f64 = t[2].parse().ok()?;
    if !(1..=12).contains(&d[1])
        || !(1..=31).contains(&d[2])
        || !(0..24).contains(&h)
        || !(0..60).contains(&mi)
        || !(0.0..61.0).contains(&s)
    {
        return None;
    }
    Some(days_from_civil(d[0], d[1], d[2]) as f64 * 86_400.0 + (h * 3600 + mi * 60) as f64 + s)
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
    let text = read_text(path)?;
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('%'))
        .collect();
    let mut fixes: Vec<GnssFix> = Vec::with_capacity(lines.len());
    let mut warnings = Vec::new();
    for (k, &(line, text)) in lines.iter().enumerate() {
        let tokens: Vec<&str> = text.split_whitespace().collect();
        let is_last = k + 1 == lines.len();
        if tokens.len() < 2 + 13 {
            if is_last {
                warnings.push(format!(
                    "{}:{line}: truncated last line skipped ({} fields)",
                    path.display(),
                    tokens.len()
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
        let time_s = parse_time(tokens[0], tokens[1]).ok_or_else(|| {
            data_error(
                path,
                line,
                "GPST",
                format!(
                    "`{} {}` is no time (YYYY/MM/DD HH:MM:SS.sss or WEEK TOW)",
                    tokens[0], tokens[1]
                ),
            )
        })?;
        let mut values = [f64::NAN; 19];
        for (i, tok) in tokens[2..].iter().take(19).enumerate() {
            let v: f64 = tok.parse().map_err(|_| {
                data_error(
                    path,
                    line,
                    POS_COLUMNS[i],
                    format!("`{tok}` is not a number"),
                )
            })?;
            if !v.is_finite() {
                return Err(data_error(path, line, POS_COLUMNS[i], "not finite"));
            }
            values[i] = v;
        }
        if values[0].abs() > 90.0 {
            return Err(data_error(
                path,
                line,
                "latitude",
                format!(
                    "{} deg is outside ±90 (x/y/z ECEF files are not supported)",
                    values[0]
                ),
            ));
        }
        if values[1].abs() > 360.0 {
            return Err(data_error(
                path,
                line,
                "longitude",
                format!("{} deg is outside ±360", values[1]),
            ));
        }
        for (i, name) in [(5, "sdn"), (6, "sde"), (7, "sdu")] {
            if values[i] <= 0.0 {
                return Err(data_error(
                    path,
                    line,
                    name,
                    format!("σ = {} m: a position σ must be > 0", values[i]),
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
                        format!("σ = {} m/s: a velocity σ must be > 0", values[i]),
                    ));
                }
            }
        }
        if let Some(prev) = fixes.last()
            && time_s <= prev.time_s
        {
            return Err(data_error(
                path,
                line,
                "GPST",
                format!(
                    "time {time_s:.3} s does not increase (previous epoch {:.3} s)",
                    prev.time_s
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
    let bytes = std::fs::read(path).map_err(|source| IoError::Read {
        path: path.to_path_buf(),
        source,
    })?;
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
    if body.len() % 8 != 0 {
        return Err(bad("tag records are not whole (u32, u32) pairs"));
    }
    let tags = body
        .chunks_exact(8)
        .map(|c| {
            (
                u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                u32::from_le_bytes([c[4], c[5], c[6], c[7]]),
            )
        })
        .collect();
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
/// for (ms, offset) in [(0u32, 0u32), (30, 100)] {
///     t.extend(ms.to_le_bytes());
///     t.extend(offset.to_le_bytes());
/// }
/// std::fs::write(&tag, &t).unwrap();
/// // ax ay az [g], gx gy gz [deg/s], tick [ms]; first and last line dropped.
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
    let tags = read_time_tags(tag_path)?;
    let last_tag_ms = tags
        .tags
        .last()
        .map(|&(ms, _)| ms)
        .ok_or_else(|| data_error(tag_path, 0, "(tags)", "no time tags"))?;
    let text = read_text(csv_path)?;
    let lines: Vec<&str> = text.lines().collect();
    let mut warnings = Vec::new();
    if lines.len() < 4 {
        return Err(data_error(
            csv_path,
            0,
            "(file)",
            format!("{} lines: too short for an IMU log", lines.len()),
        ));
    }
    warnings.push(format!(
        "{}: first and last line dropped (logger artefact, as upstream)",
        csv_path.display()
    ));
    let mut raw: Vec<(usize, [f64; 6], f64)> = Vec::with_capacity(lines.len());
    for (i, l) in lines.iter().enumerate().take(lines.len() - 1).skip(1) {
        let line = i + 1;
        let fields: Vec<&str> = l.trim().split(',').collect();
        if fields.len() != 7 {
            return Err(data_error(
                csv_path,
                line,
                "(line)",
                format!(
                    "{} fields, expected 7 (ax ay az [g], gx gy gz [deg/s], tick [ms])",
                    fields.len()
                ),
            ));
        }
        let mut v = [0.0; 7];
        for (k, f) in fields.iter().enumerate() {
            v[k] = f.trim().parse::<f64>().map_err(|_| {
                data_error(
                    csv_path,
                    line,
                    IMU_COLUMNS[k],
                    format!("`{f}` is not a number"),
                )
            })?;
            if !v[k].is_finite() {
                return Err(data_error(csv_path, line, IMU_COLUMNS[k], "not finite"));
            }
        }
        // Units that cannot be right: a specific force in m/s² where g was
        // expected, or a rate in rad/s that saturates no MEMS gyro.
        let f_norm = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if f_norm > 16.0 {
            return Err(data_error(
                csv_path,
                line,
                "ax [g]",
                format!(
                    "|f| = {f_norm:.2} g: more than 16 g — are the accelerometer columns in m/s² instead of g?"
                ),
            ));
        }
        if let Some(&(prev_line, _, prev_tick)) = raw.last()
            && v[6] <= prev_tick
        {
            return Err(data_error(
                csv_path,
                line,
                "tick [ms]",
                format!(
                    "tick {} does not increase (line {prev_line}: {prev_tick})",
                    v[6]
                ),
            ));
        }
        raw.push((line, [v[0], v[1], v[2], v[3], v[4], v[5]], v[6]));
    }
    // Units that cannot be right: a road vehicle's specific force has a
    // median magnitude of about 1 g; a median near 9.8 means the columns are
    // in m/s², not g.
    let mut norms: Vec<f64> = raw
        .iter()
        .map(|(_, v, _)| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt())
        .collect();
    norms.sort_by(f64::total_cmp);
    let median = norms[norms.len() / 2];
    if !(0.5..=2.0).contains(&median) {
        return Err(data_error(
            csv_path,
            raw[0].0,
            "ax [g]",
            format!(
                "median |f| = {median:.3} in the file's unit, expected ≈ 1 g{}",
                if (5.0..15.0).contains(&median) {
                    " — are the accelerometer columns in m/s² instead of g?"
                } else {
                    ""
                }
            ),
        ));
    }
    let first_tick = raw[0].2;
    let last_tick = raw[raw.len() - 1].2;
    let scale = (f64::from(last_tag_ms) / 1000.0) / ((last_tick - first_tick) / 1000.0);
    if !(0.99..=1.01).contains(&scale) {
        warnings.push(format!(
            "{}: tick-to-time scale {scale:.6} is far from 1",
            tag_path.display()
        ));
    }
    let samples = raw
        .iter()
        .map(|&(_, v, tick)| ImuSample {
            time_s: tags.start_s + (tick - first_tick) / 1000.0 * scale,
            specific_force: Vector3::new(v[0], v[1], v[2]) * G0,
            angular_rate: Vector3::new(v[3], v[4], v[5]).map(f64::to_radians),
        })
        .collect();
    Ok((samples, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/rtklibexplorer-gnss-imu/drive_0708")
    }

    #[test]
    fn calendar_time_matches_the_gps_week_form() {
        // 2025/07/08 19:34:18.499 GPST is GPS week 2374, TOW 243 258.499.
        let a = parse_time("2025/07/08", "19:34:18.499").unwrap();
        let b = parse_time("2374", "243258.499").unwrap();
        assert!((a - b).abs() < 1e-6, "{a} {b}");
        assert!(parse_time("2025/13/08", "19:34:18").is_none());
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
}
