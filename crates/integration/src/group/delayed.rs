//! Delayed measurements fused at their own time, by rewind and replay.
//!
//! A measurement that reaches the filter after the epoch it was taken at must
//! not be applied as if it were current (the members have moved) nor simply
//! dropped. [`DelayedFusion`] keeps, for the last `depth` epochs, the filter
//! as it was before each epoch and the packets fused at it. A late packet is
//! inserted into its own epoch's set; the filter is restored to that epoch's
//! snapshot and the epochs up to the current one are run again, each with
//! its (now larger) set. The result is the filter that would have run had
//! every packet arrived on time (the same operations in the same order, so
//! equal to rounding — exactly, in practice). A packet older than the buffer
//! is counted ([`DelayStats::too_old`]) and dropped: the buffer's size is
//! fixed, so no input can exhaust memory.
//!
//! The mechanism is filter-agnostic: any [`EpochFusion`] (a `Clone`able
//! filter that runs one epoch from a slice of packets) can be wrapped. The
//! packets of an epoch are fused in the order of their source (member) index,
//! whatever order they arrived in, so the result does not depend on arrival
//! order. [`MemberPacket`] is the packet of the formation's stage 2: one
//! member's stage-1 solution (and whether it holds a new GNSS fix), its
//! relative measurements and its range rates / relative velocities at one
//! epoch;
//! [`EkfFusion`](super::EkfFusion) and [`PaperFusion`](super::PaperFusion)
//! implement [`EpochFusion`] with it.
//!
//! ```
//! use aidnav_estimation::EstimationError;
//! use aidnav_integration::group::{DelayedFusion, EpochFusion};
//!
//! /// A scalar random walk observed directly (σ² = 1 per measurement).
//! #[derive(Clone)]
//! struct Walk { x: f64, p: f64 }
//! impl EpochFusion for Walk {
//!     type Packet = f64;
//!     fn fuse_epoch(&mut self, z: &[f64], predict: bool) -> Result<(), EstimationError> {
//!         if predict { self.p += 0.5; }
//!         for z in z {
//!             let k = self.p / (self.p + 1.0);
//!             self.x += k * (z - self.x);
//!             self.p *= 1.0 - k;
//!         }
//!         Ok(())
//!     }
//! }
//! let mut late = DelayedFusion::new(Walk { x: 0.0, p: 4.0 }, 3);
//! let mut on_time = DelayedFusion::new(Walk { x: 0.0, p: 4.0 }, 3);
//! late.advance(vec![(0, 0, 1.0)])?;
//! on_time.advance(vec![(0, 0, 1.0)])?;
//! late.advance(vec![])?; // epoch 1's measurement is in flight …
//! on_time.advance(vec![(1, 0, 2.0)])?;
//! late.advance(vec![(1, 0, 2.0), (2, 0, 2.5)])?; // … and arrives at epoch 2
//! on_time.advance(vec![(2, 0, 2.5)])?;
//! assert!((late.filter().x - on_time.filter().x).abs() < 1e-12);
//! assert_eq!(late.stats().rewound, 1);
//! # Ok::<(), EstimationError>(())
//! ```

use std::collections::VecDeque;

use aidnav_estimation::EstimationError;
use serde::Serialize;

use super::{OwnSolution, RelativeMeasurement, RelativeRate};

/// A filter that runs one epoch at a time from the packets of that epoch.
pub trait EpochFusion: Clone {
    /// What one source sends for one epoch.
    type Packet: Clone + std::fmt::Debug;

    /// One epoch: the time update from the previous epoch (if `predict`;
    /// [`DelayedFusion`] passes false for epoch 0 only, where the filter's
    /// prior applies), then the packets, fused in the order given.
    fn fuse_epoch(
        &mut self,
        packets: &[Self::Packet],
        predict: bool,
    ) -> Result<(), EstimationError>;
}

