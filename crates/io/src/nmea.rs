//! NMEA 0183 GNSS logs (spec 40's "welcome next format"): `GGA` (position,
//! fix quality, satellites), `RMC` (date, speed and course) and `GST`
//! (position error σ), any talker (`GP`, `GN`, `GL`, …).
//!
//! One fix per GGA epoch:
//! - time: the GGA UTC time of day on the date of the last RMC (a day is
//!   added when the time of day wraps past midnight and no RMC has
//!   advanced the date since the previous GGA), converted to GPST
//!   (UTC + the leap seconds of that date) — as the other readers' times;
//! - position: latitude, longitude, and the *ellipsoidal* height = GGA's
//!   altitude above mean sea level + its geoid separation (field 11);
//! - quality, mapped to RTKLIB's Q (which the scores use): GGA 4 (RTK fixed)
//!   → 1, 5 (RTK float) → 2, 2 (DGPS) → 4, 1 (single) → 5; GGA 0 (no fix)
//!   and 6 (dead reckoning) epochs are skipped and counted in a warning;
//! - σ (north, east, up): from the GST of the same time when there is one,
//!   otherwise by quality: 0.02 / 0.02 / 0.04 m fixed, 0.3 / 0.3 / 0.6 m
//!   float, 1 / 1 / 2 m DGPS, 3 / 3 / 6 m single (the file says nothing
//!   better; a warning says how many epochs took these);
//! - velocity (north, east, 0) from the RMC of the same time (knots, course
//!   over ground), σ 0.1 m/s horizontally and 10 m/s vertically (NMEA has no
//!   vertical velocity: it is left practically unobserved).
//!
//! Errors name the file and line: a bad checksum, a field that is not a
//! number, latitude beyond 90°, minutes ≥ 60, an impossible date (31 April),
//! a height outside the bounds of [`crate::limits`], time going backwards, a
//! GGA before any RMC (no date). A UTF-8 byte-order mark is stripped. A truncated last line, lines that are not NMEA
//! sentences and sentences of other types are skipped with a warning.

use std::collections::HashMap;
use std::path::Path;

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::error::Result;
use crate::rtklib::{GnssFix, check_position, data_error, days_from_civil};
use crate::text::{excerpt, num};

/// GPS − UTC (s) on the day `days` since 1970-01-01.
fn leap_seconds(days: i64) -> f64 {
    crate::text::gps_minus_utc_s(days)
}

/// σ (north, east, up) by GGA quality when no GST is given.
fn default_sigma(gga_quality: u8) -> Vector3<f64> {
    match gga_quality {
        4 => Vector3::new(0.02, 0.02, 0.04),
        5 => Vector3::new(0.3, 0.3, 0.6),
        2 => Vector3::new(1.0, 1.0, 2.0),
        _ => Vector3::new(3.0, 3.0, 6.0),
    }
}

/// RTKLIB's Q for a GGA quality (None: not a position fix).
fn rtklib_quality(gga_quality: u8) -> Option<u8> {
    match gga_quality {
        4 => Some(1),
        5 => Some(2),
        2 => Some(4),
        1 => Some(5),
        _ => None,
    }
}

/// The sentence between `$` and `*`, its checksum verified.
fn checked_body<'a>(path: &Path, line: usize, text: &'a str) -> Result<Option<&'a str>> {
    let Some(rest) = text.strip_prefix('$') else {
        return Ok(None);
    };
    let Some((body, sum)) = rest.rsplit_once('*') else {
        return Ok(None);
    };
    let want = u8::from_str_radix(sum.trim(), 16).map_err(|_| {
        data_error(
            path,
            line,
            "checksum",
            format!("`{}` is not hex", excerpt(sum)),
        )
    })?;
    let got = body.bytes().fold(0u8, |a, b| a ^ b);
    if got != want {
        return Err(data_error(
            path,
            line,
            "checksum",
            format!("{got:02X} computed, {want:02X} written: a corrupted sentence"),
        ));
    }
    Ok(Some(body))
}

/// `hhmmss.ss` → seconds of the day.
fn time_of_day(path: &Path, line: usize, f: &str) -> Result<f64> {
    let bad = || {
        data_error(
            path,
            line,
            "time",
            format!("`{}` is not hhmmss.ss", excerpt(f)),
        )
    };
    if f.len() < 6 || !f.is_char_boundary(2) || !f.is_char_boundary(4) {
        return Err(bad());
    }
    let h: u32 = f[0..2].parse().map_err(|_| bad())?;
    let m: u32 = f[2..4].parse().map_err(|_| bad())?;
    let s: f64 = f[4..].parse().map_err(|_| bad())?;
    if h > 23 || m > 59 || !(0.0..61.0).contains(&s) {
        return Err(bad());
    }
    Ok(f64::from(h * 3600 + m * 60) + s)
}

