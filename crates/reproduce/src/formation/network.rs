//! The exchange between the formation's members as a network: latency
//! (fixed plus uniform jitter), lost packets, a limit on the neighbours each
//! member reports per epoch, and stage 2 fed by what has arrived, late
//! packets fused at their own epoch
//! ([`aidnav_integration::group::DelayedFusion`]).
//!
//! Each member sends one packet per epoch, stamped with the epoch (and time)
//! it was made at: its stage-1 solution (flagged with whether it holds a new
//! GNSS fix, as the ideal exchange treats it), its relative measurements and
//! its range rates / relative velocities (when the sensor measures them; the
//! same random streams as the ideal exchange). The
//! node that runs stage 2 receives every member's packet over the network
//! (its own too: a ground station, or a member whose packets queue like the
//! others'). Both stage-2 filters start from the first epoch's stage-1
//! solutions as today (the prior, exchanged before the scored flight).
//!
//! The loss and jitter draws come from their own random stream (two uniform
//! draws per packet, whatever the settings), so runs with different
//! latencies and loss rates share the stage-1 errors, the relative
//! measurements' noise and the network's draws: the sweep's comparisons are
//! paired.

use aidnav_estimation::EstimationError;
use aidnav_ins::local_level::LocalLevelState;
use aidnav_integration::group::{
    DelayStats, DelayedFusion, EkfFusion, MemberPacket, OwnSolution, PaperFusion,
    RelativeMeasurement, RelativeRate,
};
use aidnav_io::config::{Invalid, count_in_range, in_range};
use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::{RngExt, RunRng, channel_rng};
use serde::{Deserialize, Serialize};

use super::run::{RunErrors, own_new};
use super::simulate::{
    RATE_CHANNEL, RELATIVE_CHANNEL, StageOnePaths, relative_measurements, relative_rates,
    stage_one_on,
};
use super::{FormationScenario, Stage2OwnErrors};

/// The network's random stream (channel of [`channel_rng`]; not the rates'
/// [`RATE_CHANNEL`], so loss and jitter are independent of the rates' noise).
const NETWORK_CHANNEL: u64 = 3_000_000;

/// Memory the late-packet buffers of one run may take (both filters) \[B\].
const HISTORY_BUDGET_BYTES: f64 = 256.0 * 1024.0 * 1024.0;

/// The exchange between members (TOML `[formation.network]`; every key
/// optional, the defaults are the ideal exchange).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Network {
    /// Fixed part of each packet's delay \[s\], 0 … 60. Default 0.
    pub latency_s: f64,
    /// Random part of each packet's delay: uniform in \[0, `jitter_s`\]
    /// \[s\], 0 … 60. Default 0.
    pub jitter_s: f64,
    /// Probability that a packet is lost, 0 … 1, independently per packet.
    /// Default 0.
    pub loss_probability: f64,
    /// The most neighbours each member reports per epoch (the nearest by
    /// measured range), 0 … 1000; absent: all within sensor range. Default
    /// absent.
    pub max_neighbours: Option<usize>,
    /// How far back a late packet is still fused \[s\] (the buffer of
    /// filter snapshots; older packets are counted and dropped), 0 … 600 and
    /// at most 256 MiB of snapshots for the group's size. Default 10.
    pub history_s: f64,
    /// A grid of latencies and loss rates to run on the same stage 1 and
    /// measurements ([`sweep`]); absent: none. Default absent.
    pub sweep: Option<NetworkSweep>,
}

impl Default for Network {
    fn default() -> Self {
        Self {
            latency_s: 0.0,
            jitter_s: 0.0,
            loss_probability: 0.0,
            max_neighbours: None,
            history_s: 10.0,
            sweep: None,
        }
    }
}

