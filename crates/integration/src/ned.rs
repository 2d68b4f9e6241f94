//! Spec 40's loosely coupled GNSS/INS filter: the WGS-84 NED mechanization
//! ([`aidnav_ins::ned`]), the 21-state error model
//! ([`aidnav_models::ned_ins`]), GNSS position and velocity updates with the
//! antenna lever arm, closed-loop feedback into the INS and into the
//! instrument corrections (`ω = (ω̃ − b_g) / (1 + s_g)`, likewise f), and
//! any measurement policy of the engine on each update.

use aidnav_estimation::{
    AcceptAll, EstimationError, FisherInformation, FixedKalmanFilter, ForwardEpoch,
    MeasurementPolicy, Outcome, UpdateRecord,
    adaptive::{AnomalyDetector, InnovationFeedbackNoise},
    nalgebra::{Const, U3},
    rts_smooth,
};
use aidnav_frames::earth::{Geodetic, earth_rate_ned, transport_rate_ned};
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, NedErrorModel, POSITION, STATES,
    VELOCITY, Vector21,
};
use nalgebra::{Matrix3, SMatrix, Vector3};

use aidnav_ins::ned::{ImuIncrement, NedMechanization, NedState};

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
fn corrected(state: &NedState, x: &Vector21) -> NedState {
    // The navigation error states are NED vectors (δr, δv, φ).
    let v3 = |o: usize| Vec3::<Ned>::new(x[o], x[o + 1], x[o + 2]);
    NedState {
        position: state.position.offset_by(&-v3(POSITION)),
        velocity: state.velocity - v3(VELOCITY),
        attitude: Rotation::from_rotation_vector(v3(ATTITUDE)) * state.attitude,
    }
}

/// Record of one GNSS update.
pub type GnssUpdate = UpdateRecord<Const<STATES>, U3>;

/// Bytes the stored forward pass takes per epoch (Φ, P⁻, P⁺, two vectors,
/// the nominal state): what a smoothing run costs in memory.
pub const BYTES_PER_RECORDED_EPOCH: usize =
    std::mem::size_of::<ForwardEpoch<Const<STATES>>>() + std::mem::size_of::<NedState>();

/// The forward pass kept for the Rauch–Tung–Striebel smoother, in the
/// closed-loop form: one epoch per covariance propagation, the updates at
/// that time folded into it. Errors are stored relative to the nominal
/// state *after* the epoch's feedback, so the filtered error is 0 and the
/// predicted one is minus the feedback δ applied at the epoch; the engine's
/// [`rts_smooth`] then works unchanged.
#[derive(Debug, Clone, Default)]
struct ForwardRecord {
    epochs: Vec<ForwardEpoch<Const<STATES>>>,
    states: Vec<NedState>,
    max_epochs: usize,
    overflow: bool,
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
/// use aidnav_integration::ned::NedFilter;
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
/// let record = filter.update_position(&fix, &Vector3::repeat(0.1)).unwrap();
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
pub struct NedFilter {
    model: NedErrorModel,
    ins: NedMechanization,
    kf: FixedKalmanFilter<STATES>,
    instruments: InstrumentEstimate,
    lever_arm: Vec3<Body>,
    rate: Vec3<Body>,
    pending_force: Vec3<Body>,
    pending_angle: Vec3<Body>,
    pending_dt: f64,
    covariance_interval_s: f64,
    record: Option<ForwardRecord>,
    open_loop: bool,
    monitor: Option<ConvergenceMonitor>,
    fed_back: Vector21,
    adaptive: Option<InnovationFeedbackNoise<Const<STATES>, U3>>,
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

/// A smoothed navigation state and the covariance of its antenna position
/// error (NED, m²).
pub type SmoothedAntenna = (NedState, Matrix3<f64>);

impl NedFilter {
    /// Start at `state` with the prior σ of every error state and the
    /// antenna lever arm (body frame, from the IMU to the antenna).
    pub fn new(
        model: NedErrorModel,
        state: NedState,
        prior_sigmas: &Vector21,
        lever_arm: Vec3<Body>,
    ) -> Result<Self, EstimationError> {
        let p0 = SMatrix::<f64, STATES, STATES>::from_diagonal(&prior_sigmas.map(|s| s * s));
        Ok(Self {
            model,
            ins: NedMechanization::new(state),
            kf: FixedKalmanFilter::new(Vector21::zeros(), p0)?,
            instruments: InstrumentEstimate::default(),
            lever_arm,
            rate: Vec3::zeros(),
            pending_force: Vec3::zeros(),
            pending_angle: Vec3::zeros(),
            pending_dt: 0.0,
            covariance_interval_s: 0.05,
            record: None,
            open_loop: false,
            monitor: None,
            fed_back: Vector21::zeros(),
            adaptive: None,
        })
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
        let s = *self.ins.state();
        if !self.open_loop {
            return s;
        }
        corrected(&s, self.kf.state())
    }

