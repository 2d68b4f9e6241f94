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
use crate::error::EstimationError;
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

/// The tuning constants the schemes read — their one home: the defaults
/// ([`Default`]) and the allowed ranges ([`SchemeParameters::validate`])
/// that the navigation application's `[gnss]` keys, the CLI's
/// `--print-config` and the Python binding all take from here.
///
/// Read from TOML or JSON by its field names; a missing field takes its
/// default, an unknown one is an error.
///
/// ```
/// use aidnav_estimation::scheme::SchemeParameters;
/// use aidnav_estimation::EstimationError;
///
/// let p = SchemeParameters { huber_k: 0.0, ..SchemeParameters::default() };
/// let EstimationError::OutOfRange { parameter, .. } = p.validate().unwrap_err() else {
///     unreachable!()
/// };
/// assert_eq!(parameter, "huber_k");
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SchemeParameters {
    /// Probability of the χ² gates' quantile (`chi2_gate`,
    /// `recovering_gate`), 0 < p < 1. Default 0.999.
    pub chi2_probability: f64,
    /// Rejections in a row after which `recovering_gate` accepts again,
    /// 1 … 100 000. Default 20 (5 s of fixes at 4 Hz).
    pub recovering_after: usize,
    /// Huber threshold k on √NIS (`huber`), 0.1 … 100. Default 1.345: 95 %
    /// efficiency at the normal (Huber 1964).
    pub huber_k: f64,
    /// Eq. 5's γ: an innovation with νᵀν > γ tr S is anomalous
    /// (`rejection`, `limiting`, `limited_adaptive_gain`, `developed`,
    /// `robust`), 1 … 10 000. Default 9 (spec 20).
    pub anomaly_gamma: f64,
    /// Eq. 4's sliding window (`adaptive_gain`, `limited_adaptive_gain`),
    /// innovations, 1 … 10 000. Default 20.
    pub adaptive_window: usize,
    /// How eq. 4 compares the diagonals of M̂ and H P⁻ Hᵀ for vector
    /// measurements (`adaptive_gain`, `limited_adaptive_gain`): `all` or
    /// `any`. Default `all`.
    pub adaptive_diagonal_rule: DiagonalRule,
}

impl Default for SchemeParameters {
    /// χ² 0.999, recovery after 20 rejections, Huber k = 1.345 (95 %
    /// efficiency at the normal, Huber 1964), γ = 9 (spec 20), window 20
    /// compared on all diagonal elements.
    fn default() -> Self {
        Self {
            chi2_probability: 0.999,
            recovering_after: 20,
            huber_k: 1.345,
            anomaly_gamma: 9.0,
            adaptive_window: 20,
            adaptive_diagonal_rule: DiagonalRule::All,
        }
    }
}

/// Allowed `huber_k`, inclusive: below 0.1 every innovation is re-weighted,
/// above 100 none is.
const HUBER_K_RANGE: (f64, f64) = (0.1, 100.0);
/// Allowed `anomaly_gamma`, inclusive: below 1 an innovation of ordinary
/// size is anomalous.
const ANOMALY_GAMMA_RANGE: (f64, f64) = (1.0, 1e4);
/// Allowed `recovering_after`, inclusive (0 would never reject).
const RECOVERING_AFTER_RANGE: (usize, usize) = (1, 100_000);
/// Allowed `adaptive_window`, inclusive.
const ADAPTIVE_WINDOW_RANGE: (usize, usize) = (1, 10_000);

/// `Err` naming `parameter` unless `lo ≤ value ≤ hi` (and finite).
fn real_in(parameter: &'static str, value: f64, (lo, hi): (f64, f64)) -> crate::Result<()> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(EstimationError::OutOfRange {
        parameter,
        value: value.to_string(),
        allowed: format!("{lo} ≤ {parameter} ≤ {hi}"),
    })
}

