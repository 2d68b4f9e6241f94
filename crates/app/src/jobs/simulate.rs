//! `aidnav simulate SCENARIO.toml --out DIR`: a realistic log with known
//! truth, written in every format aidnav's readers take, with the truth
//! and the configuration a new user would write.
//!
//! The scenario file is [`aidnav_sim::scenario::ScenarioFile`] (platform,
//! route, IMU grade, GNSS mode, wheel speed, barometer, installation, seed)
//! plus an `[output]` table ([`SimulationOutput`]): which formats to write
//! and which of them the configuration reads. Files written into DIR
//! (files of these names left by an earlier run are removed first, and
//! `summary.json` is written last, so DIR never mixes two runs):
//!
//! | file | what |
//! |---|---|
//! | `imu.csv` | generic IMU CSV (`time_s, gx_rad_s … az_m_s2`), sensor axes |
//! | `imu_raw.csv`, `imu_raw.csv.tag` | raw CSV (g, deg/s) with its RTKLIB `.tag` |
//! | `imu.txt` | KF-GINS IMU text (increments, GPS seconds of week) |
//! | `gnss.csv` | generic GNSS CSV |
//! | `gnss.pos` | RTKLIB `.pos` |
//! | `gnss.txt` | KF-GINS GNSS text |
//! | `gnss.nmea` | NMEA 0183 GGA + RMC + GST |
//! | `gnss.ubx` | u-blox UBX NAV-PVT |
//! | `wheel_speed.csv`, `barometer.csv` | the aiding streams, when simulated |
//! | `truth.csv` | the reference trajectory at the IMU ([`aidnav_io::reference`]) |
//! | `aidnav.toml` | the `aidnav process` configuration a new user would write |
//! | `scenario.toml` | the scenario with every default filled in |
//! | `summary.json` | seed, version, the planted installation, the errors drawn |
//!
//! The configuration holds the platform preset and the IMU's datasheet
//! noise only — no mounting, lever arm or latency: estimating those (or
//! naming them in an error) is the filter's job, and the planted values
//! are in `summary.json` to compare with.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use aidnav_io::config::{Invalid, Validate};
use aidnav_io::formats::{BaroFormat, GnssFormat, ImuFormat, TimeSystem, WheelSpeedFormat};
use aidnav_io::reference::{ReferenceSample, write_reference};
use aidnav_sim::SimError;
use aidnav_sim::scenario::{Scenario, ScenarioFile, SimLog, simulate};
use serde::{Deserialize, Serialize};

use super::{JobError, JobResult};
use crate::VERSION;
use crate::process::config_name;

/// The `[output]` table of a simulation scenario: the formats written and
/// the ones the generated configuration reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimulationOutput {
    /// IMU formats written. Default all: `generic_csv`, `rtklib_tagged`,
    /// `kf_gins`.
    pub imu_formats: Vec<ImuFormat>,
    /// GNSS formats written. Default all: `generic_csv`, `rtklib_pos`,
    /// `kf_gins`, `nmea`, `ubx`.
    pub gnss_formats: Vec<GnssFormat>,
    /// Time system of the GNSS stamps where a format can hold either
    /// (`gpst` | `utc`; NMEA is UTC and UBX both, whatever this says).
    /// Default `gpst`.
    pub time_system: TimeSystem,
    /// Whether the generic GNSS CSV carries the receiver's σ; false writes
    /// it without σ columns and `aidnav.toml` gives `data.gnss_sigma_m`
    /// (the mode's nominal σ, as a user would take it from a datasheet).
    /// The other formats always hold σ. Default true.
    pub gnss_sigma: bool,
    /// The IMU format `aidnav.toml` reads (one of `imu_formats`). Default
    /// `generic_csv`.
    pub imu_format: ImuFormat,
    /// The GNSS format `aidnav.toml` reads (one of `gnss_formats`).
    /// Default `generic_csv`.
    pub gnss_format: GnssFormat,
    /// `platform` of `aidnav.toml` (`car` | `pedestrian` | `aircraft` |
    /// `generic`). Default: from the scenario's platform (car, rover and
    /// phone in a car: `car`; pedestrian: `pedestrian`; aircraft:
    /// `aircraft`).
    pub platform: Option<String>,
}

