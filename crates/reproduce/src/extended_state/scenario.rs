//! The extended-state experiment's scenario (TOML) and its validation.

use aidnav_estimation::EstimationError;
use aidnav_ins::launch::LaunchInstrumentErrors;
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range, positive};
use aidnav_models::extended_state::TransitionForm;
use aidnav_supervisors::convergence::SwitchRule;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use aidnav_sim::trajectory::{LaunchProgram, LaunchTarget, TABLE1, TrajectoryError};

/// Signs of the true instrument errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorSigns {
    /// Every component positive (Table 2 as printed).
    Positive,
    /// Each component's sign drawn per run.
    Random,
}

/// The magnitudes of the true instrument errors, the same for each axis
/// (Table 2 by default); `error_signs` gives their signs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ErrorMagnitudes {
    /// Accelerometer bias Δa0 [m/s²], 0 … 10. Default 5.01e-2.
    pub accel_bias_mps2: f64,
    /// Accelerometer scale-factor error K_a, 0 … 0.5. Default 2.46e-2.
    pub accel_scale: f64,
    /// Attitude-angle offset Δb0 \[rad\], 0 … 0.5. Default 5.25e-2.
    pub angle_offset_rad: f64,
    /// Attitude-angle drift ω_b [rad/s], 0 … 0.01. Default 2.33e-4.
    pub angle_drift_radps: f64,
}

impl Default for ErrorMagnitudes {
    fn default() -> Self {
        let t = LaunchInstrumentErrors::table2(1.0);
        Self {
            accel_bias_mps2: t.accel_bias.x,
            accel_scale: t.accel_scale.x,
            angle_offset_rad: t.angle_offset.x,
            angle_drift_radps: t.angle_drift.x,
        }
    }
}

impl ErrorMagnitudes {
    /// The twelve errors with these magnitudes and a sign per component
    /// (order of [`LaunchInstrumentErrors::table2_signed`]).
    pub fn errors(&self, signs: &[f64; 12]) -> LaunchInstrumentErrors {
        let v = |i: usize, value: f64| {
            Vector3::new(signs[i] * value, signs[i + 1] * value, signs[i + 2] * value)
        };
        LaunchInstrumentErrors {
            accel_bias: v(0, self.accel_bias_mps2),
            accel_scale: v(3, self.accel_scale),
            angle_offset: v(6, self.angle_offset_rad),
            angle_drift: v(9, self.angle_drift_radps),
        }
    }

    fn validate(&self) -> Result<(), Invalid> {
        in_range("accel_bias_mps2", self.accel_bias_mps2, 0.0, 10.0)?;
        in_range("accel_scale", self.accel_scale, 0.0, 0.5)?;
        in_range("angle_offset_rad", self.angle_offset_rad, 0.0, 0.5)?;
        in_range("angle_drift_radps", self.angle_drift_radps, 0.0, 0.01)
    }
}

