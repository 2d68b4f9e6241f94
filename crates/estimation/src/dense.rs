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
//! The batch's fused time and Joseph updates add a third, at the sizes
//! where n − 1 is a multiple of four (5, 9, 13, 21): the last row of the
//! symmetric result is computed apart, as a vector over the other factor's
//! columns (the same terms in the same order), so that the columns of the
//! leading n − 1 rows fill whole four-lane vectors ([`last_row_apart`]).
//!
//! For run-time sized matrices beyond [`SMALL_DYN`] they hand over to
//! nalgebra, whose `matrixmultiply` backend wins there.
//!
//! The filter step's kernels (Φ P Φᵀ, the Joseph rank-2m term, P Hᵀ,
//! H P Hᵀ, the gain solve) run through [`run_widest`]: in the default
//! (portable x86-64, SSE2) build, on a CPU with AVX2, the same code compiled
//! with AVX2 — four elements per instruction instead of two, the same
//! operations on each element in the same order, no FMA — so P is the same
//! bit for bit on every machine, and one predict + update at 21 states /
//! 6 measurements runs about 1.3× faster. The `unsafe` calls of the crate
//! are that dispatch and the batch's two fused ones ([`predicted_aside`],
//! [`accepted_update`]: many matrices, each an argument of the dispatching
//! function), each after run-time detection.

use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, SMatrix, allocator::Allocator};

/// Largest run-time dimension handled by the kernels; larger `Dyn` products
/// go to nalgebra (packed, cache-blocked `matrixmultiply`).
const SMALL_DYN: usize = 32;

/// nalgebra's `SMALL_DIM` (0.35, `gemm_uninit`): a run-time sized product
/// with any dimension at most this runs nalgebra's plain column loop, not
/// `matrixmultiply`.
const NALGEBRA_SMALL: usize = 5;

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

/// Columns `cols` of `out = α · a · B + β · out`, rows `rows`, for
/// column-major a (r × k) and out (r × c), where `b(kk, j)` reads element
/// (kk, j) of B: B itself, or a transpose. Axpy form: each output column
/// accumulates scaled columns of a over the inner indices `inner`, in their
/// order. When the row count is a compile-time constant (fixed-size matrices) the
/// compiler keeps the whole output column in registers while the inner index
/// runs: one load of a's column and one broadcast per column element pair.
/// With `init` (r × c, column-major) each output column starts from init's
/// instead of out's own values (out then needs no copy of it beforehand).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn columns<I: Iterator<Item = usize> + Clone>(
    r: usize,
    (rows, cols): (std::ops::Range<usize>, std::ops::Range<usize>),
    inner: &I,
    alpha: f64,
    a: &[f64],
    b: &impl Fn(usize, usize) -> f64,
    (beta, init): (f64, Option<&[f64]>),
    out: &mut [f64],
) {
    let (row0, len) = (rows.start, rows.end - rows.start);
    for j in cols {
        let oc = &mut out[j * r + row0..][..len];
        if let Some(init) = init {
            oc.copy_from_slice(&init[j * r + row0..][..len]);
        }
        if beta == 0.0 {
            oc.fill(0.0);
        } else if beta != 1.0 {
            oc.iter_mut().for_each(|v| *v *= beta);
        }
        for kk in inner.clone() {
            let s = alpha * b(kk, j);
            let ac = &a[kk * r + row0..][..len];
            axpy(oc, ac, s);
        }
    }
}

/// `o += x · s` element by element (o and x of one length). (Not in
/// explicit groups of four: that made run-time sized columns slower, and
/// the compiler vectorises this plain loop well once it knows that o does
/// not overlap x, see [`Widened`].)
#[inline(always)]
fn axpy(o: &mut [f64], x: &[f64], s: f64) {
    for (o, &x) in o.iter_mut().zip(x) {
        *o += x * s;
    }
}

/// out = α · a · B + β · out (see [`columns`]), each output column started
/// from `init`'s when it is given (`start` = (β, init): α a B + β init,
/// out's own values unread); with `lower`, a square out's
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
    start: (f64, Option<&[f64]>),
    out: &mut [f64],
    lower: bool,
) {
    if !lower {
        columns(r, (0..r, 0..c), &inner, alpha, a, &b, start, out);
        return;
    }
    lower_leading(r, r, inner, alpha, a, b, start, out);
}

/// The lower triangle of the leading `rows` × `rows` block of a square
/// r × r `out` (see [`kernel`], `lower`), in [`LOWER_BLOCKS`] column
/// blocks.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn lower_leading<I: Iterator<Item = usize> + Clone>(
    r: usize,
    rows: usize,
    inner: I,
    alpha: f64,
    a: &[f64],
    b: impl Fn(usize, usize) -> f64,
    start: (f64, Option<&[f64]>),
    out: &mut [f64],
) {
    let (s1, s2, s3) = lower_block_starts(rows);
    // Four calls, not a loop or a closure: each inlines with its own
    // constant row count (fixed sizes), which keeps the columns in registers.
    columns(r, (0..rows, 0..s1), &inner, alpha, a, &b, start, out);
    columns(r, (s1..rows, s1..s2), &inner, alpha, a, &b, start, out);
    columns(r, (s2..rows, s2..s3), &inner, alpha, a, &b, start, out);
    columns(r, (s3..rows, s3..rows), &inner, alpha, a, &b, start, out);
}

/// First columns (and rows) of blocks 1–3 of the [`LOWER_BLOCKS`] column
/// blocks that cover the lower triangle of an r × r matrix, each starting at
/// an even row at or above its first column (see [`kernel`]).
#[inline(always)]
pub(crate) fn lower_block_starts(r: usize) -> (usize, usize, usize) {
    let start = |b: usize| (b * r / LOWER_BLOCKS) & !1;
    (start(1), start(2), start(3))
}

/// Column blocks of a lower-triangle product (the four calls in [`kernel`]).
const LOWER_BLOCKS: usize = 4;

/// `out = α a B + β out` for an r × k a through [`kernel`] (B's element
/// (kk, j) read by `read`; the lower triangle only with `lower`) where
/// [`use_kernel`] takes the sizes, else through `packed`, nalgebra's
/// product.
#[inline(always)]
fn product<R: Dim, K: Dim, C: Dim>(
    out: &mut OMatrix<f64, R, C>,
    (r, k, c): (usize, usize, usize),
    (alpha, a): (f64, &[f64]),
    read: impl Fn(usize, usize) -> f64,
    (beta, lower): (f64, bool),
    packed: impl FnOnce(&mut OMatrix<f64, R, C>),
) where
    DefaultAllocator: Allocator<R, C>,
{
    if use_kernel::<R, K, C>(r, k, c) {
        let out = out.as_mut_slice();
        kernel((r, c), 0..k, alpha, a, read, (beta, None), out, lower);
    } else {
        packed(out);
    }
}

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
    let bs = b.as_slice();
    let read = |kk: usize, j: usize| bs[j * k + kk];
    let packed = |out: &mut OMatrix<f64, R, C>| out.gemm(alpha, a, b, beta);
    product::<R, K, C>(
        out,
        (r, k, c),
        (alpha, a.as_slice()),
        read,
        (beta, false),
        packed,
    );
}

/// `out = α a bᵀ + β out`; with `lower` (a square `out`) its lower triangle
/// only, the elements above the diagonal left unspecified (follow with
/// [`mirror_lower`]): for products known to be symmetric.
#[inline]
fn product_nt<R: Dim, K: Dim, C: Dim>(
    out: &mut OMatrix<f64, R, C>,
    (alpha, a): (f64, &OMatrix<f64, R, K>),
    b: &OMatrix<f64, C, K>,
    (beta, lower): (f64, bool),
) where
    DefaultAllocator: Allocator<R, C> + Allocator<R, K> + Allocator<C, K> + Allocator<K, C>,
{
    let (r, k, c) = (a.nrows(), a.ncols(), b.nrows());
    let bs = b.as_slice();
    let read = |kk: usize, j: usize| bs[kk * c + j];
    let packed = |out: &mut OMatrix<f64, R, C>| out.gemm(alpha, a, &b.transpose(), beta);
    product::<R, K, C>(
        out,
        (r, k, c),
        (alpha, a.as_slice()),
        read,
        (beta, lower),
        packed,
    );
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
    product_nt(out, (alpha, a), b, (beta, false));
}

