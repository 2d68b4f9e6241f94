//! The one error type of the estimation engine.
//!
//! Every failure names the *step* that failed (predict, update, …) and the
//! *matrix* at fault, so a caller can tell "R is not positive definite at the
//! update" from "P went non-finite after the predict" without a debugger.

use std::fmt;

/// The step of the engine in which an error was detected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Step {
    /// Building a filter from its initial state and covariance.
    Initialise,
    /// Time update `x = Φ x`, `P = Φ P Φᵀ + Q`.
    Predict,
    /// Measurement update in batch (vector) form.
    Update,
    /// Measurement update one scalar component at a time.
    SequentialUpdate,
    /// Time update of the information filter or Fisher recursion.
    InformationPredict,
    /// Measurement update of the information filter or Fisher recursion.
    InformationUpdate,
    /// Inversion of the Fisher information into the Cramér–Rao bound.
    CramerRao,
    /// Rauch–Tung–Striebel backward pass.
    Smooth,
    /// Steady-state (algebraic Riccati) solution.
    Riccati,
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Step::Initialise => "initialise",
            Step::Predict => "predict",
            Step::Update => "update",
            Step::SequentialUpdate => "sequential update",
            Step::InformationPredict => "information predict",
            Step::InformationUpdate => "information update",
            Step::CramerRao => "Cramér–Rao bound",
            Step::Smooth => "RTS smoother",
            Step::Riccati => "Riccati solution",
        };
        f.write_str(s)
    }
}

/// The matrix (or vector) an error refers to, by its name in the equations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Matrix {
    /// State estimate x.
    X,
    /// State covariance P.
    P,
    /// Predicted state covariance P⁻.
    PPredicted,
    /// Transition matrix Φ.
    Phi,
    /// Process noise covariance Q.
    Q,
    /// Measurement matrix H.
    H,
    /// Measurement noise covariance R.
    R,
    /// Measurement vector z.
    Z,
    /// Innovation covariance S = H P Hᵀ + R (or the policy's replacement).
    S,
    /// Kalman gain K.
    K,
    /// Innovation (residual) vector ν, as given or replaced by a policy.
    Innovation,
    /// Fisher information matrix F (or information matrix Y = P⁻¹).
    Information,
    /// Information vector y = P⁻¹ x.
    InformationVector,
}

impl fmt::Display for Matrix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            Matrix::X => "x",
            Matrix::P => "P",
            Matrix::PPredicted => "P⁻ (predicted covariance)",
            Matrix::Phi => "Φ (transition)",
            Matrix::Q => "Q (process noise)",
            Matrix::H => "H (measurement matrix)",
            Matrix::R => "R (measurement noise)",
            Matrix::Z => "z (measurement)",
            Matrix::S => "S (innovation covariance)",
            Matrix::K => "K (gain)",
            Matrix::Innovation => "ν (innovation)",
            Matrix::Information => "F (information matrix)",
            Matrix::InformationVector => "y (information vector)",
        };
        f.write_str(s)
    }
}

/// Everything that can go wrong in the engine. Never a panic, never a silent NaN.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum EstimationError {
    /// A matrix held NaN or ±∞ (on input or after the step).
    #[error("{step}: {matrix} contains a non-finite value")]
    NonFinite {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
    },
    /// A covariance that must be positive definite (S, R, P⁻ …) is not.
    #[error("{step}: {matrix} is not positive definite")]
    NotPositiveDefinite {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
    },
    /// A matrix that must be invertible (Φ in the information recursion) is singular.
    #[error("{step}: {matrix} is singular")]
    Singular {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
    },
    /// A matrix that must be symmetric is not (beyond rounding).
    #[error("{step}: {matrix} is not symmetric (largest asymmetry {asymmetry:e})")]
    NotSymmetric {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
        /// max |A − Aᵀ| found.
        asymmetry: f64,
    },
    /// The sequential update needs a diagonal R.
    #[error(
        "{step}: {matrix} must be diagonal for the sequential update (element ({row}, {col}) = {value:e})"
    )]
    NotDiagonal {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
        /// Row of the first off-diagonal non-zero.
        row: usize,
        /// Column of the first off-diagonal non-zero.
        col: usize,
        /// Its value.
        value: f64,
    },
    /// Run-time sized inputs whose shapes do not fit together.
    #[error("{step}: {matrix} has shape {rows}×{cols}, expected {expected_rows}×{expected_cols}")]
    DimensionMismatch {
        /// Step in which it was found.
        step: Step,
        /// Offending matrix.
        matrix: Matrix,
        /// Actual rows.
        rows: usize,
        /// Actual columns.
        cols: usize,
        /// Expected rows.
        expected_rows: usize,
        /// Expected columns.
        expected_cols: usize,
    },
    /// An iterative solution did not converge.
    #[error("{step}: no convergence after {iterations} iterations")]
    NoConvergence {
        /// Step in which it was found.
        step: Step,
        /// Iterations made.
        iterations: usize,
    },
    /// A tuning parameter outside its allowed range (a field of
    /// [`SchemeParameters`](crate::scheme::SchemeParameters), by its name
    /// in configuration files).
    #[error("{parameter} = {value} is out of range: allowed {allowed}")]
    OutOfRange {
        /// The parameter, by its configuration name (`huber_k`).
        parameter: &'static str,
        /// The offending value, as text.
        value: String,
        /// The allowed range, as text (`0.1 ≤ huber_k ≤ 100`).
        allowed: String,
    },
    /// An error at a given epoch of a filter run (wraps the error of that epoch).
    ///
    /// The wrapped error is part of the message and deliberately not also
    /// returned by `Error::source`, so a printer walking the chain shows it
    /// once.
    #[error("epoch {epoch}: {error}")]
    AtEpoch {
        /// Zero-based epoch index.
        epoch: usize,
        /// The error at that epoch.
        error: Box<EstimationError>,
    },
}

impl EstimationError {
    /// Attach the epoch index at which this error happened.
    pub fn at_epoch(self, epoch: usize) -> Self {
        EstimationError::AtEpoch {
            epoch,
            error: Box::new(self),
        }
    }
}

/// Result alias of the engine.
pub type Result<T> = std::result::Result<T, EstimationError>;
