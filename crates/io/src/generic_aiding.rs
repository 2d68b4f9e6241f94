//! aidnav's generic CSVs of the scalar aiding sensors: wheel speed
//! (odometer) and barometric height. Each is a comma-separated file with a
//! header row naming its columns (any order), the unit in each name.
//!
//! Wheel speed ([`read_wheel_speed`], [`WheelSpeedSample`]):
//!
//! | columns | meaning |
//! | --- | --- |
//! | **time**, one of: | as in the generic GNSS CSV, plus `time_s` |
//! | `time_s` | seconds as written, on the scale of the run's other files (GPST seconds since 1970 for generic logs, seconds of week beside KF-GINS files) |
//! | `gpst_s` | GPST seconds since 1970-01-01 |
//! | `gps_week`, `tow_s` | GPS week and seconds of week |
//! | `utc` | ISO 8601 UTC time, converted to GPST with the leap seconds of its date |
//! | **speed**, one of: | |
//! | `speed_mps` | forward speed \[m/s\], negative when reversing |
//! | `speed_kmh` | forward speed \[km/h\] |
//! | `sigma_mps` (optional) | 1σ of the speed \[m/s\]; absent or empty: none given |
//!
//! Barometer ([`read_baro`], [`BaroSample`]):
//!
//! | columns | meaning |
//! | --- | --- |
//! | **time**, one of: | as for wheel speed |
//! | **height**, one of: | |
//! | `height_m` | barometric height \[m\], on the sensor's own datum |
//! | `pressure_pa` | static pressure \[Pa\], converted to the ISA pressure height ([`isa_pressure_height_m`]) |
//! | `pressure_hpa` | static pressure \[hPa = mbar\], converted likewise |
//! | `sigma_m` (optional) | 1σ of the height \[m\]; absent or empty: none given |
//!
//! Rules (those of [`crate::generic_gnss`]):
//! - a header name not in [`WHEEL_SPEED_COLUMNS`] / [`BARO_COLUMNS`] is an
//!   error listing the known names; two forms of one quantity, a form with
//!   a column missing, or a repeated name are errors naming the columns;
//! - blank lines and lines starting with `#` are skipped; a UTF-8
//!   byte-order mark is stripped; LF, CR LF or CR line ends; a truncated
//!   last line (fewer cells than the header) is skipped with a warning;
//! - time must increase strictly from row to row: a repeated or earlier
//!   time is an error naming the row and both times (the reader does not
//!   guess which of two rows is right: sort the log and drop duplicates);
//! - every bad value is an error naming the file, the line and the column
//!   with the value: not a number, not finite, a speed beyond ±170 m/s
//!   ([`crate::limits::MAX_WHEEL_SPEED_M_S`]), a height outside −1 000 …
//!   100 000 m, a pressure ≤ 0 or whose ISA height is outside −1 000 …
//!   20 000 m (the layers converted), σ ≤ 0 or beyond the bound of its
//!   quantity, and the time errors of the generic GNSS CSV.
//!
//! Memory grows with the file only (one record and one line reference a
//! row, as in the other readers); no input makes a reader panic (fuzz
//! targets `generic_wheel_speed` and `generic_baro`).

use std::path::Path;

use aidnav_sensors::{BaroSample, Timed, WheelSpeedSample};

use crate::error::Result;
use crate::kfgins::STANDARD_GRAVITY_M_S2;
use crate::limits::{MAX_HEIGHT_M, MAX_WHEEL_SPEED_M_S, MIN_HEIGHT_M, outside};
use crate::named_csv::{Header, Row, TimeForm, read_table};
use crate::text::{num, read_bytes};

/// Every column name of the wheel-speed CSV, in the order of the module
/// docs.
pub const WHEEL_SPEED_COLUMNS: [&str; 8] = [
    "time_s",
    "gpst_s",
    "gps_week",
    "tow_s",
    "utc",
    "speed_mps",
    "speed_kmh",
    "sigma_mps",
];

/// Every column name of the barometer CSV, in the order of the module docs.
pub const BARO_COLUMNS: [&str; 9] = [
    "time_s",
    "gpst_s",
    "gps_week",
    "tow_s",
    "utc",
    "height_m",
    "pressure_pa",
    "pressure_hpa",
    "sigma_m",
];

/// Kilometres per hour in one metre per second.
const KMH_PER_MPS: f64 = 3.6;

/// Largest barometric height σ accepted \[m\]: a σ of a kilometre carries no
/// height information a GNSS fix would not beat.
const MAX_BARO_SIGMA_M: f64 = 1_000.0;

