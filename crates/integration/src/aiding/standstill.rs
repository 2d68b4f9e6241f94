//! The standstill updates as a source on the IMU's clock: a zero-velocity
//! and a zero-angular-rate update when the IMU window is still and a
//! recent GNSS velocity says the vehicle stands.

use aidnav_estimation::{AcceptAll, EstimationError};
use aidnav_ins::standstill::{
    StandstillThresholds, WindowStats, gnss_says_still, window_ending_at,
};

use super::{AidRecord, AidSource, SourceStatus, StepContext};
use crate::measurements::{Measurement, ZeroAngularRate, ZeroVelocity};

/// Zero-velocity and zero-angular-rate updates while the vehicle stands
/// still: the IMU window is still ([`StandstillThresholds`]) and a GNSS
/// velocity (a fix not withheld, within the last second) says "at rest"
/// ([`gnss_says_still`]: below `max_speed_mps`, or below the speed its own
/// σ allows a receiver at rest). Without GNSS (an outage) there is no standstill update:
/// a smooth straight motion looks like rest to an IMU, and the coasting
/// filter's own speed is no evidence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandstillUpdates {
    /// Check (and update) rate \[Hz\].
    pub rate_hz: f64,
    /// Window of the IMU statistics \[s\].
    pub window_s: f64,
    /// Largest speed of a standstill \[m/s\] (raised to what the GNSS
    /// velocity's σ allows at rest).
    pub max_speed_mps: f64,
    /// IMU thresholds.
    pub thresholds: StandstillThresholds,
    /// σ of the zero-velocity update per axis \[m/s\].
    pub velocity_sigma_mps: f64,
    /// Floor of the σ of the zero-angular-rate update per axis \[rad/s\]
    /// (the window's own noise of the mean counts too).
    pub angular_rate_sigma_rad_s: f64,
}

/// The standstill updates' source.
#[derive(Debug, Clone)]
pub struct StandstillSource {
    config: StandstillUpdates,
    interval_s: f64,
    next_s: f64,
    status: SourceStatus,
    rate_status: SourceStatus,
}

impl StandstillSource {
    /// A source checking at the configured rate.
    pub fn new(config: StandstillUpdates) -> Self {
        Self {
            config,
            interval_s: 1.0 / config.rate_hz,
            next_s: f64::INFINITY,
            status: SourceStatus::new("zero_velocity"),
            rate_status: SourceStatus::new("zero_angular_rate"),
        }
    }

    /// What the zero-angular-rate updates came to (the zero-velocity
    /// updates' is [`AidSource::status`]).
    pub fn angular_rate_status(&self) -> SourceStatus {
        self.rate_status
    }

    /// Whether the vehicle stands at the check: a recent slow GNSS
    /// velocity and a still IMU window; the window's statistics if so.
    fn still<const N: usize>(&self, ctx: &StepContext<'_, '_, N>) -> Option<WindowStats> {
        let z = &self.config;
        let t = ctx.time_s;
        // Only a GNSS velocity says "standing": the filter's own speed is no
        // evidence while it coasts (on the drive, trusting it made the burst
        // runs after 30 s outages 3.5 m instead of 0.67 m).
        let slow = matches!(ctx.evidence.gnss_velocity,
            Some((at, v, sigma)) if t - at <= 1.0
                && gnss_says_still(&v, sigma.as_ref(), z.max_speed_mps));
        if !slow {
            return None;
        }
        let stats = WindowStats::of(window_ending_at(ctx.imu, ctx.imu_index, z.window_s))?;
        stats.is_still(&z.thresholds).then_some(stats)
    }
}

impl<const N: usize> AidSource<N> for StandstillSource {
    fn name(&self) -> &'static str {
        "standstill"
    }

    fn start(&mut self, t_start_s: f64) {
        self.next_s = t_start_s + self.interval_s;
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        let t = ctx.time_s;
        if !ctx.at_imu_sample || t < self.next_s {
            return Ok(());
        }
        while self.next_s <= t {
            self.next_s += self.interval_s;
        }
        let Some(stats) = self.still(ctx) else {
            return Ok(());
        };
        let zupt = ZeroVelocity {
            sigma_mps: self.config.velocity_sigma_mps,
        };
        let rec = ctx.filter.fuse(&zupt, None, &mut AcceptAll)?;
        let record = AidRecord::of(
            t,
            "standstill",
            <ZeroVelocity as Measurement<3, N>>::NAME,
            &rec,
        );
        ctx.report(&mut self.status, &record);
        // σ of the window's mean rate: its spread over √n, floored.
        let n = stats.samples as f64;
        let zaru = ZeroAngularRate {
            mean_raw_rate_rad_s: stats.mean_rate,
            sigma_rad_s: stats
                .rate_std
                .map(|s| (s / n.sqrt()).max(self.config.angular_rate_sigma_rad_s)),
        };
        let rec = ctx.filter.fuse(&zaru, None, &mut AcceptAll)?;
        let record = AidRecord::of(
            t,
            "standstill",
            <ZeroAngularRate as Measurement<3, N>>::NAME,
            &rec,
        );
        ctx.report(&mut self.rate_status, &record);
        for o in ctx.observers.iter_mut() {
            o.standstill(t);
        }
        Ok(())
    }

    fn status(&self) -> SourceStatus {
        self.status
    }

    fn statuses(&self) -> Vec<SourceStatus> {
        vec![self.status, self.rate_status]
    }
}
