//! The spec-20 figures drawn like the paper's (seed 004): Figs. 3–8 (INS
//! error and its estimate with anomalous fixes) and Fig. 10's navigation
//! errors by source. Fig. 9 (predictors and the relay) is drawn by the
//! outages job itself.

use std::path::Path;

use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};
use aidnav_sim::experiments::anomalies::{AnomaliesResult, ESTIMATORS, ExampleRun};
use aidnav_sim::experiments::outages::EfficiencyExample;

/// The estimators drawn against the truth in Figs. 3–8.
const DRAWN: [&str; 3] = ["kf_plain", "kf_reject", "developed"];

/// Which state a figure shows.
#[derive(Clone, Copy)]
enum State {
    Velocity,
    /// The tilt; the constant accelerometer bias is absorbed by the filter
    /// as this equivalent tilt B/g [rad], drawn as a second truth curve.
    Tilt(f64),
}

/// Truth, the `DRAWN` estimates and the anomalous epochs of `run` over the
/// epochs `from..to`, for one state.
fn estimate_chart(
    run: &ExampleRun,
    state: State,
    from: usize,
    to: usize,
    dt: f64,
    title: String,
) -> LineChart {
    let (truth, estimates, scale, y_label) = match state {
        State::Velocity => (&run.truth, &run.estimates, 1.0, "δV [m/s]"),
        State::Tilt(_) => (&run.tilt, &run.tilt_estimates, 1e3, "tilt φ [mrad]"),
    };
    let to = to.min(truth.len());
    let trace = |v: &[f64]| -> Vec<(f64, f64)> {
        (from..to).map(|k| (k as f64 * dt, scale * v[k])).collect()
    };
    let mut series = vec![Series {
        label: "1 — INS error (truth)".into(),
        points: trace(truth),
        style: LineStyle::Solid,
        color: TRUTH_COLOR,
    }];
    if let State::Tilt(offset) = state {
        series.push(Series {
            label: "1′ — φ − B/g (the tilt a 3-state filter can estimate)".into(),
            points: (from..to)
                .map(|k| (k as f64 * dt, scale * (truth[k] - offset)))
                .collect(),
            style: LineStyle::Dashed,
            color: TRUTH_COLOR,
        });
    }
    for (c, name) in DRAWN.iter().enumerate() {
        if let Some(i) = ESTIMATORS.iter().position(|e| e == name) {
            series.push(Series {
                label: format!("2 — estimate, {name}"),
                points: trace(&estimates[i]),
                style: LineStyle::Dashed,
                color: c,
            });
        }
    }
    series.push(Series {
        label: "anomalous fix (on the truth)".into(),
        points: (from..to)
            .filter(|&k| run.anomalous[k])
            .map(|k| (k as f64 * dt, scale * truth[k]))
            .collect(),
        style: LineStyle::Points,
        color: 3,
    });
    LineChart {
        title,
        x_label: "time [s]".into(),
        y_label: y_label.into(),
        series,
        log_y: false,
    }
}

/// Figs. 3–8 into `out`; returns the file names written.
pub(crate) fn anomaly_figures(
    result: &AnomaliesResult,
    at_epoch: usize,
    dt: f64,
    equivalent_tilt_rad: f64,
    out: &Path,
) -> Result<Vec<&'static str>, IoError> {
    let tilt = State::Tilt(equivalent_tilt_rad);
    // Around the hand-placed fault: a little before, long enough after to
    // see the tilt estimate recover.
    let (from, to) = (at_epoch.saturating_sub(100), at_epoch + 400);
    let full = result.example.truth.len();
    let figures: [(&str, &ExampleRun, State, usize, usize, &str); 6] = [
        (
            "fig03_outlier_velocity.svg",
            &result.outlier,
            State::Velocity,
            from,
            to,
            "Fig. 3: δV and its estimates, single outlier",
        ),
        (
            "fig04_outlier_tilt.svg",
            &result.outlier,
            tilt,
            from,
            to,
            "Fig. 4: platform tilt and its estimates, single outlier",
        ),
        (
            "fig05_burst_velocity.svg",
            &result.burst,
            State::Velocity,
            from,
            to,
            "Fig. 5: δV and its estimates, burst of anomalies",
        ),
        (
            "fig06_burst_tilt.svg",
            &result.burst,
            tilt,
            from,
            to,
            "Fig. 6: platform tilt and its estimates, burst of anomalies",
        ),
        (
            "fig07_random_velocity.svg",
            &result.example,
            State::Velocity,
            0,
            full,
            "Fig. 7: δV and its estimates, random anomalies (run 0)",
        ),
        (
            "fig08_random_tilt.svg",
            &result.example,
            tilt,
            0,
            full,
            "Fig. 8: platform tilt and its estimates, random anomalies (run 0)",
        ),
    ];
    for (name, run, state, a, b, title) in figures {
        estimate_chart(run, state, a, b, dt, title.into()).write_svg(&out.join(name))?;
    }
    Ok(figures.map(|f| f.0).to_vec())
}

/// Fig. 10's navigation errors after the outage: GNSS alone, INS + filter,
/// and the source chosen by K_eff (σ_KOI = √P⁻).
pub(crate) fn recovery_figure(ex: &EfficiencyExample, out: &Path) -> Result<&'static str, IoError> {
    let name = "fig10_recovery_errors.svg";
    // The recovery epochs are the last ones of `age_s`.
    let recovery_age = &ex.age_s[ex.age_s.len().saturating_sub(ex.gnss_error.len())..];
    let trace = |v: &[f64]| -> Vec<(f64, f64)> {
        recovery_age
            .iter()
            .copied()
            .zip(v.iter().copied())
            .collect()
    };
    LineChart {
        title: "Fig. 10: velocity error after the outage by navigation source, run 0".into(),
        x_label: "time since the outage started [s]".into(),
        y_label: "navigation error [m/s]".into(),
        series: vec![
            Series {
                label: "GNSS alone".into(),
                points: trace(&ex.gnss_error),
                style: LineStyle::Points,
                color: 1,
            },
            Series {
                label: "INS + filter (estimation error)".into(),
                points: trace(&ex.integrated_error),
                style: LineStyle::Solid,
                color: 0,
            },
            Series {
                label: "chosen by K_eff (σ_KOI = √P⁻)".into(),
                points: trace(&ex.selected_error),
                style: LineStyle::Dashed,
                color: 2,
            },
        ],
        log_y: false,
    }
    .write_svg(&out.join(name))?;
    Ok(name)
}