/// `(d)ddmm.mmmm` + hemisphere → radians.
fn angle(path: &Path, line: usize, column: &str, f: &str, hemi: &str, limit: f64) -> Result<f64> {
    let bad = |why: String| data_error(path, line, column, why);
    let v: f64 = f
        .parse()
        .map_err(|_| bad(format!("`{}` is not a number", excerpt(f))))?;
    let degrees = (v / 100.0).trunc();
    let minutes = v - 100.0 * degrees;
    if !(0.0..60.0).contains(&minutes) || !v.is_finite() || v < 0.0 {
        return Err(bad(format!("`{}` is not (d)ddmm.mmmm", excerpt(f))));
    }
    let value = degrees + minutes / 60.0;
    if value > limit {
        return Err(bad(format!("{}° is beyond {limit}°", num(value))));
    }
    let sign = match hemi {
        "N" | "E" => 1.0,
        "S" | "W" => -1.0,
        _ => {
            return Err(bad(format!(
                "hemisphere `{}` is not N/S/E/W",
                excerpt(hemi)
            )));
        }
    };
    Ok((sign * value).to_radians())
}

fn number(path: &Path, line: usize, column: &str, f: &str) -> Result<f64> {
    f.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            data_error(
                path,
                line,
                column,
                format!("`{}` is not a number", excerpt(f)),
            )
        })
}

/// A GGA epoch waiting for its GST / RMC of the same time.
struct Pending {
    line: usize,
    time_of_day: f64,
    time_s: f64,
    position: Geodetic,
    gga_quality: u8,
    satellites: u32,
}

/// Read an NMEA log (see the module docs).
///
/// ```
/// let sentence = |body: &str| format!("${body}*{:02X}\r\n", body.bytes().fold(0u8, |a, b| a ^ b));
/// let log = [
///     "GNRMC,120000.00,A,4807.038000,N,01131.000000,E,10.0,90.0,080725,,,A",
///     "GNGGA,120000.00,4807.038000,N,01131.000000,E,4,12,0.9,545.4,M,46.9,M,1.0,0000",
///     "GNGST,120000.00,0.5,0.01,0.01,0.0,0.011,0.012,0.025",
/// ]
/// .map(sentence)
/// .concat();
/// let path = std::env::temp_dir().join(format!("aidnav-doc-{}.nmea", std::process::id()));
/// std::fs::write(&path, log).unwrap();
/// let (fixes, _) = aidnav_io::nmea::read_nmea(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!((fixes.len(), fixes[0].quality), (1, 1)); // RTK fixed
/// assert!((fixes[0].position.height_m - (545.4 + 46.9)).abs() < 1e-9);
/// assert!(fixes[0].velocity_ned.unwrap().y > 5.0); // 10 kn due east
/// ```
pub fn read_nmea(path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_nmea_from(&crate::text::read_bytes(path)?, path)
}