/// Scenario (TOML; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ExtendedStateScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs per trajectory, 1 … 100 000. Default 100.
    pub runs: usize,
    /// INS and truth step \[s\] (≤ 0.01 s: 100 Hz or faster). Default 0.01.
    pub imu_dt_s: f64,
    /// Interval between fixes Δt \[s\] (a whole number of steps). Default 0.15.
    pub fix_interval_s: f64,
    /// Flight time of the first fix \[s\]. Default 20.
    pub fusion_start_s: f64,
    /// σ of the fixes' position noise \[m\] (R = σ² I). Default 10.
    pub position_sigma_m: f64,
    /// σ of the fixes' velocity noise [m/s]. Default 10.
    pub velocity_sigma_mps: f64,
    /// Scale of the simulated fix noise (0: exact fixes; the filter still
    /// assumes R from the two σ above). Default 1.
    pub fix_noise_scale: f64,
    /// Prior variance of the navigation states (P_H(0) = v I6). Default 1e3.
    pub prior_navigation_variance: f64,
    /// Prior variance of the instrument states (P_M(0) = v I8) when
    /// `prior_instrument_sigmas` is empty. Default 1e3 (the paper's, in SI
    /// units: σ 32 m/s², 32 rad, 32 rad/s).
    pub prior_instrument_variance: f64,
    /// Prior σ of each instrument state in the filter's order (Δẍ10, Δÿ10,
    /// Δz̈10 [m/s²], K_ẍ1, Δψ0, Δϑ0 \[rad\], ω_ψ, ω_ϑ [rad/s]): empty, or
    /// eight values 1e-9 … 1e6. Default empty.
    pub prior_instrument_sigmas: Vec<f64>,
    /// Process noise on each velocity per fix interval [(m/s)²]. The paper
    /// gives none; with 0 the filter's covariance equals the Cramér–Rao
    /// bound and δ(n) is exactly the relative reduction of tr P_M by one
    /// fix. Any Q > 0 keeps P_M above the bound, so δ(n) turns up again late
    /// in the flight (1e-4: δ never falls below 1 % on t_B = 300 s).
    /// Default 0.
    pub velocity_process_noise: f64,
    /// Φ from A: `first_order` (the paper's I + AΔt, A at the interval
    /// start) or `exact` (I + AΔ + A²Δ²/2 per INS step). Default `exact`.
    pub transition: TransitionForm,
    /// Thresholds δ_thr. Default [0.03, 0.01].
    pub thresholds: Vec<f64>,
    /// Arming of the switch (its `threshold` is replaced by each of
    /// `thresholds`). Default: δ non-increasing for 15 s, then δ ≤ δ_thr
    /// for 5 epochs. The 15 s were chosen after looking at δ(n) of the
    /// t_B = 300 s, φ = 0 flight: its early humps fall for 4 s and 11 s
    /// before the next instrument errors become observable.
    pub switch: SwitchRule,
    /// Signs of the true instrument errors. Default `positive`.
    pub error_signs: ErrorSigns,
    /// Magnitudes of the true instrument errors. Default: Table 2.
    pub error_magnitudes: ErrorMagnitudes,
    /// Also run the paper's rule taken literally: switch at the first fix
    /// with δ(n) ≤ δ_thr, no arming (rows `delta_literal`). Default true.
    pub literal_rule: bool,
    /// The forecast rule (rows `forecast`), one row per value: switch at the
    /// first fix at which the predicted variance of the position error at
    /// t_B (the current P carried to t_B by the exact Φ, all states in one
    /// unit, m²) falls by less than this fraction per second of fusion.
    /// The paper's δ_thr = 3 % and 1 % per 0.15 s fix are 0.2 and 0.0667
    /// per second; measured, any such fraction is a choice of time (the
    /// reduction falls like k/τ and rises again as t → t_B: on t_B = 300 s
    /// it is 15 %/s at 65 s of fusion and never below 7 %/s), so by default
    /// there are no such rows. 0 … 10 values, each 1e-9 … 100. Default empty.
    pub forecast_reduction_per_s: Vec<f64>,
    /// The share rule (rows `forecast_share`), one row per value: switch
    /// once the instrument states' share of the forecast t_B position-error
    /// variance (P_M's part over P_M's plus P_H's) has fallen to this value
    /// for `switch.confirm_epochs` fixes. Default [0.5]: the instruments'
    /// remaining uncertainty adds no more to the t_B error than the
    /// navigation errors handed to the autonomous INS, so even perfect
    /// instrument estimates could improve the forecast σ by at most √2.
    /// 0 … 10 values, each in (0, 1).
    pub forecast_instrument_share: Vec<f64>,
    /// Runs (the first ones, at most `runs`) in which the Gauss–Newton batch
    /// estimate is also computed at every switch but the first fix (0:
    /// none), 0 … 100 000. Default 5 (it re-flies the fusion interval a few
    /// times per switch: the experiment's cost grows by about 0.1 s of CPU
    /// per run and trajectory).
    pub gauss_newton_runs: usize,
    /// Most Gauss–Newton iterations, 1 … 50. Default 8.
    pub gauss_newton_iterations: usize,
    /// Shape of the guidance program.
    pub program: LaunchProgram,
    /// Target points. Default: Table 1.
    pub targets: Vec<LaunchTarget>,
    /// Index into `targets` of the trajectory drawn in the figures. Default 4
    /// (t_B = 400 s, φ = 30°).
    pub figure_target: usize,
    /// Forced switch times for the sweep figure: every this many seconds of
    /// fusion, fix_interval_s … 3600 (a switch between two fixes is the
    /// same switch). Default 10.
    pub sweep_step_s: f64,
    /// Runs of the sweep. Default 20.
    pub sweep_runs: usize,
}

