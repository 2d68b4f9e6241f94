//! Small dense products for the filter's hot path.
//!
//! nalgebra multiplies statically sized matrices column by column through a
//! generic gemv; at the 15–21 state sizes of navigation filters that runs at
//! about half the speed of a plain axpy kernel whose sizes the compiler sees
//! as constants (measured: 21×21·21×21 twice, 5.9 µs vs 2.7 µs). The kernel
//! here is that plain loop, over the column-major slices nalgebra stores: the
//! whole output column stays in registers while the inner index runs (for
//! fixed sizes), each output element accumulated in the plain order
//! `β·out + α a₀b₀ + α a₁b₁ + …` with a separate multiply and add (Rust never
//! contracts to FMA), so the result does not depend on the CPU.
//!
//! Two structural savings, both exact:
//! - [`gemm_nt_lower`] computes only the lower triangle (plus the upper part of
//!   column blocks) of a product known to be symmetric; [`mirror_lower`]
//!   copies it up. Φ P Φᵀ and the Joseph update's rank-2m term cost 37 % less.
//! - [`nonzero_columns`] lists the columns of a measurement matrix that are not
//!   identically zero; products with H then run over those only. A navigation
//!   filter's H touches 3–6 of 15–21 states, so H P costs a third or less. The
//!   skipped terms are exact zeros (P is finite), so the result is the dense one.
//!
//! For run-time sized matrices beyond [`SMALL_DYN`] they hand over to
//! nalgebra, whose `matrixmultiply` backend wins there.

use nalgebra::{DefaultAllocator, Dim, OMatrix, allocator::Allocator};

/// Largest run-time dimension handled by the kernels; larger `Dyn` products
/// go to nalgebra (packed, cache-blocked `matrixmultiply`).
const SMALL_DYN: usize = 32;

/// Capacity of a [`nonzero_columns`] list (larger matrices use every column).
pub(crate) const MAX_LISTED: usize = 64;

/// Whether the small kernels here handle an r × k by k × c product (every
/// size known at compile time, or none above [`SMALL_DYN`]); nalgebra's
/// packed product otherwise.
pub(crate) fn use_kernel<R: Dim, K: Dim, C: Dim>(r: usize, k: usize, c: usize) -> bool {
    let all_static =
        R::try_to_usize().is_some() && K::try_to_usize().is_some() && C::try_to_usize().is_some();
    all_static || r.max(k).max(c) <= SMALL_DYN
}

/// Columns `cols` of `out = α · a · B + β · out`, rows `row0..r`, for
/// column-major a (r × k) and out (r × c), where `b(kk, j)` reads element
/// (kk, j) of B: B itself, or a transpose. Axpy form: each output column
/// accumulates scaled columns of a over the inner indices `inner`, in their
/// order. When r − row0 is a compile-time constant (fixed-size matrices) the
/// compiler keeps the whole output column in registers while the inner index
/// runs: one load of a's column and one broadcast per column element pair.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn columns<I: Iterator<Item = usize> + Clone>(
    r: usize,
    (row0, cols): (usize, std::ops::Range<usize>),
    inner: &I,
    alpha: f64,
    a: &[f64],
    b: &impl Fn(usize, usize) -> f64,
    beta: f64,
    out: &mut [f64],
) {
    let len = r - row0;
    for j in cols {
        let oc = &mut out[j * r + row0..][..len];
        if beta == 0.0 {
            oc.fill(0.0);
        } else if beta != 1.0 {
            oc.iter_mut().for_each(|v| *v *= beta);
        }
        for kk in inner.clone() {
            let s = alpha * b(kk, j);
            let ac = &a[kk * r + row0..][..len];
            for (o, &x) in oc.iter_mut().zip(ac) {
                *o += x * s;
            }
        }
    }
}

