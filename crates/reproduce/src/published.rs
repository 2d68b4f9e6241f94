//! The source papers' published numbers that the reproductions are compared
//! with, in one place. Each constant names its source: the seed file under
//! `shared/seeds/` (Russian original) and the table, figure or passage it is
//! read from; the English summaries in `shared/spec/` quote the same numbers.
//!
//! The CLI prints each number next to the reproduction it belongs to and
//! nowhere else.

use std::fmt;

/// A published range `lo–hi` (a single number when `lo == hi`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

impl Range {
    /// The range `lo–hi`.
    pub const fn new(lo: f64, hi: f64) -> Self {
        Self { lo, hi }
    }

    /// A single published number.
    pub const fn single(value: f64) -> Self {
        Self {
            lo: value,
            hi: value,
        }
    }
}

impl fmt::Display for Range {
    /// `lo–hi`, or the one number when both ends agree.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.lo == self.hi {
            write!(f, "{}", self.lo)
        } else {
            write!(f, "{}–{}", self.lo, self.hi)
        }
    }
}

// --- Spec 10: extended-state launch INS ----------------------------------

/// How many times the proposed algorithm reduces the INS position error at
/// t_B compared with uncorrected instruments, per flight time t_B \[s\]:
/// "в среднем примерно в 2—5, 3—8 и 4—10 раз" for t_B = 300, 400, 500 s.
/// Source: seed `000_bee609a9abd1eee9.txt` (Vasiliev et al., 2014),
/// simulation results after Figs. 1–3; spec 10, "Results to reproduce" 3.
pub const EXTENDED_STATE_ERROR_RATIO: [(f64, Range); 3] = [
    (300.0, Range::new(2.0, 5.0)),
    (400.0, Range::new(3.0, 8.0)),
    (500.0, Range::new(4.0, 10.0)),
];

/// The published error ratio for a flight time t_B \[s\] (rounded to the
/// second), if the paper gives one ([`EXTENDED_STATE_ERROR_RATIO`]).
pub fn extended_state_error_ratio(t_b_s: f64) -> Option<Range> {
    EXTENDED_STATE_ERROR_RATIO
        .iter()
        .find(|(t, _)| t.round() as i64 == t_b_s.round() as i64)
        .map(|&(_, r)| r)
}

/// Time after the start of fusion at which the Kalman filter reaches its
/// steady state (δ(n) ≤ 3 %) \[s\]: "примерно 65—70 с".
/// Source: seed `000_bee609a9abd1eee9.txt`, text under Figs. 1–2 (Fig. 2,
/// δ(n)); spec 10, "Results to reproduce" 2.
pub const EXTENDED_STATE_STEADY_STATE_S: Range = Range::new(65.0, 70.0);

// --- Spec 20: anomalies --------------------------------------------------

/// Improvement of the developed anomaly-tolerant algorithm (eq. 9) over the
/// Kalman filter with anomalous measurements \[%\]: "в среднем на 8-10% выше
/// по сравнению с фильтром Калмана".
/// Source: seed `004_80c35bdad714be83.txt` (Nguyen Dinh Thai, 2017),
/// conclusions after Figs. 3–8; spec 20, "Results to reproduce" 1.
pub const ANOMALIES_DEVELOPED_VS_KF_PERCENT: Range = Range::new(8.0, 10.0);

/// Improvement of the developed algorithm over the adaptive algorithm with
/// anomalous measurements \[%\]: "и на 5% по сравнению с адаптивным
/// алгоритмом". Source: as [`ANOMALIES_DEVELOPED_VS_KF_PERCENT`].
pub const ANOMALIES_DEVELOPED_VS_ADAPTIVE_PERCENT: Range = Range::single(5.0);

/// The adaptive algorithm's improvement over the Kalman filter implied by
/// the two published figures \[%\]: (8–10 %) − 5 % = 3–5 %. Not printed in
/// the paper; derived from [`ANOMALIES_DEVELOPED_VS_KF_PERCENT`] and
/// [`ANOMALIES_DEVELOPED_VS_ADAPTIVE_PERCENT`] (seed `004_80c35bdad714be83.txt`).
pub const ANOMALIES_ADAPTIVE_VS_KF_PERCENT: Range = Range::new(
    ANOMALIES_DEVELOPED_VS_KF_PERCENT.lo - ANOMALIES_DEVELOPED_VS_ADAPTIVE_PERCENT.lo,
    ANOMALIES_DEVELOPED_VS_KF_PERCENT.hi - ANOMALIES_DEVELOPED_VS_ADAPTIVE_PERCENT.hi,
);

/// What the paper says of each anomaly type of the per-type table (order
/// of `anomalies::ANOMALY_TYPES`), translated; the abstract
/// (`004_80c35bdad714be83.txt`) gives no number per type. Sources: its
/// introduction ("10-30% результатов измерений оказываются аномальными …
/// одиночные аномальные выбросы, короткие пачки выбросов и пачки аномальных
/// измерений большой длительности"), the section on the modified algorithm
/// (rejection "при появлении целой последовательности аномальных измерений
/// точность оценивания существенно снижается"; limiting raises it; "при
/// восстановлении работоспособности системы СНС появление сигналов часто
/// сопровождается возникновением аномальных выбросов … ошибки резко
/// возрастают") and the conclusion after Figs. 3–8 (8–10 % / 5 %).
pub const ANOMALY_TYPE_STATEMENTS: [&str; 6] = [
    "Figs. 3-4: a single outlier; zeroing the gain keeps it out of the estimate",
    "Figs. 5-6: a burst; rejection then runs on predictions only and loses accuracy, limiting raises it",
    "a long sequence of anomalies: rejection's accuracy drops substantially (predictions only); limiting raises it",
    "10-30 % of fixes anomalous; developed 8-10 % better than KF, 5 % better than adaptive",
    "10-30 % of fixes anomalous; developed 8-10 % better than KF, 5 % better than adaptive",
    "when GNSS comes back, outliers often come with it and estimation errors rise sharply",
];

