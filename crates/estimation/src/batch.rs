//! A whole measurement sequence through one filter in one call: for each
//! epoch predict with (Φ, Q), then update with the components of the
//! epoch's measurement that are present (NaN: missing) under a policy. The
//! loop a caller outside Rust would otherwise write epoch by epoch (the
//! Python package's batch call); [`LinearGaussianModel::run`](crate::LinearGaussianModel::run)
//! is the same loop with records for observers.

use nalgebra::{
    Cholesky, Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix,
    SVector, allocator::Allocator,
};

use crate::check;
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::{FilterAllocator, KalmanFilter, UpdateWork};
use crate::policy::{AcceptAll, Decision, InnovationView, MeasurementPolicy, Outcome};
use crate::smoother::ForwardEpoch;

/// What to keep per epoch besides the state, the innovation, the NIS and
/// the outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BatchKeep {
    /// The filtered covariance of every epoch.
    pub covariance: bool,
    /// The forward pass for [`rts_smooth`](crate::rts_smooth).
    pub forward: bool,
}

/// Per-epoch results of [`filter_batch`]; matrices row-major, one row per
/// epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchOutput<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Filtered states, epochs × n.
    pub states: Vec<f64>,
    /// Filtered covariances, epochs × n × n (with [`BatchKeep::covariance`]).
    pub covariances: Vec<f64>,
    /// Innovations ν = z − H x⁻, epochs × m (NaN where missing).
    pub residuals: Vec<f64>,
    /// NIS (NaN at an epoch without a measurement).
    pub nis: Vec<f64>,
    /// What the policy decided ([`Outcome::Missing`] without a measurement).
    pub outcomes: Vec<Outcome>,
    /// The forward pass (with [`BatchKeep::forward`]).
    pub forward: Vec<ForwardEpoch<N>>,
    /// Epochs computed in the steady state: once an accepted update leaves
    /// P⁺ bit for bit as that of one of the last [`MAX_STEADY_PERIOD`]
    /// epochs with the same components present (a fixed point, or a cycle
    /// of up to that many covariances), the later epochs with the same
    /// components present and an accepted update repeat the cycle's P⁻, S,
    /// K and P⁺, and only the state is computed (bit for bit the full
    /// step's numbers). Any other epoch (a component missing, an update
    /// rejected or changed by the policy) takes the full step.
    pub steady_epochs: usize,
}

/// Largest number of measurement components an epoch's update runs in
/// fixed-size code (`Const<c>` matrices for the c components present): the
/// selected rows of H and R are copied into stack matrices, so an epoch
/// allocates nothing when the filter is of fixed size. Larger updates take
/// run-time sized matrices.
pub const MAX_FIXED_MEASUREMENT: usize = 6;

/// Run `kf` over `epochs` measurement rows of `m` values each (`z`,
/// row-major, NaN marking a missing component): at every epoch predict
/// with (Φ, Q) — except the first when `predict_first` is false, the prior
/// then being the first epoch's — and update with the components present
/// (rows of H and rows/columns of R selected) under `policy`; an epoch with
/// none is a prediction only (`policy.missing()` is told). Errors carry the
/// epoch.
/// The filter may be of fixed size (`N = Const<n>`) or run-time sized;
/// up to [`MAX_FIXED_MEASUREMENT`] components present, the update runs in
/// fixed-size matrices (the policy sees the innovation as run-time sized
/// copies, a few small allocations per epoch; [`filter_batch_plain`] has
/// none).
#[allow(clippy::too_many_arguments)]
pub fn filter_batch<N: Dim, P: MeasurementPolicy<Dyn> + ?Sized>(
    kf: &mut KalmanFilter<N>,
    phi: &OMatrix<f64, N, N>,
    q: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, Dyn, N>,
    r: &DMatrix<f64>,
    z: &[f64],
    predict_first: bool,
    policy: &mut P,
    keep: BatchKeep,
) -> Result<BatchOutput<N>>
where
    DefaultAllocator: FixedBatchAllocator<N>,
{
    run_batch(
        kf,
        phi,
        q,
        h,
        r,
        z,
        predict_first,
        &mut BatchPolicy::Given(policy),
        keep,
    )
}

/// [`filter_batch`] accepting every measurement (the plain Kalman filter):
/// with a fixed-size filter and at most [`MAX_FIXED_MEASUREMENT`]
/// components present, an epoch allocates nothing.
#[allow(clippy::too_many_arguments)]
pub fn filter_batch_plain<N: Dim>(
    kf: &mut KalmanFilter<N>,
    phi: &OMatrix<f64, N, N>,
    q: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, Dyn, N>,
    r: &DMatrix<f64>,
    z: &[f64],
    predict_first: bool,
    keep: BatchKeep,
) -> Result<BatchOutput<N>>
where
    DefaultAllocator: FixedBatchAllocator<N>,
{
    run_batch::<N, AcceptAll>(
        kf,
        phi,
        q,
        h,
        r,
        z,
        predict_first,
        &mut BatchPolicy::Accept,
        keep,
    )
}

/// The allocations the batch needs for an n-state filter: every
/// measurement size up to [`MAX_FIXED_MEASUREMENT`] and run-time sized.
pub trait FixedBatchAllocator<N: Dim>:
    FilterAllocator<N, Dyn>
    + FilterAllocator<N, Const<1>>
    + FilterAllocator<N, Const<2>>
    + FilterAllocator<N, Const<3>>
    + FilterAllocator<N, Const<4>>
    + FilterAllocator<N, Const<5>>
    + FilterAllocator<N, Const<6>>
{
}

impl<N: Dim, A> FixedBatchAllocator<N> for A where
    A: FilterAllocator<N, Dyn>
        + FilterAllocator<N, Const<1>>
        + FilterAllocator<N, Const<2>>
        + FilterAllocator<N, Const<3>>
        + FilterAllocator<N, Const<4>>
        + FilterAllocator<N, Const<5>>
        + FilterAllocator<N, Const<6>>
{
}

/// The batch's policy: none (accept all, no conversion) or a run-time
/// sized one, shown fixed-size innovations through [`AsDyn`].
enum BatchPolicy<'a, P: ?Sized> {
    Accept,
    Given(&'a mut P),
}

/// A run-time sized policy deciding on a fixed-size update: the innovation
/// is copied into run-time sized matrices for it (the same numbers), its
/// decision copied back.
struct AsDyn<'a, P: ?Sized>(&'a mut P);

impl<const C: usize, P: MeasurementPolicy<Dyn> + ?Sized> MeasurementPolicy<Const<C>>
    for AsDyn<'_, P>
{
    fn decide(&mut self, view: &InnovationView<'_, Const<C>>) -> Decision<Const<C>> {
        let residual = DVector::from_column_slice(view.residual.as_slice());
        let hph = DMatrix::from_column_slice(C, C, view.hph.as_slice());
        let r = DMatrix::from_column_slice(C, C, view.r.as_slice());
        let s = DMatrix::from_column_slice(C, C, view.s.as_slice());
        let decision = self.0.decide(&InnovationView {
            residual: &residual,
            hph: &hph,
            r: &r,
            s: &s,
            nis: view.nis,
        });
        // A decision of another size than the innovation's is refused by
        // the update's shape check, as the run-time sized path refuses it:
        // here it is passed on as a non-finite replacement, refused too.
        let vector = |v: DVector<f64>| {
            if v.len() == C {
                SVector::<f64, C>::from_column_slice(v.as_slice())
            } else {
                SVector::<f64, C>::repeat(f64::NAN)
            }
        };
        let square = |m: DMatrix<f64>| {
            if m.shape() == (C, C) {
                SMatrix::<f64, C, C>::from_column_slice(m.as_slice())
            } else {
                SMatrix::<f64, C, C>::repeat(f64::NAN)
            }
        };
        match decision {
            Decision::Accept => Decision::Accept,
            Decision::Reject => Decision::Reject,
            Decision::ReplaceResidual(v) => Decision::ReplaceResidual(vector(v)),
            Decision::InflateR(f) => Decision::InflateR(f),
            Decision::GainCovariance(c) => Decision::GainCovariance(square(c)),
            Decision::LimitWithGainCovariance {
                residual,
                covariance,
            } => Decision::LimitWithGainCovariance {
                residual: vector(residual),
                covariance: square(covariance),
            },
        }
    }

    fn missing(&mut self) {
        self.0.missing();
    }
}

