//! Stage 2 in the paper's form: the 3-D group split into three independent
//! axis filters ([`GroupAxisFilter`], constant-velocity model, own positions
//! and optionally velocities observed), each relative measurement converted
//! to Cartesian coordinates with the observer's INS* attitude and its
//! per-axis variance taken from the diagonal of the converted covariance.
//! Body-frame relative velocities are converted the same way; range rates
//! are not used (a scalar along the line of sight has no per-axis form).
//! With [`OwnErrorModel::GaussMarkov`] each axis filter carries the
//! correlated own errors of that axis ([`GroupAxisFilter::with_own_errors`]).

use aidnav_estimation::EstimationError;
use aidnav_models::local_ins::Matrix6;
use nalgebra::{Matrix2, Vector3};

use super::delayed::check_packets;
use super::{
    AxisOwnErrors, EpochFusion, FusionParams, GroupAxisFilter, MemberPacket, OwnErrorModel,
    OwnSolution, RelativeMeasurement, RelativeRate, STAGE1_WHITE_FRACTION, Stage1Errors,
    attitude_covariance_on,
};

/// Axis `a`'s 2×2 block (position, velocity) of a 6×6 position–velocity
/// matrix: the paper's decoupling drops the cross-axis terms.
fn axis_block(m: &Matrix6, a: usize) -> Matrix2<f64> {
    Matrix2::new(m[(a, a)], m[(a, 3 + a)], m[(3 + a, a)], m[(3 + a, 3 + a)])
}

