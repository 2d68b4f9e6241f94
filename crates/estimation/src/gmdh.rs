//! Self-organising model selection for time series (combinatorial GMDH,
//! Ivakhnenko's group method of data handling), as spec 20 uses it to bridge
//! GNSS outages: the structure of `x(t)` is *selected* from candidate basis
//! functions by an external criterion, not assumed.
//!
//! Candidates are *units*: polynomial terms `1, t, t², …` and harmonic units
//! `a sin ωt + b cos ωt` (one unit per frequency: the amplitude–phase form
//! `A sin(ωt + φ)` of spec 20 eq. 11) at given frequencies and at frequencies
//! searched on a grid. The samples are split into a training part A and a
//! checking part B (alternating, or the latest fraction as B). Every structure
//! is fitted by least squares on A and scored on B by the regularity
//! criterion `Δ²(B) = Σ_B (y − ŷ_A)² / Σ_B (y − ȳ_B)²`. Complexity grows one
//! unit at a time — all single units and pairs exhaustively, then the best
//! [`GmdhConfig::beam`] structures of each complexity extended by one unit —
//! and stops when the best criterion no longer improves by
//! [`GmdhConfig::min_improvement`]. The winner is refitted on all samples.
//!
//! ```
//! use aidnav_estimation::gmdh::{GmdhConfig, select};
//! let w = 2.0 * std::f64::consts::PI / 50.0;
//! let t: Vec<f64> = (0..200).map(|k| k as f64).collect();
//! let y: Vec<f64> = t.iter().map(|&t| 0.5 + 0.01 * t + 2.0 * (w * t).sin()).collect();
//! let sel = select(&t, &y, &GmdhConfig { frequencies: vec![w], ..GmdhConfig::default() }).unwrap();
//! assert!((sel.model.predict(250.0) - (0.5 + 2.5 + 2.0 * (w * 250.0).sin())).abs() < 1e-6);
//! ```

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

/// One candidate unit of a model structure.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Unit {
    /// `τᵖ` with τ the time normalised to [−1, 1] over the fitted window (p = 0: constant).
    Power {
        /// Exponent.
        p: u32,
    },
    /// `a sin ωt + b cos ωt` (two coefficients).
    Harmonic {
        /// Angular frequency ω [rad/s].
        omega: f64,
    },
}

impl Unit {
    fn columns(&self) -> usize {
        match self {
            Unit::Power { .. } => 1,
            Unit::Harmonic { .. } => 2,
        }
    }
}

/// How the samples are split into training (A) and checking (B) parts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Split {
    /// Even samples train, odd samples check.
    Alternating,
    /// The latest `fraction` of the samples check (favours models that extrapolate).
    Latest {
        /// Fraction in B, in (0, 1).
        fraction: f64,
    },
}

/// Grid of searched frequencies.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrequencyGrid {
    /// Lowest ω [rad/s], > 0.
    pub min: f64,
    /// Highest ω [rad/s], > min.
    pub max: f64,
    /// Number of grid points (log-spaced), ≥ 1.
    pub count: usize,
}

/// Configuration of the selection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GmdhConfig {
    /// Highest polynomial degree among the candidates. Default 2.
    pub max_degree: u32,
    /// Given frequencies [rad/s] (e.g. Schuler, Earth rate). Default none.
    pub frequencies: Vec<f64>,
    /// Searched frequencies. Default none.
    pub search: Option<FrequencyGrid>,
    /// Training / checking split. Default alternating.
    pub split: Split,
    /// Most units in a structure. Default 4.
    pub max_units: usize,
    /// Structures of each complexity carried to the next. Default 8.
    pub beam: usize,
    /// Relative improvement of the criterion needed to accept one more unit.
    /// Default 0.02.
    pub min_improvement: f64,
    /// Guard against selecting noise: the improvement must also exceed
    /// `noise_guard / n_B` (n_B samples in B). The criterion of a useless unit
    /// fluctuates by a few / n_B, and the best of many useless candidates (a
    /// searched grid) beats it by several of those. Default 15.
    pub noise_guard: f64,
    /// Refine the frequencies of the best searched harmonic units by a
    /// golden-section search between their grid neighbours (on the training
    /// part only). Default true.
    pub refine: bool,
    /// Forecast horizon H beyond the last sample that the model is selected
    /// for \[s\]. When set, the external criterion becomes the combined
    /// criterion `regularity + balance`, where the *balance of forecasts* is
    /// the mean squared difference, over (t_last, t_last + H], between the
    /// structure fitted on the earlier half of the samples and the same
    /// structure fitted on the later half, divided by the variance of the
    /// checking part. A structure whose extrapolation depends on which
    /// stretch of the record it was fitted to (a harmonic slower than the
    /// record, a high power of t) is penalised in proportion to the horizon
    /// actually predicted; an alternating split cannot see this when the
    /// samples are correlated in time. Default none (regularity alone).
    pub horizon_s: Option<f64>,
}