impl Default for SimulationOutput {
    fn default() -> Self {
        Self {
            imu_formats: vec![
                ImuFormat::GenericCsv,
                ImuFormat::RtklibTagged,
                ImuFormat::KfGins,
            ],
            gnss_formats: vec![
                GnssFormat::GenericCsv,
                GnssFormat::RtklibPos,
                GnssFormat::KfGins,
                GnssFormat::Nmea,
                GnssFormat::Ubx,
            ],
            time_system: TimeSystem::Gpst,
            gnss_sigma: true,
            imu_format: ImuFormat::GenericCsv,
            gnss_format: GnssFormat::GenericCsv,
            platform: None,
        }
    }
}

/// A simulation scenario file: a [`ScenarioFile`] whose `[output]` table
/// is a [`SimulationOutput`]; checking it resolves the scenario.
#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(transparent)]
pub struct SimulationFile(pub ScenarioFile);

/// A resolved simulation: the scenario with every value filled in and its
/// output table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Simulation {
    /// The scenario.
    #[serde(flatten)]
    pub scenario: Scenario,
    /// What is written.
    pub output: SimulationOutput,
}

impl Simulation {
    /// The scenario file with every default written out (valid input).
    pub fn to_toml(&self) -> String {
        let output = toml::to_string(&self.output).unwrap_or_default();
        format!("{}\n[output]\n{output}", self.scenario.to_toml())
    }
}

/// The `allowed` of an [`Invalid`] that is a table's read error (its
/// `value` the reader's message), not a value out of range.
const TABLE_ERROR: &str = "(the table's fields)";

/// The scenario key and requirement of a simulator error.
fn invalid(e: SimError) -> Invalid {
    match e {
        SimError::InvalidParameter {
            field,
            value,
            requirement,
        } => Invalid::new(field, value, requirement),
        SimError::InfeasibleSegment { index, reason } => {
            Invalid::new(format!("route.segments[{index}]"), "this segment", reason)
        }
        SimError::Table { table, message } => Invalid::new(table, message, TABLE_ERROR),
        other => Invalid::new("(scenario)", other, "a valid scenario"),
    }
}

impl SimulationFile {
    /// The scenario resolved and its output table read.
    pub fn resolve(&self) -> Result<Simulation, Invalid> {
        let scenario = self.0.resolve().map_err(invalid)?;
        let output: SimulationOutput = toml::Value::Table(self.0.output.clone())
            .try_into()
            .map_err(|e: toml::de::Error| Invalid::new("output", e.message(), TABLE_ERROR))?;
        output.check()?;
        Ok(Simulation { scenario, output })
    }
}

impl Validate for SimulationFile {
    /// Every value in range (a table that does not read is reported by
    /// [`load_simulation`], with the reader's message).
    fn validate(&self) -> Result<(), Invalid> {
        match self.resolve() {
            Err(inv) if inv.allowed == TABLE_ERROR => Ok(()),
            r => r.map(|_| ()),
        }
    }
}

impl SimulationOutput {
    fn check(&self) -> Result<(), Invalid> {
        let platforms = ["car", "pedestrian", "aircraft", "generic"];
        if let Some(p) = &self.platform
            && !platforms.contains(&p.as_str())
        {
            return Err(Invalid::new(
                "output.platform",
                p,
                "one of car, pedestrian, aircraft, generic",
            ));
        }
        if !self.imu_formats.contains(&self.imu_format) {
            return Err(Invalid::new(
                "output.imu_format",
                config_name(&self.imu_format),
                "one of output.imu_formats",
            ));
        }
        if !self.gnss_formats.contains(&self.gnss_format) {
            return Err(Invalid::new(
                "output.gnss_format",
                config_name(&self.gnss_format),
                "one of output.gnss_formats",
            ));
        }
        Ok(())
    }
}

/// File name of each IMU format's file.
pub fn imu_file_name(format: ImuFormat) -> &'static str {
    match format {
        ImuFormat::GenericCsv => "imu.csv",
        ImuFormat::RtklibTagged => "imu_raw.csv",
        ImuFormat::KfGins => "imu.txt",
    }
}

/// File name of each GNSS format's file.
pub fn gnss_file_name(format: GnssFormat) -> &'static str {
    match format {
        GnssFormat::GenericCsv => "gnss.csv",
        GnssFormat::RtklibPos => "gnss.pos",
        GnssFormat::KfGins => "gnss.txt",
        GnssFormat::Nmea => "gnss.nmea",
        GnssFormat::Ubx => "gnss.ubx",
    }
}

