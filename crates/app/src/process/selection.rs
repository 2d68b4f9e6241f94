//! Spec 20's efficiency criterion applied, per navigation parameter: at
//! every GNSS epoch the output takes, for position and for velocity
//! separately, the source whose σ is smaller — the integrated solution
//! (INS corrected by the filter, КОИ) when `K_eff = σ_GNSS / σ_filter > 1`,
//! else the GNSS fix itself (seed 004, eqs. 12–13). An epoch whose fix was
//! withheld or carries no velocity has only the integrated solution.
//!
//! `σ_GNSS` of position is the run's (`efficiency.sigma_gnss_m`, else each
//! fix's own σ with the floor); of velocity `efficiency.sigma_gnss_velocity_mps`,
//! else each fix's velocity σ (3-D, floored at `gnss.min_velocity_sigma_mps`).
//! The integrated velocity is the IMU's (the antenna's differs by ω × lever
//! arm, below the σ of either source for the lever arms of vehicles).

use aidnav_frames::earth::Geodetic;
use aidnav_supervisors::efficiency::{EfficiencyCriterion, Source};
use nalgebra::Vector3;
use serde::Serialize;

use super::config::ProcessConfig;
use super::run::Epoch;

/// The selected output of one GNSS epoch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SelectedEpoch {
    /// GPST (s since 1970).
    pub time_s: f64,
    /// Where the position comes from.
    pub position_source: Source,
    /// The selected antenna position.
    pub position: Geodetic,
    /// K_eff of position (σ_GNSS / σ_filter, 3-D).
    pub k_eff_position: f64,
    /// Where the velocity comes from.
    pub velocity_source: Source,
    /// The selected NED velocity [m/s].
    pub velocity: Vector3<f64>,
    /// K_eff of velocity (NaN: no σ_GNSS of velocity).
    pub k_eff_velocity: f64,
}

/// `summary.json`'s `result.selection`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SelectionSummary {
    /// GNSS epochs selected over.
    pub epochs: usize,
    /// Fraction of them whose position is the integrated solution.
    pub position_integrated_fraction: f64,
    /// Fraction whose velocity is the integrated solution.
    pub velocity_integrated_fraction: f64,
    /// Changes of the position source from one epoch to the next.
    pub position_switches: usize,
    /// Changes of the velocity source.
    pub velocity_switches: usize,
}

/// The source of one parameter: integrated without a usable fix, else by
/// the criterion.
fn choose(gnss: Option<f64>, sigma_filter: f64) -> (Source, f64) {
    match gnss {
        Some(sigma_gnss) if sigma_gnss.is_finite() => {
            EfficiencyCriterion { sigma_gnss }.select(sigma_filter)
        }
        _ => (Source::Integrated, f64::NAN),
    }
}

/// The selected output of every epoch (see the module documentation).
pub fn select_sources(cfg: &ProcessConfig, epochs: &[Epoch]) -> Vec<SelectedEpoch> {
    epochs
        .iter()
        .map(|e| {
            // A withheld fix (no update made) is not there to select.
            let present = e.outcome.is_some();
            // The run's own K_eff of position (its σ_GNSS rule): GNSS when
            // it is not above 1 (eq. 13's "K_eff < 1: GNSS alone"; at
            // exactly 1 either will do).
            let position_source = if present && e.k_eff.is_finite() && e.k_eff <= 1.0 {
                Source::Gnss
            } else {
                Source::Integrated
            };
            let sigma_gnss_velocity = present
                .then(|| {
                    e.fix.velocity_ned?;
                    cfg.efficiency.sigma_gnss_velocity_mps.or_else(|| {
                        e.fix
                            .velocity_sigma_neu
                            .map(|s| s.map(|v| v.max(cfg.gnss.min_velocity_sigma_mps)).norm())
                    })
                })
                .flatten();
            let (velocity_source, k_eff_velocity) =
                choose(sigma_gnss_velocity, e.sigma_velocity.norm());
            SelectedEpoch {
                time_s: e.fix.time_s,
                position_source,
                position: match position_source {
                    Source::Gnss => e.fix.position,
                    Source::Integrated => e.antenna,
                },
                k_eff_position: e.k_eff,
                velocity_source,
                velocity: match (velocity_source, e.fix.velocity_ned) {
                    (Source::Gnss, Some(v)) => v,
                    _ => e.velocity.raw(),
                },
                k_eff_velocity,
            }
        })
        .collect()
}

