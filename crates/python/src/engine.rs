//! The estimation engine: `KalmanFilter`, the policies, the batch call and
//! the RTS smoother.

use aidnav::estimation::kalman::FilterAllocator;
use aidnav::estimation::scheme::{Scheme as RustScheme, SchemeParameters, SchemePolicy};
use aidnav::estimation::{
    BatchKeep, CovarianceUpdate, DynKalmanFilter, EstimationError, ForwardEpoch,
    KalmanFilter as RustKalmanFilter, Matrix, Step, UpdateRecord, filter_batch, filter_batch_plain,
    rts_smooth as rust_rts_smooth,
};
use nalgebra::{
    Const, DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, OVector, SMatrix, SVector,
};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

use crate::convert::{matrix, py_of_json, to_array1, to_array2, vector};
use crate::errors;

/// Add the engine's classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<KalmanFilter>()?;
    m.add_class::<Update>()?;
    m.add_class::<Policy>()?;
    m.add_function(wrap_pyfunction!(rts_smooth, m)?)?;
    m.add_function(wrap_pyfunction!(scheme_names, m)?)?;
    m.add_function(wrap_pyfunction!(scheme_defaults, m)?)?;
    Ok(())
}

/// A measurement policy: decides, per update, what to do with the
/// innovation (accept, reject, limit, re-weight, adapt the gain). Made by
/// `Policy.chi2_gate(p)`, `Policy.huber(k)` or `Policy.scheme(name, ...)`
/// (every scheme of the registry, `scheme_names()`); a policy keeps its
/// state (windows, rejection counts) across the updates it decides.
#[pyclass(module = "aidnav._aidnav")]
pub struct Policy {
    scheme: RustScheme,
    parameters: SchemeParameters,
    policy: SchemePolicy<Dyn>,
}

#[pymethods]
impl Policy {
    /// A scheme of the registry by name (`accept`, `chi2_gate`,
    /// `recovering_gate`, `huber`, `rejection`, `limiting`,
    /// `adaptive_gain`, `limited_adaptive_gain`, `developed`, `robust`)
    /// with its tuning constants; a constant left `None` takes the
    /// engine's default (`scheme_defaults()`), and each is checked against
    /// the engine's range.
    #[staticmethod]
    #[pyo3(signature = (name, *, chi2_probability=None, recovering_after=None, huber_k=None, anomaly_gamma=None, adaptive_window=None, adaptive_diagonal_rule=None))]
    fn scheme(
        name: &str,
        chi2_probability: Option<f64>,
        recovering_after: Option<usize>,
        huber_k: Option<f64>,
        anomaly_gamma: Option<f64>,
        adaptive_window: Option<usize>,
        adaptive_diagonal_rule: Option<&str>,
    ) -> PyResult<Self> {
        let scheme: RustScheme = name.parse().map_err(PyValueError::new_err)?;
        let d = SchemeParameters::default();
        let adaptive_diagonal_rule = match adaptive_diagonal_rule {
            None => d.adaptive_diagonal_rule,
            Some(rule) => serde_json::from_value(rule.into()).map_err(|e| {
                PyValueError::new_err(format!("adaptive_diagonal_rule = {rule:?}: {e}"))
            })?,
        };
        Self::new(
            scheme,
            SchemeParameters {
                chi2_probability: chi2_probability.unwrap_or(d.chi2_probability),
                recovering_after: recovering_after.unwrap_or(d.recovering_after),
                huber_k: huber_k.unwrap_or(d.huber_k),
                anomaly_gamma: anomaly_gamma.unwrap_or(d.anomaly_gamma),
                adaptive_window: adaptive_window.unwrap_or(d.adaptive_window),
                adaptive_diagonal_rule,
            },
        )
    }

    /// χ² gate: reject when the NIS exceeds the χ²(m) quantile of
    /// `probability` (`None`: the engine's default).
    #[staticmethod]
    #[pyo3(signature = (probability=None))]
    fn chi2_gate(probability: Option<f64>) -> PyResult<Self> {
        Self::scheme("chi2_gate", probability, None, None, None, None, None)
    }

    /// Huber re-weighting: R inflated by √NIS / k above k (`None`: the
    /// engine's default k).
    #[staticmethod]
    #[pyo3(signature = (k=None))]
    fn huber(k: Option<f64>) -> PyResult<Self> {
        Self::scheme("huber", None, None, k, None, None, None)
    }