/// The grid of [`sweep`] (TOML `[formation.network.sweep]`): every latency
/// with every loss rate, the other keys of `[formation.network]` kept.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetworkSweep {
    /// Fixed latencies \[s\] (1 … 20 values, each 0 … 60).
    pub latency_s: Vec<f64>,
    /// Loss probabilities (1 … 20 values, each 0 … 1).
    pub loss_probability: Vec<f64>,
}

impl Network {
    /// Checks the keys (names relative to `[formation.network]`), with the
    /// formation's interval and size for the buffer's bound.
    pub fn validate_for(&self, sc: &FormationScenario) -> Result<(), Invalid> {
        in_range("latency_s", self.latency_s, 0.0, 60.0)?;
        in_range("jitter_s", self.jitter_s, 0.0, 60.0)?;
        in_range("loss_probability", self.loss_probability, 0.0, 1.0)?;
        if let Some(n) = self.max_neighbours {
            count_in_range("max_neighbours", n, 0, 1000)?;
        }
        in_range("history_s", self.history_s, 0.0, 600.0)?;
        let bytes = (self.history_epochs(sc.fix_interval_s) + 1) as f64 * snapshot_bytes(sc);
        if bytes > HISTORY_BUDGET_BYTES {
            return Err(Invalid::new(
                "history_s",
                self.history_s,
                format!(
                    "a buffer of at most {:.0} s for {} members at {} s epochs (256 MiB of filter snapshots)",
                    (HISTORY_BUDGET_BYTES / snapshot_bytes(sc) - 1.0).floor() * sc.fix_interval_s,
                    sc.members,
                    sc.fix_interval_s
                ),
            ));
        }
        if let Some(g) = &self.sweep {
            count_in_range("sweep.latency_s", g.latency_s.len(), 1, 20)?;
            count_in_range("sweep.loss_probability", g.loss_probability.len(), 1, 20)?;
            for &l in &g.latency_s {
                in_range("sweep.latency_s", l, 0.0, 60.0)?;
            }
            for &p in &g.loss_probability {
                in_range("sweep.loss_probability", p, 0.0, 1.0)?;
            }
        }
        Ok(())
    }

    /// The buffer's depth in epochs: a packet late by up to `history_s` is
    /// fused.
    pub fn history_epochs(&self, fix_interval_s: f64) -> usize {
        (self.history_s / fix_interval_s + 1e-9).floor() as usize
    }

    /// Whether this is the ideal exchange (no delay, no loss, no limit).
    pub fn is_ideal(&self) -> bool {
        self.latency_s == 0.0
            && self.jitter_s == 0.0
            && self.loss_probability == 0.0
            && self.max_neighbours.is_none()
    }
}

/// An upper estimate of one snapshot of both stage-2 filters \[B\]: the
/// EKF's covariance, transition and noise matrices (square in its state:
/// 6M, plus 3M per block of Gauss–Markov own-error states) and the paper
/// form's three axes (covariance and update workspace, square in 2M plus M
/// per own-error block).
fn snapshot_bytes(sc: &FormationScenario) -> f64 {
    let blocks = match sc.stage2_own_errors {
        Stage2OwnErrors::White => 0,
        Stage2OwnErrors::GaussMarkov if sc.stage2_own_velocity => 2,
        Stage2OwnErrors::GaussMarkov => 1,
        Stage2OwnErrors::Stage1Reported => 2,
    };
    let ekf = ((6 + 3 * blocks) * sc.members) as f64;
    let axis = ((2 + blocks) * sc.members) as f64;
    8.0 * (3.0 * ekf * ekf + 3.0 * 3.0 * axis * axis)
}

/// What the network did (per run, or summed over runs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct NetworkStats {
    /// Packets sent (members × epochs).
    pub sent: usize,
    /// Packets lost.
    pub lost: usize,
    /// Packets still in flight at the end of the flight.
    pub in_flight_at_end: usize,
    /// Relative measurements not sent because of `max_neighbours`.
    pub withheld_by_neighbour_limit: usize,
    /// What stage 2 did with the packets that arrived (the EKF's counts;
    /// the paper form sees the same packets).
    pub fusion: DelayStats,
}

