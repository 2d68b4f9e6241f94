//! Input and output checks shared by every step of the engine.

use nalgebra::{
    DefaultAllocator, Dim, IsContiguous, Matrix as NaMatrix, OMatrix, OVector, RawStorage,
    allocator::Allocator,
};

use crate::error::{EstimationError, Matrix, Result, Step};

/// Relative tolerance on |A − Aᵀ| for matrices that must be symmetric.
/// Inputs written by hand with 15 significant digits pass; a transposed
/// off-diagonal block does not.
pub(crate) const SYMMETRY_RTOL: f64 = 1e-9;

/// Error unless every element is finite.
///
/// One branch-free reduction over the whole matrix ([`all_finite`]): a
/// short-circuiting `all(is_finite)` costs about as much as the 15×15
/// product it guards.
pub(crate) fn finite<R: Dim, C: Dim, S: RawStorage<f64, R, C> + IsContiguous>(
    m: &NaMatrix<f64, R, C, S>,
    step: Step,
    matrix: Matrix,
) -> Result<()> {
    if all_finite(m.as_slice()) {
        Ok(())
    } else {
        Err(EstimationError::NonFinite { step, matrix })
    }
}

/// Independent partial sums in [`all_finite`]: enough to hide the add
/// latency, and a multiple of every vector width (2, 4 or 8 lanes).
const FINITE_LANES: usize = 8;

/// True when every value is finite: Σ v·0 is (±)0 when every v is finite and
/// NaN as soon as one is ±∞ or NaN (∞·0 = NaN, and a NaN survives every
/// later addition). A multiply and an add per element, over
/// eight partial sums the compiler keeps in vector registers (no
/// reassociation needed, so it vectorises without fast-math), and no branch
/// until the end. (The batch's fused AVX2 kernels test the exponent bits
/// instead, with the same answer.)
///
/// ```
/// use aidnav_estimation::all_finite;
/// assert!(all_finite(&[1.0, -2.5e300, 0.0]));
/// assert!(!all_finite(&[1.0, f64::INFINITY]));
/// assert!(!all_finite(&[f64::NAN; 9]));
/// ```
#[inline]
pub fn all_finite(values: &[f64]) -> bool {
    let mut partial = [0.0_f64; FINITE_LANES];
    let chunks = values.chunks_exact(FINITE_LANES);
    let rest = chunks.remainder();
    for chunk in chunks {
        for (s, &v) in partial.iter_mut().zip(chunk) {
            *s += v * 0.0;
        }
    }
    let mut sum = rest.iter().fold(0.0, |s, &v| s + v * 0.0);
    for s in partial {
        sum += s;
    }
    sum == 0.0
}

/// [`all_finite`] by the exponent bits, for the AVX2 builds of the batch's
/// fused kernels (`crate::dense::accepted_update`,
/// `crate::dense::predicted_aside`): a value is ±∞ or NaN exactly when its
/// exponent field is all ones, and adding one to the exponent field then
/// carries into the top bit, so the OR of `(bits & exponent) + one` over
/// the values has its top bit set exactly when one is not finite — the
/// same answer as the sum of v·0. An OR of integers may be regrouped, so
/// the compiler vectorises it four lanes wide over a fixed-size matrix
/// (three instructions per four values); the partial sums of v·0 came out
/// in two-lane vectors there (two per two: 81 values of a 9-state P,
/// about 100 instructions against 65).
#[inline(always)]
pub(crate) fn all_finite_by_exponent(values: &[f64]) -> bool {
    const EXPONENT: u64 = 0x7ff0_0000_0000_0000;
    const EXPONENT_ONE: u64 = 0x0010_0000_0000_0000;
    let mut carried = 0_u64;
    for &v in values {
        carried |= (v.to_bits() & EXPONENT) + EXPONENT_ONE;
    }
    carried >> 63 == 0
}

/// Error unless the shape is `rows × cols` (only ever fails for run-time sizes).
pub(crate) fn shape<R: Dim, C: Dim, S: RawStorage<f64, R, C>>(
    m: &NaMatrix<f64, R, C, S>,
    expected: (usize, usize),
    step: Step,
    matrix: Matrix,
) -> Result<()> {
    let (rows, cols) = m.shape();
    if (rows, cols) == expected {
        Ok(())
    } else {
        Err(EstimationError::DimensionMismatch {
            step,
            matrix,
            rows,
            cols,
            expected_rows: expected.0,
            expected_cols: expected.1,
        })
    }
}

