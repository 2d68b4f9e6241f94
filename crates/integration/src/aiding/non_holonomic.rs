//! The non-holonomic constraint as a source on the IMU's clock: at its
//! rate, above a speed, the lateral and vertical body velocity are zero.

use aidnav_estimation::{AcceptAll, EstimationError};

use super::{AidRecord, AidSource, SourceStatus, StepContext};
use crate::measurements::{Measurement, NonHolonomicConstraint};

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

/// The constraint's source.
#[derive(Debug, Clone)]
pub struct NonHolonomicSource {
    config: NonHolonomic,
    interval_s: f64,
    next_s: f64,
    status: SourceStatus,
}

impl NonHolonomicSource {
    /// A source at the configured rate.
    pub fn new(config: NonHolonomic) -> Self {
        Self {
            config,
            interval_s: 1.0 / config.rate_hz,
            next_s: f64::INFINITY,
            status: SourceStatus::new("non_holonomic"),
        }
    }
}

impl<const N: usize> AidSource<N> for NonHolonomicSource {
    fn name(&self) -> &'static str {
        "non_holonomic"
    }

    fn start(&mut self, t_start_s: f64) {
        self.next_s = t_start_s + self.interval_s;
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        if ctx.time_s < self.next_s {
            return Ok(());
        }
        self.next_s += self.interval_s;
        if ctx.filter.state().velocity.norm() <= self.config.min_speed_mps {
            self.status.skipped += 1;
            return Ok(());
        }
        let constraint = NonHolonomicConstraint {
            sigma_mps: self.config.sigma_mps,
        };
        let rec = ctx.filter.fuse(&constraint, None, &mut AcceptAll)?;
        let record = AidRecord::of(
            ctx.time_s,
            "non_holonomic",
            <NonHolonomicConstraint as Measurement<2, N>>::NAME,
            &rec,
        );
        ctx.report(&mut self.status, &record);
        Ok(())
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}
