#!/usr/bin/env bash
# The zoo: every scenario of zoo/*.toml simulated, processed by aidnav with
# the configuration a new user would write and with the matched noise
# model, scored against its truth; prints one row per log.
#
#   bash bench/zoo.sh [OUT_DIR] [SCENARIO.toml …]
#
# OUT_DIR (default ${CARGO_TARGET_DIR:-target}/zoo): one folder per log
# (its files, truth.csv, aidnav.toml, summary.json with the planted
# installation), zoo.csv (every score, the planted mounting, lever arm and
# latency, aidnav's error for a log it refused) and summary.json. Without
# scenario arguments, all of zoo/*.toml. Builds the release CLI first;
# prints the wall time of the zoo run, the date and the CPU.
set -euo pipefail
[[ ${1:-} == -h || ${1:-} == --help ]] && { sed -n '2,13p' "$0" | sed 's/^# \{0,1\}//'; exit 0; }
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}
out=${1:-$target/zoo}
shift || true
if [[ $# -eq 0 ]]; then set -- zoo/*.toml; fi
cargo build --release --quiet --bin aidnav
start=$(date +%s.%N)
"$target/release/aidnav" zoo "$@" --out "$out"
end=$(date +%s.%N)
printf "%d logs in %.1f s wall; %s; %s\n" "$#" "$(awk -v a="$start" -v b="$end" "BEGIN{print b-a}")" "$(date -u +%FT%TZ)" \
    "$(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
