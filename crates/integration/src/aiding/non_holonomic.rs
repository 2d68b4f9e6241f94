//! The non-holonomic constraint as a source on the IMU's clock: at its
//! rate, above a speed, the lateral and vertical body velocity are zero.

use aidnav_estimation::{AcceptAll, Chi2Gate, EstimationError};

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
    /// χ² gate of each update while GNSS fixes arrive (the probability of
    /// its χ²(2) quantile; None: every update accepted). A gate keeps a
    /// constraint whose frame is not the vehicle's from dragging the
    /// solution while the fixes can tell: its innovations then exceed the
    /// gate and are rejected (and counted). Without fixes (the last more
    /// than [`GATE_FIX_AGE_S`] ago) every update is accepted: the
    /// constraint is then what bounds the drift, and a filter that has
    /// drifted would gate it out just when it is needed.
    pub gate_probability: Option<f64>,
}

/// Age of the last GNSS fix beyond which the constraint's gate is open
/// \[s\]: a few fix intervals of the slowest common receivers (1 Hz).
pub const GATE_FIX_AGE_S: f64 = 3.0;

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
        let fixes_arrive =
            matches!(ctx.evidence.last_fix_s, Some(t) if ctx.time_s - t <= GATE_FIX_AGE_S);
        let rec = match self.config.gate_probability.filter(|_| fixes_arrive) {
            Some(probability) => {
                ctx.filter
                    .fuse(&constraint, None, &mut Chi2Gate { probability })?
            }
            None => ctx.filter.fuse(&constraint, None, &mut AcceptAll)?,
        };
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
