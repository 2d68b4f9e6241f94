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
