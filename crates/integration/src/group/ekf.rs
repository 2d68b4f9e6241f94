//! Stage 2 as one extended Kalman filter over all members' 3-D positions
//! and velocities, state `[R¹ V¹ … R^M V^M]`. It uses range, bearing and
//! elevation directly (their noise uncorrelated in polar form, so the
//! cross-axis correlation of the Cartesian errors is carried exactly by the
//! Jacobian), and the full stage-1 covariance block of each member's own
//! solution.
//!
//! With [`OwnErrorModel::GaussMarkov`] the state carries after the members'
//! `[R V]` the correlated parts of their stage-1 errors, `[b_R¹ … b_R^M]`
//! and, when own velocities are fused, `[b_V¹ … b_V^M]` (3-D each); an own
//! fix observes `R + b_R` (`V + b_V`) with only the white rest of the
//! stage-1 covariance as its noise.

use aidnav_estimation::{DynKalmanFilter, EstimationError};
use aidnav_models::local_ins::Matrix6;
use aidnav_models::relative_sensor::{
    Polar, body_relative_velocity, body_relative_velocity_jacobian, range_rate,
    range_rate_jacobian, wrap_angle,
};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use super::delayed::check_packets;
use super::{
    EpochFusion, FusionParams, MemberPacket, OwnErrorModel, OwnSolution, RelativeMeasurement,
    RelativeRate, STAGE1_WHITE_FRACTION, Stage1Errors, attitude_covariance_on,
};

/// Stage 2, EKF form: state [R¹ V¹ … R^M V^M], 3-D each.
#[derive(Debug, Clone)]
pub struct EkfFusion {
    params: FusionParams,
    kf: DynKalmanFilter,
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
    members: usize,
    /// Own-error state blocks carried (0, 1 position, 2 position and velocity).
    own_error_blocks: usize,
    /// Under [`OwnErrorModel::Stage1Reported`]: what turns each epoch's
    /// solutions into the own-error states' transition.
    stage1: Option<Stage1Errors>,
}

impl EkfFusion {
    /// A filter for the members of `first` (their stage-1 solutions at the
    /// first epoch give the initial state).
    pub fn new(params: FusionParams, first: &[OwnSolution]) -> Result<Self, EstimationError> {
        let m = first.len();
        let own_error_blocks = match params.own_errors {
            OwnErrorModel::White => 0,
            OwnErrorModel::GaussMarkov(_) if params.own_velocity => 2,
            OwnErrorModel::GaussMarkov(_) => 1,
            OwnErrorModel::Stage1Reported => 2,
        };
        let n = 6 * m + 3 * m * own_error_blocks;
        let mut x = DVector::zeros(n);
        let mut p0 = DVector::zeros(n);
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::zeros(n, n);
        let (qr, qrv, qv) = params
            .motion
            .process_noise(params.accel_sigma_m_s2, params.interval_s);
        for (l, o) in first.iter().enumerate() {
            for a in 0..3 {
                let (r, v) = (6 * l + a, 6 * l + 3 + a);
                x[r] = o.state.position[a];
                x[v] = o.state.velocity[a];
                p0[r] = params.initial_position_sigma_m.powi(2);
                p0[v] = params.initial_velocity_sigma_mps.powi(2);
                phi[(r, v)] = params.interval_s;
                q[(r, r)] = qr;
                q[(r, v)] = qrv;
                q[(v, r)] = qrv;
                q[(v, v)] = qv;
            }
        }
        if let OwnErrorModel::GaussMarkov(c) = params.own_errors {
            for block in 0..own_error_blocks {
                let models = if block == 0 { c.position } else { c.velocity };
                for l in 0..m {
                    for (a, gm) in models.iter().enumerate() {
                        let i = 6 * m + 3 * (block * m + l) + a;
                        let (f, qb) = gm.discretise(params.interval_s);
                        p0[i] = gm.sigma().powi(2);
                        phi[(i, i)] = f;
                        q[(i, i)] = qb;
                    }
                }
            }
        }
        let mut p0 = DMatrix::from_diagonal(&p0);
        let stage1 = (params.own_errors == OwnErrorModel::Stage1Reported).then(|| {
            // The own-error states start at stage 1's covariance (position
            // and velocity blocks and their cross terms); Φ = I, Q = 0 here,
            // each epoch's transition comes from the solutions.
            for (l, o) in first.iter().enumerate() {
                let idx = |i: usize| 6 * m + 3 * ((i / 3) * m + l) + i % 3;
                for i in 0..6 {
                    for j in 0..6 {
                        p0[(idx(i), idx(j))] = o.covariance[(i, j)];
                    }
                }
            }
            Stage1Errors::new(first)
        });
        Ok(Self {
            params,
            kf: DynKalmanFilter::new(x, p0)?,
            phi,
            q,
            members: m,
            own_error_blocks,
            stage1,
        })
    }

