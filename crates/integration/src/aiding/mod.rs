//! Aid sources: each owns its configuration, decides when to fuse (its
//! control step), fuses through the filter's one update
//! ([`NedFilter::fuse`]) and keeps the record of every decision it made.
//! The epoch loop ([`crate::ned_loop::run_loop`]) integrates the IMU up to
//! the next time any source asks for ([`AidSource::next_time`]) and steps
//! every source there ([`AidSource::step`]).
//!
//! A new sensor is its record (`aidnav-sensors`), its reader (`aidnav-io`),
//! its measurement model ([`crate::measurements`]), its source here and its
//! configuration section: nothing in the filter or the loop changes.

use aidnav_estimation::{EstimationError, Outcome, UpdateRecord, nalgebra::Const};
use aidnav_ins::samples::ImuSample;
use nalgebra::Vector3;

use crate::ned::NedFilter;
use crate::ned_loop::EpochObserver;

mod barometer;
mod gnss;
mod non_holonomic;
mod sampled;
mod standstill;
mod wheel_speed;

pub use barometer::{BaroConfig, BaroSource};
pub use gnss::{GnssConfig, GnssPolicies, GnssSource};
pub use non_holonomic::{GATE_FIX_AGE_S, NonHolonomic, NonHolonomicSource};
pub use sampled::{SampledSensor, SampledSource};
pub use standstill::{StandstillSource, StandstillUpdates};
pub use wheel_speed::{WheelSpeedConfig, WheelSpeedSource};

/// What one source's updates came to (`summary.json`'s
/// `result.aid_sources[]` is a list of these).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct SourceStatus {
    /// The measurement stream's name (snake_case): `non_holonomic`,
    /// `zero_velocity`, `zero_angular_rate`, `gnss_position`,
    /// `gnss_velocity`, `wheel_speed`, `barometer`.
    pub name: &'static str,
    /// Measurements the control step passed to the filter.
    pub fused: usize,
    /// Of those, accepted as they were.
    pub accepted: usize,
    /// Of those, refused (rejected by the policy: no update).
    pub rejected: usize,
    /// Of those, limited, re-weighted or given another gain by the policy.
    pub modified: usize,
    /// Of those, ending in a reset of the measured states.
    pub reset: usize,
    /// Samples the control step did not fuse (withheld, out of range, not
    /// due, the condition not met).
    pub skipped: usize,
}

impl SourceStatus {
    /// An empty status of the source `name`.
    pub const fn new(name: &'static str) -> Self {
        Self {
            name,
            fused: 0,
            accepted: 0,
            rejected: 0,
            modified: 0,
            reset: 0,
            skipped: 0,
        }
    }

    /// Count one update's outcome.
    pub fn count(&mut self, outcome: Outcome) {
        self.fused += 1;
        match outcome {
            Outcome::Accepted => self.accepted += 1,
            Outcome::Rejected | Outcome::Missing => self.rejected += 1,
            Outcome::Reset => self.reset += 1,
            Outcome::Limited | Outcome::Reweighted | Outcome::AdaptiveGain => self.modified += 1,
        }
    }
}

/// The record of one measurement update, accepted or not: innovation,
/// its σ (from S), the test ratio and the outcome. Components past
/// `dim` are NaN.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidRecord {
    /// Time of the update (GPST s).
    pub time_s: f64,
    /// The source's name.
    pub source: &'static str,
    /// The measurement's name ([`crate::measurements::Measurement::NAME`]).
    pub measurement: &'static str,
    /// Number of components.
    pub dim: usize,
    /// Innovation, predicted minus measured (first `dim` components).
    pub innovation: [f64; 3],
    /// σ of each innovation component: √S_ii.
    pub innovation_sigma: [f64; 3],
    /// Normalised innovation squared νᵀ S⁻¹ ν.
    pub nis: f64,
    /// NIS over the number of components (≈ 1 on average for a consistent
    /// filter).
    pub test_ratio: f64,
    /// What the update did.
    pub outcome: Outcome,
}

