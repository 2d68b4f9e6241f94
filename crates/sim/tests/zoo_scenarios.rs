//! Every scenario of the repository's zoo (`zoo/*.toml`) resolves and
//! simulates: a log with IMU samples, GNSS fixes and its truth.

use aidnav_sim::scenario::{ScenarioFile, simulate};

#[test]
fn every_zoo_scenario_simulates() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../zoo");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let file: ScenarioFile =
            toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let scenario = file
            .resolve()
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!(
            Some(scenario.name.as_str()),
            path.file_stem().and_then(|s| s.to_str()),
            "{}: the name is the file's stem",
            path.display()
        );
        let log = simulate(&scenario, scenario.seed, 0).unwrap();
        let duration = log.truth.last().unwrap().time_s - log.truth[0].time_s;
        assert!(duration >= 150.0, "{}: {duration} s", path.display());
        assert!(log.gnss.len() as f64 >= 0.5 * duration * scenario.gnss.rate_hz);
        names.push(scenario.name);
    }
    assert!(names.len() >= 24, "{} scenarios", names.len());
}
