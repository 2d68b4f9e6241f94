//! The reference (truth) trajectory CSV: what a simulator writes beside its
//! sensor logs, and what a user can supply for their own logs (from a
//! tactical-grade system or a post-processed solution) to score a run
//! against.
//!
//! ```text
//! # aidnav simulate 0.4.0
//! # seed = 42
//! time_s,latitude_deg,longitude_deg,height_m,velocity_north_m_s,velocity_east_m_s,velocity_down_m_s,roll_deg,pitch_deg,yaw_deg
//! 1724716800,30.5,114.3,20,10,0,0,0,0,90
//! ```
//!
//! | column | meaning |
//! | --- | --- |
//! | `time_s` | GPST seconds since 1970-01-01 (the scale of the logs) |
//! | `latitude_deg`, `longitude_deg` | WGS-84 latitude, longitude \[deg\] |
//! | `height_m` | ellipsoidal height \[m\] |
//! | `velocity_north_m_s`, `velocity_east_m_s`, `velocity_down_m_s` | NED velocity \[m/s\] (optional, the three together) |
//! | `roll_deg`, `pitch_deg`, `yaw_deg` | attitude of the body frame, Euler angles ZYX \[deg\] (optional, the three together) |
//!
//! Rules:
//! - lines starting with `#` before the header are comments (the writer
//!   puts the caller's header lines there: seed, version, scenario);
//!   blank lines are skipped; a UTF-8 byte-order mark is stripped; LF,
//!   CR LF or CR line ends; columns in any order;
//! - a file with only time and position is valid; in a file with velocity
//!   or attitude columns, a row may leave all three cells of one group
//!   empty (none that epoch), not some;
//! - errors name the file, the line and the column: an unknown or repeated
//!   column, a group with a column missing, not a number, not finite,
//!   |latitude| > 90°, |longitude| > 360°, a height outside −1 000 …
//!   100 000 m ([`crate::limits`]), time that does not increase; a
//!   truncated last line is skipped with a warning. No input makes the
//!   reader panic.
//!
//! Round trip: [`write_reference`] writes every number with Rust's `{}`
//! (the shortest decimal that reads back as the same `f64`), so time,
//! height and velocity come back exactly; angles are held in radians and
//! written in degrees, so they come back within 2 ulp (relative 4.5e-16:
//! `to_degrees` then `to_radians`).

use std::fmt::Write as _;
use std::path::Path;

use aidnav_sensors::Timed;

use crate::error::{IoError, Result};
use crate::named_csv::{Header, Row, TimeForm, read_table};

/// The columns of the reference CSV, in the writer's order.
pub const REFERENCE_COLUMNS: [&str; 10] = [
    "time_s",
    "latitude_deg",
    "longitude_deg",
    "height_m",
    "velocity_north_m_s",
    "velocity_east_m_s",
    "velocity_down_m_s",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
];

/// One epoch of a reference trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSample {
    /// GPST, seconds since 1970-01-01.
    pub time_s: f64,
    /// WGS-84 latitude \[rad\].
    pub latitude_rad: f64,
    /// WGS-84 longitude \[rad\].
    pub longitude_rad: f64,
    /// Ellipsoidal height \[m\].
    pub height_m: f64,
    /// NED velocity \[m/s\], when known.
    pub velocity_ned_m_s: Option<[f64; 3]>,
    /// Roll, pitch, yaw of the body frame (ZYX Euler angles) \[rad\], when
    /// known.
    pub attitude_rpy_rad: Option<[f64; 3]>,
}

impl Timed for ReferenceSample {
    fn time_s(&self) -> f64 {
        self.time_s
    }
}

