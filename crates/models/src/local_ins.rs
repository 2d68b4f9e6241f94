//! Error model of a local-level (flat-Earth, ENU) strapdown INS aided by a
//! GNSS receiver whose errors are first-order Gauss–Markov plus white — the
//! stage-1 loosely coupled filter of spec 30 (paper eqs. 3–6).
//!
//! State (21): δp, δv (INS minus truth, nav frame), ψ (attitude error, the
//! INS attitude is `(I − [ψ×]) C`), accelerometer and gyro bias residuals
//! (body frame), and the GNSS receiver's correlated position and velocity
//! errors ε_R, ε_V:
//!
//! ```text
//! δṗ = δv            δv̇ = [f×] ψ + C b_a + C w_a        ψ̇ = −C b_g − C w_g
//! ḃ_a = −b_a/τ_a + ξ   ḃ_g = −b_g/τ_g + ξ   ε̇_R = −ε_R/τ_R + ξ   ε̇_V = −ε_V/τ_V + ξ
//! z = (p_GNSS − p_INS, v_GNSS − v_INS) = (ε_R − δp + v_R, ε_V − δv + v_V)
//! ```
//!
//! ```
//! use aidnav_models::local_ins::{LocalInsModel, STATES};
//! use nalgebra::{Matrix3, Vector3};
//! let model = LocalInsModel::default();
//! let (phi, q) = model.discrete(&Vector3::new(0.0, 0.0, 9.8), &Matrix3::identity(), 0.1);
//! assert_eq!(phi.nrows(), STATES);
//! assert!(q[(3, 3)] > 0.0); // velocity random walk
//! let (h, _r) = model.measurement();
//! assert_eq!(h[(0, 0)], -1.0); // position difference sees −δp …
//! assert_eq!(h[(0, 15)], 1.0); // … and +ε_R
//! ```

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use serde::{Deserialize, Serialize};

/// Number of states.
pub const STATES: usize = 21;
/// Offset of δp.
pub const POSITION: usize = 0;
/// Offset of δv.
pub const VELOCITY: usize = 3;
/// Offset of ψ.
pub const ATTITUDE: usize = 6;
/// Offset of the accelerometer bias residual.
pub const ACCEL_BIAS: usize = 9;
/// Offset of the gyro bias residual.
pub const GYRO_BIAS: usize = 12;
/// Offset of the GNSS correlated position error ε_R.
pub const GNSS_POSITION: usize = 15;
/// Offset of the GNSS correlated velocity error ε_V.
pub const GNSS_VELOCITY: usize = 18;

/// 21×21 matrix.
pub type Matrix21 = SMatrix<f64, STATES, STATES>;
/// 21-vector.
pub type Vector21 = SVector<f64, STATES>;
/// 6×21 measurement matrix.
pub type Matrix6x21 = SMatrix<f64, 6, STATES>;
/// 6×6 matrix.
pub type Matrix6 = SMatrix<f64, 6, 6>;

/// Instrument errors of the IMU (defaults: a tactical-grade unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuGrade {
    /// σ of each accelerometer bias [m/s²]. Default 5e-3 (≈ 0.5 mg).
    pub accel_bias_sigma_m_s2: f64,
    /// Correlation time of the accelerometer biases \[s\]. Default 3600.
    pub accel_bias_correlation_s: f64,
    /// σ of each gyro bias [rad/s]. Default 4.85e-5 (10 °/h).
    pub gyro_bias_sigma_rad_s: f64,
    /// Correlation time of the gyro biases \[s\]. Default 3600.
    pub gyro_bias_correlation_s: f64,
    /// Velocity random walk [m/s/√s]. Default 1e-3 (0.06 m/s/√h).
    pub velocity_random_walk: f64,
    /// Angle random walk [rad/√s]. Default 3e-5 (0.1 °/√h).
    pub angle_random_walk: f64,
}

impl Default for ImuGrade {
    fn default() -> Self {
        Self {
            accel_bias_sigma_m_s2: 5e-3,
            accel_bias_correlation_s: 3600.0,
            gyro_bias_sigma_rad_s: 4.85e-5,
            gyro_bias_correlation_s: 3600.0,
            velocity_random_walk: 1e-3,
            angle_random_walk: 3e-5,
        }
    }
}

