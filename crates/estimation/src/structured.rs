//! The time update for a transition matrix with a diagonal trailing block.
//!
//! Many state vectors end in states that evolve on their own — random
//! constants, first-order Gauss–Markov processes (sensor biases, scale
//! factors, clock terms) — so the rows of Φ that belong to them hold only
//! their diagonal element, while the leading rows may couple to anything.
//! Φ is then block upper triangular with a diagonal trailing block, and
//! `Φ P Φᵀ` needs the dense arithmetic only for the leading rows: with r
//! full rows of n, Φ P costs r n² multiply-adds instead of n³ (the trailing
//! rows are scaled rows of P), and the lower triangle of (Φ P) Φᵀ costs
//! about r n (n − r/2) instead of about 0.6 n³ (a trailing column j is
//! `(Φ P)(·, j) Φ(j, j)`). At 9 full rows of 21 that is half the work.
//!
//! Each element is summed over the same nonzero terms, in the same order
//! (increasing inner index, `out += a · b` with a separate multiply and
//! add), as the dense kernels of [`KalmanFilter::predict`] for fixed sizes
//! and run-time sizes up to 32: the terms left out are products with an
//! exact zero of Φ, which change a sum only in the sign of an exact zero. So
//! for those sizes the propagated covariance equals the dense one bit for
//! bit, up to the sign of elements that are exactly zero.
//!
//! The structure is declared ([`TrailingDiagonal`]) and checked on every
//! call: a Φ without it is propagated by the dense product, so a wrong
//! declaration costs time, never accuracy.

use nalgebra::{DefaultAllocator, Dim, OMatrix, allocator::Allocator};

use crate::check;
use crate::dense;
use crate::error::{Matrix, Result, Step};
use crate::kalman::KalmanFilter;

/// The structure of a transition matrix Φ (n × n): the first
/// [`full_rows`](Self::full_rows) rows may hold anything, every later row
/// only its diagonal element (those states evolve on their own).
///
/// ```
/// use aidnav_estimation::{TrailingDiagonal, nalgebra::Matrix3};
/// let phi = Matrix3::new(1.0, 0.1, 0.2,
///                        0.0, 0.9, 0.0,
///                        0.0, 0.0, 0.8);
/// assert!(TrailingDiagonal::new(1).holds(&phi));
/// assert!(!TrailingDiagonal::new(0).holds(&phi));
/// assert_eq!(TrailingDiagonal::of(&phi), TrailingDiagonal::new(1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrailingDiagonal {
    full_rows: usize,
}

impl TrailingDiagonal {
    /// Φ's first `full_rows` rows are full, the rest diagonal (`full_rows`
    /// at or beyond the dimension: Φ is dense).
    pub const fn new(full_rows: usize) -> Self {
        Self { full_rows }
    }

    /// The number of leading rows that may hold off-diagonal elements.
    pub const fn full_rows(&self) -> usize {
        self.full_rows
    }

    /// The tightest structure of a square `phi`: the fewest leading rows
    /// after which every row is diagonal (its dimension when the last row is
    /// not; 0 for a diagonal Φ).
    pub fn of<N: Dim>(phi: &OMatrix<f64, N, N>) -> Self
    where
        DefaultAllocator: Allocator<N, N>,
    {
        // One past the last row with an off-diagonal nonzero: each column
        // is read from the bottom up to the rows already known to be full
        // (a structured Φ is read about once below its full rows; a
        // column's first off-diagonal nonzero from the bottom ends it).
        let n = phi.nrows();
        let s = phi.as_slice();
        let mut full_rows = 0;
        for j in 0..n {
            let column = &s[j * n..(j + 1) * n];
            if let Some(i) = (full_rows..n).rev().find(|&i| i != j && column[i] != 0.0) {
                full_rows = i + 1;
            }
        }
        Self { full_rows }
    }

