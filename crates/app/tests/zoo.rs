//! The zoo's fast subset (`zoo/fast.txt`): six short simulated logs of
//! different platforms, IMU grades, receivers and planted installation
//! errors, each simulated, written, read back through its new-user
//! configuration, processed and scored against its truth.
//!
//! The bounds are what aidnav achieves today with a margin (about 2× the
//! measured value, printed by the test): a change that makes any log
//! worse fails here. The planted installation errors (lever arm, mounting,
//! latency) are not estimated yet — those logs' bounds hold the cost of
//! that, and the install-parameters issue tightens them.

use std::path::{Path, PathBuf};

use aidnav_app::jobs::simulate::{load_simulation, simulate_to_dir};
use aidnav_app::jobs::zoo::{SCORE_COLUMNS, ZooEntry, score_cells, zoo};

fn zoo_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo")
}

fn fast_files() -> Vec<PathBuf> {
    let list = std::fs::read_to_string(zoo_dir().join("fast.txt")).unwrap();
    list.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| zoo_dir().join(l))
        .collect()
}

/// (score column, largest allowed) per log; `in99` and NEES bounds below.
fn bounds(name: &str) -> &'static [(&'static str, f64)] {
    match name {
        // Measured: 1.69, 2.06, 5.77, 3.70 m; matched 1.40 m.
        "short_car_baseline" => &[
            ("tracking_3d_m", 3.0),
            ("drift_10s_m", 4.0),
            ("drift_30s_m", 10.0),
            ("drift_60s_m", 8.0),
            ("yaw_error_deg", 0.5),
            ("mean_nees", 6.0),
        ],
        // The 1.1 m lever arm the configuration does not know is the
        // tracking error with RTK fixes; the non-holonomic gate rejects
        // the pitched constraint while fixes arrive (a vehicle_frame
        // warning). Measured 1.11, 3.55, 15.0, 32.5 m.
        "short_car_pitch3_fixed" => &[
            ("tracking_3d_m", 1.5),
            ("drift_10s_m", 8.0),
            ("drift_60s_m", 70.0),
        ],
        // 0.2 s of latency at 12 m/s. Measured 2.78, 4.7, 25.8 m.
        "short_car_latency_fixed_10hz" => &[
            ("tracking_3d_m", 4.0),
            ("drift_10s_m", 10.0),
            ("drift_60s_m", 55.0),
        ],
        // Measured 1.68, 2.86, 44.4 m.
        "short_flight_tactical" => &[
            ("tracking_3d_m", 3.0),
            ("drift_10s_m", 6.0),
            ("drift_60s_m", 90.0),
        ],
        // Measured 3.49, 19.7 m, yaw 6.4°.
        "short_walk_consumer" => &[
            ("tracking_3d_m", 7.0),
            ("drift_10s_m", 40.0),
            ("yaw_error_deg", 13.0),
        ],
        _ => &[],
    }
}

fn value(e: &ZooEntry, column: &str, matched: bool) -> Option<f64> {
    let i = SCORE_COLUMNS.iter().position(|c| *c == column).unwrap();
    score_cells(if matched {
        e.matched.as_ref()
    } else {
        e.new_user.as_ref()
    })[i]
}

