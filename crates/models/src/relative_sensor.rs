//! Inter-vehicle sensor of spec 30: slant range D, bearing α and elevation β
//! of another member, measured in the observer's body frame, and their
//! conversion to Cartesian coordinates (the paper's
//! `x = D cos α cos β, y = D sin α cos β, z = D sin β`).
//!
//! The conversion makes independent polar errors correlated across the
//! Cartesian axes, with a size that grows with range (D σ_α across the line of
//! sight against σ_D along it): \[`converted_covariance`\] gives the
//! first-order covariance `J diag(σ_D², σ_α², σ_β²) Jᵀ`, which the paper's
//! axis-decoupled fusion can only use through its diagonal.
//!
//!
//! The same sensors may also measure motion: the range rate Ḋ (a Doppler
//! sensor; \[`range_rate`\], independent of any frame, so of the observer's
//! attitude) and the relative velocity vector in the observer's body frame
//! (\[`body_relative_velocity`\]), each with its Jacobians.
//!
//! ```
//! use aidnav_models::relative_sensor::{Polar, RelativeSensor};
//! use nalgebra::Vector3;
//! let p = Polar::from_cartesian(&Vector3::new(100.0, 100.0, 0.0));
//! assert!((p.range_m - 141.42135623730951).abs() < 1e-9);
//! assert!((p.bearing_rad - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
//! let s = RelativeSensor::default(); // σ_D 0.5 m, σ_α = σ_β = 2 mrad
//! let c = s.converted_covariance(&p);
//! // At 45° the larger range error (0.5 m against D σ_α = 0.28 m across)
//! // makes the x and y errors positively correlated.
//! assert!(c[(0, 1)] > 0.0);
//! ```

use nalgebra::{Matrix3, RowVector3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// Range, bearing, elevation of a vector in some frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polar {
    /// Slant range D \[m\].
    pub range_m: f64,
    /// Bearing α = atan2(y, x) \[rad\], in (−π, π].
    pub bearing_rad: f64,
    /// Elevation β = asin(z / D) \[rad\].
    pub elevation_rad: f64,
}

impl Polar {
    /// Polar coordinates of r (r ≠ 0).
    pub fn from_cartesian(r: &Vector3<f64>) -> Self {
        let horizontal = r.x.hypot(r.y);
        Self {
            range_m: r.norm(),
            bearing_rad: r.y.atan2(r.x),
            elevation_rad: r.z.atan2(horizontal),
        }
    }

    /// The paper's conversion to Cartesian coordinates.
    pub fn to_cartesian(&self) -> Vector3<f64> {
        let (sa, ca) = self.bearing_rad.sin_cos();
        let (sb, cb) = self.elevation_rad.sin_cos();
        self.range_m * Vector3::new(ca * cb, sa * cb, sb)
    }

    /// ∂(x, y, z)/∂(D, α, β).
    pub fn cartesian_jacobian(&self) -> Matrix3<f64> {
        let d = self.range_m;
        let (sa, ca) = self.bearing_rad.sin_cos();
        let (sb, cb) = self.elevation_rad.sin_cos();
        Matrix3::new(
            ca * cb,
            -d * sa * cb,
            -d * ca * sb,
            sa * cb,
            d * ca * cb,
            -d * sa * sb,
            sb,
            0.0,
            d * cb,
        )
    }

    /// ∂(D, α, β)/∂(x, y, z) at r (the EKF's measurement Jacobian in the
    /// body frame). Singular on the vertical through the observer.
    pub fn polar_jacobian(r: &Vector3<f64>) -> Matrix3<f64> {
        let d2 = r.norm_squared();
        let d = d2.sqrt();
        let h2 = r.x * r.x + r.y * r.y;
        let h = h2.sqrt();
        Matrix3::new(
            r.x / d,
            r.y / d,
            r.z / d,
            -r.y / h2,
            r.x / h2,
            0.0,
            -r.x * r.z / (d2 * h),
            -r.y * r.z / (d2 * h),
            h / d2,
        )
    }
}

/// Wrap an angle difference into (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let w = a.rem_euclid(std::f64::consts::TAU);
    if w > std::f64::consts::PI {
        w - std::f64::consts::TAU
    } else {
        w
    }
}

/// Range rate Ḋ = d · ḋ / |d| of a line of sight `d` changing at `d_dot`
/// (for members, d = R^to − R^from and ḋ = V^to − V^from). Zero at d = 0.
pub fn range_rate(d: &Vector3<f64>, d_dot: &Vector3<f64>) -> f64 {
    let n = d.norm();
    if n > 0.0 { d.dot(d_dot) / n } else { 0.0 }
}

/// ∂Ḋ/∂d = (ḋ − Ḋ u)ᵀ / |d| and ∂Ḋ/∂ḋ = uᵀ, u = d / |d| (d ≠ 0).
pub fn range_rate_jacobian(
    d: &Vector3<f64>,
    d_dot: &Vector3<f64>,
) -> (RowVector3<f64>, RowVector3<f64>) {
    let n = d.norm();
    let u = d / n;
    let rate = u.dot(d_dot);
    ((d_dot - rate * u).transpose() / n, u.transpose())
}