/// Longest cycle of the Riccati recursion the batch looks for: P⁺ may
/// settle, bit for bit, not on a fixed point but on a short cycle (the
/// rounding of one step undone by the next: the 6-state model of
/// bench/filterpy_step.py, with the tests' P₀, ends in a cycle of two
/// covariances).
pub const MAX_STEADY_PERIOD: usize = 4;

/// One epoch of a steady cycle: what the full step computes from the
/// cycle's previous covariance.
struct Phase<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// P⁻ = Φ P⁺ Φᵀ + Q of the previous phase's P⁺.
    p_predicted: OMatrix<f64, N, N>,
    /// H P⁻ Hᵀ (for a policy's view).
    hph: OMatrix<f64, M, M>,
    /// S = H P⁻ Hᵀ + R.
    s: OMatrix<f64, M, M>,
    /// Cholesky factor of S (for the NIS).
    chol: Cholesky<f64, M>,
    /// The gain K.
    gain: OMatrix<f64, N, M>,
    /// P⁺ after this phase's accepted update.
    p_filtered: OMatrix<f64, N, N>,
}

/// The steady state of the Riccati recursion for one set of components
/// present: a cycle of p ≤ [`MAX_STEADY_PERIOD`] covariances that p
/// predicts + accepted updates map back to the first, bit for bit (p = 1:
/// a fixed point). The recursion being deterministic, every later epoch
/// with the same components present and an accepted update has the P⁻, S,
/// K and P⁺ of its phase of the cycle, so only the state is computed there
/// (x ← Φ x, x ← x + K (z − H x)): the full step's numbers, bit for bit,
/// without its covariance work.
struct Steady<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// The components present (indices into the measurement row).
    present: Vec<usize>,
    /// The rows of H present.
    h: OMatrix<f64, M, N>,
    /// The rows and columns of R present.
    r: OMatrix<f64, M, M>,
    /// The cycle, in order; the last phase's P⁺ is the first one's input.
    phases: Vec<Phase<N, M>>,
    /// (k, j): epoch k left the filter's covariance on the cycle, epoch
    /// k + 1 being phase j.
    current: Option<(usize, usize)>,
}

impl<N: Dim, M: Dim> Steady<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// The phase of epoch `k` when the filter (covariance `p`) is on the
    /// cycle: the one after the phase the previous epoch computed, or
    /// after the phase whose P⁺ `p` is (a full step came back to it).
    fn phase_of(&self, k: usize, p: &OMatrix<f64, N, N>) -> Option<usize> {
        let period = self.phases.len();
        match self.current {
            Some((after, next)) if k > 0 && after == k - 1 => Some(next),
            _ => self
                .phases
                .iter()
                .position(|ph| same_bits(p, &ph.p_filtered))
                .map(|j| (j + 1) % period),
        }
    }
}

/// What the batch keeps for the updates of one size (`M` components
/// present): the steady state, the rows of H and R last selected and the
/// update's reused innovation and gain.
struct SizeState<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    steady: Option<Steady<N, M>>,
    /// The components present at the last full step of this size and the
    /// rows of H and of R (and columns) selected for them: selected again
    /// only when the components change.
    selected: Option<SelectedRows<N, M>>,
    /// Made at the first update of this size (of another number of
    /// components, for `Dyn`: made again).
    work: Option<UpdateWork<N, M>>,
}

impl<N: Dim, M: Dim> SizeState<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    fn new() -> Self {
        Self {
            steady: None,
            selected: None,
            work: None,
        }
    }
}

/// The components present and the rows of H and of R (and columns)
/// selected for them.
type SelectedRows<N, M> = (Vec<usize>, OMatrix<f64, M, N>, OMatrix<f64, M, M>);

/// Whether two lists of components present are the same, compared in
/// line: `==` on slices of integers calls memcmp, about 2 % of a 9-state
/// epoch for lists of a few indices compared three times an epoch.
#[inline(always)]
fn same_components(a: &[usize], b: &[usize]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x == y)
}

/// Whether two matrices hold the same bits (not `==`: 0.0 and −0.0 differ
/// here, and a NaN equals itself).
fn same_bits<R: Dim, C: Dim>(a: &OMatrix<f64, R, C>, b: &OMatrix<f64, R, C>) -> bool
where
    DefaultAllocator: Allocator<R, C>,
{
    same_bit_slices(a.as_slice(), b.as_slice())
}

/// [`same_bits`] on two slices of one length.
#[inline(always)]
fn same_bit_slices(a: &[f64], b: &[f64]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The covariances after the last epochs of a run of full steps with the
/// same components present, each predicted and accepted: a P⁺ equal to
/// one of them, bit for bit, closes a cycle of the recursion.
struct Recent<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// The components present in the run.
    present: Vec<usize>,
    /// P⁺ of the run's last epochs (up to [`MAX_STEADY_PERIOD`]), a ring
    /// that starts at slot 0 with each run: held in place (not behind a
    /// pointer), so that it sits in the batch's page-aligned work block
    /// ([`BatchWork`]).
    covariances: [OMatrix<f64, N, N>; MAX_STEADY_PERIOD],
    /// How many of `covariances` belong to the run: the first `len` slots.
    len: usize,
    /// The slot of the next P⁺.
    next: usize,
}

impl<N: Dim> Recent<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// An empty ring of covariances shaped as `p` (their values are
    /// written before they are read).
    fn new(p: &OMatrix<f64, N, N>) -> Self {
        Self {
            present: Vec::new(),
            covariances: std::array::from_fn(|_| p.clone()),
            len: 0,
            next: 0,
        }
    }

    /// The run is broken (a gap, a rejected or changed update, a steady
    /// epoch): forget it.
    fn reset(&mut self) {
        self.len = 0;
        self.next = 0;
    }

    /// Epoch's P⁺ `p` after a predicted, accepted full step with the
    /// components `present`: whether it closes a cycle (equals the P⁺ of
    /// one of the run's last epochs); then recorded.
    fn closes_cycle(&mut self, present: &[usize], p: &OMatrix<f64, N, N>) -> bool {
        if self.len == 0 || !same_components(&self.present, present) {
            self.present.clear();
            self.present.extend_from_slice(present);
            self.reset();
        }
        // The run's P⁺ are the first `len` slots (the ring restarts with
        // each run), compared in slot order (whether any equals p: the
        // order does not matter), without the ring's index arithmetic and
        // its bounds checks per slot.
        let values = p.as_slice();
        let closes = self.covariances[..self.len]
            .iter()
            .any(|c| same_bit_slices(values, c.as_slice()));
        self.covariances[self.next]
            .as_mut_slice()
            .copy_from_slice(values);
        self.next = (self.next + 1) % MAX_STEADY_PERIOD;
        self.len = (self.len + 1).min(MAX_STEADY_PERIOD);
        closes
    }
}

