//! Information form: the information filter and the Fisher-information /
//! Cramér–Rao recursion of spec 10.
//!
//! With Y = P⁻¹ and y = P⁻¹ x the measurement update is additive,
//! `Y += Hᵀ R⁻¹ H`, `y += Hᵀ R⁻¹ z`, and a diffuse prior (Y = 0) is allowed.
//! The time update uses `M = Φ⁻ᵀ Y Φ⁻¹` and then `Y⁻ = (I + M Q)⁻¹ M`,
//! `y⁻ = (I + M Q)⁻¹ Φ⁻ᵀ y`, which is `(M⁻¹ + Q)⁻¹` without ever inverting M
//! (so it holds for singular M), by the identity `(M⁻¹ + Q) M (I + Q M)⁻¹ = I`.
//! With Q = 0 it reduces to the Fisher recursion of spec 10,
//! `F(n) = Φ⁻ᵀ F(n−1) Φ⁻¹ + Cᵀ R⁻¹ C`, whose inverse P_Γ = F⁻¹ is the
//! Cramér–Rao lower bound of the estimation error covariance.
//! Every inverse above is applied by LU or Cholesky solve.

use nalgebra::{Cholesky, DefaultAllocator, Dim, DimMin, OMatrix, OVector, allocator::Allocator};

use crate::check;
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::FilterAllocator;

/// An information matrix with, optionally, its information vector.
type InformationPair<N> = (OMatrix<f64, N, N>, Option<OVector<f64, N>>);

/// A state estimate with its covariance.
pub type StateAndCovariance<N> = (OVector<f64, N>, OMatrix<f64, N, N>);

/// `Hᵀ R⁻¹ H` and, if given, `Hᵀ R⁻¹ z`, by Cholesky solve of R.
fn measurement_information<N: Dim, M: Dim>(
    h: &OMatrix<f64, M, N>,
    r: &OMatrix<f64, M, M>,
    z: Option<&OVector<f64, M>>,
) -> Result<InformationPair<N>>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let step = Step::InformationUpdate;
    check::shape(r, (h.nrows(), h.nrows()), step, Matrix::R)?;
    check::finite(h, step, Matrix::H)?;
    check::finite(r, step, Matrix::R)?;
    check::symmetric(r, step, Matrix::R)?;
    let chol = Cholesky::new(r.clone()).ok_or(EstimationError::NotPositiveDefinite {
        step,
        matrix: Matrix::R,
    })?;
    let rinv_h = chol.solve(h);
    let info = h.transpose() * rinv_h;
    let vec = match z {
        Some(z) => {
            check::shape(z, (h.nrows(), 1), step, Matrix::Z)?;
            check::finite(z, step, Matrix::Z)?;
            Some(h.transpose() * chol.solve(z))
        }
        None => None,
    };
    Ok((info, vec))
}

/// `Φ⁻ᵀ Y Φ⁻¹` and `Φ⁻ᵀ y` by LU solves with Φᵀ.
fn transport_information<N: Dim + DimMin<N, Output = N>>(
    phi: &OMatrix<f64, N, N>,
    info: &OMatrix<f64, N, N>,
    vec: Option<&OVector<f64, N>>,
) -> Result<InformationPair<N>>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    let step = Step::InformationPredict;
    let n = info.nrows();
    check::shape(phi, (n, n), step, Matrix::Phi)?;
    check::finite(phi, step, Matrix::Phi)?;
    let singular = EstimationError::Singular {
        step,
        matrix: Matrix::Phi,
    };
    let lu = phi.transpose().lu();
    // T = Φ⁻ᵀ Y; then M = Φ⁻ᵀ Tᵀ = Φ⁻ᵀ Y Φ⁻¹ (Y symmetric).
    let t = lu.solve(info).ok_or(singular.clone())?;
    let mut m = lu.solve(&t.transpose()).ok_or(singular.clone())?;
    check::symmetrize(&mut m);
    let v = match vec {
        Some(y) => Some(lu.solve(y).ok_or(singular)?),
        None => None,
    };
    Ok((m, v))
}

