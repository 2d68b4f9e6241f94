//! The reproductions' tables as the CLI prints them.

use super::*;
use aidnav::reproduce::formation::Stage2OwnErrors;
use aidnav::reproduce::published;

pub(crate) fn print_formation(s: &FormationScenario, o: &jobs::FormationOutcome, out: &Path) {
    let r = &o.result;
    println!(
        "Formation flight (spec 30 pipeline) — {} members, {:.0} s, {} runs, scored from {:.0} s, seed {}, aidnav {}",
        s.members,
        s.duration_s,
        s.runs,
        s.settle_s,
        s.seed,
        aidnav::VERSION
    );
    println!(
        "{:.1} relative measurements per epoch (range limit {:.0} m); 3-D position error RMS [m] (filter σ in brackets)",
        r.relative_per_epoch, s.sensor.range_limit_m
    );
    println!(
        "{:<7} {:<9} {:>20} {:>20} {:>20} {:>27}",
        "member",
        "GNSS",
        "GNSS/INS alone",
        "paper fusion",
        "EKF fusion",
        "velocity RMS alone/pap/ekf"
    );
    let cell = |rms: f64, sigma: f64| format!("{rms:.3} ({sigma:.3})");
    for m in &r.members {
        println!(
            "{:<7} {:<9} {:>20} {:>20} {:>20} {:>27}",
            m.member,
            match (m.denied, m.degraded) {
                (true, true) => "den+deg",
                (true, false) => "denied",
                (false, true) => "degraded",
                (false, false) => "ok",
            },
            cell(m.position_rms_m[0], m.position_sigma_m[0]),
            cell(m.position_rms_m[1], m.position_sigma_m[1]),
            cell(m.position_rms_m[2], m.position_sigma_m[2]),
            format!(
                "{:.3} / {:.3} / {:.3}",
                m.velocity_rms_mps[0], m.velocity_rms_mps[1], m.velocity_rms_mps[2]
            )
        );
    }
    println!(
        "stage 2: own errors {}, own velocities {}, range rate {}, relative velocity {}; velocity RMS [m/s] (σ) and NEES position / velocity (ideal 3)",
        match s.stage2_own_errors {
            Stage2OwnErrors::GaussMarkov => "Gauss–Markov",
            Stage2OwnErrors::White => "white",
            Stage2OwnErrors::Stage1Reported => "stage-1 reported",
        },
        if s.stage2_own_velocity {
            "fused"
        } else {
            "not fused"
        },
        if s.sensor.range_rate {
            format!("σ {} m/s", s.sensor.range_rate_sigma_mps)
        } else {
            "off".into()
        },
        if s.sensor.relative_velocity {
            format!("σ {} m/s", s.sensor.relative_velocity_sigma_mps)
        } else {
            "off".into()
        },
    );
    println!(
        "{:<7} {:>30} {:>30} {:>30}",
        "member", "GNSS/INS alone", "paper fusion", "EKF fusion"
    );
    for m in &r.members {
        let c = |k: usize| {
            format!(
                "{:.3} ({:.3}) {:.1} / {:.1}",
                m.velocity_rms_mps[k],
                m.velocity_sigma_mps[k],
                m.position_nees[k],
                m.velocity_nees[k]
            )
        };
        println!("{:<7} {:>30} {:>30} {:>30}", m.member, c(0), c(1), c(2));
    }
    let kept: Vec<_> = r
        .members
        .iter()
        .filter(|m| !m.denied && !m.degraded)
        .collect();
    if !kept.is_empty() {
        let mean =
            |k: usize| kept.iter().map(|m| m.position_rms_m[k]).sum::<f64>() / kept.len() as f64;
        println!(
            "mean over the members that keep undisturbed GNSS: alone {:.3}, paper {:.3}, EKF {:.3} m (gain {:.2}× / {:.2}×)",
            mean(0),
            mean(1),
            mean(2),
            mean(0) / mean(1),
            mean(0) / mean(2)
        );
    }
    for m in r.members.iter().filter(|m| m.denied) {
        if let (Some(max), Some(end)) = (m.denial_max_error_m, m.denial_end_error_m) {
            println!(
                "member {} during its GNSS denial: largest error alone {:.2} m, paper {:.2} m, EKF {:.2} m (mean over runs); at its end {:.2} / {:.2} / {:.2} m",
                m.member, max[0], max[1], max[2], end[0], end[1], end[2]
            );
        }
    }
    for m in &r.members {
        if let Some(e) = m.degradation_rms_error_m {
            println!(
                "member {} during its GNSS degradation: error RMS alone {:.2} m, paper {:.2} m, EKF {:.2} m (over runs and epochs)",
                m.member, e[0], e[1], e[2]
            );
        }
    }
    if let (Some(net), Some(n)) = (&s.network, &r.network) {
        println!(
            "network: latency {} s + jitter ≤ {} s, loss {:.0} %, {}, late packets fused up to {} s back: {} packets sent, {} lost ({:.1} %), {} fused on time, {} late (by rewind, {} epochs replayed), {} too old, {} in flight at the end, {} relative measurements withheld",
            net.latency_s,
            net.jitter_s,
            100.0 * net.loss_probability,
            net.max_neighbours.map_or_else(
                || "all neighbours".to_string(),
                |k| format!("≤ {k} neighbours")
            ),
            net.history_s,
            n.sent,
            n.lost,
            100.0 * n.lost_fraction(),
            n.fusion.on_time,
            n.fusion.delayed,
            n.fusion.replayed_epochs,
            n.fusion.too_old,
            n.in_flight_at_end,
            n.withheld_by_neighbour_limit
        );
    }
    if !o.sweep.is_empty() {
        print_network_sweep(&o.sweep, out);
    }
    println!(
        "wrote {}/{{formation_errors.svg, formation.csv, summary.json}}",
        out.display()
    );
}

