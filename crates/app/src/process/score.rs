//! Scores of a run: outage drift, efficiency criterion, tracking, injected anomalies.

use aidnav_io::rtklib::GnssFix;
use nalgebra::Vector3;
use serde::Serialize;

use super::config::{FixQuality, ScoreConfig};
use super::run::Epoch;

/// The default outage schedule for length L.
pub fn outage_windows(
    cfg: &ScoreConfig,
    first_imu_s: f64,
    last_gnss_s: f64,
    length_s: f64,
) -> Vec<(f64, f64)> {
    periodic_windows(first_imu_s + cfg.lead_s, length_s, cfg.gap_s, last_gnss_s)
}

/// Windows [a, a + `length_s`) from `start_s`, one every `length_s +
/// gap_s`, each ending before `last_s`.
pub fn periodic_windows(start_s: f64, length_s: f64, gap_s: f64, last_s: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for k in 0.. {
        let a = start_s + k as f64 * (length_s + gap_s);
        let b = a + length_s;
        if b >= last_s {
            break;
        }
        out.push((a, b));
    }
    out
}

/// Per outage length: RMS over windows of the maximum drift.
///
/// Only reference fixes (`score.reference_quality`) are scored against; a
/// window without one is not scored, and a length without any scored
/// window has no score (None; `null` in `summary.json`, "no reference" in
/// the printout).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageScore {
    /// L \[s\].
    pub outage_s: f64,
    /// Windows scheduled ([`outage_windows`]).
    pub windows_scheduled: usize,
    /// Windows scored: those with at least one reference epoch.
    pub windows: usize,
    /// Scored windows cut short by the end of the reference: their last
    /// reference epoch lies more than [`cut_short_tolerance_s`] before the
    /// window's end, so the drift at the end of the window (usually the
    /// largest) is not measured.
    pub windows_cut_short: usize,
    /// Per cut-short window, the time from its start to its last reference
    /// epoch \[s\].
    pub cut_short_scored_s: Vec<f64>,
    /// Reference epochs inside the scored windows.
    pub reference_epochs: usize,
    /// RMS over windows of the max horizontal drift \[m\] (None: no reference).
    pub horizontal_m: Option<f64>,
    /// … vertical \[m\] (None: no reference).
    pub vertical_m: Option<f64>,
    /// … 3-D \[m\] (None: no reference).
    pub three_d_m: Option<f64>,
}

/// A scored window's reference may end this long before the window without
/// the window counting as cut short \[s\]: 1 s, or 1.5 GNSS intervals
/// (the median spacing of `epochs`) for receivers slower than 1.5 Hz — the
/// last epoch of a window [a, b) lies up to one interval before b.
pub fn cut_short_tolerance_s(epochs: &[Epoch]) -> f64 {
    let mut dt: Vec<f64> = epochs
        .windows(2)
        .map(|w| w[1].fix.time_s - w[0].fix.time_s)
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if dt.is_empty() {
        return 1.0;
    }
    let mid = dt.len() / 2;
    let (_, median, _) = dt.select_nth_unstable_by(mid, f64::total_cmp);
    (1.5 * *median).max(1.0)
}

/// Score a run's epochs inside windows against the withheld reference fixes
/// (those whose quality is in `reference`).
pub fn score_windows(
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
    reference: &[FixQuality],
) -> OutageScore {
    let tolerance = cut_short_tolerance_s(epochs);
    let mut maxima: Vec<[f64; 3]> = Vec::new();
    let (mut cut_short_scored_s, mut reference_epochs) = (Vec::new(), 0usize);
    for &(a, b) in windows {
        let mut m = [0.0f64; 3];
        let mut last: Option<f64> = None;
        for e in epochs {
            let g = &e.fix;
            if g.time_s < a || g.time_s >= b || !is_reference(g, reference) {
                continue;
            }
            let d = g.position.ned_to(&e.antenna).raw();
            m[0] = m[0].max(d.xy().norm());
            m[1] = m[1].max(d.z.abs());
            m[2] = m[2].max(d.norm());
            last = Some(g.time_s);
            reference_epochs += 1;
        }
        if let Some(t) = last {
            maxima.push(m);
            if b - t > tolerance {
                cut_short_scored_s.push(t - a);
            }
        }
    }
    let rms = |i: usize| {
        (!maxima.is_empty())
            .then(|| (maxima.iter().map(|m| m[i] * m[i]).sum::<f64>() / maxima.len() as f64).sqrt())
    };
    OutageScore {
        outage_s: length_s,
        windows_scheduled: windows.len(),
        windows: maxima.len(),
        windows_cut_short: cut_short_scored_s.len(),
        cut_short_scored_s,
        reference_epochs,
        horizontal_m: rms(0),
        vertical_m: rms(1),
        three_d_m: rms(2),
    }
}

