//! `aidnav process`: a recorded log, filtered, scored and written.

use super::*;

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
        let d = origin.ned_to(g).raw();
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
