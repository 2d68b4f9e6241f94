//! Parallel Monte Carlo over all cores, deterministic whatever the thread count.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::rng::{RunRng, run_rng};

pub use aidnav_estimation::{Cancel, Cancelled};

/// Whether to show a progress bar.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Progress {
    /// Show one on a terminal, unless the `CI` environment variable is set.
    #[default]
    Auto,
    /// Never show one.
    Hidden,
}

/// A Monte Carlo campaign: `runs` runs under master seed `seed`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MonteCarlo {
    /// Number of runs.
    pub runs: usize,
    /// Master seed; run k uses stream k of it (see [`crate::rng`]).
    pub seed: u64,
    /// Progress bar policy.
    pub progress: Progress,
    /// Label shown before the bar.
    pub label: String,
    /// Looked at before every run: once set, the campaign stops (see
    /// [`Cancel`]: it unwinds with [`Cancelled`]; [`Cancel::catch`] turns
    /// that into an error). Never set unless the caller sets it.
    pub cancel: Cancel,
}

impl MonteCarlo {
    /// `runs` runs under `seed`, progress bar on a terminal.
    pub fn new(runs: usize, seed: u64) -> Self {
        Self {
            runs,
            seed,
            progress: Progress::Auto,
            label: String::from("Monte Carlo"),
            cancel: Cancel::default(),
        }
    }

    /// Stop when `cancel` is set (before the next run, on every thread).
    pub fn with_cancel(mut self, cancel: Cancel) -> Self {
        self.cancel = cancel;
        self
    }

    /// Never show a progress bar.
    pub fn quiet(mut self) -> Self {
        self.progress = Progress::Hidden;
        self
    }

    /// Set the label of the progress bar.
    pub fn with_label(mut self, label: impl Into<String>) -> Self {
        self.label = label.into();
        self
    }

    fn bar(&self) -> ProgressBar {
        let show = self.progress == Progress::Auto
            && std::io::stderr().is_terminal()
            && std::env::var_os("CI").is_none();
        if !show {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new(self.runs as u64);
        let style = ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} runs ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
        bar.set_style(style);
        bar.set_message(self.label.clone());
        bar
    }

    /// Run `f(run_index, rng)` for every run in parallel; results in run order.
    pub fn run<T, F>(&self, f: F) -> Vec<T>
    where
        T: Send,
        F: Fn(usize, &mut RunRng) -> T + Sync,
    {
        self.run_range(0..self.runs, f)
    }

    /// Run `f(run_index, rng)` for the runs in `range` only, in parallel;
    /// results in run order. Run k draws stream k of the seed whatever the
    /// range, so a campaign computed in chunks (on other threads, processes
    /// or machines) gives each run the numbers the whole campaign gives it.
    pub fn run_range<T, F>(&self, range: std::ops::Range<usize>, f: F) -> Vec<T>
    where
        T: Send,
        F: Fn(usize, &mut RunRng) -> T + Sync,
    {
        let bar = self.bar();
        // Once the token is set, the runs not yet started are skipped
        // (None) rather than unwound one by one: rayon catches a job's
        // unwinding, waits for its sibling and unwinds again at every join,
        // and its splitter keeps splitting the rest among the threads, so a
        // campaign of 100 000 runs spent 1.5 s in some 10⁵ unwindings after
        // the token was set (a run lasting 0.1 s). One unwinding, here, after
        // the parallel loop.
        let out: Vec<Option<T>> = range
            .into_par_iter()
            .map(|k| {
                if self.cancel.is_cancelled() {
                    return None;
                }
                let mut rng = run_rng(self.seed, k as u64);
                let r = f(k, &mut rng);
                bar.inc(1);
                Some(r)
            })
            .collect();
        bar.finish_and_clear();
        self.cancel.stop_if_cancelled();
        // A run is skipped only once the token is set, and the token is
        // never unset: every run is here.
        out.into_iter().flatten().collect()
    }

    /// As [`run`](Self::run) for fallible runs: the first error (lowest run index) wins.
    pub fn try_run<T, E, F>(&self, f: F) -> Result<Vec<T>, E>
    where
        T: Send,
        E: Send,
        F: Fn(usize, &mut RunRng) -> Result<T, E> + Sync,
    {
        self.run(f).into_iter().collect()
    }

    /// As [`run_range`](Self::run_range) for fallible runs: the first error
    /// (lowest run index) wins.
    pub fn try_run_range<T, E, F>(&self, range: std::ops::Range<usize>, f: F) -> Result<Vec<T>, E>
    where
        T: Send,
        E: Send,
        F: Fn(usize, &mut RunRng) -> Result<T, E> + Sync,
    {
        self.run_range(range, f).into_iter().collect()
    }

