//! aidnav's generic GNSS CSV: any receiver's or tool's solution written as
//! a comma-separated file with a header row naming its columns (any order).
//!
//! | columns | meaning |
//! | --- | --- |
//! | **time**, one of: | |
//! | `gpst_s` | GPST seconds since 1970-01-01 (no leap seconds) |
//! | `gps_week`, `tow_s` | GPS week (integer) and seconds of week |
//! | `utc` | ISO 8601 UTC time, `2024-08-27T17:30:00.2Z` (a space for the `T`, an offset `+02:00` or no zone = UTC accepted); converted to GPST with the leap seconds of its date |
//! | **position**, one of: | |
//! | `lat_deg`, `lon_deg`, `height_m` | WGS-84 latitude, longitude \[deg\], ellipsoidal height \[m\] |
//! | `lat_deg`, `lon_deg`, `height_msl_m`, `geoid_sep_m` | height above mean sea level and the geoid separation (ellipsoid − geoid, as NMEA GGA's field 11) \[m\]; their sum is used |
//! | `ecef_x_m`, `ecef_y_m`, `ecef_z_m` | WGS-84 ECEF \[m\] |
//! | **position σ**, one of: | |
//! | `sigma_n_m`, `sigma_e_m`, `sigma_u_m` | 1σ north, east, up \[m\] |
//! | `sigma_h_m`, `sigma_v_m` | 1σ of *each* horizontal axis (north and east), and up \[m\] |
//! | (none) | the configuration's `[data] gnss_sigma_m = [horizontal, vertical]` (same meaning); without it an error |
//! | **velocity** (optional), one of: | |
//! | `vel_n_mps`, `vel_e_mps`, `vel_d_mps` | NED velocity \[m/s\] |
//! | `speed_mps`, `course_deg` \[, `vertical_speed_mps`\] | speed over ground, course clockwise from north \[deg\], vertical speed (up positive) |
//! | `sigma_vel_mps` | 1σ of each velocity axis \[m/s\] (optional) |
//! | `quality` (optional) | `fixed`, `float`, `dgps`, `single` or RTKLIB's Q (0–6); absent: 0 (unknown) |
//! | `satellites` (optional) | number of satellites used |
//!
//! Rules:
//! - a header name not in [`KNOWN_COLUMNS`] is an error listing the known
//!   names (nothing is silently dropped); a time or position form with a
//!   column missing, two forms of one quantity, or a repeated name are
//!   errors naming the columns;
//! - blank lines and lines starting with `#` are skipped (before the header
//!   too); a UTF-8 byte-order mark is stripped; LF, CR LF or CR line ends;
//! - every cell must hold a value, except: the velocity cells of a row may
//!   all be empty (no velocity that epoch), and `quality`, `satellites`,
//!   `sigma_vel_mps` may be empty (unknown);
//! - every bad value is an error naming the file, the line and the column:
//!   not a number, not finite, |latitude| > 90°, |longitude| > 360°, a
//!   height outside −1 000 … 100 000 m, a geoid separation beyond ±200 m, a
//!   speed beyond 1 000 m/s ([`crate::limits`]), σ ≤ 0 (or beyond 10 000 km
//!   / 10 km/s), a GPST before GPS time began (1980-01-06: seconds of week
//!   or since 1980 given as seconds since 1970?), seconds of week outside
//!   [0, 604 800), an impossible date, time that does not increase;
//! - a truncated last line (fewer cells than the header) is skipped with a
//!   warning, as in the other readers;
//! - velocity without `sigma_vel_mps` gets 0.1 m/s on each axis; speed and
//!   course without a vertical speed give a vertical velocity of 0 with σ
//!   10 m/s (practically unobserved); both are reported as warnings.
//!
//! `examples/data/gnss_generic_example.csv` is a documented example.

use std::path::Path;

use aidnav_frames::Vec3;
use aidnav_frames::earth::Geodetic;
use nalgebra::Vector3;

use crate::error::Result;
use crate::named_csv::{Header, Row, TimeForm, read_table};
use crate::rtklib::GnssFix;
use crate::text::{days_from_civil, excerpt, num, read_bytes};

/// Options of the reader that come from the configuration.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GenericGnssOptions {
    /// σ of each horizontal axis and of up \[m\] for files without σ
    /// columns (`[data] gnss_sigma_m`); σ columns, when present, win.
    pub default_sigma_m: Option<[f64; 2]>,
}

