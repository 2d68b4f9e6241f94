//! `aidnav process --print-config`: a complete configuration with every key,
//! its default (the platform's where a preset decides) and a comment.
//!
//! The text is the serialized default configuration, so it cannot drift
//! from the code: each `key = value` line gets its comment from [`KEY_DOCS`]
//! (a test fails when a key has none), and the keys that default to "none"
//! are written commented out from [`OPTIONAL_KEYS`].

use super::config::{DataFiles, Platform, ProcessConfig};

/// One line of help per key, by dotted path, in no particular order.
pub const KEY_DOCS: &[(&str, &str)] = &[
    (
        "platform",
        "car | pedestrian | aircraft | generic: presets the constraints and thresholds marked (preset)",
    ),
    ("data.dir", "directory of the files, relative to this file"),
    ("data.imu", "IMU file"),
    (
        "data.imu_format",
        "rtklib_tagged (raw CSV in g and deg/s + .tag) | kf_gins (increments) | generic_csv",
    ),
    ("data.gnss", "GNSS file"),
    (
        "data.gnss_format",
        "rtklib_pos | kf_gins | nmea (GGA + RMC, GST for σ) | ubx (NAV-PVT) | generic_csv (see --help)",
    ),
    (
        "imu.time_offset_s",
        "added to the IMU time [s] (a logging delay)",
    ),
    (
        "imu.mounting_deg",
        "sensor → body (roll, pitch, yaw) [deg], Groves' Euler_to_CTM; body forward, right, down",
    ),
    (
        "imu.smoothing_s",
        "zero-phase moving average [s] against a gyro vibration line (0: none)",
    ),
    (
        "imu.noise.auto",
        "tune the noise first (Allan deviation at rest, then maximum likelihood; `aidnav tune`), starting from the values below",
    ),
    (
        "imu.noise.arw_deg_per_sqrt_h",
        "angle random walk [deg/√h]; this and the next five: one number or [x, y, z] per sensor axis",
    ),
    (
        "imu.noise.vrw_mps_per_sqrt_h",
        "velocity random walk [m/s/√h]",
    ),
    (
        "imu.noise.gyro_bias_deg_per_h",
        "gyro bias instability σ [deg/h]",
    ),
    (
        "imu.noise.accel_bias_mg",
        "accelerometer bias instability σ [mg]",
    ),
    ("imu.noise.gyro_scale_ppm", "gyro scale-factor σ [ppm]"),
    (
        "imu.noise.accel_scale_ppm",
        "accelerometer scale-factor σ [ppm]",
    ),
    (
        "imu.noise.bias_correlation_s",
        "correlation time of the biases [s]",
    ),
    (
        "imu.noise.scale_correlation_s",
        "correlation time of the scale factors [s]",
    ),
    (
        "imu.noise.scale_factors",
        "estimate the scale-factor states (false: frozen at zero)",
    ),
    (
        "initial.static_s",
        "standstill window at the start for levelling and the gyro bias [s]; not a standstill: align in motion",
    ),
    (
        "initial.heading_speed_mps",
        "(preset) GNSS speed above which the course gives the heading [m/s]",
    ),
    (
        "initial.heading_sigma_deg",
        "prior σ of the heading after a static start [deg]",
    ),
    (
        "initial.tilt_sigma_deg",
        "prior σ of roll and pitch after levelling at rest [deg]",
    ),
    (
        "initial.moving_tilt_sigma_deg",
        "prior σ of roll and pitch after an alignment in motion [deg]",
    ),
    (
        "initial.moving_heading_sigma_deg",
        "prior σ of the heading after an alignment in motion [deg]",
    ),
    (
        "gnss.lever_arm_m",
        "IMU → antenna in the body frame (forward, right, down) [m]",
    ),
    ("gnss.use_velocity", "update with the GNSS velocity too"),
    (
        "gnss.latency",
        "GNSS time-tag latency: seconds (a fix stamped t is the antenna at t − latency) or \"estimate\" (a filter state)",
    ),
    (
        "gnss.latency_sigma_s",
        "prior σ of an estimated latency [s]",
    ),
    (
        "gnss.estimate_lever_arm",
        "estimate the lever arm as filter states, starting from lever_arm_m (observable in turns)",
    ),
    (
        "gnss.lever_arm_sigma_m",
        "prior σ of each axis of an estimated lever arm [m]",
    ),
    (
        "gnss.min_position_sigma_m",
        "floor on the position σ of the file [m]",
    ),
    (
        "gnss.min_velocity_sigma_mps",
        "floor on the velocity σ of the file [m/s]",
    ),
    (
        "gnss.policy",
        "robust | accept | chi2_gate | recovering_gate | huber | rejection | limiting | adaptive_gain | limited_adaptive_gain | developed",
    ),
    (
        "gnss.recovery",
        "never lock out: reset position and velocity to an agreeing run of refused fixes",
    ),
    (
        "gnss.recovery_fixes",
        "refused fixes that must agree before a reset",
    ),
    (
        "gnss.recovery_probability",
        "χ²(3) probability of the pairwise agreement test",
    ),
    (
        "gnss.recovery_margin",
        "a reset state's covariance is (1 + margin) R of the fix",
    ),
    (
        "gnss.anomaly_gamma",
        "spec 20's detector: anomalous when νᵀν > γ tr S",
    ),
    (
        "gnss.adaptive_window",
        "innovations in eq. 4's window (adaptive_gain, limited_adaptive_gain)",
    ),
    (
        "gnss.chi2_probability",
        "chi2_gate, recovering_gate: reject when the NIS exceeds the χ²(m) quantile of this probability",
    ),
    (
        "gnss.recovering_after",
        "recovering_gate: accept again after this many rejections in a row [fixes]",
    ),
    (
        "gnss.huber_k",
        "huber: R inflated by √NIS / k when √NIS > k [dimensionless, σ of the innovation]",
    ),
    (
        "gnss.adaptive_diagonal_rule",
        "all | any: eq. 4 uses M̂ when all (any) of its diagonal exceeds H P⁻ Hᵀ's",
    ),
    (
        "gnss.quality_sigma_scale.float",
        "σ of RTK float solutions × this",
    ),
    (
        "gnss.quality_sigma_scale.dgps",
        "σ of DGPS / SBAS solutions × this",
    ),
    (
        "gnss.quality_sigma_scale.single",
        "σ of single-point solutions × this",
    ),
    (
        "gnss.sigma_scale",
        "every GNSS σ (after the quality factors and floors) × this",
    ),
    (
        "constraints.non_holonomic",
        "(preset) no lateral or vertical body velocity (a car)",
    ),
    ("constraints.non_holonomic_sigma_mps", "its σ [m/s]"),
    ("constraints.non_holonomic_rate_hz", "its rate [Hz]"),
    (
        "constraints.min_speed_mps",
        "no non-holonomic update below this speed [m/s]",
    ),
    (
        "constraints.non_holonomic_gate_probability",
        "χ²(2) gate of each constraint update (1: none); a rejected run names a misaligned vehicle frame",
    ),
    (
        "constraints.misalignment_deg",
        "vehicle frame against the body (roll, pitch, yaw) [deg]: v_vehicle = R_z(yaw) R_y(pitch) R_x(roll) v_body",
    ),
    (
        "constraints.estimate_misalignment",
        "estimate the misalignment's pitch and yaw as filter states (needs the non-holonomic constraint or a wheel speed)",
    ),
    (
        "constraints.misalignment_sigma_deg",
        "prior σ of the estimated pitch and yaw [deg]",
    ),
    (
        "constraints.zero_velocity",
        "(preset) zero-velocity and zero-angular-rate updates at a detected standstill",
    ),
    (
        "constraints.zero_velocity_sigma_mps",
        "σ of the zero-velocity update per axis [m/s]",
    ),
    (
        "constraints.zero_angular_rate_sigma_deg_s",
        "σ of the zero-angular-rate update per axis [deg/s]",
    ),
    (
        "constraints.zero_velocity_rate_hz",
        "rate of the standstill updates [Hz]",
    ),
    ("standstill.window_s", "window of the IMU statistics [s]"),
    (
        "standstill.max_speed_mps",
        "largest GNSS speed of a standstill (a fix within 1 s; none in an outage), raised to 3.7 × the fix's own horizontal velocity σ [m/s]",
    ),
    (
        "standstill.max_accel_std_mps2",
        "(preset) largest std of each accelerometer axis [m/s²]",
    ),
    (
        "standstill.max_gyro_std_deg_s",
        "(preset) largest std of each gyro axis [deg/s]",
    ),
    (
        "filter.feedback",
        "closed (seed 000) | open (seed 004's output correction)",
    ),
    (
        "filter.convergence_monitor",
        "spec 10's δ(n) on the instruments (per epoch in solution.csv)",
    ),
    (
        "filter.adaptive_noise",
        "spec 20 eq. 3, K ν νᵀ Kᵀ added to P before each position update: off | hard | averaged",
    ),
    (
        "filter.adaptive_noise_window",
        "epochs of the averaged term and of the anomaly guard's mean",
    ),
    (
        "outage_bridge.enabled",
        "score spec 20's predictors bridging the outage windows",
    ),
    ("outage_bridge.trend_window_s", "history of the trend [s]"),
    (
        "outage_bridge.model_window_s",
        "history of the self-organising model [s]",
    ),
    (
        "outage_bridge.model_decimation",
        "every n-th epoch of the model history is used",
    ),
    ("outage_bridge.relay.t1_s", "relay: hold until [s]"),
    ("outage_bridge.relay.t2_s", "relay: trend until [s]"),
    (
        "outage_bridge.relay.t3_s",
        "relay: combined trend until [s], the model after",
    ),
    (
        "outage_bridge.gmdh.max_degree",
        "highest polynomial degree of the candidates",
    ),
    (
        "outage_bridge.gmdh.frequencies",
        "given harmonic frequencies [rad/s]",
    ),
    ("outage_bridge.gmdh.max_units", "most units in a structure"),
    (
        "outage_bridge.gmdh.beam",
        "structures of each complexity carried on",
    ),
    (
        "outage_bridge.gmdh.min_improvement",
        "relative criterion improvement needed for one more unit",
    ),
    (
        "outage_bridge.gmdh.noise_guard",
        "the improvement must also exceed noise_guard / n_B",
    ),
    (
        "outage_bridge.gmdh.refine",
        "refine searched frequencies by golden section",
    ),
    (
        "outage_bridge.gmdh.split.kind",
        "training / checking split: alternating | latest (with fraction = 0.5)",
    ),
    (
        "score.outages_s",
        "simulated outage lengths [s] (spec 40's schedule)",
    ),
    (
        "score.lead_s",
        "first window this long after the first IMU sample [s]",
    ),
    ("score.gap_s", "GNSS between windows [s]"),
    (
        "score.outlier_fractions",
        "fractions of epochs given an injected outlier",
    ),
    ("score.outlier_m", "outlier size range [m]"),
    ("score.seed", "seed of the injected outliers"),
    (
        "score.reference_quality",
        "fix qualities scored against: fixed | float | sbas | dgps | single | ppp | unknown",
    ),
    (
        "score.post_outage_burst_s",
        "a burst this long after every 30 s outage [s] (0: no burst run)",
    ),
    (
        "tune.min_static_s",
        "shortest standstill for an Allan deviation [s] (shorter: start from [imu.noise])",
    ),
    (
        "tune.max_evaluations",
        "most filter passes of the likelihood search",
    ),
    (
        "tune.max_factor",
        "each fitted factor within [1/this, this] of its start",
    ),
    (
        "tune.initial_factor",
        "first step of the search, as a factor",
    ),
    (
        "tune.tolerance",
        "stop when the log-likelihood over the simplex spans less than this",
    ),
    (
        "tune.objective",
        "coasting (every fix's predictive likelihood, windows withheld) | innovations (one step, every fix)",
    ),
    (
        "tune.outage_s",
        "windows the coasting objective withholds [s] (default: the longest of score.outages_s)",
    ),
    (
        "tune.gap_s",
        "GNSS between two withheld windows [s] (default: score.gap_s)",
    ),
    (
        "output.smooth",
        "also the RTS-smoothed solution and its scores",
    ),
    (
        "output.kf_gins_text",
        "also navresult.txt in KF-GINS's layout",
    ),
    (
        "output.interval_s",
        "also rows between GNSS epochs every this many s (0: one row per GNSS epoch)",
    ),
    (
        "wheel_speed.file",
        "wheel-speed (odometer) file (generic CSV: time_s | gpst_s | gps_week + tow_s | utc, speed_mps | speed_kmh, optional sigma_mps; see --help)",
    ),
    (
        "checks.units",
        "the readers' IMU unit checks (median |f| ≈ 1 g, gyro at rest < 0.1 rad/s): error | warn | off",
    ),
    (
        "checks.turn_rate",
        "the gyro's yaw against the GNSS course while moving (a deg/rad mix-up): error | warn | off",
    ),
    ("wheel_speed.format", "generic_csv"),
    ("wheel_speed.time_offset_s", "added to the file's time [s]"),
    (
        "wheel_speed.sigma_mps",
        "σ of a sample without its own, floor of a given one [m/s]",
    ),
    (
        "wheel_speed.lever_arm_m",
        "IMU → wheel contact point, body frame (forward, right, down) [m]",
    ),
    (
        "wheel_speed.scale_state",
        "estimate the odometer's scale-factor error (a state)",
    ),
    ("wheel_speed.scale_sigma", "its prior σ [–]"),
    (
        "wheel_speed.scale_noise_per_sqrt_s",
        "its random-walk density [1/√s]",
    ),
    (
        "wheel_speed.gate_probability",
        "χ² gate probability of an update (1: no gate)",
    ),
    (
        "wheel_speed.min_interval_s",
        "at most one update per this interval [s] (0: every sample)",
    ),
    (
        "barometer.file",
        "barometer file (generic CSV: a time column as for wheel speed, height_m | pressure_pa | pressure_hpa (ISA), optional sigma_m; see --help)",
    ),
    ("barometer.format", "generic_csv"),
    ("barometer.time_offset_s", "added to the file's time [s]"),
    (
        "barometer.sigma_m",
        "σ of a sample without its own, floor of a given one [m]",
    ),
    (
        "barometer.bias_state",
        "estimate the barometer's height bias (a state; off: the heights must be ellipsoidal)",
    ),
    ("barometer.bias_sigma_m", "its prior σ [m]"),
    (
        "barometer.bias_noise_m_per_sqrt_s",
        "its random-walk density [m/√s]",
    ),
    (
        "barometer.gate_probability",
        "χ² gate probability of an update (1: no gate)",
    ),
    (
        "barometer.min_interval_s",
        "at most one update per this interval [s] (0: every sample)",
    ),
];

