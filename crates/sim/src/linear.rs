//! Truth and measurement simulation of a linear Gaussian model.

use aidnav_estimation::LinearGaussianModel;
use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand::RngExt;

use crate::rng::standard_normal;

/// A simulated truth trajectory and its measurements.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearSimulation {
    /// True state per epoch.
    pub truth: Vec<DVector<f64>>,
    /// Measurement per epoch (None where dropped).
    pub measurements: Vec<Vec<Option<f64>>>,
}

/// A square-root factor L with L Lᵀ = A for a symmetric PSD A (eigen
/// decomposition, so singular A such as Q of a partly deterministic model works).
pub fn covariance_factor(a: &DMatrix<f64>) -> DMatrix<f64> {
    let eig = a.clone().symmetric_eigen();
    let sqrt = eig.eigenvalues.map(|l| l.max(0.0).sqrt());
    &eig.eigenvectors * DMatrix::from_diagonal(&sqrt)
}

/// Simulate `epochs` epochs: x_0 ~ N(x0, P0), x_k = Φ x_{k−1} + w, z_k = H x_k + v;
/// each component is dropped with probability `missing_probability`.
pub fn simulate<R: Rng + ?Sized>(
    model: &LinearGaussianModel,
    epochs: usize,
    missing_probability: f64,
    rng: &mut R,
) -> LinearSimulation {
    let n = model.states();
    let m = model.measurements();
    let (lp, lq, lr) = (
        covariance_factor(model.p0()),
        covariance_factor(model.q()),
        covariance_factor(model.r()),
    );
    let draw = |k: usize, rng: &mut R| DVector::from_fn(k, |_, _| standard_normal(rng));
    let mut x = model.x0() + &lp * draw(n, rng);
    let mut truth = Vec::with_capacity(epochs);
    let mut measurements = Vec::with_capacity(epochs);
    for k in 0..epochs {
        if k > 0 {
            x = model.phi() * &x + &lq * draw(n, rng);
        }
        let z = model.h() * &x + &lr * draw(m, rng);
        let zs = z
            .iter()
            .map(|&v| (rng.random::<f64>() >= missing_probability).then_some(v))
            .collect();
        truth.push(x.clone());
        measurements.push(zs);
    }
    LinearSimulation {
        truth,
        measurements,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::run_rng;

    #[test]
    fn factor_reproduces_psd_matrices() {
        let a = DMatrix::from_row_slice(3, 3, &[4.0, 2.0, 0.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0]);
        let l = covariance_factor(&a);
        assert!((&l * l.transpose() - &a).abs().max() < 1e-12);
    }

    #[test]
    fn simulated_noise_has_the_model_statistics() {
        // Static scalar, x0 ~ N(0, 0): z = v with R = 4 ⇒ sample variance ≈ 4.
        let model = LinearGaussianModel::new(
            DMatrix::identity(1, 1),
            DMatrix::zeros(1, 1),
            DMatrix::identity(1, 1),
            DMatrix::from_element(1, 1, 4.0),
            DVector::zeros(1),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let sim = simulate(&model, 20_000, 0.25, &mut run_rng(3, 0));
        let present: Vec<f64> = sim.measurements.iter().filter_map(|z| z[0]).collect();
        let frac = present.len() as f64 / 20_000.0;
        assert!((frac - 0.75).abs() < 0.02, "{frac}");
        let var = present.iter().map(|v| v * v).sum::<f64>() / present.len() as f64;
        // σ of the variance estimate ≈ 4·√(2/15000) ≈ 0.046: allow 4σ.
        assert!((var - 4.0).abs() < 0.2, "{var}");
    }
}