#[test]
fn the_fast_zoo_scores_within_its_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let files = fast_files();
    assert_eq!(files.len(), 6);
    let run = zoo(&files, dir.path()).unwrap();
    let csv = std::fs::read_to_string(dir.path().join("zoo.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + files.len());
    for e in &run.entries {
        eprintln!(
            "{}: {:?} | matched {:?} | {:?}",
            e.name,
            score_cells(e.new_user.as_ref()),
            score_cells(e.matched.as_ref()),
            e.error
        );
        if e.name == "short_rover_no_velocity" {
            // A 0.8 m/s rover never reaches the car preset's heading
            // speed: refused with the way out named (a finding of the
            // zoo for the install-parameters issue, not a crash).
            let why = e.error.as_deref().unwrap_or_default();
            assert!(why.contains("heading_speed_mps"), "{why}");
            continue;
        }
        assert!(e.error.is_none(), "{}: {:?}", e.name, e.error);
        assert!(!bounds(&e.name).is_empty(), "{}: no bounds", e.name);
        for &(column, max) in bounds(&e.name) {
            let v = value(e, column, false).unwrap_or(f64::NAN);
            assert!(v <= max, "{}: {column} = {v} > {max}", e.name);
        }
        // The matched noise model tracks at least as well, to 0.5 m, where
        // nothing but noise is planted.
        if e.name == "short_car_baseline" {
            let (n, m) = (
                value(e, "tracking_3d_m", false).unwrap(),
                value(e, "tracking_3d_m", true).unwrap(),
            );
            assert!(m <= n + 0.5, "matched {m} m, new user {n} m");
            // The new user's σ (single-point σ × 5) is honest: measured
            // 100 % inside the 99 % ellipsoid. (The matched model is not,
            // 31 %: it takes the receiver's time-correlated error as
            // white, as every loosely coupled filter without GNSS error
            // states does.)
            let inside = value(e, "inside_99_fraction", false).unwrap();
            assert!(inside >= 0.9, "{inside} inside the 99 % ellipsoid");
        }
    }
}

/// Same scenario, same seed: the same bytes in every file; another seed:
/// another log.
#[test]
fn a_simulation_is_byte_reproducible() {
    let file = zoo_dir().join("short_car_baseline.toml");
    let dirs = [(); 3].map(|_| tempfile::tempdir().unwrap());
    for (d, seed) in dirs.iter().zip([None, None, Some(99)]) {
        simulate_to_dir(&load_simulation(&file, seed).unwrap(), d.path()).unwrap();
    }
    let bytes = |d: &tempfile::TempDir, f: &str| std::fs::read(d.path().join(f)).unwrap();
    let mut names: Vec<String> = std::fs::read_dir(dirs[0].path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert!(names.len() >= 12, "{names:?}");
    for f in &names {
        assert!(
            bytes(&dirs[0], f) == bytes(&dirs[1], f),
            "{f} differs between two runs"
        );
    }
    assert!(bytes(&dirs[0], "imu.csv") != bytes(&dirs[2], "imu.csv"));
    let summary = String::from_utf8(bytes(&dirs[2], "summary.json")).unwrap();
    assert!(summary.contains("\"seed\": 99") && summary.contains("aidnav_version"));
}

/// Every format written reads back, through the configuration's
/// `[data]`, as the same log: the IMU samples of every IMU format and the
/// fixes of every GNSS format agree with the generic CSV's to the format's
/// resolution.
#[test]
fn every_format_written_reads_back_as_the_same_log() {
    use aidnav_app::process::{Inputs, ProcessConfig};
    let dir = tempfile::tempdir().unwrap();
    let sim = load_simulation(&zoo_dir().join("short_car_latency_fixed_10hz.toml"), None).unwrap();
    simulate_to_dir(&sim, dir.path()).unwrap();
    let config = std::fs::read_to_string(dir.path().join("aidnav.toml")).unwrap();
    let load = |imu: (&str, &str), gnss: (&str, &str)| {
        let mut text = config
            .replace("imu = \"imu.csv\"", &format!("imu = \"{}\"", imu.0))
            .replace(
                "imu_format = \"generic_csv\"",
                &format!("imu_format = \"{}\"", imu.1),
            )
            .replace("gnss = \"gnss.csv\"", &format!("gnss = \"{}\"", gnss.0))
            .replace(
                "gnss_format = \"generic_csv\"",
                &format!("gnss_format = \"{}\"", gnss.1),
            );
        if imu.1 == "rtklib_tagged" {
            text = text.replace("[data]\n", "[data]\nimu_tags = \"imu_raw.csv.tag\"\n");
        }
        let path = dir.path().join("variant.toml");
        std::fs::write(&path, text).unwrap();
        let (cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&path).unwrap();
        Inputs::load_raw(&cfg, dir.path()).unwrap()
    };
    let generic = load(("imu.csv", "generic_csv"), ("gnss.csv", "generic_csv"));
    for (imu, time_tol, value_tol) in [
        (("imu_raw.csv", "rtklib_tagged"), 2e-3, 1e-6),
        (("imu.txt", "kf_gins"), 1e-6, 1e-6),
    ] {
        let other = load(imu, ("gnss.csv", "generic_csv"));
        assert_eq!(other.imu.len(), generic.imu.len(), "{imu:?}");
        for (a, b) in generic.imu.iter().zip(&other.imu).skip(1) {
            assert!(
                (a.time_s - b.time_s).abs() < time_tol,
                "{imu:?}: {} vs {}",
                a.time_s,
                b.time_s
            );
            // KF-GINS increments are the interval's mean rate: compare
            // loosely (the signals change little over 10 ms).
            let tol: f64 = if imu.1 == "kf_gins" { 0.05 } else { value_tol };
            assert!(
                (a.specific_force - b.specific_force).norm() < tol.max(value_tol),
                "{imu:?}"
            );
        }
    }
    for (gnss, metres, seconds) in [
        (("gnss.pos", "rtklib_pos"), 2e-3, 1e-3),
        (("gnss.txt", "kf_gins"), 1e-6, 1e-6),
        (("gnss.nmea", "nmea"), 2e-2, 1e-2),
        (("gnss.ubx", "ubx"), 2e-2, 1e-3),
    ] {
        let other = load(("imu.csv", "generic_csv"), gnss);
        assert_eq!(other.gnss.len(), generic.gnss.len(), "{gnss:?}");
        for (a, b) in generic.gnss.iter().zip(&other.gnss) {
            assert!(
                (a.time_s - b.time_s).abs() <= seconds,
                "{gnss:?}: {} vs {}",
                a.time_s,
                b.time_s
            );
            let d = a.position.ned_to(&b.position).norm();
            assert!(d < metres, "{gnss:?}: {d} m");
        }
    }
}

/// RMS over the `length_s` outage windows of the largest 3-D drift, every
/// fix accepted, scored against the RTK-fixed fixes withheld (the same
/// path for a recorded and a simulated log).
fn coasting_m(
    cfg: &aidnav_app::process::ProcessConfig,
    inputs: &aidnav_app::process::Inputs,
    length_s: f64,
) -> f64 {
    use aidnav_app::process::{PolicyName, RunPlan, outage_windows, run_filter, score_windows};
    let first = inputs.imu[0].time_s;
    let last = inputs.gnss[inputs.gnss.len() - 1].time_s;
    let windows = outage_windows(&cfg.score, first, last, length_s);
    let plan = RunPlan {
        windows: windows.clone(),
        ..RunPlan::default()
    };
    let epochs = run_filter(cfg, inputs, &plan, PolicyName::Accept)
        .unwrap()
        .epochs;
    score_windows(&epochs, &windows, length_s, &cfg.score.reference_quality)
        .three_d_m
        .unwrap()
}

/// The simulator against the real drive: the drive's IMU as its Allan
/// deviation at rest describes it (zoo/car_drive_0708_imu.toml), coasted
/// by the drive's own filter configuration, drifts like the recorded drive
/// in 30 and 60 s outages — within a factor of 2 of the real figures, as
/// the RMS over six seeds. Measured (every fix accepted): real 1.54 /
/// 10.7 / 25.9 m; simulated 0.58 / 9.2 / 37.3 m. The 10 s figure is 2.7×
/// smaller than the real one:
/// the simulated car has no road vibration, which the real drive's first
/// seconds of coasting feel (its gyro noise density while driving is 3–5×
/// the at-rest value). With the example's tuned values taken as white
/// noise (13.8 °/√h) the simulated car drifts hundreds of metres in 60 s:
/// those values are the filter's inflated process noise, not a random
/// walk the real IMU has (the closing note of the simulator issue).
#[test]
fn a_simulated_drive_coasts_like_the_real_one() {
    use aidnav_app::process::{Inputs, ProcessConfig};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let config = root.join("examples/drive_0708.toml");
    let (drive_cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&config).unwrap();
    let drive = Inputs::load(&drive_cfg, config.parent().unwrap()).unwrap();
    let lengths = [10.0, 30.0, 60.0];
    let real = lengths.map(|l| coasting_m(&drive_cfg, &drive, l));
    let dir = tempfile::tempdir().unwrap();
    let mut sum_sq = [0.0; 3];
    let seeds = 1..=6;
    for seed in seeds.clone() {
        let sim = load_simulation(&zoo_dir().join("car_drive_0708_imu.toml"), Some(seed)).unwrap();
        let out = dir.path().join(format!("seed{seed}"));
        simulate_to_dir(&sim, &out).unwrap();
        let (mut cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&out.join("aidnav.toml")).unwrap();
        cfg.imu.noise = drive_cfg.imu.noise;
        cfg.gnss.sigma_scale = drive_cfg.gnss.sigma_scale;
        cfg.constraints.non_holonomic_sigma_mps = drive_cfg.constraints.non_holonomic_sigma_mps;
        let inputs = Inputs::load(&cfg, &out).unwrap();
        for (k, &l) in lengths.iter().enumerate() {
            sum_sq[k] += coasting_m(&cfg, &inputs, l).powi(2);
        }
    }
    let n = seeds.count() as f64;
    let simulated = sum_sq.map(|s| (s / n).sqrt());
    eprintln!("coasting 10 / 30 / 60 s: real {real:.2?} m, simulated {simulated:.2?} m");
    for k in 1..3 {
        let ratio = simulated[k] / real[k];
        assert!(
            (0.5..=2.0).contains(&ratio),
            "{} s: simulated {} m, real {} m",
            lengths[k],
            simulated[k],
            real[k]
        );
    }
}
