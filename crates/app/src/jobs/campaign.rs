//! The reproductions as values, and Monte Carlo campaigns in chunks.
//!
//! [`reproduce_summary`] runs an experiment and returns its `summary.json`
//! without writing a file (what `aidnav reproduce NAME` writes). A
//! [`Campaign`] can also be computed a chunk of runs at a time
//! ([`Campaign::run_chunk`]), on other threads, processes or machines, and
//! combined ([`Campaign::finish`]) into the summary of the whole campaign,
//! bit for bit: run k always draws stream k of the master seed, and the
//! combination folds the runs in run order. A chunk travels as bytes
//! (postcard: f64 as its eight bytes, so nothing is rounded on the way).

use std::ops::Range;
use std::path::Path;

use aidnav_io::writers::Summary;
use aidnav_reproduce::Chunk;
use aidnav_reproduce::MonteCarloScenario;
use aidnav_reproduce::anomalies::AnomaliesScenario;
use aidnav_reproduce::consistency::ConsistencyScenario;
use aidnav_reproduce::extended_state::ExtendedStateScenario;
use aidnav_reproduce::formation::{FormationScenario, NetworkSweepScenario};
use aidnav_reproduce::group::GroupScenario;
use aidnav_reproduce::outages::OutagesScenario;
use aidnav_sim::{Cancel, MonteCarlo};

use super::*;

/// A reproduction, by the name `aidnav reproduce` gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Experiment {
    /// `consistency`: the NEES/NIS demo.
    Consistency,
    /// `extended-state`: spec 10's launch INS.
    ExtendedState,
    /// `anomalies`: spec 20's anomalous fixes.
    Anomalies,
    /// `outages`: spec 20's outage bridging.
    Outages,
    /// `group`: spec 30's one-axis group.
    Group,
    /// `formation`: spec 30's formation pipeline.
    Formation,
    /// `formation-network`: the formation's exchange as a network, the
    /// accuracy per latency × loss rate.
    FormationNetwork,
}

impl Experiment {
    /// Every experiment, in the order of `reproduce all`.
    pub const ALL: [Experiment; 7] = [
        Experiment::Consistency,
        Experiment::ExtendedState,
        Experiment::Anomalies,
        Experiment::Outages,
        Experiment::Group,
        Experiment::Formation,
        Experiment::FormationNetwork,
    ];

    /// The name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            Experiment::Consistency => "consistency",
            Experiment::ExtendedState => "extended-state",
            Experiment::Anomalies => "anomalies",
            Experiment::Outages => "outages",
            Experiment::Group => "group",
            Experiment::Formation => "formation",
            Experiment::FormationNetwork => "formation-network",
        }
    }

    /// Whether its runs can be computed in chunks ([`Campaign::run_chunk`]):
    /// every reproduction's can.
    pub const fn splits(self) -> bool {
        true
    }
}

impl std::str::FromStr for Experiment {
    type Err = JobError;

    /// An experiment by its name (`extended_state` is taken for
    /// `extended-state`); the error lists the names.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.replace('_', "-");
        Experiment::ALL
            .into_iter()
            .find(|e| e.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Experiment::ALL.iter().map(|e| e.name()).collect();
                JobError::Refused(format!(
                    "unknown experiment {s:?}: one of {}",
                    names.join(", ")
                ))
            })
    }
}

/// An experiment with its scenario: the TOML text of a scenario (None: the
/// defaults) with the overrides applied, validated.
#[derive(Debug, Clone)]
pub struct Campaign {
    experiment: Experiment,
    scenario: Scenario,
    cancel: Cancel,
}

/// The scenario of each experiment.
#[derive(Debug, Clone)]
enum Scenario {
    Consistency(ConsistencyScenario),
    ExtendedState(ExtendedStateScenario),
    Anomalies(AnomaliesScenario),
    Outages(OutagesScenario),
    Group(GroupScenario),
    Formation(FormationScenario),
    FormationNetwork(NetworkSweepScenario),
}

/// Parse (or default), override, validate.
fn scenario<S>(text: Option<(&str, &Path)>, overrides: &ScenarioOverrides) -> JobResult<S>
where
    S: Default + serde::de::DeserializeOwned + aidnav_io::Validate + MonteCarloScenario,
{
    let mut s = match text {
        Some((text, origin)) => aidnav_io::config::parse_toml::<S>(text, origin)?,
        None => S::default(),
    };
    overrides.apply(&mut s);
    validated(s)
}

