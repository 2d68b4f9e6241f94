//! Spec 10's 14-state error model of a launch-frame INS with its
//! instrument errors (corrected form of paper eq. 3):
//!
//! ```text
//! x = (Δx, Δy, Δz, Δẋ, Δẏ, Δż | Δẍ10, Δÿ10, Δz̈10, K_ẍ1, Δψ0, Δϑ0, ω_ψ, ω_ϑ)
//! d/dt Δr = Δv
//! d/dt Δv = Dᵀ Δa0 + (Dᵀ e1 ẍ1) K_ẍ1 + l_ψ (Δψ0 + ω_ψ t) + l_ϑ (Δϑ0 + ω_ϑ t)
//! d/dt x_M = 0,      l_b = (∂D/∂b)ᵀ f_B,      z = [I6 0] x + f
//! ```
//!
//! Δr, Δv are INS minus true position and velocity; t is flight time. The
//! chain Δr ← Δv ← x_M has length two, so A² A = 0 and for A held over a step
//! `exp(AΔt) = I + AΔt + A²Δt²/2` exactly ([`TransitionForm::Exact`]); the
//! paper uses `I + AΔt` ([`TransitionForm::FirstOrder`]).
//!
//! ```
//! use aidnav_frames::launch::LaunchAttitude;
//! use aidnav_models::extended_state::{ExtendedStateModel, TransitionForm};
//! use nalgebra::Vector3;
//! let att = LaunchAttitude { yaw: 0.0, pitch: 0.5, roll: 0.0 };
//! let a = ExtendedStateModel::continuous(30.0, &att, &Vector3::new(30.0, 0.0, 0.0));
//! // Velocity error from the x accelerometer bias: the body X1 axis in L.
//! assert!((a[(4, 6)] - 0.5f64.sin()).abs() < 1e-15);
//! let phi = ExtendedStateModel::transition(&a, 0.15, TransitionForm::Exact);
//! assert!((phi[(1, 6)] - 0.5f64.sin() * 0.15 * 0.15 / 2.0).abs() < 1e-15);
//! ```

use aidnav_frames::launch::LaunchAttitude;
use nalgebra::{SMatrix, Vector3};
use serde::{Deserialize, Serialize};

/// Number of states.
pub const STATES: usize = 14;
/// Number of observed (navigation) states.
pub const NAVIGATION: usize = 6;
/// Number of instrument-error states.
pub const INSTRUMENTS: usize = 8;

/// 14×14 matrix.
pub type Matrix14 = SMatrix<f64, STATES, STATES>;
/// 6×14 measurement matrix.
pub type Matrix6x14 = SMatrix<f64, NAVIGATION, STATES>;

/// How Φ is formed from A over a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TransitionForm {
    /// The paper's `Φ = I + A Δt`.
    FirstOrder,
    /// `I + A Δt + A² Δt² / 2`, exact for A constant over the step.
    Exact,
}

/// The model's matrices; stateless.
#[derive(Debug, Clone, Copy)]
pub struct ExtendedStateModel;

impl ExtendedStateModel {
    /// A(t) at flight time t, attitude D(ψ, ϑ, γ) and body specific force f_B.
    pub fn continuous(t: f64, attitude: &LaunchAttitude, force: &Vector3<f64>) -> Matrix14 {
        let mut a = Matrix14::zeros();
        for i in 0..3 {
            a[(i, 3 + i)] = 1.0;
        }
        let dt = attitude.orientation().transpose();
        let [d_yaw, d_pitch, _] = attitude.orientation_partials();
        let l_yaw = d_yaw.transpose() * force;
        let l_pitch = d_pitch.transpose() * force;
        a.fixed_view_mut::<3, 3>(3, 6).copy_from(&dt);
        let scale = dt.column(0) * force.x;
        let columns = [scale, l_yaw, l_pitch, l_yaw * t, l_pitch * t];
        for (j, c) in columns.iter().enumerate() {
            a.fixed_view_mut::<3, 1>(3, 9 + j).copy_from(c);
        }
        a
    }

    /// Φ over Δt from A (see [`TransitionForm`]).
    pub fn transition(a: &Matrix14, dt: f64, form: TransitionForm) -> Matrix14 {
        let adt = a * dt;
        match form {
            TransitionForm::FirstOrder => Matrix14::identity() + adt,
            TransitionForm::Exact => Matrix14::identity() + adt + adt * adt * 0.5,
        }
    }

    /// C = [I6 0].
    pub fn measurement() -> Matrix6x14 {
        let mut c = Matrix6x14::zeros();
        for i in 0..NAVIGATION {
            c[(i, i)] = 1.0;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_transition_is_the_matrix_exponential() {
        let att = LaunchAttitude {
            yaw: -0.5,
            pitch: 0.7,
            roll: 0.0,
        };
        let a = ExtendedStateModel::continuous(120.0, &att, &Vector3::new(40.0, 0.0, 0.0));
        // A is nilpotent of index 3.
        assert!((a * a * a).abs().max() == 0.0);
        let mut exp = Matrix14::identity();
        let mut term = Matrix14::identity();
        for k in 1..10 {
            term = term * a * (0.15 / k as f64);
            exp += term;
        }
        let phi = ExtendedStateModel::transition(&a, 0.15, TransitionForm::Exact);
        assert!((phi - exp).abs().max() < 1e-12);
        let first = ExtendedStateModel::transition(&a, 0.15, TransitionForm::FirstOrder);
        assert!((first - exp).abs().max() > 1e-3); // misses the Δr ← x_M term
    }
}
