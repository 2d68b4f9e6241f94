//! KF-GINS text files (spec 40), so KF-GINS users can switch with their data
//! as it is, and aidnav's generic CSV.
//!
//! KF-GINS IMU file: whitespace- or comma-separated columns `time [s]`,
//! three angle increments `dθx dθy dθz [rad]`, three velocity increments
//! `dvx dvy dvz [m/s]`, body frame forward–right–down; each row holds the
//! increments over the interval that ends at its time. KF-GINS GNSS file:
//! `time [s] latitude [deg] longitude [deg] height [m] σN σE σD [m]`, or
//! 13 columns with the velocity between position and σ: `time lat lon h vN
//! vE vD [m/s] σN σE σD [m] σvN σvE σvD [m/s]` — KF-GINS's own loader
//! (`src/fileio/gnssfileloader.h`) takes the position σ of a 13-column
//! row from its columns 7–9 (0-based).
//!
//! Generic IMU CSV (header required, column order free, extra columns
//! ignored): `time_s, gx_rad_s, gy_rad_s, gz_rad_s, ax_m_s2, ay_m_s2,
//! az_m_s2` (rates and specific force, body or sensor frame, the units in
//! the names). A log in other units names its columns `time_s, gx, gy, gz,
//! ax, ay, az` and declares the units in the configuration ([`ImuUnits`]:
//! `[data] imu_units = { gyro = "deg_s", accel = "g", kind = "rates" }`;
//! `kind = "increments"`: each row holds the angle and velocity increments
//! over the interval that ends at its time, in rad or deg and m/s or g·s).
//! Units that cannot be right are refused with the evidence: the median
//! specific-force magnitude against g, and the gyro magnitude while the
//! specific force says the sensor is at rest (above 0.1 rad/s ≈ 5.7 °/s no
//! MEMS gyro's bias reaches: degrees read as radians). The generic GNSS CSV
//! has a module of its own: [`crate::generic_gnss`].
//!
//! Errors name the file, line and column: non-numbers, non-finite values,
//! σ ≤ 0, time that does not increase, a KF-GINS row with another number of
//! columns than 7 (IMU) or 7 / 13 (GNSS), a 13-column file readable in both
//! orders (columns 4–9 all positive) whose positions do not confirm
//! KF-GINS's, values outside the physical bounds
//! of [`crate::limits`] (a rate that cannot be in rad/s, a latitude beyond
//! the poles, a height below the lowest land or above 100 km), and a median
//! specific force far from 1 g (an accelerometer in g); a truncated last
//! line is skipped with a warning. Every reader has an in-memory entry point
//! (`…_from`), its `&Path` form reads the file and calls it.

use std::path::Path;

use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::checks::CheckLevel;
use crate::error::Result;
use crate::rtklib::{
    GnssFix, ImuSample, check_force, check_median_force, check_position, check_rate, data_error,
};
use crate::text::{decode, excerpt, num, read_bytes};

/// Numeric rows of a text file: (line number, values); comment lines (`#`,
/// `%`) and blank lines skipped; a last line with fewer than `min` fields
/// skipped with a warning.
/// Parsed rows (line number, values) and the warnings.
type Rows = (Vec<(usize, Vec<f64>)>, Vec<String>);

/// The numeric rows of `bytes`, each with the field count of one of
/// `layouts` (the column names of each accepted layout, in order).
fn rows(bytes: &[u8], path: &Path, layouts: &[&[&str]]) -> Result<Rows> {
    let text = decode(bytes, path)?;
    let lines: Vec<(usize, String)> = crate::text::lines(text)
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim().to_string()))
        .collect();
    parse_rows(path, lines, layouts)
}

/// The row checks on (line number, text) pairs: each row has the field
/// count of one of `layouts` (the column names of each accepted layout, in
/// order; errors name a field by the layout of its row), and a last row
/// with fewer fields than the shortest layout is skipped with a warning.
fn parse_rows(path: &Path, lines: Vec<(usize, String)>, layouts: &[&[&str]]) -> Result<Rows> {
    let shortest = layouts
        .iter()
        .copied()
        .min_by_key(|l| l.len())
        .unwrap_or(&[]);
    let min = shortest.len().max(1);
    let lines: Vec<(usize, String)> = lines
        .into_iter()
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#') && !l.starts_with('%'))
        .collect();
    let mut out: Vec<(usize, Vec<f64>)> = Vec::with_capacity(lines.len());
    let mut warnings = Vec::new();
    let expected = layouts
        .iter()
        .map(|l| l.len().to_string())
        .collect::<Vec<_>>()
        .join(" or ");
    for (k, (line, l)) in lines.iter().enumerate() {
        let line = *line;
        let fields: Vec<&str> = l
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        if fields.len() < min && k + 1 == lines.len() {
            warnings.push(crate::rtklib::truncated_last_line(
                path,
                line,
                format_args!("{} fields", fields.len()),
            ));
            continue;
        }
        let Some(names) = layouts.iter().find(|l| l.len() == fields.len()) else {
            return Err(data_error(
                path,
                line,
                "(line)",
                format!(
                    "{} fields, expected {expected} ({})",
                    fields.len(),
                    shortest.join(" ")
                ),
            ));
        };
        let mut v = Vec::with_capacity(fields.len());
        for (i, f) in fields.iter().enumerate() {
            let name = names[i];
            let x: f64 = f.parse().map_err(|_| {
                data_error(
                    path,
                    line,
                    name,
                    format!("`{}` is not a number", excerpt(f)),
                )
            })?;
            if !x.is_finite() {
                return Err(data_error(path, line, name, "not finite"));
            }
            v.push(x);
        }
        if let Some((prev_line, prev)) = out.last()
            && v[0] <= prev[0]
        {
            return Err(data_error(
                path,
                line,
                names[0],
                format!(
                    "time {} does not increase (line {prev_line}: {})",
                    num(v[0]),
                    num(prev[0])
                ),
            ));
        }
        out.push((line, v));
    }
    if out.is_empty() {
        return Err(data_error(path, 0, "(file)", "no data rows"));
    }
    Ok((out, warnings))
}

const KF_IMU: [&str; 7] = ["time", "dθx", "dθy", "dθz", "dvx", "dvy", "dvz"];
/// A 7-column KF-GINS GNSS row.
const KF_GNSS: [&str; 7] = ["time", "latitude", "longitude", "height", "σN", "σE", "σD"];
/// A 13-column KF-GINS GNSS row: the velocity comes before the position σ
/// (KF-GINS reads the position σ from columns 7–9 of such a row).
const KF_GNSS_VELOCITY: [&str; 13] = [
    "time",
    "latitude",
    "longitude",
    "height",
    "vN",
    "vE",
    "vD",
    "σN",
    "σE",
    "σD",
    "σvN",
    "σvE",
    "σvD",
];

