//! The extended-state experiment's scenario (TOML) and its validation.

use aidnav_estimation::EstimationError;
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range, positive};
use aidnav_models::extended_state::TransitionForm;
use aidnav_supervisors::convergence::SwitchRule;
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
    /// Prior variance of the instrument states (P_M(0) = v I8). Default 1e3.
    pub prior_instrument_variance: f64,
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
            velocity_process_noise: 0.0,
            transition: TransitionForm::Exact,
            thresholds: vec![0.03, 0.01],
            switch: SwitchRule {
                falling_s: 15.0,
                ..SwitchRule::default()
            },
            error_signs: ErrorSigns::Positive,
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
