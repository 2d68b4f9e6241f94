//! Stage 2 as one extended Kalman filter over all members' 3-D positions
//! and velocities, state `[R¹ V¹ … R^M V^M]`. It uses range, bearing and
//! elevation directly (their noise uncorrelated in polar form, so the
//! cross-axis correlation of the Cartesian errors is carried exactly by the
//! Jacobian), and the full stage-1 covariance block of each member's own
//! solution.

use aidnav_estimation::{DynKalmanFilter, EstimationError};
use aidnav_models::relative_sensor::{Polar, wrap_angle};
use nalgebra::{DMatrix, DVector, Vector3};

use super::delayed::check_packets;
use super::{
    EpochFusion, FusionParams, MemberPacket, OwnSolution, RelativeMeasurement,
    attitude_covariance_on,
};

/// Stage 2, EKF form: state [R¹ V¹ … R^M V^M], 3-D each.
#[derive(Debug, Clone)]
pub struct EkfFusion {
    params: FusionParams,
    kf: DynKalmanFilter,
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
}

impl EkfFusion {
    /// A filter for the members of `first` (their stage-1 solutions at the
    /// first epoch give the initial state).
    pub fn new(params: FusionParams, first: &[OwnSolution]) -> Result<Self, EstimationError> {
        let n = 6 * first.len();
        let mut x = DVector::zeros(n);
        let mut p0 = DVector::zeros(n);
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::zeros(n, n);
        let qv = (params.accel_sigma_m_s2 * params.interval_s).powi(2);
        for (l, o) in first.iter().enumerate() {
            for a in 0..3 {
                x[6 * l + a] = o.state.position[a];
                x[6 * l + 3 + a] = o.state.velocity[a];
                p0[6 * l + a] = params.initial_position_sigma_m.powi(2);
                p0[6 * l + 3 + a] = params.initial_velocity_sigma_mps.powi(2);
                phi[(6 * l + a, 6 * l + 3 + a)] = params.interval_s;
                q[(6 * l + 3 + a, 6 * l + 3 + a)] = qv;
            }
        }
        Ok(Self {
            params,
            kf: DynKalmanFilter::new(x, DMatrix::from_diagonal(&p0))?,
            phi,
            q,
        })
    }

    /// One epoch: predict (unless it is the first), then fuse every
    /// member's own solution and every relative measurement, one by one.
    pub fn epoch(
        &mut self,
        own: &[OwnSolution],
        relative: &[RelativeMeasurement],
        predict: bool,
    ) -> Result<(), EstimationError> {
        if predict {
            self.kf.predict(&self.phi, &self.q)?;
        }
        for (l, o) in own.iter().enumerate() {
            self.fuse_own(l, o)?;
        }
        for meas in relative {
            self.fuse_relative(&own[meas.from], meas)?;
        }
        Ok(())
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
        check_packets(packets, self.kf.dim() / 6)?;
        if predict {
            self.kf.predict(&self.phi, &self.q)?;
        }
        for p in packets {
            self.fuse_own(p.member, &p.own)?;
        }
        for p in packets {
            for meas in &p.relative {
                self.fuse_relative(&p.own, meas)?;
            }
        }
        Ok(())
    }

    /// Own solution of member `l`: position (and velocity) with its stage-1
    /// covariance block.
    fn fuse_own(&mut self, l: usize, o: &OwnSolution) -> Result<(), EstimationError> {
        let n = self.kf.dim();
        let k = if self.params.own_velocity { 6 } else { 3 };
        let mut h = DMatrix::zeros(k, n);
        for i in 0..k {
            h[(i, 6 * l + i)] = 1.0;
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
        let r = DMatrix::from_fn(k, k, |i, j| o.covariance[(i, j)]);
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