/// The paper's headline range of the ratio for a t_B, or a dash.
fn paper_ratio(t_b_s: f64) -> String {
    published::extended_state_error_ratio(t_b_s).map_or_else(|| "—".into(), |r| r.to_string())
}

pub(crate) fn print_extended_state(s: &ExtendedStateScenario, r: &ExtendedStateResult, out: &Path) {
    println!(
        "Extended-state INS (spec 10) — {} runs per case (Gauss–Newton in {}), fixes every {} s from {} s, Φ {:?}, Q {:e}, seed {}, aidnav {}",
        s.runs,
        s.gauss_newton_runs.min(s.runs),
        s.fix_interval_s,
        s.fusion_start_s,
        s.transition,
        s.velocity_process_noise,
        s.seed,
        aidnav::VERSION
    );
    println!(
        "switch rules: armed = δ non-increasing {} s then ≤ δ_thr for {} epochs; literal = first δ(n) ≤ δ_thr; forecast = the filter's t_B position-error variance falls by less than the threshold per second ({} fixes in a row, after the transient); share = the instrument states' share of that variance ≤ the threshold ({} fixes in a row)",
        s.switch.falling_s,
        s.switch.confirm_epochs,
        s.switch.confirm_epochs,
        s.switch.confirm_epochs
    );
    println!(
        "{:>5} {:>4} {:>8} {:>6} {:>8} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8} {:>7} {:>13} {:>6}",
        "t_B",
        "φ",
        "rule",
        "thr",
        "switch",
        "free[km]",
        "outputs",
        "proposed",
        "G–N [km]",
        "oracle",
        "CRB σ",
        "ratio",
        "10–90 %",
        "paper"
    );
    for c in &r.cases {
        let rule = match c.rule {
            SwitchKind::DeltaArmed => "δ armed",
            SwitchKind::DeltaLiteral => "δ literal",
            SwitchKind::Forecast => "forecast",
            SwitchKind::ForecastShare => "share",
        };
        let unit = if c.rule == SwitchKind::Forecast {
            "/s"
        } else {
            ""
        };
        println!(
            "{:>5.0} {:>4.0} {:>8} {:>4.1}%{:<2}{:>7.1}s {:>9.1} {:>9.1} {:>9.2} {:>9.3} {:>7.0}m {:>7.0}m {:>7.2} {:>6.2}–{:<6.2} {:>6}",
            c.t_b_s,
            c.course_deg,
            rule,
            100.0 * c.delta_threshold,
            unit,
            c.switch_time_s,
            c.error_free_ins_m / 1e3,
            c.error_outputs_only_m / 1e3,
            c.error_proposed_m / 1e3,
            c.error_gauss_newton_m / 1e3,
            c.error_oracle_m,
            c.bound_sigma_m,
            c.ratio_median,
            c.ratio_p10,
            c.ratio_p90,
            paper_ratio(c.t_b_s)
        );
        if c.never_switched > 0 {
            println!("      ({} runs never switched)", c.never_switched);
        }
    }
    println!(
        "errors |Δx(t_B)| are medians over runs (outputs only / proposed / Gauss–Newton in km, oracle in m); CRB σ = the Cramér–Rao bound on the RMS error at t_B for that switch; switch = flight time (fixes from {} s; paper: steady state {} s after fixes start)",
        s.fusion_start_s,
        published::EXTENDED_STATE_STEADY_STATE_S
    );
    println!(
        "wrote {}/{{extended_state.csv, fig1_accel_bias_error.svg, fig1_scale_factor_error.svg, fig2_delta.svg, fig3_position_error.svg, switch_sweep.svg, summary.json}}",
        out.display()
    );
}

