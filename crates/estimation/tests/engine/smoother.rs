//! RTS smoother against batch solutions computed independently.

use aidnav_estimation::nalgebra::{DMatrix, DVector};
use aidnav_estimation::{Collect, LinearGaussianModel, RunOptions, rts_smooth};

#[test]
fn static_state_smooths_to_the_final_estimate() {
    // Φ = I, Q = 0: every smoothed epoch equals the estimate from all data.
    let model = LinearGaussianModel::new(
        DMatrix::identity(2, 2),
        DMatrix::zeros(2, 2),
        DMatrix::from_row_slice(2, 2, &[1.0, 0.0, 1.0, 1.0]),
        DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 2.0])),
        DVector::zeros(2),
        DMatrix::identity(2, 2) * 10.0,
    )
    .unwrap();
    let zs = [[1.0, 3.0], [0.5, 2.5], [1.5, 3.5], [0.9, 2.9]];
    let data: Vec<Vec<Option<f64>>> = zs
        .iter()
        .map(|z| z.iter().map(|&v| Some(v)).collect())
        .collect();
    let opts = RunOptions {
        keep_forward_pass: true,
        ..Default::default()
    };
    let out = model
        .run(
            data.iter()
                .enumerate()
                .map(|(k, z)| (k as f64, z.as_slice())),
            &opts,
            &mut Collect::default(),
        )
        .unwrap();
    let smoothed = rts_smooth(&out.forward).unwrap();
    for s in &smoothed {
        assert!((&s.x - &out.final_state).abs().max() < 1e-12);
        assert!((&s.p - &out.final_covariance).abs().max() < 1e-12);
    }
}

#[test]
fn random_walk_smoother_equals_batch_least_squares() {
    // Scalar random walk x_k = x_{k−1} + w, z_k = x_k + v with some z missing.
    // The smoothed means solve the batch normal equations over (x_0..x_T);
    // the smoothed variances are the diagonal of their inverse.
    let (p0, q, r) = (5.0, 0.4, 1.5);
    let z: Vec<Option<f64>> = [
        0.3,
        1.1,
        f64::NAN,
        0.7,
        2.0,
        f64::NAN,
        f64::NAN,
        1.4,
        0.9,
        1.8,
        2.2,
        1.0,
    ]
    .iter()
    .map(|v| (!v.is_nan()).then_some(*v))
    .collect();
    let t = z.len();
    let mut a = DMatrix::<f64>::zeros(t, t);
    let mut b = DVector::<f64>::zeros(t);
    a[(0, 0)] += 1.0 / p0;
    for k in 1..t {
        a[(k, k)] += 1.0 / q;
        a[(k - 1, k - 1)] += 1.0 / q;
        a[(k, k - 1)] -= 1.0 / q;
        a[(k - 1, k)] -= 1.0 / q;
    }
    for (k, zk) in z.iter().enumerate() {
        if let Some(v) = zk {
            a[(k, k)] += 1.0 / r;
            b[k] += v / r;
        }
    }
    let chol = a.clone().cholesky().unwrap();
    let batch_mean = chol.solve(&b);
    let batch_cov = chol.inverse();

    let model = LinearGaussianModel::new(
        DMatrix::identity(1, 1),
        DMatrix::from_element(1, 1, q),
        DMatrix::identity(1, 1),
        DMatrix::from_element(1, 1, r),
        DVector::zeros(1),
        DMatrix::from_element(1, 1, p0),
    )
    .unwrap();
    let data: Vec<[Option<f64>; 1]> = z.iter().map(|v| [*v]).collect();
    let opts = RunOptions {
        keep_forward_pass: true,
        ..Default::default()
    };
    let out = model
        .run(
            data.iter()
                .enumerate()
                .map(|(k, z)| (k as f64, z.as_slice())),
            &opts,
            &mut Collect::default(),
        )
        .unwrap();
    let smoothed = rts_smooth(&out.forward).unwrap();
    for k in 0..t {
        assert!(
            (smoothed[k].x[0] - batch_mean[k]).abs() < 1e-12,
            "mean at {k}"
        );
        assert!(
            (smoothed[k].p[(0, 0)] - batch_cov[(k, k)]).abs() < 1e-12,
            "var at {k}"
        );
    }
}

/// A frozen state (variance exactly zero, a switched-off state) beside a
/// live one: the smoother sets it aside and the live state smooths exactly
/// as it does alone.
#[test]
fn a_frozen_state_is_set_aside() {
    use aidnav_estimation::ForwardEpoch;
    let model = LinearGaussianModel::new(
        DMatrix::identity(1, 1),
        DMatrix::identity(1, 1) * 0.4,
        DMatrix::identity(1, 1),
        DMatrix::identity(1, 1) * 1.5,
        DVector::zeros(1),
        DMatrix::identity(1, 1) * 5.0,
    )
    .unwrap();
    let data: Vec<Vec<Option<f64>>> = [0.3, 1.1, 0.7, 2.0, 1.4]
        .iter()
        .map(|&v| vec![Some(v)])
        .collect();
    let opts = RunOptions {
        keep_forward_pass: true,
        ..Default::default()
    };
    let out = model
        .run(
            data.iter()
                .enumerate()
                .map(|(k, z)| (k as f64, z.as_slice())),
            &opts,
            &mut Collect::default(),
        )
        .unwrap();
    let alone = rts_smooth(&out.forward).unwrap();
    let grow_v = |v: &DVector<f64>| DVector::from_vec(vec![v[0], 0.0]);
    let grow_m = |m: &DMatrix<f64>, frozen: f64| {
        DMatrix::from_row_slice(2, 2, &[m[(0, 0)], 0.0, 0.0, frozen])
    };
    let pair: Vec<ForwardEpoch<_>> = out
        .forward
        .iter()
        .map(|e| ForwardEpoch {
            phi: grow_m(&e.phi, 0.9),
            x_predicted: grow_v(&e.x_predicted),
            p_predicted: grow_m(&e.p_predicted, 0.0),
            x_filtered: grow_v(&e.x_filtered),
            p_filtered: grow_m(&e.p_filtered, 0.0),
        })
        .collect();
    let together = rts_smooth(&pair).unwrap();
    for (a, b) in alone.iter().zip(&together) {
        assert!((a.x[0] - b.x[0]).abs() < 1e-12);
        assert!((a.p[(0, 0)] - b.p[(0, 0)]).abs() < 1e-12);
        assert_eq!((b.x[1], b.p[(1, 1)], b.p[(0, 1)]), (0.0, 0.0, 0.0));
    }
}
