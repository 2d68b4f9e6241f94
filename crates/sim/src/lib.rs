//! # aidnav-sim — simulation
//!
//! Seeded random streams whose output does not depend on the number of
//! threads ([`rng`]), a parallel Monte Carlo runner with a progress bar
//! ([`monte_carlo`]), truth and measurement simulation of linear Gaussian
//! models ([`linear`]), measurement faults and outages ([`faults`]) and launch trajectories
//! ([`trajectory`]). The experiments built on them live in `aidnav-reproduce`.
//!
//! ```
//! use aidnav_sim::{MonteCarlo, rng::RngExt};
//! // The mean of 1000 seeded uniform draws, one per run, in parallel.
//! let mc = MonteCarlo::new(1000, 42).quiet();
//! let draws: Vec<f64> = mc.run(|_run, rng| rng.random::<f64>());
//! let mean = draws.iter().sum::<f64>() / draws.len() as f64;
//! assert!((mean - 0.5).abs() < 0.05);
//! // Same seed, same draws, whatever the thread count.
//! assert_eq!(draws, mc.run(|_run, rng| rng.random::<f64>()));
//! ```

pub mod faults;
pub mod linear;
pub mod monte_carlo;
pub mod rng;
pub mod trajectory;

pub use monte_carlo::{Cancel, Cancelled, MonteCarlo, Progress};
pub use rng::{RunRng, run_rng};
