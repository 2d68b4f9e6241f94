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

use aidnav_estimation::gmdh::{GmdhConfig, GmdhError, human_bytes};
use aidnav_io::config::{Invalid, count_in_range, in_range};
use aidnav_models::PlatformChannel;

/// Physical ranges of the `[platform]` keys (spec-20 scenarios). Each is
/// far wider than any real platform yet keeps every variance σ² and every
/// Φ, Q entry a normal f64 (no underflow to 0, no overflow to ∞):
///
/// | key | range |
/// | --- | --- |
/// | `dt_s` | 1e-3 … 100 s |
/// | `beta_per_s` | 1e-8 … 1 1/s |
/// | `drift_sigma_rad_s` | 1e-12 … 1e-2 rad/s |
/// | `gnss_velocity_sigma_mps` | 1e-6 … 1e3 m/s |
/// | `accel_bias_m_s2` | −100 … 100 m/s² |
/// | `accel_bias_variation_m_s2` | 0, or 1e-9 … 100 m/s² |
/// | `accel_bias_correlation_s` | 1e-3 … 1e7 s |
pub const PLATFORM_RANGES: [(&str, f64, f64); 7] = [
    ("dt_s", 1e-3, 100.0),
    ("beta_per_s", 1e-8, 1.0),
    ("drift_sigma_rad_s", 1e-12, 1e-2),
    ("gnss_velocity_sigma_mps", 1e-6, 1e3),
    ("accel_bias_m_s2", -100.0, 100.0),
    ("accel_bias_variation_m_s2", 1e-9, 100.0),
    ("accel_bias_correlation_s", 1e-3, 1e7),
];

/// Range checks of a `[platform]` table, shared by the spec-20 scenarios
/// (ranges in [`PLATFORM_RANGES`]).
pub(crate) fn validate_platform(p: &PlatformChannel) -> Result<(), Invalid> {
    let values = [
        p.dt_s,
        p.beta_per_s,
        p.drift_sigma_rad_s,
        p.gnss_velocity_sigma_mps,
        p.accel_bias_m_s2,
        p.accel_bias_variation_m_s2,
        p.accel_bias_correlation_s,
    ];
    for (&(key, lo, hi), v) in PLATFORM_RANGES.iter().zip(values) {
        // b(t) may be switched off exactly.
        if key == "accel_bias_variation_m_s2" && v == 0.0 {
            continue;
        }
        in_range(key, v, lo, hi).map_err(|e| e.within("platform"))?;
    }
    Ok(())
}

/// Range of every σ key of the reproduction scenarios without a narrower
/// physical range of its own (m, m/s, m/s², rad): 1e-9 … 1e6, so σ² stays a
/// normal f64 (1e-18 … 1e12), never 0 or ∞.
pub const SIGMA_RANGE: (f64, f64) = (1e-9, 1e6);

/// Range of a velocity σ [m/s]: 1e-6 … 1e3.
pub const SIGMA_MPS_RANGE: (f64, f64) = (1e-6, 1e3);

/// Range of a factor on a believed Q or R (mistuning): 1e-6 … 1e6.
pub const SCALE_RANGE: (f64, f64) = (1e-6, 1e6);

/// Error unless `lo ≤ value ≤ hi` for `(lo, hi) = range`.
pub(crate) fn within(key: &str, value: f64, range: (f64, f64)) -> Result<(), Invalid> {
    in_range(key, value, range.0, range.1)
}

/// Memory one experiment may plan to hold at once \[bytes\] (4 GB): a
/// size key that would need more is refused at load, before allocating.
pub const MEMORY_BUDGET_BYTES: f64 = 4e9;

