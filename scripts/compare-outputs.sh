#!/usr/bin/env bash
# Byte-for-byte comparison of aidnav's outputs between a base revision and
# the working tree: builds both, runs `reproduce all` and the recorded drive
# (`process examples/drive_0708.toml`) with each, and compares every file
# they write (CSV, JSON, SVG, text) byte for byte — summary.json without its
# wall-clock `timing_s`.
#
#   scripts/compare-outputs.sh [BASE_REV]      (default: HEAD)
#   DATA=/path/to/drive_0708 scripts/compare-outputs.sh HEAD~3
#
# The base is built in a git worktree under target/compare/ with its own
# target directory (nothing is written into the source tree); exit status 0
# when every file is identical, 1 otherwise.
set -euo pipefail
top=$(git rev-parse --show-toplevel)
cd "$top"
base_rev=${1:-HEAD}
base_sha=$(git rev-parse --verify "$base_rev^{commit}")
work="${COMPARE_WORK:-$top/target/compare}"
mkdir -p "$work"
tree="$work/base-tree"
if [ -d "$tree" ]; then
  git worktree remove --force "$tree" 2>/dev/null || rm -rf "$tree"
fi
git worktree prune
git worktree add --detach "$tree" "$base_sha" >/dev/null
data=${DATA:-}
if [ -z "$data" ]; then
  for d in "$top/data/rtklibexplorer-gnss-imu/drive_0708" "$top/../shared/data/rtklibexplorer-gnss-imu/drive_0708"; do
    if [ -d "$d" ]; then data=$(cd "$d" && pwd); break; fi
  done
fi
[ -n "$data" ] || { echo "no drive_0708 data found: set DATA=" >&2; exit 2; }

echo "building base $base_sha ..."
(cd "$tree" && CARGO_TARGET_DIR="$work/target-base" cargo build --release -q -p aidnav-cli)
echo "building the working tree ..."
cargo build --release -q -p aidnav-cli
base_bin="$work/target-base/release/aidnav"
new_bin="${CARGO_TARGET_DIR:-$top/target}/release/aidnav"

run() { # BIN CONFIG_ROOT OUT
  # Both runs write to the same folder (summary.json names its files), then
  # move it aside.
  local bin=$1 root=$2 out=$3 scratch="$work/out"
  rm -rf "$out" "$scratch"
  mkdir -p "$scratch"
  CI=true "$bin" reproduce all --out "$scratch/reproduce" >"$scratch/reproduce.log" 2>&1
  CI=true "$bin" process "$root/examples/drive_0708.toml" --data "$data" --out "$scratch/drive" >"$scratch/drive.log" 2>&1
  mv "$scratch" "$out"
}
echo "running base ..."
run "$base_bin" "$tree" "$work/out-base"
echo "running working tree ..."
run "$new_bin" "$top" "$work/out-new"

# Wall-clock timings ("timing_s") are the one thing meant to differ.
for f in $(find "$work/out-base" "$work/out-new" -name summary.json); do
  awk '/"timing_s": \[/ {skip=1; print "      \"timing_s\": (wall clock, not compared)"; next}
       skip && /\]/ {skip=0; next}
       !skip' "$f" >"$f.tmp" && mv "$f.tmp" "$f"
done

status=0
compared=0
while IFS= read -r f; do
  rel=${f#"$work/out-base/"}
  case "$rel" in *.log) continue ;; esac
  compared=$((compared + 1))
  if [ ! -f "$work/out-new/$rel" ]; then
    echo "MISSING  $rel"; status=1
  elif ! cmp -s "$f" "$work/out-new/$rel"; then
    echo "DIFFERS  $rel"; status=1
  fi
done < <(find "$work/out-base" -type f | sort)
while IFS= read -r f; do
  rel=${f#"$work/out-new/"}
  case "$rel" in *.log) continue ;; esac
  [ -f "$work/out-base/$rel" ] || { echo "NEW      $rel"; status=1; }
done < <(find "$work/out-new" -type f | sort)
if [ $status -eq 0 ]; then
  echo "identical: $compared files (reproduce all + drive) against $base_sha"
else
  echo "outputs differ from $base_sha (outputs under $work/out-base and $work/out-new)"
fi
git worktree remove --force "$tree"
exit $status
