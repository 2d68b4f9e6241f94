//! [`Process`]: a recorded log as a library call. Reading the inputs is a
//! separate call ([`super::Inputs::load`]); running and scoring return
//! values and touch no file; [`super::export`] writes them.

use aidnav_sim::Cancel;
use std::path::Path;

use aidnav_frames::earth::Geodetic;
use aidnav_integration::aiding::{AidRecord, SourceStatus};

use super::config::{FixQuality, GnssLatency, PolicyName, ProcessConfig};
use super::consistency::{NisConsistency, nis_consistency};
use super::run::{
    Epoch, PendingSmoothing, ResetEvent, RunPlan, SmoothedPositions, SolutionRow, reset_events,
    run_filter_forward,
};
use super::score::{convergence_times, reference_epochs, tracking_rms};
use super::scoring::{Scores, score_log};
use super::tune::{TuneResult, tune};
use super::warnings::{Warning, WarningKind, divergence_warnings, rejection_run_warnings};
use super::{Inputs, ProcessError, StartKind, initialise};
use aidnav_integration::state::{AddedStateEstimate, Augmented};
use serde::Serialize;

/// A recorded IMU + GNSS log ready to be filtered and scored.
///
/// A tiny synthetic log: an IMU at rest (specific force −g, no rotation)
/// at 100 Hz for 12 s and a receiver at one place at 4 Hz; the attitude is
/// given, so no heading from motion is needed. The filter stays at the fix.
///
/// ```
/// use aidnav_frames::earth::Geodetic;
/// use aidnav_io::rtklib::{GnssFix, ImuSample};
/// use aidnav_app::process::{Inputs, Process, ProcessConfig};
/// use nalgebra::Vector3;
///
/// let mut cfg: ProcessConfig = toml::from_str(
///     "[data]\ndir = \".\"\nimu = \"none\"\ngnss = \"none\"\n",
/// )
/// .unwrap();
/// cfg.initial.attitude_deg = Some([0.0; 3]);
/// cfg.outage_bridge.enabled = false;
/// let place = Geodetic { latitude_rad: 0.6, longitude_rad: 0.2, height_m: 10.0 };
/// let g = aidnav_ins::ned::gravity_ned(&place).z();
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
/// let inputs = Inputs::new(imu, gnss);
/// let process = Process::new(cfg, inputs).unwrap();
/// let result = process.run().unwrap();
/// assert_eq!(result.epochs.len(), 47); // every fix after the first IMU sample
/// let rms = result.tracking_rms_m.unwrap(); // the fixes are RTK fixed (Q = 1)
/// assert!(rms < 0.05, "{rms}");
/// ```
#[derive(Debug, Clone)]
pub struct Process {
    cfg: ProcessConfig,
    inputs: Inputs,
    tuning: Option<TuneResult>,
    /// The calibration pass's install estimates (`gnss.latency =
    /// "estimate"`, `gnss.estimate_lever_arm`,
    /// `constraints.estimate_misalignment`; the configuration took them).
    calibration: Vec<AddedStateEstimate>,
    cancel: Cancel,
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
    /// Epochs whose fix is a reference (`score.reference_quality`).
    pub reference_epochs: usize,
    /// RMS 3-D antenna error over the reference epochs \[m\] (None: no
    /// reference epoch).
    pub tracking_rms_m: Option<f64>,
    /// RMS 3-D error of the RTS-smoothed antenna positions over the
    /// reference epochs (None: not smoothed; `Some(None)`: no reference).
    pub tracking_smoothed_rms_m: Option<Option<f64>>,
    /// The position NIS of the updates against χ²(3).
    pub nis: NisConsistency,
    /// Time after the first fix at which spec 10's rule declares the
    /// instruments converged, for δ_thr = 3 % and 1 % (with
    /// `filter.convergence_monitor`; None: never).
    pub instrument_convergence_s: Vec<(f64, Option<f64>)>,
    /// Fraction of the epochs at which K_eff > 1.
    pub k_eff_integrated_fraction: f64,
    /// The output the efficiency criterion selects per parameter, one per
    /// epoch (`selected.csv`; see [`super::selection`]).
    pub selected: Vec<super::selection::SelectedEpoch>,
    /// Its fractions and switches (`result.selection`).
    pub selection: super::selection::SelectionSummary,
    /// How and when the filter started.
    pub start: StartSummary,
    /// Standstill (zero-velocity + zero-angular-rate) updates made.
    pub standstill_updates: usize,
    /// Every aid source's counts, in the loop's order.
    pub aid_sources: Vec<SourceStatus>,
    /// Every update of the wheel-speed and barometer sources, in time
    /// order (`wheel_speed.csv`, `barometer.csv`).
    pub aid_updates: Vec<AidRecord>,
    /// The added states' estimates at the end of the run (GNSS latency,
    /// odometer scale, barometer bias …) with σ and prior σ.
    pub install: Vec<AddedStateEstimate>,
    /// Warnings: the readers' notes (kind `input`), divergence and long
    /// rejection runs of this run ([`super::warnings`]); other checks of
    /// the run push theirs here.
    pub warnings: Vec<Warning>,
}