    /// Whether `phi` is square and every row from
    /// [`full_rows`](Self::full_rows) on is zero off the diagonal.
    pub fn holds<N: Dim>(&self, phi: &OMatrix<f64, N, N>) -> bool
    where
        DefaultAllocator: Allocator<N, N>,
    {
        let (nd, cd) = phi.shape_generic();
        let n = nd.value();
        cd.value() == n
            && (self.full_rows >= n
                || trailing_rows_are_diagonal(n, self.full_rows, phi.as_slice()))
    }
}

/// Whether the rows from r on of the square (n × n, column-major) `phi`
/// are zero off the diagonal, read column by column (contiguous).
/// Without early exits, so that the loop vectorises (Φ has the structure
/// nearly always; a check that stops early saves nothing then); inlined, so
/// that a compile-time n fixes the column lengths.
#[inline(always)]
fn trailing_rows_are_diagonal(n: usize, r: usize, phi: &[f64]) -> bool {
    // A value is nonzero when its bits without the sign are; the bits are
    // OR-ed over each column's rows r.. but the diagonal (integer ORs that
    // vectorise; a compare per element with the diagonal's index test was
    // a hundredth of the drive's processing).
    let nonzero_bits = |values: &[f64]| values.iter().fold(0, |acc, v| acc | (v.to_bits() << 1));
    let mut off_diagonal = 0;
    for j in 0..n {
        let column = &phi[j * n + r..(j + 1) * n];
        off_diagonal |= if j >= r {
            let (above, below) = column.split_at(j - r);
            nonzero_bits(above) | nonzero_bits(&below[1..])
        } else {
            nonzero_bits(column)
        };
    }
    off_diagonal == 0
}

impl<N: Dim> KalmanFilter<N>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// [`predict`](Self::predict) for a Φ of the declared structure:
    /// `x = Φ x`, `P = Φ P Φᵀ + Q`, the same checks and the same result (see
    /// the [module documentation](crate::structured)) at the cost of the
    /// leading rows only. A Φ that does not have the structure is
    /// propagated by the dense product.
    ///
    /// ```
    /// use aidnav_estimation::{KalmanFilter, TrailingDiagonal, nalgebra::{Matrix2, Vector2}};
    /// // Position driven by a velocity that decays (first-order Gauss–Markov).
    /// let phi = Matrix2::new(1.0, 0.1, 0.0, 0.99);
    /// let q = Matrix2::new(0.0, 0.0, 0.0, 0.01);
    /// let mut dense = KalmanFilter::new(Vector2::new(0.0, 1.0), Matrix2::identity()).unwrap();
    /// let mut structured = dense.clone();
    /// dense.predict(&phi, &q).unwrap();
    /// structured.predict_structured(&phi, &q, TrailingDiagonal::new(1)).unwrap();
    /// assert_eq!(dense, structured);
    /// ```
    pub fn predict_structured(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q: &OMatrix<f64, N, N>,
        structure: TrailingDiagonal,
    ) -> Result<()> {
        self.predict_state(phi)?;
        self.propagate_structured(phi, q, structure)
    }

    /// [`predict_covariance`](Self::predict_covariance) for a Φ of the
    /// declared structure (see [`predict_structured`](Self::predict_structured)).
    pub fn predict_covariance_structured(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q: &OMatrix<f64, N, N>,
        structure: TrailingDiagonal,
    ) -> Result<()> {
        let n = self.dim();
        check::shape(phi, (n, n), Step::Predict, Matrix::Phi)?;
        check::finite(phi, Step::Predict, Matrix::Phi)?;
        self.propagate_structured(phi, q, structure)
    }

    /// `P = Φ P Φᵀ + Q` for a Φ already checked (shape, finite).
    fn propagate_structured(
        &mut self,
        phi: &OMatrix<f64, N, N>,
        q: &OMatrix<f64, N, N>,
        structure: TrailingDiagonal,
    ) -> Result<()> {
        let n = self.dim();
        let r = structure.full_rows();
        if r >= n || !structure.holds(phi) {
            return self.predict_covariance(phi, q);
        }
        // Φ P Φᵀ is symmetric: its lower triangle only, on (Q + Qᵀ)/2 —
        // an exactly symmetric Q read where it is (no copy, its finiteness
        // told by P's: see `check::process_noise_unless_exact`).
        let symmetrized = check::process_noise_unless_exact(q, n)?;
        let q_added = symmetrized.as_ref().unwrap_or(q);
        let (nd, _) = self.p.shape_generic();
        // (Φ P)ᵀ, then P: every element of the result is written.
        let mut scratch = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
        let mut phi_p = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
        // Both products through `run_widest` (AVX2 where the CPU has it:
        // the same operations in the same order, bit for bit).
        dense::run_widest(
            StructuredProduct { n: nd, r },
            phi_p.as_mut_slice(),
            scratch.as_mut_slice(),
            self.p.as_slice(),
            phi.as_slice(),
        );
        dense::run_widest(
            StructuredCongruence {
                n: nd,
                r,
                q: q_added.as_slice(),
            },
            scratch.as_mut_slice(),
            &mut [],
            phi_p.as_slice(),
            phi.as_slice(),
        );
        if let Err(not_finite) = check::finite(&scratch, Step::Predict, Matrix::P) {
            // A non-finite Q is what made P so: reported as before.
            if symmetrized.is_none() {
                check::finite(q, Step::Predict, Matrix::Q)?;
            }
            return Err(not_finite);
        }
        self.p = scratch;
        Ok(())
    }
}