impl AidRecord {
    /// The record of an update of `M` components.
    pub fn of<const N: usize, const M: usize>(
        time_s: f64,
        source: &'static str,
        measurement: &'static str,
        rec: &UpdateRecord<Const<N>, Const<M>>,
    ) -> Self {
        let mut innovation = [f64::NAN; 3];
        let mut innovation_sigma = [f64::NAN; 3];
        for i in 0..M.min(3) {
            innovation[i] = rec.residual[i];
            innovation_sigma[i] = rec.s[(i, i)].max(0.0).sqrt();
        }
        Self {
            time_s,
            source,
            measurement,
            dim: M,
            innovation,
            innovation_sigma,
            nis: rec.nis,
            test_ratio: rec.nis / M as f64,
            outcome: rec.outcome,
        }
    }
}

/// What sources share: the evidence one source's data give another's
/// control step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Evidence {
    /// (time, NED velocity, its σ north/east/up) of the last GNSS velocity
    /// used \[s, m/s, m/s\].
    pub gnss_velocity: Option<(f64, Vector3<f64>, Option<Vector3<f64>>)>,
    /// Time of the last GNSS fix used (not withheld) \[s\].
    pub last_fix_s: Option<f64>,
}

/// What a source sees when the loop steps it.
pub struct StepContext<'a, 'o, const N: usize> {
    /// The filter, propagated to `time_s`.
    pub filter: &'a mut NedFilter<N>,
    /// Now (GPST s).
    pub time_s: f64,
    /// `time_s` is an IMU sample's time (not a time the loop split an
    /// increment at for a source).
    pub at_imu_sample: bool,
    /// The IMU log.
    pub imu: &'a [ImuSample],
    /// Index of the IMU sample that ends the increment being integrated.
    pub imu_index: usize,
    /// What sources share.
    pub evidence: &'a mut Evidence,
    /// The loop's observers.
    pub observers: &'a mut [&'o mut dyn EpochObserver],
}

impl<const N: usize> StepContext<'_, '_, N> {
    /// Report one update to the observers and count it in `status`.
    pub fn report(&mut self, status: &mut SourceStatus, record: &AidRecord) {
        status.count(record.outcome);
        for o in self.observers.iter_mut() {
            o.aided(record);
        }
    }
}

/// An aid source of the NED filter.
pub trait AidSource<const N: usize> {
    /// The source's name (snake_case).
    fn name(&self) -> &'static str;

    /// The loop starts at `t_start_s`: samples at or before it are not used.
    fn start(&mut self, _t_start_s: f64) {}

    /// Time of this source's next sample, at which the loop ends an IMU
    /// increment; None when it has no more or runs on the IMU's clock.
    fn next_time(&self) -> Option<f64> {
        None
    }

    /// Whether this source's samples are the epochs of the solution (the
    /// GNSS fixes): a row between epochs is not written at such a time.
    fn marks_epochs(&self) -> bool {
        false
    }

    /// The filter is at `ctx.time_s`: decide, and fuse what is due.
    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError>;

    /// What the source's updates came to so far (the first measurement's,
    /// for a source of two: see [`statuses`](Self::statuses)).
    fn status(&self) -> SourceStatus;

    /// The status of every measurement the source makes (one for most;
    /// GNSS position and velocity, zero velocity and zero angular rate).
    fn statuses(&self) -> Vec<SourceStatus> {
        vec![self.status()]
    }

    /// Forget every sample so far and its decisions' state (not the
    /// counts): the next due sample is the first after `time_s`.
    fn reset(&mut self, time_s: f64) {
        self.start(time_s);
    }
}

/// Index of the first sample after `t` in a time-sorted stream.
pub(crate) fn first_after<T>(samples: &[T], t: f64, time: impl Fn(&T) -> f64) -> usize {
    samples
        .iter()
        .position(|s| time(s) > t)
        .unwrap_or(samples.len())
}
