//! Maximum-likelihood noise identification on a case with a known truth:
//! the local-level model (a random walk seen in white noise) simulated
//! with q and r, then (q, r) fitted by Nelder–Mead on the sum of the
//! updates' log-likelihoods ([`UpdateRecord::log_likelihood`]).

use aidnav_estimation::KalmanFilter;
use aidnav_estimation::nalgebra::{Matrix1, Vector1};
use aidnav_estimation::optimise::{NelderMeadOptions, nelder_mead};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// True process and measurement noise variances.
const Q_TRUE: f64 = 0.04;
const R_TRUE: f64 = 1.0;
/// Measurements: the maximum-likelihood estimates' relative σ is about
/// √(2/n)-ish for r and a few times more for q (the signal is 25× below
/// the noise per step); 4000 epochs keep both within the limits below.
const EPOCHS: usize = 4000;
/// Acceptance: the fitted variances within 10 % (r) and 25 % (q) of the
/// truth — about three of their standard errors at this length.
const R_LIMIT: f64 = 0.10;
const Q_LIMIT: f64 = 0.25;

fn simulate(seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let w = Normal::new(0.0, Q_TRUE.sqrt()).unwrap();
    let v = Normal::new(0.0, R_TRUE.sqrt()).unwrap();
    let mut x = 0.0;
    (0..EPOCHS)
        .map(|_| {
            x += w.sample(&mut rng);
            x + v.sample(&mut rng)
        })
        .collect()
}

/// Σ ln p(ν) of a pass over `z` with variances (q, r); −∞ when the filter
/// refuses them.
fn log_likelihood(z: &[f64], q: f64, r: f64) -> f64 {
    let Ok(mut kf) = KalmanFilter::new(Vector1::new(z[0]), Matrix1::new(r)) else {
        return f64::NEG_INFINITY;
    };
    let one = Matrix1::new(1.0);
    let mut total = 0.0;
    for zk in &z[1..] {
        if kf.predict(&one, &Matrix1::new(q)).is_err() {
            return f64::NEG_INFINITY;
        }
        match kf.update(&Vector1::new(*zk), &one, &Matrix1::new(r)) {
            Ok(rec) => total += rec.log_likelihood(),
            Err(_) => return f64::NEG_INFINITY,
        }
    }
    total
}

#[test]
fn the_likelihood_search_recovers_the_noise_of_a_local_level_model() {
    let z = simulate(13);
    // Start a factor 10 off in q and 3 off in r, log-scale coordinates.
    let start = [(Q_TRUE * 10.0).ln(), (R_TRUE / 3.0).ln()];
    let options = NelderMeadOptions {
        initial_step: vec![0.7, 0.7],
        lower: vec![-20.0, -20.0],
        upper: vec![5.0, 5.0],
        max_evaluations: 300,
        f_tolerance: 1e-4,
        x_tolerance: 1e-3,
    };
    let m = nelder_mead(
        |points: &[Vec<f64>]| {
            points
                .iter()
                .map(|p| -log_likelihood(&z, p[0].exp(), p[1].exp()))
                .collect()
        },
        &start,
        &options,
    )
    .unwrap();
    assert!(m.converged, "{m:?}");
    let (q, r) = (m.x[0].exp(), m.x[1].exp());
    assert!((r / R_TRUE - 1.0).abs() < R_LIMIT, "r = {r}");
    assert!((q / Q_TRUE - 1.0).abs() < Q_LIMIT, "q = {q}");
    // The truth is close to the optimum: within the χ²(2) 99 % level
    // (9.21 / 2) of the likelihood-ratio test.
    let at_truth = log_likelihood(&z, Q_TRUE, R_TRUE);
    assert!(-m.value - at_truth < 4.61, "{} vs {at_truth}", -m.value);
    assert!(-m.value >= at_truth);
    assert!(m.value < m.start_value);
}
