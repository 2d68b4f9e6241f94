//! A whole measurement sequence through one filter in one call: for each
//! epoch predict with (Φ, Q), then update with the components of the
//! epoch's measurement that are present (NaN: missing) under a policy. The
//! loop a caller outside Rust would otherwise write epoch by epoch (the
//! Python package's batch call); [`LinearGaussianModel::run`](crate::LinearGaussianModel::run)
//! is the same loop with records for observers.

use nalgebra::{
    Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix, SVector,
    allocator::Allocator,
};

use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::{FilterAllocator, KalmanFilter};
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

/// The update of one epoch with its `c = present.len()` components in
/// fixed-size matrices (`C = c`): z, the rows of H and the rows/columns
/// of R selected by copying into stack matrices.
fn update_fixed<N: Dim, const C: usize, P: MeasurementPolicy<Dyn> + ?Sized>(
    kf: &mut KalmanFilter<N>,
    row: &[f64],
    present: &[usize],
    h: &OMatrix<f64, Dyn, N>,
    r: &DMatrix<f64>,
    policy: &mut BatchPolicy<'_, P>,
) -> Result<(OVector<f64, Const<C>>, f64, Outcome)>
where
    DefaultAllocator: FilterAllocator<N, Const<C>>,
{
    let (_, nd) = h.shape_generic();
    let zc =
        OVector::<f64, Const<C>>::from_fn_generic(Const::<C>, nalgebra::U1, |i, _| row[present[i]]);
    let hc =
        OMatrix::<f64, Const<C>, N>::from_fn_generic(Const::<C>, nd, |i, j| h[(present[i], j)]);
    let rc = OMatrix::<f64, Const<C>, Const<C>>::from_fn_generic(Const::<C>, Const::<C>, |i, j| {
        r[(present[i], present[j])]
    });
    let rec = match policy {
        BatchPolicy::Accept => kf.update_with(&zc, &hc, &rc, &mut AcceptAll),
        BatchPolicy::Given(p) => kf.update_with(&zc, &hc, &rc, &mut AsDyn(&mut **p)),
    }?;
    Ok((rec.residual, rec.nis, rec.outcome))
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
    };
    // The indices of the components present, reused by every epoch.
    let mut present: Vec<usize> = Vec::with_capacity(m);
    for (k, row) in z.chunks_exact(m).enumerate() {
        if k > 0 || predict_first {
            kf.predict(phi, q).map_err(|e| e.at_epoch(k))?;
        }
        let predicted = keep
            .forward
            .then(|| (kf.state().clone(), kf.covariance().clone()));
        present.clear();
        present.extend((0..m).filter(|&i| !row[i].is_nan()));
        let first = out.residuals.len();
        out.residuals.resize(first + m, f64::NAN);
        if present.is_empty() {
            if let BatchPolicy::Given(p) = policy {
                p.missing();
            }
            out.nis.push(f64::NAN);
            out.outcomes.push(Outcome::Missing);
        } else {
            let residuals = &mut out.residuals[first..];
            macro_rules! fixed {
                ($c:literal) => {{
                    let (residual, nis, outcome) =
                        update_fixed::<N, $c, P>(kf, row, &present, h, r, policy)
                            .map_err(|e| e.at_epoch(k))?;
                    for (j, &i) in present.iter().enumerate() {
                        residuals[i] = residual[j];
                    }
                    (nis, outcome)
                }};
            }
            let (nis, outcome) = match present.len() {
                1 => fixed!(1),
                2 => fixed!(2),
                3 => fixed!(3),
                4 => fixed!(4),
                5 => fixed!(5),
                6 => fixed!(6),
                c => {
                    let zv = DVector::from_iterator(c, present.iter().map(|&i| row[i]));
                    let hs = h.select_rows(present.iter());
                    let rs = r.select_rows(present.iter()).select_columns(present.iter());
                    let rec = match policy {
                        BatchPolicy::Accept => kf.update_with(&zv, &hs, &rs, &mut AcceptAll),
                        BatchPolicy::Given(p) => kf.update_with(&zv, &hs, &rs, &mut **p),
                    }
                    .map_err(|e| e.at_epoch(k))?;
                    for (j, &i) in present.iter().enumerate() {
                        residuals[i] = rec.residual[j];
                    }
                    (rec.nis, rec.outcome)
                }
            };
            out.nis.push(nis);
            out.outcomes.push(outcome);
        }
        out.states.extend(kf.state().iter());
        if keep.covariance {
            // nalgebra is column-major; P is symmetric, so its columns are its rows.
            out.covariances.extend(kf.covariance().iter());
        }
        if let Some((x_predicted, p_predicted)) = predicted {
            out.forward.push(ForwardEpoch {
                phi: phi.clone(),
                x_predicted,
                p_predicted,
                x_filtered: kf.state().clone(),
                p_filtered: kf.covariance().clone(),
            });
        }
    }
    Ok(out)
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

    /// The step-by-step reference: a run-time sized filter updated with
    /// the rows present selected into run-time sized matrices.
    fn step_by_step(
        x0: &DVector<f64>,
        p0: &DMatrix<f64>,
        (phi, q, h, r): (&DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>, &DMatrix<f64>),
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
        let keep = BatchKeep::default();
        let plain =
            filter_batch_plain(&mut fixed.clone(), &phi_s, &q_s, &h_d, &r, &z, true, keep).unwrap();
        let (states, nis, outcomes) = step_by_step(&x0, &p0, model, &z, &mut AcceptAll);
        assert_eq!(plain.states, states);
        assert_eq!(plain.outcomes, outcomes);
        assert!(
            plain
                .nis
                .iter()
                .zip(&nis)
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
        let gate = || Chi2Gate { probability: 0.99 };
        let gated = filter_batch(
            &mut fixed.clone(),
            &phi_s,
            &q_s,
            &h_d,
            &r,
            &z,
            true,
            &mut gate(),
            keep,
        )
        .unwrap();
        let (states, _, outcomes) = step_by_step(&x0, &p0, model, &z, &mut gate());
        assert_eq!(gated.states, states);
        assert_eq!(gated.outcomes, outcomes);
        assert!(outcomes.contains(&Outcome::Rejected));
        // R of the wrong size is refused.
        let r6 = DMatrix::identity(6, 6);
        assert!(
            filter_batch_plain(&mut fixed.clone(), &phi_s, &q_s, &h_d, &r6, &z, true, keep)
                .is_err()
        );
    }
}
