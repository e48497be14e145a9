"""The type stub `_prrrp.pyi` agrees with the compiled module, checked by mypy's stubtest:
every name, parameter (name, kind, default) and class property (final) of the runtime."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

PYTHON = Path(__file__).resolve().parents[1]
STUB = PYTHON / "prrrp" / "_prrrp.pyi"
ALLOWLIST = PYTHON / "stubtest-allowlist.txt"


def test_stub_matches_the_compiled_module(tmp_path):
    # The repository's stub, not the copy installed beside the extension: a stub edit is
    # checked without rebuilding. Alone on MYPYPATH, so that mypy does not type-check the
    # package's .py modules on the way (that is not this test's business).
    stubs = tmp_path / "stubs" / "prrrp"
    stubs.mkdir(parents=True)
    (stubs / "__init__.pyi").touch()
    shutil.copy(STUB, stubs / "_prrrp.pyi")
    env = {**os.environ, "MYPYPATH": str(stubs.parent)}
    run = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "prrrp._prrrp", "--allowlist", str(ALLOWLIST)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, f"stubtest failed:\n{run.stdout}\n{run.stderr}"