/// The relative velocity `d_dot` (nav frame) resolved in the body frame of
/// an observer with attitude `attitude` (body → nav): Cᵀ ḋ. It is the
/// velocity of the other member relative to the observer expressed in the
/// observer's axes, not the rate of the body-frame line of sight (which
/// would add −ω × d).
pub fn body_relative_velocity(
    attitude: &UnitQuaternion<f64>,
    d_dot: &Vector3<f64>,
) -> Vector3<f64> {
    attitude.inverse_transform_vector(d_dot)
}

/// Jacobians of [`body_relative_velocity`]: ∂/∂ḋ = Cᵀ, and ∂/∂ψ = Cᵀ [ḋ×]
/// for a small rotation ψ of the observer's attitude about the nav axes,
/// C(ψ) = exp([ψ×]) C (so an attitude error ψ moves the measured vector by
/// Cᵀ (ḋ × ψ)).
pub fn body_relative_velocity_jacobian(
    attitude: &UnitQuaternion<f64>,
    d_dot: &Vector3<f64>,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let ct = attitude.to_rotation_matrix().into_inner().transpose();
    (ct, ct * d_dot.cross_matrix())
}

/// Noise and reach of an inter-vehicle range / direction finder.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RelativeSensor {
    /// σ of the slant range \[m\]. Default 0.5.
    pub range_sigma_m: f64,
    /// σ of the bearing \[rad\]. Default 2e-3 (0.11°).
    pub bearing_sigma_rad: f64,
    /// σ of the elevation \[rad\]. Default 2e-3.
    pub elevation_sigma_rad: f64,
    /// Members farther than this are not measured \[m\]. Default 2000.
    pub range_limit_m: f64,
    /// Whether the sensor also measures the range rate Ḋ (Doppler). Default
    /// false.
    pub range_rate: bool,
    /// σ of the range rate [m/s]. Default 0.1 (a Doppler radar's
    /// centimetres to decimetres per second).
    pub range_rate_sigma_mps: f64,
    /// Whether the sensor also measures the relative velocity vector in the
    /// observer's body frame. Default false.
    pub relative_velocity: bool,
    /// σ of each body-frame component of the relative velocity [m/s].
    /// Default 0.2.
    pub relative_velocity_sigma_mps: f64,
}

impl Default for RelativeSensor {
    fn default() -> Self {
        Self {
            range_sigma_m: 0.5,
            bearing_sigma_rad: 2e-3,
            elevation_sigma_rad: 2e-3,
            range_limit_m: 2000.0,
            range_rate: false,
            range_rate_sigma_mps: 0.1,
            relative_velocity: false,
            relative_velocity_sigma_mps: 0.2,
        }
    }
}

