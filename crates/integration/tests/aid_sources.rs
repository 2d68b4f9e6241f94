//! The wheel-speed and barometer sources on a simulated car with known
//! truth (`aidnav_sim::car`): a 60 s GNSS outage, the drift of the IMU
//! position against the truth with and without each source.

use aidnav_estimation::AcceptAll;
use aidnav_frames::{Body, Vec3};
use aidnav_integration::aiding::{
    AidSource, BaroConfig, BaroSource, GnssConfig, GnssPolicies, GnssSource, NonHolonomic,
    NonHolonomicSource, WheelSpeedConfig, WheelSpeedSource,
};
use aidnav_integration::ned::NedFilter;
use aidnav_integration::ned_loop::{AidingFix, Collector, EpochObserver, run_loop};
use aidnav_integration::state::{Augmented, BlockDynamics, StateLayout};
use aidnav_models::ned_ins::{
    ACCEL_BIAS, ACCEL_SCALE, ATTITUDE, GYRO_BIAS, GYRO_SCALE, ImuNoise, NedErrorModel, POSITION,
    PerAxis, STATES, VELOCITY,
};
use aidnav_sim::car::{CarLog, CarScenario, simulate_car};
use nalgebra::SVector;

/// The outage, seconds from the log's start: in the urban part, with turns.
const OUTAGE_S: [f64; 2] = [200.0, 260.0];

fn scenario() -> CarScenario {
    let mut s = CarScenario::default();
    s.gnss.outages_s = vec![OUTAGE_S];
    s
}

/// The filter's model of the simulated IMU (the scenario's datasheet
/// numbers, its turn-on bias as the bias σ).
fn model(s: &CarScenario) -> NedErrorModel {
    let (g, a) = (&s.imu.gyro, &s.imu.accel);
    NedErrorModel {
        noise: ImuNoise {
            arw_deg_per_sqrt_h: PerAxis(g.angle_random_walk_deg_sqrt_h),
            vrw_mps_per_sqrt_h: PerAxis(a.velocity_random_walk_m_s_sqrt_h),
            gyro_bias_deg_per_h: PerAxis(g.turn_on_bias_sigma_deg_h),
            accel_bias_mg: PerAxis(a.turn_on_bias_sigma_mg),
            gyro_scale_ppm: PerAxis(g.scale_factor_sigma_ppm),
            accel_scale_ppm: PerAxis(a.scale_factor_sigma_ppm),
            ..ImuNoise::default()
        },
    }
}

/// Which sources aid the GNSS.
#[derive(Clone, Copy)]
struct Aiding {
    non_holonomic: bool,
    wheel_speed: bool,
    barometer: bool,
}

/// Largest horizontal and vertical IMU position error inside the outage
/// \[m\], from the solution rows every 0.5 s.
fn outage_errors<const N: usize>(
    s: &CarScenario,
    log: &CarLog,
    layout: StateLayout,
    aiding: Aiding,
) -> (f64, f64) {
    let model = model(s);
    let start = 100; // 1 s into the log
    let t0 = log.imu[start].time_s;
    let truth = log.truth_at(t0).unwrap().nav_state();
    let [sg, sa, kg, ka] = model.noise.instrument_sigmas();
    let mut sig = SVector::<f64, N>::zeros();
    for i in 0..3 {
        sig[POSITION + i] = 0.5;
        sig[VELOCITY + i] = 0.05;
        sig[ATTITUDE + i] = if i == 2 { 0.02 } else { 0.005 };
        sig[GYRO_BIAS + i] = sg[i];
        sig[ACCEL_BIAS + i] = sa[i];
        sig[GYRO_SCALE + i] = kg[i];
        sig[ACCEL_SCALE + i] = ka[i];
    }
    layout.fill_block_priors(&mut sig);
    let [lx, ly, lz] = s.gnss.lever_arm_m;
    let lever = Vec3::<Body>::new(lx, ly, lz);
    let mut filter = NedFilter::<N>::with_layout(model, truth, &sig, lever, layout).unwrap();
    let fixes: Vec<AidingFix> = log
        .gnss
        .iter()
        .map(|&fix| AidingFix {
            fix,
            withheld: false,
        })
        .collect();
    let (mut position_policy, mut velocity_policy) = (AcceptAll, AcceptAll);
    let mut gnss = GnssSource::new(
        &fixes,
        GnssConfig {
            min_position_sigma_m: 0.1,
            use_velocity: true,
            min_velocity_sigma_mps: 0.01,
            convergence_monitor: false,
            sigma_gnss_m: None,
        },
        GnssPolicies {
            position: &mut position_policy,
            velocity: &mut velocity_policy,
        },
    );
    let mut nhc = NonHolonomicSource::new(NonHolonomic {
        rate_hz: 10.0,
        sigma_mps: 0.1,
        min_speed_mps: 1.0,
        gate_probability: None,
    });
    let mut wheel = WheelSpeedSource::new(
        &log.wheel_speed,
        WheelSpeedConfig {
            sigma_mps: s.wheel_speed.noise_sigma_mps,
            lever_arm_m: {
                let [x, y, z] = s.wheel_speed.lever_arm_m;
                Vec3::new(x, y, z)
            },
            gate_probability: None,
            min_interval_s: 0.0,
        },
    );
    let mut baro = BaroSource::new(
        &log.baro,
        BaroConfig {
            sigma_m: s.baro.noise_sigma_m,
            gate_probability: None,
            min_interval_s: 0.0,
        },
    );
    let mut sources: Vec<&mut dyn AidSource<N>> = Vec::new();
    if aiding.non_holonomic {
        sources.push(&mut nhc);
    }
    sources.push(&mut gnss);
    if aiding.wheel_speed {
        sources.push(&mut wheel);
    }
    if aiding.barometer {
        sources.push(&mut baro);
    }
    let mut collector = Collector::default();
    let mut observers: Vec<&mut dyn EpochObserver> = vec![&mut collector];
    run_loop(
        &mut filter,
        &log.imu,
        start,
        &mut sources,
        0.5,
        &mut observers,
    )
    .unwrap();
    drop(observers);
    let log_start = log.imu[0].time_s;
    let (a, b) = (log_start + OUTAGE_S[0], log_start + OUTAGE_S[1]);
    let (mut horizontal, mut vertical) = (0.0f64, 0.0f64);
    let mut rows = 0;
    for row in collector
        .rows
        .iter()
        .filter(|r| r.time_s > a && r.time_s < b)
    {
        let truth = log.truth_at(row.time_s).unwrap();
        let e = truth.position.ned_to(&row.imu);
        horizontal = horizontal.max(e.x().hypot(e.y()));
        vertical = vertical.max(e.z().abs());
        rows += 1;
    }
    assert!(rows > 100, "{rows} rows in the outage");
    (horizontal, vertical)
}

