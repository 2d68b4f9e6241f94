//! The reproductions of the three source papers (specs 10–30) and the
//! consistency demonstration: each one a scenario struct (TOML, documented
//! defaults), a pure function that runs it by seeded Monte Carlo
//! ([`aidnav_sim::MonteCarlo`]), a result struct the CLI prints and writes,
//! and its figures ([`figures`]). The papers' published numbers they are
//! compared with are in [`published`].

pub mod anomalies;
pub mod consistency;
pub mod extended_state;
pub mod figures;
pub mod formation;
pub mod group;
pub mod outages;
pub mod published;

use aidnav_io::config::{Invalid, non_negative, positive};
use aidnav_models::PlatformChannel;

/// Range checks of a `[platform]` table, shared by the spec-20 scenarios.
pub(crate) fn validate_platform(p: &PlatformChannel) -> Result<(), Invalid> {
    positive("dt_s", p.dt_s).map_err(|e| e.within("platform"))?;
    positive("beta_per_s", p.beta_per_s).map_err(|e| e.within("platform"))?;
    positive("drift_sigma_rad_s", p.drift_sigma_rad_s).map_err(|e| e.within("platform"))?;
    positive("gnss_velocity_sigma_mps", p.gnss_velocity_sigma_mps)
        .map_err(|e| e.within("platform"))?;
    non_negative("accel_bias_variation_m_s2", p.accel_bias_variation_m_s2)
        .map_err(|e| e.within("platform"))?;
    positive("accel_bias_correlation_s", p.accel_bias_correlation_s)
        .map_err(|e| e.within("platform"))?;
    if !p.accel_bias_m_s2.is_finite() {
        return Err(Invalid::new(
            "platform.accel_bias_m_s2",
            p.accel_bias_m_s2,
            "a finite number",
        ));
    }
    Ok(())
}

/// Range checks of a scenario's list of fault specs (`[[faults]]`,
/// `[[recovery_faults]]`): sim's [`aidnav_sim::faults::InvalidFault`] as a
/// scenario [`Invalid`] under the list's key.
pub(crate) fn validate_faults(
    key: &str,
    faults: &[aidnav_sim::faults::FaultSpec],
) -> Result<(), Invalid> {
    for f in faults {
        f.validate()
            .map_err(|e| Invalid::new(e.key, e.value, e.allowed).within(key))?;
    }
    Ok(())
}

/// What every Monte Carlo scenario has: a run count and a master seed, so
/// the CLI can override both the same way for every experiment.
pub trait MonteCarloScenario {
    /// Number of runs.
    fn runs_mut(&mut self) -> &mut usize;
    /// Master seed.
    fn seed_mut(&mut self) -> &mut u64;
}

macro_rules! monte_carlo_scenario {
    ($($t:ty),*) => {$(
        impl MonteCarloScenario for $t {
            fn runs_mut(&mut self) -> &mut usize {
                &mut self.runs
            }
            fn seed_mut(&mut self) -> &mut u64 {
                &mut self.seed
            }
        }
    )*};
}

monte_carlo_scenario!(
    anomalies::AnomaliesScenario,
    consistency::ConsistencyScenario,
    extended_state::ExtendedStateScenario,
    formation::FormationScenario,
    group::GroupScenario,
    outages::OutagesScenario
);
