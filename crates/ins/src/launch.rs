//! The launch-frame INS of spec 10 (seed 000): navigation equation
//! `r̈ = Dᵀ f_B + g(r)` integrated from the measured attitude angles and
//! specific force, and the twelve slowly varying instrument errors
//! (paper's ММО): accelerometer bias and scale factor, attitude-angle offset
//! and drift, per axis.
//!
//! ```
//! use aidnav_frames::launch::LaunchAttitude;
//! use aidnav_ins::launch::LaunchInstrumentErrors;
//! use nalgebra::Vector3;
//! let e = LaunchInstrumentErrors::table2(1.0);
//! let truth = LaunchAttitude { yaw: 0.0, pitch: 1.0, roll: 0.0 };
//! let f = Vector3::new(30.0, 0.0, 0.0);
//! let (att, f_meas) = e.measure(10.0, &truth, &f);
//! assert!((att.pitch - (1.0 + 5.25e-2 + 2.33e-4 * 10.0)).abs() < 1e-15);
//! let (att_back, f_back) = e.correct(10.0, &att, &f_meas);
//! assert!((att_back.pitch - 1.0).abs() < 1e-15 && (f_back - f).norm() < 1e-12);
//! ```

use aidnav_frames::constants::{EARTH_MEAN_RADIUS_M, GM_M3_S2};
use aidnav_frames::launch::{LaunchAttitude, central_gravity};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// The twelve instrument errors (spec 10): `f̃ = f + Δa0 + K ⊙ f` per
/// accelerometer axis and `b̃ = b + Δb0 + ω_b t` per angle (ψ, ϑ, γ).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LaunchInstrumentErrors {
    /// Accelerometer biases Δa0 (X1, Y1, Z1) [m/s²].
    pub accel_bias: Vector3<f64>,
    /// Accelerometer scale-factor errors K (X1, Y1, Z1).
    pub accel_scale: Vector3<f64>,
    /// Angle offsets Δb0 (ψ, ϑ, γ) \[rad\].
    pub angle_offset: Vector3<f64>,
    /// Angle drifts ω_b (ψ, ϑ, γ) [rad/s].
    pub angle_drift: Vector3<f64>,
}

/// Number of instrument errors the filter estimates (paper eq. 2).
pub const ESTIMATED: usize = 8;

impl LaunchInstrumentErrors {
    /// Table 2 of the paper, every component with the sign `sign` (±1).
    pub fn table2(sign: f64) -> Self {
        Self::table2_signed(&[sign; 12])
    }

    /// Table 2 with a sign per component, in the order bias x y z, scale
    /// x y z, offset ψ ϑ γ, drift ψ ϑ γ.
    pub fn table2_signed(signs: &[f64; 12]) -> Self {
        let v = |i: usize, value: f64| {
            Vector3::new(signs[i] * value, signs[i + 1] * value, signs[i + 2] * value)
        };
        Self {
            accel_bias: v(0, 5.01e-2),
            accel_scale: v(3, 2.46e-2),
            angle_offset: v(6, 5.25e-2),
            angle_drift: v(9, 2.33e-4),
        }
    }

    /// The errors an 8-state estimate `(Δẍ10, Δÿ10, Δz̈10, K_ẍ1, Δψ0, Δϑ0,
    /// ω_ψ, ω_ϑ)` stands for (the four unestimated ones zero).
    pub fn from_estimate(x: &[f64; ESTIMATED]) -> Self {
        Self {
            accel_bias: Vector3::new(x[0], x[1], x[2]),
            accel_scale: Vector3::new(x[3], 0.0, 0.0),
            angle_offset: Vector3::new(x[4], x[5], 0.0),
            angle_drift: Vector3::new(x[6], x[7], 0.0),
        }
    }

    /// The eight estimated components, in the filter's order.
    pub fn estimated_components(&self) -> [f64; ESTIMATED] {
        [
            self.accel_bias.x,
            self.accel_bias.y,
            self.accel_bias.z,
            self.accel_scale.x,
            self.angle_offset.x,
            self.angle_offset.y,
            self.angle_drift.x,
            self.angle_drift.y,
        ]
    }

