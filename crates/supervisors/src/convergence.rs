//! Spec 10's Cramér–Rao convergence criterion and the switch it drives.
//!
//! With the state split into observed states H (the first `observed`) and
//! the rest M, paper eq. 4:
//!
//! `δ(n) = tr(K_M(n) P_HM,e(n)) / tr(P_Γ,M(n))`
//!
//! The numerator is the reduction of `tr P_M` the update at step n achieved
//! (`P = P_e − K H P_e` with H = [I 0]); the denominator the Cramér–Rao bound
//! of the M block. δ is "how much one more fix still teaches about M,
//! relative to the best achievable".
//!
//! The transient: with `P_HM(0) = 0` the first updates cannot reduce `P_M`,
//! so δ starts near zero for a reason unrelated to convergence, then rises
//! and falls — in humps, one per group of instrument errors that becomes
//! observable. [`ConvergenceSwitch`] therefore arms only after a minimum
//! fusion time, (optionally) once δ has risen above the threshold, and once
//! δ has not increased for `falling_s` seconds; it switches when δ ≤
//! threshold for `confirm_epochs` epochs in a row.
//!
//! ```
//! use aidnav_supervisors::convergence::{ConvergenceSwitch, SwitchRule};
//! let mut s = ConvergenceSwitch::new(SwitchRule {
//!     threshold: 0.03,
//!     require_rise: true,
//!     ..SwitchRule::default()
//! });
//! // Transient: small δ before it ever rose — not armed.
//! assert!(!s.observe(0.15, 0.001));
//! for (k, d) in [0.2, 0.1, 0.02, 0.02, 0.02, 0.02, 0.02].iter().enumerate() {
//!     let fired = s.observe(0.3 + 0.15 * k as f64, *d);
//!     assert_eq!(fired, k == 6); // the fifth epoch at or below 3 %
//! }
//! assert_eq!(s.switch_time(), Some(0.3 + 0.15 * 6.0));
//! ```

use aidnav_estimation::nalgebra::{DefaultAllocator, Dim, OMatrix, allocator::Allocator};
use serde::{Deserialize, Serialize};

/// δ(n) of paper eq. 4 from the gain K (n×m, H = [I_m 0]), the predicted
/// covariance P_e and the Cramér–Rao bound P_Γ (both n×n); the observed
/// states are the first `observed` ones.
pub fn cramer_rao_ratio<N: Dim, M: Dim>(
    gain: &OMatrix<f64, N, M>,
    predicted: &OMatrix<f64, N, N>,
    bound: &OMatrix<f64, N, N>,
    observed: usize,
) -> f64
where
    DefaultAllocator: Allocator<N, M> + Allocator<N, N>,
{
    let n = predicted.nrows();
    let mut reduction = 0.0;
    for i in observed..n {
        for j in 0..observed {
            reduction += gain[(i, j)] * predicted[(j, i)];
        }
    }
    let bound_trace: f64 = (observed..n).map(|i| bound[(i, i)]).sum();
    reduction / bound_trace
}

/// When the switch may fire.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SwitchRule {
    /// δ_thr. Default 0.03.
    pub threshold: f64,
    /// Not before this fusion time \[s\]. Default 0.
    pub arm_after_s: f64,
    /// Only after δ has once exceeded the threshold. Default false.
    pub require_rise: bool,
    /// Only once δ has not increased for this long \[s\] (0: no such
    /// condition). Default 0.
    pub falling_s: f64,
    /// Consecutive epochs with δ ≤ δ_thr needed. Default 5.
    pub confirm_epochs: usize,
}

impl Default for SwitchRule {
    fn default() -> Self {
        Self {
            threshold: 0.03,
            arm_after_s: 0.0,
            require_rise: false,
            falling_s: 0.0,
            confirm_epochs: 5,
        }
    }
}

/// The switch of paper eq. 5 with the arming of [`SwitchRule`].
#[derive(Debug, Clone, PartialEq)]
pub struct ConvergenceSwitch {
    rule: SwitchRule,
    risen: bool,
    below: usize,
    switched: Option<f64>,
    previous: f64,
    falling_since: f64,
}

