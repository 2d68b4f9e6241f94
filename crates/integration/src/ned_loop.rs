//! The epoch loop of the NED filter ([`crate::ned`]) over a recorded log:
//! IMU increments by the trapezoid rule ([`aidnav_ins::increments`]), split
//! at every GNSS epoch so each update is made at the fix's own time,
//! non-holonomic updates at their rate, solution rows between the fixes.
//!
//! The loop knows nothing about scoring: a caller that wants a fix withheld
//! or corrupted prepares the [`AidingFix`] stream so. The estimator reports,
//! observers write: every increment, every row between fixes and one
//! [`FixRecord`] per GNSS epoch go to the [`EpochObserver`]s (a collector,
//! the outage bridge of [`crate::bridge`], a free INS, …). The loop itself
//! allocates nothing per IMU sample.

use aidnav_estimation::{EstimationError, Outcome};
use aidnav_frames::earth::Geodetic;
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_ins::increments::{Rates, trapezoid};
use aidnav_ins::ned::ImuIncrement;
use aidnav_ins::samples::{GnssFix, ImuSample};
use aidnav_models::ned_ins::{ATTITUDE, VELOCITY};
use nalgebra::{Matrix3, Vector3};

use crate::aiding::{AidRecord, AidSource, Evidence, StepContext};
use crate::ned::{FilterView, FreeInertial, InstrumentEstimate, NedFilter};

pub use crate::aiding::{NonHolonomic, StandstillUpdates};

/// One GNSS epoch as the loop uses it: the fix (possibly corrupted by the
/// caller) and whether it is withheld (the filter coasts through it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AidingFix {
    /// The fix.
    pub fix: GnssFix,
    /// Withheld: no update at this epoch.
    pub withheld: bool,
}

/// The navigation solution at one time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolutionRow {
    /// GPST, seconds since 1970.
    pub time_s: f64,
    /// Antenna position.
    pub antenna: Geodetic,
    /// The IMU's position.
    pub imu: Geodetic,
    /// The IMU's NED velocity.
    pub velocity: Vec3<Ned>,
    /// Attitude, body to NED.
    pub attitude: Rotation<Body, Ned>,
    /// σ of the antenna position error (N, E, D) \[m\]: the square roots of
    /// the diagonal of `position_covariance`.
    pub sigma: Vector3<f64>,
    /// Covariance of the antenna position error (NED) \[m²\]
    /// ([`NedFilter::antenna_position_covariance`]: IMU position and the
    /// attitude error through the lever arm).
    pub position_covariance: Matrix3<f64>,
    /// σ of the velocity error (N, E, D) \[m/s\].
    pub sigma_velocity: Vector3<f64>,
    /// σ of the attitude error φ (tilt about N, E; heading about D) \[rad\].
    pub sigma_attitude: Vector3<f64>,
}

impl SolutionRow {
    /// The filter's navigation solution at `time_s`: antenna and IMU
    /// position, the IMU's velocity and attitude, the antenna position's
    /// covariance and σ, the σ of velocity and attitude.
    pub fn of(filter: &dyn FilterView, time_s: f64) -> Self {
        let (antenna, _) = filter.antenna();
        let solution = filter.solution();
        let position_covariance = filter.antenna_position_covariance();
        let s = filter.base_sigmas();
        let block = |o: usize| Vector3::new(s[o], s[o + 1], s[o + 2]);
        Self {
            time_s,
            antenna,
            imu: solution.position,
            velocity: solution.velocity,
            attitude: solution.attitude,
            sigma: position_covariance.diagonal().map(|v| v.max(0.0).sqrt()),
            position_covariance,
            sigma_velocity: block(VELOCITY),
            sigma_attitude: block(ATTITUDE),
        }
    }
}

