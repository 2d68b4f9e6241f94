//! A [`ProcessResult`] and its optional [`Scores`] as the files `aidnav
//! process` writes: `solution.csv`, `navresult.txt` (optional),
//! `smoothed.csv`, `selected.csv`, `trajectory.svg`, `instruments.csv`, `innovations.svg`,
//! `outage_drift.svg` (with scores), `wheel_speed.csv` and `barometer.csv`
//! (with those streams) and `summary.json`; a tuning's
//! `allan.svg`, `allan.csv` and `tuned_noise.toml`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use aidnav_estimation::Outcome;
use aidnav_frames::earth::Geodetic;
use aidnav_integration::aiding::{AidRecord, BaroConfig, SampledSensor, WheelSpeedConfig};
use aidnav_io::IoError;
use aidnav_io::plot::{LineChart, LineStyle, Series, TRUTH_COLOR};
use aidnav_io::writers::{Summary, begin_outputs, write_table_noting_infinities};
use aidnav_supervisors::efficiency::Source;
use serde::Serialize;

use super::api::ProcessResult;
use super::config::ProcessConfig;
use super::run::{Epoch, SolutionRow};
use super::scoring::Scores;
use super::selection::SelectedEpoch;
use super::tune::{AxisAllan, ImuAllan, TuneResult, tuned_noise_toml};

/// The files `aidnav process` writes only when asked (`navresult.txt`
/// with `output.kf_gins_text`, `smoothed.csv` when smoothing,
/// `outage_drift.svg` when scoring): one an earlier run left in the same
/// directory is removed when this run does not write it
/// ([`remove_stale_outputs`](aidnav_io::writers::remove_stale_outputs)).
/// The tuning's files are not among them: `tuned_noise.toml` is a result
/// the user pastes into a configuration, kept until a tuning replaces it.
pub const OPTIONAL_FILES: [&str; 5] = [
    "navresult.txt",
    "smoothed.csv",
    "outage_drift.svg",
    "wheel_speed.csv",
    "barometer.csv",
];

/// Write every file of a result (and of its scores) into `out`, in the
/// order `aidnav process` lists them; `navresult` adds `navresult.txt`.
/// Each file is written atomically; returns the files and one warning per
/// table column that received ±inf (file, column, count, first row).
pub fn write_files(
    result: &ProcessResult,
    scores: Option<&Scores>,
    out: &Path,
    navresult: bool,
) -> Result<(Vec<PathBuf>, Vec<String>), IoError> {
    let forward = write_forward_files(result, scores, out, navresult)?;
    let smoothed = write_smoothed_file(&result.smoothed, out)?;
    Ok(forward.with_smoothed(smoothed))
}

/// The files of [`write_files`] written by [`write_forward_files`], to be
/// listed with `smoothed.csv` by [`ForwardFiles::with_smoothed`].
#[derive(Debug)]
pub struct ForwardFiles {
    /// `solution.csv`, then `navresult.txt` when written.
    navigation: Vec<PathBuf>,
    /// The navigation tables' warnings.
    navigation_warnings: Vec<String>,
    /// `selected.csv`, `trajectory.svg`, `instruments.csv`,
    /// `innovations.svg`, then `outage_drift.svg` when written.
    others: Vec<PathBuf>,
    /// The other tables' warnings.
    other_warnings: Vec<String>,
}

