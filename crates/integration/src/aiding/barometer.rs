//! The barometric-height source: every sample (at most one per
//! `min_interval_s`) a height update; the barometer's bias against the
//! ellipsoidal height is estimated when the filter's layout has
//! [`Augmented::BaroBias`](crate::state::Augmented::BaroBias) (without it,
//! the barometer's datum must be the ellipsoid's).

use aidnav_sensors::BaroSample;

use super::{SampledSensor, SampledSource};
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
pub type BaroSource<'a> = SampledSource<'a, BaroConfig>;

impl SampledSensor for BaroConfig {
    type Sample = BaroSample;
    type Measurement = Barometer;
    const NAME: &'static str = "barometer";

    fn usable(sample: &BaroSample) -> bool {
        sample.height_m.is_finite()
    }

    fn measurement(&self, sample: &BaroSample) -> Barometer {
        let floor = self.sigma_m;
        Barometer {
            height_m: sample.height_m,
            sigma_m: sample.sigma_m.map_or(floor, |s| s.max(floor)),
        }
    }

    fn gate_probability(&self) -> Option<f64> {
        self.gate_probability
    }

    fn min_interval_s(&self) -> f64 {
        self.min_interval_s
    }
}
