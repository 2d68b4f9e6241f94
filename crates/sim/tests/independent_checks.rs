//! Checks of the simulator against quantities computed independently:
//! closed-form kinematics, the Allan deviation of the error processes and
//! the exact form of the deterministic IMU errors.

use aidnav_frames::earth::Geodetic;
use aidnav_frames::{Body, Ned, Rotation, Vec3};
use aidnav_sim::imu::{ImuSpec, simulate_imu};
use aidnav_sim::truth::TruthSample;

/// FNV-1a over the bit patterns (stable across Rust versions, unlike
/// `DefaultHasher`).
fn fnv(values: impl IntoIterator<Item = f64>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

/// A hand-made moving truth (no route generator involved) at `rate_hz` for
/// `duration_s`, sinusoidal rates and forces, fixed position.
fn synthetic_truth(rate_hz: f64, duration_s: f64) -> Vec<TruthSample> {
    let n = (duration_s * rate_hz) as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 / rate_hz;
            TruthSample {
                time_s: 1.7e9 + t,
                position: Geodetic {
                    latitude_rad: 0.5,
                    longitude_rad: 2.0,
                    height_m: 30.0,
                },
                velocity_ned: Vec3::<Ned>::new(0.0, 0.0, 0.0),
                attitude: Rotation::<Body, Ned>::from_euler_angles(0.0, 0.0, 0.3),
                angular_rate_body: Vec3::<Body>::new(
                    0.1 * (0.7 * t).sin(),
                    0.05 * (1.3 * t).cos(),
                    0.2 * (0.2 * t).sin(),
                ),
                specific_force_body: Vec3::<Body>::new(
                    1.5 * (0.4 * t).sin(),
                    0.8 * (0.9 * t).cos(),
                    -9.8 + 0.3 * (2.1 * t).sin(),
                ),
                speed_mps: 0.0,
                distance_m: 0.0,
            }
        })
        .collect()
}

/// The default IMU's output on a fixed truth is pinned bit for bit: every
/// error term added since defaults to off and draws from new streams only.
#[test]
fn default_imu_output_is_unchanged() {
    let truth = synthetic_truth(100.0, 60.0);
    let (imu, draw) = simulate_imu(&ImuSpec::default(), &truth, 42, 3).unwrap();
    assert_eq!(imu.len(), truth.len());
    let h = fnv(imu.iter().flat_map(|s| {
        std::iter::once(s.time_s)
            .chain(s.specific_force.iter().copied())
            .chain(s.angular_rate.iter().copied())
    }));
    let d = fnv(draw
        .gyro_bias_rad_s
        .iter()
        .chain(draw.gyro_scale_factor.iter())
        .chain(draw.accel_bias_m_s2.iter())
        .chain(draw.accel_scale_factor.iter())
        .copied());
    eprintln!("default IMU fingerprint {h:#018x}, draw {d:#018x}");
    assert_eq!((h, d), (0x484a_866f_4b9c_8ca1, 0x4519_02e6_6051_a602));
}

// ---------------------------------------------------------------------
// Independent physics: WGS-84 and normal gravity written out here from
// the textbook formulas (NIMA TR8350.2), not taken from the crates.

const A: f64 = 6_378_137.0;
const F: f64 = 1.0 / 298.257_223_563;
const OMEGA: f64 = 7.292_115e-5;
const GM: f64 = 3.986_004_418e14;
const GAMMA_E: f64 = 9.780_325_335_9;
const GAMMA_P: f64 = 9.832_184_937_8;

/// Meridian and prime-vertical radii of curvature \[m\].
fn radii(lat: f64) -> (f64, f64) {
    let e2 = F * (2.0 - F);
    let w2 = 1.0 - e2 * lat.sin().powi(2);
    (A * (1.0 - e2) / w2.powf(1.5), A / w2.sqrt())
}

/// Somigliana normal gravity with the second-order free-air correction.
fn gravity(lat: f64, h: f64) -> f64 {
    let (e2, b) = (F * (2.0 - F), A * (1.0 - F));
    let k = (b * GAMMA_P - A * GAMMA_E) / (A * GAMMA_E);
    let s2 = lat.sin().powi(2);
    let g0 = GAMMA_E * (1.0 + k * s2) / (1.0 - e2 * s2).sqrt();
    let m = OMEGA * OMEGA * A * A * b / GM;
    g0 * (1.0 - 2.0 / A * (1.0 + F + m - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))
}

