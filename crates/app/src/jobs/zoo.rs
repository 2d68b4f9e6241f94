//! The zoo: simulated logs of many platforms, IMU grades, GNSS qualities and
//! planted installation errors, each processed with the configuration a new
//! user would write and scored against its truth — and once more with the
//! matched (true) noise model, to tell what the noise model costs from what
//! the rest costs.
//!
//! Each scenario is simulated into `out/<name>/` by
//! [`super::simulate::simulate_to_dir`], read back through the files with
//! its `aidnav.toml` exactly as `aidnav process` reads them, and scored by
//! [`crate::process::reference::score_against_reference`].

use std::path::{Path, PathBuf};

use aidnav_frames::{Body, Ned, Rotation};
use aidnav_io::reference::read_reference;
use aidnav_models::ned_ins::PerAxis;
use rayon::prelude::*;
use serde::Serialize;

use super::simulate::{Simulation, load_simulation, planted_installation, simulate_to_dir};
use super::{JobError, JobResult};
use crate::process::reference::{
    ReferenceScores, ReferenceState, ReferenceTrajectory, score_against_reference,
};
use crate::process::{Inputs, ProcessConfig, QualitySigmaScale};

/// One scenario of the zoo, scored.
#[derive(Debug, Clone, Serialize)]
pub struct ZooEntry {
    /// Scenario name.
    pub name: String,
    /// The scenario file.
    pub file: PathBuf,
    /// Its seed.
    pub seed: u64,
    /// The platform preset of its configuration.
    pub platform: String,
    /// The planted installation parameters.
    pub installation: serde_json::Value,
    /// With the new user's configuration (datasheet noise, no
    /// installation); none when aidnav refused or failed the log.
    pub new_user: Option<ReferenceScores>,
    /// With the matched noise model (the simulator's own error sizes).
    pub matched: Option<ReferenceScores>,
    /// Why aidnav could not process the log (the first error), if so: a
    /// finding of the zoo, not a failure of the run.
    pub error: Option<String>,
}

/// What [`zoo`] ran and wrote.
#[derive(Debug, Clone, Serialize)]
pub struct ZooRun {
    /// One entry per scenario, in the order given.
    pub entries: Vec<ZooEntry>,
    /// `zoo.csv` and `summary.json`.
    pub files: Vec<PathBuf>,
}

/// Simulate, process and score every scenario file of `files` into `out`
/// (one folder per scenario; the scenarios run in parallel), then write
/// `out/zoo.csv` (one row per log) and `out/summary.json`. The first
/// failure is returned as an error naming its file, and nothing is
/// written at the top of `out`.
pub fn zoo(files: &[PathBuf], out: &Path) -> JobResult<ZooRun> {
    if files.is_empty() {
        return Err(JobError::Refused(
            "zoo: no scenario file given: nothing to run".into(),
        ));
    }
    let mut seen = std::collections::HashSet::new();
    for f in files {
        if !seen.insert(f.file_stem()) {
            return Err(JobError::Refused(format!(
                "zoo: {} is given twice (each scenario gets its own folder)",
                f.display()
            )));
        }
    }
    let entries: Vec<ZooEntry> = files
        .par_iter()
        .map(|f| zoo_entry(f, out))
        .collect::<JobResult<_>>()?;
    let csv = out.join("zoo.csv");
    aidnav_io::writers::write_atomic(&csv, zoo_csv(&entries).as_bytes())?;
    let mut summary = aidnav_io::writers::Summary::new(
        "zoo",
        crate::VERSION,
        None,
        &files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>(),
    );
    summary.insert("result", &entries);
    let json = summary.write(out)?;
    Ok(ZooRun {
        entries,
        files: vec![csv, json],
    })
}

/// The score columns of one run (snake_case with units).
pub const SCORE_COLUMNS: [&str; 9] = [
    "tracking_3d_m",
    "drift_10s_m",
    "drift_30s_m",
    "drift_60s_m",
    "roll_error_deg",
    "pitch_error_deg",
    "yaw_error_deg",
    "inside_99_fraction",
    "mean_nees",
];

/// The values of [`SCORE_COLUMNS`] for one run (all none without one).
pub fn score_cells(s: Option<&ReferenceScores>) -> [Option<f64>; 9] {
    let Some(s) = s else {
        return [None; 9];
    };
    let drift = |l: f64| {
        s.outages
            .iter()
            .find(|o| o.outage_s == l)
            .and_then(|o| o.three_d_m)
    };
    let (inside, nees) = pooled_consistency(s);
    let att = s.attitude_deg;
    [
        s.tracking_three_d_m,
        drift(10.0),
        drift(30.0),
        drift(60.0),
        att.map(|a| a[0]),
        att.map(|a| a[1]),
        att.map(|a| a[2]),
        inside,
        nees,
    ]
}

