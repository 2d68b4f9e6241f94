//! Spec 30's full pipeline: M vehicles flying a 3-D formation, each with its
//! own INS and GNSS receiver (GNSS errors first-order Gauss–Markov plus
//! white) fused by the stage-1 loosely coupled filter
//! ([`aidnav_integration::local_level`]); inter-vehicle sensors measuring slant
//! range, bearing and elevation in the observer's body frame
//! ([`aidnav_models::relative_sensor`]), exchanged over the network; and the
//! stage-2 group filter in two forms, both from [`aidnav_integration::group`]
//! with their parameters from [`FormationScenario::fusion_params`]:
//!
//! - **paper**: the paper's axis-decoupled fusion
//!   ([`aidnav_integration::group::PaperFusion`]) — each relative measurement
//!   converted to Cartesian coordinates with the observer's INS* attitude,
//!   its per-axis variance the diagonal of the converted covariance, one
//!   constant-velocity filter per axis;
//! - **ekf**: one extended Kalman filter over all members' 3-D positions and
//!   velocities ([`aidnav_integration::group::EkfFusion`]) that uses range,
//!   bearing and elevation directly, and the full 6×6 stage-1 covariance of
//!   each member's own solution.
//!
//! This module holds the scenario and its results; `scenario` its checks and
//! flight, `simulate` stage 1 and the relative measurements, `run` the Monte
//! Carlo and the scores.
//!
//! Network (`[formation.network]`, see [`Network`]): each member sends, per
//! epoch, one packet — its stage-1 solution and its relative measurements
//! (of at most `max_neighbours` neighbours, the nearest by measured range),
//! stamped with the epoch it was made at — to the node that runs stage 2.
//! A packet is lost with `loss_probability` or arrives `latency_s` plus a
//! uniform `jitter_s` later; stage 2 runs at each epoch with what has
//! arrived, and a late packet is fused at its own epoch by rewinding to a
//! buffered snapshot and running the epochs since again
//! ([`aidnav_integration::group::DelayedFusion`]); packets older than
//! `history_s` are counted and dropped. The scored estimate at each epoch is
//! what the node knows at that time. [`sweep`] runs a grid of latencies and
//! loss rates on the same stage 1 and measurements.
//!
//! GNSS denial: the members listed in `[[formation.denial]]` lose GNSS for
//! the interval; their stage-1 INS runs free (its σ grows) while the group
//! keeps measuring them.
//!
//! Partial GNSS failure: a member listed in `[[formation.degradation]]` keeps
//! its fixes over the interval, but their errors are degraded — the receiver's
//! Gauss–Markov and white errors multiplied by `sigma_scale` (≥ 1) and a
//! constant `bias_m` (north, east, down) added to the position. With
//! `reported = false` (default) the failure is silent: the stage-1 filter
//! weighs the fixes as usual and its covariance (which stage 2 sees) does not
//! grow. With `reported = true` the receiver reports the inflation: the
//! filter's fix noise is raised so that the total σ it assumes per axis
//! (correlated plus white) is `sigma_scale` times the nominal one; the bias
//! stays unreported.
//!
//! The flight: the leader flies east at `speed_mps`, weaving left and right
//! (`weave_amplitude_m`, `weave_period_s`) and climbing and descending; the
//! others hold a V behind it (`spacing_m`, rotated with the leader's heading).
//! The flight is defined in the local tangent plane (ENU) at the origin
//! `origin_latitude_deg`, `origin_longitude_deg`; stage 2, the relative
//! sensors and the scores work in that frame.
//!
//! Stage 1's INS and error model (`ins_model`): `"ned"` (default) — the
//! paper's eq. 3 model in an Earth frame: the WGS-84 NED INS on the rotating
//! Earth with spec 40's error model (Earth and transport rates, Coriolis,
//! the gravity gradient) and the receiver's correlated errors
//! ([`aidnav_integration::ned_loosely`]); `"flat"` — a flat, non-rotating
//! Earth with constant gravity, the tangent plane as the navigation frame
//! ([`aidnav_ins::local_level`], [`aidnav_integration::local_level`]).

