//! The GNSS source: a position update at every fix not withheld, then a
//! velocity update when the fix has a velocity (or the velocity reset when
//! the position fix reset the filter), one [`FixRecord`] per fix epoch.

use aidnav_estimation::{EstimationError, MeasurementPolicy, Outcome, nalgebra::U3};
use aidnav_frames::Vec3;
use aidnav_supervisors::efficiency::EfficiencyCriterion;
use nalgebra::Vector3;

use super::{AidRecord, AidSource, SourceStatus, StepContext, first_after};
use crate::measurements::{GnssPosition, GnssVelocity, Measurement};
use crate::ned::{GnssStream, NedFilter};
use crate::ned_loop::{AidingFix, FixRecord, SolutionRow};

/// How the GNSS source uses the fixes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssConfig {
    /// Floor of the fixes' position σ \[m\].
    pub min_position_sigma_m: f64,
    /// Update with the fixes' velocity when they have one.
    pub use_velocity: bool,
    /// Floor of the fixes' velocity σ \[m/s\].
    pub min_velocity_sigma_mps: f64,
    /// Compute spec 10's δ(n) at every fix (the filter's monitor must be
    /// started).
    pub convergence_monitor: bool,
    /// σ_GNSS of the efficiency criterion \[m\] (None: each fix's own 3-D σ).
    pub sigma_gnss_m: Option<f64>,
}

/// The measurement policies of the position and the velocity updates
/// (told of every gap in their stream: [`MeasurementPolicy::missing`]).
pub struct GnssPolicies<'a> {
    /// Position updates.
    pub position: &'a mut dyn MeasurementPolicy<U3>,
    /// Velocity updates.
    pub velocity: &'a mut dyn MeasurementPolicy<U3>,
}

/// The GNSS fixes as an aid source.
pub struct GnssSource<'a> {
    fixes: &'a [AidingFix],
    config: GnssConfig,
    policies: GnssPolicies<'a>,
    next: usize,
    status: SourceStatus,
    velocity_status: SourceStatus,
}

impl<'a> GnssSource<'a> {
    /// A source over time-sorted fixes (prepared by the caller: withheld or
    /// corrupted as a score wants).
    pub fn new(fixes: &'a [AidingFix], config: GnssConfig, policies: GnssPolicies<'a>) -> Self {
        Self {
            fixes,
            config,
            policies,
            next: 0,
            status: SourceStatus::new("gnss_position"),
            velocity_status: SourceStatus::new("gnss_velocity"),
        }
    }

    /// What the velocity updates came to (the position's is
    /// [`AidSource::status`]).
    pub fn velocity_status(&self) -> SourceStatus {
        self.velocity_status
    }

