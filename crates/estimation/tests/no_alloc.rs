//! The fixed-size filter's predict and update allocate nothing: counted with
//! a global allocator wrapper (the only unsafe code in the workspace, and
//! only in this test binary).
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use aidnav_estimation::nalgebra::{SMatrix, SVector};
use aidnav_estimation::{Chi2Gate, KalmanFilter};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards every call unchanged to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn fixed_size_predict_and_update_do_not_allocate() {
    const N: usize = 15;
    const M: usize = 6;
    let phi = SMatrix::<f64, N, N>::identity() * 0.999;
    let q = SMatrix::<f64, N, N>::identity() * 1e-4;
    let h = SMatrix::<f64, M, N>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 });
    let r = SMatrix::<f64, M, M>::identity();
    let z = SVector::<f64, M>::from_element(0.5);
    let mut kf = KalmanFilter::new(SVector::<f64, N>::zeros(), SMatrix::identity()).unwrap();
    let mut gate = Chi2Gate { probability: 0.999 };
    // Warm-up outside the count (first use of statrs' quantile may allocate).
    kf.update_with(&z, &h, &r, &mut gate).unwrap();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for _ in 0..100 {
        kf.predict(&phi, &q).unwrap();
        let rec = kf.update(&z, &h, &r).unwrap();
        assert!(rec.nis.is_finite());
        kf.update_sequential(&z, &h, &r).unwrap();
        kf.update_with(&z, &h, &r, &mut gate).unwrap();
    }
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(
        after - before,
        0,
        "{} allocations in 100 fixed-size steps",
        after - before
    );
}