/// The paper's table: mean position and velocity error per case (NaN where none).
fn paper_group(name: &str) -> (f64, f64) {
    published::group_case(name).map_or((f64::NAN, f64::NAN), |c| (c.position_m, c.velocity_mps))
}

pub(crate) fn print_group(s: &GroupScenario, r: &GroupResult, out: &Path) {
    println!(
        "Group navigation, one axis (spec 30) — {} runs × {} epochs, averages from {:.0} s, seed {}, aidnav {}",
        s.runs,
        s.epochs,
        s.settle_s,
        s.seed,
        aidnav::VERSION
    );
    println!(
        "{:<11} {:>2} {:>9} {:>9} {:>9} {:>8} {:>10} {:>10} {:>10} {:>8}",
        "case",
        "M",
        "σ_R [m]",
        "RMS_R [m]",
        "σ_R ∞ [m]",
        "paper",
        "σ_V [m/s]",
        "RMS_V",
        "σ_V ∞",
        "paper"
    );
    for c in &r.cases {
        let (pr, pv) = paper_group(&c.name);
        println!(
            "{:<11} {:>2} {:>9.3} {:>9.3} {:>9.3} {:>8.2} {:>10.3} {:>10.3} {:>10.3} {:>8.2}",
            c.name,
            c.members,
            c.position_sigma_m,
            c.position_rms_m,
            c.steady_position_sigma_m,
            pr,
            c.velocity_sigma_mps,
            c.velocity_rms_mps,
            c.steady_velocity_sigma_mps,
            pv
        );
    }
    if let (Some(single), Some(low), Some(high)) =
        (r.case("single"), r.case("group_low"), r.case("group_high"))
    {
        println!(
            "gain M=1 / M=5 in position RMS: low-grade {:.2}×, high-grade {:.2}× (paper {}×, {}×; from its table {:.2}×, {:.2}×)",
            single.position_rms_m / low.position_rms_m,
            single.position_rms_m / high.position_rms_m,
            published::GROUP_GAIN_LOW_GRADE,
            published::GROUP_GAIN_HIGH_GRADE,
            published::GROUP_SINGLE.position_m / published::GROUP_LOW_GRADE.position_m,
            published::GROUP_SINGLE.position_m / published::GROUP_HIGH_GRADE.position_m
        );
    }
    println!(
        "σ = filter's σ, RMS = Monte Carlo error, both over members and settled epochs; ∞ = steady-state Riccati σ; wrote {}/{{group_errors.svg, group.csv, summary.json}}",
        out.display()
    );
}

