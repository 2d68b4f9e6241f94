//! Shared helpers: seeded random models.

use aidnav_estimation::nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

pub fn random_matrix(rng: &mut ChaCha8Rng, rows: usize, cols: usize) -> DMatrix<f64> {
    DMatrix::from_fn(rows, cols, |_, _| normal(rng))
}

pub fn random_vector(rng: &mut ChaCha8Rng, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| normal(rng))
}

/// A A^T / n + floor I: symmetric positive definite.
pub fn random_spd(rng: &mut ChaCha8Rng, n: usize, floor: f64) -> DMatrix<f64> {
    let a = random_matrix(rng, n, n);
    let mut s = &a * a.transpose() / n as f64 + DMatrix::identity(n, n) * floor;
    s = (&s + s.transpose()) * 0.5;
    s
}

/// A stable-ish transition: identity plus a small random part.
pub fn random_transition(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
    DMatrix::identity(n, n) + random_matrix(rng, n, n) * (0.1 / (n as f64).sqrt())
}

pub fn max_abs_diff(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).abs().max()
}

/// Smallest eigenvalue of a symmetric matrix.
pub fn min_eigenvalue(a: &DMatrix<f64>) -> f64 {
    a.clone().symmetric_eigen().eigenvalues.min()
}
