//! A time-invariant linear Gaussian model given as run-time sized matrices,
//! and the filter loop that runs it over a sequence of (possibly incomplete)
//! measurement vectors. This is the engine as `aidnav filter` exposes it.

use nalgebra::{DMatrix, DVector, Dyn};
use serde::{Deserialize, Serialize};

use crate::check;
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::{CovarianceUpdate, KalmanFilter};
use crate::observer::{EpochRecord, Observer};
use crate::policy::{Outcome, PolicyChoice};
use crate::smoother::ForwardEpoch;

/// `x_k = Φ x_{k−1} + w`, `z_k = H x_k + v`, w ~ N(0, Q), v ~ N(0, R), x_0 ~ N(x0, P0).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearGaussianModel {
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    x0: DVector<f64>,
    p0: DMatrix<f64>,
}

impl LinearGaussianModel {
    /// Build and check a model: shapes agree, every value finite, Q, R, P0
    /// symmetric, R positive definite.
    pub fn new(
        phi: DMatrix<f64>,
        q: DMatrix<f64>,
        h: DMatrix<f64>,
        r: DMatrix<f64>,
        x0: DVector<f64>,
        p0: DMatrix<f64>,
    ) -> Result<Self> {
        let step = Step::Initialise;
        let n = x0.len();
        let m = h.nrows();
        check::shape(&phi, (n, n), step, Matrix::Phi)?;
        check::shape(&q, (n, n), step, Matrix::Q)?;
        check::shape(&h, (m, n), step, Matrix::H)?;
        check::shape(&r, (m, m), step, Matrix::R)?;
        check::shape(&p0, (n, n), step, Matrix::P)?;
        check::finite(&phi, step, Matrix::Phi)?;
        check::finite(&q, step, Matrix::Q)?;
        check::finite(&h, step, Matrix::H)?;
        check::finite(&r, step, Matrix::R)?;
        check::finite(&x0, step, Matrix::X)?;
        check::finite(&p0, step, Matrix::P)?;
        check::symmetric(&q, step, Matrix::Q)?;
        check::symmetric(&r, step, Matrix::R)?;
        check::symmetric(&p0, step, Matrix::P)?;
        if r.clone().cholesky().is_none() {
            return Err(EstimationError::NotPositiveDefinite {
                step,
                matrix: Matrix::R,
            });
        }
        Ok(Self {
            phi,
            q,
            h,
            r,
            x0,
            p0,
        })
    }

    /// Number of states n.
    pub fn states(&self) -> usize {
        self.x0.len()
    }
    /// Number of measurement components m.
    pub fn measurements(&self) -> usize {
        self.h.nrows()
    }
    /// Φ.
    pub fn phi(&self) -> &DMatrix<f64> {
        &self.phi
    }
    /// Q.
    pub fn q(&self) -> &DMatrix<f64> {
        &self.q
    }
    /// H.
    pub fn h(&self) -> &DMatrix<f64> {
        &self.h
    }
    /// R.
    pub fn r(&self) -> &DMatrix<f64> {
        &self.r
    }
    /// x0.
    pub fn x0(&self) -> &DVector<f64> {
        &self.x0
    }
    /// P0.
    pub fn p0(&self) -> &DMatrix<f64> {
        &self.p0
    }

