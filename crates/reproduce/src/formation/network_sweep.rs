//! `aidnav reproduce formation-network`: the network sweep of
//! `[formation.network.sweep]` ([`sweep`]) as a reproduction of its own, so
//! `reproduce all` shows the accuracy against latency and loss rate without
//! changing `reproduce formation`'s flight (whose exchange stays ideal).

use aidnav_io::config::{Invalid, Validate};
use serde::{Deserialize, Serialize};

use super::{FormationScenario, Network, NetworkSweep};

#[cfg(doc)]
use super::sweep;

/// Runs of the quick grid (`reproduce formation-network`'s default): each
/// run is one stage 1 and one stage 2 per cell. The full grid with 20 runs
/// is examples/formation_network.toml.
pub const QUICK_SWEEP_RUNS: usize = 4;

/// A formation scenario run only for its network sweep (TOML: the keys of
/// `reproduce formation --print-scenario`, with a `[network]` table holding
/// a `[network.sweep]` grid; every key optional).
///
/// Default: [`FormationScenario::default`] with [`QUICK_SWEEP_RUNS`] runs and
/// the exchange of [`Network::default`] swept over latencies 0 and 2 s ×
/// loss rates 0 and 0.3: the cells that separate (a latency below the 1 s
/// fix interval delays a packet by one epoch, as 1 s does; the example's
/// 0.1, 0.5 and 1 s rows are the same numbers), sized to keep
/// `reproduce all` quick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct NetworkSweepScenario(pub FormationScenario);

impl Default for NetworkSweepScenario {
    fn default() -> Self {
        Self(FormationScenario {
            runs: QUICK_SWEEP_RUNS,
            network: Some(Network {
                sweep: Some(NetworkSweep {
                    latency_s: vec![0.0, 2.0],
                    loss_probability: vec![0.0, 0.3],
                }),
                ..Network::default()
            }),
            ..FormationScenario::default()
        })
    }
}

impl Validate for NetworkSweepScenario {
    fn validate(&self) -> Result<(), Invalid> {
        self.0.validate()?;
        if self.0.network.as_ref().is_none_or(|n| n.sweep.is_none()) {
            return Err(Invalid::new(
                "network.sweep",
                "absent",
                "a [network.sweep] table (lists latency_s and loss_probability)",
            ));
        }
        Ok(())
    }
}

impl crate::MonteCarloScenario for NetworkSweepScenario {
    fn runs_mut(&mut self) -> &mut usize {
        &mut self.0.runs
    }

    fn seed_mut(&mut self) -> &mut u64 {
        &mut self.0.seed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quick_grid_is_valid_and_a_scenario_without_a_grid_is_refused() {
        assert_eq!(NetworkSweepScenario::default().validate(), Ok(()));
        let path = std::path::Path::new("s.toml");
        let grid = "runs = 2\n[network.sweep]\nlatency_s = [1.0]\nloss_probability = [0.5]\n";
        let s = aidnav_io::config::parse_toml::<NetworkSweepScenario>(grid, path).unwrap();
        assert_eq!(s.0.runs, 2);
        assert_eq!(s.0.network.unwrap().sweep.unwrap().latency_s, vec![1.0]);
        let e = aidnav_io::config::parse_toml::<NetworkSweepScenario>("runs = 2\n", path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("network.sweep"), "{e}");
    }
}
