//! The registry of robust-estimation schemes: one list, serde-named, of what
//! a filter does with each measurement (its [`MeasurementPolicy`]) and with
//! its process noise (its [`NoiseRule`]). The navigation filter's GNSS
//! policies, the spec-20 anomalies experiment and anyone building on the
//! engine pick schemes from here; adding a scheme is one edit, in this file:
//! a variant of [`Scheme`], its arm in [`Scheme::policy`] (and in
//! [`Scheme::noise_rule`] when it adapts Q), and its place in
//! [`Scheme::ALL`].
//!
//! ```
//! use aidnav_estimation::scheme::{Scheme, SchemeParameters, NoiseRule};
//! use aidnav_estimation::{KalmanFilter, Outcome};
//! use aidnav_estimation::nalgebra::{Matrix1, Vector1, U1};
//!
//! let scheme: Scheme = "rejection".parse().unwrap();
//! assert_eq!(scheme.noise_rule(), NoiseRule::Fixed);
//! let mut policy = scheme.policy::<U1>(&SchemeParameters::default());
//! let mut kf = KalmanFilter::new(Vector1::new(0.0), Matrix1::new(1.0)).unwrap();
//! let (h, r) = (Matrix1::new(1.0), Matrix1::new(1.0));
//! let rec = kf.update_with(&Vector1::new(40.0), &h, &r, &mut policy).unwrap();
//! assert_eq!(rec.outcome, Outcome::Rejected); // νᵀν = 1600 > γ tr S = 18
//! ```

use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim};
use serde::{Deserialize, Serialize};

use crate::adaptive::{AdaptiveGain, AnomalyDetector, DiagonalRule, LimitedAdaptiveGain};
use crate::adaptive::{Limiting, ReacquiringLimiting, Rejection};
use crate::policy::{
    AcceptAll, Chi2Gate, Decision, Huber, InnovationView, MeasurementPolicy, RecoveringChi2Gate,
};

/// A robust-estimation scheme, by the name it has in configuration files,
/// scenario files and tables (`snake_case`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Scheme {
    /// Accept every measurement (the plain Kalman filter).
    Accept,
    /// χ² gate: reject when the NIS exceeds its χ²(m) quantile.
    Chi2Gate,
    /// χ² gate that accepts again after a run of rejections, so it cannot
    /// lock out for good.
    RecoveringGate,
    /// Huber re-weighting: R inflated by √NIS / k above k.
    Huber,
    /// Spec 20 eq. 5 detector (νᵀν > γ tr S) with eq. 6 rejection.
    Rejection,
    /// Spec 20 eq. 5 detector with eq. 8 limiting (the innovation clipped to
    /// the gate, its direction kept).
    Limiting,
    /// Spec 20 eq. 4: the gain from the empirical innovation covariance of
    /// a sliding window when it exceeds the model's.
    AdaptiveGain,
    /// Eq. 4's gain with the eq. 5 detector and eq. 8 limiting.
    LimitedAdaptiveGain,
    /// Spec 20 eq. 9, the developed algorithm: eq. 8 limiting with the
    /// eq. 3 innovation-feedback process noise, fed by normal innovations only.
    Developed,
    /// The developed algorithm made safe on re-acquisition
    /// ([`ReacquiringLimiting`]): eq. 8 limiting while the stream flows,
    /// rejection after a gap until a measurement is accepted, with the
    /// eq. 3 guarded innovation-feedback noise. Meant to run with a
    /// recovery from lock-out ([`recovery`](crate::recovery)).
    Robust,
}

/// What a scheme does to the process noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseRule {
    /// Q as modelled.
    Fixed,
    /// Spec 20 eq. 3: `K ν νᵀ Kᵀ` of the previous update feeds Q; with the
    /// detector an anomalous ν feeds the mean of the last stable terms
    /// instead (eq. 5's guard).
    Feedback {
        /// Guard the feedback with eq. 5's detector.
        detector: bool,
    },
}

/// The tuning constants the schemes read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SchemeParameters {
    /// Probability of the χ² gates' quantile, in (0, 1).
    pub chi2_probability: f64,
    /// Rejections in a row after which the recovering gate accepts again.
    pub recovering_after: usize,
    /// Huber threshold on √NIS, > 0.
    pub huber_k: f64,
    /// Eq. 5's γ: an innovation with νᵀν > γ tr S is anomalous.
    pub anomaly_gamma: f64,
    /// Eq. 4's sliding window, innovations (≥ 1).
    pub adaptive_window: usize,
}

impl Default for SchemeParameters {
    /// χ² 0.999, recovery after 20 rejections, Huber k = 1.345 (95 %
    /// efficiency at the normal, Huber 1964), γ = 9 (spec 20), window 20.
    fn default() -> Self {
        Self {
            chi2_probability: 0.999,
            recovering_after: 20,
            huber_k: 1.345,
            anomaly_gamma: 9.0,
            adaptive_window: 20,
        }
    }
}

impl Scheme {
    /// Every scheme, in the order of the comparison tables.
    pub const ALL: [Scheme; 10] = [
        Scheme::Accept,
        Scheme::Chi2Gate,
        Scheme::RecoveringGate,
        Scheme::Huber,
        Scheme::Rejection,
        Scheme::Limiting,
        Scheme::AdaptiveGain,
        Scheme::LimitedAdaptiveGain,
        Scheme::Developed,
        Scheme::Robust,
    ];