type V = nalgebra::Vector3<f64>;
type M3 = nalgebra::Matrix3<f64>;

/// Body → NED for roll 0, pitch θ, yaw ψ: R_z(ψ) R_y(θ).
fn c_nb(theta: f64, psi: f64) -> M3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    M3::new(cp, -sp, 0.0, sp, cp, 0.0, 0.0, 0.0, 1.0)
        * M3::new(ct, 0.0, st, 0.0, 1.0, 0.0, -st, 0.0, ct)
}

/// Specific force and angular rate in body axes of a car at latitude
/// `lat`, height `h`, pitch θ, heading ψ, speed s (constant), yaw rate
/// ψ̇ and pitch rate θ̇ (roll 0, velocity along body x):
/// `f_n = v̇_n − g_n + (2 ω_ie + ω_en) × v_n`,
/// `ω_ib^b = (−ψ̇ sin θ, θ̇, ψ̇ cos θ) + C_bn (ω_ie + ω_en)`.
fn expected_imu(
    lat: f64,
    h: f64,
    theta: f64,
    psi: f64,
    s: f64,
    psi_dot: f64,
    theta_dot: f64,
) -> (V, V) {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    let v = s * V::new(ct * cp, ct * sp, -st);
    // v̇ = s (θ̇ ∂u/∂θ + ψ̇ ∂u/∂ψ) at constant speed.
    let a = s
        * (theta_dot * V::new(-st * cp, -st * sp, -ct) + psi_dot * V::new(-ct * sp, ct * cp, 0.0));
    let (rm, rn) = radii(lat);
    let w_ie = OMEGA * V::new(lat.cos(), 0.0, -lat.sin());
    let w_en = V::new(v.y / (rn + h), -v.x / (rm + h), -v.y * lat.tan() / (rn + h));
    let f_n = a - V::new(0.0, 0.0, gravity(lat, h)) + (2.0 * w_ie + w_en).cross(&v);
    let c_bn = c_nb(theta, psi).transpose();
    let w_nb = V::new(-psi_dot * st, theta_dot, psi_dot * ct);
    (c_bn * f_n, w_nb + c_bn * (w_ie + w_en))
}