/// Read a KF-GINS IMU file; increments become mean rates over each row's
/// interval, time-tagged at the interval's middle (the first row, with no
/// interval, is dropped). The middle matters: the filter integrates rates
/// by the trapezoid rule between samples, and a mean rate tagged at the
/// interval's end would lag by half a sample (5 ms at 100 Hz); between
/// mid-interval samples the trapezoids sum back to the increments.
///
/// ```
/// let path = std::env::temp_dir().join(format!("aidnav-doc-kfimu-{}.txt", std::process::id()));
/// // time, dθ (rad), dv (m/s) over the interval ending at the time.
/// std::fs::write(
///     &path,
///     "100.000 0 0 0 0 0 0\n100.005 1e-5 -2e-5 3e-5 0.001 0.002 -0.049\n100.010 1e-5 -2e-5 3e-5 0.001 0.002 -0.049\n",
/// )
/// .unwrap();
/// let (imu, _) = aidnav_io::kfgins::read_kfgins_imu(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(imu.len(), 2);
/// assert!((imu[0].specific_force.z + 9.8).abs() < 1e-9); // −0.049 m/s over 5 ms
/// ```
pub fn read_kfgins_imu(path: &Path) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_kfgins_imu_from(&read_bytes(path)?, path)
}

/// [`read_kfgins_imu`] on the file's bytes; `path` names the origin in
/// messages.
pub fn read_kfgins_imu_from(bytes: &[u8], path: &Path) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_kfgins_imu_checked_from(bytes, path, CheckLevel::Error)
}

/// [`read_kfgins_imu_from`] with the plausibility check of the units (the
/// median specific force about 1 g) acting as `unit_checks` says.
pub fn read_kfgins_imu_checked_from(
    bytes: &[u8],
    path: &Path,
    unit_checks: CheckLevel,
) -> Result<(Vec<ImuSample>, Vec<String>)> {
    let (rows, mut warnings) = rows(bytes, path, &[&KF_IMU])?;
    let mut out = Vec::with_capacity(rows.len());
    for w in rows.windows(2) {
        let (line, v) = (w[1].0, &w[1].1);
        let dt = v[0] - w[0].1[0];
        let rate = Vector3::new(v[1], v[2], v[3]) / dt;
        check_rate(
            path,
            line,
            "dθx",
            &rate,
            " — are the angle increments in degrees?",
        )?;
        let force = Vector3::new(v[4], v[5], v[6]) / dt;
        check_force(path, line, "dvx", &force)?;
        out.push(ImuSample {
            time_s: v[0] - 0.5 * dt,
            angular_rate: rate,
            specific_force: force,
        });
    }
    if let Some(&(line, _)) = rows.get(1) {
        unit_checks.apply(
            check_median_force(path, line, "dvx", out.iter().map(|s| s.specific_force)),
            &mut warnings,
        )?;
    }
    Ok((out, warnings))
}

