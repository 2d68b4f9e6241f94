//! # aidnav-sim — simulation
//!
//! Seeded random streams whose output does not depend on the number of
//! threads ([`rng`]), a parallel Monte Carlo runner with a progress bar
//! ([`monte_carlo`]), truth and measurement simulation of linear Gaussian
//! models ([`linear`]), measurement faults and outages ([`faults`]) and launch trajectories
//! ([`trajectory`]). The experiments built on them live in `aidnav-reproduce`.
//!
//! A land vehicle with known truth ([`car::simulate_car`]): the truth
//! trajectory of a car on WGS-84 ([`ground`], [`truth`]), IMU samples
//! consistent with the NED mechanization of `aidnav-ins` and their errors
//! ([`imu`]), GNSS fixes ([`gnss`]), wheel speed and barometric height
//! ([`aiding`]), the Gauss–Markov processes they share ([`processes`]),
//! each error process seeded from its own stream ([`rng::Stream`]), and the
//! Allan deviation to check their noise against the datasheet ([`allan`]).
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

pub mod aiding;
pub mod allan;
pub mod car;
pub mod error;
pub mod faults;
pub mod gnss;
pub mod ground;
pub mod imu;
pub mod linear;
pub mod monte_carlo;
pub mod processes;
pub mod rng;
pub mod scenario;
pub mod trajectory;
pub mod truth;

pub use car::{CarLog, CarScenario, simulate_car, simulate_car_run};
pub use error::SimError;
pub use monte_carlo::{Cancel, Cancelled, MonteCarlo, Progress};
pub use rng::{RunRng, run_rng};
