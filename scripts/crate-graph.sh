#!/usr/bin/env bash
# Prints the workspace's crate graph: each aidnav crate and the aidnav crates
# it depends on (normal dependencies; dev-dependencies apart).
#   scripts/crate-graph.sh
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
cargo metadata --format-version 1 --no-deps | python3 -c '
import json, sys
meta = json.load(sys.stdin)
names = {p["name"] for p in meta["packages"]}
for p in sorted(meta["packages"], key=lambda p: p["name"]):
    normal = sorted(d["name"] for d in p["dependencies"] if d["name"] in names and d["kind"] is None)
    dev = sorted(d["name"] for d in p["dependencies"] if d["name"] in names and d["kind"] == "dev")
    line = "%-20s -> %s" % (p["name"], ", ".join(normal) or "(no aidnav crate)")
    if dev:
        line += "   [dev: %s]" % ", ".join(dev)
    print(line)
'
