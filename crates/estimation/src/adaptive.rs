//! The adaptive and anomaly-tolerant building blocks of spec 20 (seed 004,
//! eqs. 3–8), as policies and helpers on the engine — none copies the filter.
//!
//! - [`AnomalyDetector`] (eq. 5): ν is anomalous when `νᵀν > γ tr S`,
//!   `S = H P⁻ Hᵀ + R`.
//! - [`Rejection`] (eq. 6): on an anomaly K = 0, the estimate stays the prediction.
//! - [`Limiting`] (eq. 8): on an anomaly ν is replaced by `ν · √(γ tr S) / |ν|`
//!   — clipped to the gate, direction (sign) kept.
//! - [`AdaptiveGain`] (eq. 4): gain from the empirical innovation covariance
//!   of a sliding window instead of the model's S.
//! - [`LimitedAdaptiveGain`] (eq. 9's update): the eq. 4 gain with the
//!   eq. 5 detector and the eq. 8 limiting.
//! - [`innovation_feedback_q`] (eq. 3): the process-noise term `K ν νᵀ Kᵀ`
//!   that replaces Q in the innovation-feedback adaptive filter; use it with
//!   the split predict (`predict_state`, `innovation`, `predict_covariance`).
//! - [`InnovationFeedbackNoise`] (eq. 3 with eq. 9's guard): that term from
//!   the previous gain, and on anomalous innovations (or epochs without a
//!   measurement) the mean of the terms of the last stable epochs instead.

use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, allocator::Allocator};
use serde::{Deserialize, Serialize};

use crate::kalman::FilterAllocator;
use crate::policy::{Decision, InnovationView, MeasurementPolicy};

/// Spec 20 eq. 5: anomalous when `νᵀν > γ · tr S`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AnomalyDetector {
    /// Anomaly level γ > 0 (e.g. 9: a "3σ" gate on the summed variance).
    pub gamma: f64,
}

impl AnomalyDetector {
    /// Whether the innovation in `view` is anomalous.
    pub fn is_anomalous<M: Dim>(&self, view: &InnovationView<'_, M>) -> bool
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        self.exceeds(view.residual, view.s)
    }

    /// Eq. 5 on an innovation ν and its covariance S given directly (for
    /// schemes that must decide before the update, e.g. whether ν may feed Q).
    pub fn exceeds<M: Dim>(&self, residual: &OVector<f64, M>, s: &OMatrix<f64, M, M>) -> bool
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        residual.norm_squared() > self.gamma * s.trace()
    }

    /// The gate radius `√(γ tr S)`.
    pub fn bound<M: Dim>(&self, view: &InnovationView<'_, M>) -> f64
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        (self.gamma * view.s.trace()).sqrt()
    }

    /// Eq. 8: for an anomalous innovation, the innovation clipped to the
    /// gate radius with its direction kept; None when it is not anomalous.
    pub fn limit<M: Dim>(&self, view: &InnovationView<'_, M>) -> Option<OVector<f64, M>>
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        self.is_anomalous(view)
            .then(|| view.residual * (self.bound(view) / view.residual.norm()))
    }
}

/// Spec 20 eq. 6: reject anomalous measurements (K = 0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rejection {
    /// The detector.
    pub detector: AnomalyDetector,
}

impl<M: Dim> MeasurementPolicy<M> for Rejection
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        if self.detector.is_anomalous(view) {
            Decision::Reject
        } else {
            Decision::Accept
        }
    }
}

/// Spec 20 eq. 8: limit anomalous innovations to the gate, keeping their direction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Limiting {
    /// The detector.
    pub detector: AnomalyDetector,
}

impl<M: Dim> MeasurementPolicy<M> for Limiting
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        match self.detector.limit(view) {
            Some(limited) => Decision::ReplaceResidual(limited),
            None => Decision::Accept,
        }
    }
}

