//! The Kalman filter against closed forms and against itself in other shapes.

use aidnav_estimation::nalgebra::{
    Const, DMatrix, DVector, Dyn, Matrix1, SMatrix, SVector, Vector1,
};
use aidnav_estimation::{CovarianceUpdate, Decision, InnovationView, KalmanFilter};

use crate::common::*;

/// Agreement demanded between code paths that do the same arithmetic in a
/// different order (fixed vs run-time storage): the issue asks for 1e-12.
const SAME_ARITHMETIC_TOL: f64 = 1e-12;

#[test]
fn static_scalar_matches_closed_form() {
    // x constant, prior N(x0, p0), measurements z_i with variance r:
    // P_n = 1 / (1/p0 + n/r), x_n = P_n (x0/p0 + sum z / r).
    let (x0, p0, r) = (3.0, 4.0, 0.25);
    let zs = [2.5, 3.7, 2.9, 3.1, 3.3, 2.2, 3.05];
    let mut kf = KalmanFilter::new(Vector1::new(x0), Matrix1::new(p0)).unwrap();
    let mut sum = 0.0;
    for (i, &z) in zs.iter().enumerate() {
        if i > 0 {
            kf.predict(&Matrix1::new(1.0), &Matrix1::new(0.0)).unwrap();
        }
        kf.update(&Vector1::new(z), &Matrix1::new(1.0), &Matrix1::new(r))
            .unwrap();
        sum += z;
        let n = (i + 1) as f64;
        let p_n = 1.0 / (1.0 / p0 + n / r);
        let x_n = p_n * (x0 / p0 + sum / r);
        assert!((kf.covariance()[(0, 0)] - p_n).abs() < 1e-14 * p_n.max(1.0));
        assert!((kf.state()[0] - x_n).abs() < 1e-13);
    }
}

#[test]
fn random_walk_scalar_matches_hand_recursion() {
    // Scalar random walk: p⁻ = p + q, k = p⁻/(p⁻ + r), x += k(z − x), p = (1−k) p⁻.
    let (q, r) = (0.3, 2.0);
    let zs = [1.0, -0.5, 2.0, 0.7, 0.1];
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    let (mut x, mut p) = (0.0_f64, 1.0_f64);
    for &z in &zs {
        kf.predict(&Matrix1::new(1.0), &Matrix1::new(q)).unwrap();
        kf.update(&Vector1::new(z), &Matrix1::new(1.0), &Matrix1::new(r))
            .unwrap();
        let pm = p + q;
        let k = pm / (pm + r);
        x += k * (z - x);
        p = (1.0 - k) * pm;
        assert!((kf.state()[0] - x).abs() < 1e-14);
        assert!((kf.covariance()[(0, 0)] - p).abs() < 1e-14);
    }
}

struct Problem {
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    p0: DMatrix<f64>,
    zs: Vec<DVector<f64>>,
}

fn random_problem(seed: u64, n: usize, m: usize) -> Problem {
    let mut g = rng(seed);
    let phi = random_transition(&mut g, n);
    let q = random_spd(&mut g, n, 1e-3) * 0.01;
    let h = random_matrix(&mut g, m, n);
    let r = random_spd(&mut g, m, 0.1);
    let p0 = random_spd(&mut g, n, 0.5);
    let zs = (0..40).map(|_| random_vector(&mut g, m)).collect();
    Problem {
        phi,
        q,
        h,
        r,
        p0,
        zs,
    }
}

#[test]
fn fixed_and_dynamic_sizes_agree() {
    const N: usize = 15;
    const M: usize = 6;
    let Problem {
        phi,
        q,
        h,
        r,
        p0,
        zs,
    } = random_problem(7, N, M);
    let mut dynf = KalmanFilter::<Dyn>::new(DVector::zeros(N), p0.clone()).unwrap();
    let fixed = |m: &DMatrix<f64>| m.fixed_view::<N, N>(0, 0).into_owned();
    let mut fix = KalmanFilter::<Const<N>>::new(SVector::zeros(), fixed(&p0)).unwrap();
    let (phi_f, q_f) = (fixed(&phi), fixed(&q));
    let h_f: SMatrix<f64, M, N> = h.fixed_view::<M, N>(0, 0).into_owned();
    let r_f: SMatrix<f64, M, M> = r.fixed_view::<M, M>(0, 0).into_owned();
    for z in &zs {
        dynf.predict(&phi, &q).unwrap();
        fix.predict(&phi_f, &q_f).unwrap();
        let z_f: SVector<f64, M> = z.fixed_rows::<M>(0).into_owned();
        let a = dynf.update(z, &h, &r).unwrap();
        let b = fix.update(&z_f, &h_f, &r_f).unwrap();
        assert!((a.nis - b.nis).abs() <= SAME_ARITHMETIC_TOL * a.nis.max(1.0));
        for i in 0..N {
            assert!((dynf.state()[i] - fix.state()[i]).abs() <= SAME_ARITHMETIC_TOL);
            for j in 0..N {
                let d = (dynf.covariance()[(i, j)] - fix.covariance()[(i, j)]).abs();
                assert!(d <= SAME_ARITHMETIC_TOL, "P({i},{j}) differs by {d:e}");
            }
        }
    }
}

