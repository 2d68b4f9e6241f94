//! Warnings of a run: what the readers repaired, and what makes a result
//! untrustworthy — divergence, long runs of rejected updates, levelling
//! while moving, implausible units, failed scoring runs, non-finite output.
//!
//! One list carries them all: [`super::ProcessResult::warnings`] (the main
//! run: input notes and the health checks of this module),
//! [`super::Scores::warnings`] (scoring runs that failed) and the job's
//! report (values written as ±inf). A check of another layer pushes a
//! [`Warning`] of its kind there; `summary.json` writes the list as
//! `result.warnings` (`kind`, `message`, `start_s`, `end_s`), the CLI prints
//! each on stderr, and `aidnav process --strict` exits non-zero when any
//! warning is of a kind that [`WarningKind::fails_strict`].

use aidnav_estimation::Outcome;
use serde::Serialize;

use super::consistency::POSITION_DOF;
use super::run::Epoch;

/// What a warning is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum WarningKind {
    /// A reader's note: lines dropped or repaired, epochs outside the IMU
    /// span (the input was usable as read; not a `--strict` failure).
    Input,
    /// The position NIS per degree of freedom stayed far above 1: the
    /// covariance no longer explains the innovations ([`divergence_warnings`]).
    Divergence,
    /// Position updates rejected or limited for a long stretch
    /// ([`rejection_run_warnings`]).
    RejectionRun,
    /// The levelling window at the start was not at rest.
    LevellingWhileMoving,
    /// Input values in units that cannot be right (g for m/s², deg for rad …).
    ImplausibleUnits,
    /// A scoring run failed (its score is NaN).
    ScoringRun,
    /// A written table holds non-finite values.
    Output,
}

impl WarningKind {
    /// Whether `aidnav process --strict` fails on a warning of this kind:
    /// every kind but the readers' notes.
    pub fn fails_strict(self) -> bool {
        self != WarningKind::Input
    }
}

/// A warning of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Warning {
    /// Its kind.
    pub kind: WarningKind,
    /// What happened, where and when, in words.
    pub message: String,
    /// Start of the stretch it concerns (GPST, seconds since 1970), if any.
    pub start_s: Option<f64>,
    /// End of that stretch (GPST, seconds since 1970), if any.
    pub end_s: Option<f64>,
}

impl Warning {
    /// A warning without a time stretch.
    pub fn new(kind: WarningKind, message: impl Into<String>) -> Self {
        Self {
            kind,
            message: message.into(),
            start_s: None,
            end_s: None,
        }
    }

    /// A warning about the stretch [start_s, end_s] (GPST s).
    pub fn during(kind: WarningKind, message: impl Into<String>, start_s: f64, end_s: f64) -> Self {
        Self {
            kind,
            message: message.into(),
            start_s: Some(start_s),
            end_s: Some(end_s),
        }
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

/// Sliding window of the divergence check \[s\].
pub const DIVERGENCE_WINDOW_S: f64 = 30.0;

/// Mean position NIS per degree of freedom over [`DIVERGENCE_WINDOW_S`]
/// above which the filter is taken to diverge: 10, i.e. innovations about
/// √10 ≈ 3.2 times larger than the filter's S explains, on average over
/// 30 s (a consistent filter's 30 s mean over ~120 updates at 4 Hz stays
/// below 1.3 with 99 % probability).
pub const DIVERGENCE_NIS_PER_DOF: f64 = 10.0;

/// A rejection run longer than this is a warning \[s\]: 10 s of rejected
/// or limited position updates is 40 fixes at 4 Hz in which the filter
/// navigates on the IMU alone, or against a stream it no longer trusts.
pub const REJECTION_RUN_S: f64 = 10.0;

/// Time in words: seconds after `t0_s` and the GPST date.
fn when(t_s: f64, t0_s: f64) -> String {
    format!("{:.1} s ({})", t_s - t0_s, aidnav_io::text::date_time(t_s))
}

/// Divergence: the mean position NIS per degree of freedom over the last
/// [`DIVERGENCE_WINDOW_S`] of updates stays above [`DIVERGENCE_NIS_PER_DOF`]
/// for longer than one window (a single outlier lifts the mean for less
/// than one window length, however large it is). One warning per stretch,
/// with its times (`t0_s`: the time the messages count from, the first IMU
/// sample).
pub fn divergence_warnings(epochs: &[Epoch], t0_s: f64) -> Vec<Warning> {
    let points: Vec<(f64, f64)> = epochs
        .iter()
        .filter(|e| e.outcome.is_some() && e.nis.is_finite())
        .map(|e| (e.fix.time_s, e.nis / POSITION_DOF as f64))
        .collect();
    let (mut first, mut sum) = (0usize, 0.0);
    let mut stretch: Option<(f64, f64, f64)> = None;
    let mut out = Vec::new();
    let close = |stretch: &mut Option<(f64, f64, f64)>, out: &mut Vec<Warning>| {
        if let Some((a, b, peak)) = stretch.take()
            && b - a > DIVERGENCE_WINDOW_S
        {
            out.push(Warning::during(
                WarningKind::Divergence,
                format!(
                    "divergence: the mean position NIS per degree of freedom over {DIVERGENCE_WINDOW_S:.0} s stayed above {DIVERGENCE_NIS_PER_DOF:.0} from {} to {} after the first IMU sample (peak {peak:.1}; 1 for a consistent filter): the covariance no longer explains the innovations",
                    when(a, t0_s),
                    when(b, t0_s)
                ),
                a,
                b,
            ));
        }
    };
    for (k, &(t, v)) in points.iter().enumerate() {
        sum += v;
        while points[first].0 <= t - DIVERGENCE_WINDOW_S {
            sum -= points[first].1;
            first += 1;
        }
        let mean = sum / (k + 1 - first) as f64;
        if mean > DIVERGENCE_NIS_PER_DOF {
            stretch = Some(match stretch {
                Some((a, _, peak)) => (a, t, peak.max(mean)),
                None => (t, t, mean),
            });
        } else {
            close(&mut stretch, &mut out);
        }
    }
    close(&mut stretch, &mut out);
    out
}

/// Long rejection runs: consecutive position updates rejected or limited by
/// the measurement policy (withheld epochs break no run) for longer than
/// [`REJECTION_RUN_S`], from the first such update to the next one accepted
/// or down-weighted (or the last epoch). One warning per run.
pub fn rejection_run_warnings(epochs: &[Epoch], t0_s: f64) -> Vec<Warning> {
    let mut out = Vec::new();
    let mut run: Option<(f64, usize)> = None;
    let close = |run: &mut Option<(f64, usize)>, end: f64, out: &mut Vec<Warning>| {
        if let Some((start, n)) = run.take()
            && end - start > REJECTION_RUN_S
        {
            out.push(Warning::during(
                WarningKind::RejectionRun,
                format!(
                    "{n} position updates in a row rejected or limited, from {} to {} after the first IMU sample ({:.1} s > {REJECTION_RUN_S:.0} s)",
                    when(start, t0_s),
                    when(end, t0_s),
                    end - start
                ),
                start,
                end,
            ));
        }
    };
    for e in epochs {
        let t = e.fix.time_s;
        match e.outcome {
            Some(Outcome::Rejected | Outcome::Limited) => {
                run = Some(run.map_or((t, 1), |(start, n)| (start, n + 1)));
            }
            Some(_) => close(&mut run, t, &mut out),
            None => {}
        }
    }
    if let Some(last) = epochs.last() {
        close(&mut run, last.fix.time_s, &mut out);
    }
    out
}
