#!/usr/bin/env bash
# Run every cargo-fuzz target for MINUTES each (default 10), two at a time
# (the machine's cores), and print executions and findings per target.
#   scripts/fuzz.sh [MINUTES] [TARGET …]
# Needs the nightly toolchain; installs cargo-fuzz from crates.io if missing.
# Seeds: fuzz/corpus/<target>/seed-* (scripts/fuzz-seeds.py cuts them from
# the recorded logs). A crash lands in fuzz/artifacts/<target>/: commit it
# with its fix — `cargo test` replays it on stable.
set -euo pipefail
cd "$(git rev-parse --show-toplevel)/fuzz"
minutes=${1:-10}
shift || true
command -v cargo-fuzz >/dev/null || cargo install cargo-fuzz --locked
targets=("$@")
[ ${#targets[@]} -gt 0 ] || mapfile -t targets < <(cargo +nightly fuzz list)
# `cargo fuzz build` takes one target (or none: all of them).
for t in "${targets[@]}"; do cargo +nightly fuzz build -O "$t" >/dev/null; done
mkdir -p logs
run_one() {
  local t=$1
  # -rss_limit_mb: a reader may not need 2 GiB for a few kB of input;
  # -timeout: nor 10 s for one input (a loop).
  cargo +nightly fuzz run -O "$t" -- -max_total_time=$((minutes * 60)) \
    -rss_limit_mb=2048 -timeout=10 -max_len=65536 -print_final_stats=1 >"logs/$t.log" 2>&1 || true
  local execs crashes
  # (No match must not end the script under `set -e -o pipefail`.)
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "logs/$t.log" | awk '{print $2}' | tail -1 || true)
  [ -n "$execs" ] || execs=$(grep -o 'Done [0-9]* runs' "logs/$t.log" | awk '{print $2}' | tail -1 || true)
  crashes=$(find "artifacts/$t" -type f 2>/dev/null | wc -l)
  printf '%-22s %12s executions  %3s findings  (fuzz/logs/%s.log)\n' "$t" "${execs:-?}" "$crashes" "$t"
}
i=0
for t in "${targets[@]}"; do
  run_one "$t" &
  i=$((i + 1))
  if [ $((i % 2)) -eq 0 ]; then wait; fi
done
wait
