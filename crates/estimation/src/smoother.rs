//! Rauch–Tung–Striebel fixed-interval smoother over a stored forward pass
//! (Rauch, Tung & Striebel, AIAA J. 3(8), 1965; Särkkä, *Bayesian Filtering
//! and Smoothing*, Thm 8.2).
//!
//! The forward pass stores, per epoch k, the transition Φ_k that led into it,
//! the predicted (x⁻_k, P⁻_k) and the filtered (x_k, P_k). The backward pass is
//! `C_k = P_k Φ_{k+1}ᵀ (P⁻_{k+1})⁻¹` (by Cholesky solve of P⁻_{k+1}),
//! `xˢ_k = x_k + C_k (xˢ_{k+1} − x⁻_{k+1})`,
//! `Pˢ_k = P_k + C_k (Pˢ_{k+1} − P⁻_{k+1}) C_kᵀ`.
//!
//! [`rts_smooth`] keeps every epoch (three N×N matrices each).
//! [`RtsRecorder`] computes the same smoothed estimates at the epochs the
//! caller marks, from a store that grows only with the marks: it is fed the
//! forward pass as it happens and composes the backward pass's affine maps
//! between marks (see its documentation for the algebra).

use nalgebra::{
    Cholesky, DefaultAllocator, Dim, OMatrix, OVector, SMatrix, SVector, allocator::Allocator,
};

use crate::check;
use crate::dense::{
    Widened, mirror_lower_slice, push_lower_triangle, read_lower_triangle, run_widest,
};
use crate::error::{EstimationError, Matrix, Result, Step};
use crate::structured::{TrailingDiagonal, times_transpose};

/// One epoch of a stored forward pass.
#[derive(Debug, Clone, PartialEq)]
pub struct ForwardEpoch<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Transition from the previous epoch into this one (unused for the first epoch).
    pub phi: OMatrix<f64, N, N>,
    /// Predicted state x⁻_k.
    pub x_predicted: OVector<f64, N>,
    /// Predicted covariance P⁻_k.
    pub p_predicted: OMatrix<f64, N, N>,
    /// Filtered state x_k (equal to the prediction when there was no measurement).
    pub x_filtered: OVector<f64, N>,
    /// Filtered covariance P_k.
    pub p_filtered: OMatrix<f64, N, N>,
}

/// A smoothed epoch: (xˢ_k, Pˢ_k).
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothedEpoch<N: Dim>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    /// Smoothed state.
    pub x: OVector<f64, N>,
    /// Smoothed covariance.
    pub p: OMatrix<f64, N, N>,
}

/// Run the RTS backward pass over `forward` (oldest first). The last smoothed
/// epoch equals the last filtered one.
pub fn rts_smooth<N: Dim>(forward: &[ForwardEpoch<N>]) -> Result<Vec<SmoothedEpoch<N>>>
where
    DefaultAllocator: Allocator<N> + Allocator<N, N>,
{
    let Some(last) = forward.last() else {
        return Ok(Vec::new());
    };
    let mut out = Vec::with_capacity(forward.len());
    out.push(SmoothedEpoch {
        x: last.x_filtered.clone(),
        p: last.p_filtered.clone(),
    });
    for k in (0..forward.len() - 1).rev() {
        let cur = &forward[k];
        let next = &forward[k + 1];
        let later = out.last().expect("pushed before the loop");
        // A frozen state (a switched-off state: variance exactly zero, its
        // row and column zero, Φ diagonal there) is set aside by a unit
        // diagonal: P⁻ becomes block diagonal, the solve for the other
        // states is unchanged and the frozen state's gain is zero (P_k has a
        // zero row there).
        let mut p_predicted = next.p_predicted.clone();
        for i in 0..p_predicted.nrows() {
            if p_predicted[(i, i)] == 0.0 {
                p_predicted[(i, i)] = 1.0;
            }
        }
        let chol = Cholesky::new(p_predicted).ok_or(
            EstimationError::NotPositiveDefinite {
                step: Step::Smooth,
                matrix: Matrix::PPredicted,
            }
            .at_epoch(k + 1),
        )?;
        // C_kᵀ = (P⁻_{k+1})⁻¹ Φ_{k+1} P_k, since P⁻ and P_k are symmetric.
        let c = chol.solve(&(&next.phi * &cur.p_filtered)).transpose();
        let x = &cur.x_filtered + &c * (&later.x - &next.x_predicted);
        let mut p = &cur.p_filtered + &c * (&later.p - &next.p_predicted) * c.transpose();
        check::symmetrize(&mut p);
        check::finite(&x, Step::Smooth, Matrix::X).map_err(|e| e.at_epoch(k))?;
        check::finite(&p, Step::Smooth, Matrix::P).map_err(|e| e.at_epoch(k))?;
        out.push(SmoothedEpoch { x, p });
    }
    out.reverse();
    Ok(out)
}

/// The backward map from one node's smoothed estimate to an earlier mark's:
/// `xˢ_m = A xˢ_j + b`, `Pˢ_m = D + A Pˢ_j Aᵀ` (the identity map while
/// `identity`: nothing composed yet).
#[derive(Debug, Clone)]
struct BackwardMap<const N: usize> {
    /// Boxed: A ← A C swaps it with the product's buffer.
    a: Box<SMatrix<f64, N, N>>,
    b: SVector<f64, N>,
    d: SMatrix<f64, N, N>,
    identity: bool,
    /// Epoch index of the mark the map leads to.
    mark_epoch: usize,
}

impl<const N: usize> BackwardMap<N> {
    fn identity(mark_epoch: usize) -> Self {
        Self {
            a: Box::new(SMatrix::identity()),
            b: SVector::zeros(),
            d: SMatrix::zeros(),
            identity: true,
            mark_epoch,
        }
    }

    /// Apply to a later smoothed estimate: `(A x + b, D + (A P) Aᵀ)`.
    fn apply(
        &self,
        x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
    ) -> (SVector<f64, N>, SMatrix<f64, N, N>) {
        if self.identity {
            return (*x, *p);
        }
        let mut ps = SMatrix::<f64, N, N>::zeros();
        copy_matrix(&mut ps, &self.d);
        let mut t = SMatrix::<f64, N, N>::zeros();
        product(&mut t, &self.a, p);
        symmetric_product::<N, false>(&mut ps, &t, &self.a);
        (*self.a * x + self.b, ps)
    }
}

