#!/usr/bin/env bash
# Rerun the performance comparison of README.md § Performance on this machine.
# Needs: g++, Eigen 3 headers (Debian: libeigen3-dev), Python 3 with numpy and
# filterpy (pip install filterpy). Run from the repository root; takes ~3 min.
set -euo pipefail
cd "$(dirname "$0")/.."
EIGEN=${EIGEN_INCLUDE:-/usr/include/eigen3}
out=$(mktemp -d)
echo "== Eigen (g++ -O3 -march=native), same step, same matrices"
g++ -O3 -march=native -DNDEBUG -I"$EIGEN" bench/cpp/kf_step.cpp -o "$out/kf_eigen"
"$out/kf_eigen"
echo "== Eigen with aidnav's input/output checks (-DCHECKS)"
g++ -O3 -march=native -DNDEBUG -DCHECKS -I"$EIGEN" bench/cpp/kf_step.cpp -o "$out/kf_eigen_checks"
"$out/kf_eigen_checks"
echo "== FilterPy KalmanFilter"
python3 bench/filterpy_step.py
echo "== aidnav, default release build"
cargo bench -q -p aidnav-estimation --bench kalman_step -- --warm-up-time 1 --measurement-time 4 'predict_update/(fixed|dyn)/[0-9]+x6$' 2>&1 | grep -E '^predict_update|time:'
echo "== aidnav, -C target-cpu=native (the flags Eigen gets)"
RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR=target/native cargo bench -q -p aidnav-estimation --bench kalman_step -- --warm-up-time 1 --measurement-time 4 'predict_update/(fixed|dyn)/[0-9]+x6$' 2>&1 | grep -E '^predict_update|time:'