    /// Time update; under [`OwnErrorModel::Stage1Reported`] with each
    /// member's own-error transition from its solution `own[l]` (if it
    /// arrived).
    fn predict(&mut self, own: &[Option<&OwnSolution>]) -> Result<(), EstimationError> {
        let m = self.members;
        let Some(stage1) = self.stage1.as_mut() else {
            return self.kf.predict(&self.phi, &self.q);
        };
        let mut phi = self.phi.clone();
        let mut q = self.q.clone();
        for (l, (a, qb)) in stage1.step(own).into_iter().enumerate() {
            let idx = |i: usize| 6 * m + 3 * ((i / 3) * m + l) + i % 3;
            for i in 0..6 {
                for j in 0..6 {
                    phi[(idx(i), idx(j))] = a[(i, j)];
                    q[(idx(i), idx(j))] = qb[(i, j)];
                }
            }
        }
        self.kf.predict(&phi, &q)
    }

    /// Index of the first (east) own-error state of `block` (0 position, 1
    /// velocity) of member l, if carried.
    fn own_error_index(&self, block: usize, l: usize) -> Option<usize> {
        (block < self.own_error_blocks).then(|| 6 * self.members + 3 * (block * self.members + l))
    }

    /// One epoch: predict (unless it is the first), then fuse every
    /// member's own solution and every relative measurement, one by one.
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
        if predict {
            self.predict(&own.iter().map(Some).collect::<Vec<_>>())?;
        }
        for (l, o) in own.iter().enumerate() {
            if own_new.get(l).copied().unwrap_or(true) {
                self.fuse_own(l, o)?;
            }
        }
        for meas in relative {
            self.fuse_relative(&own[meas.from], meas)?;
        }
        Ok(())
    }

    /// One epoch from the packets that arrived for it
    /// ([`DelayedFusion`](super::DelayedFusion)): predict (if `predict`),
    /// then the own solutions of the members that sent a packet with a new
    /// own fix ([`MemberPacket::own_new`]), their relative measurements and
    /// then their rates, in the order of `packets`. With every member's
    /// packet, in member order, it is [`epoch_with_new_own`](Self::epoch_with_new_own)
    /// followed by [`fuse_rates`](Self::fuse_rates).
    pub fn epoch_from_packets(
        &mut self,
        packets: &[MemberPacket],
        predict: bool,
    ) -> Result<(), EstimationError> {
        // The number of members, not `kf.dim() / 6`: the Gauss–Markov
        // own-error states follow the members' [R V] blocks.
        check_packets(packets, self.members)?;
        if predict {
            let mut own = vec![None; self.members];
            for p in packets {
                own[p.member] = Some(&p.own);
            }
            self.predict(&own)?;
        }
        for p in packets {
            if p.own_new {
                self.fuse_own(p.member, &p.own)?;
            }
        }
        for p in packets {
            for meas in &p.relative {
                self.fuse_relative(&p.own, meas)?;
            }
        }
        for p in packets {
            for meas in &p.rates {
                self.fuse_rate(&p.own, meas)?;
            }
        }
        Ok(())
    }

    /// Own solution of member `l`: position (and velocity) with its stage-1
    /// covariance block (its white part under the Gauss–Markov model, which
    /// also observes the member's own-error states).
    fn fuse_own(&mut self, l: usize, o: &OwnSolution) -> Result<(), EstimationError> {
        let n = self.kf.dim();
        let k = if self.params.own_velocity { 6 } else { 3 };
        let mut h = DMatrix::zeros(k, n);
        for i in 0..k {
            h[(i, 6 * l + i)] = 1.0;
            if let Some(b) = self.own_error_index(i / 3, l) {
                h[(i, b + i % 3)] = 1.0;
            }
        }
        let z = DVector::from_iterator(
            k,
            o.state
                .position
                .iter()
                .chain(o.state.velocity.iter())
                .take(k)
                .copied(),
        );
        let noise: Matrix6 = match self.params.own_errors {
            OwnErrorModel::White => o.covariance,
            OwnErrorModel::GaussMarkov(c) => c.white_covariance(&o.covariance),
            OwnErrorModel::Stage1Reported => o.covariance * STAGE1_WHITE_FRACTION.powi(2),
        };
        let r = DMatrix::from_fn(k, k, |i, j| noise[(i, j)]);
        self.kf.update(&z, &h, &r)?;
        Ok(())
    }

    /// Range, bearing and elevation of `meas.to` seen by `observer`,
    /// linearised about the current estimate.
    fn fuse_relative(
        &mut self,
        observer: &OwnSolution,
        meas: &RelativeMeasurement,
    ) -> Result<(), EstimationError> {
        let n = self.kf.dim();
        let c = observer.state.attitude.to_rotation_matrix().into_inner();
        let x = self.kf.state();
        let d = Vector3::new(
            x[6 * meas.to] - x[6 * meas.from],
            x[6 * meas.to + 1] - x[6 * meas.from + 1],
            x[6 * meas.to + 2] - x[6 * meas.from + 2],
        );
        let body = c.transpose() * d;
        let predicted = Polar::from_cartesian(&body);
        let jp = Polar::polar_jacobian(&body);
        let jd = jp * c.transpose(); // ∂h/∂d
        let mut h = DMatrix::zeros(3, n);
        for i in 0..3 {
            for j in 0..3 {
                h[(i, 6 * meas.to + j)] = jd[(i, j)];
                h[(i, 6 * meas.from + j)] = -jd[(i, j)];
            }
        }
        let r3 = self.params.sensor.polar_covariance()
            + jd * attitude_covariance_on(&d, &observer.attitude_covariance) * jd.transpose();
        let nu = Vector3::new(
            meas.polar.range_m - predicted.range_m,
            wrap_angle(meas.polar.bearing_rad - predicted.bearing_rad),
            meas.polar.elevation_rad - predicted.elevation_rad,
        );
        // Linearised about x̂: z_eff − H x̂ = ν.
        let hx = &h * x;
        let z = DVector::from_fn(3, |i, _| nu[i] + hx[i]);
        let r = DMatrix::from_fn(3, 3, |i, j| r3[(i, j)]);
        self.kf.update(&z, &h, &r)?;
        Ok(())
    }

    /// Fuse range rates and body-frame relative velocities (after
    /// [`Self::epoch`], at the same epoch), linearised about the current
    /// estimate. `own` gives each observer's attitude and its uncertainty.
    pub fn fuse_rates(
        &mut self,
        own: &[OwnSolution],
        rates: &[RelativeRate],
    ) -> Result<(), EstimationError> {
        for meas in rates {
            self.fuse_rate(&own[meas.from], meas)?;
        }
        Ok(())
    }

    /// One range rate and/or body-frame relative velocity of `meas.to` seen
    /// by `observer`, linearised about the current estimate.
    fn fuse_rate(
        &mut self,
        observer: &OwnSolution,
        meas: &RelativeRate,
    ) -> Result<(), EstimationError> {
        let n = self.kf.dim();
        let x = self.kf.state();
        let block = |l: usize, off: usize| Vector3::from_fn(|a, _| x[6 * l + off + a]);
        let d = block(meas.to, 0) - block(meas.from, 0);
        let d_dot = block(meas.to, 3) - block(meas.from, 3);
        if let Some(z) = meas.range_rate_mps {
            let (jd, jv) = range_rate_jacobian(&d, &d_dot);
            let mut h = DMatrix::zeros(1, n);
            for a in 0..3 {
                h[(0, 6 * meas.to + a)] = jd[a];
                h[(0, 6 * meas.from + a)] = -jd[a];
                h[(0, 6 * meas.to + 3 + a)] = jv[a];
                h[(0, 6 * meas.from + 3 + a)] = -jv[a];
            }
            let nu = z - range_rate(&d, &d_dot);
            let hx = (&h * x)[0];
            let r = DMatrix::from_element(1, 1, self.params.sensor.range_rate_sigma_mps.powi(2));
            self.kf.update(&DVector::from_element(1, nu + hx), &h, &r)?;
        }
        if let Some(z) = meas.body_velocity_mps {
            let x = self.kf.state();
            let d_dot = Vector3::from_fn(|a, _| x[6 * meas.to + 3 + a] - x[6 * meas.from + 3 + a]);
            let attitude = observer.state.attitude;
            let (jv, _) = body_relative_velocity_jacobian(&attitude, &d_dot);
            let mut h = DMatrix::zeros(3, n);
            for i in 0..3 {
                for j in 0..3 {
                    h[(i, 6 * meas.to + 3 + j)] = jv[(i, j)];
                    h[(i, 6 * meas.from + 3 + j)] = -jv[(i, j)];
                }
            }
            // The observer's attitude error turns the measured vector:
            // Cᵀ (ḋ × ψ), the same form as for a line of sight.
            let r3 = Matrix3::from_diagonal_element(
                self.params.sensor.relative_velocity_sigma_mps.powi(2),
            ) + jv
                * attitude_covariance_on(&d_dot, &observer.attitude_covariance)
                * jv.transpose();
            // Linear in the velocities (z = H x + n); written as the
            // innovation about x̂ like the other relative measurements.
            let nu = z - body_relative_velocity(&attitude, &d_dot);
            let hx = &h * x;
            let zv = DVector::from_fn(3, |i, _| nu[i] + hx[i]);
            let r = DMatrix::from_fn(3, 3, |i, j| r3[(i, j)]);
            self.kf.update(&zv, &h, &r)?;
        }
        Ok(())
    }

    /// Covariance of member `l`'s position and velocity (6×6, position
    /// first).
    pub fn position_velocity_covariance(&self, l: usize) -> Matrix6 {
        let p = self.kf.covariance();
        Matrix6::from_fn(|i, j| p[(6 * l + i, 6 * l + j)])
    }

    /// The filter's 3-D velocity σ of member `l` (√ trace) [m/s].
    pub fn velocity_sigma(&self, l: usize) -> f64 {
        let p = self.kf.covariance();
        (3..6)
            .map(|a| p[(6 * l + a, 6 * l + a)])
            .sum::<f64>()
            .sqrt()
    }

    /// Estimated position of member `l` \[m\].
    pub fn position(&self, l: usize) -> Vector3<f64> {
        let x = self.kf.state();
        Vector3::new(x[6 * l], x[6 * l + 1], x[6 * l + 2])
    }

    /// Estimated velocity of member `l` \[m/s\].
    pub fn velocity(&self, l: usize) -> Vector3<f64> {
        let x = self.kf.state();
        Vector3::new(x[6 * l + 3], x[6 * l + 4], x[6 * l + 5])
    }

    /// The filter's 3-D position σ of member `l` (√ trace) \[m\].
    pub fn position_sigma(&self, l: usize) -> f64 {
        let p = self.kf.covariance();
        (0..3)
            .map(|a| p[(6 * l + a, 6 * l + a)])
            .sum::<f64>()
            .sqrt()
    }
}

impl EpochFusion for EkfFusion {
    type Packet = MemberPacket;

    fn fuse_epoch(
        &mut self,
        packets: &[MemberPacket],
        predict: bool,
    ) -> Result<(), EstimationError> {
        self.epoch_from_packets(packets, predict)
    }
}
