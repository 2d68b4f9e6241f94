//! The launch frame of spec 10 (seed 000): origin at the launch point, fixed
//! in inertial space at lift-off (Earth rotation neglected, as in the paper),
//! `Y` up along the local vertical, `X` horizontal along the reference azimuth
//! (course 0), `Z` completing the right-handed triad.
//!
//! [`LaunchAttitude::orientation`] is the paper's matrix D (rows: body axes
//! in the launch frame, `x_B = D x_L`) with yaw ψ, pitch ϑ, roll γ; its
//! element d31 carries a plus sign (the OCR's minus makes D non-orthogonal).
//! [`central_gravity`] is the point-mass field with the Earth's centre at
//! `−R_E e_y`.
//!
//! ```
//! use aidnav_frames::launch::{LaunchAttitude, central_gravity};
//! use nalgebra::Vector3;
//! // Pitch 90°: the body X1 axis points straight up (row 1 of D).
//! let d = LaunchAttitude { yaw: 0.3, pitch: std::f64::consts::FRAC_PI_2, roll: 0.0 }.orientation();
//! assert!((d.row(0).transpose() - Vector3::y()).norm() < 1e-15);
//! // At the origin gravity points down with μ / R_E².
//! let g = central_gravity(&Vector3::zeros());
//! assert!((g.y + 9.82).abs() < 0.01 && g.x == 0.0);
//! ```

use nalgebra::{Matrix3, Vector3};

use crate::constants::{EARTH_MEAN_RADIUS_M, GM_M3_S2};

/// Yaw ψ, pitch ϑ, roll γ of the body in the launch frame \[rad\].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LaunchAttitude {
    /// Yaw ψ (a course φ corresponds to ψ = −φ).
    pub yaw: f64,
    /// Pitch ϑ, the angle of the body X1 axis above the horizontal.
    pub pitch: f64,
    /// Roll γ.
    pub roll: f64,
}

impl LaunchAttitude {
    /// The orientation matrix D (`x_B = D x_L`).
    pub fn orientation(&self) -> Matrix3<f64> {
        Self::orientation_from_sin_cos(
            self.yaw.sin_cos(),
            self.pitch.sin_cos(),
            self.roll.sin_cos(),
        )
    }

    /// [`orientation`](Self::orientation) from the (sine, cosine) of yaw,
    /// pitch and roll, for a caller that already holds some of them (the
    /// same arithmetic, so the same matrix).
    #[inline]
    pub fn orientation_from_sin_cos(
        (sp, cp): (f64, f64),
        (st, ct): (f64, f64),
        (sg, cg): (f64, f64),
    ) -> Matrix3<f64> {
        Matrix3::new(
            cp * ct,
            st,
            -sp * ct,
            sp * sg - cp * st * cg,
            ct * cg,
            cp * sg + sp * st * cg,
            sp * cg + cp * st * sg,
            -ct * sg,
            cp * cg - sp * st * sg,
        )
    }

    /// ∂D/∂ψ, ∂D/∂ϑ, ∂D/∂γ.
    pub fn orientation_partials(&self) -> [Matrix3<f64>; 3] {
        let (sp, cp) = self.yaw.sin_cos();
        let (st, ct) = self.pitch.sin_cos();
        let (sg, cg) = self.roll.sin_cos();
        let d_yaw = Matrix3::new(
            -sp * ct,
            0.0,
            -cp * ct,
            cp * sg + sp * st * cg,
            0.0,
            -sp * sg + cp * st * cg,
            cp * cg - sp * st * sg,
            0.0,
            -sp * cg - cp * st * sg,
        );
        let d_pitch = Matrix3::new(
            -cp * st,
            ct,
            sp * st,
            -cp * ct * cg,
            -st * cg,
            sp * ct * cg,
            cp * ct * sg,
            st * sg,
            -sp * ct * sg,
        );
        let d_roll = Matrix3::new(
            0.0,
            0.0,
            0.0,
            sp * cg + cp * st * sg,
            -ct * sg,
            cp * cg - sp * st * sg,
            -sp * sg + cp * st * cg,
            -ct * cg,
            -cp * sg - sp * st * cg,
        );
        [d_yaw, d_pitch, d_roll]
    }

