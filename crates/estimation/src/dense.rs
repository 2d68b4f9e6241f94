//! Small dense products for the filter's hot path.
//!
//! nalgebra multiplies statically sized matrices column by column through a
//! generic gemv; at the 15–21 state sizes of navigation filters that runs at
//! about half the speed of a plain axpy kernel whose sizes the compiler sees
//! as constants (measured: 21×21·21×21 twice, 5.9 µs vs 2.7 µs). These two
//! kernels are that plain loop, over the column-major slices nalgebra stores.
//! For run-time sized matrices beyond [`SMALL_DYN`] they hand over to
//! nalgebra, whose `matrixmultiply` backend wins there.

use nalgebra::{DefaultAllocator, Dim, OMatrix, allocator::Allocator};

/// Largest run-time dimension handled by the kernels; larger `Dyn` products
/// go to nalgebra (packed, cache-blocked `matrixmultiply`).
const SMALL_DYN: usize = 32;

fn use_kernel<R: Dim, K: Dim, C: Dim>(r: usize, k: usize, c: usize) -> bool {
    let all_static =
        R::try_to_usize().is_some() && K::try_to_usize().is_some() && C::try_to_usize().is_some();
    all_static || r.max(k).max(c) <= SMALL_DYN
}

/// out = α · a · B + β · out for column-major a (r×k) and out (r×c), where
/// `b(kk, j)` reads element (kk, j) of B (k×c): B itself, or a transpose.
/// Axpy form: each output column accumulates scaled columns of a.
#[inline(always)]
fn kernel(
    (r, k, c): (usize, usize, usize),
    alpha: f64,
    a: &[f64],
    b: impl Fn(usize, usize) -> f64,
    beta: f64,
    out: &mut [f64],
) {
    for j in 0..c {
        let oc = &mut out[j * r..(j + 1) * r];
        if beta == 0.0 {
            oc.fill(0.0);
        } else if beta != 1.0 {
            oc.iter_mut().for_each(|v| *v *= beta);
        }
        for kk in 0..k {
            let s = alpha * b(kk, j);
            let ac = &a[kk * r..(kk + 1) * r];
            for (o, &x) in oc.iter_mut().zip(ac) {
                *o += x * s;
            }
        }
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
    if use_kernel::<R, K, C>(r, k, c) {
        let b = b.as_slice();
        kernel(
            (r, k, c),
            alpha,
            a.as_slice(),
            |kk, j| b[j * k + kk],
            beta,
            out.as_mut_slice(),
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
        kernel(
            (r, k, c),
            alpha,
            a.as_slice(),
            |kk, j| b[kk * c + j],
            beta,
            out.as_mut_slice(),
        );
    } else {
        out.gemm(alpha, a, &b.transpose(), beta);
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
}
