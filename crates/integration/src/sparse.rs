//! A product of statically sized matrices that skips the exact zeros of its
//! factors and still gives nalgebra's dense product bit for bit.
//!
//! The stage-1 filters discretise a sparse F (about 60 of 441 entries
//! nonzero at 21 states) and carry a block-diagonal Q_c through Φ; the dense
//! 21×21 products of that were a third of the formation's run time.
//!
//! nalgebra multiplies statically sized matrices column by column
//! (`gemv`): element (i, j) is `t₀ + t₁ + … ` with `t_k = a_ik b_kj`, each
//! step `y = t_k + y` with a separate multiply and add (no FMA), starting
//! from `y = t₀`. [`product`] sums the same terms in the same increasing k
//! over only the k where both factors are nonzero. Leaving out an exact zero
//! term changes a running sum only when that sum is itself zero, and then
//! only its sign: the next nonzero term wipes the difference out
//! (`±0 + t = t`). So the two agree wherever the dense result is nonzero,
//! and where it is zero the dense sign is the one rule of IEEE round to
//! nearest: a sum of zeros is −0 exactly when every term is −0. [`product`]
//! applies that rule to its zero results, so it returns the dense bits
//! everywhere, signs of zeros included. A factor with a non-finite element
//! (where `0 · ∞` would be NaN) goes to the dense product.
//!
//! Finding the zeros of each factor at run time costs about as much as the
//! dense product at 21 states (unpredictable branches), so a filter whose
//! matrices are zero outside a known pattern plans its products once
//! ([`Product::new`] from the factors' [`Pattern`]s): the terms of each
//! element and the few elements whose zero sign needs the rule are listed
//! in advance, and each call only checks, without branches, that the
//! factors are finite and +0 (every bit clear) outside their patterns — a
//! term with a +0 factor outside both patterns makes a zero sum +0 — and
//! falls back to [`product`] when they are not.

use nalgebra::SMatrix;

/// Which elements of an r × c matrix may be nonzero (column-major).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Pattern {
    rows: usize,
    cols: usize,
    nonzero: Vec<bool>,
}

impl Pattern {
    /// The pattern whose element (i, j) may be nonzero when `nonzero(i, j)`.
    pub(crate) fn of(rows: usize, cols: usize, nonzero: impl Fn(usize, usize) -> bool) -> Self {
        Self {
            rows,
            cols,
            nonzero: (0..cols)
                .flat_map(|j| (0..rows).map(move |i| (i, j)))
                .map(|(i, j)| nonzero(i, j))
                .collect(),
        }
    }

    /// Whether element (i, j) may be nonzero.
    pub(crate) fn at(&self, i: usize, j: usize) -> bool {
        self.nonzero[j * self.rows + i]
    }

    /// The elements that may be nonzero in either.
    pub(crate) fn union(&self, other: &Self) -> Self {
        assert_eq!((self.rows, self.cols), (other.rows, other.cols));
        Self::of(self.rows, self.cols, |i, j| self.at(i, j) || other.at(i, j))
    }

    /// The pattern of the transpose.
    pub(crate) fn transpose(&self) -> Self {
        Self::of(self.cols, self.rows, |i, j| self.at(j, i))
    }
}

/// A planned product `a · b` of factors zero outside known patterns: the
/// dense product's bits (see the [module documentation](self)).
#[derive(Debug, Clone)]
pub(crate) struct Product {
    rows: usize,
    inner: usize,
    cols: usize,
    /// Per element of a and of b (column-major): every bit set where the
    /// factor must be +0, none inside its pattern.
    a_outside: Vec<u64>,
    b_outside: Vec<u64>,
    /// The terms of the product's column j, k increasing, as runs
    /// `(k, rows)` of a's column k (consecutive rows, so that each run is
    /// one vectorised axpy), are `runs[starts[j]..starts[j + 1]]`.
    runs: Vec<(usize, std::ops::Range<usize>)>,
    starts: Vec<usize>,
    /// The elements (i, j) with no term outside both patterns: the only
    /// ones whose dense sum can be −0.
    sign_rule: Vec<(u8, u8)>,
    pattern: Pattern,
}