/// A measurement's z, H and R.
type MeasurementRef<'a, M, N> = (
    &'a OVector<f64, M>,
    &'a OMatrix<f64, M, N>,
    &'a OMatrix<f64, M, M>,
);

/// Error unless a measurement of m = z.len() components on n states is
/// well formed: H m × n and R m × m, then z, H and R finite, checked in
/// that order (the error names the first that fails). Returns m.
pub(crate) fn measurement<M: Dim, N: Dim>(
    (z, h, r): MeasurementRef<'_, M, N>,
    n: usize,
    step: Step,
) -> Result<usize>
where
    DefaultAllocator: Allocator<M> + Allocator<M, N> + Allocator<M, M>,
{
    let m = z.len();
    shape(h, (m, n), step, Matrix::H)?;
    shape(r, (m, m), step, Matrix::R)?;
    finite(z, step, Matrix::Z)?;
    finite(h, step, Matrix::H)?;
    finite(r, step, Matrix::R)?;
    Ok(m)
}

/// Error unless the square matrix is symmetric to [`SYMMETRY_RTOL`] of its
/// largest element; `Ok(true)` when it is exactly symmetric (the common case,
/// tested first by a branch-free comparison that vectorises; only an inexact
/// matrix pays for the largest asymmetry and the scale).
pub(crate) fn symmetric<D: Dim, S: RawStorage<f64, D, D>>(
    m: &NaMatrix<f64, D, D, S>,
    step: Step,
    matrix: Matrix,
) -> Result<bool> {
    let n = m.nrows();
    let mut exact = true;
    for j in 0..n {
        for i in (j + 1)..n {
            exact &= m[(i, j)] == m[(j, i)];
        }
    }
    if exact {
        return Ok(true);
    }
    let mut worst = 0.0_f64;
    for j in 0..n {
        for i in (j + 1)..n {
            worst = worst.max((m[(i, j)] - m[(j, i)]).abs());
        }
    }
    if worst == 0.0 {
        return Ok(true);
    }
    let scale = m.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    if worst <= SYMMETRY_RTOL * scale.max(f64::MIN_POSITIVE) {
        Ok(false)
    } else {
        Err(EstimationError::NotSymmetric {
            step,
            matrix,
            asymmetry: worst,
        })
    }
}

/// Whether every element of the square n × n matrix stored column-major in
/// `m` has its mirror's bits or equals it (`==`: ±0): exactly symmetric,
/// a NaN counted equal to a NaN of the same bits (the callers check
/// finiteness on every path). The bits first ([`crate::dense::symmetric_bits`],
/// three instructions a pair, against about seven for the `==`
/// comparison, which only a matrix with a +0/−0 pair or an asymmetry
/// reaches). Inlined, so that a compile-time n unrolls the loops and drops
/// the bounds checks (an iterator that skips to the diagonal cost 14
/// instructions a pair).
#[inline(always)]
fn exactly_symmetric(m: &[f64], n: usize) -> bool {
    if crate::dense::symmetric_bits(m, n) {
        return true;
    }
    let m = &m[..n * n];
    let mut exact = true;
    for j in 0..n {
        for i in j + 1..n {
            exact &= m[j * n + i] == m[i * n + j];
        }
    }
    exact
}

/// Replace `m` by `(m + mᵀ)/2` in place, without allocating.
pub(crate) fn symmetrize<D: Dim>(m: &mut OMatrix<f64, D, D>)
where
    DefaultAllocator: Allocator<D, D>,
{
    let n = m.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let v = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
}

/// Q as a time update adds it: checked (n × n, finite, symmetric to
/// [`SYMMETRY_RTOL`]), then `(Q + Qᵀ)/2` unless exactly symmetric.
pub(crate) fn process_noise<N: Dim>(q: &OMatrix<f64, N, N>, n: usize) -> Result<OMatrix<f64, N, N>>
where
    DefaultAllocator: Allocator<N, N>,
{
    Ok(match process_noise_unless_exact(q, n)? {
        Some(symmetrized) => symmetrized,
        None => {
            finite(q, Step::Predict, Matrix::Q)?;
            q.clone()
        }
    })
}

