//! Spec 30's stage 1 in an Earth frame (the paper's eq. 3): the WGS-84 NED
//! strapdown INS ([`aidnav_ins::ned`]) with a 21-state loosely coupled
//! error-state filter on GNSS position and velocity fixes, closed loop.
//!
//! The INS error part is the NED error model of spec 40
//! ([`aidnav_models::ned_ins`]: δr, δv, φ, gyro and accelerometer biases,
//! with Earth rate, transport rate, Coriolis and the gravity gradient; its
//! scale-factor states are left out, the formation's IMU has none); the
//! GNSS receiver's correlated position and velocity errors ε_R, ε_V (paper
//! eq. 4) are appended as in the flat model ([`aidnav_models::local_ins`]),
//! so the fix's H and R are that model's:
//!
//! ```text
//! x = (δr, δv, φ, b_g, b_a, ε_R, ε_V)          (NED; biases in the body frame)
//! z = (r_GNSS − r_INS, v_GNSS − v_INS) = (ε_R − δr + v_R, ε_V − δv + v_V)
//! ```
//!
//! The bias decay and driving noise come from the formation's IMU grade
//! ([`ImuGrade`]: its own correlation time per sensor), the velocity and
//! attitude white noise from its random walks.

use aidnav_estimation::{EstimationError, FixedKalmanFilter};
use aidnav_frames::earth::{Geodetic, earth_rate_ned, transport_rate_ned};
use aidnav_frames::{Ned, Rotation, Vec3};
use aidnav_ins::ned::{ImuIncrement, NedMechanization, NedState};
use aidnav_models::local_ins::{GNSS_POSITION, GNSS_VELOCITY, ImuGrade, LocalInsModel, Matrix6};
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ATTITUDE, GYRO_BIAS, ImuNoise, NedErrorModel, POSITION, PerAxis, VELOCITY,
};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use crate::local_level::ErrorCrossCovariance;
use crate::sparse;

/// Number of states.
pub const STATES: usize = 21;
/// The NED model's states kept (δr, δv, φ, b_g, b_a).
const INS_STATES: usize = 15;

/// 21×21 matrix.
pub type Matrix21 = SMatrix<f64, STATES, STATES>;
/// 21-vector.
pub type Vector21 = SVector<f64, STATES>;

/// The NED error model with the noise of an IMU grade given in SI units.
pub fn ned_model_of(imu: &ImuGrade) -> NedErrorModel {
    let deg = 1f64.to_radians();
    NedErrorModel {
        noise: ImuNoise {
            arw_deg_per_sqrt_h: PerAxis::all(imu.angle_random_walk / deg * 60.0),
            vrw_mps_per_sqrt_h: PerAxis::all(imu.velocity_random_walk * 60.0),
            gyro_bias_deg_per_h: PerAxis::all(imu.gyro_bias_sigma_rad_s / deg * 3600.0),
            accel_bias_mg: PerAxis::all(imu.accel_bias_sigma_m_s2 / (1e-3 * 9.806_65)),
            gyro_scale_ppm: PerAxis::all(0.0),
            accel_scale_ppm: PerAxis::all(0.0),
            bias_correlation_s: imu.accel_bias_correlation_s,
            scale_correlation_s: imu.accel_bias_correlation_s,
            scale_factors: false,
        },
    }
}

