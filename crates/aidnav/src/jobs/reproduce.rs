//! The reproductions' jobs: run one experiment of `aidnav_reproduce`, write
//! its CSV, figures and `summary.json`.

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
    let result = aidnav_reproduce::anomalies::run(scenario, &mc)
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
    aidnav_reproduce::figures::anomaly_figures(
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
    let result = aidnav_reproduce::outages::run(scenario, &mc)?;
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
    aidnav_reproduce::figures::recovery_figure(&result.efficiency_example, out)?;
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
    let result =
        aidnav_reproduce::group::run(scenario, &mc).map_err(estimation("group experiment"))?;
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
    let result =
        aidnav_reproduce::formation::run(scenario, &mc).map_err(estimation("formation flight"))?;
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
    let result = aidnav_reproduce::extended_state::run(scenario, &mc)?;
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
    aidnav_reproduce::figures::extended_state_figures(scenario, &result, out)?;
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
