//! Spec 40: process a recorded IMU + GNSS log end to end with the NED
//! filter ([`aidnav_integration::ned`]) and score it with simulated GNSS
//! outages and injected anomalies.
//!
//! Pipeline: read (GNSS: RTKLIB `.pos`, KF-GINS text, NMEA; IMU: raw CSV +
//! `.tag`, KF-GINS increments, generic CSV), shift the IMU time
//! by `imu.time_offset_s`, rotate sensor → body (`imu.mounting_deg`, Groves'
//! Euler_to_CTM convention as the data set's upstream uses), smooth with a
//! zero-phase centred moving average (`imu.smoothing_s`, offline), initialise
//! (levelling and gyro bias over the first `initial.static_s` seconds at
//! rest, heading from the first GNSS course above `initial.heading_speed_mps`
//! — the car is assumed to drive straight off), then filter: IMU increments
//! by the trapezoid rule, split at every GNSS epoch so each update is made
//! at the fix's own time.
//!
//! Layout: [`config`] (the configuration file and its validation), this
//! module (reading and initialisation), [`api`] ([`Process`]: run and score
//! as library calls, no file I/O), [`run`] (one filter pass under a plan:
//! the plan becomes a prepared GNSS stream and observers of
//! [`aidnav_integration::ned_loop`]), [`score`] (the outage, efficiency and
//! anomaly scores of a run), [`scoring`] (every scoring run of a log,
//! [`Scores`]), [`export`] (a result and its scores as files); the configuration's
//! validation lives beside [`config`].

pub mod api;
pub mod config;
pub mod export;
pub mod run;
pub mod score;
pub mod scoring;
mod start;
pub mod template;
pub mod tune;
mod validate;

pub use api::*;
pub use config::*;
pub use run::*;
pub use score::*;
pub use scoring::*;
pub use start::{Start, StartKind, initialise};
pub use template::{config_template, doc_of};

pub use aidnav_ins::mounting::euler_to_ctm;

use std::path::Path;

use aidnav_estimation::EstimationError;
use aidnav_ins::samples::moving_average;
use aidnav_io::rtklib::{GnssFix, ImuSample, read_pos, read_tagged_imu};

/// Anything processing can fail with.
#[derive(Debug, thiserror::Error)]
pub enum ProcessError {
    /// Reading the inputs.
    #[error(transparent)]
    Io(#[from] aidnav_io::IoError),
    /// The filter.
    ///
    /// The cause is part of the message and deliberately not also returned
    /// by `Error::source`, so a printer walking the chain shows it once.
    #[error("filter: {0}")]
    Estimation(EstimationError),
    /// The data do not allow processing.
    #[error("{0}")]
    Data(String),
}

impl From<EstimationError> for ProcessError {
    fn from(error: EstimationError) -> Self {
        ProcessError::Estimation(error)
    }
}

/// IMU samples (body frame) and GNSS fixes ready for the filter.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// Body-frame IMU samples, SI.
    pub imu: Vec<ImuSample>,
    /// GNSS fixes.
    pub gnss: Vec<GnssFix>,
    /// Reader warnings.
    pub warnings: Vec<String>,
}

impl Inputs {
    /// Read the files named in the configuration (relative to `base`),
    /// time-shift, rotate to the body frame and smooth: [`load_inputs`].
    pub fn load(cfg: &ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        load_inputs(cfg, base)
    }

    /// [`Inputs::load`] without the smoothing (`imu.smoothing_s`): the
    /// samples as the sensor gave them, for noise analysis.
    pub fn load_unsmoothed(cfg: &ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        load_unsmoothed(cfg, base)
    }

