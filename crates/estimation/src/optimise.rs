//! Derivative-free minimisation by the Nelder–Mead simplex (Nelder & Mead,
//! Computer Journal 7, 1965; the standard coefficients and tie rules of
//! Lagarias, Reeds, Wright & Wright, SIAM J. Optim. 9(1), 1998), in a box,
//! with a bounded number of evaluations.
//!
//! The objective is evaluated in *batches*: the caller receives every point
//! the method can evaluate at once (the initial simplex, a shrink) and may
//! evaluate them in parallel; the result does not depend on how. A value
//! that is not finite (a failed evaluation) counts as +∞. A trial point
//! outside the box is projected onto it (each coordinate clamped), so the
//! simplex can slide along a face rather than collapse against it.
//!
//! ```
//! use aidnav_estimation::optimise::{nelder_mead, NelderMeadOptions};
//! // Rosenbrock's valley from (−1.2, 1): minimum 0 at (1, 1).
//! let f = |x: &[f64]| 100.0 * (x[1] - x[0] * x[0]).powi(2) + (1.0 - x[0]).powi(2);
//! let options = NelderMeadOptions { max_evaluations: 2000, x_tolerance: 1e-8, f_tolerance: 1e-12, ..NelderMeadOptions::new(2) };
//! let m = nelder_mead(|points: &[Vec<f64>]| points.iter().map(|x| f(x)).collect(), &[-1.2, 1.0], &options).unwrap();
//! assert!(m.converged);
//! assert!((m.x[0] - 1.0).abs() < 1e-4 && (m.x[1] - 1.0).abs() < 1e-4, "{:?}", m.x);
//! ```

/// Reflection, expansion, contraction and shrink coefficients (the
/// standard 1, 2, ½, ½).
const REFLECT: f64 = 1.0;
const EXPAND: f64 = 2.0;
const CONTRACT: f64 = 0.5;
const SHRINK: f64 = 0.5;

/// Why no minimisation was made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum OptimiseError {
    /// The start has no coordinate.
    #[error("the start point has no coordinate")]
    Empty,
    /// A vector of the options does not have the start's dimension.
    #[error("{what} has {len} elements for {dimension} coordinates")]
    Dimension {
        /// Which vector.
        what: &'static str,
        /// Its length.
        len: usize,
        /// The start's dimension.
        dimension: usize,
    },
    /// A coordinate of the start, a step or a bound is not usable.
    #[error("{what}[{index}] = {value}: {allowed}")]
    Invalid {
        /// Which vector.
        what: &'static str,
        /// Coordinate.
        index: usize,
        /// Its value.
        value: f64,
        /// What is allowed.
        allowed: &'static str,
    },
    /// The batch evaluator returned a different number of values than points.
    #[error("the evaluator returned {returned} values for {points} points")]
    Evaluator {
        /// Points given.
        points: usize,
        /// Values returned.
        returned: usize,
    },
    /// Every vertex of the initial simplex evaluated to +∞ (or NaN).
    #[error("the objective is not finite at any vertex of the initial simplex")]
    NoFiniteStart,
}

/// Settings of [`nelder_mead`].
#[derive(Debug, Clone, PartialEq)]
pub struct NelderMeadOptions {
    /// Initial simplex: the start plus `initial_step[i]` along axis i.
    pub initial_step: Vec<f64>,
    /// Box: lower bound per coordinate.
    pub lower: Vec<f64>,
    /// Box: upper bound per coordinate.
    pub upper: Vec<f64>,
    /// Stop after this many evaluations (the initial simplex included).
    /// Default 200.
    pub max_evaluations: usize,
    /// Converged when the values of the simplex span at most this … Default 1e-3.
    pub f_tolerance: f64,
    /// … and every vertex is within this of the best, per coordinate
    /// (max norm). Default 1e-3.
    pub x_tolerance: f64,
}