/// F and the white-noise density Q_c of the 21 states at attitude C_b^n,
/// body specific force and position/velocity (for the Earth and transport
/// rates).
pub fn continuous(
    model: &LocalInsModel,
    c_bn: &Matrix3<f64>,
    f_body: &Vector3<f64>,
    position: &Geodetic,
    velocity: &Vec3<Ned>,
) -> (Matrix21, Matrix21) {
    let ned = ned_model_of(&model.imu);
    let w_ie = earth_rate_ned(position.latitude_rad).raw();
    let w_en = transport_rate_ned(position, velocity).raw();
    let f_ned = ned.continuous(
        c_bn,
        f_body,
        &Vector3::zeros(),
        &w_ie,
        &w_en,
        position.latitude_rad,
    );
    let qc_ned = ned.spectral_density(c_bn);
    let mut f = Matrix21::zeros();
    let mut qc = Matrix21::zeros();
    f.fixed_view_mut::<INS_STATES, INS_STATES>(0, 0)
        .copy_from(&f_ned.fixed_view::<INS_STATES, INS_STATES>(0, 0));
    qc.fixed_view_mut::<INS_STATES, INS_STATES>(0, 0)
        .copy_from(&qc_ned.fixed_view::<INS_STATES, INS_STATES>(0, 0));
    let imu = &model.imu;
    let gnss = &model.gnss;
    let gm = |sigma: f64, tau: f64| 2.0 * sigma * sigma / tau;
    let pos = gnss.position_sigmas();
    // ENU σ (E, N, U) in NED order.
    let pos_ned = Vector3::new(pos.y, pos.x, pos.z);
    for i in 0..3 {
        // Each sensor's own correlation time (the NED model has one for both).
        f[(GYRO_BIAS + i, GYRO_BIAS + i)] = -1.0 / imu.gyro_bias_correlation_s;
        qc[(GYRO_BIAS + i, GYRO_BIAS + i)] =
            gm(imu.gyro_bias_sigma_rad_s, imu.gyro_bias_correlation_s);
        f[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = -1.0 / imu.accel_bias_correlation_s;
        qc[(ACCEL_BIAS + i, ACCEL_BIAS + i)] =
            gm(imu.accel_bias_sigma_m_s2, imu.accel_bias_correlation_s);
        f[(GNSS_POSITION + i, GNSS_POSITION + i)] = -1.0 / gnss.position_correlation_s;
        qc[(GNSS_POSITION + i, GNSS_POSITION + i)] = gm(pos_ned[i], gnss.position_correlation_s);
        f[(GNSS_VELOCITY + i, GNSS_VELOCITY + i)] = -1.0 / gnss.velocity_correlation_s;
        qc[(GNSS_VELOCITY + i, GNSS_VELOCITY + i)] =
            gm(gnss.velocity_sigma_mps, gnss.velocity_correlation_s);
    }
    (f, qc)
}

/// Φ = I + FΔt + (FΔt)²/2 + (FΔt)³/6 and Q = ½ (Φ Q_c Φᵀ + Q_c) Δt, as the
/// flat model discretises.
///
/// F is sparse (about 60 of 441 entries) and Q_c block diagonal, so the
/// four 21×21 products run over their nonzero terms only, planned once
/// from where [`continuous`] puts its nonzeros: the dense products' bits,
/// signs of zeros included, at a fraction of their cost (they were a third
/// of the formation's run time). An F or Q_c with nonzeros elsewhere gets
/// the same bits the slower way.
pub fn discrete(f: &Matrix21, qc: &Matrix21, dt_s: f64) -> (Matrix21, Matrix21) {
    let plans = DiscretePlans::get();
    let fdt = f * dt_s;
    let fdt2 = plans.fdt2.apply(&fdt, &fdt);
    let fdt3 = plans.fdt3.apply(&fdt2, &fdt);
    // I + FΔt + (FΔt)²/2 + (FΔt)³/6 element by element, in that order.
    let phi = Matrix21::from_fn(|i, j| {
        let identity = if i == j { 1.0 } else { 0.0 };
        identity + fdt[(i, j)] + fdt2[(i, j)] * 0.5 + fdt3[(i, j)] * (1.0 / 6.0)
    });
    let phi_qc = plans.phi_qc.apply(&phi, qc);
    let congruence = plans.phi_qc_phit.apply(&phi_qc, &phi.transpose());
    // (Φ Q_c Φᵀ + Q_c) Δt/2, then its symmetric part, element by element.
    let half_dt = 0.5 * dt_s;
    let unsymmetric = |i: usize, j: usize| (congruence[(i, j)] + qc[(i, j)]) * half_dt;
    let q = Matrix21::from_fn(|i, j| (unsymmetric(i, j) + unsymmetric(j, i)) * 0.5);
    (phi, q)
}

/// The products of [`discrete`], planned once ([`sparse::Product`]) from
/// where [`continuous`] puts its nonzeros.
struct DiscretePlans {
    /// (FΔt)².
    fdt2: sparse::Product,
    /// (FΔt)² FΔt.
    fdt3: sparse::Product,
    /// Φ Q_c.
    phi_qc: sparse::Product,
    /// (Φ Q_c) Φᵀ.
    phi_qc_phit: sparse::Product,
    /// Φ times the error cross-covariance ([`ErrorCrossCovariance`], dense).
    phi_cross: sparse::Product,
}

impl DiscretePlans {
    fn get() -> &'static Self {
        static PLANS: std::sync::OnceLock<DiscretePlans> = std::sync::OnceLock::new();
        PLANS.get_or_init(Self::new)
    }

    fn new() -> Self {
        let in_block = |k: usize, from: usize| (from..from + 3).contains(&k);
        // F: position (−[ω_en×], I), velocity (the gravity gradient in
        // δr_D, −[(2ω_ie + ω_en)×], [f^n×], C), attitude (−[ω_in×], −C),
        // every Gauss–Markov state its own diagonal.
        let f = sparse::Pattern::of(STATES, STATES, |i, k| match i {
            POSITION..VELOCITY => k < ATTITUDE,
            VELOCITY..ATTITUDE => (POSITION + 2..GYRO_BIAS).contains(&k) || in_block(k, ACCEL_BIAS),
            ATTITUDE..GYRO_BIAS => (ATTITUDE..ACCEL_BIAS).contains(&k),
            _ => i == k,
        });
        // Q_c: velocity and attitude blocks, the Gauss–Markov diagonal.
        let qc = sparse::Pattern::of(STATES, STATES, |i, k| {
            let white = |s: usize| (VELOCITY..GYRO_BIAS).contains(&s);
            if white(i) && white(k) {
                (i - VELOCITY) / 3 == (k - VELOCITY) / 3
            } else {
                i >= GYRO_BIAS && i == k
            }
        });
        let fdt2 = sparse::Product::new(&f, &f);
        let fdt3 = sparse::Product::new(fdt2.pattern(), &f);
        let identity = sparse::Pattern::of(STATES, STATES, |i, k| i == k);
        let phi = identity
            .union(&f)
            .union(fdt2.pattern())
            .union(fdt3.pattern());
        let phi_qc = sparse::Product::new(&phi, &qc);
        let phi_qc_phit = sparse::Product::new(phi_qc.pattern(), &phi.transpose());
        let cross = sparse::Pattern::of(STATES, 6, |_, _| true);
        Self {
            fdt2,
            fdt3,
            phi_qc,
            phi_qc_phit,
            phi_cross: sparse::Product::new(&phi, &cross),
        }
    }
}

