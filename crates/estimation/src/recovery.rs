//! Recovery from a lock-out: is a run of refused measurements a fault of
//! the measurements, or has the *state* gone wrong?
//!
//! A gate (or a limiter) that refuses every measurement of a stream can be
//! right — the stream is faulty — or wrong: the state has drifted or the
//! truth has jumped, and the filter will never believe the measurements
//! again ("lock-out"). Navigation filters in service end a lock-out by a
//! *reset* of the measured states to the measurement after a timeout (PX4
//! EKF2: position and velocity reset to GNSS when no fix was fused for
//! 7 s; ArduPilot EKF3: the same after its GPS retry time). A timeout
//! alone resets onto whatever fix comes next, a wild one included; here
//! the evidence is the measurements' agreement *with each other*.
//!
//! [`AgreementDetector`] watches the refused measurements of one stream
//! and declares a recovery when `run_length` of them agree. Two refused
//! measurements j, k agree when the change the filter predicts for the
//! measured quantity between them matches the change the measurements
//! show. With ν_k = z_k − H_k x⁻_k the innovation of measurement k and
//! e_j = ν_j − H_j (x⁺_j − x⁻_j) the residual of measurement j against the
//! state its update left (ν itself when it was rejected), the difference
//!
//! ```text
//! d = ν_k − e_j
//! ```
//!
//! is (predicted change) − (measured change) up to sign: it is zero-mean
//! under "the measurements are right" whatever the state's error, since a
//! common error cancels. Its covariance, with δx the estimation error, is
//!
//! ```text
//! C = R_k + R_j + H_k P⁻_k H_kᵀ + H_j P⁺_j H_jᵀ − H_k X − Xᵀ H_kᵀ,
//! X = Cov(δx_k⁻, H_j δx⁺_j)
//! ```
//!
//! and the pair agrees when `dᵀ C⁻¹ d ≤ χ²_m(p)`. The cross-covariance X
//! starts at `P⁺_j H_jᵀ` and follows the filter: `X ← Φ X` at each time
//! update, `X ← (I − K H) X` at each other measurement update (the error
//! of any update is `(I − K H) δx⁻ − K v` for any gain K, v independent of
//! the past). So a moving vehicle is handled by the filter's own predicted
//! change, and C grows with the filter's uncertainty between the two.
//!
//! That test trusts the filter's covariance over the short interval. A
//! filter that has *diverged* — the lock-out a recovery exists for — may
//! predict the change wrongly by far more than it admits: its velocity is
//! off by some b it does not know. The run then also accepts a member
//! whose discrepancy *rate* d / Δt matches that of the run's previous link
//! (the hypothesis "the measurements are right, the prediction is off by a
//! common rate b"): with Δ = d/Δt − d′/Δt′ (d′ the previous link's, which
//! shares the measurement j with this one),
//!
//! ```text
//! Cov(Δ) = C/Δt² + C′/Δt′² + 2 R_j / (Δt Δt′),   ΔᵀCov(Δ)⁻¹Δ ≤ χ²_m(p).
//! ```
//!
//! Under an unknown b the first link of a run cannot be tested at all: a
//! measurement that agrees with no run starts a run of its own *and* a
//! branch of two with the most recent run of one, joined without evidence;
//! a run recovers when it holds `run_length` measurements that each passed
//! a test against their predecessor (counting the first): with a healthy
//! filter, `run_length` members; with a diverged one, one more.
//!
//! A run is the measurements that agree in sequence; a measurement that
//! agrees with no run (an outlier amid a genuine step) starts its own in a
//! spare slot without breaking the others, so interleaved outliers cannot
//! hold off a recovery for ever, and outliers (which agree with nothing,
//! neither in offset nor in rate) never produce one. An accepted
//! measurement ends every run (the filter agrees with the stream again).
//!
//! The detector knows nothing about what the states mean; the reset itself
//! (which states, to what, with what covariance) is the caller's.
//!
//! ```
//! use aidnav_estimation::recovery::{AgreementConfig, AgreementDetector, Update, Verdict};
//! use aidnav_estimation::nalgebra::{Const, Matrix1, Vector1};
//!
//! // A scalar random constant x, measured directly with σ = 0.1: the truth
//! // jumps by 50 while the filter is sure of itself (σ = 0.01), so a gate
//! // refuses every measurement. The refused measurements agree with each
//! // other, and the third one completes a run of three.
//! let cfg = AgreementConfig { run_length: 3, probability: 0.999 };
//! let mut detector = AgreementDetector::<Const<1>, Const<1>>::new(cfg).unwrap();
//! let (h, r, p) = (Matrix1::new(1.0), Matrix1::new(0.01), Matrix1::new(1e-4));
//! let (zero_gain, unchanged) = (Matrix1::new(0.0), Vector1::new(0.0));
//! let mut verdicts = Vec::new();
//! for z in [50.05, 49.98, 50.02] {
//!     detector.propagate(&Matrix1::new(1.0), 0.25);
//!     let nu = Vector1::new(z); // z − H x with x = 0
//!     verdicts.push(detector.refused(&Update {
//!         residual: &nu, state_change: &unchanged, r: &r, h: &h,
//!         prior_covariance: &p, gain: &zero_gain, posterior_covariance: &p,
//!     }));
//! }
//! assert_eq!(verdicts, [Verdict::Started, Verdict::Joined { members: 2 }, Verdict::Recover { members: 3 }]);
//! ```

