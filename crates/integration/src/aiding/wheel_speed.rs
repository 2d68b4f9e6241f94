//! The wheel-speed (odometer) source: every sample (at most one per
//! `min_interval_s`) a forward-speed update at the wheel's lever arm; the
//! odometer's scale-factor error is estimated when the filter's layout has
//! [`Augmented::WheelSpeedScale`](crate::state::Augmented::WheelSpeedScale).

use aidnav_frames::{Body, Vec3};
use aidnav_sensors::WheelSpeedSample;

use super::{SampledSensor, SampledSource};
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
pub type WheelSpeedSource<'a> = SampledSource<'a, WheelSpeedConfig>;

impl SampledSensor for WheelSpeedConfig {
    type Sample = WheelSpeedSample;
    type Measurement = WheelSpeed;
    const NAME: &'static str = "wheel_speed";

    fn usable(sample: &WheelSpeedSample) -> bool {
        sample.speed_mps.is_finite()
    }

    fn measurement(&self, sample: &WheelSpeedSample) -> WheelSpeed {
        let floor = self.sigma_mps;
        WheelSpeed {
            speed_mps: sample.speed_mps,
            sigma_mps: sample.sigma_mps.map_or(floor, |s| s.max(floor)),
            lever_arm_m: self.lever_arm_m,
        }
    }

    fn gate_probability(&self) -> Option<f64> {
        self.gate_probability
    }

    fn min_interval_s(&self) -> f64 {
        self.min_interval_s
    }
}