impl Default for ExtendedStateScenario {
    fn default() -> Self {
        Self {
            seed: 20261123,
            runs: 100,
            imu_dt_s: 0.01,
            fix_interval_s: 0.15,
            fusion_start_s: 20.0,
            position_sigma_m: 10.0,
            velocity_sigma_mps: 10.0,
            fix_noise_scale: 1.0,
            prior_navigation_variance: 1e3,
            prior_instrument_variance: 1e3,
            prior_instrument_sigmas: Vec::new(),
            velocity_process_noise: 0.0,
            transition: TransitionForm::Exact,
            thresholds: vec![0.03, 0.01],
            switch: SwitchRule {
                falling_s: 15.0,
                ..SwitchRule::default()
            },
            error_signs: ErrorSigns::Positive,
            error_magnitudes: ErrorMagnitudes::default(),
            literal_rule: true,
            forecast_reduction_per_s: Vec::new(),
            forecast_instrument_share: vec![0.5],
            gauss_newton_runs: 5,
            gauss_newton_iterations: 8,
            program: LaunchProgram::default(),
            targets: TABLE1.to_vec(),
            figure_target: 4,
            sweep_step_s: 10.0,
            sweep_runs: 20,
        }
    }
}

impl ExtendedStateScenario {
    /// Memory the forced-switch sweep holds at most \[bytes\]: per forced
    /// switch time (every `sweep_step_s` up to the latest t_B), its time, the
    /// filter state saved there in a run and every sweep run's error ratio.
    pub fn sweep_memory_bytes(&self) -> f64 {
        let t_b = self.targets.iter().map(|t| t.t_b_s).fold(0.0, f64::max);
        let points = ((t_b - self.fusion_start_s).max(0.0) / self.sweep_step_s).ceil();
        let snapshot = std::mem::size_of::<Option<super::Snapshot>>() as f64;
        points * (8.0 * (self.sweep_runs as f64 + 1.0) + snapshot)
    }
}