/// Every file of [`write_files`] but `smoothed.csv` — none of them depends
/// on the smoothed solution, so they can be written while the log is
/// smoothed ([`Process::run_forward`](super::Process::run_forward)).
pub fn write_forward_files(
    result: &ProcessResult,
    scores: Option<&Scores>,
    out: &Path,
    navresult: bool,
) -> Result<ForwardFiles, IoError> {
    begin_outputs(out)?;
    // Three threads: this one writes the navigation tables (`solution.csv`,
    // `navresult.txt`), a second one `selected.csv` and `instruments.csv`,
    // a third the charts (about as much work as the tables of either) —
    // the same error when one fails as written in turn (the first in
    // `aidnav process`'s order).
    let trajectory = out.join("trajectory.svg");
    let innovations = out.join("innovations.svg");
    let drift = scores.map(|_| out.join("outage_drift.svg"));
    let (navigation, (others, charts)) = std::thread::scope(|s| {
        let others = s.spawn(|| write_other_tables(result, out));
        let charts = s.spawn(|| -> Result<(), IoError> {
            trajectory_chart(result).write_svg(&trajectory)?;
            innovations_chart(result).write_svg(&innovations)?;
            if let (Some(scores), Some(path)) = (scores, &drift) {
                drift_chart(scores).write_svg(path)?;
            }
            Ok(())
        });
        let navigation = write_navigation_tables(result, out, navresult);
        // A panic on another thread is re-raised here, as it would have
        // been on this one.
        let others = others
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        let charts = charts
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (navigation, (others, charts))
    });
    let (navigation, navigation_warnings) = navigation?;
    let ([selected, instruments], other_warnings) = others?;
    charts?;
    // `aidnav process`'s order: trajectory.svg after selected.csv,
    // innovations.svg after instruments.csv, outage_drift.svg last.
    let mut others = vec![selected, trajectory, instruments, innovations];
    others.extend(drift);
    let mut other_warnings = other_warnings;
    for (source, header) in AID_UPDATE_FILES {
        if result.aid_sources.iter().any(|s| s.name == source) {
            let path = out.join(format!("{source}.csv"));
            let rows = aid_update_rows(&result.aid_updates, source);
            other_warnings.extend(aidnav_io::writers::write_rows(&path, &header, rows)?);
            others.push(path);
        }
    }
    Ok(ForwardFiles {
        navigation,
        navigation_warnings,
        others,
        other_warnings,
    })
}

impl ForwardFiles {
    /// Every file and warning, `smoothed.csv`'s ([`write_smoothed_file`])
    /// with them, in [`write_files`]'s order: `solution.csv`,
    /// `navresult.txt`, `smoothed.csv`, then the others.
    pub fn with_smoothed(
        self,
        smoothed: Option<(PathBuf, Vec<String>)>,
    ) -> (Vec<PathBuf>, Vec<String>) {
        let (mut files, mut warnings) = (self.navigation, self.navigation_warnings);
        if let Some((path, table_warnings)) = smoothed {
            files.push(path);
            warnings.extend(table_warnings);
        }
        files.extend(self.others);
        warnings.extend(self.other_warnings);
        (files, warnings)
    }
}

/// `smoothed.csv` of [`write_files`] in `out` (none for no smoothed
/// epochs): the file and its warnings.
pub fn write_smoothed_file(
    smoothed: &[Epoch],
    out: &Path,
) -> Result<Option<(PathBuf, Vec<String>)>, IoError> {
    if smoothed.is_empty() {
        return Ok(None);
    }
    let path = out.join("smoothed.csv");
    let warnings = write_smoothed(&path, smoothed)?;
    Ok(Some((path, warnings)))
}

/// The sources whose every update has a file of its own
/// (`<source>.csv`, [`aid_updates_table`]), with its header.
const AID_UPDATE_FILES: [(&str, [&str; 5]); 2] = [
    (
        <WheelSpeedConfig as SampledSensor>::NAME,
        [
            "time [s GPST since 1970]",
            "innovation [m/s]",
            "innovation_sigma [m/s]",
            "nis",
            "outcome (1 accepted, 2 limited, 3 rejected, 4 reset)",
        ],
    ),
    (
        <BaroConfig as SampledSensor>::NAME,
        [
            "time [s GPST since 1970]",
            "innovation [m]",
            "innovation_sigma [m]",
            "nis",
            "outcome (1 accepted, 2 limited, 3 rejected, 4 reset)",
        ],
    ),
];

/// `<source>.csv`'s columns (`wheel_speed.csv`, `barometer.csv`): one row
/// per update of the source — its time, the innovation (predicted minus
/// measured), its σ, the NIS and the outcome. None for a source without
/// such a file.
pub fn aid_updates_table(
    updates: &[AidRecord],
    source: &str,
) -> Option<(Vec<&'static str>, Vec<Vec<f64>>)> {
    let (_, header) = AID_UPDATE_FILES.iter().find(|(s, _)| *s == source)?;
    let rows = aid_update_rows(updates, source).map(Vec::from).collect();
    Some((header.to_vec(), rows))
}