impl NelderMeadOptions {
    /// Unit steps, an unbounded box, the default tolerances, for `dimension`
    /// coordinates.
    pub fn new(dimension: usize) -> Self {
        Self {
            initial_step: vec![1.0; dimension],
            lower: vec![f64::NEG_INFINITY; dimension],
            upper: vec![f64::INFINITY; dimension],
            max_evaluations: 200,
            f_tolerance: 1e-3,
            x_tolerance: 1e-3,
        }
    }
}

/// The best point found.
#[derive(Debug, Clone, PartialEq)]
pub struct Minimum {
    /// The best point.
    pub x: Vec<f64>,
    /// The objective there.
    pub value: f64,
    /// The objective at the start.
    pub start_value: f64,
    /// Objective evaluations made.
    pub evaluations: usize,
    /// Simplex iterations made.
    pub iterations: usize,
    /// The tolerances were met (else the evaluation budget ran out).
    pub converged: bool,
    /// The best value after each iteration (its first entry: after the
    /// initial simplex).
    pub history: Vec<f64>,
}

/// The simplex and its bookkeeping.
struct Search<'a, F> {
    evaluate: F,
    options: &'a NelderMeadOptions,
    evaluations: usize,
}

impl<F: FnMut(&[Vec<f64>]) -> Vec<f64>> Search<'_, F> {
    /// `x` projected into the box.
    fn clamp(&self, mut x: Vec<f64>) -> Vec<f64> {
        for (i, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.options.lower[i], self.options.upper[i]);
        }
        x
    }

    /// Values of `points` (in the box): +∞ where not finite.
    fn values(&mut self, points: &[Vec<f64>]) -> Result<Vec<f64>, OptimiseError> {
        let got = (self.evaluate)(points);
        if got.len() != points.len() {
            return Err(OptimiseError::Evaluator {
                points: points.len(),
                returned: got.len(),
            });
        }
        self.evaluations += points.len();
        Ok(got
            .into_iter()
            .map(|v| if v.is_finite() { v } else { f64::INFINITY })
            .collect())
    }

    /// The value at `x` projected into the box.
    fn value(&mut self, x: Vec<f64>) -> Result<(Vec<f64>, f64), OptimiseError> {
        let x = self.clamp(x);
        let v = self.values(std::slice::from_ref(&x))?[0];
        Ok((x, v))
    }
}

fn check(x0: &[f64], o: &NelderMeadOptions) -> Result<(), OptimiseError> {
    let d = x0.len();
    if d == 0 {
        return Err(OptimiseError::Empty);
    }
    for (what, v) in [
        ("initial_step", &o.initial_step),
        ("lower", &o.lower),
        ("upper", &o.upper),
    ] {
        if v.len() != d {
            return Err(OptimiseError::Dimension {
                what,
                len: v.len(),
                dimension: d,
            });
        }
    }
    for (i, &x) in x0.iter().enumerate() {
        let bad = |what, value, allowed| {
            Err(OptimiseError::Invalid {
                what,
                index: i,
                value,
                allowed,
            })
        };
        if !x.is_finite() || x < o.lower[i] || x > o.upper[i] {
            return bad("start", x, "finite and inside the box");
        }
        if !(o.initial_step[i].is_finite() && o.initial_step[i] != 0.0) {
            return bad("initial_step", o.initial_step[i], "finite and non-zero");
        }
        if o.lower[i].is_nan() || o.upper[i].is_nan() || o.lower[i] > o.upper[i] {
            return bad("lower", o.lower[i], "lower ≤ upper, not NaN");
        }
    }
    Ok(())
}

