//! Information form and the Cramér–Rao recursion against the covariance form.

use aidnav_estimation::nalgebra::{DMatrix, DVector};
use aidnav_estimation::{FisherInformation, InformationFilter, KalmanFilter};

use crate::common::*;

#[test]
fn information_filter_equals_kalman_filter() {
    let mut g = rng(21);
    let n = 5;
    let phi = random_transition(&mut g, n);
    let q = random_spd(&mut g, n, 0.01) * 0.1;
    let h = random_matrix(&mut g, 2, n);
    let r = random_spd(&mut g, 2, 0.3);
    let p0 = random_spd(&mut g, n, 1.0);
    let x0 = random_vector(&mut g, n);
    let mut kf = KalmanFilter::new(x0.clone(), p0.clone()).unwrap();
    let mut inf = InformationFilter::from_covariance(&x0, &p0).unwrap();
    for _ in 0..30 {
        let z = random_vector(&mut g, 2);
        kf.predict(&phi, &q).unwrap();
        inf.predict(&phi, &q).unwrap();
        kf.update(&z, &h, &r).unwrap();
        inf.update(&z, &h, &r).unwrap();
        let (x, p) = inf.state_and_covariance().unwrap();
        assert!((&x - kf.state()).abs().max() < 1e-9);
        assert!(max_abs_diff(&p, kf.covariance()) < 1e-9 * kf.covariance().abs().max());
    }
}

#[test]
fn information_filter_starts_from_a_diffuse_prior() {
    // Y0 = 0 (no prior): after two scalar fixes of a static scalar, x̂ is their weighted mean.
    let mut inf = InformationFilter::new(DVector::zeros(1), DMatrix::zeros(1, 1)).unwrap();
    assert!(inf.state_and_covariance().is_err());
    let one = DMatrix::identity(1, 1);
    inf.update(
        &DVector::from_element(1, 2.0),
        &one,
        &DMatrix::from_element(1, 1, 1.0),
    )
    .unwrap();
    inf.predict(&one, &DMatrix::zeros(1, 1)).unwrap();
    inf.update(
        &DVector::from_element(1, 5.0),
        &one,
        &DMatrix::from_element(1, 1, 2.0),
    )
    .unwrap();
    let (x, p) = inf.state_and_covariance().unwrap();
    assert!((x[0] - (2.0 + 5.0 / 2.0) / 1.5).abs() < 1e-14);
    assert!((p[(0, 0)] - 1.0 / 1.5).abs() < 1e-14);
}

#[test]
fn cramer_rao_bound_equals_filter_covariance_without_process_noise() {
    // Spec 10: with Q = 0 the filter covariance equals the Cramér–Rao bound.
    let mut g = rng(5);
    let n = 6;
    let phi = random_transition(&mut g, n);
    let h = random_matrix(&mut g, 2, n);
    let r = random_spd(&mut g, 2, 0.2);
    let p0 = random_spd(&mut g, n, 1.0) * 10.0;
    let mut kf = KalmanFilter::new(DVector::zeros(n), p0.clone()).unwrap();
    let mut fisher = FisherInformation::from_prior_covariance(&p0).unwrap();
    let z = DVector::zeros(2);
    for _ in 0..25 {
        kf.predict(&phi, &DMatrix::zeros(n, n)).unwrap();
        kf.update(&z, &h, &r).unwrap();
        fisher.step(&phi, &h, &r).unwrap();
        let bound = fisher.cramer_rao_bound().unwrap();
        let scale = kf.covariance().abs().max();
        assert!(max_abs_diff(&bound, kf.covariance()) < 1e-8 * scale);
    }
}

#[test]
fn filter_with_process_noise_stays_above_the_noise_free_bound() {
    // P − P_Γ ⪰ 0 at every step when the filter has Q > 0 and the bound has none.
    let mut g = rng(8);
    let n = 4;
    let phi = random_transition(&mut g, n);
    let q = random_spd(&mut g, n, 0.01) * 0.05;
    let h = random_matrix(&mut g, 1, n);
    let r = DMatrix::from_element(1, 1, 0.5);
    let p0 = random_spd(&mut g, n, 1.0);
    let mut kf = KalmanFilter::new(DVector::zeros(n), p0.clone()).unwrap();
    let mut fisher = FisherInformation::from_prior_covariance(&p0).unwrap();
    for _ in 0..40 {
        kf.predict(&phi, &q).unwrap();
        kf.update(&DVector::zeros(1), &h, &r).unwrap();
        fisher.step(&phi, &h, &r).unwrap();
        let gap = kf.covariance() - fisher.cramer_rao_bound().unwrap();
        assert!(min_eigenvalue(&gap) > -1e-10 * kf.covariance().abs().max());
    }
}