fn write_error(path: &Path, message: impl Into<String>) -> IoError {
    IoError::Write {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Write `samples` to `path` (atomically, the directory created): each of
/// `header_lines` as a `# ` comment line (a line holding line breaks
/// becomes several), the header, one row per sample. The velocity and
/// attitude columns are written when any sample has them (empty cells for
/// the others). Errors (nothing written): no sample, a non-finite value,
/// |latitude| > 90°, time that does not increase.
pub fn write_reference(
    path: &Path,
    samples: &[ReferenceSample],
    header_lines: &[String],
) -> Result<()> {
    if samples.is_empty() {
        return Err(write_error(path, "no reference sample to write"));
    }
    let velocity = samples.iter().any(|s| s.velocity_ned_m_s.is_some());
    let attitude = samples.iter().any(|s| s.attitude_rpy_rad.is_some());
    let mut text = String::with_capacity(160 * (samples.len() + 2));
    for line in header_lines {
        for part in crate::text::lines(line) {
            let _ = writeln!(text, "# {part}");
        }
        if line.is_empty() {
            text.push_str("#\n");
        }
    }
    let mut columns: Vec<&str> = REFERENCE_COLUMNS[..4].to_vec();
    if velocity {
        columns.extend(&REFERENCE_COLUMNS[4..7]);
    }
    if attitude {
        columns.extend(&REFERENCE_COLUMNS[7..10]);
    }
    text.push_str(&columns.join(","));
    text.push('\n');
    let mut previous: Option<f64> = None;
    for (k, s) in samples.iter().enumerate() {
        let mut values = vec![s.time_s, s.latitude_rad, s.longitude_rad, s.height_m];
        values.extend(s.velocity_ned_m_s.iter().flatten());
        values.extend(s.attitude_rpy_rad.iter().flatten());
        if !values.iter().all(|v| v.is_finite()) {
            return Err(write_error(
                path,
                format!("reference sample {k}: a value is not finite"),
            ));
        }
        if s.latitude_rad.to_degrees().abs() > 90.0 {
            return Err(write_error(
                path,
                format!("reference sample {k}: latitude beyond ±90°"),
            ));
        }
        if let Some(p) = previous
            && s.time_s <= p
        {
            return Err(write_error(
                path,
                format!(
                    "reference sample {k}: time {} does not increase (previous {})",
                    crate::text::num(s.time_s),
                    crate::text::num(p)
                ),
            ));
        }
        previous = Some(s.time_s);
        let _ = write!(
            text,
            "{},{},{},{}",
            s.time_s,
            s.latitude_rad.to_degrees(),
            s.longitude_rad.to_degrees(),
            s.height_m
        );
        if velocity {
            match s.velocity_ned_m_s {
                Some([n, e, d]) => {
                    let _ = write!(text, ",{n},{e},{d}");
                }
                None => text.push_str(",,,"),
            }
        }
        if attitude {
            match s.attitude_rpy_rad {
                Some(a) => {
                    let [r, p, y] = a.map(f64::to_degrees);
                    let _ = write!(text, ",{r},{p},{y}");
                }
                None => text.push_str(",,,"),
            }
        }
        text.push('\n');
    }
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        crate::writers::ensure_dir(dir)?;
    }
    crate::writers::write_atomic(path, text.as_bytes())
}

/// Read a reference trajectory CSV (see the module docs): the samples and
/// the warnings.
///
/// ```
/// use aidnav_io::reference::read_reference_from;
/// let csv = "# seed = 7\ntime_s,latitude_deg,longitude_deg,height_m\n100,30,114,20\n100.1,30,114,20.5\n";
/// let (samples, warnings) = read_reference_from(csv.as_bytes(), "truth.csv".as_ref()).unwrap();
/// assert_eq!((samples.len(), samples[1].height_m), (2, 20.5));
/// assert!(samples[0].velocity_ned_m_s.is_none() && warnings.is_empty());
/// ```
pub fn read_reference(path: &Path) -> Result<(Vec<ReferenceSample>, Vec<String>)> {
    read_reference_from(&crate::text::read_bytes(path)?, path)
}

/// The column groups of a header.
struct Layout {
    position: [usize; 3],
    velocity: Option<[usize; 3]>,
    attitude: Option<[usize; 3]>,
}

/// The three indices of a found group.
fn three(v: &[usize]) -> [usize; 3] {
    [0, 1, 2].map(|k| v.get(k).copied().unwrap_or(0))
}

impl Layout {
    fn parse(h: &Header) -> Result<Self> {
        let position = h
            .group("a position", &REFERENCE_COLUMNS[1..4])?
            .ok_or_else(|| {
                h.error(
                    "latitude_deg",
                    "column missing: a position needs latitude_deg, longitude_deg, height_m",
                )
            })?;
        let velocity = h.group("a velocity", &REFERENCE_COLUMNS[4..7])?;
        let attitude = h.group("an attitude", &REFERENCE_COLUMNS[7..10])?;
        Ok(Self {
            position: three(&position),
            velocity: velocity.as_deref().map(three),
            attitude: attitude.as_deref().map(three),
        })
    }

    /// An optional group of three numbers: None when all its cells are
    /// empty.
    fn optional(row: &Row, cols: Option<[usize; 3]>, what: &str) -> Result<Option<[f64; 3]>> {
        let Some(c) = cols else {
            return Ok(None);
        };
        let empty = c.iter().filter(|&&i| row.cell(i).is_empty()).count();
        match empty {
            3 => Ok(None),
            0 => Ok(Some([
                row.number(c[0])?,
                row.number(c[1])?,
                row.number(c[2])?,
            ])),
            _ => {
                let first = c
                    .iter()
                    .copied()
                    .find(|&i| row.cell(i).is_empty())
                    .unwrap_or(c[0]);
                Err(row.error(
                    first,
                    format!(
                        "empty while other {what} cells of the row are not: give all three or none"
                    ),
                ))
            }
        }
    }

    fn sample(&self, row: &Row, time_s: f64) -> Result<ReferenceSample> {
        use crate::limits::*;
        let [la, lo, h] = self.position;
        let lat = row.bounded(la, -MAX_LATITUDE_DEG, MAX_LATITUDE_DEG, "deg", "the poles")?;
        let lon = row.bounded(
            lo,
            -MAX_LONGITUDE_DEG,
            MAX_LONGITUDE_DEG,
            "deg",
            "±180° or 0–360°",
        )?;
        let height = row.bounded(
            h,
            MIN_HEIGHT_M,
            MAX_HEIGHT_M,
            "m",
            "below the lowest land or above 100 km",
        )?;
        let velocity = Self::optional(row, self.velocity, "velocity")?;
        if let Some(v) = velocity {
            let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if let Some(m) = outside(speed, 0.0, MAX_SPEED_M_S, "m/s", "faster than any vehicle") {
                return Err(row.error(self.velocity.map_or(0, |c| c[0]), format!("speed {m}")));
            }
        }
        let attitude = Self::optional(row, self.attitude, "attitude")?;
        Ok(ReferenceSample {
            time_s,
            latitude_rad: lat.to_radians(),
            longitude_rad: lon.to_radians(),
            height_m: height,
            velocity_ned_m_s: velocity,
            attitude_rpy_rad: attitude.map(|a| a.map(f64::to_radians)),
        })
    }
}

/// [`read_reference`] on the file's bytes; `origin` names them in messages.
pub fn read_reference_from(
    bytes: &[u8],
    origin: &Path,
) -> Result<(Vec<ReferenceSample>, Vec<String>)> {
    read_table(
        bytes,
        origin,
        &REFERENCE_COLUMNS,
        |h| {
            let time = TimeForm::parse(h, true)?;
            Ok((Layout::parse(h)?, time))
        },
        |layout, row, time_s| layout.sample(row, time_s),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(k: usize, velocity: bool, attitude: bool) -> ReferenceSample {
        let t = k as f64;
        ReferenceSample {
            time_s: 1_724_716_800.0 + 0.01 * t,
            latitude_rad: (30.5 + 1e-7 * t).to_radians() + 1e-17,
            longitude_rad: (114.3 - 3e-7 * t).to_radians(),
            height_m: 20.0 + 0.123_456_789 * t,
            velocity_ned_m_s: velocity.then_some([10.0 + 0.1 * t, -0.3, 1.0 / 3.0]),
            attitude_rpy_rad: attitude.then_some([0.01 * t, -0.02, std::f64::consts::PI - 0.1 * t]),
        }
    }

    fn close(a: f64, b: f64) -> bool {
        a == b || (a - b).abs() <= 4.5e-16 * a.abs().max(b.abs())
    }

    fn same(a: &ReferenceSample, b: &ReferenceSample) -> bool {
        let opt = |x: Option<[f64; 3]>, y: Option<[f64; 3]>, exact: bool| match (x, y) {
            (None, None) => true,
            (Some(x), Some(y)) => x
                .iter()
                .zip(&y)
                .all(|(p, q)| if exact { p == q } else { close(*p, *q) }),
            _ => false,
        };
        a.time_s == b.time_s
            && close(a.latitude_rad, b.latitude_rad)
            && close(a.longitude_rad, b.longitude_rad)
            && a.height_m == b.height_m
            && opt(a.velocity_ned_m_s, b.velocity_ned_m_s, true)
            && opt(a.attitude_rpy_rad, b.attitude_rpy_rad, false)
    }

    #[test]
    fn reference_round_trips_with_and_without_optional_columns() {
        let dir = tempfile::tempdir().unwrap();
        let header = vec![
            "aidnav simulate 0.4.0".to_string(),
            "seed = 42\nscenario = x".into(),
        ];
        for (velocity, attitude) in [(false, false), (true, false), (false, true), (true, true)] {
            let mut samples: Vec<ReferenceSample> =
                (0..50).map(|k| sample(k, velocity, attitude)).collect();
            if velocity {
                samples[3].velocity_ned_m_s = None;
            }
            let path = dir
                .path()
                .join(format!("sub/truth_{velocity}_{attitude}.csv"));
            write_reference(&path, &samples, &header).unwrap();
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(
                text.starts_with("# aidnav simulate 0.4.0\n# seed = 42\n# scenario = x\ntime_s,"),
                "{text}"
            );
            let (back, warnings) = read_reference(&path).unwrap();
            assert!(warnings.is_empty(), "{warnings:?}");
            assert_eq!(back.len(), samples.len());
            for (a, b) in samples.iter().zip(&back) {
                assert!(same(a, b), "{a:?}\n{b:?}");
            }
        }
    }

    #[test]
    fn bad_reference_files_are_errors_naming_line_and_column() {
        let o = Path::new("t.csv");
        let h = "time_s,latitude_deg,longitude_deg,height_m,roll_deg,pitch_deg,yaw_deg\n";
        let cases = [
            (
                format!("{h}1,30,114,0,0,0,0\n1,30,114,0,0,0,0\n"),
                "t.csv:3: column `time_s`",
            ),
            (
                format!("{h}1,91,114,0,0,0,0\n"),
                "t.csv:2: column `latitude_deg`",
            ),
            (
                format!("{h}1,30,114,inf,0,0,0\n"),
                "t.csv:2: column `height_m`",
            ),
            (
                format!("{h}1,30,114,0,0,,0\n"),
                "t.csv:2: column `pitch_deg`",
            ),
            (
                format!("{h}1,30,x,0,0,0,0\n"),
                "t.csv:2: column `longitude_deg`",
            ),
            (
                "time_s,latitude_deg,longitude_deg\n1,2,3\n".to_string(),
                "t.csv:1: column `height_m`",
            ),
            (
                "time_s,latitude_deg,longitude_deg,height_m,roll_deg\n1,2,3,4,5\n".to_string(),
                "t.csv:1: column `pitch_deg`",
            ),
            ("time_s,lat\n".to_string(), "t.csv:1: column `lat`"),
            (String::new(), "t.csv:0: column `(header)`"),
        ];
        for (text, want) in cases {
            let e = read_reference_from(text.as_bytes(), o)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(want), "{want}: {e}");
        }
        // Empty attitude cells: no attitude that epoch; a truncated last
        // line is a warning.
        let (s, w) =
            read_reference_from(format!("{h}1,30,114,0,,,\n2,30,114,0,1,2\n").as_bytes(), o)
                .unwrap();
        assert_eq!((s.len(), w.len()), (1, 1));
        assert!(s[0].attitude_rpy_rad.is_none());
    }

    #[test]
    fn the_writer_refuses_what_the_reader_would() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        let mut s = vec![sample(0, true, true), sample(1, true, true)];
        assert!(write_reference(&path, &[], &[]).is_err());
        s[1].time_s = s[0].time_s;
        assert!(write_reference(&path, &s, &[]).is_err());
        s[1].time_s += 1.0;
        s[1].latitude_rad = 2.0;
        assert!(write_reference(&path, &s, &[]).is_err());
        s[1].latitude_rad = 0.5;
        s[1].attitude_rpy_rad = Some([f64::NAN, 0.0, 0.0]);
        assert!(write_reference(&path, &s, &[]).is_err());
        assert!(!path.exists());
    }

    /// Random bytes and mutated files: errors, never a panic.
    #[test]
    fn no_input_panics() {
        let mut next = crate::xorshift(0x1234_5678_9ABC_DEF1);
        let good = "# c\ntime_s,latitude_deg,longitude_deg,height_m,velocity_north_m_s,velocity_east_m_s,velocity_down_m_s\n1,30,114,0,1,2,3\n2,30,114,0,,,\n";
        let alphabet = b",.-+e0123456789#\n\r NaiftmS_\xC3\xEF";
        for _ in 0..3000 {
            let mut bytes = good.as_bytes().to_vec();
            for _ in 0..(next() % 6) {
                let at = (next() as usize) % (bytes.len() + 1);
                let c = alphabet[(next() as usize) % alphabet.len()];
                match next() % 3 {
                    0 if at < bytes.len() => bytes[at] = c,
                    1 if at < bytes.len() => {
                        bytes.remove(at);
                    }
                    _ => bytes.insert(at, c),
                }
            }
            let _ = read_reference_from(&bytes, Path::new("f.csv"));
        }
    }
}
