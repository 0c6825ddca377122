#!/usr/bin/env bash
# The whole test suite, as CI runs it (.ci/run calls this script):
#   1. the Rust tests: cargo test --workspace --release (also builds target/release/laparo);
#   2. the Python package: a venv (target/pyvenv, or $LAPARO_VENV) with maturin, pytest and numpy
#      from PyPI, the extension built by `maturin develop --release` into the workspace target dir
#      (only pyo3, numpy and laparo-py compile on top of step 1), then pytest, whose tests compare
#      every binding with the CLI binary of step 1.
# Needs only the Rust toolchain and CPython >= 3.9 with pip (PYTHON=python3.x to choose one).
# PyTorch is optional: its tests skip with a message when it is absent.
# SKIP_RUST=1 runs only the Python part (after a previous cargo build --release -p laparo).
set -euo pipefail
cd "$(dirname "$0")/.."

if [ "${SKIP_RUST:-0}" != 1 ]; then
    cargo test --workspace --release
fi

PY="${PYTHON:-python3}"
VENV="${LAPARO_VENV:-target/pyvenv}"
if [ ! -x "$VENV/bin/python" ]; then
    "$PY" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check "maturin>=1.5,<2" "pytest>=7" "numpy>=1.21"
if [ "${SKIP_RUST:-0}" = 1 ]; then
    cargo build --release -p laparo # the CLI the Python tests compare against (step 1 builds it otherwise)
fi
(
    # maturin develop installs into the active virtual environment.
    VIRTUAL_ENV="$(cd "$VENV" && pwd)"
    export VIRTUAL_ENV PATH="$VIRTUAL_ENV/bin:$PATH"
    maturin develop --release --quiet -m crates/laparo-py/Cargo.toml
)
"$VENV/bin/python" -m pytest crates/laparo-py/tests -q -rs
