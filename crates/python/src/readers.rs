//! The readers of every format `process` reads, to columns of numpy
//! arrays; and the same columns back to samples (in-memory inputs).

use std::path::PathBuf;

use aidnav::app::process::{GnssFormat, ImuFormat};
use aidnav::frames::earth::Geodetic;
use aidnav::io::rtklib::{GnssFix, ImuSample};
use nalgebra::Vector3;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::json_of;
use crate::errors::{self, DataError};

/// Add the readers to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_imu, m)?)?;
    m.add_function(wrap_pyfunction!(read_gnss, m)?)?;
    Ok(())
}

/// The IMU columns, SI, sensor frame: the generic IMU CSV's names.
pub const IMU_COLUMNS: [&str; 7] = [
    "time_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2",
];

/// The GNSS columns: required ones first (the generic GNSS CSV's names),
/// then the optional quality, satellites and velocity (NaN: none).
pub const GNSS_COLUMNS: [&str; 16] = [
    "gpst_s",
    "lat_deg",
    "lon_deg",
    "height_m",
    "sigma_n_m",
    "sigma_e_m",
    "sigma_u_m",
    "quality",
    "satellites",
    "vel_n_mps",
    "vel_e_mps",
    "vel_d_mps",
    "sigma_vel_n_mps",
    "sigma_vel_e_mps",
    "sigma_vel_u_mps",
    "has_velocity",
];

/// A format by its configuration name (`imu_format` / `gnss_format`).
fn format<T: serde::de::DeserializeOwned>(name: &str, key: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(name.into()))
        .map_err(|e| PyValueError::new_err(format!("{key} = {name:?}: {e}")))
}

/// Samples as columns.
pub fn imu_columns<'py>(py: Python<'py>, imu: &[ImuSample]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let col = |f: &dyn Fn(&ImuSample) -> f64| imu.iter().map(f).collect::<Vec<f64>>();
    d.set_item(IMU_COLUMNS[0], PyArray1::from_vec(py, col(&|s| s.time_s)))?;
    for k in 0..3 {
        d.set_item(
            IMU_COLUMNS[1 + k],
            PyArray1::from_vec(py, col(&|s| s.angular_rate[k])),
        )?;
    }
    for k in 0..3 {
        d.set_item(
            IMU_COLUMNS[4 + k],
            PyArray1::from_vec(py, col(&|s| s.specific_force[k])),
        )?;
    }
    Ok(d)
}

/// Fixes as columns.
pub fn gnss_columns<'py>(py: Python<'py>, gnss: &[GnssFix]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let col = |f: &dyn Fn(&GnssFix) -> f64| gnss.iter().map(f).collect::<Vec<f64>>();
    let cols: [Vec<f64>; 7] = [
        col(&|g| g.time_s),
        col(&|g| g.position.latitude_rad.to_degrees()),
        col(&|g| g.position.longitude_rad.to_degrees()),
        col(&|g| g.position.height_m),
        col(&|g| g.position_sigma_neu[0]),
        col(&|g| g.position_sigma_neu[1]),
        col(&|g| g.position_sigma_neu[2]),
    ];
    for (name, c) in GNSS_COLUMNS.iter().zip(cols) {
        d.set_item(name, PyArray1::from_vec(py, c))?;
    }
    d.set_item(
        "quality",
        PyArray1::from_vec(py, gnss.iter().map(|g| i64::from(g.quality)).collect()),
    )?;
    d.set_item(
        "satellites",
        PyArray1::from_vec(py, gnss.iter().map(|g| i64::from(g.satellites)).collect()),
    )?;
    for k in 0..3 {
        d.set_item(
            GNSS_COLUMNS[9 + k],
            PyArray1::from_vec(py, col(&|g| g.velocity_ned.map_or(f64::NAN, |v| v[k]))),
        )?;
        d.set_item(
            GNSS_COLUMNS[12 + k],
            PyArray1::from_vec(
                py,
                col(&|g| g.velocity_sigma_neu.map_or(f64::NAN, |v| v[k])),
            ),
        )?;
    }
    d.set_item(
        "has_velocity",
        PyArray1::from_vec(py, gnss.iter().map(|g| g.velocity_ned.is_some()).collect()),
    )?;
    Ok(d)
}

