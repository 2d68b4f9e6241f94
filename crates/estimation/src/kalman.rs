//! The linear Kalman filter: predict with (Φ, Q), update with (z, H, R).
//!
//! One generic type serves compile-time sized filters (`Const<N>`, no heap
//! allocation in predict or update) and run-time sized ones (`Dyn`, for
//! filters that grow with the number of vehicles). The code path is the same;
//! only nalgebra's storage differs.
//!
//! Numerics follow the careful textbook route (Grewal & Andrews, *Kalman
//! Filtering*, §6; Bar-Shalom, Li & Kirubarajan, §5.2): S is factored by
//! Cholesky and the gain obtained by solving `S Kᵀ = H P⁻` rather than by
//! inverting S; the covariance is updated in Joseph form
//! `P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`, which is valid for *any* gain and
//! keeps P positive semi-definite under rounding; P is symmetrised after every
//! step and checked for non-finite values.

use nalgebra::{Cholesky, DefaultAllocator, Dim, Dyn, OMatrix, OVector, allocator::Allocator};
use serde::{Deserialize, Serialize};

use crate::check;
use crate::dense;
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::policy::{AcceptAll, Decision, InnovationView, MeasurementPolicy, Outcome};
use crate::smoother::cholesky_lower_in_place;

/// Allocation bounds for a filter of `N` states and `M` measurements, named
/// once so the generic signatures stay readable.
pub trait FilterAllocator<N: Dim, M: Dim>:
    Allocator<N> + Allocator<M> + Allocator<N, N> + Allocator<M, M> + Allocator<N, M> + Allocator<M, N>
{
}

impl<N: Dim, M: Dim, A> FilterAllocator<N, M> for A where
    A: Allocator<N>
        + Allocator<M>
        + Allocator<N, N>
        + Allocator<M, M>
        + Allocator<N, M>
        + Allocator<M, N>
{
}

/// How the covariance is updated after the gain is applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CovarianceUpdate {
    /// `P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`: valid for any gain, PSD under rounding.
    #[default]
    Joseph,
    /// `P = (I − K H) P⁻`: cheaper, valid only for the optimal gain; kept to
    /// cross-check and for users reproducing papers that print it.
    Standard,
}

/// What one measurement update did, returned to the caller (and to observers):
/// the quantities adaptive and robust schemes need.
#[derive(Debug, Clone, PartialEq)]
pub struct UpdateRecord<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Innovation ν = z − H x⁻ as measured (before any policy change).
    pub residual: OVector<f64, M>,
    /// Innovation covariance S = H P⁻ Hᵀ + R (with the R as given).
    pub s: OMatrix<f64, M, M>,
    /// Gain actually applied (zero when rejected).
    pub gain: OMatrix<f64, N, M>,
    /// Normalised innovation squared νᵀ S⁻¹ ν (χ²(m) for a consistent filter).
    pub nis: f64,
    /// What the policy decided.
    pub outcome: Outcome,
}

impl<N: Dim, M: Dim> UpdateRecord<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Gaussian log-likelihood of the innovation under the model,
    /// ln p(ν) = −½ (m ln 2π + ln det S + νᵀ S⁻¹ ν) with the S of the R as
    /// given (the prediction-error decomposition: summed over a run's
    /// updates it is the log-likelihood of the measurements, Schweppe 1965;
    /// Harvey, *Forecasting, structural time series models and the Kalman
    /// filter*, §3.4). ln det S from the Cholesky factor, 2 Σ ln L_ii. NaN
    /// when S is not positive definite or ν is not finite.
    ///
    /// ```
    /// use aidnav_estimation::{KalmanFilter, nalgebra::{Matrix1, Vector1}};
    /// let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    /// let rec = kf.update(&Vector1::new(2.0), &Matrix1::new(1.0), &Matrix1::new(1.0)).unwrap();
    /// // S = 2, ν = 2: −½ (ln 2π + ln 2 + 2).
    /// let expected = -0.5 * ((2.0 * std::f64::consts::PI).ln() + 2f64.ln() + 2.0);
    /// assert!((rec.log_likelihood() - expected).abs() < 1e-14);
    /// ```
    pub fn log_likelihood(&self) -> f64 {
        let m = self.residual.len() as f64;
        match Cholesky::new(self.s.clone()) {
            Some(chol) if self.nis.is_finite() => {
                let l = chol.l_dirty();
                let log_det: f64 = (0..self.residual.len()).map(|i| 2.0 * l[(i, i)].ln()).sum();
                -0.5 * (m * (2.0 * std::f64::consts::PI).ln() + log_det + self.nis)
            }
            _ => f64::NAN,
        }
    }
}

/// A linear Kalman filter over `N` states (`Const<n>` or `Dyn`).
///
/// ```
/// use aidnav_estimation::{KalmanFilter, nalgebra::{Matrix1, Vector1}};
/// // Static scalar x, prior N(0, 1), one measurement z = 2 with R = 1.
/// let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
/// kf.predict(&Matrix1::new(1.0), &Matrix1::new(0.0)).unwrap();
/// let rec = kf.update(&Vector1::new(2.0), &Matrix1::new(1.0), &Matrix1::new(1.0)).unwrap();
/// assert!((kf.state()[0] - 1.0).abs() < 1e-15);      // (0/1 + 2/1) / (1/1 + 1/1)
/// assert!((kf.covariance()[(0, 0)] - 0.5).abs() < 1e-15);
/// assert!((rec.nis - 2.0).abs() < 1e-15);             // 2² / (1 + 1)
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct KalmanFilter<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    x: OVector<f64, N>,
    pub(crate) p: OMatrix<f64, N, N>,
    covariance_update: CovarianceUpdate,
}

/// A filter whose size is fixed at compile time.
pub type FixedKalmanFilter<const N: usize> = KalmanFilter<nalgebra::Const<N>>;
/// A filter whose size is chosen at run time.
pub type DynKalmanFilter = KalmanFilter<Dyn>;