/// Compose one RTS step from node j to the next node k,
/// `xˢ_j = C xˢ_k + β`, `Pˢ_j = Δ + C Pˢ_k Cᵀ` with
/// `C = P_j Φᵀ (P⁻_k)⁻¹`, `β = x_j − C x⁻_k`, `Δ = P_j − C P⁻_k Cᵀ`, into
/// `map`: `A ← A C`, `b ← b + A β`, `D ← D + A Δ Aᵀ` (C, β, Δ on an
/// identity map). None, the map untouched, when P⁻_k is not positive
/// definite.
///
/// Z = P_j Φᵀ (the cross-covariance of x_j and x_k) at the cost of Φ's
/// full rows; P⁻_k = L Lᵀ; C = Z L⁻ᵀ L⁻¹ by two triangular solves from the
/// right (W = Z L⁻ᵀ, then C = W L⁻¹), and C P⁻_k Cᵀ = W Wᵀ. Symmetric
/// products as lower triangles. Every element is the same sum, in the same
/// order, as in the step and composition the recorder made with nalgebra's
/// Cholesky and dense products before (a test keeps that form and checks
/// bit for bit). The N³ kernels run through [`run_widest`], each a function
/// of its own whose operands are its arguments (so that the compiler keeps
/// a column in registers).
fn compose_step<const N: usize>(
    map: &mut BackwardMap<N>,
    (x_j, p_j): (&SVector<f64, N>, &SMatrix<f64, N, N>),
    (phi, full_rows): (&SMatrix<f64, N, N>, usize),
    (x_predicted, p_predicted): (&SVector<f64, N>, &SMatrix<f64, N, N>),
    scratch: &mut StepScratch<N>,
) -> Option<()> {
    let StepScratch { l, w, c, delta, t } = scratch;
    let mut positive = [0.0];
    run_widest(
        CholeskyKernel::<N>,
        l.as_mut_slice(),
        &mut positive,
        p_predicted.as_slice(),
        &[],
    );
    if positive[0] != 1.0 {
        return None;
    }
    run_widest(
        TimesTranspose::<N> { full_rows },
        w.as_mut_slice(),
        &mut [],
        p_j.as_slice(),
        phi.as_slice(),
    );
    run_widest(
        SolveLowerTransposed::<N>,
        w.as_mut_slice(),
        &mut [],
        l.as_slice(),
        &[],
    );
    if map.identity {
        // C, Δ straight into the map.
        run_widest(
            SolveLower::<N>,
            map.a.as_mut_slice(),
            &mut [],
            l.as_slice(),
            w.as_slice(),
        );
        map.b = x_j - *map.a * x_predicted;
        subtract_gram(&mut map.d, p_j, w);
        map.identity = false;
        return Some(());
    }
    run_widest(
        SolveLower::<N>,
        c.as_mut_slice(),
        &mut [],
        l.as_slice(),
        w.as_slice(),
    );
    let beta = x_j - **c * x_predicted;
    subtract_gram(delta, p_j, w);
    map.b += *map.a * beta;
    product(t, &map.a, delta);
    symmetric_product::<N, false>(&mut map.d, t, &map.a);
    product(t, &map.a, c);
    std::mem::swap(&mut map.a, t);
    Some(())
}

/// `out = P − W Wᵀ` (P symmetric), the lower triangle mirrored, through
/// [`run_widest`]: each lower element is P's, then loses `W(c, k) W(r, k)`
/// in increasing k.
fn subtract_gram<const N: usize>(
    out: &mut SMatrix<f64, N, N>,
    p: &SMatrix<f64, N, N>,
    w: &SMatrix<f64, N, N>,
) {
    run_widest(
        GramFrom::<N>,
        out.as_mut_slice(),
        &mut [],
        p.as_slice(),
        w.as_slice(),
    );
}

/// [`subtract_gram`]'s kernel: `out` = P − W Wᵀ, `a` = P, `b` = W.
struct GramFrom<const N: usize>;

impl<const N: usize> Widened for GramFrom<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let (out, p, w) = (&mut out[..N * N], &a[..N * N], &b[..N * N]);
        // P's lower triangle (and the block rows above it, see
        // `block_row`) first, column by column (short copies), then the
        // product subtracted in place.
        for c in 0..N {
            let row0 = block_row(c);
            out[c * N + row0..(c + 1) * N].copy_from_slice(&p[c * N + row0..(c + 1) * N]);
        }
        add_symmetric_product::<N, true>(out, w, w);
    }
}

/// Buffers of one node step ([`compose_step`]): every element is written
/// before it is read, so they are kept from step to step (no N × N
/// matrix is zeroed or copied per node).
#[derive(Debug, Clone)]
struct StepScratch<const N: usize> {
    /// Cholesky factor of P⁻ (lower triangle).
    l: SMatrix<f64, N, N>,
    /// W = P_j Φᵀ L⁻ᵀ.
    w: SMatrix<f64, N, N>,
    /// C = W L⁻¹.
    c: Box<SMatrix<f64, N, N>>,
    /// Δ = P_j − W Wᵀ.
    delta: SMatrix<f64, N, N>,
    /// A Δ, then A C (swapped into the map).
    t: Box<SMatrix<f64, N, N>>,
}

impl<const N: usize> StepScratch<N> {
    fn new() -> Box<Self> {
        Box::new(Self {
            l: SMatrix::zeros(),
            w: SMatrix::zeros(),
            c: Box::new(SMatrix::zeros()),
            delta: SMatrix::zeros(),
            t: Box::new(SMatrix::zeros()),
        })
    }
}

/// `dst ← src` in two halves. A 21 × 21 matrix is 3528 bytes; glibc's
/// `memcpy` copies blocks above 2112 bytes with `rep movsb` on CPUs with
/// fast short `rep movsb`, which some (AMD Zen 4) run several times slower
/// at some relative alignments of source and destination (measured here:
/// a quarter of the recorder's time in `rep movsb`); halves of at most
/// 2112 bytes take glibc's vector loop. Same values, bit for bit.
#[inline(always)]
pub fn copy_matrix<const N: usize>(dst: &mut SMatrix<f64, N, N>, src: &SMatrix<f64, N, N>) {
    let (d, s) = (dst.as_mut_slice(), src.as_slice());
    let half = N * N / 2;
    d[..half].copy_from_slice(&s[..half]);
    d[half..].copy_from_slice(&s[half..]);
}

/// `out = a b` (N × N), as nalgebra's `gemm` computes it (each column from zero,
/// gaining `a(·, k) b(k, j)` in increasing k), through [`run_widest`].
fn product<const N: usize>(
    out: &mut SMatrix<f64, N, N>,
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, N>,
) {
    run_widest(
        Product::<N>,
        out.as_mut_slice(),
        &mut [],
        a.as_slice(),
        b.as_slice(),
    );
}

/// [`symmetric_product`] through [`run_widest`].
fn symmetric_product<const N: usize, const SUBTRACT: bool>(
    s: &mut SMatrix<f64, N, N>,
    x: &SMatrix<f64, N, N>,
    y: &SMatrix<f64, N, N>,
) {
    run_widest(
        SymmetricProduct::<N, SUBTRACT>,
        s.as_mut_slice(),
        &mut [],
        x.as_slice(),
        y.as_slice(),
    );
}

/// [`product`]'s kernel: `out` = a b, `a`, `b` (N × N column-major).
struct Product<const N: usize>;

impl<const N: usize> Widened for Product<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let (out, a, b) = (&mut out[..N * N], &a[..N * N], &b[..N * N]);
        for j in 0..N {
            let oc = &mut out[j * N..(j + 1) * N];
            oc.fill(0.0);
            for k in 0..N {
                let f = b[j * N + k];
                for (o, &x) in oc.iter_mut().zip(&a[k * N..(k + 1) * N]) {
                    *o += x * f;
                }
            }
        }
    }
}

/// [`add_symmetric_product`]'s kernel: `out` = S, `a` = X, `b` = Y.
struct SymmetricProduct<const N: usize, const SUBTRACT: bool>;

impl<const N: usize, const SUBTRACT: bool> Widened for SymmetricProduct<N, SUBTRACT> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        add_symmetric_product::<N, SUBTRACT>(&mut out[..N * N], &a[..N * N], &b[..N * N]);
    }
}

/// The Cholesky factor of P⁻ with its frozen states set aside: `a` = P⁻,
/// `out` = L (the lower triangle of P⁻, a zero diagonal element made 1,
/// factored by [`cholesky_lower_in_place`]; the upper triangle not
/// written); `scratch[0]` = 1 when every pivot was positive, 0 otherwise.
///
/// A frozen state (variance exactly zero, its row and column zero, Φ
/// diagonal there) is set aside by the unit diagonal, as in
/// [`rts_smooth`]: its gain is zero.
struct CholeskyKernel<const N: usize>;

impl<const N: usize> Widened for CholeskyKernel<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], scratch: &mut [f64], a: &[f64], _: &[f64]) {
        let (l, p) = (&mut out[..N * N], &a[..N * N]);
        for j in 0..N {
            l[j * N + j..(j + 1) * N].copy_from_slice(&p[j * N + j..(j + 1) * N]);
            if l[j * N + j] == 0.0 {
                l[j * N + j] = 1.0;
            }
        }
        scratch[0] = if cholesky_lower_in_place::<N>(l) {
            1.0
        } else {
            0.0
        };
    }
}

