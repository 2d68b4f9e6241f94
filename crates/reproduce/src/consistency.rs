//! Filter consistency demo: a constant-velocity tracking filter, tuned and
//! mistuned, checked by Monte Carlo NEES and NIS against their χ² bounds
//! (Bar-Shalom, Li & Kirubarajan, §5.4). This is the engine proving itself
//! before the paper reproductions run on it.
//!
//! Every run draws one truth trajectory and its measurements from its own
//! seeded stream; the three filter variants process the *same* data (common
//! random numbers), so their differences are the tuning, not the luck.

use aidnav_estimation::{Chi2Mean, KalmanFilter, mean_chi2_bounds, nees};
use aidnav_io::config::{Invalid, Validate, count_in_range, in_range, probability};
use aidnav_models::ConstantVelocity;
use nalgebra::{Matrix2, Vector1, Vector2};
use serde::{Deserialize, Serialize};

use aidnav_sim::monte_carlo::MonteCarlo;
use aidnav_sim::rng::standard_normal;

/// Fraction of epochs whose run-averaged NEES must fall inside its interval
/// for the verdict "consistent": with a 95 % interval a consistent filter
/// leaves it in about 5 % of epochs, so 90 % leaves room for chance.
pub const MIN_FRACTION_INSIDE: f64 = 0.90;

/// Scenario of the consistency demo (all fields optional in the TOML file).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ConsistencyScenario {
    /// Master seed. Default 20261123.
    pub seed: u64,
    /// Monte Carlo runs, 1 … 1 000 000. Default 200.
    pub runs: usize,
    /// Epochs per run, 2 … 1 000 000. Default 300.
    pub epochs: usize,
    /// Sampling period \[s\], > 0. Default 1.
    pub dt_s: f64,
    /// White-acceleration power spectral density [m²/s³], > 0. Default 0.05.
    pub accel_psd: f64,
    /// Position measurement noise σ \[m\], > 0. Default 2.
    pub position_sigma_m: f64,
    /// Initial position σ \[m\], > 0. Default 10.
    pub initial_position_sigma_m: f64,
    /// Initial velocity σ [m/s], > 0. Default 1.
    pub initial_velocity_sigma_mps: f64,
    /// Confidence of the χ² intervals, 0 … 1. Default 0.95.
    pub confidence: f64,
    /// The "Q too small" filter believes Q times this, > 0. Default 0.01.
    pub mistuned_q_scale: f64,
    /// The "R too large" filter believes R times this, > 0. Default 10.
    pub mistuned_r_scale: f64,
}

impl Default for ConsistencyScenario {
    fn default() -> Self {
        Self {
            seed: 20261123,
            runs: 200,
            epochs: 300,
            dt_s: 1.0,
            accel_psd: 0.05,
            position_sigma_m: 2.0,
            initial_position_sigma_m: 10.0,
            initial_velocity_sigma_mps: 1.0,
            confidence: 0.95,
            mistuned_q_scale: 0.01,
            mistuned_r_scale: 10.0,
        }
    }
}

/// Memory the run records computed ahead of the campaign's fold may take
/// \[bytes\] (256 MB): fewer runs are computed at once when epochs are many.
const IN_FLIGHT_BYTES: usize = 256 * 1024 * 1024;

/// Most runs computed before they are folded (enough for 16 threads).
const MAX_RUNS_IN_FLIGHT: usize = 64;

impl ConsistencyScenario {
    /// Bytes of one run's record: NEES and NIS per epoch of each variant.
    fn run_record_bytes(&self) -> usize {
        self.epochs
            .saturating_mul(2 * VARIANTS * std::mem::size_of::<f64>())
            .max(1)
    }

    /// Most runs computed before they are folded: [`MAX_RUNS_IN_FLIGHT`],
    /// fewer when their records would exceed [`IN_FLIGHT_BYTES`].
    fn runs_in_flight(&self) -> usize {
        (IN_FLIGHT_BYTES / self.run_record_bytes()).clamp(1, MAX_RUNS_IN_FLIGHT)
    }

    /// Memory the campaign holds at most \[bytes\]: the run records in
    /// flight and the per-epoch sums (NEES and NIS of each variant). It does
    /// not grow with `runs`: runs are folded in as they finish.
    pub fn memory_bytes(&self) -> f64 {
        let record = self.run_record_bytes() as f64;
        record * self.runs_in_flight().min(self.runs.max(1)) as f64 + record
    }
}

