//! Overlapping Allan deviation of a uniformly sampled rate signal, and the
//! noise terms read from it (IEEE Std 952-1997, annex C; El-Sheimy, Hou &
//! Niu, "Analysis and modeling of inertial sensors using Allan variance",
//! IEEE TIM 57(1), 2008).
//!
//! For rate samples y₀ … y_{n−1} at interval τ₀, the integrated signal is
//! θ_k = τ₀ Σ_{i<k} y_i (k = 0 … n) and, at the cluster time τ = m τ₀,
//!
//! ```text
//! σ²(τ) = Σ_{k=0}^{n−2m} (θ_{k+2m} − 2θ_{k+m} + θ_k)² / (2 τ² (n − 2m + 1))
//! ```
//!
//! (every overlapping cluster; m = 1, 2, 4, … octave-spaced). The slopes
//! of a log–log plot name the noise terms:
//!
//! | term | σ(τ) | slope | read as |
//! | --- | --- | --- | --- |
//! | white noise of density N (angle / velocity random walk) | N / √τ | −½ | σ √τ (σ at τ = 1 s) |
//! | bias instability B (flicker floor) | ≈ 0.664 B | 0 | σ_min / 0.664 |
//! | rate random walk K | K √(τ / 3) | +½ | σ √(3 / τ) (σ at τ = 3 s) |
//!
//! The function knows nothing about navigation: it takes one axis of any
//! rate (a gyro in rad/s gives N in rad/√s, an accelerometer in m/s² gives
//! N in m/s/√s).
//!
//! ```
//! use aidnav_estimation::allan::{allan_deviation, AllanOptions};
//! // A constant has no Allan deviation; an alternating ±1 at τ₀ = 1 s
//! // has σ(τ₀) = 2/√2 (θ steps +1, −1: differences ±2).
//! let y: Vec<f64> = (0..64).map(|k| if k % 2 == 0 { 1.0 } else { -1.0 }).collect();
//! let c = allan_deviation(&y, 1.0, &AllanOptions::default()).unwrap();
//! assert_eq!(c.tau_s[0], 1.0);
//! assert!((c.deviation[0] - 2.0f64.sqrt()).abs() < 1e-12);
//! assert!(c.deviation[1].abs() < 1e-12); // m = 2: two ±1 cancel
//! ```

/// Factor between the flat minimum of the Allan deviation and the bias
/// instability coefficient B of flicker noise: σ_min = √(2 ln 2 / π) B
/// ≈ 0.664 B (IEEE Std 952-1997, C.3).
pub const BIAS_INSTABILITY_FACTOR: f64 = 0.664_282_040_010_972_6;

/// Fewest consecutive curve points a slope fit reads (one point's local
/// slope is too easily a bump of another term).
pub const MIN_FIT_POINTS: usize = 2;

/// How far a local log–log slope may be from the slope of a noise term for
/// the point to be read as that term (±0.25: half-way to the neighbouring
/// terms' slopes −1, 0, +1).
pub const SLOPE_TOLERANCE: f64 = 0.25;

/// Why no curve could be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum AllanError {
    /// The sample interval is not a positive finite number.
    #[error("sample interval {0} s: must be positive and finite")]
    SampleInterval(f64),
    /// A sample is NaN or infinite.
    #[error("sample {index} is not finite")]
    NonFinite {
        /// Index of the first bad sample.
        index: usize,
    },
    /// Too few samples for a single cluster time.
    #[error("{samples} samples: at least {needed} are needed")]
    TooFewSamples {
        /// Given.
        samples: usize,
        /// Needed.
        needed: usize,
    },
}

/// Which cluster times are computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AllanOptions {
    /// Largest cluster m is such that n / m ≥ this (non-overlapping clusters
    /// in the record; fewer make the longest τ mostly noise). Default 3.
    pub min_clusters: usize,
}

impl Default for AllanOptions {
    fn default() -> Self {
        Self { min_clusters: 3 }
    }
}

