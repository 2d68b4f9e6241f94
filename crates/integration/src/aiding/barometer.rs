//! The barometric-height source: every sample (at most one per
//! `min_interval_s`) a height update; the barometer's bias against the
//! ellipsoidal height is estimated when the filter's layout has
//! [`Augmented::BaroBias`](crate::state::Augmented::BaroBias) (without it,
//! the barometer's datum must be the ellipsoid's).

use aidnav_estimation::EstimationError;
use aidnav_sensors::BaroSample;

use super::{AidSource, SampleQueue, SourceStatus, StepContext, fuse_gated};
use crate::measurements::Barometer;

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
    queue: SampleQueue<'a, BaroSample>,
    config: BaroConfig,
    status: SourceStatus,
}

impl<'a> BaroSource<'a> {
    /// A source over time-sorted samples.
    pub fn new(samples: &'a [BaroSample], config: BaroConfig) -> Self {
        Self {
            queue: SampleQueue::new(samples, config.min_interval_s),
            config,
            status: SourceStatus::new("barometer"),
        }
    }
}

impl<const N: usize> AidSource<N> for BaroSource<'_> {
    fn name(&self) -> &'static str {
        "barometer"
    }

    fn start(&mut self, t_start_s: f64) {
        self.queue.start(t_start_s);
    }

    fn next_time(&self) -> Option<f64> {
        self.queue.next_time()
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        let due = self
            .queue
            .take_due(ctx.time_s, &mut self.status, |s| s.height_m.is_finite());
        let Some(sample) = due else {
            return Ok(());
        };
        let floor = self.config.sigma_m;
        let measurement = Barometer {
            height_m: sample.height_m,
            sigma_m: sample.sigma_m.map_or(floor, |s| s.max(floor)),
        };
        let source = ("barometer", sample.time_s);
        let gate = self.config.gate_probability;
        fuse_gated(ctx, &measurement, gate, source, &mut self.status)
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}
