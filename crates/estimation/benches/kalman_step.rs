//! One predict + update (Joseph form, Cholesky-solved gain) for the filter
//! sizes of the navigation filters: 15 states / 6 measurements (INS error
//! state with GNSS position + velocity) and 21 / 6 (with scale factors), in
//! compile-time and run-time sized storage. Compare with bench/cpp (Eigen) and
//! bench/filterpy_step.py on the same machine; see bench/README.md.

use std::hint::black_box;

use aidnav_estimation::nalgebra::{Const, DMatrix, DVector, SMatrix, SVector};
use aidnav_estimation::{KalmanFilter, TrailingDiagonal};
use criterion::{Criterion, criterion_group, criterion_main};

/// The matrices of one benchmark problem.
struct Problem {
    phi: DMatrix<f64>,
    q: DMatrix<f64>,
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    p0: DMatrix<f64>,
    z: DVector<f64>,
}

/// Deterministic well-conditioned test matrices (no RNG needed for timing);
/// bench/cpp and bench/filterpy_step.py build the very same ones.
fn problem(n: usize, m: usize) -> Problem {
    let phi = DMatrix::from_fn(n, n, |i, j| {
        if i == j {
            1.0
        } else {
            0.01 * (((i * 7 + j * 3) % 11) as f64 - 5.0) / 5.0
        }
    });
    let q = DMatrix::from_fn(
        n,
        n,
        |i, j| if i == j { 1e-4 * (1.0 + i as f64) } else { 0.0 },
    );
    let h = DMatrix::from_fn(m, n, |i, j| {
        if i == j {
            1.0
        } else if j == i + m {
            0.1
        } else {
            0.0
        }
    });
    let r = DMatrix::from_fn(
        m,
        m,
        |i, j| if i == j { 0.5 + 0.1 * i as f64 } else { 0.01 },
    );
    let a = DMatrix::from_fn(n, n, |i, j| (((i * 5 + j * 13) % 17) as f64 - 8.0) / 8.0);
    let p0 = &a * a.transpose() / n as f64 + DMatrix::identity(n, n);
    let z = DVector::from_fn(m, |i, _| 0.1 * i as f64);
    Problem {
        phi,
        q,
        h,
        r,
        p0,
        z,
    }
}

fn bench_fixed<const N: usize, const M: usize>(c: &mut Criterion, name: &str) {
    let Problem {
        phi,
        q,
        h,
        r,
        p0,
        z,
    } = problem(N, M);
    let phi: SMatrix<f64, N, N> = phi.fixed_view::<N, N>(0, 0).into_owned();
    let q: SMatrix<f64, N, N> = q.fixed_view::<N, N>(0, 0).into_owned();
    let h: SMatrix<f64, M, N> = h.fixed_view::<M, N>(0, 0).into_owned();
    let r: SMatrix<f64, M, M> = r.fixed_view::<M, M>(0, 0).into_owned();
    let z: SVector<f64, M> = z.fixed_rows::<M>(0).into_owned();
    let mut kf =
        KalmanFilter::<Const<N>>::new(SVector::zeros(), p0.fixed_view::<N, N>(0, 0).into_owned())
            .unwrap();
    c.bench_function(name, |b| {
        b.iter(|| {
            kf.predict(black_box(&phi), black_box(&q)).unwrap();
            black_box(
                kf.update(black_box(&z), black_box(&h), black_box(&r))
                    .unwrap(),
            );
        })
    });
    let base = kf.clone();
    c.bench_function(&format!("{name}/predict_only"), |b| {
        b.iter(|| {
            let mut k = base.clone();
            k.predict(black_box(&phi), black_box(&q)).unwrap();
            black_box(k)
        })
    });
    // Φ with its rows from 9 on diagonal (an INS error model's instrument
    // states): the dense predict against the structured one.
    if N > 9 {
        let mut structured_phi = phi;
        for i in 9..N {
            for j in 0..N {
                if i != j {
                    structured_phi[(i, j)] = 0.0;
                }
            }
        }
        c.bench_function(&format!("{name}/predict_trailing_diagonal_dense"), |b| {
            b.iter(|| {
                let mut k = base.clone();
                k.predict(black_box(&structured_phi), black_box(&q))
                    .unwrap();
                black_box(k)
            })
        });
        c.bench_function(
            &format!("{name}/predict_trailing_diagonal_structured"),
            |b| {
                b.iter(|| {
                    let mut k = base.clone();
                    k.predict_structured(
                        black_box(&structured_phi),
                        black_box(&q),
                        TrailingDiagonal::new(9),
                    )
                    .unwrap();
                    black_box(k)
                })
            },
        );
    }
    c.bench_function(&format!("{name}/update_only"), |b| {
        b.iter(|| {
            let mut k = base.clone();
            black_box(
                k.update(black_box(&z), black_box(&h), black_box(&r))
                    .unwrap(),
            );
            black_box(k)
        })
    });
}

fn bench_dyn(c: &mut Criterion, name: &str, n: usize, m: usize) {
    let Problem {
        phi,
        q,
        h,
        r,
        p0,
        z,
    } = problem(n, m);
    let mut kf = KalmanFilter::new(DVector::zeros(n), p0).unwrap();
    c.bench_function(name, |b| {
        b.iter(|| {
            kf.predict(black_box(&phi), black_box(&q)).unwrap();
            black_box(
                kf.update(black_box(&z), black_box(&h), black_box(&r))
                    .unwrap(),
            );
        })
    });
}

fn kalman_step(c: &mut Criterion) {
    bench_fixed::<15, 6>(c, "predict_update/fixed/15x6");
    bench_fixed::<21, 6>(c, "predict_update/fixed/21x6");
    bench_dyn(c, "predict_update/dyn/15x6", 15, 6);
    bench_dyn(c, "predict_update/dyn/21x6", 21, 6);
}

criterion_group!(benches, kalman_step);
criterion_main!(benches);
