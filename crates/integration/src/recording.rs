//! The smoother's recording of the forward pass on a worker thread.
//!
//! [`RtsRecorder::predict`] does the recorder's arithmetic (at every node a
//! Cholesky factorisation, two triangular solves and the composition of the
//! step into the backward map, a few 21³ products) inline, which made the
//! smoother about as expensive as the forward pass it records. None of it
//! feeds back into the filter, so [`Recording`] runs it on a second thread:
//! the filter sends the recorder's calls, in batches (a wake-up per call
//! cost more than the call on a busy machine), through a bounded channel
//! and goes on, and the worker calls the same recorder in the same order — the
//! arithmetic, hence every smoothed number, is the engine's, bit for bit.
//! What the filter asks back (the marks, the open epoch's predicted state)
//! is mirrored on the filter's side by the recorder's own rules, so a call
//! never waits for the worker; only the backward pass does.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use aidnav_estimation::smoother::copy_matrix;
use aidnav_estimation::{EstimationError, RtsRecorder};
use nalgebra::{SMatrix, SVector};

/// Calls sent to the worker at once.
const BATCH: usize = 32;

/// Batches queued before the filter waits for the worker: the worker may
/// lag by `QUEUE · BATCH` calls (≈ 7 kB each for 21 states).
const QUEUE: usize = 4;

/// A prediction's Φ, x⁻, P⁻.
type Prediction<const N: usize> = (SMatrix<f64, N, N>, SVector<f64, N>, SMatrix<f64, N, N>);

/// An update's x⁻, x, P.
type Update<const N: usize> = (SVector<f64, N>, SVector<f64, N>, SMatrix<f64, N, N>);

/// A recorder call for the worker. The boxes go back to the filter with
/// their batch and are filled again (no allocation per call).
enum Call<const N: usize> {
    Predict(Box<Prediction<N>>),
    Filtered(Box<Update<N>>),
    Mark,
    /// Answer once every earlier call is done.
    Flush(SyncSender<()>),
}

/// Calls not yet sent, and the boxes of calls the worker has done.
struct Pending<const N: usize> {
    calls: Vec<Call<N>>,
    predictions: Vec<Box<Prediction<N>>>,
    updates: Vec<Box<Update<N>>>,
}

/// The worker thread and the filter's mirror of the recorder's marks.
pub(crate) struct Worker<const N: usize> {
    calls: Option<SyncSender<Vec<Call<N>>>>,
    /// Batches the worker has done, for their boxes.
    done: Receiver<Vec<Call<N>>>,
    /// Calls not yet sent (behind a lock only so that the backward pass,
    /// which takes `&self`, can send them).
    batch: Mutex<Pending<N>>,
    thread: Option<JoinHandle<()>>,
    recorder: Arc<Mutex<RtsRecorder<N>>>,
    x_predicted: SVector<f64, N>,
    open_mark: Option<usize>,
    marks: usize,
    max_marks: usize,
    overflow: bool,
}

/// An [`RtsRecorder`] fed either inline or, when a thread could be
/// started, from a worker thread (see the module's documentation). Same
/// methods, same results.
pub(crate) enum Recording<const N: usize> {
    Inline(Box<RtsRecorder<N>>),
    Background(Box<Worker<N>>),
}

