//! The smoother's recording of the forward pass on a worker thread.
//!
//! [`RtsRecorder::predict`] does the recorder's arithmetic (at every node a
//! Cholesky factorisation, two triangular solves and the composition of the
//! step into the backward map, a few 21³ products) inline, which made the
//! smoother about as expensive as the forward pass it records. None of it
//! feeds back into the filter, so [`Recording`] runs it on a second thread:
//! the filter writes the recorder's calls into flat batch buffers that go
//! to the worker through a bounded channel and come back to be filled
//! again, and the worker calls the same recorder in the same order — the
//! arithmetic, hence every smoothed number, is the engine's, bit for bit.
//! What the filter asks back (the marks, the open epoch's predicted state)
//! is mirrored on the filter's side by the recorder's own rules, so a call
//! never waits for the worker; only the backward pass does.
//!
//! The filter's side is a copy per call, so it sends only what the
//! recorder cannot do without, in a form the worker expands to the same
//! bits:
//!
//! - P⁻ and P as lower triangles when they are exactly symmetric (every
//!   upper element has the bits of its mirror, which the filter's
//!   covariances do by construction); the worker mirrors them. Any other
//!   matrix goes whole.
//! - Φ's rows that can hold off-diagonal elements and its diagonal, when
//!   every other element is +0.0 (the structure of the last Φ is tried
//!   first: a transition keeps it from epoch to epoch); the worker writes
//!   the zeros. Any other Φ goes whole.
//! - A state vector that is +0.0 everywhere (the closed-loop filter's x⁻
//!   at a prediction and x after its feedback, always) as a flag in the
//!   call's tag; the worker writes the zeros.
//! - An update's call replaces the one before it when nothing came
//!   between (the recorder keeps only the latest filtered estimate of an
//!   epoch).
//! - A prediction's P⁻ is sent only when the recorder can read it: when
//!   the epoch is updated or marked (it may become a node), or ends the
//!   record (the backward pass starts from it). The filter's own P is P⁻
//!   until an update changes it, so it is not copied aside: the caller
//!   hands it over again ([`Recording::predicted_covariance`]) before
//!   anything changes or reads it (an update, a mark, the backward pass),
//!   and an epoch followed directly by the next prediction (no update, no
//!   mark: not a node, its P⁻ never read) sends Φ and x⁻ alone.

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use aidnav_estimation::{
    EstimationError, RtsRecorder, TrailingDiagonal, push_lower_triangle, read_lower_triangle,
    symmetric_bits,
};
use nalgebra::{SMatrix, SVector};

/// Floats of calls a batch holds before it goes to the worker: about 80
/// calls for 21 states (a wake-up of the worker per call cost more than
/// the call on a busy machine; 16 Ki and 64 Ki floats measured the same
/// on the drive, 64 Ki with a quarter of the wake-ups but more pages).
const BATCH_FLOATS: usize = 32 * 1024;

/// Buffers out at once (being written, queued, at the worker) before the
/// filter waits for one back: the worker may lag by about
/// `IN_FLIGHT · BATCH_FLOATS` floats (4 MiB, over a thousand calls) — the
/// memory of the hand-off whatever the log's length — so the filter does
/// not wait in the normal case, only when the worker has no core.
const IN_FLIGHT: usize = 16;

/// Call kinds, in the tag that starts each call in a batch.
const PREDICT: usize = 0;
const FILTERED: usize = 1;
const MARK: usize = 2;
/// A prediction whose P⁻ the recorder will not read (see the module's
/// documentation).
const PREDICT_WITHOUT_COVARIANCE: usize = 3;

/// A call's tag: its kind, whether its covariance is a lower triangle,
/// whether its state vector (a prediction's x⁻, an update's x) is +0.0
/// everywhere and left out and, for a prediction, Φ's full rows (N: Φ
/// whole). Small integers, exact in an f64.
fn tag(kind: usize, packed: bool, zero_state: bool, phi_rows: usize) -> f64 {
    (kind + 4 * usize::from(packed) + 8 * usize::from(zero_state) + 16 * phi_rows) as f64
}

/// `tag`'s fields back.
fn untag(t: f64) -> (usize, bool, bool, usize) {
    let t = t as usize;
    (t % 4, (t / 4) % 2 == 1, (t / 8) % 2 == 1, t / 16)
}

/// Append a state vector unless it is +0.0 everywhere (bit for bit: a −0.0
/// is sent); returns whether it was left out.
fn write_state<const N: usize>(data: &mut Vec<f64>, x: &SVector<f64, N>) -> bool {
    // Branch-free: the bits OR-ed.
    if x.iter().fold(0_u64, |a, v| a | v.to_bits()) == 0 {
        return true;
    }
    data.extend_from_slice(x.as_slice());
    false
}

/// A state vector from what [`write_state`] appended at the start of
/// `data` (nothing when `zero`) into `x`; returns the floats read.
fn read_state<const N: usize>(data: &[f64], x: &mut SVector<f64, N>, zero: bool) -> usize {
    if zero {
        x.fill(0.0);
        return 0;
    }
    x.copy_from_slice(&data[..N]);
    N
}

