//! The raw data a mechanization is fed: IMU samples and GNSS fixes, as the
//! readers of `aidnav-io` produce them (plain data, SI units, GPST seconds
//! since 1970-01-01), and the zero-phase moving average applied to the IMU
//! before filtering.

use nalgebra::Vector3;

pub use aidnav_sensors::{GnssFix, ImuSample};

/// Zero-phase centred moving average over 2·half + 1 samples (shrinking at
/// the ends), by prefix sums (O(n)); offline smoothing of a whole log.
///
/// ```
/// use aidnav_ins::samples::{ImuSample, moving_average};
/// use nalgebra::Vector3;
/// let imu: Vec<ImuSample> = (0..5)
///     .map(|k| ImuSample {
///         time_s: k as f64,
///         specific_force: Vector3::new(k as f64, 0.0, -9.8),
///         angular_rate: Vector3::zeros(),
///     })
///     .collect();
/// let smooth = moving_average(&imu, 1);
/// assert_eq!(smooth[2].specific_force.x, 2.0); // (1 + 2 + 3) / 3
/// assert_eq!(smooth[0].specific_force.x, 0.5); // (0 + 1) / 2 at the end
/// ```
pub fn moving_average(imu: &[ImuSample], half: usize) -> Vec<ImuSample> {
    let mut out = imu.to_vec();
    moving_average_in_place(&mut out, half);
    out
}

/// [`moving_average`] in place: the same values, bit for bit, without a
/// second copy of the samples. The prefix sums are kept only over the
/// window (a ring of `2·half + 2`): sample `k` is overwritten after the
/// sum through sample `k + half` is taken, and no later output reads a
/// sum from before its window, so the memory is the window's, not the
/// log's.
pub fn moving_average_in_place(imu: &mut [ImuSample], half: usize) {
    let n = imu.len();
    // Prefix sum j (the samples before j) sits in slot j % ring; an
    // output reads sums lo and hi with hi − lo ≤ 2·half + 1 < ring.
    let ring = half.saturating_mul(2).saturating_add(2).min(n + 1);
    let mut sums = vec![(Vector3::zeros(), Vector3::zeros()); ring];
    let (mut sum_f, mut sum_w) = (Vector3::zeros(), Vector3::zeros());
    // Prefix sums taken so far: sums 0..=taken are known.
    let mut taken = 0;
    for k in 0..n {
        let lo = k.saturating_sub(half);
        let hi = k.saturating_add(half).saturating_add(1).min(n);
        // In the order of the whole-log prefix sums; samples k.. are
        // still the input.
        while taken < hi {
            sum_f += imu[taken].specific_force;
            sum_w += imu[taken].angular_rate;
            taken += 1;
            sums[taken % ring] = (sum_f, sum_w);
        }
        let m = (hi - lo) as f64;
        let ((f_hi, w_hi), (f_lo, w_lo)) = (sums[hi % ring], sums[lo % ring]);
        imu[k].specific_force = (f_hi - f_lo) / m;
        imu[k].angular_rate = (w_hi - w_lo) / m;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The whole-log formulation: prefix sums of every sample, then each
    /// output from two of them.
    fn moving_average_by_whole_prefix_sums(imu: &[ImuSample], half: usize) -> Vec<ImuSample> {
        let n = imu.len();
        let (mut pf, mut pw) = (vec![Vector3::zeros()], vec![Vector3::zeros()]);
        for s in imu {
            pf.push(pf[pf.len() - 1] + s.specific_force);
            pw.push(pw[pw.len() - 1] + s.angular_rate);
        }
        (0..n)
            .map(|k| {
                let lo = k.saturating_sub(half);
                let hi = (k + half + 1).min(n);
                let m = (hi - lo) as f64;
                ImuSample {
                    time_s: imu[k].time_s,
                    specific_force: (pf[hi] - pf[lo]) / m,
                    angular_rate: (pw[hi] - pw[lo]) / m,
                }
            })
            .collect()
    }

    #[test]
    fn the_window_ring_gives_the_whole_prefix_sums_bits() {
        // xorshift64: samples of mixed magnitudes, so that the sums round.
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for n in [1_usize, 2, 3, 7, 64, 1000] {
            let imu: Vec<ImuSample> = (0..n)
                .map(|k| ImuSample {
                    time_s: k as f64 * 0.01,
                    specific_force: Vector3::new(next() * 20.0, next() * 1e-3, next() - 9.8),
                    angular_rate: Vector3::new(next() * 1e-4, next(), next() * 3.0),
                })
                .collect();
            for half in [0, 1, 2, 5, n / 2, n.saturating_sub(1), n, 3 * n, usize::MAX] {
                let mut ours = imu.clone();
                moving_average_in_place(&mut ours, half);
                let reference = moving_average_by_whole_prefix_sums(&imu, half.min(n));
                let bits = |v: &[ImuSample]| {
                    v.iter()
                        .flat_map(|s| {
                            s.specific_force
                                .iter()
                                .chain(s.angular_rate.iter())
                                .chain([s.time_s].iter())
                                .map(|x| x.to_bits())
                                .collect::<Vec<_>>()
                        })
                        .collect::<Vec<_>>()
                };
                assert_eq!(bits(&ours), bits(&reference), "n = {n}, half = {half}");
            }
        }
    }
}
