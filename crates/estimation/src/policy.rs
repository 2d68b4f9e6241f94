//! Measurement policies: values that look at an innovation before the state is
//! touched and decide what the update does with it.
//!
//! This is the hook on which adaptive and anomaly-tolerant filters are built
//! (gating, rejection, limiting, Huber weighting, adaptive gain) without
//! copying the filter: [`KalmanFilter::update_with`](crate::KalmanFilter::update_with)
//! computes the innovation ν and its covariance S, asks the policy for a
//! [`Decision`], applies it, and reports what happened in the
//! [`UpdateRecord`](crate::UpdateRecord).
//!
//! Policies that change the *time* update (adaptive Q from the innovation,
//! paper eq. 3 of spec 20) use the split predict API
//! ([`predict_state`](crate::KalmanFilter::predict_state) then
//! [`predict_covariance`](crate::KalmanFilter::predict_covariance)) and pass
//! their own Q: the engine never needs to know.

use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, allocator::Allocator};
use serde::{Deserialize, Serialize};

use crate::consistency::chi2_quantile;

/// What the policy sees: the innovation and the covariances it came from.
#[derive(Debug)]
pub struct InnovationView<'a, M: Dim>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    /// ν = z − H x⁻.
    pub residual: &'a OVector<f64, M>,
    /// H P⁻ Hᵀ, the part of S due to the state's uncertainty.
    pub hph: &'a OMatrix<f64, M, M>,
    /// R, the measurement noise covariance as given.
    pub r: &'a OMatrix<f64, M, M>,
    /// S = H P⁻ Hᵀ + R.
    pub s: &'a OMatrix<f64, M, M>,
    /// Normalised innovation squared νᵀ S⁻¹ ν.
    pub nis: f64,
}

/// What the update should do with the innovation.
#[derive(Debug, Clone, PartialEq)]
pub enum Decision<M: Dim>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    /// Ordinary Kalman update.
    Accept,
    /// Skip the update: the estimate stays the prediction (K = 0).
    Reject,
    /// Use this innovation instead of ν (limiting / clipping), with the ordinary gain.
    ReplaceResidual(OVector<f64, M>),
    /// Multiply R by this factor (≥ 1 down-weights; robust re-weighting).
    InflateR(f64),
    /// Form the gain as K = P⁻ Hᵀ C⁻¹ with this C instead of S (adaptive gain
    /// from an empirical innovation covariance). The covariance is still
    /// updated in Joseph form with the true R, so P stays the covariance of
    /// the estimate actually produced.
    GainCovariance(OMatrix<f64, M, M>),
    /// Both at once (spec 20 eq. 9): use `residual` instead of ν with the gain
    /// K = P⁻ Hᵀ C⁻¹ formed from `covariance`. Recorded as [`Outcome::Limited`].
    LimitWithGainCovariance {
        /// The limited innovation.
        residual: OVector<f64, M>,
        /// C of the gain.
        covariance: OMatrix<f64, M, M>,
    },
}

/// How the update ended, as recorded per epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Ordinary update.
    Accepted,
    /// No update (K = 0).
    Rejected,
    /// Innovation replaced by a limited one.
    Limited,
    /// R inflated (down-weighted).
    Reweighted,
    /// Gain formed from a policy-supplied innovation covariance.
    AdaptiveGain,
    /// Measurement absent at this epoch (no update attempted).
    Missing,
    /// The measured states were reset to the measurement: it completed a
    /// run of refused measurements that agree with each other (see
    /// [`recovery`](crate::recovery)); the caller's reset replaced the update.
    Reset,
}

impl Outcome {
    /// Short lower-case name, as written to CSV.
    pub fn as_str(self) -> &'static str {
        match self {
            Outcome::Accepted => "accepted",
            Outcome::Rejected => "rejected",
            Outcome::Limited => "limited",
            Outcome::Reweighted => "reweighted",
            Outcome::AdaptiveGain => "adaptive_gain",
            Outcome::Missing => "missing",
            Outcome::Reset => "reset",
        }
    }
}

/// A policy: decides, per update, what to do with the innovation.
pub trait MeasurementPolicy<M: Dim>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    /// Look at the innovation and decide.
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M>;

    /// The stream had no measurement at an epoch where it was expected (a
    /// gap, an outage). Policies that behave differently on re-acquisition
    /// note it; by default nothing happens.
    fn missing(&mut self) {}
}