/// The model of a batch and what the loop keeps between epochs. Laid out
/// in declaration order (`repr(C)`), the matrices every full step writes
/// and reads first: in [`BatchWork`] they start at the beginning of a
/// page, and at 9 states none of them crosses into the next one.
#[repr(C)]
struct BatchModel<'a, N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Scratch for Φ P in the prediction.
    phi_p: OMatrix<f64, N, N>,
    /// P⁻ of the full step with its constants checked once: the
    /// prediction writes it here and the update P⁺ from it into the
    /// filter, so that neither copies P.
    p_predicted: OMatrix<f64, N, N>,
    /// Φ, copied into the work block.
    phi: OMatrix<f64, N, N>,
    h: &'a OMatrix<f64, Dyn, N>,
    r: &'a DMatrix<f64>,
    keep: BatchKeep,
    /// Q as the prediction uses it ((Q + Qᵀ)/2 unless exactly symmetric)
    /// when Φ, Q, H and R passed their checks once for the batch (shapes,
    /// finite, Q symmetric, R exactly symmetric: every selection of its
    /// rows and columns then passes the update's check too): the epochs
    /// then skip the checks of these constants. None: every epoch checks
    /// them, and names the epoch where one fails.
    q_symmetric: Option<OMatrix<f64, N, N>>,
    q: &'a OMatrix<f64, N, N>,
    /// False once the steady path's arithmetic disagreed with the full
    /// step's (it never has; a change to the step's arithmetic would
    /// switch the steady path off rather than change a result).
    steady_allowed: bool,
    /// Epochs computed in the steady state.
    steady_epochs: usize,
    /// The current run of full steps (to find a cycle).
    recent: Recent<N>,
    /// The filter's P is symmetric bit for bit: checked once, at the
    /// start; every P an epoch gives the filter then is too (the time
    /// update and the Joseph form mirror their lower triangle, the standard
    /// form symmetrises, a steady phase's P⁺ was computed so).
    p_symmetric: bool,
}

impl<N: Dim> BatchModel<'_, N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// The prediction of the full step, its constants' checks skipped
    /// when they passed once for the batch.
    fn predict(&self, kf: &mut KalmanFilter<N>) -> Result<()> {
        match &self.q_symmetric {
            Some(q) => kf.predict_prechecked(&self.phi, q),
            None => kf.predict(&self.phi, self.q),
        }
    }
}

/// Q as the prediction uses it when Φ, Q, H and R pass the checks every
/// epoch would make of them (see [`BatchModel::q_symmetric`]); None
/// otherwise (or with R not exactly symmetric: a selection of its rows and
/// columns is checked against its own largest element).
fn prechecked<N: Dim>(
    phi: &OMatrix<f64, N, N>,
    q: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, Dyn, N>,
    r: &DMatrix<f64>,
    n: usize,
) -> Option<OMatrix<f64, N, N>>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    let shapes = phi.shape() == (n, n)
        && q.shape() == (n, n)
        && h.ncols() == n
        && r.shape() == (h.nrows(), h.nrows());
    let finite = check::all_finite(phi.as_slice())
        && check::all_finite(q.as_slice())
        && check::all_finite(h.as_slice())
        && check::all_finite(r.as_slice());
    if !(shapes && finite) || check::symmetric(r, Step::Update, Matrix::R) != Ok(true) {
        return None;
    }
    check::process_noise(q, n).ok()
}

/// One epoch's update and what it reports.
struct EpochUpdate<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    nis: f64,
    outcome: Outcome,
    /// (x⁻, P⁻), with [`BatchKeep::forward`] (boxed: an epoch's result
    /// is moved a few times, and without the forward pass it is None).
    predicted: Option<Box<Prediction<N>>>,
}

/// A prediction (x⁻, P⁻).
type Prediction<N> = (OVector<f64, N>, OMatrix<f64, N, N>);

/// An epoch's measurement and the rows of H and of R (and columns) of its
/// components present.
type Selected<N, M> = (OVector<f64, M>, OMatrix<f64, M, N>, OMatrix<f64, M, M>);

/// Predict (when `predict`) and update with the `present` components of
/// `row` in `M`-sized matrices (`md`): in the steady state of `steady`
/// when the filter is on its cycle, else by the full step (finding the
/// steady state when this epoch's P⁺ closes a cycle). Writes the
/// residuals of the components present into `residuals`.
#[allow(clippy::too_many_arguments)]
fn update_epoch<N: Dim, M: Dim, Pol: MeasurementPolicy<M> + ?Sized>(
    kf: &mut KalmanFilter<N>,
    model: &mut BatchModel<'_, N>,
    md: M,
    (k, row, present, predict): (usize, &[f64], &[usize], bool),
    mut policy: Option<&mut Pol>,
    sized: &mut SizeState<N, M>,
    residuals: &mut [f64],
) -> Result<EpochUpdate<N>>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let SizeState {
        steady,
        selected,
        work,
    } = sized;
    let z = OVector::<f64, M>::from_fn_generic(md, nalgebra::U1, |i, _| row[present[i]]);
    let phase = if predict && model.steady_allowed {
        steady
            .as_ref()
            .filter(|st| same_components(&st.present, present))
            .and_then(|st| st.phase_of(k, kf.covariance()))
    } else {
        None
    };
    if let (Some(j), Some(st)) = (phase, steady.as_mut()) {
        model.recent.reset();
        let ph = &st.phases[j];
        // The full step's arithmetic on the state (kalman.rs: predict_state,
        // innovation, apply), the covariance work skipped.
        if model.q_symmetric.is_some() {
            kf.predict_state_prechecked(&model.phi)?;
        } else {
            kf.predict_state(&model.phi)?;
        }
        let predicted = model
            .keep
            .forward
            .then(|| Box::new((kf.state().clone(), ph.p_predicted.clone())));
        check::finite(&z, Step::Update, Matrix::Z)?;
        let residual = &z - &st.h * kf.state();
        let nis = residual.dot(&ph.chol.solve(&residual));
        let decision = match policy.as_deref_mut() {
            None => Decision::Accept,
            Some(p) => p.decide(&InnovationView {
                residual: &residual,
                hph: &ph.hph,
                r: &st.r,
                s: &ph.s,
                nis,
            }),
        };
        if matches!(decision, Decision::Accept) {
            let mut x = kf.state().clone();
            x += &ph.gain * &residual;
            check::finite(&x, Step::Update, Matrix::X)?;
            kf.set_state(x)?;
            if st.phases.len() > 1 {
                kf.set_covariance_computed(&ph.p_filtered);
            }
            for (j, &i) in present.iter().enumerate() {
                residuals[i] = residual[j];
            }
            st.current = Some((k, (j + 1) % st.phases.len()));
            model.steady_epochs += 1;
            return Ok(EpochUpdate {
                nis,
                outcome: Outcome::Accepted,
                predicted,
            });
        }
        // Rejected, limited, re-weighted...: the full step, its covariance
        // prediction made now (from the same P⁺, so the same P⁻) and the
        // decision already taken replayed.
        st.current = None;
        kf.predict_covariance(&model.phi, model.q)?;
        let predicted = model
            .keep
            .forward
            .then(|| Box::new((kf.state().clone(), kf.covariance().clone())));
        let rec = kf.update_decided(&z, &st.h, &st.r, decision)?;
        for (j, &i) in present.iter().enumerate() {
            residuals[i] = rec.residual[j];
        }
        return Ok(EpochUpdate {
            nis: rec.nis,
            outcome: rec.outcome,
            predicted,
        });
    }
    // The full step.
    let (_, nd) = model.h.shape_generic();
    if selected
        .as_ref()
        .is_some_and(|(last, _, _)| !same_components(last, present))
    {
        *selected = None;
    }
    let (_, hc, rc) = selected.get_or_insert_with(|| {
        let hc = OMatrix::<f64, M, N>::from_fn_generic(md, nd, |i, j| model.h[(present[i], j)]);
        let rc =
            OMatrix::<f64, M, M>::from_fn_generic(md, md, |i, j| model.r[(present[i], present[j])]);
        (present.to_vec(), hc, rc)
    });
    let (hc, rc) = (&*hc, &*rc);
    // With the constants checked once, P⁻ is kept aside (model.p_predicted)
    // between the prediction and the update.
    let aside = predict && model.q_symmetric.is_some();
    match &model.q_symmetric {
        Some(q) if aside => kf.predict_prechecked_aside(
            &model.phi,
            q,
            (&mut model.p_predicted, &mut model.phi_p),
            model.p_symmetric,
        )?,
        _ if predict => model.predict(kf)?,
        _ => {}
    }
    let x_predicted = kf.state().clone();
    let predicted = model.keep.forward.then(|| {
        let p_predicted = if aside {
            &model.p_predicted
        } else {
            kf.covariance()
        };
        Box::new((x_predicted.clone(), p_predicted.clone()))
    });
    if work
        .as_ref()
        .is_some_and(|w| w.measurements() != md.value())
    {
        *work = None;
    }
    let work = work.get_or_insert_with(|| UpdateWork::zeros(nd, md));
    let outcome = match (&model.q_symmetric, policy) {
        (Some(_), policy) if aside => {
            kf.update_prechecked_from(&model.p_predicted, (&z, hc, rc), policy, work)?
        }
        (Some(_), policy) => work.take(kf.update_prechecked(&z, hc, rc, policy)?),
        (None, None) => work.take(kf.update_with(&z, hc, rc, &mut AcceptAll)?),
        (None, Some(p)) => work.take(kf.update_with(&z, hc, rc, p)?),
    };
    for (j, &i) in present.iter().enumerate() {
        residuals[i] = work.residual()[j];
    }
    if predict && model.steady_allowed && outcome == Outcome::Accepted {
        if model.recent.closes_cycle(present, kf.covariance()) {
            let selection = (z, hc.clone(), rc.clone());
            *steady = find_steady(kf, model, selection, &x_predicted, work, present, k);
            if steady.is_some() {
                model.recent.reset();
            }
        }
    } else {
        model.recent.reset();
    }
    Ok(EpochUpdate {
        nis: work.nis(),
        outcome,
        predicted,
    })
}