impl Default for GmdhConfig {
    fn default() -> Self {
        Self {
            max_degree: 2,
            frequencies: Vec::new(),
            search: None,
            split: Split::Alternating,
            max_units: 4,
            beam: 8,
            min_improvement: 0.02,
            noise_guard: 15.0,
            refine: true,
            horizon_s: None,
        }
    }
}

/// Why a selection could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GmdhError {
    /// Times and values differ in length.
    #[error("{times} times but {values} values")]
    LengthMismatch {
        /// Number of times.
        times: usize,
        /// Number of values.
        values: usize,
    },
    /// Too few samples for even the simplest structure on both parts.
    #[error("{samples} samples: at least {needed} are needed")]
    TooFewSamples {
        /// Given.
        samples: usize,
        /// Needed.
        needed: usize,
    },
    /// A time or value is NaN or infinite.
    #[error("sample {index} is not finite")]
    NonFinite {
        /// Index of the first bad sample.
        index: usize,
    },
    /// Times not strictly increasing.
    #[error("time {index} is not after the previous one")]
    NotIncreasing {
        /// Index of the first bad time.
        index: usize,
    },
    /// A configuration value out of range.
    #[error("invalid configuration: {0}")]
    Config(String),
}

/// A fitted structure.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GmdhModel {
    /// The units, in fitting order.
    pub units: Vec<Unit>,
    /// Coefficients, one per column (two per harmonic unit: sin, cos).
    pub coefficients: Vec<f64>,
    /// Time origin and half-span normalising polynomial terms: τ = (t − t_mid) / half_span.
    pub t_mid: f64,
    /// See `t_mid`.
    pub half_span: f64,
}

impl GmdhModel {
    /// Value of the model at time `t` (any t: inside the window or beyond it).
    pub fn predict(&self, t: f64) -> f64 {
        let mut row = Vec::with_capacity(self.coefficients.len());
        push_row(&mut row, &self.units, t, self.t_mid, self.half_span);
        row.iter().zip(&self.coefficients).map(|(a, c)| a * c).sum()
    }
}

/// The outcome of a selection: the model and the criterion path.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GmdhSelection {
    /// Winning structure refitted on all samples.
    pub model: GmdhModel,
    /// Its external criterion: the regularity on B (fitted on A), plus the
    /// balance of forecasts when [`GmdhConfig::horizon_s`] is set.
    pub criterion: f64,
    /// Best criterion at each complexity explored (1 unit, 2 units, …).
    pub best_by_complexity: Vec<f64>,
}

fn push_row(row: &mut Vec<f64>, units: &[Unit], t: f64, t_mid: f64, half_span: f64) {
    let tau = (t - t_mid) / half_span;
    for u in units {
        match *u {
            Unit::Power { p } => row.push(tau.powi(p as i32)),
            Unit::Harmonic { omega } => {
                row.push((omega * t).sin());
                row.push((omega * t).cos());
            }
        }
    }
}

/// The samples and the time normalisation shared by every fit.
struct Window<'a> {
    t: &'a [f64],
    y: &'a [f64],
    t_mid: f64,
    half_span: f64,
}

