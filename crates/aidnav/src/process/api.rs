//! [`Process`]: a recorded log as a library call. Reading the inputs is a
//! separate call ([`super::Inputs::load`]); running and scoring return
//! values and touch no file; [`super::export`] writes them.

use std::path::Path;

use aidnav_frames::earth::Geodetic;

use super::config::{PolicyName, ProcessConfig};
use super::run::{Epoch, ResetEvent, RunPlan, SolutionRow, reset_events, run_filter_rows};
use super::score::{convergence_times, tracking_rms};
use super::scoring::{Scores, score_log};
use super::{Inputs, ProcessError};

/// A recorded IMU + GNSS log ready to be filtered and scored.
///
/// A tiny synthetic log: an IMU at rest (specific force −g, no rotation)
/// at 100 Hz for 12 s and a receiver at one place at 4 Hz; the attitude is
/// given, so no heading from motion is needed. The filter stays at the fix.
///
/// ```
/// use aidnav::frames::earth::Geodetic;
/// use aidnav::io::rtklib::{GnssFix, ImuSample};
/// use aidnav::process::{Inputs, Process, ProcessConfig};
/// use nalgebra::Vector3;
///
/// let mut cfg: ProcessConfig = toml::from_str(
///     "[data]\ndir = \".\"\nimu = \"none\"\ngnss = \"none\"\n",
/// )
/// .unwrap();
/// cfg.initial.attitude_deg = Some([0.0; 3]);
/// cfg.outage_bridge.enabled = false;
/// let place = Geodetic { latitude_rad: 0.6, longitude_rad: 0.2, height_m: 10.0 };
/// let g = aidnav::ins::ned::gravity_ned(&place).z();
/// let imu = (0..1200)
///     .map(|k| ImuSample {
///         time_s: k as f64 * 0.01,
///         specific_force: Vector3::new(0.0, 0.0, -g),
///         angular_rate: Vector3::zeros(),
///     })
///     .collect();
/// let gnss = (0..48)
///     .map(|k| GnssFix {
///         time_s: k as f64 * 0.25,
///         position: place,
///         quality: 1,
///         satellites: 20,
///         position_sigma_neu: Vector3::repeat(0.02),
///         velocity_ned: None,
///         velocity_sigma_neu: None,
///     })
///     .collect();
/// let inputs = Inputs { imu, gnss, warnings: Vec::new() };
/// let process = Process::new(cfg, inputs).unwrap();
/// let result = process.run().unwrap();
/// assert_eq!(result.epochs.len(), 47); // every fix after the first IMU sample
/// assert!(result.tracking_rms_m < 0.05, "{}", result.tracking_rms_m);
/// ```
#[derive(Debug, Clone)]
pub struct Process {
    cfg: ProcessConfig,
    inputs: Inputs,
}

/// What a filter pass over the whole log gives (all GNSS used).
#[derive(Debug, Clone)]
pub struct ProcessResult {
    /// IMU samples used.
    pub imu_samples: usize,
    /// GNSS epochs.
    pub gnss_epochs: usize,
    /// Policy of the GNSS updates.
    pub policy: PolicyName,
    /// One per GNSS epoch after the first IMU sample.
    pub epochs: Vec<Epoch>,
    /// Rows between the GNSS epochs (`output.interval_s`).
    pub between: Vec<SolutionRow>,
    /// The epochs with their RTS-smoothed antenna position (with `output.smooth`).
    pub smoothed: Vec<Epoch>,
    /// Every fix's position, in file order (the trajectory plot).
    pub fix_track: Vec<Geodetic>,
    /// Time of the first fix (GPST s).
    pub first_fix_time_s: f64,
    /// Updates by outcome, in order of first appearance.
    pub outcomes: Vec<(String, usize)>,
    /// The recovery's resets of the filter to a fix, in time order.
    pub resets: Vec<ResetEvent>,
    /// RMS 3-D antenna error over RTK-fixed epochs \[m\].
    pub tracking_rms_m: f64,
    /// RMS 3-D error of the RTS-smoothed antenna positions (with `output.smooth`).
    pub tracking_smoothed_rms_m: Option<f64>,
    /// Time after the first fix at which spec 10's rule declares the
    /// instruments converged, for δ_thr = 3 % and 1 % (with
    /// `filter.convergence_monitor`; None: never).
    pub instrument_convergence_s: Vec<(f64, Option<f64>)>,
    /// Fraction of the epochs at which K_eff > 1.
    pub k_eff_integrated_fraction: f64,
    /// Reader warnings.
    pub warnings: Vec<String>,
}