impl<N: Dim> KalmanFilter<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Start from `x0` and its covariance `p0` (symmetric, finite; it may be
    /// singular, e.g. for states known exactly).
    pub fn new(x0: OVector<f64, N>, p0: OMatrix<f64, N, N>) -> Result<Self> {
        let p = Self::checked_covariance(&x0, p0)?;
        Ok(Self {
            x: x0,
            p,
            covariance_update: CovarianceUpdate::Joseph,
        })
    }

    /// The checks of [`new`](Self::new) on a covariance for the state `x`,
    /// and P symmetrised.
    fn checked_covariance(
        x: &OVector<f64, N>,
        p0: OMatrix<f64, N, N>,
    ) -> Result<OMatrix<f64, N, N>> {
        let step = Step::Initialise;
        check::shape(&p0, (x.len(), x.len()), step, Matrix::P)?;
        check::finite(x, step, Matrix::X)?;
        check::finite(&p0, step, Matrix::P)?;
        check::symmetric(&p0, step, Matrix::P)?;
        let mut p = p0;
        check::symmetrize(&mut p);
        if (0..p.nrows()).any(|i| p[(i, i)] < 0.0) {
            return Err(EstimationError::NotPositiveDefinite {
                step,
                matrix: Matrix::P,
            });
        }
        Ok(p)
    }

    /// Choose the covariance update form (Joseph by default).
    pub fn with_covariance_update(mut self, form: CovarianceUpdate) -> Self {
        self.covariance_update = form;
        self
    }

    /// The covariance update form in use.
    pub fn covariance_update(&self) -> CovarianceUpdate {
        self.covariance_update
    }

    /// Current state estimate.
    pub fn state(&self) -> &OVector<f64, N> {
        &self.x
    }

    /// Current covariance.
    pub fn covariance(&self) -> &OMatrix<f64, N, N> {
        &self.p
    }

    /// Number of states.
    pub fn dim(&self) -> usize {
        self.x.len()
    }

    /// Replace the state estimate (closed-loop feedback resets it to zero, say).
    pub fn set_state(&mut self, x: OVector<f64, N>) -> Result<()> {
        check::shape(&x, (self.dim(), 1), Step::Initialise, Matrix::X)?;
        check::finite(&x, Step::Initialise, Matrix::X)?;
        self.x = x;
        Ok(())
    }

    /// Replace the covariance (checked as in [`KalmanFilter::new`]).
    pub fn set_covariance(&mut self, p: OMatrix<f64, N, N>) -> Result<()> {
        // The checks of `new` without building a filter (a copy of x and P).
        self.p = Self::checked_covariance(&self.x, p)?;
        Ok(())
    }

    /// Time update `x = Φ x`, `P = Φ P Φᵀ + Q`.
    pub fn predict(&mut self, phi: &OMatrix<f64, N, N>, q: &OMatrix<f64, N, N>) -> Result<()> {
        self.predict_state(phi)?;
        // Φ has just been checked (shape and finite): not again.
        self.propagate_covariance(phi, q)
    }

    /// State half of the time update, `x = Φ x`. Adaptive schemes that need the
    /// innovation of the predicted state before choosing Q call this, then
    /// [`innovation`](Self::innovation), then [`predict_covariance`](Self::predict_covariance).
    pub fn predict_state(&mut self, phi: &OMatrix<f64, N, N>) -> Result<()> {
        let n = self.dim();
        check::shape(phi, (n, n), Step::Predict, Matrix::Phi)?;
        check::finite(phi, Step::Predict, Matrix::Phi)?;
        self.predict_state_prechecked(phi)
    }

    /// Covariance half of the time update, `P = Φ P Φᵀ + Q`.
    pub fn predict_covariance(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q: &OMatrix<f64, N, N>,
    ) -> Result<()> {
        let n = self.dim();
        let step = Step::Predict;
        check::shape(phi, (n, n), step, Matrix::Phi)?;
        check::shape(q, (n, n), step, Matrix::Q)?;
        check::finite(phi, step, Matrix::Phi)?;
        self.propagate_covariance(phi, q)
    }

    /// `P = Φ P Φᵀ + Q` for a Φ already checked (shape, finite).
    fn propagate_covariance(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q: &OMatrix<f64, N, N>,
    ) -> Result<()> {
        // Φ P Φᵀ is symmetric: its lower triangle only, on (Q + Qᵀ)/2.
        let base = check::process_noise(q, self.dim())?;
        self.propagate_onto(base, phi)
    }

    /// `P = Φ P Φᵀ + base`, `base` Q as checked and symmetrised (its lower
    /// triangle read), and the check of the result: the dense time update
    /// of `predict`, `predict_covariance` and the batch's prechecked predict.
    fn propagate_onto(
        &mut self,
        mut base: OMatrix<f64, N, N>,
        phi: &OMatrix<f64, N, N>,
    ) -> Result<()> {
        dense::add_congruence(&mut base, phi, &self.p);
        check::finite(&base, Step::Predict, Matrix::P)?;
        self.p = base;
        Ok(())
    }

    /// Innovation ν = z − H x, S = H P Hᵀ + R and the NIS, without changing the filter.
    pub fn innovation<M: Dim>(
        &self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<Innovation<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let innov = self.innovate(z, h, r)?;
        Ok(Innovation {
            residual: innov.residual,
            hp: innov.cross.transpose(),
            hph: innov.hph,
            s: innov.s,
            chol: innov.chol,
            nis: innov.nis,
        })
    }

    /// [`innovation`](Self::innovation) with the cross covariance kept as
    /// P Hᵀ (n × m), the shape the gain and the covariance update read.
    fn innovate<M: Dim>(
        &self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<Innovated<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let step = Step::Update;
        check::measurement((z, h, r), self.dim(), step)?;
        check::symmetric(r, step, Matrix::R)?;
        self.innovate_prechecked(&self.p, z, h, r)
    }

    /// [`innovate`](Self::innovate) for an H and R the caller checked
    /// (shapes, finite, R symmetric) and a finite z: the arithmetic alone,
    /// on the covariance `p` (the filter's own, or the batch's P⁻ kept
    /// aside by [`predict_prechecked_aside`](Self::predict_prechecked_aside)).
    fn innovate_prechecked<M: Dim>(
        &self,
        p: &OMatrix<f64, N, N>,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<Innovated<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let (md, nd) = h.shape_generic();
        let mut innov = Innovated::zeros(nd, md);
        self.innovate_into(p, z, h, r, &mut innov)?;
        Ok(innov)
    }

    /// [`innovate_prechecked`](Self::innovate_prechecked) into `innov`
    /// (its values on entry unread): the batch's update reuses one for
    /// every epoch instead of moving a new one through the calls.
    fn innovate_into<M: Dim>(
        &self,
        p: &OMatrix<f64, N, N>,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
        innov: &mut Innovated<N, M>,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let step = Step::Update;
        let (m, n) = (z.len(), self.dim());
        innov.residual = z - h * &self.x;
        let (md, nd) = h.shape_generic();
        if dense::use_kernel::<M, N, N>(m, n, n) {
            // Only H's nonzero elements enter P Hᵀ and H P Hᵀ (a navigation
            // filter's H selects a few states); the rest are exact zeros.
            dense::measured_covariances((&mut innov.cross, &mut innov.hph), p, h);
        } else {
            let mut listed = [0; dense::MAX_LISTED];
            let columns = dense::nonzero_columns(h, &mut listed);
            let mut hp = OMatrix::<f64, M, N>::zeros_generic(md, nd);
            dense::h_times_symmetric(&mut hp, h, p, columns);
            dense::times_h_transpose(&mut innov.hph, &hp, h, columns);
            innov.cross = hp.transpose();
        }
        check::symmetrize(&mut innov.hph);
        innov.s = &innov.hph + r;
        innov.chol = factor(&innov.s).ok_or(EstimationError::NotPositiveDefinite {
            step,
            matrix: Matrix::S,
        })?;
        innov.nis = normalised_square(&innov.chol, &innov.residual);
        Ok(())
    }

    /// Measurement update accepting every measurement (the plain Kalman filter).
    pub fn update<M: Dim>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        self.update_with(z, h, r, &mut AcceptAll)
    }

    /// Measurement update under a policy: the policy sees the innovation and
    /// decides to accept, reject, limit, re-weight or use another gain.
    pub fn update_with<M: Dim, Pol: MeasurementPolicy<M> + ?Sized>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
        policy: &mut Pol,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let innov = self.innovate(z, h, r)?;
        let decision = policy.decide(&innov.view(r));
        self.decided_record(innov, decision, r)
    }

    /// [`update_with`](Self::update_with) with the policy's decision already
    /// taken (the batch replays a decision it took on the steady path's
    /// innovation, the same numbers; a policy asked twice could change its
    /// state).
    pub(crate) fn update_decided<M: Dim>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
        decision: Decision<M>,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let innov = self.innovate(z, h, r)?;
        self.decided_record(innov, decision, r)
    }

    /// The update a decision asks for, on the innovation it was taken on,
    /// and its record.
    fn decided_record<M: Dim>(
        &mut self,
        innov: Innovated<N, M>,
        decision: Decision<M>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let (nd, md) = innov.cross.shape_generic();
        let mut gain = OMatrix::zeros_generic(nd, md);
        let outcome = self.apply_decision(None, &innov, decision, r, &mut gain)?;
        Ok(UpdateRecord {
            residual: innov.residual,
            s: innov.s,
            gain,
            nis: innov.nis,
            outcome,
        })
    }

    /// The update a decision asks for, on the innovation it was taken on;
    /// P⁺ from `prior` (P⁻) when given, else from the filter's own P (see
    /// [`apply`](Self::apply)). The gain applied (zero when rejected) is
    /// written into `gain`.
    fn apply_decision<M: Dim>(
        &mut self,
        prior: Option<&OMatrix<f64, N, N>>,
        innov: &Innovated<N, M>,
        decision: Decision<M>,
        r: &OMatrix<f64, M, M>,
        gain: &mut OMatrix<f64, N, M>,
    ) -> Result<Outcome>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let step = Step::Update;
        let m = innov.residual.len();
        let outcome = match decision {
            Decision::Reject => {
                gain.fill(0.0);
                Outcome::Rejected
            }
            Decision::Accept => {
                Self::gain_into(&innov.chol, &innov.cross, gain);
                self.apply(prior, gain, &innov.residual, &innov.cross, &innov.s, step)?;
                Outcome::Accepted
            }
            Decision::ReplaceResidual(limited) => {
                check::shape(&limited, (m, 1), step, Matrix::Innovation)?;
                check::finite(&limited, step, Matrix::Innovation)?;
                Self::gain_into(&innov.chol, &innov.cross, gain);
                self.apply(prior, gain, &limited, &innov.cross, &innov.s, step)?;
                Outcome::Limited
            }
            Decision::InflateR(factor) => {
                if !(factor.is_finite() && factor > 0.0) {
                    return Err(EstimationError::NonFinite {
                        step,
                        matrix: Matrix::R,
                    });
                }
                let s_used = &innov.hph + r * factor;
                let chol =
                    Cholesky::new(s_used.clone()).ok_or(EstimationError::NotPositiveDefinite {
                        step,
                        matrix: Matrix::S,
                    })?;
                Self::gain_into(&chol, &innov.cross, gain);
                self.apply(prior, gain, &innov.residual, &innov.cross, &s_used, step)?;
                Outcome::Reweighted
            }
            Decision::GainCovariance(c) => {
                Self::gain_from(c, &innov.cross, m, step, gain)?;
                self.apply(prior, gain, &innov.residual, &innov.cross, &innov.s, step)?;
                Outcome::AdaptiveGain
            }
            Decision::LimitWithGainCovariance {
                residual,
                covariance,
            } => {
                check::shape(&residual, (m, 1), step, Matrix::Innovation)?;
                check::finite(&residual, step, Matrix::Innovation)?;
                Self::gain_from(covariance, &innov.cross, m, step, gain)?;
                self.apply(prior, gain, &residual, &innov.cross, &innov.s, step)?;
                Outcome::Limited
            }
        };
        Ok(outcome)
    }

    /// K = P Hᵀ C⁻¹ into `gain` from a Cholesky factor of C, solving
    /// C Kᵀ = H P (C, P symmetric), given `cross` = P Hᵀ.
    fn gain_into<M: Dim>(
        chol: &Cholesky<f64, M>,
        cross: &OMatrix<f64, N, M>,
        gain: &mut OMatrix<f64, N, M>,
    ) where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let (n, m) = cross.shape();
        if m <= dense::MAX_GAIN_SOLVE && dense::use_kernel::<N, M, M>(n, m, m) {
            gain.copy_from(cross);
            dense::solve_gain_in_place(gain, chol.l_dirty());
        } else {
            *gain = chol.solve(&cross.transpose()).transpose();
        }
    }

    /// K = P⁻ Hᵀ C⁻¹ into `gain` for a policy-supplied C (checked: shape,
    /// finite, positive definite).
    fn gain_from<M: Dim>(
        c: OMatrix<f64, M, M>,
        cross: &OMatrix<f64, N, M>,
        m: usize,
        step: Step,
        gain: &mut OMatrix<f64, N, M>,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        check::shape(&c, (m, m), step, Matrix::S)?;
        check::finite(&c, step, Matrix::S)?;
        let chol = Cholesky::new(c).ok_or(EstimationError::NotPositiveDefinite {
            step,
            matrix: Matrix::S,
        })?;
        Self::gain_into(&chol, cross, gain);
        Ok(())
    }

    /// x += K ν; P by the configured form; symmetrise and check.
    ///
    /// `s_used` is H P⁻ Hᵀ + R with the R the update uses. The Joseph form
    /// `(I − K H) P (I − K H)ᵀ + K R Kᵀ` is evaluated expanded, which it
    /// equals term by term for *any* gain K (optimal or not; P symmetric, so
    /// P Hᵀ = (H P)ᵀ = Uᵀ):
    /// `P − K U − Uᵀ Kᵀ + K (H P Hᵀ + R) Kᵀ = P + V Kᵀ + K Vᵀ`
    /// with `V = ½ K S − Uᵀ`. It is the same polynomial in K as the product
    /// form, so a gain error still changes P only at second order, and it is a
    /// symmetric rank-2m update: one n × m product for V and the lower
    /// triangle of V Kᵀ + K Vᵀ, n²m multiply-adds instead of the 3n²m of
    /// `A = P − K U`, `A + (K R − A Hᵀ) Kᵀ`, with P exactly symmetric by
    /// construction. The sequential update expands it the same way.
    ///
    /// With `prior` (P⁻ kept aside by the batch) P⁺ is written straight
    /// into the filter's covariance from it, no copy of P made; on an error
    /// the caller puts P⁻ back (see
    /// [`update_prechecked_from`](Self::update_prechecked_from)). Without,
    /// P⁺ is computed on a copy of the filter's P and the filter's P is
    /// left as it was on an error.
    fn apply<M: Dim>(
        &mut self,
        prior: Option<&OMatrix<f64, N, N>>,
        gain: &OMatrix<f64, N, M>,
        residual: &OVector<f64, M>,
        cross: &OMatrix<f64, N, M>,
        s_used: &OMatrix<f64, M, M>,
        step: Step,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        check::finite(gain, step, Matrix::K)?;
        self.x += gain * residual;
        let form = self.covariance_update;
        if let Some(prior) = prior {
            Self::update_covariance(form, &mut self.p, Some(prior), gain, cross, s_used);
            check::finite(&self.x, step, Matrix::X)?;
            return check::finite(&self.p, step, Matrix::P);
        }
        let mut p = self.p.clone();
        Self::update_covariance(form, &mut p, None, gain, cross, s_used);
        check::finite(&self.x, step, Matrix::X)?;
        check::finite(&p, step, Matrix::P)?;
        self.p = p;
        Ok(())
    }

    /// P⁺ by `form` into `p`, from `prior` when given, else from p's own
    /// values (see [`apply`](Self::apply)).
    fn update_covariance<M: Dim>(
        form: CovarianceUpdate,
        p: &mut OMatrix<f64, N, N>,
        prior: Option<&OMatrix<f64, N, N>>,
        gain: &OMatrix<f64, N, M>,
        cross: &OMatrix<f64, N, M>,
        s_used: &OMatrix<f64, M, M>,
    ) where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        match form {
            CovarianceUpdate::Joseph => {
                // V = ½ K S − Uᵀ, then P + V Kᵀ + K Vᵀ, lower triangle.
                let mut v = cross.clone();
                dense::joseph_rank_2k(p, prior, &mut v, (gain, s_used), (0.5, -1.0));
            }
            CovarianceUpdate::Standard => {
                if let Some(prior) = prior {
                    p.copy_from(prior);
                }
                // (I − K H) P = P − K (H P)
                dense::gemm(p, -1.0, gain, &cross.transpose(), 1.0);
                check::symmetrize(p);
            }
        }
    }

    /// Sequential (scalar-by-scalar) update for a diagonal R: each component is
    /// processed as its own scalar measurement, so no matrix is factored.
    /// Mathematically identical to the batch update when R is diagonal; the
    /// returned record holds the sequential innovations, their variances on the
    /// diagonal of `s`, the columns of the scalar gains, and the NIS as the sum
    /// of the scalar NIS (equal to the batch NIS by the chain rule of the
    /// Gaussian likelihood). No policy is applied on this path.
    pub fn update_sequential<M: Dim>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let step = Step::SequentialUpdate;
        let m = check::measurement((z, h, r), self.dim(), step)?;
        for i in 0..m {
            for j in 0..m {
                if i != j && r[(i, j)] != 0.0 {
                    return Err(EstimationError::NotDiagonal {
                        step,
                        matrix: Matrix::R,
                        row: i,
                        col: j,
                        value: r[(i, j)],
                    });
                }
            }
        }
        let (md, nd) = h.shape_generic();
        let mut residual = OVector::<f64, M>::zeros_generic(md, nalgebra::U1);
        let mut s = OMatrix::<f64, M, M>::zeros_generic(md, md);
        let mut gains = OMatrix::<f64, N, M>::zeros_generic(nd, md);
        let mut nis = 0.0;
        let mut ph = OVector::<f64, N>::zeros_generic(nd, nalgebra::U1);
        for i in 0..m {
            let hi = h.row(i);
            let ri = r[(i, i)];
            // P hᵀ, then the scalar innovation variance s = h P hᵀ + r.
            ph.gemv(1.0, &self.p, &hi.transpose(), 0.0);
            let si = (hi * &ph)[0] + ri;
            if !(si > 0.0 && si.is_finite()) {
                return Err(EstimationError::NotPositiveDefinite {
                    step,
                    matrix: Matrix::S,
                });
            }
            let nu = z[i] - (hi * &self.x)[0];
            let k = &ph / si;
            self.x.axpy(nu, &k, 1.0);
            // Joseph form for a scalar measurement, expanded without forming
            // (I − k h): P − k (hP) − (Ph) kᵀ + k s kᵀ, which equals
            // (I − k h) P (I − k h)ᵀ + k r kᵀ exactly.
            match self.covariance_update {
                CovarianceUpdate::Joseph => {
                    self.p.ger(-1.0, &k, &ph, 1.0);
                    self.p.ger(-1.0, &ph, &k, 1.0);
                    self.p.ger(si, &k, &k, 1.0);
                }
                CovarianceUpdate::Standard => self.p.ger(-1.0, &k, &ph, 1.0),
            }
            check::symmetrize(&mut self.p);
            residual[i] = nu;
            s[(i, i)] = si;
            gains.set_column(i, &k);
            nis += nu * nu / si;
        }
        check::finite(&self.x, step, Matrix::X)?;
        check::finite(&self.p, step, Matrix::P)?;
        Ok(UpdateRecord {
            residual,
            s,
            gain: gains,
            nis,
            outcome: Outcome::Accepted,
        })
    }
}