    /// One GNSS epoch: the updates (or the missing fix), the record.
    fn epoch<const N: usize>(
        &mut self,
        ctx: &mut StepContext<'_, '_, N>,
        index: usize,
    ) -> Result<FixRecord, EstimationError> {
        let g = self.fixes[index];
        let cfg = self.config;
        let filter: &mut NedFilter<N> = ctx.filter;
        let (mut nis, mut outcome, mut velocity_outcome) = (f64::NAN, None, None);
        let mut log_likelihood = f64::NAN;
        let mut innovation = Vector3::repeat(f64::NAN);
        let mut convergence = f64::NAN;
        let mut records = [None, None];
        if !g.withheld {
            let s = g.fix.position_sigma_neu;
            let sigma = Vector3::new(s.x, s.y, s.z).map(|v| v.max(cfg.min_position_sigma_m));
            let position = GnssPosition {
                fix: g.fix.position,
                sigma_ned_m: sigma,
            };
            let rec = filter.fuse(
                &position,
                Some(GnssStream::Position),
                self.policies.position,
            )?;
            records[0] = Some(AidRecord::of(
                g.fix.time_s,
                "gnss",
                <GnssPosition as Measurement<3, N>>::NAME,
                &rec,
            ));
            nis = rec.nis;
            outcome = Some(rec.outcome);
            innovation = rec.residual;
            log_likelihood = rec.log_likelihood();
            if cfg.use_velocity
                && let (Some(v), Some(sv)) = (g.fix.velocity_ned, g.fix.velocity_sigma_neu)
            {
                let velocity = GnssVelocity {
                    velocity_ned_mps: Vec3::assume_in_frame(v),
                    sigma_ned_mps: sv.map(|x| x.max(cfg.min_velocity_sigma_mps)),
                };
                // A position reset restarts the velocity from the same fix.
                velocity_outcome = Some(if rec.outcome == Outcome::Reset {
                    filter.reset_to(&velocity, GnssStream::Velocity)?;
                    self.velocity_status.count(Outcome::Reset);
                    Outcome::Reset
                } else {
                    let vrec = filter.fuse(
                        &velocity,
                        Some(GnssStream::Velocity),
                        self.policies.velocity,
                    )?;
                    log_likelihood += vrec.log_likelihood();
                    records[1] = Some(AidRecord::of(
                        g.fix.time_s,
                        "gnss",
                        <GnssVelocity as Measurement<3, N>>::NAME,
                        &vrec,
                    ));
                    vrec.outcome
                });
            } else {
                // A gap in the velocity stream.
                self.policies.velocity.missing();
            }
        } else {
            filter.position_fix_missing()?;
            self.policies.position.missing();
            self.policies.velocity.missing();
            self.status.skipped += 1;
        }
        if cfg.convergence_monitor {
            convergence = filter.instrument_convergence().unwrap_or(f64::NAN);
        }
        let row = SolutionRow::of(&*filter, g.fix.time_s);
        let sigma_gnss_m = cfg.sigma_gnss_m.unwrap_or_else(|| {
            g.fix
                .position_sigma_neu
                .map(|v| v.max(cfg.min_position_sigma_m))
                .norm()
        });
        let record = FixRecord {
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
        };
        if let Some(r) = records[0] {
            ctx.report(&mut self.status, &r);
        }
        if let Some(r) = records[1] {
            ctx.report(&mut self.velocity_status, &r);
        }
        Ok(record)
    }
}

impl<const N: usize> AidSource<N> for GnssSource<'_> {
    fn name(&self) -> &'static str {
        "gnss"
    }

    fn start(&mut self, t_start_s: f64) {
        self.next = first_after(self.fixes, t_start_s, |g| g.fix.time_s);
    }

    fn next_time(&self) -> Option<f64> {
        self.fixes.get(self.next).map(|g| g.fix.time_s)
    }

    fn marks_epochs(&self) -> bool {
        true
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        // One fix per step: a second one at the same time comes at the
        // loop's next (zero-length) split.
        if !matches!(AidSource::<N>::next_time(self), Some(t) if t <= ctx.time_s) {
            return Ok(());
        }
        let index = self.next;
        if self.config.convergence_monitor {
            ctx.filter.begin_epoch()?;
        }
        for o in ctx.observers.iter_mut() {
            o.before_update(&*ctx.filter);
        }
        let record = self.epoch(ctx, index)?;
        let g = &self.fixes[index];
        if !g.withheld {
            ctx.evidence.last_fix_s = Some(g.fix.time_s);
        }
        if let (false, Some(v)) = (g.withheld, g.fix.velocity_ned) {
            ctx.evidence.gnss_velocity = Some((g.fix.time_s, v, g.fix.velocity_sigma_neu));
        }
        for o in ctx.observers.iter_mut() {
            o.fix(&*ctx.filter, &record);
        }
        self.next += 1;
        Ok(())
    }

    fn status(&self) -> SourceStatus {
        self.status
    }

    fn statuses(&self) -> Vec<SourceStatus> {
        vec![self.status, self.velocity_status]
    }
}
