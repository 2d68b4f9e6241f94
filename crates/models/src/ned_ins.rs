//! The 21-state error model of a WGS-84 NED strapdown INS (spec 40):
//!
//! ```text
//! x = (δr, δv, φ, b_g, b_a, s_g, s_a)      δr, δv: INS minus truth (NED, m, m/s)
//! Ĉ_b^n = (I − [φ×]) C_b^n                 φ: attitude error [rad]
//! ω̃ = ω + b_g + s_g ⊙ ω,  f̃ = f + b_a + s_a ⊙ f   (first-order Gauss–Markov each)
//! δṙ = δv − ω_en × δr
//! δv̇ = [f^n×] φ + C (b_a + f ⊙ s_a) − (2ω_ie + ω_en) × δv + (2g/R) δh e_D
//! φ̇ = −ω_in × φ − C (b_g + ω ⊙ s_g)
//! ```
//!
//! Terms of order v/R and ω_ie·v/R in the position and attitude rows are
//! dropped (below 1e-6 of the kept ones for a land vehicle). Noise comes
//! from datasheet terms ([`ImuNoise`]): velocity and angle random walk give
//! white noise densities VRW², ARW²; a bias instability σ with correlation
//! time τ gives the Gauss–Markov driving density 2σ²/τ (likewise the scale
//! factors).
//!
//! GNSS position with lever arm l (body frame, IMU → antenna):
//! `z = r̂_ant − r_GNSS = δr + [(Ĉ l)×] φ + n`.
//!
//! ```
//! use aidnav_models::ned_ins::{NedErrorModel, STATES};
//! use nalgebra::{Matrix3, Vector3};
//! let m = NedErrorModel::default();
//! let f = m.continuous(&Matrix3::identity(), &Vector3::new(0.0, 0.0, -9.8), &Vector3::zeros(), &Vector3::zeros(), &Vector3::zeros(), 0.7);
//! // At rest (f^n = −g up): a tilt error about east drives the north
//! // velocity error, δv̇_N = −f_D φ_E = g φ_E.
//! assert_eq!(f[(3, 6 + 1)], 9.8);
//! ```

use aidnav_estimation::{SecondOrderPattern, TrailingDiagonal};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};
use serde::{Deserialize, Serialize};

/// Number of states.
pub const STATES: usize = 21;
/// Offset of δr.
pub const POSITION: usize = 0;
/// Offset of δv.
pub const VELOCITY: usize = 3;
/// Offset of φ.
pub const ATTITUDE: usize = 6;
/// Offset of the gyro bias.
pub const GYRO_BIAS: usize = 9;
/// Offset of the accelerometer bias.
pub const ACCEL_BIAS: usize = 12;
/// Offset of the gyro scale factor.
pub const GYRO_SCALE: usize = 15;
/// Offset of the accelerometer scale factor.
pub const ACCEL_SCALE: usize = 18;

/// 21×21 matrix.
pub type Matrix21 = SMatrix<f64, STATES, STATES>;
/// 21-vector.
pub type Vector21 = SVector<f64, STATES>;
/// 3×21 matrix.
pub type Matrix3x21 = SMatrix<f64, 3, STATES>;

/// One value per sensor axis (x, y, z), written in a configuration as one
/// number (every axis) or an array of exactly three.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerAxis(pub [f64; 3]);

impl PerAxis {
    /// The same value on every axis.
    pub const fn all(v: f64) -> Self {
        Self([v; 3])
    }

    /// As a vector.
    pub fn vector(&self) -> Vector3<f64> {
        Vector3::from(self.0)
    }

    /// Every axis × `k`.
    pub fn scaled(&self, k: f64) -> Self {
        Self(self.0.map(|v| v * k))
    }
}

impl Serialize for PerAxis {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let [x, y, z] = self.0;
        if x == y && y == z {
            s.serialize_f64(x)
        } else {
            self.0.serialize(s)
        }
    }
}

impl<'de> Deserialize<'de> for PerAxis {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Written {
            One(f64),
            Axes(Vec<f64>),
        }
        match Written::deserialize(d).map_err(|_| {
            serde::de::Error::custom("a number (every axis) or an array of 3 numbers (x, y, z)")
        })? {
            Written::One(v) => Ok(Self::all(v)),
            Written::Axes(v) => {
                let n = v.len();
                v.try_into().map(Self).map_err(|_| {
                    serde::de::Error::invalid_length(n, &"an array of 3 numbers (x, y, z)")
                })
            }
        }
    }
}

