"""The README's Python examples run as written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


@pytest.mark.parametrize(
    "needle",
    [
        'load_robot("paper")',
        "Robot.paper()",
        "SerialChain.puma560",
        "SerialChain.from_urdf",
        "prrrp.identify",
        "OnlineIdentifier",
    ],
)
def test_readme_example_runs(needle):
    blocks = [b for b in python_blocks() if needle in b]
    assert blocks, f"no README example uses {needle}"
    for block in blocks:
        exec(compile(block, str(README), "exec"), {})


def test_your_robot_tour_runs_as_written(tmp_path):
    """The "Your robot" shell tour, run by bash in a fresh folder with the installed
    `prrrp` command on PATH."""
    from conftest import run_shell_block

    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Your robot") :]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    assert "prrrp excite" in block
    assert "prrrp predict" in block
    run = run_shell_block(block, tmp_path)
    for name in (
        "traj/trajectory.csv",
        "data/data.csv",
        "val/data.csv",
        "tau.csv",
        "panda-id/model.json",
    ):
        assert (tmp_path / name).is_file(), name
    assert "torque-prediction error" in run.stdout
    assert "deprecated" not in run.stderr


def test_benchmark_example_runs_as_a_saved_script(tmp_path):
    """The README's Python benchmark example, saved as a script and run as one: the
    process pool's workers import the script, which the `__main__` guard makes safe."""
    import subprocess
    import sys

    block = next(b for b in python_blocks() if "prrrp.benchmark(" in b)
    assert 'if __name__ == "__main__":' in block
    script = tmp_path / "bench.py"
    script.write_text(block)
    run = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr
    rate, error = run.stdout.split()
    assert float(rate) > 0
    assert float(error) > 0


def test_an_unguarded_benchmark_script_is_told_what_to_do(tmp_path):
    """The same script without the guard: a WorkerStartError (not an input error) whose
    message names the fix."""
    import subprocess
    import sys

    script = tmp_path / "bench.py"
    script.write_text(
        "import prrrp\nprrrp.benchmark(seeds=1, methods='ls', workers=1, progress=False)\n"
    )
    run = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=300
    )
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("prrrp.montecarlo.runner.WorkerStartError"), last
    assert 'if __name__ == "__main__":' in last
