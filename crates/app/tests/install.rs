//! Installation parameters estimated from the log, on simulated logs
//! with the values planted: `gnss.latency = "estimate"` recovers the GNSS
//! time tag's latency, `gnss.estimate_lever_arm` the antenna's lever arm.

use std::path::Path;

use aidnav_app::jobs::simulate::{Simulation, simulate_to_dir, simulation_of_text};
use aidnav_app::jobs::zoo::matched_config;
use aidnav_app::process::{Process, ProcessConfig};
use aidnav_integration::state::{AddedStateEstimate, Augmented};

/// The zoo's 10 Hz RTK car with the latency set to `latency_s`, written
/// to `dir`; its planted lever arm (IMU axes).
fn car_log(dir: &Path, latency_s: f64) -> [f64; 3] {
    car_simulation(dir, latency_s)
        .scenario
        .gnss_lever_arm_imu_m()
}

/// [`car_log`]'s simulation.
fn car_simulation(dir: &Path, latency_s: f64) -> Simulation {
    let zoo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo");
    let path = zoo.join("short_car_latency_fixed_10hz.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("latency_s = 0.2", &format!("latency_s = {latency_s}"));
    assert!(text.contains(&format!("latency_s = {latency_s}")));
    let sim = simulation_of_text(&text, &path, None).unwrap();
    simulate_to_dir(&sim, dir).unwrap();
    sim
}

/// The log's new-user configuration with the planted lever arm (the
/// lever arm is not what this test estimates) and `extra_gnss` keys.
fn config(dir: &Path, arm: [f64; 3], extra_gnss: &str) -> ProcessConfig {
    let text = std::fs::read_to_string(dir.join("aidnav.toml"))
        .unwrap()
        .replace(
            "[data]\n",
            &format!(
                "[gnss]\nlever_arm_m = [{}, {}, {}]\n{extra_gnss}\n\n[data]\n",
                arm[0], arm[1], arm[2]
            ),
        );
    let path = dir.join("estimate.toml");
    std::fs::write(&path, text).unwrap();
    aidnav_io::load_toml::<ProcessConfig>(&path).unwrap().0
}

/// Latencies of 0, 0.1 and 0.3 s recovered within ±10 ms (measured: +1.4,
/// +2.1, +2.8 ms, σ 0.64 ms), and the re-timed run coasts as well as one
/// told the true latency. The σ is optimistic by about 1.5× (the RTK
/// errors are correlated over seconds, the filter takes 10 Hz fixes as
/// independent): the bound is 5σ, not 3σ.
#[test]
fn the_gnss_latency_is_recovered_from_the_log() {
    for latency_s in [0.0, 0.1, 0.3] {
        let dir = tempfile::tempdir().unwrap();
        let arm = car_log(dir.path(), latency_s);
        let cfg = config(dir.path(), arm, "latency = \"estimate\"");
        let process = Process::load(cfg, dir.path()).unwrap();
        let result = process.run().unwrap();
        let e = result
            .install
            .iter()
            .find(|e| e.name == "gnss_latency")
            .expect("the latency estimate is reported");
        let error = e.value - latency_s;
        println!(
            "latency {latency_s} s: estimated {:.4} ± {:.4} s",
            e.value, e.sigma
        );
        assert!(error.abs() < 0.010, "{latency_s}: {} s", e.value);
        assert!(
            error.abs() < 5.0 * e.sigma,
            "{latency_s}: {error} vs σ {}",
            e.sigma
        );
        assert!(e.sigma < 0.1 * e.prior_sigma);
        assert_eq!(e.unit, "s");
        // The fixes were re-timed: the filter tracks them to centimetres
        // (0.2 s at 12 m/s would be 2.4 m).
        let tracking = result.tracking_rms_m.unwrap();
        assert!(tracking < 0.05, "{tracking}");
        // As good as knowing it: the 30 s outage score within 50 % of the
        // run told the true latency.
        let known = config(dir.path(), arm, &format!("latency = {latency_s}"));
        let known = Process::load(known, dir.path()).unwrap();
        let (a, b) = (process.score().unwrap(), known.score().unwrap());
        let drift = |s: &aidnav_app::process::Scores| {
            s.outages
                .iter()
                .find(|o| o.outage_s == 30.0)
                .and_then(|o| o.three_d_m)
                .unwrap()
        };
        let (estimated, told) = (drift(&a), drift(&b));
        println!("  30 s outages: estimated {estimated:.3} m, told {told:.3} m");
        assert!(estimated < 1.5 * told + 0.1, "{estimated} vs {told}");
        assert!(known.run().unwrap().install.is_empty());
    }
}

/// A latency that is neither a number nor `"estimate"` is refused at load,
/// naming the key.
#[test]
fn a_latency_key_is_seconds_or_estimate() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "[data]\ndir = \".\"\nimu = \"a\"\ngnss = \"b\"\n[gnss]\nlatency = \"guess\"\n",
    )
    .unwrap();
    let err = aidnav_io::load_toml::<ProcessConfig>(&path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("latency") && err.contains("estimate"), "{err}");
}

