//! Self-tuning of the noise terms (`aidnav tune`, `[imu.noise] auto`).
//!
//! Two steps, each a library call that returns values and touches no file:
//!
//! 1. **Allan deviation at rest.** The longest standstill of the log
//!    ([`aidnav_ins::standstill::still_stretches`] with the configuration's
//!    window and platform thresholds, and the GNSS speed at most
//!    `standstill.max_speed_mps`), less one window at each end (the
//!    stopping and starting motion). When it lasts at least
//!    `tune.min_static_s`, the overlapping Allan deviation of each of the
//!    six axes ([`aidnav_estimation::allan`]) gives the white noise (angle
//!    and velocity random walk, on the −½ slope at τ ≥ `imu.smoothing_s`)
//!    and the bias instability
//!    (the flat minimum / 0.664; an upper bound when the record ends before
//!    the curve flattens). It is computed on the **unsmoothed** samples:
//!    `imu.smoothing_s`'s moving average of L samples divides the white
//!    noise's variance at the shortest cluster times by up to L and would
//!    make the curve's left end a smoothing artefact; the white-noise
//!    density itself (the spectrum at low frequency) is what the smoothed
//!    samples the filter sees still carry, and it is read at τ ≥ the
//!    smoothing window (shorter τ are the band the moving average removes,
//!    where a vibration line can dominate the raw samples). The filter
//!    takes one number per sensor: the RMS over the three axes.
//! 2. **Maximum likelihood.** From the Allan values (the configured ones
//!    where the Allan deviation says nothing) or the configured values,
//!    whichever have the higher likelihood (a noise measured at rest can be
//!    far below what a moving platform needs), log-scale factors on
//!    ARW, VRW, the gyro and accelerometer bias instabilities, the GNSS σ
//!    scale and — with the non-holonomic constraint — its σ
//!    ([`PARAMETERS`]) maximise a log-likelihood over one filter pass per
//!    evaluation (smoothed inputs, as `process` filters them; the accept
//!    policy, no adaptive noise, no smoother, no scoring). Nelder–Mead in
//!    the box [1/`max_factor`, `max_factor`] around the start
//!    ([`aidnav_estimation::optimise`]), at most `tune.max_evaluations`
//!    passes; the initial simplex and shrinks run in parallel (rayon), and
//!    the result does not depend on the thread count.
//!
//! The likelihood ([`log_likelihood`], `tune.objective`):
//!
//! - `coasting` (default): the pass withholds the windows of
//!   [`tuning_windows`]; the likelihood is that of every fix as the filter
//!   predicted it — the updates' innovations
//!   `−½ (m ln 2π + ln det S + νᵀ S⁻¹ ν)` between the windows, and inside
//!   them each withheld fix's position against the coasting filter's
//!   antenna position with covariance `P_antenna + R_fix`. A filter whose
//!   covariance grows too slowly over an outage (or too fast) loses
//!   likelihood there, so the fit is the noise whose covariance is honest
//!   over the outages the log is scored on as well as at the GNSS rate.
//! - `innovations`: every fix is an update; the one-step predictions at the
//!   GNSS rate alone. On the recorded drive and walk the noise it fits
//!   tracks better and coasts worse (see the README).
//!
//! The tuning windows and the scored windows lie in the same log: scores of
//! a configuration tuned on its own log are in-sample.

use std::time::Instant;

use aidnav_estimation::allan::{
    AllanCurve, AllanOptions, BiasInstability, SlopeFit, allan_deviation,
};
use aidnav_estimation::optimise::{NelderMeadOptions, nelder_mead};
use aidnav_ins::standstill::{StandstillThresholds, still_stretches};
use aidnav_io::rtklib::{GnssFix, ImuSample};
use aidnav_models::ned_ins::{ImuNoise, PerAxis};
use nalgebra::{Cholesky, Matrix3, Vector3};
use rayon::prelude::*;
use serde::Serialize;

use super::config::{AdaptiveNoise, PolicyName, ProcessConfig, TuneObjective};
use super::run::{RunPlan, fix_position_sigma, run_filter};
use super::{Inputs, ProcessError};

/// Standard gravity, the unit of `accel_bias_mg` (as
/// [`ImuNoise::instrument_sigmas`] converts it) \[m/s²\].
const STANDARD_GRAVITY_MPS2: f64 = 9.806_65;

/// The fitted parameters, in the order of the search's coordinates.
/// The last, `constraints.non_holonomic_sigma_mps`, only when the
/// configuration applies the non-holonomic constraint (it is part of the
/// model the likelihood judges: a car's lateral and vertical velocity are
/// not exactly zero).
pub const PARAMETERS: [&str; 6] = [
    "arw_deg_per_sqrt_h",
    "vrw_mps_per_sqrt_h",
    "gyro_bias_deg_per_h",
    "accel_bias_mg",
    "gnss_sigma_scale",
    "non_holonomic_sigma_mps",
];

/// How many of [`PARAMETERS`] a tuning of `cfg` searches: the last only
/// with the non-holonomic constraint.
pub fn searched_parameters(cfg: &ProcessConfig) -> usize {
    if cfg.non_holonomic() {
        PARAMETERS.len()
    } else {
        PARAMETERS.len() - 1
    }
}

/// The six IMU axes of the Allan deviation, body frame.
pub const AXES: [&str; 6] = [
    "gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y", "accel_z",
];

// ---------------------------------------------------------------------
// The noise terms tuning reads and writes. These three functions are the
// only code of this module that names fields of `ImuNoise`: a model with
// per-axis terms changes them alone (a per-axis model would set each axis
// from its own Allan value and scale all three by one factor).
// ---------------------------------------------------------------------

/// The four noise scalars tuning fits, in datasheet units: ARW \[deg/√h\],
/// VRW \[m/s/√h\], gyro bias instability \[deg/h\], accelerometer bias
/// instability \[mg\] — each the RMS over the sensor axes (the terms are
/// per axis; tuning keeps the ratios between the axes).
pub fn noise_scalars(n: &ImuNoise) -> [f64; 4] {
    [
        rms(&n.arw_deg_per_sqrt_h),
        rms(&n.vrw_mps_per_sqrt_h),
        rms(&n.gyro_bias_deg_per_h),
        rms(&n.accel_bias_mg),
    ]
}