/// Stage 2, paper form: three axis filters over all members.
#[derive(Debug, Clone)]
pub struct PaperFusion {
    params: FusionParams,
    axes: Vec<GroupAxisFilter>,
    /// Under [`OwnErrorModel::Stage1Reported`]: what turns each epoch's
    /// solutions into the own-error states' transition.
    stage1: Option<Stage1Errors>,
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
                let f = GroupAxisFilter::new(
                    m,
                    params.interval_s,
                    params.accel_sigma_m_s2,
                    params.own_velocity || params.sensor.relative_velocity,
                    &p,
                    &v,
                    params.initial_position_sigma_m,
                    params.initial_velocity_sigma_mps,
                )?
                .with_motion(params.motion);
                Ok(match params.own_errors {
                    OwnErrorModel::White => f,
                    OwnErrorModel::GaussMarkov(c) => f.with_own_errors(AxisOwnErrors {
                        position: c.position[a],
                        velocity: params.own_velocity.then_some(c.velocity[a]),
                    }),
                    OwnErrorModel::Stage1Reported => f.with_reported_own_errors(
                        &first
                            .iter()
                            .map(|o| axis_block(&o.covariance, a))
                            .collect::<Vec<_>>(),
                    ),
                })
            })
            .collect::<Result<_, _>>()?;
        let stage1 =
            (params.own_errors == OwnErrorModel::Stage1Reported).then(|| Stage1Errors::new(first));
        Ok(Self {
            params,
            axes,
            stage1,
        })
    }

    /// Under [`OwnErrorModel::Stage1Reported`] and when predicting: each
    /// member's own-error transition from its solution `own[l]` (if it
    /// arrived).
    fn transitions(
        &mut self,
        own: &[Option<&OwnSolution>],
        predict: bool,
    ) -> Option<Vec<(Matrix6, Matrix6)>> {
        if !predict {
            return None;
        }
        self.stage1.as_mut().map(|s| s.step(own))
    }

    /// One epoch: predict (unless it is the first), then fuse every
    /// member's own solution and every relative measurement.
    pub fn epoch(
        &mut self,
        own: &[OwnSolution],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        self.epoch_with_new_own(own, &[], relative, predict)
    }

    /// [`Self::epoch`] fusing member l's own solution only where `own_new[l]`
    /// (its stage 1 had a GNSS fix since the last epoch; otherwise its
    /// solution is a prediction from information already fused). Its
    /// attitude still serves its relative measurements. Members beyond
    /// `own_new`'s length count as new (`&[]`: every member, as
    /// [`Self::epoch`]).
    pub fn epoch_with_new_own(
        &mut self,
        own: &[OwnSolution],
        own_new: &[bool],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        let transitions = self.transitions(&own.iter().map(Some).collect::<Vec<_>>(), predict);
        self.fuse(
            transitions,
            own.iter()
                .enumerate()
                .filter(|(l, _)| own_new.get(*l).copied().unwrap_or(true)),
            relative.iter().map(|r| (&own[r.from], r)),
            predict,
        )
    }

    /// One epoch from the packets that arrived for it
    /// ([`DelayedFusion`](super::DelayedFusion)): predict (if `predict`),
    /// then the own solutions of the members that sent a packet with a new
    /// own fix ([`MemberPacket::own_new`]) and their relative measurements,
    /// then their rates, in the order of `packets`. With every member's
    /// packet, in member order, it is [`epoch_with_new_own`](Self::epoch_with_new_own)
    /// followed by [`fuse_rates`](Self::fuse_rates).
    pub fn epoch_from_packets(
        &mut self,
        packets: &[MemberPacket],
        predict: bool,
    ) -> Result<(), EstimationError> {
        check_packets(packets, self.axes[0].members())?;
        let mut own = vec![None; self.axes[0].members()];
        for p in packets {
            own[p.member] = Some(&p.own);
        }
        let transitions = self.transitions(&own, predict);
        self.fuse(
            transitions,
            packets
                .iter()
                .filter(|p| p.own_new)
                .map(|p| (p.member, &p.own)),
            packets
                .iter()
                .flat_map(|p| p.relative.iter().map(move |r| (&p.own, r))),
            predict,
        )?;
        self.fuse_rate_list(
            packets
                .iter()
                .flat_map(|p| p.rates.iter().map(move |r| (&p.own, r))),
        )
    }

    /// Per axis: predict, own solutions `(member, solution)` (their white
    /// noise under the Gauss–Markov model), relative measurements
    /// `(observer's solution, measurement)`, one update.
    fn fuse<'a>(
        &mut self,
        transitions: Option<Vec<(Matrix6, Matrix6)>>,
        own: impl Iterator<Item = (usize, &'a OwnSolution)>,
        relative: impl Iterator<Item = (&'a OwnSolution, &'a RelativeMeasurement)> + Clone,
        predict: bool,
    ) -> Result<(), EstimationError> {
        let params = &self.params;
        let own: Vec<(usize, &OwnSolution, Matrix6)> = own
            .map(|(l, o)| {
                let noise = match params.own_errors {
                    OwnErrorModel::White => o.covariance,
                    OwnErrorModel::GaussMarkov(c) => c.white_covariance(&o.covariance),
                    OwnErrorModel::Stage1Reported => o.covariance * STAGE1_WHITE_FRACTION.powi(2),
                };
                (l, o, noise)
            })
            .collect();
        for (a, f) in self.axes.iter_mut().enumerate() {
            if predict {
                f.predict();
                if let Some(t) = &transitions {
                    let per_axis: Vec<(Matrix2<f64>, Matrix2<f64>)> = t
                        .iter()
                        .map(|(phi, q)| (axis_block(phi, a), axis_block(q, a)))
                        .collect();
                    f.transition_own_errors(&per_axis)?;
                }
            }
            for &(l, o, r) in &own {
                f.observe_own_position(l, o.state.position[a], r[(a, a)].sqrt())?;
                if params.own_velocity {
                    f.observe_own_velocity(l, o.state.velocity[a], r[(3 + a, 3 + a)].sqrt())?;
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

    /// Fuse body-frame relative velocities (after [`Self::epoch`], at the
    /// same epoch), each converted to the nav frame with the observer's INS*
    /// attitude, its per-axis variance the diagonal of the rotated sensor
    /// covariance plus the attitude term. Range rates are skipped: the
    /// projection of the relative velocity on the line of sight cannot be
    /// split into independent per-axis observations.
    pub fn fuse_rates(
        &mut self,
        own: &[OwnSolution],
        rates: &[RelativeRate],
    ) -> Result<(), EstimationError> {
        self.fuse_rate_list(rates.iter().map(|r| (&own[r.from], r)))
    }

    /// [`Self::fuse_rates`] over `(observer's solution, rate)` pairs.
    fn fuse_rate_list<'a>(
        &mut self,
        rates: impl Iterator<Item = (&'a OwnSolution, &'a RelativeRate)>,
    ) -> Result<(), EstimationError> {
        let sigma2 = self.params.sensor.relative_velocity_sigma_mps.powi(2);
        let converted: Vec<(usize, usize, Vector3<f64>, Vector3<f64>)> = rates
            .filter_map(|(observer, r)| {
                let z = r.body_velocity_mps?;
                let c = observer.state.attitude.to_rotation_matrix().into_inner();
                let dv = c * z;
                let cov = c * (sigma2 * c.transpose())
                    + attitude_covariance_on(&dv, &observer.attitude_covariance);
                Some((r.from, r.to, dv, cov.diagonal()))
            })
            .collect();
        if converted.is_empty() {
            return Ok(());
        }
        for (a, f) in self.axes.iter_mut().enumerate() {
            for &(from, to, dv, var) in &converted {
                // As for positions, z^{lk} = V^l − V^k with l the observer.
                f.observe_relative_velocity(from, to, -dv[a], var[a].sqrt())?;
            }
            f.update()?;
        }
        Ok(())
    }

    /// Covariance of member `l`'s position and velocity (6×6, position
    /// first): the axis filters' variances, no cross-axis terms (the
    /// paper's decoupling).
    pub fn position_velocity_covariance(&self, l: usize) -> Matrix6 {
        let mut p = Matrix6::zeros();
        for (a, f) in self.axes.iter().enumerate() {
            let c = f.covariance();
            let (r, v) = (l, f.members() + l);
            p[(a, a)] = c[(r, r)];
            p[(3 + a, 3 + a)] = c[(v, v)];
            p[(a, 3 + a)] = c[(r, v)];
            p[(3 + a, a)] = c[(v, r)];
        }
        p
    }

    /// The filter's 3-D velocity σ of member `l` (√ trace) [m/s].
    pub fn velocity_sigma(&self, l: usize) -> f64 {
        self.axes
            .iter()
            .map(|f| f.velocity_sigma(l).powi(2))
            .sum::<f64>()
            .sqrt()
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