/// [`solve_right_lower_transposed`]'s kernel: `out` = W, `a` = L.
struct SolveLowerTransposed<const N: usize>;

impl<const N: usize> Widened for SolveLowerTransposed<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], _: &[f64]) {
        solve_right_lower_transposed::<N>(&a[..N * N], &mut out[..N * N]);
    }
}

/// [`solve_right_lower`]'s kernel from W: `out` = C, `a` = L, `b` = W
/// (each column of C starts as W's).
struct SolveLower<const N: usize>;

impl<const N: usize> Widened for SolveLower<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        solve_right_lower::<N>(&a[..N * N], Some(&b[..N * N]), &mut out[..N * N]);
    }
}

/// [`times_transpose`]'s kernel (`out = S Φᵀ` for a Φ whose rows from
/// `full_rows` on are diagonal): `a` = S, `b` = Φ.
struct TimesTranspose<const N: usize> {
    full_rows: usize,
}

impl<const N: usize> Widened for TimesTranspose<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        times_transpose(
            N,
            self.full_rows,
            &a[..N * N],
            &b[..N * N],
            &mut out[..N * N],
        );
    }
}

/// The Cholesky factor L of a symmetric N × N matrix (column-major; its
/// lower triangle read) in place of its lower triangle, the elements above
/// the diagonal left as they were; false when a pivot is not positive (or
/// not a number). nalgebra's `Cholesky::new` operation for operation:
/// column j first loses `L(j, k) L(j.., k)` for k = 0, 1, …, j − 1 in turn,
/// then its diagonal becomes the square root d and the rest is divided by d.
///
/// The columns go in the blocks of four of [`add_symmetric_product`], each
/// column worked on in a local array of constant length from its block's
/// first row (kept in registers while k runs, where a column of varying
/// length went through memory at every k); the rows above the diagonal
/// computed on the way are not stored. Each stored element is the same
/// sum in the same order.
#[inline(always)]
pub(crate) fn cholesky_lower_in_place<const N: usize>(m: &mut [f64]) -> bool {
    let m = &mut m[..N * N];
    // Separate calls, as in `add_symmetric_product`.
    let block = |b: usize| (b, b..(b + 4).min(N));
    cholesky_columns::<N>(m, block(0))
        && (N <= 4 || cholesky_columns::<N>(m, block(4)))
        && (N <= 8 || cholesky_columns::<N>(m, block(8)))
        && (N <= 12 || cholesky_columns::<N>(m, block(12)))
        && (N <= 16 || cholesky_columns::<N>(m, block(16)))
        && (N <= 20 || cholesky_columns::<N>(m, block(20)))
        && (N <= 24 || cholesky_columns::<N>(m, block(24)))
        && (N <= 28 || cholesky_columns::<N>(m, block(28)))
        && (N <= 32
            || (32..N)
                .step_by(4)
                .all(|b| cholesky_columns::<N>(m, block(b))))
}

/// Columns `cols` of [`cholesky_lower_in_place`], each computed from row
/// `row0` (at or above its diagonal) on; false at a pivot that is not
/// positive.
#[inline(always)]
fn cholesky_columns<const N: usize>(
    m: &mut [f64],
    (row0, cols): (usize, std::ops::Range<usize>),
) -> bool {
    for j in cols {
        let mut acc = [0.0; N];
        let acc = &mut acc[row0..];
        acc.copy_from_slice(&m[j * N + row0..(j + 1) * N]);
        for k in 0..j {
            let f = m[k * N + j];
            for (a, b) in acc.iter_mut().zip(&m[k * N + row0..(k + 1) * N]) {
                *a -= f * b;
            }
        }
        let cj = &mut acc[j - row0..];
        let d = cj[0];
        if d.is_nan() || d <= 0.0 {
            return false;
        }
        let d = d.sqrt();
        cj[0] = d;
        for a in &mut cj[1..] {
            *a /= d;
        }
        m[j * N + j..(j + 1) * N].copy_from_slice(cj);
    }
    true
}

/// `W ← W L⁻ᵀ` (solve `W Lᵀ = Z` in place, L lower triangular with a
/// non-zero diagonal, column-major; only its lower triangle is read),
/// column by column: `W_j = (Z_j − Σ_{k<j} L_jk W_k) / L_jj`. Whole columns
/// at a time, so the inner loops run over contiguous memory; each column
/// in a local array while k runs (in registers: a column of the matrix
/// itself was stored back at every k, the compiler not knowing that the
/// columns it reads are others).
#[inline(always)]
fn solve_right_lower_transposed<const N: usize>(l: &[f64], w: &mut [f64]) {
    let (l, w) = (&l[..N * N], &mut w[..N * N]);
    for j in 0..N {
        let mut wj = [0.0; N];
        wj.copy_from_slice(&w[j * N..(j + 1) * N]);
        for k in 0..j {
            let f = l[k * N + j];
            for (a, b) in wj.iter_mut().zip(&w[k * N..(k + 1) * N]) {
                *a -= f * b;
            }
        }
        let d = l[j * N + j];
        for a in &mut wj {
            *a /= d;
        }
        w[j * N..(j + 1) * N].copy_from_slice(&wj);
    }
}

/// `C ← C L⁻¹` (solve `C L = W` in place, L lower triangular with a
/// non-zero diagonal, column-major; only its lower triangle is read), from
/// the last column: `C_j = (W_j − Σ_{k>j} L_kj C_k) / L_jj`. With `w`,
/// column j of C is W's column j before it is solved (C = W L⁻¹ out of
/// place). Each column in a local array while k runs, as in
/// [`solve_right_lower_transposed`].
#[inline(always)]
fn solve_right_lower<const N: usize>(l: &[f64], w: Option<&[f64]>, c: &mut [f64]) {
    let (l, c) = (&l[..N * N], &mut c[..N * N]);
    for j in (0..N).rev() {
        let mut cj = [0.0; N];
        cj.copy_from_slice(match w {
            Some(w) => &w[j * N..(j + 1) * N],
            None => &c[j * N..(j + 1) * N],
        });
        for k in j + 1..N {
            let f = l[j * N + k];
            for (a, b) in cj.iter_mut().zip(&c[k * N..(k + 1) * N]) {
                *a -= f * b;
            }
        }
        let d = l[j * N + j];
        for a in &mut cj {
            *a /= d;
        }
        c[j * N..(j + 1) * N].copy_from_slice(&cj);
    }
}

/// `S ← S + X Yᵀ` (`S ← S − X Yᵀ` when `SUBTRACT`; column-major N × N) for
/// a product known to be symmetric (S symmetric on entry): the lower
/// triangle is computed, the upper one mirrored from it, so S leaves
/// exactly symmetric. Each lower element gains `Y(c, k) X(r, k)` (loses
/// it: the same as gaining `Y(c, k) (−X(r, k))`) in increasing k; the
/// columns go in blocks of four whose rows start at the block's first
/// column ([`block_row`]; the elements above the diagonal computed on the
/// way are overwritten by the mirror), so each column stays in registers
/// while k runs — the same sums, faster than columns of varying length
/// (blocks of four columns compute fewer elements above the diagonal than
/// the four blocks of `dense::lower_block_starts`: 261 against 279 per k for
/// 21 states).
#[inline(always)]
fn add_symmetric_product<const N: usize, const SUBTRACT: bool>(
    s: &mut [f64],
    x: &[f64],
    y: &[f64],
) {
    // Separate calls, not a loop (nor a closure, through which the
    // compiler kept the columns in memory), up to 32 states: each inlines
    // with its own constant row count (`N > …` is known at compile time).
    let block = |b: usize| (b, b..(b + 4).min(N));
    add_product_columns::<N, SUBTRACT>(block(0), x, y, s);
    if N > 4 {
        add_product_columns::<N, SUBTRACT>(block(4), x, y, s);
    }
    if N > 8 {
        add_product_columns::<N, SUBTRACT>(block(8), x, y, s);
    }
    if N > 12 {
        add_product_columns::<N, SUBTRACT>(block(12), x, y, s);
    }
    if N > 16 {
        add_product_columns::<N, SUBTRACT>(block(16), x, y, s);
    }
    if N > 20 {
        add_product_columns::<N, SUBTRACT>(block(20), x, y, s);
    }
    if N > 24 {
        add_product_columns::<N, SUBTRACT>(block(24), x, y, s);
    }
    if N > 28 {
        add_product_columns::<N, SUBTRACT>(block(28), x, y, s);
    }
    for b in (32..N).step_by(4) {
        add_product_columns::<N, SUBTRACT>(block(b), x, y, s);
    }
    mirror_lower_slice(N, s);
}

