//! The `aidnav` binary end to end: hand-checked example, errors, reproduction outputs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn aidnav(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_aidnav"))
        .args(args)
        .env("CI", "true")
        .output()
        .expect("the aidnav binary runs")
}

/// Run a command expected to fail and return its standard error.
fn failure(args: &[&str]) -> String {
    let out = aidnav(args);
    assert!(!out.status.success(), "expected failure: {args:?}");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!err.contains("panicked"), "{err}");
    err
}

/// Run a command expected to succeed and return its standard output.
fn success(args: &[&str]) -> String {
    let out = aidnav(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `aidnav reproduce EXPERIMENT ARGS… --out OUT`, expected to succeed; its
/// standard output.
fn reproduce(experiment: &str, args: &[&str], out: &Path) -> String {
    let mut all = vec!["reproduce", experiment];
    all.extend_from_slice(args);
    all.extend(["--out", out.to_str().unwrap()]);
    success(&all)
}

/// The arguments of `aidnav filter --model MODEL --measurements Z --out OUT`.
fn filter_args<'a>(model: &'a Path, z: &'a Path, out: &'a Path) -> Vec<&'a str> {
    vec![
        "filter",
        "--model",
        model.to_str().unwrap(),
        "--measurements",
        z.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]
}

/// `aidnav COMMAND INPUT ARGS… --out OUT`, expected to succeed (`process`,
/// `run`, `tune`, `convert`); its standard output.
fn on_file(command: &str, input: &Path, args: &[&str], out: &Path) -> String {
    let mut all = vec![command, input.to_str().unwrap()];
    all.extend_from_slice(args);
    all.extend(["--out", out.to_str().unwrap()]);
    success(&all)
}

/// `aidnav run examples/{example}.toml --runs 2 --quiet --out OUT`: the
/// formation examples cut short; its standard output.
fn run_two_runs_of(example: &str, out: &Path) -> String {
    let config = repo().join(format!("examples/{example}.toml"));
    on_file("run", &config, &["--runs", "2", "--quiet"], out)
}

/// `text` holds every one of `parts` (the whole text shown if not).
#[track_caller]
fn assert_contains_all(text: &str, parts: &[&str]) {
    assert!(parts.iter().all(|p| text.contains(p)), "{text}");
}

/// A recorded log of the repository's data (`drive_0708`, `walk_0827`).
fn data_dir(log: &str) -> PathBuf {
    repo().join("data/rtklibexplorer-gnss-imu").join(log)
}

/// The example configuration `examples/{log}.toml` with its data dir made
/// absolute (a copy written elsewhere still finds the log).
fn example_with_absolute_data(log: &str) -> String {
    let example = std::fs::read_to_string(repo().join(format!("examples/{log}.toml"))).unwrap();
    example.replace(
        &format!("dir = \"../data/rtklibexplorer-gnss-imu/{log}\""),
        &format!("dir = {:?}", data_dir(log).to_str().unwrap()),
    )
}

/// The scalar model and measurements `z_csv`, written as `m.toml` and
/// `z.csv` in `dir`.
fn scalar_inputs(dir: &Path, z_csv: &str) -> (PathBuf, PathBuf) {
    let model = dir.join("m.toml");
    std::fs::write(&model, SCALAR_MODEL).unwrap();
    let z = dir.join("z.csv");
    std::fs::write(&z, z_csv).unwrap();
    (model, z)
}

/// `text` written to `config`, `aidnav COMMAND CONFIG` expected to fail; its
/// standard error.
fn failure_on(command: &str, config: &Path, text: &str) -> String {
    std::fs::write(config, text).unwrap();
    failure(&[command, config.to_str().unwrap()])
}

