//! Seeded random streams.
//!
//! Run k of an experiment with master seed s draws from
//! `ChaCha8Rng::seed_from_u64(s)` switched to stream k: each run has its own
//! independent stream, so a run's numbers depend only on (s, k) — never on
//! which thread ran it or in what order. ChaCha8 is portable across platforms
//! and versions of this crate (unlike `StdRng`).

pub use rand::RngExt;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The generator type of every seeded run.
pub type RunRng = ChaCha8Rng;

/// The generator of run `run` under master seed `seed`.
pub fn run_rng(seed: u64, run: u64) -> RunRng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(run);
    rng
}

/// A generator for one purpose (`channel`) inside run `run`: lets a
/// simulation draw, e.g., sensor noise and fault times from separate streams so
/// that enabling one does not shift the other's numbers.
pub fn channel_rng(seed: u64, run: u64, channel: u64) -> RunRng {
    // splitmix64 finaliser: decorrelates (seed, channel) into a new seed.
    let mut z = seed ^ channel.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    run_rng(z, run)
}

/// The random streams of a vehicle simulation ([`crate::car`]): each error
/// process of each sensor draws from its own generator,
/// `channel_rng(seed, run, stream as u64)`, so enabling, disabling or adding
/// a process leaves every other stream's numbers unchanged. The
/// discriminants are fixed for ever (new streams take new numbers; 1000 up,
/// clear of the small channel numbers experiments pass to [`channel_rng`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Stream {
    /// Gyro turn-on bias, one draw per axis.
    GyroTurnOnBias = 1000,
    /// Gyro scale-factor error, one draw per axis.
    GyroScaleFactor = 1001,
    /// Gyro bias instability (Gauss–Markov), per sample and axis.
    GyroBiasInstability = 1002,
    /// Gyro white noise (angle random walk), per sample and axis.
    GyroNoise = 1003,
    /// Accelerometer turn-on bias, one draw per axis.
    AccelTurnOnBias = 1004,
    /// Accelerometer scale-factor error, one draw per axis.
    AccelScaleFactor = 1005,
    /// Accelerometer bias instability (Gauss–Markov), per sample and axis.
    AccelBiasInstability = 1006,
    /// Accelerometer white noise (velocity random walk), per sample and axis.
    AccelNoise = 1007,
    /// GNSS position white noise, per epoch and axis (N, E, U).
    GnssPositionNoise = 1008,
    /// GNSS position Gauss–Markov error, per epoch and axis (N, E, U).
    GnssPositionMarkov = 1009,
    /// GNSS velocity white noise, per epoch and axis (N, E, U).
    GnssVelocityNoise = 1010,
    /// Wheel-speed white noise, per sample.
    WheelSpeedNoise = 1011,
    /// Barometer Gauss–Markov drift, per sample.
    BaroDrift = 1012,
    /// Barometer white noise, per sample.
    BaroNoise = 1013,
    /// GNSS multipath jumps: a start test and an offset per epoch.
    GnssMultipath = 1014,
    /// GNSS outliers: a test and an error per epoch.
    GnssOutliers = 1015,
    /// Gyro axis misalignment / non-orthogonality, six off-diagonal
    /// draws per run (row-major).
    GyroMisalignment = 1030,
    /// Accelerometer axis misalignment / non-orthogonality, six
    /// off-diagonal draws per run (row-major).
    AccelMisalignment = 1031,
    /// IMU vibration-line phases, per run: for each line, three
    /// accelerometer then three gyro phases.
    ImuVibrationPhase = 1032,
    /// IMU time-stamp jitter, one draw per sample.
    ImuTimeJitter = 1033,
    /// IMU dropped samples, one uniform draw per sample.
    ImuDropout = 1034,
}

impl Stream {
    /// This stream's generator in run `run` under master seed `seed`.
    pub fn rng(self, seed: u64, run: u64) -> RunRng {
        channel_rng(seed, run, self as u64)
    }
}

/// One standard normal draw.
pub fn standard_normal<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    StandardNormal.sample(rng)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_differ_and_repeat() {
        let a: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(run_rng(1, 0), |r, _| Some(r.random()))
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(run_rng(1, 0), |r, _| Some(r.random()))
            .collect();
        let c: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(run_rng(1, 1), |r, _| Some(r.random()))
            .collect();
        let d: Vec<u64> = (0..4)
            .map(|_| 0)
            .scan(channel_rng(1, 0, 1), |r, _| Some(r.random()))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert_ne!(a, d);
    }
}
