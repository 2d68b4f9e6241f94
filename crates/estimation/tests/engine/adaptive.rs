//! Spec 20 policies on constructed cases.

use aidnav_estimation::adaptive::{
    AdaptiveGain, AnomalyDetector, DiagonalRule, LimitedAdaptiveGain, Limiting, Rejection,
    innovation_feedback_q,
};
use aidnav_estimation::nalgebra::{Matrix1, Matrix1x2, Matrix2, Vector1, Vector2};
use aidnav_estimation::{KalmanFilter, Outcome};

use crate::common::{normal, rng};

const GAMMA: f64 = 9.0;

fn filter() -> KalmanFilter<aidnav_estimation::nalgebra::Const<2>> {
    KalmanFilter::new(Vector2::new(1.0, 0.5), Matrix2::new(1.0, 0.2, 0.2, 0.5)).unwrap()
}
const H: Matrix1x2<f64> = Matrix1x2::new(1.0, 0.0);

#[test]
fn limiting_moves_a_50_sigma_outlier_by_the_gate_amount_in_its_direction() {
    let s: f64 = 2.0; // S = P00 + R = 1 + 1
    for sign in [1.0, -1.0] {
        let mut kf = filter();
        let z = Vector1::new(1.0 + sign * 50.0 * s.sqrt());
        let rec = kf
            .update_with(
                &z,
                &H,
                &Matrix1::new(1.0),
                &mut Limiting {
                    detector: AnomalyDetector { gamma: GAMMA },
                },
            )
            .unwrap();
        assert_eq!(rec.outcome, Outcome::Limited);
        // Gain on x is P00/S = 0.5; the limited innovation is sign·√(γ S).
        let moved = kf.state()[0] - 1.0;
        assert!((moved - sign * 0.5 * (GAMMA * s).sqrt()).abs() < 1e-12);
        // The velocity moves by its own gain times the same limited innovation.
        assert!((kf.state()[1] - 0.5 - sign * 0.1 * (GAMMA * s).sqrt()).abs() < 1e-12);
    }
}

#[test]
fn rejection_leaves_the_pure_prediction() {
    let mut kf = filter();
    let phi = Matrix2::new(1.0, 1.0, 0.0, 1.0);
    kf.predict(&phi, &(Matrix2::identity() * 0.01)).unwrap();
    let predicted = *kf.state();
    let rec = kf
        .update_with(
            &Vector1::new(100.0),
            &H,
            &Matrix1::new(1.0),
            &mut Rejection {
                detector: AnomalyDetector { gamma: GAMMA },
            },
        )
        .unwrap();
    assert_eq!(rec.outcome, Outcome::Rejected);
    assert_eq!(*kf.state(), predicted);
}

#[test]
fn the_detector_threshold_is_gamma_times_trace_s() {
    // S = 2: the gate is |ν| = √18 ≈ 4.243.
    for (nu, anomalous) in [(4.2, false), (4.3, true)] {
        let mut kf = filter();
        let rec = kf
            .update_with(
                &Vector1::new(1.0 + nu),
                &H,
                &Matrix1::new(1.0),
                &mut Limiting {
                    detector: AnomalyDetector { gamma: GAMMA },
                },
            )
            .unwrap();
        assert_eq!(rec.outcome == Outcome::Limited, anomalous, "ν = {nu}");
    }
}

#[test]
fn adaptive_gain_trusts_noisier_measurements_less() {
    // Static scalar, modelled R = 1 but true noise σ = 5: once the window is
    // full, M̂ ≫ H P Hᵀ and the gain P / M̂ is far below the ordinary P / S.
    let mut g = rng(4);
    let mut policy = AdaptiveGain::new(20, DiagonalRule::All).unwrap();
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    let mut last = None;
    for k in 0..60 {
        kf.predict(&Matrix1::new(1.0), &Matrix1::new(0.01)).unwrap();
        let p = kf.covariance()[(0, 0)];
        let rec = kf
            .update_with(
                &Vector1::new(5.0 * normal(&mut g)),
                &Matrix1::new(1.0),
                &Matrix1::new(1.0),
                &mut policy,
            )
            .unwrap();
        if k < 19 {
            assert_eq!(rec.outcome, Outcome::Accepted);
        } else {
            assert_eq!(rec.outcome, Outcome::AdaptiveGain);
            let ordinary = p / (p + 1.0);
            assert!(
                rec.gain[(0, 0)] < 0.3 * ordinary,
                "k {k}: {} vs {ordinary}",
                rec.gain[(0, 0)]
            );
        }
        last = Some(rec);
    }
    assert!(last.is_some());
}