/// The estimates of one block, in state order.
fn estimates_of(install: &[AddedStateEstimate], kind: Augmented) -> Vec<&AddedStateEstimate> {
    install.iter().filter(|e| e.kind == kind).collect()
}

/// The lever arm estimated with the GNSS latency on the 10 Hz RTK car
/// (antenna 0.5 m behind and 1 m above the IMU, fixes 0.2 s late), the
/// filter's noise matched to the simulated IMU (the new user's datasheet
/// bias instability leaves the turn-on bias unmodelled, and the lever
/// arm then absorbs it: 7 cm across). Horizontal axes within 5 cm and
/// 5σ (measured: x +1.0 cm ± 1.9, y −3.3 cm ± 1.1: optimistic as the
/// latency's σ is); the vertical is seen only through the pitch on two
/// hills (measured +8 cm ± 9): within 3σ. The calibrated configuration then tracks to
/// centimetres and coasts as well as one told the truth.
#[test]
fn the_lever_arm_is_recovered_with_the_latency() {
    let dir = tempfile::tempdir().unwrap();
    let sim = car_simulation(dir.path(), 0.2);
    let truth = sim.scenario.gnss_lever_arm_imu_m();
    let user = config(dir.path(), [0.0; 3], "");
    let mut cfg = matched_config(&user, &sim);
    cfg.gnss.latency = aidnav_app::process::GnssLatency::Estimate;
    cfg.gnss.estimate_lever_arm = true;
    let process = Process::load(cfg.clone(), dir.path()).unwrap();
    let result = process.run().unwrap();
    let latency = estimates_of(&result.install, Augmented::GnssLatency);
    println!(
        "latency: {:.4} ± {:.4} s",
        latency[0].value, latency[0].sigma
    );
    assert!((latency[0].value - 0.2).abs() < 0.010, "{:?}", latency[0]);
    let arm = estimates_of(&result.install, Augmented::LeverArm);
    assert_eq!(arm.len(), 3);
    for (axis, e) in arm.iter().enumerate() {
        let error = e.value - truth[axis];
        println!(
            "{}: {:.3} ± {:.3} m (truth {})",
            e.name, e.value, e.sigma, truth[axis]
        );
        assert_eq!(e.unit, "m");
        if axis < 2 {
            assert!(error.abs() < 0.05, "{}: {error} m", e.name);
            assert!(
                error.abs() < 5.0 * e.sigma,
                "{}: {error} vs σ {}",
                e.name,
                e.sigma
            );
        } else {
            assert!(
                error.abs() < 3.0 * e.sigma,
                "{}: {error} vs σ {}",
                e.name,
                e.sigma
            );
            assert!(e.sigma < 0.5 * e.prior_sigma, "{}", e.sigma);
        }
    }
    let tracking = result.tracking_rms_m.unwrap();
    assert!(tracking < 0.05, "{tracking}");
    // Coasting against the run told the planted values.
    let mut told = matched_config(&config(dir.path(), truth, "latency = 0.2"), &sim);
    told.gnss.estimate_lever_arm = false;
    let told = Process::load(told, dir.path()).unwrap();
    let drift = |p: &Process| {
        p.score()
            .unwrap()
            .outages
            .iter()
            .find(|o| o.outage_s == 30.0)
            .and_then(|o| o.three_d_m)
            .unwrap()
    };
    let (estimated, known) = (drift(&process), drift(&told));
    println!("30 s outages: estimated {estimated:.3} m, told {known:.3} m");
    assert!(estimated < 1.5 * known + 0.1, "{estimated} vs {known}");
}

/// A prior σ out of its range is refused naming the key.
#[test]
fn a_lever_arm_sigma_out_of_range_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "[data]\ndir = \".\"\nimu = \"a\"\nimu_format = \"generic_csv\"\ngnss = \"b\"\ngnss_format = \"generic_csv\"\n[gnss]\nestimate_lever_arm = true\nlever_arm_sigma_m = 0\n",
    )
    .unwrap();
    let err = aidnav_io::load_toml::<ProcessConfig>(&path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("lever_arm_sigma_m"), "{err}");
}

/// The zoo's pitched-IMU car with the IMU's axes at `mounting_deg` against
/// the vehicle's, written to `dir`.
fn pitched_car(dir: &Path, mounting_deg: [f64; 3]) -> Simulation {
    let zoo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo");
    let path = zoo.join("short_car_pitch3_fixed.toml");
    let planted = format!(
        "mounting_deg = [{}, {}, {}]",
        mounting_deg[0], mounting_deg[1], mounting_deg[2]
    );
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("mounting_deg = [0.0, 3.0, 0.0]", &planted);
    assert!(text.contains(&planted));
    let sim = simulation_of_text(&text, &path, None).unwrap();
    simulate_to_dir(&sim, dir).unwrap();
    sim
}

