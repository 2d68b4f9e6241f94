//! Scores of a run: outage drift, efficiency criterion, tracking, injected anomalies.

use aidnav_io::rtklib::GnssFix;
use nalgebra::Vector3;
use serde::Serialize;

use super::config::ScoreConfig;
use super::run::Epoch;

/// The default outage schedule for length L.
pub fn outage_windows(
    cfg: &ScoreConfig,
    first_imu_s: f64,
    last_gnss_s: f64,
    length_s: f64,
) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for k in 0.. {
        let a = first_imu_s + cfg.lead_s + k as f64 * (length_s + cfg.gap_s);
        let b = a + length_s;
        if b >= last_gnss_s {
            break;
        }
        out.push((a, b));
    }
    out
}

/// Per outage length: RMS over windows of the maximum drift.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutageScore {
    /// L \[s\].
    pub outage_s: f64,
    /// Windows scored.
    pub windows: usize,
    /// RMS over windows of the max horizontal drift \[m\].
    pub horizontal_m: f64,
    /// … vertical \[m\].
    pub vertical_m: f64,
    /// … 3-D \[m\].
    pub three_d_m: f64,
}

/// Score a run's epochs inside windows against the withheld RTK-fixed fixes.
pub fn score_windows(epochs: &[Epoch], windows: &[(f64, f64)], length_s: f64) -> OutageScore {
    let mut maxima: Vec<[f64; 3]> = Vec::new();
    for &(a, b) in windows {
        let mut m = [0.0f64; 3];
        let mut any = false;
        for e in epochs {
            let g = &e.fix;
            if g.time_s < a || g.time_s >= b || !is_reference(g) {
                continue;
            }
            let d = g.position.ned_to(&e.antenna).raw();
            m[0] = m[0].max(d.xy().norm());
            m[1] = m[1].max(d.z.abs());
            m[2] = m[2].max(d.norm());
            any = true;
        }
        if any {
            maxima.push(m);
        }
    }
    let rms = |i: usize| {
        (maxima.iter().map(|m| m[i] * m[i]).sum::<f64>() / maxima.len().max(1) as f64).sqrt()
    };
    OutageScore {
        outage_s: length_s,
        windows: maxima.len(),
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
    /// Windows scored.
    pub windows: usize,
    /// Mean σ_GNSS over the windows' epochs \[m\].
    pub sigma_gnss_m: f64,
    /// Mean over windows of the outage age at which K_eff first falls below
    /// 1 (windows where it never does count as L) \[s\].
    pub predicted_crossing_s: f64,
    /// Windows where it fell below 1.
    pub predicted_crossed: usize,
    /// Mean over windows of the age at which the actual 3-D error against
    /// the RTK-fixed reference first exceeds σ_GNSS (censored at L) \[s\].
    pub actual_crossing_s: f64,
    /// Windows where it did.
    pub actual_crossed: usize,
}

/// The efficiency criterion of a run with outage windows (see [`EfficiencyScore`]).
pub fn efficiency_in_windows(
    epochs: &[Epoch],
    windows: &[(f64, f64)],
    length_s: f64,
) -> EfficiencyScore {
    let (mut n, mut sigma_sum, mut sigma_n) = (0usize, 0.0, 0usize);
    let (mut predicted, mut actual) = ((0.0, 0usize), (0.0, 0usize));
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
        for (acc, crossing) in [
            (&mut predicted, first(&|e| e.k_eff < 1.0)),
            (
                &mut actual,
                first(&|e| {
                    is_reference(&e.fix) && e.fix.position.ned_to(&e.antenna).norm() > sigma_gnss(e)
                }),
            ),
        ] {
            acc.0 += crossing.unwrap_or(length_s);
            acc.1 += usize::from(crossing.is_some());
        }
    }
    let mean = |x: f64| x / n.max(1) as f64;
    EfficiencyScore {
        outage_s: length_s,
        windows: n,
        sigma_gnss_m: sigma_sum / sigma_n.max(1) as f64,
        predicted_crossing_s: mean(predicted.0),
        predicted_crossed: predicted.1,
        actual_crossing_s: mean(actual.0),
        actual_crossed: actual.1,
    }
}

/// Whether a fix serves as the reference of the scores: RTK fixed (Q = 1),
/// or of unknown quality (Q = 0, formats without a quality column).
fn is_reference(g: &GnssFix) -> bool {
    g.quality == 1 || g.quality == 0
}

/// RMS 3-D error over all RTK-fixed epochs against the clean fixes.
pub fn tracking_rms(epochs: &[Epoch]) -> f64 {
    let (sum, n) = epochs
        .iter()
        .filter(|e| is_reference(&e.fix))
        .fold((0.0, 0usize), |(s, n), e| {
            (s + e.fix.position.ned_to(&e.antenna).norm_squared(), n + 1)
        });
    (sum / n.max(1) as f64).sqrt()
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

/// RMS 3-D error over the RTK-fixed epochs where GNSS was used (not
/// withheld), against the clean fixes.
pub fn tracking_rms_with_gnss(epochs: &[Epoch]) -> f64 {
    let used: Vec<Epoch> = epochs
        .iter()
        .filter(|e| e.outcome.is_some())
        .copied()
        .collect();
    tracking_rms(&used)
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
