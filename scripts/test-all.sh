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
# The CLI the Python tests compare with: cargo test's build of it (the test
# profile, optimised), so nothing is compiled twice.
cargo build --profile test -p aidnav-cli --bin aidnav

venv=${AIDNAV_VENV:-$target/py-venv}
python=${PYTHON:-python3}
[ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
"$venv/bin/python" -m pip install -q numpy pandas filterpy "dask[distributed]" pytest
# Built with the test profile here, reusing cargo test's dependencies (a
# plain `pip install ./python` builds in release).
MATURIN_PEP517_ARGS="--profile test" "$venv/bin/python" -m pip install -q --force-reinstall --no-deps ./python
AIDNAV_CLI="$target/debug/aidnav" "$venv/bin/python" -m pytest python/tests -q -p no:cacheprovider