#[test]
fn joseph_and_standard_agree_for_the_optimal_gain() {
    let Problem {
        phi,
        q,
        h,
        r,
        p0,
        zs,
    } = random_problem(11, 8, 3);
    let mut joseph = KalmanFilter::<Dyn>::new(DVector::zeros(8), p0.clone()).unwrap();
    let mut standard = KalmanFilter::<Dyn>::new(DVector::zeros(8), p0)
        .unwrap()
        .with_covariance_update(CovarianceUpdate::Standard);
    for z in &zs {
        joseph.predict(&phi, &q).unwrap();
        standard.predict(&phi, &q).unwrap();
        joseph.update(z, &h, &r).unwrap();
        standard.update(z, &h, &r).unwrap();
        let scale = joseph.covariance().abs().max();
        assert!(max_abs_diff(joseph.covariance(), standard.covariance()) < 1e-10 * scale);
        assert!((joseph.state() - standard.state()).abs().max() < 1e-10);
    }
}

#[test]
fn sequential_equals_batch_for_diagonal_r() {
    let Problem {
        phi, q, h, p0, zs, ..
    } = random_problem(13, 6, 4);
    let r = DMatrix::from_diagonal(&DVector::from_vec(vec![0.5, 1.0, 2.0, 0.1]));
    let mut batch = KalmanFilter::<Dyn>::new(DVector::zeros(6), p0.clone()).unwrap();
    let mut seq = KalmanFilter::<Dyn>::new(DVector::zeros(6), p0).unwrap();
    for z in &zs {
        batch.predict(&phi, &q).unwrap();
        seq.predict(&phi, &q).unwrap();
        let a = batch.update(z, &h, &r).unwrap();
        let b = seq.update_sequential(z, &h, &r).unwrap();
        // The sum of the scalar NIS equals the batch NIS (chain rule of the likelihood).
        assert!((a.nis - b.nis).abs() < 1e-9 * a.nis.max(1.0));
        assert!((batch.state() - seq.state()).abs().max() < 1e-10);
        assert!(max_abs_diff(batch.covariance(), seq.covariance()) < 1e-10);
    }
}

#[test]
fn sequential_rejects_non_diagonal_r() {
    let mut kf = KalmanFilter::<Dyn>::new(DVector::zeros(2), DMatrix::identity(2, 2)).unwrap();
    let r = DMatrix::from_row_slice(2, 2, &[1.0, 0.1, 0.1, 1.0]);
    let err = kf
        .update_sequential(&DVector::zeros(2), &DMatrix::identity(2, 2), &r)
        .unwrap_err();
    assert!(err.to_string().contains("diagonal"), "{err}");
}

#[test]
fn fixed_size_update_allocates_nothing_and_is_deterministic() {
    // Same inputs, same outputs, bit for bit (no hidden state, no threads).
    let p0 = SMatrix::<f64, 3, 3>::identity();
    let h = SMatrix::<f64, 1, 3>::new(1.0, 0.0, 0.0);
    let run = || {
        let mut kf = KalmanFilter::new(SVector::<f64, 3>::zeros(), p0).unwrap();
        for k in 0..10 {
            kf.predict(&SMatrix::identity(), &(SMatrix::identity() * 0.01))
                .unwrap();
            kf.update(
                &SVector::<f64, 1>::new(k as f64),
                &h,
                &SMatrix::<f64, 1, 1>::new(1.0),
            )
            .unwrap();
        }
        kf
    };
    assert_eq!(run(), run());
}

/// One predict + update as the textbook writes it, dense and unfused:
/// P⁻ = Φ P Φᵀ + Q, S = H P⁻ Hᵀ + R_used, K = P⁻ Hᵀ C⁻¹ (C = S unless a
/// policy gives another), P = (I − K H) P⁻ (I − K H)ᵀ + K R_used Kᵀ.
#[allow(clippy::too_many_arguments)]
fn dense_joseph_reference(
    x: &DVector<f64>,
    p: &DMatrix<f64>,
    (phi, q): (&DMatrix<f64>, &DMatrix<f64>),
    (z, h, r_used): (&DVector<f64>, &DMatrix<f64>, &DMatrix<f64>),
    gain_covariance: Option<&DMatrix<f64>>,
) -> (DVector<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = x.len();
    let xp = phi * x;
    let pp = phi * p * phi.transpose() + q;
    let s = h * &pp * h.transpose() + r_used;
    let c = gain_covariance.unwrap_or(&s).clone();
    let k = (c.cholesky().unwrap().solve(&(h * &pp))).transpose();
    let xu = &xp + &k * (z - h * &xp);
    let ikh = DMatrix::identity(n, n) - &k * h;
    let pu = &ikh * &pp * ikh.transpose() + &k * r_used * k.transpose();
    (xu, (&pu + pu.transpose()) * 0.5, k)
}

