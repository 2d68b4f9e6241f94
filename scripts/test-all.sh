#!/usr/bin/env bash
# The whole test suite, the README's one test command: the Rust workspace
# (unit, integration, property and doc tests), then the Python package —
# a virtual environment (AIDNAV_VENV, default target/py-venv) gets what
# the Python tests need from PyPI (numpy, pandas, filterpy,
# dask[distributed], pytest; maturin comes with pip's build), the package
# is built and installed from ./python, and pytest runs python/tests
# against the CLI built here. Works on a fresh machine with a Rust
# toolchain and CPython ≥ 3.9 with venv and pip.
set -euo pipefail
cd "$(dirname "$0")/.."
target=${CARGO_TARGET_DIR:-target}

cargo test --workspace
# The CLI the Python tests compare with: the binary cargo test built for
# the CLI's integration tests (the test profile, optimised).
cli="$target/debug/aidnav"
[ -x "$cli" ] || { echo "no $cli after cargo test" >&2; exit 1; }

venv=${AIDNAV_VENV:-$target/py-venv}
python=${PYTHON:-python3}
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install -q numpy pandas filterpy "dask[distributed]" pytest
# A release build, as users get it (maturin cannot build a cdylib with
# cargo's test profile: that profile means a test harness).
"$venv/bin/python" -m pip install -q --force-reinstall --no-deps ./python
AIDNAV_CLI="$cli" "$venv/bin/python" -m pytest python/tests -q -p no:cacheprovider