/// Φ P for a Φ whose rows from r on are diagonal and a finite, exactly
/// symmetric P, on column-major slices: `out` = Φ P, `scratch` = (Φ P)ᵀ,
/// `a` = P, `b` = Φ. (Φ P)ᵀ = P Φᵀ column by column ([`times_transpose`];
/// leaving out the terms of Φ's exact zeros there would give the same bits
/// but measured slower: the branch costs more than the products it skips),
/// then turned over: the second product reads Φ P by columns.
struct StructuredProduct<D: Dim> {
    n: D,
    r: usize,
}

impl<D: Dim> dense::Widened for StructuredProduct<D> {
    #[inline(always)]
    fn run(self, out: &mut [f64], scratch: &mut [f64], a: &[f64], b: &[f64]) {
        let n = self.n.value();
        let nn = n * n;
        let (phi_p, phi_p_t, p, phi) = (&mut out[..nn], &mut scratch[..nn], &a[..nn], &b[..nn]);
        times_transpose(n, self.r, p, phi, phi_p_t);
        transpose(n, phi_p_t, phi_p);
    }
}

/// `out = Q + W Φᵀ`, lower triangle, then mirrored
/// ([`add_times_transpose_lower_onto`]), on column-major slices: `out`
/// (anything on entry), `q` = Q, `a` = W = Φ P, `b` = Φ.
struct StructuredCongruence<'q, D: Dim> {
    n: D,
    r: usize,
    q: &'q [f64],
}

impl<D: Dim> dense::Widened for StructuredCongruence<'_, D> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let n = self.n.value();
        let nn = n * n;
        let (out, q, phi_p, phi) = (&mut out[..nn], &self.q[..nn], &a[..nn], &b[..nn]);
        add_times_transpose_lower_onto(n, self.r, q, phi_p, phi, out);
        dense::mirror_lower_slice(n, out);
    }
}

