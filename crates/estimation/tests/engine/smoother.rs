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

/// [`RtsRecorder`] against [`rts_smooth`] over the same forward pass: a
/// 6-state system with a frozen state, epochs with and without updates,
/// closed-loop resets of the estimate (x⁻ moved by the feedback, x = 0),
/// marks at some epochs only (the last epoch unmarked in one case, marked
/// in the other). Both smoothers run from the same stored numbers; the
/// recorder composes the steps between marks, so only rounding differs.
#[test]
fn recorder_equals_the_stored_pass_smoother_at_the_marks() {
    use super::common::{normal, random_spd, random_transition, rng};
    use aidnav_estimation::nalgebra::{Const, SMatrix, SVector};
    use aidnav_estimation::{ForwardEpoch, RtsRecorder};
    const N: usize = 6;
    const FROZEN: usize = 4;
    // Rounding of two orders of summation over ≈ 10² steps of O(1)
    // numbers: far below the 1e-9 the smoothed output must keep.
    const TOLERANCE: f64 = 1e-9;
    type M = SMatrix<f64, N, N>;
    type V = SVector<f64, N>;
    let freeze = |m: &mut M| {
        for i in 0..N {
            if i != FROZEN {
                m[(i, FROZEN)] = 0.0;
                m[(FROZEN, i)] = 0.0;
            }
        }
    };
    for (seed, mark_last) in [(11_u64, false), (12, true)] {
        let mut g = rng(seed);
        let mut p = M::from_iterator(random_spd(&mut g, N, 0.5).iter().copied());
        freeze(&mut p);
        p[(FROZEN, FROZEN)] = 0.0;
        let mut x = V::from_fn(|i, _| if i == FROZEN { 0.0 } else { normal(&mut g) });
        let mut forward = vec![ForwardEpoch::<Const<N>> {
            phi: M::identity(),
            x_predicted: x,
            p_predicted: p,
            x_filtered: x,
            p_filtered: p,
        }];
        let mut rec = RtsRecorder::<N>::new(&x, &p, usize::MAX);
        let mut marked = Vec::new();
        let epochs = 120;
        for k in 0..epochs {
            if k > 0 {
                let mut phi = M::from_iterator(random_transition(&mut g, N).iter().copied());
                freeze(&mut phi);
                phi[(FROZEN, FROZEN)] = 1.0;
                let mut q = M::from_iterator(random_spd(&mut g, N, 0.01).iter().copied()) * 0.05;
                freeze(&mut q);
                q[(FROZEN, FROZEN)] = 0.0;
                x = phi * x;
                p = phi * p * phi.transpose() + q;
                p = (p + p.transpose()) * 0.5;
                rec.predict(&phi, &x, &p);
                forward.push(ForwardEpoch {
                    phi,
                    x_predicted: x,
                    p_predicted: p,
                    x_filtered: x,
                    p_filtered: p,
                });
            }
            // Updates at about half the epochs: two measurements of the
            // live states (Joseph form).
            if normal(&mut g) > 0.0 {
                let mut h = SMatrix::<f64, 2, N>::from_fn(|_, _| normal(&mut g));
                h.column_mut(FROZEN).fill(0.0);
                let r = SMatrix::<f64, 2, 2>::from_diagonal(&SVector::<f64, 2>::new(0.3, 0.7));
                let s = h * p * h.transpose() + r;
                let gain = p * h.transpose() * s.try_inverse().unwrap();
                let z = SVector::<f64, 2>::from_fn(|_, _| normal(&mut g));
                let x_predicted = x;
                x += gain * (z - h * x);
                let i_kh = M::identity() - gain * h;
                p = i_kh * p * i_kh.transpose() + gain * r * gain.transpose();
                p = (p + p.transpose()) * 0.5;
                // Closed loop at every other update: the estimate is fed
                // back, so x = 0 and the prediction sits −x away.
                let (x_predicted, x_filtered) = if normal(&mut g) > 0.0 {
                    let fed = x;
                    x = V::zeros();
                    (x_predicted - fed, x)
                } else {
                    (x_predicted, x)
                };
                rec.filtered(&x_predicted, &x_filtered, &p);
                let e = forward.last_mut().unwrap();
                e.x_predicted = x_predicted;
                e.x_filtered = x_filtered;
                e.p_filtered = p;
            }
            let last = k == epochs - 1;
            if (last && mark_last) || (!last && k % 7 != 3 && normal(&mut g) > 0.3) {
                assert_eq!(rec.mark(), Some(marked.len()));
                assert_eq!(rec.mark(), Some(marked.len()), "marking again");
                marked.push(k);
            }
        }
        assert_eq!(rec.epoch(), epochs - 1);
        let reference = rts_smooth(&forward).unwrap();
        let smoothed = rec.smooth().unwrap();
        assert_eq!(smoothed.len(), marked.len());
        assert!(marked.len() > 20, "{} marks", marked.len());
        let mut worst = 0.0_f64;
        for (s, &k) in smoothed.iter().zip(&marked) {
            worst = worst
                .max((s.x - reference[k].x).abs().max())
                .max((s.p - reference[k].p).abs().max());
            assert_eq!(s.p[(FROZEN, FROZEN)], 0.0, "the frozen state stays frozen");
        }
        eprintln!(
            "seed {seed}: {} marks, worst difference {worst:e}",
            marked.len()
        );
        assert!(worst < TOLERANCE, "seed {seed}: {worst:e}");
        // The smoother did something: the first mark moved from its filtered value.
        let first = &forward[marked[0]];
        assert!((smoothed[0].x - first.x_filtered).norm() > 1e-3);
    }
}

/// The recorder refuses more marks than it was given room for, and says so.
#[test]
fn recorder_overflows_at_its_limit() {
    use aidnav_estimation::RtsRecorder;
    use aidnav_estimation::nalgebra::{Matrix1, Vector1};
    let mut rec = RtsRecorder::<1>::new(&Vector1::new(0.0), &Matrix1::new(1.0), 2);
    assert_eq!(rec.mark(), Some(0));
    rec.predict(&Matrix1::identity(), &Vector1::new(0.0), &Matrix1::new(2.0));
    assert_eq!(rec.mark(), Some(1));
    rec.predict(&Matrix1::identity(), &Vector1::new(0.0), &Matrix1::new(3.0));
    assert_eq!(rec.mark(), None);
    assert!(rec.overflowed());
}
