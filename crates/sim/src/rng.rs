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