/// What the loop reports at one GNSS epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixRecord {
    /// Index of the fix in the stream.
    pub index: usize,
    /// The solution after the epoch (updated or not), at the fix's time.
    pub row: SolutionRow,
    /// The fix was withheld.
    pub withheld: bool,
    /// Position NIS of the update (NaN when withheld).
    pub nis: f64,
    /// Position innovation, antenna estimate minus fix (NED) \[m\] (NaN when withheld).
    pub innovation: Vector3<f64>,
    /// What the update did (None: withheld).
    pub outcome: Option<Outcome>,
    /// Gaussian log-likelihood of the epoch's GNSS innovations, position
    /// and (when used) velocity, under the filter's model:
    /// Σ −½ (3 ln 2π + ln det S + νᵀ S⁻¹ ν) over the two updates (the
    /// velocity's S after the position update, so the sum is the joint
    /// likelihood of the epoch's fix). NaN when withheld.
    pub log_likelihood: f64,
    /// What the velocity update did (None: withheld, no velocity in the
    /// fix, or velocity updates off). [`Outcome::Reset`] also when the
    /// position fix reset the filter and took the velocity with it.
    pub velocity_outcome: Option<Outcome>,
    /// The instrument corrections after the epoch.
    pub instruments: InstrumentEstimate,
    /// Spec 10's δ(n) (NaN without the monitor or while singular).
    pub convergence: f64,
    /// σ_GNSS of the efficiency criterion at this epoch \[m\].
    pub sigma_gnss_m: f64,
    /// Spec 20's K_eff = σ_GNSS / σ_filter (3-D position).
    pub k_eff: f64,
    /// Index of this epoch's smoothed state in
    /// [`NedFilter::smoothed_states`] (smoothing runs).
    pub smoothed_index: Option<usize>,
}

/// Receives what the loop reports. Every method but [`EpochObserver::fix`]
/// does nothing by default; the filter is seen through a read-only
/// [`FilterView`], whatever its layout.
pub trait EpochObserver {
    /// An increment ending at `t_end_s`, before the filter propagates it.
    fn increment(&mut self, _filter: &dyn FilterView, _inc: &ImuIncrement, _t_end_s: f64) {}
    /// A row between fixes.
    fn row(&mut self, _row: &SolutionRow) {}
    /// A GNSS epoch is about to be processed (before its updates).
    fn before_update(&mut self, _filter: &dyn FilterView) {}
    /// Standstill updates were made at `time_s`.
    fn standstill(&mut self, _time_s: f64) {}
    /// An aid source made a measurement update (accepted or not).
    fn aided(&mut self, _record: &AidRecord) {}
    /// A GNSS epoch, after its updates.
    fn fix(&mut self, filter: &dyn FilterView, record: &FixRecord);
}

/// The filter failed inside the loop.
///
/// The engine's error is part of the message and deliberately not also
/// returned by `Error::source`, so a printer walking the chain shows it once.
#[derive(Debug, thiserror::Error)]
#[error("the filter failed at t = {time_s:.3} s: {error}")]
pub struct LoopError {
    /// Time of the IMU sample being processed (GPST s).
    pub time_s: f64,
    /// The engine's error.
    pub error: EstimationError,
}