/// Largest measurement count whose S is factored and solved by the
/// fixed-size code here ([`factor`], [`normalised_square`]) rather than by
/// nalgebra's generic `Cholesky`: the batch's fixed-size updates.
const MAX_FIXED_FACTOR: usize = 6;

/// The Cholesky factor of S: for a fixed size up to [`MAX_FIXED_FACTOR`]
/// by the smoother's in-place factor, nalgebra's `Cholesky::new` operation
/// for operation (the same factor bit for bit, the same refusal of a pivot
/// that is not positive, the upper triangle left as S's) without its
/// generic column views, which cost more than the arithmetic at m = 3;
/// else by nalgebra. None when S is not positive definite.
fn factor<M: Dim>(s: &OMatrix<f64, M, M>) -> Option<Cholesky<f64, M>>
where
    DefaultAllocator: Allocator<M, M>,
{
    let mut l = s.clone();
    let factored = match M::try_to_usize() {
        Some(1) => cholesky_lower_in_place::<1>(l.as_mut_slice()),
        Some(2) => cholesky_lower_in_place::<2>(l.as_mut_slice()),
        Some(3) => cholesky_lower_in_place::<3>(l.as_mut_slice()),
        Some(4) => cholesky_lower_in_place::<4>(l.as_mut_slice()),
        Some(5) => cholesky_lower_in_place::<5>(l.as_mut_slice()),
        Some(MAX_FIXED_FACTOR) => cholesky_lower_in_place::<MAX_FIXED_FACTOR>(l.as_mut_slice()),
        _ => return Cholesky::new(l),
    };
    factored.then(|| Cholesky::pack_dirty(l))
}

