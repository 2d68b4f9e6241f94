//! Spec 30 at scale: one axis of a group of hundreds to thousands of
//! vehicles, the paper's constant-velocity model with a dense covariance,
//! updated in information form ([`aidnav_estimation::SubspaceUpdate`]) from
//! sparse observations — own position (and velocity) fixes, and relative
//! positions to a few neighbours ([`k_nearest`], [`within_range`]).
//!
//! The state is ordered `[R¹ … R^M, V¹ … V^M]` (positions first) so the
//! observed block is contiguous; [`aidnav_models::AxisGroup`] keeps the paper's
//! interleaved order for the small reproduction.
//!
//! ```
//! use aidnav_integration::group::GroupAxisFilter;
//! let mut f = GroupAxisFilter::new(3, 1.0, 1.0, false, &[0.0; 3], &[0.0; 3], 10.0, 5.0).unwrap();
//! f.predict();
//! f.observe_own_position(0, 2.0, 10.0).unwrap();
//! f.observe_relative(0, 1, -50.0, 0.5).unwrap(); // R¹ − R² = −50
//! f.update().unwrap();
//! assert!(f.position_sigma(1) < 10.0); // member 2 gained from member 1's fix
//! ```

use aidnav_estimation::{EstimationError, SparseInformation, SubspaceUpdate};
use aidnav_models::GaussMarkov;
use nalgebra::{DMatrix, DVector, Matrix2, Vector3};

use super::MotionModel;

/// Correlated errors of the members' own fixes on one axis, carried as
/// first-order Gauss–Markov states ([`GroupAxisFilter::with_own_errors`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisOwnErrors {
    /// The own position fixes' correlated error.
    pub position: GaussMarkov,
    /// The own velocity fixes' correlated error (only with own velocity
    /// fixes).
    pub velocity: Option<GaussMarkov>,
}

/// One axis of an M-member group: dense covariance, information-form update.
#[derive(Debug, Clone)]
pub struct GroupAxisFilter {
    members: usize,
    dt_s: f64,
    velocity_variance: f64,
    x: DVector<f64>,
    p: DMatrix<f64>,
    info: SparseInformation,
    update: SubspaceUpdate,
    /// Per own-error state block after `[R, V]` (position block, then
    /// velocity block): its (φ, q) per step.
    own_errors: Vec<(f64, f64)>,
    /// Process noise on each position and its cross term with the
    /// velocity, `(q_RR, q_RV)` ([`MotionModel`]; zero in the paper's).
    position_noise: (f64, f64),
}

