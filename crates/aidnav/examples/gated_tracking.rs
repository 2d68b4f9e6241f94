//! A constant-velocity tracker with outliers in its fixes, with and without a
//! χ² gate: the smallest complete use of the library (seeded simulation,
//! fixed-size filter, a policy as a value, the update record).
//!
//! `cargo run --release -p aidnav --example gated_tracking`

use aidnav::estimation::nalgebra::U1;
use aidnav::estimation::nalgebra::{Matrix2, Vector1, Vector2};
use aidnav::estimation::{AcceptAll, Chi2Gate, KalmanFilter, MeasurementPolicy, Outcome};
use aidnav::models::ConstantVelocity;
use aidnav::sim::rng::{RngExt, run_rng, standard_normal};

/// Fraction of fixes replaced by gross errors.
const OUTLIER_RATE: f64 = 0.1;
/// Size of a gross error [m].
const OUTLIER_M: f64 = 60.0;

fn run<P: MeasurementPolicy<U1>>(policy: &mut P, seed: u64) -> (f64, usize) {
    let cv = ConstantVelocity::new(1.0, 0.05).expect("valid model");
    let (h, r) = ConstantVelocity::position_measurement(2.0);
    let (phi, q) = (cv.transition(), cv.process_noise());
    let q_factor = q.cholesky().expect("Q is positive definite").l();
    let mut rng = run_rng(seed, 0);
    let mut truth = Vector2::new(0.0, 1.0);
    let mut kf = KalmanFilter::new(Vector2::new(0.0, 1.0), Matrix2::new(25.0, 0.0, 0.0, 1.0))
        .expect("valid prior");
    let (mut sq, mut rejected) = (0.0, 0);
    let epochs = 2000;
    for k in 0..epochs {
        if k > 0 {
            truth = phi * truth
                + q_factor * Vector2::new(standard_normal(&mut rng), standard_normal(&mut rng));
            kf.predict(&phi, &q).expect("finite");
        }
        let mut z = truth[0] + 2.0 * standard_normal(&mut rng);
        if rng.random::<f64>() < OUTLIER_RATE {
            z += OUTLIER_M * if rng.random::<bool>() { 1.0 } else { -1.0 };
        }
        let rec = kf
            .update_with(&Vector1::new(z), &h, &r, policy)
            .expect("finite");
        rejected += usize::from(rec.outcome == Outcome::Rejected);
        sq += (kf.state()[0] - truth[0]).powi(2);
    }
    ((sq / epochs as f64).sqrt(), rejected)
}

fn main() {
    let seed = 7;
    let (plain, _) = run(&mut AcceptAll, seed);
    let (gated, rejected) = run(&mut Chi2Gate { probability: 0.999 }, seed);
    println!(
        "seed {seed}: position RMS error, plain KF {plain:.2} m; χ²-gated {gated:.2} m ({rejected} fixes rejected)"
    );
}
