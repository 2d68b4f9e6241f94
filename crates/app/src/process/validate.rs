//! Validation of the configuration of `aidnav process`: every field in
//! its range, errors naming the table and the key.

use aidnav_io::config::{Invalid, Validate, all_positive, count_in_range, in_range, non_negative};

use aidnav_estimation::EstimationError;
use aidnav_estimation::gmdh::{GmdhConfig, GmdhError};

use super::config::{GnssConfig, GnssFormat, ImuFormat, ProcessConfig};

impl Validate for ProcessConfig {
    fn validate(&self) -> Result<(), Invalid> {
        validate_inputs(self)?;
        validate_physical_bounds(self)?;
        validate_aid_sources(self)?;
        validate_supervision_and_scores(self)
    }
}

/// Each element of a 3-vector in `lo ≤ v ≤ hi` (and finite); the key names
/// the element (`gnss.lever_arm_m[2]`, 0-based).
fn vector_in_range(key: &str, v: &[f64; 3], lo: f64, hi: f64) -> Result<(), Invalid> {
    for (i, x) in v.iter().enumerate() {
        if !(x.is_finite() && *x >= lo && *x <= hi) {
            return Err(Invalid::new(
                format!("{key}[{i}]"),
                x,
                format!("{lo} ≤ each element ≤ {hi}"),
            ));
        }
    }
    Ok(())
}

/// The `[wheel_speed]` and `[barometer]` tables: a file, every number in a
/// physical range, and a layout the filter is built for.
fn validate_aid_sources(cfg: &ProcessConfig) -> Result<(), Invalid> {
    let file = |table: &str, file: &std::path::Path| {
        if file.as_os_str().is_empty() {
            Err(Invalid::new(
                format!("{table}.file"),
                "(missing)",
                "the stream's file, relative to data.dir",
            ))
        } else {
            Ok(())
        }
    };
    if let Some(w) = &cfg.wheel_speed {
        file("wheel_speed", &w.file)?;
        for (key, value, lo, hi) in [
            ("time_offset_s", w.time_offset_s, -10.0, 10.0),
            ("sigma_mps", w.sigma_mps, 1e-6, 100.0),
            ("scale_sigma", w.scale_sigma, 1e-9, 1.0),
            ("scale_noise_per_sqrt_s", w.scale_noise_per_sqrt_s, 0.0, 1.0),
            ("gate_probability", w.gate_probability, 0.5, 1.0),
            ("min_interval_s", w.min_interval_s, 0.0, 3600.0),
        ] {
            bounded("wheel_speed", key, value, lo, hi)?;
        }
        vector_in_range("wheel_speed.lever_arm_m", &w.lever_arm_m, -100.0, 100.0)?;
    }
    if cfg.constraints.estimate_misalignment && !cfg.non_holonomic() && cfg.wheel_speed.is_none() {
        return Err(Invalid::new(
            "constraints.estimate_misalignment",
            true,
            "false without a vehicle constraint: set constraints.non_holonomic = true or add [wheel_speed] (nothing else observes the vehicle frame)",
        ));
    }
    if let Some(b) = &cfg.barometer {
        file("barometer", &b.file)?;
        for (key, value, lo, hi) in [
            ("time_offset_s", b.time_offset_s, -10.0, 10.0),
            ("sigma_m", b.sigma_m, 1e-6, 1e4),
            ("bias_sigma_m", b.bias_sigma_m, 1e-6, 1e5),
            (
                "bias_noise_m_per_sqrt_s",
                b.bias_noise_m_per_sqrt_s,
                0.0,
                100.0,
            ),
            ("gate_probability", b.gate_probability, 0.5, 1.0),
            ("min_interval_s", b.min_interval_s, 0.0, 3600.0),
        ] {
            bounded("barometer", key, value, lo, hi)?;
        }
    }
    if cfg.filter.convergence_monitor && cfg.state_layout().len() != aidnav_models::ned_ins::STATES
    {
        return Err(Invalid::new(
            "filter.convergence_monitor",
            true,
            "off with an added state (wheel_speed.scale_state, barometer.bias_state): the monitor covers the base 21 states only",
        ));
    }
    Ok(())
}