/// The lower triangle of `out = α a bᵀ + β out` for a square `out` (see
/// [`product_nt`]).
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
    product_nt(out, (alpha, a), b, (beta, true));
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

/// `out = a B` (r × c) summing over the inner indices in `list` only
/// ([`kernel`], B's element (kk, j) read by `read`).
#[inline(always)]
fn listed(
    (r, c): (usize, usize),
    list: &[usize],
    a: &[f64],
    read: impl Fn(usize, usize) -> f64,
    out: &mut [f64],
) {
    let inner = list.iter().copied();
    kernel((r, c), inner, 1.0, a, read, (0.0, None), out, false);
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
            listed((m, n), list, h.as_slice(), read, out.as_mut_slice());
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
            listed((m, m), list, u.as_slice(), read, out.as_mut_slice());
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
    // Beyond the kernels' sizes nalgebra's product is packed and blocked
    // (its own order of operations) only when every dimension exceeds its
    // small size, 5; a rank-2m term with m ≤ 5 (a measurement of a few
    // components on a large state: the group filter's) runs its plain
    // column loop, the kernel's operations in the kernel's order (α = β =
    // 1), so the kernel gives its bits while computing only the lower
    // triangle and allocating no transposes.
    if !use_kernel::<D, K, D>(n, m, n) {
        if m > NALGEBRA_SMALL {
            gemm_nt_lower(out, 1.0, v, k, 1.0);
            gemm_nt_lower(out, 1.0, k, v, 1.0);
        } else {
            // Large n: worth the wider vectors.
            run_widest(
                Rank2kLower { n, m },
                out.as_mut_slice(),
                &mut [],
                v.as_slice(),
                k.as_slice(),
            );
        }
        return;
    }
    rank_2k_lower_kernel(
        (n, n),
        m,
        (v.as_slice(), k.as_slice()),
        None,
        out.as_mut_slice(),
    );
}

/// [`add_rank_2k_lower`] on the column-major slices: `out` (n × n), `a` =
/// V and `b` = K (n × m); no scratch.
struct Rank2kLower {
    n: usize,
    m: usize,
}

impl Widened for Rank2kLower {
    #[inline(always)]
    fn run(self, out: &mut [f64], _scratch: &mut [f64], a: &[f64], b: &[f64]) {
        let (n, m) = (self.n, self.m);
        rank_2k_lower_kernel(
            (n, n),
            m,
            (&a[..n * m], &b[..n * m]),
            None,
            &mut out[..n * n],
        );
    }
}

/// The kernel of [`add_rank_2k_lower`] on column-major slices (v, k: n × m),
/// adding onto `prior` (n × n) when given instead of onto out's own values:
/// the lower triangle of the leading `rows` × `rows` block of out (n × n).
#[inline(always)]
fn rank_2k_lower_kernel(
    (n, rows): (usize, usize),
    m: usize,
    (vs, ks): (&[f64], &[f64]),
    prior: Option<&[f64]>,
    os: &mut [f64],
) {
    let (s1, s2, s3) = lower_block_starts(rows);
    rank_2k_columns(n, m, (0..rows, 0..s1), (vs, ks), prior, os);
    rank_2k_columns(n, m, (s1..rows, s1..s2), (vs, ks), prior, os);
    rank_2k_columns(n, m, (s2..rows, s2..s3), (vs, ks), prior, os);
    rank_2k_columns(n, m, (s3..rows, s3..rows), (vs, ks), prior, os);
}

/// Columns `cols`, rows `rows`, of [`add_rank_2k_lower`] (the column of
/// out stays in registers for fixed sizes, as in [`columns`]; with `prior`
/// it starts from prior's column, as in [`columns`]'s `init`).
#[inline(always)]
fn rank_2k_columns(
    n: usize,
    m: usize,
    (rows, cols): (std::ops::Range<usize>, std::ops::Range<usize>),
    (vs, ks): (&[f64], &[f64]),
    prior: Option<&[f64]>,
    os: &mut [f64],
) {
    let (row0, len) = (rows.start, rows.end - rows.start);
    for j in cols {
        let oc = &mut os[j * n + row0..][..len];
        if let Some(prior) = prior {
            oc.copy_from_slice(&prior[j * n + row0..][..len]);
        }
        // (No opaque column reference for AVX-512 builds any more: with the
        // matrices as the dispatching function's slice arguments the
        // compiler knows they do not overlap, and the opaque reference,
        // which had stopped it vectorising across the columns j with
        // gathers, now made the -C target-cpu=native step slower: 21/6,
        // 7.6 → 6.0 µs without it, interleaved pairs on a loaded machine.)
        // (Two plain loops: a loop over the pair of operands stops the
        // compiler from keeping the column in registers.)
        for l in 0..m {
            let s = ks[l * n + j];
            let ac = &vs[l * n + row0..][..len];
            axpy(oc, ac, s);
        }
        for l in 0..m {
            let s = vs[l * n + j];
            let ac = &ks[l * n + row0..][..len];
            axpy(oc, ac, s);
        }
    }
}

/// `cross = p hᵀ` (n × m) for a symmetric `p` (n × n) and h (m × n),
/// then `hph = h cross` (m × m), H P Hᵀ. Column i of P Hᵀ sums the
/// columns k of p weighted by h(i, k), over the nonzero h(i, k) only (a
/// navigation filter's H selects a few states), in increasing k from 0:
/// the transpose of [`h_times_symmetric`]'s H P bit for bit (each product
/// is the same, and a left-out term is an exact zero added to a sum that
/// started at +0 and so is never −0, which leaves it unchanged; p is
/// finite). Likewise `hph(i, j) = Σ_k cross(k, i) h(j, k)` over the
/// nonzero h(j, k) in increasing k, bit for bit what
/// [`times_h_transpose`] gives from H P.
pub(crate) fn measured_covariances<M: Dim, N: Dim>(
    (cross, hph): (&mut OMatrix<f64, N, M>, &mut OMatrix<f64, M, M>),
    p: &OMatrix<f64, N, N>,
    h: &OMatrix<f64, M, N>,
) where
    DefaultAllocator: Allocator<M, N> + Allocator<N, N> + Allocator<N, M> + Allocator<M, M>,
{
    let (md, nd) = h.shape_generic();
    let (out, hs) = (cross.as_mut_slice(), h.as_slice());
    let work = MeasuredProduct::<_, _, true> { n: nd, m: md };
    run_widest(work, out, &mut [], p.as_slice(), hs);
    let work = MeasuredProduct::<_, _, false> { n: nd, m: md };
    run_widest(work, hph.as_mut_slice(), &mut [], hs, cross.as_slice());
}

/// The two products of [`measured_covariances`] (P Hᵀ with `CROSS`) on the
/// column-major slices, no scratch: `out` = P Hᵀ (n × m), `a` = P (n × n),
/// `b` = H (m × n); or `out` = H P Hᵀ (m × m), `a` = H (m × n), `b` = P Hᵀ
/// (n × m).
struct MeasuredProduct<N: Dim, M: Dim, const CROSS: bool> {
    n: N,
    m: M,
}

impl<N: Dim, M: Dim, const CROSS: bool> Widened for MeasuredProduct<N, M, CROSS> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let (n, m) = (self.n.value(), self.m.value());
        if CROSS {
            let (ps, hs) = (&a[..n * n], &b[..m * n]);
            over_nonzero_h(&mut out[..n * m], n, (n, m), hs, |oc, k, hv| {
                for (o, &x) in oc.iter_mut().zip(&ps[k * n..][..n]) {
                    *o += hv * x;
                }
            });
        } else {
            let (hs, ws) = (&a[..m * n], &b[..n * m]);
            over_nonzero_h(&mut out[..m * m], m, (n, m), hs, |oc, k, hv| {
                for (i, o) in oc.iter_mut().enumerate() {
                    *o += ws[i * n + k] * hv;
                }
            });
        }
    }
}