/// How and when the filter started (`summary.json`'s `result.start`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StartSummary {
    /// `given`, `static` or `moving`.
    pub kind: StartKind,
    /// GPST of the start (s since 1970).
    pub time_s: f64,
    /// Seconds after the first GNSS epoch inside the IMU span.
    pub after_first_fix_s: f64,
    /// GNSS speed at the start [m/s] (null without a velocity).
    pub speed_mps: Option<f64>,
}

/// `gnss.latency = "estimate"`, `gnss.estimate_lever_arm` and
/// `constraints.estimate_misalignment`: one forward
/// pass with the install states estimates them; the configuration takes
/// each as known (the fixes re-timed by the latency), so every later pass
/// (the main run, the scores) sees the installation the log showed. The
/// estimates and their σ are the pass's at the end of the log; a state
/// whose σ is still above half its prior (the motion did not observe it)
/// keeps its configured value.
fn calibrate_install(
    config: &mut ProcessConfig,
    inputs: &mut Inputs,
) -> Result<Vec<AddedStateEstimate>, ProcessError> {
    let plan = RunPlan::default();
    let (run, _) = run_filter_forward(config, inputs, &plan, config.gnss.policy)?;
    let observed = |e: &AddedStateEstimate| e.sigma <= 0.5 * e.prior_sigma;
    let of = |kind: Augmented| move |e: &&AddedStateEstimate| e.kind == kind;
    let mut estimates = Vec::new();
    if config.gnss.latency == GnssLatency::Estimate {
        let estimate = run
            .install
            .iter()
            .find(of(Augmented::GnssLatency))
            .ok_or_else(|| {
                ProcessError::Data(
                    "gnss.latency = \"estimate\": the filter has no latency state".into(),
                )
            })?;
        if !estimate.value.is_finite() || estimate.value.abs() > 10.0 {
            return Err(ProcessError::Data(format!(
                "gnss.latency = \"estimate\": the estimate {} s is not a latency (the fixes and the IMU disagree by more than time can explain; check the time scales)",
                estimate.value
            )));
        }
        let latency = if observed(estimate) {
            estimate.value
        } else {
            0.0
        };
        super::retime_fixes(&mut inputs.gnss, latency);
        config.gnss.latency = GnssLatency::Seconds(latency);
        estimates.push(estimate.clone());
    }
    if config.gnss.estimate_lever_arm {
        let arm: Vec<_> = run.install.iter().filter(of(Augmented::LeverArm)).collect();
        if arm.len() != 3 {
            return Err(ProcessError::Data(
                "gnss.estimate_lever_arm: the filter has no lever-arm states".into(),
            ));
        }
        for (axis, e) in arm.into_iter().enumerate() {
            if !e.value.is_finite() || e.value.abs() > 100.0 {
                return Err(ProcessError::Data(format!(
                    "gnss.estimate_lever_arm: the estimate {} m of {} is not a lever arm (check gnss.lever_arm_m's axes and imu.mounting_deg)",
                    e.value, e.name
                )));
            }
            if observed(e) {
                config.gnss.lever_arm_m[axis] = e.value;
            }
            estimates.push(e.clone());
        }
        config.gnss.estimate_lever_arm = false;
    }
    if config.constraints.estimate_misalignment {
        let angles: Vec<_> = run
            .install
            .iter()
            .filter(of(Augmented::VehicleMisalignment))
            .collect();
        if angles.len() != 2 {
            return Err(ProcessError::Data(
                "constraints.estimate_misalignment: the filter has no misalignment states".into(),
            ));
        }
        // Pitch and yaw: elements 1 and 2 of misalignment_deg.
        for (axis, e) in (1..).zip(angles) {
            let deg = e.value.to_degrees();
            if !deg.is_finite() || deg.abs() > 45.0 {
                return Err(ProcessError::Data(format!(
                    "constraints.estimate_misalignment: the estimate {deg:.1}° of {} is not a misalignment (check imu.mounting_deg: the IMU axes must be the vehicle's within a few degrees)",
                    e.name
                )));
            }
            if observed(e) {
                config.constraints.misalignment_deg[axis] = deg;
            }
            estimates.push(e.clone());
        }
        config.constraints.estimate_misalignment = false;
    }
    Ok(estimates)
}