use aidnav_io::config::{Invalid, Validate};
use aidnav_models::local_ins::LocalInsModel;
use aidnav_models::relative_sensor::RelativeSensor;
use serde::{Deserialize, Serialize};

mod network;
mod network_sweep;
mod run;
mod scenario;
mod simulate;
mod stage_one_ned;

pub use network::{
    CellRun, Network, NetworkStats, NetworkSweep, SweepCell, sweep, sweep_finish, sweep_range,
};
pub use network_sweep::{NetworkSweepScenario, QUICK_SWEEP_RUNS};
pub use run::{RunErrors, finish, run, run_range};

/// How stage 2 treats the errors of each member's stage-1 solution
/// (`stage2_own_errors`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage2OwnErrors {
    /// Each member's whole stage-1 position–velocity error as states,
    /// carried from epoch to epoch by the transition its own stage-1
    /// filter reports (its covariance and the cross-covariance of its error
    /// with the previous epoch's, which it tracks through its Φ and gains):
    /// no second model of the receiver.
    #[default]
    Stage1Reported,
    /// The correlated part of each member's stage-1 position (and velocity)
    /// error as first-order Gauss–Markov states, with σ and τ from the
    /// receiver model (`model.gnss`); the rest of the stage-1 covariance,
    /// at least the receiver's white σ, as white noise.
    GaussMarkov,
    /// The paper's treatment: each epoch's stage-1 covariance as white noise.
    White,
}

/// How stage 2 propagates positions and velocities between epochs
/// (`stage2_motion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage2Motion {
    /// The acceleration disturbance a_R held over each step moves the
    /// position too (Q = a_R² [T⁴/4, T³/2; T³/2, T²]).
    #[default]
    PiecewiseConstantAcceleration,
    /// The paper's item 7: Q = (a_R T)² on the velocity only.
    Paper,
}

/// Names of the three solutions compared per member.
pub const SOLUTIONS: [&str; 3] = ["gnss_ins", "paper", "ekf"];

/// One GNSS denial interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Denial {
    /// Members (0-based) that lose GNSS.
    pub members: Vec<usize>,
    /// Start of the denial \[s\].
    pub start_s: f64,
    /// End of the denial \[s\].
    pub end_s: f64,
}

/// One interval of degraded (not denied) GNSS for one member.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Degradation {
    /// Member (0-based) whose fixes degrade.
    pub member: usize,
    /// Start of the degradation \[s\].
    pub start_s: f64,
    /// End of the degradation \[s\].
    pub end_s: f64,
    /// Factor (1 … 1000) on the receiver's position and velocity errors
    /// (correlated and white parts).
    pub sigma_scale: f64,
    /// Constant bias added to the position fixes, \[north, east, down\] \[m\]
    /// (each within ±100 000). Default zero.
    #[serde(default)]
    pub bias_m: [f64; 3],
    /// Whether the receiver reports the inflation (`sigma_scale`) to the
    /// stage-1 filter. Default false: a silent failure.
    #[serde(default)]
    pub reported: bool,
}

/// Stage 1's INS and error model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InsModel {
    /// WGS-84 NED INS on the rotating Earth, spec 40's error model (the
    /// paper's eq. 3).
    #[default]
    Ned,
    /// Flat, non-rotating Earth, constant gravity, the tangent plane as the
    /// navigation frame.
    Flat,
}

/// Initial INS errors (σ).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InitialErrors {
    /// Position σ per axis \[m\]. Default 3.
    pub position_sigma_m: f64,
    /// Velocity σ per axis [m/s]. Default 0.2.
    pub velocity_sigma_mps: f64,
    /// Roll and pitch σ \[rad\]. Default 1e-3.
    pub tilt_sigma_rad: f64,
    /// Heading σ \[rad\]. Default 5e-3.
    pub heading_sigma_rad: f64,
}