/// The prior σ of every state: INS errors from the given initial σ
/// (position and velocity per axis, attitude (N, E, D)), instrument and GNSS
/// states from their model.
pub fn prior_sigmas(
    model: &LocalInsModel,
    position_sigma_m: f64,
    velocity_sigma_mps: f64,
    attitude_sigma_rad: Vector3<f64>,
) -> Vector21 {
    let mut s = Vector21::zeros();
    let pos = model.gnss.position_sigmas();
    let pos_ned = Vector3::new(pos.y, pos.x, pos.z);
    for i in 0..3 {
        s[POSITION + i] = position_sigma_m;
        s[VELOCITY + i] = velocity_sigma_mps;
        s[ATTITUDE + i] = attitude_sigma_rad[i];
        s[GYRO_BIAS + i] = model.imu.gyro_bias_sigma_rad_s;
        s[ACCEL_BIAS + i] = model.imu.accel_bias_sigma_m_s2;
        s[GNSS_POSITION + i] = pos_ned[i];
        s[GNSS_VELOCITY + i] = model.gnss.velocity_sigma_mps;
    }
    s
}

/// NED INS + 21-state loosely coupled filter, closed loop.
#[derive(Debug, Clone)]
pub struct NedLooselyCoupled {
    model: LocalInsModel,
    ins: NedMechanization,
    gyro_bias: Vector3<f64>,
    accel_bias: Vector3<f64>,
    kf: FixedKalmanFilter<STATES>,
    filter_dt_s: f64,
    pending_s: f64,
    delta_velocity_sum: Vector3<f64>,
    cross: ErrorCrossCovariance,
}

