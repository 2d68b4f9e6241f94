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
