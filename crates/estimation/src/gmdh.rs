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
    /// Number of grid points (log-spaced), 1 … [`MAX_SEARCH_COUNT`].
    pub count: usize,
}

/// Configuration of the selection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GmdhConfig {
    /// Highest polynomial degree among the candidates, 0 … [`MAX_DEGREE`]. Default 2.
    pub max_degree: u32,
    /// Given frequencies [rad/s] (e.g. Schuler, Earth rate), each within
    /// [`MIN_OMEGA_RAD_S`] … [`MAX_OMEGA_RAD_S`], at most [`MAX_FREQUENCIES`]. Default none.
    pub frequencies: Vec<f64>,
    /// Searched frequencies. Default none.
    pub search: Option<FrequencyGrid>,
    /// Training / checking split. Default alternating.
    pub split: Split,
    /// Most units in a structure, 1 … [`MAX_UNITS`]. Default 4.
    pub max_units: usize,
    /// Structures of each complexity carried to the next, 1 … [`MAX_BEAM`]. Default 8.
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
    /// A configuration key out of its bounds (see [`GmdhConfig::check`]).
    #[error("{key} = {value}: allowed {allowed}")]
    OutOfRange {
        /// Key inside the GMDH table (`max_degree`, `search.count`, …).
        key: &'static str,
        /// The offending value, as text.
        value: String,
        /// The allowed range, and for a size the memory it would need.
        allowed: String,
    },
}

/// Highest polynomial degree allowed ([`GmdhConfig::max_degree`]): τᵖ on
/// [−1, 1] beyond this is numerically indistinguishable from its neighbours.
pub const MAX_DEGREE: u32 = 12;
/// Most given frequencies ([`GmdhConfig::frequencies`]).
pub const MAX_FREQUENCIES: usize = 64;
/// Most searched frequencies ([`FrequencyGrid::count`]).
pub const MAX_SEARCH_COUNT: usize = 1024;
/// Highest angular frequency of a harmonic unit [rad/s] (≈ 160 Hz, far
/// above any navigation-error dynamics a bridge models).
pub const MAX_OMEGA_RAD_S: f64 = 1e3;
/// Lowest angular frequency of a harmonic unit [rad/s] (a period of ≈ 200 years).
pub const MIN_OMEGA_RAD_S: f64 = 1e-9;
/// Most units in a structure ([`GmdhConfig::max_units`]).
pub const MAX_UNITS: usize = 16;
/// Most structures carried per complexity ([`GmdhConfig::beam`]).
pub const MAX_BEAM: usize = 1024;
/// Longest forecast horizon \[s\] ([`GmdhConfig::horizon_s`]): 10 days.
pub const MAX_HORIZON_S: f64 = 864_000.0;
/// Memory the candidate structures of one selection may take \[bytes\].
pub const MEMORY_BUDGET_BYTES: f64 = 1024.0 * 1024.0 * 1024.0;

/// `bytes` as text with a decimal unit (`19.2 GB`).
pub fn human_bytes(bytes: f64) -> String {
    let units = ["B", "kB", "MB", "GB", "TB", "PB", "EB"];
    let mut v = bytes;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    if u == 0 {
        format!("{v:.0} {}", units[u])
    } else {
        format!("{v:.1} {}", units[u])
    }
}

fn out_of_range(key: &'static str, value: impl std::fmt::Display, allowed: String) -> GmdhError {
    GmdhError::OutOfRange {
        key,
        value: value.to_string(),
        allowed,
    }
}

impl GmdhConfig {
    /// Number of candidate units: powers, given and searched frequencies
    /// (saturating, so a huge key cannot overflow).
    pub fn candidate_count(&self) -> usize {
        (self.max_degree as usize)
            .saturating_add(1)
            .saturating_add(self.frequencies.len())
            .saturating_add(self.search.map_or(0, |g| g.count))
    }

    /// Memory the candidate structures of a selection need at most
    /// \[bytes\]: the exhaustive pairs of complexity 2, or a beam times the
    /// candidates of each later complexity, each a criterion and a list of
    /// `max_units` indices.
    pub fn memory_bytes(&self) -> f64 {
        let n = self.candidate_count() as f64;
        let structure = (std::mem::size_of::<(f64, Vec<usize>)>()
            + self.max_units.min(MAX_UNITS.max(1)) * std::mem::size_of::<usize>())
            as f64;
        let pairs = n * (n - 1.0) / 2.0;
        let beam = self.beam as f64 * n;
        pairs.max(beam).max(n) * structure
    }