/// Whether the updates of `source` have a file of their own (and so are
/// kept for it, [`aid_updates_table`]).
pub(crate) fn has_update_file(source: &str) -> bool {
    AID_UPDATE_FILES.iter().any(|(s, _)| *s == source)
}

/// The rows of `<source>.csv`.
fn aid_update_rows<'a>(
    updates: &'a [AidRecord],
    source: &'a str,
) -> impl Iterator<Item = [f64; 5]> + 'a {
    updates.iter().filter(move |u| u.source == source).map(|u| {
        [
            u.time_s,
            u.innovation[0],
            u.innovation_sigma[0],
            u.nis,
            outcome_code(Some(u.outcome)),
        ]
    })
}

/// The outcome column of `solution.csv` and the aid-update files.
fn outcome_code(outcome: Option<Outcome>) -> f64 {
    match outcome {
        Some(Outcome::Accepted) => 1.0,
        Some(Outcome::Limited) | Some(Outcome::Reweighted) => 2.0,
        Some(Outcome::Rejected) => 3.0,
        Some(Outcome::Reset) => 4.0,
        _ => 0.0,
    }
}

/// The navigation tables of [`write_forward_files`], in its order:
/// `solution.csv`, `navresult.txt` (with `navresult`); returns the files
/// and the tables' warnings.
fn write_navigation_tables(
    result: &ProcessResult,
    out: &Path,
    navresult: bool,
) -> Result<(Vec<PathBuf>, Vec<String>), IoError> {
    let mut files = Vec::new();
    let mut warnings = Vec::new();
    let solution = out.join("solution.csv");
    warnings.extend(write_solution(&solution, &result.epochs, &result.between)?);
    files.push(solution);
    if navresult {
        let path = out.join("navresult.txt");
        write_navresult(&path, &result.epochs, &result.between)?;
        files.push(path);
    }
    Ok((files, warnings))
}

/// `selected.csv` and `instruments.csv` of [`write_files`]; returns them
/// and their warnings.
fn write_other_tables(
    result: &ProcessResult,
    out: &Path,
) -> Result<([PathBuf; 2], Vec<String>), IoError> {
    let mut warnings = Vec::new();
    let selected = out.join("selected.csv");
    warnings.extend(write_selected(&selected, &result.selected)?);
    let instruments = out.join("instruments.csv");
    warnings.extend(write_instruments(&instruments, &result.epochs)?);
    Ok(([selected, instruments], warnings))
}

/// Write the files of a tuning into `out`: `allan.svg` and `allan.csv`
/// (when the log had a standstill long enough) and `tuned_noise.toml`
/// (`config_name` names the configuration in its comment). Returns the
/// files and the warnings of the tables.
pub fn write_tune_files(
    result: &TuneResult,
    out: &Path,
    config_name: &str,
) -> Result<(Vec<PathBuf>, Vec<String>), IoError> {
    let mut files = Vec::new();
    let mut warnings = Vec::new();
    if let Some(allan) = &result.allan {
        let path = out.join("allan.svg");
        allan_chart(allan).write_svg_log_log(&path)?;
        files.push(path);
        let path = out.join("allan.csv");
        warnings.extend(write_allan(&path, allan)?);
        files.push(path);
    }
    let path = out.join("tuned_noise.toml");
    aidnav_io::writers::write_atomic(&path, tuned_noise_toml(result, config_name).as_bytes())?;
    files.push(path);
    Ok((files, warnings))
}

/// σ(τ) of an axis in datasheet units: gyro \[deg/h\], accelerometer \[mg\].
fn datasheet_deviation(axis: &AxisAllan, sigma_si: f64) -> f64 {
    if axis.axis.starts_with("gyro") {
        sigma_si.to_degrees() * 3600.0
    } else {
        sigma_si / 9.806_65 * 1e3
    }
}

/// Write `allan.csv`: per cluster time the six axes' Allan deviation in
/// datasheet units.
pub fn write_allan(path: &Path, allan: &ImuAllan) -> Result<Vec<String>, IoError> {
    let tau = allan.axes.first().map_or(&[][..], |a| &a.curve.tau_s[..]);
    let rows = tau.iter().enumerate().map(|(i, t)| {
        let mut row = vec![*t];
        row.extend(allan.axes.iter().map(|a| {
            a.curve
                .deviation
                .get(i)
                .map_or(f64::NAN, |&d| datasheet_deviation(a, d))
        }));
        row
    });
    write_table_noting_infinities(
        path,
        &[
            "tau [s]",
            "gyro_x [deg/h]",
            "gyro_y [deg/h]",
            "gyro_z [deg/h]",
            "accel_x [mg]",
            "accel_y [mg]",
            "accel_z [mg]",
        ],
        rows,
    )
}