impl NetworkStats {
    /// Adds another run's counts to these.
    pub fn add(&mut self, other: &NetworkStats) {
        self.sent += other.sent;
        self.lost += other.lost;
        self.in_flight_at_end += other.in_flight_at_end;
        self.withheld_by_neighbour_limit += other.withheld_by_neighbour_limit;
        self.fusion.add(&other.fusion);
    }

    /// Lost packets / sent packets.
    pub fn lost_fraction(&self) -> f64 {
        self.lost as f64 / self.sent.max(1) as f64
    }

    /// Of the packets fused, the fraction fused late (by rewind).
    pub fn late_fraction(&self) -> f64 {
        let fused = self.fusion.on_time + self.fusion.delayed;
        self.fusion.delayed as f64 / fused.max(1) as f64
    }
}

/// A packet on its way.
struct Message {
    /// Epoch it was made at (its time is `(epoch + 1) × fix interval`).
    epoch: usize,
    arrival_s: f64,
    packet: MemberPacket,
}

/// The simulated network: packets in flight, their loss and delays.
struct Exchange<'a> {
    net: &'a Network,
    rng: RunRng,
    in_flight: Vec<Message>,
    stats: NetworkStats,
}

impl<'a> Exchange<'a> {
    fn new(net: &'a Network, seed: u64, run: u64) -> Self {
        Self {
            net,
            rng: channel_rng(seed, run, NETWORK_CHANNEL),
            in_flight: Vec::new(),
            stats: NetworkStats::default(),
        }
    }

    /// Every member's packet of `epoch`, made at `time_s`: its solution
    /// (and whether it holds a new fix, `own_new`), its relative measurements,
    /// at most `max_neighbours` (the nearest by measured range; the kept ones
    /// in their original order), and its rates of the same neighbours.
    fn send(
        &mut self,
        epoch: usize,
        time_s: f64,
        own: &[OwnSolution],
        own_new: &[bool],
        relative: &[RelativeMeasurement],
        rates: &[RelativeRate],
    ) {
        for (member, o) in own.iter().enumerate() {
            let mut mine_rates: Vec<RelativeRate> =
                rates.iter().filter(|r| r.from == member).copied().collect();
            let mut mine: Vec<RelativeMeasurement> = relative
                .iter()
                .filter(|r| r.from == member)
                .copied()
                .collect();
            if let Some(limit) = self.net.max_neighbours
                && mine.len() > limit
            {
                let mut by_range: Vec<usize> = (0..mine.len()).collect();
                by_range.sort_by(|&a, &b| {
                    mine[a]
                        .polar
                        .range_m
                        .total_cmp(&mine[b].polar.range_m)
                        .then(a.cmp(&b))
                });
                let mut keep = vec![false; mine.len()];
                for &i in &by_range[..limit] {
                    keep[i] = true;
                }
                self.stats.withheld_by_neighbour_limit += mine.len() - limit;
                let mut k = keep.iter();
                mine.retain(|_| *k.next().expect("one flag per measurement"));
                // The rates of the neighbours kept (the sensor reports them
                // together).
                mine_rates.retain(|r| mine.iter().any(|m| m.to == r.to));
            }
            // Both draws always, so the stream does not depend on the settings.
            let loss_draw: f64 = self.rng.random();
            let jitter_draw: f64 = self.rng.random();
            self.stats.sent += 1;
            if loss_draw < self.net.loss_probability {
                self.stats.lost += 1;
                continue;
            }
            self.in_flight.push(Message {
                epoch,
                arrival_s: time_s + self.net.latency_s + self.net.jitter_s * jitter_draw,
                packet: MemberPacket {
                    member,
                    own: *o,
                    own_new: own_new[member],
                    relative: mine,
                    rates: mine_rates,
                },
            });
        }
    }