/// [`process_noise`] without the copy of an exactly symmetric Q (the
/// common case), which the caller adds as it is: `Ok(None)` then, after
/// the shape check only. Its finiteness is left to the caller, who checks
/// it ([`finite`], `Matrix::Q`) when the propagated P is not finite, before
/// reporting P: every element of a non-finite Q reaches P (a value off the
/// diagonal of an exactly symmetric Q is also its mirror, and ±∞ or NaN
/// plus anything is not finite), so the same error comes out as from
/// checking Q first.
/// Any other Q is checked and symmetrised as by [`process_noise`]
/// (`Ok(Some((Q + Qᵀ)/2))`).
pub(crate) fn process_noise_unless_exact<N: Dim>(
    q: &OMatrix<f64, N, N>,
    n: usize,
) -> Result<Option<OMatrix<f64, N, N>>>
where
    DefaultAllocator: Allocator<N, N>,
{
    let step = Step::Predict;
    shape(q, (n, n), step, Matrix::Q)?;
    // The common case, an exactly symmetric Q, tested on the contiguous
    // storage first (what `symmetric` finds first, without its indexing).
    let (nd, _) = q.shape_generic();
    if exactly_symmetric(q.as_slice(), nd.value()) {
        return Ok(None);
    }
    finite(q, step, Matrix::Q)?;
    let exact = symmetric(q, step, Matrix::Q)?;
    let mut base = q.clone();
    if !exact {
        symmetrize(&mut base);
    }
    Ok(Some(base))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exponent test answers as the sum of v·0 on every kind of value
    /// (zeros of both signs, subnormals, the largest finite values, the
    /// infinities, NaN of several payloads), alone and among finite values
    /// at every position of runs of several lengths.
    #[test]
    fn the_exponent_test_is_the_finiteness_test() {
        let specials = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE / 4.0,
            -f64::MIN_POSITIVE / 4.0,
            f64::MAX,
            f64::MIN,
            1.5,
            -2.0e-300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
            f64::from_bits(0x7ff0_0000_0000_0001),
            f64::from_bits(0xfff8_dead_beef_0000),
        ];
        for &v in &specials {
            assert_eq!(all_finite_by_exponent(&[v]), all_finite(&[v]), "{v:e}");
        }
        for len in [1, 3, 8, 9, 27, 81] {
            for at in 0..len {
                for &v in &specials {
                    let mut values = vec![0.25; len];
                    values[at] = v;
                    assert_eq!(
                        all_finite_by_exponent(&values),
                        all_finite(&values),
                        "{v:e} at {at} of {len}"
                    );
                }
            }
        }
        assert!(all_finite_by_exponent(&[]));
    }

    /// The bitwise test first, then `==`: the same answer as the pairwise
    /// comparison, but for a NaN pair of equal bits (counted symmetric;
    /// every caller checks finiteness).
    #[test]
    fn exact_symmetry_is_the_pairwise_comparison_or_equal_bits() {
        let n = 5;
        let base: Vec<f64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k % n, k / n);
                (i.min(j) * 7 + i.max(j)) as f64 * 0.25 - 1.0
            })
            .collect();
        let compare = |m: &[f64]| (0..n).all(|j| (j + 1..n).all(|i| m[j * n + i] == m[i * n + j]));
        assert!(exactly_symmetric(&base, n));
        let mut signed = base.clone();
        (signed[n + 3], signed[3 * n + 1]) = (0.0, -0.0);
        assert!(compare(&signed) && exactly_symmetric(&signed, n));
        let mut skewed = base.clone();
        skewed[2 * n + 4] = f64::from_bits(skewed[2 * n + 4].to_bits() + 1);
        assert!(!compare(&skewed) && !exactly_symmetric(&skewed, n));
        let mut nan = base.clone();
        (nan[1], nan[n]) = (f64::NAN, f64::NAN);
        assert!(exactly_symmetric(&nan, n));
        nan[n] = -f64::NAN;
        assert!(!exactly_symmetric(&nan, n));
    }

    #[test]
    fn all_finite_finds_every_non_finite_value_wherever_it_is() {
        for len in [0_usize, 1, 7, 8, 9, 36, 225, 441] {
            let values: Vec<f64> = (0..len).map(|i| (i as f64 - 3.5) * 1e300).collect();
            assert!(all_finite(&values), "len {len}");
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                for at in [0, len / 2, len.saturating_sub(1)] {
                    if len == 0 {
                        continue;
                    }
                    let mut v = values.clone();
                    v[at] = bad;
                    assert!(!all_finite(&v), "len {len}, {bad} at {at}");
                }
            }
        }
        // Extremes that are finite: the largest, the smallest subnormal, −0.
        assert!(all_finite(&[f64::MAX, -f64::MAX, 5e-324, -0.0, 0.0]));
    }
}