/// The six Allan deviation curves, log–log; the legend carries what each
/// curve reads (white noise, bias instability; ≤ when a bound).
pub fn allan_chart(allan: &ImuAllan) -> LineChart {
    let series = allan
        .axes
        .iter()
        .enumerate()
        .map(|(k, a)| {
            let gyro = k < 3;
            let white = a.white_datasheet.map_or("—".to_string(), |v| {
                format!("{v:.3} {}", if gyro { "deg/√h" } else { "m/s/√h" })
            });
            let bias = match (a.bias_datasheet, a.bias_instability) {
                (Some(v), Some(b)) => format!(
                    "{}{v:.3} {}",
                    if b.upper_bound { "≤ " } else { "" },
                    if gyro { "deg/h" } else { "mg" }
                ),
                _ => "—".to_string(),
            };
            Series {
                label: format!("{} (white {white}, bias instability {bias})", a.axis),
                points: a
                    .curve
                    .tau_s
                    .iter()
                    .zip(&a.curve.deviation)
                    .map(|(&t, &d)| (t, datasheet_deviation(a, d)))
                    .collect(),
                style: if gyro {
                    LineStyle::Solid
                } else {
                    LineStyle::Dashed
                },
                color: k % 3 + if gyro { 0 } else { 3 },
            }
        })
        .collect();
    LineChart {
        title: format!(
            "Allan deviation at rest ({:.1} s, {:.1} s into the log)",
            allan.stretch.duration_s, allan.stretch.after_first_sample_s
        ),
        x_label: "cluster time τ [s]".into(),
        y_label: "σ(τ): gyro [deg/h], accelerometer [mg]".into(),
        series,
        log_y: true,
    }
}

/// Write `summary.json` with the configuration and `report` as its result.
pub fn write_summary(
    out: &Path,
    cfg: &ProcessConfig,
    report: &impl Serialize,
) -> Result<PathBuf, IoError> {
    summary(cfg, report).write(out)
}

/// `summary.json` as a value: the configuration as used (the platform's
/// values filled in) and `report` under `result`.
pub fn summary(cfg: &ProcessConfig, report: &impl Serialize) -> Summary {
    let mut summary = Summary::new(
        "process",
        crate::VERSION,
        Some(cfg.score.seed),
        &cfg.resolved(),
    );
    summary.insert("result", report);
    summary
}

/// Write `solution.csv`: per GNSS epoch the antenna position, NED velocity,
/// attitude, σ, NIS, δ(n), K_eff, innovation and update outcome (4: the
/// recovery reset the filter to the fix); merged in
/// time order with the rows `between` the epochs (NaN where a column needs
/// a fix, outcome 0).
pub fn write_solution(
    path: &Path,
    epochs: &[Epoch],
    between: &[SolutionRow],
) -> Result<Vec<String>, IoError> {
    // The rows streamed as arrays: no table in memory, no allocation per row.
    aidnav_io::writers::write_rows(path, &solution_header(), solution_rows(epochs, between))
}

/// Columns of `solution.csv`.
const SOLUTION_COLUMNS: usize = POSITION_COLUMNS.len() + 22;

/// The header of `solution.csv`.
fn solution_header() -> Vec<&'static str> {
    POSITION_COLUMNS
        .iter()
        .copied()
        .chain([
            "vn [m/s]",
            "ve [m/s]",
            "vd [m/s]",
            "roll [deg]",
            "pitch [deg]",
            "yaw [deg]",
            "sigma_n [m]",
            "sigma_e [m]",
            "sigma_d [m]",
            "sigma_vn [m/s]",
            "sigma_ve [m/s]",
            "sigma_vd [m/s]",
            "sigma_tilt_n [deg]",
            "sigma_tilt_e [deg]",
            "sigma_heading [deg]",
            "nis",
            "delta (Cramér–Rao convergence of the instruments)",
            "k_eff (sigma_gnss / sigma_filter, 3-D)",
            "innovation_n [m]",
            "innovation_e [m]",
            "innovation_d [m]",
            "outcome (1 accepted, 2 limited, 3 rejected, 4 reset to the fix, 0 no fix)",
        ])
        .collect()
}

