//! Spec 20's outages figures: Fig. 9 (the predictors and the relay during
//! the long outage), K_eff through the outage and recovery, and Fig. 10's
//! navigation errors by source.

use std::path::Path;

use crate::outages::{EfficiencyExample, OutagesResult, PREDICTORS};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};

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

/// `outage_predictors.svg` (Fig. 9): run 0's true δV through the long
/// outage and every predictor's prediction of it.
pub fn outage_predictors_figure(result: &OutagesResult, out: &Path) -> Result<(), IoError> {
    let ex = &result.example;
    let mut series = vec![Series {
        label: "true δV (uncorrected INS error)".into(),
        points: ex
            .age_s
            .iter()
            .copied()
            .zip(ex.truth.iter().copied())
            .collect(),
        style: LineStyle::Solid,
        color: TRUTH_COLOR,
    }];
    for (j, name) in PREDICTORS.iter().enumerate() {
        series.push(Series {
            label: format!("predicted, {name}"),
            points: ex
                .age_s
                .iter()
                .copied()
                .zip(ex.predictions[j].iter().copied())
                .collect(),
            style: if *name == "relay" {
                LineStyle::Solid
            } else {
                LineStyle::Dashed
            },
            color: j,
        });
    }
    LineChart {
        title: format!(
            "Predictors during a {:.0} s GNSS outage, run 0",
            result.long.length_s
        ),
        x_label: "time since the outage started [s]".into(),
        y_label: "δV [m/s]".into(),
        series,
        log_y: false,
    }
    .write_svg(&out.join("outage_predictors.svg"))
}

/// `efficiency.svg`: run 0's K_eff from the outage start to the end of
/// recovery, with the K_eff = 1 switching line.
pub fn efficiency_figure(eff: &EfficiencyExample, out: &Path) -> Result<(), IoError> {
    let end = eff.age_s.last().copied().unwrap_or(1.0);
    LineChart {
        title: "Efficiency criterion K_eff = σ_GNSS / σ_KOI, run 0 (outage, then GNSS back)".into(),
        x_label: "time since the outage started [s]".into(),
        y_label: "K_eff".into(),
        series: vec![
            Series {
                label: "K_eff".into(),
                points: eff
                    .age_s
                    .iter()
                    .copied()
                    .zip(eff.k_eff.iter().copied())
                    .collect(),
                style: LineStyle::Solid,
                color: 0,
            },
            Series {
                label: "K_eff = 1 (above: INS + filter, below: GNSS)".into(),
                points: vec![(0.0, 1.0), (end, 1.0)],
                style: LineStyle::Dashed,
                color: TRUTH_COLOR,
            },
        ],
        log_y: true,
    }
    .write_svg(&out.join("efficiency.svg"))
}
