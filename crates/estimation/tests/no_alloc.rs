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

/// The counter is global: the tests take turns so one's allocations never
/// land in the other's count.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

#[test]
fn fixed_size_predict_and_update_do_not_allocate() {
    let _turn = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
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

/// The recovery detector and the calibrated gate on fixed sizes allocate
/// nothing per measurement either (the gate's window is allocated when it
/// is built).
#[test]
fn recovery_detector_and_scaled_gate_do_not_allocate() {
    let _turn = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    use aidnav_estimation::ScaledChi2Gate;
    use aidnav_estimation::nalgebra::Const;
    use aidnav_estimation::recovery::{AgreementConfig, AgreementDetector, Refused};
    const N: usize = 21;
    const M: usize = 3;
    let phi = SMatrix::<f64, N, N>::identity();
    let p = SMatrix::<f64, N, N>::identity() * 1e-4;
    let h = SMatrix::<f64, M, N>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 });
    let r = SMatrix::<f64, M, M>::identity() * 1e-4;
    let zero = SMatrix::<f64, N, M>::zeros();
    let mut detector = AgreementDetector::<Const<N>, Const<M>>::new(AgreementConfig {
        run_length: 1000,
        probability: 0.999,
    })
    .unwrap();
    let mut gate = ScaledChi2Gate::new(0.999, 20);
    let mut kf = KalmanFilter::new(SVector::<f64, N>::zeros(), p).unwrap();
    let z = SVector::<f64, M>::from_element(0.001);
    kf.update_with(&z, &h, &r, &mut gate).unwrap();
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    for k in 0..100 {
        let nu = SVector::<f64, M>::from_element(5.0 + (k % 3) as f64 * 1e-3);
        detector.propagate(&phi);
        detector.refused(&Refused {
            residual: &nu,
            applied_residual: &nu,
            r: &r,
            h: &h,
            prior_covariance: &p,
            gain: &zero,
            posterior_covariance: &p,
        });
        detector.updated(&zero, &h);
        kf.update_with(&z, &h, &r, &mut gate).unwrap();
    }
    assert!(detector.longest_run() > 50);
    let after = ALLOCATIONS.load(Ordering::SeqCst);
    assert_eq!(after - before, 0, "{} allocations", after - before);
}
