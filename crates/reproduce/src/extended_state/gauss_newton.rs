//! Beyond the paper: the fusion interval as a batch estimation problem.
//! With Q = 0 the fixes from the fusion start to the switch depend on 14
//! numbers only — the INS position and velocity errors at the first fix
//! (θ_H) and the eight instrument errors (θ_M) — through the nonlinear INS.
//! Gauss–Newton minimises
//!
//! `J(θ) = Σ_n (y_n(θ) − z_n)ᵀ R⁻¹ (y_n(θ) − z_n) + θᵀ P(0)⁻¹ θ`
//!
//! (y_n(θ): the INS started at its first-fix state minus θ_H and flown with
//! the instrument outputs corrected by θ_M; z_n: the fixes; the prior is the
//! filter's), re-linearising at every iterate: the Jacobian ∂y_n/∂θ is
//! propagated along the re-flown INS with the error model's A(t) evaluated
//! at the corrected outputs (plus the gravity gradient the paper's model
//! neglects), so no linearisation about the uncorrected outputs remains.

use super::filter::{Fix, filter_matrices};
use super::*;
use aidnav_estimation::{Matrix as MatrixName, Step};
use aidnav_frames::constants::{EARTH_MEAN_RADIUS_M, GM_M3_S2};
use nalgebra::Matrix3;

/// The result of a Gauss–Newton estimate.
#[derive(Debug, Clone)]
#[cfg_attr(not(test), allow(dead_code))] // θ and J are read by the tests
pub(super) struct BatchEstimate {
    /// θ = (INS error at the first fix, instrument errors).
    pub(super) parameters: SVector<f64, STATES>,
    /// J(θ) at every iterate, starting with the initial guess (the last
    /// only when asked for).
    pub(super) costs: Vec<f64>,
    /// |Δx(t_B)| of the INS flown with the estimate to t_B \[m\].
    pub(super) error_m: f64,
}

/// ∂g/∂r of the central gravity at r (launch frame).
fn gravity_gradient(r: &Vector3<f64>) -> Matrix3<f64> {
    let rho = r + Vector3::new(0.0, EARTH_MEAN_RADIUS_M, 0.0);
    let d = rho.norm();
    let u = rho / d;
    let mu_over_d3 = GM_M3_S2 / (d * d * d);
    (u * u.transpose() * 3.0 - Matrix3::identity()) * mu_over_d3
}

/// What parameters θ say: the instrument correction of its instrument
/// part, and the INS at the first fix with its position and velocity
/// errors (θ's first six) removed.
fn apply_parameters(
    start: &LaunchIns,
    theta: &SVector<f64, STATES>,
) -> (LaunchInstrumentErrors, LaunchIns) {
    let m: [f64; ESTIMATED] = std::array::from_fn(|i| theta[NAVIGATION + i]);
    let mut ins = *start;
    for i in 0..3 {
        ins.position[i] -= theta[i];
        ins.velocity[i] -= theta[3 + i];
    }
    (LaunchInstrumentErrors::from_estimate(&m), ins)
}

