//! A source of a sensor each of whose samples is one update (the
//! wheel-speed and barometer sources): its samples taken in time order, at
//! most one per `min_interval_s`, each under a χ² gate. A new sensor of
//! this kind implements [`SampledSensor`] for its configuration.

use aidnav_estimation::{AcceptAll, Chi2Gate, EstimationError};
use aidnav_sensors::Timed;

use super::{AidRecord, AidSource, SourceStatus, StepContext, first_after};
use crate::measurements::Measurement;

/// A sensor each of whose samples is one update: what a
/// [`SampledSource`] needs of it (its configuration implements this).
pub trait SampledSensor {
    /// The sample record.
    type Sample: Timed + std::fmt::Debug;
    /// The measurement model of a sample.
    type Measurement;
    /// The source's name (and its status's, snake_case).
    const NAME: &'static str;
    /// Whether a sample can be fused at all (its values finite).
    fn usable(sample: &Self::Sample) -> bool;
    /// The measurement a sample makes.
    fn measurement(&self, sample: &Self::Sample) -> Self::Measurement;
    /// χ² gate probability (None: every sample accepted).
    fn gate_probability(&self) -> Option<f64>;
    /// Fuse at most one sample per this interval \[s\] (0: every sample).
    fn min_interval_s(&self) -> f64;
}

/// The samples of a [`SampledSensor`] as an aid source.
#[derive(Debug, Clone)]
pub struct SampledSource<'a, S: SampledSensor> {
    queue: SampleQueue<'a, S::Sample>,
    sensor: S,
    status: SourceStatus,
}

impl<'a, S: SampledSensor> SampledSource<'a, S> {
    /// A source over time-sorted samples.
    pub fn new(samples: &'a [S::Sample], sensor: S) -> Self {
        Self {
            queue: SampleQueue::new(samples, sensor.min_interval_s()),
            sensor,
            status: SourceStatus::new(S::NAME),
        }
    }
}

impl<const N: usize, S> AidSource<N> for SampledSource<'_, S>
where
    S: SampledSensor,
    S::Measurement: Measurement<1, N>,
{
    fn name(&self) -> &'static str {
        S::NAME
    }

    fn start(&mut self, t_start_s: f64) {
        self.queue.start(t_start_s);
    }

    fn next_time(&self) -> Option<f64> {
        self.queue.next_time()
    }

    fn step(&mut self, ctx: &mut StepContext<'_, '_, N>) -> Result<(), EstimationError> {
        let Some(sample) = self.queue.take_due(ctx.time_s, &mut self.status, S::usable) else {
            return Ok(());
        };
        let measurement = self.sensor.measurement(sample);
        let gate = self.sensor.gate_probability();
        let source = (S::NAME, sample.time_s());
        fuse_gated(ctx, &measurement, gate, source, &mut self.status)
    }

    fn status(&self) -> SourceStatus {
        self.status
    }
}

/// A time-sorted stream of samples that a source fuses one by one, at most
/// one per `min_interval_s`: the control step of a [`SampledSource`].
#[derive(Debug, Clone)]
struct SampleQueue<'a, T> {
    samples: &'a [T],
    next: usize,
    last_fused_s: f64,
    min_interval_s: f64,
}

impl<'a, T: Timed> SampleQueue<'a, T> {
    fn new(samples: &'a [T], min_interval_s: f64) -> Self {
        Self {
            samples,
            next: 0,
            last_fused_s: f64::NEG_INFINITY,
            min_interval_s,
        }
    }

    /// Start after `t_start_s`.
    fn start(&mut self, t_start_s: f64) {
        self.next = first_after(self.samples, t_start_s, Timed::time_s);
        self.last_fused_s = f64::NEG_INFINITY;
    }

    fn next_time(&self) -> Option<f64> {
        self.samples.get(self.next).map(Timed::time_s)
    }

    /// The sample due at `t_s`, when it is to be fused: None when none is
    /// due; a due sample too soon after the last fused one, or one that
    /// `usable` refuses, is counted as skipped in `status`.
    fn take_due(
        &mut self,
        t_s: f64,
        status: &mut SourceStatus,
        usable: impl Fn(&T) -> bool,
    ) -> Option<&'a T> {
        let sample = self.samples.get(self.next).filter(|s| s.time_s() <= t_s)?;
        self.next += 1;
        // 1 % slack: time tags a nominal interval apart (10 Hz against
        // 0.1 s) differ by a rounding error either way, and a strict test
        // would skip every other one of them.
        let elapsed = sample.time_s() - self.last_fused_s;
        if elapsed < 0.99 * self.min_interval_s || !usable(sample) {
            status.skipped += 1;
            return None;
        }
        self.last_fused_s = sample.time_s();
        Some(sample)
    }
}

/// Fuse `measurement` under a χ² gate of `gate_probability` (None: accept
/// every measurement) and report the update.
fn fuse_gated<const M: usize, const N: usize, Meas: Measurement<M, N>>(
    ctx: &mut StepContext<'_, '_, N>,
    measurement: &Meas,
    gate_probability: Option<f64>,
    (source, time_s): (&'static str, f64),
    status: &mut SourceStatus,
) -> Result<(), EstimationError> {
    let rec = match gate_probability {
        Some(probability) => ctx
            .filter
            .fuse(measurement, None, &mut Chi2Gate { probability })?,
        None => ctx.filter.fuse(measurement, None, &mut AcceptAll)?,
    };
    let record = AidRecord::of(time_s, source, <Meas as Measurement<M, N>>::NAME, &rec);
    ctx.report(status, &record);
    Ok(())
}
