//! The NED filter's error state: spec 40's base 21 states and the optional
//! blocks an aid source or an installation estimate adds behind them.
//!
//! A layout is chosen when the filter is built ([`StateLayout::with`]); its
//! length is the filter's const size `N`, so every layout runs on
//! fixed-size matrices and the plain 21 states keep their fast paths. The
//! base block order is [`aidnav_models::ned_ins`]'s (`POSITION` …
//! `ACCEL_SCALE`); each added block sits at the offset the layout gives it.
//!
//! ```
//! use aidnav_integration::state::{Augmented, BlockDynamics, StateLayout};
//! let layout = StateLayout::base()
//!     .with(Augmented::WheelSpeedScale, BlockDynamics::constant(0.02))
//!     .with(Augmented::BaroBias, BlockDynamics::random_walk(5.0, 0.01));
//! assert_eq!(layout.len(), 23);
//! assert_eq!(layout.offset(Augmented::WheelSpeedScale), Some(21));
//! assert_eq!(layout.offset(Augmented::BaroBias), Some(22));
//! assert_eq!(layout.offset(Augmented::GnssLatency), None);
//! ```

use aidnav_models::ned_ins::STATES;

/// An optional block of error states behind the base 21.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Augmented {
    /// Scale-factor error of a wheel-speed (odometer) sensor (1 state,
    /// dimensionless: measured = (1 + k) × true).
    WheelSpeedScale,
    /// Bias of a barometric height (1 state \[m\]: measured = true + b).
    BaroBias,
    /// Latency of the GNSS time tag (1 state \[s\]).
    GnssLatency,
    /// Misalignment of the vehicle frame against the IMU body frame, its
    /// pitch and yaw (2 states \[rad\]; the roll about the forward axis
    /// leaves the lateral and vertical velocity of a forward motion
    /// unchanged, so no vehicle constraint observes it).
    VehicleMisalignment,
    /// GNSS antenna lever arm (3 states \[m\], body frame).
    LeverArm,
    /// Receiver clock bias and drift (2 states \[m\], \[m/s\]).
    ReceiverClock,
}

impl Augmented {
    /// Number of states in the block.
    pub const fn states(self) -> usize {
        match self {
            Augmented::WheelSpeedScale | Augmented::BaroBias | Augmented::GnssLatency => 1,
            Augmented::LeverArm => 3,
            Augmented::VehicleMisalignment | Augmented::ReceiverClock => 2,
        }
    }

    /// Unit of each of the block's states (in outputs: the name's suffix).
    pub const fn unit(self) -> &'static str {
        match self {
            Augmented::WheelSpeedScale => "",
            Augmented::BaroBias | Augmented::LeverArm => "m",
            Augmented::GnssLatency => "s",
            Augmented::VehicleMisalignment => "rad",
            Augmented::ReceiverClock => "m",
        }
    }

    /// The block's name in outputs (`summary.json`, CSV columns).
    pub const fn name(self) -> &'static str {
        match self {
            Augmented::WheelSpeedScale => "wheel_speed_scale",
            Augmented::BaroBias => "baro_bias",
            Augmented::GnssLatency => "gnss_latency",
            Augmented::VehicleMisalignment => "misalignment",
            Augmented::LeverArm => "lever_arm",
            Augmented::ReceiverClock => "receiver_clock",
        }
    }

    /// The names of the block's states behind its name (`lever_arm_x` …;
    /// empty for a single state).
    pub const fn axis_names(self) -> &'static [&'static str] {
        match self {
            // Body axes: forward, right, down.
            Augmented::LeverArm => &["x", "y", "z"],
            Augmented::VehicleMisalignment => &["pitch", "yaw"],
            Augmented::ReceiverClock => &["bias", "drift"],
            Augmented::WheelSpeedScale | Augmented::BaroBias | Augmented::GnssLatency => &[],
        }
    }
}

/// Prior and dynamics of every state of an added block: a first-order
/// Gauss–Markov process `ẋ = −x/τ + w` with the driving white noise of
/// density `q` (a random walk when τ is infinite, a random constant when q
/// is also 0), discretised exactly: `Φ = e^{−Δt/τ}`,
/// `Q = q τ (1 − e^{−2Δt/τ}) / 2` (`q Δt` as τ → ∞).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlockDynamics {
    /// Prior σ of each state (in the block's unit).
    pub prior_sigma: f64,
    /// Density of the driving noise, σ² per second (unit² / s).
    pub noise_density: f64,
    /// Correlation time τ \[s\] (infinite: a random walk).
    pub correlation_s: f64,
}