/// Keys whose default is "none", written commented out after their table's
/// keys: (table, line).
pub const OPTIONAL_KEYS: &[(&str, &str)] = &[
    (
        "data",
        "# imu_tags = \"imu.csv.tag\"        # RTKLIB time-tag file (imu_format = rtklib_tagged)",
    ),
    (
        "data",
        "# imu_units = { gyro = \"deg_s\", accel = \"g\", kind = \"rates\" }   # generic_csv with columns gx … az: rad_s | deg_s, m_s2 | g, rates | increments",
    ),
    (
        "data",
        "# gnss_sigma_m = [0.02, 0.04]      # σ [horizontal, vertical] of a generic CSV without σ columns [m]",
    ),
    (
        "initial",
        "# attitude_deg = [0.0, 0.0, 90.0]   # a given initial attitude (roll, pitch, yaw) [deg]",
    ),
    (
        "initial",
        "# velocity_ned_mps = [0.0, 0.0, 0.0] # with attitude_deg: the initial NED velocity [m/s]",
    ),
    (
        "initial",
        "# position_sigma_m = 0.1           # prior σ of position [m] (default: the first fix's σ)",
    ),
    (
        "initial",
        "# velocity_sigma_mps = 0.1         # prior σ of velocity [m/s] (default: standstill max speed / fix's σ)",
    ),
    (
        "outage_bridge.relay",
        "# t4_s = 60.0                      # relay: the model until T4 [s], its correction held after (default none: no end)",
    ),
    (
        "outage_bridge.gmdh",
        "# horizon_s = 30.0                 # forecast horizon of the combined criterion [s] (default none)",
    ),
    (
        "outage_bridge.gmdh",
        "# search = { min = 1e-4, max = 1e-2, count = 20 }   # searched frequencies [rad/s] (default none)",
    ),
    (
        "efficiency",
        "# sigma_gnss_m = 1.5               # σ_GNSS of K_eff [m, 3-D] (default: each fix's own σ)",
    ),
    (
        "efficiency",
        "# sigma_gnss_velocity_mps = 0.1    # σ_GNSS of velocity for selected.csv [m/s, 3-D] (default: each fix's)",
    ),
];