use nalgebra::allocator::Allocator;
use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector};
use serde::{Deserialize, Serialize};

use crate::consistency::chi2_quantile;
use crate::dense;
use crate::kalman::FilterAllocator;

/// Runs followed at once: the stream's true step, and spares for the
/// outliers interleaved with it (each agrees with nothing and takes a run
/// of one, and a branch of two, until a run with more evidence needs the
/// slot).
pub const CANDIDATE_RUNS: usize = 5;

/// When refused measurements count as agreeing, and how many make a recovery.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgreementConfig {
    /// Refused measurements that must agree in a run (≥ 2).
    pub run_length: usize,
    /// Probability of the χ²(m) quantile the tests use, in (0, 1).
    pub probability: f64,
}

/// What the detector concluded from a refused measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// It agrees with no run: it starts one of its own.
    Started,
    /// It extends a run, which now has `members` measurements.
    Joined {
        /// Measurements in the run, this one included.
        members: usize,
    },
    /// It completes a run of `run_length` agreeing measurements: reset the
    /// measured states to it. Every run is forgotten.
    Recover {
        /// Measurements in the run, this one included.
        members: usize,
    },
}

/// One measurement update of the stream as the detector needs it (the
/// filter's update, whatever its policy decided, has just been made).
#[derive(Debug)]
pub struct Update<'a, N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Innovation ν = z − H x⁻ as measured.
    pub residual: &'a OVector<f64, M>,
    /// What the update did to the state, x⁺ − x⁻ (zero for a rejection,
    /// K ν_lim for a limited innovation).
    pub state_change: &'a OVector<f64, N>,
    /// Measurement noise covariance R.
    pub r: &'a OMatrix<f64, M, M>,
    /// Measurement matrix H.
    pub h: &'a OMatrix<f64, M, N>,
    /// State covariance before the update, P⁻.
    pub prior_covariance: &'a OMatrix<f64, N, N>,
    /// The gain the update applied (zero for a rejection).
    pub gain: &'a OMatrix<f64, N, M>,
    /// State covariance after the update, P⁺.
    pub posterior_covariance: &'a OMatrix<f64, N, N>,
}

/// The last member of a run: what the next measurement is compared with.
#[derive(Debug, Clone)]
struct Anchor<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// e = ν − H (x⁺ − x⁻): the member's residual against the state its update left.
    residual: OVector<f64, M>,
    /// Its R.
    r: OMatrix<f64, M, M>,
    /// R + H P⁺ Hᵀ of the member.
    covariance: OMatrix<f64, M, M>,
    /// X = Cov(δx now, H δx⁺ of the member), N × m.
    cross: OMatrix<f64, N, M>,
    /// Time since the member \[s\].
    age_s: f64,
}

/// The discrepancy rate of a run's last link: d / Δt and C / Δt².
#[derive(Debug, Clone)]
struct Rate<M: Dim>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    rate: OVector<f64, M>,
    covariance: OMatrix<f64, M, M>,
    interval_s: f64,
}