impl Process {
    /// A log to process under a configuration, the inputs ready to filter
    /// ([`Inputs::load`]: smoothed as configured); refuses inputs the
    /// filter cannot start on (fewer than two IMU samples, no GNSS fix).
    ///
    /// With `[imu.noise] auto` the noise is tuned first ([`tune`]) and the
    /// fitted values replace the configured ones ([`Process::tuning`]).
    /// The tuning needs the unsmoothed samples: with `imu.smoothing_s > 0`
    /// use [`Process::from_unsmoothed`] or [`Process::load`] (an error here).
    pub fn new(config: ProcessConfig, inputs: Inputs) -> Result<Self, ProcessError> {
        if config.imu.noise.auto && config.imu.smoothing_s > 0.0 {
            return Err(ProcessError::Data(
                "[imu.noise] auto with imu.smoothing_s > 0 needs the unsmoothed samples: use Process::from_unsmoothed or Process::load".into(),
            ));
        }
        Self::build(config, inputs, false)
    }

    /// A log to process from its inputs *before* smoothing
    /// ([`Inputs::load_unsmoothed`]): tuned first with `[imu.noise] auto`
    /// (the Allan deviation on these samples), then smoothed as configured.
    pub fn from_unsmoothed(config: ProcessConfig, inputs: Inputs) -> Result<Self, ProcessError> {
        Self::build(config, inputs, true)
    }

    /// Check, tune (with `auto`), smooth (with `smooth`).
    fn build(
        mut config: ProcessConfig,
        mut inputs: Inputs,
        smooth: bool,
    ) -> Result<Self, ProcessError> {
        if inputs.imu.len() < 2 || inputs.gnss.is_empty() {
            return Err(ProcessError::Data(format!(
                "{} IMU samples and {} GNSS fixes: need at least 2 and 1",
                inputs.imu.len(),
                inputs.gnss.len()
            )));
        }
        let tuning = if config.imu.noise.auto {
            let t = tune(&config, &inputs)?;
            t.fitted.apply_to(&mut config);
            Some(t)
        } else {
            None
        };
        let calibration = if config.gnss.latency == GnssLatency::Estimate
            || config.gnss.estimate_lever_arm
            || config.constraints.estimate_misalignment
        {
            calibrate_install(&mut config, &mut inputs)?
        } else {
            Vec::new()
        };
        let inputs = if smooth {
            // Taken, not cloned: no copy of the raw samples beside the
            // smoothed ones.
            inputs.into_smoothed(config.imu.smoothing_s)
        } else {
            inputs
        };
        Ok(Self {
            cfg: config,
            inputs,
            tuning,
            calibration,
            cancel: Cancel::default(),
        })
    }

    /// Read the inputs the configuration names (relative to `base`) and
    /// make a [`Process`] of them (tuned first with `[imu.noise] auto`).
    pub fn load(config: ProcessConfig, base: &Path) -> Result<Self, ProcessError> {
        let inputs = Inputs::load_unsmoothed(&config, base)?;
        Self::from_unsmoothed(config, inputs)
    }

    /// The tuning made with `[imu.noise] auto` (the configuration then
    /// holds the fitted noise and GNSS σ scale, `auto` still set).
    pub fn tuning(&self) -> Option<&TuneResult> {
        self.tuning.as_ref()
    }

    /// Stop [`run`](Self::run) and [`score`](Self::score) within an IMU
    /// sample of `cancel` being set: they then unwind with
    /// [`Cancelled`](aidnav_sim::Cancelled), which
    /// [`Cancel::catch`] turns into an error (as
    /// [`ProcessRun::run`](crate::jobs::ProcessRun::run) does).
    pub fn with_cancel(mut self, cancel: Cancel) -> Self {
        self.cancel = cancel;
        self
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
        let (mut result, smoothing) = self.run_forward()?;
        if let Some(smoothing) = smoothing {
            smoothing.finish(&result)?.apply_to(&mut result);
        }
        Ok(result)
    }