impl Product {
    /// The plan of `a · b` for an `a` zero outside `a` and a `b` zero
    /// outside `b` (at most 255 rows and inner dimension).
    pub(crate) fn new(a: &Pattern, b: &Pattern) -> Self {
        assert_eq!(a.cols, b.rows, "inner dimensions");
        assert!(a.rows < 256 && a.cols < 256, "dimensions beyond a byte");
        let (r, n, c) = (a.rows, a.cols, b.cols);
        let outside = |p: &Pattern| {
            p.nonzero
                .iter()
                .map(|&nz| if nz { 0 } else { u64::MAX })
                .collect()
        };
        // a's column k as runs of consecutive rows that may be nonzero.
        let column_runs: Vec<Vec<std::ops::Range<usize>>> = (0..n)
            .map(|k| {
                let mut out: Vec<std::ops::Range<usize>> = Vec::new();
                for i in (0..r).filter(|&i| a.at(i, k)) {
                    match out.last_mut() {
                        Some(run) if run.end == i => run.end = i + 1,
                        _ => out.push(i..i + 1),
                    }
                }
                out
            })
            .collect();
        let mut runs = Vec::new();
        let mut starts = vec![0];
        let mut sign_rule = Vec::new();
        for j in 0..c {
            for k in (0..n).filter(|&k| b.at(k, j)) {
                runs.extend(column_runs[k].iter().map(|rows| (k, rows.clone())));
            }
            starts.push(runs.len());
            for i in 0..r {
                if (0..n).all(|k| a.at(i, k) || b.at(k, j)) {
                    sign_rule.push((i as u8, j as u8));
                }
            }
        }
        Self {
            rows: r,
            inner: n,
            cols: c,
            a_outside: outside(a),
            b_outside: outside(b),
            runs,
            starts,
            sign_rule,
            pattern: Pattern::of(r, c, |i, j| (0..n).any(|k| a.at(i, k) && b.at(k, j))),
        }
    }

    /// Where the product may be nonzero.
    pub(crate) fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// Whether the plan holds for `a` and `b`: they are finite and +0
    /// (every bit clear) outside their patterns.
    pub(crate) fn planned<const R: usize, const K: usize, const C: usize>(
        &self,
        a: &SMatrix<f64, R, K>,
        b: &SMatrix<f64, K, C>,
    ) -> bool {
        assert_eq!(
            (self.rows, self.inner, self.cols),
            (R, K, C),
            "planned sizes"
        );
        // Without early exits, so that the checks vectorise.
        let fits = |s: &[f64], outside: &[u64]| {
            let (mut finite, mut set) = (true, 0u64);
            for (v, m) in s.iter().zip(outside) {
                finite &= v.is_finite();
                set |= v.to_bits() & m;
            }
            finite && set == 0
        };
        fits(a.as_slice(), &self.a_outside) && fits(b.as_slice(), &self.b_outside)
    }

    /// `a · b`, equal bit for bit to nalgebra's `a * b`: the planned terms
    /// when the factors are finite and +0 outside their patterns,
    /// [`product`] otherwise.
    pub(crate) fn apply<const R: usize, const K: usize, const C: usize>(
        &self,
        a: &SMatrix<f64, R, K>,
        b: &SMatrix<f64, K, C>,
    ) -> SMatrix<f64, R, C> {
        if !self.planned(a, b) {
            return product(a, b);
        }
        let a_s = a.as_slice();
        let b_s = b.as_slice();
        let mut out = SMatrix::<f64, R, C>::zeros();
        let out_s = out.as_mut_slice();
        for j in 0..C {
            let col = &mut out_s[j * R..(j + 1) * R];
            let b_col = &b_s[j * K..(j + 1) * K];
            for (k, rows) in &self.runs[self.starts[j]..self.starts[j + 1]] {
                let b_kj = b_col[*k];
                let a_col = &a_s[k * R..(k + 1) * R];
                for (c, &a_ik) in col[rows.clone()].iter_mut().zip(&a_col[rows.clone()]) {
                    // nalgebra's `t + y`; IEEE addition commutes exactly.
                    *c += a_ik * b_kj;
                }
            }
        }
        for &(i, j) in &self.sign_rule {
            let (i, j) = (usize::from(i), usize::from(j));
            let c = &mut out_s[j * R + i];
            if *c == 0.0 && (0..K).all(|k| is_negative_zero(a_s[k * R + i] * b_s[j * K + k])) {
                *c = -0.0;
            }
        }
        out
    }
}

