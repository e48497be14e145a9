"""The native fast path of reading a measurement CSV (``prrrp._prrrp.read_numeric_csv``,
used by ``prrrp.csvio.read_table``) reads what the general Python reader reads, to the
same bits, and declines everything else, so that a bad file gets the general reader's
message (line, column, what is wrong)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prrrp import csvio
from prrrp._prrrp import read_numeric_csv

HEADER = "t,q1,q2,tau1,tau2"


def outcome(path: Path, fast: bool, monkeypatch: pytest.MonkeyPatch) -> object:
    """read_table's arrays, or its InputError's message, with or without the fast path."""
    with monkeypatch.context() as m:
        if not fast:
            m.setattr(csvio, "_fast_table", lambda path: None)
        try:
            out = csvio.read_table(path, 2, real_log=True)
        except csvio.InputError as e:
            return str(e)
    return {k: v.tobytes() for k, v in out.items()}


def rows(n: int, cells: list[str] | None = None) -> list[str]:
    rng = np.random.default_rng(n)
    lines = []
    for k in range(n):
        values = [repr(0.01 * k), *(repr(float(x)) for x in rng.normal(size=4))]
        lines.append(",".join(values))
    if cells is not None:
        lines[len(lines) // 2] = ",".join(cells)
    return lines


CASES = {
    "plain": HEADER + "\n" + "\n".join(rows(30)) + "\n",
    "crlf, bom, comments, blanks": "\ufeff# log\r\n\r\n"
    + HEADER
    + "\r\n"
    + "\r\n  # a note\r\n\t\r\n".join(rows(30))
    + "\r\n",
    "no final line end": HEADER + "\n" + "\n".join(rows(30)),
    "padded cells": HEADER + "\n" + "\n".join(" , ".join(r.split(",")) for r in rows(30)),
    "other spellings": HEADER + "\n" + "\n".join(rows(30, ["1.", ".5", "+2E-3", "-0", "7e+1"])),
    "underscores": HEADER + "\n" + "\n".join(rows(30, ["1_0", "1", "2", "3", "4"])),
    "nan": HEADER + "\n" + "\n".join(rows(30, ["1", "nan", "2", "3", "4"])),
    "inf": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "-inf", "3", "4"])),
    "overflow": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "3", "1e999", "4"])),
    "text": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "3", "4", "abc"])),
    "empty cell": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "", "4", "5"])),
    "short row": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "3", "4"])),
    "long row": HEADER + "\n" + "\n".join(rows(30, ["1", "2", "3", "4", "5", "6"])),
    "quoted": HEADER + "\n" + "\n".join(rows(30, ['"1"', "2", "3", "4", "5"])),
    "quoted header": '"t",q1,q2,tau1,tau2\n' + "\n".join(rows(30)),
    "lone cr": HEADER + "\r" + "\r".join(rows(30)) + "\r",
    "lone cr in a comment": HEADER + "\n# note\r" + "\n".join(rows(30)),
    "unicode space": HEADER + "\n" + "\n".join(rows(30, ["1", "\u00a02", "3", "4", "5"])),
    "missing column": "t,q1,q2,tau1\n" + "\n".join(r.rsplit(",", 1)[0] for r in rows(30)),
    "unknown column": "t,q1,q2,tau1,tau2,x\n" + "\n".join(r + ",1" for r in rows(30)),
    "too few rows": HEADER + "\n" + "\n".join(rows(5)),
    "time backwards": HEADER + "\n" + "\n".join(rows(30)[::-1]),
    "empty": "",
    "only comments": "# nothing\n\n",
}


@pytest.mark.parametrize("block", [None, 64, 200])
@pytest.mark.parametrize("name", list(CASES))
def test_the_fast_path_reads_or_declines_like_the_general_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str, block: int | None
) -> None:
    """Whole, and in blocks of 64 and 200 bytes (lines longer than a block, blocks
    ending inside a CRLF pair or a comment)."""
    path = tmp_path / "log.csv"
    path.write_bytes(CASES[name].encode("utf-8"))
    if block is not None:
        monkeypatch.setattr(csvio, "FAST_BLOCK_BYTES", block)
    assert outcome(path, True, monkeypatch) == outcome(path, False, monkeypatch)


@pytest.mark.parametrize("name", ["plain", "crlf, bom, comments, blanks", "no final line end"])
def test_blocks_are_read_natively(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    """The block-by-block native read is not a decline in disguise: small blocks give the
    numbers of one whole read."""
    path = tmp_path / "log.csv"
    path.write_bytes(CASES[name].encode("utf-8"))
    whole = csvio._fast_table(path)
    assert whole is not None
    for block in (64, 200):
        monkeypatch.setattr(csvio, "FAST_BLOCK_BYTES", block)
        parts = csvio._fast_table(path)
        assert parts is not None, block
        assert parts[:2] == whole[:2]
        assert parts[2].tobytes() == whole[2].tobytes()


def test_the_fast_path_reads_a_plain_file_itself(tmp_path: Path) -> None:
    """Not a test of one reader against itself: the plain files are read natively (and the
    values are the numbers written, to the bit)."""
    path = tmp_path / "log.csv"
    path.write_text(CASES["crlf, bom, comments, blanks"], encoding="utf-8")
    found = read_numeric_csv(path.read_bytes())
    assert found is not None
    header, lineno, count, width, values = found
    assert (header, lineno, count, width) == (HEADER, 3, 30, 5)
    want = np.array([[float(x) for x in r.split(",")] for r in rows(30)])
    assert values == want.tobytes()
    for name in ("nan", "quoted", "lone cr", "short row", "underscores", "empty"):
        assert read_numeric_csv(CASES[name].encode("utf-8")) is None, name
    assert read_numeric_csv(b"t,q1\n0,1\n# \xff\n") is None


def test_a_bad_cell_is_named_by_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "log.csv"
    path.write_text(CASES["nan"], encoding="utf-8")
    with pytest.raises(csvio.InputError, match=r"line 17, column 'q1': nan is not finite"):
        csvio.read_table(path, 2, real_log=True)


def test_a_value_beyond_any_arm_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A torque of -1e300 (a unit slip, or garbage): refused with its row and column, by
    either path; before, `identify` called the log rank deficient and `predict` printed
    numpy's overflow warnings and exit 0."""
    lines = rows(30)
    cells = lines[12].split(",")
    cells[4] = "-1e300"
    lines[12] = ",".join(cells)
    path = tmp_path / "log.csv"
    path.write_text("\n".join([HEADER, *lines]) + "\n", encoding="utf-8")
    for fast in (True, False):
        message = outcome(path, fast, monkeypatch)
        assert isinstance(message, str), fast
        assert "data row 13, column 'tau2': -1e+300 is 1e100 or more" in message, message
        assert "units" in message


CELL = st.text(alphabet="0123456789.eE+-_ \tnaif", min_size=0, max_size=8)


@settings(max_examples=150, deadline=None)
@given(cells=st.lists(CELL, min_size=5, max_size=5))
def test_any_cell_is_read_or_declined_like_the_general_reader(cells: list[str]) -> None:
    """Random cells of number-like characters: the same values or the same message."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.csv"
        path.write_text(HEADER + "\n" + "\n".join(rows(25, cells)) + "\n", encoding="utf-8")
        with pytest.MonkeyPatch.context() as mp:
            assert outcome(path, True, mp) == outcome(path, False, mp)
