//! # aidnav-estimation — the Kalman engine
//!
//! A small, generic estimation engine that knows nothing about navigation:
//!
//! - [`KalmanFilter`]: predict (Φ, Q) and update (z, H, R) with Cholesky-solved
//!   gain and Joseph-form covariance, P kept symmetric, every step checked for
//!   non-finite and non-positive-definite matrices ([`EstimationError`] names the
//!   step and the matrix). One generic type serves compile-time sized filters
//!   (`Const<N>`, allocation-free) and run-time sized ones (`Dyn`).
//! - [`policy`]: measurement policies as values — accept, χ² gate, Huber, and
//!   any closure — that see the innovation and decide; the update returns the
//!   innovation, its covariance and the gain ([`UpdateRecord`]).
//! - the adaptive / anomaly-tolerant policies of spec 20 ([`adaptive`]), and the
//!   classical robust pre-filters seed 004 lists: running median, Tukey 53H
//!   ([`prefilter`]).
//! - sequential scalar update for diagonal R ([`KalmanFilter::update_sequential`]).
//! - time update for a Φ whose trailing rows are diagonal (states that
//!   evolve on their own), at the cost of its leading rows only
//!   ([`KalmanFilter::predict_structured`], [`TrailingDiagonal`]).
//! - second-order discretisation (Φ, Q) of a sparse linear model whose
//!   trailing states evolve on their own ([`SecondOrderPattern`]).
//! - the lower triangle of a symmetric matrix packed and read back, and its
//!   bit-for-bit symmetry ([`push_lower_triangle`], [`read_lower_triangle`],
//!   [`symmetric_bits`]), for recording covariances compactly.
//! - information form and the Fisher / Cramér–Rao recursion ([`InformationFilter`],
//!   [`FisherInformation`]).
//! - information-form update for many sparse observations on a dense
//!   covariance, with blocked factorisations ([`SubspaceUpdate`], [`blocked`]).
//! - Rauch–Tung–Striebel smoother over a stored forward pass ([`rts_smooth`]),
//!   or recorded as the filter runs and evaluated at marked epochs only
//!   ([`RtsRecorder`]).
//! - NIS / NEES with χ² bounds ([`consistency`]).
//! - steady-state covariance from the discrete algebraic Riccati equation
//!   ([`steady_state_covariance`]).
//! - self-organising (GMDH) time-series model selection ([`gmdh`]).
//! - overlapping Allan deviation and the noise terms read from it ([`allan`]).
//! - Nelder–Mead minimisation in a box with batch (parallel) evaluations
//!   ([`optimise`]), and each update's Gaussian log-likelihood
//!   ([`UpdateRecord::log_likelihood`]) for fitting noise by maximum likelihood.
//! - a linear Gaussian model and its filter loop reporting to an [`Observer`]
//!   ([`LinearGaussianModel`]).
//!
//! ```
//! use aidnav_estimation::{KalmanFilter, Chi2Gate, Outcome, nalgebra::{Matrix2, Vector2, Matrix1x2, Vector1, Matrix1}};
//! // Constant-velocity model, position measured; a 50σ outlier is gated out.
//! let dt: f64 = 1.0;
//! let phi = Matrix2::new(1.0, dt, 0.0, 1.0);
//! let q = Matrix2::new(dt.powi(3) / 3.0, dt.powi(2) / 2.0, dt.powi(2) / 2.0, dt) * 0.01;
//! let h = Matrix1x2::new(1.0, 0.0);
//! let r = Matrix1::new(1.0);
//! let mut kf = KalmanFilter::new(Vector2::zeros(), Matrix2::identity()).unwrap();
//! kf.predict(&phi, &q).unwrap();
//! let rec = kf.update_with(&Vector1::new(50.0), &h, &r, &mut Chi2Gate { probability: 0.999 }).unwrap();
//! assert_eq!(rec.outcome, Outcome::Rejected);
//! assert_eq!(kf.state()[0], 0.0);
//! ```

pub mod adaptive;
pub mod allan;
pub mod batch;
pub mod blocked;
pub mod cancel;
mod check;
pub mod consistency;
mod dense;
pub mod discretise;
pub mod error;
pub mod gmdh;
pub mod information;
pub mod kalman;
pub mod linear;
pub mod observer;
pub mod optimise;
pub mod policy;
pub mod prefilter;
pub mod recovery;
pub mod riccati;
pub mod scheme;
pub mod smoother;
pub mod structured;
pub mod subspace;

pub use batch::{
    BatchKeep, BatchOutput, FixedBatchAllocator, MAX_FIXED_MEASUREMENT, MAX_STEADY_PERIOD,
    filter_batch, filter_batch_plain,
};
pub use cancel::{Cancel, Cancelled};
pub use check::all_finite;
pub use consistency::{Chi2Mean, chi2_quantile, mean_chi2_bounds, nees};
pub use dense::{push_lower_triangle, read_lower_triangle, symmetric_bits};
pub use discretise::SecondOrderPattern;
pub use error::{EstimationError, Matrix, Result, Step};
pub use information::{FisherInformation, InformationFilter};
pub use kalman::{
    CovarianceUpdate, DynKalmanFilter, FilterAllocator, FixedKalmanFilter, Innovation,
    KalmanFilter, UpdateRecord,
};
pub use linear::{LinearGaussianModel, RunOptions, RunOutput, UpdateMethod};
pub use observer::{Collect, Discard, EpochRecord, Observer};
pub use policy::{
    AcceptAll, Chi2Gate, Decision, Huber, InnovationView, MeasurementPolicy, Outcome, PolicyChoice,
    RecoveringChi2Gate,
};
pub use riccati::{SteadyState, steady_state_covariance};
pub use scheme::{NoiseRule, Scheme, SchemeParameters, SchemePolicy};
pub use smoother::{ForwardEpoch, RtsRecorder, SmoothedEpoch, rts_smooth};
pub use structured::TrailingDiagonal;
pub use subspace::{SparseInformation, SubspaceUpdate};

/// The linear-algebra crate the engine is written in, re-exported so users
/// build matrices of the very same version.
pub use nalgebra;

// Linked for its "threading" feature only: nalgebra's large products then use
// every core (see the workspace manifest).
use matrixmultiply as _;