/// A column of a dict of arrays as f64 (`None`: absent).
fn column(d: &Bound<'_, PyDict>, name: &str, origin: &str) -> PyResult<Option<Vec<f64>>> {
    let Some(v) = d.get_item(name)? else {
        return Ok(None);
    };
    let np = d.py().import("numpy")?;
    let arr = np
        .call_method1("ascontiguousarray", (v,))?
        .call_method1("astype", ("float64",))?;
    let arr: PyReadonlyArray1<'_, f64> = arr.extract().map_err(|_| {
        DataError::new_err(format!(
            "{origin}: column `{name}`: not a 1-D array of numbers"
        ))
    })?;
    Ok(Some(arr.as_slice()?.to_vec()))
}

fn required(d: &Bound<'_, PyDict>, name: &str, origin: &str, known: &[&str]) -> PyResult<Vec<f64>> {
    column(d, name, origin)?.ok_or_else(|| {
        DataError::new_err(format!(
            "{origin}: column `{name}` is missing (columns: {})",
            known.join(", ")
        ))
    })
}

/// Refuse columns the reader does not know, a length that differs, a
/// value that is not finite.
fn check_columns(
    d: &Bound<'_, PyDict>,
    origin: &str,
    known: &[&str],
    cols: &[(&str, &[f64], bool)],
) -> PyResult<usize> {
    for k in d.keys() {
        let k: String = k.extract()?;
        if !known.contains(&k.as_str()) {
            return Err(DataError::new_err(format!(
                "{origin}: unknown column `{k}` (columns: {})",
                known.join(", ")
            )));
        }
    }
    let n = cols.first().map_or(0, |c| c.1.len());
    for (name, c, finite) in cols {
        if c.len() != n {
            return Err(DataError::new_err(format!(
                "{origin}: column `{name}` has {} rows, `{}` has {n}",
                c.len(),
                cols[0].0
            )));
        }
        if *finite && let Some(i) = c.iter().position(|v| !v.is_finite()) {
            return Err(DataError::new_err(format!(
                "{origin}: row {i}: column `{name}`: {} is not a finite number",
                c[i]
            )));
        }
    }
    Ok(n)
}

/// IMU samples from columns (names of [`IMU_COLUMNS`]).
pub fn imu_from_columns(d: &Bound<'_, PyDict>, origin: &str) -> PyResult<Vec<ImuSample>> {
    let cols: Vec<Vec<f64>> = IMU_COLUMNS
        .iter()
        .map(|c| required(d, c, origin, &IMU_COLUMNS))
        .collect::<PyResult<_>>()?;
    let named: Vec<(&str, &[f64], bool)> = IMU_COLUMNS
        .iter()
        .zip(&cols)
        .map(|(n, c)| (*n, c.as_slice(), true))
        .collect();
    let n = check_columns(d, origin, &IMU_COLUMNS, &named)?;
    Ok((0..n)
        .map(|i| ImuSample {
            time_s: cols[0][i],
            angular_rate: Vector3::new(cols[1][i], cols[2][i], cols[3][i]),
            specific_force: Vector3::new(cols[4][i], cols[5][i], cols[6][i]),
        })
        .collect())
}