impl NedLooselyCoupled {
    /// Start from an INS state and the prior σ of every error state
    /// ([`prior_sigmas`]).
    pub fn new(
        model: LocalInsModel,
        ins: NedState,
        prior_sigmas: &Vector21,
        filter_dt_s: f64,
    ) -> Result<Self, EstimationError> {
        let p0 = Matrix21::from_diagonal(&prior_sigmas.map(|s| s * s));
        let cross = ErrorCrossCovariance::new(&p0);
        Ok(Self {
            cross,
            model,
            ins: NedMechanization::new(ins),
            gyro_bias: Vector3::zeros(),
            accel_bias: Vector3::zeros(),
            kf: FixedKalmanFilter::new(SVector::zeros(), p0)?,
            filter_dt_s,
            pending_s: 0.0,
            delta_velocity_sum: Vector3::zeros(),
        })
    }

    /// The corrected INS ("INS*").
    pub fn solution(&self) -> &NedState {
        self.ins.state()
    }

    /// Estimated accelerometer and gyro biases (body frame), in the order
    /// of [`local_level::LooselyCoupled::bias_estimates`](crate::local_level::LooselyCoupled::bias_estimates).
    pub fn bias_estimates(&self) -> (Vector3<f64>, Vector3<f64>) {
        (self.accel_bias, self.gyro_bias)
    }

    /// Covariance of the INS* position and velocity errors (6×6, NED).
    pub fn position_velocity_covariance(&self) -> Matrix6 {
        self.kf
            .covariance()
            .fixed_view::<6, 6>(POSITION, POSITION)
            .into_owned()
    }

    /// `E[e_now e_prevᵀ]` (6×6, NED, position first) of the INS*
    /// position–velocity error now with the one at the previous call, as
    /// [`crate::local_level::LooselyCoupled::take_error_cross_covariance`].
    pub fn take_error_cross_covariance(&mut self) -> Matrix6 {
        self.cross.take(self.kf.covariance())
    }

    /// Covariance of the INS* attitude error φ (NED).
    pub fn attitude_covariance(&self) -> Matrix3<f64> {
        self.kf
            .covariance()
            .fixed_view::<3, 3>(ATTITUDE, ATTITUDE)
            .into_owned()
    }

    /// One raw IMU increment (body frame, with the sensors' errors).
    pub fn step_increment(&mut self, raw: &ImuIncrement) -> Result<(), EstimationError> {
        let dt = raw.dt_s;
        let corrected = ImuIncrement {
            dt_s: dt,
            delta_angle: Vec3::assume_in_frame(raw.delta_angle.raw() - self.gyro_bias * dt),
            delta_velocity: Vec3::assume_in_frame(raw.delta_velocity.raw() - self.accel_bias * dt),
        };
        self.delta_velocity_sum += corrected.delta_velocity.raw();
        self.ins.update(&corrected);
        self.pending_s += dt;
        if self.pending_s >= self.filter_dt_s * (1.0 - 1e-9) {
            self.time_update()?;
        }
        Ok(())
    }

    fn time_update(&mut self) -> Result<(), EstimationError> {
        if self.pending_s <= 0.0 {
            return Ok(());
        }
        let f_body = self.delta_velocity_sum / self.pending_s;
        let s = *self.ins.state();
        let c_bn = s.attitude.matrix().raw();
        let (f, qc) = continuous(&self.model, &c_bn, &f_body, &s.position, &s.velocity);
        let (phi, q) = discrete(&f, &qc, self.pending_s);
        // (`predict_structured` with Φ's 9 full rows measured slower here
        // than the dense product, which runs with AVX2 where the CPU has it.)
        self.kf.predict(&phi, &q)?;
        self.cross
            .predict_with(|c| DiscretePlans::get().phi_cross.apply(&phi, c));
        self.pending_s = 0.0;
        self.delta_velocity_sum = Vector3::zeros();
        Ok(())
    }

    /// Propagate the filter to now without a fix (a GNSS outage).
    pub fn propagate(&mut self) -> Result<(), EstimationError> {
        self.time_update()
    }

    /// A GNSS position + velocity fix at the current time, with the model's
    /// white noise.
    pub fn gnss_update(
        &mut self,
        position: &Geodetic,
        velocity: &Vec3<Ned>,
    ) -> Result<(), EstimationError> {
        let (_, r) = self.model.measurement();
        self.gnss_update_with_noise(position, velocity, &r)
    }

