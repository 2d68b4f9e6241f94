//! Spec 40's loosely coupled GNSS/INS filter: the WGS-84 NED mechanization
//! ([`aidnav_ins::ned`]), the 21-state error model
//! ([`aidnav_models::ned_ins`]), GNSS position and velocity updates with the
//! antenna lever arm, closed-loop feedback into the INS and into the
//! instrument corrections (`ω = (ω̃ − b_g) / (1 + s_g)`, likewise f), and
//! any measurement policy of the engine on each update.

use std::any::Any;

use aidnav_estimation::{
    EstimationError, FisherInformation, FixedKalmanFilter, Matrix as ErrorMatrix,
    MeasurementPolicy, Outcome, RtsRecorder, Step, UpdateRecord,
    adaptive::{AnomalyDetector, InnovationFeedbackNoise},
    nalgebra::{Const, U3},
    recovery::{AgreementConfig, AgreementDetector, Update, Verdict},
};
use aidnav_frames::earth::{Geodetic, earth_rate_ned, transport_rate_ned};
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, Matrix21, NedErrorModel, POSITION,
    STATES, VELOCITY, Vector21,
};
use nalgebra::{Matrix3, SMatrix, SVector, Vector3};

use aidnav_ins::ned::{ImuIncrement, NedMechanization, NedState};

use crate::measurements::{Linearized, Measurement, Nominal, on_layout};
use crate::state::StateLayout;

/// The instrument corrections in use, per sensor axis (the body axes).
/// Biases and scale factors stay raw: a scale factor is no vector, and the
/// corrections act component by component.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct InstrumentEstimate {
    /// Gyro bias [rad/s].
    pub gyro_bias: Vector3<f64>,
    /// Accelerometer bias [m/s²].
    pub accel_bias: Vector3<f64>,
    /// Gyro scale factor.
    pub gyro_scale: Vector3<f64>,
    /// Accelerometer scale factor.
    pub accel_scale: Vector3<f64>,
}

impl InstrumentEstimate {
    /// Correct raw increments.
    pub fn correct(&self, raw: &ImuIncrement) -> ImuIncrement {
        let one = Vector3::repeat(1.0);
        ImuIncrement {
            dt_s: raw.dt_s,
            delta_angle: Vec3::assume_in_frame(
                (raw.delta_angle.raw() - self.gyro_bias * raw.dt_s)
                    .component_div(&(one + self.gyro_scale)),
            ),
            delta_velocity: Vec3::assume_in_frame(
                (raw.delta_velocity.raw() - self.accel_bias * raw.dt_s)
                    .component_div(&(one + self.accel_scale)),
            ),
        }
    }
}

/// A navigation state with an error estimate x removed: δr, δv subtracted,
/// the attitude turned by φ (`C = (I + [φ×]) Ĉ`). Feedback, the open-loop
/// output and the smoothed states all apply an estimate this way.
fn corrected<const N: usize>(state: &NedState, x: &SVector<f64, N>) -> NedState {
    // The navigation error states are NED vectors (δr, δv, φ).
    let v3 = |o: usize| Vec3::<Ned>::new(x[o], x[o + 1], x[o + 2]);
    NedState {
        position: state.position.offset_by(&-v3(POSITION)),
        velocity: state.velocity - v3(VELOCITY),
        attitude: Rotation::from_rotation_vector(v3(ATTITUDE)) * state.attitude,
    }
}

/// Record of one GNSS update.
pub type GnssUpdate<const N: usize = STATES> = UpdateRecord<Const<N>, U3>;

/// The columns of [`NedErrorModel::position_measurement`]'s H that are not
/// +0.0 by construction (the IMU position and the attitude error), in
/// increasing order.
const ANTENNA_COLUMNS: [usize; 6] = [
    POSITION,
    POSITION + 1,
    POSITION + 2,
    ATTITUDE,
    ATTITUDE + 1,
    ATTITUDE + 2,
];

/// The antenna position's covariance `H P Hᵀ`, symmetrised, for the H of
/// [`NedErrorModel::position_measurement`] at `lever_nav` = Ĉ l: nalgebra's
/// `h * p * h.transpose()` and `(s + sᵀ) / 2` to the bit, with each sum run
/// over H's six columns that are not +0.0 by construction instead of all 21
/// (a fifth of the arithmetic, at every GNSS epoch of the forward pass and
/// of the smoothed one).
///
/// nalgebra sums each element of a product from its first term on, in
/// order. The terms left out are `p · (+0.0)`, ±0 for a finite P, and adding
/// ±0 changes no sum but one that is itself ±0 (its sign), while a zero
/// partial sum becomes the next nonzero term whatever its sign: the sums
/// differ at most in the sign of a zero result. So an element of either
/// product that ends at ±0, or a P that is not finite (∞ · 0 is NaN), takes
/// nalgebra's formula.
fn antenna_covariance<const N: usize>(
    lever_nav: &Vector3<f64>,
    p: &SMatrix<f64, N, N>,
) -> Matrix3<f64> {
    if !aidnav_estimation::all_finite(p.as_slice()) {
        return antenna_covariance_by_nalgebra(lever_nav, p);
    }
    let h = NedErrorModel::position_measurement(lever_nav);
    let [first, rest @ ..] = ANTENNA_COLUMNS;
    // H P on H's columns: hp[(i, c)] = (H P)(i, ANTENNA_COLUMNS[c]).
    let mut hp = SMatrix::<f64, 3, 6>::zeros();
    for (c, &j) in ANTENNA_COLUMNS.iter().enumerate() {
        for i in 0..3 {
            let mut sum = p[(first, j)] * h[(i, first)];
            for &k in &rest {
                sum += p[(k, j)] * h[(i, k)];
            }
            hp[(i, c)] = sum;
        }
    }
    // (H P) Hᵀ: element (i, l) sums (H P)(i, k) · H(l, k) over k.
    let mut s = Matrix3::zeros();
    for l in 0..3 {
        for i in 0..3 {
            let mut sum = h[(l, first)] * hp[(i, 0)];
            for (c, &k) in rest.iter().enumerate() {
                sum += h[(l, k)] * hp[(i, c + 1)];
            }
            s[(i, l)] = sum;
        }
    }
    if hp.iter().chain(s.iter()).any(|&v| v == 0.0) {
        return antenna_covariance_by_nalgebra(lever_nav, p);
    }
    (s + s.transpose()) * 0.5
}

/// [`antenna_covariance`] by nalgebra's dense products over all 21 columns:
/// its fallback, and the reference its test compares with.
fn antenna_covariance_by_nalgebra<const N: usize>(
    lever_nav: &Vector3<f64>,
    p: &SMatrix<f64, N, N>,
) -> Matrix3<f64> {
    let h: SMatrix<f64, 3, N> = on_layout(&NedErrorModel::position_measurement(lever_nav));
    let s = h * p * h.transpose();
    (s + s.transpose()) * 0.5
}

/// [`antenna_covariance`] of a layout: with a lever-arm state the antenna
/// error also holds `−C δl` (`c` the attitude matrix, `lever_arm` the body
/// frame's).
fn antenna_covariance_on<const N: usize>(
    layout: &StateLayout,
    c: &Matrix3<f64>,
    lever_arm: &Vector3<f64>,
    p: &SMatrix<f64, N, N>,
) -> Matrix3<f64> {
    let lever_nav = c * lever_arm;
    let Some(o) = layout.offset(crate::state::Augmented::LeverArm) else {
        return antenna_covariance(&lever_nav, p);
    };
    let mut h: SMatrix<f64, 3, N> = on_layout(&NedErrorModel::position_measurement(&lever_nav));
    h.fixed_view_mut::<3, 3>(0, o).copy_from(&-c);
    let s = h * p * h.transpose();
    (s + s.transpose()) * 0.5
}

/// Bytes a smoothing run keeps per smoothed (marked) epoch: the
/// recorder's backward map, the nominal state, and the smoothed state with
/// its antenna covariance. Independent of the IMU rate and of the updates
/// between marks.
pub const BYTES_PER_SMOOTHED_EPOCH: usize = RtsRecorder::<STATES>::BYTES_PER_MARK
    + std::mem::size_of::<NedState>()
    + std::mem::size_of::<SmoothedAntenna>();

/// The forward pass kept for the Rauch–Tung–Striebel smoother, in the
/// closed-loop form: one epoch per covariance propagation, the updates at
/// that time folded into it. Errors are relative to the nominal state
/// *after* the epoch's feedback, so the filtered error is 0 and the
/// predicted one is minus the feedback δ applied at the epoch. The engine's
/// [`RtsRecorder`] keeps only what the backward pass needs at the marked
/// epochs (the GNSS epochs of the epoch loop); it runs on a worker thread
/// beside the filter (`recording`: same calls, same numbers).
#[derive(Debug, Clone)]
struct ForwardRecord<const N: usize> {
    rts: crate::recording::Recording<N>,
    /// The open epoch's nominal state (after its feedback so far).
    open_state: NedState,
    /// The nominal state of every marked epoch.
    states: Vec<NedState>,
}

/// The forward pass in full, for the test that checks [`RtsRecorder`]
/// against the engine's stored-pass smoother on this filter.
#[cfg(test)]
#[derive(Debug, Clone, Default)]
struct FullRecord<const N: usize> {
    epochs: Vec<aidnav_estimation::ForwardEpoch<Const<N>>>,
    states: Vec<NedState>,
}

