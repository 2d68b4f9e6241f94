//! The `[wheel_speed]` and `[barometer]` sections of `aidnav process` on a
//! simulated car with known truth (`aidnav_sim::car`): the streams written
//! as the generic CSVs, read back through the configuration, fused by the
//! pipeline's filter (its state grown by the sections' blocks), and the
//! drift in a 60 s GNSS outage measured against the truth.

use std::fmt::Write as _;
use std::path::Path;

use aidnav_app::process::{Inputs, PolicyName, ProcessConfig, RunPlan, run_filter};
use aidnav_sim::car::{CarLog, CarScenario, simulate_car};

/// The outage, seconds from the log's start: in the urban part, with turns.
const OUTAGE_S: [f64; 2] = [200.0, 260.0];

/// The configuration: the car platform (non-holonomic constraint and
/// standstill updates on), the scenario's datasheet IMU noise, and the
/// extra tables.
fn config(s: &CarScenario, extra: &str) -> ProcessConfig {
    let (g, a) = (&s.imu.gyro, &s.imu.accel);
    let [lx, ly, lz] = s.gnss.lever_arm_m;
    let text = format!(
        "platform = \"car\"\n\
         [data]\ndir = \".\"\nimu = \"none\"\nimu_format = \"generic_csv\"\ngnss = \"none\"\n\
         [gnss]\nlever_arm_m = [{lx}, {ly}, {lz}]\n\
         [imu.noise]\narw_deg_per_sqrt_h = {:?}\nvrw_mps_per_sqrt_h = {:?}\n\
         gyro_bias_deg_per_h = {:?}\naccel_bias_mg = {:?}\n\
         gyro_scale_ppm = {:?}\naccel_scale_ppm = {:?}\n\
         [output]\nsmooth = false\n{extra}",
        g.angle_random_walk_deg_sqrt_h,
        a.velocity_random_walk_m_s_sqrt_h,
        g.turn_on_bias_sigma_deg_h,
        a.turn_on_bias_sigma_mg,
        g.scale_factor_sigma_ppm,
        a.scale_factor_sigma_ppm,
    );
    aidnav_io::config::parse_toml::<ProcessConfig>(&text, Path::new("test.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// The simulated streams as the generic CSVs in `dir`.
fn write_streams(log: &CarLog, dir: &Path) {
    let mut wheel = String::from("time_s,speed_mps\n");
    for w in &log.wheel_speed {
        writeln!(wheel, "{},{}", w.time_s, w.speed_mps).unwrap();
    }
    std::fs::write(dir.join("wheel_speed.csv"), wheel).unwrap();
    let mut baro = String::from("time_s,height_m\n");
    for b in &log.baro {
        writeln!(baro, "{},{}", b.time_s, b.height_m).unwrap();
    }
    std::fs::write(dir.join("barometer.csv"), baro).unwrap();
}

/// Inputs of the log under `cfg`, the sections' streams read from `dir`.
fn inputs(cfg: &ProcessConfig, log: &CarLog, dir: &Path) -> Inputs {
    let mut inputs = Inputs::from_samples(
        cfg,
        log.imu.clone(),
        log.gnss.clone(),
        Vec::new(),
        (Path::new("imu"), Path::new("gnss")),
    )
    .unwrap();
    let wheel = cfg
        .wheel_speed
        .as_ref()
        .map_or_else(Vec::new, |w| w.format.read(&dir.join(&w.file)).unwrap().0);
    let baro = cfg
        .barometer
        .as_ref()
        .map_or_else(Vec::new, |b| b.format.read(&dir.join(&b.file)).unwrap().0);
    inputs.add_aiding(cfg, wheel, baro, dir).unwrap();
    inputs
}

/// Largest horizontal and vertical IMU position error in the outage \[m\]
/// (rows every 0.5 s), and the run's per-source counts.
fn outage_errors(
    cfg: &ProcessConfig,
    log: &CarLog,
    dir: &Path,
) -> (f64, f64, Vec<aidnav_integration::aiding::SourceStatus>) {
    let inputs = inputs(cfg, log, dir);
    let plan = RunPlan {
        row_interval_s: 0.5,
        ..RunPlan::default()
    };
    let run = run_filter(cfg, &inputs, &plan, PolicyName::Accept).unwrap();
    let t0 = log.imu[0].time_s;
    let (a, b) = (t0 + OUTAGE_S[0], t0 + OUTAGE_S[1]);
    let (mut horizontal, mut vertical, mut rows) = (0.0f64, 0.0f64, 0);
    for row in run.between.iter().filter(|r| r.time_s > a && r.time_s < b) {
        let e = log.truth_at(row.time_s).unwrap().position.ned_to(&row.imu);
        horizontal = horizontal.max(e.x().hypot(e.y()));
        vertical = vertical.max(e.z().abs());
        rows += 1;
    }
    assert!(rows > 100, "{rows} rows in the outage");
    (horizontal, vertical, run.sources)
}

#[test]
fn the_sections_build_their_sources_and_shrink_the_outage_drift() {
    let mut s = CarScenario::default();
    s.gnss.outages_s = vec![OUTAGE_S];
    let log = simulate_car(&s, 34).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_streams(&log, dir.path());
    let [wx, wy, wz] = s.wheel_speed.lever_arm_m;
    let wheel = format!(
        "[wheel_speed]\nfile = \"wheel_speed.csv\"\nlever_arm_m = [{wx}, {wy}, {wz}]\n\
         sigma_mps = {}\n",
        s.wheel_speed.noise_sigma_mps
    );
    let baro = format!(
        "[barometer]\nfile = \"barometer.csv\"\nsigma_m = {}\n",
        s.baro.noise_sigma_m
    );

    let plain = config(&s, "");
    assert_eq!(plain.state_layout().len(), 21);
    let (h_plain, v_plain, sources) = outage_errors(&plain, &log, dir.path());
    let names: Vec<_> = sources.iter().map(|s| s.name).collect();
    assert_eq!(
        names,
        [
            "non_holonomic",
            "zero_velocity",
            "zero_angular_rate",
            "gnss_position",
            "gnss_velocity"
        ]
    );

    let aided = config(&s, &format!("{wheel}{baro}"));
    assert_eq!(aided.state_layout().len(), 23);
    let (h_aided, v_aided, sources) = outage_errors(&aided, &log, dir.path());
    println!(
        "60 s outage through the configuration: horizontal {h_plain:.2} → {h_aided:.2} m, \
         vertical {v_plain:.2} → {v_aided:.2} m; {sources:?}"
    );
    let by_name = |n: &str| *sources.iter().find(|s| s.name == n).unwrap();
    let (w, b) = (by_name("wheel_speed"), by_name("barometer"));
    // At most one update per 0.1 s (the default min_interval_s) of a 20 Hz
    // odometer and a 10 Hz barometer over the 449 s after the start.
    for status in [w, b] {
        assert!(
            (3_500..=4_600).contains(&status.fused),
            "{status:?}: about 10 Hz over the log"
        );
        assert_eq!(
            status.fused,
            status.accepted + status.rejected + status.modified
        );
        assert!(
            status.rejected * 100 < status.fused,
            "{status:?}: a few gated at most"
        );
    }
    // The car platform already constrains the lateral and vertical body
    // velocity; the odometer adds the forward speed.
    assert!(
        h_aided * 2.0 < h_plain,
        "odometer: {h_aided:.2} m against {h_plain:.2} m"
    );
    // The barometer bounds the height to its noise and drift.
    let bound = 3.0 * (s.baro.noise_sigma_m + s.baro.drift_sigma_m);
    assert!(
        v_aided < bound,
        "barometer: {v_aided:.2} m against {bound:.2} m"
    );

    // A stream outside the IMU's span is refused, naming its file.
    let late = config(
        &s,
        "[wheel_speed]\nfile = \"wheel_speed.csv\"\ntime_offset_s = 10.0\n",
    );
    let mut shifted = log.clone();
    shifted.wheel_speed.iter_mut().for_each(|w| w.time_s += 1e6);
    write_streams(&shifted, dir.path());
    let mut inputs = Inputs::from_samples(
        &late,
        log.imu.clone(),
        log.gnss.clone(),
        Vec::new(),
        (Path::new("imu"), Path::new("gnss")),
    )
    .unwrap();
    let path = dir.path().join("wheel_speed.csv");
    let samples = late
        .wheel_speed
        .as_ref()
        .unwrap()
        .format
        .read(&path)
        .unwrap()
        .0;
    let err = inputs
        .add_aiding(&late, samples, Vec::new(), dir.path())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("wheel_speed.csv") && err.contains("none of its"),
        "{err}"
    );
}
