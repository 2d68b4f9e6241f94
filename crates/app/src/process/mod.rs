//! Spec 40: process a recorded IMU + GNSS log end to end with the NED
//! filter ([`aidnav_integration::ned`]) and score it with simulated GNSS
//! outages and injected anomalies.
//!
//! Pipeline: read (GNSS: RTKLIB `.pos`, KF-GINS text, NMEA, u-blox UBX
//! (NAV-PVT), generic CSV; IMU: raw CSV +
//! `.tag`, KF-GINS increments, generic CSV), shift the IMU time
//! by `imu.time_offset_s`, rotate sensor → body (`imu.mounting_deg`, Groves'
//! Euler_to_CTM convention as the data set's upstream uses), check that the
//! IMU and GNSS overlap and that the gyro turns with the GNSS course
//! ([`check_turn_rate`]: a unit mistake), smooth with a
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
//! [`Scores`]), [`consistency`] (the filter's covariance against the actual
//! error), [`warnings`] (divergence, rejection runs and the other warnings
//! of a run), [`export`] (a result and its scores as files); the
//! configuration's validation lives beside [`config`].

pub mod api;
pub mod config;
pub mod consistency;
pub mod export;
pub mod reference;
pub mod run;
pub mod score;
pub mod scoring;
pub mod selection;
mod start;
pub mod template;
pub mod tune;
pub mod turn_rate;
mod validate;
pub mod warnings;

pub use api::{Process, ProcessResult, Smoothed, Smoothing, StartSummary};
pub use config::{
    AdaptiveNoise, BRIDGE_PREDICTORS, BaroFormat, BarometerSection, CheckLevel, ChecksConfig,
    ConstraintConfig, DataFiles, EfficiencyConfig, Feedback, FilterConfig, FixQuality, GnssConfig,
    GnssFormat, GnssLatency, ImuConfig, ImuFormat, InitialConfig, NoiseConfig, OutageBridgeConfig,
    OutputConfig, Platform, PlatformPreset, PolicyName, ProcessConfig, QualitySigmaScale,
    ScoreConfig, StandstillConfig, TuneConfig, TuneObjective, WheelSpeedFormat, WheelSpeedSection,
    config_name,
};
pub use consistency::{
    Consistency, ELLIPSOID_PROBABILITY, NisConsistency, OutageConsistency, POSITION_DOF, chi2_3_99,
    nis_consistency, outage_consistency, position_nees,
};
pub use run::{
    Epoch, MAX_SMOOTHED_EPOCHS, ResetEvent, Run, RunPlan, SolutionRow, fix_position_sigma,
    reset_events, run_filter,
};
pub use score::{
    EfficiencyScore, OutageScore, bridged_epochs, convergence_times, cut_short_tolerance_s,
    efficiency_in_windows, inject_outliers, is_reference, outage_windows, periodic_windows,
    post_outage_bursts, reference_epochs, score_windows, tracking_rms, tracking_rms_with_gnss,
};
pub use scoring::{BridgedScores, DriftSeries, Scores, score_log};
pub use selection::{SelectedEpoch, SelectionSummary, select_sources, selection_summary};
pub use start::{Start, StartKind, initialise};
pub use template::{config_template, doc_of};
pub use turn_rate::{TurnRateFit, check_turn_rate, turn_rate_fit};
pub use warnings::{
    DIVERGENCE_NIS_PER_DOF, DIVERGENCE_WINDOW_S, REJECTION_RUN_S, VEHICLE_FRAME_MIN_UPDATES,
    VEHICLE_FRAME_NORMALISED_MEAN, VEHICLE_FRAME_REJECTED_FRACTION, Warning, WarningKind,
    divergence_warnings, rejection_run_warnings, vehicle_frame_warning,
};

pub use aidnav_ins::mounting::euler_to_ctm;

use std::path::Path;

use aidnav_estimation::EstimationError;
use aidnav_ins::samples::moving_average_in_place;
use aidnav_io::rtklib::{GnssFix, ImuSample};
use aidnav_sensors::{BaroSample, WheelSpeedSample};

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