    /// Run the filter over `epochs` (time tag, one optional value per
    /// measurement component). Convention: (x0, P0) is the prior *at the first
    /// epoch*; every later epoch is predicted with (Φ, Q) from the one before,
    /// then updated with the components present. An epoch with no component
    /// present is a pure prediction (outcome `missing`).
    pub fn run<'a, I, O>(
        &self,
        epochs: I,
        options: &RunOptions,
        observer: &mut O,
    ) -> Result<RunOutput>
    where
        I: IntoIterator<Item = (f64, &'a [Option<f64>])>,
        O: Observer + ?Sized,
    {
        let n = self.states();
        let m = self.measurements();
        let mut kf = KalmanFilter::<Dyn>::new(self.x0.clone(), self.p0.clone())?
            .with_covariance_update(options.covariance_update);
        let mut policy = options.policy;
        let mut forward = Vec::new();
        observer.observe_init(n, m);
        let mut count = 0usize;
        for (k, (time, z)) in epochs.into_iter().enumerate() {
            if z.len() != m {
                return Err(EstimationError::DimensionMismatch {
                    step: Step::Update,
                    matrix: Matrix::Z,
                    rows: z.len(),
                    cols: 1,
                    expected_rows: m,
                    expected_cols: 1,
                }
                .at_epoch(k));
            }
            if k > 0 {
                kf.predict(&self.phi, &self.q).map_err(|e| e.at_epoch(k))?;
            }
            let x_predicted = kf.state().clone();
            let p_predicted = kf.covariance().clone();
            let present: Vec<usize> = (0..m).filter(|&i| z[i].is_some()).collect();
            let mut innovation = DVector::from_element(m, f64::NAN);
            let mut innovation_sigma = DVector::from_element(m, f64::NAN);
            let (nis, outcome) = if present.is_empty() {
                (f64::NAN, Outcome::Missing)
            } else {
                let zv = DVector::from_iterator(
                    present.len(),
                    present.iter().map(|&i| z[i].unwrap_or(f64::NAN)),
                );
                let h = self.h.select_rows(present.iter());
                let r = self
                    .r
                    .select_rows(present.iter())
                    .select_columns(present.iter());
                let rec = match options.update {
                    UpdateMethod::Batch => kf.update_with(&zv, &h, &r, &mut policy),
                    UpdateMethod::Sequential => kf.update_sequential(&zv, &h, &r),
                }
                .map_err(|e| e.at_epoch(k))?;
                for (j, &i) in present.iter().enumerate() {
                    innovation[i] = rec.residual[j];
                    innovation_sigma[i] = rec.s[(j, j)].sqrt();
                }
                (rec.nis, rec.outcome)
            };
            let p = kf.covariance();
            let record = EpochRecord {
                epoch: k,
                time,
                state: kf.state().clone(),
                sigma: p.diagonal().map(|v| v.max(0.0).sqrt()),
                covariance: options.keep_covariance.then(|| p.clone()),
                innovation,
                innovation_sigma,
                nis,
                dof: present.len(),
                outcome,
            };
            observer.observe_epoch(&record);
            if options.keep_forward_pass {
                forward.push(ForwardEpoch {
                    phi: self.phi.clone(),
                    x_predicted,
                    p_predicted,
                    x_filtered: kf.state().clone(),
                    p_filtered: kf.covariance().clone(),
                });
            }
            count += 1;
        }
        observer.observe_final();
        Ok(RunOutput {
            epochs: count,
            final_state: kf.state().clone(),
            final_covariance: kf.covariance().clone(),
            forward,
        })
    }
}

/// Batch (vector) or sequential (scalar) measurement update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UpdateMethod {
    /// One vector update per epoch (policies apply here).
    #[default]
    Batch,
    /// One scalar update per component; needs a diagonal R; no policy.
    Sequential,
}

/// How [`LinearGaussianModel::run`] runs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RunOptions {
    /// Batch or sequential update.
    pub update: UpdateMethod,
    /// Joseph (default) or standard covariance update.
    pub covariance_update: CovarianceUpdate,
    /// Measurement policy (batch updates only).
    pub policy: PolicyChoice,
    /// Put the full covariance into every record.
    pub keep_covariance: bool,
    /// Store the forward pass for the RTS smoother.
    pub keep_forward_pass: bool,
}

/// What a run returns besides the records.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutput {
    /// Number of epochs processed.
    pub epochs: usize,
    /// Final state estimate.
    pub final_state: DVector<f64>,
    /// Final covariance.
    pub final_covariance: DMatrix<f64>,
    /// Stored forward pass (empty unless asked for).
    pub forward: Vec<ForwardEpoch<Dyn>>,
}