/// `lo ≤ value ≤ hi` with `key` prefixed by `table`.
fn bounded(table: &str, key: &str, value: f64, lo: f64, hi: f64) -> Result<(), Invalid> {
    in_range(key, value, lo, hi).map_err(|e| e.within(table))
}

/// Physical bounds of every numeric key of `imu`, `initial`, `gnss`,
/// `constraints`, `efficiency` and `score` beyond "> 0": angles within a
/// turn, lever arms and speeds of a vehicle, σ that cannot underflow when
/// squared (≥ 1e-9) — so a typo is refused at load, naming the key.
fn validate_physical_bounds(cfg: &ProcessConfig) -> Result<(), Invalid> {
    vector_in_range("imu.mounting_deg", &cfg.imu.mounting_deg, -360.0, 360.0)?;
    let n = &cfg.imu.noise;
    for (key, value, hi) in [
        ("arw_deg_per_sqrt_h", n.arw_deg_per_sqrt_h, 1e4),
        ("vrw_mps_per_sqrt_h", n.vrw_mps_per_sqrt_h, 1e4),
        ("gyro_bias_deg_per_h", n.gyro_bias_deg_per_h, 1e6),
        ("accel_bias_mg", n.accel_bias_mg, 1e4),
        ("gyro_scale_ppm", n.gyro_scale_ppm, 1e6),
        ("accel_scale_ppm", n.accel_scale_ppm, 1e6),
    ] {
        let [x, y, z] = value.0;
        if x == y && y == z {
            bounded("imu.noise", key, x, 1e-9, hi)?;
        } else {
            vector_in_range(&format!("imu.noise.{key}"), &value.0, 1e-9, hi)?;
        }
    }
    bounded(
        "imu.noise",
        "bias_correlation_s",
        n.bias_correlation_s,
        1e-3,
        1e9,
    )?;
    bounded(
        "imu.noise",
        "scale_correlation_s",
        n.scale_correlation_s,
        1e-3,
        1e9,
    )?;
    let i = &cfg.initial;
    bounded("initial", "static_s", i.static_s, 1e-3, 3600.0)?;
    if let Some(v) = i.heading_speed_mps {
        bounded("initial", "heading_speed_mps", v, 1e-3, 1000.0)?;
    }
    bounded(
        "initial",
        "moving_heading_sigma_deg",
        i.moving_heading_sigma_deg,
        1e-6,
        180.0,
    )?;
    bounded(
        "initial",
        "moving_tilt_sigma_deg",
        i.moving_tilt_sigma_deg,
        1e-6,
        90.0,
    )?;
    bounded(
        "initial",
        "heading_sigma_deg",
        i.heading_sigma_deg,
        1e-6,
        180.0,
    )?;
    bounded("initial", "tilt_sigma_deg", i.tilt_sigma_deg, 1e-6, 90.0)?;
    if let Some(a) = &i.attitude_deg {
        vector_in_range("initial.attitude_deg", a, -360.0, 360.0)?;
    }
    if let Some(v) = i.position_sigma_m {
        bounded("initial", "position_sigma_m", v, 1e-4, 1e5)?;
    }
    if let Some(v) = i.velocity_sigma_mps {
        bounded("initial", "velocity_sigma_mps", v, 1e-5, 1e3)?;
    }
    if let Some(v) = &i.velocity_ned_mps {
        vector_in_range("initial.velocity_ned_mps", v, -1000.0, 1000.0)?;
    }
    let g = &cfg.gnss;
    vector_in_range("gnss.lever_arm_m", &g.lever_arm_m, -100.0, 100.0)?;
    bounded(
        "gnss",
        "min_position_sigma_m",
        g.min_position_sigma_m,
        1e-9,
        1e4,
    )?;
    bounded(
        "gnss",
        "min_velocity_sigma_mps",
        g.min_velocity_sigma_mps,
        1e-9,
        1e3,
    )?;
    let c = &cfg.constraints;
    bounded(
        "constraints",
        "non_holonomic_sigma_mps",
        c.non_holonomic_sigma_mps,
        1e-9,
        100.0,
    )?;
    bounded(
        "constraints",
        "non_holonomic_rate_hz",
        c.non_holonomic_rate_hz,
        1e-3,
        1e4,
    )?;
    bounded("constraints", "min_speed_mps", c.min_speed_mps, 0.0, 1000.0)?;
    bounded(
        "constraints",
        "non_holonomic_gate_probability",
        c.non_holonomic_gate_probability,
        0.5,
        1.0,
    )?;
    vector_in_range(
        "constraints.misalignment_deg",
        &c.misalignment_deg,
        -180.0,
        180.0,
    )?;
    // A pitch near ±90° is a mounting, not a misalignment (and the
    // angles' singularity).
    if c.misalignment_deg[1].abs() >= 80.0 {
        return Err(Invalid::new(
            "constraints.misalignment_deg[1]",
            c.misalignment_deg[1],
            "must be within ±80° (a larger pitch is an imu.mounting_deg)",
        ));
    }
    bounded(
        "constraints",
        "misalignment_sigma_deg",
        c.misalignment_sigma_deg,
        1e-3,
        30.0,
    )?;
    bounded(
        "constraints",
        "zero_velocity_sigma_mps",
        c.zero_velocity_sigma_mps,
        1e-6,
        10.0,
    )?;
    bounded(
        "constraints",
        "zero_angular_rate_sigma_deg_s",
        c.zero_angular_rate_sigma_deg_s,
        1e-6,
        100.0,
    )?;
    bounded(
        "constraints",
        "zero_velocity_rate_hz",
        c.zero_velocity_rate_hz,
        1e-3,
        1e4,
    )?;
    let st = &cfg.standstill;
    bounded("standstill", "window_s", st.window_s, 0.01, 60.0)?;
    bounded("standstill", "max_speed_mps", st.max_speed_mps, 0.0, 10.0)?;
    if let Some(v) = st.max_accel_std_mps2 {
        bounded("standstill", "max_accel_std_mps2", v, 1e-6, 100.0)?;
    }
    if let Some(v) = st.max_gyro_std_deg_s {
        bounded("standstill", "max_gyro_std_deg_s", v, 1e-6, 1000.0)?;
    }
    let q = &cfg.gnss.quality_sigma_scale;
    for (key, value) in [("float", q.float), ("dgps", q.dgps), ("single", q.single)] {
        bounded("gnss.quality_sigma_scale", key, value, 1.0, 1e4)?;
    }
    bounded("gnss", "sigma_scale", cfg.gnss.sigma_scale, 1e-3, 1e3)?;
    if let super::config::GnssLatency::Seconds(v) = cfg.gnss.latency {
        bounded("gnss", "latency", v, -10.0, 10.0)?;
    }
    bounded(
        "gnss",
        "latency_sigma_s",
        cfg.gnss.latency_sigma_s,
        1e-4,
        10.0,
    )?;
    bounded(
        "gnss",
        "lever_arm_sigma_m",
        cfg.gnss.lever_arm_sigma_m,
        1e-3,
        10.0,
    )?;
    let t = &cfg.tune;
    bounded("tune", "min_static_s", t.min_static_s, 1.0, 1e5)?;
    count_in_range("max_evaluations", t.max_evaluations, 1, 10_000)
        .map_err(|e| e.within("tune"))?;
    bounded("tune", "max_factor", t.max_factor, 1.01, 1e6)?;
    bounded("tune", "initial_factor", t.initial_factor, 1.01, 100.0)?;
    bounded("tune", "tolerance", t.tolerance, 1e-9, 1e6)?;
    if let Some(v) = t.outage_s {
        bounded("tune", "outage_s", v, 1.0, 1e5)?;
    }
    if let Some(v) = t.gap_s {
        bounded("tune", "gap_s", v, 1.0, 1e5)?;
    }
    if let Some(sg) = cfg.efficiency.sigma_gnss_m {
        bounded("efficiency", "sigma_gnss_m", sg, 1e-9, 1e4)?;
    }
    bounded("score", "lead_s", cfg.score.lead_s, 0.0, 1e6)?;
    bounded("score", "gap_s", cfg.score.gap_s, 0.0, 1e6)?;
    count_in_range(
        "outlier_fractions",
        cfg.score.outlier_fractions.len(),
        0,
        10,
    )
    .map_err(|e| e.within("score"))?;
    let [lo, hi] = cfg.score.outlier_m;
    if hi > 1e6 {
        return Err(Invalid::new(
            "score.outlier_m",
            format!("[{lo}, {hi}]"),
            "0 ≤ low ≤ high ≤ 1e6",
        ));
    }
    Ok(())
}