/// Every column name the reader knows, in the order of the module docs.
pub const KNOWN_COLUMNS: [&str; 26] = [
    "gpst_s",
    "gps_week",
    "tow_s",
    "utc",
    "lat_deg",
    "lon_deg",
    "height_m",
    "height_msl_m",
    "geoid_sep_m",
    "ecef_x_m",
    "ecef_y_m",
    "ecef_z_m",
    "sigma_n_m",
    "sigma_e_m",
    "sigma_u_m",
    "sigma_h_m",
    "sigma_v_m",
    "vel_n_mps",
    "vel_e_mps",
    "vel_d_mps",
    "speed_mps",
    "course_deg",
    "vertical_speed_mps",
    "sigma_vel_mps",
    "quality",
    "satellites",
];

/// Velocity σ of each axis when the file gives none \[m/s\]: a typical
/// receiver's Doppler velocity (u-blox and Septentrio quote 0.05–0.1 m/s).
pub const DEFAULT_VELOCITY_SIGMA_MPS: f64 = 0.1;

/// σ of the vertical velocity set to 0 when only speed and course are given
/// \[m/s\]: practically unobserved (as the NMEA reader does).
pub const UNOBSERVED_VERTICAL_SIGMA_MPS: f64 = 10.0;

/// Largest position σ accepted \[m\]: beyond the Earth's size a fix carries
/// no information (and its square nears overflow).
const MAX_POSITION_SIGMA_M: f64 = 1e7;

/// Largest velocity σ accepted \[m/s\].
const MAX_VELOCITY_SIGMA_MPS: f64 = 1e4;

/// Largest geoid separation magnitude accepted \[m\] (EGM2008 spans
/// −107…+86 m).
const MAX_GEOID_SEPARATION_M: f64 = 200.0;

/// How the position is given.
#[derive(Debug, Clone, Copy)]
enum PositionForm {
    Ellipsoidal([usize; 3]),
    Msl([usize; 4]),
    Ecef([usize; 3]),
}

/// How the position σ is given.
#[derive(Debug, Clone, Copy)]
enum SigmaForm {
    Neu([usize; 3]),
    HorizontalVertical([usize; 2]),
    Default([f64; 2]),
}

/// How the velocity is given.
#[derive(Debug, Clone, Copy)]
enum VelocityForm {
    Ned([usize; 3]),
    SpeedCourse([usize; 2], Option<usize>),
}

/// The header resolved into forms (column indices).
#[derive(Debug, Clone)]
struct Layout {
    position: PositionForm,
    sigma: SigmaForm,
    velocity: Option<VelocityForm>,
    sigma_vel: Option<usize>,
    quality: Option<usize>,
    satellites: Option<usize>,
}

/// Read a generic GNSS CSV (see the module docs).
///
/// ```
/// use aidnav_io::generic_gnss::{GenericGnssOptions, read_generic_gnss_from};
/// let csv = "utc,lat_deg,lon_deg,height_msl_m,geoid_sep_m,speed_mps,course_deg,quality\n\
///            2025-08-28T17:30:21.75Z,40.0966916,-105.1471665,1601.435,-21.387,1.0,90,fixed\n";
/// let options = GenericGnssOptions { default_sigma_m: Some([0.02, 0.04]) };
/// let (fixes, warnings) = read_generic_gnss_from(csv.as_bytes(), "g.csv".as_ref(), options).unwrap();
/// let f = fixes[0];
/// // UTC + 18 leap seconds: GPS week 2381, 408 639.75 s of week.
/// assert_eq!(f.time_s, 315_964_800.0 + 2381.0 * 604_800.0 + 408_639.75);
/// assert!((f.position.height_m - 1580.048).abs() < 1e-9);
/// assert_eq!((f.quality, f.position_sigma_neu.z), (1, 0.04));
/// assert!((f.velocity_ned.unwrap().y - 1.0).abs() < 1e-12); // due east
/// assert_eq!(warnings.len(), 2); // velocity σ and vertical velocity assumed
/// ```
pub fn read_generic_gnss(
    path: &Path,
    options: GenericGnssOptions,
) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_generic_gnss_from(&read_bytes(path)?, path, options)
}