#[test]
fn adaptive_gain_falls_back_to_h_p_ht_when_innovations_are_small() {
    // Innovations far smaller than H P Hᵀ: K = P Hᵀ (H P Hᵀ)⁻¹ = 1 for a scalar.
    let mut policy = AdaptiveGain::new(3, DiagonalRule::Any).unwrap();
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(100.0)).unwrap();
    let mut rec = None;
    for _ in 0..3 {
        rec = Some(
            kf.update_with(
                &Vector1::new(0.01),
                &Matrix1::new(1.0),
                &Matrix1::new(1.0),
                &mut policy,
            )
            .unwrap(),
        );
    }
    let rec = rec.unwrap();
    assert_eq!(rec.outcome, Outcome::AdaptiveGain);
    assert!((rec.gain[(0, 0)] - 1.0).abs() < 1e-12);
}

#[test]
fn innovation_feedback_q_grows_when_the_true_noise_grows() {
    // Random walk whose process noise jumps ×100 half way; the eq. 3 filter
    // builds its own Q from K ν νᵀ Kᵀ, which must follow the jump.
    let mut g = rng(9);
    let r = 1.0;
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    let mut gain = Matrix1::new(0.5);
    let mut truth = 0.0;
    let (mut q_before, mut q_after) = (0.0, 0.0);
    for k in 0..800 {
        let q_true: f64 = if k < 400 { 0.01 } else { 1.0 };
        truth += q_true.sqrt() * normal(&mut g);
        let z = Vector1::new(truth + normal(&mut g));
        kf.predict_state(&Matrix1::new(1.0)).unwrap();
        let innovation = kf
            .innovation(&z, &Matrix1::new(1.0), &Matrix1::new(r))
            .unwrap();
        let q = innovation_feedback_q(&gain, &innovation.residual);
        kf.predict_covariance(&Matrix1::new(1.0), &q).unwrap();
        let rec = kf.update(&z, &Matrix1::new(1.0), &Matrix1::new(r)).unwrap();
        gain = rec.gain;
        if (200..400).contains(&k) {
            q_before += q[(0, 0)] / 200.0;
        } else if k >= 600 {
            q_after += q[(0, 0)] / 200.0;
        }
    }
    assert!(
        q_after > 5.0 * q_before,
        "adaptive Q {q_before} → {q_after}"
    );
}

#[test]
fn eq9_update_limits_with_the_windowed_gain() {
    // Window of 2: after one clean innovation of 3 the window is full on the
    // next update. A 50σ outlier is then limited to √(γ S) (S = 2), and M̂
    // holds 3² and the limited value² = 18: M̂ = 13.5 > H P Hᵀ = 1, so the
    // gain is P Hᵀ / 13.5 rather than P Hᵀ / S.
    let bound = (GAMMA * 2.0_f64).sqrt();
    let mut policy = LimitedAdaptiveGain {
        gain: AdaptiveGain::new(2, DiagonalRule::All).unwrap(),
        detector: AnomalyDetector { gamma: GAMMA },
    };
    let r = Matrix1::new(1.0);
    let mut first = filter();
    let rec = first
        .update_with(&Vector1::new(1.0 + 3.0), &H, &r, &mut policy)
        .unwrap();
    // Window not full yet: the ordinary gain.
    assert_eq!(rec.outcome, Outcome::Accepted);
    for sign in [1.0, -1.0] {
        let mut p = policy.clone();
        let mut kf = filter();
        let rec = kf
            .update_with(&Vector1::new(1.0 + sign * 100.0), &H, &r, &mut p)
            .unwrap();
        assert_eq!(rec.outcome, Outcome::Limited);
        let m_hat = 0.5 * (9.0 + bound * bound);
        assert!((rec.gain[0] - 1.0 / m_hat).abs() < 1e-12, "{}", rec.gain[0]);
        assert!((kf.state()[0] - 1.0 - sign * bound / m_hat).abs() < 1e-12);
        assert!((kf.state()[1] - 0.5 - sign * 0.2 * bound / m_hat).abs() < 1e-12);
    }
}
