//! GNSS position and velocity fixes of the antenna, with white noise, an
//! optional first-order Gauss–Markov position error per axis, and outage
//! windows.
//!
//! Fix j is at `start + j / rate_hz` (j = 0, 1, …, within the truth span).
//! Every epoch draws its noise, also inside an outage, so adding an outage
//! window changes no other fix. The σ written is the model's own:
//! `√(σ_white² + σ_GM²)` per axis for the position, `σ_white` for the
//! velocity.

use aidnav_frames::{Body, Vec3};
use aidnav_sensors::GnssFix;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{SimError, check, non_negative, positive};
use crate::processes::{GaussMarkov, white};
use crate::rng::Stream;
use crate::truth::{TruthSample, truth_at};

/// The GNSS receiver: rate, antenna lever arm, error model, outages.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GnssSpec {
    /// Fix rate \[Hz\] (> 0). Default 1.
    pub rate_hz: f64,
    /// Antenna position from the IMU in body axes (x fwd, y right, z down)
    /// \[m\]. Default (−0.5, 0, −1.0): on the roof, half a metre back.
    pub lever_arm_m: [f64; 3],
    /// σ of the white position noise, north, east, up \[m\].
    /// Default (1.5, 1.5, 3.0) (single-point / SBAS class).
    pub position_sigma_neu_m: [f64; 3],
    /// σ of the Gauss–Markov position error, north, east, up \[m\];
    /// 0 disables it. Default (0, 0, 0).
    pub position_markov_sigma_neu_m: [f64; 3],
    /// Correlation time of the Gauss–Markov position error \[s\] (> 0).
    /// Default 100.
    pub position_markov_time_s: f64,
    /// σ of the velocity noise, north, east, up \[m/s\]. Default
    /// (0.05, 0.05, 0.1).
    pub velocity_sigma_neu_m_s: [f64; 3],
    /// Whether fixes carry the NED velocity (and its σ). Default true.
    pub write_velocity: bool,
    /// Solution quality written (RTKLIB Q). Default 1.
    pub quality: u8,
    /// Number of satellites written. Default 10.
    pub satellites: u32,
    /// Outage windows `[start, end)`, seconds from the start of the
    /// simulation; no fix is written inside them. Default none.
    pub outages_s: Vec<[f64; 2]>,
    /// Latency of the time tag \[s\]: the fix stamped t holds the antenna's
    /// state at t − latency (a receiver that stamps its output late; the
    /// estimator should find it). Default 0.
    pub latency_s: f64,
    /// The σ written is this times the model's σ (receivers report
    /// optimistic or pessimistic σ; 1 = honest). Default 1.
    pub reported_sigma_scale: f64,
    /// Multipath: jumps of the position error that hold for a while.
    pub multipath: MultipathSpec,
    /// Outliers: single fixes far off, with the σ of a good one.
    pub outliers: OutlierSpec,
    /// Degraded stretches (urban canyons, trees): larger errors, a worse
    /// quality flag. Default none.
    pub degraded_s: Vec<DegradedWindow>,
}

/// The error classes of a receiver's solution, each with errors of its
/// size ([`GnssSpec::for_mode`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum GnssMode {
    /// Single point (code only, broadcast ephemeris): metres, correlated
    /// over minutes (ionosphere, orbits, multipath). Quality 5.
    Standalone,
    /// Code differential (SBAS / DGPS): about half a metre. Quality 4.
    Dgps,
    /// RTK float: decimetres. Quality 2.
    Float,
    /// RTK fixed: centimetres. Quality 1.
    Fixed,
}

/// Multipath jumps: events at a mean rate, each an offset of the position
/// (north, east and 1.5× up, Gaussian of σ `sigma_m`) that holds for
/// `duration_s`, then drops back.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MultipathSpec {
    /// Mean number of jumps per minute (≥ 0). Default 0 (none).
    pub rate_per_min: f64,
    /// σ of a jump, horizontal per axis \[m\]. Default 3.
    pub sigma_m: f64,
    /// How long a jump holds \[s\] (> 0). Default 5.
    pub duration_s: f64,
}

impl Default for MultipathSpec {
    fn default() -> Self {
        Self {
            rate_per_min: 0.0,
            sigma_m: 3.0,
            duration_s: 5.0,
        }
    }
}