/// out = α · a · B + β · out (see [`columns`]); with `lower`, a square out's
/// lower triangle only, in [`LOWER_BLOCKS`] column blocks that each start at
/// an even row at or above their first column (so a block's row count is a
/// constant for fixed sizes, and vectors stay aligned to pairs): 37 % of the
/// full product's work saved at 4 blocks instead of 50 % for an exact
/// triangle, without variable-length loops.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn kernel<I: Iterator<Item = usize> + Clone>(
    (r, c): (usize, usize),
    inner: I,
    alpha: f64,
    a: &[f64],
    b: impl Fn(usize, usize) -> f64,
    beta: f64,
    out: &mut [f64],
    lower: bool,
) {
    if !lower {
        columns(r, (0, 0..c), &inner, alpha, a, &b, beta, out);
        return;
    }
    let (s1, s2, s3) = lower_block_starts(r);
    // Four calls, not a loop or a closure: each inlines with its own
    // constant row count (fixed sizes), which keeps the columns in registers.
    columns(r, (0, 0..s1), &inner, alpha, a, &b, beta, out);
    columns(r, (s1, s1..s2), &inner, alpha, a, &b, beta, out);
    columns(r, (s2, s2..s3), &inner, alpha, a, &b, beta, out);
    columns(r, (s3, s3..r), &inner, alpha, a, &b, beta, out);
}

/// First columns (and rows) of blocks 1–3 of the [`LOWER_BLOCKS`] column
/// blocks that cover the lower triangle of an r × r matrix, each starting at
/// an even row at or above its first column (see [`kernel`]).
#[inline(always)]
fn lower_block_starts(r: usize) -> (usize, usize, usize) {
    let start = |b: usize| (b * r / LOWER_BLOCKS) & !1;
    (start(1), start(2), start(3))
}

/// Column blocks of a lower-triangle product (the four calls in [`kernel`]).
const LOWER_BLOCKS: usize = 4;

/// `out = α a b + β out`.
#[inline]
pub(crate) fn gemm<R: Dim, K: Dim, C: Dim>(
    out: &mut OMatrix<f64, R, C>,
    alpha: f64,
    a: &OMatrix<f64, R, K>,
    b: &OMatrix<f64, K, C>,
    beta: f64,
) where
    DefaultAllocator: Allocator<R, C> + Allocator<R, K> + Allocator<K, C>,
{
    let (r, k, c) = (a.nrows(), a.ncols(), b.ncols());
    if use_kernel::<R, K, C>(r, k, c) {
        let b = b.as_slice();
        let read = |kk: usize, j: usize| b[j * k + kk];
        kernel(
            (r, c),
            0..k,
            alpha,
            a.as_slice(),
            read,
            beta,
            out.as_mut_slice(),
            false,
        );
    } else {
        out.gemm(alpha, a, b, beta);
    }
}

/// `out = α a bᵀ + β out`.
#[inline]
pub(crate) fn gemm_nt<R: Dim, K: Dim, C: Dim>(
    out: &mut OMatrix<f64, R, C>,
    alpha: f64,
    a: &OMatrix<f64, R, K>,
    b: &OMatrix<f64, C, K>,
    beta: f64,
) where
    DefaultAllocator: Allocator<R, C> + Allocator<R, K> + Allocator<C, K> + Allocator<K, C>,
{
    let (r, k, c) = (a.nrows(), a.ncols(), b.nrows());
    if use_kernel::<R, K, C>(r, k, c) {
        let b = b.as_slice();
        let read = |kk: usize, j: usize| b[kk * c + j];
        kernel(
            (r, c),
            0..k,
            alpha,
            a.as_slice(),
            read,
            beta,
            out.as_mut_slice(),
            false,
        );
    } else {
        out.gemm(alpha, a, &b.transpose(), beta);
    }
}

/// The lower triangle of `out = α a bᵀ + β out` for a square `out` (the
/// elements above the diagonal are left unspecified: follow with
/// [`mirror_lower`]). For products known to be symmetric.
#[inline]
pub(crate) fn gemm_nt_lower<D: Dim, K: Dim>(
    out: &mut OMatrix<f64, D, D>,
    alpha: f64,
    a: &OMatrix<f64, D, K>,
    b: &OMatrix<f64, D, K>,
    beta: f64,
) where
    DefaultAllocator: Allocator<D, D> + Allocator<D, K> + Allocator<K, D>,
{
    let (r, k) = (a.nrows(), a.ncols());
    if use_kernel::<D, K, D>(r, k, r) {
        let b = b.as_slice();
        let read = |kk: usize, j: usize| b[kk * r + j];
        kernel(
            (r, r),
            0..k,
            alpha,
            a.as_slice(),
            read,
            beta,
            out.as_mut_slice(),
            true,
        );
    } else {
        out.gemm(alpha, a, &b.transpose(), beta);
    }
}