/// The NIS νᵀ S⁻¹ ν from S's factor: S⁻¹ ν for a fixed size up to
/// [`MAX_FIXED_FACTOR`] by [`dense::cholesky_solve_vector`] (nalgebra's
/// `Cholesky::solve` operation for operation), else by nalgebra; the dot
/// product nalgebra's in both.
fn normalised_square<M: Dim>(chol: &Cholesky<f64, M>, residual: &OVector<f64, M>) -> f64
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    if M::try_to_usize().is_some_and(|m| m <= MAX_FIXED_FACTOR) {
        let mut solved = residual.clone();
        dense::cholesky_solve_vector(chol.l_dirty().as_slice(), solved.as_mut_slice());
        residual.dot(&solved)
    } else {
        residual.dot(&chol.solve(residual))
    }
}

/// An innovation with its covariance and factor, computed without changing the filter.
#[derive(Debug, Clone)]
pub struct Innovation<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// ν = z − H x.
    pub residual: OVector<f64, M>,
    /// H P (kept: the gain and the covariance update reuse it).
    pub hp: OMatrix<f64, M, N>,
    /// H P Hᵀ.
    pub hph: OMatrix<f64, M, M>,
    /// S = H P Hᵀ + R.
    pub s: OMatrix<f64, M, M>,
    /// Cholesky factor of S.
    pub chol: Cholesky<f64, M>,
    /// νᵀ S⁻¹ ν.
    pub nis: f64,
}

