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


def earlier_run(tmp_path: Path, files: dict[str, str]) -> Path:
    """``tmp_path/out`` as an earlier run left it: ``files`` and the marker."""
    out = tmp_path / "out"
    outdir.write_dir(out, fill(files))
    return out


def write_replaces_whole(out: Path, files: dict[str, str]) -> None:
    """``write_dir`` of ``files`` leaves ``out`` holding just them (and the marker), with
    nothing temporary beside it."""
    outdir.write_dir(out, fill(files))
    assert set(snapshot(out)) == {*files, outdir.MARKER}
    assert leftovers(out.parent) == []


def test_new_folder_then_replaced_whole(tmp_path: Path) -> None:
    out = tmp_path / "out"
    assert outdir.write_dir(out, fill({"a.txt": "1", "b.txt": "2"})) == 2
    assert set(snapshot(out)) == {"a.txt", "b.txt", outdir.MARKER}
    write_replaces_whole(out, {"c.txt": "3"})


def test_failed_build_leaves_the_old_folder(tmp_path: Path) -> None:
    out = earlier_run(tmp_path, {"a.txt": "1"})
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


def test_an_unwritable_place_is_refused_before_the_work(tmp_path: Path) -> None:
    """`check` (called before the computation) refuses an --out below a file, or in a
    folder this process cannot write in, naming --out and the place, not the hidden
    staging folder the failure at the end used to name."""
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(outdir.OutputDirError, match=r"file is a file, not a folder"):
        outdir.check(afile / "sub" / "out")
    with pytest.raises(outdir.OutputDirError, match=r"file is a file, not a folder"):
        outdir.write_dir(afile / "out", fill({"a.txt": "1"}))
    assert afile.read_text() == "x"
    outdir.check(tmp_path / "new" / "deeper" / "out")  # missing folders are made
    if os.geteuid() == 0:
        return  # root writes in any folder: the permission case cannot be set up
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        with pytest.raises(outdir.OutputDirError, match=r"cannot write in .*locked"):
            outdir.check(locked / "out")
    finally:
        locked.chmod(0o700)


def test_leftovers_of_a_killed_run_are_cleaned_and_repaired(tmp_path: Path) -> None:
    out = earlier_run(tmp_path, {"a.txt": "1"})
    # A run killed between the two renames of the fallback swap: `out` moved aside.
    tmp_prefix, old_prefix = outdir._prefixes(out)
    out.rename(tmp_path / f"{old_prefix}x")
    (tmp_path / f"{tmp_prefix}y").mkdir()
    write_replaces_whole(out, {"b.txt": "2"})


def test_sigterm_during_reproduce_leaves_the_old_results(tmp_path: Path) -> None:
    out = earlier_run(tmp_path, {"results.json": "{}"})
    before = snapshot(out)
    env = dict(os.environ)
    child = subprocess.Popen(
        [sys.executable, "-m", "prrrp", "reproduce", "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
    )
    try:
        # Signal once the run is building its output (its handler is installed before
        # that): a fixed sleep sometimes ended while Python was still importing, whose
        # default SIGTERM action is right too but is not what this test checks.
        deadline = time.monotonic() + 60.0
        while not leftovers(tmp_path) and child.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert leftovers(tmp_path), "reproduce never started building its output"
        child.send_signal(signal.SIGTERM)
        child.communicate(timeout=30)
    finally:
        child.kill()
    assert child.returncode == 128 + signal.SIGTERM
    assert snapshot(out) == before
    assert leftovers(tmp_path) == []


# A process that builds an output folder and waits for a file before finishing.
_SLOW_BUILD = """
import sys, time
from pathlib import Path
from prrrp import outdir
out, go = Path(sys.argv[1]), Path(sys.argv[2])
def build(tmp):
    (tmp / "started").write_text("1")
    print("building", flush=True)
    while not go.exists():
        time.sleep(0.02)
    (tmp / "result.txt").write_text("slow run")
outdir.write_dir(out, build)
print("done", flush=True)
"""


def _slow_run(tmp_path: Path, out: Path) -> tuple[subprocess.Popen, Path]:
    go = tmp_path / "go"
    child = subprocess.Popen(
        [sys.executable, "-c", _SLOW_BUILD, str(out), str(go)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert child.stdout.readline().strip() == "building"
    return child, go


def test_a_second_run_does_not_remove_a_live_runs_staging_folder(tmp_path: Path, capsys) -> None:
    """The cause of a benchmark losing its results to "errors_by_noise.png: no such file or
    directory": a second run into the same --out removed the first's staging folder as a
    leftover. Staging folders are locked while their run lives."""
    out = tmp_path / "big"
    child, go = _slow_run(tmp_path, out)
    try:
        outdir.write_dir(out, fill({"fast.txt": "fast run"}))
        go.write_text("1")
        stdout, stderr = child.communicate(timeout=60)
    finally:
        child.kill()
    assert child.returncode == 0, stderr
    assert stdout.strip() == "done"
    assert "another prrrp run is writing" in capsys.readouterr().err
    # The run that finished last replaced the folder whole.
    assert (out / "result.txt").read_text() == "slow run"
    assert leftovers(tmp_path) == []


def test_staging_folder_of_a_sigkilled_run_is_removed_and_reported(tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    child, _ = _slow_run(tmp_path, out)
    child.send_signal(signal.SIGKILL)
    child.communicate(timeout=30)
    assert len(leftovers(tmp_path)) == 1
    write_replaces_whole(out, {"a.txt": "1"})
    err = capsys.readouterr().err
    assert "removed 1 staging folder" in err
    assert "killed" in err


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_output_folder_honours_the_umask(tmp_path: Path, umask: int) -> None:
    old = os.umask(umask)
    try:
        outdir.write_dir(tmp_path / "out", fill({"a.txt": "1"}))
        reference = tmp_path / "mkdir"
        reference.mkdir()
    finally:
        os.umask(old)
    mode = (tmp_path / "out").stat().st_mode & 0o777
    assert mode == 0o777 & ~umask
    assert mode == reference.stat().st_mode & 0o777


def test_a_symlinked_out_is_followed_and_kept(tmp_path: Path) -> None:
    target = tmp_path / "real"
    link = tmp_path / "link"
    link.symlink_to(target)  # dangling at first: the first run creates the target
    for text in ("1", "2"):
        outdir.write_dir(link, fill({"a.txt": text}))
        assert link.is_symlink()
        assert os.readlink(link) == str(target)
        assert (target / "a.txt").read_text() == text
    assert leftovers(tmp_path) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "real"]