/// Spec 20 eq. 8 limiting that rejects instead while the stream is being
/// re-acquired: after a gap ([`MeasurementPolicy::missing`]) an anomalous
/// measurement is rejected, until one is accepted; then anomalous ones are
/// limited again.
///
/// Limiting bounds an outlier's pull to K times the gate radius √(γ tr S).
/// While the stream flows the filter knows its state about as well as the
/// measurement does, the radius is a few σ of the measurement and the pull
/// small — and a filter that a skipped update has carried beyond the gate
/// keeps being corrected instead of locking out. After a gap the filter
/// has dead-reckoned: S is the dead-reckoning uncertainty, the radius
/// metres and K near one, so limiting would drag the state by metres
/// towards a bad measurement — and bursts come exactly then (spec 20: "when
/// the signal comes back after an outage"). So a re-acquired stream must
/// first pass the detector once. (A stream that never does is a lock-out:
/// the caller's [`recovery`](crate::recovery) ends it.)
///
/// ```
/// use aidnav_estimation::adaptive::{AnomalyDetector, ReacquiringLimiting};
/// use aidnav_estimation::{KalmanFilter, MeasurementPolicy, Outcome, nalgebra::{Matrix1, U1, Vector1}};
/// let mut policy = ReacquiringLimiting::new(AnomalyDetector { gamma: 9.0 });
/// let (h, r) = (Matrix1::new(1.0), Matrix1::new(1.0));
/// let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
/// let mut outcome = |kf: &mut KalmanFilter<_>, z: f64, p: &mut ReacquiringLimiting| {
///     kf.update_with(&Vector1::new(z), &h, &r, p).unwrap().outcome
/// };
/// assert_eq!(outcome(&mut kf.clone(), 40.0, &mut policy), Outcome::Limited);
/// MeasurementPolicy::<U1>::missing(&mut policy); // a gap
/// assert_eq!(outcome(&mut kf.clone(), 40.0, &mut policy), Outcome::Rejected);
/// assert_eq!(outcome(&mut kf, 0.5, &mut policy), Outcome::Accepted);
/// assert_eq!(outcome(&mut kf, 40.0, &mut policy), Outcome::Limited);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReacquiringLimiting {
    /// The detector.
    pub detector: AnomalyDetector,
    reacquiring: bool,
}

impl ReacquiringLimiting {
    /// Limiting by `detector`, the stream flowing.
    pub fn new(detector: AnomalyDetector) -> Self {
        Self {
            detector,
            reacquiring: false,
        }
    }

    /// Whether the stream is being re-acquired (a gap, no acceptance since).
    pub fn reacquiring(&self) -> bool {
        self.reacquiring
    }
}

impl<M: Dim> MeasurementPolicy<M> for ReacquiringLimiting
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        match self.detector.limit(view) {
            None => {
                self.reacquiring = false;
                Decision::Accept
            }
            Some(_) if self.reacquiring => Decision::Reject,
            Some(limited) => Decision::ReplaceResidual(limited),
        }
    }

    fn missing(&mut self) {
        self.reacquiring = true;
    }
}

/// How eq. 4 compares the diagonals of M̂ and H P⁻ Hᵀ for vector measurements.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DiagonalRule {
    /// M̂ is used when every diagonal element exceeds that of H P⁻ Hᵀ.
    #[default]
    All,
    /// M̂ is used when any diagonal element does.
    Any,
}

/// Spec 20 eq. 4: adaptive gain without noise statistics. Over a sliding
/// window of n innovations, `M̂ = (1/n) Σ ν νᵀ`; if diag M̂ > diag H P⁻ Hᵀ
/// (by [`DiagonalRule`]) the gain is `P⁻ Hᵀ M̂⁻¹`, else `P⁻ Hᵀ (H P⁻ Hᵀ)⁻¹`.
/// Until the window is full the ordinary gain is used. The ring buffer is
/// allocated once, at construction.
#[derive(Debug, Clone)]
pub struct AdaptiveGain<M: Dim>
where
    DefaultAllocator: Allocator<M, M>,
{
    window: Ring<OMatrix<f64, M, M>>,
    rule: DiagonalRule,
}

/// The last `capacity` values, oldest overwritten first (storage allocated
/// once): the sliding windows of eqs. 3 and 4.
#[derive(Debug, Clone)]
struct Ring<T> {
    items: Vec<T>,
    capacity: usize,
    next: usize,
}

impl<T> Ring<T> {
    fn new(capacity: usize) -> Self {
        Self {
            items: Vec::with_capacity(capacity),
            capacity,
            next: 0,
        }
    }

    fn push(&mut self, item: T) {
        if self.items.len() < self.capacity {
            self.items.push(item);
        } else {
            self.items[self.next] = item;
        }
        self.next = (self.next + 1) % self.capacity;
    }

    fn is_full(&self) -> bool {
        self.items.len() == self.capacity
    }
}