/// The zoo as CSV: per log the scores of both runs, the planted
/// installation and aidnav's error when it could not process the log.
pub fn zoo_csv(entries: &[ZooEntry]) -> String {
    use std::fmt::Write as _;
    let num = |x: Option<f64>| x.map_or_else(String::new, |v| format!("{v}"));
    let cols = SCORE_COLUMNS.join(",");
    let matched: String = SCORE_COLUMNS
        .iter()
        .map(|c| format!(",matched_{c}"))
        .collect();
    let mut t = format!(
        "log,platform,seed,{cols}{matched},mounting_roll_deg,mounting_pitch_deg,mounting_yaw_deg,\
         lever_arm_x_m,lever_arm_y_m,lever_arm_z_m,gnss_latency_s,error\n"
    );
    for e in entries {
        let i = &e.installation;
        let mut cells: Vec<String> = vec![e.name.clone(), e.platform.clone(), e.seed.to_string()];
        cells.extend(score_cells(e.new_user.as_ref()).map(num));
        cells.extend(score_cells(e.matched.as_ref()).map(num));
        for key in ["mounting_deg", "gnss_lever_arm_imu_m"] {
            cells.extend((0..3).map(|k| num(i[key][k].as_f64())));
        }
        cells.push(num(i["gnss_latency_s"].as_f64()));
        cells.push(
            e.error
                .as_ref()
                .map_or_else(String::new, |m| format!("\"{}\"", m.replace('"', "\"\""))),
        );
        let _ = writeln!(t, "{}", cells.join(","));
    }
    t
}

/// One scenario: simulate, read back, score twice.
fn zoo_entry(file: &Path, out: &Path) -> JobResult<ZooEntry> {
    let context = |e: JobError| JobError::Refused(format!("{}: {e}", file.display()));
    let sim = load_simulation(file, None).map_err(context)?;
    score_simulation(&sim, file, &out.join(&sim.scenario.name))
}

/// Simulate `sim` into `dir`, read it back through its new-user
/// configuration exactly as `aidnav process` does, and score it with
/// that configuration and with the matched noise model. `file` names the
/// scenario in the entry and in errors.
pub fn score_simulation(sim: &Simulation, file: &Path, dir: &Path) -> JobResult<ZooEntry> {
    let context = |e: JobError| JobError::Refused(format!("{}: {e}", file.display()));
    simulate_to_dir(sim, dir).map_err(context)?;
    let config_path = dir.join("aidnav.toml");
    let (cfg, _) =
        aidnav_io::load_toml::<ProcessConfig>(&config_path).map_err(|e| context(e.into()))?;
    let reference = load_reference(&dir.join("truth.csv")).map_err(context)?;
    let mut entry = ZooEntry {
        name: sim.scenario.name.clone(),
        file: file.to_path_buf(),
        seed: sim.scenario.seed,
        platform: crate::process::config_name(&cfg.platform),
        installation: planted_installation(&sim.scenario),
        new_user: None,
        matched: None,
        error: None,
    };
    let inputs = match Inputs::load(&cfg, dir) {
        Ok(i) => i,
        Err(e) => {
            entry.error = Some(e.to_string());
            return Ok(entry);
        }
    };
    let score = |cfg: &ProcessConfig| score_against_reference(cfg, &inputs, &reference);
    match score(&cfg) {
        Ok(s) => entry.new_user = Some(s),
        Err(e) => entry.error = Some(e.to_string()),
    }
    match score(&matched_config(&cfg, sim)) {
        Ok(s) => entry.matched = Some(s),
        Err(e) => {
            entry.error.get_or_insert(e.to_string());
        }
    }
    Ok(entry)
}

/// Read a reference CSV ([`aidnav_io::reference`]) as a trajectory.
pub fn load_reference(path: &Path) -> JobResult<ReferenceTrajectory> {
    let (samples, _) = read_reference(path)?;
    let states = samples
        .into_iter()
        .map(|s| ReferenceState {
            time_s: s.time_s,
            position: aidnav_frames::earth::Geodetic {
                latitude_rad: s.latitude_rad,
                longitude_rad: s.longitude_rad,
                height_m: s.height_m,
            },
            velocity_ned: s.velocity_ned_m_s.map(nalgebra::Vector3::from),
            attitude: s
                .attitude_rpy_rad
                .map(|[r, p, y]| Rotation::<Body, Ned>::from_euler_angles(r, p, y)),
        })
        .collect();
    ReferenceTrajectory::new(states)
        .map_err(|e| JobError::Refused(format!("{}: {e}", path.display())))
}