fn sigma_checked(path: &Path, line: usize, names: &[&str], v: &[f64]) -> Result<Vector3<f64>> {
    for (k, x) in v.iter().enumerate() {
        if *x <= 0.0 {
            return Err(data_error(
                path,
                line,
                names[k],
                format!("σ = {}: must be > 0", num(*x)),
            ));
        }
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// Read a KF-GINS GNSS file (quality unknown: reported as 0).
///
/// ```
/// let path = std::env::temp_dir().join(format!("aidnav-doc-kfgnss-{}.txt", std::process::id()));
/// // time, latitude, longitude [deg], height [m], σN σE σD [m].
/// std::fs::write(&path, "100.0 30.5 114.3 20.0 0.01 0.01 0.02\n101.0 30.5 114.3 20.1 0.01 0.01 0.02\n")
///     .unwrap();
/// let (fixes, _) = aidnav_io::kfgins::read_kfgins_gnss(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(fixes.len(), 2);
/// assert!((fixes[1].position.height_m - 20.1).abs() < 1e-12);
/// assert!(fixes[0].velocity_ned.is_none());
/// ```
pub fn read_kfgins_gnss(path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_kfgins_gnss_from(&read_bytes(path)?, path)
}

/// [`read_kfgins_gnss`] on the file's bytes; `path` names the origin in
/// messages. Rows have 7 columns (`time lat lon h σN σE σD`), or 13 (`time
/// lat lon h vN vE vD σN σE σD σvN σvE σvD`: KF-GINS's layout, whose loader
/// takes the position σ from columns 7–9).
pub fn read_kfgins_gnss_from(bytes: &[u8], path: &Path) -> Result<(Vec<GnssFix>, Vec<String>)> {
    let (rows, warnings) = rows(bytes, path, &[&KF_GNSS, &KF_GNSS_VELOCITY])?;
    check_column_order(path, &rows)?;
    let fixes = rows
        .iter()
        .map(|(line, v)| {
            check_position(path, *line, v[1], v[2], v[3])?;
            let (sigma, velocity_ned, velocity_sigma_neu) = if v.len() == KF_GNSS_VELOCITY.len() {
                let sigma = sigma_checked(path, *line, &KF_GNSS_VELOCITY[7..10], &v[7..10])?;
                let s = sigma_checked(path, *line, &KF_GNSS_VELOCITY[10..13], &v[10..13])?;
                let velocity = Vector3::new(v[4], v[5], v[6]);
                crate::rtklib::in_range(
                    path,
                    *line,
                    "vN",
                    velocity.norm(),
                    0.0,
                    crate::limits::MAX_SPEED_M_S,
                    "m/s",
                    "faster than any vehicle a receiver reports",
                )?;
                (sigma, Some(velocity), Some(s))
            } else {
                let sigma = sigma_checked(path, *line, &KF_GNSS[4..7], &v[4..7])?;
                (sigma, None, None)
            };
            Ok(GnssFix {
                time_s: v[0],
                position: Geodetic {
                    latitude_rad: v[1].to_radians(),
                    longitude_rad: v[2].to_radians(),
                    height_m: v[3],
                },
                quality: 0,
                satellites: 0,
                position_sigma_neu: sigma,
                velocity_ned,
                velocity_sigma_neu,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((fixes, warnings))
}

/// Which 13-column layout the rows' motion supports.
#[derive(Debug, Clone, Copy, PartialEq)]
enum OrderEvidence {
    /// Columns 4–6 are the velocity (KF-GINS's layout).
    VelocityFirst,
    /// Columns 7–9 are the velocity (the position σ first).
    SigmaFirst,
    /// The positions cannot tell.
    Undecided,
}

/// A 13-column file in the other order (`time lat lon h σN σE σD vN vE vD
/// σvN σvE σvD`, as some converters write it) reads without an error
/// whenever every velocity is positive: its σ become the velocity and its
/// velocity the σ. When columns 4–9 are all positive (both layouts
/// plausible) the positions decide — the velocity must match their
/// differences — and a file whose positions say "σ first", or cannot
/// tell, is an error asking for KF-GINS's order, not a guess.
fn check_column_order(path: &Path, rows: &[(usize, Vec<f64>)]) -> Result<()> {
    let thirteen: Vec<&(usize, Vec<f64>)> = rows
        .iter()
        .filter(|(_, v)| v.len() == KF_GNSS_VELOCITY.len())
        .collect();
    let both_plausible = !thirteen.is_empty()
        && thirteen
            .iter()
            .all(|(_, v)| v[4..10].iter().all(|x| *x > 0.0));
    if !both_plausible {
        return Ok(());
    }
    let evidence = order_evidence(&thirteen);
    if evidence == OrderEvidence::VelocityFirst {
        return Ok(());
    }
    let line = thirteen[0].0;
    let why = match evidence {
        OrderEvidence::SigmaFirst => {
            "the position differences match columns 7–9 as the velocity: the file looks like `time lat lon h σN σE σD vN vE vD σvN σvE σvD`"
        }
        _ => "the position differences cannot tell which columns are the velocity",
    };
    Err(data_error(
        path,
        line,
        "vN",
        format!(
            "every value of columns 4–9 is positive, so the 13 columns read in either order: {why}. Write KF-GINS's order, `time lat lon h vN vE vD σN σE σD σvN σvE σvD`, or a generic CSV with named columns (gnss_format = \"generic_csv\")"
        ),
    ))
}

/// Compare the two candidate velocities of consecutive 13-column rows (at
/// most 2 s apart) with the velocity of their position difference: the
/// layout whose RMS mismatch is below half the other's wins.
fn order_evidence(rows: &[&(usize, Vec<f64>)]) -> OrderEvidence {
    let position = |v: &[f64]| Geodetic {
        latitude_rad: v[1].to_radians(),
        longitude_rad: v[2].to_radians(),
        height_m: v[3],
    };
    let (mut first, mut second, mut n) = (0.0, 0.0, 0usize);
    for pair in rows.windows(2) {
        let (a, b) = (&pair[0].1, &pair[1].1);
        let dt = b[0] - a[0];
        if !(dt > 0.0 && dt <= 2.0) {
            continue;
        }
        let d = position(a).ned_to(&position(b));
        let moved = Vector3::new(d.x(), d.y(), d.z()) / dt;
        let mean =
            |k: usize| Vector3::new(a[k] + b[k], a[k + 1] + b[k + 1], a[k + 2] + b[k + 2]) / 2.0;
        first += (mean(4) - moved).norm_squared();
        second += (mean(7) - moved).norm_squared();
        n += 1;
    }
    if n < 3 {
        OrderEvidence::Undecided
    } else if first < 0.25 * second {
        OrderEvidence::VelocityFirst
    } else if second < 0.25 * first {
        OrderEvidence::SigmaFirst
    } else {
        OrderEvidence::Undecided
    }
}

/// The GPS week holding `time_s` (GPST seconds since 1970, aidnav's time
/// scale) and the week's start on that scale: KF-GINS files carry seconds
/// of week, `time_s − start`. `None` before GPS time began (1980-01-06), or
/// when the time is not finite.
///
/// ```
/// // 2024-08-27 00:00:00 GPST is in GPS week 2329, 172 800 s into it.
/// let (week, start) = aidnav_io::kfgins::gps_week_start(1_724_716_800.0).unwrap();
/// assert_eq!(week, 2329);
/// assert_eq!(1_724_716_800.0 - start, 172_800.0);
/// ```
pub fn gps_week_start(time_s: f64) -> Option<(u32, f64)> {
    use crate::text::{GPS_EPOCH_1970_S, WEEK_S};
    if !time_s.is_finite() || time_s < GPS_EPOCH_1970_S {
        return None;
    }
    let week = ((time_s - GPS_EPOCH_1970_S) / WEEK_S).floor();
    Some((week as u32, GPS_EPOCH_1970_S + week * WEEK_S))
}

fn write_error(path: &Path, message: impl Into<String>) -> crate::IoError {
    crate::IoError::Write {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// The text of a KF-GINS IMU file holding `samples` (rates and specific
/// force at their times, in whatever frame they are), times shifted by
/// `−shift_s` (the GPS week's start: [`gps_week_start`]); `path` names the
/// file in errors.
///
/// Each sample becomes one row of increments over an interval whose middle
/// is the sample: the interval's ends are the midpoints between neighbouring
/// samples (half a spacing beyond the first and last), the increments the
/// rates times the interval. A first row of zeros opens the first interval.
/// [`read_kfgins_imu`] gives back the samples: the rates to a few units of
/// the last place (numbers are written in their shortest exact decimal
/// form), the times exactly on an even grid and within a quarter of the
/// change of spacing otherwise. Errors: fewer than two samples, times that
/// do not increase, non-finite values.
pub fn kfgins_imu_text(samples: &[ImuSample], shift_s: f64, path: &Path) -> Result<String> {
    use std::fmt::Write as _;
    if samples.len() < 2 {
        return Err(write_error(
            path,
            format!("{} IMU samples: need at least 2", samples.len()),
        ));
    }
    let t: Vec<f64> = samples.iter().map(|s| s.time_s - shift_s).collect();
    let n = t.len();
    let mut ends = Vec::with_capacity(n + 1);
    ends.push(t[0] - 0.5 * (t[1] - t[0]));
    for k in 0..n - 1 {
        ends.push(0.5 * (t[k] + t[k + 1]));
    }
    ends.push(t[n - 1] + 0.5 * (t[n - 1] - t[n - 2]));
    let mut text = String::with_capacity(100 * (n + 1));
    let _ = writeln!(text, "{} 0 0 0 0 0 0", ends[0]);
    for (k, s) in samples.iter().enumerate() {
        let dt = ends[k + 1] - ends[k];
        if dt.is_nan() || dt <= 0.0 || !ends[k + 1].is_finite() {
            return Err(write_error(
                path,
                format!(
                    "IMU sample {k}: time {} does not increase (previous interval end {})",
                    num(s.time_s),
                    num(ends[k] + shift_s)
                ),
            ));
        }
        let (w, f) = (s.angular_rate * dt, s.specific_force * dt);
        if !w.iter().chain(f.iter()).all(|x| x.is_finite()) {
            return Err(write_error(
                path,
                format!("IMU sample {k} at {}: not finite", num(s.time_s)),
            ));
        }
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {}",
            ends[k + 1],
            w.x,
            w.y,
            w.z,
            f.x,
            f.y,
            f.z
        );
    }
    Ok(text)
}

/// The text of a KF-GINS GNSS file holding `fixes`: `time lat lon h σN σE
/// σD` (degrees, metres; the σ as [`GnssFix::position_sigma_neu`] holds
/// them), times shifted by `−shift_s`, every number in its shortest exact
/// decimal form. Seven columns only: KF-GINS reads seven by default, and
/// velocity, quality and satellite count are not written. Errors: no fix,
/// non-finite values.
pub fn kfgins_gnss_text(fixes: &[GnssFix], shift_s: f64, path: &Path) -> Result<String> {
    use std::fmt::Write as _;
    if fixes.is_empty() {
        return Err(write_error(path, "no GNSS fix to write"));
    }
    let mut text = String::with_capacity(100 * fixes.len());
    for (k, g) in fixes.iter().enumerate() {
        let p = &g.position;
        let v = [
            g.time_s - shift_s,
            p.latitude_rad.to_degrees(),
            p.longitude_rad.to_degrees(),
            p.height_m,
            g.position_sigma_neu.x,
            g.position_sigma_neu.y,
            g.position_sigma_neu.z,
        ];
        if !v.iter().all(|x| x.is_finite()) {
            return Err(write_error(
                path,
                format!("GNSS fix {k} at {}: not finite", num(g.time_s)),
            ));
        }
        let _ = writeln!(
            text,
            "{} {} {} {} {} {} {}",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6]
        );
    }
    Ok(text)
}

/// Write [`kfgins_imu_text`] to `path` (atomically).
pub fn write_kfgins_imu(path: &Path, samples: &[ImuSample], shift_s: f64) -> Result<()> {
    crate::writers::write_atomic(path, kfgins_imu_text(samples, shift_s, path)?.as_bytes())
}

/// Write [`kfgins_gnss_text`] to `path` (atomically).
pub fn write_kfgins_gnss(path: &Path, fixes: &[GnssFix], shift_s: f64) -> Result<()> {
    crate::writers::write_atomic(path, kfgins_gnss_text(fixes, shift_s, path)?.as_bytes())
}

/// Column indices of named header fields; error naming the missing one.
fn columns(path: &Path, header: &str, wanted: &[&str]) -> Result<Vec<usize>> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    wanted
        .iter()
        .map(|w| {
            names.iter().position(|n| n == w).ok_or_else(|| {
                data_error(
                    path,
                    1,
                    w,
                    format!("column missing from the header `{}`", excerpt(header)),
                )
            })
        })
        .collect()
}

/// Standard gravity \[m/s²\]: the unit `g` of [`AccelUnit::G`].
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;

/// Unit of the gyro columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum GyroUnit {
    /// rad/s (rates) or rad (increments).
    #[serde(rename = "rad_s")]
    RadPerS,
    /// deg/s (rates) or deg (increments).
    #[serde(rename = "deg_s")]
    DegPerS,
}

/// Unit of the accelerometer columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum AccelUnit {
    /// m/s² (rates) or m/s (increments).
    #[serde(rename = "m_s2")]
    MPerS2,
    /// Standard gravity, 9.80665 m/s² (rates) or g·s (increments).
    #[serde(rename = "g")]
    G,
}

/// What the sensor columns hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuKind {
    /// Angular rate and specific force at the row's time.
    Rates,
    /// Angle and velocity increments over the interval that ends at the
    /// row's time (the first row, with no interval, is dropped).
    Increments,
}

/// Units of a generic IMU CSV whose columns are named `gx … az`
/// (`[data] imu_units` of `aidnav process`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImuUnits {
    /// `rad_s` or `deg_s`.
    pub gyro: GyroUnit,
    /// `m_s2` or `g`.
    pub accel: AccelUnit,
    /// `rates` (default) or `increments`.
    #[serde(default = "rates")]
    pub kind: ImuKind,
}

fn rates() -> ImuKind {
    ImuKind::Rates
}

/// Options of the generic IMU reader that come from the configuration.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GenericImuOptions {
    /// Units of `gx … az` columns; None: the columns carry their units in
    /// their names (`gx_rad_s … az_m_s2`).
    pub units: Option<ImuUnits>,
    /// What the plausibility checks of the units (median |f| about 1 g, the
    /// gyro at rest below [`MAX_RATE_AT_REST_RAD_S`]) do when they fail.
    pub unit_checks: CheckLevel,
}