impl RelativeSensor {
    /// diag(σ_D², σ_α², σ_β²).
    pub fn polar_covariance(&self) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::new(
            self.range_sigma_m.powi(2),
            self.bearing_sigma_rad.powi(2),
            self.elevation_sigma_rad.powi(2),
        ))
    }

    /// First-order covariance of the converted Cartesian vector, in the
    /// sensor's frame: `J diag(σ_D², σ_α², σ_β²) Jᵀ`.
    pub fn converted_covariance(&self, p: &Polar) -> Matrix3<f64> {
        let j = p.cartesian_jacobian();
        j * self.polar_covariance() * j.transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn conversion_round_trips() {
        for r in [
            Vector3::new(120.0, -40.0, 15.0),
            Vector3::new(-300.0, 2.0, -80.0),
            Vector3::new(-5.0, -900.0, 1.0),
        ] {
            let back = Polar::from_cartesian(&r).to_cartesian();
            assert!((back - r).norm() < 1e-9);
        }
        assert!(
            (wrap_angle(3.5 * std::f64::consts::PI) + 0.5 * std::f64::consts::PI).abs() < 1e-12
        );
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let r = Vector3::new(150.0, -60.0, 25.0);
        let p = Polar::from_cartesian(&r);
        let h = 1e-6;
        let jc = p.cartesian_jacobian();
        let jp = Polar::polar_jacobian(&r);
        for k in 0..3 {
            let mut dp = [p.range_m, p.bearing_rad, p.elevation_rad];
            dp[k] += h;
            let plus = Polar {
                range_m: dp[0],
                bearing_rad: dp[1],
                elevation_rad: dp[2],
            };
            dp[k] -= 2.0 * h;
            let minus = Polar {
                range_m: dp[0],
                bearing_rad: dp[1],
                elevation_rad: dp[2],
            };
            let col = (plus.to_cartesian() - minus.to_cartesian()) / (2.0 * h);
            assert!((col - jc.column(k)).norm() < 1e-5 * (1.0 + col.norm()));
            let mut e = Vector3::zeros();
            e[k] = 1e-4;
            let (a, b) = (
                Polar::from_cartesian(&(r + e)),
                Polar::from_cartesian(&(r - e)),
            );
            let fd = Vector3::new(
                a.range_m - b.range_m,
                a.bearing_rad - b.bearing_rad,
                a.elevation_rad - b.elevation_rad,
            ) / 2e-4;
            assert!((fd - jp.column(k)).norm() < 1e-8, "column {k}");
        }
        // The two Jacobians are inverse to each other.
        assert!((jp * jc - Matrix3::identity()).norm() < 1e-12);
    }

    /// Range rate and body-frame relative velocity against central
    /// differences of their predictions (the attitude column by rotating the
    /// observer's attitude about each nav axis).
    #[test]
    fn rate_jacobians_match_finite_differences() {
        let d = Vector3::new(150.0, -60.0, 25.0);
        let d_dot = Vector3::new(-3.0, 7.5, 0.4);
        let (jd, jv) = range_rate_jacobian(&d, &d_dot);
        let h = 1e-5;
        for k in 0..3 {
            let mut e = Vector3::zeros();
            e[k] = h;
            let fd_d = (range_rate(&(d + e), &d_dot) - range_rate(&(d - e), &d_dot)) / (2.0 * h);
            let fd_v = (range_rate(&d, &(d_dot + e)) - range_rate(&d, &(d_dot - e))) / (2.0 * h);
            assert!(
                (fd_d - jd[k]).abs() < 1e-9,
                "∂Ḋ/∂d[{k}]: {fd_d} vs {}",
                jd[k]
            );
            assert!(
                (fd_v - jv[k]).abs() < 1e-9,
                "∂Ḋ/∂ḋ[{k}]: {fd_v} vs {}",
                jv[k]
            );
        }
        // Closed form: a purely radial rate is the full speed, a purely
        // transverse one is zero.
        assert!((range_rate(&d, &(2.0 * d / d.norm())) - 2.0).abs() < 1e-12);
        assert!(range_rate(&d, &d.cross(&Vector3::z())).abs() < 1e-12);
        assert_eq!(range_rate(&Vector3::zeros(), &d_dot), 0.0);

        let attitude = UnitQuaternion::from_euler_angles(0.1, -0.2, 2.0);
        let (jdv, jpsi) = body_relative_velocity_jacobian(&attitude, &d_dot);
        for k in 0..3 {
            let mut e = Vector3::zeros();
            e[k] = h;
            let fd_v = (body_relative_velocity(&attitude, &(d_dot + e))
                - body_relative_velocity(&attitude, &(d_dot - e)))
                / (2.0 * h);
            assert!((fd_v - jdv.column(k)).norm() < 1e-9, "∂/∂ḋ column {k}");
            let turned = |s: f64| UnitQuaternion::from_scaled_axis(s * e) * attitude;
            let fd_psi = (body_relative_velocity(&turned(1.0), &d_dot)
                - body_relative_velocity(&turned(-1.0), &d_dot))
                / (2.0 * h);
            assert!(
                (fd_psi - jpsi.column(k)).norm() < 1e-8,
                "∂/∂ψ column {k}: {fd_psi} vs {}",
                jpsi.column(k)
            );
        }
    }

    /// The converted covariance against the sample covariance of 200 000
    /// converted noisy triples (0.3 % sampling error on the variances).
    #[test]
    fn converted_covariance_matches_monte_carlo() {
        let sensor = RelativeSensor {
            range_sigma_m: 1.0,
            bearing_sigma_rad: 5e-3,
            elevation_sigma_rad: 3e-3,
            range_limit_m: 1e4,
            ..RelativeSensor::default()
        };
        let truth = Polar::from_cartesian(&Vector3::new(300.0, 250.0, -60.0));
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let n = 200_000;
        let mut mean = Vector3::zeros();
        let mut samples = Vec::with_capacity(n);
        for _ in 0..n {
            let g = |rng: &mut ChaCha8Rng| -> f64 { StandardNormal.sample(rng) };
            let noisy = Polar {
                range_m: truth.range_m + sensor.range_sigma_m * g(&mut rng),
                bearing_rad: truth.bearing_rad + sensor.bearing_sigma_rad * g(&mut rng),
                elevation_rad: truth.elevation_rad + sensor.elevation_sigma_rad * g(&mut rng),
            };
            let c = noisy.to_cartesian();
            mean += c;
            samples.push(c);
        }
        mean /= n as f64;
        let mut cov = Matrix3::zeros();
        for c in &samples {
            let d = c - mean;
            cov += d * d.transpose();
        }
        cov /= (n - 1) as f64;
        let predicted = sensor.converted_covariance(&truth);
        for i in 0..3 {
            for j in 0..3 {
                let scale = (predicted[(i, i)] * predicted[(j, j)]).sqrt();
                let err = (cov[(i, j)] - predicted[(i, j)]).abs() / scale;
                assert!(
                    err < 0.02,
                    "({i},{j}): MC {} vs {}",
                    cov[(i, j)],
                    predicted[(i, j)]
                );
            }
        }
        // And the cross-axis correlation is real, not rounding.
        let corr = predicted[(0, 1)] / (predicted[(0, 0)] * predicted[(1, 1)]).sqrt();
        assert!(corr.abs() > 0.3, "correlation {corr}");
    }
}