/// RMS over the axes.
fn rms(p: &PerAxis) -> f64 {
    (p.0.iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt()
}

/// `p` scaled so its RMS over the axes is `v` (every axis `v` when it is 0).
fn with_rms(p: &PerAxis, v: f64) -> PerAxis {
    let r = rms(p);
    if r > 0.0 {
        p.scaled(v / r)
    } else {
        PerAxis::all(v)
    }
}

/// `n` with the scalars that are `Some` replaced (order of [`noise_scalars`];
/// the axes keep their ratios).
fn set_noise_scalars(n: &ImuNoise, values: [Option<f64>; 4]) -> ImuNoise {
    let mut out = *n;
    let [arw, vrw, bg, ba] = values;
    if let Some(v) = arw {
        out.arw_deg_per_sqrt_h = with_rms(&n.arw_deg_per_sqrt_h, v);
    }
    if let Some(v) = vrw {
        out.vrw_mps_per_sqrt_h = with_rms(&n.vrw_mps_per_sqrt_h, v);
    }
    if let Some(v) = bg {
        out.gyro_bias_deg_per_h = with_rms(&n.gyro_bias_deg_per_h, v);
    }
    if let Some(v) = ba {
        out.accel_bias_mg = with_rms(&n.accel_bias_mg, v);
    }
    out
}

/// `n` with each scalar × its factor (order of [`noise_scalars`]).
fn scale_noise(n: &ImuNoise, k: [f64; 4]) -> ImuNoise {
    let v = noise_scalars(n);
    set_noise_scalars(n, std::array::from_fn(|i| Some(v[i] * k[i])))
}

/// A span of the log at rest.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StaticStretch {
    /// First sample (GPST s).
    pub start_s: f64,
    /// Last sample (GPST s).
    pub end_s: f64,
    /// Seconds after the first IMU sample of the log.
    pub after_first_sample_s: f64,
    /// Its length \[s\].
    pub duration_s: f64,
    /// IMU samples in it.
    pub samples: usize,
    /// Sample index range [first, last + 1) in the log's IMU samples.
    #[serde(skip)]
    pub range: std::ops::Range<usize>,
}

/// The longest standstill of `inputs` (IMU thresholds of the platform or
/// the `[standstill]` keys over windows of `standstill.window_s`, GNSS
/// speed at most `standstill.max_speed_mps` within a second of each
/// window), less one window at each end. None when nothing is still.
pub fn longest_standstill(cfg: &ProcessConfig, inputs: &Inputs) -> Option<StaticStretch> {
    let (accel, gyro) = cfg.standstill_thresholds();
    let thresholds = StandstillThresholds {
        accel_std_mps2: accel,
        gyro_std_rad_s: gyro,
    };
    let window_s = cfg.standstill.window_s;
    let max_speed = cfg.standstill.max_speed_mps;
    let imu = &inputs.imu;
    let longest = still_stretches(imu, window_s, &thresholds, |t0, t1| {
        gnss_slow(&inputs.gnss, t0, t1, max_speed)
    })
    .into_iter()
    .next()?;
    // One window off each end: the vehicle stopping and moving off.
    let (t_first, t_last) = (imu[longest.start].time_s, imu[longest.end - 1].time_s);
    let start =
        longest.start + imu[longest.clone()].partition_point(|s| s.time_s < t_first + window_s);
    let end =
        longest.start + imu[longest.clone()].partition_point(|s| s.time_s <= t_last - window_s);
    let range = if end > start + 1 { start..end } else { longest };
    let (a, b) = (imu[range.start].time_s, imu[range.end - 1].time_s);
    Some(StaticStretch {
        start_s: a,
        end_s: b,
        after_first_sample_s: a - imu[0].time_s,
        duration_s: b - a,
        samples: range.len(),
        range,
    })
}

/// GNSS evidence that the vehicle is slow over [t0, t1]: every fix within
/// a second of it with a velocity is at most `max` fast; the fixes without
/// one moved at most `max` on average between the first and the last, less
/// 3 σ of each. No fix near: no evidence against.
fn gnss_slow(gnss: &[GnssFix], t0: f64, t1: f64, max: f64) -> bool {
    let a = gnss.partition_point(|g| g.time_s < t0 - 1.0);
    let b = gnss.partition_point(|g| g.time_s <= t1 + 1.0);
    let near = &gnss[a..b.max(a)];
    if near.iter().any(|g| {
        g.velocity_ned.is_some_and(|v| {
            !aidnav_ins::standstill::gnss_says_still(&v, g.velocity_sigma_neu.as_ref(), max)
        })
    }) {
        return false;
    }
    let mut without = near.iter().filter(|g| g.velocity_ned.is_none());
    match (without.next(), without.next_back()) {
        (Some(f), Some(l)) if l.time_s > f.time_s => {
            let d = f.position.ned_to(&l.position).norm();
            let noise = 3.0 * (f.position_sigma_neu.norm() + l.position_sigma_neu.norm());
            (d - noise).max(0.0) / (l.time_s - f.time_s) <= max
        }
        _ => true,
    }
}

/// The Allan deviation of one axis and what it reads.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AxisAllan {
    /// `gyro_x` … `accel_z` ([`AXES`]).
    pub axis: &'static str,
    /// The curve, SI (rad/s, m/s²).
    pub curve: AllanCurve,
    /// White noise on the −½ slope, SI (rad/√s, m/s/√s).
    pub white: Option<SlopeFit>,
    /// Bias instability at the minimum, SI (rad/s, m/s²).
    pub bias_instability: Option<BiasInstability>,
    /// Rate random walk on the +½ slope, SI (rad/s/√s, m/s²/√s).
    pub random_walk: Option<SlopeFit>,
    /// White noise in datasheet units: ARW \[deg/√h\] or VRW \[m/s/√h\].
    pub white_datasheet: Option<f64>,
    /// Bias instability in datasheet units: \[deg/h\] or \[mg\].
    pub bias_datasheet: Option<f64>,
    /// Rate random walk in datasheet units: \[deg/h/√h\] or \[mg/√h\].
    pub random_walk_datasheet: Option<f64>,
}

/// The six axes' Allan deviations over a standstill, and the noise terms
/// for the filter (RMS over the three axes of each sensor).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImuAllan {
    /// The standstill.
    pub stretch: StaticStretch,
    /// Mean sample interval over it \[s\] (the samples are taken as
    /// uniformly spaced).
    pub sample_interval_s: f64,
    /// Per axis, in the order of [`AXES`].
    pub axes: Vec<AxisAllan>,
    /// ARW \[deg/√h\]: RMS over the gyro axes that show the −½ slope.
    pub arw_deg_per_sqrt_h: Option<f64>,
    /// VRW \[m/s/√h\]: RMS over the accelerometer axes with the −½ slope.
    pub vrw_mps_per_sqrt_h: Option<f64>,
    /// Gyro bias instability \[deg/h\]: RMS over the axes.
    pub gyro_bias_deg_per_h: Option<f64>,
    /// Some gyro axis had not flattened: the value is an upper bound.
    pub gyro_bias_upper_bound: bool,
    /// Accelerometer bias instability \[mg\]: RMS over the axes.
    pub accel_bias_mg: Option<f64>,
    /// Some accelerometer axis had not flattened: an upper bound.
    pub accel_bias_upper_bound: bool,
}