    /// The scheme's name in the registry.
    #[getter]
    fn name(&self) -> &'static str {
        self.scheme.name()
    }

    /// What the scheme does to the process noise: `fixed`, or `feedback`
    /// (spec 20 eq. 3: the caller adds K ν νᵀ Kᵀ of the previous update to
    /// Q; the engine's `predict` takes whatever Q it is given).
    #[getter]
    fn noise_rule(&self) -> &'static str {
        match self.scheme.noise_rule() {
            aidnav::estimation::NoiseRule::Fixed => "fixed",
            aidnav::estimation::NoiseRule::Feedback { .. } => "feedback",
        }
    }

    /// The tuning constants, a dict by the engine's names.
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        parameters_dict(py, &self.parameters)
    }

    /// Forget the state kept across updates (a fresh policy).
    fn reset(&mut self) {
        self.policy = self.scheme.policy(&self.parameters);
    }

    fn __repr__(&self) -> String {
        format!("Policy.scheme({:?})", self.scheme.name())
    }
}

impl Policy {
    /// `scheme` with `parameters`, checked by the engine
    /// ([`SchemeParameters::validate`]: the error names the parameter, its
    /// value and its range).
    fn new(scheme: RustScheme, parameters: SchemeParameters) -> PyResult<Self> {
        parameters
            .validate()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Self {
            scheme,
            parameters,
            policy: scheme.policy(&parameters),
        })
    }
}

/// Scheme parameters as a dict, by the engine's (serde) names.
fn parameters_dict<'py>(py: Python<'py>, p: &SchemeParameters) -> PyResult<Bound<'py, PyAny>> {
    let value = serde_json::to_value(p).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py_of_json(py, &value)
}

/// The engine's default tuning constants of the schemes, a dict by the
/// keyword names of `Policy.scheme` (the `[gnss]` keys of `process`).
#[pyfunction]
fn scheme_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    parameters_dict(py, &SchemeParameters::default())
}

/// The names of the registry's schemes, in the order of the tables.
#[pyfunction]
fn scheme_names() -> Vec<&'static str> {
    RustScheme::ALL.iter().map(|s| s.name()).collect()
}

/// What one measurement update did.
#[pyclass(module = "aidnav._aidnav", frozen)]
pub struct Update {
    record: UpdateRecord<Dyn, Dyn>,
}

#[pymethods]
impl Update {
    /// Innovation ν = z − H x⁻ (before any policy change).
    #[getter]
    fn residual<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_array1(py, &self.record.residual)
    }
    /// Innovation covariance S = H P⁻ Hᵀ + R.
    #[getter(S)]
    fn s<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        to_array2(py, &self.record.s)
    }
    /// Gain applied (zero when rejected).
    #[getter]
    fn gain<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        to_array2(py, &self.record.gain)
    }
    /// Normalised innovation squared νᵀ S⁻¹ ν.
    #[getter]
    fn nis(&self) -> f64 {
        self.record.nis
    }
    /// What the policy decided: `accepted`, `rejected`, `limited`,
    /// `reweighted`, `adaptive_gain`.
    #[getter]
    fn outcome(&self) -> &'static str {
        self.record.outcome.as_str()
    }
    /// Gaussian log-likelihood of the innovation.
    #[getter]
    fn log_likelihood(&self) -> f64 {
        self.record.log_likelihood()
    }
    fn __repr__(&self) -> String {
        format!(
            "Update(outcome={:?}, nis={}, m={})",
            self.record.outcome.as_str(),
            self.record.nis,
            self.record.residual.len()
        )
    }
}