/// The navigation columns of a `solution.csv` row (all but NIS, δ, K_eff,
/// innovation and outcome).
fn navigation_values(row: &SolutionRow) -> [f64; SOLUTION_COLUMNS - 7] {
    let (r, p, y) = row.attitude.euler_angles();
    let [t, a0, a1, a2, i0, i1, i2] = time_and_positions(row.time_s, &row.antenna, &row.imu);
    [
        t,
        a0,
        a1,
        a2,
        i0,
        i1,
        i2,
        row.velocity.x(),
        row.velocity.y(),
        row.velocity.z(),
        r.to_degrees(),
        p.to_degrees(),
        y.to_degrees(),
        row.sigma[0],
        row.sigma[1],
        row.sigma[2],
        row.sigma_velocity[0],
        row.sigma_velocity[1],
        row.sigma_velocity[2],
        row.sigma_attitude[0].to_degrees(),
        row.sigma_attitude[1].to_degrees(),
        row.sigma_attitude[2].to_degrees(),
    ]
}

/// The rows of `solution.csv` in time order ([`write_solution`]).
fn solution_rows<'a>(
    epochs: &'a [Epoch],
    between: &'a [SolutionRow],
) -> impl Iterator<Item = [f64; SOLUTION_COLUMNS]> + 'a {
    let row = |navigation: [f64; SOLUTION_COLUMNS - 7], rest: [f64; 7]| {
        let mut row = [0.0; SOLUTION_COLUMNS];
        row[..SOLUTION_COLUMNS - 7].copy_from_slice(&navigation);
        row[SOLUTION_COLUMNS - 7..].copy_from_slice(&rest);
        row
    };
    let epoch_rows = epochs.iter().map(move |e| {
        let outcome = outcome_code(e.outcome);
        row(
            navigation_values(&e.row()),
            [
                e.nis,
                e.convergence,
                e.k_eff,
                e.innovation[0],
                e.innovation[1],
                e.innovation[2],
                outcome,
            ],
        )
    });
    // No fix: NIS, δ, K_eff, innovation are NaN, outcome 0.
    let other_rows = between.iter().map(move |b| {
        let mut rest = [f64::NAN; 7];
        rest[6] = 0.0;
        row(navigation_values(b), rest)
    });
    merge_in_time(epoch_rows, other_rows, |row| row[0])
}

/// The header and rows of `solution.csv` ([`write_solution`]).
pub fn solution_table(
    epochs: &[Epoch],
    between: &[SolutionRow],
) -> (Vec<&'static str>, Vec<Vec<f64>>) {
    (
        solution_header(),
        solution_rows(epochs, between).map(Vec::from).collect(),
    )
}

/// Write `navresult.txt` in KF-GINS's layout: the GNSS epochs and the rows
/// between them, in time order.
pub fn write_navresult(
    path: &Path,
    epochs: &[Epoch],
    between: &[SolutionRow],
) -> Result<(), IoError> {
    let mut text = String::new();
    let rows = merge_in_time(
        epochs.iter().map(Epoch::row),
        between.iter().copied(),
        |r| r.time_s,
    );
    for e in rows {
        let gps = e.time_s - 315_964_800.0;
        let week = (gps / 604_800.0).floor();
        let (r, p, y) = e.attitude.euler_angles();
        let _ = writeln!(
            text,
            "{:.0} {:.3} {:.9} {:.9} {:.4} {:.4} {:.4} {:.4} {:.5} {:.5} {:.5}",
            week,
            gps - week * 604_800.0,
            e.antenna.latitude_rad.to_degrees(),
            e.antenna.longitude_rad.to_degrees(),
            e.antenna.height_m,
            e.velocity.x(),
            e.velocity.y(),
            e.velocity.z(),
            r.to_degrees(),
            p.to_degrees(),
            y.to_degrees()
        );
    }
    aidnav_io::writers::write_atomic(path, text.as_bytes())
}

