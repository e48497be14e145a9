#!/usr/bin/env bash
# The project's one test command: Rust tests, then (once the Python package exists) the
# Python tests in a private virtual environment. Needs only a Rust toolchain and Python 3.11.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo test (workspace)"
cargo test --workspace --locked

echo "== symbolic derivation check (derivation/regressor.py)"
VENV=${PRRRP_VENV:-.venv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check sympy
"$VENV/bin/python" derivation/regressor.py | tail -n 1
