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
    /// Per outage length, the RTS-smoothed solution against the smoother's
    /// covariance (with `output.smooth`; empty otherwise).
    pub outages_smoothed: Vec<OutageConsistency>,
    /// All GNSS: the position NIS.
    pub all_gnss: NisConsistency,
}

impl Default for Consistency {
    fn default() -> Self {
        Self {
            chi2_99: chi2_3_99(),
            outages: Vec::new(),
            outages_smoothed: Vec::new(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::run::synthetic::epoch;
    use nalgebra::{Matrix3, Vector3};

    const FIXED: [FixQuality; 1] = [FixQuality::Fixed];

    #[test]
    fn the_99_percent_bound_of_three_dof_is_the_tabulated_quantile() {
        // χ²₃(0.99) = 11.3449 (Abramowitz & Stegun, table 26.8).
        assert!((chi2_3_99() - 11.344_866_730_144_373).abs() < 1e-9);
    }

    #[test]
    fn nees_is_computed_with_the_full_covariance_and_the_reference_sigma() {
        // e = (1, 1, 1) m, P = [[2, 1, 0], [1, 2, 0], [0, 0, 1]] m²: the
        // horizontal block's inverse is [[2, −1], [−1, 2]] / 3, so
        // NEES = (2 − 1 − 1 + 2) / 3 + 1 = 5/3.
        let p = Matrix3::new(2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 1.0);
        let e = epoch(0.0, 1, 0.0, Vector3::repeat(1.0), p, 3.0);
        assert!((position_nees(&e).unwrap() - 5.0 / 3.0).abs() < 1e-6);
        // With a reference σ of 1 m on each axis: P + R = [[3, 1, 0], [1,
        // 3, 0], [0, 0, 2]], inverse block [[3, −1], [−1, 3]] / 8, so
        // NEES = (3 − 1 − 1 + 3) / 8 + 1/2 = 1.
        let e = epoch(0.0, 1, 1.0, Vector3::repeat(1.0), p, 3.0);
        assert!((position_nees(&e).unwrap() - 1.0).abs() < 1e-6);
        // A covariance that is not positive definite gives none.
        let e = epoch(0.0, 1, 0.0, Vector3::repeat(1.0), Matrix3::zeros(), 3.0);
        assert_eq!(position_nees(&e), None);
    }

    #[test]
    fn outage_consistency_counts_reference_epochs_inside_the_windows() {
        let p = Matrix3::from_diagonal(&Vector3::new(1.0, 4.0, 1.0));
        let epochs = vec![
            // Window 1: NEES 1 + 4/4 = 2 (inside), then 16 + 1 = 17 (outside).
            epoch(1.0, 1, 0.0, Vector3::new(1.0, 2.0, 0.0), p, f64::NAN),
            epoch(2.0, 1, 0.0, Vector3::new(4.0, 2.0, 0.0), p, f64::NAN),
            // Float (not a reference) and outside every window: ignored.
            epoch(3.0, 2, 0.0, Vector3::new(40.0, 0.0, 0.0), p, f64::NAN),
            epoch(7.0, 1, 0.0, Vector3::new(40.0, 0.0, 0.0), p, 3.0),
            // Window 2: e = (0, 1, 0), NEES 1/4 …
            epoch(11.0, 1, 0.0, Vector3::new(0.0, 1.0, 0.0), p, f64::NAN),
            // … and a singular covariance, left out and counted.
            epoch(
                12.0,
                1,
                0.0,
                Vector3::new(0.0, 1.0, 0.0),
                Matrix3::zeros(),
                f64::NAN,
            ),
        ];
        let c = outage_consistency(
            &epochs,
            &[(0.0, 5.0), (10.0, 15.0), (20.0, 25.0)],
            5.0,
            &FIXED,
        );
        assert_eq!(
            (c.windows, c.epochs, c.singular_epochs, c.nees_dof),
            (2, 3, 1, 3)
        );
        assert!((c.inside_99_fraction.unwrap() - 2.0 / 3.0).abs() < 1e-12);
        assert!((c.mean_nees.unwrap() - (2.0 + 17.0 + 0.25) / 3.0).abs() < 1e-6);
        // Without a reference-quality fix: no score.
        let none = outage_consistency(&epochs, &[(0.0, 5.0)], 5.0, &[FixQuality::Ppp]);
        assert_eq!(
            (none.epochs, none.inside_99_fraction, none.mean_nees),
            (0, None, None)
        );
    }

    #[test]
    fn nis_per_dof_averages_the_updates_only() {
        let p = Matrix3::identity();
        let epochs = [
            epoch(0.0, 1, 0.0, Vector3::zeros(), p, 3.0),
            epoch(1.0, 1, 0.0, Vector3::zeros(), p, 6.0),
            epoch(2.0, 1, 0.0, Vector3::zeros(), p, 30.0),
            // Withheld: no update.
            epoch(3.0, 1, 0.0, Vector3::zeros(), p, f64::NAN),
        ];
        let n = nis_consistency(&epochs);
        assert_eq!((n.epochs, n.nis_dof), (3, 3));
        // (3 + 6 + 30) / 3 updates / 3 dof = 39 / 9.
        assert!((n.mean_nis_per_dof.unwrap() - 39.0 / 9.0).abs() < 1e-12);
        assert!((n.inside_99_fraction.unwrap() - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(nis_consistency(&epochs[3..]).mean_nis_per_dof, None);
    }
}