    /// Every key within its bounds and the selection within
    /// [`MEMORY_BUDGET_BYTES`]; the error names the key.
    pub fn check(&self) -> Result<(), GmdhError> {
        if self.max_degree > MAX_DEGREE {
            return Err(out_of_range(
                "max_degree",
                self.max_degree,
                format!("0 ≤ max_degree ≤ {MAX_DEGREE}"),
            ));
        }
        if self.frequencies.len() > MAX_FREQUENCIES {
            return Err(out_of_range(
                "frequencies",
                format!("{} frequencies", self.frequencies.len()),
                format!("at most {MAX_FREQUENCIES}"),
            ));
        }
        let omega_range = format!("{MIN_OMEGA_RAD_S:e} ≤ ω ≤ {MAX_OMEGA_RAD_S:e} rad/s");
        for &w in &self.frequencies {
            if !(w.is_finite() && (MIN_OMEGA_RAD_S..=MAX_OMEGA_RAD_S).contains(&w)) {
                return Err(out_of_range("frequencies", format!("{w:e}"), omega_range));
            }
        }
        if let Some(g) = self.search {
            if !(g.count >= 1 && g.count <= MAX_SEARCH_COUNT) {
                let bytes = g.count as f64 * std::mem::size_of::<Unit>() as f64;
                return Err(out_of_range(
                    "search.count",
                    g.count,
                    format!(
                        "1 ≤ search.count ≤ {MAX_SEARCH_COUNT} ({} would need {} for the candidate units alone)",
                        g.count,
                        human_bytes(bytes)
                    ),
                ));
            }
            for (key, w) in [("search.min", g.min), ("search.max", g.max)] {
                if !(w.is_finite() && (MIN_OMEGA_RAD_S..=MAX_OMEGA_RAD_S).contains(&w)) {
                    return Err(out_of_range(key, format!("{w:e}"), omega_range));
                }
            }
            if g.max <= g.min {
                return Err(out_of_range(
                    "search.max",
                    format!("{:e}", g.max),
                    "search.max > search.min".into(),
                ));
            }
        }
        if !(1..=MAX_UNITS).contains(&self.max_units) {
            return Err(out_of_range(
                "max_units",
                self.max_units,
                format!("1 ≤ max_units ≤ {MAX_UNITS}"),
            ));
        }
        if !(1..=MAX_BEAM).contains(&self.beam) {
            return Err(out_of_range(
                "beam",
                self.beam,
                format!("1 ≤ beam ≤ {MAX_BEAM}"),
            ));
        }
        if !(self.min_improvement.is_finite() && (0.0..1.0).contains(&self.min_improvement)) {
            return Err(out_of_range(
                "min_improvement",
                self.min_improvement,
                "0 ≤ min_improvement < 1".into(),
            ));
        }
        if !(self.noise_guard.is_finite() && (0.0..=1e6).contains(&self.noise_guard)) {
            return Err(out_of_range(
                "noise_guard",
                self.noise_guard,
                "0 ≤ noise_guard ≤ 1e6".into(),
            ));
        }
        if let Split::Latest { fraction } = self.split
            && !(fraction > 0.0 && fraction < 1.0)
        {
            return Err(out_of_range(
                "split.fraction",
                fraction,
                "0 < fraction < 1".into(),
            ));
        }
        if let Some(h) = self.horizon_s
            && !(h.is_finite() && h > 0.0 && h <= MAX_HORIZON_S)
        {
            return Err(out_of_range(
                "horizon_s",
                h,
                format!("0 < horizon_s ≤ {MAX_HORIZON_S}"),
            ));
        }
        let bytes = self.memory_bytes();
        if bytes > MEMORY_BUDGET_BYTES {
            return Err(out_of_range(
                "beam",
                self.beam,
                format!(
                    "a selection within {}: {} candidates, beam {} would need {}",
                    human_bytes(MEMORY_BUDGET_BYTES),
                    self.candidate_count(),
                    self.beam,
                    human_bytes(bytes)
                ),
            ));
        }
        Ok(())
    }
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
    let (t, t_mid, half_span) = (w.t, w.t_mid, w.half_span);
    let cols: usize = units.iter().map(Unit::columns).sum();
    fit_rows(cols, w, idx, |row, i| {
        push_row(row, units, t[i], t_mid, half_span);
    })
}