/// The Allan deviation of the six axes of `samples` (a standstill); the
/// white noise is read at τ ≥ `smoothing_s` (the band the filter's moving
/// average leaves; at shorter τ a vibration line may dominate the
/// unsmoothed samples).
pub fn imu_allan(
    samples: &[ImuSample],
    stretch: StaticStretch,
    smoothing_s: f64,
) -> Result<ImuAllan, ProcessError> {
    let n = samples.len();
    if n < 2 {
        return Err(ProcessError::Data(format!(
            "{n} IMU samples at rest: too few for an Allan deviation"
        )));
    }
    let dt = (samples[n - 1].time_s - samples[0].time_s) / (n - 1) as f64;
    let options = AllanOptions::default();
    let mut axes = Vec::with_capacity(6);
    for (k, axis) in AXES.iter().enumerate() {
        let gyro = k < 3;
        let values: Vec<f64> = samples
            .iter()
            .map(|s| {
                if gyro {
                    s.angular_rate[k]
                } else {
                    s.specific_force[k - 3]
                }
            })
            .collect();
        let curve = allan_deviation(&values, dt, &options)
            .map_err(|e| ProcessError::Data(format!("Allan deviation of {axis}: {e}")))?;
        let (white, bias, walk) = (
            curve.white_noise_above(smoothing_s),
            curve.bias_instability(),
            curve.random_walk(),
        );
        // White noise: rad/√s → deg/√h and m/s/√s → m/s/√h (× √3600 = 60).
        // Rates: rad/s → deg/h and m/s² → mg; a random walk's "per √s" →
        // "per √h" is another × 60.
        let white_datasheet = white.map(|f| {
            if gyro {
                f.value.to_degrees() * 60.0
            } else {
                f.value * 60.0
            }
        });
        let to_rate = |v: f64| {
            if gyro {
                v.to_degrees() * 3600.0
            } else {
                v / STANDARD_GRAVITY_MPS2 * 1e3
            }
        };
        axes.push(AxisAllan {
            axis,
            white_datasheet,
            bias_datasheet: bias.map(|b| to_rate(b.value)),
            random_walk_datasheet: walk.map(|f| to_rate(f.value) * 60.0),
            curve,
            white,
            bias_instability: bias,
            random_walk: walk,
        });
    }
    let rms = |range: std::ops::Range<usize>, get: &dyn Fn(&AxisAllan) -> Option<f64>| {
        let v: Vec<f64> = axes[range].iter().filter_map(get).collect();
        (!v.is_empty()).then(|| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt())
    };
    let bound = |range: std::ops::Range<usize>| {
        axes[range]
            .iter()
            .any(|a| a.bias_instability.is_some_and(|b| b.upper_bound))
    };
    Ok(ImuAllan {
        arw_deg_per_sqrt_h: rms(0..3, &|a| a.white_datasheet),
        vrw_mps_per_sqrt_h: rms(3..6, &|a| a.white_datasheet),
        gyro_bias_deg_per_h: rms(0..3, &|a| a.bias_datasheet),
        gyro_bias_upper_bound: bound(0..3),
        accel_bias_mg: rms(3..6, &|a| a.bias_datasheet),
        accel_bias_upper_bound: bound(3..6),
        stretch,
        sample_interval_s: dt,
        axes,
    })
}

/// The noise terms, the GNSS σ scale and the non-holonomic σ of a filter.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct NoiseValues {
    /// The `[imu.noise]` terms.
    pub noise: ImuNoise,
    /// `gnss.sigma_scale`.
    pub gnss_sigma_scale: f64,
    /// `constraints.non_holonomic_sigma_mps`.
    pub non_holonomic_sigma_mps: f64,
}

impl NoiseValues {
    /// The values of `cfg`.
    pub fn of(cfg: &ProcessConfig) -> Self {
        Self {
            noise: cfg.imu.noise.values,
            gnss_sigma_scale: cfg.gnss.sigma_scale,
            non_holonomic_sigma_mps: cfg.constraints.non_holonomic_sigma_mps,
        }
    }

    /// The six values in the order of [`PARAMETERS`].
    pub fn parameters(&self) -> [f64; 6] {
        let [a, b, c, d] = noise_scalars(&self.noise);
        [
            a,
            b,
            c,
            d,
            self.gnss_sigma_scale,
            self.non_holonomic_sigma_mps,
        ]
    }

    /// These values × `factors` (order of [`PARAMETERS`]).
    fn scaled(&self, factors: &[f64]) -> Self {
        let k = |i: usize| factors.get(i).copied().unwrap_or(1.0);
        Self {
            noise: scale_noise(&self.noise, [k(0), k(1), k(2), k(3)]),
            gnss_sigma_scale: self.gnss_sigma_scale * k(4),
            non_holonomic_sigma_mps: self.non_holonomic_sigma_mps * k(5),
        }
    }

    /// `cfg` with these values.
    pub fn apply_to(&self, cfg: &mut ProcessConfig) {
        cfg.imu.noise.values = self.noise;
        cfg.gnss.sigma_scale = self.gnss_sigma_scale;
        cfg.constraints.non_holonomic_sigma_mps = self.non_holonomic_sigma_mps;
    }
}

/// The log-likelihood of a filter pass's GNSS fixes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Likelihood {
    /// Σ over the terms of ln p: the updates' innovations (position and
    /// velocity) and the withheld fixes' positions.
    pub total: f64,
    /// GNSS epochs with an update.
    pub updates: usize,
    /// Withheld fixes whose position was predicted.
    pub withheld: usize,
}

/// The windows the `coasting` objective withholds: `tune.outage_s` long
/// (default: the longest scored outage), one every `tune.outage_s +
/// tune.gap_s` (default `score.gap_s`), from `score.lead_s` plus half a
/// period after the first IMU sample (between the score's windows of the
/// same length), ending before the last fix. Empty for `innovations`.
pub fn tuning_windows(cfg: &ProcessConfig, inputs: &Inputs) -> Vec<(f64, f64)> {
    let (Some(first), Some(last)) = (inputs.imu.first(), inputs.gnss.last()) else {
        return Vec::new();
    };
    if cfg.tune.objective == TuneObjective::Innovations {
        return Vec::new();
    }
    let Some(length) = cfg.tune_outage_s() else {
        return Vec::new();
    };
    let gap = cfg.tune_gap_s();
    let start = first.time_s + cfg.score.lead_s + 0.5 * (length + gap);
    super::score::periodic_windows(start, length, gap, last.time_s)
}

/// ln N(e; 0, C) of a 3-vector, by Cholesky (None: C not positive
/// definite or the result not finite).
fn gaussian_log_density(e: &Vector3<f64>, c: &Matrix3<f64>) -> Option<f64> {
    let chol = Cholesky::new(*c)?;
    let log_det: f64 = 2.0 * chol.l().diagonal().iter().map(|d| d.ln()).sum::<f64>();
    let v = -0.5 * (3.0 * (2.0 * std::f64::consts::PI).ln() + log_det + e.dot(&chol.solve(e)));
    v.is_finite().then_some(v)
}