/// An Allan deviation curve at octave-spaced cluster times.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize)]
pub struct AllanCurve {
    /// Sample interval τ₀ \[s\].
    pub sample_interval_s: f64,
    /// Number of samples.
    pub samples: usize,
    /// Cluster times τ = m τ₀ \[s\], m = 1, 2, 4, ….
    pub tau_s: Vec<f64>,
    /// σ(τ), in the unit of the rate.
    pub deviation: Vec<f64>,
}

/// A noise coefficient read on a slope of the curve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SlopeFit {
    /// The coefficient (N or K, in the rate's unit × √s or ÷ √s).
    pub value: f64,
    /// The cluster times used: first and last \[s\].
    pub tau_range_s: (f64, f64),
    /// Number of curve points used.
    pub points: usize,
}

/// The bias instability read at the minimum of the curve.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct BiasInstability {
    /// B = σ_min / 0.664, in the rate's unit.
    pub value: f64,
    /// Cluster time of the minimum \[s\].
    pub tau_s: f64,
    /// The minimum is the curve's last point: the curve had not flattened
    /// yet, so the record is too short to see the floor and `value` is an
    /// upper bound.
    pub upper_bound: bool,
}

/// Overlapping Allan deviation of `rate` sampled every `sample_interval_s`,
/// at m = 1, 2, 4, … while n / m ≥ `options.min_clusters` (and 2m ≤ n).
/// Cost O(n log n), memory n + 1 values.
pub fn allan_deviation(
    rate: &[f64],
    sample_interval_s: f64,
    options: &AllanOptions,
) -> Result<AllanCurve, AllanError> {
    if !(sample_interval_s.is_finite() && sample_interval_s > 0.0) {
        return Err(AllanError::SampleInterval(sample_interval_s));
    }
    if let Some(index) = rate.iter().position(|v| !v.is_finite()) {
        return Err(AllanError::NonFinite { index });
    }
    let n = rate.len();
    let min_clusters = options.min_clusters.max(2);
    if n < min_clusters {
        return Err(AllanError::TooFewSamples {
            samples: n,
            needed: min_clusters,
        });
    }
    let theta = integrated(rate, sample_interval_s);
    let mut curve = AllanCurve {
        sample_interval_s,
        samples: n,
        ..AllanCurve::default()
    };
    let mut m = 1usize;
    while 2 * m <= n && n / m >= min_clusters {
        curve.tau_s.push(m as f64 * sample_interval_s);
        curve
            .deviation
            .push(deviation_at(&theta, m, sample_interval_s));
        m *= 2;
    }
    Ok(curve)
}

/// θ_j = Δt Σ_{i<j} (y_i − ȳ), j = 0 … n: relative to the mean rate (a
/// constant cancels in the second difference anyway, and removing it keeps
/// θ small: no cancellation between large numbers over a long record).
fn integrated(rate: &[f64], sample_interval_s: f64) -> Vec<f64> {
    let mean = rate.iter().sum::<f64>() / rate.len().max(1) as f64;
    let mut theta = Vec::with_capacity(rate.len() + 1);
    theta.push(0.0);
    let mut acc = 0.0;
    for y in rate {
        acc += (y - mean) * sample_interval_s;
        theta.push(acc);
    }
    theta
}

/// The overlapping Allan deviation at cluster m from the integrated
/// signal θ (2m ≤ n).
fn deviation_at(theta: &[f64], m: usize, sample_interval_s: f64) -> f64 {
    let n = theta.len() - 1;
    let tau = m as f64 * sample_interval_s;
    let terms = n - 2 * m + 1;
    let sum: f64 = (0..terms)
        .map(|k| {
            let d = theta[k + 2 * m] - 2.0 * theta[k + m] + theta[k];
            d * d
        })
        .sum();
    (sum / (2.0 * tau * tau * terms as f64)).sqrt()
}