/// The information filter (Y = P⁻¹, y = P⁻¹ x).
#[derive(Debug, Clone, PartialEq)]
pub struct InformationFilter<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    info_vector: OVector<f64, N>,
    info_matrix: OMatrix<f64, N, N>,
}

impl<N: Dim + DimMin<N, Output = N>> InformationFilter<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Start from information y0 = P0⁻¹ x0 and Y0 = P0⁻¹ (Y0 may be singular: diffuse prior).
    pub fn new(info_vector: OVector<f64, N>, info_matrix: OMatrix<f64, N, N>) -> Result<Self> {
        let step = Step::Initialise;
        let n = info_vector.len();
        check::shape(&info_matrix, (n, n), step, Matrix::Information)?;
        check::finite(&info_vector, step, Matrix::InformationVector)?;
        check::finite(&info_matrix, step, Matrix::Information)?;
        check::symmetric(&info_matrix, step, Matrix::Information)?;
        Ok(Self {
            info_vector,
            info_matrix,
        })
    }

    /// Start from a state and a positive definite covariance.
    pub fn from_covariance(x0: &OVector<f64, N>, p0: &OMatrix<f64, N, N>) -> Result<Self> {
        let chol = Cholesky::new(p0.clone()).ok_or(EstimationError::NotPositiveDefinite {
            step: Step::Initialise,
            matrix: Matrix::P,
        })?;
        let mut y = chol.inverse();
        check::symmetrize(&mut y);
        Self::new(chol.solve(x0), y)
    }

    /// Information matrix Y.
    pub fn information_matrix(&self) -> &OMatrix<f64, N, N> {
        &self.info_matrix
    }

    /// Information vector y.
    pub fn information_vector(&self) -> &OVector<f64, N> {
        &self.info_vector
    }

    /// Time update with (Φ, Q).
    pub fn predict(&mut self, phi: &OMatrix<f64, N, N>, q: &OMatrix<f64, N, N>) -> Result<()> {
        let step = Step::InformationPredict;
        let n = self.info_vector.len();
        check::shape(q, (n, n), step, Matrix::Q)?;
        check::finite(q, step, Matrix::Q)?;
        let (m, b) = transport_information(phi, &self.info_matrix, Some(&self.info_vector))?;
        let b = b.unwrap_or_else(|| self.info_vector.clone());
        let (nd, _) = m.shape_generic();
        let g = OMatrix::<f64, N, N>::identity_generic(nd, nd) + &m * q;
        let lu = g.lu();
        let singular = EstimationError::Singular {
            step,
            matrix: Matrix::Information,
        };
        let mut y = lu.solve(&m).ok_or(singular.clone())?;
        check::symmetrize(&mut y);
        let v = lu.solve(&b).ok_or(singular)?;
        check::finite(&y, step, Matrix::Information)?;
        check::finite(&v, step, Matrix::InformationVector)?;
        self.info_matrix = y;
        self.info_vector = v;
        Ok(())
    }

    /// Measurement update: `Y += Hᵀ R⁻¹ H`, `y += Hᵀ R⁻¹ z`.
    pub fn update<M: Dim>(
        &mut self,
        z: &OVector<f64, M>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        check::shape(
            h,
            (z.len(), self.info_vector.len()),
            Step::InformationUpdate,
            Matrix::H,
        )?;
        let (info, vec) = measurement_information(h, r, Some(z))?;
        self.info_matrix += info;
        if let Some(v) = vec {
            self.info_vector += v;
        }
        Ok(())
    }

    /// Back to covariance form: (x̂, P). Fails while Y is singular (not yet observable).
    pub fn state_and_covariance(&self) -> Result<StateAndCovariance<N>> {
        let chol = Cholesky::new(self.info_matrix.clone()).ok_or(
            EstimationError::NotPositiveDefinite {
                step: Step::CramerRao,
                matrix: Matrix::Information,
            },
        )?;
        let mut p = chol.inverse();
        check::symmetrize(&mut p);
        Ok((chol.solve(&self.info_vector), p))
    }
}

