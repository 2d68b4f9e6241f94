#!/usr/bin/env bash
# Rerun the performance comparison of README.md § Performance on this machine.
# Needs: g++, Eigen 3 headers (Debian: libeigen3-dev), Python 3 with numpy and
# filterpy (pip install filterpy). Run from anywhere; takes ~3 min.
# Writes only into the build directory, ${CARGO_TARGET_DIR:-target} of this
# repository: bench-step/ (the Eigen binaries), criterion's reports, and
# native/ (the -C target-cpu=native build) — never beside the sources, also
# when CARGO_TARGET_DIR points elsewhere.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
target=${CARGO_TARGET_DIR:-$repo/target}
EIGEN=${EIGEN_INCLUDE:-/usr/include/eigen3}
out=$target/bench-step
mkdir -p "$out"
echo "== Eigen (g++ -O3 -march=native), same step, same matrices"
g++ -O3 -march=native -DNDEBUG -I"$EIGEN" bench/cpp/kf_step.cpp -o "$out/kf_eigen"
"$out/kf_eigen"
echo "== Eigen with aidnav's input/output checks (-DCHECKS)"
g++ -O3 -march=native -DNDEBUG -DCHECKS -I"$EIGEN" bench/cpp/kf_step.cpp -o "$out/kf_eigen_checks"
"$out/kf_eigen_checks"
echo "== FilterPy KalmanFilter"
PYTHONDONTWRITEBYTECODE=1 python3 bench/filterpy_step.py
echo "== aidnav, default release build"
CARGO_TARGET_DIR=$target cargo bench -q -p aidnav-estimation --bench kalman_step -- --warm-up-time 1 --measurement-time 4 'predict_update/(fixed|dyn)/[0-9]+x6$' 2>&1 | grep -E '^predict_update|time:'
echo "== aidnav, -C target-cpu=native (the flags Eigen gets)"
RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR=$target/native cargo bench -q -p aidnav-estimation --bench kalman_step -- --warm-up-time 1 --measurement-time 4 'predict_update/(fixed|dyn)/[0-9]+x6$' 2>&1 | grep -E '^predict_update|time:'
