//! The reproductions' jobs: run one experiment of `aidnav_reproduce`, write
//! its CSV, figures and `summary.json`.

use std::path::Path;

use aidnav_io::writers::{Summary, write_table};
use aidnav_reproduce::anomalies::{AnomaliesResult, AnomaliesScenario, ESTIMATORS};
use aidnav_reproduce::consistency::{ConsistencyResult, ConsistencyScenario};
use aidnav_reproduce::extended_state::{ExtendedStateResult, ExtendedStateScenario};
use aidnav_reproduce::formation::{
    FormationResult, FormationScenario, NetworkSweepScenario, SOLUTIONS, SweepCell,
};
use aidnav_reproduce::group::{GroupResult, GroupScenario};
use aidnav_reproduce::outages::{OutagesResult, OutagesScenario, PREDICTORS};
use aidnav_sim::MonteCarlo;

use crate::VERSION;

use super::*;

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
    let result = aidnav_reproduce::consistency::run(scenario, &mc)
        .map_err(estimation("consistency demo"))?;
    aidnav_io::writers::begin_outputs(out)?;
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
    aidnav_reproduce::figures::nees_figure(scenario, &result, out)?;
    consistency_summary(scenario, &result).write(out)?;
    Ok(result)
}

/// Run the spec-20 anomalies experiment and write `anomalies_example.csv`,
/// `anomalies_example.svg`, the paper-like Figs. 3–8 (`fig03_…svg` to
/// `fig08_…svg`), the per-type table `anomaly_types.csv` and `summary.json`
/// into `out`.
pub fn anomalies(
    scenario: &AnomaliesScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<AnomaliesResult> {
    let mc = campaign(scenario.runs, scenario.seed, "anomalies", quiet);
    let result = aidnav_reproduce::anomalies::run(scenario, &mc)
        .map_err(estimation("anomalies experiment"))?;
    aidnav_io::writers::begin_outputs(out)?;
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
    aidnav_reproduce::figures::anomaly_example_figure(&result, dt, out)?;
    aidnav_reproduce::figures::anomaly_figures(
        &result,
        scenario.illustration.at_epoch,
        dt,
        scenario.platform.equivalent_tilt_rad(),
        out,
    )?;
    if !result.per_type.is_empty() {
        aidnav_io::writers::write_atomic(
            &out.join("anomaly_types.csv"),
            anomaly_types_csv(&result.per_type).as_bytes(),
        )?;
    }
    anomalies_summary(scenario, &result).write(out)?;
    Ok(result)
}

/// `anomaly_types.csv`: one row per anomaly type, its anomalous and lost
/// fractions and every estimator's RMS (the type names hold no comma).
fn anomaly_types_csv(table: &[aidnav_reproduce::anomalies::TypeScores]) -> String {
    let mut text = String::from("anomaly_type,anomaly_fraction,lost_fraction");
    for e in ESTIMATORS {
        text.push_str(&format!(",{e} [m/s]"));
    }
    text.push('\n');
    for t in table {
        text.push_str(&format!(
            "{},{},{}",
            t.anomaly_type, t.anomaly_fraction, t.lost_fraction
        ));
        for e in &t.rms_mps {
            text.push_str(&format!(",{}", e.rms_mps));
        }
        text.push('\n');
    }
    text
}

/// Run the spec-20 outages experiment and write `outage_example.csv`,
/// `outage_predictors.svg` (Fig. 9), `efficiency.svg`,
/// `fig10_recovery_errors.svg` and `summary.json` into `out`.
pub fn outages(scenario: &OutagesScenario, out: &Path, quiet: bool) -> JobResult<OutagesResult> {
    let mc = campaign(scenario.runs, scenario.seed, "outages", quiet);
    let result = aidnav_reproduce::outages::run(scenario, &mc)?;
    aidnav_io::writers::begin_outputs(out)?;
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
    aidnav_reproduce::figures::outage_predictors_figure(&result, out)?;
    aidnav_reproduce::figures::efficiency_figure(&result.efficiency_example, out)?;
    aidnav_reproduce::figures::recovery_figure(&result.efficiency_example, out)?;
    outages_summary(scenario, &result).write(out)?;
    Ok(result)
}

/// Run the spec-30 group experiment and write `group.csv` (per epoch and
/// case: filter σ and Monte Carlo RMS of position and of velocity),
/// `group_errors.svg` and `group_velocity_errors.svg` (the paper's Fig. 6,
/// position and velocity panels) and `summary.json` (an object per case `single`,
/// `group_low`, `group_high`) into `out`.
pub fn group(scenario: &GroupScenario, out: &Path, quiet: bool) -> JobResult<GroupResult> {
    let mc = campaign(scenario.runs, scenario.seed, "group", quiet);
    let result =
        aidnav_reproduce::group::run(scenario, &mc).map_err(estimation("group experiment"))?;
    aidnav_io::writers::begin_outputs(out)?;
    let dt = scenario.single.dt_s;
    let mut header = vec!["time [s]".to_string()];
    for c in &result.cases {
        header.push(format!("{}_sigma [m]", c.name));
        header.push(format!("{}_rms [m]", c.name));
    }
    for c in &result.cases {
        header.push(format!("{}_velocity_sigma [m/s]", c.name));
        header.push(format!("{}_velocity_rms [m/s]", c.name));
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
            for c in &result.cases {
                row.push(c.velocity_sigma_by_epoch[e]);
                row.push(c.velocity_rms_by_epoch[e]);
            }
            row
        }),
    )?;
    aidnav_reproduce::figures::group_figure(scenario, &result, out)?;
    group_summary(scenario, &result).write(out)?;
    Ok(result)
}