/// Write `selected.csv`: per GNSS epoch the output spec 20's efficiency
/// criterion selects for position and for velocity, with its source (1
/// integrated, 2 GNSS) and K_eff (see [`super::selection`]).
pub fn write_selected(path: &Path, selected: &[SelectedEpoch]) -> Result<Vec<String>, IoError> {
    let code = |s: Source| match s {
        Source::Integrated => 1.0,
        Source::Gnss => 2.0,
    };
    let rows = selected.iter().map(|s| {
        [
            s.time_s,
            code(s.position_source),
            s.position.latitude_rad.to_degrees(),
            s.position.longitude_rad.to_degrees(),
            s.position.height_m,
            s.k_eff_position,
            code(s.velocity_source),
            s.velocity.x,
            s.velocity.y,
            s.velocity.z,
            s.k_eff_velocity,
        ]
    });
    aidnav_io::writers::write_rows(
        path,
        &[
            POSITION_COLUMNS[0],
            "position_source (1 integrated, 2 gnss)",
            "antenna latitude [deg]",
            "antenna longitude [deg]",
            "antenna height [m]",
            "k_eff_position",
            "velocity_source (1 integrated, 2 gnss)",
            "vn [m/s]",
            "ve [m/s]",
            "vd [m/s]",
            "k_eff_velocity",
        ],
        rows,
    )
}

/// Write `smoothed.csv`: time and the smoothed antenna and IMU positions.
pub fn write_smoothed(path: &Path, smoothed: &[Epoch]) -> Result<Vec<String>, IoError> {
    aidnav_io::writers::write_rows(path, &POSITION_COLUMNS, smoothed_rows(smoothed))
}

/// The rows of `smoothed.csv`: time and the smoothed antenna and IMU
/// positions of each epoch.
fn smoothed_rows(smoothed: &[Epoch]) -> impl Iterator<Item = [f64; 7]> + '_ {
    smoothed
        .iter()
        .map(|e| time_and_positions(e.time_s(), &e.antenna, &e.imu_position))
}

/// The header and rows of `smoothed.csv` ([`write_smoothed`]).
pub fn smoothed_table(smoothed: &[Epoch]) -> (Vec<&'static str>, Vec<Vec<f64>>) {
    (
        POSITION_COLUMNS.to_vec(),
        smoothed_rows(smoothed).map(Vec::from).collect(),
    )
}

/// The first columns of `solution.csv` and `smoothed.csv`.
const POSITION_COLUMNS: [&str; 7] = [
    "time [s GPST since 1970]",
    "antenna latitude [deg]",
    "antenna longitude [deg]",
    "antenna height [m]",
    "imu latitude [deg]",
    "imu longitude [deg]",
    "imu height [m]",
];

/// The values of [`POSITION_COLUMNS`].
fn time_and_positions(time_s: f64, antenna: &Geodetic, imu: &Geodetic) -> [f64; 7] {
    [
        time_s,
        antenna.latitude_rad.to_degrees(),
        antenna.longitude_rad.to_degrees(),
        antenna.height_m,
        imu.latitude_rad.to_degrees(),
        imu.longitude_rad.to_degrees(),
        imu.height_m,
    ]
}

/// Write `instruments.csv`: the instrument corrections after every epoch.
pub fn write_instruments(path: &Path, epochs: &[Epoch]) -> Result<Vec<String>, IoError> {
    aidnav_io::writers::write_rows(
        path,
        &INSTRUMENT_COLUMNS,
        epochs.iter().map(instrument_values),
    )
}

/// The header of `instruments.csv`.
const INSTRUMENT_COLUMNS: [&str; 13] = [
    "time [s GPST since 1970]",
    "gyro_bias_x [deg/h]",
    "gyro_bias_y [deg/h]",
    "gyro_bias_z [deg/h]",
    "accel_bias_x [mg]",
    "accel_bias_y [mg]",
    "accel_bias_z [mg]",
    "gyro_scale_x [ppm]",
    "gyro_scale_y [ppm]",
    "gyro_scale_z [ppm]",
    "accel_scale_x [ppm]",
    "accel_scale_y [ppm]",
    "accel_scale_z [ppm]",
];