impl Default for InitialErrors {
    fn default() -> Self {
        Self {
            position_sigma_m: 3.0,
            velocity_sigma_mps: 0.2,
            tilt_sigma_rad: 1e-3,
            heading_sigma_rad: 5e-3,
        }
    }
}

/// The formation scenario (TOML table `[formation]`; every key optional).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FormationScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 10 000. Default 20.
    pub runs: usize,
    /// Members M, 1 … 50. Default 5.
    pub members: usize,
    /// Flight duration \[s\], at most 36 000. Default 600.
    pub duration_s: f64,
    /// IMU sample interval \[s\] (≤ 0.02). Default 0.01.
    pub imu_dt_s: f64,
    /// Stage-1 filter time-update interval \[s\]. Default 0.1.
    pub filter_dt_s: f64,
    /// GNSS fix, relative measurement and stage-2 interval \[s\]. Default 1.
    pub fix_interval_s: f64,
    /// Errors are scored from this time on \[s\]. Default 60.
    pub settle_s: f64,
    /// Leader ground speed [m/s]. Default 60.
    pub speed_mps: f64,
    /// Initial altitude \[m\]. Default 1000.
    pub altitude_m: f64,
    /// Lateral weave amplitude of the leader \[m\]. Default 800.
    pub weave_amplitude_m: f64,
    /// Weave period \[s\]. Default 240.
    pub weave_period_s: f64,
    /// Climb/descent amplitude \[m\]. Default 50.
    pub climb_amplitude_m: f64,
    /// Climb period \[s\]. Default 180.
    pub climb_period_s: f64,
    /// Distance between neighbours in the V \[m\]. Default 150.
    pub spacing_m: f64,
    /// Stage-2 acceleration disturbance a_R [m/s²]. Default 1.
    pub group_accel_sigma_m_s2: f64,
    /// Whether stage 2 also fuses each member's own INS* velocity (the
    /// paper's optional z_V). Default true. With `stage2_own_errors =
    /// "white"` set it to false: the INS* velocity is precise (σ ≈ 0.05 m/s)
    /// so it ties stage 2's position to its own integral, and stage 2 then
    /// averages the INS* positions over minutes as if their errors were
    /// white — they are not (GNSS errors correlated over
    /// `position_correlation_s`) — and becomes overconfident and lags.
    pub stage2_own_velocity: bool,
    /// How stage 2 treats the errors of each member's stage-1 solution.
    /// Default `"stage1_reported"`; `"gauss_markov"` (the receiver model's
    /// σ and τ), `"white"` (the paper's treatment).
    pub stage2_own_errors: Stage2OwnErrors,
    /// How stage 2 propagates positions and velocities: default
    /// `"piecewise_constant_acceleration"`, or `"paper"` (Q on the
    /// velocities only).
    pub stage2_motion: Stage2Motion,
    /// Stage 1's INS and error model, `"ned"` or `"flat"`. Default `"ned"`.
    pub ins_model: InsModel,
    /// Latitude of the tangent plane's origin \[deg\], within ±85 (`ned`
    /// only). Default 45.
    pub origin_latitude_deg: f64,
    /// Longitude of the origin \[deg\], within ±180 (`ned` only). Default 0.
    pub origin_longitude_deg: f64,
    /// Initial INS errors.
    pub initial: InitialErrors,
    /// IMU and GNSS errors (stage-1 model; the truth draws from the same).
    pub model: LocalInsModel,
    /// Inter-vehicle sensor.
    pub sensor: RelativeSensor,
    /// GNSS denials. Default: member 2 from 200 s to 500 s.
    pub denial: Vec<Denial>,
    /// GNSS degradations (inflated and biased fixes). Default none.
    pub degradation: Vec<Degradation>,
    /// The exchange between members as a network (`[formation.network]`:
    /// latency, loss, neighbour limit, the late-packet buffer; see
    /// [`Network`]). Default none: the ideal exchange, every packet at the
    /// epoch it is made (not written out when absent, so results of
    /// scenarios without it are unchanged).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub network: Option<Network>,
}

