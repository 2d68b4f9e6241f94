//! The jobs behind the CLI's subcommands: each reads its inputs, runs the
//! library, writes its outputs and returns a report for the CLI to print.
//! The CLI itself only parses arguments and prints.

use std::path::{Path, PathBuf};

use aidnav_estimation::{Chi2Mean, EpochRecord, EstimationError, Observer, Outcome, rts_smooth};
use aidnav_io::IoError;
use aidnav_io::measurements::read_measurements;
use aidnav_io::model_file::load_model;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};
use aidnav_io::writers::{FilterCsvWriter, Summary, write_smoothed, write_table};
use aidnav_sim::MonteCarlo;
use aidnav_sim::experiments::anomalies::{AnomaliesResult, AnomaliesScenario, ESTIMATORS};
use aidnav_sim::experiments::consistency::{ConsistencyResult, ConsistencyScenario};
use aidnav_sim::experiments::extended_state::{ExtendedStateResult, ExtendedStateScenario};
use aidnav_sim::experiments::formation::{FormationResult, FormationScenario, SOLUTIONS};
use aidnav_sim::experiments::group::{GroupResult, GroupScenario};
use aidnav_sim::experiments::outages::{OutagesResult, OutagesScenario, PREDICTORS};
use serde::Serialize;

use crate::VERSION;