/// `out = S Φᵀ` (column-major n × n) for a Φ whose rows from r on are
/// diagonal and any S; with S = P symmetric it is (Φ P)ᵀ. Column j < r
/// accumulates `S(·, k) Φ(j, k)` in increasing k — element (i, j) is the
/// dense kernels' `Σ_k Φ(j, k) P(k, i)`, the same products in the same
/// order — with the whole column in registers for fixed sizes; column
/// j ≥ r is `S(·, j) Φ(j, j)`, after `0 +` so that a zero product is +0
/// as the dense sum from +0 gives.
#[inline(always)]
pub(crate) fn times_transpose(n: usize, r: usize, s: &[f64], phi: &[f64], out: &mut [f64]) {
    for j in 0..n {
        let oc = &mut out[j * n..(j + 1) * n];
        if j < r {
            oc.fill(0.0);
            for k in 0..n {
                let f = phi[k * n + j];
                let sc = &s[k * n..(k + 1) * n];
                for (o, &x) in oc.iter_mut().zip(sc) {
                    *o += x * f;
                }
            }
        } else {
            let f = phi[j * n + j];
            let sc = &s[j * n..(j + 1) * n];
            for (o, &x) in oc.iter_mut().zip(sc) {
                *o = 0.0 + x * f;
            }
        }
    }
}

/// `out = aᵀ` (column-major n × n).
#[inline(always)]
fn transpose(n: usize, a: &[f64], out: &mut [f64]) {
    for j in 0..n {
        for (i, o) in out[j * n..(j + 1) * n].iter_mut().enumerate() {
            *o = a[i * n + j];
        }
    }
}

/// Columns `cols` of `out = Q + W Φᵀ`, rows `row0..n`: each starts at Q's
/// and accumulates `W(·, k) Φ(j, k)` in increasing k (the column in
/// registers for fixed sizes).
#[inline(always)]
fn full_columns(
    n: usize,
    (row0, cols): (usize, std::ops::Range<usize>),
    (q, w): (&[f64], &[f64]),
    phi: &[f64],
    out: &mut [f64],
) {
    for j in cols {
        let oc = &mut out[j * n + row0..(j + 1) * n];
        oc.copy_from_slice(&q[j * n + row0..(j + 1) * n]);
        for k in 0..n {
            let f = phi[k * n + j];
            let wc = &w[k * n + row0..(k + 1) * n];
            for (o, &x) in oc.iter_mut().zip(wc) {
                *o += x * f;
            }
        }
    }
}