/// What one member of the formation sends for one epoch: its stage-1
/// solution, whether that solution holds a new GNSS fix, and the relative
/// measurements (positions, then rates) it made of its neighbours.
#[derive(Debug, Clone, PartialEq)]
pub struct MemberPacket {
    /// The sending member (0-based); every `relative[i].from` must equal it
    /// (the filters refuse the packet otherwise).
    pub member: usize,
    /// Its stage-1 (INS*) solution; its attitude and attitude covariance
    /// also convert its relative measurements.
    pub own: OwnSolution,
    /// Whether its stage 1 had a GNSS fix since the last epoch. If not, its
    /// solution is a prediction from information already fused and is not
    /// fused again (its attitude still serves its relative measurements);
    /// see `epoch_with_new_own` on the filters.
    pub own_new: bool,
    /// Its relative measurements of other members at the same epoch.
    pub relative: Vec<RelativeMeasurement>,
    /// Its range rates and/or relative velocities of other members at the
    /// same epoch (fused after every packet's positions, like `fuse_rates`).
    pub rates: Vec<RelativeRate>,
}

/// Checks that every packet's member and every relative measurement's and
/// rate's members are below `members` (the number of members, not a state
/// dimension: the filters may carry more states per member), and that each
/// relative measurement and rate was made by the packet's member. Refused as a dimension mismatch: an index too
/// large as `cols` = 6 (index + 1) against `expected_cols` = 6 `members`; a
/// measurement from another member as `rows` = its `from` against
/// `expected_rows` = the packet's member.
pub(super) fn check_packets(
    packets: &[MemberPacket],
    members: usize,
) -> Result<(), EstimationError> {
    let mismatch = |rows, cols, expected_rows| EstimationError::DimensionMismatch {
        step: aidnav_estimation::Step::Update,
        matrix: aidnav_estimation::Matrix::H,
        rows,
        cols,
        expected_rows,
        expected_cols: 6 * members,
    };
    for p in packets {
        let pairs = || {
            p.relative
                .iter()
                .map(|r| (r.from, r.to))
                .chain(p.rates.iter().map(|r| (r.from, r.to)))
        };
        let largest = pairs()
            .flat_map(|(from, to)| [from, to])
            .fold(p.member, usize::max);
        if largest >= members {
            return Err(mismatch(1, 6 * (largest + 1), 1));
        }
        if let Some((from, _)) = pairs().find(|&(from, _)| from != p.member) {
            return Err(mismatch(from, 6 * members, p.member));
        }
    }
    Ok(())
}

/// Counts of what [`DelayedFusion`] did with the packets it was given.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, serde::Deserialize)]
pub struct DelayStats {
    /// Packets fused in the epoch at which they arrived.
    pub on_time: usize,
    /// Packets that arrived after their epoch and were fused at it by rewind.
    pub delayed: usize,
    /// Packets older than the buffer, dropped.
    pub too_old: usize,
    /// Packets for an epoch not yet run (a caller's error), dropped.
    pub from_future: usize,
    /// Second packets from the same source for the same epoch, dropped.
    pub duplicate: usize,
    /// Rewinds made (one per [`DelayedFusion::advance`] with late packets).
    pub rewound: usize,
    /// Epochs run again by the rewinds.
    pub replayed_epochs: usize,
}

impl DelayStats {
    /// Adds another filter's or run's counts to these.
    pub fn add(&mut self, other: &DelayStats) {
        self.on_time += other.on_time;
        self.delayed += other.delayed;
        self.too_old += other.too_old;
        self.from_future += other.from_future;
        self.duplicate += other.duplicate;
        self.rewound += other.rewound;
        self.replayed_epochs += other.replayed_epochs;
    }
}

/// One buffered epoch: the filter before it ran, and its packets sorted by
/// source.
#[derive(Debug, Clone)]
struct EpochRecord<F: EpochFusion> {
    epoch: usize,
    before: F,
    sources: Vec<usize>,
    packets: Vec<F::Packet>,
}

