//! Second-order discretisation of a sparse linear model, ẋ = F x + w with
//! E[w(t) w(s)ᵀ] = Q_c δ(t − s), over a step Δt:
//!
//! ```text
//! Φ = I + A + A²/2                       A = F Δt
//! Q = Q_c Δt + (A Q_c + (A Q_c)ᵀ) Δt/2   (= Q_c Δt + (F Q_c + Q_c Fᵀ) Δt²/2)
//! ```
//!
//! for an F and a Q_c whose rows from `LEAD` on hold only their diagonal
//! element (states that evolve on their own, such as Gauss–Markov
//! processes), with the nonzeros of the leading rows in a pattern fixed in
//! advance ([`SecondOrderPattern`]). Neither product is dense: each column
//! of the result sums over the rows its pattern lists only, and only the
//! leading rows, which is what makes such a model cheap at a filter's
//! covariance rate.

use std::ops::Range;

use nalgebra::SMatrix;

use crate::dense::{Widened, run_widest};

/// The sparsity of a square N × N matrix: for each column, the rows that
/// may hold a nonzero in it, increasing (the first `count` entries).
type ColumnRows<const N: usize> = [([usize; N], usize); N];

/// Where F and Q_c may hold nonzeros, for [`SecondOrderPattern::discretise`]:
/// rows from `LEAD` on hold only their diagonal in both; the leading rows
/// of F whatever the pattern lists, and Q_c is block diagonal over the
/// leading states (states in no block have no noise). Built at compile
/// time (`const`), so that a pattern that breaks these rules does not
/// build.
///
/// ```
/// use aidnav_estimation::SecondOrderPattern;
/// use nalgebra::{Matrix3, Vector3, matrix};
/// // x = (position, velocity, a first-order Gauss–Markov acceleration):
/// // the third row evolves on its own, velocity has noise of its own.
/// const PATTERN: SecondOrderPattern<3, 2> =
///     SecondOrderPattern::new([&[1], &[2], &[2]], &[1..2]);
/// let dt = 0.1;
/// let f = matrix![0.0, 1.0, 0.0; 0.0, 0.0, 1.0; 0.0, 0.0, -0.5];
/// let qc = Matrix3::from_diagonal(&Vector3::new(0.0, 1e-4, 2e-3));
/// let (mut phi, mut q) = (Matrix3::zeros(), Matrix3::zeros());
/// PATTERN.discretise(&(f * dt), &qc, dt, &mut phi, &mut q);
/// let a = f * dt;
/// assert!((phi - (Matrix3::identity() + a + a * a / 2.0)).norm() < 1e-15);
/// let fq = a * qc;
/// assert!((q - (qc * dt + (fq + fq.transpose()) * (dt / 2.0))).norm() < 1e-15);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SecondOrderPattern<const N: usize, const LEAD: usize> {
    /// For each column j, the rows k where F(k, j) may be nonzero: the
    /// terms of A²(·, j) = Σ_k A(·, k) A(k, j).
    transition: ColumnRows<N>,
    /// For each column j, the rows k0..k1 of Q_c's block that holds it:
    /// the terms of (A Q_c)(·, j) = Σ_k A(·, k) Q_c(k, j).
    noise: [(usize, usize); N],
}

impl<const N: usize, const LEAD: usize> SecondOrderPattern<N, LEAD> {
    /// The pattern of an F whose row i may hold a nonzero in the columns
    /// `f_row_columns[i]` (increasing) and of a symmetric Q_c made of the
    /// diagonal blocks `qc_blocks` (increasing, apart, within the leading
    /// states) and of its diagonal from LEAD on. Panics (at compile time in
    /// a `const`) when LEAD exceeds N, a list is not increasing or names a
    /// state beyond N, a row from LEAD on lists anything but its own
    /// diagonal, or a block overlaps another or reaches past LEAD.
    pub const fn new(f_row_columns: [&[usize]; N], qc_blocks: &[Range<usize>]) -> Self {
        assert!(LEAD <= N, "LEAD beyond the states");
        let mut transition = [([0; N], 0); N];
        let mut i = 0;
        while i < N {
            let row = f_row_columns[i];
            let mut k = 0;
            while k < row.len() {
                assert!(row[k] < N, "a column beyond the states");
                assert!(k == 0 || row[k - 1] < row[k], "columns not increasing");
                assert!(
                    i < LEAD || row[k] == i,
                    "a trailing row of F off its diagonal"
                );
                // Rows i increase in the outer loop: each column's list of
                // rows comes out increasing.
                let j = row[k];
                transition[j].0[transition[j].1] = i;
                transition[j].1 += 1;
                k += 1;
            }
            i += 1;
        }
        let mut noise = [(0, 0); N];
        let (mut b, mut end) = (0, 0);
        while b < qc_blocks.len() {
            let block = &qc_blocks[b];
            assert!(
                end <= block.start && block.start < block.end,
                "blocks not apart"
            );
            assert!(block.end <= LEAD, "a block past the leading states");
            let mut j = block.start;
            while j < block.end {
                noise[j] = (block.start, block.end);
                j += 1;
            }
            end = block.end;
            b += 1;
        }
        let mut j = LEAD;
        while j < N {
            noise[j] = (j, j + 1);
            j += 1;
        }
        Self { transition, noise }
    }