/// Each column i of `out` (columns of `len`) from +0, gaining `term(column,
/// k, h(i, k))` for the nonzero h(i, k) of the m × n `hs` in increasing k.
#[inline(always)]
fn over_nonzero_h(
    out: &mut [f64],
    len: usize,
    (n, m): (usize, usize),
    hs: &[f64],
    term: impl Fn(&mut [f64], usize, f64),
) {
    for i in 0..m {
        let oc = &mut out[i * len..][..len];
        oc.fill(0.0);
        for k in 0..n {
            let hv = hs[k * m + i];
            if hv != 0.0 {
                term(oc, k, hv);
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
    let (nd, md) = w.shape_generic();
    debug_assert!(md.value() <= MAX_GAIN_SOLVE);
    run_widest(
        GainSolve { n: nd, m: md },
        w.as_mut_slice(),
        &mut [],
        l.as_slice(),
        &[],
    );
}

/// [`solve_gain_in_place`] on the column-major slices: `out` = W, then K
/// (n × m), `a` = L (m × m); no scratch, no `b`.
struct GainSolve<N: Dim, M: Dim> {
    n: N,
    m: M,
}

impl<N: Dim, M: Dim> Widened for GainSolve<N, M> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], _: &[f64]) {
        let (n, m) = (self.n.value(), self.m.value());
        let (ws, ls) = (&mut out[..n * m], &a[..m * m]);
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
}

/// Solve C y = b in place (`b` holds b on entry, y on return) from the
/// Cholesky factor of C (`l`, m × m column-major, m = b's length; its lower
/// triangle read): nalgebra's `Cholesky::solve` on a vector operation for
/// operation — forward, y_i = b_i / L(i, i) then b_r = −y_i L(r, i) + b_r
/// for r > i (its axpy); back, from the last row, the dot product
/// Σ_{r>i} L(r, i) y_r from +0 in increasing r (its dot of a run-time
/// sized view, plain order below 8 terms), y_i = (y_i − dot) / L(i, i) — so
/// the same bits, for the small fixed sizes whose generic views cost more
/// than the arithmetic.
#[inline(always)]
pub(crate) fn cholesky_solve_vector(l: &[f64], b: &mut [f64]) {
    let m = b.len();
    let l = &l[..m * m];
    for i in 0..m {
        let coefficient = b[i] / l[i * m + i];
        b[i] = coefficient;
        for r in i + 1..m {
            // nalgebra's axpy: a x + β y with β = 1 (exact).
            #[allow(clippy::assign_op_pattern)]
            {
                b[r] = -coefficient * l[i * m + r] + b[r];
            }
        }
    }
    for i in (0..m).rev() {
        let mut dot = 0.0;
        for r in i + 1..m {
            dot += l[i * m + r] * b[r];
        }
        b[i] = (b[i] - dot) / l[i * m + i];
    }
}

/// `y = Φ x` (the time update's state) as nalgebra's product computes it
/// (its gemv: `y = Φ(·, 0) x₀`, then `y = Φ(·, k) x_k + y` for k = 1, 2, …,
/// its multiplications by α = β = 1 exact), through [`run_widest`]: the
/// same bits with wider vectors, where nalgebra's strided loop was one
/// element at a time.
pub(crate) fn matrix_vector<D: Dim>(
    y: &mut OVector<f64, D>,
    phi: &OMatrix<f64, D, D>,
    x: &OVector<f64, D>,
) where
    DefaultAllocator: Allocator<D, D> + Allocator<D>,
{
    let (nd, _) = phi.shape_generic();
    run_widest(
        MatrixVector { n: nd },
        y.as_mut_slice(),
        &mut [],
        phi.as_slice(),
        x.as_slice(),
    );
}

/// [`matrix_vector`] on the column-major slices: `out` = y (n), `a` = Φ
/// (n × n), `b` = x (n).
struct MatrixVector<D: Dim> {
    n: D,
}

impl<D: Dim> Widened for MatrixVector<D> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let n = self.n.value();
        if n == 0 {
            return;
        }
        let (y, phi, x) = (&mut out[..n], &a[..n * n], &b[..n]);
        let x0 = x[0];
        for (o, &f) in y.iter_mut().zip(&phi[..n]) {
            *o = f * x0;
        }
        for (k, &xk) in x.iter().enumerate().skip(1) {
            for (o, &f) in y.iter_mut().zip(&phi[k * n..(k + 1) * n]) {
                // nalgebra's operand order (term + y), kept so that even a
                // NaN propagates as it did.
                #[allow(clippy::assign_op_pattern)]
                {
                    *o = f * xk + *o;
                }
            }
        }
    }
}

/// `out = Φ p Φᵀ + out` for a symmetric `out` and `p` (the time update's
/// covariance, `out` holding Q on entry): Φ P as [`gemm`] computes it, then
/// the lower triangle of (Φ P) Φᵀ as [`gemm_nt_lower`] does, and
/// [`mirror_lower`]: the same operations in the same order, bit for bit,
/// through [`run_widest`] (wider vectors where the CPU has them).
pub(crate) fn add_congruence<D: Dim>(
    out: &mut OMatrix<f64, D, D>,
    phi: &OMatrix<f64, D, D>,
    p: &OMatrix<f64, D, D>,
) where
    DefaultAllocator: Allocator<D, D>,
{
    let (nd, _) = p.shape_generic();
    let mut phi_p = OMatrix::<f64, D, D>::zeros_generic(nd, nd);
    congruence(out, None, phi, p, &mut phi_p);
}

/// [`add_congruence`] (`base` None: onto out's values) or `out = Φ p Φᵀ +
/// base`, [`add_congruence`] on a copy of `base` bit for bit, out's values
/// on entry unread, `phi_p` the scratch for Φ P (its values on entry
/// unread too): each column of out starts from base's inside the kernel
/// instead of out being a copy of it made beforehand (the batch's time
/// update, a copy of P fewer).
pub(crate) fn congruence<D: Dim>(
    out: &mut OMatrix<f64, D, D>,
    base: Option<&OMatrix<f64, D, D>>,
    phi: &OMatrix<f64, D, D>,
    p: &OMatrix<f64, D, D>,
    phi_p: &mut OMatrix<f64, D, D>,
) where
    DefaultAllocator: Allocator<D, D>,
{
    let (nd, _) = p.shape_generic();
    let n = nd.value();
    if use_kernel::<D, D, D>(n, n, n) {
        run_widest(
            Congruence {
                n: nd,
                base: base.map(|q| q.as_slice()),
                p_symmetric: false,
            },
            out.as_mut_slice(),
            phi_p.as_mut_slice(),
            phi.as_slice(),
            p.as_slice(),
        );
    } else {
        if let Some(q) = base {
            out.copy_from(q);
        }
        gemm(phi_p, 1.0, phi, p, 0.0);
        gemm_nt_lower(out, 1.0, phi_p, phi, 1.0);
        mirror_lower(out);
    }
}

/// [`add_congruence`] on the column-major slices: `out` (n × n), `scratch`
/// for Φ P (n × n), `a` = Φ, `b` = P; with `base` (n × n, Q) the sum
/// starts from base's elements instead of out's. `p_symmetric`: the caller
/// knows P to be symmetric bit for bit, so that row n − 1 of Φ P, too, is
/// a column's worth of vectors (see [`last_row_apart`]; row n − 1 of the
/// scratch is then left unwritten).
struct Congruence<'q, D: Dim> {
    n: D,
    base: Option<&'q [f64]>,
    p_symmetric: bool,
}