    /// The packets that have arrived by `now_s`, as `(epoch, member,
    /// packet)` (a packet due within a billionth of an interval counts as
    /// arrived, so a zero delay is never lost to rounding).
    fn deliver(&mut self, now_s: f64, fix_interval_s: f64) -> Vec<(usize, usize, MemberPacket)> {
        let due = now_s + 1e-9 * fix_interval_s;
        let (arrived, waiting): (Vec<Message>, Vec<Message>) = std::mem::take(&mut self.in_flight)
            .into_iter()
            .partition(|m| m.arrival_s <= due);
        self.in_flight = waiting;
        arrived
            .into_iter()
            .map(|m| (m.epoch, m.packet.member, m.packet))
            .collect()
    }
}

/// Stage 2 over the network: per epoch, the relative measurements and rates
/// (the same random streams as the ideal exchange), every member's packet
/// sent (its own solution flagged as the ideal exchange fuses it), and
/// both filters advanced with the packets that have arrived.
pub(super) fn stage_two(
    sc: &FormationScenario,
    net: &Network,
    run: u64,
    own: &[Vec<OwnSolution>],
    truth: &[Vec<LocalLevelState>],
) -> Result<RunErrors, EstimationError> {
    let mut rng = channel_rng(sc.seed, run, RELATIVE_CHANNEL);
    let mut rate_rng = channel_rng(sc.seed, run, RATE_CHANNEL);
    let depth = net.history_epochs(sc.fix_interval_s);
    let mut paper = DelayedFusion::new(PaperFusion::new(sc.fusion_params(), &own[0])?, depth);
    let mut ekf = DelayedFusion::new(EkfFusion::new(sc.fusion_params(), &own[0])?, depth);
    let mut exchange = Exchange::new(net, sc.seed, run);
    let mut errors = RunErrors::with_capacity(own.len());
    for (epoch, (own_e, truth_e)) in own.iter().zip(truth).enumerate() {
        let relative = relative_measurements(sc, truth_e, &mut rng);
        errors.relative += relative.len();
        let rates = relative_rates(sc, truth_e, &mut rate_rng);
        let time_s = (epoch + 1) as f64 * sc.fix_interval_s;
        exchange.send(epoch, time_s, own_e, &own_new(sc, epoch), &relative, &rates);
        let arrived = exchange.deliver(time_s, sc.fix_interval_s);
        paper.advance(arrived.clone())?;
        ekf.advance(arrived)?;
        errors.push_epoch(own_e, truth_e, paper.filter(), ekf.filter());
    }
    let mut stats = exchange.stats;
    stats.in_flight_at_end = exchange.in_flight.len();
    stats.fusion = ekf.stats();
    errors.network = Some(stats);
    Ok(errors)
}

/// One cell of the [`sweep`]: a latency and a loss rate, and the accuracy
/// with them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SweepCell {
    /// Fixed latency \[s\] (plus the scenario's jitter).
    pub latency_s: f64,
    /// Loss probability.
    pub loss_probability: f64,
    /// What the network did, summed over runs.
    pub network: NetworkStats,
    /// Mean over the members that keep undisturbed GNSS of their 3-D
    /// position error RMS (settled epochs, all runs) \[m\]: GNSS/INS alone,
    /// paper fusion, EKF fusion.
    pub kept_rms_m: [f64; 3],
    /// The same members' mean filter σ (√ trace of position) \[m\].
    pub kept_sigma_m: [f64; 3],
    /// The GNSS-denied members' largest error during their denial (mean over
    /// runs and denied members) \[m\], if any member is denied.
    pub denied_max_error_m: Option<[f64; 3]>,
}

