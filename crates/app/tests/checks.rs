//! The plausibility checks on simulated logs of every platform: a correct
//! log is never refused, and a gyro unit mistake is caught.
//!
//! Each log of the zoo's fast subset (`AIDNAV_ZOO=all`: every scenario of
//! `zoo/`) is simulated and its IMU written as a generic CSV with unit-free
//! columns, then loaded through the new user's configuration three ways:
//! declared right (must load), the numbers in deg/s declared rad/s (every
//! rate 57.3× too large: must be refused) and the numbers in rad/s
//! declared deg/s (57.3× too small: nothing at rest shows it; refused
//! where the log turns enough to tell, counted otherwise).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use aidnav_app::jobs::simulate::{load_simulation, simulate_to_dir};
use aidnav_app::process::{CheckLevel, ImuFormat, Inputs, ProcessConfig};

fn zoo_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo")
}

fn scenarios() -> Vec<PathBuf> {
    if std::env::var("AIDNAV_ZOO").as_deref() == Ok("all") {
        let mut all: Vec<PathBuf> = std::fs::read_dir(zoo_dir())
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        all.sort();
        return all;
    }
    std::fs::read_to_string(zoo_dir().join("fast.txt"))
        .unwrap()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| zoo_dir().join(l))
        .collect()
}

/// The new user's configuration of a simulated log in `dir`, reading the
/// IMU from `imu_generic.csv` with the gyro declared in `gyro`.
fn config(dir: &Path, gyro: &str) -> ProcessConfig {
    let (mut cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&dir.join("aidnav.toml")).unwrap();
    cfg.data.imu = "imu_generic.csv".into();
    cfg.data.imu_format = ImuFormat::GenericCsv;
    cfg.data.imu_tags = None;
    cfg.data.imu_units =
        Some(toml::from_str(&format!("gyro = \"{gyro}\"\naccel = \"m_s2\"\n")).unwrap());
    cfg
}

#[test]
fn no_correct_log_is_refused_and_a_degree_radian_mix_up_is() {
    let mut caught_small = 0;
    let files = scenarios();
    for file in &files {
        let dir = tempfile::tempdir().unwrap();
        simulate_to_dir(&load_simulation(file, None).unwrap(), dir.path()).unwrap();
        let (cfg, _) =
            aidnav_io::load_toml::<ProcessConfig>(&dir.path().join("aidnav.toml")).unwrap();
        let raw = Inputs::load_raw(&cfg, dir.path()).unwrap();
        // As the user's configuration reads it: a correct log loads.
        let loaded = Inputs::load_unsmoothed(&cfg, dir.path());
        let name = file.file_stem().unwrap().to_string_lossy().into_owned();
        assert!(loaded.is_ok(), "{name}: {}", loaded.unwrap_err());
        let fit = aidnav_app::process::turn_rate_fit(&raw.imu, &raw.gnss);
        let write = |gyro_scale: f64| {
            let mut csv = String::from("time_s,gx,gy,gz,ax,ay,az\n");
            for s in &raw.imu {
                let (w, f) = (s.angular_rate * gyro_scale, s.specific_force);
                writeln!(
                    csv,
                    "{:.6},{:e},{:e},{:e},{:e},{:e},{:e}",
                    s.time_s, w.x, w.y, w.z, f.x, f.y, f.z
                )
                .unwrap();
            }
            std::fs::write(dir.path().join("imu_generic.csv"), csv).unwrap();
        };
        write(1.0);
        let right = Inputs::load_unsmoothed(&config(dir.path(), "rad_s"), dir.path());
        assert!(right.is_ok(), "{name}: {}", right.unwrap_err());
        write(1f64.to_degrees());
        let large = Inputs::load_unsmoothed(&config(dir.path(), "rad_s"), dir.path());
        let mut scaled = raw.imu.clone();
        scaled
            .iter_mut()
            .for_each(|s| s.angular_rate *= 1f64.to_degrees());
        let large_fit = aidnav_app::process::turn_rate_fit(&scaled, &raw.gnss);
        let large = match large {
            Ok(_) => panic!("{name}: deg/s read as rad/s loads; fit {large_fit:?}"),
            Err(e) => e.to_string(),
        };
        assert!(
            large.contains("degrees per second read as radians") || large.contains("degrees given"),
            "{name}: {large}"
        );
        write(1.0);
        let small = Inputs::load_unsmoothed(&config(dir.path(), "deg_s"), dir.path())
            .map(|_| ())
            .map_err(|e| e.to_string());
        if let Err(e) = &small {
            assert!(
                e.contains("radians per second read as degrees"),
                "{name}: {e}"
            );
            caught_small += 1;
        }
        // Turned into a warning, the mistake loads and says so.
        let mut warn = config(dir.path(), "deg_s");
        warn.checks.turn_rate = CheckLevel::Warn;
        let warned = Inputs::load_unsmoothed(&warn, dir.path()).unwrap();
        assert_eq!(
            warned
                .warnings
                .iter()
                .any(|w| w.contains("radians per second read as degrees")),
            small.is_err(),
            "{name}"
        );
        eprintln!(
            "{name}: fit {fit:?}; rad/s declared deg/s {}",
            if small.is_err() {
                "refused"
            } else {
                "not judged"
            }
        );
    }
    eprintln!(
        "{caught_small} of {} logs refuse rad/s declared deg/s",
        files.len()
    );
}