/// Datasheet noise terms of an IMU, per sensor axis (defaults: a consumer
/// MEMS unit). The instrument states start at their stationary σ (the bias
/// instabilities and scale-factor σ below).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ImuNoise {
    /// Angle random walk [deg/√h]. Default 0.6.
    pub arw_deg_per_sqrt_h: PerAxis,
    /// Velocity random walk [m/s/√h]. Default 0.6.
    pub vrw_mps_per_sqrt_h: PerAxis,
    /// Gyro bias instability σ [deg/h]. Default 50.
    pub gyro_bias_deg_per_h: PerAxis,
    /// Accelerometer bias instability σ \[mg\]. Default 2.
    pub accel_bias_mg: PerAxis,
    /// Gyro scale-factor σ \[ppm\]. Default 1000.
    pub gyro_scale_ppm: PerAxis,
    /// Accelerometer scale-factor σ \[ppm\]. Default 1000.
    pub accel_scale_ppm: PerAxis,
    /// Correlation time of the biases (first-order Gauss–Markov) \[s\].
    /// Default 3600.
    pub bias_correlation_s: f64,
    /// Correlation time of the scale factors \[s\]. Default 3600.
    pub scale_correlation_s: f64,
    /// Estimate the six scale-factor states. Off: they are frozen at zero
    /// (no variance, no process noise) — a sensor whose scale factors are
    /// calibrated, or a log too short to see them. Default true.
    pub scale_factors: bool,
}

impl Default for ImuNoise {
    fn default() -> Self {
        Self {
            arw_deg_per_sqrt_h: PerAxis::all(0.6),
            vrw_mps_per_sqrt_h: PerAxis::all(0.6),
            gyro_bias_deg_per_h: PerAxis::all(50.0),
            accel_bias_mg: PerAxis::all(2.0),
            gyro_scale_ppm: PerAxis::all(1000.0),
            accel_scale_ppm: PerAxis::all(1000.0),
            bias_correlation_s: 3600.0,
            scale_correlation_s: 3600.0,
            scale_factors: true,
        }
    }
}

impl ImuNoise {
    /// The σ of the instrument states' stationary distributions per axis,
    /// in SI: gyro bias [rad/s], accelerometer bias [m/s²], gyro and
    /// accelerometer scale factor (zero when `scale_factors` is off).
    pub fn instrument_sigmas(&self) -> [Vector3<f64>; 4] {
        let sf = if self.scale_factors { 1e-6 } else { 0.0 };
        [
            self.gyro_bias_deg_per_h.vector() * (1f64.to_radians() / 3600.0),
            self.accel_bias_mg.vector() * (1e-3 * 9.806_65),
            self.gyro_scale_ppm.vector() * sf,
            self.accel_scale_ppm.vector() * sf,
        ]
    }

    /// White noise densities (ARW², VRW²) per axis in SI: rad²/s, (m/s)²/s.
    pub fn white_densities(&self) -> (Vector3<f64>, Vector3<f64>) {
        let arw = self.arw_deg_per_sqrt_h.vector() * (1f64.to_radians() / 60.0);
        let vrw = self.vrw_mps_per_sqrt_h.vector() / 60.0;
        (arw.component_mul(&arw), vrw.component_mul(&vrw))
    }
}

/// The columns of Q_c's block that holds state `k`.
fn block_of(k: usize) -> std::ops::Range<usize> {
    match k {
        VELOCITY..ATTITUDE => VELOCITY..ATTITUDE,
        ATTITUDE..GYRO_BIAS => ATTITUDE..GYRO_BIAS,
        POSITION..VELOCITY => 0..0,
        _ => k..k + 1,
    }
}

/// The columns that row `i` of F ([`NedErrorModel::continuous`]) may hold
/// a nonzero in, increasing: position (−[ω_en×], I), velocity (the gravity
/// gradient in δr_D, −[(2ω_ie + ω_en)×], [f^n×], C, C diag f), attitude
/// (−[ω_in×], −C, −C diag ω), the instruments their own diagonal.
/// [`NedErrorModel::discrete`] sums over these instead of all 21.
const F_ROW_COLUMNS: [&[usize]; STATES] = {
    const POS: &[usize] = &[0, 1, 2, 3, 4, 5];
    const VEL: &[usize] = &[2, 3, 4, 5, 6, 7, 8, 12, 13, 14, 18, 19, 20];
    const ATT: &[usize] = &[6, 7, 8, 9, 10, 11, 15, 16, 17];
    [
        POS,
        POS,
        POS,
        VEL,
        VEL,
        VEL,
        ATT,
        ATT,
        ATT,
        &[9],
        &[10],
        &[11],
        &[12],
        &[13],
        &[14],
        &[15],
        &[16],
        &[17],
        &[18],
        &[19],
        &[20],
    ]
};

/// [`F_ROW_COLUMNS`] as bit masks (bit j: column j).
const F_ROW_MASKS: [u32; STATES] = {
    let mut masks = [0; STATES];
    let mut i = 0;
    while i < STATES {
        let mut k = 0;
        while k < F_ROW_COLUMNS[i].len() {
            masks[i] |= 1 << F_ROW_COLUMNS[i][k];
            k += 1;
        }
        i += 1;
    }
    masks
};