/// The columns of `h` (m × n) that hold a nonzero element, in order, written
/// into `list`; `None` when every column does or when n exceeds
/// [`MAX_LISTED`] (then the dense products are the right ones).
pub(crate) fn nonzero_columns<'l, M: Dim, N: Dim>(
    h: &OMatrix<f64, M, N>,
    list: &'l mut [usize; MAX_LISTED],
) -> Option<&'l [usize]>
where
    DefaultAllocator: Allocator<M, N>,
{
    let (m, n) = h.shape();
    if n > MAX_LISTED {
        return None;
    }
    let values = h.as_slice();
    let mut count = 0;
    for j in 0..n {
        if values[j * m..(j + 1) * m].iter().any(|&v| v != 0.0) {
            list[count] = j;
            count += 1;
        }
    }
    (count < n).then_some(&list[..count])
}

/// `out = h p` (m × n) for a symmetric `p` (n × n), summing over the columns
/// of h in `columns` (all when `None`): the terms left out are exact zeros.
pub(crate) fn h_times_symmetric<M: Dim, N: Dim>(
    out: &mut OMatrix<f64, M, N>,
    h: &OMatrix<f64, M, N>,
    p: &OMatrix<f64, N, N>,
    columns: Option<&[usize]>,
) where
    DefaultAllocator: Allocator<M, N> + Allocator<N, N>,
{
    match columns {
        None => gemm(out, 1.0, h, p, 0.0),
        Some(list) => {
            let (m, n) = h.shape();
            // p is symmetric: p(kk, j) = p(j, kk), the contiguous read.
            let ps = p.as_slice();
            let read = |kk: usize, j: usize| ps[kk * n + j];
            let inner = list.iter().copied();
            kernel(
                (m, n),
                inner,
                1.0,
                h.as_slice(),
                read,
                0.0,
                out.as_mut_slice(),
                false,
            );
        }
    }
}

/// `out = u hᵀ` (m × m) for u = H P (m × n), summing over the columns of h in
/// `columns` (all when `None`).
pub(crate) fn times_h_transpose<M: Dim, N: Dim>(
    out: &mut OMatrix<f64, M, M>,
    u: &OMatrix<f64, M, N>,
    h: &OMatrix<f64, M, N>,
    columns: Option<&[usize]>,
) where
    DefaultAllocator: Allocator<M, N> + Allocator<M, M> + Allocator<N, M>,
{
    match columns {
        None => gemm_nt(out, 1.0, u, h, 0.0),
        Some(list) => {
            let m = u.nrows();
            let hs = h.as_slice();
            let read = |kk: usize, j: usize| hs[kk * m + j];
            let inner = list.iter().copied();
            kernel(
                (m, m),
                inner,
                1.0,
                u.as_slice(),
                read,
                0.0,
                out.as_mut_slice(),
                false,
            );
        }
    }
}

/// The lower triangle of `out += v kᵀ + k vᵀ` for a square `out` (the
/// Joseph update's symmetric rank-2m term; the elements above the diagonal
/// are left unspecified: follow with [`mirror_lower`]). One pass over out:
/// each element gets `Σ v(i, l) k(j, l)` then `Σ k(i, l) v(j, l)` in
/// increasing l, the operations and order of two [`gemm_nt_lower`] calls,
/// so the result is theirs bit for bit at half the loads and stores of out.
pub(crate) fn add_rank_2k_lower<D: Dim, K: Dim>(
    out: &mut OMatrix<f64, D, D>,
    v: &OMatrix<f64, D, K>,
    k: &OMatrix<f64, D, K>,
) where
    DefaultAllocator: Allocator<D, D> + Allocator<D, K> + Allocator<K, D>,
{
    let (n, m) = v.shape();
    if !use_kernel::<D, K, D>(n, m, n) {
        gemm_nt_lower(out, 1.0, v, k, 1.0);
        gemm_nt_lower(out, 1.0, k, v, 1.0);
        return;
    }
    let (vs, ks) = (v.as_slice(), k.as_slice());
    let os = out.as_mut_slice();
    let (s1, s2, s3) = lower_block_starts(n);
    rank_2k_columns(n, m, (0, 0..s1), vs, ks, os);
    rank_2k_columns(n, m, (s1, s1..s2), vs, ks, os);
    rank_2k_columns(n, m, (s2, s2..s3), vs, ks, os);
    rank_2k_columns(n, m, (s3, s3..n), vs, ks, os);
}

