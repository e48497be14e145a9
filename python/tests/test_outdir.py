"""All-or-nothing output folders: a failed, interrupted or terminated run leaves the old
folder exactly as it was and nothing temporary behind."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from prrrp import outdir


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def leftovers(parent: Path) -> list[str]:
    return [p.name for p in parent.iterdir() if ".prrrp-" in p.name]


def fill(files: dict[str, str]):
    def build(tmp: Path) -> int:
        for name, text in files.items():
            (tmp / name).write_text(text)
        return len(files)

    return build


def test_new_folder_then_replaced_whole(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert outdir.write_dir(out, fill({"a.txt": "1", "b.txt": "2"})) == 2
    assert set(snapshot(out)) == {"a.txt", "b.txt", outdir.MARKER}
    outdir.write_dir(out, fill({"c.txt": "3"}))
    assert set(snapshot(out)) == {"c.txt", outdir.MARKER}
    assert leftovers(tmp_path) == []


def test_failed_build_leaves_the_old_folder(tmp_path: Path) -> None:
    out = tmp_path / "out"
    outdir.write_dir(out, fill({"a.txt": "1"}))
    before = snapshot(out)

    def failing(tmp: Path) -> None:
        (tmp / "a.txt").write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        outdir.write_dir(out, failing)
    assert snapshot(out) == before
    assert leftovers(tmp_path) == []


def test_foreign_or_file_output_is_refused(tmp_path: Path) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("precious")
    with pytest.raises(outdir.OutputDirError, match=r"thesis\.tex"):
        outdir.write_dir(mine, fill({"a.txt": "1"}))
    assert snapshot(mine) == {"thesis.tex": b"precious"}
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(outdir.OutputDirError, match="not a directory"):
        outdir.write_dir(afile, fill({"a.txt": "1"}))


def test_leftovers_of_a_killed_run_are_cleaned_and_repaired(tmp_path: Path) -> None:
    out = tmp_path / "out"
    outdir.write_dir(out, fill({"a.txt": "1"}))
    # A run killed between the two renames of the fallback swap: `out` moved aside.
    tmp_prefix, old_prefix = outdir._prefixes(out)
    out.rename(tmp_path / f"{old_prefix}x")
    (tmp_path / f"{tmp_prefix}y").mkdir()
    outdir.write_dir(out, fill({"b.txt": "2"}))
    assert set(snapshot(out)) == {"b.txt", outdir.MARKER}
    assert leftovers(tmp_path) == []


def test_sigterm_during_reproduce_leaves_the_old_results(tmp_path: Path) -> None:
    out = tmp_path / "out"
    outdir.write_dir(out, fill({"results.json": "{}"}))
    before = snapshot(out)
    env = dict(os.environ)
    child = subprocess.Popen(
        [sys.executable, "-m", "prrrp", "reproduce", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    try:
        time.sleep(2.0)
        child.send_signal(signal.SIGTERM)
        child.communicate(timeout=30)
    finally:
        child.kill()
    assert child.returncode == 128 + signal.SIGTERM
    assert snapshot(out) == before
    assert leftovers(tmp_path) == []
