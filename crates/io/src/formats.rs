//! The format registry: one enum per stream kind (IMU, GNSS, wheel speed,
//! barometer), each value a file format with its configuration name (the
//! serde name, `snake_case`) and one `read` arm that calls its reader. A
//! new format is a variant and an arm here; the application's
//! configuration names these enums (`[data] imu_format = "kf_gins"`).
//!
//! ```
//! use aidnav_io::formats::{BaroFormat, GnssFormat, ImuFormat, WheelSpeedFormat};
//! // The configuration's names.
//! let f: ImuFormat = serde_json::from_str("\"kf_gins\"").unwrap();
//! assert_eq!(f, ImuFormat::KfGins);
//! assert_eq!(serde_json::to_string(&GnssFormat::GenericCsv).unwrap(), "\"generic_csv\"");
//! // The defaults.
//! assert_eq!(
//!     (ImuFormat::default(), GnssFormat::default()),
//!     (ImuFormat::RtklibTagged, GnssFormat::RtklibPos)
//! );
//! let csv = "time_s,speed_kmh\n100.0,36\n100.1,36.36\n";
//! let (wheel, _) = WheelSpeedFormat::GenericCsv.read_from(csv.as_bytes(), "w.csv".as_ref()).unwrap();
//! assert_eq!(wheel[0].speed_mps, 10.0);
//! let (baro, _) = BaroFormat::default().read_from(b"time_s,height_m\n1,52.5\n", "b.csv".as_ref()).unwrap();
//! assert_eq!(baro[0].height_m, 52.5);
//! ```

use std::path::{Path, PathBuf};

use aidnav_sensors::{BaroSample, GnssFix, ImuSample, WheelSpeedSample};
use serde::{Deserialize, Serialize};

use crate::checks::CheckLevel;
use crate::error::Result;
use crate::kfgins::{GenericImuOptions, ImuUnits};
use crate::rtklib::data_error;

/// The time system a file's time stamps are written in.
///
/// aidnav's records hold GPST (seconds since 1970-01-01, no leap seconds).
/// A writer given [`TimeSystem::Utc`] stamps GPST − (GPS − UTC), the leap
/// seconds of the UTC date ([`crate::text::gps_minus_utc_s`]: 18 s since
/// 2017-01-01), which is exactly what the readers add back, so a round
/// trip gives the GPST time back (the instant of a leap second itself,
/// 23:59:60 UTC, excepted). Formats with one fixed time system ignore it:
/// NMEA is always UTC, UBX NAV-PVT always GPST `iTOW` with UTC date
/// fields, KF-GINS and the IMU and aiding CSVs always the time as given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeSystem {
    /// GPS time (RTKLIB's `GPST`).
    #[default]
    Gpst,
    /// UTC: GPST minus the leap seconds of the date.
    Utc,
}

/// Records read and the reader's warnings.
pub type Read<T> = Result<(Vec<T>, Vec<String>)>;

/// Format of the IMU file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImuFormat {
    /// Raw CSV (g, deg/s, tick ms) with an RTKLIB `.tag` file (`imu_tags`).
    #[default]
    RtklibTagged,
    /// KF-GINS text: time, angle and velocity increments, body frame.
    KfGins,
    /// aidnav's generic CSV (see `aidnav_io::kfgins`).
    GenericCsv,
}

impl ImuFormat {
    /// Read the IMU file `path` of this format (sensor frame, SI, time as
    /// written). `options.tags` is the RTKLIB `.tag` file (needed for
    /// `rtklib_tagged`: without it, an error naming the file),
    /// `options.units` the units of a generic CSV whose columns are named
    /// `gx … az` ([`crate::kfgins::read_generic_imu_with`]); each is
    /// ignored by the formats that take none. `options.unit_checks` says
    /// what the plausibility checks of the units do when they fail.
    pub fn read(self, path: &Path, options: &ImuReadOptions<'_>) -> Read<ImuSample> {
        let checks = options.unit_checks;
        match self {
            Self::RtklibTagged => match options.tags {
                Some(tags) => crate::rtklib::read_tagged_imu_checked_from(
                    &crate::text::read_bytes(path)?,
                    path,
                    &crate::text::read_bytes(tags)?,
                    tags,
                    checks,
                ),
                None => Err(data_error(
                    path,
                    0,
                    "(file)",
                    "a raw IMU CSV needs its RTKLIB time-tag file (.tag) to be read",
                )),
            },
            Self::KfGins => crate::kfgins::read_kfgins_imu_checked_from(
                &crate::text::read_bytes(path)?,
                path,
                checks,
            ),
            Self::GenericCsv => crate::kfgins::read_generic_imu_with(
                path,
                GenericImuOptions {
                    units: options.units,
                    unit_checks: checks,
                },
            ),
        }
    }