/// One run's sums for one cell of the [`sweep`]; a run's cells are what
/// [`sweep_range`] computes and [`sweep_finish`] combines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CellRun {
    /// Per member, per solution: Σ over settled epochs of the squared error.
    position_sq: Vec<[f64; 3]>,
    /// Per member, per solution: Σ over settled epochs of σ.
    sigma: Vec<[f64; 3]>,
    /// Per denied member, per solution: largest error during its denial.
    denied_max: Vec<[f64; 3]>,
    network: NetworkStats,
}

fn cell_run(sc: &FormationScenario, e: &RunErrors, settled: &[usize]) -> CellRun {
    let mut position_sq = vec![[0.0; 3]; sc.members];
    let mut sigma = vec![[0.0; 3]; sc.members];
    for &k in settled {
        for l in 0..sc.members {
            for s in 0..3 {
                position_sq[l][s] += e.position_sq[k][l][s];
                sigma[l][s] += e.sigma[k][l][s];
            }
        }
    }
    let time = |k: usize| (k + 1) as f64 * sc.fix_interval_s;
    let denied_max = (0..sc.members)
        .filter(|&l| (0..e.position_sq.len()).any(|k| sc.denied(l, time(k))))
        .map(|l| {
            let mut max = [0.0_f64; 3];
            for k in (0..e.position_sq.len()).filter(|&k| sc.denied(l, time(k))) {
                for (m, sq) in max.iter_mut().zip(e.position_sq[k][l]) {
                    *m = m.max(sq.sqrt());
                }
            }
            max
        })
        .collect();
    CellRun {
        position_sq,
        sigma,
        denied_max,
        network: e.network.unwrap_or_default(),
    }
}

/// Runs stage 2 for every latency × loss rate of `[formation.network.sweep]`
/// on each run's stage 1 and relative measurements (computed once per run),
/// with the network's other keys (jitter, neighbour limit, buffer) as
/// given. Empty without a sweep. Cells are ordered latency-major.
/// [`sweep_finish`] of every run ([`sweep_range`] over `0..mc.runs`).
pub fn sweep(sc: &FormationScenario, mc: &MonteCarlo) -> Result<Vec<SweepCell>, EstimationError> {
    Ok(sweep_finish(sc, sweep_range(sc, mc, 0..mc.runs)?))
}

/// The cells of the sweep (latency-major), or none without one.
fn sweep_cells(sc: &FormationScenario) -> Vec<Network> {
    let Some(base) = &sc.network else {
        return Vec::new();
    };
    let Some(grid) = &base.sweep else {
        return Vec::new();
    };
    grid.latency_s
        .iter()
        .flat_map(|&latency_s| {
            grid.loss_probability
                .iter()
                .map(move |&loss_probability| Network {
                    latency_s,
                    loss_probability,
                    sweep: None,
                    ..base.clone()
                })
        })
        .collect()
}

/// The epochs scored by the sweep (after `settle_s`).
fn settled_epochs(sc: &FormationScenario) -> Vec<usize> {
    (0..sc.epochs())
        .filter(|&k| (k + 1) as f64 * sc.fix_interval_s >= sc.settle_s)
        .collect()
}

