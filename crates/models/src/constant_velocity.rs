//! One axis of a constant-velocity (white-noise acceleration) model.
//!
//! State (position, velocity); acceleration is white noise of power spectral
//! density `q` [m²/s³]. Exact discretisation (Bar-Shalom et al., §6.2.2):
//! `Φ = [[1, T], [0, 1]]`, `Q = q [[T³/3, T²/2], [T²/2, T]]`.

use nalgebra::{Matrix1, Matrix1x2, Matrix2};

/// Constant-velocity model of one axis.
///
/// ```
/// use aidnav_models::ConstantVelocity;
/// let cv = ConstantVelocity::new(2.0, 0.5).unwrap();
/// assert_eq!(cv.transition()[(0, 1)], 2.0);
/// assert!((cv.process_noise()[(0, 0)] - 0.5 * 8.0 / 3.0).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConstantVelocity {
    dt_s: f64,
    accel_psd: f64,
}

impl ConstantVelocity {
    /// Sampling period `dt_s` > 0 \[s\] and acceleration PSD `accel_psd` ≥ 0 [m²/s³].
    /// Returns `None` for a non-positive or non-finite period or a negative PSD.
    pub fn new(dt_s: f64, accel_psd: f64) -> Option<Self> {
        (dt_s.is_finite() && dt_s > 0.0 && accel_psd.is_finite() && accel_psd >= 0.0)
            .then_some(Self { dt_s, accel_psd })
    }

    /// Sampling period \[s\].
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Φ = [[1, T], [0, 1]].
    pub fn transition(&self) -> Matrix2<f64> {
        Matrix2::new(1.0, self.dt_s, 0.0, 1.0)
    }

    /// Q = q [[T³/3, T²/2], [T²/2, T]].
    pub fn process_noise(&self) -> Matrix2<f64> {
        let t = self.dt_s;
        Matrix2::new(t.powi(3) / 3.0, t * t / 2.0, t * t / 2.0, t) * self.accel_psd
    }

    /// Position measurement H = [1, 0], R = σ².
    pub fn position_measurement(sigma_m: f64) -> (Matrix1x2<f64>, Matrix1<f64>) {
        (Matrix1x2::new(1.0, 0.0), Matrix1::new(sigma_m * sigma_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn q_is_the_integral_of_the_white_acceleration() {
        // Q = ∫₀ᵀ Φ(s) G q Gᵀ Φ(s)ᵀ ds with G = (0, 1): midpoint rule on a fine grid.
        let cv = ConstantVelocity::new(0.7, 1.3).unwrap();
        let steps = 20_000;
        let h = cv.dt_s() / steps as f64;
        let mut q = Matrix2::zeros();
        for i in 0..steps {
            let s = (i as f64 + 0.5) * h;
            let g = nalgebra::Vector2::new(s, 1.0);
            q += g * g.transpose() * 1.3 * h;
        }
        assert!((q - cv.process_noise()).abs().max() < 1e-8);
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(ConstantVelocity::new(0.0, 1.0).is_none());
        assert!(ConstantVelocity::new(1.0, -1.0).is_none());
        assert!(ConstantVelocity::new(f64::NAN, 1.0).is_none());
    }
}