/// `a · b`, equal bit for bit to nalgebra's `a * b` (see the [module
/// documentation](self)), at the cost of the nonzero terms only.
pub(crate) fn product<const R: usize, const K: usize, const C: usize>(
    a: &SMatrix<f64, R, K>,
    b: &SMatrix<f64, K, C>,
) -> SMatrix<f64, R, C> {
    let a_s = a.as_slice();
    let b_s = b.as_slice();
    // Without early exits, so that the checks vectorise.
    let finite = |s: &[f64]| s.iter().fold(true, |ok, v| ok & v.is_finite());
    if K > 64 || !(finite(a_s) && finite(b_s)) {
        return a * b;
    }
    // Per row of a and per column of b, bit k: whether element k is zero,
    // whether its sign bit is set (for the sign of zero sums below).
    let mut a_zero = [0u64; R];
    let mut a_sign = [0u64; R];
    // The rows of each column of a that hold a nonzero, increasing.
    let mut rows = [[0u8; R]; K];
    let mut counts = [0usize; K];
    for k in 0..K {
        for (i, &v) in a_s[k * R..(k + 1) * R].iter().enumerate() {
            a_zero[i] |= u64::from(v == 0.0) << k;
            a_sign[i] |= (v.to_bits() >> 63) << k;
            if v != 0.0 {
                rows[k][counts[k]] = i as u8;
                counts[k] += 1;
            }
        }
    }
    let every = if K == 64 { u64::MAX } else { (1u64 << K) - 1 };
    let mut out = SMatrix::<f64, R, C>::zeros();
    let out_s = out.as_mut_slice();
    for j in 0..C {
        let col = &mut out_s[j * R..(j + 1) * R];
        let b_col = &b_s[j * K..(j + 1) * K];
        let mut b_zero = 0u64;
        let mut b_sign = 0u64;
        for (k, &bkj) in b_col.iter().enumerate() {
            b_zero |= u64::from(bkj == 0.0) << k;
            b_sign |= (bkj.to_bits() >> 63) << k;
            if bkj == 0.0 {
                continue;
            }
            let a_col = &a_s[k * R..(k + 1) * R];
            for &i in &rows[k][..counts[k]] {
                let i = i as usize;
                col[i] += a_col[i] * bkj;
            }
        }
        // A zero is −0 in the dense sum exactly when every term is −0 (the
        // sum above, from +0, gives +0). A term with a zero factor is a
        // zero signed by the factors' signs; one of two nonzero factors
        // can still underflow to a zero, so those are multiplied out.
        for (i, c) in col.iter_mut().enumerate() {
            if *c != 0.0 {
                continue;
            }
            let zero_terms = a_zero[i] | b_zero;
            let negative = if zero_terms == every {
                (a_sign[i] ^ b_sign) & every == every
            } else {
                (0..K).all(|k| is_negative_zero(a_s[k * R + i] * b_col[k]))
            };
            if negative {
                *c = -0.0;
            }
        }
    }
    out
}