/// The filter: the entry point of spec 40's GNSS/INS integration.
///
/// Build it from an error model, an initial state, the prior σ of the 21
/// error states and the antenna lever arm (body frame); feed it corrected-
/// or-not IMU increments and GNSS fixes; read the solution:
///
/// ```
/// use aidnav_frames::{Body, Ned, Rotation, Vec3, earth::Geodetic};
/// use aidnav_ins::ned::{NedMechanization, NedState};
/// use aidnav_estimation::AcceptAll;
/// use aidnav_integration::measurements::GnssPosition;
/// use aidnav_integration::ned::{GnssStream, NedFilter};
/// use aidnav_models::ned_ins::{
///     ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, NedErrorModel, POSITION,
///     VELOCITY, Vector21,
/// };
/// use nalgebra::Vector3;
///
/// let start = NedState {
///     position: Geodetic { latitude_rad: 0.52, longitude_rad: 2.0, height_m: 30.0 },
///     velocity: Vec3::<Ned>::zeros(),
///     attitude: Rotation::<Body, Ned>::from_euler_angles(0.0, 0.0, 1.2),
/// };
/// // Prior σ: 1 m, 0.1 m/s, 10 mrad; the instrument states from the model.
/// let model = NedErrorModel::default();
/// let [sg, sa, kg, ka] = model.noise.instrument_sigmas();
/// let mut sigmas = Vector21::zeros();
/// for (block, sigma) in [(POSITION, 1.0), (VELOCITY, 0.1), (ATTITUDE, 0.01)] {
///     sigmas.fixed_rows_mut::<3>(block).fill(sigma);
/// }
/// for (block, sigma) in [(GYRO_BIAS, sg), (ACCEL_BIAS, sa), (GYRO_SCALE, kg), (ACCEL_SCALE, ka)] {
///     sigmas.fixed_rows_mut::<3>(block).copy_from(&sigma);
/// }
/// // Antenna 1 m forward of and 0.5 m above the IMU: a body-frame vector.
/// let lever = Vec3::<Body>::new(1.0, 0.0, -0.5);
/// let mut filter = NedFilter::new(model, start, &sigmas, lever).unwrap();
///
/// // One second at rest (ideal increments), then a fix 0.3 m north of the
/// // true antenna position, σ 0.1 m.
/// let imu = NedMechanization::stationary_increment(&start, 0.01);
/// for _ in 0..100 {
///     filter.propagate(&imu).unwrap();
/// }
/// let (antenna, _) = filter.antenna();
/// let fix = antenna.offset_by(&Vec3::new(0.3, 0.0, 0.0));
/// let measurement = GnssPosition { fix, sigma_ned_m: Vector3::repeat(0.1) };
/// let record = filter
///     .fuse(&measurement, Some(GnssStream::Position), &mut AcceptAll)
///     .unwrap();
/// assert!(record.nis > 0.0);
///
/// // The solution moved most of the way towards the fix.
/// let solution = filter.solution();
/// let moved = start.position.ned_to(&solution.position);
/// assert!(moved.x() > 0.2 && moved.x() < 0.3, "{moved}");
/// let (roll, pitch, yaw) = solution.attitude.euler_angles();
/// assert!(roll.abs() < 0.01 && pitch.abs() < 0.01 && (yaw - 1.2).abs() < 0.01);
/// assert!(solution.velocity.norm() < 0.1);
/// ```
///
/// A NED vector does not go where a body vector is expected:
///
/// ```compile_fail
/// # use aidnav_frames::{Ned, Vec3};
/// # use aidnav_integration::ned::NedFilter;
/// # fn f(model: aidnav_models::ned_ins::NedErrorModel, s: aidnav_ins::ned::NedState,
/// #      p: &aidnav_models::ned_ins::Vector21) {
/// let lever = Vec3::<Ned>::new(1.0, 0.0, -0.5);
/// let _ = NedFilter::new(model, s, p, lever); // expected `Vec3<Body>`
/// # }
/// ```
#[derive(Debug, Clone)]
pub struct NedFilter<const N: usize = STATES> {
    model: NedErrorModel,
    ins: NedMechanization,
    kf: FixedKalmanFilter<N>,
    instruments: InstrumentEstimate,
    lever_arm: Vec3<Body>,
    /// Body → vehicle frame of the vehicle constraints, and the roll it is
    /// built with (a vehicle misalignment block estimates pitch and yaw).
    vehicle_from_body: Matrix3<f64>,
    vehicle_roll_rad: f64,
    rate: Vec3<Body>,
    pending_force: Vec3<Body>,
    pending_angle: Vec3<Body>,
    pending_dt: f64,
    covariance_interval_s: f64,
    record: Option<ForwardRecord<N>>,
    #[cfg(test)]
    full_record: Option<FullRecord<N>>,
    open_loop: bool,
    monitor: Option<ConvergenceMonitor>,
    fed_back: SVector<f64, N>,
    adaptive: Option<InnovationFeedbackNoise<Const<N>, U3>>,
    recovery: Option<Box<Recovery<N>>>,
    /// Φ and Q of the last covariance flush: buffers the model writes into.
    phi: SMatrix<f64, N, N>,
    q: SMatrix<f64, N, N>,
    /// The base model's Φ and Q when the layout adds states (the model
    /// writes 21 × 21; None for the base layout, whose Φ and Q it writes
    /// directly).
    base_transition: Option<Box<(Matrix21, Matrix21)>>,
    /// Where the added states sit, and their dynamics.
    layout: StateLayout,
    /// Nominal values of the added states (the base entries stay 0).
    parameters: SVector<f64, N>,
    /// The navigation-frame acceleration, low-passed over
    /// [`ACCELERATION_SMOOTHING_S`] (kept only when a measurement needs it:
    /// a GNSS latency state).
    acceleration: Option<Vec3<Ned>>,
}

/// `R_z(yaw) R_y(pitch) R_x(roll)`: body → vehicle.
fn vehicle_rotation(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw).into_inner()
}

/// Time constant of the acceleration a latency-compensated GNSS velocity
/// is predicted with \[s\]: long against vibration, short against a
/// vehicle's manoeuvres.
pub const ACCELERATION_SMOOTHING_S: f64 = 0.2;

/// The reset recovery of the GNSS updates: when a run of refused (rejected
/// or limited) fixes agree with each other, the filter stops believing
/// itself and resets the measured states to the latest fix.
///
/// The agreement is the engine's ([`aidnav_estimation::recovery`]): two
/// refused fixes agree when the change the filter predicts for the antenna
/// between them (its own mechanization, so a moving vehicle is handled)
/// matches the change of the fixes, within a χ² bound on the covariance of
/// that difference. `run_length` agreeing fixes in a run make a reset.
/// The reset (as PX4 EKF2's `resetHorizontalPositionTo` and ArduPilot
/// EKF3's `ResetPosition`, which reset after a timeout): the position
/// (velocity) error states take the whole innovation of the fix, so the
/// solution passes through it; their rows and columns of P are zeroed (no
/// correlation with any other state, nor with each other) and their block
/// set to `(1 + margin) R`. P stays symmetric and positive semi-definite:
/// it is block diagonal with a principal block of the old P and a positive
/// definite block.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecoveryConfig {
    /// The agreement test: run length (≥ 2) and χ² probability (in (0, 1)).
    pub agreement: AgreementConfig,
    /// Margin of the reset covariance: a reset block is `(1 + margin) R`
    /// (≥ 0).
    pub margin: f64,
}

impl Default for RecoveryConfig {
    /// A run of 21 refused fixes that agree at χ² probability 0.999, reset
    /// to `2 R`: at 1–10 Hz a genuine jump of the fixes (a new reference,
    /// a corrected multipath bias) is followed within 2–20 s, while a run
    /// of 21 outliers agreeing by chance is below 1e-50 at that
    /// probability; a margin of 1 doubles the variance the fix claims, so
    /// the filter takes the next fixes without trusting the reset one
    /// alone.
    fn default() -> Self {
        Self {
            agreement: AgreementConfig {
                run_length: 21,
                probability: 0.999,
            },
            margin: 1.0,
        }
    }
}

impl RecoveryConfig {
    /// Every parameter in its range: a run of 2 to 100 000 fixes, a
    /// probability in [1e-9, 1 − 1e-12], a margin in [0, 1e6]; the error
    /// names the configuration key (`recovery_fixes`,
    /// `recovery_probability`, `recovery_margin`).
    pub fn validate(&self) -> Result<(), EstimationError> {
        let out_of_range = |parameter, value: String, allowed: &str| {
            Err(EstimationError::OutOfRange {
                parameter,
                value,
                allowed: allowed.into(),
            })
        };
        let a = &self.agreement;
        if !(2..=100_000).contains(&a.run_length) {
            return out_of_range(
                "recovery_fixes",
                a.run_length.to_string(),
                "2 ≤ recovery_fixes ≤ 100000",
            );
        }
        if !(1e-9..=1.0 - 1e-12).contains(&a.probability) {
            return out_of_range(
                "recovery_probability",
                a.probability.to_string(),
                "1e-9 ≤ recovery_probability ≤ 1 − 1e-12",
            );
        }
        if !(0.0..=1e6).contains(&self.margin) {
            return out_of_range(
                "recovery_margin",
                self.margin.to_string(),
                "0 ≤ recovery_margin ≤ 1e6",
            );
        }
        Ok(())
    }
}

/// One detector per GNSS stream.
#[derive(Debug, Clone)]
struct Recovery<const N: usize> {
    config: RecoveryConfig,
    position: AgreementDetector<Const<N>, U3>,
    velocity: AgreementDetector<Const<N>, U3>,
}

impl<const N: usize> Recovery<N> {
    /// Every detector sees another update (gain K, matrix H), but `except`.
    fn updated<M: nalgebra::Dim>(
        &mut self,
        gain: &nalgebra::OMatrix<f64, Const<N>, M>,
        h: &nalgebra::OMatrix<f64, M, Const<N>>,
        except: Option<GnssStream>,
    ) where
        nalgebra::DefaultAllocator:
            aidnav_estimation::FilterAllocator<Const<N>, M> + nalgebra::allocator::Allocator<M, U3>,
    {
        if except != Some(GnssStream::Position) {
            self.position.updated(gain, h);
        }
        if except != Some(GnssStream::Velocity) {
            self.velocity.updated(gain, h);
        }
    }

    fn detector(&mut self, stream: GnssStream) -> &mut AgreementDetector<Const<N>, U3> {
        match stream {
            GnssStream::Position => &mut self.position,
            GnssStream::Velocity => &mut self.velocity,
        }
    }
}

/// A GNSS measurement stream of the filter: the recovery keeps one
/// agreement detector per stream, and the adaptive process noise acts on
/// the position stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GnssStream {
    /// The antenna position.
    Position,
    /// The antenna velocity.
    Velocity,
}

impl GnssStream {
    /// The other stream.
    fn other(self) -> Self {
        match self {
            GnssStream::Position => GnssStream::Velocity,
            GnssStream::Velocity => GnssStream::Position,
        }
    }

    /// First index of the error states it measures.
    fn block(self) -> usize {
        match self {
            GnssStream::Position => POSITION,
            GnssStream::Velocity => VELOCITY,
        }
    }
}

/// Spec 10's Cramér–Rao convergence measure on the instrument states:
/// the Fisher information without process noise, propagated and updated
/// alongside the filter, and the prior variances that make the 12
/// instrument states (four units) comparable.
#[derive(Debug, Clone)]
struct ConvergenceMonitor {
    fisher: FisherInformation<Const<STATES>>,
    prior: Vector21,
    before: f64,
}

/// The navigation solution of an INS state: itself in closed loop, the INS
/// corrected by the estimate x in open loop.
fn solution_of<const N: usize>(ins: &NedState, open_loop: bool, x: &SVector<f64, N>) -> NedState {
    if !open_loop {
        return *ins;
    }
    corrected(ins, x)
}

/// The antenna position and NED velocity of a solution, lever arm `l`
/// (body) and body rate ω: `r ⊕ C l`, `v + C (ω × l)`.
pub(crate) fn antenna_of_solution(
    s: &NedState,
    lever_arm: Vec3<Body>,
    rate: Vec3<Body>,
) -> (Geodetic, Vec3<Ned>) {
    let c = s.attitude.matrix();
    let arm = c * lever_arm;
    (
        s.position.offset_by(&arm),
        s.velocity + c * rate.cross(&lever_arm),
    )
}

/// A read-only view of a NED filter, whatever its layout: what the loop's
/// observers and the solution rows read.
pub trait FilterView {
    /// The INS's own navigation state (uncorrected in open loop).
    fn state(&self) -> &NedState;
    /// The navigation solution (the INS, corrected by the estimate in open
    /// loop).
    fn solution(&self) -> NedState;
    /// The instrument corrections.
    fn instruments(&self) -> &InstrumentEstimate;
    /// The antenna position and NED velocity implied by the solution.
    fn antenna(&self) -> (Geodetic, Vec3<Ned>);
    /// Covariance of the antenna position error (NED) \[m²\].
    fn antenna_position_covariance(&self) -> Matrix3<f64>;
    /// σ of the base 21 error states.
    fn base_sigmas(&self) -> Vector21;
    /// Sum of the base 21 error estimates fed back so far.
    fn base_fed_back(&self) -> Vector21;
    /// A copy of the INS that coasts on raw increments from here on (no
    /// instrument corrections, no updates, the covariance frozen): the
    /// free INS of an outage score.
    fn free_inertial(&self) -> FreeInertial;
}

/// The first 21 entries of a vector of a layout's states.
fn base_of<const N: usize>(v: &SVector<f64, N>) -> Vector21 {
    Vector21::from_fn(|i, _| v[i])
}

impl<const N: usize> FilterView for NedFilter<N> {
    fn state(&self) -> &NedState {
        self.ins.state()
    }

    fn solution(&self) -> NedState {
        NedFilter::solution(self)
    }

