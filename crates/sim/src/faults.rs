//! Measurement faults and outages for simulation (spec 20): single outliers,
//! short and long bursts, a random anomaly rate, bursts right after an outage
//! ends, and outages of given start and length. Everything is drawn from the
//! generator the caller passes, so a plan depends only on (seed, run).
//!
//! A [`FaultPlan`] is per epoch: an additive error (0 where clean) and whether
//! the measurement is lost to an outage.

use rand::Rng;
use rand::RngExt;
use serde::{Deserialize, Serialize};

/// A magnitude range in units of the measurement noise σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SigmaRange {
    /// Smallest |error| / σ.
    pub min: f64,
    /// Largest |error| / σ.
    pub max: f64,
}

/// One kind of fault; several combine in a plan.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum FaultSpec {
    /// `count` single-epoch outliers at random epochs, random sign.
    SingleOutliers {
        /// Number of outliers.
        count: usize,
        /// Magnitude range.
        magnitude: SigmaRange,
    },
    /// `count` bursts of `min_length..=max_length` consecutive anomalous
    /// epochs at random places (short: 2–20, long: 50–300); one sign per burst.
    Bursts {
        /// Number of bursts.
        count: usize,
        /// Shortest burst \[epochs\].
        min_length: usize,
        /// Longest burst \[epochs\].
        max_length: usize,
        /// Magnitude range.
        magnitude: SigmaRange,
    },
    /// Every epoch is anomalous with probability `rate` (10–30 % in jamming).
    RandomRate {
        /// Probability per epoch, in [0, 1].
        rate: f64,
        /// Magnitude range.
        magnitude: SigmaRange,
    },
    /// An anomaly of `sigmas` · σ (signed) on `length` epochs from `start`:
    /// a fault placed by hand (illustrations, tests).
    Fixed {
        /// First anomalous epoch.
        start: usize,
        /// Number of anomalous epochs.
        length: usize,
        /// Signed magnitude in units of σ.
        sigmas: f64,
    },
    /// A burst of `length` epochs starting right after each outage ends.
    AfterOutage {
        /// Burst length \[epochs\].
        length: usize,
        /// Magnitude range.
        magnitude: SigmaRange,
    },
}

/// A GNSS outage: no measurement for `length` epochs from `start`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Outage {
    /// First epoch without a measurement.
    pub start: usize,
    /// Number of epochs without one.
    pub length: usize,
}

/// A fault spec out of its allowed range: which field, its value, and what
/// is allowed. Scenario owners map it into their own validation error.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{key} = {value}: allowed {allowed}")]
pub struct InvalidFault {
    /// The offending field of the spec (`rate`, `magnitude`, …).
    pub key: &'static str,
    /// The offending value, as text.
    pub value: String,
    /// The allowed range, as text.
    pub allowed: &'static str,
}

impl InvalidFault {
    fn new(key: &'static str, value: impl std::fmt::Display, allowed: &'static str) -> Self {
        Self {
            key,
            value: value.to_string(),
            allowed,
        }
    }
}

/// Per-epoch faults of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct FaultPlan {
    /// Additive measurement error per epoch (0 when clean).
    pub error: Vec<f64>,
    /// Whether the epoch's measurement is lost to an outage.
    pub lost: Vec<bool>,
}

/// Upper bound of every count, length and start epoch of a fault spec: the
/// longest run a scenario allows (10⁶ epochs). A larger count would only
/// spin the planner (`count` draws per run) without adding anything.
pub const MAX_FAULT_EPOCHS: usize = 1_000_000;
/// Upper bound of a fault magnitude in units of σ (10⁶ σ is already far
/// beyond any gate; larger values only risk overflow in squared terms).
pub const MAX_FAULT_SIGMAS: f64 = 1e6;