/// The first row [`add_symmetric_product`] computes in column `c`: its
/// block's first column (c rounded down to a multiple of four).
#[inline(always)]
const fn block_row(c: usize) -> usize {
    c & !3
}

/// Columns `cols`, rows `row0..N`, of `S += X Yᵀ` (`S −= X Yᵀ` when
/// `SUBTRACT`; column-major slices).
#[inline(always)]
fn add_product_columns<const N: usize, const SUBTRACT: bool>(
    (row0, cols): (usize, std::ops::Range<usize>),
    x: &[f64],
    y: &[f64],
    s: &mut [f64],
) {
    for c in cols {
        let sc = &mut s[c * N + row0..(c + 1) * N];
        for k in 0..N {
            let f = y[k * N + c];
            let xk = &x[k * N + row0..(k + 1) * N];
            for (a, b) in sc.iter_mut().zip(xk) {
                if SUBTRACT {
                    *a -= f * b;
                } else {
                    *a += f * b;
                }
            }
        }
    }
}

/// `Φ Φ_acc` for a Φ whose rows from `full_rows` on are diagonal, through
/// [`run_widest`]: `out` = the product, `a` = Φ, `b` = Φ_acc. Element
/// (i, j) is `0 + Σ_k Φ(i, k) Φ_acc(k, j)` in increasing k, as the dense
/// product; a diagonal row's sum is `0 + Φ(i, i) Φ_acc(i, j)` plus exact
/// zeros (finite operands), which is exactly that product after `0 +`. So
/// the full rows are computed in a block of a constant number of rows (a
/// multiple of four at or above `full_rows`, the column in registers; the
/// diagonal rows in it as dense sums, the same numbers) and the remaining
/// rows by their one product.
struct TransitionProduct<const N: usize> {
    full_rows: usize,
}

impl<const N: usize> Widened for TransitionProduct<N> {
    #[inline(always)]
    fn run(self, out: &mut [f64], _: &mut [f64], a: &[f64], b: &[f64]) {
        let (out, phi, acc) = (&mut out[..N * N], &a[..N * N], &b[..N * N]);
        // Four calls with constant row counts (each inlines with its own).
        match self.full_rows.div_ceil(4) {
            0 => rows_times::<N, 0>(phi, acc, out),
            1 if N >= 4 => rows_times::<N, 4>(phi, acc, out),
            2 if N >= 8 => rows_times::<N, 8>(phi, acc, out),
            3 if N >= 12 => rows_times::<N, 12>(phi, acc, out),
            _ => rows_times::<N, N>(phi, acc, out),
        }
    }
}

/// [`TransitionProduct`] with its first `R` rows as dense sums.
#[inline(always)]
fn rows_times<const N: usize, const R: usize>(phi: &[f64], b: &[f64], out: &mut [f64]) {
    for j in 0..N {
        let oc = &mut out[j * N..(j + 1) * N];
        let bc = &b[j * N..(j + 1) * N];
        let (full, diagonal) = oc.split_at_mut(R);
        full.fill(0.0);
        for (k, &f) in bc.iter().enumerate() {
            for (o, &p) in full.iter_mut().zip(&phi[k * N..k * N + R]) {
                *o += p * f;
            }
        }
        for (i, o) in diagonal.iter_mut().enumerate() {
            *o = 0.0 + phi[(R + i) * N + R + i] * bc[R + i];
        }
    }
}

/// Append a completed map to the store as its slot `i` (a new chunk when
/// it starts one). A chunk is reserved whole and filled by appending, so
/// its memory is written once (not zero-filled first) and never moves.
fn store<const N: usize>(chunks: &mut Vec<Vec<f64>>, i: usize, map: &BackwardMap<N>) {
    let stride = floats_per_mark(N);
    if i.is_multiple_of(MARKS_PER_CHUNK) {
        chunks.push(Vec::with_capacity(MARKS_PER_CHUNK * stride));
    }
    let out = chunks.last_mut().expect("a chunk was pushed for slot 0");
    debug_assert_eq!(out.len(), (i % MARKS_PER_CHUNK) * stride);
    let a = map.a.as_slice();
    let half = N * N / 2;
    // In halves, as `copy_matrix` (glibc's `rep movsb` above 2112 bytes).
    out.extend_from_slice(&a[..half]);
    out.extend_from_slice(&a[half..]);
    out.extend_from_slice(map.b.as_slice());
    push_lower_triangle(&map.d, out);
    // Exact: an epoch index is far below 2⁵³.
    out.push(map.mark_epoch as f64);
}

/// The stored map of mark `i` into `map`.
fn load<const N: usize>(chunks: &[Vec<f64>], i: usize, map: &mut BackwardMap<N>) {
    let stride = floats_per_mark(N);
    let (chunk, slot) = (i / MARKS_PER_CHUNK, i % MARKS_PER_CHUNK);
    let v = &chunks[chunk][slot * stride..(slot + 1) * stride];
    let (a, rest) = v.split_at(N * N);
    let (b, rest) = rest.split_at(N);
    let (d_packed, epoch) = rest.split_at(N * (N + 1) / 2);
    let half = N * N / 2;
    map.a.as_mut_slice()[..half].copy_from_slice(&a[..half]);
    map.a.as_mut_slice()[half..].copy_from_slice(&a[half..]);
    map.b.copy_from_slice(b);
    read_lower_triangle(d_packed, &mut map.d);
    map.identity = false;
    map.mark_epoch = epoch[0] as usize;
}

/// The error of a P⁻ that is not positive definite at `epoch`.
fn not_positive_definite(epoch: usize) -> EstimationError {
    EstimationError::NotPositiveDefinite {
        step: Step::Smooth,
        matrix: Matrix::PPredicted,
    }
    .at_epoch(epoch)
}

/// Marked epochs per allocation of the store (one allocation per this many
/// marks, none per epoch; pages not yet written are not resident).
const MARKS_PER_CHUNK: usize = 256;

/// Floats stored per mark for N states: A (N×N), b (N), the lower triangle
/// of D (N(N+1)/2) and the mark's epoch index.
const fn floats_per_mark(n: usize) -> usize {
    n * n + n + n * (n + 1) / 2 + 1
}