impl Validate for ConsistencyScenario {
    fn validate(&self) -> Result<(), Invalid> {
        count_in_range("runs", self.runs, 1, 1_000_000)?;
        count_in_range("epochs", self.epochs, 2, 1_000_000)?;
        in_range("dt_s", self.dt_s, 1e-4, 100.0)?;
        in_range("accel_psd", self.accel_psd, 1e-12, 1e6)?;
        crate::within(
            "position_sigma_m",
            self.position_sigma_m,
            crate::SIGMA_RANGE,
        )?;
        crate::within(
            "initial_position_sigma_m",
            self.initial_position_sigma_m,
            crate::SIGMA_RANGE,
        )?;
        crate::within(
            "initial_velocity_sigma_mps",
            self.initial_velocity_sigma_mps,
            crate::SIGMA_MPS_RANGE,
        )?;
        probability("confidence", self.confidence)?;
        crate::within(
            "mistuned_q_scale",
            self.mistuned_q_scale,
            crate::SCALE_RANGE,
        )?;
        crate::within(
            "mistuned_r_scale",
            self.mistuned_r_scale,
            crate::SCALE_RANGE,
        )?;
        crate::within_memory(
            "epochs",
            self.epochs,
            self.memory_bytes(),
            "the per-epoch NEES and NIS sums",
            "2 ≤ epochs ≤ 1000000",
        )?;
        if self.runs.saturating_mul(self.epochs) > 2_000_000_000 {
            return Err(Invalid::new("runs", self.runs, "runs × epochs ≤ 2·10⁹"));
        }
        Ok(())
    }
}

/// One filter variant's scores.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VariantResult {
    /// `tuned`, `q_too_small` or `r_too_large`.
    pub name: String,
    /// Factor on Q the filter believes.
    pub q_scale: f64,
    /// Factor on R the filter believes.
    pub r_scale: f64,
    /// Mean NEES over all runs and epochs (2 for a consistent 2-state filter).
    pub mean_nees: f64,
    /// Mean NIS over all runs and epochs (1 for a consistent filter).
    pub mean_nis: f64,
    /// 95 % (or chosen) interval of the mean NIS over all runs and epochs.
    pub nis_bounds: (f64, f64),
    /// Whether the mean NIS is inside `nis_bounds`.
    pub nis_inside: bool,
    /// Fraction of epochs whose run-averaged NEES is inside its interval.
    pub fraction_epochs_nees_inside: f64,
    /// Verdict: NIS inside and at least [`MIN_FRACTION_INSIDE`] of epochs' NEES inside.
    pub consistent: bool,
    /// RMS position error over all runs and epochs \[m\].
    pub rms_position_error_m: f64,
    /// Filter's own position σ, RMS over runs and epochs \[m\].
    pub rms_position_sigma_m: f64,
    /// Run-averaged NEES per epoch.
    #[serde(skip)]
    pub nees_per_epoch: Vec<f64>,
    /// Run-averaged NIS per epoch.
    #[serde(skip)]
    pub nis_per_epoch: Vec<f64>,
}

/// The demo's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConsistencyResult {
    /// Interval of the run-averaged NEES at one epoch.
    pub nees_epoch_bounds: (f64, f64),
    /// Variants in the order tuned, Q too small, R too large.
    pub variants: Vec<VariantResult>,
}

const VARIANTS: usize = 3;

/// One run's record, what [`finish`] folds: for each variant, per-epoch
/// NEES and NIS, and squared errors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSums {
    nees: [Vec<f64>; VARIANTS],
    nis: [Vec<f64>; VARIANTS],
    sq_err: [f64; VARIANTS],
    sq_sigma: [f64; VARIANTS],
}

/// The demo's model, shared by every run.
struct Model {
    phi: Matrix2<f64>,
    q: Matrix2<f64>,
    q_factor: Matrix2<f64>,
    h: nalgebra::Matrix1x2<f64>,
    r: nalgebra::Matrix1<f64>,
    p0: Matrix2<f64>,
    scales: [(f64, f64); VARIANTS],
}

fn model(s: &ConsistencyScenario) -> Result<Model, aidnav_estimation::EstimationError> {
    let cv = ConstantVelocity::new(s.dt_s, s.accel_psd).ok_or(
        aidnav_estimation::EstimationError::NonFinite {
            step: aidnav_estimation::Step::Initialise,
            matrix: aidnav_estimation::Matrix::Q,
        },
    )?;
    let phi = cv.transition();
    let q = cv.process_noise();
    let q_factor = q.cholesky().map(|c| c.l()).unwrap_or_else(Matrix2::zeros);
    let (h, r) = ConstantVelocity::position_measurement(s.position_sigma_m);
    let p0 = Matrix2::new(
        s.initial_position_sigma_m.powi(2),
        0.0,
        0.0,
        s.initial_velocity_sigma_mps.powi(2),
    );
    let scales = [
        (1.0, 1.0),
        (s.mistuned_q_scale, 1.0),
        (1.0, s.mistuned_r_scale),
    ];
    Ok(Model {
        phi,
        q,
        q_factor,
        h,
        r,
        p0,
        scales,
    })
}