/// The log-likelihood of one filter pass over `inputs` (ready to filter:
/// smoothed as configured) under `cfg` with the accept policy and no
/// adaptive noise, withholding `windows` (none: every fix is an update):
/// the GNSS innovations of the updates, and the position of every withheld
/// fix against the coasting filter's antenna position, with covariance
/// the filter's antenna covariance plus the fix's own (its σ as the update
/// would have taken it: quality factor, floor, `gnss.sigma_scale`).
pub fn log_likelihood(
    cfg: &ProcessConfig,
    inputs: &Inputs,
    windows: &[(f64, f64)],
) -> Result<Likelihood, ProcessError> {
    let mut cfg = cfg.clone();
    cfg.filter.adaptive_noise = AdaptiveNoise::Off;
    let plan = RunPlan {
        windows: windows.to_vec(),
        ..RunPlan::default()
    };
    let epochs = run_filter(&cfg, inputs, &plan, PolicyName::Accept)?.epochs;
    let not_finite = |t: f64| {
        ProcessError::Data(format!(
            "the log-likelihood of the fix at {} is not finite",
            aidnav_io::text::date_time(t)
        ))
    };
    let (mut total, mut updates, mut withheld) = (0.0, 0, 0);
    for e in &epochs {
        if e.outcome.is_some() {
            if !e.log_likelihood.is_finite() {
                return Err(not_finite(e.fix.time_s));
            }
            total += e.log_likelihood;
            updates += 1;
        } else if windows.iter().any(|&(a, b)| (a..b).contains(&e.fix.time_s)) {
            let sigma = fix_position_sigma(&cfg, &e.fix);
            if !sigma.iter().all(|v| v.is_finite()) {
                continue;
            }
            let error = e.fix.position.ned_to(&e.antenna).raw();
            let c = e.position_covariance + Matrix3::from_diagonal(&sigma.map(|v| v * v));
            total += gaussian_log_density(&error, &c).ok_or_else(|| not_finite(e.fix.time_s))?;
            withheld += 1;
        }
    }
    Ok(Likelihood {
        total,
        updates,
        withheld,
    })
}

/// What a tuning found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TuneResult {
    /// The longest standstill (also when too short for the Allan deviation).
    pub stretch: Option<StaticStretch>,
    /// The Allan deviation (None: no standstill of `tune.min_static_s`).
    pub allan: Option<ImuAllan>,
    /// What a user should know (a standstill too short, bounds reached).
    pub notes: Vec<String>,
    /// The configuration's values.
    pub configured: NoiseValues,
    /// The Allan deviation's values (the configured ones where it says
    /// nothing; equal to `configured` without an Allan deviation).
    pub allan_values: NoiseValues,
    /// Where each of `allan_values` came from (order of [`PARAMETERS`]):
    /// `allan`, `allan bound` (an upper bound below the configured value),
    /// `configured`.
    pub allan_sources: Vec<&'static str>,
    /// The search started from `allan` or `configured` values: the ones
    /// with the higher likelihood.
    pub search_start: &'static str,
    /// The fitted values.
    pub fitted: NoiseValues,
    /// Fitted / configured, per parameter.
    pub factors: Vec<f64>,
    /// The parameters that ended at the search box's edge.
    pub at_bound: Vec<&'static str>,
    /// Log-likelihood with the configured values.
    pub log_likelihood_configured: f64,
    /// … with the Allan values (None without an Allan deviation).
    pub log_likelihood_allan: Option<f64>,
    /// … with the fitted values.
    pub log_likelihood_fitted: f64,
    /// What the search maximised.
    pub objective: TuneObjective,
    /// The windows withheld by the `coasting` objective (GPST s).
    pub windows: Vec<(f64, f64)>,
    /// The parameters searched: the first this many of [`PARAMETERS`]
    /// (the others keep their configured values).
    pub searched: usize,
    /// GNSS epochs with an update (the likelihood's innovation terms).
    pub updates: usize,
    /// Withheld fixes predicted by the coasting filter (the likelihood's
    /// other terms; 0 for `innovations`).
    pub withheld: usize,
    /// Filter passes of the search.
    pub evaluations: usize,
    /// Filter passes in all: the search's, the configured and the Allan
    /// values'.
    pub passes: usize,
    /// Simplex iterations.
    pub iterations: usize,
    /// The tolerance was met (else `tune.max_evaluations` ran out).
    pub converged: bool,
    /// Best log-likelihood after each iteration.
    pub history: Vec<f64>,
    /// Wall time \[s\]: standstill + Allan deviation, likelihood search.
    pub timing_s: [f64; 2],
}

impl TuneResult {
    /// What the likelihood is of, in words (for printouts and files).
    pub fn objective_text(&self) -> String {
        match self.objective {
            TuneObjective::Innovations => format!(
                "log-likelihood of the GNSS innovations (accept policy, every fix, {} updates)",
                self.updates
            ),
            TuneObjective::Coasting => {
                let length = self.windows.first().map_or(0.0, |(a, b)| b - a);
                format!(
                    "predictive log-likelihood of every fix with {} windows of {length:.0} s withheld ({} updates one step ahead, {} withheld fixes from the coasting filter)",
                    self.windows.len(),
                    self.updates,
                    self.withheld
                )
            }
        }
    }

    /// Log-likelihood gained over the configured values.
    pub fn gain(&self) -> f64 {
        self.log_likelihood_fitted - self.log_likelihood_configured
    }
}

/// The search is settled when every log-factor of the simplex is within
/// ln 1.05 of the best one's (5 %: noise terms are not known better, and
/// the likelihood is flat along some combinations).
const FACTOR_TOLERANCE: f64 = 1.05;

/// Where the start value of one scalar comes from: the Allan value (a
/// bound only when lower than the configured value), else the configured.
fn start_value(configured: f64, allan: Option<f64>, bound: bool) -> (Option<f64>, &'static str) {
    match allan {
        Some(v) if v.is_finite() && v > 0.0 && !bound => (Some(v), "allan"),
        Some(v) if v.is_finite() && v > 0.0 && v < configured => (Some(v), "allan bound"),
        _ => (None, "configured"),
    }
}

/// The Allan deviation of the longest standstill, when it lasts
/// `tune.min_static_s` and has enough samples (else a note).
fn allan_of_log(
    cfg: &ProcessConfig,
    unsmoothed: &Inputs,
    notes: &mut Vec<String>,
) -> (Option<StaticStretch>, Option<ImuAllan>) {
    let min_s = cfg.tune.min_static_s;
    let stretch = longest_standstill(cfg, unsmoothed);
    let allan = match &stretch {
        Some(s) if s.duration_s >= min_s => {
            match imu_allan(
                &unsmoothed.imu[s.range.clone()],
                s.clone(),
                cfg.imu.smoothing_s,
            ) {
                Ok(a) => Some(a),
                Err(e) => {
                    notes.push(format!(
                        "no Allan deviation of the {:.1} s standstill: {e}; the search starts from the configured noise",
                        s.duration_s
                    ));
                    None
                }
            }
        }
        Some(s) => {
            notes.push(format!(
                "the longest standstill lasts {:.1} s ({:.1} s after the first IMU sample), shorter than tune.min_static_s = {min_s} s: no Allan deviation, the search starts from the configured noise",
                s.duration_s, s.after_first_sample_s
            ));
            None
        }
        None => {
            notes.push(
                "no standstill in the log (see [standstill]): no Allan deviation, the search starts from the configured noise".into(),
            );
            None
        }
    };
    (stretch, allan)
}

