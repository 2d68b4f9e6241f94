//! `aidnav`: the command-line face of the aidnav library. Thin by design:
//! every subcommand parses its arguments, calls one job of `aidnav::app::jobs`,
//! and prints what it returns.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use aidnav::app::jobs::{self, FilterJob};
use aidnav::io::measurements::DEFAULT_MAX_EPOCHS;
use aidnav::reproduce::MonteCarloScenario;
use aidnav::reproduce::anomalies::{AnomaliesResult, AnomaliesScenario};
use aidnav::reproduce::consistency::{ConsistencyResult, ConsistencyScenario};
use aidnav::reproduce::extended_state::{ExtendedStateResult, ExtendedStateScenario, SwitchKind};
use aidnav::reproduce::formation::{FormationScenario, Network, NetworkSweepScenario};
use aidnav::reproduce::group::{GroupResult, GroupScenario};
use aidnav::reproduce::outages::{OutageScores, OutagesResult, OutagesScenario};
use anyhow::{Context, Result};

mod print;
mod process;
mod simulate;
mod tune;

use clap::{Args, Parser, Subcommand, ValueEnum};
use print::*;
use process::run_process;
use simulate::{SimulateArgs, ZooArgs, run_simulate, run_zoo};
use tune::run_tune;

/// aidnav — aided inertial navigation toolkit.
///
/// Kalman filtering of INS errors with GNSS/radio fixes and inter-vehicle
/// measurements, seeded Monte Carlo proof of every result, and the published
/// experiments reproduced with one command. Every result folder gets a
/// summary.json with the aidnav version, the seed and the full scenario.
#[derive(Debug, Parser)]
#[command(name = "aidnav", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a linear Kalman filter given as Φ, Q, H, R, x0, P0 in TOML over a
    /// CSV of measurements.
    ///
    /// Writes estimates.csv (states and σ), innovations.csv (innovation, its σ,
    /// NIS, degrees of freedom and what the update did), optionally
    /// covariance.csv (upper triangle of P per epoch) and smoothed.csv (RTS),
    /// and summary.json. See examples/01-scalar-filter for both file formats:
    /// the model file documents its keys; the CSV has a header with an
    /// optional `time` column and one column per measurement name; an empty
    /// cell is a missing value. (x0, P0) is the prior at the first epoch.
    Filter(FilterArgs),
    /// Reproduce a published experiment (seeded Monte Carlo), print its table,
    /// write CSV, SVG plots and summary.json.
    Reproduce(ReproduceArgs),
    /// Run a simulation scenario file and print its per-member results.
    ///
    /// The file's table names the simulation; today `[formation]`: M vehicles
    /// in a 3-D formation, each with INS + GNSS (stage-1 loosely coupled
    /// filter), inter-vehicle range/bearing/elevation sensors and the stage-2
    /// group filter in the paper's per-axis form and as an EKF, with optional
    /// GNSS denial of chosen members (`[[formation.denial]]`). Every key is
    /// optional; `aidnav reproduce formation --print-scenario` prints the
    /// defaults (write them under `[formation]`), examples/formation.toml is a
    /// documented example. Writes formation.csv, formation_errors.svg and
    /// summary.json. `[formation.network]` makes the exchange a network
    /// (latency, loss, neighbour limit; late packets fused at their own
    /// epoch), and its `sweep` table also writes network_sweep.csv and
    /// network_sweep.svg (examples/formation_network.toml).
    Run(RunArgs),
    /// Process a recorded IMU + GNSS log end to end and score it.
    ///
    /// The configuration (TOML) names the files (`[data]`: GNSS as RTKLIB
    /// `.pos`, KF-GINS text, NMEA, a u-blox UBX log (`gnss_format = "ubx"`:
    /// its NAV-PVT epochs, ellipsoidal heights) or aidnav's generic CSV
    /// (`gnss_format = "generic_csv"`); IMU as raw CSV with its RTKLIB
    /// `.tag`, KF-GINS increments or generic CSV), the IMU mounting,
    /// smoothing and noise, the initialisation and the lever arm.
    /// `--print-config` writes a complete configuration with every key, its
    /// default and a comment; `platform = "car" | "pedestrian" | "aircraft"
    /// | "generic"` presets the constraints and thresholds. Examples:
    /// examples/drive_0708.toml (the car drive) and examples/walk_0827.toml
    /// (the handheld walk, read from its UBX log).
    ///
    /// Generic GNSS CSV: a header row naming the columns, any order. Time:
    /// `gpst_s` (GPST s since 1970), or `gps_week` + `tow_s`, or `utc` (ISO
    /// 8601, e.g. 2024-08-27T17:30:00.2Z; leap seconds applied). Position:
    /// `lat_deg`, `lon_deg` with `height_m` (ellipsoidal) or `height_msl_m` +
    /// `geoid_sep_m`; or `ecef_x_m`, `ecef_y_m`, `ecef_z_m`. σ [m]:
    /// `sigma_n_m`, `sigma_e_m`, `sigma_u_m`, or `sigma_h_m` (each horizontal
    /// axis) + `sigma_v_m`, or none and `[data] gnss_sigma_m = [horizontal,
    /// vertical]`. Optional velocity: `vel_n_mps`, `vel_e_mps`, `vel_d_mps`,
    /// or `speed_mps` + `course_deg` [+ `vertical_speed_mps`, up positive],
    /// with `sigma_vel_mps`; optional `quality` (fixed, float, dgps, single
    /// or RTKLIB Q) and `satellites`. Any other column is an error listing
    /// these; examples/data/gnss_generic_example.csv is an example.
    ///
    /// Generic IMU CSV: `time_s` and `gx_rad_s … az_m_s2`, or `gx, gy, gz,
    /// ax, ay, az` with `[data] imu_units = { gyro = "rad_s" | "deg_s",
    /// accel = "m_s2" | "g", kind = "rates" | "increments" }`. Units that
    /// cannot be right are refused with the evidence: the median specific
    /// force against g, the gyro at rest, and the gyro's turn against the
    /// GNSS course while moving (57× or 1/57×: degrees and radians mixed).
    /// `[checks] units` and `[checks] turn_rate` = `error` (default) |
    /// `warn` | `off` let a correct but unusual log go on.
    ///
    /// More aiding streams, each a table of its own (in `--print-config`,
    /// commented out): `[wheel_speed] file = "…"` fuses a wheel-speed
    /// (odometer) log as a forward-speed update at the wheel's lever arm
    /// (`lever_arm_m`), estimating its scale factor (`scale_state`);
    /// `[barometer] file = "…"` fuses barometric heights, estimating their
    /// bias against the ellipsoid (`bias_state`). Their generic CSVs: a
    /// header row naming the columns, any order; time `time_s` (the scale
    /// of the other files), `gpst_s`, `gps_week` + `tow_s` or `utc`; wheel
    /// speed `speed_mps` or `speed_kmh` (negative when reversing), optional
    /// `sigma_mps`; barometer `height_m`, or `pressure_pa` / `pressure_hpa`
    /// (converted by the ISA standard atmosphere), optional `sigma_m`. A
    /// stream with no sample inside the IMU's span is an error.
    ///
    /// Writes solution.csv, instruments.csv,
    /// smoothed.csv, trajectory.svg, innovations.svg, outage_drift.svg and
    /// summary.json (its `result.aid_sources`: per measurement stream the
    /// updates fused, accepted, rejected, modified, reset and the samples
    /// skipped), wheel_speed.csv and barometer.csv with those streams (one
    /// row per update: innovation, its σ, NIS, outcome), and prints the
    /// score tables: simulated GNSS outages of
    /// 10/30/60 s (RMS over windows of the maximum drift against the
    /// withheld RTK fixes: filter, RTS-smoothed, free INS, and bridged by
    /// spec 20's predictors), the efficiency criterion K_eff in the outages,
    /// injected outliers per measurement policy, and bursts after outages.
    /// `--no-score` runs the filter only. Scores are measured against the
    /// fixes whose quality `[score] reference_quality` names (RTK fixed by
    /// default); a score without such a fix prints "no reference" (null in
    /// summary.json). summary.json's `result.consistency` compares the
    /// filter's covariance with its actual error in the outages (fraction
    /// inside the 99 % ellipsoid, mean NEES) and gives the mean NIS per
    /// degree of freedom with all GNSS. Warnings (divergence, long runs of
    /// rejected updates, …) go to stderr and to summary.json's
    /// `result.warnings`.
    /// `[imu.noise] auto = true` tunes the noise first (as `aidnav tune`;
    /// also allan.svg, allan.csv, tuned_noise.toml) and runs with the
    /// fitted values.
    Process(ProcessArgs),
    /// Tune the IMU noise terms, the GNSS σ scale and the non-holonomic σ
    /// of a log's configuration.
    ///
    /// Takes `aidnav process`'s configuration. Step 1: the longest
    /// standstill of the log (the `[standstill]` thresholds of the platform
    /// and the GNSS speed), if it lasts at least `tune.min_static_s` (10 s),
    /// gives the overlapping Allan deviation of the six axes, computed on
    /// the unsmoothed samples: white noise (angle / velocity random walk)
    /// on the −½ slope at τ ≥ `imu.smoothing_s`, bias instability at the
    /// minimum / 0.664 (an upper bound when the curve still falls at the
    /// longest cluster time). Step 2: from those values or the configured
    /// ones, whichever have the higher likelihood, factors on ARW, VRW, the
    /// two bias instabilities, the GNSS σ scale and (with the non-holonomic
    /// constraint) its σ maximise a log-likelihood, each evaluation one
    /// filter pass (Nelder–Mead, at most `tune.max_evaluations` or
    /// --max-evaluations passes). `tune.objective = "coasting"` (default):
    /// the predictive likelihood of every fix in a pass that withholds
    /// windows of `tune.outage_s` (default: the longest of
    /// `score.outages_s`) every `tune.outage_s + tune.gap_s` — the updates'
    /// innovations, and each withheld fix against the coasting filter's
    /// position and covariance; it fits a covariance that is honest over an
    /// outage. `"innovations"`: the GNSS innovations of a pass with every
    /// fix, −½ Σ (ln det S + νᵀ S⁻¹ ν) (one step ahead only). Prints the
    /// Allan table, the fitted values and the likelihood gain; writes
    /// allan.svg, allan.csv, tuned_noise.toml (an [imu.noise] table to
    /// paste, gnss.sigma_scale and constraints.non_holonomic_sigma_mps as
    /// comments) and summary.json. `[imu.noise] auto = true` makes `aidnav
    /// process` run this first and use the fitted values.
    Tune(TuneArgs),
    /// Write a log aidnav reads as another program's input files (today
    /// KF-GINS's).
    ///
    /// Reads the files `aidnav process`'s configuration names, with its
    /// formats and units, exactly as `process` reads them, and writes into
    /// --out: imu.txt (KF-GINS IMU text: `time dθx dθy dθz dvx dvy dvz`,
    /// rad and m/s, the increments over the interval ending at the time),
    /// gnss.txt (`time lat lon h σN σE σD`, degrees and metres; GNSS
    /// velocity, fix quality and satellites are not written) and
    /// kf-gins.yaml (a KF-GINS configuration skeleton: paths, IMU rate,
    /// start time, initial position from the first fix, levelled roll and
    /// pitch, yaw from initial.attitude_deg or 0 — check it —, the
    /// [imu.noise] values in KF-GINS's units, the lever arm).
    ///
    /// The IMU samples are written as the readers give them: in the SENSOR
    /// frame on the IMU file's own time tags. imu.mounting_deg,
    /// imu.time_offset_s and imu.smoothing_s are not applied, so the same
    /// configuration with `imu_format = "kf_gins"`, `gnss_format =
    /// "kf_gins"` and these file names reads the same samples back (times
    /// aside). Times: aidnav's are GPST seconds since 1970, KF-GINS's GPS
    /// seconds of week; the start of the first IMU sample's GPS week is
    /// subtracted from every time (a log crossing into the next week goes
    /// on past 604800 s). Each IMU sample becomes one row whose interval
    /// has the sample at its middle (ends at the midpoints between
    /// samples); a first row of zeros opens the first interval. Numbers are
    /// written in their shortest exact decimal form.
    Convert(ConvertArgs),
    /// Simulate a realistic log with known truth, in every format the
    /// readers take, with the configuration a new user would write.
    ///
    /// The scenario (TOML; `--print-scenario` prints every key, zoo/*.toml
    /// are examples): `platform` (car | rover | pedestrian | aircraft |
    /// phone_in_car), the path (`route_preset` = urban | highway | walk |
    /// rover | flight, or a `[route]` of segments — accelerate, cruise,
    /// turn, stop — with hills, `bank_in_turns` and walking `steps`), the
    /// IMU (`[imu] grade` = consumer | industrial | tactical | navigation,
    /// `rate_hz`, and any datasheet value over the grade's), the receiver
    /// (`[gnss] mode` = standalone | dgps | float | fixed, `rate_hz`,
    /// `latency_s`, `write_velocity`, `reported_sigma_scale`, `multipath`,
    /// `outliers`, `outages_s`, `degraded_s`, `lever_arm_m` in vehicle
    /// axes), optional `[wheel_speed]` and `[barometer]`, the planted
    /// `[installation] mounting_deg` (IMU axes against the vehicle's), the
    /// `seed`, and `[output]`: the formats written (`imu_formats`,
    /// `gnss_formats`), the ones aidnav.toml reads (`imu_format`,
    /// `gnss_format`), `time_system` (gpst | utc), `gnss_sigma` (false: the
    /// generic GNSS CSV without σ columns, aidnav.toml then gives
    /// `data.gnss_sigma_m`) and `platform`.
    ///
    /// Writes into --out: imu.csv (generic), imu_raw.csv + .tag (RTKLIB),
    /// imu.txt (KF-GINS), gnss.csv, gnss.pos, gnss.txt, gnss.nmea,
    /// gnss.ubx, wheel_speed.csv and barometer.csv when simulated,
    /// truth.csv (time, position, NED velocity and attitude of the IMU:
    /// the reference format), aidnav.toml (platform, files and datasheet
    /// noise only — no installation parameter), scenario.toml (every value
    /// filled in) and summary.json (seed, version, the planted
    /// installation, the IMU errors drawn). Seeded and byte-reproducible.
    Simulate(SimulateArgs),
    /// Simulate every scenario, process each with its new-user
    /// configuration and with the matched noise model, score both against
    /// the truth and print one row per log.
    ///
    /// Columns: tracking RMS 3-D error with all GNSS, the RMS over windows
    /// of the largest 3-D drift in 10 / 30 / 60 s outages, the RMS roll /
    /// pitch / yaw error after the first 60 s, the fraction of outage
    /// epochs inside the filter's 99 % ellipsoid and the mean NEES (3
    /// when honest), then the same drifts with the matched noise model.
    /// Writes DIR/<scenario>/ (each log), zoo.csv and summary.json.
    Zoo(ZooArgs),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ConvertTarget {
    /// KF-GINS (i2Nav-WHU/KF-GINS) text files and YAML configuration.
    KfGins,
}