/// GNSS fixes from columns (names of [`GNSS_COLUMNS`]; quality default 0
/// (unknown), satellites 0, velocity none unless all three `vel_*` are
/// given (NaN in a row: none that epoch), its σ 0.1 m/s by default).
pub fn gnss_from_columns(d: &Bound<'_, PyDict>, origin: &str) -> PyResult<Vec<GnssFix>> {
    let req: Vec<Vec<f64>> = GNSS_COLUMNS[..7]
        .iter()
        .map(|c| required(d, c, origin, &GNSS_COLUMNS))
        .collect::<PyResult<_>>()?;
    let opt = |name: &str| column(d, name, origin);
    let n = req[0].len();
    let quality = opt("quality")?.unwrap_or_else(|| vec![0.0; n]);
    let satellites = opt("satellites")?.unwrap_or_else(|| vec![0.0; n]);
    let vel: Vec<Option<Vec<f64>>> = (9..15)
        .map(|k| opt(GNSS_COLUMNS[k]))
        .collect::<PyResult<_>>()?;
    let mut named: Vec<(&str, &[f64], bool)> = GNSS_COLUMNS[..7]
        .iter()
        .zip(&req)
        .map(|(n, c)| (*n, c.as_slice(), true))
        .collect();
    named.push(("quality", &quality, true));
    named.push(("satellites", &satellites, true));
    for (k, v) in vel.iter().enumerate() {
        if let Some(v) = v {
            named.push((GNSS_COLUMNS[9 + k], v, false));
        }
    }
    let mut known = GNSS_COLUMNS.to_vec();
    known.push("index");
    check_columns(d, origin, &known, &named)?;
    let bad = |i: usize, col: &str, msg: String| {
        DataError::new_err(format!("{origin}: row {i}: column `{col}`: {msg}"))
    };
    (0..n)
        .map(|i| {
            let (lat, lon) = (req[1][i], req[2][i]);
            if lat.abs() > 90.0 {
                return Err(bad(i, "lat_deg", format!("{lat} is beyond the poles")));
            }
            for (k, name) in ["sigma_n_m", "sigma_e_m", "sigma_u_m"].iter().enumerate() {
                if req[4 + k][i] <= 0.0 {
                    return Err(bad(i, name, format!("σ = {} must be > 0", req[4 + k][i])));
                }
            }
            let q = quality[i];
            if !(0.0..=255.0).contains(&q) || q.fract() != 0.0 {
                return Err(bad(
                    i,
                    "quality",
                    format!("{q} is not a quality code 0–255"),
                ));
            }
            let velocity = match (&vel[0], &vel[1], &vel[2]) {
                (Some(a), Some(b), Some(c))
                    if a[i].is_finite() && b[i].is_finite() && c[i].is_finite() =>
                {
                    Some(Vector3::new(a[i], b[i], c[i]))
                }
                _ => None,
            };
            let sigma_v = velocity.map(|_| {
                Vector3::from_fn(|k, _| {
                    vel[3 + k]
                        .as_ref()
                        .map(|s| s[i])
                        .filter(|s| s.is_finite() && *s > 0.0)
                        .unwrap_or(0.1)
                })
            });
            Ok(GnssFix {
                time_s: req[0][i],
                position: Geodetic {
                    latitude_rad: lat.to_radians(),
                    longitude_rad: lon.to_radians(),
                    height_m: req[3][i],
                },
                quality: q as u8,
                satellites: satellites[i].max(0.0) as u32,
                position_sigma_neu: Vector3::new(req[4][i], req[5][i], req[6][i]),
                velocity_ned: velocity,
                velocity_sigma_neu: sigma_v,
            })
        })
        .collect()
}

/// Options of a generic CSV as the configuration writes them.
fn units_of(units: Option<&Bound<'_, PyAny>>) -> PyResult<Option<aidnav::io::kfgins::ImuUnits>> {
    match units {
        None => Ok(None),
        Some(u) if u.is_none() => Ok(None),
        Some(u) => serde_json::from_value(json_of(u, "units")?)
            .map(Some)
            .map_err(|e| PyValueError::new_err(format!("units: {e}"))),
    }
}

/// Read an IMU file as `process` reads it (`format` as `data.imu_format`:
/// `rtklib_tagged` with `tags`, `kf_gins`, `generic_csv` with optional
/// `units` as `data.imu_units`). Returns (columns, warnings): sensor frame,
/// SI, time as recorded.
#[pyfunction]
#[pyo3(signature = (path, format="generic_csv", tags=None, units=None))]
fn read_imu<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: &str,
    tags: Option<PathBuf>,
    units: Option<&Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
    let f: ImuFormat = self::format(format, "format")?;
    let units = units_of(units)?;
    let (imu, warnings) = py
        .detach(|| {
            let options = aidnav::io::formats::ImuReadOptions {
                tags: tags.as_deref(),
                units,
                ..Default::default()
            };
            aidnav::app::process::read_imu(f, &path, &options)
        })
        .map_err(errors::process)?;
    Ok((imu_columns(py, &imu)?, warnings))
}

/// Read a GNSS file as `process` reads it (`format` as `data.gnss_format`:
/// `rtklib_pos`, `kf_gins`, `nmea`, `ubx`, `generic_csv` with optional
/// `sigma_m = (horizontal, up)`). Returns (columns, warnings).
#[pyfunction]
#[pyo3(signature = (path, format="rtklib_pos", sigma_m=None))]
fn read_gnss<'py>(
    py: Python<'py>,
    path: PathBuf,
    format: &str,
    sigma_m: Option<[f64; 2]>,
) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
    let f: GnssFormat = self::format(format, "format")?;
    let (gnss, warnings) = py
        .detach(|| aidnav::app::process::read_gnss(f, &path, sigma_m))
        .map_err(errors::process)?;
    Ok((gnss_columns(py, &gnss)?, warnings))
}