/// One run: the truth, its measurements and the three filters.
fn one_run(
    s: &ConsistencyScenario,
    m: &Model,
    rng: &mut aidnav_sim::rng::RunRng,
) -> Result<RunSums, aidnav_estimation::EstimationError> {
    let Model {
        phi,
        q,
        q_factor,
        h,
        r,
        p0,
        scales,
    } = m;
    let (phi, q, q_factor, h, r, p0) = (*phi, *q, *q_factor, *h, *r, *p0);
    let epochs = s.epochs;
    let mut out = RunSums {
        nees: std::array::from_fn(|_| Vec::with_capacity(epochs)),
        nis: std::array::from_fn(|_| Vec::with_capacity(epochs)),
        sq_err: [0.0; VARIANTS],
        sq_sigma: [0.0; VARIANTS],
    };
    let mut truth = Vector2::new(
        s.initial_position_sigma_m * standard_normal(rng),
        s.initial_velocity_sigma_mps * standard_normal(rng),
    );
    let first = KalmanFilter::new(Vector2::zeros(), p0)?;
    let mut filters: [_; VARIANTS] = std::array::from_fn(|_| first.clone());
    for k in 0..epochs {
        if k > 0 {
            truth =
                phi * truth + q_factor * Vector2::new(standard_normal(rng), standard_normal(rng));
        }
        let z = Vector1::new(truth[0] + s.position_sigma_m * standard_normal(rng));
        for (v, kf) in filters.iter_mut().enumerate() {
            let (qs, rs) = scales[v];
            if k > 0 {
                kf.predict(&phi, &(q * qs)).map_err(|e| e.at_epoch(k))?;
            }
            let rec = kf.update(&z, &h, &(r * rs)).map_err(|e| e.at_epoch(k))?;
            out.nis[v].push(rec.nis);
            out.nees[v].push(nees(&truth, kf.state(), kf.covariance()).map_err(|e| e.at_epoch(k))?);
            out.sq_err[v] += (kf.state()[0] - truth[0]).powi(2);
            out.sq_sigma[v] += kf.covariance()[(0, 0)];
        }
    }
    Ok(out)
}

/// Run the demo (runs folded as they are computed: memory of a few runs,
/// not of all). Errors only if the engine reports one (it should not).
pub fn run(
    s: &ConsistencyScenario,
    mc: &MonteCarlo,
) -> Result<ConsistencyResult, aidnav_estimation::EstimationError> {
    let m = model(s)?;
    let runs = mc.runs as f64;
    let sums = mc.try_fold_chunked(
        s.runs_in_flight(),
        CampaignSums::new(s.epochs),
        |_, rng| one_run(s, &m, rng),
        |acc, _, run| acc.add(&run, runs),
    )?;
    Ok(result_of(s, &m, sums, mc.runs))
}

/// Runs `range` of the campaign (run k draws stream k of the seed whatever
/// the range): a chunk for [`finish`] to combine with the others, computed
/// anywhere.
pub fn run_range(
    s: &ConsistencyScenario,
    mc: &MonteCarlo,
    range: std::ops::Range<usize>,
) -> Result<Vec<RunSums>, aidnav_estimation::EstimationError> {
    let m = model(s)?;
    mc.try_run_range(range, |_, rng| one_run(s, &m, rng))
}

/// The result from every run, in run order (the chunks of [`run_range`]
/// concatenated): the same numbers, bit for bit, as [`run`] (the same
/// fold, in the same order).
pub fn finish(
    s: &ConsistencyScenario,
    per_run: Vec<RunSums>,
) -> Result<ConsistencyResult, aidnav_estimation::EstimationError> {
    let m = model(s)?;
    let runs = per_run.len() as f64;
    let mut sums = CampaignSums::new(s.epochs);
    for run in &per_run {
        sums.add(run, runs);
    }
    Ok(result_of(s, &m, sums, per_run.len()))
}

/// The result from the folded sums of `runs` runs.
fn result_of(
    s: &ConsistencyScenario,
    m: &Model,
    sums: CampaignSums,
    runs: usize,
) -> ConsistencyResult {
    let names = ["tuned", "q_too_small", "r_too_large"];
    let nees_epoch_bounds = mean_chi2_bounds(2, runs, s.confidence);
    let variants = sums
        .variants
        .into_iter()
        .enumerate()
        .map(|(v, sums)| {
            variant_result(
                s,
                sums,
                runs as f64,
                names[v],
                m.scales[v],
                nees_epoch_bounds,
            )
        })
        .collect();
    ConsistencyResult {
        nees_epoch_bounds,
        variants,
    }
}