/// IMU samples (body frame), GNSS fixes and the other aiding streams
/// ready for the filter.
#[derive(Debug, Clone)]
pub struct Inputs {
    /// Body-frame IMU samples, SI.
    pub imu: Vec<ImuSample>,
    /// GNSS fixes.
    pub gnss: Vec<GnssFix>,
    /// Wheel-speed samples (`[wheel_speed]`; empty without).
    pub wheel_speed: Vec<WheelSpeedSample>,
    /// Barometric heights (`[barometer]`; empty without).
    pub barometer: Vec<BaroSample>,
    /// Reader warnings.
    pub warnings: Vec<String>,
}

impl Inputs {
    /// Body-frame IMU samples and GNSS fixes as they are (no other stream,
    /// no warning): inputs built in memory.
    pub fn new(imu: Vec<ImuSample>, gnss: Vec<GnssFix>) -> Self {
        Self {
            imu,
            gnss,
            wheel_speed: Vec::new(),
            barometer: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Read the files named in the configuration (relative to `base`),
    /// time-shift, rotate to the body frame and smooth.
    pub fn load(cfg: &ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        load_inputs(cfg, base)
    }

    /// [`Inputs::load`] without the smoothing (`imu.smoothing_s`): the
    /// samples as the sensor gave them, for noise analysis.
    pub fn load_unsmoothed(cfg: &ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        load_unsmoothed(cfg, base)
    }

    /// The samples as the readers give them (sensor frame, the file's time
    /// tags, no smoothing).
    pub fn load_raw(cfg: &ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        load_raw(cfg, base)
    }

    /// These inputs with the IMU smoothed by a zero-phase centred moving
    /// average over `smoothing_s` (none at 0 or for fewer than 3 samples).
    pub fn smoothed(&self, smoothing_s: f64) -> Self {
        self.clone().into_smoothed(smoothing_s)
    }

    /// [`Inputs::smoothed`], taking the inputs: no copy of the raw samples
    /// is kept beside the smoothed ones.
    fn into_smoothed(mut self, smoothing_s: f64) -> Self {
        let imu = &mut self.imu;
        if smoothing_s > 0.0 && imu.len() > 2 {
            let dt = (imu[imu.len() - 1].time_s - imu[0].time_s) / (imu.len() - 1) as f64;
            let half = ((smoothing_s / dt) / 2.0).round() as usize;
            if half > 0 {
                moving_average_in_place(imu, half);
            }
        }
        self
    }
}

/// Read, time-shift, rotate to the body frame and smooth.
fn load_inputs(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    Ok(load_unsmoothed(cfg, base)?.into_smoothed(cfg.imu.smoothing_s))
}

/// Read, time-shift and rotate to the body frame.
fn load_unsmoothed(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    let raw = load_raw(cfg, base)?;
    let dir = data_dir(cfg, base);
    let mut inputs = Inputs::from_samples(
        cfg,
        raw.imu,
        raw.gnss,
        raw.warnings,
        (&dir.join(&cfg.data.imu), &dir.join(&cfg.data.gnss)),
    )?;
    inputs.add_aiding(cfg, raw.wheel_speed, raw.barometer, &dir)?;
    Ok(inputs)
}

/// The samples as the readers give them, before [`Inputs::load_unsmoothed`] applies
/// the configuration: IMU in the sensor frame on the IMU file's time tags
/// (no `imu.mounting_deg`, no `imu.time_offset_s`, no smoothing), GNSS as
/// read, and the readers' warnings. The files are read with the
/// configuration's formats and units, exactly as `aidnav process` reads them.
fn load_raw(cfg: &ProcessConfig, base: &Path) -> Result<Inputs, ProcessError> {
    let dir = data_dir(cfg, base);
    let gnss_path = dir.join(&cfg.data.gnss);
    // The GNSS file is read on a second thread while this one reads the
    // IMU's (the larger); an IMU error comes first, as when read in turn.
    let (imu, gnss) = std::thread::scope(|s| {
        let gnss = s.spawn(|| read_gnss(cfg.data.gnss_format, &gnss_path, cfg.data.gnss_sigma_m));
        let imu = read_configured_imu(cfg, &dir);
        let gnss = gnss
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (imu, gnss)
    });
    let (imu, mut warnings) = imu?;
    let (gnss, w) = gnss?;
    warnings.extend(w);
    let mut wheel_speed = Vec::new();
    if let Some(section) = &cfg.wheel_speed {
        let (samples, w) = section.format.read(&dir.join(&section.file))?;
        wheel_speed = samples;
        warnings.extend(w);
    }
    let mut barometer = Vec::new();
    if let Some(section) = &cfg.barometer {
        let (samples, w) = section.format.read(&dir.join(&section.file))?;
        barometer = samples;
        warnings.extend(w);
    }
    Ok(Inputs {
        imu,
        gnss,
        wheel_speed,
        barometer,
        warnings,
    })
}

/// The directory of the data files: `data.dir`, relative to `base` unless
/// absolute.
pub fn data_dir(cfg: &ProcessConfig, base: &Path) -> std::path::PathBuf {
    if cfg.data.dir.is_absolute() {
        cfg.data.dir.clone()
    } else {
        base.join(&cfg.data.dir)
    }
}

/// Read an IMU file of `format` (sensor frame, SI, time as written): the
/// samples and the reader's warnings. `tags` is the RTKLIB `.tag` file
/// (needed for `rtklib_tagged`), `units` the units of a generic CSV whose
/// columns are named `gx … az`.
pub fn read_imu(
    format: ImuFormat,
    path: &Path,
    options: &aidnav_io::formats::ImuReadOptions<'_>,
) -> Result<(Vec<ImuSample>, Vec<String>), ProcessError> {
    if format == ImuFormat::RtklibTagged && options.tags.is_none() {
        return Err(ProcessError::Data(
            "data.imu_tags is needed for imu_format = rtklib_tagged".into(),
        ));
    }
    Ok(format.read(path, options)?)
}

/// Read the configuration's IMU file (`data.imu` in the data directory
/// `dir`) with its format, time tags, units and `[checks] units`.
pub fn read_configured_imu(
    cfg: &ProcessConfig,
    dir: &Path,
) -> Result<(Vec<ImuSample>, Vec<String>), ProcessError> {
    let tags = cfg.data.imu_tags.as_ref().map(|t| dir.join(t));
    read_imu(
        cfg.data.imu_format,
        &dir.join(&cfg.data.imu),
        &aidnav_io::formats::ImuReadOptions {
            tags: tags.as_deref(),
            units: cfg.data.imu_units,
            unit_checks: cfg.checks.units,
        },
    )
}

/// Read a GNSS file of `format`: the fixes and the reader's warnings.
/// `default_sigma_m` (horizontal, up) is the σ of a generic CSV without σ
/// columns.
pub fn read_gnss(
    format: GnssFormat,
    path: &Path,
    default_sigma_m: Option<[f64; 2]>,
) -> Result<(Vec<GnssFix>, Vec<String>), ProcessError> {
    Ok(format.read(path, default_sigma_m)?)
}

impl Inputs {
    /// Inputs from samples already in memory (sensor-frame IMU, time as
    /// recorded), treated as [`Inputs::load_unsmoothed`] treats the files' samples:
    /// time-shifted (`imu.time_offset_s`), rotated to the body frame
    /// (`imu.mounting_deg`), the fixes re-timed by a known `gnss.latency`, and checked (the spans overlap, the gyro turns
    /// with the GNSS course). `origins` name the IMU and GNSS sources in
    /// messages (the files, or e.g. `imu (in memory)`). Not smoothed.
    pub fn from_samples(
        cfg: &ProcessConfig,
        mut imu: Vec<ImuSample>,
        mut gnss: Vec<GnssFix>,
        mut warnings: Vec<String>,
        origins: (&Path, &Path),
    ) -> Result<Self, ProcessError> {
        let (imu_path, gnss_path) = origins;
        aidnav_ins::mounting::mount(&mut imu, cfg.imu.mounting_deg, cfg.imu.time_offset_s);
        // A known latency: each fix is the antenna's state that long before
        // its tag.
        retime_fixes(&mut gnss, cfg.gnss.known_latency_s());
        warnings.extend(check_overlap(&imu, &gnss, imu_path, gnss_path)?);
        if cfg.checks.turn_rate != CheckLevel::Off {
            let declared = cfg.data.imu_units.map(|u| u.gyro);
            let outcome = check_turn_rate(&imu, &gnss, imu_path, gnss_path, declared);
            if let Err(e) = outcome {
                match cfg.checks.turn_rate {
                    CheckLevel::Warn => warnings.push(e.to_string()),
                    _ => return Err(e),
                }
            }
        }
        Ok(Inputs {
            warnings,
            ..Inputs::new(imu, gnss)
        })
    }

    /// Add the wheel-speed and barometer streams (as read: the sections'
    /// `time_offset_s` is applied here), each checked to overlap the IMU's
    /// span: a configured stream that would give no update is an error
    /// naming its file. `dir` is the data directory (for the messages).
    pub fn add_aiding(
        &mut self,
        cfg: &ProcessConfig,
        mut wheel_speed: Vec<WheelSpeedSample>,
        mut barometer: Vec<BaroSample>,
        dir: &Path,
    ) -> Result<(), ProcessError> {
        if let Some(section) = &cfg.wheel_speed {
            wheel_speed
                .iter_mut()
                .for_each(|s| s.time_s += section.time_offset_s);
            let path = dir.join(&section.file);
            self.check_aiding_overlap(wheel_speed.iter().map(|s| s.time_s), &path)?;
        }
        if let Some(section) = &cfg.barometer {
            barometer
                .iter_mut()
                .for_each(|s| s.time_s += section.time_offset_s);
            let path = dir.join(&section.file);
            self.check_aiding_overlap(barometer.iter().map(|s| s.time_s), &path)?;
        }
        self.wheel_speed = wheel_speed;
        self.barometer = barometer;
        Ok(())
    }

    /// An error unless some sample of an aiding stream lies within the IMU
    /// span; a warning with the count of those outside it.
    fn check_aiding_overlap(
        &mut self,
        times: impl Iterator<Item = f64>,
        path: &Path,
    ) -> Result<(), ProcessError> {
        let (Some(first), Some(last)) = (self.imu.first(), self.imu.last()) else {
            return Ok(());
        };
        let (a, b) = (first.time_s, last.time_s);
        let (mut inside, mut outside) = (0usize, 0usize);
        for t in times {
            if (a..=b).contains(&t) {
                inside += 1;
            } else {
                outside += 1;
            }
        }
        if inside == 0 {
            return Err(ProcessError::Data(format!(
                "{}: none of its {outside} samples lies within the IMU span {}–{} s (GPST s since 1970; same time scale? its time_offset_s?)",
                path.display(),
                aidnav_io::text::num(a),
                aidnav_io::text::num(b),
            )));
        }
        if outside > 0 {
            self.warnings.push(format!(
                "{}: {outside} of {} samples lie outside the IMU span and are not used",
                path.display(),
                inside + outside
            ));
        }
        Ok(())
    }
}

/// Re-time fixes whose tags are `latency_s` late: each becomes the time
/// of the antenna state it describes.
pub(crate) fn retime_fixes(gnss: &mut [GnssFix], latency_s: f64) {
    if latency_s != 0.0 {
        gnss.iter_mut().for_each(|g| g.time_s -= latency_s);
    }
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
        let inputs = Inputs::new(
            imu_at((0..100).map(|k| k as f64 * 0.01)),
            gnss_at([0.99].into_iter()),
        );
        let e = initialise(&cfg, &inputs).unwrap_err().to_string();
        assert!(e.contains("the run would make no update"), "{e}");
    }
}