/// The Rauch–Tung–Striebel smoother of [`rts_smooth`], recorded as the
/// forward pass runs and evaluated only at the epochs the caller marks.
///
/// The forward pass is a sequence of epochs k, each opened by a prediction
/// ([`predict`](Self::predict): Φ_k, x⁻_k, P⁻_k) and closed by the next one,
/// its filtered (x_k, P_k) given by [`filtered`](Self::filtered) when an
/// update changed them. Two facts make the store small:
///
/// - An epoch without an update (x_k = x⁻_k, P_k = P⁻_k) and without a mark
///   drops out exactly: with `C_k = P_k Φ_{k+1}ᵀ (P⁻_{k+1})⁻¹` and
///   `P_{k+1} = P⁻_{k+1}`, `C_k C_{k+1} = P_k (Φ_{k+2} Φ_{k+1})ᵀ (P⁻_{k+2})⁻¹`,
///   and the two covariance steps combine the same way. Between *nodes*
///   (updated, marked or last epochs) only the product of the transitions
///   is kept.
/// - Each RTS step is affine in the later smoothed estimate:
///   `xˢ_j = C xˢ_k + β`, `Pˢ_j = Δ + C Pˢ_k Cᵀ` with `β = x_j − C x⁻_k`,
///   `Δ = P_j − C P⁻_k Cᵀ`. The steps between two marks compose, as the
///   forward pass goes, into one map (A, b, D); only that is stored, one per
///   mark: [`BYTES_PER_MARK`](Self::BYTES_PER_MARK), whatever the number of
///   epochs or updates between marks.
///
/// The backward pass ([`smooth_with`](Self::smooth_with)) then applies the
/// stored maps from the last epoch back to the first mark. Equal to
/// [`rts_smooth`] at the marked epochs up to rounding (a test checks 1e-9).
/// A step that finds P⁻ not positive definite stops the recording; the
/// error is returned by the backward pass, not by the forward pass.
///
/// ```
/// use aidnav_estimation::RtsRecorder;
/// use aidnav_estimation::nalgebra::{Matrix1, Vector1};
///
/// // A random walk (q = 1) measured directly (r = 1) at every epoch.
/// let (mut x, mut p) = (Vector1::new(0.0), Matrix1::new(10.0));
/// let mut rec = RtsRecorder::<1>::new(&x, &p, 100);
/// for (k, z) in [1.0, 2.0, 1.5, 2.5].into_iter().enumerate() {
///     if k > 0 {
///         p += Matrix1::new(1.0);
///         rec.predict(&Matrix1::identity(), &x, &p);
///     }
///     let gain = p[0] / (p[0] + 1.0);
///     let x_predicted = x;
///     x[0] += gain * (z - x[0]);
///     p[0] *= 1.0 - gain;
///     rec.filtered(&x_predicted, &x, &p);
///     rec.mark();
/// }
/// let smoothed = rec.smooth().unwrap();
/// assert_eq!(smoothed.len(), 4);
/// assert_eq!(smoothed[3].x, x); // the last epoch: smoothed = filtered
/// assert!(smoothed[0].p[0] < 1.0);
/// ```
#[derive(Debug, Clone)]
pub struct RtsRecorder<const N: usize> {
    /// Index of the open (latest) epoch.
    epoch: usize,
    x_predicted: SVector<f64, N>,
    p_predicted: SMatrix<f64, N, N>,
    /// Valid when `updated` (else equal to the prediction).
    x_filtered: SVector<f64, N>,
    /// Valid when `updated`.
    p_filtered: SMatrix<f64, N, N>,
    updated: bool,
    /// The open epoch's mark (its index among the marks).
    open_mark: Option<usize>,
    /// The last closed node: its filtered (x, P).
    anchor: Option<(SVector<f64, N>, SMatrix<f64, N, N>)>,
    /// Transition from the anchor to the open epoch.
    phi: SMatrix<f64, N, N>,
    /// `phi`'s rows from this one on are diagonal (see [`TrailingDiagonal`]).
    phi_full_rows: usize,
    /// Buffers of the node step.
    scratch: Box<StepScratch<N>>,
    /// Backward map from the anchor to the latest closed mark (None before
    /// the first mark closes).
    map: Option<BackwardMap<N>>,
    /// The stored maps: mark i's leads from mark i + 1 to mark i.
    chunks: Vec<Vec<f64>>,
    stored: usize,
    marks: usize,
    max_marks: usize,
    overflow: bool,
    failed: Option<EstimationError>,
}

impl<const N: usize> RtsRecorder<N> {
    /// Bytes stored per marked epoch.
    pub const BYTES_PER_MARK: usize = floats_per_mark(N) * std::mem::size_of::<f64>();

    /// Start at epoch 0 with its (filtered) estimate; keep at most
    /// `max_marks` marks (more overflow: see [`overflowed`](Self::overflowed)).
    pub fn new(x: &SVector<f64, N>, p: &SMatrix<f64, N, N>, max_marks: usize) -> Self {
        Self {
            epoch: 0,
            x_predicted: *x,
            p_predicted: *p,
            x_filtered: *x,
            p_filtered: *p,
            updated: false,
            open_mark: None,
            anchor: None,
            phi: SMatrix::identity(),
            phi_full_rows: 0,
            scratch: StepScratch::new(),
            map: None,
            chunks: Vec::new(),
            stored: 0,
            marks: 0,
            max_marks,
            overflow: false,
            failed: None,
        }
    }

    /// Open the next epoch with its transition Φ (from the previous epoch)
    /// and prediction (x⁻, P⁻); its filtered estimate starts equal to it.
    pub fn predict(
        &mut self,
        phi: &SMatrix<f64, N, N>,
        x_predicted: &SVector<f64, N>,
        p_predicted: &SMatrix<f64, N, N>,
    ) {
        if self.overflow || self.failed.is_some() {
            return;
        }
        // The tightest structure, once per Φ: a product of two such
        // transitions has the larger number of full rows.
        let full_rows = TrailingDiagonal::of(phi).full_rows();
        self.predict_with_rows(phi, full_rows, x_predicted, p_predicted);
    }

    /// [`predict`](Self::predict) for a Φ whose rows from
    /// `structure.full_rows()` on the caller knows to be zero off the
    /// diagonal (Φ made in that form, as the smoother's worker thread
    /// rebuilds it from the rows it was sent), which saves finding Φ's
    /// structure again at every epoch. The structure is the caller's
    /// guarantee: it is checked ([`TrailingDiagonal::holds`]) in debug
    /// builds only, and a Φ without it would be smoothed as if its other
    /// elements were zero. A structure of every row finds Φ's tightest, as
    /// `predict` does.
    ///
    /// The same numbers as `predict`, bit for bit, for finite covariances:
    /// a structure looser than Φ's tightest only adds exact zero products
    /// (Φ's zeros times finite covariances) to sums that start from +0,
    /// which leaves them unchanged.
    pub fn predict_structured(
        &mut self,
        phi: &SMatrix<f64, N, N>,
        structure: TrailingDiagonal,
        x_predicted: &SVector<f64, N>,
        p_predicted: &SMatrix<f64, N, N>,
    ) {
        if self.overflow || self.failed.is_some() {
            return;
        }
        debug_assert!(structure.holds(phi), "Φ does not have the structure passed");
        let full_rows = if structure.full_rows() < N {
            structure.full_rows()
        } else {
            TrailingDiagonal::of(phi).full_rows()
        };
        self.predict_with_rows(phi, full_rows, x_predicted, p_predicted);
    }

    /// [`predict`](Self::predict) with Φ's rows from `full_rows` on
    /// diagonal.
    fn predict_with_rows(
        &mut self,
        phi: &SMatrix<f64, N, N>,
        full_rows: usize,
        x_predicted: &SVector<f64, N>,
        p_predicted: &SMatrix<f64, N, N>,
    ) {
        if self.close_open_epoch() {
            copy_matrix(&mut self.phi, phi);
            self.phi_full_rows = full_rows;
        } else if self.map.is_some() {
            // Only the steps after the first mark are ever composed.
            // Φ Φ_acc at the cost of Φ's full rows, the same products in
            // the same order as the dense product.
            let product = &mut self.scratch.delta;
            run_widest(
                TransitionProduct::<N> { full_rows },
                product.as_mut_slice(),
                &mut [],
                phi.as_slice(),
                self.phi.as_slice(),
            );
            copy_matrix(&mut self.phi, product);
            self.phi_full_rows = self.phi_full_rows.max(full_rows);
        }
        self.epoch += 1;
        self.x_predicted = *x_predicted;
        copy_matrix(&mut self.p_predicted, p_predicted);
        self.updated = false;
        self.open_mark = None;
    }