impl FaultSpec {
    /// Range checks (a scenario file's `[[faults]]` entry): counts, lengths
    /// and starts at most [`MAX_FAULT_EPOCHS`], magnitudes at most
    /// [`MAX_FAULT_SIGMAS`].
    pub fn validate(&self) -> Result<(), InvalidFault> {
        const EPOCHS: &str = "0 … 1000000";
        let counts: &[(&'static str, usize)] = match *self {
            FaultSpec::SingleOutliers { count, .. } => &[("count", count)],
            FaultSpec::Bursts {
                count,
                min_length,
                max_length,
                ..
            } => &[
                ("count", count),
                ("min_length", min_length),
                ("max_length", max_length),
            ],
            FaultSpec::RandomRate { .. } => &[],
            FaultSpec::Fixed { start, length, .. } => &[("start", start), ("length", length)],
            FaultSpec::AfterOutage { length, .. } => &[("length", length)],
        };
        if let Some(&(key, value)) = counts.iter().find(|(_, v)| *v > MAX_FAULT_EPOCHS) {
            return Err(InvalidFault::new(key, value, EPOCHS));
        }
        let magnitude = match *self {
            FaultSpec::SingleOutliers { magnitude, .. }
            | FaultSpec::Bursts { magnitude, .. }
            | FaultSpec::RandomRate { magnitude, .. }
            | FaultSpec::AfterOutage { magnitude, .. } => Some(magnitude),
            FaultSpec::Fixed { sigmas, .. } => {
                if !sigmas.is_finite() || sigmas.abs() > MAX_FAULT_SIGMAS {
                    return Err(InvalidFault::new("sigmas", sigmas, "-1e6 … 1e6"));
                }
                None
            }
        };
        if let Some(m) = magnitude
            && !(m.min >= 0.0 && m.max >= m.min && m.max <= MAX_FAULT_SIGMAS)
        {
            return Err(InvalidFault::new(
                "magnitude",
                format!("{}..{}", m.min, m.max),
                "0 ≤ min ≤ max ≤ 1e6",
            ));
        }
        if let FaultSpec::RandomRate { rate, .. } = *self
            && !(0.0..=1.0).contains(&rate)
        {
            return Err(InvalidFault::new("rate", rate, "0 ≤ rate ≤ 1"));
        }
        if let FaultSpec::Bursts {
            min_length,
            max_length,
            ..
        } = *self
            && min_length > max_length
        {
            return Err(InvalidFault::new(
                "min_length",
                min_length,
                "min_length ≤ max_length",
            ));
        }
        Ok(())
    }
}

impl FaultPlan {
    /// Whether epoch k carries an anomaly.
    pub fn is_anomalous(&self, k: usize) -> bool {
        self.error[k] != 0.0
    }

    /// Fraction of epochs with an anomaly.
    pub fn anomaly_fraction(&self) -> f64 {
        self.error.iter().filter(|e| **e != 0.0).count() as f64 / self.error.len().max(1) as f64
    }
}

fn magnitude<R: Rng + ?Sized>(rng: &mut R, m: SigmaRange, sigma: f64) -> f64 {
    let u: f64 = rng.random();
    (m.min + (m.max - m.min) * u) * sigma
}

fn sign<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    if rng.random::<bool>() { 1.0 } else { -1.0 }
}

