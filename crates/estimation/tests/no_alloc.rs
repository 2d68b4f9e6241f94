//! The fixed-size filter's predict and update allocate nothing: counted with
//! a global allocator wrapper (the only unsafe code in the workspace, and
//! only in this test binary), per thread, so the test harness's own
//! allocations on other threads never land in a test's count.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use aidnav_estimation::nalgebra::{SMatrix, SVector};
use aidnav_estimation::{Chi2Gate, KalmanFilter};

struct Counting;

thread_local! {
    /// Allocations made by this thread (const-initialised, no destructor:
    /// touching it from the allocator allocates nothing).
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Allocations made by the calling thread so far.
fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards every call unchanged to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // (Fails only while the thread is being torn down: not counted.)
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
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
    let before = allocations();
    for _ in 0..100 {
        kf.predict(&phi, &q).unwrap();
        let rec = kf.update(&z, &h, &r).unwrap();
        assert!(rec.nis.is_finite());
        kf.update_sequential(&z, &h, &r).unwrap();
        kf.update_with(&z, &h, &r, &mut gate).unwrap();
    }
    let after = allocations();
    assert_eq!(
        after - before,
        0,
        "{} allocations in 100 fixed-size steps",
        after - before
    );
}

/// The recovery detector allocates nothing per measurement either, nor
/// the re-acquiring limiter.
#[test]
fn recovery_detector_and_reacquiring_limiting_do_not_allocate() {
    use aidnav_estimation::MeasurementPolicy;
    use aidnav_estimation::adaptive::{AnomalyDetector, ReacquiringLimiting};
    use aidnav_estimation::nalgebra::Const;
    use aidnav_estimation::recovery::{AgreementConfig, AgreementDetector, Update};
    const N: usize = 21;
    const M: usize = 3;
    let phi = SMatrix::<f64, N, N>::identity();
    let p = SMatrix::<f64, N, N>::identity() * 1e-4;
    let h = SMatrix::<f64, M, N>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 });
    let r = SMatrix::<f64, M, M>::identity() * 1e-4;
    let zero = SMatrix::<f64, N, M>::zeros();
    let unchanged = SVector::<f64, N>::zeros();
    let mut detector = AgreementDetector::<Const<N>, Const<M>>::new(AgreementConfig {
        run_length: 1000,
        probability: 0.999,
    })
    .unwrap();
    let mut limiter = ReacquiringLimiting::new(AnomalyDetector { gamma: 9.0 });
    let mut kf = KalmanFilter::new(SVector::<f64, N>::zeros(), p).unwrap();
    let z = SVector::<f64, M>::from_element(0.5);
    let before = allocations();
    for k in 0..100 {
        // Alternately a steady step and an outlier: runs grow, branch and churn.
        let offset = if k % 3 == 0 { 40.0 + k as f64 } else { 5.0 };
        let nu = SVector::<f64, M>::from_element(offset);
        detector.propagate(&phi, 0.25);
        detector.refused(&Update {
            residual: &nu,
            state_change: &unchanged,
            r: &r,
            h: &h,
            prior_covariance: &p,
            gain: &zero,
            posterior_covariance: &p,
        });
        detector.updated(&zero, &h);
        if k % 10 == 0 {
            MeasurementPolicy::<Const<M>>::missing(&mut limiter);
        }
        kf.update_with(&z, &h, &r, &mut limiter).unwrap();
    }
    assert!(detector.longest_run() > 50);
    let after = allocations();
    assert_eq!(after - before, 0, "{} allocations", after - before);
}