/// [`read_nmea`] on the file's bytes; `path` names the origin in messages.
pub fn read_nmea_from(bytes: &[u8], path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    let text = crate::text::decode(bytes, path)?;
    let lines: Vec<&str> = crate::text::lines(text).collect();
    let mut warnings = Vec::new();
    let mut date_days: Option<i64> = None;
    let mut last_tod: Option<f64> = None;
    // The date the previous GGA was placed on: a time of day that wraps
    // past midnight adds a day only when no RMC has advanced the date since
    // (a receiver writing RMC before GGA dates the new day itself).
    let mut last_gga_days: Option<i64> = None;
    let mut epochs: Vec<Pending> = Vec::new();
    // σ (north, east, up) and NED velocity by time of day [centiseconds].
    let mut sigmas: HashMap<i64, Vector3<f64>> = HashMap::new();
    let mut velocities: HashMap<i64, Vector3<f64>> = HashMap::new();
    let key = |tod: f64| (tod * 100.0).round() as i64;
    let (mut not_nmea, mut other, mut no_fix, mut duplicates) = (0usize, 0usize, 0usize, 0usize);
    for (i, raw) in lines.iter().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() {
            continue;
        }
        let body = match checked_body(path, line, t) {
            Ok(Some(b)) => b,
            Ok(None) if i + 1 == lines.len() && t.starts_with('$') => {
                warnings.push(format!(
                    "{}:{line}: truncated last sentence skipped",
                    path.display()
                ));
                continue;
            }
            Ok(None) => {
                not_nmea += 1;
                continue;
            }
            Err(e) => return Err(e),
        };
        let f: Vec<&str> = body.split(',').collect();
        let kind = f[0].get(2..).unwrap_or("");
        let need = |n: usize| {
            if f.len() < n {
                Err(data_error(
                    path,
                    line,
                    kind,
                    format!("{} fields, {kind} has at least {n}", f.len()),
                ))
            } else {
                Ok(())
            }
        };
        match kind {
            "RMC" => {
                need(10)?;
                let d = f[9];
                let bad = || {
                    data_error(
                        path,
                        line,
                        "date",
                        format!("`{}` is not a ddmmyy calendar date", excerpt(d)),
                    )
                };
                if d.len() != 6 || !d.is_ascii() {
                    return Err(bad());
                }
                let dd: i64 = d[0..2].parse().map_err(|_| bad())?;
                let mm: i64 = d[2..4].parse().map_err(|_| bad())?;
                let yy: i64 = d[4..6].parse().map_err(|_| bad())?;
                // Two-digit years: 1980–2079.
                let year = if yy >= 80 { 1900 + yy } else { 2000 + yy };
                if !crate::text::is_date(year, mm, dd) {
                    return Err(bad());
                }
                date_days = Some(days_from_civil(year, mm, dd));
                let tod = time_of_day(path, line, f[1])?;
                if f[2] == "A" && !f[7].is_empty() && !f[8].is_empty() {
                    let speed = number(path, line, "speed", f[7])? * 1852.0 / 3600.0;
                    let course = number(path, line, "course", f[8])?.to_radians();
                    velocities.insert(
                        key(tod),
                        Vector3::new(speed * course.cos(), speed * course.sin(), 0.0),
                    );
                }
            }
            "GST" => {
                need(9)?;
                let tod = time_of_day(path, line, f[1])?;
                if f[6].is_empty() || f[7].is_empty() || f[8].is_empty() {
                    continue;
                }
                let s = Vector3::new(
                    number(path, line, "sigma_latitude", f[6])?,
                    number(path, line, "sigma_longitude", f[7])?,
                    number(path, line, "sigma_altitude", f[8])?,
                );
                if s.iter().any(|&v| v <= 0.0) {
                    return Err(data_error(
                        path,
                        line,
                        "sigma",
                        format!(
                            "σ = ({}, {}, {}) m must be > 0 (a receiver claiming 0 cannot be weighted)",
                            num(s.x),
                            num(s.y),
                            num(s.z)
                        ),
                    ));
                }
                sigmas.insert(key(tod), s);
            }
            "GGA" => {
                need(12)?;
                let tod = time_of_day(path, line, f[1])?;
                let gga_quality: u8 = f[6].parse().map_err(|_| {
                    data_error(
                        path,
                        line,
                        "quality",
                        format!("`{}` is not a number", excerpt(f[6])),
                    )
                })?;
                if rtklib_quality(gga_quality).is_none() || f[2].is_empty() {
                    no_fix += 1;
                    continue;
                }
                let Some(mut days) = date_days else {
                    return Err(data_error(
                        path,
                        line,
                        "date",
                        "a GGA before any RMC: the time of day cannot be placed (log RMC too)",
                    ));
                };
                let date_advanced = last_gga_days.is_some_and(|d| days > d);
                if let Some(prev) = last_tod.filter(|_| !date_advanced) {
                    if tod < prev - 43_200.0 {
                        // Past midnight before the next RMC.
                        days += 1;
                        date_days = Some(days);
                    } else if tod == prev {
                        duplicates += 1;
                        continue;
                    } else if tod < prev {
                        return Err(data_error(
                            path,
                            line,
                            "time",
                            format!(
                                "{} s of the day after {} s: time goes backwards",
                                num(tod),
                                num(prev)
                            ),
                        ));
                    }
                }
                last_tod = Some(tod);
                last_gga_days = Some(days);
                let altitude = number(path, line, "altitude", f[9])?;
                let separation = if f[11].is_empty() {
                    0.0
                } else {
                    number(path, line, "geoid_separation", f[11])?
                };
                let utc = days as f64 * 86_400.0 + tod;
                let position = Geodetic {
                    latitude_rad: angle(path, line, "latitude", f[2], f[3], 90.0)?,
                    longitude_rad: angle(path, line, "longitude", f[4], f[5], 180.0)?,
                    height_m: altitude + separation,
                };
                check_position(
                    path,
                    line,
                    position.latitude_rad.to_degrees(),
                    position.longitude_rad.to_degrees(),
                    position.height_m,
                )?;
                epochs.push(Pending {
                    line,
                    time_of_day: tod,
                    time_s: utc + leap_seconds(days),
                    position,
                    gga_quality,
                    satellites: f[7].parse().unwrap_or(0),
                });
            }
            _ => other += 1,
        }
    }
    let mut defaulted = 0usize;
    let fixes: Vec<GnssFix> = epochs
        .iter()
        .map(|e| {
            let k = key(e.time_of_day);
            let sigma = sigmas.get(&k).copied().unwrap_or_else(|| {
                defaulted += 1;
                default_sigma(e.gga_quality)
            });
            let velocity = velocities.get(&k).copied();
            GnssFix {
                time_s: e.time_s,
                position: e.position,
                quality: rtklib_quality(e.gga_quality).unwrap_or(0),
                satellites: e.satellites,
                position_sigma_neu: sigma,
                velocity_ned: velocity,
                velocity_sigma_neu: velocity.map(|_| Vector3::new(0.1, 0.1, 10.0)),
            }
        })
        .collect();
    let p = path.display();
    for (n, what) in [
        (not_nmea, "lines that are not NMEA sentences skipped"),
        (other, "sentences other than GGA, RMC and GST skipped"),
        (
            no_fix,
            "GGA epochs without a position fix (quality 0 or 6) skipped",
        ),
        (
            duplicates,
            "repeated GGA epochs (same time, another talker) skipped",
        ),
        (defaulted, "epochs without GST: σ by fix quality"),
    ] {
        if n > 0 {
            warnings.push(format!("{p}: {n} {what}"));
        }
    }
    if fixes.is_empty() {
        return Err(data_error(
            path,
            epochs.first().map_or(lines.len(), |e| e.line),
            "GGA",
            "no GGA position fix in the file",
        ));
    }
    Ok((fixes, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sentence with its checksum.
    fn sentence(body: &str) -> String {
        format!("${body}*{:02X}", body.bytes().fold(0u8, |a, b| a ^ b))
    }

    fn read(lines: &[String]) -> Result<(Vec<GnssFix>, Vec<String>)> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("log.nmea");
        std::fs::write(&p, lines.join("\r\n")).unwrap();
        read_nmea(&p)
    }

    fn log() -> Vec<String> {
        [
            "GNRMC,235959.00,A,4807.038000,N,01131.000000,E,10.0,90.0,311216,,,A",
            "GNGGA,235959.00,4807.038000,N,01131.000000,E,4,12,0.9,545.4,M,46.9,M,1.0,0000",
            "GNGST,235959.00,0.5,0.01,0.01,0.0,0.011,0.012,0.025",
            "GNGGA,000000.00,4807.038000,N,01131.000000,W,5,12,0.9,545.4,M,46.9,M,1.0,0000",
            "GNGGA,000000.00,4807.038000,N,01131.000000,W,5,12,0.9,545.4,M,46.9,M,1.0,0000",
            "GNGGA,000000.25,,,,,0,0,,,M,,M,,",
            "GNGSV,3,1,12,01,40,083,46",
        ]
        .iter()
        .map(|b| sentence(b))
        .collect()
    }

    #[test]
    fn reads_position_time_quality_sigma_and_velocity() {
        let (fixes, warnings) = read(&log()).unwrap();
        assert_eq!(fixes.len(), 2);
        let (a, b) = (&fixes[0], &fixes[1]);
        // 2016-12-31 23:59:59 UTC: 17 leap seconds that day (18 from 2017).
        let utc = days_from_civil(2016, 12, 31) as f64 * 86_400.0 + 86_399.0;
        assert_eq!(a.time_s, utc + 17.0);
        // Past midnight without a new RMC: the next day, 18 leap seconds.
        assert_eq!(b.time_s, utc + 1.0 + 18.0);
        assert!((a.position.latitude_rad.to_degrees() - (48.0 + 7.038 / 60.0)).abs() < 1e-12);
        assert!((a.position.longitude_rad.to_degrees() - (11.0 + 31.0 / 60.0)).abs() < 1e-12);
        assert!(b.position.longitude_rad < 0.0);
        assert!((a.position.height_m - (545.4 + 46.9)).abs() < 1e-9);
        assert_eq!((a.quality, b.quality, a.satellites), (1, 2, 12));
        assert_eq!(a.position_sigma_neu, Vector3::new(0.011, 0.012, 0.025));
        assert_eq!(b.position_sigma_neu, Vector3::new(0.3, 0.3, 0.6));
        // 10 kn due east.
        let v = a.velocity_ned.unwrap();
        assert!((v.y - 10.0 * 1852.0 / 3600.0).abs() < 1e-12 && v.x.abs() < 1e-12);
        assert!(b.velocity_ned.is_none());
        let all = warnings.join("\n");
        for w in [
            "1 sentences other than",
            "1 GGA epochs without",
            "1 repeated GGA",
            "1 epochs without GST",
        ] {
            assert!(all.contains(w), "{w} in {all}");
        }
    }

    #[test]
    fn malformed_logs_are_named() {
        let cases: Vec<(Vec<String>, &str)> = vec![
            // A corrupted character: the checksum no longer matches.
            (
                {
                    let mut l = log();
                    l[1] = l[1].replace("545.4", "545.5");
                    l
                },
                "log.nmea:2: column `checksum`",
            ),
            (log()[1..].to_vec(), "log.nmea:1: column `date`"),
            (
                {
                    let mut l = log();
                    l.insert(
                        3,
                        sentence(
                            "GNGGA,235958.00,4807.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,,",
                        ),
                    );
                    l
                },
                "log.nmea:4: column `time`",
            ),
            (
                {
                    let mut l = log();
                    l[1] = sentence(
                        "GNGGA,235959.00,4867.038,N,01131.000,E,4,12,0.9,545.4,M,46.9,M,,",
                    );
                    l
                },
                "log.nmea:2: column `latitude`",
            ),
            (
                {
                    let mut l = log();
                    l[2] = sentence("GNGST,235959.00,0.5,0.01,0.01,0.0,0.0,0.012,0.025");
                    l
                },
                "log.nmea:3: column `sigma`",
            ),
            (
                {
                    let mut l = log();
                    l[1] =
                        sentence("GNGGA,235959.00,4807.038,N,01131.000,E,4,12,0.9,NaN,M,46.9,M,,");
                    l
                },
                "log.nmea:2: column `altitude`",
            ),
        ];
        for (lines, want) in cases {
            let err = read(&lines).unwrap_err().to_string();
            assert!(err.contains(want), "{want}: {err}");
        }
        // A truncated last sentence is skipped with a warning.
        let mut l = log();
        l.push("$GNGGA,000001.00,4807.0".into());
        let (fixes, warnings) = read(&l).unwrap();
        assert_eq!(fixes.len(), 2);
        assert!(
            warnings.iter().any(|w| w.contains("truncated")),
            "{warnings:?}"
        );
    }

    #[test]
    fn april_31_is_not_a_date() {
        let mut l = log();
        l[0] = sentence("GNRMC,235959.00,A,4807.038000,N,01131.000000,E,10.0,90.0,310425,,,A");
        let e = read(&l).unwrap_err().to_string();
        assert!(
            e.contains("log.nmea:1: column `date`: `310425` is not a ddmmyy calendar date"),
            "{e}"
        );
        l[0] = sentence("GNRMC,235959.00,A,4807.038000,N,01131.000000,E,10.0,90.0,290224,,,A");
        assert!(read(&l).is_ok());
    }

    #[test]
    fn a_bom_is_stripped_and_invalid_utf8_named() {
        // The BOM used to hide the first RMC: "a GGA before any RMC".
        let text = format!("\u{FEFF}{}", log().join("\r\n"));
        let (fixes, _) = read_nmea_from(text.as_bytes(), Path::new("log.nmea")).unwrap();
        assert_eq!(fixes.len(), 2);
        let mut bytes = log().join("\n").into_bytes();
        let at = bytes.len();
        bytes.extend(b"\n$GN\xFE");
        let e = read_nmea_from(&bytes, Path::new("log.nmea"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!(
                "log.nmea:8: column `(text)`: invalid UTF-8 at byte {}",
                at + 4
            )),
            "{e}"
        );
    }

    #[test]
    fn impossible_heights_are_refused() {
        let mut l = log();
        l[1] = sentence("GNGGA,235959.00,4807.038,N,01131.000,E,4,12,0.9,545400.0,M,46.9,M,,");
        let e = read(&l).unwrap_err().to_string();
        assert!(
            e.contains("log.nmea:2: column `height`: 545446.9 m is outside"),
            "{e}"
        );
    }
}
