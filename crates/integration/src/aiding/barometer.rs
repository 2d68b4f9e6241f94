//! The barometric-height source: every sample (at most one per
//! `min_interval_s`) a height update; the barometer's bias against the
//! ellipsoidal height is estimated when the filter's layout has
//! [`Augmented::BaroBias`](crate::state::Augmented::BaroBias) (without it,
//! the barometer's datum must be the ellipsoid's).

use aidnav_estimation::{AcceptAll, Chi2Gate, EstimationError};
use aidnav_sensors::BaroSample;

use super::{AidRecord, AidSource, SourceStatus, StepContext, first_after};
use crate::measurements::{Barometer, Measurement};

/// How the barometer source uses the samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaroConfig {
    /// σ of a sample without its own \[m\]; also the floor of a given σ.
    pub sigma_m: f64,
    /// χ² gate probability (None: every sample accepted).
    pub gate_probability: Option<f64>,
    /// Fuse at most one sample per this interval \[s\] (0: every sample).
    pub min_interval_s: f64,
}

/// Barometric heights as an aid source.
#[derive(Debug, Clone)]
pub struct BaroSource<'a> {
    samples: &'a [BaroSample],
    config: BaroConfig,
    next: usize,
    last_fused_s: f64,
    status: SourceStatus,
}

impl<'a> BaroSource<'a> {
    /// A source over time-sorted samples.
    pub fn new(samples: &'a [BaroSample], config: BaroConfig) -> Self {
        Self {
            samples,
            config,
            next: 0,
            last_fused_s: f64::NEG_INFINITY,
            status: SourceStatus::new("barometer"),
        }
    }
}

impl<const N: usize> AidSource<N> for BaroSource<'_> {
    fn name(&self) -> &'static str {
        "barometer"
    }

    fn start(&mut self, t_start_s: f64) {
        self.next = first_after(self.samples, t_start_s, |s| s.time_s);
        self.last_fused_s = f64::NEG_INFINITY;
    }

    fn next_time(&self) -> Option<f64> {
        self.samples.get(self.next).map(|s| s.time_s)
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        let Some(sample) = self
            .samples
            .get(self.next)
            .filter(|s| s.time_s <= ctx.time_s)
        else {
            return Ok(());
        };
        self.next += 1;
        if sample.time_s - self.last_fused_s < self.config.min_interval_s
            || !sample.height_m.is_finite()
        {
            self.status.skipped += 1;
            return Ok(());
        }
        self.last_fused_s = sample.time_s;
        let measurement = Barometer {
            height_m: sample.height_m,
            sigma_m: sample
                .sigma_m
                .map_or(self.config.sigma_m, |s| s.max(self.config.sigma_m)),
        };
        let rec = match self.config.gate_probability {
            Some(probability) => {
                ctx.filter
                    .fuse(&measurement, None, &mut Chi2Gate { probability })?
            }
            None => ctx.filter.fuse(&measurement, None, &mut AcceptAll)?,
        };
        let record = AidRecord::of(
            sample.time_s,
            "barometer",
            <Barometer as Measurement<1, N>>::NAME,
            &rec,
        );
        ctx.report(&mut self.status, &record);
        Ok(())
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}