/// [`fit`] of the candidates `set` with their values read from `table`
/// (the same rows, so the same coefficients).
fn fit_set(set: &[usize], table: &DesignTable, w: &Window<'_>, idx: &[usize]) -> Option<Vec<f64>> {
    let cols = table.columns(set);
    if idx.len() <= cols {
        return None;
    }
    // The design matrix column by column (the rows `push_row` writes,
    // without building each row first).
    let mut a = DMatrix::zeros(idx.len(), cols);
    let mut c = 0;
    for &k in set {
        for (r, &i) in idx.iter().enumerate() {
            a[(r, c)] = table.values[i][k].0;
        }
        c += 1;
        if table.two[k] {
            for (r, &i) in idx.iter().enumerate() {
                a[(r, c)] = table.values[i][k].1;
            }
            c += 1;
        }
    }
    solve_design(a, w, idx)
}

/// Least-squares coefficients on the samples `idx` with `cols` columns, the
/// row of sample i written by `row_of`, or None if rank-deficient.
fn fit_rows(
    cols: usize,
    w: &Window<'_>,
    idx: &[usize],
    mut row_of: impl FnMut(&mut Vec<f64>, usize),
) -> Option<Vec<f64>> {
    if idx.len() <= cols {
        return None;
    }
    let mut a = DMatrix::zeros(idx.len(), cols);
    let mut row = Vec::with_capacity(cols);
    for (r, &i) in idx.iter().enumerate() {
        row.clear();
        row_of(&mut row, i);
        for (c, v) in row.iter().enumerate() {
            a[(r, c)] = *v;
        }
    }
    solve_design(a, w, idx)
}