/// A filter of any size behind one interface: fixed-size (`Const<n>`)
/// filters for the sizes of [`new_filter`] (1–6, 9, 12, 15, 18, 21, 24),
/// whose products the compiler unrolls (about twice as fast at 15 states),
/// run-time sized otherwise (each fixed size costs compile time). Matrices
/// arrive row-major, as numpy holds them.
trait AnyFilter: Send + Sync {
    fn dim(&self) -> usize;
    fn state(&self) -> DVector<f64>;
    fn covariance(&self) -> DMatrix<f64>;
    fn set_state(&mut self, x: DVector<f64>) -> Result<(), EstimationError>;
    fn set_covariance(&mut self, p: &[f64]) -> Result<(), EstimationError>;
    fn predict(&mut self, phi: &[f64], q: &[f64]) -> Result<(), EstimationError>;
    fn update(
        &mut self,
        z: &DVector<f64>,
        h: &[f64],
        r: &DMatrix<f64>,
        policy: Option<&mut SchemePolicy<Dyn>>,
    ) -> Result<UpdateRecord<Dyn, Dyn>, EstimationError>;
    #[allow(clippy::too_many_arguments)]
    fn batch(
        &mut self,
        phi: &[f64],
        q: &[f64],
        h: &[f64],
        r: &DMatrix<f64>,
        z: &[f64],
        predict_first: bool,
        policy: Option<&mut SchemePolicy<Dyn>>,
        keep: BatchKeep,
    ) -> Result<Batch, EstimationError>;
    fn boxed_clone(&self) -> Box<dyn AnyFilter>;
}

/// A batch's arrays, flat and row-major, with the smoothed pass.
struct Batch {
    states: Vec<f64>,
    covariances: Vec<f64>,
    residuals: Vec<f64>,
    nis: Vec<f64>,
    outcomes: Vec<&'static str>,
    smoothed: Option<(Vec<f64>, Vec<f64>)>,
    steady_epochs: usize,
}

/// The plain update with M fixed: the same arithmetic as the `Dyn` path.
fn update_fixed_m<N: Dim, const M: usize>(
    kf: &mut RustKalmanFilter<N>,
    z: &DVector<f64>,
    h: &[f64],
    r: &DMatrix<f64>,
) -> Result<UpdateRecord<Dyn, Dyn>, EstimationError>
where
    DefaultAllocator: FilterAllocator<N, Const<M>> + FilterAllocator<N, Dyn>,
{
    let n = kf.dim();
    check_len(h.len(), (M, n), Step::Update, Matrix::H)?;
    check_len(r.len(), (M, M), Step::Update, Matrix::R)?;
    let (nd, _) = kf.covariance().shape_generic();
    let hm = OMatrix::<f64, Const<M>, N>::from_row_slice_generic(Const::<M>, nd, h);
    let zm = OMatrix::<f64, Const<M>, nalgebra::U1>::from_column_slice_generic(
        Const::<M>,
        nalgebra::U1,
        z.as_slice(),
    );
    let rm = OMatrix::<f64, Const<M>, Const<M>>::from_column_slice_generic(
        Const::<M>,
        Const::<M>,
        r.as_slice(),
    );
    let rec = kf.update(&zm, &hm, &rm)?;
    Ok(UpdateRecord::<Dyn, Dyn> {
        residual: DVector::from_column_slice(rec.residual.as_slice()),
        s: DMatrix::from_column_slice(M, M, rec.s.as_slice()),
        gain: DMatrix::from_column_slice(n, M, rec.gain.as_slice()),
        nis: rec.nis,
        outcome: rec.outcome,
    })
}