    /// The attitude whose body X1 axis points along `direction` (launch
    /// frame), with zero roll.
    pub fn along(direction: &Vector3<f64>) -> Self {
        let horizontal = direction.x.hypot(direction.z);
        Self {
            yaw: (-direction.z).atan2(direction.x),
            pitch: direction.y.atan2(horizontal),
            roll: 0.0,
        }
    }
}

/// Central gravity at launch-frame position r: `−μ (r + R_E e_y) / |r + R_E e_y|³`.
#[inline]
pub fn central_gravity(r: &Vector3<f64>) -> Vector3<f64> {
    let from_centre = r + Vector3::new(0.0, EARTH_MEAN_RADIUS_M, 0.0);
    let d = from_centre.norm();
    -from_centre * (GM_M3_S2 / (d * d * d))
}

/// ∂g/∂r of [`central_gravity`] (the gravity gradient).
pub fn gravity_gradient(r: &Vector3<f64>) -> Matrix3<f64> {
    let from_centre = r + Vector3::new(0.0, EARTH_MEAN_RADIUS_M, 0.0);
    let d = from_centre.norm();
    let u = from_centre / d;
    (3.0 * u * u.transpose() - Matrix3::identity()) * (GM_M3_S2 / (d * d * d))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attitudes() -> Vec<LaunchAttitude> {
        let mut v = Vec::new();
        for &yaw in &[0.0, -0.5, 0.87, 2.5] {
            for &pitch in &[0.0, 0.4, 1.2, -0.3] {
                for &roll in &[0.0, 0.25, -1.1] {
                    v.push(LaunchAttitude { yaw, pitch, roll });
                }
            }
        }
        v
    }

    #[test]
    fn orientation_is_a_rotation() {
        for a in attitudes() {
            let d = a.orientation();
            assert!((d * d.transpose() - Matrix3::identity()).norm() < 1e-14);
            assert!((d.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn partials_match_finite_differences() {
        let h = 1e-6;
        for a in attitudes() {
            let partials = a.orientation_partials();
            for (k, analytic) in partials.iter().enumerate() {
                let shifted = |s: f64| {
                    let mut b = a;
                    match k {
                        0 => b.yaw += s,
                        1 => b.pitch += s,
                        _ => b.roll += s,
                    }
                    b.orientation()
                };
                let fd = (shifted(h) - shifted(-h)) / (2.0 * h);
                assert!((fd - analytic).norm() < 1e-9, "{a:?} angle {k}");
            }
        }
    }

    #[test]
    fn along_points_the_body_axis() {
        for dir in [
            Vector3::new(1.0, 0.2, 0.0),
            Vector3::new(0.5, 0.9, 0.5),
            Vector3::new(-0.3, 0.1, -0.8),
        ] {
            let d = LaunchAttitude::along(&dir).orientation();
            let x1 = d.row(0).transpose();
            assert!((x1 - dir.normalize()).norm() < 1e-14);
        }
        // Course 30° (x = r cos φ, z = r sin φ) is yaw −30°.
        let a = LaunchAttitude::along(&Vector3::new(
            30f64.to_radians().cos(),
            0.0,
            30f64.to_radians().sin(),
        ));
        assert!((a.yaw + 30f64.to_radians()).abs() < 1e-14);
    }

    #[test]
    fn gravity_gradient_matches_finite_differences() {
        let r = Vector3::new(300e3, 150e3, -80e3);
        let g = gravity_gradient(&r);
        for k in 0..3 {
            let mut e = Vector3::zeros();
            e[k] = 1.0;
            let fd = (central_gravity(&(r + e)) - central_gravity(&(r - e))) / 2.0;
            assert!((fd - g.column(k)).norm() < 1e-12);
        }
    }
}
