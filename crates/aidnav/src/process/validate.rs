//! Validation of the configuration of `aidnav process`: every field in
//! its range, errors naming the table and the key.

use aidnav_io::config::{Invalid, Validate, all_positive, count_in_range, in_range, non_negative};

use aidnav_estimation::gmdh::{GmdhConfig, GmdhError};

use super::config::{ImuFormat, ProcessConfig};

impl Validate for ProcessConfig {
    fn validate(&self) -> Result<(), Invalid> {
        validate_inputs(self)?;
        validate_supervision_and_scores(self)
    }
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
    in_range("time_offset_s", cfg.imu.time_offset_s, -10.0, 10.0).map_err(|e| e.within("imu"))?;
    in_range("smoothing_s", cfg.imu.smoothing_s, 0.0, 5.0).map_err(|e| e.within("imu"))?;
    let n = &cfg.imu.noise;
    all_positive(
        "imu.noise",
        &[
            ("arw_deg_per_sqrt_h", n.arw_deg_per_sqrt_h),
            ("vrw_mps_per_sqrt_h", n.vrw_mps_per_sqrt_h),
            ("gyro_bias_deg_per_h", n.gyro_bias_deg_per_h),
            ("accel_bias_mg", n.accel_bias_mg),
            ("gyro_scale_ppm", n.gyro_scale_ppm),
            ("accel_scale_ppm", n.accel_scale_ppm),
            ("correlation_s", n.correlation_s),
        ],
    )?;
    all_positive(
        "initial",
        &[
            ("static_s", cfg.initial.static_s),
            ("heading_speed_mps", cfg.initial.heading_speed_mps),
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
    in_range("anomaly_gamma", cfg.gnss.anomaly_gamma, 1.0, 1e4).map_err(|e| e.within("gnss"))?;
    count_in_range("adaptive_window", cfg.gnss.adaptive_window, 1, 10_000)
        .map_err(|e| e.within("gnss"))?;
    count_in_range(
        "adaptive_noise_window",
        cfg.filter.adaptive_noise_window,
        1,
        10_000,
    )
    .map_err(|e| e.within("filter"))?;
    Ok(())
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
    count_in_range("model_decimation", b.model_decimation, 1, 1000)
        .map_err(|e| e.within("outage_bridge"))?;
    validate_gmdh(&b.gmdh)?;
    if let Some(sg) = cfg.efficiency.sigma_gnss_m {
        all_positive("efficiency", &[("sigma_gnss_m", sg)])?;
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
}