impl GroupAxisFilter {
    /// A filter for `members` vehicles with step `dt_s`, acceleration
    /// disturbance `accel_sigma_m_s2` (Q = (a_R T)² on each velocity),
    /// initial positions/velocities and their σ. `observe_velocity` makes the
    /// velocities part of the observed block (own velocity fixes allowed).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        members: usize,
        dt_s: f64,
        accel_sigma_m_s2: f64,
        observe_velocity: bool,
        positions: &[f64],
        velocities: &[f64],
        position_sigma_m: f64,
        velocity_sigma_mps: f64,
    ) -> Result<Self, EstimationError> {
        let n = 2 * members;
        if positions.len() != members || velocities.len() != members {
            return Err(EstimationError::DimensionMismatch {
                step: aidnav_estimation::Step::Initialise,
                matrix: aidnav_estimation::Matrix::X,
                rows: positions.len().max(velocities.len()),
                cols: 1,
                expected_rows: members,
                expected_cols: 1,
            });
        }
        let x = DVector::from_iterator(n, positions.iter().chain(velocities).copied());
        let p = DMatrix::from_diagonal(&DVector::from_fn(n, |i, _| {
            if i < members {
                position_sigma_m.powi(2)
            } else {
                velocity_sigma_mps.powi(2)
            }
        }));
        let block = if observe_velocity { n } else { members };
        Ok(Self {
            members,
            dt_s,
            velocity_variance: (accel_sigma_m_s2 * dt_s).powi(2),
            x,
            p,
            info: SparseInformation::new(block),
            update: SubspaceUpdate::new(n, block),
            own_errors: Vec::new(),
            position_noise: (0.0, 0.0),
        })
    }

    /// The same filter with the motion model `motion` (the acceleration
    /// disturbance and step of [`Self::new`]).
    pub fn with_motion(self, motion: MotionModel) -> Self {
        let a = self.velocity_variance.sqrt() / self.dt_s;
        let (q_rr, q_rv, _) = motion.process_noise(a, self.dt_s);
        Self {
            position_noise: (q_rr, q_rv),
            ..self
        }
    }

    /// The state extended by `steps.len()` own-error blocks of M states
    /// after `[R, V]`, zero mean and zero covariance; each block's (φ, q)
    /// per step from `steps`. Every state is then observed.
    fn extended(self, steps: Vec<(f64, f64)>) -> Self {
        let m = self.members;
        let n = 2 * m + m * steps.len();
        let mut x = DVector::zeros(n);
        x.rows_mut(0, 2 * m).copy_from(&self.x.rows(0, 2 * m));
        let mut p = DMatrix::zeros(n, n);
        p.view_mut((0, 0), (2 * m, 2 * m))
            .copy_from(&self.p.view((0, 0), (2 * m, 2 * m)));
        Self {
            x,
            p,
            info: SparseInformation::new(n),
            update: SubspaceUpdate::new(n, n),
            own_errors: steps,
            ..self
        }
    }

    /// The same filter with the whole error of each member's own fixes as
    /// states `[b_R, b_V]` (state `[R, V, b_R, b_V]`), started at
    /// `initial[l]` (the 2×2 covariance of member l's position and velocity
    /// error on this axis) and moved each step by
    /// [`Self::transition_own_errors`] (no transition of their own): an own
    /// fix observes `R + b_R` (`V + b_V`).
    pub fn with_reported_own_errors(self, initial: &[Matrix2<f64>]) -> Self {
        let m = self.members;
        let mut f = self.extended(vec![(1.0, 0.0); 2]);
        for (l, c) in initial.iter().enumerate().take(m) {
            let (r, v) = (2 * m + l, 3 * m + l);
            f.p[(r, r)] = c[(0, 0)];
            f.p[(v, v)] = c[(1, 1)];
            f.p[(r, v)] = c[(0, 1)];
            f.p[(v, r)] = c[(1, 0)];
        }
        f
    }

    /// After [`Self::predict`], move each member's own-error states
    /// `[b_R, b_V]` by its `(A, Q)`: b ← A b + w, Cov(w) = Q (only with
    /// [`Self::with_reported_own_errors`]; one pair per member).
    pub fn transition_own_errors(
        &mut self,
        per_member: &[(Matrix2<f64>, Matrix2<f64>)],
    ) -> Result<(), EstimationError> {
        let m = self.members;
        if self.own_errors.len() != 2 || per_member.len() != m {
            return Err(EstimationError::DimensionMismatch {
                step: aidnav_estimation::Step::Predict,
                matrix: aidnav_estimation::Matrix::Phi,
                rows: 2 * per_member.len(),
                cols: 2 * per_member.len(),
                expected_rows: 2 * m,
                expected_cols: 2 * m,
            });
        }
        let n = self.x.len();
        let p = &mut self.p;
        for (l, (a, q)) in per_member.iter().enumerate() {
            let (r, v) = (2 * m + l, 3 * m + l);
            let (xr, xv) = (self.x[r], self.x[v]);
            self.x[r] = a[(0, 0)] * xr + a[(0, 1)] * xv;
            self.x[v] = a[(1, 0)] * xr + a[(1, 1)] * xv;
            // P ← G P Gᵀ with G the identity but for this member's block:
            // rows, then columns.
            for j in 0..n {
                let (pr, pv) = (p[(r, j)], p[(v, j)]);
                p[(r, j)] = a[(0, 0)] * pr + a[(0, 1)] * pv;
                p[(v, j)] = a[(1, 0)] * pr + a[(1, 1)] * pv;
            }
            for i in 0..n {
                let (pr, pv) = (p[(i, r)], p[(i, v)]);
                p[(i, r)] = a[(0, 0)] * pr + a[(0, 1)] * pv;
                p[(i, v)] = a[(1, 0)] * pr + a[(1, 1)] * pv;
            }
            p[(r, r)] += q[(0, 0)];
            p[(r, v)] += q[(0, 1)];
            p[(v, r)] += q[(1, 0)];
            p[(v, v)] += q[(1, 1)];
        }
        Ok(())
    }

    /// The same filter with the correlated errors of the own fixes as
    /// states: the state becomes `[R, V, b_R, b_V]` (b_V only with
    /// `errors.velocity`), each b at its stationary σ and zero mean, and an
    /// own fix observes `R + b_R` (`V + b_V`). Every state is then observed,
    /// so the information-form update covers the whole state.
    pub fn with_own_errors(self, errors: AxisOwnErrors) -> Self {
        let m = self.members;
        let blocks: Vec<GaussMarkov> = std::iter::once(errors.position)
            .chain(errors.velocity)
            .collect();
        let n = 2 * m + m * blocks.len();
        let mut x = DVector::zeros(n);
        x.rows_mut(0, 2 * m).copy_from(&self.x.rows(0, 2 * m));
        let mut p = DMatrix::zeros(n, n);
        p.view_mut((0, 0), (2 * m, 2 * m))
            .copy_from(&self.p.view((0, 0), (2 * m, 2 * m)));
        for (b, gm) in blocks.iter().enumerate() {
            for l in 0..m {
                let i = 2 * m + b * m + l;
                p[(i, i)] = gm.sigma().powi(2);
            }
        }
        Self {
            x,
            p,
            info: SparseInformation::new(n),
            update: SubspaceUpdate::new(n, n),
            own_errors: blocks.iter().map(|gm| gm.discretise(self.dt_s)).collect(),
            ..self
        }
    }

    /// Index of the own-error state of `block` (0 position, 1 velocity) of
    /// member l, if carried.
    fn own_error_index(&self, block: usize, l: usize) -> Option<usize> {
        (block < self.own_errors.len()).then(|| 2 * self.members + block * self.members + l)
    }

    /// Number of members.
    pub fn members(&self) -> usize {
        self.members
    }

    /// Estimated position of member l.
    pub fn position(&self, l: usize) -> f64 {
        self.x[l]
    }

    /// Estimated velocity of member l.
    pub fn velocity(&self, l: usize) -> f64 {
        self.x[self.members + l]
    }

    /// σ of member l's position.
    pub fn position_sigma(&self, l: usize) -> f64 {
        self.p[(l, l)].sqrt()
    }

    /// σ of member l's velocity.
    pub fn velocity_sigma(&self, l: usize) -> f64 {
        let i = self.members + l;
        self.p[(i, i)].sqrt()
    }

    /// The state covariance, ordered `[R¹ … R^M, V¹ … V^M]`.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// Time update `R += V T`, `P = Φ P Φᵀ + Q`, using Φ's block structure
    /// (O(M²) instead of a dense triple product).
    pub fn predict(&mut self) {
        let (m, t) = (self.members, self.dt_s);
        let (xr, xv) = self.x.as_mut_slice().split_at_mut(m);
        for (r, v) in xr.iter_mut().zip(xv.iter()) {
            *r += v * t;
        }
        let p = &mut self.p;
        // P_RR += T (P_RV + P_VR) + T² P_VV; P_RV += T P_VV; P_VV += Q.
        for j in 0..m {
            for i in 0..m {
                let rv = p[(i, m + j)];
                let vr = p[(m + i, j)];
                let vv = p[(m + i, m + j)];
                p[(i, j)] += t * (rv + vr) + t * t * vv;
                p[(i, m + j)] = rv + t * vv;
                p[(m + i, j)] = vr + t * vv;
            }
        }
        let (q_rr, q_rv) = self.position_noise;
        for l in 0..m {
            p[(m + l, m + l)] += self.velocity_variance;
            p[(l, l)] += q_rr;
            p[(l, m + l)] += q_rv;
            p[(m + l, l)] += q_rv;
        }
        // Own-error states b ← φ b: the cross terms with R pick up T times
        // those with V, all of a b's row and column scale by its φ.
        let bias: Vec<(usize, f64, f64)> = self
            .own_errors
            .iter()
            .enumerate()
            .flat_map(|(b, &(phi, q))| (0..m).map(move |l| (2 * m + b * m + l, phi, q)))
            .collect();
        for &(j, phi, _) in &bias {
            self.x[j] *= phi;
            for i in 0..m {
                let rb = (p[(i, j)] + t * p[(m + i, j)]) * phi;
                let vb = p[(m + i, j)] * phi;
                p[(i, j)] = rb;
                p[(j, i)] = rb;
                p[(m + i, j)] = vb;
                p[(j, m + i)] = vb;
            }
        }
        for &(i, phi_i, q) in &bias {
            for &(j, phi_j, _) in &bias {
                p[(i, j)] *= phi_i * phi_j;
            }
            p[(i, i)] += q;
        }
    }

    /// Own position fix of member l.
    pub fn observe_own_position(
        &mut self,
        l: usize,
        z: f64,
        sigma: f64,
    ) -> Result<(), EstimationError> {
        self.observe_own(l, 0, z, sigma)
    }

    /// Own velocity fix of member l (only with `observe_velocity`).
    pub fn observe_own_velocity(
        &mut self,
        l: usize,
        z: f64,
        sigma: f64,
    ) -> Result<(), EstimationError> {
        self.observe_own(l, 1, z, sigma)
    }

    /// Own fix of member l's position (`block` 0) or velocity (1): the
    /// state plus, with own-error states, that block's error state.
    fn observe_own(
        &mut self,
        l: usize,
        block: usize,
        z: f64,
        sigma: f64,
    ) -> Result<(), EstimationError> {
        let state = block * self.members + l;
        match self.own_error_index(block, l) {
            Some(b) => self
                .info
                .add_scalar(&[(state, 1.0), (b, 1.0)], sigma * sigma, z),
            None => self.info.add_scalar(&[(state, 1.0)], sigma * sigma, z),
        }
    }

    /// Relative velocity observation `z = V^l − V^k + n`, σ(n) = `sigma`
    /// (only with `observe_velocity` or own-error states).
    pub fn observe_relative_velocity(
        &mut self,
        l: usize,
        k: usize,
        z: f64,
        sigma: f64,
    ) -> Result<(), EstimationError> {
        let m = self.members;
        self.info
            .add_scalar(&[(m + l, 1.0), (m + k, -1.0)], sigma * sigma, z)
    }

    /// Relative observation `z = R^l − R^k + n`, σ(n) = `sigma`.
    pub fn observe_relative(
        &mut self,
        l: usize,
        k: usize,
        z: f64,
        sigma: f64,
    ) -> Result<(), EstimationError> {
        self.info
            .add_scalar(&[(l, 1.0), (k, -1.0)], sigma * sigma, z)
    }

    /// Apply every observation added since the last update.
    pub fn update(&mut self) -> Result<(), EstimationError> {
        let result = self.update.apply(&mut self.x, &mut self.p, &self.info);
        self.info.clear();
        result
    }
}