/// GNSS receiver errors: first-order Gauss–Markov plus white (paper eq. 4).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssErrors {
    /// σ of the correlated horizontal position error, per axis \[m\]. Default 2.
    pub position_horizontal_sigma_m: f64,
    /// σ of the correlated vertical position error \[m\]. Default 4.
    pub position_vertical_sigma_m: f64,
    /// Correlation time of the position error \[s\]. Default 300.
    pub position_correlation_s: f64,
    /// σ of the white position error, per axis \[m\]. Default 0.5.
    pub position_white_sigma_m: f64,
    /// σ of the correlated velocity error, per axis [m/s]. Default 0.05.
    pub velocity_sigma_mps: f64,
    /// Correlation time of the velocity error \[s\]. Default 60.
    pub velocity_correlation_s: f64,
    /// σ of the white velocity error, per axis [m/s]. Default 0.05.
    pub velocity_white_sigma_mps: f64,
}

impl Default for GnssErrors {
    fn default() -> Self {
        Self {
            position_horizontal_sigma_m: 2.0,
            position_vertical_sigma_m: 4.0,
            position_correlation_s: 300.0,
            position_white_sigma_m: 0.5,
            velocity_sigma_mps: 0.05,
            velocity_correlation_s: 60.0,
            velocity_white_sigma_mps: 0.05,
        }
    }
}

impl GnssErrors {
    /// σ of the correlated position error per axis (E, N, U).
    pub fn position_sigmas(&self) -> Vector3<f64> {
        let h = self.position_horizontal_sigma_m;
        Vector3::new(h, h, self.position_vertical_sigma_m)
    }
}

/// The stage-1 error model: IMU grade and GNSS error statistics.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LocalInsModel {
    /// IMU errors.
    pub imu: ImuGrade,
    /// GNSS errors.
    pub gnss: GnssErrors,
}

impl LocalInsModel {
    /// F of the continuous model at specific force `f_nav` (nav frame) and
    /// attitude `c_bn` (body → nav).
    pub fn continuous(&self, f_nav: &Vector3<f64>, c_bn: &Matrix3<f64>) -> Matrix21 {
        let mut f = Matrix21::zeros();
        let i3 = Matrix3::identity();
        f.fixed_view_mut::<3, 3>(POSITION, VELOCITY).copy_from(&i3);
        f.fixed_view_mut::<3, 3>(VELOCITY, ATTITUDE)
            .copy_from(&f_nav.cross_matrix());
        f.fixed_view_mut::<3, 3>(VELOCITY, ACCEL_BIAS)
            .copy_from(c_bn);
        f.fixed_view_mut::<3, 3>(ATTITUDE, GYRO_BIAS)
            .copy_from(&-c_bn);
        let decay = [
            (ACCEL_BIAS, self.imu.accel_bias_correlation_s),
            (GYRO_BIAS, self.imu.gyro_bias_correlation_s),
            (GNSS_POSITION, self.gnss.position_correlation_s),
            (GNSS_VELOCITY, self.gnss.velocity_correlation_s),
        ];
        for (offset, tau) in decay {
            for i in 0..3 {
                f[(offset + i, offset + i)] = -1.0 / tau;
            }
        }
        f
    }

    /// Diagonal of the continuous white-noise spectral densities, per state.
    fn spectral_densities(&self) -> Vector21 {
        let mut q = Vector21::zeros();
        let imu = &self.imu;
        let gnss = &self.gnss;
        let gm = |sigma: f64, tau: f64| 2.0 * sigma * sigma / tau;
        let pos = gnss.position_sigmas();
        for i in 0..3 {
            // Isotropic white noise keeps its density when rotated by C.
            q[VELOCITY + i] = imu.velocity_random_walk.powi(2);
            q[ATTITUDE + i] = imu.angle_random_walk.powi(2);
            q[ACCEL_BIAS + i] = gm(imu.accel_bias_sigma_m_s2, imu.accel_bias_correlation_s);
            q[GYRO_BIAS + i] = gm(imu.gyro_bias_sigma_rad_s, imu.gyro_bias_correlation_s);
            q[GNSS_POSITION + i] = gm(pos[i], gnss.position_correlation_s);
            q[GNSS_VELOCITY + i] = gm(gnss.velocity_sigma_mps, gnss.velocity_correlation_s);
        }
        q
    }

