//! The 21-state error model of a WGS-84 NED strapdown INS (spec 40):
//!
//! ```text
//! x = (δr, δv, φ, b_g, b_a, s_g, s_a)      δr, δv: INS minus truth (NED, m, m/s)
//! Ĉ_b^n = (I − [φ×]) C_b^n                 φ: attitude error [rad]
//! ω̃ = ω + b_g + s_g ⊙ ω,  f̃ = f + b_a + s_a ⊙ f   (first-order Gauss–Markov each)
//! δṙ = δv − ω_en × δr
//! δv̇ = [f^n×] φ + C (b_a + f ⊙ s_a) − (2ω_ie + ω_en) × δv + (2g/R) δh e_D
//! φ̇ = −ω_in × φ − C (b_g + ω ⊙ s_g)
//! ```
//!
//! Terms of order v/R and ω_ie·v/R in the position and attitude rows are
//! dropped (below 1e-6 of the kept ones for a land vehicle). Noise comes
//! from datasheet terms ([`ImuNoise`]): velocity and angle random walk give
//! white noise densities VRW², ARW²; a bias instability σ with correlation
//! time τ gives the Gauss–Markov driving density 2σ²/τ (likewise the scale
//! factors).
//!
//! GNSS position with lever arm l (body frame, IMU → antenna):
//! `z = r̂_ant − r_GNSS = δr + [(Ĉ l)×] φ + n`.
//!
//! ```
//! use aidnav_models::ned_ins::{NedErrorModel, STATES};
//! use nalgebra::{Matrix3, Vector3};
//! let m = NedErrorModel::default();
//! let f = m.continuous(&Matrix3::identity(), &Vector3::new(0.0, 0.0, -9.8), &Vector3::zeros(), &Vector3::zeros(), &Vector3::zeros(), 0.7);
//! // At rest (f^n = −g up): a tilt error about east drives the north
//! // velocity error, δv̇_N = −f_D φ_E = g φ_E.
//! assert_eq!(f[(3, 6 + 1)], 9.8);
//! ```

use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use serde::{Deserialize, Serialize};

/// Number of states.
pub const STATES: usize = 21;
/// Offset of δr.
pub const POSITION: usize = 0;
/// Offset of δv.
pub const VELOCITY: usize = 3;
/// Offset of φ.
pub const ATTITUDE: usize = 6;
/// Offset of the gyro bias.
pub const GYRO_BIAS: usize = 9;
/// Offset of the accelerometer bias.
pub const ACCEL_BIAS: usize = 12;
/// Offset of the gyro scale factor.
pub const GYRO_SCALE: usize = 15;
/// Offset of the accelerometer scale factor.
pub const ACCEL_SCALE: usize = 18;

/// 21×21 matrix.
pub type Matrix21 = SMatrix<f64, STATES, STATES>;
/// 21-vector.
pub type Vector21 = SVector<f64, STATES>;
/// 3×21 matrix.
pub type Matrix3x21 = SMatrix<f64, 3, STATES>;

/// Datasheet noise terms of an IMU (defaults: a consumer MEMS unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuNoise {
    /// Angle random walk [deg/√h]. Default 0.6.
    pub arw_deg_per_sqrt_h: f64,
    /// Velocity random walk [m/s/√h]. Default 0.6.
    pub vrw_mps_per_sqrt_h: f64,
    /// Gyro bias instability σ [deg/h]. Default 50.
    pub gyro_bias_deg_per_h: f64,
    /// Accelerometer bias instability σ \[mg\]. Default 2.
    pub accel_bias_mg: f64,
    /// Gyro scale-factor σ \[ppm\]. Default 1000.
    pub gyro_scale_ppm: f64,
    /// Accelerometer scale-factor σ \[ppm\]. Default 1000.
    pub accel_scale_ppm: f64,
    /// Correlation time of every bias and scale factor \[s\]. Default 3600.
    pub correlation_s: f64,
}

impl Default for ImuNoise {
    fn default() -> Self {
        Self {
            arw_deg_per_sqrt_h: 0.6,
            vrw_mps_per_sqrt_h: 0.6,
            gyro_bias_deg_per_h: 50.0,
            accel_bias_mg: 2.0,
            gyro_scale_ppm: 1000.0,
            accel_scale_ppm: 1000.0,
            correlation_s: 3600.0,
        }
    }
}

impl ImuNoise {
    /// The σ of the six instrument states' stationary distributions, in SI.
    pub fn instrument_sigmas(&self) -> [f64; 4] {
        [
            self.gyro_bias_deg_per_h.to_radians() / 3600.0,
            self.accel_bias_mg * 1e-3 * 9.806_65,
            self.gyro_scale_ppm * 1e-6,
            self.accel_scale_ppm * 1e-6,
        ]
    }

    /// White noise densities (ARW², VRW²) in SI: rad²/s, (m/s)²/s.
    pub fn white_densities(&self) -> (f64, f64) {
        let arw = self.arw_deg_per_sqrt_h.to_radians() / 60.0;
        let vrw = self.vrw_mps_per_sqrt_h / 60.0;
        (arw * arw, vrw * vrw)
    }
}