    /// As [`try_run_range`](Self::try_run_range) with the runs handed out
    /// `batch` at a time (the last batch may be shorter): `f(runs)` returns
    /// one result per run of `runs`, in order, for work that is cheaper
    /// done for several runs together. The batches run in parallel; the
    /// first error (lowest run index) wins. No stream is drawn for `f`: a
    /// run's randomness is its own business (e.g.
    /// [`channel_rng`](crate::rng::channel_rng)).
    pub fn try_run_batches<T, E, F>(
        &self,
        range: std::ops::Range<usize>,
        batch: usize,
        f: F,
    ) -> Result<Vec<T>, E>
    where
        T: Send,
        E: Send,
        F: Fn(std::ops::Range<usize>) -> Vec<Result<T, E>> + Sync,
    {
        let batch = batch.max(1);
        let bar = self.bar();
        let batches = range.len().div_ceil(batch);
        let out: Vec<Option<Vec<Result<T, E>>>> = (0..batches)
            .into_par_iter()
            .map(|b| {
                if self.cancel.is_cancelled() {
                    return None;
                }
                let first = range.start + b * batch;
                let runs = first..(first + batch).min(range.end);
                let len = runs.len();
                let r = f(runs);
                assert_eq!(r.len(), len, "one result per run of the batch");
                bar.inc(len as u64);
                Some(r)
            })
            .collect();
        bar.finish_and_clear();
        self.cancel.stop_if_cancelled();
        // As in `run_range`: a batch is skipped only once the token is set.
        out.into_iter().flatten().flatten().collect()
    }
}

/// Runs computed in parallel before [`MonteCarlo::try_fold`] folds them:
/// this many per thread.
const FOLD_CHUNK_PER_THREAD: usize = 4;

impl MonteCarlo {
    /// Run `f(run_index, rng)` for every run and fold the results into
    /// `init` with `fold(acc, run_index, result)` **in run order**, so the
    /// fold's arithmetic is the same whatever the thread count. Runs are
    /// computed in parallel a chunk at a time (a few per thread), so only a
    /// chunk of results is held at once: memory does not grow with `runs`.
    /// The first error (lowest run index) wins, as in [`try_run`](Self::try_run).
    pub fn try_fold<T, E, A, F, G>(&self, init: A, f: F, fold: G) -> Result<A, E>
    where
        T: Send,
        E: Send,
        F: Fn(usize, &mut RunRng) -> Result<T, E> + Sync,
        G: FnMut(&mut A, usize, T),
    {
        self.try_fold_chunked(usize::MAX, init, f, fold)
    }