impl<N: Dim> AnyFilter for RustKalmanFilter<N>
where
    // Measurement sizes served by fixed-size code when no policy is given
    // (a policy keeps state sized at run time: it takes the `Dyn` path).
    DefaultAllocator: FilterAllocator<N, Dyn>
        + FilterAllocator<N, Const<1>>
        + FilterAllocator<N, Const<2>>
        + FilterAllocator<N, Const<3>>
        + FilterAllocator<N, Const<4>>
        + FilterAllocator<N, Const<5>>
        + FilterAllocator<N, Const<6>>,
    RustKalmanFilter<N>: Send + Sync + 'static,
{
    fn dim(&self) -> usize {
        RustKalmanFilter::dim(self)
    }
    fn state(&self) -> DVector<f64> {
        DVector::from_column_slice(RustKalmanFilter::state(self).as_slice())
    }
    fn covariance(&self) -> DMatrix<f64> {
        let n = RustKalmanFilter::dim(self);
        DMatrix::from_column_slice(n, n, RustKalmanFilter::covariance(self).as_slice())
    }
    fn set_state(&mut self, x: DVector<f64>) -> Result<(), EstimationError> {
        let (nd, _) = RustKalmanFilter::covariance(self).shape_generic();
        check_len(
            x.len(),
            (RustKalmanFilter::dim(self), 1),
            Step::Initialise,
            Matrix::X,
        )?;
        RustKalmanFilter::set_state(
            self,
            OVector::<f64, N>::from_column_slice_generic(nd, nalgebra::U1, x.as_slice()),
        )
    }
    fn set_covariance(&mut self, p: &[f64]) -> Result<(), EstimationError> {
        let p = square_of::<N>(self, p, Step::Initialise, Matrix::P)?;
        RustKalmanFilter::set_covariance(self, p)
    }
    fn predict(&mut self, phi: &[f64], q: &[f64]) -> Result<(), EstimationError> {
        let phi = square_of::<N>(self, phi, Step::Predict, Matrix::Phi)?;
        let q = square_of::<N>(self, q, Step::Predict, Matrix::Q)?;
        RustKalmanFilter::predict(self, &phi, &q)
    }
    fn update(
        &mut self,
        z: &DVector<f64>,
        h: &[f64],
        r: &DMatrix<f64>,
        policy: Option<&mut SchemePolicy<Dyn>>,
    ) -> Result<UpdateRecord<Dyn, Dyn>, EstimationError> {
        if policy.is_none() {
            match z.len() {
                1 => return update_fixed_m::<N, 1>(self, z, h, r),
                2 => return update_fixed_m::<N, 2>(self, z, h, r),
                3 => return update_fixed_m::<N, 3>(self, z, h, r),
                4 => return update_fixed_m::<N, 4>(self, z, h, r),
                5 => return update_fixed_m::<N, 5>(self, z, h, r),
                6 => return update_fixed_m::<N, 6>(self, z, h, r),
                _ => {}
            }
        }
        let h = rows_of::<N>(self, h, z.len())?;
        let rec = match policy {
            None => RustKalmanFilter::update(self, z, &h, r),
            Some(p) => RustKalmanFilter::update_with(self, z, &h, r, p),
        }?;
        let (n, m) = (RustKalmanFilter::dim(self), z.len());
        Ok(UpdateRecord::<Dyn, Dyn> {
            residual: rec.residual,
            s: rec.s,
            gain: DMatrix::from_column_slice(n, m, rec.gain.as_slice()),
            nis: rec.nis,
            outcome: rec.outcome,
        })
    }
    fn batch(
        &mut self,
        phi: &[f64],
        q: &[f64],
        h: &[f64],
        r: &DMatrix<f64>,
        z: &[f64],
        predict_first: bool,
        policy: Option<&mut SchemePolicy<Dyn>>,
        keep: BatchKeep,
    ) -> Result<Batch, EstimationError> {
        let phi = square_of::<N>(self, phi, Step::Predict, Matrix::Phi)?;
        let q = square_of::<N>(self, q, Step::Predict, Matrix::Q)?;
        let h = rows_of::<N>(self, h, r.nrows())?;
        let out = match policy {
            None => filter_batch_plain(self, &phi, &q, &h, r, z, predict_first, keep),
            Some(p) => filter_batch(self, &phi, &q, &h, r, z, predict_first, p, keep),
        }?;
        let smoothed = if keep.forward {
            let s = rust_rts_smooth(&out.forward)?;
            let xs = s.iter().flat_map(|e| e.x.iter().copied()).collect();
            // P is symmetric: its column-major slice is its row-major one.
            let ps = s.iter().flat_map(|e| e.p.iter().copied()).collect();
            Some((xs, ps))
        } else {
            None
        };
        Ok(Batch {
            states: out.states,
            covariances: out.covariances,
            residuals: out.residuals,
            nis: out.nis,
            outcomes: out.outcomes.iter().map(|o| o.as_str()).collect(),
            smoothed,
            steady_epochs: out.steady_epochs,
        })
    }
    fn boxed_clone(&self) -> Box<dyn AnyFilter> {
        Box::new(self.clone())
    }
}

/// The engine's shape error for a matrix that does not fit.
fn check_len(
    len: usize,
    (rows, cols): (usize, usize),
    step: Step,
    matrix: Matrix,
) -> Result<(), EstimationError> {
    if len == rows * cols {
        return Ok(());
    }
    Err(EstimationError::DimensionMismatch {
        step,
        matrix,
        rows: len / cols.max(1),
        cols,
        expected_rows: rows,
        expected_cols: cols,
    })
}