/// Columns `cols`, rows `row0..n`, of [`add_rank_2k_lower`] (the column of
/// out stays in registers for fixed sizes, as in [`columns`]).
#[inline(always)]
fn rank_2k_columns(
    n: usize,
    m: usize,
    (row0, cols): (usize, std::ops::Range<usize>),
    vs: &[f64],
    ks: &[f64],
    os: &mut [f64],
) {
    let len = n - row0;
    for j in cols {
        let oc = &mut os[j * n + row0..][..len];
        // With AVX-512 (-C target-cpu=native on Zen 4) the compiler
        // otherwise vectorises across the columns j, with gathers and
        // scatters: the update ran 1.6× slower than the portable build. An
        // opaque column reference stops that; the column itself still stays
        // in registers. (The portable build is better without it.)
        #[cfg(target_feature = "avx512f")]
        let oc = std::hint::black_box(oc);
        // (Two plain loops: a loop over the pair of operands stops the
        // compiler from keeping the column in registers.)
        for l in 0..m {
            let s = ks[l * n + j];
            let ac = &vs[l * n + row0..][..len];
            for (o, &x) in oc.iter_mut().zip(ac) {
                *o += x * s;
            }
        }
        for l in 0..m {
            let s = vs[l * n + j];
            let ac = &ks[l * n + row0..][..len];
            for (o, &x) in oc.iter_mut().zip(ac) {
                *o += x * s;
            }
        }
    }
}

/// `out = p hᵀ` (n × m) for a symmetric `p` (n × n) and h (m × n): column i
/// of out sums the columns k of p weighted by h(i, k), over the nonzero
/// h(i, k) only (a navigation filter's H selects a few states), in
/// increasing k from 0. The transpose of [`h_times_symmetric`]'s H P bit for
/// bit: each product is the same, and a left-out term is an exact zero
/// added to a sum that started at +0 and so is never −0, which leaves it
/// unchanged (p is finite).
pub(crate) fn symmetric_times_h_transpose<M: Dim, N: Dim>(
    out: &mut OMatrix<f64, N, M>,
    p: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, M, N>,
) where
    DefaultAllocator: Allocator<M, N> + Allocator<N, N> + Allocator<N, M>,
{
    let (m, n) = h.shape();
    let (hs, ps) = (h.as_slice(), p.as_slice());
    let os = out.as_mut_slice();
    for i in 0..m {
        let oc = &mut os[i * n..][..n];
        oc.fill(0.0);
        for k in 0..n {
            let hv = hs[k * m + i];
            if hv != 0.0 {
                let pc = &ps[k * n..][..n];
                for (o, &x) in oc.iter_mut().zip(pc) {
                    *o += hv * x;
                }
            }
        }
    }
}

/// `out(i, j) = Σ_k w(k, i) h(j, k)` (m × m) for w = P Hᵀ (n × m), over the
/// nonzero h(j, k) in increasing k: H P Hᵀ, bit for bit what
/// [`times_h_transpose`] gives from H P (see [`symmetric_times_h_transpose`]).
pub(crate) fn h_times_cross<M: Dim, N: Dim>(
    out: &mut OMatrix<f64, M, M>,
    h: &OMatrix<f64, M, N>,
    w: &OMatrix<f64, N, M>,
) where
    DefaultAllocator: Allocator<M, N> + Allocator<N, M> + Allocator<M, M>,
{
    let (m, n) = h.shape();
    let (hs, ws) = (h.as_slice(), w.as_slice());
    let os = out.as_mut_slice();
    for j in 0..m {
        let oc = &mut os[j * m..][..m];
        oc.fill(0.0);
        for k in 0..n {
            let hv = hs[k * m + j];
            if hv != 0.0 {
                for (i, o) in oc.iter_mut().enumerate() {
                    *o += ws[i * n + k] * hv;
                }
            }
        }
    }
}

