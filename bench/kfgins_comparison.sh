#!/usr/bin/env bash
# aidnav against KF-GINS on the recorded drive, end to end, interleaved.
#
#   bash bench/kfgins_comparison.sh KF_GINS_SOURCE_DIR [RUNS]
#
# KF_GINS_SOURCE_DIR: a checkout of https://github.com/i2Nav-WHU/KF-GINS (its
# CMakeLists.txt and ThirdParty/ with Eigen, yaml-cpp, abseil). It is never
# written to: KF-GINS's CMakeLists puts its binary and libraries into the
# source tree (bin/, lib/), so the script copies the sources into the build directory and
# builds the copy (CMake, Release). RUNS (default 5): rounds of three runs —
# aidnav on examples/drive_0708.toml (RTS smoother on), aidnav with the
# smoother off, KF-GINS on the converted drive — interleaved so all three see
# the same machine load, each after a `sync` outside its time.
#
# Everything goes under BENCH_DIR (default: ${CARGO_TARGET_DIR:-target}/kfgins-bench
# of this repository): src/ (the copy), build/, drive/ (aidnav convert's
# imu.txt, gnss.txt, kf-gins.yaml and KF-GINS's output), aidnav/ (aidnav's
# output). Needs: cmake ≥ 3.10, a C++14 compiler, cargo.
# Prints each run's wall time, the date and CPU, and a table of the medians
# and their ratios to KF-GINS.
set -euo pipefail

usage() {
    sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

[[ $# -ge 1 && $# -le 2 ]] || usage
[[ $1 == -h || $1 == --help ]] && usage
src=$1
runs=${2:-5}
[[ $runs =~ ^[1-9][0-9]*$ ]] || { echo "error: RUNS must be a positive integer, got '$runs'" >&2; exit 2; }
[[ -f $src/CMakeLists.txt && -d $src/src/kf-gins ]] ||
    { echo "error: $src is not a KF-GINS source directory (no CMakeLists.txt and src/kf-gins/)" >&2; exit 2; }
src=$(cd "$src" && pwd)
command -v cmake >/dev/null || { echo "error: cmake not found (Debian: apt-get install cmake)" >&2; exit 2; }

repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
target=${CARGO_TARGET_DIR:-$repo/target}
bench=${BENCH_DIR:-$target/kfgins-bench}
case "$bench/" in
    "$src"/*) echo "error: BENCH_DIR $bench is inside the KF-GINS sources" >&2; exit 2 ;;
esac
mkdir -p "$bench/src" "$bench/drive" "$bench/aidnav"

echo "== KF-GINS: copy $src → $bench/src, build (Release)"
# tar keeps modification times, so an unchanged copy is not rebuilt.
(cd "$src" && tar --exclude=./bin --exclude=./lib --exclude=./build --exclude=./dataset -cf - .) | (cd "$bench/src" && tar -xpf -)
cmake -S "$bench/src" -B "$bench/build" -DCMAKE_BUILD_TYPE=Release >"$bench/cmake.log"
cmake --build "$bench/build" -j "$(nproc)" >>"$bench/cmake.log"
kfgins=$bench/src/bin/KF-GINS
[[ -x $kfgins ]] || { echo "error: no $kfgins after the build (see $bench/cmake.log)" >&2; exit 1; }

echo "== aidnav: release build, convert the drive"
cargo build --release -q -p aidnav-cli
aidnav=$target/release/aidnav
config=examples/drive_0708.toml
"$aidnav" convert "$config" --to kf-gins --out "$bench/drive" 2>/dev/null
yaml=$bench/drive/kf-gins.yaml

# The same drive with the RTS smoother off (the data directory made absolute).
nosmooth=$bench/drive_0708_no_smoother.toml
sed -e "s|^dir = \"\.\./data/|dir = \"$repo/data/|" -e 's|^smooth = true |smooth = false |' "$config" >"$nosmooth"
grep -q '^smooth = false ' "$nosmooth" || { echo "error: $config has no 'smooth = true ' line to turn off" >&2; exit 1; }

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN {printf "%.4f", b - a}'; }
# timed LOG COMMAND...: run COMMAND (output to LOG), its wall time in $last.
# Each run starts after a `sync` that is not timed, so that no program pays
# for the writeback of the run before it: aidnav syncs each output file
# before it renames it into place (a write error then surfaces as an error,
# not as a truncated file), and right after KF-GINS has left 47 MB of
# output to the kernel those syncs took up to 6 ms each instead of under 1.
timed() {
    local log=$1 t0
    shift
    sync
    t0=$(now)
    "$@" >"$log" 2>&1
    last=$(elapsed "$t0" "$(now)")
}
a_times=() n_times=() k_times=()
for ((i = 1; i <= runs; i++)); do
    timed /dev/null "$aidnav" process "$config" --no-score --out "$bench/aidnav"
    a_times+=("$last")
    timed /dev/null "$aidnav" process "$nosmooth" --no-score --out "$bench/aidnav_no_smoother"
    n_times+=("$last")
    timed "$bench/kfgins.log" "$kfgins" "$yaml"
    k_times+=("$last")
    echo "run $i: aidnav ${a_times[-1]} s, aidnav smoother off ${n_times[-1]} s, KF-GINS ${k_times[-1]} s"
done

median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }
am=$(median "${a_times[@]}")
nm=$(median "${n_times[@]}")
km=$(median "${k_times[@]}")
echo "== $(date -u +%Y-%m-%d), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2- | sed 's/^ //'), $(nproc) cores; medians of $runs interleaved runs (wall time, process start to exit)"
awk -v a="$am" -v n="$nm" -v k="$km" 'BEGIN {
    printf "| program | median \\[s\\] | / KF-GINS | KF-GINS / it |\n| --- | --- | --- | --- |\n"
    printf "| aidnav process --no-score, drive_0708.toml (RTS smoother on) | %.3f | %.3f | %.1f× |\n", a, a / k, k / a
    printf "| aidnav process --no-score, smoother off | %.3f | %.3f | %.1f× |\n", n, n / k, k / n
    printf "| KF-GINS (Release), same drive via aidnav convert | %.3f | 1 | 1× |\n", k
}'