/// `aidnav ARGS…` with its standard output closed before it writes (the
/// reader of a pipe gone, as `| head`): its exit status and output.
fn with_stdout_closed(args: &[&str]) -> Output {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_aidnav"))
        .args(args)
        .env("CI", "true")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

fn filter_failure(model: &Path, z: &Path, out: &Path) -> String {
    failure(&filter_args(model, z, out))
}

/// `text` written to `scenario`, `aidnav reproduce consistency --scenario
/// SCENARIO --out OUT` expected to fail; its standard error.
fn reproduce_failure(scenario: &Path, text: &str, out: &Path) -> String {
    std::fs::write(scenario, text).unwrap();
    failure(&[
        "reproduce",
        "consistency",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
}

fn read_summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn column(csv_text: &str, name: &str) -> Vec<f64> {
    let mut lines = csv_text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let c = header.iter().position(|h| *h == name).unwrap();
    lines
        .map(|l| l.split(',').nth(c).unwrap().parse().unwrap())
        .collect()
}

#[test]
fn filter_reproduces_the_hand_checked_example() {
    let dir = tempfile::tempdir().unwrap();
    let ex = repo().join("examples/01-scalar-filter");
    let (model, measurements) = (ex.join("model.toml"), ex.join("measurements.csv"));
    let filter = |extra: &[&str]| {
        let mut args = filter_args(&model, &measurements, dir.path());
        args.extend_from_slice(extra);
        success(&args)
    };
    filter(&["--smooth"]);
    // The values derived by hand in model.toml.
    let est = std::fs::read_to_string(dir.path().join("estimates.csv")).unwrap();
    let x = column(&est, "level");
    let s = column(&est, "sigma_level");
    let expected_x = [0.5, 1.0, 1.5, 1.5, 2.0];
    let expected_p = [0.5, 1.0 / 3.0, 0.25, 0.25, 0.2];
    for k in 0..5 {
        assert!((x[k] - expected_x[k]).abs() < 1e-14, "x at {k}");
        assert!((s[k] * s[k] - expected_p[k]).abs() < 1e-14, "P at {k}");
    }
    let sm = std::fs::read_to_string(dir.path().join("smoothed.csv")).unwrap();
    for (x, s) in column(&sm, "level").iter().zip(column(&sm, "sigma_level")) {
        assert!((x - 2.0).abs() < 1e-14);
        assert!((s * s - 0.2).abs() < 1e-14);
    }
    let inn = std::fs::read_to_string(dir.path().join("innovations.csv")).unwrap();
    assert!(inn.lines().nth(4).unwrap().ends_with(",,,0,missing"));
    let summary = read_summary(dir.path());
    assert_eq!(summary["command"], "filter");
    assert_eq!(summary["aidnav_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(summary["scenario"]["r"][0][0], 1.0);
    // Run again into the same directory without smoothing: the first run's
    // smoothed.csv goes, with a warning saying so.
    filter(&[]);
    assert!(!dir.path().join("smoothed.csv").exists());
    let warnings = read_summary(dir.path())["warnings"].to_string();
    assert!(warnings.contains("smoothed.csv: removed"), "{warnings}");
}

#[test]
fn bad_inputs_give_errors_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let (model, z) = scalar_inputs(dir.path(), "z1\n1\n");
    std::fs::write(&model, format!("{SCALAR_MODEL}rr = 3\n")).unwrap();
    let err = filter_failure(&model, &z, dir.path());
    assert!(err.contains("m.toml:7: rr: unknown field `rr`"), "{err}");

    std::fs::write(&model, SCALAR_MODEL).unwrap();
    std::fs::write(&z, "z1\n1\nabc\n").unwrap();
    let err = filter_failure(&model, &z, dir.path());
    assert!(
        err.contains("z.csv:3: column `z1`: \"abc\" is not a number"),
        "{err}"
    );

    let err = filter_failure(Path::new("/nonexistent.toml"), &z, dir.path());
    assert!(err.contains("/nonexistent.toml: cannot read"), "{err}");
}

#[test]
fn scenario_range_errors_name_the_key_and_range() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("s.toml");
    let err = reproduce_failure(&s, "seed = 1\n\nconfidence = 1.5\n", dir.path());
    assert!(
        err.contains("s.toml:3: confidence: 1.5 is out of range: allowed 0 < confidence < 1"),
        "{err}"
    );
    let err = reproduce_failure(&s, "runs = \"ten\"\n", dir.path());
    assert!(
        err.contains("s.toml:1: runs: invalid type: string \"ten\""),
        "{err}"
    );
}

#[test]
fn reproduce_writes_table_plot_and_summary_with_seed_and_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--runs", "20", "--seed", "99"];
    let stdout = reproduce("consistency", &args, dir.path());
    assert_contains_all(&stdout, &["tuned", "q_too_small", "seed 99"]);
    for f in ["consistency.csv", "nees.svg", "summary.json"] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let summary = read_summary(dir.path());
    assert_eq!(summary["seed"], 99);
    assert_eq!(summary["scenario"]["runs"], 20);
    assert_eq!(summary["scenario"]["accel_psd"], 0.05);
    assert_eq!(summary["variants"].as_array().unwrap().len(), 3);
    // Same seed, same numbers.
    let again = tempfile::tempdir().unwrap();
    reproduce("consistency", &args, again.path());
    assert_eq!(
        std::fs::read_to_string(dir.path().join("consistency.csv")).unwrap(),
        std::fs::read_to_string(again.path().join("consistency.csv")).unwrap()
    );
}

/// A reproduction that fails after it began writing leaves no `summary.json`
/// (the previous run's is removed first), so the folder never looks complete.
#[test]
fn a_failed_reproduction_leaves_no_stale_summary() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("summary.json"), "{\"stale\": true}").unwrap();
    // A directory where the CSV must go: its rename fails.
    std::fs::create_dir(dir.path().join("consistency.csv")).unwrap();
    let err = failure(&[
        "reproduce",
        "consistency",
        "--runs",
        "5",
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    assert!(err.contains("consistency.csv"), "{err}");
    assert!(!dir.path().join("summary.json").exists(), "{err}");
}

/// `aidnav … | head` closing the pipe early: the program stops the way Unix
/// tools do (SIGPIPE), without "Broken pipe" or a panic on stderr.
#[cfg(unix)]
#[test]
fn a_closed_pipe_stops_the_program_quietly() {
    use std::os::unix::process::ExitStatusExt;
    let out = tempfile::tempdir().unwrap();
    // The reading end is closed before the table is printed.
    let result = with_stdout_closed(&[
        "reproduce",
        "consistency",
        "--runs",
        "50",
        "--out",
        out.path().to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&result.stderr);
    assert!(
        !err.contains("Broken pipe") && !err.contains("panicked"),
        "{err}"
    );
    assert_eq!(
        result.status.signal(),
        Some(13),
        "{:?}: {err}",
        result.status
    );
}

#[test]
fn help_explains_every_subcommand() {
    let cases: [(&[&str], &[&str]); 5] = [
        (&["--help"], &["filter", "reproduce", "run"]),
        (&["run", "--help"], &["[formation]", "denial"]),
        (
            &["filter", "--help"],
            &["--smooth", "empty", "--max-epochs"],
        ),
        (
            &["reproduce", "--help"],
            &["--print-scenario", "consistency"],
        ),
        (
            &["process", "--help"],
            &["--strict", "status 3", "no reference"],
        ),
    ];
    for (args, words) in cases {
        let out = aidnav(args);
        assert_contains_all(&String::from_utf8_lossy(&out.stdout), words);
    }
}

#[test]
fn reproduce_anomalies_writes_the_rms_keys_other_tools_read() {
    let dir = tempfile::tempdir().unwrap();
    reproduce("anomalies", &["--runs", "3", "--seed", "5"], dir.path());
    let summary = read_summary(dir.path());
    for key in [
        "kf_known_clean",
        "kf_plain",
        "kf_reject",
        "adaptive_reject",
        "developed",
        "chi2_gate",
        "huber",
    ] {
        assert!(
            summary["rms"][key]
                .as_f64()
                .is_some_and(|v| v.is_finite() && v > 0.0),
            "rms.{key}"
        );
    }
    assert_eq!(summary["seed"], 5);
    for figure in [
        "anomalies_example.svg",
        "fig03_outlier_velocity.svg",
        "fig04_outlier_tilt.svg",
        "fig05_burst_velocity.svg",
        "fig06_burst_tilt.svg",
        "fig07_random_velocity.svg",
        "fig08_random_tilt.svg",
    ] {
        assert!(dir.path().join(figure).is_file(), "{figure}");
    }
}

#[test]
fn reproduce_outages_writes_the_improvement_keys_other_tools_read() {
    let dir = tempfile::tempdir().unwrap();
    reproduce("outages", &["--runs", "2"], dir.path());
    let summary = read_summary(dir.path());
    for case in ["short", "long"] {
        for key in [
            "apriori",
            "hold",
            "trend",
            "combined_trend",
            "gmdh",
            "relay",
        ] {
            assert!(
                summary[case]["improvement"][key]
                    .as_f64()
                    .is_some_and(f64::is_finite),
                "{case}.improvement.{key}"
            );
        }
    }
    for figure in [
        "outage_predictors.svg",
        "efficiency.svg",
        "fig10_recovery_errors.svg",
    ] {
        assert!(dir.path().join(figure).is_file(), "{figure}");
    }
    assert!(
        summary["short"]["predictors"][0]["improvement_vs_reset"]
            .as_f64()
            .is_some_and(f64::is_finite)
    );
}

#[test]
fn print_scenario_round_trips_through_the_loader() {
    let dir = tempfile::tempdir().unwrap();
    for exp in [
        "consistency",
        "anomalies",
        "outages",
        "group",
        "formation",
        "extended-state",
    ] {
        let text = success(&["reproduce", exp, "--print-scenario"]);
        let path = dir.path().join(format!("{exp}.toml"));
        std::fs::write(&path, text).unwrap();
        reproduce(
            exp,
            &["--scenario", path.to_str().unwrap(), "--runs", "1"],
            &dir.path().join(exp),
        );
    }
}

#[test]
fn reproduce_group_writes_the_case_keys_other_tools_read() {
    let dir = tempfile::tempdir().unwrap();
    reproduce("group", &["--runs", "20"], dir.path());
    let summary = read_summary(dir.path());
    for case in ["single", "group_low", "group_high"] {
        for key in [
            "position_sigma_m",
            "position_rms_m",
            "velocity_sigma_mps",
            "velocity_rms_mps",
        ] {
            assert!(
                summary[case][key]
                    .as_f64()
                    .is_some_and(|v| v.is_finite() && v > 0.0),
                "{case}.{key}"
            );
        }
    }
    assert!(dir.path().join("group_errors.svg").is_file());
    assert!(dir.path().join("group.csv").is_file());
}

#[test]
fn run_formation_example_prints_members_and_bounds_the_denied_one() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = run_two_runs_of("formation", dir.path());
    assert_contains_all(&stdout, &["GNSS/INS alone", "EKF fusion"]);
    for f in ["formation.csv", "formation_errors.svg", "summary.json"] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    let summary = read_summary(dir.path());
    assert_eq!(summary["scenario"]["runs"], 2);
    let members = summary["members"].as_array().unwrap();
    assert_eq!(members.len(), 5);
    for m in members {
        let rms: Vec<f64> = m["position_rms_m"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        // Paper fusion and EKF beat the member's own GNSS/INS solution.
        assert!(rms[1] < rms[0] && rms[2] < rms[0], "{m}");
        if m["denied"] == true {
            let max = &m["denial_max_error_m"];
            assert!(max[0].as_f64().unwrap() > 50.0, "{m}");
            assert!(max[1].as_f64().unwrap() < 15.0, "{m}");
            assert!(max[2].as_f64().unwrap() < 15.0, "{m}");
        }
    }
}

/// The silent-degradation example: member 2 (and only it) is scored over
/// its degradation, and the group fusion reduces its error there.
#[test]
fn run_formation_degraded_example_scores_the_degraded_member() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = run_two_runs_of("formation_degraded", dir.path());
    assert!(
        stdout.contains("member 2 during its GNSS degradation"),
        "{stdout}"
    );
    let summary = read_summary(dir.path());
    for m in summary["members"].as_array().unwrap() {
        let degraded = m["member"] == 2;
        assert_eq!(m["degraded"], degraded, "{m}");
        let e = &m["degradation_rms_error_m"];
        if degraded {
            let e: Vec<f64> = (0..3).map(|s| e[s].as_f64().unwrap()).collect();
            assert!(e[1] < e[0] && e[2] < e[0], "{m}");
        } else {
            assert!(e.is_null(), "{m}");
        }
    }
}

#[test]
fn run_names_file_line_and_key_of_a_bad_formation() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("f.toml");
    for (text, message) in [
        (
            "[formation]\nmembers = 0\n",
            "f.toml:2: formation.members: 0 is out of range",
        ),
        (
            "[formation]\nmembers = 3\n[[formation.denial]]\nmembers = [3]\nstart_s = 1.0\nend_s = 2.0\n",
            "formation.denial[0].members",
        ),
        (
            "[formation]\n[[formation.degradation]]\nmember = 1\nstart_s = 1.0\nend_s = 2.0\nsigma_scale = 0.5\n",
            "formation.degradation[0].sigma_scale",
        ),
    ] {
        let err = failure_on("run", &f, text);
        assert!(err.contains(message), "{err}");
    }
    let err = failure_on("run", &f, "[formaton]\n");
    assert_contains_all(&err, &["f.toml:1", "formaton"]);
}

#[test]
fn reproduce_extended_state_writes_the_case_keys_other_tools_read() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(&scenario, "runs = 2\nsweep_runs = 2\nsweep_step_s = 60.0\n").unwrap();
    let out = dir.path().join("out");
    let stdout = reproduce(
        "extended-state",
        &["--scenario", scenario.to_str().unwrap(), "--quiet"],
        &out,
    );
    assert_contains_all(&stdout, &["2–5", "4–10"]);
    let summary = read_summary(&out);
    let cases = summary["cases"].as_array().unwrap();
    // Per trajectory: δ armed and δ literal per threshold, the share rule.
    assert_eq!(cases.len(), 45);
    for c in cases {
        let rule = c["rule"].as_str().unwrap();
        assert!(
            ["delta_armed", "delta_literal", "forecast_share"].contains(&rule),
            "{rule}"
        );
        assert!(
            c["bound_sigma_m"].as_f64().is_some_and(f64::is_finite),
            "{c}"
        );
        if rule != "delta_literal" {
            let e = c["error_gauss_newton_m"].as_f64();
            assert!(e.is_some_and(|e| e.is_finite() && e > 0.0), "{c}");
        }
        for key in [
            "t_b_s",
            "course_deg",
            "delta_threshold",
            "switch_time_s",
            "error_free_ins_m",
            "error_outputs_only_m",
            "error_proposed_m",
            "error_oracle_m",
            "ratio_median",
            "ratio_p10",
            "ratio_p90",
        ] {
            assert!(c[key].as_f64().is_some_and(f64::is_finite), "{key} in {c}");
        }
    }
    for f in [
        "extended_state.csv",
        "fig1_accel_bias_error.svg",
        "fig1_scale_factor_error.svg",
        "fig2_delta.svg",
        "fig3_position_error.svg",
        "switch_sweep.svg",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
}

#[test]
fn process_runs_the_recorded_drive_and_scores_it() {
    let dir = tempfile::tempdir().unwrap();
    let config = repo().join("examples/drive_0708.toml");
    // `--strict`: the readers' notes (a truncated line dropped, fixes
    // before the first IMU sample) do not fail it; a healthy run passes.
    let stdout = on_file("process", &config, &["--strict"], dir.path());
    assert!(
        stdout.contains("54858 IMU samples")
            // Published numbers of other tools are not printed beside an
            // arbitrary log's results (the README keeps them).
            && !stdout.contains("KF-GINS")
            && stdout.contains("huber"),
        "{stdout}"
    );
    let summary = read_summary(dir.path());
    let outages = summary["result"]["outages"].as_array().unwrap();
    assert_eq!(outages.len(), 3);
    for o in outages {
        assert!(
            o["three_d_m"]
                .as_f64()
                .is_some_and(|v| v.is_finite() && v > 0.0),
            "{o}"
        );
    }
    assert!(
        !summary["result"]["anomalies"]
            .as_array()
            .unwrap()
            .is_empty()
    );
    // Spec 20's supervisors: every predictor scored on every length, the
    // efficiency criterion per length, K_eff per epoch in solution.csv.
    let bridged = summary["result"]["outages_bridged"].as_array().unwrap();
    let predictors: Vec<&str> = bridged
        .iter()
        .map(|b| b["predictor"].as_str().unwrap())
        .collect();
    assert_eq!(predictors, ["trend", "combined_trend", "gmdh", "relay"]);
    for b in bridged {
        assert_eq!(b["scores"].as_array().unwrap().len(), 3, "{b}");
    }
    let efficiency = summary["result"]["efficiency"].as_array().unwrap();
    assert_eq!(efficiency.len(), 3);
    assert_eq!(efficiency[1]["sigma_gnss_m"], 1.5);
    let policies: Vec<&str> = summary["result"]["anomalies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a[1].as_str().unwrap())
        .collect();
    assert!(policies.contains(&"developed") && policies.contains(&"adaptive_gain"));
    let solution = std::fs::read_to_string(dir.path().join("solution.csv")).unwrap();
    assert!(solution.lines().next().unwrap().contains("k_eff"));
    // Antenna and IMU positions both, named: the drive's lever arm is 5 cm
    // (to the left of the IMU), so they differ by 5 cm at every row.
    let deg = std::f64::consts::PI / 180.0;
    let (alat, alon, ah) = (
        column(&solution, "antenna latitude [deg]"),
        column(&solution, "antenna longitude [deg]"),
        column(&solution, "antenna height [m]"),
    );
    let (ilat, ilon, ih) = (
        column(&solution, "imu latitude [deg]"),
        column(&solution, "imu longitude [deg]"),
        column(&solution, "imu height [m]"),
    );
    for k in (0..alat.len()).step_by(97) {
        let north = (alat[k] - ilat[k]) * deg * 6.37e6;
        let east = (alon[k] - ilon[k]) * deg * 6.37e6 * (ilat[k] * deg).cos();
        let d = (north * north + east * east + (ah[k] - ih[k]).powi(2)).sqrt();
        assert!((d - 0.05).abs() < 0.002, "row {k}: {d} m");
    }
    // σ of velocity and attitude beside the position's.
    let sv = column(&solution, "sigma_vn [m/s]");
    let sh = column(&solution, "sigma_heading [deg]");
    assert!(sv.iter().all(|v| *v > 0.0 && *v < 1.0));
    assert!(sh.iter().all(|v| *v > 0.0 && *v < 10.0));
    for f in ["solution.csv", "trajectory.svg", "outage_drift.svg"] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    // Item 7 of issue 13: the covariance against the actual error, per
    // outage length, and the NIS with all GNSS; printed after the outages.
    let consistency = &summary["result"]["consistency"];
    assert!((consistency["chi2_99"].as_f64().unwrap() - 11.3449).abs() < 1e-4);
    let lengths = consistency["outages"].as_array().unwrap();
    assert_eq!(lengths.len(), 3);
    for (o, l) in lengths.iter().zip([10.0, 30.0, 60.0]) {
        assert_eq!(o["outage_s"], l);
        assert_eq!(o["nees_dof"], 3);
        assert!(o["epochs"].as_u64().unwrap() > 100, "{o}");
        let inside = o["inside_99_fraction"].as_f64().unwrap();
        assert!(inside > 0.0 && inside <= 1.0, "{o}");
        assert!(o["mean_nees"].as_f64().unwrap() > 0.0, "{o}");
    }
    let all = &consistency["all_gnss"];
    assert!(all["mean_nis_per_dof"].as_f64().unwrap() > 0.0, "{all}");
    assert_eq!(all["epochs"], 2183);
    assert_eq!(summary["result"]["reference_epochs"], 2175);
    assert_eq!(outages[1]["windows_cut_short"], 0);
    let table = stdout
        .find("covariance consistency in the outages")
        .unwrap();
    assert!(
        stdout.find("simulated outages").unwrap() < table,
        "{stdout}"
    );
    // Input notes are in the summary with their kind; the only other
    // warnings are comparison-table runs of the adaptive-gain scheme,
    // which diverges under 30 % outliers (tens of km: its covariance then
    // fails) — the configured run warns of nothing.
    let warnings = summary["result"]["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().all(|w| w["kind"] == "input"
            || (w["kind"] == "scoring_run"
                && w["message"].as_str().unwrap().contains("adaptive_gain"))),
        "{warnings:?}"
    );
    assert!(warnings.iter().any(|w| w["kind"] == "input"));
}

/// The drive as a cheap scoring run: 10 s outages only, no anomaly or
/// burst runs, no bridging or smoothing; `extra` appended.
fn quick_drive_config(dir: &Path, extra: &str) -> PathBuf {
    let config = example_with_absolute_data("drive_0708")
        .replace("outages_s = [10.0, 30.0, 60.0]", "outages_s = [10.0]")
        .replace(
            "outlier_fractions = [0.1, 0.3]",
            "outlier_fractions = []\npost_outage_burst_s = 0.0",
        )
        .replace("enabled = true", "enabled = false")
        .replace("smooth = true ", "smooth = false ")
        + extra;
    let c = dir.join("c.toml");
    std::fs::write(&c, config).unwrap();
    c
}

#[test]
fn process_without_a_reference_quality_fix_says_no_reference() {
    let dir = tempfile::tempdir().unwrap();
    // The drive has RTK fixed and float fixes, no PPP: naming PPP as the
    // only reference leaves nothing to score against.
    let c = quick_drive_config(dir.path(), "");
    let text = std::fs::read_to_string(&c).unwrap().replace(
        "reference_quality = [\"fixed\"]",
        "reference_quality = [\"ppp\"]",
    );
    assert!(text.contains("[\"ppp\"]"));
    std::fs::write(&c, text).unwrap();
    let out = dir.path().join("out");
    let stdout = on_file("process", &c, &[], &out);
    assert_contains_all(
        &stdout,
        &[
            "over the 0 reference epochs no reference",
            "0/12",
            "12 of 12 windows hold no reference epoch",
            "actual error: no reference",
        ],
    );
    let lines: Vec<&str> = stdout.lines().collect();
    let row = lines.iter().position(|l| l.contains("L [s]")).unwrap() + 1;
    assert!(
        lines[row].matches("no reference").count() >= 4,
        "{}",
        lines[row]
    );
    let summary = read_summary(&out);
    let r = &summary["result"];
    assert!(r["tracking_rms_m"].is_null());
    assert_eq!(r["reference_epochs"], 0);
    assert!(r["outages"][0]["three_d_m"].is_null() && r["outages"][0]["horizontal_m"].is_null());
    assert_eq!(r["outages"][0]["windows"], 0);
    assert!(r["consistency"]["outages"][0]["mean_nees"].is_null());
    assert!(r["efficiency"][0]["actual_crossing_s"].is_null());
    // The NIS needs no reference.
    assert!(
        r["consistency"]["all_gnss"]["mean_nis_per_dof"]
            .as_f64()
            .unwrap()
            > 0.0
    );
}

#[test]
fn process_strict_exits_non_zero_after_writing_when_the_filter_diverges() {
    let dir = tempfile::tempdir().unwrap();
    // A χ² gate on the drive locks out after a turn: its innovations grow
    // while it rejects every fix (RMS 1.4 m against the 2.5 cm of
    // accepting them all) — a divergence and long rejection runs.
    let c = quick_drive_config(dir.path(), "");
    let text = std::fs::read_to_string(&c)
        .unwrap()
        .replace("policy = \"robust\"", "policy = \"chi2_gate\"")
        .replace("recovery = true", "recovery = false");
    std::fs::write(&c, text).unwrap();
    let out = dir.path().join("out");
    let args = [
        "process",
        c.to_str().unwrap(),
        "--no-score",
        "--out",
        out.to_str().unwrap(),
    ];
    // Without --strict: warnings, exit 0.
    let o = aidnav(&args);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_contains_all(
        &err,
        &[
            "warning: divergence: the mean position NIS per degree of freedom over 30 s stayed above 10 from",
            "position updates in a row rejected or limited, from",
        ],
    );
    // With it: exit status 3, every output written first.
    std::fs::remove_dir_all(&out).unwrap();
    let mut strict = args.to_vec();
    strict.push("--strict");
    let o = aidnav(&strict);
    assert_eq!(o.status.code(), Some(3), "{o:?}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("error: --strict: ") && !err.contains("panicked"),
        "{err}"
    );
    for f in ["solution.csv", "summary.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let summary = read_summary(&out);
    let kinds: Vec<&str> = summary["result"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["kind"].as_str().unwrap())
        .collect();
    assert!(
        kinds.contains(&"divergence") && kinds.contains(&"rejection_run"),
        "{kinds:?}"
    );
    let divergence = summary["result"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|w| w["kind"] == "divergence")
        .unwrap();
    assert!(divergence["end_s"].as_f64().unwrap() - divergence["start_s"].as_f64().unwrap() > 30.0);
}

/// The README's main job: the handheld walk from the repository's data, with
/// the pedestrian preset (levelled at its first standstill, standstill
/// updates while the walker stands).
#[test]
fn process_runs_the_walk_example_from_the_repository() {
    let dir = tempfile::tempdir().unwrap();
    let config = repo().join("examples/walk_0827.toml");
    let stdout = on_file("process", &config, &[], dir.path());
    assert!(stdout.contains("levelled at a standstill"), "{stdout}");
    assert!(stdout.contains("simulated outages"), "{stdout}");
    let summary = read_summary(dir.path());
    let result = &summary["result"];
    assert_eq!(result["start"]["kind"], "static");
    assert!(
        result["standstill_updates"].as_u64().unwrap() > 10,
        "{result}"
    );
    let tracking = result["tracking_rms_m"].as_f64().unwrap();
    assert!(tracking < 0.1, "{tracking}");
    // The configuration as used, the preset's values written out.
    assert_eq!(summary["scenario"]["platform"], "pedestrian");
    assert_eq!(summary["scenario"]["constraints"]["zero_velocity"], true);
    assert_eq!(summary["scenario"]["constraints"]["non_holonomic"], false);
}

#[test]
fn process_names_file_line_and_key_of_a_bad_config() {
    let dir = tempfile::tempdir().unwrap();
    let c = dir.path().join("c.toml");
    // Inputs that do not exist, named relative to the configuration.
    let data = "[data]\ndir = \".\"\nimu = \"i.csv\"\nimu_tags = \"i.csv.tag\"\ngnss = \"g.pos\"\n";
    let err = failure_on("process", &c, &format!("{data}[imu]\nsmoothing_s = -1.0\n"));
    assert!(err.contains("c.toml:7: imu.smoothing_s"), "{err}");
    // Neither input exists: the first one read is named.
    let err = failure_on("process", &c, data);
    assert!(
        err.contains("i.csv: cannot read") || err.contains("i.csv.tag: cannot read"),
        "{err}"
    );
}

#[test]
fn process_takes_a_given_attitude_and_writes_kf_gins_text() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string(repo().join("examples/drive_0708.toml")).unwrap();
    let data = data_dir("drive_0708");
    let config = example
        .replace(
            "# attitude_deg = [0.0, 0.0, 90.0]",
            "attitude_deg = [0.0, 0.0, 90.0]",
        )
        .replace("kf_gins_text = false", "kf_gins_text = true")
        .replace("interval_s = 0.0 ", "interval_s = 0.1 ")
        .replace("convergence_monitor = false", "convergence_monitor = true")
        .replace("smooth = true ", "smooth = false ");
    let c = dir.path().join("c.toml");
    std::fs::write(&c, config).unwrap();
    let out = dir.path().join("out");
    // The directory holds an earlier run's optional outputs: this run
    // writes navresult.txt anew, and removes the smoothed.csv and
    // outage_drift.svg it does not write (noting each); other files stay.
    std::fs::create_dir_all(&out).unwrap();
    for name in [
        "navresult.txt",
        "smoothed.csv",
        "outage_drift.svg",
        "notes.txt",
    ] {
        std::fs::write(out.join(name), "an earlier run's").unwrap();
    }
    on_file(
        "process",
        &c,
        &["--data", data.to_str().unwrap(), "--no-score"],
        &out,
    );
    assert!(out.join("notes.txt").exists());
    assert!(!out.join("outage_drift.svg").exists());
    let removed: Vec<String> = read_summary(&out)["result"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w["message"].as_str().unwrap().to_string())
        .filter(|m| m.contains("left by an earlier run"))
        .collect();
    assert_eq!(removed.len(), 2, "{removed:?}");
    assert!(removed[0].contains("smoothed.csv"), "{removed:?}");
    assert!(removed[1].contains("outage_drift.svg"), "{removed:?}");
    let nav = std::fs::read_to_string(out.join("navresult.txt")).unwrap();
    let first: Vec<&str> = nav.lines().next().unwrap().split_whitespace().collect();
    assert_eq!(first.len(), 11);
    assert_eq!(first[0], "2374"); // GPS week of 2025-07-08
    // The 2197 fixes and rows every 0.1 s between them (10 per second of
    // the 547 s drive), in time order.
    let times: Vec<f64> = nav
        .lines()
        .map(|l| l.split_whitespace().nth(1).unwrap().parse().unwrap())
        .collect();
    assert!((7000..8500).contains(&times.len()), "{}", times.len());
    assert!(times.windows(2).all(|w| w[1] > w[0]));
    assert!(!out.join("smoothed.csv").exists());
    let summary = read_summary(&out);
    assert_eq!(summary["scenario"]["initial"]["attitude_deg"][2], 90.0);
    // The monitor reports one entry per threshold (3 %, 1 %).
    assert_eq!(
        summary["result"]["instrument_convergence_s"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
}

#[test]
fn an_os_error_is_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let z = dir.path().join("z.csv");
    std::fs::write(&z, "z1\n1\n").unwrap();
    let err = filter_failure(Path::new("/nonexistent.toml"), &z, dir.path());
    assert_eq!(err.matches("/nonexistent.toml").count(), 1, "{err}");
    assert_eq!(err.matches("No such file").count(), 1, "{err}");
}

#[test]
fn a_closed_stdout_stops_the_process_quietly() {
    // The reader goes away before the first line is written (`| head -0`).
    let out = with_stdout_closed(&["reproduce", "all", "--print-scenario"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.is_empty(), "{err}");
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        assert!(
            out.status.success() || out.status.signal() == Some(13),
            "{:?}",
            out.status
        );
    }
}

const SCALAR_MODEL: &str =
    "phi = [[1.0]]\nq = [[0.0]]\nh = [[1.0]]\nr = [[1.0]]\nx0 = [0.0]\np0 = [[1.0]]\n";

#[test]
fn a_non_finite_nis_is_a_warning_naming_file_column_and_epoch() {
    let dir = tempfile::tempdir().unwrap();
    // 1e200² overflows: the NIS of epoch 1 is inf.
    let (model, z) = scalar_inputs(dir.path(), "z1\n1\n1e200\n");
    let out = dir.path().join("out");
    let o = aidnav(&filter_args(&model, &z, &out));
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "warning: innovations.csv: column `nis`: 1 non-finite value (first at epoch 1)"
        ),
        "{err}"
    );
    let summary = read_summary(&out);
    let warnings = summary["warnings"].as_array().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("column `nis`")),
        "{warnings:?}"
    );
}