/// What [`simulate_to_dir`] wrote.
#[derive(Debug, Clone, Serialize)]
pub struct SimulateReport {
    /// Scenario name.
    pub name: String,
    /// Master seed.
    pub seed: u64,
    /// IMU samples.
    pub imu_samples: usize,
    /// GNSS fixes.
    pub gnss_epochs: usize,
    /// Wheel-speed samples (0: none simulated).
    pub wheel_speed_samples: usize,
    /// Barometer samples (0: none simulated).
    pub barometer_samples: usize,
    /// Duration of the log \[s\].
    pub duration_s: f64,
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// The command that processes the log.
    pub process_command: String,
}

/// Every file name [`simulate_to_dir`] may write (cleared before a run).
const FILE_NAMES: [&str; 15] = [
    "imu.csv",
    "imu_raw.csv",
    "imu_raw.csv.tag",
    "imu.txt",
    "gnss.csv",
    "gnss.pos",
    "gnss.txt",
    "gnss.nmea",
    "gnss.ubx",
    "wheel_speed.csv",
    "barometer.csv",
    "truth.csv",
    "aidnav.toml",
    "scenario.toml",
    "summary.json",
];

/// Load and resolve the scenario file `path`; `seed` replaces its seed.
/// A scenario without a `name` takes the file's stem.
pub fn load_simulation(path: &Path, seed: Option<u64>) -> JobResult<Simulation> {
    let text = std::fs::read_to_string(path).map_err(|reason| aidnav_io::IoError::Read {
        path: path.to_path_buf(),
        reason,
    })?;
    simulation_of_text(&text, path, seed)
}

/// [`load_simulation`] on a scenario's TOML text; `origin` names it in
/// errors and gives the default name (its stem).
pub fn simulation_of_text(text: &str, origin: &Path, seed: Option<u64>) -> JobResult<Simulation> {
    let mut file = aidnav_io::config::parse_toml::<SimulationFile>(text, origin)?;
    if !text.lines().any(|l| l.trim_start().starts_with("name")) {
        file.0.name = origin
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.is_empty() && !s.starts_with('<'))
            .unwrap_or_else(|| "simulation".into());
    }
    if let Some(s) = seed {
        file.0.seed = s;
    }
    file.resolve().map_err(|inv| {
        let message = if inv.allowed == TABLE_ERROR {
            inv.value.clone()
        } else {
            format!("{} is out of range: allowed {}", inv.value, inv.allowed)
        };
        JobError::Io(aidnav_io::IoError::Config {
            path: origin.to_path_buf(),
            line: aidnav_io::config::find_key_line(text, &inv.key).unwrap_or(0),
            key: inv.key,
            message,
        })
    })
}