/// The lower triangle of `out = Q + W Φᵀ` (column-major n × n; elements
/// above the diagonal are left unspecified: follow with a mirror) for
/// W = Φ P and a Φ whose rows from r on are diagonal, each element starting
/// at Q's (what `out += W Φᵀ` on a copy of Q adds, without the copy).
/// Columns j < r: `W(·, k) Φ(j, k)` in increasing k, as the dense kernel,
/// in its column blocks; column j ≥ r: `W(·, j) Φ(j, j)`, its only nonzero
/// term.
#[inline(always)]
fn add_times_transpose_lower_onto(
    n: usize,
    r: usize,
    q: &[f64],
    w: &[f64],
    phi: &[f64],
    out: &mut [f64],
) {
    let (s1, s2, s3) = dense::lower_block_starts(n);
    // Four calls, not a loop: each inlines with its own constant row count.
    full_columns(n, (0, 0..s1.min(r)), (q, w), phi, out);
    full_columns(n, (s1, s1..s2.min(r)), (q, w), phi, out);
    full_columns(n, (s2, s2..s3.min(r)), (q, w), phi, out);
    full_columns(n, (s3, s3..r), (q, w), phi, out);
    for j in r..n {
        let f = phi[j * n + j];
        let oc = &mut out[j * n + j..(j + 1) * n];
        let (qc, wc) = (&q[j * n + j..(j + 1) * n], &w[j * n + j..(j + 1) * n]);
        for ((o, &e), &x) in oc.iter_mut().zip(qc).zip(wc) {
            *o = e + x * f;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector, SMatrix, SVector};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng as StdRng;

    /// A random Φ with `full_rows` full rows (entries of both signs, some
    /// exact zeros in the full rows too) and a diagonal trailing block.
    fn structured_phi<const N: usize>(rng: &mut StdRng, full_rows: usize) -> SMatrix<f64, N, N> {
        SMatrix::from_fn(|i, j| {
            if i < full_rows {
                if rng.random_bool(0.2) {
                    0.0
                } else {
                    rng.random_range(-1.0..1.0) + if i == j { 1.0 } else { 0.0 }
                }
            } else if i == j {
                rng.random_range(0.5..1.0)
            } else {
                0.0
            }
        })
    }

    /// A random symmetric positive definite matrix, A Aᵀ + I/10.
    fn spd<const N: usize>(rng: &mut StdRng) -> SMatrix<f64, N, N> {
        let a = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let m = a * a.transpose() + SMatrix::identity() * 0.1;
        (m + m.transpose()) * 0.5
    }

    /// Bitwise equality of two matrices, the sign of exact zeros aside.
    fn same_bits<const N: usize>(a: &SMatrix<f64, N, N>, b: &SMatrix<f64, N, N>) -> bool {
        a.iter()
            .zip(b.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits() || (*x == 0.0 && *y == 0.0))
    }

    #[test]
    fn the_structure_is_found_and_checked() {
        let mut rng = StdRng::seed_from_u64(1);
        let phi = structured_phi::<7>(&mut rng, 3);
        // Row 2 is full (its random entries are nonzero with probability 1
        // somewhere off the diagonal at this seed): the tightest is 3.
        assert_eq!(TrailingDiagonal::of(&phi), TrailingDiagonal::new(3));
        assert!(TrailingDiagonal::new(3).holds(&phi));
        assert!(TrailingDiagonal::new(5).holds(&phi));
        assert!(!TrailingDiagonal::new(2).holds(&phi));
        assert_eq!(
            TrailingDiagonal::of(&SMatrix::<f64, 4, 4>::identity()),
            TrailingDiagonal::new(0)
        );
        let mut last_full = SMatrix::<f64, 4, 4>::identity();
        last_full[(3, 0)] = 0.5;
        assert_eq!(TrailingDiagonal::of(&last_full), TrailingDiagonal::new(4));
        // A diagonal row among full ones does not end the full rows.
        let mut gap = SMatrix::<f64, 4, 4>::identity();
        gap[(0, 3)] = 0.1;
        gap[(2, 1)] = -0.2;
        assert_eq!(TrailingDiagonal::of(&gap), TrailingDiagonal::new(3));
        assert!(!TrailingDiagonal::new(1).holds(&gap));
    }

    /// `of` (read from the bottom, stopping early) against its definition
    /// read in full: one past the last row with an off-diagonal nonzero
    /// (NaN counts), on random patterns of nonzeros.
    #[test]
    fn the_tightest_structure_equals_its_definition() {
        let mut rng = StdRng::seed_from_u64(7);
        for _ in 0..500 {
            let density = rng.random_range(0.0..0.2);
            let phi = SMatrix::<f64, 9, 9>::from_fn(|_, _| {
                if rng.random_bool(density) {
                    if rng.random_bool(0.1) { f64::NAN } else { -0.5 }
                } else {
                    0.0
                }
            });
            let mut expected = 0;
            for i in 0..9 {
                for j in 0..9 {
                    if i != j && phi[(i, j)] != 0.0 {
                        expected = expected.max(i + 1);
                    }
                }
            }
            assert_eq!(TrailingDiagonal::of(&phi).full_rows(), expected, "{phi}");
        }
    }

    /// `holds` against the plain test of every trailing off-diagonal
    /// element, for one value (nonzero, −0, NaN, ∞, a subnormal) at every
    /// position of a 7 × 7 Φ and every declared number of full rows.
    #[test]
    fn the_structure_check_equals_the_elementwise_test() {
        let naive = |phi: &SMatrix<f64, 7, 7>, r: usize| {
            (r..7).all(|i| (0..7).all(|j| i == j || phi[(i, j)] == 0.0))
        };
        for value in [0.5, -0.0, f64::NAN, f64::INFINITY, 5e-324] {
            for at in 0..49 {
                let mut phi = SMatrix::<f64, 7, 7>::identity() * 0.9;
                phi[(at % 7, at / 7)] = value;
                for r in 0..=7 {
                    let s = TrailingDiagonal::new(r);
                    assert_eq!(s.holds(&phi), naive(&phi, r), "{value} at {at}, {r} rows");
                }
            }
        }
    }

    /// Fixed size 21 (the navigation filter's), 9 full rows and others: the
    /// structured time update equals the dense one bit for bit (up to the
    /// sign of exact zeros), P exactly symmetric.
    #[test]
    fn structured_predict_equals_the_dense_one_bit_for_bit() {
        let mut rng = StdRng::seed_from_u64(17);
        for full_rows in [0, 1, 9, 20, 21] {
            for _ in 0..20 {
                let phi = structured_phi::<21>(&mut rng, full_rows);
                let q = spd::<21>(&mut rng) * 0.01;
                let x = SVector::<f64, 21>::from_fn(|_, _| rng.random_range(-1.0..1.0));
                let mut dense = KalmanFilter::new(x, spd::<21>(&mut rng)).unwrap();
                let mut structured = dense.clone();
                dense.predict(&phi, &q).unwrap();
                structured
                    .predict_structured(&phi, &q, TrailingDiagonal::new(full_rows))
                    .unwrap();
                assert_eq!(dense.state(), structured.state());
                assert!(same_bits(dense.covariance(), structured.covariance()));
                let p = structured.covariance();
                assert_eq!(p, &p.transpose(), "P exactly symmetric");
            }
        }
    }

    /// The previous formulation of the structured time update (without the
    /// wider dispatch), the reference of the one in use.
    fn reference_propagate<const N: usize>(
        p: &SMatrix<f64, N, N>,
        phi: &SMatrix<f64, N, N>,
        q: &SMatrix<f64, N, N>,
        r: usize,
    ) -> SMatrix<f64, N, N> {
        let mut out = check::process_noise(q, N).unwrap();
        let mut scratch = SMatrix::<f64, N, N>::zeros();
        let mut phi_p = SMatrix::<f64, N, N>::zeros();
        times_transpose(N, r, p.as_slice(), phi.as_slice(), scratch.as_mut_slice());
        transpose(N, scratch.as_slice(), phi_p.as_mut_slice());
        // `out += W Φᵀ` on Q's copy, lower triangle: each element in
        // increasing k; a trailing column's only term Φ(j, j).
        let (w, f) = (phi_p.as_slice(), phi.as_slice());
        let o = out.as_mut_slice();
        for j in 0..N {
            for i in j..N {
                if j < r {
                    for k in 0..N {
                        o[j * N + i] += w[k * N + i] * f[k * N + j];
                    }
                } else {
                    o[j * N + i] += w[j * N + i] * f[j * N + j];
                }
            }
        }
        dense::mirror_lower(&mut out);
        out
    }

    /// The time update in use (AVX2 where the CPU has it) equals the
    /// previous formulation to the bit, the sign of exact zeros included,
    /// on random Φ (a fifth of the leading rows' entries ±0), P and Q with
    /// exact zeros and −0s.
    #[test]
    fn structured_predict_equals_the_previous_formulation_to_the_bit() {
        let mut rng = StdRng::seed_from_u64(29);
        let bits = |m: &SMatrix<f64, 21, 21>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for full_rows in [0, 1, 9, 20] {
            for round in 0..40 {
                let mut phi = structured_phi::<21>(&mut rng, full_rows);
                for v in phi.iter_mut() {
                    if *v == 0.0 && rng.random_bool(0.5) {
                        *v = -0.0;
                    }
                }
                let mut q = spd::<21>(&mut rng) * 0.01;
                let mut p0 = spd::<21>(&mut rng);
                // Uncorrelated blocks (exact zeros, some −0 in Q) in half the rounds.
                if round % 2 == 1 {
                    for i in 0..21 {
                        for j in 0..i {
                            if (i + j) % 3 == 0 {
                                let zero = if rng.random_bool(0.5) { -0.0 } else { 0.0 };
                                q[(i, j)] = zero;
                                q[(j, i)] = zero;
                                p0[(i, j)] = 0.0;
                                p0[(j, i)] = 0.0;
                            }
                        }
                    }
                }
                let expected = reference_propagate(&p0, &phi, &q, full_rows);
                let mut kf = KalmanFilter::new(SVector::<f64, 21>::zeros(), p0).unwrap();
                kf.predict_structured(&phi, &q, TrailingDiagonal::new(full_rows))
                    .unwrap();
                assert_eq!(
                    bits(kf.covariance()),
                    bits(&expected),
                    "{full_rows} rows, round {round}"
                );
            }
        }
    }

    /// Q's finiteness is checked after P's when Q is exactly symmetric:
    /// the same error as the dense time update (which checks Q first) for a
    /// non-finite Q wherever the bad value is (±∞ or NaN on the diagonal, a
    /// ±∞ pair or a NaN off it), for an asymmetric Q and for a P that
    /// overflows with a finite Q.
    #[test]
    fn a_bad_q_or_an_overflow_gives_the_dense_time_updates_error() {
        use crate::error::EstimationError;
        let mut rng = StdRng::seed_from_u64(31);
        let phi = structured_phi::<21>(&mut rng, 9);
        let q = spd::<21>(&mut rng) * 0.01;
        let kf = KalmanFilter::new(SVector::<f64, 21>::zeros(), spd::<21>(&mut rng)).unwrap();
        let s = TrailingDiagonal::new(9);
        let mut cases = Vec::new();
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            for (i, j) in [(0, 0), (20, 20), (4, 13), (12, 1), (19, 20)] {
                let mut q_bad = q;
                q_bad[(i, j)] = bad;
                cases.push((phi, q_bad));
                q_bad[(j, i)] = bad;
                cases.push((phi, q_bad));
            }
        }
        let mut asymmetric = q;
        asymmetric[(1, 0)] += 1.0;
        cases.push((phi, asymmetric));
        let mut huge = phi;
        huge[(0, 0)] = 1e200;
        cases.push((huge, q));
        let mut huge_q = q;
        huge_q[(3, 3)] = f64::INFINITY;
        cases.push((huge, huge_q));
        let non_finite = |matrix| EstimationError::NonFinite {
            step: Step::Predict,
            matrix,
        };
        for (k, (phi, q)) in cases.iter().enumerate() {
            let dense = kf.clone().predict(phi, q).unwrap_err();
            let structured = kf.clone().predict_structured(phi, q, s).unwrap_err();
            assert_eq!(structured, dense, "case {k}");
            // What checking Q first reports.
            let expected = if !q.iter().all(|v| v.is_finite()) {
                Some(non_finite(Matrix::Q))
            } else if phi[(0, 0)] == 1e200 {
                Some(non_finite(Matrix::P))
            } else {
                None
            };
            if let Some(e) = expected {
                assert_eq!(structured, e, "case {k}");
            } else {
                assert!(
                    matches!(structured, EstimationError::NotSymmetric { .. }),
                    "case {k}: {structured:?}"
                );
            }
        }
    }

    /// `S Φᵀ` for any S (the smoother's P Φᵀ and its Φ Φ_acc turned
    /// over): the dense product bit for bit.
    #[test]
    fn the_transpose_product_equals_the_dense_one_bit_for_bit() {
        let mut rng = StdRng::seed_from_u64(23);
        for full_rows in [0, 4, 9, 21] {
            let phi = structured_phi::<21>(&mut rng, full_rows);
            let s = SMatrix::<f64, 21, 21>::from_fn(|_, _| rng.random_range(-2.0..2.0));
            let mut out = SMatrix::<f64, 21, 21>::zeros();
            times_transpose(
                21,
                full_rows,
                s.as_slice(),
                phi.as_slice(),
                out.as_mut_slice(),
            );
            let mut dense = SMatrix::<f64, 21, 21>::zeros();
            dense::gemm_nt(&mut dense, 1.0, &s, &phi, 0.0);
            let bits = |m: &SMatrix<f64, 21, 21>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&out), bits(&dense), "{full_rows} full rows");
        }
    }

    /// Run-time size beyond the dense kernels' (nalgebra's packed product
    /// there): the same to 1e-12 relative, P exactly symmetric.
    #[test]
    fn structured_predict_matches_the_dense_one_at_a_large_run_time_size() {
        let mut rng = StdRng::seed_from_u64(3);
        let n = 40;
        let full_rows = 15;
        let phi = DMatrix::from_fn(n, n, |i, j| {
            if i < full_rows {
                rng.random_range(-1.0..1.0)
            } else if i == j {
                rng.random_range(0.5..1.0)
            } else {
                0.0
            }
        });
        let a = DMatrix::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
        let p0 = &a * a.transpose() + DMatrix::identity(n, n);
        let p0 = (&p0 + p0.transpose()) * 0.5;
        let q = DMatrix::identity(n, n) * 0.01;
        let mut dense = KalmanFilter::new(DVector::zeros(n), p0).unwrap();
        let mut structured = dense.clone();
        dense.predict(&phi, &q).unwrap();
        structured
            .predict_structured(&phi, &q, TrailingDiagonal::new(full_rows))
            .unwrap();
        let (d, s) = (dense.covariance(), structured.covariance());
        let worst = d
            .iter()
            .zip(s.iter())
            .map(|(a, b)| (a - b).abs() / a.abs().max(1.0))
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "relative difference {worst}");
        assert_eq!(s, &s.transpose());
    }

    /// A declared structure Φ does not have is not trusted: the dense
    /// product, the dense result exactly.
    #[test]
    fn a_wrong_declaration_falls_back_to_the_dense_product() {
        let mut rng = StdRng::seed_from_u64(5);
        let phi = structured_phi::<21>(&mut rng, 12);
        let q = spd::<21>(&mut rng) * 0.01;
        let mut dense = KalmanFilter::new(SVector::zeros(), spd::<21>(&mut rng)).unwrap();
        let mut structured = dense.clone();
        dense.predict(&phi, &q).unwrap();
        structured
            .predict_structured(&phi, &q, TrailingDiagonal::new(9))
            .unwrap();
        assert_eq!(dense, structured);
    }

    /// The checks of the dense time update: a non-finite Φ or Q and a P that
    /// overflows are errors, not silently propagated.
    #[test]
    fn non_finite_inputs_and_results_are_errors() {
        let mut rng = StdRng::seed_from_u64(9);
        let phi = structured_phi::<21>(&mut rng, 9);
        let q = spd::<21>(&mut rng) * 0.01;
        let kf = KalmanFilter::new(SVector::<f64, 21>::zeros(), spd::<21>(&mut rng)).unwrap();
        let s = TrailingDiagonal::new(9);
        let mut bad_phi = phi;
        bad_phi[(2, 4)] = f64::NAN;
        assert!(kf.clone().predict_structured(&bad_phi, &q, s).is_err());
        let mut bad_q = q;
        bad_q[(15, 15)] = f64::INFINITY;
        assert!(kf.clone().predict_structured(&phi, &bad_q, s).is_err());
        let mut huge = phi;
        huge[(0, 0)] = 1e200;
        assert!(kf.clone().predict_structured(&huge, &q, s).is_err());
        let mut asymmetric = q;
        asymmetric[(1, 0)] += 1.0;
        assert!(kf.clone().predict_structured(&phi, &asymmetric, s).is_err());
    }
}
