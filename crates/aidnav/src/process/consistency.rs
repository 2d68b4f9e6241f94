//! Is the filter's covariance honest? In every scored outage window the
//! actual antenna error against the withheld reference is compared with the
//! filter's own 3×3 antenna position covariance (NEES, and whether the
//! error lies inside the 99 % ellipsoid); with all GNSS the position NIS.
//!
//! For a consistent filter the NEES of the 3-D position is χ²(3): mean 3,
//! inside χ²₃(0.99) = 11.345 for 99 % of the epochs (Bar-Shalom, Li &
//! Kirubarajan, *Estimation with Applications to Tracking and Navigation*,
//! §5.4). The epochs of a window are correlated, so the fraction and the
//! mean are descriptive, not a test with a stated confidence.

use aidnav_estimation::chi2_quantile;
use nalgebra::{Cholesky, Matrix3};
use serde::Serialize;

use super::config::FixQuality;
use super::run::Epoch;
use super::score::is_reference;

/// Degrees of freedom of the position NEES and NIS (north, east, down).
pub const POSITION_DOF: usize = 3;

/// Probability of the ellipsoid the errors are counted inside.
pub const ELLIPSOID_PROBABILITY: f64 = 0.99;

/// χ²₃(0.99) = 11.3449: the 99 % ellipsoid of a 3-D Gaussian error is
/// `eᵀ P⁻¹ e ≤` this.
pub fn chi2_3_99() -> f64 {
    chi2_quantile(POSITION_DOF, ELLIPSOID_PROBABILITY)
}

/// The filter's covariance against the actual error in the outage windows
/// of one length (the coasting filter).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageConsistency {
    /// L \[s\].
    pub outage_s: f64,
    /// Windows with at least one reference epoch.
    pub windows: usize,
    /// Reference epochs inside the windows whose NEES could be formed.
    pub epochs: usize,
    /// Fraction of those epochs whose 3-D error lies inside the 99 %
    /// ellipsoid, NEES ≤ χ²₃(0.99) (None: no epoch). 0.99 for an honest
    /// covariance.
    pub inside_99_fraction: Option<f64>,
    /// Mean NEES `eᵀ (P + R_ref)⁻¹ e` (None: no epoch); `nees_dof` (3) for
    /// an honest covariance.
    pub mean_nees: Option<f64>,
    /// Degrees of freedom of the NEES (3).
    pub nees_dof: usize,
    /// Reference epochs in the windows whose covariance was not positive
    /// definite (left out).
    pub singular_epochs: usize,
}

/// The position NIS of the updates with all GNSS (the main run).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NisConsistency {
    /// Position updates with a finite NIS (accepted or not).
    pub epochs: usize,
    /// Mean NIS per degree of freedom (None: no update); 1 for an honest
    /// covariance and honest fix σ.
    pub mean_nis_per_dof: Option<f64>,
    /// Fraction of the updates with NIS ≤ χ²₃(0.99) (None: no update).
    pub inside_99_fraction: Option<f64>,
    /// Degrees of freedom of the NIS (3).
    pub nis_dof: usize,
}

/// `result.consistency` of `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Consistency {
    /// The 99 % bound on the 3-D NEES and NIS, χ²₃(0.99).
    pub chi2_99: f64,
    /// Per outage length, the coasting filter.
    pub outages: Vec<OutageConsistency>,
    /// All GNSS: the position NIS.
    pub all_gnss: NisConsistency,
}

impl Default for Consistency {
    fn default() -> Self {
        Self {
            chi2_99: chi2_3_99(),
            outages: Vec::new(),
            all_gnss: nis_consistency(&[]),
        }
    }
}

/// The NEES of an epoch's antenna position against its fix, `eᵀ (P +
/// R_ref)⁻¹ e` by Cholesky, with P the filter's antenna covariance and
/// `R_ref` the fix's own (its σ as read, diagonal: the reference is
/// cm-level, not truth). None when the sum is not positive definite or the
/// NEES is not finite.
pub fn position_nees(e: &Epoch) -> Option<f64> {
    let error = e.fix.position.ned_to(&e.antenna).raw();
    let s = e.fix.position_sigma_neu;
    let reference = Matrix3::from_diagonal(&s.map(|v| if v.is_finite() { v * v } else { 0.0 }));
    let chol = Cholesky::new(e.position_covariance + reference)?;
    let nees = error.dot(&chol.solve(&error));
    nees.is_finite().then_some(nees)
}

/// The consistency of a coasting run's epochs in the outage windows of one
/// length, against the fixes whose quality is in `reference`.
pub fn outage_consistency(
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
    reference: &[FixQuality],
) -> OutageConsistency {
    let bound = chi2_3_99();
    let (mut n, mut inside, mut sum, mut singular) = (0usize, 0usize, 0.0, 0usize);
    let mut scored_windows = 0usize;
    for &(a, b) in windows {
        let mut any = false;
        for e in epochs
            .iter()
            .filter(|e| (a..b).contains(&e.fix.time_s) && is_reference(&e.fix, reference))
        {
            any = true;
            match position_nees(e) {
                Some(nees) => {
                    n += 1;
                    sum += nees;
                    inside += usize::from(nees <= bound);
                }
                None => singular += 1,
            }
        }
        scored_windows += usize::from(any);
    }
    OutageConsistency {
        outage_s: length_s,
        windows: scored_windows,
        epochs: n,
        inside_99_fraction: (n > 0).then(|| inside as f64 / n as f64),
        mean_nees: (n > 0).then(|| sum / n as f64),
        nees_dof: POSITION_DOF,
        singular_epochs: singular,
    }
}

/// The position NIS of a run's updates (epochs with an outcome and a
/// finite NIS).
pub fn nis_consistency(epochs: &[Epoch]) -> NisConsistency {
    let bound = chi2_3_99();
    let nis: Vec<f64> = epochs
        .iter()
        .filter(|e| e.outcome.is_some() && e.nis.is_finite())
        .map(|e| e.nis)
        .collect();
    let n = nis.len();
    NisConsistency {
        epochs: n,
        mean_nis_per_dof: (n > 0).then(|| nis.iter().sum::<f64>() / (n * POSITION_DOF) as f64),
        inside_99_fraction: (n > 0)
            .then(|| nis.iter().filter(|&&v| v <= bound).count() as f64 / n as f64),
        nis_dof: POSITION_DOF,
    }
}