impl<D: Dim> Widened for Congruence<'_, D> {
    #[inline(always)]
    fn run(self, out: &mut [f64], scratch: &mut [f64], a: &[f64], b: &[f64]) {
        let n = self.n.value();
        let nn = n * n;
        let (out, phi_p, phi, p) = (&mut out[..nn], &mut scratch[..nn], &a[..nn], &b[..nn]);
        let base = self.base.map(|q| &q[..nn]);
        // Φ P, as gemm(Φ P): b(kk, j) = P(kk, j).
        let read_p = |kk: usize, j: usize| p[j * n + kk];
        // (Φ P) Φᵀ, lower, as gemm_nt_lower: b(kk, j) = Φ(j, kk).
        let read_phi = |kk: usize, j: usize| phi[kk * n + j];
        if !last_row_apart(n) {
            kernel((n, n), 0..n, 1.0, phi, read_p, (0.0, None), phi_p, false);
            kernel((n, n), 0..n, 1.0, phi_p, read_phi, (1.0, base), out, true);
            mirror_lower_slice(n, out);
            return;
        }
        let last = n - 1;
        // Row `last` of Φ P: with P symmetric bit for bit, element
        // (last, j), Σ Φ(last, kk) P(kk, j) from +0 over kk in order, has
        // the terms of Φ(last, kk) P(j, kk): as a vector over j, P's
        // column kk scaled (each product commuted, exact); else as the
        // other rows.
        let mut phi_p_last = [0.0; SMALL_DYN];
        let phi_p_last = &mut phi_p_last[..n];
        if self.p_symmetric {
            columns(
                n,
                (0..last, 0..n),
                &(0..n),
                1.0,
                phi,
                &read_p,
                (0.0, None),
                phi_p,
            );
            for kk in 0..n {
                axpy(phi_p_last, &p[kk * n..][..n], phi[kk * n + last]);
            }
        } else {
            kernel((n, n), 0..n, 1.0, phi, read_p, (0.0, None), phi_p, false);
            for (k, v) in phi_p_last.iter_mut().enumerate() {
                *v = phi_p[k * n + last];
            }
        }
        lower_leading(n, last, 0..n, 1.0, phi_p, read_phi, (1.0, base), out);
        // Row `last`, element (last, j) the sum of Φ P(last, k) Φ(j, k) over
        // k in order, the kernel's terms (each product commuted, exact):
        // as a vector over j, Φ's column k scaled.
        let column = last_row_start(n, base, out);
        for (k, &s) in phi_p_last.iter().enumerate() {
            axpy(column, &phi[k * n..][..n], s);
        }
        mirror_with_last_column(n, out);
    }
}

/// Whether the fused kernels ([`Congruence`], [`JosephRank2k`]) compute
/// the last row of their symmetric n × n result apart: when n − 1 is a
/// multiple of four (n = 5, 9, 13, 21, …). The columns of the leading
/// n − 1 rows then fill whole four-lane vectors, where at n = 9 each
/// column of nine rows took two vectors and a scalar (a third of the
/// instructions for a ninth of the elements); the last row, element
/// (n − 1, j) for every j, is one more column's worth of vectors: the same
/// terms summed in the same order, with the roles of the two factors of
/// each product swapped (exact: multiplication commutes, and the inputs'
/// NaN are the one default NaN), kept in the storage of column n − 1 and
/// mirrored from there ([`mirror_with_last_column`]).
#[inline(always)]
fn last_row_apart(n: usize) -> bool {
    n >= 5 && n % 4 == 1 && n <= SMALL_DYN
}

/// The start of row n − 1 of a lower-triangle sum onto `base` (or onto
/// out's own values when None), element (n − 1, j) written at (j, n − 1),
/// in column n − 1 of out (n × n), which is returned: the storage
/// [`last_row_apart`]'s sums accumulate in.
#[inline(always)]
fn last_row_start<'o>(n: usize, base: Option<&[f64]>, out: &'o mut [f64]) -> &'o mut [f64] {
    let last = n - 1;
    let (head, column) = out[..n * n].split_at_mut(last * n);
    for (j, o) in column[..last].iter_mut().enumerate() {
        *o = match base {
            Some(b) => b[j * n + last],
            None => head[j * n + last],
        };
    }
    if let Some(b) = base {
        column[last] = b[last * n + last];
    }
    column
}

/// The symmetric n × n matrix from the lower triangle of its leading
/// n − 1 rows and from its row n − 1 kept in column n − 1 (see
/// [`last_row_apart`]): the leading block mirrored as by
/// [`mirror_lower_slice`], then column n − 1 copied onto row n − 1.
#[inline(always)]
fn mirror_with_last_column(n: usize, s: &mut [f64]) {
    let last = n - 1;
    let s = &mut s[..n * n];
    for j in 1..last {
        for i in 0..j {
            s[j * n + i] = s[i * n + j];
        }
    }
    for j in 0..last {
        s[j * n + last] = s[last * n + j];
    }
}

/// The Joseph update's covariance, `prior + V Kᵀ + K Vᵀ` into `p` with
/// `V = α K S + β W` (`v` holds W on entry, V on return): V as [`gemm`]
/// computes it, then [`add_rank_2k_lower`] and [`mirror_lower`]: the same
/// operations in the same order, bit for bit, through [`run_widest`].
/// `prior` None: in place, onto p's values; else onto `prior`'s, bit for
/// bit the same as onto a copy of it, p's values on entry unread (each
/// column of p starts from prior's inside the kernel: the batch's update,
/// a copy of P fewer).
pub(crate) fn joseph_rank_2k<N: Dim, M: Dim>(
    p: &mut OMatrix<f64, N, N>,
    prior: Option<&OMatrix<f64, N, N>>,
    v: &mut OMatrix<f64, N, M>,
    (gain, s): (&OMatrix<f64, N, M>, &OMatrix<f64, M, M>),
    (alpha, beta): (f64, f64),
) where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    let (nd, md) = v.shape_generic();
    let (n, m) = (nd.value(), md.value());
    if use_kernel::<N, M, N>(n, m, n) && use_kernel::<N, M, M>(n, m, m) {
        run_widest(
            JosephRank2k {
                n: nd,
                m: md,
                alpha,
                beta,
                prior: prior.map(|q| q.as_slice()),
            },
            p.as_mut_slice(),
            v.as_mut_slice(),
            gain.as_slice(),
            s.as_slice(),
        );
    } else {
        if let Some(prior) = prior {
            p.copy_from(prior);
        }
        gemm(v, alpha, gain, s, beta);
        add_rank_2k_lower(p, v, gain);
        mirror_lower(p);
    }
}

/// [`joseph_rank_2k`] on the column-major slices: `out` = P (n × n),
/// `scratch` = W, then V (n × m), `a` = K (n × m), `b` = S (m × m); with
/// `prior` (n × n) the sum starts from prior's elements instead of out's.
struct JosephRank2k<'p, N: Dim, M: Dim> {
    n: N,
    m: M,
    alpha: f64,
    beta: f64,
    prior: Option<&'p [f64]>,
}

impl<N: Dim, M: Dim> Widened for JosephRank2k<'_, N, M> {
    #[inline(always)]
    fn run(self, out: &mut [f64], scratch: &mut [f64], a: &[f64], b: &[f64]) {
        let (n, m) = (self.n.value(), self.m.value());
        let (p, v, gain, s) = (
            &mut out[..n * n],
            &mut scratch[..n * m],
            &a[..n * m],
            &b[..m * m],
        );
        let prior = self.prior.map(|q| &q[..n * n]);
        // V = α K S + β W, as gemm: b(kk, j) = S(kk, j).
        let read_s = |kk: usize, j: usize| s[j * m + kk];
        kernel(
            (n, m),
            0..m,
            self.alpha,
            gain,
            read_s,
            (self.beta, None),
            v,
            false,
        );
        if !last_row_apart(n) {
            rank_2k_lower_kernel((n, n), m, (v, gain), prior, p);
            mirror_lower_slice(n, p);
            return;
        }
        let last = n - 1;
        rank_2k_lower_kernel((n, last), m, (v, gain), prior, p);
        // Row `last` (see last_row_apart): element (last, j) gets
        // Σ V(last, l) K(j, l) then Σ K(last, l) V(j, l), as the kernel
        // sums them.
        let column = last_row_start(n, prior, p);
        for l in 0..m {
            axpy(column, &gain[l * n..][..n], v[l * n + last]);
        }
        for l in 0..m {
            axpy(column, &v[l * n..][..n], gain[l * n + last]);
        }
        mirror_with_last_column(n, p);
    }
}