/// [`Innovation`] as the update uses it: the cross covariance as P Hᵀ.
struct Innovated<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    residual: OVector<f64, M>,
    /// P Hᵀ = (H P)ᵀ.
    cross: OMatrix<f64, N, M>,
    hph: OMatrix<f64, M, M>,
    s: OMatrix<f64, M, M>,
    chol: Cholesky<f64, M>,
    nis: f64,
}

impl<N: Dim, M: Dim> Innovated<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Zeros (and the identity's factor) for n states, m measurements: a
    /// place for [`KalmanFilter::innovate_into`] to write.
    fn zeros(nd: N, md: M) -> Self {
        Self {
            residual: OVector::zeros_generic(md, nalgebra::U1),
            cross: OMatrix::zeros_generic(nd, md),
            hph: OMatrix::zeros_generic(md, md),
            s: OMatrix::zeros_generic(md, md),
            chol: Cholesky::new_unchecked(OMatrix::identity_generic(md, md)),
            nis: 0.0,
        }
    }

    /// What a policy sees of this innovation, with the R it was formed with.
    fn view<'a>(&'a self, r: &'a OMatrix<f64, M, M>) -> InnovationView<'a, M> {
        InnovationView {
            residual: &self.residual,
            hph: &self.hph,
            r,
            s: &self.s,
            nis: self.nis,
        }
    }
}