#[derive(Debug, Clone)]
struct Run<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    anchor: Anchor<N, M>,
    /// The previous link's rate (None for a run of one).
    rate: Option<Rate<M>>,
    members: usize,
    /// Members that passed a test against their predecessor, the first
    /// counted (a second member joined without evidence is not).
    evidence: usize,
    /// Order of the last join (larger: more recent).
    stamp: u64,
}

/// A run a measurement may extend or branch from.
struct Candidate<M: Dim>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    slot: usize,
    rate: Rate<M>,
    /// (evidence after joining, members, stamp): larger is preferred.
    key: (usize, usize, u64),
}

/// How a measurement relates to a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Link {
    /// Joins without evidence (second member, first test failed).
    Free,
    /// Passed a test.
    Agrees,
}

/// Watches the refused measurements of one stream for a run that agrees
/// (see the [module documentation](self)). Fixed storage: with `Const`
/// dimensions nothing is allocated after construction.
#[derive(Debug, Clone)]
pub struct AgreementDetector<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    config: AgreementConfig,
    /// χ²_m quantile of the probability (NaN until m is known).
    threshold: f64,
    runs: [Option<Run<N, M>>; CANDIDATE_RUNS],
    clock: u64,
}

impl<N: Dim, M: Dim> AgreementDetector<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// A detector for m-dimensional measurements (m known from `M`; for a
    /// run-time `M` the threshold is fixed at the first measurement). None
    /// unless `run_length ≥ 2` and `0 < probability < 1`.
    pub fn new(config: AgreementConfig) -> Option<Self> {
        let valid = config.run_length >= 2 && config.probability > 0.0 && config.probability < 1.0;
        valid.then(|| Self {
            config,
            threshold: M::try_to_usize().map_or(f64::NAN, |m| chi2_quantile(m, config.probability)),
            runs: [None, None, None, None, None],
            clock: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> AgreementConfig {
        self.config
    }

    /// Members of the longest run followed (0: none).
    pub fn longest_run(&self) -> usize {
        self.runs
            .iter()
            .flatten()
            .map(|r| r.members)
            .max()
            .unwrap_or(0)
    }

    /// Forget every run (a gap in the stream, a reset of the states).
    pub fn clear(&mut self) {
        self.runs = [None, None, None, None, None];
    }

    /// States `first .. first + count` were reset to values independent of
    /// the past (their rows and columns of P zeroed, a new block set, by
    /// another stream's reset): their rows of every cross-covariance are
    /// zero now, and the runs go on.
    pub fn decorrelate(&mut self, first: usize, count: usize) {
        for run in self.runs.iter_mut().flatten() {
            let x = &mut run.anchor.cross;
            let end = (first + count).min(x.nrows());
            for i in first.min(end)..end {
                x.row_mut(i).fill(0.0);
            }
        }
    }

    /// The stream's measurement was accepted: the filter agrees with it
    /// again, every run ends.
    pub fn accepted(&mut self) {
        self.clear();
    }

    /// The filter's time update `x ← Φ x` over `interval_s` seconds
    /// (between measurements).
    pub fn propagate(&mut self, phi: &OMatrix<f64, N, N>, interval_s: f64) {
        for run in self.runs.iter_mut().flatten() {
            let a = &mut run.anchor;
            let mut next = a.cross.clone();
            dense::gemm(&mut next, 1.0, phi, &a.cross, 0.0);
            a.cross = next;
            a.age_s += interval_s;
        }
    }

    /// Another measurement update of the filter (another stream, or a
    /// constraint) with gain K and matrix H: `X ← X − K (H X)`.
    pub fn updated<M2: Dim>(&mut self, gain: &OMatrix<f64, N, M2>, h: &OMatrix<f64, M2, N>)
    where
        DefaultAllocator: FilterAllocator<N, M2> + Allocator<M2, M>,
    {
        for run in self.runs.iter_mut().flatten() {
            let x = &mut run.anchor.cross;
            let (m2, _) = h.shape_generic();
            let (_, m) = x.shape_generic();
            let mut hx = OMatrix::<f64, M2, M>::zeros_generic(m2, m);
            dense::gemm(&mut hx, 1.0, h, x, 0.0);
            dense::gemm(x, -1.0, gain, &hx, 1.0);
        }
    }

    /// A measurement of the stream was refused (rejected or limited; the
    /// update has been made): test it against every run and extend the one
    /// it agrees with (the one with the most evidence); if it agrees with
    /// none, start a run of its own and, paired with the most recent run
    /// of one, a run of two joined without evidence (the branch a diverged
    /// filter's runs grow from). Every run's cross-covariance then follows
    /// this update.
    pub fn refused(&mut self, m: &Update<'_, N, M>) -> Verdict {
        if self.threshold.is_nan() {
            self.threshold = chi2_quantile(m.residual.len(), self.config.probability);
        }
        let hph = projected(m.h, m.prior_covariance);
        // (slot, rate of the link, ranking key): the agreeing run with the
        // most evidence; the most recent run of one it may branch from.
        let mut best: Option<Candidate<M>> = None;
        let mut single: Option<Candidate<M>> = None;
        for (i, run) in self.runs.iter().enumerate() {
            let Some(run) = run else { continue };
            let (choice, key) = match self.link(run, m, &hph) {
                Some((Link::Agrees, rate)) => (
                    &mut best,
                    ((run.evidence + 1, run.members, run.stamp), rate),
                ),
                Some((Link::Free, rate)) => (&mut single, ((0, 0, run.stamp), rate)),
                None => continue,
            };
            if choice.as_ref().is_none_or(|c| key.0 > c.key) {
                *choice = Some(Candidate {
                    slot: i,
                    rate: key.1,
                    key: key.0,
                });
            }
        }
        // This update, seen by every run: X ← (I − K H) X.
        self.updated(m.gain, m.h);
        self.clock += 1;
        let stamp = self.clock;
        if let Some(Candidate { slot: i, rate, .. }) = best
            && let Some(run) = self.runs[i].as_mut()
        {
            run.members += 1;
            run.evidence += 1;
            if run.evidence >= self.config.run_length {
                let members = run.members;
                self.clear();
                return Verdict::Recover { members };
            }
            run.anchor = anchor_of(m);
            run.rate = Some(rate);
            run.stamp = stamp;
            return Verdict::Joined {
                members: run.members,
            };
        }
        let alone = Run {
            anchor: anchor_of(m),
            rate: None,
            members: 1,
            evidence: 1,
            stamp,
        };
        let keep = single.as_ref().map(|s| s.slot);
        let slot = self.spare_slot(keep);
        self.runs[slot] = Some(alone);
        if let Some(Candidate { rate, .. }) = single {
            let slot = self.spare_slot(keep);
            self.runs[slot] = Some(Run {
                anchor: anchor_of(m),
                rate: Some(rate),
                members: 2,
                evidence: 1,
                stamp,
            });
        }
        Verdict::Started
    }

    /// A free slot, else the one whose run has the least evidence (the
    /// fewest members, the oldest, of those), never the just-started ones
    /// nor `keep`.
    fn spare_slot(&self, keep: Option<usize>) -> usize {
        (0..CANDIDATE_RUNS)
            .filter(|&i| Some(i) != keep)
            .filter(|&i| self.runs[i].as_ref().is_none_or(|r| r.stamp != self.clock))
            .min_by_key(|&i| {
                self.runs[i]
                    .as_ref()
                    .map_or((0, 0, 0), |r| (r.evidence, r.members, r.stamp))
            })
            .unwrap_or(0)
    }

    /// How the measurement relates to a run (None: it does not join it),
    /// and the rate of the link it would make.
    fn link(
        &self,
        run: &Run<N, M>,
        m: &Update<'_, N, M>,
        hph: &OMatrix<f64, M, M>,
    ) -> Option<(Link, Rate<M>)> {
        let a = &run.anchor;
        let (d, c) = difference(a, m, hph);
        let interval_s = a.age_s;
        let rate = if interval_s > 0.0 {
            Rate {
                rate: &d / interval_s,
                covariance: &c / (interval_s * interval_s),
                interval_s,
            }
        } else {
            Rate {
                rate: d.clone(),
                covariance: c.clone(),
                interval_s: 0.0,
            }
        };
        if self.passes(&d, c) {
            return Some((Link::Agrees, rate));
        }
        match &run.rate {
            // Same rate as the previous link: the prediction is off by a
            // common b. The two links share the anchor's measurement, whose
            // noise enters them with opposite signs.
            Some(prev) if interval_s > 0.0 && prev.interval_s > 0.0 => {
                let delta = &rate.rate - &prev.rate;
                let cov = &rate.covariance
                    + &prev.covariance
                    + &a.r * (2.0 / (interval_s * prev.interval_s));
                self.passes(&delta, cov).then_some((Link::Agrees, rate))
            }
            Some(_) => None,
            None => Some((Link::Free, rate)),
        }
    }

    /// `vᵀ C⁻¹ v ≤ χ²_m(p)` (false when C is not positive definite).
    fn passes(&self, v: &OVector<f64, M>, c: OMatrix<f64, M, M>) -> bool {
        Cholesky::new(c).is_some_and(|chol| v.dot(&chol.solve(v)) <= self.threshold)
    }
}

/// H P Hᵀ, symmetrised.
fn projected<N: Dim, M: Dim>(h: &OMatrix<f64, M, N>, p: &OMatrix<f64, N, N>) -> OMatrix<f64, M, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let (md, nd) = h.shape_generic();
    let mut hp = OMatrix::<f64, M, N>::zeros_generic(md, nd);
    dense::gemm(&mut hp, 1.0, h, p, 0.0);
    let mut hph = OMatrix::<f64, M, M>::zeros_generic(md, md);
    dense::gemm_nt(&mut hph, 1.0, &hp, h, 0.0);
    (&hph + hph.transpose()) * 0.5
}

/// The difference d = ν_k − e_anchor and its covariance
/// C = R_k + H P⁻ Hᵀ + (R + H P⁺ Hᵀ)_anchor − H X − Xᵀ Hᵀ (symmetrised),
/// `hph` = H P⁻ Hᵀ of the measurement.
fn difference<N: Dim, M: Dim>(
    anchor: &Anchor<N, M>,
    m: &Update<'_, N, M>,
    hph: &OMatrix<f64, M, M>,
) -> (OVector<f64, M>, OMatrix<f64, M, M>)
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let d = m.residual - &anchor.residual;
    let (md, _) = m.r.shape_generic();
    let mut hx = OMatrix::<f64, M, M>::zeros_generic(md, md);
    dense::gemm(&mut hx, 1.0, m.h, &anchor.cross, 0.0);
    let c = m.r + hph + &anchor.covariance - &hx - hx.transpose();
    let c = (&c + c.transpose()) * 0.5;
    (d, c)
}

