"""The README's Python examples run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


@pytest.mark.parametrize(
    "needle", ["SerialChain.puma560", "SerialChain.from_urdf", "prrrp.identify"]
)
def test_readme_example_runs(needle):
    blocks = [b for b in python_blocks() if needle in b]
    assert blocks, f"no README example uses {needle}"
    for block in blocks:
        exec(compile(block, str(README), "exec"), {})


def test_your_robot_tour_runs_as_written(tmp_path):
    """The "Your robot" shell tour, run by bash in a fresh folder with the installed
    `prrrp` command on PATH."""
    import os
    import subprocess
    import sys

    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Your robot") :]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    assert "prrrp excite" in block
    assert "prrrp predict" in block
    env = dict(os.environ)
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    run = subprocess.run(
        ["bash", "-e", "-c", block],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    for name in ("traj.csv", "data.csv", "val.csv", "tau.csv", "panda-id/model.json"):
        assert (tmp_path / name).is_file(), name
    assert "torque-prediction error" in run.stdout
