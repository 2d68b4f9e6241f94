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

/// A χ² gate on an innovation covariance calibrated from the innovations
/// it accepts: the gate that stays a χ² test when the filter's S is
/// optimistic (a receiver's σ, an unmodelled error).
///
/// The NIS of a consistent filter is χ²(m); when S is too small by a
/// factor λ, the NIS is λ·χ²(m). The gate estimates λ robustly as the
/// median NIS of the last `window` accepted innovations over the median of
/// χ²(m), never below 1 (an S larger than needed is left alone), and
/// rejects when `NIS / λ` exceeds the χ²(m) quantile of `probability`.
/// Only accepted innovations feed the window, so outliers cannot widen the
/// gate; the median keeps one large accepted innovation from moving it.
/// Until the window holds half its length λ = 1 (the plain gate). The
/// window is allocated once, at construction.
///
/// ```
/// use aidnav_estimation::{KalmanFilter, Outcome, ScaledChi2Gate, nalgebra::{Matrix1, Vector1}};
/// // S = 1 as modelled, but the innovations spread wider (σ ≈ 2): λ > 1.
/// let mut gate = ScaledChi2Gate::new(0.999, 20);
/// let (h, r) = (Matrix1::new(1.0), Matrix1::new(0.5));
/// let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(0.5)).unwrap();
/// let mut fresh = || kf.clone();
/// for nu in [1.9, -2.2, 0.8, -1.4, 2.9, -0.5, 1.1, -3.1, 0.3, 2.4] {
///     fresh().update_with(&Vector1::new(nu), &h, &r, &mut gate).unwrap();
/// }
/// assert!(gate.scale() > 2.0, "{}", gate.scale());
/// // A 4-σ innovation of the true spread (8 = 4 × 2) passes the calibrated
/// // gate although its NIS, 64, is far beyond χ²₁(0.999) = 10.8; a 20-σ one does not.
/// let rec = fresh().update_with(&Vector1::new(8.0), &h, &r, &mut gate).unwrap();
/// assert_eq!(rec.outcome, Outcome::Accepted);
/// let rec = fresh().update_with(&Vector1::new(40.0), &h, &r, &mut gate).unwrap();
/// assert_eq!(rec.outcome, Outcome::Rejected);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ScaledChi2Gate {
    probability: f64,
    accepted_nis: Vec<f64>,
    scratch: Vec<f64>,
    window: usize,
    next: usize,
    /// (m, χ²_m quantile of `probability`, median of χ²_m), cached.
    quantiles: Option<(usize, f64, f64)>,
    scale: f64,
}

impl ScaledChi2Gate {
    /// A gate at `probability` (as [`chi2_quantile`]: ≥ 1 accepts every
    /// finite NIS, ≤ 0 none) calibrated over the last `window` accepted
    /// innovations (at least 2).
    pub fn new(probability: f64, window: usize) -> Self {
        let window = window.max(2);
        Self {
            probability,
            accepted_nis: Vec::with_capacity(window),
            scratch: Vec::with_capacity(window),
            window,
            next: 0,
            quantiles: None,
            scale: 1.0,
        }
    }

    /// The current scale λ ≥ 1 of S.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    fn quantiles(&mut self, dof: usize) -> (f64, f64) {
        match self.quantiles {
            Some((m, q, median)) if m == dof => (q, median),
            _ => {
                let q = chi2_quantile(dof, self.probability);
                let median = chi2_quantile(dof, 0.5);
                self.quantiles = Some((dof, q, median));
                (q, median)
            }
        }
    }

    fn record(&mut self, nis: f64, median_chi2: f64) {
        if self.accepted_nis.len() < self.window {
            self.accepted_nis.push(nis);
        } else {
            self.accepted_nis[self.next] = nis;
        }
        self.next = (self.next + 1) % self.window;
        if 2 * self.accepted_nis.len() < self.window {
            return;
        }
        self.scratch.clear();
        self.scratch.extend_from_slice(&self.accepted_nis);
        let mid = self.scratch.len() / 2;
        let (_, median, _) = self.scratch.select_nth_unstable_by(mid, f64::total_cmp);
        self.scale = (*median / median_chi2).max(1.0);
    }
}

impl<M: Dim> MeasurementPolicy<M> for ScaledChi2Gate
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        let (quantile, median) = self.quantiles(view.residual.len());
        if view.nis.is_finite() && view.nis / self.scale <= quantile {
            self.record(view.nis, median);
            Decision::Accept
        } else {
            Decision::Reject
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