/// Least-squares coefficients of the design matrix `a` (one row per sample
/// of `idx`) for the samples' values, or None if rank-deficient or not
/// finite.
fn solve_design(a: DMatrix<f64>, w: &Window<'_>, idx: &[usize]) -> Option<Vec<f64>> {
    let y = w.y;
    // A non-finite entry (an overflowing ω·t) would make the SVD panic: such
    // a structure is not identifiable and is skipped like a rank-deficient one.
    if a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let b = DVector::from_iterator(idx.len(), idx.iter().map(|&i| y[i]));
    if b.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let svd = a.svd(true, true);
    if svd.singular_values.iter().any(|v| !v.is_finite()) {
        return None;
    }
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

/// [`criterion`] of the candidates `set` with their values read from
/// `table`: the same products summed in the same order as
/// [`GmdhModel::predict`], so the same number.
fn criterion_set(
    set: &[usize],
    coef: &[f64],
    table: &DesignTable,
    w: &Window<'_>,
    check: &[usize],
) -> f64 {
    let y = w.y;
    let mean = check.iter().map(|&i| y[i]).sum::<f64>() / check.len() as f64;
    let (mut err, mut var) = (0.0, 0.0);
    let mut row = Vec::with_capacity(coef.len());
    for &i in check {
        row.clear();
        table.push_row(&mut row, set, i);
        let predicted: f64 = row.iter().zip(coef).map(|(a, c)| a * c).sum();
        err += (y[i] - predicted).powi(2);
        var += (y[i] - mean).powi(2);
    }
    err / var.max(f64::MIN_POSITIVE)
}

/// Every candidate unit's value(s) at a list of times, computed once: the
/// selection fits thousands of candidate sets on the same samples, and a
/// harmonic's sine and cosine cost more than the rest of a row. The values
/// are those [`push_row`] computes, so the rows are the same.
struct DesignTable {
    /// Per time, per candidate: its first and (harmonics) second column.
    values: Vec<Vec<(f64, f64)>>,
    /// Per candidate: whether it has two columns.
    two: Vec<bool>,
}

impl DesignTable {
    fn new(candidates: &[Unit], times: &[f64], t_mid: f64, half_span: f64) -> Self {
        let values = times
            .iter()
            .map(|&t| {
                let tau = (t - t_mid) / half_span;
                candidates
                    .iter()
                    .map(|u| match *u {
                        Unit::Power { p } => (tau.powi(p as i32), 0.0),
                        Unit::Harmonic { omega } => ((omega * t).sin(), (omega * t).cos()),
                    })
                    .collect()
            })
            .collect();
        let two = candidates.iter().map(|u| u.columns() == 2).collect();
        Self { values, two }
    }

    /// Number of columns of the candidates `set`.
    fn columns(&self, set: &[usize]) -> usize {
        set.iter().map(|&k| 1 + usize::from(self.two[k])).sum()
    }

    /// The row of the candidates `set` at time index i.
    fn push_row(&self, row: &mut Vec<f64>, set: &[usize], i: usize) {
        let at = &self.values[i];
        for &k in set {
            row.push(at[k].0);
            if self.two[k] {
                row.push(at[k].1);
            }
        }
    }

    /// [`GmdhModel::predict`] of the candidates `set` with `coef` at time
    /// index i (the same products in the same order).
    fn predict(&self, set: &[usize], coef: &[f64], i: usize) -> f64 {
        // The row's values as `push_row` lays them out, without building it.
        let at = &self.values[i];
        let row = set.iter().flat_map(|&k| {
            let (first, second) = at[k];
            std::iter::once(first).chain(self.two[k].then_some(second))
        });
        row.zip(coef).map(|(a, c)| a * c).sum()
    }
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

/// Largest phase ω·t of a harmonic unit (rad): beyond it an f64 no longer
/// resolves a fraction of a period.
const MAX_PHASE_RAD: f64 = 1e12;

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
    let mut one = select_for_horizons(t, y, config, &[config.horizon_s])?;
    Ok(one.remove(0))
}

/// Least-squares fits of one candidate structure that every horizon's
/// criterion shares: the regularity on the checking part, and the fits to
/// the earlier and later halves for the balance of forecasts.
struct SharedFits {
    regularity: f64,
    /// Coefficients fitted to the earlier and the later half.
    halves: Option<HalfFits>,
}

/// Coefficients of one structure fitted to the earlier and the later half.
type HalfFits = (Vec<f64>, Vec<f64>);

/// [`select`] once per forecast horizon (`None`: regularity alone), as if
/// each were [`GmdhConfig::horizon_s`], with identical results, but every
/// least-squares fit done once and shared by the horizons: a model
/// re-selected for several prediction lengths costs little more than one.
/// `config.horizon_s` is ignored.
///
/// ```
/// use aidnav_estimation::gmdh::{GmdhConfig, select, select_for_horizons};
/// let t: Vec<f64> = (0..100).map(f64::from).collect();
/// let y: Vec<f64> = t.iter().map(|t| 0.3 * t + (0.2 * t).sin()).collect();
/// let config = GmdhConfig { frequencies: vec![0.2], ..GmdhConfig::default() };
/// let both = select_for_horizons(&t, &y, &config, &[Some(10.0), Some(300.0)]).unwrap();
/// let alone = select(&t, &y, &GmdhConfig { horizon_s: Some(300.0), ..config }).unwrap();
/// assert_eq!(both[1], alone);
/// ```
pub fn select_for_horizons(
    t: &[f64],
    y: &[f64],
    config: &GmdhConfig,
    horizons: &[Option<f64>],
) -> Result<Vec<GmdhSelection>, GmdhError> {
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
    config.check()?;
    // The phase ω·t must stay where sin and cos still resolve it (and finite).
    let t_abs = t.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let highest = config
        .frequencies
        .iter()
        .copied()
        .chain(config.search.map(|g| g.max))
        .fold(0.0_f64, f64::max);
    let phase = highest * t_abs;
    if !phase.is_finite() || phase > MAX_PHASE_RAD {
        return Err(out_of_range(
            "frequencies",
            format!("{highest:e}"),
            format!("ω · |t| ≤ {MAX_PHASE_RAD:e} rad over the samples (|t| up to {t_abs:e} s)"),
        ));
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
    for h in horizons.iter().flatten() {
        if !(h.is_finite() && *h > 0.0) {
            return Err(GmdhError::Config(format!("horizon_s {h} must be > 0")));
        }
    }
    let needs_halves = horizons.iter().any(Option::is_some);
    let check_variance = {
        let mean = check.iter().map(|&i| y[i]).sum::<f64>() / check.len() as f64;
        (check.iter().map(|&i| (y[i] - mean).powi(2)).sum::<f64>() / check.len() as f64)
            .max(f64::MIN_POSITIVE)
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

    // Every candidate's values at the samples, computed once for all sets.
    let table = DesignTable::new(&candidates, t, t_mid, half_span);
    let mut cache: std::collections::HashMap<Vec<usize>, Option<SharedFits>> =
        std::collections::HashMap::new();
    let mut shared = |set: &[usize]| -> Option<(f64, Option<HalfFits>)> {
        let fits = cache.entry(set.to_vec()).or_insert_with(|| {
            let coef = fit_set(set, &table, &window, &train)?;
            let regularity = criterion_set(set, &coef, &table, &window, &check);
            let halves = if needs_halves {
                fit_set(set, &table, &window, &early).zip(fit_set(set, &table, &window, &late))
            } else {
                None
            };
            Some(SharedFits { regularity, halves })
        });
        fits.as_ref().map(|f| (f.regularity, f.halves.clone()))
    };
    let mut selections = Vec::with_capacity(horizons.len());
    for horizon in horizons {
        let horizon_grid: Vec<f64> = match horizon {
            Some(h) => (1..=BALANCE_POINTS)
                .map(|k| t[n - 1] + h * k as f64 / BALANCE_POINTS as f64)
                .collect(),
            None => Vec::new(),
        };
        // The candidates' values on the forecast horizon, once per horizon.
        let horizon_table = DesignTable::new(&candidates, &horizon_grid, t_mid, half_span);
        let mut score = |set: &[usize]| -> Option<f64> {
            let (regularity, halves) = shared(set)?;
            if horizon_grid.is_empty() {
                return Some(regularity);
            }
            let (a, b) = halves?;
            let balance = (0..horizon_grid.len())
                .map(|j| {
                    (horizon_table.predict(set, &a, j) - horizon_table.predict(set, &b, j)).powi(2)
                })
                .sum::<f64>()
                / horizon_grid.len() as f64
                / check_variance;
            Some(regularity + balance)
        };
        // Complexity 1 and 2 exhaustively, then beam extension.
        let mut layer: Vec<(f64, Vec<usize>)> = (0..candidates.len())
            .filter_map(|i| score(&[i]).map(|c| (c, vec![i])))
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
                        if let Some(c) = score(&s) {
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
        selections.push(GmdhSelection {
            model: GmdhModel {
                units,
                coefficients,
                t_mid,
                half_span,
            },
            criterion: crit,
            best_by_complexity,
        });
    }
    Ok(selections)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples() -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..200).map(|k| k as f64).collect();
        let y = t.iter().map(|&t| 0.5 + 0.01 * t).collect();
        (t, y)
    }

    fn key_of(e: GmdhError) -> &'static str {
        match e {
            GmdhError::OutOfRange { key, .. } => key,
            other => panic!("expected OutOfRange, got {other:?}"),
        }
    }

    #[test]
    fn a_huge_frequency_is_an_error_not_an_svd_panic() {
        let (t, y) = samples();
        let cfg = GmdhConfig {
            frequencies: vec![1e308],
            ..GmdhConfig::default()
        };
        assert_eq!(key_of(select(&t, &y, &cfg).unwrap_err()), "frequencies");
    }

    #[test]
    fn a_non_finite_design_matrix_is_skipped_not_decomposed() {
        let (t, y) = samples();
        let w = Window {
            t: &t,
            y: &y,
            t_mid: 100.0,
            half_span: 100.0,
        };
        let idx: Vec<usize> = (0..t.len()).collect();
        assert_eq!(fit(&[Unit::Harmonic { omega: 1e308 }], &w, &idx), None);
    }

    #[test]
    fn a_huge_max_degree_is_refused_before_allocating() {
        let (t, y) = samples();
        let cfg = GmdhConfig {
            max_degree: 2_147_483_648,
            ..GmdhConfig::default()
        };
        assert_eq!(key_of(select(&t, &y, &cfg).unwrap_err()), "max_degree");
    }

    #[test]
    fn a_huge_search_count_is_refused_with_its_memory() {
        let (t, y) = samples();
        let cfg = GmdhConfig {
            search: Some(FrequencyGrid {
                min: 1e-3,
                max: 1e-1,
                count: 1 << 32,
            }),
            ..GmdhConfig::default()
        };
        let e = select(&t, &y, &cfg).unwrap_err();
        assert!(e.to_string().contains("GB"), "{e}");
        assert_eq!(key_of(e), "search.count");
    }

    #[test]
    fn the_largest_allowed_configuration_fits_the_memory_budget() {
        let cfg = GmdhConfig {
            max_degree: MAX_DEGREE,
            frequencies: vec![1e-3; MAX_FREQUENCIES],
            search: Some(FrequencyGrid {
                min: 1e-3,
                max: 1e-1,
                count: MAX_SEARCH_COUNT,
            }),
            max_units: MAX_UNITS,
            beam: MAX_BEAM,
            ..GmdhConfig::default()
        };
        assert!(
            cfg.memory_bytes() <= MEMORY_BUDGET_BYTES,
            "{}",
            cfg.memory_bytes()
        );
        assert!(cfg.check().is_ok());
        assert!(GmdhConfig::default().check().is_ok());
    }
}
