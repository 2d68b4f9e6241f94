//! Windowed NIS monitor: the mean NIS of the last `window` updates against its
//! χ² interval tells whether the filter's S still matches the innovations it
//! sees (too large: noise or dynamics underestimated, a fault; too small:
//! noise overestimated).

use aidnav_estimation::mean_chi2_bounds;
use serde::Serialize;

/// The monitor's judgement after an update.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum NisVerdict {
    /// Fewer than `window` samples so far.
    Filling,
    /// Mean NIS inside its interval.
    Consistent,
    /// Mean NIS above the interval.
    TooLarge,
    /// Mean NIS below the interval.
    TooSmall,
}

/// Sliding-window NIS monitor (ring buffer allocated once).
///
/// ```
/// use aidnav_supervisors::{NisMonitor, NisVerdict};
/// let mut m = NisMonitor::new(10, 0.95).unwrap();
/// for _ in 0..10 { m.push(1.0, 1); }
/// assert_eq!(m.verdict(), NisVerdict::Consistent);
/// for _ in 0..10 { m.push(25.0, 1); }
/// assert_eq!(m.verdict(), NisVerdict::TooLarge);
/// ```
#[derive(Debug, Clone)]
pub struct NisMonitor {
    values: Vec<(f64, usize)>,
    next: usize,
    filled: bool,
    confidence: f64,
}

impl NisMonitor {
    /// A window of `window` ≥ 1 updates, interval at `confidence` in (0, 1).
    pub fn new(window: usize, confidence: f64) -> Option<Self> {
        (window >= 1 && confidence > 0.0 && confidence < 1.0).then(|| Self {
            values: vec![(0.0, 0); window],
            next: 0,
            filled: false,
            confidence,
        })
    }

    /// Record the NIS of one update with its degrees of freedom.
    pub fn push(&mut self, nis: f64, dof: usize) {
        self.values[self.next] = (nis, dof);
        self.next = (self.next + 1) % self.values.len();
        self.filled |= self.next == 0;
    }

    /// Mean NIS over the window and its interval (None while filling).
    pub fn window_mean_and_bounds(&self) -> Option<(f64, (f64, f64))> {
        if !self.filled {
            return None;
        }
        let n = self.values.len();
        let sum: f64 = self.values.iter().map(|v| v.0).sum();
        let dof: usize = self.values.iter().map(|v| v.1).sum();
        // Mean of n samples of total dof: bounds of χ²(dof)/n.
        let (lo, hi) = mean_chi2_bounds(dof, 1, self.confidence);
        Some((sum / n as f64, (lo / n as f64, hi / n as f64)))
    }

    /// Current verdict.
    pub fn verdict(&self) -> NisVerdict {
        match self.window_mean_and_bounds() {
            None => NisVerdict::Filling,
            Some((m, (_, hi))) if m > hi => NisVerdict::TooLarge,
            Some((m, (lo, _))) if m < lo => NisVerdict::TooSmall,
            Some(_) => NisVerdict::Consistent,
        }
    }
}