    /// Φ = I + A + A²/2 and Q = Q_c Δt + (A Q_c + (A Q_c)ᵀ) Δt/2 into `phi`
    /// and `q` (every element written), for `fdt` = A = F Δt and `qc` with
    /// this pattern (nonzeros elsewhere are not read), both finite, `qc`
    /// exactly symmetric.
    ///
    /// Each element of A²/2 is the sum over the listed k in increasing
    /// order of `0.5 · A(i, k) · A(k, j)`, added to `0 + A(i, j)` (`1 + A(i, i)`
    /// on the diagonal); each of A Q_c the sum of `A(i, k) · Q_c(k, j)`
    /// from +0: the terms a dense loop over every k adds beyond these are
    /// ±0 and change no such sum, so the results equal that loop's to the
    /// bit. Q is symmetric bit for bit. Every CPU gives the same bits (the
    /// sums run in this order whatever the vector width).
    pub fn discretise(
        &self,
        fdt: &SMatrix<f64, N, N>,
        qc: &SMatrix<f64, N, N>,
        dt: f64,
        phi: &mut SMatrix<f64, N, N>,
        q: &mut SMatrix<f64, N, N>,
    ) {
        let mut fq = SMatrix::<f64, N, N>::zeros();
        run_widest(
            Products::<N, LEAD> { pattern: self },
            phi.as_mut_slice(),
            fq.as_mut_slice(),
            fdt.as_slice(),
            qc.as_slice(),
        );
        run_widest(
            NoiseFormula::<N, LEAD> { dt },
            q.as_mut_slice(),
            &mut [],
            qc.as_slice(),
            fq.as_slice(),
        );
    }
}

/// The products of [`SecondOrderPattern::discretise`] on column-major
/// slices: `out` = Φ = I + A + A²/2, `scratch` = A Q_c (zeros on entry),
/// `a` = A, `b` = Q_c.
struct Products<'p, const N: usize, const LEAD: usize> {
    pattern: &'p SecondOrderPattern<N, LEAD>,
}

impl<const N: usize, const LEAD: usize> Widened for Products<'_, N, LEAD> {
    #[inline(always)]
    fn run(self, phi: &mut [f64], fq: &mut [f64], fdt: &[f64], qc: &[f64]) {
        // Column-major slices: element (i, j) at j N + i, the diagonal every
        // (N + 1)-th.
        let (phi, fq, f, c) = (
            &mut phi[..N * N],
            &mut fq[..N * N],
            &fdt[..N * N],
            &qc[..N * N],
        );
        // I + A (0 + a, as the identity's zeros add: −0 becomes +0).
        for (o, &a) in phi.iter_mut().zip(f) {
            *o = 0.0 + a;
        }
        for d in (0..N).map(|i| i * (N + 1)) {
            phi[d] = 1.0 + f[d];
        }
        // A²/2 over the leading rows of each column, the terms k in
        // increasing order, each a contiguous update.
        for (j, (rows, count)) in self.pattern.transition.iter().enumerate() {
            let out = &mut phi[j * N..j * N + LEAD];
            for &k in &rows[..*count] {
                let b = f[j * N + k];
                for (o, &a) in out.iter_mut().zip(&f[k * N..k * N + LEAD]) {
                    *o += 0.5 * a * b;
                }
            }
        }
        // The trailing rows of A (and so of A²) hold their diagonal only.
        for d in (LEAD..N).map(|i| i * (N + 1)) {
            let a = f[d];
            phi[d] += 0.5 * a * a;
        }
        // A Q_c likewise, over the rows of Q_c's block.
        for (j, &(k0, k1)) in self.pattern.noise.iter().enumerate() {
            let out = &mut fq[j * N..j * N + LEAD];
            for k in k0..k1 {
                let b = c[j * N + k];
                for (o, &a) in out.iter_mut().zip(&f[k * N..k * N + LEAD]) {
                    *o += a * b;
                }
            }
        }
        for d in (LEAD..N).map(|i| i * (N + 1)) {
            fq[d] += f[d] * c[d];
        }
    }
}