/// The steady state found at epoch `k`, whose accepted update (`work`) left
/// P⁺ equal to that of one of the last few epochs of a run with the same
/// components present: the cycle from P⁺, followed by a probe filter
/// (predict, innovation, accepted update) until it comes back to P⁺, bit
/// for bit, within [`MAX_STEADY_PERIOD`] phases. The cycle's last phase is
/// then this epoch's step (its S and K are checked against `work`'s), and the
/// steady path's arithmetic is checked against this epoch's full step
/// (residual, NIS and state, bit for bit); if either disagrees the steady
/// path is switched off for the batch. None too when the probe fails or
/// does not come back (the next epochs find out in their own full steps).
fn find_steady<N: Dim, M: Dim>(
    kf: &KalmanFilter<N>,
    model: &mut BatchModel<'_, N>,
    (z, hc, rc): Selected<N, M>,
    x_predicted: &OVector<f64, N>,
    work: &UpdateWork<N, M>,
    present: &[usize],
    k: usize,
) -> Option<Steady<N, M>>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let mut probe = kf.clone();
    let mut phases: Vec<Phase<N, M>> = Vec::with_capacity(MAX_STEADY_PERIOD);
    while phases.len() < MAX_STEADY_PERIOD {
        probe.predict_covariance(&model.phi, model.q).ok()?;
        let p_predicted = probe.covariance().clone();
        let innovation = probe.innovation(&z, &hc, &rc).ok()?;
        let step = probe.update(&z, &hc, &rc).ok()?;
        phases.push(Phase {
            p_predicted,
            hph: innovation.hph,
            s: innovation.s,
            chol: innovation.chol,
            gain: step.gain,
            p_filtered: probe.covariance().clone(),
        });
        if same_bits(probe.covariance(), kf.covariance()) {
            break;
        }
    }
    let last = phases.last()?;
    if !same_bits(&last.p_filtered, kf.covariance()) {
        return None;
    }
    let residual = &z - &hc * x_predicted;
    let nis = residual.dot(&last.chol.solve(&residual));
    let mut x = x_predicted.clone();
    x += &last.gain * &residual;
    let agrees = same_bits(&last.s, work.s())
        && same_bits(&last.gain, work.gain())
        && same_bits(&residual, work.residual())
        && nis.to_bits() == work.nis().to_bits()
        && same_bits(&x, kf.state());
    if !agrees {
        model.steady_allowed = false;
        return None;
    }
    Some(Steady {
        present: present.to_vec(),
        h: hc,
        r: rc,
        phases,
        current: Some((k, 0)),
    })
}

/// The batch loop behind [`filter_batch`] and [`filter_batch_plain`].
#[allow(clippy::too_many_arguments)]
fn run_batch<N: Dim, P: MeasurementPolicy<Dyn> + ?Sized>(
    kf: &mut KalmanFilter<N>,
    phi: &OMatrix<f64, N, N>,
    q: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, Dyn, N>,
    r: &DMatrix<f64>,
    z: &[f64],
    predict_first: bool,
    policy: &mut BatchPolicy<'_, P>,
    keep: BatchKeep,
) -> Result<BatchOutput<N>>
where
    DefaultAllocator: FixedBatchAllocator<N>,
{
    let n = kf.dim();
    let m = h.nrows();
    if m == 0 || !z.len().is_multiple_of(m) {
        return Err(EstimationError::DimensionMismatch {
            step: Step::Update,
            matrix: Matrix::Z,
            rows: z.len(),
            cols: 1,
            expected_rows: m.max(1) * (z.len() / m.max(1)),
            expected_cols: 1,
        });
    }
    if r.shape() != (m, m) {
        return Err(EstimationError::DimensionMismatch {
            step: Step::Update,
            matrix: Matrix::R,
            rows: r.nrows(),
            cols: r.ncols(),
            expected_rows: m,
            expected_cols: m,
        });
    }
    let epochs = z.len() / m;
    let mut out = BatchOutput {
        states: Vec::with_capacity(epochs * n),
        covariances: Vec::with_capacity(if keep.covariance { epochs * n * n } else { 0 }),
        residuals: Vec::with_capacity(epochs * m),
        nis: Vec::with_capacity(epochs),
        outcomes: Vec::with_capacity(epochs),
        forward: Vec::new(),
        steady_epochs: 0,
    };
    let mut work = BatchWork {
        model: BatchModel {
            // Any values: both are written before they are read.
            phi_p: kf.covariance().clone(),
            p_predicted: kf.covariance().clone(),
            phi: phi.clone(),
            h,
            r,
            keep,
            q_symmetric: prechecked(phi, q, h, r, n),
            q,
            steady_allowed: true,
            steady_epochs: 0,
            recent: Recent::new(kf.covariance()),
            p_symmetric: crate::dense::symmetric_bits(kf.covariance().as_slice(), n),
        },
        kf: kf.clone(),
    };
    let BatchWork { model, kf: filter } = &mut work;
    let looped = run_epochs(filter, model, (z, m, predict_first), policy, &mut out);
    // The caller's filter ends where the epochs left the copy, whether
    // they ran to the end or stopped at an error.
    kf.clone_from(filter);
    looped?;
    out.steady_epochs = model.steady_epochs;
    Ok(out)
}