/// Data, IMU, initialisation, GNSS and filter settings.
fn validate_inputs(cfg: &ProcessConfig) -> Result<(), Invalid> {
    if cfg.data.imu_format == ImuFormat::RtklibTagged && cfg.data.imu_tags.is_none() {
        return Err(Invalid::new(
            "data.imu_tags",
            "(missing)",
            "the RTKLIB .tag file of the IMU CSV (imu_format = \"rtklib_tagged\")",
        ));
    }
    if cfg.data.imu_units.is_some() && cfg.data.imu_format != ImuFormat::GenericCsv {
        return Err(Invalid::new(
            "data.imu_units",
            "(given)",
            "only with imu_format = \"generic_csv\" (the other formats fix their units)",
        ));
    }
    if let Some(sigma) = cfg.data.gnss_sigma_m {
        if cfg.data.gnss_format != GnssFormat::GenericCsv {
            return Err(Invalid::new(
                "data.gnss_sigma_m",
                format!("[{}, {}]", sigma[0], sigma[1]),
                "only with gnss_format = \"generic_csv\" (the other formats carry their own σ)",
            ));
        }
        for (i, s) in sigma.iter().enumerate() {
            if !(s.is_finite() && (1e-9..=1e7).contains(s)) {
                return Err(Invalid::new(
                    format!("data.gnss_sigma_m[{i}]"),
                    s,
                    "1e-9 ≤ σ ≤ 1e7 m ([horizontal (each axis), vertical])",
                ));
            }
        }
    }
    in_range("time_offset_s", cfg.imu.time_offset_s, -10.0, 10.0).map_err(|e| e.within("imu"))?;
    in_range("smoothing_s", cfg.imu.smoothing_s, 0.0, 5.0).map_err(|e| e.within("imu"))?;
    all_positive(
        "initial",
        &[
            ("static_s", cfg.initial.static_s),
            ("heading_sigma_deg", cfg.initial.heading_sigma_deg),
            ("tilt_sigma_deg", cfg.initial.tilt_sigma_deg),
        ],
    )?;
    all_positive(
        "gnss",
        &[
            ("min_position_sigma_m", cfg.gnss.min_position_sigma_m),
            ("min_velocity_sigma_mps", cfg.gnss.min_velocity_sigma_mps),
        ],
    )?;
    validate_scheme(&cfg.gnss)?;
    engine_ranges("gnss", cfg.gnss.recovery_parameters().validate())?;
    count_in_range(
        "adaptive_noise_window",
        cfg.filter.adaptive_noise_window,
        1,
        10_000,
    )
    .map_err(|e| e.within("filter"))?;
    Ok(())
}

