//! Spec 30's axis-decoupled group model (seed 002, "Complex model of the
//! navigation information processing system of a group of dynamic objects"):
//! one coordinate axis of M vehicles, fused with their own position fixes and
//! the relative positions measured between members.
//!
//! State `X = (R¹, V¹, R², V², …, R^M, V^M)`; per step T
//! `R^l ← R^l + V^l T`, `V^l ← V^l + a_R T w^l` (w standard normal), so
//! `Q = diag(0, (a_R T)²)` per member. Observations, in this order:
//! own positions `z^l = R^l + n` (σ_own), optionally own velocities
//! (σ_vel), and one relative observation per *ordered* pair l ≠ k,
//! `z^{lk} = R^l − R^k + n^{lk}` (σ_rel), as in the paper's worked example.
//! The paper treats z^{lk} and z^{kl} as independent measurements (two
//! sensors, one on each vehicle); so does this model.
//!
//! ```
//! use aidnav_models::AxisGroup;
//! let g = AxisGroup { members: 3, relative_sigma_m: Some(1.0), ..AxisGroup::default() };
//! let (h, r) = g.measurement();
//! assert_eq!((h.nrows(), h.ncols()), (3 + 6, 6)); // 3 own + 3·2 ordered pairs
//! assert_eq!(r[(3, 3)], 1.0);
//! ```

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// One axis of a group of M vehicles (paper defaults: T = 1 s, σ_own = 10 m,
/// a_R = 1 m/s², no relative sensors).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AxisGroup {
    /// Number of members M ≥ 1. Default 1.
    pub members: usize,
    /// Step T \[s\]. Default 1.
    pub dt_s: f64,
    /// Acceleration disturbance a_R [m/s²]. Default 1.
    pub accel_sigma_m_s2: f64,
    /// σ of each member's own position fix \[m\]. Default 10.
    pub own_position_sigma_m: f64,
    /// σ of each member's own velocity fix [m/s]; none: not observed. Default none.
    pub own_velocity_sigma_mps: Option<f64>,
    /// σ of each relative position \[m\]; none: no relative sensors. Default none.
    pub relative_sigma_m: Option<f64>,
}

impl Default for AxisGroup {
    fn default() -> Self {
        Self {
            members: 1,
            dt_s: 1.0,
            accel_sigma_m_s2: 1.0,
            own_position_sigma_m: 10.0,
            own_velocity_sigma_mps: None,
            relative_sigma_m: None,
        }
    }
}

impl AxisGroup {
    /// Number of states, 2M.
    pub fn states(&self) -> usize {
        2 * self.members
    }

    /// The ordered pairs (l, k), l ≠ k, in the order of the relative rows
    /// (empty without relative sensors).
    pub fn relative_pairs(&self) -> Vec<(usize, usize)> {
        if self.relative_sigma_m.is_none() {
            return Vec::new();
        }
        let m = self.members;
        (0..m)
            .flat_map(|l| (0..m).filter(move |&k| k != l).map(move |k| (l, k)))
            .collect()
    }

    /// Φ: a constant-velocity block per member.
    pub fn transition(&self) -> DMatrix<f64> {
        let mut phi = DMatrix::identity(self.states(), self.states());
        for l in 0..self.members {
            phi[(2 * l, 2 * l + 1)] = self.dt_s;
        }
        phi
    }

    /// Q = diag(0, (a_R T)²) per member.
    pub fn process_noise(&self) -> DMatrix<f64> {
        let v = (self.accel_sigma_m_s2 * self.dt_s).powi(2);
        DMatrix::from_diagonal(&DVector::from_fn(self.states(), |i, _| {
            if i % 2 == 1 { v } else { 0.0 }
        }))
    }

    /// H and R for one epoch with every observation present.
    pub fn measurement(&self) -> (DMatrix<f64>, DMatrix<f64>) {
        let m = self.members;
        let pairs = self.relative_pairs();
        let velocity_rows = if self.own_velocity_sigma_mps.is_some() {
            m
        } else {
            0
        };
        let rows = m + velocity_rows + pairs.len();
        let mut h = DMatrix::zeros(rows, self.states());
        let mut r = DVector::zeros(rows);
        for l in 0..m {
            h[(l, 2 * l)] = 1.0;
            r[l] = self.own_position_sigma_m.powi(2);
        }
        if let Some(s) = self.own_velocity_sigma_mps {
            for l in 0..m {
                h[(m + l, 2 * l + 1)] = 1.0;
                r[m + l] = s * s;
            }
        }
        if let Some(s) = self.relative_sigma_m {
            for (i, &(l, k)) in pairs.iter().enumerate() {
                let row = m + velocity_rows + i;
                h[(row, 2 * l)] = 1.0;
                h[(row, 2 * k)] = -1.0;
                r[row] = s * s;
            }
        }
        (h, DMatrix::from_diagonal(&r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_rows_difference_two_members() {
        let g = AxisGroup {
            members: 3,
            own_velocity_sigma_mps: Some(2.0),
            relative_sigma_m: Some(0.5),
            ..AxisGroup::default()
        };
        let (h, r) = g.measurement();
        assert_eq!(h.nrows(), 3 + 3 + 6);
        assert_eq!(g.relative_pairs()[0], (0, 1));
        // Row of pair (0, 1): +R¹ − R².
        assert_eq!(
            h.row(6).iter().copied().collect::<Vec<_>>(),
            [1.0, 0.0, -1.0, 0.0, 0.0, 0.0]
        );
        assert_eq!(r[(4, 4)], 4.0);
        assert_eq!(r[(6, 6)], 0.25);
        let phi = g.transition();
        assert_eq!(phi[(2, 3)], 1.0);
        assert_eq!(g.process_noise()[(3, 3)], 1.0);
        assert_eq!(g.process_noise()[(2, 2)], 0.0);
    }
}