/// A row-major n×n slice as the filter's square matrix.
fn square_of<N: Dim>(
    kf: &RustKalmanFilter<N>,
    s: &[f64],
    step: Step,
    matrix: Matrix,
) -> Result<OMatrix<f64, N, N>, EstimationError>
where
    DefaultAllocator: FilterAllocator<N, Dyn>,
{
    let n = kf.dim();
    check_len(s.len(), (n, n), step, matrix)?;
    let (nd, _) = kf.covariance().shape_generic();
    Ok(OMatrix::<f64, N, N>::from_row_slice_generic(nd, nd, s))
}

/// A row-major m×n slice as H.
fn rows_of<N: Dim>(
    kf: &RustKalmanFilter<N>,
    s: &[f64],
    m: usize,
) -> Result<OMatrix<f64, Dyn, N>, EstimationError>
where
    DefaultAllocator: FilterAllocator<N, Dyn>,
{
    let n = kf.dim();
    check_len(s.len(), (m, n), Step::Update, Matrix::H)?;
    let (nd, _) = kf.covariance().shape_generic();
    Ok(OMatrix::<f64, Dyn, N>::from_row_slice_generic(
        Dyn(m),
        nd,
        s,
    ))
}

/// A new filter of the size of `x0`: fixed-size for the common sizes.
fn new_filter(
    x0: &[f64],
    p0: &[f64],
    form: CovarianceUpdate,
) -> Result<Box<dyn AnyFilter>, EstimationError> {
    let n = x0.len();
    check_len(p0.len(), (n, n), Step::Initialise, Matrix::P)?;
    macro_rules! fixed {
        ($($k:literal)*) => {
            match n {
                $($k => {
                    let kf = RustKalmanFilter::<Const<$k>>::new(
                        SVector::<f64, $k>::from_column_slice(x0),
                        SMatrix::<f64, $k, $k>::from_row_slice(p0),
                    )?;
                    return Ok(Box::new(kf.with_covariance_update(form)));
                })*
                _ => {}
            }
        };
    }
    fixed!(1 2 3 4 5 6 9 12 15 18 21 24);

    let kf = DynKalmanFilter::new(
        DVector::from_column_slice(x0),
        DMatrix::from_row_slice(n, n, p0),
    )?;
    Ok(Box::new(kf.with_covariance_update(form)))
}

/// A 2-D array's values, row-major, and its shape.
fn row_major(a: &PyReadonlyArray2<'_, f64>) -> (Vec<f64>, (usize, usize)) {
    let v = a.as_array();
    let dim = v.dim();
    let data = match v.as_slice() {
        Some(s) => s.to_vec(),
        None => v.iter().copied().collect(),
    };
    (data, dim)
}

/// An n×n argument's shape, refused as the engine refuses it.
fn shape_is(dim: (usize, usize), n: usize, step: Step, matrix: Matrix) -> PyResult<()> {
    if dim == (n, n) {
        return Ok(());
    }
    Err(errors::estimation(EstimationError::DimensionMismatch {
        step,
        matrix,
        rows: dim.0,
        cols: dim.1,
        expected_rows: n,
        expected_cols: n,
    }))
}

/// H's shape (m × n), refused as the engine refuses it.
fn h_is(dim: (usize, usize), m: usize, n: usize) -> PyResult<()> {
    if dim == (m, n) {
        return Ok(());
    }
    Err(errors::estimation(EstimationError::DimensionMismatch {
        step: Step::Update,
        matrix: Matrix::H,
        rows: dim.0,
        cols: dim.1,
        expected_rows: m,
        expected_cols: n,
    }))
}

/// A linear Kalman filter (the engine's `KalmanFilter`): Joseph-form
/// update, Cholesky-solved gain, P symmetrised and checked after every
/// step. Fixed-size code for 1–6, 9, 12, 15, 18, 21 and 24 states,
/// run-time sized otherwise: the same arithmetic either way.
#[pyclass(module = "aidnav._aidnav")]
pub struct KalmanFilter {
    kf: Box<dyn AnyFilter>,
}

fn square(name: &str, m: &DMatrix<f64>, n: usize) -> PyResult<()> {
    if m.nrows() != n || m.ncols() != n {
        return Err(PyValueError::new_err(format!(
            "{name} has shape {}×{}, expected {n}×{n}",
            m.nrows(),
            m.ncols()
        )));
    }
    Ok(())
}

