#!/usr/bin/env bash
# Rerun the step comparison of README.md § Performance on this machine and
# print its table: one Kalman predict + update (Joseph form, Cholesky-solved
# gain), 15 states / 6 measurements and 21 / 6, in Eigen 3 (g++ -O3
# -march=native, without and with aidnav's checks), aidnav (default portable
# release build and -C target-cpu=native; fixed and run-time sizes) and
# FilterPy, the same matrices everywhere.
#
# Needs: g++, Eigen 3 headers (Debian: libeigen3-dev; or EIGEN_INCLUDE=dir),
# Python 3 with numpy and filterpy (pip install filterpy; or PYTHON=path of
# an interpreter that has them — without, FilterPy's row says n/a).
# ROUNDS (default 3) interleaved rounds of every program; the table gives
# the median over rounds of each program's own median. Takes ~1 min per round
# after the builds.
#
# Writes only into the build directory, ${CARGO_TARGET_DIR:-target} of this
# repository: bench-step/ (the Eigen binaries and the per-round results),
# criterion/ (criterion's reports) and native/ (the -C target-cpu=native
# build) — never beside the sources, also when CARGO_TARGET_DIR points elsewhere.
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
target=${CARGO_TARGET_DIR:-$repo/target}
case $target in /*) ;; *) target=$repo/$target ;; esac
EIGEN=${EIGEN_INCLUDE:-/usr/include/eigen3}
PYTHON=${PYTHON:-python3}
ROUNDS=${ROUNDS:-3}
out=$target/bench-step
mkdir -p "$out"
results=$out/rounds.txt
: >"$results"
filter='predict_update/(fixed|dyn)/[0-9]+x6$'
criterion_args=(--warm-up-time 1 --measurement-time 3 "$filter")

echo "== building (Eigen twice, aidnav default and native)"
# (Eigen takes minutes to compile on a loaded machine: only when the source is newer.)
for variant in kf_eigen kf_eigen_checks; do
  if [ ! "$out/$variant" -nt bench/cpp/kf_step.cpp ]; then
    checks=; [ $variant = kf_eigen_checks ] && checks=-DCHECKS
    g++ -O3 -march=native -DNDEBUG $checks -I"$EIGEN" bench/cpp/kf_step.cpp -o "$out/$variant"
  fi
done
CARGO_TARGET_DIR=$target cargo bench -q -p aidnav-estimation --bench kalman_step --no-run
RUSTFLAGS="-C target-cpu=native" CARGO_TARGET_DIR=$target/native \
  cargo bench -q -p aidnav-estimation --bench kalman_step --no-run
have_filterpy=1
if ! PYTHONDONTWRITEBYTECODE=1 "$PYTHON" -c 'import filterpy' 2>/dev/null; then
  have_filterpy=0
  echo "(no filterpy for $PYTHON: its row is n/a; pip install filterpy or set PYTHON)"
fi

# criterion's median of the last run of one benchmark, in ns.
criterion_median() { # criterion_dir bench_dir
  "$PYTHON" -c 'import json,sys; print(json.load(open(sys.argv[1]))["median"]["point_estimate"])' \
    "$1/$2/new/estimates.json"
}
# "name: median X ns ..." lines of the Eigen and FilterPy programs → results.
record_lines() { # label
  sed -nE "s/.* ([0-9]+x6): median ([0-9.]+) ns.*/$1 \1 \2/p" >>"$results"
}

for round in $(seq 1 "$ROUNDS"); do
  echo "== round $round of $ROUNDS"
  "$out/kf_eigen" | tee /dev/stderr | record_lines eigen
  "$out/kf_eigen_checks" | tee /dev/stderr | record_lines eigen_checks
  if [ "$have_filterpy" = 1 ]; then
    PYTHONDONTWRITEBYTECODE=1 "$PYTHON" bench/filterpy_step.py | tee /dev/stderr | record_lines filterpy
  fi
  for build in default native; do
    if [ $build = default ]; then dir=$target; flags=; else dir=$target/native; flags="-C target-cpu=native"; fi
    RUSTFLAGS="$flags" CARGO_TARGET_DIR=$dir cargo bench -q -p aidnav-estimation --bench kalman_step \
      -- "${criterion_args[@]}" >/dev/null 2>&1
    for kind in fixed dyn; do
      for size in 15x6 21x6; do
        ns=$(criterion_median "$dir/criterion" "predict_update_${kind}_$size")
        echo "aidnav_${build}_$kind $size $ns" | tee -a "$results" >&2
      done
    done
  done
done

echo
echo "== one predict + update, median ns over $ROUNDS interleaved rounds ($(date -u '+%Y-%m-%d %H:%M UTC'))"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores;" \
  "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
eigen_version=$(sed -nE 's/#define EIGEN_(WORLD|MAJOR|MINOR)_VERSION ([0-9]+)/\2/p' "$EIGEN/Eigen/src/Core/util/Macros.h" | paste -sd.)
echo "Eigen $eigen_version, g++ $(g++ -dumpfullversion), $(rustc --version | cut -d' ' -f1-2)"
if [ "$have_filterpy" = 1 ]; then
  PYTHONDONTWRITEBYTECODE=1 "$PYTHON" -c 'import filterpy, numpy, sys; print(f"FilterPy {filterpy.__version__}, numpy {numpy.__version__}, CPython {sys.version.split()[0]}")'
fi
echo
"$PYTHON" - "$results" <<'PY'
import statistics, sys
rows = {}
for line in open(sys.argv[1]):
    name, case, ns = line.split()
    rows.setdefault(name, {}).setdefault(case, []).append(float(ns))
med = {n: {c: statistics.median(v) for c, v in cs.items()} for n, cs in rows.items()}
labels = [
    ("eigen", "Eigen fixed size, g++ -O3 -march=native"),
    ("eigen_checks", "Eigen, same, plus aidnav's input/output checks"),
    ("aidnav_default_fixed", "aidnav fixed size, default release build (portable x86-64)"),
    ("aidnav_native_fixed", "aidnav fixed size, -C target-cpu=native"),
    ("aidnav_default_dyn", "aidnav run-time size (Dyn), default release build"),
    ("aidnav_native_dyn", "aidnav run-time size (Dyn), -C target-cpu=native"),
    ("filterpy", "FilterPy KalmanFilter"),
]
cases = ["15x6", "21x6"]
def us(n, c):
    v = med.get(n, {}).get(c)
    return "n/a" if v is None else f"{v / 1000:.2f} µs"
def ratio(n, c):
    v, e = med.get(n, {}).get(c), med.get("eigen", {}).get(c)
    return "n/a" if v is None or e is None else f"{v / e:.2f}"
print("| implementation | 15 states / 6 meas. | 21 / 6 | ÷ Eigen, 15/6 | ÷ Eigen, 21/6 |")
print("| --- | --- | --- | --- | --- |")
for n, label in labels:
    print(f"| {label} | {us(n, cases[0])} | {us(n, cases[1])} | {ratio(n, cases[0])} | {ratio(n, cases[1])} |")
PY