pub(crate) fn print_consistency(s: &ConsistencyScenario, r: &ConsistencyResult, out: &Path) {
    println!(
        "Filter consistency — constant-velocity filter, {} runs × {} epochs, seed {}, aidnav {}",
        s.runs,
        s.epochs,
        s.seed,
        aidnav::VERSION
    );
    let (lo, hi) = r.nees_epoch_bounds;
    println!(
        "NEES of a consistent 2-state filter: 2; per-epoch {:.0} % interval of the run mean [{lo:.3}, {hi:.3}]",
        s.confidence * 100.0
    );
    println!(
        "{:<12} {:>5} {:>5} {:>10} {:>9} {:>19} {:>13} {:>12} {:>11}  verdict",
        "variant",
        "Q×",
        "R×",
        "mean NEES",
        "mean NIS",
        "NIS interval",
        "NEES inside",
        "RMS err [m]",
        "RMS σ [m]"
    );
    for v in &r.variants {
        println!(
            "{:<12} {:>5} {:>5} {:>10.3} {:>9.3} {:>19} {:>12.1}% {:>12.3} {:>11.3}  {}",
            v.name,
            v.q_scale,
            v.r_scale,
            v.mean_nees,
            v.mean_nis,
            format!("[{:.3}, {:.3}]", v.nis_bounds.0, v.nis_bounds.1),
            100.0 * v.fraction_epochs_nees_inside,
            v.rms_position_error_m,
            v.rms_position_sigma_m,
            if v.consistent {
                "consistent"
            } else {
                "INCONSISTENT"
            }
        );
    }
    println!(
        "wrote {}/{{consistency.csv, nees.svg, summary.json}}",
        out.display()
    );
}

/// The paper's figure for an estimator, where it gives one.
fn paper_anomalies(name: &str) -> String {
    match name {
        "developed" | "developed_eq4" => format!(
            "{} % better than KF, {} % better than adaptive",
            published::ANOMALIES_DEVELOPED_VS_KF_PERCENT,
            published::ANOMALIES_DEVELOPED_VS_ADAPTIVE_PERCENT
        ),
        "kf_plain" | "kf_reject" => "reference (\"Kalman filter\")".into(),
        "adaptive" | "adaptive_reject" => format!(
            "reference (\"adaptive\"), ≈ {} % better than KF",
            published::ANOMALIES_ADAPTIVE_VS_KF_PERCENT
        ),
        "adaptive_clean" => "better than KF (model error, no anomalies)".into(),
        _ => "—".into(),
    }
}

pub(crate) fn print_anomalies(s: &AnomaliesScenario, r: &AnomaliesResult, out: &Path) {
    println!(
        "Anomalous GNSS fixes (spec 20) — {} runs × {} epochs, seed {}, {:.1} % of fixes anomalous, aidnav {}",
        s.runs,
        s.epochs,
        s.seed,
        100.0 * r.anomaly_fraction,
        aidnav::VERSION
    );
    println!(
        "{:<16} {:>12} {:>23} {:>9} {:>11}  paper",
        "estimator", "RMS [m/s]", "per-run RMS p10–p90", "vs KF", "vs KF+rej"
    );
    for sc in &r.scores {
        println!(
            "{:<16} {:>12.5} {:>23} {:>8.1}% {:>10.1}%  {}",
            sc.name,
            sc.rms_mps,
            format!("{:.5}–{:.5}", sc.p10_mps, sc.p90_mps),
            100.0 * sc.improvement_vs_kf,
            100.0 * sc.improvement_vs_kf_reject,
            paper_anomalies(&sc.name)
        );
    }
    print_anomaly_types(r);
    println!(
        "improvement = 1 − RMS / RMS(reference); wrote {}/{{anomalies_example.csv, anomalies_example.svg, fig03…fig08 *.svg, anomaly_types.csv, summary.json}}",
        out.display()
    );
}