    /// The open epoch's estimates after its updates: the prediction x⁻ as
    /// the filter now expresses it (a closed-loop filter moves it by the
    /// feedback) and the filtered (x, P).
    pub fn filtered(
        &mut self,
        x_predicted: &SVector<f64, N>,
        x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
    ) {
        self.x_predicted = *x_predicted;
        self.x_filtered = *x;
        copy_matrix(&mut self.p_filtered, p);
        self.updated = true;
    }

    /// The open epoch's filtered (x, P).
    fn open_filtered(&self) -> (&SVector<f64, N>, &SMatrix<f64, N, N>) {
        if self.updated {
            (&self.x_filtered, &self.p_filtered)
        } else {
            (&self.x_predicted, &self.p_predicted)
        }
    }

    /// The open epoch's predicted state x⁻.
    pub fn x_predicted(&self) -> &SVector<f64, N> {
        &self.x_predicted
    }

    /// Index of the open epoch (0: the one [`new`](Self::new) started).
    pub fn epoch(&self) -> usize {
        self.epoch
    }

    /// Mark the open epoch for the backward pass; returns its index among
    /// the marks (the same index when marked again), None once more than
    /// `max_marks` were asked for.
    pub fn mark(&mut self) -> Option<usize> {
        if let Some(m) = self.open_mark {
            return Some(m);
        }
        if self.marks >= self.max_marks {
            self.overflow = true;
            return None;
        }
        self.open_mark = Some(self.marks);
        self.marks += 1;
        Some(self.marks - 1)
    }

    /// The open epoch's mark, if any.
    pub fn open_mark(&self) -> Option<usize> {
        self.open_mark
    }

    /// Marks so far.
    pub fn marks(&self) -> usize {
        self.marks
    }

    /// Whether more marks than `max_marks` were asked for (the backward
    /// pass is then unavailable).
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Close the open epoch; returns whether it was a node (updated or
    /// marked), which then becomes the anchor.
    fn close_open_epoch(&mut self) -> bool {
        let node = self.open_mark.is_some()
            || (self.updated
                && (self.x_filtered != self.x_predicted || self.p_filtered != self.p_predicted));
        if !node {
            return false;
        }
        if let Err(e) = self.compose_to_open() {
            self.failed = Some(e);
            return true;
        }
        if self.open_mark.is_some() {
            match self.map.as_mut() {
                Some(map) => {
                    store(&mut self.chunks, self.stored, map);
                    self.stored += 1;
                    // Composing onto an identity map overwrites A, b, D.
                    map.identity = true;
                    map.mark_epoch = self.epoch;
                }
                None => self.map = Some(BackwardMap::identity(self.epoch)),
            }
        }
        let (x, p) = if self.updated {
            (&self.x_filtered, &self.p_filtered)
        } else {
            (&self.x_predicted, &self.p_predicted)
        };
        match self.anchor.as_mut() {
            Some((ax, ap)) => {
                *ax = *x;
                copy_matrix(ap, p);
            }
            None => self.anchor = Some((*x, *p)),
        }
        true
    }

    /// Compose the step from the anchor to the open epoch into the map.
    fn compose_to_open(&mut self) -> Result<()> {
        if let (Some(map), Some((x_j, p_j))) = (self.map.as_mut(), self.anchor.as_ref()) {
            compose_step(
                map,
                (x_j, p_j),
                (&self.phi, self.phi_full_rows),
                (&self.x_predicted, &self.p_predicted),
                &mut self.scratch,
            )
            .ok_or_else(|| not_positive_definite(self.epoch))?;
        }
        Ok(())
    }

    /// The backward pass: calls `visit(mark, xˢ, Pˢ)` for every mark, the
    /// latest first. The open epoch is taken as the last epoch of the pass
    /// (its smoothed estimate is its filtered one). Allocates nothing per
    /// mark.
    pub fn smooth_with(
        &self,
        mut visit: impl FnMut(usize, &SVector<f64, N>, &SMatrix<f64, N, N>) -> Result<()>,
    ) -> Result<()> {
        if let Some(e) = &self.failed {
            return Err(e.clone());
        }
        let mut checked =
            |mark: usize, epoch: usize, x: &SVector<f64, N>, p: &SMatrix<f64, N, N>| {
                check::finite(x, Step::Smooth, Matrix::X).map_err(|e| e.at_epoch(epoch))?;
                check::finite(p, Step::Smooth, Matrix::P).map_err(|e| e.at_epoch(epoch))?;
                visit(mark, x, p)
            };
        let (mut x, mut p) = {
            let (x, p) = self.open_filtered();
            (*x, *p)
        };
        if let Some(m) = self.open_mark {
            checked(m, self.epoch, &x, &p)?;
        }
        if let Some(map) = &self.map {
            // The last closed mark, through the step to the open epoch.
            let mut map = map.clone();
            if let Some((x_j, p_j)) = &self.anchor {
                compose_step(
                    &mut map,
                    (x_j, p_j),
                    (&self.phi, self.phi_full_rows),
                    (&self.x_predicted, &self.p_predicted),
                    &mut StepScratch::new(),
                )
                .ok_or_else(|| not_positive_definite(self.epoch))?;
            }
            (x, p) = map.apply(&x, &p);
            checked(self.stored, map.mark_epoch, &x, &p)?;
        }
        let mut map = BackwardMap::identity(0);
        for i in (0..self.stored).rev() {
            load(&self.chunks, i, &mut map);
            (x, p) = map.apply(&x, &p);
            checked(i, map.mark_epoch, &x, &p)?;
        }
        Ok(())
    }

    /// The smoothed estimate of every mark, oldest first (see
    /// [`smooth_with`](Self::smooth_with)).
    pub fn smooth(&self) -> Result<Vec<SmoothedEpoch<nalgebra::Const<N>>>> {
        let mut out = Vec::with_capacity(self.marks);
        self.smooth_with(|_, x, p| {
            out.push(SmoothedEpoch { x: *x, p: *p });
            Ok(())
        })?;
        out.reverse();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dense::gemm;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The plain triangle, column by column from the diagonal down: the
    /// reference the blocked [`add_symmetric_product`] must equal to the bit.
    fn add_symmetric_product_plain<const N: usize>(
        s: &mut SMatrix<f64, N, N>,
        x: &SMatrix<f64, N, N>,
        y: &SMatrix<f64, N, N>,
    ) {
        for c in 0..N {
            for k in 0..N {
                for r in c..N {
                    s[(r, c)] += y[(c, k)] * x[(r, k)];
                }
            }
        }
        for c in 0..N {
            for r in c + 1..N {
                s[(c, r)] = s[(r, c)];
            }
        }
    }

    fn check<const N: usize>(rng: &mut ChaCha8Rng) {
        let x = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let y = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let a = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let s0 = a + a.transpose();
        let (mut blocked, mut plain) = (s0, s0);
        add_symmetric_product::<N, false>(blocked.as_mut_slice(), x.as_slice(), y.as_slice());
        add_symmetric_product_plain(&mut plain, &x, &y);
        let bits = |m: &SMatrix<f64, N, N>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&blocked), bits(&plain), "{N} states");
        assert_eq!(blocked, blocked.transpose());
    }

    fn bits<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> Vec<u64> {
        m.iter().map(|v| v.to_bits()).collect()
    }

    /// A random symmetric positive definite matrix, A Aᵀ + I/10, with its
    /// last `frozen` states frozen (zero rows and columns).
    fn covariance<const N: usize>(rng: &mut ChaCha8Rng, frozen: usize) -> SMatrix<f64, N, N> {
        let a = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let m = a * a.transpose() + SMatrix::identity() * 0.1;
        let mut m = (m + m.transpose()) * 0.5;
        for i in N - frozen..N {
            for j in 0..N {
                m[(i, j)] = 0.0;
                m[(j, i)] = 0.0;
            }
        }
        m
    }