#[derive(Debug, Args)]
struct ConvertArgs {
    /// Configuration file (TOML), as `aidnav process` takes it.
    #[arg(value_name = "CONFIG.toml")]
    config: PathBuf,
    /// The format to write.
    #[arg(long, value_enum, value_name = "FORMAT")]
    to: ConvertTarget,
    /// Directory of the data files (replaces data.dir of the configuration).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Output directory (created if needed; imu.txt, gnss.txt and
    /// kf-gins.yaml in it are overwritten).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
}

#[derive(Debug, Args)]
struct TuneArgs {
    /// Configuration file (TOML), as `aidnav process` takes it.
    #[arg(value_name = "CONFIG.toml")]
    config: PathBuf,
    /// Directory of the data files (replaces data.dir of the configuration).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Output directory [default: results/<config file stem>_tune].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Most filter passes of the likelihood search (replaces
    /// tune.max_evaluations; a small number for a quick look).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=10_000))]
    max_evaluations: Option<u32>,
}

#[derive(Debug, Args)]
struct ProcessArgs {
    /// Configuration file (TOML).
    #[arg(value_name = "CONFIG.toml", required_unless_present = "print_config")]
    config: Option<PathBuf>,
    /// Print a complete configuration (every key, its default, a comment)
    /// for `--platform` and exit.
    #[arg(long)]
    print_config: bool,
    /// The platform preset of `--print-config`.
    #[arg(long, value_name = "PLATFORM", default_value = "generic",
          value_parser = ["car", "pedestrian", "aircraft", "generic"])]
    platform: String,
    /// Directory of the data files (replaces data.dir of the configuration).
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// Output directory [default: results/<config file stem>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Skip the outage and anomaly scoring (one filter pass only).
    #[arg(long)]
    no_score: bool,
    /// Exit with status 3 (after writing every output) when the run gave a
    /// warning: divergence (mean position NIS per degree of freedom above
    /// 10 over 30 s, for longer than 30 s), a run of rejected or limited
    /// updates longer than 10 s, levelling while moving, implausible units
    /// or non-finite output values. The readers' notes (a truncated line
    /// dropped, epochs outside the IMU span) and failed runs of the
    /// comparison tables (another policy on corrupted data: NaN in the
    /// table) are printed but do not fail.
    #[arg(long)]
    strict: bool,
}