/// What [`formation`] computed: the flight's result and, with
/// `[formation.network.sweep]`, the accuracy per latency × loss cell.
#[derive(Debug, Clone)]
pub struct FormationOutcome {
    /// The flight (with the scenario's network, if any).
    pub result: FormationResult,
    /// The network sweep's cells (empty without a sweep).
    pub sweep: Vec<SweepCell>,
}

/// The files of a formation's network sweep, written only with
/// `[formation.network.sweep]`.
const NETWORK_SWEEP_FILES: [&str; 2] = ["network_sweep.csv", "network_sweep.svg"];

/// Run the spec-30 formation pipeline (stage-1 INS/GNSS per member, stage-2
/// group fusion in the paper's and the EKF form) and write `formation.csv`
/// (per epoch and member: RMS over runs of the 3-D position error of each
/// solution), `formation_errors.svg` (each GNSS-denied or -degraded member alone and in
/// the group, and the mean of the others) and `summary.json` (list `members`;
/// `network` with `[formation.network]`) into `out`; with
/// `[formation.network.sweep]` also `network_sweep.csv`, `network_sweep.svg`
/// and `summary.json`'s `network_sweep` (without it, the sweep's files an
/// earlier run left in `out` are removed).
pub fn formation(
    scenario: &FormationScenario,
    command: &str,
    out: &Path,
    quiet: bool,
) -> JobResult<FormationOutcome> {
    let mc = campaign(scenario.runs, scenario.seed, "formation", quiet);
    let result =
        aidnav_reproduce::formation::run(scenario, &mc).map_err(estimation("formation flight"))?;
    aidnav_io::writers::begin_outputs(out)?;
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
    aidnav_reproduce::figures::formation_figure(scenario, &result, out)?;
    let sweep = aidnav_reproduce::formation::sweep(scenario, &mc)
        .map_err(estimation("formation network sweep"))?;
    if sweep.is_empty() {
        // An earlier run's sweep would otherwise pass for this one's
        // (this summary lists no files to note the removal in).
        aidnav_io::writers::remove_stale_outputs(out, &NETWORK_SWEEP_FILES, &[])?;
    } else {
        write_network_sweep(&sweep, scenario.members, out)?;
        aidnav_reproduce::figures::network_sweep_figure(scenario, &sweep, out)?;
    }
    let mut summary = formation_summary(scenario, command, &result);
    if !sweep.is_empty() {
        summary.insert("network_sweep", &sweep);
    }
    summary.write(out)?;
    Ok(FormationOutcome { result, sweep })
}