    /// Write `samples` (sensor frame, SI, GPST seconds since 1970) to
    /// `path` in this format; the files written. `rtklib_tagged` writes the
    /// raw CSV at `path` and its time tags beside it at
    /// [`crate::log_writers::tag_path`] (`path` + `.tag`), returned second.
    /// The round-trip resolution of each format: [`crate::log_writers`]
    /// ([`write_generic_imu`](crate::log_writers::write_generic_imu),
    /// [`write_tagged_imu`](crate::log_writers::write_tagged_imu),
    /// [`write_kfgins_imu`](crate::log_writers::write_kfgins_imu)).
    pub fn write(self, path: &Path, samples: &[ImuSample]) -> Result<Vec<PathBuf>> {
        use crate::log_writers as w;
        match self {
            Self::RtklibTagged => w::write_tagged_imu(path, samples),
            Self::KfGins => w::write_kfgins_imu(path, samples),
            Self::GenericCsv => w::write_generic_imu(path, samples),
        }
    }
}

/// What [`ImuFormat::read`] needs beyond the file.
#[derive(Debug, Clone, Copy, Default)]
pub struct ImuReadOptions<'a> {
    /// The RTKLIB `.tag` file of a raw IMU CSV.
    pub tags: Option<&'a Path>,
    /// The units of a generic CSV's `gx … az` columns.
    pub units: Option<ImuUnits>,
    /// What the plausibility checks of the units do when they fail.
    pub unit_checks: CheckLevel,
}

/// Format of the GNSS file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GnssFormat {
    /// RTKLIB `.pos` (latitude/longitude/height).
    #[default]
    RtklibPos,
    /// KF-GINS text: time, lat, lon, h, σN σE σD [, velocity and σ].
    KfGins,
    /// NMEA 0183: GGA + RMC (+ GST for σ), see `aidnav_io::nmea`.
    Nmea,
    /// u-blox UBX binary log: NAV-PVT epochs, ellipsoidal heights, see
    /// `aidnav_io::ubx`.
    Ubx,
    /// aidnav's generic GNSS CSV (named columns; σ from its columns or
    /// `data.gnss_sigma_m`), see `aidnav_io::generic_gnss`.
    GenericCsv,
}

impl GnssFormat {
    /// Read the GNSS file `path` of this format. `default_sigma_m`
    /// (horizontal, up) is the σ of a generic CSV without σ columns
    /// ([`crate::generic_gnss::GenericGnssOptions`]), ignored by the
    /// other formats.
    pub fn read(self, path: &Path, default_sigma_m: Option<[f64; 2]>) -> Read<GnssFix> {
        self.read_from(&crate::text::read_bytes(path)?, path, default_sigma_m)
    }

    /// [`GnssFormat::read`] on the file's bytes; `origin` names them in
    /// messages.
    pub fn read_from(
        self,
        bytes: &[u8],
        origin: &Path,
        default_sigma_m: Option<[f64; 2]>,
    ) -> Read<GnssFix> {
        use crate::generic_gnss::{GenericGnssOptions, read_generic_gnss_from};
        match self {
            Self::RtklibPos => crate::rtklib::read_pos_from(bytes, origin),
            Self::KfGins => crate::kfgins::read_kfgins_gnss_from(bytes, origin),
            Self::Nmea => crate::nmea::read_nmea_from(bytes, origin),
            Self::Ubx => crate::ubx::read_ubx_from(bytes, origin),
            Self::GenericCsv => {
                read_generic_gnss_from(bytes, origin, GenericGnssOptions { default_sigma_m })
            }
        }
    }

    /// Write `fixes` (ellipsoidal heights, GPST) to `path` in this format,
    /// its times in `time` where the format can hold either (generic CSV,
    /// RTKLIB `.pos`; NMEA is always UTC, UBX and KF-GINS fixed, see
    /// [`TimeSystem`]); the files written. What each format cannot hold
    /// (velocity in a 7-column KF-GINS file, vertical velocity and velocity
    /// σ in NMEA, quality in KF-GINS) and its resolution:
    /// [`crate::log_writers`].
    pub fn write(self, path: &Path, fixes: &[GnssFix], time: TimeSystem) -> Result<Vec<PathBuf>> {
        use crate::log_writers as w;
        match self {
            Self::RtklibPos => w::write_pos(path, fixes, time),
            Self::KfGins => w::write_kfgins_gnss(path, fixes),
            Self::Nmea => w::write_nmea(path, fixes),
            Self::Ubx => w::write_ubx(path, fixes),
            Self::GenericCsv => w::write_generic_gnss(path, fixes, time),
        }
    }
}