/// Simulate (run 0 of the scenario's seed) and write every file into
/// `out` (see the module docs).
pub fn simulate_to_dir(sim: &Simulation, out: &Path) -> JobResult<SimulateReport> {
    let s = &sim.scenario;
    let log = simulate(s, s.seed, 0)
        .map_err(|e| JobError::Refused(format!("scenario {}: {e}", s.name)))?;
    if log.imu.len() < 2 || log.gnss.is_empty() {
        return Err(JobError::Refused(format!(
            "scenario {}: {} IMU samples and {} GNSS fixes simulated: nothing to process",
            s.name,
            log.imu.len(),
            log.gnss.len()
        )));
    }
    aidnav_io::writers::ensure_dir(out)?;
    for name in FILE_NAMES {
        let path = out.join(name);
        if path.is_file() {
            std::fs::remove_file(&path).map_err(|e| {
                JobError::Refused(format!(
                    "{}: cannot remove the earlier run's file: {e}",
                    path.display()
                ))
            })?;
        }
    }
    let mut files = Vec::new();
    for &f in &sim.output.imu_formats {
        files.extend(f.write(&out.join(imu_file_name(f)), &log.imu)?);
    }
    // The receiver's σ left out of the generic CSV: its fixes with NaN σ,
    // which its writer omits.
    let without_sigma: Option<Vec<_>> = (!sim.output.gnss_sigma).then(|| {
        log.gnss
            .iter()
            .map(|f| aidnav_sensors::GnssFix {
                position_sigma_neu: nalgebra::Vector3::repeat(f64::NAN),
                ..*f
            })
            .collect()
    });
    for &f in &sim.output.gnss_formats {
        let fixes = match &without_sigma {
            Some(fixes) if f == GnssFormat::GenericCsv => fixes,
            _ => &log.gnss,
        };
        files.extend(f.write(&out.join(gnss_file_name(f)), fixes, sim.output.time_system)?);
    }
    if !log.wheel_speed.is_empty() {
        files.extend(
            WheelSpeedFormat::GenericCsv.write(&out.join("wheel_speed.csv"), &log.wheel_speed)?,
        );
    }
    if !log.baro.is_empty() {
        files.extend(BaroFormat::GenericCsv.write(&out.join("barometer.csv"), &log.baro)?);
    }
    let stamp = format!(
        "aidnav {VERSION} simulate: scenario {}, seed {}",
        s.name, s.seed
    );
    for f in &files {
        stamp_file(f, &stamp)?;
    }
    let header = vec![
        stamp,
        String::from("the state of the IMU: position, NED velocity, attitude of the IMU axes"),
    ];
    let truth_path = out.join("truth.csv");
    write_reference(&truth_path, &reference_of(&log), &header)?;
    files.push(truth_path);
    let config_path = out.join("aidnav.toml");
    aidnav_io::writers::write_atomic(&config_path, new_user_config(sim, &log).as_bytes())?;
    files.push(config_path.clone());
    let scenario_path = out.join("scenario.toml");
    aidnav_io::writers::write_atomic(
        &scenario_path,
        format!(
            "# aidnav {VERSION} simulate, seed {}\n{}",
            s.seed,
            sim.to_toml()
        )
        .as_bytes(),
    )?;
    files.push(scenario_path);
    let mut report = SimulateReport {
        name: s.name.clone(),
        seed: s.seed,
        imu_samples: log.imu.len(),
        gnss_epochs: log.gnss.len(),
        wheel_speed_samples: log.wheel_speed.len(),
        barometer_samples: log.baro.len(),
        duration_s: log.imu[log.imu.len() - 1].time_s - log.imu[0].time_s,
        files,
        process_command: format!("aidnav process {}", config_path.display()),
    };
    let mut summary = aidnav_io::writers::Summary::new("simulate", VERSION, Some(s.seed), sim);
    // File names relative to DIR: the same scenario and seed give the same
    // bytes wherever they are written.
    let relative = SimulateReport {
        files: report
            .files
            .iter()
            .map(|f| f.file_name().map(PathBuf::from).unwrap_or_default())
            .collect(),
        process_command: String::from("aidnav process aidnav.toml"),
        ..report.clone()
    };
    summary.insert("result", &relative);
    summary.insert("installation", planted_installation(s));
    summary.insert("imu_errors", imu_errors_json(&log));
    report.files.push(summary.write(out)?);
    Ok(report)
}

/// Put `stamp` (seed and version) as a first comment line into a written
/// file whose format has comments: `#` in the KF-GINS texts and NMEA, `%`
/// in RTKLIB `.pos`. The generic CSVs (whose first line is the header), the
/// raw IMU CSV, its `.tag` and UBX have none: their seed and version are in
/// `summary.json` and `scenario.toml` beside them.
fn stamp_file(path: &Path, stamp: &str) -> JobResult<()> {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or_default();
    let mark = match name {
        "gnss.pos" => "%",
        "imu.txt" | "gnss.txt" | "gnss.nmea" => "#",
        _ => return Ok(()),
    };
    let body = std::fs::read(path)
        .map_err(|e| JobError::Refused(format!("{}: cannot read it back: {e}", path.display())))?;
    let mut text = format!("{mark} {stamp}\n").into_bytes();
    text.extend(body);
    aidnav_io::writers::write_atomic(path, &text)?;
    Ok(())
}

/// The planted installation parameters, the values an estimator should find.
pub fn planted_installation(s: &Scenario) -> serde_json::Value {
    serde_json::json!({
        "mounting_deg": s.installation.mounting_deg,
        "gnss_lever_arm_vehicle_m": s.gnss.lever_arm_m,
        "gnss_lever_arm_imu_m": s.gnss_lever_arm_imu_m(),
        "gnss_latency_s": s.gnss.latency_s,
        "wheel_lever_arm_vehicle_m": s.wheel_speed.as_ref().map(|w| w.lever_arm_m),
    })
}