/// Run only the formation's network sweep (`reproduce formation-network`:
/// the latency × loss grid of `[network.sweep]`, each cell's stage 2 on the
/// same stage 1 and measurements per run) and write `network_sweep.csv`,
/// `network_sweep.svg` and `summary.json` (list `network_sweep`) into `out`.
pub fn formation_network(
    scenario: &NetworkSweepScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<Vec<SweepCell>> {
    let s = &scenario.0;
    let mc = campaign(s.runs, s.seed, "formation-network", quiet);
    let sweep = aidnav_reproduce::formation::sweep(s, &mc)
        .map_err(estimation("formation network sweep"))?;
    aidnav_io::writers::begin_outputs(out)?;
    write_network_sweep(&sweep, s.members, out)?;
    aidnav_reproduce::figures::network_sweep_figure(s, &sweep, out)?;
    formation_network_summary(scenario, &sweep).write(out)?;
    Ok(sweep)
}

/// The `summary.json` of `reproduce formation-network` (list
/// `network_sweep`).
pub fn formation_network_summary(scenario: &NetworkSweepScenario, sweep: &[SweepCell]) -> Summary {
    let mut summary = Summary::new(
        "reproduce formation-network",
        VERSION,
        Some(scenario.0.seed),
        scenario,
    );
    summary.insert("network_sweep", sweep);
    summary
}

/// `network_sweep.csv`: one row per latency × loss cell of the formation's
/// network sweep.
fn write_network_sweep(sweep: &[SweepCell], members: usize, out: &Path) -> JobResult<()> {
    let denied = sweep[0].denied_max_error_m.is_some();
    let mut header = vec![
        "latency [s]",
        "loss_probability",
        "lost_fraction",
        "late_fraction",
        "too_old",
        "replayed_epochs_per_epoch",
        "alone_rms [m]",
        "paper_rms [m]",
        "ekf_rms [m]",
        "paper_sigma [m]",
        "ekf_sigma [m]",
    ];
    if denied {
        header.extend([
            "denied_max_alone [m]",
            "denied_max_paper [m]",
            "denied_max_ekf [m]",
        ]);
    }
    write_table(
        &out.join("network_sweep.csv"),
        &header,
        sweep.iter().map(|c| {
            let n = &c.network;
            // Every member sends one packet per epoch and run.
            let epochs = (n.sent / members).max(1) as f64;
            let mut row = vec![
                c.latency_s,
                c.loss_probability,
                n.lost_fraction(),
                n.late_fraction(),
                n.fusion.too_old as f64,
                n.fusion.replayed_epochs as f64 / epochs,
                c.kept_rms_m[0],
                c.kept_rms_m[1],
                c.kept_rms_m[2],
                c.kept_sigma_m[1],
                c.kept_sigma_m[2],
            ];
            if let Some(d) = c.denied_max_error_m {
                row.extend(d);
            }
            row
        }),
    )?;
    Ok(())
}

/// Run the spec-10 extended-state experiment and write `extended_state.csv`
/// (one row per trajectory × switch case; `rule`: 0 δ armed by the
/// scenario's `switch`, 1 δ ≤ δ_thr literally, 2 the t_B forecast's
/// reduction per second, 3 the instrument share of the t_B forecast; for 2
/// and 3 `delta_threshold` is that rule's threshold), the figures `fig1_accel_bias_error.svg`,
/// `fig1_scale_factor_error.svg`, `fig2_delta.svg`, `fig3_position_error.svg`,
/// `switch_sweep.svg`, and `summary.json` (list `cases`) into `out`.
pub fn extended_state(
    scenario: &ExtendedStateScenario,
    out: &Path,
    quiet: bool,
) -> JobResult<ExtendedStateResult> {
    let mc = campaign(scenario.runs, scenario.seed, "extended-state", quiet);
    let result = aidnav_reproduce::extended_state::run(scenario, &mc)?;
    aidnav_io::writers::begin_outputs(out)?;
    write_table(
        &out.join("extended_state.csv"),
        &[
            "t_b [s]",
            "course [deg]",
            "rule",
            "delta_threshold",
            "switch_time [s]",
            "error_free_ins [m]",
            "error_outputs_only [m]",
            "error_proposed [m]",
            "error_oracle [m]",
            "ratio_median",
            "ratio_p10",
            "ratio_p90",
            "error_gauss_newton [m]",
            "rms_proposed [m]",
            "rms_gauss_newton [m]",
            "rms_oracle [m]",
            "bound_sigma [m]",
        ],
        result.cases.iter().map(|c| {
            vec![
                c.t_b_s,
                c.course_deg,
                c.rule.code(),
                c.delta_threshold,
                c.switch_time_s,
                c.error_free_ins_m,
                c.error_outputs_only_m,
                c.error_proposed_m,
                c.error_oracle_m,
                c.ratio_median,
                c.ratio_p10,
                c.ratio_p90,
                c.error_gauss_newton_m,
                c.rms_proposed_gauss_newton_oracle_m[0],
                c.rms_proposed_gauss_newton_oracle_m[1],
                c.rms_proposed_gauss_newton_oracle_m[2],
                c.bound_sigma_m,
            ]
        }),
    )?;
    aidnav_reproduce::figures::extended_state_figures(scenario, &result, out)?;
    extended_state_summary(scenario, &result).write(out)?;
    Ok(result)
}

/// The consistency demo's `summary.json` as a value.
pub fn consistency_summary(scenario: &ConsistencyScenario, result: &ConsistencyResult) -> Summary {
    let mut summary = Summary::new(
        "reproduce consistency",
        VERSION,
        Some(scenario.seed),
        scenario,
    );
    summary.insert("runs", scenario.runs);
    summary.insert("nees_epoch_bounds", result.nees_epoch_bounds);
    summary.insert("variants", &result.variants);
    summary
}

/// The anomalies experiment's `summary.json` as a value.
pub fn anomalies_summary(scenario: &AnomaliesScenario, result: &AnomaliesResult) -> Summary {
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
    summary.insert("rms", rms);
    summary.insert("scores", &result.scores);
    summary.insert("anomaly_fraction", result.anomaly_fraction);
    summary.insert("per_type", &result.per_type);
    summary
}

/// The outages experiment's `summary.json` as a value.
pub fn outages_summary(scenario: &OutagesScenario, result: &OutagesResult) -> Summary {
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
    summary
}

/// The group experiment's `summary.json` as a value.
pub fn group_summary(scenario: &GroupScenario, result: &GroupResult) -> Summary {
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
    summary
}

/// The formation pipeline's `summary.json` as a value (`command` as the
/// CLI names it: `reproduce formation` or `run FILE`).
pub fn formation_summary(
    scenario: &FormationScenario,
    command: &str,
    result: &FormationResult,
) -> Summary {
    let mut summary = Summary::new(command, VERSION, Some(scenario.seed), scenario);
    summary.insert("solutions", SOLUTIONS);
    summary.insert("members", &result.members);
    summary.insert("relative_measurements_per_epoch", result.relative_per_epoch);
    if let Some(n) = &result.network {
        summary.insert("network", n);
    }
    summary
}

/// The extended-state experiment's `summary.json` as a value.
pub fn extended_state_summary(
    scenario: &ExtendedStateScenario,
    result: &ExtendedStateResult,
) -> Summary {
    let mut summary = Summary::new(
        "reproduce extended-state",
        VERSION,
        Some(scenario.seed),
        scenario,
    );
    summary.insert("cases", &result.cases);
    summary.insert("sweep", &result.sweep);
    summary
}