    /// Angle errors (yaw, pitch, roll) at time t: offset plus drift.
    #[inline]
    fn angle_error(&self, t: f64) -> Vector3<f64> {
        let e = |k: usize| self.angle_offset[k] + self.angle_drift[k] * t;
        Vector3::new(e(0), e(1), e(2))
    }

    /// Instrument outputs for the true attitude and specific force at time t.
    pub fn measure(
        &self,
        t: f64,
        attitude: &LaunchAttitude,
        force: &Vector3<f64>,
    ) -> (LaunchAttitude, Vector3<f64>) {
        let angle = self.angle_error(t);
        (
            LaunchAttitude {
                yaw: attitude.yaw + angle[0],
                pitch: attitude.pitch + angle[1],
                roll: attitude.roll + angle[2],
            },
            force + self.accel_bias + self.accel_scale.component_mul(force),
        )
    }

    /// Correct instrument outputs with these errors (the inverse of
    /// [`measure`](Self::measure)).
    pub fn correct(
        &self,
        t: f64,
        attitude: &LaunchAttitude,
        force: &Vector3<f64>,
    ) -> (LaunchAttitude, Vector3<f64>) {
        let angle = self.angle_error(t);
        // Written out per component (the same operations as
        // `(f − Δa0).component_div(1 + K)`): flight loops call this for
        // every RK4 sample.
        let f = |k: usize| (force[k] - self.accel_bias[k]) / (1.0 + self.accel_scale[k]);
        (
            LaunchAttitude {
                yaw: attitude.yaw - angle[0],
                pitch: attitude.pitch - angle[1],
                roll: attitude.roll - angle[2],
            },
            Vector3::new(f(0), f(1), f(2)),
        )
    }
}

/// Position and velocity of the launch-frame INS.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LaunchIns {
    /// Position in the launch frame \[m\].
    pub position: Vector3<f64>,
    /// Velocity [m/s].
    pub velocity: Vector3<f64>,
}

impl LaunchIns {
    /// One RK4 step of `r̈ = Dᵀ f_B + g(r)` from t to t + dt, with
    /// `sensed(τ)` the attitude and body specific force the INS uses at τ
    /// (instrument outputs, corrected or not).
    pub fn step(
        &mut self,
        t: f64,
        dt: f64,
        sensed: impl Fn(f64) -> (LaunchAttitude, Vector3<f64>),
    ) {
        self.step_with_thrust(dt, &Self::step_thrust(t, dt, sensed));
    }

    /// The non-gravitational acceleration `Dᵀ f_B` in the launch frame from
    /// a sensed attitude and body specific force.
    pub fn thrust(attitude: &LaunchAttitude, force: &Vector3<f64>) -> Vector3<f64> {
        attitude.orientation().transpose() * force
    }

    /// The thrust at the three RK4 times of the step from t to t + dt
    /// (t, t + dt/2, t + dt), as [`step`](Self::step) evaluates it. It does
    /// not depend on the INS state: a caller flying many INS through the
    /// same sensed outputs computes it once per step.
    pub fn step_thrust(
        t: f64,
        dt: f64,
        sensed: impl Fn(f64) -> (LaunchAttitude, Vector3<f64>),
    ) -> [Vector3<f64>; 3] {
        let thrust = |tau: f64| {
            let (att, f) = sensed(tau);
            Self::thrust(&att, &f)
        };
        [thrust(t), thrust(t + dt / 2.0), thrust(t + dt)]
    }

    /// [`step`](Self::step) with the thrust of
    /// [`step_thrust`](Self::step_thrust) given: the same arithmetic.
    pub fn step_with_thrust(&mut self, dt: f64, thrust: &[Vector3<f64>; 3]) {
        Self::step_many(std::array::from_mut(self), dt, [thrust]);
    }

