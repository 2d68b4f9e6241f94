//! The fuzz targets' bodies: every reader and every configuration loader of
//! aidnav fed arbitrary bytes. Each must return — an error is a fine answer
//! — and never panic, loop or exhaust memory. The cargo-fuzz targets in
//! `fuzz/` call these, and the default test suite replays every corpus and
//! crash file through them on stable (`crates/aidnav/tests/fuzz_corpus.rs`).
//!
//! ```
//! // A truncated RTKLIB line: an error, not a panic.
//! aidnav_app::fuzzing::run("rtklib_pos", b"2025/07/08 19:34:01.000 ").unwrap();
//! ```

use std::path::Path;

use aidnav_io::config::parse_toml;
use aidnav_io::{generic_aiding, generic_gnss, kfgins, measurements, nmea, rtklib, ubx};

/// A fuzz target: its name (the cargo-fuzz binary and corpus folder) and
/// its body.
pub type Target = (&'static str, fn(&[u8]));

/// Every target, by name.
pub const TARGETS: [Target; 14] = [
    ("rtklib_pos", rtklib_pos),
    ("rtklib_tagged_imu", rtklib_tagged_imu),
    ("kfgins_imu", kfgins_imu),
    ("kfgins_gnss", kfgins_gnss),
    ("generic_imu", generic_imu),
    ("nmea", nmea_sentences),
    ("ubx", ubx_log),
    ("generic_gnss", generic_gnss_csv),
    ("generic_wheel_speed", generic_wheel_speed),
    ("generic_baro", generic_baro),
    ("filter_measurements", filter_measurements),
    ("filter_model", filter_model),
    ("process_config", process_config),
    ("scenarios", scenarios),
];

/// Run the target `name` on `data`; an error only for an unknown name.
pub fn run(name: &str, data: &[u8]) -> Result<(), String> {
    let (_, body) = TARGETS
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| format!("no fuzz target named {name:?}"))?;
    body(data);
    Ok(())
}

/// RTKLIB `.pos` text.
pub fn rtklib_pos(data: &[u8]) {
    let _ = rtklib::read_pos_from(data, Path::new("fuzz.pos"));
}

/// The two inputs of one target cut from one byte string: the first four
/// bytes (little-endian) give the first input's length, capped at what
/// follows, so the fuzzer moves the cut.
pub fn split(data: &[u8]) -> (&[u8], &[u8]) {
    match data.split_first_chunk::<4>() {
        Some((len, rest)) => rest.split_at((u32::from_le_bytes(*len) as usize).min(rest.len())),
        None => (&[], &[]),
    }
}

/// Raw IMU CSV and its binary RTKLIB `.tag` file.
pub fn rtklib_tagged_imu(data: &[u8]) {
    let (csv, tag) = split(data);
    let _ =
        rtklib::read_tagged_imu_from(csv, Path::new("fuzz.csv"), tag, Path::new("fuzz.csv.tag"));
}

/// KF-GINS IMU increments text.
pub fn kfgins_imu(data: &[u8]) {
    let _ = kfgins::read_kfgins_imu_from(data, Path::new("fuzz-imu.txt"));
}

/// KF-GINS GNSS text.
pub fn kfgins_gnss(data: &[u8]) {
    let _ = kfgins::read_kfgins_gnss_from(data, Path::new("fuzz-gnss.txt"));
}

/// The generic IMU CSV.
pub fn generic_imu(data: &[u8]) {
    let _ = kfgins::read_generic_imu_from(data, Path::new("fuzz-imu.csv"));
}

/// NMEA 0183 sentences.
pub fn nmea_sentences(data: &[u8]) {
    let _ = nmea::read_nmea_from(data, Path::new("fuzz.nmea"));
}

/// A u-blox UBX binary log (NAV-PVT epochs among other frames and NMEA).
pub fn ubx_log(data: &[u8]) {
    let _ = ubx::read_ubx_from(data, Path::new("fuzz.ubx"));
}

/// The generic GNSS CSV, without and with a σ from the configuration (the
/// two paths a file without σ columns takes).
pub fn generic_gnss_csv(data: &[u8]) {
    use generic_gnss::{GenericGnssOptions, read_generic_gnss_from};
    let origin = Path::new("fuzz-gnss.csv");
    let _ = read_generic_gnss_from(data, origin, GenericGnssOptions::default());
    let _ = read_generic_gnss_from(
        data,
        origin,
        GenericGnssOptions {
            default_sigma_m: Some([0.5, 1.0]),
        },
    );
}

/// The generic wheel-speed CSV.
pub fn generic_wheel_speed(data: &[u8]) {
    let _ = generic_aiding::read_wheel_speed_from(data, Path::new("fuzz-wheel.csv"));
}

/// The generic barometer CSV (heights or pressures).
pub fn generic_baro(data: &[u8]) {
    let _ = generic_aiding::read_baro_from(data, Path::new("fuzz-baro.csv"));
}

/// `aidnav filter`'s measurement CSV (columns `z1`, `z2`).
pub fn filter_measurements(data: &[u8]) {
    let names = ["z1".to_string(), "z2".to_string()];
    let _ = measurements::read_measurements_from(
        data,
        Path::new("fuzz.csv"),
        &names,
        measurements::DEFAULT_MAX_EPOCHS,
    );
}

/// `aidnav filter`'s model file (TOML).
pub fn filter_model(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = parse_toml::<aidnav_io::model_file::ModelFile>(text, Path::new("fuzz.toml"));
    }
}

/// `aidnav process`'s configuration (TOML).
pub fn process_config(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = parse_toml::<crate::process::ProcessConfig>(text, Path::new("fuzz.toml"));
    }
}

/// Every reproduction's scenario file and `aidnav run`'s formation file
/// (TOML), through the loader the CLI uses.
pub fn scenarios(data: &[u8]) {
    use aidnav_reproduce::*;
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let origin = Path::new("fuzz.toml");
    let _ = parse_toml::<anomalies::AnomaliesScenario>(text, origin);
    let _ = parse_toml::<consistency::ConsistencyScenario>(text, origin);
    let _ = parse_toml::<extended_state::ExtendedStateScenario>(text, origin);
    let _ = parse_toml::<group::GroupScenario>(text, origin);
    let _ = parse_toml::<outages::OutagesScenario>(text, origin);
    let _ = parse_toml::<formation::FormationScenario>(text, origin);
    let _ = parse_toml::<formation::FormationFile>(text, origin);
}