/// Calls for the worker, written one after another; `flush` is answered
/// once they are done.
struct Batch {
    data: Vec<f64>,
    flush: Option<SyncSender<()>>,
}

/// The batch being written and the buffers of batches the worker is done
/// with.
struct Pending<const N: usize> {
    data: Vec<f64>,
    /// Start of the last call when it is an update's (one that a next
    /// update replaces).
    last_filtered: Option<usize>,
    /// Start of the last call when it is a prediction whose P⁻ is not
    /// written yet (waiting for [`Recording::predicted_covariance`]).
    open_prediction: Option<usize>,
    /// The open prediction's P⁻ as `predict` was given it, in debug builds:
    /// what [`Recording::predicted_covariance`] must hand over again.
    #[cfg(debug_assertions)]
    p_open: Box<SMatrix<f64, N, N>>,
    free: Vec<Vec<f64>>,
    /// Buffers made: the one being written, those in `free`, and those
    /// queued, at the worker, or back but not yet taken from `returns`.
    buffers: usize,
}

/// The worker thread and the filter's mirror of the recorder's marks.
pub(crate) struct Worker<const N: usize> {
    calls: Option<SyncSender<Batch>>,
    /// Buffers of batches the worker has done.
    returns: Receiver<Vec<f64>>,
    /// Calls not yet sent (behind a lock only so that the backward pass,
    /// which takes `&self`, can send them; the calls of the forward pass
    /// take `&mut self` and reach them without locking: a lock's atomic
    /// operations wait for every store before them, the call's writes to
    /// the batch included).
    batch: Mutex<Pending<N>>,
    thread: Option<JoinHandle<()>>,
    /// Shared with the worker thread; None only while the worker is
    /// dropped (see its `Drop`).
    recorder: Option<Arc<Mutex<RtsRecorder<N>>>>,
    x_predicted: SVector<f64, N>,
    open_mark: Option<usize>,
    marks: usize,
    max_marks: usize,
    overflow: bool,
    /// Full rows of the last Φ sent by its structure (N: none).
    phi_rows: usize,
}

/// An [`RtsRecorder`] fed either inline or, when a thread could be
/// started, from a worker thread (see the module's documentation). Same
/// methods, same results.
pub(crate) enum Recording<const N: usize> {
    Inline(Box<Inline<N>>),
    Background(Box<Worker<N>>),
}

/// A recorder fed inline; in a copy of a worker's recording taken while a
/// prediction waited for its P⁻, that prediction (Φ, x⁻), made when
/// [`Recording::predicted_covariance`] or the next prediction comes.
#[derive(Debug, Clone)]
pub(crate) struct Inline<const N: usize> {
    recorder: RtsRecorder<N>,
    waiting: Option<Box<(SMatrix<f64, N, N>, SVector<f64, N>)>>,
}

impl<const N: usize> Inline<N> {
    /// A recorder with no prediction waiting.
    fn of(recorder: RtsRecorder<N>) -> Self {
        Self {
            recorder,
            waiting: None,
        }
    }

    /// The waiting prediction made, with `p_predicted` as its P⁻.
    fn make_waiting(&mut self, p_predicted: &SMatrix<f64, N, N>) {
        if let Some(w) = self.waiting.take() {
            self.recorder.predict(&w.0, &w.1, p_predicted);
        }
    }

    /// The recorder, for a call that reads the open prediction's P⁻.
    fn reading(&mut self) -> &mut RtsRecorder<N> {
        assert!(self.waiting.is_none(), "{UNSUPPLIED}");
        &mut self.recorder
    }
}

/// The panic of a call that reads a prediction's P⁻ before the caller
/// handed it over (a bug of the caller).
const UNSUPPLIED: &str = "a prediction's P⁻ was not handed over (Recording::predicted_covariance) before a call that reads it";

/// Floats of a batch buffer: a full batch and the largest call (a
/// prediction with Φ and P⁻ whole), so that a call never reallocates.
const fn buffer_floats(n: usize) -> usize {
    BATCH_FLOATS + 2 * n * n + n + 1
}