fn policy_of<'py>(
    policy: Option<&'py Bound<'py, PyAny>>,
) -> PyResult<Option<PyRefMut<'py, Policy>>> {
    match policy {
        None => Ok(None),
        Some(p) if p.is_none() => Ok(None),
        Some(p) => p.extract::<PyRefMut<'py, Policy>>().map(Some).map_err(|_| {
            PyTypeError::new_err(format!(
                "policy must be an aidnav Policy (chi2_gate, huber, scheme), not {}",
                p.get_type()
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            ))
        }),
    }
}

#[pymethods]
impl KalmanFilter {
    /// A filter at state `x0` with covariance `P0` (symmetric, finite);
    /// `joseph=False` uses the standard covariance update.
    #[new]
    #[pyo3(signature = (x0, P0, joseph=true))]
    #[allow(non_snake_case)]
    fn new(
        x0: PyReadonlyArray1<'_, f64>,
        P0: PyReadonlyArray2<'_, f64>,
        joseph: bool,
    ) -> PyResult<Self> {
        let form = if joseph {
            CovarianceUpdate::Joseph
        } else {
            CovarianceUpdate::Standard
        };
        let x0 = vector(&x0);
        let (p0, pd) = row_major(&P0);
        shape_is(pd, x0.len(), Step::Initialise, Matrix::P)?;
        let kf = new_filter(x0.as_slice(), &p0, form).map_err(errors::estimation)?;
        Ok(Self { kf })
    }

