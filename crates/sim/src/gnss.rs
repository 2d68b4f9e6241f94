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
        }
    }
}

impl GnssSpec {
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

/// The fixes of run `run` under master seed `seed` along `truth`.
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
        let Some(s) = truth_at(truth, (first.time_s + t_rel).min(last.time_s)) else {
            continue;
        };
        let gm = Vector3::from_fn(|i, _| {
            if j == 0 {
                markov[i].value()
            } else {
                markov[i].step(dt, &mut markov_rng)
            }
        });
        let e_pos = Vector3::from_fn(|i, _| white(white_sigma[i], &mut noise_rng)) + gm;
        let e_vel = Vector3::from_fn(|i, _| white(vel_sigma[i], &mut vel_rng));
        if spec.in_outage(t_rel) {
            continue;
        }
        // NEU errors → NED offset.
        let position = s
            .point_position(&lever)
            .offset_by(&Vec3::new(e_pos.x, e_pos.y, -e_pos.z));
        let v_antenna = s.attitude * s.point_velocity_body(&lever);
        let velocity = v_antenna.raw() + Vector3::new(e_vel.x, e_vel.y, -e_vel.z);
        fixes.push(GnssFix {
            time_s: s.time_s,
            position,
            quality: spec.quality,
            satellites: spec.satellites,
            position_sigma_neu: reported,
            velocity_ned: spec.write_velocity.then_some(velocity),
            velocity_sigma_neu: spec.write_velocity.then_some(vel_sigma),
        });
    }
    Ok(fixes)
}
