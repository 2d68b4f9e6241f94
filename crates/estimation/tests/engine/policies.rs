//! Policies as values on the engine: constructed cases.

use aidnav_estimation::nalgebra::{
    DMatrix, DVector, Matrix1, Matrix1x2, Matrix2, Vector1, Vector2,
};
use aidnav_estimation::{
    Chi2Gate, Decision, Huber, InnovationView, KalmanFilter, Outcome, PolicyChoice,
};

fn filter() -> KalmanFilter<aidnav_estimation::nalgebra::Const<2>> {
    KalmanFilter::new(Vector2::new(1.0, 0.5), Matrix2::new(1.0, 0.2, 0.2, 0.5)).unwrap()
}

const H: Matrix1x2<f64> = Matrix1x2::new(1.0, 0.0);

fn r() -> Matrix1<f64> {
    Matrix1::new(1.0)
}

#[test]
fn chi2_gate_rejects_a_50_sigma_outlier_and_keeps_the_prediction() {
    let mut kf = filter();
    let before = *kf.state();
    let p_before = *kf.covariance();
    let sigma = 2f64.sqrt(); // √S = √(1 + 1)
    let rec = kf
        .update_with(
            &Vector1::new(1.0 + 50.0 * sigma),
            &H,
            &r(),
            &mut Chi2Gate { probability: 0.999 },
        )
        .unwrap();
    assert_eq!(rec.outcome, Outcome::Rejected);
    assert_eq!(*kf.state(), before);
    assert_eq!(*kf.covariance(), p_before);
    assert!((rec.nis - 2500.0).abs() < 1e-9);
    assert_eq!(rec.gain, aidnav_estimation::nalgebra::Matrix2x1::zeros());
}

#[test]
fn chi2_gate_accepts_an_ordinary_measurement() {
    let mut kf = filter();
    let rec = kf
        .update_with(
            &Vector1::new(2.0),
            &H,
            &r(),
            &mut Chi2Gate { probability: 0.999 },
        )
        .unwrap();
    assert_eq!(rec.outcome, Outcome::Accepted);
    assert!((kf.state()[0] - 1.5).abs() < 1e-15);
}

#[test]
fn huber_limits_the_pull_of_an_outlier_in_the_right_direction() {
    let k = 1.345;
    let sigma = 2f64.sqrt();
    for sign in [1.0, -1.0] {
        let z = Vector1::new(1.0 + sign * 50.0 * sigma);
        let mut plain = filter();
        plain.update(&z, &H, &r()).unwrap();
        let mut robust = filter();
        let rec = robust.update_with(&z, &H, &r(), &mut Huber { k }).unwrap();
        assert_eq!(rec.outcome, Outcome::Reweighted);
        let moved = robust.state()[0] - 1.0;
        let moved_plain = plain.state()[0] - 1.0;
        assert!(moved * sign > 0.0, "moved against the innovation");
        // The scalar Huber update moves x by P ν / (P + R e/k) with e = 50:
        let expected = 1.0 * (sign * 50.0 * sigma) / (1.0 + 50.0 / k);
        assert!((moved - expected).abs() < 1e-12);
        assert!(moved.abs() < moved_plain.abs() / 10.0);
        // Bounded influence: however large e, |Δx| < P k √S / R (here 1·k·√2/1).
        assert!(moved.abs() < k * sigma);
    }
}

#[test]
fn limiting_closure_clips_the_innovation_keeping_its_sign() {
    // Spec 20 eq. 8 as a closure: clip ν to the gate ±√(γ tr S).
    let gamma = 9.0;
    let mut limit = |v: &InnovationView<'_, aidnav_estimation::nalgebra::U1>| {
        let bound = (gamma * v.s.trace()).sqrt();
        if v.residual.norm_squared() > gamma * v.s.trace() {
            Decision::ReplaceResidual(v.residual.map(|e| e.signum() * bound))
        } else {
            Decision::Accept
        }
    };
    let mut kf = filter();
    let rec = kf
        .update_with(&Vector1::new(-100.0), &H, &r(), &mut limit)
        .unwrap();
    assert_eq!(rec.outcome, Outcome::Limited);
    let bound = (gamma * 2.0f64).sqrt();
    // Gain for x is P00 / S = 0.5; the clipped innovation is −bound.
    assert!((kf.state()[0] - (1.0 - 0.5 * bound)).abs() < 1e-12);
    // The record keeps the innovation as measured.
    assert!((rec.residual[0] + 101.0).abs() < 1e-12);
}

#[test]
fn adaptive_gain_covariance_keeps_p_honest() {
    // A policy that forms the gain from C = 4 S (too cautious): the Joseph
    // form must give the true covariance of that estimator,
    // P = P − K H P − P Hᵀ Kᵀ + K S Kᵀ (an independent expansion).
    let mut kf = KalmanFilter::new(
        DVector::from_vec(vec![0.0, 0.0]),
        DMatrix::from_row_slice(2, 2, &[2.0, 0.3, 0.3, 1.0]),
    )
    .unwrap();
    let p = kf.covariance().clone();
    let h = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
    let r = DMatrix::from_element(1, 1, 0.5);
    let s = &h * &p * h.transpose() + &r;
    let mut policy = |v: &InnovationView<'_, aidnav_estimation::nalgebra::Dyn>| {
        Decision::GainCovariance(v.s * 4.0)
    };
    let rec = kf
        .update_with(&DVector::from_element(1, 1.0), &h, &r, &mut policy)
        .unwrap();
    assert_eq!(rec.outcome, Outcome::AdaptiveGain);
    let k = &p * h.transpose() / (4.0 * s[(0, 0)]);
    assert!((&rec.gain - &k).abs().max() < 1e-15);
    let expected = &p - &k * &h * &p - &p * h.transpose() * k.transpose() + &k * &s * k.transpose();
    assert!((kf.covariance() - expected).abs().max() < 1e-14);
}

#[test]
fn policy_choice_dispatches_by_value() {
    let z = Vector1::new(200.0);
    let mut a = filter();
    let mut b = filter();
    let ra = a
        .update_with(
            &z,
            &H,
            &r(),
            &mut PolicyChoice::Chi2Gate { probability: 0.99 },
        )
        .unwrap();
    let rb = b
        .update_with(&z, &H, &r(), &mut PolicyChoice::Huber { k: 2.0 })
        .unwrap();
    assert_eq!(ra.outcome, Outcome::Rejected);
    assert_eq!(rb.outcome, Outcome::Reweighted);
    let mut c = filter();
    let rc = c
        .update_with(&z, &H, &r(), &mut PolicyChoice::None)
        .unwrap();
    assert_eq!(rc.outcome, Outcome::Accepted);
}