impl Campaign {
    /// `experiment` under the scenario `text` (TOML; `origin` names it in
    /// errors; None: the defaults), with `overrides` (runs, seed) applied.
    /// Errors name the file, line and key as `aidnav reproduce --scenario`
    /// does.
    pub fn new(
        experiment: Experiment,
        text: Option<(&str, &Path)>,
        overrides: &ScenarioOverrides,
    ) -> JobResult<Self> {
        let scenario = match experiment {
            Experiment::Consistency => Scenario::Consistency(scenario(text, overrides)?),
            Experiment::ExtendedState => Scenario::ExtendedState(scenario(text, overrides)?),
            Experiment::Anomalies => Scenario::Anomalies(scenario(text, overrides)?),
            Experiment::Outages => Scenario::Outages(scenario(text, overrides)?),
            Experiment::Group => Scenario::Group(scenario(text, overrides)?),
            Experiment::Formation => Scenario::Formation(scenario(text, overrides)?),
            Experiment::FormationNetwork => Scenario::FormationNetwork(scenario(text, overrides)?),
        };
        Ok(Self {
            experiment,
            scenario,
            cancel: Cancel::default(),
        })
    }

    /// Stop [`summary`](Self::summary) and [`run_chunk`](Self::run_chunk)
    /// (with [`JobError::Cancelled`]) within a run of `cancel` being set.
    pub fn with_cancel(mut self, cancel: Cancel) -> Self {
        self.cancel = cancel;
        self
    }

    /// The experiment.
    pub fn experiment(&self) -> Experiment {
        self.experiment
    }

    /// Number of runs of the scenario.
    pub fn runs(&self) -> usize {
        self.monte_carlo().runs
    }

    /// The campaign's Monte Carlo settings (no progress bar).
    fn monte_carlo(&self) -> MonteCarlo {
        let (runs, seed) = match &self.scenario {
            Scenario::Consistency(s) => (s.runs, s.seed),
            Scenario::ExtendedState(s) => (s.runs, s.seed),
            Scenario::Anomalies(s) => (s.runs, s.seed),
            Scenario::Outages(s) => (s.runs, s.seed),
            Scenario::Group(s) => (s.runs, s.seed),
            Scenario::Formation(s) => (s.runs, s.seed),
            Scenario::FormationNetwork(s) => (s.0.runs, s.0.seed),
        };
        MonteCarlo::new(runs, seed)
            .quiet()
            .with_cancel(self.cancel.clone())
    }

    /// Run the whole campaign here and return its `summary.json` (what
    /// `aidnav reproduce NAME` writes; no file is written).
    pub fn summary(&self) -> JobResult<Summary> {
        Cancel::catch(|| self.summary_uncancelled())?
    }

    fn summary_uncancelled(&self) -> JobResult<Summary> {
        let mc = self.monte_carlo();
        Ok(match &self.scenario {
            Scenario::Consistency(s) => {
                let r = aidnav_reproduce::consistency::run(s, &mc)
                    .map_err(estimation("consistency demo"))?;
                consistency_summary(s, &r)
            }
            Scenario::ExtendedState(s) => {
                extended_state_summary(s, &aidnav_reproduce::extended_state::run(s, &mc)?)
            }
            Scenario::Anomalies(s) => {
                let r = aidnav_reproduce::anomalies::run(s, &mc)
                    .map_err(estimation("anomalies experiment"))?;
                anomalies_summary(s, &r)
            }
            Scenario::Outages(s) => outages_summary(s, &aidnav_reproduce::outages::run(s, &mc)?),
            Scenario::Group(s) => {
                let r =
                    aidnav_reproduce::group::run(s, &mc).map_err(estimation("group experiment"))?;
                group_summary(s, &r)
            }
            Scenario::Formation(s) => {
                let r = aidnav_reproduce::formation::run(s, &mc)
                    .map_err(estimation("formation flight"))?;
                formation_summary(s, "reproduce formation", &r)
            }
            Scenario::FormationNetwork(s) => {
                let sweep = aidnav_reproduce::formation::sweep(&s.0, &mc)
                    .map_err(estimation("formation network sweep"))?;
                formation_network_summary(s, &sweep)
            }
        })
    }