    fn instruments(&self) -> &InstrumentEstimate {
        &self.instruments
    }

    fn antenna(&self) -> (Geodetic, Vec3<Ned>) {
        NedFilter::antenna(self)
    }

    fn antenna_position_covariance(&self) -> Matrix3<f64> {
        NedFilter::antenna_position_covariance(self)
    }

    fn base_sigmas(&self) -> Vector21 {
        base_of(&self.sigmas())
    }

    fn base_fed_back(&self) -> Vector21 {
        base_of(&self.fed_back)
    }

    fn free_inertial(&self) -> FreeInertial {
        let p = self.kf.covariance();
        FreeInertial {
            ins: self.ins,
            instruments: self.instruments,
            lever_arm: self.lever_arm,
            rate: self.rate,
            open_loop: self.open_loop,
            x: base_of(self.kf.state()),
            p: Matrix21::from_fn(|i, j| p[(i, j)]),
            fed_back: base_of(&self.fed_back),
        }
    }
}

/// A free INS: a filter's INS, instruments and covariance as they were,
/// mechanized from raw increments ([`FilterView::free_inertial`]).
#[derive(Debug, Clone)]
pub struct FreeInertial {
    ins: NedMechanization,
    instruments: InstrumentEstimate,
    lever_arm: Vec3<Body>,
    rate: Vec3<Body>,
    open_loop: bool,
    x: Vector21,
    p: Matrix21,
    fed_back: Vector21,
}

impl FreeInertial {
    /// Mechanize one raw increment without the instrument corrections and
    /// without touching the covariance.
    pub fn coast_uncorrected(&mut self, raw: &ImuIncrement) {
        if raw.dt_s > 0.0 {
            self.ins.update(raw);
        }
    }
}

impl FilterView for FreeInertial {
    fn state(&self) -> &NedState {
        self.ins.state()
    }

    fn solution(&self) -> NedState {
        solution_of(self.ins.state(), self.open_loop, &self.x)
    }

    fn instruments(&self) -> &InstrumentEstimate {
        &self.instruments
    }

    fn antenna(&self) -> (Geodetic, Vec3<Ned>) {
        antenna_of_solution(&self.solution(), self.lever_arm, self.rate)
    }

    fn antenna_position_covariance(&self) -> Matrix3<f64> {
        let c = self.solution().attitude.matrix();
        antenna_covariance((c * self.lever_arm).as_raw(), &self.p)
    }

    fn base_sigmas(&self) -> Vector21 {
        self.p.diagonal().map(f64::sqrt)
    }

    fn base_fed_back(&self) -> Vector21 {
        self.fed_back
    }

    fn free_inertial(&self) -> FreeInertial {
        self.clone()
    }
}

/// `m` as a matrix of another const shape with the same number of rows and
/// columns (None when they differ): how the generic update hands a
/// three-component measurement to the GNSS streams' three-typed detectors.
fn reshape<const R1: usize, const C1: usize, const R2: usize, const C2: usize>(
    m: &SMatrix<f64, R1, C1>,
) -> Option<SMatrix<f64, R2, C2>> {
    (R1 == R2 && C1 == C2).then(|| SMatrix::from_column_slice(m.as_slice()))
}

/// A smoothed navigation state and the covariance of its antenna position
/// error (NED, m²).
pub type SmoothedAntenna = (NedState, Matrix3<f64>);

impl<const N: usize> NedFilter<N> {
    /// Start at `state` with the prior σ of every error state and the
    /// antenna lever arm (body frame, from the IMU to the antenna), on the
    /// base 21 states (an error unless `N` is 21: see
    /// [`with_layout`](Self::with_layout)).
    pub fn new(
        model: NedErrorModel,
        state: NedState,
        prior_sigmas: &SVector<f64, N>,
        lever_arm: Vec3<Body>,
    ) -> Result<Self, EstimationError> {
        Self::with_layout(model, state, prior_sigmas, lever_arm, StateLayout::base())
    }

    /// [`new`](Self::new) on a layout with added states: `N` must be the
    /// layout's length; `prior_sigmas` holds every state's prior σ (the
    /// added blocks' too: [`BlockDynamics::prior_sigma`](crate::state::BlockDynamics)
    /// is where a caller usually takes them from).
    pub fn with_layout(
        model: NedErrorModel,
        state: NedState,
        prior_sigmas: &SVector<f64, N>,
        lever_arm: Vec3<Body>,
        layout: StateLayout,
    ) -> Result<Self, EstimationError> {
        if layout.len() != N || layout.blocks().iter().any(|b| !b.dynamics.is_valid()) {
            return Err(EstimationError::DimensionMismatch {
                step: Step::Initialise,
                matrix: ErrorMatrix::P,
                rows: N,
                cols: N,
                expected_rows: layout.len(),
                expected_cols: layout.len(),
            });
        }
        let p0 = SMatrix::<f64, N, N>::from_diagonal(&prior_sigmas.map(|s| s * s));
        Ok(Self {
            model,
            ins: NedMechanization::new(state),
            kf: FixedKalmanFilter::new(SVector::zeros(), p0)?,
            instruments: InstrumentEstimate::default(),
            lever_arm,
            vehicle_from_body: Matrix3::identity(),
            vehicle_roll_rad: 0.0,
            rate: Vec3::zeros(),
            pending_force: Vec3::zeros(),
            pending_angle: Vec3::zeros(),
            pending_dt: 0.0,
            covariance_interval_s: 0.05,
            record: None,
            #[cfg(test)]
            full_record: None,
            open_loop: false,
            monitor: None,
            fed_back: SVector::zeros(),
            adaptive: None,
            recovery: None,
            phi: SMatrix::zeros(),
            q: SMatrix::zeros(),
            base_transition: (N != STATES)
                .then(|| Box::new((Matrix21::zeros(), Matrix21::zeros()))),
            acceleration: layout
                .offset(crate::state::Augmented::GnssLatency)
                .map(|_| Vec3::zeros()),
            parameters: Self::initial_parameters(&layout, lever_arm),
            layout,
        })
    }

    /// The added states' nominal values at the start: 0, but the lever
    /// arm's block, which holds the whole lever arm (the filter's
    /// `lever_arm` follows it at every feedback).
    fn initial_parameters(layout: &StateLayout, lever_arm: Vec3<Body>) -> SVector<f64, N> {
        let mut parameters = SVector::<f64, N>::zeros();
        if let Some(o) = layout.offset(crate::state::Augmented::LeverArm) {
            parameters
                .fixed_rows_mut::<3>(o)
                .copy_from(&lever_arm.raw());
        }
        parameters
    }

    /// The vehicle frame of the vehicle constraints (non-holonomic,
    /// wheel speed) against the body frame, as roll, pitch, yaw \[rad\]
    /// (`v_vehicle = R_z(yaw) R_y(pitch) R_x(roll) v_body`); the start of
    /// the estimate when the layout has a
    /// [`VehicleMisalignment`](crate::state::Augmented::VehicleMisalignment)
    /// block (which estimates pitch and yaw; the roll stays).
    pub fn set_vehicle_misalignment(&mut self, [roll, pitch, yaw]: [f64; 3]) {
        self.vehicle_roll_rad = roll;
        self.vehicle_from_body = vehicle_rotation(roll, pitch, yaw);
        if let Some(o) = self
            .layout
            .offset(crate::state::Augmented::VehicleMisalignment)
        {
            self.parameters[o] = pitch;
            self.parameters[o + 1] = yaw;
        }
    }

    /// The body → vehicle rotation of the vehicle constraints.
    pub fn vehicle_from_body(&self) -> &Matrix3<f64> {
        &self.vehicle_from_body
    }

    /// Where the added states sit.
    pub fn layout(&self) -> &StateLayout {
        &self.layout
    }

    /// Nominal values of the added states, by state index (the base
    /// entries are 0): the value an added block's estimate has been fed
    /// back into (e.g. the odometer's scale-factor error).
    pub fn parameters(&self) -> &SVector<f64, N> {
        &self.parameters
    }

    /// Every added state's estimate with its σ (see
    /// [`StateLayout::estimates`]).
    pub fn added_state_estimates(&self) -> Vec<crate::state::AddedStateEstimate> {
        let x = if self.open_loop {
            *self.kf.state()
        } else {
            SVector::zeros()
        };
        self.layout.estimates(&self.parameters, &x, &self.sigmas())
    }