/// Least-squares coefficients of `units` on the samples `idx`, or None if rank-deficient.
fn fit(units: &[Unit], w: &Window<'_>, idx: &[usize]) -> Option<Vec<f64>> {
    let (t, y, t_mid, half_span) = (w.t, w.y, w.t_mid, w.half_span);
    let cols: usize = units.iter().map(Unit::columns).sum();
    if idx.len() <= cols {
        return None;
    }
    let mut a = DMatrix::zeros(idx.len(), cols);
    let mut row = Vec::with_capacity(cols);
    for (r, &i) in idx.iter().enumerate() {
        row.clear();
        push_row(&mut row, units, t[i], t_mid, half_span);
        for (c, v) in row.iter().enumerate() {
            a[(r, c)] = *v;
        }
    }
    let b = DVector::from_iterator(idx.len(), idx.iter().map(|&i| y[i]));
    let svd = a.svd(true, true);
    let smax = svd.singular_values.max();
    // Rank test: a structure whose columns are (nearly) dependent on A is
    // not identifiable there and is skipped rather than regularised.
    if svd.singular_values.min() <= 1e-10 * smax {
        return None;
    }
    svd.solve(&b, 0.0).ok().map(|x| x.iter().copied().collect())
}

/// Regularity criterion of a fitted structure on the samples `check`.
fn criterion(units: &[Unit], coef: &[f64], w: &Window<'_>, check: &[usize]) -> f64 {
    let (t, y) = (w.t, w.y);
    let model = GmdhModel {
        units: units.to_vec(),
        coefficients: coef.to_vec(),
        t_mid: w.t_mid,
        half_span: w.half_span,
    };
    let mean = check.iter().map(|&i| y[i]).sum::<f64>() / check.len() as f64;
    let (mut err, mut var) = (0.0, 0.0);
    for &i in check {
        err += (y[i] - model.predict(t[i])).powi(2);
        var += (y[i] - mean).powi(2);
    }
    err / var.max(f64::MIN_POSITIVE)
}

/// Training-part residual of {polynomial up to `degree`, harmonic at ω}: what
/// the frequency refinement minimises (the polynomial absorbs trends that
/// would bias ω; B stays untouched, so the criterion stays external).
fn harmonic_residual(omega: f64, degree: u32, w: &Window<'_>, train: &[usize]) -> f64 {
    let mut units: Vec<Unit> = (0..=degree).map(|p| Unit::Power { p }).collect();
    units.push(Unit::Harmonic { omega });
    match fit(&units, w, train) {
        Some(coef) => criterion(&units, &coef, w, train),
        None => f64::INFINITY,
    }
}

/// Points on the forecast horizon where the balance criterion compares forecasts.
const BALANCE_POINTS: usize = 64;

/// Number of searched harmonics refined (the best by training residual).
const REFINED_HARMONICS: usize = 3;
/// Golden-section iterations: the bracket shrinks by 0.618ⁿ (≈ 1e-6 for 30).
const GOLDEN_ITERATIONS: usize = 30;

/// Refine the best searched harmonics; a refined frequency that lands within
/// half a grid step of a better one is dropped (both would model one line).
fn refine_frequencies(
    grid: &mut Vec<Unit>,
    ratio: f64,
    degree: u32,
    w: &Window<'_>,
    train: &[usize],
) {
    let mut ranked: Vec<(f64, usize)> = grid
        .iter()
        .enumerate()
        .filter_map(|(i, u)| match u {
            Unit::Harmonic { omega } => Some((harmonic_residual(*omega, degree, w, train), i)),
            Unit::Power { .. } => None,
        })
        .collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let golden = 0.5 * (5f64.sqrt() - 1.0);
    for &(_, i) in ranked.iter().take(REFINED_HARMONICS) {
        let Unit::Harmonic { omega } = grid[i] else {
            continue;
        };
        let (mut lo, mut hi) = ((omega / ratio).ln(), (omega * ratio).ln());
        let f = |x: f64| harmonic_residual(x.exp(), degree, w, train);
        let (mut a, mut b) = (hi - golden * (hi - lo), lo + golden * (hi - lo));
        let (mut fa, mut fb) = (f(a), f(b));
        for _ in 0..GOLDEN_ITERATIONS {
            if fa < fb {
                hi = b;
                b = a;
                fb = fa;
                a = hi - golden * (hi - lo);
                fa = f(a);
            } else {
                lo = a;
                a = b;
                fa = fb;
                b = lo + golden * (hi - lo);
                fb = f(b);
            }
        }
        let best = if fa < fb { a } else { b };
        if f(best) < f(omega.ln()) {
            grid[i] = Unit::Harmonic { omega: best.exp() };
        }
    }
    // Keep the better of any two refined harmonics closer than half a step.
    let refined: Vec<usize> = ranked
        .iter()
        .take(REFINED_HARMONICS)
        .map(|&(_, i)| i)
        .collect();
    let mut drop = Vec::new();
    for (a, &i) in refined.iter().enumerate() {
        for &j in &refined[..a] {
            if let (Unit::Harmonic { omega: wi }, Unit::Harmonic { omega: wj }) = (grid[i], grid[j])
                && (wi / wj).ln().abs() < 0.5 * ratio.ln()
                && !drop.contains(&j)
            {
                drop.push(i);
            }
        }
    }
    drop.sort_unstable();
    for i in drop.into_iter().rev() {
        grid.remove(i);
    }
}

