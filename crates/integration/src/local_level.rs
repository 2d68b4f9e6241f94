//! Stage 1 of spec 30: a local-level INS with a 21-state loosely coupled
//! error-state filter on GNSS position and velocity fixes
//! ([`aidnav_models::local_ins`]), closed loop: after every fix the estimated
//! position, velocity and attitude errors are removed from the INS and the
//! bias estimates move into the IMU correction; the GNSS receiver's own
//! correlated errors stay in the filter state. The output ("INS*", paper) is
//! the corrected INS and the covariance of its remaining error.
//!
//! The filter's time update runs every `filter_dt_s` (and before each fix)
//! with the specific force averaged over the interval; the INS runs at the
//! IMU rate.

use aidnav_estimation::{EstimationError, FixedKalmanFilter};
use aidnav_models::local_ins::{
    ACCEL_BIAS, ATTITUDE, GYRO_BIAS, LocalInsModel, Matrix6, POSITION, STATES, VELOCITY, Vector21,
};
use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3};

use aidnav_ins::local_level::LocalLevelState;

/// INS + 21-state loosely coupled filter, closed loop.
#[derive(Debug, Clone)]
pub struct LooselyCoupled {
    model: LocalInsModel,
    ins: LocalLevelState,
    accel_bias: Vector3<f64>,
    gyro_bias: Vector3<f64>,
    kf: FixedKalmanFilter<STATES>,
    filter_dt_s: f64,
    pending_s: f64,
    force_sum: Vector3<f64>,
}

impl LooselyCoupled {
    /// Start from an INS state and the prior σ of every error state.
    pub fn new(
        model: LocalInsModel,
        ins: LocalLevelState,
        prior_sigmas: &Vector21,
        filter_dt_s: f64,
    ) -> Result<Self, EstimationError> {
        let p0 = SMatrix::<f64, STATES, STATES>::from_diagonal(&prior_sigmas.map(|s| s * s));
        Ok(Self {
            model,
            ins,
            accel_bias: Vector3::zeros(),
            gyro_bias: Vector3::zeros(),
            kf: FixedKalmanFilter::new(SVector::zeros(), p0)?,
            filter_dt_s,
            pending_s: 0.0,
            force_sum: Vector3::zeros(),
        })
    }

    /// The corrected INS ("INS*").
    pub fn solution(&self) -> &LocalLevelState {
        &self.ins
    }