    /// The instrument corrections.
    pub fn instruments(&self) -> &InstrumentEstimate {
        &self.instruments
    }

    /// Start the gyro-bias correction at a value (e.g. measured at rest).
    pub fn set_gyro_bias(&mut self, bias: Vector3<f64>) {
        self.instruments.gyro_bias = bias;
    }

    /// Mechanize one raw increment *without* the instrument corrections and
    /// without touching the covariance: the free INS of an outage score.
    pub fn coast_uncorrected(&mut self, raw: &ImuIncrement) {
        if raw.dt_s > 0.0 {
            self.ins.update(raw);
        }
    }

    /// σ of every error state (as of the last covariance propagation).
    pub fn sigmas(&self) -> Vector21 {
        self.kf.covariance().diagonal().map(f64::sqrt)
    }

    /// Covariance of the antenna position error (NED, m²) as of the last
    /// covariance propagation: `H P Hᵀ` with the position measurement's
    /// `H = [I, 0, [(C l)×], 0 …]` — the IMU position block plus the
    /// attitude error seen through the lever arm `C l`, and their
    /// cross-covariance (symmetrised).
    pub fn antenna_position_covariance(&self) -> Matrix3<f64> {
        let c = self.solution().attitude.matrix();
        let h = NedErrorModel::position_measurement((c * self.lever_arm).as_raw());
        let p = h * self.kf.covariance() * h.transpose();
        (p + p.transpose()) * 0.5
    }

    /// The antenna position and NED velocity implied by the INS.
    pub fn antenna(&self) -> (Geodetic, Vec3<Ned>) {
        let s = &self.solution();
        let c = s.attitude.matrix();
        let arm = c * self.lever_arm;
        (
            s.position.offset_by(&arm),
            s.velocity + c * self.rate.cross(&self.lever_arm),
        )
    }