/// Error naming `key` unless `bytes` (what `value` of `key` would make the
/// experiment hold for `what`) is within [`MEMORY_BUDGET_BYTES`].
pub(crate) fn within_memory(
    key: &str,
    value: impl std::fmt::Display,
    bytes: f64,
    what: &str,
    bound: &str,
) -> Result<(), Invalid> {
    if bytes.is_finite() && bytes <= MEMORY_BUDGET_BYTES {
        return Ok(());
    }
    Err(Invalid::new(
        key,
        &value,
        format!(
            "{bound} ({key} = {value} would need {} for {what}; at most {})",
            human_bytes(bytes),
            human_bytes(MEMORY_BUDGET_BYTES)
        ),
    ))
}

/// A GMDH table's bounds ([`GmdhConfig::check`]) as a scenario [`Invalid`]
/// under `table` (e.g. `bridge.gmdh`).
pub(crate) fn validate_gmdh(table: &str, g: &GmdhConfig) -> Result<(), Invalid> {
    match g.check() {
        Ok(()) => Ok(()),
        Err(GmdhError::OutOfRange {
            key,
            value,
            allowed,
        }) => Err(Invalid::new(key, value, allowed).within(table)),
        Err(other) => Err(Invalid::new(table, other, "a valid GMDH configuration")),
    }
}

/// Most fault specs one scenario may list (each is applied to every run).
const MAX_FAULT_SPECS: usize = 100;

/// Range checks of a scenario's list of fault specs (`[[faults]]`,
/// `[[recovery_faults]]`): sim's [`aidnav_sim::faults::InvalidFault`] as a
/// scenario [`Invalid`] under the list's key.
pub(crate) fn validate_faults(
    key: &str,
    faults: &[aidnav_sim::faults::FaultSpec],
) -> Result<(), Invalid> {
    count_in_range(key, faults.len(), 0, MAX_FAULT_SPECS)?;
    for f in faults {
        f.validate()
            .map_err(|e| Invalid::new(e.key, e.value, e.allowed).within(key))?;
    }
    Ok(())
}

/// The runs of a range of a campaign (what an experiment's `run_range`
/// returns and its `finish` takes): chunks computed anywhere are appended
/// in run order, then finished into the result of the whole campaign.
pub trait Chunk: serde::Serialize + serde::de::DeserializeOwned + Default {
    /// Number of runs held.
    fn runs(&self) -> usize;
    /// Append the runs of `other` (the range right after this one's).
    fn append(&mut self, other: Self);
}

impl<T: serde::Serialize + serde::de::DeserializeOwned> Chunk for Vec<T> {
    fn runs(&self) -> usize {
        self.len()
    }

    fn append(&mut self, other: Self) {
        self.extend(other);
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_io::config::Validate;

    #[test]
    fn every_default_scenario_is_within_its_bounds() {
        assert_eq!(anomalies::AnomaliesScenario::default().validate(), Ok(()));
        assert_eq!(
            consistency::ConsistencyScenario::default().validate(),
            Ok(())
        );
        assert_eq!(
            extended_state::ExtendedStateScenario::default().validate(),
            Ok(())
        );
        assert_eq!(formation::FormationScenario::default().validate(), Ok(()));
        assert_eq!(group::GroupScenario::default().validate(), Ok(()));
        assert_eq!(outages::OutagesScenario::default().validate(), Ok(()));
    }

    #[test]
    fn platform_sigmas_are_bounded_physically_not_just_positive() {
        let p = PlatformChannel {
            gnss_velocity_sigma_mps: 1e-170,
            ..PlatformChannel::default()
        };
        let e = validate_platform(&p).unwrap_err();
        assert_eq!(e.key, "platform.gnss_velocity_sigma_mps");
        let p = PlatformChannel {
            drift_sigma_rad_s: 1e-170,
            ..PlatformChannel::default()
        };
        assert_eq!(
            validate_platform(&p).unwrap_err().key,
            "platform.drift_sigma_rad_s"
        );
        // Every bound keeps σ² a normal number.
        for (key, lo, hi) in PLATFORM_RANGES {
            assert!((lo * lo).is_normal() || lo < 0.0, "{key}");
            assert!((hi * hi).is_normal(), "{key}");
        }
    }
}