/// [`read_generic_gnss`] on the file's bytes; `path` names the origin in
/// messages.
pub fn read_generic_gnss_from(
    bytes: &[u8],
    path: &Path,
    options: GenericGnssOptions,
) -> Result<(Vec<GnssFix>, Vec<String>)> {
    let (mut no_sigma_vel, mut no_vertical) = (0usize, 0usize);
    let (fixes, mut warnings) = read_table(
        bytes,
        path,
        &KNOWN_COLUMNS,
        |h| {
            let time = TimeForm::parse(h, false)?;
            Ok((Layout::parse(h, options)?, time))
        },
        |layout, row, time_s| layout.fix(row, time_s, &mut no_sigma_vel, &mut no_vertical),
    )?;
    let p = path.display();
    if no_sigma_vel > 0 {
        warnings.push(format!(
            "{p}: {no_sigma_vel} epochs with velocity but no sigma_vel_mps: {DEFAULT_VELOCITY_SIGMA_MPS} m/s assumed on each axis"
        ));
    }
    if no_vertical > 0 {
        warnings.push(format!(
            "{p}: {no_vertical} epochs with speed and course but no vertical_speed_mps: vertical velocity 0 with σ {UNOBSERVED_VERTICAL_SIGMA_MPS} m/s (unobserved)"
        ));
    }
    Ok((fixes, warnings))
}

impl Layout {
    /// Resolve the header (its names known, each once) into complete
    /// forms; the time form is [`TimeForm::parse`]'s.
    fn parse(h: &Header, options: GenericGnssOptions) -> Result<Self> {
        let find = |n: &str| h.find(n);
        let group = |what: &str, cols: &[&str]| h.group(what, cols);
        let one_of =
            |quantity: &str, forms: &[(&str, Option<&Vec<usize>>)]| h.one_of(quantity, forms);
        let err = |column: &str, message: String| h.error(column, message);
        let at = |v: &[usize], k: usize| v.get(k).copied().unwrap_or(0);

        let has_msl = find("height_msl_m").is_some() || find("geoid_sep_m").is_some();
        let geodetic = group("a geodetic position", &["lat_deg", "lon_deg"])?;
        let ellipsoidal = group("an ellipsoidal height", &["height_m"])?;
        let msl = group("a height above sea level", &["height_msl_m", "geoid_sep_m"])?;
        let ecef = group("an ECEF position", &["ecef_x_m", "ecef_y_m", "ecef_z_m"])?;
        one_of(
            "the height",
            &[
                ("height_m", ellipsoidal.as_ref()),
                ("height_msl_m + geoid_sep_m", msl.as_ref()),
            ],
        )?;
        one_of(
            "the position",
            &[
                ("lat_deg + lon_deg", geodetic.as_ref()),
                ("ecef_x_m + ecef_y_m + ecef_z_m", ecef.as_ref()),
            ],
        )?;
        let position = match (&geodetic, &ellipsoidal, &msl, &ecef) {
            (Some(g), Some(h), _, _) => PositionForm::Ellipsoidal([at(g, 0), at(g, 1), at(h, 0)]),
            (Some(g), _, Some(m), _) => PositionForm::Msl([at(g, 0), at(g, 1), at(m, 0), at(m, 1)]),
            (Some(_), None, None, _) => {
                return Err(err(
                    "height_m",
                    "column missing: a height is needed: height_m (ellipsoidal) or height_msl_m and geoid_sep_m".into(),
                ));
            }
            (None, _, _, Some(e)) if ellipsoidal.is_none() && !has_msl => {
                PositionForm::Ecef([at(e, 0), at(e, 1), at(e, 2)])
            }
            (None, _, _, Some(_)) => {
                return Err(err(
                    "(header)",
                    "an ECEF position takes no height column: drop height_m / height_msl_m / geoid_sep_m".into(),
                ));
            }
            (None, _, _, None) => {
                return Err(err(
                    "(position)",
                    "no position columns: give lat_deg, lon_deg with height_m (or height_msl_m and geoid_sep_m), or ecef_x_m, ecef_y_m, ecef_z_m".into(),
                ));
            }
        };

        let neu = group("σ north/east/up", &["sigma_n_m", "sigma_e_m", "sigma_u_m"])?;
        let hv = group("σ horizontal/vertical", &["sigma_h_m", "sigma_v_m"])?;
        one_of(
            "the position σ",
            &[
                ("sigma_n_m + sigma_e_m + sigma_u_m", neu.as_ref()),
                ("sigma_h_m + sigma_v_m", hv.as_ref()),
            ],
        )?;
        let sigma = match (&neu, &hv, options.default_sigma_m) {
            (Some(s), _, _) => SigmaForm::Neu([at(s, 0), at(s, 1), at(s, 2)]),
            (_, Some(s), _) => SigmaForm::HorizontalVertical([at(s, 0), at(s, 1)]),
            (None, None, Some(d)) => SigmaForm::Default(d),
            (None, None, None) => {
                return Err(err(
                    "(σ)",
                    "no position σ: give the columns sigma_n_m, sigma_e_m, sigma_u_m (or sigma_h_m, sigma_v_m), or one σ for the whole file in the configuration: [data] gnss_sigma_m = [horizontal, vertical] (metres, each horizontal axis and up)".into(),
                ));
            }
        };

        let ned = group("an NED velocity", &["vel_n_mps", "vel_e_mps", "vel_d_mps"])?;
        let speed = group("speed and course", &["speed_mps", "course_deg"])?;
        one_of(
            "the velocity",
            &[
                ("vel_n_mps + vel_e_mps + vel_d_mps", ned.as_ref()),
                ("speed_mps + course_deg", speed.as_ref()),
            ],
        )?;
        let vertical = find("vertical_speed_mps");
        let velocity = match (&ned, &speed) {
            (Some(v), _) => Some(VelocityForm::Ned([at(v, 0), at(v, 1), at(v, 2)])),
            (_, Some(s)) => Some(VelocityForm::SpeedCourse([at(s, 0), at(s, 1)], vertical)),
            _ => None,
        };
        if vertical.is_some() && speed.is_none() {
            return Err(err(
                "vertical_speed_mps",
                "only with speed_mps and course_deg (an NED velocity has vel_d_mps)".into(),
            ));
        }
        let sigma_vel = find("sigma_vel_mps");
        if sigma_vel.is_some() && velocity.is_none() {
            return Err(err(
                "sigma_vel_mps",
                "a velocity σ without velocity columns (vel_n_mps, vel_e_mps, vel_d_mps or speed_mps, course_deg)".into(),
            ));
        }
        Ok(Self {
            position,
            sigma,
            velocity,
            sigma_vel,
            quality: find("quality"),
            satellites: find("satellites"),
        })
    }