#[test]
fn a_failed_filter_leaves_no_file_under_a_final_name() {
    let dir = tempfile::tempdir().unwrap();
    let (model, z) = scalar_inputs(dir.path(), "z1\n1\n2\n");
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    // A summary of an earlier run, and a directory where innovations.csv goes.
    std::fs::write(out.join("summary.json"), "{}").unwrap();
    std::fs::create_dir(out.join("innovations.csv")).unwrap();
    let err = filter_failure(&model, &z, &out);
    assert!(err.contains("innovations.csv: cannot write"), "{err}");
    let mut left: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, vec!["innovations.csv"]);
}

/// Issue 13: the walk processed end to end from the receiver's raw UBX log
/// (examples/walk_0827.toml): every NAV-PVT epoch used, the interleaved
/// NMEA and raw-measurement frames reported as skipped, and the RTK fixes
/// tracked to a few centimetres (2.5 cm measured, as from the `.pos`).
#[test]
fn process_runs_the_walk_from_its_ubx_log() {
    let dir = tempfile::tempdir().unwrap();
    let config = repo().join("examples/walk_0827.toml");
    on_file("process", &config, &["--no-score"], dir.path());
    let summary = read_summary(dir.path());
    let result = &summary["result"];
    assert_eq!(result["gnss_epochs"], 536, "{result}");
    let tracking = result["tracking_rms_m"].as_f64().unwrap();
    assert!((0.01..0.04).contains(&tracking), "{tracking}");
    let warnings = result["warnings"].to_string();
    assert_contains_all(
        &warnings,
        &[
            "136199 bytes outside UBX frames",
            "RXM-SFRBX ×2328, RXM-RAWX ×536",
        ],
    );
}