impl Default for FormationScenario {
    fn default() -> Self {
        Self {
            seed: 20261123,
            runs: 20,
            members: 5,
            duration_s: 600.0,
            imu_dt_s: 0.01,
            filter_dt_s: 0.1,
            fix_interval_s: 1.0,
            settle_s: 60.0,
            speed_mps: 60.0,
            altitude_m: 1000.0,
            weave_amplitude_m: 800.0,
            weave_period_s: 240.0,
            climb_amplitude_m: 50.0,
            climb_period_s: 180.0,
            spacing_m: 150.0,
            group_accel_sigma_m_s2: 1.0,
            stage2_own_velocity: true,
            stage2_own_errors: Stage2OwnErrors::Stage1Reported,
            stage2_motion: Stage2Motion::PiecewiseConstantAcceleration,
            ins_model: InsModel::Ned,
            origin_latitude_deg: 45.0,
            origin_longitude_deg: 0.0,
            initial: InitialErrors::default(),
            model: LocalInsModel::default(),
            sensor: RelativeSensor::default(),
            denial: vec![Denial {
                members: vec![2],
                start_s: 200.0,
                end_s: 500.0,
            }],
            degradation: Vec::new(),
            network: None,
        }
    }
}

/// A scenario file for `aidnav run`: the formation under a `[formation]` table.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FormationFile {
    /// The scenario.
    #[serde(default)]
    pub formation: FormationScenario,
}

impl Validate for FormationFile {
    fn validate(&self) -> Result<(), Invalid> {
        self.formation.validate().map_err(|e| e.within("formation"))
    }
}

/// Per-member result (RMS over settled epochs and runs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MemberScore {
    /// Member index.
    pub member: usize,
    /// Whether the member is denied GNSS at some time.
    pub denied: bool,
    /// 3-D position error RMS \[m\], per solution in [`SOLUTIONS`] order.
    pub position_rms_m: [f64; 3],
    /// 3-D velocity error RMS [m/s], per solution.
    pub velocity_rms_mps: [f64; 3],
    /// Filter's predicted 3-D position σ (√ trace), mean over epochs \[m\].
    pub position_sigma_m: [f64; 3],
    /// Filter's predicted 3-D velocity σ (√ trace), mean over epochs [m/s].
    pub velocity_sigma_mps: [f64; 3],
    /// Mean normalised estimation error squared of the 3-D position, per
    /// solution (3 when the filter's covariance matches its errors).
    pub position_nees: [f64; 3],
    /// Mean NEES of the 3-D velocity, per solution (ideal 3).
    pub velocity_nees: [f64; 3],
    /// During its denial: mean over runs of the largest 3-D position error \[m\].
    pub denial_max_error_m: Option<[f64; 3]>,
    /// At the end of its denial: RMS over runs of the 3-D position error \[m\].
    pub denial_end_error_m: Option<[f64; 3]>,
    /// Whether the member's GNSS is degraded at some time.
    pub degraded: bool,
    /// During its degradations: RMS over runs and epochs of the 3-D position
    /// error \[m\], per solution.
    pub degradation_rms_error_m: Option<[f64; 3]>,
}

/// The experiment's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FormationResult {
    /// Per member.
    pub members: Vec<MemberScore>,
    /// Epoch times \[s\].
    pub time_s: Vec<f64>,
    /// Per epoch, per member, per solution: RMS over runs of the 3-D position error \[m\].
    pub error_by_epoch: Vec<Vec<[f64; 3]>>,
    /// Relative measurements per epoch (mean over epochs and runs).
    pub relative_per_epoch: f64,
    /// What the network did, summed over runs (only with
    /// `[formation.network]`).
    pub network: Option<NetworkStats>,
}