/// An epoch's row of `instruments.csv`: time, gyro bias \[deg/h\],
/// accelerometer bias \[mg\], gyro and accelerometer scale factors \[ppm\].
fn instrument_values(e: &Epoch) -> [f64; 13] {
    let i = &e.instruments;
    let mut row = [0.0; 13];
    row[0] = e.time_s();
    for k in 0..3 {
        row[1 + k] = i.gyro_bias[k].to_degrees() * 3600.0;
        row[4 + k] = i.accel_bias[k] / 9.806_65 * 1e3;
        row[7 + k] = i.gyro_scale[k] * 1e6;
        row[10 + k] = i.accel_scale[k] * 1e6;
    }
    row
}

/// The header and rows of `instruments.csv` ([`write_instruments`]).
pub fn instruments_table(epochs: &[Epoch]) -> (Vec<&'static str>, Vec<Vec<f64>>) {
    (
        INSTRUMENT_COLUMNS.to_vec(),
        epochs
            .iter()
            .map(|e| instrument_values(e).to_vec())
            .collect(),
    )
}

/// GNSS fixes and the filter's antenna position, east/north of the first fix.
pub fn trajectory_chart(result: &ProcessResult) -> LineChart {
    let origin = result.fix_track[0];
    let ne = |g: &Geodetic| {
        let d = origin.ned_to(g);
        (d.y(), d.x())
    };
    LineChart {
        title: "Trajectory: GNSS fixes and the filter's antenna position".into(),
        x_label: "east [m]".into(),
        y_label: "north [m]".into(),
        series: vec![
            Series {
                label: "GNSS (RTK)".into(),
                points: result.fix_track.iter().map(ne).collect(),
                style: LineStyle::Points,
                color: TRUTH_COLOR,
            },
            Series {
                label: "aidnav".into(),
                points: result.epochs.iter().map(|e| ne(&e.antenna)).collect(),
                style: LineStyle::Solid,
                color: 0,
            },
        ],
        log_y: false,
    }
}

/// The position innovations (N, E, D) against time since the first fix.
pub fn innovations_chart(result: &ProcessResult) -> LineChart {
    let t0 = result.first_fix_time_s;
    LineChart {
        title: "GNSS position innovations (antenna estimate − fix)".into(),
        x_label: "time since the first fix [s]".into(),
        y_label: "innovation [m]".into(),
        series: ["north", "east", "down"]
            .iter()
            .enumerate()
            .map(|(k, name)| Series {
                label: (*name).into(),
                points: result
                    .epochs
                    .iter()
                    .filter(|e| e.innovation[k].is_finite())
                    .map(|e| (e.time_s() - t0, e.innovation[k]))
                    .collect(),
                style: LineStyle::Solid,
                color: k,
            })
            .collect(),
        log_y: false,
    }
}

/// The coasting filter's 3-D error and 3σ through each outage length's windows.
pub fn drift_chart(scores: &Scores) -> LineChart {
    let mut series = Vec::new();
    for (k, d) in scores.drift.iter().enumerate() {
        series.push(Series {
            label: format!("{:.0} s outages", d.outage_s),
            points: d.error_m.clone(),
            style: LineStyle::Solid,
            color: k,
        });
        series.push(Series {
            label: format!("{:.0} s outages: 3σ", d.outage_s),
            points: d.three_sigma_m.clone(),
            style: LineStyle::Dashed,
            color: k,
        });
    }
    LineChart {
        title: "3-D antenna error with simulated GNSS outages (filter coasting)".into(),
        x_label: "time since the first IMU sample [s]".into(),
        y_label: "3-D error [m]".into(),
        series,
        log_y: true,
    }
}

/// Two sequences, each in time order, merged in time order (the first's
/// item first on equal times) as they are consumed.
fn merge_in_time<T>(
    a: impl Iterator<Item = T>,
    b: impl Iterator<Item = T>,
    time: impl Fn(&T) -> f64,
) -> impl Iterator<Item = T> {
    let (mut a, mut b) = (a.peekable(), b.peekable());
    std::iter::from_fn(move || match (a.peek(), b.peek()) {
        (Some(x), Some(y)) if time(x) <= time(y) => a.next(),
        (Some(_), None) => a.next(),
        _ => b.next(),
    })
}
