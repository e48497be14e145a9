#!/usr/bin/env bash
# The project's one test command: Rust tests (cargo) and Python tests (pytest).
#
#   bash scripts/test.sh
#
# Creates the virtual environment .venv on first use (override with PRRRP_VENV), installs the
# package with its test extras and ruff (`pip install .[dev]`, dev = test + ruff: maturin
# builds the extension as the build backend), then runs `cargo test --workspace`, pytest and
# the Python lint (ruff). Idempotent: a second run
# reuses the venv and cargo's incremental build. Needs only Rust and Python >= 3.11.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"

python="${PYTHON:-python3}"
venv="${PRRRP_VENV:-$root/.venv}"

if [[ ! -x "$venv/bin/python" ]]; then
    echo "== creating virtual environment $venv"
    "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --upgrade pip
fi

echo "== pip install .[dev] (builds the Rust extension)"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check ".[dev]"

echo "== cargo test --workspace"
cargo test --workspace --locked

echo "== symbolic derivation check (derivation/regressor.py)"
"$venv/bin/python" derivation/regressor.py | tail -n 1

echo "== ruff"
"$venv/bin/ruff" check python
"$venv/bin/ruff" format --check python

echo "== pytest"
"$venv/bin/python" -m pytest python/tests

echo "== pytest -m protocol (the full convergence grid, 2 processes)"
"$venv/bin/python" -m pytest -q -m protocol python/tests/test_convergence_protocol.py
