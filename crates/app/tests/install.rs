//! Installation parameters estimated from the log, on simulated logs
//! with the values planted: `gnss.latency = "estimate"` recovers the GNSS
//! time tag's latency.

use std::path::Path;

use aidnav_app::jobs::simulate::{simulate_to_dir, simulation_of_text};
use aidnav_app::process::{Process, ProcessConfig};

/// The zoo's 10 Hz RTK car with the latency set to `latency_s`, written
/// to `dir`; its planted lever arm (IMU axes).
fn car_log(dir: &Path, latency_s: f64) -> [f64; 3] {
    let zoo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo");
    let path = zoo.join("short_car_latency_fixed_10hz.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("latency_s = 0.2", &format!("latency_s = {latency_s}"));
    assert!(text.contains(&format!("latency_s = {latency_s}")));
    let sim = simulation_of_text(&text, &path, None).unwrap();
    simulate_to_dir(&sim, dir).unwrap();
    sim.scenario.gnss_lever_arm_imu_m()
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