/// Minimise over the box from `x0`. `evaluate` gets a batch of points
/// (each with `x0.len()` coordinates) and returns their values in order.
/// At most `options.max_evaluations` evaluations (a batch that would
/// exceed it is still completed: the initial simplex has `d + 1` points, a
/// shrink `d`).
pub fn nelder_mead<F>(
    evaluate: F,
    x0: &[f64],
    options: &NelderMeadOptions,
) -> Result<Minimum, OptimiseError>
where
    F: FnMut(&[Vec<f64>]) -> Vec<f64>,
{
    check(x0, options)?;
    let d = x0.len();
    let mut search = Search {
        evaluate,
        options,
        evaluations: 0,
    };
    let mut points = vec![x0.to_vec()];
    for i in 0..d {
        let mut x = x0.to_vec();
        x[i] += options.initial_step[i];
        // A step out of the box goes the other way (then into the box).
        if x[i] > options.upper[i] || x[i] < options.lower[i] {
            x[i] = x0[i] - options.initial_step[i];
        }
        points.push(search.clamp(x));
    }
    let values = search.values(&points)?;
    let start_value = values[0];
    let mut simplex: Vec<(Vec<f64>, f64)> = points.into_iter().zip(values).collect();
    if simplex.iter().all(|(_, v)| !v.is_finite()) {
        return Err(OptimiseError::NoFiniteStart);
    }
    let order = |s: &mut Vec<(Vec<f64>, f64)>| s.sort_by(|a, b| a.1.total_cmp(&b.1));
    order(&mut simplex);
    let mut history = vec![simplex[0].1];
    let mut iterations = 0;
    let mut converged = false;
    loop {
        let (best, worst) = (&simplex[0], &simplex[d]);
        let f_spread = worst.1 - best.1;
        let x_spread = simplex[1..]
            .iter()
            .flat_map(|(x, _)| x.iter().zip(&best.0).map(|(a, b)| (a - b).abs()))
            .fold(0.0, f64::max);
        if f_spread <= options.f_tolerance && x_spread <= options.x_tolerance {
            converged = true;
            break;
        }
        if search.evaluations >= options.max_evaluations {
            break;
        }
        iterations += 1;
        let centroid: Vec<f64> = (0..d)
            .map(|i| simplex[..d].iter().map(|(x, _)| x[i]).sum::<f64>() / d as f64)
            .collect();
        let along = |t: f64| -> Vec<f64> {
            centroid
                .iter()
                .zip(&simplex[d].0)
                .map(|(c, w)| c + t * (c - w))
                .collect()
        };
        let (xr, fr) = search.value(along(REFLECT))?;
        let (f_best, f_second_worst, f_worst) = (simplex[0].1, simplex[d - 1].1, simplex[d].1);
        let replacement = if fr < f_best {
            let (xe, fe) = search.value(along(REFLECT * EXPAND))?;
            Some(if fe < fr { (xe, fe) } else { (xr, fr) })
        } else if fr < f_second_worst {
            Some((xr, fr))
        } else if fr < f_worst {
            let (xc, fc) = search.value(along(REFLECT * CONTRACT))?;
            (fc <= fr).then_some((xc, fc))
        } else {
            let (xc, fc) = search.value(along(-CONTRACT))?;
            (fc < f_worst).then_some((xc, fc))
        };
        match replacement {
            Some(p) => simplex[d] = p,
            None => {
                // Shrink towards the best vertex: d new points, one batch.
                let best_x = simplex[0].0.clone();
                let shrunk: Vec<Vec<f64>> = simplex[1..]
                    .iter()
                    .map(|(x, _)| {
                        x.iter()
                            .zip(&best_x)
                            .map(|(v, b)| b + SHRINK * (v - b))
                            .collect()
                    })
                    .collect();
                let values = search.values(&shrunk)?;
                for (k, (x, v)) in shrunk.into_iter().zip(values).enumerate() {
                    simplex[k + 1] = (x, v);
                }
            }
        }
        order(&mut simplex);
        history.push(simplex[0].1);
    }
    let (x, value) = simplex.swap_remove(0);
    Ok(Minimum {
        x,
        value,
        start_value,
        evaluations: search.evaluations,
        iterations,
        converged,
        history,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn batch<F: Fn(&[f64]) -> f64>(f: F) -> impl FnMut(&[Vec<f64>]) -> Vec<f64> {
        move |p: &[Vec<f64>]| p.iter().map(|x| f(x)).collect()
    }

    /// A quadratic bowl with its minimum at (1, −2, 0.5): found to the
    /// tolerance, within the budget.
    #[test]
    fn finds_the_minimum_of_a_quadratic() {
        let f = |x: &[f64]| {
            (x[0] - 1.0).powi(2) + 4.0 * (x[1] + 2.0).powi(2) + 0.5 * (x[2] - 0.5).powi(2) + 3.0
        };
        let o = NelderMeadOptions {
            x_tolerance: 1e-6,
            f_tolerance: 1e-10,
            max_evaluations: 1000,
            ..NelderMeadOptions::new(3)
        };
        let m = nelder_mead(batch(f), &[0.0, 0.0, 0.0], &o).unwrap();
        assert!(m.converged, "{m:?}");
        assert!((m.x[0] - 1.0).abs() < 1e-5 && (m.x[1] + 2.0).abs() < 1e-5);
        assert!((m.x[2] - 0.5).abs() < 1e-5);
        assert!((m.value - 3.0).abs() < 1e-9);
        assert_eq!(m.start_value, f(&[0.0, 0.0, 0.0]));
        assert!(m.evaluations <= 1000);
        // The best value never gets worse.
        assert!(m.history.windows(2).all(|w| w[1] <= w[0]));
    }

    /// The box holds: the minimum outside it is found on its face.
    #[test]
    fn stays_in_the_box() {
        let f = |x: &[f64]| (x[0] - 5.0).powi(2) + x[1] * x[1];
        let o = NelderMeadOptions {
            lower: vec![-1.0, -1.0],
            upper: vec![2.0, 1.0],
            max_evaluations: 400,
            x_tolerance: 1e-6,
            f_tolerance: 1e-10,
            ..NelderMeadOptions::new(2)
        };
        let mut seen = Vec::new();
        let m = nelder_mead(
            |p: &[Vec<f64>]| {
                seen.extend(p.iter().cloned());
                p.iter().map(|x| f(x)).collect()
            },
            &[0.0, 0.5],
            &o,
        )
        .unwrap();
        assert!(seen.iter().all(|x| x[0] <= 2.0 && x[0] >= -1.0));
        assert!((m.x[0] - 2.0).abs() < 1e-4, "{m:?}");
        assert!(m.x[1].abs() < 1e-4, "{m:?}");
    }

    /// Failed evaluations (NaN) are +∞; the budget stops the search.
    #[test]
    fn failures_and_the_budget() {
        let f = |x: &[f64]| {
            if x[0] > 0.5 {
                f64::NAN
            } else {
                (x[0] + 1.0).powi(2)
            }
        };
        let o = NelderMeadOptions {
            max_evaluations: 8,
            ..NelderMeadOptions::new(1)
        };
        let m = nelder_mead(batch(f), &[0.0], &o).unwrap();
        assert!(!m.converged);
        assert!(m.evaluations <= 9);
        assert!(m.value < 1.0);
        // Nothing finite at the start.
        let e = nelder_mead(batch(|_: &[f64]| f64::NAN), &[0.0], &o).unwrap_err();
        assert_eq!(e, OptimiseError::NoFiniteStart);
    }

    #[test]
    fn bad_settings_are_errors() {
        let o = NelderMeadOptions::new(2);
        let f = |p: &[Vec<f64>]| p.iter().map(|_| 0.0).collect();
        assert_eq!(nelder_mead(f, &[], &o), Err(OptimiseError::Empty));
        assert!(matches!(
            nelder_mead(f, &[0.0], &o),
            Err(OptimiseError::Dimension {
                what: "initial_step",
                ..
            })
        ));
        assert!(matches!(
            nelder_mead(f, &[f64::NAN, 0.0], &o),
            Err(OptimiseError::Invalid { what: "start", .. })
        ));
        let short = |p: &[Vec<f64>]| vec![0.0; p.len() - 1];
        assert!(matches!(
            nelder_mead(short, &[0.0, 0.0], &o),
            Err(OptimiseError::Evaluator { .. })
        ));
    }
}