impl<const N: usize> Recording<N> {
    /// [`RtsRecorder::new`], on a worker thread unless none can be started.
    pub(crate) fn new(x: &SVector<f64, N>, p: &SMatrix<f64, N, N>, max_marks: usize) -> Self {
        let recorder = Arc::new(Mutex::new(RtsRecorder::new(x, p, max_marks)));
        let (calls, queue) = sync_channel(IN_FLIGHT);
        let (done, returns) = sync_channel(IN_FLIGHT);
        let shared = Arc::clone(&recorder);
        match std::thread::Builder::new()
            .name("aidnav-smoother".into())
            .spawn(move || work(&shared, &queue, &done))
        {
            Ok(thread) => Self::Background(Box::new(Worker {
                calls: Some(calls),
                returns,
                batch: Mutex::new(Pending {
                    data: Vec::with_capacity(buffer_floats(N)),
                    last_filtered: None,
                    open_prediction: None,
                    #[cfg(debug_assertions)]
                    p_open: Box::new(SMatrix::zeros()),
                    free: Vec::new(),
                    buffers: 1,
                }),
                thread: Some(thread),
                recorder: Some(recorder),
                x_predicted: *x,
                open_mark: None,
                marks: 0,
                max_marks,
                overflow: false,
                phi_rows: N,
            })),
            Err(_) => {
                let recorder = Arc::try_unwrap(recorder).map_or_else(
                    |r| lock(&r).clone(),
                    |m| m.into_inner().unwrap_or_else(PoisonError::into_inner),
                );
                Self::Inline(Box::new(Inline::of(recorder)))
            }
        }
    }

    /// [`RtsRecorder::predict`]. A worker's recording sends P⁻ only when
    /// [`predicted_covariance`](Self::predicted_covariance) hands it over again, which
    /// the caller must do before it changes its P or makes any other call
    /// but the next prediction.
    pub(crate) fn predict(
        &mut self,
        phi: &SMatrix<f64, N, N>,
        x_predicted: &SVector<f64, N>,
        p_predicted: &SMatrix<f64, N, N>,
    ) {
        match self {
            Self::Inline(r) => {
                // A waiting prediction followed by this one: its P⁻ is
                // never read (any P will do).
                r.make_waiting(p_predicted);
                r.recorder.predict(phi, x_predicted, p_predicted);
            }
            Self::Background(w) => {
                // The recorder ignores every prediction after an overflow.
                if w.overflow {
                    return;
                }
                w.x_predicted = *x_predicted;
                w.open_mark = None;
                let rows = w.structure_of(phi);
                w.send_with(false, |pending| {
                    let data = &mut pending.data;
                    let start = data.len();
                    data.push(0.0);
                    write_phi(data, phi, rows);
                    let zero = write_state(data, x_predicted);
                    data[start] = tag(PREDICT_WITHOUT_COVARIANCE, false, zero, rows);
                    #[cfg(debug_assertions)]
                    pending.p_open.copy_from(p_predicted);
                    #[cfg(not(debug_assertions))]
                    let _ = p_predicted;
                    pending.open_prediction = Some(start);
                    pending.last_filtered = None;
                });
            }
        }
    }

    /// The open prediction's P⁻ handed over again (the caller's P, unchanged
    /// since [`predict`](Self::predict)): written now when a prediction
    /// waits for it, else nothing. Due before the caller changes its P
    /// (an update) or makes a call that reads P⁻ ([`filtered`](Self::filtered),
    /// [`mark`](Self::mark)); those panic when it was not.
    pub(crate) fn predicted_covariance(&mut self, p_predicted: &SMatrix<f64, N, N>) {
        match self {
            Self::Inline(r) => r.make_waiting(p_predicted),
            Self::Background(w) => close_prediction(w.pending(), p_predicted),
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
            Self::Inline(r) => r.reading().filtered(x_predicted, x, p),
            Self::Background(w) => {
                w.x_predicted = *x_predicted;
                w.send_with(true, |pending| {
                    let data = &mut pending.data;
                    // The recorder's `filtered` overwrites all that the
                    // previous one set: the later call alone does the same.
                    if let Some(previous) = pending.last_filtered {
                        data.truncate(previous);
                    }
                    let start = data.len();
                    data.push(0.0);
                    data.extend_from_slice(x_predicted.as_slice());
                    let zero = write_state(data, x);
                    let packed = write_covariance(data, p);
                    data[start] = tag(FILTERED, packed, zero, 0);
                    pending.last_filtered = Some(start);
                });
            }
        }
    }