    /// These inputs with the IMU smoothed by a zero-phase centred moving
    /// average over `smoothing_s` (none at 0 or for fewer than 3 samples).
    pub fn smoothed(&self, smoothing_s: f64) -> Self {
        let mut out = self.clone();
        let imu = &self.imu;
        if smoothing_s > 0.0 && imu.len() > 2 {
            let dt = (imu[imu.len() - 1].time_s - imu[0].time_s) / (imu.len() - 1) as f64;
            let half = ((smoothing_s / dt) / 2.0).round() as usize;
            if half > 0 {
                out.imu = moving_average(imu, half);
            }
        }
        out
    }
}

/// Read, time-shift, rotate to the body frame and smooth.
pub fn load_inputs(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    Ok(load_unsmoothed(cfg, base)?.smoothed(cfg.imu.smoothing_s))
}

/// Read, time-shift and rotate to the body frame.
pub fn load_unsmoothed(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    let dir = if cfg.data.dir.is_absolute() {
        cfg.data.dir.clone()
    } else {
        base.join(&cfg.data.dir)
    };
    let imu_path = dir.join(&cfg.data.imu);
    let (mut imu, mut warnings) = match cfg.data.imu_format {
        ImuFormat::RtklibTagged => {
            let tags = cfg.data.imu_tags.as_ref().ok_or_else(|| {
                ProcessError::Data("data.imu_tags is needed for imu_format = rtklib_tagged".into())
            })?;
            read_tagged_imu(&imu_path, &dir.join(tags))?
        }
        ImuFormat::KfGins => aidnav_io::kfgins::read_kfgins_imu(&imu_path)?,
        ImuFormat::GenericCsv => aidnav_io::kfgins::read_generic_imu(&imu_path)?,
    };
    let gnss_path = dir.join(&cfg.data.gnss);
    let (gnss, w) = match cfg.data.gnss_format {
        GnssFormat::RtklibPos => read_pos(&gnss_path)?,
        GnssFormat::KfGins => aidnav_io::kfgins::read_kfgins_gnss(&gnss_path)?,
        GnssFormat::Nmea => aidnav_io::nmea::read_nmea(&gnss_path)?,
    };
    warnings.extend(w);
    aidnav_ins::mounting::mount(&mut imu, cfg.imu.mounting_deg, cfg.imu.time_offset_s);
    warnings.extend(check_overlap(&imu, &gnss, &imu_path, &gnss_path)?);
    Ok(Inputs {
        imu,
        gnss,
        warnings,
    })
}