    /// One row, whose time is `time_s`, as a fix.
    fn fix(
        &self,
        row: &Row,
        time_s: f64,
        no_sigma_vel: &mut usize,
        no_vertical: &mut usize,
    ) -> Result<GnssFix> {
        let position = self.position(row)?;
        let position_sigma_neu = match self.sigma {
            SigmaForm::Neu(c) => Vector3::new(
                row.sigma(c[0], MAX_POSITION_SIGMA_M, "m")?,
                row.sigma(c[1], MAX_POSITION_SIGMA_M, "m")?,
                row.sigma(c[2], MAX_POSITION_SIGMA_M, "m")?,
            ),
            SigmaForm::HorizontalVertical([h, v]) => {
                let h = row.sigma(h, MAX_POSITION_SIGMA_M, "m")?;
                Vector3::new(h, h, row.sigma(v, MAX_POSITION_SIGMA_M, "m")?)
            }
            SigmaForm::Default([h, v]) => Vector3::new(h, h, v),
        };
        let (velocity_ned, velocity_sigma_neu) =
            match self.velocity(row, no_sigma_vel, no_vertical)? {
                Some((v, s)) => (Some(v), Some(s)),
                None => (None, None),
            };
        let quality = match self.quality {
            Some(c) if !row.cell(c).is_empty() => quality(row, c)?,
            _ => 0,
        };
        let satellites = match self.satellites {
            Some(c) if !row.cell(c).is_empty() => {
                let n = row.bounded(c, 0.0, 1000.0, "", "a receiver tracks fewer")?;
                if n.fract() != 0.0 {
                    return Err(row.error(c, format!("{} is not a whole number", num(n))));
                }
                n as u32
            }
            _ => 0,
        };
        Ok(GnssFix {
            time_s,
            position,
            quality,
            satellites,
            position_sigma_neu,
            velocity_ned,
            velocity_sigma_neu,
        })
    }

