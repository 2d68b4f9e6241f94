//! Rauch–Tung–Striebel fixed-interval smoother over a stored forward pass
//! (Rauch, Tung & Striebel, AIAA J. 3(8), 1965; Särkkä, *Bayesian Filtering
//! and Smoothing*, Thm 8.2).
//!
//! The forward pass stores, per epoch k, the transition Φ_k that led into it,
//! the predicted (x⁻_k, P⁻_k) and the filtered (x_k, P_k). The backward pass is
//! `C_k = P_k Φ_{k+1}ᵀ (P⁻_{k+1})⁻¹` (by Cholesky solve of P⁻_{k+1}),
//! `xˢ_k = x_k + C_k (xˢ_{k+1} − x⁻_{k+1})`,
//! `Pˢ_k = P_k + C_k (Pˢ_{k+1} − P⁻_{k+1}) C_kᵀ`.

use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector, allocator::Allocator};

use crate::check;
use crate::error::{EstimationError, Matrix, Result, Step};

/// One epoch of a stored forward pass.
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardEpoch<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Transition from the previous epoch into this one (unused for the first epoch).
    pub phi: OMatrix<f64, N, N>,
    /// Predicted state x⁻_k.
    pub x_predicted: OVector<f64, N>,
    /// Predicted covariance P⁻_k.
    pub p_predicted: OMatrix<f64, N, N>,
    /// Filtered state x_k (equal to the prediction when there was no measurement).
    pub x_filtered: OVector<f64, N>,
    /// Filtered covariance P_k.
    pub p_filtered: OMatrix<f64, N, N>,
}

/// A smoothed epoch: (xˢ_k, Pˢ_k).
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedEpoch<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Smoothed state.
    pub x: OVector<f64, N>,
    /// Smoothed covariance.
    pub p: OMatrix<f64, N, N>,
}

/// Run the RTS backward pass over `forward` (oldest first). The last smoothed
/// epoch equals the last filtered one.
pub fn rts_smooth<N: Dim>(forward: &[ForwardEpoch<N>]) -> Result<Vec<SmoothedEpoch<N>>>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    let Some(last) = forward.last() else {
        return Ok(Vec::new());
    };
    let mut out = Vec::with_capacity(forward.len());
    out.push(SmoothedEpoch {
        x: last.x_filtered.clone(),
        p: last.p_filtered.clone(),
    });
    for k in (0..forward.len() - 1).rev() {
        let cur = &forward[k];
        let next = &forward[k + 1];
        let later = out.last().expect("pushed before the loop");
        // A frozen state (a switched-off state: variance exactly zero, its
        // row and column zero, Φ diagonal there) is set aside by a unit
        // diagonal: P⁻ becomes block diagonal, the solve for the other
        // states is unchanged and the frozen state's gain is zero (P_k has a
        // zero row there).
        let mut p_predicted = next.p_predicted.clone();
        for i in 0..p_predicted.nrows() {
            if p_predicted[(i, i)] == 0.0 {
                p_predicted[(i, i)] = 1.0;
            }
        }
        let chol = Cholesky::new(p_predicted).ok_or(
            EstimationError::NotPositiveDefinite {
                step: Step::Smooth,
                matrix: Matrix::PPredicted,
            }
            .at_epoch(k + 1),
        )?;
        // C_kᵀ = (P⁻_{k+1})⁻¹ Φ_{k+1} P_k, since P⁻ and P_k are symmetric.
        let c = chol.solve(&(&next.phi * &cur.p_filtered)).transpose();
        let x = &cur.x_filtered + &c * (&later.x - &next.x_predicted);
        let mut p = &cur.p_filtered + &c * (&later.p - &next.p_predicted) * c.transpose();
        check::symmetrize(&mut p);
        check::finite(&x, Step::Smooth, Matrix::X).map_err(|e| e.at_epoch(k))?;
        check::finite(&p, Step::Smooth, Matrix::P).map_err(|e| e.at_epoch(k))?;
        out.push(SmoothedEpoch { x, p });
    }
    out.reverse();
    Ok(out)
}