impl BlockDynamics {
    /// A random constant with prior σ.
    pub const fn constant(prior_sigma: f64) -> Self {
        Self {
            prior_sigma,
            noise_density: 0.0,
            correlation_s: f64::INFINITY,
        }
    }

    /// A random walk with prior σ whose σ grows by `sigma_per_sqrt_s` in the
    /// square root of every second.
    pub fn random_walk(prior_sigma: f64, sigma_per_sqrt_s: f64) -> Self {
        Self {
            prior_sigma,
            noise_density: sigma_per_sqrt_s * sigma_per_sqrt_s,
            correlation_s: f64::INFINITY,
        }
    }

    /// Φ and Q of one state over `dt_s`.
    pub fn discrete(&self, dt_s: f64) -> (f64, f64) {
        if self.correlation_s.is_finite() && self.correlation_s > 0.0 {
            let phi = (-dt_s / self.correlation_s).exp();
            let q = self.noise_density * self.correlation_s * (1.0 - phi * phi) * 0.5;
            (phi, q)
        } else {
            (1.0, self.noise_density * dt_s)
        }
    }

    /// Whether the values can describe a process: a finite, non-negative
    /// prior σ and density, a positive τ.
    pub fn is_valid(&self) -> bool {
        self.prior_sigma.is_finite()
            && self.prior_sigma >= 0.0
            && self.noise_density.is_finite()
            && self.noise_density >= 0.0
            && self.correlation_s > 0.0
    }
}

/// One added block: what it is, where it sits, how it evolves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Block {
    /// Which block.
    pub kind: Augmented,
    /// Offset of its first state.
    pub offset: usize,
    /// Its prior and dynamics.
    pub dynamics: BlockDynamics,
}

/// The base 21 states and the blocks added behind them, in the order added.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StateLayout {
    blocks: Vec<Block>,
}

impl StateLayout {
    /// The base 21 states alone.
    pub fn base() -> Self {
        Self::default()
    }

    /// This layout with `kind` added behind the present states (a block
    /// already present keeps its place and takes the new dynamics).
    pub fn with(mut self, kind: Augmented, dynamics: BlockDynamics) -> Self {
        if let Some(b) = self.blocks.iter_mut().find(|b| b.kind == kind) {
            b.dynamics = dynamics;
        } else {
            let offset = self.len();
            self.blocks.push(Block {
                kind,
                offset,
                dynamics,
            });
        }
        self
    }

    /// Number of states.
    pub fn len(&self) -> usize {
        STATES + self.blocks.iter().map(|b| b.kind.states()).sum::<usize>()
    }

    /// Never empty: the base states are always there.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Offset of a block's first state (None: not in the layout).
    pub fn offset(&self, kind: Augmented) -> Option<usize> {
        self.blocks
            .iter()
            .find(|b| b.kind == kind)
            .map(|b| b.offset)
    }

    /// The added blocks, in state order.
    pub fn blocks(&self) -> &[Block] {
        &self.blocks
    }

    /// Write every added block's prior σ into its states of `sigmas` (the
    /// base 21 entries untouched): with the base's own σ, the prior of
    /// [`NedFilter::with_layout`](crate::ned::NedFilter::with_layout).
    pub fn fill_block_priors<const N: usize>(&self, sigmas: &mut nalgebra::SVector<f64, N>) {
        for b in &self.blocks {
            for i in b.offset..b.offset + b.kind.states() {
                sigmas[i] = b.dynamics.prior_sigma;
            }
        }
    }

    /// Name of state `i` (`"pos_n"` … for the base, the block's name with
    /// an index for added ones); None past the end.
    pub fn state_name(&self, i: usize) -> Option<String> {
        const BASE: [&str; STATES] = [
            "pos_n",
            "pos_e",
            "pos_d",
            "vel_n",
            "vel_e",
            "vel_d",
            "att_n",
            "att_e",
            "att_d",
            "gyro_bias_x",
            "gyro_bias_y",
            "gyro_bias_z",
            "accel_bias_x",
            "accel_bias_y",
            "accel_bias_z",
            "gyro_scale_x",
            "gyro_scale_y",
            "gyro_scale_z",
            "accel_scale_x",
            "accel_scale_y",
            "accel_scale_z",
        ];
        if i < STATES {
            return Some(BASE[i].to_string());
        }
        let b = self
            .blocks
            .iter()
            .find(|b| i >= b.offset && i < b.offset + b.kind.states())?;
        let k = i - b.offset;
        Some(match b.kind.axis_names().get(k) {
            Some(axis) => format!("{}_{axis}", b.kind.name()),
            None => b.kind.name().to_string(),
        })
    }
}