/// Largest gyro magnitude accepted while the sensor is at rest \[rad/s\]
/// (≈ 5.7 °/s): consumer MEMS gyro biases stay below about 1 °/s, so more
/// is a unit mistake (degrees read as radians).
pub const MAX_RATE_AT_REST_RAD_S: f64 = 0.1;

/// Read a generic IMU CSV (see the module docs).
///
/// ```
/// let path = std::env::temp_dir().join(format!("aidnav-doc-generic-{}.csv", std::process::id()));
/// std::fs::write(
///     &path,
///     "time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n1.0,0,0,0.1,0,0,-9.8\n1.01,0,0,0.1,0,0,-9.8\n",
/// )
/// .unwrap();
/// let (imu, _) = aidnav_io::kfgins::read_generic_imu(&path).unwrap();
/// std::fs::remove_file(&path).unwrap();
/// assert_eq!(imu.len(), 2);
/// assert_eq!((imu[0].angular_rate.z, imu[1].specific_force.z), (0.1, -9.8));
/// ```
pub fn read_generic_imu(path: &Path) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_generic_imu_from(&read_bytes(path)?, path)
}

/// [`read_generic_imu`] on the file's bytes; `path` names the origin in
/// messages.
pub fn read_generic_imu_from(bytes: &[u8], path: &Path) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_generic_imu_with_from(bytes, path, GenericImuOptions::default())
}

/// [`read_generic_imu`] with the units of `gx … az` columns declared.
///
/// ```
/// use aidnav_io::kfgins::{GenericImuOptions, ImuUnits, GyroUnit, AccelUnit, ImuKind};
/// let csv = "time_s,gx,gy,gz,ax,ay,az\n1.0,0,0,5.73,0,0,-1\n1.01,0,0,5.73,0,0,-1\n";
/// let units = ImuUnits { gyro: GyroUnit::DegPerS, accel: AccelUnit::G, kind: ImuKind::Rates };
/// let (imu, _) = aidnav_io::kfgins::read_generic_imu_with_from(
///     csv.as_bytes(),
///     "imu.csv".as_ref(),
///     GenericImuOptions { units: Some(units), ..Default::default() },
/// )
/// .unwrap();
/// assert!((imu[0].angular_rate.z - 0.1).abs() < 1e-3); // 5.73 °/s
/// assert_eq!(imu[1].specific_force.z, -9.80665);
/// ```
pub fn read_generic_imu_with(
    path: &Path,
    options: GenericImuOptions,
) -> Result<(Vec<ImuSample>, Vec<String>)> {
    read_generic_imu_with_from(&read_bytes(path)?, path, options)
}

/// [`read_generic_imu_with`] on the file's bytes; `path` names the origin
/// in messages.
pub fn read_generic_imu_with_from(
    bytes: &[u8],
    path: &Path,
    options: GenericImuOptions,
) -> Result<(Vec<ImuSample>, Vec<String>)> {
    let text = decode(bytes, path)?;
    let header = crate::text::lines(text).next().unwrap_or("");
    const SUFFIXED: [&str; 7] = [
        "time_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
    ];
    const NEUTRAL: [&str; 7] = ["time_s", "gx", "gy", "gz", "ax", "ay", "az"];
    let has = |name: &str| header.split(',').any(|n| n.trim() == name);
    let wanted = match options.units {
        None if has("gx") && !has("gx_rad_s") => {
            return Err(data_error(
                path,
                1,
                "gx",
                "columns gx … az carry no unit: declare them in the configuration, [data] imu_units = { gyro = \"rad_s\" | \"deg_s\", accel = \"m_s2\" | \"g\", kind = \"rates\" | \"increments\" }, or name them gx_rad_s … az_m_s2",
            ));
        }
        None => SUFFIXED,
        Some(_) if has("gx_rad_s") && !has("gx") => {
            return Err(data_error(
                path,
                1,
                "gx_rad_s",
                "imu_units is declared, but the columns are named with their units (gx_rad_s … az_m_s2): name them gx, gy, gz, ax, ay, az, or drop imu_units",
            ));
        }
        Some(_) => NEUTRAL,
    };
    let idx = columns(path, header, &wanted)?;
    // The named columns, in order, with their original line numbers.
    let lines = crate::text::lines(text)
        .enumerate()
        .skip(1)
        .map(|(i, l)| {
            let f: Vec<&str> = l.split(',').map(str::trim).collect();
            let picked: Vec<&str> = idx.iter().filter_map(|&c| f.get(c).copied()).collect();
            (i + 1, picked.join(","))
        })
        .collect();
    let (rows, mut warnings) = parse_rows(path, lines, &[&wanted])?;
    let units = options.units.unwrap_or(ImuUnits {
        gyro: GyroUnit::RadPerS,
        accel: AccelUnit::MPerS2,
        kind: ImuKind::Rates,
    });
    let (gyro_scale, accel_scale) = (
        match units.gyro {
            GyroUnit::RadPerS => 1.0,
            GyroUnit::DegPerS => 1f64.to_radians(),
        },
        match units.accel {
            AccelUnit::MPerS2 => 1.0,
            AccelUnit::G => STANDARD_GRAVITY_M_S2,
        },
    );
    let (gyro_col, accel_col) = (wanted[1], wanted[4]);
    let mut out = Vec::with_capacity(rows.len());
    let mut previous: Option<f64> = None;
    for (line, v) in &rows {
        // Increments become mean rates over the row's interval.
        let per_s = match units.kind {
            ImuKind::Rates => 1.0,
            ImuKind::Increments => match previous.replace(v[0]) {
                Some(t) => 1.0 / (v[0] - t),
                None => continue,
            },
        };
        let sample = ImuSample {
            time_s: v[0],
            angular_rate: Vector3::new(v[1], v[2], v[3]) * gyro_scale * per_s,
            specific_force: Vector3::new(v[4], v[5], v[6]) * accel_scale * per_s,
        };
        let hint = match units.gyro {
            GyroUnit::RadPerS => " — degrees given? (imu_units.gyro = \"deg_s\")",
            GyroUnit::DegPerS => " — are the gyro columns scaled (milli-degrees/s)?",
        };
        check_rate(path, *line, gyro_col, &sample.angular_rate, hint)?;
        check_force(path, *line, accel_col, &sample.specific_force)?;
        out.push(sample);
    }
    if let Some(&(line, _)) = rows.first() {
        let checks = options.unit_checks;
        checks.apply(
            check_median_force_declared(path, line, accel_col, &out, units),
            &mut warnings,
        )?;
        checks.apply(
            check_rate_at_rest(path, &rows, gyro_col, &out, units),
            &mut warnings,
        )?;
    }
    Ok((out, warnings))
}

