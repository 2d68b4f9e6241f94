//! Stage 2 in the paper's form: the 3-D group split into three independent
//! axis filters ([`GroupAxisFilter`], constant-velocity model, own positions
//! and optionally velocities observed), each relative measurement converted
//! to Cartesian coordinates with the observer's INS* attitude and its
//! per-axis variance taken from the diagonal of the converted covariance.

use aidnav_estimation::EstimationError;
use nalgebra::Vector3;

use super::delayed::check_packets;
use super::{
    EpochFusion, FusionParams, GroupAxisFilter, MemberPacket, OwnSolution, RelativeMeasurement,
    attitude_covariance_on,
};

/// Stage 2, paper form: three axis filters over all members.
#[derive(Debug, Clone)]
pub struct PaperFusion {
    params: FusionParams,
    axes: Vec<GroupAxisFilter>,
}

impl PaperFusion {
    /// A filter for the members of `first` (their stage-1 solutions at the
    /// first epoch give the initial state).
    pub fn new(params: FusionParams, first: &[OwnSolution]) -> Result<Self, EstimationError> {
        let m = first.len();
        let axes = (0..3)
            .map(|a| {
                let p: Vec<f64> = first.iter().map(|o| o.state.position[a]).collect();
                let v: Vec<f64> = first.iter().map(|o| o.state.velocity[a]).collect();
                GroupAxisFilter::new(
                    m,
                    params.interval_s,
                    params.accel_sigma_m_s2,
                    params.own_velocity,
                    &p,
                    &v,
                    params.initial_position_sigma_m,
                    params.initial_velocity_sigma_mps,
                )
            })
            .collect::<Result<_, _>>()?;
        Ok(Self { params, axes })
    }

    /// One epoch: predict (unless it is the first), then fuse every
    /// member's own solution and every relative measurement.
    pub fn epoch(
        &mut self,
        own: &[OwnSolution],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        self.fuse(
            own.iter().enumerate(),
            relative.iter().map(|r| (&own[r.from], r)),
            predict,
        )
    }

    /// One epoch from the packets that arrived for it
    /// ([`DelayedFusion`](super::DelayedFusion)): predict (if `predict`),
    /// then the own solutions of the members that sent a packet and their
    /// relative measurements, in the order of `packets`. With every
    /// member's packet, in member order, it is [`epoch`](Self::epoch).
    pub fn epoch_from_packets(
        &mut self,
        packets: &[MemberPacket],
        predict: bool,
    ) -> Result<(), EstimationError> {
        check_packets(packets, self.axes[0].members())?;
        self.fuse(
            packets.iter().map(|p| (p.member, &p.own)),
            packets
                .iter()
                .flat_map(|p| p.relative.iter().map(move |r| (&p.own, r))),
            predict,
        )
    }

    /// Per axis: predict, own solutions `(member, solution)`, relative
    /// measurements `(observer's solution, measurement)`, one update.
    fn fuse<'a>(
        &mut self,
        own: impl Iterator<Item = (usize, &'a OwnSolution)> + Clone,
        relative: impl Iterator<Item = (&'a OwnSolution, &'a RelativeMeasurement)> + Clone,
        predict: bool,
    ) -> Result<(), EstimationError> {
        let params = &self.params;
        for (a, f) in self.axes.iter_mut().enumerate() {
            if predict {
                f.predict();
            }
            for (l, o) in own.clone() {
                f.observe_own_position(l, o.state.position[a], o.covariance[(a, a)].sqrt())?;
                if params.own_velocity {
                    f.observe_own_velocity(
                        l,
                        o.state.velocity[a],
                        o.covariance[(3 + a, 3 + a)].sqrt(),
                    )?;
                }
            }
            for (observer, r) in relative.clone() {
                let c = observer.state.attitude.to_rotation_matrix().into_inner();
                // Line of sight to `to` in the nav frame: d = R^to − R^from.
                let d = c * r.polar.to_cartesian();
                let cov = c * params.sensor.converted_covariance(&r.polar) * c.transpose()
                    + attitude_covariance_on(&d, &observer.attitude_covariance);
                // The paper's z^{lk} = R^l − R^k with l the observer.
                f.observe_relative(r.from, r.to, -d[a], cov[(a, a)].sqrt())?;
            }
            f.update()?;
        }
        Ok(())
    }

    /// Estimated position of member `l` \[m\].
    pub fn position(&self, l: usize) -> Vector3<f64> {
        Vector3::new(
            self.axes[0].position(l),
            self.axes[1].position(l),
            self.axes[2].position(l),
        )
    }

    /// Estimated velocity of member `l` \[m/s\].
    pub fn velocity(&self, l: usize) -> Vector3<f64> {
        Vector3::new(
            self.axes[0].velocity(l),
            self.axes[1].velocity(l),
            self.axes[2].velocity(l),
        )
    }

    /// The filter's 3-D position σ of member `l` (√ trace) \[m\].
    pub fn position_sigma(&self, l: usize) -> f64 {
        self.axes
            .iter()
            .map(|f| f.position_sigma(l).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

impl EpochFusion for PaperFusion {
    type Packet = MemberPacket;

    fn fuse_epoch(
        &mut self,
        packets: &[MemberPacket],
        predict: bool,
    ) -> Result<(), EstimationError> {
        self.epoch_from_packets(packets, predict)
    }
}
