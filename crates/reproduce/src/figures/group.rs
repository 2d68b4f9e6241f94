//! Spec 30's figures: the one-axis group's position and velocity errors
//! (the paper's Fig. 6)
//! and the formation's 3-D position errors.

use std::path::Path;

use crate::formation::{FormationResult, FormationScenario, SweepCell};
use crate::group::{CaseScore, GroupResult, GroupScenario};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series};

/// Fig. 6 of the paper in two files: `group_errors.svg` (its position
/// panel) and `group_velocity_errors.svg` (its velocity panel); per case,
/// the Monte Carlo RMS and the filter's σ per epoch.
pub fn group_figure(
    scenario: &GroupScenario,
    result: &GroupResult,
    out: &Path,
) -> Result<(), IoError> {
    type Pick = fn(&CaseScore) -> (&[f64], &[f64]);
    let panels: [(&str, &str, &str, Pick); 2] = [
        ("group_errors.svg", "Position", "position error [m]", |c| {
            (&c.rms_by_epoch, &c.sigma_by_epoch)
        }),
        (
            "group_velocity_errors.svg",
            "Velocity",
            "velocity error [m/s]",
            |c| (&c.velocity_rms_by_epoch, &c.velocity_sigma_by_epoch),
        ),
    ];
    for (file, quantity, y_label, pick) in panels {
        let mut series = Vec::new();
        for (i, c) in result.cases.iter().enumerate() {
            let case_dt = scenario.cases()[i].dt_s;
            let trace = |v: &[f64]| -> Vec<(f64, f64)> {
                v.iter()
                    .enumerate()
                    .map(|(e, &y)| (e as f64 * case_dt, y))
                    .collect()
            };
            let (rms, sigma) = pick(c);
            series.push(Series {
                label: format!("{}: Monte Carlo RMS", c.name),
                points: trace(rms),
                style: LineStyle::Solid,
                color: i,
            });
            series.push(Series {
                label: format!("{}: filter σ", c.name),
                points: trace(sigma),
                style: LineStyle::Dashed,
                color: i,
            });
        }
        LineChart {
            title: format!(
                "{quantity} error per member, one axis, {} runs (paper Fig. 6)",
                scenario.runs
            ),
            x_label: "time [s]".into(),
            y_label: y_label.into(),
            series,
            log_y: false,
        }
        .write_svg(&out.join(file))?;
    }
    Ok(())
}

/// `formation_errors.svg`: each GNSS-denied or -degraded member alone and in
/// the group (both stage-2 forms), and the mean of the other members.
pub fn formation_figure(
    scenario: &FormationScenario,
    result: &FormationResult,
    out: &Path,
) -> Result<(), IoError> {
    let labels = ["GNSS/INS alone", "paper fusion", "EKF fusion"];
    let mut series = Vec::new();
    let trace = |pick: &dyn Fn(&[[f64; 3]], usize) -> f64, s: usize| -> Vec<(f64, f64)> {
        result
            .time_s
            .iter()
            .zip(&result.error_by_epoch)
            .map(|(&t, e)| (t, pick(e, s)))
            .collect()
    };
    let denied: Vec<usize> = result
        .members
        .iter()
        .filter(|m| m.denied || m.degraded)
        .map(|m| m.member)
        .collect();
    for &l in &denied {
        let what = match (result.members[l].denied, result.members[l].degraded) {
            (true, true) => "GNSS denied and degraded",
            (true, false) => "GNSS denied",
            _ => "GNSS degraded",
        };
        for (s, label) in labels.iter().enumerate() {
            series.push(Series {
                label: format!("member {l} ({what}): {label}"),
                points: trace(&|e, s| e[l][s], s),
                style: LineStyle::Solid,
                color: s,
            });
        }
    }
    let others: Vec<usize> = (0..scenario.members)
        .filter(|l| !denied.contains(l))
        .collect();
    if !others.is_empty() {
        for (s, label) in labels.iter().enumerate() {
            series.push(Series {
                label: format!("other members (mean): {label}"),
                points: trace(
                    &|e, s| others.iter().map(|&l| e[l][s]).sum::<f64>() / others.len() as f64,
                    s,
                ),
                style: LineStyle::Dashed,
                color: s,
            });
        }
    }
    LineChart {
        title: format!(
            "Formation of {}: 3-D position error, RMS over {} runs",
            scenario.members, scenario.runs
        ),
        x_label: "time [s]".into(),
        y_label: "position error [m]".into(),
        series,
        log_y: true,
    }
    .write_svg(&out.join("formation_errors.svg"))
}

/// `network_sweep.svg`: the members that keep GNSS, mean 3-D position RMS
/// against the network's latency, one line per loss rate (EKF solid, paper
/// fusion dashed), and GNSS/INS alone for reference.
pub fn network_sweep_figure(
    scenario: &FormationScenario,
    sweep: &[SweepCell],
    out: &Path,
) -> Result<(), IoError> {
    let mut losses: Vec<f64> = Vec::new();
    for c in sweep {
        if !losses.contains(&c.loss_probability) {
            losses.push(c.loss_probability);
        }
    }
    let mut series = Vec::new();
    for (i, &loss) in losses.iter().enumerate() {
        let line = |s: usize| -> Vec<(f64, f64)> {
            sweep
                .iter()
                .filter(|c| c.loss_probability == loss)
                .map(|c| (c.latency_s, c.kept_rms_m[s]))
                .collect()
        };
        series.push(Series {
            label: format!("EKF fusion, loss {:.0} %", 100.0 * loss),
            points: line(2),
            style: LineStyle::Solid,
            color: i,
        });
        series.push(Series {
            label: format!("paper fusion, loss {:.0} %", 100.0 * loss),
            points: line(1),
            style: LineStyle::Dashed,
            color: i,
        });
    }
    series.push(Series {
        label: "GNSS/INS alone".into(),
        points: sweep
            .iter()
            .filter(|c| c.loss_probability == losses[0])
            .map(|c| (c.latency_s, c.kept_rms_m[0]))
            .collect(),
        style: LineStyle::Solid,
        color: losses.len(),
    });
    LineChart {
        title: format!(
            "Formation of {} over a network: members keeping GNSS, RMS over {} runs",
            scenario.members, scenario.runs
        ),
        x_label: "latency [s]".into(),
        y_label: "3-D position error RMS [m]".into(),
        series,
        log_y: false,
    }
    .write_svg(&out.join("network_sweep.svg"))
}