/// Where F and Q_c may hold nonzeros, for the engine's second-order
/// discretisation: the rows of position, velocity and attitude may couple
/// ([`F_ROW_COLUMNS`]), Q_c has a velocity and an attitude block
/// ([`block_of`]; none for position), the instruments' rows (from
/// [`GYRO_BIAS`] on) hold only their diagonal.
static DISCRETISATION: SecondOrderPattern<STATES, GYRO_BIAS> =
    SecondOrderPattern::new(F_ROW_COLUMNS, &[VELOCITY..ATTITUDE, ATTITUDE..GYRO_BIAS]);

/// Whether every nonzero of `f` lies in [`F_ROW_COLUMNS`].
fn follows_pattern(f: &Matrix21) -> bool {
    (0..STATES).all(|j| (0..STATES).all(|i| F_ROW_MASKS[i] & (1 << j) != 0 || f[(i, j)] == 0.0))
}

/// Whether every element of `m` inside [`F_ROW_COLUMNS`]'s pattern is
/// finite (Σ v·0 over them, as [`all_finite`]).
fn pattern_finite(m: &Matrix21) -> bool {
    let s = m.as_slice();
    let mut sum = 0.0;
    for (i, row) in F_ROW_COLUMNS.iter().enumerate() {
        for &j in row.iter() {
            sum += s[j * STATES + i] * 0.0;
        }
    }
    sum == 0.0
}

/// Whether the elements of a Q_c that [`NedErrorModel::spectral_density`]
/// writes (its velocity and attitude blocks, the instruments' diagonal) are
/// finite; every other element is +0.
fn spectral_density_finite(qc: &Matrix21) -> bool {
    let s = qc.as_slice();
    let mut sum = 0.0;
    for j in VELOCITY..STATES {
        for k in block_of(j) {
            sum += s[j * STATES + k] * 0.0;
        }
    }
    sum == 0.0
}

/// Whether every value is finite: Σ v·0 is ±0 when every v is finite and
/// NaN as soon as one is ±∞ or NaN, over 8 partial sums (no branch, and it
/// vectorises).
fn all_finite(values: &[f64]) -> bool {
    let mut partial = [0.0_f64; 8];
    let chunks = values.chunks_exact(8);
    let rest = chunks.remainder().iter().fold(0.0, |s, &v| s + v * 0.0);
    for chunk in chunks {
        for (s, &v) in partial.iter_mut().zip(chunk) {
            *s += v * 0.0;
        }
    }
    partial.iter().fold(rest, |s, &v| s + v) == 0.0
}

/// [`NedErrorModel::discrete`] for an F with [`continuous`](NedErrorModel::continuous)'s
/// pattern ([`F_ROW_COLUMNS`]), FΔt and Q_c finite: the same sums as
/// [`discrete_of_any`] to the bit, by columns and without a branch.
///
/// Each element of (FΔt)²/2 is summed over the same k in the same
/// increasing order, `0.5 · a · b` each; the terms [`discrete_of_any`]
/// skips for an exact zero a or b are ±0 here, and adding ±0 changes no
/// sum (a sum that starts at +0 or at Φ's first-order term is never −0:
/// x + y = 0 rounds to +0), so the results are equal to the bit. Likewise
/// F Q_c. The engine sums them over [`DISCRETISATION`]
/// ([`SecondOrderPattern::discretise`]).
fn discrete_of_pattern(fdt: &Matrix21, qc: &Matrix21, dt: f64) -> (Matrix21, Matrix21) {
    let (mut phi, mut q) = (Matrix21::zeros(), Matrix21::zeros());
    discrete_of_pattern_into(fdt, qc, dt, &mut phi, &mut q);
    (phi, q)
}

/// [`discrete_of_pattern`] into `phi` and `q` (every element written): the
/// filter's buffers, without two 21 × 21 results copied out on the way.
fn discrete_of_pattern_into(
    fdt: &Matrix21,
    qc: &Matrix21,
    dt: f64,
    phi: &mut Matrix21,
    q: &mut Matrix21,
) {
    DISCRETISATION.discretise(fdt, qc, dt, phi, q);
}

