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

use aidnav_estimation::{EstimationError, MeasurementPolicy, Outcome, nalgebra::U3};
use aidnav_frames::earth::Geodetic;
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_ins::increments::{Rates, trapezoid};
use aidnav_ins::ned::ImuIncrement;
use aidnav_ins::samples::{GnssFix, ImuSample};
use aidnav_ins::standstill::{StandstillThresholds, WindowStats, window_ending_at};
use aidnav_models::ned_ins::{ATTITUDE, VELOCITY};
use aidnav_supervisors::efficiency::EfficiencyCriterion;
use nalgebra::{Matrix3, Vector3};

use crate::ned::{InstrumentEstimate, NedFilter};

/// Non-holonomic constraint (no lateral or vertical body velocity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonHolonomic {
    /// Update rate \[Hz\].
    pub rate_hz: f64,
    /// σ of the lateral and vertical velocity \[m/s\].
    pub sigma_mps: f64,
    /// Applied only above this speed \[m/s\].
    pub min_speed_mps: f64,
}

/// Zero-velocity and zero-angular-rate updates while the vehicle stands
/// still: the IMU window is still ([`StandstillThresholds`]) and a GNSS
/// velocity (a fix not withheld, within the last second) is below
/// `max_speed_mps`. Without GNSS (an outage) there is no standstill update:
/// a smooth straight motion looks like rest to an IMU, and the coasting
/// filter's own speed is no evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandstillUpdates {
    /// Check (and update) rate \[Hz\].
    pub rate_hz: f64,
    /// Window of the IMU statistics \[s\].
    pub window_s: f64,
    /// Largest speed of a standstill \[m/s\].
    pub max_speed_mps: f64,
    /// IMU thresholds.
    pub thresholds: StandstillThresholds,
    /// σ of the zero-velocity update per axis \[m/s\].
    pub velocity_sigma_mps: f64,
    /// Floor of the σ of the zero-angular-rate update per axis \[rad/s\]
    /// (the window's own noise of the mean counts too).
    pub angular_rate_sigma_rad_s: f64,
}