impl<M: Dim> AdaptiveGain<M>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    /// A window of `n ≥ 1` innovations.
    pub fn new(n: usize, rule: DiagonalRule) -> Option<Self> {
        (n >= 1).then(|| Self {
            window: Ring::new(n),
            rule,
        })
    }

    /// How the diagonals are compared.
    pub fn rule(&self) -> DiagonalRule {
        self.rule
    }

    /// The empirical innovation covariance M̂ (None until the window is full).
    pub fn empirical_covariance(&self) -> Option<OMatrix<f64, M, M>> {
        if !self.window.is_full() {
            return None;
        }
        let items = &self.window.items;
        let mut sum = items[0].clone();
        for m in &items[1..] {
            sum += m;
        }
        Some(sum / items.len() as f64)
    }

    /// Record the innovation ν and return eq. 4's gain covariance: M̂ when its
    /// diagonal exceeds that of `hph` (by the rule), else `hph`; None until
    /// the window is full.
    pub fn observe(
        &mut self,
        residual: &OVector<f64, M>,
        hph: &OMatrix<f64, M, M>,
    ) -> Option<OMatrix<f64, M, M>> {
        let (md, _) = hph.shape_generic();
        let mut outer = OMatrix::<f64, M, M>::zeros_generic(md, md);
        outer.ger(1.0, residual, residual, 0.0);
        self.window.push(outer);
        let m_hat = self.empirical_covariance()?;
        let exceeds = (0..residual.len()).map(|i| m_hat[(i, i)] > hph[(i, i)]);
        let use_empirical = match self.rule {
            DiagonalRule::All => exceeds.into_iter().all(|b| b),
            DiagonalRule::Any => exceeds.into_iter().any(|b| b),
        };
        Some(if use_empirical { m_hat } else { hph.clone() })
    }
}

impl<M: Dim> MeasurementPolicy<M> for AdaptiveGain<M>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        match self.observe(view.residual, view.hph) {
            Some(c) => Decision::GainCovariance(c),
            None => Decision::Accept,
        }
    }
}

/// Spec 20 eq. 9's measurement update, the developed algorithm: the adaptive
/// gain of eq. 4 and, when the detector of eq. 5 fires, the innovation
/// limited to the gate (eq. 8, direction kept). The window of M̂ records the
/// innovation actually used (the limited one on anomalies), so a burst
/// cannot blow M̂ up without bound. (The innovation-feedback prior of eq. 3
/// is the caller's: [`innovation_feedback_q`] with the split predict.)
#[derive(Debug, Clone)]
pub struct LimitedAdaptiveGain<M: Dim>
where
    DefaultAllocator: Allocator<M, M>,
{
    /// Eq. 4's window.
    pub gain: AdaptiveGain<M>,
    /// Eq. 5's detector.
    pub detector: AnomalyDetector,
}

impl<M: Dim> MeasurementPolicy<M> for LimitedAdaptiveGain<M>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        let Some(residual) = self.detector.limit(view) else {
            return match self.gain.observe(view.residual, view.hph) {
                Some(c) => Decision::GainCovariance(c),
                None => Decision::Accept,
            };
        };
        match self.gain.observe(&residual, view.hph) {
            Some(covariance) => Decision::LimitWithGainCovariance {
                residual,
                covariance,
            },
            None => Decision::ReplaceResidual(residual),
        }
    }
}

/// Spec 20 eq. 3: the innovation-feedback term `K_{k−1} ν_k ν_kᵀ K_{k−1}ᵀ`
/// that the adaptive filter uses in place of Q.
pub fn innovation_feedback_q<N: Dim, M: Dim>(
    previous_gain: &OMatrix<f64, N, M>,
    residual: &OVector<f64, M>,
) -> OMatrix<f64, N, N>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let kv = previous_gain * residual;
    let (nd, _) = previous_gain.shape_generic();
    let mut q = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
    q.ger(1.0, &kv, &kv, 0.0);
    q
}

/// Spec 20 eq. 3's innovation-feedback process noise with eq. 9's guard:
/// the term `K_{k−1} ν_k ν_kᵀ K_{k−1}ᵀ` while the innovations are normal; on
/// an anomalous innovation (by the optional detector) or an epoch without a
/// measurement, the mean of the terms of the last `stable_window` normal
/// epochs, so a burst cannot inflate P. Feed it every update's gain with
/// [`record_gain`](Self::record_gain). The ring is allocated once.
///
/// ```
/// use aidnav_estimation::adaptive::InnovationFeedbackNoise;
/// use aidnav_estimation::nalgebra::{Matrix1, Matrix2x1, Vector1};
/// let mut q = InnovationFeedbackNoise::new(Matrix2x1::zeros(), None, 4).unwrap();
/// q.record_gain(&Matrix2x1::new(0.5, 0.1));
/// let term = q.process_noise(&Vector1::new(2.0), &Matrix1::new(1.0));
/// assert!((term[(0, 0)] - 1.0).abs() < 1e-15); // (0.5 · 2)²
/// assert!((term[(0, 1)] - 0.2).abs() < 1e-15); // (0.5 · 2)(0.1 · 2)
/// ```
#[derive(Debug, Clone)]
pub struct InnovationFeedbackNoise<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    gain: OMatrix<f64, N, M>,
    detector: Option<AnomalyDetector>,
    stable: Ring<OMatrix<f64, N, N>>,
    average: bool,
}