    /// As [`try_fold`](Self::try_fold) holding at most `max_chunk` run
    /// results at once (for runs whose results are large), still at most a
    /// few per thread.
    pub fn try_fold_chunked<T, E, A, F, G>(
        &self,
        max_chunk: usize,
        init: A,
        f: F,
        mut fold: G,
    ) -> Result<A, E>
    where
        T: Send,
        E: Send,
        F: Fn(usize, &mut RunRng) -> Result<T, E> + Sync,
        G: FnMut(&mut A, usize, T),
    {
        let bar = self.bar();
        let chunk = (rayon::current_num_threads() * FOLD_CHUNK_PER_THREAD)
            .min(max_chunk)
            .max(1);
        let mut acc = init;
        let mut first = 0;
        while first < self.runs {
            let last = (first + chunk).min(self.runs);
            // A chunk is a few runs per thread: unwinding from each of its
            // runs once the token is set costs little (see `run_range`).
            let results: Vec<Result<T, E>> = (first..last)
                .into_par_iter()
                .map(|k| {
                    self.cancel.stop_if_cancelled();
                    let mut rng = run_rng(self.seed, k as u64);
                    let r = f(k, &mut rng);
                    bar.inc(1);
                    r
                })
                .collect();
            for (k, r) in (first..last).zip(results) {
                match r {
                    Ok(t) => fold(&mut acc, k, t),
                    Err(e) => {
                        bar.finish_and_clear();
                        return Err(e);
                    }
                }
            }
            first = last;
        }
        bar.finish_and_clear();
        Ok(acc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::RngExt;

    #[test]
    fn batches_give_the_runs_in_order_and_the_first_error() {
        let mc = MonteCarlo::new(10, 3).quiet();
        let squares = mc
            .try_run_batches(3..10, 3, |runs| {
                runs.map(|k| Ok::<_, usize>(k * k)).collect()
            })
            .unwrap();
        assert_eq!(squares, (3..10).map(|k| k * k).collect::<Vec<_>>());
        let failing = mc.try_run_batches(0..10, 4, |runs| {
            runs.map(|k| if k % 3 == 2 { Err(k) } else { Ok(k) })
                .collect()
        });
        assert_eq!(failing, Err(2));
    }

    #[test]
    fn serial_equals_parallel() {
        let mc = MonteCarlo::new(64, 7).quiet();
        let work = |k: usize, rng: &mut RunRng| -> (usize, f64) {
            let s: f64 = (0..1000).map(|_| rng.random::<f64>()).sum();
            (k, s)
        };
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let serial = one.install(|| mc.run(work));
        let four = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let parallel = four.install(|| mc.run(work));
        assert_eq!(serial, parallel);
        assert!(serial.iter().enumerate().all(|(i, (k, _))| i == *k));
    }

    #[test]
    fn try_fold_folds_in_run_order_whatever_the_thread_count() {
        let mc = MonteCarlo::new(1000, 3).quiet();
        let work = |_: usize, rng: &mut RunRng| -> Result<f64, ()> { Ok(rng.random::<f64>()) };
        let fold = |acc: &mut Vec<usize>, k: usize, x: f64| {
            acc.push(k);
            let _ = x;
        };
        let order = mc.try_fold(Vec::new(), work, fold).unwrap();
        assert_eq!(order, (0..1000).collect::<Vec<_>>());
        // The same floating-point sum as summing the collected runs in order.
        let sum_fold = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| mc.try_fold(0.0, work, |a: &mut f64, _, x| *a += x / 1000.0))
                .unwrap()
        };
        let collected: f64 = mc
            .try_run(work)
            .unwrap()
            .iter()
            .fold(0.0, |a, x| a + x / 1000.0);
        assert_eq!(sum_fold(1).to_bits(), collected.to_bits());
        assert_eq!(sum_fold(3).to_bits(), collected.to_bits());
        let r: Result<(), usize> = mc.try_fold(
            (),
            |k, _| if k >= 517 { Err(k) } else { Ok(()) },
            |_, _, _| {},
        );
        assert_eq!(r, Err(517));
    }

    #[test]
    fn a_set_token_stops_the_campaign_within_a_run_per_thread() {
        let cancel = Cancel::new();
        let mc = MonteCarlo::new(10_000, 1)
            .quiet()
            .with_cancel(cancel.clone());
        let done = std::sync::atomic::AtomicUsize::new(0);
        let r = Cancel::catch(|| {
            mc.run(|k, _| {
                if k == 20 {
                    cancel.cancel();
                }
                done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            })
        });
        assert_eq!(r, Err(Cancelled));
        // The runs started before the flag was seen finish; no more start.
        let done = done.into_inner();
        assert!(done < 10_000, "{done} runs");
        let r: Result<Result<f64, ()>, _> =
            Cancel::catch(|| mc.try_fold(0.0, |_, _| Ok(1.0), |a: &mut f64, _, x| *a += x));
        assert_eq!(r, Err(Cancelled));
    }

    /// A campaign cancelled at its first run skips the rest without
    /// unwinding from each: a million runs end in about a millisecond (each
    /// unwinding took some 15 µs, so a million of them would take seconds;
    /// the bound leaves a wide margin for a loaded machine).
    #[test]
    fn a_cancelled_campaign_of_a_million_runs_stops_at_once() {
        let cancel = Cancel::new();
        let mc = MonteCarlo::new(1_000_000, 1)
            .quiet()
            .with_cancel(cancel.clone());
        let done = std::sync::atomic::AtomicUsize::new(0);
        let t = std::time::Instant::now();
        let r = Cancel::catch(|| {
            mc.run(|_, _| {
                cancel.cancel();
                done.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            })
        });
        let elapsed = t.elapsed().as_secs_f64();
        assert_eq!(r, Err(Cancelled));
        assert!(done.into_inner() <= rayon::current_num_threads());
        assert!(elapsed < 1.0, "{elapsed} s");
    }

    #[test]
    fn try_run_reports_the_first_failing_run() {
        let mc = MonteCarlo::new(10, 1).quiet();
        let r: Result<Vec<usize>, usize> = mc.try_run(|k, _| if k >= 3 { Err(k) } else { Ok(k) });
        assert_eq!(r, Err(3));
    }
}
