//! The overlapping Allan deviation of a sampled rate signal (IEEE Std
//! 952/1293 definition), to check the noise of the simulated sensors
//! against their datasheet coefficients.
//!
//! For rate samples y₀ … y_{N−1} at interval Δt, the integrated signal
//! θ_j = Δt Σ_{i<j} y_i (j = 0 … N) and τ = m Δt:
//!
//! `σ²(τ) = Σ_{j=0}^{N−2m} (θ_{j+2m} − 2 θ_{j+m} + θ_j)² / (2 τ² (N − 2m + 1))`.
//!
//! Closed forms for the processes of [`crate::imu`] (continuous time):
//! - white rate noise of density N (per-sample σ = N √f_s):
//!   σ(τ) = N / √τ, exact for the discrete estimator too;
//! - rate random walk of coefficient K (`ẏ = K w`): σ²(τ) = K² τ / 3
//!   (discrete: K² (τ/3 + Δt²/(6τ)));
//! - first-order Gauss–Markov of stationary σ and correlation time T
//!   ([`gauss_markov_adev`]).

/// The overlapping Allan deviation at any averaging times (the
/// estimator `aidnav tune` uses), re-exported for the checks.
pub use aidnav_estimation::allan::allan_deviation_at as allan_deviation;

/// The Allan deviation at `tau_s` \[s\] of a first-order Gauss–Markov
/// process of stationary σ `sigma` (unit of the process) and correlation
/// time T `correlation_time_s` \[s\] (continuous time):
///
/// `σ²(τ) = (2σ² T / τ) [1 − (T / 2τ)(3 − 4 e^{−τ/T} + e^{−2τ/T})]`,
///
/// which rises as a rate random walk of K² = 2σ²/T (σ²τ/3 · 2/T) for
/// τ ≪ T, peaks at ≈ 0.617 σ near τ ≈ 1.89 T and falls as white noise of
/// density σ √(2T) for τ ≫ T.
///
/// ```
/// use aidnav_sim::allan::gauss_markov_adev;
/// let peak = (1..400).map(|i| gauss_markov_adev(1.0, 1.0, i as f64 * 0.01)).fold(0.0, f64::max);
/// assert!((peak - 0.6174).abs() < 1e-4);
/// ```
pub fn gauss_markov_adev(sigma: f64, correlation_time_s: f64, tau_s: f64) -> f64 {
    let (t, x) = (correlation_time_s, tau_s / correlation_time_s);
    let bracket = if x < 0.1 {
        // 1 − (3 − 4e^{−x} + e^{−2x}) / (2x) = Σ_{n≥2} c_n xⁿ with
        // c_n = (−1)ⁿ (2ⁿ⁺¹ − 4) / (2 (n + 1)!) = x²/3 − x³/4 + 7x⁴/60 − …,
        // which the closed form loses to cancellation for small x; to
        // n = 12 the truncation is < 1e-15 relative at x = 0.1.
        let (mut sum, mut power, mut factorial) = (0.0, x, 2.0);
        for n in 2..=12 {
            power *= x;
            factorial *= (n + 1) as f64;
            let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            sum += sign * (2f64.powi(n + 1) - 4.0) / (2.0 * factorial) * power;
        }
        sum
    } else {
        1.0 - (3.0 - 4.0 * (-x).exp() + (-2.0 * x).exp()) / (2.0 * x)
    };
    (2.0 * sigma * sigma * t / tau_s * bracket).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::{run_rng, standard_normal};

    /// Relative 1σ error of an overlapping ADEV estimate from data of
    /// duration `length_s` at τ: ≈ 1/√(2 (L/τ − 1)) for the non-
    /// overlapping estimator, which bounds the overlapping one.
    fn relative_sigma(length_s: f64, tau_s: f64) -> f64 {
        1.0 / (2.0 * (length_s / tau_s - 1.0)).sqrt()
    }

    #[test]
    fn white_noise_falls_as_one_over_root_tau() {
        let (sigma, rate) = (0.3, 100.0);
        let n = 360_000; // 1 h
        let mut rng = run_rng(5, 0);
        let y: Vec<f64> = (0..n).map(|_| sigma * standard_normal(&mut rng)).collect();
        let taus = [0.01, 0.1, 1.0, 10.0, 60.0];
        let adev = allan_deviation(&y, 1.0 / rate, &taus);
        for (tau, a) in taus.iter().zip(&adev) {
            let expect = sigma / (tau * rate).sqrt();
            let rel = a / expect - 1.0;
            let tol = 4.0 * relative_sigma(n as f64 / rate, *tau);
            eprintln!("white τ {tau:>5} s: {a:.5e} vs {expect:.5e} ({rel:+.4}, tol {tol:.4})");
            assert!(rel.abs() < tol, "{tau} {a} {expect}");
        }
    }

    #[test]
    fn rate_random_walk_rises_as_root_tau_over_three() {
        let (k, rate) = (2e-3, 10.0_f64);
        let dt = 1.0 / rate;
        let n = 200_000; // 20 000 s
        let mut rng = run_rng(6, 0);
        let mut x = 0.0;
        let y: Vec<f64> = (0..n)
            .map(|_| {
                x += k * dt.sqrt() * standard_normal(&mut rng);
                x
            })
            .collect();
        let taus = [1.0, 10.0, 100.0];
        let adev = allan_deviation(&y, dt, &taus);
        for (tau, a) in taus.iter().zip(&adev) {
            let expect = k * (tau / 3.0 + dt * dt / (6.0 * tau)).sqrt();
            let rel = a / expect - 1.0;
            // Random walk: fewer effective degrees of freedom than white
            // noise at the same L/τ (≈ 1.2 × the white-noise error for
            // the overlapping estimator); 5σ of the white-noise bound.
            let tol = 5.0 * relative_sigma(n as f64 * dt, *tau);
            eprintln!("rrw τ {tau:>5} s: {a:.5e} vs {expect:.5e} ({rel:+.4}, tol {tol:.4})");
            assert!(rel.abs() < tol, "{tau} {a} {expect}");
        }
    }

    #[test]
    fn gauss_markov_closed_form_has_its_limits() {
        let (s, t) = (2.0_f64, 50.0);
        // τ ≪ T: rate random walk K² = 2σ²/T.
        let tau = 0.01;
        let rrw = (2.0 * s * s / t * tau / 3.0).sqrt();
        assert!((gauss_markov_adev(s, t, tau) / rrw - 1.0).abs() < 1e-4);
        // τ ≫ T: white noise of density σ √(2T).
        let tau = 1e6;
        let white = s * (2.0 * t / tau).sqrt();
        assert!((gauss_markov_adev(s, t, tau) / white - 1.0).abs() < 1e-4);
        // Continuous across the series switch (x = 0.1): the ratio is the
        // local slope d ln σ / d ln τ ≈ 0.5 − 3x/8 + … = 0.46318 times 2e-9.
        let (a, b) = (
            gauss_markov_adev(s, t, (1.0 - 1e-9) * 0.1 * t),
            gauss_markov_adev(s, t, (1.0 + 1e-9) * 0.1 * t),
        );
        let slope = (1.0 - a / b) / 2e-9;
        assert!((slope - 0.46318).abs() < 1e-4, "{a} {b} {slope}");
    }

    #[test]
    fn short_data_gives_nan() {
        assert!(allan_deviation(&[1.0, 2.0, 3.0], 1.0, &[2.0, 0.1])[0].is_nan());
        assert!(allan_deviation(&[1.0, 2.0, 3.0], 1.0, &[0.1])[0].is_nan());
        assert!(allan_deviation(&[], 1.0, &[1.0])[0].is_nan());
    }
}
