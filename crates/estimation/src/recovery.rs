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
//! measurements k−1, k agree when the change the filter predicts for the
//! measured quantity between them matches the change the measurements
//! show. With ν_k = z_k − H_k x⁻_k the innovation of measurement k and
//! e_{k−1} = ν_{k−1} − H_{k−1} (x⁺_{k−1} − x⁻_{k−1}) the residual of
//! measurement k−1 against the state its update left (ν itself when it was
//! rejected), the difference
//!
//! ```text
//! d = ν_k − e_{k−1}
//! ```
//!
//! is (predicted change) − (measured change) up to sign: it is zero-mean
//! under "the measurements are right" whatever the state's error, since a
//! common error cancels. Its covariance, with δx the estimation error, is
//!
//! ```text
//! C = R_k + R_{k−1} + H_k P⁻_k H_kᵀ + H_{k−1} P⁺_{k−1} H_{k−1}ᵀ − H_k X − Xᵀ H_kᵀ,
//! X = Cov(δx_k⁻, H_{k−1} δx⁺_{k−1})
//! ```
//!
//! and the pair agrees when `dᵀ C⁻¹ d ≤ χ²_m(p)`. The cross-covariance X
//! starts at `P⁺_{k−1} H_{k−1}ᵀ` and follows the filter: `X ← Φ X` at each
//! time update, `X ← (I − K H) X` at each other measurement update (the
//! error of any update is `(I − K H) δx⁻ − K v` for any gain K, v
//! independent of the past). So a moving vehicle is handled by the filter's
//! own predicted displacement, and C grows with the filter's uncertainty
//! between the two measurements.
//!
//! A run is the measurements that agree pairwise in sequence; a measurement
//! that agrees with no run (an outlier amid a genuine step) starts a run of
//! its own in a spare slot without breaking the others, so interleaved
//! outliers cannot hold off a recovery for ever, and alternating outliers
//! (which agree with nothing) never produce one. An accepted measurement
//! ends every run (the filter agrees with the stream again).
//!
//! The detector knows nothing about what the states mean; the reset itself
//! (which states, to what, with what covariance) is the caller's.
//!
//! ```
//! use aidnav_estimation::recovery::{AgreementConfig, AgreementDetector, Refused, Verdict};
//! use aidnav_estimation::nalgebra::{Const, Matrix1, Vector1};
//!
//! // A scalar random constant x, measured directly with σ = 0.1: the truth
//! // jumps by 50 while the filter is sure of itself (σ = 0.01), so a gate
//! // refuses every measurement. The refused measurements agree with each
//! // other, and the third one completes a run of three.
//! let cfg = AgreementConfig { run_length: 3, probability: 0.999 };
//! let mut detector = AgreementDetector::<Const<1>, Const<1>>::new(cfg).unwrap();
//! let (h, r, p) = (Matrix1::new(1.0), Matrix1::new(0.01), Matrix1::new(1e-4));
//! let zero_gain = Matrix1::new(0.0);
//! let mut verdicts = Vec::new();
//! for z in [50.05, 49.98, 50.02] {
//!     let nu = Vector1::new(z); // z − H x with x = 0
//!     verdicts.push(detector.refused(&Refused {
//!         residual: &nu, applied_residual: &nu, r: &r, h: &h,
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

/// Runs followed at once: one for the stream's true step and spares for
/// the outliers interleaved with it (each of which agrees with nothing and
/// takes a spare slot until a longer run needs it).
pub const CANDIDATE_RUNS: usize = 3;

/// When refused measurements count as agreeing, and how many make a recovery.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgreementConfig {
    /// Refused measurements that must agree in a run (≥ 2).
    pub run_length: usize,
    /// Probability of the χ²(m) quantile the pairwise test uses, in (0, 1).
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
    /// It completes a run of `run_length`: reset the measured states to it.
    /// Every run is forgotten.
    Recover {
        /// Measurements in the run, this one included.
        members: usize,
    },
}

/// One refused measurement as the detector needs it (the filter's update
/// with a rejecting or limiting policy has just been made).
#[derive(Debug)]
pub struct Refused<'a, N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    /// Innovation ν = z − H x⁻ as measured.
    pub residual: &'a OVector<f64, M>,
    /// The innovation the update applied (ν itself, a limited ν, or
    /// anything when `gain` is zero).
    pub applied_residual: &'a OVector<f64, M>,
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
    /// R + H P⁺ Hᵀ of the member.
    covariance: OMatrix<f64, M, M>,
    /// X = Cov(δx now, H δx⁺ of the member), N × m.
    cross: OMatrix<f64, N, M>,
}

