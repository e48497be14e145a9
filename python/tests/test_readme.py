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