    fn position(&self, row: &Row) -> Result<Geodetic> {
        use crate::limits::*;
        let lat_lon = |la: usize, lo: usize| -> Result<(f64, f64)> {
            Ok((
                row.bounded(la, -MAX_LATITUDE_DEG, MAX_LATITUDE_DEG, "deg", "the poles")?,
                row.bounded(
                    lo,
                    -MAX_LONGITUDE_DEG,
                    MAX_LONGITUDE_DEG,
                    "deg",
                    "±180° or 0–360°",
                )?,
            ))
        };
        let height_why = "below the lowest land or above 100 km";
        let (lat, lon, height) = match self.position {
            PositionForm::Ellipsoidal([la, lo, h]) => {
                let (lat, lon) = lat_lon(la, lo)?;
                (
                    lat,
                    lon,
                    row.bounded(h, MIN_HEIGHT_M, MAX_HEIGHT_M, "m", height_why)?,
                )
            }
            PositionForm::Msl([la, lo, h, n]) => {
                let (lat, lon) = lat_lon(la, lo)?;
                let msl = row.number(h)?;
                let separation = row.bounded(
                    n,
                    -MAX_GEOID_SEPARATION_M,
                    MAX_GEOID_SEPARATION_M,
                    "m",
                    "the geoid undulation spans −107…+86 m",
                )?;
                let height = msl + separation;
                if let Some(m) = outside(height, MIN_HEIGHT_M, MAX_HEIGHT_M, "m", height_why) {
                    return Err(row.error(h, format!("ellipsoidal height {m}")));
                }
                (lat, lon, height)
            }
            PositionForm::Ecef([x, y, z]) => {
                let r = Vec3::new(row.number(x)?, row.number(y)?, row.number(z)?);
                let g = Geodetic::from_ecef(&r);
                if let Some(m) = outside(g.height_m, MIN_HEIGHT_M, MAX_HEIGHT_M, "m", height_why) {
                    return Err(row.error(
                        x,
                        format!(
                            "the point's ellipsoidal height {m} — metres from the Earth's centre expected"
                        ),
                    ));
                }
                return Ok(g);
            }
        };
        Ok(Geodetic {
            latitude_rad: lat.to_radians(),
            longitude_rad: lon.to_radians(),
            height_m: height,
        })
    }

    /// NED velocity and its σ (north, east, up), when the row has one.
    fn velocity(
        &self,
        row: &Row,
        no_sigma_vel: &mut usize,
        no_vertical: &mut usize,
    ) -> Result<Option<(Vector3<f64>, Vector3<f64>)>> {
        use crate::limits::MAX_SPEED_M_S;
        let Some(form) = self.velocity else {
            return Ok(None);
        };
        let cols: Vec<usize> = match form {
            VelocityForm::Ned(c) => c.to_vec(),
            VelocityForm::SpeedCourse(c, v) => c.iter().copied().chain(v).collect(),
        };
        let empty = cols.iter().filter(|&&c| row.cell(c).is_empty()).count();
        if empty == cols.len() {
            return Ok(None);
        }
        let fast = "faster than any vehicle a receiver reports";
        let (v, has_vertical) = match form {
            VelocityForm::Ned([n, e, d]) => {
                let v = Vector3::new(row.number(n)?, row.number(e)?, row.number(d)?);
                if let Some(m) = crate::limits::outside(v.norm(), 0.0, MAX_SPEED_M_S, "m/s", fast) {
                    return Err(row.error(n, format!("speed {m}")));
                }
                (v, true)
            }
            VelocityForm::SpeedCourse([s, c], vertical) => {
                let speed = row.bounded(s, 0.0, MAX_SPEED_M_S, "m/s", fast)?;
                let course = row
                    .bounded(c, -360.0, 360.0, "deg", "clockwise from north")?
                    .to_radians();
                let up = match vertical {
                    Some(u) => Some(row.bounded(u, -MAX_SPEED_M_S, MAX_SPEED_M_S, "m/s", fast)?),
                    None => None,
                };
                (
                    Vector3::new(
                        speed * course.cos(),
                        speed * course.sin(),
                        -up.unwrap_or(0.0),
                    ),
                    up.is_some(),
                )
            }
        };
        let s = match self.sigma_vel {
            Some(c) if !row.cell(c).is_empty() => row.sigma(c, MAX_VELOCITY_SIGMA_MPS, "m/s")?,
            _ => {
                *no_sigma_vel += 1;
                DEFAULT_VELOCITY_SIGMA_MPS
            }
        };
        let vertical_sigma = if has_vertical {
            s
        } else {
            *no_vertical += 1;
            UNOBSERVED_VERTICAL_SIGMA_MPS
        };
        Ok(Some((v, Vector3::new(s, s, vertical_sigma))))
    }
}

