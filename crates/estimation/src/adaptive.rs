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
    window: Vec<OMatrix<f64, M, M>>,
    capacity: usize,
    next: usize,
    rule: DiagonalRule,
}

impl<M: Dim> AdaptiveGain<M>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    /// A window of `n ≥ 1` innovations.
    pub fn new(n: usize, rule: DiagonalRule) -> Option<Self> {
        (n >= 1).then(|| Self {
            window: Vec::with_capacity(n),
            capacity: n,
            next: 0,
            rule,
        })
    }

    /// The empirical innovation covariance M̂ (None until the window is full).
    pub fn empirical_covariance(&self) -> Option<OMatrix<f64, M, M>> {
        if self.window.len() < self.capacity {
            return None;
        }
        let mut sum = self.window[0].clone();
        for m in &self.window[1..] {
            sum += m;
        }
        Some(sum / self.capacity as f64)
    }

    fn push(&mut self, outer: OMatrix<f64, M, M>) {
        if self.window.len() < self.capacity {
            self.window.push(outer);
        } else {
            self.window[self.next] = outer;
        }
        self.next = (self.next + 1) % self.capacity;
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
        self.push(outer);
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