/// The overlapping Allan deviation of `rate` sampled every
/// `sample_interval_s` \[s\] at each averaging time of `taus_s` \[s\],
/// each rounded to a whole number m of samples (the same estimator as
/// [`allan_deviation`] at any τ, not only octaves); a τ with m < 1 or
/// 2m > n (not one pair of averages) gives NaN.
///
/// ```
/// use aidnav_estimation::allan::allan_deviation_at;
/// // A ramp of slope r has σ(τ) = r τ / √2.
/// let ramp: Vec<f64> = (0..1000).map(|k| 0.5 * k as f64 * 0.1).collect();
/// let adev = allan_deviation_at(&ramp, 0.1, &[1.0, 5.0, 1000.0]);
/// assert!((adev[0] - 0.5 / 2f64.sqrt()).abs() < 1e-9);
/// assert!((adev[1] - 2.5 / 2f64.sqrt()).abs() < 1e-9);
/// assert!(adev[2].is_nan());
/// ```
pub fn allan_deviation_at(rate: &[f64], sample_interval_s: f64, taus_s: &[f64]) -> Vec<f64> {
    let theta = integrated(rate, sample_interval_s);
    let n = rate.len();
    taus_s
        .iter()
        .map(|&tau| {
            let m = (tau / sample_interval_s).round();
            if m.is_nan() || m < 1.0 || 2.0 * m > n as f64 {
                f64::NAN
            } else {
                deviation_at(&theta, m as usize, sample_interval_s)
            }
        })
        .collect()
}

impl AllanCurve {
    /// Local log–log slope at each point (central difference; one-sided at
    /// the ends; NaN with fewer than two points or a zero deviation).
    pub fn slopes(&self) -> Vec<f64> {
        let n = self.tau_s.len();
        let slope = |a: usize, b: usize| {
            (self.deviation[b].ln() - self.deviation[a].ln())
                / (self.tau_s[b].ln() - self.tau_s[a].ln())
        };
        (0..n)
            .map(|i| {
                if n < 2 {
                    f64::NAN
                } else if i == 0 {
                    slope(0, 1)
                } else if i == n - 1 {
                    slope(n - 2, n - 1)
                } else {
                    slope(i - 1, i + 1)
                }
            })
            .collect()
    }

    /// Index of the smallest deviation.
    fn minimum(&self) -> Option<usize> {
        (0..self.deviation.len()).min_by(|&a, &b| self.deviation[a].total_cmp(&self.deviation[b]))
    }

    /// The longest run of consecutive points in `range` whose local slope
    /// is within [`SLOPE_TOLERANCE`] of `target`; the coefficient is the
    /// geometric mean over the run of σ(τ) τ^(−target) × `scale`.
    fn fit_slope(
        &self,
        target: f64,
        scale: f64,
        range: std::ops::Range<usize>,
    ) -> Option<SlopeFit> {
        let slopes = self.slopes();
        let mut best: Option<(usize, usize)> = None;
        let mut run_start = None;
        for i in range.clone().chain(std::iter::once(range.end)) {
            let inside = i < range.end
                && slopes[i].is_finite()
                && (slopes[i] - target).abs() <= SLOPE_TOLERANCE;
            match (inside, run_start) {
                (true, None) => run_start = Some(i),
                (false, Some(s)) => {
                    if best.is_none_or(|(a, b)| i - s > b - a) {
                        best = Some((s, i));
                    }
                    run_start = None;
                }
                _ => {}
            }
        }
        let (a, b) = best.filter(|(a, b)| b - a >= MIN_FIT_POINTS)?;
        let mean_ln = (a..b)
            .map(|i| self.deviation[i].ln() - target * self.tau_s[i].ln())
            .sum::<f64>()
            / (b - a) as f64;
        Some(SlopeFit {
            value: mean_ln.exp() * scale,
            tau_range_s: (self.tau_s[a], self.tau_s[b - 1]),
            points: b - a,
        })
    }

    /// White-noise density N (σ = N/√τ): the slope −½ left of the minimum
    /// (at and before it). None when fewer than [`MIN_FIT_POINTS`]
    /// consecutive points there have a slope within ±0.25 of −½ (another
    /// term, e.g. a vibration line with slope −1, dominates).
    pub fn white_noise(&self) -> Option<SlopeFit> {
        self.white_noise_above(0.0)
    }

    /// [`white_noise`](Self::white_noise) read only at τ ≥ `min_tau_s`
    /// (the slopes still use the neighbouring points): leaves out a band
    /// the user of the noise never sees, e.g. the one a moving average of
    /// that length removes, where a vibration line may dominate.
    pub fn white_noise_above(&self, min_tau_s: f64) -> Option<SlopeFit> {
        let end = self.minimum()? + 1;
        let start = self.tau_s.partition_point(|&t| t < min_tau_s).min(end);
        self.fit_slope(-0.5, 1.0, start..end)
    }