/// A full circle at 10 m/s and 10 °/s (radius 57.3 m, 1.75 m/s² of
/// centripetal acceleration) at 45° N: on the constant-rate part of the
/// turn the truth's specific force and angular rate equal the closed
/// form, the heading grows linearly and the positions differentiate to
/// the velocity.
#[test]
fn constant_rate_circle_matches_the_closed_form() {
    use aidnav_sim::ground::{CarRoute, Segment, drive};
    let (s, rate_deg_s, rise) = (10.0, 10.0_f64, 1.5);
    let route = CarRoute {
        start_latitude_deg: 45.0,
        start_longitude_deg: 7.0,
        start_height_m: 300.0,
        start_heading_deg: 0.0,
        accel_rise_s: 1.0,
        yaw_rate_rise_s: rise,
        segments: vec![
            Segment::Accelerate {
                speed_mps: s,
                accel_mps2: 2.0,
            },
            Segment::Cruise { duration_s: 5.0 },
            Segment::Turn {
                angle_deg: 360.0,
                rate_deg_s,
            },
            Segment::Cruise { duration_s: 5.0 },
        ],
        hills: vec![],
        ..CarRoute::default()
    };
    let rate_hz = 100.0;
    let truth = drive(&route, rate_hz, 0.0).unwrap();
    let r = rate_deg_s.to_radians();
    // Speed pulse: 10 / 2 + 1 = 6 s; the turn starts at 11 s, its yaw
    // rate holds r from 11 + rise to 11 + 36 s; heading there
    // r (t − 11 − rise/2).
    let turn_start = 6.0 + 5.0;
    let (mut f_err, mut w_err, mut psi_err, mut v_err) = (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
    let mut checked = 0;
    for k in 1..truth.len() - 1 {
        let t = &truth[k];
        let tau = t.time_s - turn_start;
        if !(rise + 0.1..36.0 - 0.1).contains(&tau) {
            continue;
        }
        checked += 1;
        let psi = r * (tau - 0.5 * rise);
        let (_, pitch, yaw) = t.attitude.euler_angles();
        let dpsi = (yaw - psi + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        psi_err = psi_err.max(dpsi.abs()).max(pitch.abs());
        let p = &t.position;
        let (f, w) = expected_imu(p.latitude_rad, p.height_m, 0.0, psi, s, r, 0.0);
        f_err = f_err.max((t.specific_force_body.raw() - f).norm());
        w_err = w_err.max((t.angular_rate_body.raw() - w).norm());
        // Central difference of the integrated positions.
        let d = truth[k - 1].position.ned_to(&truth[k + 1].position).raw() * (rate_hz / 2.0);
        v_err = v_err.max((d - t.velocity_ned.raw()).norm());
    }
    eprintln!(
        "circle: {checked} samples, |Δf| ≤ {f_err:.2e} m/s², |Δω| ≤ {w_err:.2e} rad/s, \
         heading ≤ {psi_err:.2e} rad, position-derived velocity ≤ {v_err:.2e} m/s"
    );
    assert!(checked > 3000);
    assert!(f_err < 1e-6, "{f_err}");
    assert!(w_err < 1e-9, "{w_err}");
    assert!(psi_err < 1e-9, "{psi_err}");
    // Central difference truncation s r² Δt²/6 ≈ 5e-6 m/s.
    assert!(v_err < 1e-5, "{v_err}");
}

/// A long hill (5°, 2 km) at a constant 15 m/s: everywhere on it the
/// truth's specific force and angular rate equal the closed form of the
/// documented grade profile θ(d) = θ_max sin³(2π ξ); at the top grade
/// (ξ = 1/4, θ̇ = 0) the specific force is gravity's (g sin θ, 0,
/// −g cos θ) plus the Earth-rate terms.
#[test]
fn constant_speed_hill_matches_the_closed_form() {
    use aidnav_sim::ground::{CarRoute, Hill, Segment, drive};
    let (s, start, length, max_deg) = (15.0, 200.0, 2000.0, 5.0_f64);
    let psi = 60f64.to_radians();
    let route = CarRoute {
        start_latitude_deg: -20.0,
        start_longitude_deg: 30.0,
        start_height_m: 1000.0,
        start_heading_deg: psi.to_degrees(),
        segments: vec![
            Segment::Accelerate {
                speed_mps: s,
                accel_mps2: 2.0,
            },
            Segment::Cruise { duration_s: 160.0 },
        ],
        hills: vec![Hill {
            start_m: start,
            length_m: length,
            max_pitch_deg: max_deg,
            shape: aidnav_sim::ground::HillShape::Bump,
        }],
        ..CarRoute::default()
    };
    let truth = drive(&route, 100.0, 0.0).unwrap();
    let peak = max_deg.to_radians();
    let grade = |d: f64| {
        let (sn, cs) = (std::f64::consts::TAU * (d - start) / length).sin_cos();
        (
            peak * sn.powi(3),
            peak * 3.0 * sn * sn * cs * std::f64::consts::TAU / length,
        )
    };
    let (mut f_err, mut w_err, mut pitch_err) = (0.0_f64, 0.0_f64, 0.0_f64);
    let mut checked = 0;
    let top = start + 0.25 * length;
    let mut nearest_top = (f64::INFINITY, 0);
    for (k, t) in truth.iter().enumerate() {
        if !(start..start + length).contains(&t.distance_m) || t.time_s < 8.6 {
            continue;
        }
        checked += 1;
        let (theta, dtheta_dd) = grade(t.distance_m);
        let (_, pitch, _) = t.attitude.euler_angles();
        pitch_err = pitch_err.max((pitch - theta).abs());
        let p = &t.position;
        let (f, w) = expected_imu(
            p.latitude_rad,
            p.height_m,
            theta,
            psi,
            s,
            0.0,
            s * dtheta_dd,
        );
        f_err = f_err.max((t.specific_force_body.raw() - f).norm());
        w_err = w_err.max((t.angular_rate_body.raw() - w).norm());
        if (t.distance_m - top).abs() < nearest_top.0 {
            nearest_top = ((t.distance_m - top).abs(), k);
        }
    }
    let t = &truth[nearest_top.1];
    let g = gravity(t.position.latitude_rad, t.position.height_m);
    let gravity_only = V::new(g * peak.sin(), 0.0, -g * peak.cos());
    let earth_terms = (t.specific_force_body.raw() - gravity_only).norm();
    eprintln!(
        "hill: {checked} samples, |Δf| ≤ {f_err:.2e} m/s², |Δω| ≤ {w_err:.2e} rad/s, \
         pitch ≤ {pitch_err:.2e} rad; at the top grade ({:.3} m off ξ = 1/4) f − g(sin θ, 0, −cos θ) = {earth_terms:.2e} m/s²",
        nearest_top.0
    );
    assert!(checked > 10_000);
    assert!(f_err < 1e-6, "{f_err}");
    assert!(w_err < 1e-9, "{w_err}");
    assert!(pitch_err < 1e-12, "{pitch_err}");
    // Coriolis 2 Ω s ≈ 2.2e-3 m/s² plus the curvature s² θ' of the
    // nearest sample (< 1e-4 m/s²).
    assert!(earth_terms < 2.0 * OMEGA * s + 1e-4, "{earth_terms}");
}

// ---------------------------------------------------------------------
// Statistics of the error processes on a static truth.

use aidnav_sensors::ImuSample;
use aidnav_sim::allan::{allan_deviation, gauss_markov_adev};
use aidnav_sim::imu::{ImuOutput, VibrationLine};

/// A car standing still at 0.5 rad latitude, heading north, for
/// `duration_s` at `rate_hz`: gravity up on the accelerometers, Earth rate
/// on the gyros.
fn static_truth(rate_hz: f64, duration_s: f64) -> Vec<TruthSample> {
    let lat: f64 = 0.5;
    let n = (duration_s * rate_hz).round() as usize;
    let f = Vec3::<Body>::new(0.0, 0.0, -gravity(lat, 30.0));
    let w = Vec3::<Body>::new(OMEGA * lat.cos(), 0.0, -OMEGA * lat.sin());
    (0..n)
        .map(|k| TruthSample {
            time_s: 1.7e9 + k as f64 / rate_hz,
            position: Geodetic {
                latitude_rad: lat,
                longitude_rad: 2.0,
                height_m: 30.0,
            },
            velocity_ned: Vec3::<Ned>::new(0.0, 0.0, 0.0),
            attitude: Rotation::<Body, Ned>::from_euler_angles(0.0, 0.0, 0.0),
            angular_rate_body: w,
            specific_force_body: f,
            speed_mps: 0.0,
            distance_m: 0.0,
        })
        .collect()
}

/// Per axis, (gyro error, accel error) series: output − truth.
fn errors(imu: &[ImuSample], truth: &[TruthSample]) -> ([Vec<f64>; 3], [Vec<f64>; 3]) {
    let g = std::array::from_fn(|i| {
        imu.iter()
            .zip(truth)
            .map(|(m, t)| m.angular_rate[i] - t.angular_rate_body.raw()[i])
            .collect()
    });
    let a = std::array::from_fn(|i| {
        imu.iter()
            .zip(truth)
            .map(|(m, t)| m.specific_force[i] - t.specific_force_body.raw()[i])
            .collect()
    });
    (g, a)
}

/// Relative 1σ error of an Allan deviation estimate at τ from data of
/// duration L: ≈ 1/√(2 (L/τ − 1)) (non-overlapping estimator of white
/// noise; the overlapping one is better).
fn adev_relative_sigma(length_s: f64, tau_s: f64) -> f64 {
    1.0 / (2.0 * (length_s / tau_s - 1.0)).sqrt()
}

/// White noise alone: the Allan deviation of the gyro and accelerometer
/// errors falls as N/√τ, at τ = 1 s the datasheet ARW / VRW converted to
/// rad/√s and m/s/√s.
#[test]
fn white_noise_allan_deviation_is_the_random_walk_coefficient() {
    let (rate, length) = (100.0, 1800.0);
    let truth = static_truth(rate, length);
    let mut spec = ImuSpec::ideal(rate);
    spec.gyro.angle_random_walk_deg_sqrt_h = [0.2, 0.3, 0.5];
    spec.accel.velocity_random_walk_m_s_sqrt_h = [0.05, 0.1, 0.02];
    let (imu, _) = simulate_imu(&spec, &truth, 21, 0).unwrap();
    let (g, a) = errors(&imu, &truth);
    let taus = [0.1, 1.0, 10.0];
    let mut worst = 0.0_f64;
    for i in 0..3 {
        let n_gyro = spec.gyro.angle_random_walk_deg_sqrt_h[i].to_radians() / 60.0;
        let n_accel = spec.accel.velocity_random_walk_m_s_sqrt_h[i] / 60.0;
        for (series, n, what) in [(&g[i], n_gyro, "gyro"), (&a[i], n_accel, "accel")] {
            let adev = allan_deviation(series, 1.0 / rate, &taus);
            for (tau, s) in taus.iter().zip(&adev) {
                let expect = n / tau.sqrt();
                let rel = s / expect - 1.0;
                let tol = 4.0 * adev_relative_sigma(length, *tau);
                eprintln!(
                    "{what}[{i}] τ {tau:>4} s: ADEV {s:.4e}, N/√τ {expect:.4e}, {rel:+.4} (tol {tol:.3})"
                );
                assert!(rel.abs() < tol, "{what}[{i}] τ {tau}: {s} vs {expect}");
                worst = worst.max(rel.abs());
            }
        }
    }
    eprintln!("white noise: worst relative ADEV error {worst:.4}");
}

/// A Gauss–Markov bias alone (σ 3 °/h / 0.05 mg, τ_c 10 s, 10 Hz for
/// 6 h): the Allan deviation at τ = τ_c, 2 τ_c and 10 τ_c is the closed
/// form of the first-order Gauss–Markov process.
#[test]
fn gauss_markov_allan_deviation_is_the_closed_form() {
    let (rate, length, tau_c) = (10.0, 21_600.0, 10.0);
    let truth = static_truth(rate, length);
    let mut spec = ImuSpec::ideal(rate);
    spec.gyro.bias_instability_deg_h = [3.0; 3];
    spec.gyro.bias_correlation_time_s = [tau_c; 3];
    spec.accel.bias_instability_mg = [0.05; 3];
    spec.accel.bias_correlation_time_s = [tau_c; 3];
    let (imu, _) = simulate_imu(&spec, &truth, 22, 0).unwrap();
    let (g, a) = errors(&imu, &truth);
    let taus = [tau_c, 2.0 * tau_c, 10.0 * tau_c];
    let gyro_sigma = 3f64.to_radians() / 3600.0;
    let accel_sigma = 0.05e-3 * 9.806_65;
    let mut worst = 0.0_f64;
    for i in 0..3 {
        for (series, sigma, what) in [(&g[i], gyro_sigma, "gyro"), (&a[i], accel_sigma, "accel")] {
            let adev = allan_deviation(series, 1.0 / rate, &taus);
            for (tau, s) in taus.iter().zip(&adev) {
                let expect = gauss_markov_adev(sigma, tau_c, *tau);
                let rel = s / expect - 1.0;
                // Correlated data: fewer degrees of freedom than white
                // noise near τ_c; 5σ of the white-noise bound.
                let tol = 5.0 * adev_relative_sigma(length, *tau);
                eprintln!(
                    "GM {what}[{i}] τ {tau:>4} s: ADEV {s:.4e}, closed form {expect:.4e}, {rel:+.4} (tol {tol:.3})"
                );
                assert!(rel.abs() < tol, "{what}[{i}] τ {tau}: {s} vs {expect}");
                worst = worst.max(rel.abs());
            }
        }
    }
    eprintln!("Gauss–Markov: worst relative ADEV error {worst:.4}");
}

/// Quantisation and saturation alone: every output is a multiple of the
/// LSB, within LSB/2 of the truth, and clipped at the range.
#[test]
fn quantised_outputs_are_multiples_of_the_lsb_and_clipped() {
    let truth = synthetic_truth(100.0, 60.0);
    let mut spec = ImuSpec::ideal(100.0);
    spec.gyro.quantisation_lsb_rad_s = 1e-3;
    spec.accel.quantisation_lsb_m_s2 = 2.4e-3;
    spec.accel.range_g = 0.5; // 4.9 m/s²: clips the z axis (−9.8 ± 0.3)
    let (imu, _) = simulate_imu(&spec, &truth, 23, 0).unwrap();
    let range = (0.5 * 9.806_65 / 2.4e-3_f64).floor() * 2.4e-3;
    let (mut worst_multiple, mut worst_error, mut clipped) = (0.0_f64, 0.0_f64, 0);
    for (m, t) in imu.iter().zip(&truth) {
        for (x, lsb, x_true, limit) in (0..3)
            .map(|i| {
                (
                    m.angular_rate[i],
                    1e-3,
                    t.angular_rate_body.raw()[i],
                    f64::INFINITY,
                )
            })
            .chain((0..3).map(|i| {
                (
                    m.specific_force[i],
                    2.4e-3,
                    t.specific_force_body.raw()[i],
                    range,
                )
            }))
        {
            let q = x / lsb;
            worst_multiple = worst_multiple.max((q - q.round()).abs());
            if x_true.abs() > limit {
                clipped += 1;
                assert!((x.abs() - limit).abs() < 1e-12, "{x} {limit}");
            } else {
                worst_error = worst_error.max((x - x_true).abs() / lsb);
            }
        }
    }
    eprintln!(
        "quantisation: |x/LSB − round| ≤ {worst_multiple:.1e}, |x − truth| ≤ {worst_error:.4} LSB, {clipped} clipped"
    );
    assert!(worst_multiple < 1e-9);
    assert!(worst_error <= 0.5 + 1e-9);
    assert_eq!(clipped, truth.len());
}

/// Misalignment and scale factor alone: the output is (I + K + M) t
/// exactly, with the M and K of the draw; over 400 runs the off-diagonal
/// elements have the σ given.
#[test]
fn misalignment_and_scale_factor_are_i_plus_k_plus_m() {
    let truth = synthetic_truth(100.0, 20.0);
    let mut spec = ImuSpec::ideal(100.0);
    spec.gyro.scale_factor_sigma_ppm = [1000.0, 2000.0, 500.0];
    spec.gyro.misalignment_sigma_mrad = 2.0;
    spec.accel.scale_factor_sigma_ppm = [800.0; 3];
    spec.accel.misalignment_sigma_mrad = 1.0;
    let (imu, draw) = simulate_imu(&spec, &truth, 24, 0).unwrap();
    let mut worst = 0.0_f64;
    for (m, t) in imu.iter().zip(&truth) {
        let gm =
            (M3::identity() + M3::from_diagonal(&draw.gyro_scale_factor) + draw.gyro_misalignment)
                * t.angular_rate_body.raw();
        let am = (M3::identity()
            + M3::from_diagonal(&draw.accel_scale_factor)
            + draw.accel_misalignment)
            * t.specific_force_body.raw();
        worst = worst
            .max((m.angular_rate - gm).amax())
            .max((m.specific_force - am).amax());
    }
    for mm in [draw.gyro_misalignment, draw.accel_misalignment] {
        assert!((0..3).all(|i| mm[(i, i)] == 0.0));
        assert!((0..3).all(|i| (0..3).all(|j| i == j || mm[(i, j)] != 0.0)));
    }
    // The σ of the drawn elements.
    let runs = 400;
    let (mut g2, mut a2) = (0.0, 0.0);
    for run in 0..runs {
        let (_, d) = simulate_imu(&spec, &truth[..1], 24, run).unwrap();
        g2 += d.gyro_misalignment.norm_squared();
        a2 += d.accel_misalignment.norm_squared();
    }
    let count = 6.0 * runs as f64;
    let (g_sigma, a_sigma) = ((g2 / count).sqrt() / 2e-3, (a2 / count).sqrt() / 1e-3);
    let tol = 4.0 / (2.0 * count).sqrt();
    eprintln!(
        "misalignment: |m − (I+K+M) t| ≤ {worst:.2e}; drawn σ / given: gyro {g_sigma:.4}, accel {a_sigma:.4} (tol {tol:.3})"
    );
    assert!(worst < 1e-12, "{worst}");
    assert!((g_sigma - 1.0).abs() < tol && (a_sigma - 1.0).abs() < tol);
}

/// Increments: sample k is the trapezoid mean of truth samples k − 1 and
/// k (sample 0 the instantaneous truth), and a vibration line's exact
/// interval mean; in rate mode the line's RMS is A/√2.
#[test]
fn increments_and_vibration() {
    let rate = 100.0;
    let truth = synthetic_truth(rate, 10.0);
    let mut spec = ImuSpec::ideal(rate);
    spec.output = ImuOutput::Increments;
    let (imu, _) = simulate_imu(&spec, &truth, 25, 0).unwrap();
    assert_eq!(imu[0].angular_rate, truth[0].angular_rate_body.raw());
    let mut worst = 0.0_f64;
    for k in 1..truth.len() {
        let w = 0.5 * (truth[k - 1].angular_rate_body.raw() + truth[k].angular_rate_body.raw());
        let f = 0.5 * (truth[k - 1].specific_force_body.raw() + truth[k].specific_force_body.raw());
        worst = worst
            .max((imu[k].angular_rate - w).amax())
            .max((imu[k].specific_force - f).amax());
    }
    assert!(worst < 1e-15, "{worst}");
    // One line at 23 Hz (above nothing: Nyquist 50 Hz), 0.2 m/s² on x,
    // 1.5 deg/s on z; 10 s is 230 whole periods.
    let line = VibrationLine {
        frequency_hz: 23.0,
        accel_amplitude_m_s2: [0.2, 0.0, 0.0],
        gyro_amplitude_deg_s: [0.0, 0.0, 1.5],
    };
    let mut vib = ImuSpec::ideal(rate);
    vib.vibration[1] = line;
    let (imu, _) = simulate_imu(&vib, &truth, 25, 0).unwrap();
    let (g, a) = errors(&imu, &truth);
    let n = (truth.len() - 1) as f64;
    let rms = |x: &[f64]| (x[1..].iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    let (ax, gz) = (rms(&a[0]), rms(&g[2]));
    assert!((ax / (0.2 / 2f64.sqrt()) - 1.0).abs() < 1e-3, "{ax}");
    assert!(
        (gz / (1.5f64.to_radians() / 2f64.sqrt()) - 1.0).abs() < 1e-3,
        "{gz}"
    );
    assert!(rms(&a[1]) == 0.0 && rms(&g[0]) == 0.0);
    // Increments: the interval mean of A sin(ωt + φ) is A sinc(ωΔ/2) times
    // the sine at the interval's middle, so the RMS shrinks by sinc(π f Δ).
    vib.output = ImuOutput::Increments;
    let (imu, _) = simulate_imu(&vib, &truth, 25, 0).unwrap();
    let truth_mean: Vec<TruthSample> = (0..truth.len())
        .map(|k| {
            let mut t = truth[k];
            if k > 0 {
                t.specific_force_body =
                    0.5 * (truth[k - 1].specific_force_body + truth[k].specific_force_body);
                t.angular_rate_body =
                    0.5 * (truth[k - 1].angular_rate_body + truth[k].angular_rate_body);
            }
            t
        })
        .collect();
    let (_, a) = errors(&imu, &truth_mean);
    let x = std::f64::consts::PI * 23.0 / rate;
    let expect = 0.2 / 2f64.sqrt() * x.sin() / x;
    let got = rms(&a[0]);
    eprintln!(
        "vibration: rate RMS {ax:.6} (A/√2 {:.6}), increment RMS {got:.6} (× sinc {expect:.6})",
        0.2 / 2f64.sqrt()
    );
    assert!((got / expect - 1.0).abs() < 1e-3, "{got} {expect}");
}

/// Time-stamp jitter and dropped samples: the stamps scatter by the σ
/// given and stay in order; the fraction dropped is the probability.
#[test]
fn jitter_and_dropped_samples() {
    let rate = 100.0;
    let truth = synthetic_truth(rate, 200.0);
    let mut spec = ImuSpec::ideal(rate);
    spec.time_jitter_sigma_s = 5e-4;
    let (imu, _) = simulate_imu(&spec, &truth, 26, 0).unwrap();
    let n = imu.len() as f64;
    let sigma = (imu
        .iter()
        .zip(&truth)
        .map(|(m, t)| (m.time_s - t.time_s).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    assert!(imu.windows(2).all(|w| w[1].time_s > w[0].time_s));
    // Values are those of the true instant.
    assert!(
        imu.iter()
            .zip(&truth)
            .all(|(m, t)| m.angular_rate == t.angular_rate_body.raw())
    );
    let tol = 4.0 / (2.0 * n).sqrt() + 1e-7 / 5e-4; // + the ulp of 1.7e9 s
    assert!((sigma / 5e-4 - 1.0).abs() < tol, "{sigma}");
    spec.time_jitter_sigma_s = 0.0;
    spec.drop_probability = 0.05;
    let (imu, _) = simulate_imu(&spec, &truth, 26, 0).unwrap();
    let dropped = (truth.len() - imu.len()) as f64 / truth.len() as f64;
    let binomial = (0.05 * 0.95 / truth.len() as f64).sqrt();
    eprintln!(
        "timing: jitter σ {sigma:.4e} s (given 5e-4), dropped {dropped:.4} (given 0.05 ± {binomial:.4})"
    );
    assert!((dropped - 0.05).abs() < 4.0 * binomial);
    // The samples kept are unchanged and in order.
    assert!(
        imu.iter()
            .all(|m| truth.iter().any(|t| t.time_s == m.time_s))
    );
}

/// Every grade validates, the industrial one is the default, and
/// invalid new fields are named in the error.
#[test]
fn grades_and_validation() {
    use aidnav_sim::imu::ImuGrade;
    for g in [
        ImuGrade::Consumer,
        ImuGrade::Industrial,
        ImuGrade::Tactical,
        ImuGrade::Navigation,
    ] {
        ImuSpec::grade(g, 200.0).validate().unwrap();
    }
    assert_eq!(
        ImuSpec::grade(ImuGrade::Industrial, 100.0),
        ImuSpec::default()
    );
    let nav = ImuSpec::grade(ImuGrade::Navigation, 100.0);
    assert_eq!(nav.output, ImuOutput::Increments);
    type Edit = Box<dyn Fn(&mut ImuSpec)>;
    let cases: Vec<(Edit, &str)> = vec![
        (
            Box::new(|s| s.drop_probability = 1.0),
            "imu.drop_probability",
        ),
        (
            Box::new(|s| s.time_jitter_sigma_s = 0.01),
            "imu.time_jitter_sigma_s",
        ),
        (
            Box::new(|s| s.gyro.misalignment_sigma_mrad = -1.0),
            "imu.gyro.misalignment_sigma_mrad",
        ),
        (
            Box::new(|s| s.vibration[2].frequency_hz = f64::NAN),
            "imu.vibration[2].frequency_hz",
        ),
        (
            Box::new(|s| {
                s.accel.quantisation_lsb_m_s2 = 1.0;
                s.accel.range_g = 0.05;
            }),
            "imu.accel.range_g",
        ),
    ];
    for (edit, field) in cases {
        let mut s = ImuSpec::default();
        edit(&mut s);
        let err = s.validate().unwrap_err().to_string();
        assert!(err.contains(field), "{err} / {field}");
    }
}

/// The GNSS position error is the first-order Gauss–Markov process of its
/// specification: over 20 h of 1 Hz fixes (1200 correlation times) its
/// variance is σ² and its autocorrelation e^{−lag/T} at T/2, T and 2T,
/// within 4σ of the estimators (variance ≈ √(4T/T_total) relative,
/// autocorrelation ≈ √(2T/T_total)); the white part alone is
/// uncorrelated from one fix to the next.
#[test]
fn gnss_errors_have_their_specified_size_and_autocorrelation() {
    use aidnav_sim::gnss::{GnssSpec, simulate_gnss};
    let (sigma, tau, hours) = ([0.2, 0.3, 0.5], 60.0, 20.0);
    let total_s = hours * 3600.0;
    let truth = static_truth(1.0, total_s);
    let spec = GnssSpec {
        lever_arm_m: [0.0; 3],
        position_sigma_neu_m: [0.0; 3],
        position_markov_sigma_neu_m: sigma,
        position_markov_time_s: tau,
        ..GnssSpec::default()
    };
    let fixes = simulate_gnss(&spec, &truth, 17, 0).unwrap();
    assert_eq!(fixes.len(), truth.len());
    let error = |fixes: &[aidnav_sensors::GnssFix], axis: usize| -> Vec<f64> {
        fixes
            .iter()
            .zip(&truth)
            .map(|(f, t)| {
                let d = t.position.ned_to(&f.position);
                [d.x(), d.y(), -d.z()][axis]
            })
            .collect()
    };
    let autocorrelation = |e: &[f64], lag: usize| {
        let n = e.len() - lag;
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let var = e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / e.len() as f64;
        (0..n)
            .map(|k| (e[k] - mean) * (e[k + lag] - mean))
            .sum::<f64>()
            / (n as f64 * var)
    };
    let var_tol = 4.0 * (4.0 * tau / total_s).sqrt();
    let acf_tol = 4.0 * (2.0 * tau / total_s).sqrt();
    for (axis, s) in sigma.iter().enumerate() {
        let e = error(&fixes, axis);
        let var = e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64;
        assert!(
            (var / (s * s) - 1.0).abs() < var_tol,
            "axis {axis}: variance {var} against {}",
            s * s
        );
        for lag in [30, 60, 120] {
            let r = autocorrelation(&e, lag);
            let expected = (-(lag as f64) / tau).exp();
            eprintln!("axis {axis} lag {lag} s: {r:.3} (expected {expected:.3})");
            assert!(
                (r - expected).abs() < acf_tol,
                "axis {axis} lag {lag}: {r} against {expected}"
            );
        }
    }
    let white = GnssSpec {
        position_sigma_neu_m: [0.5, 0.5, 1.0],
        position_markov_sigma_neu_m: [0.0; 3],
        ..spec
    };
    let fixes = simulate_gnss(&white, &truth, 17, 0).unwrap();
    let e = error(&fixes, 0);
    let r1 = autocorrelation(&e, 1);
    assert!(
        r1.abs() < 4.0 / (e.len() as f64).sqrt(),
        "white lag-1 correlation {r1}"
    );
}