/// Outliers: each fix, with probability `probability`, is off by a
/// Gaussian error of σ `sigma_m` per axis, its σ written as usual (the
/// receiver does not know).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutlierSpec {
    /// Probability of an outlier per fix (0 … 1). Default 0.
    pub probability: f64,
    /// σ of an outlier's error per axis \[m\]. Default 20.
    pub sigma_m: f64,
}

impl Default for OutlierSpec {
    fn default() -> Self {
        Self {
            probability: 0.0,
            sigma_m: 20.0,
        }
    }
}

/// A stretch of degraded reception `[start_s, end_s)` (seconds from the
/// start of the simulation): every position error (white, Gauss–Markov,
/// multipath) and the σ written are `sigma_scale` times larger, and the
/// fixes carry quality `quality`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DegradedWindow {
    /// Start \[s from the start\].
    pub start_s: f64,
    /// End \[s from the start\] (> start).
    pub end_s: f64,
    /// Error scale (≥ 1).
    pub sigma_scale: f64,
    /// Quality flag written inside (RTKLIB Q, e.g. 5 single).
    pub quality: u8,
}

impl Default for GnssSpec {
    fn default() -> Self {
        Self {
            rate_hz: 1.0,
            lever_arm_m: [-0.5, 0.0, -1.0],
            position_sigma_neu_m: [1.5, 1.5, 3.0],
            position_markov_sigma_neu_m: [0.0; 3],
            position_markov_time_s: 100.0,
            velocity_sigma_neu_m_s: [0.05, 0.05, 0.1],
            write_velocity: true,
            quality: 1,
            satellites: 10,
            outages_s: Vec::new(),
            latency_s: 0.0,
            reported_sigma_scale: 1.0,
            multipath: MultipathSpec::default(),
            outliers: OutlierSpec::default(),
            degraded_s: Vec::new(),
        }
    }
}

impl GnssSpec {
    /// A receiver of solution class `mode` (1 Hz, the default antenna
    /// lever arm and velocity), with errors of the size such solutions
    /// have in open sky — white noise plus a Gauss–Markov part, σ per
    /// axis north / east / up:
    ///
    /// | mode | white \[m\] | Gauss–Markov \[m\] | τ \[s\] | velocity \[m/s\] | Q |
    /// |---|---|---|---|---|---|
    /// | standalone | 0.5, 0.5, 1.0 | 1.2, 1.2, 2.5 | 300 | 0.05, 0.05, 0.1 | 5 |
    /// | dgps | 0.3, 0.3, 0.6 | 0.5, 0.5, 1.0 | 120 | 0.05, 0.05, 0.1 | 4 |
    /// | float | 0.05, 0.05, 0.1 | 0.2, 0.2, 0.4 | 60 | 0.03, 0.03, 0.06 | 2 |
    /// | fixed | 0.01, 0.01, 0.02 | 0.005, 0.005, 0.01 | 30 | 0.02, 0.02, 0.04 | 1 |
    pub fn for_mode(mode: GnssMode) -> Self {
        let (white, markov, tau, vel, quality) = match mode {
            GnssMode::Standalone => (
                [0.5, 0.5, 1.0],
                [1.2, 1.2, 2.5],
                300.0,
                [0.05, 0.05, 0.1],
                5,
            ),
            GnssMode::Dgps => (
                [0.3, 0.3, 0.6],
                [0.5, 0.5, 1.0],
                120.0,
                [0.05, 0.05, 0.1],
                4,
            ),
            GnssMode::Float => (
                [0.05, 0.05, 0.1],
                [0.2, 0.2, 0.4],
                60.0,
                [0.03, 0.03, 0.06],
                2,
            ),
            GnssMode::Fixed => (
                [0.01, 0.01, 0.02],
                [0.005, 0.005, 0.01],
                30.0,
                [0.02, 0.02, 0.04],
                1,
            ),
        };
        Self {
            position_sigma_neu_m: white,
            position_markov_sigma_neu_m: markov,
            position_markov_time_s: tau,
            velocity_sigma_neu_m_s: vel,
            quality,
            ..Self::default()
        }
    }

    /// The model's position σ per axis (north, east, up) \[m\]: white and
    /// Gauss–Markov combined (before any degradation).
    pub fn model_sigma_neu_m(&self) -> [f64; 3] {
        std::array::from_fn(|i| {
            self.position_sigma_neu_m[i].hypot(self.position_markov_sigma_neu_m[i])
        })
    }

