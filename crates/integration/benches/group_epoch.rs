//! One epoch of the large-group filter (spec 30 "scale"): three axes, each a
//! dense covariance over M members' positions and velocities, updated in
//! information form from M own position fixes and 10 M relative observations
//! (every member sees its 10 nearest neighbours). The epoch includes the
//! neighbour search, the structured predict, the accumulation of the sparse
//! information and the update. Memory: per axis the (2M)² covariance plus
//! about six M² workspace matrices.
//!
//! `cargo bench -p aidnav-integration --bench group_epoch`; the M = 2000 case takes
//! a couple of minutes (criterion's minimum of ten samples).

use std::hint::black_box;

use aidnav_integration::group::{GroupAxisFilter, k_nearest};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;

const NEIGHBOURS: usize = 10;

/// Deterministic formation: members on a jittered grid, 100 m apart.
fn positions(m: usize) -> Vec<Vector3<f64>> {
    let side = (m as f64).cbrt().ceil() as usize;
    (0..m)
        .map(|i| {
            let (a, b, c) = (i % side, (i / side) % side, i / (side * side));
            let jitter = ((i * 7919) % 101) as f64 / 101.0 * 20.0;
            Vector3::new(
                a as f64 * 100.0 + jitter,
                b as f64 * 100.0,
                c as f64 * 100.0 - jitter,
            )
        })
        .collect()
}

struct Group {
    truth: Vec<Vector3<f64>>,
    axes: Vec<GroupAxisFilter>,
}

impl Group {
    fn new(m: usize) -> Self {
        let truth = positions(m);
        let axes = (0..3)
            .map(|a| {
                let p: Vec<f64> = truth.iter().map(|t| t[a]).collect();
                GroupAxisFilter::new(m, 1.0, 1.0, false, &p, &vec![0.0; m], 10.0, 3.0).unwrap()
            })
            .collect();
        Self { truth, axes }
    }

    fn epoch(&mut self) {
        let neighbours = k_nearest(&self.truth, NEIGHBOURS);
        for (a, f) in self.axes.iter_mut().enumerate() {
            f.predict();
            for (l, t) in self.truth.iter().enumerate() {
                f.observe_own_position(l, t[a] + 3.0, 10.0).unwrap();
                for &k in &neighbours[l] {
                    f.observe_relative(l, k, t[a] - self.truth[k][a], 0.5)
                        .unwrap();
                }
            }
            f.update().unwrap();
        }
    }
}

fn group_epoch(c: &mut Criterion) {
    let mut g = c.benchmark_group("group_epoch_10_neighbours");
    g.sample_size(10);
    for m in [5usize, 50, 100, 500, 1000, 2000] {
        let mut group = Group::new(m);
        group.epoch(); // dense covariance from here on
        g.bench_with_input(BenchmarkId::from_parameter(m), &m, |b, _| {
            b.iter(|| {
                group.epoch();
                black_box(group.axes[0].position(0))
            })
        });
    }
    g.finish();
}

criterion_group!(benches, group_epoch);
criterion_main!(benches);