/// The walk example with its `[imu.noise]` table and GNSS σ scale removed
/// (the defaults' noise, far from the walk's), its data dir absolute.
fn walk_with_default_noise(dir: &Path) -> PathBuf {
    let example = example_with_absolute_data("walk_0827");
    let mut out = String::new();
    let mut in_noise = false;
    for line in example.lines() {
        if line.starts_with('[') {
            in_noise = line.trim() == "[imu.noise]";
        }
        if in_noise || line.starts_with("sigma_scale") {
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    let c = dir.join("walk_default_noise.toml");
    std::fs::write(&c, out).unwrap();
    c
}

/// `aidnav tune` on the recorded walk, the search cut to 12 filter passes:
/// the Allan table of its 18 s standstill, a likelihood gain, the files; the
/// fitted table pasted into the walk's configuration processes.
#[test]
fn tune_fits_the_walk_and_its_table_pastes_into_the_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let config = walk_with_default_noise(dir.path());
    let out = dir.path().join("tune");
    let stdout = on_file("tune", &config, &["--max-evaluations", "12"], &out);
    assert_contains_all(
        &stdout,
        &[
            "longest standstill: 18.1 s, 115.6 s into the log",
            "Allan deviation of the unsmoothed samples at rest",
            "gnss_sigma_scale",
            "log-likelihood: configured",
        ],
    );
    let summary = read_summary(&out);
    assert_eq!(summary["command"], "tune");
    assert!(summary["seed"].is_null());
    let t = &summary["result"]["tuning"];
    // The walk's gyro white noise at rest: RMS over the axes 0.30 deg/√h
    // (0.25 / 0.42 / 0.17), far below the handheld motion's.
    let arw = t["allan"]["arw_deg_per_sqrt_h"].as_f64().unwrap();
    assert!((0.25..0.35).contains(&arw), "ARW {arw}");
    assert_eq!(t["allan"]["axes"].as_array().unwrap().len(), 6);
    // The coasting objective: 4 windows of 15 s (the walk's longest scored
    // outage) withheld; every fix after the first is an update or withheld.
    assert_eq!(t["objective"], "coasting");
    assert_eq!(t["windows"].as_array().unwrap().len(), 4);
    assert_eq!(
        t["updates"].as_u64().unwrap() + t["withheld"].as_u64().unwrap(),
        515
    );
    assert_eq!(t["withheld"], 240);
    assert!(stdout.contains("4 windows of 15 s withheld"), "{stdout}");
    assert_eq!(t["passes"], 14);
    let (conf, fitted) = (
        t["log_likelihood_configured"].as_f64().unwrap(),
        t["log_likelihood_fitted"].as_f64().unwrap(),
    );
    // The defaults' noise is far from the walk's: thousands gained even
    // in 12 passes.
    assert!(fitted - conf > 1000.0, "{conf} → {fitted}");
    let csv = std::fs::read_to_string(out.join("allan.csv")).unwrap();
    assert_eq!(csv.lines().count(), 11, "{csv}"); // header, τ = 0.0064 … 3.3 s
    assert_eq!(column(&csv, "gyro_x [deg/h]").len(), 10);
    assert!(out.join("allan.svg").is_file());
    // tuned_noise.toml appended to the walk's configuration (which has no
    // [imu.noise] table) is a configuration that runs with those values.
    let tuned = std::fs::read_to_string(out.join("tuned_noise.toml")).unwrap();
    let example = std::fs::read_to_string(&config).unwrap();
    let c = dir.path().join("tuned.toml");
    std::fs::write(&c, format!("{example}\n{tuned}")).unwrap();
    let data = data_dir("walk_0827");
    let p_out = dir.path().join("process");
    on_file(
        "process",
        &c,
        &["--data", data.to_str().unwrap(), "--no-score"],
        &p_out,
    );
    let used = &read_summary(&p_out)["scenario"]["imu"]["noise"];
    let fitted_arw = t["fitted"]["noise"]["arw_deg_per_sqrt_h"].as_f64().unwrap();
    let used_arw = used["arw_deg_per_sqrt_h"].as_f64().unwrap();
    assert!(
        (used_arw / fitted_arw - 1.0).abs() < 1e-3,
        "{used_arw} {fitted_arw}"
    );
    assert_eq!(used["auto"], false);
}

/// `[imu.noise] auto = true`: `process` tunes first (here 6 passes), says
/// so, writes the tuning's files and filters with the fitted values.
#[test]
fn process_with_auto_noise_tunes_first() {
    let dir = tempfile::tempdir().unwrap();
    let example = std::fs::read_to_string(walk_with_default_noise(dir.path())).unwrap();
    let c = dir.path().join("auto.toml");
    std::fs::write(
        &c,
        format!("{example}\n[imu.noise]\nauto = true\n\n[tune]\nmax_evaluations = 6\n"),
    )
    .unwrap();
    let data = data_dir("walk_0827");
    let out = dir.path().join("out");
    let stdout = on_file(
        "process",
        &c,
        &["--data", data.to_str().unwrap(), "--no-score"],
        &out,
    );
    assert!(
        stdout.contains("[imu.noise] auto: the noise was tuned first"),
        "{stdout}"
    );
    let summary = read_summary(&out);
    let t = &summary["result"]["tuning"];
    assert_eq!(t["passes"], 8);
    let used = &summary["scenario"]["imu"]["noise"];
    assert_eq!(used["auto"], true);
    assert_eq!(
        used["vrw_mps_per_sqrt_h"],
        t["fitted"]["noise"]["vrw_mps_per_sqrt_h"]
    );
    assert_eq!(
        summary["scenario"]["gnss"]["sigma_scale"],
        t["fitted"]["gnss_sigma_scale"]
    );
    for f in ["allan.svg", "allan.csv", "tuned_noise.toml", "solution.csv"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
}

/// `aidnav convert --to kf-gins` on the drive, read back by aidnav's own
/// KF-GINS readers under the same configuration: the same samples. Rates,
/// specific force, positions and σ are written in their shortest exact
/// decimal form, so they come back to 4 ulp (rate × dt / dt) and exactly;
/// times move by the start of the GPS week, and an IMU sample's time by at
/// most a quarter of the change of spacing around it (its interval's ends
/// are the midpoints to its neighbours) plus 1e-9 s of rounding at 6e5 s.
#[test]
fn convert_to_kf_gins_round_trips_the_drive() {
    use aidnav::app::process::{Inputs, ProcessConfig};
    let dir = tempfile::tempdir().unwrap();
    let data = data_dir("drive_0708");
    let original = example_with_absolute_data("drive_0708");
    let c = dir.path().join("drive.toml");
    std::fs::write(&c, &original).unwrap();
    let out = dir.path().join("kf");
    let stdout = on_file("convert", &c, &["--to", "kf-gins"], &out);
    assert!(stdout.contains("times in seconds of GPS week"), "{stdout}");
    let yaml = std::fs::read_to_string(out.join("kf-gins.yaml")).unwrap();
    for key in [
        "imupath:",
        "gnsspath:",
        "outputpath:",
        "imudatalen: 7",
        "imudatarate: 100",
        "starttime:",
        "endtime: -1",
        "initpos:",
        "initvel:",
        "initatt:",
        "imunoise:",
        "corrtime:",
        "antlever:",
    ] {
        assert!(yaml.contains(key), "{key} missing:\n{yaml}");
    }
    let converted = original
        .replace(
            &format!("dir = {:?}", data.to_str().unwrap()),
            &format!("dir = {:?}", out.to_str().unwrap()),
        )
        .replace("imu = \"imu_1934.csv\"", "imu = \"imu.txt\"")
        .replace("imu_format = \"rtklib_tagged\"", "imu_format = \"kf_gins\"")
        .replace("imu_tags = \"imu_1934.csv.tag\"", "")
        .replace("gnss = \"gnss_1934_sf.pos\"", "gnss = \"gnss.txt\"")
        .replace("gnss_format = \"rtklib_pos\"", "gnss_format = \"kf_gins\"");
    let cfg_a: ProcessConfig = toml::from_str(&original).unwrap();
    let cfg_b: ProcessConfig = toml::from_str(&converted).unwrap();
    let a = Inputs::load_raw(&cfg_a, dir.path()).unwrap();
    let b = Inputs::load_raw(&cfg_b, dir.path()).unwrap();
    assert_eq!(a.imu.len(), b.imu.len());
    assert_eq!(a.gnss.len(), b.gnss.len());
    let week = a.imu[0].time_s - b.imu[0].time_s;
    assert_eq!((week - 315_964_800.0).rem_euclid(604_800.0), 0.0, "{week}");
    for (k, (x, y)) in a.imu.iter().zip(&b.imu).enumerate() {
        let jitter = if k == 0 || k + 1 == a.imu.len() {
            0.0
        } else {
            ((a.imu[k + 1].time_s - x.time_s) - (x.time_s - a.imu[k - 1].time_s)).abs()
        };
        let dt = x.time_s - week - y.time_s;
        assert!(dt.abs() <= jitter / 4.0 + 1e-9, "IMU {k}: {dt} s");
        for (p, q) in x
            .angular_rate
            .iter()
            .chain(x.specific_force.iter())
            .zip(y.angular_rate.iter().chain(y.specific_force.iter()))
        {
            assert!(
                (p - q).abs() <= 4.0 * f64::EPSILON * p.abs(),
                "IMU {k}: {p} {q}"
            );
        }
    }
    for (k, (x, y)) in a.gnss.iter().zip(&b.gnss).enumerate() {
        assert_eq!(x.time_s - week, y.time_s, "GNSS {k}");
        assert!((x.position.latitude_rad - y.position.latitude_rad).abs() < 1e-15);
        assert!((x.position.longitude_rad - y.position.longitude_rad).abs() < 1e-15);
        assert_eq!(x.position.height_m, y.position.height_m, "GNSS {k}");
        assert_eq!(x.position_sigma_neu, y.position_sigma_neu, "GNSS {k}");
    }
    // The converted log goes through `process`'s loading (mounting, time
    // offset, overlap and turn-rate checks) as the original does.
    let mounted = Inputs::load_unsmoothed(&cfg_b, dir.path()).unwrap();
    assert_eq!(mounted.imu.len(), a.imu.len());
}

#[test]
fn convert_help_and_errors() {
    let help = success(&["convert", "--help"]);
    assert!(help.contains("SENSOR"), "{help}");
    assert!(help.contains("seconds of week"), "{help}");
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.toml");
    let out = dir.path().join("o");
    let convert_to = |format: &str| {
        failure(&[
            "convert",
            missing.to_str().unwrap(),
            "--to",
            format,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let err = convert_to("kf-gins");
    assert!(err.contains("missing.toml"), "{err}");
    let err = convert_to("rinex");
    assert!(err.contains("kf-gins"), "{err}");
}