    /// A random Φ whose rows from `full_rows` on are diagonal (a few exact
    /// zeros in the full rows too).
    fn transition<const N: usize>(rng: &mut ChaCha8Rng, full_rows: usize) -> SMatrix<f64, N, N> {
        SMatrix::from_fn(|i, j| {
            if i < full_rows {
                if rng.random_bool(0.1) {
                    0.0
                } else {
                    rng.random_range(-0.3..0.3) + if i == j { 1.0 } else { 0.0 }
                }
            } else if i == j {
                rng.random_range(0.9..1.0)
            } else {
                0.0
            }
        })
    }

    /// The RTS step and its composition as the recorder computed them
    /// before the fused [`compose_step`]: nalgebra's Cholesky, a negated
    /// copy of W, separate C, β and Δ, the map composed from them. The
    /// reference the fused step must equal to the bit.
    fn compose_reference<const N: usize>(
        map: &mut BackwardMap<N>,
        (x_j, p_j): (&SVector<f64, N>, &SMatrix<f64, N, N>),
        phi: &SMatrix<f64, N, N>,
        (x_predicted, p_predicted): (&SVector<f64, N>, &SMatrix<f64, N, N>),
    ) -> Option<()> {
        let mut pp = *p_predicted;
        for i in 0..N {
            if pp[(i, i)] == 0.0 {
                pp[(i, i)] = 1.0;
            }
        }
        let chol = Cholesky::new(pp)?;
        let l = chol.l_dirty();
        let mut w = SMatrix::<f64, N, N>::zeros();
        times_transpose(
            N,
            TrailingDiagonal::of(phi).full_rows(),
            p_j.as_slice(),
            phi.as_slice(),
            w.as_mut_slice(),
        );
        solve_right_lower_transposed::<N>(l.as_slice(), w.as_mut_slice());
        let mut delta = *p_j;
        add_symmetric_product::<N, false>(delta.as_mut_slice(), (-w).as_slice(), w.as_slice());
        let mut c = w;
        solve_right_lower::<N>(l.as_slice(), None, c.as_mut_slice());
        let beta = x_j - c * x_predicted;
        if map.identity {
            (*map.a, map.b, map.d, map.identity) = (c, beta, delta, false);
            return Some(());
        }
        map.b += *map.a * beta;
        let mut t = SMatrix::<f64, N, N>::zeros();
        gemm(&mut t, 1.0, &*map.a, &delta, 0.0);
        add_symmetric_product::<N, false>(map.d.as_mut_slice(), t.as_slice(), map.a.as_slice());
        gemm(&mut t, 1.0, &*map.a, &c, 0.0);
        *map.a = t;
        Some(())
    }

    /// [`compose_step`] with every kernel run as compiled (no
    /// [`run_widest`] dispatch): the portable build's arithmetic.
    fn compose_portable<const N: usize>(
        map: &mut BackwardMap<N>,
        (x_j, p_j): (&SVector<f64, N>, &SMatrix<f64, N, N>),
        phi: &SMatrix<f64, N, N>,
        (x_predicted, p_predicted): (&SVector<f64, N>, &SMatrix<f64, N, N>),
    ) -> Option<()> {
        let mut l = *p_predicted;
        for i in 0..N {
            if l[(i, i)] == 0.0 {
                l[(i, i)] = 1.0;
            }
        }
        if !cholesky_lower_in_place::<N>(l.as_mut_slice()) {
            return None;
        }
        let mut w = SMatrix::<f64, N, N>::zeros();
        TimesTranspose::<N> {
            full_rows: TrailingDiagonal::of(phi).full_rows(),
        }
        .run(w.as_mut_slice(), &mut [], p_j.as_slice(), phi.as_slice());
        solve_right_lower_transposed::<N>(l.as_slice(), w.as_mut_slice());
        let mut c = w;
        solve_right_lower::<N>(l.as_slice(), None, c.as_mut_slice());
        let beta = x_j - c * x_predicted;
        let mut delta = *p_j;
        add_symmetric_product::<N, true>(delta.as_mut_slice(), w.as_slice(), w.as_slice());
        if map.identity {
            (*map.a, map.b, map.d, map.identity) = (c, beta, delta, false);
            return Some(());
        }
        map.b += *map.a * beta;
        let mut t = SMatrix::<f64, N, N>::zeros();
        Product::<N>.run(
            t.as_mut_slice(),
            &mut [],
            map.a.as_slice(),
            delta.as_slice(),
        );
        add_symmetric_product::<N, false>(map.d.as_mut_slice(), t.as_slice(), map.a.as_slice());
        Product::<N>.run(t.as_mut_slice(), &mut [], map.a.as_slice(), c.as_slice());
        *map.a = t;
        Some(())
    }

    /// Three steps composed (onto the identity map, then twice onto the
    /// result) by the fused step, portable and through [`widest`], and by
    /// the reference: A, b and D bit for bit; then one map applied both
    /// ways; a P⁻ that is not positive definite is refused by both.
    fn fused_case<const N: usize>(rng: &mut ChaCha8Rng, full_rows: usize, frozen: usize) {
        let mut maps = [
            BackwardMap::<N>::identity(0),
            BackwardMap::<N>::identity(0),
            BackwardMap::<N>::identity(0),
        ];
        let mut scratch = StepScratch::<N>::new();
        for _ in 0..3 {
            let p_j = covariance::<N>(rng, frozen);
            let phi = transition::<N>(rng, full_rows);
            let x_j = SVector::<f64, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let x_predicted = SVector::<f64, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let p_predicted = covariance::<N>(rng, frozen);
            let [portable, dispatched, reference] = &mut maps;
            compose_portable(portable, (&x_j, &p_j), &phi, (&x_predicted, &p_predicted)).unwrap();
            compose_step(
                dispatched,
                (&x_j, &p_j),
                (&phi, TrailingDiagonal::of(&phi).full_rows()),
                (&x_predicted, &p_predicted),
                &mut scratch,
            )
            .unwrap();
            compose_reference(reference, (&x_j, &p_j), &phi, (&x_predicted, &p_predicted)).unwrap();
            for m in [&maps[0], &maps[1]] {
                assert_eq!(bits(&*m.a), bits(&*maps[2].a), "A, {N} states");
                assert_eq!(bits(&m.b), bits(&maps[2].b), "b, {N} states");
                assert_eq!(bits(&m.d), bits(&maps[2].d), "D, {N} states");
            }
        }
        let x = SVector::<f64, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let p = covariance::<N>(rng, 0);
        let (xa, pa) = maps[0].apply(&x, &p);
        let (xr, pr) = {
            let m = &maps[2];
            let mut ps = m.d;
            let mut t = SMatrix::<f64, N, N>::zeros();
            gemm(&mut t, 1.0, &*m.a, &p, 0.0);
            add_symmetric_product::<N, false>(ps.as_mut_slice(), t.as_slice(), m.a.as_slice());
            (*m.a * x + m.b, ps)
        };
        assert_eq!(bits(&xa), bits(&xr));
        assert_eq!(bits(&pa), bits(&pr));
        // Not positive definite: refused, the map untouched.
        let bad = -covariance::<N>(rng, 0);
        let before = bits(&*maps[0].a);
        assert!(
            compose_step(
                &mut maps[0],
                (&x, &p),
                (&SMatrix::identity(), 0),
                (&x, &bad),
                &mut scratch
            )
            .is_none()
        );
        assert_eq!(bits(&*maps[0].a), before);
        let mut reference = maps[2].clone();
        assert!(
            compose_reference(&mut reference, (&x, &p), &SMatrix::identity(), (&x, &bad)).is_none()
        );
    }