    /// Mechanize one raw increment and propagate the covariance.
    pub fn propagate(&mut self, raw: &ImuIncrement) -> Result<(), EstimationError> {
        let imu = self.instruments.correct(raw);
        if imu.dt_s.is_nan() || imu.dt_s <= 0.0 {
            return Ok(());
        }
        self.ins.update(&imu);
        self.rate = imu.delta_angle / imu.dt_s;
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

    /// Propagate the covariance over the accumulated interval.
    fn flush_covariance(&mut self) -> Result<(), EstimationError> {
        if self.pending_dt <= 0.0 {
            return Ok(());
        }
        let dt = self.pending_dt;
        let s = self.ins.state();
        let c = s.attitude.matrix();
        let f = self.model.continuous(
            c.as_raw(),
            (self.pending_force / dt).as_raw(),
            (self.pending_angle / dt).as_raw(),
            earth_rate_ned(s.position.latitude_rad).as_raw(),
            transport_rate_ned(&s.position, &s.velocity).as_raw(),
            s.position.latitude_rad,
        );
        let (phi, q) = self.model.discrete(&f, c.as_raw(), dt);
        self.pending_force = Vec3::zeros();
        self.pending_angle = Vec3::zeros();
        self.pending_dt = 0.0;
        self.kf.predict(&phi, &q)?;
        if let Some(m) = self.monitor.as_mut() {
            m.fisher.propagate(&phi)?;
        }
        let (p, state) = (*self.kf.covariance(), *self.ins.state());
        if let Some(r) = self.record.as_mut() {
            if r.epochs.len() >= r.max_epochs {
                r.overflow = true;
            } else {
                r.epochs.push(ForwardEpoch {
                    phi,
                    x_predicted: Vector21::zeros(),
                    p_predicted: p,
                    x_filtered: Vector21::zeros(),
                    p_filtered: p,
                });
                r.states.push(state);
            }
        }
        Ok(())
    }

    /// Keep the forward pass (at most `max_epochs` covariance epochs) for
    /// [`smoothed_states`](Self::smoothed_states); starts at the current state.
    pub fn start_recording(&mut self, max_epochs: usize) {
        let p = *self.kf.covariance();
        self.record = Some(ForwardRecord {
            epochs: vec![ForwardEpoch {
                phi: SMatrix::identity(),
                x_predicted: Vector21::zeros(),
                p_predicted: p,
                x_filtered: Vector21::zeros(),
                p_filtered: p,
            }],
            states: vec![*self.ins.state()],
            max_epochs: max_epochs.max(1),
            overflow: false,
        });
    }

    /// Index of the current recorded epoch (None when not recording).
    pub fn recorded_epoch(&self) -> Option<usize> {
        self.record.as_ref().map(|r| r.epochs.len() - 1)
    }

    /// The Rauch–Tung–Striebel smoothed navigation state of every recorded
    /// epoch (IMU position, velocity, attitude), or None when not
    /// recording or when the record overflowed its epoch limit.
    pub fn smoothed_states(&self) -> Result<Option<Vec<NedState>>, EstimationError> {
        Ok(self
            .smoothed_states_with_covariance()?
            .map(|v| v.into_iter().map(|(s, _)| s).collect()))
    }

    /// [`smoothed_states`](Self::smoothed_states), each with the smoothed
    /// covariance of its antenna position error (NED, m²; `H P Hᵀ` as in
    /// [`antenna_position_covariance`](Self::antenna_position_covariance),
    /// at the smoothed attitude).
    pub fn smoothed_states_with_covariance(
        &self,
    ) -> Result<Option<Vec<SmoothedAntenna>>, EstimationError> {
        let Some(r) = self.record.as_ref().filter(|r| !r.overflow) else {
            return Ok(None);
        };
        let smoothed = rts_smooth(&r.epochs)?;
        Ok(Some(
            smoothed
                .iter()
                .zip(&r.states)
                .map(|(e, s)| {
                    let state = corrected(s, &e.x);
                    let c = state.attitude.matrix();
                    let h = NedErrorModel::position_measurement((c * self.lever_arm).as_raw());
                    let p = h * e.p * h.transpose();
                    (state, (p + p.transpose()) * 0.5)
                })
                .collect(),
        ))
    }

    /// Antenna position of an IMU state under this filter's lever arm.
    pub fn antenna_of(&self, state: &NedState) -> Geodetic {
        state.position.offset_by(&(state.attitude * self.lever_arm))
    }

    /// Start the Cramér–Rao convergence monitor of the instrument states
    /// (spec 10's δ(n), see [`instrument_convergence`](Self::instrument_convergence)).
    pub fn start_convergence_monitor(&mut self) -> Result<(), EstimationError> {
        let p = *self.kf.covariance();
        self.monitor = Some(ConvergenceMonitor {
            fisher: FisherInformation::from_prior_covariance(&p)?,
            prior: p.diagonal(),
            before: 0.0,
        });
        Ok(())
    }

    /// Normalised trace of the instrument block of P.
    fn instrument_trace(&self, p: &SMatrix<f64, STATES, STATES>) -> f64 {
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

    fn add_information<M: nalgebra::Dim>(
        &mut self,
        h: &nalgebra::OMatrix<f64, M, Const<STATES>>,
        r: &nalgebra::OMatrix<f64, M, M>,
        outcome: Outcome,
    ) -> Result<(), EstimationError>
    where
        nalgebra::DefaultAllocator: aidnav_estimation::FilterAllocator<Const<STATES>, M>,
    {
        if let Some(m) = self.monitor.as_mut()
            && outcome != Outcome::Rejected
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
    /// feeds nothing back.
    pub fn position_fix_missing(&mut self) -> Result<(), EstimationError> {
        if let Some(a) = self.adaptive.as_mut() {
            a.record_gain(&SMatrix::zeros());
        }
        Ok(())
    }

    /// Sum of every error estimate fed back so far (closed loop): its
    /// position and velocity parts are the corrections the INS has needed,
    /// whose history the outage predictors extrapolate.
    pub fn fed_back(&self) -> &Vector21 {
        &self.fed_back
    }

    /// Interval of the covariance propagation \[s\] (default 0.05; 0: every sample).
    pub fn set_covariance_interval(&mut self, seconds: f64) {
        self.covariance_interval_s = seconds.max(0.0);
    }

    /// GNSS antenna position fix with σ (north, east, down) under a policy.
    pub fn update_position_with<P: MeasurementPolicy<U3> + ?Sized>(
        &mut self,
        fix: &Geodetic,
        sigma_ned: &Vector3<f64>,
        policy: &mut P,
    ) -> Result<GnssUpdate, EstimationError> {
        let s = *self.ins.state();
        let c = s.attitude.matrix();
        // The INS's own antenna: in open loop the estimate x is part of H x.
        let antenna = s.position.offset_by(&(c * self.lever_arm));
        let z = fix.ned_to(&antenna).raw();
        let h = NedErrorModel::position_measurement((c * self.lever_arm).as_raw());
        let r = Matrix3::from_diagonal(&sigma_ned.map(|v| v * v));
        self.flush_covariance()?;
        if let Some(a) = self.adaptive.as_mut() {
            let innovation = self.kf.innovation(&z, &h, &r)?;
            let q = a.process_noise(&innovation.residual, &innovation.s);
            self.kf.set_covariance(self.kf.covariance() + q)?;
        }
        let rec = self.kf.update_with(&z, &h, &r, policy)?;
        if let Some(a) = self.adaptive.as_mut() {
            a.record_gain(&rec.gain);
        }
        self.add_information(&h, &r, rec.outcome)?;
        self.feedback()?;
        Ok(rec)
    }

    /// GNSS antenna position fix, accepted.
    pub fn update_position(
        &mut self,
        fix: &Geodetic,
        sigma_ned: &Vector3<f64>,
    ) -> Result<GnssUpdate, EstimationError> {
        self.update_position_with(fix, sigma_ned, &mut AcceptAll)
    }

    /// GNSS antenna velocity fix (NED) with σ (north, east, down).
    pub fn update_velocity_with<P: MeasurementPolicy<U3> + ?Sized>(
        &mut self,
        velocity_ned: &Vec3<Ned>,
        sigma_ned: &Vector3<f64>,
        policy: &mut P,
    ) -> Result<GnssUpdate, EstimationError> {
        let s = *self.ins.state();
        let c = s.attitude.matrix();
        let v_ant = s.velocity + c * self.rate.cross(&self.lever_arm);
        let z = (v_ant - *velocity_ned).raw();
        let h =
            NedErrorModel::velocity_measurement((c * self.rate.cross(&self.lever_arm)).as_raw());
        let r = Matrix3::from_diagonal(&sigma_ned.map(|v| v * v));
        self.flush_covariance()?;
        let rec = self.kf.update_with(&z, &h, &r, policy)?;
        self.add_information(&h, &r, rec.outcome)?;
        self.feedback()?;
        Ok(rec)
    }

    /// Non-holonomic constraint: zero lateral and vertical body velocity
    /// with σ `sigma_mps` (a land vehicle on its wheels).
    pub fn update_non_holonomic(&mut self, sigma_mps: f64) -> Result<(), EstimationError> {
        self.flush_covariance()?;
        let s = *self.ins.state();
        let c = s.attitude.matrix();
        let body = c.transpose() * s.velocity;
        let z = nalgebra::Vector2::new(body.y(), body.z());
        let h = NedErrorModel::non_holonomic_measurement(c.as_raw(), s.velocity.as_raw());
        let r = nalgebra::Matrix2::identity() * (sigma_mps * sigma_mps);
        self.kf.update(&z, &h, &r)?;
        self.add_information(&h, &r, Outcome::Accepted)?;
        self.feedback()
    }

    /// Zero-velocity update at a standstill: the IMU's velocity is zero,
    /// σ `sigma_mps` per axis.
    pub fn update_zero_velocity(&mut self, sigma_mps: f64) -> Result<(), EstimationError> {
        self.flush_covariance()?;
        let z = self.ins.state().velocity.raw();
        let mut h = SMatrix::<f64, 3, STATES>::zeros();
        h.fixed_view_mut::<3, 3>(0, VELOCITY)
            .copy_from(&Matrix3::identity());
        let r = Matrix3::identity() * (sigma_mps * sigma_mps);
        self.kf.update(&z, &h, &r)?;
        self.add_information(&h, &r, Outcome::Accepted)?;
        self.feedback()
    }

    /// Zero-angular-rate update at a standstill: the body turns with the
    /// Earth only, so the corrected mean gyro output of the window
    /// (`mean_raw_rate`, raw body-frame rates averaged over the standstill)
    /// less the Earth rate in the body frame is the remaining gyro bias
    /// error; σ per axis `sigma_rad_s` (the window's noise of the mean).
    pub fn update_zero_angular_rate(
        &mut self,
        mean_raw_rate: &Vector3<f64>,
        sigma_rad_s: &Vector3<f64>,
    ) -> Result<(), EstimationError> {
        self.flush_covariance()?;
        let s = *self.ins.state();
        let one = Vector3::repeat(1.0);
        let corrected = (mean_raw_rate - self.instruments.gyro_bias)
            .component_div(&(one + self.instruments.gyro_scale));
        let earth_body = s.attitude.matrix().transpose() * earth_rate_ned(s.position.latitude_rad);
        let z = corrected - earth_body.raw();
        // ω = (ω̃ − b)/(1 + s): ∂ω/∂b = −1/(1 + s); the error state is the
        // excess of the corrected rate, fed back as b += δb.
        let mut h = SMatrix::<f64, 3, STATES>::zeros();
        h.fixed_view_mut::<3, 3>(0, GYRO_BIAS)
            .copy_from(&Matrix3::from_diagonal(
                &(one + self.instruments.gyro_scale).map(|v| 1.0 / v),
            ));
        let r = Matrix3::from_diagonal(&sigma_rad_s.map(|v| v * v));
        self.kf.update(&z, &h, &r)?;
        self.add_information(&h, &r, Outcome::Accepted)?;
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
        let (p, state) = (*self.kf.covariance(), *self.ins.state());
        if let Some(r) = self.record.as_mut()
            && !r.overflow
            && let (Some(e), Some(st)) = (r.epochs.last_mut(), r.states.last_mut())
        {
            // Errors relative to the post-feedback nominal: the prediction
            // sat the feedback δ away from it.
            e.x_predicted -= x;
            e.p_filtered = p;
            *st = state;
        }
        self.kf.set_state(Vector21::zeros())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_models::ned_ins::ImuNoise;

    /// Prior σ: position, velocity, tilt, heading as given, instruments from
    /// the model's noise terms.
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
        let start = NedState {
            position: Geodetic {
                latitude_rad: 0.7,
                longitude_rad: -1.8,
                height_m: 1600.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(0.0, 0.0, 0.5),
        };
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
                gap.push((f.recorded_epoch().unwrap(), drift));
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

    /// At a standstill without GNSS: zero-velocity updates hold the velocity
    /// and position, zero-angular-rate updates find a gyro bias that the
    /// levelled, static INS otherwise only sees through slow tilt drift.
    #[test]
    fn standstill_updates_hold_the_ins_and_find_the_gyro_bias() {
        let start = NedState {
            position: Geodetic {
                latitude_rad: 0.7,
                longitude_rad: -1.8,
                height_m: 1600.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(0.01, -0.02, 0.5),
        };
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

    #[test]
    fn static_alignment_finds_the_vertical_accelerometer_bias() {
        let start = NedState {
            position: Geodetic {
                latitude_rad: 0.7,
                longitude_rad: -1.8,
                height_m: 1600.0,
            },
            velocity: Vec3::zeros(),
            attitude: Rotation::from_euler_angles(0.01, -0.02, 0.5),
        };
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