/// The outage-window epochs with each epoch's antenna replaced by the
/// position bridged by predictor `k` of [`super::BRIDGE_PREDICTORS`] (epochs
/// without a bridge keep the coasting filter's).
pub fn bridged_epochs(epochs: &[Epoch], k: usize) -> Vec<Epoch> {
    epochs
        .iter()
        .map(|e| Epoch {
            antenna: e.bridged.map_or(e.antenna, |b| b[k]),
            ..*e
        })
        .collect()
}

/// Spec 20's efficiency criterion in the outage windows of one length:
/// how long after GNSS is lost the filter still predicts itself better than
/// GNSS (K_eff > 1), and how long its actual 3-D error stays below σ_GNSS.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EfficiencyScore {
    /// L \[s\].
    pub outage_s: f64,
    /// Windows scored (with at least one epoch).
    pub windows: usize,
    /// Mean σ_GNSS over the windows' epochs \[m\].
    pub sigma_gnss_m: f64,
    /// Mean over windows of the outage age at which K_eff first falls below
    /// 1 (windows where it never does count as L) \[s\].
    pub predicted_crossing_s: f64,
    /// Windows where it fell below 1.
    pub predicted_crossed: usize,
    /// Windows with at least one reference epoch (the actual crossing is
    /// measured in these only).
    pub reference_windows: usize,
    /// Mean over the windows with a reference of the age at which the
    /// actual 3-D error against the reference first exceeds σ_GNSS
    /// (censored at L) \[s\] (None: no reference).
    pub actual_crossing_s: Option<f64>,
    /// Windows where it did.
    pub actual_crossed: usize,
}

/// The efficiency criterion of a run with outage windows (see
/// [`EfficiencyScore`]); the actual error against the fixes whose quality
/// is in `reference`.
pub fn efficiency_in_windows(
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
    reference: &[FixQuality],
) -> EfficiencyScore {
    let (mut n, mut sigma_sum, mut sigma_n) = (0usize, 0.0, 0usize);
    let (mut predicted, mut actual) = ((0.0, 0usize), (0.0, 0usize));
    let mut reference_windows = 0usize;
    for &(a, b) in windows {
        let inside: Vec<&Epoch> = epochs
            .iter()
            .filter(|e| (a..b).contains(&e.fix.time_s))
            .collect();
        if inside.is_empty() {
            continue;
        }
        n += 1;
        let age = |e: &Epoch| e.fix.time_s - a;
        let sigma_gnss = |e: &Epoch| e.k_eff * e.sigma.norm();
        for e in &inside {
            sigma_sum += sigma_gnss(e);
            sigma_n += 1;
        }
        let first = |hit: &dyn Fn(&Epoch) -> bool| inside.iter().find(|e| hit(e)).map(|e| age(e));
        let crossing = first(&|e| e.k_eff < 1.0);
        predicted.0 += crossing.unwrap_or(length_s);
        predicted.1 += usize::from(crossing.is_some());
        if inside.iter().any(|e| is_reference(&e.fix, reference)) {
            reference_windows += 1;
            let crossing = first(&|e| {
                is_reference(&e.fix, reference)
                    && e.fix.position.ned_to(&e.antenna).norm() > sigma_gnss(e)
            });
            actual.0 += crossing.unwrap_or(length_s);
            actual.1 += usize::from(crossing.is_some());
        }
    }
    EfficiencyScore {
        outage_s: length_s,
        windows: n,
        sigma_gnss_m: sigma_sum / sigma_n.max(1) as f64,
        predicted_crossing_s: predicted.0 / n.max(1) as f64,
        predicted_crossed: predicted.1,
        reference_windows,
        actual_crossing_s: (reference_windows > 0).then(|| actual.0 / reference_windows as f64),
        actual_crossed: actual.1,
    }
}

/// Whether a fix serves as the reference of the scores: its quality
/// (RTKLIB's Q) is one of `reference` (`score.reference_quality`).
pub fn is_reference(g: &GnssFix, reference: &[FixQuality]) -> bool {
    reference.iter().any(|q| q.rtklib_q() == g.quality)
}