/// The new user's configuration with the simulator's own error sizes: the
/// white noise and scale-factor σ of the datasheet, the bias σ of the
/// turn-on and in-run parts together (the filter's one Gauss–Markov bias
/// holds both), the GNSS σ as simulated (no quality factors, the reported
/// σ's scale undone).
pub fn matched_config(cfg: &ProcessConfig, sim: &Simulation) -> ProcessConfig {
    let s = &sim.scenario;
    let (g, a) = (&s.imu.gyro, &s.imu.accel);
    let rss = |x: [f64; 3], y: [f64; 3]| PerAxis(std::array::from_fn(|i| x[i].hypot(y[i])));
    let mut m = cfg.clone();
    let n = &mut m.imu.noise.values;
    n.arw_deg_per_sqrt_h = PerAxis(g.angle_random_walk_deg_sqrt_h);
    n.vrw_mps_per_sqrt_h = PerAxis(a.velocity_random_walk_m_s_sqrt_h);
    n.gyro_bias_deg_per_h = rss(g.turn_on_bias_sigma_deg_h, g.bias_instability_deg_h);
    n.accel_bias_mg = rss(a.turn_on_bias_sigma_mg, a.bias_instability_mg);
    n.gyro_scale_ppm = PerAxis(g.scale_factor_sigma_ppm);
    n.accel_scale_ppm = PerAxis(a.scale_factor_sigma_ppm);
    m.gnss.quality_sigma_scale = QualitySigmaScale {
        float: 1.0,
        dgps: 1.0,
        single: 1.0,
    };
    m.gnss.sigma_scale = 1.0 / s.gnss.reported_sigma_scale;
    if m.data.gnss_sigma_m.is_some() {
        let [n, e, u] = s.gnss.model_sigma_neu_m();
        m.data.gnss_sigma_m = Some([n.hypot(e) / 2f64.sqrt(), u]);
    }
    m
}

/// `x` with 2 decimals, or `—` for none.
fn cell(x: Option<f64>) -> String {
    x.map_or_else(|| "—".into(), |v| format!("{v:.2}"))
}

/// The zoo's table: one row per log — the new user's configuration
/// (tracking, the 10 / 30 / 60 s outage drifts as the RMS over windows of
/// the largest 3-D error, the RMS roll / pitch / yaw error, the fraction
/// inside the 99 % ellipsoid, the mean NEES), then the matched noise
/// model's tracking and drifts; a log aidnav refused gets its error.
pub fn zoo_table(entries: &[ZooEntry]) -> String {
    use std::fmt::Write as _;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{:<34} {:<10} {:>7} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>5} {:>6} | {:>7} {:>7} {:>7} {:>7}",
        "log",
        "platform",
        "track_m",
        "10s_m",
        "30s_m",
        "60s_m",
        "roll°",
        "pitch°",
        "yaw°",
        "in99",
        "nees",
        "track_m",
        "10s_m",
        "30s_m",
        "60s_m"
    );
    let _ = writeln!(
        t,
        "{:<45} {:-^78} | {:-^31}",
        "", " new user's configuration ", " matched noise "
    );
    for e in entries {
        let n = score_cells(e.new_user.as_ref()).map(cell);
        let m = score_cells(e.matched.as_ref()).map(cell);
        let _ = write!(t, "{:<34} {:<10} ", e.name, e.platform);
        if e.new_user.is_none() {
            let why = e.error.as_deref().unwrap_or("no score");
            let _ = writeln!(t, "refused: {why}");
            continue;
        }
        let _ = writeln!(
            t,
            "{:>7} {:>7} {:>7} {:>7} {:>6} {:>6} {:>6} {:>5} {:>6} | {:>7} {:>7} {:>7} {:>7}",
            n[0], n[1], n[2], n[3], n[4], n[5], n[6], n[7], n[8], m[0], m[1], m[2], m[3]
        );
    }
    t
}

/// Fraction inside the 99 % ellipsoid and mean NEES over every outage
/// epoch of every length.
pub fn pooled_consistency(s: &ReferenceScores) -> (Option<f64>, Option<f64>) {
    let n: usize = s.outages.iter().map(|o| o.epochs).sum();
    if n == 0 {
        return (None, None);
    }
    let inside: f64 = s
        .outages
        .iter()
        .filter_map(|o| o.inside_99_fraction.map(|f| f * o.epochs as f64))
        .sum();
    let nees: f64 = s
        .outages
        .iter()
        .filter_map(|o| o.mean_nees.map(|m| m * o.epochs as f64))
        .sum();
    (Some(inside / n as f64), Some(nees / n as f64))
}