impl<M: Dim, F> MeasurementPolicy<M> for F
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
    F: FnMut(&InnovationView<'_, M>) -> Decision<M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        self(view)
    }
}

/// The plain Kalman filter: accept every measurement.
#[derive(Debug, Clone, Copy, Default)]
pub struct AcceptAll;

impl<M: Dim> MeasurementPolicy<M> for AcceptAll
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, _view: &InnovationView<'_, M>) -> Decision<M> {
        Decision::Accept
    }
}

/// χ² innovation gate: reject when NIS exceeds the χ²(m) quantile of `probability`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Chi2Gate {
    /// Probability of the χ² quantile used as the gate (e.g. 0.999).
    pub probability: f64,
}

impl<M: Dim> MeasurementPolicy<M> for Chi2Gate
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        let dof = view.residual.len();
        if view.nis > chi2_quantile(dof, self.probability) {
            Decision::Reject
        } else {
            Decision::Accept
        }
    }
}

/// A χ² gate that cannot lock out: after `max_rejections` consecutive
/// rejections the next measurement is accepted whatever its NIS. A plain
/// gate on an overconfident filter rejects every fix once it has drifted
/// (the lock-out seen in spec 20 and on the recorded drive); a fault longer
/// than `max_rejections` epochs is then left to a supervisor.
///
/// ```
/// use aidnav_estimation::{KalmanFilter, RecoveringChi2Gate, Outcome, nalgebra::{Matrix1, Vector1}};
/// let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
/// let mut gate = RecoveringChi2Gate::new(0.999, 2);
/// let h = Matrix1::new(1.0);
/// let r = Matrix1::new(1.0);
/// let outcomes: Vec<Outcome> = (0..3)
///     .map(|_| kf.update_with(&Vector1::new(100.0), &h, &r, &mut gate).unwrap().outcome)
///     .collect();
/// assert_eq!(outcomes, [Outcome::Rejected, Outcome::Rejected, Outcome::Accepted]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecoveringChi2Gate {
    /// Probability of the χ² quantile used as the gate.
    pub probability: f64,
    /// Consecutive rejections after which the next measurement is accepted.
    pub max_rejections: usize,
    rejected: usize,
}

impl RecoveringChi2Gate {
    /// A gate at `probability` accepting after `max_rejections` rejections in a row.
    pub fn new(probability: f64, max_rejections: usize) -> Self {
        Self {
            probability,
            max_rejections,
            rejected: 0,
        }
    }
}

impl<M: Dim> MeasurementPolicy<M> for RecoveringChi2Gate
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        let dof = view.residual.len();
        if view.nis > chi2_quantile(dof, self.probability) && self.rejected < self.max_rejections {
            self.rejected += 1;
            Decision::Reject
        } else {
            self.rejected = 0;
            Decision::Accept
        }
    }
}

/// Huber-type robust update on the normalised innovation: with
/// e = √NIS, the measurement keeps full weight while e ≤ k and is down-weighted
/// by w = k / e beyond (R inflated by 1/w), so its influence grows only
/// linearly with the size of the outlier (Huber's ψ-function).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Huber {
    /// Threshold k on √NIS (1.345 gives 95 % efficiency on Gaussian data).
    pub k: f64,
}

impl<M: Dim> MeasurementPolicy<M> for Huber
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        let e = view.nis.sqrt();
        if e <= self.k {
            Decision::Accept
        } else {
            Decision::InflateR(e / self.k)
        }
    }
}

/// A policy chosen by value at run time (from a scenario or model file).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum PolicyChoice {
    /// Accept every measurement.
    #[default]
    None,
    /// χ² gate with rejection.
    Chi2Gate {
        /// Probability of the χ² quantile, in (0, 1).
        probability: f64,
    },
    /// Huber down-weighting.
    Huber {
        /// Threshold on √NIS, > 0.
        k: f64,
    },
}

impl<M: Dim> MeasurementPolicy<M> for PolicyChoice
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        match *self {
            PolicyChoice::None => Decision::Accept,
            PolicyChoice::Chi2Gate { probability } => Chi2Gate { probability }.decide(view),
            PolicyChoice::Huber { k } => Huber { k }.decide(view),
        }
    }
}