/// Epochs whose fix is a reference.
pub fn reference_epochs(epochs: &[Epoch], reference: &[FixQuality]) -> usize {
    epochs
        .iter()
        .filter(|e| is_reference(&e.fix, reference))
        .count()
}

/// RMS 3-D error over the reference epochs against their (clean) fixes;
/// None when there is no reference epoch.
pub fn tracking_rms(epochs: &[Epoch], reference: &[FixQuality]) -> Option<f64> {
    let (sum, n) = epochs
        .iter()
        .filter(|e| is_reference(&e.fix, reference))
        .fold((0.0, 0usize), |(s, n), e| {
            (s + e.fix.position.ned_to(&e.antenna).norm_squared(), n + 1)
        });
    (n > 0).then(|| (sum / n as f64).sqrt())
}

/// Flight times (since the first epoch) at which spec 10's switch rule —
/// δ(n) non-increasing for `falling_s`, then ≤ threshold for 5 epochs —
/// declares the instrument errors converged, per threshold (None: never).
pub fn convergence_times(epochs: &[Epoch], thresholds: &[f64], falling_s: f64) -> Vec<Option<f64>> {
    use aidnav_supervisors::convergence::{ConvergenceSwitch, SwitchRule};
    let Some(t0) = epochs.first().map(|e| e.fix.time_s) else {
        return vec![None; thresholds.len()];
    };
    thresholds
        .iter()
        .map(|&threshold| {
            let mut switch = ConvergenceSwitch::new(SwitchRule {
                threshold,
                falling_s,
                ..SwitchRule::default()
            });
            epochs
                .iter()
                .filter(|e| e.convergence.is_finite())
                .find_map(|e| {
                    let t = e.fix.time_s - t0;
                    switch.observe(t, e.convergence).then_some(t)
                })
        })
        .collect()
}

/// RMS 3-D error over the reference epochs where GNSS was used (not
/// withheld), against the clean fixes; None when there is none.
pub fn tracking_rms_with_gnss(epochs: &[Epoch], reference: &[FixQuality]) -> Option<f64> {
    let used: Vec<Epoch> = epochs
        .iter()
        .filter(|e| e.outcome.is_some())
        .copied()
        .collect();
    tracking_rms(&used, reference)
}

/// One common jump per window for the fixes in [end, end + burst_s) after
/// each window (seeded), by GNSS index.
pub fn post_outage_bursts(
    gnss: &[GnssFix],
    windows: &[(f64, f64)],
    burst_s: f64,
    range_m: [f64; 2],
    seed: u64,
) -> Vec<Option<Vector3<f64>>> {
    let jumps = inject_outliers(windows.len(), 1.0, range_m, seed);
    gnss.iter()
        .map(|g| {
            windows
                .iter()
                .zip(&jumps)
                .find(|((_, end), _)| g.time_s >= *end && g.time_s < end + burst_s)
                .and_then(|(_, j)| *j)
        })
        .collect()
}