impl<N: Dim, M: Dim> InnovationFeedbackNoise<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Start with a previous gain (zeros: no feedback until the first
    /// update), an optional anomaly detector and a window of `stable_window
    /// ≥ 1` stable terms (None when the window is 0).
    pub fn new(
        gain: OMatrix<f64, N, M>,
        detector: Option<AnomalyDetector>,
        stable_window: usize,
    ) -> Option<Self> {
        (stable_window >= 1).then(|| Self {
            gain,
            detector,
            stable: Ring::new(stable_window),
            average: false,
        })
    }

    /// Return the mean of the last `stable_window` normal terms (this one
    /// included) instead of the single term: the windowed estimate
    /// `K (1/n Σ ν νᵀ) Kᵀ` of Mohamed and Schwarz (1999), smoother than
    /// eq. 3's hard feedback when one large innovation meets a large gain
    /// (the first fixes after an outage).
    pub fn averaged(mut self, average: bool) -> Self {
        self.average = average;
        self
    }

    /// The gain of the last update (zero when it was rejected).
    pub fn record_gain(&mut self, gain: &OMatrix<f64, N, M>) {
        self.gain.copy_from(gain);
    }

    /// The process-noise term for an epoch with a measurement, from the
    /// innovation ν of the predicted state and its covariance S. (For an
    /// epoch without one use [`stable_mean`](Self::stable_mean).)
    pub fn process_noise(
        &mut self,
        residual: &OVector<f64, M>,
        s: &OMatrix<f64, M, M>,
    ) -> OMatrix<f64, N, N> {
        if self.detector.is_some_and(|d| d.exceeds(residual, s)) {
            return self.stable_mean();
        }
        let q = innovation_feedback_q(&self.gain, residual);
        self.stable.push(q.clone());
        if self.average { self.stable_mean() } else { q }
    }

    /// Mean of the remembered stable terms (zero before the first).
    pub fn stable_mean(&self) -> OMatrix<f64, N, N> {
        let (nd, _) = self.gain.shape_generic();
        let mut mean = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
        let items = &self.stable.items;
        for q in items {
            mean += q;
        }
        if !items.is_empty() {
            mean /= items.len() as f64;
        }
        mean
    }
}

#[cfg(test)]
mod feedback_tests {
    use super::*;
    use nalgebra::{Matrix1, Matrix2, Matrix2x1, Vector1};

    #[test]
    fn anomalies_and_missing_measurements_use_the_stable_mean() {
        let detector = AnomalyDetector { gamma: 9.0 };
        let mut q = InnovationFeedbackNoise::new(Matrix2x1::zeros(), Some(detector), 2).unwrap();
        let s = Matrix1::new(1.0);
        // Before any gain the term is zero.
        assert_eq!(q.process_noise(&Vector1::new(1.0), &s), Matrix2::zeros());
        q.record_gain(&Matrix2x1::new(1.0, 0.0));
        let a = q.process_noise(&Vector1::new(1.0), &s);
        let b = q.process_noise(&Vector1::new(2.0), &s);
        assert_eq!((a[(0, 0)], b[(0, 0)]), (1.0, 4.0));
        // The window holds the last two normal terms: (1 + 4) / 2 …
        let outlier = q.process_noise(&Vector1::new(10.0), &s);
        assert_eq!(outlier[(0, 0)], 2.5);
        // … also when no measurement came.
        assert_eq!(q.stable_mean()[(0, 0)], 2.5);
        // A third normal term pushes the first out: (4 + 0.25) / 2.
        q.process_noise(&Vector1::new(0.5), &s);
        assert_eq!(q.stable_mean()[(0, 0)], 2.125);
        assert!(InnovationFeedbackNoise::new(Matrix2x1::zeros(), None, 0).is_none());
        // Averaged: the mean of the window, this term included.
        let mut q = InnovationFeedbackNoise::new(Matrix2x1::new(1.0, 0.0), None, 2)
            .unwrap()
            .averaged(true);
        q.process_noise(&Vector1::new(1.0), &s);
        assert_eq!(q.process_noise(&Vector1::new(3.0), &s)[(0, 0)], 5.0);
    }
}