    /// A GNSS fix whose white-noise covariance `r` (position, velocity, NED;
    /// 6×6) is given instead of the model's.
    pub fn gnss_update_with_noise(
        &mut self,
        position: &Geodetic,
        velocity: &Vec3<Ned>,
        r: &Matrix6,
    ) -> Result<(), EstimationError> {
        self.time_update()?;
        // The fix's H is the flat model's: it touches δr, δv, ε_R, ε_V only,
        // at the same offsets in both layouts.
        let (h, _) = self.model.measurement();
        let s = self.ins.state();
        let dp = s.position.ned_to(position).raw();
        let dv = (*velocity - s.velocity).raw();
        let z = SVector::<f64, 6>::from([dp.x, dp.y, dp.z, dv.x, dv.y, dv.z]);
        let p_prior = *self.kf.covariance();
        self.kf.update(&z, &h, r)?;
        self.cross.update(&p_prior, &h, r)?;
        self.feedback()
    }

    /// Move the INS error estimates into the INS and the IMU correction.
    fn feedback(&mut self) -> Result<(), EstimationError> {
        let mut x = *self.kf.state();
        let v3 = |o: usize| Vec3::<Ned>::new(x[o], x[o + 1], x[o + 2]);
        let s = *self.ins.state();
        self.ins.set_state(NedState {
            position: s.position.offset_by(&-v3(POSITION)),
            velocity: s.velocity - v3(VELOCITY),
            // True attitude C = (I + [φ×]) Ĉ.
            attitude: Rotation::from_rotation_vector(v3(ATTITUDE)) * s.attitude,
        });
        self.gyro_bias += v3(GYRO_BIAS).raw();
        self.accel_bias += v3(ACCEL_BIAS).raw();
        x.rows_mut(POSITION, INS_STATES).fill(0.0);
        self.kf.set_state(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_ins::ned::gravity_ned;

    /// The NED block is spec 40's model, the GNSS block the flat model's:
    /// at rest, a tilt about east drives the north velocity error by g; the
    /// Gauss–Markov states decay with their own τ.
    #[test]
    fn blocks_come_from_both_models() {
        let model = LocalInsModel::default();
        let p = Geodetic {
            latitude_rad: 0.7,
            longitude_rad: 0.2,
            height_m: 1000.0,
        };
        let g = gravity_ned(&p).z();
        let (f, qc) = continuous(
            &model,
            &Matrix3::identity(),
            &Vector3::new(0.0, 0.0, -g),
            &p,
            &Vec3::zeros(),
        );
        assert!((f[(VELOCITY, ATTITUDE + 1)] - g).abs() < 1e-12);
        // Coriolis: δv̇ = −2 ω_ie × δv, ω_ie,N = Ω cos φ.
        let w = earth_rate_ned(0.7).raw();
        assert!((f[(VELOCITY + 1, VELOCITY + 2)] - 2.0 * w.x).abs() < 1e-15);
        assert_eq!(
            f[(GNSS_POSITION, GNSS_POSITION)],
            -1.0 / model.gnss.position_correlation_s
        );
        assert_eq!(
            f[(GYRO_BIAS, GYRO_BIAS)],
            -1.0 / model.imu.gyro_bias_correlation_s
        );
        // Vertical GNSS σ on the down state.
        let s = model.gnss.position_vertical_sigma_m;
        assert!(
            (qc[(GNSS_POSITION + 2, GNSS_POSITION + 2)]
                - 2.0 * s * s / model.gnss.position_correlation_s)
                .abs()
                < 1e-15
        );
        // Velocity random walk: VRW² per axis, whatever the conversion.
        let vrw = model.imu.velocity_random_walk;
        assert!((qc[(VELOCITY, VELOCITY)] / (vrw * vrw) - 1.0).abs() < 1e-12);
        let arw = model.imu.angle_random_walk;
        assert!((qc[(ATTITUDE, ATTITUDE)] / (arw * arw) - 1.0).abs() < 1e-9);
    }

    /// The dense discretisation, as it was written before the planned
    /// products.
    fn dense_discrete(f: &Matrix21, qc: &Matrix21, dt_s: f64) -> (Matrix21, Matrix21) {
        let fdt = f * dt_s;
        let fdt2 = fdt * fdt;
        let phi = Matrix21::identity() + fdt + fdt2 * 0.5 + fdt2 * fdt * (1.0 / 6.0);
        let mut q = (phi * qc * phi.transpose() + qc) * (0.5 * dt_s);
        q = (q + q.transpose()) * 0.5;
        (phi, q)
    }

    fn same_bits(a: &Matrix21, b: &Matrix21) -> bool {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())
    }

    /// Φ, Q and Φ C equal the dense products bit for bit, zero signs
    /// included, at attitudes, forces, places and velocities of every sign
    /// (zero components too, and a level, heading-north attitude whose C
    /// holds exact zeros), at the filter's and odd intervals; F and Q_c
    /// from [`continuous`] follow the planned patterns, so the fast path is
    /// the one taken; an F with a nonzero outside them gives the dense bits
    /// too.
    #[test]
    fn discrete_equals_the_dense_products_bit_for_bit() {
        let model = LocalInsModel::default();
        let plans = DiscretePlans::get();
        let attitudes = [
            Matrix3::identity(),
            nalgebra::Rotation3::from_euler_angles(0.1, -0.05, 1.2).into_inner(),
            nalgebra::Rotation3::from_euler_angles(-0.3, 0.2, -2.9).into_inner(),
        ];
        let forces = [
            Vector3::new(0.0, 0.0, -9.8),
            Vector3::new(0.4, -0.25, -9.9),
            Vector3::zeros(),
        ];
        let places = [(0.7, 0.2, 1000.0), (-0.4, -2.0, 0.0), (0.0, 0.0, -30.0)];
        let velocities = [
            Vec3::zeros(),
            Vec3::new(30.0, -20.0, 1.0),
            Vec3::new(-60.0, 0.0, 0.0),
        ];
        let mut cases = 0;
        for c_bn in &attitudes {
            for f_body in &forces {
                for &(latitude_rad, longitude_rad, height_m) in &places {
                    let position = Geodetic {
                        latitude_rad,
                        longitude_rad,
                        height_m,
                    };
                    for v in &velocities {
                        let (f, qc) = continuous(&model, c_bn, f_body, &position, v);
                        let cross = SMatrix::<f64, STATES, 6>::from_fn(|i, j| {
                            ((i * 7 + j * 3) % 11) as f64 - 5.0
                        });
                        for dt in [0.1, 0.01, 1.0, 0.037] {
                            let (phi, q) = discrete(&f, &qc, dt);
                            let (phi_d, q_d) = dense_discrete(&f, &qc, dt);
                            assert!(same_bits(&phi, &phi_d) && same_bits(&q, &q_d));
                            let fdt = f * dt;
                            let fdt2 = fdt * fdt;
                            assert!(plans.fdt2.planned(&fdt, &fdt));
                            assert!(plans.fdt3.planned(&fdt2, &fdt));
                            assert!(plans.phi_qc.planned(&phi, &qc));
                            assert!(plans.phi_qc_phit.planned(&(phi * qc), &phi.transpose()));
                            assert!(plans.phi_cross.planned(&phi, &cross));
                            let pc = plans.phi_cross.apply(&phi, &cross);
                            let pc_d = phi * cross;
                            assert!(
                                pc.iter()
                                    .zip(pc_d.iter())
                                    .all(|(x, y)| x.to_bits() == y.to_bits())
                            );
                            cases += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(cases, 324);
        // Off the pattern: still the dense bits, by the general product.
        let (mut f, qc) = continuous(
            &model,
            &attitudes[1],
            &forces[1],
            &Geodetic {
                latitude_rad: 0.7,
                longitude_rad: 0.2,
                height_m: 1000.0,
            },
            &velocities[1],
        );
        f[(GYRO_BIAS, POSITION)] = 1e-3;
        f[(POSITION, GNSS_VELOCITY)] = -0.0;
        assert!(!plans.fdt2.planned(&f, &f));
        let (phi, q) = discrete(&f, &qc, 0.1);
        let (phi_d, q_d) = dense_discrete(&f, &qc, 0.1);
        assert!(same_bits(&phi, &phi_d) && same_bits(&q, &q_d));
    }
}