/// Defines a function whose body runs with the widest vectors worth having
/// on this CPU: on x86-64 when AVX2 is not enabled at compile time (the
/// default, portable build) but the CPU has it (detected once, then a
/// cached load), the body compiled with AVX2; otherwise as compiled. One
/// definition for every such dispatch ([`run_widest`], [`accepted_update`],
/// [`predicted_aside`]): `fn name [generics] [generic arguments] (args) ->
/// type { body }`, each argument a name (destructure in the body).
///
/// The body must not depend on the vector width (element-wise loops, no
/// reassociated sums; FMA is not enabled and Rust never contracts a
/// multiply and an add), so that only the number of elements per
/// instruction changes and the result is the same bit for bit. Every slice
/// is an argument of the dispatching function, so that the compiler knows
/// they do not overlap.
macro_rules! widest {
    (
        $(#[$attr:meta])*
        $vis:vis fn $name:ident [$($generics:tt)*] [$($arguments:tt)*]
            ($($arg:ident: $ty:ty),* $(,)?) -> $ret:ty $body:block
    ) => {
        $(#[$attr])*
        #[inline(always)]
        #[allow(clippy::too_many_arguments)]
        $vis fn $name<$($generics)*>($($arg: $ty),*) -> $ret {
            /// The body, inlined into both builds.
            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            fn body<$($generics)*>($($arg: $ty),*) -> $ret $body

            /// The body compiled with AVX2.
            #[cfg(all(target_arch = "x86_64", not(target_feature = "avx2")))]
            #[target_feature(enable = "avx2")]
            #[allow(clippy::too_many_arguments)]
            fn avx2<$($generics)*>($($arg: $ty),*) -> $ret {
                body::<$($arguments)*>($($arg),*)
            }

            #[cfg(all(target_arch = "x86_64", not(target_feature = "avx2")))]
            if std::arch::is_x86_feature_detected!("avx2") {
                #[allow(unsafe_code)]
                // SAFETY: `avx2`'s only requirement is that the CPU
                // executes AVX2 instructions, which was just detected at
                // run time.
                return unsafe { avx2::<$($arguments)*>($($arg),*) };
            }
            body::<$($arguments)*>($($arg),*)
        }
    };
}

/// How [`accepted_update`] ended: the check that failed, in the order of
/// the update's own checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum AcceptedStatus {
    /// Every check passed: x⁺ and P⁺ written.
    Applied,
    /// S is not positive definite (nothing else written).
    SNotPositiveDefinite,
    /// The gain is not finite (x and P not written).
    GainNonFinite,
    /// x⁺ is not finite (x⁺ and P⁺ written).
    StateNonFinite,
    /// P⁺ is not finite (x⁺ and P⁺ written).
    CovarianceNonFinite,
}

widest! {
/// The accepted Joseph update from P⁻ of a fixed-size measurement (`M`
/// components, up to [`MAX_GAIN_SOLVE`]), whole, in one dispatch to its
/// AVX2 build (as [`run_widest`]): P Hᵀ and H P Hᵀ
/// ([`MeasuredProduct`]) symmetrised as `check::symmetrize` does,
/// S = H P Hᵀ + R, its Cholesky factor (the smoother's in-place factor,
/// nalgebra's operations), the NIS ([`cholesky_solve_vector`] and
/// nalgebra's dot), the gain ([`GainSolve`] on a copy of P Hᵀ),
/// x⁺ = x⁻ + K ν (nalgebra's product and sum, in its order), P⁺
/// ([`JosephRank2k`] from P⁻, V made in place of P Hᵀ) and the checks of
/// K, x⁺ and P⁺ — the operations of `innovate_into` and `apply` in their
/// order, so the same bits and the same failures, without the six
/// dispatches and the calls and copies between them.
///
/// Every matrix is an argument of the dispatching function (as
/// [`Widened`] explains: fields of a struct would lose the compiler's
/// knowledge that they do not overlap): `p` = P⁺ (n × n, written),
/// `cross` = P Hᵀ, then V (n × m), `prior` = P⁻, `h` = H (m × n), `r`,
/// `residual` = ν, `x` (x⁻ on entry, x⁺ once the gain passed its check),
/// `hph`, `s`, `factor` (S's Cholesky factor in its lower triangle, S's
/// values above: nalgebra's layout) and `gain` written. Returns the NIS
/// and how the update ended.
pub(crate) fn accepted_update [N: Dim, const M: usize] [N, M] (
    nd: N,
    written: (&mut [f64], &mut [f64]),
    read: (&[f64], &[f64], &[f64], &[f64]),
    x: &mut [f64],
    hph: &mut [f64],
    s: &mut [f64],
    factor: &mut [f64],
    gain: &mut [f64],
) -> (f64, AcceptedStatus) {
    let ((p, cross), (prior, h, r, residual)) = (written, read);
    let n = nd.value();
    let (p, cross, prior, h) = (
        &mut p[..n * n],
        &mut cross[..n * M],
        &prior[..n * n],
        &h[..M * n],
    );
    let (r, residual, x) = (&r[..M * M], &residual[..M], &mut x[..n]);
    let (hph, s, l, gain) = (
        &mut hph[..M * M],
        &mut s[..M * M],
        &mut factor[..M * M],
        &mut gain[..n * M],
    );
    let md = nalgebra::Const::<M>;
    MeasuredProduct::<_, _, true> { n: nd, m: md }.run(cross, &mut [], prior, h);
    MeasuredProduct::<_, _, false> { n: nd, m: md }.run(hph, &mut [], h, cross);
    // check::symmetrize: ½ (m(i, j) + m(j, i)) to both.
    for i in 0..M {
        for j in (i + 1)..M {
            let v = 0.5 * (hph[j * M + i] + hph[i * M + j]);
            hph[j * M + i] = v;
            hph[i * M + j] = v;
        }
    }
    for ((s, &hv), &rv) in s.iter_mut().zip(hph.iter()).zip(r) {
        *s = hv + rv;
    }
    l.copy_from_slice(s);
    if !crate::smoother::cholesky_lower_in_place::<M>(l) {
        return (f64::NAN, AcceptedStatus::SNotPositiveDefinite);
    }
    gain.copy_from_slice(cross);
    GainSolve { n: nd, m: md }.run(gain, &mut [], l, &[]);
    if !crate::check::all_finite_by_exponent(gain) {
        return (f64::NAN, AcceptedStatus::GainNonFinite);
    }
    // x += K ν: nalgebra's product (K(·, 0) ν₀, then K(·, l) ν_l + y),
    // then its sum x + y. (Over the residual's slice: skip(1) on
    // nalgebra's iterator of ν was a call, with the vectors spilled around
    // it.)
    let mut step = [0.0; MAX_FUSED_STATES];
    let step = &mut step[..n];
    for (o, &k) in step.iter_mut().zip(&gain[..n]) {
        *o = k * residual[0];
    }
    for (l, &nl) in residual.iter().enumerate().skip(1) {
        for (o, &k) in step.iter_mut().zip(&gain[l * n..(l + 1) * n]) {
            #[allow(clippy::assign_op_pattern)]
            {
                *o = k * nl + *o;
            }
        }
    }
    for (x, &d) in x.iter_mut().zip(step.iter()) {
        *x += d;
    }
    JosephRank2k {
        n: nd,
        m: md,
        alpha: 0.5,
        beta: -1.0,
        prior: Some(prior),
    }
    .run(p, cross, gain, s);
    // The NIS last: its chain of divisions then runs beside the Joseph
    // update's products instead of beside the gain's divisions, which the
    // rest waits for (nothing here reads it; the same operations).
    let mut solved = [0.0; M];
    solved.copy_from_slice(residual);
    cholesky_solve_vector(l, &mut solved);
    let nu = nalgebra::SVector::<f64, M>::from_column_slice(residual);
    let nis = nu.dot(&nalgebra::SVector::<f64, M>::from_column_slice(&solved));
    let status = if !crate::check::all_finite_by_exponent(x) {
        AcceptedStatus::StateNonFinite
    } else if !crate::check::all_finite_by_exponent(p) {
        AcceptedStatus::CovarianceNonFinite
    } else {
        AcceptedStatus::Applied
    };
    (nis, status)
}
}

/// How [`predicted_aside`] ended: the check that failed, in the order of
/// the time update's own checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PredictedStatus {
    /// x⁻ and P⁻ finite, both written.
    Applied,
    /// x⁻ is not finite (written; P⁻ not computed).
    StateNonFinite,
    /// P⁻ is not finite (x⁻ and P⁻ written).
    CovarianceNonFinite,
}