/// The anchor a refused measurement leaves: its residual against the
/// updated state, R, R + H P⁺ Hᵀ, and X = P⁺ Hᵀ.
fn anchor_of<N: Dim, M: Dim>(m: &Update<'_, N, M>) -> Anchor<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let (md, nd) = m.h.shape_generic();
    // e = ν − H (x⁺ − x⁻)
    let mut residual = m.residual.clone();
    dense::gemm(&mut residual, -1.0, m.h, m.state_change, 1.0);
    let mut cross = OMatrix::<f64, N, M>::zeros_generic(nd, md);
    dense::gemm_nt(&mut cross, 1.0, m.posterior_covariance, m.h, 0.0);
    let mut covariance = m.r.clone();
    dense::gemm(&mut covariance, 1.0, m.h, &cross, 1.0);
    Anchor {
        residual,
        r: m.r.clone(),
        covariance: (&covariance + covariance.transpose()) * 0.5,
        cross,
        age_s: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Const, Matrix1x2, Matrix2, Matrix2x1, Vector1, Vector2};

    type Detector = AgreementDetector<Const<2>, Const<1>>;

    const DT: f64 = 0.25;
    const ZERO_CHANGE: Vector2<f64> = Vector2::new(0.0, 0.0);
    const ZERO_GAIN: Matrix2x1<f64> = Matrix2x1::new(0.0, 0.0);

    fn config(run_length: usize) -> AgreementConfig {
        AgreementConfig {
            run_length,
            probability: 0.999,
        }
    }

    /// Constant velocity x = (position, velocity), position measured every
    /// DT with σ 0.1; no process noise.
    struct Track {
        p: Matrix2<f64>,
        h: Matrix1x2<f64>,
        r: nalgebra::Matrix1<f64>,
        phi: Matrix2<f64>,
    }

    impl Track {
        fn new() -> Self {
            Self {
                p: Matrix2::new(0.01, 0.0, 0.0, 0.0001),
                h: Matrix1x2::new(1.0, 0.0),
                r: nalgebra::Matrix1::new(0.01),
                phi: Matrix2::new(1.0, DT, 0.0, 1.0),
            }
        }

        /// Propagate one step, refuse a measurement with innovation ν.
        fn refuse(&mut self, d: &mut Detector, nu: f64) -> Verdict {
            self.p = self.phi * self.p * self.phi.transpose();
            d.propagate(&self.phi, DT);
            let nu = Vector1::new(nu);
            d.refused(&Update {
                residual: &nu,
                state_change: &ZERO_CHANGE,
                r: &self.r,
                h: &self.h,
                prior_covariance: &self.p,
                gain: &ZERO_GAIN,
                posterior_covariance: &self.p,
            })
        }
    }

    #[test]
    fn an_agreeing_run_recovers_at_its_length() {
        let mut t = Track::new();
        let mut d = Detector::new(config(4)).unwrap();
        // The truth stepped by 30: every innovation is 30 ± noise (the
        // filter's own prediction moves with the state, so ν stays).
        let v: Vec<Verdict> = [30.05, 29.95, 30.1, 30.0]
            .into_iter()
            .map(|nu| t.refuse(&mut d, nu))
            .collect();
        assert_eq!(
            v,
            [
                Verdict::Started,
                Verdict::Joined { members: 2 },
                Verdict::Joined { members: 3 },
                Verdict::Recover { members: 4 }
            ]
        );
        // The runs are forgotten after a recovery.
        assert_eq!(d.longest_run(), 0);
    }

    /// Outliers of every size and sign agree with nothing, neither in
    /// offset nor in rate: a second one may join a first without evidence,
    /// but no run reaches three.
    #[test]
    fn alternating_outliers_never_recover() {
        let mut t = Track::new();
        let mut d = Detector::new(config(3)).unwrap();
        for k in 0..40 {
            let nu = if k % 2 == 0 { 1.0 } else { -1.0 } * (5.0 + 2.2 * k as f64);
            let v = t.refuse(&mut d, nu);
            assert!(
                matches!(v, Verdict::Started | Verdict::Joined { members: 2 }),
                "{k}: {v:?}"
            );
        }
        assert!(d.longest_run() <= 2);
    }

    /// Good measurements accepted between equal outliers: each acceptance
    /// ends the runs, so even identical outliers never make a recovery.
    #[test]
    fn acceptances_between_outliers_end_every_run() {
        let mut t = Track::new();
        let mut d = Detector::new(config(2)).unwrap();
        for k in 0..20 {
            assert_eq!(t.refuse(&mut d, 25.0), Verdict::Started, "{k}");
            d.accepted();
        }
    }

    #[test]
    fn outliers_amid_a_step_do_not_break_its_run() {
        let mut t = Track::new();
        let mut d = Detector::new(config(4)).unwrap();
        let stream = [30.0, -12.0, 30.05, 77.0, 29.9, 30.02];
        let v: Vec<Verdict> = stream.into_iter().map(|nu| t.refuse(&mut d, nu)).collect();
        assert_eq!(v[2], Verdict::Joined { members: 2 });
        assert_eq!(v[4], Verdict::Joined { members: 3 });
        assert_eq!(v[5], Verdict::Recover { members: 4 });
    }

    /// A diverged filter: its velocity is off by 2 (per s) and it does not
    /// know (σ_v 0.01), so every innovation grows by 0.5 a step and no pair
    /// passes the first test. The rates agree: the run recovers with one
    /// member more than with a healthy filter (the second joins without
    /// evidence). Random outliers at the same sizes never do.
    #[test]
    fn a_diverged_filter_recovers_by_the_common_rate() {
        let mut t = Track::new();
        let mut d = Detector::new(config(4)).unwrap();
        let v: Vec<Verdict> = (0..5)
            .map(|k| t.refuse(&mut d, 3.0 + 0.5 * k as f64 + 0.01 * (k as f64).sin()))
            .collect();
        assert_eq!(
            v,
            [
                Verdict::Started,
                Verdict::Started, // and a branch of two, without evidence
                Verdict::Joined { members: 3 },
                Verdict::Joined { members: 4 },
                Verdict::Recover { members: 5 }
            ]
        );
        let mut t = Track::new();
        let mut d = Detector::new(config(4)).unwrap();
        for k in 0..30 {
            let nu = 3.0 + 0.5 * k as f64 + [0.0, 7.0, -4.0, 11.0, -9.0][k % 5];
            assert!(
                !matches!(t.refuse(&mut d, nu), Verdict::Recover { .. }),
                "{k}"
            );
        }
    }

    /// The test scales with the filter's own uncertainty of the predicted
    /// change: the same 0.5 disagreement between the first two measurements
    /// one step apart is consistent when the velocity is uncertain (σ_v = 4,
    /// 1 over the step) and not when it is known (σ_v = 0.04); R alone
    /// (σ 0.1) would refuse both. (The second measurement that fails starts
    /// its own run and a branch of two without evidence.)
    #[test]
    fn the_pairwise_test_uses_the_predicted_change_and_its_covariance() {
        for (velocity_var, agrees) in [(16.0, true), (16e-4, false)] {
            let mut t = Track::new();
            t.p[(1, 1)] = velocity_var;
            let mut d = Detector::new(config(5)).unwrap();
            t.refuse(&mut d, 10.0);
            let v = t.refuse(&mut d, 10.5);
            let most = d.runs.iter().flatten().map(|r| r.evidence).max();
            if agrees {
                assert_eq!((v, most), (Verdict::Joined { members: 2 }, Some(2)));
            } else {
                assert_eq!((v, most, d.longest_run()), (Verdict::Started, Some(1), 2));
            }
        }
    }

    /// The covariance of the difference against an oracle: the filter's
    /// state augmented with the anchor's H δx⁺, propagated and updated as
    /// one (block Φ, the other update's gain acting on the filter part
    /// only); C − R_k − R_anchor must be `[H, −1] A [H, −1]ᵀ`.
    #[test]
    fn the_cross_covariance_matches_the_augmented_state() {
        let p_a = Matrix2::new(0.3, 0.1, 0.1, 0.2);
        let h = Matrix1x2::new(1.0, 0.0);
        let r = nalgebra::Matrix1::new(0.01);
        let phi = Matrix2::new(1.0, 0.5, 0.0, 0.9);
        let q = Matrix2::new(0.01, 0.0, 0.0, 0.02);
        // Augmented covariance of (δx, H δx_a).
        let mut a = nalgebra::Matrix3::zeros();
        a.fixed_view_mut::<2, 2>(0, 0).copy_from(&p_a);
        let ph = p_a * h.transpose();
        a.fixed_view_mut::<2, 1>(0, 2).copy_from(&ph);
        a.fixed_view_mut::<1, 2>(2, 0).copy_from(&ph.transpose());
        a[(2, 2)] = (h * ph)[0];
        let mut d = Detector::new(config(5)).unwrap();
        let nu = Vector1::new(3.0);
        d.refused(&Update {
            residual: &nu,
            state_change: &ZERO_CHANGE,
            r: &r,
            h: &h,
            prior_covariance: &p_a,
            gain: &ZERO_GAIN,
            posterior_covariance: &p_a,
        });
        let mut phi_aug = nalgebra::Matrix3::identity();
        phi_aug.fixed_view_mut::<2, 2>(0, 0).copy_from(&phi);
        let mut q_aug = nalgebra::Matrix3::zeros();
        q_aug.fixed_view_mut::<2, 2>(0, 0).copy_from(&q);
        // Propagate, a velocity update (any gain), propagate.
        let hv = Matrix1x2::new(0.0, 1.0);
        let kv = Matrix2x1::new(0.2, 0.6);
        let rv = 0.05;
        a = phi_aug * a * phi_aug.transpose() + q_aug;
        d.propagate(&phi, 0.5);
        let mut kh = nalgebra::Matrix3::zeros();
        kh.fixed_view_mut::<2, 2>(0, 0).copy_from(&(kv * hv));
        let i_kh = nalgebra::Matrix3::identity() - kh;
        let k_aug = nalgebra::Vector3::new(kv[0], kv[1], 0.0);
        a = i_kh * a * i_kh.transpose() + k_aug * rv * k_aug.transpose();
        d.updated(&kv, &hv);
        a = phi_aug * a * phi_aug.transpose() + q_aug;
        d.propagate(&phi, 0.5);
        let p_k = a.fixed_view::<2, 2>(0, 0).into_owned();
        let nu_k = Vector1::new(3.2);
        let m = Update {
            residual: &nu_k,
            state_change: &ZERO_CHANGE,
            r: &r,
            h: &h,
            prior_covariance: &p_k,
            gain: &ZERO_GAIN,
            posterior_covariance: &p_k,
        };
        let anchor = &d.runs.iter().flatten().next().unwrap().anchor;
        assert_eq!(anchor.age_s, 1.0);
        let (diff, c) = difference(anchor, &m, &projected(&h, &p_k));
        let w = nalgebra::RowVector3::new(1.0, 0.0, -1.0);
        let oracle = (w * a * w.transpose())[0] + 2.0 * r[0];
        assert!((diff[0] - 0.2).abs() < 1e-12);
        assert!((c[0] - oracle).abs() < 1e-12, "{} vs {oracle}", c[0]);
        // The difference is not the covariance of the two alone.
        assert!((c[0] - (p_k[(0, 0)] + p_a[(0, 0)] + 2.0 * r[0])).abs() > 0.1);
    }

    #[test]
    fn limited_updates_leave_the_residual_against_the_updated_state() {
        // A limited update that moved the state by K ν_lim: the next
        // measurement's innovation is smaller by H K ν_lim, and it agrees.
        let h = Matrix1x2::new(1.0, 0.0);
        let r = nalgebra::Matrix1::new(0.01);
        let p = Matrix2::new(0.01, 0.0, 0.0, 1e-4);
        let gain = Matrix2x1::new(0.5, 0.0);
        let nu = Vector1::new(30.0);
        let moved = gain * Vector1::new(2.0); // K ν_lim
        let i_kh = Matrix2::identity() - gain * h;
        let p_after = i_kh * p * i_kh.transpose() + gain * r * gain.transpose();
        let mut d = Detector::new(config(3)).unwrap();
        let first = Update {
            residual: &nu,
            state_change: &moved,
            r: &r,
            h: &h,
            prior_covariance: &p,
            gain: &gain,
            posterior_covariance: &p_after,
        };
        assert_eq!(d.refused(&first), Verdict::Started);
        // The state moved by 1.0 towards the measurement: ν = 29.
        let nu2 = Vector1::new(29.02);
        let second = Update {
            residual: &nu2,
            state_change: &ZERO_CHANGE,
            gain: &ZERO_GAIN,
            prior_covariance: &p_after,
            posterior_covariance: &p_after,
            ..first
        };
        d.refused(&second);
        let run = d.runs.iter().flatten().next().unwrap();
        assert_eq!((run.members, run.evidence), (2, 2));
    }

    /// Another stream's reset of state 1 (velocity): the runs keep their
    /// anchors, their cross-covariances lose row 1.
    #[test]
    fn decorrelate_zeroes_the_reset_rows_of_every_run() {
        let mut t = Track::new();
        t.p = Matrix2::new(0.02, 0.01, 0.01, 0.03);
        let mut d = Detector::new(config(5)).unwrap();
        t.refuse(&mut d, 1.0);
        let before = d.runs.iter().flatten().next().unwrap().anchor.cross;
        assert!(before[0] != 0.0 && before[1] != 0.0);
        d.decorrelate(1, 1);
        let run = d.runs.iter().flatten().next().unwrap();
        assert_eq!((run.anchor.cross[0], run.anchor.cross[1]), (before[0], 0.0));
        assert_eq!(run.members, 1);
        // Out-of-range rows are ignored.
        d.decorrelate(5, 3);
    }

    #[test]
    fn invalid_configurations_are_refused() {
        assert!(Detector::new(config(1)).is_none());
        let bad = AgreementConfig {
            run_length: 3,
            probability: 1.0,
        };
        assert!(Detector::new(bad).is_none());
    }
}
