//! Steady-state Kalman covariance from the discrete algebraic Riccati equation
//! (DARE), solved by the structure-preserving doubling algorithm — a method
//! independent of iterating the filter, used as a reference in tests and by
//! users who size a filter before running it.
//!
//! Filtering DARE for the predicted covariance X = P⁻:
//! `X = Φ X Φᵀ − Φ X Hᵀ (H X Hᵀ + R)⁻¹ H X Φᵀ + Q`.
//! With A = Φᵀ, G₀ = Hᵀ R⁻¹ H, H₀ = Q and W = I + G_k H_k the doubling steps
//! (Chu, Fan & Lin, *Linear Algebra Appl.* 396, 2005) are
//! `A_{k+1} = A_k W⁻¹ A_k`, `G_{k+1} = G_k + A_k W⁻¹ G_k A_kᵀ`,
//! `H_{k+1} = H_k + A_kᵀ H_k W⁻¹ A_k`, and H_k → X quadratically.

use nalgebra::{Cholesky, DefaultAllocator, Dim, DimMin, OMatrix, allocator::Allocator};

use crate::check;
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::kalman::FilterAllocator;

/// Iteration cap for the doubling algorithm; it converges quadratically, so a
/// well-posed problem needs a few tens at most.
const MAX_DOUBLING_ITERATIONS: usize = 100;
/// Relative change of X under which the doubling has converged.
const DOUBLING_RTOL: f64 = 1e-14;

/// The steady-state covariances of a time-invariant Kalman filter.
#[derive(Debug, Clone, PartialEq)]
pub struct SteadyState<N: Dim>
where
    DefaultAllocator: Allocator<N, N>,
{
    /// Predicted (a priori) covariance P⁻.
    pub predicted: OMatrix<f64, N, N>,
    /// Filtered (a posteriori) covariance P.
    pub filtered: OMatrix<f64, N, N>,
}

/// Solve the filtering DARE for (Φ, H, Q, R). Requires (Φ, H) detectable and
/// (Φ, Q^{1/2}) stabilisable; otherwise it reports no convergence.
///
/// ```
/// use aidnav_estimation::{steady_state_covariance, nalgebra::Matrix1};
/// // Random walk q = 1 observed with r = 1: P⁻ = (q + √(q² + 4qr)) / 2 = (1 + √5) / 2.
/// let ss = steady_state_covariance(&Matrix1::new(1.0), &Matrix1::new(1.0),
///                                  &Matrix1::new(1.0), &Matrix1::new(1.0)).unwrap();
/// assert!((ss.predicted[(0, 0)] - (1.0 + 5f64.sqrt()) / 2.0).abs() < 1e-12);
/// ```
pub fn steady_state_covariance<N: Dim + DimMin<N, Output = N>, M: Dim>(
    phi: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, M, N>,
    q: &OMatrix<f64, N, N>,
    r: &OMatrix<f64, M, M>,
) -> Result<SteadyState<N>>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let step = Step::Riccati;
    let n = phi.nrows();
    check::shape(phi, (n, n), step, Matrix::Phi)?;
    check::shape(q, (n, n), step, Matrix::Q)?;
    check::shape(h, (h.nrows(), n), step, Matrix::H)?;
    check::shape(r, (h.nrows(), h.nrows()), step, Matrix::R)?;
    for (m, name) in [(phi, Matrix::Phi), (q, Matrix::Q)] {
        check::finite(m, step, name)?;
    }
    check::finite(h, step, Matrix::H)?;
    check::finite(r, step, Matrix::R)?;
    let r_chol = Cholesky::new(r.clone()).ok_or(EstimationError::NotPositiveDefinite {
        step,
        matrix: Matrix::R,
    })?;
    let (nd, _) = phi.shape_generic();
    let eye = OMatrix::<f64, N, N>::identity_generic(nd, nd);
    let mut a = phi.transpose();
    let mut g = h.transpose() * r_chol.solve(h);
    let mut x = q.clone();
    for _ in 0..MAX_DOUBLING_ITERATIONS {
        let w = (&eye + &g * &x).lu();
        let singular = EstimationError::Singular {
            step,
            matrix: Matrix::PPredicted,
        };
        let w_a = w.solve(&a).ok_or(singular.clone())?;
        let w_g = w.solve(&g).ok_or(singular)?;
        let x_next = &x + a.transpose() * &x * &w_a;
        let g_next = &g + &a * w_g * a.transpose();
        let a_next = &a * &w_a;
        let change = (&x_next - &x).norm();
        let scale = x_next.norm().max(f64::MIN_POSITIVE);
        x = x_next;
        check::symmetrize(&mut x);
        g = g_next;
        check::symmetrize(&mut g);
        a = a_next;
        check::finite(&x, step, Matrix::PPredicted)?;
        if change <= DOUBLING_RTOL * scale {
            let s = h * &x * h.transpose() + r;
            let s_chol = Cholesky::new(s).ok_or(EstimationError::NotPositiveDefinite {
                step,
                matrix: Matrix::S,
            })?;
            let hx = h * &x;
            let mut filtered = &x - hx.transpose() * s_chol.solve(&hx);
            check::symmetrize(&mut filtered);
            return Ok(SteadyState {
                predicted: x,
                filtered,
            });
        }
    }
    Err(EstimationError::NoConvergence {
        step,
        iterations: MAX_DOUBLING_ITERATIONS,
    })
}
