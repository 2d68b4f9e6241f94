//! `aidnav process` with a wheel-speed and a barometer table, end to end
//! on a simulated car written as generic CSVs: the per-update files and
//! `summary.json`'s counts are written, the smoother runs on the grown
//! state, and a later run without the tables leaves no stale file behind.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use aidnav::sim::car::{CarLog, CarScenario, simulate_car};

/// The log as aidnav's generic CSVs in `dir`.
fn write_log(log: &CarLog, dir: &Path) {
    let mut imu = String::from("time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n");
    for s in &log.imu {
        let (w, f) = (s.angular_rate, s.specific_force);
        writeln!(
            imu,
            "{},{},{},{},{},{},{}",
            s.time_s, w.x, w.y, w.z, f.x, f.y, f.z
        )
        .unwrap();
    }
    std::fs::write(dir.join("imu.csv"), imu).unwrap();
    let mut gnss = String::from(
        "gpst_s,lat_deg,lon_deg,height_m,sigma_n_m,sigma_e_m,sigma_u_m,\
         vel_n_mps,vel_e_mps,vel_d_mps,sigma_vel_mps,quality\n",
    );
    for g in &log.gnss {
        let (p, s) = (g.position, g.position_sigma_neu);
        let v = g.velocity_ned.unwrap();
        let sv = g.velocity_sigma_neu.unwrap();
        writeln!(
            gnss,
            "{},{},{},{},{},{},{},{},{},{},{},single",
            g.time_s,
            p.latitude_rad.to_degrees(),
            p.longitude_rad.to_degrees(),
            p.height_m,
            s.x,
            s.y,
            s.z,
            v.x,
            v.y,
            v.z,
            sv.x
        )
        .unwrap();
    }
    std::fs::write(dir.join("gnss.csv"), gnss).unwrap();
    let mut wheel = String::from("time_s,speed_kmh\n");
    for w in &log.wheel_speed {
        writeln!(wheel, "{},{}", w.time_s, w.speed_mps * 3.6).unwrap();
    }
    std::fs::write(dir.join("wheel.csv"), wheel).unwrap();
    let mut baro = String::from("time_s,height_m,sigma_m\n");
    for b in &log.baro {
        writeln!(baro, "{},{},0.3", b.time_s, b.height_m).unwrap();
    }
    std::fs::write(dir.join("baro.csv"), baro).unwrap();
}

fn process(config: &Path, out: &Path) -> String {
    let run = Command::new(env!("CARGO_BIN_EXE_aidnav"))
        .args(["process", "--no-score", "--out"])
        .arg(out)
        .arg(config)
        .env("CI", "true")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "{stderr}");
    stderr
}

#[test]
fn process_fuses_the_tables_and_writes_their_updates() {
    let log = simulate_car(&CarScenario::default(), 35).unwrap();
    let dir = tempfile::tempdir().unwrap();
    write_log(&log, dir.path());
    let base = "platform = \"car\"\n\
                [data]\ndir = \".\"\nimu = \"imu.csv\"\nimu_format = \"generic_csv\"\n\
                gnss = \"gnss.csv\"\ngnss_format = \"generic_csv\"\n\
                [gnss]\nlever_arm_m = [-0.5, 0.0, -1.0]\n\
                [output]\nsmooth = true\n";
    let tables = "[wheel_speed]\nfile = \"wheel.csv\"\nlever_arm_m = [-1.3, 0.0, 0.3]\n\
                  [barometer]\nfile = \"baro.csv\"\n";
    let config = dir.path().join("aided.toml");
    std::fs::write(&config, format!("{base}{tables}")).unwrap();
    let out = dir.path().join("out");
    process(&config, &out);

    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let sources = summary["result"]["aid_sources"].as_array().unwrap();
    let fused = |name: &str| {
        sources
            .iter()
            .find(|s| s["name"] == name)
            .map(|s| s["fused"].as_u64().unwrap())
            .unwrap_or_else(|| panic!("no {name} in {sources:?}"))
    };
    // 450 s at most one update per 0.1 s (the default min_interval_s).
    for name in ["wheel_speed", "barometer"] {
        assert!(
            (4_000..=4_600).contains(&fused(name)),
            "{name}: {sources:?}"
        );
    }
    assert!(fused("gnss_position") > 400, "{sources:?}");
    for (file, unit) in [("wheel_speed.csv", "m/s"), ("barometer.csv", "m")] {
        let text = std::fs::read_to_string(out.join(file)).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        assert!(header.contains(&format!("innovation [{unit}]")), "{header}");
        let rows: Vec<Vec<f64>> = lines
            .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
            .collect();
        assert!(rows.len() > 4_000, "{file}: {} rows", rows.len());
        // Each innovation within a few of its own σ on average: the
        // filter's σ is honest for these streams too.
        let mean_nis = rows.iter().map(|r| r[3]).sum::<f64>() / rows.len() as f64;
        assert!(
            mean_nis > 0.1 && mean_nis < 5.0,
            "{file}: mean NIS {mean_nis}"
        );
    }
    // The smoother ran on the 23-state filter.
    assert!(out.join("smoothed.csv").exists());

    // Without the tables, the same output directory keeps no stale file.
    let plain = dir.path().join("plain.toml");
    std::fs::write(&plain, base).unwrap();
    process(&plain, &out);
    assert!(!out.join("wheel_speed.csv").exists());
    assert!(!out.join("barometer.csv").exists());
}