impl ConvergenceSwitch {
    /// A switch that has not fired.
    pub fn new(rule: SwitchRule) -> Self {
        Self {
            rule,
            risen: false,
            below: 0,
            switched: None,
            previous: f64::INFINITY,
            falling_since: 0.0,
        }
    }

    /// The rule.
    pub fn rule(&self) -> &SwitchRule {
        &self.rule
    }

    /// Feed δ at fusion time `fusion_s` (since fixes started); true exactly
    /// at the epoch the switch fires.
    pub fn observe(&mut self, fusion_s: f64, delta: f64) -> bool {
        if self.switched.is_some() {
            return false;
        }
        if delta > self.rule.threshold {
            self.risen = true;
        }
        if delta > self.previous {
            self.falling_since = fusion_s;
        }
        self.previous = delta;
        let falling = fusion_s - self.falling_since >= self.rule.falling_s;
        let armed =
            fusion_s >= self.rule.arm_after_s && (self.risen || !self.rule.require_rise) && falling;
        if armed && delta <= self.rule.threshold {
            self.below += 1;
        } else {
            self.below = 0;
        }
        if self.below >= self.rule.confirm_epochs.max(1) {
            self.switched = Some(fusion_s);
            return true;
        }
        false
    }

    /// Fusion time at which the switch fired.
    pub fn switch_time(&self) -> Option<f64> {
        self.switched
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_estimation::KalmanFilter;
    use aidnav_estimation::nalgebra::{Matrix1x2, Matrix2, Vector1, Vector2};

    /// δ's numerator is the reduction of tr P_M achieved by the update.
    #[test]
    fn numerator_is_the_reduction_of_the_unobserved_trace() {
        // State (observed h, hidden m) with a correlated prior.
        let p0 = Matrix2::new(4.0, 1.5, 1.5, 2.0);
        let mut kf = KalmanFilter::new(Vector2::zeros(), p0).unwrap();
        let rec = kf
            .update(
                &Vector1::new(1.0),
                &Matrix1x2::new(1.0, 0.0),
                &aidnav_estimation::nalgebra::Matrix1::new(1.0),
            )
            .unwrap();
        let reduction = p0[(1, 1)] - kf.covariance()[(1, 1)];
        let bound = Matrix2::identity();
        let delta = cramer_rao_ratio(&rec.gain, &p0, &bound, 1);
        assert!((delta - reduction).abs() < 1e-12);
    }

    #[test]
    fn minimum_time_arms_without_a_rise() {
        let mut s = ConvergenceSwitch::new(SwitchRule {
            threshold: 0.01,
            arm_after_s: 1.0,
            confirm_epochs: 1,
            ..SwitchRule::default()
        });
        assert!(!s.observe(0.5, 0.0));
        assert!(s.observe(1.0, 0.0));
        assert!(!s.observe(1.5, 0.0));
    }

    #[test]
    fn a_new_hump_disarms_until_delta_has_fallen_long_enough() {
        let mut s = ConvergenceSwitch::new(SwitchRule {
            threshold: 0.03,
            falling_s: 2.0,
            confirm_epochs: 1,
            ..SwitchRule::default()
        });
        // Falls for 1 s, rises (a new hump), then falls for good.
        let deltas = [
            0.02, 0.015, 0.01, 0.02, 0.025, 0.02, 0.015, 0.01, 0.008, 0.006,
        ];
        let fired: Vec<bool> = deltas
            .iter()
            .enumerate()
            .map(|(k, &d)| s.observe(0.5 * k as f64, d))
            .collect();
        // Rise at 2.0 s (0.01 → 0.02) and at 2.0 → 2.5 s; falling from 2.0 s
        // is last reset at 2.0 s; 2 s later is 4.0 s (index 8).
        assert_eq!(fired.iter().position(|&f| f), Some(8));
    }
}