/// Outliers for a fraction of the epochs (seeded).
pub fn inject_outliers(
    n: usize,
    fraction: f64,
    range_m: [f64; 2],
    seed: u64,
) -> Vec<Option<Vector3<f64>>> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            if rng.random_bool(fraction) {
                let size = rng.random_range(range_m[0]..=range_m[1]);
                let dir = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                Some(dir.normalize() * size)
            } else {
                None
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::process::run::synthetic::epoch;
    use nalgebra::Matrix3;

    const FIXED: [FixQuality; 1] = [FixQuality::Fixed];

    /// 4 Hz epochs from `a` to `b` (exclusive), quality `quality`, the
    /// antenna `error(t)` from the fix.
    fn epochs(a: f64, b: f64, quality: u8, error: impl Fn(f64) -> Vector3<f64>) -> Vec<Epoch> {
        let n = ((b - a) * 4.0).round() as usize;
        (0..n)
            .map(|k| {
                let t = a + k as f64 * 0.25;
                epoch(t, quality, 0.01, error(t), Matrix3::identity(), 3.0)
            })
            .collect()
    }

    #[test]
    fn drift_is_the_rms_over_windows_of_the_maximum_against_the_reference() {
        // Window [0, 10): the error grows 0.1 m/s north; window [20, 30):
        // 0.3 m/s down. Maxima at 9.75 s: 0.975 m horizontal; 2.925 m vertical.
        let mut all = epochs(0.0, 10.0, 1, |t| Vector3::new(0.1 * t, 0.0, 0.0));
        all.extend(epochs(10.0, 20.0, 1, |_| Vector3::zeros()));
        all.extend(epochs(20.0, 30.0, 1, |t| {
            Vector3::new(0.0, 0.0, 0.3 * (t - 20.0))
        }));
        let s = score_windows(&all, &[(0.0, 10.0), (20.0, 30.0)], 10.0, &FIXED);
        assert_eq!(
            (s.windows_scheduled, s.windows, s.windows_cut_short),
            (2, 2, 0)
        );
        assert_eq!(s.reference_epochs, 80);
        let rms = |a: f64, b: f64| ((a * a + b * b) / 2.0).sqrt();
        assert!((s.horizontal_m.unwrap() - rms(0.975, 0.0)).abs() < 1e-6);
        assert!((s.vertical_m.unwrap() - rms(0.0, 2.925)).abs() < 1e-6);
        assert!((s.three_d_m.unwrap() - rms(0.975, 2.925)).abs() < 1e-6);
        assert!((tracking_rms(&all[40..80], &FIXED).unwrap()).abs() < 1e-6);
    }

    #[test]
    fn without_a_reference_quality_fix_nothing_is_scored() {
        // Float fixes only (and the default reference: RTK fixed): the
        // filter's solution is not scored against itself or its stream.
        let float = epochs(0.0, 30.0, 2, |t| Vector3::new(0.1 * t, 0.0, 0.0));
        let s = score_windows(&float, &[(0.0, 10.0), (15.0, 25.0)], 10.0, &FIXED);
        assert_eq!(
            (s.windows_scheduled, s.windows, s.reference_epochs),
            (2, 0, 0)
        );
        assert_eq!(
            (s.horizontal_m, s.vertical_m, s.three_d_m),
            (None, None, None)
        );
        assert_eq!(tracking_rms(&float, &FIXED), None);
        assert_eq!(tracking_rms_with_gnss(&float, &FIXED), None);
        assert_eq!(reference_epochs(&float, &FIXED), 0);
        let e = efficiency_in_windows(&float, &[(0.0, 10.0)], 10.0, &FIXED);
        assert_eq!(
            (e.windows, e.reference_windows, e.actual_crossing_s),
            (1, 0, None)
        );
        // Named as a reference, the same fixes are scored.
        let s = score_windows(&float, &[(0.0, 10.0)], 10.0, &[FixQuality::Float]);
        assert!((s.three_d_m.unwrap() - 0.975).abs() < 1e-6);
        // A quality 0 file (no quality column) only when `unknown` is named.
        let unknown = epochs(0.0, 10.0, 0, |_| Vector3::zeros());
        assert_eq!(tracking_rms(&unknown, &FIXED), None);
        assert!(tracking_rms(&unknown, &[FixQuality::Unknown]).unwrap() < 1e-9);
    }

    #[test]
    fn windows_cut_short_by_the_end_of_the_reference_are_counted() {
        // RTK fixed until 25 s, float after: the window [20, 30) is scored
        // over its first 4.75 s only; [0, 10) is whole; [40, 50) has no
        // reference at all.
        let mut all = epochs(0.0, 25.0, 1, |t| Vector3::new(0.01 * t, 0.0, 0.0));
        all.extend(epochs(25.0, 60.0, 2, |t| Vector3::new(0.01 * t, 0.0, 0.0)));
        let s = score_windows(
            &all,
            &[(0.0, 10.0), (20.0, 30.0), (40.0, 50.0)],
            10.0,
            &FIXED,
        );
        assert_eq!(
            (s.windows_scheduled, s.windows, s.windows_cut_short),
            (3, 2, 1)
        );
        assert_eq!(s.cut_short_scored_s, vec![4.75]);
        // A window whose last reference epoch is the last epoch before its
        // end (0.25 s at 4 Hz) is whole.
        assert!((cut_short_tolerance_s(&all) - 1.0).abs() < 1e-12);
        // At 0.5 Hz a whole window ends up to 2 s after its last epoch.
        let slow: Vec<Epoch> = (0..10)
            .map(|k| {
                epoch(
                    2.0 * k as f64,
                    1,
                    0.01,
                    Vector3::zeros(),
                    Matrix3::identity(),
                    3.0,
                )
            })
            .collect();
        assert!((cut_short_tolerance_s(&slow) - 3.0).abs() < 1e-12);
        assert_eq!(
            score_windows(&slow, &[(0.0, 10.0)], 10.0, &FIXED).windows_cut_short,
            0
        );
    }
}