    /// [`RtsRecorder::mark`].
    pub(crate) fn mark(&mut self) -> Option<usize> {
        match self {
            Self::Inline(r) => r.reading().mark(),
            Self::Background(w) => {
                if let Some(m) = w.open_mark {
                    return Some(m);
                }
                w.send_with(true, |pending| {
                    pending.data.push(tag(MARK, false, false, 0));
                    pending.last_filtered = None;
                });
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
            Self::Inline(r) => r.recorder.open_mark(),
            Self::Background(w) => w.open_mark,
        }
    }

    /// [`RtsRecorder::overflowed`].
    pub(crate) fn overflowed(&self) -> bool {
        match self {
            Self::Inline(r) => r.recorder.overflowed(),
            Self::Background(w) => w.overflow,
        }
    }

    /// [`RtsRecorder::x_predicted`].
    pub(crate) fn x_predicted(&self) -> SVector<f64, N> {
        match self {
            Self::Inline(r) => *r.recorder.x_predicted(),
            Self::Background(w) => w.x_predicted,
        }
    }

    /// Return once the worker has done every call so far (none waits on an
    /// inline recording); `p` as for [`smooth_with`](Self::smooth_with).
    /// The backward pass then starts at once.
    pub(crate) fn catch_up(&self, p: &SMatrix<f64, N, N>) {
        if let Self::Background(w) = self {
            w.catch_up(p);
        }
    }

    /// [`RtsRecorder::smooth_with`], once the worker has done every call;
    /// `p` is the caller's P, P⁻ of an open prediction (the backward pass
    /// starts from it).
    pub(crate) fn smooth_with(
        &self,
        p: &SMatrix<f64, N, N>,
        visit: impl FnMut(usize, &SVector<f64, N>, &SMatrix<f64, N, N>) -> Result<(), EstimationError>,
    ) -> Result<(), EstimationError> {
        match self {
            Self::Inline(r) if r.waiting.is_some() => {
                let mut made = r.as_ref().clone();
                made.make_waiting(p);
                made.recorder.smooth_with(visit)
            }
            Self::Inline(r) => r.recorder.smooth_with(visit),
            Self::Background(w) => {
                w.catch_up(p);
                lock(w.recorder()).smooth_with(visit)
            }
        }
    }
}

/// Append Φ: with `rows` < N its first `rows` rows and its diagonal below
/// them, column by column (every other element is +0.0, see
/// [`Worker::structure_of`]); else whole.
fn write_phi<const N: usize>(data: &mut Vec<f64>, phi: &SMatrix<f64, N, N>, rows: usize) {
    let s = phi.as_slice();
    if rows >= N {
        data.extend_from_slice(s);
        return;
    }
    // Each column is copied whole (a copy of constant length) and the next
    // one written over its rows from `rows` on, into room reserved once:
    // an `extend_from_slice` of the first `rows` elements, a length known
    // only here, per column measured 3 % slower on the smoothed drive.
    // Room for one whole column past the end; cut off after.
    let start = data.len();
    let count = N * rows + (N - rows);
    data.resize(start + count + N, 0.0);
    let out = &mut data[start..];
    let mut at = 0;
    for (j, column) in s.chunks_exact(N).enumerate() {
        out[at..at + N].copy_from_slice(column);
        at += rows;
        if j >= rows {
            out[at] = column[j];
            at += 1;
        }
    }
    data.truncate(start + count);
}

/// Φ from what [`write_phi`] appended at the start of `data` into `phi`;
/// returns the floats read.
fn read_phi<const N: usize>(data: &[f64], phi: &mut SMatrix<f64, N, N>, rows: usize) -> usize {
    let s = phi.as_mut_slice();
    if rows >= N {
        s.copy_from_slice(&data[..N * N]);
        return N * N;
    }
    let mut at = 0;
    for (j, column) in s.chunks_exact_mut(N).enumerate() {
        column[..rows].copy_from_slice(&data[at..at + rows]);
        at += rows;
        column[rows..].fill(0.0);
        if j >= rows {
            column[j] = data[at];
            at += 1;
        }
    }
    at
}

/// Append a covariance: its lower triangle, column by column, when it is
/// exactly symmetric (bit for bit), else whole; returns whether packed.
fn write_covariance<const N: usize>(data: &mut Vec<f64>, p: &SMatrix<f64, N, N>) -> bool {
    let s = p.as_slice();
    if !symmetric_bits(s, N) {
        data.extend_from_slice(s);
        return false;
    }
    push_lower_triangle(p, data);
    true
}

/// A covariance from what [`write_covariance`] appended at the start of
/// `data` into `p`; returns the floats read. A packed one is read by
/// [`read_lower_triangle`].
fn read_covariance<const N: usize>(
    data: &[f64],
    p: &mut SMatrix<f64, N, N>,
    packed: bool,
) -> usize {
    if !packed {
        p.as_mut_slice().copy_from_slice(&data[..N * N]);
        return N * N;
    }
    read_lower_triangle(data, p)
}

/// The recorder, whatever a panicking holder left (the worker holds it
/// only while it does a batch).
fn lock<const N: usize>(r: &Mutex<RtsRecorder<N>>) -> std::sync::MutexGuard<'_, RtsRecorder<N>> {
    r.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Buffers the worker expands the calls into.
struct Expanded<const N: usize> {
    phi: SMatrix<f64, N, N>,
    x_predicted: SVector<f64, N>,
    x: SVector<f64, N>,
    p: SMatrix<f64, N, N>,
}

/// The worker: the calls, in order, until the filter drops its end; each
/// batch's buffer goes back to the filter.
fn work<const N: usize>(
    recorder: &Mutex<RtsRecorder<N>>,
    batches: &Receiver<Batch>,
    returns: &SyncSender<Vec<f64>>,
) {
    let mut e = Box::new(Expanded::<N> {
        phi: SMatrix::zeros(),
        x_predicted: SVector::zeros(),
        x: SVector::zeros(),
        p: SMatrix::zeros(),
    });
    for Batch { mut data, flush } in batches.iter() {
        {
            let mut recorder = lock(recorder);
            let mut at = 0;
            while at < data.len() {
                let (kind, packed, zero, rows) = untag(data[at]);
                at += 1;
                match kind {
                    PREDICT | PREDICT_WITHOUT_COVARIANCE => {
                        at += read_phi(&data[at..], &mut e.phi, rows);
                        at += read_state(&data[at..], &mut e.x_predicted, zero);
                        if kind == PREDICT {
                            at += read_covariance(&data[at..], &mut e.p, packed);
                        } else if cfg!(debug_assertions) {
                            // Never read by the recorder (the next call is
                            // a prediction): NaN would show in the tests.
                            e.p.fill(f64::NAN);
                        }
                        // Φ rebuilt by its structure (zeros written
                        // outside it): the recorder need not find it again.
                        recorder.predict_structured(
                            &e.phi,
                            TrailingDiagonal::new(rows),
                            &e.x_predicted,
                            &e.p,
                        );
                    }
                    FILTERED => {
                        e.x_predicted.copy_from_slice(&data[at..at + N]);
                        at += N;
                        at += read_state(&data[at..], &mut e.x, zero);
                        at += read_covariance(&data[at..], &mut e.p, packed);
                        recorder.filtered(&e.x_predicted, &e.x, &e.p);
                    }
                    _ => {
                        recorder.mark();
                    }
                }
            }
        }
        if let Some(done) = flush {
            let _ = done.send(());
        }
        data.clear();
        // The filter holds at most `IN_FLIGHT` buffers out, so this never
        // waits; an error is the filter gone.
        let _ = returns.try_send(data);
    }
}

/// Write the open prediction's P⁻ after it (its tag made a
/// [`PREDICT`]'s); nothing when no prediction is open.
fn close_prediction<const N: usize>(pending: &mut Pending<N>, p_predicted: &SMatrix<f64, N, N>) {
    if let Some(start) = pending.open_prediction.take() {
        #[cfg(debug_assertions)]
        {
            let bits = |m: &SMatrix<f64, N, N>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(
                bits(p_predicted),
                bits(&pending.p_open),
                "the P⁻ handed over is not the prediction's"
            );
        }
        let (_, _, zero, rows) = untag(pending.data[start]);
        let packed = write_covariance(&mut pending.data, p_predicted);
        pending.data[start] = tag(PREDICT, packed, zero, rows);
    }
}

impl<const N: usize> Worker<N> {
    /// The open prediction's P⁻ handed over (`p`), the calls not yet sent
    /// sent, and the worker done with all of them.
    fn catch_up(&self, p: &SMatrix<f64, N, N>) {
        self.supply(p);
        self.flush();
    }