/// The scheme keys of `[gnss]` (`anomaly_gamma`, `chi2_probability`, …)
/// in the engine's ranges ([`SchemeParameters::validate`]), the error
/// naming `gnss.<key>`.
///
/// [`SchemeParameters::validate`]: aidnav_estimation::SchemeParameters::validate
fn validate_scheme(g: &GnssConfig) -> Result<(), Invalid> {
    engine_ranges("gnss", g.scheme_parameters().validate())
}

/// A library's own range check of parameters read from `table`, its error
/// naming `table.<key>`.
fn engine_ranges(table: &str, checked: Result<(), EstimationError>) -> Result<(), Invalid> {
    match checked {
        Ok(()) => Ok(()),
        Err(EstimationError::OutOfRange {
            parameter,
            value,
            allowed,
        }) => Err(Invalid::new(parameter, value, allowed).within(table)),
        Err(other) => Err(Invalid::new(table, other, "valid parameters")),
    }
}

/// The outage bridge's GMDH table: every key within the bounds of
/// [`GmdhConfig::check`] (degree, frequencies, grid size, units, beam and the
/// memory of a selection), the error naming `outage_bridge.gmdh.<key>`.
fn validate_gmdh(g: &GmdhConfig) -> Result<(), Invalid> {
    match g.check() {
        Ok(()) => Ok(()),
        Err(GmdhError::OutOfRange {
            key,
            value,
            allowed,
        }) => Err(Invalid::new(key, value, allowed).within("outage_bridge.gmdh")),
        Err(other) => Err(Invalid::new(
            "outage_bridge.gmdh",
            other,
            "a valid GMDH configuration",
        )),
    }
}