/// ISA sea-level pressure \[Pa\] (ICAO Doc 7488/3, U.S. Standard Atmosphere
/// 1976).
const ISA_P0_PA: f64 = 101_325.0;
/// ISA sea-level temperature \[K\].
const ISA_T0_K: f64 = 288.15;
/// ISA temperature lapse rate of the troposphere \[K/m\] (temperature falls
/// by this much per metre up to the tropopause).
const ISA_LAPSE_K_PER_M: f64 = 0.0065;
/// ISA tropopause: geopotential height where the lapse rate becomes 0 \[m\].
const ISA_TROPOPAUSE_M: f64 = 11_000.0;
/// Top of the isothermal lower stratosphere, the highest height
/// [`isa_pressure_height_m`] is valid to \[m\].
pub const ISA_TOP_M: f64 = 20_000.0;
/// Universal gas constant of the U.S. Standard Atmosphere 1976 \[J/(mol·K)\].
const GAS_CONSTANT_J_PER_MOL_K: f64 = 8.314_32;
/// Mean molar mass of dry air at sea level \[kg/mol\] (ISA).
const AIR_MOLAR_MASS_KG_PER_MOL: f64 = 0.028_964_4;

/// The ISA pressure height \[m\] of a static pressure \[Pa\]: the
/// geopotential height at which the International Standard Atmosphere
/// (ICAO Doc 7488/3, 1993; identical to the U.S. Standard Atmosphere 1976
/// below 32 km, its eqs. 33a and 33b) has that pressure. Two layers:
///
/// - troposphere (below 11 km, lapse rate L = 6.5 K/km):
///   h = (T₀ / L) · (1 − (p / p₀)^(L R / (g₀ M)));
/// - lower stratosphere (11–20 km, isothermal T₁₁ = 216.65 K):
///   h = 11 000 m + (R T₁₁ / (g₀ M)) · ln(p₁₁ / p), p₁₁ ≈ 22 632 Pa;
///
/// with p₀ = 101 325 Pa, T₀ = 288.15 K, g₀ = 9.806 65 m/s², M = 0.028 964 4
/// kg/mol, R = 8.314 32 J/(mol·K). Above 20 km (below ≈ 5 475 Pa) the
/// formula is outside its layers; the barometer reader refuses such
/// pressures. A pressure height is not an ellipsoidal height: weather moves
/// it by tens of metres, and the filter estimates the offset as a bias.
///
/// ```
/// use aidnav_io::generic_aiding::isa_pressure_height_m;
/// // ISA table values (ICAO Doc 7488/3): 1 000 m at 898.746 hPa,
/// // 11 000 m at 226.321 hPa, 15 000 m at 120.446 hPa.
/// assert_eq!(isa_pressure_height_m(101_325.0), 0.0);
/// assert!((isa_pressure_height_m(89_874.6) - 1_000.0).abs() < 0.01);
/// assert!((isa_pressure_height_m(22_632.1) - 11_000.0).abs() < 0.02);
/// assert!((isa_pressure_height_m(12_044.6) - 15_000.0).abs() < 0.02);
/// ```
pub fn isa_pressure_height_m(pressure_pa: f64) -> f64 {
    // g₀ M / R [K/m]: the hydrostatic equation's constant.
    let gmr = STANDARD_GRAVITY_M_S2 * AIR_MOLAR_MASS_KG_PER_MOL / GAS_CONSTANT_J_PER_MOL_K;
    let t11 = ISA_T0_K - ISA_LAPSE_K_PER_M * ISA_TROPOPAUSE_M;
    let p11 = ISA_P0_PA * (t11 / ISA_T0_K).powf(gmr / ISA_LAPSE_K_PER_M);
    if pressure_pa >= p11 {
        ISA_T0_K / ISA_LAPSE_K_PER_M
            * (1.0 - (pressure_pa / ISA_P0_PA).powf(ISA_LAPSE_K_PER_M / gmr))
    } else {
        ISA_TROPOPAUSE_M + t11 / gmr * (p11 / pressure_pa).ln()
    }
}