/// Select and fit the best structure for samples `y` at times `t`.
pub fn select(t: &[f64], y: &[f64], config: &GmdhConfig) -> Result<GmdhSelection, GmdhError> {
    if t.len() != y.len() {
        return Err(GmdhError::LengthMismatch {
            times: t.len(),
            values: y.len(),
        });
    }
    if let Some(index) = t
        .iter()
        .zip(y)
        .position(|(a, b)| !a.is_finite() || !b.is_finite())
    {
        return Err(GmdhError::NonFinite { index });
    }
    if let Some(index) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(GmdhError::NotIncreasing { index: index + 1 });
    }
    const MIN_SAMPLES: usize = 6;
    if t.len() < MIN_SAMPLES {
        return Err(GmdhError::TooFewSamples {
            samples: t.len(),
            needed: MIN_SAMPLES,
        });
    }
    if config.max_units == 0 || config.beam == 0 {
        return Err(GmdhError::Config("max_units and beam must be ≥ 1".into()));
    }
    let mut candidates: Vec<Unit> = (0..=config.max_degree).map(|p| Unit::Power { p }).collect();
    for &omega in &config.frequencies {
        if !(omega.is_finite() && omega > 0.0) {
            return Err(GmdhError::Config(format!("frequency {omega} must be > 0")));
        }
        candidates.push(Unit::Harmonic { omega });
    }
    let given = candidates.len();
    let mut grid_ratio = 1.0;
    if let Some(g) = config.search {
        if !(g.min > 0.0 && g.max > g.min && g.count >= 1) {
            return Err(GmdhError::Config(format!(
                "frequency grid {g:?}: need 0 < min < max, count ≥ 1"
            )));
        }
        if g.count > 1 {
            grid_ratio = (g.max / g.min).powf(1.0 / (g.count - 1) as f64);
        }
        for i in 0..g.count {
            candidates.push(Unit::Harmonic {
                omega: g.min * grid_ratio.powi(i as i32),
            });
        }
    }
    let n = t.len();
    let (train, check): (Vec<usize>, Vec<usize>) = match config.split {
        Split::Alternating => (0..n).partition(|i| i % 2 == 0),
        Split::Latest { fraction } => {
            if !(fraction > 0.0 && fraction < 1.0) {
                return Err(GmdhError::Config(format!(
                    "split fraction {fraction} must be in (0, 1)"
                )));
            }
            let nb = ((n as f64 * fraction).round() as usize).clamp(1, n - 1);
            ((0..n - nb).collect(), (n - nb..n).collect())
        }
    };
    let t_mid = 0.5 * (t[0] + t[n - 1]);
    let half_span = (0.5 * (t[n - 1] - t[0])).max(f64::MIN_POSITIVE);
    let window = Window {
        t,
        y,
        t_mid,
        half_span,
    };
    let (early, late): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| i < n / 2);
    let horizon_grid: Vec<f64> = match config.horizon_s {
        Some(h) => {
            if !(h.is_finite() && h > 0.0) {
                return Err(GmdhError::Config(format!("horizon_s {h} must be > 0")));
            }
            (1..=BALANCE_POINTS)
                .map(|k| t[n - 1] + h * k as f64 / BALANCE_POINTS as f64)
                .collect()
        }
        None => Vec::new(),
    };
    let check_variance = {
        let mean = check.iter().map(|&i| y[i]).sum::<f64>() / check.len() as f64;
        (check.iter().map(|&i| (y[i] - mean).powi(2)).sum::<f64>() / check.len() as f64)
            .max(f64::MIN_POSITIVE)
    };
    let score = |units: &[Unit]| -> Option<f64> {
        let coef = fit(units, &window, &train)?;
        let regularity = criterion(units, &coef, &window, &check);
        if horizon_grid.is_empty() {
            return Some(regularity);
        }
        let model = |idx: &[usize]| {
            fit(units, &window, idx).map(|coefficients| GmdhModel {
                units: units.to_vec(),
                coefficients,
                t_mid,
                half_span,
            })
        };
        let (a, b) = (model(&early)?, model(&late)?);
        let balance = horizon_grid
            .iter()
            .map(|&t| (a.predict(t) - b.predict(t)).powi(2))
            .sum::<f64>()
            / horizon_grid.len() as f64
            / check_variance;
        Some(regularity + balance)
    };
    if config.refine && grid_ratio > 1.0 {
        let mut searched = candidates.split_off(given);
        refine_frequencies(
            &mut searched,
            grid_ratio,
            config.max_degree,
            &window,
            &train,
        );
        candidates.extend(searched);
    }
    let required = config
        .min_improvement
        .max(config.noise_guard / check.len() as f64);

    // Complexity 1 and 2 exhaustively, then beam extension.
    let mut layer: Vec<(f64, Vec<usize>)> = (0..candidates.len())
        .filter_map(|i| score(&[candidates[i]]).map(|c| (c, vec![i])))
        .collect();
    let mut best_by_complexity = Vec::new();
    let mut best: Option<(f64, Vec<usize>)> = None;
    for complexity in 1..=config.max_units {
        if complexity > 1 {
            let parents: Vec<Vec<usize>> = if complexity == 2 {
                (0..candidates.len()).map(|i| vec![i]).collect()
            } else {
                layer.iter().map(|(_, s)| s.clone()).collect()
            };
            let mut next: Vec<(f64, Vec<usize>)> = Vec::new();
            for p in parents {
                let last = *p.last().unwrap_or(&0);
                for i in 0..candidates.len() {
                    if p.contains(&i) || (complexity == 2 && i <= last) {
                        continue;
                    }
                    let mut s = p.clone();
                    s.push(i);
                    s.sort_unstable();
                    if next.iter().any(|(_, q)| *q == s) {
                        continue;
                    }
                    let units: Vec<Unit> = s.iter().map(|&k| candidates[k]).collect();
                    if let Some(c) = score(&units) {
                        next.push((c, s));
                    }
                }
            }
            layer = next;
        }
        layer.sort_by(|a, b| a.0.total_cmp(&b.0));
        layer.truncate(config.beam);
        let Some(top) = layer.first().cloned() else {
            break;
        };
        best_by_complexity.push(top.0);
        // An exactly fitted structure (criterion at rounding level) cannot be
        // improved by more units, only made to look so by rounding.
        const EXACT_FIT: f64 = 1e-20;
        match &best {
            Some((c, _)) if top.0 >= c * (1.0 - required) || *c < EXACT_FIT => break,
            _ => best = Some(top),
        }
    }
    let (crit, set) = best.ok_or(GmdhError::TooFewSamples {
        samples: n,
        needed: MIN_SAMPLES,
    })?;
    let units: Vec<Unit> = set.iter().map(|&k| candidates[k]).collect();
    let all: Vec<usize> = (0..n).collect();
    let coefficients = fit(&units, &window, &all).ok_or(GmdhError::TooFewSamples {
        samples: n,
        needed: MIN_SAMPLES,
    })?;
    Ok(GmdhSelection {
        model: GmdhModel {
            units,
            coefficients,
            t_mid,
            half_span,
        },
        criterion: crit,
        best_by_complexity,
    })
}
