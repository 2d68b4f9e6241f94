//! The wheel-speed (odometer) source: every sample (at most one per
//! `min_interval_s`) a forward-speed update at the wheel's lever arm; the
//! odometer's scale-factor error is estimated when the filter's layout has
//! [`Augmented::WheelSpeedScale`](crate::state::Augmented::WheelSpeedScale).

use aidnav_estimation::EstimationError;
use aidnav_frames::{Body, Vec3};
use aidnav_sensors::WheelSpeedSample;

use super::{AidSource, SampleQueue, SourceStatus, StepContext, fuse_gated};
use crate::measurements::WheelSpeed;

/// How the wheel-speed source uses the samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelSpeedConfig {
    /// σ of a sample without its own \[m/s\]; also the floor of a given σ.
    pub sigma_mps: f64,
    /// Lever arm from the IMU to the wheel's contact point (body frame) \[m\].
    pub lever_arm_m: Vec3<Body>,
    /// χ² gate probability (None: every sample accepted).
    pub gate_probability: Option<f64>,
    /// Fuse at most one sample per this interval \[s\] (0: every sample).
    pub min_interval_s: f64,
}

/// Wheel-speed samples as an aid source.
#[derive(Debug, Clone)]
pub struct WheelSpeedSource<'a> {
    queue: SampleQueue<'a, WheelSpeedSample>,
    config: WheelSpeedConfig,
    status: SourceStatus,
}

impl<'a> WheelSpeedSource<'a> {
    /// A source over time-sorted samples.
    pub fn new(samples: &'a [WheelSpeedSample], config: WheelSpeedConfig) -> Self {
        Self {
            queue: SampleQueue::new(samples, config.min_interval_s),
            config,
            status: SourceStatus::new("wheel_speed"),
        }
    }
}

impl<const N: usize> AidSource<N> for WheelSpeedSource<'_> {
    fn name(&self) -> &'static str {
        "wheel_speed"
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
            .take_due(ctx.time_s, &mut self.status, |s| s.speed_mps.is_finite());
        let Some(sample) = due else {
            return Ok(());
        };
        let floor = self.config.sigma_mps;
        let measurement = WheelSpeed {
            speed_mps: sample.speed_mps,
            sigma_mps: sample.sigma_mps.map_or(floor, |s| s.max(floor)),
            lever_arm_m: self.config.lever_arm_m,
        };
        let source = ("wheel_speed", sample.time_s);
        let gate = self.config.gate_probability;
        fuse_gated(ctx, &measurement, gate, source, &mut self.status)
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}