/// Tune the noise of `cfg` on a log: `unsmoothed` are its inputs without
/// `imu.smoothing_s` ([`Inputs::load_unsmoothed`]); the filter passes
/// smooth them as configured. See the module documentation.
pub fn tune(cfg: &ProcessConfig, unsmoothed: &Inputs) -> Result<TuneResult, ProcessError> {
    let t = &cfg.tune;
    let clock = Instant::now();
    let mut notes = Vec::new();
    let (stretch, allan) = allan_of_log(cfg, unsmoothed, &mut notes);
    let configured = NoiseValues::of(cfg);
    let conf = noise_scalars(&configured.noise);
    let from_allan: [(Option<f64>, &'static str); 4] = match &allan {
        Some(a) => [
            start_value(conf[0], a.arw_deg_per_sqrt_h, false),
            start_value(conf[1], a.vrw_mps_per_sqrt_h, false),
            start_value(conf[2], a.gyro_bias_deg_per_h, a.gyro_bias_upper_bound),
            start_value(conf[3], a.accel_bias_mg, a.accel_bias_upper_bound),
        ],
        None => [(None, "configured"); 4],
    };
    if let Some(a) = &allan {
        for (name, value, bound, used) in [
            (
                "gyro",
                a.gyro_bias_deg_per_h,
                a.gyro_bias_upper_bound,
                from_allan[2].1,
            ),
            (
                "accelerometer",
                a.accel_bias_mg,
                a.accel_bias_upper_bound,
                from_allan[3].1,
            ),
        ] {
            if let (Some(v), true) = (value, bound) {
                notes.push(format!(
                    "the {name} Allan deviation still falls at the longest cluster time ({:.1} s of rest): its bias instability {v:.3} is an upper bound; the Allan values take {}",
                    a.stretch.duration_s,
                    if used == "configured" {
                        "the configured value (lower)"
                    } else {
                        "the bound"
                    }
                ));
            }
        }
    }
    let allan_values = NoiseValues {
        noise: set_noise_scalars(&configured.noise, from_allan.map(|(v, _)| v)),
        ..configured
    };
    let mut allan_sources: Vec<&'static str> = from_allan.iter().map(|(_, s)| *s).collect();
    allan_sources.extend(["configured", "configured"]);
    let allan_s = clock.elapsed().as_secs_f64();

    let clock = Instant::now();
    let inputs = unsmoothed.smoothed(cfg.imu.smoothing_s);
    let mut base = cfg.clone();
    base.imu.noise.auto = false;
    let windows = tuning_windows(cfg, &inputs);
    if cfg.tune.objective == TuneObjective::Coasting && windows.is_empty() {
        return Err(ProcessError::Data(format!(
            "the log is too short for tune.objective = \"coasting\": no window of tune.outage_s = {} s fits after score.lead_s = {} s plus half a period (shorten them, or use \"innovations\")",
            cfg.tune_outage_s().unwrap_or(f64::NAN),
            cfg.score.lead_s
        )));
    }
    let at = |values: &NoiseValues| {
        let mut c = base.clone();
        values.apply_to(&mut c);
        log_likelihood(&c, &inputs, &windows)
    };
    // The configured and the Allan values' likelihoods, side by side; the
    // search starts from the better (a failed pass: the other).
    let same = allan_values == configured;
    let (configured_ll, allan_run) = rayon::join(
        || at(&configured),
        || (allan.is_some() && !same).then(|| at(&allan_values)),
    );
    let allan_ll: Option<Likelihood> = match allan_run {
        Some(Ok(l)) => Some(l),
        Some(Err(e)) => {
            notes.push(format!("the filter fails with the Allan values: {e}"));
            None
        }
        None if allan.is_some() => configured_ll.as_ref().ok().copied(),
        None => None,
    };
    let (start, search_start) = match (&configured_ll, allan_ll) {
        (Ok(c), Some(a)) if a.total > c.total => (allan_values, "allan"),
        (Err(_), Some(_)) => (allan_values, "allan"),
        _ => (configured, "configured"),
    };
    let (updates, withheld) = match (&configured_ll, allan_ll) {
        (Ok(c), _) => (c.updates, c.withheld),
        (Err(_), Some(a)) => (a.updates, a.withheld),
        (Err(e), None) => {
            return Err(ProcessError::Data(format!(
                "the filter fails with the configured noise, the likelihood search cannot start: {e}"
            )));
        }
    };
    let half_width = t.max_factor.ln();
    let dim = searched_parameters(cfg);
    let options = NelderMeadOptions {
        initial_step: vec![t.initial_factor.ln(); dim],
        lower: vec![-half_width; dim],
        upper: vec![half_width; dim],
        max_evaluations: t.max_evaluations,
        f_tolerance: t.tolerance,
        x_tolerance: FACTOR_TOLERANCE.ln(),
    };
    // −ln L at a batch of log-factor points, one filter pass each, in
    // parallel; a failed pass is +∞ (the search steps away from it).
    let batch = |points: &[Vec<f64>]| -> Vec<f64> {
        points
            .par_iter()
            .map(|theta| {
                let factors: Vec<f64> = theta.iter().map(|v| v.exp()).collect();
                at(&start.scaled(&factors)).map_or(f64::INFINITY, |l| -l.total)
            })
            .collect()
    };
    let minimum = nelder_mead(batch, &vec![0.0; dim], &options).map_err(|e| {
        ProcessError::Data(format!(
            "the likelihood search could not start: {e} (the filter fails with the start noise)"
        ))
    })?;
    let fitted = start.scaled(&minimum.x.iter().map(|v| v.exp()).collect::<Vec<_>>());
    let at_bound: Vec<&'static str> = PARAMETERS[..dim]
        .iter()
        .zip(&minimum.x)
        .filter(|(_, v)| v.abs() >= half_width - 1e-9)
        .map(|(p, _)| *p)
        .collect();
    if !at_bound.is_empty() {
        notes.push(format!(
            "{} ended at the search's edge (× or ÷ tune.max_factor = {} of the start): the likelihood wants more",
            at_bound.join(", "),
            t.max_factor
        ));
    }
    if !minimum.converged {
        notes.push(format!(
            "the search stopped after tune.max_evaluations = {} filter passes before the tolerance was met",
            t.max_evaluations
        ));
    }
    let (c, f) = (configured.parameters(), fitted.parameters());
    let allan_pass = allan.is_some() && !same;
    Ok(TuneResult {
        stretch,
        allan,
        notes,
        configured,
        allan_values,
        allan_sources,
        search_start,
        fitted,
        factors: (0..PARAMETERS.len()).map(|i| f[i] / c[i]).collect(),
        at_bound,
        objective: cfg.tune.objective,
        windows,
        searched: dim,
        withheld,
        log_likelihood_configured: configured_ll.map_or(f64::NEG_INFINITY, |l| l.total),
        log_likelihood_allan: allan_ll.map(|l| l.total),
        log_likelihood_fitted: -minimum.value,
        updates,
        evaluations: minimum.evaluations,
        passes: minimum.evaluations + 1 + usize::from(allan_pass),
        iterations: minimum.iterations,
        converged: minimum.converged,
        history: minimum.history.iter().map(|v| -v).collect(),
        timing_s: [allan_s, clock.elapsed().as_secs_f64()],
    })
}

/// `tuned_noise.toml`: the fitted `[imu.noise]` table (every key, ready to
/// paste over the configuration's), the GNSS σ scale as a commented
/// `[gnss]` key, and where the numbers came from.
pub fn tuned_noise_toml(result: &TuneResult, config_name: &str) -> String {
    let mut out = format!(
        "# aidnav tune {config_name} (aidnav {}): the noise that maximises the\n\
         # {}, {:.1} → {:.1} (gain {:.1}).\n",
        crate::VERSION,
        result.objective_text(),
        result.log_likelihood_configured,
        result.log_likelihood_fitted,
        result.gain(),
    );
    match &result.allan {
        Some(a) => out.push_str(&format!(
            "# Allan deviation of {:.1} s at rest ({:.1} s into the log); the search started from the {} values (the higher likelihood).\n",
            a.stretch.duration_s, a.stretch.after_first_sample_s, result.search_start
        )),
        None => out.push_str("# Start: the configured values (no standstill long enough for an Allan deviation).\n"),
    }
    out.push_str("# Paste over [imu.noise]; the GNSS σ scale goes into [gnss], the non-holonomic σ into [constraints].\n\n[imu.noise]\n");
    // Four significant digits of the fitted scalars (the likelihood is
    // flat to well below that); the other keys as configured. Plain
    // numbers serialize; an empty table would show in the test.
    let rounded = set_noise_scalars(
        &result.fitted.noise,
        noise_scalars(&result.fitted.noise).map(|v| Some(round_sig(v, 4))),
    );
    out.push_str(&toml::to_string(&rounded).unwrap_or_default());
    out.push_str(&format!(
        "\n# [gnss]\n# sigma_scale = {}\n",
        round_sig(result.fitted.gnss_sigma_scale, 4)
    ));
    if result.searched == PARAMETERS.len() {
        out.push_str(&format!(
            "\n# [constraints]\n# non_holonomic_sigma_mps = {}\n",
            round_sig(result.fitted.non_holonomic_sigma_mps, 4)
        ));
    }
    out
}

/// `x` to `digits` significant digits (for files people read): through
/// decimal text, so that the value prints as its digits (21.49, not
/// 21.489999999999995).
fn round_sig(x: f64, digits: i32) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let precision = usize::try_from(digits.max(1) - 1).unwrap_or(0);
    format!("{x:.precision$e}").parse().unwrap_or(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_frames::Vec3;
    use aidnav_frames::earth::{Geodetic, earth_rate_ned};
    use aidnav_sim::rng::{run_rng, standard_normal};
    use nalgebra::Vector3;

    /// True noise of the synthetic log: ARW \[deg/√h\], VRW \[m/s/√h\],
    /// the receiver's reported σ \[m\] and the factor by which its real
    /// errors exceed it.
    const ARW: f64 = 1.0;
    const VRW: f64 = 0.3;
    const GNSS_SIGMA_M: f64 = 0.02;
    const GNSS_TRUE_SCALE: f64 = 2.0;

    /// A static IMU at 100 Hz (Earth rate and gravity, white noise of
    /// density ARW and VRW) and position fixes at 4 Hz whose errors are
    /// `GNSS_TRUE_SCALE` × their σ; the attitude is given (level, north).
    fn synthetic_log(seconds: f64, seed: u64) -> (ProcessConfig, Inputs) {
        let mut cfg: ProcessConfig =
            toml::from_str("[data]\ndir = \".\"\nimu = \"none\"\ngnss = \"none\"\n").unwrap();
        cfg.initial.attitude_deg = Some([0.0; 3]);
        // Most tests judge the one-step search (the logs are shorter than
        // the default score lead); the coasting tests set their windows.
        cfg.tune.objective = TuneObjective::Innovations;
        let place = Geodetic {
            latitude_rad: 0.7,
            longitude_rad: -1.8,
            height_m: 1600.0,
        };
        let g = aidnav_ins::ned::gravity_ned(&place).raw();
        let w_ie = earth_rate_ned(place.latitude_rad).raw();
        let dt = 0.01f64;
        let gyro_sd = ARW.to_radians() / 60.0 / dt.sqrt();
        let accel_sd = VRW / 60.0 / dt.sqrt();
        let mut rng = run_rng(seed, 0);
        let mut noise = |sd: f64| {
            Vector3::new(
                standard_normal(&mut rng),
                standard_normal(&mut rng),
                standard_normal(&mut rng),
            ) * sd
        };
        let n = (seconds / dt) as usize;
        let imu = (0..n)
            .map(|k| ImuSample {
                time_s: k as f64 * dt,
                specific_force: -g + noise(accel_sd),
                angular_rate: w_ie + noise(gyro_sd),
            })
            .collect();
        let gnss = (0..(seconds * 4.0) as usize)
            .map(|k| GnssFix {
                time_s: k as f64 * 0.25,
                position: place.offset_by(&Vec3::assume_in_frame(noise(
                    GNSS_SIGMA_M * GNSS_TRUE_SCALE,
                ))),
                quality: 1,
                satellites: 20,
                position_sigma_neu: Vector3::repeat(GNSS_SIGMA_M),
                velocity_ned: None,
                velocity_sigma_neu: None,
            })
            .collect();
        (cfg, Inputs::new(imu, gnss))
    }

    /// The Allan deviation of a static log reads the white noise it was
    /// made with (RMS over three axes, each within a few % at 60 s: 10 %
    /// allowed); white noise alone has no floor, so the bias instability
    /// is an upper bound.
    #[test]
    fn the_allan_deviation_reads_the_white_noise_of_a_synthetic_log() {
        let (cfg, inputs) = synthetic_log(60.0, 1);
        let s = longest_standstill(&cfg, &inputs).unwrap();
        // The whole log less a window at each end.
        assert!((s.duration_s - 59.0).abs() < 0.05, "{s:?}");
        let a = imu_allan(&inputs.imu[s.range.clone()], s, 0.0).unwrap();
        let arw = a.arw_deg_per_sqrt_h.unwrap();
        let vrw = a.vrw_mps_per_sqrt_h.unwrap();
        assert!((arw / ARW - 1.0).abs() < 0.1, "ARW {arw}");
        assert!((vrw / VRW - 1.0).abs() < 0.1, "VRW {vrw}");
        assert!(a.gyro_bias_upper_bound && a.accel_bias_upper_bound);
        assert_eq!(a.axes.len(), 6);
        assert!((a.sample_interval_s - 0.01).abs() < 1e-12);
    }

    /// The likelihood search finds the GNSS σ scale the log was made with
    /// (errors 2 × the reported σ): within 10 % (about three standard
    /// errors of a scale from 240 three-axis fixes, √(1/1440) ≈ 2.6 %).
    /// (The IMU terms are weakly seen by a static filter fed 4 cm fixes:
    /// no assertion on them.)
    #[test]
    fn the_likelihood_search_finds_the_gnss_sigma_scale() {
        let (mut cfg, inputs) = synthetic_log(60.0, 2);
        cfg.tune.max_evaluations = 80;
        let r = tune(&cfg, &inputs).unwrap();
        assert!(r.allan.is_some());
        let scale = r.fitted.gnss_sigma_scale;
        assert!((scale / GNSS_TRUE_SCALE - 1.0).abs() < 0.1, "scale {scale}");
        // The search starts from the better of the two and never ends
        // below its start.
        let best_start = r
            .log_likelihood_configured
            .max(r.log_likelihood_allan.unwrap());
        assert!(r.log_likelihood_fitted >= best_start);
        assert!(r.gain() > 100.0, "{}", r.gain());
        assert_eq!((r.updates, r.withheld), (239, 0)); // every fix after the first
        assert!(r.windows.is_empty());
        // No non-holonomic constraint: five parameters searched.
        assert_eq!(r.searched, 5);
        assert!(r.passes <= 80 + 2 + 5);
        assert_eq!(r.factors.len(), PARAMETERS.len());
        assert_eq!(r.factors[5], 1.0);
        // The fitted file: an [imu.noise] table that reads back.
        let text = tuned_noise_toml(&r, "synthetic.toml");
        let table: toml::Table = toml::from_str(&text).unwrap();
        let noise: crate::process::NoiseConfig = table["imu"]["noise"].clone().try_into().unwrap();
        assert!(!noise.auto);
        let back = noise_scalars(&noise.values);
        for (b, f) in back.iter().zip(noise_scalars(&r.fitted.noise)) {
            assert!((b / f - 1.0).abs() < 1e-3, "{b} vs {f}");
        }
        assert!(text.contains("# sigma_scale = "));
    }

    /// ln N(e; 0, C) against the closed form of a diagonal covariance:
    /// −½ (3 ln 2π + Σ ln cᵢ + Σ eᵢ² / cᵢ); none when C is singular.
    #[test]
    fn the_gaussian_log_density_is_the_closed_form() {
        let e = Vector3::new(1.0, -2.0, 0.5);
        let c: Vector3<f64> = Vector3::new(2.0, 0.5, 4.0);
        let expected = -0.5
            * (3.0 * (2.0 * std::f64::consts::PI).ln()
                + c.iter().map(|v: &f64| v.ln()).sum::<f64>()
                + e.component_div(&c).dot(&e));
        let got = gaussian_log_density(&e, &Matrix3::from_diagonal(&c)).unwrap();
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
        // Rotating the frame changes nothing (full covariance path).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1);
        let rotated =
            gaussian_log_density(&(r * e), &(r * Matrix3::from_diagonal(&c) * r.transpose()))
                .unwrap();
        assert!((rotated - expected).abs() < 1e-9);
        assert_eq!(gaussian_log_density(&e, &Matrix3::zeros()), None);
    }

    /// The coasting windows: `tune.outage_s` (default the longest scored
    /// outage) every outage + gap (default `score.gap_s`), from the lead
    /// plus half a period, all before the last fix; none for the
    /// innovation objective.
    #[test]
    fn the_coasting_windows_fall_between_the_scored_ones() {
        let (mut cfg, inputs) = synthetic_log(100.0, 6);
        cfg.tune.objective = TuneObjective::Coasting;
        cfg.score.outages_s = vec![5.0, 10.0];
        cfg.score.lead_s = 20.0;
        cfg.score.gap_s = 10.0;
        // Period 20 s from 20 + 10 s: [30, 40), [50, 60), [70, 80); the
        // next, [90, 100), would end at the last fix (99.75 s).
        assert_eq!(
            tuning_windows(&cfg, &inputs),
            vec![(30.0, 40.0), (50.0, 60.0), (70.0, 80.0)]
        );
        cfg.tune.outage_s = Some(4.0);
        cfg.tune.gap_s = Some(16.0);
        assert_eq!(tuning_windows(&cfg, &inputs)[0], (30.0, 34.0));
        cfg.tune.objective = TuneObjective::Innovations;
        assert!(tuning_windows(&cfg, &inputs).is_empty());
        // A log too short for one window: an error that says so.
        let (mut short, inputs) = synthetic_log(30.0, 6);
        short.tune.objective = TuneObjective::Coasting;
        short.tune.max_evaluations = 6;
        let e = tune(&short, &inputs).unwrap_err().to_string();
        assert!(e.contains("too short for tune.objective"), "{e}");
    }

    /// The coasting objective judges the withheld fixes by the coasting
    /// filter's covariance: an accelerometer noise 10× below the truth
    /// makes the coasting σ too small and the likelihood lower, and the
    /// search from there (no Allan deviation) comes back to within a
    /// factor 2 of the true VRW. The pass counts its terms: every fix in
    /// a window withheld, every other fix after the first an update.
    #[test]
    fn the_coasting_likelihood_prefers_the_true_noise() {
        let (mut cfg, inputs) = synthetic_log(120.0, 7);
        cfg.tune.objective = TuneObjective::Coasting;
        cfg.tune.min_static_s = 1e4; // no Allan deviation: start from the configuration
        cfg.tune.max_evaluations = 120;
        cfg.score.outages_s = vec![10.0];
        cfg.score.lead_s = 10.0;
        cfg.score.gap_s = 10.0;
        cfg.gnss.sigma_scale = GNSS_TRUE_SCALE;
        cfg.imu.noise.values.arw_deg_per_sqrt_h = PerAxis::all(ARW);
        cfg.imu.noise.values.vrw_mps_per_sqrt_h = PerAxis::all(VRW);
        let windows = tuning_windows(&cfg, &inputs);
        assert_eq!(windows.len(), 5); // [20, 30) … [100, 110)
        let truth = log_likelihood(&cfg, &inputs, &windows).unwrap();
        assert_eq!(truth.withheld, 5 * 40);
        assert_eq!(truth.updates, 479 - 5 * 40);
        let mut low = cfg.clone();
        low.imu.noise.values.vrw_mps_per_sqrt_h = PerAxis::all(VRW / 10.0);
        let overconfident = log_likelihood(&low, &inputs, &windows).unwrap();
        assert!(
            overconfident.total < truth.total - 10.0,
            "{} vs {}",
            overconfident.total,
            truth.total
        );
        let r = tune(&low, &inputs).unwrap();
        assert_eq!(r.objective, TuneObjective::Coasting);
        assert_eq!(r.withheld, 200);
        let vrw = noise_scalars(&r.fitted.noise)[1];
        assert!(vrw > VRW / 2.0 && vrw < VRW * 2.0, "VRW {vrw}");
    }

    /// Serial and parallel evaluations give the same search.
    #[test]
    fn the_search_does_not_depend_on_the_thread_count() {
        let (mut cfg, inputs) = synthetic_log(20.0, 3);
        cfg.tune.max_evaluations = 12;
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut r = pool.install(|| tune(&cfg, &inputs)).unwrap();
            r.timing_s = [0.0; 2];
            r
        };
        assert_eq!(run(1), run(2));
    }

    /// `[imu.noise] auto`: `Process` tunes first and filters with the
    /// fitted values; with smoothing, `Process::new` (smoothed inputs)
    /// refuses.
    #[test]
    fn auto_noise_tunes_before_processing() {
        let (mut cfg, inputs) = synthetic_log(20.0, 4);
        cfg.imu.noise.auto = true;
        cfg.tune.max_evaluations = 8;
        let p = crate::process::Process::new(cfg.clone(), inputs.clone()).unwrap();
        let t = p.tuning().unwrap();
        assert_eq!(p.config().imu.noise.values, t.fitted.noise);
        assert_eq!(p.config().gnss.sigma_scale, t.fitted.gnss_sigma_scale);
        assert!(p.run().unwrap().tracking_rms_m.is_some_and(f64::is_finite));
        cfg.imu.smoothing_s = 0.05;
        let e = crate::process::Process::new(cfg.clone(), inputs.clone()).unwrap_err();
        assert!(e.to_string().contains("unsmoothed"), "{e}");
        assert!(crate::process::Process::from_unsmoothed(cfg, inputs).is_ok());
    }

    /// Too short a standstill: no Allan deviation, a note, the search from
    /// the configured values.
    #[test]
    fn a_short_standstill_skips_the_allan_deviation() {
        let (mut cfg, inputs) = synthetic_log(8.0, 5);
        cfg.tune.max_evaluations = 6;
        let r = tune(&cfg, &inputs).unwrap();
        assert!(r.allan.is_none());
        assert!((r.stretch.as_ref().unwrap().duration_s - 7.0).abs() < 0.05);
        assert!(
            r.notes[0].contains("shorter than tune.min_static_s = 10 s"),
            "{:?}",
            r.notes
        );
        assert_eq!(r.search_start, "configured");
        assert_eq!(r.allan_values, r.configured);
        assert!(r.log_likelihood_allan.is_none());
    }

    /// `[imu.noise]`: `auto` beside the terms, `noise = "auto"`, and
    /// errors that name the key.
    #[test]
    fn the_noise_table_takes_auto() {
        let head = "[data]\ndir = \".\"\nimu = \"i\"\ngnss = \"g\"\n";
        let parse = |tail: &str| toml::from_str::<ProcessConfig>(&format!("{head}{tail}"));
        let c = parse("[imu.noise]\nauto = true\narw_deg_per_sqrt_h = 2.0\n").unwrap();
        assert!(c.imu.noise.auto);
        assert_eq!(c.imu.noise.arw_deg_per_sqrt_h, PerAxis::all(2.0));
        assert_eq!(
            c.imu.noise.vrw_mps_per_sqrt_h,
            ImuNoise::default().vrw_mps_per_sqrt_h
        );
        let c = parse("[imu]\nnoise = \"auto\"\n").unwrap();
        assert!(c.imu.noise.auto);
        assert_eq!(c.imu.noise.values, ImuNoise::default());
        let c = parse("[imu.noise]\naccel_bias_mg = 3\n").unwrap();
        assert!(!c.imu.noise.auto);
        assert_eq!(c.imu.noise.accel_bias_mg, PerAxis::all(3.0));
        let e = parse("[imu.noise]\narw = 2.0\n").unwrap_err().to_string();
        assert!(e.contains("unknown field `arw`"), "{e}");
        let e = parse("[imu.noise]\nauto = 1\n").unwrap_err().to_string();
        assert!(e.contains("auto = 1: expected true or false"), "{e}");
        let e = parse("[imu]\nnoise = \"manual\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected a table of noise terms"), "{e}");
        // Written back, it reads the same.
        let c = parse("[imu.noise]\nauto = true\ngyro_bias_deg_per_h = 7.5\n").unwrap();
        let back: ProcessConfig = toml::from_str(&toml::to_string(&c).unwrap()).unwrap();
        assert_eq!(back, c);
    }

    #[test]
    fn the_accessors_scale_and_set_the_four_scalars() {
        let n = ImuNoise::default();
        let s = scale_noise(&n, [2.0, 3.0, 0.5, 10.0]);
        let v = noise_scalars(&n);
        let w = noise_scalars(&s);
        for (i, k) in [2.0, 3.0, 0.5, 10.0].into_iter().enumerate() {
            assert!((w[i] - k * v[i]).abs() < 1e-12 * v[i], "{w:?} {v:?}");
        }
        assert_eq!(s.gyro_scale_ppm, n.gyro_scale_ppm);
        let t = set_noise_scalars(&n, [None, Some(0.1), None, Some(7.0)]);
        assert!((noise_scalars(&t)[1] - 0.1).abs() < 1e-15);
        assert_eq!(noise_scalars(&t)[0], v[0]);
        assert!((noise_scalars(&t)[3] - 7.0).abs() < 1e-12);
        // Per-axis terms keep their ratios.
        let axes = ImuNoise {
            arw_deg_per_sqrt_h: PerAxis([1.0, 2.0, 2.0]),
            ..n
        };
        let u = set_noise_scalars(
            &axes,
            [Some(2.0 * rms(&axes.arw_deg_per_sqrt_h)), None, None, None],
        );
        assert!((u.arw_deg_per_sqrt_h.0[1] - 4.0).abs() < 1e-12);
    }

    #[test]
    fn a_bound_starts_the_search_only_below_the_configured_value() {
        assert_eq!(start_value(50.0, Some(20.0), false), (Some(20.0), "allan"));
        assert_eq!(start_value(50.0, Some(80.0), false), (Some(80.0), "allan"));
        assert_eq!(
            start_value(50.0, Some(20.0), true),
            (Some(20.0), "allan bound")
        );
        assert_eq!(start_value(50.0, Some(80.0), true), (None, "configured"));
        assert_eq!(start_value(50.0, None, false), (None, "configured"));
        assert_eq!(
            start_value(50.0, Some(f64::NAN), false),
            (None, "configured")
        );
    }

    #[test]
    fn significant_digits() {
        assert_eq!(round_sig(1.234567, 4), 1.235);
        assert_eq!(round_sig(0.000123456, 3), 0.000123);
        assert_eq!(round_sig(0.0, 3), 0.0);
        assert_eq!(round_sig(21.48934, 4), 21.49);
        assert_eq!(round_sig(-41.0996, 4).to_string(), "-41.1");
    }
}
