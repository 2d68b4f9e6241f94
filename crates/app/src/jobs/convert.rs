//! `aidnav convert CONFIG.toml --to kf-gins`: a log aidnav reads, written as
//! KF-GINS input files.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use aidnav_io::kfgins::{gps_week_start, write_kfgins_gnss, write_kfgins_imu};
use serde::Serialize;

use super::{JobError, JobResult, process::process_error};
use crate::process::{Inputs, ProcessConfig};

/// What [`convert_kfgins`] wrote.
#[derive(Debug, Clone, Serialize)]
pub struct ConvertReport {
    /// IMU samples written (one row each, after an opening row of zeros).
    pub imu_samples: usize,
    /// GNSS fixes written.
    pub gnss_epochs: usize,
    /// The GPS week of the first IMU sample; every time written is seconds
    /// since this week's start (past 604 800 when the log crosses a week).
    pub gps_week: u32,
    /// The files written: `imu.txt`, `gnss.txt`, `kf-gins.yaml`.
    pub files: Vec<PathBuf>,
    /// The readers' warnings and what the files leave out.
    pub warnings: Vec<String>,
}

/// Convert the log named by `config` (`data_dir` replaces its `data.dir`)
/// into KF-GINS input files in `out`: `imu.txt` (increments, see
/// [`aidnav_io::kfgins::kfgins_imu_text`]), `gnss.txt` (7 columns,
/// [`aidnav_io::kfgins::kfgins_gnss_text`]) and `kf-gins.yaml`, a KF-GINS
/// configuration skeleton.
///
/// The files are read as `aidnav process` reads them (the configuration's
/// formats and units) and written as the readers give them: IMU in the
/// sensor frame on the IMU file's time tags — `imu.mounting_deg`,
/// `imu.time_offset_s` and `imu.smoothing_s` are *not* applied, so the same
/// configuration with `imu_format = gnss_format = "kf_gins"` reads the same
/// samples back. Times become GPS seconds of week (aidnav's times are GPST
/// seconds since 1970): the first IMU sample's week is subtracted from
/// both files. The YAML's lever arm is the configuration's, rotated into
/// the sensor frame; its initial attitude has roll and pitch levelled from
/// the first `initial.static_s` of specific force (sensor frame) and yaw
/// from `initial.attitude_deg` when given, 0 otherwise (KF-GINS needs it:
/// edit it); its noise is `[imu.noise]` in KF-GINS's units.
pub fn convert_kfgins(
    config: &Path,
    data_dir: Option<&Path>,
    out: &Path,
) -> JobResult<ConvertReport> {
    let (mut cfg, _) = aidnav_io::load_toml::<ProcessConfig>(config)?;
    if let Some(d) = data_dir {
        cfg.data.dir = d.to_path_buf();
    }
    let base = config.parent().unwrap_or(Path::new("."));
    let inputs = Inputs::load_raw(&cfg, base).map_err(process_error)?;
    let (Some(first), Some(fix)) = (inputs.imu.first(), inputs.gnss.first()) else {
        return Err(JobError::Refused(format!(
            "{}: {} IMU samples and {} GNSS fixes read: nothing to convert",
            config.display(),
            inputs.imu.len(),
            inputs.gnss.len()
        )));
    };
    let Some((week, start)) = gps_week_start(first.time_s) else {
        return Err(JobError::Refused(format!(
            "{}: the first IMU time {} s is before GPS time began (1980-01-06 as GPST seconds since 1970): not a time KF-GINS's seconds of week can hold",
            config.display(),
            first.time_s
        )));
    };
    aidnav_io::writers::ensure_dir(out)?;
    let imu_path = out.join("imu.txt");
    let gnss_path = out.join("gnss.txt");
    let yaml_path = out.join("kf-gins.yaml");
    write_kfgins_imu(&imu_path, &inputs.imu, start)?;
    write_kfgins_gnss(&gnss_path, &inputs.gnss, start)?;
    let yaml = yaml(&cfg, &inputs, start, fix, out);
    aidnav_io::writers::write_atomic(&yaml_path, yaml.as_bytes())?;
    let mut warnings = inputs.warnings.clone();
    if inputs.gnss.iter().any(|g| g.velocity_ned.is_some()) {
        warnings.push(format!(
            "{}: GNSS velocity not written (7 columns: KF-GINS's default)",
            gnss_path.display()
        ));
    }
    warnings.push(format!(
        "{}: fix quality not written (KF-GINS has none): score a read-back with score.reference_quality = [\"unknown\"]",
        gnss_path.display()
    ));
    Ok(ConvertReport {
        imu_samples: inputs.imu.len(),
        gnss_epochs: inputs.gnss.len(),
        gps_week: week,
        files: vec![imu_path, gnss_path, yaml_path],
        warnings,
    })
}

/// `[a, b, c]` in YAML.
fn list(v: [f64; 3]) -> String {
    format!("[ {}, {}, {} ]", v[0], v[1], v[2])
}