    /// [`run`](Self::run) in two stages: the forward pass's result — the
    /// whole result but the smoothed solution (`smoothed` empty,
    /// `tracking_smoothed_rms_m` None, the epochs' smoothed positions
    /// None) — and, when the configuration smooths, the [`Smoothing`] that
    /// completes it ([`Smoothing::finish`], then [`Smoothed::apply_to`]).
    /// In between the forward result can be read on other threads: what
    /// `aidnav process` writes the forward tables in while the log is
    /// smoothed.
    pub fn run_forward(&self) -> Result<(ProcessResult, Option<Smoothing>), ProcessError> {
        let (cfg, inputs) = (&self.cfg, &self.inputs);
        let plan = RunPlan {
            smooth: cfg.output.smooth,
            monitor: cfg.filter.convergence_monitor,
            row_interval_s: cfg.output.interval_s,
            cancel: self.cancel.clone(),
            ..RunPlan::default()
        };
        let begin = initialise(cfg, inputs)?;
        let (run, pending) = run_filter_forward(cfg, inputs, &plan, cfg.gnss.policy)?;
        let start_time_s = inputs.imu[begin.index].time_s;
        let first_fix_in_imu_span_s = inputs
            .gnss
            .iter()
            .map(|g| g.time_s)
            .find(|&t| t >= inputs.imu[0].time_s)
            .unwrap_or(start_time_s);
        let epochs = run.epochs;
        let reference = &cfg.score.reference_quality;
        let t0 = inputs.imu[0].time_s;
        let mut warnings: Vec<Warning> = inputs
            .warnings
            .iter()
            .map(|w| Warning::new(WarningKind::Input, w.clone()))
            .collect();
        warnings.extend(begin.warnings.iter().cloned());
        warnings.extend(divergence_warnings(&epochs, t0));
        warnings.extend(super::warnings::vehicle_frame_warning(
            &run.non_holonomic,
            t0,
        ));
        warnings.extend(rejection_run_warnings(&epochs, t0));
        let selected = super::selection::select_sources(cfg, &epochs);
        let result = ProcessResult {
            imu_samples: inputs.imu.len(),
            gnss_epochs: inputs.gnss.len(),
            policy: cfg.gnss.policy,
            outcomes: outcomes(&epochs),
            resets: reset_events(&epochs),
            reference_epochs: reference_epochs(&epochs, reference),
            tracking_rms_m: tracking_rms(&epochs, reference),
            tracking_smoothed_rms_m: None,
            nis: nis_consistency(&epochs),
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
            selection: super::selection::selection_summary(&selected),
            selected,
            fix_track: inputs.gnss.iter().map(|g| g.position).collect(),
            first_fix_time_s: inputs.gnss[0].time_s,
            start: StartSummary {
                kind: begin.kind,
                time_s: start_time_s,
                after_first_fix_s: start_time_s - first_fix_in_imu_span_s,
                speed_mps: begin.speed_mps.is_finite().then_some(begin.speed_mps),
            },
            standstill_updates: run.standstill_updates,
            aid_sources: run.sources,
            aid_updates: run.aid_updates,
            install: self
                .calibration
                .iter()
                .cloned()
                .chain(run.install)
                .collect(),
            warnings,
            between: run.between,
            smoothed: Vec::new(),
            epochs,
        };
        let smoothing = pending.map(|pending| Smoothing {
            pending,
            reference: reference.clone(),
        });
        Ok((result, smoothing))
    }

    /// Score the log (see [`Scores`]): many filter passes with prepared
    /// inputs (withheld windows, injected outliers and bursts), in parallel.
    pub fn score(&self) -> Result<Scores, ProcessError> {
        score_log(&self.cfg, &self.inputs, &self.cancel)
    }
}

/// The smoothing of a forward pass ([`Process::run_forward`]): the
/// filter's recording of it, waiting for the backward pass.
pub struct Smoothing {
    pending: PendingSmoothing,
    /// The fix qualities the smoothed solution is scored against.
    reference: Vec<FixQuality>,
}

impl std::fmt::Debug for Smoothing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Smoothing").finish_non_exhaustive()
    }
}

impl Smoothing {
    /// Wait until the smoother's worker thread has recorded the whole
    /// forward pass (the backward pass of [`finish`](Self::finish) then
    /// starts at once): before other threads start, so that the worker
    /// has a core to itself while it catches up.
    pub fn catch_up(&self) {
        self.pending.catch_up();
    }

    /// The backward pass, and the smoothed epochs of `forward` (the
    /// result [`Process::run_forward`] gave with this smoothing) and
    /// their score, without changing `forward`. The recording is freed
    /// before it returns.
    pub fn finish(self, forward: &ProcessResult) -> Result<Smoothed, ProcessError> {
        let positions = self.pending.finish()?;
        let epochs = positions.smoothed_epochs(&forward.epochs);
        let tracking_rms_m = (!epochs.is_empty()).then(|| tracking_rms(&epochs, &self.reference));
        Ok(Smoothed {
            positions,
            epochs,
            tracking_rms_m,
        })
    }
}

/// A finished [`Smoothing`]: what completes the forward result.
#[derive(Debug)]
pub struct Smoothed {
    positions: SmoothedPositions,
    epochs: Vec<Epoch>,
    tracking_rms_m: Option<Option<f64>>,
}

impl Smoothed {
    /// The smoothed epochs: [`ProcessResult::smoothed`] once applied.
    pub fn epochs(&self) -> &[Epoch] {
        &self.epochs
    }

    /// Complete the forward result it was made from: its smoothed epochs,
    /// their RMS error and the epochs' smoothed positions.
    pub fn apply_to(self, result: &mut ProcessResult) {
        self.positions.apply(&mut result.epochs);
        result.smoothed = self.epochs;
        result.tracking_smoothed_rms_m = self.tracking_rms_m;
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
