//! What an added state costs: the NED filter's whole pass over a simulated
//! 450 s car drive (100 Hz IMU, 1 Hz GNSS position and velocity, the
//! non-holonomic constraint at 10 Hz), on the base 21 states and on
//! layouts grown by one (odometer scale), two (+ barometer bias) and five
//! (+ a mounting misalignment) states. The measurements are the same in
//! every case, so the difference is the larger covariance only; every
//! layout runs on fixed-size matrices.
//!
//! `cargo bench -p aidnav-integration --bench layouts`; divide 45 000 by
//! the time for IMU epochs per second.

use std::hint::black_box;

use aidnav_estimation::AcceptAll;
use aidnav_frames::{Body, Vec3};
use aidnav_integration::aiding::{
    AidSource, GnssConfig, GnssPolicies, GnssSource, NonHolonomic, NonHolonomicSource,
};
use aidnav_integration::ned::NedFilter;
use aidnav_integration::ned_loop::{AidingFix, Collector, EpochObserver, run_loop};
use aidnav_integration::state::{Augmented, BlockDynamics, StateLayout};
use aidnav_models::ned_ins::{ATTITUDE, ImuNoise, NedErrorModel, POSITION, VELOCITY};
use aidnav_sim::car::{CarLog, CarScenario, simulate_car};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::SVector;

/// One filter pass over the log on a layout of `N` states.
fn pass<const N: usize>(log: &CarLog, fixes: &[AidingFix], layout: &StateLayout) -> usize {
    let t0 = log.imu[100].time_s;
    let start = log.truth_at(t0).unwrap().nav_state();
    let model = NedErrorModel {
        noise: ImuNoise::default(),
    };
    let [sg, sa, kg, ka] = model.noise.instrument_sigmas();
    let mut sig = SVector::<f64, N>::repeat(0.01);
    for i in 0..3 {
        sig[POSITION + i] = 0.5;
        sig[VELOCITY + i] = 0.05;
        sig[ATTITUDE + i] = 0.01;
        sig[9 + i] = sg[i];
        sig[12 + i] = sa[i];
        sig[15 + i] = kg[i];
        sig[18 + i] = ka[i];
    }
    let lever = Vec3::<Body>::new(-0.5, 0.0, -1.0);
    let mut filter =
        NedFilter::<N>::with_layout(model, start, &sig, lever, layout.clone()).unwrap();
    let (mut p, mut v) = (AcceptAll, AcceptAll);
    let mut gnss = GnssSource::new(
        fixes,
        GnssConfig {
            min_position_sigma_m: 0.1,
            use_velocity: true,
            min_velocity_sigma_mps: 0.01,
            convergence_monitor: false,
            sigma_gnss_m: None,
        },
        GnssPolicies {
            position: &mut p,
            velocity: &mut v,
        },
    );
    let mut nhc = NonHolonomicSource::new(NonHolonomic {
        rate_hz: 10.0,
        sigma_mps: 0.1,
        min_speed_mps: 1.0,
        gate_probability: None,
    });
    let mut sources: Vec<&mut dyn AidSource<N>> = vec![&mut nhc, &mut gnss];
    let mut collector = Collector::default();
    let mut observers: Vec<&mut dyn EpochObserver> = vec![&mut collector];
    run_loop(
        &mut filter,
        &log.imu,
        100,
        &mut sources,
        0.0,
        &mut observers,
    )
    .unwrap();
    drop(observers);
    collector.fixes.len()
}

fn layouts(c: &mut Criterion) {
    let log = simulate_car(&CarScenario::default(), 1).unwrap();
    let fixes: Vec<AidingFix> = log
        .gnss
        .iter()
        .map(|&fix| AidingFix {
            fix,
            withheld: false,
        })
        .collect();
    let base = StateLayout::base();
    let one = base
        .clone()
        .with(Augmented::WheelSpeedScale, BlockDynamics::constant(0.02));
    let two = one
        .clone()
        .with(Augmented::BaroBias, BlockDynamics::random_walk(100.0, 0.05));
    let five = two
        .clone()
        .with(Augmented::LeverArm, BlockDynamics::constant(0.02));
    let mut g = c.benchmark_group("ned_filter_pass_450s");
    g.sample_size(10);
    g.bench_function("21_states", |b| {
        b.iter(|| black_box(pass::<21>(&log, &fixes, &base)))
    });
    g.bench_function("22_states", |b| {
        b.iter(|| black_box(pass::<22>(&log, &fixes, &one)))
    });
    g.bench_function("23_states", |b| {
        b.iter(|| black_box(pass::<23>(&log, &fixes, &two)))
    });
    g.bench_function("26_states", |b| {
        b.iter(|| black_box(pass::<26>(&log, &fixes, &five)))
    });
    g.finish();
}

criterion_group!(benches, layouts);
criterion_main!(benches);