    /// Φ = I + F Δt + (F Δt)²/2 + (F Δt)³/6 and Q = ½ (Φ Q_c Φᵀ + Q_c) Δt (trapezoid).
    pub fn discrete(
        &self,
        f_nav: &Vector3<f64>,
        c_bn: &Matrix3<f64>,
        dt_s: f64,
    ) -> (Matrix21, Matrix21) {
        let fdt = self.continuous(f_nav, c_bn) * dt_s;
        let fdt2 = fdt * fdt;
        // Third order: the chain δp ← δv ← ψ ← b_g needs F³ to be exact to O(Δt⁴).
        let phi = Matrix21::identity() + fdt + fdt2 * 0.5 + fdt2 * fdt * (1.0 / 6.0);
        let qc = Matrix21::from_diagonal(&self.spectral_densities());
        let mut q = (phi * qc * phi.transpose() + qc) * (0.5 * dt_s);
        q = (q + q.transpose()) * 0.5;
        (phi, q)
    }

    /// H and R of a GNSS position + velocity fix.
    pub fn measurement(&self) -> (Matrix6x21, Matrix6) {
        let mut h = Matrix6x21::zeros();
        for i in 0..3 {
            h[(i, POSITION + i)] = -1.0;
            h[(i, GNSS_POSITION + i)] = 1.0;
            h[(3 + i, VELOCITY + i)] = -1.0;
            h[(3 + i, GNSS_VELOCITY + i)] = 1.0;
        }
        let p = self.gnss.position_white_sigma_m.powi(2);
        let v = self.gnss.velocity_white_sigma_mps.powi(2);
        let r = Matrix6::from_diagonal(&SVector::<f64, 6>::from([p, p, p, v, v, v]));
        (h, r)
    }

    /// Stationary σ of every state for a prior: INS errors from the given
    /// initial σ, instrument and GNSS states from their model.
    pub fn prior_sigmas(
        &self,
        position_sigma_m: f64,
        velocity_sigma_mps: f64,
        attitude_sigma_rad: Vector3<f64>,
    ) -> Vector21 {
        let mut s = Vector21::zeros();
        let pos = self.gnss.position_sigmas();
        for i in 0..3 {
            s[POSITION + i] = position_sigma_m;
            s[VELOCITY + i] = velocity_sigma_mps;
            s[ATTITUDE + i] = attitude_sigma_rad[i];
            s[ACCEL_BIAS + i] = self.imu.accel_bias_sigma_m_s2;
            s[GYRO_BIAS + i] = self.imu.gyro_bias_sigma_rad_s;
            s[GNSS_POSITION + i] = pos[i];
            s[GNSS_VELOCITY + i] = self.gnss.velocity_sigma_mps;
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Φ against the matrix exponential, and the
    /// attitude → velocity coupling against a direct perturbation.
    #[test]
    fn transition_matches_fine_integration() {
        let model = LocalInsModel::default();
        let f_nav = Vector3::new(1.0, -0.5, 9.8);
        let c = nalgebra::Rotation3::from_euler_angles(0.1, -0.2, 0.7).into_inner();
        let (phi, _) = model.discrete(&f_nav, &c, 0.1);
        let f = model.continuous(&f_nav, &c);
        // exp(F Δt) by its Taylor series to 20 terms (‖F Δt‖ ≈ 1).
        let mut exact = Matrix21::identity();
        let mut term = Matrix21::identity();
        for k in 1..20 {
            term = term * f * (0.1 / k as f64);
            exact += term;
        }
        assert!((phi - exact).abs().max() < 1e-7);
        // A tilt ψ about x with f = g up: δv̇ = f × ψ = (0, 9.8 ψ, 0).
        let f_up = model.continuous(&Vector3::new(0.0, 0.0, 9.8), &Matrix3::identity());
        assert!((f_up[(VELOCITY + 1, ATTITUDE)] - 9.8).abs() < 1e-12);
    }

    #[test]
    fn gauss_markov_noise_keeps_the_stationary_sigma() {
        // Iterate Φ P Φᵀ + Q for the GNSS position states only (f = 0).
        let model = LocalInsModel::default();
        let (phi, q) = model.discrete(&Vector3::zeros(), &Matrix3::identity(), 1.0);
        let i = GNSS_POSITION + 2;
        let mut p = 0.0;
        for _ in 0..20_000 {
            p = phi[(i, i)] * p * phi[(i, i)] + q[(i, i)];
        }
        assert!((p.sqrt() / model.gnss.position_vertical_sigma_m - 1.0).abs() < 2e-3);
    }
}
