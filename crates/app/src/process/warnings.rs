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
//!
//! Where a new check goes: one on the main run (levelling while moving, say)
//! pushes its `Warning` in [`super::Process::run`] next to
//! [`divergence_warnings`]; one at reading (implausible units) must reach
//! `ProcessResult::warnings` typed — the strings of
//! [`super::Inputs::warnings`] become `input` notes, which never fail
//! `--strict`.

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
    /// A run of the comparison tables (another policy on corrupted data)
    /// failed: its score is NaN. A result of the table, not of the
    /// configured run: not a `--strict` failure.
    ScoringRun,
    /// A written table holds non-finite values.
    Output,
    /// The filter started later than the first GNSS epoch (no alignment
    /// was possible before): a note, not a `--strict` failure.
    Start,
    /// The non-holonomic constraint's residuals are systematic: the
    /// vehicle frame is misaligned against the IMU ([`vehicle_frame_warning`]).
    VehicleFrame,
}

impl WarningKind {
    /// Whether `aidnav process --strict` fails on a warning of this kind:
    /// every kind but the readers' notes, the comparison tables' failed
    /// runs and a late start.
    pub fn fails_strict(self) -> bool {
        !matches!(
            self,
            WarningKind::Input | WarningKind::ScoringRun | WarningKind::Start
        )
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

/// Mean non-holonomic innovation over its σ above which the vehicle frame
/// is taken to be misaligned: 1, the residual's own σ on average over the
/// whole run. A consistent filter's mean is the noise's, well below 0.3
/// over a few hundred updates even as correlated as the constraint's are;
/// a misalignment θ at speed v gives about `v sin θ / σ` (1° at 10 m/s
/// against σ 0.1 m/s: 1.7).
pub const VEHICLE_FRAME_NORMALISED_MEAN: f64 = 1.0;

/// Fraction of the non-holonomic updates rejected by their gate above
/// which the vehicle frame is taken to be misaligned: 10 % (a consistent
/// filter's 0.9999 gate rejects one in 10⁴; turns, bumps and braking a
/// few in a hundred).
pub const VEHICLE_FRAME_REJECTED_FRACTION: f64 = 0.1;

/// Fewest constraint updates (accepted or rejected) the vehicle-frame
/// check judges.
pub const VEHICLE_FRAME_MIN_UPDATES: usize = 100;

/// Systematic non-holonomic residuals: the mean lateral or vertical
/// innovation over its σ above [`VEHICLE_FRAME_NORMALISED_MEAN`], or more
/// than [`VEHICLE_FRAME_REJECTED_FRACTION`] of the updates rejected by the
/// constraint's gate, says the constraint's frame is not the vehicle's (a
/// yaw or pitch misalignment of the IMU), which the constraint then
/// forces into the velocity or fights.
pub fn vehicle_frame_warning(
    residuals: &super::run::NonHolonomicResiduals,
    t0_s: f64,
) -> Option<Warning> {
    if residuals.updates < VEHICLE_FRAME_MIN_UPDATES {
        return None;
    }
    let (normalised, mean) = (residuals.mean_normalised(), residuals.mean_mps());
    let rejected = residuals.rejected_fraction();
    let systematic = |i: usize| normalised[i].abs() > VEHICLE_FRAME_NORMALISED_MEAN;
    if !systematic(0) && !systematic(1) && rejected <= VEHICLE_FRAME_REJECTED_FRACTION {
        return None;
    }
    // The components beyond the bound, else (a rejected run alone) the
    // larger one.
    let larger = usize::from(normalised[1].abs() > normalised[0].abs());
    let axes = [("lateral", "yaw"), ("vertical", "pitch")];
    let mut parts: Vec<String> = (0..2)
        .filter(|&i| systematic(i) || (!systematic(1 - i) && i == larger))
        .map(|i| {
            format!(
                "mean {} {:+.3} m/s ({:+.1}σ, the {})",
                axes[i].0, mean[i], normalised[i], axes[i].1
            )
        })
        .collect();
    if rejected > VEHICLE_FRAME_REJECTED_FRACTION {
        parts.push(format!(
            "{:.0} % of the updates rejected by the gate",
            100.0 * rejected
        ));
    }
    let [a, b] = residuals.span_s;
    Some(Warning::during(
        WarningKind::VehicleFrame,
        format!(
            "the non-holonomic constraint's residuals are systematic over its {} updates from {} to {}: {}; the vehicle frame looks misaligned against the IMU — set constraints.estimate_misalignment = true (or constraints.misalignment_deg, or check imu.mounting_deg)",
            residuals.updates,
            when(a, t0_s),
            when(b, t0_s),
            parts.join(", ")
        ),
        a,
        b,
    ))
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::run::synthetic::epoch;
    use nalgebra::{Matrix3, Vector3};

    /// 4 Hz updates from `a` to `b` with position NIS `nis(t)`.
    fn updates(a: f64, b: f64, nis: impl Fn(f64) -> f64) -> Vec<Epoch> {
        let n = ((b - a) * 4.0).round() as usize;
        (0..n)
            .map(|k| {
                let t = a + k as f64 * 0.25;
                epoch(t, 1, 0.01, Vector3::zeros(), Matrix3::identity(), nis(t))
            })
            .collect()
    }

    #[test]
    fn a_sustained_nis_far_above_its_dof_is_a_divergence_with_its_times() {
        // NIS per dof 1 until 100 s, 20 from 100 to 160 s, 1 after.
        let epochs = updates(0.0, 300.0, |t| {
            if (100.0..160.0).contains(&t) {
                60.0
            } else {
                3.0
            }
        });
        let w = divergence_warnings(&epochs, 0.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert_eq!(w[0].kind, WarningKind::Divergence);
        let (a, b) = (w[0].start_s.unwrap(), w[0].end_s.unwrap());
        // The window (t − 30, t] holds 120 updates; its mean per dof is
        // (19 n + 120) / 120 with n of them at 20: above 10 for n ≥ 57,
        // first at 100 + 56 · 0.25 = 114 s, last at 175.5 s (the window
        // (145.5, 175.5] holds 57 of them).
        assert!((a - 114.0).abs() < 1e-9, "{a}");
        assert!((b - 175.5).abs() < 1e-9, "{b}");
        assert!(
            w[0].message.contains("from 114.0 s") && w[0].message.contains("to 175.5 s"),
            "{}",
            w[0].message
        );
        assert!(w[0].kind.fails_strict());
    }

    #[test]
    fn a_single_outlier_is_no_divergence() {
        // However large, one NIS lifts the 30 s mean for less than 30 s.
        let epochs = updates(0.0, 200.0, |t| if t == 50.0 { 1e9 } else { 3.0 });
        assert!(divergence_warnings(&epochs, 0.0).is_empty());
        // Nor is a stretch of 20 s (mean above 10 for less than a window).
        let short = updates(0.0, 200.0, |t| {
            if (50.0..70.0).contains(&t) { 60.0 } else { 3.0 }
        });
        assert!(divergence_warnings(&short, 0.0).is_empty());
    }

    #[test]
    fn a_long_run_of_rejected_updates_is_a_warning_with_its_times() {
        let mut epochs = updates(0.0, 60.0, |_| 3.0);
        // 12.5 s rejected from 10 s (until the accepted update at 22.5 s),
        // 5 s limited from 40 s: only the first is a warning.
        for e in &mut epochs {
            let t = e.fix.time_s;
            if (10.0..22.5).contains(&t) {
                e.outcome = Some(Outcome::Rejected);
            } else if (40.0..45.0).contains(&t) {
                e.outcome = Some(Outcome::Limited);
            }
        }
        let w = rejection_run_warnings(&epochs, 0.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert_eq!((w[0].start_s, w[0].end_s), (Some(10.0), Some(22.5)));
        assert!(
            w[0].message
                .starts_with("50 position updates in a row rejected or limited"),
            "{}",
            w[0].message
        );
        // A run lasting to the last epoch ends there.
        for e in &mut epochs[160..] {
            e.outcome = Some(Outcome::Limited);
        }
        let w = rejection_run_warnings(&epochs, 0.0);
        assert_eq!(w.len(), 2);
        assert_eq!((w[1].start_s, w[1].end_s), (Some(40.0), Some(59.75)));
        // Withheld epochs (an outage) neither start nor break a run.
        for k in (160..164).chain(180..190) {
            epochs[k].outcome = None;
        }
        let w = rejection_run_warnings(&epochs, 0.0);
        assert_eq!((w[1].start_s, w[1].end_s), (Some(41.0), Some(59.75)));
        assert!(
            w[1].message.starts_with("66 position updates"),
            "{}",
            w[1].message
        );
    }

    #[test]
    fn input_notes_and_failed_table_runs_do_not_fail_strict() {
        assert!(!WarningKind::Input.fails_strict());
        assert!(!WarningKind::ScoringRun.fails_strict());
        for k in [
            WarningKind::Divergence,
            WarningKind::RejectionRun,
            WarningKind::LevellingWhileMoving,
            WarningKind::ImplausibleUnits,
            WarningKind::Output,
        ] {
            assert!(k.fails_strict(), "{k:?}");
        }
        let w = serde_json::to_value(Warning::new(WarningKind::RejectionRun, "x")).unwrap();
        assert_eq!(w["kind"], "rejection_run");
        assert!(w["start_s"].is_null());
    }
}