/// The median specific-force magnitude must be about 1 g; the message
/// says which unit the numbers look like given the declared one.
fn check_median_force_declared(
    path: &Path,
    line: usize,
    column: &str,
    imu: &[ImuSample],
    units: ImuUnits,
) -> Result<()> {
    let mut norms: Vec<f64> = imu.iter().map(|s| s.specific_force.norm()).collect();
    if norms.is_empty() {
        return Ok(());
    }
    norms.sort_by(f64::total_cmp);
    let median = norms[norms.len() / 2];
    let range = crate::limits::MEDIAN_SPECIFIC_FORCE_M_S2;
    if range.contains(&median) {
        return Ok(());
    }
    let g = STANDARD_GRAVITY_M_S2;
    let hint = match units.accel {
        AccelUnit::MPerS2 if (0.5..2.0).contains(&median) => {
            " — the numbers look like g: is the accelerometer in g instead of m/s²? (imu_units.accel = \"g\")"
        }
        AccelUnit::G if (0.5 * g * g..2.0 * g * g).contains(&median) => {
            " — with imu_units.accel = \"g\" the numbers (≈ 9.8 as written) look like m/s² already: imu_units.accel = \"m_s2\""
        }
        _ => "",
    };
    Err(data_error(
        path,
        line,
        column,
        format!(
            "median |f| = {} m/s² after the declared units, expected about 9.8 (between {} and {}){hint}",
            num(median),
            range.start(),
            range.end()
        ),
    ))
}