/// The Fisher-information recursion without process noise, and its inverse,
/// the Cramér–Rao lower bound P_Γ (spec 10):
/// `F(0) = P(0)⁻¹`, `F(n) = Φ⁻ᵀ F(n−1) Φ⁻¹ + Hᵀ R⁻¹ H`.
///
/// ```
/// use aidnav_estimation::{FisherInformation, nalgebra::{Matrix1, Vector1}};
/// // Static scalar, prior variance 4, three fixes of variance 1:
/// // F = 1/4 + 3 = 3.25 and the bound is 1/3.25.
/// let mut f = FisherInformation::from_prior_covariance(&Matrix1::new(4.0)).unwrap();
/// for _ in 0..3 {
///     f.step(&Matrix1::new(1.0), &Matrix1::new(1.0), &Matrix1::new(1.0)).unwrap();
/// }
/// let bound = f.cramer_rao_bound().unwrap();
/// assert!((bound[(0, 0)] - 1.0 / 3.25).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FisherInformation<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    f: OMatrix<f64, N, N>,
}

impl<N: Dim + DimMin<N, Output = N>> FisherInformation<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// F(0) = P(0)⁻¹ for a positive definite prior covariance.
    pub fn from_prior_covariance(p0: &OMatrix<f64, N, N>) -> Result<Self> {
        let chol = Cholesky::new(p0.clone()).ok_or(EstimationError::NotPositiveDefinite {
            step: Step::Initialise,
            matrix: Matrix::P,
        })?;
        let mut f = chol.inverse();
        check::symmetrize(&mut f);
        Ok(Self { f })
    }

    /// Start from a given information matrix (zero: no prior information).
    pub fn from_information(f: OMatrix<f64, N, N>) -> Result<Self> {
        check::finite(&f, Step::Initialise, Matrix::Information)?;
        check::symmetric(&f, Step::Initialise, Matrix::Information)?;
        Ok(Self { f })
    }

    /// The current Fisher information F(n).
    pub fn information(&self) -> &OMatrix<f64, N, N> {
        &self.f
    }

    /// Transport through Φ only (an epoch without a measurement).
    pub fn propagate(&mut self, phi: &OMatrix<f64, N, N>) -> Result<()> {
        let (m, _) = transport_information(phi, &self.f, None)?;
        check::finite(&m, Step::InformationPredict, Matrix::Information)?;
        self.f = m;
        Ok(())
    }

    /// Add the information of one measurement (H, R) at the current epoch.
    pub fn add_measurement<M: Dim>(
        &mut self,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        check::shape(
            h,
            (h.nrows(), self.f.nrows()),
            Step::InformationUpdate,
            Matrix::H,
        )?;
        let (info, _) = measurement_information::<N, M>(h, r, None)?;
        self.f += info;
        check::symmetrize(&mut self.f);
        Ok(())
    }

    /// One full step of the recursion: propagate through Φ, then add (H, R).
    pub fn step<M: Dim>(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        h: &OMatrix<f64, M, N>,
        r: &OMatrix<f64, M, M>,
    ) -> Result<()>
    where
        DefaultAllocator: FilterAllocator<N, M>,
    {
        self.propagate(phi)?;
        self.add_measurement(h, r)
    }

    /// P_Γ = F⁻¹ (Cholesky inverse); fails while F is singular.
    pub fn cramer_rao_bound(&self) -> Result<OMatrix<f64, N, N>> {
        let chol = Cholesky::new(self.f.clone()).ok_or(EstimationError::NotPositiveDefinite {
            step: Step::CramerRao,
            matrix: Matrix::Information,
        })?;
        let mut p = chol.inverse();
        check::symmetrize(&mut p);
        Ok(p)
    }
}