/// Anything a job can fail with.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum JobError {
    /// Reading or writing files.
    #[error(transparent)]
    Io(#[from] IoError),
    /// The estimation engine (with the file that fed it).
    #[error("{context}: {source}")]
    Estimation {
        /// What was being processed.
        context: String,
        /// The engine's error.
        source: EstimationError,
    },
    /// The extended-state experiment (guidance solution or filter).
    #[error("extended-state experiment: {0}")]
    ExtendedState(#[from] aidnav_sim::experiments::extended_state::ExtendedStateError),
    /// The outages experiment (its filter or its model selection).
    #[error("outages experiment: {0}")]
    Outages(#[from] aidnav_sim::experiments::outages::OutagesError),
    /// The job refuses the request (size limits and the like).
    #[error("{0}")]
    Refused(String),
}

/// Result alias of the jobs.
pub type JobResult<T> = Result<T, JobError>;

/// Wrap an engine error with what was being computed.
fn estimation(context: &str) -> impl FnOnce(EstimationError) -> JobError + '_ {
    move |source| JobError::Estimation {
        context: context.into(),
        source,
    }
}

/// Memory the RTS smoother may use for the stored forward pass before the job
/// refuses (two n×n matrices and two n-vectors per epoch).
pub const MAX_SMOOTHER_BYTES: usize = 4 << 30;

/// Inputs of `aidnav filter`.
#[derive(Debug, Clone)]
pub struct FilterJob {
    /// Model TOML.
    pub model: PathBuf,
    /// Measurement CSV.
    pub measurements: PathBuf,
    /// Output directory.
    pub out: PathBuf,
    /// Also run the RTS smoother.
    pub smooth: bool,
    /// Also write the full covariance per epoch.
    pub full_covariance: bool,
    /// Cap on epochs read.
    pub max_epochs: usize,
}

/// What `aidnav filter` reports.
#[derive(Debug, Clone, Serialize)]
pub struct FilterReport {
    /// Epochs processed.
    pub epochs: usize,
    /// State names.
    pub states: Vec<String>,
    /// Final estimate.
    pub final_state: Vec<f64>,
    /// Final 1σ.
    pub final_sigma: Vec<f64>,
    /// Mean NIS over the updates (per degree of freedom: 1 when consistent).
    pub mean_nis_per_dof: f64,
    /// Updates by outcome.
    pub outcomes: std::collections::BTreeMap<String, usize>,
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Accumulates the NIS and outcome counts of a run.
#[derive(Default)]
struct RunStats {
    nis: Chi2Mean,
    outcomes: std::collections::BTreeMap<String, usize>,
}

impl Observer for RunStats {
    fn observe_epoch(&mut self, r: &EpochRecord) {
        if r.outcome != Outcome::Missing && r.nis.is_finite() {
            self.nis.push(r.nis, r.dof);
        }
        *self
            .outcomes
            .entry(r.outcome.as_str().to_string())
            .or_default() += 1;
    }
}

/// Run a linear Kalman filter from a model file over a measurement CSV.
pub fn filter(job: &FilterJob) -> JobResult<FilterReport> {
    let loaded = load_model(&job.model)?;
    let table = read_measurements(&job.measurements, &loaded.measurement_names, job.max_epochs)?;
    let n = loaded.model.states();
    if job.smooth {
        let per_epoch = (2 * n * n + 2 * n) * std::mem::size_of::<f64>();
        if per_epoch.saturating_mul(table.len()) > MAX_SMOOTHER_BYTES {
            return Err(JobError::Refused(format!(
                "{}: smoothing {} epochs of {n} states needs {} MiB for the forward pass, over the {} MiB limit; split the file",
                job.measurements.display(),
                table.len(),
                per_epoch.saturating_mul(table.len()) >> 20,
                MAX_SMOOTHER_BYTES >> 20
            )));
        }
    }
    let mut writer = FilterCsvWriter::create(
        &job.out,
        &loaded.state_names,
        &loaded.measurement_names,
        job.full_covariance,
    )?;
    let mut stats = RunStats::default();
    let mut options = loaded.options;
    options.keep_covariance = job.full_covariance;
    options.keep_forward_pass = job.smooth;
    let out = {
        let mut both = (&mut writer, &mut stats);
        loaded
            .model
            .run(table.epochs(), &options, &mut both)
            .map_err(|source| JobError::Estimation {
                context: format!(
                    "{} with {}",
                    job.model.display(),
                    job.measurements.display()
                ),
                source,
            })?
    };
    writer.finish()?;
    let mut files = vec![
        job.out.join("estimates.csv"),
        job.out.join("innovations.csv"),
    ];
    if job.full_covariance {
        files.push(job.out.join("covariance.csv"));
    }
    if job.smooth {
        let smoothed = rts_smooth(&out.forward).map_err(|source| JobError::Estimation {
            context: format!("smoothing {}", job.measurements.display()),
            source,
        })?;
        files.push(write_smoothed(
            &job.out,
            &loaded.state_names,
            &table.times,
            &smoothed,
        )?);
    }
    let report = FilterReport {
        epochs: out.epochs,
        states: loaded.state_names.clone(),
        final_state: out.final_state.iter().copied().collect(),
        final_sigma: out
            .final_covariance
            .diagonal()
            .iter()
            .map(|v| v.max(0.0).sqrt())
            .collect(),
        mean_nis_per_dof: stats.nis.mean_per_dof(),
        outcomes: stats.outcomes,
        files: files.clone(),
    };
    let mut summary = Summary::new("filter", VERSION, None, &loaded.file);
    summary.insert("model_file", job.model.display().to_string());
    summary.insert("measurement_file", job.measurements.display().to_string());
    summary.insert("smooth", job.smooth);
    summary.insert("epochs", report.epochs);
    summary.insert("final_state", &report.final_state);
    summary.insert("final_sigma", &report.final_sigma);
    summary.insert("mean_nis_per_dof", report.mean_nis_per_dof);
    summary.insert("outcomes", &report.outcomes);
    let mut report = report;
    report.files.push(summary.write(&job.out)?);
    Ok(report)
}

/// The Monte Carlo runner of an experiment, with or without a progress bar.
fn campaign(runs: usize, seed: u64, label: &str, quiet: bool) -> MonteCarlo {
    let mc = MonteCarlo::new(runs, seed).with_label(label);
    if quiet { mc.quiet() } else { mc }
}

/// Run the consistency demo and write its CSV, plots and `summary.json` into `out`.
pub fn consistency(
    scenario: &ConsistencyScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<ConsistencyResult> {
    let mc = campaign(scenario.runs, scenario.seed, "consistency", quiet);
    let result = aidnav_sim::experiments::consistency::run(scenario, &mc)
        .map_err(estimation("consistency demo"))?;
    aidnav_io::writers::ensure_dir(out)?;
    let (lo, hi) = result.nees_epoch_bounds;
    let epochs = scenario.epochs;
    let t = |k: usize| k as f64 * scenario.dt_s;
    let mut header = vec!["time [s]"];
    let names: Vec<String> = result
        .variants
        .iter()
        .flat_map(|v| [format!("nees_{}", v.name), format!("nis_{}", v.name)])
        .collect();
    header.extend(names.iter().map(String::as_str));
    header.extend(["nees_lower", "nees_upper"]);
    write_table(
        &out.join("consistency.csv"),
        &header,
        (0..epochs).map(|k| {
            let mut row = vec![t(k)];
            for v in &result.variants {
                row.push(v.nees_per_epoch[k]);
                row.push(v.nis_per_epoch[k]);
            }
            row.extend([lo, hi]);
            row
        }),
    )?;
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
    .write_svg(&out.join("nees.svg"))?;
    let mut summary = Summary::new(
        "reproduce consistency",
        VERSION,
        Some(scenario.seed),
        scenario,
    );
    summary.insert("runs", scenario.runs);
    summary.insert("nees_epoch_bounds", result.nees_epoch_bounds);
    summary.insert("variants", &result.variants);
    summary.write(out)?;
    Ok(result)
}

/// Run the spec-20 anomalies experiment and write `anomalies_example.csv`,
/// `anomalies_example.svg`, the paper-like Figs. 3–8 (`fig03_…svg` to
/// `fig08_…svg`) and `summary.json` into `out`.
pub fn anomalies(
    scenario: &AnomaliesScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<AnomaliesResult> {
    let mc = campaign(scenario.runs, scenario.seed, "anomalies", quiet);
    let result = aidnav_sim::experiments::anomalies::run(scenario, &mc)
        .map_err(estimation("anomalies experiment"))?;
    aidnav_io::writers::ensure_dir(out)?;
    let ex = &result.example;
    let dt = scenario.platform.dt_s;
    let mut header: Vec<String> = vec![
        "time [s]".into(),
        "true_dv [m/s]".into(),
        "anomalous".into(),
    ];
    header.extend(ESTIMATORS.iter().map(|e| format!("{e} [m/s]")));
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    write_table(
        &out.join("anomalies_example.csv"),
        &header_ref,
        (0..ex.truth.len()).map(|k| {
            let mut row = vec![
                k as f64 * dt,
                ex.truth[k],
                f64::from(u8::from(ex.anomalous[k])),
            ];
            row.extend(ex.estimates.iter().map(|e| e[k]));
            row
        }),
    )?;
    // Estimates overlap the truth at this scale: plot the estimation errors.
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
    .write_svg(&out.join("anomalies_example.svg"))?;
    let mut summary = Summary::new(
        "reproduce anomalies",
        VERSION,
        Some(scenario.seed),
        scenario,
    );
    let rms: serde_json::Map<String, serde_json::Value> = result
        .scores
        .iter()
        .map(|s| (s.name.clone(), serde_json::json!(s.rms_mps)))
        .collect();
    crate::figures::anomaly_figures(
        &result,
        scenario.illustration.at_epoch,
        dt,
        scenario.platform.equivalent_tilt_rad(),
        out,
    )?;
    summary.insert("rms", rms);
    summary.insert("scores", &result.scores);
    summary.insert("anomaly_fraction", result.anomaly_fraction);
    summary.write(out)?;
    Ok(result)
}

/// Run the spec-20 outages experiment and write `outage_example.csv`,
/// `outage_predictors.svg` (Fig. 9), `efficiency.svg`,
/// `fig10_recovery_errors.svg` and `summary.json` into `out`.
pub fn outages(scenario: &OutagesScenario, out: &Path, quiet: bool) -> JobResult<OutagesResult> {
    let mc = campaign(scenario.runs, scenario.seed, "outages", quiet);
    let result = aidnav_sim::experiments::outages::run(scenario, &mc)?;
    aidnav_io::writers::ensure_dir(out)?;
    let ex = &result.example;
    let mut header: Vec<String> = vec!["outage age [s]".into(), "true_dv [m/s]".into()];
    header.extend(PREDICTORS.iter().map(|p| format!("{p} [m/s]")));
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    write_table(
        &out.join("outage_example.csv"),
        &header_ref,
        (0..ex.truth.len()).map(|k| {
            let mut row = vec![ex.age_s[k], ex.truth[k]];
            row.extend(ex.predictions.iter().map(|p| p[k]));
            row
        }),
    )?;
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
    .write_svg(&out.join("outage_predictors.svg"))?;
    let eff = &result.efficiency_example;
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
    .write_svg(&out.join("efficiency.svg"))?;
    crate::figures::recovery_figure(&result.efficiency_example, out)?;
    let mut summary = Summary::new("reproduce outages", VERSION, Some(scenario.seed), scenario);
    summary.insert("efficiency", &result.efficiency);
    for (key, scores) in [("short", &result.short), ("long", &result.long)] {
        let improvement: serde_json::Map<String, serde_json::Value> = scores
            .predictors
            .iter()
            .map(|p| (p.name.clone(), serde_json::json!(p.improvement)))
            .collect();
        summary.insert(
            key,
            serde_json::json!({
                "length_s": scores.length_s,
                "uncorrected_rms_mps": scores.uncorrected_rms_mps,
                "improvement": improvement,
                "predictors": scores.predictors,
            }),
        );
    }
    summary.write(out)?;
    Ok(result)
}

/// Run the spec-30 group experiment and write `group.csv` (per epoch and
/// case: filter σ and Monte Carlo RMS of position), `group_errors.svg` (like
/// the paper's Fig. 6) and `summary.json` (an object per case `single`,
/// `group_low`, `group_high`) into `out`.
pub fn group(scenario: &GroupScenario, out: &Path, quiet: bool) -> JobResult<GroupResult> {
    let mc = campaign(scenario.runs, scenario.seed, "group", quiet);
    let result = aidnav_sim::experiments::group::run(scenario, &mc)
        .map_err(estimation("group experiment"))?;
    aidnav_io::writers::ensure_dir(out)?;
    let dt = scenario.single.dt_s;
    let mut header = vec!["time [s]".to_string()];
    for c in &result.cases {
        header.push(format!("{}_sigma [m]", c.name));
        header.push(format!("{}_rms [m]", c.name));
    }
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    write_table(
        &out.join("group.csv"),
        &header_ref,
        (0..scenario.epochs).map(|e| {
            let mut row = vec![e as f64 * dt];
            for c in &result.cases {
                row.push(c.sigma_by_epoch[e]);
                row.push(c.rms_by_epoch[e]);
            }
            row
        }),
    )?;
    let mut series = Vec::new();
    for (i, c) in result.cases.iter().enumerate() {
        let case_dt = scenario.cases()[i].dt_s;
        let trace = |v: &[f64]| -> Vec<(f64, f64)> {
            v.iter()
                .enumerate()
                .map(|(e, &y)| (e as f64 * case_dt, y))
                .collect()
        };
        series.push(Series {
            label: format!("{}: Monte Carlo RMS", c.name),
            points: trace(&c.rms_by_epoch),
            style: LineStyle::Solid,
            color: i,
        });
        series.push(Series {
            label: format!("{}: filter σ", c.name),
            points: trace(&c.sigma_by_epoch),
            style: LineStyle::Dashed,
            color: i,
        });
    }
    LineChart {
        title: format!(
            "Position error per member, one axis, {} runs (paper Fig. 6)",
            scenario.runs
        ),
        x_label: "time [s]".into(),
        y_label: "position error [m]".into(),
        series,
        log_y: false,
    }
    .write_svg(&out.join("group_errors.svg"))?;
    let mut summary = Summary::new("reproduce group", VERSION, Some(scenario.seed), scenario);
    for c in &result.cases {
        summary.insert(
            &c.name,
            serde_json::json!({
                "members": c.members,
                "position_sigma_m": c.position_sigma_m,
                "position_rms_m": c.position_rms_m,
                "velocity_sigma_mps": c.velocity_sigma_mps,
                "velocity_rms_mps": c.velocity_rms_mps,
                "steady_position_sigma_m": c.steady_position_sigma_m,
                "steady_velocity_sigma_mps": c.steady_velocity_sigma_mps,
            }),
        );
    }
    summary.write(out)?;
    Ok(result)
}

/// Run the spec-30 formation pipeline (stage-1 INS/GNSS per member, stage-2
/// group fusion in the paper's and the EKF form) and write `formation.csv`
/// (per epoch and member: RMS over runs of the 3-D position error of each
/// solution), `formation_errors.svg` (each GNSS-denied member alone and in
/// the group, and the mean of the others) and `summary.json` (list `members`)
/// into `out`.
pub fn formation(
    scenario: &FormationScenario,
    command: &str,
    out: &Path,
    quiet: bool,
) -> JobResult<FormationResult> {
    let mc = campaign(scenario.runs, scenario.seed, "formation", quiet);
    let result = aidnav_sim::experiments::formation::run(scenario, &mc)
        .map_err(estimation("formation flight"))?;
    aidnav_io::writers::ensure_dir(out)?;
    let mut header = vec!["time [s]".to_string(), "member".to_string()];
    header.extend(SOLUTIONS.iter().map(|s| format!("{s}_position_error [m]")));
    let header_ref: Vec<&str> = header.iter().map(String::as_str).collect();
    write_table(
        &out.join("formation.csv"),
        &header_ref,
        result.time_s.iter().enumerate().flat_map(|(k, &t)| {
            result.error_by_epoch[k]
                .iter()
                .enumerate()
                .map(move |(l, e)| vec![t, l as f64, e[0], e[1], e[2]])
        }),
    )?;
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
        .filter(|m| m.denied)
        .map(|m| m.member)
        .collect();
    for &l in &denied {
        for (s, label) in labels.iter().enumerate() {
            series.push(Series {
                label: format!("member {l} (GNSS denied): {label}"),
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
    .write_svg(&out.join("formation_errors.svg"))?;
    let mut summary = Summary::new(command, VERSION, Some(scenario.seed), scenario);
    summary.insert("solutions", SOLUTIONS);
    summary.insert("members", &result.members);
    summary.insert("relative_measurements_per_epoch", result.relative_per_epoch);
    summary.write(out)?;
    Ok(result)
}

/// Run the spec-10 extended-state experiment and write `extended_state.csv`
/// (one row per trajectory × threshold), the figures `fig1_accel_bias_error.svg`,
/// `fig1_scale_factor_error.svg`, `fig2_delta.svg`, `fig3_position_error.svg`,
/// `switch_sweep.svg`, and `summary.json` (list `cases`) into `out`.
pub fn extended_state(
    scenario: &ExtendedStateScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<ExtendedStateResult> {
    let mc = campaign(scenario.runs, scenario.seed, "extended-state", quiet);
    let result = aidnav_sim::experiments::extended_state::run(scenario, &mc)?;
    aidnav_io::writers::ensure_dir(out)?;
    write_table(
        &out.join("extended_state.csv"),
        &[
            "t_b [s]",
            "course [deg]",
            "delta_threshold",
            "switch_time [s]",
            "error_free_ins [m]",
            "error_outputs_only [m]",
            "error_proposed [m]",
            "error_oracle [m]",
            "ratio_median",
            "ratio_p10",
            "ratio_p90",
        ],
        result.cases.iter().map(|c| {
            vec![
                c.t_b_s,
                c.course_deg,
                c.delta_threshold,
                c.switch_time_s,
                c.error_free_ins_m,
                c.error_outputs_only_m,
                c.error_proposed_m,
                c.error_oracle_m,
                c.ratio_median,
                c.ratio_p10,
                c.ratio_p90,
            ]
        }),
    )?;
    crate::figures::extended_state_figures(scenario, &result, out)?;
    let mut summary = Summary::new(
        "reproduce extended-state",
        VERSION,
        Some(scenario.seed),
        scenario,
    );
    summary.insert("cases", &result.cases);
    summary.insert("sweep", &result.sweep);
    summary.write(out)?;
    Ok(result)
}

/// What `aidnav process` measured.
#[derive(Debug, Clone, Serialize)]
pub struct ProcessReport {
    /// IMU samples used.
    pub imu_samples: usize,
    /// GNSS epochs.
    pub gnss_epochs: usize,
    /// Policy of the GNSS updates in the main run and the outage scores.
    pub policy: crate::process::PolicyName,
    /// RMS 3-D antenna error over RTK-fixed epochs, all GNSS used \[m\].
    pub tracking_rms_m: f64,
    /// Updates by outcome in the clean run.
    pub outcomes: Vec<(String, usize)>,
    /// RMS 3-D error of the RTS-smoothed antenna positions (with `output.smooth`).
    pub tracking_smoothed_rms_m: Option<f64>,
    /// Time after the first fix at which spec 10's rule (δ non-increasing
    /// 15 s, then ≤ threshold) declares the instruments converged, for
    /// δ_thr = 3 % and 1 % (None: never).
    pub instrument_convergence_s: Vec<(f64, Option<f64>)>,
    /// Outage scores (filter coasting).
    pub outages: Vec<crate::process::OutageScore>,
    /// Outage scores of the RTS-smoothed solution (with `output.smooth`).
    pub outages_smoothed: Vec<crate::process::OutageScore>,
    /// Outage scores of the free INS (raw IMU, no instrument correction).
    pub outages_free_ins: Vec<crate::process::OutageScore>,
    /// Outage scores with spec 20's predictors bridging the windows (with
    /// `outage_bridge.enabled`), per predictor.
    pub outages_bridged: Vec<BridgedScores>,
    /// Spec 20's efficiency criterion in the outage windows, per length.
    pub efficiency: Vec<crate::process::EfficiencyScore>,
    /// Fraction of the clean run's epochs at which K_eff > 1 (the
    /// integrated solution is predicted better than GNSS).
    pub k_eff_integrated_fraction: f64,
    /// (fraction, policy, RMS 3-D error over RTK-fixed epochs against the clean fixes).
    pub anomalies: Vec<(f64, crate::process::PolicyName, f64)>,
    /// (policy, RMS 3-D error over the RTK-fixed epochs with GNSS) with the
    /// 30 s outages and a burst after each; and the same without bursts.
    pub post_outage_bursts: Vec<(crate::process::PolicyName, f64, f64)>,
    /// Reader warnings.
    pub warnings: Vec<String>,
    /// Wall time \[s\]: reading, one filter pass, scoring.
    pub timing_s: [f64; 3],
    /// Files written.
    pub files: Vec<PathBuf>,
}

/// Outage scores of one bridging predictor.
#[derive(Debug, Clone, Serialize)]
pub struct BridgedScores {
    /// The predictor.
    pub predictor: aidnav_supervisors::outage::Predictor,
    /// Per outage length, as the coasting filter's.
    pub scores: Vec<crate::process::OutageScore>,
}

/// Run `aidnav process CONFIG.toml`: read the log named in the
/// configuration (`data_dir` replaces its `data.dir`), filter it, write
/// `solution.csv` (per GNSS epoch: antenna position, NED velocity, attitude,
/// σ, NIS, update outcome), `trajectory.svg`, `outage_drift.svg` and
/// `summary.json`; with `score`, also the outage and anomaly tables.
pub fn process(
    config: &Path,
    data_dir: Option<&Path>,
    out: &Path,
    score: bool,
) -> JobResult<ProcessReport> {
    use crate::process::{
        PolicyName, RunPlan, inject_outliers, load_inputs, outage_windows, run_filter,
        score_windows, tracking_rms,
    };
    use rayon::prelude::*;
    use std::time::Instant;
    let (mut cfg, _) = aidnav_io::load_toml::<crate::process::ProcessConfig>(config)?;
    if let Some(d) = data_dir {
        cfg.data.dir = d.to_path_buf();
    }
    let base = config.parent().unwrap_or(Path::new("."));
    let t_read = Instant::now();
    let inputs = load_inputs(&cfg, base).map_err(process_error)?;
    let read_s = t_read.elapsed().as_secs_f64();
    let t_run = Instant::now();
    let clean_plan = RunPlan {
        smooth: cfg.output.smooth,
        monitor: cfg.filter.convergence_monitor,
        ..RunPlan::default()
    };
    let crate::process::Run {
        epochs: clean,
        between,
    } = crate::process::run_filter_rows(
        &cfg,
        &inputs,
        &clean_plan,
        cfg.gnss.policy,
        cfg.output.interval_s,
    )
    .map_err(process_error)?;
    let smoothed: Vec<crate::process::Epoch> = clean.iter().filter_map(|e| e.smoothed()).collect();
    let run_s = t_run.elapsed().as_secs_f64();
    aidnav_io::writers::ensure_dir(out)?;
    let mut files = Vec::new();
    let solution = out.join("solution.csv");
    write_solution(&solution, &inputs.gnss, &clean, &between)?;
    files.push(solution);
    if cfg.output.kf_gins_text {
        use std::fmt::Write as _;
        let mut text = String::new();
        // GNSS epochs and the rows between them, in time order.
        let rows = merge_in_time(
            clean.iter().map(|e| e.row(&inputs.gnss)),
            between.iter().copied(),
            |r| r.time_s,
        );
        for e in rows {
            let gps = e.time_s - 315_964_800.0;
            let week = (gps / 604_800.0).floor();
            let (r, p, y) = e.attitude.euler_angles();
            let _ = writeln!(
                text,
                "{:.0} {:.3} {:.9} {:.9} {:.4} {:.4} {:.4} {:.4} {:.5} {:.5} {:.5}",
                week,
                gps - week * 604_800.0,
                e.antenna.latitude_rad.to_degrees(),
                e.antenna.longitude_rad.to_degrees(),
                e.antenna.height_m,
                e.velocity.x,
                e.velocity.y,
                e.velocity.z,
                r.to_degrees(),
                p.to_degrees(),
                y.to_degrees()
            );
        }
        let path = out.join("navresult.txt");
        std::fs::write(&path, text).map_err(|e| {
            JobError::Io(IoError::Write {
                path: path.clone(),
                message: e.to_string(),
            })
        })?;
        files.push(path);
    }
    if !smoothed.is_empty() {
        let path = out.join("smoothed.csv");
        write_table(
            &path,
            &[
                "time [s GPST since 1970]",
                "latitude [deg]",
                "longitude [deg]",
                "height [m]",
            ],
            smoothed.iter().map(|e| {
                vec![
                    inputs.gnss[e.index].time_s,
                    e.antenna.latitude_rad.to_degrees(),
                    e.antenna.longitude_rad.to_degrees(),
                    e.antenna.height_m,
                ]
            }),
        )?;
        files.push(path);
    }
    let mut outcomes: Vec<(String, usize)> = Vec::new();
    for e in &clean {
        let key = e
            .outcome
            .map_or("withheld".to_string(), |o| format!("{o:?}").to_lowercase());
        match outcomes.iter_mut().find(|(k, _)| *k == key) {
            Some((_, n)) => *n += 1,
            None => outcomes.push((key, 1)),
        }
    }
    let origin = inputs.gnss[0].position;
    let ne = |g: &aidnav_frames::earth::Geodetic| {
        let d = origin.ned_to(g);
        (d.y, d.x)
    };
    LineChart {
        title: "Trajectory: GNSS fixes and the filter's antenna position".into(),
        x_label: "east [m]".into(),
        y_label: "north [m]".into(),
        series: vec![
            Series {
                label: "GNSS (RTK)".into(),
                points: inputs.gnss.iter().map(|g| ne(&g.position)).collect(),
                style: LineStyle::Points,
                color: TRUTH_COLOR,
            },
            Series {
                label: "aidnav".into(),
                points: clean.iter().map(|e| ne(&e.antenna)).collect(),
                style: LineStyle::Solid,
                color: 0,
            },
        ],
        log_y: false,
    }
    .write_svg(&out.join("trajectory.svg"))?;
    files.push(out.join("trajectory.svg"));
    let instruments = out.join("instruments.csv");
    write_table(
        &instruments,
        &[
            "time [s GPST since 1970]",
            "gyro_bias_x [deg/h]",
            "gyro_bias_y [deg/h]",
            "gyro_bias_z [deg/h]",
            "accel_bias_x [mg]",
            "accel_bias_y [mg]",
            "accel_bias_z [mg]",
            "gyro_scale_x [ppm]",
            "gyro_scale_y [ppm]",
            "gyro_scale_z [ppm]",
            "accel_scale_x [ppm]",
            "accel_scale_y [ppm]",
            "accel_scale_z [ppm]",
        ],
        clean.iter().map(|e| {
            let i = &e.instruments;
            let mut row = vec![inputs.gnss[e.index].time_s];
            row.extend(i.gyro_bias.iter().map(|v| v.to_degrees() * 3600.0));
            row.extend(i.accel_bias.iter().map(|v| v / 9.806_65 * 1e3));
            row.extend(i.gyro_scale.iter().map(|v| v * 1e6));
            row.extend(i.accel_scale.iter().map(|v| v * 1e6));
            row
        }),
    )?;
    files.push(instruments);
    let t0 = inputs.gnss[0].time_s;
    LineChart {
        title: "GNSS position innovations (antenna estimate − fix)".into(),
        x_label: "time since the first fix [s]".into(),
        y_label: "innovation [m]".into(),
        series: ["north", "east", "down"]
            .iter()
            .enumerate()
            .map(|(k, name)| Series {
                label: (*name).into(),
                points: clean
                    .iter()
                    .filter(|e| e.innovation[k].is_finite())
                    .map(|e| (inputs.gnss[e.index].time_s - t0, e.innovation[k]))
                    .collect(),
                style: LineStyle::Solid,
                color: k,
            })
            .collect(),
        log_y: false,
    }
    .write_svg(&out.join("innovations.svg"))?;
    files.push(out.join("innovations.svg"));
    let t_score = Instant::now();
    let (mut outages, mut outages_free, mut anomalies) = (Vec::new(), Vec::new(), Vec::new());
    let mut outages_smoothed = Vec::new();
    let mut post_bursts = Vec::new();
    let (mut outages_bridged, mut efficiency) = (Vec::new(), Vec::new());
    let mut score_failures = Vec::new();
    if score {
        let first = inputs.imu[0].time_s;
        let last = inputs.gnss[inputs.gnss.len() - 1].time_s;
        // (L, free INS?, the windows of L)
        type Plan = (f64, bool, Vec<(f64, f64)>);
        let plans: Vec<Plan> = cfg
            .score
            .outages_s
            .iter()
            .flat_map(|&l| {
                let windows = outage_windows(&cfg.score, first, last, l);
                [(l, false, windows.clone()), (l, true, windows)]
            })
            .collect();
        // (L, free INS?, score, score of the smoothed solution, epochs)
        type Scored = (
            f64,
            bool,
            crate::process::OutageScore,
            Option<crate::process::OutageScore>,
            Vec<crate::process::Epoch>,
        );
        let scored: Vec<Scored> = plans
            .par_iter()
            .map(|(l, free, windows)| {
                let (l, free) = (*l, *free);
                let plan = RunPlan {
                    windows: windows.clone(),
                    free_ins_in_windows: free,
                    smooth: cfg.output.smooth,
                    bridge: cfg.outage_bridge.enabled,
                    ..RunPlan::default()
                };
                let epochs = run_filter(&cfg, &inputs, &plan, cfg.gnss.policy)?;
                let smoothed: Vec<crate::process::Epoch> =
                    epochs.iter().filter_map(|e| e.smoothed()).collect();
                Ok((
                    l,
                    free,
                    score_windows(&inputs.gnss, &epochs, windows, l),
                    (!smoothed.is_empty())
                        .then(|| score_windows(&inputs.gnss, &smoothed, windows, l)),
                    epochs,
                ))
            })
            .collect::<Result<_, crate::process::ProcessError>>()
            .map_err(process_error)?;
        let mut drift_series = Vec::new();
        if cfg.outage_bridge.enabled {
            outages_bridged = crate::process::BRIDGE_PREDICTORS
                .iter()
                .map(|&predictor| BridgedScores {
                    predictor,
                    scores: Vec::new(),
                })
                .collect();
        }
        for (i, ((l, free, s, smoothed, epochs), (_, _, windows))) in
            scored.into_iter().zip(&plans).enumerate()
        {
            if !free {
                for (k, b) in outages_bridged.iter_mut().enumerate() {
                    let bridged = crate::process::bridged_epochs(&epochs, k);
                    b.scores
                        .push(score_windows(&inputs.gnss, &bridged, windows, l));
                }
                efficiency.push(crate::process::efficiency_in_windows(
                    &inputs.gnss,
                    &epochs,
                    windows,
                    l,
                ));
                drift_series.push(Series {
                    label: format!("{l:.0} s outages"),
                    points: epochs
                        .iter()
                        .map(|e| {
                            let g = &inputs.gnss[e.index];
                            (
                                g.time_s - first,
                                g.position.ned_to(&e.antenna).norm().max(1e-3),
                            )
                        })
                        .collect(),
                    style: LineStyle::Solid,
                    color: i / 2,
                });
                drift_series.push(Series {
                    label: format!("{l:.0} s outages: 3σ"),
                    points: epochs
                        .iter()
                        .map(|e| {
                            let g = &inputs.gnss[e.index];
                            (g.time_s - first, (3.0 * e.sigma.norm()).max(1e-3))
                        })
                        .collect(),
                    style: LineStyle::Dashed,
                    color: i / 2,
                });
                outages_smoothed.extend(smoothed);
                outages.push(s);
            } else {
                outages_free.push(s);
            }
        }
        LineChart {
            title: "3-D antenna error with simulated GNSS outages (filter coasting)".into(),
            x_label: "time since the first IMU sample [s]".into(),
            y_label: "3-D error [m]".into(),
            series: drift_series,
            log_y: true,
        }
        .write_svg(&out.join("outage_drift.svg"))?;
        files.push(out.join("outage_drift.svg"));
        let policies = PolicyName::ALL;
        let mut cases: Vec<(f64, PolicyName)> = policies.iter().map(|&p| (0.0, p)).collect();
        for &f in &cfg.score.outlier_fractions {
            cases.extend(policies.iter().map(|&p| (f, p)));
        }
        // A policy other than the configured one may make the filter fail
        // on corrupted data (eq. 4's gain, say): that is a result of the
        // table (NaN, and a warning saying why), not a reason to stop.
        let failures = std::sync::Mutex::new(Vec::new());
        let scored_or_nan = |what: String, run: Result<f64, crate::process::ProcessError>| {
            run.unwrap_or_else(|e| {
                failures
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner)
                    .push(format!("{what}: {e}"));
                f64::NAN
            })
        };
        anomalies = cases
            .par_iter()
            .map(|&(f, p)| {
                let plan = RunPlan {
                    outliers: inject_outliers(
                        inputs.gnss.len(),
                        f,
                        cfg.score.outlier_m,
                        cfg.score.seed,
                    ),
                    ..RunPlan::default()
                };
                let run = run_filter(&cfg, &inputs, &plan, p)
                    .map(|epochs| tracking_rms(&inputs.gnss, &epochs));
                let what = format!("{:.0} % outliers, {}", 100.0 * f, p.name());
                (f, p, scored_or_nan(what, run))
            })
            .collect();
        if cfg.score.post_outage_burst_s > 0.0 {
            let windows = outage_windows(&cfg.score, first, last, 30.0);
            let bursts = crate::process::post_outage_bursts(
                &inputs.gnss,
                &windows,
                cfg.score.post_outage_burst_s,
                cfg.score.outlier_m,
                cfg.score.seed,
            );
            post_bursts = policies
                .par_iter()
                .map(|&p| {
                    let run = |outliers: Vec<Option<nalgebra::Vector3<f64>>>, what: &str| {
                        let plan = RunPlan {
                            windows: windows.clone(),
                            outliers,
                            ..RunPlan::default()
                        };
                        let run = run_filter(&cfg, &inputs, &plan, p)
                            .map(|e| crate::process::tracking_rms_with_gnss(&inputs.gnss, &e));
                        scored_or_nan(format!("30 s outages {what}, {}", p.name()), run)
                    };
                    (
                        p,
                        run(bursts.clone(), "with bursts"),
                        run(Vec::new(), "without bursts"),
                    )
                })
                .collect();
        }
        score_failures = failures
            .into_inner()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
    }
    let score_s = t_score.elapsed().as_secs_f64();
    let report = ProcessReport {
        imu_samples: inputs.imu.len(),
        gnss_epochs: inputs.gnss.len(),
        policy: cfg.gnss.policy,
        tracking_rms_m: tracking_rms(&inputs.gnss, &clean),
        instrument_convergence_s: if cfg.filter.convergence_monitor {
            [0.03, 0.01]
                .into_iter()
                .zip(crate::process::convergence_times(
                    &inputs.gnss,
                    &clean,
                    &[0.03, 0.01],
                    15.0,
                ))
                .collect()
        } else {
            Vec::new()
        },
        tracking_smoothed_rms_m: (!smoothed.is_empty())
            .then(|| tracking_rms(&inputs.gnss, &smoothed)),
        outages_smoothed,
        post_outage_bursts: post_bursts,
        outcomes,
        outages,
        outages_free_ins: outages_free,
        outages_bridged,
        efficiency,
        k_eff_integrated_fraction: clean.iter().filter(|e| e.k_eff > 1.0).count() as f64
            / clean.len().max(1) as f64,
        anomalies,
        warnings: inputs
            .warnings
            .iter()
            .cloned()
            .chain(score_failures)
            .collect(),
        timing_s: [read_s, run_s, score_s],
        files: files.clone(),
    };
    let mut summary = Summary::new("process", VERSION, Some(cfg.score.seed), &cfg);
    summary.insert("result", &report);
    let path = summary.write(out)?;
    let mut report = report;
    report.files.push(path);
    Ok(report)
}

/// Write `solution.csv`: per GNSS epoch the antenna position, NED velocity,
/// attitude, σ, NIS, δ(n), K_eff, innovation and update outcome; merged in
/// time order with the rows `between` the epochs (NaN where a column needs
/// a fix, outcome 0).
pub fn write_solution(
    path: &Path,
    gnss: &[aidnav_io::rtklib::GnssFix],
    epochs: &[crate::process::Epoch],
    between: &[crate::process::SolutionRow],
) -> JobResult<()> {
    let navigation = |row: &crate::process::SolutionRow| {
        let (r, p, y) = row.attitude.euler_angles();
        vec![
            row.time_s,
            row.antenna.latitude_rad.to_degrees(),
            row.antenna.longitude_rad.to_degrees(),
            row.antenna.height_m,
            row.velocity.x,
            row.velocity.y,
            row.velocity.z,
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees(),
            row.sigma.x,
            row.sigma.y,
            row.sigma.z,
        ]
    };
    let epoch_rows = epochs.iter().map(|e| {
        let mut row = navigation(&e.row(gnss));
        row.extend([e.nis, e.convergence, e.k_eff]);
        row.extend(e.innovation.iter());
        row.push(match e.outcome {
            Some(Outcome::Accepted) => 1.0,
            Some(Outcome::Limited) | Some(Outcome::Reweighted) => 2.0,
            Some(Outcome::Rejected) => 3.0,
            _ => 0.0,
        });
        row
    });
    let other_rows = between.iter().map(|b| {
        let mut row = navigation(b);
        // No fix: NIS, δ, K_eff, innovation are NaN, outcome 0.
        row.extend([f64::NAN; 6]);
        row.push(0.0);
        row
    });
    let rows = merge_in_time(epoch_rows, other_rows, |row| row[0]);
    write_table(
        path,
        &[
            "time [s GPST since 1970]",
            "latitude [deg]",
            "longitude [deg]",
            "height [m]",
            "vn [m/s]",
            "ve [m/s]",
            "vd [m/s]",
            "roll [deg]",
            "pitch [deg]",
            "yaw [deg]",
            "sigma_n [m]",
            "sigma_e [m]",
            "sigma_d [m]",
            "nis",
            "delta (Cramér–Rao convergence of the instruments)",
            "k_eff (sigma_gnss / sigma_filter, 3-D)",
            "innovation_n [m]",
            "innovation_e [m]",
            "innovation_d [m]",
            "outcome (1 accepted, 2 limited, 3 rejected, 0 no fix)",
        ],
        rows,
    )?;
    Ok(())
}

/// Two sequences, each in time order, merged in time order (the first's
/// item first on equal times) as they are consumed.
fn merge_in_time<T>(
    a: impl Iterator<Item = T>,
    b: impl Iterator<Item = T>,
    time: impl Fn(&T) -> f64,
) -> impl Iterator<Item = T> {
    let (mut a, mut b) = (a.peekable(), b.peekable());
    std::iter::from_fn(move || match (a.peek(), b.peek()) {
        (Some(x), Some(y)) if time(x) <= time(y) => a.next(),
        (Some(_), None) => a.next(),
        _ => b.next(),
    })
}

fn process_error(e: crate::process::ProcessError) -> JobError {
    match e {
        crate::process::ProcessError::Io(io) => JobError::Io(io),
        crate::process::ProcessError::Estimation(source) => estimation("GNSS/INS filter")(source),
        crate::process::ProcessError::Data(m) => JobError::Refused(m),
    }
}