/// The estimators of the per-type table's printout (every one is in
/// `anomaly_types.csv` and `summary.json`).
const TYPE_COLUMNS: [&str; 8] = [
    "kf_plain",
    "kf_reject",
    "adaptive",
    "developed",
    "chi2_gate",
    "huber",
    "median_kf",
    "tukey53h_kf",
];

/// One anomaly type at a time: RMS of each estimator, the paper beside it.
fn print_anomaly_types(r: &AnomaliesResult) {
    let Some(first) = r.per_type.first() else {
        return;
    };
    println!(
        "per anomaly type ({} runs each, same truth draws) — RMS of the δV estimate [m/s]:",
        first.runs
    );
    print!("{:<22} {:>7}", "type", "anom.");
    for c in TYPE_COLUMNS {
        print!(" {c:>11}");
    }
    println!();
    for t in &r.per_type {
        print!(
            "{:<22} {:>6.1}%",
            t.anomaly_type,
            100.0 * t.anomaly_fraction
        );
        for c in TYPE_COLUMNS {
            let v = t
                .rms_mps
                .iter()
                .find(|e| e.name == c)
                .map_or(f64::NAN, |e| e.rms_mps);
            print!(" {v:>11.4}");
        }
        println!();
        println!("{:<22} paper: {}", "", t.paper);
    }
}

/// The paper's improvement over the uncorrected INS, where given.
fn paper_outages(long: bool, name: &str) -> String {
    let percent = |r: published::Range| format!("+{r} %");
    match (long, name) {
        (false, "apriori") => percent(published::OUTAGES_SHORT_APRIORI_PERCENT),
        (false, "trend") => percent(published::OUTAGES_SHORT_TREND_PERCENT),
        (false, "gmdh" | "gmdh_reselected") => percent(published::OUTAGES_SHORT_GMDH_PERCENT),
        (true, "apriori") | (true, "trend") => published::OUTAGES_LONG_APRIORI_AND_TREND.into(),
        (true, "gmdh" | "gmdh_reselected") => percent(published::OUTAGES_LONG_GMDH_PERCENT),
        (true, "combined_trend") => published::OUTAGES_LONG_COMBINED_TREND.into(),
        (_, "relay") => published::OUTAGES_RELAY.into(),
        _ => "—".into(),
    }
}

pub(crate) fn print_outage_table(title: &str, long: bool, s: &OutageScores) {
    println!(
        "{title}: {:.0} s, uncorrected INS RMS {:.4} m/s",
        s.length_s, s.uncorrected_rms_mps
    );
    println!(
        "{:<16} {:>12} {:>12} {:>22} {:>13}  paper",
        "predictor", "RMS [m/s]", "improvement", "per-run p10–p90", "vs reset INS"
    );
    for p in &s.predictors {
        println!(
            "{:<16} {:>12.4} {:>11.1}% {:>22} {:>12.1}%  {}",
            p.name,
            p.rms_mps,
            100.0 * p.improvement,
            format!(
                "{:.1}% – {:.1}%",
                100.0 * p.improvement_p10,
                100.0 * p.improvement_p90
            ),
            100.0 * p.improvement_vs_reset,
            paper_outages(long, &p.name)
        );
    }
}

