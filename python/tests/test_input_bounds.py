"""Fuzz reproducers of issue 25, one regression test each: every one ends in a typed error
saying what to fix, or in the right result — a model file that is a FIFO or /dev/zero, a
hand-edited model.json, an excitation too large for memory, a CSV file read in memory
proportional to its numbers."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from conftest import TWO

import prrrp
from prrrp import cli, csvio, prediction, workflow


@pytest.fixture(scope="module")
def model_file(tmp_path_factory) -> Path:
    """A saved model of a two-joint arm identified from exact torques, with a recorded
    preprocessing (cut-off 8 Hz)."""
    folder = tmp_path_factory.mktemp("model")
    chain = prrrp.SerialChain.from_urdf(TWO)
    t = np.arange(0, 20, 0.01)
    q = np.column_stack([0.8 * np.sin(0.7 * t), 0.6 * np.sin(1.1 * t + 1)])
    qd = np.column_stack([0.56 * np.cos(0.7 * t), 0.66 * np.cos(1.1 * t + 1)])
    qdd = np.column_stack([-0.392 * np.sin(0.7 * t), -0.726 * np.sin(1.1 * t + 1)])
    data = prrrp.Dataset(t, q, qd, qdd, chain.inverse_dynamics(q, qd, qdd))
    model = prrrp.identify(chain, data, "ls", preprocessing={"settings": {"cutoff_hz": 8.0}})
    path = folder / "model.json"
    model.save(path)
    (folder / "log.csv").write_text(
        csvio.format_measurements(t, q, chain.inverse_dynamics(q, qd, qdd))
    )
    return path


# ------------------------------------------------------------------------- model loading


def test_loading_a_fifo_is_refused_without_blocking(tmp_path: Path) -> None:
    """Opening a FIFO blocks until a writer comes: the file type is checked first."""
    fifo = tmp_path / "model.json"
    os.mkfifo(fifo)
    code = (
        "import prrrp, sys\n"
        "try:\n"
        "    prrrp.IdentifiedModel.load(sys.argv[1])\n"
        "except prrrp.InvalidParameterError as e:\n"
        "    print(e.what, '|', e)\n"
    )
    start = time.monotonic()
    run = subprocess.run(
        [sys.executable, "-c", code, str(fifo)], capture_output=True, text=True, timeout=60
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("path | ")
    assert "not a regular file" in run.stdout
    assert time.monotonic() - start < 30


@pytest.mark.parametrize("path", ["/dev/zero", "/dev/null"])
def test_loading_a_device_is_refused(path: str) -> None:
    if not os.path.exists(path):
        pytest.skip(f"no {path}")
    with pytest.raises(prrrp.InvalidParameterError, match="not a regular file") as info:
        prrrp.IdentifiedModel.load(path)
    assert info.value.file == path


def test_loading_a_folder_or_a_huge_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(prrrp.InvalidParameterError, match="a folder"):
        prrrp.IdentifiedModel.load(tmp_path)
    big = tmp_path / "big.json"
    with big.open("wb") as f:  # sparse: no disk or memory used
        f.truncate(prrrp.IdentifiedModel.MAX_FILE_BYTES + 1)
    with pytest.raises(prrrp.InvalidParameterError, match="bytes a model file may have") as info:
        prrrp.IdentifiedModel.load(big)
    assert info.value.what == "size"


def test_a_malformed_model_names_what_is_wrong(model_file: Path, tmp_path: Path) -> None:
    doc = json.loads(model_file.read_text())
    doc["epochs"] = "ten"
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(prrrp.InvalidParameterError) as info:
        prrrp.IdentifiedModel.load(bad)
    assert 'invalid type: string "ten", expected usize' in str(info.value)
    assert str(info.value).startswith(f"{bad}: not a prrrp model file")


def _damaged(doc: dict, what: str) -> dict:
    if what == "beta":
        doc["beta"][0] = 1e299
    elif what == "gravity":
        doc["robot"]["gravity"][2] = -1e299
    else:
        doc["base"]["independent"][1] = doc["base"]["independent"][0]
    return doc


@pytest.mark.parametrize(
    ("what", "error", "needle"),
    [
        ("beta", prrrp.InvalidParameterError, "beta[0]"),
        ("gravity", prrrp.InvalidParameterError, "gravity[2]"),
        ("independent", prrrp.ShapeMismatchError, "twice"),
    ],
)
def test_a_damaged_model_is_refused_at_load(
    model_file: Path, tmp_path: Path, capsys, what: str, error: type, needle: str
) -> None:
    """A β or a gravity of 1e299 predicted torques whose squares overflowed (errors printed
    as inf, numpy's warnings on stderr, exit 0); a repeated base index read one parameter
    twice and predicted wrong torques without a word."""
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps(_damaged(json.loads(model_file.read_text()), what)))
    with pytest.raises(error, match=re.escape(needle)):
        prrrp.IdentifiedModel.load(bad).predict(
            np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2))
        )
    out = tmp_path / "tau.csv"
    argv = ["predict", str(bad), str(model_file.parent / "log.csv"), "--out", str(out)]
    assert cli.main(argv) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert needle in err, err
    assert "Warning" not in err, err
    assert not out.exists()


@pytest.mark.parametrize(
    ("setting", "value", "expected"),
    [
        ("cutoff_hz", "ten", "a number"),
        ("order", 4.5, "an integer"),
        ("filter_torque", "yes", "true or false"),
        ("rate_hz", [100], "a number"),
        ("trim_s", True, "a number"),
    ],
)
def test_a_string_setting_in_model_json_is_a_clear_error(
    model_file: Path, tmp_path: Path, capsys, setting, value, expected
) -> None:
    """A hand-edited preprocessing setting of the wrong type was a TypeError traceback
    from `prrrp predict`; it is a one-line usage error naming the setting."""
    doc = json.loads(model_file.read_text())
    doc["preprocessing"]["settings"][setting] = value
    bad = tmp_path / "m.json"
    bad.write_text(json.dumps(doc))
    out = tmp_path / "tau.csv"
    argv = ["predict", str(bad), str(model_file.parent / "log.csv"), "--out", str(out)]
    assert cli.main(argv) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert f"'{setting}'" in err
    assert expected in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()
    model = prrrp.IdentifiedModel.load(bad)
    with pytest.raises(ValueError, match=setting):
        prediction.recorded_settings(model)


def test_predict_does_not_replace_a_fifo_or_a_device(
    model_file: Path, tmp_path: Path, capsys
) -> None:
    """`predict --out` took a FIFO (or, run as root, /dev/null) and replaced it with a
    regular file; it is a one-line usage error, the node left as it was."""
    fifo = tmp_path / "tau.csv"
    os.mkfifo(fifo)
    for out in [fifo, tmp_path / "link.csv"]:
        if out.name == "link.csv":
            out.symlink_to(fifo)
        argv = ["predict", str(model_file), str(model_file.parent / "log.csv"), "--out", str(out)]
        assert cli.main(argv) == cli.EXIT_USAGE
        err = capsys.readouterr().err
        assert "device, pipe or socket" in err, err
        assert len(err.strip().splitlines()) == 1
        assert fifo.is_fifo()
    with pytest.raises(csvio.InputError, match="pipe"):
        csvio.write_table_atomic(fifo, ["t"], np.zeros((1, 1)))
    assert fifo.is_fifo()


# ------------------------------------------------------------------- excitation size


def test_excite_refuses_a_rate_that_would_not_fit(tmp_path: Path, capsys) -> None:
    """`excite --rate 1e7` died of memory; it is refused before the design starts, saying
    what to lower."""
    robot = tmp_path / "two.urdf"
    robot.write_text(TWO)
    out = tmp_path / "t.csv"
    start = time.monotonic()
    code = cli.main(["excite", "--robot", str(robot), "--rate", "1e7", "--out", str(out)])
    assert code == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "lower --rate or --duration" in err
    assert len(err.strip().splitlines()) == 1
    assert not out.exists()
    # 5e6 samples of the Panda's 7 joints: a CSV of ~2.3 GiB, more than prrrp reads back.
    import importlib.metadata

    panda = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots/panda_description/urdf/panda.urdf"
    )
    argv = ["excite", "--robot", str(panda), "--tip", "panda_link8", "--out", str(out)]
    assert cli.main([*argv, "--rate", "1e6", "--duration", "5"]) == cli.EXIT_USAGE
    err = capsys.readouterr().err
    assert "GiB prrrp reads back: lower --rate or --duration" in err
    assert not out.exists()
    assert time.monotonic() - start < 10  # refused before the (slow) design


def test_excite_memory_estimate_against_the_available_memory(monkeypatch) -> None:
    chain = prrrp.SerialChain.from_urdf(TWO)
    monkeypatch.setattr(workflow, "available_memory", lambda: 64 << 20)
    # 2e6 samples × 7 columns × 8 bytes = 112 MB > 40 % of 64 MiB.
    with pytest.raises(prrrp.InvalidInputError, match="lower the rate or duration"):
        workflow.excite(chain, 10.0, rate=2e5, max_evaluations=1)
    workflow.check_memory(1000, 2, 7, "rate")  # small enough: no error


# ---------------------------------------------------------------------------- CSV reader


def test_csv_reader_memory_is_proportional_to_the_numbers(tmp_path: Path) -> None:
    """The reader held every row as a Python list of floats (6-8× the numbers' 8 bytes,
    28× the file for short cells); it now parses blocks into one float64 array."""
    rows, n = 60_000, 7
    rng = np.random.default_rng(0)
    t = np.arange(rows) * 1e-3
    q, tau = rng.normal(size=(2, rows, n))
    path = tmp_path / "log.csv"
    path.write_text(csvio.format_measurements(t, q, tau))
    numbers = rows * (1 + 2 * n) * 8
    tracemalloc.start()
    try:
        data = csvio.read_table(path, n, real_log=True)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert np.array_equal(data["t"], t)
    assert np.array_equal(data["q"], q)
    assert np.array_equal(data["tau"], tau)
    # The array, the returned copies and one block of text: under 3× the numbers.
    assert peak < 3 * numbers, (peak, numbers)


def test_csv_errors_keep_their_line_numbers_across_blocks(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(csvio, "CHUNK_LINES", 7)
    t = np.arange(40) * 0.01
    text = csvio.format_measurements(t, np.zeros((40, 5)), np.zeros((40, 5))).splitlines()
    for line, cell, message in ((23, "abc", "'abc' is not a number"), (31, "inf", "not finite")):
        lines = list(text)
        cells = lines[line - 1].split(",")
        cells[3] = cell
        lines[line - 1] = ",".join(cells)
        path = tmp_path / "bad.csv"
        path.write_text("\n".join(lines) + "\n")
        with pytest.raises(csvio.InputError, match=rf"line {line}, column 'q3': .*{message}"):
            csvio.read_measurements(path)
    lines = list(text)
    lines[17] += ",1"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(csvio.InputError, match="line 18 has 12 cells"):
        csvio.read_measurements(path)