/// The IMU and GNSS time spans must overlap (GNSS in seconds of week against
/// IMU seconds since 1970, or an impossible date, would otherwise run without
/// a single update): an error printing both spans with their dates when no
/// GNSS epoch lies within the IMU span; the number of GNSS epochs outside it
/// (no update is made from them) as a warning.
pub fn check_overlap(
    imu: &[ImuSample],
    gnss: &[GnssFix],
    imu_path: &Path,
    gnss_path: &Path,
) -> Result<Option<String>, ProcessError> {
    use aidnav_io::text::date_time;
    let (Some(i0), Some(i1), Some(g0), Some(g1)) =
        (imu.first(), imu.last(), gnss.first(), gnss.last())
    else {
        return Err(ProcessError::Data(format!(
            "{} holds {} IMU samples and {} {} GNSS epochs: nothing to process",
            imu_path.display(),
            imu.len(),
            gnss_path.display(),
            gnss.len()
        )));
    };
    let (a, b) = (i0.time_s, i1.time_s);
    let before = gnss.iter().filter(|g| g.time_s < a).count();
    let after = gnss.iter().filter(|g| g.time_s > b).count();
    let span = |x: f64, y: f64| {
        format!(
            "{} to {} (GPST; {}–{} s since 1970)",
            date_time(x),
            date_time(y),
            aidnav_io::text::num(x),
            aidnav_io::text::num(y)
        )
    };
    if before + after == gnss.len() {
        return Err(ProcessError::Data(format!(
            "the IMU and GNSS times do not overlap: no GNSS update could be made\n  IMU  {}: {}\n  GNSS {}: {}\n(same time scale? KF-GINS GNSS time in seconds of week against IMU seconds since 1970, a wrong date or imu.time_offset_s)",
            imu_path.display(),
            span(a, b),
            gnss_path.display(),
            span(g0.time_s, g1.time_s)
        )));
    }
    Ok((before + after > 0).then(|| {
        format!(
            "{}: {} of {} GNSS epochs lie outside the IMU span {} ({before} before its start, {after} after its end): no update is made from them",
            gnss_path.display(),
            before + after,
            gnss.len(),
            span(a, b)
        )
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_frames::earth::Geodetic;
    use nalgebra::Vector3;

    fn imu_at(times: impl Iterator<Item = f64>) -> Vec<ImuSample> {
        times
            .map(|t| ImuSample {
                time_s: t,
                specific_force: Vector3::new(0.0, 0.0, -9.8),
                angular_rate: Vector3::zeros(),
            })
            .collect()
    }

    fn gnss_at(times: impl Iterator<Item = f64>) -> Vec<GnssFix> {
        times
            .map(|t| GnssFix {
                time_s: t,
                position: Geodetic {
                    latitude_rad: 0.6,
                    longitude_rad: 0.2,
                    height_m: 10.0,
                },
                quality: 1,
                satellites: 20,
                position_sigma_neu: Vector3::repeat(0.02),
                velocity_ned: None,
                velocity_sigma_neu: None,
            })
            .collect()
    }

    /// 2025-07-08 19:34:18 GPST in seconds since 1970.
    const T0: f64 = 1_752_003_258.0;

    #[test]
    fn imu_and_gnss_times_that_do_not_overlap_are_an_error() {
        // KF-GINS GNSS in seconds of week against IMU seconds since 1970.
        let imu = imu_at((0..100).map(|k| T0 + k as f64 * 0.01));
        let gnss = gnss_at((0..4).map(|k| 243_258.0 + k as f64));
        let e = check_overlap(&imu, &gnss, Path::new("imu.csv"), Path::new("gnss.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("do not overlap"), "{e}");
        assert!(
            e.contains("IMU  imu.csv: 2025-07-08 19:34:18.000 to 2025-07-08 19:34:18.990"),
            "{e}"
        );
        assert!(
            e.contains("GNSS gnss.txt: 1970-01-03 19:34:18.000 to 1970-01-03 19:34:21.000"),
            "{e}"
        );
    }

    #[test]
    fn gnss_epochs_outside_the_imu_span_are_counted() {
        let imu = imu_at((0..1000).map(|k| T0 + k as f64 * 0.01));
        let gnss = gnss_at((0..20).map(|k| T0 - 1.0 + k as f64));
        let w = check_overlap(&imu, &gnss, Path::new("imu.csv"), Path::new("g.pos"))
            .unwrap()
            .unwrap();
        // Epochs at −1 s (before) and 10…18 s (after); 0…9 s inside.
        assert!(
            w.starts_with("g.pos: 10 of 20 GNSS epochs lie outside the IMU span")
                && w.contains("(1 before its start, 9 after its end)"),
            "{w}"
        );
        let inside = gnss_at((0..5).map(|k| T0 + k as f64));
        assert!(
            check_overlap(&imu, &inside, Path::new("i"), Path::new("g"))
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn a_run_without_a_gnss_update_is_an_error() {
        let mut cfg: ProcessConfig =
            toml::from_str("[data]\ndir = \".\"\nimu = \"none\"\ngnss = \"none\"\n").unwrap();
        cfg.initial.attitude_deg = Some([0.0; 3]);
        // The only fix is at the last IMU sample's time: the filter starts
        // there and no update follows.
        let inputs = Inputs {
            imu: imu_at((0..100).map(|k| k as f64 * 0.01)),
            gnss: gnss_at([0.99].into_iter()),
            warnings: Vec::new(),
        };
        let e = initialise(&cfg, &inputs).unwrap_err().to_string();
        assert!(e.contains("the run would make no update"), "{e}");
    }
}