    /// The state estimate (a copy).
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        to_array1(py, &self.kf.state())
    }

    /// Set the state.
    #[setter]
    fn set_x(&mut self, x: PyReadonlyArray1<'_, f64>) -> PyResult<()> {
        self.kf.set_state(vector(&x)).map_err(errors::estimation)
    }

    /// The covariance (a copy).
    #[getter(P)]
    fn p<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        to_array2(py, &self.kf.covariance())
    }

    /// Set the covariance (checked: symmetric, finite).
    #[setter(P)]
    fn set_p(&mut self, p: PyReadonlyArray2<'_, f64>) -> PyResult<()> {
        let (p, pd) = row_major(&p);
        shape_is(pd, self.kf.dim(), Step::Initialise, Matrix::P)?;
        self.kf.set_covariance(&p).map_err(errors::estimation)
    }

    /// Number of states.
    #[getter]
    fn dim(&self) -> usize {
        self.kf.dim()
    }

    /// Time update x = F x, P = F P Fᵀ + Q.
    #[allow(non_snake_case)]
    fn predict(
        &mut self,
        F: PyReadonlyArray2<'_, f64>,
        Q: PyReadonlyArray2<'_, f64>,
    ) -> PyResult<()> {
        let n = self.kf.dim();
        let (f, fd) = row_major(&F);
        let (q, qd) = row_major(&Q);
        shape_is(fd, n, Step::Predict, Matrix::Phi)?;
        shape_is(qd, n, Step::Predict, Matrix::Q)?;
        self.kf.predict(&f, &q).map_err(errors::estimation)
    }

    /// Measurement update with z (m), H (m×n), R (m×m) under `policy`
    /// (None: accept every measurement); returns what it did.
    #[pyo3(signature = (z, H, R, policy=None))]
    #[allow(non_snake_case)]
    fn update<'py>(
        &mut self,
        z: PyReadonlyArray1<'py, f64>,
        H: PyReadonlyArray2<'py, f64>,
        R: PyReadonlyArray2<'py, f64>,
        policy: Option<&'py Bound<'py, PyAny>>,
    ) -> PyResult<Update> {
        let z = vector(&z);
        let (h, hd) = row_major(&H);
        h_is(hd, z.len(), self.kf.dim())?;
        let r = matrix(&R);
        let record = match policy_of(policy)? {
            None => self.kf.update(&z, &h, &r, None),
            Some(mut p) => self.kf.update(&z, &h, &r, Some(&mut p.policy)),
        }
        .map_err(errors::estimation)?;
        Ok(Update { record })
    }

    /// Run a whole measurement array in one call: for each row of `zs`
    /// (epochs × m; NaN marks a missing component, a row of NaN a missing
    /// epoch) predict with (F, Q) — not before the first row with
    /// `predict_first=False` — then update with the components present
    /// under `policy`. The filter ends at the last epoch. Returns a dict of
    /// arrays: `x` (epochs × n), `residual` (epochs × m), `nis`, `outcome`
    /// (strings); with `covariances=True` also `P` (epochs × n × n); with
    /// `smooth=True` also the RTS-smoothed `x_smooth` and `P_smooth`;
    /// `steady_epochs`: the epochs computed in the Riccati recursion's
    /// steady state, a bit-for-bit fixed point or cycle of up to four
    /// covariances (state only, bit for bit the full step's numbers).
    /// Each epoch's update runs in fixed-size matrices (the components
    /// present, up to six, copied into stack matrices: no allocation per
    /// epoch without a policy), with the GIL released.
    #[pyo3(signature = (zs, F, Q, H, R, policy=None, predict_first=true, covariances=false, smooth=false))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn batch<'py>(
        &mut self,
        py: Python<'py>,
        zs: PyReadonlyArray2<'py, f64>,
        F: PyReadonlyArray2<'py, f64>,
        Q: PyReadonlyArray2<'py, f64>,
        H: PyReadonlyArray2<'py, f64>,
        R: PyReadonlyArray2<'py, f64>,
        policy: Option<&'py Bound<'py, PyAny>>,
        predict_first: bool,
        covariances: bool,
        smooth: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = self.kf.dim();
        let (phi, fd) = row_major(&F);
        let (q, qd) = row_major(&Q);
        shape_is(fd, n, Step::Predict, Matrix::Phi)?;
        shape_is(qd, n, Step::Predict, Matrix::Q)?;
        let (h, hd) = row_major(&H);
        let m = hd.0;
        h_is(hd, m, n)?;
        let r = matrix(&R);
        let (z, (epochs, zc)) = row_major(&zs);
        if zc != m {
            return Err(PyValueError::new_err(format!(
                "zs has {zc} columns, H has {m} rows"
            )));
        }
        let keep = BatchKeep {
            covariance: covariances,
            forward: smooth,
        };
        let mut policy = policy_of(policy)?;
        let kf = &mut self.kf;
        let pol = policy.as_deref_mut().map(|p| &mut p.policy);
        let out = py
            .detach(|| kf.batch(&phi, &q, &h, &r, &z, predict_first, pol, keep))
            .map_err(errors::estimation)?;
        let d = PyDict::new(py);
        d.set_item(
            "x",
            PyArray1::from_vec(py, out.states).reshape([epochs, n])?,
        )?;
        d.set_item(
            "residual",
            PyArray1::from_vec(py, out.residuals).reshape([epochs, m])?,
        )?;
        d.set_item("nis", PyArray1::from_vec(py, out.nis))?;
        d.set_item("outcome", outcome_list(py, &out.outcomes)?)?;
        d.set_item("steady_epochs", out.steady_epochs)?;
        if covariances {
            d.set_item(
                "P",
                PyArray1::from_vec(py, out.covariances).reshape([epochs, n, n])?,
            )?;
        }
        if let Some((xs, ps)) = out.smoothed {
            d.set_item("x_smooth", PyArray1::from_vec(py, xs).reshape([epochs, n])?)?;
            d.set_item(
                "P_smooth",
                PyArray1::from_vec(py, ps).reshape([epochs, n, n])?,
            )?;
        }
        Ok(d)
    }

    /// A copy of the filter.
    fn copy(&self) -> Self {
        Self {
            kf: self.kf.boxed_clone(),
        }
    }

    fn __repr__(&self) -> String {
        format!("KalmanFilter(dim={})", self.kf.dim())
    }
}

