//! Classical robust pre-filters of a scalar measurement series, the
//! baselines seed 004 lists beside the adaptive filters ("медианный фильтр,
//! процедура Тьюки 53Х"): a running median and Tukey's 53H smoother. Each
//! is causal — it sees the samples up to the current one — and turns the
//! raw series into the one a filter is fed.
//!
//! Both keep their last samples in a buffer allocated once; a gap in the
//! series ([`RunningMedian::clear`], [`Tukey53H::clear`]) starts afresh.
//!
//! Tukey's 53H (Tukey, *Exploratory Data Analysis*, 1977; Velleman,
//! "Definition and comparison of robust nonlinear data smoothing
//! algorithms", JASA 75, 1980): a running median of 5, a running median of
//! 3 of those, then the Hanning weights ¼, ½, ¼. Computed on the trailing
//! nine samples it is the smoothed value four samples back (each stage
//! centred: 2 + 1 + 1); a spike shorter than three samples does not pass
//! the median of 5.

/// The median of a short slice (sorted in `scratch`; even lengths: the
/// mean of the two middle values). NaN for an empty slice.
fn median_of(values: &[f64], scratch: &mut [f64]) -> f64 {
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    let s = &mut scratch[..n];
    s.copy_from_slice(values);
    s.sort_by(f64::total_cmp);
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// The last `capacity` samples in time order, in a fixed buffer.
#[derive(Debug, Clone)]
struct Window {
    samples: Vec<f64>,
    capacity: usize,
}

impl Window {
    fn new(capacity: usize) -> Self {
        Self {
            samples: Vec::with_capacity(capacity),
            capacity,
        }
    }

    fn push(&mut self, v: f64) {
        if self.samples.len() == self.capacity {
            // Short windows (≤ a few tens): shifting is cheaper than a ring's
            // index arithmetic for the slices the medians need.
            self.samples.remove(0);
        }
        self.samples.push(v);
    }
}

/// Causal running median of the last `window` samples (fewer at the
/// start or after a gap).
///
/// ```
/// use aidnav_estimation::prefilter::RunningMedian;
/// let mut m = RunningMedian::new(5).unwrap();
/// let out: Vec<f64> = [1.0, 2.0, 90.0, 3.0, 4.0].iter().map(|&z| m.filter(z)).collect();
/// assert_eq!(out, [1.0, 1.5, 2.0, 2.5, 3.0]); // the spike never passes
/// ```
#[derive(Debug, Clone)]
pub struct RunningMedian {
    window: Window,
    scratch: Vec<f64>,
}

impl RunningMedian {
    /// A running median over `window ≥ 1` samples (None for 0).
    pub fn new(window: usize) -> Option<Self> {
        (window >= 1).then(|| Self {
            window: Window::new(window),
            scratch: vec![0.0; window],
        })
    }

    /// Take sample `z` and return the median of the window ending with it.
    pub fn filter(&mut self, z: f64) -> f64 {
        self.window.push(z);
        median_of(&self.window.samples, &mut self.scratch)
    }

    /// Forget the samples (a gap in the series).
    pub fn clear(&mut self) {
        self.window.samples.clear();
    }
}

/// Samples the trailing 53H needs: 5 + 2 + 2 (each median of 3 needs three
/// medians of 5, the Hanning three medians of 3).
const TUKEY_SPAN: usize = 9;

/// Causal Tukey 53H smoother: the 53H value of the trailing nine samples
/// (four samples of delay). Until nine samples are in (the start, after a
/// gap) the running median of what there is.
///
/// ```
/// use aidnav_estimation::prefilter::Tukey53H;
/// let mut t = Tukey53H::new();
/// let ramp: Vec<f64> = (0..12).map(|k| k as f64).collect();
/// let out: Vec<f64> = ramp.iter().map(|&z| t.filter(z)).collect();
/// assert_eq!(out[8..], [4.0, 5.0, 6.0, 7.0]); // a ramp comes out four samples late
/// ```
#[derive(Debug, Clone)]
pub struct Tukey53H {
    window: Window,
    scratch: Vec<f64>,
}

impl Default for Tukey53H {
    fn default() -> Self {
        Self::new()
    }
}

impl Tukey53H {
    /// An empty smoother.
    pub fn new() -> Self {
        Self {
            window: Window::new(TUKEY_SPAN),
            scratch: vec![0.0; TUKEY_SPAN],
        }
    }

    /// Take sample `z` and return the smoothed value.
    pub fn filter(&mut self, z: f64) -> f64 {
        self.window.push(z);
        let x = &self.window.samples;
        if x.len() < TUKEY_SPAN {
            return median_of(x, &mut self.scratch);
        }
        // Medians of 5 ending at samples 4 … 8, medians of 3 of those,
        // then ¼ ½ ¼.
        let mut m5 = [0.0; 5];
        for (j, m) in m5.iter_mut().enumerate() {
            *m = median_of(&x[j..j + 5], &mut self.scratch);
        }
        let mut m3 = [0.0; 3];
        for (i, m) in m3.iter_mut().enumerate() {
            *m = median_of(&m5[i..i + 3], &mut self.scratch);
        }
        0.25 * m3[0] + 0.5 * m3[1] + 0.25 * m3[2]
    }

    /// Forget the samples (a gap in the series).
    pub fn clear(&mut self) {
        self.window.samples.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_of_odd_and_even_windows() {
        let mut s = [0.0; 4];
        assert_eq!(median_of(&[3.0, 1.0, 2.0], &mut s), 2.0);
        assert_eq!(median_of(&[4.0, 1.0, 3.0, 2.0], &mut s), 2.5);
        assert!(median_of(&[], &mut s).is_nan());
        assert!(RunningMedian::new(0).is_none());
    }

    /// A window of 5 removes spikes of up to two samples and keeps a
    /// constant; a step passes after three samples (the median's
    /// majority); `clear` starts afresh.
    #[test]
    fn the_running_median_removes_short_spikes() {
        let mut m = RunningMedian::new(5).unwrap();
        let z = [1.0, 1.0, 1.0, 1.0, 50.0, 50.0, 1.0, 1.0, 1.0];
        let out: Vec<f64> = z.iter().map(|&v| m.filter(v)).collect();
        assert!(out.iter().all(|&v| v == 1.0), "{out:?}");
        let mut m = RunningMedian::new(5).unwrap();
        let step: Vec<f64> = [0.0; 5]
            .iter()
            .chain(&[1.0; 5])
            .map(|&v| m.filter(v))
            .collect();
        assert_eq!(step[5..], [0.0, 0.0, 1.0, 1.0, 1.0]);
        m.clear();
        assert_eq!(m.filter(7.0), 7.0);
    }

    /// 53H against a hand computation: a spike of two samples on a
    /// constant is removed entirely; a ramp is reproduced four samples
    /// late (every median of a monotone window is its middle value, and the
    /// Hanning weights of a line give its centre); at sample k of a
    /// parabola j²: the medians of 5 ending at j are (j−2)², the medians of
    /// 3 of those ending at j are (j−3)², and the Hanning of the last three,
    /// ¼(k−5)² + ½(k−4)² + ¼(k−3)², is (k−4)² + ½ — four samples late,
    /// plus the curvature's half.
    #[test]
    fn tukey_53h_matches_hand_computations() {
        let mut t = Tukey53H::new();
        let spike = [2.0, 2.0, 2.0, 2.0, 2.0, 9.0, 9.0, 2.0, 2.0, 2.0, 2.0, 2.0];
        let out: Vec<f64> = spike.iter().map(|&v| t.filter(v)).collect();
        assert!(out[8..].iter().all(|&v| v == 2.0), "{out:?}");
        let mut t = Tukey53H::new();
        let out: Vec<f64> = (0..15).map(|k| t.filter(f64::from(k) * 0.5)).collect();
        for (k, v) in out.iter().enumerate().skip(8) {
            assert!((v - (k as f64 - 4.0) * 0.5).abs() < 1e-12);
        }
        let mut t = Tukey53H::new();
        let mut last = 0.0;
        for k in 0..=12 {
            last = t.filter(f64::from(k * k));
        }
        assert!((last - (64.0 + 0.5)).abs() < 1e-12, "{last}"); // k = 12
        // Before nine samples: the running median; after `clear` too.
        t.clear();
        assert_eq!(t.filter(3.0), 3.0);
        assert_eq!(t.filter(5.0), 4.0);
    }
}