const GNSS: Aiding = Aiding {
    non_holonomic: false,
    wheel_speed: false,
    barometer: false,
};

#[test]
fn the_odometer_shrinks_the_outage_drift_fivefold() {
    let s = scenario();
    let log = simulate_car(&s, 32).unwrap();
    let (free, _) = outage_errors::<STATES>(&s, &log, StateLayout::base(), GNSS);
    let nhc = Aiding {
        non_holonomic: true,
        ..GNSS
    };
    let (constrained, _) = outage_errors::<STATES>(&s, &log, StateLayout::base(), nhc);
    let layout =
        StateLayout::base().with(Augmented::WheelSpeedScale, BlockDynamics::constant(0.02));
    let odometer = Aiding {
        wheel_speed: true,
        ..nhc
    };
    let (aided, _) = outage_errors::<{ STATES + 1 }>(&s, &log, layout, odometer);
    println!(
        "60 s outage, largest horizontal error: GNSS only {free:.2} m, \
         with the constraint {constrained:.2} m, with the odometer {aided:.2} m"
    );
    assert!(aided * 5.0 <= free, "{aided} against {free}");
    assert!(aided < constrained, "{aided} against {constrained}");
}

#[test]
fn the_barometer_bounds_the_vertical_error_in_an_outage() {
    // A consumer-grade accelerometer, whose bias wanders enough in a
    // minute to move the free vertical channel by metres.
    let mut s = scenario();
    s.imu.accel.turn_on_bias_sigma_mg = [5.0; 3];
    s.imu.accel.bias_instability_mg = [1.0; 3];
    s.imu.accel.bias_correlation_time_s = [60.0; 3];
    let log = simulate_car(&s, 33).unwrap();
    let (_, free) = outage_errors::<STATES>(&s, &log, StateLayout::base(), GNSS);
    let drift = s.baro.drift_sigma_m;
    // The bias as a random walk whose 300 s growth is the drift's σ.
    let walk = drift / (s.baro.drift_correlation_time_s).sqrt();
    let layout = StateLayout::base().with(
        Augmented::BaroBias,
        BlockDynamics::random_walk(2.0 * s.baro.bias_m.abs().max(1.0), walk),
    );
    let baro = Aiding {
        barometer: true,
        ..GNSS
    };
    let (_, aided) = outage_errors::<{ STATES + 1 }>(&s, &log, layout, baro);
    assert!(aided * 2.0 < free, "{aided} against {free}");
    // Its own noise plus its bias's drift, at three σ.
    let bound = 3.0 * (s.baro.noise_sigma_m + drift);
    println!(
        "60 s outage, largest vertical error: GNSS only {free:.2} m, with the barometer \
         {aided:.2} m (bound {bound:.2} m)"
    );
    assert!(aided <= bound, "{aided} against {bound}");
}