/// Fractions and switches of a selection.
pub fn selection_summary(selected: &[SelectedEpoch]) -> SelectionSummary {
    let n = selected.len();
    let fraction = |f: fn(&SelectedEpoch) -> Source| {
        selected
            .iter()
            .filter(|s| f(s) == Source::Integrated)
            .count() as f64
            / n.max(1) as f64
    };
    let switches = |f: fn(&SelectedEpoch) -> Source| {
        selected.windows(2).filter(|w| f(&w[0]) != f(&w[1])).count()
    };
    SelectionSummary {
        epochs: n,
        position_integrated_fraction: fraction(|s| s.position_source),
        velocity_integrated_fraction: fraction(|s| s.velocity_source),
        position_switches: switches(|s| s.position_source),
        velocity_switches: switches(|s| s.velocity_source),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::run::synthetic::{PLACE, epoch};
    use nalgebra::Matrix3;

    /// An updated epoch at `t` with K_eff of position `k`, the filter's
    /// velocity σ 0.01 m/s per axis, and (when `velocity_sigma` is Some) a
    /// GNSS velocity of 1 m/s north with that σ per axis; the antenna 2 m
    /// east of the fix.
    fn at(t: f64, k: f64, velocity_sigma: Option<f64>) -> Epoch {
        let mut e = epoch(
            t,
            1,
            0.02,
            Vector3::new(0.0, 2.0, 0.0),
            Matrix3::identity(),
            1.0,
        );
        e.k_eff = k;
        e.fix.velocity_ned = velocity_sigma.map(|_| Vector3::new(1.0, 0.0, 0.0));
        e.fix.velocity_sigma_neu = velocity_sigma.map(Vector3::repeat);
        e
    }

    /// Position: GNSS where K_eff ≤ 1, the integrated solution above it
    /// and at a withheld fix. Velocity: σ_GNSS = √3 × the fix's σ per axis
    /// against the filter's √3 × 0.01: GNSS when the fix is the better;
    /// without a GNSS velocity, or with `sigma_gnss_velocity_mps` larger
    /// than the filter's, integrated. Switches count the changes.
    #[test]
    fn each_parameter_takes_the_source_with_the_smaller_sigma() {
        let mut cfg: ProcessConfig =
            toml::from_str("[data]\ndir = \".\"\nimu = \"i\"\ngnss = \"g\"\n").unwrap();
        cfg.gnss.min_velocity_sigma_mps = 0.001;
        let mut withheld = at(3.0, 0.5, Some(0.005));
        withheld.outcome = None;
        let epochs = [
            at(0.0, 2.0, Some(0.005)),
            at(1.0, 0.5, Some(0.05)),
            at(2.0, 0.8, None),
            withheld,
        ];
        let s = select_sources(&cfg, &epochs);
        let sources: Vec<(Source, Source)> = s
            .iter()
            .map(|e| (e.position_source, e.velocity_source))
            .collect();
        use Source::{Gnss, Integrated};
        assert_eq!(
            sources,
            [
                (Integrated, Gnss),
                (Gnss, Integrated),
                (Gnss, Integrated),
                (Integrated, Integrated)
            ]
        );
        // The selected values are the chosen source's.
        assert_eq!(s[1].position, PLACE);
        assert!((s[0].position.ned_to(&PLACE).raw() - Vector3::new(0.0, -2.0, 0.0)).norm() < 1e-6);
        assert_eq!(s[0].velocity, Vector3::new(1.0, 0.0, 0.0));
        assert_eq!(s[1].velocity, Vector3::zeros());
        // K_eff of velocity: σ_GNSS / σ_filter = 0.005 / 0.01.
        assert!((s[0].k_eff_velocity - 0.5).abs() < 1e-12);
        assert!(s[2].k_eff_velocity.is_nan());
        let summary = selection_summary(&s);
        assert_eq!(summary.epochs, 4);
        assert!((summary.position_integrated_fraction - 0.5).abs() < 1e-12);
        assert!((summary.velocity_integrated_fraction - 0.75).abs() < 1e-12);
        assert_eq!(
            (summary.position_switches, summary.velocity_switches),
            (2, 1)
        );
        // A configured σ_GNSS of velocity replaces the fixes'.
        cfg.efficiency.sigma_gnss_velocity_mps = Some(1.0);
        assert!(
            select_sources(&cfg, &epochs)
                .iter()
                .all(|e| e.velocity_source == Integrated)
        );
    }
}