    /// The recorder the worker thread feeds (behind its lock).
    fn recorder(&self) -> &Mutex<RtsRecorder<N>> {
        self.recorder
            .as_deref()
            .expect("the recorder is only let go when the worker is dropped")
    }

    /// Full rows by which to send `phi`: those of the last Φ when every
    /// element of `phi` outside them and the diagonal is +0.0 (the worker
    /// writes +0.0 there), else the tightest such structure of `phi`
    /// (N: none), kept for the next Φ.
    fn structure_of(&mut self, phi: &SMatrix<f64, N, N>) -> usize {
        let s = phi.as_slice();
        let zero_below = |rows: usize| {
            // The bits OR-ed over each column's rows from `rows` on, its
            // diagonal aside (two runs that vectorise).
            let or = |v: &[f64]| v.iter().fold(0_u64, |a, x| a | x.to_bits());
            let mut bits = 0_u64;
            for (j, column) in s.chunks_exact(N).enumerate() {
                bits |= if j < rows {
                    or(&column[rows..])
                } else {
                    or(&column[rows..j]) | or(&column[j + 1..])
                };
            }
            bits == 0
        };
        if self.phi_rows < N && zero_below(self.phi_rows) {
            return self.phi_rows;
        }
        // One past the last row holding anything but +0.0 off the diagonal.
        let mut rows = 0;
        for (j, column) in s.chunks_exact(N).enumerate() {
            if let Some(i) = (rows..N)
                .rev()
                .find(|&i| i != j && column[i].to_bits() != 0)
            {
                rows = i + 1;
            }
        }
        self.phi_rows = rows;
        rows
    }

    /// The calls not yet sent, without locking (see `batch`).
    fn pending(&mut self) -> &mut Pending<N> {
        self.batch.get_mut().unwrap_or_else(PoisonError::into_inner)
    }

    /// [`Recording::predicted_covariance`] for the backward pass (`&self`).
    fn supply(&self, p_predicted: &SMatrix<f64, N, N>) {
        let mut pending = self.batch.lock().unwrap_or_else(PoisonError::into_inner);
        close_prediction(&mut pending, p_predicted);
    }