    /// The runs in `range` (within `0..runs()`), as bytes for
    /// [`finish`](Self::finish).
    pub fn run_chunk(&self, range: Range<usize>) -> JobResult<Vec<u8>> {
        let mc = self.monte_carlo();
        if range.start > range.end || range.end > mc.runs {
            return Err(JobError::Refused(format!(
                "runs {}..{} are not within the campaign's {} runs",
                range.start, range.end, mc.runs
            )));
        }
        fn encode<C: Chunk>(chunk: &C) -> JobResult<Vec<u8>> {
            postcard::to_allocvec(chunk)
                .map_err(|e| JobError::Refused(format!("encoding a chunk: {e}")))
        }
        Cancel::catch(|| match &self.scenario {
            Scenario::Consistency(s) => encode(
                &aidnav_reproduce::consistency::run_range(s, &mc, range)
                    .map_err(estimation("consistency demo"))?,
            ),
            Scenario::ExtendedState(s) => {
                encode(&aidnav_reproduce::extended_state::run_range(s, &mc, range)?)
            }
            Scenario::Anomalies(s) => encode(
                &aidnav_reproduce::anomalies::run_range(s, &mc, range)
                    .map_err(estimation("anomalies experiment"))?,
            ),
            Scenario::Outages(s) => encode(&aidnav_reproduce::outages::run_range(s, &mc, range)?),
            Scenario::Group(s) => encode(
                &aidnav_reproduce::group::run_range(s, &mc, range)
                    .map_err(estimation("group experiment"))?,
            ),
            Scenario::Formation(s) => encode(
                &aidnav_reproduce::formation::run_range(s, &mc, range)
                    .map_err(estimation("formation flight"))?,
            ),
            Scenario::FormationNetwork(s) => encode(
                &aidnav_reproduce::formation::sweep_range(&s.0, &mc, range)
                    .map_err(estimation("formation network sweep"))?,
            ),
        })?
    }

    /// The `summary.json` of the whole campaign from its chunks (the bytes
    /// of [`run_chunk`](Self::run_chunk)) in run order, covering every run
    /// once: the same value, bit for bit, as [`summary`](Self::summary).
    pub fn finish(&self, chunks: &[Vec<u8>]) -> JobResult<Summary> {
        // The anomalies' per-type table is a campaign of its own, run here.
        Cancel::catch(|| self.finish_uncancelled(chunks))?
    }

    fn finish_uncancelled(&self, chunks: &[Vec<u8>]) -> JobResult<Summary> {
        let runs = self.runs();
        Ok(match &self.scenario {
            Scenario::Consistency(s) => {
                let r = aidnav_reproduce::consistency::finish(s, joined(chunks, runs)?)
                    .map_err(estimation("consistency demo"))?;
                consistency_summary(s, &r)
            }
            Scenario::ExtendedState(s) => extended_state_summary(
                s,
                &aidnav_reproduce::extended_state::finish(s, joined(chunks, runs)?)?,
            ),
            Scenario::Anomalies(s) => {
                let r = aidnav_reproduce::anomalies::finish_cancellable(
                    s,
                    joined(chunks, runs)?,
                    &self.cancel,
                )
                .map_err(estimation("anomalies experiment"))?;
                anomalies_summary(s, &r)
            }
            Scenario::Outages(s) => outages_summary(
                s,
                &aidnav_reproduce::outages::finish(s, joined(chunks, runs)?)?,
            ),
            Scenario::Group(s) => {
                let r = aidnav_reproduce::group::finish(s, joined(chunks, runs)?)
                    .map_err(estimation("group experiment"))?;
                group_summary(s, &r)
            }
            Scenario::Formation(s) => {
                let r = aidnav_reproduce::formation::finish(s, joined(chunks, runs)?)
                    .map_err(estimation("formation flight"))?;
                formation_summary(s, "reproduce formation", &r)
            }
            Scenario::FormationNetwork(s) => {
                let sweep = aidnav_reproduce::formation::sweep_finish(&s.0, joined(chunks, runs)?);
                formation_network_summary(s, &sweep)
            }
        })
    }
}

/// The chunks decoded and joined in order; refused unless they hold
/// exactly `runs` runs.
fn joined<C: Chunk>(chunks: &[Vec<u8>], runs: usize) -> JobResult<C> {
    let mut all = C::default();
    for (i, c) in chunks.iter().enumerate() {
        let part: C = postcard::from_bytes(c).map_err(|e| {
            JobError::Refused(format!("chunk {i}: not a chunk of this campaign: {e}"))
        })?;
        all.append(part);
    }
    if all.runs() != runs {
        return Err(JobError::Refused(format!(
            "the chunks hold {} runs, the campaign has {runs}",
            all.runs()
        )));
    }
    Ok(all)
}