impl Validate for ExtendedStateScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 100_000)?;
        count_in_range("sweep_runs", self.sweep_runs, 1, 100_000)?;
        in_range("imu_dt_s", self.imu_dt_s, 1e-4, 0.01)?;
        in_range("fix_interval_s", self.fix_interval_s, self.imu_dt_s, 10.0)?;
        let ratio = self.fix_interval_s / self.imu_dt_s;
        if (ratio - ratio.round()).abs() > 1e-6 {
            return Err(Invalid::new(
                "fix_interval_s",
                self.fix_interval_s,
                "a whole number of imu_dt_s",
            ));
        }
        in_range("fusion_start_s", self.fusion_start_s, 0.0, 3600.0)?;
        crate::within(
            "position_sigma_m",
            self.position_sigma_m,
            crate::SIGMA_RANGE,
        )?;
        crate::within(
            "velocity_sigma_mps",
            self.velocity_sigma_mps,
            crate::SIGMA_MPS_RANGE,
        )?;
        in_range("fix_noise_scale", self.fix_noise_scale, 0.0, 100.0)?;
        in_range(
            "prior_navigation_variance",
            self.prior_navigation_variance,
            1e-12,
            1e12,
        )?;
        in_range(
            "prior_instrument_variance",
            self.prior_instrument_variance,
            1e-12,
            1e12,
        )?;
        if !matches!(self.prior_instrument_sigmas.len(), 0 | 8) {
            return Err(Invalid::new(
                "prior_instrument_sigmas",
                self.prior_instrument_sigmas.len(),
                "empty or 8 values",
            ));
        }
        for s in &self.prior_instrument_sigmas {
            in_range("prior_instrument_sigmas", *s, 1e-9, 1e6)?;
        }
        self.error_magnitudes
            .validate()
            .map_err(|e| e.within("error_magnitudes"))?;
        if self.forecast_reduction_per_s.len() > 10 {
            return Err(Invalid::new(
                "forecast_reduction_per_s",
                self.forecast_reduction_per_s.len(),
                "0 … 10 values",
            ));
        }
        for f in &self.forecast_reduction_per_s {
            in_range("forecast_reduction_per_s", *f, 1e-9, 100.0)?;
        }
        if self.forecast_instrument_share.len() > 10 {
            return Err(Invalid::new(
                "forecast_instrument_share",
                self.forecast_instrument_share.len(),
                "0 … 10 values",
            ));
        }
        for f in &self.forecast_instrument_share {
            in_range("forecast_instrument_share", *f, 1e-9, 1.0 - 1e-9)?;
        }
        count_in_range("gauss_newton_runs", self.gauss_newton_runs, 0, 100_000)?;
        count_in_range(
            "gauss_newton_iterations",
            self.gauss_newton_iterations,
            1,
            50,
        )?;
        in_range(
            "velocity_process_noise",
            self.velocity_process_noise,
            0.0,
            1e6,
        )?;
        positive("sweep_step_s", self.sweep_step_s)?;
        crate::within_memory(
            "sweep_step_s",
            self.sweep_step_s,
            self.sweep_memory_bytes(),
            "the forced-switch sweep",
            "fix_interval_s ≤ sweep_step_s ≤ 3600",
        )?;
        in_range(
            "sweep_step_s",
            self.sweep_step_s,
            self.fix_interval_s,
            3600.0,
        )?;
        if self.thresholds.is_empty() || self.thresholds.len() > 10 {
            return Err(Invalid::new(
                "thresholds",
                self.thresholds.len(),
                "1 … 10 thresholds",
            ));
        }
        for t in &self.thresholds {
            in_range("thresholds", *t, 1e-9, 1.0)?;
        }
        in_range("arm_after_s", self.switch.arm_after_s, 0.0, 3600.0)
            .map_err(|e| e.within("switch"))?;
        in_range("falling_s", self.switch.falling_s, 0.0, 3600.0)
            .map_err(|e| e.within("switch"))?;
        count_in_range("confirm_epochs", self.switch.confirm_epochs, 1, 100_000)
            .map_err(|e| e.within("switch"))?;
        count_in_range("targets", self.targets.len(), 1, 100)?;
        for (i, t) in self.targets.iter().enumerate() {
            if !(t.t_b_s > self.fusion_start_s + 10.0 && t.t_b_s <= 3600.0) {
                return Err(Invalid::new(
                    format!("targets[{i}].t_b_s"),
                    t.t_b_s,
                    "fusion_start_s + 10 < t_b_s ≤ 3600",
                ));
            }
        }
        count_in_range(
            "figure_target",
            self.figure_target,
            0,
            self.targets.len() - 1,
        )?;
        Ok(())
    }
}

/// Anything the experiment can fail with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExtendedStateError {
    /// A target could not be reached by the guidance program.
    #[error("target t_B = {t_b_s} s, course {course_deg}°: {reason}")]
    Trajectory {
        /// t_B of the target.
        t_b_s: f64,
        /// Course.
        course_deg: f64,
        /// Why (part of the message, so not also the `Error::source`).
        reason: TrajectoryError,
    },
    /// The filter.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}