/// Read a wheel-speed CSV (see the module docs): the samples and the
/// warnings.
///
/// ```
/// use aidnav_io::generic_aiding::read_wheel_speed_from;
/// let csv = "gpst_s,speed_kmh,sigma_mps\n1724716800.0,90,0.05\n1724716800.1,90.36,\n";
/// let (wheel, warnings) = read_wheel_speed_from(csv.as_bytes(), "wheel.csv".as_ref()).unwrap();
/// assert_eq!(wheel[0].speed_mps, 25.0); // 90 km/h
/// assert_eq!((wheel[0].sigma_mps, wheel[1].sigma_mps), (Some(0.05), None));
/// assert!(warnings.is_empty());
/// ```
pub fn read_wheel_speed(path: &Path) -> Result<(Vec<WheelSpeedSample>, Vec<String>)> {
    read_wheel_speed_from(&read_bytes(path)?, path)
}

/// [`read_wheel_speed`] on the file's bytes; `origin` names them in
/// messages.
pub fn read_wheel_speed_from(
    bytes: &[u8],
    origin: &Path,
) -> Result<(Vec<WheelSpeedSample>, Vec<String>)> {
    let fast = "faster than any wheeled vehicle: mm/s, or a wheel's rpm?";
    let forms: [Form; 2] = [
        ("speed_mps", &|row, c| {
            row.bounded(c, -MAX_WHEEL_SPEED_M_S, MAX_WHEEL_SPEED_M_S, "m/s", fast)
        }),
        ("speed_kmh", &|row, c| {
            let max = MAX_WHEEL_SPEED_M_S * KMH_PER_MPS;
            Ok(row.bounded(c, -max, max, "km/h", fast)? / KMH_PER_MPS)
        }),
    ];
    let scalar = Scalar {
        quantity: "speed",
        forms: &forms,
        sigma: ("sigma_mps", MAX_WHEEL_SPEED_M_S, "m/s"),
    };
    scalar.read(
        bytes,
        origin,
        &WHEEL_SPEED_COLUMNS,
        |time_s, speed_mps, sigma_mps| WheelSpeedSample {
            time_s,
            speed_mps,
            sigma_mps,
        },
    )
}

/// Read a barometer CSV (see the module docs): the samples and the
/// warnings.
///
/// ```
/// use aidnav_io::generic_aiding::read_baro_from;
/// let csv = "time_s,pressure_hpa,sigma_m\n100.0,898.746,0.5\n100.1,1013.25,0.5\n";
/// let (baro, _) = read_baro_from(csv.as_bytes(), "baro.csv".as_ref()).unwrap();
/// assert!((baro[0].height_m - 1_000.0).abs() < 0.01); // ISA 1 000 m
/// assert_eq!((baro[1].height_m, baro[1].sigma_m), (0.0, Some(0.5)));
/// ```
pub fn read_baro(path: &Path) -> Result<(Vec<BaroSample>, Vec<String>)> {
    read_baro_from(&read_bytes(path)?, path)
}

/// [`read_baro`] on the file's bytes; `origin` names them in messages.
pub fn read_baro_from(bytes: &[u8], origin: &Path) -> Result<(Vec<BaroSample>, Vec<String>)> {
    let forms: [Form; 3] = [
        ("height_m", &|row, c| {
            row.bounded(
                c,
                MIN_HEIGHT_M,
                MAX_HEIGHT_M,
                "m",
                "below the lowest land or above 100 km",
            )
        }),
        ("pressure_pa", &|row, c| pressure_height(row, c, 1.0, "Pa")),
        ("pressure_hpa", &|row, c| {
            pressure_height(row, c, 100.0, "hPa")
        }),
    ];
    let scalar = Scalar {
        quantity: "height",
        forms: &forms,
        sigma: ("sigma_m", MAX_BARO_SIGMA_M, "m"),
    };
    scalar.read(bytes, origin, &BARO_COLUMNS, |time_s, height_m, sigma_m| {
        BaroSample {
            time_s,
            height_m,
            sigma_m,
        }
    })
}

/// The ISA pressure height of the pressure in column `c` (in units of
/// `pa_per_unit` Pa, named `unit`).
fn pressure_height(row: &Row, c: usize, pa_per_unit: f64, unit: &str) -> Result<f64> {
    let p = row.number(c)?;
    if p <= 0.0 {
        return Err(row.error(c, format!("{} {unit}: a pressure must be > 0", num(p))));
    }
    let h = isa_pressure_height_m(p * pa_per_unit);
    match outside(
        h,
        MIN_HEIGHT_M,
        ISA_TOP_M,
        "m",
        "the ISA layers converted; another unit (kPa, inHg, Pa for hPa)?",
    ) {
        Some(m) => Err(row.error(
            c,
            format!("{} {unit} is an ISA pressure height of {m}", num(p)),
        )),
        None => Ok(h),
    }
}