impl<const N: usize> Recording<N> {
    /// [`RtsRecorder::new`], on a worker thread unless none can be started.
    pub(crate) fn new(x: &SVector<f64, N>, p: &SMatrix<f64, N, N>, max_marks: usize) -> Self {
        let recorder = Arc::new(Mutex::new(RtsRecorder::new(x, p, max_marks)));
        let (calls, queue) = sync_channel(QUEUE);
        let (returns, done) = sync_channel(1);
        let shared = Arc::clone(&recorder);
        match std::thread::Builder::new()
            .name("aidnav-smoother".into())
            .spawn(move || work(&shared, &queue, &returns))
        {
            Ok(thread) => Self::Background(Box::new(Worker {
                calls: Some(calls),
                done,
                batch: Mutex::new(Pending {
                    calls: Vec::with_capacity(BATCH),
                    predictions: Vec::new(),
                    updates: Vec::new(),
                }),
                thread: Some(thread),
                recorder,
                x_predicted: *x,
                open_mark: None,
                marks: 0,
                max_marks,
                overflow: false,
            })),
            Err(_) => {
                let recorder = Arc::try_unwrap(recorder).map_or_else(
                    |r| lock(&r).clone(),
                    |m| m.into_inner().unwrap_or_else(PoisonError::into_inner),
                );
                Self::Inline(Box::new(recorder))
            }
        }
    }

    /// [`RtsRecorder::predict`].
    pub(crate) fn predict(
        &mut self,
        phi: &SMatrix<f64, N, N>,
        x_predicted: &SVector<f64, N>,
        p_predicted: &SMatrix<f64, N, N>,
    ) {
        match self {
            Self::Inline(r) => r.predict(phi, x_predicted, p_predicted),
            Self::Background(w) => {
                // The recorder ignores every prediction after an overflow.
                if w.overflow {
                    return;
                }
                w.x_predicted = *x_predicted;
                w.open_mark = None;
                w.send_with(|pending| {
                    let mut call = pending.predictions.pop().unwrap_or_else(|| {
                        Box::new((SMatrix::zeros(), SVector::zeros(), SMatrix::zeros()))
                    });
                    copy_matrix(&mut call.0, phi);
                    call.1 = *x_predicted;
                    copy_matrix(&mut call.2, p_predicted);
                    Call::Predict(call)
                });
            }
        }
    }

    /// [`RtsRecorder::filtered`].
    pub(crate) fn filtered(
        &mut self,
        x_predicted: &SVector<f64, N>,
        x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
    ) {
        match self {
            Self::Inline(r) => r.filtered(x_predicted, x, p),
            Self::Background(w) => {
                w.x_predicted = *x_predicted;
                w.send_with(|pending| {
                    let mut call = pending.updates.pop().unwrap_or_else(|| {
                        Box::new((SVector::zeros(), SVector::zeros(), SMatrix::zeros()))
                    });
                    call.0 = *x_predicted;
                    call.1 = *x;
                    copy_matrix(&mut call.2, p);
                    Call::Filtered(call)
                });
            }
        }
    }

    /// [`RtsRecorder::mark`].
    pub(crate) fn mark(&mut self) -> Option<usize> {
        match self {
            Self::Inline(r) => r.mark(),
            Self::Background(w) => {
                if let Some(m) = w.open_mark {
                    return Some(m);
                }
                w.send_with(|_| Call::Mark);
                if w.marks >= w.max_marks {
                    w.overflow = true;
                    return None;
                }
                w.open_mark = Some(w.marks);
                w.marks += 1;
                Some(w.marks - 1)
            }
        }
    }

    /// [`RtsRecorder::open_mark`].
    pub(crate) fn open_mark(&self) -> Option<usize> {
        match self {
            Self::Inline(r) => r.open_mark(),
            Self::Background(w) => w.open_mark,
        }
    }

    /// [`RtsRecorder::overflowed`].
    pub(crate) fn overflowed(&self) -> bool {
        match self {
            Self::Inline(r) => r.overflowed(),
            Self::Background(w) => w.overflow,
        }
    }

    /// [`RtsRecorder::x_predicted`].
    pub(crate) fn x_predicted(&self) -> SVector<f64, N> {
        match self {
            Self::Inline(r) => *r.x_predicted(),
            Self::Background(w) => w.x_predicted,
        }
    }

    /// [`RtsRecorder::smooth_with`], once the worker has done every call.
    pub(crate) fn smooth_with(
        &self,
        visit: impl FnMut(usize, &SVector<f64, N>, &SMatrix<f64, N, N>) -> Result<(), EstimationError>,
    ) -> Result<(), EstimationError> {
        match self {
            Self::Inline(r) => r.smooth_with(visit),
            Self::Background(w) => {
                w.flush();
                lock(&w.recorder).smooth_with(visit)
            }
        }
    }
}