    /// [`step_with_thrust`](Self::step_with_thrust) of `N` independent INS
    /// at once, each with its own thrust: per INS the same operations in
    /// the same order, so the same numbers. Stepped stage by stage, so the
    /// processor overlaps the INS' gravity evaluations (a square root and a
    /// division each, on a chain of four per step) instead of waiting on
    /// one chain.
    pub fn step_many<const N: usize>(
        ins: &mut [LaunchIns; N],
        dt: f64,
        thrust: [&[Vector3<f64>; 3]; N],
    ) {
        let r: [Vector3<f64>; N] = std::array::from_fn(|i| ins[i].position);
        let v: [Vector3<f64>; N] = std::array::from_fn(|i| ins[i].velocity);
        let k1r = v;
        let k1v: [Vector3<f64>; N] = std::array::from_fn(|i| thrust[i][0] + central_gravity(&r[i]));
        let k2r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k1v[i] * (dt / 2.0));
        let k2v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][1] + central_gravity(&(r[i] + k1r[i] * (dt / 2.0))));
        let k3r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k2v[i] * (dt / 2.0));
        let k3v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][1] + central_gravity(&(r[i] + k2r[i] * (dt / 2.0))));
        let k4r: [Vector3<f64>; N] = std::array::from_fn(|i| v[i] + k3v[i] * dt);
        let k4v: [Vector3<f64>; N] =
            std::array::from_fn(|i| thrust[i][2] + central_gravity(&(r[i] + k3r[i] * dt)));
        for i in 0..N {
            ins[i].position += (k1r[i] + 2.0 * k2r[i] + 2.0 * k3r[i] + k4r[i]) * (dt / 6.0);
            ins[i].velocity += (k1v[i] + 2.0 * k2v[i] + 2.0 * k3v[i] + k4v[i]) * (dt / 6.0);
        }
    }
}

/// Many launch INS stepped together: the processor overlaps the INS'
/// gravity evaluations (a square root and a division each, on a chain of
/// four per step that one INS alone must wait on) and does them [`LANES`]
/// INS per vector instruction. Per INS the same operations in the same
/// order as [`LaunchIns::step_with_thrust`], so the same numbers bit for
/// bit. INS join with [`push`](Self::push), get their thrust with
/// [`set_thrust`](Self::set_thrust) before every [`step`](Self::step), and
/// are read back with [`get`](Self::get).
#[derive(Debug, Clone, Default)]
pub struct LaunchInsLanes {
    /// The INS, [`LANES`] per block (the last block's unused lanes fly a
    /// harmless zero state that is never read).
    blocks: Vec<Block>,
    /// Number of INS.
    len: usize,
}

/// INS per block of [`LaunchInsLanes`]: one AVX vector of `f64`.
pub const LANES: usize = 4;

/// One value per lane.
type Lanes = [f64; LANES];

/// [`LANES`] INS by component, with the thrust of their next step and the
/// RK4 stages' scratch.
#[derive(Debug, Clone, Copy, Default)]
struct Block {
    /// Position components (x, y, z), in m.
    r: [Lanes; 3],
    /// Velocity components [m/s].
    v: [Lanes; 3],
    /// Thrust at the three RK4 times (outer index), per component.
    thrust: [[Lanes; 3]; 3],
    /// The RK4 sums of the position and velocity slopes so far.
    sum_r: [Lanes; 3],
    sum_v: [Lanes; 3],
    /// The last stage's position and velocity slopes.
    k_r: [Lanes; 3],
    k_v: [Lanes; 3],
}

/// Lane-wise `a + b`.
#[inline(always)]
fn add(a: Lanes, b: Lanes) -> Lanes {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]
}

/// Lane-wise `a · b`.
#[inline(always)]
fn mul(a: Lanes, b: Lanes) -> Lanes {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2], a[3] * b[3]]
}

/// Every lane of `a` times `s`.
#[inline(always)]
fn scale(a: Lanes, s: f64) -> Lanes {
    mul(a, [s; LANES])
}

/// [`central_gravity`] per lane at `r + offset · h`: the same operations
/// (the centre's offset added to every component, `|·|` as
/// `√((x² + y²) + z²)`, `−c · (μ / (d d d))`).
#[inline(always)]
fn gravity_lanes(r: &[Lanes; 3], offset: &[Lanes; 3], h: f64) -> [Lanes; 3] {
    let point = |k: usize| add(r[k], scale(offset[k], h));
    gravity_at([point(0), point(1), point(2)])
}