widest! {
/// The batch's time update with P⁻ kept aside, whole, in one dispatch to
/// its AVX2 build (as [`accepted_update`]): x⁻ = Φ x ([`MatrixVector`],
/// nalgebra's product) and its check, then P⁻ = Φ P Φᵀ + Q
/// ([`Congruence`] onto Q) and its check — the operations and checks of
/// `predict_state_prechecked` and `congruence` onto Q followed by
/// `check::finite`, in their order, without the two dispatches, the calls
/// and the copy of x between them. `x` holds x on entry, x⁻ on return;
/// `predicted` (P⁻) and `phi_p` (scratch for Φ P) are written, their
/// values on entry unread; n at most [`MAX_FUSED_STATES`]; `p_symmetric`:
/// P is known to be symmetric bit for bit (see [`Congruence`]).
pub(crate) fn predicted_aside [D: Dim] [D] (
    size: (D, bool),
    x: &mut [f64],
    read: (&[f64], &[f64], &[f64]),
    predicted: &mut [f64],
    phi_p: &mut [f64],
) -> PredictedStatus {
    let ((nd, p_symmetric), (phi, q, p)) = (size, read);
    let n = nd.value();
    let mut x_predicted = [0.0; MAX_FUSED_STATES];
    let x_predicted = &mut x_predicted[..n];
    MatrixVector { n: nd }.run(x_predicted, &mut [], phi, x);
    let x = &mut x[..n];
    x.copy_from_slice(x_predicted);
    if !crate::check::all_finite_by_exponent(x) {
        return PredictedStatus::StateNonFinite;
    }
    Congruence {
        n: nd,
        base: Some(q),
        p_symmetric,
    }
    .run(predicted, phi_p, phi, p);
    if crate::check::all_finite_by_exponent(&predicted[..n * n]) {
        PredictedStatus::Applied
    } else {
        PredictedStatus::CovarianceNonFinite
    }
}
}

/// Largest number of states [`accepted_update`] and [`predicted_aside`]
/// take (a vector of n on the stack): the kernels' run-time limit.
pub(crate) const MAX_FUSED_STATES: usize = SMALL_DYN;

/// Work that [`run_widest`] may compile for a wider instruction set, on
/// column-major slices: `out` and `scratch` written, `a` and `b` read.
/// An implementation should mark `run` `#[inline(always)]` (nothing
/// enforces it; without it the work runs as compiled for the baseline
/// target: slower, same result), so that its body (and the
/// `#[inline(always)]` kernels it calls) is compiled into the dispatching
/// function with that function's target features; the slices
/// are that function's arguments, so the compiler knows that they do not
/// overlap (matrices reached through a struct's fields lose that, and the
/// output columns are no longer kept in registers).
///
/// The work must not depend on the vector width (no reassociated sums), so
/// that its result is the same on every CPU. Crate-private: what other
/// crates need of it is a product with a stated result (such as
/// [`SecondOrderPattern`](crate::SecondOrderPattern)), not the dispatch.
pub(crate) trait Widened {
    /// Do the work.
    fn run(self, out: &mut [f64], scratch: &mut [f64], a: &[f64], b: &[f64]);
}

widest! {
/// Run `work` with the widest vectors worth having on this CPU: on x86-64
/// when AVX2 is not enabled at compile time (the default, portable build)
/// but the CPU has it (detected once, then a cached load), the work
/// compiled with AVX2; otherwise as compiled.
///
/// The result is the same bit for bit: the kernels are element-wise loops
/// (each output element's multiplies and adds in a fixed order whatever the
/// vector width; the compiler never reassociates floating-point sums), and
/// FMA is not enabled (AVX2 does not imply it, and Rust never contracts a
/// multiply and an add anyway), so only the number of elements per
/// instruction changes.
pub(crate) fn run_widest [W: Widened] [W] (
    work: W,
    out: &mut [f64],
    scratch: &mut [f64],
    a: &[f64],
    b: &[f64],
) -> () {
    work.run(out, scratch, a, b)
}
}

/// Copy the lower triangle of a square matrix onto the upper one.
pub(crate) fn mirror_lower<D: Dim>(m: &mut OMatrix<f64, D, D>)
where
    DefaultAllocator: Allocator<D, D>,
{
    let n = m.nrows();
    mirror_lower_slice(n, m.as_mut_slice());
}

/// [`mirror_lower`] on a column-major n × n slice.
#[inline(always)]
pub(crate) fn mirror_lower_slice(n: usize, s: &mut [f64]) {
    for j in 1..n {
        for i in 0..j {
            s[j * n + i] = s[i * n + j];
        }
    }
}

/// Whether every element of the square n × n matrix stored column-major in
/// `m` has the bits of its mirror (symmetric bit for bit: a +0/−0 pair
/// differs, a NaN equals a NaN of the same bits): when it does, the lower
/// triangle ([`push_lower_triangle`]) carries the whole matrix. One
/// branch-free OR of XORs, three instructions a pair; inlined, so that a
/// compile-time n unrolls the loops and drops the bounds checks.
///
/// ```
/// use aidnav_estimation::symmetric_bits;
/// assert!(symmetric_bits(&[4.0, 1.0, 1.0, 9.0], 2));
/// assert!(!symmetric_bits(&[4.0, 0.0, -0.0, 9.0], 2));
/// ```
#[inline(always)]
pub fn symmetric_bits(m: &[f64], n: usize) -> bool {
    let m = &m[..n * n];
    let mut differ = 0_u64;
    for j in 0..n {
        for i in j + 1..n {
            differ |= m[j * n + i].to_bits() ^ m[i * n + j].to_bits();
        }
    }
    differ == 0
}

/// Append the lower triangle of the N × N `m`, column by column (column j
/// from its diagonal down): N (N + 1) / 2 values, which
/// [`read_lower_triangle`] turns back into the symmetric matrix.
///
/// ```
/// use aidnav_estimation::{push_lower_triangle, read_lower_triangle};
/// use nalgebra::Matrix2;
/// let p = Matrix2::new(4.0, 1.0, 1.0, 9.0);
/// let mut packed = Vec::new();
/// push_lower_triangle(&p, &mut packed);
/// assert_eq!(packed, [4.0, 1.0, 9.0]);
/// let mut back = Matrix2::zeros();
/// assert_eq!(read_lower_triangle(&packed, &mut back), 3);
/// assert_eq!(back, p);
/// ```
#[inline]
pub fn push_lower_triangle<const N: usize>(m: &SMatrix<f64, N, N>, out: &mut Vec<f64>) {
    let s = m.as_slice();
    let start = out.len();
    let count = N * (N + 1) / 2;
    // Each column is copied N long from its diagonal (a copy of constant
    // length; it runs on into the next column, which is written over it)
    // into room reserved once, where an `extend_from_slice` of the N − j
    // elements per column measured slower. Room for N values past the end;
    // cut off after.
    out.resize(start + count + N, 0.0);
    let packed = &mut out[start..];
    let mut at = 0;
    for j in 0..N {
        let from = j * N + j;
        if from + N <= N * N {
            packed[at..at + N].copy_from_slice(&s[from..from + N]);
        } else {
            packed[at..at + N - j].copy_from_slice(&s[from..]);
        }
        at += N - j;
    }
    out.truncate(start + count);
}