impl<F: EpochFusion> EpochRecord<F> {
    /// Inserts a packet in source order; false if the source already sent one.
    fn insert(&mut self, source: usize, packet: F::Packet) -> bool {
        match self.sources.binary_search(&source) {
            Ok(_) => false,
            Err(i) => {
                self.sources.insert(i, source);
                self.packets.insert(i, packet);
                true
            }
        }
    }
}

/// A filter wrapped so that late packets are fused at their own epoch
/// (rewind and replay over a buffer of the last `depth` epochs).
#[derive(Debug, Clone)]
pub struct DelayedFusion<F: EpochFusion> {
    filter: F,
    /// Records of epochs `next_epoch − len … next_epoch − 1`.
    history: VecDeque<EpochRecord<F>>,
    depth: usize,
    next_epoch: usize,
    stats: DelayStats,
}

impl<F: EpochFusion> DelayedFusion<F> {
    /// Wraps `filter` (its prior applies at epoch 0). `depth` is how many
    /// epochs back a packet may be late and still be fused: a packet for
    /// epoch j arriving when epoch k runs is fused if k − j ≤ `depth`. The
    /// buffer holds `depth + 1` copies of the filter.
    pub fn new(filter: F, depth: usize) -> Self {
        Self {
            filter,
            history: VecDeque::with_capacity(depth + 1),
            depth,
            next_epoch: 0,
            stats: DelayStats::default(),
        }
    }

    /// The filter after the last epoch run, with every packet that had
    /// arrived by then.
    pub fn filter(&self) -> &F {
        &self.filter
    }

    /// What happened to the packets so far.
    pub fn stats(&self) -> DelayStats {
        self.stats
    }

    /// The index of the epoch the next [`advance`](Self::advance) runs.
    pub fn next_epoch(&self) -> usize {
        self.next_epoch
    }

