//! A whole measurement sequence through one filter in one call: for each
//! epoch predict with (Φ, Q), then update with the components of the
//! epoch's measurement that are present (NaN: missing) under a policy. The
//! loop a caller outside Rust would otherwise write epoch by epoch (the
//! Python package's batch call); [`LinearGaussianModel::run`](crate::LinearGaussianModel::run)
//! is the same loop with records for observers.

use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, allocator::Allocator};

use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::KalmanFilter;
use crate::policy::{MeasurementPolicy, Outcome};
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

/// Run `kf` over `epochs` measurement rows of `m` values each (`z`,
/// row-major, NaN marking a missing component): at every epoch predict
/// with (Φ, Q) — except the first when `predict_first` is false, the prior
/// then being the first epoch's — and update with the components present
/// (rows of H and rows/columns of R selected) under `policy`; an epoch with
/// none is a prediction only (`policy.missing()` is told). Errors carry the
/// epoch.
/// The filter may be of fixed size (`N = Const<n>`) or run-time sized;
/// measurements are run-time sized.
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
    DefaultAllocator: crate::kalman::FilterAllocator<N, Dyn>,
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
    let epochs = z.len() / m;
    let mut out = BatchOutput {
        states: Vec::with_capacity(epochs * n),
        covariances: Vec::with_capacity(if keep.covariance { epochs * n * n } else { 0 }),
        residuals: Vec::with_capacity(epochs * m),
        nis: Vec::with_capacity(epochs),
        outcomes: Vec::with_capacity(epochs),
        forward: Vec::new(),
    };
    for (k, row) in z.chunks_exact(m).enumerate() {
        if k > 0 || predict_first {
            kf.predict(phi, q).map_err(|e| e.at_epoch(k))?;
        }
        let predicted = keep
            .forward
            .then(|| (kf.state().clone(), kf.covariance().clone()));
        let present: Vec<usize> = (0..m).filter(|&i| !row[i].is_nan()).collect();
        let first = out.residuals.len();
        out.residuals.resize(first + m, f64::NAN);
        if present.is_empty() {
            policy.missing();
            out.nis.push(f64::NAN);
            out.outcomes.push(Outcome::Missing);
        } else {
            let rec = if present.len() == m {
                kf.update_with(&DVector::from_column_slice(row), h, r, policy)
            } else {
                let zv = DVector::from_iterator(present.len(), present.iter().map(|&i| row[i]));
                let hs = h.select_rows(present.iter());
                let rs = r.select_rows(present.iter()).select_columns(present.iter());
                kf.update_with(&zv, &hs, &rs, policy)
            }
            .map_err(|e| e.at_epoch(k))?;
            for (j, &i) in present.iter().enumerate() {
                out.residuals[first + i] = rec.residual[j];
            }
            out.nis.push(rec.nis);
            out.outcomes.push(rec.outcome);
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
}