    /// Estimated accelerometer and gyro biases (body frame).
    pub fn bias_estimates(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.accel_bias, self.gyro_bias)
    }

    /// Covariance of the INS* position and velocity errors (6×6, nav frame).
    pub fn position_velocity_covariance(&self) -> Matrix6 {
        self.kf
            .covariance()
            .fixed_view::<6, 6>(POSITION, POSITION)
            .into_owned()
    }

    /// Covariance of the INS* attitude error ψ.
    pub fn attitude_covariance(&self) -> Matrix3<f64> {
        self.kf
            .covariance()
            .fixed_view::<3, 3>(ATTITUDE, ATTITUDE)
            .into_owned()
    }

    /// One IMU sample (raw gyro rate and specific force, body frame) over `dt_s`.
    pub fn step_imu(
        &mut self,
        gyro: &Vector3<f64>,
        accel: &Vector3<f64>,
        dt_s: f64,
    ) -> Result<(), EstimationError> {
        let rate = gyro - self.gyro_bias;
        let force = accel - self.accel_bias;
        self.force_sum += self.ins.specific_force_nav(&force) * dt_s;
        self.ins.step(&rate, &force, dt_s);
        self.pending_s += dt_s;
        if self.pending_s >= self.filter_dt_s * (1.0 - 1e-9) {
            self.time_update()?;
        }
        Ok(())
    }

    fn time_update(&mut self) -> Result<(), EstimationError> {
        if self.pending_s <= 0.0 {
            return Ok(());
        }
        let f_nav = self.force_sum / self.pending_s;
        let c_bn = self.ins.attitude.to_rotation_matrix().into_inner();
        let (phi, q) = self.model.discrete(&f_nav, &c_bn, self.pending_s);
        self.kf.predict(&phi, &q)?;
        self.pending_s = 0.0;
        self.force_sum = Vector3::zeros();
        Ok(())
    }

    /// Propagate the filter to now without a fix (e.g. during a GNSS outage,
    /// so the covariance reported at this epoch is current).
    pub fn propagate(&mut self) -> Result<(), EstimationError> {
        self.time_update()
    }

    /// A GNSS position + velocity fix at the current time; corrects the INS.
    pub fn gnss_update(
        &mut self,
        position: &Vector3<f64>,
        velocity: &Vector3<f64>,
    ) -> Result<(), EstimationError> {
        let (_, r) = self.model.measurement();
        self.gnss_update_with_noise(position, velocity, &r)
    }

    /// A GNSS fix whose white-noise covariance `r` (position, velocity; 6×6)
    /// is given instead of the model's — e.g. a receiver reporting degraded
    /// accuracy. The correlated GNSS errors keep their model.
    pub fn gnss_update_with_noise(
        &mut self,
        position: &Vector3<f64>,
        velocity: &Vector3<f64>,
        r: &Matrix6,
    ) -> Result<(), EstimationError> {
        self.time_update()?;
        let (h, _) = self.model.measurement();
        let dp = position - self.ins.position;
        let dv = velocity - self.ins.velocity;
        let z = SVector::<f64, 6>::from([dp.x, dp.y, dp.z, dv.x, dv.y, dv.z]);
        self.kf.update(&z, &h, r)?;
        self.feedback()
    }

    /// Move the INS error estimates into the INS and the IMU correction.
    fn feedback(&mut self) -> Result<(), EstimationError> {
        let mut x = *self.kf.state();
        let v3 = |o: usize| Vector3::new(x[o], x[o + 1], x[o + 2]);
        self.ins.position -= v3(POSITION);
        self.ins.velocity -= v3(VELOCITY);
        // True attitude C = (I + [ψ×]) Ĉ: rotate the estimate by ψ in the nav frame.
        self.ins.attitude = UnitQuaternion::from_scaled_axis(v3(ATTITUDE)) * self.ins.attitude;
        self.accel_bias += v3(ACCEL_BIAS);
        self.gyro_bias += v3(GYRO_BIAS);
        x.rows_mut(POSITION, GYRO_BIAS + 3).fill(0.0);
        self.kf.set_state(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_ins::local_level::GRAVITY_ENU;

    /// Static INS with a vertical accelerometer bias (observable: no tilt
    /// can mimic it) and error-free fixes: the filter finds the bias and
    /// holds the position.
    #[test]
    fn static_ins_estimates_a_vertical_accelerometer_bias() {
        let model = LocalInsModel::default();
        let truth = LocalLevelState {
            position: Vector3::new(0.0, 0.0, 100.0),
            velocity: Vector3::zeros(),
            attitude: UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
        };
        let sig = model.prior_sigmas(1.0, 0.1, Vector3::new(1e-3, 1e-3, 1e-2));
        let mut lc = LooselyCoupled::new(model, truth, &sig, 0.1).unwrap();
        let bias = Vector3::new(0.0, 0.0, 3e-3);
        let f_body = truth.attitude.inverse() * -GRAVITY_ENU + bias;
        for k in 0..60_000 {
            lc.step_imu(&Vector3::zeros(), &f_body, 0.01).unwrap();
            if k % 100 == 99 {
                lc.gnss_update(&truth.position, &truth.velocity).unwrap();
            }
        }
        let (ba, _) = lc.bias_estimates();
        assert!((ba.z - 3e-3).abs() < 3e-4, "bias estimate {}", ba.z);
        assert!((lc.solution().position - truth.position).norm() < 0.5);
        let cov = lc.position_velocity_covariance();
        assert!(cov[(2, 2)].sqrt() < 5.0 && cov[(5, 5)].sqrt() < 0.1);
    }
}
