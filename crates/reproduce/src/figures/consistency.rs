//! The consistency demo's figure: mean NEES per epoch of every variant
//! against the χ² interval.

use std::path::Path;

use crate::consistency::{ConsistencyResult, ConsistencyScenario};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};

/// `nees.svg`: each variant's mean NEES per epoch (log scale) and the
/// per-epoch χ² interval of the run mean.
pub fn nees_figure(
    scenario: &ConsistencyScenario,
    result: &ConsistencyResult,
    out: &Path,
) -> Result<(), IoError> {
    let (lo, hi) = result.nees_epoch_bounds;
    let epochs = scenario.epochs;
    let t = |k: usize| k as f64 * scenario.dt_s;
    let mut series: Vec<Series> = result
        .variants
        .iter()
        .enumerate()
        .map(|(i, v)| Series {
            label: format!("{} (Q×{}, R×{})", v.name, v.q_scale, v.r_scale),
            points: v
                .nees_per_epoch
                .iter()
                .enumerate()
                .map(|(k, &y)| (t(k), y))
                .collect(),
            style: LineStyle::Solid,
            color: i,
        })
        .collect();
    for (b, label) in [(lo, "χ² interval, lower"), (hi, "χ² interval, upper")] {
        series.push(Series {
            label: label.into(),
            points: vec![(0.0, b), (t(epochs - 1), b)],
            style: LineStyle::Dashed,
            color: TRUTH_COLOR,
        });
    }
    LineChart {
        title: format!("Mean NEES over {} runs (2 states)", scenario.runs),
        x_label: "time [s]".into(),
        y_label: "NEES".into(),
        series,
        log_y: true,
    }
    .write_svg(&out.join("nees.svg"))
}
