//! Seeded Monte Carlo: a correctly tuned filter's NEES and NIS fall inside
//! their χ² 95 % bounds; a mistuned one's do not.

use aidnav_estimation::nalgebra::{Matrix1, Matrix1x2, Matrix2, Vector1, Vector2};
use aidnav_estimation::{Chi2Mean, KalmanFilter, mean_chi2_bounds, nees};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use crate::common::normal;

const RUNS: usize = 100;
const EPOCHS: usize = 150;
/// Confidence of the χ² acceptance intervals (Bar-Shalom et al. §5.4 use 95 %).
const CONFIDENCE: f64 = 0.95;
/// A consistent filter's per-epoch mean NEES leaves its 95 % interval in about
/// 5 % of epochs; demand at least 90 % inside (well clear of chance failure
/// with this seed) and at most 30 % inside for the mistuned filter.
const TUNED_MIN_INSIDE: f64 = 0.90;
const MISTUNED_MAX_INSIDE: f64 = 0.30;

struct Tuning {
    q_scale: f64,
    r_scale: f64,
}

/// Returns (mean NIS over all runs and epochs, fraction of epochs whose
/// run-averaged NEES is inside the bounds).
fn campaign(t: Tuning) -> (Chi2Mean, f64) {
    let dt: f64 = 1.0;
    let accel_psd = 0.05;
    let phi = Matrix2::new(1.0, dt, 0.0, 1.0);
    let q = Matrix2::new(dt.powi(3) / 3.0, dt * dt / 2.0, dt * dt / 2.0, dt) * accel_psd;
    let q_chol = q.cholesky().unwrap().l();
    let h = Matrix1x2::new(1.0, 0.0);
    let r: f64 = 4.0;
    let p0 = Matrix2::<f64>::new(10.0, 0.0, 0.0, 1.0);
    let mut nis = Chi2Mean::default();
    let mut nees_sum = vec![0.0; EPOCHS];
    for run in 0..RUNS {
        let mut g = ChaCha8Rng::seed_from_u64(20261123);
        g.set_stream(run as u64);
        let mut truth = Vector2::new(
            p0[(0, 0)].sqrt() * normal(&mut g),
            p0[(1, 1)].sqrt() * normal(&mut g),
        );
        let mut kf = KalmanFilter::new(Vector2::zeros(), p0).unwrap();
        for (k, slot) in nees_sum.iter_mut().enumerate() {
            if k > 0 {
                truth = phi * truth + q_chol * Vector2::new(normal(&mut g), normal(&mut g));
                kf.predict(&phi, &(q * t.q_scale)).unwrap();
            }
            let z = Vector1::new(truth[0] + r.sqrt() * normal(&mut g));
            let rec = kf.update(&z, &h, &Matrix1::new(r * t.r_scale)).unwrap();
            nis.push(rec.nis, 1);
            *slot += nees(&truth, kf.state(), kf.covariance()).unwrap();
        }
    }
    let (lo, hi) = mean_chi2_bounds(2, RUNS, CONFIDENCE);
    let inside = nees_sum
        .iter()
        .filter(|s| (lo..=hi).contains(&(*s / RUNS as f64)))
        .count();
    (nis, inside as f64 / EPOCHS as f64)
}

#[test]
fn tuned_filter_is_consistent() {
    let (nis, inside) = campaign(Tuning {
        q_scale: 1.0,
        r_scale: 1.0,
    });
    let (lo, hi) = nis.bounds(CONFIDENCE);
    assert!(
        nis.is_consistent(CONFIDENCE),
        "mean NIS {} outside [{lo}, {hi}]",
        nis.mean()
    );
    assert!(
        inside >= TUNED_MIN_INSIDE,
        "only {inside} of epochs inside the NEES bounds"
    );
}

#[test]
fn filter_with_too_little_process_noise_is_detected() {
    let (nis, inside) = campaign(Tuning {
        q_scale: 0.01,
        r_scale: 1.0,
    });
    assert!(!nis.is_consistent(CONFIDENCE), "mean NIS {}", nis.mean());
    assert!(nis.mean() > nis.bounds(CONFIDENCE).1);
    assert!(
        inside <= MISTUNED_MAX_INSIDE,
        "{inside} of epochs inside the NEES bounds"
    );
}

#[test]
fn filter_with_too_much_measurement_noise_is_detected() {
    let (nis, _) = campaign(Tuning {
        q_scale: 1.0,
        r_scale: 10.0,
    });
    assert!(
        nis.mean() < nis.bounds(CONFIDENCE).0,
        "mean NIS {}",
        nis.mean()
    );
}
