//! Bias and scale-factor error of one instrument axis.
//!
//! Measurement model (spec 10): `m = (1 + k) t + b` for a true value t, bias b
//! and scale-factor error k. Correction with estimates (b̂, k̂) inverts it:
//! `t̂ = (m − b̂) / (1 + k̂)`.

use serde::{Deserialize, Serialize};

/// Bias and scale-factor error of one axis.
///
/// ```
/// use aidnav_ins::AxisError;
/// let e = AxisError { bias: 5.01e-2, scale_factor: 2.46e-2 };
/// let m = e.corrupt(9.81);
/// assert!((e.correct(m) - 9.81).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct AxisError {
    /// Additive bias (unit of the measured quantity).
    pub bias: f64,
    /// Scale-factor error k (dimensionless; 0 = perfect).
    pub scale_factor: f64,
}

impl AxisError {
    /// What the instrument outputs for a true value.
    pub fn corrupt(&self, truth: f64) -> f64 {
        (1.0 + self.scale_factor) * truth + self.bias
    }

    /// The true value recovered from an output, with this error as the estimate.
    pub fn correct(&self, measured: f64) -> f64 {
        (measured - self.bias) / (1.0 + self.scale_factor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partial_correction_leaves_the_residual_error() {
        let truth = AxisError {
            bias: 0.05,
            scale_factor: 0.02,
        };
        let estimate = AxisError {
            bias: 0.04,
            scale_factor: 0.02,
        };
        let t = 20.0;
        let left = estimate.correct(truth.corrupt(t)) - t;
        assert!((left - 0.01 / 1.02).abs() < 1e-14);
    }
}