/// The turn-on errors drawn for the run, in SI units.
fn imu_errors_json(log: &SimLog) -> serde_json::Value {
    let e = &log.imu_errors;
    let v = |x: &nalgebra::Vector3<f64>| [x.x, x.y, x.z];
    serde_json::json!({
        "gyro_bias_rad_s": v(&e.gyro_bias_rad_s),
        "gyro_scale_factor": v(&e.gyro_scale_factor),
        "accel_bias_m_s2": v(&e.accel_bias_m_s2),
        "accel_scale_factor": v(&e.accel_scale_factor),
    })
}

/// The truth as reference samples (position, velocity, attitude of the IMU).
pub fn reference_of(log: &SimLog) -> Vec<ReferenceSample> {
    log.truth
        .iter()
        .map(|t| {
            let (r, p, y) = t.attitude.euler_angles();
            ReferenceSample {
                time_s: t.time_s,
                latitude_rad: t.position.latitude_rad,
                longitude_rad: t.position.longitude_rad,
                height_m: t.position.height_m,
                velocity_ned_m_s: Some(t.velocity_ned.raw().into()),
                attitude_rpy_rad: Some([r, p, y]),
            }
        })
        .collect()
}

/// One number when the three axes agree, else `[x, y, z]`.
fn axes(v: [f64; 3]) -> String {
    if v[0] == v[1] && v[1] == v[2] {
        format!("{}", v[0])
    } else {
        format!("[{}, {}, {}]", v[0], v[1], v[2])
    }
}

/// The configuration a new user would write for this log: the platform,
/// the files, the IMU's datasheet noise (white noise, bias instability,
/// scale-factor σ), the GNSS σ when the receiver reports none, and the
/// aiding streams' files. No installation parameter.
pub fn new_user_config(sim: &Simulation, log: &SimLog) -> String {
    let s = &sim.scenario;
    let out = &sim.output;
    let platform = out
        .platform
        .clone()
        .unwrap_or_else(|| s.platform.process_preset().to_string());
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# aidnav process configuration of the simulated log \"{}\" (seed {}, aidnav {VERSION}):",
        s.name, s.seed
    );
    t.push_str(
        "# what a new user would write: the platform and the IMU's datasheet noise.\n\
         # No installation parameters (mounting, lever arm, GNSS latency): the planted\n\
         # values are in summary.json, the truth in truth.csv.\n",
    );
    let _ = writeln!(t, "platform = \"{platform}\"\n\n[data]\ndir = \".\"");
    let imu_file = imu_file_name(out.imu_format);
    let _ = writeln!(
        t,
        "imu = \"{imu_file}\"\nimu_format = \"{}\"",
        config_name(&out.imu_format)
    );
    if out.imu_format == ImuFormat::RtklibTagged {
        let _ = writeln!(t, "imu_tags = \"imu_raw.csv.tag\"");
    }
    let _ = writeln!(
        t,
        "gnss = \"{}\"\ngnss_format = \"{}\"",
        gnss_file_name(out.gnss_format),
        config_name(&out.gnss_format)
    );
    if out.gnss_format == GnssFormat::GenericCsv && !out.gnss_sigma {
        let [n, e, u] = s.gnss.model_sigma_neu_m();
        let _ = writeln!(t, "gnss_sigma_m = [{}, {}]", n.max(e), u);
    }
    let g = &s.imu.gyro;
    let a = &s.imu.accel;
    let _ = writeln!(
        t,
        "\n[imu.noise]\narw_deg_per_sqrt_h = {}\nvrw_mps_per_sqrt_h = {}\ngyro_bias_deg_per_h = {}\naccel_bias_mg = {}\ngyro_scale_ppm = {}\naccel_scale_ppm = {}",
        axes(g.angle_random_walk_deg_sqrt_h),
        axes(a.velocity_random_walk_m_s_sqrt_h),
        axes(g.bias_instability_deg_h),
        axes(a.bias_instability_mg),
        axes(g.scale_factor_sigma_ppm),
        axes(a.scale_factor_sigma_ppm),
    );
    if !log.wheel_speed.is_empty() {
        t.push_str("\n[wheel_speed]\nfile = \"wheel_speed.csv\"\n");
    }
    if !log.baro.is_empty() {
        t.push_str("\n[barometer]\nfile = \"barometer.csv\"\n");
    }
    t
}