/// For each member, the indices of its `k` nearest other members
/// (fewer if the group is smaller), nearest first.
pub fn k_nearest(positions: &[Vector3<f64>], k: usize) -> Vec<Vec<usize>> {
    let mut order: Vec<(f64, usize)> = Vec::with_capacity(positions.len());
    positions
        .iter()
        .enumerate()
        .map(|(l, pl)| {
            order.clear();
            order.extend(
                positions
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != l)
                    .map(|(j, pj)| ((pj - pl).norm_squared(), j)),
            );
            let k = k.min(order.len());
            if k > 0 && k < order.len() {
                order.select_nth_unstable_by(k - 1, |a, b| a.0.total_cmp(&b.0));
            }
            order.truncate(k);
            order.sort_by(|a, b| a.0.total_cmp(&b.0));
            order.iter().map(|&(_, j)| j).collect()
        })
        .collect()
}

/// For each member, the indices of the other members within `range_m`.
pub fn within_range(positions: &[Vector3<f64>], range_m: f64) -> Vec<Vec<usize>> {
    let r2 = range_m * range_m;
    positions
        .iter()
        .enumerate()
        .map(|(l, pl)| {
            positions
                .iter()
                .enumerate()
                .filter(|&(j, pj)| j != l && (pj - pl).norm_squared() <= r2)
                .map(|(j, _)| j)
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use aidnav_estimation::KalmanFilter;
    use aidnav_models::AxisGroup;

    /// The motion model with the position's share of the acceleration and
    /// the own-error states moved by given transitions equal the dense
    /// model (Φ and Q written out) run through the engine's filter.
    #[test]
    fn reported_own_errors_and_acceleration_in_step_match_the_dense_model() {
        let (m, t, a_r) = (2, 0.5, 0.8);
        let init = [
            Matrix2::new(4.0, 0.1, 0.1, 0.01),
            Matrix2::new(9.0, -0.2, -0.2, 0.02),
        ];
        let mut f = GroupAxisFilter::new(m, t, a_r, true, &[0.0, 150.0], &[60.0, 61.0], 10.0, 1.0)
            .unwrap()
            .with_motion(MotionModel::PiecewiseConstantAcceleration)
            .with_reported_own_errors(&init);
        // Dense reference, state [R1 R2 V1 V2 bR1 bR2 bV1 bV2].
        let n = 4 * m;
        let mut p0 = DMatrix::zeros(n, n);
        for l in 0..m {
            p0[(l, l)] = 100.0;
            p0[(m + l, m + l)] = 1.0;
            let (r, v) = (2 * m + l, 3 * m + l);
            p0[(r, r)] = init[l][(0, 0)];
            p0[(v, v)] = init[l][(1, 1)];
            p0[(r, v)] = init[l][(0, 1)];
            p0[(v, r)] = init[l][(1, 0)];
        }
        let x0 = DVector::from_vec(vec![0.0, 150.0, 60.0, 61.0, 0.0, 0.0, 0.0, 0.0]);
        let mut dense = KalmanFilter::new(x0, p0).unwrap();
        for k in 0..6 {
            let trans: Vec<(Matrix2<f64>, Matrix2<f64>)> = (0..m)
                .map(|l| {
                    let s = 0.01 * (k + l) as f64;
                    (
                        Matrix2::new(0.95 - s, 0.3, -0.01, 0.9 + s),
                        Matrix2::new(0.2, 0.01, 0.01, 0.003),
                    )
                })
                .collect();
            f.predict();
            f.transition_own_errors(&trans).unwrap();
            let mut phi = DMatrix::identity(n, n);
            let mut q = DMatrix::zeros(n, n);
            let qa = (a_r * t).powi(2);
            for l in 0..m {
                phi[(l, m + l)] = t;
                q[(l, l)] = qa * t * t / 4.0;
                q[(l, m + l)] = qa * t / 2.0;
                q[(m + l, l)] = qa * t / 2.0;
                q[(m + l, m + l)] = qa;
                let (r, v) = (2 * m + l, 3 * m + l);
                let (a, qb) = trans[l];
                for (i, ii) in [r, v].into_iter().enumerate() {
                    for (j, jj) in [r, v].into_iter().enumerate() {
                        phi[(ii, jj)] = a[(i, j)];
                        q[(ii, jj)] = qb[(i, j)];
                    }
                }
            }
            dense.predict(&phi, &q).unwrap();
            // Own position and velocity fixes and one relative position.
            let zs = [
                (vec![(0, 1.0), (4, 1.0)], 1.0 + k as f64, 0.3),
                (vec![(1, 1.0), (5, 1.0)], 151.0 - k as f64, 0.4),
                (vec![(2, 1.0), (6, 1.0)], 60.1, 0.02),
                (vec![(3, 1.0), (7, 1.0)], 60.9, 0.03),
                (vec![(0, 1.0), (1, -1.0)], -149.5, 0.5),
            ];
            let mut h = DMatrix::zeros(zs.len(), n);
            let mut z = DVector::zeros(zs.len());
            let mut r = DMatrix::zeros(zs.len(), zs.len());
            for (i, (row, zi, sigma)) in zs.iter().enumerate() {
                for &(j, c) in row {
                    h[(i, j)] = c;
                }
                z[i] = *zi;
                r[(i, i)] = sigma * sigma;
            }
            f.observe_own_position(0, z[0], 0.3).unwrap();
            f.observe_own_position(1, z[1], 0.4).unwrap();
            f.observe_own_velocity(0, z[2], 0.02).unwrap();
            f.observe_own_velocity(1, z[3], 0.03).unwrap();
            f.observe_relative(0, 1, z[4], 0.5).unwrap();
            f.update().unwrap();
            dense.update(&z, &h, &r).unwrap();
            let dx = (dense.state() - &f.x).amax();
            let dp = (dense.covariance() - &f.p).amax();
            assert!(dx < 1e-8 && dp < 1e-8, "epoch {k}: {dx:e}, {dp:e}");
        }
    }

    /// The sparse filter with every ordered pair observed equals the paper's
    /// dense model run through the engine's Joseph-form filter.
    #[test]
    fn matches_dense_paper_model() {
        let model = AxisGroup {
            members: 4,
            relative_sigma_m: Some(0.5),
            ..AxisGroup::default()
        };
        let m = model.members;
        let mut sparse =
            GroupAxisFilter::new(m, 1.0, 1.0, false, &[0.0; 4], &[0.0; 4], 10.0, 10.0).unwrap();
        // Interleaved (paper) order for the dense filter.
        let p0 = DMatrix::from_diagonal_element(2 * m, 2 * m, 100.0);
        let mut dense = KalmanFilter::new(DVector::zeros(2 * m), p0).unwrap();
        let (h, r) = model.measurement();
        let pairs = model.relative_pairs();
        for epoch in 0..15 {
            let truth: Vec<f64> = (0..m).map(|l| 10.0 * l as f64 + epoch as f64).collect();
            let own: Vec<f64> = truth
                .iter()
                .enumerate()
                .map(|(l, t)| t + (l as f64 - 1.5))
                .collect();
            let mut z = DVector::zeros(h.nrows());
            for l in 0..m {
                z[l] = own[l];
                sparse.observe_own_position(l, own[l], 10.0).unwrap();
            }
            for (i, &(l, k)) in pairs.iter().enumerate() {
                let zr = truth[l] - truth[k] + 0.1 * (i as f64 - 5.0);
                z[m + i] = zr;
                sparse.observe_relative(l, k, zr, 0.5).unwrap();
            }
            dense
                .predict(&model.transition(), &model.process_noise())
                .unwrap();
            sparse.predict();
            dense.update(&z, &h, &r).unwrap();
            sparse.update().unwrap();
            for l in 0..m {
                let (pd, vd) = (dense.state()[2 * l], dense.state()[2 * l + 1]);
                assert!((pd - sparse.position(l)).abs() < 1e-9, "epoch {epoch}");
                assert!((vd - sparse.velocity(l)).abs() < 1e-9);
                let sd = dense.covariance()[(2 * l, 2 * l)].sqrt();
                assert!((sd - sparse.position_sigma(l)).abs() < 1e-9);
            }
        }
    }

    /// With own-error states the sparse filter equals the augmented model
    /// `[R, V, b_R, b_V]` (Φ with T and the Gauss–Markov φ, Q with (a_R T)²
    /// and σ²(1 − φ²)) run through the engine's Joseph-form filter, with own
    /// fixes R + b_R and V + b_V, relative positions and relative velocities.
    #[test]
    fn own_error_states_match_dense_augmented_model() {
        let (m, t, a) = (3, 1.0, 0.5);
        let pos_gm = GaussMarkov::new(300.0, 2.0).unwrap();
        let vel_gm = GaussMarkov::new(60.0, 0.05).unwrap();
        let r0 = [0.0, 50.0, -40.0];
        let v0 = [1.0, 0.0, 2.0];
        let mut sparse = GroupAxisFilter::new(m, t, a, true, &r0, &v0, 10.0, 1.0)
            .unwrap()
            .with_own_errors(AxisOwnErrors {
                position: pos_gm,
                velocity: Some(vel_gm),
            });
        let n = 4 * m;
        let (fp, qp) = pos_gm.discretise(t);
        let (fv, qv) = vel_gm.discretise(t);
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::zeros(n, n);
        let mut p0 = DVector::zeros(n);
        let mut x0 = DVector::zeros(n);
        for l in 0..m {
            phi[(l, m + l)] = t;
            phi[(2 * m + l, 2 * m + l)] = fp;
            phi[(3 * m + l, 3 * m + l)] = fv;
            q[(m + l, m + l)] = (a * t) * (a * t);
            q[(2 * m + l, 2 * m + l)] = qp;
            q[(3 * m + l, 3 * m + l)] = qv;
            p0[l] = 100.0;
            p0[m + l] = 1.0;
            p0[2 * m + l] = 4.0;
            p0[3 * m + l] = 0.05f64.powi(2);
            x0[l] = r0[l];
            x0[m + l] = v0[l];
        }
        let mut dense =
            aidnav_estimation::DynKalmanFilter::new(x0, DMatrix::from_diagonal(&p0)).unwrap();
        for epoch in 0..12 {
            let e = epoch as f64;
            // (terms, variance, z) of each scalar observation.
            type Row = (Vec<(usize, f64)>, f64, f64);
            let mut rows: Vec<Row> = Vec::new();
            for l in 0..m {
                let zp = r0[l] + v0[l] * e + 0.3 * (l as f64 - e).sin();
                let zv = v0[l] + 0.02 * (e + l as f64).cos();
                sparse.observe_own_position(l, zp, 0.5).unwrap();
                sparse.observe_own_velocity(l, zv, 0.05).unwrap();
                rows.push((vec![(l, 1.0), (2 * m + l, 1.0)], 0.25, zp));
                rows.push((vec![(m + l, 1.0), (3 * m + l, 1.0)], 0.0025, zv));
            }
            for (l, k) in [(0, 1), (1, 2), (2, 0)] {
                let zr = r0[l] - r0[k] + (v0[l] - v0[k]) * e + 0.1 * e.cos();
                let zd = v0[l] - v0[k] + 0.05 * (e + 1.0).sin();
                sparse.observe_relative(l, k, zr, 0.5).unwrap();
                sparse.observe_relative_velocity(l, k, zd, 0.2).unwrap();
                rows.push((vec![(l, 1.0), (k, -1.0)], 0.25, zr));
                rows.push((vec![(m + l, 1.0), (m + k, -1.0)], 0.04, zd));
            }
            if epoch > 0 {
                sparse.predict();
                dense.predict(&phi, &q).unwrap();
            }
            sparse.update().unwrap();
            let mut h = DMatrix::zeros(rows.len(), n);
            let mut r = DMatrix::zeros(rows.len(), rows.len());
            let mut z = DVector::zeros(rows.len());
            for (i, (terms, var, zi)) in rows.iter().enumerate() {
                for &(j, c) in terms {
                    h[(i, j)] = c;
                }
                r[(i, i)] = *var;
                z[i] = *zi;
            }
            dense.update(&z, &h, &r).unwrap();
            let (xs, xd) = (&sparse.x, dense.state());
            assert!((xs - xd).amax() < 1e-8, "epoch {epoch}: state");
            assert!(
                (&sparse.p - dense.covariance()).amax() < 1e-9,
                "epoch {epoch}: P"
            );
        }
        // The correlated errors were estimated, not left at their prior.
        assert!(sparse.p[(2 * m, 2 * m)] < 4.0);
    }

    #[test]
    fn neighbours_are_nearest_first() {
        let p: Vec<Vector3<f64>> = (0..6)
            .map(|i| Vector3::new(i as f64 * i as f64, 0.0, 0.0))
            .collect();
        let nn = k_nearest(&p, 2);
        assert_eq!(nn[0], vec![1, 2]);
        assert_eq!(nn[3], vec![2, 4]);
        assert_eq!(k_nearest(&p[..2], 5)[0], vec![1]);
        let wr = within_range(&p, 4.5);
        assert_eq!(wr[1], vec![0, 2]);
    }
}