/// Runs `range` of the [`sweep`] (run k's streams depend on k alone): per
/// run, its sums for every cell; a chunk for [`sweep_finish`] to combine
/// with the others, computed anywhere. Empty runs without a sweep.
pub fn sweep_range(
    sc: &FormationScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<Vec<Vec<CellRun>>, EstimationError> {
    let cells = sweep_cells(sc);
    if cells.is_empty() {
        return Ok(range.map(|_| Vec::new()).collect());
    }
    let settled = settled_epochs(sc);
    let paths = StageOnePaths::new(sc);
    mc.try_run_range(
        range,
        |run, _rng| -> Result<Vec<CellRun>, EstimationError> {
            let (own, truth) = stage_one_on(sc, run as u64, &paths)?;
            cells
                .iter()
                .map(|net| {
                    stage_two(sc, net, run as u64, &own, &truth).map(|e| cell_run(sc, &e, &settled))
                })
                .collect()
        },
    )
}

/// The sweep's cells from every run's sums, in run order (the chunks of
/// [`sweep_range`] concatenated): the same numbers, bit for bit, as
/// [`sweep`]. Empty without a sweep.
pub fn sweep_finish(sc: &FormationScenario, runs: Vec<Vec<CellRun>>) -> Vec<SweepCell> {
    let cells = sweep_cells(sc);
    if cells.is_empty() {
        return Vec::new();
    }
    let epochs = sc.epochs();
    let settled = settled_epochs(sc);
    let kept: Vec<usize> = (0..sc.members)
        .filter(|&l| {
            let disturbed = (0..epochs).any(|k| {
                let t = (k + 1) as f64 * sc.fix_interval_s;
                sc.denied(l, t) || sc.degradation_at(l, t).is_some()
            });
            !disturbed
        })
        .collect();
    let n_runs = runs.len() as f64;
    let per_member = settled.len() as f64 * n_runs;
    cells
        .iter()
        .enumerate()
        .map(|(c, net)| {
            let mut network = NetworkStats::default();
            let mut kept_rms = [0.0; 3];
            let mut kept_sigma = [0.0; 3];
            for &l in &kept {
                for s in 0..3 {
                    let sq: f64 = runs.iter().map(|r| r[c].position_sq[l][s]).sum();
                    let sigma: f64 = runs.iter().map(|r| r[c].sigma[l][s]).sum();
                    kept_rms[s] += (sq / per_member).sqrt() / kept.len() as f64;
                    kept_sigma[s] += sigma / per_member / kept.len() as f64;
                }
            }
            let mut denied = [0.0; 3];
            let mut denied_count = 0;
            for r in &runs {
                network.add(&r[c].network);
                for max in &r[c].denied_max {
                    denied_count += 1;
                    for s in 0..3 {
                        denied[s] += max[s];
                    }
                }
            }
            SweepCell {
                latency_s: net.latency_s,
                loss_probability: net.loss_probability,
                network,
                kept_rms_m: kept_rms,
                kept_sigma_m: kept_sigma,
                denied_max_error_m: (denied_count > 0)
                    .then(|| denied.map(|d| d / denied_count as f64)),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::run;
    use super::*;
    use aidnav_io::config::Validate;

    fn short() -> FormationScenario {
        FormationScenario {
            runs: 2,
            duration_s: 120.0,
            settle_s: 20.0,
            denial: vec![super::super::Denial {
                members: vec![2],
                start_s: 40.0,
                end_s: 100.0,
            }],
            ..FormationScenario::default()
        }
    }

    /// The network with zero latency, no loss and no neighbour limit gives
    /// exactly today's result (every number of the result equal): with the
    /// default stage 2 (Gauss–Markov own errors, own velocities, a denied
    /// member's solutions not re-fused), with range rates and relative
    /// velocities measured too, and with the white treatment.
    #[test]
    fn ideal_network_equals_the_ideal_exchange_exactly() {
        let rates = {
            let mut sc = short();
            sc.sensor.range_rate = true;
            sc.sensor.relative_velocity = true;
            sc
        };
        let white = FormationScenario {
            stage2_own_errors: Stage2OwnErrors::White,
            stage2_own_velocity: false,
            ..short()
        };
        for sc in [short(), rates, white] {
            ideal_network_equals_the_ideal_exchange(sc);
        }
    }

    fn ideal_network_equals_the_ideal_exchange(sc: FormationScenario) {
        let mc = MonteCarlo::new(sc.runs, sc.seed).quiet();
        let ideal = run(&sc, &mc).unwrap();
        let networked = FormationScenario {
            network: Some(Network::default()),
            ..sc.clone()
        };
        assert!(networked.network.as_ref().unwrap().is_ideal());
        let mut r = run(&networked, &mc).unwrap();
        let stats = r.network.take().unwrap();
        assert_eq!(r, ideal);
        let packets = sc.runs * sc.epochs() * sc.members;
        assert_eq!((stats.sent, stats.lost), (packets, 0));
        assert_eq!((stats.fusion.on_time, stats.fusion.delayed), (packets, 0));
    }

    /// Lost packets: the measured fraction matches the probability within
    /// 4 binomial σ; latency of 2.5 epochs: every fused packet late, none
    /// too old with the default buffer, too old (all: each is 3 epochs late)
    /// with a 2 s buffer.
    /// The same seed gives the same numbers.
    #[test]
    fn loss_and_latency_statistics() {
        let sc = FormationScenario {
            runs: 2,
            duration_s: 150.0,
            settle_s: 20.0,
            ..FormationScenario::default()
        };
        let mc = MonteCarlo::new(sc.runs, sc.seed).quiet();
        let with = |net: Network| {
            let s = FormationScenario {
                network: Some(net),
                ..sc.clone()
            };
            s.validate().unwrap();
            run(&s, &mc).unwrap()
        };
        let p = 0.3;
        let lossy = with(Network {
            loss_probability: p,
            ..Network::default()
        });
        let stats = lossy.network.unwrap();
        let n = stats.sent as f64;
        let sigma = (p * (1.0 - p) / n).sqrt();
        assert_eq!(stats.sent, sc.runs * sc.epochs() * sc.members);
        assert!(
            (stats.lost_fraction() - p).abs() < 4.0 * sigma,
            "lost {} of {}",
            stats.lost,
            stats.sent
        );
        assert_eq!(stats.fusion.on_time + stats.lost, stats.sent);
        let again = with(Network {
            loss_probability: p,
            ..Network::default()
        });
        assert_eq!(again, lossy);

        let late = with(Network {
            latency_s: 2.5,
            ..Network::default()
        });
        let stats = late.network.unwrap();
        // A packet of epoch k arrives at t_k + 2.5 s and is fused when epoch
        // k + 3 runs: the last three epochs' packets are still in flight at
        // the end.
        assert_eq!(stats.in_flight_at_end, 3 * sc.runs * sc.members);
        assert_eq!(stats.fusion.delayed + stats.in_flight_at_end, stats.sent);
        assert_eq!((stats.fusion.on_time, stats.fusion.too_old), (0, 0));
        let dropped = with(Network {
            latency_s: 2.5,
            history_s: 2.0,
            ..Network::default()
        });
        let stats = dropped.network.unwrap();
        assert_eq!(stats.fusion.delayed, 0);
        assert_eq!(stats.fusion.too_old + stats.in_flight_at_end, stats.sent);
        // Nothing fused: stage 2 only predicts and is far worse than with
        // the late packets fused at their own time.
        let rms = |r: &super::super::FormationResult| r.members[0].position_rms_m[2];
        assert!(
            rms(&dropped) > 10.0 * rms(&late),
            "{} vs {}",
            rms(&dropped),
            rms(&late)
        );
    }

    /// The neighbour limit withholds the farthest measurements: with one
    /// neighbour per member, 5 members in a V within range of each other,
    /// 3 of each member's 4 measurements are withheld.
    #[test]
    fn neighbour_limit_withholds_the_rest() {
        let sc = FormationScenario {
            runs: 1,
            duration_s: 30.0,
            settle_s: 10.0,
            network: Some(Network {
                max_neighbours: Some(1),
                ..Network::default()
            }),
            ..FormationScenario::default()
        };
        let r = run(&sc, &MonteCarlo::new(1, sc.seed).quiet()).unwrap();
        let stats = r.network.unwrap();
        assert!((r.relative_per_epoch - 20.0).abs() < 1e-12);
        assert_eq!(stats.withheld_by_neighbour_limit, 30 * 5 * 3);
    }

    #[test]
    fn bad_network_keys_are_named() {
        let with = |net: Network| FormationScenario {
            network: Some(net),
            ..FormationScenario::default()
        };
        let cases = [
            (
                Network {
                    latency_s: -1.0,
                    ..Network::default()
                },
                "network.latency_s",
            ),
            (
                Network {
                    jitter_s: f64::NAN,
                    ..Network::default()
                },
                "network.jitter_s",
            ),
            (
                Network {
                    loss_probability: 1.5,
                    ..Network::default()
                },
                "network.loss_probability",
            ),
            (
                Network {
                    max_neighbours: Some(5000),
                    ..Network::default()
                },
                "network.max_neighbours",
            ),
            (
                Network {
                    history_s: 1e9,
                    ..Network::default()
                },
                "network.history_s",
            ),
            (
                Network {
                    sweep: Some(NetworkSweep {
                        latency_s: vec![0.0, 100.0],
                        loss_probability: vec![0.0],
                    }),
                    ..Network::default()
                },
                "network.sweep.latency_s",
            ),
            (
                Network {
                    sweep: Some(NetworkSweep {
                        latency_s: vec![0.0],
                        loss_probability: vec![],
                    }),
                    ..Network::default()
                },
                "network.sweep.loss_probability",
            ),
        ];
        for (net, key) in cases {
            assert_eq!(with(net).validate().unwrap_err().key, key);
        }
        // 50 members at 0.1 s epochs: a 600 s buffer would take gigabytes.
        let big = FormationScenario {
            members: 50,
            fix_interval_s: 0.1,
            network: Some(Network {
                history_s: 600.0,
                ..Network::default()
            }),
            ..FormationScenario::default()
        };
        assert_eq!(big.validate().unwrap_err().key, "network.history_s");
        assert!(with(Network::default()).validate().is_ok());
    }

    /// The sweep's cell with zero latency and loss equals the plain run with
    /// the ideal network; its other cells are paired with it (same stage 1),
    /// and a lossy cell loses about its share.
    #[test]
    fn sweep_cells_match_single_runs() {
        let sc = FormationScenario {
            network: Some(Network {
                sweep: Some(NetworkSweep {
                    latency_s: vec![0.0, 1.5],
                    loss_probability: vec![0.0, 0.5],
                }),
                ..Network::default()
            }),
            ..short()
        };
        sc.validate().unwrap();
        let mc = MonteCarlo::new(sc.runs, sc.seed).quiet();
        let cells = sweep(&sc, &mc).unwrap();
        assert_eq!(cells.len(), 4);
        let single = |latency_s: f64, loss_probability: f64| {
            let s = FormationScenario {
                network: Some(Network {
                    latency_s,
                    loss_probability,
                    ..Network::default()
                }),
                ..sc.clone()
            };
            run(&s, &mc).unwrap()
        };
        for cell in [&cells[0], &cells[3]] {
            let r = single(cell.latency_s, cell.loss_probability);
            assert_eq!(r.network.unwrap(), cell.network);
            let kept = [0, 1, 3, 4];
            let ekf: f64 = kept
                .iter()
                .map(|&l| r.members[l].position_rms_m[2])
                .sum::<f64>()
                / 4.0;
            assert!(
                (ekf - cell.kept_rms_m[2]).abs() < 1e-12,
                "{ekf} vs {:?}",
                cell.kept_rms_m
            );
            let denied = r.members[2].denial_max_error_m.unwrap();
            let d = cell.denied_max_error_m.unwrap();
            assert!((denied[2] - d[2]).abs() < 1e-12);
        }
        // Stage 1 is shared: GNSS/INS alone is the same in every cell.
        assert!(
            cells
                .iter()
                .all(|c| c.kept_rms_m[0] == cells[0].kept_rms_m[0])
        );
        // Late and lossy is worse than ideal.
        assert!(cells[3].kept_rms_m[2] > cells[0].kept_rms_m[2]);
    }
}