/// Format of the wheel-speed (odometer) file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WheelSpeedFormat {
    /// aidnav's generic wheel-speed CSV, see [`crate::generic_aiding`].
    #[default]
    GenericCsv,
}

impl WheelSpeedFormat {
    /// Read the wheel-speed file `path` of this format.
    pub fn read(self, path: &Path) -> Read<WheelSpeedSample> {
        self.read_from(&crate::text::read_bytes(path)?, path)
    }

    /// [`WheelSpeedFormat::read`] on the file's bytes; `origin` names them
    /// in messages.
    pub fn read_from(self, bytes: &[u8], origin: &Path) -> Read<WheelSpeedSample> {
        match self {
            Self::GenericCsv => crate::generic_aiding::read_wheel_speed_from(bytes, origin),
        }
    }

    /// Write `samples` to `path` in this format
    /// ([`crate::log_writers::write_wheel_speed`]); the files written.
    pub fn write(self, path: &Path, samples: &[WheelSpeedSample]) -> Result<Vec<PathBuf>> {
        match self {
            Self::GenericCsv => crate::log_writers::write_wheel_speed(path, samples),
        }
    }
}

/// Format of the barometer file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BaroFormat {
    /// aidnav's generic barometer CSV (height or pressure), see
    /// [`crate::generic_aiding`].
    #[default]
    GenericCsv,
}

impl BaroFormat {
    /// Read the barometer file `path` of this format.
    pub fn read(self, path: &Path) -> Read<BaroSample> {
        self.read_from(&crate::text::read_bytes(path)?, path)
    }

    /// [`BaroFormat::read`] on the file's bytes; `origin` names them in
    /// messages.
    pub fn read_from(self, bytes: &[u8], origin: &Path) -> Read<BaroSample> {
        match self {
            Self::GenericCsv => crate::generic_aiding::read_baro_from(bytes, origin),
        }
    }

    /// Write `samples` to `path` in this format
    /// ([`crate::log_writers::write_baro`]); the files written.
    pub fn write(self, path: &Path, samples: &[BaroSample]) -> Result<Vec<PathBuf>> {
        match self {
            Self::GenericCsv => crate::log_writers::write_baro(path, samples),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The serde name of a unit variant.
    fn name<T: Serialize>(v: T) -> String {
        serde_json::to_value(v)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default()
    }

    /// The configuration names are the ones `aidnav process` has always
    /// read (its TOML keys' values and `--print-config` text rely on them).
    #[test]
    fn serde_names_are_the_configuration_values() {
        use ImuFormat as I;
        assert_eq!(
            [I::RtklibTagged, I::KfGins, I::GenericCsv].map(name),
            ["rtklib_tagged", "kf_gins", "generic_csv"]
        );
        use GnssFormat as G;
        assert_eq!(
            [G::RtklibPos, G::KfGins, G::Nmea, G::Ubx, G::GenericCsv].map(name),
            ["rtklib_pos", "kf_gins", "nmea", "ubx", "generic_csv"]
        );
        assert_eq!(name(WheelSpeedFormat::GenericCsv), "generic_csv");
        assert_eq!(name(BaroFormat::GenericCsv), "generic_csv");
        let e = serde_json::from_str::<ImuFormat>("\"csv\"")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "unknown variant `csv`, expected one of `rtklib_tagged`, `kf_gins`, `generic_csv`"
            ),
            "{e}"
        );
    }

    #[test]
    fn a_tagged_imu_without_tags_is_an_error_naming_the_file() {
        let e = ImuFormat::RtklibTagged
            .read(Path::new("imu.csv"), &Default::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("imu.csv:0: column `(file)`: "), "{e}");
    }

    #[test]
    fn every_gnss_format_reads_through_its_arm() {
        let kf = b"100.0 30.5 114.3 20.0 0.01 0.01 0.02\n";
        let (f, _) = GnssFormat::KfGins
            .read_from(kf, Path::new("g.txt"), None)
            .unwrap();
        assert_eq!(f[0].position.height_m, 20.0);
        let csv = b"gpst_s,lat_deg,lon_deg,height_m\n1700000000,30.5,114.3,20\n";
        let (f, _) = GnssFormat::GenericCsv
            .read_from(csv, Path::new("g.csv"), Some([0.5, 1.0]))
            .unwrap();
        assert_eq!(f[0].position_sigma_neu.z, 1.0);
        let e = GnssFormat::GenericCsv
            .read(Path::new("/no/such/g.csv"), None)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("/no/such/g.csv: cannot read"), "{e}");
    }
}