/// `Err` naming `parameter` unless `lo ≤ value ≤ hi`.
fn count_in(parameter: &'static str, value: usize, (lo, hi): (usize, usize)) -> crate::Result<()> {
    if (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(EstimationError::OutOfRange {
        parameter,
        value: value.to_string(),
        allowed: format!("{lo} ≤ {parameter} ≤ {hi}"),
    })
}

impl SchemeParameters {
    /// `Ok` when every parameter is in its allowed range, else
    /// [`EstimationError::OutOfRange`] naming the first one out, its value
    /// and the range (the ranges are on the fields' docs).
    pub fn validate(&self) -> crate::Result<()> {
        let p = self.chi2_probability;
        if !(p > 0.0 && p < 1.0) {
            return Err(EstimationError::OutOfRange {
                parameter: "chi2_probability",
                value: p.to_string(),
                allowed: "0 < chi2_probability < 1".into(),
            });
        }
        count_in(
            "recovering_after",
            self.recovering_after,
            RECOVERING_AFTER_RANGE,
        )?;
        real_in("huber_k", self.huber_k, HUBER_K_RANGE)?;
        real_in("anomaly_gamma", self.anomaly_gamma, ANOMALY_GAMMA_RANGE)?;
        count_in(
            "adaptive_window",
            self.adaptive_window,
            ADAPTIVE_WINDOW_RANGE,
        )
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
    /// If `adaptive_window` is 0 for the eq. 4 schemes: callers validate
    /// the parameters ([`SchemeParameters::validate`]).
    pub fn policy<M: Dim>(self, p: &SchemeParameters) -> SchemePolicy<M>
    where
        DefaultAllocator: Allocator<M> + Allocator<M, M>,
    {
        let detector = AnomalyDetector {
            gamma: p.anomaly_gamma,
        };
        let window = || {
            AdaptiveGain::new(p.adaptive_window, p.adaptive_diagonal_rule)
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

    /// The defaults pass; each parameter just out of its range is refused,
    /// the error naming it, its value and its range.
    #[test]
    fn validate_names_the_parameter_its_value_and_its_range() {
        let d = SchemeParameters::default();
        assert_eq!(d.validate(), Ok(()));
        let cases: [(SchemeParameters, &str, &str); 6] = [
            (
                SchemeParameters {
                    chi2_probability: 1.0,
                    ..d
                },
                "chi2_probability",
                "0 < chi2_probability < 1",
            ),
            (
                SchemeParameters {
                    recovering_after: 0,
                    ..d
                },
                "recovering_after",
                "1 ≤ recovering_after ≤ 100000",
            ),
            (
                SchemeParameters {
                    huber_k: f64::NAN,
                    ..d
                },
                "huber_k",
                "0.1 ≤ huber_k ≤ 100",
            ),
            (
                SchemeParameters {
                    anomaly_gamma: 0.5,
                    ..d
                },
                "anomaly_gamma",
                "1 ≤ anomaly_gamma ≤ 10000",
            ),
            (
                SchemeParameters {
                    adaptive_window: 0,
                    ..d
                },
                "adaptive_window",
                "1 ≤ adaptive_window ≤ 10000",
            ),
            (
                SchemeParameters {
                    adaptive_window: 10_001,
                    ..d
                },
                "adaptive_window",
                "1 ≤ adaptive_window ≤ 10000",
            ),
        ];
        for (p, name, range) in cases {
            let e = p.validate().unwrap_err();
            let EstimationError::OutOfRange {
                parameter, allowed, ..
            } = &e
            else {
                panic!("{e}");
            };
            assert_eq!((*parameter, allowed.as_str()), (name, range));
            assert!(e.to_string().starts_with(&format!("{name} = ")), "{e}");
        }
    }

    /// The eq. 4 schemes compare the diagonals by the configured rule.
    #[test]
    fn the_adaptive_schemes_take_the_diagonal_rule() {
        use nalgebra::U2;
        let p = SchemeParameters {
            adaptive_diagonal_rule: DiagonalRule::Any,
            ..SchemeParameters::default()
        };
        let SchemePolicy::AdaptiveGain(gain) = Scheme::AdaptiveGain.policy::<U2>(&p) else {
            panic!("adaptive_gain is not an AdaptiveGain");
        };
        assert_eq!(gain.rule(), DiagonalRule::Any);
    }

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