#[derive(Debug, Args)]
struct RunArgs {
    /// Scenario file (TOML) with a `[formation]` table.
    #[arg(value_name = "SCENARIO.toml")]
    scenario: PathBuf,
    #[command(flatten)]
    mc: MonteCarloOverrides,
    /// Output directory [default: results/<scenario file stem>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
}

/// Options every Monte Carlo command shares.
#[derive(Debug, Args)]
struct MonteCarloOverrides {
    /// Number of Monte Carlo runs (overrides the scenario).
    #[arg(long, value_name = "N")]
    runs: Option<usize>,
    /// Master seed (overrides the scenario).
    #[arg(long, value_name = "SEED")]
    seed: Option<u64>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

impl MonteCarloOverrides {
    fn overrides(&self) -> jobs::ScenarioOverrides {
        jobs::ScenarioOverrides {
            runs: self.runs,
            seed: self.seed,
            max_runs: None,
        }
    }
}

#[derive(Debug, Args)]
struct FilterArgs {
    /// Model file (TOML): phi, q, h, r, x0, p0 and an optional \[filter\] table.
    #[arg(long, value_name = "MODEL.toml")]
    model: PathBuf,
    /// Measurement file (CSV): header with optional `time` and the model's measurement names.
    #[arg(long, value_name = "Z.csv")]
    measurements: PathBuf,
    /// Output directory (created if needed; files in it are overwritten).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Also run the Rauch–Tung–Striebel smoother and write smoothed.csv.
    #[arg(long)]
    smooth: bool,
    /// Also write the full covariance of every epoch to covariance.csv.
    #[arg(long)]
    full_covariance: bool,
    /// Refuse files with more epochs than this (an error, never a truncation).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_MAX_EPOCHS)]
    max_epochs: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Experiment {
    /// Every reproduction with quick defaults (the README's main job).
    All,
    /// Filter consistency demo: tuned vs mistuned constant-velocity filters, NEES/NIS against χ² bounds.
    Consistency,
    /// Spec 10: launch-vehicle INS, 14-state instrument-error filter, Cramér–Rao switch, 9 trajectories × 2 thresholds.
    ExtendedState,
    /// Spec 20: INS error estimation under anomalous GNSS fixes, every estimator side by side.
    Anomalies,
    /// Spec 20: bridging GNSS outages with predictors (hold, trend, GMDH, relay …).
    Outages,
    /// Spec 30: the paper's axis-decoupled group filter, single vehicle vs five with relative sensors.
    Group,
    /// Spec 30 beyond the paper: 3-D formation, INS/GNSS per member, paper fusion vs EKF, GNSS denial.
    Formation,
    /// Spec 30 beyond the paper: the formation's exchange as a network, accuracy per latency × loss rate (a quick grid; the full one: examples/formation_network.toml).
    FormationNetwork,
}

#[derive(Debug, Args)]
struct ReproduceArgs {
    /// Which experiment.
    #[arg(value_enum)]
    experiment: Experiment,
    /// Scenario file (TOML) overriding the defaults; see --print-scenario.
    #[arg(long, value_name = "SCENARIO.toml")]
    scenario: Option<PathBuf>,
    #[command(flatten)]
    mc: MonteCarloOverrides,
    /// Output directory [default: results/<experiment>].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print the default scenario as TOML and exit.
    #[arg(long)]
    print_scenario: bool,
}

fn main() -> ExitCode {
    stop_quietly_on_closed_stdout();
    let cli = Cli::parse();
    if !matches!(&cli.command, Command::Process(a) if a.no_score) {
        fixed_mmap_threshold();
    }
    let result = match cli.command {
        Command::Filter(a) => run_filter(a).map(|()| ExitCode::SUCCESS),
        Command::Reproduce(a) => run_reproduce(a).map(|()| ExitCode::SUCCESS),
        Command::Run(a) => run_scenario(a).map(|()| ExitCode::SUCCESS),
        Command::Process(a) => run_process(a),
        Command::Tune(a) => run_tune(a).map(|()| ExitCode::SUCCESS),
        Command::Convert(a) => run_convert(a).map(|()| ExitCode::SUCCESS),
        Command::Simulate(a) => run_simulate(a).map(|()| ExitCode::SUCCESS),
        Command::Zoo(a) => run_zoo(a).map(|()| ExitCode::SUCCESS),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// `aidnav convert`: write the files, print what was written.
fn run_convert(a: ConvertArgs) -> Result<()> {
    let r = match a.to {
        ConvertTarget::KfGins => jobs::convert_kfgins(&a.config, a.data.as_deref(), &a.out)?,
    };
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} IMU samples, {} GNSS epochs; times in seconds of GPS week {}",
        r.imu_samples, r.gnss_epochs, r.gps_week
    );
    for f in &r.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}

/// `aidnav … | head`: when the reader of stdout goes away, end the process
/// the way Unix tools do (SIGPIPE, exit status 141, no message) instead of
/// the Rust default (SIGPIPE ignored, so `println!` panics with "Broken pipe").
fn stop_quietly_on_closed_stdout() {
    #[cfg(unix)]
    #[allow(unsafe_code)]
    // SAFETY: called first thing in `main`, before any other thread exists;
    // restores the default disposition of one signal.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Large allocations (from [`MMAP_THRESHOLD`] bytes) always in their own
/// mappings, returned to the system when freed, unless
/// `MALLOC_MMAP_THRESHOLD_` says otherwise. glibc starts so but raises the
/// threshold to the size of each such block freed (up to 32 MB), after
/// which the large blocks of later runs come from the heap and stay
/// resident when freed: `aidnav process` with scoring (many runs, each
/// with its smoother's storage, freed one after another on several
/// threads) peaked at 44–48 MB on the drive with the moving threshold and
/// at 32–33 MB with the fixed one, in the same time (see CHANGELOG).
///
/// Every command but `process --no-score` sets it (right after the
/// arguments are parsed, before any other thread exists). One filter pass
/// has no runs to free one after another: with glibc's moving threshold
/// its large blocks freed early (the IMU file's text, the parsers' parts)
/// come back from the heap for the later ones instead of as fresh pages —
/// on the drive with the smoother 8 800 → 7 900 page faults, CPU 146 →
/// 141 ms, the same peak (32–33 MB).
fn fixed_mmap_threshold() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if std::env::var_os("MALLOC_MMAP_THRESHOLD_").is_none() {
        #[allow(unsafe_code)]
        // SAFETY: called in `main` before any other thread exists;
        // mallopt only sets a parameter of the allocator's.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        }
    }
}

/// The threshold of [`fixed_mmap_threshold`]: glibc's initial value.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: libc::c_int = 128 * 1024;

/// The error and its causes joined with ": ", each level once: a level whose
/// text the level above already ends with (an error that prints its source
/// and also returns it from `source()`) is skipped, and a context that the
/// level below repeats at its start is replaced by that level.
fn error_chain(e: &anyhow::Error) -> String {
    let mut levels: Vec<String> = Vec::new();
    for cause in e.chain() {
        let text = cause.to_string();
        match levels.last_mut() {
            Some(last) if last.ends_with(&text) => {}
            Some(last) if text.starts_with(last.as_str()) => *last = text,
            _ => levels.push(text),
        }
    }
    levels.join(": ")
}

fn run_filter(a: FilterArgs) -> Result<()> {
    let report = jobs::filter(&FilterJob {
        model: a.model,
        measurements: a.measurements,
        out: a.out.clone(),
        smooth: a.smooth,
        full_covariance: a.full_covariance,
        max_epochs: a.max_epochs,
    })?;
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "{} epochs filtered; mean NIS per degree of freedom {:.3}",
        report.epochs, report.mean_nis_per_dof
    );
    let outcomes: Vec<String> = report
        .outcomes
        .iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect();
    println!("updates: {}", outcomes.join(", "));
    println!("{:<20} {:>16} {:>14}", "state", "final estimate", "final σ");
    for ((name, x), s) in report
        .states
        .iter()
        .zip(&report.final_state)
        .zip(&report.final_sigma)
    {
        println!("{name:<20} {x:>16.6} {s:>14.6}");
    }
    for f in &report.files {
        println!("wrote {}", f.display());
    }
    Ok(())
}

/// Quick defaults for `reproduce all`: fewer runs, same physics.
const QUICK_RUNS: usize = 100;

/// The scenario of one experiment — from `--scenario` or the defaults, with
/// `--runs` / `--seed` applied and `reproduce all`'s quick run count — checked,
/// and its output directory.
fn scenario_and_out<S>(a: &ReproduceArgs, root: &Path, name: &str) -> Result<(S, PathBuf)>
where
    S: Default + serde::de::DeserializeOwned + aidnav::io::Validate + MonteCarloScenario,
{
    let overrides = jobs::ScenarioOverrides {
        max_runs: (a.experiment == Experiment::All).then_some(QUICK_RUNS),
        ..a.mc.overrides()
    };
    let s = jobs::load_scenario::<S>(a.scenario.as_deref(), &overrides)?;
    let out = if a.experiment == Experiment::All || a.out.is_none() {
        root.join(name)
    } else {
        root.to_path_buf()
    };
    Ok((s, out))
}

fn run_reproduce(a: ReproduceArgs) -> Result<()> {
    let experiments: Vec<Experiment> = match a.experiment {
        Experiment::All => vec![
            Experiment::Consistency,
            Experiment::ExtendedState,
            Experiment::Anomalies,
            Experiment::Outages,
            Experiment::Group,
            Experiment::Formation,
            Experiment::FormationNetwork,
        ],
        e => vec![e],
    };
    if a.print_scenario {
        for e in &experiments {
            let (name, text) = match e {
                Experiment::Consistency => (
                    "consistency",
                    toml::to_string(&ConsistencyScenario::default())?,
                ),
                Experiment::ExtendedState => (
                    "extended-state",
                    toml::to_string(&ExtendedStateScenario::default())?,
                ),
                Experiment::Anomalies => {
                    ("anomalies", toml::to_string(&AnomaliesScenario::default())?)
                }
                Experiment::Outages => ("outages", toml::to_string(&OutagesScenario::default())?),
                Experiment::Group => ("group", toml::to_string(&GroupScenario::default())?),
                Experiment::Formation => (
                    "formation",
                    format!(
                        "{}{}",
                        toml::to_string(&FormationScenario::default())?,
                        absent_network_table()?
                    ),
                ),
                Experiment::FormationNetwork => (
                    "formation-network",
                    toml::to_string(&NetworkSweepScenario::default())?,
                ),
                Experiment::All => continue,
            };
            println!("# aidnav reproduce {name} — default scenario\n{text}");
        }
        return Ok(());
    }
    if a.scenario.is_some() && a.experiment == Experiment::All {
        anyhow::bail!("--scenario needs a single experiment, not `all`");
    }
    let root = a.out.clone().unwrap_or_else(|| PathBuf::from("results"));
    for e in experiments {
        match e {
            Experiment::Consistency => {
                let (s, out) = scenario_and_out::<ConsistencyScenario>(&a, &root, "consistency")?;
                let r = jobs::consistency(&s, &out, a.mc.quiet).context("consistency demo")?;
                print_consistency(&s, &r, &out);
            }
            Experiment::ExtendedState => {
                let (s, out) =
                    scenario_and_out::<ExtendedStateScenario>(&a, &root, "extended_state")?;
                let r = jobs::extended_state(&s, &out, a.mc.quiet)
                    .context("extended-state experiment")?;
                print_extended_state(&s, &r, &out);
            }
            Experiment::Anomalies => {
                let (s, out) = scenario_and_out::<AnomaliesScenario>(&a, &root, "anomalies")?;
                let r = jobs::anomalies(&s, &out, a.mc.quiet).context("anomalies experiment")?;
                print_anomalies(&s, &r, &out);
            }
            Experiment::Outages => {
                let (s, out) = scenario_and_out::<OutagesScenario>(&a, &root, "outages")?;
                let r = jobs::outages(&s, &out, a.mc.quiet).context("outages experiment")?;
                print_outages(&s, &r, &out);
            }
            Experiment::Group => {
                let (s, out) = scenario_and_out::<GroupScenario>(&a, &root, "group")?;
                let r = jobs::group(&s, &out, a.mc.quiet).context("group experiment")?;
                print_group(&s, &r, &out);
            }
            Experiment::Formation => {
                let (s, out) = scenario_and_out::<FormationScenario>(&a, &root, "formation")?;
                let r = jobs::formation(&s, "reproduce formation", &out, a.mc.quiet)
                    .context("formation flight")?;
                print_formation(&s, &r, &out);
            }
            Experiment::FormationNetwork => {
                let (s, out) =
                    scenario_and_out::<NetworkSweepScenario>(&a, &root, "formation_network")?;
                let sweep = jobs::formation_network(&s, &out, a.mc.quiet)
                    .context("formation network sweep")?;
                print_formation_network(&s.0, &sweep, &out);
            }
            Experiment::All => unreachable!("expanded above"),
        }
    }
    Ok(())
}

/// The `[network]` table `reproduce formation`'s defaults leave out (no
/// table: the ideal exchange), as TOML comments with its keys' defaults.
fn absent_network_table() -> Result<String> {
    let keys = toml::to_string(&Network::default())?;
    let mut text = String::from(
        "\n# [network]  (absent: the ideal exchange; with it, packets have latency and loss,\n# and [network.sweep] runs a grid: see `reproduce formation-network --print-scenario`)\n",
    );
    for line in keys.lines() {
        text.push_str(&format!("# {line}\n"));
    }
    Ok(text)
}

fn run_scenario(a: RunArgs) -> Result<()> {
    let file = jobs::load_formation_file(&a.scenario, &a.mc.overrides())?;
    let stem = a
        .scenario
        .file_stem()
        .map_or_else(|| "run".into(), |s| s.to_string_lossy().into_owned());
    let out = a.out.unwrap_or_else(|| Path::new("results").join(stem));
    let command = format!("run {}", a.scenario.display());
    let r =
        jobs::formation(&file.formation, &command, &out, a.mc.quiet).context("formation flight")?;
    print_formation(&file.formation, &r, &out);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An error that prints its source and also returns it (like an
    /// `#[error("…: {source}")]` with a `source` field).
    #[derive(Debug)]
    struct Repeats(std::io::Error);

    impl std::fmt::Display for Repeats {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "epoch 0: {}", self.0)
        }
    }

    impl std::error::Error for Repeats {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.0)
        }
    }

    #[test]
    fn error_chain_prints_each_level_once() {
        let e = anyhow::Error::new(Repeats(std::io::Error::other(
            "P0 is not positive definite",
        )))
        .context("consistency demo: epoch 0: P0 is not positive definite")
        .context("consistency demo");
        assert_eq!(
            error_chain(&e),
            "consistency demo: epoch 0: P0 is not positive definite"
        );
        let e = anyhow::Error::new(std::io::Error::other("disk full")).context("writing x.csv");
        assert_eq!(error_chain(&e), "writing x.csv: disk full");
    }
}