/// Draw a plan of `epochs` epochs for measurement noise `sigma`. Faults that
/// would fall past the end are cut at the last epoch; outages past the end
/// likewise.
pub fn plan<R: Rng + ?Sized>(
    specs: &[FaultSpec],
    outages: &[Outage],
    epochs: usize,
    sigma: f64,
    rng: &mut R,
) -> FaultPlan {
    let mut error = vec![0.0; epochs];
    let mut lost = vec![false; epochs];
    for o in outages {
        for slot in lost.iter_mut().skip(o.start).take(o.length) {
            *slot = true;
        }
    }
    if epochs == 0 {
        return FaultPlan { error, lost };
    }
    let burst = |error: &mut Vec<f64>, rng: &mut R, start: usize, length: usize, m: SigmaRange| {
        let s = sign(rng);
        for e in error.iter_mut().skip(start).take(length) {
            *e = s * magnitude(rng, m, sigma);
        }
    };
    for spec in specs {
        match *spec {
            FaultSpec::SingleOutliers {
                count,
                magnitude: m,
            } => {
                for _ in 0..count {
                    let k = rng.random_range(0..epochs);
                    error[k] = sign(rng) * magnitude(rng, m, sigma);
                }
            }
            FaultSpec::Bursts {
                count,
                min_length,
                max_length,
                magnitude: m,
            } => {
                for _ in 0..count {
                    let length = rng.random_range(min_length..=max_length.max(min_length));
                    let start = rng.random_range(0..epochs);
                    burst(&mut error, rng, start, length, m);
                }
            }
            FaultSpec::RandomRate { rate, magnitude: m } => {
                for e in error.iter_mut() {
                    if rng.random::<f64>() < rate {
                        *e = sign(rng) * magnitude(rng, m, sigma);
                    }
                }
            }
            FaultSpec::Fixed {
                start,
                length,
                sigmas,
            } => {
                for e in error.iter_mut().skip(start).take(length) {
                    *e = sigmas * sigma;
                }
            }
            FaultSpec::AfterOutage {
                length,
                magnitude: m,
            } => {
                for o in outages {
                    burst(&mut error, rng, o.start + o.length, length, m);
                }
            }
        }
    }
    // A lost measurement carries no error.
    for (e, l) in error.iter_mut().zip(&lost) {
        if *l {
            *e = 0.0;
        }
    }
    FaultPlan { error, lost }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::run_rng;

    const M: SigmaRange = SigmaRange {
        min: 10.0,
        max: 50.0,
    };

    #[test]
    fn random_rate_hits_its_fraction_and_magnitudes() {
        let p = plan(
            &[FaultSpec::RandomRate {
                rate: 0.2,
                magnitude: M,
            }],
            &[],
            20_000,
            0.1,
            &mut run_rng(1, 0),
        );
        // σ of the fraction: √(0.2·0.8/20000) ≈ 0.0028; allow 4σ.
        assert!(
            (p.anomaly_fraction() - 0.2).abs() < 0.012,
            "{}",
            p.anomaly_fraction()
        );
        assert!(
            p.error
                .iter()
                .filter(|e| **e != 0.0)
                .all(|e| (1.0..=5.0).contains(&e.abs()))
        );
        let positive = p.error.iter().filter(|e| **e > 0.0).count() as f64;
        let negative = p.error.iter().filter(|e| **e < 0.0).count() as f64;
        assert!((positive / (positive + negative) - 0.5).abs() < 0.05);
    }

    #[test]
    fn bursts_follow_outages_and_outages_carry_no_error() {
        let outages = [Outage {
            start: 100,
            length: 50,
        }];
        let specs = [FaultSpec::AfterOutage {
            length: 10,
            magnitude: M,
        }];
        let p = plan(&specs, &outages, 300, 1.0, &mut run_rng(2, 0));
        assert!((100..150).all(|k| p.lost[k] && p.error[k] == 0.0));
        assert!((150..160).all(|k| p.is_anomalous(k)));
        assert!(!p.is_anomalous(160) && !p.is_anomalous(99));
        let s = p.error[150].signum();
        assert!(
            (150..160).all(|k| p.error[k].signum() == s),
            "one sign per burst"
        );
    }

    #[test]
    fn same_seed_same_plan() {
        let specs = [
            FaultSpec::SingleOutliers {
                count: 5,
                magnitude: M,
            },
            FaultSpec::Bursts {
                count: 2,
                min_length: 2,
                max_length: 20,
                magnitude: M,
            },
        ];
        let a = plan(&specs, &[], 1000, 1.0, &mut run_rng(3, 4));
        let b = plan(&specs, &[], 1000, 1.0, &mut run_rng(3, 4));
        assert_eq!(a, b);
        assert!(a.anomaly_fraction() > 0.0);
    }

    #[test]
    fn fixed_faults_land_where_placed_and_specs_are_validated() {
        let p = plan(
            &[FaultSpec::Fixed {
                start: 5,
                length: 3,
                sigmas: -30.0,
            }],
            &[],
            10,
            0.1,
            &mut run_rng(1, 0),
        );
        let hit: Vec<usize> = (0..10).filter(|&k| p.is_anomalous(k)).collect();
        assert_eq!(hit, [5, 6, 7]);
        assert!((p.error[6] + 3.0).abs() < 1e-12);
        let bad = FaultSpec::Bursts {
            count: 1,
            min_length: 5,
            max_length: 2,
            magnitude: M,
        };
        assert_eq!(bad.validate().unwrap_err().key, "min_length");
        let rate = FaultSpec::RandomRate {
            rate: 1.5,
            magnitude: M,
        };
        assert_eq!(rate.validate().unwrap_err().key, "rate");
        // Counts are bounded: 2^60 draws per run would only spin.
        let many = FaultSpec::SingleOutliers {
            count: 1 << 60,
            magnitude: M,
        };
        let e = many.validate().unwrap_err();
        assert_eq!((e.key, e.allowed), ("count", "0 … 1000000"));
        let huge = FaultSpec::AfterOutage {
            length: 3,
            magnitude: SigmaRange {
                min: 1.0,
                max: 1e300,
            },
        };
        assert_eq!(huge.validate().unwrap_err().key, "magnitude");
        let ok = FaultSpec::SingleOutliers {
            count: MAX_FAULT_EPOCHS,
            magnitude: M,
        };
        assert!(ok.validate().is_ok());
    }
}
