//! Spec 20's anomalies figures: Figs. 3–8 drawn like the paper's (INS
//! error and its estimate with anomalous fixes) and the estimation errors of
//! run 0.

use std::path::Path;

use crate::anomalies::{AnomaliesResult, ESTIMATORS, ExampleRun};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};

/// The estimators drawn against the truth in Figs. 3–8.
const DRAWN: [&str; 3] = ["kf_plain", "kf_reject", "developed"];

/// Which state a figure shows.
#[derive(Clone, Copy)]
enum State {
    Velocity,
    /// The tilt; the constant accelerometer bias is absorbed by the filter
    /// as this equivalent tilt B/g (rad), drawn as a second truth curve.
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
pub fn anomaly_figures(
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

/// `anomalies_example.svg`: the estimation error of the drawn estimators over
/// run 0 (estimates overlap the truth at this scale) and the anomalous fixes;
/// `dt` is the epoch interval \[s\].
pub fn anomaly_example_figure(
    result: &AnomaliesResult,
    dt: f64,
    out: &Path,
) -> Result<(), IoError> {
    let ex = &result.example;
    let pick = ["kf_plain", "kf_reject", "developed"];
    let mut series = Vec::new();
    for (c, name) in pick.iter().enumerate() {
        if let Some(i) = ESTIMATORS.iter().position(|e| e == name) {
            series.push(Series {
                label: format!("{name}: estimate − true δV"),
                points: ex.estimates[i]
                    .iter()
                    .zip(&ex.truth)
                    .enumerate()
                    .map(|(k, (&v, &t))| (k as f64 * dt, v - t))
                    .collect(),
                style: LineStyle::Solid,
                color: c,
            });
        }
    }
    series.push(Series {
        label: "anomalous fix".into(),
        points: (0..ex.truth.len())
            .filter(|&k| ex.anomalous[k])
            .map(|k| (k as f64 * dt, 0.0))
            .collect(),
        style: LineStyle::Points,
        color: 3,
    });
    LineChart {
        title: "Error of the INS velocity-error estimate, run 0 (true δV in the CSV)".into(),
        x_label: "time [s]".into(),
        y_label: "estimate − truth [m/s]".into(),
        series,
        log_y: false,
    }
    .write_svg(&out.join("anomalies_example.svg"))
}
