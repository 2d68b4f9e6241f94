//! The spec-20 figures drawn like the paper's (seed 004): Figs. 3–8 (INS
//! error and its estimate with anomalous fixes) and Fig. 10's navigation
//! errors by source. Fig. 9 (predictors and the relay) is drawn by the
//! outages job itself. Spec 10's Figs. 1–3 and the forced-switch sweep
//! ([`extended_state_figures`]).

use std::path::Path;

use crate::anomalies::{AnomaliesResult, ESTIMATORS, ExampleRun};
use crate::extended_state::{ExtendedStateResult, ExtendedStateScenario};
use crate::outages::EfficiencyExample;
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};

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

/// Fig. 10's navigation errors after the outage: GNSS alone, INS + filter,
/// and the source chosen by K_eff (σ_KOI = √P⁻).
pub fn recovery_figure(ex: &EfficiencyExample, out: &Path) -> Result<&'static str, IoError> {
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

/// Spec 10's figures for the scenario's figure trajectory (run 0): Fig. 1
/// (estimation error of Δẍ10 and K_ẍ1 with ±σ), Fig. 2 (δ(n)), Fig. 3
/// (|Δx(t)| for each threshold) and the ratio against a forced switch time.
pub fn extended_state_figures(
    sc: &ExtendedStateScenario,
    r: &ExtendedStateResult,
    out: &Path,
) -> Result<(), IoError> {
    let h = &r.history;
    let target = &sc.targets[sc.figure_target];
    let name = format!("t_B = {:.0} s, φ = {:.0}°", target.t_b_s, target.course_deg);
    for (index, file, label, unit_scale, unit) in [
        (0, "fig1_accel_bias_error.svg", "Δẍ10", 1.0, "m/s²"),
        (3, "fig1_scale_factor_error.svg", "K_ẍ1", 1.0, "—"),
    ] {
        let pick = |v: &Vec<[f64; 8]>, sign: f64| -> Vec<(f64, f64)> {
            h.time_s
                .iter()
                .zip(v)
                .map(|(&t, x)| (t, sign * x[index] * unit_scale))
                .collect()
        };
        LineChart {
            title: format!("Fig. 1: estimation error of {label}, {name}, run 0"),
            x_label: "flight time [s]".into(),
            y_label: format!("{label} error [{unit}]"),
            series: vec![
                Series {
                    label: "estimate − truth".into(),
                    points: pick(&h.instrument_error, 1.0),
                    style: LineStyle::Solid,
                    color: 0,
                },
                Series {
                    label: "+σ (filter)".into(),
                    points: pick(&h.instrument_sigma, 1.0),
                    style: LineStyle::Dashed,
                    color: TRUTH_COLOR,
                },
                Series {
                    label: "−σ (filter)".into(),
                    points: pick(&h.instrument_sigma, -1.0),
                    style: LineStyle::Dashed,
                    color: TRUTH_COLOR,
                },
            ],
            log_y: false,
        }
        .write_svg(&out.join(file))?;
    }
    let fusion: Vec<(f64, f64)> = h
        .time_s
        .iter()
        .zip(&h.delta)
        .filter(|&(_, &d)| d > 0.0)
        .map(|(&t, &d)| (t - sc.fusion_start_s, 100.0 * d))
        .collect();
    let mut series = vec![Series {
        label: "δ(n)".into(),
        points: fusion,
        style: LineStyle::Solid,
        color: 0,
    }];
    let span = (0.0, target.t_b_s - sc.fusion_start_s);
    for (i, thr) in sc.thresholds.iter().enumerate() {
        series.push(Series {
            label: format!("δ_thr = {:.0} %", 100.0 * thr),
            points: vec![(span.0, 100.0 * thr), (span.1, 100.0 * thr)],
            style: LineStyle::Dashed,
            color: 1 + i,
        });
    }
    LineChart {
        title: format!("Fig. 2: convergence measure δ(n), {name}"),
        x_label: "time since fixes started [s]".into(),
        y_label: "δ(n) [%]".into(),
        series,
        log_y: true,
    }
    .write_svg(&out.join("fig2_delta.svg"))?;
    let curve = |v: &[f64]| -> Vec<(f64, f64)> {
        r.error_time_s
            .iter()
            .zip(v)
            .filter(|&(_, &e)| e.is_finite() && e > 0.0)
            .map(|(&t, &e)| (t, e))
            .collect()
    };
    let mut series = vec![
        Series {
            label: "free INS".into(),
            points: curve(&r.error_free),
            style: LineStyle::Solid,
            color: TRUTH_COLOR,
        },
        Series {
            label: "with fixes (navigation states corrected)".into(),
            points: h
                .time_s
                .iter()
                .zip(&h.position_error_m)
                .map(|(&t, &e)| (t, e.max(1e-3)))
                .collect(),
            style: LineStyle::Solid,
            color: 5,
        },
    ];
    for (i, thr) in sc.thresholds.iter().enumerate() {
        series.push(Series {
            label: format!("proposed, δ_thr = {:.0} %", 100.0 * thr),
            points: curve(&r.error_proposed[i]),
            style: LineStyle::Solid,
            color: i,
        });
        series.push(Series {
            label: format!("outputs only, δ_thr = {:.0} %", 100.0 * thr),
            points: curve(&r.error_outputs_only[i]),
            style: LineStyle::Dashed,
            color: i,
        });
    }
    LineChart {
        title: format!("Fig. 3: position error |Δx(t)|, {name}, run 0"),
        x_label: "flight time [s]".into(),
        y_label: "|Δx| [m]".into(),
        series,
        log_y: true,
    }
    .write_svg(&out.join("fig3_position_error.svg"))?;
    let sweep = |k: usize| -> Vec<(f64, f64)> {
        r.sweep
            .iter()
            .filter(|p| p.ratio[k].is_finite() && p.ratio[k] > 0.0)
            .map(|p| (p.switch_time_s, p.ratio[k]))
            .collect()
    };
    let mut series = vec![
        Series {
            label: "ratio outputs only / proposed, median".into(),
            points: sweep(0),
            style: LineStyle::Solid,
            color: 0,
        },
        Series {
            label: "10 % quantile".into(),
            points: sweep(1),
            style: LineStyle::Dashed,
            color: 0,
        },
        Series {
            label: "90 % quantile".into(),
            points: sweep(2),
            style: LineStyle::Dashed,
            color: 0,
        },
    ];
    for (i, c) in r
        .cases
        .iter()
        .filter(|c| c.t_b_s == target.t_b_s && c.course_deg == target.course_deg)
        .enumerate()
    {
        series.push(Series {
            label: format!(
                "criterion, δ_thr = {:.0} %: switch {:.0} s",
                100.0 * c.delta_threshold,
                c.switch_time_s
            ),
            points: vec![(c.switch_time_s, c.ratio_median)],
            style: LineStyle::Points,
            color: 1 + i,
        });
    }
    LineChart {
        title: format!(
            "Ratio at t_B against a forced switch time, {name}, {} runs",
            sc.sweep_runs
        ),
        x_label: "switch time (flight time) [s]".into(),
        y_label: "|Δx| outputs only / proposed".into(),
        series,
        log_y: true,
    }
    .write_svg(&out.join("switch_sweep.svg"))?;
    Ok(())
}