/// One variant's sums over the runs folded so far: the run-averaged NEES
/// and NIS per epoch (each run's value / runs, added in run order), every
/// NIS, and the squared errors and variances.
struct VariantSums {
    nees_per_epoch: Vec<f64>,
    nis_per_epoch: Vec<f64>,
    nis_all: Chi2Mean,
    sq_err: f64,
    sq_sigma: f64,
}

/// The campaign's running sums: memory of one run's per-epoch record, not
/// of every run's.
struct CampaignSums {
    variants: [VariantSums; VARIANTS],
}

impl CampaignSums {
    fn new(epochs: usize) -> Self {
        Self {
            variants: std::array::from_fn(|_| VariantSums {
                nees_per_epoch: vec![0.0; epochs],
                nis_per_epoch: vec![0.0; epochs],
                nis_all: Chi2Mean::default(),
                sq_err: 0.0,
                sq_sigma: 0.0,
            }),
        }
    }

    /// Fold in the next run (runs come in run order).
    fn add(&mut self, r: &RunSums, runs: f64) {
        for (v, acc) in self.variants.iter_mut().enumerate() {
            for k in 0..acc.nees_per_epoch.len() {
                acc.nees_per_epoch[k] += r.nees[v][k] / runs;
                acc.nis_per_epoch[k] += r.nis[v][k] / runs;
                acc.nis_all.push(r.nis[v][k], 1);
            }
            acc.sq_err += r.sq_err[v];
            acc.sq_sigma += r.sq_sigma[v];
        }
    }
}

/// One variant's scores over every run: the fraction of epochs inside the
/// NEES bounds, the NIS test, RMS error and σ.
fn variant_result(
    s: &ConsistencyScenario,
    sums: VariantSums,
    runs: f64,
    name: &str,
    (q_scale, r_scale): (f64, f64),
    nees_epoch_bounds: (f64, f64),
) -> VariantResult {
    let epochs = s.epochs;
    let samples = runs * epochs as f64;
    let VariantSums {
        nees_per_epoch,
        nis_per_epoch,
        nis_all,
        sq_err,
        sq_sigma,
    } = sums;
    let (lo, hi) = nees_epoch_bounds;
    let inside = nees_per_epoch
        .iter()
        .filter(|m| (lo..=hi).contains(*m))
        .count() as f64
        / epochs as f64;
    let nis_inside = nis_all.is_consistent(s.confidence);
    VariantResult {
        name: name.to_string(),
        q_scale,
        r_scale,
        mean_nees: nees_per_epoch.iter().sum::<f64>() / epochs as f64,
        mean_nis: nis_all.mean(),
        nis_bounds: nis_all.bounds(s.confidence),
        nis_inside,
        fraction_epochs_nees_inside: inside,
        consistent: nis_inside && inside >= MIN_FRACTION_INSIDE,
        rms_position_error_m: (sq_err / samples).sqrt(),
        rms_position_sigma_m: (sq_sigma / samples).sqrt(),
        nees_per_epoch,
        nis_per_epoch,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_documented_maximum_run_count_needs_memory_independent_of_runs() {
        let max = ConsistencyScenario {
            runs: 1_000_000,
            ..Default::default()
        };
        assert!(max.validate().is_ok());
        let few = ConsistencyScenario {
            runs: 200_000,
            ..Default::default()
        };
        assert_eq!(max.memory_bytes(), few.memory_bytes());
        // The default scenario holds well under 100 MB whatever the run count.
        assert!(max.memory_bytes() < 1e8, "{}", max.memory_bytes());
        let longest = ConsistencyScenario {
            runs: 2000,
            epochs: 1_000_000,
            ..Default::default()
        };
        assert!(longest.validate().is_ok());
        assert!(longest.memory_bytes() <= 512.0 * 1024.0 * 1024.0);
    }

    #[test]
    fn reduced_run_demo_separates_tuned_from_mistuned() {
        let s = ConsistencyScenario {
            runs: 60,
            epochs: 120,
            ..Default::default()
        };
        let r = run(&s, &MonteCarlo::new(s.runs, s.seed).quiet()).unwrap();
        assert!(r.variants[0].consistent, "{:?}", r.variants[0]);
        assert!(!r.variants[1].consistent);
        assert!(!r.variants[2].consistent);
        // The mistuned filters are also worse (Q too small) or overly pessimistic (R too large).
        assert!(r.variants[1].rms_position_error_m > r.variants[0].rms_position_error_m);
        assert!(r.variants[2].rms_position_sigma_m > r.variants[2].rms_position_error_m);
    }
}