// --- Spec 20: outages ----------------------------------------------------

/// Short outage, a-priori model: improvement of the INS velocity-error
/// compensation over the uncorrected autonomous INS \[%\] ("в среднем на 60%").
/// Source: seed `004_80c35bdad714be83.txt`, conclusions on outages (before
/// Fig. 9); spec 20, "Results to reproduce" 2.
pub const OUTAGES_SHORT_APRIORI_PERCENT: Range = Range::single(60.0);

/// Short outage, linear trend: improvement over the uncorrected INS \[%\]
/// ("при использовании линейного тренда – на 75%").
/// Source: as [`OUTAGES_SHORT_APRIORI_PERCENT`].
pub const OUTAGES_SHORT_TREND_PERCENT: Range = Range::single(75.0);

/// Short outage, self-organisation (GMDH): improvement over the uncorrected
/// INS \[%\] ("алгоритма самоорганизации – на 70-80%").
/// Source: as [`OUTAGES_SHORT_APRIORI_PERCENT`].
pub const OUTAGES_SHORT_GMDH_PERCENT: Range = Range::new(70.0, 80.0);

/// Long outage, self-organisation (GMDH): improvement over the uncorrected
/// INS \[%\] ("алгоритм самоорганизации позволяет повысить точность в
/// среднем на 75%"). Source: seed `004_80c35bdad714be83.txt`, conclusions
/// on outages (before Fig. 9); spec 20, "Results to reproduce" 3.
pub const OUTAGES_LONG_GMDH_PERCENT: Range = Range::single(75.0);

/// Long outage, a-priori model and linear trend: the paper's verdict
/// ("не представляется возможным" — cannot be used).
/// Source: as [`OUTAGES_LONG_GMDH_PERCENT`].
pub const OUTAGES_LONG_APRIORI_AND_TREND: &str = "unusable";

/// Long outage, combined (modified) trend: "at the end of long prediction the
/// self-organising model and the modified trend give identical results".
/// Source: seed `004_80c35bdad714be83.txt`, text above and Fig. 9; spec 20,
/// "Results to reproduce" 4.
pub const OUTAGES_LONG_COMBINED_TREND: &str = "= gmdh at the end";

/// The relay algorithm, both outage lengths: its curve follows the best
/// predictor of each stage. Source: seed `004_80c35bdad714be83.txt`, Fig. 9;
/// spec 20, "Results to reproduce" 4.
pub const OUTAGES_RELAY: &str = "follows the best stage";

// --- Spec 30: group navigation -------------------------------------------

/// One case of the paper's one-axis group simulation: mean errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupCase {
    /// Mean position error \[m\].
    pub position_m: f64,
    /// Mean velocity error \[m/s\].
    pub velocity_mps: f64,
}

/// Single vehicle (M = 1, own σ 10 m, a_R = 1 m/s²): 6.05 m, 3.63 m/s.
/// Source: seed `002_77d8f78588729d31.txt` (Kozyrev et al., 2023),
/// "Результаты моделирования", the list under the simulation parameters
/// (before Fig. 6); spec 30, "Experiment to reproduce" table.
pub const GROUP_SINGLE: GroupCase = GroupCase {
    position_m: 6.05,
    velocity_mps: 3.63,
};

/// Group of five, low-grade relative sensors (relative σ 10 m,
/// a_R = 1 m/s²): 3.57 m, 1.62 m/s. Source: as [`GROUP_SINGLE`].
pub const GROUP_LOW_GRADE: GroupCase = GroupCase {
    position_m: 3.57,
    velocity_mps: 1.62,
};

/// Group of five, high-grade relative sensors (relative σ 0.5 m,
/// a_R = 0.01 m/s²): 1.17 m, 0.05 m/s. Source: as [`GROUP_SINGLE`].
pub const GROUP_HIGH_GRADE: GroupCase = GroupCase {
    position_m: 1.17,
    velocity_mps: 0.05,
};

/// Claimed accuracy gain of five vehicles over one with low-grade relative
/// sensors and strong disturbances ("в 1,6 - 1,7 раз").
/// Source: seed `002_77d8f78588729d31.txt`, analysis of Fig. 6; spec 30,
/// "Claimed gains".
pub const GROUP_GAIN_LOW_GRADE: Range = Range::new(1.6, 1.7);

/// Claimed accuracy gain with high-grade relative sensors and weak
/// disturbances ("в 4,5 - 5 раз"). Source: as [`GROUP_GAIN_LOW_GRADE`].
pub const GROUP_GAIN_HIGH_GRADE: Range = Range::new(4.5, 5.0);

/// The paper's case for a case name of [`crate::group`] (`single`,
/// `group_low`, `group_high`).
pub fn group_case(name: &str) -> Option<GroupCase> {
    match name {
        "single" => Some(GROUP_SINGLE),
        "group_low" => Some(GROUP_LOW_GRADE),
        "group_high" => Some(GROUP_HIGH_GRADE),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_print_as_the_papers_do() {
        assert_eq!(
            extended_state_error_ratio(400.0).unwrap().to_string(),
            "3–8"
        );
        assert_eq!(extended_state_error_ratio(450.0), None);
        assert_eq!(ANOMALIES_ADAPTIVE_VS_KF_PERCENT.to_string(), "3–5");
        assert_eq!(OUTAGES_SHORT_TREND_PERCENT.to_string(), "75");
        assert_eq!(GROUP_GAIN_HIGH_GRADE.to_string(), "4.5–5");
    }
}