/// [`central_gravity`] per lane at `p`.
#[inline(always)]
fn gravity_at(p: [Lanes; 3]) -> [Lanes; 3] {
    let c = [
        add(p[0], [0.0; LANES]),
        add(p[1], [EARTH_MEAN_RADIUS_M; LANES]),
        add(p[2], [0.0; LANES]),
    ];
    let norm2 = add(add(mul(c[0], c[0]), mul(c[1], c[1])), mul(c[2], c[2]));
    let d = [
        norm2[0].sqrt(),
        norm2[1].sqrt(),
        norm2[2].sqrt(),
        norm2[3].sqrt(),
    ];
    let d3 = mul(mul(d, d), d);
    let s = [
        GM_M3_S2 / d3[0],
        GM_M3_S2 / d3[1],
        GM_M3_S2 / d3[2],
        GM_M3_S2 / d3[3],
    ];
    // Written out: `array::map` is not inlined (nor compiled with the
    // caller's target features).
    let neg = |a: Lanes| [-a[0], -a[1], -a[2], -a[3]];
    [mul(neg(c[0]), s), mul(neg(c[1]), s), mul(neg(c[2]), s)]
}

/// Stage 1 of a block's step: `k1r = v`, `k1v = a0 + g(r)`.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // k indexes seven arrays alike
fn stage_first(b: &mut Block) {
    let g = gravity_at(b.r);
    for k in 0..3 {
        let kv = add(b.thrust[0][k], g[k]);
        b.sum_r[k] = b.v[k];
        b.sum_v[k] = kv;
        b.k_r[k] = b.v[k];
        b.k_v[k] = kv;
    }
}

/// Stage 2 or 3 of a block's step: `k_r = v + k_v h/2` and
/// `k_v = a½ + g(r + k_r h/2)` from the previous stage's slopes, added
/// twice to the sums.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // k indexes seven arrays alike
fn stage_middle(b: &mut Block, half: f64) {
    let g = gravity_lanes(&b.r, &b.k_r, half);
    for k in 0..3 {
        let kr = add(b.v[k], scale(b.k_v[k], half));
        let kv = add(b.thrust[1][k], g[k]);
        b.sum_r[k] = add(b.sum_r[k], scale(kr, 2.0));
        b.sum_v[k] = add(b.sum_v[k], scale(kv, 2.0));
        b.k_r[k] = kr;
        b.k_v[k] = kv;
    }
}

/// Stage 4 of a block's step and the update: `k4r = v + k3v h`,
/// `k4v = a1 + g(r + k3r h)`, `r += (sum_r + k4r) h/6`, likewise v.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // k indexes seven arrays alike
fn stage_last(b: &mut Block, dt: f64, sixth: f64) {
    let g = gravity_lanes(&b.r, &b.k_r, dt);
    for k in 0..3 {
        let kr = add(b.v[k], scale(b.k_v[k], dt));
        let kv = add(b.thrust[2][k], g[k]);
        b.r[k] = add(b.r[k], scale(add(b.sum_r[k], kr), sixth));
        b.v[k] = add(b.v[k], scale(add(b.sum_v[k], kv), sixth));
    }
}