/// What the loop does besides propagating: the GNSS updates' σ floors,
/// velocity updates, the constraint, rows between fixes, the monitor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopConfig {
    /// Floor of the fixes' position σ \[m\].
    pub min_position_sigma_m: f64,
    /// Update with the fixes' velocity when they have one.
    pub use_velocity: bool,
    /// Floor of the fixes' velocity σ \[m/s\].
    pub min_velocity_sigma_mps: f64,
    /// The non-holonomic constraint (None: off).
    pub non_holonomic: Option<NonHolonomic>,
    /// Standstill updates (None: off).
    pub standstill: Option<StandstillUpdates>,
    /// A row between fixes at the first IMU sample at or after every
    /// multiple of this interval \[s\] (0: none).
    pub row_interval_s: f64,
    /// Compute spec 10's δ(n) at every fix (the filter's monitor must be
    /// started).
    pub convergence_monitor: bool,
    /// σ_GNSS of the efficiency criterion \[m\] (None: each fix's own 3-D σ).
    pub sigma_gnss_m: Option<f64>,
}

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
    pub fn of(filter: &NedFilter, time_s: f64) -> Self {
        let (antenna, _) = filter.antenna();
        let solution = filter.solution();
        let position_covariance = filter.antenna_position_covariance();
        let s = filter.sigmas();
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
/// does nothing by default.
pub trait EpochObserver {
    /// An increment ending at `t_end_s`, before the filter propagates it.
    fn increment(&mut self, _filter: &NedFilter, _inc: &ImuIncrement, _t_end_s: f64) {}
    /// A row between fixes.
    fn row(&mut self, _row: &SolutionRow) {}
    /// A GNSS epoch is about to be processed (before its updates).
    fn before_update(&mut self, _filter: &NedFilter) {}
    /// Standstill updates were made at `time_s`.
    fn standstill(&mut self, _time_s: f64) {}
    /// A GNSS epoch, after its updates.
    fn fix(&mut self, filter: &NedFilter, record: &FixRecord);
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

/// The measurement policies of the position and the velocity updates
/// (told of every gap in their stream: [`MeasurementPolicy::missing`]).
pub struct LoopPolicies<'a> {
    /// Position updates.
    pub position: &'a mut dyn MeasurementPolicy<U3>,
    /// Velocity updates.
    pub velocity: &'a mut dyn MeasurementPolicy<U3>,
}

/// Run `filter` (initialised at `imu[start]`) over the rest of the log.
pub fn run_loop(
    filter: &mut NedFilter,
    imu: &[ImuSample],
    start: usize,
    fixes: &[AidingFix],
    cfg: &LoopConfig,
    policies: &mut LoopPolicies<'_>,
    observers: &mut [&mut dyn EpochObserver],
) -> Result<(), LoopError> {
    let t_start = imu[start].time_s;
    let mut next = fixes
        .iter()
        .position(|g| g.fix.time_s > t_start)
        .unwrap_or(fixes.len());
    let interval_s = cfg.row_interval_s;
    let mut next_row = t_start + interval_s;
    let nhc_interval = cfg.non_holonomic.map_or(f64::INFINITY, |n| 1.0 / n.rate_hz);
    let mut next_nhc = t_start + nhc_interval;
    let zupt_interval = cfg.standstill.map_or(f64::INFINITY, |z| 1.0 / z.rate_hz);
    let mut next_zupt = t_start + zupt_interval;
    // (time, speed) of the last GNSS velocity that was used.
    let mut gnss_speed: Option<(f64, f64)> = None;
    for k in start + 1..imu.len() {
        let (a, b) = (&imu[k - 1], &imu[k]);
        let at = |error| LoopError {
            time_s: b.time_s,
            error,
        };
        let mut t = a.time_s;
        let mut r0 = Rates::of(a);
        loop {
            let split = next < fixes.len() && fixes[next].fix.time_s <= b.time_s;
            let t_end = if split {
                fixes[next].fix.time_s
            } else {
                b.time_s
            };
            let r1 = Rates::interpolate(a, b, t_end);
            let dt = t_end - t;
            if dt > 0.0 {
                let inc = trapezoid(&r0, &r1, dt);
                for o in observers.iter_mut() {
                    o.increment(filter, &inc, t_end);
                }
                filter.propagate(&inc).map_err(at)?;
            }
            t = t_end;
            r0 = r1;
            if interval_s > 0.0 && t >= next_row {
                while next_row <= t {
                    next_row += interval_s;
                }
                if !split {
                    let row = SolutionRow::of(filter, t);
                    for o in observers.iter_mut() {
                        o.row(&row);
                    }
                }
            }
            if let Some(nhc) = &cfg.non_holonomic
                && t >= next_nhc
            {
                next_nhc += nhc_interval;
                if filter.state().velocity.norm() > nhc.min_speed_mps {
                    filter.update_non_holonomic(nhc.sigma_mps).map_err(at)?;
                }
            }
            if let Some(z) = &cfg.standstill
                && !split
                && t >= next_zupt
            {
                while next_zupt <= t {
                    next_zupt += zupt_interval;
                }
                if standstill_update(filter, imu, k, t, z, gnss_speed).map_err(at)? {
                    for o in observers.iter_mut() {
                        o.standstill(t);
                    }
                }
            }
            if !split {
                break;
            }
            if cfg.convergence_monitor {
                filter.begin_epoch().map_err(at)?;
            }
            for o in observers.iter_mut() {
                o.before_update(filter);
            }
            let record = fix_epoch(filter, &fixes[next], next, cfg, policies).map_err(at)?;
            if let (false, Some(v)) = (fixes[next].withheld, fixes[next].fix.velocity_ned) {
                gnss_speed = Some((fixes[next].fix.time_s, v.norm()));
            }
            for o in observers.iter_mut() {
                o.fix(filter, &record);
            }
            next += 1;
        }
    }
    Ok(())
}

/// At a check time `t` (IMU sample `k`): the standstill updates when the
/// window ending at `k` is still and the speed is low; whether they were made.
fn standstill_update(
    filter: &mut NedFilter,
    imu: &[ImuSample],
    k: usize,
    t: f64,
    z: &StandstillUpdates,
    gnss_speed: Option<(f64, f64)>,
) -> Result<bool, EstimationError> {
    // Only a GNSS velocity says "standing": the filter's own speed is no
    // evidence while it coasts (on the drive, trusting it made the burst
    // runs after 30 s outages 3.5 m instead of 0.67 m).
    let slow = matches!(gnss_speed, Some((at, speed)) if t - at <= 1.0 && speed <= z.max_speed_mps);
    if !slow {
        return Ok(false);
    }
    let Some(stats) = WindowStats::of(window_ending_at(imu, k, z.window_s)) else {
        return Ok(false);
    };
    if !stats.is_still(&z.thresholds) {
        return Ok(false);
    }
    filter.update_zero_velocity(z.velocity_sigma_mps)?;
    // σ of the window's mean rate: its spread over √n, floored.
    let n = stats.samples as f64;
    let sigma = stats
        .rate_std
        .map(|s| (s / n.sqrt()).max(z.angular_rate_sigma_rad_s));
    filter.update_zero_angular_rate(&stats.mean_rate, &sigma)?;
    Ok(true)
}

/// One GNSS epoch: the updates (or the missing fix), the record.
fn fix_epoch(
    filter: &mut NedFilter,
    g: &AidingFix,
    index: usize,
    cfg: &LoopConfig,
    policies: &mut LoopPolicies<'_>,
) -> Result<FixRecord, EstimationError> {
    let (mut nis, mut outcome, mut velocity_outcome) = (f64::NAN, None, None);
    let mut log_likelihood = f64::NAN;
    let mut innovation = Vector3::repeat(f64::NAN);
    let mut convergence = f64::NAN;
    if !g.withheld {
        let s = g.fix.position_sigma_neu;
        let sigma = Vector3::new(s.x, s.y, s.z).map(|v| v.max(cfg.min_position_sigma_m));
        let rec = filter.update_position_with(&g.fix.position, &sigma, policies.position)?;
        nis = rec.nis;
        outcome = Some(rec.outcome);
        innovation = rec.residual;
        log_likelihood = rec.log_likelihood();
        if cfg.use_velocity
            && let (Some(v), Some(sv)) = (g.fix.velocity_ned, g.fix.velocity_sigma_neu)
        {
            let sv = sv.map(|x| x.max(cfg.min_velocity_sigma_mps));
            let v = Vec3::assume_in_frame(v);
            // A position reset restarts the velocity from the same fix.
            velocity_outcome = Some(if rec.outcome == Outcome::Reset {
                filter.reset_velocity_to(&v, &sv)?;
                Outcome::Reset
            } else {
                let vrec = filter.update_velocity_with(&v, &sv, policies.velocity)?;
                log_likelihood += vrec.log_likelihood();
                vrec.outcome
            });
        } else {
            // A gap in the velocity stream.
            policies.velocity.missing();
        }
    } else {
        filter.position_fix_missing()?;
        policies.position.missing();
        policies.velocity.missing();
    }
    if cfg.convergence_monitor {
        convergence = filter.instrument_convergence().unwrap_or(f64::NAN);
    }
    let row = SolutionRow::of(filter, g.fix.time_s);
    let sigma_gnss_m = cfg.sigma_gnss_m.unwrap_or_else(|| {
        g.fix
            .position_sigma_neu
            .map(|v| v.max(cfg.min_position_sigma_m))
            .norm()
    });
    Ok(FixRecord {
        index,
        row,
        withheld: g.withheld,
        nis,
        innovation,
        outcome,
        log_likelihood,
        velocity_outcome,
        instruments: *filter.instruments(),
        convergence,
        sigma_gnss_m,
        k_eff: EfficiencyCriterion {
            sigma_gnss: sigma_gnss_m,
        }
        .coefficient(row.sigma.norm()),
        smoothed_index: filter.mark_for_smoothing(),
    })
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

    fn fix(&mut self, _filter: &NedFilter, record: &FixRecord) {
        self.fixes.push(*record);
    }
}

/// A free INS in given intervals: from each interval's start a copy of the
/// filter's INS is mechanized from the raw increments (no instrument
/// corrections, no updates) to the interval's end.
#[derive(Debug, Clone)]
pub struct FreeInsObserver {
    windows: Vec<(f64, f64)>,
    ins: Option<NedFilter>,
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
    fn increment(&mut self, filter: &NedFilter, inc: &ImuIncrement, t_end_s: f64) {
        if self.inside(t_end_s) {
            self.ins
                .get_or_insert_with(|| filter.clone())
                .coast_uncorrected(inc);
        } else {
            self.ins = None;
        }
    }

    fn fix(&mut self, _filter: &NedFilter, record: &FixRecord) {
        let t = record.row.time_s;
        let row = match &self.ins {
            Some(f) if self.inside(t) => Some((SolutionRow::of(f, t), *f.instruments())),
            _ => None,
        };
        self.rows.push(row);
    }
}