/// While the specific force says the sensor is at rest (its magnitude
/// within 1 % of g and steady over ten samples), the gyro magnitude must
/// stay below [`MAX_RATE_AT_REST_RAD_S`]: the median over such samples
/// above it is a unit mistake, reported with the lines it comes from.
fn check_rate_at_rest(
    path: &Path,
    rows: &[(usize, Vec<f64>)],
    column: &str,
    imu: &[ImuSample],
    units: ImuUnits,
) -> Result<()> {
    const WINDOW: usize = 10;
    let g = STANDARD_GRAVITY_M_S2;
    let still = |w: &[ImuSample]| {
        w.iter()
            .all(|s| (s.specific_force.norm() - g).abs() < 0.01 * g)
            && w.windows(2)
                .all(|p| (p[1].specific_force - p[0].specific_force).norm() < 0.02 * g)
    };
    let mut at_rest: Vec<(usize, f64)> = imu
        .windows(WINDOW)
        .enumerate()
        .filter(|(_, w)| still(w))
        .map(|(k, w)| {
            (
                k,
                w.iter().map(|s| s.angular_rate.norm()).sum::<f64>() / WINDOW as f64,
            )
        })
        .collect();
    if at_rest.len() < 10 {
        return Ok(());
    }
    at_rest.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (k, median) = at_rest[at_rest.len() / 2];
    if median <= MAX_RATE_AT_REST_RAD_S {
        return Ok(());
    }
    // Rows and samples line up except for increments (first row dropped).
    let shift = usize::from(units.kind == ImuKind::Increments);
    let line = rows.get(k + shift).map_or(0, |r| r.0);
    let hint = match units.gyro {
        GyroUnit::RadPerS => " — degrees per second read as radians? (imu_units.gyro = \"deg_s\")",
        GyroUnit::DegPerS => " — the gyro columns look scaled (milli-degrees, or LSB counts?)",
    };
    Err(data_error(
        path,
        line,
        column,
        format!(
            "|ω| = {median:.4} rad/s (median over {} stretches of {WINDOW} samples at rest: |f| steady within 1 % of g; this one from line {line}) — a MEMS gyro at rest reads its bias, below {MAX_RATE_AT_REST_RAD_S} rad/s ≈ 5.7 °/s{hint}",
            at_rest.len()
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The writers invert the readers: an uneven, jittered 100 Hz log in
    /// GPST since 1970 written as KF-GINS text (seconds of week) and read
    /// back gives the rates and specific forces to 4 ulp (x·dt/dt, each
    /// operation rounding once; the numbers are written exactly) and the
    /// times to a quarter of the change of spacing plus 1e-9 s.
    #[test]
    fn kfgins_writers_round_trip() {
        let t0 = 1_724_716_800.0 + 3_600.25;
        let (_, start) = gps_week_start(t0).unwrap();
        let mut time = t0;
        let samples: Vec<ImuSample> = (0..200)
            .map(|k| {
                let k = k as f64;
                time += 0.01 + if k % 7.0 == 0.0 { 2e-4 } else { 0.0 };
                ImuSample {
                    time_s: time,
                    angular_rate: Vector3::new(0.01 * k.sin(), -0.2, 1.0 / (k + 3.0)),
                    specific_force: Vector3::new(0.3, -0.1 * k.cos(), -9.81),
                }
            })
            .collect();
        let path = Path::new("imu.txt");
        let text = kfgins_imu_text(&samples, start, path).unwrap();
        let (back, w) = read_kfgins_imu_from(text.as_bytes(), path).unwrap();
        assert!(w.is_empty());
        assert_eq!(back.len(), samples.len());
        for (k, (a, b)) in samples.iter().zip(&back).enumerate() {
            let jitter = if k == 0 || k + 1 == samples.len() {
                0.0
            } else {
                ((samples[k + 1].time_s - a.time_s) - (a.time_s - samples[k - 1].time_s)).abs()
            };
            assert!(
                (a.time_s - start - b.time_s).abs() <= jitter / 4.0 + 1e-9,
                "{k}: {} {}",
                a.time_s - start,
                b.time_s
            );
            for (x, y) in a
                .angular_rate
                .iter()
                .chain(a.specific_force.iter())
                .zip(b.angular_rate.iter().chain(b.specific_force.iter()))
            {
                assert!(
                    (x - y).abs() <= 4.0 * f64::EPSILON * x.abs(),
                    "{k}: {x} {y}"
                );
            }
        }
        let fixes: Vec<GnssFix> = samples
            .iter()
            .step_by(100)
            .map(|s| GnssFix {
                time_s: s.time_s,
                position: Geodetic {
                    latitude_rad: 0.6,
                    longitude_rad: -2.1,
                    height_m: 12.345_678_9,
                },
                quality: 1,
                satellites: 9,
                position_sigma_neu: Vector3::new(0.01, 0.012, 0.03),
                velocity_ned: None,
                velocity_sigma_neu: None,
            })
            .collect();
        let text = kfgins_gnss_text(&fixes, start, Path::new("gnss.txt")).unwrap();
        let (gback, _) = read_kfgins_gnss_from(text.as_bytes(), Path::new("gnss.txt")).unwrap();
        assert_eq!(gback.len(), fixes.len());
        for (a, b) in fixes.iter().zip(&gback) {
            assert_eq!(a.time_s - start, b.time_s);
            assert!((a.position.latitude_rad - b.position.latitude_rad).abs() < 1e-15);
            assert!((a.position.longitude_rad - b.position.longitude_rad).abs() < 1e-15);
            assert_eq!(a.position.height_m, b.position.height_m);
            assert_eq!(a.position_sigma_neu, b.position_sigma_neu);
        }
        let err = kfgins_imu_text(&samples[..1], start, path).unwrap_err();
        assert!(err.to_string().contains("imu.txt"), "{err}");
    }

    /// Increments of a rate that grows linearly (ω = a t): each row's mean
    /// rate is the rate at the interval's middle, where the sample is now
    /// tagged — no half-sample lag.
    #[test]
    fn increments_become_rates_at_the_middle_of_their_interval() {
        let a = 0.01;
        let mut text = String::from("100.00 0 0 0 0 0 -0.098\n");
        for k in 1..=5 {
            let (t0, t1) = (100.0 + (k - 1) as f64 * 0.01, 100.0 + k as f64 * 0.01);
            let dz = a * (t1 * t1 - t0 * t0) / 2.0;
            text.push_str(&format!("{t1:.2} 0 0 {dz:e} 0 0 -0.098\n"));
        }
        let (imu, _) = read_kfgins_imu_from(text.as_bytes(), Path::new("ramp.txt")).unwrap();
        assert_eq!(imu.len(), 5);
        for (k, s) in imu.iter().enumerate() {
            let mid = 100.0 + (k as f64 + 0.5) * 0.01;
            assert!((s.time_s - mid).abs() < 1e-9, "{}", s.time_s);
            assert!(
                (s.angular_rate.z - a * mid).abs() < 1e-9,
                "{}",
                s.angular_rate.z
            );
        }
    }

    #[test]
    fn kfgins_files_round_trip_and_fail_clearly() {
        let dir = tempfile::tempdir().unwrap();
        let imu = dir.path().join("imu.txt");
        std::fs::write(
            &imu,
            "100.000 0 0 0 0 0 0\n100.005 1e-5 -2e-5 3e-5 0.001 0.002 -0.049\n100.010 1e-5 -2e-5 3e-5 0.001 0.002 -0.049\n100.0",
        )
        .unwrap();
        let (s, w) = read_kfgins_imu(&imu).unwrap();
        assert_eq!(s.len(), 2);
        assert!((s[0].specific_force.z + 9.8).abs() < 1e-9);
        assert!(w[0].contains("truncated last line"));
        std::fs::write(&imu, "100.000 0 0 0 0 0 0\n100.005 1 0 0 0 0 -0.049\n").unwrap();
        let e = read_kfgins_imu(&imu).unwrap_err().to_string();
        assert!(
            e.contains("imu.txt:2: column `dθx`") && e.contains("degrees"),
            "{e}"
        );
        let gnss = dir.path().join("gnss.txt");
        std::fs::write(
            &gnss,
            "100.0 30.5 114.3 20.0 0.01 0.01 0.02\n100.0 30.5 114.3 20.0 0.01 0.01 0.02\n",
        )
        .unwrap();
        let e = kfgins_gnss_err(&gnss);
        assert!(
            e.contains("gnss.txt:2: column `time`") && e.contains("does not increase"),
            "{e}"
        );
        std::fs::write(&gnss, "100.0 30.5 114.3 20.0 0.01 0 0.02\n").unwrap();
        let e = kfgins_gnss_err(&gnss);
        assert!(e.contains("column `σE`: σ = 0"), "{e}");
        std::fs::write(&gnss, "100.0 30.5 114.3 NaN 0.01 0.01 0.02\n").unwrap();
        let e = kfgins_gnss_err(&gnss);
        assert!(e.contains("column `height`"), "{e}");
    }

    #[test]
    fn generic_csv_finds_its_columns_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("imu.csv");
        std::fs::write(
            &p,
            "extra,time_s,az_m_s2,ay_m_s2,ax_m_s2,gz_rad_s,gy_rad_s,gx_rad_s\n7,1.0,-9.8,0,0,0.1,0,0\n7,1.01,-9.8,0,0,0.1,0,0\n",
        )
        .unwrap();
        let (s, _) = read_generic_imu(&p).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].specific_force.z, -9.8);
        assert_eq!(s[0].angular_rate.z, 0.1);
        std::fs::write(&p, "time_s,gx_rad_s\n1,0\n").unwrap();
        let e = read_generic_imu(&p).unwrap_err().to_string();
        assert!(
            e.contains("imu.csv:1: column `gy_rad_s`: column missing"),
            "{e}"
        );
        std::fs::write(
            &p,
            "time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n1,0,0,0,0,0,x\n",
        )
        .unwrap();
        let e = read_generic_imu(&p).unwrap_err().to_string();
        assert!(e.contains("imu.csv:2: column `az_m_s2`"), "{e}");
    }

    const HEADER: &str = "time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2";

    fn generic(text: &str) -> Result<(Vec<ImuSample>, Vec<String>)> {
        read_generic_imu_from(text.as_bytes(), Path::new("g.csv"))
    }

    fn kf_gnss(text: &str) -> Result<(Vec<GnssFix>, Vec<String>)> {
        read_kfgins_gnss_from(text.as_bytes(), Path::new("gnss.txt"))
    }

    // The error tests read only the message: one call each instead of
    // `.unwrap_err().to_string()` after every read.
    fn generic_err(text: &str) -> String {
        generic(text).unwrap_err().to_string()
    }

    fn kf_gnss_err(text: &str) -> String {
        kf_gnss(text).unwrap_err().to_string()
    }

    fn kfgins_gnss_err(path: &Path) -> String {
        read_kfgins_gnss(path).unwrap_err().to_string()
    }

    #[test]
    fn accelerometers_in_g_are_refused() {
        let e = generic_err(&format!("{HEADER}\n1.0,0,0,0,0,0,-1\n1.01,0,0,0,0,0,-1\n"));
        assert!(
            e.starts_with("g.csv:2: column `ax_m_s2`: median |f| = 1 m/s²") && e.contains("in g"),
            "{e}"
        );
        // KF-GINS: dv of 1 g · 5 ms written in g · s.
        let e = read_kfgins_imu_from(
            b"100.000 0 0 0 0 0 0\n100.005 0 0 0 0 0 -0.005\n100.010 0 0 0 0 0 -0.005\n",
            Path::new("imu.txt"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("imu.txt:2: column `dvx`: median |f|") && e.contains("in g"),
            "{e}"
        );
    }

    /// `[checks] units = "warn"`: the same findings become warnings and
    /// the samples are read; `off`: not a word.
    #[test]
    fn the_unit_checks_can_warn_or_be_off() {
        let kf = b"100.000 0 0 0 0 0 0\n100.005 0 0 0 0 0 -0.005\n100.010 0 0 0 0 0 -0.005\n";
        let (imu, w) =
            read_kfgins_imu_checked_from(kf, Path::new("imu.txt"), CheckLevel::Warn).unwrap();
        assert_eq!(imu.len(), 2);
        assert!(w.iter().any(|w| w.contains("median |f|")), "{w:?}");
        let (_, w) =
            read_kfgins_imu_checked_from(kf, Path::new("imu.txt"), CheckLevel::Off).unwrap();
        assert!(!w.iter().any(|w| w.contains("median |f|")), "{w:?}");
        let text = format!("{HEADER}\n1.0,0,0,0,0,0,-1\n1.01,0,0,0,0,0,-1\n");
        let options = GenericImuOptions {
            units: None,
            unit_checks: CheckLevel::Warn,
        };
        let (imu, w) =
            read_generic_imu_with_from(text.as_bytes(), Path::new("g.csv"), options).unwrap();
        assert_eq!(imu.len(), 2);
        assert!(w.iter().any(|w| w.contains("median |f| = 1 m/s²")), "{w:?}");
    }

    #[test]
    fn impossible_rates_and_forces_name_their_line() {
        for (rows, message) in [
            (
                "1.0,0,0,0,0,0,-9.8\n1.01,0,0,57.3,0,0,-9.8\n",
                "g.csv:3: column `gx_rad_s`: |ω| = 57.3 rad/s",
            ),
            (
                "1.0,0,0,0,0,0,-9.8\n1.01,0,0,0,0,0,-9800\n",
                "g.csv:3: column `ax_m_s2`: |f| = 9800 m/s²",
            ),
        ] {
            let e = generic_err(&format!("{HEADER}\n{rows}"));
            assert!(e.starts_with(message), "{e}");
        }
    }

    /// A 13-column row in KF-GINS's layout (`time lat lon h vN vE vD σN σE
    /// σD σvN σvE σvD`, the position σ in columns 7–9 as KF-GINS's
    /// `GnssFileLoader` reads it): distinct values in every column land
    /// where KF-GINS puts them; a zero position σ is named by its column.
    #[test]
    fn kfgins_gnss_13_columns_hold_velocity_before_the_position_sigma() {
        let (f, w) = kf_gnss(
            "100.0 30.5 114.3 20.0 1.5 -2.5 0.25 0.01 0.02 0.03 0.1 0.2 0.3
",
        )
        .unwrap();
        assert!(w.is_empty());
        assert_eq!(f[0].position_sigma_neu, Vector3::new(0.01, 0.02, 0.03));
        assert_eq!(f[0].velocity_ned, Some(Vector3::new(1.5, -2.5, 0.25)));
        assert_eq!(f[0].velocity_sigma_neu, Some(Vector3::new(0.1, 0.2, 0.3)));
        assert_eq!(f[0].position.height_m, 20.0);
        // A velocity of zero is valid; a position σ of zero is not.
        let (f, _) = kf_gnss(
            "100.0 30.5 114.3 20.0 0 0 0 0.01 0.02 0.03 0.1 0.2 0.3
",
        )
        .unwrap();
        assert_eq!(f[0].velocity_ned, Some(Vector3::zeros()));
        let e = kf_gnss_err(
            "100.0 30.5 114.3 20.0 1 2 3 0.01 0 0.03 0.1 0.2 0.3
",
        );
        assert!(e.contains("gnss.txt:1: column `σE`: σ = 0"), "{e}");
        let e = kf_gnss_err(
            "100.0 30.5 114.3 20.0 x 2 3 0.01 0.02 0.03 0.1 0.2 0.3
",
        );
        assert!(e.contains("column `vN`"), "{e}");
        // Seven columns keep the σ in columns 4–6.
        let e = kf_gnss_err(
            "100.0 30.5 114.3 20.0 x 0.02 0.03
",
        );
        assert!(e.contains("column `σN`"), "{e}");
    }

    /// Ten fixes of a vehicle driving north-east and downhill (every
    /// velocity component positive), in KF-GINS's order or with the σ
    /// first.
    fn all_positive_drive(sigma_first: bool) -> String {
        let origin = Geodetic {
            latitude_rad: 30.5f64.to_radians(),
            longitude_rad: 114.3f64.to_radians(),
            height_m: 20.0,
        };
        let v = aidnav_frames::Vec3::new(3.0, 4.0, 0.5);
        (0..10)
            .map(|k| {
                let p = origin.offset_by(&(v * k as f64));
                let (lat, lon, h) = (
                    p.latitude_rad.to_degrees(),
                    p.longitude_rad.to_degrees(),
                    p.height_m,
                );
                let (velocity, sigma) = ("3 4 0.5", "0.02 0.02 0.05");
                let (first, second) = if sigma_first {
                    (sigma, velocity)
                } else {
                    (velocity, sigma)
                };
                format!(
                    "{}.0 {lat:.9} {lon:.9} {h:.3} {first} {second} 0.1 0.1 0.1\n",
                    100 + k
                )
            })
            .collect()
    }

    #[test]
    fn kfgins_gnss_columns_readable_in_both_orders_are_decided_by_the_positions() {
        let (f, _) = kf_gnss(&all_positive_drive(false)).unwrap();
        assert_eq!(f[3].velocity_ned, Some(Vector3::new(3.0, 4.0, 0.5)));
        let e = kf_gnss_err(&all_positive_drive(true));
        assert!(
            e.starts_with("gnss.txt:1: column `vN`: every value of columns 4–9 is positive")
                && e.contains("looks like `time lat lon h σN σE σD vN vE vD")
                && e.contains("generic_csv"),
            "{e}"
        );
        // One row: nothing to decide by.
        let drive = all_positive_drive(false);
        let e = kf_gnss_err(drive.lines().next().unwrap());
        assert!(e.contains("cannot tell"), "{e}");
    }

    #[test]
    fn kfgins_gnss_columns_must_be_7_or_13() {
        // Velocity without its σ used to be dropped silently.
        let e = kf_gnss_err(
            "100.0 30.5 114.3 20.0 0.01 0.01 0.02 1 2 3\n101.0 30.5 114.3 20.0 0.01 0.01 0.02 1 2 3\n",
        );
        assert!(
            e.starts_with("gnss.txt:1: column `(line)`: 10 fields, expected 7 or 13"),
            "{e}"
        );
        let e = kf_gnss_err("100.0 30.5 114.3 20.0 0.01 0.01 0.02 1 2 3 0.1 0.1 0.1 9\n");
        assert!(e.contains("14 fields, expected 7 or 13"), "{e}");
        let e = read_kfgins_imu_from(b"100.0 0 0 0 0 0 0 0\n", Path::new("imu.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("8 fields, expected 7"), "{e}");
    }

    #[test]
    fn kfgins_positions_are_range_checked() {
        for (line, message) in [
            (
                "100.0 30.5 114.3 -5000 0.01 0.01 0.02\n",
                "gnss.txt:1: column `height`: -5000 m is outside [-1000, 100000] m",
            ),
            (
                "100.0 30.5 414.3 20 0.01 0.01 0.02\n",
                "gnss.txt:1: column `longitude`",
            ),
        ] {
            let e = kf_gnss_err(line);
            assert!(e.starts_with(message), "{e}");
        }
    }

    #[test]
    fn cr_only_bom_and_long_headers() {
        // A CR-only file used to be one row (and its message quoted the file).
        let (s, _) = generic(&format!(
            "\u{FEFF}{HEADER}\r1.0,0,0,0,0,0,-9.8\r1.01,0,0,0,0,0,-9.8\r"
        ))
        .unwrap();
        assert_eq!(s.len(), 2);
        let header = format!("time_s,{}", "y".repeat(100_000));
        let e = generic_err(&format!("{header}\n1\n"));
        assert!(e.len() < 200 && e.contains('…'), "{} chars", e.len());
        let (f, _) = kf_gnss(
            "\u{FEFF}100.0 30.5 114.3 20.0 0.01 0.01 0.02\r101.0 30.5 114.3 20.0 0.01 0.01 0.02",
        )
        .unwrap();
        assert_eq!(f.len(), 2);
        let e = read_kfgins_gnss_from(b"100.0 30.5\xC3 114.3", Path::new("gnss.txt"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("gnss.txt:1: column `(text)`: invalid UTF-8 at byte 10"),
            "{e}"
        );
    }

    /// `text` as `g.csv` with the units declared.
    fn generic_with(
        text: &str,
        gyro: GyroUnit,
        accel: AccelUnit,
        kind: ImuKind,
    ) -> Result<(Vec<ImuSample>, Vec<String>)> {
        let units = Some(ImuUnits { gyro, accel, kind });
        read_generic_imu_with_from(
            text.as_bytes(),
            Path::new("g.csv"),
            GenericImuOptions {
                units,
                ..Default::default()
            },
        )
    }

    fn generic_with_err(text: &str, gyro: GyroUnit, accel: AccelUnit, kind: ImuKind) -> String {
        generic_with(text, gyro, accel, kind)
            .unwrap_err()
            .to_string()
    }

    /// `n` rows at rest at 100 Hz: gyro `w`, accelerometer `f`, as written.
    fn at_rest(header: &str, n: usize, w: [f64; 3], f: [f64; 3]) -> String {
        let mut t = format!("{header}\n");
        for k in 0..n {
            t += &format!(
                "{},{},{},{},{},{},{}\n",
                1.0 + 0.01 * k as f64,
                w[0],
                w[1],
                w[2],
                f[0],
                f[1],
                f[2]
            );
        }
        t
    }

    #[test]
    fn declared_units_convert_rates_and_increments() {
        use std::f64::consts::PI;
        // Increments over 10 ms: 0.01° about z and 0.01 g·s down.
        let csv = "time_s,gx,gy,gz,ax,ay,az\n1.00,0,0,0,0,0,0\n1.01,0,0,0.01,0,0,-0.01\n1.02,0,0,0.01,0,0,-0.01\n";
        let (s, _) =
            generic_with(csv, GyroUnit::DegPerS, AccelUnit::G, ImuKind::Increments).unwrap();
        assert_eq!(s.len(), 2);
        assert!(
            (s[0].angular_rate.z - PI / 180.0).abs() < 1e-9,
            "{}",
            s[0].angular_rate.z
        );
        assert!((s[1].specific_force.z + STANDARD_GRAVITY_M_S2).abs() < 1e-9);
        assert_eq!(s[0].time_s, 1.01);
        // The same in rad and m/s.
        let csv = "time_s,gx,gy,gz,ax,ay,az\n1.00,0,0,0,0,0,0\n1.01,0,0,1e-3,0,0,-0.098\n";
        let (s, _) = generic_with(
            csv,
            GyroUnit::RadPerS,
            AccelUnit::MPerS2,
            ImuKind::Increments,
        )
        .unwrap();
        assert!(
            (s[0].angular_rate.z - 0.1).abs() < 1e-9 && (s[0].specific_force.z + 9.8).abs() < 1e-9
        );
    }

    #[test]
    fn unit_free_names_need_declared_units_and_the_other_way_round() {
        let csv = at_rest("time_s,gx,gy,gz,ax,ay,az", 3, [0.0; 3], [0.0, 0.0, -9.8]);
        let e = generic_err(&csv);
        assert!(
            e.starts_with("g.csv:1: column `gx`: columns gx … az carry no unit")
                && e.contains("imu_units"),
            "{e}"
        );
        let csv = at_rest(HEADER, 3, [0.0; 3], [0.0, 0.0, -9.8]);
        let e = generic_with_err(&csv, GyroUnit::RadPerS, AccelUnit::MPerS2, ImuKind::Rates);
        assert!(
            e.starts_with("g.csv:1: column `gx_rad_s`: imu_units is declared"),
            "{e}"
        );
    }

    #[test]
    fn wrong_declared_units_are_refused_with_the_evidence() {
        let neutral = "time_s,gx,gy,gz,ax,ay,az";
        // A MEMS gyro's bias in deg/s (0.2, −0.3, 0.25) declared rad/s.
        let csv = at_rest(neutral, 50, [0.2, -0.3, 0.25], [0.1, 0.2, -9.8]);
        let e = generic_with_err(&csv, GyroUnit::RadPerS, AccelUnit::MPerS2, ImuKind::Rates);
        assert!(
            e.starts_with("g.csv:22: column `gx`: |ω| = 0.4387 rad/s")
                && e.contains("median over 41 stretches of 10 samples at rest")
                && e.contains("degrees per second read as radians"),
            "{e}"
        );
        // Declared deg/s, it passes (0.0077 rad/s).
        let ok = generic_with(&csv, GyroUnit::DegPerS, AccelUnit::MPerS2, ImuKind::Rates);
        assert_eq!(ok.unwrap().0.len(), 50);
        // m/s² declared g.
        let e = generic_with_err(&csv, GyroUnit::DegPerS, AccelUnit::G, ImuKind::Rates);
        assert!(
            e.starts_with("g.csv:2: column `ax`: median |f| = 96.1")
                && e.contains("imu_units.accel = \"m_s2\""),
            "{e}"
        );
        // g declared m/s².
        let csv = at_rest(neutral, 50, [0.0; 3], [0.0, 0.0, -1.0]);
        let e = generic_with_err(&csv, GyroUnit::DegPerS, AccelUnit::MPerS2, ImuKind::Rates);
        assert!(
            e.contains("median |f| = 1 m/s²") && e.contains("imu_units.accel = \"g\""),
            "{e}"
        );
    }

    #[test]
    fn units_deserialize_from_the_configuration_names() {
        let u: ImuUnits = toml::from_str("gyro = \"deg_s\"\naccel = \"g\"\n").unwrap();
        assert_eq!(
            u,
            ImuUnits {
                gyro: GyroUnit::DegPerS,
                accel: AccelUnit::G,
                kind: ImuKind::Rates
            }
        );
        assert!(toml::from_str::<ImuUnits>("gyro = \"deg\"\naccel = \"g\"\n").is_err());
        assert!(
            toml::from_str::<ImuUnits>(
                "gyro = \"rad_s\"\naccel = \"g\"\nkind = \"increments\"\nx = 1\n"
            )
            .is_err()
        );
    }
}