/// The symmetric N × N matrix whose lower triangle
/// [`push_lower_triangle`] wrote at the start of `packed`, into `m`: each
/// column copied from its diagonal down, then the upper triangle mirrored
/// from the lower. Returns the values read, N (N + 1) / 2.
#[inline]
pub fn read_lower_triangle<const N: usize>(packed: &[f64], m: &mut SMatrix<f64, N, N>) -> usize {
    let s = m.as_mut_slice();
    let mut at = 0;
    for j in 0..N {
        s[j * N + j..(j + 1) * N].copy_from_slice(&packed[at..at + N - j]);
        at += N - j;
    }
    mirror_lower_slice(N, s);
    at
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector, Dyn, SMatrix, SVector};

    /// `matrix_vector` equals nalgebra's `Φ * x` to the bit (the sign of
    /// zeros included) at fixed size 21 and run-time sizes, with exact
    /// zeros, −0 and negative rows in Φ and a zero x among the cases.
    #[test]
    fn matrix_vector_equals_nalgebras_product_to_the_bit() {
        let mut seed = 12345_u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = (seed >> 11) as f64 / (1u64 << 53) as f64;
            match seed % 7 {
                0 => 0.0,
                1 => -0.0,
                _ => 4.0 * u - 2.0,
            }
        };
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for round in 0..50 {
            let mut phi = SMatrix::<f64, 21, 21>::from_fn(|_, _| next());
            if round % 5 == 0 {
                // A row of negative values and −0: Φ 0 is −0 there.
                for j in 0..21 {
                    phi[(4, j)] = -(phi[(4, j)].abs());
                }
            }
            let x = if round % 3 == 0 {
                SVector::<f64, 21>::zeros()
            } else {
                SVector::<f64, 21>::from_fn(|_, _| next())
            };
            let mut y = SVector::<f64, 21>::zeros();
            matrix_vector(&mut y, &phi, &x);
            assert_eq!(
                bits(y.as_slice()),
                bits((phi * x).as_slice()),
                "round {round}"
            );
        }
        for n in [1, 5, 40] {
            let phi = DMatrix::from_fn(n, n, |_, _| next());
            let x = DVector::from_fn(n, |_, _| next());
            let mut y = DVector::zeros(n);
            matrix_vector(&mut y, &phi, &x);
            assert_eq!(bits(y.as_slice()), bits((&phi * &x).as_slice()), "n {n}");
        }
    }

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

    /// `push_lower_triangle` appends column j from its diagonal down, after
    /// what the vector held, and nothing else: checked against a plain
    /// element loop at sizes whose last columns take its short copy.
    #[test]
    fn the_lower_triangle_is_appended_column_by_column() {
        fn case<const N: usize>() {
            let m = SMatrix::<f64, N, N>::from_fn(|i, j| (i * 100 + j) as f64 + 0.5);
            let mut packed = vec![-1.0, -2.0];
            push_lower_triangle(&m, &mut packed);
            let mut expected = vec![-1.0, -2.0];
            for j in 0..N {
                for i in j..N {
                    expected.push(m[(i, j)]);
                }
            }
            assert_eq!(packed, expected, "N = {N}");
        }
        case::<1>();
        case::<2>();
        case::<3>();
        case::<9>();
        case::<21>();
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
            let (mut cross, mut hph_sparse) = (DMatrix::zeros(n, m), DMatrix::zeros(m, m));
            measured_covariances((&mut cross, &mut hph_sparse), &p, &h);
            assert_eq!(cross, hp.transpose(), "P Hᵀ, {m}×{n}");
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

    /// Beyond the kernels' run-time sizes, a rank-2m term with m ≤ 5 (the
    /// group filter's few-component fixes on its 60 states) takes the
    /// kernel and gives nalgebra's two products bit for bit: random values,
    /// so the order of the sums shows.
    #[test]
    fn large_rank_2k_with_few_columns_equals_nalgebra_bit_for_bit() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        for (n, m) in [(60, 3), (33, 1), (64, 5), (90, 2), (40, 6)] {
            let p = random_covariance(&mut rng, n);
            let v = random_matrix(&mut rng, n, m);
            let k = random_matrix(&mut rng, n, m) * 0.3;
            let mut nalgebra = p.clone();
            nalgebra.gemm(1.0, &v, &k.transpose(), 1.0);
            nalgebra.gemm(1.0, &k, &v.transpose(), 1.0);
            mirror_lower(&mut nalgebra);
            let mut fused = p.clone();
            add_rank_2k_lower(&mut fused, &v, &k);
            mirror_lower(&mut fused);
            let same = fused
                .iter()
                .zip(nalgebra.iter())
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "n = {n}, m = {m}");
        }
    }

    /// The fused kernels with the last row apart (n − 1 a multiple of
    /// four) give the full lower triangle's result bit for bit: Φ P Φᵀ + Q
    /// against gemm, gemm_nt_lower and mirror_lower, the Joseph update
    /// against gemm, add_rank_2k_lower and mirror_lower, onto the matrix's
    /// own values and onto a prior, at the fixed sizes 5, 9, 13 and 21 and
    /// run-time sized; random values, exact zeros in Φ and a Q whose
    /// mirrored zeros differ in sign, so that order and operands show.
    #[test]
    fn the_last_row_apart_equals_the_full_lower_triangle_bit_for_bit() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(29);
        let bits = |m: &[f64]| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        fn check<D: Dim, M: Dim>(
            (nd, md): (D, M),
            rng: &mut rand_chacha::ChaCha8Rng,
            bits: &impl Fn(&[f64]) -> Vec<u64>,
        ) where
            DefaultAllocator: Allocator<D, D> + Allocator<D, M> + Allocator<M, D> + Allocator<M, M>,
        {
            let (n, m) = (nd.value(), md.value());
            assert!(last_row_apart(n), "n = {n}");
            let square = |values: DMatrix<f64>| {
                OMatrix::<f64, D, D>::from_iterator_generic(nd, nd, values.iter().copied())
            };
            let tall = |values: DMatrix<f64>| {
                OMatrix::<f64, D, M>::from_iterator_generic(nd, md, values.iter().copied())
            };
            let mut phi = random_matrix(rng, n, n) * 0.3 + DMatrix::identity(n, n);
            phi[(n - 1, 2)] = 0.0;
            phi[(1, n - 1)] = 0.0;
            let (phi, p) = (square(phi), square(random_covariance(rng, n)));
            let mut q = random_covariance(rng, n) * 1e-3;
            q[(n - 1, 0)] = 0.0;
            q[(0, n - 1)] = -0.0;
            let q = square(q);
            // Time update, onto out's values and onto Q.
            let mut full = q.clone();
            let mut phi_p = square(DMatrix::zeros(n, n));
            gemm(&mut phi_p, 1.0, &phi, &p, 0.0);
            gemm_nt_lower(&mut full, 1.0, &phi_p, &phi, 1.0);
            mirror_lower(&mut full);
            let mut apart = q.clone();
            add_congruence(&mut apart, &phi, &p);
            assert_eq!(
                bits(apart.as_slice()),
                bits(full.as_slice()),
                "Φ P Φᵀ + Q, n = {n}"
            );
            let mut onto = square(DMatrix::repeat(n, n, f64::NAN));
            let mut scratch = square(DMatrix::repeat(n, n, f64::NAN));
            congruence(&mut onto, Some(&q), &phi, &p, &mut scratch);
            assert_eq!(
                bits(onto.as_slice()),
                bits(full.as_slice()),
                "onto Q, n = {n}"
            );
            // P symmetric bit for bit: row n − 1 of Φ P apart too.
            assert_eq!(bits(p.as_slice()), bits(p.transpose().as_slice()));
            let mut onto = square(DMatrix::repeat(n, n, f64::NAN));
            run_widest(
                Congruence {
                    n: nd,
                    base: Some(q.as_slice()),
                    p_symmetric: true,
                },
                onto.as_mut_slice(),
                scratch.as_mut_slice(),
                phi.as_slice(),
                p.as_slice(),
            );
            assert_eq!(
                bits(onto.as_slice()),
                bits(full.as_slice()),
                "P symmetric, n = {n}"
            );
            // Joseph update, onto P's values and onto a prior.
            let gain = tall(random_matrix(rng, n, m) * 0.2);
            let s = OMatrix::<f64, M, M>::from_iterator_generic(
                md,
                md,
                (random_covariance(rng, m) + DMatrix::identity(m, m))
                    .iter()
                    .copied(),
            );
            let w = tall(random_matrix(rng, n, m));
            let (mut full, mut v) = (p.clone(), w.clone());
            gemm(&mut v, 0.5, &gain, &s, -1.0);
            add_rank_2k_lower(&mut full, &v, &gain);
            mirror_lower(&mut full);
            let (mut apart, mut v_apart) = (p.clone(), w.clone());
            joseph_rank_2k(&mut apart, None, &mut v_apart, (&gain, &s), (0.5, -1.0));
            assert_eq!(
                bits(apart.as_slice()),
                bits(full.as_slice()),
                "Joseph, {n}×{m}"
            );
            let (mut onto, mut v_onto) = (square(DMatrix::repeat(n, n, f64::NAN)), w.clone());
            joseph_rank_2k(&mut onto, Some(&p), &mut v_onto, (&gain, &s), (0.5, -1.0));
            assert_eq!(
                bits(onto.as_slice()),
                bits(full.as_slice()),
                "Joseph onto P⁻, {n}×{m}"
            );
        }
        for _ in 0..3 {
            check(
                (nalgebra::Const::<5>, nalgebra::Const::<2>),
                &mut rng,
                &bits,
            );
            check(
                (nalgebra::Const::<9>, nalgebra::Const::<3>),
                &mut rng,
                &bits,
            );
            check(
                (nalgebra::Const::<9>, nalgebra::Const::<6>),
                &mut rng,
                &bits,
            );
            check(
                (nalgebra::Const::<13>, nalgebra::Const::<4>),
                &mut rng,
                &bits,
            );
            check(
                (nalgebra::Const::<21>, nalgebra::Const::<6>),
                &mut rng,
                &bits,
            );
            check((Dyn(9), Dyn(3)), &mut rng, &bits);
            check((Dyn(29), Dyn(1)), &mut rng, &bits);
        }
    }

    /// Seeded Gaussian n × c matrix.
    fn random_matrix(rng: &mut rand_chacha::ChaCha8Rng, n: usize, c: usize) -> DMatrix<f64> {
        use rand_distr::{Distribution, StandardNormal};
        DMatrix::from_fn(n, c, |_, _| StandardNormal.sample(rng))
    }

    /// Seeded random symmetric positive definite n × n matrix.
    fn random_covariance(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> DMatrix<f64> {
        let a = random_matrix(rng, n, n);
        let p = &a * a.transpose() / n as f64 + DMatrix::identity(n, n) * 0.1;
        (&p + p.transpose()) * 0.5
    }

    /// The dispatched kernels (AVX2 on a CPU that has it, in the default
    /// build) give the portable kernels' P bit for bit, exactly symmetric,
    /// and the dense products' to rounding, on random inputs of several
    /// sizes, run-time and compile-time sized.
    #[test]
    fn dispatched_kernels_equal_the_portable_ones_bit_for_bit() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
        for (n, m) in [
            (1, 1),
            (2, 1),
            (3, 2),
            (5, 3),
            (8, 4),
            (15, 6),
            (21, 6),
            (24, 8),
            (32, 6),
        ] {
            for _ in 0..3 {
                let phi = random_matrix(&mut rng, n, n) * 0.3 + DMatrix::identity(n, n);
                let p = random_covariance(&mut rng, n);
                let q = random_covariance(&mut rng, n) * 1e-3;
                // Time update: dispatched, portable, dense reference.
                let mut dispatched = q.clone();
                add_congruence(&mut dispatched, &phi, &p);
                let mut portable = q.clone();
                let mut scratch = DMatrix::zeros(n, n);
                let work = Congruence {
                    n: Dyn(n),
                    base: None,
                    p_symmetric: false,
                };
                work.run(
                    portable.as_mut_slice(),
                    scratch.as_mut_slice(),
                    phi.as_slice(),
                    p.as_slice(),
                );
                assert_eq!(dispatched, portable, "Φ P Φᵀ + Q, n = {n}");
                assert_eq!(dispatched, dispatched.transpose(), "symmetric, n = {n}");
                // Onto Q from outside, out and the scratch NaN on entry.
                let mut onto = DMatrix::repeat(n, n, f64::NAN);
                let mut phi_p = DMatrix::repeat(n, n, f64::NAN);
                congruence(&mut onto, Some(&q), &phi, &p, &mut phi_p);
                assert_eq!(onto, dispatched, "Φ P Φᵀ + Q onto Q, n = {n}");
                let reference = &phi * &p * phi.transpose() + &q;
                let scale = reference.abs().max();
                assert!(
                    (&dispatched - &reference).abs().max() <= 1e-12 * scale,
                    "n = {n}"
                );
                // Joseph update: dispatched, portable, dense reference.
                let gain = random_matrix(&mut rng, n, m) * 0.2;
                let s = random_covariance(&mut rng, m) + DMatrix::identity(m, m);
                let w = random_matrix(&mut rng, n, m);
                let (mut p_dispatched, mut v_dispatched) = (p.clone(), w.clone());
                joseph_rank_2k(
                    &mut p_dispatched,
                    None,
                    &mut v_dispatched,
                    (&gain, &s),
                    (0.5, -1.0),
                );
                let (mut p_portable, mut v_portable) = (p.clone(), w.clone());
                let work = JosephRank2k {
                    n: Dyn(n),
                    m: Dyn(m),
                    alpha: 0.5,
                    beta: -1.0,
                    prior: None,
                };
                work.run(
                    p_portable.as_mut_slice(),
                    v_portable.as_mut_slice(),
                    gain.as_slice(),
                    s.as_slice(),
                );
                assert_eq!(v_dispatched, v_portable, "V, {n}×{m}");
                assert_eq!(p_dispatched, p_portable, "Joseph P, {n}×{m}");
                assert_eq!(p_dispatched, p_dispatched.transpose());
                // Onto P from outside, out NaN on entry.
                let (mut p_onto, mut v_onto) = (DMatrix::repeat(n, n, f64::NAN), w.clone());
                joseph_rank_2k(&mut p_onto, Some(&p), &mut v_onto, (&gain, &s), (0.5, -1.0));
                assert_eq!(p_onto, p_dispatched, "Joseph P onto P⁻, {n}×{m}");
                // Innovation: P Hᵀ, H P Hᵀ and the gain solve.
                let h = measurement_test_matrix(m, n);
                let (mut cross, mut hph) = (DMatrix::zeros(n, m), DMatrix::zeros(m, m));
                measured_covariances((&mut cross, &mut hph), &p, &h);
                let mut cross_portable = DMatrix::zeros(n, m);
                MeasuredProduct::<_, _, true> {
                    n: Dyn(n),
                    m: Dyn(m),
                }
                .run(
                    cross_portable.as_mut_slice(),
                    &mut [],
                    p.as_slice(),
                    h.as_slice(),
                );
                assert_eq!(cross, cross_portable, "P Hᵀ, {n}×{m}");
                let mut hph_portable = DMatrix::zeros(m, m);
                MeasuredProduct::<_, _, false> {
                    n: Dyn(n),
                    m: Dyn(m),
                }
                .run(
                    hph_portable.as_mut_slice(),
                    &mut [],
                    h.as_slice(),
                    cross.as_slice(),
                );
                assert_eq!(hph, hph_portable, "H P Hᵀ, {n}×{m}");
                let chol = nalgebra::Cholesky::new(s.clone()).expect("positive definite");
                let mut k_dispatched = cross.clone();
                solve_gain_in_place(&mut k_dispatched, chol.l_dirty());
                let mut k_portable = cross.clone();
                GainSolve {
                    n: Dyn(n),
                    m: Dyn(m),
                }
                .run(
                    k_portable.as_mut_slice(),
                    &mut [],
                    chol.l_dirty().as_slice(),
                    &[],
                );
                assert_eq!(k_dispatched, k_portable, "gain, {n}×{m}");
                let v = &gain * &s * 0.5 - &w;
                let reference = &p + &v * gain.transpose() + &gain * v.transpose();
                let scale = reference.abs().max();
                assert!((&p_dispatched - &reference).abs().max() <= 1e-12 * scale);
            }
        }
        // Compile-time sizes (constant lengths, the bench's and the
        // navigation filters' case) against the run-time sized portable run.
        fn fixed<const N: usize>(rng: &mut rand_chacha::ChaCha8Rng) {
            let phi = random_matrix(rng, N, N) * 0.3 + DMatrix::identity(N, N);
            let p = random_covariance(rng, N);
            let q = random_covariance(rng, N) * 1e-3;
            let fixed = |m: &DMatrix<f64>| SMatrix::<f64, N, N>::from_column_slice(m.as_slice());
            let mut dispatched = fixed(&q);
            add_congruence(&mut dispatched, &fixed(&phi), &fixed(&p));
            let mut portable = q.clone();
            let mut scratch = DMatrix::zeros(N, N);
            Congruence {
                n: Dyn(N),
                base: None,
                p_symmetric: false,
            }
            .run(
                portable.as_mut_slice(),
                scratch.as_mut_slice(),
                phi.as_slice(),
                p.as_slice(),
            );
            assert_eq!(dispatched.as_slice(), portable.as_slice(), "N = {N}");
        }
        fixed::<15>(&mut rng);
        fixed::<21>(&mut rng);
        fixed::<9>(&mut rng);
    }
}