    /// Runs the next epoch with the packets that arrived since the previous
    /// one, each given as `(epoch, source, packet)`: the epoch it was
    /// measured at, its sender, and its content. Packets for the epoch being
    /// run are fused in it; packets for earlier epochs within the buffer are
    /// fused at their own epoch by rewinding to it and running the epochs
    /// since again; older ones, second packets from a source for an epoch,
    /// and packets for later epochs are counted and dropped.
    pub fn advance(
        &mut self,
        arrived: impl IntoIterator<Item = (usize, usize, F::Packet)>,
    ) -> Result<(), EstimationError> {
        let now = self.next_epoch;
        if self.history.len() == self.depth + 1 {
            self.history.pop_front();
        }
        self.history.push_back(EpochRecord {
            epoch: now,
            before: self.filter.clone(),
            sources: Vec::new(),
            packets: Vec::new(),
        });
        let oldest = self.history[0].epoch;
        let mut rewind_to = now;
        for (epoch, source, packet) in arrived {
            if epoch > now {
                self.stats.from_future += 1;
                continue;
            }
            if epoch < oldest {
                self.stats.too_old += 1;
                continue;
            }
            if !self.history[epoch - oldest].insert(source, packet) {
                self.stats.duplicate += 1;
            } else if epoch == now {
                self.stats.on_time += 1;
            } else {
                self.stats.delayed += 1;
                rewind_to = rewind_to.min(epoch);
            }
        }
        if rewind_to < now {
            self.stats.rewound += 1;
            self.stats.replayed_epochs += now - rewind_to;
        }
        // Without late packets only the current epoch runs; with them, from
        // the earliest late packet's epoch on, each epoch's snapshot renewed.
        let start = rewind_to - oldest;
        if rewind_to < now {
            self.filter = self.history[start].before.clone();
        }
        for i in start..self.history.len() {
            if i > start {
                self.history[i].before = self.filter.clone();
            }
            let record = &self.history[i];
            self.filter
                .fuse_epoch(&record.packets, record.epoch > 0)
                .map_err(|e| e.at_epoch(record.epoch))?;
        }
        self.next_epoch += 1;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Scalar random walk, Q = 0.3, each packet a direct observation with
    /// R = 0.7; the order of fusion matters only to rounding.
    #[derive(Debug, Clone, PartialEq)]
    struct Walk {
        x: f64,
        p: f64,
    }

    impl EpochFusion for Walk {
        type Packet = f64;
        fn fuse_epoch(&mut self, z: &[f64], predict: bool) -> Result<(), EstimationError> {
            if predict {
                self.p += 0.3;
            }
            for z in z {
                let k = self.p / (self.p + 0.7);
                self.x += k * (z - self.x);
                self.p *= 1.0 - k;
            }
            Ok(())
        }
    }

    fn measurement(epoch: usize, source: usize) -> f64 {
        (epoch as f64 * 0.37 + source as f64 * 1.3).sin() * 2.0 + epoch as f64 * 0.1
    }

    /// Every packet delayed by a fixed number of epochs ≤ the depth: after
    /// the last packet has arrived the filter equals the one that had every
    /// packet on time, and its closed-form check (two sources fused in
    /// sequence) holds.
    #[test]
    fn rewind_equals_on_time_fusion() {
        let epochs = 12;
        let sources = 3;
        for delay in 0..4 {
            let mut on_time = DelayedFusion::new(Walk { x: 0.0, p: 5.0 }, 0);
            let mut late = DelayedFusion::new(Walk { x: 0.0, p: 5.0 }, 3);
            for k in 0..epochs + delay {
                if k < epochs {
                    on_time
                        .advance((0..sources).map(|s| (k, s, measurement(k, s))))
                        .unwrap();
                }
                // Source s is late by `delay` epochs; sources arrive in reverse.
                let arrivals: Vec<_> = (0..sources)
                    .rev()
                    .filter(|_| k >= delay && k - delay < epochs)
                    .map(|s| (k - delay, s, measurement(k - delay, s)))
                    .collect();
                late.advance(arrivals).unwrap();
                // Epochs after the last one carry no packets; the on-time
                // filter predicts through them too.
                if k >= epochs {
                    on_time.advance(Vec::new()).unwrap();
                }
            }
            let (a, b) = (on_time.filter(), late.filter());
            assert!((a.x - b.x).abs() < 1e-12, "delay {delay}: {a:?} vs {b:?}");
            assert!((a.p - b.p).abs() < 1e-12, "delay {delay}: {a:?} vs {b:?}");
            let s = late.stats();
            assert_eq!(s.too_old, 0);
            if delay == 0 {
                assert_eq!((s.on_time, s.delayed, s.rewound), (epochs * sources, 0, 0));
            } else {
                assert_eq!((s.on_time, s.delayed), (0, epochs * sources));
                assert_eq!(s.rewound, epochs);
                assert_eq!(s.replayed_epochs, epochs * delay);
            }
        }
        // Independent check of the scalar filter itself: one epoch from the
        // prior with two observations is the information-form fusion.
        let mut w = Walk { x: 0.0, p: 5.0 };
        w.fuse_epoch(&[1.0, 2.0], false).unwrap();
        let info = 1.0 / 5.0 + 2.0 / 0.7;
        assert!((w.p - 1.0 / info).abs() < 1e-12);
        assert!((w.x - (3.0 / 0.7) / info).abs() < 1e-12);
    }

    /// Packets older than the buffer are counted and dropped; those for the
    /// future and duplicates likewise; the buffer never holds more than
    /// depth + 1 epochs.
    #[test]
    fn old_future_and_duplicate_packets_are_counted_and_dropped() {
        let mut f = DelayedFusion::new(Walk { x: 0.0, p: 5.0 }, 2);
        for _ in 0..5 {
            f.advance(Vec::new()).unwrap();
        }
        assert_eq!(f.history.len(), 3);
        // Now running epoch 5: the buffer holds epochs 3, 4, 5.
        f.advance(vec![
            (2, 0, 1.0),
            (3, 0, 1.0),
            (3, 0, 9.0),
            (6, 0, 1.0),
            (5, 1, 1.0),
        ])
        .unwrap();
        let s = f.stats();
        assert_eq!(
            (s.too_old, s.delayed, s.duplicate, s.from_future, s.on_time),
            (1, 1, 1, 1, 1)
        );
        assert_eq!((s.rewound, s.replayed_epochs), (1, 2));
        assert_eq!(f.history.len(), 3);
        assert_eq!(f.next_epoch(), 6);
    }

    use crate::group::{
        CorrelatedOwnErrors, EkfFusion, FusionParams, MotionModel, OwnErrorModel, PaperFusion,
    };
    use aidnav_ins::local_level::LocalLevelState;
    use aidnav_models::GaussMarkov;
    use aidnav_models::local_ins::Matrix6;
    use aidnav_models::relative_sensor::{Polar, RelativeSensor};
    use nalgebra::{Matrix3, UnitQuaternion, Vector3};

    const MEMBERS: usize = 3;

    fn params() -> FusionParams {
        FusionParams {
            interval_s: 1.0,
            accel_sigma_m_s2: 1.0,
            own_velocity: false,
            sensor: RelativeSensor::default(),
            initial_position_sigma_m: 10.0,
            initial_velocity_sigma_mps: 1.0,
            own_errors: OwnErrorModel::White,
            motion: MotionModel::Paper,
        }
    }

    /// Stage 2 on stage 1's reported error transition (own-error states of
    /// position and velocity), the motion with the position's share of the
    /// acceleration, rates measured.
    fn params_stage1_reported() -> FusionParams {
        FusionParams {
            own_errors: OwnErrorModel::Stage1Reported,
            motion: MotionModel::PiecewiseConstantAcceleration,
            ..params_gauss_markov()
        }
    }

    /// wt-grpB's stage 2: Gauss–Markov own-error states (position and
    /// velocity, so the state is longer than 6 per member), own velocities
    /// fused, range rate and relative velocity measured.
    fn params_gauss_markov() -> FusionParams {
        let gm = |tau, sigma| GaussMarkov::new(tau, sigma).unwrap();
        FusionParams {
            own_velocity: true,
            sensor: RelativeSensor {
                range_rate: true,
                relative_velocity: true,
                ..RelativeSensor::default()
            },
            own_errors: OwnErrorModel::GaussMarkov(CorrelatedOwnErrors {
                position: [gm(60.0, 1.5), gm(60.0, 1.5), gm(60.0, 3.0)],
                velocity: [gm(30.0, 0.05); 3],
                position_white_floor_m: 0.3,
                velocity_white_floor_mps: 0.01,
            }),
            ..params()
        }
    }

    /// Member l at epoch k: flying east at 60 m/s, 150 m apart, with
    /// deterministic "errors" (a few metres) on the stage-1 solution and on
    /// the relative measurements, so the updates move the state.
    fn packet(k: usize, l: usize) -> MemberPacket {
        let truth = |m: usize| {
            Vector3::new(
                60.0 * k as f64 - 100.0 * m as f64,
                150.0 * m as f64,
                1000.0 + 10.0 * m as f64,
            )
        };
        let wobble = |a: f64| (a * (k * 7 + l * 3 + 1) as f64).sin();
        let attitude = UnitQuaternion::from_euler_angles(0.01 * wobble(1.1), 0.02, 0.05 * l as f64);
        let covariance =
            Matrix6::from_diagonal(&nalgebra::Vector6::new(4.0, 4.0, 16.0, 0.01, 0.01, 0.02));
        let own = OwnSolution {
            state: LocalLevelState {
                position: truth(l)
                    + Vector3::new(2.0 * wobble(0.3), -1.5 * wobble(0.7), wobble(1.9)),
                velocity: Vector3::new(60.0 + 0.1 * wobble(2.3), 0.05 * wobble(0.9), 0.0),
                attitude,
            },
            covariance,
            attitude_covariance: Matrix3::from_diagonal_element(1e-6),
            // An error correlated 0.9 from one epoch to the next.
            error_cross_covariance: Some(covariance * 0.9),
        };
        let relative = (0..MEMBERS)
            .filter(|&m| m != l)
            .map(|m| {
                let body = attitude.inverse() * (truth(m) - truth(l));
                let p = Polar::from_cartesian(&body);
                RelativeMeasurement {
                    from: l,
                    to: m,
                    polar: Polar {
                        range_m: p.range_m + 0.4 * wobble(0.5),
                        bearing_rad: p.bearing_rad + 2e-3 * wobble(0.2),
                        elevation_rad: p.elevation_rad - 1e-3 * wobble(0.4),
                    },
                }
            })
            .collect();
        let rates = (0..MEMBERS)
            .filter(|&m| m != l)
            .map(|m| RelativeRate {
                // The members fly in parallel: true rates are zero.
                from: l,
                to: m,
                range_rate_mps: Some(0.05 * wobble(1.3 + m as f64)),
                body_velocity_mps: Some(
                    attitude.inverse() * Vector3::new(0.03 * wobble(0.6), -0.02 * wobble(0.8), 0.0),
                ),
            })
            .collect();
        MemberPacket {
            member: l,
            own,
            // Every third solution without a new GNSS fix.
            own_new: (k + l) % 3 != 2,
            relative,
            rates,
        }
    }

    fn first() -> Vec<OwnSolution> {
        (0..MEMBERS).map(|l| packet(0, l).own).collect()
    }

    /// Largest difference in any member's position, velocity or σ.
    fn difference(
        a: [(Vector3<f64>, Vector3<f64>, f64); MEMBERS],
        b: [(Vector3<f64>, Vector3<f64>, f64); MEMBERS],
    ) -> f64 {
        a.iter()
            .zip(&b)
            .map(|(x, y)| {
                (x.0 - y.0)
                    .amax()
                    .max((x.1 - y.1).amax())
                    .max((x.2 - y.2).abs())
            })
            .fold(0.0, f64::max)
    }

    fn ekf_estimate(f: &EkfFusion) -> [(Vector3<f64>, Vector3<f64>, f64); MEMBERS] {
        std::array::from_fn(|l| (f.position(l), f.velocity(l), f.position_sigma(l)))
    }

    fn paper_estimate(f: &PaperFusion) -> [(Vector3<f64>, Vector3<f64>, f64); MEMBERS] {
        std::array::from_fn(|l| (f.position(l), f.velocity(l), f.position_sigma(l)))
    }

    /// Member 1's packet of epoch 4 arrives at epoch 7; every other packet
    /// on time. After epoch 7 the wrapped filter equals (to 1e-9) a filter
    /// fed every packet on time through `epoch`; before the late packet
    /// arrives it differs (the packet matters). Both stage-2 forms.
    #[test]
    fn late_packet_fused_by_rewind_equals_on_time_fusion_in_both_filters() {
        late_packet_fused_by_rewind(params());
        late_packet_fused_by_rewind(params_gauss_markov());
        late_packet_fused_by_rewind(params_stage1_reported());
    }

    /// The rewind test with `params`; the reference runs `epoch_with_new_own`
    /// (own solutions fused only with a new fix) then `fuse_rates`.
    fn late_packet_fused_by_rewind(params: FusionParams) {
        let epochs = 10;
        // Rates only where the sensor measures them (the paper's axis filters
        // carry no relative velocity otherwise).
        let rates_on = params.sensor.range_rate || params.sensor.relative_velocity;
        let packet = |k: usize, l: usize| {
            let mut p = packet(k, l);
            if !rates_on {
                p.rates.clear();
            }
            p
        };
        let late = |k: usize, l: usize| k == 4 && l == 1;
        let arrivals = |k: usize| {
            let mut a: Vec<(usize, usize, MemberPacket)> = (0..MEMBERS)
                .filter(|&l| !late(k, l))
                .map(|l| (k, l, packet(k, l)))
                .collect();
            if k == 7 {
                a.push((4, 1, packet(4, 1)));
            }
            a
        };
        let mut ekf_ref = EkfFusion::new(params, &first()).unwrap();
        let mut paper_ref = PaperFusion::new(params, &first()).unwrap();
        let mut ekf = DelayedFusion::new(EkfFusion::new(params, &first()).unwrap(), 5);
        let mut paper = DelayedFusion::new(PaperFusion::new(params, &first()).unwrap(), 5);
        for k in 0..epochs {
            let packets: Vec<MemberPacket> = (0..MEMBERS).map(|l| packet(k, l)).collect();
            let own: Vec<OwnSolution> = packets.iter().map(|p| p.own).collect();
            let own_new: Vec<bool> = packets.iter().map(|p| p.own_new).collect();
            let relative: Vec<RelativeMeasurement> =
                packets.iter().flat_map(|p| p.relative.clone()).collect();
            let rates: Vec<RelativeRate> = packets.iter().flat_map(|p| p.rates.clone()).collect();
            ekf_ref
                .epoch_with_new_own(&own, &own_new, &relative, k > 0)
                .unwrap();
            paper_ref
                .epoch_with_new_own(&own, &own_new, &relative, k > 0)
                .unwrap();
            if rates_on {
                ekf_ref.fuse_rates(&own, &rates).unwrap();
                paper_ref.fuse_rates(&own, &rates).unwrap();
            }
            ekf.advance(arrivals(k)).unwrap();
            paper.advance(arrivals(k)).unwrap();
            let d_ekf = difference(ekf_estimate(ekf.filter()), ekf_estimate(&ekf_ref));
            let d_paper = difference(paper_estimate(paper.filter()), paper_estimate(&paper_ref));
            if (4..7).contains(&k) {
                assert!(
                    d_ekf > 1e-3 && d_paper > 1e-3,
                    "epoch {k}: {d_ekf}, {d_paper}"
                );
            } else {
                assert!(
                    d_ekf < 1e-9 && d_paper < 1e-9,
                    "epoch {k}: {d_ekf}, {d_paper}"
                );
            }
        }
        let s = ekf.stats();
        assert_eq!((s.delayed, s.rewound, s.replayed_epochs), (1, 1, 3));
        assert_eq!(s.on_time, epochs * MEMBERS - 1);
    }

    /// A packet naming a member outside the group, or a relative
    /// measurement or rate made by another member, is refused, not a panic.
    #[test]
    fn packets_with_bad_members_are_refused() {
        // With the Gauss–Markov states the EKF's state is longer than 6 per
        // member: the check must use the number of members.
        let mut ekf = EkfFusion::new(params_gauss_markov(), &first()).unwrap();
        let mut paper = PaperFusion::new(params_gauss_markov(), &first()).unwrap();
        let mut outside = packet(1, 2);
        outside.member = MEMBERS;
        let mut foreign = packet(1, 2);
        foreign.relative[0].from = 0;
        let mut rate_outside = packet(1, 2);
        rate_outside.rates[0].to = MEMBERS;
        let mut rate_foreign = packet(1, 2);
        rate_foreign.rates[0].from = 0;
        for bad in [outside, foreign, rate_outside, rate_foreign] {
            assert!(matches!(
                ekf.epoch_from_packets(std::slice::from_ref(&bad), true),
                Err(EstimationError::DimensionMismatch { .. })
            ));
            assert!(matches!(
                paper.epoch_from_packets(&[bad], true),
                Err(EstimationError::DimensionMismatch { .. })
            ));
        }
    }
}