/// [`NedErrorModel::discrete`] for any F: (FΔt)² and F Q_c summed over
/// [`F_ROW_COLUMNS`] when F has that pattern (`pattern`), else over every
/// column, skipping exact zeros.
fn discrete_of_any(fdt: &Matrix21, qc: &Matrix21, dt: f64, pattern: bool) -> (Matrix21, Matrix21) {
    let mut phi = Matrix21::identity() + fdt;
    // (FΔt)²[i, j] = Σ_k FΔt[i, k] FΔt[k, j], summed over the columns k
    // that row i of F may hold ([`F_ROW_COLUMNS`]) and the columns j that
    // row k may hold, each (i, j) in increasing k as the loop over
    // every column adds ½ a b (the tests' reference; not (FΔt)² halved
    // afterwards, which rounds differently) — the same additions in the
    // same order, so the same Φ to the bit.
    // An F with nonzeros elsewhere (not `continuous`'s) is summed over
    // every column.
    const EVERY: [usize; STATES] = {
        let mut all = [0; STATES];
        let mut i = 0;
        while i < STATES {
            all[i] = i;
            i += 1;
        }
        all
    };
    let columns: [&[usize]; STATES] = if pattern {
        F_ROW_COLUMNS
    } else {
        [&EVERY; STATES]
    };
    for (i, row) in columns.iter().enumerate() {
        for &k in row.iter() {
            let a = fdt[(i, k)];
            if a != 0.0 {
                for &j in columns[k].iter() {
                    let b = fdt[(k, j)];
                    if b != 0.0 {
                        phi[(i, j)] += 0.5 * a * b;
                    }
                }
            }
        }
    }
    // (FΔt Q_c)[i, j] = Σ_k FΔt[i, k] Q_c[k, j], Q_c[k, ·] nonzero only
    // within k's block.
    let mut fq = Matrix21::zeros();
    for (i, row) in columns.iter().enumerate() {
        for &k in row.iter() {
            let a = fdt[(i, k)];
            if a != 0.0 {
                for j in block_of(k) {
                    fq[(i, j)] += a * qc[(k, j)];
                }
            }
        }
    }
    let mut q = qc * dt;
    for j in 0..STATES {
        for i in 0..STATES {
            q[(i, j)] += 0.5 * dt * (fq[(i, j)] + fq[(j, i)]);
        }
    }
    (phi, q)
}

/// The model; only the noise is configuration.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NedErrorModel {
    /// IMU noise terms.
    pub noise: ImuNoise,
}

impl NedErrorModel {
    /// The structure of every Φ of [`discrete`](Self::discrete): rows of
    /// position, velocity and attitude error may couple to any state, the
    /// instruments' Gauss–Markov rows (from [`GYRO_BIAS`] on) hold only their
    /// diagonal element — F's rows there are diagonal, so are those of
    /// (FΔt)². The filter's time update costs the 9 leading rows only
    /// ([`KalmanFilter::predict_structured`](aidnav_estimation::KalmanFilter::predict_structured)).
    pub const TRANSITION: TrailingDiagonal = TrailingDiagonal::new(GYRO_BIAS);