    /// The degraded window containing `t_s` (seconds from the start), if any.
    pub fn degradation(&self, t_s: f64) -> Option<&DegradedWindow> {
        self.degraded_s
            .iter()
            .find(|w| t_s >= w.start_s && t_s < w.end_s)
    }

    /// An error-free receiver at the IMU (no lever arm), 1 Hz, no outages
    /// (σ written 0).
    pub fn ideal() -> Self {
        Self {
            lever_arm_m: [0.0; 3],
            position_sigma_neu_m: [0.0; 3],
            velocity_sigma_neu_m_s: [0.0; 3],
            ..Self::default()
        }
    }

    /// Check every parameter (fields named as in the scenario).
    pub fn validate(&self) -> Result<(), SimError> {
        positive("gnss.rate_hz", self.rate_hz)?;
        positive("gnss.position_markov_time_s", self.position_markov_time_s)?;
        for i in 0..3 {
            crate::error::finite(format!("gnss.lever_arm_m[{i}]"), self.lever_arm_m[i])?;
            non_negative(
                format!("gnss.position_sigma_neu_m[{i}]"),
                self.position_sigma_neu_m[i],
            )?;
            non_negative(
                format!("gnss.position_markov_sigma_neu_m[{i}]"),
                self.position_markov_sigma_neu_m[i],
            )?;
            non_negative(
                format!("gnss.velocity_sigma_neu_m_s[{i}]"),
                self.velocity_sigma_neu_m_s[i],
            )?;
        }
        crate::error::finite("gnss.latency_s", self.latency_s)?;
        check(
            "gnss.latency_s",
            self.latency_s,
            self.latency_s.abs() <= 10.0,
            "must be within ±10 s",
        )?;
        positive("gnss.reported_sigma_scale", self.reported_sigma_scale)?;
        non_negative("gnss.multipath.rate_per_min", self.multipath.rate_per_min)?;
        non_negative("gnss.multipath.sigma_m", self.multipath.sigma_m)?;
        positive("gnss.multipath.duration_s", self.multipath.duration_s)?;
        check(
            "gnss.outliers.probability",
            self.outliers.probability,
            (0.0..=1.0).contains(&self.outliers.probability),
            "must be within 0 … 1",
        )?;
        non_negative("gnss.outliers.sigma_m", self.outliers.sigma_m)?;
        for (i, w) in self.degraded_s.iter().enumerate() {
            crate::error::finite(format!("gnss.degraded_s[{i}].start_s"), w.start_s)?;
            check(
                format!("gnss.degraded_s[{i}].end_s"),
                w.end_s,
                w.end_s > w.start_s,
                "a window must end after it starts",
            )?;
            check(
                format!("gnss.degraded_s[{i}].sigma_scale"),
                w.sigma_scale,
                w.sigma_scale >= 1.0 && w.sigma_scale.is_finite(),
                "must be ≥ 1",
            )?;
        }
        for (i, w) in self.outages_s.iter().enumerate() {
            crate::error::finite(format!("gnss.outages_s[{i}][0]"), w[0])?;
            check(
                format!("gnss.outages_s[{i}][1]"),
                w[1],
                w[1] > w[0],
                "an outage must end after it starts",
            )?;
        }
        Ok(())
    }

    /// Whether `t_s` (seconds from the start) is inside an outage.
    pub fn in_outage(&self, t_s: f64) -> bool {
        self.outages_s.iter().any(|w| t_s >= w[0] && t_s < w[1])
    }
}

/// One uniform draw in \[0, 1).
fn uniform(rng: &mut crate::rng::RunRng) -> f64 {
    use crate::rng::RngExt;
    rng.random::<f64>()
}

/// The multipath offset at `t_rel` (north, east, up) \[m\]: draws every
/// epoch (a start test and three normals) whether or not a jump starts, so
/// the stream's use does not depend on the outcome.
fn multipath_step(
    spec: &GnssSpec,
    probability: f64,
    t_rel: f64,
    (jump, until): (&mut Vector3<f64>, &mut f64),
    rng: &mut crate::rng::RunRng,
) -> Vector3<f64> {
    if spec.multipath.rate_per_min == 0.0 {
        return Vector3::zeros();
    }
    let start = uniform(rng) < probability;
    let sigma = spec.multipath.sigma_m;
    let draw = Vector3::new(
        white(sigma, rng),
        white(sigma, rng),
        white(1.5 * sigma, rng),
    );
    if start {
        *jump = draw;
        *until = t_rel + spec.multipath.duration_s;
    }
    if t_rel < *until {
        *jump
    } else {
        Vector3::zeros()
    }
}