#[derive(Debug, Clone)]
struct Run<N: Dim, M: Dim>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    anchor: Anchor<N, M>,
    members: usize,
    /// Order of the last join (larger: more recent).
    stamp: u64,
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
            runs: [None, None, None],
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
        self.runs = [None, None, None];
    }

    /// The stream's measurement was accepted: the filter agrees with it
    /// again, every run ends.
    pub fn accepted(&mut self) {
        self.clear();
    }

    /// The filter's time update `x ← Φ x` (between measurements).
    pub fn propagate(&mut self, phi: &OMatrix<f64, N, N>) {
        for run in self.runs.iter_mut().flatten() {
            let x = &mut run.anchor.cross;
            let mut next = x.clone();
            dense::gemm(&mut next, 1.0, phi, x, 0.0);
            *x = next;
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
    /// update has been made): test it against every run, extend the one it
    /// agrees with (the longest), or start a run; every run's
    /// cross-covariance then follows this update.
    pub fn refused(&mut self, m: &Refused<'_, N, M>) -> Verdict {
        if self.threshold.is_nan() {
            self.threshold = chi2_quantile(m.residual.len(), self.config.probability);
        }
        let joined = self.best_agreeing(m);
        // This update, seen by every run: X ← (I − K H) X.
        self.updated(m.gain, m.h);
        let anchor = anchor_of(m);
        self.clock += 1;
        let stamp = self.clock;
        match joined {
            Some(i) => {
                let members = self.runs[i].as_ref().map_or(0, |r| r.members) + 1;
                if members >= self.config.run_length {
                    self.clear();
                    return Verdict::Recover { members };
                }
                self.runs[i] = Some(Run {
                    anchor,
                    members,
                    stamp,
                });
                Verdict::Joined { members }
            }
            None => {
                // A free slot, else the run with the fewest members (the
                // oldest of those).
                let slot = (0..CANDIDATE_RUNS)
                    .min_by_key(|&i| {
                        self.runs[i]
                            .as_ref()
                            .map_or((0, 0), |r| (r.members, r.stamp))
                    })
                    .unwrap_or(0);
                self.runs[slot] = Some(Run {
                    anchor,
                    members: 1,
                    stamp,
                });
                Verdict::Started
            }
        }
    }

    /// The slot of the run this measurement agrees with (the one with the
    /// most members, the most recent of those), if any.
    fn best_agreeing(&self, m: &Refused<'_, N, M>) -> Option<usize> {
        let hph = projected(m.h, m.prior_covariance);
        let mut best: Option<(usize, (usize, u64))> = None;
        for (i, run) in self.runs.iter().enumerate() {
            let Some(run) = run else { continue };
            let (d, c) = link(&run.anchor, m, &hph);
            let agrees =
                Cholesky::new(c).is_some_and(|chol| d.dot(&chol.solve(&d)) <= self.threshold);
            let key = (run.members, run.stamp);
            if agrees && best.is_none_or(|(_, k)| key > k) {
                best = Some((i, key));
            }
        }
        best.map(|(i, _)| i)
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
fn link<N: Dim, M: Dim>(
    anchor: &Anchor<N, M>,
    m: &Refused<'_, N, M>,
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
/// updated state, R + H P⁺ Hᵀ, and X = P⁺ Hᵀ.
fn anchor_of<N: Dim, M: Dim>(m: &Refused<'_, N, M>) -> Anchor<N, M>
where
    DefaultAllocator: FilterAllocator<N, M>,
{
    let (md, nd) = m.h.shape_generic();
    // e = ν − H K ν_applied
    let mut delta = OMatrix::<f64, N, nalgebra::U1>::zeros_generic(nd, nalgebra::U1);
    dense::gemm(&mut delta, 1.0, m.gain, m.applied_residual, 0.0);
    let mut residual = m.residual.clone();
    dense::gemm(&mut residual, -1.0, m.h, &delta, 1.0);
    let mut cross = OMatrix::<f64, N, M>::zeros_generic(nd, md);
    dense::gemm_nt(&mut cross, 1.0, m.posterior_covariance, m.h, 0.0);
    let mut covariance = m.r.clone();
    dense::gemm(&mut covariance, 1.0, m.h, &cross, 1.0);
    Anchor {
        residual,
        covariance: (&covariance + covariance.transpose()) * 0.5,
        cross,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Const, Matrix1x2, Matrix2, Matrix2x1, Vector1};

    type Detector = AgreementDetector<Const<2>, Const<1>>;

    fn config(run_length: usize) -> AgreementConfig {
        AgreementConfig {
            run_length,
            probability: 0.999,
        }
    }

    /// Constant velocity x = (position, velocity), position measured.
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
                phi: Matrix2::new(1.0, 1.0, 0.0, 1.0),
            }
        }

        /// Propagate one step (no process noise), refuse a measurement with
        /// innovation ν.
        fn refuse(&mut self, d: &mut Detector, nu: f64) -> Verdict {
            self.p = self.phi * self.p * self.phi.transpose();
            d.propagate(&self.phi);
            let nu = Vector1::new(nu);
            d.refused(&Refused {
                residual: &nu,
                applied_residual: &nu,
                r: &self.r,
                h: &self.h,
                prior_covariance: &self.p,
                gain: &Matrix2x1::zeros(),
                posterior_covariance: &self.p,
            })
        }
    }

    #[test]
    fn an_agreeing_run_recovers_at_its_length() {
        let mut t = Track::new();
        let mut d = Detector::new(config(4)).unwrap();
        // The truth stepped by 30: every innovation is 30 ± noise (and the
        // filter's own prediction moves with the state, so ν is constant).
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

    /// Outliers of every size and sign agree with nothing: no run grows.
    #[test]
    fn alternating_outliers_never_recover() {
        let mut t = Track::new();
        let mut d = Detector::new(config(3)).unwrap();
        for k in 0..20 {
            let nu = if k % 2 == 0 { 1.0 } else { -1.0 } * (5.0 + 2.2 * k as f64);
            assert_eq!(t.refuse(&mut d, nu), Verdict::Started, "{k}");
        }
        assert_eq!(d.longest_run(), 1);
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
        assert_eq!(v[1], Verdict::Started);
        assert_eq!(v[2], Verdict::Joined { members: 2 });
        assert_eq!(v[4], Verdict::Joined { members: 3 });
        assert_eq!(v[5], Verdict::Recover { members: 4 });
    }

    /// The test scales with the filter's own uncertainty of the predicted
    /// change: the same 0.5 disagreement between two measurements one step
    /// apart is consistent when the velocity is uncertain (σ_v = 1) and not
    /// when it is known (σ_v = 0.01); R alone (σ 0.1) would refuse both.
    #[test]
    fn the_pairwise_test_uses_the_predicted_change_and_its_covariance() {
        for (velocity_var, agrees) in [(1.0, true), (1e-4, false)] {
            let mut t = Track::new();
            t.p[(1, 1)] = velocity_var;
            let mut d = Detector::new(config(5)).unwrap();
            t.refuse(&mut d, 10.0);
            let v = t.refuse(&mut d, 10.5);
            assert_eq!(
                v == Verdict::Joined { members: 2 },
                agrees,
                "{velocity_var}"
            );
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
        d.refused(&Refused {
            residual: &nu,
            applied_residual: &nu,
            r: &r,
            h: &h,
            prior_covariance: &p_a,
            gain: &Matrix2x1::zeros(),
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
        d.propagate(&phi);
        let mut kh = nalgebra::Matrix3::zeros();
        kh.fixed_view_mut::<2, 2>(0, 0).copy_from(&(kv * hv));
        let i_kh = nalgebra::Matrix3::identity() - kh;
        let k_aug = nalgebra::Vector3::new(kv[0], kv[1], 0.0);
        a = i_kh * a * i_kh.transpose() + k_aug * rv * k_aug.transpose();
        d.updated(&kv, &hv);
        a = phi_aug * a * phi_aug.transpose() + q_aug;
        d.propagate(&phi);
        let p_k = a.fixed_view::<2, 2>(0, 0).into_owned();
        let nu_k = Vector1::new(3.2);
        let m = Refused {
            residual: &nu_k,
            applied_residual: &nu_k,
            r: &r,
            h: &h,
            prior_covariance: &p_k,
            gain: &Matrix2x1::zeros(),
            posterior_covariance: &p_k,
        };
        let anchor = &d.runs.iter().flatten().next().unwrap().anchor;
        let (diff, c) = link(anchor, &m, &projected(&h, &p_k));
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
        // measurement's innovation is smaller by H K ν_lim, and it still agrees.
        let h = Matrix1x2::new(1.0, 0.0);
        let r = nalgebra::Matrix1::new(0.01);
        let p = Matrix2::new(0.01, 0.0, 0.0, 1e-4);
        let gain = Matrix2x1::new(0.5, 0.0);
        let nu = Vector1::new(30.0);
        let limited = Vector1::new(2.0);
        let p_after =
            (Matrix2::identity() - gain * h) * p * (Matrix2::identity() - gain * h).transpose()
                + gain * r * gain.transpose();
        let mut d = Detector::new(config(3)).unwrap();
        let first = Refused {
            residual: &nu,
            applied_residual: &limited,
            r: &r,
            h: &h,
            prior_covariance: &p,
            gain: &gain,
            posterior_covariance: &p_after,
        };
        assert_eq!(d.refused(&first), Verdict::Started);
        // The state moved by 1.0 towards the measurement: ν = 29.
        let nu2 = Vector1::new(29.02);
        let second = Refused {
            residual: &nu2,
            applied_residual: &nu2,
            gain: &Matrix2x1::zeros(),
            prior_covariance: &p_after,
            posterior_covariance: &p_after,
            ..first
        };
        assert_eq!(d.refused(&second), Verdict::Joined { members: 2 });
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