/// Largest measurement count for [`solve_gain_in_place`]: nalgebra's dot
/// product sums fewer than 8 terms in plain order, which the substitution
/// here reproduces (it switches to 8 interleaved partial sums beyond).
pub(crate) const MAX_GAIN_SOLVE: usize = 8;

/// Rows per block of the back substitution's partial sums.
const SOLVE_BLOCK: usize = 8;

/// The gain K = W C⁻¹ (n × m) in place of W = P Hᵀ, from the Cholesky
/// factor `l` of C (its lower triangle; m × m, m ≤ [`MAX_GAIN_SOLVE`]): Kᵀ
/// solves C Kᵀ = Wᵀ, by forward then back substitution on the columns of W
/// (contiguous, so each step is a vectorised axpy over the n states instead
/// of n separate m-long solves). Per element the operations and their order
/// are those of nalgebra's `Cholesky::solve` applied to H P column by
/// column (divide by L(i, i), subtract L(r, i)·y; then the dot product from
/// +0 in increasing r, subtracted, divided), so the gain is the same bit for
/// bit.
pub(crate) fn solve_gain_in_place<N: Dim, M: Dim>(
    w: &mut OMatrix<f64, N, M>,
    l: &OMatrix<f64, M, M>,
) where
    DefaultAllocator: Allocator<N, M> + Allocator<M, M>,
{
    let (n, m) = w.shape();
    debug_assert!(m <= MAX_GAIN_SOLVE);
    let ls = l.as_slice();
    let ws = w.as_mut_slice();
    // Forward: L Y = W ᵀ, one column of Yᵀ (a row of Y) at a time.
    for i in 0..m {
        let d = ls[i * m + i];
        let (head, tail) = ws.split_at_mut((i + 1) * n);
        let yi = &mut head[i * n..];
        for y in yi.iter_mut() {
            *y /= d;
        }
        for r in (i + 1)..m {
            let lri = ls[i * m + r];
            let yr = &mut tail[(r - i - 1) * n..][..n];
            for (o, &y) in yr.iter_mut().zip(yi.iter()) {
                *o -= y * lri;
            }
        }
    }
    // Back: Lᵀ Kᵀ = Yᵀ, last column first.
    for i in (0..m).rev() {
        let d = ls[i * m + i];
        let (head, tail) = ws.split_at_mut((i + 1) * n);
        let ki = &mut head[i * n..];
        for (c0, chunk) in ki.chunks_mut(SOLVE_BLOCK).enumerate() {
            let c0 = c0 * SOLVE_BLOCK;
            let len = chunk.len();
            let mut dot = [0.0_f64; SOLVE_BLOCK];
            for r in (i + 1)..m {
                let lri = ls[i * m + r];
                let kr = &tail[(r - i - 1) * n + c0..][..len];
                for (s, &x) in dot.iter_mut().zip(kr) {
                    *s += lri * x;
                }
            }
            for (k, &s) in chunk.iter_mut().zip(&dot) {
                *k = (*k - s) / d;
            }
        }
    }
}

