//! Spec 10's figures: Figs. 1–3 for the scenario's figure trajectory and
//! the forced-switch sweep.

use std::path::Path;

use crate::extended_state::{ExtendedStateResult, ExtendedStateScenario, SwitchKind};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};

/// Spec 10's figures for the scenario's figure trajectory (run 0): Fig. 1
/// (estimation error of Δẍ10 and K_ẍ1 with ±σ), Fig. 2 (δ(n)), Fig. 3
/// (|Δx(t)| for each threshold) and the ratio against a forced switch time.
pub fn extended_state_figures(
    sc: &ExtendedStateScenario,
    r: &ExtendedStateResult,
    out: &Path,
) -> Result<(), IoError> {
    let target = &sc.targets[sc.figure_target];
    let name = format!("t_B = {:.0} s, φ = {:.0}°", target.t_b_s, target.course_deg);
    fig1_instrument_errors(r, &name, out)?;
    fig2_delta(sc, r, &name, out)?;
    fig3_position_error(sc, r, &name, out)?;
    switch_sweep(sc, r, &name, out)
}

/// Fig. 1: estimation error of Δẍ10 and K_ẍ1 with the filter's ±σ.
fn fig1_instrument_errors(r: &ExtendedStateResult, name: &str, out: &Path) -> Result<(), IoError> {
    let h = &r.history;
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
    Ok(())
}

/// Fig. 2: δ(n) since fixes started, with the thresholds.
fn fig2_delta(
    sc: &ExtendedStateScenario,
    r: &ExtendedStateResult,
    name: &str,
    out: &Path,
) -> Result<(), IoError> {
    let h = &r.history;
    let target = &sc.targets[sc.figure_target];
    let fusion: Vec<(f64, f64)> = h
        .time_s
        .iter()
        .zip(&h.delta)
        .filter(|&(_, &d)| d > 0.0)
        .map(|(&t, &d)| (t - sc.fusion_start_s, 100.0 * d))
        .collect();
    // The forecast rule's input on the same scale: the relative reduction
    // of the forecast t_B position-error variance per fix.
    let forecast: Vec<(f64, f64)> = h
        .time_s
        .iter()
        .zip(&h.forecast_reduction)
        .filter(|&(_, &d)| d > 0.0)
        .map(|(&t, &d)| (t - sc.fusion_start_s, 100.0 * d * sc.fix_interval_s))
        .collect();
    let mut series = vec![
        Series {
            label: "δ(n)".into(),
            points: fusion,
            style: LineStyle::Solid,
            color: 0,
        },
        Series {
            label: "t_B forecast: variance reduction per fix".into(),
            points: forecast,
            style: LineStyle::Solid,
            color: 1 + sc.thresholds.len(),
        },
        Series {
            label: "instrument share of the t_B forecast".into(),
            points: h
                .time_s
                .iter()
                .zip(&h.forecast_share)
                .map(|(&t, &s)| (t - sc.fusion_start_s, 100.0 * s))
                .collect(),
            style: LineStyle::Dashed,
            color: 2 + sc.thresholds.len(),
        },
    ];
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
    Ok(())
}

/// Fig. 3: |Δx(t)| of the free INS, the corrected one, and each threshold.
fn fig3_position_error(
    sc: &ExtendedStateScenario,
    r: &ExtendedStateResult,
    name: &str,
    out: &Path,
) -> Result<(), IoError> {
    let h = &r.history;
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
    Ok(())
}

/// The ratio at t_B against a forced switch time, and the criterion's switches.
fn switch_sweep(
    sc: &ExtendedStateScenario,
    r: &ExtendedStateResult,
    name: &str,
    out: &Path,
) -> Result<(), IoError> {
    let target = &sc.targets[sc.figure_target];
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
            label: match c.rule {
                SwitchKind::ForecastShare => format!(
                    "instrument share ≤ {:.0} %: switch {:.0} s",
                    100.0 * c.delta_threshold,
                    c.switch_time_s
                ),
                SwitchKind::Forecast => format!(
                    "t_B forecast, {:.1} %/s: switch {:.0} s",
                    100.0 * c.delta_threshold,
                    c.switch_time_s
                ),
                SwitchKind::DeltaLiteral => format!(
                    "δ ≤ {:.0} % literally: switch {:.0} s",
                    100.0 * c.delta_threshold,
                    c.switch_time_s
                ),
                SwitchKind::DeltaArmed => format!(
                    "criterion, δ_thr = {:.0} %: switch {:.0} s",
                    100.0 * c.delta_threshold,
                    c.switch_time_s
                ),
            },
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