/// The fixes of run `run` under master seed `seed` along `truth`: fix j
/// stamped `start + j / rate` (the antenna's state `latency_s` earlier),
/// none inside an outage or before the truth starts.
pub fn simulate_gnss(
    spec: &GnssSpec,
    truth: &[TruthSample],
    seed: u64,
    run: u64,
) -> Result<Vec<GnssFix>, SimError> {
    spec.validate()?;
    let (Some(first), Some(last)) = (truth.first(), truth.last()) else {
        return Ok(Vec::new());
    };
    let lever = Vec3::<Body>::assume_in_frame(Vector3::from(spec.lever_arm_m));
    let white_sigma = Vector3::from(spec.position_sigma_neu_m);
    let markov_sigma = Vector3::from(spec.position_markov_sigma_neu_m);
    let vel_sigma = Vector3::from(spec.velocity_sigma_neu_m_s);
    let reported = white_sigma.zip_map(&markov_sigma, |w, m| w.hypot(m));
    let mut noise_rng = Stream::GnssPositionNoise.rng(seed, run);
    let mut markov_rng = Stream::GnssPositionMarkov.rng(seed, run);
    let mut vel_rng = Stream::GnssVelocityNoise.rng(seed, run);
    let mut multipath_rng = Stream::GnssMultipath.rng(seed, run);
    let mut outlier_rng = Stream::GnssOutliers.rng(seed, run);
    let jump_probability = spec.multipath.rate_per_min / 60.0 / spec.rate_hz;
    let (mut jump, mut jump_until) = (Vector3::zeros(), f64::NEG_INFINITY);
    let mut markov: [GaussMarkov; 3] = std::array::from_fn(|i| {
        GaussMarkov::new(
            markov_sigma[i],
            spec.position_markov_time_s,
            &mut markov_rng,
        )
    });
    let dt = 1.0 / spec.rate_hz;
    let span = last.time_s - first.time_s;
    let count = (span * spec.rate_hz + 1e-9).floor() as usize + 1;
    let mut fixes = Vec::with_capacity(count);
    for j in 0..count {
        let t_rel = j as f64 * dt;
        let gm = Vector3::from_fn(|i, _| {
            if j == 0 {
                markov[i].value()
            } else {
                markov[i].step(dt, &mut markov_rng)
            }
        });
        let e_pos = Vector3::from_fn(|i, _| white(white_sigma[i], &mut noise_rng)) + gm;
        let e_vel = Vector3::from_fn(|i, _| white(vel_sigma[i], &mut vel_rng));
        let mut e_pos = e_pos
            + multipath_step(
                spec,
                jump_probability,
                t_rel,
                (&mut jump, &mut jump_until),
                &mut multipath_rng,
            );
        if spec.outliers.probability > 0.0 {
            let hit = uniform(&mut outlier_rng) < spec.outliers.probability;
            let e = Vector3::from_fn(|_, _| white(spec.outliers.sigma_m, &mut outlier_rng));
            if hit {
                e_pos += e;
            }
        }
        let (mut quality, mut sigma) = (spec.quality, reported * spec.reported_sigma_scale);
        if let Some(w) = spec.degradation(t_rel) {
            e_pos *= w.sigma_scale;
            sigma *= w.sigma_scale;
            quality = w.quality;
        }
        if spec.in_outage(t_rel) {
            continue;
        }
        let stamp = (first.time_s + t_rel).min(last.time_s);
        let Some(s) = truth_at(truth, stamp - spec.latency_s) else {
            continue;
        };
        // NEU errors → NED offset.
        let position = s
            .point_position(&lever)
            .offset_by(&Vec3::new(e_pos.x, e_pos.y, -e_pos.z));
        let v_antenna = s.attitude * s.point_velocity_body(&lever);
        let velocity = v_antenna.raw() + Vector3::new(e_vel.x, e_vel.y, -e_vel.z);
        fixes.push(GnssFix {
            time_s: if spec.latency_s == 0.0 {
                s.time_s
            } else {
                stamp
            },
            position,
            quality,
            satellites: spec.satellites,
            position_sigma_neu: sigma,
            velocity_ned: spec.write_velocity.then_some(velocity),
            velocity_sigma_neu: spec.write_velocity.then_some(vel_sigma),
        });
    }
    Ok(fixes)
}