/// A value column: its name and how a row's cell in it becomes the value
/// (checked and in SI units).
type Form<'a> = (&'a str, &'a dyn Fn(&Row, usize) -> Result<f64>);

/// A file of one scalar quantity per row, given in one of several forms,
/// with an optional σ column.
struct Scalar<'a> {
    /// The quantity's name in messages.
    quantity: &'a str,
    /// Its forms.
    forms: &'a [Form<'a>],
    /// The σ column: name, largest σ accepted, unit.
    sigma: (&'a str, f64, &'a str),
}

impl Scalar<'_> {
    /// The records of `bytes`: `record(time, value, σ)` of each row.
    fn read<T: Timed>(
        &self,
        bytes: &[u8],
        origin: &Path,
        known: &[&str],
        record: impl Fn(f64, f64, Option<f64>) -> T,
    ) -> Result<(Vec<T>, Vec<String>)> {
        let names: Vec<&str> = self.forms.iter().map(|(n, _)| *n).collect();
        let (sigma_name, sigma_max, sigma_unit) = self.sigma;
        read_table(
            bytes,
            origin,
            known,
            |h: &Header| {
                let time = TimeForm::parse(h, true)?;
                let value = h.one_column(self.quantity, &names)?;
                Ok(((value, h.find(sigma_name)), time))
            },
            |&((form, c), sigma), row, time_s| {
                let value = self
                    .forms
                    .get(form)
                    .map_or(Ok(f64::NAN), |(_, f)| f(row, c))?;
                let sigma = row.optional_sigma(sigma, sigma_max, sigma_unit)?;
                Ok(record(time_s, value, sigma))
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wheel(text: &str) -> Result<(Vec<WheelSpeedSample>, Vec<String>)> {
        read_wheel_speed_from(text.as_bytes(), Path::new("wheel.csv"))
    }

    fn baro(text: &str) -> Result<(Vec<BaroSample>, Vec<String>)> {
        read_baro_from(text.as_bytes(), Path::new("baro.csv"))
    }

    fn wheel_error(text: &str) -> String {
        wheel(text).unwrap_err().to_string()
    }

    fn baro_error(text: &str) -> String {
        baro(text).unwrap_err().to_string()
    }

    /// Each input's error message begins with its expected text.
    fn errors_begin_with(error: fn(&str) -> String, cases: &[(&str, &str)]) {
        for (input, expected) in cases {
            let e = error(input);
            assert!(e.starts_with(expected), "{input:?}: {e}");
        }
    }

    #[test]
    fn wheel_speed_in_mps_and_kmh() {
        let (w, warnings) = wheel(
            "# odometer\nsigma_mps,time_s,speed_mps\n0.02,100.00,12.5\n,100.05,-1.25\n0.02,100.1\n",
        )
        .unwrap();
        assert_eq!(w.len(), 2);
        assert_eq!(
            w[0],
            WheelSpeedSample {
                time_s: 100.0,
                speed_mps: 12.5,
                sigma_mps: Some(0.02)
            }
        );
        assert_eq!((w[1].speed_mps, w[1].sigma_mps), (-1.25, None));
        assert_eq!(
            warnings,
            ["wheel.csv:5: truncated last line skipped (2 of 3 cells)"]
        );
        // 50 km/h = 13.888… m/s; 612 km/h is the bound, allowed.
        let (w, _) = wheel("time_s,speed_kmh\n1,50\n2,612\n3,-612\n").unwrap();
        assert!((w[0].speed_mps - 50.0 / 3.6).abs() < 1e-12);
        assert_eq!((w[1].speed_mps, w[2].speed_mps), (170.0, -170.0));
    }

    #[test]
    fn wheel_speed_time_forms_are_the_gnss_csvs() {
        // GPS week 2329, 172 800 s: 2024-08-27 00:00:00 GPST.
        let t = 1_724_716_800.0;
        let (w, _) = wheel("gps_week,tow_s,speed_mps\n2329,172800,1\n2329,172800.5,1\n").unwrap();
        assert_eq!((w[0].time_s, w[1].time_s), (t, t + 0.5));
        // 18 leap seconds in 2024.
        let (w, _) = wheel("utc,speed_mps\n2024-08-26T23:59:42Z,1\n").unwrap();
        assert_eq!(w[0].time_s, t);
        let (w, _) = wheel("gpst_s,speed_mps\n1724716800,1\n").unwrap();
        assert_eq!(w[0].time_s, t);
        let e = wheel_error("gpst_s,speed_mps\n172800,1\n");
        assert!(
            e.starts_with("wheel.csv:2: column `gpst_s`: 172800 s is outside"),
            "{e}"
        );
    }

    #[test]
    fn wheel_speed_errors_name_line_column_and_value() {
        errors_begin_with(
            wheel_error,
            &[
                (
                    "time_s,speed_mps\n1,10\n2,1e4\n",
                    "wheel.csv:3: column `speed_mps`: 10000 m/s is outside [-170, 170] m/s (faster",
                ),
                (
                    "time_s,speed_kmh\n1,700\n",
                    "wheel.csv:2: column `speed_kmh`: 700 km/h is outside [-612, 612] km/h",
                ),
                (
                    "time_s,speed_mps,sigma_mps\n1,10,0\n",
                    "wheel.csv:2: column `sigma_mps`: σ = 0 m/s: must be > 0 and ≤ 170 m/s",
                ),
                (
                    "time_s,speed_mps,sigma_mps\n1,10,-0.1\n",
                    "wheel.csv:2: column `sigma_mps`: σ = -0.1 m/s: must be > 0",
                ),
                (
                    "time_s,speed_mps\n1,ten\n",
                    "wheel.csv:2: column `speed_mps`: `ten` is not a number",
                ),
                (
                    "time_s,speed_mps\n1,NaN\n",
                    "wheel.csv:2: column `speed_mps`: `NaN` is not finite",
                ),
                (
                    "time_s,speed_mps\ninf,1\n",
                    "wheel.csv:2: column `time_s`: `inf` is not finite",
                ),
                (
                    "time_s,speed_mps\n1,\n",
                    "wheel.csv:2: column `speed_mps`: empty: a value is needed",
                ),
                (
                    "time_s,speed_mps\n1,1\n2,1,3\n",
                    "wheel.csv:3: column `(line)`: 3 cells, the header (line 1) has 2",
                ),
                // Time must increase strictly: a repeat is an error.
                (
                    "time_s,speed_mps\n1.5,1\n1.5,1\n",
                    "wheel.csv:3: column `time_s`: time 1.5 s does not increase (previous row 1.5 s)",
                ),
            ],
        );
    }

    #[test]
    fn headers_are_checked() {
        errors_begin_with(
            wheel_error,
            &[
                (
                    "time_s,speed_mps,speed_kmh\n1,1,3.6\n",
                    "wheel.csv:1: column `(header)`: the speed given twice (speed_mps and speed_kmh): keep one form",
                ),
                (
                    "time_s,sigma_mps\n1,1\n",
                    "wheel.csv:1: column `(speed)`: no speed column: give one of speed_mps, speed_kmh",
                ),
                (
                    "speed_mps\n1\n",
                    "wheel.csv:1: column `(time)`: no time column: give time_s, gpst_s, or gps_week and tow_s, or utc",
                ),
                (
                    "time_s,gpst_s,speed_mps\n1,1,1\n",
                    "wheel.csv:1: column `(header)`: the time given twice (time_s and gpst_s)",
                ),
                (
                    "time_s,speed_mps,odometer_m\n1,1,1\n",
                    "wheel.csv:1: column `odometer_m`: unknown column (column 3); the known columns are: time_s, gpst_s",
                ),
            ],
        );
        errors_begin_with(
            baro_error,
            &[
                (
                    "time_s,height_m,time_s\n1,1,1\n",
                    "baro.csv:1: column `time_s`: named twice (column 3)",
                ),
                (
                    "gps_week,height_m\n2329,1\n",
                    "baro.csv:1: column `tow_s`: column missing: GPS week time needs gps_week, tow_s",
                ),
                (
                    "\n# nothing\n",
                    "baro.csv:0: column `(header)`: no header row",
                ),
                (
                    "time_s,height_m\n",
                    "baro.csv:1: column `(file)`: no data rows after the header",
                ),
                (
                    "gpst_s,height_m\n1724716800,1\n1724716799.5,1\n",
                    "baro.csv:3: column `gpst_s`: time 2024-08-26 23:59:59.500 GPST does not increase (previous row 2024-08-27 00:00:00.000 GPST)",
                ),
            ],
        );
    }

    #[test]
    fn baro_heights_and_pressures() {
        let (b, w) =
            baro("\u{FEFF}time_s,height_m,sigma_m\r\n1,-20.5,1.5\r\n2,8848.86,\r\n").unwrap();
        assert!(w.is_empty());
        assert_eq!(
            b[0],
            BaroSample {
                time_s: 1.0,
                height_m: -20.5,
                sigma_m: Some(1.5)
            }
        );
        assert_eq!((b[1].height_m, b[1].sigma_m), (8848.86, None));
        // ISA table values: 500 m at 954.608 hPa, −500 m at 1074.78 hPa,
        // 11 000 m at 226.321 hPa (the tropopause), 20 000 m at 54.7489 hPa.
        let (b, _) =
            baro("time_s,pressure_pa\n1,95460.8\n2,107477.5\n3,22632.1\n4,5474.89\n").unwrap();
        let expected = [500.0, -500.0, 11_000.0, 20_000.0];
        for (s, h) in b.iter().zip(expected) {
            assert!((s.height_m - h).abs() < 0.02, "{} vs {h}", s.height_m);
        }
        let (b, _) = baro("time_s,pressure_hpa\n1,954.608\n").unwrap();
        assert!((b[0].height_m - 500.0).abs() < 0.01, "{}", b[0].height_m);
        // The two layers meet: the height is continuous at the tropopause.
        let p11 = 22_632.063_973_462_933;
        let (below, above) = (
            isa_pressure_height_m(p11 * (1.0 + 1e-12)),
            isa_pressure_height_m(p11 * (1.0 - 1e-12)),
        );
        assert!((below - 11_000.0).abs() < 1e-6 && (above - 11_000.0).abs() < 1e-6);
    }

    #[test]
    fn baro_errors_name_line_column_and_value() {
        errors_begin_with(
            baro_error,
            &[
                (
                    "time_s,height_m\n1,0\n2,-5000\n",
                    "baro.csv:3: column `height_m`: -5000 m is outside [-1000, 100000] m (below the lowest land",
                ),
                (
                    "time_s,pressure_pa\n1,0\n",
                    "baro.csv:2: column `pressure_pa`: 0 Pa: a pressure must be > 0",
                ),
                // Kilopascals written as pascals: above the layers.
                (
                    "time_s,pressure_pa\n1,101.3\n",
                    "baro.csv:2: column `pressure_pa`: 101.3 Pa is an ISA pressure height of ",
                ),
                (
                    "time_s,height_m,sigma_m\n1,10,2000\n",
                    "baro.csv:2: column `sigma_m`: σ = 2000 m: must be > 0 and ≤ 1000 m",
                ),
                (
                    "time_s,height_m,pressure_pa\n1,10,100000\n",
                    "baro.csv:1: column `(header)`: the height given twice (height_m and pressure_pa)",
                ),
            ],
        );
        // Pascals written as hectopascals: far below the lowest land.
        let e = baro_error("time_s,pressure_hpa\n1,101325\n");
        assert!(
            e.starts_with(
                "baro.csv:2: column `pressure_hpa`: 101325 hPa is an ISA pressure height of "
            ) && e.contains("m is outside [-1000, 20000] m (the ISA layers converted"),
            "{e}"
        );
        let e = read_baro_from(b"time_s,height_m\n1,\xFF\n", Path::new("baro.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("baro.csv:2: column `(text)`: invalid UTF-8"),
            "{e}"
        );
    }

    #[test]
    fn the_path_forms_read_files_and_name_them() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("wheel.csv");
        std::fs::write(&p, "time_s,speed_mps\n1,2\n").unwrap();
        assert_eq!(read_wheel_speed(&p).unwrap().0[0].speed_mps, 2.0);
        let p = dir.path().join("baro.csv");
        std::fs::write(&p, "time_s,height_m\n1,2\n").unwrap();
        assert_eq!(read_baro(&p).unwrap().0[0].height_m, 2.0);
        let e = read_baro(&dir.path().join("none.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.csv: cannot read"), "{e}");
    }

    /// Arbitrary bytes: an answer, never a panic (the fuzz targets' check,
    /// here on a reproducible stream).
    #[test]
    fn arbitrary_bytes_give_an_answer() {
        let mut next = crate::xorshift(0x2545_F491_4F6C_DD1D);
        let alphabet =
            b"time_s,speed_mps,height_m,pressure_hpa,sigma_m,utc,0123456789.-e\n\r#\xFF ";
        for _ in 0..2_000 {
            let len = (next() % 120) as usize;
            let bytes: Vec<u8> = (0..len)
                .map(|_| alphabet[(next() % alphabet.len() as u64) as usize])
                .collect();
            let _ = read_wheel_speed_from(&bytes, Path::new("f.csv"));
            let _ = read_baro_from(&bytes, Path::new("f.csv"));
        }
    }
}