/// The INS of parameters θ flown from the first fix to the last of
/// `fixes`: J(θ), the normal matrix `P(0)⁻¹ + Σ Hᵀ R⁻¹ H` and the
/// right-hand side `−(Σ Hᵀ R⁻¹ ν + P(0)⁻¹ θ)`, with ν = y − z and
/// H = ∂y/∂θ.
#[allow(clippy::type_complexity)]
fn linearise(
    flight: &Flight<'_>,
    start: &LaunchIns,
    fixes: &[Fix],
    theta: &SVector<f64, STATES>,
    prior_information: &Matrix14,
    r_inv: &SMatrix<f64, NAVIGATION, NAVIGATION>,
) -> (f64, Matrix14, SVector<f64, STATES>) {
    let dt = flight.traj.dt_s;
    let (correction, mut ins) = apply_parameters(start, theta);
    // ∂(position, velocity)/∂θ.
    let mut jr = SMatrix::<f64, 3, STATES>::zeros();
    let mut jv = SMatrix::<f64, 3, STATES>::zeros();
    for i in 0..3 {
        jr[(i, i)] = -1.0;
        jv[(i, 3 + i)] = -1.0;
    }
    let scale = 1.0 / (1.0 + theta[NAVIGATION + 3]);
    let mut cost = (theta.transpose() * prior_information * theta)[0];
    let mut normal = *prior_information;
    let mut rhs = -(prior_information * theta);
    let mut add_fix =
        |fix: &Fix, ins: &LaunchIns, jr: &SMatrix<f64, 3, STATES>, jv: &SMatrix<f64, 3, STATES>| {
            let mut nu = SVector::<f64, NAVIGATION>::zeros();
            let mut h = SMatrix::<f64, NAVIGATION, STATES>::zeros();
            for i in 0..3 {
                nu[i] = ins.position[i] - fix.measured[i];
                nu[3 + i] = ins.velocity[i] - fix.measured[3 + i];
            }
            h.fixed_rows_mut::<3>(0).copy_from(jr);
            h.fixed_rows_mut::<3>(3).copy_from(jv);
            let ht_r = h.transpose() * r_inv;
            cost += (nu.transpose() * r_inv * nu)[0];
            normal += ht_r * h;
            rhs -= ht_r * nu;
        };
    let mut thrust = EstimateThrust::new(flight, &correction);
    let (first, rest) = fixes.split_first().expect("at least one fix");
    add_fix(first, &ins, &jr, &jv);
    let mut k = first.step;
    for fix in rest {
        // The Jacobian over the interval between fixes, with A at its
        // midpoint's corrected outputs (stored at the RK4 times) and the
        // gravity gradient at the mean of its end positions: a step of
        // 0.15 s, far below the time A and G change on.
        let span = fix.step - k;
        let (mid, half) = (k + (span - 1) / 2, span % 2);
        let tau = (mid as f64 + 0.5 * half as f64) * dt;
        let (att, f) = &flight.outputs[mid][half];
        let (att, f) = correction.correct(tau, att, f);
        let a = ExtendedStateModel::continuous(tau, &att, &f);
        // The INS acceleration's derivative by θ_M: −(the error model's
        // columns), with ∂f/∂Δa_x and ∂f/∂K_x carrying 1/(1 + K̂_x).
        let mut b = SMatrix::<f64, 3, STATES>::zeros();
        for j in 0..ESTIMATED {
            let factor = if j == 0 || j == 3 { scale } else { 1.0 };
            for i in 0..3 {
                b[(i, NAVIGATION + j)] = -a[(3 + i, NAVIGATION + j)] * factor;
            }
        }
        let from = ins.position;
        while k < fix.step {
            ins.step_with_thrust(dt, &thrust.at(k));
            k += 1;
        }
        let g = gravity_gradient(&((from + ins.position) * 0.5));
        let h = span as f64 * dt;
        let accel = g * jr + b;
        let new_jr = jr + jv * h + accel * (h * h / 2.0);
        let new_jv = jv + accel * h + g * jv * (h * h / 2.0);
        jr = new_jr;
        jv = new_jv;
        add_fix(fix, &ins, &jr, &jv);
    }
    (cost, normal, rhs)
}

/// Gauss–Newton over `fixes` (the first one received by the INS state
/// `start`, before any update), from the instrument errors `initial` (the
/// filter's estimate), at most `max_iterations` steps; stops when a step
/// changes J by less than 1e-6 (its predicted decrease, Δᵀ N Δ). Then flies
/// the estimate to t_B. `final_cost`: also evaluate J at the final
/// estimate (one more flight over the interval; the tests read it).
pub(super) fn gauss_newton(
    sc: &ExtendedStateScenario,
    flight: &Flight<'_>,
    start: &LaunchIns,
    fixes: &[Fix],
    initial: &[f64; ESTIMATED],
    max_iterations: usize,
    final_cost: bool,
) -> Result<BatchEstimate, EstimationError> {
    let (p0, r, _) = filter_matrices(sc);
    let not_pd = |matrix| EstimationError::NotPositiveDefinite {
        step: Step::Update,
        matrix,
    };
    let prior_information = p0.try_inverse().ok_or(not_pd(MatrixName::P))?;
    let r_inv = r.try_inverse().ok_or(not_pd(MatrixName::R))?;
    let mut theta = SVector::<f64, STATES>::zeros();
    for i in 0..ESTIMATED {
        theta[NAVIGATION + i] = initial[i];
    }
    let mut costs = Vec::new();
    for _ in 0..max_iterations {
        let (cost, normal, rhs) =
            linearise(flight, start, fixes, &theta, &prior_information, &r_inv);
        if !cost.is_finite() {
            return Err(EstimationError::NonFinite {
                step: Step::Update,
                matrix: MatrixName::Innovation,
            });
        }
        costs.push(cost);
        let step = normal
            .cholesky()
            .ok_or(not_pd(MatrixName::Information))?
            .solve(&rhs);
        theta += step;
        if (step.transpose() * normal * step)[0] < 1e-6 {
            break;
        }
    }
    if final_cost {
        costs.push(linearise(flight, start, fixes, &theta, &prior_information, &r_inv).0);
    }
    let (correction, ins) = apply_parameters(start, &theta);
    let error_m = flight.fly(
        Correction::Estimate(&correction),
        ins,
        fixes[0].step,
        |_, _| {},
    );
    Ok(BatchEstimate {
        parameters: theta,
        costs,
        error_m,
    })
}
