//! The wheel-speed (odometer) source: every sample (at most one per
//! `min_interval_s`) a forward-speed update at the wheel's lever arm; the
//! odometer's scale-factor error is estimated when the filter's layout has
//! [`Augmented::WheelSpeedScale`](crate::state::Augmented::WheelSpeedScale).

use aidnav_estimation::{AcceptAll, Chi2Gate, EstimationError};
use aidnav_frames::{Body, Vec3};
use aidnav_sensors::WheelSpeedSample;

use super::{AidRecord, AidSource, SourceStatus, StepContext, first_after};
use crate::measurements::{Measurement, WheelSpeed};

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
    samples: &'a [WheelSpeedSample],
    config: WheelSpeedConfig,
    next: usize,
    last_fused_s: f64,
    status: SourceStatus,
}

impl<'a> WheelSpeedSource<'a> {
    /// A source over time-sorted samples.
    pub fn new(samples: &'a [WheelSpeedSample], config: WheelSpeedConfig) -> Self {
        Self {
            samples,
            config,
            next: 0,
            last_fused_s: f64::NEG_INFINITY,
            status: SourceStatus::new("wheel_speed"),
        }
    }
}

impl<const N: usize> AidSource<N> for WheelSpeedSource<'_> {
    fn name(&self) -> &'static str {
        "wheel_speed"
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
            || !sample.speed_mps.is_finite()
        {
            self.status.skipped += 1;
            return Ok(());
        }
        self.last_fused_s = sample.time_s;
        let measurement = WheelSpeed {
            speed_mps: sample.speed_mps,
            sigma_mps: sample
                .sigma_mps
                .map_or(self.config.sigma_mps, |s| s.max(self.config.sigma_mps)),
            lever_arm_m: self.config.lever_arm_m,
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
            "wheel_speed",
            <WheelSpeed as Measurement<1, N>>::NAME,
            &rec,
        );
        ctx.report(&mut self.status, &record);
        Ok(())
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}