/// A complete configuration for `platform`: every key with its default,
/// a comment per key, the data files as placeholders to edit.
///
/// ```
/// use aidnav_app::process::{Platform, ProcessConfig, config_template};
/// let text = config_template(Platform::Car);
/// let cfg: ProcessConfig = toml::from_str(&text).unwrap();
/// assert!(cfg.non_holonomic());
/// ```
pub fn config_template(platform: Platform) -> String {
    let cfg = ProcessConfig {
        platform,
        data: DataFiles {
            dir: ".".into(),
            imu: "imu.csv".into(),
            imu_format: Default::default(),
            imu_tags: None,
            gnss: "gnss.pos".into(),
            gnss_format: Default::default(),
            gnss_sigma_m: None,
            imu_units: None,
        },
        imu: Default::default(),
        initial: Default::default(),
        gnss: Default::default(),
        constraints: Default::default(),
        standstill: Default::default(),
        filter: Default::default(),
        outage_bridge: Default::default(),
        efficiency: Default::default(),
        score: Default::default(),
        tune: Default::default(),
        output: Default::default(),
        checks: Default::default(),
        wheel_speed: None,
        barometer: None,
    }
    .resolved();
    // Serializing plain data to TOML cannot fail; an empty body would be
    // caught by the round-trip test.
    let body = toml::to_string(&cfg).unwrap_or_default();
    let mut out = String::from(
        "# aidnav process configuration: every key with its default.\n\
         # `(preset)`: the default comes from `platform`; leave such a key out to\n\
         # follow the preset. Edit [data], then: aidnav process THIS_FILE\n\n",
    );
    let mut table = String::new();
    for line in body.lines() {
        if let Some(header) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            // The optional keys go with their table, before the blank line.
            let blank = out.ends_with("\n\n");
            if blank {
                out.pop();
            }
            flush_optional(&mut out, &table);
            if blank {
                out.push('\n');
            }
            table = header.to_string();
            out.push_str(line);
            out.push('\n');
            continue;
        }
        match line.split_once(" = ") {
            Some((key, _)) => {
                let path = if table.is_empty() {
                    key.to_string()
                } else {
                    format!("{table}.{key}")
                };
                let doc = doc_of(&path).unwrap_or("");
                out.push_str(&format!("{line:<40} # {doc}\n"));
            }
            None => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    flush_optional(&mut out, &table);
    for (table, section) in optional_sections() {
        let header = format!("[{table}]");
        out.push_str(&format!(
            "\n# {header:<38} # uncomment this table to use the stream\n"
        ));
        for line in section.lines() {
            let doc = line
                .split_once(" = ")
                .and_then(|(key, _)| doc_of(&format!("{table}.{key}")))
                .unwrap_or("");
            out.push_str(&format!("# {line:<38} # {doc}\n"));
        }
    }
    out
}

/// The optional tables (an aid source each), serialized with their
/// defaults and a placeholder file: the template writes them commented out.
fn optional_sections() -> [(&'static str, String); 2] {
    use super::config::{BarometerSection, WheelSpeedSection};
    let wheel = WheelSpeedSection {
        file: "wheel_speed.csv".into(),
        ..Default::default()
    };
    let baro = BarometerSection {
        file: "barometer.csv".into(),
        ..Default::default()
    };
    // Serializing plain data to TOML cannot fail (see above).
    [
        ("wheel_speed", toml::to_string(&wheel).unwrap_or_default()),
        ("barometer", toml::to_string(&baro).unwrap_or_default()),
    ]
}

/// The template with its optional tables uncommented (for tests: every key
/// of every table then parses and is documented).
#[cfg(test)]
fn uncomment_optional_sections(text: &str) -> String {
    let mut inside = false;
    let mut out = Vec::new();
    for line in text.lines() {
        if let Some(rest) = line.strip_prefix("# [") {
            inside = optional_sections()
                .iter()
                .any(|(t, _)| rest.starts_with(&format!("{t}]")));
        } else if line.is_empty() {
            inside = false;
        }
        out.push(if inside {
            line.trim_start_matches("# ")
        } else {
            line
        });
    }
    out.join("\n")
}

/// The comment of a dotted key.
pub fn doc_of(path: &str) -> Option<&'static str> {
    KEY_DOCS.iter().find(|(k, _)| *k == path).map(|(_, d)| *d)
}

fn flush_optional(out: &mut String, table: &str) {
    for (t, line) in OPTIONAL_KEYS {
        if *t == table {
            out.push_str(line);
            out.push('\n');
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key of the serialized configuration, dotted.
    fn keys(value: &toml::Value, prefix: &str, out: &mut Vec<String>) {
        if let toml::Value::Table(t) = value {
            for (k, v) in t {
                let path = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                if v.is_table() {
                    keys(v, &path, out);
                } else {
                    out.push(path);
                }
            }
        }
    }

    #[test]
    fn the_template_round_trips_and_documents_every_key() {
        for platform in [
            Platform::Car,
            Platform::Pedestrian,
            Platform::Aircraft,
            Platform::Generic,
        ] {
            let text = config_template(platform);
            let cfg: ProcessConfig = toml::from_str(&text).unwrap();
            assert_eq!(cfg.platform, platform);
            assert!(cfg.wheel_speed.is_none() && cfg.barometer.is_none());
            let cfg: ProcessConfig = toml::from_str(&uncomment_optional_sections(&text)).unwrap();
            assert_eq!(cfg.wheel_speed.as_ref().unwrap().sigma_mps, 0.1);
            assert_eq!(cfg.barometer.as_ref().unwrap().bias_sigma_m, 100.0);
            // Resolving again changes nothing: the preset values are written.
            assert_eq!(cfg, cfg.resolved());
            let mut all = Vec::new();
            keys(&toml::Value::try_from(&cfg).unwrap(), "", &mut all);
            assert!(all.len() > 60, "{}", all.len());
            for k in &all {
                assert!(doc_of(k).is_some(), "no comment for key {k}");
            }
            // And no comment for a key that no longer exists.
            for (k, _) in KEY_DOCS {
                assert!(all.iter().any(|a| a == k), "{k} documented but absent");
            }
        }
    }

    #[test]
    fn the_optional_keys_parse_when_uncommented() {
        let text = config_template(Platform::Generic);
        let uncommented: String = text
            .lines()
            .map(|l| {
                if OPTIONAL_KEYS.iter().any(|(_, o)| *o == l) {
                    l.trim_start_matches("# ")
                } else {
                    l
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        let cfg: ProcessConfig = toml::from_str(&uncommented).unwrap();
        assert_eq!(cfg.initial.attitude_deg, Some([0.0, 0.0, 90.0]));
        assert_eq!(cfg.efficiency.sigma_gnss_m, Some(1.5));
        assert_eq!(cfg.outage_bridge.gmdh.horizon_s, Some(30.0));
        assert!(cfg.data.imu_tags.is_some());
    }

    #[test]
    fn presets_differ_where_the_table_says() {
        let car = toml::from_str::<ProcessConfig>(&config_template(Platform::Car)).unwrap();
        let walk = toml::from_str::<ProcessConfig>(&config_template(Platform::Pedestrian)).unwrap();
        let air = toml::from_str::<ProcessConfig>(&config_template(Platform::Aircraft)).unwrap();
        assert!(car.non_holonomic() && car.zero_velocity());
        assert!(!walk.non_holonomic() && walk.zero_velocity());
        assert!(!air.non_holonomic() && !air.zero_velocity());
        assert_eq!(walk.heading_speed_mps(), 0.5);
        assert_eq!(car.heading_speed_mps(), 2.0);
    }
}