/// The recorder, whatever a panicking holder left (the worker holds it
/// only inside one recorder call).
fn lock<const N: usize>(r: &Mutex<RtsRecorder<N>>) -> std::sync::MutexGuard<'_, RtsRecorder<N>> {
    r.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The worker: the calls, in order, until the filter drops its end; each
/// batch done goes back (for its boxes) unless the filter has enough.
fn work<const N: usize>(
    recorder: &Mutex<RtsRecorder<N>>,
    batches: &Receiver<Vec<Call<N>>>,
    returns: &SyncSender<Vec<Call<N>>>,
) {
    for batch in batches.iter() {
        for call in &batch {
            match call {
                Call::Predict(a) => lock(recorder).predict(&a.0, &a.1, &a.2),
                Call::Filtered(a) => lock(recorder).filtered(&a.0, &a.1, &a.2),
                Call::Mark => {
                    lock(recorder).mark();
                }
                Call::Flush(done) => {
                    let _ = done.send(());
                }
            }
        }
        let _ = returns.try_send(batch);
    }
}

impl<const N: usize> Worker<N> {
    /// Queue the call `make` builds (from a box of a done call when there
    /// is one); send the batch when full.
    fn send_with(&self, make: impl FnOnce(&mut Pending<N>) -> Call<N>) {
        let mut pending = self.batch.lock().unwrap_or_else(PoisonError::into_inner);
        let call = make(&mut pending);
        pending.calls.push(call);
        if pending.calls.len() >= BATCH {
            self.send_batch(&mut pending);
        }
    }

    /// Send the queued calls; the next batch reuses a done one, its boxes
    /// kept for the next calls.
    fn send_batch(&self, pending: &mut Pending<N>) {
        let next = match self.done.try_recv() {
            Ok(mut done) => {
                // At most a batch of each kept (the rest freed): memory
                // stays that of the calls in flight.
                for call in done.drain(..) {
                    match call {
                        Call::Predict(b) if pending.predictions.len() < BATCH => {
                            pending.predictions.push(b);
                        }
                        Call::Filtered(b) if pending.updates.len() < BATCH => {
                            pending.updates.push(b);
                        }
                        _ => {}
                    }
                }
                done
            }
            Err(_) => Vec::with_capacity(BATCH),
        };
        let batch = std::mem::replace(&mut pending.calls, next);
        if let Some(calls) = &self.calls
            && calls.send(batch).is_err()
        {
            self.worker_died();
        }
    }

    /// Wait until the worker has done every call queued so far.
    fn flush(&self) {
        let (done, wait) = sync_channel(1);
        {
            let mut pending = self.batch.lock().unwrap_or_else(PoisonError::into_inner);
            pending.calls.push(Call::Flush(done));
            self.send_batch(&mut pending);
        }
        if wait.recv().is_err() {
            self.worker_died();
        }
    }

    /// The worker only stops early by a panic in the recorder (a bug):
    /// resurface it here rather than smooth an incomplete record.
    fn worker_died(&self) -> ! {
        panic!("the smoother's worker thread stopped (a panic in RtsRecorder)")
    }
}