/// One RK4 step of every block, stage by stage over all blocks (so the
/// blocks' chains overlap). A block's stage is a call
/// (`#[inline(never)]`): inlined, the compiler would vectorise the loop
/// over the blocks (pairing lane j of two blocks) instead of the block's
/// four lanes.
macro_rules! step_blocks {
    ($(#[$attr:meta])* $step:ident, $first:ident, $middle:ident, $last:ident) => {
        $(#[$attr])*
        #[inline(never)]
        fn $first(b: &mut Block) {
            stage_first(b);
        }

        $(#[$attr])*
        #[inline(never)]
        fn $middle(b: &mut Block, half: f64) {
            stage_middle(b, half);
        }

        $(#[$attr])*
        #[inline(never)]
        fn $last(b: &mut Block, dt: f64, sixth: f64) {
            stage_last(b, dt, sixth);
        }

        $(#[$attr])*
        fn $step(blocks: &mut [Block], dt: f64) {
            let (half, sixth) = (dt / 2.0, dt / 6.0);
            for b in blocks.iter_mut() {
                $first(b);
            }
            for _ in 0..2 {
                for b in blocks.iter_mut() {
                    $middle(b, half);
                }
            }
            for b in blocks.iter_mut() {
                $last(b, dt, sixth);
            }
        }
    };
}

step_blocks!(step_blocks, first_block, middle_block, last_block);

// Compiled with AVX: the same operations, four lanes per instruction (the
// operations are IEEE-exact element-wise ones and Rust never fuses a
// multiply and an add, so the same numbers).
step_blocks!(
    #[cfg(all(target_arch = "x86_64", not(target_feature = "avx")))]
    #[target_feature(enable = "avx")]
    step_blocks_avx,
    first_block_avx,
    middle_block_avx,
    last_block_avx
);

impl LaunchInsLanes {
    /// No INS, room for `capacity`.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            blocks: Vec::with_capacity(capacity.div_ceil(LANES)),
            len: 0,
        }
    }

    /// Number of INS.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there is no INS.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Add an INS (its index: the previous [`len`](Self::len)); its thrust
    /// is zero until [`set_thrust`](Self::set_thrust).
    pub fn push(&mut self, ins: LaunchIns) {
        let (b, j) = (self.len / LANES, self.len % LANES);
        if j == 0 {
            self.blocks.push(Block::default());
        }
        let block = &mut self.blocks[b];
        for k in 0..3 {
            block.r[k][j] = ins.position[k];
            block.v[k][j] = ins.velocity[k];
            for t in &mut block.thrust {
                t[k][j] = 0.0;
            }
        }
        self.len += 1;
    }

    /// INS `i`. Panics if `i ≥ len()`.
    pub fn get(&self, i: usize) -> LaunchIns {
        assert!(i < self.len, "INS {i} of {}", self.len);
        let (b, j) = (&self.blocks[i / LANES], i % LANES);
        LaunchIns {
            position: Vector3::new(b.r[0][j], b.r[1][j], b.r[2][j]),
            velocity: Vector3::new(b.v[0][j], b.v[1][j], b.v[2][j]),
        }
    }

    /// Replace INS `i`'s state (a reset). Panics if `i ≥ len()`.
    pub fn set(&mut self, i: usize, ins: LaunchIns) {
        assert!(i < self.len, "INS {i} of {}", self.len);
        let (b, j) = (&mut self.blocks[i / LANES], i % LANES);
        for k in 0..3 {
            b.r[k][j] = ins.position[k];
            b.v[k][j] = ins.velocity[k];
        }
    }

    /// The thrust INS `i` flies its next step with (as
    /// [`LaunchIns::step_with_thrust`] takes it). Panics if `i ≥ len()`.
    #[inline]
    pub fn set_thrust(&mut self, i: usize, thrust: &[Vector3<f64>; 3]) {
        assert!(i < self.len, "INS {i} of {}", self.len);
        let (b, j) = (&mut self.blocks[i / LANES], i % LANES);
        for (s, t) in thrust.iter().enumerate() {
            for k in 0..3 {
                b.thrust[s][k][j] = t[k];
            }
        }
    }

    /// One RK4 step of every INS with its thrust: per INS,
    /// [`LaunchIns::step_with_thrust`]'s arithmetic. On x86-64 without AVX
    /// enabled at compile time (the portable build) but on a CPU that has
    /// it, compiled with AVX.
    pub fn step(&mut self, dt: f64) {
        #[cfg(all(target_arch = "x86_64", not(target_feature = "avx")))]
        if std::arch::is_x86_feature_detected!("avx") {
            #[allow(unsafe_code)]
            // SAFETY: `step_blocks_avx`'s only requirement is that the CPU
            // executes AVX instructions, which was just detected at run time.
            unsafe {
                step_blocks_avx(&mut self.blocks, dt)
            };
            return;
        }
        step_blocks(&mut self.blocks, dt);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One RK4 step written out for a single INS (the form `step_with_thrust`
    /// had before `step_many`): the reference the stage-by-stage form must
    /// match bit for bit.
    fn reference_step(ins: &mut LaunchIns, dt: f64, thrust: &[Vector3<f64>; 3]) {
        let [a0, a_half, a1] = *thrust;
        let (r, v) = (ins.position, ins.velocity);
        let (k1r, k1v) = (v, a0 + central_gravity(&r));
        let (k2r, k2v) = (
            v + k1v * (dt / 2.0),
            a_half + central_gravity(&(r + k1r * (dt / 2.0))),
        );
        let (k3r, k3v) = (
            v + k2v * (dt / 2.0),
            a_half + central_gravity(&(r + k2r * (dt / 2.0))),
        );
        let (k4r, k4v) = (v + k3v * dt, a1 + central_gravity(&(r + k3r * dt)));
        ins.position += (k1r + 2.0 * k2r + 2.0 * k3r + k4r) * (dt / 6.0);
        ins.velocity += (k1v + 2.0 * k2v + 2.0 * k3v + k4v) * (dt / 6.0);
    }

    #[test]
    fn stepping_together_is_stepping_each_alone_bit_for_bit() {
        let start = [
            LaunchIns::default(),
            LaunchIns {
                position: Vector3::new(1.0e3, 2.5e4, -3.0e2),
                velocity: Vector3::new(900.0, 750.0, -12.0),
            },
            LaunchIns {
                position: Vector3::new(-4.0e2, 1.2e5, 7.0e3),
                velocity: Vector3::new(2.1e3, 1.1e3, 40.0),
            },
        ];
        let thrust = |i: usize, k: usize| -> [Vector3<f64>; 3] {
            std::array::from_fn(|j| {
                let s = (i * 7 + k * 3 + j) as f64;
                Vector3::new(20.0 + s.sin(), 30.0 + s.cos(), 0.1 * s.sin())
            })
        };
        let (mut together, mut alone, mut reference) = (start, start, start);
        for k in 0..500 {
            let t: [[Vector3<f64>; 3]; 3] = std::array::from_fn(|i| thrust(i, k));
            LaunchIns::step_many(&mut together, 0.01, [&t[0], &t[1], &t[2]]);
            for i in 0..3 {
                alone[i].step_with_thrust(0.01, &t[i]);
                reference_step(&mut reference[i], 0.01, &t[i]);
            }
        }
        for i in 0..3 {
            assert_eq!(together[i], alone[i]);
            assert_eq!(together[i], reference[i]);
        }
    }

    #[test]
    fn lanes_step_each_ins_bit_for_bit() {
        let start: Vec<LaunchIns> = (0..7)
            .map(|i| {
                let s = i as f64;
                LaunchIns {
                    position: Vector3::new(1.0e3 * s - 2.0e3, 2.5e4 * s, -3.0e2 * s.cos()),
                    velocity: Vector3::new(900.0 + s, 750.0 * s.sin(), -12.0 * s),
                }
            })
            .collect();
        let thrust = |i: usize, k: usize| -> [Vector3<f64>; 3] {
            std::array::from_fn(|j| {
                let s = (i * 7 + k * 3 + j) as f64;
                Vector3::new(20.0 + s.sin(), 30.0 + s.cos(), 0.1 * s.sin())
            })
        };
        let mut lanes = LaunchInsLanes::with_capacity(2);
        let mut alone = start.clone();
        // INS join at different steps, as the flights of different switches.
        for k in 0..400 {
            if k % 50 == 0 && lanes.len() < start.len() {
                lanes.push(alone[lanes.len()]);
            }
            for (i, ins) in alone.iter_mut().enumerate().take(lanes.len()) {
                let t = thrust(i, k);
                lanes.set_thrust(i, &t);
                ins.step_with_thrust(0.01, &t);
            }
            lanes.step(0.01);
            if k == 321 {
                // A reset, as the filter's feedback.
                alone[2].position.x -= 3.5;
                lanes.set(2, alone[2]);
            }
        }
        assert_eq!(lanes.len(), start.len());
        for (i, a) in alone.iter().enumerate() {
            assert_eq!(lanes.get(i), *a);
            assert_ne!(*a, start[i]);
        }
    }
}
