//! Steady state: the filter's Riccati recursion against the doubling solution.

use aidnav_estimation::nalgebra::{DMatrix, DVector, Matrix1};
use aidnav_estimation::{KalmanFilter, steady_state_covariance};

use crate::common::*;

#[test]
fn scalar_random_walk_closed_form() {
    // p⁻² − q p⁻ − q r = 0  ⇒  p⁻ = (q + √(q² + 4 q r)) / 2.
    for (q, r) in [(1.0, 1.0), (0.01, 4.0), (3.0, 0.2)] {
        let ss = steady_state_covariance(
            &Matrix1::new(1.0),
            &Matrix1::new(1.0),
            &Matrix1::new(q),
            &Matrix1::new(r),
        )
        .unwrap();
        let expected = (q + (q * q + 4.0 * q * r).sqrt()) / 2.0;
        assert!((ss.predicted[(0, 0)] - expected).abs() < 1e-12 * expected);
        let filtered = expected * r / (expected + r);
        assert!((ss.filtered[(0, 0)] - filtered).abs() < 1e-12 * filtered);
    }
}

fn dare_residual(
    phi: &DMatrix<f64>,
    h: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    x: &DMatrix<f64>,
) -> f64 {
    let s = h * x * h.transpose() + r;
    let s_inv = s.try_inverse().unwrap();
    let rhs =
        phi * x * phi.transpose() - phi * x * h.transpose() * s_inv * h * x * phi.transpose() + q;
    (rhs - x).abs().max()
}

#[test]
fn filter_converges_to_the_doubling_solution() {
    // Constant-velocity model plus a random 4-state model with 2 measurements.
    let dt: f64 = 0.5;
    let cv_phi = DMatrix::from_row_slice(2, 2, &[1.0, dt, 0.0, 1.0]);
    let cv_q =
        DMatrix::from_row_slice(2, 2, &[dt.powi(3) / 3.0, dt * dt / 2.0, dt * dt / 2.0, dt]) * 0.2;
    let cv_h = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let cv_r = DMatrix::from_element(1, 1, 4.0);
    let mut g = rng(3);
    let phi4 = random_transition(&mut g, 4) * 0.9;
    let q4 = random_spd(&mut g, 4, 0.05);
    let h4 = random_matrix(&mut g, 2, 4);
    let r4 = random_spd(&mut g, 2, 0.5);
    for (phi, q, h, r) in [(cv_phi, cv_q, cv_h, cv_r), (phi4, q4, h4, r4)] {
        let n = phi.nrows();
        let ss = steady_state_covariance(&phi, &h, &q, &r).unwrap();
        assert!(dare_residual(&phi, &h, &q, &r, &ss.predicted) < 1e-10 * ss.predicted.abs().max());
        let mut kf = KalmanFilter::new(DVector::zeros(n), DMatrix::identity(n, n) * 100.0).unwrap();
        let z = DVector::zeros(h.nrows());
        for _ in 0..3000 {
            kf.predict(&phi, &q).unwrap();
            let prior = kf.covariance().clone();
            kf.update(&z, &h, &r).unwrap();
            let _ = prior;
        }
        let scale = ss.filtered.abs().max();
        assert!(
            max_abs_diff(kf.covariance(), &ss.filtered) < 1e-10 * scale,
            "filtered P differs from DARE: {:e}",
            max_abs_diff(kf.covariance(), &ss.filtered)
        );
        kf.predict(&phi, &q).unwrap();
        assert!(max_abs_diff(kf.covariance(), &ss.predicted) < 1e-10 * scale);
    }
}