fn is_negative_zero(v: f64) -> bool {
    v == 0.0 && v.is_sign_negative()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random matrix with about `density` of its entries nonzero; its
    /// zeros −0 with probability `negative_zeros`, some entries tiny (their
    /// products underflow to signed zeros), negative ones unless `positive`.
    fn sparse<const R: usize, const C: usize>(
        rng: &mut ChaCha8Rng,
        density: f64,
        negative_zeros: f64,
        positive: bool,
    ) -> SMatrix<f64, R, C> {
        SMatrix::from_fn(|_, _| {
            if rng.random::<f64>() >= density {
                return if rng.random::<f64>() < negative_zeros {
                    -0.0
                } else {
                    0.0
                };
            }
            let low = if positive { 0.5 } else { -2.0 };
            let v: f64 = rng.random_range(low..2.0);
            match rng.random_range(0..10) {
                0 => v * 1e-200,
                1 => v * 1e150,
                _ => v,
            }
        })
    }

    fn assert_same_bits<const R: usize, const C: usize>(
        got: &SMatrix<f64, R, C>,
        want: &SMatrix<f64, R, C>,
    ) {
        for (g, w) in got.iter().zip(want.iter()) {
            assert_eq!(g.to_bits(), w.to_bits(), "{g:e} vs {w:e}");
        }
    }

    /// Random sparse factors of the sizes the filters use, from almost
    /// empty to dense, signed zeros and underflowing products included:
    /// every bit (zero signs too) equals nalgebra's product.
    #[test]
    fn equals_the_dense_product_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut negative_zeros = 0;
        for round in 0..480 {
            let density = [0.0, 0.02, 0.1, 0.3, 0.7, 1.0][round % 6];
            // Every zero of a −0 and b's values positive (zeros +0) makes
            // the rows of a that are all zero give −0 in the dense sum.
            let (a_negative_zeros, b_negative_zeros, positive) = match (round / 6) % 4 {
                0 => (1.0, 0.0, true),
                _ => (0.5, 0.5, false),
            };
            let a: SMatrix<f64, 21, 21> = sparse(&mut rng, density, a_negative_zeros, positive);
            let b: SMatrix<f64, 21, 21> = sparse(&mut rng, density, b_negative_zeros, positive);
            let want = a * b;
            negative_zeros += want
                .iter()
                .filter(|v| **v == 0.0 && v.is_sign_negative())
                .count();
            assert_same_bits(&product(&a, &b), &want);
            let c: SMatrix<f64, 21, 6> = sparse(&mut rng, density, b_negative_zeros, positive);
            assert_same_bits(&product(&a, &c), &(a * c));
            let d: SMatrix<f64, 3, 5> = sparse(&mut rng, density, a_negative_zeros, positive);
            let e: SMatrix<f64, 5, 4> = sparse(&mut rng, density, b_negative_zeros, positive);
            assert_same_bits(&product(&d, &e), &(d * e));
        }
        // The sign rule was exercised, not only +0.
        assert!(negative_zeros > 100, "{negative_zeros} negative zeros");
    }

    /// A matrix following `pattern`: inside, what `sparse` draws; outside,
    /// +0.
    fn following<const R: usize, const C: usize>(
        rng: &mut ChaCha8Rng,
        pattern: &Pattern,
        density: f64,
        negative_zeros: f64,
        positive: bool,
    ) -> SMatrix<f64, R, C> {
        let inside: SMatrix<f64, R, C> = sparse(rng, density, negative_zeros, positive);
        SMatrix::from_fn(|i, j| {
            if pattern.at(i, j) {
                inside[(i, j)]
            } else {
                0.0
            }
        })
    }

    /// Planned products on random patterns, with factors that follow them
    /// (zeros of both signs and underflowing products inside) and factors
    /// that do not (a −0, a nonzero or an infinity outside): every bit
    /// equals nalgebra's product.
    #[test]
    fn planned_products_equal_the_dense_product_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut negative_zeros = 0;
        let mut planned_sign_rules = 0;
        for round in 0..240 {
            let fill = [0.05, 0.2, 0.5, 0.9, 1.0][round % 5];
            let mut draw = |rows, cols| {
                let u: Vec<f64> = (0..rows * cols).map(|_| rng.random()).collect();
                Pattern::of(rows, cols, |i, j| u[j * rows + i] < fill)
            };
            let (pa, pb, pc) = (draw(21, 21), draw(21, 6), draw(21, 21));
            let ab = Product::new(&pa, &pb);
            let ac = Product::new(&pa, &pc);
            planned_sign_rules += ac.sign_rule.len();
            let (a_negative_zeros, b_negative_zeros, positive) = match (round / 5) % 3 {
                0 => (1.0, 0.0, true),
                _ => (0.5, 0.5, false),
            };
            let density = [1.0, 0.8, 0.3, 0.0][(round / 15) % 4];
            let mut a: SMatrix<f64, 21, 21> =
                following(&mut rng, &pa, density, a_negative_zeros, positive);
            let b: SMatrix<f64, 21, 6> =
                following(&mut rng, &pb, density, b_negative_zeros, positive);
            let c: SMatrix<f64, 21, 21> =
                following(&mut rng, &pc, density, b_negative_zeros, positive);
            let want = a * c;
            negative_zeros += want
                .iter()
                .filter(|v| **v == 0.0 && v.is_sign_negative())
                .count();
            assert_same_bits(&ac.apply(&a, &c), &want);
            assert_same_bits(&ab.apply(&a, &b), &(a * b));
            // The product's pattern holds its nonzeros.
            let got = ac.apply(&a, &c);
            for j in 0..21 {
                for i in 0..21 {
                    assert!(ac.pattern().at(i, j) || got[(i, j)] == 0.0);
                }
            }
            // Outside the pattern: planned or not, the dense bits.
            if let Some((i, k)) = (0..21 * 21)
                .map(|e| (e % 21, e / 21))
                .find(|&(i, k)| !pa.at(i, k))
            {
                for v in [-0.0, 1.5, f64::INFINITY] {
                    a[(i, k)] = v;
                    let (got, want) = (ab.apply(&a, &b), a * b);
                    for (g, w) in got.iter().zip(want.iter()) {
                        assert!(g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()));
                    }
                }
            }
        }
        assert!(negative_zeros > 50, "{negative_zeros} negative zeros");
        assert!(planned_sign_rules > 50, "{planned_sign_rules} sign rules");
    }

    /// All-negative-zero terms: a row of −0 times a column of positive
    /// values sums to −0, as the dense product does; one +0 term makes it
    /// +0.
    #[test]
    fn a_sum_of_negative_zeros_is_negative_zero() {
        let mut a = SMatrix::<f64, 3, 3>::from_element(-0.0);
        let b = SMatrix::<f64, 3, 3>::from_element(1.0);
        assert!(product(&a, &b)[(0, 0)].is_sign_negative());
        assert_same_bits(&product(&a, &b), &(a * b));
        a[(0, 1)] = 0.0;
        assert!(product(&a, &b)[(0, 0)].is_sign_positive());
        assert_same_bits(&product(&a, &b), &(a * b));
    }

    /// A non-finite factor goes to the dense product: 0 · ∞ is NaN there.
    #[test]
    fn non_finite_factors_give_the_dense_result() {
        let mut a = SMatrix::<f64, 3, 3>::zeros();
        a[(0, 0)] = 1.0;
        let mut b = SMatrix::<f64, 3, 3>::identity();
        b[(1, 2)] = f64::INFINITY;
        let got = product(&a, &b);
        assert!(got[(0, 2)].is_nan());
        assert_eq!(got[(0, 0)], 1.0);
    }
}