pub(crate) fn print_outages(s: &OutagesScenario, r: &OutagesResult, out: &Path) {
    println!(
        "GNSS outages (spec 20) — {} runs, outage from {:.0} s, seed {}, aidnav {}",
        s.runs,
        s.outage_start_s,
        s.seed,
        aidnav::VERSION
    );
    print_outage_table("short outage", false, &r.short);
    print_outage_table("long outage", true, &r.long);
    let e = &r.efficiency;
    println!(
        "after the long outage, {:.0} s of GNSS with a burst — RMS velocity error [m/s]: GNSS alone {:.4}; INS + filter {:.4}; chosen by K_eff with σ_KOI = √P⁺ {:.4} (INS + filter on {:.1} % of epochs); σ_KOI = √P⁻ {:.4} ({:.1} %); σ_KOI from eqs. 14–15 {:.4} ({:.1} %)",
        e.length_s,
        e.rms_always_gnss_mps,
        e.rms_always_integrated_mps,
        e.rms_selected_mps,
        100.0 * e.fraction_integrated,
        e.rms_selected_predicted_mps,
        100.0 * e.fraction_integrated_predicted,
        e.rms_selected_adaptive_mps,
        100.0 * e.fraction_integrated_adaptive
    );
    println!(
        "improvement = 1 − RMS(δV − prediction) / RMS(δV) (uncorrected INS); vs reset INS = 1 − RMS / RMS(hold) (INS corrected until the outage, free after); wrote {}/{{outage_example.csv, outage_predictors.svg (Fig. 9), efficiency.svg, fig10_recovery_errors.svg, summary.json}}",
        out.display()
    );
}

/// The network sweep's table (`reproduce formation` with a sweep, and
/// `reproduce formation-network`).
fn print_network_sweep(sweep: &[aidnav::reproduce::formation::SweepCell], out: &Path) {
    let cell = |rms: f64, sigma: f64| format!("{rms:.3} ({sigma:.3})");
    println!(
        "network sweep (same stage 1 and measurements per run): members keeping GNSS, mean 3-D position RMS [m] (filter σ in brackets){}",
        if sweep[0].denied_max_error_m.is_some() {
            "; denied members' largest error while denied [m]"
        } else {
            ""
        }
    );
    println!(
        "{:>11} {:>6} {:>7} {:>7} {:>8} {:>17} {:>17} {:>26}",
        "latency [s]", "loss", "lost", "late", "alone", "paper", "EKF", "denied alone/paper/EKF"
    );
    for c in sweep {
        println!(
            "{:>11} {:>5.0}% {:>6.1}% {:>6.1}% {:>8.3} {:>17} {:>17} {:>26}",
            c.latency_s,
            100.0 * c.loss_probability,
            100.0 * c.network.lost_fraction(),
            100.0 * c.network.late_fraction(),
            c.kept_rms_m[0],
            cell(c.kept_rms_m[1], c.kept_sigma_m[1]),
            cell(c.kept_rms_m[2], c.kept_sigma_m[2]),
            c.denied_max_error_m.map_or_else(
                || "—".to_string(),
                |d| format!("{:.2} / {:.2} / {:.2}", d[0], d[1], d[2])
            )
        );
    }
    println!(
        "wrote {}/{{network_sweep.csv, network_sweep.svg}}",
        out.display()
    );
}

/// `reproduce formation-network`: the scenario line and the sweep's table.
pub(crate) fn print_formation_network(
    s: &FormationScenario,
    sweep: &[aidnav::reproduce::formation::SweepCell],
    out: &Path,
) {
    let net = s.network.clone().unwrap_or_default();
    println!(
        "Formation network sweep (spec 30 pipeline) — {} members, {:.0} s, {} runs, scored from {:.0} s, jitter ≤ {} s, {}, late packets fused up to {} s back, seed {}, aidnav {}",
        s.members,
        s.duration_s,
        s.runs,
        s.settle_s,
        net.jitter_s,
        net.max_neighbours.map_or_else(
            || "all neighbours".to_string(),
            |n| format!("at most {n} neighbours")
        ),
        net.history_s,
        s.seed,
        aidnav::VERSION
    );
    print_network_sweep(sweep, out);
    println!("wrote {}/summary.json", out.display());
}