/// The vehicle frame's pitch and yaw against the IMU estimated through the
/// non-holonomic constraint, on the RTK car with the IMU misaligned by up
/// to 5° (the lever arm told, the noise matched: the misalignment alone):
/// within ±0.2° and 3σ of the planted angles (measured: every angle within
/// 0.011°, σ 0.013° pitch, 0.023° yaw), the roll left as configured. The
/// calibrated run then coasts far better than one that takes the IMU for
/// the vehicle (10 s outages 0.13 m against 6.2–28 m: in the outages the
/// constraint forces a vertical or lateral velocity of v·sin of the
/// angle), and that run is warned of the misaligned vehicle frame.
#[test]
fn the_vehicle_misalignment_is_recovered() {
    for planted in [
        [0.0, 3.0, 0.0],
        [0.0, -2.0, 4.0],
        [1.5, 4.5, -5.0],
        [0.0; 3],
    ] {
        let dir = tempfile::tempdir().unwrap();
        let sim = pitched_car(dir.path(), planted);
        let arm = sim.scenario.gnss_lever_arm_imu_m();
        let user = matched_config(&config(dir.path(), arm, ""), &sim);
        let mut cfg = user.clone();
        cfg.constraints.estimate_misalignment = true;
        cfg.constraints.misalignment_deg[0] = planted[0];
        let process = Process::load(cfg, dir.path()).unwrap();
        let result = process.run().unwrap();
        let angles = estimates_of(&result.install, Augmented::VehicleMisalignment);
        assert_eq!(angles.len(), 2);
        for (e, truth) in angles.iter().zip(&planted[1..]) {
            let (value, sigma) = (e.value.to_degrees(), e.sigma.to_degrees());
            println!("{planted:?}: {} {value:.3} ± {sigma:.3}°", e.name);
            assert_eq!(e.unit, "rad");
            let error = value - truth;
            assert!(error.abs() < 0.2, "{planted:?} {}: {value}°", e.name);
            assert!(
                error.abs() < 3.0 * sigma,
                "{planted:?} {}: {error} vs σ {sigma}",
                e.name
            );
        }
        // Calibrated, the constraint's residuals are not systematic.
        let frame_warning = |r: &aidnav_app::process::ProcessResult| {
            r.warnings
                .iter()
                .find(|w| w.kind == aidnav_app::process::WarningKind::VehicleFrame)
                .map(|w| w.message.clone())
        };
        assert_eq!(frame_warning(&result), None, "{planted:?}");
        // The calibrated configuration holds the estimate.
        let c = process.config();
        assert!(!c.constraints.estimate_misalignment);
        assert!((c.constraints.misalignment_deg[1] - planted[1]).abs() < 0.2);
        let blind = Process::load(user, dir.path()).unwrap();
        // Taken for the vehicle, the IMU's misalignment is named.
        let warning = frame_warning(&blind.run().unwrap());
        println!("  blind: {warning:?}");
        if planted == [0.0; 3] {
            assert_eq!(warning, None);
        } else {
            let warning = warning.expect("a misaligned vehicle frame is warned of");
            assert!(warning.contains("estimate_misalignment"), "{warning}");
            // At least the larger angle's axis (the other may follow: a
            // misaligned constraint upsets the whole solution).
            let larger = if planted[1].abs() > planted[2].abs() {
                "pitch"
            } else {
                "yaw"
            };
            assert!(warning.contains(&format!("the {larger}")), "{warning}");
            let drift = |p: &Process| {
                p.score()
                    .unwrap()
                    .outages
                    .iter()
                    .find(|o| o.outage_s == 10.0)
                    .and_then(|o| o.three_d_m)
                    .unwrap()
            };
            let (estimated, ignored) = (drift(&process), drift(&blind));
            println!("  10 s outages: estimated {estimated:.2} m, ignored {ignored:.2} m");
            assert!(estimated < 0.5 * ignored, "{estimated} vs {ignored}");
        }
    }
}

/// Estimating the misalignment without a vehicle constraint is refused:
/// nothing would observe it.
#[test]
fn a_misalignment_without_a_vehicle_constraint_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(
        &path,
        "platform = \"aircraft\"\n[data]\ndir = \".\"\nimu = \"a\"\nimu_format = \"generic_csv\"\ngnss = \"b\"\ngnss_format = \"generic_csv\"\n[constraints]\nestimate_misalignment = true\n",
    )
    .unwrap();
    let err = aidnav_io::load_toml::<ProcessConfig>(&path)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("estimate_misalignment") && err.contains("non_holonomic"),
        "{err}"
    );
}
