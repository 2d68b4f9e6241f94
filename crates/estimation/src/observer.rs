//! The estimator reports; observers write.
//!
//! A filter loop hands one [`EpochRecord`] per epoch to an [`Observer`]: CSV
//! writers, plots, progress bars and in-memory collectors for tests are all
//! observers, and the loop itself never opens a file.

use nalgebra::{DMatrix, DVector};

use crate::policy::Outcome;

/// Everything a run reports for one epoch (run-time sized; missing innovation
/// components are NaN, and `dof` counts the components actually used).
#[derive(Debug, Clone, PartialEq)]
pub struct EpochRecord {
    /// Zero-based epoch index.
    pub epoch: usize,
    /// Time tag of the epoch, in the caller's unit (seconds by convention).
    pub time: f64,
    /// State estimate after the update.
    pub state: DVector<f64>,
    /// 1σ of each state (√ of the covariance diagonal).
    pub sigma: DVector<f64>,
    /// Full covariance, when the run was asked to keep it.
    pub covariance: Option<DMatrix<f64>>,
    /// Innovation per measurement component (NaN where missing).
    pub innovation: DVector<f64>,
    /// Innovation σ per component, √S_ii (NaN where missing).
    pub innovation_sigma: DVector<f64>,
    /// Normalised innovation squared over the present components (NaN if none).
    pub nis: f64,
    /// Number of measurement components present.
    pub dof: usize,
    /// What the update did.
    pub outcome: Outcome,
}

/// Receives the records of a run (argmin's observe-init/iter/final shape).
pub trait Observer {
    /// Called once before the first epoch with the number of states and
    /// measurement components.
    fn observe_init(&mut self, _states: usize, _measurements: usize) {}
    /// Called once per epoch.
    fn observe_epoch(&mut self, record: &EpochRecord);
    /// Called once after the last epoch.
    fn observe_final(&mut self) {}
}

/// Keeps every record in memory (tests, small runs).
#[derive(Debug, Clone, Default)]
pub struct Collect {
    /// The records, in epoch order.
    pub records: Vec<EpochRecord>,
}

impl Observer for Collect {
    fn observe_epoch(&mut self, record: &EpochRecord) {
        self.records.push(record.clone());
    }
}

/// Discards everything.
#[derive(Debug, Clone, Copy, Default)]
pub struct Discard;

impl Observer for Discard {
    fn observe_epoch(&mut self, _record: &EpochRecord) {}
}

impl<T: Observer + ?Sized> Observer for &mut T {
    fn observe_init(&mut self, states: usize, measurements: usize) {
        (**self).observe_init(states, measurements);
    }
    fn observe_epoch(&mut self, record: &EpochRecord) {
        (**self).observe_epoch(record);
    }
    fn observe_final(&mut self) {
        (**self).observe_final();
    }
}

impl<A: Observer, B: Observer> Observer for (A, B) {
    fn observe_init(&mut self, states: usize, measurements: usize) {
        self.0.observe_init(states, measurements);
        self.1.observe_init(states, measurements);
    }
    fn observe_epoch(&mut self, record: &EpochRecord) {
        self.0.observe_epoch(record);
        self.1.observe_epoch(record);
    }
    fn observe_final(&mut self) {
        self.0.observe_final();
        self.1.observe_final();
    }
}