/// Run `experiment` (scenario TOML `text`, or the defaults; `overrides`
/// applied) and return its `summary.json` without writing a file.
pub fn reproduce_summary(
    experiment: Experiment,
    text: Option<(&str, &Path)>,
    overrides: &ScenarioOverrides,
) -> JobResult<Summary> {
    Campaign::new(experiment, text, overrides)?.summary()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn campaign(experiment: Experiment, text: Option<&str>, runs: usize) -> Campaign {
        let overrides = ScenarioOverrides {
            runs: Some(runs),
            seed: Some(5),
            max_runs: None,
        };
        Campaign::new(
            experiment,
            text.map(|t| (t, Path::new("<test scenario>"))),
            &overrides,
        )
        .unwrap()
    }

    fn json(s: &Summary) -> String {
        // serde_json writes the shortest text that reads back to the same
        // f64: equal text, equal bits.
        serde_json::to_string(s).unwrap()
    }

    /// `experiment` computed in chunks — whole, uneven with an empty
    /// chunk, one run each — gives the summary of the whole campaign, bit
    /// for bit; chunks that miss a run are refused, as is a range past the
    /// end.
    fn chunks_give_the_whole_summary(experiment: Experiment, text: Option<&str>, runs: usize) {
        let c = campaign(experiment, text, runs);
        let whole = json(&c.summary().unwrap());
        let splits: [Vec<Range<usize>>; 3] = [
            std::iter::once(0..runs).collect(),
            vec![0..1, 1..1, 1..runs],
            (0..runs).map(|k| k..k + 1).collect(),
        ];
        for bounds in splits {
            let chunks: Vec<Vec<u8>> = bounds
                .iter()
                .map(|r| c.run_chunk(r.clone()).unwrap())
                .collect();
            let joined = json(&c.finish(&chunks).unwrap());
            assert!(joined == whole, "{}: {bounds:?}", experiment.name());
        }
        let first = c.run_chunk(0..1).unwrap();
        assert!(c.finish(&[first]).is_err());
        assert!(c.run_chunk(0..runs + 1).is_err());
    }

    #[test]
    fn campaigns_in_chunks_give_the_whole_summary_bit_for_bit() {
        chunks_give_the_whole_summary(Experiment::Consistency, Some("epochs = 30"), 5);
        chunks_give_the_whole_summary(Experiment::Group, Some("epochs = 30"), 4);
        chunks_give_the_whole_summary(Experiment::Anomalies, None, 3);
        chunks_give_the_whole_summary(Experiment::Formation, None, 3);
    }

    /// `formation-network` (the reproduction `reproduce all` runs last) in
    /// chunks gives its whole summary bit for bit; a short flight keeps
    /// the sweep (four cells per run) quick.
    #[test]
    fn the_formation_network_campaign_in_chunks_gives_the_whole_summary_bit_for_bit() {
        chunks_give_the_whole_summary(
            Experiment::FormationNetwork,
            Some(FORMATION_NETWORK_SHORT),
            2,
        );
        let c = campaign(
            Experiment::FormationNetwork,
            Some(FORMATION_NETWORK_SHORT),
            2,
        );
        let summary = json(&c.summary().unwrap());
        assert!(summary.contains("\"network_sweep\""), "{summary}");
    }

    /// `formation-network` on a short flight: the quick grid's cells, a
    /// denied member, 60 s.
    const FORMATION_NETWORK_SHORT: &str = "duration_s = 60.0\nsettle_s = 10.0\n\
        [[denial]]\nmembers = [2]\nstart_s = 20.0\nend_s = 50.0\n\
        [network.sweep]\nlatency_s = [0.0, 2.0]\nloss_probability = [0.0, 0.3]\n";

    /// Every experiment's name is taken, and its campaign splits.
    #[test]
    fn every_reproduction_has_a_campaign() {
        for e in Experiment::ALL {
            assert_eq!(e.name().parse::<Experiment>().unwrap(), e);
            assert!(e.splits());
        }
        assert!("formation_network".parse::<Experiment>().is_ok());
        // A formation-network scenario without a sweep is refused, naming
        // the key.
        let e = Campaign::new(
            Experiment::FormationNetwork,
            Some(("runs = 2\n", Path::new("s.toml"))),
            &ScenarioOverrides::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("network.sweep"), "{e}");
    }

    /// The two long experiments (a minute or more in the test profile).
    #[test]
    #[ignore = "long: cargo test -p aidnav-app -- --ignored"]
    fn long_campaigns_in_chunks_give_the_whole_summary_bit_for_bit() {
        chunks_give_the_whole_summary(Experiment::Outages, None, 3);
        chunks_give_the_whole_summary(Experiment::ExtendedState, None, 3);
    }

    #[test]
    fn a_cancelled_campaign_stops_with_cancelled() {
        let cancel = Cancel::new();
        let c =
            campaign(Experiment::Consistency, Some("epochs = 30"), 50).with_cancel(cancel.clone());
        cancel.cancel();
        assert!(matches!(c.summary(), Err(JobError::Cancelled)));
        assert!(matches!(c.run_chunk(0..10), Err(JobError::Cancelled)));
    }
}