    /// Rate random walk K (σ = K √(τ/3)): the slope +½ right of the minimum.
    /// None when the curve does not rise there (the usual case for a record
    /// of a minute or less).
    pub fn random_walk(&self) -> Option<SlopeFit> {
        let start = self.minimum()?;
        self.fit_slope(0.5, 3f64.sqrt(), start..self.tau_s.len())
    }

    /// Bias instability B = σ_min / 0.664 at the curve's minimum; an upper
    /// bound when the minimum is the last point.
    pub fn bias_instability(&self) -> Option<BiasInstability> {
        let i = self.minimum()?;
        Some(BiasInstability {
            value: self.deviation[i] / BIAS_INSTABILITY_FACTOR,
            tau_s: self.tau_s[i],
            upper_bound: i + 1 == self.tau_s.len(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    fn normal(rng: &mut ChaCha8Rng) -> f64 {
        StandardNormal.sample(rng)
    }

    /// Relative error of an Allan deviation estimate from n samples at
    /// cluster m, white noise: ≈ 1/√(2 (n/m − 1)) for non-overlapping
    /// clusters (IEEE 952 C.2); overlapping ones do better. Checks allow
    /// three of those.
    fn allowed(n: usize, m: usize) -> f64 {
        3.0 / (2.0 * (n as f64 / m as f64 - 1.0)).sqrt()
    }

    /// White noise of density N sampled at τ₀ (std N/√τ₀) gives N/√τ at
    /// every cluster time, and the slope fit reads N.
    #[test]
    fn white_noise_follows_n_over_root_tau() {
        let (n, dt, density) = (1 << 16, 0.01f64, 0.003);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let y: Vec<f64> = (0..n)
            .map(|_| 5.0 + density / dt.sqrt() * normal(&mut rng))
            .collect();
        let c = allan_deviation(&y, dt, &AllanOptions::default()).unwrap();
        assert_eq!(c.tau_s.len(), 15); // m = 1 … 2^14 (n/m ≥ 3)
        for (k, (&tau, &s)) in c.tau_s.iter().zip(&c.deviation).enumerate() {
            let expected = density / tau.sqrt();
            assert!(
                (s / expected - 1.0).abs() < allowed(n, 1 << k),
                "τ = {tau}: {s} vs {expected}"
            );
        }
        let fit = c.white_noise().unwrap();
        assert!((fit.value / density - 1.0).abs() < 0.02, "{fit:?}");
        assert!(fit.points >= 8, "{fit:?}");
        assert!(c.random_walk().is_none());
        // White noise only: the minimum is at the longest τ, a bound.
        let b = c.bias_instability().unwrap();
        assert!(b.upper_bound);
    }

    /// A rate random walk y_k = y_{k−1} + K √τ₀ w_k gives K √(τ/3).
    #[test]
    fn rate_random_walk_follows_k_root_tau_over_three() {
        let (n, dt, k_rw) = (1 << 16, 0.01f64, 2e-4);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let mut y = 0.0;
        let rate: Vec<f64> = (0..n)
            .map(|_| {
                y += k_rw * dt.sqrt() * normal(&mut rng);
                y
            })
            .collect();
        let c = allan_deviation(&rate, dt, &AllanOptions::default()).unwrap();
        // m = 8 … 128 (n/m ≥ 512): a random walk's estimate has far fewer
        // degrees of freedom than white noise's at the same m (its
        // differences are correlated), so long τ scatter by 15 % and more;
        // the shortest τ carry a discrete-time term K²τ₀/6 … .
        for (&tau, &s) in c.tau_s.iter().zip(&c.deviation).skip(3).take(5) {
            let expected = k_rw * (tau / 3.0).sqrt();
            assert!(
                (s / expected - 1.0).abs() < 0.1,
                "τ = {tau}: {s} vs {expected}"
            );
        }
        let fit = c.random_walk().unwrap();
        assert!((fit.value / k_rw - 1.0).abs() < 0.15, "{fit:?}");
    }

    /// White noise plus a rate random walk: σ² = N²/τ + K²τ/3 has its
    /// minimum σ²_min = 2NK/√3 at τ* = √3 N/K; the octave points straddle
    /// it within a factor √2 in τ, where σ is at most 3 % above σ_min.
    /// The bias instability is read as σ_min / 0.664 (flat minimum).
    #[test]
    fn bias_instability_is_read_at_the_flat_minimum() {
        let (n, dt, density, k_rw) = (1 << 17, 0.01f64, 0.003, 2e-4);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut walk = 0.0;
        let rate: Vec<f64> = (0..n)
            .map(|_| {
                walk += k_rw * dt.sqrt() * normal(&mut rng);
                walk + density / dt.sqrt() * normal(&mut rng)
            })
            .collect();
        let c = allan_deviation(&rate, dt, &AllanOptions::default()).unwrap();
        let tau_star = 3f64.sqrt() * density / k_rw;
        let sigma_min = (2.0 * density * k_rw / 3f64.sqrt()).sqrt();
        let b = c.bias_instability().unwrap();
        assert!(!b.upper_bound);
        assert!(
            b.tau_s > tau_star / 2.0 && b.tau_s < tau_star * 2.0,
            "{b:?} τ* {tau_star}"
        );
        assert!(
            (b.value * BIAS_INSTABILITY_FACTOR / sigma_min - 1.0).abs() < 0.08,
            "{} vs {sigma_min}",
            b.value * BIAS_INSTABILITY_FACTOR
        );
        let white = c.white_noise().unwrap();
        assert!((white.value / density - 1.0).abs() < 0.05, "{white:?}");
    }

    /// The reading rules on a hand-made curve: the −½ run, a flat floor at
    /// 0.664 B, the +½ run.
    #[test]
    fn reading_rules_on_a_constructed_curve() {
        let (n_w, b, k) = (0.001, 0.002, 0.0004);
        let tau_s: Vec<f64> = (0..14).map(|i| 0.01 * 2f64.powi(i)).collect();
        // Piecewise: white, then the floor, then the walk.
        let deviation: Vec<f64> = tau_s
            .iter()
            .map(|&t| {
                (n_w / t.sqrt())
                    .max(BIAS_INSTABILITY_FACTOR * b)
                    .max(k * (t / 3.0).sqrt())
            })
            .collect();
        let c = AllanCurve {
            sample_interval_s: 0.01,
            samples: 1 << 20,
            tau_s,
            deviation,
        };
        let w = c.white_noise().unwrap();
        assert!((w.value / n_w - 1.0).abs() < 1e-12, "{w:?}");
        assert_eq!(w.tau_range_s.0, 0.01);
        let above = c.white_noise_above(0.05).unwrap();
        assert_eq!(above.tau_range_s.0, 0.08);
        assert!((above.value / n_w - 1.0).abs() < 1e-12);
        // Nothing left of the floor above 10 s.
        assert!(c.white_noise_above(10.0).is_none());
        let bi = c.bias_instability().unwrap();
        assert!((bi.value / b - 1.0).abs() < 1e-12 && !bi.upper_bound);
        let rw = c.random_walk().unwrap();
        assert!((rw.value / k - 1.0).abs() < 1e-12, "{rw:?}");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let o = AllanOptions::default();
        assert_eq!(
            allan_deviation(&[1.0; 10], 0.0, &o),
            Err(AllanError::SampleInterval(0.0))
        );
        assert_eq!(
            allan_deviation(&[1.0, f64::NAN, 2.0], 0.1, &o),
            Err(AllanError::NonFinite { index: 1 })
        );
        assert_eq!(
            allan_deviation(&[1.0, 2.0], 0.1, &o),
            Err(AllanError::TooFewSamples {
                samples: 2,
                needed: 3
            })
        );
        // A constant: a zero curve, no slope, the minimum a bound.
        let c = allan_deviation(&[3.0; 12], 0.1, &o).unwrap();
        assert!(c.deviation.iter().all(|&d| d == 0.0));
        assert!(c.white_noise().is_none());
    }
}