/// An added state's estimate at some time: what `summary.json`'s
/// `install` lists.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct AddedStateEstimate {
    /// The block the state belongs to.
    #[serde(skip)]
    pub kind: Augmented,
    /// The state's name ([`StateLayout::state_name`]).
    pub name: String,
    /// Its unit (`s`, `m`, `rad`, or empty for a ratio).
    pub unit: &'static str,
    /// The estimate.
    pub value: f64,
    /// Its σ from the filter's covariance.
    pub sigma: f64,
    /// Its prior σ: a σ still near it says the log held little
    /// information on the state.
    pub prior_sigma: f64,
}

impl StateLayout {
    /// Every added state's estimate: the nominal value `parameters[i]`
    /// plus the error estimate `x[i]` not yet fed back, σ from `sigmas`.
    pub fn estimates<const N: usize>(
        &self,
        parameters: &nalgebra::SVector<f64, N>,
        x: &nalgebra::SVector<f64, N>,
        sigmas: &nalgebra::SVector<f64, N>,
    ) -> Vec<AddedStateEstimate> {
        let mut out = Vec::new();
        for b in &self.blocks {
            for i in b.offset..(b.offset + b.kind.states()).min(N) {
                out.push(AddedStateEstimate {
                    kind: b.kind,
                    name: self.state_name(i).unwrap_or_default(),
                    unit: b.kind.unit(),
                    value: parameters[i] + x[i],
                    sigma: sigmas[i],
                    prior_sigma: b.dynamics.prior_sigma,
                });
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The exact Gauss–Markov discretisation against the closed form of
    /// its variance: from x₀ = 0 the variance after t is q τ (1 − e^{−2t/τ}) / 2
    /// however t is cut into steps.
    #[test]
    fn gauss_markov_steps_compose_to_the_closed_form() {
        let d = BlockDynamics {
            prior_sigma: 1.0,
            noise_density: 0.3,
            correlation_s: 40.0,
        };
        let (mut var, dt) = (0.0, 0.05);
        for _ in 0..2000 {
            let (phi, q) = d.discrete(dt);
            var = phi * phi * var + q;
        }
        let t: f64 = 2000.0 * dt;
        let closed = 0.3 * 40.0 * (1.0 - (-2.0 * t / 40.0).exp()) / 2.0;
        assert!((var - closed).abs() < 1e-12 * closed, "{var} vs {closed}");
        // A random walk grows as q t.
        let rw = BlockDynamics::random_walk(0.0, 0.1);
        assert_eq!(rw.discrete(2.0), (1.0, 0.1 * 0.1 * 2.0));
    }

    #[test]
    fn blocks_take_their_places_and_names() {
        let l = StateLayout::base()
            .with(Augmented::LeverArm, BlockDynamics::constant(0.01))
            .with(
                Augmented::VehicleMisalignment,
                BlockDynamics::constant(0.05),
            )
            .with(Augmented::BaroBias, BlockDynamics::constant(3.0));
        assert_eq!(l.len(), 27);
        assert_eq!(l.offset(Augmented::BaroBias), Some(26));
        assert_eq!(l.state_name(22).as_deref(), Some("lever_arm_y"));
        assert_eq!(l.state_name(25).as_deref(), Some("misalignment_yaw"));
        assert_eq!(l.state_name(26).as_deref(), Some("baro_bias"));
        assert_eq!(l.state_name(3).as_deref(), Some("vel_n"));
        assert_eq!(l.state_name(27), None);
        // Adding a block again keeps its place.
        let again = l.with(Augmented::LeverArm, BlockDynamics::constant(0.02));
        assert_eq!(again.len(), 27);
        assert_eq!(again.offset(Augmented::LeverArm), Some(21));
        assert!(!BlockDynamics::constant(f64::NAN).is_valid());
    }
}