/// Q = Q_c Δt + (G + Gᵀ) Δt/2 element by element, on column-major slices:
/// `out` = Q, `a` = Q_c, `b` = G = A Q_c as [`Products`] leaves it. G's
/// rows from `LEAD` on are +0.0 off the diagonal (only the leading rows and
/// the diagonal are written), so in a column j from `LEAD` on the
/// transposed term G(j, i) is that +0.0 for every i but j: added as the
/// constant, the column is read down (contiguous, it vectorises) instead of
/// across, with the same operations on the same values. The leading columns
/// read Gᵀ across.
struct NoiseFormula<const N: usize, const LEAD: usize> {
    dt: f64,
}

impl<const N: usize, const LEAD: usize> Widened for NoiseFormula<N, LEAD> {
    #[inline(always)]
    fn run(self, q: &mut [f64], _: &mut [f64], qc: &[f64], fq: &[f64]) {
        let (e, c, g) = (&mut q[..N * N], &qc[..N * N], &fq[..N * N]);
        let (dt, half_dt) = (self.dt, 0.5 * self.dt);
        for j in 0..LEAD {
            for i in 0..N {
                e[j * N + i] = c[j * N + i] * dt + half_dt * (g[j * N + i] + g[i * N + j]);
            }
        }
        for j in LEAD..N {
            let column = j * N..(j + 1) * N;
            for ((o, &cv), &gv) in e[column.clone()]
                .iter_mut()
                .zip(&c[column.clone()])
                .zip(&g[column])
            {
                *o = cv * dt + half_dt * (gv + 0.0);
            }
            let d = j * (N + 1);
            e[d] = c[d] * dt + half_dt * (g[d] + g[d]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const N: usize = 7;
    const LEAD: usize = 4;
    const F_ROWS: [&[usize]; N] = [
        &[0, 1, 3],
        &[1, 2, 4, 5],
        &[0, 2, 3, 6],
        &[1, 3, 4, 5, 6],
        &[4],
        &[5],
        &[6],
    ];
    const QC_COLUMNS: [&[usize]; N] = [&[], &[1, 2], &[1, 2], &[3], &[4], &[5], &[6]];
    /// [`QC_COLUMNS`] as blocks (the diagonal from LEAD on is implied).
    const QC_BLOCKS: &[Range<usize>] = &[1..3, 3..4];
    const PATTERN: SecondOrderPattern<N, LEAD> = SecondOrderPattern::new(F_ROWS, QC_BLOCKS);

    /// A random value, an exact +0 or −0 a quarter of the time each.
    fn value(rng: &mut ChaCha8Rng) -> f64 {
        match rng.random_range(0..8) {
            0 | 1 => 0.0,
            2 | 3 => -0.0,
            _ => rng.random_range(-2.0..2.0),
        }
    }

    /// Φ and Q summed over every k, the terms in increasing k (the
    /// definition), against the pattern's sums, bit for bit; and Q's
    /// leading formula read across for every column.
    #[test]
    fn the_pattern_sums_equal_the_dense_sums_bitwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for case in 0..500 {
            let mut a = SMatrix::<f64, N, N>::zeros();
            for (i, row) in F_ROWS.iter().enumerate() {
                for &j in row.iter() {
                    a[(i, j)] = value(&mut rng);
                }
            }
            let mut qc = SMatrix::<f64, N, N>::zeros();
            for (j, column) in QC_COLUMNS.iter().enumerate() {
                for &k in column.iter().filter(|&&k| k <= j) {
                    qc[(k, j)] = value(&mut rng).abs();
                    qc[(j, k)] = qc[(k, j)];
                }
            }
            let dt = if case % 5 == 0 {
                -0.05
            } else {
                rng.random_range(1e-3..0.2)
            };
            // 0 + a off the diagonal, 1 + a on it.
            let mut phi_ref =
                SMatrix::<f64, N, N>::from_fn(|i, j| (if i == j { 1.0 } else { 0.0 }) + a[(i, j)]);
            let mut fq = SMatrix::<f64, N, N>::zeros();
            for j in 0..N {
                for i in 0..N {
                    for k in 0..N {
                        phi_ref[(i, j)] += 0.5 * a[(i, k)] * a[(k, j)];
                        fq[(i, j)] += a[(i, k)] * qc[(k, j)];
                    }
                }
            }
            let mut q_ref = SMatrix::<f64, N, N>::zeros();
            for j in 0..N {
                for i in 0..N {
                    q_ref[(i, j)] = qc[(i, j)] * dt + 0.5 * dt * (fq[(i, j)] + fq[(j, i)]);
                }
            }
            let (mut phi, mut q) = (
                SMatrix::<f64, N, N>::from_element(f64::NAN),
                SMatrix::<f64, N, N>::from_element(f64::NAN),
            );
            PATTERN.discretise(&a, &qc, dt, &mut phi, &mut q);
            let bits = |m: &SMatrix<f64, N, N>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&phi), bits(&phi_ref), "Φ, case {case}");
            assert_eq!(bits(&q), bits(&q_ref), "Q, case {case}");
        }
    }
}
