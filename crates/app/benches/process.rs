//! Throughput of `aidnav process` on the recorded drive (54 858 IMU samples,
//! 2 197 GNSS epochs), by stage: reading (+ mounting and smoothing), the NED
//! mechanization alone, the whole filter pass (mechanization, covariance,
//! GNSS, non-holonomic and standstill updates) and the same pass without the
//! standstill updates, the pass under the configured policy without and
//! with the RTS smoother, and writing the solution CSV.
//! Divide 54 858 by the time for IMU epochs per second.
//!
//! `cargo bench -p aidnav-app --bench process` (reads data/ of the
//! repository).

use std::hint::black_box;
use std::path::Path;

use aidnav_app::process::{Inputs, PolicyName, ProcessConfig, RunPlan, export, run_filter};
use aidnav_frames::{Rotation, Vec3};
use aidnav_ins::ned::{ImuIncrement, NedMechanization, NedState};
use criterion::{Criterion, criterion_group, criterion_main};

fn process(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let config = root.join("examples/drive_0708.toml");
    let (cfg, _) = aidnav_io::load_toml::<ProcessConfig>(&config).unwrap();
    let base = config.parent().unwrap().to_path_buf();
    let inputs = Inputs::load(&cfg, &base).unwrap();
    let mut g = c.benchmark_group("drive_0708");
    g.sample_size(10);
    g.bench_function("read", |b| {
        b.iter(|| black_box(Inputs::load(&cfg, &base).unwrap().imu.len()))
    });
    g.bench_function("mechanization", |b| {
        b.iter(|| {
            let start = NedState {
                position: inputs.gnss[0].position,
                velocity: Vec3::zeros(),
                attitude: Rotation::from_euler_angles(0.0, 0.0, 0.0),
            };
            let mut ins = NedMechanization::new(start);
            for w in inputs.imu.windows(2) {
                let dt = w[1].time_s - w[0].time_s;
                ins.update(&ImuIncrement {
                    dt_s: dt,
                    delta_angle: Vec3::assume_in_frame(
                        (w[0].angular_rate + w[1].angular_rate) * (0.5 * dt),
                    ),
                    delta_velocity: Vec3::assume_in_frame(
                        (w[0].specific_force + w[1].specific_force) * (0.5 * dt),
                    ),
                });
            }
            black_box(ins.state().velocity)
        })
    });
    g.bench_function("filter", |b| {
        b.iter(|| {
            black_box(
                run_filter(&cfg, &inputs, &RunPlan::default(), PolicyName::Accept)
                    .unwrap()
                    .epochs
                    .len(),
            )
        })
    });
    // The same pass without the standstill updates (zero velocity and zero
    // angular rate): the ratio of the two is their cost, in one run.
    let mut without = cfg.clone();
    without.constraints.zero_velocity = Some(false);
    g.bench_function("filter_without_standstill_updates", |b| {
        b.iter(|| {
            black_box(
                run_filter(&without, &inputs, &RunPlan::default(), PolicyName::Accept)
                    .unwrap()
                    .epochs
                    .len(),
            )
        })
    });
    // The same pass under the configured policy without and with the RTS
    // smoother (`output.smooth`): their difference is the smoother's cost,
    // forward recording and backward pass together.
    for (name, smooth) in [("filter_robust", false), ("filter_robust_smoothed", true)] {
        let plan = RunPlan {
            smooth,
            ..RunPlan::default()
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                black_box(
                    run_filter(&cfg, &inputs, &plan, cfg.gnss.policy)
                        .unwrap()
                        .epochs
                        .len(),
                )
            })
        });
    }
    let epochs = run_filter(&cfg, &inputs, &RunPlan::default(), PolicyName::Accept)
        .unwrap()
        .epochs;
    let dir = tempfile::tempdir().unwrap();
    g.bench_function("write_solution", |b| {
        b.iter(|| export::write_solution(&dir.path().join("solution.csv"), &epochs, &[]).unwrap())
    });
    g.finish();
}

criterion_group!(benches, process);
criterion_main!(benches);