/// RTKLIB's Q from a `quality` cell.
fn quality(row: &Row, c: usize) -> Result<u8> {
    let s = row.cell(c);
    Ok(match s.to_ascii_lowercase().as_str() {
        "fixed" | "fix" => 1,
        "float" => 2,
        "dgps" | "dgnss" => 4,
        "single" => 5,
        other => match other.parse::<u8>() {
            Ok(q) if q <= 6 => q,
            _ => {
                return Err(row.error(
                    c,
                    format!(
                        "`{}` is no quality: fixed, float, dgps, single, or RTKLIB's Q 0–6 (1 fixed, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP)",
                        excerpt(s)
                    ),
                ));
            }
        },
    })
}

/// `YYYY-MM-DD[T ]hh:mm:ss[.f…][Z|±hh:mm|±hhmm]` (no zone: UTC) → (UTC
/// seconds since 1970, the UTC day since 1970 for the leap seconds).
pub fn parse_iso8601(s: &str) -> std::result::Result<(f64, i64), String> {
    let bad = || {
        format!(
            "`{}` is not an ISO 8601 time (YYYY-MM-DDThh:mm:ss.sssZ)",
            excerpt(s)
        )
    };
    if !s.is_ascii() || s.len() < 19 {
        return Err(bad());
    }
    let (date, rest) = s.split_at(10);
    let rest = rest.strip_prefix(['T', 't', ' ']).ok_or_else(bad)?;
    // The zone: Z, ±hh:mm, ±hhmm or none.
    let (clock, offset_s) = if let Some(c) = rest.strip_suffix(['Z', 'z']) {
        (c, 0i64)
    } else if let Some(i) = rest.rfind(['+', '-']) {
        let (c, zone) = rest.split_at(i);
        let sign = if zone.starts_with('-') { -1 } else { 1 };
        let digits: String = zone.get(1..).unwrap_or("").replace(':', "");
        if digits.len() != 4 || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let hh: i64 = digits
            .get(0..2)
            .and_then(|x| x.parse().ok())
            .ok_or_else(bad)?;
        let mm: i64 = digits
            .get(2..4)
            .and_then(|x| x.parse().ok())
            .ok_or_else(bad)?;
        if hh > 14 || mm > 59 {
            return Err(bad());
        }
        (c, sign * (hh * 3600 + mm * 60))
    } else {
        (rest, 0)
    };
    let d: Vec<&str> = date.split('-').collect();
    let t: Vec<&str> = clock.split(':').collect();
    let (&[y, mo, da], &[h, mi, se]) = (d.as_slice(), t.as_slice()) else {
        return Err(bad());
    };
    let int = |x: &str, n: usize| -> std::result::Result<i64, String> {
        if x.len() != n || !x.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        x.parse().map_err(|_| bad())
    };
    let (y, mo, da, h, mi) = (
        int(y, 4)?,
        int(mo, 2)?,
        int(da, 2)?,
        int(h, 2)?,
        int(mi, 2)?,
    );
    // Seconds: two digits, then optionally a point and at least one digit.
    let (whole, fraction) = se.split_once('.').unwrap_or((se, "0"));
    int(whole, 2)?;
    if fraction.is_empty() || !fraction.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad());
    }
    let sec: f64 = se.parse().map_err(|_| bad())?;
    if !(1..=9999).contains(&y) || !crate::text::is_date(y, mo, da) {
        return Err(format!(
            "`{}` is not a calendar date (month 1–12, day within the month)",
            excerpt(date)
        ));
    }
    if h > 23 || mi > 59 || !(0.0..61.0).contains(&sec) {
        return Err(format!(
            "`{}` is not a time of day (hh 0–23, mm 0–59, ss < 61)",
            excerpt(clock)
        ));
    }
    let local = days_from_civil(y, mo, da) * 86_400 + h * 3600 + mi * 60;
    let utc = local - offset_s;
    Ok((utc as f64 + sec, utc.div_euclid(86_400)))
}

#[cfg(test)]
mod tests;