/// The outcomes as a list of names, one Python string per distinct name:
/// a string built per epoch was about 8 % of a batch call's time in the
/// garbage collector's bookkeeping.
fn outcome_list<'py>(py: Python<'py>, outcomes: &[&'static str]) -> PyResult<Bound<'py, PyList>> {
    let mut names: Vec<(&'static str, Bound<'py, PyString>)> = Vec::new();
    let mut items = Vec::with_capacity(outcomes.len());
    for &o in outcomes {
        // At most seven names: a linear search.
        let name = match names.iter().find(|(s, _)| *s == o) {
            Some((_, name)) => name.clone(),
            None => {
                let name = PyString::new(py, o);
                names.push((o, name.clone()));
                name
            }
        };
        items.push(name);
    }
    PyList::new(py, items)
}

/// Put `x_smooth` and `P_smooth` into `d`.
fn smoothed_into(
    py: Python<'_>,
    d: &Bound<'_, PyDict>,
    smoothed: &[aidnav::estimation::SmoothedEpoch<Dyn>],
    n: usize,
) -> PyResult<()> {
    let epochs = smoothed.len();
    let xs: Vec<f64> = smoothed.iter().flat_map(|e| e.x.iter().copied()).collect();
    let ps: Vec<f64> = smoothed
        .iter()
        .flat_map(|e| e.p.transpose().iter().copied().collect::<Vec<_>>())
        .collect();
    d.set_item("x_smooth", PyArray1::from_vec(py, xs).reshape([epochs, n])?)?;
    d.set_item(
        "P_smooth",
        PyArray1::from_vec(py, ps).reshape([epochs, n, n])?,
    )?;
    Ok(())
}

/// The RTS smoother over a stored forward pass: filtered states
/// `x_filtered` (epochs × n) and covariances `P_filtered` (epochs × n × n),
/// predicted ones `x_predicted`, `P_predicted`, and the transition `F`
/// into each epoch (n × n, or epochs × n × n). Returns a dict with `x`
/// (epochs × n) and `P` (epochs × n × n).
#[pyfunction]
#[pyo3(signature = (x_filtered, P_filtered, x_predicted, P_predicted, F))]
#[allow(non_snake_case)]
fn rts_smooth<'py>(
    py: Python<'py>,
    x_filtered: PyReadonlyArray2<'py, f64>,
    P_filtered: PyReadonlyArray3<'py, f64>,
    x_predicted: PyReadonlyArray2<'py, f64>,
    P_predicted: PyReadonlyArray3<'py, f64>,
    F: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let (xf, pf, xp, pp) = (
        x_filtered.as_array(),
        P_filtered.as_array(),
        x_predicted.as_array(),
        P_predicted.as_array(),
    );
    let (epochs, n) = xf.dim();
    for (name, shape) in [("P_filtered", pf.dim()), ("P_predicted", pp.dim())] {
        if shape != (epochs, n, n) {
            return Err(PyValueError::new_err(format!(
                "{name} has shape {:?}, expected ({epochs}, {n}, {n})",
                shape
            )));
        }
    }
    if xp.dim() != (epochs, n) {
        return Err(PyValueError::new_err(format!(
            "x_predicted has shape {:?}, expected ({epochs}, {n})",
            xp.dim()
        )));
    }
    let phis: Vec<DMatrix<f64>> = if let Ok(f) = F.extract::<PyReadonlyArray2<'py, f64>>() {
        let f = matrix(&f);
        square("F", &f, n)?;
        vec![f; epochs]
    } else {
        let f: PyReadonlyArray3<'py, f64> = F.extract()?;
        let f = f.as_array();
        if f.dim() != (epochs, n, n) {
            return Err(PyValueError::new_err(format!(
                "F has shape {:?}, expected ({n}, {n}) or ({epochs}, {n}, {n})",
                f.dim()
            )));
        }
        (0..epochs)
            .map(|k| DMatrix::from_fn(n, n, |i, j| f[[k, i, j]]))
            .collect()
    };
    let forward: Vec<ForwardEpoch<Dyn>> = (0..epochs)
        .map(|k| ForwardEpoch {
            phi: phis[k].clone(),
            x_predicted: DVector::from_fn(n, |i, _| xp[[k, i]]),
            p_predicted: DMatrix::from_fn(n, n, |i, j| pp[[k, i, j]]),
            x_filtered: DVector::from_fn(n, |i, _| xf[[k, i]]),
            p_filtered: DMatrix::from_fn(n, n, |i, j| pf[[k, i, j]]),
        })
        .collect();
    let smoothed = py
        .detach(|| rust_rts_smooth(&forward))
        .map_err(errors::estimation)?;
    let d = PyDict::new(py);
    smoothed_into(py, &d, &smoothed, n)?;
    let x = d.get_item("x_smooth")?;
    let p = d.get_item("P_smooth")?;
    let out = PyDict::new(py);
    out.set_item("x", x)?;
    out.set_item("P", p)?;
    Ok(out)
}