impl<N: Dim> KalmanFilter<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Set the covariance to `p` without the checks of
    /// [`set_covariance`](Self::set_covariance): for the batch's steady
    /// state, whose `p` is a covariance this filter's own full step
    /// computed (finite, symmetric by construction).
    pub(crate) fn set_covariance_computed(&mut self, p: &OMatrix<f64, N, N>) {
        self.p.as_mut_slice().copy_from_slice(p.as_slice());
    }

    /// [`predict_state`](Self::predict_state) for a Φ the caller checked
    /// once for many epochs (shape, finite): the same arithmetic, the
    /// state's check kept.
    pub(crate) fn predict_state_prechecked(&mut self, phi: &OMatrix<f64, N, N>) -> Result<()> {
        // Φ x as nalgebra's product, bit for bit, with wider vectors.
        let mut x = self.x.clone();
        dense::matrix_vector(&mut x, phi, &self.x);
        self.x = x;
        check::finite(&self.x, Step::Predict, Matrix::X)
    }

    /// [`predict`](Self::predict) for a Φ and Q the caller checked once for
    /// many epochs (shape, finite, Q symmetric; `q_symmetric` is Q as
    /// `propagate_covariance` uses it, (Q + Qᵀ)/2 unless exactly
    /// symmetric): the same arithmetic, bit for bit, the checks of what
    /// changes (x, P) kept.
    pub(crate) fn predict_prechecked(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q_symmetric: &OMatrix<f64, N, N>,
    ) -> Result<()> {
        self.predict_state_prechecked(phi)?;
        self.propagate_onto(q_symmetric.clone(), phi)
    }

    /// [`update_with`](Self::update_with) for an H and R the caller checked
    /// once for many epochs (shapes, finite, R exactly symmetric): the
    /// same arithmetic, bit for bit, the checks of what changes (z, x, P,
    /// the gain) kept; any decision applied as `update_with` applies it.
    pub(crate) fn update_prechecked<M: Dim, Pol: MeasurementPolicy<M> + ?Sized>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
        policy: Option<&mut Pol>,
    ) -> Result<UpdateRecord<N, M>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let step = Step::Update;
        check::finite(z, step, Matrix::Z)?;
        let innov = self.innovate_prechecked(&self.p, z, h, r)?;
        let decision = match policy {
            None => Decision::Accept,
            Some(p) => p.decide(&innov.view(r)),
        };
        self.decided_record(innov, decision, r)
    }

    /// [`predict_prechecked`](Self::predict_prechecked) with P⁻ written
    /// into `predicted` (`phi_p` scratch for Φ P; the values of both on
    /// entry unread) and the filter's covariance left as it was: the
    /// batch's full step, followed by
    /// [`update_prechecked_from`](Self::update_prechecked_from), which
    /// writes P⁺ from `predicted` into the filter, so that neither step
    /// copies P. The same arithmetic and checks, bit for bit; on an error
    /// the filter is as `predict_prechecked` leaves it (x⁻, P unchanged).
    /// `p_symmetric`: the caller knows the filter's P to be symmetric bit
    /// for bit (the batch checks it once: every P a step computes is, by
    /// its mirror or symmetrisation), which saves work at some sizes.
    pub(crate) fn predict_prechecked_aside(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q_symmetric: &OMatrix<f64, N, N>,
        (predicted, phi_p): (&mut OMatrix<f64, N, N>, &mut OMatrix<f64, N, N>),
        p_symmetric: bool,
    ) -> Result<()> {
        let (nd, _) = phi.shape_generic();
        if nd.value() > dense::MAX_FUSED_STATES {
            self.predict_state_prechecked(phi)?;
            dense::congruence(predicted, Some(q_symmetric), phi, &self.p, phi_p);
            return check::finite(predicted, Step::Predict, Matrix::P);
        }
        // One dispatch for x⁻, P⁻ and their checks (the same operations).
        let matrix = match dense::predicted_aside(
            (nd, p_symmetric),
            self.x.as_mut_slice(),
            (phi.as_slice(), q_symmetric.as_slice(), self.p.as_slice()),
            predicted.as_mut_slice(),
            phi_p.as_mut_slice(),
        ) {
            dense::PredictedStatus::Applied => return Ok(()),
            dense::PredictedStatus::StateNonFinite => Matrix::X,
            dense::PredictedStatus::CovarianceNonFinite => Matrix::P,
        };
        Err(EstimationError::NonFinite {
            step: Step::Predict,
            matrix,
        })
    }

    /// [`update_prechecked`](Self::update_prechecked) after
    /// [`predict_prechecked_aside`](Self::predict_prechecked_aside): the
    /// update from P⁻ = `predicted` (the filter's own covariance on entry
    /// is not read), the same arithmetic and checks, bit for bit, its
    /// innovation and gain left in `work` (what the record would hold)
    /// instead of a record. The filter ends as `predict_prechecked` then
    /// `update_prechecked` leave it: P⁺ when the update is applied, else
    /// (rejected, or an error) P⁻.
    pub(crate) fn update_prechecked_from<M: Dim, Pol: MeasurementPolicy<M> + ?Sized>(
        &mut self,
        predicted: &OMatrix<f64, N, N>,
        (z, h, r): Measured<'_, N, M>,
        policy: Option<&mut Pol>,
        work: &mut UpdateWork<N, M>,
    ) -> Result<Outcome>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let applied = self.update_onto(predicted, (z, h, r), policy, work);
        // P⁺ was written only by an update applied without error.
        if !matches!(applied, Ok(outcome) if outcome != Outcome::Rejected) {
            self.p.copy_from(predicted);
        }
        applied
    }

    /// The body of [`update_prechecked_from`](Self::update_prechecked_from).
    fn update_onto<M: Dim, Pol: MeasurementPolicy<M> + ?Sized>(
        &mut self,
        predicted: &OMatrix<f64, N, N>,
        (z, h, r): Measured<'_, N, M>,
        policy: Option<&mut Pol>,
        work: &mut UpdateWork<N, M>,
    ) -> Result<Outcome>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        check::finite(z, Step::Update, Matrix::Z)?;
        if policy.is_none() && self.covariance_update == CovarianceUpdate::Joseph {
            let fused = match M::try_to_usize() {
                Some(1) => self.accept_fused::<M, 1>(predicted, (z, h, r), work),
                Some(2) => self.accept_fused::<M, 2>(predicted, (z, h, r), work),
                Some(3) => self.accept_fused::<M, 3>(predicted, (z, h, r), work),
                Some(4) => self.accept_fused::<M, 4>(predicted, (z, h, r), work),
                Some(5) => self.accept_fused::<M, 5>(predicted, (z, h, r), work),
                Some(6) => self.accept_fused::<M, 6>(predicted, (z, h, r), work),
                _ => None,
            };
            if let Some(outcome) = fused {
                return outcome;
            }
        }
        self.innovate_into(predicted, z, h, r, &mut work.innov)?;
        let decision = match policy {
            None => Decision::Accept,
            Some(p) => p.decide(&work.innov.view(r)),
        };
        self.apply_decision(Some(predicted), &work.innov, decision, r, &mut work.gain)
    }
}

impl<N: Dim> KalmanFilter<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// [`update_onto`](Self::update_onto) accepting the update (no
    /// policy), Joseph form, for `M` = `Const<C>`: the innovation, gain, x⁺
    /// and P⁺ (into the filter) in one dispatch ([`dense::accepted_update`],
    /// the same operations in the same order, the same errors), the
    /// residual z − H x⁻ by nalgebra first as in
    /// [`innovate_into`](Self::innovate_into). None (nothing done) where
    /// the kernels do not serve the size: more than
    /// [`dense::MAX_FUSED_STATES`] states. In line: called (not inlined)
    /// it returned its result through memory written field by field, which
    /// the caller then read in wider loads, and a load that spans several
    /// stores waits for them to be written to the cache, behind the
    /// kernel's stores of P⁺ (about 2 % of a 9/3 batch epoch).
    #[inline(always)]
    fn accept_fused<M: Dim, const C: usize>(
        &mut self,
        predicted: &OMatrix<f64, N, N>,
        (z, h, r): Measured<'_, N, M>,
        work: &mut UpdateWork<N, M>,
    ) -> Option<Result<Outcome>>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        let n = self.dim();
        if n > dense::MAX_FUSED_STATES || C > dense::MAX_GAIN_SOLVE {
            return None;
        }
        let step = Step::Update;
        let innov = &mut work.innov;
        innov.residual = z - h * &self.x;
        let mut factor = innov.s.clone();
        let (nis, status) = dense::accepted_update::<N, C>(
            predicted.shape_generic().0,
            (self.p.as_mut_slice(), innov.cross.as_mut_slice()),
            (
                predicted.as_slice(),
                h.as_slice(),
                r.as_slice(),
                innov.residual.as_slice(),
            ),
            self.x.as_mut_slice(),
            innov.hph.as_mut_slice(),
            innov.s.as_mut_slice(),
            factor.as_mut_slice(),
            work.gain.as_mut_slice(),
        );
        let matrix = match status {
            dense::AcceptedStatus::Applied => {
                innov.chol = Cholesky::pack_dirty(factor);
                innov.nis = nis;
                return Some(Ok(Outcome::Accepted));
            }
            dense::AcceptedStatus::SNotPositiveDefinite => {
                return Some(Err(EstimationError::NotPositiveDefinite {
                    step,
                    matrix: Matrix::S,
                }));
            }
            dense::AcceptedStatus::GainNonFinite => Matrix::K,
            dense::AcceptedStatus::StateNonFinite => Matrix::X,
            dense::AcceptedStatus::CovarianceNonFinite => Matrix::P,
        };
        Some(Err(EstimationError::NonFinite { step, matrix }))
    }
}