    /// Append a call by `write` (which also keeps `last_filtered` and
    /// `open_prediction`), after the open prediction (whose P⁻ a call that
    /// `reads_covariance`, not the next prediction, needs handed over
    /// first) and sending the batch when full (never with a prediction
    /// open).
    fn send_with(&mut self, reads_covariance: bool, write: impl FnOnce(&mut Pending<N>)) {
        let Self {
            batch,
            calls,
            returns,
            ..
        } = self;
        let pending = batch.get_mut().unwrap_or_else(PoisonError::into_inner);
        if reads_covariance {
            assert!(pending.open_prediction.is_none(), "{UNSUPPLIED}");
        }
        pending.open_prediction = None;
        if pending.data.len() >= BATCH_FLOATS {
            send_batch(calls, returns, pending, None);
        }
        write(pending);
    }

    /// Wait until the worker has done every call queued so far (the open
    /// epoch ends the record so far: its P⁻ is read, so it must have been
    /// handed over).
    fn flush(&self) {
        let (done, wait) = sync_channel(1);
        {
            let mut pending = self.batch.lock().unwrap_or_else(PoisonError::into_inner);
            assert!(pending.open_prediction.is_none(), "{UNSUPPLIED}");
            // Nothing written since the worker gave every buffer back (it
            // gives one back after its batch, the recorder unlocked):
            // nothing to wait for. A round trip to a worker that shares
            // its core with the output writers waited for a scheduler
            // slice (3 ms on the drive) for nothing.
            while let Ok(buffer) = self.returns.try_recv() {
                pending.free.push(buffer);
            }
            if pending.data.is_empty() && pending.free.len() + 1 == pending.buffers {
                return;
            }
            send_batch(&self.calls, &self.returns, &mut pending, Some(done));
        }
        if wait.recv().is_err() {
            worker_died();
        }
    }