    /// A forward pass of `epochs` epochs (Φ with `full_rows` full rows,
    /// a scalar update of a rotating state in two of three epochs, a mark
    /// in one of four) fed to a recorder by `predict` and to recorders by
    /// `predict_structured` with the structure Φ was made with, looser
    /// ones and every row: the smoothed marks bit for bit the same.
    fn structured_case<const N: usize>(rng: &mut ChaCha8Rng, full_rows: usize, epochs: usize) {
        let q = SMatrix::<f64, N, N>::from_diagonal_element(1e-3);
        let (mut x, mut p) = (SVector::<f64, N>::zeros(), covariance::<N>(rng, 0));
        let structures = [full_rows, (full_rows + 1).min(N), (full_rows + 5).min(N), N];
        let mut found = RtsRecorder::<N>::new(&x, &p, epochs);
        let mut given: Vec<_> = structures
            .iter()
            .map(|_| RtsRecorder::<N>::new(&x, &p, epochs))
            .collect();
        for k in 1..epochs {
            let phi = transition::<N>(rng, full_rows);
            x = phi * x;
            p = phi * p * phi.transpose() + q;
            p = (p + p.transpose()) * 0.5;
            found.predict(&phi, &x, &p);
            for (r, &rows) in given.iter_mut().zip(&structures) {
                r.predict_structured(&phi, TrailingDiagonal::new(rows), &x, &p);
            }
            if k % 3 != 0 {
                let i = k % N;
                let x_predicted = x;
                let gain = p.column(i) / (p[(i, i)] + 0.5);
                x += gain * (rng.random_range(-1.0..1.0) - x[i]);
                p -= gain * p.row(i);
                p = (p + p.transpose()) * 0.5;
                found.filtered(&x_predicted, &x, &p);
                for r in &mut given {
                    r.filtered(&x_predicted, &x, &p);
                }
            }
            if k % 4 == 0 {
                found.mark();
                for r in &mut given {
                    r.mark();
                }
            }
        }
        let expected = found.smooth().unwrap();
        assert_eq!(expected.len(), (epochs - 1) / 4);
        for (r, rows) in given.iter().zip(structures) {
            let smoothed = r.smooth().unwrap();
            assert_eq!(smoothed.len(), expected.len());
            for (a, b) in smoothed.iter().zip(&expected) {
                assert_eq!(bits(&a.x), bits(&b.x), "x, {N}/{full_rows} given {rows}");
                assert_eq!(bits(&a.p), bits(&b.p), "P, {N}/{full_rows} given {rows}");
            }
        }
    }

    #[test]
    fn a_structure_passed_in_gives_the_bits_of_the_structure_found() {
        let mut rng = ChaCha8Rng::seed_from_u64(46);
        structured_case::<21>(&mut rng, 9, 60);
        structured_case::<21>(&mut rng, 1, 30);
        structured_case::<15>(&mut rng, 9, 30);
        structured_case::<5>(&mut rng, 2, 30);
        structured_case::<1>(&mut rng, 0, 30);
    }

    /// A structure Φ does not have is the caller's error, caught in debug
    /// builds.
    #[test]
    #[cfg(debug_assertions)]
    #[should_panic(expected = "Φ does not have the structure passed")]
    fn a_structure_phi_does_not_have_is_caught_in_debug_builds() {
        let mut rng = ChaCha8Rng::seed_from_u64(47);
        let phi = transition::<5>(&mut rng, 3);
        let p = covariance::<5>(&mut rng, 0);
        let x = SVector::<f64, 5>::zeros();
        let mut r = RtsRecorder::<5>::new(&x, &p, 4);
        r.predict_structured(&phi, TrailingDiagonal::new(1), &x, &p);
    }

    #[test]
    fn the_fused_step_equals_the_separate_step_and_composition_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(43);
        fused_case::<1>(&mut rng, 0, 0);
        fused_case::<2>(&mut rng, 1, 0);
        fused_case::<5>(&mut rng, 2, 1);
        fused_case::<15>(&mut rng, 9, 0);
        fused_case::<21>(&mut rng, 9, 0);
        fused_case::<21>(&mut rng, 9, 6);
        fused_case::<21>(&mut rng, 21, 0);
        fused_case::<21>(&mut rng, 0, 0);
    }

    #[test]
    fn the_in_place_cholesky_equals_nalgebras_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(44);
        fn one<const N: usize>(m: SMatrix<f64, N, N>) {
            let mut ours = m;
            let ok = cholesky_lower_in_place::<N>(ours.as_mut_slice());
            match Cholesky::new(m) {
                Some(c) => {
                    assert!(ok);
                    assert_eq!(bits(&ours), bits(c.l_dirty()));
                }
                None => assert!(!ok),
            }
        }
        for _ in 0..5 {
            one(covariance::<21>(&mut rng, 0));
            one(covariance::<7>(&mut rng, 0));
            one(covariance::<1>(&mut rng, 0));
            one(covariance::<38>(&mut rng, 0));
        }
        // A zero, a negative and a NaN pivot.
        one(covariance::<21>(&mut rng, 3));
        let mut m = covariance::<6>(&mut rng, 0);
        m[(3, 3)] = -1.0;
        one(m);
        m[(3, 3)] = f64::NAN;
        one(m);
    }

    #[test]
    fn the_structured_transition_product_equals_the_dense_product() {
        let mut rng = ChaCha8Rng::seed_from_u64(45);
        fn one<const N: usize>(rng: &mut ChaCha8Rng, full_rows: usize) {
            let phi = transition::<N>(rng, full_rows);
            let acc = transition::<N>(rng, full_rows) * transition::<N>(rng, full_rows);
            // The transposed form the recorder used before, and the dense
            // kernel: the same bits up to the sign of exact zeros.
            let turned = acc.transpose();
            let mut before = SMatrix::<f64, N, N>::zeros();
            times_transpose(
                N,
                TrailingDiagonal::of(&phi).full_rows(),
                turned.as_slice(),
                phi.as_slice(),
                before.as_mut_slice(),
            );
            let before = before.transpose();
            let mut dense = SMatrix::<f64, N, N>::zeros();
            gemm(&mut dense, 1.0, &phi, &acc, 0.0);
            let full_rows = TrailingDiagonal::of(&phi).full_rows();
            let mut portable = SMatrix::<f64, N, N>::zeros();
            TransitionProduct::<N> { full_rows }.run(
                portable.as_mut_slice(),
                &mut [],
                phi.as_slice(),
                acc.as_slice(),
            );
            let mut dispatched = SMatrix::<f64, N, N>::zeros();
            run_widest(
                TransitionProduct::<N> { full_rows },
                dispatched.as_mut_slice(),
                &mut [],
                phi.as_slice(),
                acc.as_slice(),
            );
            assert_eq!(bits(&portable), bits(&before), "{N}/{full_rows}");
            assert_eq!(bits(&dispatched), bits(&before), "{N}/{full_rows}");
            for (a, b) in portable.iter().zip(dense.iter()) {
                assert!(a.to_bits() == b.to_bits() || (*a == 0.0 && *b == 0.0));
            }
        }
        one::<1>(&mut rng, 0);
        one::<4>(&mut rng, 2);
        one::<15>(&mut rng, 9);
        one::<21>(&mut rng, 9);
        one::<21>(&mut rng, 21);
        one::<21>(&mut rng, 0);
    }

    #[test]
    fn the_blocked_symmetric_product_equals_the_plain_triangle_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(41);
        check::<1>(&mut rng);
        check::<3>(&mut rng);
        check::<5>(&mut rng);
        check::<8>(&mut rng);
        check::<15>(&mut rng);
        check::<21>(&mut rng);
        check::<38>(&mut rng);
    }
}