/// The KF-GINS configuration skeleton.
fn yaml(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    start: f64,
    fix: &aidnav_io::rtklib::GnssFix,
    out: &Path,
) -> String {
    let imu = &inputs.imu;
    let n = imu.len();
    let span = imu[n - 1].time_s - imu[0].time_s;
    let rate = if span > 0.0 {
        ((n - 1) as f64 / span).round().max(1.0)
    } else {
        1.0
    };
    // KF-GINS's first epoch: the first IMU sample at or after the first fix.
    let t0 = imu
        .iter()
        .map(|s| s.time_s)
        .find(|&t| t >= fix.time_s)
        .unwrap_or(imu[0].time_s);
    let static_end = t0 + cfg.initial.static_s.max(0.0);
    let (sum, count) = imu
        .iter()
        .filter(|s| s.time_s >= t0 && s.time_s <= static_end)
        .fold((nalgebra::Vector3::zeros(), 0usize), |(a, c), s| {
            (a + s.specific_force, c + 1)
        });
    let f = if count > 0 {
        sum / count as f64
    } else {
        nalgebra::Vector3::new(0.0, 0.0, -1.0)
    };
    let roll = (-f.y).atan2(-f.z).to_degrees();
    let pitch = f.x.atan2((f.y * f.y + f.z * f.z).sqrt()).to_degrees();
    let yaw = cfg.initial.attitude_deg.map_or(0.0, |a| a[2]);
    let [r, p, y] = cfg.imu.mounting_deg.map(f64::to_radians);
    let c = crate::process::euler_to_ctm(r, p, y);
    let lever = c.transpose() * nalgebra::Vector3::from(cfg.gnss.lever_arm_m);
    let v = fix.velocity_ned.unwrap_or_else(nalgebra::Vector3::zeros);
    let s = fix.position_sigma_neu;
    let nz = &cfg.imu.noise.values;
    // 1 mg = 1e-3 × 9.80665 m/s², 1 mGal = 1e-5 m/s².
    let mgal = |p: &aidnav_models::ned_ins::PerAxis| {
        list(p.0.map(|mg| mg * aidnav_frames::constants::STANDARD_GRAVITY_M_S2 * 100.0))
    };
    let mut y_text = String::new();
    let _ = write!(
        y_text,
        "# KF-GINS configuration written by aidnav {ver} (`aidnav convert --to kf-gins`).
# Times are GPS seconds of week: aidnav's GPST seconds since 1970 minus {start} s
# (the start of the first IMU sample's week). The IMU file is in the SENSOR
# frame as the log gives it (aidnav's imu.mounting_deg and imu.time_offset_s
# are not applied); initatt and antlever below are for that frame.
# A skeleton: check initatt (yaw is not known from the log) and the noise.

imupath: \"{imu}\"
gnsspath: \"{gnss}\"
outputpath: \"{outp}\"

imudatalen: 7
imudatarate: {rate}

starttime: {t0}
endtime: -1

# first GNSS fix [deg, deg, m] and its velocity (0 without one) [m/s]
initpos: {pos}
initvel: {vel}
# roll, pitch levelled over the first {st} s (sensor frame); yaw {yaw_note}
initatt: {att}

initgyrbias: [ 0, 0, 0 ]    # [deg/h]
initaccbias: [ 0, 0, 0 ]    # [mGal]
initgyrscale: [ 0, 0, 0 ]   # [ppm]
initaccscale: [ 0, 0, 0 ]   # [ppm]

initposstd: {pstd}
initvelstd: [ 0.1, 0.1, 0.1 ]
initattstd: [ 1.0, 1.0, 10.0 ]

# aidnav's [imu.noise]
imunoise:
  arw: {arw}     # [deg/sqrt(hr)]
  vrw: {vrw}     # [m/s/sqrt(hr)]
  gbstd: {gb}    # [deg/hr]
  abstd: {ab}    # [mGal]
  gsstd: {gs}    # [ppm]
  asstd: {as_}   # [ppm]
  corrtime: {corr}   # [hr]

# aidnav's gnss.lever_arm_m (body frame) rotated into the sensor frame [m]
antlever: {lever}
",
        ver = crate::VERSION,
        imu = out.join("imu.txt").display(),
        gnss = out.join("gnss.txt").display(),
        outp = out.display(),
        t0 = t0 - start,
        pos = list([
            fix.position.latitude_rad.to_degrees(),
            fix.position.longitude_rad.to_degrees(),
            fix.position.height_m
        ]),
        vel = list([v.x, v.y, v.z]),
        st = cfg.initial.static_s,
        yaw_note = if cfg.initial.attitude_deg.is_some() {
            "from initial.attitude_deg"
        } else {
            "0: unknown, set it"
        },
        att = list([roll, pitch, yaw]),
        pstd = list([s.x, s.y, s.z]),
        arw = list(nz.arw_deg_per_sqrt_h.0),
        vrw = list(nz.vrw_mps_per_sqrt_h.0),
        gb = list(nz.gyro_bias_deg_per_h.0),
        ab = mgal(&nz.accel_bias_mg),
        gs = list(nz.gyro_scale_ppm.0),
        as_ = list(nz.accel_scale_ppm.0),
        corr = nz.bias_correlation_s / 3600.0,
        lever = list([lever.x, lever.y, lever.z]),
    );
    y_text
}