    /// An inline copy of the recorder after every call so far: a prediction
    /// waiting for its P⁻ is kept out of the calls the worker does first
    /// and handed to the copy as waiting too (it goes on waiting here).
    fn copy(&self) -> Inline<N> {
        let (done, wait) = sync_channel(1);
        let waiting = {
            let mut pending = self.batch.lock().unwrap_or_else(PoisonError::into_inner);
            let open = pending
                .open_prediction
                .take()
                .map(|start| pending.data.split_off(start));
            send_batch(&self.calls, &self.returns, &mut pending, Some(done));
            open.map(|call| {
                let (_, _, zero, rows) = untag(call[0]);
                let mut phi = SMatrix::zeros();
                let at = 1 + read_phi(&call[1..], &mut phi, rows);
                let mut x = SVector::zeros();
                read_state(&call[at..], &mut x, zero);
                pending.open_prediction = Some(pending.data.len());
                pending.data.extend_from_slice(&call);
                Box::new((phi, x))
            })
        };
        if wait.recv().is_err() {
            worker_died();
        }
        Inline {
            recorder: lock(self.recorder()).clone(),
            waiting,
        }
    }
}

/// Send the calls written so far (and `flush` to answer after them) on
/// `calls`; the next calls go into a buffer the worker is done with (back
/// on `returns`), or a new one while fewer than `IN_FLIGHT` are out, or
/// else the next one the worker gives back.
fn send_batch<const N: usize>(
    calls: &Option<SyncSender<Batch>>,
    returns: &Receiver<Vec<f64>>,
    pending: &mut Pending<N>,
    flush: Option<SyncSender<()>>,
) {
    while let Ok(buffer) = returns.try_recv() {
        pending.free.push(buffer);
    }
    let next = match pending.free.pop() {
        Some(buffer) => buffer,
        None if pending.buffers < IN_FLIGHT => {
            pending.buffers += 1;
            Vec::with_capacity(buffer_floats(N))
        }
        None => match returns.recv() {
            Ok(buffer) => buffer,
            Err(_) => worker_died(),
        },
    };
    let data = std::mem::replace(&mut pending.data, next);
    pending.last_filtered = None;
    if let Some(calls) = calls
        && calls.send(Batch { data, flush }).is_err()
    {
        worker_died();
    }
}

/// The worker only stops early by a panic in the recorder (a bug):
/// resurface it here rather than smooth an incomplete record.
fn worker_died() -> ! {
    panic!("the smoother's worker thread stopped (a panic in RtsRecorder)")
}

impl<const N: usize> Drop for Worker<N> {
    /// The worker thread frees the recording, on its own core: freeing its
    /// megabytes of blocks took the caller 1.5 ms of the drive's smoothing
    /// (the recording is dropped right after the backward pass, before the
    /// smoothed epochs are made and written). This side's reference goes
    /// first; closing the channel then ends the worker's loop (calls not
    /// sent are dropped with it: nothing will smooth them) and its
    /// reference, the last, frees the recorder. The thread is not joined:
    /// nothing is left to wait for (a panic in it was never reported here
    /// either), and it touches nothing after the recorder.
    fn drop(&mut self) {
        self.recorder = None;
        self.calls = None;
        drop(self.thread.take());
    }
}

impl<const N: usize> Clone for Recording<N> {
    /// An inline copy of the recorder as it stands after every call so far.
    fn clone(&self) -> Self {
        match self {
            Self::Inline(r) => Self::Inline(r.clone()),
            Self::Background(w) => Self::Inline(Box::new(w.copy())),
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
    use nalgebra::{Matrix4, Vector4};

    /// Position, velocity, an acceleration bias and a scale-like state: Φ
    /// with two full rows and a diagonal below, as the navigation filter's.
    fn transition() -> Matrix4<f64> {
        Matrix4::new(
            1.0, 0.1, 0.005, 0.0, //
            0.0, 1.0, 0.1, 0.02, //
            0.0, 0.0, 1.0, 0.0, //
            0.0, 0.0, 0.0, 0.999,
        )
    }

    /// The Φ of epoch k: mostly the structured one, some dense (an element
    /// below the full rows), some with −0.0 off the structure (which the
    /// worker must not turn into +0.0), some diagonal.
    fn transition_at(k: usize) -> Matrix4<f64> {
        let mut phi = transition();
        match k % 13 {
            5 => phi[(3, 1)] = 1e-3,
            7 => phi[(2, 0)] = -0.0,
            11 => phi = Matrix4::from_diagonal(&phi.diagonal()),
            _ => {}
        }
        phi
    }

    /// P made inexactly symmetric by an ulp in an upper element (the worker
    /// must send it whole).
    fn skewed(mut p: Matrix4<f64>) -> Matrix4<f64> {
        p[(0, 2)] = f64::from_bits(p[(0, 2)].to_bits() + 1);
        p
    }

    /// Every Φ and covariance form sent comes back with the same bits:
    /// structured, dense, −0.0 off the structure, diagonal; exactly and
    /// inexactly symmetric covariances (and a packed form is used where it
    /// applies).
    #[test]
    fn what_the_filter_writes_the_worker_reads_back_bit_for_bit() {
        let x = Vector4::new(0.0, 1.0, 2.0, 3.0);
        let p = Matrix4::from_fn(|i, j| 1.0 / (1.0 + i as f64 + j as f64));
        let mut w = match Recording::<4>::new(&x, &p, 10) {
            Recording::Background(w) => w,
            Recording::Inline(_) => panic!("no worker thread"),
        };
        let bits = |m: &Matrix4<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for k in 0..13 {
            let phi = transition_at(k);
            let rows = w.structure_of(&phi);
            let mut data = Vec::new();
            write_phi(&mut data, &phi, rows);
            let mut back = Matrix4::from_element(7.0);
            assert_eq!(read_phi(&data, &mut back, rows), data.len());
            assert_eq!(bits(&back), bits(&phi), "Φ at {k}");
            // The tightest structure bit for bit; the one sent may be the
            // last Φ's when it holds, looser.
            let tightest = match k % 13 {
                5 => 4,
                7 => 3,
                11 => 0,
                _ => 2,
            };
            assert!(rows >= tightest, "structure at {k}: {rows}");
            assert_eq!(rows == 4, tightest == 4, "structure at {k}: {rows}");
        }
        for (q, packed) in [(p, true), (skewed(p), false)] {
            let mut data = Vec::new();
            assert_eq!(write_covariance(&mut data, &q), packed);
            assert_eq!(data.len(), if packed { 10 } else { 16 });
            let mut back = Matrix4::from_element(7.0);
            assert_eq!(read_covariance(&data, &mut back, packed), data.len());
            assert_eq!(bits(&back), bits(&q));
        }
        // −0.0 against +0.0 in a mirrored pair is not symmetric bit for bit.
        let mut signed = p;
        (signed[(1, 3)], signed[(3, 1)]) = (0.0, -0.0);
        assert!(!write_covariance(&mut Vec::new(), &signed));
    }

    /// The same forward pass (a four-state model measured in position in
    /// most epochs and in velocity in some, so that two updates follow
    /// each other; marks in some epochs, one mark repeated, one between
    /// two updates; Φ in every form of [`transition_at`], covariances
    /// sometimes inexactly symmetric; long enough for many batches)
    /// through the worker and inline: marks, mirrored state and every
    /// smoothed number bit for bit equal; a copy taken midway smooths like
    /// an inline recorder stopped there; a visit that fails stops the
    /// backward pass at the same mark with its error; the mark limit
    /// overflows the same way.
    #[test]
    fn the_worker_records_exactly_what_the_recorder_does_inline() {
        const EPOCHS: usize = 12_000;
        let q = Matrix4::from_diagonal(&Vector4::new(1e-6, 1e-4, 1e-8, 1e-9));
        let run = |rec: &mut Recording<4>, copy_at: usize| {
            let (mut x, mut p) = (Vector4::new(0.0, 1.0, 0.0, 0.0), Matrix4::identity());
            let (mut marks, mut predicted) = (Vec::new(), Vec::new());
            let mut copy = None;
            // P⁻ handed over before P changes and before a mark.
            let update = |rec: &mut Recording<4>,
                          x: &mut Vector4<f64>,
                          p: &mut Matrix4<f64>,
                          state: usize,
                          z: f64,
                          symmetric: bool| {
                rec.predicted_covariance(p);
                let s = p[(state, state)] + 0.01;
                let gain = p.column(state) / s;
                let x_predicted = rec.x_predicted() - *x;
                *x += gain * (z - x[state]);
                *p -= gain * p.row(state);
                *p = (*p + p.transpose()) * 0.5;
                if !symmetric {
                    *p = skewed(*p);
                }
                rec.filtered(&(x_predicted + *x), x, p);
            };
            for k in 1..EPOCHS {
                let phi = transition_at(k);
                x = phi * x;
                p = phi * p * phi.transpose() + q;
                if k % 5 == 0 {
                    p = skewed(p);
                }
                // Now and then a state +0.0 everywhere (left out) or with
                // a −0.0 (sent).
                let x_sent = match k % 17 {
                    0 => Vector4::zeros(),
                    8 => Vector4::new(0.0, -0.0, 0.0, 0.0),
                    _ => x,
                };
                rec.predict(&phi, &x_sent, &p);
                let t = k as f64 * 0.1;
                if k % 3 != 0 {
                    let z = t + (k as f64 * 0.7).sin() * 0.05;
                    update(rec, &mut x, &mut p, 0, z, k % 7 != 0);
                }
                if k % 4 == 0 {
                    rec.predicted_covariance(&p);
                    marks.push(rec.mark());
                    marks.push(rec.mark());
                    assert_eq!(rec.open_mark(), *marks.last().unwrap());
                }
                if k % 3 == 1 {
                    let z = 1.0 + (k as f64 * 0.3).cos() * 0.02;
                    update(rec, &mut x, &mut p, 1, z, k % 11 != 0);
                }
                predicted.push(rec.x_predicted());
                if k == copy_at {
                    copy = Some((rec.clone(), p));
                }
            }
            (marks, predicted, copy, rec.overflowed(), p)
        };
        let smoothed = |(rec, p): (&Recording<4>, &Matrix4<f64>)| {
            let mut out = Vec::new();
            rec.smooth_with(p, |m, x, p| {
                out.push((m, *x, *p));
                Ok(())
            })
            .map(|()| out)
        };
        // Copies taken after an epoch's updates and while a prediction
        // waits for its P⁻ (no update, no mark at 5001).
        for (max_marks, copy_at) in [(EPOCHS, 5_000), (EPOCHS, 5_001), (20, 5_000)] {
            let (x0, p0) = (Vector4::new(0.0, 1.0, 0.0, 0.0), Matrix4::identity());
            let mut background = Recording::new(&x0, &p0, max_marks);
            assert!(matches!(background, Recording::Background(_)));
            let mut inline =
                Recording::Inline(Box::new(Inline::of(RtsRecorder::new(&x0, &p0, max_marks))));
            let (marks_b, predicted_b, copy_b, over_b, p_b) = run(&mut background, copy_at);
            let (marks_i, predicted_i, copy_i, over_i, p_i) = run(&mut inline, copy_at);
            assert_eq!(marks_b, marks_i);
            assert_eq!(predicted_b, predicted_i);
            assert_eq!(over_b, over_i);
            assert_eq!(over_b, max_marks == 20);
            let (sb, si) = (smoothed((&background, &p_b)), smoothed((&inline, &p_i)));
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
            assert_eq!(sb.len(), (EPOCHS - 1) / 4);
            assert_eq!(sb, si);
            // A visit that fails stops the pass there, with its error, and
            // the recording goes on answering (the pass again, whole).
            let stopped = |rec: &Recording<4>, p: &Matrix4<f64>| {
                let mut visited = 0;
                let result = rec.smooth_with(p, |m, _, _| {
                    visited += 1;
                    if m == 1000 {
                        return Err(EstimationError::Singular {
                            step: aidnav_estimation::Step::Smooth,
                            matrix: aidnav_estimation::Matrix::P,
                        });
                    }
                    Ok(())
                });
                (visited, result)
            };
            let (visited, result) = stopped(&background, &p_b);
            assert_eq!(
                (visited, &result),
                (sb.len() - 1000, &stopped(&inline, &p_i).1)
            );
            assert!(result.is_err());
            assert_eq!(smoothed((&background, &p_b)).unwrap(), si);
            let ((cb, pb), (ci, pi)) = (copy_b.unwrap(), copy_i.unwrap());
            assert!(matches!(cb, Recording::Inline(_)));
            assert_eq!(smoothed((&cb, &pb)).unwrap(), smoothed((&ci, &pi)).unwrap());
            // The copy goes on as the recording would: a waiting prediction
            // is made when the next one comes.
            let (mut cb, mut ci) = (cb, ci);
            for rec in [&mut cb, &mut ci] {
                let phi = transition_at(3);
                rec.predict(&phi, &Vector4::zeros(), &pb);
                rec.predicted_covariance(&pb);
                rec.mark();
            }
            assert_eq!(smoothed((&cb, &pb)).unwrap(), smoothed((&ci, &pb)).unwrap());
        }
    }
}