    /// What a measurement model sees of the filter.
    pub fn nominal(&self) -> Nominal<'_, N> {
        Nominal {
            state: self.ins.state(),
            body_rate: self.rate,
            acceleration: self.acceleration.unwrap_or_else(Vec3::zeros),
            antenna_lever_arm: self.lever_arm,
            vehicle_from_body: self.vehicle_from_body,
            instruments: &self.instruments,
            parameters: &self.parameters,
            layout: &self.layout,
        }
    }

    /// Turn on the reset recovery of the GNSS updates (see
    /// [`RecoveryConfig`]); None turns it off. An invalid configuration
    /// ([`RecoveryConfig::validate`]) is an error and leaves it off.
    pub fn set_recovery(&mut self, config: Option<RecoveryConfig>) -> Result<(), EstimationError> {
        self.recovery = None;
        let Some(config) = config else {
            return Ok(());
        };
        config.validate()?;
        let (Some(position), Some(velocity)) = (
            AgreementDetector::new(config.agreement),
            AgreementDetector::new(config.agreement),
        ) else {
            // Not reached after `validate`; the detector's own check kept.
            return Err(EstimationError::OutOfRange {
                parameter: "recovery_fixes",
                value: config.agreement.run_length.to_string(),
                allowed: "a run of at least 2 fixes at a probability in (0, 1)".into(),
            });
        };
        self.recovery = Some(Box::new(Recovery {
            config,
            position,
            velocity,
        }));
        Ok(())
    }

    /// The recovery's configuration (None: off).
    pub fn recovery(&self) -> Option<RecoveryConfig> {
        self.recovery.as_ref().map(|r| r.config)
    }

    /// The INS's own navigation state (uncorrected in open loop).
    pub fn state(&self) -> &NedState {
        self.ins.state()
    }

    /// Open loop (seed 004's output-correction scheme): the estimates are
    /// never fed back; the INS runs on its raw (initially corrected)
    /// instruments and the output is the INS corrected by the estimate.
    /// Smoothing is not available in open loop.
    pub fn set_open_loop(&mut self, open: bool) {
        self.open_loop = open;
        if open {
            self.record = None;
        }
    }

    /// The navigation solution: the INS, corrected by the error estimate in
    /// open loop.
    pub fn solution(&self) -> NedState {
        solution_of(self.ins.state(), self.open_loop, self.kf.state())
    }

    /// The instrument corrections.
    pub fn instruments(&self) -> &InstrumentEstimate {
        &self.instruments
    }

    /// Start the gyro-bias correction at a value (e.g. measured at rest).
    pub fn set_gyro_bias(&mut self, bias: Vector3<f64>) {
        self.instruments.gyro_bias = bias;
    }

    /// Tell the filter that its start position came from an antenna fix
    /// through the nominal lever arm (`r = r_fix − C l̂`): the position
    /// error then holds the lever arm's, `δr = n + C δl`, and with a
    /// lever-arm state the prior becomes `T P Tᵀ` with `T = I + [C in
    /// (position, lever arm)]`. Without it, a fix would read the lever
    /// arm's error as position error the prior rules out, and the lever
    /// arm's estimate would stay at its start. No-op without a lever-arm
    /// state.
    pub fn start_position_is_from_antenna_fix(&mut self) -> Result<(), EstimationError> {
        let Some(o) = self.layout.offset(crate::state::Augmented::LeverArm) else {
            return Ok(());
        };
        let mut t = SMatrix::<f64, N, N>::identity();
        t.fixed_view_mut::<3, 3>(POSITION, o)
            .copy_from(self.ins.state().attitude.matrix().as_raw());
        let p = t * self.kf.covariance() * t.transpose();
        self.kf.set_covariance((p + p.transpose()) * 0.5)
    }

    /// σ of every error state (as of the last covariance propagation).
    pub fn sigmas(&self) -> SVector<f64, N> {
        self.kf.covariance().diagonal().map(f64::sqrt)
    }

    /// Covariance of the antenna position error (NED, m²) as of the last
    /// covariance propagation: `H P Hᵀ` with the position measurement's
    /// `H = [I, 0, [(C l)×], 0 …]` — the IMU position block plus the
    /// attitude error seen through the lever arm `C l`, and their
    /// cross-covariance (symmetrised).
    pub fn antenna_position_covariance(&self) -> Matrix3<f64> {
        let c = self.solution().attitude.matrix();
        antenna_covariance_on(
            &self.layout,
            c.as_raw(),
            self.lever_arm.as_raw(),
            self.kf.covariance(),
        )
    }

    /// The antenna position and NED velocity implied by the INS.
    pub fn antenna(&self) -> (Geodetic, Vec3<Ned>) {
        antenna_of_solution(&self.solution(), self.lever_arm, self.rate)
    }

    /// Mechanize one raw increment and propagate the covariance.
    pub fn propagate(&mut self, raw: &ImuIncrement) -> Result<(), EstimationError> {
        let imu = self.instruments.correct(raw);
        if imu.dt_s.is_nan() || imu.dt_s <= 0.0 {
            return Ok(());
        }
        self.ins.update(&imu);
        self.rate = imu.delta_angle / imu.dt_s;
        if let Some(a) = self.acceleration.as_mut() {
            let s = self.ins.state();
            let now = s.attitude.matrix() * (imu.delta_velocity / imu.dt_s)
                + aidnav_ins::ned::gravity_ned(&s.position);
            let k = (imu.dt_s / ACCELERATION_SMOOTHING_S).min(1.0);
            *a += (now - *a) * k;
        }
        // The covariance follows at a lower rate, with F built once per
        // interval from the mean body specific force and rate (the error
        // dynamics change slowly against 100 Hz).
        self.pending_force += imu.delta_velocity;
        self.pending_angle += imu.delta_angle;
        self.pending_dt += imu.dt_s;
        if self.pending_dt >= self.covariance_interval_s {
            self.flush_covariance()?;
        }
        Ok(())
    }

    /// Propagate the covariance over the accumulated interval before an
    /// update, and hand the recording the prediction's P⁻ before the update
    /// changes P (it is not copied aside at every prediction).
    fn flush_covariance_for_update(&mut self) -> Result<(), EstimationError> {
        self.flush_covariance()?;
        self.hand_over_predicted_covariance();
        Ok(())
    }

    /// The recording's open prediction, if any, gets its P⁻: P as the last
    /// covariance propagation left it (every change of P since would have
    /// come through [`flush_covariance_for_update`](Self::flush_covariance_for_update)).
    fn hand_over_predicted_covariance(&mut self) {
        if let Some(r) = self.record.as_mut() {
            r.rts.predicted_covariance(self.kf.covariance());
        }
    }

    /// Propagate the covariance over the accumulated interval.
    fn flush_covariance(&mut self) -> Result<(), EstimationError> {
        if self.pending_dt <= 0.0 {
            return Ok(());
        }
        let dt = self.pending_dt;
        let s = self.ins.state();
        let c = s.attitude.matrix();
        let rates = [
            (self.pending_force / dt).raw(),
            (self.pending_angle / dt).raw(),
            earth_rate_ned(s.position.latitude_rad).raw(),
            transport_rate_ned(&s.position, &s.velocity).raw(),
        ];
        let rates = [&rates[0], &rates[1], &rates[2], &rates[3]];
        // On the base layout straight into the filter's own buffers (no
        // 21 × 21 copies on the way: the downcast is to the type `N = 21`
        // already is); with added states the model's 21 × 21 go into the
        // top left, each added state its own step (Φ stays diagonal from
        // the gyro bias on, the structure the prediction is told).
        let base = (&mut self.phi as &mut dyn Any)
            .downcast_mut::<Matrix21>()
            .zip((&mut self.q as &mut dyn Any).downcast_mut::<Matrix21>());
        if let Some((phi, q)) = base {
            let latitude = s.position.latitude_rad;
            self.model
                .transition_into(c.as_raw(), rates, latitude, dt, (phi, q));
        } else if let Some(b) = self.base_transition.as_deref_mut() {
            let (phi21, q21) = (&mut b.0, &mut b.1);
            let latitude = s.position.latitude_rad;
            self.model
                .transition_into(c.as_raw(), rates, latitude, dt, (phi21, q21));
            self.phi
                .fixed_view_mut::<STATES, STATES>(0, 0)
                .copy_from(phi21);
            self.q.fixed_view_mut::<STATES, STATES>(0, 0).copy_from(q21);
            for block in self.layout.blocks() {
                let (phi, q) = block.dynamics.discrete(dt);
                for i in block.offset..block.offset + block.kind.states() {
                    self.phi[(i, i)] = phi;
                    self.q[(i, i)] = q;
                }
            }
        }
        let (phi, q) = (&self.phi, &self.q);
        self.pending_force = Vec3::zeros();
        self.pending_angle = Vec3::zeros();
        self.pending_dt = 0.0;
        self.kf
            .predict_structured(phi, q, NedErrorModel::TRANSITION)?;
        if let Some(m) = self.monitor.as_mut()
            && let Some(phi) = (phi as &dyn Any).downcast_ref::<Matrix21>()
        {
            m.fisher.propagate(phi)?;
        }
        if let Some(r) = self.recovery.as_mut() {
            r.position.propagate(phi, dt);
            r.velocity.propagate(phi, dt);
        }
        if let Some(r) = self.record.as_mut() {
            r.rts.predict(phi, &SVector::zeros(), self.kf.covariance());
            r.open_state = *self.ins.state();
        }
        #[cfg(test)]
        if let Some(r) = self.full_record.as_mut() {
            let p = *self.kf.covariance();
            r.epochs.push(aidnav_estimation::ForwardEpoch {
                phi: *phi,
                x_predicted: SVector::zeros(),
                p_predicted: p,
                x_filtered: SVector::zeros(),
                p_filtered: p,
            });
            r.states.push(*self.ins.state());
        }
        Ok(())
    }

    /// Keep what the smoother needs of the forward pass, from the current
    /// state on, for at most `max_epochs` smoothed epochs (those marked by
    /// [`mark_for_smoothing`](Self::mark_for_smoothing); a run that marks
    /// more cannot be smoothed). Memory: [`BYTES_PER_SMOOTHED_EPOCH`] per
    /// marked epoch, nothing per covariance epoch.
    pub fn start_recording(&mut self, max_epochs: usize) {
        let p = *self.kf.covariance();
        self.record = Some(ForwardRecord {
            rts: crate::recording::Recording::new(&SVector::zeros(), &p, max_epochs.max(1)),
            open_state: *self.ins.state(),
            states: Vec::new(),
        });
        #[cfg(test)]
        {
            self.full_record = Some(FullRecord {
                epochs: vec![aidnav_estimation::ForwardEpoch {
                    phi: SMatrix::identity(),
                    x_predicted: SVector::zeros(),
                    p_predicted: p,
                    x_filtered: SVector::zeros(),
                    p_filtered: p,
                }],
                states: vec![*self.ins.state()],
            });
        }
    }

    /// Ask for the smoothed state of the current covariance epoch (the last
    /// propagated one, with every update made in it, also later ones);
    /// returns its index in [`smoothed_states`](Self::smoothed_states)
    /// (the same index when asked again in the same epoch). None when not
    /// recording or past the recording's limit.
    pub fn mark_for_smoothing(&mut self) -> Option<usize> {
        self.hand_over_predicted_covariance();
        let r = self.record.as_mut()?;
        let new = r.rts.open_mark().is_none();
        let mark = r.rts.mark()?;
        if new {
            r.states.push(r.open_state);
        }
        Some(mark)
    }

    /// The Rauch–Tung–Striebel smoothed navigation state (IMU position,
    /// velocity, attitude) of every epoch marked by
    /// [`mark_for_smoothing`](Self::mark_for_smoothing), in marking order;
    /// None when not recording or when more epochs were marked than the
    /// recording's limit.
    pub fn smoothed_states(&self) -> Result<Option<Vec<NedState>>, EstimationError> {
        Ok(self
            .smoothed_states_with_covariance()?
            .map(|v| v.into_iter().map(|(s, _)| s).collect()))
    }

    /// Wait until the smoother's worker thread has recorded the whole
    /// forward pass so far (nothing to wait for without a recording or
    /// when it is recorded inline). Optional: the backward pass waits
    /// for it too; called before other threads start work (the outputs'
    /// writers), the worker finishes on a core of its own.
    pub fn catch_up_recording(&self) {
        if let Some(r) = self.record.as_ref() {
            r.rts.catch_up(self.kf.covariance());
        }
    }

    /// [`smoothed_states`](Self::smoothed_states), each with the smoothed
    /// covariance of its antenna position error (NED, m²; `H P Hᵀ` as in
    /// [`antenna_position_covariance`](Self::antenna_position_covariance),
    /// at the smoothed attitude).
    pub fn smoothed_states_with_covariance(
        &self,
    ) -> Result<Option<Vec<SmoothedAntenna>>, EstimationError> {
        let Some(r) = self.record.as_ref().filter(|r| !r.rts.overflowed()) else {
            return Ok(None);
        };
        let mut out = r.states.clone();
        let mut covariances = vec![Matrix3::zeros(); out.len()];
        r.rts.smooth_with(self.kf.covariance(), |mark, x, p| {
            let state = corrected(&out[mark], x);
            let c = state.attitude.matrix();
            covariances[mark] =
                antenna_covariance_on(&self.layout, c.as_raw(), self.lever_arm.as_raw(), p);
            out[mark] = state;
            Ok(())
        })?;
        Ok(Some(out.into_iter().zip(covariances).collect()))
    }

    /// Antenna position of an IMU state under this filter's lever arm.
    pub fn antenna_of(&self, state: &NedState) -> Geodetic {
        state.position.offset_by(&(state.attitude * self.lever_arm))
    }

    /// Start the Cramér–Rao convergence monitor of the instrument states
    /// (spec 10's δ(n), see [`instrument_convergence`](Self::instrument_convergence)),
    /// on the base 21 states (an error with added states).
    pub fn start_convergence_monitor(&mut self) -> Result<(), EstimationError> {
        let Some(&p) = (self.kf.covariance() as &dyn Any).downcast_ref::<Matrix21>() else {
            return Err(EstimationError::DimensionMismatch {
                step: Step::Initialise,
                matrix: ErrorMatrix::Information,
                rows: N,
                cols: N,
                expected_rows: STATES,
                expected_cols: STATES,
            });
        };
        self.monitor = Some(ConvergenceMonitor {
            fisher: FisherInformation::from_prior_covariance(&p)?,
            prior: p.diagonal(),
            before: 0.0,
        });
        Ok(())
    }

    /// Normalised trace of the instrument block of P.
    fn instrument_trace(&self, p: &SMatrix<f64, N, N>) -> f64 {
        self.monitor.as_ref().map_or(0.0, |m| {
            (GYRO_BIAS..STATES).map(|i| p[(i, i)] / m.prior[i]).sum()
        })
    }

    /// Mark the start of an epoch's updates (the δ numerator is the drop of
    /// the instrument trace from here to [`instrument_convergence`](Self::instrument_convergence)).
    pub fn begin_epoch(&mut self) -> Result<(), EstimationError> {
        self.flush_covariance()?;
        let before = self.instrument_trace(self.kf.covariance());
        if let Some(m) = self.monitor.as_mut() {
            m.before = before;
        }
        Ok(())
    }

    /// δ(n) of spec 10 for the instrument states since [`begin_epoch`](Self::begin_epoch):
    /// the reduction of tr P_M by this epoch's updates over tr P_Γ,M, each
    /// instrument state in units of its prior variance (the 12 states have
    /// four units). None without a monitor or while the Fisher information
    /// is still singular.
    pub fn instrument_convergence(&self) -> Option<f64> {
        let m = self.monitor.as_ref()?;
        let bound = m.fisher.cramer_rao_bound().ok()?;
        let after = self.instrument_trace(self.kf.covariance());
        let bound_trace: f64 = (GYRO_BIAS..STATES)
            .map(|i| bound[(i, i)] / m.prior[i])
            .sum();
        Some((m.before - after) / bound_trace)
    }

    fn add_information<const M: usize>(
        &mut self,
        h: &SMatrix<f64, M, N>,
        r: &SMatrix<f64, M, M>,
        outcome: Outcome,
    ) -> Result<(), EstimationError> {
        if let Some(m) = self.monitor.as_mut()
            && !matches!(outcome, Outcome::Rejected | Outcome::Reset)
            && let Some(h) = (h as &dyn Any).downcast_ref::<SMatrix<f64, M, STATES>>()
        {
            m.fisher.add_measurement(h, r)?;
        }
        Ok(())
    }

    /// Spec 20 eq. 3's adaptive process noise on the GNSS position updates:
    /// before each, `K_{k−1} ν_k ν_kᵀ K_{k−1}ᵀ` (previous position gain, this
    /// innovation) is added to P on top of the model's Q — the mean over the
    /// last `window` normal epochs when `average` (Mohamed–Schwarz), else
    /// the single term (eq. 3's hard feedback). When the eq. 5 detector
    /// (`gamma`) finds ν anomalous, the mean term of the last `window`
    /// normal epochs is added instead (eq. 9's guard). (The paper's term
    /// *replaces* Q; on this 21-state filter that made the recorded drive
    /// fail with a non-positive-definite S — a rank-3 term per fix cannot
    /// keep 21 states' covariance positive — so it is added here.)
    pub fn set_adaptive_noise(&mut self, gamma: Option<f64>, window: usize, average: bool) {
        self.adaptive = InnovationFeedbackNoise::new(
            SMatrix::zeros(),
            gamma.map(|gamma| AnomalyDetector { gamma }),
            window.max(1),
        )
        .map(|noise| noise.averaged(average));
    }

    /// A GNSS epoch without a position fix (an outage): for the adaptive
    /// noise the epoch's gain is zero, so the first fix after an outage
    /// feeds nothing back; the recovery's runs end (a run is consecutive).
    pub fn position_fix_missing(&mut self) -> Result<(), EstimationError> {
        // The smoother marks this epoch next: its state must be the INS's
        // at the fix's time, not at the last covariance step up to
        // `covariance_interval_s` before it (at 12 m/s, 0.6 m).
        if self.record.is_some() {
            self.flush_covariance_for_update()?;
        }
        if let Some(a) = self.adaptive.as_mut() {
            a.record_gain(&SMatrix::zeros());
        }
        // A gap ends every run of refused fixes: a run is consecutive.
        if let Some(r) = self.recovery.as_mut() {
            r.position.clear();
            r.velocity.clear();
        }
        Ok(())
    }

    /// Sum of every error estimate fed back so far (closed loop): its
    /// position and velocity parts are the corrections the INS has needed,
    /// whose history the outage predictors extrapolate.
    pub fn fed_back(&self) -> &SVector<f64, N> {
        &self.fed_back
    }

    /// Interval of the covariance propagation \[s\] (default 0.05; 0: every sample).
    pub fn set_covariance_interval(&mut self, seconds: f64) {
        self.covariance_interval_s = seconds.max(0.0);
    }

    /// The one measurement update, for every measurement model alike: the
    /// covariance propagated to now, the model linearised at the nominal
    /// state ([`nominal`](Self::nominal)), the update under `policy`, the
    /// recovery (see [`RecoveryConfig`]: a GNSS stream's detector takes its
    /// stream's refused fixes and may reset the stream; every detector sees
    /// every other update), the Fisher information of the convergence
    /// monitor, and the feedback. The adaptive process noise
    /// ([`set_adaptive_noise`](Self::set_adaptive_noise)) acts before and
    /// after the GNSS position updates. Returns the update's record
    /// (innovation, S, gain, NIS, outcome).
    ///
    /// ```
    /// # use aidnav_frames::{Ned, Rotation, Vec3, earth::Geodetic};
    /// # use aidnav_ins::ned::{NedMechanization, NedState};
    /// use aidnav_estimation::AcceptAll;
    /// use aidnav_integration::measurements::ZeroVelocity;
    /// use aidnav_integration::ned::NedFilter;
    /// use aidnav_models::ned_ins::{NedErrorModel, Vector21};
    /// # let start = NedState {
    /// #     position: Geodetic { latitude_rad: 0.5, longitude_rad: 0.2, height_m: 10.0 },
    /// #     velocity: Vec3::<Ned>::zeros(),
    /// #     attitude: Rotation::from_euler_angles(0.0, 0.0, 0.3),
    /// # };
    /// let mut f = NedFilter::new(NedErrorModel::default(), start, &Vector21::repeat(0.1), Vec3::zeros())
    ///     .unwrap();
    /// let rec = f.fuse(&ZeroVelocity { sigma_mps: 0.01 }, None, &mut AcceptAll).unwrap();
    /// assert_eq!(rec.nis, 0.0); // at rest the INS already says 0
    /// assert!(f.sigmas()[3] < 0.011);
    /// ```
    pub fn fuse<const M: usize, Meas, P>(
        &mut self,
        measurement: &Meas,
        stream: Option<GnssStream>,
        policy: &mut P,
    ) -> Result<UpdateRecord<Const<N>, Const<M>>, EstimationError>
    where
        Meas: Measurement<M, N> + ?Sized,
        P: MeasurementPolicy<Const<M>> + ?Sized,
    {
        self.flush_covariance_for_update()?;
        let lin = measurement.linearize(&self.nominal());
        let adapts = stream == Some(GnssStream::Position);
        if adapts {
            self.adapt_process_noise(&lin)?;
        }
        let rec = self.update_stream(stream, &lin, policy)?;
        if adapts {
            self.record_adaptive_gain(&rec);
        }
        self.add_information(&lin.h, &lin.r, rec.outcome)?;
        self.feedback()?;
        Ok(rec)
    }

    /// Eq. 3's term added to P before a GNSS position update (see
    /// [`set_adaptive_noise`](Self::set_adaptive_noise)); nothing without it.
    fn adapt_process_noise<const M: usize>(
        &mut self,
        lin: &Linearized<M, N>,
    ) -> Result<(), EstimationError> {
        let Some(a) = self.adaptive.as_mut() else {
            return Ok(());
        };
        let (Some(z), Some(h), Some(r)) = (reshape(&lin.z), reshape(&lin.h), reshape(&lin.r))
        else {
            return Ok(());
        };
        let innovation = self.kf.innovation(&z, &h, &r)?;
        let q = a.process_noise(&innovation.residual, &innovation.s);
        self.kf.set_covariance(self.kf.covariance() + q)
    }

    /// The adaptive noise's gain memory after a GNSS position update.
    fn record_adaptive_gain<const M: usize>(&mut self, rec: &UpdateRecord<Const<N>, Const<M>>) {
        let (Some(a), Some(gain)) = (self.adaptive.as_mut(), reshape(&rec.gain)) else {
            return;
        };
        // K_{k−1} of eq. 3 is the gain of the previous *update*: a
        // rejected fix made none and leaves it (recording its zero gain
        // would switch the feedback off at the next fix, P would
        // shrink, and one rejection would lead to the next). After a
        // reset the next fix feeds nothing back.
        match rec.outcome {
            Outcome::Rejected => {}
            Outcome::Reset => a.record_gain(&SMatrix::zeros()),
            _ => a.record_gain(&gain),
        }
    }

    /// An update under a policy, followed by the recovery (see
    /// [`RecoveryConfig`]): every detector sees an update that is not of
    /// its stream; a refused (rejected or limited) fix of a GNSS stream
    /// goes to the stream's agreement detector, and when it completes an
    /// agreeing run the stream's states are reset to it (outcome
    /// [`Outcome::Reset`]); an accepted one ends the stream's runs.
    fn update_stream<const M: usize, P: MeasurementPolicy<Const<M>> + ?Sized>(
        &mut self,
        stream: Option<GnssStream>,
        lin: &Linearized<M, N>,
        policy: &mut P,
    ) -> Result<UpdateRecord<Const<N>, Const<M>>, EstimationError> {
        let (z, h, r) = (&lin.z, &lin.h, &lin.r);
        if self.recovery.is_none() {
            return self.kf.update_with(z, h, r, policy);
        }
        let Some(stream) = stream else {
            let rec = self.kf.update_with(z, h, r, policy)?;
            if let Some(recovery) = self.recovery.as_mut() {
                recovery.updated(&rec.gain, h, None);
            }
            return Ok(rec);
        };
        let (x_prior, p_prior) = (*self.kf.state(), *self.kf.covariance());
        let mut rec = self.kf.update_with(z, h, r, policy)?;
        let Some(recovery) = self.recovery.as_mut() else {
            return Ok(rec);
        };
        recovery.updated(&rec.gain, h, Some(stream));
        if !matches!(rec.outcome, Outcome::Rejected | Outcome::Limited) {
            recovery.detector(stream).accepted();
            return Ok(rec);
        }
        // A GNSS stream's measurement has three components.
        let (Some(z3), Some(h3), Some(r3), Some(residual), Some(gain)) = (
            reshape(z),
            reshape(h),
            reshape(r),
            reshape(&rec.residual),
            reshape(&rec.gain),
        ) else {
            return Ok(rec);
        };
        let state_change = self.kf.state() - x_prior;
        let verdict = recovery.detector(stream).refused(&Update {
            residual: &residual,
            state_change: &state_change,
            r: &r3,
            h: &h3,
            prior_covariance: &p_prior,
            gain: &gain,
            posterior_covariance: self.kf.covariance(),
        });
        if let Verdict::Recover { .. } = verdict {
            self.reset_stream(stream, &z3, &h3, &r3)?;
            rec.outcome = Outcome::Reset;
        }
        Ok(rec)
    }

    /// Reset the error states a stream measures to its measurement z (H, R):
    /// they take the whole residual `z − H x` (so `H x = z`), their rows and
    /// columns of P are zeroed and their block set to `(1 + margin) R`
    /// (margin from the recovery; 0 without). The stream's detector forgets
    /// its runs; the other's lose those rows of their cross-covariances. No
    /// feedback here.
    fn reset_stream(
        &mut self,
        stream: GnssStream,
        z: &Vector3<f64>,
        h: &SMatrix<f64, 3, N>,
        r: &Matrix3<f64>,
    ) -> Result<(), EstimationError> {
        let margin = self.recovery.as_ref().map_or(0.0, |rc| rc.config.margin);
        let block = stream.block();
        let mut x = *self.kf.state();
        let residual = z - h * x;
        for i in 0..3 {
            x[block + i] += residual[i];
        }
        let mut p = *self.kf.covariance();
        for i in block..block + 3 {
            p.row_mut(i).fill(0.0);
            p.column_mut(i).fill(0.0);
        }
        let r_sym = (r + r.transpose()) * (0.5 * (1.0 + margin));
        p.fixed_view_mut::<3, 3>(block, block).copy_from(&r_sym);
        self.kf.set_state(x)?;
        self.kf.set_covariance(p)?;
        // The stream's own runs are over; the other stream's go on, their
        // cross-covariances without the rows of the reset states.
        if let Some(rc) = self.recovery.as_mut() {
            rc.detector(stream).clear();
            rc.detector(stream.other()).decorrelate(block, 3);
        }
        Ok(())
    }

    /// Reset the states of a GNSS stream to a measurement of it (a
    /// position or a velocity fix): they take the whole innovation, their P
    /// rows and columns are zeroed and their block set to `(1 + margin) R`
    /// (see [`RecoveryConfig`]); fed back as any update. The GNSS source
    /// calls it for the velocity after a position fix ended in
    /// [`Outcome::Reset`], so position and velocity restart together.
    pub fn reset_to<Meas: Measurement<3, N> + ?Sized>(
        &mut self,
        measurement: &Meas,
        stream: GnssStream,
    ) -> Result<(), EstimationError> {
        self.flush_covariance_for_update()?;
        let lin = measurement.linearize(&self.nominal());
        self.reset_stream(stream, &lin.z, &lin.h, &lin.r)?;
        self.feedback()
    }

    /// Move every error estimate into the INS and the instrument corrections.
    fn feedback(&mut self) -> Result<(), EstimationError> {
        if self.open_loop {
            return Ok(());
        }
        let x = *self.kf.state();
        self.fed_back += x;
        let v3 = |o: usize| Vector3::new(x[o], x[o + 1], x[o + 2]);
        self.ins.set_state(corrected(self.ins.state(), &x));
        self.instruments.gyro_bias += v3(GYRO_BIAS);
        self.instruments.accel_bias += v3(ACCEL_BIAS);
        self.instruments.gyro_scale += v3(GYRO_SCALE);
        self.instruments.accel_scale += v3(ACCEL_SCALE);
        for i in STATES..N {
            self.parameters[i] += x[i];
        }
        if let Some(o) = self.layout.offset(crate::state::Augmented::LeverArm) {
            self.lever_arm = Vec3::assume_in_frame(self.parameters.fixed_rows::<3>(o).into());
        }
        if let Some(o) = self
            .layout
            .offset(crate::state::Augmented::VehicleMisalignment)
        {
            self.vehicle_from_body = vehicle_rotation(
                self.vehicle_roll_rad,
                self.parameters[o],
                self.parameters[o + 1],
            );
        }
        // P by reference: a copy of it per update is a 3.5 kB memory copy.
        let (p, state) = (self.kf.covariance(), *self.ins.state());
        if let Some(r) = self.record.as_mut() {
            // Errors relative to the post-feedback nominal: the prediction
            // sat the feedback δ away from it.
            let x_predicted = r.rts.x_predicted() - x;
            r.rts.filtered(&x_predicted, &SVector::zeros(), p);
            r.open_state = state;
            if r.rts.open_mark().is_some()
                && let Some(st) = r.states.last_mut()
            {
                *st = state;
            }
        }
        #[cfg(test)]
        if let Some(r) = self.full_record.as_mut()
            && let (Some(e), Some(st)) = (r.epochs.last_mut(), r.states.last_mut())
        {
            e.x_predicted -= x;
            e.p_filtered = *p;
            *st = state;
        }
        self.kf.set_state(SVector::zeros())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurements::{
        GnssPosition, GnssVelocity, NonHolonomicConstraint, ZeroAngularRate, ZeroVelocity,
    };
    use aidnav_estimation::AcceptAll;

    /// The updates the tests make, each through the one update sequence.
    impl<const N: usize> NedFilter<N> {
        fn update_position(
            &mut self,
            fix: &Geodetic,
            sigma_ned: &Vector3<f64>,
        ) -> Result<GnssUpdate<N>, EstimationError> {
            self.update_position_with(fix, sigma_ned, &mut AcceptAll)
        }

        fn update_position_with<P: MeasurementPolicy<U3> + ?Sized>(
            &mut self,
            fix: &Geodetic,
            sigma_ned: &Vector3<f64>,
            policy: &mut P,
        ) -> Result<GnssUpdate<N>, EstimationError> {
            let m = GnssPosition {
                fix: *fix,
                sigma_ned_m: *sigma_ned,
            };
            self.fuse(&m, Some(GnssStream::Position), policy)
        }

        fn update_velocity_with<P: MeasurementPolicy<U3> + ?Sized>(
            &mut self,
            velocity_ned: &Vec3<Ned>,
            sigma_ned: &Vector3<f64>,
            policy: &mut P,
        ) -> Result<GnssUpdate<N>, EstimationError> {
            let m = GnssVelocity {
                velocity_ned_mps: *velocity_ned,
                sigma_ned_mps: *sigma_ned,
            };
            self.fuse(&m, Some(GnssStream::Velocity), policy)
        }

        fn reset_velocity_to(
            &mut self,
            velocity_ned: &Vec3<Ned>,
            sigma_ned: &Vector3<f64>,
        ) -> Result<(), EstimationError> {
            let m = GnssVelocity {
                velocity_ned_mps: *velocity_ned,
                sigma_ned_mps: *sigma_ned,
            };
            self.reset_to(&m, GnssStream::Velocity)
        }

        fn update_non_holonomic(&mut self, sigma_mps: f64) -> Result<(), EstimationError> {
            let m = NonHolonomicConstraint { sigma_mps };
            self.fuse(&m, None, &mut AcceptAll).map(|_| ())
        }

        fn update_zero_velocity(&mut self, sigma_mps: f64) -> Result<(), EstimationError> {
            self.fuse(&ZeroVelocity { sigma_mps }, None, &mut AcceptAll)
                .map(|_| ())
        }

        fn update_zero_angular_rate(
            &mut self,
            mean_raw_rate: &Vector3<f64>,
            sigma_rad_s: &Vector3<f64>,
        ) -> Result<(), EstimationError> {
            let m = ZeroAngularRate {
                mean_raw_rate_rad_s: *mean_raw_rate,
                sigma_rad_s: *sigma_rad_s,
            };
            self.fuse(&m, None, &mut AcceptAll).map(|_| ())
        }
    }

    use aidnav_models::ned_ins::ImuNoise;

    /// The structured antenna covariance equals nalgebra's formula to the
    /// bit: random covariances, lever arms zero and not, exact zeros of
    /// either sign where the sums end at zero (the fallback), and a P that
    /// is not finite.
    #[test]
    fn antenna_covariance_is_nalgebras_formula_to_the_bit() {
        use rand::{RngExt, SeedableRng};
        let bits = |m: &Matrix3<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20_261_130);
        let mut fallbacks = 0;
        for case in 0..600 {
            let a = Matrix21::from_fn(|_, _| rng.random_range(-1.0..1.0));
            let mut p = a * a.transpose();
            let lever = match case % 3 {
                0 => Vector3::zeros(),
                1 => Vector3::from_fn(|_, _| rng.random_range(-2.0..2.0)),
                _ => Vector3::new(0.0, rng.random_range(-0.5..0.5), 0.0),
            };
            if case % 4 == 0 {
                // Zeros of both signs in the position rows and columns.
                for (i, j, v) in [(0, 1, -0.0), (1, 2, 0.0), (0, 7, -0.0), (2, 2, 0.0)] {
                    p[(i, j)] = v;
                    p[(j, i)] = v;
                }
                fallbacks += 1;
            }
            let ours = antenna_covariance(&lever, &p);
            assert_eq!(
                bits(&ours),
                bits(&antenna_covariance_by_nalgebra(&lever, &p)),
                "case {case}"
            );
        }
        assert!(fallbacks > 0);
        let mut p = Matrix21::identity();
        p[(12, 12)] = f64::INFINITY;
        let lever = Vector3::new(0.1, 0.2, 0.3);
        assert!(antenna_covariance(&lever, &p).iter().all(|v| v.is_nan()));
        assert!(
            antenna_covariance_by_nalgebra(&lever, &p)
                .iter()
                .all(|v| v.is_nan())
        );
    }

    /// Prior σ: position, velocity, tilt, heading as given, instruments from
    /// the model's noise terms.
    /// At rest at the tests' site (latitude 0.7 rad, longitude −1.8 rad,
    /// 1600 m) with the attitude of these Euler angles (roll, pitch, yaw).
    fn at_rest(roll: f64, pitch: f64, yaw: f64) -> NedState {
        NedState {
            position: Geodetic {
                latitude_rad: 0.7,
                longitude_rad: -1.8,
                height_m: 1600.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(roll, pitch, yaw),
        }
    }

    /// At the tests' site at 10 m/s north-east, heading north-east, level.
    fn driving_north_east() -> NedState {
        NedState {
            velocity: Vec3::new(7.0, 7.0, 0.0),
            ..at_rest(0.0, 0.0, std::f64::consts::FRAC_PI_4)
        }
    }

    fn prior(model: &NedErrorModel, [p, v, tilt, heading]: [f64; 4]) -> Vector21 {
        let [sg, sa, kg, ka] = model.noise.instrument_sigmas();
        let mut sig = Vector21::zeros();
        for i in 0..3 {
            sig[POSITION + i] = p;
            sig[VELOCITY + i] = v;
            sig[ATTITUDE + i] = if i == 2 { heading } else { tilt };
            sig[GYRO_BIAS + i] = sg[i];
            sig[ACCEL_BIAS + i] = sa[i];
            sig[GYRO_SCALE + i] = kg[i];
            sig[ACCEL_SCALE + i] = ka[i];
        }
        sig
    }

    /// A static INS with biased gyros and accelerometers, fed exact
    /// position and zero velocity: it stays put, levels itself, and finds the
    /// vertical accelerometer bias.
    /// The smoother on a static INS whose accelerometer bias appears when
    /// the fixes stop for 60 s: the filtered position drifts in the gap, the
    /// smoothed one (fixes after the gap tell the bias) stays much closer.
    #[test]
    fn smoother_closes_a_gap_between_fixes() {
        let start = at_rest(0.0, 0.0, 0.5);
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.5, 0.05, 0.01, 0.01]);
        let mut f = NedFilter::new(model, start, &sig, Vec3::zeros()).unwrap();
        f.start_recording(100_000);
        let imu = NedMechanization::stationary_increment(&start, 0.01);
        // An accelerometer bias of 0.02 m/s² on x appears when the fixes stop.
        let mut biased = imu;
        biased.delta_velocity += Vec3::new(0.02 * 0.01, 0.0, 0.0);
        let mut gap = Vec::new(); // (record index, filtered drift)
        for k in 0..18_000 {
            let t = (k + 1) as f64 * 0.01;
            f.propagate(if t > 60.0 { &biased } else { &imu }).unwrap();
            let in_gap = (60.0..120.0).contains(&t);
            if k % 25 == 24 && !in_gap {
                f.update_position(&start.position, &Vector3::repeat(0.05))
                    .unwrap();
            }
            if in_gap && k % 100 == 99 {
                let drift = start.position.ned_to(&f.state().position).norm();
                gap.push((f.mark_for_smoothing().unwrap(), drift));
            }
        }
        let smoothed = f.smoothed_states().unwrap().unwrap();
        let worst_filtered = gap.iter().map(|g| g.1).fold(0.0, f64::max);
        let worst_smoothed = gap
            .iter()
            .map(|&(i, _)| start.position.ned_to(&smoothed[i].position).norm())
            .fold(0.0, f64::max);
        // Measured: filtered 34.8 m, smoothed 0.44 m.
        assert!(
            worst_filtered > 1.0,
            "the gap must hurt the filter: {worst_filtered}"
        );
        assert!(
            worst_smoothed < 0.2 * worst_filtered,
            "{worst_smoothed} vs {worst_filtered}"
        );
    }

    /// The recorded smoother (the engine's [`RtsRecorder`], composed between
    /// the marked epochs) against the engine's stored-pass smoother
    /// ([`aidnav_estimation::rts_smooth`] over every covariance epoch, the
    /// smoother this filter used before) on the same run: a static INS
    /// with position and velocity fixes at 4 Hz, non-holonomic updates at
    /// 10 Hz, zero-velocity updates at 1 Hz, an accelerometer bias that
    /// appears in a 20 s gap without fixes, marks at every fix and every
    /// second of the gap. Smoothed position, velocity, attitude and antenna
    /// covariance agree to rounding.
    #[test]
    fn recorded_smoother_equals_the_stored_pass_smoother() {
        // The smoothed output's promise (position in m, velocity in m/s,
        // attitude in rad, covariance in m²); the difference is rounding.
        const TOLERANCE: f64 = 1e-9;
        let start = at_rest(0.01, -0.02, 0.5);
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.5, 0.05, 0.01, 0.02]);
        let mut f = NedFilter::new(model, start, &sig, Vec3::new(0.3, -0.1, -0.8)).unwrap();
        f.start_recording(100_000);
        let imu = NedMechanization::stationary_increment(&start, 0.01);
        let mut biased = imu;
        biased.delta_velocity += Vec3::new(0.02 * 0.01, -0.01 * 0.01, 0.0);
        let mut marks = Vec::new(); // (mark, index in the full record)
        let full_index = |f: &NedFilter| f.full_record.as_ref().unwrap().epochs.len() - 1;
        for k in 0..9_000 {
            let t = (k + 1) as f64 * 0.01;
            f.propagate(if t > 30.0 { &biased } else { &imu }).unwrap();
            let in_gap = (40.0..60.0).contains(&t);
            if k % 10 == 9 {
                f.update_non_holonomic(0.1).unwrap();
            }
            if k % 100 == 99 && !in_gap {
                f.update_zero_velocity(0.05).unwrap();
            }
            if k % 25 == 24 && !in_gap {
                let truth = start.position.offset_by(&(start.attitude * f.lever_arm));
                let fix = truth.offset_by(&Vec3::new(0.01, -0.02, 0.015));
                f.update_position(&fix, &Vector3::repeat(0.05)).unwrap();
                f.update_velocity_with(&Vec3::zeros(), &Vector3::repeat(0.02), &mut AcceptAll)
                    .unwrap();
                marks.push((f.mark_for_smoothing().unwrap(), full_index(&f)));
            }
            if in_gap && k % 100 == 99 {
                marks.push((f.mark_for_smoothing().unwrap(), full_index(&f)));
            }
        }
        let new = f.smoothed_states_with_covariance().unwrap().unwrap();
        let full = f.full_record.as_ref().unwrap();
        let old = aidnav_estimation::rts_smooth(&full.epochs).unwrap();
        assert_eq!(new.len(), marks.len());
        assert!(full.epochs.len() > 2 * marks.len());
        let mut worst = [0.0_f64; 4];
        for &(m, i) in &marks {
            let state = corrected(&full.states[i], &old[i].x);
            let c = state.attitude.matrix();
            let h = NedErrorModel::position_measurement((c * f.lever_arm).as_raw());
            let p = h * old[i].p * h.transpose();
            let p = (p + p.transpose()) * 0.5;
            let (s, cov) = &new[m];
            worst[0] = worst[0].max(state.position.ned_to(&s.position).norm());
            worst[1] = worst[1].max((state.velocity - s.velocity).norm());
            worst[2] = worst[2].max(state.attitude.angle_to(&s.attitude));
            worst[3] = worst[3].max((p - cov).abs().max());
        }
        eprintln!(
            "worst differences (position m, velocity m/s, attitude rad, covariance m²): {worst:?}"
        );
        assert!(worst.iter().all(|&w| w < TOLERANCE), "{worst:?}");
        // The smoother did its job in the gap: the smoothed positions there
        // moved away from the drifting filtered ones.
        let moved = marks
            .iter()
            .map(|&(m, i)| full.states[i].position.ned_to(&new[m].0.position).norm())
            .fold(0.0, f64::max);
        assert!(moved > 0.1, "{moved}");
    }

    /// At a standstill without GNSS: zero-velocity updates hold the velocity
    /// and position, zero-angular-rate updates find a gyro bias that the
    /// levelled, static INS otherwise only sees through slow tilt drift.
    #[test]
    fn standstill_updates_hold_the_ins_and_find_the_gyro_bias() {
        let start = at_rest(0.01, -0.02, 0.5);
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.5, 0.05, 0.01, 0.01]);
        let bias = Vector3::new(2e-4, -3e-4, 1e-4); // ≈ 40, 60, 20 °/h
        let run = |standstill: bool| {
            let mut f = NedFilter::new(model, start, &sig, Vec3::zeros()).unwrap();
            let mut imu = NedMechanization::stationary_increment(&start, 0.01);
            imu.delta_angle += Vec3::assume_in_frame(bias * 0.01);
            let raw_rate = imu.delta_angle.raw() / 0.01;
            for k in 0..6000 {
                f.propagate(&imu).unwrap();
                if standstill && k % 10 == 9 {
                    f.update_zero_velocity(0.02).unwrap();
                    f.update_zero_angular_rate(&raw_rate, &Vector3::repeat(1e-4))
                        .unwrap();
                }
            }
            let drift = start.position.ned_to(&f.state().position).norm();
            (drift, f.instruments().gyro_bias)
        };
        let (drift_free, _) = run(false);
        let (drift, estimated) = run(true);
        // Measured: 60 s free 127 m; held 6e-7 m; bias error 1.3e-10 rad/s.
        assert!(drift_free > 10.0, "free drift {drift_free}");
        assert!(drift < 0.01, "held drift {drift}");
        assert!(
            (estimated - bias).norm() < 1e-7,
            "bias {estimated} against {bias}"
        );
    }

    /// While the INS errors stay small (linear regime), open and closed loop
    /// give the same solution.
    #[test]
    fn open_loop_matches_closed_loop_for_small_errors() {
        let start = NedState {
            position: Geodetic {
                latitude_rad: 0.5,
                longitude_rad: 0.2,
                height_m: 10.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(0.0, 0.0, 1.0),
        };
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.5, 0.05, 0.01, 0.01]);
        let mut closed = NedFilter::new(model, start, &sig, Vec3::zeros()).unwrap();
        let mut open = closed.clone();
        open.set_open_loop(true);
        let mut imu = NedMechanization::stationary_increment(&start, 0.01);
        imu.delta_velocity += Vec3::new(0.0, 2e-3 * 0.01, 0.0);
        for k in 0..6_000 {
            closed.propagate(&imu).unwrap();
            open.propagate(&imu).unwrap();
            if k % 25 == 24 {
                for f in [&mut closed, &mut open] {
                    f.update_position(&start.position, &Vector3::repeat(0.05))
                        .unwrap();
                }
            }
        }
        let (a, b) = (closed.solution(), open.solution());
        let d = a.position.ned_to(&b.position).norm();
        assert!(d < 0.01, "{d}");
        // The open-loop INS itself has drifted away; only its output is corrected.
        assert!(start.position.ned_to(&open.state().position).norm() > 1.0);
    }

    /// Eq. 3 on this filter: before a position update, P grows by exactly
    /// `K_prev ν νᵀ K_prevᵀ` (previous position gain, this innovation); a
    /// missing fix zeroes the gain, so the first fix after it adds nothing.
    #[test]
    fn adaptive_noise_adds_the_innovation_feedback_term() {
        let start = NedState {
            position: Geodetic {
                latitude_rad: 0.6,
                longitude_rad: 0.1,
                height_m: 100.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(0.0, 0.0, 0.3),
        };
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.5, 0.05, 0.01, 0.01]);
        let mut adaptive = NedFilter::new(model, start, &sig, Vec3::new(0.5, 0.2, -0.3)).unwrap();
        adaptive.set_adaptive_noise(None, 1, false);
        let mut imu = NedMechanization::stationary_increment(&start, 0.01);
        imu.delta_velocity += Vec3::new(0.05 * 0.01, 0.0, 0.0);
        let sigma = Vector3::repeat(0.05);
        let coast = |f: &mut NedFilter| {
            for _ in 0..25 {
                f.propagate(&imu).unwrap();
            }
        };
        coast(&mut adaptive);
        let first = adaptive.update_position(&start.position, &sigma).unwrap();
        coast(&mut adaptive);
        // The same filter without the adaptive term, its P raised by hand.
        let mut by_hand = adaptive.clone();
        by_hand.adaptive = None;
        by_hand.flush_covariance().unwrap();
        let second = adaptive.update_position(&start.position, &sigma).unwrap();
        let kv = first.gain * second.residual;
        let raised = by_hand.kf.covariance() + kv * kv.transpose();
        by_hand.kf.set_covariance(raised).unwrap();
        let again = by_hand.update_position(&start.position, &sigma).unwrap();
        assert!(kv.norm() > 1e-4, "the term must matter: {}", kv.norm());
        assert!((again.residual - second.residual).norm() < 1e-12);
        let scale = adaptive.kf.covariance().norm();
        assert!((adaptive.kf.covariance() - by_hand.kf.covariance()).norm() < 1e-12 * scale);
        // After a missing fix the gain is zero: the next update equals one
        // without the adaptive term.
        adaptive.position_fix_missing().unwrap();
        coast(&mut adaptive);
        let mut plain = adaptive.clone();
        plain.adaptive = None;
        adaptive.update_position(&start.position, &sigma).unwrap();
        plain.update_position(&start.position, &sigma).unwrap();
        assert_eq!(adaptive.kf.covariance(), plain.kf.covariance());
    }

    /// Fixes every this many IMU samples (100 Hz → 4 Hz).
    const FIX_EVERY: usize = 25;

    /// A car at 10 m/s heading north-east (the INS of the filter *is* the
    /// truth: both mechanize the same ideal increments), antenna 1 m ahead
    /// of the IMU; fixes σ 2 cm at the true antenna, shifted by `step` from
    /// fix `step_at` on. Returns the filter, the outcome of every fix and the
    /// distance of the solution's antenna from each fix (as given) after it.
    fn drive_with_step(
        recovery: Option<RecoveryConfig>,
        fixes: usize,
        step_at: usize,
        step: Vec3<Ned>,
    ) -> (NedFilter, Vec<Outcome>, Vec<f64>) {
        let start = driving_north_east();
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.02, 0.01, 0.001, 0.001]);
        let lever = Vec3::new(1.0, 0.0, 0.0);
        let mut filter = NedFilter::new(model, start, &sig, lever).unwrap();
        filter.set_recovery(recovery).unwrap();
        let mut truth = NedMechanization::new(start);
        let mut gate = aidnav_estimation::Chi2Gate { probability: 0.999 };
        let sigma = Vector3::repeat(0.02);
        let (mut outcomes, mut distances) = (Vec::new(), Vec::new());
        for k in 0..fixes * FIX_EVERY {
            let imu = NedMechanization::stationary_increment(truth.state(), 0.01);
            truth.update(&imu);
            filter.propagate(&imu).unwrap();
            if k % FIX_EVERY == FIX_EVERY - 1 {
                let s = truth.state();
                let antenna = s.position.offset_by(&(s.attitude * lever));
                let n = k / FIX_EVERY;
                // ±1 cm of deterministic noise.
                let noise = Vec3::new(
                    0.01 * (n as f64 * 1.3).sin(),
                    0.01 * (n as f64 * 2.1).cos(),
                    0.0,
                );
                let fix = if n >= step_at {
                    antenna.offset_by(&(step + noise))
                } else {
                    antenna.offset_by(&noise)
                };
                let rec = filter
                    .update_position_with(&fix, &sigma, &mut gate)
                    .unwrap();
                outcomes.push(rec.outcome);
                distances.push(fix.ned_to(&filter.antenna().0).norm());
            }
        }
        (filter, outcomes, distances)
    }

    /// Fixes agreeing in a run this long make a reset (the default of
    /// `aidnav process`: one more than the longest short burst of spec 20).
    const RUN: usize = 21;

    fn recovery(run_length: usize) -> RecoveryConfig {
        RecoveryConfig {
            agreement: AgreementConfig {
                run_length,
                probability: 0.999,
            },
            margin: 1.0,
        }
    }

    /// Every fix from fix 40 on 50 m east of the truth (the reference
    /// changed): a χ² gate never believes it and locks out for good; with
    /// the recovery the 21st refused fix resets the filter onto the new
    /// reference, whose fixes are then accepted — on a car moving at
    /// 10 m/s, whose fixes move 2.5 m between fixes, which the agreement test
    /// takes from the filter's own prediction.
    #[test]
    fn a_step_the_gate_never_believes_is_recovered_within_the_run_length() {
        let step = Vec3::new(0.0, 50.0, 0.0);
        let (_, locked, far) = drive_with_step(None, 100, 40, step);
        assert!(
            locked[..40].iter().all(|&o| o == Outcome::Accepted),
            "{locked:?}"
        );
        assert!(
            locked[40..].iter().all(|&o| o == Outcome::Rejected),
            "{locked:?}"
        );
        assert!(far[99] > 49.0, "{}", far[99]);

        let (filter, outcomes, distances) = drive_with_step(Some(recovery(RUN)), 100, 40, step);
        assert!(outcomes[..40].iter().all(|&o| o == Outcome::Accepted));
        let after = &outcomes[40..];
        assert!(
            after[..RUN - 1].iter().all(|&o| o == Outcome::Rejected),
            "{after:?}"
        );
        assert_eq!(after[RUN - 1], Outcome::Reset, "{after:?}");
        assert!(
            after[RUN..].iter().all(|&o| o == Outcome::Accepted),
            "{after:?}"
        );
        // The reset puts the antenna on the fix (to the first-order
        // geodetic offsets, 0.3 mm over 50 m); the next fixes track it.
        assert!(
            distances[40 + RUN - 1] < 1e-3,
            "{}",
            distances[40 + RUN - 1]
        );
        let worst = distances[40 + RUN..].iter().fold(0.0_f64, |a, &b| a.max(b));
        assert!(worst < 0.05, "{worst}");
        assert!(filter.sigmas()[POSITION] < 0.05);
    }

    /// The fixes of the moving car move 2.5 m between fixes: the test takes
    /// that from the filter's prediction, and the count of fixes to the
    /// reset is exactly the run length.
    #[test]
    fn the_run_length_is_the_number_of_fixes_to_recover() {
        for run in [2, 5, 9] {
            let (_, outcomes, _) =
                drive_with_step(Some(recovery(run)), 60, 30, Vec3::new(20.0, 0.0, -5.0));
            let first_reset = outcomes.iter().position(|&o| o == Outcome::Reset);
            assert_eq!(first_reset, Some(30 + run - 1), "{run}: {outcomes:?}");
            assert_eq!(outcomes.iter().filter(|&&o| o == Outcome::Reset).count(), 1);
        }
    }

    /// A filter whose velocity is 1 m/s off while it believes it to 1 cm/s
    /// (P): a χ² gate refuses every position and velocity fix from the
    /// start, and the position fixes disagree with the filter's prediction
    /// by 0.25 m a fix — the first agreement test fails, the common-rate one
    /// holds. The velocity fixes agree at once and reset the velocity at the
    /// 21st; the position run, its cross-covariances stripped of the
    /// velocity rows, goes on and resets at the 22nd; then every fix is
    /// accepted and the solution is on the fixes.
    #[test]
    fn a_diverged_filter_is_reset_by_its_velocity_and_position_runs() {
        let start = driving_north_east();
        let model = NedErrorModel::default();
        let sig = prior(&model, [0.02, 0.01, 0.001, 0.001]);
        let wrong = NedState {
            velocity: start.velocity + Vec3::new(0.0, 1.0, 0.0),
            ..start
        };
        let mut filter = NedFilter::new(model, wrong, &sig, Vec3::zeros()).unwrap();
        filter.set_recovery(Some(recovery(RUN))).unwrap();
        let mut truth = NedMechanization::new(start);
        let (mut gate, mut vgate) = (
            aidnav_estimation::Chi2Gate { probability: 0.999 },
            aidnav_estimation::Chi2Gate { probability: 0.999 },
        );
        let (mut position, mut velocity, mut errors) = (Vec::new(), Vec::new(), Vec::new());
        for k in 0..60 * FIX_EVERY {
            let imu = NedMechanization::stationary_increment(truth.state(), 0.01);
            truth.update(&imu);
            filter.propagate(&imu).unwrap();
            if k % FIX_EVERY == FIX_EVERY - 1 {
                let s = *truth.state();
                let p = filter
                    .update_position_with(&s.position, &Vector3::repeat(0.02), &mut gate)
                    .unwrap();
                let v = if p.outcome == Outcome::Reset {
                    filter
                        .reset_velocity_to(&s.velocity, &Vector3::repeat(0.05))
                        .unwrap();
                    Outcome::Reset
                } else {
                    filter
                        .update_velocity_with(&s.velocity, &Vector3::repeat(0.05), &mut vgate)
                        .unwrap()
                        .outcome
                };
                position.push(p.outcome);
                velocity.push(v);
                errors.push(s.position.ned_to(&filter.solution().position).norm());
            }
        }
        let refused = |o: &Outcome| *o == Outcome::Rejected;
        assert!(velocity[..RUN - 1].iter().all(refused), "{velocity:?}");
        assert_eq!(velocity[RUN - 1], Outcome::Reset);
        assert!(position[..RUN].iter().all(refused), "{position:?}");
        assert_eq!(position[RUN], Outcome::Reset, "{position:?}");
        assert!(position[RUN + 1..].iter().all(|&o| o == Outcome::Accepted));
        assert!(velocity[RUN + 1..].iter().all(|&o| o == Outcome::Accepted));
        // 5 m off when the position resets (21 × 0.25 s at 1 m/s), on the
        // fixes after it.
        assert!(errors[RUN - 1] > 5.0, "{}", errors[RUN - 1]);
        let worst = errors[RUN..].iter().fold(0.0_f64, |a, &b| a.max(b));
        assert!(worst < 0.03, "{worst}");
    }

    /// The covariance after a reset: symmetric, positive semi-definite, the
    /// reset block (1 + margin) R, no correlation of the reset states with
    /// any other state; the other states' block untouched. The state moves
    /// so that H x = z.
    #[test]
    fn a_reset_decorrelates_the_states_and_keeps_p_symmetric_psd() {
        let (mut filter, _, _) = drive_with_step(None, 20, 100, Vec3::zeros());
        filter
            .set_recovery(Some(RecoveryConfig {
                margin: 0.5,
                ..recovery(RUN)
            }))
            .unwrap();
        let before = *filter.kf.covariance();
        // Correlated beforehand: position with attitude and velocity.
        assert!(before[(POSITION, VELOCITY)].abs() > 1e-9);
        assert!(before[(POSITION, ATTITUDE + 2)].abs() > 1e-12);
        let (antenna, _) = filter.antenna();
        let fix = antenna.offset_by(&Vec3::new(3.0, -4.0, 1.0));
        let sigma = Vector3::new(0.3, 0.4, 0.5);
        let z = fix.ned_to(&antenna).raw();
        let h = NedErrorModel::position_measurement(
            &(filter.state().attitude.matrix() * filter.lever_arm).raw(),
        );
        let r = Matrix3::from_diagonal(&sigma.map(|v| v * v));
        filter.flush_covariance().unwrap();
        filter
            .reset_stream(GnssStream::Position, &z, &h, &r)
            .unwrap();
        let x = *filter.kf.state();
        assert!((h * x - z).norm() < 1e-12);
        let p = *filter.kf.covariance();
        assert_eq!(p, p.transpose());
        let eig = p.symmetric_eigenvalues();
        assert!(eig.min() >= -1e-15 * eig.max(), "{}", eig.min());
        for i in POSITION..POSITION + 3 {
            for j in 0..STATES {
                let expected = if (POSITION..POSITION + 3).contains(&j) {
                    1.5 * r[(i - POSITION, j - POSITION)]
                } else {
                    0.0
                };
                assert_eq!(p[(i, j)], expected, "({i}, {j})");
            }
        }
        for i in VELOCITY..STATES {
            for j in VELOCITY..STATES {
                assert_eq!(p[(i, j)], before[(i, j)]);
            }
        }
        // Fed back, the antenna is on the fix (to the first-order geodetic
        // offsets).
        filter.feedback().unwrap();
        let off = fix.ned_to(&filter.antenna().0).norm();
        assert!(off < 1e-4, "{off}");
        // The velocity reset does the same to its block, and keeps the
        // position block it does not measure.
        let v_fix = filter.antenna().1 + Vec3::new(0.5, 0.0, 0.0);
        filter
            .reset_velocity_to(&v_fix, &Vector3::repeat(0.1))
            .unwrap();
        let p = *filter.kf.covariance();
        assert!((p[(POSITION, POSITION)] - 1.5 * 0.09).abs() < 1e-15);
        assert!((p[(VELOCITY, VELOCITY)] - 1.5 * 0.01).abs() < 1e-15);
        assert_eq!(p[(POSITION, VELOCITY)], 0.0);
        assert!((filter.antenna().1 - v_fix).norm() < 1e-9);
    }

    #[test]
    fn static_alignment_finds_the_vertical_accelerometer_bias() {
        let start = at_rest(0.01, -0.02, 0.5);
        let model = NedErrorModel {
            noise: ImuNoise::default(),
        };
        let sig = prior(&model, [1.0, 0.1, 0.01, 0.1]);
        let mut f = NedFilter::new(model, start, &sig, Vec3::zeros()).unwrap();
        let mut imu = NedMechanization::stationary_increment(&start, 0.01);
        imu.delta_velocity += Vec3::new(0.0, 0.0, 0.01 * 0.01); // 0.01 m/s² bias on body z
        for k in 0..30_000 {
            f.propagate(&imu).unwrap();
            if k % 25 == 24 {
                f.update_position(&start.position, &Vector3::repeat(0.02))
                    .unwrap();
                f.update_velocity_with(&Vec3::zeros(), &Vector3::repeat(0.01), &mut AcceptAll)
                    .unwrap();
            }
        }
        let drift = start.position.ned_to(&f.state().position).norm();
        assert!(drift < 0.05, "{drift}");
        // Static, bias and scale factor on z are one thing: b_z + s_z f_z
        // (f_z ≈ −g) is what is observable, and it is found.
        let i = f.instruments();
        let f_z = imu.delta_velocity.z() / 0.01;
        let effective = i.accel_bias.z + i.accel_scale.z * f_z;
        assert!((effective - 0.01).abs() < 2e-4, "{effective} from {i:?}");
    }
}