    /// F at attitude C_b^n, body specific force f^b and rate ω^b, Earth rate
    /// ω_ie and transport rate ω_en (NED), latitude-free gravity gradient at
    /// about g/R.
    pub fn continuous(
        &self,
        c_bn: &Matrix3<f64>,
        f_body: &Vector3<f64>,
        w_body: &Vector3<f64>,
        w_ie: &Vector3<f64>,
        w_en: &Vector3<f64>,
        _latitude_rad: f64,
    ) -> Matrix21 {
        let mut f = Matrix21::zeros();
        let f_nav = c_bn * f_body;
        let w_in = w_ie + w_en;
        f.fixed_view_mut::<3, 3>(POSITION, POSITION)
            .copy_from(&-w_en.cross_matrix());
        f.fixed_view_mut::<3, 3>(POSITION, VELOCITY)
            .copy_from(&Matrix3::identity());
        f.fixed_view_mut::<3, 3>(VELOCITY, VELOCITY)
            .copy_from(&-(2.0 * w_ie + w_en).cross_matrix());
        f.fixed_view_mut::<3, 3>(VELOCITY, ATTITUDE)
            .copy_from(&f_nav.cross_matrix());
        f.fixed_view_mut::<3, 3>(VELOCITY, ACCEL_BIAS)
            .copy_from(c_bn);
        f.fixed_view_mut::<3, 3>(VELOCITY, ACCEL_SCALE)
            .copy_from(&(c_bn * Matrix3::from_diagonal(f_body)));
        // Vertical channel: gravity grows as the INS sinks (δr_D > 0 ⇒ δg > 0).
        f[(VELOCITY + 2, POSITION + 2)] = 2.0 * 9.8 / 6.371e6;
        f.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&-w_in.cross_matrix());
        f.fixed_view_mut::<3, 3>(ATTITUDE, GYRO_BIAS)
            .copy_from(&-c_bn);
        f.fixed_view_mut::<3, 3>(ATTITUDE, GYRO_SCALE)
            .copy_from(&-(c_bn * Matrix3::from_diagonal(w_body)));
        for i in GYRO_BIAS..GYRO_SCALE {
            f[(i, i)] = -1.0 / self.noise.bias_correlation_s;
        }
        for i in GYRO_SCALE..STATES {
            f[(i, i)] = -1.0 / self.noise.scale_correlation_s;
        }
        f
    }

    /// Φ = I + FΔt + (FΔt)²/2 and Q = Q_c Δt + (F Q_c + Q_c Fᵀ) Δt²/2 (both
    /// to second order) at attitude C_b^n (the sensors' per-axis white noise
    /// seen in NED). F is sparse — about 60 of 441 entries — and Q_c block
    /// diagonal (3×3 blocks for velocity and attitude, diagonal for the
    /// instruments), so neither needs a dense product: this runs at the
    /// filter's covariance rate, 20 Hz, and dense 21³ products were 40 % of
    /// a pass.
    pub fn discrete(&self, f: &Matrix21, c_bn: &Matrix3<f64>, dt: f64) -> (Matrix21, Matrix21) {
        // `map`, not `f * dt`: the same products, written once (the
        // product clones f first).
        let fdt = f.map(|v| v * dt);
        let qc = self.spectral_density(c_bn);
        let pattern = follows_pattern(f);
        if pattern && all_finite(fdt.as_slice()) && all_finite(qc.as_slice()) {
            discrete_of_pattern(&fdt, &qc, dt)
        } else {
            discrete_of_any(&fdt, &qc, dt, pattern)
        }
    }

    /// [`discrete`](Self::discrete) of [`continuous`](Self::continuous)'s F
    /// at these arguments, bit for bit, into the caller's Φ and Q (every
    /// element written), `rates` = (f^b, ω^b, ω_ie, ω_en), for the filter's
    /// covariance rate: that F has the pattern `discrete` checks for by
    /// construction (every element outside it is never written, +0), so it
    /// is not checked, and FΔt and Q_c are finite exactly when Δt, F's
    /// blocks and Q_c's blocks are (an element never written is +0, and
    /// +0 · Δt is finite for a finite Δt), so only those are checked. The
    /// filter keeps the two buffers: a 21 × 21 result returned by value is
    /// copied on its way out (twice per flush, a memory copy each).
    pub fn transition_into(
        &self,
        c_bn: &Matrix3<f64>,
        [f_body, w_body, w_ie, w_en]: [&Vector3<f64>; 4],
        latitude_rad: f64,
        dt: f64,
        (phi, q): (&mut Matrix21, &mut Matrix21),
    ) {
        let mut fdt = self.continuous(c_bn, f_body, w_body, w_ie, w_en, latitude_rad);
        debug_assert!(follows_pattern(&fdt));
        // F Δt in place (`map` builds a new matrix and copies it out).
        for v in fdt.as_mut_slice() {
            *v *= dt;
        }
        let qc = self.spectral_density(c_bn);
        if dt.is_finite() && pattern_finite(&fdt) && spectral_density_finite(&qc) {
            discrete_of_pattern_into(&fdt, &qc, dt, phi, q);
        } else {
            (*phi, *q) = discrete_of_any(&fdt, &qc, dt, true);
        }
    }

    /// The continuous white-noise density Q_c at attitude C_b^n: velocity
    /// and attitude blocks `C diag(VRW², ARW² per sensor axis) Cᵀ` (NED),
    /// the instruments' Gauss–Markov densities `2σ²/τ` on the diagonal.
    pub fn spectral_density(&self, c_bn: &Matrix3<f64>) -> Matrix21 {
        let (arw2, vrw2) = self.noise.white_densities();
        let [sg, sa, kg, ka] = self.noise.instrument_sigmas();
        let (tb, ts) = (
            self.noise.bias_correlation_s,
            self.noise.scale_correlation_s,
        );
        // Exactly symmetric blocks (rounding of C D Cᵀ is not).
        let ned = |d: &Vector3<f64>| {
            let b = c_bn * Matrix3::from_diagonal(d) * c_bn.transpose();
            (b + b.transpose()) * 0.5
        };
        let mut qc = Matrix21::zeros();
        qc.fixed_view_mut::<3, 3>(VELOCITY, VELOCITY)
            .copy_from(&ned(&vrw2));
        qc.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&ned(&arw2));
        for i in 0..3 {
            qc[(GYRO_BIAS + i, GYRO_BIAS + i)] = 2.0 * sg[i] * sg[i] / tb;
            qc[(ACCEL_BIAS + i, ACCEL_BIAS + i)] = 2.0 * sa[i] * sa[i] / tb;
            qc[(GYRO_SCALE + i, GYRO_SCALE + i)] = 2.0 * kg[i] * kg[i] / ts;
            qc[(ACCEL_SCALE + i, ACCEL_SCALE + i)] = 2.0 * ka[i] * ka[i] / ts;
        }
        qc
    }

    /// H of a GNSS position fix with lever arm `lever_nav` = Ĉ l (NED).
    pub fn position_measurement(lever_nav: &Vector3<f64>) -> Matrix3x21 {
        let mut h = Matrix3x21::zeros();
        h.fixed_view_mut::<3, 3>(0, POSITION)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, ATTITUDE)
            .copy_from(&lever_nav.cross_matrix());
        h
    }

    /// H of the non-holonomic constraint (a land vehicle's lateral and
    /// vertical body velocity are zero): rows y and z of
    /// `δv^b = Cᵀ δv − Cᵀ [v×] φ` at attitude C_b^n and NED velocity v
    /// (for a vehicle frame misaligned against the body, pass
    /// `C_v^n = C_b^n C_vbᵀ`: the rows are then the vehicle's axes).
    pub fn non_holonomic_measurement(
        c_bn: &Matrix3<f64>,
        velocity: &Vector3<f64>,
    ) -> SMatrix<f64, 2, STATES> {
        let ct = c_bn.transpose();
        let dv = ct;
        let dphi = -(ct * velocity.cross_matrix());
        let mut h = SMatrix::<f64, 2, STATES>::zeros();
        for r in 0..2 {
            for c in 0..3 {
                h[(r, VELOCITY + c)] = dv[(r + 1, c)];
                h[(r, ATTITUDE + c)] = dphi[(r + 1, c)];
            }
        }
        h
    }

    /// H of a GNSS velocity fix; `lever_velocity_nav` = Ĉ (ω × l) (NED).
    pub fn velocity_measurement(lever_velocity_nav: &Vector3<f64>) -> Matrix3x21 {
        let mut h = Matrix3x21::zeros();
        h.fixed_view_mut::<3, 3>(0, VELOCITY)
            .copy_from(&Matrix3::identity());
        h.fixed_view_mut::<3, 3>(0, ATTITUDE)
            .copy_from(&lever_velocity_nav.cross_matrix());
        h
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sparse Φ and Q against the dense formulas.
    #[test]
    fn sparse_discretisation_matches_the_dense_one() {
        // Different noise per axis, so the NED blocks are full.
        let m = NedErrorModel {
            noise: ImuNoise {
                arw_deg_per_sqrt_h: PerAxis([0.3, 0.6, 1.2]),
                vrw_mps_per_sqrt_h: PerAxis([0.1, 0.2, 0.5]),
                gyro_bias_deg_per_h: PerAxis([10.0, 20.0, 30.0]),
                bias_correlation_s: 1000.0,
                ..ImuNoise::default()
            },
        };
        let c = nalgebra::Rotation3::from_euler_angles(0.1, -0.05, 2.0).into_inner();
        let f = m.continuous(
            &c,
            &Vector3::new(0.5, -0.3, -9.8),
            &Vector3::new(0.01, -0.02, 0.3),
            &Vector3::new(5e-5, 0.0, -4e-5),
            &Vector3::new(1e-6, -2e-6, 1e-6),
            0.7,
        );
        let dt = 0.05;
        let (phi, q) = m.discrete(&f, &c, dt);
        let fdt = f * dt;
        let dense_phi = Matrix21::identity() + fdt + fdt * fdt * 0.5;
        let qc = m.spectral_density(&c);
        let dense_q = qc * dt + (f * qc + qc * f.transpose()) * (0.5 * dt * dt);
        assert!((phi - dense_phi).abs().max() < 1e-15);
        assert!((q - dense_q).abs().max() < 1e-18);
        assert!((q - q.transpose()).abs().max() == 0.0);
        // The declared structure holds, and no tighter one does.
        assert!(NedErrorModel::TRANSITION.holds(&phi));
        assert_eq!(TrailingDiagonal::of(&phi), NedErrorModel::TRANSITION);
    }

    /// The loop over every (k, i, j) that `discrete` replaced: the
    /// reference its Φ and Q must equal to the bit.
    fn discrete_every_column(
        m: &NedErrorModel,
        f: &Matrix21,
        c_bn: &Matrix3<f64>,
        dt: f64,
    ) -> (Matrix21, Matrix21) {
        let fdt = f * dt;
        let mut phi = Matrix21::identity() + fdt;
        for k in 0..STATES {
            for i in 0..STATES {
                let a = fdt[(i, k)];
                if a != 0.0 {
                    for j in 0..STATES {
                        let b = fdt[(k, j)];
                        if b != 0.0 {
                            phi[(i, j)] += 0.5 * a * b;
                        }
                    }
                }
            }
        }
        let qc = m.spectral_density(c_bn);
        let mut fq = Matrix21::zeros();
        for k in 0..STATES {
            for i in 0..STATES {
                let a = fdt[(i, k)];
                if a != 0.0 {
                    for j in block_of(k) {
                        fq[(i, j)] += a * qc[(k, j)];
                    }
                }
            }
        }
        let mut q = qc * dt;
        for j in 0..STATES {
            for i in 0..STATES {
                q[(i, j)] += 0.5 * dt * (fq[(i, j)] + fq[(j, i)]);
            }
        }
        (phi, q)
    }

    /// Bitwise equal to the loop over every column, for `continuous`'s F
    /// and for an F with nonzeros outside its pattern.
    #[test]
    fn the_pattern_loop_equals_the_loop_over_every_column_bitwise() {
        let m = NedErrorModel::default();
        let c = nalgebra::Rotation3::from_euler_angles(-0.3, 0.2, 1.1).into_inner();
        let f = m.continuous(
            &c,
            &Vector3::new(1.5, -0.7, -9.6),
            &Vector3::new(0.03, 0.01, -0.2),
            &Vector3::new(5e-5, 0.0, -4e-5),
            &Vector3::new(2e-6, 1e-6, -3e-6),
            0.5,
        );
        let mut dense = f;
        for (n, v) in dense.iter_mut().enumerate() {
            if *v == 0.0 && n % 7 == 3 {
                *v = 1e-3 * (n as f64).sin();
            }
        }
        assert!(follows_pattern(&f) && !follows_pattern(&dense));
        for f in [f, dense] {
            let (phi, q) = m.discrete(&f, &c, 0.05);
            let (phi_ref, q_ref) = discrete_every_column(&m, &f, &c, 0.05);
            let bits = |a: &Matrix21| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&phi), bits(&phi_ref));
            assert_eq!(bits(&q), bits(&q_ref));
        }
    }

    /// A random attitude (roll, pitch, yaw over most of their ranges).
    fn random_attitude(rng: &mut impl rand::Rng) -> Matrix3<f64> {
        use rand::RngExt;
        nalgebra::Rotation3::from_euler_angles(
            rng.random_range(-3.0..3.0),
            rng.random_range(-1.5..1.5),
            rng.random_range(-3.0..3.0),
        )
        .into_inner()
    }

    /// A random vector of magnitude up to `scale` per element, with exact
    /// +0 and −0 elements a third of the time.
    fn random_vector(rng: &mut impl rand::Rng, scale: f64) -> Vector3<f64> {
        use rand::RngExt;
        Vector3::from_fn(|_, _| match rng.random_range(0..6) {
            0 => 0.0,
            1 => -0.0,
            _ => scale * rng.random_range(-1.0..1.0),
        })
    }

    /// The bits of every element, NaN as None (any NaN payload).
    fn nan_or_bits(a: &Matrix21) -> Vec<Option<u64>> {
        a.iter()
            .map(|v| if v.is_nan() { None } else { Some(v.to_bits()) })
            .collect()
    }

    /// The branch-free column path (`continuous`'s pattern, finite values)
    /// equals the loop over every column to the bit on random models and
    /// states — zero rates and forces, exact zeros and −0 inside the
    /// pattern, per-axis noise, scale factors off — and a non-finite F takes
    /// the general path (the same NaN and infinity positions).
    #[test]
    fn the_column_path_equals_the_loop_over_every_column_bitwise() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(40);
        let bits = |a: &Matrix21| a.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for case in 0..400 {
            let axes = |rng: &mut rand_chacha::ChaCha8Rng, scale: f64| {
                PerAxis([0, 1, 2].map(|_| scale * rng.random_range(0.1..3.0)))
            };
            let m = NedErrorModel {
                noise: ImuNoise {
                    arw_deg_per_sqrt_h: axes(&mut rng, 1.0),
                    vrw_mps_per_sqrt_h: axes(&mut rng, 0.3),
                    gyro_bias_deg_per_h: axes(&mut rng, 20.0),
                    accel_bias_mg: axes(&mut rng, 2.0),
                    gyro_scale_ppm: axes(&mut rng, 500.0),
                    accel_scale_ppm: axes(&mut rng, 500.0),
                    bias_correlation_s: rng.random_range(10.0..5000.0),
                    scale_correlation_s: rng.random_range(10.0..5000.0),
                    scale_factors: case % 5 != 0,
                },
            };
            let c = random_attitude(&mut rng);
            let mut vector = |scale: f64| random_vector(&mut rng, scale);
            let (force, rate) = (vector(12.0), vector(1.0));
            let (w_ie, w_en) = (vector(7.3e-5), vector(1e-5));
            let mut f = m.continuous(&c, &force, &rate, &w_ie, &w_en, 0.6);
            if case % 7 == 0 {
                // Exact zeros and −0 at places of the pattern.
                f[(3, 7)] = 0.0;
                f[(7, 16)] = -0.0;
                f[(0, 4)] = -0.0;
            }
            let dt = [0.05, 0.01, 0.0123, 1.0][case % 4];
            assert!(follows_pattern(&f));
            let (phi, q) = m.discrete(&f, &c, dt);
            let (phi_ref, q_ref) = discrete_every_column(&m, &f, &c, dt);
            assert_eq!(bits(&phi), bits(&phi_ref), "case {case}");
            assert_eq!(bits(&q), bits(&q_ref), "case {case}");
        }
        let c = Matrix3::identity();
        let m = NedErrorModel::default();
        let mut f = m.continuous(
            &c,
            &Vector3::new(0.1, 0.2, -9.8),
            &Vector3::new(0.01, 0.02, 0.03),
            &Vector3::new(5e-5, 0.0, -4e-5),
            &Vector3::new(1e-6, 0.0, 1e-6),
            0.6,
        );
        f[(4, 6)] = f64::NAN;
        f[(7, 9)] = f64::INFINITY;
        let (phi, q) = m.discrete(&f, &c, 0.05);
        let (phi_ref, q_ref) = discrete_every_column(&m, &f, &c, 0.05);
        assert_eq!(nan_or_bits(&phi), nan_or_bits(&phi_ref));
        assert_eq!(nan_or_bits(&q), nan_or_bits(&q_ref));
    }

    /// `transition_into` (no pattern check, finiteness of the written
    /// elements only; every element of Φ and Q written) equals `discrete` of `continuous`'s F to the bit on random
    /// states, and with a NaN or infinite input (a force, a rate, Δt) the
    /// same NaN and infinity positions.
    #[test]
    fn transition_equals_discrete_of_continuous_bitwise() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(41);
        for case in 0..300 {
            let m = NedErrorModel {
                noise: ImuNoise {
                    arw_deg_per_sqrt_h: PerAxis::all(rng.random_range(0.1..20.0)),
                    scale_factors: case % 3 != 0,
                    ..ImuNoise::default()
                },
            };
            let c = random_attitude(&mut rng);
            let mut vector = |scale: f64| random_vector(&mut rng, scale);
            let (mut force, rate) = (vector(12.0), vector(1.0));
            let (w_ie, w_en) = (vector(7.3e-5), vector(1e-5));
            let mut dt = [0.05, 0.01, 0.0123, 1.0][case % 4];
            match case % 25 {
                5 => force[1] = f64::NAN,
                10 => force[2] = f64::INFINITY,
                15 => dt = f64::INFINITY,
                20 => dt = f64::NAN,
                _ => {}
            }
            // NaN-filled buffers: an element left unwritten shows.
            let (mut phi, mut q) = (Matrix21::repeat(f64::NAN), Matrix21::repeat(f64::NAN));
            let rates = [&force, &rate, &w_ie, &w_en];
            m.transition_into(&c, rates, 0.6, dt, (&mut phi, &mut q));
            let f = m.continuous(&c, &force, &rate, &w_ie, &w_en, 0.6);
            let (phi_ref, q_ref) = m.discrete(&f, &c, dt);
            assert_eq!(nan_or_bits(&phi), nan_or_bits(&phi_ref), "case {case}");
            assert_eq!(nan_or_bits(&q), nan_or_bits(&q_ref), "case {case}");
        }
    }

    #[test]
    fn gauss_markov_noise_keeps_the_datasheet_sigma() {
        let m = NedErrorModel::default();
        let f = m.continuous(
            &Matrix3::identity(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            &Vector3::zeros(),
            0.0,
        );
        let (phi, q) = m.discrete(&f, &Matrix3::identity(), 1.0);
        let i = ACCEL_BIAS;
        let mut p = 0.0;
        for _ in 0..50_000 {
            p = phi[(i, i)] * p * phi[(i, i)] + q[(i, i)];
        }
        let sigma = m.noise.instrument_sigmas()[1].x;
        assert!((p.sqrt() / sigma - 1.0).abs() < 1e-3);
    }

    /// The non-holonomic rows against a perturbed attitude and velocity.
    #[test]
    fn non_holonomic_rows_match_a_perturbation() {
        let c = nalgebra::Rotation3::from_euler_angles(0.05, -0.03, 2.0).into_inner();
        let v = c * Vector3::new(15.0, 0.0, 0.0);
        let phi = Vector3::new(2e-4, -1e-4, 3e-4);
        let dv = Vector3::new(0.02, -0.01, 0.03);
        let c_hat = (Matrix3::identity() - phi.cross_matrix()) * c;
        let body = c_hat.transpose() * (v + dv);
        let h = NedErrorModel::non_holonomic_measurement(&c_hat, &(v + dv));
        let mut x = Vector21::zeros();
        x.fixed_rows_mut::<3>(ATTITUDE).copy_from(&phi);
        x.fixed_rows_mut::<3>(VELOCITY).copy_from(&dv);
        let predicted = h * x;
        assert!((predicted[0] - body.y).abs() < 1e-3 * body.y.abs().max(1e-3));
        assert!((predicted[1] - body.z).abs() < 1e-3 * body.z.abs().max(1e-3));
    }

    /// The lever-arm row against a direct perturbation of the attitude.
    #[test]
    fn lever_arm_row_matches_a_perturbed_attitude() {
        let c = nalgebra::Rotation3::from_euler_angles(0.1, 0.2, 1.0).into_inner();
        let l = Vector3::new(0.3, -0.05, -0.65);
        let phi = Vector3::new(1e-4, -2e-4, 3e-4);
        let c_hat = (Matrix3::identity() - phi.cross_matrix()) * c;
        let direct = c_hat * l - c * l;
        let h = NedErrorModel::position_measurement(&(c_hat * l));
        let mut x = Vector21::zeros();
        x.fixed_rows_mut::<3>(ATTITUDE).copy_from(&phi);
        // Equal to first order; the rest is O(φ²) ≈ 1e-7 m here.
        assert!((h * x - direct).norm() < 1e-3 * direct.norm());
    }
}