/// The memory the batch's epochs work in, in one block aligned to a 4 KiB
/// page: the model's matrices ([`BatchModel`]'s first fields) and a copy
/// of the filter, whose P and x [`run_batch`] copies back at the end.
/// Each run otherwise found these matrices wherever the stack and the heap
/// happened to put them, which ASLR moves from process to process: with
/// one of them across a page boundary (Φ P or P⁻ at 9 states, one process
/// in four), every epoch ran 10–20 % slower. Its alignment also aligns
/// the stack frame that holds it, so the epochs' other stack memory (the
/// update's innovation and gain, the kernels' vectors) keeps one place
/// relative to the pages too.
#[repr(C, align(4096))]
struct BatchWork<'a, N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    model: BatchModel<'a, N>,
    kf: KalmanFilter<N>,
}

/// The epochs of [`run_batch`]: `z` in rows of `m`, predicting before the
/// first with `predict_first`; each epoch's results pushed onto `out`.
fn run_epochs<N: Dim, P: MeasurementPolicy<Dyn> + ?Sized>(
    kf: &mut KalmanFilter<N>,
    model: &mut BatchModel<'_, N>,
    (z, m, predict_first): (&[f64], usize, bool),
    policy: &mut BatchPolicy<'_, P>,
    out: &mut BatchOutput<N>,
) -> Result<()>
where
    DefaultAllocator: FixedBatchAllocator<N>,
{
    let keep = model.keep;
    // What each update size keeps (its steady state: one set of
    // components each).
    let mut sized1 = SizeState::new();
    let mut sized2 = SizeState::new();
    let mut sized3 = SizeState::new();
    let mut sized4 = SizeState::new();
    let mut sized5 = SizeState::new();
    let mut sized6 = SizeState::new();
    let mut sized_dyn = SizeState::new();
    // The indices of the components present, reused by every epoch.
    let mut present: Vec<usize> = Vec::with_capacity(m);
    for (k, row) in z.chunks_exact(m).enumerate() {
        let predict = k > 0 || predict_first;
        present.clear();
        present.extend((0..m).filter(|&i| !row[i].is_nan()));
        let first = out.residuals.len();
        out.residuals.resize(first + m, f64::NAN);
        let residuals = &mut out.residuals[first..];
        let epoch = (k, row, present.as_slice(), predict);
        macro_rules! fixed {
            ($c:literal, $sized:ident) => {
                match policy {
                    BatchPolicy::Accept => update_epoch::<N, Const<$c>, AsDyn<'_, P>>(
                        kf,
                        model,
                        Const::<$c>,
                        epoch,
                        None,
                        &mut $sized,
                        residuals,
                    ),
                    BatchPolicy::Given(p) => update_epoch(
                        kf,
                        model,
                        Const::<$c>,
                        epoch,
                        Some(&mut AsDyn(&mut **p)),
                        &mut $sized,
                        residuals,
                    ),
                }
            };
        }
        let update = match present.len() {
            0 => {
                model.recent.reset();
                if predict {
                    model.predict(kf).map_err(|e| e.at_epoch(k))?;
                }
                if let BatchPolicy::Given(p) = policy {
                    p.missing();
                }
                Ok(EpochUpdate {
                    nis: f64::NAN,
                    outcome: Outcome::Missing,
                    predicted: keep
                        .forward
                        .then(|| Box::new((kf.state().clone(), kf.covariance().clone()))),
                })
            }
            1 => fixed!(1, sized1),
            2 => fixed!(2, sized2),
            3 => fixed!(3, sized3),
            4 => fixed!(4, sized4),
            5 => fixed!(5, sized5),
            6 => fixed!(6, sized6),
            c => match policy {
                BatchPolicy::Accept => update_epoch::<N, Dyn, P>(
                    kf,
                    model,
                    Dyn(c),
                    epoch,
                    None,
                    &mut sized_dyn,
                    residuals,
                ),
                BatchPolicy::Given(p) => update_epoch(
                    kf,
                    model,
                    Dyn(c),
                    epoch,
                    Some(&mut **p),
                    &mut sized_dyn,
                    residuals,
                ),
            },
        }
        .map_err(|e| e.at_epoch(k))?;
        out.nis.push(update.nis);
        out.outcomes.push(update.outcome);
        out.states.extend_from_slice(kf.state().as_slice());
        if keep.covariance {
            // nalgebra is column-major; P is symmetric, so its columns are its rows.
            out.covariances
                .extend_from_slice(kf.covariance().as_slice());
        }
        if let Some(prediction) = update.predicted {
            let (x_predicted, p_predicted) = *prediction;
            out.forward.push(ForwardEpoch {
                phi: model.phi.clone(),
                x_predicted,
                p_predicted,
                x_filtered: kf.state().clone(),
                p_filtered: kf.covariance().clone(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::{AcceptAll, Chi2Gate};

    /// The batch call equals the same predict/update calls made one by one,
    /// bit for bit, with a missing component and a missing epoch.
    #[test]
    fn batch_equals_the_step_by_step_filter() {
        let phi = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 0.0, 1.0]);
        let q = DMatrix::from_row_slice(2, 2, &[0.25, 0.5, 0.5, 1.0]) * 0.01;
        let h = DMatrix::identity(2, 2);
        let r = DMatrix::from_diagonal(&DVector::from_vec(vec![4.0, 1.0]));
        let z = [1.0, 0.5, f64::NAN, 0.7, f64::NAN, f64::NAN, 3.9, 1.1];
        let prior =
            KalmanFilter::<Dyn>::new(DVector::zeros(2), DMatrix::identity(2, 2) * 10.0).unwrap();
        let mut kf = prior.clone();
        let out = filter_batch(
            &mut kf,
            &phi,
            &q,
            &h,
            &r,
            &z,
            true,
            &mut AcceptAll,
            BatchKeep {
                covariance: true,
                forward: true,
            },
        )
        .unwrap();
        let mut one = prior;
        for (k, row) in z.chunks(2).enumerate() {
            one.predict(&phi, &q).unwrap();
            let present: Vec<usize> = (0..2).filter(|&i| !row[i].is_nan()).collect();
            if !present.is_empty() {
                let zv = DVector::from_iterator(present.len(), present.iter().map(|&i| row[i]));
                let rec = one
                    .update(
                        &zv,
                        &h.select_rows(present.iter()),
                        &r.select_rows(present.iter()).select_columns(present.iter()),
                    )
                    .unwrap();
                assert_eq!(out.nis[k].to_bits(), rec.nis.to_bits());
            } else {
                assert!(out.nis[k].is_nan());
                assert_eq!(out.outcomes[k], Outcome::Missing);
            }
            assert_eq!(&out.states[2 * k..2 * k + 2], one.state().as_slice());
            assert_eq!(
                &out.covariances[4 * k..4 * k + 4],
                one.covariance().as_slice()
            );
        }
        assert!(out.residuals[2].is_nan() && out.residuals[3].is_finite());
        assert_eq!(out.forward.len(), 4);
        // A gate rejects an outlier and says so.
        let mut kf = KalmanFilter::<Dyn>::new(DVector::zeros(2), DMatrix::identity(2, 2)).unwrap();
        let z = [0.1, 0.0, 500.0, 0.0];
        let mut gate = Chi2Gate { probability: 0.999 };
        let out = filter_batch(
            &mut kf,
            &phi,
            &q,
            &h,
            &r,
            &z,
            false,
            &mut gate,
            BatchKeep::default(),
        )
        .unwrap();
        assert_eq!(out.outcomes, [Outcome::Accepted, Outcome::Rejected]);
        // A row length that does not divide is refused.
        assert!(
            filter_batch(
                &mut kf,
                &phi,
                &q,
                &h,
                &r,
                &[1.0; 3],
                true,
                &mut AcceptAll,
                BatchKeep::default()
            )
            .is_err()
        );
    }

    /// The plain and the χ²-gated (`probability`) batch from `prior` on the
    /// batch's own (Φ, Q, H) against [`step_by_step`] from (x0, P0) on the
    /// run-time sized model, R the model's: the same states, outcomes and
    /// NIS bit for bit; the gate rejects something.
    fn assert_batch_is_step_by_step<N: Dim>(
        prior: &KalmanFilter<N>,
        (phi, q, h): BatchModel<'_, N>,
        (x0, p0, model): (&DVector<f64>, &DMatrix<f64>, StepModel<'_>),
        z: &[f64],
        probability: f64,
    ) where
        DefaultAllocator: FixedBatchAllocator<N>,
    {
        let (r, keep) = (model.3, BatchKeep::default());
        let plain = filter_batch_plain(&mut prior.clone(), phi, q, h, r, z, true, keep).unwrap();
        let (states, nis, outcomes) = step_by_step(x0, p0, model, z, &mut AcceptAll);
        assert_eq!(plain.states, states);
        assert_eq!(plain.outcomes, outcomes);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&plain.nis), bits(&nis));
        let gate = || Chi2Gate { probability };
        let mut policy = gate();
        let gated = filter_batch(&mut prior.clone(), phi, q, h, r, z, true, &mut policy, keep);
        let gated = gated.unwrap();
        let (states, _, outcomes) = step_by_step(x0, p0, model, z, &mut gate());
        assert_eq!(gated.states, states);
        assert_eq!(gated.outcomes, outcomes);
        assert!(outcomes.contains(&Outcome::Rejected));
    }

    /// (Φ, Q, H) of a batch.
    type BatchModel<'a, N> = (
        &'a OMatrix<f64, N, N>,
        &'a OMatrix<f64, N, N>,
        &'a OMatrix<f64, Dyn, N>,
    );

    /// (Φ, Q, H, R) of [`step_by_step`].
    type StepModel<'a> = (
        &'a DMatrix<f64>,
        &'a DMatrix<f64>,
        &'a DMatrix<f64>,
        &'a DMatrix<f64>,
    );

    /// The step-by-step reference: a run-time sized filter updated with
    /// the rows present selected into run-time sized matrices.
    fn step_by_step(
        x0: &DVector<f64>,
        p0: &DMatrix<f64>,
        (phi, q, h, r): StepModel<'_>,
        z: &[f64],
        policy: &mut dyn MeasurementPolicy<Dyn>,
    ) -> (Vec<f64>, Vec<f64>, Vec<Outcome>) {
        let m = h.nrows();
        let mut kf = KalmanFilter::<Dyn>::new(x0.clone(), p0.clone()).unwrap();
        let (mut states, mut nis, mut outcomes) = (Vec::new(), Vec::new(), Vec::new());
        for row in z.chunks(m) {
            kf.predict(phi, q).unwrap();
            let present: Vec<usize> = (0..m).filter(|&i| !row[i].is_nan()).collect();
            if present.is_empty() {
                policy.missing();
                nis.push(f64::NAN);
                outcomes.push(Outcome::Missing);
            } else {
                let zv = DVector::from_iterator(present.len(), present.iter().map(|&i| row[i]));
                let rs = r.select_rows(present.iter()).select_columns(present.iter());
                let rec = kf
                    .update_with(&zv, &h.select_rows(present.iter()), &rs, policy)
                    .unwrap();
                nis.push(rec.nis);
                outcomes.push(rec.outcome);
            }
            states.extend(kf.state().iter());
        }
        (states, nis, outcomes)
    }

    /// A fixed-size filter's batch — fixed-size updates of the components
    /// present, up to six, run-time sized beyond — equals the step-by-step
    /// run-time sized filter bit for bit, with and without a policy, over
    /// epochs with every component (7: the run-time sized path), six, two
    /// and none.
    #[test]
    fn fixed_size_batch_equals_the_run_time_sized_steps() {
        use nalgebra::{Const, SMatrix, SVector};
        let phi = DMatrix::from_fn(4, 4, |i, j| {
            if i == j {
                1.0
            } else if j == i + 1 {
                0.1
            } else {
                0.0
            }
        });
        let q = DMatrix::from_diagonal(&DVector::from_vec(vec![1e-3, 2e-3, 1e-3, 3e-3]));
        let h = DMatrix::from_fn(7, 4, |i, j| if i % 4 == j { 1.0 } else { 0.05 * i as f64 });
        let r = DMatrix::from_fn(
            7,
            7,
            |i, j| if i == j { 0.5 + 0.1 * i as f64 } else { 0.01 },
        );
        let p0 = DMatrix::from_fn(4, 4, |i, j| if i == j { 2.0 } else { 0.1 });
        let x0 = DVector::from_vec(vec![0.1, -0.2, 0.3, 0.0]);
        let nan = f64::NAN;
        let mut z = Vec::new();
        for k in 0..12 {
            let v = |i: usize| ((k * 7 + i * 3) % 5) as f64 * 0.3 - 0.6;
            let row: Vec<f64> = match k % 4 {
                0 => (0..7).map(v).collect(),
                1 => (0..7).map(|i| if i == 3 { nan } else { v(i) }).collect(),
                2 => (0..7)
                    .map(|i| if i == 1 || i == 5 { v(i) } else { nan })
                    .collect(),
                _ => vec![nan; 7],
            };
            z.extend(row);
        }
        // An outlier the gate rejects.
        z[7 * 4] = 80.0;
        let fixed = KalmanFilter::<Const<4>>::new(
            SVector::<f64, 4>::from_column_slice(x0.as_slice()),
            SMatrix::<f64, 4, 4>::from_column_slice(p0.as_slice()),
        )
        .unwrap();
        let (phi_s, q_s) = (
            SMatrix::<f64, 4, 4>::from_column_slice(phi.as_slice()),
            SMatrix::<f64, 4, 4>::from_column_slice(q.as_slice()),
        );
        let h_d = OMatrix::<f64, Dyn, Const<4>>::from_column_slice(h.as_slice());
        let model = (&phi, &q, &h, &r);
        let batch = (&phi_s, &q_s, &h_d);
        assert_batch_is_step_by_step(&fixed, batch, (&x0, &p0, model), &z, 0.99);
        let keep = BatchKeep::default();
        // R of the wrong size is refused.
        let r6 = DMatrix::identity(6, 6);
        assert!(
            filter_batch_plain(&mut fixed.clone(), &phi_s, &q_s, &h_d, &r6, &z, true, keep)
                .is_err()
        );
    }

    /// A model like the benchmark's (bench/filterpy_step.py `problem`):
    /// n states, m measurements, Φ near the identity, H the identity's
    /// first m rows with 0.1 m columns on.
    fn bench_model(n: usize, m: usize) -> [DMatrix<f64>; 5] {
        let phi = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                1.0
            } else {
                0.01 * (((i * 7 + j * 3) % 11) as f64 - 5.0) / 5.0
            }
        });
        let q = DMatrix::from_fn(
            n,
            n,
            |i, j| if i == j { 1e-4 * (1.0 + i as f64) } else { 0.0 },
        );
        let h = DMatrix::from_fn(m, n, |i, j| {
            if i == j {
                1.0
            } else if j == i + m {
                0.1
            } else {
                0.0
            }
        });
        let r = DMatrix::from_fn(
            m,
            m,
            |i, j| if i == j { 0.5 + 0.1 * i as f64 } else { 0.01 },
        );
        let a = DMatrix::from_fn(n, n, |i, j| (((i * 5 + j * 13) % 17) as f64 - 8.0) / 8.0);
        let p0 = &a * a.transpose() / n as f64 + DMatrix::identity(n, n);
        [phi, q, h, r, p0]
    }

    /// `epochs` rows of m pseudo-random values (a fixed formula), a
    /// `missing` fraction of them NaN, and outliers (50) at the epochs in
    /// `outliers`.
    fn measurements(epochs: usize, m: usize, missing: f64, outliers: &[usize]) -> Vec<f64> {
        let mut z = Vec::with_capacity(epochs * m);
        for k in 0..epochs {
            for i in 0..m {
                let u = ((k * 31 + i * 17) as f64 * 0.618_033_988_75).fract();
                let v = ((k * 13 + i * 29) as f64 * 0.414_213_562_37).fract();
                z.push(if u < missing { f64::NAN } else { 2.0 * v - 1.0 });
            }
            if outliers.contains(&k) {
                z[k * m] = 50.0;
            }
        }
        z
    }

    /// The batch of a fixed-size filter (`NN` states) equals the same
    /// filter's full step epoch by epoch (the batch called one epoch at a
    /// time: no steady state within a call) bit for bit — states,
    /// covariances, NIS, outcomes and the forward pass's predictions — with
    /// or without a χ² gate; returns the epochs computed in the steady
    /// state.
    fn batch_equals_steps<const NN: usize>(
        model: &[DMatrix<f64>; 5],
        z: &[f64],
        gate: Option<f64>,
    ) -> usize {
        let [phi, q, h, r, p0] = model;
        let m = h.nrows();
        let prior = KalmanFilter::<Const<NN>>::new(
            SVector::<f64, NN>::zeros(),
            SMatrix::<f64, NN, NN>::from_column_slice(p0.as_slice()),
        )
        .unwrap();
        let phi_s = SMatrix::<f64, NN, NN>::from_column_slice(phi.as_slice());
        let q_s = SMatrix::<f64, NN, NN>::from_column_slice(q.as_slice());
        let h_d = OMatrix::<f64, Dyn, Const<NN>>::from_column_slice(h.as_slice());
        let keep = BatchKeep {
            covariance: true,
            forward: true,
        };
        let mut policy = gate.map(|probability| Chi2Gate { probability });
        let run = |kf: &mut KalmanFilter<Const<NN>>, z: &[f64], policy: &mut Option<Chi2Gate>| {
            match policy {
                None => filter_batch_plain(kf, &phi_s, &q_s, &h_d, r, z, true, keep),
                Some(p) => filter_batch(kf, &phi_s, &q_s, &h_d, r, z, true, p, keep),
            }
            .unwrap()
        };
        let out = run(&mut prior.clone(), z, &mut policy);
        let mut reference_policy = gate.map(|probability| Chi2Gate { probability });
        let mut one = prior;
        let mut reference = Vec::new();
        for row in z.chunks(m) {
            let epoch = run(&mut one, row, &mut reference_policy);
            assert_eq!(epoch.steady_epochs, 0);
            reference.push(epoch);
        }
        let flat = |f: &dyn Fn(&BatchOutput<Const<NN>>) -> Vec<f64>| -> Vec<f64> {
            reference.iter().flat_map(f).collect()
        };
        let states = flat(&|e| e.states.clone());
        let covariances = flat(&|e| e.covariances.clone());
        let nis = flat(&|e| e.nis.clone());
        let predicted = flat(&|e| e.forward[0].p_predicted.as_slice().to_vec());
        let ours_predicted: Vec<f64> = out
            .forward
            .iter()
            .flat_map(|e| e.p_predicted.as_slice().to_vec())
            .collect();
        let outcomes: Vec<Outcome> = reference.iter().map(|e| e.outcomes[0]).collect();
        let first_difference = |a: &[f64], b: &[f64]| {
            assert_eq!(a.len(), b.len());
            a.iter()
                .zip(b)
                .position(|(a, b)| a.to_bits() != b.to_bits())
        };
        for (what, ours, theirs, per_epoch) in [
            ("x", &out.states, &states, NN),
            ("P", &out.covariances, &covariances, NN * NN),
            ("NIS", &out.nis, &nis, 1),
            ("P⁻", &ours_predicted, &predicted, NN * NN),
        ] {
            let at = first_difference(ours, theirs).map(|i| i / per_epoch);
            assert!(
                at.is_none(),
                "{what} differs at epoch {at:?} ({} of {} epochs steady, gate {gate:?})",
                out.steady_epochs,
                out.nis.len()
            );
        }
        assert_eq!(out.outcomes, outcomes);
        out.steady_epochs
    }

    /// `b` constant-velocity axes (Φ = [[1, 1], [0, 1]] each, Q = 10⁻³ I,
    /// positions measured, R = I, P₀ = I): 2b states, b measurements. Its
    /// Riccati recursion reaches a bit-for-bit fixed point (at epoch 144);
    /// the benchmark model's does not (6/3 settles into a cycle of two
    /// covariances at epoch 1801, the larger ones change still after 3000
    /// epochs).
    fn constant_velocity(b: usize) -> [DMatrix<f64>; 5] {
        let n = 2 * b;
        let phi = DMatrix::from_fn(n, n, |i, j| {
            if i == j || (j == i + 1 && i % 2 == 0) {
                1.0
            } else {
                0.0
            }
        });
        let h = DMatrix::from_fn(b, n, |i, j| if j == 2 * i { 1.0 } else { 0.0 });
        [
            phi,
            DMatrix::identity(n, n) * 1e-3,
            h,
            DMatrix::identity(b, b),
            DMatrix::identity(n, n),
        ]
    }

    /// The steady state: at several sizes the Riccati recursion reaches a
    /// covariance that an accepted update leaves bit for bit as it was,
    /// the batch then computes the state only, and every number equals
    /// the full step-by-step recursion bit for bit — with every value
    /// present (most epochs steady), with 10 % missing (back to the full
    /// step at every gap), with a χ² gate rejecting outliers in the steady
    /// state (the full step for the rejected epoch, then the steady state
    /// found again).
    #[test]
    fn steady_state_batch_equals_the_full_recursion_bit_for_bit() {
        let epochs = 1500;
        let outliers = [700, 701, 1200];
        for b in [2, 3, 4, 6] {
            let model = constant_velocity(b);
            let full = measurements(epochs, b, 0.0, &[]);
            let gappy = measurements(epochs, b, 0.1, &[]);
            let spiked = measurements(epochs, b, 0.0, &outliers);
            let run = |z: &[f64], gate: Option<f64>| match b {
                2 => batch_equals_steps::<4>(&model, z, gate),
                3 => batch_equals_steps::<6>(&model, z, gate),
                4 => batch_equals_steps::<8>(&model, z, gate),
                _ => batch_equals_steps::<12>(&model, z, gate),
            };
            let steady = run(&full, None);
            assert!(steady > epochs / 2, "{b} axes: {steady} steady epochs");
            // Every gap breaks the steady state; it is found again when
            // P⁺ repeats.
            let steady_gappy = run(&gappy, None);
            assert!(steady_gappy < steady, "{b} axes: {steady_gappy}");
            let steady_gated = run(&spiked, Some(0.999));
            assert!(
                steady_gated > epochs / 2 && steady_gated < steady,
                "{b} axes: {steady_gated} of {steady}"
            );
        }
        // More components than the fixed-size updates take (run-time
        // sized update matrices).
        let model = constant_velocity(8);
        let steady = batch_equals_steps::<16>(&model, &measurements(600, 8, 0.0, &[]), None);
        assert!(steady > 300, "8 axes: {steady}");
        // The benchmark's model does not settle within 600 epochs: the
        // batch is the full recursion.
        let model = bench_model(6, 3);
        let z = measurements(600, 3, 0.0, &[]);
        assert_eq!(batch_equals_steps::<6>(&model, &z, None), 0);
    }

    /// The benchmark's 6-state model (bench/filterpy_step.py `problem`)
    /// settles, bit for bit, not on a fixed point but on a cycle of two
    /// covariances (from epoch 1801 here): the batch's steady state follows
    /// the cycle, and every number equals the full step-by-step recursion
    /// bit for bit — with every value present, with gaps once the cycle is
    /// reached (the full step at each, the cycle found again after), and
    /// with a χ² gate rejecting outliers on the cycle.
    #[test]
    fn a_two_cycle_steady_state_equals_the_full_recursion_bit_for_bit() {
        let epochs = 2600;
        let model = bench_model(6, 3);
        // The premise, from the filter's own steps: P⁺ ends in a cycle of
        // two (equal to the one two epochs back, not to the last one).
        let [phi, q, h, r, p0] = &model;
        let mut kf = KalmanFilter::<Dyn>::new(DVector::zeros(6), p0.clone()).unwrap();
        let mut step = || {
            kf.predict(phi, q).unwrap();
            kf.update(&DVector::zeros(3), h, r).unwrap();
            kf.covariance().clone()
        };
        for _ in 0..epochs - 3 {
            step();
        }
        let (two_back, one_back, last) = (step(), step(), step());
        assert!(
            same_bits(&last, &two_back) && !same_bits(&last, &one_back),
            "the 6/3 model's P⁺ no longer ends in a two-covariance cycle: pick another model"
        );
        let full = measurements(epochs, 3, 0.0, &[]);
        let steady = batch_equals_steps::<6>(&model, &full, None);
        let mut gappy = full.clone();
        for k in [2000, 2001, 2150, 2300] {
            gappy[3 * k + 1] = f64::NAN;
        }
        gappy[3 * 2400..3 * 2401].fill(f64::NAN);
        let steady_gappy = batch_equals_steps::<6>(&model, &gappy, None);
        let spiked = measurements(epochs, 3, 0.0, &[2100, 2101, 2350]);
        let steady_gated = batch_equals_steps::<6>(&model, &spiked, Some(0.999));
        // A fixed point would be no steady state here: the epochs counted
        // are the cycle's.
        assert!(steady > 700, "{steady} steady epochs of {epochs}");
        assert!(steady_gappy > 0 && steady_gappy < steady, "{steady_gappy}");
        assert!(steady_gated > 0 && steady_gated < steady, "{steady_gated}");
    }

    /// Φ, Q, H and R are checked once per batch when they pass (the
    /// epochs then skip those checks): the batch equals the run-time
    /// sized filter's own predict and update calls bit for bit — with gaps
    /// and a χ² gate rejecting an outlier — whether Q and R are exactly
    /// symmetric (checked once), Q only to rounding (symmetrised once, as
    /// every prediction would), or R only to rounding (checked every
    /// epoch). A value that changes (z) is still checked at every epoch,
    /// and the error names the epoch; a constant that fails its check is
    /// refused at the first epoch that uses it, naming it.
    #[test]
    fn constants_checked_once_give_the_checked_steps_bit_for_bit() {
        let [phi, q, h, r, p0] = bench_model(6, 3);
        let x0 = DVector::from_vec(vec![0.1, -0.2, 0.3, 0.0, 0.5, -0.1]);
        let z = {
            let mut z = measurements(300, 3, 0.1, &[150]);
            z[3 * 200..3 * 201].fill(f64::NAN);
            z
        };
        let mut q_rounded = q.clone();
        q_rounded[(0, 1)] = 1e-7;
        q_rounded[(1, 0)] = 1e-7 * (1.0 + 1e-12);
        let mut r_rounded = r.clone();
        r_rounded[(1, 2)] *= 1.0 + 1e-12;
        for (q, r, constants_once) in [
            (&q, &r, true),
            (&q_rounded, &r, true),
            (&q, &r_rounded, false),
        ] {
            assert_eq!(
                prechecked(&phi, q, &h, r, 6).is_some(),
                constants_once,
                "{q} {r}"
            );
            let model = (&phi, q, &h, r);
            let prior = KalmanFilter::<Dyn>::new(x0.clone(), p0.clone()).unwrap();
            assert_batch_is_step_by_step(&prior, (&phi, q, &h), (&x0, &p0, model), &z, 0.999);
        }
        let prior = KalmanFilter::<Dyn>::new(x0, p0).unwrap();
        let keep = BatchKeep::default();
        let run = |phi: &DMatrix<f64>, q: &DMatrix<f64>, h: &DMatrix<f64>, z: &[f64]| {
            filter_batch_plain(&mut prior.clone(), phi, q, h, &r, z, true, keep)
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        let mut bad_z = z.clone();
        bad_z[3 * 7 + 1] = f64::INFINITY;
        let e = run(&phi, &q, &h, &bad_z).unwrap_err();
        assert!(e.starts_with("epoch 7:"), "{e}");
        // The filter the error leaves is the step-by-step one's at the
        // same point, bit for bit: x⁻ and P⁻ of epoch 7 (the batch's
        // update writes P⁺ from its P⁻ kept aside, and puts P⁻ back).
        let mut failed = prior.clone();
        filter_batch_plain(&mut failed, &phi, &q, &h, &r, &bad_z, true, keep).unwrap_err();
        let mut one = prior.clone();
        filter_batch_plain(&mut one, &phi, &q, &h, &r, &bad_z[..3 * 7], true, keep).unwrap();
        one.predict(&phi, &q).unwrap();
        assert!(same_bits(failed.state(), one.state()));
        assert!(same_bits(failed.covariance(), one.covariance()));
        let mut bad_phi = phi.clone();
        bad_phi[(2, 3)] = f64::NAN;
        let e = run(&bad_phi, &q, &h, &z).unwrap_err();
        assert!(e.starts_with("epoch 0:") && e.contains("Φ"), "{e}");
        let mut bad_q = q.clone();
        bad_q[(0, 1)] = 1.0;
        let e = run(&phi, &bad_q, &h, &z).unwrap_err();
        assert!(e.starts_with("epoch 0:") && e.contains('Q'), "{e}");
        // A row of H whose component is never present is never used.
        let mut unused_row = h.clone();
        unused_row[(2, 0)] = f64::NAN;
        let mut z_without_2 = z.clone();
        z_without_2
            .iter_mut()
            .skip(2)
            .step_by(3)
            .for_each(|v| *v = f64::NAN);
        assert_eq!(run(&phi, &q, &unused_row, &z_without_2), Ok(()));
        let first_use = (0..300).find(|k| !z[3 * k + 2].is_nan()).unwrap();
        let e = run(&phi, &q, &unused_row, &z).unwrap_err();
        assert!(
            e.starts_with(&format!("epoch {first_use}:")) && e.contains('H'),
            "{e}"
        );
    }

    /// A model whose covariance never settles (a random walk no
    /// measurement sees: P grows without bound) never takes the steady
    /// path, and the batch is the full recursion.
    #[test]
    fn an_unsettled_covariance_never_takes_the_steady_path() {
        let [phi, mut q, mut h, r, p0] = bench_model(4, 2);
        q[(3, 3)] = 1.0;
        h.column_mut(3).fill(0.0);
        let model = [phi, q, h, r, p0];
        let z = measurements(400, 2, 0.0, &[]);
        assert_eq!(batch_equals_steps::<4>(&model, &z, None), 0);
    }
}
