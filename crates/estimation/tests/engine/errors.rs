//! Bad matrices give errors naming the step and the matrix, never a panic or NaN.

use aidnav_estimation::nalgebra::{DMatrix, DVector, Matrix1, Vector1};
use aidnav_estimation::{
    Collect, EstimationError, KalmanFilter, LinearGaussianModel, Matrix, RunOptions, Step,
};
use proptest::prelude::*;

use crate::common::min_eigenvalue;

#[test]
fn nan_measurement_is_named() {
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    let err = kf
        .update(
            &Vector1::new(f64::NAN),
            &Matrix1::new(1.0),
            &Matrix1::new(1.0),
        )
        .unwrap_err();
    assert_eq!(
        err,
        EstimationError::NonFinite {
            step: Step::Update,
            matrix: Matrix::Z
        }
    );
    assert!(err.to_string().contains("update") && err.to_string().contains("z"));
}

#[test]
fn indefinite_innovation_covariance_is_named() {
    let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
    let err = kf
        .update(&Vector1::new(0.0), &Matrix1::new(1.0), &Matrix1::new(-5.0))
        .unwrap_err();
    assert_eq!(
        err,
        EstimationError::NotPositiveDefinite {
            step: Step::Update,
            matrix: Matrix::S
        }
    );
}

#[test]
fn overflowing_prediction_is_caught() {
    let mut kf = KalmanFilter::new(Vector1::new(1.0), Matrix1::new(1.0)).unwrap();
    let err = kf
        .predict(&Matrix1::new(1e200), &Matrix1::new(0.0))
        .unwrap_err();
    assert_eq!(
        err,
        EstimationError::NonFinite {
            step: Step::Predict,
            matrix: Matrix::P
        }
    );
}

#[test]
fn asymmetric_q_and_wrong_shapes_are_named() {
    let mut kf = KalmanFilter::new(DVector::zeros(2), DMatrix::identity(2, 2)).unwrap();
    let q = DMatrix::from_row_slice(2, 2, &[1.0, 0.5, 0.0, 1.0]);
    let err = kf.predict(&DMatrix::identity(2, 2), &q).unwrap_err();
    assert!(matches!(
        err,
        EstimationError::NotSymmetric {
            step: Step::Predict,
            matrix: Matrix::Q,
            ..
        }
    ));
    let err = kf
        .predict(&DMatrix::identity(3, 3), &DMatrix::zeros(2, 2))
        .unwrap_err();
    assert!(matches!(
        err,
        EstimationError::DimensionMismatch {
            matrix: Matrix::Phi,
            rows: 3,
            ..
        }
    ));
    let err = kf
        .update(
            &DVector::zeros(1),
            &DMatrix::zeros(1, 3),
            &DMatrix::identity(1, 1),
        )
        .unwrap_err();
    assert!(matches!(
        err,
        EstimationError::DimensionMismatch {
            matrix: Matrix::H,
            ..
        }
    ));
}

#[test]
fn run_errors_carry_the_epoch() {
    let model = LinearGaussianModel::new(
        DMatrix::identity(1, 1) * 1e200,
        DMatrix::zeros(1, 1),
        DMatrix::identity(1, 1),
        DMatrix::identity(1, 1),
        DVector::zeros(1),
        DMatrix::identity(1, 1),
    )
    .unwrap();
    let data = [[Some(1.0)], [Some(1.0)], [Some(1.0)]];
    let err = model
        .run(
            data.iter()
                .enumerate()
                .map(|(k, z)| (k as f64, z.as_slice())),
            &RunOptions::default(),
            &mut Collect::default(),
        )
        .unwrap_err();
    assert!(
        matches!(err, EstimationError::AtEpoch { epoch: 1, .. }),
        "{err}"
    );
    assert!(err.to_string().starts_with("epoch 1: predict"), "{err}");
    // The wrapped error is in the message, so it is not also the source: a
    // chain printer shows "predict" once.
    assert!(std::error::Error::source(&err).is_none());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    /// After any update with a PD prior and a PD R, P stays symmetric PSD and
    /// its trace does not grow.
    #[test]
    fn update_keeps_p_symmetric_positive(
        a in proptest::collection::vec(-3.0f64..3.0, 16),
        hv in proptest::collection::vec(-2.0f64..2.0, 8),
        rdiag in proptest::collection::vec(0.01f64..10.0, 2),
        z in proptest::collection::vec(-100.0f64..100.0, 2),
    ) {
        let a = DMatrix::from_vec(4, 4, a);
        let p0 = &a * a.transpose() + DMatrix::identity(4, 4) * 1e-3;
        let p0 = (&p0 + p0.transpose()) * 0.5;
        let h = DMatrix::from_vec(2, 4, hv);
        let r = DMatrix::from_diagonal(&DVector::from_vec(rdiag));
        let mut kf = KalmanFilter::new(DVector::zeros(4), p0.clone()).unwrap();
        kf.update(&DVector::from_vec(z), &h, &r).unwrap();
        let p = kf.covariance();
        prop_assert!((p - p.transpose()).abs().max() == 0.0);
        prop_assert!(min_eigenvalue(p) > -1e-9 * p0.abs().max());
        prop_assert!(p.trace() <= p0.trace() * (1.0 + 1e-12));
    }
}
