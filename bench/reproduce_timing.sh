#!/usr/bin/env bash
# Wall time, CPU time and peak memory of the main jobs, and Monte Carlo
# scaling over the cores.
#
#   bash bench/reproduce_timing.sh [RUNS]
#
# RUNS (default 3) rounds of: `aidnav reproduce all --quiet`; the recorded
# drive's whole default run (`aidnav process examples/drive_0708.toml`:
# scoring and RTS smoothing); and `aidnav reproduce anomalies --quiet` with
# RAYON_NUM_THREADS=1 and with every core — interleaved, so all see the same
# machine load. Times come from /usr/bin/time (GNU time; Debian package
# `time`). Outputs go under ${CARGO_TARGET_DIR:-target}/reproduce-timing.
# Prints each run, the date, the CPU model and core count, and a table of
# the medians; the one- and many-thread anomaly summaries are compared
# (`cmp`), since the campaign must not depend on the thread count.
set -euo pipefail

usage() {
    sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
}

[[ $# -le 1 ]] || usage
[[ ${1:-} == -h || ${1:-} == --help ]] && usage
runs=${1:-3}
[[ $runs =~ ^[1-9][0-9]*$ ]] || { echo "error: RUNS must be a positive integer, got '$runs'" >&2; exit 2; }
[[ -x /usr/bin/time ]] || { echo "error: /usr/bin/time not found (Debian: apt-get install time)" >&2; exit 2; }

repo=$(cd "$(dirname "$0")/.." && pwd)
cd "$repo"
target=${CARGO_TARGET_DIR:-$repo/target}
out=$target/reproduce-timing
mkdir -p "$out"
cargo build --release -q -p aidnav-cli
aidnav=$target/release/aidnav
cores=$(nproc)

# timed NAME COMMAND…: runs the command, appends "NAME wall cpu peak_kB" to
# $out/times.txt and echoes it.
timed() {
    local name=$1
    shift
    /usr/bin/time -f "%e %U %S %M" -o "$out/time.txt" "$@" >"$out/$name.log" 2>&1 ||
        { echo "error: $name failed (see $out/$name.log)" >&2; exit 1; }
    read -r wall user sys peak <"$out/time.txt"
    local cpu
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
    echo "$name $wall $cpu $peak" >>"$out/times.txt"
    echo "  $name: wall $wall s, CPU $cpu s, peak $((peak / 1024)) MB"
}

: >"$out/times.txt"
for i in $(seq 1 "$runs"); do
    echo "== round $i of $runs"
    timed reproduce_all "$aidnav" reproduce all --quiet --out "$out/all"
    timed drive_process "$aidnav" process examples/drive_0708.toml --out "$out/drive"
    RAYON_NUM_THREADS=1 timed anomalies_1_thread "$aidnav" reproduce anomalies --quiet --out "$out/anomalies_1"
    RAYON_NUM_THREADS=$cores timed anomalies_all_threads "$aidnav" reproduce anomalies --quiet --out "$out/anomalies_n"
    cmp -s "$out/anomalies_1/summary.json" "$out/anomalies_n/summary.json" ||
        { echo "error: the anomalies summary depends on the thread count" >&2; exit 1; }
done

echo "== $(date -u '+%Y-%m-%d %H:%M UTC'), $(grep -m1 'model name' /proc/cpuinfo | sed 's/.*: //'), $cores cores; medians of $runs interleaved rounds; load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)"
awk -v cores="$cores" '
    { wall[$1] = wall[$1] " " $2; cpu[$1] = cpu[$1] " " $3; peak[$1] = peak[$1] " " $4 }
    function median(list,   n, v, i, j, t) {
        n = split(list, v, " ")
        for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (v[j] + 0 < v[i] + 0) { t = v[i]; v[i] = v[j]; v[j] = t }
        return n % 2 ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2
    }
    END {
        print "| job | wall \\[s\\] | CPU \\[s\\] | peak memory \\[MB\\] |"
        print "| --- | --- | --- | --- |"
        printf "| `aidnav reproduce all --quiet` | %.2f | %.2f | %.1f |\n", median(wall["reproduce_all"]), median(cpu["reproduce_all"]), median(peak["reproduce_all"]) / 1024
        printf "| `aidnav process examples/drive_0708.toml` (scoring, smoothing) | %.2f | %.2f | %.1f |\n", median(wall["drive_process"]), median(cpu["drive_process"]), median(peak["drive_process"]) / 1024
        printf "| `aidnav reproduce anomalies --quiet`, 1 thread | %.2f | %.2f | %.1f |\n", median(wall["anomalies_1_thread"]), median(cpu["anomalies_1_thread"]), median(peak["anomalies_1_thread"]) / 1024
        printf "| the same, %d threads | %.2f | %.2f | %.1f |\n", cores, median(wall["anomalies_all_threads"]), median(cpu["anomalies_all_threads"]), median(peak["anomalies_all_threads"]) / 1024
        printf "\nMonte Carlo scaling over %d cores (anomalies, wall 1 thread ÷ wall %d threads): %.2f×\n", cores, cores, median(wall["anomalies_1_thread"]) / median(wall["anomalies_all_threads"])
    }' "$out/times.txt"