/// A measurement matrix touching only some states, as a navigation
/// filter's does: every third column nonzero (one exactly selecting).
fn sparse_measurement(g: &mut rand_chacha::ChaCha8Rng, m: usize, n: usize) -> DMatrix<f64> {
    let mut h = random_matrix(g, m, n);
    for j in 0..n {
        if j % 3 != 0 {
            h.column_mut(j).fill(0.0);
        }
    }
    h.row_mut(0).fill(0.0);
    h[(0, 0)] = 1.0;
    h
}

/// The fused, triangle-only step (fixed and run-time sizes, dense and
/// sparse H, the gain of S and a policy's other gain, an inflated R) against
/// the straightforward dense Joseph reference, to 1e-12 of the covariance.
fn check_against_reference<const N: usize, const M: usize>(seed: u64) {
    let mut g = rng(seed);
    for draw in 0..12 {
        let phi = random_transition(&mut g, N);
        let q = random_spd(&mut g, N, 1e-3) * 0.01;
        let h = if draw % 2 == 0 {
            random_matrix(&mut g, M, N)
        } else {
            sparse_measurement(&mut g, M, N)
        };
        let r = random_spd(&mut g, M, 0.1);
        let p0 = random_spd(&mut g, N, 0.5);
        let x0 = random_vector(&mut g, N);
        let z = random_vector(&mut g, M);
        let other = random_spd(&mut g, M, 0.2) * 3.0;
        // 0: accept; 1: a policy's gain covariance; 2: R inflated 2.5×.
        let case = draw % 3;
        let r_used = if case == 2 { &r * 2.5 } else { r.clone() };
        let (x_ref, p_ref, k_ref) = dense_joseph_reference(
            &x0,
            &p0,
            (&phi, &q),
            (&z, &h, &r_used),
            (case == 1).then_some(&other),
        );
        let decide = |_: &InnovationView<'_, Dyn>| match case {
            1 => Decision::GainCovariance(other.clone()),
            2 => Decision::InflateR(2.5),
            _ => Decision::Accept,
        };
        let mut dynf = KalmanFilter::<Dyn>::new(x0.clone(), p0.clone()).unwrap();
        dynf.predict(&phi, &q).unwrap();
        let mut decide = decide;
        let rec = dynf.update_with(&z, &h, &r, &mut decide).unwrap();
        let scale = p_ref.abs().max();
        let tol = SAME_ARITHMETIC_TOL * scale;
        assert!(
            max_abs_diff(dynf.covariance(), &p_ref) <= tol,
            "dyn P, draw {draw}"
        );
        assert!((dynf.state() - &x_ref).abs().max() <= SAME_ARITHMETIC_TOL * x_ref.abs().max());
        assert!((&rec.gain - &k_ref).abs().max() <= SAME_ARITHMETIC_TOL * k_ref.abs().max());
        assert_eq!(dynf.covariance(), &dynf.covariance().transpose());

        let fixed = |m: &DMatrix<f64>| m.fixed_view::<N, N>(0, 0).into_owned();
        let mut fix =
            KalmanFilter::<Const<N>>::new(x0.fixed_rows::<N>(0).into_owned(), fixed(&p0)).unwrap();
        fix.predict(&fixed(&phi), &fixed(&q)).unwrap();
        let other_f: SMatrix<f64, M, M> = other.fixed_view::<M, M>(0, 0).into_owned();
        let decide_f = |_: &InnovationView<'_, Const<M>>| match case {
            1 => Decision::GainCovariance(other_f),
            2 => Decision::InflateR(2.5),
            _ => Decision::Accept,
        };
        let h_f: SMatrix<f64, M, N> = h.fixed_view::<M, N>(0, 0).into_owned();
        let r_f: SMatrix<f64, M, M> = r.fixed_view::<M, M>(0, 0).into_owned();
        let z_f: SVector<f64, M> = z.fixed_rows::<M>(0).into_owned();
        let mut decide_f = decide_f;
        fix.update_with(&z_f, &h_f, &r_f, &mut decide_f).unwrap();
        let p_fix = DMatrix::from_column_slice(N, N, fix.covariance().as_slice());
        assert!(max_abs_diff(&p_fix, &p_ref) <= tol, "fixed P, draw {draw}");
        assert_eq!(fix.covariance(), &fix.covariance().transpose());
        for i in 0..N {
            assert!((fix.state()[i] - x_ref[i]).abs() <= SAME_ARITHMETIC_TOL * x_ref.abs().max());
        }
    }
}

#[test]
fn fused_step_matches_the_dense_joseph_reference() {
    check_against_reference::<15, 6>(101);
    check_against_reference::<21, 6>(102);
    check_against_reference::<8, 3>(103);
    check_against_reference::<1, 1>(104);
}