    /// The name in configuration files and tables.
    pub const fn name(self) -> &'static str {
        match self {
            Scheme::Accept => "accept",
            Scheme::Chi2Gate => "chi2_gate",
            Scheme::RecoveringGate => "recovering_gate",
            Scheme::Huber => "huber",
            Scheme::Rejection => "rejection",
            Scheme::Limiting => "limiting",
            Scheme::AdaptiveGain => "adaptive_gain",
            Scheme::LimitedAdaptiveGain => "limited_adaptive_gain",
            Scheme::Developed => "developed",
            Scheme::Robust => "robust",
        }
    }

    /// The scheme's measurement policy for m-dimensional measurements (its
    /// windows allocated once, here).
    ///
    /// # Panics
    /// If `adaptive_window` is 0 for the eq. 4 schemes: callers validate it.
    pub fn policy<M: Dim>(self, p: &SchemeParameters) -> SchemePolicy<M>
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        let detector = AnomalyDetector {
            gamma: p.anomaly_gamma,
        };
        let window = || {
            AdaptiveGain::new(p.adaptive_window, DiagonalRule::All)
                .unwrap_or_else(|| panic!("adaptive_window = 0: validate it (≥ 1)"))
        };
        match self {
            Scheme::Accept => SchemePolicy::Accept(AcceptAll),
            Scheme::Chi2Gate => SchemePolicy::Chi2Gate(Chi2Gate {
                probability: p.chi2_probability,
            }),
            Scheme::RecoveringGate => SchemePolicy::RecoveringGate(RecoveringChi2Gate::new(
                p.chi2_probability,
                p.recovering_after,
            )),
            Scheme::Huber => SchemePolicy::Huber(Huber { k: p.huber_k }),
            Scheme::Rejection => SchemePolicy::Rejection(Rejection { detector }),
            Scheme::Limiting | Scheme::Developed => SchemePolicy::Limiting(Limiting { detector }),
            Scheme::AdaptiveGain => SchemePolicy::AdaptiveGain(window()),
            Scheme::LimitedAdaptiveGain => SchemePolicy::LimitedAdaptiveGain(LimitedAdaptiveGain {
                gain: window(),
                detector,
            }),
            Scheme::Robust => SchemePolicy::Robust(ReacquiringLimiting::new(detector)),
        }
    }

    /// What the scheme does to the process noise.
    pub const fn noise_rule(self) -> NoiseRule {
        match self {
            Scheme::Developed | Scheme::Robust => NoiseRule::Feedback { detector: true },
            _ => NoiseRule::Fixed,
        }
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Scheme {
    type Err = String;

    /// A scheme by its name; the error lists the names.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Scheme::ALL
            .into_iter()
            .find(|scheme| scheme.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Scheme::ALL.iter().map(|s| s.name()).collect();
                format!("unknown scheme {s:?}: one of {}", names.join(", "))
            })
    }
}

/// A scheme's measurement policy, dispatched by value (no allocation, no
/// virtual call).
#[derive(Debug, Clone)]
pub enum SchemePolicy<M: Dim>
where
    DefaultAllocator: Allocator<M, M>,
{
    /// [`Scheme::Accept`].
    Accept(AcceptAll),
    /// [`Scheme::Chi2Gate`].
    Chi2Gate(Chi2Gate),
    /// [`Scheme::RecoveringGate`].
    RecoveringGate(RecoveringChi2Gate),
    /// [`Scheme::Huber`].
    Huber(Huber),
    /// [`Scheme::Rejection`].
    Rejection(Rejection),
    /// [`Scheme::Limiting`] and [`Scheme::Developed`].
    Limiting(Limiting),
    /// [`Scheme::AdaptiveGain`].
    AdaptiveGain(AdaptiveGain<M>),
    /// [`Scheme::LimitedAdaptiveGain`].
    LimitedAdaptiveGain(LimitedAdaptiveGain<M>),
    /// [`Scheme::Robust`].
    Robust(ReacquiringLimiting),
}

impl<M: Dim> MeasurementPolicy<M> for SchemePolicy<M>
where
    DefaultAllocator: Allocator<M> + Allocator<M, M>,
{
    fn decide(&mut self, view: &InnovationView<'_, M>) -> Decision<M> {
        match self {
            SchemePolicy::Accept(p) => p.decide(view),
            SchemePolicy::Chi2Gate(p) => p.decide(view),
            SchemePolicy::RecoveringGate(p) => p.decide(view),
            SchemePolicy::Huber(p) => p.decide(view),
            SchemePolicy::Rejection(p) => p.decide(view),
            SchemePolicy::Limiting(p) => p.decide(view),
            SchemePolicy::AdaptiveGain(p) => p.decide(view),
            SchemePolicy::LimitedAdaptiveGain(p) => p.decide(view),
            SchemePolicy::Robust(p) => p.decide(view),
        }
    }

    /// Only `robust` notes a gap (the others keep no state that a gap changes).
    fn missing(&mut self) {
        if let SchemePolicy::Robust(p) = self {
            MeasurementPolicy::<M>::missing(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `name()` is the serde name: reading each name back through serde
    /// and through `FromStr` gives the same scheme.
    #[test]
    fn names_are_the_serde_names_and_parse_back() {
        use serde::de::IntoDeserializer;
        use serde::de::value::{Error, StrDeserializer};
        for s in Scheme::ALL {
            let d: StrDeserializer<'_, Error> = s.name().into_deserializer();
            assert_eq!(Scheme::deserialize(d), Ok(s));
            assert_eq!(s.name().parse::<Scheme>(), Ok(s));
        }
        assert!(
            "median"
                .parse::<Scheme>()
                .unwrap_err()
                .contains("developed")
        );
    }
}