impl Process {
    /// A log to process under a configuration; refuses inputs the filter
    /// cannot start on (fewer than two IMU samples, no GNSS fix).
    pub fn new(config: ProcessConfig, inputs: Inputs) -> Result<Self, ProcessError> {
        if inputs.imu.len() < 2 || inputs.gnss.is_empty() {
            return Err(ProcessError::Data(format!(
                "{} IMU samples and {} GNSS fixes: need at least 2 and 1",
                inputs.imu.len(),
                inputs.gnss.len()
            )));
        }
        Ok(Self {
            cfg: config,
            inputs,
        })
    }

    /// Read the inputs the configuration names (relative to `base`) and
    /// make a [`Process`] of them.
    pub fn load(config: ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        let inputs = Inputs::load(&config, base)?;
        Self::new(config, inputs)
    }

    /// The configuration.
    pub fn config(&self) -> &ProcessConfig {
        &self.cfg
    }

    /// The inputs.
    pub fn inputs(&self) -> &Inputs {
        &self.inputs
    }

    /// Filter the whole log with every fix (and smooth, and monitor the
    /// instruments' convergence, as configured).
    pub fn run(&self) -> Result<ProcessResult, ProcessError> {
        let (cfg, inputs) = (&self.cfg, &self.inputs);
        let plan = RunPlan {
            smooth: cfg.output.smooth,
            monitor: cfg.filter.convergence_monitor,
            ..RunPlan::default()
        };
        let run = run_filter_rows(cfg, inputs, &plan, cfg.gnss.policy, cfg.output.interval_s)?;
        let smoothed: Vec<Epoch> = run.epochs.iter().filter_map(|e| e.smoothed()).collect();
        let epochs = run.epochs;
        Ok(ProcessResult {
            imu_samples: inputs.imu.len(),
            gnss_epochs: inputs.gnss.len(),
            policy: cfg.gnss.policy,
            outcomes: outcomes(&epochs),
            resets: reset_events(&epochs),
            tracking_rms_m: tracking_rms(&epochs),
            tracking_smoothed_rms_m: (!smoothed.is_empty()).then(|| tracking_rms(&smoothed)),
            instrument_convergence_s: if cfg.filter.convergence_monitor {
                [0.03, 0.01]
                    .into_iter()
                    .zip(convergence_times(&epochs, &[0.03, 0.01], 15.0))
                    .collect()
            } else {
                Vec::new()
            },
            k_eff_integrated_fraction: epochs.iter().filter(|e| e.k_eff > 1.0).count() as f64
                / epochs.len().max(1) as f64,
            fix_track: inputs.gnss.iter().map(|g| g.position).collect(),
            first_fix_time_s: inputs.gnss[0].time_s,
            warnings: inputs.warnings.clone(),
            between: run.between,
            smoothed,
            epochs,
        })
    }

    /// Score the log (see [`Scores`]): many filter passes with prepared
    /// inputs (withheld windows, injected outliers and bursts), in parallel.
    pub fn score(&self) -> Result<Scores, ProcessError> {
        score_log(&self.cfg, &self.inputs)
    }
}

/// Updates by outcome ("withheld" when none), in order of first appearance.
fn outcomes(epochs: &[Epoch]) -> Vec<(String, usize)> {
    let mut outcomes: Vec<(String, usize)> = Vec::new();
    for e in epochs {
        let key = e
            .outcome
            .map_or("withheld".to_string(), |o| format!("{o:?}").to_lowercase());
        match outcomes.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += 1,
            None => outcomes.push((key, 1)),
        }
    }
    outcomes
}