/// The model; only the noise is configuration.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NedErrorModel {
    /// IMU noise terms.
    pub noise: ImuNoise,
}

impl NedErrorModel {
    /// F at attitude C_b^n, body specific force f^b and rate ω^b, Earth rate
    /// ω_ie and transport rate ω_en (NED), latitude-free gravity gradient at
    /// about g/R.
    pub fn continuous(
        &self,
        c_bn: &Matrix3<f64>,
        f_body: &Vector3<f64>,
        w_body: &Vector3<f64>,
        w_ie: &Vector3<f64>,
        w_en: &Vector3<f64>,
        _latitude_rad: f64,
    ) -> Matrix21 {
        let mut f = Matrix21::zeros();
        let f_nav = c_bn * f_body;
        let w_in = w_ie + w_en;
        f.fixed_view_mut::<3, 3>(POSITION, POSITION)
            .copy_from(&-w_en.cross_matrix());
        f.fixed_view_mut::<3, 3>(POSITION, VELOCITY)
            .copy_from(&Matrix3::identity());
        f.fixed_view_mut::<3, 3>(VELOCITY, VELOCITY)
            .copy_from(&-(2.0 * w_ie + w_en).cross_matrix());
        f.fixed_view_mut::<3, 3>(VELOCITY, ATTITUDE)
            .copy_from(&f_nav.cross_matrix());
        f.fixed_view_mut::<3, 3>(VELOCITY, ACCEL_BIAS)
            .copy_from(c_bn);
        f.fixed_view_mut::<3, 3>(VELOCITY, ACCEL_SCALE)
            .copy_from(&(c_bn * Matrix3::from_diagonal(f_body)));
        // Vertical channel: gravity grows as the INS sinks (δr_D > 0 ⇒ δg > 0).
        f[(VELOCITY + 2, POSITION + 2)] = 2.0 * 9.8 / 6.371e6;
        f.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&-w_in.cross_matrix());
        f.fixed_view_mut::<3, 3>(ATTITUDE, GYRO_BIAS)
            .copy_from(&-c_bn);
        f.fixed_view_mut::<3, 3>(ATTITUDE, GYRO_SCALE)
            .copy_from(&-(c_bn * Matrix3::from_diagonal(w_body)));
        let tau = self.noise.correlation_s;
        for i in GYRO_BIAS..STATES {
            f[(i, i)] = -1.0 / tau;
        }
        f
    }

    /// Φ = I + FΔt + (FΔt)²/2 and Q = Q_c Δt + (F Q_c + Q_c Fᵀ) Δt²/2 (both
    /// to second order; F is sparse — about 60 of 441 entries — and Q_c
    /// diagonal, so neither needs a dense product: this runs at the filter's
    /// covariance rate, 20 Hz, and dense 21³ products were 40 % of a pass).
    pub fn discrete(&self, f: &Matrix21, dt: f64) -> (Matrix21, Matrix21) {
        let fdt = f * dt;
        let mut phi = Matrix21::identity() + fdt;
        for k in 0..STATES {
            for i in 0..STATES {
                let a = fdt[(i, k)];
                if a != 0.0 {
                    // (FΔt)²[i, :] += a · FΔt[k, :]
                    for j in 0..STATES {
                        let b = fdt[(k, j)];
                        if b != 0.0 {
                            phi[(i, j)] += 0.5 * a * b;
                        }
                    }
                }
            }
        }
        let qc = self.spectral_densities();
        let mut q = Matrix21::zeros();
        for j in 0..STATES {
            for i in 0..STATES {
                // (F Q_c)_{ij} = F_ij q_j; (Q_c Fᵀ)_{ij} = q_i F_ji.
                q[(i, j)] = 0.5 * dt * (fdt[(i, j)] * qc[j] + qc[i] * fdt[(j, i)]);
            }
            q[(j, j)] += qc[j] * dt;
        }
        (phi, q)
    }

    /// Diagonal of the continuous white-noise densities, per state.
    fn spectral_densities(&self) -> Vector21 {
        let (arw2, vrw2) = self.noise.white_densities();
        let [sg, sa, kg, ka] = self.noise.instrument_sigmas();
        let tau = self.noise.correlation_s;
        let mut qc = Vector21::zeros();
        for i in 0..3 {
            qc[VELOCITY + i] = vrw2;
            qc[ATTITUDE + i] = arw2;
            qc[GYRO_BIAS + i] = 2.0 * sg * sg / tau;
            qc[ACCEL_BIAS + i] = 2.0 * sa * sa / tau;
            qc[GYRO_SCALE + i] = 2.0 * kg * kg / tau;
            qc[ACCEL_SCALE + i] = 2.0 * ka * ka / tau;
        }
        qc
    }

    /// H of a GNSS position fix with lever arm `lever_nav` = Ĉ l (NED).
    pub fn position_measurement(lever_nav: &Vector3<f64>) -> Matrix3x21 {
        let mut h = Matrix3x21::zeros();
        h.fixed_view_mut::<3, 3>(0, POSITION)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, ATTITUDE)
            .copy_from(&lever_nav.cross_matrix());
        h
    }

    /// H of the non-holonomic constraint (a land vehicle's lateral and
    /// vertical body velocity are zero): rows y and z of
    /// `δv^b = Cᵀ δv − Cᵀ [v×] φ` at attitude C_b^n and NED velocity v.
    pub fn non_holonomic_measurement(
        c_bn: &Matrix3<f64>,
        velocity: &Vector3<f64>,
    ) -> SMatrix<f64, 2, STATES> {
        let ct = c_bn.transpose();
        let dv = ct;
        let dphi = -(ct * velocity.cross_matrix());
        let mut h = SMatrix::<f64, 2, STATES>::zeros();
        for r in 0..2 {
            for c in 0..3 {
                h[(r, VELOCITY + c)] = dv[(r + 1, c)];
                h[(r, ATTITUDE + c)] = dphi[(r + 1, c)];
            }
        }
        h
    }

    /// H of a GNSS velocity fix; `lever_velocity_nav` = Ĉ (ω × l) (NED).
    pub fn velocity_measurement(lever_velocity_nav: &Vector3<f64>) -> Matrix3x21 {
        let mut h = Matrix3x21::zeros();
        h.fixed_view_mut::<3, 3>(0, VELOCITY)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, ATTITUDE)
            .copy_from(&lever_velocity_nav.cross_matrix());
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sparse Φ and Q against the dense formulas.
    #[test]
    fn sparse_discretisation_matches_the_dense_one() {
        let m = NedErrorModel::default();
        let c = nalgebra::Rotation3::from_euler_angles(0.1, -0.05, 2.0).into_inner();
        let f = m.continuous(
            &c,
            &Vector3::new(0.5, -0.3, -9.8),
            &Vector3::new(0.01, -0.02, 0.3),
            &Vector3::new(5e-5, 0.0, -4e-5),
            &Vector3::new(1e-6, -2e-6, 1e-6),
            0.7,
        );
        let dt = 0.05;
        let (phi, q) = m.discrete(&f, dt);
        let fdt = f * dt;
        let dense_phi = Matrix21::identity() + fdt + fdt * fdt * 0.5;
        let qc = Matrix21::from_diagonal(&m.spectral_densities());
        let dense_q = qc * dt + (f * qc + qc * f.transpose()) * (0.5 * dt * dt);
        assert!((phi - dense_phi).abs().max() < 1e-15);
        assert!((q - dense_q).abs().max() < 1e-18);
        assert!((q - q.transpose()).abs().max() == 0.0);
    }

    #[test]
    fn gauss_markov_noise_keeps_the_datasheet_sigma() {
        let m = NedErrorModel::default();
        let f = m.continuous(
            &Matrix3::identity(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            0.0,
        );
        let (phi, q) = m.discrete(&f, 1.0);
        let i = ACCEL_BIAS;
        let mut p = 0.0;
        for _ in 0..50_000 {
            p = phi[(i, i)] * p * phi[(i, i)] + q[(i, i)];
        }
        let sigma = m.noise.instrument_sigmas()[1];
        assert!((p.sqrt() / sigma - 1.0).abs() < 1e-3);
    }

    /// The non-holonomic rows against a perturbed attitude and velocity.
    #[test]
    fn non_holonomic_rows_match_a_perturbation() {
        let c = nalgebra::Rotation3::from_euler_angles(0.05, -0.03, 2.0).into_inner();
        let v = c * Vector3::new(15.0, 0.0, 0.0);
        let phi = Vector3::new(2e-4, -1e-4, 3e-4);
        let dv = Vector3::new(0.02, -0.01, 0.03);
        let c_hat = (Matrix3::identity() - phi.cross_matrix()) * c;
        let body = c_hat.transpose() * (v + dv);
        let h = NedErrorModel::non_holonomic_measurement(&c_hat, &(v + dv));
        let mut x = Vector21::zeros();
        x.fixed_rows_mut::<3>(ATTITUDE).copy_from(&phi);
        x.fixed_rows_mut::<3>(VELOCITY).copy_from(&dv);
        let predicted = h * x;
        assert!((predicted[0] - body.y).abs() < 1e-3 * body.y.abs().max(1e-3));
        assert!((predicted[1] - body.z).abs() < 1e-3 * body.z.abs().max(1e-3));
    }

    /// The lever-arm row against a direct perturbation of the attitude.
    #[test]
    fn lever_arm_row_matches_a_perturbed_attitude() {
        let c = nalgebra::Rotation3::from_euler_angles(0.1, 0.2, 1.0).into_inner();
        let l = Vector3::new(0.3, -0.05, -0.65);
        let phi = Vector3::new(1e-4, -2e-4, 3e-4);
        let c_hat = (Matrix3::identity() - phi.cross_matrix()) * c;
        let direct = c_hat * l - c * l;
        let h = NedErrorModel::position_measurement(&(c_hat * l));
        let mut x = Vector21::zeros();
        x.fixed_rows_mut::<3>(ATTITUDE).copy_from(&phi);
        // Equal to first order; the rest is O(φ²) ≈ 1e-7 m here.
        assert!((h * x - direct).norm() < 1e-3 * direct.norm());
    }
}