/// Run `filter` (initialised at `imu[start]`) over the rest of the log,
/// aided by `sources` (stepped in this order at every time one of them
/// asks for and at every IMU sample), a [`SolutionRow`] to the observers
/// at the first IMU sample at or after every multiple of `row_interval_s`
/// (0: none) that is not a GNSS epoch.
pub fn run_loop<const N: usize>(
    filter: &mut NedFilter<N>,
    imu: &[ImuSample],
    start: usize,
    sources: &mut [&mut dyn AidSource<N>],
    row_interval_s: f64,
    observers: &mut [&mut dyn EpochObserver],
) -> Result<(), LoopError> {
    let t_start = imu[start].time_s;
    for s in sources.iter_mut() {
        s.start(t_start);
    }
    let interval_s = row_interval_s;
    let mut next_row = t_start + interval_s;
    let mut evidence = Evidence::default();
    for k in start + 1..imu.len() {
        let (a, b) = (&imu[k - 1], &imu[k]);
        let at = |error| LoopError {
            time_s: b.time_s,
            error,
        };
        let mut t = a.time_s;
        let mut r0 = Rates::of(a);
        loop {
            // The earliest time a source asks for within this increment.
            let (mut due, mut epoch) = (None::<f64>, false);
            for s in sources.iter() {
                if let Some(ts) = s.next_time().filter(|&ts| ts <= b.time_s) {
                    match due {
                        Some(d) if d < ts => {}
                        Some(d) if d == ts => epoch |= s.marks_epochs(),
                        _ => (due, epoch) = (Some(ts), s.marks_epochs()),
                    }
                }
            }
            let split = due.is_some();
            let t_end = due.unwrap_or(b.time_s);
            let r1 = Rates::interpolate(a, b, t_end);
            let dt = t_end - t;
            if dt > 0.0 {
                let inc = trapezoid(&r0, &r1, dt);
                for o in observers.iter_mut() {
                    o.increment(&*filter, &inc, t_end);
                }
                filter.propagate(&inc).map_err(at)?;
            }
            t = t_end;
            r0 = r1;
            // Rows at IMU samples; a GNSS epoch at or past the row's time
            // stands for it.
            if interval_s > 0.0 && (epoch || !split) && t >= next_row {
                while next_row <= t {
                    next_row += interval_s;
                }
                if !split {
                    let row = SolutionRow::of(&*filter, t);
                    for o in observers.iter_mut() {
                        o.row(&row);
                    }
                }
            }
            let mut ctx = StepContext {
                filter: &mut *filter,
                time_s: t,
                at_imu_sample: !split,
                imu,
                imu_index: k,
                evidence: &mut evidence,
                observers: &mut *observers,
            };
            for s in sources.iter_mut() {
                s.step(&mut ctx).map_err(at)?;
            }
            if !split {
                break;
            }
        }
    }
    Ok(())
}

/// Collects the records and the rows between fixes.
#[derive(Debug, Clone, Default)]
pub struct Collector {
    /// One per GNSS epoch.
    pub fixes: Vec<FixRecord>,
    /// Between the GNSS epochs.
    pub rows: Vec<SolutionRow>,
    /// Standstill updates made.
    pub standstill_updates: usize,
}

impl EpochObserver for Collector {
    fn row(&mut self, row: &SolutionRow) {
        self.rows.push(*row);
    }

    fn standstill(&mut self, _time_s: f64) {
        self.standstill_updates += 1;
    }

    fn fix(&mut self, _filter: &dyn FilterView, record: &FixRecord) {
        self.fixes.push(*record);
    }
}

/// A free INS in given intervals: from each interval's start a copy of the
/// filter's INS is mechanized from the raw increments (no instrument
/// corrections, no updates) to the interval's end.
#[derive(Debug, Clone)]
pub struct FreeInsObserver {
    windows: Vec<(f64, f64)>,
    ins: Option<FreeInertial>,
    /// Per GNSS epoch, in loop order: the free INS's solution and
    /// instrument corrections inside an interval (None outside).
    pub rows: Vec<Option<(SolutionRow, InstrumentEstimate)>>,
}

impl FreeInsObserver {
    /// A free INS in the intervals [start, end) (GPST s).
    pub fn new(windows: Vec<(f64, f64)>) -> Self {
        Self {
            windows,
            ins: None,
            rows: Vec::new(),
        }
    }

    fn inside(&self, t: f64) -> bool {
        self.windows.iter().any(|&(a, b)| t >= a && t < b)
    }
}

impl EpochObserver for FreeInsObserver {
    fn increment(&mut self, filter: &dyn FilterView, inc: &ImuIncrement, t_end_s: f64) {
        if self.inside(t_end_s) {
            self.ins
                .get_or_insert_with(|| filter.free_inertial())
                .coast_uncorrected(inc);
        } else {
            self.ins = None;
        }
    }

    fn fix(&mut self, _filter: &dyn FilterView, record: &FixRecord) {
        let t = record.row.time_s;
        let row = match &self.ins {
            Some(f) if self.inside(t) => Some((SolutionRow::of(f, t), *f.instruments())),
            _ => None,
        };
        self.rows.push(row);
    }
}