/// Outage bridge, efficiency criterion, outputs and scoring settings.
fn validate_supervision_and_scores(cfg: &ProcessConfig) -> Result<(), Invalid> {
    let b = &cfg.outage_bridge;
    all_positive(
        "outage_bridge",
        &[
            ("trend_window_s", b.trend_window_s),
            ("model_window_s", b.model_window_s),
            ("relay.t1_s", b.relay.t1_s),
        ],
    )?;
    if !(b.relay.t1_s < b.relay.t2_s && b.relay.t2_s < b.relay.t3_s && b.relay.t3_s.is_finite()) {
        return Err(Invalid::new(
            "outage_bridge.relay",
            format!("[{}, {}, {}]", b.relay.t1_s, b.relay.t2_s, b.relay.t3_s),
            "0 < t1_s < t2_s < t3_s",
        ));
    }
    if let Some(t4) = b.relay.t4_s
        && !(t4 > b.relay.t3_s && t4.is_finite())
    {
        return Err(Invalid::new(
            "outage_bridge.relay.t4_s",
            t4,
            format!("t3_s = {} < t4_s, finite", b.relay.t3_s),
        ));
    }
    count_in_range("model_decimation", b.model_decimation, 1, 1000)
        .map_err(|e| e.within("outage_bridge"))?;
    validate_gmdh(&b.gmdh)?;
    if let Some(sg) = cfg.efficiency.sigma_gnss_m {
        all_positive("efficiency", &[("sigma_gnss_m", sg)])?;
    }
    if let Some(sv) = cfg.efficiency.sigma_gnss_velocity_mps {
        bounded("efficiency", "sigma_gnss_velocity_mps", sv, 1e-9, 1e4)?;
    }
    let i = cfg.output.interval_s;
    if !(i == 0.0 || (1e-3..=3600.0).contains(&i)) {
        return Err(Invalid::new(
            "output.interval_s",
            i,
            "0 (GNSS epochs only) or 0.001 ≤ interval_s ≤ 3600",
        ));
    }
    count_in_range("outages_s", cfg.score.outages_s.len(), 0, 10).map_err(|e| e.within("score"))?;
    for l in &cfg.score.outages_s {
        in_range("outages_s", *l, 1.0, 3600.0).map_err(|e| e.within("score"))?;
    }
    non_negative("lead_s", cfg.score.lead_s).map_err(|e| e.within("score"))?;
    non_negative("gap_s", cfg.score.gap_s).map_err(|e| e.within("score"))?;
    in_range(
        "post_outage_burst_s",
        cfg.score.post_outage_burst_s,
        0.0,
        60.0,
    )
    .map_err(|e| e.within("score"))?;
    // An empty list would score nothing while reading as "no reference";
    // seven qualities exist.
    count_in_range("reference_quality", cfg.score.reference_quality.len(), 1, 7)
        .map_err(|e| e.within("score"))?;
    for f in &cfg.score.outlier_fractions {
        in_range("outlier_fractions", *f, 0.0, 1.0).map_err(|e| e.within("score"))?;
    }
    let [lo, hi] = cfg.score.outlier_m;
    if !(lo >= 0.0 && hi >= lo && hi.is_finite()) {
        return Err(Invalid::new(
            "score.outlier_m",
            format!("[{lo}, {hi}]"),
            "0 ≤ low ≤ high",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn outage_bridge_gmdh_keys_are_bounded_before_allocating() {
        let mut cfg = GmdhConfig {
            max_degree: 2_147_483_648,
            ..GmdhConfig::default()
        };
        let e = validate_gmdh(&cfg).unwrap_err();
        assert_eq!(e.key, "outage_bridge.gmdh.max_degree");
        cfg.max_degree = 2;
        cfg.frequencies = vec![1e308];
        assert_eq!(
            validate_gmdh(&cfg).unwrap_err().key,
            "outage_bridge.gmdh.frequencies"
        );
        assert_eq!(validate_gmdh(&GmdhConfig::default()), Ok(()));
    }

    const DATA: &str =
        "[data]\ndir = \".\"\nimu = \"i.csv\"\nimu_format = \"generic_csv\"\ngnss = \"g.pos\"\n";

    fn err(extra: &str) -> String {
        let text = format!("{DATA}{extra}");
        aidnav_io::config::parse_toml::<ProcessConfig>(&text, std::path::Path::new("p.toml"))
            .unwrap_err()
            .to_string()
    }

    /// The application's scheme defaults are the engine's, by value.
    #[test]
    fn the_scheme_defaults_are_the_engines() {
        use aidnav_estimation::SchemeParameters;
        let engine = SchemeParameters::default();
        assert_eq!(GnssConfig::default().scheme_parameters(), engine);
        let cfg =
            aidnav_io::config::parse_toml::<ProcessConfig>(DATA, std::path::Path::new("p.toml"))
                .unwrap();
        assert_eq!(cfg.gnss.scheme_parameters(), engine);
    }

    /// Each scheme key of `[gnss]` is read into the engine's parameters; a
    /// value out of the engine's range is refused naming the file, the
    /// line, the key and the range.
    #[test]
    fn the_scheme_keys_are_read_and_bounded_by_the_engine() {
        use aidnav_estimation::adaptive::DiagonalRule;
        let text = format!(
            "{DATA}[gnss]\nchi2_probability = 0.99\nrecovering_after = 7\nhuber_k = 2.5\n\
             anomaly_gamma = 16.0\nadaptive_window = 12\nadaptive_diagonal_rule = \"any\"\n"
        );
        let cfg =
            aidnav_io::config::parse_toml::<ProcessConfig>(&text, std::path::Path::new("p.toml"))
                .unwrap();
        let p = cfg.gnss.scheme_parameters();
        assert_eq!(
            (p.chi2_probability, p.recovering_after, p.huber_k),
            (0.99, 7, 2.5)
        );
        assert_eq!((p.anomaly_gamma, p.adaptive_window), (16.0, 12));
        assert_eq!(p.adaptive_diagonal_rule, DiagonalRule::Any);
        for (line, range) in [
            ("chi2_probability = 1.0", "allowed 0 < chi2_probability < 1"),
            (
                "recovering_after = 0",
                "allowed 1 ≤ recovering_after ≤ 100000",
            ),
            ("huber_k = 0.0", "allowed 0.1 ≤ huber_k ≤ 100"),
            ("anomaly_gamma = 0.5", "allowed 1 ≤ anomaly_gamma ≤ 10000"),
            ("adaptive_window = 0", "allowed 1 ≤ adaptive_window ≤ 10000"),
        ] {
            let (key, value) = line.split_once(" = ").unwrap();
            let e = err(&format!("[gnss]\nuse_velocity = true\n{line}\n"));
            let shown: f64 = value.parse().unwrap();
            assert!(
                e.starts_with(&format!("p.toml:8: gnss.{key}: {shown} is out of range")),
                "{e}"
            );
            assert!(e.ends_with(range), "{e}");
        }
        let e = err("[gnss]\nadaptive_diagonal_rule = \"most\"\n");
        assert!(
            e.starts_with("p.toml:7: gnss.adaptive_diagonal_rule: ") && e.contains("any"),
            "{e}"
        );
    }

    #[test]
    fn the_base_config_loads() {
        aidnav_io::config::parse_toml::<ProcessConfig>(DATA, std::path::Path::new("p.toml"))
            .unwrap();
    }

    #[test]
    fn gnss_sigma_is_for_the_generic_csv_only_and_bounded() {
        let ok = "gnss_format = \"generic_csv\"\ngnss_sigma_m = [0.5, 1.0]\n";
        let cfg = aidnav_io::config::parse_toml::<ProcessConfig>(
            &format!("{DATA}{ok}"),
            std::path::Path::new("p.toml"),
        )
        .unwrap();
        assert_eq!(cfg.data.gnss_sigma_m, Some([0.5, 1.0]));
        let e = err("gnss_sigma_m = [0.5, 1.0]\n");
        assert!(
            e.contains("data.gnss_sigma_m: [0.5, 1] is out of range")
                && e.contains("only with gnss_format = \"generic_csv\""),
            "{e}"
        );
        let e = err("gnss_format = \"generic_csv\"\ngnss_sigma_m = [0.5, 0.0]\n");
        assert!(e.contains("data.gnss_sigma_m[1]: 0 is out of range"), "{e}");
        let e = err("gnss_format = \"generic_csv\"\ngnss_sigma_m = [0.5]\n");
        assert!(
            e.contains("data.gnss_sigma_m") && e.contains("length 2"),
            "{e}"
        );
    }

    #[test]
    fn imu_units_are_for_the_generic_csv_only() {
        let units = "imu_units = { gyro = \"deg_s\", accel = \"g\" }\n";
        let cfg = aidnav_io::config::parse_toml::<ProcessConfig>(
            &format!("{DATA}{units}"),
            std::path::Path::new("p.toml"),
        )
        .unwrap();
        assert_eq!(
            cfg.data.imu_units.map(|u| u.kind),
            Some(aidnav_io::kfgins::ImuKind::Rates)
        );
        let e = aidnav_io::config::parse_toml::<ProcessConfig>(
            &format!("{}{units}", DATA.replace("generic_csv", "kf_gins")),
            std::path::Path::new("p.toml"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("data.imu_units") && e.contains("only with imu_format = \"generic_csv\""),
            "{e}"
        );
        let e = err("imu_units = { gyro = \"deg\", accel = \"g\" }\n");
        assert!(e.contains("data.imu_units") && e.contains("deg_s"), "{e}");
    }

    #[test]
    fn the_aid_source_tables_are_bounded_and_name_their_key() {
        let ok = |extra: &str| {
            let text = format!("{DATA}{extra}");
            aidnav_io::config::parse_toml::<ProcessConfig>(&text, std::path::Path::new("p.toml"))
                .unwrap()
        };
        let cfg = ok("[wheel_speed]\nfile = \"w.csv\"\n[barometer]\nfile = \"b.csv\"\n");
        assert_eq!(cfg.state_layout().len(), 23);
        let cfg = ok("[wheel_speed]\nfile = \"w.csv\"\nscale_state = false\n");
        assert_eq!(cfg.state_layout().len(), 21);
        // The engine's recovery defaults are the table's.
        let recovery = aidnav_integration::ned::RecoveryConfig::default();
        assert_eq!(GnssConfig::default().recovery_parameters(), recovery);
        for (extra, key) in [
            ("[wheel_speed]\nsigma_mps = 0.1\n", "wheel_speed.file"),
            ("[barometer]\nsigma_m = 0.5\n", "barometer.file"),
            (
                "[wheel_speed]\nfile = \"w\"\ngate_probability = 0.2\n",
                "wheel_speed.gate_probability",
            ),
            (
                "[wheel_speed]\nfile = \"w\"\nsigma_mps = -1\n",
                "wheel_speed.sigma_mps",
            ),
            (
                "[wheel_speed]\nfile = \"w\"\nlever_arm_m = [0, 0, 1e9]\n",
                "wheel_speed.lever_arm_m[2]",
            ),
            (
                "[barometer]\nfile = \"b\"\nbias_sigma_m = inf\n",
                "barometer.bias_sigma_m",
            ),
            (
                "[barometer]\nfile = \"b\"\nmin_interval_s = -1\n",
                "barometer.min_interval_s",
            ),
            (
                "[filter]\nconvergence_monitor = true\n[barometer]\nfile = \"b\"\n",
                "filter.convergence_monitor",
            ),
            ("[gnss]\nrecovery_fixes = 1\n", "gnss.recovery_fixes"),
            ("[gnss]\nrecovery_margin = -1\n", "gnss.recovery_margin"),
        ] {
            let e = err(extra);
            assert!(e.contains(&format!("{key}: ")), "{key}: {e}");
        }
        let e = err("[wheel_speed]\nfile = \"w\"\nspeed = 3\n");
        assert!(e.contains("speed"), "{e}");
    }

    #[test]
    fn non_holonomic_sigma_and_rate_are_bounded() {
        for (value, shown) in [
            ("-0.1", "-0.1"),
            ("inf", "inf"),
            ("-inf", "-inf"),
            ("1e-170", "0."),
        ] {
            let e = err(&format!(
                "[constraints]\nnon_holonomic_sigma_mps = {value}\n"
            ));
            assert!(
                e.starts_with("p.toml:7: constraints.non_holonomic_sigma_mps: "),
                "{e}"
            );
            assert!(e.contains(shown) || e.contains("e-170"), "{e}");
        }
        for value in ["-10.0", "inf", "0.0"] {
            let e = err(&format!("[constraints]\nnon_holonomic_rate_hz = {value}\n"));
            assert!(
                e.starts_with("p.toml:7: constraints.non_holonomic_rate_hz: "),
                "{e}"
            );
        }
    }

    #[test]
    fn three_vectors_have_exactly_three_finite_elements() {
        for (table, key) in [
            ("imu", "mounting_deg"),
            ("initial", "attitude_deg"),
            ("initial", "velocity_ned_mps"),
            ("gnss", "lever_arm_m"),
        ] {
            let e = err(&format!("[{table}]\n{key} = [0.0, 0.0, 0.0, 1.0]\n"));
            assert!(e.starts_with(&format!("p.toml:7: {table}.{key}: ")), "{e}");
            assert!(
                e.contains("expected an array of length 3") || e.contains("length 3"),
                "{e}"
            );
            let e = err(&format!("[{table}]\n{key} = [0.0, 0.0]\n"));
            assert!(e.starts_with(&format!("p.toml:7: {table}.{key}: ")), "{e}");
            let e = err(&format!("[{table}]\n{key} = [0.0, nan, 0.0]\n"));
            assert!(
                e.starts_with(&format!("p.toml:7: {table}.{key}[1]: NaN is out of range")),
                "{e}"
            );
        }
        let e = err("[gnss]\nlever_arm_m = [0.0, 1e9, 0.0]\n");
        assert!(
            e.contains("gnss.lever_arm_m[1]: 1000000000 is out of range"),
            "{e}"
        );
    }

    #[test]
    fn sigma_that_underflows_when_squared_is_refused() {
        let e = err("[gnss]\nmin_position_sigma_m = 1e-170\n");
        assert!(
            e.starts_with("p.toml:7: gnss.min_position_sigma_m: "),
            "{e}"
        );
        let e = err("[imu.noise]\narw_deg_per_sqrt_h = 1e-170\n");
        assert!(
            e.starts_with("p.toml:7: imu.noise.arw_deg_per_sqrt_h: "),
            "{e}"
        );
        let e = err("[initial]\nheading_sigma_deg = 1e300\n");
        assert!(
            e.starts_with("p.toml:7: initial.heading_sigma_deg: "),
            "{e}"
        );
    }
}