/// Copy the lower triangle of a square matrix onto the upper one.
pub(crate) fn mirror_lower<D: Dim>(m: &mut OMatrix<f64, D, D>)
where
    DefaultAllocator: Allocator<D, D>,
{
    let n = m.nrows();
    let s = m.as_mut_slice();
    for j in 1..n {
        for i in 0..j {
            s[j * n + i] = s[i * n + j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, SMatrix};

    #[test]
    fn kernels_match_nalgebra() {
        let a = SMatrix::<f64, 5, 3>::from_fn(|i, j| (i * 3 + j) as f64 - 4.0);
        let b = SMatrix::<f64, 3, 4>::from_fn(|i, j| (i + 2 * j) as f64 * 0.5);
        let bt = b.transpose();
        let mut out = SMatrix::<f64, 5, 4>::from_element(1.0);
        gemm(&mut out, 2.0, &a, &b, 3.0);
        assert_eq!(out, a * b * 2.0 + SMatrix::<f64, 5, 4>::from_element(3.0));
        let mut out2 = SMatrix::<f64, 5, 4>::zeros();
        gemm_nt(&mut out2, -1.0, &a, &bt, 0.0);
        assert_eq!(out2, -(a * b));
        // Large run-time sizes take nalgebra's path and agree.
        let a = DMatrix::from_fn(40, 35, |i, j| ((i * 7 + j) % 13) as f64);
        let b = DMatrix::from_fn(35, 33, |i, j| ((i + 5 * j) % 11) as f64);
        let mut out = DMatrix::zeros(40, 33);
        gemm(&mut out, 1.0, &a, &b, 0.0);
        assert_eq!(out, &a * &b);
        let mut out = DMatrix::zeros(40, 33);
        gemm_nt(&mut out, 1.0, &a, &b.transpose(), 0.0);
        assert_eq!(out, &a * &b);
    }

    /// Every small shape against nalgebra, integer-valued so the sums are
    /// exact whatever the order.
    #[test]
    fn every_tile_shape_matches_nalgebra() {
        for r in 1..=11 {
            for c in 1..=9 {
                let a = DMatrix::from_fn(r, 5, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
                let b = DMatrix::from_fn(5, c, |i, j| ((i * 5 + j * 2) % 7) as f64 - 3.0);
                let base = DMatrix::from_fn(r, c, |i, j| (i + j) as f64);
                let mut out = base.clone();
                gemm(&mut out, -2.0, &a, &b, 0.5);
                assert_eq!(out, &a * &b * -2.0 + &base * 0.5, "{r}×{c}");
            }
        }
    }

    #[test]
    fn lower_triangle_and_mirror_give_the_symmetric_product() {
        for n in [1, 2, 3, 4, 5, 7, 8, 15, 21, 33] {
            let a = DMatrix::from_fn(n, 6, |i, j| ((i * 7 + j * 3) % 11) as f64 - 5.0);
            let q = DMatrix::from_fn(n, n, |i, j| (i.min(j) + 2 * i.max(j)) as f64);
            let mut out = q.clone();
            gemm_nt_lower(&mut out, 1.0, &a, &a, 1.0);
            mirror_lower(&mut out);
            assert_eq!(out, &a * a.transpose() + &q, "n = {n}");
        }
    }

    #[test]
    fn sparse_measurement_products_equal_the_dense_ones() {
        let p = SMatrix::<f64, 9, 9>::from_fn(|i, j| (i.min(j) * 3 + i.max(j)) as f64 - 7.0);
        let mut h = SMatrix::<f64, 3, 9>::zeros();
        h[(0, 2)] = 1.0;
        h[(1, 5)] = 2.0;
        h[(2, 5)] = -1.5;
        h[(2, 8)] = 0.5;
        let mut list = [0; MAX_LISTED];
        let columns = nonzero_columns(&h, &mut list);
        assert_eq!(columns, Some(&[2, 5, 8][..]));
        let mut u = SMatrix::<f64, 3, 9>::zeros();
        h_times_symmetric(&mut u, &h, &p, columns);
        assert_eq!(u, h * p);
        let mut hph = SMatrix::<f64, 3, 3>::zeros();
        times_h_transpose(&mut hph, &u, &h, columns);
        assert_eq!(hph, h * p * h.transpose());
        let dense = SMatrix::<f64, 2, 3>::from_element(1.0);
        assert_eq!(nonzero_columns(&dense, &mut list), None);
    }

    /// A symmetric, non-integer matrix (so that the order of the sums
    /// matters and exact equality below is a real test of it).
    fn symmetric_test_matrix(n: usize) -> DMatrix<f64> {
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 13) % 17) as f64 / 3.0 - 2.7);
        let p = &a * a.transpose() / n as f64 + DMatrix::identity(n, n) * 0.3;
        (&p + p.transpose()) * 0.5
    }

    /// A measurement matrix with exact zeros, a −0 and a dense row.
    fn measurement_test_matrix(m: usize, n: usize) -> DMatrix<f64> {
        let mut h = DMatrix::from_fn(m, n, |i, j| {
            if (i + 2 * j) % 3 == 0 {
                ((i * 5 + j) % 7) as f64 / 7.0 - 0.4
            } else {
                0.0
            }
        });
        h[(0, n - 1)] = -0.0;
        h.row_mut(m - 1)
            .iter_mut()
            .enumerate()
            .for_each(|(j, v)| *v = 0.1 + j as f64 / 9.0);
        h
    }

    #[test]
    fn cross_covariance_is_the_transposed_dense_product_bit_for_bit() {
        for (m, n) in [(1, 1), (3, 8), (6, 15), (6, 21), (9, 12)] {
            let p = symmetric_test_matrix(n);
            let h = measurement_test_matrix(m, n);
            let mut list = [0; MAX_LISTED];
            let columns = nonzero_columns(&h, &mut list);
            let mut hp = DMatrix::zeros(m, n);
            h_times_symmetric(&mut hp, &h, &p, columns);
            let mut hph = DMatrix::zeros(m, m);
            times_h_transpose(&mut hph, &hp, &h, columns);
            let mut cross = DMatrix::zeros(n, m);
            symmetric_times_h_transpose(&mut cross, &p, &h);
            assert_eq!(cross, hp.transpose(), "P Hᵀ, {m}×{n}");
            let mut hph_sparse = DMatrix::zeros(m, m);
            h_times_cross(&mut hph_sparse, &h, &cross);
            assert_eq!(hph_sparse, hph, "H P Hᵀ, {m}×{n}");
            // And both agree with nalgebra's product to rounding.
            let reference = &h * &p * h.transpose();
            assert!((&hph - &reference).abs().max() <= 1e-12 * reference.abs().max());
        }
    }

    #[test]
    fn gain_solve_equals_nalgebra_cholesky_solve_bit_for_bit() {
        for (m, n) in [(1, 1), (3, 8), (6, 15), (6, 21), (8, 21)] {
            let p = symmetric_test_matrix(n);
            let h = measurement_test_matrix(m, n);
            let hp = &h * &p;
            let s = &hp * h.transpose()
                + DMatrix::from_fn(m, m, |i, j| if i == j { 0.7 } else { 0.01 });
            let s = (&s + s.transpose()) * 0.5;
            let chol = nalgebra::Cholesky::new(s.clone()).expect("positive definite");
            let expected = chol.solve(&hp).transpose();
            let mut gain = hp.transpose();
            solve_gain_in_place(&mut gain, chol.l_dirty());
            assert_eq!(gain, expected, "{m}×{n}");
            // K S = P Hᵀ, to rounding.
            let back = &gain * &s;
            assert!((&back - hp.transpose()).abs().max() <= 1e-12 * hp.abs().max());
        }
    }

    #[test]
    fn fused_rank_2k_equals_two_lower_products_bit_for_bit() {
        for (n, m) in [(1, 1), (5, 2), (15, 6), (21, 6), (40, 6)] {
            let p = symmetric_test_matrix(n);
            let v = DMatrix::from_fn(n, m, |i, j| ((i * 3 + j * 5) % 11) as f64 / 7.0 - 0.6);
            let k = DMatrix::from_fn(n, m, |i, j| ((i * 7 + j) % 13) as f64 / 9.0 - 0.5);
            let mut two = p.clone();
            gemm_nt_lower(&mut two, 1.0, &v, &k, 1.0);
            gemm_nt_lower(&mut two, 1.0, &k, &v, 1.0);
            mirror_lower(&mut two);
            let mut fused = p.clone();
            add_rank_2k_lower(&mut fused, &v, &k);
            mirror_lower(&mut fused);
            assert_eq!(fused, two, "n = {n}");
            assert_eq!(fused, fused.transpose());
            let reference = &p + &v * k.transpose() + &k * v.transpose();
            assert!((&fused - &reference).abs().max() <= 1e-12 * reference.abs().max());
        }
        // Fixed sizes take the same kernel with constant lengths.
        let p = SMatrix::<f64, 21, 21>::from_fn(|i, j| (i.min(j) * 3 + i.max(j)) as f64 / 5.0);
        let v = SMatrix::<f64, 21, 6>::from_fn(|i, j| ((i * 3 + j * 5) % 11) as f64 / 7.0);
        let k = SMatrix::<f64, 21, 6>::from_fn(|i, j| ((i * 7 + j) % 13) as f64 / 9.0);
        let mut two = p;
        gemm_nt_lower(&mut two, 1.0, &v, &k, 1.0);
        gemm_nt_lower(&mut two, 1.0, &k, &v, 1.0);
        mirror_lower(&mut two);
        let mut fused = p;
        add_rank_2k_lower(&mut fused, &v, &k);
        mirror_lower(&mut fused);
        assert_eq!(fused, two);
    }
}