/// A measurement and its model: z, H and R.
pub(crate) type Measured<'a, N, M> = (
    &'a OVector<f64, M>,
    &'a OMatrix<f64, M, N>,
    &'a OMatrix<f64, M, M>,
);

/// What the batch's update of one measurement size reuses from epoch to
/// epoch: the innovation and the gain, written in place (an update record
/// moved through the calls was several copies of them per epoch).
pub(crate) struct UpdateWork<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    innov: Innovated<N, M>,
    gain: OMatrix<f64, N, M>,
}

impl<N: Dim, M: Dim> UpdateWork<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Zeros for n states and m measurements.
    pub(crate) fn zeros(nd: N, md: M) -> Self {
        Self {
            innov: Innovated::zeros(nd, md),
            gain: OMatrix::zeros_generic(nd, md),
        }
    }

    /// Its number of measurement components.
    pub(crate) fn measurements(&self) -> usize {
        self.innov.residual.len()
    }

    /// A record's innovation and gain put into this work, its outcome
    /// returned (the batch's updates that return a record).
    pub(crate) fn take(&mut self, rec: UpdateRecord<N, M>) -> Outcome {
        self.innov.residual = rec.residual;
        self.innov.s = rec.s;
        self.innov.nis = rec.nis;
        self.gain = rec.gain;
        rec.outcome
    }

    /// ν = z − H x⁻.
    pub(crate) fn residual(&self) -> &OVector<f64, M> {
        &self.innov.residual
    }

    /// S = H P⁻ Hᵀ + R.
    pub(crate) fn s(&self) -> &OMatrix<f64, M, M> {
        &self.innov.s
    }

    /// The gain applied (zero when rejected).
    pub(crate) fn gain(&self) -> &OMatrix<f64, N, M> {
        &self.gain
    }

    /// The NIS.
    pub(crate) fn nis(&self) -> f64 {
        self.innov.nis
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Const, DMatrix, DVector, SMatrix, SVector};

    /// Values uniform in [−1, 1) from a 64-bit linear congruential stream
    /// seeded with `seed` (the same values on every platform).
    fn uniform_stream(mut seed: u64) -> impl FnMut() -> f64 {
        move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        }
    }

    /// `factor` and `normalised_square` give nalgebra's Cholesky factor
    /// (all of it: the upper triangle too) and NIS bit for bit at every
    /// fixed size they serve and a run-time size, and refuse what
    /// nalgebra refuses (a zero, negative or NaN pivot).
    #[test]
    fn the_fixed_size_factor_and_nis_equal_nalgebras_bit_for_bit() {
        let mut next = uniform_stream(977_u64);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        fn case<const M: usize>(
            next: &mut impl FnMut() -> f64,
            bits: &impl Fn(&[f64]) -> Vec<u64>,
        ) {
            for round in 0..40 {
                let a = SMatrix::<f64, M, M>::from_fn(|_, _| next());
                let mut s = a * a.transpose() + SMatrix::<f64, M, M>::identity() * 0.1;
                if round % 10 == 9 {
                    // Not positive definite: a zero, negative or NaN pivot.
                    s[(M - 1, M - 1)] = [0.0, -1.0, f64::NAN][round % 3];
                }
                let residual = SVector::<f64, M>::from_fn(|_, _| next());
                let ours = factor::<Const<M>>(&s);
                let theirs = Cholesky::new(s);
                assert_eq!(ours.is_some(), theirs.is_some(), "{M}, round {round}");
                if let (Some(ours), Some(theirs)) = (ours, theirs) {
                    assert_eq!(
                        bits(ours.l_dirty().as_slice()),
                        bits(theirs.l_dirty().as_slice())
                    );
                    let nis = normalised_square(&ours, &residual);
                    let expected = residual.dot(&theirs.solve(&residual));
                    assert_eq!(nis.to_bits(), expected.to_bits(), "{M}, round {round}");
                }
            }
        }
        case::<1>(&mut next, &bits);
        case::<2>(&mut next, &bits);
        case::<3>(&mut next, &bits);
        case::<4>(&mut next, &bits);
        case::<5>(&mut next, &bits);
        case::<6>(&mut next, &bits);
        // Run-time sized: nalgebra's own path.
        let a = DMatrix::from_fn(4, 4, |_, _| next());
        let s = &a * a.transpose() + DMatrix::identity(4, 4);
        let residual = DVector::from_fn(4, |_, _| next());
        let ours = factor(&s).unwrap();
        let theirs = Cholesky::new(s).unwrap();
        assert_eq!(
            bits(ours.l_dirty().as_slice()),
            bits(theirs.l_dirty().as_slice())
        );
        assert_eq!(
            normalised_square(&ours, &residual).to_bits(),
            residual.dot(&theirs.solve(&residual)).to_bits()
        );
    }
    /// The batch's fused accepted update (no policy: one dispatch) equals
    /// the update through the policy path (`AcceptAll`: the innovation,
    /// gain and Joseph form in separate steps) bit for bit — x⁺, P⁺, ν, S,
    /// K, the NIS — and fails with the same error leaving the same filter
    /// (S not positive definite, P⁺ overflowing), at every measurement
    /// size it serves, on fixed-size and run-time sized filters.
    #[test]
    fn the_fused_accepted_update_equals_the_stepwise_update_bit_for_bit() {
        let mut next = uniform_stream(4242_u64);
        fn case<N: Dim, const M: usize>(nd: N, next: &mut impl FnMut() -> f64)
        where
            DefaultAllocator: FilterAllocator<N, Const<M>>,
        {
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let n = nd.value();
            let md = Const::<M>;
            for round in 0..12 {
                let a = OMatrix::<f64, N, N>::from_fn_generic(nd, nd, |_, _| next());
                let mut predicted =
                    &a * a.transpose() + OMatrix::<f64, N, N>::identity_generic(nd, nd);
                // Sparse rows as a navigation H, with an exact zero column.
                let h = OMatrix::<f64, Const<M>, N>::from_fn_generic(md, nd, |i, j| {
                    if j == 0 || (i + j) % 3 == 0 {
                        0.0
                    } else {
                        next()
                    }
                });
                let mut r = OMatrix::<f64, Const<M>, Const<M>>::from_fn_generic(md, md, |i, j| {
                    if i == j { 0.5 } else { 0.01 }
                });
                let z = OVector::<f64, Const<M>>::from_fn_generic(md, nalgebra::U1, |_, _| next());
                match round {
                    // S not positive definite.
                    10 => r[(M - 1, M - 1)] = -1e9,
                    // Values near overflow: P⁺ or the gain may not be
                    // finite (the same error either way).
                    11 => predicted *= 1e307,
                    _ => {}
                }
                let x0 = OVector::<f64, N>::from_fn_generic(nd, nalgebra::U1, |_, _| next());
                let prior = KalmanFilter::new(x0, OMatrix::identity_generic(nd, nd)).unwrap();
                let (mut fused, mut stepwise) = (prior.clone(), prior);
                let mut fused_work = UpdateWork::zeros(nd, md);
                let mut stepwise_work = UpdateWork::zeros(nd, md);
                let ours = fused.update_prechecked_from(
                    &predicted,
                    (&z, &h, &r),
                    None::<&mut AcceptAll>,
                    &mut fused_work,
                );
                let theirs = stepwise.update_prechecked_from(
                    &predicted,
                    (&z, &h, &r),
                    Some(&mut AcceptAll),
                    &mut stepwise_work,
                );
                let what = format!("{n}/{M}, round {round}");
                assert_eq!(ours, theirs, "{what}");
                assert_eq!(
                    bits(fused.x.as_slice()),
                    bits(stepwise.x.as_slice()),
                    "{what}"
                );
                assert_eq!(
                    bits(fused.p.as_slice()),
                    bits(stepwise.p.as_slice()),
                    "{what}"
                );
                if ours.is_ok() {
                    for (a, b) in [
                        (
                            fused_work.residual().as_slice(),
                            stepwise_work.residual().as_slice(),
                        ),
                        (fused_work.s().as_slice(), stepwise_work.s().as_slice()),
                        (
                            fused_work.gain().as_slice(),
                            stepwise_work.gain().as_slice(),
                        ),
                    ] {
                        assert_eq!(bits(a), bits(b), "{what}");
                    }
                    assert_eq!(fused_work.nis().to_bits(), stepwise_work.nis().to_bits());
                } else {
                    assert!(round >= 10, "{what}: {ours:?}");
                }
                if round == 10 {
                    assert!(ours.is_err(), "{what}");
                }
            }
        }
        case::<Const<9>, 1>(Const::<9>, &mut next);
        case::<Const<9>, 2>(Const::<9>, &mut next);
        case::<Const<9>, 3>(Const::<9>, &mut next);
        case::<Const<15>, 4>(Const::<15>, &mut next);
        case::<Const<6>, 5>(Const::<6>, &mut next);
        case::<Const<21>, 6>(Const::<21>, &mut next);
        case::<Const<24>, 3>(Const::<24>, &mut next);
        case::<Dyn, 3>(Dyn(7), &mut next);
        case::<Dyn, 6>(Dyn(13), &mut next);
    }
    /// The batch's fused time update with P⁻ aside (one dispatch) equals
    /// `predict_prechecked` bit for bit — x⁻, P⁻ — and fails with the same
    /// error leaving the same state (x⁻ overflowing, P⁻ overflowing), on
    /// fixed-size and run-time sized filters.
    #[test]
    fn the_fused_prediction_aside_equals_the_checked_prediction_bit_for_bit() {
        let mut next = uniform_stream(99_u64);
        fn case<N: Dim>(nd: N, next: &mut impl FnMut() -> f64)
        where
            DefaultAllocator: Allocator<N> + Allocator<N, N>,
        {
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let n = nd.value();
            for round in 0..6 {
                let a = OMatrix::<f64, N, N>::from_fn_generic(nd, nd, |_, _| next());
                let p0 = &a * a.transpose() + OMatrix::<f64, N, N>::identity_generic(nd, nd);
                let mut phi = OMatrix::<f64, N, N>::from_fn_generic(nd, nd, |i, j| {
                    if i == j { 1.0 } else { 0.1 * next() }
                });
                let q = OMatrix::<f64, N, N>::identity_generic(nd, nd) * 1e-3;
                let mut x0 = OVector::<f64, N>::from_fn_generic(nd, nalgebra::U1, |_, _| next());
                match round {
                    // x⁻ overflows (and P⁻ would).
                    4 => {
                        phi *= 1e200;
                        x0 *= 1e200;
                    }
                    // P⁻ overflows, x⁻ does not.
                    5 => phi *= 1e160,
                    _ => {}
                }
                let prior = KalmanFilter::new(x0, p0).unwrap();
                let (mut fused, mut checked) = (prior.clone(), prior);
                let mut predicted = OMatrix::<f64, N, N>::from_element_generic(nd, nd, f64::NAN);
                let mut phi_p = predicted.clone();
                // P from `new`, symmetrised: symmetric bit for bit.
                let ours =
                    fused.predict_prechecked_aside(&phi, &q, (&mut predicted, &mut phi_p), true);
                let theirs = checked.predict_prechecked(&phi, &q);
                let what = format!("n {n}, round {round}");
                assert_eq!(ours, theirs, "{what}");
                assert_eq!(
                    bits(fused.x.as_slice()),
                    bits(checked.x.as_slice()),
                    "{what}"
                );
                match round {
                    4 | 5 => assert!(ours.is_err(), "{what}"),
                    _ => assert_eq!(
                        bits(predicted.as_slice()),
                        bits(checked.p.as_slice()),
                        "{what}"
                    ),
                }
                if round == 5 {
                    assert_eq!(
                        ours,
                        Err(EstimationError::NonFinite {
                            step: Step::Predict,
                            matrix: Matrix::P
                        })
                    );
                }
            }
        }
        case(Const::<3>, &mut next);
        case(Const::<5>, &mut next);
        case(Const::<9>, &mut next);
        case(Const::<21>, &mut next);
        case(Const::<24>, &mut next);
        case(Dyn(9), &mut next);
        case(Dyn(11), &mut next);
        case(Dyn(40), &mut next);
    }
}