impl<const N: usize> Drop for Worker<N> {
    fn drop(&mut self) {
        // Closing the channel ends the worker's loop (calls not sent are
        // dropped with it: nothing will smooth them).
        self.calls = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl<const N: usize> Clone for Recording<N> {
    /// An inline copy of the recorder as it stands after every call so far.
    fn clone(&self) -> Self {
        match self {
            Self::Inline(r) => Self::Inline(r.clone()),
            Self::Background(w) => {
                w.flush();
                Self::Inline(Box::new(lock(&w.recorder).clone()))
            }
        }
    }
}

impl<const N: usize> std::fmt::Debug for Recording<N> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Inline(r) => f.debug_tuple("Inline").field(r).finish(),
            Self::Background(w) => f
                .debug_struct("Background")
                .field("marks", &w.marks)
                .field("open_mark", &w.open_mark)
                .field("overflow", &w.overflow)
                .finish_non_exhaustive(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    /// The same forward pass (a constant-velocity model measured in
    /// position, an update in most epochs, marks in some, one mark
    /// repeated) through the worker and inline: marks, mirrored state and
    /// every smoothed number bit for bit equal; a copy taken midway
    /// smooths like an inline recorder stopped there; the mark limit
    /// overflows the same way.
    #[test]
    fn the_worker_records_exactly_what_the_recorder_does_inline() {
        let phi = Matrix2::new(1.0, 0.1, 0.0, 1.0);
        let q = Matrix2::new(1e-4, 5e-4, 5e-4, 1e-2);
        let run = |rec: &mut Recording<2>, copy_at: usize| {
            let (mut x, mut p) = (Vector2::new(0.0, 1.0), Matrix2::identity());
            let (mut marks, mut predicted) = (Vec::new(), Vec::new());
            let mut copy = None;
            for k in 1..200 {
                x = phi * x;
                p = phi * p * phi.transpose() + q;
                rec.predict(&phi, &x, &p);
                if k % 3 != 0 {
                    let z = 0.1 * k as f64 + (k as f64 * 0.7).sin() * 0.05;
                    let s = p[(0, 0)] + 0.01;
                    let gain = p.column(0) / s;
                    let x_predicted = x;
                    x += gain * (z - x[0]);
                    p -= gain * p.row(0);
                    p = (p + p.transpose()) * 0.5;
                    rec.filtered(&x_predicted, &x, &p);
                }
                if k % 4 == 0 {
                    marks.push(rec.mark());
                    marks.push(rec.mark());
                    assert_eq!(rec.open_mark(), *marks.last().unwrap());
                }
                predicted.push(rec.x_predicted());
                if k == copy_at {
                    copy = Some(rec.clone());
                }
            }
            (marks, predicted, copy, rec.overflowed())
        };
        let smoothed = |rec: &Recording<2>| {
            let mut out = Vec::new();
            rec.smooth_with(|m, x, p| {
                out.push((m, *x, *p));
                Ok(())
            })
            .map(|()| out)
        };
        for max_marks in [1000, 20] {
            let (x0, p0) = (Vector2::new(0.0, 1.0), Matrix2::identity());
            let mut background = Recording::new(&x0, &p0, max_marks);
            assert!(matches!(background, Recording::Background(_)));
            let mut inline = Recording::Inline(Box::new(RtsRecorder::new(&x0, &p0, max_marks)));
            let (marks_b, predicted_b, copy_b, over_b) = run(&mut background, 100);
            let (marks_i, predicted_i, copy_i, over_i) = run(&mut inline, 100);
            assert_eq!(marks_b, marks_i);
            assert_eq!(predicted_b, predicted_i);
            assert_eq!(over_b, over_i);
            assert_eq!(over_b, max_marks == 20);
            let (sb, si) = (smoothed(&background), smoothed(&inline));
            if over_b {
                // Past the limit there is nothing to smooth (the caller
                // checks `overflowed`); both agree on that.
                assert_eq!(
                    sb.map(|v| v.len()).unwrap_or(0),
                    si.map(|v| v.len()).unwrap_or(0)
                );
                continue;
            }
            let (sb, si) = (sb.unwrap(), si.unwrap());
            assert_eq!(sb.len(), 49);
            assert_eq!(sb, si);
            let (cb, ci) = (copy_b.unwrap(), copy_i.unwrap());
            assert!(matches!(cb, Recording::Inline(_)));
            assert_eq!(smoothed(&cb).unwrap(), smoothed(&ci).unwrap());
        }
    }
}
